"""The methods the paper compares itself with, computed from the same handles.

Each baseline takes the same handles document as :func:`omniwidget.raster.pipeline.warp`
and builds the same controls (:func:`omniwidget.method.constraints.build_constraints`: one
Möbius map per point handle, line piece and cage vertex, with Sec. 3.4's rectify-all
solve when the document asks for it); only the way the maps are combined differs:

- :func:`single_moebius`: one control's map for the whole sphere (Fig. 2c). Conformal,
  one-to-one, straightens one line and bends the others.
- :func:`piecewise_constant`: every output pixel takes the map of the control whose
  handle is nearest on the sphere (a Voronoi partition, weights 0 or 1), as the
  perspective patches of Zelnik-Manor et al. 2005 do (Fig. 3c). Each line is as straight
  as its own map makes it, but the image tears along the seams between regions.
- :func:`gaussian_2017`: the blend of the 2017 local Möbius method (Souto Ferreira,
  Sacht and Velho 2017; Fig. 12b): each map's displacement in longitude and latitude,
  weighted by a Gaussian of the distance from its handle, summed. Handles close
  together pull on each other's lines.
- :func:`perspective`: a rectilinear (gnomonic) view (Fig. 2b): every straight line is
  straight, but it is a planar picture of less than a hemisphere, stretched towards its
  edges. It is the toolkit's one perspective camera, :mod:`omniwidget.raster.perspective`
  (``omniwidget view`` and the editor's look-around view use it too), named here as well.
- :func:`content_preserving`: the content-preserving projection of Carroll, Agrawala and
  Agarwala 2009 ([10], Fig. 13), the paper's strongest rival, from
  :mod:`omniwidget.evaluate.content_preserving`: a mesh over the whole sphere optimised
  into a plane by sparse least squares, the marked lines straight, with an irregular border.

:func:`compare` runs the paper's method and the baselines on the same handles and
measures each (:func:`omniwidget.evaluate.quality.summary`): a :class:`Comparison`, shown in a
notebook as a table.

The first three return a :class:`BaselineResult`, a :class:`~omniwidget.raster.pipeline.Result`
whose deformation is a :class:`BaselineDeformation` (the same controls, combined the method's
way), with the same attributes (``image``, ``controls``, ``folds``, ``inverse_map()``,
``inverse_points()``, ``forward_points()``), so every figure of
:mod:`omniwidget.evaluate.quality` is measured on them as on the paper's method. They use no
mesh: ``blend``, ``vertices``, ``faces``, ``constrained``, ``prescribed`` and ``weights``
are None, and the per-pixel weights are :meth:`BaselineResult.pixel_weights`.
"""

from __future__ import annotations

import html
import math
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import whole_number
from .._lazy import lazy
from ..document.handles import CageHandle, Handles, Options, PointHandle
from ..method.constraints import SAMPLES, Constraints, Control, build_constraints
from ..method.deformation import Deformation
from ..raster.blend import NEGLIGIBLE, PixelWeights, blended_inverse
from ..raster.perspective import PerspectiveView, perspective
from ..raster.pipeline import BlendWarning, Result, warp
from ..raster.warping import (
    PAD,
    GridInverse,
    Order,
    check_warp_arguments,
    grid_homogeneous,
    grid_inverse,
    homogeneous_to_lonlat,
    inverse_lonlat,
    remap_panorama,
    warp_moebius,
)
from ..sphere import coords
from .content_preserving import ContentPreservingResult, content_preserving
from .quality import FoldOver, Summary, fold_over, summary

if TYPE_CHECKING:
    from scipy import spatial
else:
    spatial = lazy("scipy.spatial")

__all__ = [
    "METHODS",
    "RIVALS",
    "SIGMA_PER_RADIUS",
    "BaselineDeformation",
    "BaselineResult",
    "Comparison",
    "ContentPreservingResult",
    "PerspectiveView",
    "compare",
    "content_preserving",
    "gaussian_2017",
    "perspective",
    "piecewise_constant",
    "single_moebius",
]

#: The Gaussian of :func:`gaussian_2017` has ``sigma = radius * SIGMA_PER_RADIUS``: it falls
#: to ``exp(-4.5)``, about 1%, at the handle's radius.
SIGMA_PER_RADIUS = 1.0 / 3.0
#: Gaussian weights are cut to 0 beyond this many sigmas (``exp(-12.5)``, below 4e-6).
_CUTOFF_SIGMAS = 5.0

