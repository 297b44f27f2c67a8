"""Where the true vertical is seen, from the vertical edges among a panorama's lines.

Every vertical 3D edge is seen along a great circle through the vertical direction: the
plane through the camera and the edge contains the vertical. So the great circles of the
vertical edges all pass through one point of the sphere, the vertical vanishing direction
``v``, and their unit normals ``n_i`` satisfy ``n_i · v = 0``. :func:`find_up` finds ``v``
among the lines robustly: a RANSAC over pairs of arcs whose crossing lies near the
zenith, then a reweighted least squares refit on the inliers (``v`` the smallest
eigenvector of ``Σ w_i n_i n_iᵀ``, Huber weights).

:func:`omniwidget.detect.level.level` and the choice of a structural set of lines
(:mod:`omniwidget.detect.structure`) both rest on it; it lives here, below both, so that
:func:`omniwidget.detect.lines.suggest_lines` can use it without an import cycle.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from ..errors import LevelError
from ..sphere import coords

if TYPE_CHECKING:
    from .lines import Suggestion

__all__ = ["INLIER_SIGMAS", "MAX_TILT", "MIN_EDGE_LENGTH", "find_up"]

FloatArray = NDArray[np.float64]
#: Farthest the vertical direction is looked for from the zenith, degrees.
MAX_TILT = 35.0
#: An arc is never a vertical edge when its great circle passes farther than this (degrees) from the vertical direction.
INLIER_DISTANCE = 1.0
#: Refuse when the inliers' root-mean-square distance from the vertical, in their own errors, exceeds this.
MAX_RESIDUAL = 2.0
#: Normals closer than this (degrees) belong to the same plane, counted as one edge.
SAME_PLANE = 1.0
#: An arc is a vertical edge when its circle passes within this many of its own errors (:func:`_sigma`) of the vertical.
INLIER_SIGMAS = 3.0
#: The Huber threshold of the refit, in errors.
HUBER = 1.5
#: The endpoints' accuracy assumed, in pixels of the panorama.
ENDPOINT_PX = 0.5
#: The arc length (degrees) whose endpoints are placed within :data:`ENDPOINT_PX`.
REFERENCE_LENGTH = 20.0
#: Contrast (share of the full range) above which an edge is taken as sharply placed.
CLEAR_CONTRAST = 0.15
#: Arcs reaching within this many degrees of the vertical direction (or its opposite) do not vote for it:
#: a line on the floor passing near the camera's foot is seen along a circle nearly through the nadir
#: too, while vertical edges are rarely seen so steeply.
POLAR_CAP = 20.0
#: Candidate directions scored at a time (bounds the (arcs x candidates) arrays; smaller blocks stay nearer the cache).
CANDIDATES_PER_BLOCK = 512
#: Shortest arc that votes for the vertical, degrees.
MIN_EDGE_LENGTH = 5.0


# --- the estimate --------------------------------------------------------------------


def _normals(edges: Sequence[Suggestion]) -> tuple[FloatArray, FloatArray]:
    """Unit normals of the arcs' great circles, (k, 3), and their lengths in degrees, (k,)."""
    a = coords.lonlat_to_xyz(np.array([s.start for s in edges], dtype=np.float64).reshape(-1, 2))
    b = coords.lonlat_to_xyz(np.array([s.end for s in edges], dtype=np.float64).reshape(-1, 2))
    n = np.cross(a, b)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    return n, np.array([s.length for s in edges], dtype=np.float64)


def _distinct_planes(normals: FloatArray) -> int:
    """How many of the normals (k, 3) differ by more than :data:`SAME_PLANE` degrees (up to sign)."""
    kept: list[FloatArray] = []
    limit = math.cos(math.radians(SAME_PLANE))
    for n in normals:
        if all(abs(float(n @ m)) < limit for m in kept):
            kept.append(n)
    return len(kept)


def _sigma(normals: FloatArray, mids: FloatArray, lengths: FloatArray, contrast: FloatArray, v: FloatArray, accuracy: float) -> FloatArray:
    """How far (radians) each arc's great circle may pass from ``v`` by the endpoints' error alone.

    An arc of length ``L`` whose endpoints are each off by ``accuracy`` tilts its circle by
    about ``accuracy / L``; at ``v``, a distance ``d`` from the arc's middle, the circle is
    off by about ``accuracy * (1 + d / L)``: short arcs far from ``v`` say little about it.
    And a longer edge is fitted to more pixels, which places it better still: the error
    shrinks further as ``sqrt(REFERENCE_LENGTH / L)``.
    A faint edge is placed less accurately: below :data:`CLEAR_CONTRAST` the error grows
    in inverse proportion to the contrast.
    """
    d = np.arccos(np.clip(np.abs(mids @ v), 0.0, 1.0))
    faint = np.maximum(1.0, CLEAR_CONTRAST / np.maximum(contrast, 1e-3))
    length = np.maximum(lengths, 1e-6)
    return accuracy * (1.0 + d / np.radians(length)) * np.sqrt(REFERENCE_LENGTH / length) * faint


