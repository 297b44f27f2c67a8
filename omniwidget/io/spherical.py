"""Spherical-video metadata in MP4 and QuickTime files: read it, write it.

A 360° video says it is one with the boxes of Google's Spherical Video V2 RFC
(https://github.com/google/spatial-media/blob/master/docs/spherical-video-v2-rfc.md):
``st3d`` (stereo mode) and ``sv3d`` (projection: ``svhd``, then ``proj`` holding ``prhd``,
the pose, and ``equi``, ``cbmp`` or ``mshp``) inside the video track's sample entry
(``moov/trak/mdia/minf/stbl/stsd/avc1``, say). Older files carry version 1 instead: XMP
text in a ``uuid`` box of the video ``trak`` (``<GSpherical:ProjectionType>``...). FFmpeg reads
both and shows them as the stream side data "Spherical Mapping" (``ffprobe -show_streams``).

FFmpeg's MP4 muxer writes ``sv3d`` only from stream side data set through its C API
(``-strict unofficial``); PyAV exposes no way to set it. :func:`write_spherical` therefore
writes the boxes itself into a finished file: it adds 13 + 91 bytes to the sample entry
and version 1's XMP ``uuid`` box to the video ``trak`` (some players read only version 1),
grows the sizes of the boxes around them, and moves the media data's chunk offsets
(``stco``, ``co64``) when ``moov`` comes before it. Only these standard boxes are touched.
"""

from __future__ import annotations

import os
import re
import struct
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

from .._checks import require_regular_file
from ..errors import NotRegularFileError, VideoError

__all__ = ["EQUIRECTANGULAR", "Spherical", "check_mp4_structure", "read_spherical", "spherical_boxes", "v1_box", "write_spherical"]

#: Stereo modes of the ``st3d`` box, by their number.
STEREO_MODES = ("mono", "top-bottom", "left-right", "custom")
#: The ``uuid`` of version 1's XMP box.
V1_UUID = bytes.fromhex("ffcc8263f8554a938814587a02521fdd")
#: Boxes that hold only boxes (and ``stsd``, which holds sample entries after 8 bytes).
_CONTAINERS = {b"moov", b"trak", b"mdia", b"minf", b"stbl", b"edts", b"dinf", b"udta", b"sv3d", b"proj"}
#: Bytes of a visual sample entry's own fields, after its 8-byte header, before its boxes.
_VISUAL_ENTRY_FIELDS = 78


@dataclass(frozen=True)
class Spherical:
    """What a video's spherical metadata says.

    Attributes
    ----------
    projection : str
        ``"equirectangular"``, ``"cubemap"`` or ``"mesh"``.
    stereo : str
        ``"mono"``, ``"top-bottom"`` (left eye on top), ``"left-right"`` or ``"custom"``.
    yaw, pitch, roll : float
        The pose of the sphere (``prhd``), degrees; the projection is turned by it on display.
    bounds : tuple of 4 floats
        ``(top, bottom, left, right)``: the share of the full equirectangular image cropped
        away on each side (``equi``), 0 for a full panorama.
    source : str
        Where it was read: ``"sv3d"``, ``"xmp"`` (version 1), ``"side data"`` (what FFmpeg
        decoded, for other containers), or ``""`` for metadata made here.
    """

    projection: str = "equirectangular"
    stereo: str = "mono"
    yaw: float = 0.0
    pitch: float = 0.0
    roll: float = 0.0
    bounds: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)
    source: str = ""

    @property
    def full_panorama(self) -> bool:
        """A mono equirectangular image of the whole sphere: what the warp reads and writes."""
        return self.projection == "equirectangular" and self.stereo == "mono" and not any(self.bounds)

    def describe(self) -> str:
        """A few words for a person, e.g. ``"equirectangular, mono"`` or ``"cubemap, top-bottom stereo"``."""
        parts = [self.projection, "mono" if self.stereo == "mono" else f"{self.stereo} stereo"]
        if any(self.bounds):
            parts.append("cropped " + "/".join(f"{b:.3g}" for b in self.bounds) + " (top/bottom/left/right)")
        if self.yaw or self.pitch or self.roll:
            parts.append(f"pose yaw {self.yaw:g}°, pitch {self.pitch:g}°, roll {self.roll:g}°")
        return ", ".join(parts)


