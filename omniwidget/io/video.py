"""360° video files: read frames, and warp a whole video by one map, its sound and metadata kept.

Needs PyAV (``pip install 'omniwidget[video]'``; its wheels bring FFmpeg's libraries).

- :func:`probe_video` what a file holds (:class:`VideoInfo`): size, frames, rate, time base,
  duration, pixel format and depth, audio streams, spherical metadata.
- :class:`VideoReader` frames as RGB arrays, by number or by time, for the editor (it seeks).
- :func:`warp_video` the whole video through one map, as ``omniwidget warp IN.mp4 ... -o OUT.mp4``
  does: the map is computed once (from the first frame with :func:`~omniwidget.raster.pipeline.warp`,
  or given), turned into source pixel coordinates once
  (:func:`~omniwidget.io.frames.map_coordinates`), and every frame is then only decoded,
  resampled (:func:`~omniwidget.raster.warping.remap_panorama`) and encoded. Time stamps, frame rate and
  duration are kept, audio streams are copied packet for packet (not re-encoded), and the
  spherical metadata is carried over (:mod:`omniwidget.io.spherical`). The output is written
  to a temporary file next to it and renamed at the end: an error, a cancel or Ctrl+C leaves
  no file under its name.

Speed. Decoding, resampling and encoding overlap on threads (FFmpeg's decoders and encoders
and OpenCV's ``remap`` release the GIL; the decoder and libx264 run their own threads too).
A ``yuv420p`` (or ``yuv420p10le``) video is resampled plane by plane without a colour
conversion: the luma plane with the map's coordinates, the two half-size chroma planes with
the map at half resolution (each chroma pixel's four luma directions averaged on the sphere),
so a frame costs about 1.5 single-channel remaps. Other pixel formats are converted to RGB
(48-bit for deeper than 8 bits), resampled, and converted back.
"""

from __future__ import annotations

import contextlib
import os
import queue
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._files import commit, remove_leftovers, same_file, temporary_file
from ..errors import VideoError
from ..raster.warping import ORDERS, Order, remap_panorama
from .frames import map_coordinates
from .spherical import EQUIRECTANGULAR, Spherical, check_mp4_structure, read_spherical, write_spherical

if TYPE_CHECKING:
    import av.container
    from av.video.stream import VideoStream

    from ..document.handles import Handles

__all__ = [
    "INPUT_SUFFIXES",
    "OUTPUT_SUFFIXES",
    "TEMPORARY_SUFFIX",
    "VideoCancelled",
    "VideoInfo",
    "VideoReader",
    "VideoReport",
    "default_codec",
    "half_resolution_map",
    "is_video_path",
    "join_video_segments",
    "probe_video",
    "warp_video",
]

#: File names read as videos by the command line (the content decides what FFmpeg makes of them).
INPUT_SUFFIXES = (".mp4", ".m4v", ".mov", ".mkv", ".webm", ".avi", ".mts", ".m2ts", ".ts")
#: Containers written: MP4 and QuickTime (the spherical metadata's boxes are theirs).
OUTPUT_SUFFIXES = (".mp4", ".m4v", ".mov")
#: The end of the temporary file's name a video is written to before it is renamed
#: (``.NAME.``, eight random hex digits, ``.part``; locked while it is written, and removed by the next warp
#: of ``NAME`` if a killed run left it: ``omniwidget._files.remove_leftovers``).
TEMPORARY_SUFFIX = ".part"
#: Pixel formats resampled plane by plane, and the format they are written in.
PLANE_FORMATS = {"yuv420p": "yuv420p", "yuvj420p": "yuv420p", "yuv420p10le": "yuv420p10le"}
#: x264's and x265's presets, slowest last.
PRESETS = ("ultrafast", "superfast", "veryfast", "faster", "fast", "medium", "slow", "slower", "veryslow", "placebo")
#: Quality by default: visually lossless for a resampled panorama (x265's 20 is about x264's 18).
DEFAULT_CRF = {"libx264": 18, "libx265": 20, "libsvtav1": 30}
DEFAULT_PRESET = {"libx264": "medium", "libx265": "medium"}
#: Container metadata the muxer writes itself (not copied from the input).
_OWN_METADATA = {"major_brand", "minor_version", "compatible_brands", "encoder"}

#: ``progress(done, total)``: frames encoded so far and the expected count (None if unknown);
#: return False to cancel.
Progress = Callable[[int, "int | None"], "bool | None"]


class VideoCancelled(Exception):
    """:func:`warp_video` stopped because it was asked to (``cancel`` set, or ``progress`` returned False); no output was written."""


def _av() -> Any:
    """PyAV, or a VideoError saying how to install it."""
    try:
        import av
    except ImportError:
        raise VideoError("reading and writing videos needs PyAV: pip install 'omniwidget[video]' (or pip install av)") from None
    return av


def is_video_path(path: str | os.PathLike[str]) -> bool:
    """Whether a file name ends like a video (:data:`INPUT_SUFFIXES`)."""
    return Path(path).suffix.lower() in INPUT_SUFFIXES


def _ffmpeg_reason(exc: BaseException) -> str:
    """FFmpeg's words for an error, without PyAV's ``[Errno n]`` and the file name."""
    text = getattr(exc, "strerror", None) or str(exc)
    return str(text).strip().rstrip(".")


def _looks_like_text(head: bytes) -> bool:
    try:
        text = head.decode("utf-8")
    except UnicodeDecodeError as exc:
        if exc.start < len(head) - 3:
            return False
        text = head[: exc.start].decode("utf-8")
    return bool(text) and all(c.isprintable() or c in "\r\n\t" for c in text)


# --- what a file holds -----------------------------------------------------------------------


