"""A panorama's metadata carried to the outputs: Photo Sphere XMP (GPano), EXIF and the ICC profile.

Cameras and stitchers write Google's Photo Sphere XMP (``GPano:ProjectionType``, the full
and cropped sizes, the pose) into the file; photo sites and viewers (Photo Sphere Viewer,
Pannellum, Kuula, Facebook) rely on it. :func:`read_metadata` reads the three blocks with
Pillow (its format plugins, which parse a file's headers without decoding its pixels);
:func:`output_metadata` brings them up to date for an output (its size, its pose, EXIF
orientation 1: outputs are written turned as shown); :func:`with_metadata` adds them to
the bytes an encoder already made (JPEG APP1/APP2 segments, PNG chunks, WebP chunks), so
the pixels are exactly those written without them.

The EXIF block is carried byte for byte but for the values changed in place (orientation,
pixel sizes) and the thumbnail's link, which is cut (it shows the input): re-serialising it
(Pillow's ``Exif.tobytes``) would move the maker notes, whose internal offsets several
makers write as absolute, and drop entries Pillow does not know.

GPano pose convention
---------------------
``PosePitchDegrees`` and ``PoseRollDegrees`` are written as Pannellum reads them (its
``horizonPitch`` and ``horizonRoll``): a viewer shows the direction ``d`` of the level world
where the panorama's pixels have ``M d``, ``M = R_y(pitch) R_x(roll)`` in the axes
(forward, 90° to the right, up). That is :func:`omniwidget.detect.level.tilt_rotation` in
:mod:`omniwidget.sphere.coords`' axes (longitude grows to the right), so the pitch and roll
are :class:`omniwidget.detect.level.Level`'s as they are: a positive pitch sees the zenith
towards the panorama's centre (longitude 0), a positive roll towards longitude -90.
"""

from __future__ import annotations

import io
import math
import re
import struct
import warnings
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any
from xml.etree import ElementTree

from .._lazy import lazy

if TYPE_CHECKING:
    from PIL import Image, JpegImagePlugin, PngImagePlugin, TiffImagePlugin, WebPImagePlugin
else:
    JpegImagePlugin = lazy("PIL.JpegImagePlugin")
    PngImagePlugin = lazy("PIL.PngImagePlugin")
    TiffImagePlugin = lazy("PIL.TiffImagePlugin")
    WebPImagePlugin = lazy("PIL.WebPImagePlugin")
    Image = lazy("PIL.Image")

__all__ = [
    "GPANO",
    "GPano",
    "Metadata",
    "Pose",
    "jpeg_metadata_offset",
    "jpeg_segments",
    "orientation",
    "output_metadata",
    "png_chunks",
    "read_metadata",
    "replace_xmp",
    "tiff_tags",
    "with_metadata",
    "with_xmp",
]

#: The Photo Sphere XMP namespace.
GPANO = "http://ns.google.com/photos/1.0/panorama/"
_RDF = "http://www.w3.org/1999/02/22-rdf-syntax-ns#"
_X = "adobe:ns:meta/"
_XMP_NOTE = "http://ns.adobe.com/xmp/note/"
_XMP_ID = b"http://ns.adobe.com/xap/1.0/\x00"
_XMP_EXTENDED_ID = b"http://ns.adobe.com/xmp/extension/\x00"
_ICC_ID = b"ICC_PROFILE\x00"
_EXIF_ID = b"Exif\x00\x00"
#: The most a JPEG segment holds after its length field.
_SEGMENT = 65533
#: The most of an ICC profile one APP2 segment holds (after its 14-byte header).
_ICC_CHUNK = _SEGMENT - 14


@dataclass(frozen=True)
class Pose:
    """The three GPano pose angles, degrees; None where unknown (not written).

    ``pitch`` and ``roll`` in Pannellum's convention (the module's docstring), which is
    :class:`omniwidget.detect.level.Level`'s; ``heading`` the compass heading of the
    image's centre.
    """

    heading: float | None = None
    pitch: float | None = None
    roll: float | None = None

    def as_dict(self) -> dict[str, float]:
        """The known angles under their GPano names (``PoseHeadingDegrees``, ...)."""
        names = {"PoseHeadingDegrees": self.heading, "PosePitchDegrees": self.pitch, "PoseRollDegrees": self.roll}
        return {k: float(v) for k, v in names.items() if v is not None}


