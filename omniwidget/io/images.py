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
import os
import struct
import zlib
from pathlib import Path
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from .._checks import SUPPORTED_DTYPES, check_image, check_panorama, require_regular_file
from .._files import atomic_write_bytes
from ..errors import ImageError, NotRegularFileError

__all__ = [
    "FITS",
    "SUPPORTED_DTYPES",
    "atomic_write_bytes",
    "check_format",
    "check_panorama",
    "check_writable",
    "encode_image",
    "read_image",
    "read_panorama",
    "to_equirectangular",
    "write_bytes",
    "write_image",
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


# --- checks ------------------------------------------------------------------------------


def to_equirectangular(image: NDArray, fit: Fit, name: str = "image") -> NDArray:
    """Make an image twice as wide as high, by padding rows or by resizing.

    Parameters
    ----------
    image : ndarray, shape (H, W) or (H, W, C)
        1 to 4 channels; uint8, uint16, float32 or float64.
    fit : {"pad", "stretch"}
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
    if fit not in FITS:
        raise ValueError(f'fit must be "pad" or "stretch", got {fit!r}')
    h, w = check_image(image, name)
    if w == 2 * h:
        return image
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
    import cv2

    new_w = w + w % 2
    new_h = new_w // 2
    interpolation = cv2.INTER_AREA if new_h < h else cv2.INTER_LINEAR
    out = cv2.resize(image, (new_w, new_h), interpolation=interpolation)
    return out.reshape(new_h, new_w, *image.shape[2:])  # OpenCV drops a single channel axis


# --- reading -----------------------------------------------------------------------------

_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_NPY_MAGIC = b"\x93NUMPY"


def _tiff_ifd0(blob: bytes | memoryview) -> dict[int, tuple[int, ...]] | None:
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


def _orientation(exif: bytes | None) -> int:
    """The EXIF Orientation (1 to 8) in a TIFF-structured EXIF block; 1 if absent or malformed."""
    if exif is None:
        return 1
    if exif[:6] == b"Exif\x00\x00":
        exif = exif[6:]
    values = (_tiff_ifd0(exif) or {}).get(0x0112, ())
    return values[0] if values and 1 <= values[0] <= 8 else 1


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


def _read_npy(path: Path, data: bytes) -> NDArray:
    try:
        array = np.load(io.BytesIO(data), allow_pickle=False)
    except (OSError, ValueError) as exc:
        raise ImageError(f"{path}: a damaged or unreadable .npy file ({exc})") from None
    if not isinstance(array, np.ndarray) or array.dtype.kind not in "uif":
        raise ImageError(f"{path}: the .npy file does not hold an array of numbers")
    return array.astype(array.dtype.newbyteorder("="), copy=False)


def read_image(path: str | os.PathLike[str], *, orientation: bool = True) -> NDArray:
    """Read an image file as an array in RGB(A) order, keeping its sample depth.

    Parameters
    ----------
    path : path-like
        PNG, JPEG, TIFF, WebP, BMP, ... (whatever OpenCV decodes), or a ``.npy`` array;
        the format is told from the content, not the name. The file is only read.
    orientation : bool
        Turn the pixels as the file's EXIF orientation says (JPEG, PNG and WebP; OpenCV
        does it for TIFF), so that the array is the picture viewers show.

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
    import cv2

    path = Path(path)
    if path.is_dir():
        raise ImageError(f"{path}: is a folder, not an image file")
    try:
        require_regular_file(path, "image")  # a FIFO would hang the read, a device never end
    except NotRegularFileError as exc:
        raise ImageError(str(exc)) from None
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise ImageError(f"{path}: cannot read the image ({exc.strerror or exc})") from None
    if not data:
        raise ImageError(f"{path}: the file is empty")
    kind = _format(data)
    if kind == "npy":
        return _read_npy(path, data)
    problem, exif, size = None, None, None
    if kind == "JPEG":
        problem, exif, size = _jpeg_structure(data)
        if problem == "truncated":
            problem = "the JPEG data ends before its end-of-image marker"
        elif problem == "damaged":
            problem = "damaged: a JPEG segment has an impossible length"
    elif kind == "PNG":
        problem, exif, size = _png_structure(data)
    elif kind == "WebP":
        problem, exif = _webp_structure(data)
    elif kind == "TIFF":
        problem = _tiff_structure(data)
    elif kind == "BMP":
        declared = int.from_bytes(data[2:6], "little")
        if declared > len(data):
            problem = f"the BMP data is {len(data)} bytes, its header says {declared}"
    if problem is not None:
        if problem.startswith("damaged"):
            raise ImageError(f"{path}: the file is {problem}")
        raise ImageError(f"{path}: the file looks truncated ({problem}); was it copied or downloaded whole?")
    try:
        image = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
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
    image = _swap_red_blue(image)  # OpenCV's BGR(A) to RGB(A)
    if orientation and kind in ("JPEG", "PNG", "WebP"):
        image = _oriented(image, _orientation(exif))
    return image


