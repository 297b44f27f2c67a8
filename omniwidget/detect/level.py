"""Level a panorama: the camera's pitch and roll from the vertical edges it sees.

Every vertical 3D edge is seen along a great circle through the vertical direction: the
plane through the camera and the edge contains the vertical. So the great circles of the
vertical edges all pass through one point of the sphere, the vertical vanishing direction
``v``, and their unit normals ``n_i`` satisfy ``n_i · v = 0``. :func:`level` finds ``v``
among the suggested lines (:func:`omniwidget.detect.lines.suggest_lines`) robustly: a
RANSAC over pairs of arcs whose crossing lies near the zenith, then a reweighted least
squares refit on the inliers (``v`` the smallest eigenvector of ``Σ w_i n_i n_iᵀ``, Huber
weights). The rotation that takes ``v`` to the zenith by the shortest turn levels the
panorama without turning it about the vertical.

Convention
----------
The camera's tilt is ``T = R_y(pitch) R_x(roll)``: ``R_x(a)`` turns by ``a`` degrees
right-handedly about the forward axis ``+x`` (lon 0, lat 0), ``R_y(a)`` about ``+y``
(lon 90, lat 0). A direction ``d`` of the level world is seen in the tilted panorama at
``T d``; in particular the zenith is seen at ``up = T (0, 0, 1) = (sin p cos r, -sin r,
cos p cos r)``, so a positive pitch moves the zenith towards lon 0 and a positive roll
towards lon -90. :func:`omniwidget.evaluate.scenes.synthetic_room` renders with the same
convention.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..document.handles import CageHandle, Handle, Handles, Options, PointHandle
from ..errors import LevelError
from ..sphere import coords
from ..sphere.moebius import Moebius
from .lines import DETECT_WIDTH, Suggestion, check_detectable, suggest_lines

__all__ = ["LEVEL_ID", "Level", "level", "level_document", "tilt_rotation", "up_to_pitch_roll"]

LonLat = tuple[float, float]
FloatArray = NDArray[np.float64]

#: The id of the point handle that levelled documents of earlier versions (:func:`level_document` replaces it by ``options.up``).
LEVEL_ID = "level"
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


def tilt_rotation(pitch: float, roll: float) -> FloatArray:
    """The camera tilt ``T = R_y(pitch) R_x(roll)`` of the module's convention, shape (3, 3).

    Parameters
    ----------
    pitch, roll : float
        Degrees.

    Returns
    -------
    ndarray of float64, shape (3, 3)
        A level direction ``d`` is seen at ``T @ d`` in the tilted panorama.
    """
    cp, sp = math.cos(math.radians(pitch)), math.sin(math.radians(pitch))
    cr, sr = math.cos(math.radians(roll)), math.sin(math.radians(roll))
    about_y = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    about_x = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    return about_y @ about_x


def up_to_pitch_roll(up: ArrayLike) -> tuple[float, float]:
    """Pitch and roll (degrees) of a camera that sees the zenith at ``up`` (a ``[lon, lat]``).

    The inverse of ``up = T (0, 0, 1) = (sin p cos r, -sin r, cos p cos r)``, with
    ``roll`` in ``[-90, 90]``.
    """
    u = coords.lonlat_to_xyz(up)
    roll = -math.degrees(math.asin(float(np.clip(u[1], -1.0, 1.0))))
    pitch = math.degrees(math.atan2(float(u[0]), float(u[2])))
    return pitch, roll


@dataclass(frozen=True)
class Level:
    """How far a panorama's camera was from level, and the rotation that levels it.

    Attributes
    ----------
    pitch, roll : float
        Degrees, in the module's convention (``up = (sin p cos r, -sin r, cos p cos r)``).
    up : (float, float)
        ``[lon, lat]`` in degrees where the input panorama sees the true vertical.
    edges : tuple of Suggestion
        The vertical edges the estimate rests on (the inliers).
    residual : float
        Root mean square distance in degrees of the inliers' great circles from ``up``.
    """

    pitch: float
    roll: float
    up: LonLat
    edges: tuple[Suggestion, ...] = ()
    residual: float = 0.0

    @property
    def tilt(self) -> float:
        """Angle of ``up`` from the zenith, degrees: how far the camera was from level."""
        return float(90.0 - self.up[1])

    def rotation(self) -> FloatArray:
        """The levelling rotation as a matrix, shape (3, 3): ``up`` to the zenith about ``up × z``."""
        return self.moebius().apply_xyz(np.eye(3)).T

    def moebius(self) -> Moebius:
        """The levelling rotation as a Möbius map, input to output: ``up`` to the zenith, the yaw unchanged."""
        return Moebius.levelling(self.up)

    def handles(self) -> Handles:
        """A handles document whose warp is exactly the levelling rotation: no handles, ``options.up`` set."""
        return Handles((), Options(up=self.up))


def level_document(doc: Handles, up: Level | LonLat | Moebius) -> Handles:
    """The editor's one-click Level: ``doc`` with its input levelled (``options.up``), the result changed only by the turn.

    The document's ``options.up`` becomes the new ``up``: the method then works on the input
    turned by ``L_new`` (``up`` to the zenith, :meth:`Options.levelling`), and the still
    background, if on, stays on and shows the levelled panorama. Each handle's output is
    carried by ``Q = L_new L_old⁻¹`` (``L_old`` the document's levelling before, the
    identity without one): a point's target becomes ``Q(target)`` and its turn changes by
    ``Q``'s local turns (its map becomes ``Q M Q⁻¹`` in the levelled frame), a cage's
    targets ``Q(targets)``, a line's explicit targets ``Q(targets)``. A rectified line
    without targets stays rectified: it is straightened again in the new frame, where its
    verticals are vertical. So near points, cages and fixed lines, and far from every
    handle, the new warp is ``Q`` after the old one; only rectified lines change beyond
    that. A handle with id ``"level"`` (the point handle that levelled documents of earlier
    versions) is taken as the old levelling and removed.

    Parameters
    ----------
    doc : Handles
    up : Level, (float, float) or Moebius
        Where the input sees the true vertical (a :class:`Level`, or its ``up``), or the
        levelling turn itself (:meth:`Level.moebius`: a rotation taking some ``up`` to the
        zenith by the shortest turn).

    Returns
    -------
    Handles
        A new document; ``doc`` is not changed.

    Raises
    ------
    ValueError
        For a rotation that also turns about the vertical (a levelling keeps the yaw), or
        an ``up`` farther than 45° from the zenith.
    """
    new_up = _up_of(up)
    legacy = [h for h in doc.handles if h.id == LEVEL_ID and isinstance(h, PointHandle)]
    old = doc.options.levelling() or Moebius.identity()
    if legacy:
        old = legacy[0].moebius() @ old
    new = Moebius.levelling(new_up)
    q = new @ old.inverse

    def carried(points: Sequence[LonLat]) -> tuple[LonLat, ...]:
        moved = q(np.asarray(points, dtype=np.float64))
        return tuple((float(lon), float(lat)) for lon, lat in moved)

    out: list[Handle] = []
    for h in doc.handles:
        if h.id == LEVEL_ID and isinstance(h, PointHandle):
            continue
        if isinstance(h, PointHandle):
            final = h.target if h.target is not None else tuple(old(np.asarray(h.position, dtype=np.float64)))  # as shown now
            (target,) = carried([final])
            at_target = q.local_scale_rotation(final)[1]
            at_position = q.local_scale_rotation(old(np.asarray(h.position, dtype=np.float64)))[1]
            out.append(replace(h, target=target, rotation=_wrap_turn(h.rotation + at_target - at_position)))
        elif isinstance(h, CageHandle):
            finals = h.targets if h.targets is not None else [tuple(v) for v in old(np.asarray(h.vertices, dtype=np.float64))]
            out.append(replace(h, targets=carried(finals)))
        elif h.targets is not None:
            start, middle, end = carried(h.targets)
            out.append(replace(h, targets=(start, middle, end)))
        else:
            out.append(h)
    return Handles(tuple(out), replace(doc.options, up=new_up))


def _up_of(up: Level | LonLat | Moebius) -> LonLat:
    """``up`` as ``[lon, lat]``: a Level's, a pair's, or the direction a levelling turn takes to the zenith."""
    if isinstance(up, Level):
        return up.up
    if isinstance(up, Moebius):
        lon, lat = up.inverse(np.array([0.0, 90.0]))
        found = (float(lon), float(lat))
        if lat <= 0 or not Moebius.levelling(found).isclose(up, 1e-7):
            raise ValueError("the rotation is not a levelling: it also turns about the vertical (a levelling keeps the yaw)")
        return found
    lon, lat = (float(v) for v in up)
    return (lon, lat)


def _wrap_turn(angle: float) -> float:
    """An angle in degrees brought into ``(-180, 180]``."""
    out = math.fmod(angle, 360.0)
    if out > 180.0:
        out -= 360.0
    elif out <= -180.0:
        out += 360.0
    return out


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


def _scores(
    normals: FloatArray,
    ends_a: FloatArray,
    ends_b: FloatArray,
    along: FloatArray,
    spans: FloatArray,
    v: FloatArray,
    sigma: FloatArray,
    cap: float,
    polar: float,
) -> FloatArray:
    """Each candidate's score, ``Σ 1 / σ_i`` over the arcs that vote for it (:func:`level`'s ``votes``), shape (m,).

    The same sums as over the whole ``(k, m)`` table of votes: the normals' dot products are
    taken for all of it, the rest (the other dot products too) only where an arc's circle
    passes within ``cap`` of the candidate and within :data:`INLIER_SIGMAS` of its own errors
    (few do), and the sums add the voters in the arcs' order.

    Parameters
    ----------
    normals, ends_a, ends_b, along : ndarray of float64, shape (k, 3)
        The arcs' normals, starts, ends, and tangents at their starts.
    spans : ndarray of float64, shape (k,)
        Lengths, radians.
    v : ndarray of float64, shape (3, m)
        Candidate directions as columns.
    sigma : ndarray of float64, shape (k,)
    cap, polar : float
        The sine of :data:`INLIER_DISTANCE` and the cosine of :data:`POLAR_CAP`.
    """
    v = np.ascontiguousarray(v)  # einsum is several times slower on a transposed view
    # numpy's loop, not BLAS: BLAS in threads stalls on this thin product when the cores are busy
    dots = np.abs(np.einsum("ij,jk->ik", normals, v))
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
    start, tangent, end = ((p[:, 0][rows] * vx + p[:, 2][rows] * vz) + p[:, 1][rows] * vy for p in (ends_a, along, ends_b))
    t = np.arctan2(tangent, start)  # the angle along each circle of the point nearest to v
    opposite = np.where(t > 0, t - np.pi, t + np.pi)  # and of the point nearest to -v
    span = spans[rows]
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


def level(
    image: NDArray,
    *,
    suggestions: Sequence[Suggestion] | None = None,
    min_edges: int = 4,
    max_tilt: float = MAX_TILT,
) -> Level:
    """Estimate how far the camera was from level, from the vertical edges of the panorama.

    Parameters
    ----------
    image : ndarray, shape (H, 2H) or (H, 2H, C)
        Equirectangular panorama (as for :func:`omniwidget.detect.lines.suggest_lines`).
    suggestions : sequence of Suggestion, optional
        The lines to look among; by default every line :func:`suggest_lines` finds.
    min_edges : int
        Fewest distinct vertical edges to trust, ``>= 2``.
    max_tilt : float
        Farthest from the zenith the vertical is looked for, degrees, in ``(0, 90)``.

    Returns
    -------
    Level

    Raises
    ------
    LevelError
        If fewer than ``min_edges`` vertical edges are found, if they do not fix the
        vertical (all in one plane), or if they disagree on it.
    ImageError
        If ``image`` is not a usable panorama.
    """
    if isinstance(min_edges, bool) or not isinstance(min_edges, int | np.integer) or min_edges < 2:
        raise ValueError(f"min_edges must be an integer of at least 2, got {min_edges!r}")
    if isinstance(max_tilt, bool) or not isinstance(max_tilt, int | float | np.integer | np.floating) or not 0 < max_tilt < 90:
        raise ValueError(f"max_tilt must be a number of degrees in (0, 90), got {max_tilt!r}")
    if suggestions is None:
        suggestions = suggest_lines(image, max_lines=None)
    else:
        check_detectable(image)  # the same checks of the image (not its grey copy: the suggestions are found)
    too_few = "found {found} vertical edge{s}, need at least {need}: the panorama shows too few vertical lines to level it"
    candidates = [s for s in suggestions if s.length >= MIN_EDGE_LENGTH]
    if candidates:
        normals, lengths = _normals(candidates)
        near = np.abs(normals[:, 2]) <= math.sin(math.radians(max_tilt)) + 1e-12  # the circle passes within max_tilt of the zenith
        candidates = [s for s, ok in zip(candidates, near, strict=True) if ok]
        normals, lengths = normals[near], lengths[near]
    if len(candidates) < 2:
        raise LevelError(too_few.format(found=len(candidates), s="" if len(candidates) == 1 else "s", need=min_edges))
    accuracy = ENDPOINT_PX * 2 * math.pi / min(image.shape[1], DETECT_WIDTH)  # the width the lines were found at
    ends = [coords.lonlat_to_xyz(np.array([s.start, s.end], dtype=np.float64)) for s in candidates]
    mids = np.array([(p + q) / np.linalg.norm(p + q) for p, q in ends])
    cap = math.sin(math.radians(INLIER_DISTANCE))
    contrast = np.array([s.contrast for s in candidates])

    ends_a = np.array([p for p, _ in ends])
    ends_b = np.array([q for _, q in ends])
    polar = math.cos(math.radians(POLAR_CAP))
    along = np.cross(normals, ends_a)  # with ends_a, the frame of each arc's plane
    spans = np.radians(lengths)

    def votes(v: FloatArray, sigma: FloatArray) -> NDArray[np.bool_]:
        """Which arcs vote for each candidate (columns of ``v``, shape (3, m)): (k, m)."""
        r = np.arcsin(np.clip(np.abs(normals @ v), 0.0, 1.0))
        far = ~_passes_by(ends_a, along, spans, v) & (np.maximum(np.abs(ends_a @ v), np.abs(ends_b @ v)) < polar)
        return (r < INLIER_SIGMAS * sigma[:, None]) & (r < cap) & far

    def inliers_of(v: FloatArray) -> tuple[NDArray[np.bool_], FloatArray]:
        sigma = _sigma(normals, mids, lengths, contrast, v, accuracy)
        return votes(v[:, None], sigma)[:, 0], sigma

    cos_tilt = math.cos(math.radians(max_tilt))
    i, j = np.triu_indices(len(candidates), 1)
    v = np.cross(normals[i], normals[j])
    size = np.linalg.norm(v, axis=1)
    ok = size > math.sin(math.radians(5.0))  # planes that cross at a good angle
    v = v[ok] / size[ok, None]
    v *= np.where(v[:, 2] < 0, -1.0, 1.0)[:, None]
    v = v[v[:, 2] >= cos_tilt]
    if len(v) == 0:
        raise LevelError(too_few.format(found=0, s="s", need=min_edges))
    zenith = np.array([0.0, 0.0, 1.0])
    sigma_z = _sigma(normals, mids, lengths, contrast, zenith, accuracy)  # the errors hardly change within max_tilt of the zenith
    scores = np.concatenate(
        [_scores(normals, ends_a, ends_b, along, spans, block.T, sigma_z, cap, polar) for block in np.array_split(v, max(1, len(v) // CANDIDATES_PER_BLOCK))]
    )
    best = v[int(np.argmax(scores))]
    inliers, sigma = inliers_of(best)
    for _ in range(3):
        if inliers.sum() < 2:
            break
        v = _refit(normals[inliers], sigma[inliers], best)
        inliers, sigma = inliers_of(v)
        best = v
    v = best
    found = _distinct_planes(normals[inliers])
    if found < min_edges:
        raise LevelError(too_few.format(found=found, s="" if found == 1 else "s", need=min_edges))
    spread = np.linalg.eigvalsh(normals[inliers].T @ normals[inliers])
    if spread[1] < 0.02 * spread[2]:
        raise LevelError(f"the {found} vertical edges found lie nearly in one plane through the camera, so they do not fix where up is")
    r = _residuals(normals[inliers], v)
    chi = math.sqrt(float(np.mean((r / sigma[inliers]) ** 2)))
    residual = math.degrees(math.sqrt(float(np.mean(r**2))))
    if chi > MAX_RESIDUAL:
        raise LevelError(
            f"the {found} vertical edges found disagree on where up is (by {residual:.2f}° on average), so the panorama is not levelled"
        )
    lon, lat = coords.xyz_to_lonlat(v)
    up = (float(lon), float(lat))
    pitch, roll = up_to_pitch_roll(up)
    return Level(pitch=pitch, roll=roll, up=up, edges=tuple(s for s, ok in zip(candidates, inliers, strict=True) if ok), residual=residual)
