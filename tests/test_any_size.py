"""Panoramas of any size: the tiled resampling beyond OpenCV's 32,767 pixels.

OpenCV's ``remap`` keeps coordinates in 16 bits and refuses a source or a map of 32,767
pixels a side or more. ``remap_panorama`` resamples such panoramas by tiles of the output,
each from the patch of the source its samples fall in (no padded copy of the source). The
tests check that the tiled path gives the bytes of the one call wherever both can run
(every order, depth and layout, tiles across the seam and over the poles), then warp a
generated room wider than the limit.
"""

from __future__ import annotations

import os
import subprocess
import sys

import cv2
import numpy as np
import pytest

import omniwidget as ow
from omniwidget.evaluate.scenes import family_scene
from omniwidget.io.images import memory_needed
from omniwidget.raster import warping
from omniwidget.sphere.moebius import Moebius


def _coordinates(width: int, src_width: int) -> np.ndarray:
    """Source coordinates of a zoom and a turn that carry samples across the seam and over the poles."""
    m = Moebius.rotation((100.0, 60.0), 2.0) @ Moebius.zoom((175.0, 70.0), 1.7)
    return warping.remap_coordinates(warping.grid_inverse(m.inverse, "single"), width, src_width)


@pytest.fixture(scope="module")
def room() -> np.ndarray:
    return family_scene("mixed", 3, width=512)[0].image


@pytest.mark.parametrize("layout", ["gray", "two", "rgb", "rgba"])
@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.float32])
def test_the_tiled_resampling_gives_the_bytes_of_one_call(room, layout, dtype):
    image = {"gray": room[..., 0], "two": room[..., :2], "rgb": room, "rgba": np.dstack([room, room[..., :1]])}[layout]
    image = image.astype(dtype) * (257 if dtype == np.uint16 else 1)
    coordinates = _coordinates(768, image.shape[1])
    coordinates[5, 7] = (-50.0, 9e4)  # off the source: its border, as OpenCV's one call gives
    east = coordinates[..., 0] >= warping.PAD + image.shape[1] / 2
    assert east.any() and not east.all(), "the map must carry samples to both sides of the seam"
    for order in warping.ORDERS:
        one_call = warping.remap(warping.pad_panorama(image), coordinates, order)
        for tile in (300, 37, 4):
            tiled = warping.remap_panorama(image, coordinates, order, tile=tile)
            assert tiled.dtype == one_call.dtype and tiled.shape == one_call.shape
            assert np.array_equal(tiled, one_call), f"{order}, tiles of {tile}: {np.count_nonzero(tiled != one_call)} values differ"
            assert np.array_equal(warping.remap(warping.pad_panorama(image), coordinates, order, tile=tile), one_call)


def test_a_tiny_panorama_and_bad_input(room):
    tiny = np.arange(2 * 4 * 3, dtype=np.uint8).reshape(2, 4, 3)
    coordinates = _coordinates(16, 4)
    for order in warping.ORDERS:
        assert np.array_equal(
            warping.remap_panorama(tiny, coordinates, order, tile=3), warping.remap(warping.pad_panorama(tiny), coordinates, order)
        )
    with pytest.raises(ow.ImageError, match="width must be even"):
        warping.remap_panorama(np.zeros((3, 5)), coordinates)
    with pytest.raises(ValueError, match="order must be one of"):
        warping.remap_panorama(room, coordinates, "cubic")
    with pytest.raises(ValueError, match="tile"):
        warping.remap_panorama(room, coordinates, tile=0)


