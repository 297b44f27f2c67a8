"""Handles (points, lines, cages), their Möbius maps, and the handles file.

The handles document is JSON, read and written identically by the command line, the
Python API and the widget::

    {"format": "omniwidget.handles", "version": 1,
     "handles": [
       {"kind": "point", "position": [lon, lat], "target": [lon, lat], "rotation": 0.0, "scale": 1.0},
       {"kind": "line", "start": [lon, lat], "end": [lon, lat], "rectify": true},
       {"kind": "cage", "vertices": [[lon, lat], ...], "targets": [[lon, lat], ...]}],
     "options": {"rectify": "all"}}

Positions are ``[lon, lat]`` in degrees (see :mod:`omniwidget.sphere.coords`). Optional
fields: a point's ``target`` (default: its ``position``), ``rotation`` (degrees,
counter-clockwise as seen in the image), ``scale`` (> 1 zooms in) and ``reach`` (degrees:
how far its turn and zoom reach with the still background); a line's ``rectify``
(default true, eq. 4) or explicit ``targets`` (start, middle, end); a cage's ``targets``
(default: it stays); an ``id`` string on any handle; ``options.rectify``, ``"all"``
(Sec. 3.4, the default) or ``"each"`` (eq. 4 line by line). Anything else is refused by a
:class:`~omniwidget.errors.HandlesError` naming the handle and the field.
"""

from __future__ import annotations

import json
import math
import os
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import limit, require_regular_file
from .._files import atomic_write_bytes
from ..errors import HandlesError, NotRegularFileError
from ..sphere import coords
from ..sphere.moebius import Moebius, frame_rotation

__all__ = [
    "ARROW_LENGTH",
    "CageHandle",
    "Handle",
    "Handles",
    "LineHandle",
    "MAX_DEPTH",
    "MAX_FILE_BYTES",
    "MAX_HANDLES",
    "Options",
    "PointHandle",
    "REACH_RANGE",
    "load_handles",
    "save_handles",
]

FORMAT = "omniwidget.handles"
VERSION = 1
#: The anchor distance (degrees) that measured best on rooms of 6 to 10 lines (bench/RESULTS.md, "The still background").
SUGGESTED_ANCHOR = 5.0
#: ``options.anchor``'s default: the still background at :data:`SUGGESTED_ANCHOR` (None: the paper's method).
DEFAULT_ANCHOR: float | None = SUGGESTED_ANCHOR
#: The range ``options.anchor`` may take, degrees.
ANCHOR_RANGE = (1.0, 180.0)
#: The latitudes ``options.up`` may take, degrees: a levelling turns the panorama by at most 45°.
UP_LATITUDE_RANGE = (45.0, 90.0)
#: Angular distance (radians) from a point handle's centre to its arrow tips, the authors' 0.3 rad.
ARROW_LENGTH = 0.3
#: Control points closer than this (degrees) count as coincident.
MIN_SEPARATION = 1e-6
SCALE_RANGE = (1e-3, 1e3)
ROTATION_RANGE = (-360.0, 360.0)
#: The range a point handle's ``reach`` may take, degrees.
REACH_RANGE = (0.5, 90.0)
#: The deepest nesting of arrays and objects a handles file may have (a document needs 5):
#: deeper JSON is refused before it is parsed.
MAX_DEPTH = 32
#: The most handles a document may have, a cage's vertices counted each (each is a control of
#: the blend); ``OMNIWIDGET_MAX_HANDLES`` raises it. The cost in time and memory grows faster
#: than the count (bench/RESULTS.md, "Limits"); the weights' own cap
#: (:data:`omniwidget.method.limits.MAX_WEIGHTS`) may refuse fewer lines.
MAX_HANDLES = 1000
#: The largest handles file read (bytes): a document of :data:`MAX_HANDLES` handles takes
#: about 0.2 MB; a larger file is refused before it is read.
MAX_FILE_BYTES = 64 << 20

LonLat = tuple[float, float]


def _separation(a: ArrayLike, b: ArrayLike) -> float:
    return float(coords.angular_distance(a, b))


def _rectified_midpoint(start: LonLat, end: LonLat) -> LonLat:
    """Eq. (4): the midpoint of the endpoints in the lon/lat plane, unwrapped across the seam."""
    end_lon = float(coords.unwrap_lon(end[0], start[0]))
    lon = float(coords.wrap_lon((start[0] + end_lon) / 2.0))
    return (lon, (start[1] + end[1]) / 2.0)


