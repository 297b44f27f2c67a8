"""What an editing session writes: Save image (whole, or in strips for a panorama too large to warp whole) and Save video."""

from __future__ import annotations

import atexit
import os
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from ..document.handles import Handles
from ..errors import ImageError, VideoError
from ..io import images, video
from ..io.images import check_format, write_image
from ..io.metadata import Metadata, output_metadata, read_metadata
from ..raster import strips
from . import strips as app_strips
from . import video as app_video
from ._places import PACKAGE, same_file
from .preview import PreviewJob
from .source import Source
from .status import Board, JobState, VideoStatus, exception_text

if TYPE_CHECKING:
    from typing_extensions import Unpack

    from ..io.video import VideoReport

__all__ = ["RESULT_SUFFIX", "ImageExport", "VideoExport", "result_location"]

#: Save image names the full-size result so: ``room-rectified.jpg`` next to ``room.jpg``.
RESULT_SUFFIX = "-rectified"
#: Formats tried, in order, after the input's own when it cannot hold the result.
_RESULT_FORMATS = (".png", ".tif", ".npy")
_MIME = {".png": "image/png", ".jpg": "image/jpeg", ".jpeg": "image/jpeg", ".tif": "image/tiff", ".tiff": "image/tiff", ".webp": "image/webp", ".bmp": "image/bmp"}


def result_location(image_path: Path | None, result: NDArray) -> Path:
    """Where Save image writes ``result``: see :meth:`EditingSession.save_image`."""
    suffixes: tuple[str, ...]
    if image_path is None:
        base, suffixes = Path.cwd() / f"panorama{RESULT_SUFFIX}", _RESULT_FORMATS
    else:
        folder = image_path.parent
        if image_path.resolve().parent.is_relative_to(PACKAGE):  # the bundled sample: never written next to it
            folder = Path.cwd()
        base, suffixes = folder / f"{image_path.stem}{RESULT_SUFFIX}", (image_path.suffix, *_RESULT_FORMATS)
    for suffix in suffixes:
        candidate = base.with_name(base.name + suffix)
        try:
            check_format(candidate, result)
        except ImageError:
            continue  # this format cannot hold the result (alpha in a JPEG, a float image in a PNG, ...)
        return candidate
    return base.with_name(base.name + ".npy")  # pragma: no cover - .npy holds any array


def _save_image_error(exc: BaseException) -> str:
    text = str(exc) if isinstance(exc, ImageError) else exception_text(exc)
    return f"could not save the image: {text}; the handles are kept"


