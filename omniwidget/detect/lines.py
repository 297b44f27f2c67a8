"""Suggested line handles: the straight 3D edges of a panorama, found in the image.

A straight 3D segment is seen along a great-circle arc of the viewing sphere, and in any
perspective (gnomonic) view of the sphere it is a straight image segment. So the
panorama is resampled into perspective views (the six faces of a cube, each widened so
that neighbouring views overlap and no segment is lost at a face border, the poles or the
±180° seam), a plain 2D line-segment detector runs on each view, and each detected
segment's endpoints are lifted back to the sphere as rays: the segment becomes the
great-circle arc between them. Arcs of the same 3D edge (from overlapping views, from
both borders of a painted band, or cut by a junction) lie on one great circle and
overlap or nearly touch along it; they are merged into one arc, ranked by length and
contrast and given a confidence.

The detector is OpenCV's LSD (:func:`cv2.createLineSegmentDetector`): it finds each edge
as one segment with sub-pixel ends and needs no thresholds tuned per image, where
scikit-image's Canny edges and probabilistic Hough transform (kept as ``detector="hough"``
for comparison) break edges into pieces, find spurious ones and are slower
(``bench/RESULTS.md``, "Suggested lines and levelling", gives the figures).
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from .._checks import check_panorama
from .._lazy import lazy
from ..document.handles import Handles, LineHandle, Options
from ..errors import ImageError
from ..sphere import coords
from .structure import choose_structure

if TYPE_CHECKING:
    import cv2
    from skimage import feature, transform
else:
    cv2 = lazy("cv2")
    feature = lazy("skimage.feature")
    transform = lazy("skimage.transform")

__all__ = [
    "KINDS",
    "Arc",
    "Suggestion",
    "View",
    "check_detectable",
    "cube_views",
    "detect_segments",
    "find_arcs",
    "lift_segments",
    "merge_arcs",
    "pair_bands",
    "snap_ends",
    "panorama_gray",
    "render_view",
    "suggest_lines",
    "suggestions_to_handles",
]

LonLat = tuple[float, float]
FloatArray = NDArray[np.float64]

#: Half the field of view of each cube view, degrees: 45 covers the cube face, the rest overlaps.
VIEW_HALF_ANGLE = 52.0
#: Arcs whose points all lie this close (degrees) to a cluster's great circle may join it.
MERGE_DISTANCE = 0.8
#: The closeness (degrees) of the last merge, of midlines and single edges whatever their polarity.
FINAL_DISTANCE = 0.5
#: How far (degrees) an arc's end may move to the junction it stops short of (:func:`snap_ends`).
SNAP_REACH = 2.0
#: The longest merged arc, radians: below 180 degrees, so that its ends name it.
MAX_ARC = math.radians(170.0)
#: Largest gap (degrees) along a great circle between two arcs that are still one edge.
MERGE_GAP = 4.0
#: Largest angle (degrees) between the two borders of a thin painted line that are paired into its midline.
BAND_DISTANCE = 2.5
#: LSD's angle tolerance, degrees (its default 22.5 joins edges that meet at a slight bend, as at a corner).
LSD_ANGLE = 22.5
#: LSD's scale: the view is smoothed and resampled by this factor first.
LSD_SCALE = 0.8
#: Smallest panorama height the detector works on, pixels.
MIN_HEIGHT = 32
#: Widest the panorama is analysed at: a wider one is first reduced to it (area average). The
#: view sizes, LSD's scale and the merge tolerances are set for it; lines and tilt are angles,
#: found nearly as well here as at twice the width in a quarter of the time, and a large
#: photograph analysed whole finds its texture for edges (bench/RESULTS.md, "Suggested lines").
DETECT_WIDTH = 2048
#: Shortest detected image segment kept before lifting, in pixels of a view.
MIN_SEGMENT_PX = 8.0
#: What a suggested line is in 3D (:attr:`Suggestion.kind`).
KINDS = ("vertical", "horizontal", "other")


@dataclass(frozen=True)
class Suggestion:
    """A suggested line handle: a great-circle arc along a straight edge found in the image.

    Parameters
    ----------
    start, end : (float, float)
        ``[lon, lat]`` in degrees of the arc's endpoints in the input panorama.
    length : float
        Angular length of the arc, degrees.
    contrast : float
        Mean brightness step across the edge, as a share of the full range, in ``[0, 1]``.
    confidence : float
        In ``[0, 1]``: higher for longer, higher-contrast arcs whose whole extent the
        detector saw; the suggestions are sorted by it.
    kind : {"vertical", "horizontal", "other"}
        What the edge is in 3D (:func:`omniwidget.detect.structure.line_kinds`):
        ``"vertical"`` when its great circle passes through the panorama's true vertical,
        ``"horizontal"`` when it passes through one of the two dominant horizontal
        vanishing directions (a room's or a street's walls), ``"other"`` otherwise, and
        for suggestions made without looking (the default).
    """

    start: LonLat
    end: LonLat
    length: float
    contrast: float
    confidence: float
    kind: str = "other"

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"kind must be one of {', '.join(map(repr, KINDS))}, got {self.kind!r}")

    def handle(self, id: str | None = None) -> LineHandle:
        """The line handle along this arc (rectified by eq. (4) unless the document says otherwise)."""
        return LineHandle(start=self.start, end=self.end, id=id)


def suggestions_to_handles(suggestions: Iterable[Suggestion], options: Options | None = None) -> Handles:
    """A handles document of one line handle per suggestion, ids ``"suggested-1"``, ``"suggested-2"``, ...

    Parameters
    ----------
    suggestions : iterable of Suggestion
    options : Options, optional
        The document's options; the defaults if omitted.

    Returns
    -------
    Handles
    """
    handles = tuple(s.handle(f"suggested-{i + 1}") for i, s in enumerate(suggestions))
    return Handles(handles, Options() if options is None else options)


# --- the image -----------------------------------------------------------------------


def panorama_gray(image: NDArray, name: str = "image") -> NDArray[np.uint8]:
    """The panorama's brightness as 8-bit grey, the detector's input.

    Parameters
    ----------
    image : ndarray, shape (H, 2H) or (H, 2H, C)
        uint8, uint16, float32 or float64; ``C`` in 1..4 (grey, grey + alpha, RGB, RGBA;
        alpha is ignored). Floats are taken as ``[0, 1]``; a float image brighter than 1
        (high dynamic range) is scaled so that its 99.5th percentile is 1.
    name : str
        What messages call the image.

    Returns
    -------
    ndarray of uint8, shape (h, 2h)
        ``h = min(H, DETECT_WIDTH / 2)``: a wider panorama is reduced to :data:`DETECT_WIDTH`.

    Raises
    ------
    ImageError
        If the image is not a panorama the toolkit reads, or smaller than ``64 x 32``.
    """
    check_detectable(image, name)
    if image.shape[1] > DETECT_WIDTH:
        image = cv2.resize(image, (DETECT_WIDTH, DETECT_WIDTH // 2), interpolation=cv2.INTER_AREA)
    if image.ndim == 3 and image.shape[2] >= 3:
        rgb = image[..., :3]
        gray = 0.299 * rgb[..., 0].astype(np.float32) + 0.587 * rgb[..., 1] + 0.114 * rgb[..., 2]
    else:
        gray = (image[..., 0] if image.ndim == 3 else image).astype(np.float32)
    if image.dtype == np.uint8:
        full = 255.0
    elif image.dtype == np.uint16:
        full = 65535.0
    else:
        top = float(np.percentile(gray, 99.5)) if gray.size else 1.0
        full = top if top > 1.0 else 1.0
    return np.clip(np.rint(gray * np.float32(255.0 / full)), 0, 255).astype(np.uint8)


def check_detectable(image: NDArray, name: str = "image") -> None:
    """:func:`panorama_gray`'s checks alone: raise :class:`~omniwidget.errors.ImageError` where it would.

    Parameters
    ----------
    image : ndarray, shape (H, 2H[, C])
        A panorama, at least ``2 MIN_HEIGHT x MIN_HEIGHT``.
    name : str
        What the message calls it.
    """
    check_panorama(image, name)
    if image.shape[0] < MIN_HEIGHT:
        raise ImageError(
            f"{name}: {image.shape[1]} x {image.shape[0]} is too small to find lines in (at least {2 * MIN_HEIGHT} x {MIN_HEIGHT})"
        )


# --- the views -----------------------------------------------------------------------


@dataclass(frozen=True)
class View:
    """A perspective view of the sphere: ``ray(x, y) = focal * forward + (x - c) * right + (y - c) * down``, ``c = (size - 1) / 2``.

    Attributes
    ----------
    forward, right, down : ndarray of float64, shape (3,)
        Orthonormal camera axes, unit vectors in the panorama's frame.
    size : int
        Width and height of the square view, pixels.
    focal : float
        Focal length, pixels.
    """

    forward: FloatArray
    right: FloatArray
    down: FloatArray
    size: int
    focal: float

    def rays(self, xy: NDArray) -> FloatArray:
        """Unit direction vectors of view pixels ``(x, y)``, shape (..., 2) -> (..., 3)."""
        xy = np.asarray(xy, dtype=np.float64)
        c = (self.size - 1) / 2
        d = self.focal * self.forward + (xy[..., :1] - c) * self.right + (xy[..., 1:2] - c) * self.down
        return d / np.linalg.norm(d, axis=-1, keepdims=True)


def cube_views(width: int, half_angle: float = VIEW_HALF_ANGLE) -> list[View]:
    """The six cube-face views of a panorama of width ``width``, widened to ``2 * half_angle`` degrees.

    The focal length matches the panorama's resolution at the equator (``width / 2π``
    pixels per radian), so a view neither loses nor invents detail at its centre.

    Returns
    -------
    list of View
        Forward along +x, +y, -x, -y (longitudes 0, 90, 180, -90), then +z and -z.
    """
    focal = width / (2 * math.pi)
    size = int(math.ceil(2 * focal * math.tan(math.radians(half_angle))))
    z = np.array([0.0, 0.0, 1.0])
    views = []
    for lon in (0.0, 90.0, 180.0, -90.0):
        forward = coords.lonlat_to_xyz([lon, 0.0])
        right = coords.lonlat_to_xyz([lon + 90.0, 0.0])
        views.append(View(forward, right, -z, size, focal))
    x, y = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])
    views.append(View(z, y, x, size, focal))  # looking up: +y to the right, +x down
    views.append(View(-z, y, -x, size, focal))  # looking down
    return views


def render_view(gray: NDArray[np.uint8], view: View) -> NDArray[np.uint8]:
    """Resample the panorama into one perspective view (bilinear, ``cv2.remap``), seamlessly across ±180°.

    Parameters
    ----------
    gray : ndarray of uint8, shape (H, 2H)
    view : View

    Returns
    -------
    ndarray of uint8, shape (view.size, view.size)
    """
    h, w = gray.shape

    map_x, map_y = _view_maps(view, w, h)
    wrapped = np.concatenate([gray, gray[:, :1]], axis=1)
    return np.asarray(cv2.remap(wrapped, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE), dtype=np.uint8)


def _view_maps(view: View, w: int, h: int) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """Where each pixel of ``view`` looks in a ``w x h`` panorama: ``cv2.remap``'s maps, columns in ``[0, w)``.

    :meth:`View.rays`, :func:`omniwidget.sphere.coords.xyz_to_lonlat` and
    :func:`~omniwidget.sphere.coords.lonlat_to_px` written out on the view's planes of x, y
    and z: the same arithmetic, so the same maps to the bit, without their (size, size, 3)
    temporaries, in place where a plane is not needed again, and each ``np.mod`` as the one
    shift by the modulus it makes here (:func:`_wrap`).
    """
    c = (view.size - 1) / 2
    x = (np.arange(view.size, dtype=np.float64) - c)[None, :]
    y = (np.arange(view.size, dtype=np.float64) - c)[:, None]
    f = view.focal * view.forward
    d = [f[k] + x * view.right[k] + y * view.down[k] for k in range(3)]
    norm = d[0] * d[0]
    norm += d[1] * d[1]
    norm += d[2] * d[2]
    np.sqrt(norm, out=norm)
    rx, ry, rz = (np.divide(part, norm, out=part) for part in d)
    lon = np.degrees(np.arctan2(ry, rx, out=norm), out=norm)
    lon += 180.0
    lon = _wrap(lon, 360.0)  # coords.wrap_lon: np.mod(lon + 180, 360) - 180, then 180 itself to -180
    lon -= 180.0
    lon[lon >= 180.0] -= 360.0
    lat = np.degrees(np.arctan2(rz, np.hypot(rx, ry, out=rx), out=rx), out=rx)
    scale = w / 360.0
    # columns wrap: x in [0, w), and column w (the copy of column 0) closes the seam
    lon += 180.0
    lon *= scale
    lon -= 0.5
    map_x = _wrap(lon, float(w)).astype(np.float32)
    lat = np.subtract(90.0, lat, out=lat)
    lat *= scale
    lat -= 0.5
    map_y = np.clip(lat, 0, h - 1, out=lat).astype(np.float32)
    return map_x, map_y


def _wrap(t: FloatArray, modulus: float) -> FloatArray:
    """``np.mod(t, modulus)`` for ``t`` in ``(-modulus, 2 modulus)``, to the bit: ``t + modulus``, ``t - modulus`` or ``t`` (``-0.0`` as ``+0.0``).

    numpy's remainder is ``fmod``, plus the modulus where the signs differ: within that range
    ``fmod`` is ``t`` or the exact ``t - modulus``; a third of ``np.mod``'s time.
    """
    shift = np.where(t < 0.0, modulus, 0.0)
    shift[t >= modulus] = -modulus
    t += shift
    return t


# --- detection and lifting -----------------------------------------------------------


def detect_segments(view_image: NDArray[np.uint8], detector: str = "lsd") -> tuple[FloatArray, FloatArray]:
    """Straight segments in one view, and the brightness step across each.

    Parameters
    ----------
    view_image : ndarray of uint8, shape (n, n)
    detector : {"lsd", "hough"}
        OpenCV's line segment detector, or scikit-image's Canny edges and probabilistic
        Hough transform (kept for comparison).

    Returns
    -------
    segments : ndarray of float64, shape (k, 4)
        ``x1, y1, x2, y2`` in view pixels, each at least :data:`MIN_SEGMENT_PX` long.
    contrast : ndarray of float64, shape (k,)
        Mean absolute brightness difference between the two sides, in ``[0, 1]``.
    """
    if detector == "lsd":
        lsd = cv2.createLineSegmentDetector(cv2.LSD_REFINE_STD, LSD_SCALE, 0.6, 2.0, LSD_ANGLE)
        found = lsd.detect(view_image)[0]
        segments = np.empty((0, 4)) if found is None else found.reshape(-1, 4).astype(np.float64)
    elif detector == "hough":
        edges = feature.canny(view_image.astype(np.float64) / 255.0, sigma=1.5, low_threshold=0.05, high_threshold=0.12)
        found_h = transform.probabilistic_hough_line(edges, threshold=10, line_length=int(MIN_SEGMENT_PX * 2), line_gap=2, rng=0)
        segments = np.array([[p[0], p[1], q[0], q[1]] for p, q in found_h], dtype=np.float64).reshape(-1, 4)
    else:
        raise ValueError(f"detector must be 'lsd' or 'hough', got {detector!r}")
    lengths = np.hypot(segments[:, 2] - segments[:, 0], segments[:, 3] - segments[:, 1])
    segments = segments[lengths >= MIN_SEGMENT_PX]
    return segments, _contrast(view_image, segments)


def _contrast(view_image: NDArray[np.uint8], segments: FloatArray, samples: int = 9, offset: float = 2.0) -> FloatArray:
    """Mean ``|I(left) - I(right)|`` / 255 at ``samples`` points along each segment, ``offset`` pixels to each side."""
    if len(segments) == 0:
        return np.empty(0)

    p, q = segments[:, None, :2], segments[:, None, 2:]
    t = np.linspace(0.1, 0.9, samples)[None, :, None]
    along = p + t * (q - p)
    direction = (q - p) / np.linalg.norm(q - p, axis=-1, keepdims=True)
    normal = np.concatenate([-direction[..., 1:], direction[..., :1]], axis=-1)
    sides = []
    for sign in (1.0, -1.0):
        at = (along + sign * offset * normal).astype(np.float32)
        sides.append(cv2.remap(view_image, at[..., 0], at[..., 1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE).astype(np.float64))
    return np.abs(sides[0] - sides[1]).mean(axis=1) / 255.0


def lift_segments(segments: FloatArray, view: View) -> tuple[FloatArray, FloatArray]:
    """Endpoints of view segments as unit vectors on the sphere: ``(a, b)``, each shape (k, 3)."""
    return view.rays(segments[:, :2]), view.rays(segments[:, 2:])


# --- merging -------------------------------------------------------------------------


@dataclass(frozen=True)
class Arc:
    """A merged great-circle arc, unit vectors ``start`` and ``end``, and what supports it.

    Attributes
    ----------
    start, end : ndarray of float64, shape (3,)
    contrast : float
        Length-weighted mean contrast of its pieces.
    coverage : float
        Share of its extent covered by detected pieces, in ``[0, 1]``.
    pieces : int
        How many detected segments it merges.
    """

    start: FloatArray
    end: FloatArray
    contrast: float
    coverage: float
    pieces: int

    @property
    def length(self) -> float:
        """Degrees."""
        return _degrees_between(self.start, self.end)


def _degrees_between(start: FloatArray, end: FloatArray) -> float:
    """The angle between unit vectors ``start`` and ``end``, degrees: :attr:`Arc.length`."""
    return math.degrees(math.atan2(float(np.linalg.norm(_cross(start, end))), float(start @ end)))


def _unit(v: NDArray) -> NDArray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def merge_arcs(
    a: FloatArray,
    b: FloatArray,
    contrast: FloatArray,
    *,
    distance: float = MERGE_DISTANCE,
    gap: float = MERGE_GAP,
    polarity: bool = True,
) -> list[Arc]:
    """Merge arcs of one great circle whose extents overlap or nearly touch into one arc each.

    Greedy, longest first: the longest arc not yet taken seeds a cluster; every arc of the
    same polarity (the detector orients each segment by the side that is darker, so the
    arc's normal ``a x b`` tells the side) whose endpoints and midpoint lie within
    ``distance`` degrees of the cluster's great circle and whose extent along it comes within ``gap`` degrees of the cluster's joins it; the
    circle is refitted to all members' points (the smallest eigenvector of their scatter,
    weighted by length) and the search repeats until nothing joins.

    Each search tests only the arcs not yet taken whose middles are near the cluster (a grid
    of them, :class:`_EndTree`): an arc no longer than the seed (as every arc not yet
    taken is), within ``distance`` of the cluster's circle and within ``gap`` of its extent
    has its middle within ``extent / 2 + gap + distance + seed length`` of the extent's
    middle. So the result is that of testing every arc not yet taken.

    The seeds are grown a batch at a time (:data:`_MERGE_BATCH` of them, in their order),
    all at once, as if each were the next (:func:`_grow_together`): each takes what it
    would take from the arcs free before the batch and after it in the order. Then, in
    order, a seed's cluster is kept when none of what it took has been taken since by a
    seed before it; as the searches differ only in the arcs taken, it is then the cluster
    the greedy loop grows. Otherwise (a seed near one just grown) it is grown again alone
    (:func:`_grow_one`). The same clusters as the loop, in the same order.

    Parameters
    ----------
    a, b : ndarray of float64, shape (k, 3)
        Unit vectors of the arcs' endpoints.
    contrast : ndarray of float64, shape (k,)
    distance, gap : float
        Degrees.
    polarity : bool
        Merge only arcs of the same polarity (False: any).

    Returns
    -------
    list of Arc
        Oriented like their members, ``start x end`` along the members' normals.
    """
    k = len(a)
    if k == 0:
        return []
    setup = _MergeSetup.of(a, b, distance, gap, polarity)
    order = np.argsort(-setup.length)
    setup.rank[order] = np.arange(k)
    free = np.ones(k, dtype=bool)
    kinds: list[int] = []  # per cluster in the seeds' order: -1 alone, else the index in ``grown``
    alone: list[int] = []
    grown: list[tuple[NDArray[np.intp], FloatArray, FloatArray]] = []  # members (sorted), normal, origin
    position = 0
    while position < k:
        window = order[position : position + _MERGE_BATCH]
        position += _MERGE_BATCH
        seeds = window[free[window]]
        if seeds.size == 0:
            continue
        if 2 * np.count_nonzero(free) < len(setup.ids):  # the grid of the middles is mostly of arcs taken: made again of those left
            setup.ids = np.flatnonzero(free)
            setup.middles = _EndTree(setup.mid[setup.ids])
        first, joined, normal, origin = _grow_together(seeds, free, setup)
        bounds, took = first.tolist(), joined.tolist()
        for n, seed in enumerate(seeds.tolist()):
            if not free[seed]:
                continue  # taken by a seed before it in this batch
            free[seed] = False
            mine = took[bounds[n] : bounds[n + 1]]
            if not mine:
                kinds.append(-1)
                alone.append(seed)
                continue
            if free[mine].all():  # nothing it takes was taken since: the loop's cluster
                free[mine] = False
                kinds.append(len(grown))
                grown.append((np.sort(np.array([seed, *mine], dtype=np.intp)), normal[n], origin[n]))
                continue
            members, fitted, start = _grow_one(seed, free, setup)
            if members.size == 1:
                kinds.append(-1)
                alone.append(seed)
            else:
                kinds.append(len(grown))
                grown.append((members, fitted, start))
    singles = iter(_single_arcs(a, b, setup.normals, setup.length, contrast, np.array(alone, dtype=np.intp)))
    merged = _finish_many(a, b, setup.length, contrast, grown)
    return [next(singles) if kind < 0 else merged[kind] for kind in kinds]


#: Seeds grown together by :func:`merge_arcs` (the next ones in its order, those still free).
_MERGE_BATCH = 256


@dataclass
class _MergeSetup:
    """What :func:`merge_arcs`'s searches use: the arcs' points, lengths, the grid of their middles and the tolerances."""

    a: FloatArray
    b: FloatArray
    mid: FloatArray
    side: FloatArray
    normals: FloatArray
    length: FloatArray
    samples: FloatArray
    scatter: FloatArray
    points: FloatArray
    rank: NDArray[np.intp]
    middles: _EndTree
    ids: NDArray[np.intp]
    sin_d: float
    gap_r: float
    reach: float
    polarity: bool

    @classmethod
    def of(cls, a: FloatArray, b: FloatArray, distance: float, gap: float, polarity: bool) -> _MergeSetup:
        mid = _unit(a + b)
        length = np.arccos(np.clip(np.einsum("ij,ij->i", a, b), -1.0, 1.0))
        sample_t = np.linspace(0.0, 1.0, 5)
        samples = _unit(a[:, None, :] * (1 - sample_t)[None, :, None] + b[:, None, :] * sample_t[None, :, None])  # (k, 5, 3) chords, normalised
        side = np.cross(a, b)  # the polarity: the dark side
        weighted = samples * (length / samples.shape[1])[:, None, None]
        return cls(
            a=a,
            b=b,
            mid=mid,
            side=side,
            normals=_unit(side),
            length=length,
            samples=samples,
            scatter=np.einsum("kpi,kpj->kij", weighted, samples),  # each arc's share of a cluster's scatter (_refit's)
            points=np.stack([a, b, mid, side], axis=1),  # (k, 4, 3): what each search takes dot products of
            rank=np.empty(len(a), dtype=np.intp),
            middles=_EndTree(mid),
            ids=np.arange(len(a), dtype=np.intp),
            sin_d=math.sin(math.radians(distance)),
            gap_r=math.radians(gap),
            reach=math.radians(distance) + math.radians(gap),
            polarity=polarity,
        )


def _grow_together(
    seeds: NDArray[np.intp], free: NDArray[np.bool_], setup: _MergeSetup
) -> tuple[NDArray[np.intp], NDArray[np.intp], FloatArray, FloatArray]:
    """Each seed's cluster grown as :func:`merge_arcs`'s loop would if it were next: all seeds at once.

    Seed ``s`` may take the arcs that are ``free`` and after it in the order (``rank``).

    Returns
    -------
    first : ndarray of intp, shape (len(seeds) + 1,)
        Seed ``n`` took ``joined[first[n]:first[n + 1]]``.
    joined : ndarray of intp
        The arcs each seed took, in the order taken.
    normal, origin : ndarray of float64, shape (len(seeds), 3)
        Each cluster's last great circle and origin on it.
    """
    st = setup
    m = len(seeds)
    dot = lambda u, v: np.einsum("ij,ij->i", u, v)  # noqa: E731 - rowwise dot products
    normal = st.normals[seeds].copy()
    origin = st.a[seeds].copy()
    lo = np.zeros(m)
    hi = st.length[seeds].copy()
    longest = hi.copy()  # no arc a seed may take is longer than it
    centre = st.mid[seeds].copy()
    scatter = st.scatter[seeds].copy()
    seed_rank = st.rank[seeds]
    active = np.arange(m)
    got_n: list[NDArray[np.intp]] = []
    got_j: list[NDArray[np.intp]] = []
    own = np.empty(0, dtype=np.int64)  # seed n took arc j: n * k + j
    for _ in range(4):
        radius = 0.5 * (hi[active] - lo[active]) + st.reach + longest[active]
        # the middles near the cluster and within sin_d of its circle (the midpoint test first: it rules out most)
        which, j = st.middles.query(centre[active], radius, normal[active], st.sin_d)
        n, j = active[which], st.ids[j]
        keep = free[j] & (st.rank[j] > seed_rank[n])
        n, j = n[keep], j[keep]
        if own.size:
            keep = ~np.isin(n.astype(np.int64) * len(free) + j, own, assume_unique=True)
            n, j = n[keep], j[keep]
        c = normal[n]
        near = np.maximum(np.abs(dot(st.a[j], c)), np.abs(dot(st.b[j], c))) < st.sin_d
        if st.polarity:  # the same polarity: the dark side on the same side
            near &= dot(st.side[j], c) > 0
        n, j, c = n[near], j[near], c[near]
        o = origin[n]
        other = np.cross(c, o)
        ta = np.arctan2(dot(st.a[j], other), dot(st.a[j], o))
        tb = np.arctan2(dot(st.b[j], other), dot(st.b[j], o))
        c_lo, c_hi = np.minimum(ta, tb), np.maximum(ta, tb)
        low, high = lo[n], hi[n]
        joins = (c_lo <= high + st.gap_r) & (c_hi >= low - st.gap_r) & (c_hi - c_lo < math.pi)
        joins &= np.maximum(high, c_hi) - np.minimum(low, c_lo) < MAX_ARC  # an arc is the shorter way between its ends
        n, j = n[joins], j[joins]
        if n.size == 0:
            break
        got_n.append(n)
        got_j.append(j)
        own = np.sort(np.concatenate([own, n.astype(np.int64) * len(free) + j]))  # a seed's members: no longer its candidates
        np.minimum.at(lo, n, c_lo[joins])
        np.maximum.at(hi, n, c_hi[joins])
        np.add.at(scatter, n, st.scatter[j])
        active = np.unique(n)
        fitted = np.linalg.eigh(scatter[active])[1][:, :, 0]  # _refit's: the smallest eigenvector, signed like the last
        fitted *= np.where(dot(fitted, normal[active]) >= 0, 1.0, -1.0)[:, None]
        normal[active] = fitted
        o = origin[active]
        o = _unit(o - dot(o, fitted)[:, None] * fitted)
        origin[active] = o
        middle = 0.5 * (lo[active] + hi[active])
        centre[active] = np.cos(middle)[:, None] * o + np.sin(middle)[:, None] * np.cross(fitted, o)
    if not got_n:
        return np.zeros(m + 1, dtype=np.intp), np.empty(0, dtype=np.intp), normal, origin
    n = np.concatenate(got_n)
    j = np.concatenate(got_j)
    by_seed = np.argsort(n, kind="stable")
    return np.searchsorted(n[by_seed], np.arange(m + 1)).astype(np.intp), j[by_seed], normal, origin


def _grow_one(seed: int, free: NDArray[np.bool_], setup: _MergeSetup) -> tuple[NDArray[np.intp], FloatArray, FloatArray]:
    """The loop of :func:`merge_arcs` for one seed (already taken from ``free``): its members (sorted), circle and origin; ``free`` updated."""
    st = setup
    sin_d, gap_r = st.sin_d, st.gap_r
    members = [seed]
    normal = st.normals[seed]
    origin = st.a[seed]
    lo, hi = 0.0, float(st.length[seed])
    longest = hi  # no arc not yet taken is longer than the seed
    centre = st.mid[seed]
    for _ in range(4):
        radius = 0.5 * (hi - lo) + st.reach + longest
        cand = st.ids[st.middles.near(centre, radius)]
        cand = cand[free[cand]]
        cand = cand[np.abs(st.mid.take(cand, axis=0) @ normal) < sin_d]  # the midpoint first: it rules out most
        if cand.size == 0:
            break
        other = _cross(normal, origin)
        dots = (st.points.take(cand, axis=0).reshape(-1, 3) @ np.array([normal, other, origin]).T).reshape(-1, 4, 3)
        near = np.abs(dots[:, :2, 0]).max(axis=1) < sin_d
        if st.polarity:  # the same polarity: the dark side on the same side
            near &= dots[:, 3, 0] > 0
        if not near.any():
            break
        cand, dots = cand[near], dots[near]
        ta = np.arctan2(dots[:, 0, 1], dots[:, 0, 2])
        tb = np.arctan2(dots[:, 1, 1], dots[:, 1, 2])
        c_lo, c_hi = np.minimum(ta, tb), np.maximum(ta, tb)
        joins = (c_lo <= hi + gap_r) & (c_hi >= lo - gap_r) & (c_hi - c_lo < math.pi)
        joins &= np.maximum(hi, c_hi) - np.minimum(lo, c_lo) < MAX_ARC  # an arc is the shorter way between its ends
        if not joins.any():
            break
        new = cand[joins]
        members.extend(new.tolist())
        free[new] = False
        lo, hi = min(lo, float(c_lo[joins].min())), max(hi, float(c_hi[joins].max()))
        taken = np.sort(np.array(members))
        normal = _refit(st.samples[taken], st.length[taken], normal)
        origin = _unit(origin - (origin @ normal) * normal)
        middle = 0.5 * (lo + hi)
        centre = math.cos(middle) * origin + math.sin(middle) * _cross(normal, origin)
    return np.sort(np.array(members, dtype=np.intp)), normal, origin


def _finish_many(a: FloatArray, b: FloatArray, length: FloatArray, contrast: FloatArray, grown: list[tuple[NDArray[np.intp], FloatArray, FloatArray]]) -> list[Arc]:
    """:func:`_finish` of each cluster ``(members, normal, origin)``, all at once."""
    if not grown:
        return []
    sizes = np.array([len(g[0]) for g in grown])
    members = np.concatenate([g[0] for g in grown])
    owner = np.repeat(np.arange(len(grown)), sizes)
    normal = np.array([g[1] for g in grown])
    origin = np.array([g[2] for g in grown])
    other = np.cross(normal, origin)
    o, t = origin[owner], other[owner]
    dot = lambda u, v: np.einsum("ij,ij->i", u, v)  # noqa: E731 - rowwise dot products
    ta = np.arctan2(dot(a[members], t), dot(a[members], o))
    tb = np.arctan2(dot(b[members], t), dot(b[members], o))
    lo_each, hi_each = np.minimum(ta, tb), np.maximum(ta, tb)
    first = np.cumsum(sizes) - sizes
    lo = np.minimum.reduceat(lo_each, first)
    hi = np.maximum.reduceat(hi_each, first)
    weight = np.maximum(length[members], 1e-12)
    shade = np.bincount(owner, weights=contrast[members] * weight) / np.bincount(owner, weights=weight)
    # covered share of [lo, hi]: the union of the members' intervals, in order of their starts
    order = np.lexsort((lo_each, owner))
    lows, highs = lo_each[order].tolist(), hi_each[order].tolist()
    covered = []
    for low_c, count, begin in zip(lo.tolist(), sizes.tolist(), first.tolist(), strict=True):
        total, reach = 0.0, low_c
        for low, stop in zip(lows[begin : begin + count], highs[begin : begin + count], strict=True):
            start = max(low, reach)
            if stop > start:
                total += stop - start
                reach = stop
        covered.append(total)
    span = hi - lo
    start_v = np.cos(lo)[:, None] * origin + np.sin(lo)[:, None] * other
    end_v = np.cos(hi)[:, None] * origin + np.sin(hi)[:, None] * other
    return [
        Arc(start=s, end=e, contrast=float(c), coverage=float(min(1.0, cov / sp)) if sp > 0 else 1.0, pieces=int(p))
        for s, e, c, cov, sp, p in zip(start_v, end_v, shade.tolist(), covered, span.tolist(), sizes.tolist(), strict=True)
    ]


def _cross(u: FloatArray, v: FloatArray) -> FloatArray:
    """``np.cross`` of two 3-vectors, the same arithmetic without its overhead."""
    u0, u1, u2 = u.tolist()
    v0, v1, v2 = v.tolist()
    return np.array([u1 * v2 - u2 * v1, u2 * v0 - u0 * v2, u0 * v1 - u1 * v0])


#: Added to every search radius of :class:`_EndTree` (radians): the rounding, and an arc's extent
#: along another circle a little longer than its own length (by ``1 / cos(distance)`` at most).
_TREE_MARGIN = math.radians(1.0)
#: Side of the grid's cubes (:class:`_EndTree`), in the unit vectors' coordinates: about 6 degrees.
_GRID_CELL = 0.1


class _EndTree:
    """Points of arcs (their ends, or their middles) in a grid of cubes: which arcs have one within an angle of a point.

    The unit vectors are binned in cubes of side :data:`_GRID_CELL`, sorted so that each
    column of cubes along z is one run; a query looks in the columns that meet the box around
    its ball (near a great circle, in the cubes of each column that meet that circle's band:
    :meth:`_slab`) and keeps the points inside the ball. numpy alone: no k-d tree to import.

    Parameters
    ----------
    *points : ndarray of float64, shape (k, 3)
        Unit vectors, one of each arc per array: ``a, b`` for the ends, ``mid`` for the middles.
    """

    def __init__(self, *points: FloatArray) -> None:
        self.k = len(points[0])
        every = np.concatenate(points)
        self.m = int(math.ceil(2.0 / _GRID_CELL)) + 1
        cell = np.clip(np.floor((every + 1.0) / _GRID_CELL).astype(np.int64), 0, self.m - 1)
        key = (cell[:, 0] * self.m + cell[:, 1]) * self.m + cell[:, 2]
        order = np.argsort(key, kind="stable")
        self.keys = key[order]
        self.points = every[order]
        # the coordinates apart, each contiguous: gathering from them is several times faster than rows of ``points``
        self.xs, self.ys, self.zs = (np.ascontiguousarray(self.points[:, axis]) for axis in range(3))
        self.owner = (order % self.k).astype(np.intp)
        bounds = np.searchsorted(self.keys, np.arange(self.m**3 + 1))
        self.starts = bounds[:-1].reshape(self.m, self.m, self.m)  # where each cube's points begin in the sorted order
        self.stops = bounds[1:].reshape(self.m, self.m, self.m)  # and end
        self.first, self.last = bounds[:-1], bounds[1:]  # the same, by the flat index of a cube

    @staticmethod
    def _chord(angle: float) -> float:
        """The chord of ``angle`` radians plus :data:`_TREE_MARGIN`, at most a half-turn's (2)."""
        return 2.0 * math.sin(min(angle + _TREE_MARGIN, math.pi) / 2) + 1e-12

    def near(self, point: FloatArray, angle: float) -> NDArray[np.intp]:
        """The arcs with a point within ``angle`` radians (plus :data:`_TREE_MARGIN`) of unit vector ``point``; an arc once per point of it there."""
        chord = self._chord(angle)
        top, cell = self.m - 1, _GRID_CELL
        x, y, z = point.tolist()
        x0, x1 = max(int((x - chord + 1.0) // cell), 0), min(int((x + chord + 1.0) // cell), top)
        y0, y1 = max(int((y - chord + 1.0) // cell), 0), min(int((y + chord + 1.0) // cell), top)
        z0, z1 = max(int((z - chord + 1.0) // cell), 0), min(int((z + chord + 1.0) // cell), top)
        starts = self.starts[x0 : x1 + 1, y0 : y1 + 1, z0].ravel()  # each column's run of cubes z0..z1
        count = self.stops[x0 : x1 + 1, y0 : y1 + 1, z1].ravel() - starts
        found = np.repeat(starts - (np.cumsum(count) - count), count) + np.arange(int(count.sum()))
        near = self.points[found] @ point >= 1.0 - 0.5 * chord * chord  # within the chord: the dot product of unit vectors
        return self.owner[found[near]]

    def query(
        self, points: FloatArray, angles: NDArray | float, circles: FloatArray | None = None, band: float = 0.0
    ) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
        """``(i, j)``: arc ``j`` has a point within ``angles[i]`` radians (plus the margin) of ``points[i]``, all at once.

        With ``circles`` (unit normals, one per point), only the points ``p`` with
        ``|p · circles[i]| < band`` as well: near that great circle.
        """
        cell = _GRID_CELL
        chord = 2.0 * np.sin(np.minimum(np.broadcast_to(np.asarray(angles, dtype=np.float64), len(points)) + _TREE_MARGIN, math.pi) / 2) + 1e-12
        lo = np.clip(np.floor((points - chord[:, None] + 1.0) / cell).astype(np.int64), 0, self.m - 1)
        hi = np.clip(np.floor((points + chord[:, None] + 1.0) / cell).astype(np.int64), 0, self.m - 1)
        nx, ny = hi[:, 0] - lo[:, 0] + 1, hi[:, 1] - lo[:, 1] + 1
        columns = nx * ny
        which = np.repeat(np.arange(len(points), dtype=np.intp), columns)
        local = np.arange(int(columns.sum()), dtype=np.int64) - np.repeat(np.cumsum(columns) - columns, columns)
        across = ny[which]
        cx, cy = lo[which, 0] + local // across, lo[which, 1] + local % across
        z0, z1 = lo[which, 2], hi[which, 2]
        if circles is not None:
            z0, z1 = self._slab(circles, band, which, cx, cy, z0, z1)
            keep = z0 <= z1
            which, cx, cy, z0, z1 = which[keep], cx[keep], cy[keep], z0[keep], z1[keep]
        base = (cx * self.m + cy) * self.m
        starts = self.first[base + z0]
        count = self.last[base + z1] - starts
        which = np.repeat(which, count)
        found = np.repeat(starts - (np.cumsum(count) - count), count) + np.arange(int(count.sum()))
        # the dot products as einsum("ij,ij->i") sums them, (x + z) + y: the same to the bit, on gathered coordinates
        if circles is not None:  # the band first: it rules out most
            c = circles[which]
            near = np.abs((self.xs[found] * c[:, 0] + self.zs[found] * c[:, 2]) + self.ys[found] * c[:, 1]) < band
            found, which = found[near], which[near]
        p = points[which]
        near = (self.xs[found] * p[:, 0] + self.zs[found] * p[:, 2]) + self.ys[found] * p[:, 1] >= (1.0 - 0.5 * chord**2)[which]
        return which[near], self.owner[found[near]]

    @staticmethod
    def _slab(
        circles: FloatArray, band: float, which: NDArray[np.intp], cx: NDArray[np.int64], cy: NDArray[np.int64], z0: NDArray[np.int64], z1: NDArray[np.int64]
    ) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        """The cubes ``z0..z1`` of each column ``(cx, cy)`` narrowed to those that meet the slab ``|p · circles[which]| < band`` (loosened).

        Over the column's square, ``s = x c_x + y c_y`` lies between two bounds, so a point of
        the slab has ``z c_z`` between ``-band - max s`` and ``band - min s``. A ``c_z`` below
        1e-6 in size is taken as 1e-6 (``|z| <= 1``: the slab widened by 1e-5 holds every
        point of the true one), and the bounds are loosened by far more than their rounding.
        """
        cell = _GRID_CELL
        c0, c1 = circles[:, 0], circles[:, 1]
        c2 = np.where(np.abs(circles[:, 2]) < 1e-6, 1e-6, circles[:, 2])
        wide = band + 1e-5
        side = cell + 2e-9  # the column's square, a little wider than the cubes' side
        spread_lo = np.minimum(0.0, side * c0) + np.minimum(0.0, side * c1)
        spread_hi = np.maximum(0.0, side * c0) + np.maximum(0.0, side * c1)
        offset = -(1.0 + 1e-9) * (c0 + c1)  # s at the square's corner (cx, cy) = (0, 0)
        low = -wide - spread_hi - offset  # z c_z > low - s', s' = (cx c_x + cy c_y) cell
        high = wide - spread_lo - offset  # z c_z < high - s'
        up = c2 > 0
        # the cube index of z, (z + 1) / cell, at either bound: a + s' * slope per column
        first = (np.where(up, low, high) / c2 + 1.0) / cell - 1e-7
        last = (np.where(up, high, low) / c2 + 1.0) / cell + 1e-7
        slope = -1.0 / (c2 * cell)
        moved = (cx * (cell * c0)[which] + cy * (cell * c1)[which]) * slope[which]
        z_first = np.floor(np.clip(first[which] + moved, -5.0, 50.0)).astype(np.int64)
        z_last = np.floor(np.clip(last[which] + moved, -5.0, 50.0)).astype(np.int64)
        return np.maximum(z0, z_first), np.minimum(z1, z_last)

    def pairs(
        self, *balls: tuple[FloatArray, FloatArray], circles: FloatArray | None = None, band: float = 0.0
    ) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
        """:meth:`query` of each ``(points, angles)`` given (with ``circles`` and ``band``), together: sorted by ``i`` then ``j``, each pair once, no ``i == j``."""
        keys = []
        for points, angles in balls:
            i, j = self.query(points, angles, circles, band)
            keys.append(i.astype(np.int64) * self.k + j)
        key = np.sort(np.concatenate(keys))
        key = key[np.concatenate([[True], key[1:] != key[:-1]])]  # each pair once
        i, j = key // self.k, key % self.k
        keep = i != j
        return i[keep].astype(np.intp), j[keep].astype(np.intp)


def _single_arcs(a: FloatArray, b: FloatArray, normals: FloatArray, length: FloatArray, contrast: FloatArray, which: NDArray[np.intp]) -> list[Arc]:
    """:func:`_finish` of each arc ``which`` alone (its own circle, origin ``a``), all at once."""
    if which.size == 0:
        return []
    origin, end, n = a[which], b[which], normals[which]
    other = np.cross(n, origin)
    ta = np.arctan2(np.einsum("ij,ij->i", origin, other), np.einsum("ij,ij->i", origin, origin))
    tb = np.arctan2(np.einsum("ij,ij->i", end, other), np.einsum("ij,ij->i", end, origin))
    lo, hi = np.minimum(ta, tb), np.maximum(ta, tb)
    start_v = np.cos(lo)[:, None] * origin + np.sin(lo)[:, None] * other
    end_v = np.cos(hi)[:, None] * origin + np.sin(hi)[:, None] * other
    weight = np.maximum(length[which], 1e-12)
    shade = contrast[which] * weight / weight
    return [Arc(start=s, end=e, contrast=float(c), coverage=1.0, pieces=1) for s, e, c in zip(start_v, end_v, shade, strict=True)]


def pair_bands(arcs: Sequence[Arc], *, distance: float = BAND_DISTANCE, overlap: float = 0.5) -> list[Arc]:
    """Replace the two borders of each painted band or thin dark (or light) line by its midline.

    A thin line a few pixels wide is found as two parallel edges of opposite polarity, a
    little apart. Pairs of arcs of opposite polarity whose points lie within ``distance``
    degrees of each other's great circles and whose extents overlap by at least ``overlap``
    of the shorter become one arc along the bisecting great circle, over the union of
    their extents. Arcs without such a partner are kept as they are. Only arcs with an end
    near an arc can be its partner: the tests run on the pairs a grid of the endpoints
    (:class:`_EndTree`) finds, all at once; then, longest first, each arc not yet paired takes
    the first of its partners with the largest overlap among those not yet taken, as if the
    tests had run on every arc in turn.

    Parameters
    ----------
    arcs : sequence of Arc
        From :func:`merge_arcs` (oriented).
    distance : float
        Degrees.
    overlap : float
        Share of the shorter arc, in ``[0, 1]``.

    Returns
    -------
    list of Arc
    """
    k = len(arcs)
    if k == 0:
        return []
    a = np.array([arc.start for arc in arcs])
    b = np.array([arc.end for arc in arcs])
    normal = _unit(np.cross(a, b))
    length = np.degrees(np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), np.einsum("ij,ij->i", a, b)))
    order = np.argsort(-length)
    rank = np.empty(k, dtype=np.intp)
    rank[order] = np.arange(k)
    i_of, j_of, share = _band_candidates(a, b, normal, length, distance)
    # a partner is one the loop still has free when it comes to i: after i in its order (and not paired since)
    keep = (share >= overlap) & (share > 0.0) & (rank[j_of] > rank[i_of])
    partner, paired = _greedy_partners(k, rank, i_of[keep], j_of[keep], share[keep])
    head = np.flatnonzero(partner >= 0)
    mate = partner[head]
    start_v, end_v, shade = _midlines(a, b, normal, length, np.array([arc.contrast for arc in arcs]), head, mate)
    midline = dict(zip(head.tolist(), range(len(head)), strict=True))
    out: list[Arc] = []
    for i in order.tolist():
        if paired[i]:
            continue
        n = midline.get(i)
        if n is None:
            out.append(arcs[i])
            continue
        best = int(mate[n])
        extent = _degrees_between(start_v[n], end_v[n])
        coverage = max(arcs[i].coverage * length[i], arcs[best].coverage * length[best]) / max(extent, 1e-9)
        out.append(Arc(start_v[n], end_v[n], float(shade[n]), min(1.0, coverage), arcs[i].pieces + arcs[best].pieces))
    return out


def _rowwise_dot(u: NDArray, v: NDArray) -> NDArray:
    """Row-wise dot products of two ``(n, 3)`` arrays."""
    return np.einsum("ij,ij->i", u, v)


def _band_candidates(
    a: FloatArray, b: FloatArray, normal: FloatArray, length: FloatArray, distance: float
) -> tuple[NDArray[np.intp], NDArray[np.intp], FloatArray]:
    """:func:`pair_bands`' pairs ``(i, j)`` that pass its tests but the overlap, and their overlap as a share of the shorter.

    Every pair at once: ``j`` of the other polarity, its points within ``distance`` of
    ``i``'s circle and ``i``'s ends within ``distance`` of ``j``'s; the share is their
    overlap along ``i``'s circle.
    """
    mid = _unit(a + b)
    sin_d = math.sin(math.radians(distance))
    # the partners each arc may have, by the tests below loosened against rounding: a partner no longer
    # than it overlapping it has an end within half its length and ``distance`` of its middle; and
    # one across the far side of its circle (its ends' angles from ``a`` on either side of ±180°,
    # which the overlap takes as the whole turn) has both ends within its length and ``distance`` of ``-a``
    span, d_r = np.radians(length), math.radians(distance)
    # and both its ends lie within ``distance`` of the arc's circle, the end in the ball too (the band loosened against rounding)
    i_of, j_of = _EndTree(a, b).pairs((mid, span / 2 + d_r), (-a, span + d_r), circles=normal, band=sin_d * (1 + 1e-9) + 1e-15)
    dot = _rowwise_dot
    n_i, n_j = normal[i_of], normal[j_of]
    ok = dot(n_j, n_i) < 0
    for points, circles in ((a[j_of], n_i), (b[j_of], n_i), (mid[j_of], n_i), (a[i_of], n_j), (b[i_of], n_j)):
        ok &= np.abs(dot(points, circles)) < sin_d
    i_of, j_of = i_of[ok], j_of[ok]
    a_i, a_j, b_j = a[i_of], a[j_of], b[j_of]
    other = np.cross(normal[i_of], a_i)
    ta = np.arctan2(dot(a_j, other), dot(a_j, a_i))
    tb = np.arctan2(dot(b_j, other), dot(b_j, a_i))
    shared = np.minimum(np.maximum(ta, tb), np.radians(length[i_of])) - np.maximum(np.minimum(ta, tb), 0.0)
    share = shared / np.radians(np.minimum(length[i_of], length[j_of]))
    return i_of, j_of, share


def _greedy_partners(
    k: int, rank: NDArray[np.intp], i_of: NDArray[np.intp], j_of: NDArray[np.intp], share: FloatArray
) -> tuple[NDArray[np.intp], NDArray[np.bool_]]:
    """The greedy choice, longest first: each arc's best free partner (the first of the largest share), in turn.

    Returns each arc's partner (-1 for none) and whether it was taken as another's partner.
    """
    partner = np.full(k, -1, dtype=np.intp)
    paired = np.zeros(k, dtype=bool)  # taken as another's partner
    heads = np.unique(i_of)
    bounds = np.searchsorted(i_of, heads).tolist() + [len(i_of)]
    js, shares = j_of.tolist(), share.tolist()
    for n in np.argsort(rank[heads], kind="stable").tolist():
        i = int(heads[n])
        if paired[i]:
            continue
        best, best_share = -1, 0.0
        for m in range(bounds[n], bounds[n + 1]):
            if shares[m] > best_share and not paired[js[m]]:
                best, best_share = js[m], shares[m]
        if best >= 0:
            paired[best] = True
            partner[i] = best
    return partner, paired


def _midlines(
    a: FloatArray,
    b: FloatArray,
    normal: FloatArray,
    length: FloatArray,
    contrast: FloatArray,
    head: NDArray[np.intp],
    mate: NDArray[np.intp],
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Each pair's midline's ends and contrast, all at once.

    :func:`_finish` of each pair ``(head, mate)``: the same arithmetic, matmul batched as it
    runs one at a time.
    """
    bisector = _unit(normal[head] - normal[mate])
    origin = _unit(a[head] - np.matmul(a[head][:, None, :], bisector[:, :, None])[:, 0] * bisector)
    other = np.cross(bisector, origin)
    ends_a = np.stack([a[head], b[mate]], axis=1)  # b of the opposite arc runs the same way as a of this one
    ends_b = np.stack([b[head], a[mate]], axis=1)
    ta = np.arctan2(np.matmul(ends_a, other[:, :, None])[..., 0], np.matmul(ends_a, origin[:, :, None])[..., 0])
    tb = np.arctan2(np.matmul(ends_b, other[:, :, None])[..., 0], np.matmul(ends_b, origin[:, :, None])[..., 0])
    lo, hi = np.minimum(ta, tb).min(axis=1), np.maximum(ta, tb).max(axis=1)
    start_v = np.cos(lo)[:, None] * origin + np.sin(lo)[:, None] * other
    end_v = np.cos(hi)[:, None] * origin + np.sin(hi)[:, None] * other
    weight = np.maximum(np.stack([length[head], length[mate]], axis=1), 1e-12)
    shade = (np.stack([contrast[head], contrast[mate]], axis=1) * weight).sum(axis=1) / weight.sum(axis=1)
    return start_v, end_v, shade


def _refit(points: NDArray, weights: NDArray, previous: FloatArray) -> FloatArray:
    """The unit normal of the great circle best through ``points`` (k, s, 3), weighted per arc, signed like ``previous``."""
    flat = points.reshape(-1, 3)
    w = np.repeat(weights / points.shape[1], points.shape[1])
    scatter = (flat * w[:, None]).T @ flat
    normal = np.linalg.eigh(scatter)[1][:, 0]
    return normal if normal @ previous >= 0 else -normal


def _finish(a: NDArray, b: NDArray, length: NDArray, contrast: NDArray, normal: FloatArray, origin: FloatArray) -> Arc:
    """The merged arc: the members' extent projected on the fitted circle, and its support."""
    other = _cross(normal, origin)
    ta = np.arctan2(a @ other, a @ origin)
    tb = np.arctan2(b @ other, b @ origin)
    lo_each, hi_each = np.minimum(ta, tb), np.maximum(ta, tb)
    lo, hi = float(lo_each.min()), float(hi_each.max())
    # covered share of [lo, hi]: the union of the members' intervals
    order = np.argsort(lo_each)
    covered, reach = 0.0, lo
    for low, stop in zip(lo_each[order].tolist(), hi_each[order].tolist(), strict=True):
        start = max(low, reach)
        if stop > start:
            covered += stop - start
            reach = stop
    span = hi - lo
    start_v = math.cos(lo) * origin + math.sin(lo) * other
    end_v = math.cos(hi) * origin + math.sin(hi) * other
    weight = np.maximum(length, 1e-12)
    return Arc(
        start=start_v,
        end=end_v,
        contrast=float(np.sum(contrast * weight) / np.sum(weight)),
        coverage=float(min(1.0, covered / span)) if span > 0 else 1.0,
        pieces=len(a),
    )


# --- the suggestions -----------------------------------------------------------------


def _confidence(length: float, contrast: float, coverage: float) -> float:
    """In ``[0, 1]``: saturating in length (degrees) and contrast, times the covered share."""
    return float((1.0 - math.exp(-length / 15.0)) * min(1.0, contrast / 0.15) * coverage)


def suggest_lines(
    image: NDArray,
    *,
    max_lines: int | None = 40,
    min_length: float = 4.0,
    min_contrast: float = 0.04,
    detector: str = "lsd",
    views: Sequence[View] | None = None,
    structure: bool = True,
    up: Sequence[float] | None = None,
) -> list[Suggestion]:
    """Suggest line handles along the straight 3D edges seen in a panorama: the structure first.

    Segments are detected in six overlapping perspective views (:func:`cube_views`),
    lifted to great-circle arcs and merged across views into one arc per edge
    (:func:`merge_arcs`); arcs shorter than ``min_length`` or fainter than
    ``min_contrast`` are dropped and the rest ranked by confidence (length, contrast and
    how much of the arc the detector saw). With ``structure`` (the default) a consistent
    set of the scene's structure is then chosen among them
    (:func:`omniwidget.detect.structure.choose_structure`): each line is given its
    :attr:`~Suggestion.kind`, vertical and horizontal lines rank before other ones, and
    texture (tiles, cobbles, grid paint, mullions: lines crossed more than they bound, or
    dense families of parallel lines), lines crossing a better one and lines running close
    beside a better one are left out, so that the lines can be rectified all at once.

    Parameters
    ----------
    image : ndarray, shape (H, 2H) or (H, 2H, C)
        Equirectangular panorama, uint8, uint16, float32 or float64, 1 to 4 channels; at
        least ``64 x 32``.
    max_lines : int or None
        Keep at most this many, the most confident; None keeps all.
    min_length : float
        Shortest arc suggested, degrees, ``> 0``.
    min_contrast : float
        Faintest edge suggested: brightness step as a share of the full range, ``>= 0``.
    detector : {"lsd", "hough"}
        The 2D segment detector (:func:`detect_segments`).
    views : sequence of View, optional
        The perspective views; :func:`cube_views` of the image's width by default.
    structure : bool
        Choose the consistent structural set (``max_lines`` counts what is kept). False
        gives every line found, ranked by confidence alone and of kind ``"other"``: what
        :func:`omniwidget.detect.level` looks among (it needs every vertical).
    up : (float, float), optional
        ``[lon, lat]`` degrees of the true vertical (:attr:`omniwidget.detect.Level.up`),
        for ``structure``. By default it is found from the lines as
        :func:`~omniwidget.detect.level` finds it, and taken as the zenith (right for a
        level camera) when too few vertical edges are found.

    Returns
    -------
    list of Suggestion
        Best first.

    Raises
    ------
    ImageError
        If ``image`` is not a usable panorama.
    ValueError
        If a parameter is out of range.
    """
    if max_lines is not None and (isinstance(max_lines, bool) or not isinstance(max_lines, int | np.integer) or max_lines < 1):
        raise ValueError(f"max_lines must be a positive integer or None, got {max_lines!r}")
    for name, value, positive in (("min_length", min_length, True), ("min_contrast", min_contrast, False)):
        number = not isinstance(value, bool) and isinstance(value, int | float | np.integer | np.floating) and math.isfinite(value)
        if not number or value < 0 or (positive and value == 0):
            raise ValueError(f"{name} must be a {'positive' if positive else 'non-negative'} number, got {value!r}")
    gray = panorama_gray(image)
    arcs = find_arcs(gray, detector=detector, views=views)
    ends = coords.xyz_to_lonlat(np.array([[arc.start, arc.end] for arc in arcs]).reshape(-1, 2, 3)).tolist()  # all at once
    out = []
    for arc, ((lon0, lat0), (lon1, lat1)) in zip(arcs, ends, strict=True):
        length = arc.length
        if length < min_length or arc.contrast < min_contrast:
            continue
        out.append(
            Suggestion(
                start=(float(lon0), float(lat0)),
                end=(float(lon1), float(lat1)),
                length=length,
                contrast=arc.contrast,
                confidence=_confidence(length, arc.contrast, arc.coverage),
            )
        )
    out.sort(key=lambda s: (-s.confidence, -s.length))
    if structure:
        width = min(int(np.asarray(image).shape[1]), DETECT_WIDTH)  # the width the lines were found at
        chosen = choose_structure(out, up, width=width, max_lines=None if max_lines is None else int(max_lines), image=image)
        return list(chosen.kept)
    return out if max_lines is None else out[: int(max_lines)]


def find_arcs(gray: NDArray[np.uint8], *, detector: str = "lsd", views: Sequence[View] | None = None) -> list[Arc]:
    """Detected segments of every view, lifted and merged: the arcs :func:`suggest_lines` ranks.

    Parameters
    ----------
    gray : ndarray of uint8, shape (H, 2H)
        From :func:`panorama_gray`.
    detector : {"lsd", "hough"}
    views : sequence of View, optional

    Returns
    -------
    list of Arc
    """
    views = cube_views(gray.shape[1]) if views is None else views

    def lifted(view: View) -> tuple[FloatArray, FloatArray, FloatArray]:
        segments, contrast = detect_segments(render_view(gray, view), detector)
        a, b = lift_segments(segments, view)
        return a, b, contrast

    workers = min(len(views), os.cpu_count() or 1)
    if workers > 1:  # the views are independent, and numpy's and OpenCV's work in them lets other threads run
        with ThreadPoolExecutor(workers, thread_name_prefix="omniwidget-detect") as pool:
            found = list(pool.map(lifted, views))
    else:
        found = [lifted(view) for view in views]
    ends_a, ends_b, contrasts = (np.concatenate(part) for part in zip(*found, strict=True)) if found else (np.empty((0, 3)),) * 2 + (np.empty(0),)
    arcs = pair_bands(merge_arcs(ends_a, ends_b, contrasts))
    return _merge_again(arcs)


def _merge_again(arcs: list[Arc]) -> list[Arc]:
    """Merge the midlines and single edges once more, whatever their polarity (pieces of one line cut at junctions)."""
    if not arcs:
        return arcs
    a = np.array([arc.start for arc in arcs])
    b = np.array([arc.end for arc in arcs])
    contrast = np.array([arc.contrast for arc in arcs])
    merged = merge_arcs(a, b, contrast, distance=FINAL_DISTANCE, gap=MERGE_GAP, polarity=False)
    return snap_ends(merged)


def snap_ends(arcs: Sequence[Arc], reach: float = SNAP_REACH) -> list[Arc]:
    """Move each arc's ends to the junction they stop short of.

    A detector stops a few pixels short of where two edges meet (the gradient turns
    there). When another arc's great circle crosses this arc's circle within ``reach``
    degrees of an end, and that crossing lies on (or within ``reach`` of) the other arc,
    the end moves to the nearest such crossing: along its own circle, so the arc stays on
    its edge. The other arcs looked at are those passing near the end (a grid of
    points along each arc, at most a degree apart, :class:`_EndTree`), all ends at once.

    Parameters
    ----------
    arcs : sequence of Arc
    reach : float
        Degrees.

    Returns
    -------
    list of Arc
    """
    k = len(arcs)
    if k < 2:
        return list(arcs)
    a = np.array([arc.start for arc in arcs])
    b = np.array([arc.end for arc in arcs])
    normal = _unit(np.cross(a, b))
    length = np.arccos(np.clip(np.einsum("ij,ij->i", a, b), -1.0, 1.0))
    other = np.cross(normal, a)
    cos_reach = math.cos(math.radians(reach))
    reach_r = math.radians(reach)
    # points along each arc and ``reach`` beyond its ends, at most ``step`` apart: a crossing on the
    # arc so extended lies within ``step / 2`` of one of them
    step = math.radians(1.0)
    count = np.ceil((length + 2 * reach_r) / step).astype(np.intp) + 1
    owner = np.repeat(np.arange(k, dtype=np.intp), count)
    first = np.cumsum(count) - count
    t = -reach_r + (np.arange(len(owner)) - first[owner]) * ((length + 2 * reach_r) / (count - 1))[owner]
    along = np.cos(t)[:, None] * a[owner] + np.sin(t)[:, None] * other[owner]
    ends = np.concatenate([a, b])  # end e of arc i is row e * k + i
    row, sample = _EndTree(along).query(ends, reach_r + step / 2)
    j = owner[sample]
    key = np.sort(row * k + j)
    key = key[np.concatenate([[True], key[1:] != key[:-1]])]  # each pair once
    row, j = key // k, key % k
    i = row % k
    keep = i != j
    row, i, j = row[keep], i[keep], j[keep]
    # the tests of each end against each arc near it
    crossing = np.cross(normal[i], normal[j])
    size = np.linalg.norm(crossing, axis=1)
    usable = size > math.sin(math.radians(10.0))  # circles that cross at a clear angle
    row, j, crossing, size = row[usable], j[usable], crossing[usable], size[usable]
    end = ends[row]
    x = crossing / size[:, None]
    xs = x * np.where(np.einsum("ij,ij->i", x, end) < 0, -1.0, 1.0)[:, None]
    closeness = np.einsum("ij,ij->i", xs, end)
    tj = np.arctan2(np.einsum("ij,ij->i", xs, other[j]), np.einsum("ij,ij->i", xs, a[j]))
    ok = (closeness > cos_reach) & (tj > -reach_r) & (tj < length[j] + reach_r)
    row, j, xs, closeness = row[ok], j[ok], xs[ok], closeness[ok]
    # each end's nearest crossing (the first arc of the nearest, as an argmax)
    order = np.lexsort((j, -closeness, row))
    row, xs = row[order], xs[order]
    lead = np.ones(len(row), dtype=bool)
    lead[1:] = row[1:] != row[:-1]
    snapped: dict[int, FloatArray] = dict(zip(row[lead].tolist(), xs[lead], strict=True))
    out = []
    for n, arc in enumerate(arcs):
        if n in snapped or n + k in snapped:
            out.append(Arc(snapped.get(n, arc.start), snapped.get(n + k, arc.end), arc.contrast, arc.coverage, arc.pieces))
        else:
            out.append(Arc(arc.start, arc.end, arc.contrast, arc.coverage, arc.pieces))
    return out
