"""From handles to the blend's controls and the weights' boundary conditions (Sec. 3.3, 3.5, 4).

Every Möbius map of the blend is a *control*: one per point handle, one per line (after
crossing lines are split into four, Sec. 4), one per cage vertex. The bounded biharmonic
weights are pinned on points of the sphere at the handles' *final* positions, because the
blend of eq. (2) is an inverse map:

- a point handle: weight 1 at its target;
- a line: weight 1 at ``samples`` points of its output image (its own map applied to the
  input geodesic); an endpoint shared by ``n`` lines (a *joint*) carries ``1 / n`` for each;
- a cage: weight 1 at each vertex for that vertex's control; along each edge, sampled
  ``samples`` times, the two end vertices' weights vary linearly;
- every other control: weight 0 at all of these points.

With the still background (``options.anchor``, the default) a point also holds
its map on a small disk (:data:`POINT_HOLD`), a cage's vertex maps share the cage's best
rotation (``CageHandle.vertex_maps(carry=True)``; each kind's part is in :mod:`.kinds`), a rectified line too long for one map is
cut into pieces on one straight segment (:func:`split_line`), and a line over a pole is
kept as it is (:data:`POLE_LATITUDE`). ``"anchor": null`` is the paper's method exactly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import whole_number
from .._lazy import lazy
from ..document.handles import Handles, LineHandle
from ..sphere import coords
from ..sphere.arcs import arc_crossing
from ..sphere.moebius import Moebius
from .kinds import POINT_HOLD, Control, Part, Rows, kind_of
from .limits import check_samples, check_weights
from .rectify import Bone, RectifySolution, near_vertical, solve_bones

if TYPE_CHECKING:
    from scipy import spatial
else:
    spatial = lazy("scipy.spatial")

__all__ = [
    "JOINT_DISTANCE",
    "LINE_TOLERANCE",
    "POINT_HOLD",
    "SAMPLES",
    "Constraints",
    "Control",
    "build_constraints",
    "split_line",
]

#: Samples per line and per cage edge (the paper's 50).
SAMPLES = 50

#: Line endpoints closer than this (degrees) merge into one joint: the authors' 2π/150 rad.
JOINT_DISTANCE = 360.0 / 150.0
#: How close to an endpoint (degrees) a crossing may be and still split the lines.
CROSSING_MARGIN = 1e-6
#: With the still background a rectified line whose map leaves it farther than this many
#: degrees from its straight output segment (0.11 px at 2048 wide) is cut into pieces, each
#: with its own map, until every piece lies that close (the paper's Fig. 14: one Möbius map
#: cannot straighten a long line).
LINE_TOLERANCE = 0.02
#: The most pieces one line is cut into.
MAX_PIECES = 16
#: A rectified line that climbs to this latitude (degrees, north or south) passes over or
#: close to a pole, where eq. (4) would send its middle far round the pole (a ceiling edge
#: right above the camera): with the still background it is kept as it is (no arc over a
#: pole can be straight in the panorama). Chosen where eq. (4) stops helping: the median
#: latitude where it starts to fold and its distortion jumps (``bench/bench_pole_lines.py``).
POLE_LATITUDE = 75.0


@dataclass(frozen=True)
class Constraints:
    """The blend's controls and the points where their weights are prescribed.

    Attributes
    ----------
    controls : tuple of Control
        ``k`` controls, the columns of the weights.
    points : ndarray of float64, shape (p, 3)
        Unit vectors (final positions) where the weights are prescribed.
    values : ndarray of float64, shape (p, k)
        Prescribed weights at ``points``.
    lines : tuple of (int, ndarray)
        For each line piece, its control index and its input samples ``[lon, lat]`` (s, 2).
    rectified : RectifySolution or None
        With ``options.rectify == "all"`` and at least one rectified line: the solve of
        Sec. 3.4 that placed the lines' control points (:mod:`.rectify`).
    chains : tuple of tuple of int
        Indices into ``lines`` of the pieces that make one straight output segment, in order
        along it: a line cut for its length (:func:`split_line`) is one chain of several
        pieces, every other line piece a chain of one. Straightness is measured per chain.
    disks : tuple of (int, ndarray)
        With the still background: each point handle's control and its target (a unit
        vector, (3,)); the blend holds that control's map exactly within
        :data:`POINT_HOLD` degrees of it.
    cages : tuple of (tuple of int, ndarray)
        Each cage's controls and its output polygon ``[lon, lat]`` (n, 2): with the still
        background only those controls have weight inside it.
    near_pole : tuple of (int, float)
        Rectified lines that climb to :data:`POLE_LATITUDE` or beyond: the handle's index and
        the latitude it reaches (negative in the south). With the still background they are
        kept as they are (an identity map, fixed in Sec. 3.4).
    """

    controls: tuple[Control, ...]
    points: NDArray[np.float64]
    values: NDArray[np.float64]
    lines: tuple[tuple[int, NDArray[np.float64]], ...]
    rectified: RectifySolution | None = None
    chains: tuple[tuple[int, ...], ...] = ()
    disks: tuple[tuple[int, NDArray[np.float64]], ...] = ()
    cages: tuple[tuple[tuple[int, ...], NDArray[np.float64]], ...] = ()
    near_pole: tuple[tuple[int, float], ...] = ()


@dataclass
class _Piece:
    handle: int
    start: NDArray[np.float64]  # unit vectors
    end: NDArray[np.float64]
    line: LineHandle


def _split_crossings(pieces: list[_Piece]) -> list[_Piece]:
    """Split rectified lines at their crossings (Sec. 4), until none cross.

    Pieces are taken in order; each is split at its first crossing with a later piece (both
    are), and its first half is then looked at again. An earlier piece needs no second look:
    it did not cross the two that were split, so it crosses none of their halves. Each piece
    is compared with all later ones at once (:func:`_crossing_candidates`), and only the
    candidates by :func:`~omniwidget.sphere.arcs.arc_crossing` itself: 1,000 lines take
    seconds, not the minutes of comparing every pair again after every split.
    """
    i = 0
    while i < len(pieces):
        a = pieces[i]
        found = None
        if a.line.targets is None:  # explicit targets say where three points go: splitting would change them
            for j in _crossing_candidates(pieces, i):
                b = pieces[j]
                x = arc_crossing(a.start, a.end, b.start, b.end, CROSSING_MARGIN)
                if x is not None:
                    found = j, b, x
                    break
        if found is None:
            i += 1
            continue
        j, b, x = found
        pieces[j : j + 1] = [_Piece(b.handle, b.start, x, b.line), _Piece(b.handle, x, b.end, b.line)]
        pieces[i : i + 1] = [_Piece(a.handle, a.start, x, a.line), _Piece(a.handle, x, a.end, a.line)]
    return pieces


def _crossing_candidates(pieces: list[_Piece], i: int) -> NDArray[np.intp]:
    """The later pieces that may cross piece ``i``, in order: :func:`arc_crossing`'s test for all at once, a little looser."""
    rest = pieces[i + 1 :]
    if not rest:
        return np.empty(0, np.intp)
    a0, a1 = pieces[i].start, pieces[i].end
    b0 = np.array([p.start for p in rest])
    b1 = np.array([p.end for p in rest])
    na = np.cross(a0, a1)
    nb = np.cross(b0, b1)
    axis = np.cross(na, nb)
    norm = np.linalg.norm(axis, axis=1)
    margin, slack = math.radians(CROSSING_MARGIN), 1e-9  # looser than arc_crossing: it has the last word
    limit_a = margin * np.linalg.norm(na) - slack
    limit_b = margin * np.linalg.norm(nb, axis=1) - slack
    may = np.zeros(len(rest), bool)
    for sign in (1.0, -1.0):
        x = axis * (sign / np.maximum(norm, 1e-300))[:, None]
        inside_a = (np.cross(a0, x) @ na > limit_a) & (np.cross(x, a1) @ na > limit_a)
        inside_b = (np.einsum("ij,ij->i", np.cross(b0, x), nb) > limit_b) & (np.einsum("ij,ij->i", np.cross(x, b1), nb) > limit_b)
        may |= inside_a & inside_b
    targets = np.array([p.line.targets is not None for p in rest])
    return np.flatnonzero(may & (norm >= 0.5e-12) & ~targets) + i + 1  # arc_crossing: none below 1e-12