def _exp(lonlat: LonLat, bearing_east: float, angle: float) -> NDArray[np.float64]:
    """The point at ``angle`` radians from ``lonlat`` heading east (+1) or west (-1)."""
    p = coords.lonlat_to_xyz(lonlat)
    east, _ = coords.local_frame(lonlat)
    return coords.xyz_to_lonlat(math.cos(angle) * p + bearing_east * math.sin(angle) * east)


@dataclass(frozen=True)
class PointHandle:
    """A point handle (Sec. 3.3): translates, turns and zooms the sphere near ``position``.

    Its map sends ``position`` to ``target`` and the antipode of ``position`` to the antipode
    of ``target``, and at ``target`` magnifies by ``scale`` and turns by ``rotation`` degrees
    counter-clockwise relative to the image's east and north (:meth:`Moebius.point_map`).

    Parameters
    ----------
    position : (float, float)
        ``[lon, lat]`` in the input image, degrees.
    target : (float, float), optional
        Where ``position`` goes in the output; defaults to ``position``.
    rotation : float
        Degrees, counter-clockwise as seen in the image.
    scale : float
        Magnification at the target, ``> 0``.
    id : str, optional
    reach : float, optional
        Degrees (in :data:`REACH_RANGE`): with the still background (``options.anchor``
        set) the turn and zoom hold within a third of it around the target, fade out
        monotonically up to it, and nothing of them is left beyond it
        (:mod:`omniwidget.method.reach`). ``None``: the default,
        :func:`omniwidget.method.reach.default_reach` (half the way to the nearest other
        handle, at most 15°). Ignored by the paper's method (``anchor: null``).
    """

    position: LonLat
    target: LonLat | None = None
    rotation: float = 0.0
    scale: float = 1.0
    id: str | None = None
    reach: float | None = None
    kind: Literal["point"] = field(default="point", init=False)

    @property
    def final(self) -> LonLat:
        """The output position of the centre."""
        return self.target if self.target is not None else self.position

    def moebius(self) -> Moebius:
        """The handle's Möbius map, input sphere to output sphere."""
        return Moebius.point_map(self.position, self.final, self.scale, self.rotation)

    def control_points(self) -> NDArray[np.float64]:
        """Centre, east arrow tip, west arrow tip in the input, shape (3, 2).

        The tips lie ``ARROW_LENGTH`` radians (the authors' 0.3 rad) along the great circle
        heading east and west; on the equator that is ±0.3 rad of longitude, and unlike a
        longitude offset it stays well defined at the poles.
        """
        return np.stack([np.asarray(self.position, float), _exp(self.position, 1, ARROW_LENGTH), _exp(self.position, -1, ARROW_LENGTH)])

    def target_points(self) -> NDArray[np.float64]:
        """The control points' output positions, shape (3, 2): the exact map of :meth:`control_points`."""
        out = self.moebius()(self.control_points())
        out[0] = self.final
        return out

    def with_arrow_tip(self, tip: ArrayLike, which: Literal["east", "west"] = "east") -> PointHandle:
        """The handle with the output arrow tip dragged to ``tip``: new ``rotation`` and ``scale``.

        The opposite arrow follows (Sec. 3.3); the centre stays at its target.
        """
        final = self.final
        chart = Moebius.from_rotation(frame_rotation(final))
        u, v = coords.xyz_to_homogeneous(chart.apply_xyz(coords.lonlat_to_xyz(tip)))
        if abs(complex(v)) < 1e-12 * abs(complex(u)) or _separation(tip, final) < MIN_SEPARATION:
            raise HandlesError("arrow", "the arrow tip cannot sit on the centre or its antipode")
        k = complex(u / v) / math.tan(ARROW_LENGTH / 2) * (1 if which == "east" else -1)
        scale = float(np.clip(abs(k), *SCALE_RANGE))
        return replace(self, scale=scale, rotation=-math.degrees(math.atan2(k.imag, k.real)))