@dataclass(frozen=True)
class GPano:
    """What a file's Photo Sphere XMP says about its geometry.

    Attributes
    ----------
    full_width, full_height : int
        The whole equirectangular panorama's size, pixels.
    cropped_width, cropped_height : int
        The part the file holds, pixels (the file's own size when it is not rescaled).
    left, top : int
        Where that part lies in the whole panorama, pixels from its top left corner.
    projection : str
        ``GPano:ProjectionType`` (only ``"equirectangular"`` is placed).
    pose : Pose
    """

    full_width: int
    full_height: int
    cropped_width: int
    cropped_height: int
    left: int = 0
    top: int = 0
    projection: str = "equirectangular"
    pose: Pose = Pose()

    @classmethod
    def full(cls, width: int, height: int, pose: Pose = Pose()) -> GPano:
        """A whole equirectangular panorama of ``width x height``."""
        return cls(width, height, width, height, 0, 0, "equirectangular", pose)

    @property
    def is_full(self) -> bool:
        """Whether the file holds the whole sphere."""
        return (self.cropped_width, self.cropped_height, self.left, self.top) == (self.full_width, self.full_height, 0, 0)

    def placement(self, width: int, height: int) -> tuple[int, int, int, int] | None:
        """Where an image of ``width x height`` carrying this XMP lies on the full sphere.

        Returns ``(full_width, full_height, left, top)`` in the image's own pixels (the XMP's
        scaled by ``width / cropped_width``, as when a file was resized after it was
        tagged), or None when it is not an equirectangular part of a 2:1 sphere that a
        whole number of pixels places (then the caller falls back to ``--fit``).
        """
        if self.projection.lower() != "equirectangular" or self.cropped_width <= 0 or self.cropped_height <= 0:
            return None
        sx, sy = width / self.cropped_width, height / self.cropped_height
        if abs(sx - sy) > 0.01 * max(sx, sy):
            return None
        values = [v * sx for v in (self.full_width, self.full_height, self.left, self.top)]
        if any(abs(v - round(v)) > 0.02 * max(1.0, sx) for v in values):
            return None
        full_w, full_h, left, top = (round(v) for v in values)
        if full_w != 2 * full_h or top < 0 or top + height > full_h or width > full_w or not 0 <= left < full_w:
            return None
        return full_w, full_h, left, top

    def properties(self) -> dict[str, str]:
        """The GPano properties written, by their names."""
        out = {
            "UsePanoramaViewer": "True",
            "ProjectionType": self.projection,
            "FullPanoWidthPixels": str(self.full_width),
            "FullPanoHeightPixels": str(self.full_height),
            "CroppedAreaImageWidthPixels": str(self.cropped_width),
            "CroppedAreaImageHeightPixels": str(self.cropped_height),
            "CroppedAreaLeftPixels": str(self.left),
            "CroppedAreaTopPixels": str(self.top),
        }
        out.update({k: _number(v) for k, v in self.pose.as_dict().items()})
        return out


def _number(value: float) -> str:
    """A pose angle as written: up to 4 decimals, no trailing zeros."""
    text = f"{value:.4f}".rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


@dataclass(frozen=True)
class Metadata:
    """A file's metadata blocks, as stored.

    Attributes
    ----------
    exif : bytes or None
        The EXIF block: a TIFF structure (without the ``Exif`` of a JPEG segment).
    icc : bytes or None
        The ICC profile.
    xmp : bytes or None
        The XMP packet (UTF-8).
    """

    exif: bytes | None = None
    icc: bytes | None = None
    xmp: bytes | None = None

    @property
    def gpano(self) -> GPano | None:
        """The Photo Sphere XMP's geometry, or None when the XMP has none that reads."""
        return _parse_gpano(self.xmp)

    @property
    def orientation(self) -> int:
        """The EXIF orientation, 1 to 8 (1 without one)."""
        return orientation(self.exif)


# --- reading ---------------------------------------------------------------------------------


