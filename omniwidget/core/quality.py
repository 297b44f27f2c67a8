"""Quality figures of a warp, measured from its maps: straightness of lines, conformal distortion."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import coords

__all__ = ["conformal_distortion", "local_jacobians", "straightness"]


def straightness(curve: ArrayLike, width: int) -> float:
    """Largest distance, in pixels of an image ``width`` wide, of a curve from the chord of its ends.

    Parameters
    ----------
    curve : array_like, shape (n, 2)
        ``[lon, lat]`` in degrees, in order along the curve (for example a line's image,
        sampled densely). Longitudes are unwrapped along the curve, so curves across the
        ±180° seam are measured as they appear when the image is scrolled.
    width : int
        Image width: 1 pixel is ``360 / width`` degrees.

    Returns
    -------
    float
        ``max`` over the samples of their distance from the segment joining the first and
        last sample, in pixels.
    """
    pts = np.array(curve, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 2:
        raise ValueError(f"expected a curve of shape (n >= 2, 2), got {pts.shape}")
    pts[:, 0] = np.unwrap(pts[:, 0], period=360.0)
    px = pts * (width / 360.0)
    a, b = px[0], px[-1]
    chord = b - a
    length = np.hypot(*chord)
    if length == 0:
        return float(np.max(np.hypot(*(px - a).T)))
    t = np.clip(((px - a) @ chord) / length**2, 0.0, 1.0)
    nearest = a + t[:, None] * chord
    return float(np.max(np.hypot(*(px - nearest).T)))


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
    """
    m = np.asarray(inverse_map, dtype=np.float64)
    if m.ndim != 3 or m.shape[2] != 2 or m.shape[1] != 2 * m.shape[0] or m.shape[0] < 3:
        raise ValueError(f"expected an inverse map of shape (H, 2H, 2) with H >= 3, got {m.shape}")
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


def conformal_distortion(inverse_map: ArrayLike) -> tuple[float, NDArray[np.float64]]:
    """Conformal distortion of a warp: the ratio of the map's singular values, minus 1.

    Parameters
    ----------
    inverse_map : array_like, shape (H, W, 2)
        See :func:`local_jacobians`.

    Returns
    -------
    mean : float
        Mean over the sphere, each pixel weighted by its area (``cos lat``).
    per_pixel : ndarray of float64, shape (H - 2, W)
        ``sigma_max / sigma_min - 1`` at output rows ``1 .. H - 2``; 0 for a conformal map.
    """
    sv = np.linalg.svd(local_jacobians(inverse_map), compute_uv=False)
    ratio = sv[..., 0] / sv[..., 1] - 1.0
    _, lat = coords.grid_lonlat(ratio.shape[1])
    area = np.broadcast_to(np.cos(np.radians(lat[1:-1]))[:, None], ratio.shape)
    return float(np.sum(ratio * area) / np.sum(area)), ratio
