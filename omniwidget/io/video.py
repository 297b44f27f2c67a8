"""360° video files: read them, decode them for a transcode, and write them, their sound and metadata kept.

Needs PyAV (``pip install 'omniwidget[video]'``; its wheels bring FFmpeg's libraries).

- :func:`probe_video` what a file holds (:class:`VideoInfo`): size, frames, rate, time base,
  duration, pixel format and depth, audio streams, spherical metadata.
- :class:`VideoReader` frames as RGB arrays, by number or by time, for the editor (it seeks).
- :class:`VideoDecoder` the frames and audio packets of a whole video (or of a time range:
  :func:`time_range`) in the order the file stores them, for a transcode.
- :class:`VideoEncoder` a video written as frames come: the encoder :func:`choose_encoding`
  picks, the time base, colour and language of the source, its audio streams copied packet
  for packet (not re-encoded) and its container metadata kept; :func:`video_output` the
  temporary file it is written to, renamed over the output at the end (an error, a cancel or
  Ctrl+C leaves no file under its name), and :func:`spherical_to_write` the spherical
  metadata carried over (:mod:`omniwidget.io.spherical`).
- :func:`join_video_segments` videos warped range by range joined without re-encoding.

Warping a whole video by one map is :func:`omniwidget.app.video.warp_video`, over these.
"""

from __future__ import annotations

import contextlib
import os
import threading
import time
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from numpy.typing import NDArray

from .._files import AtomicOutput, atomic_output, same_file
from .._lazy import lazy, resolve
from ..errors import VideoError
from .spherical import EQUIRECTANGULAR, Spherical, check_mp4_structure, read_spherical, write_spherical

if TYPE_CHECKING:
    import av
    import av.container
    from av.video.stream import VideoStream
else:
    av = lazy("av")

__all__ = [
    "INPUT_SUFFIXES",
    "OUTPUT_SUFFIXES",
    "PLANE_FORMATS",
    "TEMPORARY_SUFFIX",
    "Encoding",
    "VideoDecoder",
    "VideoEncoder",
    "VideoInfo",
    "VideoReader",
    "VideoReport",
    "check_complete",
    "check_output",
    "choose_encoding",
    "default_codec",
    "frame_from_rgb",
    "frame_plane",
    "is_video_path",
    "join_video_segments",
    "new_frame",
    "probe_video",
    "spherical_to_write",
    "time_range",
    "video_output",
]

#: File names read as videos by the command line (the content decides what FFmpeg makes of them).
INPUT_SUFFIXES = (".mp4", ".m4v", ".mov", ".mkv", ".webm", ".avi", ".mts", ".m2ts", ".ts")
#: Containers written: MP4 and QuickTime (the spherical metadata's boxes are theirs).
OUTPUT_SUFFIXES = (".mp4", ".m4v", ".mov")
#: The end of the temporary file's name a video is written to before it is renamed
#: (``.NAME.``, eight random hex digits, ``.part``; locked while it is written, and removed by the next warp
#: of ``NAME`` if a killed run left it: :func:`omniwidget._files.remove_leftovers`).
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

def _av() -> Any:
    """PyAV, or a VideoError saying how to install it."""
    try:
        resolve(av)
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
        are not copied by a warp (:func:`omniwidget.app.video.warp_video`).
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


# --- what was written ----------------------------------------------------------------------------


