"""The method's harmonic fill (:mod:`omniwidget.method.harmonic`) at every output pixel.

The blend of eq. (2) is evaluated per pixel as before (:mod:`.blend`, :mod:`._kernels`,
:mod:`.sampled`); where the fill changes it (pixels with a free node of its grid round them),
the source direction becomes :meth:`~omniwidget.method.harmonic.HarmonicFill.apply` of the
blend there. Elsewhere, on and along every marked line, inside cages, on points' discs and in
the still background, the pixels keep the blend's value to the bit.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..method.harmonic import HarmonicFill
from ..sphere import coords
from . import _kernels
from .warping import GridInverse, coordinates_lonlat, source_pixels

__all__ = ["ROWS", "fill_coordinates", "filled_inverse"]


#: Output rows filled at a time (bounds the per-pixel fields' memory on wide outputs).
ROWS = 128


def fill_coordinates(coordinates: NDArray[np.float32], fill: HarmonicFill, src_width: int) -> NDArray[np.float32]:
    """Source pixel coordinates of the blend, (H, W, 2) float32 (padded as a warp resamples by), with the fill applied in place.

    With the compiled kernels, pixel by pixel (:func:`omniwidget.raster._kernels.fill_coordinates`);
    in numpy, in single precision, a block of rows at a time: the fill's affine form
    (:meth:`~omniwidget.method.harmonic.HarmonicFill.grid_affine`) at the pixels with a free
    node round them, applied there. Returns the same array.
    """
    lon, lat = coords.grid_lonlat(coordinates.shape[1])
    if _kernels.available():
        _kernels.fill_coordinates(coordinates, fill.held, fill.filled, fill.blend, fill.column_nodes(lon), fill.row_nodes(lat), src_width)
        return coordinates
    touched = fill.touched(lon, lat)
    for top in range(0, len(lat), ROWS):
        block = slice(top, min(top + ROWS, len(lat)))
        rows, cols = np.nonzero(touched[block])
        if not len(rows):
            continue
        share, offset = fill.grid_affine(lon, lat[block], rows, cols)
        blend = coords.lonlat_to_xyz(coordinates_lonlat(coordinates[block][rows, cols], src_width, np.float32))
        shown = np.radians(coords.xyz_to_lonlat(share[:, None] * blend + offset))
        coordinates[block][rows, cols] = source_pixels(shown[:, 0], shown[:, 1], src_width)
    return coordinates


def filled_inverse(fn: GridInverse, fill: HarmonicFill | None) -> GridInverse:
    """An inverse map on the output grid (the blend's, in double precision) with the fill applied; ``fn`` itself without one."""
    if fill is None:
        return fn

    def filled(lon: NDArray[np.float64], lat: NDArray[np.float64], rows: slice) -> tuple[NDArray, NDArray]:
        src_lon, src_lat = (np.array(np.broadcast_to(a, (len(lat), len(lon))), dtype=np.float64) for a in fn(lon, lat, rows))
        r, c = np.nonzero(fill.touched(np.degrees(lon), np.degrees(lat)))
        if len(r):
            blend = coords.lonlat_to_xyz(np.degrees(np.stack([src_lon[r, c], src_lat[r, c]], axis=-1)))
            shown = np.radians(coords.xyz_to_lonlat(fill.apply(np.degrees(np.stack([lon[c], lat[r]], axis=-1)), blend)))
            src_lon[r, c], src_lat[r, c] = shown[:, 0], shown[:, 1]
        return src_lon, src_lat

    return filled