#: ``fn(lonlat) -> lonlat``: an inverse map at arbitrary output positions, (n, 2) degrees.
PointInverse = Callable[[NDArray[np.float64]], NDArray[np.float64]]


@dataclass(frozen=True, eq=False, kw_only=True)
class BaselineDeformation(Deformation):
    """The deformation of the sphere a comparison method makes of the document's controls.

    The handles and the controls are those :func:`~omniwidget.method.deformation.deform`
    builds; no baseline uses a mesh, so there is no ``blend``, and the map at points is the
    method's own (:meth:`inverse_points`; :meth:`forward_points` searches through it).

    Attributes
    ----------
    method : str
        ``"single_moebius"``, ``"piecewise_constant"`` or ``"gaussian_2017"``.
    source_of : callable
        ``fn(lonlat) -> lonlat``, (n, 2) degrees to (n, 2) degrees: the method's inverse
        map at arbitrary output positions (what :meth:`inverse_points` evaluates).
    per_pixel : callable
        ``fn(rows) -> (h, W, k)``, the controls' weights on a block of output rows (see
        :meth:`pixel_weights`).
    """

    method: str
    source_of: PointInverse = field(repr=False)
    per_pixel: PixelWeights = field(repr=False)

    def inverse_points(self, lonlat: ArrayLike) -> NDArray[np.float64]:
        """The method's inverse map at arbitrary output positions.

        Parameters
        ----------
        lonlat : array_like, shape (..., 2)
            Output ``[lon, lat]`` in degrees.

        Returns
        -------
        ndarray of float64, shape (..., 2)
            The input ``[lon, lat]`` each position shows.
        """
        points = np.asarray(lonlat, dtype=np.float64)
        if points.shape[-1:] != (2,):
            raise ValueError(f"expected [lon, lat] pairs in the last axis, got shape {points.shape}")
        return self.source_of(points.reshape(-1, 2)).reshape(points.shape)

    def pixel_weights(self, rows: slice | None = None) -> NDArray[np.float64]:
        """The controls' weights at the output pixels.

        Parameters
        ----------
        rows : slice, optional
            Output rows; all by default.

        Returns
        -------
        ndarray of float64, shape (h, W, k)
            Column ``j`` is control ``j``'s weight: 1 for the chosen control of
            :func:`single_moebius`, 0 or 1 for :func:`piecewise_constant`, the Gaussian
            for :func:`gaussian_2017` (these do not sum to 1).
        """
        return np.asarray(self.per_pixel(slice(None) if rows is None else rows), dtype=np.float64)


@dataclass(frozen=True, eq=False)
class BaselineResult(Result):
    """A :class:`~omniwidget.raster.pipeline.Result` computed by a comparison method.

    Every attribute of ``Result`` means what it means there; its deformation is a
    :class:`BaselineDeformation`, so the mesh attributes (``blend``, ``vertices``, ``faces``,
    ``constrained``, ``prescribed``, ``weights``) are None, ``inverse_points`` is the
    method's map, and ``warnings`` is empty (fold-overs are in ``folds``).
    """

    deformation: BaselineDeformation

    @property
    def method(self) -> str:
        """The comparison method's name (:attr:`BaselineDeformation.method`)."""
        return self.deformation.method

    @property
    def source_of(self) -> PointInverse:
        """The method's inverse map at points (:attr:`BaselineDeformation.source_of`)."""
        return self.deformation.source_of

    @property
    def per_pixel(self) -> PixelWeights:
        """The controls' weights on a block of output rows (:attr:`BaselineDeformation.per_pixel`)."""
        return self.deformation.per_pixel

    def pixel_weights(self, rows: slice | None = None) -> NDArray[np.float64]:
        """The controls' weights at the output pixels, (h, W, k) (:meth:`BaselineDeformation.pixel_weights`)."""
        return self.deformation.pixel_weights(rows)


# --- shared steps ----------------------------------------------------------------------


