"""Batches beyond one machine: many panoramas and long 360° videos warped alike, in-process or on a Dask cluster.

:func:`warp_files` warps each input file by one handles document or one saved map and
writes its output, either here (threads, the default) or on a :mod:`dask.distributed`
cluster (``client=`` a :class:`distributed.Client` or a scheduler's address). Every file is
its own task; only paths travel through the scheduler, never pixels: each worker reads its
inputs and writes its outputs on storage it shares with the others (a network file system,
say), so the paths must name the same files on every worker.

What travels once per worker, not once per task: a small *recipe* (the handles document, or
the saved map, plus the output width, the resampling and the fit), scattered to every
worker with ``client.scatter(..., broadcast=True)`` before the tasks are sent. From it each
worker computes what it needs once per size and keeps it while the batch runs:

- with ``handles=``, the inverse map for each output width (``warp(...).inverse_map()``,
  what ``omniwidget warp`` computes from its first frame; it depends only on the handles
  and the output width), then the source coordinates for each input width;
- with ``map=``, only the source coordinates for each input width (the map is in degrees,
  so one map serves inputs of any size).

Why on the workers rather than once on the client: the client need not see the files (it
would have to read them to learn their sizes), panoramas of several sizes are met where they
are read, and the map of a large output (268 MB of float32 at 8192 x 4096) is not sent from
the client to every worker, while the handles are a few hundred bytes. The workers compute
it at the same time, so on separate machines the batch waits for one map computation; the
price is that computation's CPU time once per worker (and several workers on one machine
share its cores meanwhile). The computation is deterministic (the same bytes in any process
with the same versions; the batch warns about workers whose omniwidget, numpy or OpenCV
differ), so the outputs are the bytes a local run writes. To compute a map only once in
all, save it (``omniwidget warp FRAME -H handles.json --map map.npy``, or
``Result.inverse_map()``) and pass it as ``map=``: it is then sent once to every worker.
(A map computed as one Dask task that the other tasks wait for was tried and dropped: a task
waiting for it must leave its thread to the map's task, and the scheduler then starts more
tasks, each holding a decoded image, for as long as the map takes.)

Videos: a video is cut into equal time ranges (``segment_seconds``). A first task reads its
length and plans the ranges (on a worker: the client need not see the file), one task per
range warps it into a hidden file beside the output
(:func:`~omniwidget.app.video.warp_video` with ``start``/``end``, video only, from a key frame),
and a last task, which Dask starts when all the ranges are written, joins them without
re-encoding (:func:`~omniwidget.io.video.join_video_segments`, the source's sound copied
beside them); then the range files are removed. In-process the same ranges are warped one
after the other, so the bytes are the same either way.

Failures: a task that raises is run again up to ``retries`` times (Dask's ``retries=``, or a
loop in-process); a task whose worker dies is rescheduled by Dask itself (up to the
scheduler's ``distributed.scheduler.allowed-failures``). A file that still fails is listed
in the :class:`BatchReport` with its error and the others are written all the same.
Outputs are written through a temporary file and a rename
(:func:`~omniwidget.io.images.write_image`): a worker killed mid-write leaves at most a
temporary file, which the task's next attempt removes, and never a partial output; an
attempt run twice writes the same bytes twice. So no output is lost, duplicated or half
written.
"""

from __future__ import annotations

import dataclasses
import hashlib
import os
import re
import threading
import time
import uuid
from collections import OrderedDict
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._files import refuse_overwrites, remove_leftovers
from .._lazy import lazy, resolve
from .._version import __version__
from ..document.handles import Handles, load_handles
from ..errors import ImageError, OmniwidgetError, VideoError
from ..io import frames, images, metadata
from ..io import video as io_video
from ..io.video import OUTPUT_SUFFIXES as VIDEO_OUTPUT_SUFFIXES
from ..io.video import is_video_path
from ..raster import pipeline, warping
from . import frames as app_frames
from . import video as app_video
from .video import VideoSettings

if TYPE_CHECKING:
    import cv2
    import distributed
    from distributed import Client

    from ..io.images import Fit
    from ..raster.warping import Order
else:
    cv2 = lazy("cv2")
    distributed = lazy("distributed")

__all__ = ["BatchReport", "BatchSettings", "FileReport", "warp_files"]

#: File suffixes an output may have (the formats :func:`~omniwidget.io.images.write_image` writes).
OUTPUT_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".webp", ".bmp", ".npy")

#: Source coordinates (and, with a fixed output width, inverse maps) a process keeps, least
#: recently used dropped first: one per input size, each 2 x 4 bytes per output pixel.
CACHE_ENTRIES = 4