def _pillow_image(data: bytes | Path) -> Any:
    """Pillow's image of a JPEG, PNG, WebP or TIFF file, its headers parsed, its pixels not decoded.

    The format plugin is called directly (not ``Image.open``): its decompression-bomb check
    would refuse the panoramas of hundreds of megapixels omniwidget reads on purpose, and no
    pixel is decoded here.
    """
    try:
        fh: Any = io.BytesIO(data) if isinstance(data, bytes) else open(data, "rb")  # noqa: SIM115 - closed by the caller via the image
        head = fh.read(16)
        fh.seek(0)
    except OSError:  # gone or unreadable since it was read: no metadata to carry, the pixels are still written
        return None
    plugin: Any
    if head[:3] == b"\xff\xd8\xff":
        plugin = JpegImagePlugin.JpegImageFile
    elif head[:8] == b"\x89PNG\r\n\x1a\n":
        plugin = PngImagePlugin.PngImageFile
    elif head[:4] == b"RIFF" and head[8:12] == b"WEBP":
        plugin = WebPImagePlugin.WebPImageFile
    elif head[:4] in (b"II*\x00", b"MM\x00*", b"II+\x00", b"MM\x00+"):
        plugin = TiffImagePlugin.TiffImageFile
    else:
        fh.close()
        return None
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # Pillow's "Corrupt EXIF data": what reads is read
            return plugin(fh)
    except Exception:  # noqa: BLE001 - a file Pillow cannot parse has no metadata we can carry
        fh.close()
        return None


def read_metadata(source: str | Path | bytes) -> Metadata:
    """The EXIF, ICC profile and XMP of a JPEG, PNG, WebP or TIFF file (an empty :class:`Metadata` for others).

    Parameters
    ----------
    source : path-like or bytes
        The file, or its bytes.

    Returns
    -------
    Metadata
        Read by Pillow; a block it cannot parse is None, and all are for a file that cannot
        be read (metadata never stops an output). A TIFF's own EXIF is its image directory,
        not a block that can be carried: None.
    """
    image = _pillow_image(source if isinstance(source, bytes) else Path(source))
    if image is None:
        return Metadata()
    with image, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        info = image.info
        exif = info.get("exif")
        if isinstance(exif, bytes) and exif.startswith(_EXIF_ID):
            exif = exif[len(_EXIF_ID) :]
        if image.format == "TIFF":
            exif = None
            xmp = image.tag_v2.get(700)
        else:
            xmp = info.get("xmp")
        if isinstance(xmp, str):
            xmp = xmp.encode("utf-8")
        icc = info.get("icc_profile")
        return Metadata(exif=exif or None, icc=icc or None, xmp=bytes(xmp) if xmp else None)


def orientation(exif: bytes | None) -> int:
    """The EXIF Orientation (1 to 8) of an EXIF block (with or without ``Exif``), read by Pillow; 1 if absent or malformed."""
    if not exif:
        return 1

    parsed = Image.Exif()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # "Corrupt EXIF data": what is readable is read, the rest ignored
            parsed.load(bytes(exif))
            value = parsed.get(0x0112)
    except Exception:  # noqa: BLE001 - a malformed block says nothing
        return 1
    return value if isinstance(value, int) and 1 <= value <= 8 else 1


_GPANO_INT = ("FullPanoWidthPixels", "FullPanoHeightPixels", "CroppedAreaImageWidthPixels", "CroppedAreaImageHeightPixels")


def _xmp_root(xmp: bytes) -> ElementTree.Element | None:
    text = xmp.decode("utf-8", "replace").lstrip("\ufeff")
    start = text.find("<x:xmpmeta")
    start = start if start >= 0 else text.find("<rdf:RDF")
    if start < 0:
        return None
    end_tag = "</x:xmpmeta>" if text.startswith("<x:xmpmeta", start) else "</rdf:RDF>"
    end = text.find(end_tag, start)
    if end < 0:
        return None
    try:
        return ElementTree.fromstring(text[start : end + len(end_tag)])
    except ElementTree.ParseError:
        return None


