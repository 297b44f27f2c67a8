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
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from . import coords
from ._checks import whole_number
from .handles import CageHandle, Handles, LineHandle, PointHandle
from .moebius import Moebius
from .rectify import Anchor, Bone, RectifySolution, solve_bones

__all__ = ["JOINT_DISTANCE", "SAMPLES", "Constraints", "Control", "build_constraints"]

#: Samples per line and per cage edge (the paper's 50).
SAMPLES = 50
#: Line endpoints closer than this (degrees) merge into one joint: the authors' 2π/150 rad.
JOINT_DISTANCE = 360.0 / 150.0
#: How close to an endpoint (degrees) a crossing may be and still split the lines.
CROSSING_MARGIN = 1e-6


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
        For each line piece, its control index and its input samples ``[lon, lat]`` (s, 2),
        from which straightness is measured.
    rectified : RectifySolution or None
        With ``options.rectify == "all"`` and at least one rectified line: the solve of
        Sec. 3.4 that placed the lines' control points (:mod:`.rectify`).
    """

    controls: tuple[Control, ...]
    points: NDArray[np.float64]
    values: NDArray[np.float64]
    lines: tuple[tuple[int, NDArray[np.float64]], ...]
    rectified: RectifySolution | None = None


def _cross(a: NDArray, b: NDArray) -> tuple[float, float, float]:
    """``a × b`` of two 3-vectors, without ``np.cross``'s overhead (it is called for every pair of lines)."""
    a0, a1, a2 = float(a[0]), float(a[1]), float(a[2])
    b0, b1, b2 = float(b[0]), float(b[1]), float(b[2])
    return (a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0)


def _dot(a: Sequence[float], b: Sequence[float]) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _arc_crossing(a0: NDArray, a1: NDArray, b0: NDArray, b1: NDArray) -> NDArray | None:
    """The point where two geodesic arcs (unit vectors) cross strictly inside both, or None."""
    na, nb = _cross(a0, a1), _cross(b0, b1)
    axis = _cross(na, nb)
    norm = math.sqrt(_dot(axis, axis))
    if norm < 1e-12:
        return None  # same great circle: overlapping lines are not split
    margin = math.radians(CROSSING_MARGIN)
    limit_a, limit_b = margin * math.sqrt(_dot(na, na)), margin * math.sqrt(_dot(nb, nb))
    for sign in (1.0, -1.0):
        x = np.array(axis) * (sign / norm)
        inside_a = _dot(_cross(a0, x), na) > limit_a and _dot(_cross(x, a1), na) > limit_a
        inside_b = _dot(_cross(b0, x), nb) > limit_b and _dot(_cross(x, b1), nb) > limit_b
        if inside_a and inside_b:
            return x
    return None


@dataclass
class _Piece:
    handle: int
    start: NDArray[np.float64]  # unit vectors
    end: NDArray[np.float64]
    line: LineHandle


def _split_crossings(pieces: list[_Piece]) -> list[_Piece]:
    """Split rectified lines at their crossings (Sec. 4), repeatedly until none cross."""
    changed = True
    while changed:
        changed = False
        for i in range(len(pieces)):
            for j in range(i + 1, len(pieces)):
                a, b = pieces[i], pieces[j]
                if a.line.targets is not None or b.line.targets is not None:
                    continue  # explicit targets say where three points go: splitting would change them
                x = _arc_crossing(a.start, a.end, b.start, b.end)
                if x is None:
                    continue
                pieces[j : j + 1] = [_Piece(b.handle, b.start, x, b.line), _Piece(b.handle, x, b.end, b.line)]
                pieces[i : i + 1] = [_Piece(a.handle, a.start, x, a.line), _Piece(a.handle, x, a.end, a.line)]
                changed = True
                break
            if changed:
                break
    return pieces


def _joints(pieces: list[_Piece], distance: float) -> dict[tuple[int, int], int]:
    """Cluster line endpoints closer than ``distance`` degrees; returns (piece, end) -> joint id."""
    ends = [(i, e) for i, p in enumerate(pieces) if p.line.targets is None for e in (0, 1)]
    xyz = np.array([pieces[i].start if e == 0 else pieces[i].end for i, e in ends]).reshape(-1, 3)
    parent = list(range(len(ends)))

    def root(a: int) -> int:
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    limit = 2 * math.sin(math.radians(distance) / 2)
    for a in range(len(ends)):
        for b in range(a + 1, len(ends)):
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


