"""The compiled per-pixel kernels (numba) against the numpy path they replace."""

import warnings

import numpy as np
import pytest

from omniwidget.document.handles import CageHandle, Handles, LineHandle, Options, PointHandle
from omniwidget.evaluate.quality import fold_over
from omniwidget.evaluate.scenes import mark_lines, synthetic_room
from omniwidget.method.locate import barycentric, locate_faces, locate_grid
from omniwidget.raster import _kernels
from omniwidget.raster.blend import blended_inverse, mesh_pixel_weights
from omniwidget.raster.pipeline import warp
from omniwidget.raster.warping import PAD, remap_coordinates
from omniwidget.sphere import coords
from tests import requires

requires.kernels("numba is not installed (pip install numba), or OMNIWIDGET_NUMBA=0")

W = 512


@pytest.fixture(scope="module")
def room():
    """Lines only (they fold the far field), a fixed cage and a moved point: every kind of pixel."""
    scene = synthetic_room(W, size=(4.0, 3.0, 3.0), camera=(0.3, -0.2, -1.0), yaw=37.0)
    lines = mark_lines(scene, 8, seed=3, min_bend=5.0 * W / 2048)
    cage = CageHandle(((-150.0, -20.0), (-120.0, -20.0), (-120.0, 10.0), (-150.0, 10.0)))
    point = PointHandle((-60.0, -30.0), target=(-52.0, -26.0), scale=1.3, rotation=20.0)
    doc = Handles(
        (*(LineHandle(line.start, line.end) for line in lines), cage, point), Options(rectify="all", anchor=None)
    )  # the paper: its far field folds
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = warp(scene.image, doc)
    return scene, doc, result


def _wrapped(d: np.ndarray, src_width: int) -> np.ndarray:
    d = d.copy()
    d[..., 0] = (d[..., 0] + src_width / 2) % src_width - src_width / 2
    return d


