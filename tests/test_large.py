"""Panoramas larger than memory: read a patch at a time from disk, reduced in strips, written in strips.

A panorama on disk (:class:`omniwidget.io.large.DiskPanorama`) must give the bytes the
same panorama in memory gives, through the tiled resampling; the strip writers must give
files that decode to the strips; the command line must choose the disk when the panorama
is large (``OMNIWIDGET_STREAM_BYTES`` lowers the threshold so that small files take the
path here) and write the same output as from memory.
"""

from __future__ import annotations

import dataclasses
import io
import math

import cv2
import numpy as np
import pytest

import omniwidget as ow
from omniwidget.app.cli import main
from omniwidget.evaluate.scenes import family_scene
from omniwidget.io import large
from omniwidget.io.images import image_header, memory_needed, read_image, write_image, write_image_strips
from omniwidget.raster import strips, warping
from omniwidget.sphere.moebius import Moebius


@pytest.fixture(scope="module")
def room() -> tuple[np.ndarray, ow.Handles]:
    scene, doc, _ = family_scene("mixed", 3, width=1024)
    return scene.image, doc


def _coordinates(width: int, src_width: int) -> np.ndarray:
    """A zoom and a turn that carry samples across the seam and over the poles."""
    m = Moebius.rotation((100.0, 60.0), 2.0) @ Moebius.zoom((175.0, 70.0), 1.7)
    return warping.remap_coordinates(warping.grid_inverse(m.inverse, "single"), width, src_width)


@pytest.mark.parametrize("layout", ["gray", "two", "rgb", "rgba"])
@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.float32])
def test_a_panorama_on_disk_resamples_to_the_bytes_of_one_in_memory(room, tmp_path, layout, dtype):
    image = {"gray": room[0][..., 0], "two": room[0][..., :2], "rgb": room[0], "rgba": np.dstack([room[0], room[0][..., :1]])}[layout]
    image = np.ascontiguousarray(image.astype(dtype) * (257 if dtype == np.uint16 else 1))
    np.save(tmp_path / "p.npy", image)
    coordinates = _coordinates(700, image.shape[1])
    with large.open_on_disk(tmp_path / "p.npy", image_header(tmp_path / "p.npy")) as disk:
        rows, cols = np.array([0, 5, 5, 255, 3]), np.r_[1020:1024, 0:7, 300:301]  # repeated rows, columns round the seam
        assert np.array_equal(disk.take(rows, cols), image[np.ix_(rows, cols)])
        for order in warping.ORDERS:
            one_call = warping.remap_panorama(image, coordinates, order)
            for tile in (None, 300, 37):
                got = warping.remap_panorama(disk, coordinates, order, tile=tile)
                assert np.array_equal(got, one_call), f"{order}, tiles of {tile}: {np.count_nonzero(got != one_call)} values differ"
        with pytest.raises(IndexError, match="outside the 1024 x 512 panorama"):
            disk.take(np.array([512]), np.array([0]))
    assert (tmp_path / "p.npy").exists()  # a .npy is read where it is, never removed
    if dtype != np.uint8:  # stored in the other byte order: read in this machine's
        np.save(tmp_path / "swapped.npy", image.astype(image.dtype.newbyteorder("S")))
        with large.open_on_disk(tmp_path / "swapped.npy", image_header(tmp_path / "swapped.npy")) as disk:
            assert disk.dtype == image.dtype and np.array_equal(disk.rows(0, image.shape[0]), image)


@pytest.mark.parametrize("suffix", [".png", ".tif", ".jpg"])
def test_other_formats_are_decoded_to_a_temporary_file_that_goes_away(room, tmp_path, suffix):
    image = room[0]
    write_image(tmp_path / f"p{suffix}", image)
    expected = read_image(tmp_path / f"p{suffix}")  # OpenCV's decoding
    before = set(tmp_path.parent.iterdir())
    with large.open_on_disk(tmp_path / f"p{suffix}", image_header(tmp_path / f"p{suffix}")) as disk:
        assert disk.temporary and disk.path.exists() and disk.shape == image.shape
        pixels = disk.rows(0, image.shape[0])
        decoded = disk.path
    off = np.abs(pixels.astype(np.int64) - expected)
    # PNG and TIFF are lossless: the same pixels; libvips and OpenCV decode the JPEG with the same libjpeg (measured 0)
    assert off.max() <= (1 if suffix == ".jpg" else 0), f"{np.count_nonzero(off)} values differ, by up to {off.max()}"
    assert not decoded.exists() and set(tmp_path.parent.iterdir()) == before