#: Plain equirectangular mono metadata: what ``--spherical`` writes for a video without any.
EQUIRECTANGULAR = Spherical()


# --- boxes -------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Box:
    kind: bytes
    start: int  # offset of the box's first byte
    header: int  # 8, or 16 with a 64-bit size
    end: int  # offset after its last byte


def _boxes(data: bytes | bytearray | memoryview, start: int, end: int) -> Iterator[_Box]:
    """The boxes between ``start`` and ``end``; a VideoError if one runs past ``end``."""
    offset = start
    while offset + 8 <= end:
        size, kind = struct.unpack_from(">I4s", data, offset)
        header = 8
        if size == 1:
            if offset + 16 > end:
                raise VideoError(f"the {kind.decode('latin-1')!r} box is cut short")
            size = struct.unpack_from(">Q", data, offset + 8)[0]
            header = 16
        elif size == 0:
            size = end - offset
        if size < header or offset + size > end:
            raise VideoError(f"the {kind.decode('latin-1')!r} box at byte {offset} runs past the end of its container")
        yield _Box(kind, offset, header, offset + size)
        offset += size


def _child(data: bytes | bytearray | memoryview, box: _Box, kind: bytes, skip: int = 0) -> _Box | None:
    return next((b for b in _boxes(data, box.start + box.header + skip, box.end) if b.kind == kind), None)


def _video_traks(moov: bytes, box: _Box) -> Iterator[_Box]:
    """The ``trak`` boxes of ``moov`` whose handler is ``vide``."""
    for trak in _boxes(moov, box.start + box.header, box.end):
        if trak.kind != b"trak":
            continue
        mdia = _child(moov, trak, b"mdia")
        hdlr = _child(moov, mdia, b"hdlr") if mdia is not None else None
        if hdlr is not None and moov[hdlr.start + hdlr.header + 8 : hdlr.start + hdlr.header + 12] == b"vide":
            yield trak


def _sample_entry_path(moov: bytes, trak: _Box) -> list[_Box] | None:
    """``[trak, mdia, minf, stbl, stsd, entry]`` of a video track, or None if a box is missing."""
    path = [trak]
    for kind in (b"mdia", b"minf", b"stbl", b"stsd"):
        found = _child(moov, path[-1], kind)
        if found is None:
            return None
        path.append(found)
    entry = next(_boxes(moov, path[-1].start + path[-1].header + 8, path[-1].end), None)
    return None if entry is None else [*path, entry]


def _entry_children(moov: bytes, entry: _Box) -> list[_Box]:
    return list(_boxes(moov, entry.start + entry.header + _VISUAL_ENTRY_FIELDS, entry.end))


def _top_level(path: Path) -> tuple[list[_Box], int]:
    """The file's top-level boxes (read from their headers only) and its size."""
    size = path.stat().st_size
    boxes = []
    with path.open("rb") as fh:
        offset = 0
        while offset + 8 <= size:
            fh.seek(offset)
            head = fh.read(16)
            length, kind = struct.unpack_from(">I4s", head)
            header = 8
            if length == 1:
                length, header = struct.unpack_from(">Q", head, 8)[0], 16
            elif length == 0:
                length = size - offset
            if length < header or offset + length > size:
                raise VideoError(
                    f"the file looks truncated (its {kind.decode('latin-1')!r} box runs {offset + length - size} bytes "
                    "past the end of the file); was it copied or downloaded whole?"
                )
            boxes.append(_Box(kind, offset, header, offset + length))
            offset += length
    return boxes, size


def _regular(path: Path) -> None:
    """A VideoError for a FIFO or a device, which opening would wait on or never finish reading."""
    try:
        require_regular_file(path, "video")
    except NotRegularFileError as exc:
        raise VideoError(str(exc)) from None