@dataclass(frozen=True)
class LineHandle:
    """A line handle, the paper's spherical bone (eq. 3): the geodesic from ``start`` to ``end``.

    Its three control points are the endpoints and the geodesic midpoint. With ``rectify``
    they go by eq. (4): the endpoints stay and the midpoint goes to the midpoint of the
    endpoints in the lon/lat plane, so the line comes out straight. Explicit ``targets``
    (start, middle, end) say instead where they go. With neither, the map is the identity.
    """

    start: LonLat
    end: LonLat
    rectify: bool = True
    targets: tuple[LonLat, LonLat, LonLat] | None = None
    id: str | None = None
    kind: Literal["line"] = field(default="line", init=False)

    def control_points(self) -> NDArray[np.float64]:
        """Start, geodesic midpoint and end in the input, shape (3, 2)."""
        return np.stack([np.asarray(self.start, float), coords.geodesic_midpoint(self.start, self.end), np.asarray(self.end, float)])

    def target_points(self) -> NDArray[np.float64]:
        """The control points' output positions, shape (3, 2)."""
        if self.targets is not None:
            return np.asarray(self.targets, dtype=np.float64)
        points = self.control_points()
        if self.rectify:
            points[1] = _rectified_midpoint(self.start, self.end)
        return points

    def moebius(self) -> Moebius:
        """The handle's Möbius map: control points to target points (Theorem 1)."""
        if self.targets is None and not self.rectify:
            return Moebius.identity()
        return Moebius.from_points(self.control_points(), self.target_points())


def _shortest_turn(a: NDArray[np.float64], b: NDArray[np.float64]) -> Moebius:
    """The rotation about ``a × b`` taking unit vector ``a`` to ``b`` (the identity when they coincide).

    Unlike :meth:`Moebius.translation` it needs no east/north frame, so it is well defined at the poles.
    """
    axis = np.cross(a, b)
    size = float(np.linalg.norm(axis))
    if size < 1e-15:
        return Moebius.identity() if float(a @ b) > 0 else Moebius.translation(coords.xyz_to_lonlat(a), coords.xyz_to_lonlat(b))
    return Moebius.rotation(coords.xyz_to_lonlat(axis / size), math.degrees(math.atan2(size, float(a @ b))))


@dataclass(frozen=True)
class CageHandle:
    """A spherical cage (Sec. 3.3): a closed polygon of geodesic edges.

    Each vertex acts as a point handle whose centre alone moves (its map is the shift
    :meth:`Moebius.translation` from the vertex to its target). Without ``targets`` the cage
    stays where it is and holds the region it encloses still.
    """

    vertices: tuple[LonLat, ...]
    targets: tuple[LonLat, ...] | None = None
    id: str | None = None
    kind: Literal["cage"] = field(default="cage", init=False)

    @property
    def finals(self) -> tuple[LonLat, ...]:
        """The vertices' output positions."""
        return self.targets if self.targets is not None else self.vertices

    def vertex_maps(self, carry: bool = False) -> list[Moebius]:
        """One Möbius map per vertex.

        Parameters
        ----------
        carry : bool
            False (the paper): each vertex's map is the shift :meth:`Moebius.translation`
            from the vertex to its target. True (with the still background): each is the
            cage's best rotation (:meth:`rotation`) followed by the shift that puts the
            vertex exactly on its target, so a cage moved rigidly carries its inside by one
            rotation whatever the blend's weights inside it, and a cage bent out of shape by
            maps that differ only by what the bending asks.
        """
        if not carry:
            return [Moebius.translation(v, t) for v, t in zip(self.vertices, self.finals, strict=True)]
        rotation = self.rotation()
        turned = coords.lonlat_to_xyz(np.asarray(self.vertices, np.float64)) @ rotation.T
        whole = Moebius.from_rotation(rotation)
        return [
            _shortest_turn(v, t) @ whole for v, t in zip(turned, coords.lonlat_to_xyz(np.asarray(self.finals, np.float64)), strict=True)
        ]

    def rotation(self) -> NDArray[np.float64]:
        """The rotation of the sphere that best moves the vertices to their targets, (3, 3) (:func:`coords.best_rotation`).

        Exactly the motion for a cage moved rigidly, the identity for a cage that stays.
        """
        return coords.best_rotation(self.vertices, self.finals)


#: Any one handle: a point, a line or a cage.
Handle = PointHandle | LineHandle | CageHandle


