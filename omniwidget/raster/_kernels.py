"""Compiled per-pixel kernels (numba), used by :func:`omniwidget.raster.pipeline.warp` when numba is installed.

The numpy path of the blend (:mod:`omniwidget.raster.blend`) makes a pass over the whole
image per control and per operation; here each output pixel is done in one go: its
barycentric coordinates in its face, its weights, the Möbius maps whose weight is not
negligible there, the normalised sum of eq. (2) and its source pixel. The same per-pixel
work runs on chosen blocks of pixels for the sampled blend (:mod:`omniwidget.raster.sampled`),
beside the bilinear interpolation of the samples elsewhere; the fold check
(:func:`omniwidget.raster.fold.fold_over`'s rule), the painting of the pixels' faces
(:func:`omniwidget.method.locate.locate_faces`) and the weights named in a fold warning are
one pass each. The kernels release
the GIL and run on blocks of rows in threads (not numba's own parallel layer, which does
not allow two threads to launch kernels at once, as the editor's preview and a full-size
warp may).

The kernels themselves are module-level functions of :mod:`omniwidget._numba_kernels`,
so numba's on-disk cache serves every new process: the first warp in a fresh
process reads them instead of compiling them. Each is also kept on disk as plain machine
code (:mod:`omniwidget._native`), which a new process loads with llvmlite alone
without importing numba, which a fresh process's first warp would otherwise wait for.
Every kernel takes C-contiguous, writeable arrays (:func:`_plain`), one type per argument.

Without numba (``pip install numba``, or the ``fast`` extra), or with the environment
variable ``OMNIWIDGET_NUMBA=0``, :func:`available` is False and the numpy path runs; the
two agree to float32 rounding (``tests/test_kernels.py``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from .. import _native
from .._native import available
from ..method.locate import EDGE_TOLERANCE, face_neighbours, locate_faces
from ..sphere import coords
from ..sphere.moebius import Moebius
from .warping import PAD, run_blocks

__all__ = [
    "available",
    "blend_blocks",
    "blend_coordinates",
    "fill_coordinates",
    "fold_mask",
    "interpolate_shift",
    "split_sum",
    "strongest_weights",
    "walk_blend",
]

#: Faces a pixel's walk from its neighbour's face crosses, at most, before it is left to a slower search.
WALK_STEPS = 256


def _compiled() -> _native.Kernels:
    """The kernels of :mod:`omniwidget._numba_kernels` by name: their stored native code, else numba (:mod:`omniwidget._native`)."""
    return _native.kernels()


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
        From :func:`omniwidget.method.locate.locate_faces`: (H, W) int32 and (m, 3, 3) float64.
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
        What :func:`omniwidget.raster.warping.remap_coordinates` returns for the numpy blend.
    """
    blend_rows = _compiled().blend_rows
    height, width = face.shape
    out = np.empty((height, width, 2), np.float32)
    mesh, grid = _mesh_args(planes, faces, weights, inverses), _grid_args(width, src_width)
    face = _plain(face)
    run_blocks(height, lambda rows: blend_rows(rows.start, rows.stop, face, *mesh, *grid, out))
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
    (:func:`omniwidget.method.locate.locate_faces`); should a walk not arrive within ``walk``
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
        :func:`omniwidget.method.locate.face_neighbours` of ``faces``, when the caller has it.

    Returns
    -------
    coordinates : ndarray of float32, shape (width / 2, width, 2)
        As :func:`blend_coordinates` gives.
    face : ndarray of int32, shape (width / 2, width)
        Each pixel's face.
    planes : ndarray of float64, shape (m, 3, 3)
        The faces' edge planes, as :func:`omniwidget.method.locate.locate_faces` gives them.
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
    run_blocks(
        height,
        lambda rows: kernel(rows.start, rows.stop, 0, planes, slack, neighbours, walk, *mesh[1:], *grid, out, face, missed),
    )
    if missed.any():
        face, planes = locate_faces(v, f, width)
        out = blend_coordinates(face, planes, f, weights, inverses, src_width)
    return out, face, planes


def split_sum(
    face: NDArray[np.int32],
    planes: NDArray[np.float64],
    faces: NDArray[np.int64],
    weights: NDArray[np.floating],
    inverses: Sequence[Moebius],
    moving: Sequence[int],
) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """Eq. (2)'s un-normalised sum with some controls taken apart (:func:`omniwidget.raster.live.live_basis`).

    Parameters
    ----------
    face, planes, faces, weights, inverses
        As in :func:`blend_coordinates`.
    moving : sequence of int
        The controls taken apart, in the order of the returned weights' columns.

    Returns
    -------
    fixed : ndarray of float32, shape (H, W, 3)
        ``Σ_{j not moving} W_j(p) M_j⁻¹(p)`` per pixel.
    weights : ndarray of float32, shape (H, W, c)
        ``W_j(p)`` of the moving controls.
    """
    height, width = face.shape
    slot = np.full(len(inverses), -1, np.int64)
    slot[list(moving)] = np.arange(len(moving))
    fixed = np.empty((height, width, 3), np.float32)
    apart = np.empty((height, width, len(moving)), np.float32)
    mesh, grid = _mesh_args(planes, faces, weights, inverses), _grid_args(width, width)[:4]
    face = _plain(face)
    kernel = _compiled().split_rows
    run_blocks(height, lambda rows: kernel(rows.start, rows.stop, face, *mesh, slot, *grid, fixed, apart))
    return fixed, apart


