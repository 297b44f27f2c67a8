"""From an image and a handles document to the output image: the method's deformation applied to every pixel.

:func:`warp` asks the method for the deformation (:func:`omniwidget.method.deformation.deform`),
evaluates its blend of eq. (2) at every output pixel (:func:`blend_coordinates`: the compiled
kernels when they are there, numpy otherwise, chosen here only), resamples the input there
(:mod:`.warping`) and checks for fold-overs (:mod:`.fold`). A :class:`Result` keeps every
stage for inspection and teaching.
"""

from __future__ import annotations

import math
import threading
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._blas import one_blas_thread
from .._checks import whole_number
from .._lazy import lazy
from .._timing import Laps
from ..document.handles import Handles
from ..method.background import BACKGROUND
from ..method.constraints import POINT_HOLD, SAMPLES, Constraints, Control
from ..method.deformation import Blend, Deformation, deform
from ..method.harmonic import HarmonicFill
from ..method.locate import interpolate, locate_grid
from ..method.problems import Kind, Problem
from ..sphere import coords
from ..sphere.arcs import inside_polygon
from ..sphere.moebius import Moebius
from . import _kernels
from .blend import blended_inverse, mesh_blended_inverse, mesh_pixel_weights
from .filling import fill_coordinates, filled_inverse
from .fold import FoldOver, fold_of_coordinates
from .sampled import coarse_step, sampled_coordinates
from .untangle import Patch, apply_patches, line_mask, line_pixels, patched_inverse, untangle
from .warping import (
    GridInverse,
    Order,
    check_warp_arguments,
    coordinates_lonlat,
    grid_inverse,
    inverse_lonlat,
    remap_coordinates,
    remap_panorama,
    warp_moebius,
)

if TYPE_CHECKING:
    from scipy import ndimage

    from ..evaluate import quality as evaluate_quality
    from ..evaluate.quality import Summary
else:
    ndimage = lazy("scipy.ndimage")
    evaluate_quality = lazy("omniwidget.evaluate.quality")  # above the engine: loaded when a warp is first measured

__all__ = [
    "FOLD_WARNING_AREA",
    "BlendWarning",
    "CageWarning",
    "CrossingWarning",
    "FoldWarning",
    "GiveWayWarning",
    "PoleLineWarning",
    "Result",
    "SamePointWarning",
    "blend_coordinates",
    "warp",
]

#: Fold-overs covering at least this share of the sphere are reported as a BlendWarning
#: (1e-5 is about 20 pixels at 2048 x 1024); smaller ones only show in ``Result.folds``.
FOLD_WARNING_AREA = 1e-5
#: The shares of their maps that :func:`_give_way` tries for the handles where the blend still folds, in turn.
GIVE_WAY = (0.75, 0.5, 0.25, 0.0)
#: A blend that turns more than this share of the sphere over, or in more than :data:`UNTANGLE_PATCHES` patches, is not
#: untangled in windows (so many windows, as on photos with dozens of crossing suggestions, are slow): its handles give way first.
UNTANGLE_AREA = 0.01
UNTANGLE_PATCHES = 24
#: Rounds of untangling in the default mode (:func:`_untangled`).
UNTANGLE_ROUNDS = 3


