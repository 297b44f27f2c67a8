"""Panoramas larger than memory: read a patch at a time from disk, decoded reduced in strips, written in strips.

A stitched panorama 64,000 px wide is 6.1 GB of RGB pixels, more than a warp may hold.
Three pieces let the command line and the editor work on it in bounded memory:

- :class:`DiskPanorama`: the pixels stay on disk (a ``.npy`` file's own data, or a
  temporary decoding of any other format made by libvips as it streams, never whole in
  memory) and are read a patch at a time with ``pread``: the resampling in tiles
  (:func:`~omniwidget.raster.warping.remap_panorama`) asks for the rows and columns each
  output tile needs. Not memory-mapped: a mapped file's pages count in the process's memory
  once touched, and a full-width warp touches every one.
- :func:`read_reduced`: a panorama decoded at ``1 / factor`` of its size by an exact box
  average, strip by strip (libvips' ``shrink`` on a sequential decoding; numpy over bands
  of rows for ``.npy``), for the formats whose decoder cannot reduce (JPEG's DCT scaling is
  :func:`asked_reduction`).
- :func:`plan_read`: how a file is read for a warp ``width`` wide, the one decision the
  memory estimate (:func:`~omniwidget.io.images.memory_needed`) and the readers share.

libvips (``pyvips`` with ``pyvips-binary``) is imported only here and only for a file
that needs it.
"""

from __future__ import annotations

import math
import os
import shutil
import struct
import tempfile
import zlib
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING, Any, BinaryIO, Literal

import numpy as np
from numpy.lib import format as npy
from numpy.typing import NDArray

from .._checks import SUPPORTED_DTYPES
from .._lazy import lazy, resolve
from ..errors import ImageError
from . import metadata

if TYPE_CHECKING:
    import cv2
    import pyvips
    import tifffile

    from .images import ImageHeader
else:
    pyvips = lazy("pyvips")
    cv2 = lazy("cv2")
    tifffile = lazy("tifffile")

__all__ = [
    "JPEG_QUALITY",
    "JPEG_REDUCTIONS",
    "PNG_LEVEL",
    "STREAM_BYTES",
    "STREAM_VARIABLE",
    "DiskPanorama",
    "check_free_disk",
    "ReadPlan",
    "open_on_disk",
    "plan_read",
    "read_reduced",
    "row_blocks",
    "WARP_SIZES",
    "WarpSizes",
    "stream_bytes",
    "write_jpeg_strips",
    "write_png_strips",
]

#: A panorama decoded larger than this (bytes) is not held whole where it need not be: a warp
#: made in strips reads it from disk a patch at a time, a warp to a smaller width decodes it
#: reduced in strips. Below it files are decoded whole. The environment
#: variable of this name (bytes) sets another.
STREAM_BYTES = 1 << 30
STREAM_VARIABLE = "OMNIWIDGET_STREAM_BYTES"


def stream_bytes() -> int:
    """:data:`STREAM_BYTES`, or the environment's ``OMNIWIDGET_STREAM_BYTES`` where set."""
    value = os.environ.get(STREAM_VARIABLE, "").strip()
    if not value:
        return STREAM_BYTES
    try:
        return max(int(value), 0)
    except ValueError:
        raise ImageError(f"{STREAM_VARIABLE}={value!r}: expected a number of bytes") from None
#: Rows of the source :func:`read_reduced` averages at a time (times the factor).
REDUCE_ROWS = 64