@dataclass(frozen=True)
class VideoInfo:
    """What :func:`probe_video` found in a file: its first video stream, its audio, its metadata.

    Attributes
    ----------
    path : Path
    container : str
        FFmpeg's name of the container format (``"mov,mp4,m4a,3gp,3g2,mj2"``, ``"matroska,webm"``).
    width, height : int
        Frame size, pixels.
    frames : int or None
        Frame count from the container's header; None when it has none (Matroska).
    rate : Fraction or None
        Average frame rate, frames per second.
    time_base : Fraction
        Unit of the video stream's time stamps, seconds.
    duration : float or None
        Seconds, of the video stream (or of the file).
    start : float
        Time stamp of the first frame, seconds.
    codec : str
        The video codec (``"h264"``, ``"hevc"``, ...).
    pix_fmt : str
        The decoded pixel format (``"yuv420p"``, ``"yuv420p10le"``, ...).
    bits : int
        Bits per sample of the pixel format (8, 10, 12).
    audio : tuple of str
        The codec of each audio stream, in order.
    others : tuple of str
        Streams that are neither the video nor audio (subtitles, data, a second video): they
        are not copied by :func:`warp_video`.
    spherical : Spherical or None
        The spherical metadata, when the file has some.
    """

    path: Path
    container: str
    width: int
    height: int
    frames: int | None
    rate: Fraction | None
    time_base: Fraction
    duration: float | None
    start: float
    codec: str
    pix_fmt: str
    bits: int
    audio: tuple[str, ...]
    others: tuple[str, ...]
    spherical: Spherical | None

    def panorama_problem(self) -> str | None:
        """Why the frames cannot be warped as full equirectangular panoramas, or None if they can."""
        if self.spherical is not None and not self.spherical.full_panorama:
            return (
                f"its spherical metadata says {self.spherical.describe()}; the warp needs a mono "
                "equirectangular video of the whole sphere"
            )
        if self.width != 2 * self.height:
            return (
                f"the frames are {self.width} x {self.height}, not 2:1: an equirectangular 360° video "
                "is twice as wide as it is high"
            )
        return None


def _check_file(path: Path) -> None:
    if not path.exists():
        raise VideoError(f"{path}: no such file")
    if path.is_dir():
        raise VideoError(f"{path}: is a folder, not a video file")
    try:
        size = path.stat().st_size
    except OSError as exc:
        raise VideoError(f"{path}: cannot read the video ({exc.strerror or exc})") from None
    if size == 0:
        raise VideoError(f"{path}: the file is empty")
    try:
        check_mp4_structure(path)
    except VideoError as exc:
        raise VideoError(f"{path}: {exc}") from None
    except OSError as exc:
        raise VideoError(f"{path}: cannot read the video ({exc.strerror or exc})") from None


def _open_input(path: Path) -> av.container.InputContainer:
    av = _av()
    _check_file(path)
    try:
        return av.open(str(path), "r")
    except av.FFmpegError as exc:
        try:
            with path.open("rb") as fh:
                head = fh.read(512)
        except OSError:
            head = b""
        hint = " (it looks like a text file)" if _looks_like_text(head) else ""
        raise VideoError(f"{path}: not a video FFmpeg can read{hint} ({_ffmpeg_reason(exc)})") from None


def _video_stream(container: av.container.InputContainer, path: Path) -> VideoStream:
    """The first video stream that is not a cover picture, or a VideoError naming what the file holds instead."""
    av = _av()
    for stream in container.streams.video:
        if not stream.disposition & av.stream.Disposition.attached_pic:
            return stream
    audio = [s.codec_context.name for s in container.streams.audio]
    if audio:
        raise VideoError(f"{path}: has no video stream (only audio: {', '.join(audio)})")
    raise VideoError(f"{path}: has no video stream")


def _bits(fmt: Any) -> int:
    return max((c.bits for c in fmt.components), default=8)


def _describe(stream: Any) -> str:
    name = stream.codec_context.name if stream.codec_context is not None else "unknown codec"
    return f"stream {stream.index} ({stream.type}, {name})"


_PROJECTIONS = {0: "equirectangular", 1: "cubemap", 2: "equirectangular", 3: "half-equirectangular", 4: "rectilinear", 5: "fisheye"}
_STEREO_TYPES = {0: "mono", 1: "left-right", 2: "top-bottom"}


def _spherical_from_frame(frame: Any) -> Spherical | None:
    """Spherical metadata FFmpeg attached to a decoded frame (any container: Matroska's ``Projection``, say).

    Reads FFmpeg's ``AVSphericalMapping`` (projection, yaw, pitch, roll in 16.16 degrees,
    bounds left, top, right, bottom in 0.32) and ``AVStereo3D`` (its type first).
    """
    av = _av()
    kinds = av.sidedata.sidedata.Type
    mapping = stereo = None
    for data in frame.side_data:
        if data.type == kinds.SPHERICAL:
            mapping = np.frombuffer(bytes(data), np.int32)
        elif data.type == kinds.STEREO3D:
            stereo = np.frombuffer(bytes(data), np.int32)
    if mapping is None or len(mapping) < 8:
        return None
    projection = _PROJECTIONS.get(int(mapping[0]), "other")
    yaw, pitch, roll = (float(v) / 65536.0 for v in mapping[1:4])
    left, top, right, bottom = (float(v) / 2.0**32 for v in mapping[4:8].view(np.uint32))
    mode = _STEREO_TYPES.get(int(stereo[0]), "custom") if stereo is not None and len(stereo) else "mono"
    return Spherical(projection, mode, yaw, pitch, roll, (top, bottom, left, right), source="side data")


def _first_frame(container: Any, stream: Any, path: Path) -> Any:
    av = _av()
    try:
        for frame in container.decode(stream):
            return frame
    except av.FFmpegError as exc:
        raise VideoError(f"{path}: the video stream is broken at its first frame ({_ffmpeg_reason(exc)})") from None
    raise VideoError(f"{path}: the video stream has no frames")


def probe_video(path: str | os.PathLike[str]) -> VideoInfo:
    """Open a video file and say what it holds.

    Parameters
    ----------
    path : path-like
        Any file FFmpeg reads (MP4, QuickTime, Matroska, WebM, ...).

    Returns
    -------
    VideoInfo

    Raises
    ------
    VideoError
        Naming the file: missing, empty, a folder, not a video FFmpeg can read (a text file
        is said to be one), cut short (an MP4 whose boxes run past its end), or holding no
        video stream (an audio file, even with a cover picture).
    """
    path = Path(path)
    with _open_input(path) as container:
        stream = _video_stream(container, path)
        ctx = stream.codec_context
        spherical = read_spherical(path)
        if spherical is None and not container.format.name.startswith("mov"):
            spherical = _spherical_from_frame(_first_frame(container, stream, path))
        time_base = stream.time_base or Fraction(1, 90000)
        duration = float(stream.duration * time_base) if stream.duration else None
        if duration is None and container.duration:
            duration = container.duration / 1_000_000
        fmt = stream.format
        return VideoInfo(
            path=path,
            container=container.format.name,
            width=int(ctx.width),
            height=int(ctx.height),
            frames=int(stream.frames) or None,
            rate=stream.average_rate or stream.guessed_rate or None,
            time_base=time_base,
            duration=duration,
            start=float(stream.start_time * time_base) if stream.start_time is not None else 0.0,
            codec=ctx.name,
            pix_fmt=fmt.name if fmt is not None else "",
            bits=_bits(fmt) if fmt is not None else 8,
            audio=tuple(s.codec_context.name for s in container.streams.audio),
            others=tuple(_describe(s) for s in container.streams if s.index != stream.index and s.type != "audio"),
            spherical=spherical,
        )


