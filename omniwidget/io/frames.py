"""Inverse maps saved to files: read and checked.

A map holds, for each output pixel, the input ``[lon, lat]`` in degrees it shows
(``Result.inverse_map()``, or a map saved by ``omniwidget warp --map``). :func:`load_map`
reads one back; :func:`checked_map` says what is wrong with an array that is not one.
Applying a map to many frames is :mod:`omniwidget.app.frames`.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ImageError
from .images import check_fits

__all__ = ["checked_map", "load_map"]


def checked_map(inverse_map: ArrayLike) -> NDArray[np.floating]:
    """``inverse_map`` as an array, if it is a map of ``[lon, lat]`` degrees; else an ImageError saying what is wrong.

    Parameters
    ----------
    inverse_map : array_like, shape (H, 2H, 2)
        Finite floating-point ``[lon, lat]`` degrees: latitudes in [-90, 90], longitudes in [-360, 360].

    Raises
    ------
    ImageError
        The shape, the type or the values are not a map's.
    """
    m = np.asarray(inverse_map)
    if m.ndim != 3 or m.shape[2] != 2 or m.shape[1] != 2 * m.shape[0] or m.shape[0] < 1:
        raise ImageError(f"a map must have shape (H, 2H, 2) of [lon, lat] degrees, got {m.shape}")
    if not np.issubdtype(m.dtype, np.floating) or not np.all(np.isfinite(m)):
        raise ImageError("a map must hold finite floating-point [lon, lat] degrees")
    if np.abs(m[..., 1]).max() > 90.0 + 1e-4 or np.abs(m[..., 0]).max() > 360.0:
        raise ImageError("a map's latitudes must lie in [-90, 90] and its longitudes in [-360, 360] degrees")
    return m


def load_map(path: str | os.PathLike[str]) -> NDArray[np.float32]:
    """Read a map saved by ``omniwidget warp --map`` (``.npy``, float32 ``(H, 2H, 2)`` of ``[lon, lat]``).

    Parameters
    ----------
    path : path-like

    Returns
    -------
    ndarray of float32, shape (H, 2H, 2)

    Raises
    ------
    ImageError
        If the file cannot be read or does not hold such a map.
    """
    path = Path(path)
    if path.exists():  # a header that declares more than memory holds is refused by name, before anything is allocated
        check_fits(path)
    try:
        m = np.load(path, allow_pickle=False)
    except (OSError, ValueError) as exc:
        raise ImageError(f"{path}: cannot read the map ({exc})") from None
    try:
        checked_map(m)
    except ImageError as exc:
        raise ImageError(f"{path}: {exc}") from None
    return np.asarray(m, np.float32)