@dataclass(frozen=True)
class WarpSizes:
    """The sizes by which a warp holds memory, as the resampling and the warp in strips make it.

    :func:`omniwidget.io.images.memory_needed` counts a warp with them before the file is
    decoded. They are the resampling's and the strips' own constants
    (:data:`omniwidget.raster.warping.PAD`, ``REMAP_LIMIT``, ``PATCH_PIXELS``;
    :data:`omniwidget.raster.strips.STREAM_WIDTH`, ``MAP_WIDTH``, ``STRIP_PIXELS``,
    ``STRIPS_AHEAD``), said again here so that reading and writing stand below the method
    and the resampling; the tests check that the two agree.

    Attributes
    ----------
    pad : int
        Pixels a panorama is padded by on each side before it is resampled.
    remap_limit : int
        Pixels a side above which OpenCV's ``remap`` cannot go: larger panoramas are resampled in tiles.
    patch_pixels : int
        The most source pixels a tile's patch may have.
    stream_width : int
        Outputs wider than this are made in strips.
    map_width : int
        Width of the grid the method's map is computed on for a warp in strips.
    strip_pixels : int
        Output pixels a strip holds, about.
    strips_ahead : int
        Strips made ahead of the writer besides the one it takes.
    """

    pad: int = 3
    remap_limit: int = 32767
    patch_pixels: int = 1 << 26
    stream_width: int = 16384
    map_width: int = 8192
    strip_pixels: int = 1 << 20
    strips_ahead: int = 2

    def strip_rows(self, width: int) -> int:
        """Rows of the strips of an output ``width`` wide: :attr:`strip_pixels` pixels' worth, at least 8."""
        return max(8, self.strip_pixels // max(int(width), 1))


#: The sizes a warp's memory is counted by.
WARP_SIZES = WarpSizes()

#: The reductions libjpeg decodes a JPEG at (its DCT scaling, as OpenCV offers it).
JPEG_REDUCTIONS = (2, 4, 8)
#: libvips' sample formats and ours.
_VIPS_DTYPES = {"uchar": np.uint8, "ushort": np.uint16, "float": np.float32, "double": np.float64}


@dataclass(frozen=True)
class ReadPlan:
    """How a panorama file is read for a warp.

    Attributes
    ----------
    how : {"whole", "reduced", "disk"}
        ``"whole"``: decoded into memory (a JPEG reduced by its DCT scaling when ``reduce``
        > 1); ``"reduced"``: decoded at ``1 / reduce`` in strips (:func:`read_reduced`);
        ``"disk"``: left on disk, read a patch at a time (:class:`DiskPanorama`).
    reduce : int
        The factor the image in memory is reduced by (1: full size).
    """

    how: Literal["whole", "reduced", "disk"]
    reduce: int


def asked_reduction(header: ImageHeader, width: int | None) -> int:
    """How much a panorama wanted ``width`` wide is reduced as it is decoded: 1, 2, 4 or 8.

    A JPEG at least twice as wide as ``width`` is decoded at 1/2, 1/4 or 1/8 of its size
    by libjpeg's DCT scaling (an average over each block, so no aliasing), the most that
    keeps it at least ``width`` wide and 2:1 (both sides divisible); other formats, and a
    JPEG no wider than twice ``width``, are decoded whole (1).

    Parameters
    ----------
    header : ImageHeader
        From :func:`image_header`.
    width : int or None
        The width it is wanted at; None: its own (1).

    Returns
    -------
    int
    """
    if header.format != "JPEG" or width is None:
        return 1
    longer = max(header.width, header.height)  # the panorama's width, whichever way its EXIF orientation turns it
    whole = [f for f in JPEG_REDUCTIONS if header.width % f == 0 and header.height % f == 0 and longer // f >= width]
    return max(whole, default=1)


def _divisor_reduction(header: ImageHeader, width: int) -> int:
    """The largest whole factor dividing both sides that keeps the panorama at least ``width`` wide (1 if none)."""
    longer = max(header.width, header.height)
    factors = [f for f in range(2, longer // max(width, 1) + 1) if header.width % f == 0 and header.height % f == 0]
    return max(factors, default=1)


def plan_read(header: ImageHeader, width: int | None, *, strips: bool = False) -> ReadPlan:
    """How :func:`~omniwidget.io.images.read_panorama` and the command line read a panorama for a warp.

    Parameters
    ----------
    header : ImageHeader
        The file's (:func:`~omniwidget.io.images.image_header`).
    width : int or None
        The width it is wanted at (None: its own).
    strips : bool
        The output is made in strips (:func:`~omniwidget.raster.strips.warp_in_strips`):
        a source above :data:`STREAM_BYTES` may then stay on disk.

    Returns
    -------
    ReadPlan
        A JPEG at least twice as wide as asked: decoded reduced by libjpeg (1/2 to 1/8);
        any other file decoded above :data:`STREAM_BYTES`: reduced by the largest whole
        factor that keeps it ``width`` wide, in strips, if there is one; else left on disk
        for a warp made in strips; else whole.
    """
    jpeg = asked_reduction(header, width)
    if jpeg > 1 or header.nbytes <= stream_bytes() or len(header.shape) not in (2, 3):
        return ReadPlan("whole", jpeg)
    if width is not None and (factor := _divisor_reduction(header, width)) > 1:
        return ReadPlan("reduced", factor)
    return ReadPlan("disk", 1) if strips else ReadPlan("whole", 1)


class DiskPanorama:
    """A panorama's pixels in a file, C order, read a patch at a time (see the module).

    Parameters
    ----------
    path : path-like
        The file holding the pixels, row after row.
    offset : int
        Where the pixels start in it (bytes).
    shape : tuple of int
        ``(H, W)`` or ``(H, W, C)``.
    dtype : numpy.dtype
        As stored (either byte order); :attr:`dtype` and the pixels read are in this machine's.
    temporary : bool
        Remove the file on :meth:`close` (a decoding made by :func:`open_on_disk`).

    Notes
    -----
    Use it as a context manager, or call :meth:`close`.
    """

    def __init__(self, path: str | os.PathLike[str], offset: int, shape: tuple[int, ...], dtype: np.dtype | type, *, temporary: bool = False) -> None:
        self.path, self.offset = Path(path), int(offset)
        self._stored = np.dtype(dtype)  # as in the file: its byte order may be another than this machine's
        self.shape, self.dtype = tuple(int(s) for s in shape), self._stored.newbyteorder("=")
        self.temporary = temporary
        self._row_bytes = math.prod(self.shape[1:]) * self.dtype.itemsize
        self._pixel_bytes = self._row_bytes // max(self.shape[1], 1)
        self._fd: int | None = os.open(self.path, os.O_RDONLY)

    @property
    def ndim(self) -> int:
        """2 or 3, as the array's."""
        return len(self.shape)

    def take(self, rows: NDArray[np.integer], cols: NDArray[np.integer]) -> NDArray:
        """The pixels at ``rows`` x ``cols`` (any rows; columns in runs of consecutive ones), as ``image[np.ix_(rows, cols)]``.

        Parameters
        ----------
        rows, cols : ndarray of int, shape (n,) and (m,)
            Within ``[0, H)`` and ``[0, W)``.

        Returns
        -------
        ndarray, shape (n, m[, C]), the panorama's dtype
        """
        if self._fd is None:
            raise ImageError(f"{self.path}: the panorama on disk was closed")
        rows, cols = np.asarray(rows, np.int64), np.asarray(cols, np.int64)
        out = np.empty((len(rows), len(cols), *self.shape[2:]), self._stored)
        if not len(rows) or not len(cols):
            return out.astype(self.dtype, copy=False)
        if rows.min() < 0 or rows.max() >= self.shape[0] or cols.min() < 0 or cols.max() >= self.shape[1]:
            raise IndexError(f"pixels asked outside the {self.shape[1]} x {self.shape[0]} panorama")
        breaks = np.flatnonzero(np.diff(cols) != 1) + 1
        starts = np.concatenate([[0], breaks])
        stops = np.concatenate([breaks, [len(cols)]])
        flat = out.reshape(len(rows), -1).view(np.uint8)
        pb = self._pixel_bytes
        for i, row in enumerate(rows.tolist()):
            base = self.offset + row * self._row_bytes
            for a, b in zip(starts.tolist(), stops.tolist(), strict=True):
                size = (b - a) * pb
                got = os.preadv(self._fd, [flat[i, a * pb : b * pb].data], base + int(cols[a]) * pb)
                if got != size:
                    raise ImageError(f"{self.path}: the file ends before row {row} of the panorama")
        return out.astype(self.dtype, copy=False)  # in this machine's byte order

    def rows(self, start: int, stop: int) -> NDArray:
        """Rows ``start:stop`` whole, ``(stop - start, W[, C])``."""
        return self.take(np.arange(start, stop), np.arange(self.shape[1]))

    def close(self) -> None:
        """Close the file, and remove it if it is a temporary decoding."""
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None
        if self.temporary:
            self.path.unlink(missing_ok=True)

    def __enter__(self) -> DiskPanorama:
        return self

    def __exit__(self, kind: type[BaseException] | None, value: BaseException | None, tb: TracebackType | None) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"DiskPanorama({str(self.path)!r}, shape={self.shape}, dtype={self.dtype})"


def _vips_image(path: Path) -> Any:
    """The file opened by libvips for a sequential decoding, as :func:`~omniwidget.io.images.read_image` would give it.

    Turned as its EXIF orientation says; CMYK made RGB; gray with alpha made RGBA.
    """
    try:
        resolve(pyvips)
    except ImportError:  # pragma: no cover - a declared dependency
        raise ImageError(f"{path}: panoramas this large are read with libvips: pip install pyvips pyvips-binary") from None
    try:
        image = pyvips.Image.new_from_file(str(path), access="sequential", fail_on="truncated")
        if image.get_typeof("orientation") and image.get("orientation") not in (0, 1):
            image = pyvips.Image.new_from_file(str(path), access="random", fail_on="truncated").autorot()  # turned: random access
        if image.interpretation == "cmyk":
            image = image.colourspace("srgb")
        if image.bands == 2:
            image = image[0].bandjoin([image[0], image[0], image[1]])
    except pyvips.Error as exc:
        raise ImageError(f"{path}: libvips cannot decode it ({str(exc).strip().splitlines()[0]})") from None
    if image.format not in _VIPS_DTYPES:
        raise ImageError(f"{path}: samples of type {image.format} are not supported ({', '.join(str(np.dtype(t)) for t in SUPPORTED_DTYPES)} are)")
    return image


def check_free_disk(folder: Path, needed: int, what: str, hint: str = "") -> None:
    """Refuse, naming ``what`` and both sizes (and ``hint``, how to go on), to write ``needed`` bytes where the disk has fewer free."""
    free = shutil.disk_usage(folder).free
    if needed > free:
        raise ImageError(f"{what} needs {needed / 1e9:.2f} GB of disk at {folder}; {free / 1e9:.2f} GB are free{hint}")


def open_on_disk(path: str | os.PathLike[str], header: ImageHeader) -> DiskPanorama:
    """A panorama file as a :class:`DiskPanorama`: a ``.npy`` file as it is; any other format decoded to a temporary file.

    The decoding streams (libvips, sequential access: a few strips in memory) into a file in
    the temporary folder (``TMPDIR``), removed when the panorama is closed, or at once on an
    error or Ctrl+C.

    Parameters
    ----------
    path : path-like
    header : ImageHeader
        The file's (:func:`~omniwidget.io.images.image_header`).

    Returns
    -------
    DiskPanorama

    Raises
    ------
    ImageError
        A ``.npy`` array that is not C-ordered ``(H, W[, C])`` of a supported type, a file
        libvips cannot decode, or too little free disk for the decoding (the size said).
    """
    path = Path(path)
    if header.format == "npy":
        with path.open("rb") as fh:
            version = npy.read_magic(fh)
            _, fortran, stored = (npy.read_array_header_1_0 if version == (1, 0) else npy.read_array_header_2_0)(fh)
        if fortran or header.dtype.type not in SUPPORTED_DTYPES or len(header.shape) not in (2, 3):
            raise ImageError(f"{path}: a panorama read from disk must be a C-ordered (H, W[, C]) array of a supported type, not {header.describe()}")
        return DiskPanorama(path, header.offset, header.shape, stored)
    image = _vips_image(path)
    dtype = np.dtype(_VIPS_DTYPES[image.format])
    shape = (image.height, image.width, image.bands) if image.bands > 1 else (image.height, image.width)
    folder = Path(tempfile.gettempdir())
    check_free_disk(folder, math.prod(shape) * dtype.itemsize, f"{path}: its decoding ({image.width} x {image.height})", " (set TMPDIR to a folder on a larger disk)")
    fd, name = tempfile.mkstemp(prefix=".omniwidget-decoded-", suffix=".raw", dir=folder)
    os.close(fd)
    try:
        image.rawsave(name)
        return DiskPanorama(name, 0, shape, dtype, temporary=True)
    except BaseException as exc:
        Path(name).unlink(missing_ok=True)
        if type(exc).__name__ == "Error":  # pyvips.Error: a damaged or truncated file
            raise ImageError(f"{path}: libvips cannot decode it ({str(exc).strip().splitlines()[0]})") from None
        raise


def read_reduced(path: str | os.PathLike[str], header: ImageHeader, factor: int) -> NDArray:
    """A panorama file decoded at ``1 / factor`` of its size, strip by strip: each output pixel the mean of a ``factor`` square.

    Integer samples are rounded to the nearest. Memory holds the output and a band of
    :data:`REDUCE_ROWS` output rows' source.

    Parameters
    ----------
    path : path-like
    header : ImageHeader
    factor : int
        Must divide both sides.

    Returns
    -------
    ndarray, shape (H / factor, W / factor[, C]), the file's dtype
    """
    factor = int(factor)
    if factor < 1 or header.width % factor or header.height % factor:
        raise ValueError(f"a factor of {factor} does not divide the {header.width} x {header.height} image")

    path = Path(path)
    if header.format != "npy":
        image = _vips_image(path)
        if factor > 1:  # averaged in float, rounded once (shrink alone rounds after each direction)
            kind = image.format
            image = image.cast("double").shrink(factor, factor)
            image = (image.rint() if kind in ("uchar", "ushort") else image).cast(kind)
        return np.asarray(image.numpy(), dtype=_VIPS_DTYPES[image.format]).reshape(image.height, image.width, *([image.bands] if image.bands > 1 else []))
    with open_on_disk(path, header) as disk:
        h, w = disk.shape[0] // factor, disk.shape[1] // factor
        out = np.empty((h, w, *disk.shape[2:]), disk.dtype)
        for r0 in range(0, h, REDUCE_ROWS):
            r1 = min(r0 + REDUCE_ROWS, h)
            # OpenCV's area resampling by a whole factor: each block's mean, rounded to the nearest (20x numpy's mean)
            band = cv2.resize(disk.rows(r0 * factor, r1 * factor), (w, r1 - r0), interpolation=cv2.INTER_AREA)
            out[r0:r1] = band.reshape(out[r0:r1].shape)
        return out


# --- writing in strips ---------------------------------------------------------------------

#: zlib's level for PNGs written in strips: 1, as OpenCV writes PNG by default.
PNG_LEVEL = 1
#: JPEG quality of outputs written in strips: 95, as OpenCV writes JPEG by default.
JPEG_QUALITY = 95
#: Rows per strip of the TIFF a JPEG's rows wait in (:func:`write_jpeg_strips`).
TIFF_ROWS = 16


def _png_chunk(fh: BinaryIO, kind: bytes, data: bytes) -> None:
    fh.write(struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data)))


def write_png_strips(fh: BinaryIO, shape: tuple[int, ...], dtype: np.dtype, strips: Iterable[NDArray], *, chunks: bytes = b"") -> None:
    """Write a PNG whose rows come in strips, holding one strip: 8 or 16 bits, gray, gray+alpha, RGB or RGBA.

    Each row is filtered by PNG's "Up" filter (its difference from the row above) and the
    stream deflated at :data:`PNG_LEVEL`; the pixels decode to exactly the strips given.

    Parameters
    ----------
    fh : binary file
    shape : tuple of int
        ``(H, W)`` or ``(H, W, C)``, C from 1 to 4.
    dtype : numpy.dtype
        uint8 or uint16.
    strips : iterable of ndarray
        Rows top to bottom, each ``(rows, W[, C])``.
    chunks : bytes
        Whole chunks written after IHDR (metadata: :func:`omniwidget.io.metadata.png_chunks`).
    """
    channels = shape[2] if len(shape) == 3 else 1
    dtype = np.dtype(dtype)
    if dtype not in (np.uint8, np.uint16) or channels not in (1, 2, 3, 4):
        raise ImageError(f"PNG holds 1 to 4 channels of 8 or 16 bits, not {channels} of {dtype}")
    fh.write(b"\x89PNG\r\n\x1a\n")
    color = {1: 0, 2: 4, 3: 2, 4: 6}[channels]
    _png_chunk(fh, b"IHDR", struct.pack(">IIBBBBB", shape[1], shape[0], 8 * dtype.itemsize, color, 0, 0, 0))
    fh.write(chunks)
    deflate = zlib.compressobj(PNG_LEVEL)
    above = np.zeros(shape[1] * channels * dtype.itemsize, np.uint8)
    for strip in strips:
        rows = np.ascontiguousarray(strip, dtype.newbyteorder(">")).reshape(len(strip), -1).view(np.uint8)
        filtered = np.empty((len(rows), rows.shape[1] + 1), np.uint8)
        filtered[:, 0] = 2  # "Up"
        np.subtract(rows, np.concatenate([above[None], rows[:-1]]), out=filtered[:, 1:])
        if len(rows):
            above = rows[-1].copy()
        if data := deflate.compress(filtered.tobytes()):
            _png_chunk(fh, b"IDAT", data)
    _png_chunk(fh, b"IDAT", deflate.flush())
    _png_chunk(fh, b"IEND", b"")


def row_blocks(strips: Iterable[NDArray], rows: int) -> Iterator[NDArray]:
    """The rows of ``strips`` (any rows each) in blocks of ``rows`` rows, the last with what is left."""
    held: list[NDArray] = []
    count = 0
    for strip in strips:
        held.append(strip)
        count += len(strip)
        if count >= rows:
            joined = np.concatenate(held)
            full = len(joined) // rows * rows
            yield from (joined[r : r + rows] for r in range(0, full, rows))
            held, count = [joined[full:]], len(joined) - full
    if count:
        yield np.concatenate(held)


def write_jpeg_strips(path: str | os.PathLike[str], shape: tuple[int, ...], strips: Iterable[NDArray], *, segments: bytes = b"") -> None:
    """Write a JPEG (quality :data:`JPEG_QUALITY`, chroma 4:2:0 as OpenCV) whose rows come in strips, holding a few of them.

    The strips go into an uncompressed TIFF beside ``path`` (as they come), which libvips
    then reads strip by strip as it encodes the JPEG; the TIFF is removed at the end.

    Parameters
    ----------
    path : path-like
        Where to write it (the caller makes it whole or absent).
    shape : tuple of int
        ``(H, W)`` or ``(H, W, 3)``, uint8.
    strips : iterable of ndarray
        Rows top to bottom, uint8.
    segments : bytes
        Whole JPEG segments put after SOI and JFIF's APP0 (metadata:
        :func:`omniwidget.io.metadata.jpeg_segments`): libvips' JPEG is copied once more
        with them, block by block.
    """
    path = Path(path)
    channels = shape[2] if len(shape) == 3 else 1
    if channels not in (1, 3):
        raise ImageError(f"JPEG holds gray or RGB, not {channels} channels")
    check_free_disk(path.parent, math.prod(shape), f"{path}: the JPEG's rows, held on disk while it is encoded,")
    fd, name = tempfile.mkstemp(prefix=".omniwidget-rows-", suffix=".tif", dir=path.parent)
    os.close(fd)
    try:
        photometric = "rgb" if channels == 3 else "minisblack"
        blocks = row_blocks(strips, TIFF_ROWS)
        tifffile.imwrite(name, blocks, shape=shape, dtype=np.uint8, photometric=photometric, rowsperstrip=TIFF_ROWS, bigtiff=True)
        encoded = Path(name).with_suffix(".jpg") if segments else path
        try:
            pyvips.Image.new_from_file(name, access="sequential").jpegsave(str(encoded), Q=JPEG_QUALITY, subsample_mode="on")
        except pyvips.Error as exc:
            raise ImageError(f"{path}: libvips could not encode the JPEG ({str(exc).strip().splitlines()[0]})") from None
        if segments:
            with open(encoded, "rb") as src, open(path, "wb") as dst:
                head = src.read(1 << 16)
                at = metadata.jpeg_metadata_offset(head)
                dst.write(head[:at] + segments + head[at:])
                shutil.copyfileobj(src, dst, 1 << 22)
    finally:
        Path(name).unlink(missing_ok=True)
        Path(name).with_suffix(".jpg").unlink(missing_ok=True)