# --- reading frames ----------------------------------------------------------------------------


class VideoReader:
    """Frames of a video as RGB arrays, by number or by time: for showing, scrubbing and sampling.

    Seeks to the key frame before the one asked for and decodes forward; reading frames in
    order (or a little ahead) continues the decoding without seeking again.

    Parameters
    ----------
    path : path-like
    depth : {8, 16}, optional
        Bits per sample of the arrays: uint8 RGB, or uint16 RGB (FFmpeg's ``rgb48``, a
        10-bit sample ``v`` read as about ``v * 64``). Default: 16 for videos deeper than 8
        bits, else 8.
    panorama : bool
        Refuse (VideoError) a video whose frames are not 2:1 or whose spherical metadata
        says anything but a mono equirectangular panorama.

    Attributes
    ----------
    info : VideoInfo

    Examples
    --------
    >>> with VideoReader("walk.mp4") as video:  # doctest: +SKIP
    ...     first = video.read(0)  # (H, 2H, 3) uint8
    ...     later = video.read_at(12.5)  # the frame shown at 12.5 s
    """

    def __init__(self, path: str | os.PathLike[str], *, depth: Literal[8, 16] | None = None, panorama: bool = True) -> None:
        self.info = probe_video(path)
        if panorama:
            problem = self.info.panorama_problem()
            if problem is not None:
                raise VideoError(f"{self.info.path}: {problem}")
        if depth not in (None, 8, 16):
            raise ValueError(f"depth must be 8 or 16, got {depth!r}")
        self.depth = depth if depth is not None else (16 if self.info.bits > 8 else 8)
        self._lock = threading.Lock()
        self._container = _open_input(self.info.path)
        self._stream = _video_stream(self._container, self.info.path)
        self._stream.thread_type = "AUTO"
        self._decoder: Iterator[Any] | None = None
        self._current: Any = None  # the last frame taken from the decoder
        self._next: Any = None  # the frame after it, decoded but not taken

    # frame times ------------------------------------------------------------------------
    @property
    def frame_interval(self) -> float:
        """Seconds between frames (from the average rate; 1/30 if the file gives none)."""
        return float(1 / self.info.rate) if self.info.rate else 1 / 30

    def __len__(self) -> int:
        """Frames, from the header or from duration times rate."""
        if self.info.frames:
            return self.info.frames
        return max(1, round((self.info.duration or 0.0) / self.frame_interval))

    def time_of(self, index: int) -> float:
        """Time stamp of frame ``index`` in seconds, for a constant frame rate: ``start + index / rate``."""
        return self.info.start + index * self.frame_interval

    # reading -----------------------------------------------------------------------------
    def read(self, index: int) -> NDArray[np.uint8] | NDArray[np.uint16]:
        """Frame ``index`` (from 0) as an RGB array.

        For a variable frame rate this is the frame shown at ``index / rate`` seconds.

        Returns
        -------
        ndarray of uint8 or uint16, shape (H, W, 3)

        Raises
        ------
        IndexError
            If ``index`` is negative or past the last frame.
        VideoError
            If the stream is broken there.
        """
        if index < 0 or index >= len(self):
            raise IndexError(f"frame {index} of a video of {len(self)} frames")
        return self.read_at(self.time_of(index))

    def read_at(self, seconds: float) -> NDArray[np.uint8] | NDArray[np.uint16]:
        """The frame shown at ``seconds`` (the last one that starts at or before it; the first one before the start).

        Returns
        -------
        ndarray of uint8 or uint16, shape (H, W, 3)
        """
        with self._lock:
            return self._rgb(self._frame_at(float(seconds)))

    def iter_frames(self, start: int = 0, stop: int | None = None) -> Iterator[NDArray[np.uint8] | NDArray[np.uint16]]:
        """Frames ``start`` to ``stop - 1`` (to the end by default) in order, as RGB arrays.

        The frames are decoded by a decoder of their own (the file is opened again), so
        :meth:`read` and :meth:`read_at` can be used meanwhile, from another thread too.
        """
        own = VideoReader(self.info.path, depth=self.depth, panorama=False)
        try:
            frame = own._frame_at(own.time_of(start)) if start > 0 else None
            if frame is None:
                own._seek(own.info.start)
                frame = own._take()
            index = start
            while frame is not None and (stop is None or index < stop):
                yield own._rgb(frame)
                index += 1
                frame = own._take()
        finally:
            own.close()

    def __iter__(self) -> Iterator[NDArray[np.uint8] | NDArray[np.uint16]]:
        return self.iter_frames()

    def close(self) -> None:
        """Close the file."""
        self._decoder = None
        self._container.close()

    def __enter__(self) -> VideoReader:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # internals ---------------------------------------------------------------------------
    def _rgb(self, frame: Any) -> Any:
        return frame.to_ndarray(format="rgb48le" if self.depth == 16 else "rgb24", src_color_range=frame.color_range)

    def _seek(self, seconds: float) -> None:
        av = _av()
        first = self._stream.start_time or 0
        target = max(first, int((seconds - 0.5 * self.frame_interval) / (self._stream.time_base or Fraction(1, 90000))))
        try:
            self._container.seek(target, stream=self._stream, backward=True)
        except av.FFmpegError as exc:
            raise VideoError(f"{self.info.path}: cannot seek to {seconds:.3f} s ({_ffmpeg_reason(exc)})") from None
        self._decoder = iter(self._container.decode(self._stream))
        self._current = self._next = None

    def _peek(self) -> Any:
        if self._next is None and self._decoder is not None:
            av = _av()
            try:
                self._next = next(self._decoder, None)
            except av.FFmpegError as exc:
                raise VideoError(f"{self.info.path}: the video stream is broken here ({_ffmpeg_reason(exc)})") from None
            if self._next is None:
                self._decoder = None
        return self._next

    def _take(self) -> Any:
        frame = self._peek()
        if frame is not None:
            self._current, self._next = frame, None
        return frame

    def _time(self, frame: Any) -> float:
        return float(frame.time) if frame.time is not None else self.info.start

    def _frame_at(self, seconds: float) -> Any:
        slack = 0.5 * self.frame_interval
        current = self._current
        reuse = current is not None and self._time(current) <= seconds + slack and seconds - self._time(current) <= 2.0
        for back in (0.0, 1.0, 5.0, float("inf")):  # seek earlier when a seek lands after the time asked for
            if not reuse:
                self._seek(self.info.start if back == float("inf") else seconds - back)
            reuse = False
            while True:
                upcoming = self._peek()
                if upcoming is None or (self._current is not None and self._time(upcoming) > seconds + slack):
                    break
                self._take()
                if self._time(self._current) > seconds + slack:  # the first frame after the seek is past the time
                    break
            if self._current is None:
                raise VideoError(f"{self.info.path}: no frame at {seconds:.3f} s")
            if self._time(self._current) <= seconds + slack or seconds - back <= self.info.start:
                break
        return self._current