def _read_moov(path: Path) -> tuple[list[_Box], _Box, bytes] | None:
    """The top-level boxes, ``moov`` and its bytes; None when the file is no MP4/QuickTime file or has no ``moov``."""
    _regular(path)
    with path.open("rb") as fh:
        head = fh.read(12)
    if len(head) < 8 or head[4:8] not in (b"ftyp", b"moov", b"mdat", b"free", b"wide", b"skip", b"pnot", b"uuid"):
        return None
    boxes, _ = _top_level(path)
    moov = next((b for b in boxes if b.kind == b"moov"), None)
    if moov is None:
        return None
    with path.open("rb") as fh:
        fh.seek(moov.start)
        data = fh.read(moov.end - moov.start)
    return boxes, _Box(b"moov", 0, moov.header, len(data)), data


def check_mp4_structure(path: str | os.PathLike[str]) -> None:
    """Refuse an MP4 or QuickTime file whose top-level boxes run past its end (a file cut short).

    Other files pass unread (FFmpeg judges them).

    Raises
    ------
    VideoError
        Saying which box is cut short, without the file name (the caller adds it).
    """
    path = Path(path)
    _regular(path)
    with path.open("rb") as fh:
        head = fh.read(12)
    if len(head) >= 8 and head[4:8] in (b"ftyp", b"moov", b"mdat"):
        _top_level(path)


# --- reading ---------------------------------------------------------------------------------------


def _fixed(value: int, bits: int) -> float:
    return value / float(1 << bits)


def _parse_sv3d(moov: bytes, sv3d: _Box, stereo: str) -> Spherical | None:
    proj = _child(moov, sv3d, b"proj")
    if proj is None:
        return None
    pose = (0.0, 0.0, 0.0)
    projection, bounds = None, (0.0, 0.0, 0.0, 0.0)
    for box in _boxes(moov, proj.start + proj.header, proj.end):
        body = box.start + box.header + 4  # the full box's version and flags
        if box.kind == b"prhd" and box.end - body >= 12:
            yaw, pitch, roll = struct.unpack_from(">iii", moov, body)
            pose = (_fixed(yaw, 16), _fixed(pitch, 16), _fixed(roll, 16))
        elif box.kind == b"equi" and box.end - body >= 16:
            top, bottom, left, right = struct.unpack_from(">IIII", moov, body)
            projection, bounds = "equirectangular", (_fixed(top, 32), _fixed(bottom, 32), _fixed(left, 32), _fixed(right, 32))
        elif box.kind == b"cbmp":
            projection = "cubemap"
        elif box.kind == b"mshp":
            projection = "mesh"
    if projection is None:
        return None
    return Spherical(projection, stereo, *pose, bounds=bounds, source="sv3d")


_XMP_TAG = re.compile(rb"<GSpherical:(\w+)>\s*([^<]*?)\s*</GSpherical:\1>", re.IGNORECASE)


def _parse_v1(xml: bytes) -> Spherical | None:
    """Version 1's XMP: ``Spherical`` and ``ProjectionType`` must say so; stereo mode, pose and crop are read when there."""
    tags = {k.decode("latin-1").lower(): v.decode("utf-8", "replace") for k, v in _XMP_TAG.findall(xml)}
    if tags.get("spherical", "").lower() != "true" or tags.get("projectiontype", "").lower() != "equirectangular":
        return None
    stereo = {"top-bottom": "top-bottom", "left-right": "left-right"}.get(tags.get("stereomode", "mono").lower(), "mono")

    def number(key: str, default: float = 0.0) -> float:
        try:
            return float(tags.get(key.lower(), default))
        except ValueError:
            return default

    bounds = (0.0, 0.0, 0.0, 0.0)
    full_w, full_h = number("FullPanoWidthPixels"), number("FullPanoHeightPixels")
    crop_w, crop_h = number("CroppedAreaImageWidthPixels", full_w), number("CroppedAreaImageHeightPixels", full_h)
    left, top = number("CroppedAreaLeftPixels"), number("CroppedAreaTopPixels")
    if full_w > 0 and full_h > 0 and 0 < crop_w <= full_w and 0 < crop_h <= full_h:
        bounds = (top / full_h, max(0.0, (full_h - top - crop_h) / full_h), left / full_w, max(0.0, (full_w - left - crop_w) / full_w))
    pose = (number("PoseHeadingDegrees"), number("PosePitchDegrees"), number("PoseRollDegrees"))
    return Spherical("equirectangular", stereo, *pose, bounds=bounds, source="xmp")