#: Where the task keys of a batch start: the name of its task group on the Dask dashboard.
TASK_PREFIX = "omniwidget-warp"

#: How long, in seconds, the time ranges a video is cut into are by default (one task each).
SEGMENT_SECONDS = 60.0


@dataclass(frozen=True)
class FileReport:
    """What happened to one input of :func:`warp_files`.

    Attributes
    ----------
    input, output : Path
        The file read and the file written (as given: paths on the workers' storage).
    seconds : float or None
        Time of the attempt that succeeded, reading and writing included (and computing
        the map, for the first file of its size on a worker); None if it failed.
    error : str or None
        Why the file was not written (after every retry), naming it; None if it was.
    worker : str or None
        Where it ran: the Dask worker's address, ``"local"`` in-process; None if it failed.
    task : str or None
        The Dask task's key (its history: ``client.story(task)``); None in-process.
    map_seconds : float
        The part of ``seconds`` spent computing a map or source coordinates (0 when the
        worker had them already).
    segments : int
        The time ranges a video was cut into, each a task (their seconds added up in
        ``seconds``; ``worker`` and ``task`` are those of the task that joined them); 1
        for an image.
    """

    input: Path
    output: Path
    seconds: float | None = None
    error: str | None = None
    worker: str | None = None
    task: str | None = None
    map_seconds: float = 0.0
    segments: int = 1

    @property
    def ok(self) -> bool:
        """The output was written."""
        return self.error is None


@dataclass(frozen=True)
class BatchReport:
    """What :func:`warp_files` did: one :class:`FileReport` per input, in the order of the inputs.

    Attributes
    ----------
    files : tuple of FileReport
    seconds : float
        Wall time of the whole batch, as the caller waited for it.
    scheduler : str or None
        The Dask scheduler's address; None for an in-process run.
    workers : int
        Dask workers when the batch started, or threads in-process.
    warnings : tuple of str
        Conflicts the warp found in the handles (lines that cross, fold-overs), each once;
        and workers whose omniwidget, numpy or OpenCV differ from the caller's.
    """

    files: tuple[FileReport, ...]
    seconds: float
    scheduler: str | None = None
    workers: int = 1
    warnings: tuple[str, ...] = field(default=())

    @property
    def written(self) -> tuple[Path, ...]:
        """Outputs written, in the order of the inputs."""
        return tuple(f.output for f in self.files if f.ok)

    @property
    def failed(self) -> tuple[tuple[Path, str], ...]:
        """Inputs not warped, and why (``(input, error)``)."""
        return tuple((f.input, f.error) for f in self.files if f.error is not None)

    @property
    def ok(self) -> bool:
        """Every output was written."""
        return all(f.ok for f in self.files)

    @property
    def files_per_second(self) -> float:
        """Files written per second of wall time."""
        return len(self.written) / self.seconds if self.seconds > 0 else float("inf")

    def summary(self) -> str:
        """A few lines for a person: how many were written where and how fast, then each failure."""
        where = (
            f"on the Dask cluster at {self.scheduler} ({self.workers} worker(s))"
            if self.scheduler
            else f"in-process ({self.workers} thread(s))"
        )
        lines = [
            f"warped {len(self.written)} of {len(self.files)} file(s) {where} in {self.seconds:.2f} s: "
            f"{self.files_per_second:.2f} files per second"
        ]
        lines += [f"failed: {error}" for _, error in self.failed]
        return "\n".join(lines)