def test_a_damaged_file_is_refused_by_name(room, tmp_path):
    write_image(tmp_path / "p.png", room[0])
    data = (tmp_path / "p.png").read_bytes()
    (tmp_path / "cut.png").write_bytes(data[: len(data) // 2])
    with pytest.raises(ow.ImageError, match="cut.png: libvips cannot decode it"):
        large.open_on_disk(tmp_path / "cut.png", image_header(tmp_path / "p.png"))
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".omniwidget")] == []


@pytest.mark.parametrize("suffix", [".npy", ".png"])
def test_a_panorama_is_decoded_reduced_by_a_box_average(room, tmp_path, suffix):
    image = room[0]
    write_image(tmp_path / f"p{suffix}", image)
    got = large.read_reduced(tmp_path / f"p{suffix}", image_header(tmp_path / f"p{suffix}"), 4)
    expected = image.reshape(128, 4, 256, 4, 3).mean(axis=(1, 3))
    off = np.abs(got - expected)
    assert got.shape == (128, 256, 3) and got.dtype == np.uint8
    assert off.max() <= 0.5 + 1e-9, f"{off.max():.2f} levels from the mean of each 4 x 4 block"  # rounded to the nearest
    with pytest.raises(ValueError, match="a factor of 3 does not divide the 1024 x 512 image"):
        large.read_reduced(tmp_path / f"p{suffix}", image_header(tmp_path / f"p{suffix}"), 3)


def test_how_a_file_is_read_follows_its_size_and_the_width_asked(room, tmp_path, monkeypatch):
    write_image(tmp_path / "p.png", room[0])
    write_image(tmp_path / "p.jpg", room[0])
    png, jpg = image_header(tmp_path / "p.png"), image_header(tmp_path / "p.jpg")
    assert large.plan_read(png, 256, strips=True) == large.ReadPlan("whole", 1)  # small: as it always was
    assert large.plan_read(jpg, 256) == large.ReadPlan("whole", 4)  # JPEG's DCT scaling
    monkeypatch.setenv(large.STREAM_VARIABLE, "1000")
    assert large.plan_read(png, 256) == large.ReadPlan("reduced", 4)
    assert large.plan_read(png, 300) == large.ReadPlan("reduced", 2)  # the largest whole factor that keeps 300 px
    assert large.plan_read(png, 1024, strips=True) == large.ReadPlan("disk", 1)
    assert large.plan_read(png, 1024) == large.ReadPlan("whole", 1)  # an array is asked for: it is decoded
    assert read_image(tmp_path / "p.png", width=256).shape == (128, 256, 3)
    monkeypatch.setenv(large.STREAM_VARIABLE, "lots")
    with pytest.raises(ow.ImageError, match="OMNIWIDGET_STREAM_BYTES='lots': expected a number of bytes"):
        large.plan_read(png, 256)


@pytest.mark.parametrize(
    ("shape", "dtype"), [((37, 50), np.uint8), ((37, 50, 2), np.uint8), ((37, 50, 3), np.uint8), ((30, 40, 4), np.uint16), ((30, 40), np.uint16)]
)
def test_a_png_written_in_strips_decodes_to_the_strips(shape, dtype):
    image = np.random.default_rng(3).integers(0, np.iinfo(dtype).max, shape, dtype=dtype, endpoint=True)
    buf = io.BytesIO()
    large.write_png_strips(buf, shape, dtype, (image[r : r + 7] for r in range(0, shape[0], 7)))
    back = cv2.imdecode(np.frombuffer(buf.getvalue(), np.uint8), cv2.IMREAD_UNCHANGED)
    if back.ndim == 3:  # OpenCV's BGR(A); gray+alpha comes as BGRA
        back = back[..., [2, 1, 0, 3][: back.shape[2]]]
        if len(shape) == 3 and shape[2] == 2:
            back = back[..., [0, 3]]
    assert back.dtype == dtype and np.array_equal(back, image)


def test_a_jpeg_written_in_strips_is_opencvs_jpeg(room, tmp_path):
    image = room[0]
    large.write_jpeg_strips(tmp_path / "s.jpg", image.shape, (image[r : r + 100] for r in range(0, 512, 100)))
    write_image(tmp_path / "w.jpg", image)
    ours, opencv = read_image(tmp_path / "s.jpg").astype(np.int64), read_image(tmp_path / "w.jpg")
    off = np.abs(ours - opencv)
    assert off.max() <= 2 and off.mean() < 0.05, f"{off.mean():.3f} levels on average, {off.max()} at most"  # measured 0: the same libjpeg
    assert [p.name for p in tmp_path.iterdir()] != [] and not list(tmp_path.glob(".omniwidget-rows-*"))


