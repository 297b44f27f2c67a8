"""Where a warp turns the image over: the fold check every warp runs, written once.

A blend of maps that disagree can mirror part of the sphere (the paper's Fig. 15). The rule
is the sign of the inverse map's Jacobian determinant (:func:`fold_over`); on a warp's
source pixel coordinates the compiled kernel applies the same rule when it is there
(:func:`fold_of_coordinates`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import check_inverse_map
from ..sphere import coords
from . import _kernels
from .warping import coordinates_lonlat

__all__ = ["FoldOver", "fold_of_coordinates", "fold_over", "turned_over"]


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
        return cls(mask, float(np.count_nonzero(mask, axis=1) @ coords.row_area(len(mask))))

    @classmethod
    def none(cls, shape: tuple[int, ...]) -> FoldOver:
        """No fold-over on an output of ``shape`` (H, W[, C]): what a single Möbius map gives, being one-to-one."""
        return cls(np.zeros(shape[:2], dtype=bool), 0.0)


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
    m = check_inverse_map(inverse_map, np.float32 if np.asarray(inverse_map).dtype == np.float32 else np.float64)
    mask = np.zeros(m.shape[:2], dtype=bool)
    mask[1:-1] = turned_over(np.concatenate([m[:, -1:], m, m[:, :1]], axis=1), pole_margin)  # columns wrap at the seam
    return FoldOver.from_mask(mask)


def turned_over(lonlat: NDArray[np.floating], pole_margin: float = 1.0) -> NDArray[np.bool_]:
    """The rule of :func:`fold_over` on any window of an inverse map: its inner pixels whose determinant is <= 0.

    Parameters
    ----------
    lonlat : ndarray, shape (h, w, 2)
        Input ``[lon, lat]`` in degrees on a window of output pixels (rows southwards,
        columns eastwards), ``h, w >= 3``.
    pole_margin : float
        See :func:`fold_over`.

    Returns
    -------
    ndarray of bool, shape (h - 2, w - 2)
        For each pixel not on the window's rim (central differences need both neighbours).
    """
    lon, lat = lonlat[..., 0], lonlat[..., 1]

    def wrapped(d: NDArray) -> NDArray:
        return (d + 180) % 360 - 180

    d_lon_east, d_lat_east = wrapped(lon[1:-1, 2:] - lon[1:-1, :-2]), lat[1:-1, 2:] - lat[1:-1, :-2]
    d_lon_north, d_lat_north = wrapped(lon[:-2, 1:-1] - lon[2:, 1:-1]), lat[:-2, 1:-1] - lat[2:, 1:-1]
    return np.asarray((d_lon_east * d_lat_north - d_lon_north * d_lat_east <= 0) & (np.abs(lat[1:-1, 1:-1]) < 90 - pole_margin))


def fold_of_coordinates(coordinates: NDArray[np.float32], src_width: int) -> FoldOver:
    """:func:`fold_over` of the map a warp resamples by, from its source pixel coordinates.

    Parameters
    ----------
    coordinates : ndarray of float32, shape (H, W, 2)
        ``(x, y)`` in the source padded by :data:`~omniwidget.raster.warping.PAD`
        (:func:`~omniwidget.raster.warping.remap_coordinates`).
    src_width : int
        Width of the source image.

    Returns
    -------
    FoldOver
    """
    if _kernels.available():
        return FoldOver.from_mask(_kernels.fold_mask(coordinates, src_width))
    return fold_over(coordinates_lonlat(coordinates, src_width, np.float32))  # float32: enough for the signs