@dataclass(frozen=True)
class BatchSettings:
    """How every file of :func:`warp_files` is warped and written, and where an in-process batch runs.

    Attributes
    ----------
    width : int, optional
        Output width (even); default the input's (with a map, the map's).
    order : {"nearest", "bilinear", "bicubic"}
    fit : {"pad", "stretch"}, optional
        Make each input 2:1 first (:func:`~omniwidget.io.images.to_equirectangular`); by
        default an input that is not 2:1 fails.
    workers : int, optional
        Threads for an in-process run (default: CPUs + 1); a cluster has its own workers.
    segment_seconds : float
        About how long each time range of a video is (the ranges of one video are equal).
        Each range starts with a key frame, so a shorter range costs a little more bit rate.
    codec, crf, preset : optional
        The videos' encoder settings (:class:`~omniwidget.app.video.VideoSettings`).
    spherical : bool, optional
        The videos' spherical metadata: the input's (None), the input's or plain
        equirectangular (True), none (False).

    Raises
    ------
    ValueError
        A bad ``order``, ``fit``, ``width``, ``workers`` or ``segment_seconds``.
    """

    width: int | None = None
    order: Order = "bilinear"
    fit: Fit | None = None
    workers: int | None = None
    segment_seconds: float = SEGMENT_SECONDS
    codec: str | None = None
    crf: int | None = None
    preset: str | None = None
    spherical: bool | None = None

    def __post_init__(self) -> None:
        seconds = self.segment_seconds
        if isinstance(seconds, bool) or not isinstance(seconds, (int, float)) or not 0 < seconds < float("inf"):
            raise ValueError(f"segment_seconds must be a positive number of seconds, got {seconds!r}")
        if self.order not in warping.ORDERS:
            raise ValueError(f"order must be one of {', '.join(warping.ORDERS)}, got {self.order!r}")
        if self.fit is not None and self.fit not in images.FITS:
            raise ValueError(f"fit must be None or one of {', '.join(images.FITS)}, got {self.fit!r}")
        width = self.width
        if width is not None and (isinstance(width, bool) or not isinstance(width, (int, np.integer)) or width < 2 or width % 2):
            raise ValueError(f"width must be an even integer of at least 2, got {width!r}")
        if self.workers is not None and self.workers < 1:
            raise ValueError(f"workers must be at least 1, got {self.workers!r}")

    @property
    def video(self) -> VideoSettings:
        """What each time range of a video is warped with (:func:`~omniwidget.app.video.warp_video`)."""
        return VideoSettings(order=self.order, codec=self.codec, crf=self.crf, preset=self.preset, spherical=self.spherical)


@dataclass(frozen=True)
class _Recipe:
    """What every task needs besides its two paths; sent once to each worker."""

    handles: Handles | None
    inverse_map: NDArray[np.floating] | None
    settings: BatchSettings
    digest: str  # names the handles or the map in the workers' caches

    @property
    def width(self) -> int | None:
        return None if self.settings.width is None else int(self.settings.width)

    @property
    def order(self) -> Order:
        return self.settings.order

    @property
    def fit(self) -> Fit | None:
        return self.settings.fit


def _recipe(handles: Any, inverse_map: Any, settings: BatchSettings) -> _Recipe:
    if (handles is None) == (inverse_map is None):
        raise ValueError("give either handles= (a Handles document or a handles file) or map= (an inverse map or a .npy file)")
    width = settings.width
    if handles is not None:
        doc = handles if isinstance(handles, Handles) else load_handles(handles)
        digest = hashlib.sha256(doc.to_json(indent=None).encode()).hexdigest()
        return _Recipe(doc, None, settings, f"handles-{digest}")
    if isinstance(inverse_map, (str, os.PathLike)):
        m: NDArray[np.floating] = frames.load_map(inverse_map)
    else:
        m = np.ascontiguousarray(inverse_map)
        app_frames.map_coordinates(m, 2)  # checks it is a map: ImageError saying what is wrong
    if width is not None and width != m.shape[1]:
        raise ValueError(f"width={width}: the map makes outputs {m.shape[1]} wide")
    digest = hashlib.sha256(m.tobytes()).hexdigest()
    return _Recipe(None, m, settings, f"map-{m.dtype.str}-{m.shape[0]}-{digest}")


# --- on each worker (or in-process): the maps kept per size, one file's work -----------------

_cache: OrderedDict[tuple[Any, ...], Any] = OrderedDict()
_cache_lock = threading.Lock()
_computing: dict[tuple[Any, ...], threading.Lock] = {}


def _cached(key: tuple[Any, ...], make: Callable[[], Any]) -> tuple[Any, bool]:
    """``(make(), True)`` the first time ``key`` is asked for in this process, else ``(the kept value, False)``.

    Threads asking for the same key at once wait for one computation (``make`` never waits
    for the cluster, so a waiting thread cannot hold up what it waits for).
    """
    with _cache_lock:
        if key in _cache:
            _cache.move_to_end(key)
            return _cache[key], False
        lock = _computing.setdefault(key, threading.Lock())
    with lock:
        with _cache_lock:
            if key in _cache:
                _cache.move_to_end(key)
                return _cache[key], False
        value = make()
        with _cache_lock:
            _cache[key] = value
            while len(_cache) > CACHE_ENTRIES:
                _cache.popitem(last=False)
            _computing.pop(key, None)
        return value, True


def _forget(digest: str) -> None:
    """Drop what this process keeps for one batch's handles or map (run on every worker when a batch ends)."""
    with _cache_lock:
        for key in [k for k in _cache if k[1] == digest]:
            del _cache[key]


def _environment() -> dict[str, str]:
    """The versions that decide an output's bytes, in this process."""
    return {"omniwidget": __version__, "numpy": np.__version__, "OpenCV": cv2.__version__}


