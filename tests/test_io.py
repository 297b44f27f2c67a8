import numpy as np
import pytest

from omniwidget.errors import ImageError
from omniwidget.io.images import atomic_write_bytes, read_image, write_image


@pytest.mark.parametrize(
    ("suffix", "dtype", "channels"),
    [
        (".png", np.uint8, 3),
        (".png", np.uint8, 4),
        (".png", np.uint16, 3),
        (".png", np.uint16, None),
        (".tif", np.float32, 3),
        (".npy", np.float64, 4),
        (".jpg", np.uint8, None),
        (".tif", np.float64, 3),  # OpenCV's colour conversion takes no float64: the channels are swapped by numpy
        (".tif", np.float64, 4),
        (".png", np.uint16, 4),
        (".tif", np.uint16, 1),
    ],
)
def test_images_round_trip_in_their_depth_and_channel_order(tmp_path, rng, suffix, dtype, channels):
    shape = (16, 32) if channels is None else (16, 32, channels)
    top = 255 if dtype == np.uint8 else 65535 if dtype == np.uint16 else 1.0
    image = (rng.random(shape) * top).astype(dtype)
    if suffix == ".jpg":
        image[:] = 90  # lossy: check channels and depth, not exact values
    path = tmp_path / f"im{suffix}"
    write_image(path, image)
    back = np.load(path) if suffix == ".npy" else read_image(path)
    if channels == 1:
        image = image[..., 0]  # image files hold one channel as gray (H, W)
    assert back.dtype == image.dtype and back.shape == image.shape
    if suffix != ".jpg":
        np.testing.assert_array_equal(back, image)  # RGB stays RGB (OpenCV's BGR never leaks out)
    assert [p.name for p in tmp_path.iterdir()] == [path.name]


def test_unwritable_combinations_are_refused_before_anything_is_written(tmp_path):
    with pytest.raises(ImageError, match="cannot write a float32 image as .png"):
        write_image(tmp_path / "x.png", np.zeros((4, 8), np.float32))
    with pytest.raises(ImageError, match="does not exist"):
        write_image(tmp_path / "no" / "x.png", np.zeros((4, 8), np.uint8))
    assert list(tmp_path.iterdir()) == []


@pytest.fixture
def full_disk(monkeypatch):
    """Every atomic write fails as it moves its temporary file into place, as on a full disk."""

    def failing_replace(src, dst):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr("omniwidget._files.os.replace", failing_replace)


def test_atomic_write_leaves_the_old_file_when_writing_fails(tmp_path, full_disk):
    path = tmp_path / "out.bin"
    path.write_bytes(b"old")
    with pytest.raises(OSError, match="No space"):
        atomic_write_bytes(path, b"new")
    assert path.read_bytes() == b"old"
    assert [p.name for p in tmp_path.iterdir()] == ["out.bin"]  # the temporary file is gone


def test_unreadable_files_name_the_problem(tmp_path):
    (tmp_path / "empty.png").write_bytes(b"")
    (tmp_path / "junk.jpg").write_bytes(b"\xff\xd8 not really a jpeg")
    with pytest.raises(ImageError, match="empty.png: the file is empty"):
        read_image(tmp_path / "empty.png")
    with pytest.raises(ImageError, match="junk.jpg: not an image"):
        read_image(tmp_path / "junk.jpg")
    with pytest.raises(ImageError, match="missing.png: cannot read"):
        read_image(tmp_path / "missing.png")


def test_a_failed_write_says_where_and_leaves_the_old_file(tmp_path, full_disk):
    path = tmp_path / "out.png"
    path.write_bytes(b"old")
    with pytest.raises(ImageError) as info:
        write_image(path, np.zeros((4, 8, 3), np.uint8))
    assert str(info.value) == f"{path}: cannot write the file (No space left on device)"  # no temporary file's name in it
    assert path.read_bytes() == b"old" and [p.name for p in tmp_path.iterdir()] == ["out.png"]


def test_alpha_is_refused_by_jpeg_rather_than_dropped(tmp_path):
    with pytest.raises(ImageError, match=r"a\.jpg: JPEG has no alpha channel"):
        write_image(tmp_path / "a.jpg", np.zeros((4, 8, 4), np.uint8))
    write_image(tmp_path / "a.jpg", np.zeros((4, 8, 3), np.uint8))
    assert read_image(tmp_path / "a.jpg").shape == (4, 8, 3)


def test_a_file_written_whole_gets_the_permissions_a_plain_write_gives(tmp_path):
    import os
    import stat

    fresh = tmp_path / "fresh.bin"
    atomic_write_bytes(fresh, b"x")
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE(fresh.stat().st_mode) == 0o666 & ~umask  # not the temporary file's 0o600
    kept = tmp_path / "kept.bin"
    kept.write_bytes(b"old")
    kept.chmod(0o640)
    atomic_write_bytes(kept, b"new")
    assert kept.read_bytes() == b"new" and stat.S_IMODE(kept.stat().st_mode) == 0o640  # an existing file keeps its own


# --- drawing handles (omniwidget.io.draw) ------------------------------------------------------


def _drawn(canvas: np.ndarray) -> np.ndarray:
    """Pixels drawn on a black canvas."""
    return canvas.any(axis=2)


def test_draw_handles_in_one_colour_dashed_and_without_dots():
    """``colour``, ``dash`` and ``dots`` (how the gallery draws suggested lines); the defaults draw as before."""
    from omniwidget.document.handles import Handles, LineHandle, PointHandle
    from omniwidget.io.draw import COLOURS, draw_handles

    black = np.zeros((256, 512, 3), np.uint8)
    # a line across the ±180° seam, so the dashes are cut there too, and a point handle
    doc = Handles((LineHandle(start=(150.0, 10.0), end=(-120.0, 30.0)), PointHandle(position=(0.0, -20.0), target=(5.0, -20.0))))
    plain = draw_handles(black, doc)
    assert np.array_equal(plain, draw_handles(black, doc, colour=None, dash=None, dots=True))
    assert (plain == COLOURS["line"]).all(axis=2).any() and (plain == COLOURS["point"]).all(axis=2).any()

    purple = (191, 90, 242)
    one = draw_handles(black, doc, colour=purple)
    assert np.array_equal(_drawn(one), _drawn(plain))  # the same pixels, another colour
    assert (one == purple).all(axis=2).any() and not (one == COLOURS["line"]).all(axis=2).any()

    no_dots = draw_handles(black, doc, dots=False)
    assert _drawn(no_dots).sum() < _drawn(plain).sum() and not (_drawn(no_dots) & ~_drawn(plain)).any()

    dashed = draw_handles(black, doc, dash=(4, 12), dots=False)
    solid, gaps = _drawn(no_dots), _drawn(dashed)
    assert 0.2 * solid.sum() < gaps.sum() < 0.7 * solid.sum()  # 4 of every 16 pixels along the arcs, and the dashes' round ends
    import cv2

    near = cv2.dilate(solid.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    assert not (gaps & ~near).any()  # dashes only along the solid arcs (their ends' antialiasing may reach a pixel further)
    with pytest.raises(ValueError, match="dash"):
        draw_handles(black, doc, dash=(0, 5))