def _residuals(normals: FloatArray, v: FloatArray) -> FloatArray:
    """Distances (radians) of ``v`` from the arcs' great circles."""
    return np.arcsin(np.clip(np.abs(normals @ v), 0.0, 1.0))


def _passes_by(start: FloatArray, along: FloatArray, span: FloatArray, v: FloatArray) -> NDArray[np.bool_]:
    """Whether each arc passes by ``±v``: the point of its circle nearest to ``v`` or ``-v`` lies inside the arc.

    A vertical edge's arc lies on a circle through ``v`` and stops short of it, so the
    nearest points are beyond its ends. A line on the floor near the camera's foot is seen
    along a circle that passes close to the nadir too, but its arc sweeps past the nadir:
    such arcs do not vote for ``v``.

    Parameters
    ----------
    start, along : ndarray of float64, shape (k, 3)
        Each arc's start and the unit tangent there (``normal x start``).
    span : ndarray of float64, shape (k,)
        Lengths, radians.
    v : ndarray of float64, shape (3, m)
        Candidate directions as columns.

    Returns
    -------
    ndarray of bool, shape (k, m)
    """
    t = np.arctan2(along @ v, start @ v)  # the angle along each circle of the point nearest to v
    opposite = np.where(t > 0, t - np.pi, t + np.pi)  # and of the point nearest to -v
    inside = lambda angle: (angle > 0) & (angle < span[:, None])  # noqa: E731 - one use, two arguments
    return inside(t) | inside(opposite)


@dataclass(frozen=True)
class _Edges:
    """The arcs that may be vertical edges, as :func:`find_up` weighs them (k arcs)."""

    normals: FloatArray  # (k, 3) unit normals of their great circles
    start: FloatArray  # (k, 3) their starts
    end: FloatArray  # (k, 3) their ends
    along: FloatArray  # (k, 3) unit tangents at their starts, normal x start
    spans: FloatArray  # (k,) lengths, radians
    lengths: FloatArray  # (k,) lengths, degrees
    mids: FloatArray  # (k, 3) unit middles
    contrast: FloatArray  # (k,)

    @classmethod
    def of(cls, suggestions: Sequence[Suggestion]) -> _Edges:
        normals, lengths = _normals(suggestions)
        ends = [coords.lonlat_to_xyz(np.array([s.start, s.end], dtype=np.float64)) for s in suggestions]
        start = np.array([p for p, _ in ends]).reshape(-1, 3)
        end = np.array([q for _, q in ends]).reshape(-1, 3)
        mids = np.array([(p + q) / np.linalg.norm(p + q) for p, q in ends]).reshape(-1, 3)
        contrast = np.array([s.contrast for s in suggestions], dtype=np.float64)
        return cls(normals, start, end, np.cross(normals, start), np.radians(lengths), lengths, mids, contrast)

    def sigma(self, v: FloatArray, accuracy: float) -> FloatArray:
        """:func:`_sigma` of these arcs at ``v``."""
        return _sigma(self.normals, self.mids, self.lengths, self.contrast, v, accuracy)

    def votes(self, v: FloatArray, sigma: FloatArray, cap: float, polar: float) -> NDArray[np.bool_]:
        """Which arcs vote for each candidate (columns of ``v``, shape (3, m)): (k, m); ``cap``, ``polar`` as :func:`_scores`."""
        r = np.arcsin(np.clip(np.abs(self.normals @ v), 0.0, 1.0))
        far = ~_passes_by(self.start, self.along, self.spans, v) & (np.maximum(np.abs(self.start @ v), np.abs(self.end @ v)) < polar)
        return (r < INLIER_SIGMAS * sigma[:, None]) & (r < cap) & far