def _joints(pieces: list[_Piece], distance: float, uprights: set[int] | None = None) -> dict[tuple[int, int], int]:
    """Cluster line endpoints closer than ``distance`` degrees; returns (piece, end) -> joint id.

    Each cluster's ends move to their mean direction; where one of them is a piece made
    vertical (``uprights``), to the point of that piece's great circle nearest it, so that
    the vertical edge's own circle is the one made vertical.
    """
    ends = [(i, e) for i, p in enumerate(pieces) if p.line.targets is None for e in (0, 1)]
    xyz = np.array([pieces[i].start if e == 0 else pieces[i].end for i, e in ends]).reshape(-1, 3)
    parent = list(range(len(ends)))

    def root(a: int) -> int:
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    limit = 2 * math.sin(math.radians(distance) / 2)
    if len(ends) > 1:
        # the pairs a little closer than the limit, then the limit itself: the components are those of every pair compared
        for a, b in spatial.cKDTree(xyz).query_pairs(limit * (1 + 1e-9) + 1e-15, output_type="ndarray"):
            if ends[a][0] != ends[b][0] and np.linalg.norm(xyz[a] - xyz[b]) < limit:
                parent[root(a)] = root(b)
    groups: dict[int, list[int]] = {}
    for a in range(len(ends)):
        groups.setdefault(root(a), []).append(a)
    joint_of: dict[tuple[int, int], int] = {}
    for members in groups.values():
        pieces_in = [ends[m][0] for m in members]
        if len(set(pieces_in)) < 2 or len(set(pieces_in)) < len(pieces_in):
            continue  # a lone endpoint, or a line shorter than the joint distance: not a joint
        centre = xyz[members].sum(axis=0)
        upright = next((ends[m][0] for m in members if ends[m][0] in (uprights or set())), None)
        if upright is not None:  # onto the vertical's circle: its input is the edge itself
            normal = np.cross(pieces[upright].start, pieces[upright].end)
            normal /= np.linalg.norm(normal)
            centre -= (centre @ normal) * normal
        centre /= np.linalg.norm(centre)
        jid = len({*joint_of.values()})
        for m in members:
            i, e = ends[m]
            if e == 0:
                pieces[i].start = centre
            else:
                pieces[i].end = centre
            joint_of[(i, e)] = jid
    return joint_of