def test_blend_kernel_gives_the_numpy_blends_coordinates(room):
    _, _, result = room
    inverses = [c.moebius.inverse for c in result.controls]
    face, planes = locate_faces(result.vertices, result.faces, W)
    grid_face, bary = locate_grid(result.vertices, result.faces, W)
    assert np.array_equal(face, grid_face)
    ours = _kernels.blend_coordinates(face, planes, result.faces, result.weights, inverses, W)
    numpy_path = remap_coordinates(blended_inverse(inverses, mesh_pixel_weights(result.faces, result.weights, face, bary)), W, W)
    exact = remap_coordinates(result.inverse, W, W)  # float64 all the way, rounded to float32 at the end
    assert np.abs(_wrapped(ours - exact, W)).max() < 2e-3
    assert np.abs(_wrapped(numpy_path - exact, W)).max() < 1e-2  # single-precision complex arithmetic
    assert ours.dtype == np.float32 and ours.shape == (W // 2, W, 2)


def test_walking_blend_finds_the_painted_faces(room):
    """Walking from pixel to pixel finds the faces locate_faces paints, and so the same coordinates; without the walk, the painted way."""
    _, _, result = room
    inverses = [c.moebius.inverse for c in result.controls]
    face, planes = locate_faces(result.vertices, result.faces, W)
    painted = _kernels.blend_coordinates(face, planes, result.faces, result.weights, inverses, W)
    for walk in (_kernels.WALK_STEPS, 0):  # 0: almost every pixel is not found, and the grid is painted instead
        ours, our_face, our_planes = _kernels.walk_blend(result.vertices, result.faces, result.weights, inverses, W, W, walk=walk)
        np.testing.assert_array_equal(our_planes, planes)
        # a pixel on an edge may be found in the face across it, where the blend is the same up to rounding
        assert (our_face != face).mean() < 1e-3
        assert np.abs(_wrapped(ours - painted, W)).max() < 1e-2


def test_fold_kernel_marks_what_fold_over_marks(room):
    _, _, result = room
    coordinates = remap_coordinates(result.inverse, W, W)
    lonlat = (coordinates.astype(np.float64) - (PAD - 0.5)) * (360.0 / W) * np.array([1, -1]) + np.array([-180, 90])
    reference = fold_over(lonlat)
    ours = _kernels.fold_mask(coordinates, W)
    assert reference.area > 1e-4, "the room should fold somewhere far from its lines"
    assert np.count_nonzero(ours != reference.mask) <= 2, np.count_nonzero(ours != reference.mask)


def test_warp_with_and_without_the_kernels_agree(room, monkeypatch):
    scene, doc, fast = room
    monkeypatch.setattr(_kernels, "available", lambda: False)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        slow = warp(scene.image, doc)
    assert "locate" in slow.timings and "locate" not in fast.timings  # the kernels walk to each pixel's face as they blend
    difference = np.abs(fast.image.astype(int) - slow.image.astype(int))
    assert difference.mean() < 0.5 and difference.max() <= 2, (difference.mean(), difference.max())
    assert abs(fast.folds.area - slow.folds.area) < 1e-5 and fast.warnings == slow.warnings
    assert np.array_equal(fast.inverse_map(np.float64), slow.inverse_map(np.float64))  # the measured map is the exact one either way


def test_barycentric_from_planes_matches_locate_grid(room):
    _, _, result = room
    face, planes = locate_faces(result.vertices, result.faces, W)
    _, bary = locate_grid(result.vertices, result.faces, W)
    lon, lat = coords.grid_lonlat(W)
    rows, cols = np.arange(0, W // 2, 7), np.arange(0, W, 11)
    rr, cc = np.meshgrid(rows, cols, indexing="ij")
    ours = barycentric(planes, face[rr, cc].ravel(), coords.lonlat_to_xyz(np.stack([lon[cc], lat[rr]], axis=-1)).reshape(-1, 3))
    np.testing.assert_allclose(ours, bary[rr, cc].reshape(-1, 3), atol=1e-6)


def test_the_kernels_can_be_switched_off(monkeypatch):
    _kernels.available.cache_clear()
    try:
        monkeypatch.setenv("OMNIWIDGET_NUMBA", "0")
        assert not _kernels.available()
    finally:
        _kernels.available.cache_clear()
        monkeypatch.delenv("OMNIWIDGET_NUMBA")
    assert _kernels.available()


def test_painting_and_strongest_weights_match_numpy(room, monkeypatch):
    _, _, result = room
    face, planes = locate_faces(result.vertices, result.faces, W)
    with monkeypatch.context() as m:
        m.setattr(_kernels, "available", lambda: False)
        numpy_face, _ = locate_faces(result.vertices, result.faces, W)
    assert np.array_equal(face, numpy_face)
    mask = result.folds.mask
    assert mask.any()
    rows, cols = np.nonzero(mask)
    lon, lat = coords.grid_lonlat(W)
    at = barycentric(planes, face[rows, cols], coords.lonlat_to_xyz(np.stack([lon[cols], lat[rows]], axis=-1)))
    from omniwidget.method.locate import interpolate

    expected = interpolate(result.weights, result.faces, face[rows, cols], at).max(axis=0)
    np.testing.assert_allclose(_kernels.strongest_weights(mask, face, planes, result.faces, result.weights), expected, atol=1e-12)


_FRESH_WARP = """
import json, warnings
warnings.simplefilter("ignore")
from omniwidget import _numba_kernels as k
from omniwidget.evaluate.scenes import family_scene
from omniwidget.raster.pipeline import warp
scene, doc, _ = family_scene("mixed", 1, 2048)
warp(scene.image, doc)
kernels = [f for f in vars(k).values() if hasattr(f, "stats")]
print(json.dumps({"hits": sum(sum(f.stats.cache_hits.values()) for f in kernels),
                  "misses": sum(sum(f.stats.cache_misses.values()) for f in kernels)}))
"""


@pytest.mark.slow  # three fresh processes, the first compiling every kernel into an empty cache (20 s): the full suite
def test_the_kernels_compile_once_per_installation_not_per_process(tmp_path):
    """A fresh process: a second fresh process reads every kernel from numba's cache, and the cache does not grow."""
    import json
    import os
    import subprocess
    import sys

    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}

    def fresh() -> tuple[dict, dict[str, float]]:
        run = subprocess.run([sys.executable, "-c", _FRESH_WARP], env=env, capture_output=True, text=True, timeout=600, check=True)
        files = {str(p.relative_to(tmp_path)): p.stat().st_mtime_ns for p in tmp_path.rglob("*") if p.is_file()}
        return json.loads(run.stdout.strip().splitlines()[-1]), files

    first, files = fresh()
    assert first["misses"] > 0 and files  # compiled, and written to the cache
    for _ in range(2):
        again, files_again = fresh()
        assert again["misses"] == 0 and again["hits"] >= first["misses"], again  # nothing compiled
        assert files_again == files  # the same files, none added or rewritten


def test_the_harmonic_fill_compiled_and_in_numpy_agree(monkeypatch):
    """raster.filling.fill_coordinates: the kernel against the numpy path, on the blend of a room of long lines at 512
    (both single precision; measured 6.1e-5 px apart at most, where the fill moved the blend by 16.6 px)."""
    from omniwidget.evaluate.scenes import family_scene
    from omniwidget.method import harmonic
    from omniwidget.raster.filling import fill_coordinates

    room, doc, _ = family_scene("long", 3, 512)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = warp(room.image, doc)
        monkeypatch.setattr(harmonic, "FILL", False)
        blend = warp(room.image, doc).coordinates
    assert result.fill is not None and blend is not None
    compiled, plain = blend.copy(), blend.copy()
    fill_coordinates(compiled, result.fill, room.image.shape[1])
    monkeypatch.setattr(_kernels, "available", lambda: False)
    fill_coordinates(plain, result.fill, room.image.shape[1])
    def distance(a, b):
        d = np.abs(a - b)
        d[..., 0] = np.minimum(d[..., 0], room.image.shape[1] - d[..., 0])  # across the seam
        return d

    apart, moved = distance(compiled, plain), distance(compiled, blend).max()
    print(f"\nthe fill moved the blend by up to {moved:.2f} px; compiled and numpy {apart.max():.2e} px apart")
    assert moved > 1.0 and apart.max() < 1e-3