def read_spherical(path: str | os.PathLike[str]) -> Spherical | None:
    """The spherical metadata of an MP4 or QuickTime file's first video track.

    Version 2 (``sv3d``, ``st3d``) is read first, then version 1 (the XMP ``uuid`` box).

    Parameters
    ----------
    path : path-like

    Returns
    -------
    Spherical or None
        None when the file has none, or is not an MP4/QuickTime file (Matroska and WebM keep
        theirs elsewhere: :func:`omniwidget.io.video.probe_video` asks FFmpeg for those).

    Raises
    ------
    VideoError
        If the file's boxes are cut short or overlap, or it is a FIFO or a device.
    OSError
        If it cannot be read.
    """
    found = _read_moov(Path(path))
    if found is None:
        return None
    _, moov_box, moov = found
    for trak in _video_traks(moov, moov_box):
        entry_path = _sample_entry_path(moov, trak)
        if entry_path is not None:
            children = {b.kind: b for b in _entry_children(moov, entry_path[-1])}
            stereo = "mono"
            if b"st3d" in children:
                st3d = children[b"st3d"]
                mode = moov[st3d.start + st3d.header + 4] if st3d.end - st3d.start > st3d.header + 4 else 0
                stereo = STEREO_MODES[mode] if mode < len(STEREO_MODES) else "custom"
            if b"sv3d" in children:
                parsed = _parse_sv3d(moov, children[b"sv3d"], stereo)
                if parsed is not None:
                    return parsed
        for box in _boxes(moov, trak.start + trak.header, trak.end):
            if box.kind == b"uuid" and moov[box.start + box.header : box.start + box.header + 16] == V1_UUID:
                parsed = _parse_v1(moov[box.start + box.header + 16 : box.end])
                if parsed is not None:
                    return parsed
        break  # the first video track only
    return None


# --- writing ---------------------------------------------------------------------------------------


def _box(kind: bytes, payload: bytes) -> bytes:
    return struct.pack(">I4s", 8 + len(payload), kind) + payload


def _full_box(kind: bytes, payload: bytes) -> bytes:
    return _box(kind, b"\0\0\0\0" + payload)


def spherical_boxes(spherical: Spherical, metadata_source: str = "omniwidget") -> bytes:
    """The ``st3d`` and ``sv3d`` boxes of Spherical Video V2 for ``spherical``, as bytes.

    Parameters
    ----------
    spherical : Spherical
        An equirectangular projection (the only one written here).
    metadata_source : str
        The ``svhd`` box's text: the tool that wrote the metadata.

    Returns
    -------
    bytes
        ``st3d`` (13 bytes) then ``sv3d`` (``svhd``, ``proj`` with ``prhd`` and ``equi``).
    """
    if spherical.projection != "equirectangular":
        raise ValueError(f"only equirectangular spherical metadata is written, not {spherical.projection!r}")
    stereo = STEREO_MODES.index(spherical.stereo) if spherical.stereo in STEREO_MODES else 0

    def fixed(value: float, bits: int, signed: bool) -> int:
        scaled = round(value * (1 << bits))
        return max(-(1 << 31), min(scaled, (1 << 31) - 1)) if signed else max(0, min(scaled, (1 << 32) - 1))

    prhd = _full_box(b"prhd", struct.pack(">iii", *(fixed(v, 16, True) for v in (spherical.yaw, spherical.pitch, spherical.roll))))
    equi = _full_box(b"equi", struct.pack(">IIII", *(fixed(v, 32, False) for v in spherical.bounds)))
    svhd = _full_box(b"svhd", metadata_source.encode("utf-8") + b"\0")
    return _full_box(b"st3d", bytes([stereo])) + _box(b"sv3d", svhd + _box(b"proj", prhd + equi))


