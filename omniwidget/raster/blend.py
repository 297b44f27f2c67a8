"""The blend of eq. (2): each output direction's source is the weighted sum of the controls' inverse maps.

``T⁻¹(p) = normalize(Σ_j W_j(p) M_j⁻¹(p))``: the weights are interpolated from the mesh
at ``p`` (barycentric on the triangle whose cone contains ``p``), each inverse map is
applied as a 3D unit vector, and the sum is normalised back onto the sphere. A control
whose weight is negligible over a whole block of rows costs nothing there.

For teaching, the authors' two shortcuts can be switched on: ``projection="asin"`` takes
the latitude as ``asin`` of the un-normalised sum's ``z`` (a bias towards the equator
wherever the maps disagree), and :func:`grid_pixel_weights` interpolates the weights from
a coarse longitude/latitude grid (their 150 x 75) instead of the mesh.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from ..method.locate import interpolate, locate_points
from ..sphere import coords
from ..sphere.moebius import Moebius
from .warping import GridInverse, grid_homogeneous

__all__ = ["NEGLIGIBLE", "PixelWeights", "blended_inverse", "grid_pixel_weights", "mesh_blended_inverse", "mesh_pixel_weights"]

#: A control whose normalised weight stays below this over a block of rows is skipped there.
NEGLIGIBLE = 1e-6


#: ``fn(rows) -> (h, W, k)`` weights of the output pixels in a block of rows.
PixelWeights = Callable[[slice], NDArray[np.floating]]


def mesh_pixel_weights(
    faces: NDArray[np.int64],
    vertex_weights: NDArray[np.floating],
    face: NDArray[np.int32],
    bary: NDArray[np.float32],
    dtype: type[np.floating] = np.float32,
) -> PixelWeights:
    """Pixel weights interpolated from the mesh: barycentric on each pixel's triangle.

    Parameters
    ----------
    faces : ndarray of int64, shape (m, 3)
        The mesh's faces.
    vertex_weights : ndarray, shape (n, k)
        Normalised weights per mesh vertex (rows sum to 1).
    face, bary : ndarray, shapes (H, W) and (H, W, 3)
        For each output pixel, its mesh face and barycentric coordinates
        (:func:`omniwidget.method.locate.locate_grid`).
    dtype : numpy floating type
    """
    weights = np.ascontiguousarray(vertex_weights, dtype=dtype)
    return lambda rows: interpolate(weights, faces, face[rows], bary[rows])


def grid_pixel_weights(
    vertices: NDArray[np.float64], faces: NDArray[np.int64], vertex_weights: NDArray[np.floating], width: int, grid: int = 150
) -> PixelWeights:
    """Pixel weights interpolated bilinearly from a ``grid`` x ``grid / 2`` longitude/latitude grid.

    The authors' shortcut (150 x 75): the weights are evaluated on the mesh at the grid's
    nodes only, so they blur wherever they change fast, which is along the handles.

    Parameters
    ----------
    vertices, faces : ndarray, shapes (n, 3) and (m, 3)
    vertex_weights : ndarray, shape (n, k)
    width : int
        Output width.
    grid : int
        Grid nodes around the equator (even); nodes sit at pixel centres of a ``grid``
        wide equirectangular image.
    """
    lon, lat = coords.grid_lonlat(grid)
    nodes = coords.lonlat_to_xyz(np.stack(np.meshgrid(lon, lat), axis=-1)).reshape(-1, 3)
    face, bary = locate_points(vertices, faces, nodes)
    at_nodes = interpolate(np.asarray(vertex_weights, np.float64), faces, face, bary).reshape(grid // 2, grid, -1)
    at_nodes = np.concatenate([at_nodes, at_nodes[:, :1]], axis=1)  # wrap at the seam
    x = (np.arange(width) + 0.5) * grid / width - 0.5
    x0 = np.floor(x).astype(np.int64)
    fx = (x - x0)[None, :, None]
    x0 %= grid

    def fn(rows: slice) -> NDArray[np.float64]:
        y = np.clip((np.arange(width // 2)[rows] + 0.5) * grid / width - 0.5, 0, grid // 2 - 1)
        y0 = np.minimum(np.floor(y).astype(np.int64), grid // 2 - 2)
        fy = (y - y0)[:, None, None]
        top = at_nodes[y0][:, x0] * (1 - fx) + at_nodes[y0][:, x0 + 1] * fx
        bottom = at_nodes[y0 + 1][:, x0] * (1 - fx) + at_nodes[y0 + 1][:, x0 + 1] * fx
        return top * (1 - fy) + bottom * fy

    return fn


def blended_inverse(
    inverses: Sequence[Moebius],
    pixel_weights: PixelWeights,
    precision: Literal["double", "single"] = "single",
    projection: Literal["normalize", "asin"] = "normalize",
) -> GridInverse:
    """The blended inverse map of eq. (2) as a grid evaluator.

    Parameters
    ----------
    inverses : sequence of Moebius
        ``M_j⁻¹`` for the ``k`` controls.
    pixel_weights : PixelWeights
        The controls' weights at the output pixels, usually :func:`mesh_pixel_weights`.
    precision : {"double", "single"}
        Arithmetic of the per-pixel work.
    projection : {"normalize", "asin"}
        How the weighted sum of unit vectors returns to the sphere: normalised (ours), or
        the authors' ``asin`` of its ``z`` (biased towards the equator where maps disagree).

    Returns
    -------
    GridInverse
        ``fn(lon, lat, rows) -> (src_lon, src_lat)`` in radians.
    """
    if projection not in ("normalize", "asin"):
        raise ValueError(f"projection must be 'normalize' or 'asin', got {projection!r}")
    real = np.float64 if precision == "double" else np.float32

    def fn(lon: NDArray[np.float64], lat: NDArray[np.float64], rows: slice) -> tuple[NDArray, NDArray]:
        w = pixel_weights(rows)  # (h, W, k)
        if w.shape[-1] != len(inverses):
            raise ValueError(f"{len(inverses)} maps but {w.shape[-1]} weights per pixel")
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
        if projection == "asin":
            return np.angle(acc_xy), np.arcsin(np.clip(acc_z, -1, 1))
        return np.angle(acc_xy), np.arctan2(acc_z, np.abs(acc_xy))

    return fn


#: Rows of a band in which :func:`mesh_blended_inverse` evaluates each control on the box of the pixels it weighs on.
_BAND = 32


def mesh_blended_inverse(
    inverses: Sequence[Moebius], faces: NDArray[np.int64], vertex_weights: NDArray[np.floating], face: NDArray[np.int32], bary: NDArray[np.float32]
) -> GridInverse:
    """``blended_inverse(inverses, mesh_pixel_weights(faces, vertex_weights, face, bary, np.float64), "double")``, faster.

    The still background keeps each control's weights local (few pixel and control pairs are not 0): in each band
    of :data:`_BAND` rows a control's weights are interpolated, and its map evaluated, only on the box of the pixels
    whose triangle has a vertex where its weight is not 0. The sums are the same as over the whole grid (the other
    pixels add 0), in the same order; numpy's vectorised sines and cosines may round a shorter row's elements
    differently, in the last digits. The gain is largest in the default mode and small in the paper's (weights
    everywhere); the figures are in ``bench/RESULTS.md``.

    Parameters
    ----------
    inverses : sequence of Moebius
        ``M_j⁻¹`` for the ``k`` controls.
    faces : ndarray of int64, shape (m, 3)
    vertex_weights : ndarray, shape (n, k)
        Non-negative.
    face, bary : ndarray, shapes (H, W) and (H, W, 3)
        From :func:`omniwidget.method.locate.locate_grid`.

    Returns
    -------
    GridInverse
        ``fn(lon, lat, rows) -> (src_lon, src_lat)`` in radians, float64.
    """
    weights = np.ascontiguousarray(vertex_weights, dtype=np.float64)
    if weights.shape[1] != len(inverses):
        raise ValueError(f"{len(inverses)} maps but {weights.shape[1]} weights per vertex")
    touches = (weights != 0)[faces].any(axis=1)  # (m, k): the controls each triangle has a weight of

    def fn(lon: NDArray[np.float64], lat: NDArray[np.float64], rows: slice) -> tuple[NDArray, NDArray]:
        acc_xy = np.zeros((len(lat), len(lon)), np.complex128)
        acc_z = np.zeros((len(lat), len(lon)), np.float64)
        block_face, block_bary = face[rows], bary[rows]
        boxes: list[list[tuple[tuple[slice, slice], NDArray[np.float64]]]] = [[] for _ in inverses]
        for top in range(0, len(lat), _BAND):
            band_face = block_face[top : top + _BAND]
            band_corner = faces[band_face]
            band_bary = block_bary[top : top + _BAND].astype(np.float64)
            for j in np.flatnonzero(touches[np.unique(band_face)].any(axis=0)):
                inside = touches[band_face, j]
                cols = np.flatnonzero(inside.any(axis=0))
                rows_in = np.flatnonzero(inside.any(axis=1))
                here = slice(int(rows_in[0]), int(rows_in[-1]) + 1), slice(int(cols[0]), int(cols[-1]) + 1)
                box = slice(top + here[0].start, top + here[0].stop), here[1]
                corner, b = band_corner[here], band_bary[here]
                wj = b[..., 0] * weights[corner[..., 0], j]  # as interpolate sums them
                wj += b[..., 1] * weights[corner[..., 1], j]
                wj += b[..., 2] * weights[corner[..., 2], j]
                boxes[j].append((box, wj))
        for control, m in enumerate(inverses):
            if not max((float(wj.max()) for _, wj in boxes[control]), default=0.0) > NEGLIGIBLE:
                continue  # as blended_inverse skips it over this block
            for box, wj in boxes[control]:
                big_u, big_v = grid_homogeneous(m, lon[box[1]], lat[box[0]], "double")
                uu = big_u.real**2 + big_u.imag**2
                vv = big_v.real**2 + big_v.imag**2
                s = wj / (uu + vv)
                acc_xy[box] += (2 * s) * (big_u * np.conj(big_v))
                acc_z[box] += s * (uu - vv)
        return np.angle(acc_xy), np.arctan2(acc_z, np.abs(acc_xy))

    return fn