@dataclass(frozen=True)
class Options:
    """Document-wide options.

    Attributes
    ----------
    rectify : {"all", "each"}
        ``"all"``: the lines' targets come from the joint solve of Sec. 3.4; ``"each"``: eq. (4) line by line.
    anchor : float or None
        The still background: the sphere farther than this many degrees from every handle
        keeps its place (an identity map whose weight is 1 there; see
        :mod:`omniwidget.raster.pipeline`). The distance grows with a handle's size. ``None``
        (``"anchor": null``): no background map, the paper's method exactly. The default,
        :data:`SUGGESTED_ANCHOR` (5), measured best on rooms of lines.
    up : (float, float) or None
        ``[lon, lat]`` in degrees where the input panorama sees the true vertical (what
        :func:`omniwidget.level` finds), latitude in :data:`UP_LATITUDE_RANGE`. The method
        then works on the input levelled: turned by :meth:`levelling` (``up`` to the zenith,
        the yaw kept) before any handle acts, so the still background shows the levelled
        panorama, rectified lines are straightened in the levelled frame, and a point's
        target and turn are those of the levelled view. The handles' input positions stay
        where they were clicked on the input. None: the input as it is.
    """

    rectify: Literal["all", "each"] = "all"
    anchor: float | None = DEFAULT_ANCHOR
    up: LonLat | None = None

    def levelling(self) -> Moebius | None:
        """The turn of the input before the handles (:attr:`up` to the zenith), or None without ``up``."""
        return None if self.up is None else Moebius.levelling(self.up)


@dataclass(frozen=True)
class Handles:
    """A handles document: the handles in order, and the options.

    Build one with :meth:`from_dict`, :meth:`from_json` or :func:`load_handles`, which
    validate everything; the constructor does the same checks on handle objects.
    """

    handles: tuple[Handle, ...] = ()
    options: Options = Options()

    def __post_init__(self) -> None:
        object.__setattr__(self, "handles", tuple(self.handles))
        _validate_document(self)

    def __len__(self) -> int:
        return len(self.handles)

    def maps(self) -> list[Moebius]:
        """Every Möbius map the document defines: one per point and line, one per cage vertex.

        With ``options.rectify == "all"`` the lines' targets are to come from the joint
        solve of Sec. 3.4; for a single line that solve gives exactly eq. (4).
        """
        return [m for h in self.handles for m in _FORMATS[h.kind].maps(h)]

    # --- JSON -----------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """The document as plain JSON-ready data (lists and floats)."""
        return {
            "format": FORMAT,
            "version": VERSION,
            "handles": [_handle_to_dict(h) for h in self.handles],
            "options": _options_to_dict(self.options),
        }

    def to_json(self, indent: int | None = 2) -> str:
        """The document as a JSON string."""
        return json.dumps(self.to_dict(), indent=indent)

    @classmethod
    def from_dict(cls, data: Any) -> Handles:
        """Validate and build a document from parsed JSON.

        Raises
        ------
        HandlesError
            Naming the handle index and field of the first problem found.
        """
        return _parse_document(data)

    @classmethod
    def from_json(cls, text: str | bytes) -> Handles:
        """Validate and build a document from JSON text.

        Before parsing, the nesting is measured: JSON nested deeper than
        :data:`MAX_DEPTH` arrays and objects is refused (a handles document needs 5), so
        that no file can exhaust the parser's recursion. An object with the same key twice
        is refused too, instead of keeping the last silently (``"handles": [...],
        "handles": []`` would otherwise be an empty document).

        Raises
        ------
        HandlesError
            Not JSON, nested too deep, a duplicate key, or any field the document refuses.
        """
        try:
            if isinstance(text, (bytes, bytearray)):
                text = bytes(text).decode(json.detect_encoding(text), "surrogatepass")  # as json.loads decodes bytes
            _check_depth(text)
            data = json.loads(text, parse_constant=_constant, object_pairs_hook=_unique_keys)  # a NaN is refused by its field
        except (ValueError, UnicodeDecodeError) as exc:
            if isinstance(exc, HandlesError):
                raise
            raise HandlesError("", f"not valid JSON: {exc}") from None
        return cls.from_dict(data)


def load_handles(path: str | os.PathLike[str]) -> Handles:
    """Read and validate a handles file.

    Raises
    ------
    HandlesError
        If the file cannot be read or is not a valid handles document; the message starts
        with the file name.
    """
    path = Path(path)
    try:
        require_regular_file(path, "handles file")  # a FIFO would hang the read, a device never end
        size = path.stat().st_size
        if size > MAX_FILE_BYTES:
            raise HandlesError(
                str(path),
                f"the handles file is {size / 1e6:.0f} MB, more than the {MAX_FILE_BYTES / 1e6:.0f} MB read (1,000 handles take 0.2 MB)",
            )
        text = path.read_bytes()
    except NotRegularFileError as exc:
        raise HandlesError(str(path), f"cannot read the handles file: it is {exc.kind}, not a regular file") from None
    except OSError as exc:
        raise HandlesError(str(path), f"cannot read the handles file ({exc.strerror or exc})") from None
    try:
        return Handles.from_json(text)
    except HandlesError as exc:
        raise HandlesError(f"{path}: {exc.where}" if exc.where else str(path), exc.problem) from None


