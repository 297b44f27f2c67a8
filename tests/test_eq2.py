"""Eq. (2) written out from its definition, at chosen directions, against the pipeline's output.

The paper (Sec. 3, eq. 2): ``T⁻¹(λ, φ) = Σ_j W_j(λ, φ) · M_j⁻¹(λ, φ)``, each output direction's source the
weighted combination of the handles' inverse Möbius maps; the project normalises the sum of the 3D unit vectors
back onto the sphere (its README, "Facts about the authors' implementation": the authors took ``asin`` of the
un-normalised sum). Here every step is done by hand, with nothing of ``omniwidget`` but the inputs it solved:

- the weights ``W_j(p)``: the mesh triangle whose cone holds ``p``, found by solving ``[v0 v1 v2] λ = p`` on
  every face (all ``λ >= 0``), and the per-vertex weights (``Result.weights``) interpolated with ``λ / Σλ``,
  the barycentric coordinates of the point where the ray ``p`` meets the flat triangle;
- ``M_j⁻¹(p)``: each control's 2 x 2 complex matrix ``[[a, b], [c, d]]`` (``Result.controls[j].moebius.matrix``,
  determinant 1) inverted as ``[[d, -b], [-c, a]]`` and applied to ``z = (x + i y) / (1 - z₃)``, the
  stereographic projection from the north pole, then projected back;
- the sum ``Σ_j W_j M_j⁻¹(p)`` of unit vectors, normalised;
- in the default mode, the harmonic fill between the handles (:mod:`omniwidget.method.harmonic`) applied to it as
  its definition says: with ``fill``, ``blend`` and ``held`` the nodes' values interpolated bilinearly on their
  lon/lat grid, ``fill(p) + held(p) (T⁻¹(p) - blend(p))``, normalised; the nodes' own ``blend`` is eq. (2) by hand.

It is compared with ``Result.inverse_points`` (the blend at arbitrary directions), ``Result.inverse_map``
(every pixel, what the image and the quality figures use) and ``Result.forward_points`` (the blend inverted
near a control): a few hundred directions on two scenes, in the default mode and the paper's.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from omniwidget.document.handles import Handles, Options
from omniwidget.evaluate.scenes import family_scene
from omniwidget.raster.pipeline import warp

W = 512
#: By hand against Result.inverse_points, degrees: the same formula in double precision, other arithmetic
#: (homogeneous coordinates, another chart); measured 5.9e-14° at most. Rounding level.
POINTS_DEG = 1e-12
#: Against Result.inverse_map at pixel centres, degrees: the image's map interpolates float32 weights at float32
#: barycentric coordinates and skips a control over a block of rows where its weight stays below 1e-6;
#: measured up to 1.3e-8° (default) and 1.7e-7° (paper, whose maps move the sphere farther). Bound 1.2x the worst.
MAP_DEG = 2.1e-7
#: Result.forward_points sent back through eq. (2) by hand, degrees: measured up to 9.1e-14°. Rounding level.
FORWARD_DEG = 1e-12


def _by_hand(result, lonlat: np.ndarray) -> np.ndarray:
    """Eq. (2) at ``lonlat`` (n, 2) degrees, from the mesh, the per-vertex weights and the controls' matrices."""
    lon, lat = np.radians(lonlat[:, 0]), np.radians(lonlat[:, 1])
    p = np.stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)], axis=-1)
    # the triangle whose cone holds p, and p's barycentric coordinates on it
    corners = result.vertices[result.faces]  # (m, 3 corners, 3)
    lam = np.linalg.solve(np.transpose(corners, (0, 2, 1))[None], p[:, None, :, None])[..., 0]  # (n, m, 3)
    inside = lam.min(axis=-1) >= -1e-12
    assert np.all(inside.any(axis=1)), "a direction in no face's cone"
    face = np.argmax(np.where(inside, lam.min(axis=-1), -np.inf), axis=1)
    bary = lam[np.arange(len(p)), face]
    bary /= bary.sum(axis=1, keepdims=True)
    weights = np.einsum("nc,nck->nk", bary, result.weights[result.faces[face]])
    # each control's inverse Möbius map, through the stereographic projection from the north pole
    assert np.all(p[:, 2] < 1 - 1e-9), "a direction at the projection pole"
    z = (p[:, 0] + 1j * p[:, 1]) / (1 - p[:, 2])
    total = np.zeros_like(p)
    for j, control in enumerate(result.controls):
        (a, b), (c, d) = control.moebius.matrix
        assert abs(a * d - b * c - 1) < 1e-9
        w = (d * z - b) / (-c * z + a)
        r2 = np.abs(w) ** 2
        source = np.stack([2 * w.real, 2 * w.imag, r2 - 1], axis=-1) / (r2 + 1)[:, None]
        source[~np.isfinite(r2)] = (0.0, 0.0, 1.0)  # sent to the north pole
        total += weights[:, j : j + 1] * source
    total /= np.linalg.norm(total, axis=-1, keepdims=True)
    if result.fill is not None:
        total = _filled_by_hand(result.fill, lonlat, total)
    return np.stack([np.degrees(np.arctan2(total[:, 1], total[:, 0])), np.degrees(np.arcsin(np.clip(total[:, 2], -1, 1)))], axis=-1)


