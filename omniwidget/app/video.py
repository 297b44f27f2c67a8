"""A 360° video warped by one map: every frame decoded, resampled and encoded, its sound and metadata kept.

:func:`warp_video` is what ``omniwidget warp IN.mp4 ... -o OUT.mp4``, the editor's Save video
and the batches' time ranges run: the map is computed once (from the first frame with
:func:`~omniwidget.raster.pipeline.warp`, or given), turned into source pixel coordinates
once (:func:`~omniwidget.app.frames.map_coordinates`), and every frame is then only decoded
(:class:`~omniwidget.io.video.VideoDecoder`), resampled
(:func:`~omniwidget.raster.warping.remap_panorama`) and encoded
(:class:`~omniwidget.io.video.VideoEncoder`) into a temporary file renamed over the output
at the end (:func:`~omniwidget.io.video.video_output`). Time stamps, frame rate and duration
are kept, audio streams are copied packet for packet, and the spherical metadata is carried
over.

Speed. Decoding, resampling and encoding overlap on threads (FFmpeg's decoders and encoders
and OpenCV's ``remap`` release the GIL; the decoder and libx264 run their own threads too).
A ``yuv420p`` (or ``yuv420p10le``) video is resampled plane by plane without a colour
conversion: the luma plane with the map's coordinates, the two half-size chroma planes with
the map at half resolution (:func:`half_resolution_map`), so a frame costs about 1.5
single-channel remaps. Other pixel formats are converted to RGB (48-bit for deeper than 8
bits), resampled, and converted back.
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import queue
import threading
import time
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._lazy import lazy
from ..errors import VideoError
from ..io.spherical import Spherical, write_spherical
from ..io.video import (
    PLANE_FORMATS,
    TEMPORARY_SUFFIX,
    Encoding,
    VideoDecoder,
    VideoEncoder,
    VideoInfo,
    VideoReader,
    VideoReport,
    check_complete,
    check_output,
    choose_encoding,
    frame_from_rgb,
    frame_plane,
    new_frame,
    probe_video,
    spherical_to_write,
    time_range,
    video_output,
)
from ..raster import pipeline
from ..raster.warping import ORDERS, Order, remap_panorama
from .frames import map_coordinates

if TYPE_CHECKING:
    import cv2

    from ..document.handles import Handles
else:
    cv2 = lazy("cv2")

__all__ = ["TEMPORARY_SUFFIX", "Progress", "VideoCancelled", "VideoSettings", "half_resolution_map", "warp_video"]

#: ``progress(done, total)``: frames encoded so far and the expected count (None if unknown);
#: return False to cancel.
Progress = Callable[[int, "int | None"], "bool | None"]


class VideoCancelled(Exception):
    """:func:`warp_video` stopped because it was asked to (``cancel`` set, or ``progress`` returned False); no output was written."""


@dataclass(frozen=True)
class VideoSettings:
    """How a video is warped and encoded: :func:`warp_video`'s settings, all optional.

    Attributes
    ----------
    width : int, optional
        With handles: the output width, a multiple of 4 (default: the input's).
    order : {"nearest", "bilinear", "bicubic"}
    codec : str, optional
        The FFmpeg encoder; default :func:`~omniwidget.io.video.default_codec` (libx264;
        libx265 for 10-bit).
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
        its own thread pool on top of these busy-waits between calls.
    start, end : float, optional
        Warp only the frames shown from ``start`` up to, not including, ``end``: seconds on
        the input's timeline (:attr:`~omniwidget.io.video.VideoInfo.start` is its first
        frame). The output then starts at 0 with the first of those frames, and holds the
        audio packets that start in the range (whole packets: a range is cut at frames, not
        at audio samples). Each range is encoded on its own, from a key frame, so ranges
        warped on different machines join without re-encoding
        (:func:`~omniwidget.io.video.join_video_segments`).
    audio : bool
        Copy the audio streams (default); False writes the video alone.

    Raises
    ------
    ValueError
        An ``order`` that is not one of :data:`~omniwidget.raster.warping.ORDERS`.
    VideoError
        A ``width`` that is not a multiple of 4.
    """

    width: int | None = None
    order: Order = "bilinear"
    codec: str | None = None
    crf: int | None = None
    preset: str | None = None
    spherical: Spherical | bool | None = None
    workers: int | None = None
    start: float | None = None
    end: float | None = None
    audio: bool = True

    def __post_init__(self) -> None:
        if self.order not in ORDERS:
            raise ValueError(f"order must be one of {', '.join(ORDERS)}, got {self.order!r}")
        if self.width is not None and (self.width < 4 or self.width % 4):
            raise VideoError(f"--width {self.width}: a video's width must be a multiple of 4 (4:2:0 video has even sizes)")


def _settings(settings: VideoSettings | None, options: dict[str, Any]) -> VideoSettings:
    """``settings`` (default :class:`VideoSettings`) with the fields named in ``options`` replaced."""
    names = {f.name for f in dataclasses.fields(VideoSettings)}
    unknown = sorted(set(options) - names)
    if unknown:
        raise TypeError(f"warp_video() got unexpected keyword argument(s) {', '.join(unknown)}; its settings are {', '.join(sorted(names))}")
    return dataclasses.replace(settings or VideoSettings(), **options)


# --- the map, for planes ------------------------------------------------------------------------


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
        if self.planes:
            dtype = np.uint16 if self.deep else np.uint8
            out = new_frame(self.out_w, self.out_h, self.out_format)
            for k in range(3):
                coordinates = self.chroma if k and self.chroma is not None else self.luma
                frame_plane(out, k, dtype)[...] = remap_panorama(frame_plane(frame, k, dtype), coordinates, self.order)
        else:
            rgb_format = "rgb48le" if self.deep else "rgb24"
            rgb = frame.to_ndarray(format=rgb_format, src_color_range=frame.color_range)
            warped = np.ascontiguousarray(remap_panorama(rgb, self.luma, self.order))
            out = frame_from_rgb(warped, rgb_format, self.out_format, self.color)
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
    busy-waits between calls (``bench/bench_video.py`` measures it). The setting is
    OpenCV's, for the whole process.
    """
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