@pytest.mark.slow
def test_a_panorama_forced_through_the_tiles_warps_to_the_same_bytes(monkeypatch):
    """8192 px, a document of every kind, in the default mode: with OpenCV's limit lowered to 3000 the warp is tiled."""
    scene, doc, _ = family_scene("mixed", 5, width=8192)
    untiled = ow.warp(scene.image, doc)
    calls: list[int] = []
    patch = warping._remap_patch

    def counted(*args, **kwargs):
        calls.append(1)
        return patch(*args, **kwargs)

    monkeypatch.setattr(warping, "REMAP_LIMIT", 3000)
    monkeypatch.setattr(warping, "REMAP_TILE", 1024)
    monkeypatch.setattr(warping, "_remap_patch", counted)
    tiled = ow.warp(scene.image, doc)
    assert len(calls) >= (8192 // 1024) * (4096 // 1024), f"{len(calls)} patches: the warp was not tiled"
    assert np.array_equal(tiled.image, untiled.image)


#: The generated room beyond OpenCV's limit: 34,000 x 17,000, gray (578 MB).
WIDE = 34_000
#: Memory of the command's process and libraries, which the estimate leaves out: measured 205-210 MB (peak of
#: ``omniwidget warp`` on a 128 x 64 panorama), with room for the allocator.
PROCESS = 250 * 2**20


@pytest.fixture(scope="module")
def wide_room(tmp_path_factory):
    """A room rendered at 4096, enlarged to 34,000 px in strips into a memory-mapped .npy, and the same as a JPEG.

    Returns (folder, the 4096 render's green channel, its handles document).
    """
    folder = tmp_path_factory.mktemp("wide")
    scene, doc, _ = family_scene("mixed", 7, width=4096)
    small = np.ascontiguousarray(scene.image[..., 1])
    wide = np.lib.format.open_memmap(folder / "wide.npy", mode="w+", dtype=np.uint8, shape=(WIDE // 2, WIDE))
    strip = 1000  # rows at a time, each from the rows of the render under them (bilinear)
    x = ((np.arange(WIDE) + 0.5) * small.shape[1] / WIDE - 0.5).astype(np.float32)
    for r0 in range(0, WIDE // 2, strip):
        r1 = min(r0 + strip, WIDE // 2)
        y = ((np.arange(r0, r1) + 0.5) * small.shape[0] / (WIDE // 2) - 0.5).astype(np.float32)
        for c0 in range(0, WIDE, WIDE // 2):  # OpenCV's own limit on the map's width
            map_x, map_y = np.meshgrid(x[c0 : c0 + WIDE // 2], y)
            wide[r0:r1, c0 : c0 + WIDE // 2] = cv2.remap(small, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
    wide.flush()
    assert cv2.imwrite(str(folder / "wide.jpg"), wide, [cv2.IMWRITE_JPEG_QUALITY, 95])
    del wide
    (folder / "h.json").write_text(doc.to_json())
    return folder, small, doc


def _warp_cli(folder, name: str, width: int, suffix: str = ".png", env: dict[str, str] | None = None) -> tuple[np.ndarray, int]:
    """``omniwidget warp folder/name -H folder/h.json --width width`` in a process of its own: (the output, its peak bytes)."""
    out = folder / f"{name}-{width}{suffix}"
    command = [sys.executable, "-m", "omniwidget", "warp", str(folder / name), "-H", str(folder / "h.json"), "-o", str(out)]
    probe = "import resource, subprocess, sys; subprocess.run(sys.argv[1:], check=True); print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)"
    environment = {**os.environ, **(env or {})}
    done = subprocess.run([sys.executable, "-c", probe, *command, "--width", str(width)], capture_output=True, text=True, check=False, env=environment)
    assert done.returncode == 0, done.stderr
    got = cv2.imread(str(out), cv2.IMREAD_UNCHANGED)
    out.unlink()
    return got, int(done.stdout) * 1024


@pytest.mark.slow
@pytest.mark.parametrize(
    ("name", "levels"),
    # measured 0.083 and 0.82 levels on average: the JPEG's 1/8 DCT scaling averages 8 x 8 blocks where the
    # bilinear warp of the render keeps its edges (p99 29 levels on the painted lines), and JPEG at quality 95
    [("wide.npy", 0.2), ("wide.jpg", 1.5)],
)
def test_a_panorama_wider_than_opencvs_limit_warps(wide_room, name, levels):
    """34,000 px, warped by the command line to 4096: the same warp of the 4096 render, within the enlargement's blur.

    The .npy is resampled in tiles, the JPEG read at the size asked (1/8: 4250 px wide);
    each command's peak memory is measured and within the estimate that refuses what
    would not fit.
    """
    folder, small, doc = wide_room
    got, peak = _warp_cli(folder, name, 4096)
    assert got.shape == (2048, 4096)
    expected = ow.warp(small, doc).image
    difference = np.abs(got.astype(np.float64) - expected)
    estimate = memory_needed(folder / name, warp=True, width=4096)
    print(
        f"{name} 34,000 px to 4096: mean difference {difference.mean():.3f} levels, p99 {np.percentile(difference, 99):.1f}; "
        f"peak {peak / 2**20:.0f} MB, estimated {estimate / 2**20:.0f} MB"
    )
    assert difference.mean() < levels, f"mean difference {difference.mean():.2f} levels from the warp of the render"
    assert peak < estimate + PROCESS, f"peak {peak / 2**20:.0f} MB over the estimate {estimate / 2**20:.0f} MB and the process's {PROCESS / 2**20:.0f} MB"


@pytest.mark.slow
def test_the_editor_opens_a_large_jpeg_reduced_and_reads_it_whole_only_to_save(tmp_path):
    """A 16,384 px JPEG: the editor works on its 1/8 decoding (2048 wide); Save image reads it whole and writes it full size."""
    from omniwidget.app.session import EditingSession

    scene, doc, _ = family_scene("mixed", 9, width=2048)
    path = tmp_path / "large.jpg"
    assert cv2.imwrite(str(path), cv2.resize(scene.image[..., ::-1], (16384, 8192), interpolation=cv2.INTER_LINEAR))
    session = EditingSession(path, doc, autosave=False, quality=False)
    session.start()
    assert session.wait()["state"] == "idle"
    assert session.image_size == (16384, 8192)
    assert session._working.shape[:2] == (1024, 2048) and session._full_image is None  # the file is not read whole
    shown = cv2.imdecode(np.frombuffer(session.display_source(), np.uint8), cv2.IMREAD_COLOR)
    assert shown.shape == (1024, 2048, 3)
    difference = np.abs(shown[..., ::-1].astype(np.float64) - scene.image).mean()
    assert difference < 2.2, f"the display copy is {difference:.2f} levels from the render on average"  # measured 1.81: JPEG twice, the 1/8 scaling
    preview = session.preview_result.image
    expected = ow.warp(scene.image, doc, width=preview.shape[1]).image
    off = np.abs(preview.astype(np.float64) - expected).mean()
    print(f"display copy {difference:.2f} levels from the render, preview {off:.2f} from the render's warp")  # measured 1.81, 1.01
    assert off < 1.3, f"the preview is {off:.2f} levels from the render's warp on average"
    saved = session.save_image(tmp_path / "out.png")
    assert session._full_image is not None and session._full_image.shape[:2] == (8192, 16384)
    assert cv2.imread(str(saved)).shape == (8192, 16384, 3)


def test_a_warp_in_strips_on_its_own_grid_is_the_warp(room, tmp_path):
    """map_width = width: each strip is the warp's own rows (the coordinates through unit vectors and back), the map its placed map."""
    from omniwidget.io.images import read_image, write_image_strips
    from omniwidget.raster.strips import warp_in_strips

    _, doc, _ = family_scene("mixed", 3, width=512)
    made = warp_in_strips(room, doc, width=512, map_width=512, rows=37)
    whole = ow.warp(room, doc)
    strips = np.concatenate(list(made.image_strips()))
    assert strips.shape == whole.image.shape == made.shape
    off = np.abs(strips.astype(np.int64) - whole.image)
    assert off.max() <= 1 and np.count_nonzero(off) < 1e-3 * off.size, f"{np.count_nonzero(off)} values differ, by up to {off.max()}"
    placed = np.concatenate(list(made.map_strips())).astype(np.float64)
    difference = placed - whole.placed_map()
    difference[..., 0] = (difference[..., 0] + 180) % 360 - 180
    assert np.abs(difference).max() < 1e-3, f"the map in strips is {np.abs(difference).max():.2g}° from the placed map"
    for suffix in (".tif", ".npy", ".png"):
        write_image_strips(tmp_path / f"o{suffix}", made.shape, made.dtype, made.image_strips())
        assert np.array_equal(read_image(tmp_path / f"o{suffix}"), strips), suffix
    assert sorted(p.name for p in tmp_path.iterdir()) == ["o.npy", "o.png", "o.tif"]  # no temporary file left
    with pytest.raises(ow.ImageError, match="the strips gave 100 of the image's 256 rows"):
        write_image_strips(tmp_path / "short.tif", made.shape, made.dtype, iter([strips[:100]]))
    assert not (tmp_path / "short.tif").exists() and len(list(tmp_path.iterdir())) == 3


def test_a_single_map_in_strips_is_exact(room):
    doc = ow.Handles((ow.PointHandle((0.0, 0.0), (10.0, 5.0), scale=1.3),), options=ow.Options(anchor=None))
    from omniwidget.raster.strips import warp_in_strips

    made = warp_in_strips(room, doc, width=1024, map_width=128, rows=100)
    assert made.result.coordinates is None  # one map: no grid to interpolate
    off = np.abs(np.concatenate(list(made.image_strips())).astype(np.int64) - ow.warp(room, doc, width=1024).image)
    assert off.max() <= 1  # double against single precision: a level at most (measured 1, on 0.5% of the values)


@pytest.mark.slow
@pytest.mark.parametrize(("where", "suffix"), [("memory", ".tif"), ("disk", ".png")])
def test_a_full_width_warp_of_a_panorama_wider_than_opencvs_limit_is_made_in_strips(wide_room, where, suffix):
    """34,000 px to 34,000 px, written strip by strip: right (against the render's warp), in bounded memory.

    From memory (the panorama decoded whole, 578 MB) as a tiled BigTIFF; from disk (as a panorama above
    STREAM_BYTES is: a patch at a time, the method on a copy reduced for the map grid) as a PNG written in strips,
    in less memory than from memory and within the estimate that refuses what would not fit.
    """
    folder, small, doc = wide_room
    env = {"OMNIWIDGET_STREAM_BYTES": "1"} if where == "disk" else {}
    got, peak = _warp_cli(folder, "wide.npy", WIDE, suffix=suffix, env=env)
    assert got.shape == (WIDE // 2, WIDE)
    reduced = cv2.resize(got, (4096, 2048), interpolation=cv2.INTER_AREA)
    expected = ow.warp(small, doc).image
    difference = np.abs(reduced.astype(np.float64) - expected)
    with pytest.MonkeyPatch.context() as patch:
        for name, value in env.items():
            patch.setenv(name, value)
        estimate = memory_needed(folder / "wide.npy", warp=True, width=WIDE, streamed=where == "disk")
    print(f"34,000 px in strips from {where}: {difference.mean():.3f} levels at 4096; peak {peak / 2**20:.0f} MB, estimated {estimate / 2**20:.0f} MB")
    assert difference.mean() < 1.0
    assert peak < estimate + PROCESS
    assert peak < (4 if where == "memory" else 2.5) * 2**30, f"peak {peak / 2**30:.2f} GB"
