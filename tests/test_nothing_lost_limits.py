"""Nothing lost: limits instead of exhaustion.

Each row of the issue's table is reproduced as the issue says (a FIFO given as ``-H``, a
handles file nested 100,000 deep, duplicate keys, a PNG that declares 46,000 x 23,000
pixels, a ``.npy`` map whose header declares (100000, 200000, 2), 10,000 handles) and the
new behaviour asserted: one line on stderr naming the file, exit 2, within a time and a
memory limit.
"""

from __future__ import annotations

import json
import os
import struct
import subprocess
import sys
import zlib
from pathlib import Path

import cv2
import numpy as np
import pytest

from omniwidget._checks import require_regular_file
from omniwidget.document.handles import Handles, load_handles
from omniwidget.errors import HandlesError, ImageError, NotRegularFileError, OmniwidgetError
from omniwidget.io import images
from omniwidget.io.images import check_fits, decode_bytes, image_header, memory_needed, read_image, read_panorama, write_image
from omniwidget.raster.pipeline import warp

POINT = {"handles": [{"kind": "point", "position": [10, 20], "target": [30, 10]}]}


def _cli(*argv: str, timeout: float = 60, memory: int | None = None) -> subprocess.CompletedProcess[str]:
    """``python -m omniwidget ARGV`` in a subprocess (under ``ulimit -v`` of ``memory`` bytes when given)."""
    command = [sys.executable, "-m", "omniwidget", *argv]
    if memory is not None:
        command = ["bash", "-c", f'ulimit -v {memory // 1024} && exec "$@"', "bash", *command]
    env = {**os.environ, "OMNIWIDGET_AUTOSAVE": "0"}
    return subprocess.run(command, capture_output=True, text=True, timeout=timeout, env=env)


def _write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def _one_line_refusal(run: subprocess.CompletedProcess[str], *words: str) -> None:
    assert run.returncode == 2, run.stderr
    assert run.stderr.count("\n") == 1 and "Traceback" not in run.stderr, run.stderr
    for word in words:
        assert word in run.stderr, (word, run.stderr)


@pytest.fixture
def panorama(tmp_path: Path) -> Path:
    image = np.zeros((32, 64, 3), np.uint8)
    image[..., 0] = np.arange(64, dtype=np.uint8)[None] * 4
    write_image(tmp_path / "in.png", image)
    return tmp_path / "in.png"


# --- special files ----------------------------------------------------------------------------


def test_require_regular_file_names_the_kind(tmp_path: Path) -> None:
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    with pytest.raises(NotRegularFileError, match=r"pipe: cannot read the handles file: it is a FIFO \(named pipe\), not a regular file"):
        require_regular_file(fifo, "handles file")
    with pytest.raises(ValueError, match="it is a character device"):  # a ValueError: the CLI's exit-2 refusals
        require_regular_file(Path("/dev/zero"), "image")
    with pytest.raises(OmniwidgetError, match="it is a folder"):
        require_regular_file(tmp_path, "map")
    (tmp_path / "plain.json").write_text("{}")
    require_regular_file(tmp_path / "plain.json", "handles file")
    require_regular_file(tmp_path / "missing.json", "handles file")  # the read that follows says it is missing


def test_a_fifo_or_a_device_is_refused_by_the_readers(tmp_path: Path) -> None:
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    with pytest.raises(HandlesError, match="pipe: cannot read the handles file: it is a FIFO"):
        load_handles(fifo)
    with pytest.raises(ImageError, match="pipe: cannot read the image: it is a FIFO"):
        read_image(fifo)
    with pytest.raises(ImageError, match="/dev/zero: cannot read the image: it is a character device"):
        read_image("/dev/zero")