def _scores(edges: _Edges, v: FloatArray, sigma: FloatArray, cap: float, polar: float) -> FloatArray:
    """Each candidate's score, ``Σ 1 / σ_i`` over the arcs that vote for it (:meth:`_Edges.votes`), shape (m,).

    The same sums as over the whole ``(k, m)`` table of votes: the normals' dot products are
    taken for all of it, the rest (the other dot products too) only where an arc's circle
    passes within ``cap`` of the candidate and within :data:`INLIER_SIGMAS` of its own errors
    (few do), and the sums add the voters in the arcs' order.

    Parameters
    ----------
    edges : _Edges
        The arcs (their normals, ends, tangents and spans).
    v : ndarray of float64, shape (3, m)
        Candidate directions as columns.
    sigma : ndarray of float64, shape (k,)
    cap, polar : float
        The sine of :data:`INLIER_DISTANCE` and the cosine of :data:`POLAR_CAP`.
    """
    v = np.ascontiguousarray(v)  # einsum is several times slower on a transposed view
    # numpy's loop, not BLAS: BLAS in threads stalls on this thin product when the cores are busy
    dots = np.abs(np.einsum("ij,jk->ik", edges.normals, v))
    # a vote needs arcsin(x) < cap, so x < cap, and arcsin(x) < INLIER_SIGMAS sigma, so x below its sine (loosened
    # against rounding): these are all the voters and more
    reach = INLIER_SIGMAS * sigma
    limit = np.where(reach < np.pi / 2, np.sin(np.minimum(reach, np.pi / 2)) * (1.0 + 1e-9) + 1e-15, np.inf)
    flat = np.flatnonzero(dots < np.minimum(limit, cap)[:, None])  # np.nonzero's order, several times as fast in 1-D
    rows, cols = np.divmod(flat, dots.shape[1])
    r = np.arcsin(np.clip(dots.ravel()[flat], 0.0, 1.0))
    # the other products only where an arc is near: its start, tangent and end with the candidate, each summed
    # as einsum("ijk,ik->ji") of the stacked ends does it, (x + z) + y, on coordinates gathered one at a time
    vx, vy, vz = v[0][cols], v[1][cols], v[2][cols]
    start, tangent, end = ((p[:, 0][rows] * vx + p[:, 2][rows] * vz) + p[:, 1][rows] * vy for p in (edges.start, edges.along, edges.end))
    t = np.arctan2(tangent, start)  # the angle along each circle of the point nearest to v
    opposite = np.where(t > 0, t - np.pi, t + np.pi)  # and of the point nearest to -v
    span = edges.spans[rows]
    passes = ((t > 0) & (t < span)) | ((opposite > 0) & (opposite < span))
    far = ~passes & (np.maximum(np.abs(start), np.abs(end)) < polar)
    vote = (r < reach[rows]) & (r < cap) & far
    return np.asarray(np.bincount(cols[vote], weights=1.0 / sigma[rows[vote]], minlength=v.shape[1]), dtype=np.float64)


def _refit(normals: FloatArray, sigma: FloatArray, v: FloatArray, iterations: int = 8) -> FloatArray:
    """Reweighted least squares: ``v`` the smallest eigenvector of ``Σ w_i n_i n_iᵀ``, ``w_i = 1 / σ_i²`` with Huber weights."""
    for _ in range(iterations):
        r = _residuals(normals, v) / sigma
        w = np.where(r <= HUBER, 1.0, HUBER / np.maximum(r, 1e-15)) / sigma**2
        scatter = (normals * w[:, None]).T @ normals
        new = np.linalg.eigh(scatter)[1][:, 0]
        v = new if new[2] >= 0 else -new
    return v


def find_up(
    suggestions: Sequence[Suggestion], width: int, *, min_edges: int = 4, max_tilt: float = MAX_TILT
) -> tuple[FloatArray, NDArray[np.bool_], float]:
    """Where the true vertical is seen, from the vertical edges among ``suggestions``.

    Parameters
    ----------
    suggestions : sequence of Suggestion
        The lines to look among (every one :func:`~omniwidget.detect.lines.suggest_lines` finds with ``structure=False``).
    width : int
        Width in pixels of the image the lines were found in (for a panorama wider than
        :data:`~omniwidget.detect.lines.DETECT_WIDTH`, that width): the endpoints' accuracy.
    min_edges : int
        Fewest distinct vertical edges to trust, ``>= 2``.
    max_tilt : float
        Farthest from the zenith the vertical is looked for, degrees, in ``(0, 90)``.

    Returns
    -------
    up : ndarray of float64, shape (3,)
        The unit vector of the vertical, on the zenith's side.
    inliers : ndarray of bool, shape (len(suggestions),)
        The vertical edges the estimate rests on.
    residual : float
        Root mean square distance in degrees of the inliers' great circles from ``up``.

    Raises
    ------
    LevelError
        If fewer than ``min_edges`` vertical edges are found, if they do not fix the
        vertical (all in one plane), or if they disagree on it.
    """
    every = list(suggestions)
    index = _near_zenith(every, max_tilt)
    if len(index) < 2:
        raise LevelError(_TOO_FEW.format(found=len(index), s="" if len(index) == 1 else "s", need=min_edges))
    edges = _Edges.of([every[n] for n in index])
    accuracy = ENDPOINT_PX * 2 * math.pi / width
    v, inliers, sigma = _refined(edges, _voted(edges, max_tilt, accuracy, min_edges), accuracy)
    residual = _agreed(edges.normals[inliers], sigma[inliers], v, min_edges)
    mask = np.zeros(len(every), dtype=bool)
    mask[np.array(index, dtype=np.intp)[inliers]] = True
    return v, mask, residual