# --- the frames in flight: decoded on one thread, resampled on others, encoded in order ---------


def _put(q: queue.Queue[Any], item: Any, stop: threading.Event) -> bool:
    """Put ``item`` unless ``stop`` is set first; whether it was put."""
    while not stop.is_set():
        try:
            q.put(item, timeout=0.1)
            return True
        except queue.Full:
            continue
    return False


class _Flight:
    """The decoder on a thread of its own handing on audio packets and frame warps (futures), in order, to the caller.

    A context manager: leaving it stops the decoding thread (it may wait for room in the
    queue) and the resampling pool, the frames not started dropped.
    """

    def __init__(self, decoder: VideoDecoder, span: tuple[Fraction, Fraction] | None, warper: _Warper, workers: int | None) -> None:
        self.decoder, self.span, self.warper = decoder, span, warper
        self.stop = threading.Event()
        self.items: queue.Queue[Any] = queue.Queue(maxsize=8)
        self.pool = ThreadPoolExecutor(max(1, workers or 2), thread_name_prefix="omniwidget-warp")
        self.thread = threading.Thread(target=self._decode, name="omniwidget-decode", daemon=True)

    def __enter__(self) -> _Flight:
        self.thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop.set()
        while self.thread.is_alive():  # unblock it if it waits for room in the queue
            try:
                self.items.get_nowait()
            except queue.Empty:
                self.thread.join(0.05)
        self.pool.shutdown(wait=True, cancel_futures=True)

    def _decode(self) -> None:
        """Demux and decode on this thread; hand audio packets and frame warps to the caller."""
        try:
            for kind, value in self.decoder.items(self.span):
                if self.stop.is_set():
                    return
                item = (kind, value if kind == "audio" else self.pool.submit(self.warper, value))
                if not _put(self.items, item, self.stop):
                    return
        except BaseException as exc:  # handed to the caller, raised there
            _put(self.items, ("error", exc), self.stop)
        else:
            _put(self.items, ("end", None), self.stop)

    def __iter__(self) -> Iterator[tuple[str, Any]]:
        """``("audio", packet)`` and ``("video", warped frame)`` in order; a decoding error raised here."""
        while True:
            kind, value = self.items.get()
            if kind == "error":
                raise value
            if kind == "end":
                return
            yield kind, value.result() if kind == "video" else value


@dataclass(frozen=True)
class _Watch:
    """The caller's say after each frame: ``progress`` told, ``cancel`` looked at."""

    progress: Progress | None
    cancel: threading.Event | None
    expected: int | None
    destination: Path

    def frame_done(self, done: int) -> None:
        cancelled = (self.cancel is not None and self.cancel.is_set()) or (self.progress is not None and self.progress(done, self.expected) is False)
        if cancelled:
            raise VideoCancelled(f"cancelled after {done} frame(s); {self.destination} was not written")


def _transcode(flight: _Flight, encoder: VideoEncoder, watch: _Watch) -> float | None:
    """Encode what the flight hands on, in order; the end of the last frame shown, in seconds (None if no frame said its time)."""
    last_end = None
    for kind, value in flight:
        if kind == "audio":
            encoder.audio_packet(value)
            continue
        if value.time is not None:
            last_end = value.time + (float(value.duration * value.time_base) if value.duration else 0.0)
        encoder.frame(value)
        watch.frame_done(encoder.frames)
    return last_end


# --- warp_video --------------------------------------------------------------------------------