def test_a_fifo_given_as_handles_is_one_line_and_exit_2_not_a_hang(tmp_path: Path, panorama: Path) -> None:
    fifo = tmp_path / "h.json"
    os.mkfifo(fifo)  # before: the command line waited for a writer until killed
    run = _cli("warp", str(panorama), "-H", str(fifo), "-o", str(tmp_path / "out.png"), timeout=60)
    _one_line_refusal(run, str(fifo), "FIFO")
    assert not (tmp_path / "out.png").exists()
    (tmp_path / "good.json").write_text(json.dumps(POINT))
    run = _cli("warp", str(fifo), "-H", str(tmp_path / "good.json"), "-o", str(tmp_path / "out.png"), timeout=60)
    _one_line_refusal(run, str(fifo), "cannot read the image: it is a FIFO")


# --- the handles file: depth and duplicate keys --------------------------------------------------


def test_a_file_nested_100000_deep_is_one_line_and_exit_2(tmp_path: Path, panorama: Path) -> None:
    deep = tmp_path / "deep.json"
    deep.write_text('{"handles": ' + "[" * 100_000 + "]" * 100_000 + "}")  # before: a 27-line RecursionError, exit 1
    with pytest.raises(HandlesError, match=r"deep\.json: the JSON is nested deeper than 32 arrays and objects \(at line 1\)"):
        load_handles(deep)
    run = _cli("warp", str(panorama), "-H", str(deep), "-o", str(tmp_path / "out.png"))
    _one_line_refusal(run, str(deep), "nested deeper than 32")
    assert not (tmp_path / "out.png").exists()


def test_the_depth_is_counted_outside_strings_only(tmp_path: Path) -> None:
    brackets = "[{" * 40 + '\\"]'
    doc = {"handles": [{"kind": "point", "position": [10, 20], "id": brackets}]}
    assert load_handles(_write(tmp_path / "h.json", json.dumps(doc))).handles[0].id == brackets
    nested = json.dumps({"handles": [{"kind": "cage", "vertices": [[0, 0], [10, 0], [5, 8]]}]}, indent=2)
    assert len(load_handles(_write(tmp_path / "cage.json", nested)).handles) == 1
    with pytest.raises(HandlesError, match="at line 3"):
        load_handles(_write(tmp_path / "deep.json", '{\n"handles":\n' + "[" * 33 + "]" * 33 + "}"))


@pytest.mark.parametrize(
    ("text", "key"),
    [
        ('{"handles": [{"kind": "point", "position": [10, 20], "target": [30, 10]}], "handles": []}', '"handles" appears twice'),
        (
            '{"handles": [{"kind": "point", "position": [10, 20], "position": [30, 10]}]}',
            '"position" appears twice in one object of a point',
        ),
        ('{"handles": [], "options": {"anchor": 5, "anchor": null}}', '"anchor" appears twice'),
    ],
)
def test_duplicate_keys_are_refused(tmp_path: Path, panorama: Path, text: str, key: str) -> None:
    assert isinstance(json.loads(text), dict)  # before: json keeps the last of each key silently (an identity warp, exit 0)
    path = _write(tmp_path / "dup.json", text)
    with pytest.raises(HandlesError, match=rf"dup\.json: the key {key}"):
        load_handles(path)
    if 'handles" appears' in key:
        run = _cli("warp", str(panorama), "-H", str(path), "-o", str(tmp_path / "out.png"))
        _one_line_refusal(run, str(path), "appears twice")
        assert not (tmp_path / "out.png").exists()


# --- memory estimated before decoding -------------------------------------------------------------

#: The command line's own address space is about 1.5 GB (numpy, scipy, OpenCV, numba mapped): 3 GB leaves
#: room to run, and none for the bomb's 3.17 GB of pixels.
ULIMIT = 3 << 30


