"""Handles to output image, keeping every stage for inspection and teaching.

Stages (Sec. 3): the controls and their boundary conditions (:mod:`.constraints`), the
adaptive mesh at the handles' final positions (:mod:`.mesh`), bounded biharmonic weights
on it (:mod:`.bbw`), the location of every output pixel on the mesh (:mod:`.locate`), the
blend of eq. (2) (:mod:`.blend`) and the resampling (:mod:`.warping`).
"""

from __future__ import annotations

import math
import re
import time
import warnings
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import coords
from .constraints import POINT_HOLD, SAMPLES, Constraints, Control, build_constraints
from .handles import CageHandle, Handles, LineHandle, PointHandle
from .moebius import Moebius
from .quality import FoldOver, Summary, fold_over, inside_polygon
from .warping import (
    PAD,
    GridInverse,
    Order,
    check_warp_arguments,
    grid_inverse,
    inverse_lonlat,
    pad_panorama,
    remap,
    remap_coordinates,
    warp_moebius,
)

__all__ = ["BACKGROUND", "BACKGROUND_EASE", "FOLD_WARNING_AREA", "BlendWarning", "Result", "ease_background", "warp"]

#: Fold-overs covering at least this share of the sphere are reported as a BlendWarning
#: (1e-5 is about 20 pixels at 2048 x 1024); smaller ones only show in ``Result.folds``.
FOLD_WARNING_AREA = 1e-5


class _measured_once:
    """A property computed when first asked and kept in the instance, like :func:`functools.cached_property`.

    Without its lock: up to Python 3.11 that lock is one per class, so one result's quality
    measured in the editor's thread made every other result's wait (a notebook with several
    editors). Two threads asking at once may both compute it; the figures are the same.
    """

    def __init__(self, fn: Any) -> None:
        self.fn, self.name, self.__doc__ = fn, fn.__name__, fn.__doc__

    def __get__(self, obj: Any, owner: type | None = None) -> Any:
        if obj is None:
            return self
        if self.name not in obj.__dict__:
            obj.__dict__[self.name] = self.fn(obj)
        return obj.__dict__[self.name]


class BlendWarning(UserWarning):
    """Handles whose constraints conflict (the paper's Fig. 15); the result is still an image."""