def _gpano_values(root: ElementTree.Element) -> dict[str, str]:
    """Every GPano property in an XMP tree, attribute or element form."""
    found: dict[str, str] = {}
    prefix = "{" + GPANO + "}"
    for element in root.iter():
        for key, value in element.attrib.items():
            if key.startswith(prefix):
                found[key[len(prefix) :]] = value.strip()
        if isinstance(element.tag, str) and element.tag.startswith(prefix) and element.text is not None:
            found[element.tag[len(prefix) :]] = element.text.strip()
    return found


def _parse_gpano(xmp: bytes | None) -> GPano | None:
    if not xmp:
        return None
    root = _xmp_root(xmp)
    if root is None:
        return None
    values = _gpano_values(root)
    if not values:
        return None

    def number(name: str) -> float | None:
        try:
            value = float(values[name])
        except (KeyError, ValueError):
            return None
        return value if math.isfinite(value) else None

    pose = Pose(number("PoseHeadingDegrees"), number("PosePitchDegrees"), number("PoseRollDegrees"))
    sizes = [number(name) for name in _GPANO_INT]
    if any(s is None or s <= 0 for s in sizes):
        return GPano(0, 0, 0, 0, projection=values.get("ProjectionType", ""), pose=pose)  # no geometry, a pose perhaps
    full_w, full_h, crop_w, crop_h = (round(s or 0) for s in sizes)
    left, top = round(number("CroppedAreaLeftPixels") or 0), round(number("CroppedAreaTopPixels") or 0)
    return GPano(full_w, full_h, crop_w, crop_h, left, top, values.get("ProjectionType", "equirectangular"), pose)


# --- bringing up to date ---------------------------------------------------------------------


def output_metadata(
    source: Metadata | None,
    width: int,
    height: int,
    *,
    gpano: bool = True,
    levelled: bool = False,
    pose: Pose | None = None,
) -> Metadata:
    """The metadata of an output of ``width x height`` made from a file with ``source``'s: kept, and made true.

    Parameters
    ----------
    source : Metadata or None
        The input's (None: an array without a file).
    width, height : int
        The output's size: a whole equirectangular sphere.
    gpano : bool
        Write the Photo Sphere XMP even when the input has none (the output is a whole
        sphere by construction). An input's own GPano is always brought up to date.
    levelled : bool
        The output's pixels are levelled: pitch and roll 0 (the heading kept).
    pose : Pose, optional
        The pose to write instead (``level --pose-only``); the angles it leaves None are kept.

    Returns
    -------
    Metadata
        EXIF with orientation 1 and the pixel sizes of the output (its thumbnail's link cut),
        the ICC profile as it is, the XMP with the GPano of a whole ``width x height`` sphere.
    """
    source = source or Metadata()
    old = source.gpano
    old_pose = old.pose if old is not None else Pose()
    new_pose = old_pose
    if levelled:
        new_pose = Pose(old_pose.heading, 0.0, 0.0)
    if pose is not None:
        new_pose = Pose(*(n if n is not None else o for n, o in zip((pose.heading, pose.pitch, pose.roll), (old_pose.heading, old_pose.pitch, old_pose.roll), strict=True)))
    xmp = source.xmp
    if old is not None or gpano:
        xmp = replace_xmp(source.xmp, GPano.full(width, height, new_pose))
    exif = _patched_exif(source.exif, width, height) if source.exif else None
    return Metadata(exif=exif, icc=source.icc, xmp=xmp)


def _registered_prefixes(xmp: bytes) -> None:
    """Keep the XMP's own namespace prefixes when the tree is written back."""
    text = xmp.decode("utf-8", "replace")
    for prefix, uri in re.findall(r'xmlns:([A-Za-z_][\w.-]*)\s*=\s*["\']([^"\']*)["\']', text):
        if not re.fullmatch(r"ns\d+", prefix):
            try:
                ElementTree.register_namespace(prefix, uri)
            except ValueError:
                continue


