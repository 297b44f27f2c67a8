"""The blended map sampled on a coarser grid and interpolated where that is exact enough.

Away from its handles the blended inverse map of eq. (2) is smooth, so at large output
sizes it need not be evaluated at every pixel. :func:`sampled_coordinates` evaluates it
exactly (:mod:`omniwidget.raster._kernels`) on an equirectangular grid ``step`` times
coarser, whose samples sit at the centres of ``step x step`` blocks of output pixels, as
the *displacement* of each sample from where it is shown (the longitude difference wrapped
to ±180°, the latitude difference, in source pixels), and interpolates that bilinearly
(a compiled kernel, columns wrapped at the seam). A displacement is the right thing to
interpolate: it is 0 for the identity and changes linearly along rows near the poles.

The output pixels around these samples are evaluated exactly instead, each walked to its
mesh face from its neighbour's (:func:`omniwidget.raster._kernels.blend_blocks`):

- samples within ``band`` of a handle's prescribed point (every line, cage edge and point
  at its output position), where weights change within a few pixels: lines come out as
  straight and cages as still as the exact map makes them;
- samples where the interpolation's error, estimated from second differences (a quarter
  of one bounds the error of a kink or a curve between samples), exceeds ``tolerance``
  times the map's local scale (:func:`_scale`: where the map shrinks the image, as near
  an output pole, a smaller error would already turn neighbouring pixels over);
- samples whose displacement in longitude jumps from a neighbour's (it wraps at ±180°, and
  turns about a pole of the source), or whose source lies near a pole;
- the first and last rows of samples, whose blocks reach towards the output poles.

``tests/test_sampled.py`` compares the result with the exact map pixel by pixel.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from .._lazy import lazy
from ..method.deformation import blended_points
from ..method.locate import face_neighbours
from ..sphere import coords
from ..sphere.moebius import Moebius
from . import _kernels
from .warping import PAD

if TYPE_CHECKING:
    import cv2
else:
    cv2 = lazy("cv2")

__all__ = ["BAND", "SAMPLE_FROM", "STEP", "TOLERANCE", "coarse_step", "sampled_coordinates"]

#: Output pixels per sample along each axis.
STEP = 4
#: Outputs at least this wide are sampled (smaller ones are cheap to evaluate at every pixel).
SAMPLE_FROM = 2048
#: Samples this close to a handle's prescribed point (in samples) are not interpolated from.
BAND = 1
#: Largest estimated interpolation error (source pixels) left to the interpolation.
TOLERANCE = 0.25
#: Sources within this many samples of a pole, and displacement jumps above this many degrees, are not interpolated.
_POLE_SAMPLES = 3.0
_JUMP = 20.0


def coarse_step(width: int, step: int = STEP) -> int:
    """The sampling step for an output ``width`` wide: 1 (every pixel) below :data:`SAMPLE_FROM`.

    Parameters
    ----------
    width : int
        Output width (even).
    step : int
        Wanted step.

    Returns
    -------
    int
        The largest ``s <= step`` with ``width % (2 s) == 0``, so that the coarse grid is again
        an equirectangular grid whose samples sit at block centres; 1 for small outputs.
    """
    if width < SAMPLE_FROM:
        return 1
    return next((s for s in range(step, 1, -1) if width % (2 * s) == 0), 1)


def _grow(mask: NDArray[np.bool_], by: int) -> NDArray[np.bool_]:
    """``mask`` dilated by ``by`` samples in every direction, wrapping at the seam."""
    if by <= 0:
        return mask
    wrapped = np.concatenate([mask[:, -by:], mask, mask[:, :by]], axis=1).astype(np.uint8)
    return cv2.dilate(wrapped, np.ones((2 * by + 1, 2 * by + 1), np.uint8))[:, by:-by].astype(bool)


def _scale(shift: NDArray[np.float32], step: int) -> NDArray[np.float32]:
    """The map's smaller singular value at each sample, in source pixels per output pixel, at most 1.

    From central differences of the samples (the displacement plus the identity's unit
    step along rows and columns): the Jacobian's determinant over its longer column, exact
    for a conformal map (as Möbius maps and their blends nearly are), and near 0 along a fold
    (where the determinant changes sign).
    Where neighbouring output pixels come from sources closer than a pixel (a map that
    shrinks the image there, as near an output pole, or nearly folds it) an error of a
    fraction of a pixel could turn it over, so the tolerance shrinks with this scale.
    """
    along = (np.roll(shift, -1, axis=1) - np.roll(shift, 1, axis=1)) / (2 * step)
    along[..., 0] += 1.0
    down = np.zeros_like(shift)
    down[1:-1] = (shift[2:] - shift[:-2]) / (2 * step)
    down[0], down[-1] = down[1], down[-2]
    down[..., 1] += 1.0
    det = np.abs(along[..., 0] * down[..., 1] - along[..., 1] * down[..., 0])
    longer = np.sqrt(np.maximum(np.sum(along**2, axis=-1), np.sum(down**2, axis=-1)))
    return np.minimum(det / np.maximum(longer, 1e-12), 1.0)


def sampled_coordinates(  # noqa: PLR0913 - the blend's arrays as the kernels take them, and the two documented keyword knobs
    inverses: Sequence[Moebius],
    vertices: NDArray[np.float64],
    faces: NDArray[np.int64],
    weights: NDArray[np.float64],
    width: int,
    src_width: int,
    step: int,
    near: NDArray[np.float64],
    *,
    band: int = BAND,
    tolerance: float = TOLERANCE,
) -> tuple[NDArray[np.float32], NDArray[np.int32], NDArray[np.float64]]:
    """Source pixel coordinates of every output pixel, from the blended map sampled every ``step`` pixels.

    Needs the compiled kernels (:func:`omniwidget.raster._kernels.available`).

    Parameters
    ----------
    inverses : sequence of Moebius
        ``M_j⁻¹`` of the ``k`` controls.
    vertices, faces : ndarray, shapes (n, 3) float64 and (m, 3) int64
        The adaptive mesh.
    weights : ndarray of float64, shape (n, k)
        Normalised weights per vertex.
    width : int
        Output width, a multiple of ``2 step``.
    src_width : int
        Width of the source panorama.
    step : int
        Output pixels per sample, at least 2.
    near : ndarray of float64, shape (p, 3)
        Output directions of the handles' prescribed points (``Constraints.points``).
    band : int
        Samples around each of them that are not interpolated from.
    tolerance : float
        Source pixels; see the module's notes.

    Returns
    -------
    coordinates : ndarray of float32, shape (width / 2, width, 2)
        ``(x, y)`` in the source padded by :data:`~omniwidget.raster.warping.PAD`.
    face : ndarray of int32, shape (h, w)
        The samples' faces (``w = width / step``).
    planes : ndarray of float64, shape (m, 3, 3)
        The faces' edge planes (as :func:`~omniwidget.method.locate.locate_faces` gives them).
    """
    if step < 2 or width % (2 * step):
        raise ValueError(f"step must be at least 2 and divide the grid evenly: width {width}, step {step}")
    coarse_width = width // step
    neighbours = face_neighbours(faces)  # the samples' walk and the exact blocks' walks share them
    samples, face, planes = _kernels.walk_blend(vertices, faces, weights, inverses, coarse_width, src_width, neighbours=neighbours)
    shift = _shift(samples, src_width)
    bad = _unreliable(samples, shift, src_width, step, tolerance)
    handles = np.zeros_like(bad)
    col, row = np.floor(coords.lonlat_to_px(coords.xyz_to_lonlat(near), coarse_width) + 0.5).astype(np.int64).T
    handles[np.clip(row, 0, coarse_width // 2 - 1), col % coarse_width] = True
    exact = _grow(bad, 1) | _grow(handles, band)  # a bad sample spoils the blocks that read it
    exact[0] = exact[-1] = True  # and the first and last rows of samples, whose blocks reach towards the poles
    out = np.empty((width // 2, width, 2), np.float32)
    _kernels.interpolate_shift(shift, exact, src_width, out)
    missed = _kernels.blend_blocks(exact, face, planes, faces, weights, inverses, src_width, out, neighbours=neighbours)
    if missed.any():  # a pixel in none of the faces around its sample: located the long way
        m_rows, m_cols = np.nonzero(missed)
        lon, lat = coords.grid_lonlat(width)
        src = blended_points(inverses, vertices, faces, weights, coords.lonlat_to_xyz(np.stack([lon[m_cols], lat[m_rows]], axis=-1)))
        out[m_rows, m_cols] = coords.lonlat_to_px(src, src_width) + PAD
    return out, face, planes


def _shift(samples: NDArray[np.float32], src_width: int) -> NDArray[np.float32]:
    """Each sample's displacement from where it is shown, source pixels ``(dx, dy)``, ``dx`` wrapped to the nearest turn."""
    coarse_width = samples.shape[1]
    per_degree = src_width / 360.0
    lon_c, lat_c = coords.grid_lonlat(coarse_width)
    shift = np.empty_like(samples)
    shift[..., 0] = samples[..., 0] - ((lon_c + 180.0) * per_degree - 0.5 + PAD)[None, :]
    shift[..., 0] = (shift[..., 0] + src_width / 2) % src_width - src_width / 2
    shift[..., 1] = samples[..., 1] - ((90.0 - lat_c) * per_degree - 0.5 + PAD)[:, None]
    return shift