def _start(
    image: NDArray, handles: Handles, width: int | None, order: str, samples: int
) -> tuple[int, Constraints, dict[str, float], float]:
    """Validate the common arguments and build the controls, as :func:`warp` does; start the clock."""
    if not isinstance(handles, Handles):
        raise TypeError(f"handles must be a Handles document (see Handles.from_dict), got {type(handles).__name__}")
    width = check_warp_arguments(image, width, order)
    clock = time.perf_counter()
    constraints = build_constraints(handles, samples=samples)
    now = time.perf_counter()
    return width, constraints, {"constraints": now - clock}, now


def _sites(constraints: Constraints) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """The prescribed points (final positions, [lon, lat]) and which controls own each, (p, 2) and (p, k).

    A control owns the points where its prescribed weight is the largest (and positive):
    a point handle its target, a line piece its output samples (joints shared by the
    lines meeting there), a cage vertex its output position and the halves of its two
    edges nearest it.
    """
    values = constraints.values
    owns = (values > 0) & (values == values.max(axis=1, keepdims=True))
    return coords.xyz_to_lonlat(constraints.points), owns


def _grid_rows(width: int, rows: slice) -> NDArray[np.float64]:
    """``[lon, lat]`` of the output pixel centres of a block of rows, (h, W, 2) degrees."""
    lon, lat = coords.grid_lonlat(width)
    return np.stack(np.meshgrid(lon, lat[rows]), axis=-1)


def _finish(image: NDArray, deformation: BaselineDeformation, inverse: GridInverse, width: int, order: Order, clock: float) -> BaselineResult:
    """Evaluate the inverse map once (float64), resample, measure the fold-overs."""
    timings = deformation.timings
    inverse_map = inverse_lonlat(inverse, width)
    now = time.perf_counter()
    timings["blend"], clock = now - clock, now
    coordinates = (coords.lonlat_to_px(inverse_map, image.shape[1]) + PAD).astype(np.float32)
    out = remap_panorama(image, coordinates, order)
    now = time.perf_counter()
    timings["resampling"], clock = now - clock, now
    folds = fold_over(inverse_map)
    timings["fold check"] = time.perf_counter() - clock
    result = BaselineResult(deformation, out, inverse, image.shape[1], folds, timings=timings)
    inverse_map.flags.writeable = False
    result.__dict__["_inverse_map"] = inverse_map  # Result.inverse_map()'s cache: computed once, here
    return result


# --- 1. one map ------------------------------------------------------------------------


