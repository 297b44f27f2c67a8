"""A warp made in strips of output rows: full-size outputs of panoramas wider than memory holds.

:func:`~omniwidget.raster.pipeline.warp` holds about 42 bytes per output pixel (the
resampling's coordinates, the map the quality figures measure through): 24 GB for a
34,000 px wide output. :func:`warp_in_strips` instead runs the method once on a map grid
:data:`MAP_WIDTH` wide (its mesh, weights, untangling, quality figures and warnings: the
:class:`~omniwidget.raster.pipeline.Result` that stands for the warp) and then makes the
output a strip of about :data:`STRIP_PIXELS` pixels at a time (:func:`strip_rows`): each strip's source coordinates are those of the
map grid interpolated bilinearly on the sphere (as unit vectors, so across the ±180° seam
and over the poles alike; a single map is evaluated exactly instead), resampled by
:func:`~omniwidget.raster.warping.remap_panorama`. Memory is the input (or, for a
panorama on disk, a copy reduced for the map grid and one patch at a time), the map grid
and :data:`STRIPS_AHEAD` + 1 strips (made ahead in threads); the strips go to a writer as they are made
(:func:`omniwidget.io.images.write_image_strips`).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from ..document.handles import Handles
from ..sphere import coords
from .pipeline import Result, warp
from .warping import Order, PanoramaSource, check_warp_arguments, coordinates_lonlat, pad_panorama, remap_panorama, source_pixels

__all__ = ["MAP_WIDTH", "STREAM_WIDTH", "STRIPS_AHEAD", "STRIP_PIXELS", "Strips", "strip_rows", "warp_in_strips"]

#: The command line makes outputs wider than this in strips (:func:`warp_in_strips`).
STREAM_WIDTH = 16384
#: Width of the grid the method's map is computed on for a warp in strips.
MAP_WIDTH = 8192
#: Output pixels a strip holds, about (its rows: :func:`strip_rows`): 64 rows of a 16,384 px output, 16 of a 64,000 px one.
STRIP_PIXELS = 1 << 20
#: Strips made ahead of the writer, in threads, besides the one it takes (:meth:`Strips.image_strips`).
STRIPS_AHEAD = 2


def strip_rows(width: int) -> int:
    """Rows of the strips of an output ``width`` wide: :data:`STRIP_PIXELS` pixels' worth, at least 8."""
    return max(8, STRIP_PIXELS // max(int(width), 1))


@dataclass(frozen=True, eq=False)
class Strips:
    """A warp in strips: the method's result on the map grid, and the output made strip by strip.

    Attributes
    ----------
    result : Result
        The warp at the map grid's width: its quality figures, warnings and map stand for
        the full-size output (:attr:`Result.image` is the output at that width).
    shape : tuple of int
        The full output's shape, ``(width / 2, width[, C])``.
    dtype : numpy.dtype
        The output's, the input's.
    rows : int
        Rows per strip (the last may have fewer).
    """

    result: Result
    shape: tuple[int, ...]
    dtype: np.dtype
    rows: int
    _image: NDArray | PanoramaSource = field(repr=False)
    _order: Order = "bilinear"
    _vectors: NDArray[np.float32] | None = field(default=None, repr=False)

    def _bands(self) -> Iterator[slice]:
        height = self.shape[0]
        return (slice(r0, min(r0 + self.rows, height)) for r0 in range(0, height, self.rows))

    def coordinates(self, band: slice) -> NDArray[np.float32]:
        """``(x, y) + PAD`` source pixel coordinates of the output rows ``band``, float32 (rows, width, 2)."""
        width, src_width = self.shape[1], self._image.shape[1]
        if self._vectors is not None:
            return _interpolated(self._vectors, self.result.coordinates.shape[1], src_width, width, band)  # type: ignore[union-attr]
        lon, lat = (np.radians(x) for x in coords.grid_lonlat(width))  # one map: evaluated exactly
        src_lon, src_lat = self.result.inverse(lon, lat[band], band)
        return source_pixels(np.asarray(src_lon), np.asarray(src_lat), src_width)

    def image_strips(self) -> Iterator[NDArray]:
        """The output's strips top to bottom, each ``(rows, width[, C])``, made ahead of the taker (:data:`STRIPS_AHEAD`)."""
        return _ahead(lambda band: remap_panorama(self._image, self.coordinates(band), self._order), self._bands())

    def map_strips(self) -> Iterator[NDArray[np.float32]]:
        """The inverse map that placed them, ``[lon, lat]`` degrees float32 ``(rows, width, 2)``, strip by strip."""
        return _ahead(lambda band: coordinates_lonlat(self.coordinates(band), self._image.shape[1], np.float32), self._bands())


def _ahead(make: Callable[[slice], NDArray], bands: Iterator[slice]) -> Iterator[NDArray]:
    """``make(band)`` for each band, in order, computed in threads up to :data:`STRIPS_AHEAD` bands ahead of the taker.

    The strips' numpy and OpenCV work releases the GIL, so the next strips are made while
    the taker encodes or writes this one; memory holds :data:`STRIPS_AHEAD` strips more.
    """
    with ThreadPoolExecutor(STRIPS_AHEAD) as pool:
        pending: deque[Future[NDArray]] = deque()
        try:
            for band in bands:
                pending.append(pool.submit(make, band))
                if len(pending) > STRIPS_AHEAD:
                    yield pending.popleft().result()
            while pending:
                yield pending.popleft().result()
        finally:
            for future in pending:
                future.cancel()


def _grid_vectors(grid: NDArray[np.float32], src_width: int) -> NDArray[np.float32]:
    """The map grid's directions as unit vectors, float32 (h + 2, w + 2, 3): padded by one pixel over the seam and the poles."""
    vectors = np.empty((*grid.shape[:2], 3), np.float32)
    for r0 in range(0, grid.shape[0], 256):  # in blocks: float64 directions of a block at a time
        vectors[r0 : r0 + 256] = coords.lonlat_to_xyz(coordinates_lonlat(grid[r0 : r0 + 256], src_width))
    return pad_panorama(vectors, 1)


def _interpolated(vectors: NDArray[np.float32], w: int, src_width: int, width: int, rows: slice) -> NDArray[np.float32]:
    """Source coordinates of output rows ``rows`` of a ``width`` wide output, float32 (rows, width, 2).

    The grid's unit vectors (padded by one pixel over the seam and the poles, :func:`_grid_vectors`; the grid ``w``
    wide) interpolated bilinearly at each output pixel centre, normalised, as ``(x, y) + PAD`` source pixel coordinates.
    """
    scale = w / width
    u = (np.arange(width) + 0.5) * scale - 0.5 + 1.0  # in the padded grid
    v = (np.arange(rows.start, rows.stop) + 0.5) * scale - 0.5 + 1.0
    u0 = np.clip(np.floor(u).astype(np.int64), 0, vectors.shape[1] - 2)
    v0 = np.clip(np.floor(v).astype(np.int64), 0, vectors.shape[0] - 2)
    fu = (u - u0).astype(np.float32)[None, :, None]
    fv = (v - v0).astype(np.float32)[:, None, None]
    across = vectors[v0] + (vectors[v0 + 1] - vectors[v0]) * fv  # the grid's rows blended first: (rows, w + 2, 3)
    left = np.take(across, u0, axis=1)
    p = left + (np.take(across, u0 + 1, axis=1) - left) * fu
    return source_pixels(np.arctan2(p[..., 1], p[..., 0]), np.arctan2(p[..., 2], np.hypot(p[..., 0], p[..., 1])), src_width)


def warp_in_strips(
    image: NDArray | PanoramaSource,
    handles: Handles,
    *,
    width: int | None = None,
    order: Order = "bilinear",
    map_width: int = MAP_WIDTH,
    rows: int | None = None,
    warn: bool = True,
    map_image: NDArray | None = None,
) -> Strips:
    """Warp a panorama by handles, the output made in strips (see the module).

    Parameters
    ----------
    image : ndarray, shape (H, W[, C]), or PanoramaSource
        Equirectangular, ``W = 2 H``; one on disk (:class:`omniwidget.io.large.DiskPanorama`)
        is read a patch at a time.
    handles : Handles
    width : int, optional
        Output width (even); default: the input's.
    order : {"nearest", "bilinear", "bicubic"}
    map_width : int
        Width of the grid the method runs on (even; at most ``width``): the output's
        coordinates are interpolated from it: a coarser grid places the pixels a little
        farther from the map computed at the output's width, most at the kinks of the
        weights near handles (``tests/test_any_size.py`` bounds it; the figures are in
        ``bench/RESULTS.md``). Where the method untangled or gave way, it did so on this
        grid: at another width it may give way otherwise (both one-to-one).
    rows : int, optional
        Output rows per strip; default :func:`strip_rows` of the width.
    warn : bool
        As for :func:`~omniwidget.raster.pipeline.warp`.
    map_image : ndarray, optional
        The same panorama reduced (at least ``map_width`` wide, any size), for the method's
        run on the map grid; needed when ``image`` is not an array. Default: ``image``.

    Returns
    -------
    Strips
    """
    if map_image is None:
        if not isinstance(image, np.ndarray):
            raise ValueError("a panorama not held in memory needs map_image, a reduced copy to run the method on")
        map_image = image
    width = check_warp_arguments(map_image, image.shape[1] if width is None else width, order)
    if image.shape[1] != 2 * image.shape[0] or image.shape[2:] != map_image.shape[2:] or image.dtype != map_image.dtype:
        raise ValueError(f"map_image {map_image.shape} {map_image.dtype} is not a reduced copy of the {image.shape} {image.dtype} panorama")
    map_width = min(int(map_width), width)
    if map_width < 2 or map_width % 2:
        raise ValueError(f"map_width must be an even number of at least 2, got {map_width}")
    rows = strip_rows(width) if rows is None else int(rows)
    if rows < 1:
        raise ValueError(f"rows must be at least 1, got {rows}")
    result = warp(map_image, handles, width=map_width, order=order, warn=warn)
    vectors = None if result.coordinates is None else _grid_vectors(result.coordinates, map_image.shape[1])
    return Strips(result, (width // 2, width, *image.shape[2:]), image.dtype, rows, image, order, vectors)