def _make_inverse_map(handles: Handles, width: int, order: Order) -> tuple[NDArray[np.floating], tuple[str, ...]]:
    """The inverse map of ``handles`` at ``width``, and the warp's warnings: what ``omniwidget warp`` computes from its first frame.

    It depends on the handles and the output width only (not on the pixels nor the input's
    size), so a one-pixel source will do.
    """
    result = pipeline.warp(np.zeros((1, 2), np.uint8), handles, width=width, order=order, warn=False)
    return result.inverse_map(), tuple(result.warnings)


def _output_width(recipe: _Recipe, src_width: int) -> int:
    return recipe.inverse_map.shape[1] if recipe.inverse_map is not None else (recipe.width or src_width)


def _inverse_map(recipe: _Recipe, out_width: int, keep: bool) -> tuple[NDArray[np.floating], tuple[str, ...]]:
    """The recipe's inverse map at ``out_width`` and the warp's warnings; kept in this process when ``keep``."""
    if recipe.inverse_map is not None:
        return recipe.inverse_map, ()
    if recipe.handles is None:
        raise ValueError("a recipe has handles or a map")
    make = partial(_make_inverse_map, recipe.handles, out_width, recipe.order)
    if not keep:
        return make()
    value: tuple[NDArray[np.floating], tuple[str, ...]] = _cached(("inverse", recipe.digest, out_width), make)[0]
    return value


def _coordinates(recipe: _Recipe, src_width: int) -> tuple[NDArray[np.float32], tuple[str, ...], float]:
    """Source coordinates for inputs ``src_width`` wide, the warp's warnings, and the seconds this call spent making them."""
    start = time.perf_counter()
    out_width = _output_width(recipe, src_width)

    def make() -> tuple[NDArray[np.float32], tuple[str, ...]]:
        # a map of a fixed output width serves inputs of every size: kept; one of the input's size serves these coordinates only
        inverse_map, warnings = _inverse_map(recipe, out_width, keep=recipe.width is not None)
        return app_frames.map_coordinates(inverse_map, src_width), warnings

    (coordinates, warnings), made = _cached(("coordinates", recipe.digest, out_width, src_width), make)
    return coordinates, warnings, (time.perf_counter() - start) if made else 0.0


def _warp_file(recipe: _Recipe, src: str, dst: str, make_folder: bool) -> tuple[float, float, tuple[str, ...]]:
    """Read ``src``, warp it, write ``dst`` whole; ``(seconds, map seconds, warnings)``. Raises on any failure."""
    start = time.perf_counter()
    source, target = Path(src), Path(dst)
    frame = images.read_panorama(source, recipe.fit)
    coordinates, warnings, map_seconds = _coordinates(recipe, frame.shape[1])
    out = warping.remap_panorama(frame, coordinates, recipe.order)
    if make_folder:
        target.parent.mkdir(exist_ok=True)
    # the input's metadata brought up to date, as omniwidget warp writes it (--no-gpano is not sent to the workers)
    levelled = recipe.handles is not None and recipe.handles.options.up is not None
    meta = metadata.output_metadata(metadata.read_metadata(source), out.shape[1], out.shape[0], levelled=levelled)
    images.write_image(target, out, meta)  # what a killed attempt left beside it is removed first (omniwidget._files)
    return time.perf_counter() - start, map_seconds, warnings


# --- videos: cut into time ranges, each warped by a task, then joined without re-encoding ---------


def _plan_video(src: str, dst: str, segment_seconds: float) -> tuple[int, tuple[tuple[float | None, float | None], ...]]:
    """The video's frame width, and the time ranges ``(start, end)`` it is cut into.

    The ranges are in seconds on its timeline (None: open), equal, about ``segment_seconds``
    long. The ranges a killed batch cut otherwise left beside ``dst`` are removed, before any
    range of this one is written; those of this count are this batch's (a plan run again when
    its worker died while the ranges were written) or are written over and removed by it.
    """
    info = io_video.probe_video(src)
    problem = info.panorama_problem()
    if problem is not None:
        raise VideoError(f"{src}: {problem}")
    count = max(1, round(info.duration / segment_seconds)) if info.duration else 1
    _remove_segments(_stale_segments(Path(dst), count))
    cuts: list[float | None] = [info.start + k * info.duration / count for k in range(1, count)] if info.duration else []
    return info.width, tuple(zip([None, *cuts], [*cuts, None], strict=True))


def _segment_paths(dst: Path, count: int) -> list[Path]:
    """Where a video's ranges are written before they are joined: hidden files beside the output."""
    return [dst.parent / f".{dst.name}.{k + 1:03d}of{count:03d}{dst.suffix}" for k in range(count)]