def _filled_by_hand(fill, lonlat: np.ndarray, blend: np.ndarray) -> np.ndarray:
    """The fill's map at ``lonlat`` (n, 2) from the blend there (n, 3): bilinear on its node grid, nodes at pixel centres."""
    rows, width = fill.held.shape
    step = 360.0 / width
    x = (lonlat[:, 0] + 180.0) / step - 0.5
    y = np.clip((90.0 - lonlat[:, 1]) / step - 0.5, 0, rows - 1)
    i0, j0 = np.floor(x).astype(int), np.minimum(np.floor(y), rows - 2).astype(int)
    fx, fy = x - i0, y - j0
    out = np.zeros_like(blend)
    share = np.zeros(len(blend))
    for dj, di, w in ((0, 0, (1 - fy) * (1 - fx)), (0, 1, (1 - fy) * fx), (1, 0, fy * (1 - fx)), (1, 1, fy * fx)):
        j, i = j0 + dj, (i0 + di) % width
        out += w[:, None] * (fill.filled[j, i] - fill.blend[j, i])
        share += w * fill.held[j, i]
    out += share[:, None] * blend
    for dj, di, w in ((0, 0, (1 - fy) * (1 - fx)), (0, 1, (1 - fy) * fx), (1, 0, fy * (1 - fx)), (1, 1, fy * fx)):
        out += (w * (1 - share))[:, None] * fill.blend[j0 + dj, (i0 + di) % width]
    out /= np.linalg.norm(out, axis=-1, keepdims=True)
    return np.where(share[:, None] == 1.0, blend, out)


def _apart(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angular distance in degrees between ``[lon, lat]`` rows."""

    def xyz(q):
        lon, lat = np.radians(q[:, 0]), np.radians(q[:, 1])
        return np.stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)], axis=-1)

    u, v = xyz(a), xyz(b)
    return np.degrees(np.arctan2(np.linalg.norm(np.cross(u, v), axis=-1), np.sum(u * v, axis=-1)))


@pytest.fixture(scope="module", params=[True, False], ids=["default", "paper"])
def scene(request):
    """A room with lines, a moved cage and point handles (``mixed`` seed 1), warped at 512 in the default mode
    (the still background, which folds nothing here: no window is untangled, the map is eq. (2) with its fill
    everywhere) and in the paper's (``anchor: null``)."""
    room, doc, _ = family_scene("mixed", 1, W)
    if not request.param:
        doc = Handles(doc.handles, Options(rectify=doc.options.rectify, anchor=None))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = warp(room.image, doc)
    assert result.weights is not None and len(result.controls) > 3
    if request.param:
        assert result.folds.area == 0 and not any("untangled" in m for m in result.warnings), result.warnings
        assert result.fill is not None and not result.fill.held.all()  # the fill is there to be checked
    else:
        assert result.fill is None
    return request.param, result


def _directions(result, rng) -> np.ndarray:
    """150 directions spread over the sphere (uniform in area, away from the north pole) and 150 on and near the
    handles: their constrained points (weights 1 for one control) and points up to 3° from them."""
    xyz = rng.normal(size=(150, 3))
    spread = xyz / np.linalg.norm(xyz, axis=-1, keepdims=True)
    points = result.constraints.points[rng.choice(len(result.constraints.points), 150, replace=False)]
    near = points.copy()
    near[75:] += rng.normal(scale=np.radians(1.5), size=(75, 3))
    near /= np.linalg.norm(near, axis=-1, keepdims=True)
    every = np.concatenate([spread, near])
    every = every[every[:, 2] < 0.999]
    return np.stack([np.degrees(np.arctan2(every[:, 1], every[:, 0])), np.degrees(np.arcsin(every[:, 2]))], axis=-1)


def test_inverse_points_are_eq_2_at_chosen_directions(scene):
    default, result = scene
    lonlat = _directions(result, np.random.default_rng(2))
    assert len(lonlat) >= 280
    error = _apart(_by_hand(result, lonlat), result.inverse_points(lonlat))
    print(f"\n{'default' if default else 'paper'}: {len(lonlat)} directions, eq. (2) by hand against inverse_points: {error.max():.2e}°")
    assert error.max() < POINTS_DEG


def test_the_images_map_is_eq_2_at_chosen_pixels(scene):
    default, result = scene
    rng = np.random.default_rng(3)
    inverse = result.inverse_map(np.float64)
    h, w = inverse.shape[:2]
    rows, cols = rng.integers(2, h - 2, 300), rng.integers(0, w, 300)  # not the top rows: the projection pole
    centres = np.stack([(cols + 0.5) * 360.0 / w - 180.0, 90.0 - (rows + 0.5) * 180.0 / h], axis=-1)
    error = _apart(_by_hand(result, centres), inverse[rows, cols])
    moved = _apart(centres, inverse[rows, cols])
    print(
        f"\n{'default' if default else 'paper'}: 300 pixels, eq. (2) by hand against inverse_map: {error.max():.2e}° "
        f"(they moved up to {moved.max():.1f}°)"
    )
    assert moved.max() > 1.0  # the map is no identity here
    assert error.max() < MAP_DEG


def test_forward_points_are_inverted_by_eq_2(scene):
    default, result = scene
    worst = 0.0
    for control, samples in result.constraints.lines:
        found = result.forward_points(samples, control)
        worst = max(worst, float(_apart(_by_hand(result, found), samples).max()))
    print(f"\n{'default' if default else 'paper'}: the lines' samples found forward, sent back by eq. (2) by hand: {worst:.2e}°")
    assert worst < FORWARD_DEG
