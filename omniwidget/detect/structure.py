"""Structure first: which suggested lines are the scene's structure, and a consistent set of them.

The detector (:func:`omniwidget.detect.lines.suggest_lines` with ``structure=False``) finds
every straight edge: a room's corners and the joints of its floor tiles alike, a
building's edges and the mullions of its windows. Rectifying all of them at once asks the
warp for crossing and overlapping lines. This module keeps the structure and leaves the
texture:

- **Kinds** (:func:`line_kinds`). A vertical 3D edge is seen along a great circle through
  the panorama's true vertical ``up`` (found from the lines themselves,
  :func:`omniwidget.detect.vertical.find_up`); a horizontal edge of a room or a street
  goes to one of two horizontal vanishing directions 90° apart, found as the peak of the
  lines' horizontal directions folded onto a quarter turn. Lines of neither are "other".
- **Texture** (:func:`junctions`). A grid of tiles, cobbles, paint or mullions is a family
  of lines that *cross* one another; the structure is where such families *end*: a
  room's corner is where the floor's joints and the wall's stop, a wall's edge where its
  windows stop. So each line counts the lines that cross it (a line broken at a crossing,
  its two pieces ending on it from either side on one great circle, counts as crossing
  it) and those that end on it, and a line crossed more than it bounds is texture. A
  line with parallel neighbours close on either side and bounding nothing is texture
  too, and so is a line much fainter than the strongest edges that bounds nothing.
- **A consistent set** (:func:`choose_structure`). The lines are taken best first
  (structure before "other", then by confidence); each is kept unless it is texture, or
  "other" and short, or crosses a kept line, or runs close beside one along its length
  (the same edge found twice, or two lines that would fight for the same pixels). A kept
  line that only overshoots another kept line's end or body by the detector's error is
  cut back to where they meet, so that no two kept lines cross by the method's own test
  (:func:`omniwidget.sphere.arcs.arc_crossing`: lines that touch at their ends, as a
  box's corner joins three edges, do not cross).

Every drop says why, in words (:class:`StructureChoice`). ``bench/RESULTS.md`` ("Structure
first") gives the figures on generated box rooms and on the photographs.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from ..errors import LevelError
from ..sphere import coords
from ..sphere.arcs import arc_crossing
from . import vertical

if TYPE_CHECKING:
    from .lines import Suggestion

__all__ = [
    "BOUND_WEIGHT",
    "CLOSE_DISTANCE",
    "CLOSE_SHARE",
    "CROSS_MARGIN",
    "END_DISTANCE",
    "FAINT",
    "FAMILY_SIZE",
    "FAMILY_SPACING",
    "KIND_TOLERANCE",
    "Reason",
    "MERGE_DISTANCE",
    "OVERSHOOT",
    "OTHER_MIN_LENGTH",
    "OTHER_WEIGHT",
    "StructureChoice",
    "Junctions",
    "choose_structure",
    "horizontal_directions",
    "junctions",
    "line_kinds",
    "structure_up",
]

FloatArray = NDArray[np.float64]
LonLat = tuple[float, float]

#: The longest lines among which :func:`structure_up` looks for the vertical (level looks among all: the kinds need less).
UP_LINES = 200
#: Degrees: a line is vertical (horizontal) when its great circle passes this close to the vertical (a horizontal vanishing direction).
KIND_TOLERANCE = 1.0
#: The horizontal directions are trusted when the peak (±2°, folded onto 90°) holds at least this share of the non-vertical lines' length.
MIN_HORIZONTAL_SHARE = 0.12
#: Degrees: two arcs cross when they meet at least this far inside both (nearer an end, one ends on the other).
CROSS_MARGIN = 1.0
#: Degrees: an arc's end this close to another arc's circle, and inside it by :data:`END_MARGIN`, ends on that arc.
END_DISTANCE = 1.0
#: Degrees from an arc's own ends within which other lines' ends do not count as ending on it (a corner joins lines at their ends).
END_MARGIN = 1.5
#: Degrees: lines ending on an arc count only when their circles meet its circle at least at this angle.
JUNCTION_ANGLE = 10.0
#: Degrees: two pieces ending on an arc from either side, their circles within this of each other and their ends this close along it, are one line crossing it.
COLLINEAR = 1.0
#: A line crossed by at least this many lines, more than it bounds, is texture (one crossing is a conflict: the better line stays).
TEXTURE_CROSSINGS = 2
#: How much each line ending on an arc (up to :data:`MAX_BOUNDS`) weighs against the lines crossing it.
BOUND_WEIGHT = 0.5
#: Lines ending on an arc from both sides weigh this much more (the corner of two textured faces).
TWO_SIDED_WEIGHT = 1.0
#: The most lines ending on an arc that count.
MAX_BOUNDS = 4
#: Degrees: parallel lines (one vanishing direction) whose circles are within this of each other are neighbours in a family.
FAMILY_SPACING = 8.0
#: A line with at least this many parallel neighbours and bounding at most one line is texture.
FAMILY_SIZE = 4
#: A line fainter than this share of the strongest edges' contrast (the mean of the five strongest) and bounding at most one line is texture.
FAINT = 0.45
#: Degrees from a line at which its two sides are looked at (:func:`side_difference`).
SIDE_OFFSETS = (0.8, 1.6)
#: Points along each line at which its sides are looked at.
SIDE_SAMPLES = 24
#: Colour difference (0-255 levels, RGB distance of the sides' medians) below which a line's two sides look alike: a mark on one surface.
ALIKE = 16.0
#: A line whose sides look alike and bounding at most this many lines is a mark on a surface (texture).
MARK_BOUNDS = 99
#: Colour difference (levels) from which a line's sides count as wholly different surfaces in its rank.
DIFFERENT = 32.0
#: How much of a line's rank its sides' difference makes (with the image): 0 ranks by confidence and kind alone.
SIDE_WEIGHT = 0.5
#: Kind "other" lines shorter than this (degrees) are dropped.
OTHER_MIN_LENGTH = 10.0
#: Kind "other" lines rank with their confidence times this (structure first).
OTHER_WEIGHT = 0.5
#: Degrees: a line lying within this of a kept line ...
CLOSE_DISTANCE = 2.5
#: ... over more than this share of its length (or of the kept line's) is the same edge, or would fight it for the pixels.
CLOSE_SHARE = 0.3
#: Degrees: a line this close to a kept one (the median over where they are near) is the same edge found again.
SAME_EDGE = 1.2
#: Degrees: a line dropped as the same edge as a kept one and lying this close to the kept line's circle (median of its
#: samples; none farther than :data:`SAME_EDGE`) is a piece of it: the kept line is lengthened over it.
MERGE_DISTANCE = 0.5
#: Degrees: a kept line running on past a corner (another kept line's end on it, within :data:`END_DISTANCE`, the
#: two meeting at more than :data:`JUNCTION_ANGLE`) by less than this, and by less than a quarter of its length,
#: stops at the corner: the detector's overshoot, which the method would see as two lines crossing.
OVERSHOOT = 5.0
#: Points sampled along each line for :data:`CLOSE_SHARE`.
CLOSE_SAMPLES = 12


class Reason(str):
    """Why a suggestion was left out: the words (the string itself) and :attr:`kind`, what a count of reasons groups by.

    A ``str`` so that the reason reads, prints and compares as its words; the kind is data,
    never found again in the words.
    """

    kind: str

    def __new__(cls, words: str, kind: str) -> Reason:
        """The reason ``words``, of kind ``kind``."""
        made = super().__new__(cls, words)
        made.kind = kind
        return made

    def __getnewargs__(self) -> tuple[str, str]:  # type: ignore[override]  # str's takes one argument
        return str(self), self.kind


#: The kinds of :class:`Reason` :func:`choose_structure` gives.
TEXTURE = "texture"
CROSSING = "crossing a kept line"
BESIDE = "beside a kept line"
SHORT_OTHER = "short and neither vertical nor horizontal"
BEYOND = "beyond the first ones kept"


@dataclass(frozen=True)
class StructureChoice:
    """What :func:`choose_structure` kept and dropped, and why.

    Attributes
    ----------
    kept : tuple of Suggestion
        The consistent structural set, best first, each with its :attr:`~Suggestion.kind`;
        no two cross, none runs close beside another. Their confidence is their rank: the
        detector's confidence, a kind "other" line's scaled by :data:`OTHER_WEIGHT`, and
        (with the image) by how different its two sides look (:data:`SIDE_WEIGHT`).
    dropped : tuple of (Suggestion, Reason)
        Every other suggestion with the reason it was left, in words ("crosses suggested
        line 3", ...; line numbers count the kept lines from 1), and its kind.
    up : (float, float)
        ``[lon, lat]`` degrees of the true vertical the kinds were judged against.
    up_found : bool
        Whether ``up`` was found from the lines (False: taken as given, or the zenith
        when too few vertical edges were found).
    horizontals : tuple of (float, float)
        The two dominant horizontal vanishing directions (``[lon, lat]``; each also stands
        for its opposite), or empty when the lines show none.
    """

    kept: tuple[Suggestion, ...]
    dropped: tuple[tuple[Suggestion, Reason], ...]
    up: LonLat
    up_found: bool
    horizontals: tuple[LonLat, ...] = ()


@dataclass(frozen=True)
class Junctions:
    """How each arc meets the others (:func:`junctions`), arrays of shape (k,) unless said.

    Attributes
    ----------
    crossed : ndarray of int
        Lines crossing the arc at least :data:`CROSS_MARGIN` inside both, a line broken at
        the crossing (two collinear pieces ending on it from either side) counted once.
    bounds_left, bounds_right : ndarray of int
        Lines ending on the arc from either side of its great circle (not as pieces of a crossing).
    family : ndarray of int
        Parallel neighbours: lines to the same vanishing direction whose circles lie within
        :data:`FAMILY_SPACING` and whose arcs face each other.
    crossing : ndarray of bool, shape (k, k)
        Which pairs cross (symmetric).
    depth : ndarray of float64, shape (k, k)
        How far (radians) inside arc ``i`` circle ``j`` meets it, at the meeting nearer both
        arcs' middles: the distance to the nearer end, negative outside; ``-inf`` for
        circles within 3° of each other.
    """

    crossed: NDArray[np.intp]
    bounds_left: NDArray[np.intp]
    bounds_right: NDArray[np.intp]
    family: NDArray[np.intp]
    crossing: NDArray[np.bool_]
    depth: FloatArray

    @property
    def bounds(self) -> NDArray[np.intp]:
        """Lines ending on each arc, from both sides."""
        return self.bounds_left + self.bounds_right


# --- geometry ------------------------------------------------------------------------


@dataclass(frozen=True)
class _Arcs:
    start: FloatArray  # (k, 3) unit vectors
    end: FloatArray
    normal: FloatArray  # unit normal of each circle, start x end
    along: FloatArray  # unit tangent at the start, normal x start
    length: FloatArray  # radians

    @classmethod
    def of(cls, suggestions: Sequence[Suggestion]) -> _Arcs:
        lonlat = np.array([(s.start, s.end) for s in suggestions], dtype=np.float64).reshape(-1, 2, 2)
        xyz = coords.lonlat_to_xyz(lonlat)
        return cls.between(xyz[:, 0], xyz[:, 1])

    @classmethod
    def between(cls, a: FloatArray, b: FloatArray) -> _Arcs:
        """The arcs from unit vectors ``a`` to ``b``, (k, 3) each."""
        normal = np.cross(a, b)
        size = np.linalg.norm(normal, axis=1)
        normal = normal / np.maximum(size, 1e-300)[:, None]
        length = np.arctan2(size, np.einsum("ij,ij->i", a, b))
        return cls(a, b, normal, np.cross(normal, a), length)

    def position(self, points: FloatArray) -> FloatArray:
        """Angle (radians) along each arc's circle of each point, from its start: (p, 3) -> (p, k)."""
        return np.asarray(np.arctan2(points @ self.along.T, points @ self.start.T))

    def distance(self, points: FloatArray) -> FloatArray:
        """Degrees from each point to each arc (its circle inside it, the nearer end outside), (p, 3) -> (p, k)."""
        t = self.position(points)
        to_circle = np.arcsin(np.clip(np.abs(points @ self.normal.T), 0.0, 1.0))
        to_ends = np.minimum(np.arccos(np.clip(points @ self.start.T, -1.0, 1.0)), np.arccos(np.clip(points @ self.end.T, -1.0, 1.0)))
        return np.degrees(np.where((t >= 0) & (t <= self.length[None]), to_circle, to_ends))

    def samples(self, i: int, count: int) -> FloatArray:
        """``count`` points evenly along arc ``i``, ends included, (count, 3)."""
        t = np.linspace(0.0, float(self.length[i]), count)[:, None]
        return np.asarray(np.cos(t) * self.start[i] + np.sin(t) * self.along[i])


def _unit(v: FloatArray) -> FloatArray:
    return np.asarray(v / np.linalg.norm(v, axis=-1, keepdims=True))


def _frame(up: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Two unit vectors completing ``up`` to a right-handed orthonormal frame (the horizon's axes)."""
    helper = np.array([1.0, 0.0, 0.0]) if abs(up[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = _unit(np.cross(up, helper))
    return e1, np.cross(up, e1)


# --- kinds ---------------------------------------------------------------------------


def _vertical(arcs: _Arcs, up: FloatArray, tolerance: float) -> NDArray[np.bool_]:
    """Arcs on circles through ``±up`` that stop short of it (a floor line sweeping past the nadir is not vertical)."""
    t = arcs.start @ up, arcs.along @ up
    at = np.arctan2(t[1], t[0])
    opposite = np.where(at > 0, at - np.pi, at + np.pi)
    passes = ((at > 0) & (at < arcs.length)) | ((opposite > 0) & (opposite < arcs.length))
    return np.asarray((np.abs(arcs.normal @ up) < math.sin(math.radians(tolerance))) & ~passes)


def _horizontal_pair(arcs: _Arcs, up: FloatArray, upright: NDArray[np.bool_]) -> tuple[FloatArray, FloatArray] | None:
    """The two dominant horizontal vanishing directions, 90° apart, or None when the lines show no clear pair.

    Each non-vertical arc's plane holds one horizontal direction, ``normal x up``; a
    length-weighted histogram of their azimuths folded onto 90° (1° bins, smoothed over
    ±2°) peaks at the pair's azimuth, refined as the weighted mean within 2° of the peak.
    """
    e1, e2 = _frame(up)
    direction = np.cross(arcs.normal, up)
    size = np.linalg.norm(direction, axis=1)
    usable = ~upright & (size > 0.2)  # a circle nearly along the horizon holds every horizontal direction
    if not usable.any():
        return None
    azimuth = np.degrees(np.arctan2(direction @ e2, direction @ e1)) % 90.0
    weight = arcs.length[usable]
    hist = np.bincount(np.floor(azimuth[usable]).astype(np.intp) % 90, weights=weight, minlength=90)
    smooth = sum(np.roll(hist, s) * w for s, w in ((-2, 0.25), (-1, 0.5), (0, 1.0), (1, 0.5), (2, 0.25)))
    peak = int(np.argmax(smooth))
    window = (np.roll(hist, -2) + np.roll(hist, -1) + hist + np.roll(hist, 1) + np.roll(hist, 2))[peak]
    if window < MIN_HORIZONTAL_SHARE * float(hist.sum()):
        return None
    offset = (azimuth - (peak + 0.5) + 45.0) % 90.0 - 45.0
    near = usable & (np.abs(offset) < 2.0)
    angle = math.radians(peak + 0.5 + float(np.average(offset[near], weights=arcs.length[near])))
    h1 = math.cos(angle) * e1 + math.sin(angle) * e2
    return h1, np.cross(up, h1)


def _kinds(arcs: _Arcs, up: FloatArray, tolerance: float) -> tuple[NDArray[np.str_], tuple[FloatArray, FloatArray] | None]:
    upright = _vertical(arcs, up, tolerance)
    pair = _horizontal_pair(arcs, up, upright)
    level = np.zeros(len(upright), dtype=bool)
    if pair is not None:
        limit = math.sin(math.radians(tolerance))
        level = ~upright & ((np.abs(arcs.normal @ pair[0]) < limit) | (np.abs(arcs.normal @ pair[1]) < limit))
    kinds = np.where(upright, "vertical", np.where(level, "horizontal", "other"))
    return kinds, pair


def horizontal_directions(suggestions: Sequence[Suggestion], up: Sequence[float]) -> tuple[LonLat, LonLat] | None:
    """The two dominant horizontal vanishing directions of the lines, 90° apart, or None.

    Parameters
    ----------
    suggestions : sequence of Suggestion
    up : (float, float)
        ``[lon, lat]`` degrees of the true vertical.

    Returns
    -------
    ((float, float), (float, float)) or None
        ``[lon, lat]`` degrees of the two directions (each also stands for its opposite);
        None when no direction holds :data:`MIN_HORIZONTAL_SHARE` of the lines.
    """
    if not suggestions:
        return None
    arcs = _Arcs.of(suggestions)
    v = coords.lonlat_to_xyz(np.asarray(up, dtype=np.float64))
    pair = _horizontal_pair(arcs, v, _vertical(arcs, v, KIND_TOLERANCE))
    if pair is None:
        return None
    (lon0, lat0), (lon1, lat1) = coords.xyz_to_lonlat(np.array(pair)).tolist()
    return (float(lon0), float(lat0)), (float(lon1), float(lat1))


def line_kinds(suggestions: Sequence[Suggestion], up: Sequence[float], tolerance: float = KIND_TOLERANCE) -> tuple[str, ...]:
    """What each line is in 3D: ``"vertical"``, ``"horizontal"`` or ``"other"``.

    Vertical: its great circle passes within ``tolerance`` of ``up`` (and the arc stops
    short of it). Horizontal: not vertical, and its circle passes within ``tolerance`` of
    one of the two dominant horizontal vanishing directions (:func:`horizontal_directions`;
    none found, none is horizontal): every circle holds *some* horizontal direction, so a
    line is only known to be horizontal when it shares its vanishing point with the
    room's or the street's others.

    Parameters
    ----------
    suggestions : sequence of Suggestion
    up : (float, float)
        ``[lon, lat]`` degrees where the panorama sees the true vertical
        (:attr:`omniwidget.detect.Level.up`, or :func:`structure_up`).
    tolerance : float
        Degrees, ``> 0``.

    Returns
    -------
    tuple of str
    """
    if not (isinstance(tolerance, int | float) and math.isfinite(tolerance) and tolerance > 0):
        raise ValueError(f"tolerance must be a positive number of degrees, got {tolerance!r}")
    if not suggestions:
        return ()
    kinds, _ = _kinds(_Arcs.of(suggestions), coords.lonlat_to_xyz(np.asarray(up, dtype=np.float64)), tolerance)
    return tuple(str(k) for k in kinds)


def structure_up(suggestions: Sequence[Suggestion], width: int) -> tuple[FloatArray, bool]:
    """The true vertical as :func:`omniwidget.detect.level` finds it (among the :data:`UP_LINES` longest lines), or the zenith.

    Parameters
    ----------
    suggestions : sequence of Suggestion
        Every line found (``suggest_lines(..., structure=False)``).
    width : int
        Width in pixels of the image the lines were found in.

    Returns
    -------
    up : ndarray of float64, shape (3,)
    found : bool
        False when too few vertical edges agree (:class:`~omniwidget.errors.LevelError`):
        ``up`` is then the zenith, right for a level camera.
    """
    longest = sorted(suggestions, key=lambda s: -s.length)[:UP_LINES]  # the estimate's pairs grow as the square of the lines
    try:
        v, _, _ = vertical.find_up(longest, width)
    except LevelError:
        return np.array([0.0, 0.0, 1.0]), False
    return v, True


# --- the two sides -------------------------------------------------------------------


def side_difference(image: NDArray, suggestions: Sequence[Suggestion], offsets: Sequence[float] = SIDE_OFFSETS) -> FloatArray:
    """How different each line's two sides look: structure divides two surfaces, a texture's line lies on one.

    Along each arc (:data:`SIDE_SAMPLES` points over its middle 90%) the panorama is looked at
    ``offsets`` degrees to either side of its great circle (nearest pixel); the
    difference is the distance between the two sides' median colours, in 8-bit levels.
    A room's corner or a building's edge joins surfaces of other colours or lit otherwise;
    a tile joint, a cobble's edge or a painted stripe has the same surface on both sides.

    Parameters
    ----------
    image : ndarray, shape (H, 2H) or (H, 2H, C)
        The panorama the lines were found in, any width; uint8, uint16 or float in
        ``[0, 1]``; alpha is ignored.
    suggestions : sequence of Suggestion
    offsets : sequence of float
        Degrees, each in ``(0, 10]``.

    Returns
    -------
    ndarray of float64, shape (len(suggestions),)
        ``>= 0``, in levels of 255.
    """
    if not offsets or any(not (isinstance(o, int | float) and 0 < o <= 10) for o in offsets):
        raise ValueError(f"offsets must be degrees in (0, 10], got {offsets!r}")
    image = np.asarray(image)
    scale = 255.0 / 65535.0 if image.dtype == np.uint16 else (255.0 if image.dtype.kind == "f" else 1.0)
    pixels = image[..., :3] if image.ndim == 3 and image.shape[2] >= 3 else (image[..., :1] if image.ndim == 3 else image[..., None])
    h, w = pixels.shape[:2]
    if not suggestions:
        return np.zeros(0)
    arcs = _Arcs.of(suggestions)
    t = (0.05 + 0.9 * np.linspace(0.0, 1.0, SIDE_SAMPLES))[None, :] * arcs.length[:, None]  # (k, samples) radians along each
    points = np.cos(t)[..., None] * arcs.start[:, None, :] + np.sin(t)[..., None] * arcs.along[:, None, :]
    medians = []
    for sign in (1.0, -1.0):
        seen = []
        for offset in offsets:
            c, sn = math.cos(math.radians(offset)), math.sin(math.radians(offset))
            lonlat = coords.xyz_to_lonlat(points * c + sign * sn * arcs.normal[:, None, :])
            x = np.floor((lonlat[..., 0] + 180.0) / 360.0 * w).astype(np.intp) % w
            y = np.clip(np.floor((90.0 - lonlat[..., 1]) / 180.0 * h).astype(np.intp), 0, h - 1)
            seen.append(pixels[y, x].astype(np.float64) * scale)  # (k, samples, channels)
        medians.append(np.median(np.concatenate(seen, axis=1), axis=1))
    return np.asarray(np.linalg.norm(medians[0] - medians[1], axis=1), dtype=np.float64)


# --- junctions -----------------------------------------------------------------------


def _near_pairs(arcs: _Arcs, reach: float) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Pairs ``(i, j)``, ``i != j``, of arcs that come within ``reach`` radians of each other (or may: their caps overlap).

    Caps of half-widths ``h_i``, ``h_j`` (half the arc plus ``reach``, each below 90°)
    overlap when the middles' cosine is at least ``cos(h_i + h_j) = cos h_i cos h_j - sin
    h_i sin h_j``: two outer products, no cosine of the whole table.
    """
    middle = _unit(arcs.start + arcs.end)
    half = np.minimum(arcs.length / 2 + reach, np.pi / 2)
    c, s = np.cos(half), np.sin(half)
    i, j = np.nonzero(middle @ middle.T >= np.outer(c, c) - np.outer(s, s) - 1e-12)
    keep = i != j
    return i[keep], j[keep]


def _crossings(arcs: _Arcs, margin: float, pairs: tuple[NDArray[np.intp], NDArray[np.intp]] | None = None) -> tuple[NDArray[np.bool_], FloatArray]:
    """Which pairs cross at least ``margin`` radians inside both, (k, k), and how deep inside each the crossing is.

    ``depth[i, j]`` is the distance (radians) from the nearer end of arc ``i`` to where
    circle ``j`` meets it, on the point of the two (antipodal) meetings nearer both arcs'
    middles; negative outside arc ``i``; ``-inf`` for circles within 3° of each other and
    for arcs too far apart to meet (their caps do not overlap). ``pairs``: the pairs to look
    at, at least those of :func:`_near_pairs` at reach 0.
    """
    k = len(arcs.length)
    depth = np.full((k, k), -np.inf)
    i, j = _near_pairs(arcs, 0.0) if pairs is None else pairs
    x = np.cross(arcs.normal[i], arcs.normal[j])
    size = np.linalg.norm(x, axis=1)
    usable = size > math.sin(math.radians(3.0))
    i, j, x = i[usable], j[usable], x[usable] / size[usable, None]
    middle = _unit(arcs.start + arcs.end)
    # the meeting on the side of both middles: sign by the sum of the two middles' dot products
    sign = np.sign(np.einsum("ij,ij->i", x, middle[i]) + np.einsum("ij,ij->i", x, middle[j]))
    x = x * np.where(sign == 0, 1.0, sign)[:, None]
    t = np.arctan2(np.einsum("ij,ij->i", x, arcs.along[i]), np.einsum("ij,ij->i", x, arcs.start[i]))  # along arc i
    depth[i, j] = np.minimum(t, arcs.length[i] - t)
    cross = (depth > margin) & (depth.T > margin)
    return cross, depth


def junctions(suggestions: Sequence[Suggestion], up: Sequence[float] | None = None) -> Junctions:
    """How each line meets the others: the lines crossing it, ending on it, and parallel beside it.

    Parameters
    ----------
    suggestions : sequence of Suggestion
    up : (float, float), optional
        ``[lon, lat]`` degrees of the true vertical, for the families' vanishing
        directions; the zenith by default.

    Returns
    -------
    Junctions
    """
    arcs = _Arcs.of(suggestions)
    v = np.array([0.0, 0.0, 1.0]) if up is None else coords.lonlat_to_xyz(np.asarray(up, dtype=np.float64))
    kinds, pair = _kinds(arcs, v, KIND_TOLERANCE)
    return _junctions(arcs, kinds, v, pair)


def _junctions(arcs: _Arcs, kinds: NDArray[np.str_], up: FloatArray, pair: tuple[FloatArray, FloatArray] | None) -> Junctions:
    k = len(arcs.length)
    near_j, near_i = _near_pairs(arcs, math.radians(END_DISTANCE))  # the arcs near each other
    crossing, depth = _crossings(arcs, math.radians(CROSS_MARGIN), (near_i, near_j))
    ends = np.concatenate([arcs.start, arcs.end])  # end e of arc j is row e * k + j
    owner = np.tile(np.arange(k), 2)
    # the ends that may lie on each arc: those of the arcs near it (both ends of each), arc near_j's ends on arc near_i
    rows = np.concatenate([near_j, near_j + k])
    cols = np.concatenate([near_i, near_i])
    point = ends[rows]
    to_circle = np.abs(np.einsum("ij,ij->i", point, arcs.normal[cols]))  # sine of the distance
    t_all = np.arctan2(np.einsum("ij,ij->i", point, arcs.along[cols]), np.einsum("ij,ij->i", point, arcs.start[cols]))
    margin = math.radians(END_MARGIN)
    meets = np.abs(np.einsum("ij,ij->i", arcs.normal[owner[rows]], arcs.normal[cols])) < math.cos(math.radians(JUNCTION_ANGLE))
    on = (to_circle < math.sin(math.radians(END_DISTANCE))) & (t_all > margin) & (t_all < arcs.length[cols] - margin) & meets
    on &= ~crossing[owner[rows], cols]  # an end of a line that crosses this one does not end on it
    rows, cols, t_on = rows[on], cols[on], t_all[on]
    middle = _unit(arcs.start + arcs.end)
    side_on = np.einsum("ij,ij->i", middle[owner[rows]], arcs.normal[cols]) > 0  # the ending line's middle left of the circle
    crossed = crossing.sum(axis=1).astype(np.intp)
    left = np.zeros(k, dtype=np.intp)
    right = np.zeros(k, dtype=np.intp)
    order = np.argsort(cols, kind="stable")
    rows, cols, t_on, side_on = rows[order], cols[order], t_on[order], side_on[order]
    bounds = np.searchsorted(cols, np.arange(k + 1))
    parallel = math.cos(math.radians(COLLINEAR))
    gap = math.radians(2 * END_DISTANCE)
    for i in np.flatnonzero(np.diff(bounds)).tolist():
        events = rows[bounds[i] : bounds[i + 1]]
        js = owner[events]
        at = t_on[bounds[i] : bounds[i + 1]]
        sides = side_on[bounds[i] : bounds[i + 1]]
        used = np.zeros(len(events), dtype=bool)
        if len(events) > 1:  # two pieces of one line, from either side, meeting at one place: a crossing
            same = np.abs(arcs.normal[js] @ arcs.normal[js].T) > parallel
            close = np.abs(at[:, None] - at[None, :]) < gap
            pairs = same & close & (sides[:, None] != sides[None, :])
            for x, y in zip(*np.nonzero(np.triu(pairs, 1)), strict=True):
                if not used[x] and not used[y] and js[x] != js[y]:
                    used[x] = used[y] = True
                    crossed[i] += 1
        distinct_left = set(js[~used & sides].tolist())
        distinct_right = set(js[~used & ~sides].tolist())
        left[i], right[i] = len(distinct_left), len(distinct_right)
    family = _families(arcs, kinds, up, pair)
    return Junctions(crossed, left, right, family, crossing, depth)


def _families(arcs: _Arcs, kinds: NDArray[np.str_], up: FloatArray, pair: tuple[FloatArray, FloatArray] | None) -> NDArray[np.intp]:
    """Parallel neighbours of each vertical or horizontal arc: same vanishing direction, circles within FAMILY_SPACING, arcs facing each other.

    Compared as cosines (no arccos of the whole table): circles ``0.3° < apart <
    FAMILY_SPACING``, middles closer than half the longer arc plus FAMILY_SPACING.
    """
    k = len(arcs.length)
    out = np.zeros(k, dtype=np.intp)
    directions = np.array([up, *(pair if pair is not None else ())])
    which = np.argmin(np.abs(arcs.normal @ directions.T), axis=1)
    index = np.flatnonzero(kinds != "other")
    if index.size < 2:
        return out
    which = which[index]
    normal = arcs.normal[index]
    middle = _unit(arcs.start[index] + arcs.end[index])
    parallel = np.abs(normal @ normal.T)
    reach = np.minimum(np.maximum(arcs.length[index][:, None], arcs.length[index][None, :]) / 2 + math.radians(FAMILY_SPACING), np.pi)
    same = (which[:, None] == which[None, :]) & (parallel > math.cos(math.radians(FAMILY_SPACING))) & (parallel < math.cos(math.radians(0.3)))
    same &= middle @ middle.T > np.cos(reach)
    out[index] = same.sum(axis=1)
    return out


# --- the choice ----------------------------------------------------------------------


def _texture(j: Junctions, relative: FloatArray, sides: FloatArray | None) -> tuple[NDArray[np.bool_], list[str]]:
    """Which lines are texture, and why (an empty reason for the others)."""
    bounds = np.minimum(j.bounds, MAX_BOUNDS)
    two_sided = (j.bounds_left > 0) & (j.bounds_right > 0)
    crossed = (j.crossed >= TEXTURE_CROSSINGS) & (j.crossed - BOUND_WEIGHT * bounds - TWO_SIDED_WEIGHT * two_sided >= 1.0)
    alike = np.ones(len(relative), dtype=bool) if sides is None else sides < ALIKE
    family = (j.family >= FAMILY_SIZE) & (j.bounds < j.family)  # more parallel neighbours than lines it bounds
    faint = (relative < FAINT) & (j.bounds <= 1) & alike
    some = (j.crossed >= 1) | (j.family >= 1) | (relative < FAINT)  # some sign of a texture besides the sides
    mark = np.zeros(len(relative), dtype=bool) if sides is None else alike & (j.bounds <= MARK_BOUNDS) & some
    reasons = []
    for i in range(len(relative)):
        if mark[i] and sides is not None and not crossed[i]:
            reasons.append(f"the same surface on both sides (they differ by {sides[i]:.1f} levels) and bounding {j.bounds[i]} (a mark on a surface: joints or paint)")
        elif crossed[i]:
            reasons.append(f"crossed by {j.crossed[i]} line{'s' if j.crossed[i] != 1 else ''} and bounding {j.bounds[i]} (a texture: tiles, grid or cobbles)")
        elif family[i]:
            reasons.append(f"one of {j.family[i] + 1} parallel lines under {FAMILY_SPACING:g}° apart, bounding only {j.bounds[i]} (a texture: tiles, cobbles or courses)")
        elif faint[i]:
            reasons.append(f"{relative[i]:.0%} of the strongest edges' contrast, bounding {j.bounds[i]} (a texture: paint or joints)")
        else:
            reasons.append("")
    return crossed | family | faint | mark, reasons


def choose_structure(
    suggestions: Sequence[Suggestion],
    up: Sequence[float] | None = None,
    *,
    width: int = 2048,
    max_lines: int | None = None,
    image: NDArray | None = None,
) -> StructureChoice:
    """Keep the structure among the suggested lines: a consistent set, no two crossing, none texture.

    Parameters
    ----------
    suggestions : sequence of Suggestion
        Every line found (``suggest_lines(..., structure=False, max_lines=None)``).
    up : (float, float), optional
        ``[lon, lat]`` degrees of the true vertical (:attr:`omniwidget.detect.Level.up`).
        By default it is found from the lines as :func:`omniwidget.detect.level` does
        (:func:`structure_up`), and taken as the zenith when too few vertical edges are found.
    width : int
        Width in pixels of the image the lines were found in (their endpoints' accuracy, for ``up``).
    max_lines : int or None
        Keep at most this many; the rest are dropped as "beyond the first ...".
    image : ndarray, optional
        The panorama the lines were found in: with it, a line whose two sides look alike
        (:func:`side_difference` below :data:`ALIKE`) and that bounds at most
        :data:`MARK_BOUNDS` lines is a mark on a surface, texture; without it only the
        junctions, families and contrast tell texture.

    Returns
    -------
    StructureChoice
    """
    if max_lines is not None and (isinstance(max_lines, bool) or not isinstance(max_lines, int | np.integer) or max_lines < 1):
        raise ValueError(f"max_lines must be a positive integer or None, got {max_lines!r}")
    if isinstance(width, bool) or not isinstance(width, int | np.integer) or width < 1:
        raise ValueError(f"width must be a positive number of pixels, got {width!r}")
    every = list(suggestions)
    if up is None:
        v, found = structure_up(every, int(width))
    else:
        v, found = coords.lonlat_to_xyz(np.asarray(up, dtype=np.float64)), False
    up_lonlat = tuple(float(c) for c in coords.xyz_to_lonlat(v))
    if not every:
        return StructureChoice((), (), (up_lonlat[0], up_lonlat[1]), found)
    arcs = _Arcs.of(every)
    kinds, pair = _kinds(arcs, v, KIND_TOLERANCE)
    junction = _junctions(arcs, kinds, v, pair)
    contrast = np.array([s.contrast for s in every])
    relative = contrast / max(float(np.sort(contrast)[-5:].mean()), 1e-9)
    sides = None if image is None else side_difference(image, every)
    texture, texture_reason = _texture(junction, relative, sides)
    length = np.degrees(arcs.length)
    rank = np.array([s.confidence for s in every]) * np.where(kinds == "other", OTHER_WEIGHT, 1.0)
    if sides is not None:  # of two lines along one edge, the one dividing the surfaces
        rank = rank * (1.0 - SIDE_WEIGHT + SIDE_WEIGHT * np.minimum(1.0, sides / DIFFERENT))
    order = np.argsort(-rank, kind="stable")
    t = np.linspace(0.0, 1.0, CLOSE_SAMPLES)[None, :] * arcs.length[:, None]
    samples = np.cos(t)[..., None] * arcs.start[:, None, :] + np.sin(t)[..., None] * arcs.along[:, None, :]
    kept: list[int] = []
    dropped: list[tuple[int, Reason]] = []
    pieces: dict[int, list[int]] = {}  # kept line -> lines dropped as the same edge
    for i in order.tolist():
        if texture[i]:
            dropped.append((i, Reason(texture_reason[i], TEXTURE)))
            continue
        if kinds[i] == "other" and length[i] < OTHER_MIN_LENGTH:
            dropped.append((i, Reason(f"kind 'other' and shorter than {OTHER_MIN_LENGTH:g}°", SHORT_OTHER)))
            continue
        if max_lines is not None and len(kept) >= max_lines:
            dropped.append((i, Reason(f"beyond the first {max_lines} kept", BEYOND)))
            continue
        reason, near = _conflict(arcs, junction.crossing, samples, kept, i)
        if reason:
            dropped.append((i, reason))
            if near is not None:
                pieces.setdefault(near, []).append(i)
            continue
        kept.append(i)
    longer, depth = _lengthened(arcs, kept, pieces, junction.depth)
    ends = _corners(_trim(longer, kept, depth))
    chosen = []
    for n, i in enumerate(kept):
        a, b = ends[n]
        s = every[i]
        (lon0, lat0), (lon1, lat1) = coords.xyz_to_lonlat(np.array([a, b])).tolist()
        span = math.degrees(math.atan2(float(np.linalg.norm(np.cross(a, b))), float(a @ b)))
        moved = not (np.array_equal(a, arcs.start[i]) and np.array_equal(b, arcs.end[i]))
        chosen.append(
            replace(
                s,
                start=(float(lon0), float(lat0)) if moved else s.start,
                end=(float(lon1), float(lat1)) if moved else s.end,
                length=span if moved else s.length,
                confidence=float(rank[i]),
                kind=str(kinds[i]),
            )
        )
    horizontals: tuple[LonLat, ...] = ()
    if pair is not None:
        (lon0, lat0), (lon1, lat1) = coords.xyz_to_lonlat(np.array(pair)).tolist()
        horizontals = ((float(lon0), float(lat0)), (float(lon1), float(lat1)))
    return StructureChoice(
        kept=tuple(chosen),
        dropped=tuple((replace(every[i], kind=str(kinds[i])), why) for i, why in dropped),
        up=(up_lonlat[0], up_lonlat[1]),
        up_found=found,
        horizontals=horizontals,
    )


def _conflict(arcs: _Arcs, crossing: NDArray[np.bool_], samples: FloatArray, kept: list[int], i: int) -> tuple[Reason | None, int | None]:
    """Why line ``i`` cannot join the kept lines, or None; and the kept line it is the same edge as, if it is.

    ``samples``: (k, CLOSE_SAMPLES, 3) along every arc.
    """
    if not kept:
        return None, None
    others = np.array(kept, dtype=np.intp)
    crosses = np.flatnonzero(crossing[i, others])
    if crosses.size:
        return Reason(f"crosses suggested line {int(crosses[0]) + 1}", CROSSING), None
    # each line's samples near the other, both ways: the same edge, or neighbours fighting for the pixels
    sub = _Arcs(arcs.start[others], arcs.end[others], arcs.normal[others], arcs.along[others], arcs.length[others])
    mine = sub.distance(samples[i])  # (samples, kept)
    share = (mine < CLOSE_DISTANCE).mean(axis=0)
    one = _Arcs(arcs.start[i : i + 1], arcs.end[i : i + 1], arcs.normal[i : i + 1], arcs.along[i : i + 1], arcs.length[i : i + 1])
    theirs = (one.distance(samples[others].reshape(-1, 3))[:, 0] < CLOSE_DISTANCE).reshape(len(others), -1).mean(axis=1)
    both = np.maximum(share, theirs)
    n = int(np.argmax(both))
    if both[n] <= CLOSE_SHARE:
        return None, None
    near = mine[:, n][mine[:, n] < CLOSE_DISTANCE]
    apart = float(np.median(near)) if near.size else CLOSE_DISTANCE
    what = "the same edge" if apart < SAME_EDGE else "they would fight for the same pixels"
    reason = Reason(f"within {max(apart, 0.05):.1f}° of suggested line {n + 1} along {both[n]:.0%} of its length ({what})", BESIDE)
    return reason, (int(others[n]) if apart < SAME_EDGE else None)


def _lengthened(arcs: _Arcs, kept: list[int], pieces: dict[int, list[int]], depth: FloatArray) -> tuple[_Arcs, FloatArray]:
    """The arcs with each kept one lengthened over the pieces of the same edge dropped beside it, and their crossing depths.

    An edge the detector found in pieces (broken by a corner's shading, or one piece just
    outside the kind's tolerance) is kept once; its other pieces that lie along its circle
    (:data:`MERGE_DISTANCE`) extend it, so that the whole edge is straightened. A
    lengthening that would cross another kept line inside both (:data:`CROSS_MARGIN`) is
    not made. ``depth`` is :attr:`Junctions.depth`, returned as it is when nothing changed.
    """
    start, end = arcs.start.copy(), arcs.end.copy()
    for n, near in pieces.items():
        t = np.concatenate([_along_circle(arcs, n, arcs.samples(i, CLOSE_SAMPLES)) for i in near])
        if t.size == 0:
            continue
        low, high = min(0.0, float(t.min())), max(float(arcs.length[n]), float(t.max()))
        if high - low >= np.pi or (low == 0.0 and high == float(arcs.length[n])):
            continue
        start[n] = math.cos(low) * arcs.start[n] + math.sin(low) * arcs.along[n]
        end[n] = math.cos(high) * arcs.start[n] + math.sin(high) * arcs.along[n]
    changed = np.flatnonzero(np.any((start != arcs.start) | (end != arcs.end), axis=1))
    if changed.size == 0:
        return arcs, depth
    longer = _Arcs.between(start, end)
    crossing, new_depth = _crossings(longer, math.radians(CROSS_MARGIN))
    others = np.array(kept, dtype=np.intp)
    for n in changed.tolist():
        if crossing[n, others].any():  # undo: it would cross a kept line
            start[n], end[n] = arcs.start[n], arcs.end[n]
    if np.array_equal(start, arcs.start) and np.array_equal(end, arcs.end):
        return arcs, depth
    longer = _Arcs.between(start, end)
    return longer, _crossings(longer, math.radians(CROSS_MARGIN))[1]


def _along_circle(arcs: _Arcs, n: int, points: FloatArray) -> FloatArray:
    """Angles (radians) along arc ``n``'s circle from its start of those ``points`` of a piece that lie along it; empty if they do not."""
    off = np.degrees(np.arcsin(np.clip(np.abs(points @ arcs.normal[n]), 0.0, 1.0)))
    if float(np.median(off)) >= MERGE_DISTANCE or float(off.max()) >= SAME_EDGE:
        return np.zeros(0)
    return np.asarray(np.arctan2(points @ arcs.along[n], points @ arcs.start[n]))


def _trim(arcs: _Arcs, kept: list[int], depth: FloatArray) -> list[tuple[FloatArray, FloatArray]]:
    """The kept arcs' ends, each cut back to where it overshoots another kept arc (so no two cross by the method's test).

    Kept arcs never cross :data:`CROSS_MARGIN` inside both; closer to an end of one they
    may meet by the detector's error (a T or a corner overshot). The arc whose end is
    nearer the crossing is cut there, to touch the other: the method does not count a
    meeting at an end as a crossing (:func:`omniwidget.sphere.arcs.arc_crossing`, margin
    1e-6°). Cuts only shorten arcs, so one pass over the pairs whose circles meet inside
    both (``depth``, loosened against rounding; nearly parallel circles too) is enough.
    """
    ends = [(arcs.start[i].copy(), arcs.end[i].copy()) for i in kept]
    index = np.array(kept, dtype=np.intp)
    sub = depth[np.ix_(index, index)]
    outside = (np.isfinite(sub) & (sub < -1e-6)) | (np.isfinite(sub.T) & (sub.T < -1e-6))  # they meet beyond an end of one
    near = np.zeros(sub.shape, dtype=bool)
    i, j = _near_pairs(_Arcs(arcs.start[index], arcs.end[index], arcs.normal[index], arcs.along[index], arcs.length[index]), 0.0)
    near[i, j] = True
    near &= ~outside
    for p, q in zip(*np.nonzero(np.triu(near, 1)), strict=True):
        a0, a1 = ends[p]
        b0, b1 = ends[q]
        x = arc_crossing(a0, a1, b0, b1, 1e-6)
        if x is None:
            continue
        da = min(_angle(a0, x), _angle(a1, x))
        db = min(_angle(b0, x), _angle(b1, x))
        if da <= db:
            ends[p] = (x, a1) if _angle(a0, x) <= _angle(a1, x) else (a0, x)
        else:
            ends[q] = (x, b1) if _angle(b0, x) <= _angle(b1, x) else (b0, x)
    return ends


def _corners(ends: list[tuple[FloatArray, FloatArray]]) -> list[tuple[FloatArray, FloatArray]]:
    """The kept arcs' ends, each arc cut back where it runs on past a corner by less than :data:`OVERSHOOT`.

    At a corner of a room two edges end at one point; the detector often finds one of them
    a few degrees too long (the pattern beyond the corner continues it). The method then
    sees an end of the other line on it short of its end, not a joint, and once the lines
    are straightened the two cross. The arc is cut at the corner (the other's end put on its
    circle), so that the two meet at their ends. An end on an arc far from the arc's ends
    (a T) cuts nothing.
    """
    out = list(ends)
    limit = math.radians(OVERSHOOT)
    near = math.sin(math.radians(END_DISTANCE))
    skew = math.cos(math.radians(JUNCTION_ANGLE))
    for p, (a, b) in enumerate(ends):
        normal = _unit(np.cross(a, b))
        along = np.cross(normal, a)
        length = _angle(a, b)
        start, end = a, b
        for q, other in enumerate(ends):
            if q == p or abs(float(_unit(np.cross(*other)) @ normal)) > skew:
                continue
            for corner in other:
                if abs(float(corner @ normal)) >= near:
                    continue
                t = math.atan2(float(corner @ along), float(corner @ a))
                on = _unit(corner - float(corner @ normal) * normal)  # the corner put on this arc's circle
                if 0.0 < t < min(limit, length / 4):
                    start = on
                elif 0.0 < length - t < min(limit, length / 4):
                    end = on
        out[p] = (start, end)
    return out


def _angle(a: FloatArray, b: FloatArray) -> float:
    return math.atan2(float(np.linalg.norm(np.cross(a, b))), float(a @ b))