def _png_of_zeros(path: Path, width: int, height: int) -> Path:
    """An RGB PNG of one colour (black) declaring ``width x height``, a few MB however large.

    The zlib stream is one row's deflate (after a full flush, which resets the compressor, so
    that the same bytes encode every row) repeated ``height`` times, then an empty final block
    and the Adler-32 of that many zero bytes: made in milliseconds, where Pillow or zlib would
    compress 3 GB for a minute.
    """
    row = bytes(1 + 3 * width)  # filter byte 0, then the pixels
    raw = zlib.compressobj(9, zlib.DEFLATED, -15)
    piece = raw.compress(row) + raw.flush(zlib.Z_FULL_FLUSH)
    total = height * len(row)
    stream = b"\x78\x01" + piece * height + b"\x03\x00" + struct.pack(">I", ((total % 65521) << 16) | 1)

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    ihdr = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", stream) + chunk(b"IEND", b""))
    return path


def test_the_png_bomb_is_what_the_issue_says(tmp_path: Path) -> None:
    bomb = _png_of_zeros(tmp_path / "bomb.png", 46_000, 23_000)
    assert bomb.stat().st_size < 4e6
    pil = pytest.importorskip("PIL.Image")
    pil.MAX_IMAGE_PIXELS = None
    with pil.open(bomb) as lazy:  # Pillow reads the header only
        assert lazy.size == (46_000, 23_000) and lazy.mode == "RGB"
    check = _png_of_zeros(tmp_path / "small.png", 64, 32)  # the same making, small enough to decode
    assert np.array_equal(read_image(check), np.zeros((32, 64, 3), np.uint8))
    assert decode_bytes(bomb) == 46_000 * 23_000 * 3 == 3_174_000_000


def test_the_png_bomb_is_refused_by_name_under_a_memory_limit(tmp_path: Path) -> None:
    bomb = _png_of_zeros(tmp_path / "bomb.png", 46_000, 23_000)
    (tmp_path / "h.json").write_text(json.dumps(POINT))
    # before: decoded to 3.2 GB in 60 s, then "not enough memory for this image (try a smaller --width)"
    run = _cli("warp", str(bomb), "-H", str(tmp_path / "h.json"), "-o", str(tmp_path / "out.png"), memory=ULIMIT, timeout=60)
    _one_line_refusal(run, str(bomb), "46000 x 23000 RGB uint8 image (3.17 GB decoded)", "is available", "OMNIWIDGET_MEMORY")
    assert not (tmp_path / "out.png").exists()


def _npy_header_only(path: Path, shape: tuple[int, ...], dtype: str = "<f4") -> Path:
    """A .npy file whose header declares ``shape``, followed by 64 bytes."""
    with path.open("wb") as fh:
        np.lib.format.write_array_header_1_0(fh, {"descr": dtype, "fortran_order": False, "shape": shape})
        fh.write(bytes(64))
    return path


def test_a_huge_npy_header_is_refused_by_name_before_any_allocation(tmp_path: Path) -> None:
    huge = _npy_header_only(tmp_path / "huge.npy", (100_000, 200_000, 2))
    with pytest.raises(MemoryError):  # before: np.load allocates what the header says
        np.load(huge)
    header = image_header(huge)
    assert header is not None and header.shape == (100_000, 200_000, 2) and header.nbytes == 160_000_000_000
    with pytest.raises(ImageError, match=r"huge\.npy: an array of shape \(100000, 200000, 2\) float32 \(160 GB decoded\); reading it"):
        check_fits(huge)
    with pytest.raises(ImageError, match=r"huge\.npy: .* needs about 320 GB"):
        read_image(huge)
    (tmp_path / "h.json").write_text(json.dumps(POINT))
    run = _cli("warp", str(huge), "-H", str(tmp_path / "h.json"), "-o", str(tmp_path / "out.png"), memory=ULIMIT)
    _one_line_refusal(run, str(huge), "(100000, 200000, 2) float32")
    # and as the map a warp applies (--apply-map), where it said "not enough memory" without naming the file
    write_image(tmp_path / "in.png", np.zeros((8, 16, 3), np.uint8))
    run = _cli("warp", str(tmp_path / "in.png"), "--apply-map", str(huge), "-o", str(tmp_path / "out.png"), memory=ULIMIT)
    _one_line_refusal(run, str(huge), "(100000, 200000, 2) float32")