class ImageExport:
    """Save image: the full-size result of a document, written whole or not at all, its progress and end on ``board``.

    Parameters
    ----------
    source : Source
        The panorama (its file's metadata is carried to the result; it is never overwritten).
    preview : PreviewJob
        Makes (and keeps) the full-size result, and shows it when Save image runs in its worker.
    board : Board
        Where the progress, the end and errors are shown (``status["save"]``, ``["saving"]``, ``["saved"]``).
    on_message : callable
        ``on_message(content, buffers)``: the file written, offered to the browser as a download.
    """

    def __init__(self, source: Source, preview: PreviewJob, board: Board, on_message: Callable[[dict, list], None]) -> None:
        self.source = source
        self.preview = preview
        self.board = board
        self._on_message = on_message

    def set_state(self, state: JobState, message: str) -> None:
        """``status["save"]``: Save's and Save image's ``state`` ("running", "done" or "error") and ``message``."""
        self.board.set_job("save", {"state": state, "message": message})

    def save(self, doc: Handles, key: str, path: str | os.PathLike[str] | None, gpano: bool = True) -> Path:
        """Write the full-size result of ``doc`` (cache key ``key``); return where. An error is shown, then raised."""
        try:
            if self.in_strips():
                return self._save_in_strips(doc, path, gpano=gpano)
            result = self.preview.full(doc, key, warn=False)
            written = self._write_result(result.image, path, doc, gpano=gpano)
        except Exception as exc:
            self.board.report_error(_save_image_error(exc))
            raise
        self._say_saved(written, result.image.shape)
        return written

    def in_strips(self) -> bool:
        """Whether Save image makes the result in strips: a panorama file wider than the command line's STREAM_WIDTH."""
        source = self.source
        return source.path is not None and source.video is None and source.width > strips.STREAM_WIDTH

    def _save_in_strips(self, doc: Handles, path: str | os.PathLike[str] | None, *, gpano: bool = True) -> Path:
        """Save image for a panorama too large to warp whole: made and written in strips, its progress in the status.

        :func:`~omniwidget.app.strips.strips_of_file` chooses where the pixels come from (a patch at a time from disk
        for a panorama above :data:`~omniwidget.io.large.STREAM_BYTES` decoded, else the panorama in memory) and runs
        the method on its map grid. ``status["saving"]`` says the rows written and their total as they go, and the
        message the share.
        """
        source = self.source
        if source.path is None:  # pragma: no cover - in_strips says so
            raise ImageError("only a panorama opened from a file is saved in strips")
        target = self._target(path, np.empty((0, source.width, *source.working.shape[2:]), source.working.dtype))
        height = source.width // 2
        said = f"saving {target.name} ({source.width} x {height}): reading the panorama..."
        self.board.set_status(message=said, saving={"done": 0, "total": height}, save={"state": "running", "message": said})

        def progress(rows: int) -> None:
            said = f"saving {target.name}: {100 * rows // height}% of {height} rows"
            self.board.set_status(message=said, saving={"done": rows, "total": height}, save={"state": "running", "message": said})

        with app_strips.strips_of_file(source.path, doc, image=source.full_image, output=target) as made:
            meta = self._output_metadata(doc, made.shape, gpano)
            images.write_image_strips(target, made.shape, made.dtype, made.image_strips(), progress=progress, meta=meta)
        self._say_saved(target, made.shape)
        return target

    def _write_result(self, image: NDArray, path: str | os.PathLike[str] | None, doc: Handles | None = None, *, gpano: bool = True) -> Path:
        target = self._target(path, image)
        write_image(target, image, self._output_metadata(doc, image.shape, gpano))
        return target

    def _output_metadata(self, doc: Handles | None, shape: tuple[int, ...], gpano: bool) -> Metadata:
        """What Save image writes with the result: the panorama file's metadata brought up to date, GPano as ``gpano`` says."""
        source = read_metadata(self.source.path) if self.source.path is not None and self.source.video is None else None
        levelled = doc is not None and doc.options.up is not None
        return output_metadata(source, shape[1], shape[0], gpano=gpano, levelled=levelled)

    def _target(self, path: str | os.PathLike[str] | None, image: NDArray) -> Path:
        """Where Save image writes ``image`` (:func:`result_location`), refused if it is the input panorama."""
        image_path = self.source.path
        target = Path(path) if path is not None else result_location(image_path, image)
        if image_path is not None and same_file(target, image_path):
            raise ImageError(f"{target}: is the input panorama, which the editor never overwrites; name another file")
        return target

    def _say_saved(self, path: Path, shape: tuple[int, ...]) -> None:
        with self.board.lock:
            message = f"{shape[1]} x {shape[0]} saved to {path}"
            self.board.set_status(message=message, saved=str(path), saving=None, save={"state": "done", "message": message})

    def _failed(self, exc: BaseException) -> None:
        self.board.last_error = exc
        self.board.report_error(_save_image_error(exc))
        self.set_state("error", _save_image_error(exc))

    def job(self, doc: Handles, key: str, generation: int) -> None:
        """In the preview's worker: compute and show the full-size result, write it and send it for download.

        A panorama made in strips (:meth:`in_strips`) is written without being shown or sent: a file of
        gigabytes is no browser download; the status names where it is.
        """
        if self.in_strips():
            try:
                self._save_in_strips(doc, None)
            except Exception as exc:  # noqa: BLE001 - shown in the widget; the handles stay
                self._failed(exc)
            return
        result = self.preview.compute(doc, key, generation, full=True)
        if result is None:
            self.set_state("error", "could not save the image: the result could not be computed")
            return  # the computation's error is shown
        try:
            path = self._write_result(result.image, None, doc)
            data = path.read_bytes()
        except Exception as exc:  # noqa: BLE001 - shown in the widget; the handles stay
            self._failed(exc)
            return
        self._say_saved(path, result.image.shape)
        mime = _MIME.get(path.suffix.lower(), "application/octet-stream")
        self._on_message({"op": "image_file", "name": path.name, "mime": mime}, [data])


# --- save video ----------------------------------------------------------------------------------
def _video_location(video_path: Path) -> Path:
    """Where Save video writes: ``clip.mp4`` gives ``clip-rectified.mp4`` next to it (MP4 for inputs in other containers)."""
    suffix = video_path.suffix if video_path.suffix.lower() in video.OUTPUT_SUFFIXES else ".mp4"
    return video_path.with_name(f"{video_path.stem}{RESULT_SUFFIX}{suffix}")


#: Save video's threads running, each with its cancel: stopped when the interpreter exits.
_VIDEO_JOBS: set[tuple[threading.Thread, threading.Event]] = set()


@atexit.register
def _cancel_video_jobs() -> None:
    """Cancel every video being saved and let it clean up (its temporary file) before the interpreter finalizes."""
    for job, cancel in list(_VIDEO_JOBS):
        cancel.set()
        job.join(10.0)