def v1_box(spherical: Spherical, software: str = "omniwidget") -> bytes:
    """Version 1's ``uuid`` box: the ``<rdf:SphericalVideo>`` XMP of Google's Spherical Video RFC, for players that read only it.

    Version 1 has no pose and gives a crop only in pixels: the projection, the stereo mode,
    stitched and the software are written (version 2's boxes carry the rest).
    """
    stereo = spherical.stereo if spherical.stereo in ("mono", "top-bottom", "left-right") else "mono"
    xml = (
        '<?xml version="1.0"?><rdf:SphericalVideo xmlns:rdf="http://www.w3.org/1999/02/22-rdf-syntax-ns#" '
        'xmlns:GSpherical="http://ns.google.com/videos/1.0/spherical/">'
        "<GSpherical:Spherical>true</GSpherical:Spherical><GSpherical:Stitched>true</GSpherical:Stitched>"
        f"<GSpherical:StitchingSoftware>{software}</GSpherical:StitchingSoftware>"
        "<GSpherical:ProjectionType>equirectangular</GSpherical:ProjectionType>"
        f"<GSpherical:StereoMode>{stereo}</GSpherical:StereoMode></rdf:SphericalVideo>"
    )
    return _box(b"uuid", V1_UUID + xml.encode("utf-8"))


def _replace_v1(moov: bytearray, spherical: Spherical) -> int:
    """Put version 1's ``uuid`` box at the end of the first video ``trak`` of ``moov`` (held from byte 0), replacing any; the size change."""
    moov_box = next(_boxes(moov, 0, len(moov)))
    trak = next(_video_traks(bytes(moov), moov_box))
    stale = [b for b in _boxes(moov, trak.start + trak.header, trak.end) if b.kind == b"uuid" and moov[b.start + b.header : b.start + b.header + 16] == V1_UUID]
    for box in reversed(stale):
        del moov[box.start : box.end]
    removed = sum(b.end - b.start for b in stale)
    new = v1_box(spherical)
    moov[trak.end - removed : trak.end - removed] = new
    delta = len(new) - removed
    for box in (moov_box, trak):
        _grow(moov, box, delta)
    return delta


def _grow(moov: bytearray, box: _Box, delta: int) -> None:
    """Add ``delta`` to the size field of ``box`` (32- or 64-bit)."""
    if box.header == 16:
        struct.pack_into(">Q", moov, box.start + 8, box.end - box.start + delta)
    elif struct.unpack_from(">I", moov, box.start)[0] != 0:  # 0: "to the end of the file", still true
        size = box.end - box.start + delta
        if size >= 1 << 32:
            raise VideoError("the moov box would outgrow its 32-bit size")
        struct.pack_into(">I", moov, box.start, size)


def _shift_chunk_offsets(moov: bytearray, moov_box: _Box, after: int, delta: int) -> None:
    """Move every chunk offset at or after ``after`` (a file offset) by ``delta``, in all tracks' ``stco``/``co64``."""

    def visit(start: int, end: int) -> None:
        for box in _boxes(moov, start, end):
            if box.kind in (b"trak", b"mdia", b"minf", b"stbl"):
                visit(box.start + box.header, box.end)
            elif box.kind in (b"stco", b"co64"):
                body = box.start + box.header + 4
                (count,) = struct.unpack_from(">I", moov, body)
                wide = box.kind == b"co64"
                fmt, step = (">Q", 8) if wide else (">I", 4)
                if body + 4 + count * step > box.end:
                    raise VideoError(f"the {box.kind.decode()} box is shorter than its entry count says")
                for k in range(count):
                    at = body + 4 + k * step
                    (value,) = struct.unpack_from(fmt, moov, at)
                    if value >= after:
                        if not wide and value + delta >= 1 << 32:
                            raise VideoError("a chunk offset would outgrow its 32-bit stco entry")
                        struct.pack_into(fmt, moov, at, value + delta)

    visit(moov_box.start + moov_box.header, moov_box.end)