def test_a_npy_file_shorter_than_its_header_says_is_refused_as_truncated(tmp_path: Path) -> None:
    short = _npy_header_only(tmp_path / "short.npy", (64, 128, 3), "|u1")
    with pytest.raises(ImageError, match=r"short\.npy: the file looks truncated: its header declares an array of shape \(64, 128, 3\)"):
        read_image(short)


def test_the_headers_say_what_read_image_returns(tmp_path: Path) -> None:
    pil = pytest.importorskip("PIL.Image")
    made = {
        "rgb.png": lambda p: write_image(p, np.zeros((4, 8, 3), np.uint8)),
        "gray16.png": lambda p: write_image(p, np.zeros((4, 8), np.uint16)),
        "rgba.png": lambda p: write_image(p, np.zeros((4, 8, 4), np.uint8)),
        "palette_transparent.png": lambda p: pil.new("P", (8, 4)).save(p, transparency=0),
        "gray_alpha.png": lambda p: pil.new("LA", (8, 4)).save(p),
        "rgb.jpg": lambda p: write_image(p, np.zeros((8, 16, 3), np.uint8)),
        "gray.jpg": lambda p: write_image(p, np.zeros((8, 16), np.uint8)),
        "progressive.jpg": lambda p: pil.new("RGB", (16, 8)).save(p, progressive=True),
        "float.tif": lambda p: write_image(p, np.zeros((4, 8, 3), np.float32)),
        "double.tif": lambda p: write_image(p, np.zeros((4, 8), np.float64)),
        "rgba16.tif": lambda p: write_image(p, np.zeros((4, 8, 4), np.uint16)),
        "lossy.webp": lambda p: write_image(p, np.zeros((4, 8, 3), np.uint8)),
        "alpha.webp": lambda p: pil.new("RGBA", (8, 4), (1, 2, 3, 4)).save(p, lossless=True),
        "rgb.bmp": lambda p: write_image(p, np.zeros((4, 8, 3), np.uint8)),
        "map.npy": lambda p: np.save(p, np.zeros((4, 8, 2), np.float32)),
        "swapped.npy": lambda p: np.save(p, np.zeros((4, 8), ">u2")),
    }
    for name, make in made.items():
        make(tmp_path / name)
        header, image = image_header(tmp_path / name), read_image(tmp_path / name)
        assert header is not None, name
        assert (header.shape, header.dtype) == (image.shape, image.dtype), name
        assert header.nbytes == image.nbytes == decode_bytes(tmp_path / name), name
    (tmp_path / "text.ppm").write_bytes(b"P6\n8 4\n255\n" + bytes(96))
    assert image_header(tmp_path / "text.ppm") is None  # a format whose header is not read: decoded as before
    with pytest.raises(ImageError, match="cannot be told before decoding"):
        decode_bytes(tmp_path / "text.ppm")