def _stale_segments(dst: Path, count: int) -> list[str]:
    """The ranges of ``dst`` on the disk now, named as :func:`_segment_paths` names them, cut in other than ``count``."""
    pattern = re.compile(re.escape(f".{dst.name}.") + r"\d{3}of(\d{3})" + re.escape(dst.suffix))
    try:
        names = os.listdir(dst.parent)
    except OSError:  # no folder yet
        return []
    return [str(dst.parent / n) for n in names if (m := pattern.fullmatch(n)) is not None and int(m[1]) != count]


def _warp_segment(
    recipe: _Recipe, src: str, src_width: int, seg: str, start: float | None, end: float | None, make_folder: bool
) -> tuple[float, float, tuple[str, ...]]:
    """Warp one time range of a video ``src_width`` wide into ``seg`` (video only, from a key frame); ``(seconds, map seconds, warnings)``."""
    tick = time.perf_counter()
    target = Path(seg)
    if make_folder:
        target.parent.mkdir(exist_ok=True)
    out_width = _output_width(recipe, src_width)
    before = time.perf_counter()
    inverse_map, warnings = _inverse_map(recipe, out_width, keep=True)
    map_seconds = time.perf_counter() - before
    app_video.warp_video(src, target, inverse_map, settings=recipe.settings.video, spherical=False, start=start, end=end, audio=False)
    return time.perf_counter() - tick, map_seconds, warnings


def _join_segments(recipe: _Recipe, src: str, segs: Sequence[str], dst: str, done: Sequence[tuple[Any, ...]]) -> tuple[float, float, tuple[str, ...]]:
    """Join a video's warped ranges into ``dst`` with the source's sound; the ranges' ``(seconds, map seconds, warnings)`` summed."""
    report = io_video.join_video_segments(segs, dst, source=src, spherical=recipe.settings.spherical)
    warnings = tuple(dict.fromkeys(w for d in done for w in d[2]))
    return report.seconds + sum(d[0] for d in done), sum(d[1] for d in done), warnings


def _remove_segments(segs: Sequence[str]) -> None:
    """Remove a video's warped ranges and what killed attempts at them left."""
    for seg in segs:
        Path(seg).unlink(missing_ok=True)
    remove_leftovers(*segs)


def _dask_task(work: Callable[..., tuple[Any, ...]], *args: Any) -> tuple[Any, ...]:
    """``work(*args)`` on a Dask worker; its result, and which worker ran it."""
    return (*work(*args), distributed.get_worker().address)


def _describe(exc: BaseException, src: Path) -> str:
    """One line naming the input and what went wrong."""
    if isinstance(exc, OmniwidgetError):
        text = str(exc)
    elif type(exc).__name__ == "KilledWorker":
        text = f"the workers running it died ({exc}); too little memory on the workers?"
    elif isinstance(exc, OSError):
        text = str(exc)
    else:
        text = f"{type(exc).__name__}: {exc}" if str(exc) else type(exc).__name__
    return text if str(src) in text else f"{src}: {text}"


# --- the batch ---------------------------------------------------------------------------------


def _pairs(inputs: Sequence[str | os.PathLike[str]], outputs: Any, files: Sequence[tuple[str, Any]] = ()) -> tuple[list[tuple[Path, Path]], bool]:
    """Each input with its output, checked (nothing read); and whether outputs go into a folder of ours.

    ``files`` are the other files read, with what they are (``("the handles file", handles)``;
    only paths count): no output may name one of them, an input or another output
    (:func:`omniwidget._files.refuse_overwrites`).
    """
    sources = [Path(p) for p in inputs]
    if isinstance(outputs, (str, os.PathLike)):
        folder = Path(outputs)
        if folder.suffix.lower() in OUTPUT_SUFFIXES + VIDEO_OUTPUT_SUFFIXES:
            raise ImageError(f"{folder}: outputs= names a folder for the outputs (each keeps its input's name), or give a list of outputs")
        names = [p.name for p in sources]
        twice = sorted({n for n in names if names.count(n) > 1})
        if twice:
            raise ImageError(f"inputs share the file name {twice[0]}: their outputs in {folder} would overwrite each other")
        targets, make_folder = [folder / n for n in names], True
    else:
        targets, make_folder = [Path(p) for p in outputs], False
        if len(targets) != len(sources):
            raise ValueError(f"{len(sources)} inputs but {len(targets)} outputs")
        seen: set[str] = set()
        for t in targets:
            key = os.path.normpath(os.path.abspath(t))
            if key in seen:
                raise ImageError(f"{t}: named as the output of two inputs")
            seen.add(key)
    for s, t in zip(sources, targets, strict=True):
        video = is_video_path(s)
        allowed = VIDEO_OUTPUT_SUFFIXES if video else OUTPUT_SUFFIXES
        if t.suffix.lower() not in allowed:
            what = "the output of a video" if video else "an output"
            raise ImageError(f"{t}: {what} must end in {', '.join(allowed)}")
    reads = [("the input", s) for s in sources] + [(what, Path(f)) for what, f in files if isinstance(f, (str, os.PathLike))]
    refuse_overwrites(reads, [("the output", t) for t in targets])
    return list(zip(sources, targets, strict=True)), make_folder