def _off_chord(curve: NDArray[np.float64], a: NDArray[np.float64], b: NDArray[np.float64]) -> float:
    """Largest distance (degrees, in the lon/lat plane) of a curve from the straight line through ``a`` and ``b``.

    ``curve`` (n, 2) has its longitudes unwrapped near ``a``; ``a`` and ``b`` (2,) are in that frame.
    """
    chord = b - a
    normal = np.array([-chord[1], chord[0]]) / max(float(np.hypot(*chord)), 1e-300)
    return float(np.max(np.abs((curve - a) @ normal)))


def split_line(
    moebius: Moebius, start: ArrayLike, end: ArrayLike, tolerance: float = LINE_TOLERANCE, max_pieces: int = MAX_PIECES
) -> list[tuple[NDArray[np.float64], NDArray[np.float64], Moebius]]:
    """Cut a line that one Möbius map cannot straighten into pieces, each with its own map onto one straight segment.

    Parameters
    ----------
    moebius : Moebius
        The line's map (eq. 4's, or Sec. 3.4's): its output segment runs from where it puts
        ``start`` to where it puts ``end``, straight in the equirectangular image.
    start, end : array_like, shape (2,)
        The line's input ends, ``[lon, lat]`` in degrees.
    tolerance : float
        Degrees: the largest distance of the line's image from its segment that is left.
    max_pieces : int

    Returns
    -------
    list of (ndarray, ndarray, Moebius)
        Each piece's input start and end ``[lon, lat]`` (2,) and its map, in order along the
        line; ``[(start, end, moebius)]`` when the map alone is within ``tolerance``.

    Notes
    -----
    A Möbius map sends the line's great circle to a circle of the sphere, and a circle
    through three points of a straight segment of the image stays near it only over a short
    arc. With ``n`` pieces, the piece ends and middles (the line cut into equal arcs) go to where
    ``moebius`` puts them, moved across onto the segment (projected in the lon/lat plane):
    each piece's map is then a small correction of the line's own, the pieces meet at their
    ends, and together they run along one segment. The smallest ``n`` that leaves every
    piece within ``tolerance`` is taken.
    """
    start, end = np.asarray(start, np.float64), np.asarray(end, np.float64)
    t = np.linspace(0.0, 1.0, 101)
    whole = moebius(coords.geodesic(start, end, t))
    whole[:, 0] = np.unwrap(whole[:, 0], period=360.0)  # along the line's image, which may span more than 180°
    a, b = whole[0], whole[-1]

    def image(m: Moebius, lonlat: NDArray) -> NDArray:
        out = m(lonlat)
        out[:, 0] = np.unwrap(out[:, 0], period=360.0)
        out[:, 0] += 360.0 * np.round((whole[np.argmin(coords.angular_distance(whole, out[0]))][0] - out[0, 0]) / 360.0)
        return out

    if _off_chord(whole, a, b) <= tolerance:
        return [(start, end, moebius)]
    chord = b - a
    pieces: list[tuple[NDArray[np.float64], NDArray[np.float64], Moebius]] = []
    p, q = coords.lonlat_to_xyz(start), coords.lonlat_to_xyz(end)
    angle = math.acos(min(max(float(p @ q), -1.0), 1.0))
    across = (q - math.cos(angle) * p) / math.sin(angle)
    for n in range(2, max_pieces + 1):
        turn = np.linspace(0.0, angle, 2 * n + 1)[:, None]  # equal steps of arc
        knots = coords.xyz_to_lonlat(np.cos(turn) * p + np.sin(turn) * across)
        knots[0], knots[-1] = start, end
        onto = image(moebius, knots)
        onto = a + np.outer((onto - a) @ chord / (chord @ chord), chord)  # across onto the segment
        pieces = [
            (knots[2 * j], knots[2 * j + 2], Moebius.from_points(knots[2 * j : 2 * j + 3], onto[2 * j : 2 * j + 3])) for j in range(n)
        ]
        worst = max(_off_chord(image(m, coords.geodesic(p, q, t)), a, b) for p, q, m in pieces)
        if worst <= tolerance:
            break
    return pieces


