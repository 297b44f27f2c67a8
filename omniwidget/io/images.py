"""Reading and writing panoramas and files: clear errors, inputs never touched, outputs whole or absent.

:func:`read_image` checks a file's structure before OpenCV decodes it, so a file cut short
(an interrupted download or copy) or with a damaged PNG chunk is refused by name instead of
decoding to a partial image; it turns the pixels as the EXIF orientation says, as viewers
show them. :func:`write_image` writes through a temporary file and a rename.
:func:`to_equirectangular` makes a non-2:1 image 2:1, on request only.

Limits: damage inside a JPEG's compressed data that leaves its markers in place cannot be
told from real data (the format has no checksum); OpenCV decodes such a file as it can.
"""

from __future__ import annotations

import io
import math
import os
import struct
import zlib
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, BinaryIO, Literal

import numpy as np
from numpy.lib import format as npy
from numpy.typing import NDArray

from .._checks import SUPPORTED_DTYPES, check_image, check_panorama, require_regular_file
from .._files import AtomicOutput, atomic_output, atomic_write_bytes
from .._lazy import lazy
from ..errors import ImageError, NotRegularFileError
from . import large, metadata
from .large import REDUCE_ROWS, ReadPlan, plan_read, read_reduced

if TYPE_CHECKING:
    import resource

    import cv2
    import tifffile
else:
    cv2 = lazy("cv2")
    resource = lazy("resource")
    tifffile = lazy("tifffile")

__all__ = [
    "FITS",
    "MEMORY_VARIABLE",
    "STRIP_SUFFIXES",
    "SUPPORTED_DTYPES",
    "WARP_BYTES_PER_PIXEL",
    "WARP_INPUT_COPIES",
    "ImageHeader",
    "atomic_write_bytes",
    "available_memory",
    "check_fits",
    "check_format",
    "check_panorama",
    "check_writable",
    "decode_bytes",
    "encode_image",
    "image_header",
    "memory_needed",
    "place_gpano",
    "read_image",
    "read_panorama",
    "to_equirectangular",
    "write_bytes",
    "write_image",
    "write_image_strips",
]

Fit = Literal["pad", "stretch"]
#: The ways :func:`to_equirectangular` makes an image 2:1.
FITS: tuple[Fit, ...] = ("pad", "stretch")

#: Which file suffixes can hold which sample type (``.npy`` holds any array).
_DEPTH_SUFFIXES = {
    np.uint8: (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".webp", ".bmp"),
    np.uint16: (".png", ".tif", ".tiff"),
    np.float32: (".tif", ".tiff"),
    np.float64: (".tif", ".tiff"),
}
_NO_ALPHA = (".jpg", ".jpeg")
#: The widest image a format holds.
_MAX_SIDE = {".jpg": 65535, ".jpeg": 65535, ".webp": 16383}


# --- checks ------------------------------------------------------------------------------


def to_equirectangular(image: NDArray, fit: Fit | None, name: str = "image", *, gpano: metadata.GPano | None = None) -> NDArray:
    """Make an image twice as wide as high: where its Photo Sphere XMP places it, else by padding rows or by resizing.

    Parameters
    ----------
    image : ndarray, shape (H, W) or (H, W, C)
        1 to 4 channels; uint8, uint16, float32 or float64.
    fit : {"pad", "stretch"} or None
        How to make it 2:1 when ``gpano`` does not place it (None: refuse an image that is not 2:1).
        ``"pad"``: for an image wider than 2:1 with an even width ``W``, taken to cover the
        full 360° of longitude and a band of latitudes centred on the horizon (a panorama
        cropped at the top and bottom): ``W / 2 - H`` rows of zeros are added, half above
        and half below (the odd row below). Zeros are black, and transparent in an alpha
        channel. An image taller than 2:1 is refused: adding columns would claim longitudes
        it does not show.

        ``"stretch"``: the image is resized to ``W' x W' / 2`` with ``W'`` its width rounded
        up to even (OpenCV, area averaging where rows shrink, bilinear where they grow), so
        that it spans the whole sphere whatever it showed.
    name : str
        What to call the image in messages (a file name, say).
    gpano : GPano, optional
        The file's Photo Sphere XMP (:func:`omniwidget.io.metadata.read_metadata`): an image
        it says is a part of a sphere (``CroppedArea*``, ``FullPano*``) is put in its place
        (:func:`place_gpano`), whatever ``fit`` says.

    Returns
    -------
    ndarray, shape (H', 2 H') or (H', 2 H', C)
        The same dtype and channels; ``image`` itself if it already is 2:1.

    Raises
    ------
    ImageError
        If the image is not an image (see :func:`check_panorama`), or cannot be padded.
    ValueError
        If ``fit`` is not one of :data:`FITS`.

    Examples
    --------
    >>> import numpy as np
    >>> band = np.ones((300, 1000, 3), np.uint8)  # 360° wide, 108° high
    >>> full = to_equirectangular(band, "pad")
    >>> full.shape, int(full[:100].max()), int(full[100:400].min()), int(full[400:].max())
    ((500, 1000, 3), 0, 1, 0)
    >>> to_equirectangular(np.ones((3, 5), np.float32), "stretch").shape
    (3, 6)
    """
    if fit is not None and fit not in FITS:
        raise ValueError(f'fit must be "pad" or "stretch", got {fit!r}')
    h, w = check_image(image, name)
    if gpano is not None and not gpano.is_full and gpano.placement(w, h) is not None:
        return place_gpano(image, gpano, name)
    if w == 2 * h:
        return image
    if fit is None:
        raise ImageError(f'{name}: {w} x {h} is not 2:1 and says nothing of where it lies on the sphere: make it 2:1 with fit="pad" or "stretch"')
    if fit == "pad":
        if w < 2 * h:
            raise ImageError(
                f"{name}: {w} x {h} is taller than 2:1, so it cannot be padded with rows; padding columns would claim "
                'longitudes it does not show: resize it with fit="stretch", or crop it'
            )
        if w % 2:
            raise ImageError(f'{name}: {w} x {h} has an odd width, so no number of added rows makes it 2:1: resize it with fit="stretch"')
        extra = w // 2 - h
        above = extra // 2
        widths = [(above, extra - above), (0, 0)] + [(0, 0)] * (image.ndim - 2)
        return np.pad(image, widths)

    new_w = w + w % 2
    new_h = new_w // 2
    interpolation = cv2.INTER_AREA if new_h < h else cv2.INTER_LINEAR
    out = cv2.resize(image, (new_w, new_h), interpolation=interpolation)
    return out.reshape(new_h, new_w, *image.shape[2:])  # OpenCV drops a single channel axis


def place_gpano(image: NDArray, gpano: metadata.GPano, name: str = "image") -> NDArray:
    """Put a part of a panorama where its Photo Sphere XMP says on the full sphere, zeros elsewhere.

    Parameters
    ----------
    image : ndarray, shape (h, w) or (h, w, C)
        The part, as the file shows it (a phone's 360 x 120° sweep, say).
    gpano : GPano
        Its ``FullPanoWidthPixels/HeightPixels`` and ``CroppedAreaLeftPixels/TopPixels``,
        scaled to ``image``'s size when the file was resized after it was tagged
        (:meth:`~omniwidget.io.metadata.GPano.placement`).
    name : str
        What to call the image in messages.

    Returns
    -------
    ndarray, shape (H, 2 H) or (H, 2 H, C)
        The full sphere: ``image`` at rows ``top..top+h`` and columns ``left..left+w``
        (wrapping round the seam), zeros elsewhere: black, and transparent in an alpha
        channel, as :func:`to_equirectangular`'s ``"pad"``.

    Raises
    ------
    ImageError
        If the XMP does not place the image on a 2:1 sphere in whole pixels.
    """
    h, w = check_image(image, name)
    where = gpano.placement(w, h)
    if where is None:
        raise ImageError(
            f"{name}: its Photo Sphere XMP (full {gpano.full_width} x {gpano.full_height}, cropped {gpano.cropped_width} x "
            f"{gpano.cropped_height} at {gpano.left}, {gpano.top}) does not place a {w} x {h} image on a 2:1 sphere"
        )
    full_w, full_h, left, top = where
    out = np.zeros((full_h, full_w, *image.shape[2:]), image.dtype)
    first = min(w, full_w - left)
    out[top : top + h, left : left + first] = image[:, :first]
    out[top : top + h, : w - first] = image[:, first:]  # past the seam, from the left edge
    return out