def save_handles(handles: Handles, path: str | os.PathLike[str]) -> None:
    """Write a handles file whole (a temporary file, then a rename) or not at all."""
    atomic_write_bytes(Path(path), (handles.to_json() + "\n").encode())


# --- parsing and validation -------------------------------------------------------------

#: A JSON string (its brackets are not nesting), or what is left of one cut short.
_JSON_STRING = re.compile(r'"[^"\\]*(?:\\.[^"\\]*)*"?')


def _check_depth(text: str) -> None:
    """Refuse JSON nested deeper than :data:`MAX_DEPTH`, counting brackets outside strings (no recursion, linear time)."""
    outside = _JSON_STRING.sub('""', text).encode("utf-8", "surrogatepass")  # a JSON string holds no line break
    raw = np.frombuffer(outside, np.uint8)  # a multi-byte character holds no bracket byte
    at = np.flatnonzero((raw == 0x5B) | (raw == 0x7B) | (raw == 0x5D) | (raw == 0x7D))
    if len(at) <= MAX_DEPTH:
        return
    depth = np.cumsum(np.where((raw[at] == 0x5B) | (raw[at] == 0x7B), 1, -1), dtype=np.int64)
    if depth.max() > MAX_DEPTH:
        where = int(at[np.argmax(depth > MAX_DEPTH)])
        line = outside.count(b"\n", 0, where) + 1
        raise HandlesError(
            "", f"the JSON is nested deeper than {MAX_DEPTH} arrays and objects (at line {line}); a handles document needs 5"
        )


