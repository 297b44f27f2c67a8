"""Warping an equirectangular image by an inverse map of the sphere.

For each output pixel the inverse map gives the input direction it shows; the input is
then resampled there (nearest, bilinear or bicubic) by OpenCV's ``remap``. The input is
first padded so that sampling wraps across the ±180° seam and continues *over* the poles
(the row above the top row is the top row half a turn away), so neighbourhoods are right
everywhere on the sphere. The map is computed in blocks of rows, in two threads, straight
into the float32 array ``remap`` reads: memory stays at a few bytes per pixel.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal, Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from .._checks import check_panorama, whole_number
from .._lazy import lazy
from ..errors import ImageError
from ..sphere import coords
from ..sphere.moebius import Moebius

if TYPE_CHECKING:
    import cv2
else:
    cv2 = lazy("cv2")

__all__ = [
    "ORDERS",
    "REMAP_LIMIT",
    "PanoramaSource",
    "WarpResult",
    "check_warp_arguments",
    "coordinates_lonlat",
    "grid_homogeneous",
    "grid_inverse",
    "inverse_lonlat",
    "remap",
    "remap_coordinates",
    "remap_panorama",
    "source_pixels",
    "warp_by_inverse",
    "warp_moebius",
]

Order = Literal["nearest", "bilinear", "bicubic"]
#: The resampling orders :func:`remap` offers (OpenCV's nearest, linear and cubic interpolation).
ORDERS: tuple[Order, ...] = ("nearest", "bilinear", "bicubic")
#: Rows of source padding: bicubic reads two pixels beyond the sample on each side.
PAD = 3
BLOCK_ROWS = 128

#: ``fn(lon, lat, rows) -> (src_lon, src_lat)``: the inverse map of a warp on a block of the
#: output grid. Radians; ``lon`` shape (W,), ``lat`` shape (h,) for the output rows ``rows``
#: (a slice); results shape (h, W).
GridInverse = Callable[[NDArray[np.float64], NDArray[np.float64], slice], tuple[NDArray[np.floating], NDArray[np.floating]]]


_PRECISION = {"double": (np.float64, np.complex128), "single": (np.float32, np.complex64)}


def grid_homogeneous(
    m: Moebius, lon: NDArray[np.float64], lat: NDArray[np.float64], precision: Literal["double", "single"] = "double"
) -> tuple[NDArray, NDArray]:
    """Apply ``m`` to a block of grid directions, in homogeneous coordinates ``[U : V]``.

    Uses that grid rows share a latitude: each row's homogeneous coordinates are an outer
    product, so the matrix acts on ``W + h`` numbers before the per-pixel work. Each row
    takes the well-conditioned homogeneous form of its hemisphere (see
    :func:`coords.xyz_to_homogeneous`), so nothing is singular at the poles.

    Parameters
    ----------
    m : Moebius
    lon : ndarray of float64, shape (W,)
        Column longitudes, radians.
    lat : ndarray of float64, shape (h,)
        Row latitudes, radians, from north to south.
    precision : {"double", "single"}
        Arithmetic of the per-pixel work: complex128 or complex64.

    Returns
    -------
    U, V : ndarray of complex, shape (h, W)
    """
    real, cplx = _PRECISION[precision]
    (a, b), (c, d) = m.matrix.astype(cplx)
    e = np.exp(1j * lon).astype(cplx)
    ce = np.conj(e)
    cos_lat, sin_lat = np.cos(lat).astype(real)[:, None], np.sin(lat).astype(real)[:, None]
    k = int(np.count_nonzero(sin_lat > 0))  # rows run north to south: the first k are northern
    if np.any(sin_lat[:k] <= 0) or np.any(sin_lat[k:] > 0):
        raise ValueError("grid rows must run from north to south")
    one = real(1.0)
    big_u: NDArray[np.complexfloating] = np.empty((len(lat), len(lon)), cplx)
    big_v = np.empty_like(big_u)
    # northern rows: [u : v] = [1 + sin(lat) : cos(lat) conj(e)]
    big_u[:k] = cos_lat[:k] * (b * ce) + a * (one + sin_lat[:k])
    big_v[:k] = cos_lat[:k] * (d * ce) + c * (one + sin_lat[:k])
    # southern rows: [u : v] = [cos(lat) e : 1 - sin(lat)]
    big_u[k:] = cos_lat[k:] * (a * e) + b * (one - sin_lat[k:])
    big_v[k:] = cos_lat[k:] * (c * e) + d * (one - sin_lat[k:])
    return big_u, big_v


def homogeneous_to_lonlat(big_u: NDArray, big_v: NDArray) -> tuple[NDArray, NDArray]:
    """Longitude and latitude (radians) of homogeneous ``[U : V]``.

    ``lon = arg(U V̄)``, ``lat = atan2(|U|² - |V|², 2 |U V̄|)``: exact at the poles.
    """
    w = big_u * np.conj(big_v)
    uu = big_u.real**2 + big_u.imag**2
    uu -= big_v.real**2 + big_v.imag**2
    return np.arctan2(w.imag, w.real), np.arctan2(uu, 2 * np.abs(w))


def grid_inverse(m: Moebius, precision: Literal["double", "single"] = "double") -> GridInverse:
    """The grid evaluator of the Möbius map ``m`` (pass the *inverse* of the warp's map).

    Parameters
    ----------
    m : Moebius
    precision : {"double", "single"}
        Arithmetic of the per-pixel work. ``"single"`` is faster and places samples far
        closer than OpenCV's 1/32 px interpolation step (``tests/test_warp.py`` bounds the
        difference): the warp uses it. Measurements of the map use ``"double"``.
    """

    def fn(
        lon: NDArray[np.float64], lat: NDArray[np.float64], rows: slice | None = None
    ) -> tuple[NDArray[np.floating], NDArray[np.floating]]:
        return homogeneous_to_lonlat(*grid_homogeneous(m, lon, lat, precision))

    return fn


def _blocks(height: int) -> list[slice]:
    return [slice(s, min(s + BLOCK_ROWS, height)) for s in range(0, height, BLOCK_ROWS)]


def run_blocks(height: int, work: Callable[[slice], None]) -> None:
    blocks = _blocks(height)
    threads = min(len(blocks), os.cpu_count() or 1, 4)
    if threads <= 1:
        for block in blocks:
            work(block)
        return
    with ThreadPoolExecutor(threads) as pool:
        list(pool.map(work, blocks))


def inverse_lonlat(fn: GridInverse, width: int) -> NDArray[np.float64]:
    """Evaluate an inverse map on the full output grid, in float64 degrees.

    Parameters
    ----------
    fn : GridInverse
    width : int
        Output width; the height is ``width / 2``.

    Returns
    -------
    ndarray of float64, shape (width / 2, width, 2)
        For each output pixel centre, the input ``[lon, lat]`` it shows.
    """
    lon, lat = (np.radians(x) for x in coords.grid_lonlat(width))
    out = np.empty((width // 2, width, 2))

    def work(rows: slice) -> None:
        src_lon, src_lat = fn(lon, lat[rows], rows)
        out[rows, :, 0] = np.degrees(src_lon)
        out[rows, :, 1] = np.degrees(src_lat)

    run_blocks(width // 2, work)
    return out


def remap_coordinates(fn: GridInverse, width: int, src_width: int, offset: float = PAD) -> NDArray[np.float32]:
    """Source pixel coordinates ``(x, y) + offset`` of every output pixel, float32 (H, W, 2)."""
    lon, lat = (np.radians(x) for x in coords.grid_lonlat(width))
    out = np.empty((width // 2, width, 2), dtype=np.float32)

    def work(rows: slice) -> None:
        source_pixels(*fn(lon, lat[rows], rows), src_width, offset, out=out[rows])

    run_blocks(width // 2, work)
    return out


def source_pixels(
    lon: NDArray[np.floating], lat: NDArray[np.floating], src_width: int, offset: float = PAD, out: NDArray[np.float32] | None = None
) -> NDArray[np.float32]:
    """Source directions (radians) as pixel coordinates ``(x, y) + offset``, float32 (..., 2): :func:`coordinates_lonlat` undone.

    ``lon = 0`` sits at ``x = W/2 - 0.5`` and ``lat = 0`` at ``y = H/2 - 0.5`` (pixel centres). Written into
    ``out`` when given.
    """
    kx = src_width / (2 * math.pi)
    if out is None:
        out = np.empty((*np.shape(lon), 2), np.float32)
    out[..., 0] = lon * kx + (src_width / 2 - 0.5 + offset)
    out[..., 1] = (src_width / 4 - 0.5 + offset) - lat * kx
    return out


def coordinates_lonlat(
    coordinates: NDArray[np.float32], src_width: int, dtype: type[np.floating] = np.float64, offset: float = PAD
) -> NDArray[Any]:
    """The inverse map ``[lon, lat]`` (degrees) of source pixel coordinates: :func:`remap_coordinates` undone.

    Parameters
    ----------
    coordinates : ndarray of float32, shape (H, W, 2)
        ``(x, y) + offset`` in the source, as a warp resamples by.
    src_width : int
        Width of the source.
    dtype : {numpy.float64, numpy.float32}
        Of the answer (float32 is enough for signs, as the fold check takes them).
    offset : float

    Returns
    -------
    ndarray, shape (H, W, 2)
    """
    pixel = dtype(360.0 / src_width)
    scale = np.array([pixel, -pixel], dtype)
    return (coordinates.astype(dtype, copy=False) - dtype(offset - 0.5)) * scale + np.array([-180, 90], dtype)


def pad_panorama(image: NDArray, pad: int = PAD) -> NDArray:
    """Pad a panorama by ``pad`` pixels: columns wrap at the seam, rows continue over the poles."""
    h, w = image.shape[:2]
    if w % 2 or h < 1 or pad < 0:
        raise ImageError(f"cannot pad a {w} x {h} panorama by {pad} pixels")
    half = w // 2
    if not 0 < pad < h:  # a tiny panorama: a meridian goes over a pole and on within the padding (or no padding)
        r = np.arange(-pad, h + pad) % (2 * h)
        over = r >= h  # rows seen past a pole: half a turn away
        rows = image[np.where(over, 2 * h - 1 - r, r)]
        rows[over] = np.roll(rows[over], half, axis=1)
        return rows[:, np.arange(-pad, w + pad) % w]
    top = np.roll(image[pad - 1 :: -1], half, axis=1)  # row -1 is row 0 half a turn away, ...
    bottom = np.roll(image[h - 1 : h - pad - 1 : -1], half, axis=1)
    rows = np.concatenate([top, image, bottom], axis=0)
    return np.concatenate([rows[:, w - pad :], rows, rows[:, :pad]], axis=1)


#: OpenCV's ``remap`` keeps pixel coordinates in 16 bits: the source and the map must each be
#: under this many pixels a side (``SHRT_MAX``). Larger ones are resampled in tiles.
REMAP_LIMIT = 32767
#: The side of the output tiles the tiled path starts from (each split further while its
#: source patch is too large).
REMAP_TILE = 4096
#: The most source pixels a tile's patch may have (its copy: 200 MB of RGB at 8 bits).
PATCH_PIXELS = 1 << 26
#: Source pixels kept around a tile's samples: bicubic reads two beyond, and one for the rounding.
_MARGIN = 3

#: ``patch(y0, y1, x0, x1)``: rows y0:y1, columns x0:x1 of the padded source (a view or a copy).
_Patch = Callable[[int, int, int, int], NDArray]


@runtime_checkable
class PanoramaSource(Protocol):
    """A panorama not held in memory (one on disk: :class:`omniwidget.io.large.DiskPanorama`), read a patch at a time."""

    @property
    def shape(self) -> tuple[int, ...]:
        """``(H, W)`` or ``(H, W, C)``."""

    @property
    def dtype(self) -> np.dtype:
        """The samples' type."""

    @property
    def ndim(self) -> int:
        """2 or 3."""

    def take(self, rows: NDArray[np.int64], cols: NDArray[np.int64]) -> NDArray:
        """``image[np.ix_(rows, cols)]``: rows ``(n,)``, columns ``(m,)`` in runs of consecutive ones; ``(n, m[, C])``."""