_TOO_FEW = "found {found} vertical edge{s}, need at least {need}: the panorama shows too few vertical lines to level it"


def _near_zenith(every: list[Suggestion], max_tilt: float) -> list[int]:
    """Indices of the suggestions long enough (:data:`MIN_EDGE_LENGTH`) whose great circle passes within ``max_tilt`` of the zenith."""
    index = [n for n, s in enumerate(every) if s.length >= MIN_EDGE_LENGTH]
    if not index:
        return index
    normals, _ = _normals([every[n] for n in index])
    near = np.abs(normals[:, 2]) <= math.sin(math.radians(max_tilt)) + 1e-12
    return [n for n, ok in zip(index, near, strict=True) if ok]


def _voted(edges: _Edges, max_tilt: float, accuracy: float, min_edges: int) -> FloatArray:
    """The candidate with the highest :func:`_scores`, among where two circles cross at a good angle within ``max_tilt`` of the zenith."""
    i, j = np.triu_indices(len(edges.normals), 1)
    v = np.cross(edges.normals[i], edges.normals[j])
    size = np.linalg.norm(v, axis=1)
    ok = size > math.sin(math.radians(5.0))  # planes that cross at a good angle
    v = v[ok] / size[ok, None]
    v *= np.where(v[:, 2] < 0, -1.0, 1.0)[:, None]
    v = v[v[:, 2] >= math.cos(math.radians(max_tilt))]
    if len(v) == 0:
        raise LevelError(_TOO_FEW.format(found=0, s="s", need=min_edges))
    sigma_z = edges.sigma(np.array([0.0, 0.0, 1.0]), accuracy)  # the errors hardly change within max_tilt of the zenith
    cap, polar = math.sin(math.radians(INLIER_DISTANCE)), math.cos(math.radians(POLAR_CAP))
    blocks = np.array_split(v, max(1, len(v) // CANDIDATES_PER_BLOCK))
    scores = np.concatenate([_scores(edges, block.T, sigma_z, cap, polar) for block in blocks])
    return np.asarray(v[int(np.argmax(scores))])


def _inliers(edges: _Edges, v: FloatArray, accuracy: float) -> tuple[NDArray[np.bool_], FloatArray]:
    """The arcs voting for ``v``, (k,), and their errors there (:func:`_sigma`)."""
    sigma = edges.sigma(v, accuracy)
    cap, polar = math.sin(math.radians(INLIER_DISTANCE)), math.cos(math.radians(POLAR_CAP))
    return edges.votes(v[:, None], sigma, cap, polar)[:, 0], sigma


def _refined(edges: _Edges, best: FloatArray, accuracy: float) -> tuple[FloatArray, NDArray[np.bool_], FloatArray]:
    """``best`` refitted to its inliers (:func:`_refit`) three times; the direction, its inliers and their errors."""
    inliers, sigma = _inliers(edges, best, accuracy)
    for _ in range(3):
        if inliers.sum() < 2:
            break
        best = _refit(edges.normals[inliers], sigma[inliers], best)
        inliers, sigma = _inliers(edges, best, accuracy)
    return best, inliers, sigma


def _agreed(normals: FloatArray, sigma: FloatArray, v: FloatArray, min_edges: int) -> float:
    """The inliers' RMS distance in degrees from ``v``, once they are enough, spread and agreeing (else :class:`LevelError`)."""
    found = _distinct_planes(normals)
    if found < min_edges:
        raise LevelError(_TOO_FEW.format(found=found, s="" if found == 1 else "s", need=min_edges))
    spread = np.linalg.eigvalsh(normals.T @ normals)
    if spread[1] < 0.02 * spread[2]:
        raise LevelError(f"the {found} vertical edges found lie nearly in one plane through the camera, so they do not fix where up is")
    r = _residuals(normals, v)
    chi = math.sqrt(float(np.mean((r / sigma) ** 2)))
    residual = math.degrees(math.sqrt(float(np.mean(r**2))))
    if chi > MAX_RESIDUAL:
        raise LevelError(
            f"the {found} vertical edges found disagree on where up is (by {residual:.2f}° on average), so the panorama is not levelled"
        )
    return residual