def replace_xmp(xmp: bytes | None, gpano: GPano) -> bytes:
    """An XMP packet: ``xmp``'s properties kept, its GPano ones replaced by ``gpano``'s (a new packet when it has none that parses).

    Extended XMP (``xmpNote:HasExtendedXMP``, in further JPEG segments) is not carried: its
    note is removed.
    """
    ElementTree.register_namespace("x", _X)
    ElementTree.register_namespace("rdf", _RDF)
    ElementTree.register_namespace("GPano", GPANO)
    root = _xmp_root(xmp) if xmp else None
    if root is not None and xmp is not None:
        _registered_prefixes(xmp)
        ElementTree.register_namespace("GPano", GPANO)
    if root is None:
        root = ElementTree.Element(f"{{{_X}}}xmpmeta")
        ElementTree.SubElement(root, f"{{{_RDF}}}RDF")
    rdf = root if root.tag == f"{{{_RDF}}}RDF" else root.find(f"{{{_RDF}}}RDF")
    if rdf is None:
        rdf = ElementTree.SubElement(root, f"{{{_RDF}}}RDF")
    prefix = "{" + GPANO + "}"
    for element in list(root.iter()):
        for key in [k for k in element.attrib if k.startswith(prefix) or k == f"{{{_XMP_NOTE}}}HasExtendedXMP"]:
            del element.attrib[key]
        for child in [c for c in element if isinstance(c.tag, str) and (c.tag.startswith(prefix) or c.tag == f"{{{_XMP_NOTE}}}HasExtendedXMP")]:
            element.remove(child)
    for old in [d for d in rdf if d.tag == f"{{{_RDF}}}Description" and not len(d) and set(d.attrib) <= {f"{{{_RDF}}}about"}]:
        rdf.remove(old)  # held only GPano properties
    description = ElementTree.SubElement(rdf, f"{{{_RDF}}}Description", {f"{{{_RDF}}}about": ""})
    for name, value in gpano.properties().items():
        description.set(prefix + name, value)
    body = ElementTree.tostring(root, encoding="unicode")
    if root.tag != f"{{{_X}}}xmpmeta":
        body = f'<x:xmpmeta xmlns:x="{_X}">{body}</x:xmpmeta>'
    return ('<?xpacket begin="\ufeff" id="W5M0MpCehiHzreSzNTczkc9d"?>' + body + '<?xpacket end="w"?>').encode("utf-8")


def _ifd_entries(blob: bytes, offset: int, e: str) -> list[tuple[int, int, int, int]] | None:
    """``(tag, type, count, where its value or its offset lies)`` of the directory at ``offset``, or None if it runs past the end."""
    if offset + 2 > len(blob):
        return None
    (count,) = struct.unpack_from(e + "H", blob, offset)
    if offset + 2 + 12 * count + 4 > len(blob):
        return None
    out = []
    for k in range(count):
        at = offset + 2 + 12 * k
        tag, kind, n = struct.unpack_from(e + "HHI", blob, at)
        out.append((tag, kind, n, at + 8))
    return out


def _patched_exif(exif: bytes, width: int, height: int) -> bytes:
    """``exif`` with orientation 1, the pixel sizes (IFD0's and the Exif directory's) set, the thumbnail's link cut: in place."""
    blob = bytearray(exif)
    if len(blob) < 8 or bytes(blob[:2]) not in (b"II", b"MM"):
        return bytes(exif)
    e = "<" if bytes(blob[:2]) == b"II" else ">"
    magic, ifd0 = struct.unpack_from(e + "HI", blob, 2)
    entries = _ifd_entries(bytes(blob), ifd0, e) if magic == 42 else None
    if entries is None:
        return bytes(exif)

    def put(kind: int, count: int, where: int, value: int) -> None:
        if count != 1:
            return
        if kind == 3 and value <= 0xFFFF:
            struct.pack_into(e + "H", blob, where, value)
        elif kind == 4:
            struct.pack_into(e + "I", blob, where, value)

    sizes = {0x0100: width, 0x0101: height, 0xA002: width, 0xA003: height}
    for tag, kind, count, where in entries:
        if tag == 0x0112:
            put(kind, count, where, 1)
        elif tag in sizes:
            put(kind, count, where, sizes[tag])
        elif tag == 0x8769 and kind in (4, 13) and count == 1:
            (sub,) = struct.unpack_from(e + "I", blob, where)
            for stag, skind, scount, swhere in _ifd_entries(bytes(blob), sub, e) or []:
                if stag in (0xA002, 0xA003):
                    put(skind, scount, swhere, sizes[stag])
    struct.pack_into(e + "I", blob, ifd0 + 2 + 12 * len(entries), 0)  # no IFD1: the thumbnail showed the input
    return bytes(blob)