def test_write_image_strips_refuses_what_the_format_or_the_disk_cannot_hold(tmp_path, monkeypatch):
    with pytest.raises(ow.ImageError, match=r"\.jpg holds images at most 65535 px wide, this one is 70000"):
        write_image_strips(tmp_path / "w.jpg", (35000, 70000, 3), np.uint8, iter([]))
    monkeypatch.setattr(large.shutil, "disk_usage", lambda folder: type("U", (), {"free": 10**9})())
    with pytest.raises(ow.ImageError, match=r"m\.npy: a 32000 x 64000 x 2 float32 array needs 16\.38 GB of disk at .*; 1\.00 GB are free"):
        write_image_strips(tmp_path / "m.npy", (32000, 64000, 2), np.float32, iter([]))
    assert list(tmp_path.iterdir()) == []


def _cli(tmp_path, name: str, out: str, *more: str) -> np.ndarray:
    assert main(["warp", str(tmp_path / name), "-H", str(tmp_path / "h.json"), "-o", str(tmp_path / out), "--quiet", *more]) == 0
    return np.load(tmp_path / out) if out.endswith(".npy") else read_image(tmp_path / out)


@pytest.mark.parametrize("source", ["p.npy", "p.png"])
def test_the_command_line_warps_a_panorama_on_disk_to_the_same_output(room, tmp_path, monkeypatch, source):
    """With the thresholds lowered, a 1024 px panorama goes the disk's way: the same image and map as from memory."""
    image, doc = room
    write_image(tmp_path / source, image)
    (tmp_path / "h.json").write_text(doc.to_json())
    monkeypatch.setattr(strips, "STREAM_WIDTH", 512)  # made in strips
    monkeypatch.setattr(strips, "MAP_WIDTH", 512)
    in_memory = _cli(tmp_path, source, "memory.png", "--map", str(tmp_path / "memory.npy"))
    monkeypatch.setenv(large.STREAM_VARIABLE, "1")  # every panorama is large
    opened = []
    monkeypatch.setattr(large.DiskPanorama, "take", _counted(large.DiskPanorama.take, opened))
    on_disk = _cli(tmp_path, source, "disk.png", "--map", str(tmp_path / "disk.npy"))
    assert opened, "the panorama was not read from disk"
    # the method ran on a copy reduced to the map grid's width (512), which turns its pixel coordinates into directions
    # in other float32 roundings than the 1024 px panorama's: the same map within 1e-4°, a level on a few values
    off = np.abs(on_disk.astype(np.int64) - in_memory)
    assert off.max() <= 1 and np.count_nonzero(off) < 1e-4 * off.size, f"{np.count_nonzero(off)} values differ, by up to {off.max()}"
    moved = np.load(tmp_path / "disk.npy").astype(np.float64) - np.load(tmp_path / "memory.npy")
    moved[..., 0] = (moved[..., 0] + 180) % 360 - 180
    assert np.abs(moved).max() < 1e-4, f"the maps differ by {np.abs(moved).max():.2g}°"
    jpeg = _cli(tmp_path, source, "disk.jpg")
    assert np.abs(jpeg.astype(np.int64) - in_memory).mean() < 1.5  # JPEG at quality 95
    leftovers = [p.name for p in tmp_path.iterdir() if p.name.startswith(".")]
    assert leftovers == [], leftovers


def _counted(take, calls):
    def counted(self, rows, cols):
        calls.append(len(rows) * len(cols))
        return take(self, rows, cols)

    return counted


def test_the_estimate_of_a_warp_from_disk_counts_a_patch_not_the_panorama(room, tmp_path, monkeypatch):
    write_image(tmp_path / "p.png", room[0])
    whole = memory_needed(tmp_path / "p.png", warp=True, width=1024)
    monkeypatch.setenv(large.STREAM_VARIABLE, "1")
    monkeypatch.setattr(strips, "STREAM_WIDTH", 512)
    streamed = memory_needed(tmp_path / "p.png", warp=True, width=1024, streamed=True)
    patch = warping.PATCH_PIXELS * 3
    assert streamed >= patch and streamed != whole
    header = image_header(tmp_path / "p.png")
    assert math.prod(header.shape) < patch  # this panorama is smaller than one patch: the estimate is the patch's


