"""Synthetic equirectangular scenes whose straight 3D lines are known exactly.

:func:`synthetic_room` ray-casts a box-shaped room, seen from a camera inside it, into an
equirectangular panorama: six pale faces, a dark grid painted on them and thicker dark
lines along the twelve edges of the box. With the room it returns every drawn line as a
:class:`SceneLine`, so tests and teaching notebooks have ground truth for line handles.

Why the ground truth is exact: the straight 3D segment from ``A`` to ``B`` and the camera
span a plane through the camera, so the segment is seen along the great circle where that
plane cuts the viewing sphere. Its image is therefore exactly the geodesic (great-circle
arc, :func:`omniwidget.sphere.coords.geodesic`) between the directions of ``A`` and ``B``.

Frames
------
*Room frame*: the box is axis-aligned, centred at the origin, ``+z`` up; the camera
position is given in this frame, in metres.

*Camera frame*: the camera at the origin, ``+z`` up, and the room turned by ``yaw``
degrees counter-clockwise (seen from above) about the vertical axis. Longitude and
latitude of the panorama are those of :mod:`omniwidget.sphere.coords` in this frame, so a
camera-frame point ``p`` is seen at ``coords.xyz_to_lonlat(p)``. A turn about the vertical
axis only shifts longitudes: the room-frame direction of a pixel at ``(lon, lat)`` is the
direction of ``(lon - yaw, lat)``.

*Tilted camera* (``pitch``, ``roll``): the camera frame is then further turned by the
tilt ``T = R_y(pitch) R_x(roll)``, where ``R_x(a)`` turns by ``a`` degrees right-handedly
about the forward axis ``+x`` (lon 0, lat 0) and ``R_y(a)`` about ``+y`` (lon 90, lat 0):
a level camera-frame direction ``d`` is seen in the tilted panorama at ``T d``. The
zenith is then seen at ``T (0, 0, 1) = (sin p cos r, -sin r, cos p cos r)``; this is the
convention of :class:`omniwidget.detect.Level`.

Faces are named by the room-frame axis they are perpendicular to: ``"west"`` (``-x``),
``"east"`` (``+x``), ``"south"`` (``-y``), ``"north"`` (``+y``), ``"floor"`` (``-z``) and
``"ceiling"`` (``+z``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass, replace
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import whole_number
from ..detect.lines import suggest_lines, suggestions_to_handles
from ..document.handles import CageHandle, Handles, LineHandle, Options, PointHandle
from ..sphere import coords
from ..sphere.arcs import inside_polygon
from .quality import straightness

__all__ = [
    "BOX_ROOM_TOLERANCE",
    "FAMILIES",
    "box_room",
    "edge_coverage",
    "edge_precision",
    "close_pair",
    "closest_latitude",
    "family_scene",
    "lined_room",
    "mark_lines",
    "match_line",
    "FACE_COLORS",
    "FACE_NAMES",
    "LINE_COLOR",
    "Scene",
    "SceneLine",
    "subdivide_line",
    "synthetic_room",
]

#: Face names in index order: face ``i`` is perpendicular to room axis ``i // 2``, on its
#: negative side for even ``i`` and its positive side for odd ``i``.
FACE_NAMES: tuple[str, ...] = ("west", "east", "south", "north", "floor", "ceiling")

#: The pale base colour (RGB, uint8 levels) of each face.
FACE_COLORS: dict[str, tuple[int, int, int]] = {
    "west": (208, 224, 242),  # pale blue
    "east": (242, 214, 210),  # pale pink
    "south": (214, 238, 210),  # pale green
    "north": (240, 232, 196),  # pale yellow
    "floor": (228, 212, 188),  # beige
    "ceiling": (238, 238, 238),  # light grey
}

#: The colour (RGB) of grid lines and edges.
LINE_COLOR: tuple[int, int, int] = (36, 40, 52)

# Row 6 of the palette is the ink; rows 0-5 are the faces in FACE_NAMES order.
_PALETTE = np.array([FACE_COLORS[name] for name in FACE_NAMES] + [LINE_COLOR], dtype=np.uint8)
_INK = len(FACE_NAMES)

# Supersampled pixels ray-cast at a time: bounds the temporary arrays to a few MB.
_SAMPLES_PER_BLOCK = 1 << 16

LonLat = tuple[float, float]
Point3 = tuple[float, float, float]
FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class SceneLine:
    """A straight 3D segment of the scene and its exact image in the panorama.

    Parameters
    ----------
    start, end : (float, float)
        ``[lon, lat]`` in degrees of the endpoints' directions. The segment is drawn along
        the great-circle arc between them (never antipodal: the segment does not pass
        through the camera).
    kind : {"edge", "grid"}
        ``"edge"`` for one of the twelve edges of the box, ``"grid"`` for a grid line.
    start_3d, end_3d : (float, float, float)
        The endpoints in metres, in the camera frame (camera at the origin), so that
        ``coords.xyz_to_lonlat(start_3d) == start``.
    faces : tuple of str
        The face a grid line is painted on, or the two faces an edge joins.
    """

    start: LonLat
    end: LonLat
    kind: Literal["edge", "grid"]
    start_3d: Point3
    end_3d: Point3
    faces: tuple[str, ...] = ()

    @property
    def length(self) -> float:
        """Angular length of the arc in degrees (:func:`coords.angular_distance`)."""
        return float(coords.angular_distance(self.start, self.end))

    @property
    def max_abs_lat(self) -> float:
        """The largest ``|latitude|`` in degrees reached anywhere on the arc.

        An arc can climb higher than both its endpoints, so besides them this checks the
        highest and lowest points of the whole great circle and keeps those on the arc.
        """
        return coords.arc_max_abs_lat(self.start, self.end)

    def distance(self, lonlat: ArrayLike) -> FloatArray:
        """Angular distance from each point to the arc (not the whole great circle), degrees.

        A point whose foot on the great circle falls within the arc is as far as it is from
        the circle; any other is as far as the nearer endpoint.

        Parameters
        ----------
        lonlat : array_like, shape (..., 2)
            ``[lon, lat]`` in degrees.

        Returns
        -------
        ndarray of float64, shape (...)
            Degrees, ``>= 0``.
        """
        points = coords.lonlat_to_xyz(lonlat)
        a, b = coords.lonlat_to_xyz(np.array([self.start, self.end]))
        normal = np.cross(a, b)
        normal /= np.linalg.norm(normal)
        across = np.cross(normal, a)  # a and across span the circle's plane, across towards b
        length = math.atan2(float(np.linalg.norm(np.cross(a, b))), float(a @ b))
        t = np.arctan2(points @ across, points @ a)
        to_circle = np.degrees(np.arcsin(np.clip(np.abs(points @ normal), 0.0, 1.0)))
        # atan2 of sine and cosine: exact near an endpoint too, where arccos of a dot product is not
        to_a = np.arctan2(np.linalg.norm(np.cross(points, a), axis=-1), points @ a)
        to_b = np.arctan2(np.linalg.norm(np.cross(points, b), axis=-1), points @ b)
        to_ends = np.degrees(np.minimum(to_a, to_b))
        return np.where((t >= 0) & (t <= length), to_circle, to_ends)


@dataclass(frozen=True)
class Scene:
    """A rendered synthetic room and the ground truth of its lines.

    Parameters
    ----------
    image : ndarray of uint8, shape (width // 2, width, 3)
        The equirectangular panorama, RGB.
    lines : list of SceneLine
        Every drawn line: the 12 edges first, then the grid lines face by face.
    size : (float, float, float)
        Room dimensions along the room frame's x, y, z, metres.
    camera : (float, float, float)
        Camera position in the room frame, metres.
    yaw : float
        Turn of the room about the vertical axis, degrees counter-clockwise.
    grid : float or None
        Grid spacing in metres, ``None`` for no grid.
    line_width, edge_width : float
        Painted width of grid lines and of edge lines, metres.
    pitch, roll : float
        Tilt of the camera, degrees (the module's *Tilted camera*); 0 for a level camera.
    """

    image: NDArray[np.uint8]
    lines: list[SceneLine]
    size: Point3
    camera: Point3
    yaw: float
    grid: float | None
    line_width: float
    edge_width: float
    pitch: float = 0.0
    roll: float = 0.0

    @property
    def width(self) -> int:
        """Image width in pixels."""
        return int(self.image.shape[1])

    def lines_where(
        self,
        *,
        kind: Literal["edge", "grid"] | None = None,
        min_length: float = 0.0,
        max_length: float = 180.0,
        max_abs_lat: float = 90.0,
    ) -> list[SceneLine]:
        """Pick the lines of a given kind, angular length and latitude range.

        Parameters
        ----------
        kind : {"edge", "grid"}, optional
            Keep only this kind; all kinds by default.
        min_length, max_length : float
            Keep arcs with ``min_length <= length <= max_length`` degrees.
        max_abs_lat : float
            Keep arcs that stay within ``±max_abs_lat`` degrees of latitude everywhere,
            not only at their endpoints.

        Returns
        -------
        list of SceneLine
            In the order of :attr:`lines`.

        Examples
        --------
        Lines 20-60 degrees long, well away from the poles::

            scene.lines_where(min_length=20, max_length=60, max_abs_lat=60)
        """
        if kind not in (None, "edge", "grid"):
            raise ValueError(f"kind must be 'edge', 'grid' or None, got {kind!r}")
        return [
            line
            for line in self.lines
            if (kind is None or line.kind == kind) and min_length <= line.length <= max_length and line.max_abs_lat <= max_abs_lat
        ]

    def face_at(self, lonlat: ArrayLike) -> NDArray[np.str_]:
        """Name of the face seen in each direction.

        Parameters
        ----------
        lonlat : array_like, shape (..., 2)
            ``[lon, lat]`` in degrees.

        Returns
        -------
        ndarray of str, shape (...)
            Names from :data:`FACE_NAMES`.
        """
        lonlat = np.asarray(lonlat, dtype=np.float64)
        if self.pitch == 0.0 and self.roll == 0.0:
            room_lonlat = np.stack([lonlat[..., 0] - self.yaw, lonlat[..., 1]], axis=-1)
            directions = coords.lonlat_to_xyz(room_lonlat)
        else:
            directions = coords.lonlat_to_xyz(lonlat) @ (_tilt_matrix(self.pitch, self.roll) @ _yaw_matrix(self.yaw))
        face, _ = _cast_rays(directions, np.array(self.camera), np.array(self.size) / 2)
        return np.array(FACE_NAMES)[face]


def subdivide_line(line: SceneLine, max_length: float) -> list[SceneLine]:
    """Cut a line into consecutive pieces of at most ``max_length`` degrees each.

    Each piece is again a straight 3D segment (a part of the original), so its image is
    still exactly the geodesic between its endpoints. The cut points are placed at equal
    angles as seen from the camera.

    Parameters
    ----------
    line : SceneLine
    max_length : float
        Longest piece in degrees, ``> 0``.

    Returns
    -------
    list of SceneLine
        ``ceil(line.length / max_length)`` pieces from ``line.start`` to ``line.end``, each
        with the kind and faces of ``line``; ``[line]`` if it is short enough already.
    """
    if not (isinstance(max_length, int | float) and math.isfinite(max_length) and max_length > 0):
        raise ValueError(f"max_length must be a positive number of degrees, got {max_length!r}")
    count = math.ceil(line.length / max_length)
    if count <= 1:
        return [line]
    a = np.array(line.start_3d)
    b = np.array(line.end_3d)
    # An orthonormal pair (u, v) spanning the plane of the camera and the segment, u
    # pointing at the start and v turned towards the end: the direction at angle phi
    # from the start is cos(phi) u + sin(phi) v.
    u = a / np.linalg.norm(a)
    v = b - np.dot(b, u) * u
    v /= np.linalg.norm(v)
    total = math.atan2(np.dot(b, v), np.dot(b, u))
    points = [a]
    for k in range(1, count):
        phi = total * k / count
        points.append(_ray_meets_line(math.cos(phi) * u + math.sin(phi) * v, a, b))
    points.append(b)
    pieces = [_scene_line(p, q, line.kind, line.faces) for p, q in zip(points[:-1], points[1:], strict=True)]
    # Keep the original endpoints bit for bit.
    pieces[0] = replace(pieces[0], start=line.start, start_3d=line.start_3d)
    pieces[-1] = replace(pieces[-1], end=line.end, end_3d=line.end_3d)
    return pieces


def mark_lines(
    scene: Scene,
    count: int,
    *,
    seed: int = 0,
    keep_clear: Sequence[tuple[ArrayLike, float]] = (),
    separation: float = 8.0,
    piece: float = 45.0,
    min_bend: float = 5.0,
    max_abs_lat: float = 65.0,
) -> list[SceneLine]:
    """Pick up to ``count`` of a scene's lines as a person would mark them for rectification.

    Lines are cut into pieces of at most ``piece`` degrees (:func:`subdivide_line`); pieces
    bent by at least ``min_bend`` pixels (from their chord, at the scene's width) are taken
    in a random order and kept when neither they nor their eq. (4) rectified images come
    closer than ``separation`` degrees to a kept line's (except near an endpoint they
    share) or closer than the given distance to any ``keep_clear`` point.

    Parameters
    ----------
    scene : Scene
    count : int
    seed : int
        Seed of the random order.
    keep_clear : sequence of (array_like of shape (p, 2), float)
        ``[lon, lat]`` points and the distance in degrees that lines must keep from them.
    separation, piece, min_bend, max_abs_lat : float
        Degrees, degrees, pixels, degrees.

    Returns
    -------
    list of SceneLine
        At most ``count``, fewer if the scene has no more that fit.
    """
    rng = np.random.default_rng(seed)
    t = np.linspace(0, 1, 60)
    width = scene.image.shape[1]
    candidates = [
        p
        for line in scene.lines_where(max_abs_lat=max_abs_lat)
        for p in subdivide_line(line, piece)
        if straightness(coords.geodesic(p.start, p.end, t), width) >= min_bend
    ]

    def clear(cloud: FloatArray) -> bool:
        return all(coords.angular_distance(cloud[:, None], np.asarray(c, np.float64)[None]).min() >= r for c, r in keep_clear)

    return _pick_lines([candidates[i] for i in rng.permutation(len(candidates))], count, separation, clear, t)


def _line_cloud(line: SceneLine, t: FloatArray) -> FloatArray:
    """A line's samples at parameters ``t`` and their eq. (4) images, ``[lon, lat]``, shape (2 len(t), 2)."""
    src = coords.geodesic(line.start, line.end, t)
    return np.concatenate([src, LineHandle(line.start, line.end).moebius()(src)])


def _pick_lines(
    candidates: Iterable[Any],
    count: int,
    separation: float,
    accept: Callable[[FloatArray], bool] | None = None,
    t: FloatArray | None = None,
    line_of: Callable[[Any], SceneLine | None] = lambda c: c,
) -> list[Any]:
    """The separation logic of :func:`mark_lines`: candidates taken in their order while they keep apart.

    A candidate is kept when ``accept`` takes its cloud (:func:`_line_cloud`: its samples
    and their eq. (4) images) and that cloud keeps ``separation`` degrees from every kept
    line's cloud, except within ``2 * separation`` of an endpoint the two share.
    ``line_of`` gives a candidate's line, or None to pass it over (so that costly
    candidates can be made only when their turn comes).

    Returns
    -------
    list
        The candidates kept, at most ``count``, in their order.
    """
    t = np.linspace(0, 1, 60) if t is None else t
    picked: list[Any] = []
    lines: list[SceneLine] = []
    clouds: list[FloatArray] = []
    for candidate in candidates:
        if len(picked) == count:
            break
        line = line_of(candidate)
        if line is None:
            continue
        cloud = _line_cloud(line, t)
        ok = accept is None or accept(cloud)
        for other, cloud_other in zip(lines, clouds, strict=True):
            far = np.ones(len(cloud), dtype=bool)
            for end in (line.start, line.end):
                if coords.angular_distance(np.array([other.start, other.end]), end).min() < 1e-6:
                    far &= coords.angular_distance(cloud, end) > 2 * separation
            ok = ok and coords.angular_distance(cloud[far][:, None], cloud_other[None]).min(initial=np.inf) >= separation
        if ok:
            picked.append(candidate)
            lines.append(line)
            clouds.append(cloud)
    return picked


#: The rooms of the straightness figures (``lined_room``): seed and number of lines.
LINED_ROOMS = ((1, 6), (2, 8), (3, 10), (4, 8), (5, 7))


def lined_room(seed: int, lines: int, width: int = 2048) -> tuple[Scene, list[SceneLine]]:
    """A room of its own shape and view for each seed, with ``lines`` of its edges marked (the still background's test rooms).

    Parameters
    ----------
    seed : int
        Picks the room's size, the camera's height and turn, and the lines (:func:`mark_lines`).
    lines : int
        How many lines to mark (fewer if the room has fewer suitable ones).
    width : int
        Of the panorama.

    Returns
    -------
    scene : Scene
    marked : list of SceneLine
    """
    scene = synthetic_room(width, size=(4.0 + seed % 2, 3.0, 3.0), camera=(0.3, -0.2, -1.0 + 0.1 * seed), yaw=17.0 + 11 * seed)
    return scene, mark_lines(scene, lines, seed=seed)


def close_pair(
    scene: Scene,
    gap: tuple[float, float] = (5.0, 9.0),
    *,
    piece: float = 40.0,
    min_length: float = 25.0,
    min_bend: float = 2.0,
    max_abs_lat: float = 60.0,
) -> tuple[SceneLine, SceneLine]:
    """Two grid lines of one face, close together, each bent: handles that pull on each other.

    Grid lines are cut into pieces of at most ``piece`` degrees (:func:`subdivide_line`);
    of those at least ``min_length`` degrees long and bent by at least ``min_bend`` pixels
    (from their chord, at the scene's width), the first pair on the same face whose arcs
    come within ``gap`` degrees of each other (their closest samples) is returned.

    Parameters
    ----------
    scene : Scene
        A room with a grid (``grid`` not None).
    gap : (float, float)
        Smallest and largest closest distance between the two arcs, degrees.
    piece, min_length, min_bend, max_abs_lat : float
        Degrees, degrees, pixels, degrees.

    Returns
    -------
    (SceneLine, SceneLine)

    Raises
    ------
    ValueError
        If the scene has no such pair.
    """
    t = np.linspace(0.0, 1.0, 60)
    pieces = [
        p
        for line in scene.lines_where(kind="grid", max_abs_lat=max_abs_lat)
        for p in subdivide_line(line, piece)
        if p.length > min_length and straightness(coords.geodesic(p.start, p.end, t), scene.width) >= min_bend
    ]
    arcs = [coords.geodesic(p.start, p.end, t) for p in pieces]
    for i, a in enumerate(pieces):
        for j in range(i + 1, len(pieces)):
            b = pieces[j]
            if a.faces == b.faces and gap[0] < coords.angular_distance(arcs[i][:, None], arcs[j][None]).min() < gap[1]:
                return a, b
    raise ValueError(f"the scene has no two grid lines of one face within {gap[0]} to {gap[1]} degrees of each other")


# --- scene families ------------------------------------------------------------------

#: The generated scene families of :func:`family_scene`; a family's index here seeds its rooms.
FAMILIES: tuple[str, ...] = ("short", "long", "cage_small", "cage_large", "cage_fixed", "points", "mixed", "room_edges", "suggested")

#: Width (pixels) at which a family's candidate lines must bend: the handles do not depend on the width rendered.
FAMILY_BEND_WIDTH = 2048
#: Least bend of a marked line from its chord, pixels at :data:`FAMILY_BEND_WIDTH`.
FAMILY_MIN_BEND = 5.0
#: Highest ``|latitude|`` (degrees) anywhere on a marked line.
FAMILY_MAX_ABS_LAT = 65.0

#: ``"room_edges"``: latitude range (degrees, north for a ceiling edge, south for a floor edge) of
#: the point of a marked wall-floor or wall-ceiling edge closest to the camera.
ROOM_EDGE_LATITUDES = (20.0, 60.0)
#: ``"room_edges"``: arc (degrees) of a marked horizontal edge, between its clicked ends.
ROOM_EDGE_LENGTHS = (50.0, 150.0)
#: ``"room_edges"``: how far (degrees of arc along the edge) each marked end stops short of the
#: room corner it aims at, drawn uniformly: a person's click lands near a corner, not on it, and
#: two edges meeting there end 1.7-5.4° apart, merged into a joint only when closer than
#: :data:`omniwidget.method.constraints.JOINT_DISTANCE` (2.4°), as in real use.
ROOM_CORNER_GAP = (1.0, 3.0)
#: ``"room_edges"``: highest ``|latitude|`` (degrees) anywhere on a marked line; one degree below
#: :data:`omniwidget.method.constraints.POLE_LATITUDE`, where a line counts as over a pole.
ROOM_MAX_ABS_LAT = 74.0
#: ``"room_edges"``: shortest marked vertical edge, degrees of arc.
ROOM_MIN_VERTICAL = 15.0
#: ``"room_edges"``: least distance (degrees) between two marked lines, except within
#: ``2 * ROOM_SEPARATION`` of a room corner both edges join.
ROOM_SEPARATION = 5.0
#: ``"room_edges"``: lines per scene; of them at least ``ROOM_HORIZONTALS[0]`` horizontal edges and
#: at most ``ROOM_VERTICALS[1]`` vertical ones.
ROOM_LINES = (3, 8)
ROOM_HORIZONTALS = (2, 8)
ROOM_VERTICALS = (0, 3)

#: ``"suggested"``: width (pixels) of the panorama the detector is run on, whatever the width
#: rendered: :data:`omniwidget.detect.DETECT_WIDTH`, the width the detector analyses at.
SUGGESTED_WIDTH = 2048
#: ``"suggested"``: range of ``max_lines`` asked of :func:`omniwidget.detect.suggest_lines`.
SUGGESTED_LINES = (10, 40)
#: ``"suggested"``: a suggestion lies on a scene line when at least :data:`SUGGESTED_SHARE` of
#: its samples are within this many degrees of it (the criterion of the detector's tests).
SUGGESTED_TOLERANCE = 0.5
SUGGESTED_SHARE = 0.8
#: Samples along a suggestion for matching it to a scene line.
_SUGGESTED_SAMPLES = 41
#: The detector's suggestions per room and ``max_lines``, kept for the next call with that room
#: (it is deterministic, and it is by far the slowest step of making a scene).
_SUGGESTIONS: dict[tuple[Any, ...], tuple[Any, ...]] = {}
_SUGGESTIONS_KEPT = 64


def family_scene(family: str, seed: int, width: int = 2048) -> tuple[Scene, Handles, dict[str, Any]]:
    """A generated test scene of one family: a room of its own, its handles, and their ground truth.

    Every seed gives another room: its size (3-9 x 3-8 m, 2.4-4 m high), grid spacing
    (0.75, 1 or 1.25 m), the camera's place (anywhere in the middle 70% of the floor) and
    height (0.7 m above the floor to 0.5 m below the ceiling), and the turn of the room
    (any yaw), all drawn from ``np.random.default_rng((FAMILIES.index(family), seed))``.
    The handles are drawn from the same generator, so they are the same at every
    ``width``: lines are measured at :data:`FAMILY_BEND_WIDTH`, never at the width rendered.

    Families (in the first seven, lines are pieces of the scene's edges and grid lines, each
    bent by at least :data:`FAMILY_MIN_BEND` pixels at 2048 and within
    ±:data:`FAMILY_MAX_ABS_LAT`° of latitude everywhere, keeping 8° from each other as
    :func:`mark_lines` does; the last two say their own rules):

    ``"short"``
        4-8 lines of 15-50° of arc.
    ``"long"``
        3-5 lines of 50-150° of arc.
    ``"cage_small"``
        One cage 10-25° across (even seeds convex, a quadrilateral or pentagon; odd seeds
        not, an L or an arrow) moved rigidly: its targets are its vertices turned by 2-8°
        about a random axis. With it 0-2 lines of 15-40° at least 10° from the cage (from
        its edges before and after the move, and never inside it).
    ``"cage_large"``
        The same with a cage 30-60° across (one seed in four up to 90°).
    ``"cage_fixed"``
        One cage 10-60° across that stays (no targets), convex or not, and 2-4 lines of
        15-50° outside it, at least 5° from its edges; the first within 15° of them.
    ``"points"``
        1-3 point handles (scale 0.6-2.5, log-uniform; rotation ±30°; target 0-5° from the
        position; ``|lat| <= 60``; 25° apart) and 0-3 lines of 15-50° at least 15° from
        every point's position and target.
    ``"mixed"``
        One cage 15-40° across (moved rigidly or fixed, convex or not), 1-2 points and
        3-5 lines of 15-50°, every handle at least 10° from the others.

    ``"room_edges"``
        The long lines a person marks in a room: its own edges, not pieces of them and not
        the grid. 3-8 lines (:data:`ROOM_LINES`): 2-8 wall-floor and wall-ceiling edges
        whose point closest to the camera is seen at 20-60° of latitude
        (:data:`ROOM_EDGE_LATITUDES`; south for the floor's, north for the ceiling's) and
        whose marked arc is 50-150° (:data:`ROOM_EDGE_LENGTHS`), then 0-3 vertical
        wall-wall edges (:data:`ROOM_VERTICALS`; more if needed to make 3 lines) of at
        least :data:`ROOM_MIN_VERTICAL`°. Each is marked from near one room corner to
        near the other: every end that aims at a corner stops short of it by 1-3° along
        the edge (:data:`ROOM_CORNER_GAP`), as clicks do; two edges meeting at a corner
        end there 1.7-5.4° apart, a joint of the method when closer than its
        ``JOINT_DISTANCE`` (one corner pair in ten, seeds 0-199). A vertical edge is
        cut where it would pass :data:`ROOM_MAX_ABS_LAT`° (74: one degree short of the
        method's pole lines), so every line stays within ±74° everywhere. Lines keep
        :data:`ROOM_SEPARATION` (5°) apart except within 10° of a corner both join. The
        bend of a line is not asked for (a vertical edge is straight in the panorama), and
        the grid is drawn but never marked. Horizontal edges come first, in a random order,
        then the verticals.
    ``"suggested"``
        The lines :func:`omniwidget.detect.suggest_lines` gives on the room (what
        ``omniwidget suggest`` writes): the room is rendered at :data:`SUGGESTED_WIDTH` (2048,
        the detector's own analysis width) whatever ``width`` is, so the handles are the
        same at every width; ``max_lines`` is drawn in 10-40 (:data:`SUGGESTED_LINES`), and
        the handles are :func:`omniwidget.detect.suggestions_to_handles` of them, best
        first (ids suggested-1, suggested-2 and on; rectified). There are ``max_lines`` of them
        unless the detector finds fewer (then all it finds; never on seeds 0-39). Each
        suggestion's ground truth is the scene line it lies on (:func:`match_line`:
        :data:`SUGGESTED_SHARE` of its samples within :data:`SUGGESTED_TOLERANCE` degrees of
        it); the few that lie on no single line (an arc joining two walls' grid lines
        along the horizon, say) stay among the handles, as a person accepting every
        suggestion keeps them, and are listed in ``"unmatched_handles"``. Suggestions
        may climb past ±75° of latitude (a ceiling line over the camera), as on photos.
        The detector is the slow step; its suggestions are kept for the next call with
        the same room (it is deterministic).

    Cages keep their vertices in order around the polygon, are at most 90° across (far
    smaller than a hemisphere) and hold no point and no line.

    Parameters
    ----------
    family : str
        One of :data:`FAMILIES`.
    seed : int
        ``>= 0``; any seed makes a scene (0-39 are the benches').
    width : int
        Of the rendered panorama (:func:`synthetic_room`), even, ``>= 8``.

    Returns
    -------
    scene : Scene
        The room, rendered at ``width``.
    handles : Handles
        The handles, with the default options (``Options()``: rectify ``"all"``, the still
        background on): lines first, then the cage, then the points.
    truth : dict
        The ground truth the measurements need:

        - ``"family"`` (str), ``"seed"`` (int);
        - ``"lines"``: the marked :class:`SceneLine` of each line handle of
          ``"line_handles"``, in order (for ``"suggested"``: the part of the scene line the
          suggestion spans, its ends' feet on the line, within the line; the handle's own
          ends are the detector's: a few tenths of a degree off the line, or beyond its
          end where the detector ran on past it, as far as 10°);
        - ``"parents"``: for each, the full scene line it was cut from (a marked line
          continues beyond its ends when it is shorter than its parent);
        - ``"line_handles"``, ``"cage_handles"``, ``"point_handles"``: lists of int, the
          handles' indices in ``handles.handles`` (line handles with a ground truth);
        - ``"unmatched_handles"``: list of int, the line handles on no single scene line
          (only in ``"suggested"``; empty in the other families);
        - ``"horizontal"`` (``"room_edges"`` only): list of bool, for each line whether it
          is a wall-floor or wall-ceiling edge (else a vertical wall-wall edge);
        - ``"max_lines"`` (``"suggested"`` only): int, the most suggestions asked for;
        - ``"rotations"``: for each cage, its rigid motion, a 3 x 3 float64 rotation
          matrix acting on unit vectors (``targets = R @ vertices``; the identity for a
          fixed cage);
        - ``"convex"`` (list of bool) and ``"across"`` (list of float, degrees: the largest
          distance between two vertices), for each cage.

    Raises
    ------
    ValueError
        For an unknown family, a negative or non-integer seed, or a bad width.
    RuntimeError
        For ``"room_edges"``, if 20 rooms in a row have too few edges to mark (never seen).

    Examples
    --------
    ::

        scene, doc, truth = family_scene("cage_small", 3, width=1024)
        result = omniwidget.warp(scene.image, doc)
        quality.cage_fidelity(result, truth["cage_handles"][0], truth["rotations"][0])
    """
    if not isinstance(family, str) or family not in FAMILIES:
        raise ValueError(f"family must be one of {', '.join(FAMILIES)}, got {family!r}")
    seed = whole_number(seed, "seed", 0)
    width = whole_number(width, "width", 8)
    rng = np.random.default_rng((FAMILIES.index(family), seed))
    if family == "suggested":
        return _suggested_scene(rng, seed, width)
    if family == "room_edges":
        room, edges = _room_edges(rng, seed)
        scene = synthetic_room(width, **room)
        doc = Handles(tuple(LineHandle(line.start, line.end) for line, _ in edges), Options())
        return scene, doc, _line_truth(family, seed, edges) | {"horizontal": [_is_horizontal(p) for _, p in edges]}
    room = _room_parameters(rng)
    scene = synthetic_room(width, **room)

    lines: list[tuple[SceneLine, SceneLine]] = []
    cages: list[_Cage] = []
    points: list[PointHandle] = []
    if family == "short":
        lines = _family_lines(scene, rng, int(rng.integers(4, 9)), (15.0, 50.0))
    elif family == "long":
        lines = _family_lines(scene, rng, int(rng.integers(3, 6)), (50.0, 150.0), samples=120)
    elif family in ("cage_small", "cage_large"):
        if family == "cage_small":
            across = rng.uniform(10.0, 25.0)
        else:
            across = rng.uniform(60.0, 90.0) if seed % 4 == 3 else rng.uniform(30.0, 60.0)
        cage = _random_cage(rng, across, convex=seed % 2 == 0, moved=True)
        cages.append(cage)
        lines = _family_lines(scene, rng, int(rng.integers(0, 3)), (15.0, 40.0), accept=cage.clear_of(10.0))
    elif family == "cage_fixed":
        for _ in range(50):
            cage = _random_cage(rng, rng.uniform(10.0, 60.0), convex=bool(rng.integers(0, 2)), moved=False)
            first = _family_lines(scene, rng, 1, (15.0, 50.0), accept=cage.clear_of(5.0, within=15.0))
            if first:
                break
        else:  # pragma: no cover - every room has grid lines near any cage
            raise RuntimeError(f"no line found near a fixed cage for seed {seed}")
        cages.append(cage)
        more = _family_lines(scene, rng, int(rng.integers(1, 4)), (15.0, 50.0), accept=cage.clear_of(5.0), kept=[first[0][0]])
        lines = first + more
    elif family == "points":
        points = _random_points(rng, int(rng.integers(1, 4)))
        lines = _family_lines(scene, rng, int(rng.integers(0, 4)), (15.0, 50.0), accept=_clear_of_points(points, 15.0))
    else:  # mixed
        cage = _random_cage(rng, rng.uniform(15.0, 40.0), convex=bool(rng.integers(0, 2)), moved=bool(rng.integers(0, 2)))
        cages.append(cage)
        points = _random_points(rng, int(rng.integers(1, 3)), accept=cage.clear_of(10.0))
        near_cage, near_points = cage.clear_of(10.0), _clear_of_points(points, 10.0)
        lines = _family_lines(
            scene, rng, int(rng.integers(3, 6)), (15.0, 50.0), accept=lambda cloud: near_cage(cloud) and near_points(cloud)
        )

    handles: list[Any] = [LineHandle(line.start, line.end) for line, _ in lines]
    handles += [CageHandle(c.vertices, c.targets) for c in cages]
    handles += points
    n_lines, n_cages = len(lines), len(cages)
    truth = _line_truth(family, seed, lines) | {
        "cage_handles": list(range(n_lines, n_lines + n_cages)),
        "point_handles": list(range(n_lines + n_cages, len(handles))),
        "rotations": [c.rotation for c in cages],
        "convex": [c.convex for c in cages],
        "across": [c.across for c in cages],
    }
    return scene, Handles(tuple(handles), Options()), truth


def _line_truth(
    family: str, seed: int, lines: Sequence[tuple[SceneLine, SceneLine]], line_handles: Sequence[int] | None = None
) -> dict[str, Any]:
    """The ground truth of a scene of line handles only; the other families add their cages and points (:func:`family_scene`)."""
    return {
        "family": family,
        "seed": seed,
        "lines": [line for line, _ in lines],
        "parents": [parent for _, parent in lines],
        "line_handles": list(range(len(lines))) if line_handles is None else list(line_handles),
        "unmatched_handles": [],
        "cage_handles": [],
        "point_handles": [],
        "rotations": [],
        "convex": [],
        "across": [],
    }


# --- the room's own edges (family "room_edges") -----------------------------------------


def _is_horizontal(edge: SceneLine) -> bool:
    """Whether a (level camera's) edge of the box is a wall-floor or wall-ceiling edge."""
    return "floor" in edge.faces or "ceiling" in edge.faces


def closest_latitude(line: SceneLine) -> float:
    """Latitude (degrees, signed) of the point of a line's 3D segment closest to the camera.

    For a horizontal segment seen by a level camera this is also where its arc climbs
    highest (north) or lowest (south): its :attr:`SceneLine.max_abs_lat`, with a sign.
    """
    p, q = np.array(line.start_3d), np.array(line.end_3d)
    step = q - p
    s = float(np.clip(-np.dot(p, step) / np.dot(step, step), 0.0, 1.0))
    return float(coords.xyz_to_lonlat(p + s * step)[1])


def _room_edges(rng: np.random.Generator, seed: int, attempts: int = 20) -> tuple[dict[str, Any], list[tuple[SceneLine, SceneLine]]]:
    """A room and its marked edges for ``"room_edges"``: ``(synthetic_room keywords, [(marked, edge)])``.

    Rooms are drawn (:func:`_room_parameters`) until one has :data:`ROOM_HORIZONTALS` ``[0]``
    horizontal edges that qualify; every room of seeds 0-199 has at the first draw.
    """
    for _ in range(attempts):
        room = _room_parameters(rng)
        edges = [line for line in synthetic_room(8, **room).lines if line.kind == "edge"]  # the lines do not depend on the width
        gaps = rng.uniform(*ROOM_CORNER_GAP, size=(len(edges), 2))
        horizontal, vertical = [], []
        for edge, (gap_start, gap_end) in zip(edges, gaps, strict=True):
            if _is_horizontal(edge):
                lat = abs(closest_latitude(edge))
                piece = _sub_line(edge, float(gap_start), edge.length - float(gap_end))
                if ROOM_EDGE_LATITUDES[0] <= lat <= ROOM_EDGE_LATITUDES[1] and ROOM_EDGE_LENGTHS[0] <= piece.length <= ROOM_EDGE_LENGTHS[1]:
                    horizontal.append((piece, edge))
            else:  # floor corner to ceiling corner, along a meridian: arc from the start = latitude climbed
                low, high = edge.start[1], edge.end[1]
                a = float(gap_start) if low >= -ROOM_MAX_ABS_LAT else -ROOM_MAX_ABS_LAT - low
                b = edge.length - float(gap_end) if high <= ROOM_MAX_ABS_LAT else ROOM_MAX_ABS_LAT - low
                if b - a >= ROOM_MIN_VERTICAL:
                    vertical.append((_sub_line(edge, a, b), edge))
        n_vertical = int(rng.integers(ROOM_VERTICALS[0], ROOM_VERTICALS[1] + 1))
        n_horizontal = int(rng.integers(max(ROOM_HORIZONTALS[0], ROOM_LINES[0] - n_vertical), ROOM_LINES[1] - n_vertical + 1))
        picked: list[tuple[SceneLine, SceneLine]] = []
        horizontal = [horizontal[i] for i in rng.permutation(len(horizontal))]
        vertical = [vertical[i] for i in rng.permutation(len(vertical))]
        _add_apart(picked, horizontal, n_horizontal)
        if len(picked) < ROOM_HORIZONTALS[0]:
            continue
        _add_apart(picked, vertical, max(n_vertical, ROOM_LINES[0] - len(picked)))
        if len(picked) >= ROOM_LINES[0]:
            return room, picked
    raise RuntimeError(f"no room with {ROOM_HORIZONTALS[0]} horizontal edges to mark found in {attempts} draws for seed {seed}")


def _add_apart(picked: list[tuple[SceneLine, SceneLine]], candidates: Sequence[tuple[SceneLine, SceneLine]], count: int) -> None:
    """Append to ``picked`` up to ``count`` candidates, in order, that keep :data:`ROOM_SEPARATION` from every picked line.

    Near a room corner that both edges join (within ``2 * ROOM_SEPARATION`` of it) they may
    come closer: they meet there.
    """
    t = np.linspace(0.0, 1.0, 60)
    added = 0
    for piece, edge in candidates:
        if added == count:
            return
        cloud = coords.geodesic(piece.start, piece.end, t)
        ok = True
        for other_piece, other in picked:
            other_cloud = coords.geodesic(other_piece.start, other_piece.end, t)
            keep, keep_other = np.ones(len(t), dtype=bool), np.ones(len(t), dtype=bool)
            for corner in (edge.start_3d, edge.end_3d):
                if any(np.allclose(corner, c, atol=1e-9) for c in (other.start_3d, other.end_3d)):
                    where = coords.xyz_to_lonlat(np.array(corner))
                    keep &= coords.angular_distance(cloud, where) > 2 * ROOM_SEPARATION
                    keep_other &= coords.angular_distance(other_cloud, where) > 2 * ROOM_SEPARATION
            if coords.angular_distance(cloud[keep][:, None], other_cloud[keep_other][None]).min(initial=np.inf) < ROOM_SEPARATION:
                ok = False
                break
        if ok:
            picked.append((piece, edge))
            added += 1


# --- the detector's suggestions (family "suggested") -------------------------------------


def _suggested_scene(rng: np.random.Generator, seed: int, width: int) -> tuple[Scene, Handles, dict[str, Any]]:
    """The ``"suggested"`` family's scene, handles and truth (:func:`family_scene`)."""
    room = _room_parameters(rng)
    max_lines = int(rng.integers(SUGGESTED_LINES[0], SUGGESTED_LINES[1] + 1))
    scene = synthetic_room(width, **room)
    key = (tuple(sorted(room.items())), max_lines)
    suggestions = _SUGGESTIONS.get(key)
    if suggestions is None:
        image = scene.image if width == SUGGESTED_WIDTH else synthetic_room(SUGGESTED_WIDTH, **room).image
        # the detector's ranked lines, without the structure's choice (structure=False): the family's figures are of those
        suggestions = tuple(suggest_lines(image, max_lines=max_lines, structure=False))
        if len(_SUGGESTIONS) >= _SUGGESTIONS_KEPT:
            del _SUGGESTIONS[next(iter(_SUGGESTIONS))]
        _SUGGESTIONS[key] = suggestions
    handles = suggestions_to_handles(suggestions, Options())
    matched: list[tuple[SceneLine, SceneLine]] = []
    indices: list[int] = []
    for i, s in enumerate(suggestions):
        parent = match_line(scene.lines, s.start, s.end)
        if parent is not None:
            matched.append((_span_on(parent, s.start, s.end), parent))
            indices.append(i)
    truth = _line_truth("suggested", seed, matched, indices)
    truth["unmatched_handles"] = [i for i in range(len(suggestions)) if i not in indices]
    truth["max_lines"] = max_lines
    return scene, handles, truth


def match_line(lines: Sequence[SceneLine], start: ArrayLike, end: ArrayLike) -> SceneLine | None:
    """The scene line an arc lies on, as the detector's tests decide it, or None.

    The arc from ``start`` to ``end`` lies on a line when at least :data:`SUGGESTED_SHARE`
    of its samples (41, evenly spread) are within :data:`SUGGESTED_TOLERANCE` degrees of
    the line's arc (:meth:`SceneLine.distance`); of several such lines, the one with the
    most samples that close, then the smallest mean distance, is returned.

    Parameters
    ----------
    lines : sequence of SceneLine
    start, end : array_like, shape (2,)
        ``[lon, lat]`` in degrees.

    Returns
    -------
    SceneLine or None
    """
    samples = coords.geodesic(start, end, np.linspace(0.0, 1.0, _SUGGESTED_SAMPLES))
    best, best_key = None, (SUGGESTED_SHARE, -math.inf)
    for line in lines:
        d = line.distance(samples)
        key = (float(np.mean(d <= SUGGESTED_TOLERANCE)), -float(np.mean(d)))
        if key >= best_key:
            best, best_key = line, key
    return best


def _span_on(line: SceneLine, start: ArrayLike, end: ArrayLike) -> SceneLine:
    """The part of ``line`` an arc from ``start`` to ``end`` spans: its ends' feet on the line's great circle, kept within the line."""
    p, q = np.array(line.start_3d), np.array(line.end_3d)
    u = p / np.linalg.norm(p)
    v = q - np.dot(q, u) * u
    v /= np.linalg.norm(v)
    total = math.atan2(float(np.dot(q, v)), float(np.dot(q, u)))
    ends = []
    for direction in coords.lonlat_to_xyz(np.array([start, end], dtype=np.float64)):
        phi = float(np.clip(math.atan2(float(direction @ v), float(direction @ u)), 0.0, total))
        ends.append(_ray_meets_line(math.cos(phi) * u + math.sin(phi) * v, p, q))
    return _scene_line(ends[0], ends[1], line.kind, line.faces)


def _room_parameters(rng: np.random.Generator) -> dict[str, Any]:
    """A room's size, grid, camera and yaw (keyword arguments of :func:`synthetic_room`)."""
    size = np.array([rng.uniform(3.0, 9.0), rng.uniform(3.0, 8.0), rng.uniform(2.4, 4.0)])
    height = rng.uniform(0.7, size[2] - 0.5)  # above the floor
    camera = (rng.uniform(-0.35, 0.35) * size[0], rng.uniform(-0.35, 0.35) * size[1], height - size[2] / 2)
    return {
        "size": tuple(float(v) for v in size),
        "camera": tuple(float(v) for v in camera),
        "yaw": float(rng.uniform(-180.0, 180.0)),
        "grid": float(rng.choice([0.75, 1.0, 1.25])),
    }


def _sub_line(line: SceneLine, a: float, b: float) -> SceneLine:
    """The part of ``line`` from ``a`` to ``b`` degrees of arc from its start (``0 <= a < b <= line.length``)."""
    p, q = np.array(line.start_3d), np.array(line.end_3d)
    u = p / np.linalg.norm(p)
    v = q - np.dot(q, u) * u
    v /= np.linalg.norm(v)
    ends = [_ray_meets_line(math.cos(math.radians(phi)) * u + math.sin(math.radians(phi)) * v, p, q) for phi in (a, b)]
    return _scene_line(ends[0], ends[1], line.kind, line.faces)


def _family_lines(
    scene: Scene,
    rng: np.random.Generator,
    count: int,
    lengths: tuple[float, float],
    *,
    accept: Callable[[FloatArray], bool] | None = None,
    kept: Sequence[SceneLine] = (),
    samples: int = 60,
) -> list[tuple[SceneLine, SceneLine]]:
    """Up to ``count`` pieces of the scene's lines, ``lengths`` degrees long, each with the line it was cut from.

    Each line is cut into consecutive pieces of one random length in ``lengths``, from a
    random offset (a line no longer than that length is a piece whole). Pieces bent by at
    least :data:`FAMILY_MIN_BEND` px at :data:`FAMILY_BEND_WIDTH`, within
    :data:`FAMILY_MAX_ABS_LAT`, are taken in a random order and kept as :func:`mark_lines`
    keeps them (:func:`_pick_lines`), also apart from the lines ``kept`` already.
    """
    if count == 0:
        return []
    t = np.linspace(0.0, 1.0, samples)
    cuts: list[tuple[SceneLine, float, float]] = []
    for line in scene.lines:
        total = line.length
        if total < lengths[0]:
            continue
        size = float(rng.uniform(*lengths))
        if total <= size:
            cuts.append((line, 0.0, total))
        else:
            offset = float(rng.uniform(0.0, min(size, total - size)))
            cuts += [(line, a, a + size) for a in offset + size * np.arange(int((total - offset) // size))]

    def piece_of(cut: tuple[SceneLine, float, float]) -> SceneLine | None:
        """The cut's piece if it may be marked, else None; made only when its turn comes."""
        line, a, b = cut
        piece = line if (a, b) == (0.0, line.length) else _sub_line(line, a, b)
        if piece.max_abs_lat > FAMILY_MAX_ABS_LAT or not lengths[0] - 1e-9 <= piece.length <= lengths[1] + 1e-9:
            return None
        if straightness(coords.geodesic(piece.start, piece.end, t), FAMILY_BEND_WIDTH) < FAMILY_MIN_BEND:
            return None
        return piece

    pieces: dict[int, SceneLine | None] = {}

    def line_of(item: tuple[int, Any]) -> SceneLine | None:
        index, what = item
        if index < 0:  # a line kept already
            return what
        pieces[index] = piece_of(what)
        return pieces[index]

    order = [(-1, line) for line in kept] + [(int(i), cuts[i]) for i in rng.permutation(len(cuts))]
    picked = _pick_lines(order, count + len(kept), 8.0, accept, t, line_of)
    # the kept lines were kept clear of each other before; a picked cut's piece is never None (line_of passed it)
    return [(piece, cut[0]) for i, cut in picked if i >= 0 and (piece := pieces[i]) is not None]


def _min_distance(a: FloatArray, b: FloatArray) -> float:
    """Smallest angular distance (degrees) between two sets of unit vectors, (n, 3) and (m, 3)."""
    if len(a) == 0 or len(b) == 0:
        return math.inf
    return float(np.degrees(np.arccos(np.clip(np.max(a @ b.T), -1.0, 1.0))))


def _edge_samples(vertices: FloatArray, step: float = 0.5) -> FloatArray:
    """Unit vectors every ``step`` degrees or closer along a closed polygon's great-circle edges, (m, 3)."""
    out = []
    for a, b in zip(vertices, np.roll(vertices, -1, axis=0), strict=True):
        n = max(2, math.ceil(float(coords.angular_distance(a, b)) / step) + 1)
        out.append(coords.lonlat_to_xyz(coords.geodesic(a, b, np.linspace(0.0, 1.0, n))[:-1]))
    return np.concatenate(out)


@dataclass(frozen=True)
class _Cage:
    """A generated cage: vertices and targets ``[lon, lat]``, its rigid motion and its shape."""

    vertices: tuple[LonLat, ...]
    targets: tuple[LonLat, ...] | None
    rotation: FloatArray
    convex: bool
    across: float

    def clear_of(self, distance: float, within: float | None = None) -> Callable[[FloatArray], bool]:
        """A test of ``[lon, lat]`` points: outside the cage before and after its move, ``distance`` or more from its edges.

        With ``within``, also no farther than that from them.
        """
        polygons = [np.array(self.vertices)] + ([np.array(self.targets)] if self.targets is not None else [])
        edges = np.concatenate([_edge_samples(p) for p in polygons])

        def test(lonlat: FloatArray) -> bool:
            gap = _min_distance(coords.lonlat_to_xyz(lonlat), edges)
            if gap < distance or (within is not None and gap > within):
                return False
            return not any(inside_polygon(lonlat, p).any() for p in polygons)

        return test


def _outline(rng: np.random.Generator, convex: bool) -> FloatArray:
    """A planar polygon, vertices counter-clockwise, centred, 1 across: a quadrilateral or pentagon, or an L or an arrow."""
    if convex:
        n = int(rng.choice([4, 5]))
        while True:
            angles = 2 * np.pi * (np.arange(n) + rng.uniform(-0.25, 0.25, n)) / n
            pts = rng.uniform(0.7, 1.0, n)[:, None] * np.stack([np.cos(angles), np.sin(angles)], axis=1)
            edges = np.roll(pts, -1, axis=0) - pts
            turns = edges[:, 0] * np.roll(edges, -1, axis=0)[:, 1] - edges[:, 1] * np.roll(edges, -1, axis=0)[:, 0]
            if np.all(turns > 0) and np.min(np.hypot(*edges.T)) > 0.4:
                break
    elif rng.integers(0, 2):  # an L: a w x h box without its top right corner
        w, h = 1.0, rng.uniform(0.6, 1.0)
        arm_x, arm_y = rng.uniform(0.3, 0.55) * w, rng.uniform(0.3, 0.55) * h
        pts = np.array([[0, 0], [w, 0], [w, arm_y], [arm_x, arm_y], [arm_x, h], [0, h]])
    else:  # an arrow along +x
        shaft, half_shaft, half_head = rng.uniform(0.45, 0.7), rng.uniform(0.1, 0.2), rng.uniform(0.3, 0.45)
        pts = np.array(
            [[0, -half_shaft], [shaft, -half_shaft], [shaft, -half_head], [1, 0], [shaft, half_head], [shaft, half_shaft], [0, half_shaft]]
        )
    turn = rng.uniform(0.0, 2 * np.pi)
    c, s = math.cos(turn), math.sin(turn)
    pts = (pts - pts.mean(axis=0)) @ np.array([[c, s], [-s, c]])
    return pts / np.max(np.hypot(*(pts[:, None] - pts[None]).transpose(2, 0, 1)))


def _rotation_matrix(axis: FloatArray, angle: float) -> FloatArray:
    """Rotation by ``angle`` degrees about the unit vector ``axis`` (Rodrigues), acting on column vectors."""
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    theta = math.radians(angle)
    return np.eye(3) + math.sin(theta) * k + (1 - math.cos(theta)) * (k @ k)


def _random_cage(rng: np.random.Generator, across: float, *, convex: bool, moved: bool) -> _Cage:
    """A cage ``across`` degrees across (gnomonic about a random centre: its planar outline's edges are its great circles)."""
    outline = _outline(rng, convex)
    centre = np.array([rng.uniform(-180.0, 180.0), rng.uniform(-1.0, 1.0) * max(5.0, 60.0 - across / 2)])
    c = coords.lonlat_to_xyz(centre)
    east, north = coords.local_frame(centre)
    scale = 2 * math.tan(math.radians(across) / 2)
    for _ in range(30):  # the gnomonic projection stretches away from the centre: scale until the size is right
        xyz = c + scale * (outline[:, :1] * east + outline[:, 1:] * north)
        xyz /= np.linalg.norm(xyz, axis=1, keepdims=True)
        size = float(np.degrees(np.arccos(np.clip(np.min(xyz @ xyz.T), -1.0, 1.0))))
        if abs(size - across) < 1e-6:
            break
        scale *= across / size
    vertices = coords.xyz_to_lonlat(xyz)
    if moved:
        axis = rng.normal(size=3)
        rotation = _rotation_matrix(axis / np.linalg.norm(axis), float(rng.uniform(2.0, 8.0) * rng.choice([-1.0, 1.0])))
        targets = tuple((float(lon), float(lat)) for lon, lat in coords.xyz_to_lonlat(xyz @ rotation.T))
    else:
        rotation, targets = np.eye(3), None
    return _Cage(tuple((float(lon), float(lat)) for lon, lat in vertices), targets, rotation, convex, size)


def _clear_of_points(points: Sequence[PointHandle], distance: float) -> Callable[[FloatArray], bool]:
    """A test of ``[lon, lat]`` points: ``distance`` degrees or more from every point handle's position and target."""
    where = coords.lonlat_to_xyz(np.array([p for h in points for p in (h.position, h.final)]).reshape(-1, 2))
    return lambda lonlat: _min_distance(coords.lonlat_to_xyz(lonlat), where) >= distance


def _random_points(
    rng: np.random.Generator, count: int, *, accept: Callable[[FloatArray], bool] | None = None, apart: float = 25.0
) -> list[PointHandle]:
    """Up to ``count`` point handles, ``apart`` degrees from each other, whose position and target ``accept`` takes."""
    out: list[PointHandle] = []
    for _ in range(200 * count):
        if len(out) == count:
            break
        position = np.array([rng.uniform(-180.0, 180.0), math.degrees(math.asin(rng.uniform(-1.0, 1.0) * math.sin(math.radians(60.0))))])
        distance, bearing = math.radians(rng.uniform(0.0, 5.0)), rng.uniform(0.0, 2 * np.pi)
        east, north = coords.local_frame(position)
        heading = math.cos(bearing) * east + math.sin(bearing) * north
        target = coords.xyz_to_lonlat(math.cos(distance) * coords.lonlat_to_xyz(position) + math.sin(distance) * heading)
        scale = math.exp(rng.uniform(math.log(0.6), math.log(2.5)))
        rotation = rng.uniform(-30.0, 30.0)
        pair = np.array([position, target])
        if abs(target[1]) > 60.0 or (accept is not None and not accept(pair)) or not _clear_of_points(out, apart)(pair):
            continue
        out.append(
            PointHandle((float(position[0]), float(position[1])), (float(target[0]), float(target[1])), float(rotation), float(scale))
        )
    return out


def synthetic_room(  # noqa: PLR0913 - the room's documented keyword knobs (tests and benches call it by them)
    width: int = 2048,
    *,
    size: Sequence[float] = (8.0, 6.0, 3.0),
    camera: Sequence[float] = (0.7, -0.4, 0.2),
    yaw: float = 17.0,
    grid: float | None = 1.0,
    line_width: float = 0.02,
    edge_width: float | None = None,
    supersample: int = 2,
    noise: float = 0.0,
    seed: int | None = None,
    pitch: float = 0.0,
    roll: float = 0.0,
) -> Scene:
    """Render a box room seen from inside as an equirectangular panorama.

    Every pixel is ray-cast: ``supersample x supersample`` rays, spread evenly over the
    pixel, each finds the face of the box it hits and whether the hit point lies on
    painted ink; the pixel is the mean of their colours (a box filter, i.e.
    anti-aliasing). Line widths are in metres on the walls, so near lines look thicker
    than far ones, as in a photograph.

    Parameters
    ----------
    width : int
        Image width in pixels: even and at least 8. The height is ``width // 2``.
    size : (float, float, float)
        Room dimensions along x, y (horizontal) and z (vertical), metres, all ``> 0``.
        The box is centred at the origin of the room frame.
    camera : (float, float, float)
        Camera position in the room frame, metres; strictly inside the box.
    yaw : float
        Turn of the room about the vertical axis, degrees counter-clockwise seen from
        above. The default keeps the edges off the ±180° seam and the image axes.
    grid : float or None
        Spacing of the grid lines in metres, ``> line_width``; each face gets lines
        parallel to its edges at multiples of ``grid`` from the room's lower corner
        (``-size / 2``). ``None`` draws only the edges.
    line_width : float
        Painted width of a grid line, metres, ``> 0``.
    edge_width : float, optional
        Painted width of an edge line, metres, ``> 0``: half of it on each of the two
        faces that meet there. Defaults to ``3 * line_width``.
    supersample : int
        Rays per pixel along each axis, ``>= 1`` (1 gives aliased lines).
    noise : float
        Standard deviation, in 8-bit levels, of Gaussian noise added to the image, ``>= 0``.
        With the default 0 the image is clean and ``seed`` is unused.
    seed : int, optional
        Seed of the noise, for a reproducible noisy image.
    pitch, roll : float
        Tilt of the camera in degrees, each within ±90 (the module's *Tilted camera*:
        the zenith is seen at ``(sin p cos r, -sin r, cos p cos r)``). The lines are
        the exact images in the tilted panorama. With both 0 the camera is level.

    Returns
    -------
    Scene
        ``image`` of uint8, shape ``(width // 2, width, 3)``, RGB, and the ``lines``:
        the 12 edges of the box and every grid line, each spanning its face from edge to
        edge.

    Raises
    ------
    ValueError
        If a parameter is out of range; the message names it.

    Notes
    -----
    Memory stays small at any width: rays are cast in blocks of rows of about
    ``2**16`` rays each.
    """
    width = whole_number(width, "width", 8)
    if width % 2:
        raise ValueError(f"width must be even (the height is width / 2), got {width}")
    size_, camera_ = _checked_box(size, camera)
    half = size_ / 2
    yaw = _finite("yaw", yaw)
    pitch, roll = _checked_tilt(pitch, roll)
    line_width = _positive("line_width", line_width)
    edge_width = 3 * line_width if edge_width is None else _positive("edge_width", edge_width)
    if grid is not None:
        grid = _positive("grid", grid)
        if grid <= line_width:
            raise ValueError(f"grid ({grid} m) must be larger than line_width ({line_width} m)")
    supersample = whole_number(supersample, "supersample", 1)
    noise = _checked_noise(noise, seed)

    tilt = None if pitch == 0.0 and roll == 0.0 else _tilt_matrix(pitch, roll)
    room = _Room(camera_, half, yaw, tilt, _Paint(grid, [_grid_positions(h, grid) for h in half], line_width, edge_width))
    image = _render(width, supersample, room)
    if noise > 0:
        rng = np.random.default_rng(seed)
        noisy = image + rng.normal(0.0, noise, image.shape)
        image = np.clip(np.rint(noisy), 0, 255).astype(np.uint8)

    to_camera = _yaw_matrix(yaw) if tilt is None else tilt @ _yaw_matrix(yaw)
    lines = [
        _scene_line(to_camera @ (p - camera_), to_camera @ (q - camera_), kind, faces)
        for p, q, kind, faces in _room_segments(half, room.paint.lines)
    ]
    return Scene(
        image=image,
        lines=lines,
        size=tuple(size_.tolist()),
        camera=tuple(camera_.tolist()),
        yaw=yaw,
        grid=grid,
        line_width=line_width,
        edge_width=edge_width,
        pitch=pitch,
        roll=roll,
    )


def _checked_box(size: Sequence[float], camera: Sequence[float]) -> tuple[FloatArray, FloatArray]:
    """:func:`synthetic_room`'s ``size`` and ``camera`` as arrays, the camera strictly inside the box."""
    size_ = _vector3("size", size)
    if np.any(size_ <= 0):
        raise ValueError(f"size must be three positive lengths in metres, got {tuple(size)}")
    camera_ = _vector3("camera", camera)
    half = size_ / 2
    if np.any(np.abs(camera_) >= half):
        inside = ", ".join(f"|{axis}| < {h:g}" for axis, h in zip("xyz", half, strict=True))
        raise ValueError(f"camera {tuple(camera)} is not strictly inside the room: it needs {inside} metres")
    return size_, camera_


def _checked_tilt(pitch: float, roll: float) -> tuple[float, float]:
    """:func:`synthetic_room`'s camera tilt, each angle finite and within ±90 degrees."""
    pitch = _finite("pitch", pitch)
    roll = _finite("roll", roll)
    if abs(pitch) > 90 or abs(roll) > 90:
        raise ValueError(f"pitch and roll must be within ±90 degrees, got pitch={pitch}, roll={roll}")
    return pitch, roll


def _checked_noise(noise: float, seed: int | None) -> float:
    """:func:`synthetic_room`'s noise level, ``>= 0``, after checking that its ``seed`` is an integer or None."""
    noise = _finite("noise", noise)
    if noise < 0:
        raise ValueError(f"noise must be >= 0, got {noise}")
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, int | np.integer)):
        raise ValueError(f"seed must be an integer or None, got {seed!r}")
    return noise


# --- box rooms: the structure against its texture -----------------------------------

#: Degrees: a point of a box edge is covered, and a point of a kept line is on the structure, within this.
BOX_ROOM_TOLERANCE = 0.5
#: Spacing of the painted grid in :func:`box_room`, metres.
BOX_ROOM_GRID = (0.6, 1.5)
#: Nearest a grid line comes to a parallel edge, metres: closer, the detector pairs the edge's border with the grid line's
#: (two thin dark lines a degree or two apart read as the two borders of one band, ``BAND_DISTANCE``) and finds neither.
BOX_ROOM_GRID_MARGIN = 0.3
#: Painted width of the grid lines, and of the edges, metres: joints thinner than the room's corners.
BOX_ROOM_LINE_WIDTH = (0.006, 0.015)
BOX_ROOM_EDGE_WIDTH = (0.01, 0.02)
#: Largest tilt of the camera, degrees.
BOX_ROOM_TILT = 20.0
#: Nearest the camera comes to a wall, and to the floor or ceiling, metres.
BOX_ROOM_CLEARANCE = (1.0, 0.8)


def box_room(seed: int, width: int = 1024) -> Scene:
    """A box room of its own size, camera, turn, tilt, grid paint and noise for each seed.

    The room's structure is its twelve edges (``Scene.lines[:12]``, kind ``"edge"``);
    its texture is the grid painted on every face (kind ``"grid"``), of a spacing drawn
    from :data:`BOX_ROOM_GRID`, in thinner lines than the edges (as a floor's joints are
    finer than the corners of its room). Sizes 4-10 x 3.5-8 x 2.5-3.6 m, the camera
    anywhere at least :data:`BOX_ROOM_CLEARANCE` from the faces, tilted up to
    :data:`BOX_ROOM_TILT` degrees, noise 0-6 levels. Even seeds are for choosing
    constants, odd seeds for reporting figures.

    Parameters
    ----------
    seed : int
        ``>= 0``.
    width : int
        Image width, pixels (as :func:`synthetic_room`).

    Returns
    -------
    Scene
    """
    seed = whole_number(seed, "seed", 0)
    rng = np.random.default_rng([36, seed])
    spacings = np.linspace(*BOX_ROOM_GRID, 901)
    while True:  # a size for which some spacing keeps every grid line BOX_ROOM_GRID_MARGIN from the edges
        size = np.array([rng.uniform(4.0, 10.0), rng.uniform(3.5, 8.0), rng.uniform(2.5, 3.6)])
        rest = np.mod(size[None, :], spacings[:, None])
        fits = spacings[np.all((rest > BOX_ROOM_GRID_MARGIN) & (rest < spacings[:, None] - BOX_ROOM_GRID_MARGIN), axis=1)]
        if fits.size:
            grid = float(rng.choice(fits))
            break
    room = np.array([BOX_ROOM_CLEARANCE[0], BOX_ROOM_CLEARANCE[0], BOX_ROOM_CLEARANCE[1]])
    camera = rng.uniform(-1.0, 1.0, 3) * (size / 2 - room)
    while True:
        pitch, roll = rng.uniform(-BOX_ROOM_TILT, BOX_ROOM_TILT, 2)
        up = _tilt_matrix(float(pitch), float(roll)) @ np.array([0.0, 0.0, 1.0])
        if math.degrees(math.acos(float(np.clip(up[2], -1.0, 1.0)))) <= BOX_ROOM_TILT:
            break
    return synthetic_room(
        width,
        size=tuple(size.tolist()),
        camera=tuple(camera.tolist()),
        yaw=float(rng.uniform(-180.0, 180.0)),
        grid=grid,
        line_width=float(rng.uniform(*BOX_ROOM_LINE_WIDTH)),
        edge_width=float(rng.uniform(*BOX_ROOM_EDGE_WIDTH)),
        noise=float(rng.uniform(0.0, 6.0)),
        seed=seed,
        pitch=float(pitch),
        roll=float(roll),
    )


def _arc_points(ends: FloatArray, step: float) -> FloatArray:
    """Points along each arc ``ends[i] = (start, end)`` (unit vectors, (k, 2, 3)), at most ``step`` degrees apart, (s, 3)."""
    out = []
    for a, b in ends:
        length = math.degrees(math.atan2(float(np.linalg.norm(np.cross(a, b))), float(a @ b)))
        t = np.linspace(0.0, 1.0, max(2, math.ceil(length / step) + 1))
        out.append(coords.lonlat_to_xyz(coords.geodesic(coords.xyz_to_lonlat(a), coords.xyz_to_lonlat(b), t)))
    return np.concatenate(out) if out else np.empty((0, 3))


def _distance_to_arcs(points: FloatArray, ends: FloatArray) -> FloatArray:
    """Degrees from each point (s, 3) to the nearest of the arcs ``ends`` (k, 2, 3), (s,); infinite without arcs."""
    if len(ends) == 0:
        return np.full(len(points), np.inf)
    a, b = ends[:, 0], ends[:, 1]
    normal = np.cross(a, b)
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    across = np.cross(normal, a)
    length = np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), np.einsum("ij,ij->i", a, b))
    best = np.full(len(points), np.inf)
    for lo in range(0, len(points), 4096):  # bounds the (points x arcs) tables
        p = points[lo : lo + 4096]
        t = np.arctan2(p @ across.T, p @ a.T)
        to_circle = np.arcsin(np.clip(np.abs(p @ normal.T), 0.0, 1.0))
        to_ends = np.minimum(np.arccos(np.clip(p @ a.T, -1.0, 1.0)), np.arccos(np.clip(p @ b.T, -1.0, 1.0)))
        best[lo : lo + 4096] = np.degrees(np.where((t >= 0) & (t <= length[None]), to_circle, to_ends).min(axis=1))
    return best


def _ends_of(lines: Iterable[Any]) -> FloatArray:
    """The unit vectors of each line's ``start`` and ``end`` (``[lon, lat]``), (k, 2, 3)."""
    lonlat = np.array([(line.start, line.end) for line in lines], dtype=np.float64).reshape(-1, 2, 2)
    return coords.lonlat_to_xyz(lonlat)


def edge_coverage(scene: Scene, lines: Iterable[Any], tolerance: float = BOX_ROOM_TOLERANCE) -> float:
    """Share of the box's edges, by arc length as seen from the camera, within ``tolerance`` of one of ``lines``.

    Parameters
    ----------
    scene : Scene
        A room of :func:`synthetic_room` (its first 12 lines, kind ``"edge"``, the box's edges).
    lines : iterable
        Anything with ``start`` and ``end`` as ``[lon, lat]`` degrees (suggestions, handles).
    tolerance : float
        Degrees.

    Returns
    -------
    float
        In ``[0, 1]``; the edges are sampled every 0.25°.
    """
    points = _arc_points(_ends_of(line for line in scene.lines if line.kind == "edge"), 0.25)
    return float(np.mean(_distance_to_arcs(points, _ends_of(lines)) < tolerance))


def edge_precision(scene: Scene, lines: Iterable[Any], tolerance: float = BOX_ROOM_TOLERANCE) -> float:
    """Share of ``lines``' total arc length lying within ``tolerance`` of one of the box's edges.

    Parameters
    ----------
    scene : Scene
    lines : iterable
        Anything with ``start`` and ``end`` as ``[lon, lat]`` degrees.
    tolerance : float
        Degrees.

    Returns
    -------
    float
        In ``[0, 1]``, sampled every 0.25°; 1 for no lines (nothing kept is wrong).
    """
    ends = _ends_of(lines)
    if len(ends) == 0:
        return 1.0
    points = _arc_points(ends, 0.25)
    return float(np.mean(_distance_to_arcs(points, _ends_of(line for line in scene.lines if line.kind == "edge")) < tolerance))


# --- geometry ------------------------------------------------------------------------


def _yaw_matrix(yaw: float) -> FloatArray:
    """Rotation by ``yaw`` degrees counter-clockwise about ``+z``: room frame to camera frame."""
    c, s = math.cos(math.radians(yaw)), math.sin(math.radians(yaw))
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _tilt_matrix(pitch: float, roll: float) -> FloatArray:
    """The camera tilt ``R_y(pitch) R_x(roll)`` (module docstring): level camera frame to tilted, (3, 3)."""
    cp, sp = math.cos(math.radians(pitch)), math.sin(math.radians(pitch))
    cr, sr = math.cos(math.radians(roll)), math.sin(math.radians(roll))
    about_y = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    about_x = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    return about_y @ about_x


def _grid_positions(half: float, grid: float | None) -> FloatArray:
    """Coordinates of the grid lines across an axis spanning ``[-half, half]``.

    Lines sit at ``-half + k * grid`` for ``k >= 1``, strictly inside the span: a line
    falling on the far edge is the edge itself, not a grid line.
    """
    if grid is None:
        return np.empty(0)
    count = math.floor(2 * half / grid * (1 - 1e-12))
    return -half + grid * np.arange(1, count + 1, dtype=np.float64)


def _room_segments(
    half: FloatArray, grid_lines: list[FloatArray]
) -> Iterator[tuple[FloatArray, FloatArray, Literal["edge", "grid"], tuple[str, ...]]]:
    """Yield ``(start, end, kind, faces)`` of every line in the room frame.

    The 12 edges come first, then for each face and each of its two in-plane axes the
    grid lines across that axis, each spanning the face along the remaining axis.
    """
    for axis in range(3):  # an edge runs along `axis`, at a corner of the other two
        a, b = (i for i in range(3) if i != axis)
        for sign_a in (-1, 1):
            for sign_b in (-1, 1):
                start = np.zeros(3)
                start[a], start[b], start[axis] = sign_a * half[a], sign_b * half[b], -half[axis]
                end = start.copy()
                end[axis] = half[axis]
                faces = (FACE_NAMES[2 * a + (sign_a > 0)], FACE_NAMES[2 * b + (sign_b > 0)])
                yield start, end, "edge", faces
    for face, name in enumerate(FACE_NAMES):
        normal_axis, side = divmod(face, 2)
        in_plane = [i for i in range(3) if i != normal_axis]
        for across, along in (in_plane, in_plane[::-1]):
            for position in grid_lines[across]:
                start = np.zeros(3)
                start[normal_axis] = half[normal_axis] if side else -half[normal_axis]
                start[across] = position
                start[along] = -half[along]
                end = start.copy()
                end[along] = half[along]
                yield start, end, "grid", (name,)


def _scene_line(p: FloatArray, q: FloatArray, kind: Literal["edge", "grid"], faces: tuple[str, ...]) -> SceneLine:
    """Make the :class:`SceneLine` between camera-frame points ``p`` and ``q``."""
    (lon0, lat0), (lon1, lat1) = coords.xyz_to_lonlat(np.array([p, q]))
    return SceneLine(
        start=(float(lon0), float(lat0)),
        end=(float(lon1), float(lat1)),
        kind=kind,
        start_3d=(float(p[0]), float(p[1]), float(p[2])),
        end_3d=(float(q[0]), float(q[1]), float(q[2])),
        faces=faces,
    )


def _ray_meets_line(direction: FloatArray, a: FloatArray, b: FloatArray) -> FloatArray:
    """Where the ray from the origin along ``direction`` meets the line through ``a`` and ``b``.

    All three lie in one plane through the origin. Writing ``lam * direction = a + s (b - a)``
    and crossing both sides with ``direction`` gives ``s``.
    """
    step = b - a
    cross_step = np.cross(step, direction)
    s = -np.dot(np.cross(a, direction), cross_step) / np.dot(cross_step, cross_step)
    return a + s * step


def _cast_rays(directions: FloatArray, camera: FloatArray, half: FloatArray) -> tuple[NDArray[np.uint8], list[FloatArray]]:
    """Cast rays from ``camera`` (inside the box ``|x| <= half``) to the box's walls.

    Parameters
    ----------
    directions : ndarray of float64, shape (..., 3)
        Ray directions in the room frame, nonzero.
    camera : ndarray of float64, shape (3,)
    half : ndarray of float64, shape (3,)
        Half the room size.

    Returns
    -------
    face : ndarray of uint8, shape (...)
        Index into :data:`FACE_NAMES` of the face each ray hits.
    hit : list of three ndarrays of float64, shape (...)
        The x, y and z room-frame coordinates of the hit points.
    """
    shape = directions.shape[:-1]
    distance = np.full(shape, np.inf)
    face = np.zeros(shape, dtype=np.uint8)
    with np.errstate(divide="ignore"):
        for axis in range(3):
            d = directions[..., axis]
            # Along this axis the ray heads for the wall on the side it points to and
            # reaches it after this (positive) distance; infinite if d == 0.
            t = np.where(d >= 0, half[axis] - camera[axis], half[axis] + camera[axis]) / np.abs(d)
            closer = t < distance
            distance = np.where(closer, t, distance)
            face = np.where(closer, np.uint8(2 * axis) + (d > 0), face)
    hit = [camera[axis] + distance * directions[..., axis] for axis in range(3)]
    return face, hit


@dataclass(frozen=True, eq=False)
class _Paint:
    """The ink on the walls: grid lines every ``grid`` metres (None: none) at ``lines`` per axis, and the edges' bands."""

    grid: float | None
    lines: list[FloatArray]
    line_width: float
    edge_width: float


@dataclass(frozen=True, eq=False)
class _Room:
    """A box room as the ray caster sees it: the camera in it, the box's half size, its turn and tilt, and its paint."""

    camera: FloatArray
    half: FloatArray
    yaw: float
    tilt: FloatArray | None
    paint: _Paint


def _ink(face: NDArray[np.uint8], hit: list[FloatArray], half: FloatArray, paint: _Paint) -> NDArray[np.bool_]:
    """Whether each hit point lies on a painted grid line or edge band."""
    normal_axis = face // 2
    ink = np.zeros(face.shape, dtype=bool)
    for axis, x in enumerate(hit):
        on_line = half[axis] - np.abs(x) < paint.edge_width / 2
        positions = paint.lines[axis]
        if positions.size:
            # The grid line nearest to x, by its index in `positions`.
            k = np.clip(np.rint((x - positions[0]) / paint.grid), 0, positions.size - 1).astype(np.intp)
            on_line |= np.abs(x - positions[k]) < paint.line_width / 2
        # The coordinate along a face's normal is constant on it and draws nothing.
        ink |= on_line & (normal_axis != axis)
    return ink


def _render(width: int, supersample: int, room: _Room) -> NDArray[np.uint8]:
    """Ray-cast the room into a ``(width // 2, width, 3)`` uint8 image.

    The rays are the pixel centres of an image ``supersample`` times larger, so each
    output pixel averages a ``supersample x supersample`` block of evenly spread rays.
    """
    n = supersample
    height = width // 2
    lon, lat = coords.grid_lonlat(width * n)
    room_lon = lon - room.yaw  # turning the room by +yaw turns the rays by -yaw
    # One colour lookup table per channel, wide enough to sum n * n samples.
    channels = [_PALETTE[:, c].astype(np.uint32) for c in range(3)]
    image = np.empty((height, width, 3), dtype=np.uint8)
    rows_per_block = max(1, _SAMPLES_PER_BLOCK // (width * n * n))
    for row in range(0, height, rows_per_block):
        rows = min(rows_per_block, height - row)
        lat_block = lat[row * n : (row + rows) * n]
        if room.tilt is None:
            lonlat = np.stack(np.broadcast_arrays(room_lon[None, :], lat_block[:, None]), axis=-1)
            directions = coords.lonlat_to_xyz(lonlat)
        else:  # a tilted ray d is the room direction (T Y)^T d; as rows, d @ (T Y)
            lonlat = np.stack(np.broadcast_arrays(lon[None, :], lat_block[:, None]), axis=-1)
            directions = coords.lonlat_to_xyz(lonlat) @ (room.tilt @ _yaw_matrix(room.yaw))
        face, hit = _cast_rays(directions, room.camera, room.half)
        ink = _ink(face, hit, room.half, room.paint)
        colour_index = np.where(ink, np.uint8(_INK), face)  # (rows * n, width * n)
        for c, table in enumerate(channels):
            # Sum each pixel's n x n samples: first down the rows, then along the columns.
            total = table[colour_index].reshape(rows, n, width * n).sum(axis=1)
            total = total.reshape(rows, width, n).sum(axis=2)
            # Round half up, in integers: exact and the same on every platform.
            image[row : row + rows, :, c] = (2 * total + n * n) // (2 * n * n)
    return image


# --- validation ----------------------------------------------------------------------


def _finite(name: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise ValueError(f"{name} must be a number, got {value!r}")
    if not math.isfinite(value):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return float(value)


def _positive(name: str, value: object) -> float:
    value = _finite(name, value)
    if value <= 0:
        raise ValueError(f"{name} must be > 0, got {value}")
    return value


def _vector3(name: str, value: object) -> FloatArray:
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be three numbers (x, y, z), got {value!r}") from None
    if arr.shape != (3,):
        raise ValueError(f"{name} must be three numbers (x, y, z), got {value!r}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return arr