@dataclass(frozen=True)
class VideoReport:
    """What a video written whole held: by a warp (:func:`omniwidget.app.video.warp_video`) or :func:`join_video_segments`.

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



# --- decoding a whole video, for a transcode ---------------------------------------------------


def time_range(start: float | None, end: float | None) -> tuple[Fraction, Fraction] | None:
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


class _Cut:
    """A time range cut out of a video: which frames and audio packets fall in it, moved to start at 0.

    The audio packets met before the range's first frame wait for it, since that frame says
    how far everything is moved.
    """

    def __init__(self, span: tuple[Fraction, Fraction], path: Path) -> None:
        self.start, self.end = span
        self.path = path
        self.shift: Fraction | None = None  # seconds taken off the time stamps
        self.waiting: list[Any] = []
        self.past = False  # a frame at or after the end was met

    def audio(self, packet: Any) -> list[Any]:
        """The packets to hand on now for ``packet``: none outside the range or before its first frame, else it, moved."""
        if not self.start <= packet.pts * _time_base(packet) < self.end:
            return []
        if self.shift is None:
            self.waiting.append(packet)
            return []
        _move(packet, self.shift)
        return [packet]

    def frame(self, frame: Any, count: int) -> list[Any] | None:
        """None if ``frame`` lies outside the range; else the waiting audio packets to hand on before it (the frame moved)."""
        if frame.pts is None:
            raise VideoError(f"{self.path}: frame {count} has no time stamp, so it cannot be placed in a range")
        when = frame.pts * _time_base(frame)
        if when >= self.end:
            self.past = True
        if when < self.start or self.past:
            return None
        early: list[Any] = []
        if self.shift is None:
            self.shift = when
            for packet in self.waiting:
                _move(packet, when)
            early, self.waiting = self.waiting, []
        frame.pts -= round(self.shift / _time_base(frame))
        return early


class VideoDecoder:
    """A video's frames and audio packets in the order the file stores them: what a transcode reads.

    Opens the file at once (as :func:`open` does; use it in a ``with`` statement). The first
    video stream is decoded on FFmpeg's threads; the audio packets come as they are stored,
    to be copied, not decoded.

    Parameters
    ----------
    info : VideoInfo
        From :func:`probe_video`.
    audio : bool
        Hand on the audio packets too (default).

    Attributes
    ----------
    info : VideoInfo
    stream : av.video.stream.VideoStream
        The video stream decoded.
    audio : list of av.audio.stream.AudioStream
        The audio streams handed on (none with ``audio=False``).
    """

    def __init__(self, info: VideoInfo, *, audio: bool = True) -> None:
        self.info = info
        self.container = _open_input(info.path)
        try:
            self.stream = _video_stream(self.container, info.path)
            self.audio = list(self.container.streams.audio) if audio else []
        except BaseException:
            self.container.close()
            raise

    def __enter__(self) -> VideoDecoder:
        return self

    def __exit__(self, *exc: object) -> None:
        self.container.close()

    @property
    def color(self) -> dict[str, int]:
        """The video stream's colour space, range, primaries and transfer, as FFmpeg numbers them (the encoder writes the same)."""
        ctx = self.stream.codec_context
        color = {
            "colorspace": int(ctx.colorspace),
            "color_range": int(ctx.color_range),
            "color_primaries": int(ctx.color_primaries),
            "color_trc": int(ctx.color_trc),
        }
        if self.info.pix_fmt == "yuvj420p":
            color["color_range"] = 2  # full range, said by the flag rather than the deprecated pixel format
        return color

    @property
    def metadata(self) -> dict[str, str]:
        """The container's metadata a copy keeps (not what the muxer writes itself)."""
        return {k: v for k, v in self.container.metadata.items() if k not in _OWN_METADATA}

    def items(self, span: tuple[Fraction, Fraction] | None = None) -> Iterator[tuple[Literal["audio", "video"], Any]]:
        """``("audio", packet)`` and ``("video", frame)`` in stored order, the frames checked to keep the first one's size and format.

        Parameters
        ----------
        span : (Fraction, Fraction), optional
            Only what is shown from ``span[0]`` up to, not including, ``span[1]`` seconds
            (:func:`time_range`), its time stamps moved to start at 0; decoding starts at the
            key frame before it.

        Raises
        ------
        VideoError
            The file or its video stream is broken (naming the frame after which), a frame's
            size or pixel format changes, or a frame of a range has no time stamp.
        """
        av = _av()
        self.stream.thread_type = "AUTO"
        cut = None if span is None else _Cut(span, self.info.path)
        if span is not None:  # from the key frame before the range's start
            self.container.seek(max(0, int(span[0] / _time_base(self.stream))), stream=self.stream, backward=True)
        count = 0
        try:
            for packet in self.container.demux(self.stream, *self.audio):
                if packet.stream.type == "audio":
                    if packet.size and packet.pts is not None:
                        yield from (("audio", p) for p in (cut.audio(packet) if cut is not None else [packet]))
                    continue
                for frame in self._decode(packet, count):
                    early = cut.frame(frame, count) if cut is not None else []
                    if early is None:
                        continue
                    yield from (("audio", p) for p in early)
                    self._check_frame(frame, count)
                    yield "video", frame
                    count += 1
                if cut is not None and cut.past:  # the decoder gives frames in the order they are shown: the range is done
                    break
        except av.FFmpegError as exc:
            raise VideoError(f"{self.info.path}: the file is broken after frame {count} ({_ffmpeg_reason(exc)})") from None

    def _decode(self, packet: Any, count: int) -> list[Any]:
        av = _av()
        try:
            return list(self.stream.decode(packet))
        except av.FFmpegError as exc:
            raise VideoError(f"{self.info.path}: the video stream is broken after frame {count} ({_ffmpeg_reason(exc)})") from None

    def _check_frame(self, frame: Any, count: int) -> None:
        info = self.info
        if (frame.width, frame.height) != (info.width, info.height):
            raise VideoError(f"{info.path}: frame {count} is {frame.width} x {frame.height}, the first ones {info.width} x {info.height}")
        if frame.format.name != info.pix_fmt:
            raise VideoError(f"{info.path}: frame {count} is {frame.format.name}, the first ones {info.pix_fmt}")