# --- reading -----------------------------------------------------------------------------

_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_NPY_MAGIC = b"\x93NUMPY"


class _FileBytes:
    """A file's bytes read on demand: ``len`` and slices, as :func:`_tiff_ifd0` reads a blob, without reading it all."""

    def __init__(self, fh: BinaryIO, size: int) -> None:
        self.fh, self.size = fh, size

    def __len__(self) -> int:
        return self.size

    def __getitem__(self, where: slice) -> bytes:
        start, stop, _ = where.indices(self.size)
        self.fh.seek(start)
        return self.fh.read(max(0, stop - start))


def _tiff_ifd0(blob: bytes | memoryview | _FileBytes) -> dict[int, tuple[int, ...]] | None:
    """The numeric entries of a TIFF structure's first directory (a TIFF file or an EXIF block).

    Returns ``{tag: values}`` for entries of type BYTE, SHORT or LONG, or None if ``blob`` does
    not start like a TIFF structure; a directory running past the end is read as far as it goes.
    """
    if len(blob) < 8 or bytes(blob[:2]) not in (b"II", b"MM"):
        return None
    e = "<" if bytes(blob[:2]) == b"II" else ">"
    magic, offset = struct.unpack(e + "HI", blob[2:8])
    if magic != 42 or offset + 2 > len(blob):
        return None
    (count,) = struct.unpack(e + "H", blob[offset : offset + 2])
    sizes = {1: "B", 3: "H", 4: "I"}
    entries: dict[int, tuple[int, ...]] = {}
    for k in range(count):
        at = offset + 2 + 12 * k
        if at + 12 > len(blob):
            break
        tag, kind, n = struct.unpack(e + "HHI", blob[at : at + 8])
        if kind not in sizes:
            continue
        size = struct.calcsize(sizes[kind]) * n
        start = at + 8 if size <= 4 else struct.unpack(e + "I", blob[at + 8 : at + 12])[0]
        if start + size > len(blob):
            entries[tag] = ()  # its values lie past the end
            continue
        entries[tag] = struct.unpack(f"{e}{n}{sizes[kind]}", blob[start : start + size])
    return entries


def _oriented(image: NDArray, orientation: int) -> NDArray:
    """Pixels as stored turned into pixels as shown, for an EXIF orientation 1 to 8."""
    turn = {
        1: lambda a: a,
        2: lambda a: a[:, ::-1],  # mirrored left to right
        3: lambda a: a[::-1, ::-1],  # turned half a turn
        4: lambda a: a[::-1],  # mirrored top to bottom
        5: lambda a: a.swapaxes(0, 1),  # mirrored along the main diagonal
        6: lambda a: a.swapaxes(0, 1)[:, ::-1],  # turned a quarter clockwise
        7: lambda a: a[::-1, ::-1].swapaxes(0, 1),  # mirrored along the other diagonal
        8: lambda a: a.swapaxes(0, 1)[::-1],  # turned a quarter anticlockwise
    }[orientation]
    return image if orientation == 1 else np.ascontiguousarray(turn(image))


def _jpeg_structure(data: bytes) -> tuple[str | None, bytes | None, tuple[int, int] | None]:
    """Walk a JPEG's markers to its end-of-image marker.

    Returns ``(problem, exif, size)``: what is wrong (None if nothing), the EXIF block of the
    first APP1 Exif segment, and ``(width, height)`` from the frame header.
    """
    n = len(data)
    exif: bytes | None = None
    size: tuple[int, int] | None = None
    markers: NDArray[np.intp] | None = None  # positions of 0xFF followed by a marker code (not stuffing, RSTn or fill)

    def next_marker(at: int) -> int:
        nonlocal markers
        if markers is None:
            buf = np.frombuffer(data, np.uint8)
            ff = np.flatnonzero(buf[:-1] == 0xFF)
            code = buf[ff + 1]
            markers = ff[(code != 0x00) & (code != 0xFF) & ((code < 0xD0) | (code > 0xD7))]
        k = int(np.searchsorted(markers, at))
        return int(markers[k]) if k < len(markers) else -1

    i = 2
    while True:
        if i + 2 > n:
            return "truncated", exif, size
        if data[i] != 0xFF or data[i + 1] in (0x00, 0xFF):
            i = next_marker(i)  # stray bytes, or fill before a marker: skip to the marker, as decoders do
            if i < 0:
                return "truncated", exif, size
            continue
        code = data[i + 1]
        if code == 0xD9:
            return None, exif, size
        if code == 0x01 or 0xD0 <= code <= 0xD8:
            i += 2
            continue
        if i + 4 > n:
            return "truncated", exif, size
        length = int.from_bytes(data[i + 2 : i + 4], "big")
        end = i + 2 + length
        if length < 2 or end > n:
            return "truncated" if end > n else "damaged", exif, size
        if code == 0xE1 and exif is None and data[i + 4 : i + 10] == b"Exif\x00\x00":
            exif = data[i + 10 : end]
        elif 0xC0 <= code <= 0xCF and code not in (0xC4, 0xC8, 0xCC) and size is None and length >= 8:
            height, width = struct.unpack(">HH", data[i + 5 : i + 9])
            size = (width, height)
        if code == 0xDA:  # compressed data follows the scan header, up to the next marker
            i = next_marker(end)
            if i < 0:
                return "truncated", exif, size
        else:
            i = end


def _png_structure(data: bytes) -> tuple[str | None, bytes | None, tuple[int, int] | None]:
    """Walk a PNG's chunks, checking each checksum, to IEND: ``(problem, exif, (width, height))``."""
    n, i = len(data), len(_PNG_SIGNATURE)
    view = memoryview(data)
    exif: bytes | None = None
    size: tuple[int, int] | None = None
    while True:
        if i + 8 > n:
            return "the PNG data ends before its IEND chunk", exif, size
        length = int.from_bytes(data[i : i + 4], "big")
        kind = bytes(data[i + 4 : i + 8])
        end = i + 12 + length
        if end > n:
            return "the PNG data ends before its IEND chunk", exif, size
        crc = int.from_bytes(data[end - 4 : end], "big")
        if zlib.crc32(view[i + 4 : end - 4]) != crc:
            name = kind.decode("latin-1") if kind.isalpha() else repr(kind)
            return f"damaged: the PNG chunk {name} at byte {i} fails its checksum", exif, size
        if kind == b"IHDR" and length >= 8:
            size = struct.unpack(">II", data[i + 8 : i + 16])
        elif kind == b"eXIf":
            exif = data[i + 8 : end - 4]
        elif kind == b"IEND":
            return None, exif, size
        i = end


def _webp_structure(data: bytes) -> tuple[str | None, bytes | None]:
    """A WebP's RIFF size against the file's, and its EXIF chunk: ``(problem, exif)``."""
    declared = 8 + int.from_bytes(data[4:8], "little")
    if declared > len(data):
        return f"the WebP data is {len(data)} bytes, its header says {declared}", None
    i, exif = 12, None
    while i + 8 <= declared:
        kind, length = data[i : i + 4], int.from_bytes(data[i + 4 : i + 8], "little")
        if kind == b"EXIF":
            exif = data[i + 8 : i + 8 + length]
        i += 8 + length + (length & 1)
    return None, exif


def _tiff_structure(data: bytes) -> str | None:
    """Whether a TIFF's first directory and image lie inside the file: a problem, or None."""
    e = "<" if data[:2] == b"II" else ">"
    offset = struct.unpack(e + "I", data[4:8])[0] if len(data) >= 8 else len(data)
    count = struct.unpack(e + "H", data[offset : offset + 2])[0] if offset + 2 <= len(data) else None
    if count is None or offset + 2 + 12 * count > len(data):
        return "the TIFF directory lies past the end of the file"
    entries = _tiff_ifd0(data) or {}
    offsets = entries.get(273, entries.get(324))  # strips, or tiles
    counts = entries.get(279, entries.get(325))
    if offsets == () or counts == ():
        return "the TIFF directory's tables lie past the end of the file"
    if offsets and counts:
        end = max(o + c for o, c in zip(offsets, counts, strict=False))
        if end > len(data):
            return f"the TIFF image data runs to byte {end}, the file has {len(data)}"
    return None