def warp_files(
    inputs: Sequence[str | os.PathLike[str]],
    outputs: str | os.PathLike[str] | Sequence[str | os.PathLike[str]],
    *,
    handles: Handles | str | os.PathLike[str] | None = None,
    map: ArrayLike | str | os.PathLike[str] | None = None,  # shadows the builtin here only: the word the command line uses (--map)
    client: Client | str | None = None,
    retries: int = 2,
    progress: Callable[[int, int], None] | None = None,
    settings: BatchSettings | None = None,
    **options: Any,
) -> BatchReport:
    """Warp many panoramas and 360° videos alike, each read and written by tasks of their own, here or on a Dask cluster.

    Parameters
    ----------
    inputs : sequence of path-like
        Equirectangular images (2:1, or any shape with ``fit``), of any sizes: each size
        gets its own map; and 360° videos (:func:`~omniwidget.io.video.is_video_path`),
        each cut into time ranges of about ``segment_seconds`` (:class:`BatchSettings`), one task per range, then
        joined without re-encoding, its sound copied from the input
        (:func:`~omniwidget.io.video.join_video_segments`). With a cluster, paths as the
        workers see them.
    outputs : path-like or sequence of path-like
        A folder (made if missing, not its parents) where each output keeps its input's
        file name, or one output path per input. The suffix picks the format
        (:func:`~omniwidget.io.images.write_image`; ``.mp4``, ``.m4v`` or ``.mov`` for a
        video). Each is written whole or not at all.
    handles : Handles or path-like, optional
        The handles document (or its file) to warp by; the map is computed once per output
        width on each worker (or once in-process).
    map : array_like or path-like, optional
        Instead of ``handles``: an inverse map ``(H, 2H, 2)`` of input ``[lon, lat]``
        degrees per output pixel (``Result.inverse_map()``) or a ``.npy`` file of one
        (``omniwidget warp --map``). Outputs are ``2H`` x ``H`` whatever the input size.
    client : distributed.Client or str, optional
        Where to run: a connected client, or a scheduler's address (``"tcp://host:8786"``)
        or scheduler file (``.json``, from ``dask scheduler --scheduler-file``), connected
        to and closed again here. By default the batch runs in-process, on threads.
    retries : int
        How many more times a file that fails is tried (a corrupt file fails every time; a
        network file system's hiccup may not).
    progress : callable, optional
        ``progress(done, total)``, called in the calling thread as each file finishes.
    settings : BatchSettings, optional
        The output width, resampling and fit, the threads of an in-process run, and the
        videos' ranges and encoder (:class:`BatchSettings`; its defaults by default).
    **options
        Fields of :class:`BatchSettings` by name (``width=2048``, ``workers=4``,
        ``segment_seconds=30``, ``crf=20``, ...), replacing those of ``settings``.

    Returns
    -------
    BatchReport
        Per input: its output, the seconds it took, or the error that stopped it. A failed
        file does not stop the others; ``report.ok`` says whether all were written.

    Raises
    ------
    ValueError
        Neither or both of ``handles`` and ``map``; a bad ``retries``, or a bad setting
        (:class:`BatchSettings`).
    TypeError
        An option that is no setting.
    OmniwidgetError
        The handles or map cannot be read; outputs that would collide, overwrite an input
        or have no image suffix (found before any work starts).
    ImportError
        ``client`` is given and :mod:`distributed` is not installed
        (``pip install "omniwidget[dask]"``).
    OSError
        The scheduler cannot be reached.

    Notes
    -----
    The outputs are the bytes ``omniwidget warp`` writes for several inputs on one machine:
    the inverse map of the output size, turned into source coordinates for the input's width
    (:func:`~omniwidget.app.frames.map_coordinates`) and resampled with OpenCV. (For one
    input, ``omniwidget warp`` without ``--dask`` resamples by the blend's own coordinates,
    which differ from the map's in the last bits, so the bytes may differ slightly.) A
    video's output is the same bytes in-process and on a cluster (the same ranges, each
    encoded alike); it differs from ``omniwidget warp IN.mp4`` in one thing: a key frame
    starts each range.

    Examples
    --------
    >>> from omniwidget.app.batch import warp_files
    >>> report = warp_files(["a.jpg", "b.jpg"], "out/", handles="handles.json", client="tcp://scheduler:8786")  # doctest: +SKIP
    >>> print(report.summary())  # doctest: +SKIP
    """
    if isinstance(retries, bool) or not isinstance(retries, (int, np.integer)) or retries < 0:
        raise ValueError(f"retries must be a non-negative integer, got {retries!r}")
    recipe = _recipe(handles, map, _settings(settings, options))
    pairs, make_folder = _pairs(inputs, outputs, [("the handles file", handles), ("the map", map)])
    start = time.perf_counter()
    if client is None:
        workers = recipe.settings.workers
        threads = (os.cpu_count() or 1) + 1 if workers is None else int(workers)
        try:
            files, warnings = _in_process(recipe, pairs, make_folder, int(retries), threads, progress)
        finally:
            _forget(recipe.digest)
        return BatchReport(tuple(files), time.perf_counter() - start, None, threads, warnings)
    files, warnings, address, count = _on_cluster(recipe, pairs, make_folder, int(retries), client, progress)
    return BatchReport(tuple(files), time.perf_counter() - start, address, count, warnings)


