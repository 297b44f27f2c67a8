"""The blend of eq. (2): each output direction's source is the weighted sum of the controls' inverse maps.

``T⁻¹(p) = normalize(Σ_j W_j(p) M_j⁻¹(p))``: the weights are interpolated from the mesh
at ``p`` (barycentric on the triangle whose cone contains ``p``), each inverse map is
applied as a 3D unit vector, and the sum is normalised back onto the sphere (the authors
took ``asin`` of the un-normalised sum, a latitude bias). A control whose weight is
negligible over a whole block of rows costs nothing there.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from .locate import interpolate
from .moebius import Moebius
from .warping import GridInverse, grid_homogeneous

__all__ = ["NEGLIGIBLE", "blended_inverse"]

#: A control whose normalised weight stays below this over a block of rows is skipped there.
NEGLIGIBLE = 1e-6


def blended_inverse(
    inverses: Sequence[Moebius],
    faces: NDArray[np.int64],
    vertex_weights: NDArray[np.floating],
    face: NDArray[np.int32],
    bary: NDArray[np.float32],
    precision: Literal["double", "single"] = "single",
) -> GridInverse:
    """The blended inverse map of eq. (2) as a grid evaluator.

    Parameters
    ----------
    inverses : sequence of Moebius
        ``M_j⁻¹`` for the ``k`` controls.
    faces : ndarray of int64, shape (m, 3)
        The mesh's faces.
    vertex_weights : ndarray, shape (n, k)
        Normalised weights per mesh vertex (rows sum to 1).
    face, bary : ndarray, shapes (H, W) and (H, W, 3)
        For each output pixel, its mesh face and barycentric coordinates
        (:func:`omniwidget.core.locate.locate_grid`).
    precision : {"double", "single"}
        Arithmetic of the per-pixel work.

    Returns
    -------
    GridInverse
        ``fn(lon, lat, rows) -> (src_lon, src_lat)`` in radians.
    """
    if vertex_weights.shape[1] != len(inverses):
        raise ValueError(f"{len(inverses)} maps but {vertex_weights.shape[1]} weight columns")
    real = np.float64 if precision == "double" else np.float32
    weights = np.ascontiguousarray(vertex_weights, dtype=real)

    def fn(lon: NDArray[np.float64], lat: NDArray[np.float64], rows: slice) -> tuple[NDArray, NDArray]:
        w = interpolate(weights, faces, face[rows], bary[rows])  # (h, W, k)
        acc_xy = np.zeros((len(lat), len(lon)), np.complex128 if precision == "double" else np.complex64)
        acc_z = np.zeros((len(lat), len(lon)), real)
        for j, m in enumerate(inverses):
            wj = w[..., j]
            if not wj.max() > NEGLIGIBLE:
                continue
            big_u, big_v = grid_homogeneous(m, lon, lat, precision)
            uu = big_u.real**2 + big_u.imag**2
            vv = big_v.real**2 + big_v.imag**2
            s = wj / (uu + vv)  # unit vector: (2 U V̄, |U|² - |V|²) / (|U|² + |V|²)
            acc_xy += (2 * s) * (big_u * np.conj(big_v))
            acc_z += s * (uu - vv)
        return np.angle(acc_xy), np.arctan2(acc_z, np.abs(acc_xy))

    return fn