def build_constraints(
    handles: Handles, *, samples: int = SAMPLES, joint_distance: float = JOINT_DISTANCE, upright: bool = False
) -> Constraints:
    """The controls of a handles document and the boundary conditions of their weights.

    The steps, in order: the lines cut at their crossings (Sec. 4), their ends joined, the
    rectified ones placed together (Sec. 3.4), each line piece cut for its length; then
    every handle adds its controls and prescribed weights through its kind
    (:mod:`.kinds`), and the joints are shared among the lines that meet there. What the
    still background changes (``options.anchor`` set) is decided by one flag, read here:
    lines over a pole are kept as they are (:func:`_lines_cut_at_crossings`), long
    rectified lines cut into pieces (:func:`_parts_by_line`), and the kinds hold points on
    a disk and carry a cage's inside by its rotation (:class:`~.kinds.Rows`).

    Parameters
    ----------
    handles : Handles
    samples : int
        Points per line and per cage edge, endpoints included (at least 2).
    joint_distance : float
        Degrees; line endpoints closer than this become one joint.
    upright : bool
        The input is levelled (the method of a document with ``options.up``): a rectified
        line whose great circle passes within :data:`~omniwidget.method.rectify.UPRIGHT_TOLERANCE`
        of the zenith is a vertical edge, made vertical by Sec. 3.4 (:attr:`Bone.upright`).

    Returns
    -------
    Constraints
    """
    samples = check_samples(whole_number(samples, "samples", 2))
    t = np.linspace(0.0, 1.0, samples)
    background = handles.options.anchor is not None
    near_pole = _near_pole(handles)
    pieces = _lines_cut_at_crossings(handles, {i for i, _ in near_pole} if background else set())
    # the weights' size known so far (a control and samples per piece), before the costlier steps
    check_weights(len(pieces) * (samples - 1), len(pieces))
    uprights = _uprights(pieces) if upright else set()
    joint_of = _joints(pieces, joint_distance, uprights)
    solution = _rectify_all(handles, pieces, joint_of, t, uprights) if handles.options.rectify == "all" else None
    rows = Rows(t, background, _parts_by_line(pieces, solution, background), joint_of)
    for i, h in enumerate(handles.handles):
        kind_of(h).add_controls(i, h, rows)
    rows.share_joints()
    points, values = rows.values()
    return Constraints(
        tuple(rows.controls),
        points,
        values,
        tuple(rows.lines),
        solution,
        tuple(rows.chains),
        tuple(rows.disks),
        tuple(rows.cages),
        near_pole,
    )