def _settings(settings: BatchSettings | None, options: dict[str, Any]) -> BatchSettings:
    """``settings`` (default :class:`BatchSettings`) with the fields named in ``options`` replaced."""
    names = {f.name for f in dataclasses.fields(BatchSettings)}
    unknown = sorted(set(options) - names)
    if unknown:
        raise TypeError(f"warp_files() got unexpected keyword argument(s) {', '.join(unknown)}; its settings are {', '.join(sorted(names))}")
    return dataclasses.replace(settings or BatchSettings(), **options)


def _in_process(
    recipe: _Recipe,
    pairs: list[tuple[Path, Path]],
    make_folder: bool,
    retries: int,
    threads: int,
    progress: Callable[[int, int], None] | None,
) -> tuple[list[FileReport], tuple[str, ...]]:
    def attempt(work: Callable[..., Any], *args: Any) -> Any:
        """``work(*args)``, tried ``retries`` more times if it raises, like a task on a cluster; the last error raised."""
        for left in range(retries, -1, -1):
            try:
                return work(*args)
            except Exception:
                if not left:
                    raise
        raise AssertionError("unreachable")

    def video(src: Path, dst: Path) -> FileReport:
        width, ranges = attempt(_plan_video, str(src), str(dst), recipe.settings.segment_seconds)
        segs = [str(p) for p in _segment_paths(dst, len(ranges))]
        try:
            done = [attempt(_warp_segment, recipe, str(src), width, seg, a, b, make_folder) for seg, (a, b) in zip(segs, ranges, strict=True)]
            seconds, map_seconds, warnings = attempt(_join_segments, recipe, str(src), segs, str(dst), done)
        finally:
            _remove_segments(segs)
        found.update(dict.fromkeys(warnings))
        return FileReport(src, dst, seconds, None, "local", None, map_seconds, len(segs))

    def one(pair: tuple[Path, Path]) -> FileReport:
        src, dst = pair
        try:
            if is_video_path(src):
                return video(src, dst)
            seconds, map_seconds, warnings = attempt(_warp_file, recipe, str(src), str(dst), make_folder)
        except Exception as exc:  # reported, like a task's failure on a cluster
            return FileReport(src, dst, error=_describe(exc, src))
        found.update(dict.fromkeys(warnings))
        return FileReport(src, dst, seconds, None, "local", None, map_seconds)

    found: dict[str, None] = {}
    files: list[FileReport] = []
    remove_leftovers(*(dst for _, dst in pairs))  # each folder listed once, not once per file
    pool = ThreadPoolExecutor(max(1, threads))
    try:
        for done, report in enumerate(pool.map(one, pairs), start=1):
            files.append(report)
            if progress is not None:
                progress(done, len(pairs))
    finally:  # interrupted: the files not started are dropped, not warped while the caller waits
        pool.shutdown(wait=True, cancel_futures=True)
    return files, tuple(found)


def _connect(client: Any) -> tuple[distributed.Client, bool]:
    """A connected client and whether it is ours to close."""
    try:
        resolve(distributed)
    except ImportError as exc:
        raise ImportError(f'a Dask cluster needs dask.distributed: pip install "omniwidget[dask]" ({exc})') from None
    if isinstance(client, distributed.Client):
        return client, False
    if not isinstance(client, (str, os.PathLike)):
        raise TypeError(f"client must be a distributed.Client, a scheduler address or a scheduler file, got {type(client).__name__}")
    text = os.fspath(client)
    if text.endswith(".json") and Path(text).is_file():
        return distributed.Client(scheduler_file=text), True
    return distributed.Client(text), True