def _format(data: bytes) -> str | None:
    """The format a file's first bytes announce, or None."""
    if data[:3] == b"\xff\xd8\xff":
        return "JPEG"
    if data[:8] == _PNG_SIGNATURE:
        return "PNG"
    if data[:4] in (b"II*\x00", b"MM\x00*"):
        return "TIFF"
    if data[:4] == b"RIFF" and data[8:12] == b"WEBP":
        return "WebP"
    if data[:2] == b"BM" and len(data) >= 26:
        return "BMP"
    if data[:6] == _NPY_MAGIC:
        return "npy"
    return None


def _looks_like_text(head: bytes) -> bool:
    """Whether the first bytes of a file read as UTF-8 text."""
    try:
        text = head.decode("utf-8")
    except UnicodeDecodeError as exc:
        if exc.start < len(head) - 3:  # not just a character cut at the end
            return False
        text = head[: exc.start].decode("utf-8")
    return all(c.isprintable() or c in "\r\n\t" for c in text)


def _read_npy(path: Path, data: bytes, header: ImageHeader | None) -> NDArray:
    if header is not None and header.offset + header.nbytes > len(data):  # before np.load allocates what the header says
        raise ImageError(
            f"{path}: the file looks truncated: its header declares {header.describe()}, "
            f"it holds {len(data) - header.offset} bytes after the header; was it copied or downloaded whole?"
        )
    try:
        array = np.load(io.BytesIO(data), allow_pickle=False)
    except (OSError, ValueError) as exc:
        raise ImageError(f"{path}: a damaged or unreadable .npy file ({exc})") from None
    if not isinstance(array, np.ndarray) or array.dtype.kind not in "uif":
        raise ImageError(f"{path}: the .npy file does not hold an array of numbers")
    return array.astype(array.dtype.newbyteorder("="), copy=False)


# --- memory: what reading a file, and warping it, will take ------------------------------------

#: Bytes a warp holds per output pixel besides the output image itself, at the command line's
#: peak: the resampling's float32 coordinates (8), then the closing line's check of the lines
#: through the placed map (float64 [lon, lat], 16, and its intermediates). Checked against the
#: measured peak by bench/bench_limits.py (its figures in bench/RESULTS.md).
WARP_BYTES_PER_PIXEL = 40
#: Bytes a warp in strips holds per pixel of its strip (the interpolated unit vectors and their four corners, float32).
STRIP_BYTES_PER_PIXEL = 96
#: Copies of the input image a warp holds at its peak: the image, and the padded copy being made
#: (:func:`omniwidget.raster.warping.pad_panorama` concatenates rows, then columns).
WARP_INPUT_COPIES = 3
#: The environment variable that says how much memory :func:`check_fits` may count on (bytes,
#: or a number with K, M, G or T: ``8G``), instead of what the system says is available.
MEMORY_VARIABLE = "OMNIWIDGET_MEMORY"
_UNITS = {"": 1, "K": 1 << 10, "M": 1 << 20, "G": 1 << 30, "T": 1 << 40}
#: Chunks of a PNG looked at for a tRNS chunk before its image data (more: taken to have one).
_PNG_CHUNKS = 1024
#: JPEG segments looked at for the frame header (more: the size is unknown).
_JPEG_SEGMENTS = 4096
#: The reductions libjpeg can decode a JPEG at (its DCT scaling), in the order tried.
_REDUCTIONS = {
    2: ("IMREAD_REDUCED_COLOR_2", "IMREAD_REDUCED_GRAYSCALE_2"),
    4: ("IMREAD_REDUCED_COLOR_4", "IMREAD_REDUCED_GRAYSCALE_4"),
    8: ("IMREAD_REDUCED_COLOR_8", "IMREAD_REDUCED_GRAYSCALE_8"),
}


@dataclass(frozen=True)
class ImageHeader:
    """What an image file's header says of the array :func:`read_image` returns, read without decoding.

    Attributes
    ----------
    format : str
        ``"PNG"``, ``"JPEG"``, ``"TIFF"``, ``"WebP"``, ``"BMP"`` or ``"npy"``.
    shape : tuple of int
        ``(H, W)`` or ``(H, W, C)`` as stored, before the EXIF orientation turns it; for a
        ``.npy`` file the array's shape, whatever it is.
    dtype : numpy.dtype
        The sample type, as :func:`read_image` returns it.
    file_bytes : int
        The file's size.
    offset : int
        Where the pixels start in a ``.npy`` file (after its header); 0 for the others.
    """

    format: str
    shape: tuple[int, ...]
    dtype: np.dtype
    file_bytes: int
    offset: int = 0

    @property
    def width(self) -> int:
        """``W``, pixels."""
        return self.shape[1] if len(self.shape) > 1 else 1

    @property
    def height(self) -> int:
        """``H``, pixels."""
        return self.shape[0] if self.shape else 1

    @property
    def bytes_per_pixel(self) -> int:
        """Channels times the sample's bytes: 3 for RGB uint8, 16 for RGBA float32, 8 for a float32 map."""
        return math.prod(self.shape[2:]) * self.dtype.itemsize

    @property
    def nbytes(self) -> int:
        """Bytes of the decoded array: ``H * W * bytes_per_pixel``."""
        return math.prod(self.shape) * self.dtype.itemsize

    def describe(self) -> str:
        """E.g. ``"a 46000 x 23000 RGB uint8 image (3.17 GB decoded)"``, or ``"an array of shape (H, W, 2) float32 (...)"``."""
        names = {1: "gray", 2: "gray+alpha", 3: "RGB", 4: "RGBA"}
        channels = math.prod(self.shape[2:])
        if self.format == "npy":
            kind = f"an array of shape {self.shape} {self.dtype}"
        else:
            kind = f"a {self.width} x {self.height} {names.get(channels, f'{channels}-channel')} {self.dtype} image"
        return f"{kind} ({_gigabytes(self.nbytes)} decoded)"


def _gigabytes(n: float) -> str:
    return f"{n / 1e9:.3g} GB" if n >= 1e8 else f"{n / 1e6:.3g} MB"


def _jpeg_header(blob: _FileBytes) -> tuple[int, ...] | None:
    """``(H, W)`` or ``(H, W, 3)`` and the sample bits from a JPEG's frame header, walking its segments."""
    i = 2
    for _ in range(_JPEG_SEGMENTS):
        seg = blob[i : i + 10]
        if len(seg) < 4 or seg[0] != 0xFF:
            return None
        code = seg[1]
        if code == 0xFF:  # fill byte
            i += 1
        elif code == 0x01 or 0xD0 <= code <= 0xD8:
            i += 2
        elif code in (0xD9, 0xDA):  # the end, or a scan, before any frame header
            return None
        elif 0xC0 <= code <= 0xCF and code not in (0xC4, 0xC8, 0xCC):
            if len(seg) < 10:
                return None
            height, width = struct.unpack(">HH", seg[5:9])
            shape = (height, width) if seg[9] == 1 else (height, width, 3)  # OpenCV decodes CMYK as RGB too
            return (*shape, seg[4]) if height and width else None  # height 0: given by a DNL marker after the scan
        else:
            i += 2 + int.from_bytes(seg[2:4], "big")
    return None


