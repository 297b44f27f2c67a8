"""Quality figures of a warp, measured from its inverse map.

An *inverse map* is what every warp in omniwidget computes: for each output pixel centre
(an equirectangular grid ``(H, 2H)``), the input ``[lon, lat]`` in degrees it shows
(``Result.inverse_map()``). From it:

- :func:`forward_points` inverts it: where input positions land in the output;
- :func:`line_straightness`: how straight a marked line comes out, in pixels;
- :func:`conformal_distortion`: how far the map is from conformal (angle-preserving);
- :func:`fold_over`: where the map turns the image over (Jacobian determinant <= 0);
- :func:`coverage`: the share of the input sphere the output shows;
- :func:`cage_motion`: how far the inside of a fixed cage moved;
- :func:`tear`: the largest jump of the map between neighbouring output pixels;
- :func:`displacement`: how far the map moves the sphere, on average;
- :func:`far_field`: the same figures on the part of the sphere far from every handle;
- :func:`summary`: all of them for one warp (a :class:`~omniwidget.Result`), as a :class:`Summary`;
- :func:`point_fidelity`, :func:`cage_fidelity` and :func:`kink`: how faithfully a warp does
  what a point handle and a rigidly moved cage ask, and whether an edge marked in part
  comes out without a kink where its marked piece ends.

Use float64 maps: float32 holds only about 1e-4 of a pixel step.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import check_inverse_map, whole_number
from .._lazy import lazy
from ..document.handles import CageHandle, LineHandle, PointHandle
from ..raster.fold import FoldOver, fold_over
from ..sphere import coords
from ..sphere.arcs import inside_polygon
from ..sphere.moebius import Moebius

if TYPE_CHECKING:
    from scipy import spatial
else:
    spatial = lazy("scipy.spatial")

#: Samples per line piece in :func:`dense_line`'s first pass, which measures how long its image is.
DENSE_FIRST = 65
#: A line farther than this from straight, in output pixels, is reported as relaxed (:attr:`Summary.relaxed`).
RELAXED_PX = 0.5
#: The far field: the output sphere farther than this many degrees from every handle.
FAR_FIELD = 30.0

__all__ = [
    "FAR_FIELD",
    "KINK_STEP",
    "Distortion",
    "FarField",
    "FoldOver",
    "RELAXED_PX",
    "PointFidelity",
    "Summary",
    "cage_fidelity",
    "cage_motion",
    "chain_straightness",
    "conformal_distortion",
    "coverage",
    "dense_line",
    "dense_straightness",
    "kink",
    "kink_of_curve",
    "kept_lines",
    "near_mask",
    "displacement",
    "far_field",
    "fold_over",
    "forward_points",
    "line_straightness",
    "local_jacobians",
    "point_fidelity",
    "straightness",
    "summary",
    "tear",
    "vertical_tilt",
]


def straightness(curve: ArrayLike, width: int, fit: Literal["chord", "best"] = "chord") -> float:
    """Largest distance, in pixels of an image ``width`` wide, of a curve from a straight line.

    Parameters
    ----------
    curve : array_like, shape (n, 2)
        ``[lon, lat]`` in degrees, in order along the curve (for example a line's image,
        sampled densely). Longitudes are unwrapped along the curve, so curves across the
        ±180° seam are measured as they appear when the image is scrolled.
    width : int
        Image width: 1 pixel is ``360 / width`` degrees.
    fit : {"chord", "best"}
        ``"chord"``: the segment joining the first and last sample (how far a line bends
        away from where its ends are); ``"best"``: the straight line whose largest distance
        is smallest (the minimum-zone fit of metrology: half the width of the narrowest
        strip holding the curve), half the chord's figure for a circular arc.

    Returns
    -------
    float
        ``max`` over the samples of their distance from the chosen line, in pixels.
    """
    pts = np.array(curve, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 2:
        raise ValueError(f"expected a curve of shape (n >= 2, 2), got {pts.shape}")
    pts[:, 0] = np.unwrap(pts[:, 0], period=360.0)
    if not np.all(np.isfinite(pts)):
        raise ValueError("the curve has NaN or infinite positions (a point the output does not show?)")
    px = pts * (width / 360.0)
    if fit == "best":
        return _half_width(px)
    if fit != "chord":
        raise ValueError(f"fit must be 'chord' or 'best', got {fit!r}")
    a, b = px[0], px[-1]
    chord = b - a
    length = np.hypot(*chord)
    if length == 0:
        return float(np.max(np.hypot(*(px - a).T)))
    t = np.clip(((px - a) @ chord) / length**2, 0.0, 1.0)
    nearest = a + t[:, None] * chord
    return float(np.max(np.hypot(*(px - nearest).T)))


def _half_width(points: NDArray[np.float64]) -> float:
    """Half the width of the narrowest strip holding 2D points: the strip lies along a hull edge."""
    centred = points - points.mean(axis=0)
    try:
        hull = centred[spatial.ConvexHull(centred).vertices]
    except spatial.QhullError:  # all on one line (or one point)
        return 0.0
    edges = np.roll(hull, -1, axis=0) - hull
    normals = np.stack([-edges[:, 1], edges[:, 0]], axis=1) / np.hypot(*edges.T)[:, None]
    heights = hull @ normals.T  # (vertex, edge)
    return float(np.min(heights.max(axis=0) - heights.min(axis=0)) / 2)


def local_jacobians(inverse_map: ArrayLike) -> NDArray[np.float64]:
    """Jacobians of an inverse map in the image's east/north frames, by central differences.

    Parameters
    ----------
    inverse_map : array_like, shape (H, W, 2)
        For each output pixel centre the input ``[lon, lat]`` (degrees) it shows; use
        float64 for measurements (float32 holds only about 1e-4 of a pixel step).

    Returns
    -------
    ndarray of float64, shape (H - 2, W, 2, 2)
        For output rows ``1 .. H - 2`` and every column: ``J[..., i, k]`` is the change of
        the source position along source direction ``i`` (0 east, 1 north) per unit arc
        along output direction ``k`` (0 east, 1 north). Columns wrap at the seam.
        Differences are taken between 3D unit vectors, so sources on or across a pole are
        measured like any other.
    """
    m = check_inverse_map(inverse_map)
    height, width = m.shape[:2]
    _, lat = coords.grid_lonlat(width)
    step = np.radians(360.0 / width)
    src = coords.lonlat_to_xyz(m)
    d_east = (np.roll(src, -1, axis=1) - np.roll(src, 1, axis=1))[1:-1] / (2 * step * np.cos(np.radians(lat[1:-1])))[:, None, None]
    d_north = (src[:-2] - src[2:]) / (2 * step)
    east, north = coords.local_frame(m[1:-1])
    jac = np.empty((height - 2, width, 2, 2))
    for k, d in enumerate((d_east, d_north)):
        jac[..., 0, k] = np.sum(d * east, axis=-1)
        jac[..., 1, k] = np.sum(d * north, axis=-1)
    return jac


@dataclass(frozen=True, eq=False)
class Distortion:
    """Conformal distortion of a warp: ``sigma_max / sigma_min - 1`` of its Jacobian.

    Attributes
    ----------
    mean : float
        Area-weighted mean over the output rows within ``max_abs_lat``.
    p99 : float
        Area-weighted 99th percentile there.
    per_pixel : ndarray of float64, shape (H, W)
        Per output pixel; NaN on the first and last rows (no central difference there).
    max_abs_lat : float
        The latitude bound (degrees) of the summary figures.
    """

    mean: float
    p99: float
    per_pixel: NDArray[np.float64]
    max_abs_lat: float


def _weighted_quantile(values: NDArray, weights: NDArray, q: float) -> float:
    order = np.argsort(values, axis=None)
    cumulative = np.cumsum(weights.ravel()[order])
    return float(values.ravel()[order][np.searchsorted(cumulative, q * cumulative[-1])])


def conformal_distortion(inverse_map: ArrayLike, max_abs_lat: float = 80.0) -> Distortion:
    """Conformal distortion of a warp, away from the poles.

    Möbius maps are conformal (0 everywhere, up to differencing error); a blend of them is
    not, and this shows where and how much.

    Parameters
    ----------
    inverse_map : array_like, shape (H, W, 2)
        See :func:`local_jacobians`.
    max_abs_lat : float
        Output rows within this latitude (degrees) count in the summary: at the poles the
        equirectangular grid's east steps shrink to nothing and differences lose precision.

    Returns
    -------
    Distortion
    """
    if not 0 < max_abs_lat <= 90:
        raise ValueError(f"max_abs_lat must be in (0, 90] degrees, got {max_abs_lat!r}")
    jac = local_jacobians(inverse_map)
    per_pixel = np.full((jac.shape[0] + 2, jac.shape[1]), np.nan)
    per_pixel[1:-1] = _singular_value_ratio_minus_one(jac)
    mean, p99 = _distortion_figures(per_pixel, np.ones(per_pixel.shape, dtype=bool), max_abs_lat)
    return Distortion(mean, p99, per_pixel, float(max_abs_lat))


def _singular_value_ratio_minus_one(jac: NDArray[np.float64]) -> NDArray[np.float64]:
    """``s1 / s2 - 1`` of each 2 x 2 matrix of ``jac`` (..., 2, 2), in closed form.

    With the second row negated where the determinant is negative (the singular values stay),
    ``s1 + s2 = |(a + d, b - c)|``, ``s1 - s2 = |(a - d, b + c)|`` and ``s1 s2 = ad - bc``, so
    ``s1 / s2 - 1 = q (p + q) / (2 det)`` with no difference of close numbers: exact to rounding
    for nearly conformal maps, where an SVD loses digits (and faster than one).
    Infinite where a matrix is singular, NaN where it is zero.
    """
    a, b, c, d = jac[..., 0, 0], jac[..., 0, 1], jac[..., 1, 0], jac[..., 1, 1]
    sign = np.where(a * d - b * c < 0, -1.0, 1.0)
    c, d = c * sign, d * sign
    p, q = np.hypot(a + d, b - c), np.hypot(a - d, b + c)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.asarray(q * (p + q) / (2.0 * (a * d - b * c)), dtype=np.float64)


def _distortion_figures(per_pixel: NDArray[np.float64], where: NDArray[np.bool_], max_abs_lat: float) -> tuple[float, float]:
    """Area-weighted mean and 99th percentile of ``per_pixel`` where ``where``, within ``max_abs_lat`` (NaN if nowhere)."""
    height, width = per_pixel.shape
    _, lat = coords.grid_lonlat(width)
    rows = np.abs(lat) <= max_abs_lat
    rows[[0, -1]] = False  # no central difference there
    use = where & rows[:, None]
    if not use.any():
        return math.nan, math.nan
    values = per_pixel[use]
    area = np.broadcast_to(coords.row_area(height)[:, None], per_pixel.shape)[use]
    return float(np.sum(values * area) / np.sum(area)), _weighted_quantile(values, area, 0.99)


def _bilinear(src: NDArray[np.floating], x: NDArray, y: NDArray) -> tuple[NDArray, NDArray, NDArray]:
    """Value and x/y derivatives of the bilinear interpolation of ``src`` (H, W, 3) at pixel ``(x, y)``.

    ``src`` may also be an inverse map ``[lon, lat]`` (H, W, 2): only the corners read are
    turned into unit vectors. Columns wrap, rows are clamped to ``[0, H - 1]``.
    """
    height, width = src.shape[:2]
    y = np.clip(y, 0.0, height - 1.0)
    x0, y0 = np.floor(x), np.minimum(np.floor(y), height - 2)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    c0, c1, r0 = x0.astype(np.int64) % width, (x0.astype(np.int64) + 1) % width, y0.astype(np.int64)
    s00, s01, s10, s11 = src[r0, c0], src[r0, c1], src[r0 + 1, c0], src[r0 + 1, c1]
    if src.shape[-1] == 2:
        s00, s01, s10, s11 = (coords.lonlat_to_xyz(np.asarray(c, np.float64)) for c in (s00, s01, s10, s11))
    value = (1 - fy) * ((1 - fx) * s00 + fx * s01) + fy * ((1 - fx) * s10 + fx * s11)
    d_x = (1 - fy) * (s01 - s00) + fy * (s11 - s10)
    d_y = (1 - fx) * (s10 - s00) + fx * (s11 - s01)
    return value, d_x, d_y


def forward_points(
    inverse_map: ArrayLike, lonlat: ArrayLike, *, start: ArrayLike | None = None, iterations: int = 12, tolerance: float = 1e-3
) -> NDArray[np.float64]:
    """Where input positions land in the output: the inverse map solved for them.

    Each position starts at the output pixel (of a grid every ``W / 512`` pixels) whose
    source is nearest, then Newton steps on the map's bilinear interpolation (as 3D
    vectors) converge to the output position that shows it.

    Parameters
    ----------
    inverse_map : array_like, shape (H, W, 2)
        See :func:`local_jacobians`.
    lonlat : array_like, shape (n, 2)
        Input ``[lon, lat]`` in degrees.
    start : array_like, shape (n, 2), optional
        Output ``[lon, lat]`` to start from, for example where one map alone puts the points.
        Where the map folds, the input is shown more than once and the search finds the
        copy nearest its start: without ``start``, the output pixel whose source is
        nearest, which may be the wrong copy.
    iterations : int
        Newton steps.
    tolerance : float
        In output pixels: positions whose source is farther than this from where it should
        be after the last step are NaN (the output does not show them, or the search
        failed, for example in a fold-over).

    Returns
    -------
    ndarray of float64, shape (n, 2)
        Output ``[lon, lat]`` in degrees; NaN where not found. Positions within half a pixel
        of the output's poles (beyond the first and last pixel rows) are not found.
    """
    m = check_inverse_map(inverse_map)
    width = m.shape[1]
    src = coords.lonlat_to_xyz(m)
    lonlat = np.asarray(lonlat, np.float64)
    if start is None:
        stride = max(1, width // 512)
        coarse = src[::stride, ::stride]
        _, nearest = spatial.cKDTree(coarse.reshape(-1, 3)).query(coords.lonlat_to_xyz(lonlat).reshape(-1, 3))
        row, col = np.divmod(nearest, coarse.shape[1])
        start = coords.px_to_lonlat(np.stack([col * stride, row * stride], axis=1).astype(np.float64), width)
    out = _forward_xyz(src, lonlat.reshape(-1, 2), np.asarray(start, np.float64).reshape(-1, 2), iterations, tolerance)
    return out.reshape(lonlat.shape)


def _forward_xyz(
    src: NDArray[np.floating], lonlat: NDArray[np.float64], start: NDArray[np.float64], iterations: int = 12, tolerance: float = 1e-3
) -> NDArray[np.float64]:
    """:func:`forward_points` on an inverse map as unit vectors (H, W, 3) or ``[lon, lat]`` (H, W, 2), from output ``[lon, lat]`` starts (n, 2)."""
    height, width = src.shape[:2]
    stride = max(1, width // 512)
    targets = coords.lonlat_to_xyz(lonlat).reshape(-1, 3)
    x, y = coords.lonlat_to_px(start.reshape(-1, 2), width).T
    east, north = coords.local_frame(coords.xyz_to_lonlat(targets))
    for _ in range(iterations):
        value, d_x, d_y = _bilinear(src, x, y)
        depth = np.sum(value * targets, axis=1)  # gnomonic coordinates about the target
        e = np.stack([np.sum(value * east, axis=1), np.sum(value * north, axis=1)], axis=1) / depth[:, None]
        jac = (
            np.stack(
                [
                    np.stack([np.sum(d_x * east, axis=1), np.sum(d_y * east, axis=1)], axis=1),
                    np.stack([np.sum(d_x * north, axis=1), np.sum(d_y * north, axis=1)], axis=1),
                ],
                axis=1,
            )
            / depth[:, None, None]
        )
        ok = np.abs(np.linalg.det(jac)) > 1e-300
        step = np.zeros_like(e)
        step[ok] = np.linalg.solve(jac[ok], -e[ok][..., None])[..., 0]
        step = np.clip(step, -4.0 * stride, 4.0 * stride)
        x, y = x + step[:, 0], np.clip(y + step[:, 1], 0.0, height - 1.0)
    value = _bilinear(src, x, y)[0]
    miss = np.degrees(np.arccos(np.clip(np.sum(value * targets, axis=1) / np.linalg.norm(value, axis=1), -1.0, 1.0)))
    out = coords.px_to_lonlat(np.stack([x % width, y], axis=1), width)
    out[miss * width / 360.0 > tolerance] = np.nan
    return out


def line_straightness(inverse_map: ArrayLike, samples: ArrayLike, width: int | None = None, start: ArrayLike | None = None) -> float:
    """How straight a line comes out: its output image's largest distance from its best straight fit.

    Parameters
    ----------
    inverse_map : array_like, shape (H, W, 2)
        See :func:`local_jacobians`.
    samples : array_like, shape (s, 2)
        Input ``[lon, lat]`` along the line (for example ``coords.geodesic(start, end, t)``).
    width : int, optional
        Pixels are counted at this image width (default: the map's).
    start : array_like, shape (s, 2), optional
        Where to start looking for the samples in the output (see :func:`forward_points`):
        give it (for example the line's own map applied to them) when the map may fold.

    Returns
    -------
    float
        In pixels; NaN if the output does not show every sample.
    """
    m = check_inverse_map(inverse_map)
    out = forward_points(m, samples, start=start)
    if not np.all(np.isfinite(out)):
        return float("nan")
    return straightness(out, width or m.shape[1], fit="best")


def dense_line(
    xyz_map: NDArray[np.floating], pieces: Sequence[tuple[ArrayLike, ArrayLike, Callable[[NDArray[np.float64]], NDArray[np.float64]]]]
) -> NDArray[np.float64]:
    """A line's output image found densely: at least one sample per output pixel of its arc, through a map.

    Parameters
    ----------
    xyz_map : ndarray, shape (H, W, 3) or (H, W, 2)
        The inverse map as unit vectors (``coords.lonlat_to_xyz(inverse_map)``), or as it
        is, ``[lon, lat]`` in degrees (then only the pixels the search reads are turned
        into unit vectors: cheaper for a few lines).
    pieces : sequence of (start, end, guess)
        The line's pieces in order: input ``[lon, lat]`` ends (2,) in degrees, and a
        function taking input ``[lon, lat]`` (n, 2) to where the output is expected to
        show them (for example a piece's own Möbius map), which starts the search.

    Returns
    -------
    ndarray of float64, shape (s, 2)
        Output ``[lon, lat]`` along the whole line, its pieces in order; NaN where the map
        does not show a sample (:func:`forward_points`).
    """
    width = xyz_map.shape[1]
    found = []
    for start, end, guess in pieces:
        coarse = guess(coords.geodesic(start, end, np.linspace(0.0, 1.0, DENSE_FIRST)))
        length = float(np.sum(coords.angular_distance(coarse[:-1], coarse[1:]))) * width / 360.0
        n = max(DENSE_FIRST, 2 * math.ceil(length) + 1)
        samples = coords.geodesic(start, end, np.linspace(0.0, 1.0, n))
        found.append(_forward_xyz(xyz_map, samples, guess(samples)))
    return np.concatenate(found)


def dense_straightness(inverse_map: ArrayLike, start: ArrayLike, end: ArrayLike, guess: Callable[[NDArray], NDArray] | None = None) -> float:
    """How straight a marked line comes out along its whole length, densely, in output pixels.

    Unlike :func:`line_straightness` on a line's constrained samples (where a blend's
    weights are 1 by construction), the line's great-circle arc from ``start`` to ``end``
    is sampled at least twice per output pixel of its image and each sample found through
    ``inverse_map``: pass the map that placed the pixels (``Result.placed_map()``).

    Parameters
    ----------
    inverse_map : array_like, shape (H, W, 2)
        See :func:`local_jacobians`.
    start, end : array_like, shape (2,)
        The line's input ends, ``[lon, lat]`` in degrees.
    guess : callable, optional
        Input ``[lon, lat]`` (n, 2) to where the output should show them, which starts the
        search (a line's own Möbius map, say); by default the nearest output pixel.

    Returns
    -------
    float
        The largest distance of the output image from its best straight fit, in pixels;
        NaN if the output does not show every sample.
    """
    m = check_inverse_map(inverse_map)
    if guess is None:
        def guess(lonlat: NDArray) -> NDArray:
            return forward_points(m, lonlat)

    out = dense_line(m, [(start, end, guess)])
    return straightness(out, m.shape[1], fit="best") if np.all(np.isfinite(out)) else math.nan


def coverage(inverse_map: ArrayLike, cells: int = 360) -> float:
    """The share of the input sphere's area that the output shows.

    The input sphere is cut into a ``cells`` x ``cells / 2`` equirectangular grid; a cell
    counts as shown if an output pixel shows a point in it or, failing that, if
    :func:`forward_points` finds an output position for its centre (so a region shown
    smaller than one pixel per cell still counts).

    Parameters
    ----------
    inverse_map : array_like, shape (H, W, 2)
    cells : int
        Cells around the equator (even).

    Returns
    -------
    float
        Between 0 and 1, each cell weighted by its area.
    """
    cells = whole_number(cells, "cells", 4, even=True)
    m = check_inverse_map(inverse_map)
    px = coords.lonlat_to_px(m.reshape(-1, 2), cells)
    col = np.floor(px[:, 0] + 0.5).astype(np.int64) % cells
    row = np.clip(np.floor(px[:, 1] + 0.5).astype(np.int64), 0, cells // 2 - 1)
    hit = np.zeros(cells * cells // 2, dtype=bool)
    hit[row * cells + col] = True
    missing = np.flatnonzero(~hit)
    if len(missing):
        centres = coords.px_to_lonlat(np.stack([missing % cells, missing // cells], axis=1).astype(np.float64), cells)
        hit[missing] = np.isfinite(forward_points(m, centres)[:, 0])
    area = np.repeat(coords.row_area(cells // 2), cells)
    return float(np.sum(area * hit))


def cage_motion(inverse_map: ArrayLike, vertices: ArrayLike, width: int | None = None) -> float:
    """How far the inside of a fixed cage moved.

    The largest distance between an output pixel inside the cage and the input position it
    shows.

    Parameters
    ----------
    inverse_map : array_like, shape (H, W, 2)
    vertices : array_like, shape (n, 2)
        The cage's ``[lon, lat]`` in degrees (its edges are great-circle arcs), smaller than
        a hemisphere.
    width : int, optional
        Pixels are counted at this image width (default: the map's).

    Returns
    -------
    float
        In pixels; 0 for a cage that holds its inside perfectly still.
    """
    m = check_inverse_map(inverse_map)
    corners = np.asarray(vertices, dtype=np.float64)
    if corners.ndim != 2 or corners.shape[1] != 2 or len(corners) < 3:
        raise ValueError(f"expected cage vertices of shape (n >= 3, 2), got {corners.shape}")
    lon, lat = coords.grid_lonlat(m.shape[1])
    grid = np.stack(np.meshgrid(lon, lat), axis=-1)
    inside = inside_polygon(grid, corners)
    if not inside.any():
        raise ValueError("no output pixel lies inside the cage")
    moved = coords.angular_distance(m[inside], grid[inside])
    return float(moved.max() * (width or m.shape[1]) / 360.0)


def tear(inverse_map: ArrayLike, width: int | None = None, max_abs_lat: float = 90.0) -> float:
    """The largest jump of an inverse map between neighbouring output pixels beyond its smooth stretch, in input pixels.

    Along a row or a column of output pixels a continuous warp shows input positions that
    move in steps changing smoothly from one pixel to the next: each step is the local
    stretch (a map that shrinks a region threefold shows neighbours 3 pixels apart), and
    consecutive steps differ by a small fraction of a pixel, vanishing as the output grows
    finer. Where the output tears, as along the seams of piecewise-constant weights, one
    step jumps across a gap of the input, and the step changes by about the gap's width.

    The tear is the largest change between consecutive steps, the second difference
    ``|(p[i+1] - p[i]) - (p[i] - p[i-1])|`` of the input positions ``p`` as 3D unit
    vectors, over every three consecutive output pixels along each row (columns wrap at
    the ±180° seam) and each column, counted in pixels of ``360 / width`` degrees (an
    input pixel's height, and its width on the equator). Measured on the sphere, it needs
    no special case for the ±180° wrap of longitude (the same place) or near the poles
    (where a large change of longitude is a small arc). The identity map gives
    about ``(2 pi / W)²`` radians, 0.012 px at W = 512; a tear of a gap ``g`` pixels gives
    about ``g``. The steps themselves (the plain jumps) are the map's stretch, not a tear.

    Parameters
    ----------
    inverse_map : array_like, shape (H, W, 2)
        For each output pixel centre the input ``[lon, lat]`` (degrees) it shows
        (``Result.inverse_map(np.float64)``).
    width : int, optional
        Pixels are counted at this input width (default: the map's; pass
        ``Result.source_width`` to count the input's own pixels).
    max_abs_lat : float
        Only output pixels within this latitude (degrees) count; every row by default.

    Returns
    -------
    float
        The largest change of step, in pixels.
    """
    m = check_inverse_map(inverse_map)
    width = m.shape[1] if width is None else whole_number(width, "width", 2)
    if not 0 < max_abs_lat <= 90:
        raise ValueError(f"max_abs_lat must be in (0, 90] degrees, got {max_abs_lat!r}")
    _, lat = coords.grid_lonlat(m.shape[1])
    rows = np.flatnonzero(np.abs(lat) <= max_abs_lat)
    if len(rows) == 0:
        raise ValueError(f"no output row lies within max_abs_lat = {max_abs_lat} degrees")
    src = coords.lonlat_to_xyz(m[rows[0] : rows[-1] + 1])
    along_rows = np.roll(src, -1, axis=1) - 2 * src + np.roll(src, 1, axis=1)
    along_columns = src[2:] - 2 * src[1:-1] + src[:-2]
    largest = max(np.linalg.norm(along_rows, axis=-1).max(), np.linalg.norm(along_columns, axis=-1).max(initial=0.0))
    return float(np.degrees(largest) * width / 360.0)


def displacement(inverse_map: ArrayLike) -> float:
    """How far a warp moves the sphere: the area-weighted mean distance from each output pixel to the input position it shows.

    Parameters
    ----------
    inverse_map : array_like, shape (H, W, 2)
        See :func:`local_jacobians`.

    Returns
    -------
    float
        In degrees; 0 for the identity.
    """
    m = check_inverse_map(inverse_map)
    return float(np.sum(_moved(m) * coords.row_area(m.shape[0])[:, None]))


def _moved(m: NDArray[np.floating]) -> NDArray[np.float64]:
    """Per output pixel, degrees from it to the input position it shows, (H, W)."""
    lon, lat = coords.grid_lonlat(m.shape[1])
    return coords.angular_distance(m, np.stack(np.meshgrid(lon, lat), axis=-1))


def near_mask(lonlat: ArrayLike, radius: float, width: int) -> NDArray[np.bool_]:
    """The pixels of a ``width x width/2`` grid within ``radius`` degrees of any of some points.

    Parameters
    ----------
    lonlat : array_like, shape (n, 2)
        Points ``[lon, lat]`` in degrees.
    radius : float
        Degrees, 0 to 180.
    width : int
        Grid width (even).

    Returns
    -------
    ndarray of bool, shape (width / 2, width)
        Exact at pixel centres: each point covers, on each row, the longitudes within
        ``radius`` of it, an interval painted in one pass (no per-pixel search).
    """
    points = np.asarray(lonlat, dtype=np.float64).reshape(-1, 2) if np.size(lonlat) else np.empty((0, 2))
    if not np.all(np.isfinite(points)):
        raise ValueError("the points must be finite [lon, lat] pairs")
    if not 0 <= radius <= 180:
        raise ValueError(f"radius must be in [0, 180] degrees, got {radius!r}")
    _, lat = coords.grid_lonlat(width)
    height, step = width // 2, 360.0 / width
    phi, phi_p = np.radians(lat)[:, None], np.radians(points[:, 1])[None, :]
    with np.errstate(divide="ignore", invalid="ignore"):
        c = (math.cos(math.radians(radius)) - np.sin(phi) * np.sin(phi_p)) / (np.cos(phi) * np.cos(phi_p))
    c = np.nan_to_num(c, nan=2.0, posinf=2.0, neginf=-2.0)  # a point on a pole: covers whole rows or none
    row, col = np.nonzero(c <= 1.0)
    half = np.degrees(np.arccos(np.clip(c[row, col], -1.0, 1.0)))
    centre = (points[col, 0] + 180.0) / step - 0.5  # in pixel columns
    first = np.ceil(centre - half / step).astype(np.int64)
    last = np.floor(centre + half / step).astype(np.int64)
    whole = (last - first + 1 >= width) | (c[row, col] <= -1.0)
    some = whole | (last >= first)  # an interval narrower than a pixel may hold no pixel centre
    row, first, last, whole = row[some], first[some], last[some], whole[some]
    mask = np.zeros((height, width + 1), dtype=np.int64)
    np.add.at(mask, (row[whole], 0), 1)
    np.add.at(mask, (row[whole], width), -1)
    row, first, last = row[~whole], first[~whole], last[~whole]
    first_w, last_w = np.mod(first, width), np.mod(last, width)
    wraps = first_w > last_w  # the interval crosses the ±180° seam: two pieces
    np.add.at(mask, (row, first_w), 1)
    np.add.at(mask, (row, np.where(wraps, width, last_w + 1)), -1)
    np.add.at(mask, (row[wraps], 0), 1)
    np.add.at(mask, (row[wraps], last_w[wraps] + 1), -1)
    return np.cumsum(mask, axis=1)[:, :width] > 0


@dataclass(frozen=True)
class FarField:
    """Figures of the output sphere far from every handle (:func:`far_field`).

    Attributes
    ----------
    distance : float
        Degrees from every handle's output position: the far field begins there.
    share : float
        Its share of the sphere, 0 to 1.
    displacement : float
        Mean distance its content moved, degrees (as :func:`displacement`).
    distortion_mean, distortion_p99 : float
        Conformal distortion there, within ±80° (as :func:`conformal_distortion`); NaN if
        the far field has no such pixel.
    fold_over : float
        Share of the far field turned over, 0 to 1.
    """

    distance: float
    share: float
    displacement: float
    distortion_mean: float
    distortion_p99: float
    fold_over: float


def far_field(
    inverse_map: ArrayLike,
    handle_points: ArrayLike,
    distance: float = FAR_FIELD,
    *,
    distortion: Distortion | None = None,
    folds: NDArray[np.bool_] | None = None,
) -> FarField:
    """The quality figures of the part of the output farther than ``distance`` from every handle.

    Parameters
    ----------
    inverse_map : array_like, shape (H, W, 2)
        See :func:`local_jacobians`.
    handle_points : array_like, shape (n, 2)
        Where the handles are in the output, ``[lon, lat]`` (``Result.constraints.points``
        as lon/lat: every line's and cage edge's samples and every point's target).
    distance : float
        Degrees; :data:`FAR_FIELD` by default.
    distortion : Distortion, optional
        Of this map, if already computed (:func:`conformal_distortion`).
    folds : ndarray of bool, shape (H, W), optional
        Where the map folds, if already known (``Result.folds.mask``); else
        :func:`fold_over` finds it.

    Returns
    -------
    FarField
        With no handle the whole sphere is far.
    """
    m = check_inverse_map(inverse_map)
    height, width = m.shape[:2]
    far = ~near_mask(handle_points, distance, width)
    area = coords.row_area(height)[:, None]
    share = float(np.sum(far * area))
    if distortion is None:
        distortion = conformal_distortion(m)
    if folds is None:
        folds = fold_over(m).mask
    if share == 0:
        return FarField(float(distance), 0.0, math.nan, math.nan, math.nan, math.nan)
    mean, p99 = _distortion_figures(distortion.per_pixel, far, distortion.max_abs_lat)
    return FarField(
        distance=float(distance),
        share=share,
        displacement=float(np.sum(_moved(m) * far * area) / share),
        distortion_mean=mean,
        distortion_p99=p99,
        fold_over=float(np.sum(folds * far * area) / share),
    )


@dataclass(frozen=True)
class Summary:
    """The quality figures of one warp, each measured from its inverse map (see :func:`summary`).

    Attributes
    ----------
    method : str
        What made the warp: ``"bbw"`` for :func:`omniwidget.warp`, else the baseline's name.
    lines : tuple of float
        Each straight segment's largest distance from its best straight fit in the output,
        in output pixels, measured along its whole arc (:func:`dense_line`, not only at the
        constrained samples): one per line piece, a line cut for its length measured whole
        (``constraints.chains``); NaN for one the output does not show.
    distortion_mean, distortion_p99 : float
        Conformal distortion, area-weighted mean and 99th percentile within ±80°
        (:func:`conformal_distortion`).
    fold_over : float
        Share of the sphere turned over (:attr:`Result.folds`), 0 to 1.
    tear : float
        The largest jump of the map between neighbouring output pixels beyond its smooth
        stretch, in output pixels (:func:`tear`).
    coverage : float
        Share of the input sphere shown (:func:`coverage`), 0 to 1.
    displacement : float
        Mean distance the sphere moved, degrees (:func:`displacement`).
    cage_motion : float or None
        The largest motion inside a cage whose vertices stay, in output pixels
        (:func:`cage_motion`); None without such a cage.
    seconds : float
        The warp's own time (the sum of its ``timings``), not the measuring.
    width : int
        Width of the output, the pixels the figures count in.
    far : FarField or None
        The same figures on the output farther than :data:`FAR_FIELD` from every handle
        (:func:`far_field`), where a person expects nothing to move.
    line_handles : tuple of int
        The handle each entry of ``lines`` belongs to (empty when not known).
    kept : tuple of (int, str)
        Lines kept as they are on purpose, which no one asked to be straight: the handle and
        why, ``"pole"`` (a rectified line over or close to a pole, which the still background
        keeps as it is: :attr:`~omniwidget.method.constraints.Constraints.near_pole`) or
        ``"held"`` (a line neither rectified nor given targets: its map is the identity).
        :meth:`line` measures the other lines and names these apart; ``lines``,
        :attr:`straightness` and :attr:`relaxed` still count them.
    """

    method: str
    lines: tuple[float, ...]
    distortion_mean: float
    distortion_p99: float
    fold_over: float
    tear: float
    coverage: float
    displacement: float
    cage_motion: float | None
    seconds: float
    width: int
    far: FarField | None = None
    line_handles: tuple[int, ...] = ()
    kept: tuple[tuple[int, str], ...] = ()

    @property
    def relaxed(self) -> tuple[tuple[int, float], ...]:
        """The lines farther than :data:`RELAXED_PX` from straight: ``(handle index, px)`` each, worst first.

        A rectified line gives way where the map had to be untangled around it
        (:mod:`omniwidget.raster.untangle`) or where other handles pull on it; a line not
        shown at all counts as NaN. Needs ``line_handles`` (as :func:`summary` fills it).
        """
        found = [(h, v) for h, v in zip(self.line_handles, self.lines, strict=False) if not v <= RELAXED_PX]
        return tuple(sorted(found, key=lambda hv: -hv[1] if math.isfinite(hv[1]) else -math.inf))

    @property
    def straightness(self) -> float:
        """The worst line's distance from straight, in pixels (NaN without lines, or if one is not shown)."""
        if not self.lines:
            return math.nan
        return math.nan if any(math.isnan(v) for v in self.lines) else max(self.lines)

    def line(self) -> str:
        """The figures in one line of text, as the editor shows them: what matters first.

        The straightness headline measures the lines asked to be straight; lines kept as they
        are on purpose (:attr:`kept`) are named apart ("1 line over a pole kept as it is"),
        since their distance from straight says nothing of the warp. Relaxed lines are
        named, three at most and a count of the others.

        Examples
        --------
        >>> Summary("bbw", (0.1, 0.25), 0.031, 0.42, 0.0, 0.3, 1.0, 0.12, None, 0.2, 2048).line()
        'lines within 0.25 px · folds 0% · sphere shown 100% · moved 0.12° on average · distortion 0.031 (p99 0.42)'
        >>> Summary("bbw", (0.1, 55.0), 0.031, 0.42, 0.0, 0.3, 1.0, 0.12, None, 0.2, 2048,
        ...         line_handles=(0, 1), kept=((1, "pole"),)).line().split(" · ")[:2]
        ['lines within 0.1 px', '1 line over a pole kept as it is']
        """
        kept = {h for h, _ in self.kept}
        measured = [v for h, v in self._handle_lines() if h not in kept]
        parts = []
        if self.lines:
            shown = [v for v in measured if not math.isnan(v)]
            hidden = len(measured) - len(shown)
            if shown:
                parts.append(f"lines within {max(shown):.2g} px" + (f", {hidden} not shown" if hidden else ""))
            elif hidden:
                parts.append("no line is shown" if hidden > 1 else "the line is not shown")
        for why, one, many in (("pole", "line over a pole kept as it is", "lines over a pole kept as they are"), ("held", "line held as drawn", "lines held as drawn")):
            n = sum(1 for _, w in self.kept if w == why)
            if n:
                parts.append(f"1 {one}" if n == 1 else f"{n} {many}")
        parts += [
            f"folds {100 * self.fold_over:.2g}%",
            f"sphere shown {100 * self.coverage:.3g}%",
            f"moved {self.displacement:.2g}° on average",
            f"distortion {self.distortion_mean:.2g} (p99 {self.distortion_p99:.2g})",
        ]
        if self.cage_motion is not None:
            parts.append(f"cages still to {self.cage_motion:.2g} px")
        relaxed = [(h, v) for h, v in self.relaxed if h not in kept]
        for h, v in relaxed[:3]:
            parts.append(f"handles[{h}] (line) relaxed to {v:.2g} px" if math.isfinite(v) else f"handles[{h}] (line) not shown")
        if len(relaxed) > 3:
            parts.append(f"{len(relaxed) - 3} more line{'s' * (len(relaxed) > 4)} relaxed")
        if self.far is not None and self.far.share > 0:
            far = self.far.displacement
            parts.append(f"far from the handles moved {far:.2g}°" if far >= 0.005 else "far from the handles still")
        return " · ".join(parts)

    def _handle_lines(self) -> list[tuple[int, float]]:
        """``(handle, px)`` per entry of :attr:`lines`; handle -1 where :attr:`line_handles` is not known."""
        if len(self.line_handles) == len(self.lines):
            return list(zip(self.line_handles, self.lines, strict=True))
        return [(-1, v) for v in self.lines]

    def as_dict(self) -> dict[str, Any]:
        """The figures as plain numbers (JSON-ready: NaN becomes None), with ``straightness`` the worst line.

        Returns
        -------
        dict of str
        """

        def plain(v: Any) -> Any:
            if isinstance(v, tuple):
                return [plain(x) for x in v]
            if isinstance(v, FarField):
                return {k: plain(x) for k, x in v.__dict__.items()}
            return None if isinstance(v, float) and math.isnan(v) else v

        out = {k: plain(v) for k, v in self.__dict__.items()}
        out["straightness"] = plain(self.straightness)
        return out


def chain_straightness(result: Any, placed: NDArray[np.floating] | None = None) -> tuple[float, ...]:
    """Each straight output segment's distance from straight, measured densely through the map that placed the pixels.

    Parameters
    ----------
    result : Result
        Of :func:`omniwidget.warp` or a baseline: with ``constraints`` (its ``lines`` and
        ``chains``), ``controls``, and ``placed_map()`` or ``inverse_map()``.
    placed : ndarray, shape (H, W, 2), optional
        The map to measure through (default: ``result.placed_map()``).

    Returns
    -------
    tuple of float
        One per chain (a line cut into pieces is measured whole), in output pixels; NaN
        for one the output does not show (:func:`dense_line`, each piece's search started
        from its own Möbius map).
    """
    if placed is None:
        placed = result.placed_map() if hasattr(result, "placed_map") else result.inverse_map(np.float64)
    lines, controls = result.constraints.lines, result.controls
    out = []
    for chain in result.constraints.chains:
        curve = dense_line(placed, [(lines[k][1][0], lines[k][1][-1], controls[lines[k][0]].moebius) for k in chain])
        out.append(straightness(curve, placed.shape[1], fit="best") if np.all(np.isfinite(curve)) else math.nan)
    return tuple(out)


def summary(result: Any) -> Summary:
    """Every quality figure of one warp: straightness, distortion, fold-over, tear, coverage, displacement, cages.

    Parameters
    ----------
    result : Result
        Of :func:`omniwidget.warp` or of a baseline (:mod:`omniwidget.evaluate.baselines`):
        anything with ``inverse_map()``, ``forward_points()``, ``folds``, ``constraints``,
        ``handles`` and ``timings``.

    Returns
    -------
    Summary

    Notes
    -----
    Lines are measured along their whole length, densely (:func:`dense_line`: at least two
    samples per output pixel), through the map that placed the pixels
    (``result.placed_map()``), each piece's search started from its own Möbius map, so a
    line is measured where it is even where the map folds elsewhere.
    """
    m = result.inverse_map(np.float64)
    width = m.shape[1]
    lines = chain_straightness(result, result.placed_map() if hasattr(result, "placed_map") else m)
    distortion = conformal_distortion(m)
    far = far_field(m, coords.xyz_to_lonlat(result.constraints.points), distortion=distortion, folds=result.folds.mask)
    fixed = [h.vertices for h in result.handles.handles if isinstance(h, CageHandle) and h.finals == h.vertices]
    return Summary(
        method=getattr(result, "method", "bbw"),
        lines=lines,
        distortion_mean=distortion.mean,
        distortion_p99=distortion.p99,
        fold_over=result.folds.area,
        tear=tear(m),
        coverage=coverage(m),
        displacement=displacement(m),
        cage_motion=max(cage_motion(m, v) for v in fixed) if fixed else None,
        seconds=float(sum(result.timings.values())),
        width=width,
        far=far,
        line_handles=tuple(int(result.controls[result.constraints.lines[chain[0]][0]].handle) for chain in result.constraints.chains),
        kept=kept_lines(result.handles, result.constraints),
    )


def kept_lines(handles: Any, constraints: Any) -> tuple[tuple[int, str], ...]:
    """The lines a warp keeps as they are on purpose (:attr:`Summary.kept`), by handle index.

    Parameters
    ----------
    handles : Handles
        The document warped.
    constraints : Constraints
        Its constraints (``near_pole``: the rectified lines over or close to a pole).

    Returns
    -------
    tuple of (int, str)
        ``(index, "pole")`` for a rectified line over or close to a pole that the still
        background keeps as it is (the paper's mode, ``anchor`` None, moves it: not kept);
        ``(index, "held")`` for a line neither rectified nor given targets; in handle order.
    """
    pole = {int(i) for i, _ in constraints.near_pole} if handles.options.anchor is not None else set()
    found = []
    for i, h in enumerate(handles.handles):
        if i in pole:
            found.append((i, "pole"))
        elif isinstance(h, LineHandle) and not h.rectify and h.targets is None:
            found.append((i, "held"))
    return tuple(found)


# --- fidelity to what the handles ask ---------------------------------------------------

#: Arc (degrees) between the samples :func:`kink` takes along a line.
KINK_STEP = 0.25


@dataclass(frozen=True)
class PointFidelity:
    """How faithfully a warp carries out one point handle (:func:`point_fidelity`).

    Attributes
    ----------
    centre_px : float
        Distance, in output pixels, from the handle's target to where its position lands
        in the output; ``inf`` if the search for it fails (the output folds there).
    zoom_error : float
        ``|sqrt(det J) / sqrt(det J_exact) - 1|`` of the inverse map's Jacobians at the
        target, the warp's and the handle's own map's: the relative error of the
        magnification (0.01 is 1%); ``inf`` where the warp turns the image over
        (``det J <= 0``).
    rotation_error : float
        Degrees, 0 to 180: the angle between the two Jacobians' rotations.
    """

    centre_px: float
    zoom_error: float
    rotation_error: float


def _tangent_frame(lonlat: ArrayLike) -> NDArray[np.float64]:
    """Rows: the unit vector of ``lonlat`` and its east and north directions, (3, 3)."""
    east, north = coords.local_frame(lonlat)
    return np.stack([coords.lonlat_to_xyz(lonlat), east, north])


def _to_plane(xyz: NDArray[np.float64], frame: NDArray[np.float64]) -> NDArray[np.float64]:
    """Gnomonic coordinates (east, north) of unit vectors ``xyz`` (..., 3) about ``frame[0]``; NaN beyond its hemisphere."""
    local = xyz @ frame.T
    with np.errstate(divide="ignore", invalid="ignore"):
        out = local[..., 1:] / local[..., :1]
    out[local[..., 0] <= 0] = np.nan
    return out


def _from_plane(xy: NDArray[np.float64], frame: NDArray[np.float64]) -> NDArray[np.float64]:
    """``[lon, lat]`` of gnomonic coordinates ``xy`` (..., 2) about ``frame[0]``."""
    return coords.xyz_to_lonlat(frame[0] + xy[..., :1] * frame[1] + xy[..., 1:] * frame[2])


def _handle_at(result: Any, index: object, kind: type) -> Any:
    """``result.handles.handles[index]``, checked to be a ``kind``."""
    handles = result.handles.handles
    index = whole_number(index, "index", 0)
    if index >= len(handles):
        raise ValueError(f"index {index} is out of range: the document has {len(handles)} handles")
    handle = handles[index]
    if not isinstance(handle, kind):
        raise ValueError(f"handles[{index}] is a {handle.kind} handle, not a {kind.__name__}")
    return handle


def point_fidelity(result: Any, index: int) -> PointFidelity:
    """How faithfully a warp moves, zooms and turns the content of one point handle.

    A point handle asks for its own Möbius map ``M`` (:meth:`PointHandle.moebius`) near its
    target; the blend of many maps gives something else. With ``W`` the output width, both
    inverse maps, the warp's (``result.inverse_points``) and the exact ``M.inverse``, are
    differentiated at the target ``t = M(position)`` by central differences over ±2 output
    pixels (``h = 2 * 360 / W`` degrees), on one stencil. The differences are taken in
    gnomonic coordinates (east, north): about ``t`` in the output, and in the input about
    the point each map shows at ``t`` (``position`` for the exact map), so the 2 x 2
    Jacobians ``J`` and ``J_exact`` are in the image's local east/north frames there, at any
    latitude, the poles included (a warp that only shifts the content, without turning it
    in the image, has no rotation error even near a pole, where east turns quickly).

    Parameters
    ----------
    result : Result
        Of :func:`omniwidget.warp` (anything with ``handles``, ``image`` and
        ``inverse_points``).
    index : int
        Of a point handle in ``result.handles.handles``.

    Returns
    -------
    PointFidelity
        ``zoom_error``: ``|sqrt(det J) / sqrt(det J_exact) - 1|``; ``rotation_error``: the
        angle between the rotation parts of ``J`` and ``J_exact`` (each the angle of
        ``J + adj(J)^T``, which is the rotation of the polar decomposition when
        ``det J > 0``), degrees; ``centre_px``: two Newton steps
        ``q <- q + J^-1 (position - inverse(q))`` from ``t`` in the output's tangent plane
        find where ``position`` lands, and this is its distance from ``t`` in output pixels.

    Raises
    ------
    ValueError
        If ``index`` is not the index of a point handle.

    Notes
    -----
    A warp by the handle's own map alone (a single point handle and ``"anchor": null``)
    gives 0 for all three. The central differences' own error is ``O(h^2)``: it shrinks
    16-fold when the width is quadrupled.
    """
    handle = _handle_at(result, index, PointHandle)
    width = int(result.image.shape[1])
    exact = handle.moebius()
    position = np.asarray(handle.position, dtype=np.float64)
    target = exact(position)
    out_frame = _tangent_frame(target)
    h = math.tan(math.radians(2 * 360.0 / width))
    stencil = _from_plane(h * np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0]]), out_frame)

    def jacobian(inverse: Any, frame: NDArray[np.float64]) -> NDArray[np.float64]:
        g = _to_plane(coords.lonlat_to_xyz(inverse(stencil)), frame)
        return np.stack([g[0] - g[1], g[2] - g[3]], axis=1) / (2 * h)  # columns: d/d east, d/d north

    # each Jacobian in the east/north frame of the input point it starts from: the warp's where it shows the target
    in_frame = _tangent_frame(np.asarray(result.inverse_points(target), dtype=np.float64))
    jac, jac_exact = jacobian(result.inverse_points, in_frame), jacobian(exact.inverse, _tangent_frame(position))
    det, det_exact = np.linalg.det(jac), np.linalg.det(jac_exact)
    zoom = abs(math.sqrt(det / det_exact) - 1.0) if det > 0 else math.inf

    def angle(j: NDArray[np.float64]) -> float:
        return math.degrees(math.atan2(j[1, 0] - j[0, 1], j[0, 0] + j[1, 1]))

    turn = abs((angle(jac) - angle(jac_exact) + 180.0) % 360.0 - 180.0)
    q = np.zeros(2)
    centre = math.inf
    if np.all(np.isfinite(jac)) and det != 0:
        wanted = _to_plane(coords.lonlat_to_xyz(position), in_frame)
        for _ in range(2):
            shown = _to_plane(coords.lonlat_to_xyz(result.inverse_points(_from_plane(q, out_frame))), in_frame)
            q = q + np.linalg.solve(jac, wanted - shown)
        if np.all(np.isfinite(q)):
            centre = float(coords.angular_distance(_from_plane(q, out_frame), _from_plane(np.zeros(2), out_frame))) * width / 360.0
    return PointFidelity(centre_px=centre, zoom_error=float(zoom), rotation_error=float(turn))


def cage_fidelity(result: Any, index: int, rotation: ArrayLike | None = None) -> float:
    """How rigidly a warp carries the inside of a cage: the largest error of its motion, in output pixels.

    A cage moved rigidly (its targets its vertices turned by a rotation ``R`` of the sphere)
    asks for its inside to move with it: the output at ``q`` inside the cage's final
    polygon should show the input at ``R.T @ q``. This is the largest angular distance,
    over the output pixel centres inside the final polygon (:func:`inside_polygon` on
    ``finals``), between the input position the warp shows there
    (``result.inverse_map(np.float64)``) and ``R.T @ q``.

    Parameters
    ----------
    result : Result
        Of :func:`omniwidget.warp` (anything with ``handles`` and ``inverse_map``).
    index : int
        Of a cage handle in ``result.handles.handles``.
    rotation : array_like, shape (3, 3), optional
        ``R``, a proper rotation acting on unit vectors (``R @ xyz``), for example the one
        that made the targets. By default the best rotation of the vertices onto their
        targets (:meth:`CageHandle.rotation <omniwidget.document.handles.CageHandle.rotation>`); the identity for a cage that stays, and then this
        is :func:`cage_motion`.

    Returns
    -------
    float
        In pixels of the output's width; 0 for an inside that moves exactly rigidly.

    Raises
    ------
    ValueError
        If ``index`` is not a cage's, ``rotation`` is not a proper rotation, or no output
        pixel centre lies inside the cage.
    """
    cage = _handle_at(result, index, CageHandle)
    if rotation is None:
        r = cage.rotation()
    else:
        r = np.asarray(rotation, dtype=np.float64)
        if r.shape != (3, 3) or not np.all(np.isfinite(r)) or not np.allclose(r @ r.T, np.eye(3), atol=1e-9) or np.linalg.det(r) <= 0:
            raise ValueError("rotation must be a proper 3 x 3 rotation matrix (orthonormal, determinant +1)")
    m = check_inverse_map(result.inverse_map(np.float64))
    width = m.shape[1]
    lon, lat = coords.grid_lonlat(width)
    grid = np.stack(np.meshgrid(lon, lat), axis=-1)
    inside = inside_polygon(grid, cage.finals)
    if not inside.any():
        raise ValueError(f"no output pixel centre lies inside the cage handles[{index}]")
    expected = coords.lonlat_to_xyz(grid[inside]) @ r  # rows q: (R.T q).T = q.T R
    shown = coords.lonlat_to_xyz(m[inside])
    error = np.arctan2(np.linalg.norm(np.cross(shown, expected), axis=1), np.sum(shown * expected, axis=1))
    return float(np.degrees(error.max()) * width / 360.0)


def kink_of_curve(curve: ArrayLike, step: float = KINK_STEP, window: float = 1.0) -> float:
    """The fastest turn of a polyline in the equirectangular image plane, degrees of turn per degree of arc.

    Parameters
    ----------
    curve : array_like, shape (n, 2)
        ``[lon, lat]`` in degrees of consecutive samples taken ``step`` degrees of arc apart
        along a line (for example where a line's samples land in a warp's output).
        Longitudes are unwrapped along the curve, so a curve across the ±180° seam is
        measured as it looks when the image is scrolled.
    step : float
        Degrees of arc between consecutive samples, ``> 0``.
    window : float
        Degrees of arc, at least ``step``: the turn is measured over ``k = round(window / step)``
        samples.

    Returns
    -------
    float
        With ``theta_i`` the direction of segment ``i`` (``atan2`` of its latitude and
        longitude steps, degrees, unwrapped along the curve): ``max |theta_{i+k} - theta_i|``
        over the curve, divided by ``k * step``. 0 for a straight polyline; a corner of
        ``a`` degrees gives ``a / window``; a circle of radius ``r`` degrees of the image
        plane, sampled every ``step`` degrees of its own length, gives ``180 / (pi r)``.

    Raises
    ------
    ValueError
        For a curve of the wrong shape, with non-finite positions, or shorter than
        ``k + 2`` samples.
    """
    pts = np.array(curve, dtype=np.float64)
    if not (isinstance(step, int | float) and math.isfinite(step) and step > 0):
        raise ValueError(f"step must be a positive number of degrees, got {step!r}")
    if not (isinstance(window, int | float) and math.isfinite(window) and window >= step):
        raise ValueError(f"window must be a number of degrees of at least step ({step}), got {window!r}")
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise ValueError(f"expected a curve of shape (n, 2), got {pts.shape}")
    if not np.all(np.isfinite(pts)):
        raise ValueError("the curve has NaN or infinite positions")
    k = max(1, round(window / step))
    if len(pts) < k + 2:
        raise ValueError(f"the curve needs at least {k + 2} samples for a window of {window} degrees, got {len(pts)}")
    pts[:, 0] = np.unwrap(pts[:, 0], period=360.0)
    d = np.diff(pts, axis=0)
    theta = np.degrees(np.unwrap(np.arctan2(d[:, 1], d[:, 0])))
    return float(np.max(np.abs(theta[k:] - theta[:-k])) / (k * step))


def _arc_position(p: NDArray[np.float64], u: NDArray[np.float64], v: NDArray[np.float64]) -> float:
    """Degrees of arc from ``u`` towards ``v`` (orthonormal) to the unit vector ``p``."""
    return math.degrees(math.atan2(float(p @ v), float(p @ u)))


def kink(
    inverse_map: ArrayLike | None,
    line: ArrayLike,
    marked_start: ArrayLike,
    marked_end: ArrayLike,
    beyond: float = 20.0,
    window: float = 1.0,
    max_abs_lat: float = 70.0,
) -> float:
    """How sharply a straight edge turns in the output where it leaves the part of it that was marked ("no kinks").

    A line handle straightens the piece of an edge it marks; the rest of the edge, unmarked,
    should carry on without a kink where the straightened piece ends. Samples are taken
    every :data:`KINK_STEP` (0.25) degrees of arc along the edge's great circle, from
    ``beyond`` degrees before the marked piece to ``beyond`` degrees after it (clipped to
    the edge's own ends), leaving out those farther than ``max_abs_lat`` from the equator
    (the image plane's directions mean little near the poles). They are found in the
    output (:func:`forward_points`, starting from their input positions; those not found
    start again from where their nearest found neighbour landed), and the figure is the
    fastest turn of the output polyline in the equirectangular image plane
    (:func:`kink_of_curve`), over any ``window`` degrees of arc. Where samples are left
    out or not found, the polyline is cut there and each part measured on its own.

    Parameters
    ----------
    inverse_map : array_like of shape (H, W, 2), or None
        For each output pixel centre the input ``[lon, lat]`` it shows
        (``Result.inverse_map(np.float64)``). ``None`` measures the input itself (the
        identity map): the edge's own turn in the input panorama, the reference for the
        output's figure.
    line : array_like, shape (2, 2)
        ``[lon, lat]`` in degrees of the edge's two ends: the full great-circle arc of a
        straight edge of the scene (shorter than 180°).
    marked_start, marked_end : array_like, shape (2,)
        ``[lon, lat]`` of the marked piece's ends, on that arc (within 0.01°).
    beyond : float
        Degrees of arc measured on each side of the marked piece, ``>= 0``.
    window : float
        Degrees of arc over which the turn is measured, at least :data:`KINK_STEP`.
    max_abs_lat : float
        Degrees, in (0, 90].

    Returns
    -------
    float
        The largest turn of the output's polyline over ``window`` degrees of arc, divided by
        ``window``: degrees of turn per degree of arc. NaN if no part of at least
        ``window`` degrees is left to measure.

    Raises
    ------
    ValueError
        If an argument is out of range, or the marked ends are not on the line.

    Notes
    -----
    A great circle is curved in the equirectangular image (except meridians and the
    equator), so the input has a figure of its own: 0 for the equator and the meridians,
    a few degrees of turn per degree of arc at most for the edges of the generated rooms
    (:func:`omniwidget.evaluate.scenes.family_scene`; the figures are in ``bench/RESULTS.md``),
    more where an edge climbs towards a pole.
    A marked piece straightened by its own Möbius map and an unmarked remainder left where
    it was meet in a turn of about the angle between them, spread over the blend's
    transition: a faithful warp keeps the output's figure close to the input's.

    The samples are found on the map's bilinear interpolation to about ``1e-3`` output
    pixels, and they are ``0.25 * W / 360`` pixels apart, so a turn is measured to about
    0.1 degree per degree at ``W = 512`` and 0.01 at 2048: compare figures at 1024 or wider.
    """
    ends = np.asarray(line, dtype=np.float64)
    marked = np.array([np.asarray(marked_start, dtype=np.float64), np.asarray(marked_end, dtype=np.float64)])
    if ends.shape != (2, 2) or marked.shape != (2, 2) or not (np.all(np.isfinite(ends)) and np.all(np.isfinite(marked))):
        raise ValueError("line must be two finite [lon, lat] ends, (2, 2), and marked_start and marked_end one finite [lon, lat] each")
    for name, value, lo in (("beyond", beyond, 0.0), ("window", window, KINK_STEP)):
        if not (isinstance(value, int | float) and math.isfinite(value) and value >= lo):
            raise ValueError(f"{name} must be a number of degrees, at least {lo}, got {value!r}")
    if not (isinstance(max_abs_lat, int | float) and 0 < max_abs_lat <= 90):
        raise ValueError(f"max_abs_lat must be in (0, 90] degrees, got {max_abs_lat!r}")
    a, b = coords.lonlat_to_xyz(ends)
    normal = np.cross(a, b)
    if np.linalg.norm(normal) < 1e-9 or a @ b < -1 + 1e-12:
        raise ValueError("the line's ends coincide or are antipodal: its great circle is not defined")
    normal /= np.linalg.norm(normal)
    v = np.cross(normal, a)
    length = _arc_position(b, a, v)
    along = []
    for p in coords.lonlat_to_xyz(marked):
        position = _arc_position(p, a, v)
        if abs(float(p @ normal)) > math.sin(math.radians(0.01)) or not -0.01 <= position <= length + 0.01:
            raise ValueError(f"the marked end {coords.xyz_to_lonlat(p).round(4).tolist()} is not on the line (within 0.01 degrees)")
        along.append(position)
    first, last = max(0.0, min(along) - beyond), min(length, max(along) + beyond)
    s = first + KINK_STEP * np.arange(int(math.floor((last - first) / KINK_STEP + 1e-9)) + 1)
    phi = np.radians(s)[:, None]
    samples = coords.xyz_to_lonlat(np.cos(phi) * a + np.sin(phi) * v)
    keep = np.abs(samples[:, 1]) <= max_abs_lat
    if inverse_map is None:
        out = samples.copy()
    else:
        m = check_inverse_map(inverse_map)
        out = np.full_like(samples, np.nan)
        out[keep] = forward_points(m, samples[keep], start=samples[keep])
        for _ in range(3):  # start the lost ones again from their nearest found neighbour along the line
            found = np.flatnonzero(keep & np.isfinite(out[:, 0]))
            lost = np.flatnonzero(keep & ~np.isfinite(out[:, 0]))
            if len(lost) == 0 or len(found) == 0:
                break
            near = found[np.argmin(np.abs(lost[:, None] - found[None]), axis=1)]
            offset = samples[lost] - samples[near]
            offset[:, 0] = (offset[:, 0] + 180.0) % 360.0 - 180.0
            again = forward_points(m, samples[lost], start=out[near] + offset)
            if not np.isfinite(again[:, 0]).any():
                break
            out[lost] = again
    good = keep & np.isfinite(out[:, 0])
    k = max(1, round(window / KINK_STEP))
    worst = math.nan
    for part in np.split(np.arange(len(s)), np.flatnonzero(np.diff(good.astype(np.int8)) != 0) + 1):
        if good[part[0]] and len(part) >= k + 2:
            value = kink_of_curve(out[part], KINK_STEP, window)
            worst = value if math.isnan(worst) else max(worst, value)
    return worst


def point_reach_profile(result: Any, index: int, distances: ArrayLike, directions: int = 24, step: float = 0.02) -> dict[str, NDArray]:
    """What a point handle's turn and zoom do as a function of the distance from its target.

    On rings of ``directions`` output points at each distance from the handle's target the
    warp's inverse map (``result.inverse_points``, the blend the image is resampled by,
    exact at any point) is differentiated by central differences of ``step`` degrees in
    tangent (gnomonic) frames, in the output about the point and in the input about what it
    shows.

    Parameters
    ----------
    result : Result or Deformation
        Anything with ``handles`` and ``inverse_points``.
    index : int
        Of a point handle.
    distances : array_like of float, shape (m,)
        Degrees from the target, each > ``step``.
    directions : int
    step : float
        Degrees.

    Returns
    -------
    dict of str to ndarray of float64, each shape (m, directions)
        ``"magnification"``: one over the mean of the inverse Jacobian's singular values
        (the forward map's scale); ``"rotation"``: degrees counter-clockwise, how far the
        ring is turned about the target, the content's bearing from the handle's position
        (carried to the target by the handle's shift) against the output's; ``"moved"``:
        degrees between each output point and the input point it shows; ``"det"``: the
        inverse Jacobian's determinant (``<= 0``: a fold).
    """
    h = result.handles.handles[index]
    if not isinstance(h, PointHandle):
        raise ValueError(f"handles[{index}] is a {h.kind} handle, not a point")
    dist = np.radians(np.asarray(distances, np.float64).reshape(-1))
    centre = coords.lonlat_to_xyz(h.final)

    def frame(p: NDArray) -> tuple[NDArray, NDArray]:
        a = np.where(np.abs(p[..., :1]) < 0.9, np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0]))
        e1 = np.cross(p, a)
        e1 /= np.linalg.norm(e1, axis=-1, keepdims=True)
        return e1, np.cross(p, e1)

    c1, c2 = frame(centre)
    beta = np.linspace(0.0, 2.0 * math.pi, directions, endpoint=False)
    q = np.cos(dist)[:, None, None] * centre + np.sin(dist)[:, None, None] * (
        np.cos(beta)[None, :, None] * c1 + np.sin(beta)[None, :, None] * c2
    )
    e1, e2 = frame(q)
    hh = math.radians(step)
    stencil = np.stack([q + hh * e1, q - hh * e1, q + hh * e2, q - hh * e2, q])
    stencil /= np.linalg.norm(stencil, axis=-1, keepdims=True)
    shown = coords.lonlat_to_xyz(np.asarray(result.inverse_points(coords.xyz_to_lonlat(stencil)), np.float64))
    p = shown[4]
    f1, f2 = frame(p)

    def tangent(x: NDArray) -> NDArray:  # gnomonic coordinates about p
        dot = np.sum(x * p, axis=-1, keepdims=True)
        y = x / dot
        return np.stack([np.sum(y * f1, axis=-1), np.sum(y * f2, axis=-1)], axis=-1)

    j = np.stack([(tangent(shown[0]) - tangent(shown[1])) / (2 * hh), (tangent(shown[2]) - tangent(shown[3])) / (2 * hh)], axis=-1)
    sv = np.linalg.svd(j, compute_uv=True)[1]
    carried = Moebius.point_map(h.position, h.final).apply_xyz(p)
    seen = np.arctan2(carried @ c2, carried @ c1)
    turn = np.degrees(np.angle(np.exp(1j * (beta[None, :] - seen))))
    return {
        "magnification": 1.0 / sv.mean(axis=-1),
        "rotation": turn,
        "moved": np.degrees(np.arccos(np.clip(np.sum(q * p, axis=-1), -1.0, 1.0))),
        "det": np.linalg.det(j),
    }


def vertical_tilt(inverse_map: ArrayLike, start: ArrayLike, end: ArrayLike, max_abs_lat: float = 70.0) -> float:
    """How far a line that should come out vertical is from it: degrees from the zenith to the great circle of its output.

    A vertical 3D edge is seen, in a level panorama, along a meridian: a great circle through
    the poles. The line's input arc is sampled (within ``max_abs_lat``, where a meridian's
    direction is well defined), each sample found in the output through ``inverse_map``
    (:func:`forward_points`), and the great circle through the camera closest to them
    fitted (the plane of least squares); its normal's latitude, 0 for a meridian, is the
    tilt.

    Parameters
    ----------
    inverse_map : array_like, shape (H, W, 2)
        The map that placed the output's pixels (``Result.placed_map()``).
    start, end : array_like, shape (2,)
        The line's input ends, ``[lon, lat]`` degrees.
    max_abs_lat : float
        Samples nearer a pole than this (in the input) are left out, degrees.

    Returns
    -------
    float
        Degrees in ``[0, 90]``; NaN when fewer than 3 samples are found in the output.
    """
    m = check_inverse_map(inverse_map)
    s = coords.geodesic(np.asarray(start, dtype=np.float64), np.asarray(end, dtype=np.float64), np.linspace(0.02, 0.98, 48))
    s = s[np.abs(s[:, 1]) < max_abs_lat]
    out = forward_points(m, s) if len(s) else np.empty((0, 2))
    out = out[np.isfinite(out).all(axis=1)]
    if len(out) < 3:
        return math.nan
    normal = np.linalg.svd(coords.lonlat_to_xyz(out), full_matrices=False)[2][-1]
    return math.degrees(math.asin(min(1.0, abs(float(normal[2])))))