# --- warping a whole video ---------------------------------------------------------------------


def half_resolution_map(inverse_map: ArrayLike) -> NDArray[np.float32]:
    """An inverse map at half resolution: each 2 x 2 block's directions averaged on the sphere.

    The chroma planes of 4:2:0 video have a pixel per 2 x 2 block of luma pixels; this is
    the map they are resampled with.

    Parameters
    ----------
    inverse_map : array_like, shape (H, W, 2)
        ``[lon, lat]`` degrees per output pixel; ``H`` and ``W`` even.

    Returns
    -------
    ndarray of float32, shape (H / 2, W / 2, 2)
        ``[lon, lat]`` degrees, the normalised mean of each block's four unit vectors.
    """
    m = np.asarray(inverse_map)
    h, w = m.shape[:2]
    if h % 2 or w % 2:
        raise ValueError(f"a map of {w} x {h} has no half resolution")
    out = np.empty((h // 2, w // 2, 2), np.float32)
    block = 128  # output rows at a time: a few MB of float32
    for r in range(0, h // 2, block):
        rows = slice(2 * r, 2 * min(r + block, h // 2))
        lon = np.radians(m[rows, :, 0], dtype=np.float32)  # float32 trigonometry: 1e-4 px at 4096 wide, twice as fast
        lat = np.radians(m[rows, :, 1], dtype=np.float32)
        cos_lat = np.cos(lat)
        sums = []
        for v in (cos_lat * np.cos(lon), cos_lat * np.sin(lon), np.sin(lat)):
            sums.append(v[0::2, 0::2] + v[0::2, 1::2] + v[1::2, 0::2] + v[1::2, 1::2])
        x, y, z = sums
        out[r : r + x.shape[0], :, 0] = np.degrees(np.arctan2(y, x))
        out[r : r + x.shape[0], :, 1] = np.degrees(np.arctan2(z, np.hypot(x, y)))
    return out


def _encoder_formats(name: str) -> tuple[str, ...] | None:
    """Pixel formats encoder ``name`` takes, () if it says none, None if there is no such encoder."""
    av = _av()
    try:
        codec = av.codec.Codec(name, "w")
    except (av.FFmpegError, ValueError):
        return None
    if codec.type != "video":
        return None
    return tuple(f.name for f in (codec.video_formats or ()))


def default_codec(bits: int) -> str:
    """The encoder used by default: libx264 for 8-bit video; libx265 (else libx264) for deeper video, in 10 bits."""
    if bits <= 8:
        return "libx264"
    for name in ("libx265", "libx264"):
        if "yuv420p10le" in (_encoder_formats(name) or ()):
            return name
    raise VideoError("this FFmpeg has no encoder for 10-bit video (libx265 or a 10-bit libx264)")


@dataclass(frozen=True)
class VideoReport:
    """What :func:`warp_video` did.

    Attributes
    ----------
    source, destination : Path
    frames : int
        Frames written.
    seconds : float
        Wall time of the transcode (decoding, resampling, encoding, writing); the map excluded.
    map_seconds : float
        Wall time of computing the map and its pixel coordinates.
    size : (int, int)
        Output ``(width, height)``.
    codec, pix_fmt : str
        The encoder and the pixel format written.
    options : dict of str to str
        The encoder options set (``crf``, ``preset``, ...).
    planes : bool
        True when the frames were resampled plane by plane (YUV 4:2:0), False through RGB.
    audio : tuple of str
        Codecs of the audio streams copied.
    dropped : tuple of str
        Streams of the input not copied (subtitles, data, other video).
    spherical : Spherical or None
        The spherical metadata written.
    warnings : tuple of str
        The map's warnings (crossing lines, fold-overs), when it was computed from handles.
    """

    source: Path
    destination: Path
    frames: int
    seconds: float
    map_seconds: float
    size: tuple[int, int]
    codec: str
    pix_fmt: str
    options: dict[str, str]
    planes: bool
    audio: tuple[str, ...]
    dropped: tuple[str, ...]
    spherical: Spherical | None
    warnings: tuple[str, ...]

    @property
    def fps(self) -> float:
        """Frames written per second of wall time."""
        return self.frames / self.seconds if self.seconds > 0 else float("inf")


def _plane(frame: Any, index: int, dtype: type[np.generic]) -> NDArray:
    """A frame's plane as a (height, width) view of its buffer (rows padded to ``line_size``)."""
    plane = frame.planes[index]
    item = np.dtype(dtype).itemsize
    return np.frombuffer(plane, dtype).reshape(plane.height, plane.line_size // item)[:, : plane.width]


class _Warper:
    """Resamples decoded frames into new frames ready for the encoder (called on worker threads)."""

    def __init__(
        self, inverse_map: NDArray, src_size: tuple[int, int], pix_fmt: str, out_format: str, order: Order, color: dict[str, int]
    ) -> None:
        src_w, src_h = src_size
        self.out_h, self.out_w = inverse_map.shape[:2]
        self.order = order
        self.out_format = out_format
        self.color = color
        self.deep = out_format.endswith("10le")
        self.planes = pix_fmt in PLANE_FORMATS and src_h % 2 == 0
        self.luma = map_coordinates(inverse_map, src_w)
        self.chroma = map_coordinates(half_resolution_map(inverse_map), src_w // 2) if self.planes else None

    def __call__(self, frame: Any) -> Any:
        av = _av()
        if self.planes:
            dtype = np.uint16 if self.deep else np.uint8
            out = av.VideoFrame(self.out_w, self.out_h, self.out_format)
            for k in range(3):
                coordinates = self.chroma if k and self.chroma is not None else self.luma
                _plane(out, k, dtype)[...] = remap_panorama(_plane(frame, k, dtype), coordinates, self.order)
        else:
            rgb_format = "rgb48le" if self.deep else "rgb24"
            rgb = frame.to_ndarray(format=rgb_format, src_color_range=frame.color_range)
            warped = np.ascontiguousarray(remap_panorama(rgb, self.luma, self.order))
            out = av.VideoFrame.from_ndarray(warped, format=rgb_format).reformat(
                format=self.out_format,
                dst_colorspace=self.color["colorspace"] or None,
                dst_color_range=self.color["color_range"] or None,
            )
        out.pts = frame.pts
        out.time_base = frame.time_base
        out.duration = frame.duration
        for name, value in self.color.items():  # the encoder takes them from its context; the frame says them too
            if hasattr(out, name):  # PyAV before 16 has no primaries or transfer on frames
                setattr(out, name, value)
        return out


_opencv_lock = threading.Lock()
_opencv_users = [0, 0]  # warps running, OpenCV's thread count before the first


@contextlib.contextmanager
def _opencv_single_threaded() -> Iterator[None]:
    """OpenCV on one thread while videos are warped (restored when the last one ends).

    The frames are resampled on the warp's own threads; OpenCV's pool on top of them
    busy-waits between calls, and took about 8% of the CPU time of a 2048 x 1024 transcode
    (``bench/bench_video.py``). The setting is OpenCV's, for the whole process.
    """
    import cv2

    with _opencv_lock:
        if _opencv_users[0] == 0:
            _opencv_users[1] = cv2.getNumThreads()
            cv2.setNumThreads(1)
        _opencv_users[0] += 1
    try:
        yield
    finally:
        with _opencv_lock:
            _opencv_users[0] -= 1
            if _opencv_users[0] == 0:
                cv2.setNumThreads(_opencv_users[1])


def _put(q: queue.Queue[Any], item: Any, stop: threading.Event) -> bool:
    """Put ``item`` unless ``stop`` is set first; whether it was put."""
    while not stop.is_set():
        try:
            q.put(item, timeout=0.1)
            return True
        except queue.Full:
            continue
    return False


def _check_destination(source: Path, destination: Path) -> str:
    if destination.suffix.lower() not in OUTPUT_SUFFIXES:
        raise VideoError(f"{destination}: the output video must end in {', '.join(OUTPUT_SUFFIXES)}")
    if not destination.parent.is_dir():
        raise VideoError(f"{destination}: the folder {destination.parent} does not exist")
    if same_file(destination, source):
        raise VideoError(f"{destination}: the output would overwrite the input {source}; choose another file")
    return "mov" if destination.suffix.lower() == ".mov" else "mp4"


def _temporary_file(destination: Path) -> tuple[int, Path]:
    """A new empty file next to ``destination``, hidden, named after it (``.out.mp4.1a2b3c4d.part``), and its locked descriptor.

    What a killed run left beside ``destination`` is removed first. Made with the permissions
    a new file gets (``0o666`` less the umask), as the output will have them after the rename.
    """
    remove_leftovers(destination)
    try:
        return temporary_file(destination, TEMPORARY_SUFFIX)
    except OSError as exc:
        raise VideoError(f"{destination}: cannot make a temporary file next to it ({exc.strerror or exc})") from None


def _encoder_options(codec: str, crf: int | None, preset: str | None) -> dict[str, str]:
    crf = DEFAULT_CRF.get(codec) if crf is None else crf
    preset = DEFAULT_PRESET.get(codec) if preset is None else preset
    if codec in ("libx264", "libx265") and preset is not None and preset not in PRESETS:
        raise VideoError(f"--preset {preset}: {codec}'s presets are {', '.join(PRESETS)}")
    if crf is not None and not 0 <= crf <= 63:
        raise VideoError(f"--crf {crf}: the constant rate factor is 0 (best) to 51 (x264, x265) or 63 (AV1)")
    options = {}
    if crf is not None:
        options["crf"] = str(crf)
    if preset is not None:
        options["preset"] = preset
    if codec == "libx265":
        options["x265-params"] = "log-level=error"  # x265 prints its own banner on stderr otherwise
    return options


def warp_video(
    source: str | os.PathLike[str],
    destination: str | os.PathLike[str],
    inverse_map: ArrayLike | None = None,
    *,
    handles: Handles | None = None,
    width: int | None = None,
    order: Order = "bilinear",
    codec: str | None = None,
    crf: int | None = None,
    preset: str | None = None,
    spherical: Spherical | bool | None = None,
    workers: int | None = None,
    progress: Progress | None = None,
    cancel: threading.Event | None = None,
    start: float | None = None,
    end: float | None = None,
    audio: bool = True,
) -> VideoReport:
    """Warp every frame of a 360° video by one map and write a new video, its sound and metadata kept.

    Parameters
    ----------
    source : path-like
        The input video: 2:1 equirectangular frames of even height, any codec and container
        FFmpeg reads; 8-bit or deeper (10-bit is resampled and written in 10 bits).
    destination : path-like
        ``.mp4``, ``.m4v`` or ``.mov``; written whole at the end (a temporary file next to
        it until then), never the input.
    inverse_map : array_like, shape (h, 2h, 2), optional
        For each output pixel, the input ``[lon, lat]`` in degrees it shows
        (``Result.inverse_map()``, or a map saved by ``omniwidget warp --map``). The output
        is ``2h x h``; ``h`` must be even (4:2:0 video).
    handles : Handles, optional
        Instead of ``inverse_map``: the map is computed from the first frame by
        :func:`~omniwidget.raster.pipeline.warp` (its warnings go to ``VideoReport.warnings``).
    width : int, optional
        With ``handles``: the output width, a multiple of 4 (default: the input's).
    order : {"nearest", "bilinear", "bicubic"}
    codec : str, optional
        The FFmpeg encoder; default :func:`default_codec` (libx264; libx265 for 10-bit).
    crf : int, optional
        Constant rate factor (lower is better; default 18 for libx264, 20 for libx265).
    preset : str, optional
        Encoder speed preset (default ``"medium"`` for libx264 and libx265).
    spherical : Spherical or bool, optional
        The spherical metadata written: by default (None) the input's, if it has any;
        True: the input's, or plain equirectangular if it has none; False: none; or the
        given :class:`~omniwidget.io.spherical.Spherical`.
    workers : int, optional
        Threads resampling frames (default 2); decoding and encoding have their own. While
        a video is warped OpenCV runs on one thread (its setting, for the whole process):
        its own thread pool on top of these cost 8% more CPU time.
    progress : callable, optional
        ``progress(done, total)`` after each frame is encoded, on the calling thread;
        ``total`` is the expected frame count or None. Returning False cancels.
    cancel : threading.Event, optional
        Set from another thread to cancel (checked after each frame).
    start, end : float, optional
        Warp only the frames shown from ``start`` up to, not including, ``end``: seconds on
        the input's timeline (:attr:`VideoInfo.start` is its first frame). The output then
        starts at 0 with the first of those frames, and holds the audio packets that start
        in the range (whole packets: a range is cut at frames, not at audio samples). Each
        range is encoded on its own, from a key frame, so ranges warped on different
        machines join without re-encoding (:func:`join_video_segments`).
    audio : bool
        Copy the audio streams (default); False writes the video alone.

    Returns
    -------
    VideoReport

    Raises
    ------
    VideoError
        The input is missing, not a video, has no video stream, is not a full mono
        equirectangular panorama (2:1; its spherical metadata), is cut short or broken
        (a decoding error, fewer frames than it says), or its audio cannot go into the
        output container; the output name is wrong; the codec is missing. No output is written.
    ImageError
        The map is malformed.
    VideoCancelled
        When cancelled; no output is written.
    KeyboardInterrupt
        Passed on after the temporary file is removed.
    """
    av = _av()
    source, destination = Path(source), Path(destination)
    if order not in ORDERS:
        raise ValueError(f"order must be one of {', '.join(ORDERS)}, got {order!r}")
    if (inverse_map is None) == (handles is None):
        raise TypeError("give exactly one of inverse_map and handles")
    if width is not None and (width < 4 or width % 4):
        raise VideoError(f"--width {width}: a video's width must be a multiple of 4 (4:2:0 video has even sizes)")
    span = _time_range(start, end)
    muxer = _check_destination(source, destination)
    info = probe_video(source)
    problem = info.panorama_problem()
    if problem is not None:
        raise VideoError(f"{source}: {problem}")
    if info.height % 2 and info.pix_fmt in PLANE_FORMATS:
        raise VideoError(f"{source}: the frames are {info.width} x {info.height}; 4:2:0 video needs an even height")

    # the map, once -------------------------------------------------------------------------
    start = time.perf_counter()
    warnings: tuple[str, ...] = ()
    if handles is not None:
        from ..raster.pipeline import warp

        with VideoReader(source, depth=16 if info.bits > 8 else 8) as video:
            first = video.read_at(info.start)
        result = warp(first, handles, width=width, order=order, warn=False)
        warnings = result.warnings
        the_map = result.inverse_map()
    else:
        the_map = np.asarray(inverse_map)
        if width is not None and the_map.ndim == 3 and width != the_map.shape[1]:
            raise VideoError(f"--width {width}: the map makes frames {the_map.shape[1]} wide")
    if the_map.ndim != 3 or the_map.shape[0] % 2 or the_map.shape[1] % 4:
        raise VideoError(f"the map is {the_map.shape[1]} x {the_map.shape[0]}: a video's output width must be a multiple of 4")

    # the encoder ---------------------------------------------------------------------------
    out_format = "yuv420p10le" if info.bits > 8 else "yuv420p"
    codec = codec or default_codec(info.bits)
    formats = _encoder_formats(codec)
    if formats is None:
        raise VideoError(f"--codec {codec}: this FFmpeg has no such video encoder")
    if formats and out_format not in formats:
        raise VideoError(f"--codec {codec}: it cannot write {out_format} ({'10-bit' if info.bits > 8 else '8-bit'} 4:2:0) video")
    options = _encoder_options(codec, crf, preset)

    container = _open_input(source)
    stream = _video_stream(container, source)
    ctx = stream.codec_context
    color = {
        "colorspace": int(ctx.colorspace),
        "color_range": int(ctx.color_range),
        "color_primaries": int(ctx.color_primaries),
        "color_trc": int(ctx.color_trc),
    }
    if info.pix_fmt == "yuvj420p":
        color["color_range"] = 2  # full range, said by the flag rather than the deprecated pixel format
    warper = _Warper(np.asarray(the_map, np.float32), (info.width, info.height), info.pix_fmt, out_format, order, color)
    map_seconds = time.perf_counter() - start

    written = _spherical_written(info, spherical)
    expected = info.frames or (round(info.duration * float(info.rate)) if info.duration and info.rate else None)
    if span is not None:
        last = info.start + info.duration if info.duration else float(span[1])
        covered = min(float(span[1]), last) - max(float(span[0]), info.start)
        expected = max(0, round(covered * float(info.rate))) if info.rate and info.duration else None

    held, tmp = _temporary_file(destination)
    opencv = _opencv_single_threaded()
    opencv.__enter__()
    stop = threading.Event()
    items: queue.Queue[Any] = queue.Queue(maxsize=8)
    pool = ThreadPoolExecutor(max(1, workers or 2), thread_name_prefix="omniwidget-warp")
    output: Any = None
    decoder: threading.Thread | None = None
    done = 0
    finished = False
    try:
        output = av.open(str(tmp), "w", format=muxer)
        output.metadata.update({k: v for k, v in container.metadata.items() if k not in _OWN_METADATA})
        rate = info.rate or Fraction(30)
        out_video = output.add_stream(codec, rate=rate, options=options)
        out_video.width, out_video.height = warper.out_w, warper.out_h
        out_video.pix_fmt = out_format
        # frame threads, as the ffmpeg command line has them: PyAV's default (slice threads only)
        # makes libx264 cut each frame into slices, slower and worse
        out_video.codec_context.thread_type = "AUTO"
        out_video.codec_context.thread_count = 0
        out_video.time_base = stream.time_base
        out_video.codec_context.time_base = stream.time_base
        for name, value in color.items():
            setattr(out_video.codec_context, name, value)
        if codec == "libx265" and muxer == "mp4":
            out_video.codec_context.codec_tag = "hvc1"  # what Apple's players want for HEVC in MP4
        if "language" in stream.metadata:
            out_video.metadata["language"] = stream.metadata["language"]
        audio_streams = list(container.streams.audio) if audio else []
        audio_out = {}
        for a in audio_streams:
            copied = output.add_stream_from_template(a)
            copied.metadata.update({k: v for k, v in a.metadata.items() if k in ("language", "title", "handler_name")})
            audio_out[a.index] = copied
        try:
            output.start_encoding()
        except av.FFmpegError as exc:
            what = ", ".join(info.audio) if audio_streams else "its streams"
            raise VideoError(
                f"{source}: cannot write {what} into a {destination.suffix} file ({_ffmpeg_reason(exc)}); "
                "try .mov, or convert the audio first"
            ) from None
        stream.thread_type = "AUTO"
        if span is not None:  # from the key frame before the range's start
            container.seek(max(0, int(span[0] / _time_base(stream))), stream=stream, backward=True)

        def decode() -> None:
            """Demux and decode on this thread; hand audio packets and frame warps (futures) to the caller, in order."""
            count = 0
            shift: Fraction | None = None  # seconds taken off the time stamps of a range
            waiting: list[Any] = []  # a range's audio packets met before its first frame
            try:
                for packet in container.demux(stream, *audio_streams):
                    if stop.is_set():
                        return
                    if packet.stream.type == "audio":
                        if not packet.size or packet.pts is None:
                            continue
                        if span is not None:
                            if not span[0] <= packet.pts * _time_base(packet) < span[1]:
                                continue
                            if shift is None:  # until the first frame of the range says how far to move them
                                waiting.append(packet)
                                continue
                            _move(packet, shift)
                        if not _put(items, ("audio", packet), stop):
                            return
                        continue
                    try:
                        frames = stream.decode(packet)
                    except av.FFmpegError as exc:
                        raise VideoError(f"{source}: the video stream is broken after frame {count} ({_ffmpeg_reason(exc)})") from None
                    past = False
                    for frame in frames:
                        if span is not None:
                            if frame.pts is None:
                                raise VideoError(f"{source}: frame {count} has no time stamp, so it cannot be placed in a range")
                            when = frame.pts * _time_base(frame)
                            if when < span[0]:
                                continue
                            if when >= span[1]:
                                past = True
                                break
                            if shift is None:
                                shift = when
                                for early in waiting:
                                    _move(early, shift)
                                    if not _put(items, ("audio", early), stop):
                                        return
                                waiting.clear()
                            frame.pts -= round(shift / _time_base(frame))
                        if (frame.width, frame.height) != (info.width, info.height):
                            raise VideoError(
                                f"{source}: frame {count} is {frame.width} x {frame.height}, the first ones {info.width} x {info.height}"
                            )
                        if frame.format.name != info.pix_fmt:
                            raise VideoError(f"{source}: frame {count} is {frame.format.name}, the first ones {info.pix_fmt}")
                        if not _put(items, ("video", pool.submit(warper, frame)), stop):
                            return
                        count += 1
                    if past:  # the decoder gives frames in the order they are shown: the range is done
                        break
            except av.FFmpegError as exc:
                _put(items, ("error", VideoError(f"{source}: the file is broken after frame {count} ({_ffmpeg_reason(exc)})")), stop)
            except BaseException as exc:  # handed to the caller, raised there
                _put(items, ("error", exc), stop)
            else:
                _put(items, ("end", count), stop)

        decoder = threading.Thread(target=decode, name="omniwidget-decode", daemon=True)
        tick = time.perf_counter()
        decoder.start()
        last_end = None
        try:
            while True:
                kind, value = items.get()
                if kind == "error":
                    raise value
                if kind == "end":
                    break
                if kind == "audio":
                    value.stream = audio_out[value.stream.index]
                    output.mux(value)
                    continue
                frame = value.result()
                if frame.time is not None:
                    last_end = frame.time + (float(frame.duration * frame.time_base) if frame.duration else 0.0)
                output.mux(out_video.encode(frame))
                done += 1
                if cancel is not None and cancel.is_set():
                    raise VideoCancelled(f"cancelled after {done} frame(s); {destination} was not written")
                if progress is not None and progress(done, expected) is False:
                    raise VideoCancelled(f"cancelled after {done} frame(s); {destination} was not written")
            output.mux(out_video.encode(None))
            if span is None:
                _check_complete(info, done, last_end)
            elif done == 0:
                raise VideoError(f"{source}: no frame is shown from {float(span[0]):g} s to {float(span[1]):g} s")
            output.close()
        except av.FFmpegError as exc:  # the encoder or the muxer (a full disk, say)
            raise VideoError(f"{destination}: cannot encode or write the video after {done} frame(s) ({_ffmpeg_reason(exc)})") from None
        seconds = time.perf_counter() - tick
        if written is not None:
            write_spherical(tmp, written, in_place=True)
        commit(held, tmp, destination)
        finished = True
    finally:
        stop.set()
        if decoder is not None:
            while decoder.is_alive():  # unblock it if it waits for room in the queue
                try:
                    items.get_nowait()
                except queue.Empty:
                    decoder.join(0.05)
        pool.shutdown(wait=True, cancel_futures=True)
        opencv.__exit__(None, None, None)  # no resampling left
        if output is not None and not finished:
            try:
                output.close()
            except Exception:  # noqa: BLE001 - the temporary file goes anyway
                pass
        container.close()
        if not finished:
            tmp.unlink(missing_ok=True)
        os.close(held)
    return VideoReport(
        source=source,
        destination=destination,
        frames=done,
        seconds=seconds,
        map_seconds=map_seconds,
        size=(warper.out_w, warper.out_h),
        codec=codec,
        pix_fmt=out_format,
        options=options,
        planes=warper.planes,
        audio=info.audio,
        dropped=info.others,
        spherical=written,
        warnings=warnings,
    )


def join_video_segments(
    segments: Sequence[str | os.PathLike[str]],
    destination: str | os.PathLike[str],
    *,
    source: str | os.PathLike[str],
    spherical: Spherical | bool | None = None,
) -> VideoReport:
    """Join videos warped range by range into one, without re-encoding; the sound from the source.

    The segments are the outputs of :func:`warp_video` with ``audio=False`` on consecutive
    ranges that together cover the whole ``source`` (``start=`` one range's ``end``). Their
    packets are copied byte for byte and put back on the source's timeline: the frames are
    the source's frames in the order they are shown, so the ``i``-th frame written takes the
    time stamp of the source's ``i``-th frame. The source's audio streams are copied packet
    for packet beside them, its metadata and spherical metadata as :func:`warp_video` keeps them.

    Parameters
    ----------
    segments : sequence of path-like
        The warped ranges in order; each starts with a key frame (as :func:`warp_video`
        writes them), all with the same encoder settings and frame size.
    destination : path-like
        ``.mp4``, ``.m4v`` or ``.mov``; written whole at the end, never one of the inputs.
    source : path-like
        The video the segments were warped from.
    spherical : Spherical or bool, optional
        As in :func:`warp_video`.

    Returns
    -------
    VideoReport
        ``seconds`` the time the join took; ``map_seconds`` 0.

    Raises
    ------
    VideoError
        A segment is missing or unreadable, the segments' encoders differ (their headers),
        or their frames do not add up to the source's.
    """
    av = _av()
    source, destination = Path(source), Path(destination)
    paths = [Path(p) for p in segments]
    if not paths:
        raise VideoError(f"{destination}: no segments to join")
    muxer = _check_destination(source, destination)
    clash = next((p for p in paths if same_file(p, destination)), None)
    if clash is not None:
        raise VideoError(f"{destination}: the output would overwrite its segment {clash}")
    info = probe_video(source)
    written = _spherical_written(info, spherical)
    tick = time.perf_counter()

    # the source's frame times (in the order they are shown) and its audio, in one reading
    container = _open_input(source)
    try:
        stream = _video_stream(container, source)
        shown: list[int] = []
        sound: list[Any] = []
        try:
            for packet in container.demux(stream, *container.streams.audio):
                if not packet.size:
                    continue
                if packet.stream.type == "audio":
                    sound.append(packet)
                elif packet.pts is not None:
                    shown.append(packet.pts)
        except av.FFmpegError as exc:
            raise VideoError(f"{source}: the file is broken after {len(shown)} frame(s) ({_ffmpeg_reason(exc)})") from None
        shown.sort()
        time_base = _time_base(stream)
        audio_streams = list(container.streams.audio)
        metadata = {k: v for k, v in container.metadata.items() if k not in _OWN_METADATA}
        language = stream.metadata.get("language")
    except BaseException:
        container.close()
        raise

    opened = []
    finished = False
    held, tmp = _temporary_file(destination)
    try:
        for path in paths:
            try:
                opened.append(av.open(str(path)))
            except (av.FFmpegError, OSError) as exc:
                raise VideoError(f"{path}: cannot read this segment ({_ffmpeg_reason(exc)})") from None
        first = opened[0].streams.video[0]
        header = bytes(first.codec_context.extradata or b"")
        for path, seg in zip(paths, opened, strict=True):
            v = seg.streams.video[0]
            same = (v.codec_context.name, v.width, v.height, v.format.name) == (first.codec_context.name, first.width, first.height, first.format.name)
            if not same or bytes(v.codec_context.extradata or b"") != header:
                raise VideoError(f"{path}: this segment was encoded unlike {paths[0].name} (its codec, size or encoder header differ)")
        output = av.open(str(tmp), "w", format=muxer)
        try:
            output.metadata.update(metadata)
            out_video = output.add_stream_from_template(first)
            out_video.time_base = time_base
            if language:
                out_video.metadata["language"] = language
            audio_out = {a.index: output.add_stream_from_template(a) for a in audio_streams}
            for a in audio_streams:
                audio_out[a.index].metadata.update({k: v for k, v in a.metadata.items() if k in ("language", "title", "handler_name")})
            output.start_encoding()
            pending = iter(sound)
            next_sound = next(pending, None)
            count = 0
            for path, seg in zip(paths, opened, strict=True):
                v = seg.streams.video[0]
                if count >= len(shown):
                    raise VideoError(f"{path}: the segments hold more frames than {source} ({len(shown)})")
                base = v.start_time  # the time stamp of the segment's first frame shown (the container says it)
                begin = Fraction(shown[count]) * time_base  # where that frame is shown in the source
                for q in seg.demux(v):  # packet by packet: a segment is never held in memory whole
                    if not q.size:
                        continue
                    if q.pts is None or base is None:
                        raise VideoError(f"{path}: a frame of this segment has no time stamp")
                    if count >= len(shown):
                        raise VideoError(f"{path}: the segments hold more frames than {source} ({len(shown)})")
                    count += 1
                    pts = begin + (int(q.pts) - base) * _time_base(v)
                    dts = begin + (int(q.dts if q.dts is not None else q.pts) - base) * _time_base(v)
                    while next_sound is not None and next_sound.dts is not None and next_sound.dts * next_sound.time_base <= dts:
                        next_sound.stream = audio_out[next_sound.stream.index]
                        output.mux(next_sound)
                        next_sound = next(pending, None)
                    q.pts, q.dts = round(pts / time_base), round(dts / time_base)
                    q.time_base = time_base
                    q.stream = out_video
                    output.mux(q)
            if count != len(shown):
                raise VideoError(f"the segments hold {count} frame(s) but {source} has {len(shown)}: a range is missing")
            while next_sound is not None:
                next_sound.stream = audio_out[next_sound.stream.index]
                output.mux(next_sound)
                next_sound = next(pending, None)
        except av.FFmpegError as exc:
            raise VideoError(f"{destination}: cannot write the joined video ({_ffmpeg_reason(exc)})") from None
        finally:
            output.close()
        if written is not None:
            write_spherical(tmp, written, in_place=True)
        commit(held, tmp, destination)
        finished = True
    finally:
        for seg in opened:
            seg.close()
        container.close()
        if not finished:
            tmp.unlink(missing_ok=True)
        os.close(held)
    return VideoReport(
        source=source,
        destination=destination,
        frames=count,
        seconds=time.perf_counter() - tick,
        map_seconds=0.0,
        size=(first.width, first.height),
        codec=first.codec_context.name,
        pix_fmt=first.format.name,
        options={},
        planes=True,
        audio=info.audio,
        dropped=info.others,
        spherical=written,
        warnings=(),
    )


def _spherical_written(info: VideoInfo, spherical: Spherical | bool | None) -> Spherical | None:
    """The spherical metadata to write: the input's by default, plain equirectangular for True, none for False."""
    if spherical is None:
        written = info.spherical
    elif spherical is True:
        written = info.spherical or EQUIRECTANGULAR
    elif spherical is False:
        written = None
    else:
        written = spherical
    if written is not None and not written.full_panorama:
        raise ValueError(f"the spherical metadata written must be a full mono equirectangular panorama, not {written.describe()}")
    return written


def _time_base(thing: Any) -> Fraction:
    """The time base of a stream, packet or frame (FFmpeg always sets one on what it reads)."""
    time_base = thing.time_base
    if time_base is None:
        raise VideoError(f"{thing}: no time base: its time stamps mean nothing")
    return Fraction(time_base)


def _move(packet: Any, seconds: Fraction) -> None:
    """Move a packet ``seconds`` earlier (a range's output starts at 0)."""
    offset = round(seconds / _time_base(packet))
    packet.pts -= offset
    if packet.dts is not None:
        packet.dts -= offset


def _time_range(start: float | None, end: float | None) -> tuple[Fraction, Fraction] | None:
    """``(start, end)`` as exact fractions of a second (an open end is infinitely far), or None for the whole video."""
    if start is None and end is None:
        return None
    far = Fraction(10**18)  # an open end: further than any video goes
    for name, value in (("start", start), ("end", end)):
        if value is not None and (isinstance(value, bool) or not isinstance(value, (int, float, Fraction)) or not np.isfinite(float(value))):
            raise ValueError(f"{name} must be a finite number of seconds or None, got {value!r}")
    lo = -far if start is None else Fraction(start)
    hi = far if end is None else Fraction(end)
    if not lo < hi:
        raise ValueError(f"the range's start ({start} s) must come before its end ({end} s)")
    return lo, hi


def _check_complete(info: VideoInfo, frames: int, last_end: float | None) -> None:
    """Refuse a video that ended early: fewer frames than its header says and short of its duration by more than two frames."""
    if frames == 0:
        raise VideoError(f"{info.path}: the video stream has no frames")
    interval = float(1 / info.rate) if info.rate else 1 / 30
    short_in_time = info.duration is not None and last_end is not None and last_end < info.start + info.duration - 2 * interval
    if (info.frames is not None and frames < info.frames and (short_in_time or last_end is None)) or (info.frames is None and short_in_time):
        said = f"{info.frames} frames" if info.frames else f"{info.duration:.2f} s"
        raise VideoError(f"{info.path}: the video stream ends after {frames} frame(s), though the file says {said}; it looks truncated or damaged")