def _interpolation(order: str) -> int:
    if order not in ORDERS:
        raise ValueError(f"order must be one of {', '.join(ORDERS)}, got {order!r}")
    return int({"nearest": cv2.INTER_NEAREST, "bilinear": cv2.INTER_LINEAR, "bicubic": cv2.INTER_CUBIC}[order])


def remap(image: NDArray, coordinates: NDArray[np.float32], order: Order = "bilinear", *, tile: int | None = None) -> NDArray:
    """Sample a padded panorama at float32 pixel coordinates with OpenCV.

    A source or a map of :data:`REMAP_LIMIT` pixels a side or more, or any ``tile`` given,
    is resampled by tiles of the output, as :func:`remap_panorama` does.

    Parameters
    ----------
    image : ndarray, shape (H + 2 PAD, W + 2 PAD[, C])
        Output of :func:`pad_panorama`.
    coordinates : ndarray of float32, shape (h, w, 2)
        ``(x, y)`` in the padded image.
    order : {"nearest", "bilinear", "bicubic"}
    tile : int, optional
        As for :func:`remap_panorama`.

    Returns
    -------
    ndarray, shape (h, w[, C]), the image's dtype
    """
    interpolation = _interpolation(order)
    if tile is None and max(image.shape[:2]) < REMAP_LIMIT and max(coordinates.shape[:2]) < REMAP_LIMIT:
        return _cv_remap(image, coordinates, interpolation)
    return _remap_tiles(lambda y0, y1, x0, x1: image[y0:y1, x0:x1], image.shape, coordinates, interpolation, tile)