# --- writing ---------------------------------------------------------------------------------


def jpeg_segments(metadata: Metadata) -> bytes:
    """The APP1 (EXIF, XMP) and APP2 (ICC profile, in as many chunks as it needs) segments of ``metadata``.

    A block too large for one segment is left out (EXIF over 64 KB; XMP over 64 KB, whose
    extended form is not written).
    """
    out = bytearray()
    if metadata.exif and len(_EXIF_ID) + len(metadata.exif) <= _SEGMENT:
        out += _segment(0xE1, _EXIF_ID + metadata.exif)
    if metadata.xmp and len(_XMP_ID) + len(metadata.xmp) <= _SEGMENT:
        out += _segment(0xE1, _XMP_ID + metadata.xmp)
    if metadata.icc:
        chunks = [metadata.icc[k : k + _ICC_CHUNK] for k in range(0, len(metadata.icc), _ICC_CHUNK)]
        if len(chunks) <= 255:
            for k, chunk in enumerate(chunks):
                out += _segment(0xE2, _ICC_ID + bytes([k + 1, len(chunks)]) + chunk)
    return bytes(out)


def _segment(code: int, payload: bytes) -> bytes:
    return bytes([0xFF, code]) + struct.pack(">H", len(payload) + 2) + payload


def _jpeg_header_end(data: bytes | bytearray) -> tuple[int, list[tuple[int, int, int]]]:
    """Where the segments after SOI and APP0 start, and every segment ``(code, start, end)`` before the scan."""
    i, n, found = 2, len(data), []
    after_app0 = 2
    while i + 4 <= n and data[i] == 0xFF:
        code = data[i + 1]
        if code == 0xFF:
            i += 1
            continue
        if code in (0xD8, 0x01) or 0xD0 <= code <= 0xD7:
            i += 2
            continue
        if code in (0xDA, 0xD9):
            break
        end = i + 2 + int.from_bytes(data[i + 2 : i + 4], "big")
        found.append((code, i, end))
        if code == 0xE0 and after_app0 == i:
            after_app0 = end
        i = end
    return after_app0, found


def jpeg_metadata_offset(head: bytes) -> int:
    """Where metadata segments go in a JPEG whose first bytes are ``head``: after SOI and JFIF's APP0."""
    return _jpeg_header_end(head)[0]


def _is_metadata_segment(data: bytes | bytearray, code: int, start: int, end: int, xmp_only: bool) -> bool:
    body = bytes(data[start + 4 : min(end, start + 4 + 40)])
    if code == 0xE1 and (body.startswith(_XMP_ID) or body.startswith(_XMP_EXTENDED_ID)):
        return True
    if xmp_only:
        return False
    return (code == 0xE1 and body.startswith(_EXIF_ID)) or (code == 0xE2 and body.startswith(_ICC_ID))


def _jpeg_with(data: bytes, segments: bytes, *, xmp_only: bool = False) -> bytes:
    """A JPEG's bytes with its metadata segments (only its XMP with ``xmp_only``) replaced by ``segments``, after SOI and APP0."""
    at, found = _jpeg_header_end(data)
    stale = [(s, e) for code, s, e in found if _is_metadata_segment(data, code, s, e, xmp_only)]
    parts, last = [data[:at], segments], at
    for s, e in stale:
        if s >= at:
            parts.append(data[last:s])
            last = e
    parts.append(data[last:])
    return b"".join(parts)


def _png_chunk(kind: bytes, body: bytes) -> bytes:
    return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))