def test_the_estimate_counts_reading_and_warping(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "in.png"
    write_image(path, np.zeros((512, 1024, 3), np.uint8))
    size, pixels = path.stat().st_size, 512 * 1024 * 3
    assert memory_needed(path) == size + 2 * pixels
    per_pixel = images.WARP_BYTES_PER_PIXEL + 3
    assert memory_needed(path, warp=True) == images.WARP_INPUT_COPIES * pixels + 1024 * 512 * per_pixel
    assert memory_needed(path, warp=True, width=256) == max(size + 2 * pixels, images.WARP_INPUT_COPIES * pixels + 256 * 128 * per_pixel)
    monkeypatch.setenv("OMNIWIDGET_MEMORY", "2M")
    assert images.available_memory() == 2 << 20
    with pytest.raises(ImageError, match=r"in\.png: a 1024 x 512 RGB uint8 image \(1.57 MB decoded\); reading it needs about 3\.1"):
        read_image(path)
    monkeypatch.setenv("OMNIWIDGET_MEMORY", "4M")
    assert read_image(path).shape == (512, 1024, 3)
    with pytest.raises(ImageError, match=r"reading it and a warp 1024 pixels wide needs about .*try a smaller width \(--width"):
        read_panorama(path, warp=True)
    monkeypatch.setenv("OMNIWIDGET_MEMORY", "lots")
    with pytest.raises(ImageError, match="OMNIWIDGET_MEMORY='lots': expected bytes"):
        images.available_memory()


def test_the_memory_available_follows_ulimit() -> None:
    probe = "from omniwidget.io.images import available_memory; print(available_memory())"
    free = int(subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True).stdout)
    limited = subprocess.run(
        ["bash", "-c", f'ulimit -v {ULIMIT // 1024} && exec "$@"', "bash", sys.executable, "-c", probe],
        capture_output=True,
        text=True,
        check=True,
    )
    assert 0 < int(limited.stdout) < min(free, ULIMIT)


