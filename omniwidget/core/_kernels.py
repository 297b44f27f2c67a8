"""Compiled per-pixel kernels (numba), used by :func:`omniwidget.core.pipeline.warp` when numba is installed.

The numpy path of the blend (:mod:`omniwidget.core.blend`) makes a pass over the whole
image per control and per operation; here each output pixel is done in one go: its
barycentric coordinates in its face, its weights, the Möbius maps whose weight is not
negligible there, the normalised sum of eq. (2) and its source pixel. The same per-pixel
work runs on chosen blocks of pixels for the sampled blend (:mod:`omniwidget.core.sampled`),
beside the bilinear interpolation of the samples elsewhere; the fold check
(:func:`omniwidget.core.quality.fold_over`'s rule), the painting of the pixels' faces
(:func:`omniwidget.core.locate.locate_faces`) and the weights named in a fold warning are
one pass each. The kernels release
the GIL and run on blocks of rows in threads (not numba's own parallel layer, which does
not allow two threads to launch kernels at once, as the editor's preview and a full-size
warp may).

Without numba (``pip install numba``, or the ``fast`` extra), or with the environment
variable ``OMNIWIDGET_NUMBA=0``, :func:`available` is False and the numpy path runs; the
two agree to float32 rounding (``tests/test_kernels.py``).
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from functools import cache
from types import SimpleNamespace

import numpy as np
from numpy.typing import NDArray

from . import coords
from .locate import EDGE_TOLERANCE, face_neighbours
from .moebius import Moebius
from .warping import PAD, _run_blocks

__all__ = ["available", "blend_blocks", "blend_coordinates", "fold_mask", "interpolate_shift", "paint", "strongest_weights", "walk_blend"]

#: Weights at most this are skipped (the numpy path skips a control only where it is below
#: :data:`omniwidget.core.blend.NEGLIGIBLE` over a whole block of rows; both are far below
#: what a pixel can show).
_NEGLIGIBLE = 1e-9
#: Faces a pixel's walk from its neighbour's face crosses, at most, before it is left to a slower search.
WALK_STEPS = 256


@cache
def available() -> bool:
    """Whether the compiled kernels can be used: numba imports and ``OMNIWIDGET_NUMBA`` is not ``0``."""
    if os.environ.get("OMNIWIDGET_NUMBA", "1") == "0":
        return False
    try:
        import numba  # noqa: F401
    except ImportError:
        return False
    return True


@cache
def _compiled() -> SimpleNamespace:
    """The kernels, compiled on first use (and cached on disk by numba)."""
    from numba import njit

    @njit(nogil=True, cache=True, inline="always")
    def corner_shares(planes, f, x, y, z):  # pragma: no cover
        """Barycentric coordinates of (x, y, z) in face f: b_i ∝ max(p · planes[f, i + 1], 0)."""
        s0 = max(planes[f, 0, 0] * x + planes[f, 0, 1] * y + planes[f, 0, 2] * z, 0.0)
        s1 = max(planes[f, 1, 0] * x + planes[f, 1, 1] * y + planes[f, 1, 2] * z, 0.0)
        s2 = max(planes[f, 2, 0] * x + planes[f, 2, 1] * y + planes[f, 2, 2] * z, 0.0)
        total = s0 + s1 + s2
        if total <= 0.0:
            total = 1.0
        return s1 / total, s2 / total, s0 / total

    @njit(nogil=True, cache=True, inline="always")
    def blend_pixel(f, x, y, z, planes, corners, weights, mats):  # pragma: no cover
        """Eq. (2) at the unit vector (x, y, z) in face f: the source's (lon, lat) in radians."""
        b0, b1, b2 = corner_shares(planes, f, x, y, z)
        i0, i1, i2 = corners[f, 0], corners[f, 1], corners[f, 2]
        if z <= 0.0:  # [u : v] as coords.xyz_to_homogeneous chooses it
            ur, ui, vr, vi = x, y, 1.0 - z, 0.0
        else:
            ur, ui, vr, vi = 1.0 + z, 0.0, x, -y
        sum_r = 0.0
        sum_i = 0.0
        sum_z = 0.0
        for j in range(weights.shape[1]):
            w = b0 * weights[i0, j] + b1 * weights[i1, j] + b2 * weights[i2, j]
            if w <= _NEGLIGIBLE:
                continue
            ar, ai, br, bi = mats[j, 0], mats[j, 1], mats[j, 2], mats[j, 3]
            cr, ci, dr, di = mats[j, 4], mats[j, 5], mats[j, 6], mats[j, 7]
            big_ur = ar * ur - ai * ui + br * vr - bi * vi
            big_ui = ar * ui + ai * ur + br * vi + bi * vr
            big_vr = cr * ur - ci * ui + dr * vr - di * vi
            big_vi = cr * ui + ci * ur + dr * vi + di * vr
            uu = big_ur * big_ur + big_ui * big_ui
            vv = big_vr * big_vr + big_vi * big_vi
            share = w / (uu + vv)  # the unit vector (2 U V̄, |U|² - |V|²) / (|U|² + |V|²)
            sum_r += 2.0 * share * (big_ur * big_vr + big_ui * big_vi)
            sum_i += 2.0 * share * (big_ui * big_vr - big_ur * big_vi)
            sum_z += share * (uu - vv)
        return math.atan2(sum_i, sum_r), math.atan2(sum_z, math.sqrt(sum_r * sum_r + sum_i * sum_i))

    @njit(nogil=True, cache=True)
    def blend_rows(r0, r1, face, planes, corners, weights, mats, cos_lon, sin_lon, cos_lat, sin_lat, kx, x0, y0, out):  # pragma: no cover
        for r in range(r0, r1):
            for c in range(face.shape[1]):
                lon, lat = blend_pixel(
                    face[r, c], cos_lat[r] * cos_lon[c], cos_lat[r] * sin_lon[c], sin_lat[r], planes, corners, weights, mats
                )
                out[r, c, 0] = lon * kx + x0
                out[r, c, 1] = y0 - lat * kx

    @njit(nogil=True, cache=True, inline="always")
    def walk_to(g, x, y, z, planes, slack, neighbours, steps):  # pragma: no cover
        """The face holding (x, y, z), walked to from face g across the edges it lies beyond; -1 after ``steps`` faces.

        A visibility walk: on a Delaunay mesh of the sphere (a convex hull, as the adaptive
        mesh is) it cannot cycle, and from a nearby pixel's face it takes a step or two.
        """
        for n in range(steps + 1):
            worst, across = 0.0, -1
            for e in range(3):
                s = planes[g, e, 0] * x + planes[g, e, 1] * y + planes[g, e, 2] * z + slack[g, e]
                if s < worst:
                    worst, across = s, e
            if across < 0:
                return g
            if n == steps:
                break
            g = neighbours[g, across]
        return -1

    @njit(nogil=True, cache=True)
    def walk_blend_rows(
        r0,
        r1,
        seed,
        planes,
        slack,
        neighbours,
        walk,
        corners,
        weights,
        mats,
        cos_lon,
        sin_lon,
        cos_lat,
        sin_lat,
        kx,
        x0,
        y0,
        out,
        face,
        missed,
    ):  # pragma: no cover
        first = walk_to(seed, cos_lat[r0] * cos_lon[0], cos_lat[r0] * sin_lon[0], sin_lat[r0], planes, slack, neighbours, planes.shape[0])
        for r in range(r0, r1):
            g = first
            for c in range(face.shape[1]):
                x = cos_lat[r] * cos_lon[c]
                y = cos_lat[r] * sin_lon[c]
                z = sin_lat[r]
                f = walk_to(g, x, y, z, planes, slack, neighbours, walk) if g >= 0 else -1
                face[r, c] = f
                if f < 0:
                    missed[r, c] = True
                    continue
                if c == 0:
                    first = f  # the next row starts from here
                g = f
                lon, lat = blend_pixel(f, x, y, z, planes, corners, weights, mats)
                out[r, c, 0] = lon * kx + x0
                out[r, c, 1] = y0 - lat * kx

    @njit(nogil=True, cache=True)
    def blend_cells(
        n0,
        n1,
        cell_r,
        cell_c,
        step,
        samples,
        planes,
        slack,
        neighbours,
        walk,
        corners,
        weights,
        mats,
        cos_lon,
        sin_lon,
        cos_lat,
        sin_lat,
        kx,
        x0,
        y0,
        out,
        missed,
    ):  # pragma: no cover
        for n in range(n0, n1):
            i, j = cell_r[n], cell_c[n]
            g = samples[i, j]
            for r in range(i * step, (i + 1) * step):
                for c in range(j * step, (j + 1) * step):
                    x = cos_lat[r] * cos_lon[c]
                    y = cos_lat[r] * sin_lon[c]
                    z = sin_lat[r]
                    f = walk_to(g, x, y, z, planes, slack, neighbours, walk)
                    if f < 0:
                        missed[r, c] = True
                        continue
                    g = f  # the next pixel starts from its neighbour's face
                    lon, lat = blend_pixel(f, x, y, z, planes, corners, weights, mats)
                    out[r, c, 0] = lon * kx + x0
                    out[r, c, 1] = y0 - lat * kx

    @njit(nogil=True, cache=True)
    def interpolate_rows(r0, r1, shift, step, exact, column, part, base_x, src_width, per_degree, lat, pad, out):  # pragma: no cover
        rows_c, cols_c = exact.shape
        row_x = np.empty(shift.shape[1])
        row_y = np.empty(shift.shape[1])
        for r in range(r0, r1):
            yc = min(max((r + 0.5) / step - 0.5, 0.0), rows_c - 1.0)
            i0 = min(int(yc), rows_c - 2) if rows_c > 1 else 0
            fy = yc - i0
            for j in range(shift.shape[1]):  # the samples' displacements interpolated to this row
                row_x[j] = shift[i0, j, 0] + fy * (shift[i0 + 1, j, 0] - shift[i0, j, 0])
                row_y[j] = shift[i0, j, 1] + fy * (shift[i0 + 1, j, 1] - shift[i0, j, 1])
            base_y = (90.0 - lat[r]) * per_degree - 0.5 + pad
            skip = exact[r // step]
            for c in range(out.shape[1]):
                if skip[c // step]:
                    continue
                j0, fx = column[c], part[c]
                x = base_x[c] + row_x[j0] + fx * (row_x[j0 + 1] - row_x[j0])  # x + 0.5 of the unpadded source
                if x >= src_width:
                    x -= src_width
                elif x < 0.0:
                    x += src_width
                out[r, c, 0] = x - 0.5 + pad
                out[r, c, 1] = base_y + row_y[j0] + fx * (row_y[j0 + 1] - row_y[j0])

    @njit(nogil=True, cache=True)
    def fold_rows(r0, r1, coordinates, src_width, offset, top, bottom, mask):  # pragma: no cover
        width = coordinates.shape[1]
        half = 0.5 * src_width
        for r in range(max(r0, 1), min(r1, coordinates.shape[0] - 1)):
            for c in range(width):
                east = c + 1 if c + 1 < width else 0
                west = c - 1 if c > 0 else width - 1
                dx_e = coordinates[r, east, 0] - coordinates[r, west, 0]
                if dx_e > half:  # longitudes wrap
                    dx_e -= src_width
                elif dx_e < -half:
                    dx_e += src_width
                dy_e = coordinates[r, east, 1] - coordinates[r, west, 1]
                dx_n = coordinates[r - 1, c, 0] - coordinates[r + 1, c, 0]
                if dx_n > half:
                    dx_n -= src_width
                elif dx_n < -half:
                    dx_n += src_width
                dy_n = coordinates[r - 1, c, 1] - coordinates[r + 1, c, 1]
                y = coordinates[r, c, 1] - offset
                # lon grows with x, lat against y: the determinant in [lon, lat] is minus this one
                mask[r, c] = (dx_e * dy_n - dx_n * dy_e >= 0.0) and top < y < bottom

    @njit(nogil=True, cache=True)
    def paint_runs(run_face, flat_start, length, out):  # pragma: no cover
        for i in range(run_face.shape[0]):
            start = flat_start[i]
            for j in range(start, start + length[i]):
                out[j] = run_face[i]

    @njit(nogil=True, cache=True)
    def strongest(rows, cols, face, planes, corners, weights, cos_lon, sin_lon, cos_lat, sin_lat, out):  # pragma: no cover
        for n in range(rows.shape[0]):
            r, c = rows[n], cols[n]
            f = face[r, c]
            x = cos_lat[r] * cos_lon[c]
            y = cos_lat[r] * sin_lon[c]
            z = sin_lat[r]
            b0, b1, b2 = corner_shares(planes, f, x, y, z)
            i0, i1, i2 = corners[f, 0], corners[f, 1], corners[f, 2]
            for j in range(weights.shape[1]):
                w = b0 * weights[i0, j] + b1 * weights[i1, j] + b2 * weights[i2, j]
                if w > out[j]:
                    out[j] = w

    return SimpleNamespace(
        blend_rows=blend_rows,
        blend_cells=blend_cells,
        walk_blend_rows=walk_blend_rows,
        interpolate_rows=interpolate_rows,
        fold_rows=fold_rows,
        paint_runs=paint_runs,
        strongest=strongest,
    )


def _matrices(inverses: Sequence[Moebius]) -> NDArray[np.float64]:
    m = np.array([np.asarray(i.matrix, np.complex128).ravel() for i in inverses])
    return np.ascontiguousarray(np.stack([m.real, m.imag], axis=-1).reshape(len(inverses), 8))


def blend_coordinates(
    face: NDArray[np.int32],
    planes: NDArray[np.float64],
    faces: NDArray[np.int64],
    weights: NDArray[np.floating],
    inverses: Sequence[Moebius],
    src_width: int,
) -> NDArray[np.float32]:
    """Source pixel coordinates of every output pixel under the blend of eq. (2).

    Parameters
    ----------
    face, planes : ndarray
        From :func:`omniwidget.core.locate.locate_faces`: (H, W) int32 and (m, 3, 3) float64.
    faces : ndarray of int64, shape (m, 3)
    weights : ndarray, shape (n, k)
        Normalised weights per mesh vertex.
    inverses : sequence of Moebius
        ``M_j⁻¹`` of the ``k`` controls.
    src_width : int
        Width of the source panorama.

    Returns
    -------
    ndarray of float32, shape (H, W, 2)
        What :func:`omniwidget.core.warping.remap_coordinates` returns for the numpy blend.
    """
    blend_rows = _compiled().blend_rows
    height, width = face.shape
    out = np.empty((height, width, 2), np.float32)
    mesh, grid = _mesh_args(planes, faces, weights, inverses), _grid_args(width, src_width)
    face = np.ascontiguousarray(face)
    _run_blocks(height, lambda rows: blend_rows(rows.start, rows.stop, face, *mesh, *grid, out))
    return out


def walk_blend(
    vertices: NDArray[np.float64],
    faces: NDArray[np.int64],
    weights: NDArray[np.floating],
    inverses: Sequence[Moebius],
    width: int,
    src_width: int,
    walk: int = WALK_STEPS,
    neighbours: NDArray[np.int32] | None = None,
) -> tuple[NDArray[np.float32], NDArray[np.int32], NDArray[np.float64]]:
    """:func:`blend_coordinates` on a whole grid, each pixel's face found by walking from its neighbour's.

    Along a row each pixel's face is walked to across the mesh's edges from the face of the
    pixel before it (a step or two at most, since neighbours lie a pixel apart), and each row
    starts from the face of the first pixel of the row above. No pass paints the faces first
    (:func:`omniwidget.core.locate.locate_faces`); should a walk not arrive within ``walk``
    faces (it cannot cycle on a convex-hull mesh such as the adaptive mesh, but the mesh
    might be another), the grid is located and blended the painted way instead.

    Parameters
    ----------
    vertices, faces : ndarray, shapes (n, 3) float64 and (m, 3) int64
        A closed, outward-oriented mesh of the unit sphere.
    weights, inverses, src_width
        As in :func:`blend_coordinates`.
    width : int
        Output width (even); the height is ``width / 2``.
    walk : int
        Faces one pixel's walk may cross.
    neighbours : ndarray of int32, shape (m, 3), optional
        :func:`omniwidget.core.locate.face_neighbours` of ``faces``, when the caller has it.

    Returns
    -------
    coordinates : ndarray of float32, shape (width / 2, width, 2)
        As :func:`blend_coordinates` gives.
    face : ndarray of int32, shape (width / 2, width)
        Each pixel's face.
    planes : ndarray of float64, shape (m, 3, 3)
        The faces' edge planes, as :func:`omniwidget.core.locate.locate_faces` gives them.
    """
    kernel = _compiled().walk_blend_rows
    v = np.asarray(vertices, np.float64)
    f = np.ascontiguousarray(faces, np.int64)
    corner = [v[f[:, k]] for k in range(3)]
    planes = np.ascontiguousarray(np.stack([np.cross(corner[k], corner[(k + 1) % 3]) for k in range(3)], axis=1))
    slack = EDGE_TOLERANCE * np.linalg.norm(planes, axis=2)
    neighbours = face_neighbours(f) if neighbours is None else neighbours
    mesh = _mesh_args(planes, f, weights, inverses)
    height = width // 2
    grid = _grid_args(width, src_width)
    out = np.empty((height, width, 2), np.float32)
    face = np.empty((height, width), np.int32)
    missed = np.zeros((height, width), dtype=bool)
    _run_blocks(
        height,
        lambda rows: kernel(rows.start, rows.stop, 0, planes, slack, neighbours, walk, *mesh[1:], *grid, out, face, missed),
    )
    if missed.any():
        from .locate import locate_faces

        face, planes = locate_faces(v, f, width)
        out = blend_coordinates(face, planes, f, weights, inverses, src_width)
    return out, face, planes


def blend_blocks(
    cells: NDArray[np.bool_],
    samples: NDArray[np.int32],
    planes: NDArray[np.float64],
    faces: NDArray[np.int64],
    weights: NDArray[np.floating],
    inverses: Sequence[Moebius],
    src_width: int,
    out: NDArray[np.float32],
    walk: int = WALK_STEPS,
    neighbours: NDArray[np.int32] | None = None,
) -> NDArray[np.bool_]:
    """:func:`blend_coordinates` in chosen blocks of output pixels, located from their samples' faces; written into ``out``.

    Parameters
    ----------
    cells : ndarray of bool, shape (h, w)
        The blocks of ``out`` to evaluate: block ``(i, j)`` is the ``s x s`` pixels around the
        sample ``(i, j)`` of a grid ``s = W / w`` times coarser.
    samples : ndarray of int32, shape (h, w)
        The samples' faces (:func:`omniwidget.core.locate.locate_faces` on the coarse grid):
        each block's walk starts from its sample's face.
    planes, faces, weights, inverses, src_width
        As in :func:`blend_coordinates`.
    out : ndarray of float32, shape (H, W, 2)
        Coordinates, overwritten in the blocks at the pixels that are found.
    walk : int
        Each pixel is walked to its face across the mesh's edges (:func:`walk_blend`), from
        its neighbour's face, through at most this many faces.
    neighbours : ndarray of int32, shape (m, 3), optional
        :func:`omniwidget.core.locate.face_neighbours` of ``faces``, when the caller has it.

    Returns
    -------
    ndarray of bool, shape (H, W)
        The pixels not found (not written).
    """
    blend_cells = _compiled().blend_cells
    step = out.shape[1] // cells.shape[1]
    planes = np.ascontiguousarray(planes, np.float64)
    slack = EDGE_TOLERANCE * np.linalg.norm(planes, axis=2)  # what locate tolerates, per edge plane
    mesh = _mesh_args(planes, faces, weights, inverses)
    grid = _grid_args(out.shape[1], src_width)
    neighbours = face_neighbours(mesh[1]) if neighbours is None else neighbours
    missed = np.zeros(out.shape[:2], dtype=bool)
    cell_r, cell_c = np.nonzero(cells)
    samples = np.ascontiguousarray(samples, np.int32)

    _run_blocks(
        len(cell_r),
        lambda block: blend_cells(
            block.start, block.stop, cell_r, cell_c, step, samples, mesh[0], slack, neighbours, walk, *mesh[1:], *grid, out, missed
        ),
    )
    return missed


def interpolate_shift(shift: NDArray[np.float32], exact: NDArray[np.bool_], src_width: int, out: NDArray[np.float32]) -> None:
    """Fill ``out`` outside the ``exact`` blocks by bilinear interpolation of the samples' displacements.

    Parameters
    ----------
    shift : ndarray of float32, shape (h, w, 2)
        Each sample's source position minus where it is shown, in source pixels (longitude
        difference wrapped to half a turn).
    exact : ndarray of bool, shape (h, w)
        Blocks left alone (evaluated exactly by :func:`blend_blocks`).
    src_width : int
    out : ndarray of float32, shape (H, W, 2)
        Padded source coordinates, as :func:`blend_coordinates` gives.
    """
    interpolate_rows = _compiled().interpolate_rows
    step = out.shape[1] // exact.shape[1]
    padded = np.ascontiguousarray(np.concatenate([shift[:, -1:], shift, shift[:, :1]], axis=1), np.float64)
    lon, lat = coords.grid_lonlat(out.shape[1])
    exact = np.ascontiguousarray(exact)
    per_degree = src_width / 360.0
    xc = (np.arange(out.shape[1]) + 0.5) / step + 0.5  # in samples; shift has one wrapped sample on each side
    column = np.floor(xc).astype(np.int64)
    part = xc - column
    base_x = (lon + 180.0) * per_degree
    _run_blocks(
        len(out),
        lambda rows: interpolate_rows(
            rows.start, rows.stop, padded, step, exact, column, part, base_x, float(src_width), per_degree, lat, float(PAD), out
        ),
    )


def _mesh_args(planes, faces, weights, inverses) -> tuple:
    return (
        np.ascontiguousarray(planes, np.float64),
        np.ascontiguousarray(faces, np.int64),
        np.ascontiguousarray(weights, np.float32),
        _matrices(inverses),
    )


def _grid_args(width: int, src_width: int) -> tuple:
    lon, lat = (np.radians(x) for x in coords.grid_lonlat(width))
    kx = src_width / (2 * math.pi)
    return (np.cos(lon), np.sin(lon), np.cos(lat), np.sin(lat), kx, src_width / 2 - 0.5 + PAD, src_width / 4 - 0.5 + PAD)


def fold_mask(coordinates: NDArray[np.float32], src_width: int, pole_margin: float = 1.0) -> NDArray[np.bool_]:
    """Output pixels where the map turns the image over, from its source pixel coordinates.

    The rule of :func:`omniwidget.core.quality.fold_over` (Jacobian determinant <= 0 by
    central differences, longitudes wrapped; first and last rows and sources within
    ``pole_margin`` degrees of a pole never marked), on the coordinates
    :func:`blend_coordinates` returns.

    Parameters
    ----------
    coordinates : ndarray of float32, shape (H, W, 2)
    src_width : int
    pole_margin : float

    Returns
    -------
    ndarray of bool, shape (H, W)
    """
    fold_rows = _compiled().fold_rows
    mask = np.zeros(coordinates.shape[:2], dtype=bool)
    per_degree = src_width / 360.0
    top = pole_margin * per_degree - 0.5
    bottom = (180.0 - pole_margin) * per_degree - 0.5
    c = np.ascontiguousarray(coordinates)
    _run_blocks(len(mask), lambda rows: fold_rows(rows.start, rows.stop, c, float(src_width), float(PAD), top, bottom, mask))
    return mask


def paint(run_face: NDArray[np.int64], flat_start: NDArray[np.int64], length: NDArray[np.int64], size: int) -> NDArray[np.int32]:
    """Paint runs of pixels with their faces: what :func:`omniwidget.core.locate.locate_faces` does, without index arrays.

    Parameters
    ----------
    run_face, flat_start, length : ndarray of int64, shape (r,)
        Run ``i`` gives ``length[i]`` pixels from the flat index ``flat_start[i]`` on the face ``run_face[i]``.
    size : int
        Pixels in all.

    Returns
    -------
    ndarray of int32, shape (size,)
        -1 where no run reaches.
    """
    out = np.full(size, -1, np.int32)
    _compiled().paint_runs(run_face.astype(np.int32), flat_start.astype(np.int64), length.astype(np.int64), out)
    return out


def strongest_weights(
    mask: NDArray[np.bool_], face: NDArray[np.int32], planes: NDArray[np.float64], faces: NDArray[np.int64], weights: NDArray[np.floating]
) -> NDArray[np.float64]:
    """Each control's largest weight over the masked pixels (for naming the handles where a warp folds).

    Parameters
    ----------
    mask : ndarray of bool, shape (H, W)
    face, planes : ndarray
        From :func:`omniwidget.core.locate.locate_faces`.
    faces : ndarray of int64, shape (m, 3)
    weights : ndarray, shape (n, k)

    Returns
    -------
    ndarray of float64, shape (k,)
    """
    rows, cols = np.nonzero(mask)
    lon, lat = (np.radians(x) for x in coords.grid_lonlat(mask.shape[1]))
    out = np.zeros(weights.shape[1])
    _compiled().strongest(
        rows,
        cols,
        face,
        np.ascontiguousarray(planes, np.float64),
        np.ascontiguousarray(faces, np.int64),
        np.ascontiguousarray(weights, np.float64),
        np.cos(lon),
        np.sin(lon),
        np.cos(lat),
        np.sin(lat),
        out,
    )
    return out