def test_the_editor_saves_a_panorama_too_large_to_warp_whole_in_strips_with_its_progress(room, tmp_path, monkeypatch):
    """Save image of a panorama wider than STREAM_WIDTH: made in strips from disk, the rows written said as they go."""
    from omniwidget.app.session import EditingSession

    image, doc = room
    write_image(tmp_path / "p.png", image)
    (tmp_path / "h.json").write_text(doc.to_json())
    monkeypatch.setattr(strips, "STREAM_WIDTH", 512)
    monkeypatch.setattr(strips, "MAP_WIDTH", 512)
    monkeypatch.setattr(strips, "STRIP_PIXELS", 100 * 1024)  # strips of 100 rows
    monkeypatch.setenv(large.STREAM_VARIABLE, "1")
    expected = _cli(tmp_path, "p.png", "cli.png")  # the command line's warp in strips from disk
    session = EditingSession(tmp_path / "p.png", doc, autosave=False, quality=False)
    session.start()
    assert session.wait()["state"] == "idle"
    said = []
    set_status = session.board.set_status
    monkeypatch.setattr(session.board, "set_status", lambda **fields: (said.append(fields), set_status(**fields)))
    opened = []
    monkeypatch.setattr(large.DiskPanorama, "take", _counted(large.DiskPanorama.take, opened))
    saved = session.save_image(tmp_path / "saved.png")
    assert opened, "the panorama was not read from disk"
    assert np.array_equal(read_image(saved), expected)
    rows = [fields["saving"]["done"] for fields in said if fields.get("saving")]
    assert rows == [0, *range(strips.strip_rows(1024), 512, strips.strip_rows(1024)), 512], rows  # before the first strip, then after each
    assert [f["message"] for f in said if f.get("saving") and f["saving"]["done"] == 300] == ["saving saved.png: 58% of 512 rows"]
    assert session.status["message"] == f"1024 x 512 saved to {saved}" and session.status.get("saving") is None
    with pytest.raises(ow.ImageError, match="is the input panorama"):
        session.save_image(tmp_path / "p.png")
    assert read_image(tmp_path / "p.png").shape == image.shape


def test_a_warp_that_would_not_fit_in_memory_is_made_in_strips_where_those_fit(room, tmp_path, monkeypatch):
    """Below STREAM_WIDTH the command line warps in memory, unless that would not fit and the strips would: then in strips."""
    from omniwidget.io.images import MEMORY_VARIABLE

    image, doc = room
    write_image(tmp_path / "p.png", cv2.resize(image, (4096, 2048), interpolation=cv2.INTER_LINEAR))
    (tmp_path / "h.json").write_text(doc.to_json())
    monkeypatch.setattr(strips, "MAP_WIDTH", 1024)
    monkeypatch.setattr(large, "WARP_SIZES", dataclasses.replace(large.WARP_SIZES, map_width=1024))  # the memory counted alike
    whole = memory_needed(tmp_path / "p.png", warp=True)
    streamed = memory_needed(tmp_path / "p.png", warp=True, streamed=True)
    assert streamed < whole, (streamed, whole)  # the map grid (1024) and a strip against the whole output's arrays
    made = []
    warp_in_strips = strips.warp_in_strips
    monkeypatch.setattr(strips, "warp_in_strips", lambda *a, **k: made.append(k) or warp_in_strips(*a, **k))
    _cli(tmp_path, "p.png", "roomy.png")
    assert made == []
    monkeypatch.setenv(MEMORY_VARIABLE, str((whole + streamed) // 2))
    got = _cli(tmp_path, "p.png", "tight.png")
    assert len(made) == 1
    off = np.abs(got.astype(np.int64) - read_image(tmp_path / "roomy.png"))
    assert off.mean() < 1.0, f"{off.mean():.2f} levels from the warp in memory on average"  # the map interpolated from a 1024 px grid
    monkeypatch.setenv(MEMORY_VARIABLE, str(streamed // 2))  # not even the strips fit: refused, nothing written
    assert main(["warp", str(tmp_path / "p.png"), "-H", str(tmp_path / "h.json"), "-o", str(tmp_path / "none.png"), "--quiet"]) != 0
    assert not (tmp_path / "none.png").exists()


@pytest.mark.parametrize("channels", [1, 2, 3, 4])
def test_a_tiff_written_in_strips_reads_back_as_write_images(room, tmp_path, channels):
    """Tiles of 256 from strips of 37 rows (the last row of tiles padded): read back as the TIFF write_image writes."""
    image = np.dstack([room[0], room[0][..., :1]])[..., :channels] if channels > 1 else room[0][..., 0]
    image = np.ascontiguousarray(image[:300, :600])
    write_image_strips(tmp_path / "s.tif", image.shape, image.dtype, (image[r : r + 37] for r in range(0, 300, 37)))
    write_image(tmp_path / "w.tif", image)
    assert np.array_equal(read_image(tmp_path / "s.tif"), read_image(tmp_path / "w.tif"))
