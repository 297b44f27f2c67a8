"""The paper's method from a handles document to a deformation of the sphere, step by step (Sec. 3).

:func:`deform` runs the steps in order: the controls and their boundary conditions
(:mod:`.constraints`, with the Sec. 3.4 solve of :mod:`.rectify`), the adaptive mesh at the
handles' final positions (:mod:`.mesh`), the still background when asked for
(:mod:`.background`), and the bounded biharmonic weights (:mod:`.bbw`). The answer, a
:class:`Deformation`, is the blend of eq. (2), ``T⁻¹(p) = normalize(Σ_j W_j(p) M_j⁻¹(p))``,
which :meth:`Deformation.inverse_points` evaluates at any direction. The per-pixel engine
(:mod:`omniwidget.raster`) evaluates it on an image's grid.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._blas import one_blas_thread
from .._lazy import lazy
from .._timing import Laps
from ..document.handles import CageHandle, Handles, LineHandle, PointHandle
from ..sphere import coords
from ..sphere.arcs import crossing_pairs, inside_polygon
from ..sphere.moebius import Moebius
from . import bbw, harmonic
from .background import BACKGROUND, BACKGROUND_EASE, cage_insides, carry_insides, ease_background, with_background
from .constraints import SAMPLES, Constraints, Control, build_constraints
from .harmonic import HarmonicFill, harmonic_fill
from .kinds import kind_of
from .limits import check_mesh, check_weights
from .locate import interpolate, locate_points
from .mesh import adaptive_mesh
from .problems import Kind, Problem
from .reach import reach_discs, reach_samples, solved, with_reach

if TYPE_CHECKING:
    from scipy import spatial
else:
    spatial = lazy("scipy.spatial")

__all__ = ["Blend", "Deformation", "blended_points", "crossing_handles", "deform", "levelled_handles", "turned"]


#: An empty set of constraints, to strip a solve's controls of its ladders (:func:`.reach.solved`).
_EMPTY = Constraints((), np.zeros((0, 3)), np.zeros((0, 0)), ())


@dataclass(frozen=True, eq=False, kw_only=True)
class Blend:
    """The controls' maps blended by bounded biharmonic weights on the adaptive mesh (Secs. 3.2 and 3.5).

    A deformation has one unless one map does it all; every array is then set, so a single
    check (``deformation.blend is None``) tells the two cases apart.

    Attributes
    ----------
    vertices, faces : ndarray
        The adaptive mesh, (n, 3) float64 and (m, 3) int64.
    constrained : ndarray of int64
        Mesh vertices carrying boundary conditions, (b,).
    prescribed : ndarray of float64
        The weights prescribed there, (b, k): the boundary conditions the solver was given
        (conflicting prescriptions on one vertex already averaged).
    weights : ndarray of float64
        The blend's weights per mesh vertex and control, (n, k): the bounded biharmonic
        weights normalised, and with a still background eased
        (:func:`~omniwidget.method.background.ease_background`) and spread over the
        ladders of the point handles that turn or zoom (:func:`~omniwidget.method.reach.with_reach`:
        their rungs' columns come before the background's, and ``raw_weights`` has none).
    raw_weights : ndarray of float64
        The bounded biharmonic weights before the rows were normalised, (n, k'), one column
        per control of :func:`~omniwidget.method.reach.solved` (no rungs): what
        :func:`omniwidget.method.bbw.bbw` solved for, kept so that the next solve of a
        similar document can start from them (``deform(..., previous=...)``).
    fill : HarmonicFill or None
        With the still background: the map between the handles, filled in as the most
        conformal map that agrees with the blend around them (:mod:`.harmonic`); None in
        the paper's mode or where the handles and the background hold every node.
    """

    vertices: NDArray[np.float64]
    faces: NDArray[np.int64]
    constrained: NDArray[np.int64]
    prescribed: NDArray[np.float64]
    weights: NDArray[np.float64]
    raw_weights: NDArray[np.float64] = field(repr=False)
    fill: HarmonicFill | None = field(default=None, repr=False)

    def inverse_points(self, inverses: Sequence[Moebius], xyz: NDArray[np.float64]) -> NDArray[np.float64]:
        """Eq. (2) with the :attr:`fill`, for the controls' inverse maps, at output directions (..., 3): input ``[lon, lat]`` (..., 2)."""
        shown = blended_points(inverses, self.vertices, self.faces, self.weights, xyz)
        if self.fill is None:
            return shown
        return coords.xyz_to_lonlat(self.fill.apply(coords.xyz_to_lonlat(xyz), coords.lonlat_to_xyz(shown)))

    def weights_at(self, xyz: NDArray[np.float64]) -> NDArray[np.float64]:
        """The weights interpolated at directions (n, 3) on the mesh, (n, k)."""
        face, bary = locate_points(self.vertices, self.faces, xyz)
        return np.asarray(interpolate(self.weights, self.faces, face, bary), dtype=np.float64)

    def solves(self, vertices: NDArray, faces: NDArray, constrained: NDArray, prescribed: NDArray) -> bool:
        """Whether this blend's weights solved the weights problem of that mesh and those boundary conditions."""
        return (
            np.array_equal(self.vertices, vertices)
            and np.array_equal(self.faces, faces)
            and np.array_equal(self.constrained, constrained)
            and np.array_equal(self.prescribed, prescribed)
        )

    def raw_weights_at(self, vertices: NDArray[np.float64]) -> NDArray[np.float64]:
        """The raw weights carried to another mesh's vertices (n, 3): taken where a vertex is one of this mesh's, else interpolated."""
        # most vertices of a new mesh are vertices of the old one (the same icosphere, refined alike far from what moved)
        distance, nearest = spatial.cKDTree(self.vertices).query(vertices)
        out = self.raw_weights[nearest]
        moved = np.flatnonzero(distance > 1e-12)
        if len(moved):
            face, bary = locate_points(self.vertices, self.faces, vertices[moved])
            out[moved] = interpolate(self.raw_weights, self.faces, face, bary)
        return out


@dataclass(frozen=True, eq=False, kw_only=True)
class Deformation:
    """What the method computed for a handles document: the controls' maps and the weights that blend them.

    Attributes
    ----------
    handles : Handles
        The document.
    constraints : Constraints
        The controls (one Möbius map each) and the prescribed weights; with a still
        background, its control is the last.
    blend : Blend or None
        The weights on the adaptive mesh, and the fill; None when one map does it all. Its
        parts read as attributes here too (``vertices``, ``faces``, ``constrained``,
        ``prescribed``, ``weights``, ``raw_weights``, ``fill``: each None without a blend).
    problems : tuple of Problem
        Conflicts found on the way (:mod:`.problems`): their kind, the handles they name
        and their message.
    timings : dict of str to float
        Seconds per step.
    """

    handles: Handles
    constraints: Constraints
    blend: Blend | None = None
    problems: tuple[Problem, ...] = ()
    timings: dict[str, float] = field(default_factory=dict)

    @property
    def warnings(self) -> tuple[str, ...]:
        """The problems' messages, in order."""
        return tuple(p.message for p in self.problems)

    @property
    def vertices(self) -> NDArray[np.float64] | None:
        """The blend's mesh vertices (:attr:`Blend.vertices`), or None."""
        return None if self.blend is None else self.blend.vertices

    @property
    def faces(self) -> NDArray[np.int64] | None:
        """The blend's mesh faces (:attr:`Blend.faces`), or None."""
        return None if self.blend is None else self.blend.faces

    @property
    def constrained(self) -> NDArray[np.int64] | None:
        """The blend's constrained vertices (:attr:`Blend.constrained`), or None."""
        return None if self.blend is None else self.blend.constrained

    @property
    def prescribed(self) -> NDArray[np.float64] | None:
        """The blend's boundary conditions (:attr:`Blend.prescribed`), or None."""
        return None if self.blend is None else self.blend.prescribed

    @property
    def weights(self) -> NDArray[np.float64] | None:
        """The blend's weights (:attr:`Blend.weights`), or None."""
        return None if self.blend is None else self.blend.weights

    @property
    def raw_weights(self) -> NDArray[np.float64] | None:
        """The blend's raw weights (:attr:`Blend.raw_weights`), or None."""
        return None if self.blend is None else self.blend.raw_weights

    @property
    def fill(self) -> HarmonicFill | None:
        """The blend's fill between the handles (:attr:`Blend.fill`), or None."""
        return None if self.blend is None else self.blend.fill

    @property
    def controls(self) -> tuple[Control, ...]:
        """The controls, in the order of the weights' columns."""
        return self.constraints.controls

    @property
    def moebius(self) -> Moebius | None:
        """The single map of the warp when all controls share one map (or there are none), else None."""
        maps = [c.moebius for c in self.controls]
        if not maps:
            return Moebius.identity()
        return maps[0] if all(m.isclose(maps[0]) for m in maps[1:]) else None

    def inverse_points(self, lonlat: ArrayLike) -> NDArray[np.float64]:
        """The blended inverse map (eq. 2, with its :attr:`fill`) at arbitrary output positions.

        Parameters
        ----------
        lonlat : array_like, shape (..., 2)
            Output ``[lon, lat]`` in degrees.

        Returns
        -------
        ndarray of float64, shape (..., 2)
            The input ``[lon, lat]`` each position shows.
        """
        xyz = coords.lonlat_to_xyz(lonlat)
        if self.blend is None:
            single = self.moebius if self.moebius is not None else Moebius.identity()
            return coords.xyz_to_lonlat(single.inverse.apply_xyz(xyz))
        return self.blend.inverse_points([c.moebius.inverse for c in self.controls], xyz)

    def filled(self) -> Deformation:
        """The deformation with its :attr:`fill` made for its controls' maps as they are now (after they were changed)."""
        if self.handles.options.anchor is None or self.blend is None:
            return self
        if not harmonic.FILL:
            return replace(self, blend=replace(self.blend, fill=None))
        nodes = harmonic.node_directions().reshape(-1, 3)
        weights = self.blend.weights_at(nodes)
        blend = _blend_sum([c.moebius.inverse for c in self.controls], weights, nodes)
        fill = harmonic_fill(self.constraints, weights, blend, reach_discs(self.handles))
        return replace(self, blend=replace(self.blend, fill=fill))

    def forward_points(self, lonlat: ArrayLike, control: int, iterations: int = 8) -> NDArray[np.float64]:
        """Where input positions land in the output, by inverting the blend near a control.

        Starts from the control's own map and corrects by fixed-point steps
        ``q <- M(M⁻¹(q) + (p - T⁻¹(q)))``, which converge where the blend is close to that
        control's map (on and near its handle).

        Parameters
        ----------
        lonlat : array_like, shape (n, 2)
            Input ``[lon, lat]`` in degrees.
        control : int
            Index of the control whose map starts the search.
        iterations : int

        Returns
        -------
        ndarray of float64, shape (n, 2)
        """
        m = self.controls[control].moebius
        p = coords.lonlat_to_xyz(lonlat)
        q = m.apply_xyz(p)
        for _ in range(iterations):
            shown = coords.lonlat_to_xyz(self.inverse_points(coords.xyz_to_lonlat(q)))
            step = m.inverse.apply_xyz(q) + (p - shown)
            q = m.apply_xyz(step / np.linalg.norm(step, axis=-1, keepdims=True))
        return coords.xyz_to_lonlat(q)


@one_blas_thread
def deform(handles: Handles, *, samples: int = SAMPLES, previous: Deformation | None = None, upright: bool = False) -> Deformation:
    """The paper's method, from a handles document to the blended deformation of the sphere.

    One map for everything (no handles, one point or line, handles that do not move) needs
    no mesh: the deformation has no blend. Otherwise the controls' maps are blended by
    bounded biharmonic weights on the adaptive mesh.

    Parameters
    ----------
    handles : Handles
    samples : int
        Points per line and cage edge in the boundary conditions (the paper's 50).
    previous : Deformation, optional
        The solve of a similar document (the editor's last preview, say: a warp's
        ``Result.deformation``). When it solved the same weights problem (the same mesh and
        boundary conditions) its weights are taken as they are; when its controls are the
        same ones, its weights interpolated onto the new mesh start the solver
        (:func:`omniwidget.method.bbw.bbw`'s ``start``), which then needs fewer steps to the
        same weights.
    upright : bool
        The input is levelled: rectified lines within a degree of the vertical are made
        vertical (:func:`~omniwidget.method.constraints.build_constraints`). A document with
        ``options.up`` is solved so.

    Returns
    -------
    Deformation

    With ``options.up`` the method runs on the document levelled (:func:`levelled_handles`)
    and every control's map then starts with the levelling turn (:func:`turned`): the
    result is exactly the levelled document's after the turn of the input.
    """
    turn = handles.options.levelling()
    if turn is not None:
        before = turned(previous, turn.inverse, levelled_handles(previous.handles)) if previous is not None else None
        return turned(deform(levelled_handles(handles), samples=samples, previous=before, upright=True), turn, handles)
    timings: dict[str, float] = {}
    lap = Laps(timings)
    constraints = build_constraints(handles, samples=samples, upright=upright)
    lap("constraints")
    problems = _pole_lines(handles, constraints)
    if _one_map(handles, constraints):
        return Deformation(handles=handles, constraints=constraints, problems=tuple(problems), timings=timings)
    problems += _inside_fixed_cages(handles) + _crossing_lines(constraints)
    constraints, blend, clashes = _blended(handles, constraints, samples, previous, lap)
    d = Deformation(handles=handles, constraints=constraints, blend=blend, problems=tuple(problems + clashes), timings=timings)
    if handles.options.anchor is not None:
        d = _with_fill(d, previous)
        lap("fill")
    return d


def _one_map(handles: Handles, constraints: Constraints) -> bool:
    """Whether one map does it all: every control has the same map, and with a still background that map is the identity."""
    maps = [c.moebius for c in constraints.controls]
    single = maps[0] if maps else Moebius.identity()
    return all(m.isclose(single) for m in maps[1:]) and (handles.options.anchor is None or single.isclose(Moebius.identity()))


def _blended(
    handles: Handles, constraints: Constraints, samples: int, previous: Deformation | None, lap: Laps
) -> tuple[Constraints, Blend, list[Problem]]:
    """The adaptive mesh (Sec. 3.5), its boundary conditions and the bounded biharmonic weights (Sec. 3.2).

    Returns the constraints (with a still background, its control and the point handles'
    ladders added), the blend (without its fill) and the problems of constraints on the
    same point.
    """
    background = handles.options.anchor
    extra_samples = reach_samples(handles) if background is not None else np.empty((0, 3))
    check_mesh(len(constraints.points) + len(extra_samples), samples)
    mesh = adaptive_mesh(np.vstack([constraints.points, extra_samples]))
    sample_index = mesh.sample_index[: len(constraints.points)]
    lap("mesh")
    fixed, fixed_values, insides = np.empty(0, dtype=np.int64), np.empty((0, 0)), []
    if background is not None:
        insides = cage_insides(constraints, mesh.vertices)
        constraints, fixed, fixed_values = with_background(constraints, mesh.vertices, background, insides)
    b, bc, clashes = _merge_duplicates(sample_index, constraints.values, constraints.controls, handles)
    b, bc = _with_fixed(b, bc, fixed, fixed_values)

    raw = _previous_weights(previous, mesh.vertices, mesh.faces, b, bc)
    if raw is None:
        check_weights(len(mesh.vertices), bc.shape[1])
        raw = bbw.bbw(mesh.vertices, mesh.faces, b, bc, start=_warm_start(previous, constraints, mesh.vertices))
    weights = bbw.normalize_rows(raw)
    if background is not None:
        weights = ease_background(carry_insides(weights, insides), BACKGROUND_EASE)
        constraints, weights = with_reach(handles, constraints, mesh.vertices, weights)
    lap("weights")
    blend = Blend(vertices=mesh.vertices, faces=mesh.faces, constrained=b, prescribed=bc, weights=weights, raw_weights=raw)
    return constraints, blend, clashes


def _with_fixed(b: NDArray[np.int64], bc: NDArray[np.float64], fixed: NDArray[np.int64], values: NDArray[np.float64]) -> tuple[NDArray, NDArray]:
    """The boundary conditions with the still vertices (the background's, the points' disks) not already constrained added."""
    extra = ~np.isin(fixed, b)
    if not extra.any():
        return b, bc
    fixed, first = np.unique(fixed[extra], return_index=True)
    return np.concatenate([b, fixed]), np.vstack([bc, values[extra][first]])


def _with_fill(d: Deformation, previous: Deformation | None) -> Deformation:
    """The deformation with its fill: the previous solve's when it kept that solve's weights and maps, else made anew."""
    if previous is None or previous.blend is None or d.blend is None or not harmonic.FILL:
        return d.filled()
    if d.blend.raw_weights is not previous.blend.raw_weights or not _same_maps(previous.controls, d.controls):
        return d.filled()
    return replace(d, blend=replace(d.blend, fill=previous.blend.fill))


def levelled_handles(handles: Handles) -> Handles:
    """The document as the method sees it with ``options.up``: every input position turned by the levelling, no ``up``.

    Targets (outputs) are kept; a document without ``up`` comes back as it is.
    """
    turn = handles.options.levelling()
    if turn is None:
        return handles
    return Handles(tuple(kind_of(h).input_turned(h, turn) for h in handles.handles), replace(handles.options, up=None))


def turned(d: Deformation, turn: Moebius, handles: Handles) -> Deformation:
    """A deformation whose every control's map starts with ``turn`` (``M ∘ turn``), for ``handles``.

    The blend of eq. (2) sums the controls' inverse images as vectors, so turning them all
    turns the blend, and its fill, by ``turn⁻¹``: the deformation of a document whose input
    positions ``turn`` moved, seen from the input before the turn. The lines' input samples
    go back by ``turn⁻¹``; the weights (on the output sphere) are unchanged. Without controls
    the turn becomes the one control (the still background's place).
    """
    back = turn.inverse
    controls = tuple(replace(k, moebius=k.moebius @ turn) for k in d.controls) or (Control(turn, BACKGROUND, "the levelling turn"),)
    lines = tuple((k, back(samples)) for k, samples in d.constraints.lines)
    blend = d.blend
    if blend is not None and blend.fill is not None:
        fill = blend.fill
        shown, filled = (back.apply_xyz(v.reshape(-1, 3)).reshape(v.shape) for v in (fill.blend, fill.filled))
        blend = replace(blend, fill=replace(fill, blend=shown, filled=filled))
    return replace(d, handles=handles, constraints=replace(d.constraints, controls=controls, lines=lines), blend=blend)


def _same_maps(before: Sequence[Control], now: Sequence[Control]) -> bool:
    """Whether two lists of controls have the same maps, in order."""
    return len(before) == len(now) and all(a.moebius.isclose(b.moebius) for a, b in zip(before, now, strict=True))


def blended_points(
    inverses: Sequence[Moebius], vertices: NDArray[np.float64], faces: NDArray[np.int64], weights: NDArray[np.floating], xyz: NDArray
) -> NDArray[np.float64]:
    """The blended inverse map of eq. (2) at arbitrary output directions.

    Parameters
    ----------
    inverses : sequence of Moebius
        ``M_j⁻¹`` for the ``k`` controls.
    vertices, faces : ndarray, shapes (n, 3) and (m, 3)
        The mesh.
    weights : ndarray, shape (n, k)
        Normalised weights per vertex.
    xyz : ndarray, shape (..., 3)
        Output directions.

    Returns
    -------
    ndarray of float64, shape (..., 2)
        The input ``[lon, lat]`` (degrees) each direction shows.
    """
    xyz = np.asarray(xyz, dtype=np.float64)
    flat = xyz.reshape(-1, 3)
    face, bary = locate_points(vertices, faces, flat)
    w = interpolate(np.asarray(weights, np.float64), faces, face, bary)
    return coords.xyz_to_lonlat(_blend_sum(inverses, w, flat)).reshape(xyz.shape[:-1] + (2,))


def _blend_sum(inverses: Sequence[Moebius], weights: NDArray[np.floating], xyz: NDArray[np.float64]) -> NDArray[np.float64]:
    """``normalize(Σ_j W_j M_j⁻¹(p))`` at directions ``xyz`` (n, 3) with their weights (n, k): unit vectors (n, 3)."""
    acc = np.zeros_like(xyz)
    for j, m in enumerate(inverses):
        if np.any(weights[:, j] != 0):
            acc += weights[:, [j]] * m.apply_xyz(xyz)
    return acc / np.linalg.norm(acc, axis=-1, keepdims=True)


def _control_name(control: Control, handles: Handles) -> str:
    """How a problem names a control: its handle for a line (one name for all its pieces), else its own label."""
    if control.handle != BACKGROUND and isinstance(handles.handles[control.handle], LineHandle):
        return f"handles[{control.handle}] (line)"
    return control.label


def _merge_duplicates(
    b: NDArray[np.int64], values: NDArray[np.float64], controls: tuple[Control, ...], handles: Handles
) -> tuple[NDArray, NDArray, list[Problem]]:
    """One row per constrained vertex; conflicting prescriptions are averaged and reported."""
    order = np.argsort(b, kind="stable")
    b, values = b[order], values[order]
    unique, start = np.unique(b, return_index=True)
    merged = np.add.reduceat(values, start, axis=0) / np.diff(np.append(start, len(b)))[:, None]
    # the controls that share points (named, with their handles), and the points
    clashes: dict[tuple[tuple[str, int], ...], list[int]] = {}
    for u, s, e in zip(unique, start, np.append(start[1:], len(b)), strict=True):
        rows = values[s:e]
        if e - s > 1 and np.abs(rows - rows[0]).max() > 1e-9:
            sharing = [controls[c] for c in np.flatnonzero(np.abs(rows).sum(axis=0) > 0)]
            named = tuple(sorted({(_control_name(c, handles), c.handle) for c in sharing}))
            clashes.setdefault(named, []).append(int(u))
    return unique, merged, [_same_point(named, at) for named, at in clashes.items()]


def _same_point(named: tuple[tuple[str, int], ...], at: list[int]) -> Problem:
    """The problem of controls whose constraints fall on the same mesh vertices ``at``, each named with its handle."""
    message = (
        f"constraints of {', '.join(name for name, _ in named)} fall on the same point"
        + (f" (mesh vertex {at[0]})" if len(at) == 1 else f"s ({len(at)} mesh vertices, {at[0]} first)")
        + "; their weights were averaged"
    )
    indices = tuple(dict.fromkeys(int(h) for _, h in named if h != BACKGROUND))
    return Problem(Kind.SAME_POINT, indices, message)


def _inside_fixed_cages(handles: Handles) -> list[Problem]:
    """The problems of handles that move something inside a cage that holds its inside still (the paper's Fig. 15)."""
    found = []
    for i, cage in enumerate(handles.handles):
        if not isinstance(cage, CageHandle) or cage.finals != cage.vertices:
            continue
        for j, other in enumerate(handles.handles):
            if j == i:
                continue
            if isinstance(other, PointHandle):
                moves = other.final != other.position or other.scale != 1.0 or other.rotation != 0.0
                where = [other.position, other.final]
            elif isinstance(other, LineHandle):
                moves, where = True, [other.start, other.end]
            else:
                moves, where = other.finals != other.vertices, [*other.vertices, *other.finals]
            if moves and inside_polygon(np.asarray(where, np.float64), cage.vertices).any():
                message = (
                    f"handles[{j}] ({other.kind}) moves what handles[{i}] (cage) holds still: the cage's inside cannot stay "
                    "where it is; move the handle out of the cage, or give the cage targets"
                )
                found.append(Problem(Kind.CAGE, (j, i), message))
    return found


def _pole_lines(handles: Handles, constraints: Constraints) -> list[Problem]:
    """One problem per rectified line that passes over or close to a pole (:data:`~omniwidget.method.constraints.POLE_LATITUDE`)."""
    background = handles.options.anchor is not None
    found = []
    for i, top in constraints.near_pole:
        line = handles.handles[i]
        if not isinstance(line, LineHandle):  # build_constraints lists line handles only
            raise TypeError(f"constraints.near_pole names handles[{i}], a {line.kind} handle, not a line")
        moved = float(coords.angular_distance(coords.geodesic_midpoint(line.start, line.end), line.target_points()[1]))
        where = f"handles[{i}] (line) passes {90 - abs(top):.1f}° from the {'north' if top > 0 else 'south'} pole"
        if background:
            said = (
                f"{where}: it is kept as it is (eq. 4 would move its middle {moved:.0f}° and twist the panorama); "
                "an arc over a pole cannot be straight in the panorama, mark pieces of it that stay lower to straighten them"
            )
        else:
            said = (
                f"{where}: eq. (4) moves its middle {moved:.0f}° and twists the panorama (the paper's method, "
                '"anchor": null); give it "rectify": false, or use the still background, which keeps it as it is'
            )
        found.append(Problem(Kind.POLE_LINE, (int(i),), said))
    return found


def crossing_handles(constraints: Constraints) -> list[tuple[int, int]]:
    """Pairs of line handles whose output images cross (their maps disagree: the blend folds between them), sorted.

    Parameters
    ----------
    constraints : Constraints
        The controls and their lines' input samples (each line through its own map).

    Returns
    -------
    list of (int, int)
        Handle indices ``(a, b)``, ``a < b``: pieces of one line never count.
    """
    controls = constraints.controls
    curves = [controls[c].moebius(samples) for c, samples in constraints.lines]
    found = set()
    for a, b in crossing_pairs(curves):
        ha, hb = controls[constraints.lines[a][0]].handle, controls[constraints.lines[b][0]].handle
        if ha != hb:
            found.add((min(ha, hb), max(ha, hb)))
    return sorted(found)


def _crossing_lines(constraints: Constraints) -> list[Problem]:
    """The problems of lines whose output images cross (:func:`crossing_handles`)."""
    return [
        Problem(Kind.CROSSING, (int(a), int(b)), f"handles[{a}] (line) and handles[{b}] (line) cross each other in the output")
        for a, b in crossing_handles(constraints)
    ]


def _previous_weights(previous: Deformation | None, vertices: NDArray, faces: NDArray, b: NDArray, bc: NDArray) -> NDArray[np.float64] | None:
    """The previous solve's raw weights when it solved exactly this weights problem, else None."""
    if previous is None or previous.blend is None or not previous.blend.solves(vertices, faces, b, bc):
        return None
    return previous.blend.raw_weights


def _warm_start(previous: Deformation | None, constraints: Constraints, vertices: NDArray) -> NDArray[np.float64] | None:
    """The previous solve's raw weights interpolated at the new mesh's vertices, when its controls are the same ones."""
    if previous is None or previous.blend is None:
        return None
    before = solved(replace(_EMPTY, controls=previous.controls, values=np.zeros((0, len(previous.controls))))).controls
    if len(before) != len(constraints.controls):
        return None
    if any(p.handle != c.handle or p.label != c.label for p, c in zip(before, constraints.controls, strict=True)):
        return None
    return previous.blend.raw_weights_at(vertices)