def check_complete(info: VideoInfo, frames: int, last_end: float | None) -> None:
    """Refuse a video that ended early: fewer frames than its header says and short of its duration by more than two frames."""
    if frames == 0:
        raise VideoError(f"{info.path}: the video stream has no frames")
    interval = float(1 / info.rate) if info.rate else 1 / 30
    short_in_time = info.duration is not None and last_end is not None and last_end < info.start + info.duration - 2 * interval
    if (info.frames is not None and frames < info.frames and (short_in_time or last_end is None)) or (info.frames is None and short_in_time):
        said = f"{info.frames} frames" if info.frames else f"{info.duration:.2f} s"
        raise VideoError(f"{info.path}: the video stream ends after {frames} frame(s), though the file says {said}; it looks truncated or damaged")


# --- writing a video ---------------------------------------------------------------------------


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


@dataclass(frozen=True)
class Encoding:
    """The encoder a video is written with, and its settings: chosen by :func:`choose_encoding`.

    Attributes
    ----------
    codec : str
        The FFmpeg encoder.
    pix_fmt : str
        The pixel format written: ``yuv420p``, or ``yuv420p10le`` for an input deeper than 8 bits.
    options : dict of str to str
        The encoder's options (``crf``, ``preset``, ...).
    """

    codec: str
    pix_fmt: str
    options: dict[str, str]


def choose_encoding(info: VideoInfo, codec: str | None = None, crf: int | None = None, preset: str | None = None) -> Encoding:
    """The encoder a video like ``info`` is written with: ``codec`` (default :func:`default_codec`), in 4:2:0 of the input's depth.

    Parameters
    ----------
    info : VideoInfo
    codec : str, optional
    crf : int, optional
        Constant rate factor (default 18 for libx264, 20 for libx265, 30 for libsvtav1).
    preset : str, optional
        Speed preset (default ``"medium"`` for libx264 and libx265).

    Raises
    ------
    VideoError
        This FFmpeg has no such encoder, it cannot write the pixel format, or the preset or
        constant rate factor is not one it takes.
    """
    out_format = "yuv420p10le" if info.bits > 8 else "yuv420p"
    codec = codec or default_codec(info.bits)
    formats = _encoder_formats(codec)
    if formats is None:
        raise VideoError(f"--codec {codec}: this FFmpeg has no such video encoder")
    if formats and out_format not in formats:
        raise VideoError(f"--codec {codec}: it cannot write {out_format} ({'10-bit' if info.bits > 8 else '8-bit'} 4:2:0) video")
    return Encoding(codec, out_format, _encoder_options(codec, crf, preset))


def check_output(source: Path, destination: Path) -> str:
    """The muxer of an output video (``"mp4"`` or ``"mov"``), once its name, folder and difference from ``source`` are checked.

    Raises
    ------
    VideoError
        The name does not end in :data:`OUTPUT_SUFFIXES`, its folder is missing, or it names ``source``.
    """
    if destination.suffix.lower() not in OUTPUT_SUFFIXES:
        raise VideoError(f"{destination}: the output video must end in {', '.join(OUTPUT_SUFFIXES)}")
    if not destination.parent.is_dir():
        raise VideoError(f"{destination}: the folder {destination.parent} does not exist")
    if same_file(destination, source):
        raise VideoError(f"{destination}: the output would overwrite the input {source}; choose another file")
    return _muxer(destination)


def _muxer(destination: Path) -> str:
    return "mov" if destination.suffix.lower() == ".mov" else "mp4"


def video_output(destination: Path) -> AtomicOutput:
    """The output video written whole or not at all (:func:`omniwidget._files.atomic_output`), its temporary file a ``.part``.

    The temporary file is hidden beside ``destination`` and named after it
    (``.out.mp4.1a2b3c4d.part``), with the permissions a new file gets; what a killed run
    left there is removed first. Use it in a ``with`` statement.

    Raises
    ------
    VideoError
        No temporary file can be made beside ``destination``.
    """
    try:
        return atomic_output(destination, TEMPORARY_SUFFIX)
    except OSError as exc:
        raise VideoError(f"{destination}: cannot make a temporary file next to it ({exc.strerror or exc})") from None