def png_chunks(metadata: Metadata) -> bytes:
    """The ``iCCP``, ``eXIf`` and ``iTXt`` (``XML:com.adobe.xmp``) chunks of ``metadata``, to follow IHDR."""
    out = b""
    if metadata.icc:
        out += _png_chunk(b"iCCP", b"ICC profile\x00\x00" + zlib.compress(metadata.icc))
    if metadata.exif:
        out += _png_chunk(b"eXIf", metadata.exif)
    if metadata.xmp:
        out += _png_chunk(b"iTXt", b"XML:com.adobe.xmp\x00\x00\x00\x00\x00" + metadata.xmp)
    return out


def _png_with(data: bytes, chunks: bytes, *, xmp_only: bool = False) -> bytes:
    """A PNG's bytes with its metadata chunks (only its XMP with ``xmp_only``) replaced by ``chunks``, after IHDR."""
    parts, i = [data[:8]], 8
    inserted = False
    while i + 8 <= len(data):
        length = int.from_bytes(data[i : i + 4], "big")
        kind = data[i + 4 : i + 8]
        end = i + 12 + length
        xmp = kind == b"iTXt" and data[i + 8 : i + 26] == b"XML:com.adobe.xmp\x00"
        stale = xmp or (not xmp_only and kind in (b"iCCP", b"eXIf", b"sRGB"))
        if kind == b"sRGB" and xmp_only:
            stale = False
        if not stale:
            parts.append(data[i:end])
        if kind == b"IHDR" and not inserted:
            parts.append(chunks)
            inserted = True
        i = end
    parts.append(data[i:])
    return b"".join(parts)


def _webp_with(data: bytes, metadata: Metadata, *, xmp_only: bool = False) -> bytes:
    """A WebP's bytes in the extended format (``VP8X``) with ``metadata``'s chunks (only its XMP with ``xmp_only``)."""
    chunks: list[tuple[bytes, bytes]] = []
    i, end = 12, min(len(data), 8 + int.from_bytes(data[4:8], "little"))
    while i + 8 <= end:
        kind, length = data[i : i + 4], int.from_bytes(data[i + 4 : i + 8], "little")
        chunks.append((kind, data[i + 8 : i + 8 + length]))
        i += 8 + length + (length & 1)
    kinds = {k for k, _ in chunks}
    vp8x = next((body for k, body in chunks if k == b"VP8X"), None)
    if vp8x is not None:
        flags, canvas = vp8x[0], vp8x[4:10]
    else:
        flags, canvas = 0, b""
        for kind, body in chunks:
            if kind == b"VP8 " and len(body) >= 10:
                w, h = (struct.unpack_from("<H", body, 6)[0] & 0x3FFF), (struct.unpack_from("<H", body, 8)[0] & 0x3FFF)
                canvas = (w - 1).to_bytes(3, "little") + (h - 1).to_bytes(3, "little")
            elif kind == b"VP8L" and len(body) >= 5:
                bits = int.from_bytes(body[1:5], "little")
                w, h, alpha = (bits & 0x3FFF) + 1, ((bits >> 14) & 0x3FFF) + 1, (bits >> 28) & 1
                canvas = (w - 1).to_bytes(3, "little") + (h - 1).to_bytes(3, "little")
                flags |= 0x10 if alpha else 0
        if not canvas:
            return data
    flags |= 0x10 if b"ALPH" in kinds else 0
    keep = [(k, b) for k, b in chunks if k not in (b"VP8X", b"XMP ") and (xmp_only or k not in (b"ICCP", b"EXIF"))]
    icc = next((b for k, b in chunks if k == b"ICCP"), None) if xmp_only else metadata.icc
    exif = next((b for k, b in chunks if k == b"EXIF"), None) if xmp_only else metadata.exif
    flags = (flags & ~0x2C) | (0x20 if icc else 0) | (0x08 if exif else 0) | (0x04 if metadata.xmp else 0)
    ordered = [(b"VP8X", bytes([flags, 0, 0, 0]) + canvas)]
    ordered += [(b"ICCP", icc)] if icc else []
    ordered += [(k, b) for k, b in keep if k not in (b"ICCP", b"EXIF")]
    ordered += [(b"EXIF", exif)] if exif else []
    ordered += [(b"XMP ", metadata.xmp)] if metadata.xmp else []
    body = b"".join(k + struct.pack("<I", len(b)) + b + (b"\0" if len(b) & 1 else b"") for k, b in ordered)
    return b"RIFF" + struct.pack("<I", 4 + len(body)) + b"WEBP" + body