def build_constraints(handles: Handles, *, samples: int = SAMPLES, joint_distance: float = JOINT_DISTANCE) -> Constraints:
    """The controls of a handles document and the boundary conditions of their weights.

    Parameters
    ----------
    handles : Handles
    samples : int
        Points per line and per cage edge, endpoints included (at least 2).
    joint_distance : float
        Degrees; line endpoints closer than this become one joint.

    Returns
    -------
    Constraints
    """
    samples = whole_number(samples, "samples", 2)
    t = np.linspace(0.0, 1.0, samples)
    controls: list[Control] = []
    rows: list[tuple[NDArray[np.float64], dict[int, float]]] = []  # (point, {control: weight})
    line_samples: list[tuple[int, NDArray[np.float64]]] = []

    pieces = [
        _Piece(i, coords.lonlat_to_xyz(h.start), coords.lonlat_to_xyz(h.end), h)
        for i, h in enumerate(handles.handles)
        if isinstance(h, LineHandle)
    ]
    pieces = _split_crossings(pieces)
    joint_of = _joints(pieces, joint_distance)
    pieces_of: dict[int, list[int]] = {}
    for k, piece in enumerate(pieces):
        pieces_of.setdefault(piece.handle, []).append(k)
    solution = _rectify_all(handles, pieces, joint_of, t) if handles.options.rectify == "all" else None
    joint_rows: dict[int, dict[int, float]] = {}
    joint_points: dict[int, NDArray[np.float64]] = {}

    for i, h in enumerate(handles.handles):
        if isinstance(h, PointHandle):
            controls.append(Control(h.moebius(), i, f"handles[{i}] (point)"))
            rows.append((coords.lonlat_to_xyz(h.final), {len(controls) - 1: 1.0}))
        elif isinstance(h, CageHandle):
            first = len(controls)
            maps = h.vertex_maps()
            for v, m in enumerate(maps):
                controls.append(Control(m, i, f"handles[{i}] (cage vertex {v})"))
            finals = coords.lonlat_to_xyz(np.asarray(h.finals, dtype=np.float64))
            n = len(maps)
            for v in range(n):
                w = (v + 1) % n
                arc = coords.lonlat_to_xyz(coords.geodesic(coords.xyz_to_lonlat(finals[v]), coords.xyz_to_lonlat(finals[w]), t[:-1]))
                for s, point in enumerate(arc):
                    weights = {first + v: 1.0 - t[s]}
                    if t[s] > 0:
                        weights[first + w] = t[s]
                    rows.append((point, weights))
        else:
            own = pieces_of[i]
            for n, k in enumerate(own, start=1):
                piece = pieces[k]
                part = f", part {n} of {len(own)}" if len(own) > 1 else ""
                start, end = coords.xyz_to_lonlat(piece.start), coords.xyz_to_lonlat(piece.end)
                # explicit targets keep the handle as drawn; otherwise the piece's (split, snapped) ends
                if h.targets is not None:
                    line = h
                elif solution is not None and solution.targets[k] is not None:
                    line = LineHandle(tuple(start), tuple(end), rectify=False, targets=tuple(map(tuple, solution.targets[k])))
                else:
                    line = LineHandle(tuple(start), tuple(end), rectify=h.rectify)
                m = line.moebius()
                controls.append(Control(m, i, f"handles[{i}] (line{part})"))
                c = len(controls) - 1
                src = coords.geodesic(start, end, t)
                line_samples.append((c, src))
                out = m.apply_xyz(coords.lonlat_to_xyz(src))
                for s in range(samples):
                    end_id = 0 if s == 0 else 1 if s == samples - 1 else None
                    if end_id is not None and (k, end_id) in joint_of:
                        jid = joint_of[(k, end_id)]
                        joint_rows.setdefault(jid, {})[c] = 1.0
                        joint_points.setdefault(jid, out[s])
                        continue
                    rows.append((out[s], {c: 1.0}))
    for jid, members in joint_rows.items():
        share = 1.0 / len(members)
        rows.append((joint_points[jid], dict.fromkeys(members, share)))

    k = len(controls)
    points = np.array([r[0] for r in rows], dtype=np.float64).reshape(-1, 3)
    values = np.zeros((len(rows), k))
    for r, (_, weights) in enumerate(rows):
        for c, w in weights.items():
            values[r, c] = w
    return Constraints(tuple(controls), points, values, tuple(line_samples), solution)


def _rectify_all(handles: Handles, pieces: list[_Piece], joint_of: dict[tuple[int, int], int], t: NDArray) -> RectifySolution | None:
    """Sec. 3.4 for the rectified line pieces; the other handles take part as they are."""
    free = [p.line.rectify and p.line.targets is None for p in pieces]
    if not any(free):
        return None
    bones = []
    for k, piece in enumerate(pieces):
        start, end = coords.xyz_to_lonlat(piece.start), coords.xyz_to_lonlat(piece.end)
        outputs = None
        if not free[k]:
            outputs = piece.line.moebius()(coords.geodesic(start, end, t))  # its targets, or the identity
        bones.append(Bone(tuple(start), tuple(end), free[k], (joint_of.get((k, 0)), joint_of.get((k, 1))), outputs))
    anchors = []
    for h in handles.handles:
        if isinstance(h, PointHandle):
            anchors.append(Anchor(np.array([h.position], np.float64), np.array([h.final], np.float64)))
        elif isinstance(h, CageHandle):
            n = len(h.vertices)
            for v in range(n):
                w = (v + 1) % n
                anchors.append(Anchor(coords.geodesic(h.vertices[v], h.vertices[w], t), coords.geodesic(h.finals[v], h.finals[w], t)))
    return solve_bones(bones, anchors, samples=len(t), keep="endpoints" if handles.options.anchor is None else "sphere")