def remap_panorama(
    image: NDArray | PanoramaSource, coordinates: NDArray[np.float32], order: Order = "bilinear", *, tile: int | None = None
) -> NDArray:
    """Sample a panorama at float32 pixel coordinates of its padded frame: :func:`remap` of :func:`pad_panorama`.

    Below :data:`REMAP_LIMIT` pixels a side (source and output) it is exactly that: the
    source padded, then one call of OpenCV's ``remap``. A larger panorama (a stitched one
    35,000 px wide, say), or any ``tile`` given, is resampled by tiles of the output, each
    from the patch of the padded source its samples fall in, made from the panorama alone
    (no padded copy of it): moved by an even number of pixels (an exact float32 subtraction
    that keeps OpenCV's rounding of halves to even), each tile has the bytes one call would
    give. A tile whose samples lie on both sides of the ±180° seam is sampled once on each
    side; a tile whose patch would be :data:`REMAP_LIMIT` pixels a side or
    :data:`PATCH_PIXELS` pixels or more (near a pole a row spans every longitude) is halved.

    Parameters
    ----------
    image : ndarray, shape (H, W[, C]), or PanoramaSource
        The panorama, ``W = 2 H``; a :class:`PanoramaSource` (one on disk) is always
        resampled in tiles, each reading only its patch.
    coordinates : ndarray of float32, shape (h, w, 2)
        ``(x, y) + PAD``: pixel coordinates in the padded panorama, as
        :func:`remap_coordinates` gives them.
    order : {"nearest", "bilinear", "bicubic"}
    tile : int, optional
        Resample by output tiles at most this many pixels a side whatever the sizes (the
        tiled path, for tests); default: one call below :data:`REMAP_LIMIT`, tiles of
        :data:`REMAP_TILE` above it.

    Returns
    -------
    ndarray, shape (h, w[, C]), the image's dtype
    """
    interpolation = _interpolation(order)
    h, w = image.shape[:2]
    if w % 2 or h < 1:
        raise ImageError(f"cannot resample a {w} x {h} panorama: its width must be even and its height at least 1")
    if isinstance(image, np.ndarray) and tile is None and max(h, w) + 2 * PAD < REMAP_LIMIT and max(coordinates.shape[:2]) < REMAP_LIMIT:
        return _cv_remap(pad_panorama(image), coordinates, interpolation)
    shape = (h + 2 * PAD, w + 2 * PAD, *image.shape[2:])
    return _remap_tiles(lambda y0, y1, x0, x1: _padded_patch(image, y0, y1, x0, x1), shape, coordinates, interpolation, tile)