@dataclass(frozen=True, eq=False)
class Result:
    """Everything a warp computed.

    Attributes
    ----------
    image : ndarray, shape (H, W[, C])
        The output panorama, in the input's dtype.
    handles : Handles
        The document warped.
    constraints : Constraints
        The controls (one Möbius map each) and the prescribed weights.
    vertices, faces : ndarray or None
        The adaptive mesh, (n, 3) float64 and (m, 3) int64; None when one map does it all.
    constrained : ndarray of int64 or None
        Mesh vertices carrying boundary conditions, (b,).
    prescribed : ndarray of float64 or None
        The weights prescribed there, (b, k): the boundary conditions the solver was given
        (conflicting prescriptions on one vertex already averaged).
    weights : ndarray of float64 or None
        The blend's weights per mesh vertex and control, (n, k): the bounded biharmonic
        weights normalised, and with a still background eased (:func:`ease_background`).
    timings : dict of str to float
        Seconds per stage.
    warnings : tuple of str
        Conflicts found on the way (also issued as :class:`BlendWarning`).
    source_width : int
        Width of the input image.
    folds : FoldOver
        Where the output is turned over (:func:`omniwidget.core.quality.fold_over`): a
        mask and its share of the sphere; none for a single map.
    raw_weights : ndarray of float64 or None
        The bounded biharmonic weights before the rows were normalised, (n, k): what
        :func:`omniwidget.core.bbw.bbw` solved for, kept so that the next warp of a similar
        document can start from them (``warp(..., previous=result)``).
    """

    image: NDArray
    handles: Handles
    constraints: Constraints
    vertices: NDArray[np.float64] | None
    faces: NDArray[np.int64] | None
    constrained: NDArray[np.int64] | None
    prescribed: NDArray[np.float64] | None
    weights: NDArray[np.float64] | None
    inverse: GridInverse = field(repr=False)
    timings: dict[str, float]
    warnings: tuple[str, ...]
    source_width: int
    folds: FoldOver
    raw_weights: NDArray[np.float64] | None = field(default=None, repr=False)

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
        """The blended inverse map (eq. 2) at arbitrary output positions.

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
        if self.weights is None:
            single = self.moebius if self.moebius is not None else Moebius.identity()
            return coords.xyz_to_lonlat(single.inverse.apply_xyz(xyz))
        from .blend import blended_points

        return blended_points([c.moebius.inverse for c in self.controls], self.vertices, self.faces, self.weights, xyz)

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

    @_measured_once
    def quality(self) -> Summary:
        """Every quality figure of this warp (:func:`omniwidget.core.quality.summary`), measured when first asked.

        Straightness of each line, conformal distortion (mean and 99th percentile), fold-over,
        tear, coverage, the mean displacement of the sphere and the motion inside fixed cages;
        ``result.quality.line()`` says it in one line.
        """
        from .quality import summary

        return summary(self)

    @_measured_once
    def _inverse_map(self) -> NDArray[np.float64]:
        inverse = inverse_lonlat(self.inverse, self.image.shape[1])
        inverse.flags.writeable = False  # handed out as it is (float64): nobody may spoil the cache
        return inverse

    def inverse_map(self, dtype: type[np.floating] = np.float32) -> NDArray[np.floating]:
        """For each output pixel centre, the input ``[lon, lat]`` (degrees) it shows, (H, W, 2).

        Parameters
        ----------
        dtype : {numpy.float32, numpy.float64}
            float64 for measurements (:mod:`omniwidget.core.quality`); computed once, kept.
        """
        if dtype not in (np.float32, np.float64):
            raise ValueError(f"dtype must be numpy.float32 or numpy.float64, got {dtype!r}")
        return self._inverse_map.astype(dtype, copy=dtype is not np.float64)


#: The piece of a line a control is (", part 2 of 3"), left out where handles are named.
_PART = re.compile(r", part \d+ of \d+")


def _merge_duplicates(
    b: NDArray[np.int64], values: NDArray[np.float64], controls: tuple[Control, ...]
) -> tuple[NDArray, NDArray, list[str]]:
    """One row per constrained vertex; conflicting prescriptions are averaged and reported."""
    order = np.argsort(b, kind="stable")
    b, values = b[order], values[order]
    unique, start = np.unique(b, return_index=True)
    merged = np.add.reduceat(values, start, axis=0) / np.diff(np.append(start, len(b)))[:, None]
    clashes: dict[tuple[str, ...], list[int]] = {}  # the controls that share points, and the points
    for u, s, e in zip(unique, start, np.append(start[1:], len(b)), strict=True):
        rows = values[s:e]
        if e - s > 1 and np.abs(rows - rows[0]).max() > 1e-9:
            names = tuple(sorted({_PART.sub("", controls[c].label) for c in np.flatnonzero(np.abs(rows).sum(axis=0) > 0)}))
            clashes.setdefault(names, []).append(int(u))
    problems = [
        f"constraints of {', '.join(names)} fall on the same point"
        + (f" (mesh vertex {at[0]})" if len(at) == 1 else f"s ({len(at)} mesh vertices, {at[0]} first)")
        + "; their weights were averaged"
        for names, at in clashes.items()
    ]
    return unique, merged, problems


#: ``Control.handle`` of the still background (``Options.anchor``): the identity map.
BACKGROUND = -1
#: A control's anchor distance grows by this many times the farthest its map moves one of its own points.
ANCHOR_GROWTH = 2.0
#: Where the handles' weights sum to ``s < 1`` they get ``s ** BACKGROUND_EASE`` of it and the
#: still background the rest (:func:`ease_background`).
BACKGROUND_EASE = 3.0


def _with_background(
    constraints: Constraints, vertices: NDArray[np.float64], anchor: float, insides: list[tuple[NDArray[np.int64], NDArray[np.bool_]]]
) -> tuple[Constraints, NDArray[np.int64], NDArray[np.float64]]:
    """The constraints with the still background's control added, and the mesh vertices whose weights it fixes.

    A vertex is still (weight 1 for the background) when it lies farther than its anchor
    distance from every control's prescribed points, ``anchor`` degrees plus
    :data:`ANCHOR_GROWTH` times the largest distance the control's map moves one of them (a
    point dragged far, a line bent much, reaches farther than a cage that holds still), and
    inside no cage. A vertex within :data:`~omniwidget.core.constraints.POINT_HOLD` of a
    point handle's target has weight 1 for that point's control.

    Returns
    -------
    constraints : Constraints
    fixed : ndarray of int64, shape (f,)
        Mesh vertices.
    values : ndarray of float64, shape (f, k + 1)
        Their weights.
    """
    from scipy.spatial import cKDTree

    owner = np.argmax(constraints.values, axis=1)
    still = np.ones(len(vertices), dtype=bool)
    for c in np.unique(owner):
        points = constraints.points[owner == c]
        moved = coords.angular_distance(
            coords.xyz_to_lonlat(points), coords.xyz_to_lonlat(constraints.controls[c].moebius.inverse.apply_xyz(points))
        )
        reach = min(anchor + ANCHOR_GROWTH * float(np.max(moved)), 180.0)
        distance, _ = cKDTree(points).query(vertices, distance_upper_bound=2.0 * math.sin(math.radians(reach) / 2.0))
        still &= ~np.isfinite(distance)
    for inside, _ in insides:
        still[inside] = False
    k = len(constraints.controls) + 1
    fixed, values = [np.flatnonzero(still)], [np.tile(np.eye(k)[-1], (int(still.sum()), 1))]
    chord = 2.0 * math.sin(math.radians(POINT_HOLD) / 2.0)
    for c, centre in constraints.disks:
        held = np.flatnonzero(np.linalg.norm(vertices - centre, axis=1) <= chord * (1 + 1e-9))
        fixed.append(held)
        values.append(np.tile(np.eye(k)[c], (len(held), 1)))
    background = Control(Moebius.identity(), BACKGROUND, "the still background")
    prescribed = np.hstack([constraints.values, np.zeros((len(constraints.values), 1))])
    constraints = replace(constraints, controls=(*constraints.controls, background), values=prescribed)
    return constraints, np.concatenate(fixed), np.vstack(values)


def _cage_insides(constraints: Constraints, vertices: NDArray[np.float64]) -> list[tuple[NDArray[np.int64], NDArray[np.bool_]]]:
    """Per cage, the mesh vertices inside its output polygon and the controls that may have weight there.

    Those are the cage's own controls and any control with a prescribed point inside (a
    handle inside the cage); every other control's weight inside is set to 0 after the solve
    (:func:`_carry_insides`), so a cage carries its inside by its own maps.
    """
    lonlat = coords.xyz_to_lonlat(vertices)
    prescribed = coords.xyz_to_lonlat(constraints.points)
    out = []
    for own, polygon in constraints.cages:
        inside = np.flatnonzero(inside_polygon(lonlat, polygon))
        keep = np.zeros(len(constraints.controls) + 1, dtype=bool)  # with the background's column
        keep[list(own)] = True
        within = inside_polygon(prescribed, polygon)
        keep[: len(constraints.controls)] |= (np.abs(constraints.values[within]) > 0).any(axis=0)
        out.append((inside, keep))
    return out


def _carry_insides(weights: NDArray[np.float64], insides: list[tuple[NDArray[np.int64], NDArray[np.bool_]]]) -> NDArray[np.float64]:
    """Normalised weights with only the allowed controls inside each cage (their rows renormalised)."""
    weights = weights.copy()
    for inside, keep in insides:
        rows = weights[inside] * keep
        total = rows.sum(axis=1, keepdims=True)
        even = keep / keep.sum()
        weights[inside] = np.where(total > 1e-12, rows / np.maximum(total, 1e-300), even)
    return weights


def ease_background(weights: NDArray[np.float64], power: float = BACKGROUND_EASE) -> NDArray[np.float64]:
    """Let the handles' maps give way to the still background soon, and the background take over slowly.

    Parameters
    ----------
    weights : ndarray of float64, shape (n, k)
        Normalised weights per mesh vertex, the background's in the last column.
    power : float
        At least 1 (1 changes nothing).

    Returns
    -------
    ndarray of float64, shape (n, k)
        Rows that still sum to 1: the handles' share ``s = 1 - w_background`` becomes
        ``s ** power``, split among the handles as before; the background takes the rest.
        Where a handle's weight is 1 or 0 it stays so: every boundary condition holds.

    Notes
    -----
    Between a handle and the still region the blend's Jacobian is the identity plus about
    ``(M(p) - p) ⊗ ∇w``: its distortion is the handle's motion times the gradient of its
    weight. The motion of a Möbius map grows away from its handle (a line's fastest: it
    bends), so the weight should fall steeply close to the handle, where the map hardly
    moves the sphere, and slowly farther out. Bounded biharmonic weights fall about evenly;
    this power moves their fall towards the handle. On rooms of 6 to 10 lines it lowers the
    99th percentile of the distortion by 16-27% and the mean displacement by half
    (``bench/bench_line_maps.py``).
    """
    if power < 1:
        raise ValueError(f"power must be at least 1, got {power}")
    share = 1.0 - weights[:, -1]
    eased = np.clip(share, 0.0, 1.0) ** power
    out = weights.copy()
    out[:, :-1] *= np.divide(eased, share, out=np.zeros_like(share), where=share > 0)[:, None]
    out[:, -1] = 1.0 - eased
    return out


def _inside_fixed_cages(handles: Handles) -> list[str]:
    """Warnings for handles that move something inside a cage that holds its inside still (the paper's Fig. 15)."""
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
                found.append(
                    f"handles[{j}] ({other.kind}) moves what handles[{i}] (cage) holds still: the cage's inside cannot stay "
                    "where it is; move the handle out of the cage, or give the cage targets"
                )
    return found


def _pole_lines(handles: Handles, constraints: Constraints) -> list[str]:
    """One warning per rectified line that passes over or close to a pole (:data:`~omniwidget.core.constraints.POLE_LATITUDE`)."""
    background = handles.options.anchor is not None
    found = []
    for i, top in constraints.near_pole:
        line = handles.handles[i]
        moved = float(coords.angular_distance(coords.geodesic_midpoint(line.start, line.end), line.target_points()[1]))
        where = f"handles[{i}] (line) passes {90 - abs(top):.1f}° from the {'north' if top > 0 else 'south'} pole"
        if background:
            found.append(
                f"{where}: it is kept as it is (eq. 4 would move its middle {moved:.0f}° and twist the panorama); "
                "an arc over a pole cannot be straight in the panorama, mark pieces of it that stay lower to straighten them"
            )
        else:
            found.append(
                f"{where}: eq. (4) moves its middle {moved:.0f}° and twists the panorama (the paper's method, "
                '"anchor": null); give it "rectify": false, or use the still background, which keeps it as it is'
            )
    return found


def _crossing_lines(constraints: Constraints) -> list[str]:
    """Warnings for lines whose output images cross (their maps disagree: the blend folds between them)."""
    from .rectify import crossing_pairs

    controls = constraints.controls
    curves = [controls[c].moebius(samples) for c, samples in constraints.lines]
    found = []
    for a, b in crossing_pairs(curves):
        ha, hb = controls[constraints.lines[a][0]].handle, controls[constraints.lines[b][0]].handle
        if ha != hb:
            found.append(f"handles[{ha}] (line) and handles[{hb}] (line) cross each other in the output")
    return sorted(set(found))


def _fold_warning(handles: Handles, controls: tuple[Control, ...], pixel_weights: NDArray, area: float) -> str:
    """Name the handles whose weights are strong where the output folds, (pixels, k) weights."""
    strong = np.flatnonzero(pixel_weights.max(axis=0) >= 0.1)
    involved = sorted({controls[j].handle for j in strong} - {BACKGROUND})
    names = [f"handles[{i}] ({handles.handles[i].kind})" for i in involved]
    return (
        f"the warp folds over near {' and '.join(names)}: {100 * area:.3g}% of the sphere is shown turned over "
        "(Result.folds.mask shows where); their targets conflict, move them apart"
    )


def _previous_weights(previous: Result | None, vertices: NDArray, faces: NDArray, b: NDArray, bc: NDArray) -> NDArray[np.float64] | None:
    """The previous warp's raw weights when it solved exactly this weights problem, else None."""
    if previous is None or previous.raw_weights is None:
        return None
    same = (
        np.array_equal(previous.vertices, vertices)
        and np.array_equal(previous.faces, faces)
        and np.array_equal(previous.constrained, b)
        and np.array_equal(previous.prescribed, bc)
    )
    return previous.raw_weights if same else None


def _warm_start(previous: Result | None, constraints: Constraints, vertices: NDArray) -> NDArray[np.float64] | None:
    """The previous warp's raw weights interpolated at the new mesh's vertices, when its controls are the same ones."""
    if previous is None or previous.raw_weights is None or len(previous.controls) != len(constraints.controls):
        return None
    if any(p.handle != c.handle or p.label != c.label for p, c in zip(previous.controls, constraints.controls, strict=True)):
        return None
    from scipy.spatial import cKDTree

    from .locate import interpolate, locate_points

    # most vertices of the new mesh are vertices of the old one (the same icosphere, refined alike far from what moved)
    distance, nearest = cKDTree(previous.vertices).query(vertices)
    out = previous.raw_weights[nearest]
    moved = np.flatnonzero(distance > 1e-12)
    if len(moved):
        face, bary = locate_points(previous.vertices, previous.faces, vertices[moved])
        out[moved] = interpolate(previous.raw_weights, previous.faces, face, bary)
    return out


def _exact_inverse(
    inverses: list[Moebius], vertices: NDArray[np.float64], faces: NDArray[np.int64], weights: NDArray[np.float64], width: int
) -> GridInverse:
    """The blended map at every pixel of the output grid, in double precision, located on the mesh when first asked."""
    import threading

    from .blend import blended_inverse, mesh_pixel_weights
    from .locate import locate_grid

    lock = threading.Lock()
    cache: list[GridInverse] = []

    def fn(lon: NDArray, lat: NDArray, rows: slice) -> tuple[NDArray, NDArray]:
        with lock:
            if not cache:
                face, bary = locate_grid(vertices, faces, width)
                cache.append(blended_inverse(inverses, mesh_pixel_weights(faces, weights, face, bary, np.float64), precision="double"))
        return cache[0](lon, lat, rows)

    return fn


def warp(
    image: NDArray,
    handles: Handles,
    *,
    width: int | None = None,
    order: Order = "bilinear",
    samples: int = SAMPLES,
    warn: bool = True,
    exact: bool = False,
    previous: Result | None = None,
) -> Result:
    """Warp a panorama by any number of handles (the paper's method).

    One map for everything (no handles, one point or line, handles that do not move) is
    applied exactly, without a mesh; otherwise the controls' maps are blended by bounded
    biharmonic weights.

    Parameters
    ----------
    image : ndarray, shape (H, W[, C])
        Equirectangular, ``W = 2 H``; uint8, uint16, float32 or float64; 1 to 4 channels.
    handles : Handles
    width : int, optional
        Output width (even); default: the input's.
    order : {"nearest", "bilinear", "bicubic"}
    samples : int
        Points per line and cage edge in the boundary conditions (the paper's 50).
    warn : bool
        Issue conflicts as :class:`BlendWarning`; they are in ``Result.warnings`` either way
        (the command line and the editor show them themselves).
    exact : bool
        Evaluate the blend at every output pixel. By default, with the compiled kernels and
        an output at least :data:`omniwidget.core.sampled.SAMPLE_FROM` wide, it is evaluated
        on a coarser grid and interpolated where that is within a quarter of a pixel, and
        exactly near the handles (:mod:`omniwidget.core.sampled`). ``Result.inverse_map()``
        and so every quality figure use the exact map either way.
    previous : Result, optional
        The warp of a similar document (the editor's last preview, say). When it solved the
        same weights problem (the same mesh and boundary conditions: the same handles, at
        any output size) its weights are taken as they are; when its controls are the same
        ones, its weights interpolated onto the new mesh start the solver
        (:func:`omniwidget.core.bbw.bbw`'s ``start``), which then needs fewer steps to the
        same weights.

    Returns
    -------
    Result
    """
    if not isinstance(handles, Handles):
        raise TypeError(f"handles must be a Handles document (see Handles.from_dict), got {type(handles).__name__}")
    if previous is not None and not isinstance(previous, Result):
        raise TypeError(f"previous must be a Result of an earlier warp, got {type(previous).__name__}")
    width = check_warp_arguments(image, width, order)
    timings: dict[str, float] = {}
    clock = time.perf_counter()

    def lap(name: str) -> None:
        nonlocal clock
        now = time.perf_counter()
        timings[name] = now - clock
        clock = now

    constraints = build_constraints(handles, samples=samples)
    lap("constraints")
    problems_before = _pole_lines(handles, constraints)
    maps = [c.moebius for c in constraints.controls]
    single = maps[0] if maps else Moebius.identity()
    # one map for everything; with a still background only if that map is the identity
    if all(m.isclose(single) for m in maps[1:]) and (handles.options.anchor is None or single.isclose(Moebius.identity())):
        out = warp_moebius(image, single, width=width, order=order).image
        inverse = grid_inverse(single.inverse)
        lap("resampling")
        no_folds = FoldOver(np.zeros(out.shape[:2], dtype=bool), 0.0)  # a Möbius map is one-to-one
        for p in problems_before if warn else ():
            warnings.warn(p, BlendWarning, stacklevel=2)
        return Result(
            out, handles, constraints, None, None, None, None, None, inverse, timings, tuple(problems_before), image.shape[1], no_folds
        )

    from . import _kernels
    from .bbw import bbw, normalize_rows
    from .blend import blended_inverse, mesh_pixel_weights
    from .locate import interpolate, locate_grid
    from .mesh import adaptive_mesh
    from .sampled import coarse_step, sampled_coordinates

    problems_before += _inside_fixed_cages(handles) + _crossing_lines(constraints)
    mesh = adaptive_mesh(constraints.points)
    lap("mesh")
    fixed, fixed_values, insides = np.empty(0, dtype=np.int64), None, []
    if handles.options.anchor is not None:
        insides = _cage_insides(constraints, mesh.vertices)
        constraints, fixed, fixed_values = _with_background(constraints, mesh.vertices, handles.options.anchor, insides)
        maps.append(Moebius.identity())
    b, bc, problems = _merge_duplicates(mesh.sample_index, constraints.values, constraints.controls)
    extra = ~np.isin(fixed, b)
    if extra.any():  # the background's still vertices and the points' disks
        fixed, first = np.unique(fixed[extra], return_index=True)
        b = np.concatenate([b, fixed])
        bc = np.vstack([bc, fixed_values[extra][first]])
    problems = problems_before + problems
    raw = _previous_weights(previous, mesh.vertices, mesh.faces, b, bc)
    if raw is None:
        raw = bbw(mesh.vertices, mesh.faces, b, bc, start=_warm_start(previous, constraints, mesh.vertices))
    weights = normalize_rows(raw)
    if handles.options.anchor is not None:
        weights = ease_background(_carry_insides(weights, insides), BACKGROUND_EASE)
    lap("weights")
    inverses = [m.inverse for m in maps]
    if _kernels.available():
        step = 1 if exact else coarse_step(width)
        if step > 1:
            coordinates, face, planes = sampled_coordinates(
                inverses, mesh.vertices, mesh.faces, weights, width, image.shape[1], step, constraints.points
            )
        else:
            coordinates, face, planes = _kernels.walk_blend(mesh.vertices, mesh.faces, weights, inverses, width, image.shape[1])
        inverse = _exact_inverse(inverses, mesh.vertices, mesh.faces, weights, width)  # located again when first asked
        lap("blend")
        out = remap(pad_panorama(image), coordinates, order)
        lap("resampling")
        folds = FoldOver.from_mask(_kernels.fold_mask(coordinates, image.shape[1]))
        if folds.area >= FOLD_WARNING_AREA:
            where = folds.mask if step == 1 else folds.mask.reshape(face.shape[0], step, face.shape[1], step).any(axis=(1, 3))
            strongest = _kernels.strongest_weights(where, face, planes, mesh.faces, weights)
            problems.append(_fold_warning(handles, constraints.controls, strongest[None], folds.area))
    else:
        face, bary = locate_grid(mesh.vertices, mesh.faces, width)
        lap("locate")
        coordinates = remap_coordinates(
            blended_inverse(inverses, mesh_pixel_weights(mesh.faces, weights, face, bary)), width, image.shape[1]
        )
        inverse = blended_inverse(inverses, mesh_pixel_weights(mesh.faces, weights, face, bary, np.float64), precision="double")
        lap("blend")
        out = remap(pad_panorama(image), coordinates, order)
        lap("resampling")
        pixel = np.float32(360.0 / image.shape[1])  # back to [lon, lat], in float32 (enough for the signs)
        folds = fold_over(
            (coordinates - np.float32(PAD - 0.5)) * (pixel * np.array([1, -1], np.float32)) + np.array([-180, 90], np.float32)
        )
        if folds.area >= FOLD_WARNING_AREA:
            at = interpolate(weights, mesh.faces, face[folds.mask], bary[folds.mask])
            problems.append(_fold_warning(handles, constraints.controls, at, folds.area))
    lap("fold check")
    for p in problems if warn else ():
        warnings.warn(p, BlendWarning, stacklevel=2)
    return Result(
        out, handles, constraints, mesh.vertices, mesh.faces, b, bc, weights, inverse, timings, tuple(problems), image.shape[1], folds, raw
    )