def blend_blocks(  # noqa: PLR0913 - the kernel's flat arrays (one array per argument, as numba takes them) and the walk's two knobs
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
        The samples' faces (:func:`omniwidget.method.locate.locate_faces` on the coarse grid):
        each block's walk starts from its sample's face.
    planes, faces, weights, inverses, src_width
        As in :func:`blend_coordinates`.
    out : ndarray of float32, shape (H, W, 2)
        Coordinates, overwritten in the blocks at the pixels that are found.
    walk : int
        Each pixel is walked to its face across the mesh's edges (:func:`walk_blend`), from
        its neighbour's face, through at most this many faces.
    neighbours : ndarray of int32, shape (m, 3), optional
        :func:`omniwidget.method.locate.face_neighbours` of ``faces``, when the caller has it.

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
    cell_r, cell_c = (_plain(x) for x in np.nonzero(cells))
    samples = _plain(samples, np.int32)

    run_blocks(
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
    exact = _plain(exact)
    per_degree = src_width / 360.0
    xc = (np.arange(out.shape[1]) + 0.5) / step + 0.5  # in samples; shift has one wrapped sample on each side
    column = np.floor(xc).astype(np.int64)
    part = xc - column
    base_x = (lon + 180.0) * per_degree
    run_blocks(
        len(out),
        lambda rows: interpolate_rows(
            rows.start,
            rows.stop,
            padded,
            step,
            exact,
            column,
            part,
            base_x,
            float(src_width),
            per_degree,
            lat,
            float(PAD),
            out,
            np.empty(padded.shape[1]),  # scratch rows, one pair per block
            np.empty(padded.shape[1]),
        ),
    )


def _plain(a: NDArray, dtype: type | None = None) -> NDArray:
    """``a`` as a C-contiguous, aligned, writeable array (a copy only if it is not one): the kernels' arrays.

    One type per argument for numba's dispatch whatever the caller's array (a read-only
    mesh, a strided view), and the arrays a stored native kernel takes (:mod:`._native`).
    """
    return np.require(a, dtype, ("C", "A", "W"))


def _mesh_args(planes, faces, weights, inverses) -> tuple:
    return (_plain(planes, np.float64), _plain(faces, np.int64), _plain(weights, np.float32), _matrices(inverses))


def _grid_args(width: int, src_width: int) -> tuple:
    lon, lat = (np.radians(x) for x in coords.grid_lonlat(width))
    kx = src_width / (2 * math.pi)
    return (np.cos(lon), np.sin(lon), np.cos(lat), np.sin(lat), kx, src_width / 2 - 0.5 + PAD, src_width / 4 - 0.5 + PAD)


def fold_mask(coordinates: NDArray[np.float32], src_width: int, pole_margin: float = 1.0) -> NDArray[np.bool_]:
    """Output pixels where the map turns the image over, from its source pixel coordinates.

    The rule of :func:`omniwidget.raster.fold.fold_over` (Jacobian determinant <= 0 by
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
    c = _plain(coordinates)
    run_blocks(len(mask), lambda rows: fold_rows(rows.start, rows.stop, c, float(src_width), float(PAD), top, bottom, mask))
    return mask


def strongest_weights(
    mask: NDArray[np.bool_], face: NDArray[np.int32], planes: NDArray[np.float64], faces: NDArray[np.int64], weights: NDArray[np.floating]
) -> NDArray[np.float64]:
    """Each control's largest weight over the masked pixels (for naming the handles where a warp folds).

    Parameters
    ----------
    mask : ndarray of bool, shape (H, W)
    face, planes : ndarray
        From :func:`omniwidget.method.locate.locate_faces`.
    faces : ndarray of int64, shape (m, 3)
    weights : ndarray, shape (n, k)

    Returns
    -------
    ndarray of float64, shape (k,)
    """
    rows, cols = (_plain(x) for x in np.nonzero(mask))
    lon, lat = (np.radians(x) for x in coords.grid_lonlat(mask.shape[1]))
    out = np.zeros(weights.shape[1])
    _compiled().strongest(
        rows,
        cols,
        _plain(face),
        _plain(planes, np.float64),
        _plain(faces, np.int64),
        _plain(weights, np.float64),
        np.cos(lon),
        np.sin(lon),
        np.cos(lat),
        np.sin(lat),
        out,
    )
    return out


def fill_coordinates(
    coordinates: NDArray[np.float32],
    held: NDArray[np.bool_],
    filled: NDArray[np.float64],
    blend: NDArray[np.float64],
    columns: tuple[NDArray[np.int64], NDArray[np.float64]],
    rows: tuple[NDArray[np.int64], NDArray[np.float64]],
    src_width: int,
) -> None:
    """The harmonic fill applied in place to source pixel coordinates (H, W, 2), in blocks of rows on threads.

    ``held``, ``filled`` and ``blend`` are the fill's nodes (:class:`omniwidget.method.harmonic.HarmonicFill`);
    ``columns`` and ``rows`` each pixel column's and row's first node and its share of the next.
    """
    kernel = _compiled().fill_rows
    args = (
        _plain(held.astype(np.float64)),
        _plain(filled),
        _plain(blend),
        _plain(columns[0].astype(np.int64)),
        _plain(columns[1]),
        _plain(rows[0].astype(np.int64)),
        _plain(rows[1]),
        float(src_width),
        float(PAD),
    )
    run_blocks(len(coordinates), lambda block: kernel(block.start, block.stop, coordinates, *args))