class _measured_once:
    """A property computed when first asked and kept in the instance, like :func:`functools.cached_property`.

    Without its lock: up to Python 3.11 that lock is one per class, so one result's quality
    measured in the editor's thread would make every other result's wait (a notebook with
    several editors). Two threads asking at once may both compute it; the figures are the same.
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
    """Handles whose constraints conflict (the paper's Fig. 15); the result is still an image.

    Each problem of :attr:`Result.problems` (:class:`~omniwidget.method.problems.Problem`)
    has the ``kind`` of one of the subclasses below (:attr:`Result.warning_kinds` lists
    them, which the editor groups the warnings by); ``warp(..., warn=True)`` issues its
    message as that class.
    """

    #: What the warnings of this class are about, a short phrase (the editor's group title).
    kind = "conflicts"


class PoleLineWarning(BlendWarning):
    """A rectified line over or close to a pole: kept as it is (the still background), or twisting the panorama."""

    kind = Kind.POLE_LINE


class CageWarning(BlendWarning):
    """A handle moving what a cage that holds its inside still holds."""

    kind = Kind.CAGE


class CrossingWarning(BlendWarning):
    """Two lines whose output images cross each other."""

    kind = Kind.CROSSING


class SamePointWarning(BlendWarning):
    """Constraints of several handles on one mesh vertex, their weights averaged."""

    kind = Kind.SAME_POINT


class GiveWayWarning(BlendWarning):
    """Handles whose maps give way where the blend folded (their lines not straight there)."""

    kind = Kind.GIVE_WAY


class FoldWarning(BlendWarning):
    """Where the blend folded over: untangled, or still shown turned over."""

    kind = Kind.FOLD


#: The warning class of each kind of problem (:data:`omniwidget.method.problems.KINDS`).
_CATEGORIES: dict[str, type[BlendWarning]] = {
    c.kind: c for c in (PoleLineWarning, CageWarning, CrossingWarning, SamePointWarning, GiveWayWarning, FoldWarning)
}


@dataclass(frozen=True, eq=False)
class Result:
    """Everything a warp computed: the method's :class:`~omniwidget.method.deformation.Deformation` and the image.

    The deformation's attributes and methods read here too, each delegated to it
    (``handles``, ``constraints``, ``controls``, ``moebius``, the ``blend`` and its parts
    ``vertices``, ``faces``, ``constrained``, ``prescribed``, ``weights``, ``raw_weights``
    and ``fill``, ``inverse_points``, ``forward_points``); ``problems``, ``warnings`` and
    ``timings`` are the deformation's and the warp's.

    Attributes
    ----------
    deformation : Deformation
        What the method computed; where handles gave way, with their maps relaxed.
    image : ndarray, shape (H, W[, C])
        The output panorama, in the input's dtype.
    inverse : GridInverse
        The blended inverse map on the output grid, in double precision (what
        :meth:`inverse_map` evaluates).
    source_width : int
        Width of the input image.
    folds : FoldOver
        Where the output is turned over (:func:`omniwidget.raster.fold.fold_over`): a
        mask and its share of the sphere; none for a single map.
    coordinates : ndarray of float32, shape (H, W, 2), or None
        The source pixel coordinates the output was resampled by (the blend, evaluated on a
        coarse grid where that is exact enough); None for a single map, which is resampled
        exactly. :meth:`placed_map` turns them into ``[lon, lat]``.
    problems : tuple of Problem
        The deformation's problems, then the warp's (handles giving way, fold-overs).
    timings : dict of str to float
        Seconds per stage, the deformation's steps and the warp's.
    """

    deformation: Deformation
    image: NDArray
    inverse: GridInverse = field(repr=False)
    source_width: int
    folds: FoldOver
    coordinates: NDArray[np.float32] | None = field(default=None, repr=False)
    problems: tuple[Problem, ...] = ()
    timings: dict[str, float] = field(default_factory=dict)

    # --- the deformation's, delegated ---
    @property
    def handles(self) -> Handles:
        """The document (:attr:`Deformation.handles`)."""
        return self.deformation.handles

    @property
    def constraints(self) -> Constraints:
        """The controls and the prescribed weights (:attr:`Deformation.constraints`)."""
        return self.deformation.constraints

    @property
    def controls(self) -> tuple[Control, ...]:
        """The controls, in the order of the weights' columns (:attr:`Deformation.controls`)."""
        return self.deformation.controls

    @property
    def moebius(self) -> Moebius | None:
        """The single map when all controls share one, else None (:attr:`Deformation.moebius`)."""
        return self.deformation.moebius

    @property
    def blend(self) -> Blend | None:
        """The weights on the adaptive mesh and the fill (:class:`~omniwidget.method.deformation.Blend`); None for a single map."""
        return self.deformation.blend

    @property
    def vertices(self) -> NDArray[np.float64] | None:
        """The adaptive mesh's vertices, (n, 3), or None (:attr:`Blend.vertices`)."""
        return self.deformation.vertices

    @property
    def faces(self) -> NDArray[np.int64] | None:
        """The adaptive mesh's faces, (m, 3), or None (:attr:`Blend.faces`)."""
        return self.deformation.faces

    @property
    def constrained(self) -> NDArray[np.int64] | None:
        """Mesh vertices carrying boundary conditions, (b,), or None (:attr:`Blend.constrained`)."""
        return self.deformation.constrained

    @property
    def prescribed(self) -> NDArray[np.float64] | None:
        """The weights prescribed there, (b, k), or None (:attr:`Blend.prescribed`)."""
        return self.deformation.prescribed

    @property
    def weights(self) -> NDArray[np.float64] | None:
        """The blend's weights per mesh vertex and control, (n, k), or None (:attr:`Blend.weights`)."""
        return self.deformation.weights

    @property
    def raw_weights(self) -> NDArray[np.float64] | None:
        """The bounded biharmonic weights before normalising, or None (:attr:`Blend.raw_weights`)."""
        return self.deformation.raw_weights

    @property
    def fill(self) -> HarmonicFill | None:
        """The map filled in between the handles, or None (:attr:`Blend.fill`)."""
        return self.deformation.fill

    def inverse_points(self, lonlat: ArrayLike) -> NDArray[np.float64]:
        """The input ``[lon, lat]`` (degrees, (..., 2)) that output positions ``lonlat`` (..., 2) show (:meth:`Deformation.inverse_points`)."""
        return self.deformation.inverse_points(lonlat)

    def forward_points(self, lonlat: ArrayLike, control: int, iterations: int = 8) -> NDArray[np.float64]:
        """Where input positions land in the output, searched from a control's map (:meth:`Deformation.forward_points`)."""
        return self.deformation.forward_points(lonlat, control, iterations)

    # --- the problems, read from the records ---
    @property
    def warnings(self) -> tuple[str, ...]:
        """The problems' messages, in order."""
        return tuple(p.message for p in self.problems)

    @property
    def warning_kinds(self) -> tuple[str, ...]:
        """One per entry of ``warnings``: its problem's ``kind``, that of its :class:`BlendWarning` subclass.

        ("lines crossing in the output", "constraints on the same point", ...): what the
        editor groups them by.
        """
        return tuple(p.kind for p in self.problems)

    @property
    def gave_way(self) -> tuple[int, ...]:
        """Indices of the handles that gave way where the blend folded beyond untangling, ascending.

        Their maps relaxed, or their lines running through an untangled window: the handles
        of the problems of kind :attr:`~omniwidget.method.problems.Kind.GIVE_WAY`; their
        lines are not straight there.
        """
        return tuple(sorted({h for p in self.problems if p.kind == Kind.GIVE_WAY for h in p.handles}))

    def placed_map(self) -> NDArray[np.float64]:
        """The inverse map that placed the output's pixels, ``[lon, lat]`` in degrees, (H, W, 2) float64.

        What the resampler used (:attr:`coordinates`), which the quality figures of lines
        measure through; :meth:`inverse_map` is the blend evaluated exactly at every pixel
        (the two agree within a quarter of a pixel, :mod:`omniwidget.raster.sampled`).
        """
        if self.coordinates is None:
            return self._inverse_map  # float64 already (read-only)
        return coordinates_lonlat(self.coordinates, self.source_width)

    @_measured_once
    def quality(self) -> Summary:
        """Every quality figure of this warp (:func:`omniwidget.evaluate.quality.summary`), measured when first asked.

        Straightness of each line, conformal distortion (mean and 99th percentile), fold-over,
        tear, coverage, the mean displacement of the sphere and the motion inside fixed cages;
        ``result.quality.line()`` says it in one line.
        """
        return evaluate_quality.summary(self)

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
            float64 for measurements (:mod:`omniwidget.evaluate.quality`); computed once, kept.
        """
        if dtype not in (np.float32, np.float64):
            raise ValueError(f"dtype must be numpy.float32 or numpy.float64, got {dtype!r}")
        return self._inverse_map.astype(dtype, copy=dtype is not np.float64)

    def skimage_inverse_map(self, channels: int | None = None) -> NDArray[np.float64]:
        """The inverse map as ``skimage.transform.warp(image, inverse_map)`` takes it: input pixel coordinates per output pixel.

        ``skimage.transform.warp(image, result.skimage_inverse_map(3), order=1, mode="wrap",
        preserve_range=True)`` gives this warp's image (an RGB ``image``) within one grey
        level, away from the seam and the poles: scikit-image wraps rows as it wraps
        columns, where this toolkit continues over the poles.

        Parameters
        ----------
        channels : int, optional
            The input's channels ``C`` for a colour image; None for a grey one.

        Returns
        -------
        ndarray of float64, shape (2, H, W), or (3, H, W, C) with ``channels``
            The ``(row, col)`` in the input (pixel centres at whole numbers) each output
            pixel shows, and for a colour image the channel index too.
        """
        xy = coords.lonlat_to_px(self.inverse_map(np.float64), self.source_width)
        if channels is None:
            return np.stack([xy[..., 1], xy[..., 0]])
        c = whole_number(channels, "channels", 1)
        out = np.empty((3, *xy.shape[:2], c))
        out[0], out[1], out[2] = xy[..., 1, None], xy[..., 0, None], np.arange(c)
        return out


def _exact_inverse(inverses: list[Moebius], blend: Blend, width: int) -> GridInverse:
    """The blended map (without the fill) at every pixel of the output grid, in double precision, located on the mesh when first asked."""
    lock = threading.Lock()
    cache: list[GridInverse] = []

    def fn(lon: NDArray, lat: NDArray, rows: slice) -> tuple[NDArray, NDArray]:
        with lock:
            if not cache:
                face, bary = locate_grid(blend.vertices, blend.faces, width)
                cache.append(mesh_blended_inverse(inverses, blend.faces, blend.weights, face, bary))
        return cache[0](lon, lat, rows)

    return fn


def _blend_of(d: Deformation | Result) -> Blend:
    """The deformation's blend; a clear error for one that a single map does all of."""
    if d.blend is None:
        raise ValueError("the deformation has no weights: one Möbius map does it all (warp_moebius)")
    return d.blend


def blend_coordinates(
    deformation: Deformation | Result, width: int, src_width: int, *, exact: bool = False, timings: dict[str, float] | None = None
) -> tuple[NDArray[np.float32], FoldOver, NDArray[np.floating] | None]:
    """The deformation's inverse map on a ``width`` wide output grid, as source pixel coordinates for resampling.

    The one place the per-pixel backend is chosen: the compiled kernels
    (:mod:`._kernels`, evaluated on a coarse grid where that is exact enough,
    :mod:`.sampled`) when they are there, else numpy (:mod:`.blend`). Both evaluate eq. (2)
    as :meth:`Deformation.inverse_points` does.

    Parameters
    ----------
    deformation : Deformation or Result
        With a blend (not a single map).
    width, src_width : int
        Output and source widths.
    exact : bool
        Evaluate the blend at every output pixel, never on the coarse grid.
    timings : dict, optional
        Seconds per stage are added here: ``"locate"`` (numpy only: the compiled kernels
        find each pixel's face as they blend), ``"blend"``, ``"fill pixels"`` (the default mode's fill, :mod:`.filling`), ``"fold check"``.

    Returns
    -------
    coordinates : ndarray of float32, shape (width / 2, width, 2)
        ``(x, y)`` in the source padded by :data:`~omniwidget.raster.warping.PAD`.
    folds : FoldOver
    at_folds : ndarray of float64, shape (f, k), or None
        The controls' weights where the output folds (with the compiled kernels, one row:
        each control's strongest weight there), for naming the handles in a warning; None
        when it folds less than :data:`FOLD_WARNING_AREA`.
    """
    blend = _blend_of(deformation)
    vertices, faces, weights = blend.vertices, blend.faces, blend.weights
    laps = Laps(timings)
    inverses = [c.moebius.inverse for c in deformation.controls]
    compiled = _kernels.available()
    if compiled:
        step = 1 if exact else coarse_step(width)
        if step > 1:
            coordinates, face, planes = sampled_coordinates(
                inverses, vertices, faces, weights, width, src_width, step, deformation.constraints.points
            )
        else:
            coordinates, face, planes = _kernels.walk_blend(vertices, faces, weights, inverses, width, src_width)
    else:
        face, bary = locate_grid(vertices, faces, width)
        laps("locate")
        coordinates = remap_coordinates(blended_inverse(inverses, mesh_pixel_weights(faces, weights, face, bary)), width, src_width)
    laps("blend")
    if blend.fill is not None:
        fill_coordinates(coordinates, blend.fill, src_width)
        laps("fill pixels")
    folds = fold_of_coordinates(coordinates, src_width)
    at_folds: NDArray[np.floating] | None = None
    if folds.area > 0 and compiled:
        where = folds.mask if step == 1 else np.asarray(folds.mask.reshape(face.shape[0], step, face.shape[1], step).any(axis=(1, 3)))
        at_folds = _kernels.strongest_weights(where, face, planes, faces, weights)[None]
    elif folds.area > 0:
        at_folds = interpolate(weights, faces, face[folds.mask], bary[folds.mask])
    laps("fold check")
    return coordinates, folds, at_folds


def _fold_warning(
    handles: Handles, controls: tuple[Control, ...], pixel_weights: NDArray, area: float, patches: Sequence[Patch] = (), width: int = 0
) -> Problem:
    """The fold-over's problem: the handles whose weights are strong where the blend folded, (pixels, k) weights, and what became of it."""
    strong = np.flatnonzero(pixel_weights.max(axis=0) >= 0.1)
    involved = sorted({controls[j].handle for j in strong} - {BACKGROUND})
    names = " and ".join(f"handles[{i}] ({handles.handles[i].kind})" for i in involved) or "the still background"
    if patches and area == 0:
        moved = max(p.moved for p in patches)
        said = (
            f"the blend folded over near {names}; untangled in {len(patches)} window{'s' * (len(patches) > 1)}, where "
            f"their maps give way by up to {moved * width / 360:.2g} px ({moved:.2g}°): the warp is one-to-one"
        )
    else:
        said = (
            f"the warp folds over near {names}: {100 * area:.3g}% of the sphere is shown turned over "
            "(Result.folds.mask shows where); their targets conflict, move them apart"
        )
    return Problem(Kind.FOLD, tuple(int(i) for i in involved), said)


def _line_pixels(d: Deformation, width: int) -> list[tuple[int, NDArray[np.int64]]]:
    """Each marked line piece's handle and output pixels, placed by the piece's own map (the blend's there)."""
    out = []
    for c, samples in d.constraints.lines:
        arc = float(coords.angular_distance(samples[0], samples[-1]))
        dense = coords.geodesic(samples[0], samples[-1], np.linspace(0.0, 1.0, max(2, math.ceil(4 * arc * width / 360))))
        out.append((d.controls[c].handle, line_pixels(d.controls[c].moebius(dense), width)))
    return out


def _lines_given_way(handles: Handles, lines: list[tuple[int, NDArray[np.int64]]], patches: Sequence[Patch]) -> list[Problem]:
    """A problem per line that runs through a window untangled without keeping it (:attr:`Patch.keeps_lines`)."""
    given = sorted({h for p in patches if not p.keeps_lines for h, px in lines if p.covers(px).any()})
    return [
        Problem(
            Kind.GIVE_WAY,
            (int(h),),
            f"handles[{h}] ({handles.handles[h].kind}) gives way where the blend folded on it: it is not straight there "
            "(Result.quality.relaxed says how far)",
        )
        for h in given
    ]


def _kept(d: Deformation, width: int) -> tuple[list[tuple[int, NDArray[np.int64]]], NDArray[np.bool_]]:
    """The lines' pixels (:func:`_line_pixels`) and every pixel the untangling should keep as the blend has it."""
    lines = _line_pixels(d, width)
    return lines, line_mask([px for _, px in lines], width) | _held_pixels(d, width)


def _held_pixels(d: Deformation, width: int) -> NDArray[np.bool_]:
    """The output pixels inside every cage and on every point's disk, which the untangling keeps as the blend has them."""
    mask = np.zeros((width // 2, width), bool)
    lon, lat = coords.grid_lonlat(width)
    for _, polygon in d.constraints.cages:
        edges = np.concatenate([coords.geodesic(a, b, np.linspace(0, 1, 33)) for a, b in zip(polygon, np.roll(polygon, -1, axis=0), strict=True)])
        rows = np.flatnonzero((lat >= edges[:, 1].min() - 1) & (lat <= edges[:, 1].max() + 1))
        cols = np.arange(width)
        if np.abs(edges[:, 1]).max() < 80:  # the cage's longitudes only (all of them round a pole)
            middle = float(edges[0, 0])
            span = float(np.abs((edges[:, 0] - middle + 180) % 360 - 180).max()) + 1
            cols = np.flatnonzero(np.abs((lon - middle + 180) % 360 - 180) <= span)
        grid = np.stack(np.meshgrid(lon[cols], lat[rows]), axis=-1)
        mask[np.ix_(rows, cols)] |= inside_polygon(grid, polygon)
    for _, centre in d.constraints.disks:
        c_lon, c_lat = coords.xyz_to_lonlat(centre)
        rows = np.flatnonzero(np.abs(lat - c_lat) <= POINT_HOLD + 1)
        grid = np.stack(np.meshgrid(lon, lat[rows]), axis=-1)
        mask[rows] |= coords.angular_distance(grid, (c_lon, c_lat)) <= POINT_HOLD
    return mask


@dataclass(frozen=True, eq=False)
class _Placed:
    """Where the output's pixels come from at one stage of the warp.

    Attributes
    ----------
    deformation : Deformation
        With a blend; where handles gave way, with their maps relaxed.
    coordinates : ndarray of float32, shape (H, W, 2)
        Source pixel coordinates (:func:`blend_coordinates`), with the untangled windows written in.
    folds : FoldOver
        Their fold check.
    patches : tuple of Patch
        The windows untangled, in the order they were written.
    """

    deformation: Deformation
    coordinates: NDArray[np.float32]
    folds: FoldOver
    patches: tuple[Patch, ...] = ()


def _unfolded(placed: _Placed, width: int, src_width: int, exact: bool) -> tuple[_Placed, list[Problem]]:
    """Every fold untangled in windows (:func:`_untangled`), and where no window clears it the handles there given way.

    Returns the pixels' places and the problems of the handles that gave way (:func:`_give_way`)
    and of the lines through a window that does not keep them (:func:`_lines_given_way`).
    """
    d = placed.deformation
    lines, keep = _kept(d, width)
    coordinates, folds, patches = _untangled(placed.coordinates, placed.folds, src_width, keep)
    placed = _Placed(d, coordinates, folds, tuple(patches))
    problems: list[Problem] = []
    if folds.area > 0 and GIVE_WAY:  # folds no window clears: the handles there give way as little as clears them
        placed, given = _give_way(d, folds, width, src_width, exact)
        problems.append(given)
        lines = _line_pixels(placed.deformation, width)
    return placed, problems + _lines_given_way(d.handles, lines, placed.patches)


def _give_way(d: Deformation, folds: FoldOver, width: int, src_width: int, exact: bool) -> tuple[_Placed, Problem]:
    """The deformation with the maps of the handles where it still folds relaxed toward the background's, as little as clears it.

    The controls whose weight is at least 0.1 at a turned-over pixel are relaxed together:
    each map ``M`` becomes ``M^t`` (:meth:`~omniwidget.sphere.moebius.Moebius.power`; with
    ``options.up``, ``(M L⁻¹)^t L`` for the levelling ``L``), and
    the first ``t`` of :data:`GIVE_WAY` whose blend, untangled, turns nothing over is kept; at
    ``t = 0`` those maps are the still background's and the blend is the background's there; if
    it still folds then, every handle gives way (the identity folds nothing).
    Returns the relaxed deformation's pixels, untangled, and the problem that says who gave
    way and how far.
    """
    lon, lat = coords.grid_lonlat(width)
    rows, cols = np.nonzero(folds.mask)
    strong = _blend_of(d).weights_at(coords.lonlat_to_xyz(np.stack([lon[cols], lat[rows]], axis=-1))).max(axis=0) >= 0.1
    involved = {int(j) for j in np.flatnonzero(strong) if d.controls[j].handle != BACKGROUND}

    turn = d.handles.options.levelling() or Moebius.identity()  # the still background's map: the input levelled, or as it is

    def attempt(t: float) -> _Placed:
        controls = tuple(replace(c, moebius=(c.moebius @ turn.inverse).power(t) @ turn) if j in involved else c for j, c in enumerate(d.controls))
        relaxed = replace(d, constraints=replace(d.constraints, controls=controls)).filled()
        coordinates, turned, _ = blend_coordinates(relaxed, width, src_width, exact=exact)
        untangled, left, patches = _untangled(coordinates, turned, src_width, _kept(relaxed, width)[1])
        return _Placed(relaxed, untangled, left, tuple(patches))

    for t in GIVE_WAY:  # the first share whose blend, untangled, turns nothing over
        placed = attempt(t)
        if placed.folds.area == 0:
            break
    else:  # still folding with those maps the identity: every handle gives way (the identity everywhere folds nothing)
        involved = {j for j, c in enumerate(d.controls) if c.handle != BACKGROUND}
        placed = attempt(0.0)
    given = sorted({int(d.controls[j].handle) for j in involved})
    names = " and ".join(f"handles[{h}] ({d.handles.handles[h].kind})" for h in given)
    said = f"{names} give way where their blend folded beyond untangling: their maps are taken {100 * t:.0f}% of the way"
    if placed.folds.area > 0:
        said += f", and {100 * placed.folds.area:.3g}% of the sphere is still shown turned over"
    return placed, Problem(Kind.GIVE_WAY, tuple(given), said)


def _patch_count(mask: NDArray[np.bool_]) -> int:
    """How many separate turned-over patches a fold mask has."""
    return int(ndimage.label(mask, structure=np.ones((3, 3), bool))[1])


def _untangled(
    coordinates: NDArray[np.float32], folds: FoldOver, src_width: int, keep: NDArray[np.bool_]
) -> tuple[NDArray[np.float32], FoldOver, list[Patch]]:
    """Every turned-over patch untangled (:mod:`.untangle`), what is held kept where it can.

    Returns the coordinates, their fold check and the windows, in the order they were written.
    """
    patches: list[Patch] = []
    if folds.area > UNTANGLE_AREA or _patch_count(folds.mask) > UNTANGLE_PATCHES:  # too much for windows: the handles give way first
        return coordinates, folds, patches
    for _ in range(UNTANGLE_ROUNDS):  # a window that met another's is untangled again
        found = untangle(coordinates, folds.mask, src_width, keep)
        if not found:
            break
        coordinates = apply_patches(coordinates, found, src_width)
        patches += found
        folds = fold_of_coordinates(coordinates, src_width)
        if folds.area == 0:
            break
    return coordinates, folds, patches


@one_blas_thread
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
        an output at least :data:`omniwidget.raster.sampled.SAMPLE_FROM` wide, it is evaluated
        on a coarser grid and interpolated where that is within a quarter of a pixel, and
        exactly near the handles (:mod:`omniwidget.raster.sampled`). ``Result.inverse_map()``
        and so every quality figure use the exact map either way.
    previous : Result, optional
        The warp of a similar document (the editor's last preview, say). When it solved the
        same weights problem (the same mesh and boundary conditions: the same handles, at
        any output size) its weights are taken as they are; when its controls are the same
        ones, its weights interpolated onto the new mesh start the solver
        (:func:`omniwidget.method.deformation.deform`'s ``previous``).

    Returns
    -------
    Result
    """
    if not isinstance(handles, Handles):
        raise TypeError(f"handles must be a Handles document (see Handles.from_dict), got {type(handles).__name__}")
    if previous is not None and not isinstance(previous, Result):
        raise TypeError(f"previous must be a Result of an earlier warp, got {type(previous).__name__}")
    width = check_warp_arguments(image, width, order)
    d = deform(handles, samples=samples, previous=None if previous is None else previous.deformation)
    timings = dict(d.timings)
    result = _warped_by_one_map(image, d, width, order, timings) if d.blend is None else _warped_by_blend(image, d, width, order, exact, timings)
    for p in result.problems if warn else ():
        warnings.warn(p.message, _CATEGORIES[p.kind], stacklevel=2)
    return result


def _warped_by_one_map(image: NDArray, d: Deformation, width: int, order: Order, timings: dict[str, float]) -> Result:
    """The warp by a deformation whose controls share one map: that map applied exactly, without a mesh."""
    laps = Laps(timings)
    single = d.moebius or Moebius.identity()
    out = warp_moebius(image, single, width=width, order=order).image
    laps("resampling")
    return Result(d, out, grid_inverse(single.inverse), image.shape[1], FoldOver.none(out.shape), problems=d.problems, timings=timings)


def _warped_by_blend(image: NDArray, d: Deformation, width: int, order: Order, exact: bool, timings: dict[str, float]) -> Result:
    """The warp by a blend: eq. (2) at every output pixel, its folds untangled (the default mode), resampled, the folds left reported."""
    src_width = image.shape[1]
    coordinates, folds, at_folds = blend_coordinates(d, width, src_width, exact=exact, timings=timings)
    placed, problems = _Placed(d, coordinates, folds), list(d.problems)
    laps = Laps(timings)
    if folds.area > 0 and d.handles.options.anchor is not None:  # the default mode never folds
        placed, found = _unfolded(placed, width, src_width, exact)
        problems += found
        laps("untangle")
    d = placed.deformation  # its mesh and weights are the solve's whatever gave way (only maps are relaxed)
    blend = _blend_of(d)
    inverse = patched_inverse(filled_inverse(_exact_inverse([c.moebius.inverse for c in d.controls], blend, width), blend.fill), placed.patches)
    out = remap_panorama(image, placed.coordinates, order)
    laps("resampling")
    if at_folds is not None and (placed.patches or placed.folds.area >= FOLD_WARNING_AREA):
        problems.append(_fold_warning(d.handles, d.controls, at_folds, placed.folds.area, placed.patches, width))
    return Result(d, out, inverse, src_width, placed.folds, placed.coordinates, problems=tuple(problems), timings=timings)