# --- writing -----------------------------------------------------------------------------


def _swap_red_blue(image: NDArray) -> NDArray:
    """RGB(A) <-> BGR(A); other layouts as they are. A new array for 3 and 4 channels."""
    import cv2

    if image.ndim != 3 or image.shape[2] not in (3, 4):
        return image
    if image.dtype == np.float64:  # cvtColor takes 8-bit, 16-bit and float32 only
        return np.ascontiguousarray(image[..., [2, 1, 0, 3][: image.shape[2]]])
    return cv2.cvtColor(image, cv2.COLOR_BGR2RGB if image.shape[2] == 3 else cv2.COLOR_BGRA2RGBA)


def read_panorama(path: str | os.PathLike[str], fit: Fit | None = None) -> NDArray:
    """Read an equirectangular panorama: :func:`read_image`, made 2:1 as ``fit`` says, then :func:`check_panorama`.

    Parameters
    ----------
    path : path-like
    fit : {"pad", "stretch"}, optional
        :func:`to_equirectangular` first; by default an image that is not 2:1 is refused.

    Returns
    -------
    ndarray, shape (H, 2 H) or (H, 2 H, C)

    Raises
    ------
    ImageError
        Naming the file and what is wrong with it.
    """
    image = read_image(path)
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
    if suffix in _NO_ALPHA and image.ndim == 3 and image.shape[2] in (2, 4):
        raise ImageError(f"{path}: JPEG has no alpha channel; write .png, .tif, .webp or .npy to keep it, or drop it (image[..., :-1])")


def encode_image(path: Path, image: NDArray) -> bytes:
    """The bytes of ``image`` in the format of ``path``'s suffix (checked by :func:`check_writable`)."""
    import cv2

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
    return encoded.tobytes()


def write_bytes(path: Path, data: bytes) -> None:
    """:func:`atomic_write_bytes`, with a failure said as an :class:`ImageError` naming ``path``."""
    try:
        atomic_write_bytes(path, data)
    except OSError as exc:
        raise ImageError(f"{path}: cannot write the file ({exc.strerror or exc})") from None


def write_image(path: str | os.PathLike[str], image: NDArray) -> None:
    """Write an RGB(A) or gray image whole, or not at all.

    Parameters
    ----------
    path : path-like
        The format follows the suffix: uint8 as PNG, JPEG, TIFF, WebP or BMP; uint16 as PNG or
        TIFF; float32 and float64 as TIFF; any array as ``.npy`` (kept exactly). Gray with
        alpha is written as RGBA (except to ``.npy``); JPEG, having no alpha, refuses alpha.
    image : ndarray, shape (H, W) or (H, W, C)
        RGB(A) order, 1 to 4 channels.

    Raises
    ------
    ImageError
        If the image cannot be written there (:func:`check_writable`), cannot be encoded or
        the file cannot be written (a full disk, say); an existing file at ``path`` is then
        left as it was.
    """
    path = Path(path)
    write_bytes(path, encode_image(path, image))
