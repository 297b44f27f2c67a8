"""One place per kind of handle (point, line, cage): what the method does with each.

The document layer (:mod:`omniwidget.document.handles`) holds the records and the file
format. Everything the method does that depends on the kind of a handle is a method of its
kind object here, found through :data:`KINDS` (record type to kind) by :func:`kind_of`:

- ``maps``: its Möbius maps, one per control (Sec. 3.3, built by the record's public ``moebius`` or ``vertex_maps``);
- ``anchors``: how it takes part, held where its maps put it, in the solve of Sec. 3.4;
- ``add_controls``: its controls and the points where their weights are prescribed;
- ``output_points``: where its control points land in the output;
- ``reset``: the handle as drawn, before any transformation;
- ``footprint``: the arcs it marks in the input and the output (how far other handles' reach may go);
- ``outline``: the arcs and dots that draw it (:func:`omniwidget.io.draw.draw_handles`);
- ``carried``: its output turned by a rotation of the whole output (a new levelling);
- ``input_turned``: its input positions turned, its outputs kept (the input levelled);
- ``moving``: whether it may move what is near it, and where it marks (a still cage's conflicts).

A new kind of handle is a record with its file format and schema in the document layer,
and one kind object here added to :data:`KINDS` (``docs/handle-kinds.md``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np
from numpy.typing import NDArray

from ..document.handles import CageHandle, Handle, Handles, LineHandle, LonLat, PointHandle
from ..sphere import coords
from ..sphere.moebius import Moebius
from .rectify import Anchor

if TYPE_CHECKING:
    from .constraints import Constraints

__all__ = [
    "CAGE",
    "KINDS",
    "LINE",
    "POINT",
    "POINT_HOLD",
    "RIM_SAMPLES",
    "CageKind",
    "Control",
    "Kind",
    "LineKind",
    "Outline",
    "PointKind",
    "Rows",
    "kind_of",
    "output_points",
    "reset",
]

#: With the still background a point handle's map holds exactly within this many degrees of
#: its target (the disk's mesh vertices carry its weight 1), so the centre, the zoom and the
#: turn the person set are what the image shows there.
POINT_HOLD = 1.0
#: Samples on the rim of a point handle's disk.
RIM_SAMPLES = 12

#: A line piece's map cut for its length: input start and end ``[lon, lat]`` (2,) and the map.
Part = tuple[NDArray[np.float64], NDArray[np.float64], Moebius]


@dataclass(frozen=True)
class Control:
    """One Möbius map of the blend and where it comes from.

    Attributes
    ----------
    moebius : Moebius
        Input sphere to output sphere.
    handle : int
        Index of the handle in the document.
    label : str
        Human-readable name, e.g. ``"handles[3] (line, part 2 of 2)"`` or ``"handles[5] (cage vertex 1)"``.
    """

    moebius: Moebius
    handle: int
    label: str


@dataclass
class Rows:
    """The controls and prescribed weights of a document, as its kinds add them (:func:`~omniwidget.method.constraints.build_constraints`).

    Attributes
    ----------
    t : ndarray of float64, shape (s,)
        The sample parameters along a line or a cage edge, 0 to 1.
    background : bool
        The still background is on (``options.anchor`` set).
    line_parts : dict of int to list of (int, list of Part)
        For each line handle, its pieces (index, after crossings are split) and each piece's
        maps cut for its length.
    joint_of : dict of (int, int) to int
        ``(piece, end)`` to joint id, ``end`` 0 for the start and 1 for the end.
    controls, points, weights
        The controls so far, and the prescribed weights as points (unit vectors) each with
        ``{control: weight}``.
    lines, chains, disks, cages
        As in :class:`~omniwidget.method.constraints.Constraints`.
    joints : dict of int to (ndarray, dict of int to float)
        Each joint's output point and the controls that meet there, shared by
        :meth:`share_joints` once all lines are in.
    """

    t: NDArray[np.float64]
    background: bool
    line_parts: dict[int, list[tuple[int, list[Part]]]] = field(default_factory=dict)
    joint_of: dict[tuple[int, int], int] = field(default_factory=dict)
    controls: list[Control] = field(default_factory=list)
    points: list[NDArray[np.float64]] = field(default_factory=list)
    weights: list[dict[int, float]] = field(default_factory=list)
    lines: list[tuple[int, NDArray[np.float64]]] = field(default_factory=list)
    chains: list[tuple[int, ...]] = field(default_factory=list)
    disks: list[tuple[int, NDArray[np.float64]]] = field(default_factory=list)
    cages: list[tuple[tuple[int, ...], NDArray[np.float64]]] = field(default_factory=list)
    joints: dict[int, tuple[NDArray[np.float64], dict[int, float]]] = field(default_factory=dict)

    def control(self, moebius: Moebius, handle: int, label: str) -> int:
        """Add a control; returns its index."""
        self.controls.append(Control(moebius, handle, label))
        return len(self.controls) - 1

    def prescribe(self, point: NDArray[np.float64], weights: dict[int, float]) -> None:
        """Prescribe ``weights`` (control to weight, every other control 0) at ``point``, a unit vector (3,)."""
        self.points.append(point)
        self.weights.append(weights)

    def join(self, joint: int, point: NDArray[np.float64], control: int) -> None:
        """Let ``control`` meet at ``joint`` (its output point is the first one given)."""
        self.joints.setdefault(joint, (point, {}))[1][control] = 1.0

    def share_joints(self) -> None:
        """Each joint's weight, 1 / n for each of the n controls that meet there."""
        for point, members in self.joints.values():
            self.prescribe(point, dict.fromkeys(members, 1.0 / len(members)))
        self.joints = {}

    def values(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The points, shape (p, 3), and the prescribed weights, shape (p, k)."""
        points = np.array(self.points, dtype=np.float64).reshape(-1, 3)
        values = np.zeros((len(self.weights), len(self.controls)))
        for r, weights in enumerate(self.weights):
            for c, weight in weights.items():
                values[r, c] = weight
        return points, values


@dataclass(frozen=True)
class Outline:
    """How a handle is drawn: arcs (each ``[lon, lat]`` (n, 2)), dots and one larger dot (``[lon, lat]``)."""

    arcs: tuple[NDArray[np.float64], ...]
    dots: NDArray[np.float64]
    big_dots: NDArray[np.float64] = field(default_factory=lambda: np.empty((0, 2)))


#: Where a line's pieces put their samples: ``(map, input samples as unit vectors (s, 3))`` per piece.
Pieces = Sequence[tuple[Moebius, NDArray[np.float64]]]
#: Draws an arc from ``a`` to ``b`` (``[lon, lat]``) as a polyline (n, 2).
Arc = Callable[[Sequence[float], Sequence[float]], NDArray[np.float64]]


class Kind(Protocol):
    """What the method does with one kind of handle; one object per kind, in :data:`KINDS`."""

    name: str

    def maps(self, h: Any, carry: bool = False) -> list[Moebius]:
        """Its Möbius maps, input sphere to output sphere, one per control."""

    def anchors(self, h: Any, t: NDArray[np.float64]) -> list[Anchor]:
        """Its part in the solve of Sec. 3.4, held where its maps put it (lines take part as bones instead)."""

    def add_controls(self, i: int, h: Any, rows: Rows) -> None:
        """Add its controls and prescribed weights to ``rows``; ``i`` is its index in the document."""

    def output_points(self, h: Any, pieces: Pieces | None) -> NDArray[np.float64]:
        """Where its control points go in the output, ``[lon, lat]`` (n, 2); ``pieces``: a line's pieces, if solved."""

    def reset(self, h: Any) -> Any:
        """The handle as drawn, before any transformation."""

    def footprint(self, h: Any, t: NDArray[np.float64]) -> list[NDArray[np.float64]]:
        """What it marks, ``[lon, lat]`` arrays, in the input and where its maps put it."""

    def outline(self, h: Any, stage: str, arc: Arc) -> Outline:
        """The arcs and dots that draw it at ``stage`` (``"input"`` or ``"output"``)."""

    def carried(self, h: Any, old: Moebius, turn: Moebius) -> Any:
        """The handle whose output, shown now under ``old``, is turned by ``turn`` (a new levelling)."""

    def input_turned(self, h: Any, turn: Moebius) -> Any:
        """The handle with its input positions turned by ``turn`` and its outputs kept (the input levelled)."""

    def moving(self, h: Any) -> tuple[bool, list[LonLat]]:
        """Whether it may move what is near it, and the positions it marks, input and output (what a still cage must not hold)."""


def _as_pairs(points: NDArray[np.float64]) -> tuple[LonLat, ...]:
    return tuple((float(lon), float(lat)) for lon, lat in points)


def _turned(turn: Moebius, p: LonLat) -> LonLat:
    lon, lat = turn(np.asarray(p, dtype=np.float64))
    return (float(lon), float(lat))


def _ring_arcs(ring: Sequence[LonLat], t: NDArray[np.float64]) -> list[NDArray[np.float64]]:
    """The geodesic edges of a closed polygon, each sampled at ``t``."""
    n = len(ring)
    return [coords.geodesic(ring[v], ring[(v + 1) % n], t) for v in range(n)]


class PointKind:
    """A point handle: one map (its :meth:`~omniwidget.document.handles.PointHandle.moebius`), weight 1 at its target."""

    name = "point"

    def maps(self, h: PointHandle, carry: bool = False) -> list[Moebius]:
        """Its one map (:meth:`~omniwidget.document.handles.PointHandle.moebius`)."""
        return [h.moebius()]

    def anchors(self, h: PointHandle, t: NDArray[np.float64]) -> list[Anchor]:
        """Its position held at its target."""
        return [Anchor(np.array([h.position], np.float64), np.array([h.final], np.float64))]

    def add_controls(self, i: int, h: PointHandle, rows: Rows) -> None:
        """One control, weight 1 at its target; with the still background on the rim of a disk around it too."""
        c = rows.control(h.moebius(), i, f"handles[{i}] (point)")
        centre = coords.lonlat_to_xyz(h.final)
        rows.prescribe(centre, {c: 1.0})
        if rows.background:  # the rim of the disk where the point's map holds exactly
            rows.disks.append((c, centre))
            east, north = coords.local_frame(h.final)
            turn = np.linspace(0.0, 2.0 * math.pi, RIM_SAMPLES, endpoint=False)[:, None]
            r = math.radians(POINT_HOLD)
            for p in math.cos(r) * centre + math.sin(r) * (np.cos(turn) * east + np.sin(turn) * north):
                rows.prescribe(p, {c: 1.0})

    def output_points(self, h: PointHandle, pieces: Pieces | None) -> NDArray[np.float64]:
        """Centre, east and west arrow tips in the output."""
        return h.target_points()

    def reset(self, h: PointHandle) -> PointHandle:
        """No target, no turn, no zoom."""
        return replace(h, target=None, rotation=0.0, scale=1.0)

    def footprint(self, h: PointHandle, t: NDArray[np.float64]) -> list[NDArray[np.float64]]:
        """Its position and its target."""
        return [np.asarray([h.position, h.final], np.float64)]

    def outline(self, h: PointHandle, stage: str, arc: Arc) -> Outline:
        """Two arrows from the centre (drawn larger) to the tips."""
        points = h.control_points() if stage == "input" else h.target_points()
        return Outline(tuple(arc(points[0], tip) for tip in points[1:]), np.empty((0, 2)), points[:1])

    def carried(self, h: PointHandle, old: Moebius, turn: Moebius) -> PointHandle:
        """Its target turned, and its own turn corrected by what the rotation turns there."""
        shown = old(np.asarray(h.position, dtype=np.float64))
        final = h.target if h.target is not None else tuple(shown)  # as shown now
        (target,) = _as_pairs(turn(np.asarray([final], dtype=np.float64)))
        at_target = turn.local_scale_rotation(final)[1]
        at_position = turn.local_scale_rotation(shown)[1]
        return replace(h, target=target, rotation=_wrap_turn(h.rotation + at_target - at_position))

    def input_turned(self, h: PointHandle, turn: Moebius) -> PointHandle:
        """Its position turned."""
        return replace(h, position=_turned(turn, h.position))

    def moving(self, h: PointHandle) -> tuple[bool, list[LonLat]]:
        """Moved, turned or zoomed; its position and target."""
        return h.final != h.position or h.scale != 1.0 or h.rotation != 0.0, [h.position, h.final]


def _wrap_turn(angle: float) -> float:
    """An angle in degrees brought into ``(-180, 180]``."""
    out = math.fmod(angle, 360.0)
    if out > 180.0:
        out -= 360.0
    elif out <= -180.0:
        out += 360.0
    return out


class LineKind:
    """A line handle, the paper's spherical bone: one map per piece, weight 1 along its output image."""

    name = "line"

    def maps(self, h: LineHandle, carry: bool = False) -> list[Moebius]:
        """Its own map (eq. 4, explicit targets, or the identity), before Sec. 3.4 and any cut."""
        return [h.moebius()]

    def anchors(self, h: LineHandle, t: NDArray[np.float64]) -> list[Anchor]:
        """None: a line takes part in Sec. 3.4 as a bone."""
        return []

    def add_controls(self, i: int, h: LineHandle, rows: Rows) -> None:
        """One control per part of each piece, weight 1 along its output samples, joints and part ends shared."""
        parts_of = rows.line_parts[i]
        total = sum(len(parts) for _, parts in parts_of)
        number = 0
        for k, parts in parts_of:
            first = len(rows.lines)
            for j, (start, end, m) in enumerate(parts):
                number += 1
                part = f", part {number} of {total}" if total > 1 else ""
                c = rows.control(m, i, f"handles[{i}] (line{part})")
                src = coords.geodesic(start, end, rows.t)
                rows.lines.append((c, src))
                _line_samples(rows, k, c, m.apply_xyz(coords.lonlat_to_xyz(src)), first=j == 0, last=j == len(parts) - 1)
            rows.chains.append(tuple(range(first, len(rows.lines))))

    def output_points(self, h: LineHandle, pieces: Pieces | None) -> NDArray[np.float64]:
        """Start, middle and end, each under the piece that comes nearest it (the line's own map when not solved)."""
        points = h.control_points()
        if pieces:
            for k, p in enumerate(coords.lonlat_to_xyz(points)):
                reach = [float((piece[1] @ p).max()) for piece in pieces]
                nearest = pieces[reach.index(max(reach))]  # the first piece that comes nearest
                points[k] = nearest[0](points[k])
        return points

    def reset(self, h: LineHandle) -> LineHandle:
        """Not rectified, no explicit targets."""
        return replace(h, rectify=False, targets=None)

    def footprint(self, h: LineHandle, t: NDArray[np.float64]) -> list[NDArray[np.float64]]:
        """Its geodesic in the input and its image under its own map."""
        src = coords.geodesic(h.start, h.end, t)
        return [src, h.moebius()(src)]

    def outline(self, h: LineHandle, stage: str, arc: Arc) -> Outline:
        """Its geodesic and its three control points (under its own map at the output)."""
        curve = arc(h.start, h.end)
        if stage == "output":
            return Outline((h.moebius()(curve),), h.target_points())
        return Outline((curve,), h.control_points())

    def carried(self, h: LineHandle, old: Moebius, turn: Moebius) -> LineHandle:
        """Explicit targets turned; a rectified line follows the levelled input by itself."""
        if h.targets is None:
            return h
        start, middle, end = _as_pairs(turn(np.asarray(h.targets, dtype=np.float64)))
        return replace(h, targets=(start, middle, end))

    def input_turned(self, h: LineHandle, turn: Moebius) -> LineHandle:
        """Its start and end turned."""
        return replace(h, start=_turned(turn, h.start), end=_turned(turn, h.end))

    def moving(self, h: LineHandle) -> tuple[bool, list[LonLat]]:
        """Always (its map, or the solve of Sec. 3.4, may bend what is near it); its ends."""
        return True, [h.start, h.end]


def _line_samples(rows: Rows, piece: int, c: int, out: NDArray[np.float64], *, first: bool, last: bool) -> None:
    """A line part's output samples ``out`` (s, 3) as rows of control ``c``: its own, a joint's, or shared with the next part."""
    samples = len(out)
    for s in range(samples):
        if s == 0 and not first:
            continue  # the joint with the part before, already a row
        if s == samples - 1 and not last:
            rows.prescribe(out[s], {c: 0.5, c + 1: 0.5})  # both parts' maps put it here
            continue
        end = 0 if s == 0 else 1 if s == samples - 1 else None
        if end is not None and (piece, end) in rows.joint_of:
            rows.join(rows.joint_of[(piece, end)], out[s], c)
            continue
        rows.prescribe(out[s], {c: 1.0})


class CageKind:
    """A spherical cage: one map per vertex, weights varying linearly along each output edge."""

    name = "cage"

    def maps(self, h: CageHandle, carry: bool = False) -> list[Moebius]:
        """One map per vertex (:meth:`~omniwidget.document.handles.CageHandle.vertex_maps`)."""
        return h.vertex_maps(carry=carry)

    def anchors(self, h: CageHandle, t: NDArray[np.float64]) -> list[Anchor]:
        """Each edge held where the vertices' targets put it."""
        return [Anchor(a, b) for a, b in zip(_ring_arcs(h.vertices, t), _ring_arcs(h.finals, t), strict=True)]

    def add_controls(self, i: int, h: CageHandle, rows: Rows) -> None:
        """One control per vertex, weight 1 there, varying linearly along each output edge."""
        maps = h.vertex_maps(carry=rows.background)
        first = len(rows.controls)
        for v, m in enumerate(maps):
            rows.control(m, i, f"handles[{i}] (cage vertex {v})")
        rows.cages.append((tuple(range(first, len(rows.controls))), np.asarray(h.finals, dtype=np.float64)))
        finals = coords.lonlat_to_xyz(np.asarray(h.finals, dtype=np.float64))
        n, t = len(maps), rows.t
        for v in range(n):
            w = (v + 1) % n
            arc = coords.lonlat_to_xyz(coords.geodesic(coords.xyz_to_lonlat(finals[v]), coords.xyz_to_lonlat(finals[w]), t[:-1]))
            for s, point in enumerate(arc):
                weights = {first + v: 1.0 - t[s]}
                if t[s] > 0:
                    weights[first + w] = t[s]
                rows.prescribe(point, weights)

    def output_points(self, h: CageHandle, pieces: Pieces | None) -> NDArray[np.float64]:
        """The vertices' targets."""
        return np.asarray(h.finals, float)

    def reset(self, h: CageHandle) -> CageHandle:
        """No targets: the cage stays."""
        return replace(h, targets=None)

    def footprint(self, h: CageHandle, t: NDArray[np.float64]) -> list[NDArray[np.float64]]:
        """Its edges in the input and in the output."""
        return _ring_arcs(h.vertices, t) + _ring_arcs(h.finals, t)

    def outline(self, h: CageHandle, stage: str, arc: Arc) -> Outline:
        """Its edges and vertices."""
        vertices = h.vertices if stage == "input" else h.finals
        arcs = tuple(arc(a, b) for a, b in zip(vertices, vertices[1:] + vertices[:1], strict=True))
        return Outline(arcs, np.asarray(vertices, np.float64))

    def carried(self, h: CageHandle, old: Moebius, turn: Moebius) -> CageHandle:
        """Its vertices' output positions turned."""
        finals = h.targets if h.targets is not None else _as_pairs(old(np.asarray(h.vertices, dtype=np.float64)))
        return replace(h, targets=_as_pairs(turn(np.asarray(finals, dtype=np.float64))))

    def input_turned(self, h: CageHandle, turn: Moebius) -> CageHandle:
        """Its vertices turned."""
        return replace(h, vertices=tuple(_turned(turn, v) for v in h.vertices))

    def moving(self, h: CageHandle) -> tuple[bool, list[LonLat]]:
        """Moved when any vertex has a target of its own; its vertices and their targets."""
        return h.finals != h.vertices, [*h.vertices, *h.finals]


POINT = PointKind()
LINE = LineKind()
CAGE = CageKind()

#: The kind of each handle record.
KINDS: dict[type, Kind] = {PointHandle: POINT, LineHandle: LINE, CageHandle: CAGE}


def kind_of(h: Handle) -> Kind:
    """The kind object of a handle record (:data:`KINDS`).

    Raises
    ------
    TypeError
        For anything that is not a handle record of a known kind.
    """
    for cls in type(h).__mro__:  # a subclass of a record is of its kind
        kind = KINDS.get(cls)
        if kind is not None:
            return kind
    raise TypeError(f"expected a PointHandle, LineHandle or CageHandle, got {type(h).__name__}")


def output_points(doc: Handles, constraints: Constraints) -> list[list[list[float]]]:
    """For each handle, where its control points go in the output, ``[lon, lat]`` in degrees, rounded to 1e-9.

    A point: centre, east and west arrow tips. A line: start, middle, end, placed by the
    rectify-all solve when the document asks for it (a line split at a crossing takes each
    control point from the piece nearest to it). A cage: its vertices' targets.

    Parameters
    ----------
    doc : Handles
    constraints : Constraints
        The document's controls (:func:`~omniwidget.method.constraints.build_constraints`).

    Returns
    -------
    list of list of [float, float]
        One list of points per handle, in the document's order.
    """
    pieces: dict[int, list[tuple[Moebius, NDArray[np.float64]]]] = {}
    for index, samples in constraints.lines:
        control = constraints.controls[index]
        pieces.setdefault(control.handle, []).append((control.moebius, coords.lonlat_to_xyz(samples)))
    out = []
    for i, h in enumerate(doc.handles):
        points = kind_of(h).output_points(h, pieces.get(i))
        out.append([[round(float(lon), 9), round(float(lat), 9)] for lon, lat in points])
    return out


def reset(handle: Handle) -> Handle:
    """The handle as drawn, before any transformation: a point without target, turn or zoom, a line not rectified, a cage that stays."""
    return kind_of(handle).reset(handle)