def warp_video(
    source: str | os.PathLike[str],
    destination: str | os.PathLike[str],
    inverse_map: ArrayLike | None = None,
    *,
    handles: Handles | None = None,
    settings: VideoSettings | None = None,
    progress: Progress | None = None,
    cancel: threading.Event | None = None,
    **options: Any,
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
    settings : VideoSettings, optional
        The output width, resampling, encoder, spherical metadata, threads, time range and
        audio (:class:`VideoSettings`; its defaults by default).
    progress : callable, optional
        ``progress(done, total)`` after each frame is encoded, on the calling thread;
        ``total`` is the expected frame count or None. Returning False cancels.
    cancel : threading.Event, optional
        Set from another thread to cancel (checked after each frame).
    **options
        Fields of :class:`VideoSettings` by name (``crf=0``, ``start=1.5``, ...), replacing
        those of ``settings``.

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
    TypeError
        Neither or both of ``inverse_map`` and ``handles``; an option that is no setting.
    VideoCancelled
        When cancelled; no output is written.
    KeyboardInterrupt
        Passed on after the temporary file is removed.
    """
    setting = _settings(settings, options)
    source, destination = Path(source), Path(destination)
    if (inverse_map is None) == (handles is None):
        raise TypeError("give exactly one of inverse_map and handles")
    span = time_range(setting.start, setting.end)
    check_output(source, destination)
    info = _panorama_video(source)
    tick = time.perf_counter()
    the_map, warnings = _the_map(info, inverse_map, handles, setting)
    encoding = choose_encoding(info, setting.codec, setting.crf, setting.preset)
    with VideoDecoder(info, audio=setting.audio) as decoder:
        warper = _Warper(np.asarray(the_map, np.float32), (info.width, info.height), info.pix_fmt, encoding.pix_fmt, setting.order, decoder.color)
        map_seconds = time.perf_counter() - tick
        written = spherical_to_write(info, setting.spherical)
        watch = _Watch(progress, cancel, _expected_frames(info, span), destination)
        with video_output(destination) as out, _opencv_single_threaded():
            tick = time.perf_counter()
            frames = _encode_all(out.path, destination, encoding, decoder, warper, span, watch, setting.workers)
            seconds = time.perf_counter() - tick
            if written is not None:
                write_spherical(out.path, written, in_place=True)
    return VideoReport(
        source=source,
        destination=destination,
        frames=frames,
        seconds=seconds,
        map_seconds=map_seconds,
        size=(warper.out_w, warper.out_h),
        codec=encoding.codec,
        pix_fmt=encoding.pix_fmt,
        options=encoding.options,
        planes=warper.planes,
        audio=info.audio,
        dropped=info.others,
        spherical=written,
        warnings=warnings,
    )


def _panorama_video(source: Path) -> VideoInfo:
    """What ``source`` holds, once it is a full equirectangular video whose frames 4:2:0 can hold."""
    info = probe_video(source)
    problem = info.panorama_problem()
    if problem is not None:
        raise VideoError(f"{source}: {problem}")
    if info.height % 2 and info.pix_fmt in PLANE_FORMATS:
        raise VideoError(f"{source}: the frames are {info.width} x {info.height}; 4:2:0 video needs an even height")
    return info


def _the_map(info: VideoInfo, inverse_map: ArrayLike | None, handles: Handles | None, setting: VideoSettings) -> tuple[NDArray, tuple[str, ...]]:
    """The inverse map the frames are warped by (given, or the warp of the first frame by ``handles``) and its warnings."""
    warnings: tuple[str, ...] = ()
    if handles is not None:
        with VideoReader(info.path, depth=16 if info.bits > 8 else 8) as video:
            first = video.read_at(info.start)
        result = pipeline.warp(first, handles, width=setting.width, order=setting.order, warn=False)
        warnings = result.warnings
        the_map = result.inverse_map()
    else:
        the_map = np.asarray(inverse_map)
        if setting.width is not None and the_map.ndim == 3 and setting.width != the_map.shape[1]:
            raise VideoError(f"--width {setting.width}: the map makes frames {the_map.shape[1]} wide")
    if the_map.ndim != 3 or the_map.shape[0] % 2 or the_map.shape[1] % 4:
        raise VideoError(f"the map is {the_map.shape[1]} x {the_map.shape[0]}: a video's output width must be a multiple of 4")
    return the_map, warnings


def _expected_frames(info: VideoInfo, span: tuple[Fraction, Fraction] | None) -> int | None:
    """The frames the output is expected to hold (for ``progress``): the header's count, or duration times rate."""
    if span is None:
        return info.frames or (round(info.duration * float(info.rate)) if info.duration and info.rate else None)
    if not (info.rate and info.duration):
        return None
    covered = min(float(span[1]), info.start + info.duration) - max(float(span[0]), info.start)
    return max(0, round(covered * float(info.rate)))


def _encode_all(
    path: Path,
    destination: Path,
    encoding: Encoding,
    decoder: VideoDecoder,
    warper: _Warper,
    span: tuple[Fraction, Fraction] | None,
    watch: _Watch,
    workers: int | None,
) -> int:
    """Decode, resample and encode every frame (of the range) into ``path``; the frames written, once the count is checked."""
    with VideoEncoder(path, destination, encoding, (warper.out_w, warper.out_h), decoder) as encoder:
        with _Flight(decoder, span, warper, workers) as flight:
            last_end = _transcode(flight, encoder, watch)
        if span is None:
            check_complete(decoder.info, encoder.frames, last_end)
        elif encoder.frames == 0:
            raise VideoError(f"{decoder.info.path}: no frame is shown from {float(span[0]):g} s to {float(span[1]):g} s")
        encoder.finish()
        return encoder.frames