def _unreliable(samples: NDArray[np.float32], shift: NDArray[np.float32], src_width: int, step: int, tolerance: float) -> NDArray[np.bool_]:
    """Samples not to interpolate from: near a source pole, beside a jump of the displacement, or curved beyond ``tolerance``."""
    coarse_width = samples.shape[1]
    per_degree = src_width / 360.0
    src_lat = 90.0 - (samples[..., 1] - PAD + 0.5) / per_degree
    bad = np.abs(src_lat) > 90.0 - _POLE_SAMPLES * 360.0 / coarse_width
    jump = np.abs(np.diff(shift[..., 0], axis=0)) > _JUMP * per_degree
    bad[1:] |= jump
    bad[:-1] |= jump
    jump = np.abs(np.roll(shift[..., 0], -1, axis=1) - shift[..., 0]) > _JUMP * per_degree
    bad |= jump | np.roll(jump, 1, axis=1)
    limit = 4 * tolerance * _scale(shift, step)
    down = np.abs(shift[2:] - 2 * shift[1:-1] + shift[:-2]) > limit[1:-1, :, None]
    bad[1:-1] |= down[..., 0] | down[..., 1]
    across = np.abs(np.roll(shift, -1, axis=1) - 2 * shift + np.roll(shift, 1, axis=1)) > limit[..., None]
    bad |= across[..., 0] | across[..., 1]
    return bad