def write_spherical(path: str | os.PathLike[str], spherical: Spherical = EQUIRECTANGULAR, *, in_place: bool = False) -> None:
    """Write ``spherical`` as Spherical Video V2 boxes and V1 XMP into an MP4 or QuickTime file's first video track.

    Any ``st3d`` and ``sv3d`` already in its sample entry are replaced, and any version 1
    ``uuid`` box of its ``trak`` (:func:`v1_box`: some players read only version 1);
    nothing else changes but the sizes of the boxes around them and, when ``moov`` comes
    before the media data, the chunk offsets.

    Parameters
    ----------
    path : path-like
        An MP4/QuickTime file, not fragmented.
    spherical : Spherical
        Equirectangular; by default a full mono panorama with no pose.
    in_place : bool
        Rewrite the file where it is (quick when ``moov`` is last, as FFmpeg writes it, but a
        crash midway damages it: for a file not yet handed over, such as a temporary file).
        By default a new file is written next to it and renamed over it, so ``path`` is whole
        at every moment.

    Raises
    ------
    VideoError
        If the file is no MP4/QuickTime file, has no video track, is fragmented, or its
        boxes are damaged.
    OSError
        If it cannot be read or written.
    """
    path = Path(path)
    found = _read_moov(path)
    if found is None:
        raise VideoError(f"{path}: not an MP4 or QuickTime file with a moov box; spherical metadata cannot be written")
    top, moov_box, old = found
    if any(b.kind == b"moof" for b in top):
        raise VideoError(f"{path}: a fragmented MP4 file; spherical metadata is written only into plain MP4 files")
    file_moov = next(b for b in top if b.kind == b"moov")
    moov = bytearray(old)
    entry_path = next((p for t in _video_traks(old, moov_box) if (p := _sample_entry_path(old, t)) is not None), None)
    if entry_path is None:
        raise VideoError(f"{path}: no video track with a sample entry; spherical metadata cannot be written")
    entry = entry_path[-1]
    stale = [b for b in _entry_children(old, entry) if b.kind in (b"st3d", b"sv3d")]
    new = spherical_boxes(spherical)
    for box in reversed(stale):  # remove from the back so the earlier offsets stay valid
        del moov[box.start : box.end]
    removed = sum(b.end - b.start for b in stale)
    moov[entry.end - removed : entry.end - removed] = new
    delta = len(new) - removed
    for box in (moov_box, *entry_path):  # every box around the new ones grows (their starts are before the edit)
        _grow(moov, box, delta)
    delta += _replace_v1(moov, spherical)
    moved = file_moov.end < max(b.end for b in top)  # media data after moov moves by delta
    if moved and delta:
        _shift_chunk_offsets(moov, _Box(b"moov", 0, moov_box.header, len(moov)), file_moov.end, delta)
    if in_place and not moved:
        with path.open("r+b") as fh:
            fh.seek(file_moov.start)
            fh.write(moov)
            fh.truncate()
        return
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as out, path.open("rb") as src:
            _copy(src, out, file_moov.start)
            out.write(moov)
            src.seek(file_moov.end)
            _copy(src, out, None)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _copy(src: BinaryIO, dst: BinaryIO, count: int | None, chunk: int = 1 << 22) -> None:
    """Copy ``count`` bytes (or the rest) from one open binary file to another."""
    left = count
    while left is None or left > 0:
        block = src.read(chunk if left is None else min(chunk, left))
        if not block:
            break
        dst.write(block)
        if left is not None:
            left -= len(block)