class VideoExport:
    """Save video: every frame warped by the full-size result's map, in a thread of its own, its progress in ``status["video"]``.

    Parameters
    ----------
    source : Source
        The video (never overwritten).
    preview : PreviewJob
        Makes the full-size result on the frame shown, whose map warps every frame.
    board : Board
        Where the progress, the end and errors are shown.
    """

    def __init__(self, source: Source, preview: PreviewJob, board: Board) -> None:
        self.source = source
        self.preview = preview
        self.board = board
        self._job: threading.Thread | None = None
        self._cancel: threading.Event | None = None
        self.error: BaseException | None = None
        self.report: VideoReport | None = None

    def save(self, doc: Handles, key: str, path: str | os.PathLike[str] | None, wait: bool = False) -> Path:
        """Start writing the video warped by ``doc``'s map (cache key ``key``); return where (see :meth:`EditingSession.save_video`)."""
        source = self.source
        if source.video is None or source.path is None:
            raise TypeError("the editor shows an image, not a video: use save_image")
        with self.board.lock:
            if self._job is not None and self._job.is_alive():
                raise VideoError("a video is being saved already; wait for it or cancel it first")
            target = Path(path) if path is not None else _video_location(source.path)
            cancel = threading.Event()
            self._cancel, self.error, self.report = cancel, None, None
            job = threading.Thread(target=self._run, args=(doc, key, target, cancel), name="omniwidget-save-video", daemon=True)
            self._job = job
        message = f"saving the video to {target}: computing the map..."
        self._set(state="map", done=0, total=len(source.video), fps=0.0, path=str(target), message=message)
        _VIDEO_JOBS.add((job, cancel))
        job.start()
        if wait:
            job.join()
            if self.error is not None:
                raise self.error
        return target

    def cancel(self) -> bool:
        """Stop the video being saved (its partial file is removed); False when none is."""
        job, cancel = self._job, self._cancel
        if job is None or cancel is None or not job.is_alive():
            return False
        cancel.set()
        return True

    def wait(self, timeout: float | None = None) -> VideoReport | None:
        """Block until the video being saved is written, failed or cancelled; its report (None unless written)."""
        job = self._job
        if job is not None:
            job.join(timeout)
            if job.is_alive():
                raise TimeoutError(f"the video was not saved within {timeout} s")
        return self.report

    def _set(self, **fields: Unpack[VideoStatus]) -> None:
        with self.board.lock:
            self.board.set_status(video={**self.board.status.get("video", {}), **fields})

    def _run(self, doc: Handles, key: str, target: Path, cancel: threading.Event) -> None:
        """The save video thread: the map, then every frame; its progress and end in ``status["video"]``."""
        try:
            self._save(doc, key, target, cancel)
        finally:
            _VIDEO_JOBS.discard((threading.current_thread(), cancel))

    def _progress(self, cancel: threading.Event) -> Callable[[int, int | None], bool]:
        """The progress callback of :func:`warp_video`: a few updates a second, and False once cancelled."""
        clock = {"start": time.perf_counter(), "shown": 0.0}

        def progress(done: int, total: int | None) -> bool:
            now = time.perf_counter()
            if now - clock["shown"] >= 0.2 or done == total:  # a few updates a second reach the browser
                clock["shown"] = now
                fps = done / max(now - clock["start"], 1e-9)
                message = f"saving the video: frame {done} of {total or '?'}, {fps:.1f} fps"
                self._set(state="running", done=done, total=total or done, fps=round(fps, 1), message=message)
            return not cancel.is_set()

        return progress

    def _save(self, doc: Handles, key: str, target: Path, cancel: threading.Event) -> None:
        image_path = self.source.path
        assert image_path is not None  # save() checked it
        try:
            if same_file(target, image_path):
                raise ImageError(f"{target}: is the input video, which the editor never overwrites; name another file")
            the_map = self.preview.full(doc, key, warn=False).inverse_map()
            if cancel.is_set():
                raise app_video.VideoCancelled(f"cancelled before the first frame; {target} was not written")
            report = app_video.warp_video(image_path, target, inverse_map=the_map, progress=self._progress(cancel), cancel=cancel)
        except app_video.VideoCancelled as exc:
            self.error = exc
            self._set(state="cancelled", message=f"saving the video was cancelled: {exc}")
            return
        except Exception as exc:  # noqa: BLE001 - shown in the widget; the handles stay
            self.error = self.board.last_error = exc
            reason = str(exc) if isinstance(exc, ImageError) else exception_text(exc)  # a VideoError is an ImageError
            self._set(state="error", message=f"could not save the video: {reason}")
            return
        self.report = report
        self._set(
            state="done",
            done=report.frames,
            total=report.frames,
            fps=round(report.fps, 1),
            message=(
                f"{report.frames} frames ({report.size[0]} x {report.size[1]}) saved to {target} "
                f"in {report.seconds:.1f} s, {report.fps:.1f} fps"
            ),
        )
