"""Rectify all lines at once: the optimal control-point positions of Sec. 3.4, eqs. (5)-(12).

Rectifying each line by eq. (4) alone keeps its endpoints and pulls its midpoint onto
their chord, which makes close lines cross (the paper's Fig. 6). Here the output
``[lon, lat]`` of every rectified line's three control points are unknowns of one linear
least-squares problem, in the equirectangular plane:

- relative positions (eqs. 5-8): for every sample ``i`` of a line ``k`` and every sample
  ``j`` of another handle ``l`` closer than ``S_k / 4`` (``S_k`` the distance between
  ``k``'s endpoints), their output offset should equal their input offset, with weight
  ``(1/20)(1 - 4 r / S_k)^4``. A rectified line's output samples lie on the chord of its
  output endpoints (``(1 - t) P1 + t P3``); the samples of handles that are not solved for
  (lines that keep their map, point handles, cage edges) are where their maps put them;
- rectification (eq. 9, weight 100): the midpoint on the middle of the endpoints;
- keep in place (eq. 10, weight 0.3): each endpoint where the person put it; with the
  still background (``keep="sphere"``, see :func:`solve_bones`) instead: the sphere near
  the line where it was;
- joints (eq. 11): the authors tie joined endpoints with weight 1000; here their
  endpoints were already snapped to one point, so each joint is a single unknown (the
  weight's limit) and a joint cannot open at all.

All terms are in displacement form (output minus input), so longitudes are unwrapped per
line and nothing depends on where the ±180° seam falls. The longitude and latitude
problems share one symmetric positive definite matrix (every solved endpoint has a
keep-in-place term), factored once and solved for both; with ``keep="sphere"`` the motion
of the sphere ties them, and one system of twice the size is solved.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import whole_number
from .._lazy import lazy
from ..sphere import arcs, coords
from ..sphere.moebius import Moebius

if TYPE_CHECKING:
    import scipy.sparse as sp
    from scipy import spatial
else:
    spatial = lazy("scipy.spatial")
    sp = lazy("scipy.sparse")

__all__ = [
    "UPRIGHT_TOLERANCE",
    "near_vertical",
    "KEEP_WEIGHT",
    "MOTION_WEIGHT",
    "NEAR_LINE",
    "RECTIFY_WEIGHT",
    "RELATIVE_WEIGHT",
    "Anchor",
    "Bone",
    "RectifySolution",
    "line_neighbourhood",
    "motion_metric",
    "solve_bones",
]

#: Eq. (9): weight of a rectified line's midpoint on the middle of its endpoints.
RECTIFY_WEIGHT = 100.0
#: With ``keep="points"`` or ``"sphere"`` the middle's place is kept too, against eq. (9):
#: that weight is then this many times larger, so that the line stays straight to about 1e-6 degrees.
LEAST_MOTION_STIFFNESS = 1e6
#: Eq. (10): weight of each solved endpoint staying where it was.
KEEP_WEIGHT = 0.3
#: Eq. (8): the relative-position weight at distance 0.
RELATIVE_WEIGHT = 1.0 / 20.0
#: With ``keep="sphere"``: the sphere within this many degrees of a line is what its map
#: should move least (the choice measured best, ``bench/bench_line_maps.py``).
NEAR_LINE = 4.0
#: With ``keep="sphere"``: the weight of that motion (mean squared, degrees), 10 times an
#: endpoint's :data:`KEEP_WEIGHT`. More outweighs eq. (8) where lines meet, as in Fig. 6: the
#: sides' tops come up against the top edge, and then fold (bench/RESULTS.md, "One place per kind of handle").
MOTION_WEIGHT = 10 * KEEP_WEIGHT
#: With ``keep="sphere"``: an endpoint's keep weight is this many times :data:`KEEP_WEIGHT`. A line's least-motion map
#: moves its ends, and the unmarked edge past them kinks there; held harder they move less (bench/RESULTS.md,
#: ``END_KEEP``). Where that makes lines cross in the output (Fig. 6), those lines' ends are held as the middle is.
END_KEEP = 10.0


#: Degrees: in a levelled panorama a rectified line whose great circle passes this close to the zenith is a vertical
#: edge, and Sec. 3.4 makes it vertical (:attr:`Bone.upright`): the tolerance of the detector's vertical kind.
UPRIGHT_TOLERANCE = 1.0


def near_vertical(start: ArrayLike, end: ArrayLike, tolerance: float = UPRIGHT_TOLERANCE) -> bool:
    """Whether the great circle through two ``[lon, lat]`` points (degrees) passes within ``tolerance`` degrees of the zenith."""
    a, b = coords.lonlat_to_xyz(np.asarray([start, end], dtype=np.float64))
    normal = np.cross(a, b)
    size = float(np.linalg.norm(normal))
    return size > 0 and abs(float(normal[2])) / size <= math.sin(math.radians(tolerance))


@dataclass(frozen=True)
class Bone:
    """A line (or a piece of one, after crossings are split) in the solve.

    Attributes
    ----------
    start, end : tuple of float
        Input ``[lon, lat]`` in degrees (joined ends already snapped together).
    free : bool
        Solved for (a rectified line) or kept (its output is ``outputs``).
    joints : tuple of (int or None, int or None)
        Joint ids of the start and end: equal ids are one point.
    outputs : ndarray of float64, shape (s, 2) or None
        For a kept bone, where its ``s`` samples (``geodesic(start, end, linspace(0, 1, s))``) land.
    upright : bool
        A free bone made vertical: its three control points' output longitudes held equal
        (with the weight of its straightness), so that it comes out along a meridian while
        its joints move (a levelled panorama's vertical edges, :data:`UPRIGHT_TOLERANCE`).
    """

    start: tuple[float, float]
    end: tuple[float, float]
    free: bool
    joints: tuple[int | None, int | None] = (None, None)
    outputs: NDArray[np.float64] | None = None
    upright: bool = False


@dataclass(frozen=True)
class Anchor:
    """Samples of a handle that is not solved for (a point handle, a cage edge) and where they go.

    Attributes
    ----------
    inputs, outputs : ndarray of float64, shape (s, 2)
        ``[lon, lat]`` in degrees, in order along the handle (one row for a point).
    """

    inputs: NDArray[np.float64]
    outputs: NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class RectifySolution:
    """The solved control points.

    Attributes
    ----------
    targets : list of ndarray or None
        Per bone: the output start, middle and end ``[lon, lat]`` (3, 2) of a free bone,
        None for a kept one.
    matrix : scipy.sparse.csr_matrix, shape (n, n)
        The normal matrix of the least-squares problem (one coordinate), for inspection.
    displacement : float
        Mean distance in degrees between the solved endpoints and their input positions.
    """

    targets: list[NDArray[np.float64] | None]
    matrix: sp.csr_matrix
    displacement: float


class _Rows:
    """Residual rows ``Σ coef · x + const`` (lon and lat constants apart), weighted, in COO form."""

    def __init__(self) -> None:
        self.row: list[NDArray] = []
        self.col: list[NDArray] = []
        self.val: list[NDArray] = []
        self.const: list[NDArray] = []  # (r, 2)
        self.weight: list[NDArray] = []
        self.count = 0

    def add(self, entries: Sequence[tuple[NDArray, NDArray]], const: NDArray, weight: NDArray) -> None:
        """Add ``r`` rows; each entry is (variable index per row, coefficient per row), -1 = none."""
        r = len(weight)
        ids = np.arange(self.count, self.count + r)
        for var, coef in entries:
            var, coef = np.broadcast_to(var, (r,)), np.broadcast_to(coef, (r,))
            used = var >= 0
            self.row.append(ids[used])
            self.col.append(var[used])
            self.val.append(coef[used])
        self.const.append(np.broadcast_to(const, (r, 2)))
        self.weight.append(np.broadcast_to(weight, (r,)))
        self.count += r


def _slots(bones: Sequence[Bone]) -> tuple[NDArray, NDArray, int]:
    """Unknown index of each free bone's (start, middle, end), -1 where kept, and the known values.

    Returns ``var`` (b, 3) int, ``known`` (b, 3, 2) float (each free bone's control points in
    its own unwrapped frame; a joint with a kept bone takes that bone's output), and the
    number of unknowns.
    """
    var = np.full((len(bones), 3), -1, dtype=np.int64)
    known = np.zeros((len(bones), 3, 2))
    fixed_joint: dict[int, NDArray] = {}
    for b in bones:
        if not b.free:
            for e, j in ((0, b.joints[0]), (-1, b.joints[1])):
                if j is not None:
                    fixed_joint[j] = _kept_outputs(b)[e]
    joint_var: dict[int, int] = {}
    n = 0
    for k, b in enumerate(bones):
        if not b.free:
            continue
        known[k] = _inputs(b)
        for s, j in ((0, b.joints[0]), (2, b.joints[1])):
            if j is not None and j in fixed_joint:
                out = fixed_joint[j]
                known[k, s] = (coords.unwrap_lon(out[0], known[k, s, 0]), out[1])  # a known output, not an unknown
            elif j is not None and j in joint_var:
                var[k, s] = joint_var[j]
            else:
                var[k, s] = n
                if j is not None:
                    joint_var[j] = n
                n += 1
        var[k, 1] = n
        n += 1
    return var, known, n


def _kept_outputs(bone: Bone) -> NDArray[np.float64]:
    """A kept bone's ``outputs``; ValueError for one without them."""
    if bone.outputs is None:
        raise ValueError(f"a kept bone needs its outputs, got none for the bone from {bone.start} to {bone.end}")
    return bone.outputs


def _along(points: NDArray[np.float64]) -> float:
    """Where the middle control point lies along the chord of the other two: the parameter of its projection, in [0.2, 0.8].

    ``points`` is (3, 2): start, middle, end in one unwrapped lon/lat frame.
    """
    chord = points[2] - points[0]
    length = float(chord @ chord)
    t = float((points[1] - points[0]) @ chord / length) if length > 0 else 0.5
    return min(max(t, 0.2), 0.8)


def line_neighbourhood(
    start: ArrayLike, end: ArrayLike, radius: float, step: float = 0.5
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Points of the sphere within ``radius`` degrees of the geodesic from ``start`` to ``end``, with their areas.

    Parameters
    ----------
    start, end : array_like, shape (2,)
        ``[lon, lat]`` in degrees, neither equal nor antipodal.
    radius : float
        Degrees, more than 0.
    step : float
        Grid spacing in degrees, along the line and across it.

    Returns
    -------
    xyz : ndarray of float64, shape (m, 3)
        Unit vectors of a grid in the frame where the line runs along the equator.
    area : ndarray of float64, shape (m,)
        Their share of the neighbourhood's area (summing to 1).
    """
    if not (radius > 0 and step > 0):
        raise ValueError(f"radius and step must be positive, got {radius!r} and {step!r}")
    a, b = coords.lonlat_to_xyz(start), coords.lonlat_to_xyz(end)
    normal = np.cross(a, b)
    if np.linalg.norm(normal) < 1e-12:
        raise ValueError("the line's start and end coincide or are antipodal")
    normal /= np.linalg.norm(normal)
    across = np.cross(normal, a)
    length = math.atan2(float(b @ across), float(b @ a))
    along, off = np.meshgrid(
        np.radians(np.arange(-radius, math.degrees(length) + radius + step / 2, step)),
        np.radians(np.arange(-radius, radius + step / 2, step)),
    )
    near = np.cos(off) * np.cos(along - np.clip(along, 0.0, length)) >= math.cos(math.radians(radius))
    along, off = along[near], off[near]
    xyz = np.cos(off)[:, None] * (np.cos(along)[:, None] * a + np.sin(along)[:, None] * across) + np.sin(off)[:, None] * normal
    return xyz, np.cos(off) / np.cos(off).sum()


def motion_metric(points: ArrayLike, radius: float = NEAR_LINE, step: float = 0.5) -> NDArray[np.float64]:
    """How much a line's map moves the sphere near the line, to second order in its control points' motion.

    Parameters
    ----------
    points : array_like, shape (3, 2)
        The line's start, middle and end ``[lon, lat]`` in degrees, as in its input.
    radius : float
        The part of the sphere within this many degrees of the line (the geodesic from
        start to end) is measured.
    step : float
        Spacing of the measuring grid, degrees.

    Returns
    -------
    ndarray of float64, shape (6, 6)
        ``G`` such that ``d @ G @ d`` is the area-weighted mean of ``|M(p) - p|^2``
        (degrees squared) over that part of the sphere, for the Möbius map ``M`` sending the
        three points to themselves plus ``d``, ordered (lon of start, middle, end, lat of
        start, middle, end), as ``d`` goes to 0.

    Notes
    -----
    A map that straightens a line is fixed by three target points, but the line is just as
    straight for any targets on one straight segment: which point stays and where the
    segment lies are a choice. Its quadratic part (how much the map bends) is fixed by the
    line's own bow; this metric lets the least-squares of :func:`solve_bones` take the
    targets whose map moves the sphere around the line least.
    """
    points = np.asarray(points, dtype=np.float64)
    if points.shape != (3, 2) or not np.all(np.isfinite(points)):
        raise ValueError(f"points must be three finite [lon, lat] rows, got shape {points.shape}")
    grid, area = line_neighbourhood(points[0], points[2], radius, step)
    h = 1e-4  # degrees: one-sided differences of the motion in each of the six coordinates
    jacobian = np.empty((grid.size, 6))
    for j in range(6):
        moved = points.copy()
        moved[j % 3, j // 3] += h
        jacobian[:, j] = ((Moebius.from_points(points, moved).apply_xyz(grid) - grid) * (math.degrees(1.0) / h)).ravel()
    area = np.repeat(area, 3)
    return jacobian.T @ (area[:, None] * jacobian)


def solve_bones(
    bones: Sequence[Bone],
    anchors: Sequence[Anchor] = (),
    samples: int = 50,
    *,
    keep: Literal["endpoints", "points", "sphere"] = "endpoints",
) -> RectifySolution:
    """Solve Sec. 3.4's least squares for the free bones' output control points.

    With ``keep="sphere"`` the free bones' endpoints are held :data:`END_KEEP` times harder
    than their middles; where the lines solved so cross in the output and did not in the
    input, the crossing lines are solved again with their ends held as their middles are.

    Parameters
    ----------
    bones : sequence of Bone
    anchors : sequence of Anchor
        Point handles and cage edges, which keep their own outputs and take part in the
        relative-position terms.
    samples : int
        Samples per bone in the relative-position terms (the paper's 50).
    keep : {"endpoints", "points", "sphere"}
        What each line keeps in place while it is made straight:

        - ``"endpoints"``: eqs. (9)-(10) as the paper writes them: the middle goes to the
          middle of the output chord, the endpoints keep their places (weight
          :data:`KEEP_WEIGHT`);
        - ``"points"``: the middle goes to the point of the output chord at the parameter
          where it lies along the input chord (:data:`LEAST_MOTION_STIFFNESS` times eq. (9)'s
          weight), and all three control points keep their places alike, so the correction
          is shared;
        - ``"sphere"`` (the still background's): as ``"points"``, and the control points
          also move so that the line's map moves the sphere within :data:`NEAR_LINE`
          degrees of the line least (:func:`motion_metric`, weight :data:`MOTION_WEIGHT`).
          That is where the background's weight changes, and there the blend's distortion
          is about the map's motion times the weight's gradient.

    Returns
    -------
    RectifySolution
    """
    samples = whole_number(samples, "samples", 2)
    if keep not in ("endpoints", "points", "sphere"):
        raise ValueError(f'keep must be "endpoints", "points" or "sphere", got {keep!r}')
    ends = np.full(len(bones), END_KEEP if keep == "sphere" else 1.0)
    solution = _solve_bones(bones, anchors, samples, keep, ends)
    if keep == "sphere" and END_KEEP != 1.0:
        crossing = _new_crossings(bones, solution)
        if crossing:
            ends[sorted(crossing)] = 1.0
            solution = _solve_bones(bones, anchors, samples, keep, ends)
    return solution


def _new_crossings(bones: Sequence[Bone], solution: RectifySolution) -> set[int]:
    """The free bones in a pair that crosses in the output (straight between its targets) and not in the input."""
    t = np.linspace(0.0, 1.0, 17)
    inputs = [coords.geodesic(b.start, b.end, t) for b in bones]
    outputs = []
    for b, targets in zip(bones, solution.targets, strict=True):
        if targets is None:
            outputs.append(_kept_outputs(b))
        else:
            start, end = targets[0], targets[2].copy()
            end[0] = coords.unwrap_lon(np.array([end[0]]), start[0])[0]
            outputs.append((1 - t)[:, None] * start + t[:, None] * end)
    before = set(arcs.crossing_pairs(inputs))
    return {k for pair in set(arcs.crossing_pairs(outputs)) - before for k in pair if bones[k].free}


def _solve_bones(bones: Sequence[Bone], anchors: Sequence[Anchor], samples: int, keep: str, ends: NDArray[np.float64]) -> RectifySolution:
    """:func:`solve_bones` with each bone's endpoints' keep weight multiplied by ``ends`` (k,).

    The rows in order: eq. (8) for every close pair of samples, then for each free bone
    eq. (9) and eq. (10); with ``keep="sphere"`` each free bone's motion metric, and each
    upright bone's vertical, join them in the coupled solve.
    """
    var, known, n = _slots(bones)
    taken = _samples_of(bones, anchors, samples, known)
    rows = _Rows()
    _eq8_relative_positions(rows, taken, var, known)
    metrics: list[tuple[int, NDArray[np.float64]]] = []  # keep="sphere": (bone, motion metric)
    for k, b in enumerate(bones):
        if not b.free:
            continue
        _eq9_middle_on_chord(rows, var[k], known[k], keep)
        if keep == "sphere":
            metrics.append((k, motion_metric(_inputs(b), NEAR_LINE)))
        _eq10_keep_in_place(rows, var[k], keep, ends[k])
    q, rhs = _normal_equations(rows, n)
    x = np.zeros((n, 2))
    upright_weight = RECTIFY_WEIGHT * (1.0 if keep == "endpoints" else LEAST_MOTION_STIFFNESS)  # as its straightness
    if n and (metrics or any(b.free and b.upright for b in bones)):
        x = _solve_coupled(q.toarray(), rhs, metrics, var, known, bones, upright_weight)
    elif n:
        x = np.linalg.solve(q.toarray(), rhs)  # n is 3 per line: small and dense is fastest (numpy's LAPACK: see _solve_coupled)
    return _solution(bones, var, known, x, q)


@dataclass(frozen=True)
class _Samples:
    """Every participant's samples in the relative-position terms: the bones', then the anchors'.

    Attributes
    ----------
    inputs, displacement : ndarray of float64, shape (m, 2)
        Input ``[lon, lat]`` (a free bone's unwrapped in its own frame) and, where known
        (kept bones and anchors), output minus input; zero for a free bone's.
    owner : ndarray of int, shape (m,)
        The bone's index, or ``len(bones) + a`` for anchor ``a``.
    param : ndarray of float64, shape (m,)
        The sample's parameter along its owner, 0 to 1.
    free : ndarray of bool, shape (m,)
        Whether it belongs to a free bone (moves with the unknowns).
    span : ndarray of float64, shape (m,)
        Its owner's ``S_k``: the distance between the owner's ends in the lon/lat plane.
    bone : ndarray of int, shape (m,)
        Its owner's bone index (0 for an anchor's: read only where ``free``).
    """

    inputs: NDArray[np.float64]
    displacement: NDArray[np.float64]
    owner: NDArray[np.int64]
    param: NDArray[np.float64]
    free: NDArray[np.bool_]
    span: NDArray[np.float64]
    bone: NDArray[np.int64]


def _span(src: NDArray[np.float64]) -> float:
    """The distance in the lon/lat plane between the first and last samples (0 for one sample)."""
    return float(np.hypot(coords.wrap_lon(src[-1, 0] - src[0, 0]), src[-1, 1] - src[0, 1])) if len(src) > 1 else 0.0


def _offset(outputs: NDArray[np.float64], inputs: NDArray[np.float64]) -> NDArray[np.float64]:
    """Output minus input ``[lon, lat]``, the longitude across the seam the short way."""
    return np.stack([coords.wrap_lon(outputs[:, 0] - inputs[:, 0]), outputs[:, 1] - inputs[:, 1]], axis=1)


def _samples_of(bones: Sequence[Bone], anchors: Sequence[Anchor], samples: int, known: NDArray[np.float64]) -> _Samples:
    """The samples of every bone (``samples`` each, along its geodesic) and of every anchor, as one :class:`_Samples`."""
    t = np.linspace(0.0, 1.0, samples)
    inputs, disp, owner, param, free, spans = [], [], [], [], [], []
    for k, b in enumerate(bones):
        src = coords.geodesic(b.start, b.end, t)
        src[:, 0] = coords.unwrap_lon(src[:, 0], known[k, 0, 0] if b.free else src[0, 0])
        inputs.append(src)
        disp.append(np.zeros((samples, 2)) if b.free else _offset(_kept_outputs(b), src))
        owner.append(np.full(samples, k))
        param.append(t)
        free.append(np.full(samples, b.free))
        spans.append(_span(src))
    for a, anchor in enumerate(anchors):
        src = np.asarray(anchor.inputs, np.float64).reshape(-1, 2)
        inputs.append(src)
        disp.append(_offset(np.asarray(anchor.outputs, np.float64).reshape(-1, 2), src))
        owner.append(np.full(len(src), len(bones) + a))
        param.append(np.linspace(0.0, 1.0, len(src)) if len(src) > 1 else np.zeros(1))
        free.append(np.zeros(len(src), dtype=bool))
        spans.append(_span(src))
    owner_all = np.concatenate(owner)
    return _Samples(
        np.concatenate(inputs),
        np.concatenate(disp),
        owner_all,
        np.concatenate(param),
        np.concatenate(free),
        np.asarray(spans)[owner_all],
        np.where(owner_all < len(bones), owner_all, 0),
    )


def _moved(taken: _Samples, var: NDArray, known: NDArray, idx: NDArray, sign: float) -> tuple[list[tuple[NDArray, NDArray]], NDArray]:
    """Entries and known part of ``sign * displacement`` of samples ``idx``.

    A free bone's sample moves to the chord of its output ends (``(1 - t) P1 + t P3``, with
    x = 0 at ``known``; a slot joined to a kept bone has no unknown and sits in ``known``);
    any other sample by its known displacement.
    """
    is_free = taken.free[idx]
    k, tt = taken.bone[idx], taken.param[idx]
    v0, v2 = np.where(is_free, var[k, 0], -1), np.where(is_free, var[k, 2], -1)
    chord = (1 - tt)[:, None] * known[k, 0] + tt[:, None] * known[k, 2]
    const = np.where(is_free[:, None], chord - taken.inputs[idx], taken.displacement[idx])
    return [(v0, sign * (1 - tt) * is_free), (v2, sign * tt * is_free)], sign * const


def _close_pairs(taken: _Samples) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Every pair ``(i, j)`` of samples of different handles with ``j`` closer to ``i`` than ``S / 4`` (``i``'s owner's span), one of them free."""
    east = np.mod(taken.inputs[:, 0], 360.0)
    east[east >= 360.0] = 0.0  # a tiny negative longitude rounds to 360, outside the periodic box
    plane = np.stack([east, taken.inputs[:, 1] + 90.0], axis=1)
    tree = spatial.cKDTree(plane, boxsize=[360.0, 1e6])  # longitude periodic: the seam is nothing special
    asking = np.flatnonzero(taken.span > 0)
    found = tree.query_ball_point(plane[asking], taken.span[asking] / 4)
    i = np.repeat(asking, [len(f) for f in found])
    j = np.fromiter(itertools.chain.from_iterable(found), dtype=np.int64, count=len(i))
    pair = (taken.owner[i] != taken.owner[j]) & (taken.free[i] | taken.free[j])
    return i[pair], j[pair]


def _eq8_relative_positions(rows: _Rows, taken: _Samples, var: NDArray, known: NDArray) -> None:
    """Eqs. (5)-(8): close samples of different handles keep their offset, weight ``(1/20)(1 - 4 r / S_k)^4``."""
    i, j = _close_pairs(taken)
    if not len(i):
        return
    gap = taken.inputs[i] - taken.inputs[j]
    r = np.hypot(coords.wrap_lon(gap[:, 0]), gap[:, 1])
    w = RELATIVE_WEIGHT * np.clip(1 - 4 * r / taken.span[i], 0.0, None) ** 4
    entries_i, const_i = _moved(taken, var, known, i, 1.0)
    entries_j, const_j = _moved(taken, var, known, j, -1.0)
    rows.add(entries_i + entries_j, const_i + const_j, w)


def _eq9_middle_on_chord(rows: _Rows, v: NDArray, p: NDArray, keep: str) -> None:
    """Eq. (9): a free bone's middle on its output chord, ``middle - ((1 - t) start + t end)``.

    ``t`` is 1/2 in the paper (``keep="endpoints"``); otherwise where the middle lies along
    the input chord (:func:`_along`), held :data:`LEAST_MOTION_STIFFNESS` times harder.
    ``v`` (3,) are the bone's unknowns, ``p`` (3, 2) its known control points.
    """
    tm = 0.5 if keep == "endpoints" else _along(p)
    rows.add(
        [(v[1:2], np.ones(1)), (v[0:1], np.full(1, tm - 1.0)), (v[2:3], np.full(1, -tm))],
        (p[1] - (1.0 - tm) * p[0] - tm * p[2])[None],
        np.full(1, RECTIFY_WEIGHT * (1.0 if keep == "endpoints" else LEAST_MOTION_STIFFNESS)),
    )


def _eq10_keep_in_place(rows: _Rows, v: NDArray, keep: str, ends: float) -> None:
    """Eq. (10): a free bone's endpoints stay where they were (and its middle, unless ``keep="endpoints"``).

    Weight :data:`KEEP_WEIGHT`; with ``keep="sphere"`` the endpoints' times ``ends``.
    """
    for s in (0, 2) if keep == "endpoints" else (0, 1, 2):
        hold = ends if keep == "sphere" and s != 1 else 1.0
        rows.add([(v[s : s + 1], np.ones(1))], np.zeros((1, 2)), np.full(1, KEEP_WEIGHT * hold))


def _normal_equations(rows: _Rows, n: int) -> tuple[sp.csc_matrix, NDArray[np.float64]]:
    """The weighted least squares' normal matrix ``A^T W A`` (n, n) and right-hand side (n, 2), one for lon and lat."""
    a = sp.csr_matrix((np.concatenate(rows.val), (np.concatenate(rows.row), np.concatenate(rows.col))), shape=(rows.count, n))
    w = np.concatenate(rows.weight)
    const = np.concatenate(rows.const)
    return (a.T @ sp.diags(w) @ a).tocsc(), -(a.T @ (w[:, None] * const))


def _solution(bones: Sequence[Bone], var: NDArray, known: NDArray, x: NDArray[np.float64], q: sp.csc_matrix) -> RectifySolution:
    """The free bones' output control points from the unknowns ``x`` (n, 2), longitudes wrapped."""
    targets: list[NDArray[np.float64] | None] = []
    moved_by: list[float] = []
    for k, b in enumerate(bones):
        if not b.free:
            targets.append(None)
            continue
        out = known[k] + np.where(var[k][:, None] >= 0, x[np.maximum(var[k], 0)], 0.0)
        moved_by.extend(coords.angular_distance(out[[0, 2]], known[k][[0, 2]]))
        out[:, 0] = coords.wrap_lon(out[:, 0])
        targets.append(out)
    return RectifySolution(targets, q.tocsr(), float(np.mean(moved_by)) if moved_by else 0.0)


def _inputs(bone: Bone) -> NDArray[np.float64]:
    """A bone's input start, geodesic middle and end, (3, 2), longitudes unwrapped at the start."""
    points = np.stack(
        [np.asarray(bone.start, np.float64), coords.geodesic_midpoint(bone.start, bone.end), np.asarray(bone.end, np.float64)]
    )
    points[:, 0] = coords.unwrap_lon(points[:, 0], points[0, 0])
    return points


def _solve_coupled(
    q: NDArray[np.float64],
    rhs: NDArray[np.float64],
    metrics: Sequence[tuple[int, NDArray[np.float64]]],
    var: NDArray[np.int64],
    known: NDArray[np.float64],
    bones: Sequence[Bone],
    upright_weight: float = 0.0,
) -> NDArray[np.float64]:
    """The least squares with motion metrics, which tie longitude to latitude: one (2n, 2n) system.

    ``q`` (n, n) and ``rhs`` (n, 2) are the separable rows' normal equations (with every
    control point's keep term, so the system is definite); each metric
    adds ``(c + P x) @ (MOTION_WEIGHT G) @ (c + P x)``, where ``c`` is how far a control
    point joined to a kept bone already sits from the input. Returns x, (n, 2).
    """
    n = len(q)
    big = np.zeros((2 * n, 2 * n))
    big[:n, :n] = big[n:, n:] = q
    right = np.concatenate([rhs[:, 0], rhs[:, 1]])
    for k, metric in metrics:
        g = MOTION_WEIGHT * metric
        index = np.concatenate([var[k], np.where(var[k] >= 0, var[k] + n, -1)])
        unknown = index >= 0
        offset = (known[k] - _inputs(bones[k])).T.ravel() * ~unknown  # lon then lat, as in the metric
        big[np.ix_(index[unknown], index[unknown])] += g[np.ix_(unknown, unknown)]
        right[index[unknown]] -= (g @ offset)[unknown]
    for k, b in enumerate(bones):  # an upright bone: its ends' output longitudes those of its middle (longitude only)
        if not (b.free and b.upright):
            continue
        for s in (0, 2):
            coef = {int(var[k, s]): 1.0, int(var[k, 1]): -1.0}
            coef = {i: c for i, c in coef.items() if i >= 0}
            c0 = float(known[k, s, 0] - known[k, 1, 0])
            for i, ci in coef.items():
                right[i] -= upright_weight * ci * c0
                for j, cj in coef.items():
                    big[i, j] += upright_weight * ci * cj
    # numpy's LAPACK, not scipy's: scipy's OpenBLAS threads spin against a busy machine's other work, and the small
    # system took a thousand times longer (bench/RESULTS.md, "The BLAS threads")
    solution = np.linalg.solve(big, right)
    return np.stack([solution[:n], solution[n:]], axis=1)