def spherical_to_write(info: VideoInfo, spherical: Spherical | bool | None) -> Spherical | None:
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


def _copy_stream_metadata(copied: Any, original: Any) -> None:
    copied.metadata.update({k: v for k, v in original.metadata.items() if k in ("language", "title", "handler_name")})


def frame_plane(frame: Any, index: int, dtype: type[np.generic]) -> NDArray:
    """A frame's plane as a (height, width) view of its buffer (rows padded to ``line_size``)."""
    plane = frame.planes[index]
    item = np.dtype(dtype).itemsize
    return np.frombuffer(plane, dtype).reshape(plane.height, plane.line_size // item)[:, : plane.width]


def new_frame(width: int, height: int, pix_fmt: str) -> Any:
    """A new video frame for the encoder, its planes to be filled (:func:`frame_plane`)."""
    return _av().VideoFrame(width, height, pix_fmt)


def frame_from_rgb(rgb: NDArray, rgb_format: str, pix_fmt: str, color: dict[str, int]) -> Any:
    """A video frame of ``pix_fmt`` for the encoder, converted from RGB pixels in the colour space and range ``color`` says.

    Parameters
    ----------
    rgb : ndarray of uint8 or uint16, shape (H, W, 3)
        C-contiguous.
    rgb_format : {"rgb24", "rgb48le"}
    pix_fmt : str
        The encoder's pixel format.
    color : dict of str to int
        FFmpeg's ``colorspace`` and ``color_range`` numbers (0: unspecified), as
        :attr:`VideoDecoder.color` gives them.
    """
    return (
        _av()
        .VideoFrame.from_ndarray(rgb, format=rgb_format)
        .reformat(format=pix_fmt, dst_colorspace=color["colorspace"] or None, dst_color_range=color["color_range"] or None)
    )


class VideoEncoder:
    """A video file written as frames come: one video stream encoded, the audio streams of a decoder copied packet for packet.

    Opens the file at once (use it in a ``with`` statement, which closes it); :meth:`finish`
    flushes the encoder and closes the file.

    Parameters
    ----------
    path : Path
        The file written (the temporary file of :func:`video_output`).
    target : Path
        The output it stands for: its suffix picks the container, and messages name it.
    encoding : Encoding
    size : (int, int)
        The frames' ``(width, height)``.
    decoder : VideoDecoder
        The video's source: its frame rate, time base, colour, language, metadata and audio.

    Attributes
    ----------
    frames : int
        Frames encoded so far.
    """

    def __init__(self, path: Path, target: Path, encoding: Encoding, size: tuple[int, int], decoder: VideoDecoder) -> None:
        av = _av()
        self.target = target
        self.frames = 0
        muxer = _muxer(target)
        self.output = av.open(str(path), "w", format=muxer)
        try:
            self.output.metadata.update(decoder.metadata)
            self.video = self._video_stream(encoding, size, decoder, muxer)
            self.audio = {}
            for a in decoder.audio:
                copied = self.output.add_stream_from_template(a)
                _copy_stream_metadata(copied, a)
                self.audio[a.index] = copied
            self._start(decoder)
        except BaseException:
            self._close_quietly()
            raise

    def _video_stream(self, encoding: Encoding, size: tuple[int, int], decoder: VideoDecoder, muxer: str) -> Any:
        stream = decoder.stream
        out = self.output.add_stream(encoding.codec, rate=decoder.info.rate or Fraction(30), options=encoding.options)
        out.width, out.height = size
        out.pix_fmt = encoding.pix_fmt
        # frame threads, as the ffmpeg command line has them: PyAV's default (slice threads only)
        # makes libx264 cut each frame into slices, slower and worse
        out.codec_context.thread_type = "AUTO"
        out.codec_context.thread_count = 0
        out.time_base = stream.time_base
        out.codec_context.time_base = stream.time_base
        for name, value in decoder.color.items():
            setattr(out.codec_context, name, value)
        if encoding.codec == "libx265" and muxer == "mp4":
            out.codec_context.codec_tag = "hvc1"  # what Apple's players want for HEVC in MP4
        if "language" in stream.metadata:
            out.metadata["language"] = stream.metadata["language"]
        return out

    def _start(self, decoder: VideoDecoder) -> None:
        av = _av()
        try:
            self.output.start_encoding()
        except av.FFmpegError as exc:
            what = ", ".join(decoder.info.audio) if decoder.audio else "its streams"
            raise VideoError(
                f"{decoder.info.path}: cannot write {what} into a {self.target.suffix} file ({_ffmpeg_reason(exc)}); "
                "try .mov, or convert the audio first"
            ) from None

    def __enter__(self) -> VideoEncoder:
        return self

    def __exit__(self, kind: type[BaseException] | None, *exc: object) -> None:
        if self.output is not None:
            self._close_quietly()

    def _failed(self, exc: BaseException) -> VideoError:
        """An encoder's or muxer's error (a full disk, say) said as a VideoError naming the output."""
        return VideoError(f"{self.target}: cannot encode or write the video after {self.frames} frame(s) ({_ffmpeg_reason(exc)})")

    def audio_packet(self, packet: Any) -> None:
        """Copy an audio packet of the decoder's into its stream here."""
        av = _av()
        packet.stream = self.audio[packet.stream.index]
        try:
            self.output.mux(packet)
        except av.FFmpegError as exc:
            raise self._failed(exc) from None

    def frame(self, frame: Any) -> None:
        """Encode a frame (of :attr:`Encoding.pix_fmt` and the size given) and write its packets."""
        av = _av()
        try:
            self.output.mux(self.video.encode(frame))
        except av.FFmpegError as exc:
            raise self._failed(exc) from None
        self.frames += 1

    def finish(self) -> None:
        """Flush the encoder and close the file."""
        av = _av()
        try:
            self.output.mux(self.video.encode(None))
            self.output.close()
        except av.FFmpegError as exc:
            raise self._failed(exc) from None
        self.output = None

    def _close_quietly(self) -> None:
        try:
            self.output.close()
        except Exception:  # noqa: BLE001 - the temporary file goes anyway
            pass
        self.output = None


# --- joining ranges ------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Timeline:
    """What a join takes from the source, in one reading: its frames' time stamps in the order they are shown, and its audio."""

    shown: list[int]
    sound: list[Any]
    time_base: Fraction


def _timeline(decoder: VideoDecoder) -> _Timeline:
    av = _av()
    shown: list[int] = []
    sound: list[Any] = []
    try:
        for packet in decoder.container.demux(decoder.stream, *decoder.audio):
            if not packet.size:
                continue
            if packet.stream.type == "audio":
                sound.append(packet)
            elif packet.pts is not None:
                shown.append(packet.pts)
    except av.FFmpegError as exc:
        raise VideoError(f"{decoder.info.path}: the file is broken after {len(shown)} frame(s) ({_ffmpeg_reason(exc)})") from None
    return _Timeline(sorted(shown), sound, _time_base(decoder.stream))


@contextlib.contextmanager
def _opened_segments(paths: list[Path]) -> Iterator[list[Any]]:
    """The segments open, checked to be encoded alike (codec, size, pixel format, encoder header); closed when the block ends."""
    av = _av()
    opened: list[Any] = []
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
        yield opened
    finally:
        for seg in opened:
            seg.close()


class _Joiner:
    """Writes the segments' packets on the source's timeline, the source's audio packets interleaved by their times."""

    def __init__(self, path: Path, muxer: str, first: Any, decoder: VideoDecoder, timeline: _Timeline) -> None:
        av = _av()
        self.timeline = timeline
        self.source = decoder.info.path
        self.count = 0  # frames written
        self.output = av.open(str(path), "w", format=muxer)
        try:
            self.output.metadata.update(decoder.metadata)
            self.video = self.output.add_stream_from_template(first)
            self.video.time_base = timeline.time_base
            language = decoder.stream.metadata.get("language")
            if language:
                self.video.metadata["language"] = language
            self.audio = {a.index: self.output.add_stream_from_template(a) for a in decoder.audio}
            for a in decoder.audio:
                _copy_stream_metadata(self.audio[a.index], a)
            self.output.start_encoding()
        except BaseException:
            self.output.close()
            raise
        self.pending = iter(timeline.sound)
        self.next_sound = next(self.pending, None)

    def sound_until(self, dts: Fraction | None) -> None:
        """Write the source's audio packets up to ``dts`` seconds (all that are left for None)."""
        while self.next_sound is not None and (dts is None or (self.next_sound.dts is not None and self.next_sound.dts * self.next_sound.time_base <= dts)):
            self.next_sound.stream = self.audio[self.next_sound.stream.index]
            self.output.mux(self.next_sound)
            self.next_sound = next(self.pending, None)

    def segment(self, path: Path, seg: Any) -> None:
        """Write one segment's packets, each moved to the time of the source's frame it stands for."""
        shown, time_base = self.timeline.shown, self.timeline.time_base
        v = seg.streams.video[0]
        if self.count >= len(shown):
            raise VideoError(f"{path}: the segments hold more frames than {self.source} ({len(shown)})")
        base = v.start_time  # the time stamp of the segment's first frame shown (the container says it)
        begin = Fraction(shown[self.count]) * time_base  # where that frame is shown in the source
        for q in seg.demux(v):  # packet by packet: a segment is never held in memory whole
            if not q.size:
                continue
            if q.pts is None or base is None:
                raise VideoError(f"{path}: a frame of this segment has no time stamp")
            if self.count >= len(shown):
                raise VideoError(f"{path}: the segments hold more frames than {self.source} ({len(shown)})")
            self.count += 1
            pts = begin + (int(q.pts) - base) * _time_base(v)
            dts = begin + (int(q.dts if q.dts is not None else q.pts) - base) * _time_base(v)
            self.sound_until(dts)
            q.pts, q.dts = round(pts / time_base), round(dts / time_base)
            q.time_base = time_base
            q.stream = self.video
            self.output.mux(q)

    def close(self) -> None:
        self.output.close()


def join_video_segments(
    segments: Sequence[str | os.PathLike[str]],
    destination: str | os.PathLike[str],
    *,
    source: str | os.PathLike[str],
    spherical: Spherical | bool | None = None,
) -> VideoReport:
    """Join videos warped range by range into one, without re-encoding; the sound from the source.

    The segments are the outputs of :func:`omniwidget.app.video.warp_video` with ``audio=False`` on consecutive
    ranges that together cover the whole ``source`` (``start=`` one range's ``end``). Their
    packets are copied byte for byte and put back on the source's timeline: the frames are
    the source's frames in the order they are shown, so the ``i``-th frame written takes the
    time stamp of the source's ``i``-th frame. The source's audio streams are copied packet
    for packet beside them, its metadata and spherical metadata as the warp keeps them.

    Parameters
    ----------
    segments : sequence of path-like
        The warped ranges in order; each starts with a key frame (as the warp writes them),
        all with the same encoder settings and frame size.
    destination : path-like
        ``.mp4``, ``.m4v`` or ``.mov``; written whole at the end, never one of the inputs.
    source : path-like
        The video the segments were warped from.
    spherical : Spherical or bool, optional
        The spherical metadata written (:func:`spherical_to_write`): the source's by default.

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
    source, destination = Path(source), Path(destination)
    paths = [Path(p) for p in segments]
    if not paths:
        raise VideoError(f"{destination}: no segments to join")
    muxer = check_output(source, destination)
    clash = next((p for p in paths if same_file(p, destination)), None)
    if clash is not None:
        raise VideoError(f"{destination}: the output would overwrite its segment {clash}")
    info = probe_video(source)
    written = spherical_to_write(info, spherical)
    tick = time.perf_counter()
    with VideoDecoder(info) as decoder:
        timeline = _timeline(decoder)
        with video_output(destination) as out, _opened_segments(paths) as opened:
            first = opened[0].streams.video[0]
            _join(out.path, muxer, decoder, timeline, zip(paths, opened, strict=True), destination)
            if written is not None:
                write_spherical(out.path, written, in_place=True)
    return VideoReport(
        source=source,
        destination=destination,
        frames=len(timeline.shown),
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


def _join(path: Path, muxer: str, decoder: VideoDecoder, timeline: _Timeline, segments: Iterable[tuple[Path, Any]], destination: Path) -> None:
    """Write the segments, then the audio left, into ``path``; refuse segments whose frames are not the source's."""
    av = _av()
    joiner: _Joiner | None = None
    try:
        segments = list(segments)
        joiner = _Joiner(path, muxer, segments[0][1].streams.video[0], decoder, timeline)
        for seg_path, seg in segments:
            joiner.segment(seg_path, seg)
        if joiner.count != len(timeline.shown):
            raise VideoError(f"the segments hold {joiner.count} frame(s) but {decoder.info.path} has {len(timeline.shown)}: a range is missing")
        joiner.sound_until(None)
    except av.FFmpegError as exc:
        raise VideoError(f"{destination}: cannot write the joined video ({_ffmpeg_reason(exc)})") from None
    finally:
        if joiner is not None:
            joiner.close()
