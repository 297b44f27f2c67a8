"""Reliability of images: whatever file or array comes in, a result or one clear message naming it.

Bad files (cut short, damaged, empty, not images), tiny and non-2:1 images, every sample
type and channel layout through a warp, EXIF orientation, and a 12000 x 6000 panorama
within 4 GB. Files are made here, byte by byte where it matters.
"""

from __future__ import annotations

import hashlib
import json
import struct
import subprocess
import sys
import textwrap
import zlib

import cv2
import numpy as np
import pytest

from omniwidget import to_equirectangular
from omniwidget.app.cli import main
from omniwidget.document.handles import Handles
from omniwidget.errors import ImageError
from omniwidget.io.images import check_panorama, read_image, write_image
from omniwidget.raster.pipeline import warp
from omniwidget.raster.warping import pad_panorama, warp_moebius
from omniwidget.sphere import coords
from omniwidget.sphere.moebius import Moebius

# the paper's method (no still background): each point moves the whole image, visibly
PAPER = {"anchor": None}
ONE_POINT = {"handles": [{"kind": "point", "position": [0, 0], "target": [20, 5]}], "options": PAPER}
TWO_POINTS = {"handles": [ONE_POINT["handles"][0], {"kind": "point", "position": [120, -10], "target": [130, -15]}], "options": PAPER}


def _panorama(width: int = 64) -> np.ndarray:
    """uint8 RGB with structure in both directions (JPEG blocks of one colour would hide a flip)."""
    lon, lat = np.meshgrid(*coords.grid_lonlat(width))
    return np.stack([(lon + 180) / 360 * 255, (lat + 90) / 180 * 255, (np.sin(np.radians(5 * lon)) + 1) * 100], axis=-1).astype(np.uint8)


def _encoded(image: np.ndarray, suffix: str, params: tuple[int, ...] = ()) -> bytes:
    ok, data = cv2.imencode(suffix, image, list(params))
    assert ok
    return data.tobytes()