def test_a_huge_jpeg_is_decoded_reduced_where_a_smaller_width_is_asked(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    y, x = np.mgrid[0:1024, 0:2048].astype(np.float32)
    waves = [np.cos(2 * np.pi * x / 256), np.sin(2 * np.pi * y / 200), np.cos(2 * np.pi * (x + y) / 300)]
    image = np.stack([127 + 100 * w for w in waves], axis=-1).astype(np.uint8)
    path = tmp_path / "big.jpg"
    write_image(path, image)
    whole = read_image(path)
    monkeypatch.setenv("OMNIWIDGET_MEMORY", "6M")  # reading it whole takes 12.6 MB and the file
    with pytest.raises(ImageError, match=r"big\.jpg: a 2048 x 1024 RGB uint8 image"):
        read_image(path)
    with pytest.raises(ImageError, match=r"big\.jpg"):
        read_image(path, width=1536)  # a half would be narrower than asked
    half = read_image(path, width=1024)
    assert half.shape == (512, 1024, 3) and half.dtype == np.uint8
    area = cv2.resize(whole, (1024, 512), interpolation=cv2.INTER_AREA).astype(float)
    assert np.abs(half - area).mean() < 1  # the same picture, smaller (measured 0.33 levels)
    assert read_image(path, width=256).shape == (128, 256, 3)  # read at the size asked: the most reduction
    monkeypatch.setenv("OMNIWIDGET_MEMORY", "1M")
    assert read_image(path, width=256).shape == (128, 256, 3)  # fits reduced (file 0.4 MB, 0.2 MB decoded)


# --- caps on handles, samples, mesh and weights ---------------------------------------------------


def _points(count: int) -> dict:
    """``count`` distinct point handles, each moved a degree."""
    return {
        "handles": [
            {"kind": "point", "position": [i % 360 - 179.5, (i // 360) % 170 - 84.5], "target": [i % 360 - 179, (i // 360) % 170 - 84]}
            for i in range(count)
        ]
    }


def test_10000_point_handles_are_refused_at_once_naming_the_limit(tmp_path: Path) -> None:
    image = tmp_path / "in.png"
    write_image(image, np.zeros((256, 512, 3), np.uint8))
    many = _write(tmp_path / "many.json", json.dumps(_points(10_000)))  # before: 73 s and 10 GB
    with pytest.raises(HandlesError, match=r"many\.json: handles: 10000 handles are more than the limit of 1000 \(MAX_HANDLES"):
        load_handles(many)
    run = _cli("warp", str(image), "-H", str(many), "-o", str(tmp_path / "out.png"), timeout=60, memory=ULIMIT)
    _one_line_refusal(run, str(many), "limit of 1000", "OMNIWIDGET_MAX_HANDLES=10000")
    cage = {"handles": [{"kind": "cage", "vertices": [[0.01 * i, 0.0] for i in range(1001)]}]}
    with pytest.raises(HandlesError, match=r"1001 handles \(a cage's vertices counted each\)"):
        Handles.from_dict(cage)


def test_the_handles_cap_is_raised_by_its_variable(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("OMNIWIDGET_MAX_HANDLES", "1200")
    assert len(Handles.from_dict(_points(1200))) == 1200
    with pytest.raises(HandlesError, match="more than the limit of 1200"):
        Handles.from_dict(_points(1201))
    monkeypatch.setenv("OMNIWIDGET_MAX_HANDLES", "many")
    with pytest.raises(OmniwidgetError, match="OMNIWIDGET_MAX_HANDLES='many': expected a positive whole number"):
        Handles.from_dict(_points(1))


def test_a_handles_file_too_large_is_refused_before_it_is_read(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from omniwidget.document import handles as document

    monkeypatch.setattr(document, "MAX_FILE_BYTES", 1000)
    big = _write(tmp_path / "big.json", json.dumps(_points(50)))
    with pytest.raises(HandlesError, match=r"big\.json: the handles file is 0 MB, more than the 0 MB read"):
        load_handles(big)


def test_samples_are_capped() -> None:
    doc = Handles.from_dict({"handles": [{"kind": "line", "start": [-30, 20], "end": [30, 25]}, POINT["handles"][0]]})
    with pytest.raises(ValueError, match=r"samples: 5000 per line and cage edge are more than the limit of 1000 \(MAX_SAMPLES"):
        warp(np.zeros((32, 64, 3), np.uint8), doc, samples=5000, warn=False)


def test_the_mesh_and_the_weights_are_capped_before_the_work(monkeypatch: pytest.MonkeyPatch) -> None:
    doc = Handles.from_dict(_points(40))
    image = np.zeros((32, 64, 3), np.uint8)
    monkeypatch.setenv("OMNIWIDGET_MAX_MESH_VERTICES", "100")
    with pytest.raises(HandlesError, match=r"handles: the handles make [\d,]+ samples, .* more than the limit of 100 \(MAX_MESH_VERTICES"):
        warp(image, doc, warn=False)
    monkeypatch.delenv("OMNIWIDGET_MAX_MESH_VERTICES")
    monkeypatch.setenv("OMNIWIDGET_MAX_WEIGHTS", "10000")
    with pytest.raises(
        HandlesError, match=r"mesh vertices x 41 controls = .* more than the limit of 0 million \(MAX_WEIGHTS.*OMNIWIDGET_MAX_WEIGHTS="
    ):
        warp(image, doc, warn=False)


@pytest.mark.slow  # about 25 s: the lines' crossings are found, then the cap refuses
def test_1000_crossing_lines_are_refused_by_the_weights_cap(tmp_path: Path) -> None:
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from bench.bench_limits import _document

    lines = _write(tmp_path / "lines.json", json.dumps(_document("line", 1000)))  # before: 56 s and 2.6 GB, or more
    image = tmp_path / "in.png"
    write_image(image, np.zeros((256, 512, 3), np.uint8))
    run = _cli("warp", str(image), "-H", str(lines), "-o", str(tmp_path / "out.png"), timeout=120, memory=ULIMIT)
    _one_line_refusal(run, "more than the limit of 30 million (MAX_WEIGHTS", "OMNIWIDGET_MAX_WEIGHTS=")


def test_a_fifo_is_refused_as_a_video_too(tmp_path: Path) -> None:
    from omniwidget.errors import VideoError
    from omniwidget.io.spherical import check_mp4_structure, read_spherical

    fifo = tmp_path / "video.mp4"
    os.mkfifo(fifo)
    with pytest.raises(VideoError, match="video.mp4: cannot read the video: it is a FIFO"):
        read_spherical(fifo)
    with pytest.raises(VideoError, match="it is a FIFO"):
        check_mp4_structure(fifo)