def _png_header(blob: _FileBytes) -> tuple[tuple[int, ...], np.dtype] | None:
    head = blob[8:33]
    if len(head) < 25 or head[4:8] != b"IHDR":
        return None
    width, height, depth, colour = struct.unpack(">IIBB", head[8:18])
    transparent, i = False, 8
    for _ in range(_PNG_CHUNKS):  # a tRNS chunk (before the image data) adds an alpha channel
        chunk = blob[i : i + 8]
        if len(chunk) < 8 or chunk[4:8] in (b"IDAT", b"IEND"):
            break
        if chunk[4:8] == b"tRNS":
            transparent = True
            break
        i += 12 + int.from_bytes(chunk[:4], "big")
    else:
        transparent = True
    channels = {0: 1, 2: 4 if transparent else 3, 3: 4 if transparent else 3, 4: 4, 6: 4}.get(colour)
    if channels is None:
        return None
    shape = (height, width) if channels == 1 else (height, width, channels)
    return shape, np.dtype(np.uint16 if depth == 16 else np.uint8)


def _tiff_header(blob: _FileBytes) -> tuple[tuple[int, ...], np.dtype] | None:
    entries = _tiff_ifd0(blob)
    if not entries or not entries.get(256) or not entries.get(257):
        return None
    width, height = entries[256][0], entries[257][0]
    bits = (entries.get(258) or (1,))[0]
    samples = (entries.get(277) or (1,))[0]
    kind = (entries.get(339) or (1,))[0]
    size = 8 if bits > 32 else 4 if bits > 16 else 2 if bits > 8 else 1
    dtype = np.dtype(f"f{max(size, 4)}" if kind == 3 else f"i{size}" if kind == 2 else f"u{size}")
    palette = (entries.get(262) or (1,))[0] == 3
    channels = 3 if palette else 1 if samples <= 2 else min(samples, 4)  # OpenCV reads gray+alpha as gray
    return ((height, width) if channels == 1 else (height, width, channels)), dtype


def _webp_header(blob: _FileBytes) -> tuple[int, ...] | None:
    head = blob[:30]
    if len(head) < 30:
        return None
    if head[12:16] == b"VP8 " and head[23:26] == b"\x9d\x01\x2a":
        width, height = (int.from_bytes(head[26:28], "little") & 0x3FFF), (int.from_bytes(head[28:30], "little") & 0x3FFF)
        alpha = False
    elif head[12:16] == b"VP8L" and head[20] == 0x2F:
        bits = int.from_bytes(head[21:25], "little")
        width, height, alpha = (bits & 0x3FFF) + 1, ((bits >> 14) & 0x3FFF) + 1, bool(bits >> 28 & 1)
    elif head[12:16] == b"VP8X":
        alpha = bool(head[20] & 0x10)
        width, height = int.from_bytes(head[24:27], "little") + 1, int.from_bytes(head[27:30], "little") + 1
    else:
        return None
    return (height, width, 4 if alpha else 3)


def _bmp_header(blob: _FileBytes) -> tuple[int, ...] | None:
    head = blob[:30]
    if len(head) < 26:
        return None
    if int.from_bytes(head[14:18], "little") == 12:  # OS/2's BITMAPCOREHEADER
        width, height, bits = struct.unpack("<hhxxH", head[18:26])
    elif len(head) >= 30:
        width, height, bits = struct.unpack("<iixxH", head[18:30])
    else:
        return None
    return (abs(height), abs(width), 4 if bits == 32 else 3)  # an upper bound: a gray palette decodes to one channel


def _npy_header(fh: BinaryIO) -> tuple[tuple[int, ...], np.dtype, int] | None:
    fh.seek(0)
    try:
        version = npy.read_magic(fh)
        if version == (1, 0):
            shape, _, dtype = npy.read_array_header_1_0(fh)
        elif version == (2, 0):
            shape, _, dtype = npy.read_array_header_2_0(fh)
        else:
            return None
    except (ValueError, OSError, SyntaxError):
        return None  # np.load says what is wrong
    return tuple(int(n) for n in shape), np.dtype(dtype).newbyteorder("="), fh.tell()


def image_header(path: str | os.PathLike[str]) -> ImageHeader | None:
    """What :func:`read_image` would return for ``path`` (shape, sample type, bytes), from the file's header only.

    Reads a few bytes at the start of the file (and, for TIFF, its first directory; for
    JPEG, the segment headers up to the frame header; for PNG, the chunk headers up to the
    image data); never the pixels.

    Parameters
    ----------
    path : path-like

    Returns
    -------
    ImageHeader or None
        None when the format is none of PNG, JPEG, TIFF, WebP, BMP and ``.npy`` or the header
        does not say (the file is then decoded as it is, within OpenCV's own limit).
        ``shape`` and ``dtype`` are exactly what :func:`read_image` returns (before the EXIF
        orientation) for PNG, JPEG, WebP, ``.npy`` and common TIFFs; an upper bound for BMP
        (32-bit pixels count four channels, a gray palette three).

    Raises
    ------
    ImageError
        If the file cannot be opened, or is a FIFO or a device.
    """
    path = Path(path)
    try:
        require_regular_file(path, "image")
        with path.open("rb") as fh:
            size = os.fstat(fh.fileno()).st_size
            blob = _FileBytes(fh, size)
            kind = _format(blob[:64])
            found: tuple[tuple[int, ...], np.dtype] | None = None
            offset = 0
            if kind == "npy" and (npy := _npy_header(fh)) is not None:
                found, offset = npy[:2], npy[2]
            elif kind == "JPEG" and (shape := _jpeg_header(blob)) is not None:
                found = shape[:-1], np.dtype(np.uint16 if shape[-1] > 8 else np.uint8)
            elif kind == "PNG":
                found = _png_header(blob)
            elif kind == "TIFF":
                found = _tiff_header(blob)
            elif kind in ("WebP", "BMP") and (shape := (_webp_header if kind == "WebP" else _bmp_header)(blob)) is not None:
                found = shape, np.dtype(np.uint8)
    except NotRegularFileError as exc:
        raise ImageError(str(exc)) from None
    except OSError as exc:
        raise ImageError(f"{path}: cannot read the image ({exc.strerror or exc})") from None
    if kind is None or found is None:
        return None
    return ImageHeader(kind, found[0], found[1], size, offset)


def _known_header(path: str | os.PathLike[str]) -> ImageHeader:
    """:func:`image_header`, or an ImageError when the format's header does not say the size."""
    header = image_header(path)
    if header is None:
        raise ImageError(f"{path}: the size of the image cannot be told before decoding it (PNG, JPEG, TIFF, WebP, BMP and .npy can)")
    return header


def decode_bytes(path: str | os.PathLike[str]) -> int:
    """Bytes of the array :func:`read_image` returns for ``path``, told from the file's header before decoding.

    ``H * W * C * itemsize``: a pixel is ``C`` channels (1 gray, 3 RGB, 4 RGBA: a PNG with
    transparency and an RGBA WebP or TIFF have 4) of 1 byte (uint8: JPEG, PNG, WebP, BMP),
    2 (uint16: 16-bit PNG and TIFF), 4 (float32 TIFF) or 8 (float64 TIFF); a ``.npy`` file
    holds ``prod(shape) * itemsize``. A 46,000 x 23,000 RGB PNG is 3.17 GB however small its
    file. Reading takes more at its peak (:func:`memory_needed`).

    Parameters
    ----------
    path : path-like

    Returns
    -------
    int

    Raises
    ------
    ImageError
        If the file cannot be read, or its format's header does not say (:func:`image_header`).
    """
    return _known_header(path).nbytes