def _padded_patch(image: NDArray | PanoramaSource, y0: int, y1: int, x0: int, x1: int) -> NDArray:
    """Rows ``y0:y1`` and columns ``x0:x1`` of ``pad_panorama(image)``, from ``image`` alone: a view inside it, else a copy."""
    h, w = image.shape[:2]
    if not isinstance(image, np.ndarray):
        return _padded_take(image.take, h, w, y0, y1, x0, x1)
    if PAD <= y0 and y1 <= h + PAD and PAD <= x0 and x1 <= w + PAD:
        return image[y0 - PAD : y1 - PAD, x0 - PAD : x1 - PAD]
    return _padded_take(lambda rows, cols: image[np.ix_(rows, cols)], h, w, y0, y1, x0, x1)


def _padded_take(take: Callable[[NDArray[np.int64], NDArray[np.int64]], NDArray], h: int, w: int, y0: int, y1: int, x0: int, x1: int) -> NDArray:
    """:func:`_padded_patch` of a panorama read by ``take(rows, cols)`` (``image[np.ix_(rows, cols)]``)."""
    r = (np.arange(y0, y1) - PAD) % (2 * h)
    over = r >= h  # rows past a pole: the row on the other side, half a turn away
    rows = np.where(over, 2 * h - 1 - r, r)
    cols = np.arange(x0, x1) - PAD
    parts = []
    for turned in (False, True):
        chosen = over == turned
        if chosen.any():
            parts.append((chosen, take(rows[chosen], (cols + (w // 2 if turned else 0)) % w)))
    if len(parts) == 1:
        return parts[0][1]
    patch = np.empty((y1 - y0, *parts[0][1].shape[1:]), parts[0][1].dtype)
    for chosen, pixels in parts:
        patch[chosen] = pixels
    return patch


def _cv_remap(image: NDArray, coordinates: NDArray[np.float32], interpolation: int) -> NDArray:
    """One call of OpenCV's remap (both sides under :data:`REMAP_LIMIT`), the channel axis kept."""
    if image.ndim == 3 and image.shape[2] == 2:  # OpenCV samples two channels on a coarser grid (1/32 pixel): one at a time
        return np.dstack([_cv_remap(np.ascontiguousarray(image[..., k]), coordinates, interpolation) for k in range(2)])

    # None is OpenCV's documented empty map2 (one (x, y) map); OpenCV 4's stub wants an array there, 5's does not
    remap_fn: Any = cv2.remap
    out = remap_fn(image, coordinates, None, interpolation, borderMode=cv2.BORDER_REPLICATE)
    if image.ndim == 3 and out.ndim == 2:  # OpenCV drops a single channel axis
        out = out[..., None]
    return out


def _remap_tiles(patch: _Patch, shape: tuple[int, ...], coordinates: NDArray[np.float32], interpolation: int, tile: int | None) -> NDArray:
    """Resample a padded source of ``shape``, read through ``patch``, by tiles of the output (:func:`remap_panorama`)."""
    side = REMAP_TILE if tile is None else whole_number(tile, "tile", 1)
    side = min(side, REMAP_LIMIT - 1)
    h, w = coordinates.shape[:2]
    out = np.empty((h, w, *shape[2:]), patch(0, 1, 0, 1).dtype)
    half = PAD + (shape[1] - 2 * PAD) / 2  # samples east of it and west of it lie on either side of the seam
    todo = [(r, min(r + side, h), c, min(c + side, w)) for r in range(0, h, side) for c in range(0, w, side)]
    while todo:
        r0, r1, c0, c1 = todo.pop()
        at, into = coordinates[r0:r1, c0:c1], out[r0:r1, c0:c1]
        if _remap_patch(into, patch, shape, at, interpolation, None):
            continue
        east = at[..., 0] >= half
        if east.any() and not east.all():
            if _remap_patch(into, patch, shape, at, interpolation, ~east) and _remap_patch(into, patch, shape, at, interpolation, east):
                continue
        if r1 - r0 >= c1 - c0:
            mid = (r0 + r1) // 2
            todo += [(r0, mid, c0, c1), (mid, r1, c0, c1)]
        else:
            mid = (c0 + c1) // 2
            todo += [(r0, r1, c0, mid), (r0, r1, mid, c1)]
    return out


def _remap_patch(
    out: NDArray, patch: _Patch, shape: tuple[int, ...], at: NDArray[np.float32], interpolation: int, where: NDArray[np.bool_] | None
) -> bool:
    """Resample the samples ``at`` (those ``where`` says; all if None) into ``out`` from the source patch under them.

    Returns False, writing nothing, when that patch is too large (:func:`remap_panorama`).
    """
    chosen = at if where is None else at[where]  # (h, w, 2), or (n, 2)
    x, y = chosen[..., 0], chosen[..., 1]
    lowest, highest = np.array([x.min(), y.min()]), np.array([x.max(), y.max()])  # not nanmin (5x dearer): NaN is rare
    if not (np.isfinite(lowest).all() and np.isfinite(highest).all()):
        finite = chosen.reshape(-1, 2)[np.isfinite(chosen.reshape(-1, 2)).all(axis=1)]
        lowest, highest = (finite.min(axis=0), finite.max(axis=0)) if len(finite) else (np.zeros(2), np.zeros(2))
    low = np.floor(lowest).astype(np.int64) - _MARGIN
    high = np.ceil(highest).astype(np.int64) + _MARGIN + 1
    # even: OpenCV rounds halves to even, an odd move would change that; samples off the source keep its border
    x0, y0 = (int(v) for v in np.clip(low, 0, np.array(shape[1::-1]) - 1) & ~1)
    x1, y1 = max(min(int(high[0]), shape[1]), x0 + 1), max(min(int(high[1]), shape[0]), y0 + 1)
    if max(x1 - x0, y1 - y0) >= REMAP_LIMIT or (x1 - x0) * (y1 - y0) >= PATCH_PIXELS:
        return False
    shifted = at - np.array([x0, y0], np.float32)  # whole pixels off numbers under 2**24: exact in float32
    if where is not None:
        shifted[~where] = shifted[where][0]  # the other side's samples: any pixel of this patch, not kept
    sampled = _cv_remap(patch(y0, y1, x0, x1), shifted, interpolation)
    if where is None:
        out[...] = sampled
    else:
        out[where] = sampled[where]
    return True


@dataclass(frozen=True, eq=False)
class WarpResult:
    """The output of a warp.

    Attributes
    ----------
    image : ndarray, shape (H, W[, C])
        The warped panorama, in the input's dtype and channels.
    moebius : Moebius
        The map from the input sphere to the output sphere.
    source_width : int
        Width of the input image.
    """

    image: NDArray
    moebius: Moebius
    source_width: int

    def inverse_map(self, dtype: type[np.floating] = np.float32) -> NDArray[np.floating]:
        """For each output pixel centre, the input ``[lon, lat]`` in degrees it shows, (H, W, 2).

        Longitudes are in ``[-180, 180]``.

        Parameters
        ----------
        dtype : {numpy.float32, numpy.float64}
            float64 for measurements (:mod:`omniwidget.evaluate.quality`), as ``Result.inverse_map``.
        """
        if dtype not in (np.float32, np.float64):
            raise ValueError(f"dtype must be numpy.float32 or numpy.float64, got {dtype!r}")
        width = self.image.shape[1]
        return inverse_lonlat(grid_inverse(self.moebius.inverse), width).astype(dtype, copy=False)


def warp_moebius(image: NDArray, moebius: Moebius, *, width: int | None = None, order: Order = "bilinear") -> WarpResult:
    """Warp a panorama by one Möbius map of the sphere.

    Parameters
    ----------
    image : ndarray, shape (H, W[, C])
        Equirectangular, ``W = 2 H``; uint8, uint16, float32 or float64; 1 to 4 channels.
    moebius : Moebius
        The forward map, input sphere to output sphere: the output shows ``image`` moved by it.
    width : int, optional
        Output width (even); the height is half of it. Default: the input's width.
    order : {"nearest", "bilinear", "bicubic"}

    Returns
    -------
    WarpResult
    """
    width = check_warp_arguments(image, width, order)
    if moebius.is_identity() and width == image.shape[1]:
        return WarpResult(image.copy(), moebius, image.shape[1])
    return WarpResult(warp_by_inverse(image, grid_inverse(moebius.inverse, "single"), width, order), moebius, image.shape[1])


def check_warp_arguments(image: NDArray, width: int | None, order: str) -> int:
    """Validate a warp's image, output width and order; returns the output width."""
    check_panorama(image)
    width = whole_number(image.shape[1] if width is None else width, "width", 2, even=True)
    if order not in ORDERS:
        raise ValueError(f"order must be one of {', '.join(ORDERS)}, got {order!r}")
    return int(width)


def warp_by_inverse(image: NDArray, inverse: GridInverse, width: int, order: Order = "bilinear") -> NDArray:
    """Resample ``image`` at the directions an inverse map gives for a ``width`` wide output grid."""
    coordinates = remap_coordinates(inverse, width, image.shape[1], PAD)
    return remap_panorama(image, coordinates, order)