def tiff_tags(metadata: Metadata) -> list[tuple[int, int, int, bytes, bool]]:
    """``metadata``'s XMP (tag 700) and ICC profile (34675) as tifffile's ``extratags`` (the EXIF block is not carried into TIFF)."""
    tags = []
    if metadata.xmp:
        tags.append((700, 1, len(metadata.xmp), metadata.xmp, True))
    if metadata.icc:
        tags.append((34675, 7, len(metadata.icc), metadata.icc, True))
    return tags


def _tiff_with(data: bytes, metadata: Metadata) -> bytes:
    """A classic TIFF's bytes with ``metadata``'s XMP and ICC profile as tags of its first directory.

    The directory is written anew at the end of the file with the two tags (and the old
    entries, whose values stay where they are), and the header points to it: no byte of the
    image data moves. A BigTIFF, or a directory that does not read, is returned as it is.
    """
    tags = {tag: (kind, value) for tag, kind, _, value, _ in tiff_tags(metadata)}
    if not tags or len(data) < 8 or data[:2] not in (b"II", b"MM"):
        return data
    e = "<" if data[:2] == b"II" else ">"
    magic, ifd0 = struct.unpack_from(e + "HI", data, 2)
    entries = _ifd_entries(data, ifd0, e) if magic == 42 else None
    if entries is None:
        return data
    (next_ifd,) = struct.unpack_from(e + "I", data, ifd0 + 2 + 12 * len(entries))
    kept = {tag: data[where - 8 : where + 4] for tag, _, _, where in entries if tag not in tags}
    out = bytearray(data)
    if len(out) % 2:
        out += b"\0"
    for tag, (kind, value) in tags.items():
        at = len(out)
        out += value + (b"\0" if len(value) % 2 else b"")
        kept[tag] = struct.pack(e + "HHII", tag, kind, len(value), at)
    if len(out) + 6 + 12 * len(kept) >= 1 << 32:
        return data
    directory = len(out)
    out += struct.pack(e + "H", len(kept)) + b"".join(kept[t] for t in sorted(kept)) + struct.pack(e + "I", next_ifd)
    struct.pack_into(e + "I", out, 4, directory)
    return bytes(out)


def with_metadata(data: bytes, metadata: Metadata) -> bytes:
    """An encoded image's bytes with ``metadata`` added (JPEG, PNG, WebP; TIFF its XMP and ICC profile), the encoded pixels untouched.

    Its own metadata blocks of the same kinds are replaced. Other formats (BMP, ``.npy``)
    are returned as they are. TIFF holds no EXIF block here: its offsets would all have to
    move into the file's (a TIFF written in strips carries the same two tags, :func:`tiff_tags`).
    """
    if metadata == Metadata():
        return data
    if data[:3] == b"\xff\xd8\xff":
        return _jpeg_with(data, jpeg_segments(metadata))
    if data[:8] == b"\x89PNG\r\n\x1a\n":
        return _png_with(data, png_chunks(metadata))
    if data[:4] == b"RIFF" and data[8:12] == b"WEBP":
        return _webp_with(data, metadata)
    if data[:4] in (b"II*\x00", b"MM\x00*"):
        return _tiff_with(data, metadata)
    return data


def with_xmp(data: bytes, xmp: bytes) -> bytes:
    """A JPEG's, PNG's or WebP's bytes with only their XMP replaced by ``xmp`` (``level --pose-only``).

    Raises
    ------
    ValueError
        For another format.
    """
    meta = Metadata(xmp=xmp)
    if data[:3] == b"\xff\xd8\xff":
        return _jpeg_with(data, jpeg_segments(meta), xmp_only=True)
    if data[:8] == b"\x89PNG\r\n\x1a\n":
        return _png_with(data, png_chunks(meta), xmp_only=True)
    if data[:4] == b"RIFF" and data[8:12] == b"WEBP":
        return _webp_with(data, meta, xmp_only=True)
    raise ValueError("only a JPEG, PNG or WebP file takes the pose without being written again")