def _warp_output(header: ImageHeader, width: int | None) -> tuple[int, int]:
    """The output width of a warp to ``width`` (default: the panorama's, its longer side) and its pixels."""
    w = width if width is not None else max(header.width, header.height)
    return w, w * max(w // 2, 1)


def _plan(header: ImageHeader, *, width: int | None, reduce: bool = True, streamed: bool = False) -> ReadPlan:
    """How the file is read (:func:`omniwidget.io.large.plan_read`); left on disk only when ``streamed`` (a warp made in strips)."""
    if not reduce:
        return ReadPlan("whole", 1)
    return plan_read(header, width, strips=streamed)


def _needed(header: ImageHeader, *, warp: bool, width: int | None, plan: ReadPlan, streamed: bool = False) -> int:
    """Peak bytes of reading the image as ``plan`` says and, with ``warp``, of warping it (in strips when ``streamed`` or wide)."""
    sizes = large.WARP_SIZES  # looked up at each call, as the strips' own sizes are
    image = header.nbytes // (plan.reduce * plan.reduce)
    if plan.how == "disk":  # a patch at a time from disk; the method runs on a copy reduced for the map grid
        copy = _plan(header, width=sizes.map_width)
        reading = _needed(header, warp=False, width=sizes.map_width, plan=copy)
        image, source = header.nbytes // (copy.reduce * copy.reduce), sizes.patch_pixels * header.bytes_per_pixel
    else:
        if plan.how == "reduced":  # decoded in strips: the output and a band of rows at full size
            reading = image + REDUCE_ROWS * plan.reduce * header.width * header.bytes_per_pixel * 2
        else:  # the file, the decoded pixels and their copy in RGB order (or turned)
            reading = header.file_bytes + 2 * image
        if not warp:
            return reading
        if max(header.width, header.height) // plan.reduce + 2 * sizes.pad < sizes.remap_limit:
            source = WARP_INPUT_COPIES * image
        else:  # resampled in tiles: no padded copy, one patch at a time
            source = image + sizes.patch_pixels * header.bytes_per_pixel
    w, pixels = _warp_output(header, width)
    if not streamed and w <= sizes.stream_width:
        return max(reading, source + pixels * (WARP_BYTES_PER_PIXEL + header.bytes_per_pixel))
    # made in strips: the warp on the map grid, its unit vectors (12 bytes, twice while
    # padded), and the strips in hand (their interpolation)
    grid = sizes.map_width * (sizes.map_width // 2)
    strip = (sizes.strips_ahead + 1) * sizes.strip_rows(w) * w * STRIP_BYTES_PER_PIXEL  # the strip written and those made ahead
    return max(reading, source + grid * (WARP_BYTES_PER_PIXEL + header.bytes_per_pixel + 24) + strip)


def memory_needed(path: str | os.PathLike[str], *, warp: bool = False, width: int | None = None, streamed: bool = False) -> int:
    """Peak bytes of reading an image file (and of warping it), estimated from its header.

    Reading holds the file's bytes, the decoded pixels and one copy of them (OpenCV's BGR
    turned into RGB, or the EXIF orientation applied): ``file + 2 * decode_bytes(path)``. A
    warp holds :data:`WARP_INPUT_COPIES` copies of the input (it, and its padded copy being
    made) and per output pixel :data:`WARP_BYTES_PER_PIXEL` bytes of working arrays besides
    the output pixel itself: ``3 * decode_bytes + W_out * W_out / 2 * (40 + bytes_per_pixel)``.
    The estimate is meant to lie above the command line's peak (the three copies of the
    input and the per-pixel arrays are not all held at once; bench/bench_limits.py measures
    it, its figures in bench/RESULTS.md); the Python process itself is not counted. A file is counted at the size it is decoded at for ``width``
    (:func:`omniwidget.io.large.plan_read`: a JPEG reduced by libjpeg, another file above
    :data:`~omniwidget.io.large.STREAM_BYTES` reduced in strips); a panorama resampled in
    tiles (32,767 px a side or more, :func:`~omniwidget.raster.warping.remap_panorama`)
    with one copy of the input and one patch.

    Parameters
    ----------
    path : path-like
    warp : bool
        Count a warp of the image too.
    width : int, optional
        The warp's output width; default: the panorama's own (its longer side).
    streamed : bool
        The warp is made in strips whatever its width
        (:func:`~omniwidget.raster.strips.warp_in_strips`; it always is above
        :data:`~omniwidget.raster.strips.STREAM_WIDTH`) and may leave a large panorama on
        disk (:func:`omniwidget.io.large.plan_read`): counted with one patch of it and a
        copy reduced for the map grid instead of the whole image.

    Returns
    -------
    int

    Raises
    ------
    ImageError
        As :func:`decode_bytes`.
    """
    header = _known_header(path)
    return _needed(header, warp=warp, width=width, plan=_plan(header, width=width, streamed=streamed), streamed=streamed)


def _meminfo(name: str) -> int | None:
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith(name + ":"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


def _cgroup_available() -> int | None:
    """What the process's cgroup (v2) still allows: ``memory.max`` less what is used, page cache counted as free."""
    try:
        with open("/proc/self/cgroup") as fh:
            own = next((line.split(":", 2)[2].strip() for line in fh if line.startswith("0::")), None)
        if own is None:
            return None
        folder = Path("/sys/fs/cgroup") / own.lstrip("/")
        limit = (folder / "memory.max").read_text().strip()
        if limit == "max":
            return None
        used = int((folder / "memory.current").read_text())
        stat = dict(line.split() for line in (folder / "memory.stat").read_text().splitlines() if line.count(" ") == 1)
        return int(limit) - used + int(stat.get("inactive_file", 0))
    except (OSError, ValueError, StopIteration):
        return None


def _rlimit_available() -> int | None:
    """What ``ulimit -v`` (address space) and ``ulimit -d`` (data) leave to this process."""
    try:
        with open("/proc/self/status") as fh:
            status = {k: v for k, _, v in (line.partition(":") for line in fh)}
    except (ImportError, OSError):
        return None
    found = []
    for limit, field in ((resource.RLIMIT_AS, "VmSize"), (resource.RLIMIT_DATA, "VmData")):
        soft = resource.getrlimit(limit)[0]
        if soft != resource.RLIM_INFINITY and field in status:
            found.append(soft - int(status[field].split()[0]) * 1024)
    return min(found) if found else None


def available_memory() -> int | None:
    """Bytes this process may still allocate: the least of what the system, its cgroup and its rlimits leave.

    ``MemAvailable`` of ``/proc/meminfo`` (free memory and reclaimable cache, no swap), the
    cgroup v2 ``memory.max`` less ``memory.current`` (with its inactive page cache counted
    as free), and the soft ``RLIMIT_AS`` (``ulimit -v``) and ``RLIMIT_DATA`` (``ulimit -d``)
    less what the process already maps. :data:`MEMORY_VARIABLE` (``OMNIWIDGET_MEMORY=8G``),
    when set, is taken instead.

    Returns
    -------
    int or None
        None where none of these can be read (not Linux, and no ``OMNIWIDGET_MEMORY``).

    Raises
    ------
    ImageError
        If ``OMNIWIDGET_MEMORY`` is not a number of bytes, with an optional K, M, G or T.
    """
    given = os.environ.get(MEMORY_VARIABLE, "").strip().upper().removesuffix("B")
    if given:
        number, unit = (given[:-1], given[-1]) if given[-1] in _UNITS else (given, "")
        try:
            return int(float(number) * _UNITS[unit])
        except ValueError:
            raise ImageError(
                f"{MEMORY_VARIABLE}={os.environ[MEMORY_VARIABLE]!r}: expected bytes, or a number with K, M, G or T (8G)"
            ) from None
    found = [n for n in (_meminfo("MemAvailable"), _cgroup_available(), _rlimit_available()) if n is not None]
    if not found and hasattr(os, "sysconf"):
        try:
            found.append(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
        except (ValueError, OSError):
            pass
    return max(0, min(found)) if found else None


def _refusal(path: Path, header: ImageHeader, need: int, have: int, *, warp: bool, width: int | None) -> ImageError:
    what = "reading it"
    how = f"free memory, or set {MEMORY_VARIABLE} to the bytes it may count on"
    if warp:
        w, _ = _warp_output(header, width)
        what = f"reading it and a warp {w} pixels wide"
        how = (
            f"try a smaller width (--width; a warp takes about {WARP_BYTES_PER_PIXEL + header.bytes_per_pixel} bytes per output pixel), "
            + how
        )
    return ImageError(f"{path}: {header.describe()}; {what} needs about {_gigabytes(need)} and {_gigabytes(have)} is available: {how}")


def check_fits(path: str | os.PathLike[str], *, warp: bool = False, width: int | None = None, streamed: bool = False) -> ImageHeader | None:
    """Refuse, before decoding, an image whose reading (and warp) would not fit in the memory available.

    Parameters
    ----------
    path : path-like
    warp : bool
        Count a warp of it too (:func:`memory_needed`).
    width : int, optional
        The warp's output width; default: the panorama's own. A JPEG is counted at the
        size it will be decoded at (:func:`~omniwidget.io.large.asked_reduction`).
    streamed : bool
        As for :func:`memory_needed`.

    Returns
    -------
    ImageHeader or None
        The header, or None when the format does not say its size (nothing is checked then).

    Raises
    ------
    ImageError
        Naming the file, its size, what it needs and what is available, and how to go on:
        a smaller width, more memory, or ``OMNIWIDGET_MEMORY`` to count on more.

    Examples
    --------
    >>> import omniwidget as ow
    >>> check_fits(ow.sample_path(), warp=True).shape
    (512, 1024, 3)
    """
    header = image_header(path)
    if header is not None:
        _reduction(Path(path), header, warp=warp, width=width, streamed=streamed)
    return header


def read_image(path: str | os.PathLike[str], *, orientation: bool = True, width: int | None = None, place: bool = True) -> NDArray:
    """Read an image file as an array in RGB(A) order, keeping its sample depth.

    Parameters
    ----------
    path : path-like
        PNG, JPEG, TIFF, WebP, BMP, ... (whatever OpenCV decodes), or a ``.npy`` array;
        the format is told from the content, not the name. The file is only read.
    orientation : bool
        Turn the pixels as the file's EXIF orientation says (JPEG, PNG and WebP; OpenCV
        does it for TIFF), so that the array is the picture viewers show.
    width : int, optional
        The width the image is wanted at (a warp's output width, say). A JPEG at least
        twice as wide is decoded at 1/2, 1/4 or 1/8 of its size (libjpeg's DCT scaling, the
        most that keeps it at least ``width`` wide: :func:`~omniwidget.io.large.asked_reduction`): read at the
        size asked, in less memory and time, and averaged rather than aliased. Another
        format larger than :data:`~omniwidget.io.large.STREAM_BYTES` decoded is reduced by
        the largest whole factor that keeps it ``width`` wide, an exact box average made
        strip by strip (:func:`~omniwidget.io.large.read_reduced`); the others are decoded
        whole.
    place : bool
        A part of a panorama whose Photo Sphere XMP says where it lies on the sphere
        (``GPano:CroppedArea*``, ``FullPano*``: a phone's 360 x 120° sweep, say) is read
        into its place on the full sphere, zeros elsewhere (:func:`place_gpano`). False:
        the pixels as the file holds them.

    Returns
    -------
    ndarray, shape (H, W) or (H, W, C)
        uint8, uint16 or float32 (float64 from TIFF or ``.npy``), as stored; gray with an
        alpha channel comes as RGBA.

    Raises
    ------
    ImageError
        Naming the file: missing, a folder, unreadable, empty, not an image, truncated
        (a JPEG without its end marker, a PNG without its IEND chunk, a TIFF or WebP shorter
        than its header says), damaged (a PNG chunk failing its checksum) or too large for
        OpenCV.
    """
    return _read_image(Path(path), orientation=orientation, width=width, warp=False, place=place)


def _reduction(
    path: Path, header: ImageHeader | None, *, warp: bool, width: int | None, reduce: bool = True, streamed: bool = False
) -> ReadPlan:
    """How ``path`` is read (:func:`_plan`), once it fits in memory; else refused."""
    if header is None:
        return ReadPlan("whole", 1)
    plan = _plan(header, width=width, reduce=reduce, streamed=streamed)
    have = available_memory()
    if have is not None and (need := _needed(header, warp=warp, width=width, plan=plan, streamed=streamed)) > have:
        raise _refusal(path, header, need, have, warp=warp, width=width)
    return plan


def _read_image(
    path: Path, *, orientation: bool, width: int | None, warp: bool, reduce: bool = True, streamed: bool = False, place: bool = True
) -> NDArray:
    path = Path(path)
    if path.is_dir():
        raise ImageError(f"{path}: is a folder, not an image file")
    header = image_header(path)  # refuses a FIFO or a device: the read would hang, or never end
    plan = _reduction(path, header, warp=warp, width=width, reduce=reduce, streamed=streamed)
    if plan.how == "reduced" and header is not None:
        reduced = read_reduced(path, header, plan.reduce)
        return _placed(path, reduced, path if header.format in ("JPEG", "PNG", "WebP", "TIFF") else None) if place else reduced
    factor = plan.reduce
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise ImageError(f"{path}: cannot read the image ({exc.strerror or exc})") from None
    if not data:
        raise ImageError(f"{path}: the file is empty")
    kind = _format(data)
    if kind == "npy":
        return _read_npy(path, data, header)
    exif, size = _checked_structure(path, kind, data)
    image = _decoded(path, data, kind, size, factor, header)
    if orientation and kind in ("JPEG", "PNG", "WebP"):
        image = _oriented(image, metadata.orientation(exif))  # Pillow reads the EXIF block
    return _placed(path, image, data if kind in ("JPEG", "PNG", "WebP", "TIFF") else None) if place else image


def _structure(kind: str | None, data: bytes) -> tuple[str | None, bytes | None, tuple[int, int] | None]:
    """What is wrong with the file's structure (None if nothing), its EXIF block and the size its header says, by format."""
    if kind == "JPEG":
        problem, exif, size = _jpeg_structure(data)
        if problem == "truncated":
            problem = "the JPEG data ends before its end-of-image marker"
        elif problem == "damaged":
            problem = "damaged: a JPEG segment has an impossible length"
        return problem, exif, size
    if kind == "PNG":
        return _png_structure(data)
    if kind == "WebP":
        return (*_webp_structure(data), None)
    if kind == "TIFF":
        return _tiff_structure(data), None, None
    if kind == "BMP":
        declared = int.from_bytes(data[2:6], "little")
        if declared > len(data):
            return f"the BMP data is {len(data)} bytes, its header says {declared}", None, None
    return None, None, None


def _checked_structure(path: Path, kind: str | None, data: bytes) -> tuple[bytes | None, tuple[int, int] | None]:
    """The file's EXIF block and header size, once its structure is whole; else an ImageError saying it is cut short or damaged."""
    problem, exif, size = _structure(kind, data)
    if problem is not None:
        if problem.startswith("damaged"):
            raise ImageError(f"{path}: the file is {problem}")
        raise ImageError(f"{path}: the file looks truncated ({problem}); was it copied or downloaded whole?")
    return exif, size


def _decoded(path: Path, data: bytes, kind: str | None, size: tuple[int, int] | None, factor: int, header: ImageHeader | None) -> NDArray:
    """OpenCV's decoding of ``data`` (reduced by ``factor`` for a JPEG), in RGB(A) order; an ImageError saying why it cannot."""
    flags = cv2.IMREAD_UNCHANGED
    if factor > 1 and header is not None:  # a JPEG decoded smaller; OpenCV must not turn it too (done by the caller)
        flags = getattr(cv2, _REDUCTIONS[factor][1 if len(header.shape) == 2 else 0]) | cv2.IMREAD_IGNORE_ORIENTATION
    try:
        image = cv2.imdecode(np.frombuffer(data, np.uint8), flags)
    except cv2.error as exc:
        raise ImageError(f"{path}: OpenCV cannot decode it ({str(exc).strip().splitlines()[-1]})") from None
    if image is None:
        limit = int(os.environ.get("OPENCV_IO_MAX_IMAGE_PIXELS", 1 << 30))
        if size is not None and size[0] * size[1] > limit:
            raise ImageError(
                f"{path}: the image is {size[0]} x {size[1]}, more than the {limit} pixels OpenCV decodes "
                "(set OPENCV_IO_MAX_IMAGE_PIXELS to allow more)"
            )
        if kind is not None:
            raise ImageError(f"{path}: a damaged {kind} file (OpenCV cannot decode it)")
        hint = " (it looks like a text file)" if _looks_like_text(data[:512]) else ""
        raise ImageError(f"{path}: not an image OpenCV can decode{hint}")
    return _swap_red_blue(image)  # OpenCV's BGR(A) to RGB(A)


def _placed(path: Path, image: NDArray, data: bytes | Path | None) -> NDArray:
    """``image`` put in its place on the full sphere when its file's Photo Sphere XMP says it is a part of one.

    ``data``: the file's bytes (or the file) to read the XMP from; None for a format without one.
    """
    if data is None:
        return image
    found = metadata.read_metadata(data).gpano
    if found is None or found.is_full or found.placement(image.shape[1], image.shape[0]) is None:
        return image  # a whole sphere, or tags that place nothing (read as the file holds it: --fit as without them)
    return place_gpano(image, found, str(path))


# --- writing -----------------------------------------------------------------------------


def _swap_red_blue(image: NDArray) -> NDArray:
    """RGB(A) <-> BGR(A); other layouts as they are. A new array for 3 and 4 channels."""
    if image.ndim != 3 or image.shape[2] not in (3, 4):
        return image
    if image.dtype == np.float64:  # cvtColor takes 8-bit, 16-bit and float32 only
        return np.ascontiguousarray(image[..., [2, 1, 0, 3][: image.shape[2]]])
    return cv2.cvtColor(image, cv2.COLOR_BGR2RGB if image.shape[2] == 3 else cv2.COLOR_BGRA2RGBA)


def read_panorama(
    path: str | os.PathLike[str],
    fit: Fit | None = None,
    *,
    width: int | None = None,
    warp: bool = False,
    reduce: bool = True,
    streamed: bool = False,
    place: bool = True,
) -> NDArray:
    """Read an equirectangular panorama: :func:`read_image` (a part placed where its XMP says), made 2:1 as ``fit`` says, then :func:`check_panorama`.

    Parameters
    ----------
    path : path-like
    fit : {"pad", "stretch"}, optional
        :func:`to_equirectangular` first; by default an image that is not 2:1 is refused.
    width : int, optional
        The width it is to be warped to (default: its own): a JPEG at least twice as wide
        is decoded reduced (:func:`read_image`).
    warp : bool
        Count the memory of a warp to ``width`` too (:func:`memory_needed`), so that a
        panorama whose warp would not fit is refused before it is decoded.
    reduce : bool
        False: decode it whole whatever ``width`` says (frames that must share one size
        whatever their formats); the memory is then counted whole.
    streamed : bool
        The warp will be made in strips (:func:`memory_needed`): counted so. The caller
        reads a panorama that :func:`omniwidget.io.large.plan_read` leaves on disk with
        :func:`omniwidget.io.large.open_on_disk` instead.
    place : bool
        Put a part of a panorama in its place on the sphere as its Photo Sphere XMP says
        (:func:`read_image`), before ``fit`` is looked at.

    Returns
    -------
    ndarray, shape (H, 2 H) or (H, 2 H, C)

    Raises
    ------
    ImageError
        Naming the file and what is wrong with it.
    """
    image = _read_image(Path(path), orientation=True, width=width, warp=warp, reduce=reduce, streamed=streamed, place=place)
    if fit is not None:
        image = to_equirectangular(image, fit, str(path))
    return check_panorama(image, str(path))


def check_writable(path: str | os.PathLike[str], image: NDArray) -> None:
    """Check that ``write_image(path, image)`` can write ``image``, before any work is spent on it.

    Parameters
    ----------
    path : path-like
        Where the image would go; its suffix picks the format.
    image : ndarray, shape (H, W) or (H, W, C)
        Only its shape and dtype are looked at (a zero-size array of the same kind will do).

    Raises
    ------
    ImageError
        If the folder does not exist, ``path`` is a folder, the suffix is unknown or cannot
        hold the image's sample type or alpha channel.
    """
    path = Path(path)
    if not isinstance(image, np.ndarray):
        raise ImageError(f"{path}: expected a numpy array to write, got {type(image).__name__}")
    if path.is_dir():
        raise ImageError(f"{path}: is a folder; name an image file")
    if not path.parent.is_dir():
        raise ImageError(f"{path}: the folder {path.parent} does not exist")
    check_format(path, image)


def check_format(path: Path, image: NDArray) -> None:
    """The part of :func:`check_writable` about the suffix and the image's kind."""
    suffix = path.suffix.lower()
    if suffix == ".npy":
        return
    if image.ndim not in (2, 3) or (image.ndim == 3 and not 1 <= image.shape[2] <= 4):
        raise ImageError(f"{path}: cannot write an array of shape {image.shape} as an image (use .npy)")
    allowed = _DEPTH_SUFFIXES.get(image.dtype.type, ())
    if suffix not in allowed:
        raise ImageError(
            f"{path}: cannot write a {image.dtype} image as {suffix or 'a file without suffix'} (use {', '.join(allowed + ('.npy',))})"
        )
    if (limit := _MAX_SIDE.get(suffix)) is not None and image.shape[1] > limit:
        raise ImageError(f"{path}: {suffix} holds images at most {limit} px wide, this one is {image.shape[1]} (write .png or .tif)")
    if suffix in _NO_ALPHA and image.ndim == 3 and image.shape[2] in (2, 4):
        raise ImageError(f"{path}: JPEG has no alpha channel; write .png, .tif, .webp or .npy to keep it, or drop it (image[..., :-1])")


def encode_image(path: Path, image: NDArray, meta: metadata.Metadata | None = None) -> bytes:
    """The bytes of ``image`` in the format of ``path``'s suffix (checked by :func:`check_writable`).

    ``meta``: metadata added to the encoded bytes (:func:`omniwidget.io.metadata.with_metadata`:
    JPEG, PNG and WebP; the pixels are the same bytes as without it).
    """
    check_writable(path, image)
    suffix = path.suffix.lower()
    if suffix == ".npy":
        buf = io.BytesIO()
        np.save(buf, image)
        return buf.getvalue()
    out = image
    if out.ndim == 3 and out.shape[2] == 2:  # no encoder takes gray + alpha: as RGBA, lossless
        out = out[..., [0, 0, 0, 1]]
    out = _swap_red_blue(out)  # RGB(A) to OpenCV's BGR(A)
    try:
        ok, encoded = cv2.imencode(suffix, np.ascontiguousarray(out))
    except cv2.error as exc:
        raise ImageError(f"{path}: OpenCV could not encode the image as {suffix} ({str(exc).strip().splitlines()[-1]})") from None
    if not ok:
        raise ImageError(f"{path}: OpenCV could not encode the image as {suffix}")
    return encoded.tobytes() if meta is None else metadata.with_metadata(encoded.tobytes(), meta)


def write_bytes(path: Path, data: bytes) -> None:
    """:func:`atomic_write_bytes`, with a failure said as an :class:`ImageError` naming ``path``."""
    try:
        atomic_write_bytes(path, data)
    except OSError as exc:
        raise ImageError(f"{path}: cannot write the file ({exc.strerror or exc})") from None


def write_image(path: str | os.PathLike[str], image: NDArray, meta: metadata.Metadata | None = None) -> None:
    """Write an RGB(A) or gray image whole, or not at all.

    Parameters
    ----------
    path : path-like
        The format follows the suffix: uint8 as PNG, JPEG, TIFF, WebP or BMP; uint16 as PNG or
        TIFF; float32 and float64 as TIFF; any array as ``.npy`` (kept exactly). Gray with
        alpha is written as RGBA (except to ``.npy``); JPEG, having no alpha, refuses alpha.
    image : ndarray, shape (H, W) or (H, W, C)
        RGB(A) order, 1 to 4 channels.
    meta : Metadata, optional
        EXIF, ICC profile and XMP to write with it (JPEG, PNG, WebP: :func:`encode_image`),
        as :func:`omniwidget.io.metadata.output_metadata` makes them.

    Raises
    ------
    ImageError
        If the image cannot be written there (:func:`check_writable`), cannot be encoded or
        the file cannot be written (a full disk, say); an existing file at ``path`` is then
        left as it was.
    """
    path = Path(path)
    write_bytes(path, encode_image(path, image, meta))


#: Suffixes :func:`write_image_strips` writes strip by strip (the others are gathered whole first).
STRIP_SUFFIXES = (".npy", ".tif", ".tiff", ".png", ".jpg", ".jpeg")
#: The side of a TIFF written in strips' tiles.
TIFF_TILE = 256


def _tiles(strips: Iterable[NDArray], side: int) -> Iterator[NDArray]:
    """The tiles of an image given as strips of any rows, row of tiles by row of tiles, left to right (for tifffile)."""
    for band in large.row_blocks(strips, side):
        if len(band) < side:  # the last row of tiles, zero-padded as tifffile wants
            band = np.concatenate([band, np.zeros((side - len(band), *band.shape[1:]), band.dtype)])
        yield from _row_of_tiles(band, side)


def _row_of_tiles(band: NDArray, side: int) -> Iterator[NDArray]:
    width = band.shape[1]
    for c0 in range(0, width, side):
        tile = band[:, c0 : c0 + side]
        if tile.shape[1] < side:  # the last tile of a row, zero-padded as tifffile wants
            tile = np.concatenate([tile, np.zeros((side, side - tile.shape[1], *band.shape[2:]), band.dtype)], axis=1)
        yield np.ascontiguousarray(tile)


def write_image_strips(
    path: str | os.PathLike[str],
    shape: tuple[int, ...],
    dtype: np.dtype | type,
    strips: Iterable[NDArray],
    *,
    progress: Callable[[int], None] | None = None,
    meta: metadata.Metadata | None = None,
) -> None:
    """Write an image given as strips of rows, whole or not at all, holding one strip at a time where the format allows.

    ``.npy`` is written row after row after its header (a file ``np.load`` can memory-map),
    TIFF (BigTIFF, tiles of :data:`TIFF_TILE` pixels, deflate level 1) a row of tiles at a
    time as the strips come, PNG deflated as they come
    (:func:`omniwidget.io.large.write_png_strips`) and JPEG encoded by libvips from the
    rows held on disk (:func:`omniwidget.io.large.write_jpeg_strips`), so memory holds about
    one strip; the other formats are gathered into one array and encoded (OpenCV encodes
    whole images). A ``.npy`` larger than the free disk is refused before any work, its
    size said. Written to a hidden
    temporary file beside ``path`` and renamed over it at the end, synced (as
    :func:`write_image`); on any error, Ctrl+C included, the temporary file is removed.

    Parameters
    ----------
    path : path-like
        The format follows the suffix, as :func:`write_image`.
    shape : tuple of int
        The whole image's, ``(H, W[, C])``.
    dtype : numpy.dtype
    strips : iterable of ndarray
        Rows top to bottom, each ``(rows, W[, C])``; their rows must add up to ``H``.
    progress : callable, optional
        ``progress(rows_written)`` after each strip.
    meta : Metadata, optional
        Metadata written with it: JPEG, PNG and WebP as :func:`write_image`; TIFF its XMP
        and ICC profile (tags 700 and 34675).

    Raises
    ------
    ImageError
        If the image cannot be written there (:func:`check_writable`), the strips do not
        make the shape, or the file cannot be written.
    """
    path = Path(path)
    shape, dtype = tuple(int(s) for s in shape), np.dtype(dtype)
    check_writable(path, np.empty((0, *shape[1:]), dtype))
    suffix = path.suffix.lower()
    rows = _checked_strips(path, shape, dtype, strips, progress)
    if suffix not in STRIP_SUFFIXES:
        write_image(path, _gathered(rows, np.empty(shape, dtype)), meta)
        return
    meta = meta or metadata.Metadata()
    if suffix == ".npy":
        large.check_free_disk(path.parent, math.prod(shape) * dtype.itemsize, f"{path}: a {' x '.join(map(str, shape))} {dtype} array")
    output = atomic_output(path)
    try:
        with output:
            _STRIP_WRITERS[suffix](output, shape, dtype, rows, meta)
    except OSError as exc:
        raise ImageError(f"{path}: cannot write the file ({exc.strerror or exc})") from None


def _checked_strips(
    path: Path, shape: tuple[int, ...], dtype: np.dtype, strips: Iterable[NDArray], progress: Callable[[int], None] | None
) -> Iterator[NDArray]:
    """The strips as they come, each checked to fit the image's next rows, and ``progress`` told after each."""
    done = 0
    for strip in strips:
        if strip.shape[1:] != shape[1:] or strip.dtype != dtype or done + strip.shape[0] > shape[0]:
            raise ImageError(f"{path}: a strip of {strip.shape} {strip.dtype} does not fit an image of {shape} {dtype} at row {done}")
        done += strip.shape[0]
        yield strip
        if progress is not None:
            progress(done)
    if done != shape[0]:
        raise ImageError(f"{path}: the strips gave {done} of the image's {shape[0]} rows")


def _gathered(strips: Iterable[NDArray], out: NDArray) -> NDArray:
    """The strips copied into ``out``, top to bottom."""
    row = 0
    for strip in strips:
        out[row : row + strip.shape[0]] = strip
        row += strip.shape[0]
    return out


def _npy_strips(output: AtomicOutput, shape: tuple[int, ...], dtype: np.dtype, strips: Iterator[NDArray], meta: metadata.Metadata) -> None:
    """A ``.npy`` header, then the rows as they come (the file ``np.load`` memory-maps)."""
    with open(output.fd, "wb", closefd=False) as fh:
        np.lib.format.write_array_header_2_0(fh, {"descr": np.lib.format.dtype_to_descr(dtype), "fortran_order": False, "shape": shape})
        for strip in strips:
            fh.write(np.ascontiguousarray(strip).data)


def _png_strips(output: AtomicOutput, shape: tuple[int, ...], dtype: np.dtype, strips: Iterator[NDArray], meta: metadata.Metadata) -> None:
    """A PNG deflated as the strips come (:func:`omniwidget.io.large.write_png_strips`)."""
    with open(output.fd, "wb", closefd=False) as fh:
        large.write_png_strips(fh, shape, dtype, strips, chunks=metadata.png_chunks(meta))


def _jpeg_strips(output: AtomicOutput, shape: tuple[int, ...], dtype: np.dtype, strips: Iterator[NDArray], meta: metadata.Metadata) -> None:
    """A JPEG encoded by libvips from the rows held on disk (:func:`omniwidget.io.large.write_jpeg_strips`)."""
    large.write_jpeg_strips(output.path, shape, strips, segments=metadata.jpeg_segments(meta))


def _tiff_strips(output: AtomicOutput, shape: tuple[int, ...], dtype: np.dtype, strips: Iterator[NDArray], meta: metadata.Metadata) -> None:
    """A tiled BigTIFF written a row of tiles at a time, as OpenCV writes its channels (so :func:`read_image` gives the strips back).

    Gray + alpha is written as RGBA with the fourth channel "unspecified": OpenCV reads a gray
    + alpha tiled TIFF not at all, and the RGB of "unassalpha" premultiplied.
    """
    two = len(shape) == 3 and shape[2] == 2
    layout = (*shape[:2], 4) if two else shape
    photometric = "rgb" if len(layout) == 3 and layout[2] in (3, 4) else "minisblack"
    extras = "unspecified" if len(layout) == 3 and layout[2] == 4 else None
    tiles = _tiles((strip[..., [0, 0, 0, 1]] if two else strip for strip in strips), TIFF_TILE)
    tifffile.imwrite(
        output.path,
        tiles,
        shape=layout,
        dtype=dtype,
        bigtiff=True,
        photometric=photometric,
        extrasamples=extras,
        tile=(TIFF_TILE, TIFF_TILE),
        compression="zlib",
        compressionargs={"level": 1},
        maxworkers=min(os.cpu_count() or 1, 4),  # tiles deflated in threads
        extratags=metadata.tiff_tags(meta),
    )


#: How each suffix of :data:`STRIP_SUFFIXES` is written strip by strip into the temporary file.
_STRIP_WRITERS: dict[str, Callable[[AtomicOutput, tuple[int, ...], np.dtype, Iterator[NDArray], metadata.Metadata], None]] = {
    ".npy": _npy_strips,
    ".png": _png_strips,
    ".jpg": _jpeg_strips,
    ".jpeg": _jpeg_strips,
    ".tif": _tiff_strips,
    ".tiff": _tiff_strips,
}