def _on_cluster(
    recipe: _Recipe,
    pairs: list[tuple[Path, Path]],
    make_folder: bool,
    retries: int,
    client: Any,
    progress: Callable[[int, int], None] | None,
) -> tuple[list[FileReport], tuple[str, ...], str, int]:
    dask, ours = _connect(client)
    futures: list[Any] = []
    cleanups: list[Any] = []
    try:
        address = str(dask.scheduler.address) if dask.scheduler is not None else str(client)
        count = len(dask.scheduler_info().get("workers", {}))
        # the recipe once per worker (workers that join later fetch it from a peer), then the tasks
        shared = dask.scatter(recipe, broadcast=True, hash=True)
        prefix = f"{TASK_PREFIX}-{uuid.uuid4().hex[:12]}"
        # an image is one task (key prefix-i); a video first a plan (prefix-i-plan), then a task
        # per range (prefix-i-k) and the join (prefix-i), which waits for the ranges
        stage: dict[str, tuple[int, str]] = {}
        segments: dict[int, list[str]] = {}

        def submit(key: str, i: int, what: str, work: Callable[..., Any], *args: Any) -> Any:
            future = dask.submit(_dask_task, work, *args, key=key, retries=retries, pure=False)
            futures.append(future)
            stage[key] = (i, what)
            return future

        pending = distributed.as_completed()
        for i, (src, dst) in enumerate(pairs):
            if is_video_path(src):
                pending.add(submit(f"{prefix}-{i}-plan", i, "plan", _plan_video, str(src), str(dst), recipe.settings.segment_seconds))
            else:
                pending.add(submit(f"{prefix}-{i}", i, "file", _warp_file, shared, str(src), str(dst), make_folder))
        files: list[FileReport | None] = [None] * len(pairs)
        found = dict.fromkeys(_mismatches(dask))
        done = 0
        for future in pending:
            i, what = stage[future.key]
            src, dst = pairs[i]
            try:
                *value, worker = future.result()
            except BaseException as exc:  # the task's own exception, or Dask's (KilledWorker, cancelled)
                if isinstance(exc, (KeyboardInterrupt, SystemExit)):
                    raise
                files[i] = FileReport(src, dst, error=_describe(exc, src), task=future.key, segments=len(segments.get(i, [])) or 1)
            else:
                if what == "plan":
                    width, ranges = value
                    segs = segments[i] = [str(p) for p in _segment_paths(dst, len(ranges))]
                    parts = [
                        submit(f"{prefix}-{i}-{k}", i, "range", _warp_segment, shared, str(src), width, seg, a, b, make_folder)
                        for k, (seg, (a, b)) in enumerate(zip(segs, ranges, strict=True))
                    ]
                    pending.add(submit(f"{prefix}-{i}", i, "join", _join_segments, shared, str(src), segs, str(dst), parts))
                    continue
                seconds, map_seconds, warnings = value
                found.update(dict.fromkeys(warnings))
                files[i] = FileReport(src, dst, seconds, None, worker, future.key, map_seconds, len(segments.get(i, [])) or 1)
            if i in segments:  # the ranges joined (or given up on): remove them
                cleanups.append(dask.submit(_remove_segments, segments[i], key=f"{prefix}-{i}-cleanup", retries=retries, pure=False))
            done += 1
            if progress is not None:
                progress(done, len(pairs))
        distributed.wait(cleanups)
        return [f for f in files if f is not None], tuple(found), address, count
    finally:
        unfinished = [f for f in futures if not f.done()]
        if unfinished:  # interrupted: leave the cluster nothing to do for us
            dask.cancel(unfinished)
        try:
            dask.run(_forget, recipe.digest)  # the maps are large: the workers keep them for one batch only
        except Exception:  # a worker gone or going: what it kept goes with it
            pass
        if ours:
            dask.close()


def _mismatches(dask: Client) -> list[str]:
    """Warnings for workers whose omniwidget, numpy or OpenCV differ from this machine's: their bytes may differ too."""
    here = _environment()
    try:
        there: dict[str, dict[str, str]] = dask.run(_environment)
    except Exception as exc:  # a worker that cannot even run this will fail its tasks, each reported
        return [f"could not ask the workers for their versions ({type(exc).__name__}: {exc})"]
    out = []
    for worker, versions in sorted(there.items()):
        differ = [f"{name} {versions.get(name)} (here {version})" for name, version in here.items() if versions.get(name) != version]
        if differ:
            out.append(f"the worker {worker} runs {', '.join(differ)}: its outputs may differ from this machine's")
    return out