def _near_pole(handles: Handles) -> tuple[tuple[int, float], ...]:
    """The rectified lines that climb to :data:`POLE_LATITUDE` or beyond: index and signed latitude."""
    tops = [(i, _pole_latitude(h)) for i, h in enumerate(handles.handles) if isinstance(h, LineHandle)]
    return tuple((i, top) for i, top in tops if top)


def _lines_cut_at_crossings(handles: Handles, kept: set[int]) -> list[_Piece]:
    """Every line as a piece, the lines in ``kept`` not rectified (kept as they are), then cut at their crossings (Sec. 4)."""
    pieces = [
        _Piece(i, coords.lonlat_to_xyz(h.start), coords.lonlat_to_xyz(h.end), replace(h, rectify=False) if i in kept else h)
        for i, h in enumerate(handles.handles)
        if isinstance(h, LineHandle)
    ]
    return _split_crossings(pieces)


def _uprights(pieces: list[_Piece]) -> set[int]:
    """The rectified pieces (without explicit targets) near a vertical great circle: the levelled input's vertical edges."""
    return {k for k, p in enumerate(pieces) if p.line.rectify and p.line.targets is None and near_vertical(p.line.start, p.line.end)}


def _parts_by_line(pieces: list[_Piece], solution: RectifySolution | None, background: bool) -> dict[int, list[tuple[int, list[Part]]]]:
    """For each line handle, its pieces in order and each piece's maps (:func:`_line_parts`)."""
    out: dict[int, list[tuple[int, list[Part]]]] = {}
    for k, piece in enumerate(pieces):
        targets = solution.targets[k] if solution is not None else None
        out.setdefault(piece.handle, []).append((k, _line_parts(piece.line, piece, targets, background)))
    return out


def _pole_latitude(h: LineHandle) -> float:
    """The latitude a rectified line climbs to when that is :data:`POLE_LATITUDE` or more (signed), else 0."""
    if h.targets is not None or not h.rectify:
        return 0.0
    top = coords.arc_max_abs_lat(h.start, h.end)
    if top < POLE_LATITUDE:
        return 0.0
    middle = coords.geodesic(h.start, h.end, np.linspace(0.0, 1.0, 33))[:, 1]
    return top if middle[np.argmax(np.abs(middle))] > 0 else -top


def _line_parts(h: LineHandle, piece: _Piece, targets: NDArray[np.float64] | None, background: bool) -> list[Part]:
    """A line piece's map, cut for its length (:func:`split_line`) where the still background is on and the line is rectified."""
    start, end = coords.xyz_to_lonlat(piece.start), coords.xyz_to_lonlat(piece.end)
    # explicit targets keep the handle as drawn; otherwise the piece's (split, snapped) ends
    if h.targets is not None:
        line = h
    elif targets is not None:
        (s_lon, s_lat), (m_lon, m_lat), (e_lon, e_lat) = targets  # the piece's three control points
        line = LineHandle(tuple(start), tuple(end), rectify=False, targets=((s_lon, s_lat), (m_lon, m_lat), (e_lon, e_lat)))
    else:
        line = LineHandle(tuple(start), tuple(end), rectify=h.rectify)
    m = line.moebius()
    if background and h.targets is None and h.rectify:
        return split_line(m, start, end)
    return [(start, end, m)]


def _rectify_all(
    handles: Handles, pieces: list[_Piece], joint_of: dict[tuple[int, int], int], t: NDArray, uprights: set[int] | None = None
) -> RectifySolution | None:
    """Sec. 3.4 for the rectified line pieces; the other handles take part as they are (their kinds' anchors)."""
    free = [p.line.rectify and p.line.targets is None for p in pieces]
    if not any(free):
        return None
    bones = []
    for k, piece in enumerate(pieces):
        start, end = coords.xyz_to_lonlat(piece.start), coords.xyz_to_lonlat(piece.end)
        outputs = None
        if not free[k]:
            outputs = piece.line.moebius()(coords.geodesic(start, end, t))  # its targets, or the identity
        joints = (joint_of.get((k, 0)), joint_of.get((k, 1)))
        bones.append(Bone(tuple(start), tuple(end), free[k], joints, outputs, free[k] and k in (uprights or set())))
    anchors = [anchor for h in handles.handles for anchor in kind_of(h).anchors(h, t)]
    return solve_bones(bones, anchors, samples=len(t), keep="endpoints" if handles.options.anchor is None else "sphere")