def _digest(path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


# --- bad files -----------------------------------------------------------------------------


def _bad_files(tmp_path):
    """name -> (bytes, or None for a folder; the message expected after the name)."""
    image = np.random.default_rng(5).integers(0, 256, (200, 400, 3), dtype=np.uint8)  # noise: large compressed data
    jpeg, progressive = _encoded(image, ".jpg"), _encoded(image, ".jpg", (cv2.IMWRITE_JPEG_PROGRESSIVE, 1))
    png, tif, webp, bmp = (_encoded(image, s) for s in (".png", ".tif", ".webp", ".bmp"))
    flipped = bytearray(png)
    flipped[len(png) // 2] ^= 0x40  # one bit in the compressed pixels
    truncated = "the file looks truncated"
    return {
        "half.jpg": (jpeg[: len(jpeg) // 2], f"{truncated} (the JPEG data ends before its end-of-image marker)"),
        "no_eoi.jpg": (jpeg[:-2], f"{truncated} (the JPEG data ends before its end-of-image marker)"),
        "zero_tail.jpg": (jpeg[: len(jpeg) // 2] + bytes(len(jpeg) // 2), f"{truncated} (the JPEG data ends"),
        "progressive_half.jpg": (progressive[: len(progressive) // 2], f"{truncated} (the JPEG data ends"),
        "headers_only.jpg": (jpeg[:300], f"{truncated} (the JPEG data ends"),
        "half.png": (png[: len(png) // 2], f"{truncated} (the PNG data ends before its IEND chunk)"),
        "no_iend.png": (png[:-12], f"{truncated} (the PNG data ends before its IEND chunk)"),
        "flipped.png": (bytes(flipped), "the file is damaged: the PNG chunk IDAT at byte"),
        "half.tif": (tif[: len(tif) // 2], f"{truncated} (the TIFF directory lies past the end of the file)"),
        "half.webp": (webp[: len(webp) // 2], f"{truncated} (the WebP data is {len(webp) // 2} bytes, its header says {len(webp)})"),
        "half.bmp": (bmp[: len(bmp) // 2], f"{truncated} (the BMP data is {len(bmp) // 2} bytes, its header says {len(bmp)})"),
        "empty.jpg": (b"", "the file is empty"),
        "text.jpg": (b"just some words\nin a text file\n", "not an image OpenCV can decode (it looks like a text file)"),
        "noise.png": (bytes(np.random.default_rng(1).integers(0, 256, 999, dtype=np.uint8)), "not an image OpenCV can decode"),
        "signature_only.png": (png[:8], f"{truncated} (the PNG data ends before its IEND chunk)"),
        "folder.png": (None, "is a folder, not an image file"),
    }


def _place(path, data: bytes | None) -> None:
    """Write one of ``_bad_files``' files: its bytes, or a folder where the data is None."""
    if data is None:
        path.mkdir()
    else:
        path.write_bytes(data)


def test_bad_files_are_refused_by_name_and_decoders_print_nothing(tmp_path, capfd):
    for name, (data, message) in _bad_files(tmp_path).items():
        path = tmp_path / name
        _place(path, data)
        with pytest.raises(ImageError) as info:
            read_image(path)
        assert str(info.value).startswith(f"{path}: {message}"), (name, str(info.value))
        assert capfd.readouterr().err == "", name  # refused before libpng or libjpeg sees it: not a line of theirs
    with pytest.raises(ImageError, match=r"missing\.png: cannot read the image \(No such file or directory\)"):
        read_image(tmp_path / "missing.png")


def test_bad_files_through_the_command_line_give_one_line_and_leave_nothing(tmp_path, capfd):
    work = tmp_path / "work"
    work.mkdir()
    (work / "h.json").write_text(json.dumps(ONE_POINT))
    for name, (data, message) in _bad_files(tmp_path).items():
        path = work / name
        _place(path, data)
        listing = sorted(p.name for p in work.iterdir())
        before = _digest(path) if data is not None else None
        code = main(["warp", str(path), "-H", str(work / "h.json"), "-o", str(work / "out.png"), "--map", str(work / "map.npy")])
        err = capfd.readouterr().err  # the file descriptor: OpenCV's and libpng's own lines would show here
        assert code == 2
        assert err.startswith(f"omniwidget warp: error: {path}: {message}"), err
        assert err.count("\n") == 1 and err.endswith("\n"), err
        assert sorted(p.name for p in work.iterdir()) == listing, name  # no output, no map, no temporary file
        if before is not None:
            assert _digest(path) == before  # the input is never modified


def test_valid_files_of_every_flavour_decode_as_opencv_decodes_them(tmp_path):
    image = _panorama(128)
    bgr = np.ascontiguousarray(image[..., ::-1])  # what OpenCV encodes as this RGB image
    variants = {
        "baseline.jpg": _encoded(bgr, ".jpg"),
        "progressive.jpg": _encoded(bgr, ".jpg", (cv2.IMWRITE_JPEG_PROGRESSIVE, 1)),
        "optimized.jpg": _encoded(bgr, ".jpg", (cv2.IMWRITE_JPEG_OPTIMIZE, 1)),
        "restarts.jpg": _encoded(bgr, ".jpg", (cv2.IMWRITE_JPEG_RST_INTERVAL, 1)),
        # bytes after the end marker (camera trailers), and fill bytes before a marker: decoders accept both
        "trailer.jpg": _encoded(bgr, ".jpg") + b"\x00" * 100 + b"trailer",
        "fill.jpg": _encoded(bgr, ".jpg")[:2] + b"\xff\xff\xff" + _encoded(bgr, ".jpg")[2:],
        "rgb.png": _encoded(bgr, ".png"),
        "deep.png": _encoded(bgr.astype(np.uint16) * 257, ".png"),
        "rgb.tif": _encoded(bgr, ".tif"),
        "lossless.webp": _encoded(bgr, ".webp", (cv2.IMWRITE_WEBP_QUALITY, 101)),
        "rgb.bmp": _encoded(bgr, ".bmp"),
    }
    for name, data in variants.items():
        (tmp_path / name).write_bytes(data)
        expected = cv2.cvtColor(cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED), cv2.COLOR_BGR2RGB)
        np.testing.assert_array_equal(read_image(tmp_path / name), expected, err_msg=name)
    lossless = ("rgb.png", "rgb.tif", "lossless.webp", "rgb.bmp")
    for name in lossless:
        np.testing.assert_array_equal(read_image(tmp_path / name), image, err_msg=name)


def test_a_bad_frame_among_good_ones_is_reported_and_the_rest_written(tmp_path, capfd):
    frames = tmp_path / "frames"
    frames.mkdir()
    image = _panorama(64)
    for i in range(3):
        write_image(frames / f"f{i}.jpg", image)
    whole = (frames / "f1.jpg").read_bytes()
    (frames / "f1.jpg").write_bytes(whole[: len(whole) // 2])
    (tmp_path / "h.json").write_text(json.dumps(ONE_POINT))
    code = main(["warp", *(str(frames / f"f{i}.jpg") for i in range(3)), "-H", str(tmp_path / "h.json"), "-o", str(tmp_path / "out"), "-q"])
    err = capfd.readouterr().err.splitlines()
    assert code == 2
    assert (
        err[0]
        == f"omniwidget warp: error: {frames / 'f1.jpg'}: the file looks truncated (the JPEG data ends before its end-of-image marker); was it copied or downloaded whole?"
    )
    assert err[1] == "omniwidget warp: 1 of 3 frames were not warped (see above)" and len(err) == 2
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["f0.jpg", "f2.jpg"]


def test_npy_inputs_and_their_problems(tmp_path):
    image = np.random.default_rng(2).random((8, 16, 2))  # float64 gray + alpha: no image format holds it
    np.save(tmp_path / "a.npy", image)
    np.testing.assert_array_equal(read_image(tmp_path / "a.npy"), image)
    np.save(tmp_path / "big_endian.npy", image.astype(">f4"))
    back = read_image(tmp_path / "big_endian.npy")
    assert back.dtype == np.float32 and back.dtype.isnative and np.allclose(back, image, atol=1e-7)
    np.save(tmp_path / "objects.npy", np.array([{"a": 1}], dtype=object), allow_pickle=True)
    with pytest.raises(ImageError, match=r"objects\.npy: a damaged or unreadable \.npy file"):
        read_image(tmp_path / "objects.npy")
    (tmp_path / "cut.npy").write_bytes((tmp_path / "a.npy").read_bytes()[:100])
    with pytest.raises(ImageError, match=r"cut\.npy: a damaged or unreadable \.npy file"):
        read_image(tmp_path / "cut.npy")


# --- arrays that are not panoramas, and tiny ones ------------------------------------------


def test_arrays_that_cannot_be_warped_say_why():
    doc = Handles.from_dict(ONE_POINT)
    cases = {
        "got 3 x 1": np.zeros((1, 3, 3), np.uint8),
        "got 1 x 1": np.zeros((1, 1), np.uint8),
        "the image is empty (0 x 0)": np.zeros((0, 0), np.uint8),
        "the image is empty (0 x 4)": np.zeros((4, 0, 3), np.uint8),
        "sample type bool is not supported": np.zeros((4, 8), bool),
        "sample type float16 is not supported": np.zeros((4, 8), np.float16),
        "non-native byte order": np.zeros((4, 8), ">f4"),
        "2 sample(s) are not finite (NaN or infinity), the first at row 1, column 5": np.where(
            np.isin(np.arange(32).reshape(4, 8), [13, 30]), np.nan, 0.0
        ),
        "expected a numpy array, got list": [[0, 0]],
    }
    for message, image in cases.items():
        with pytest.raises(ImageError, match="^image: .*" + message.replace("(", r"\(").replace(")", r"\)")):
            warp(image, doc)
    inf = np.zeros((300, 600), np.float32)
    inf[299, 599] = np.inf  # the last sample of the last block checked
    with pytest.raises(ImageError, match="1 sample.* at row 299, column 599"):
        check_panorama(inf, "inf.tif")


def test_non_2_to_1_messages_name_the_size_and_the_fix():
    with pytest.raises(ImageError) as wide:
        check_panorama(np.zeros((300, 1000, 3), np.uint8), "band.jpg")
    assert str(wide.value) == (
        "band.jpg: an equirectangular panorama is twice as wide as high, got 1000 x 300; if it covers 360° of longitude but was "
        'cropped at the top and bottom, pad it with fit="pad" (rows added above and below), or resize it with fit="stretch" '
        "(omniwidget warp --fit, or omniwidget.to_equirectangular)"
    )
    with pytest.raises(ImageError) as tall:
        check_panorama(np.zeros((600, 1000), np.uint8), "tall.png")
    assert str(tall.value).startswith("tall.png: an equirectangular panorama is twice as wide as high, got 1000 x 600; resize it")


@pytest.mark.parametrize("width", [2, 4, 6, 8])
@pytest.mark.parametrize("order", ["nearest", "bilinear", "bicubic"])
def test_tiny_panoramas_warp(width, order):
    """From 2 x 1 up: the padding (3 pixels, more than such an image is high) goes round the sphere."""
    image = np.random.default_rng(width).random((width // 2, width, 3)).astype(np.float32)
    half_turn = warp_moebius(image, Moebius.rotation([0, 90], 180), order=order).image  # about the poles: a roll
    np.testing.assert_allclose(half_turn, np.roll(image, width // 2, axis=1), atol=1e-6)
    for doc in (ONE_POINT, TWO_POINTS):  # one map; a blend of two
        out = warp(image, Handles.from_dict(doc), order=order, warn=False).image
        assert out.shape == image.shape and out.dtype == np.float32 and np.isfinite(out).all()
        assert image.min() - 1e-6 <= out.min() and out.max() <= image.max() + 1e-6 or order == "bicubic"


def test_padding_a_tiny_panorama_walks_round_the_meridians():
    # 2 x 1: pixels a, b. Above row 0 is row 0 half a turn away (b, a), above that row 0 again, ...
    padded = pad_panorama(np.array([[1.0, 2.0]]), 3)
    ab, ba = [1.0, 2.0], [2.0, 1.0]
    # columns wrap too: the 8 columns -3..4 are columns 1 0 1 0 1 0 1 0
    expected = np.array([r[1:] + r + r + r + r[:1] for r in (ba, ab, ba, ab, ba, ab, ba)])
    np.testing.assert_array_equal(padded, expected)
    # as high as the padding (3 rows, pad 3): the last rows below are the bottom rows half a turn away
    image = np.arange(18.0).reshape(3, 6)
    padded = pad_panorama(image, 3)
    assert padded.shape == (9, 12)
    for k in range(3):
        np.testing.assert_array_equal(padded[3 + 3 + k, 3:-3], np.roll(image[2 - k], 3))
        np.testing.assert_array_equal(padded[2 - k, 3:-3], np.roll(image[k], 3))


# --- non-2:1: pad or stretch, on request -------------------------------------------------


def test_pad_adds_rows_of_zero_centred_on_the_horizon():
    band = np.random.default_rng(3).integers(1, 256, (301, 1000, 4), dtype=np.uint8)  # 360° x 108.4°, RGBA
    full = to_equirectangular(band, "pad")
    assert full.shape == (500, 1000, 4) and full.dtype == np.uint8
    np.testing.assert_array_equal(full[99:400], band)  # 199 rows added: 99 above, 100 below
    assert not full[:99].any() and not full[400:].any()  # black, and transparent
    # a band row keeps its latitude: the middle row of the band is the equator's
    assert coords.px_to_lonlat(np.array([[0.0, 99 + 150]]), 1000)[0, 1] == pytest.approx(0.0, abs=0.2)
    for dtype in (np.uint16, np.float32, np.float64):
        gray = np.ones((100, 400), dtype)
        out = to_equirectangular(gray, "pad")
        assert out.dtype == dtype and out.shape == (200, 400) and out.sum() == gray.sum()
    same = np.zeros((4, 8), np.uint8)
    assert to_equirectangular(same, "pad") is same and to_equirectangular(same, "stretch") is same


def test_pad_refuses_what_it_cannot_do_and_stretch_does_it():
    with pytest.raises(ImageError, match=r"1000 x 600 is taller than 2:1, so it cannot be padded with rows.*fit=\"stretch\""):
        to_equirectangular(np.zeros((600, 1000), np.uint8), "pad")
    with pytest.raises(ImageError, match=r"1001 x 300 has an odd width"):
        to_equirectangular(np.zeros((300, 1001), np.uint8), "pad")
    with pytest.raises(ValueError, match='fit must be "pad" or "stretch", got \'crop\''):
        to_equirectangular(np.zeros((300, 1000), np.uint8), "crop")
    # stretch keeps the width (rounded up to even) and makes the height half of it
    ramp = np.repeat(np.linspace(0, 1, 600, dtype=np.float32)[:, None], 1000, axis=1)[..., None]
    tall = to_equirectangular(ramp, "stretch")
    assert tall.shape == (500, 1000, 1) and tall.dtype == np.float32
    assert np.all(np.diff(tall[:, 0, 0]) > 0) and tall[0, 0, 0] < 0.002 and tall[-1, 0, 0] > 0.998  # top stays top, bottom bottom
    assert np.ptp(tall, axis=1).max() < 1e-6
    odd = to_equirectangular(np.full((1, 3, 3), 7, np.uint8), "stretch")  # the 3 x 1 image: 4 x 2
    assert odd.shape == (2, 4, 3) and (odd == 7).all()
    wide = to_equirectangular(np.full((300, 1000, 2), 40000, np.uint16), "stretch")
    assert wide.shape == (500, 1000, 2) and (wide == 40000).all()


def test_fit_through_the_command_line(tmp_path, capfd):
    band = _panorama(256)[32:96]  # 256 x 64: a panorama cropped to +-45° of latitude
    write_image(tmp_path / "band.png", band)
    (tmp_path / "h.json").write_text(json.dumps(ONE_POINT))
    argv = ["warp", str(tmp_path / "band.png"), "-H", str(tmp_path / "h.json"), "-o", str(tmp_path / "out.png")]
    assert main(argv) == 2
    err = capfd.readouterr().err
    assert err.startswith(
        f"omniwidget warp: error: {tmp_path / 'band.png'}: an equirectangular panorama is twice as wide as high, got 256 x 64; "
    )
    assert "--fit" in err and err.count("\n") == 1 and not (tmp_path / "out.png").exists()
    assert main([*argv, "--fit", "pad", "-q"]) == 0
    out = read_image(tmp_path / "out.png")
    expected = warp(to_equirectangular(band, "pad"), Handles.from_dict(ONE_POINT)).image
    np.testing.assert_array_equal(out, expected)
    assert main([*argv, "--fit", "stretch", "-o", str(tmp_path / "stretched.png"), "-q"]) == 0
    assert read_image(tmp_path / "stretched.png").shape == (128, 256, 3)
    write_image(tmp_path / "tall.png", band.transpose(1, 0, 2))
    assert main(["warp", str(tmp_path / "tall.png"), "-H", str(tmp_path / "h.json"), "-o", str(tmp_path / "t.png"), "--fit", "pad"]) == 2
    err = capfd.readouterr().err
    assert err.startswith(f"omniwidget warp: error: {tmp_path / 'tall.png'}: 64 x 256 is taller than 2:1")
    # many frames are fitted alike
    frames = [tmp_path / "f0.png", tmp_path / "f1.png"]
    for f in frames:
        write_image(f, band)
    assert main(["warp", *map(str, frames), "-H", str(tmp_path / "h.json"), "-o", str(tmp_path / "many"), "--fit", "pad"]) == 0
    many = read_image(tmp_path / "many" / "f1.png").astype(int)
    assert many.shape == expected.shape and np.abs(many - expected).mean() < 0.5  # the frames' float32 map: the same warp


# --- depths and channels: kept, and the alpha channel moves with the colours -------------------


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.float32, np.float64])
@pytest.mark.parametrize("channels", [None, 1, 2, 3, 4])
def test_every_depth_and_layout_warps_with_its_alpha(dtype, channels):
    rng = np.random.default_rng(7)
    top = {np.uint8: 255, np.uint16: 65535}.get(dtype, 1.0)
    gray = (_panorama(64)[..., 0] / 255 * top).astype(dtype)  # a pattern that moves visibly under the handle
    if channels is None:
        image = gray
    else:
        colours = (rng.random((32, 64, max(channels - 1, 1))) * top).astype(dtype)
        image = np.dstack([colours, gray])[..., -channels:] if channels > 1 else gray[..., None]
    for doc in (ONE_POINT, TWO_POINTS):
        handles = Handles.from_dict(doc)
        out = warp(image, handles, warn=False).image
        assert out.dtype == dtype and out.shape == image.shape
        alone = warp(gray, handles, warn=False).image
        last = out if channels is None else out[..., -1]
        np.testing.assert_array_equal(last, alone)  # the last (alpha) channel is warped exactly like a gray image
        assert np.abs(last.astype(float) - gray.astype(float)).mean() > 0.02 * top  # and it moved


@pytest.mark.parametrize(
    ("suffix", "dtype", "channels"),
    [
        (".png", np.uint16, 4),
        (".png", np.uint8, 2),
        (".tif", np.float32, 3),
        (".tif", np.float64, 4),
        (".npy", np.float64, 2),
        (".tif", np.uint16, None),
    ],
)
def test_depth_and_alpha_survive_the_command_line(tmp_path, capfd, suffix, dtype, channels):
    top = {np.uint8: 255, np.uint16: 65535}.get(dtype, 1.0)
    base = _panorama(128).astype(np.float64) / 255 * top
    layouts = {None: base[..., 0], 2: base[..., [0, 0]], 3: base, 4: base[..., [0, 1, 2, 0]]}  # alpha: a copy of the first colour
    image = layouts[channels].astype(dtype)
    source = tmp_path / f"in{suffix}"
    write_image(source, image)
    before = _digest(source)
    (tmp_path / "h.json").write_text(json.dumps(ONE_POINT))
    assert main(["warp", str(source), "-H", str(tmp_path / "h.json"), "-o", str(tmp_path / f"out{suffix}"), "-q"]) == 0
    assert _digest(source) == before
    out = read_image(tmp_path / f"out{suffix}")
    expected = warp(image, Handles.from_dict(ONE_POINT)).image
    if channels == 2 and suffix != ".npy":  # gray + alpha is stored as RGBA
        expected = expected[..., [0, 0, 0, 1]]
    assert out.dtype == dtype
    np.testing.assert_array_equal(out, expected)
    if channels in (2, 4):
        np.testing.assert_array_equal(out[..., -1], out[..., 0])  # the alpha, a copy of the first colour, moved with it
    assert capfd.readouterr().err == ""


def test_outputs_that_cannot_hold_the_image_are_refused_before_the_work(tmp_path, capfd, monkeypatch):
    write_image(tmp_path / "rgba.png", np.zeros((16, 32, 4), np.uint8))
    write_image(tmp_path / "deep.png", np.zeros((16, 32, 3), np.uint16))
    np.save(tmp_path / "float.npy", np.zeros((16, 32), np.float32))
    (tmp_path / "h.json").write_text(json.dumps(ONE_POINT))

    def no_warp(*args, **kwargs):
        raise AssertionError("the warp ran")

    monkeypatch.setattr("omniwidget.raster.pipeline.warp", no_warp)
    cases = {
        "rgba.png": ("out.jpg", "out.jpg: JPEG has no alpha channel; write .png, .tif, .webp or .npy to keep it"),
        "deep.png": ("out.jpg", "out.jpg: cannot write a uint16 image as .jpg (use .png, .tif, .tiff, .npy)"),
        "float.npy": ("out.png", "out.png: cannot write a float32 image as .png (use .tif, .tiff, .npy)"),
    }
    for source, (output, message) in cases.items():
        assert main(["warp", str(tmp_path / source), "-H", str(tmp_path / "h.json"), "-o", str(tmp_path / output)]) == 2
        err = capfd.readouterr().err
        assert message in err and err.count("\n") == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["deep.png", "float.npy", "h.json", "rgba.png"]


# --- EXIF orientation ----------------------------------------------------------------------


def _exif(orientation: int, order: str = "MM") -> bytes:
    """A TIFF-structured EXIF block whose first directory holds one entry: Orientation."""
    e = ">" if order == "MM" else "<"
    return (
        order.encode() + struct.pack(e + "HIH", 42, 8, 1) + struct.pack(e + "HHIHH", 0x0112, 3, 1, orientation, 0) + struct.pack(e + "I", 0)
    )


def _jpeg_with_orientation(jpeg: bytes, orientation: int, order: str = "MM") -> bytes:
    payload = b"Exif\x00\x00" + _exif(orientation, order)
    return jpeg[:2] + b"\xff\xe1" + struct.pack(">H", len(payload) + 2) + payload + jpeg[2:]


def _png_with_orientation(png: bytes, orientation: int) -> bytes:
    body = b"eXIf" + _exif(orientation, "II")
    chunk = struct.pack(">I", len(body) - 4) + body + struct.pack(">I", zlib.crc32(body))
    return png[:33] + chunk + png[33:]  # after the signature and IHDR


#: What each orientation does to the stored pixels to show them (the EXIF 2.3 definitions, written out).
SHOWN = {
    1: lambda a: a,
    2: lambda a: np.fliplr(a),
    3: lambda a: np.rot90(a, 2),
    4: lambda a: np.flipud(a),
    5: lambda a: np.transpose(a, (1, 0, 2)),
    6: lambda a: np.rot90(a, -1),  # a quarter turn clockwise
    7: lambda a: np.rot90(np.transpose(a, (1, 0, 2)), 2),
    8: lambda a: np.rot90(a, 1),  # a quarter turn anticlockwise
}


@pytest.mark.parametrize("orientation", range(1, 9))
@pytest.mark.parametrize("order", ["MM", "II"])
def test_exif_orientation_is_applied_as_viewers_show_it(tmp_path, orientation, order):
    stored = _panorama(32)  # 32 x 16, no symmetry
    jpeg = _encoded(cv2.cvtColor(stored, cv2.COLOR_RGB2BGR), ".jpg", (cv2.IMWRITE_JPEG_QUALITY, 100))
    (tmp_path / "plain.jpg").write_bytes(jpeg)
    (tmp_path / "turned.jpg").write_bytes(_jpeg_with_orientation(jpeg, orientation, order))
    plain = read_image(tmp_path / "plain.jpg")
    np.testing.assert_array_equal(read_image(tmp_path / "turned.jpg"), SHOWN[orientation](plain))
    np.testing.assert_array_equal(read_image(tmp_path / "turned.jpg", orientation=False), plain)
    png = _encoded(cv2.cvtColor(stored, cv2.COLOR_RGB2BGR), ".png")
    (tmp_path / "turned.png").write_bytes(_png_with_orientation(png, orientation))
    np.testing.assert_array_equal(read_image(tmp_path / "turned.png"), SHOWN[orientation](stored))


def test_exif_orientation_by_landmarks_and_as_pillow_shows_it(tmp_path):
    stored = np.zeros((16, 32, 3), np.uint8)
    stored[:8, :8] = (255, 0, 0)  # a red block at the top left of the stored pixels
    jpeg = _encoded(cv2.cvtColor(stored, cv2.COLOR_RGB2BGR), ".jpg", (cv2.IMWRITE_JPEG_QUALITY, 100))
    corners = {3: (-1, -1), 6: (0, -1), 8: (-1, 0), 2: (0, -1)}  # where it is seen: half turn, quarter turns, mirrored
    for orientation, (row, col) in corners.items():
        (tmp_path / f"o{orientation}.jpg").write_bytes(_jpeg_with_orientation(jpeg, orientation))
        shown = read_image(tmp_path / f"o{orientation}.jpg")
        assert shown.shape == ((32, 16, 3) if orientation in (6, 8) else (16, 32, 3))
        assert shown[row, col, 0] > 240 and shown[row, col, 1] < 15, orientation
        assert shown[0 if row else -1, -1 if col == 0 else 0, 0] < 15
    image_module = pytest.importorskip("PIL.Image")
    image_ops = pytest.importorskip("PIL.ImageOps")
    for orientation in range(1, 9):
        path = tmp_path / f"o{orientation}.jpg"
        path.write_bytes(_jpeg_with_orientation(_encoded(cv2.cvtColor(_panorama(32), cv2.COLOR_RGB2BGR), ".jpg"), orientation))
        with image_module.open(path) as im:
            pillow = np.asarray(image_ops.exif_transpose(im).convert("RGB")).astype(int)
        assert np.abs(read_image(path).astype(int) - pillow).max() <= 2, orientation  # decoders round differently


def test_a_camera_portrait_turned_by_exif_is_a_panorama(tmp_path, capfd):
    """Stored 1:2 with Orientation 6 (the camera was held on its side): shown, and warped, 2:1."""
    shown = _panorama(64)
    stored = np.rot90(shown, 1)  # what the sensor wrote: turning it a quarter clockwise gives the panorama
    jpeg = _encoded(cv2.cvtColor(np.ascontiguousarray(stored), cv2.COLOR_RGB2BGR), ".jpg", (cv2.IMWRITE_JPEG_QUALITY, 100))
    (tmp_path / "stored.jpg").write_bytes(jpeg)
    (tmp_path / "portrait.jpg").write_bytes(_jpeg_with_orientation(jpeg, 6))
    portrait = read_image(tmp_path / "portrait.jpg")
    np.testing.assert_array_equal(portrait, np.rot90(read_image(tmp_path / "stored.jpg"), -1))
    assert np.abs(portrait.astype(int) - shown).mean() < 5  # JPEG's loss on strong colour gradients
    (tmp_path / "h.json").write_text(json.dumps(ONE_POINT))
    assert main(["warp", str(tmp_path / "portrait.jpg"), "-H", str(tmp_path / "h.json"), "-o", str(tmp_path / "o.png"), "-q"]) == 0
    assert read_image(tmp_path / "o.png").shape == (32, 64, 3) and capfd.readouterr().err == ""


def test_malformed_exif_is_ignored_not_fatal(tmp_path):
    jpeg = _encoded(_panorama(32), ".jpg")
    broken = [
        b"Exif\x00\x00MM\x00\x2a\xff\xff\xff\xff",  # the directory far past the end
        b"Exif\x00\x00XX\x00\x2a\x00\x00\x00\x08",  # no byte order
        b"Exif\x00\x00" + _exif(9),  # no such orientation
        b"Exif\x00\x00" + _exif(6)[:14],  # the entry cut off
    ]
    plain = read_image_bytes(tmp_path, jpeg)
    for payload in broken:
        data = jpeg[:2] + b"\xff\xe1" + struct.pack(">H", len(payload) + 2) + payload + jpeg[2:]
        np.testing.assert_array_equal(read_image_bytes(tmp_path, data), plain)


def read_image_bytes(tmp_path, data: bytes) -> np.ndarray:
    path = tmp_path / "x.jpg"
    path.write_bytes(data)
    return read_image(path)


# --- outputs whole or not at all ----------------------------------------------------------------


def test_a_failed_run_leaves_an_existing_output_and_the_input_untouched(tmp_path, capfd, monkeypatch):
    write_image(tmp_path / "in.png", _panorama(64))
    (tmp_path / "h.json").write_text(json.dumps(ONE_POINT))
    (tmp_path / "out.png").write_bytes(b"yesterday's output")
    (tmp_path / "map.npy").write_bytes(b"yesterday's map")
    (tmp_path / "bad.json").write_text('{"handles": [{"kind": "point", "position": [0, 95]}]}')
    (tmp_path / "cut.png").write_bytes((tmp_path / "in.png").read_bytes()[:200])
    before = _digest(tmp_path / "in.png")
    argv = ["-o", str(tmp_path / "out.png"), "--map", str(tmp_path / "map.npy")]
    runs = [
        ["warp", str(tmp_path / "in.png"), "-H", str(tmp_path / "bad.json"), *argv],  # bad handles
        ["warp", str(tmp_path / "cut.png"), "-H", str(tmp_path / "h.json"), *argv],  # bad image
    ]
    for run in runs:
        assert main(run) == 2
    real_imencode = cv2.imencode

    def disk_full(path, data):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr("omniwidget.io.images.atomic_write_bytes", disk_full)  # the write fails after the warp
    assert main(["warp", str(tmp_path / "in.png"), "-H", str(tmp_path / "h.json"), *argv]) == 2
    monkeypatch.undo()
    monkeypatch.setattr(cv2, "imencode", lambda *a: (False, None) if a[0] == ".png" else real_imencode(*a))  # encoding fails
    assert main(["warp", str(tmp_path / "in.png"), "-H", str(tmp_path / "h.json"), *argv]) == 2
    err = capfd.readouterr().err.splitlines()
    assert err[2] == f"omniwidget warp: error: {tmp_path / 'out.png'}: cannot write the file (No space left on device)"
    assert err[3] == f"omniwidget warp: error: {tmp_path / 'out.png'}: OpenCV could not encode the image as .png" and len(err) == 4
    assert (tmp_path / "out.png").read_bytes() == b"yesterday's output"
    assert (tmp_path / "map.npy").read_bytes() == b"yesterday's map"  # not half a result: neither file was written
    assert _digest(tmp_path / "in.png") == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.json", "cut.png", "h.json", "in.png", "map.npy", "out.png"]


def test_writing_a_folder_or_gray_alpha(tmp_path):
    (tmp_path / "taken.png").mkdir()
    with pytest.raises(ImageError, match=r"taken\.png: is a folder; name an image file"):
        write_image(tmp_path / "taken.png", np.zeros((4, 8), np.uint8))
    la = np.dstack([np.arange(32, dtype=np.uint8).reshape(4, 8), np.full((4, 8), 200, np.uint8)])
    write_image(tmp_path / "la.png", la)
    np.testing.assert_array_equal(read_image(tmp_path / "la.png"), la[..., [0, 0, 0, 1]])  # stored as RGBA
    write_image(tmp_path / "la.tif", la.astype(np.float32))
    np.testing.assert_array_equal(read_image(tmp_path / "la.tif"), la[..., [0, 0, 0, 1]].astype(np.float32))
    with pytest.raises(ImageError, match=r"x\.png: cannot write an array of shape \(4, 8, 5\) as an image \(use \.npy\)"):
        write_image(tmp_path / "x.png", np.zeros((4, 8, 5), np.uint8))


# --- a 12000 x 6000 panorama within 4 GB ----------------------------------------------------------

BIG = textwrap.dedent(
    """
    import json, resource, sys
    import cv2, numpy as np
    from omniwidget.app.cli import main
    from omniwidget.raster import _kernels
    from omniwidget.document.handles import Handles
    from omniwidget.io.images import read_image, write_image
    from omniwidget.raster.pipeline import warp

    folder, handles = sys.argv[1], json.loads(sys.argv[2])
    h, w = 6000, 12000
    # smooth waves of 600-1200 px (75-150 px at 1500 wide): they survive JPEG and scaling, so the comparison
    # below sees the map, not aliasing (a grid of 1-px lines left 13% of the motion as noise); made in bands of
    # rows so that no float copy of the whole image raises the peak
    image = np.empty((h, w, 3), np.uint8)
    x = np.arange(w, dtype=np.float32)[None]
    for r0 in range(0, h, 500):
        y = np.arange(r0, r0 + 500, dtype=np.float32)[:, None]
        image[r0:r0 + 500, :, 0] = np.round(127.5 + 127 * np.cos(2 * np.pi * x / 800) * np.cos(2 * np.pi * y / 600))
        image[r0:r0 + 500, :, 1] = np.round(127.5 + 127 * np.sin(2 * np.pi * x / 1200) * np.sin(2 * np.pi * y / 1000))
        image[r0:r0 + 500, :, 2] = np.round(127.5 + 127 * np.cos(2 * np.pi * (x + y) / 900))
    write_image(f"{folder}/in.jpg", image)
    small_in = cv2.resize(image, (1500, 750), interpolation=cv2.INTER_AREA)
    del image
    with open(f"{folder}/h.json", "w") as fh:
        json.dump(handles, fh)
    code = main(["warp", f"{folder}/in.jpg", "-H", f"{folder}/h.json", "-o", f"{folder}/out.jpg"])
    peak_kib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss  # KiB on Linux
    out = read_image(f"{folder}/out.jpg")
    small_out = cv2.resize(out, (1500, 750), interpolation=cv2.INTER_AREA).astype(float)
    reference = warp(small_in, Handles.from_dict(handles), warn=False).image.astype(float)
    print(json.dumps({
        "code": code, "peak_kib": peak_kib, "shape": list(out.shape), "dtype": str(out.dtype), "compiled": _kernels.available(),
        "off": float(np.abs(small_out - reference).mean()), "moved": float(np.abs(small_in - reference).mean()),
    }))
    """
)


@pytest.mark.slow  # a 12000 x 6000 warp in a process of its own
def test_a_12000_by_6000_panorama_warps_within_4_gb(tmp_path):
    """The command line on a 12000 x 6000 JPEG with four handles, in a process of its own (its peak is its own)."""
    from omniwidget.raster import _kernels

    if not _kernels.available():
        pytest.skip("the memory target is the compiled kernels' (the fast extra); the numpy path needs more")
    handles = {
        "handles": [
            {"kind": "line", "start": [-4, 37.5], "end": [68, 36.5]},
            {"kind": "line", "start": [-83, 12], "end": [-45.5, 12]},
            {"kind": "point", "position": [120, -10], "target": [125, -8]},
            {"kind": "cage", "vertices": [[-28, -5], [-2, -5], [-2, -50], [-28, -50]]},
        ],
        "options": PAPER,  # it moves the whole image: the scaled-down comparison below sees the map
    }
    proc = subprocess.run([sys.executable, "-c", BIG, str(tmp_path), json.dumps(handles)], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    report = json.loads(proc.stdout.splitlines()[-1])
    assert report["code"] == 0 and report["compiled"]
    assert report["shape"] == [6000, 12000, 3] and report["dtype"] == "uint8"
    assert report["peak_kib"] <= 4 * 1024 * 1024, f"peak {report['peak_kib'] / 1024**2:.2f} GiB"
    # the big warp, scaled down, is the warp of the scaled-down input (the map is in degrees): measured a mean
    # difference of 0.46 levels against 62 levels of motion (0.75%; JPEG alone accounts for 0.22); bound 2%
    assert report["off"] < 0.02 * report["moved"] and report["off"] < 1.0, report
    print(f"12000 x 6000 through the command line: peak {report['peak_kib'] / 1024**2:.2f} GiB, {report}")


def test_the_sizes_a_warps_memory_is_counted_by_are_the_resamplings_own():
    """io counts a warp's memory without importing the resampling: its sizes must be the resampling's and the strips' own."""
    from omniwidget.io.large import WARP_SIZES
    from omniwidget.raster import strips, warping

    sizes = WARP_SIZES
    assert (sizes.pad, sizes.remap_limit, sizes.patch_pixels) == (warping.PAD, warping.REMAP_LIMIT, warping.PATCH_PIXELS)
    assert (sizes.stream_width, sizes.map_width, sizes.strip_pixels, sizes.strips_ahead) == (
        strips.STREAM_WIDTH,
        strips.MAP_WIDTH,
        strips.STRIP_PIXELS,
        strips.STRIPS_AHEAD,
    )
    for width in (1, 1000, 16384, 64000, 10**6):
        assert sizes.strip_rows(width) == strips.strip_rows(width)