def _unique_keys(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    """A JSON object as a dict, refusing a key given twice (``json`` would keep the last silently)."""
    out: dict[str, Any] = {}
    for key, value in pairs:
        if key in out:
            inside = f" of a {out['kind']} handle" if isinstance(out.get("kind"), str) and key != "kind" else ""
            raise HandlesError(
                "", f"the key {json.dumps(key)} appears twice in one object{inside}; JSON would keep only the last, so say it once"
            )
        out[key] = value
    return out


def _constant(name: str) -> float:
    """``NaN``, ``Infinity`` and ``-Infinity`` (not JSON, but Python writes them) as floats, refused where they are used."""
    return float(name)


def _describe(value: Any) -> str:
    text = json.dumps(value) if not isinstance(value, float) or math.isfinite(value) else repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _number(value: Any, where: str, lo: float | None = None, hi: float | None = None) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise HandlesError(where, f"expected a number, got {_describe(value)}")
    try:
        value = float(value)
    except OverflowError:  # an integer past float's range, 1e400 written out in full say
        raise HandlesError(where, f"an integer of {value.bit_length()} bits is out of range (past a float's)") from None
    if not math.isfinite(value):
        raise HandlesError(where, f"expected a finite number, got {value}")
    if (lo is not None and value < lo) or (hi is not None and value > hi):
        raise HandlesError(where, f"{value:g} is out of range [{lo:g}, {hi:g}]")
    return value


def _lonlat(value: Any, where: str) -> LonLat:
    if not isinstance(value, (list, tuple)) or len(value) != 2:
        raise HandlesError(where, f"expected [lon, lat] (two numbers, degrees), got {_describe(value)}")
    lon = _number(value[0], f"{where}[0] (longitude)", -180.0, 180.0)
    lat = _number(value[1], f"{where}[1] (latitude)", -90.0, 90.0)
    return (lon, lat)


def _lonlat_list(value: Any, where: str, count: int | None = None, minimum: int = 0) -> tuple[LonLat, ...]:
    if not isinstance(value, (list, tuple)):
        raise HandlesError(where, f"expected a list of [lon, lat], got {_describe(value)}")
    if count is not None and len(value) != count:
        raise HandlesError(where, f"expected {count} positions, got {len(value)}")
    if len(value) < minimum:
        raise HandlesError(where, f"expected at least {minimum} positions, got {len(value)}")
    return tuple(_lonlat(item, f"{where}[{i}]") for i, item in enumerate(value))


def _lonlat_triple(value: Any, where: str) -> tuple[LonLat, LonLat, LonLat]:
    first, second, third = _lonlat_list(value, where, count=3)
    return (first, second, third)


def _distinct(points: Sequence[LonLat], where: str, closed: bool = False) -> None:
    pts = np.asarray(points, dtype=np.float64)
    n = len(pts)
    for i in range(n):
        for j in range(i + 1, n):
            if _separation(pts[i], pts[j]) < MIN_SEPARATION:
                raise HandlesError(where, f"positions {i} and {j} coincide ({_describe(list(points[i]))})")


def _given(data: Mapping[str, Any], key: str, default: Any) -> Any:
    """An optional field's value; ``null`` means not given, as leaving it out does."""
    value = data.get(key)
    return default if value is None else value


def _parse_handle(data: Any, index: int) -> Handle:
    where = f"handles[{index}]"
    if not isinstance(data, Mapping):
        raise HandlesError(where, f"expected an object with a 'kind', got {_describe(data)}")
    kind = data.get("kind")
    if not isinstance(kind, str) or kind not in _HANDLE_FIELDS:
        raise HandlesError(f"{where}.kind", f"expected 'point', 'line' or 'cage', got {_describe(kind)}")
    required, optional = _HANDLE_FIELDS[kind]
    for key in data:
        if key not in required and key not in optional:
            raise HandlesError(f"{where}.{key}", f"unknown field for a {kind} handle (allowed: {', '.join(sorted(required | optional))})")
    for key in sorted(required):
        if key not in data:
            raise HandlesError(f"{where}.{key}", f"missing (a {kind} handle needs {', '.join(sorted(required - {'kind'}))})")
    hid = data.get("id")
    if hid is not None and (not isinstance(hid, str) or not hid):
        raise HandlesError(f"{where}.id", f"expected a non-empty string, got {_describe(hid)}")
    return _FORMATS[kind].parse(data, where, hid)


def _parse_point(data: Mapping[str, Any], where: str, hid: str | None) -> PointHandle:
    target = data.get("target")
    return PointHandle(
        position=_lonlat(data["position"], f"{where}.position"),
        target=None if target is None else _lonlat(target, f"{where}.target"),
        rotation=_number(_given(data, "rotation", 0.0), f"{where}.rotation", *ROTATION_RANGE),
        scale=_number(_given(data, "scale", 1.0), f"{where}.scale", *SCALE_RANGE),
        id=hid,
        reach=None if data.get("reach") is None else _number(data["reach"], f"{where}.reach", *REACH_RANGE),
    )


def _parse_line(data: Mapping[str, Any], where: str, hid: str | None) -> LineHandle:
    rectify = _given(data, "rectify", data.get("targets") is None)
    if not isinstance(rectify, bool):
        raise HandlesError(f"{where}.rectify", f"expected true or false, got {_describe(rectify)}")
    targets = data.get("targets")
    return LineHandle(
        start=_lonlat(data["start"], f"{where}.start"),
        end=_lonlat(data["end"], f"{where}.end"),
        rectify=rectify,
        targets=None if targets is None else _lonlat_triple(targets, f"{where}.targets"),
        id=hid,
    )


def _parse_cage(data: Mapping[str, Any], where: str, hid: str | None) -> CageHandle:
    targets = data.get("targets")
    return CageHandle(
        vertices=_lonlat_list(data["vertices"], f"{where}.vertices", minimum=3),
        targets=None if targets is None else _lonlat_list(targets, f"{where}.targets"),
        id=hid,
    )


def _validate_handle(h: Handle, where: str) -> None:
    """Geometric checks shared by parsed documents and handles built in Python."""
    form = _format_of(h)
    if form is None:
        raise HandlesError(where, f"expected a PointHandle, LineHandle or CageHandle, got {type(h).__name__}")
    form.validate(h, where)
    if h.id is not None and (not isinstance(h.id, str) or not h.id):
        raise HandlesError(f"{where}.id", f"expected a non-empty string, got {_describe(h.id)}")


def _validate_point(h: PointHandle, where: str) -> None:
    _lonlat(h.position, f"{where}.position")
    if h.target is not None:
        _lonlat(h.target, f"{where}.target")
    _number(h.rotation, f"{where}.rotation", *ROTATION_RANGE)
    _number(h.scale, f"{where}.scale", *SCALE_RANGE)
    if h.reach is not None:
        _number(h.reach, f"{where}.reach", *REACH_RANGE)


def _validate_line(h: LineHandle, where: str) -> None:
    _lonlat(h.start, f"{where}.start")
    _lonlat(h.end, f"{where}.end")
    length = _separation(h.start, h.end)
    if length < MIN_SEPARATION:
        raise HandlesError(f"{where}.end", "the line has zero length (start and end coincide)")
    if length > 180.0 - MIN_SEPARATION:
        raise HandlesError(f"{where}.end", "start and end are antipodal: the line between them is not unique")
    if h.targets is not None:
        if h.rectify:
            raise HandlesError(f"{where}.targets", "give either explicit targets or rectify: true, not both")
        _distinct(_lonlat_list(h.targets, f"{where}.targets", count=3), f"{where}.targets")


def _validate_cage(h: CageHandle, where: str) -> None:
    vertices = _lonlat_list(h.vertices, f"{where}.vertices", minimum=3)
    _distinct(vertices, f"{where}.vertices")
    if h.targets is not None:
        targets = _lonlat_list(h.targets, f"{where}.targets", count=len(vertices))
        _distinct(targets, f"{where}.targets")


def _check_count(sizes: list[int]) -> None:
    """Refuse more than :data:`MAX_HANDLES` handles (``OMNIWIDGET_MAX_HANDLES``); ``sizes``: 1 per point or line, a cage's vertices."""
    count, cap = sum(sizes), limit("HANDLES", MAX_HANDLES)
    if count > cap:
        cages = " (a cage's vertices counted each)" if len(sizes) < count else ""
        raise HandlesError(
            "handles",
            f"{count} handles{cages} are more than the limit of {cap} (MAX_HANDLES: the weights' cost grows faster than "
            f"the count, 1,000 points take minutes and over a GB); set OMNIWIDGET_MAX_HANDLES={count} to allow them",
        )


def _validate_document(doc: Handles) -> None:
    if not isinstance(doc.options, Options) or doc.options.rectify not in ("all", "each"):
        raise HandlesError("options.rectify", f"expected 'all' or 'each', got {_describe(getattr(doc.options, 'rectify', None))}")
    if doc.options.anchor is not None:
        _number(doc.options.anchor, "options.anchor", *ANCHOR_RANGE)
    if doc.options.up is not None:
        _up(doc.options.up)
    _check_count([_size(h) for h in doc.handles])
    seen: dict[str, int] = {}
    for i, h in enumerate(doc.handles):
        _validate_handle(h, f"handles[{i}]")
        if h.id is not None:
            if h.id in seen:
                raise HandlesError(f"handles[{i}].id", f"{h.id!r} is already the id of handles[{seen[h.id]}]")
            seen[h.id] = i


def _parse_document(data: Any) -> Handles:
    if not isinstance(data, Mapping):
        raise HandlesError("", f"a handles document is a JSON object with a 'handles' list, got {_describe(data)}")
    for key in data:
        if key not in ("format", "version", "handles", "options"):
            raise HandlesError(str(key), "unknown top-level field (allowed: format, version, handles, options)")
    if data.get("format", FORMAT) != FORMAT:
        raise HandlesError("format", f"expected {FORMAT!r}, got {_describe(data.get('format'))}")
    version = data.get("version", VERSION)
    if isinstance(version, bool) or version != VERSION:
        raise HandlesError("version", f"this omniwidget reads version {VERSION}, got {_describe(version)}")
    if "handles" not in data:
        raise HandlesError("handles", "missing (a list of handles, possibly empty)")
    items = data["handles"]
    if not isinstance(items, list):
        raise HandlesError("handles", f"expected a list, got {_describe(items)}")
    _check_count([len(v) if isinstance(h, Mapping) and isinstance(v := h.get("vertices"), list) else 1 for h in items])  # before the work
    options = data.get("options", {})
    if not isinstance(options, Mapping):
        raise HandlesError("options", f"expected an object, got {_describe(options)}")
    for key in options:
        if key not in ("rectify", "anchor", "up"):
            raise HandlesError(f"options.{key}", "unknown option (allowed: rectify, anchor, up)")
    rectify = options.get("rectify", "all")
    if rectify not in ("all", "each"):
        raise HandlesError("options.rectify", f"expected 'all' or 'each', got {_describe(rectify)}")
    # here null is a value: no still background (the paper's method); left out: the default
    anchor = options.get("anchor", DEFAULT_ANCHOR)
    if anchor is not None:
        anchor = _number(anchor, "options.anchor", *ANCHOR_RANGE)
    up = None if options.get("up") is None else _up(options["up"])
    return Handles(tuple(_parse_handle(item, i) for i, item in enumerate(items)), Options(rectify=rectify, anchor=anchor, up=up))


def _up(value: Any) -> LonLat:
    """``options.up`` checked: a ``[lon, lat]`` whose latitude is in :data:`UP_LATITUDE_RANGE`."""
    lon, lat = _lonlat(value, "options.up")
    if not UP_LATITUDE_RANGE[0] <= lat <= UP_LATITUDE_RANGE[1]:
        raise HandlesError(
            "options.up[1] (latitude)",
            f"expected {UP_LATITUDE_RANGE[0]:g} to {UP_LATITUDE_RANGE[1]:g} (up within 45° of the zenith: a levelling), got {lat:g}",
        )
    return (lon, lat)


def _options_to_dict(options: Options) -> dict[str, Any]:
    out: dict[str, Any] = {"rectify": options.rectify, "anchor": options.anchor}
    if options.up is not None:  # left out when not set: documents without it read as before
        out["up"] = _pair(options.up)
    return out


def _pair(p: Sequence[float]) -> list[float]:
    return [float(p[0]), float(p[1])]


def _handle_to_dict(h: Handle) -> dict[str, Any]:
    form = _format_of(h)
    if form is None:
        raise HandlesError("handles", f"expected a PointHandle, LineHandle or CageHandle, got {type(h).__name__}")
    out = form.to_dict(h)
    if h.id is not None:
        out["id"] = h.id
    return out


def _point_to_dict(h: PointHandle) -> dict[str, Any]:
    out: dict[str, Any] = {
        "kind": "point",
        "position": _pair(h.position),
        "target": _pair(h.final),
        "rotation": h.rotation,
        "scale": h.scale,
    }
    if h.reach is not None:
        out["reach"] = h.reach
    return out


def _line_to_dict(h: LineHandle) -> dict[str, Any]:
    out: dict[str, Any] = {"kind": "line", "start": _pair(h.start), "end": _pair(h.end), "rectify": h.rectify}
    if h.targets is not None:
        out["targets"] = [_pair(t) for t in h.targets]
    return out


def _cage_to_dict(h: CageHandle) -> dict[str, Any]:
    out: dict[str, Any] = {"kind": "cage", "vertices": [_pair(v) for v in h.vertices]}
    if h.targets is not None:
        out["targets"] = [_pair(t) for t in h.targets]
    return out


def _cage_size(h: CageHandle) -> int:
    return len(h.vertices) if isinstance(h.vertices, Sequence) else 1


@dataclass(frozen=True)
class _Format:
    """One kind of handle in the file: its record, its fields, and how it is read, checked, written and counted."""

    record: type
    required: frozenset[str]
    optional: frozenset[str]
    parse: Callable[[Mapping[str, Any], str, str | None], Any]
    validate: Callable[[Any, str], None]
    to_dict: Callable[[Any], dict[str, Any]]
    size: Callable[[Any], int] = lambda h: 1  # how many handles it counts for (MAX_HANDLES)
    maps: Callable[[Any], list[Moebius]] = lambda h: [h.moebius()]


#: Each kind of handle by its ``kind`` field, in the order the file's schema lists them.
_FORMATS: dict[str, _Format] = {
    "point": _Format(
        PointHandle,
        frozenset({"kind", "position"}),
        frozenset({"target", "rotation", "scale", "reach", "id"}),
        _parse_point,
        _validate_point,
        _point_to_dict,
    ),
    "line": _Format(
        LineHandle, frozenset({"kind", "start", "end"}), frozenset({"rectify", "targets", "id"}), _parse_line, _validate_line, _line_to_dict
    ),
    "cage": _Format(
        CageHandle,
        frozenset({"kind", "vertices"}),
        frozenset({"targets", "id"}),
        _parse_cage,
        _validate_cage,
        _cage_to_dict,
        _cage_size,
        lambda h: h.vertex_maps(),
    ),
}
_HANDLE_FIELDS = {kind: (set(form.required), set(form.optional)) for kind, form in _FORMATS.items()}


def _format_of(h: Any) -> _Format | None:
    """The format of a handle record (of its class or a base), None for anything else."""
    return next((form for form in _FORMATS.values() if isinstance(h, form.record)), None)


def _size(h: Any) -> int:
    form = _format_of(h)
    return form.size(h) if form is not None else 1