def single_moebius(
    image: NDArray, handles: Handles, *, handle: int = 0, width: int | None = None, order: Order = "bilinear", samples: int = SAMPLES
) -> BaselineResult:
    """Warp the whole panorama by the map of one handle (the paper's Fig. 2c).

    The map is that of the first control of ``handles.handles[handle]``, exactly as
    :func:`~omniwidget.raster.pipeline.warp` builds it (so with ``options.rectify == "all"``
    a line's map comes from the Sec. 3.4 solve over all the lines): a point's map, a
    line's (its first piece if crossings split it), a cage's first vertex. With one handle
    the result is :func:`warp`'s, pixel for pixel.

    Parameters
    ----------
    image : ndarray, shape (H, W[, C])
        Equirectangular, ``W = 2 H``; uint8, uint16, float32 or float64; 1 to 4 channels.
    handles : Handles
    handle : int
        Index of the handle whose map is used.
    width : int, optional
        Output width (even); default: the input's.
    order : {"nearest", "bilinear", "bicubic"}
    samples : int
        Points per line and cage edge in the controls' construction (the paper's 50).

    Returns
    -------
    BaselineResult
        ``controls`` lists every control of the document, each with the chosen map (its
        label says so; ``build_constraints(handles)`` has their own maps), so
        ``Result.moebius`` is the map, and ``forward_points`` works for any control.
        ``folds`` is empty: a Möbius map is one-to-one.

    Raises
    ------
    TypeError
        If ``handles`` is not a :class:`Handles`.
    ValueError
        If ``handle`` is not an index of a handle, or another argument is out of range.
    """
    width, constraints, timings, clock = _start(image, handles, width, order, samples)
    if len(handles.handles) == 0:
        raise ValueError("handles has no handles: there is no map to apply")
    handle = whole_number(handle, "handle", 0)
    if handle >= len(handles.handles):
        raise ValueError(
            f"handle must be the index of one of the {len(handles.handles)} handles (0 to {len(handles.handles) - 1}), got {handle}"
        )
    index = next(j for j, c in enumerate(constraints.controls) if c.handle == handle)
    chosen = constraints.controls[index]
    controls = tuple(
        Control(chosen.moebius, c.handle, f"{c.label}, shown by {'its own map' if c is chosen else 'the map of ' + chosen.label}")
        for c in constraints.controls
    )
    constraints = replace(constraints, controls=controls)
    m = chosen.moebius
    out = warp_moebius(image, m, width=width, order=order).image
    timings["resampling"] = time.perf_counter() - clock
    no_folds = FoldOver.none(out.shape)
    inverse = m.inverse

    def source_of(lonlat: NDArray[np.float64]) -> NDArray[np.float64]:
        return inverse(lonlat)

    def per_pixel(rows: slice) -> NDArray[np.float64]:
        h = len(range(width // 2)[rows])
        one_hot = np.zeros((h, width, len(controls)))
        one_hot[..., index] = 1.0
        return one_hot

    chosen_map = BaselineDeformation(
        handles=handles, constraints=constraints, timings=timings, method="single_moebius", source_of=source_of, per_pixel=per_pixel
    )
    return BaselineResult(chosen_map, out, grid_inverse(inverse), image.shape[1], no_folds, timings=timings)


# --- 2. piecewise-constant weights -----------------------------------------------------


def _nearest_control(constraints: Constraints) -> Callable[[NDArray[np.float64]], NDArray[np.intp]]:
    """``fn(lonlat (n, 2)) -> (n,)``: the control owning the prescribed point nearest each position."""
    lonlat, owns = _sites(constraints)
    owner = np.argmax(owns, axis=1)  # ties (joints): the first line
    tree = spatial.cKDTree(coords.lonlat_to_xyz(lonlat))  # nearest by chord is nearest by arc

    def fn(positions: NDArray[np.float64]) -> NDArray[np.intp]:
        return owner[tree.query(coords.lonlat_to_xyz(positions))[1]]

    return fn


def piecewise_constant(
    image: NDArray, handles: Handles, *, width: int | None = None, order: Order = "bilinear", samples: int = SAMPLES
) -> BaselineResult:
    """Every output pixel takes the map of the nearest handle: 0/1 weights (Fig. 3c).

    Zelnik-Manor, Peters and Perona (2005) cover the panorama with perspective patches,
    one per region; the paper compares its smooth weights with this piecewise-constant
    choice (with Möbius maps in place of perspectives). The regions here are a Voronoi
    partition of the output sphere: an output pixel belongs to the control whose final
    geometry is nearest by great-circle distance: a point handle's target, a line's
    output image (its ``samples`` points), a cage vertex's output position and the halves
    of its two edges nearest it (the points where :func:`warp` prescribes the control's
    weight as the largest). Eq. (2) with these weights shows each region by its own map,
    so each line is as straight as its map makes it, but the image tears along the seams,
    where neighbouring maps disagree (:func:`omniwidget.evaluate.quality.tear`).

    Parameters
    ----------
    image : ndarray, shape (H, W[, C])
        Equirectangular, ``W = 2 H``; uint8, uint16, float32 or float64; 1 to 4 channels.
    handles : Handles
    width : int, optional
        Output width (even); default: the input's.
    order : {"nearest", "bilinear", "bicubic"}
    samples : int
        Points per line and cage edge (the paper's 50).

    Returns
    -------
    BaselineResult
        ``pixel_weights()`` is 1 for each pixel's control and 0 for the others.

    Raises
    ------
    TypeError
        If ``handles`` is not a :class:`Handles`.
    ValueError
        If ``handles`` has no handles, or another argument is out of range.
    """
    width, constraints, timings, clock = _start(image, handles, width, order, samples)
    if not constraints.controls:
        raise ValueError("handles has no handles: there is no map to apply")
    k = len(constraints.controls)
    nearest = _nearest_control(constraints)
    inverses = [c.moebius.inverse for c in constraints.controls]

    def per_pixel(rows: slice) -> NDArray[np.float64]:
        label = nearest(_grid_rows(width, rows).reshape(-1, 2))
        one_hot = np.zeros((len(label), k))
        one_hot[np.arange(len(label)), label] = 1.0
        return one_hot.reshape(-1, width, k)

    def source_of(lonlat: NDArray[np.float64]) -> NDArray[np.float64]:
        label = nearest(lonlat)
        out = np.empty_like(lonlat)
        for j in np.unique(label):
            out[label == j] = inverses[j](lonlat[label == j])
        return out

    inverse = blended_inverse(inverses, per_pixel, precision="double")
    nearest_map = BaselineDeformation(
        handles=handles, constraints=constraints, timings=timings, method="piecewise_constant", source_of=source_of, per_pixel=per_pixel
    )
    return _finish(image, nearest_map, inverse, width, order, clock)


# --- 3. the 2017 Gaussian blend of displacements ---------------------------------------


def _radii(handles: Handles, constraints: Constraints) -> NDArray[np.float64]:
    """Each control's radius in degrees, measured on the output (see :func:`gaussian_2017`)."""
    line_of = {c: samples for c, samples in constraints.lines}
    radii = []
    vertex: dict[int, int] = {}
    for j, control in enumerate(constraints.controls):
        h = handles.handles[control.handle]
        if isinstance(h, PointHandle):
            centre, east_tip = h.target_points()[:2]
            radii.append(float(coords.angular_distance(centre, east_tip)))
        elif isinstance(h, CageHandle):
            v = vertex.setdefault(control.handle, 0)
            vertex[control.handle] += 1
            finals = np.asarray(h.finals, dtype=np.float64)
            n = len(finals)
            edges = coords.angular_distance(finals[v], finals[[(v - 1) % n, (v + 1) % n]])
            radii.append(float(edges.min() / 2))
        else:
            ends = control.moebius(line_of[j][[0, -1]])
            radii.append(float(coords.angular_distance(ends[0], ends[1]) / 2))
    return np.array(radii)


def _gaussian_weights(constraints: Constraints, sigma: NDArray[np.float64]) -> Callable[[NDArray[np.float64]], NDArray[np.float64]]:
    """``fn(lonlat (n, 2)) -> (n, k)``: each control's Gaussian of the distance from its sites."""
    lonlat, owns = _sites(constraints)
    sites = [lonlat[owns[:, j]] for j in range(owns.shape[1])]
    trees = [spatial.cKDTree(coords.lonlat_to_xyz(s)) if len(s) else None for s in sites]
    # chord length of the cut-off arc: beyond it the kd-tree stops looking
    bounds = [2 * math.sin(math.radians(min(_CUTOFF_SIGMAS * s, 180.0)) / 2) * (1 + 1e-9) for s in sigma]

    def fn(positions: NDArray[np.float64]) -> NDArray[np.float64]:
        xyz = coords.lonlat_to_xyz(positions)
        out = np.zeros((len(positions), len(trees)))
        for j, tree in enumerate(trees):
            if tree is None:
                continue
            chord, index = tree.query(xyz, distance_upper_bound=bounds[j])
            near = np.isfinite(chord)
            d = coords.angular_distance(positions[near], sites[j][index[near]])
            out[near, j] = np.exp(-0.5 * (d / sigma[j]) ** 2)
        return out

    return fn


def _displaced(lonlat: NDArray[np.float64], sources: Sequence[NDArray[np.float64] | None], weights: NDArray[np.float64]) -> NDArray[np.float64]:
    """``p + sum_j w_j (M_j⁻¹(p) - p)`` in longitude and latitude (degrees), (..., 2).

    Each displacement's longitude is wrapped into ``[-180, 180)``; the sum is wrapped
    again, and latitudes beyond a pole are clipped to it (the naive blend has no better
    answer).
    """
    lon, lat = lonlat[..., 0], lonlat[..., 1]
    acc_lon = np.zeros_like(lon)
    acc_lat = np.zeros_like(lat)
    for j, src in enumerate(sources):
        if src is None:
            continue
        acc_lon += weights[..., j] * coords.wrap_lon(src[..., 0] - lon)
        acc_lat += weights[..., j] * (src[..., 1] - lat)
    return np.stack([coords.wrap_lon(lon + acc_lon), np.clip(lat + acc_lat, -90.0, 90.0)], axis=-1)


def gaussian_2017(
    image: NDArray,
    handles: Handles,
    *,
    radius: float | None = None,
    width: int | None = None,
    order: Order = "bilinear",
    samples: int = SAMPLES,
) -> BaselineResult:
    """The blend of the 2017 local Möbius method: Gaussian-weighted lon/lat displacements (Fig. 12b).

    Souto Ferreira, Sacht and Velho (2017) restrict each Möbius map to a region around its
    handle by an ad hoc weighting function; the 2020 paper says only that these weights
    "affect overlapping regions" and so distort lines when handles are close (Fig. 12b).
    This baseline takes them as Gaussians and blends, as that method does, in the image's
    longitude and latitude rather than on the sphere. For an output position ``p``::

        T⁻¹(p) = p + Σ_j g_j(p) (M_j⁻¹(p) - p),   g_j(p) = exp(-d_j(p)² / (2 σ_j²)),

    where ``M_j⁻¹(p) - p`` is the displacement in degrees of longitude and latitude (the
    longitude difference wrapped into ``[-180, 180)``), ``d_j(p)`` the great-circle
    distance from ``p`` to control ``j``'s handle at its final position (its sites, as in
    :func:`piecewise_constant`) and ``σ_j = r_j / 3`` (:data:`SIGMA_PER_RADIUS`). The
    weights are neither normalised nor bounded in sum: where two handles' Gaussians
    overlap, both displacements apply in full. Nothing treats the poles or the seam: the
    sum is wrapped in longitude and clipped in latitude.

    The radius ``r_j``, in degrees on the output sphere:

    - a point handle: its arrows' length (0.3 rad, Sec. 3.3, times its zoom);
    - a line piece: half its length (the distance between its output ends), so the
      weight falls to 1% half a line's length away from the line;
    - a cage vertex: half its shorter output edge.

    Parameters
    ----------
    image : ndarray, shape (H, W[, C])
        Equirectangular, ``W = 2 H``; uint8, uint16, float32 or float64; 1 to 4 channels.
    handles : Handles
    radius : float, optional
        One radius in degrees, ``> 0``, for every control instead of the above.
    width : int, optional
        Output width (even); default: the input's.
    order : {"nearest", "bilinear", "bicubic"}
    samples : int
        Points per line and cage edge (the paper's 50).

    Returns
    -------
    BaselineResult
        ``pixel_weights()`` are the Gaussians ``g_j``.

    Raises
    ------
    TypeError
        If ``handles`` is not a :class:`Handles`.
    ValueError
        If ``handles`` has no handles, ``radius`` is not a positive number, or another
        argument is out of range.
    """
    width, constraints, timings, clock = _start(image, handles, width, order, samples)
    if not constraints.controls:
        raise ValueError("handles has no handles: there is no map to apply")
    if radius is None:
        radii = _radii(handles, constraints)
    else:
        if isinstance(radius, bool) or not isinstance(radius, int | float | np.integer | np.floating) or not 0 < radius <= 180:
            raise ValueError(f"radius must be a number of degrees in (0, 180], got {radius!r}")
        radii = np.full(len(constraints.controls), float(radius))
    weights_at = _gaussian_weights(constraints, np.maximum(radii, 1e-9) * SIGMA_PER_RADIUS)
    inverses = [c.moebius.inverse for c in constraints.controls]

    def per_pixel(rows: slice) -> NDArray[np.float64]:
        return weights_at(_grid_rows(width, rows).reshape(-1, 2)).reshape(-1, width, len(inverses))

    def inverse(lon: NDArray[np.float64], lat: NDArray[np.float64], rows: slice) -> tuple[NDArray, NDArray]:
        w = per_pixel(rows)
        sources: list[NDArray[np.float64] | None] = []
        for j, m in enumerate(inverses):
            if not w[..., j].max() > NEGLIGIBLE:
                sources.append(None)
                continue
            src_lon, src_lat = homogeneous_to_lonlat(*grid_homogeneous(m, lon, lat))
            sources.append(np.degrees(np.stack([src_lon, src_lat], axis=-1)))
        grid = np.degrees(np.stack(np.meshgrid(lon, lat), axis=-1))
        out = np.radians(_displaced(grid, sources, w))
        return out[..., 0], out[..., 1]

    def source_of(lonlat: NDArray[np.float64]) -> NDArray[np.float64]:
        w = weights_at(lonlat)
        return _displaced(lonlat, [m(lonlat) if w[:, j].max() > NEGLIGIBLE else None for j, m in enumerate(inverses)], w)

    gaussian_map = BaselineDeformation(
        handles=handles, constraints=constraints, timings=timings, method="gaussian_2017", source_of=source_of, per_pixel=per_pixel
    )
    return _finish(image, gaussian_map, inverse, width, order, clock)


# --- the comparison ---------------------------------------------------------------------

def _with_options(options: Options) -> Callable[..., Result]:
    """:func:`warp` with the document's handles under other options."""

    def method(image: NDArray, handles: Handles, **kwargs: Any) -> Result:
        if not isinstance(handles, Handles):
            raise TypeError(f"handles must be a Handles document (see Handles.from_dict), got {type(handles).__name__}")
        return warp(image, Handles(handles.handles, options), **kwargs)

    return method


#: The methods :func:`compare` knows, by name: the paper's method with the document's own
#: options (``"bbw"``), the toolkit's default mode (``"default"``: ``Options()``), the
#: paper's mode (``"paper"``: ``Options(rectify="all", anchor=None)``), the baselines, and
#: [10] (``"content_preserving"``).
METHODS: dict[str, Callable[..., Result | ContentPreservingResult]] = {
    "bbw": warp,
    "piecewise_constant": piecewise_constant,
    "gaussian_2017": gaussian_2017,
    "single_moebius": single_moebius,
    "default": _with_options(Options()),
    "paper": _with_options(Options(rectify="all", anchor=None)),
    "content_preserving": content_preserving,
}
#: ``compare(image, handles, RIVALS)``: ours in the default and the paper's mode beside [10] (the paper's Fig. 13).
RIVALS = ("default", "paper", "content_preserving")

#: Columns of the comparison table: (heading, Summary attribute, format).
_COLUMNS = (
    ("worst line from straight (px)", "straightness", "{:.2f}"),
    ("fold-over (% of sphere)", "fold_over", "{:.3%}"),
    ("tear (px)", "tear", "{:.2f}"),
    ("conformal distortion, mean", "distortion_mean", "{:.3f}"),
    ("conformal distortion, p99", "distortion_p99", "{:.3f}"),
    ("sphere shown (%)", "coverage", "{:.1%}"),
    ("sphere lost to the crop (%)", "cropped_loss", "{:.1%}"),
    ("mean displacement (°)", "displacement", "{:.2f}"),
    ("fixed cage moved (px)", "cage_motion", "{:.2g}"),
    ("time (s)", "seconds", "{:.2f}"),
)
_LABELS = {
    "bbw": "BBW (the paper)",
    "piecewise_constant": "piecewise-constant",
    "gaussian_2017": "Gaussian 2017",
    "single_moebius": "one Möbius map",
    "default": "BBW, default mode",
    "paper": "BBW, the paper's mode",
    "content_preserving": "content-preserving [10]",
}


@dataclass(frozen=True, eq=False)
class Comparison:
    """The paper's method and the baselines on the same handles, measured alike.

    Attributes
    ----------
    results : dict of str to Result or ContentPreservingResult
        Each method's result, by name (``"bbw"``, ``"piecewise_constant"``, ...).
    summaries : dict of str to Summary
        Each method's quality figures (:func:`omniwidget.evaluate.quality.summary`; for
        ``"content_preserving"`` a :class:`~omniwidget.evaluate.content_preserving.PlaneSummary`).

    Notes
    -----
    [10]'s output is a plane of its own aspect ratio, not an equirectangular panorama, so
    its figures are measured on its own output (:class:`~omniwidget.evaluate.content_preserving.PlaneSummary`
    says how): its lines' straightness converted to the pixels of an equirectangular
    panorama as wide as its output, at each line's own scale; distortion against the
    sphere's metric per mesh triangle; fold-over by the sign of each triangle's
    Jacobian; the share of the sphere shown, and the share lost when the plane is cropped
    to the largest rectangle inside its irregular border (only it has one: the
    panoramas' column shows "–"); its displacement does not apply ("–").

    In a notebook it shows as an HTML table, one row per method; its
    ``application/json`` representation is :meth:`as_dict`, so a notebook's saved output
    keeps the figures as numbers.
    """

    results: dict[str, Result | ContentPreservingResult]
    summaries: dict[str, Summary]

    def __getitem__(self, method: str) -> Summary:
        return self.summaries[method]

    def as_dict(self) -> dict[str, dict[str, Any]]:
        """Every method's figures as plain numbers, by method name.

        Returns
        -------
        dict of str to dict
            :meth:`Summary.as_dict` of each method.
        """
        return {name: s.as_dict() for name, s in self.summaries.items()}

    def _cells(self) -> list[list[str]]:
        rows = []
        for name, s in self.summaries.items():
            cells = [_LABELS.get(name, name)]
            for _, attribute, fmt in _COLUMNS:
                value = getattr(s, attribute, None)
                cells.append("–" if value is None or (isinstance(value, float) and math.isnan(value)) else fmt.format(value))
            rows.append(cells)
        return rows

    def to_markdown(self) -> str:
        """The table as Markdown.

        Returns
        -------
        str
        """
        head = ["method", *(c[0] for c in _COLUMNS)]
        lines = ["| " + " | ".join(head) + " |", "|" + " --- |" * len(head)]
        lines += ["| " + " | ".join(row) + " |" for row in self._cells()]
        return "\n".join(lines)

    def _repr_html_(self) -> str:
        head = "".join(f"<th>{html.escape(c[0])}</th>" for c in _COLUMNS)
        body = "".join(
            "<tr>"
            + f"<th style='text-align:left'>{html.escape(row[0])}</th>"
            + "".join(f"<td>{html.escape(c)}</td>" for c in row[1:])
            + "</tr>"
            for row in self._cells()
        )
        width = next(iter(self.summaries.values())).width if self.summaries else 0
        caption = f"measured at {width} x {width // 2}: lines and tears in output pixels"
        return f"<table><caption>{html.escape(caption)}</caption><thead><tr><th>method</th>{head}</tr></thead><tbody>{body}</tbody></table>"

    def _repr_mimebundle_(self, include: Any = None, exclude: Any = None) -> dict[str, Any]:
        return {
            "text/plain": self.to_markdown(),
            "text/html": self._repr_html_(),
            "application/json": self.as_dict(),
        }


def compare(
    image: NDArray,
    handles: Handles,
    methods: Sequence[str] = ("bbw", "piecewise_constant", "gaussian_2017", "single_moebius"),
    *,
    width: int | None = None,
    samples: int = SAMPLES,
) -> Comparison:
    """Warp one panorama with the same handles by several methods and measure each.

    Parameters
    ----------
    image : ndarray, shape (H, W[, C])
        The panorama (``W = 2 H``).
    handles : Handles
    methods : sequence of str
        Names from :data:`METHODS`: ``"bbw"`` (:func:`omniwidget.warp`, the paper's
        method with the document's options), ``"piecewise_constant"``,
        ``"gaussian_2017"``, ``"single_moebius"``; ``"default"`` and ``"paper"``
        (:func:`omniwidget.warp` under ``Options()`` and ``Options(rectify="all",
        anchor=None)``), ``"content_preserving"`` ([10]); :data:`RIVALS` is the last three.
    width : int, optional
        Output width (default the input's); the figures count pixels at this width.
    samples : int
        Samples per line and cage edge, for every method alike.

    Returns
    -------
    Comparison

    Raises
    ------
    ValueError
        If a method's name is unknown (or as the methods themselves raise).

    Notes
    -----
    The warps' own :class:`~omniwidget.BlendWarning` s are not issued here: the fold-overs
    they report are in each summary's ``fold_over``, and ``results[name].warnings`` keeps them.
    """
    unknown = [m for m in methods if m not in METHODS]
    if unknown or not methods:
        raise ValueError(f"methods must be a non-empty sequence of {', '.join(METHODS)}; unknown: {', '.join(map(repr, unknown))}")
    results: dict[str, Result | ContentPreservingResult] = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", category=BlendWarning)
        for name in methods:
            results[name] = METHODS[name](image, handles, width=width, samples=samples)
    return Comparison(results, {name: r.quality if isinstance(r, ContentPreservingResult) else summary(r) for name, r in results.items()})
