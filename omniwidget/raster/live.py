"""Eq. (2) split for a live drag: what the browser needs to redraw the result as one handle moves.

While a handle is dragged, only its own controls' maps change; the weights stay those of
the last solve. At each output direction ``p`` eq. (2) is then

``T⁻¹(p) = normalize(F(p) + Σ_{j moving} W_j(p) M_j⁻¹(p))``, with ``F(p) = Σ_{j fixed} W_j(p) M_j⁻¹(p)``,

and in the default mode the harmonic fill between the handles (:mod:`omniwidget.method.harmonic`) then
takes that to ``normalize(s(p) T⁻¹(p) + o(p))``, its affine form (:meth:`~omniwidget.method.harmonic.HarmonicFill.affine`),
as it was for the maps when the drag started (the kernel's result after the release fills for the new maps).

:func:`live_basis` computes ``F`` and the moving controls' ``W_j`` once, when a drag starts;
the browser (``omniwidget/widget/static/editor.js``) rebuilds the moving ``M_j`` from the
dragged control points every frame (``moebius.js``, the twin of :mod:`.moebius` and
:mod:`.handles`) and evaluates the sum per pixel on the GPU. On release the kernel's exact
result replaces the live frame. Where the weights did not change (an arrow tip turned or
pulled: the disk the point holds stays where it is), the two are the same image.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from ..method.locate import interpolate, locate_faces, locate_grid
from ..sphere import coords
from ..sphere.moebius import Moebius
from . import _kernels

if TYPE_CHECKING:
    from ..method.deformation import Blend
    from .pipeline import Result

__all__ = ["LiveBasis", "live_basis"]


#: Pixels where every moving control weighs at most this are left out of the live frame: the
#: kernel's result there is off by at most this times how far the drag moves a map (a
#: tenth of a degree for a map dragged by 100°, a third of a pixel at the 1024-wide preview).
REGION_WEIGHT = 1e-3


@dataclass(frozen=True, eq=False)
class LiveBasis:
    """Eq. (2)'s sum with one handle's controls taken apart, on the region of an equirectangular grid they reach.

    Attributes
    ----------
    fixed : ndarray of float32, shape (h, w, 3)
        ``F(p)``: the un-normalised sum of the other controls' terms ``W_j(p) M_j⁻¹(p)``
        (unit vectors weighted) at each pixel centre of the region.
    weights : ndarray of float32, shape (h, w, c)
        ``W_j(p)`` of the handle's own controls, in the order of :attr:`controls`.
    controls : tuple of int
        The handle's controls (indices into ``result.controls``).
    origin : (int, int)
        Row and column of the region's top left pixel in the whole grid. The region's
        columns run on from there and wrap across the ±180° seam.
    size : int
        The whole grid's width (its height is half of it).
    share, offset : ndarray of float32, shapes (h, w) and (h, w, 3)
        The fill's affine form at each pixel centre of the region: the map shown is
        ``normalize(share T⁻¹ + offset)``; 1 and 0 without a fill.
    """

    fixed: NDArray[np.float32]
    weights: NDArray[np.float32]
    controls: tuple[int, ...]
    origin: tuple[int, int]
    size: int
    share: NDArray[np.float32]
    offset: NDArray[np.float32]

    def lonlat(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Longitudes (w,) and latitudes (h,) of the region's pixel centres, radians."""
        lon, lat = (np.radians(x) for x in coords.grid_lonlat(self.size))
        row, col = self.origin
        height, width = self.fixed.shape[:2]
        return lon[(col + np.arange(width)) % self.size], lat[row : row + height]

    def inverse_lonlat(self, maps: Sequence[Moebius]) -> NDArray[np.float64]:
        """Eq. (2) with the handle's controls given new maps: the input ``[lon, lat]`` (degrees) each pixel of the region shows, (h, w, 2).

        What the browser computes per frame, here in numpy for tests and teaching.

        Parameters
        ----------
        maps : sequence of Moebius
            The handle's maps, input to output, one per control of :attr:`controls`.
        """
        if len(maps) != len(self.controls):
            raise ValueError(f"{len(self.controls)} controls move but {len(maps)} maps were given")
        total = self.fixed.astype(np.float64)
        lon, lat = self.lonlat()
        for j, m in enumerate(maps):
            total += self.weights[..., j, None] * _unit_images(m.inverse, lon, lat)
        total /= np.linalg.norm(total, axis=-1, keepdims=True)
        return coords.xyz_to_lonlat(self.share[..., None] * total + self.offset)

    def packed(self) -> NDArray[np.float16]:
        """The basis as the browser's texture: ``(L h, w, 4)`` half floats, channels ``F_x, F_y, F_z, W_0, W_1, ..., s, o_x, o_y, o_z``.

        Layer ``l`` (rows ``l h`` to ``(l + 1) h``) holds channels ``4 l`` to ``4 l + 3``;
        the last layer is padded with zeros. Half floats keep a direction to 5e-4 rad,
        well under a pixel of the 1024-wide preview (6e-3 rad).
        """
        height, width = self.fixed.shape[:2]
        channels = np.concatenate([self.fixed, self.weights, self.share[..., None], self.offset], axis=-1)
        layers = -(-channels.shape[-1] // 4)
        out = np.zeros((layers, height, width, 4), np.float16)
        for layer in range(layers):
            part = channels[..., 4 * layer : 4 * layer + 4]
            out[layer, ..., : part.shape[-1]] = part
        return out.reshape(layers * height, width, 4)


def _unit_images(m: Moebius, lon: NDArray[np.float64], lat: NDArray[np.float64]) -> NDArray[np.float64]:
    """The unit vectors ``m(p)`` at the pixel centres of a grid of longitudes and latitudes, (h, w, 3)."""
    lon_grid, lat_grid = np.meshgrid(lon, lat)
    return m.apply_xyz(coords.lonlat_to_xyz(np.degrees(np.stack([lon_grid, lat_grid], axis=-1))))


def _region(reach: NDArray[np.bool_]) -> tuple[slice, NDArray[np.int64]]:
    """The rows and the columns (wrapping across the seam) of the smallest box around the True pixels of ``reach`` (H, W)."""
    rows = np.flatnonzero(reach.any(axis=1))
    if not rows.size:
        return slice(0, 0), np.zeros(0, np.int64)
    used = reach.any(axis=0)
    width = reach.shape[1]
    longest, end, run = 0, -1, 0  # the longest run of unused columns, going round the seam
    for i, free in enumerate(np.concatenate([~used, ~used])):
        run = run + 1 if free else 0
        if run > longest:
            longest, end = run, i
    return slice(int(rows[0]), int(rows[-1]) + 1), (end + 1 + np.arange(width - longest)) % width


def _split_sum(
    blend: Blend, inverses: Sequence[Moebius], moving: tuple[int, ...], width: int
) -> tuple[NDArray[np.floating], NDArray[np.floating]]:
    """``F`` (h, w, 3) and the moving controls' weights (h, w, c) at every pixel of the whole grid, from the blend's mesh."""
    if _kernels.available():
        face, planes = locate_faces(blend.vertices, blend.faces, width)
        return _kernels.split_sum(face, planes, blend.faces, blend.weights, inverses, moving)
    lon, lat = (np.radians(x) for x in coords.grid_lonlat(width))
    face, bary = locate_grid(blend.vertices, blend.faces, width)
    w = interpolate(np.asarray(blend.weights, np.float32), blend.faces, face, bary)
    fixed = np.zeros(face.shape + (3,), np.float64)
    for j, m in enumerate(inverses):
        if j not in moving and w[..., j].max() > 0:
            fixed += w[..., j, None] * _unit_images(m, lon, lat)
    return fixed, w[..., list(moving)]


def live_basis(result: Result, handle: int, region_weight: float | None = REGION_WEIGHT) -> LiveBasis:
    """The basis of a live drag of one handle, on the grid of ``result.image``, cut to where the handle weighs.

    Parameters
    ----------
    result : Result
        The result on screen (:func:`omniwidget.raster.pipeline.warp`): its mesh, weights and
        controls.
    handle : int
        Index of the dragged handle in ``result.handles``.
    region_weight : float or None
        The region kept is the box around the pixels where one of the handle's controls
        weighs more than this (:data:`REGION_WEIGHT`); None keeps the whole grid.

    Returns
    -------
    LiveBasis

    Raises
    ------
    ValueError
        If ``handle`` names no handle with a control in ``result``.
    """
    controls = result.controls
    moving = tuple(j for j, c in enumerate(controls) if c.handle == handle)
    if isinstance(handle, bool) or not moving:
        raise ValueError(f"handles[{handle}] has no control in this result ({len(result.handles)} handles)")
    width = result.image.shape[1]
    inverses = [c.moebius.inverse for c in controls]
    lon, lat = (np.radians(x) for x in coords.grid_lonlat(width))
    blend = result.blend
    fixed: NDArray[np.floating]
    if blend is None:  # one map does it all: every control weighs the same
        share = 1.0 / len(controls)
        fixed = (share * (len(controls) - len(moving))) * _unit_images(inverses[0], lon, lat)
        weights = np.full(fixed.shape[:2] + (len(moving),), share, np.float32)
    else:
        fixed, weights = _split_sum(blend, inverses, moving, width)
    if region_weight is None:
        rows, cols = slice(0, width // 2), np.arange(width)
    else:
        rows, cols = _region(weights.max(axis=-1) > region_weight)
    fill_share: NDArray[np.float64] = np.ones((rows.stop - rows.start, len(cols)))
    offset: NDArray[np.float64] = np.zeros(fill_share.shape + (3,))
    if blend is not None and blend.fill is not None:
        lon_deg, lat_deg = coords.grid_lonlat(width)
        fill_share, offset, _ = blend.fill.affine(np.stack(np.meshgrid(lon_deg[cols], lat_deg[rows]), axis=-1))
    return LiveBasis(
        np.ascontiguousarray(fixed[rows][:, cols], np.float32),
        np.ascontiguousarray(weights[rows][:, cols], np.float32),
        moving,
        (rows.start, int(cols[0]) if cols.size else 0),
        width,
        np.ascontiguousarray(fill_share, np.float32),
        np.ascontiguousarray(offset, np.float32),
    )
