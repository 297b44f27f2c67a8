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
- :func:`summary`: all of them for one warp (a :class:`~omniwidget.Result`), as a :class:`Summary`.

Use float64 maps: float32 holds only about 1e-4 of a pixel step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import coords
from ._checks import whole_number

#: The far field: the output sphere farther than this many degrees from every handle.
FAR_FIELD = 30.0

__all__ = [
    "FAR_FIELD",
    "Distortion",
    "FarField",
    "FoldOver",
    "Summary",
    "cage_motion",
    "conformal_distortion",
    "coverage",
    "inside_polygon",
    "near_mask",
    "displacement",
    "far_field",
    "fold_over",
    "forward_points",
    "line_straightness",
    "local_jacobians",
    "straightness",
    "summary",
    "tear",
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
    from scipy.spatial import ConvexHull, QhullError

    centred = points - points.mean(axis=0)
    try:
        hull = centred[ConvexHull(centred).vertices]
    except QhullError:  # all on one line (or one point)
        return 0.0
    edges = np.roll(hull, -1, axis=0) - hull
    normals = np.stack([-edges[:, 1], edges[:, 0]], axis=1) / np.hypot(*edges.T)[:, None]
    heights = hull @ normals.T  # (vertex, edge)
    return float(np.min(heights.max(axis=0) - heights.min(axis=0)) / 2)


def _check_map(inverse_map: ArrayLike, dtype: type[np.floating] = np.float64) -> NDArray[np.floating]:
    m = np.asarray(inverse_map, dtype=dtype)
    if m.ndim != 3 or m.shape[2] != 2 or m.shape[1] != 2 * m.shape[0] or m.shape[0] < 3:
        raise ValueError(f"expected an inverse map of shape (H, 2H, 2) with H >= 3, got {m.shape}")
    if not np.all(np.isfinite(m)):
        bad = np.argwhere(~np.isfinite(m).all(axis=-1))[0]
        raise ValueError(f"the inverse map has NaN or infinite entries (first at row {bad[0]}, column {bad[1]})")
    return m


def _area(height: int) -> NDArray[np.float64]:
    """Area of each pixel row of an equirectangular grid, as a share of the sphere, (H,)."""
    edges = np.radians(np.linspace(90.0, -90.0, height + 1))
    return (np.sin(edges[:-1]) - np.sin(edges[1:])) / (2 * (2 * height))


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
    m = _check_map(inverse_map)
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
    sv = np.linalg.svd(local_jacobians(inverse_map), compute_uv=False)
    per_pixel = np.full((sv.shape[0] + 2, sv.shape[1]), np.nan)
    per_pixel[1:-1] = sv[..., 0] / sv[..., 1] - 1.0
    mean, p99 = _distortion_figures(per_pixel, np.ones(per_pixel.shape, dtype=bool), max_abs_lat)
    return Distortion(mean, p99, per_pixel, float(max_abs_lat))


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
    area = np.broadcast_to(_area(height)[:, None], per_pixel.shape)[use]
    return float(np.sum(values * area) / np.sum(area)), _weighted_quantile(values, area, 0.99)


@dataclass(frozen=True, eq=False)
class FoldOver:
    """Where a warp turns the image over.

    Attributes
    ----------
    mask : ndarray of bool, shape (H, W)
        Output pixels where the Jacobian determinant is <= 0 (mirrored or collapsed).
    area : float
        Their share of the sphere's area (0 for a map without fold-overs, 1 is everything).
    """

    mask: NDArray[np.bool_]
    area: float

    @classmethod
    def from_mask(cls, mask: NDArray[np.bool_]) -> FoldOver:
        """The fold-over of an equirectangular mask of turned-over pixels, its area weighted by row.

        Parameters
        ----------
        mask : ndarray of bool, shape (H, 2H)

        Returns
        -------
        FoldOver
        """
        return cls(mask, float(np.count_nonzero(mask, axis=1) @ _area(len(mask))))


def fold_over(inverse_map: ArrayLike, pole_margin: float = 1.0) -> FoldOver:
    """Output pixels where the inverse map's Jacobian determinant is zero or negative.

    The determinant's sign is taken from equirectangular differences (longitude steps
    wrapped at the seam): both the output's and the input's projections preserve
    orientation, so the sign is the sphere's, and this is cheap enough to run on every warp.

    Parameters
    ----------
    inverse_map : array_like, shape (H, W, 2)
        See :func:`local_jacobians`; float32 is precise enough here.
    pole_margin : float
        Pixels whose source lies within this many degrees of a pole are never marked:
        longitude differences mean nothing there. The first and last rows (no central
        difference) are never marked either.

    Returns
    -------
    FoldOver
    """
    m = _check_map(inverse_map, np.float32 if np.asarray(inverse_map).dtype == np.float32 else np.float64)
    lon, lat = m[..., 0], m[..., 1]

    def wrapped(d: NDArray) -> NDArray:
        return (d + 180) % 360 - 180

    d_lon_east = wrapped(np.roll(lon, -1, axis=1) - np.roll(lon, 1, axis=1))[1:-1]
    d_lat_east = (np.roll(lat, -1, axis=1) - np.roll(lat, 1, axis=1))[1:-1]
    d_lon_north, d_lat_north = wrapped(lon[:-2] - lon[2:]), lat[:-2] - lat[2:]
    mask = np.zeros(lon.shape, dtype=bool)
    mask[1:-1] = (d_lon_east * d_lat_north - d_lon_north * d_lat_east <= 0) & (np.abs(lat[1:-1]) < 90 - pole_margin)
    return FoldOver.from_mask(mask)


def _bilinear(src: NDArray[np.float64], x: NDArray, y: NDArray) -> tuple[NDArray, NDArray, NDArray]:
    """Value and x/y derivatives of the bilinear interpolation of ``src`` (H, W, 3) at pixel ``(x, y)``.

    Columns wrap, rows are clamped to ``[0, H - 1]``.
    """
    height, width = src.shape[:2]
    y = np.clip(y, 0.0, height - 1.0)
    x0, y0 = np.floor(x), np.minimum(np.floor(y), height - 2)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    c0, c1, r0 = x0.astype(np.int64) % width, (x0.astype(np.int64) + 1) % width, y0.astype(np.int64)
    s00, s01, s10, s11 = src[r0, c0], src[r0, c1], src[r0 + 1, c0], src[r0 + 1, c1]
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
    from scipy.spatial import cKDTree

    m = _check_map(inverse_map)
    height, width = m.shape[:2]
    targets = coords.lonlat_to_xyz(lonlat).reshape(-1, 3)
    src = coords.lonlat_to_xyz(m)
    stride = max(1, width // 512)
    if start is None:
        coarse = src[::stride, ::stride]
        _, nearest = cKDTree(coarse.reshape(-1, 3)).query(targets)
        row, col = np.divmod(nearest, coarse.shape[1])
        x, y = (col * stride).astype(np.float64), (row * stride).astype(np.float64)
    else:
        x, y = coords.lonlat_to_px(np.asarray(start, np.float64).reshape(-1, 2), width).T
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
    return out.reshape(np.shape(lonlat))


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
    m = _check_map(inverse_map)
    out = forward_points(m, samples, start=start)
    if not np.all(np.isfinite(out)):
        return float("nan")
    return straightness(out, width or m.shape[1], fit="best")


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
    m = _check_map(inverse_map)
    px = coords.lonlat_to_px(m.reshape(-1, 2), cells)
    col = np.floor(px[:, 0] + 0.5).astype(np.int64) % cells
    row = np.clip(np.floor(px[:, 1] + 0.5).astype(np.int64), 0, cells // 2 - 1)
    hit = np.zeros(cells * cells // 2, dtype=bool)
    hit[row * cells + col] = True
    missing = np.flatnonzero(~hit)
    if len(missing):
        centres = coords.px_to_lonlat(np.stack([missing % cells, missing // cells], axis=1).astype(np.float64), cells)
        hit[missing] = np.isfinite(forward_points(m, centres)[:, 0])
    area = np.repeat(_area(cells // 2), cells)
    return float(np.sum(area * hit))


def inside_polygon(lonlat: ArrayLike, vertices: ArrayLike) -> NDArray[np.bool_]:
    """Whether positions lie inside a spherical polygon with great-circle edges (even-odd rule).

    In the gnomonic projection about the vertices' centre, great circles are straight lines,
    so the planar test is exact for polygons smaller than a hemisphere.

    Parameters
    ----------
    lonlat : array_like, shape (..., 2)
        Positions ``[lon, lat]`` in degrees.
    vertices : array_like, shape (n, 2)
        The polygon's corners ``[lon, lat]`` in degrees, in order (either way round), n >= 3.

    Returns
    -------
    ndarray of bool, shape (...)
    """
    corners = coords.lonlat_to_xyz(np.asarray(vertices, np.float64))
    centre = corners.sum(axis=0)
    centre /= np.linalg.norm(centre)
    east, north = coords.local_frame(coords.xyz_to_lonlat(centre))

    def project(xyz: NDArray) -> tuple[NDArray, NDArray, NDArray]:
        depth = xyz @ centre
        return xyz @ east / depth, xyz @ north / depth, depth

    px, py, depth = project(coords.lonlat_to_xyz(np.asarray(lonlat, np.float64)))
    vx, vy, _ = project(corners)
    inside = np.zeros(px.shape, dtype=bool)
    for i in range(len(vx)):
        ax, ay, bx, by = vx[i - 1], vy[i - 1], vx[i], vy[i]
        crosses = (ay > py) != (by > py)
        with np.errstate(divide="ignore", invalid="ignore"):
            at = ax + (py - ay) * (bx - ax) / (by - ay)
        inside ^= crosses & (px < at)
    return inside & (depth > 0)


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
    m = _check_map(inverse_map)
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
    m = _check_map(inverse_map)
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
    m = _check_map(inverse_map)
    return float(np.sum(_moved(m) * _area(m.shape[0])[:, None]))


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
    m = _check_map(inverse_map)
    height, width = m.shape[:2]
    far = ~near_mask(handle_points, distance, width)
    area = _area(height)[:, None]
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
        Each line piece's largest distance from its best straight fit in the output, in
        output pixels (:func:`straightness` of the piece's samples found in the output);
        NaN for a piece the output does not show.
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

    @property
    def straightness(self) -> float:
        """The worst line's distance from straight, in pixels (NaN without lines, or if one is not shown)."""
        if not self.lines:
            return math.nan
        return math.nan if any(math.isnan(v) for v in self.lines) else max(self.lines)

    def line(self) -> str:
        """The figures in one line of text, as the editor shows them.

        Examples
        --------
        >>> Summary("bbw", (0.1, 0.25), 0.031, 0.42, 0.0, 0.3, 1.0, 0.12, None, 0.2, 2048).line()
        'lines within 0.25 px · folds 0% · sphere shown 100% · moved 0.12° on average · distortion 0.031 (p99 0.42)'
        """
        parts = []
        if self.lines:
            worst = self.straightness
            parts.append("a line is not shown" if math.isnan(worst) else f"lines within {worst:.2g} px")
        parts += [
            f"folds {100 * self.fold_over:.2g}%",
            f"sphere shown {100 * self.coverage:.3g}%",
            f"moved {self.displacement:.2g}° on average",
            f"distortion {self.distortion_mean:.2g} (p99 {self.distortion_p99:.2g})",
        ]
        if self.cage_motion is not None:
            parts.append(f"cages still to {self.cage_motion:.2g} px")
        if self.far is not None and self.far.share > 0:
            far = self.far.displacement
            parts.append(f"far from the handles moved {far:.2g}°" if far >= 0.005 else "far from the handles still")
        return " · ".join(parts)

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


def summary(result: Any) -> Summary:
    """Every quality figure of one warp: straightness, distortion, fold-over, tear, coverage, displacement, cages.

    Parameters
    ----------
    result : Result
        Of :func:`omniwidget.warp` or of a baseline (:mod:`omniwidget.core.baselines`):
        anything with ``inverse_map()``, ``forward_points()``, ``folds``, ``constraints``,
        ``handles`` and ``timings``.

    Returns
    -------
    Summary

    Notes
    -----
    Lines are found in the output by inverting the map from each piece's own Möbius map
    (``result.forward_points``), so a line is measured where it is even where the map
    folds elsewhere. At 512 x 256 all figures take about 0.3 s.
    """
    from .handles import CageHandle

    m = result.inverse_map(np.float64)
    width = m.shape[1]
    lines = tuple(straightness(result.forward_points(samples, c), width, fit="best") for c, samples in result.constraints.lines)
    lines = tuple(v if math.isfinite(v) else math.nan for v in lines)
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
    )
