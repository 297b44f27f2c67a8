"""An editing session: a panorama, its handles, undo and redo, autosave and the newest result, in plain Python.

:class:`EditingSession` is everything the notebook editor (:class:`omniwidget.Editor`) does
apart from the widget. It is a façade over small parts, each usable and tested alone:

- :class:`~omniwidget.app.source.Source`: the panorama or the video frame warped, and its
  downscaled copies;
- :class:`~omniwidget.app.history.History` (undo, redo) and
  :class:`~omniwidget.app.autosave.Autosave` (the autosave file, held as this editor's own);
- :class:`~omniwidget.app.preview.PreviewJob`: the newest edit's result, computed in a
  worker (only the newest edit's result is ever shown), and its quality line;
- :class:`~omniwidget.app.exports.ImageExport` and :class:`~omniwidget.app.exports.VideoExport`:
  Save image (whole or in strips) and Save video;
- :class:`~omniwidget.app.detection.Detection`: suggested lines, Level and Straighten, each
  in a worker of its own;
- :class:`~omniwidget.app.drag.LiveDrag`: the live drag's basis;
- :class:`~omniwidget.app.status.Board`: what is shown (the status, the result, the
  suggestions), typed by :class:`~omniwidget.app.status.Status` and
  :class:`~omniwidget.app.status.Changes`.

The commands the front end sends are a table from their name to a handler (:data:`COMMANDS`).
A session tells whoever shows it what changed through ``on_change(changes)`` (the fields
that changed: ``handles``, ``history``, ``status``, ``preview``, ``folds``, ``outputs``,
``suggestions``; called from the worker threads for results) and sends the front end
messages through ``on_message(content, buffers)``.
"""

from __future__ import annotations

import os
import weakref
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from numpy.typing import NDArray

from ..document.handles import Handles, LineHandle, Options, PointHandle, load_handles
from ..errors import HandlesError
from ..method import edits
from ..method.kinds import reset as reset_handle
from .autosave import AUTOSAVE_SUFFIX, Autosave, autosave_location
from .detection import Detection
from .drag import LiveDrag
from .exports import RESULT_SUFFIX, ImageExport, VideoExport
from .handles_file import HandlesFile
from .history import HISTORY, History
from .preview import PreviewJob
from .source import DISPLAY_WIDTH, LAZY_WIDTH, PREVIEW_WIDTH, Source
from .status import Board, Changes, HistoryCounts, Status

if TYPE_CHECKING:
    from ..io.video import VideoReader, VideoReport
    from ..raster.pipeline import Result

__all__ = [
    "AUTOSAVE_SUFFIX",
    "ANSWERED_WHEN_DONE",
    "COMMANDS",
    "DISPLAY_WIDTH",
    "HISTORY",
    "LAZY_WIDTH",
    "PREVIEW_WIDTH",
    "RESULT_SUFFIX",
    "EditingSession",
    "as_document",
]


def as_document(value: Any) -> Handles:
    """A handles document from a :class:`Handles`, its JSON-ready dict or its JSON text (validated)."""
    if isinstance(value, Handles):
        return value
    if isinstance(value, (str, bytes)):
        return Handles.from_json(value)
    return Handles.from_dict(value)


def _given_handles(handles: Any) -> tuple[Handles | None, Path | None]:
    """The document given to the session (None when none was) and the handles file it was read from."""
    if isinstance(handles, (str, os.PathLike)) and not str(handles).lstrip().startswith("{"):
        return load_handles(handles), Path(handles)
    return (None if handles is None else as_document(handles)), None


class EditingSession:
    """A panorama being edited: its handles, their history, the autosave and the newest result.

    Parameters are those of :class:`omniwidget.Editor` (``image``, ``handles``,
    ``preview_width``, ``handles_path``, ``autosave``, ``quality``), and:

    frame, time : int, float, optional
        For a video file (:func:`~omniwidget.io.video.is_video_path`): the frame shown, by
        index or by seconds from the start (default: the first); see :meth:`set_frame` and
        :meth:`save_video`.
    on_change : callable, optional
        ``on_change(changes)`` with a dict of the fields that changed (``handles``,
        ``history``, ``status``, ``preview``, ``folds``, ``outputs``; for a video ``frame``
        and ``source``, the new frame as :meth:`display_source` gives it); results arrive
        from the worker thread, Save video's progress from its own.
    on_message : callable, optional
        ``on_message(content, buffers)``: a message for the front end (a command done, the
        live drag's basis, an image file to download).

    Nothing is computed until :meth:`start`, so that the widget can sync its traits first.

    The autosave is this session's while it holds it (see :class:`omniwidget.Editor`'s
    ``autosave``): :attr:`autosave_path` is where it writes, which becomes a file of its own
    (``room.jpg.2.omniwidget-autosave.json``) when another editor has the panorama's file;
    :attr:`other_autosaves` lists the panorama's autosaves it did not restore, and
    :meth:`close` lets go of the file.
    """

    def __init__(  # noqa: PLR0913 - the Editor's documented keyword knobs, passed through as they are
        self,
        image: NDArray | str | os.PathLike[str],
        handles: Handles | dict | str | os.PathLike[str] | None = None,
        *,
        preview_width: int = PREVIEW_WIDTH,
        handles_path: str | os.PathLike[str] | None = None,
        autosave: bool | str | os.PathLike[str] | None = None,
        quality: bool = True,
        frame: int | None = None,
        time: float | None = None,
        on_change: Callable[[Changes], None] | None = None,
        on_message: Callable[[dict, list], None] | None = None,
    ) -> None:
        self._source = Source(image, preview_width, frame, time)
        self._on_message = on_message or (lambda content, buffers: None)
        #: What is shown, and the lock the parts share (:class:`~omniwidget.app.status.Board`).
        self.board = Board(on_change)
        self._history = History()
        self._preview = PreviewJob(self._source, self.board, quality)
        self._images = ImageExport(self._source, self._preview, self.board, self._on_message)
        self._videos = VideoExport(self._source, self._preview, self.board)
        self._detection = Detection(self._source, self.board, weakref.proxy(self))
        self._drag = LiveDrag(self._preview, self._on_message)
        self._handles_file = HandlesFile(self._source.path, handles_path)
        path = autosave_location(autosave, self._source.path, self._source.working)
        self._autosave = None if path is None else Autosave(path, self.board)
        given, handles_file = _given_handles(handles)
        self.board.handles = self._start_from(given).to_dict()
        if handles_file is not None:
            self._handles_file.note(handles_file)
        self.board.history = self._history.counts()

    def _start_from(self, given: Handles | None) -> Handles:
        """The document to start from: the given one, or the autosave's when none was given and it has handles."""
        doc = Handles() if given is None else given
        if self._autosave is None:
            return doc
        restored = self._autosave.open(doc, given=given is not None)
        if restored is None:
            return doc
        self._history.record(doc.to_dict())  # undo: start without them
        return restored

    def start(self) -> None:
        """Compute the first result (in the worker)."""
        self._changed(self.document)

    # --- what is shown -------------------------------------------------------------------
    @property
    def status(self) -> Status:
        """The status line, the result on screen and the jobs (:class:`~omniwidget.app.status.Status`)."""
        return self.board.status

    @property
    def handles(self) -> dict:
        """The handles document, JSON-ready (as the front end holds it)."""
        return self.board.handles

    @property
    def history(self) -> HistoryCounts:
        """How many edits undo and redo can take."""
        return self.board.history

    @property
    def preview(self) -> bytes:
        """The result on screen, a JPEG."""
        return self.board.preview

    @property
    def folds(self) -> bytes:
        """Where the result on screen folds over, a PNG (b"" when it does not)."""
        return self.board.folds

    @property
    def outputs(self) -> list[list[list[float]]]:
        """For each handle, where its control points go in the result on screen, ``[lon, lat]``."""
        return self.board.outputs

    @property
    def suggestions(self) -> list[dict]:
        """The suggested lines shown, JSON-ready; ``key`` names one."""
        return self.board.suggestions

    @property
    def last_error(self) -> BaseException | None:
        """The last error shown (a computation, a save, a detection), for scripts."""
        return self.board.last_error

    @property
    def autosave_path(self) -> Path | None:
        """Where this editor autosaves, None when it does not."""
        return None if self._autosave is None else self._autosave.path

    @property
    def other_autosaves(self) -> list[Path]:
        """The panorama's autosaves this editor did not restore, offered in the notice."""
        return [] if self._autosave is None else self._autosave.other_autosaves

    @property
    def handles_path(self) -> Path:
        """Where :meth:`save` writes when given no path (settable)."""
        return self._handles_file.path

    @handles_path.setter
    def handles_path(self, path: str | os.PathLike[str]) -> None:
        self._handles_file.path = Path(path)

    @property
    def _notice(self) -> str:
        """The autosave's notice (``status["notice"]``)."""
        return "" if self._autosave is None else self._autosave.notice

    def _report_error(self, message: str) -> None:
        """Show a refused command or edit; it stays until the next edit (a result still on its way keeps it)."""
        self.board.report_error(message)

    # --- the image -----------------------------------------------------------------------
    @property
    def image(self) -> NDArray:
        """The input panorama at full size (read-only); a panorama opened reduced is read whole at the first ask."""
        return self._source.image

    @property
    def image_size(self) -> tuple[int, int]:
        """``(width, height)`` of the panorama at full size (known before it is read whole)."""
        return self._source.width, self._source.width // 2

    @property
    def image_path(self) -> Path | None:
        """The file the panorama was read from, None for an array."""
        return self._source.path

    @property
    def _working(self) -> NDArray:
        """The panorama as opened: whole, or a large JPEG's reduced decoding."""
        return self._source.working

    @property
    def _full_image(self) -> NDArray | None:
        """The panorama at full size once read (None while only its reduced decoding is)."""
        return self._source.full_image

    def display_source(self) -> bytes:
        """The panorama as the browser shows it: a JPEG at most :data:`DISPLAY_WIDTH` wide."""
        return self._source.display_source()

    # --- a video: its frames ---------------------------------------------------------------
    @property
    def video(self) -> VideoReader | None:
        """The video the editor was opened on (its frames, :class:`~omniwidget.io.video.VideoReader`), None for an image."""
        return self._source.video

    @property
    def frame(self) -> int:
        """The frame of the video shown (0 for an image)."""
        return self._source.frame

    @property
    def frame_count(self) -> int:
        """Frames of the video, 0 for an image."""
        return len(self._source.video) if self._source.video is not None else 0

    @property
    def frame_interval(self) -> float:
        """Seconds between the video's frames, 0.0 for an image."""
        return self._source.video.frame_interval if self._source.video is not None else 0.0

    @property
    def frame_time(self) -> float:
        """Seconds from the video's start to the frame shown, 0.0 for an image."""
        return self.frame * self.frame_interval

    def set_frame(self, frame: int | None = None, *, time: float | None = None) -> None:
        """Show another frame of the video (by index, or by ``time`` in seconds) and recompute the preview on it.

        The handles stay (no edit: no undo step, no autosave). The frame is read here; the
        preview is computed in the worker, as after an edit.

        Raises
        ------
        TypeError
            For an image, or neither or both of ``frame`` and ``time``.
        IndexError, ValueError
            For a frame or a time outside the video.
        """
        index = self._source.frame_of(frame, time)
        if index == self.frame:
            return
        image = self._source.read_frame(index)
        with self.board.lock:
            self._source.show_frame(index, image)
            self._preview.forget_full()
            self._detection.forget()  # found on the frame shown before
        self.board.publish({"frame": index, "source": self.display_source()})
        self._detection.show([])
        self._changed(self.document)

    @property
    def generation(self) -> int:
        """The number of the newest edit (or computation asked for); ``status["generation"]`` is the one shown."""
        return self._preview.generation

    # --- the handles ---------------------------------------------------------------------
    @property
    def document(self) -> Handles:
        """The handles as a validated :class:`~omniwidget.Handles` document."""
        return Handles.from_dict(self.handles)

    def edit(self, handles: Handles | dict | str, record: bool = True) -> None:
        """Make ``handles`` the document: an edit (undoable when ``record``), recomputed and autosaved.

        Raises
        ------
        HandlesError
            If the document is invalid; nothing changes then.
        """
        doc = as_document(handles)
        new = doc.to_dict()
        if new == self.handles:
            return
        if record:
            self._history.record(self.handles)
        self.board.publish({"handles": new})
        self.board.clear_finished()
        self._detection.edited(doc)
        self._changed(doc)  # the preview starts first; the autosave is written meanwhile
        if self._autosave is not None:
            self._autosave.write(doc)

    def close(self) -> None:
        """Let go of the autosave file (it stays, for the next editor to restore); the handles stay in memory."""
        if self._autosave is not None:
            self._autosave.release()

    # --- computing -----------------------------------------------------------------------
    def _changed(self, doc: Handles) -> None:
        """After every change of the handles: recompute the preview (and the control points' outputs)."""
        self.board.publish({"history": self._history.counts()})
        self._show(doc, full=False)

    def _show(self, doc: Handles, full: bool) -> None:
        """Compute ``doc``'s result (the preview, or the full size) in the worker and show it."""
        key, preview = self._key(doc.to_dict()), self._preview

        def job(generation: int) -> None:
            preview.compute(doc, key, generation, full=full)

        self._schedule(job)

    def _schedule(self, job: Callable[[int], None]) -> None:
        """A new generation: ``job(generation)`` in the preview's worker."""
        self._preview.schedule(job, self._notice)

    def _key(self, handles: dict | None = None) -> str:
        """The cache key of a result: the handles and, for a video, the frame they are warped on."""
        return self._source.key(self.handles if handles is None else handles)

    def wait(self, timeout: float | None = 120.0) -> dict:
        """Block until the newest edit's result is shown (or failed); return :attr:`status`.

        Raises
        ------
        TimeoutError
            If the computation takes longer than ``timeout`` seconds.
        """
        if not self._preview.worker.wait(timeout):
            raise TimeoutError(f"the editor's computation did not finish within {timeout} s")
        return dict(self.status)

    def idle(self, timeout: float | None = 120.0) -> bool:
        """Block until the preview, the quality figures, the live drag's basis, Suggest lines and Level are all done; False on timeout."""
        workers = (self._preview.worker, self._preview.quality, self._drag.worker, *self._detection.workers.values())
        return all(worker.wait(timeout) for worker in workers)

    @property
    def result(self) -> Result:
        """The full-resolution :class:`~omniwidget.Result` of the current handles (computed on demand)."""
        return self._preview.full(self.document, self._key(), warn=True)

    @property
    def preview_result(self) -> Result | None:
        """The :class:`~omniwidget.Result` last shown, or None."""
        return self._preview.result

    def compute_full(self) -> None:
        """Compute the full-resolution result in the background and show it."""
        self._show(self.document, full=True)

    # --- save image and video ---------------------------------------------------------------
    def save_image(self, path: str | os.PathLike[str] | None = None, *, gpano: bool = True) -> Path:
        """Write the full-size result of the current handles (whole or not at all); return where.

        Parameters
        ----------
        path : path-like, optional
            Where to write (its suffix picks the format). Default: next to the panorama when
            the editor was opened from a file, ``room.jpg`` giving ``room-rectified.jpg`` in
            the input's format, or PNG (then TIFF, then ``.npy``) where that format cannot
            hold the result (alpha in a JPEG, say); in the working folder as
            ``panorama-rectified.png`` when it was opened from an array (and as
            ``<stem>-rectified.<suffix>`` for the bundled sample, never written next to).
        gpano : bool
            Write the Photo Sphere XMP when the panorama has none (the result is a whole
            sphere). The panorama file's metadata is carried either way, brought up to date
            (:func:`omniwidget.io.metadata.output_metadata`): EXIF (orientation 1, the
            sizes), ICC profile, XMP with its GPano sizes and pose (levelled: pitch and roll 0).

        Raises
        ------
        ImageError
            If the file cannot be written (a folder that is not there or not writable) or
            ``path`` is the input panorama, which is never overwritten. The error is also
            shown in the widget (:attr:`status` ``error``); the handles are kept.

        The editor's Save image button does the same in the editor's worker (the widget never waits)
        and also offers the file as a browser download. A panorama wider than
        :data:`~omniwidget.raster.strips.STREAM_WIDTH` is made and written in strips
        (:meth:`_save_in_strips`: read from disk a patch at a time when large, its progress in
        :attr:`status` ``["saving"]``) and not offered as a download.
        """
        return self._images.save(self.document, self._key(), path, gpano=gpano)

    def _save_image_in_worker(self) -> None:
        """The Save image button: in the preview's worker (the widget never waits), offered as a download."""
        doc, key, images = self.document, self._key(), self._images
        images.set_state("running", "saving the image: computing the full-size result...")
        self._schedule(lambda generation: images.job(doc, key, generation))

    def save_video(self, path: str | os.PathLike[str] | None = None, *, wait: bool = False) -> Path:
        """Warp the whole video by the map of the current handles and write it, in a thread of its own; return where.

        The map is the full-size result's (:meth:`Result.inverse_map` at the video's width),
        computed on the frame shown; every frame is then resampled by it
        (:func:`~omniwidget.io.video.warp_video`: the sound, time stamps and spherical
        metadata kept). :attr:`status` ``["video"]`` follows the job: ``state`` ("map",
        "running", "done", "cancelled" or "error"), ``done`` and ``total`` frames, ``fps``,
        ``path`` and a ``message``; :meth:`cancel_video` stops it, and nothing is written
        then. The editor goes on meanwhile (edits, other frames).

        Parameters
        ----------
        path : path-like, optional
            ``.mp4``, ``.m4v`` or ``.mov``. Default: next to the video, ``clip.mp4`` giving
            ``clip-rectified.mp4`` (MP4 for other containers).
        wait : bool
            Block until the video is written (or failed, or was cancelled) and raise its
            error, for scripts.

        Raises
        ------
        TypeError
            If the editor shows an image.
        VideoError
            If a video is being saved already (``wait`` or not), or, with ``wait``, the
            video could not be written; VideoCancelled when cancelled meanwhile.
        """
        return self._videos.save(self.document, self._key(), path, wait=wait)

    def cancel_video(self) -> bool:
        """Stop the video being saved (its partial file is removed); False when none is."""
        return self._videos.cancel()

    def wait_video(self, timeout: float | None = None) -> VideoReport | None:
        """Block until the video being saved is written, failed or cancelled; its report (None unless written)."""
        return self._videos.wait(timeout)

    # --- suggested lines, levelling and straightening ----------------------------------------
    def suggest_lines(self, *, max_lines: int = 40, wait: bool = False) -> None:
        """Find straight edges in the panorama (:func:`omniwidget.detect.suggest_lines`) in the background and show them.

        The suggestions (:attr:`suggestions`, drawn dashed on the input) replace any shown
        before; none is a handle until accepted (:meth:`accept_suggestion`,
        :meth:`accept_all_suggestions`). :attr:`status` ``["suggest"]`` follows the job:
        ``state`` ("running", "done" or "error") and ``message``.

        Parameters
        ----------
        max_lines : int
            At most this many suggestions, best first.
        wait : bool
            Block until they are found, and raise the detector's error, for scripts.
        """
        self._detection.suggest(max_lines, wait=wait)

    def accept_suggestion(self, key: int) -> None:
        """Add the suggestion ``key`` (its ``key`` in :attr:`suggestions`) as a line handle: one undoable edit."""
        line = self._detection.suggestion(key).handle()
        self._edit(lambda items: items.append(line))

    def accept_all_suggestions(self) -> int:
        """Add every suggestion shown as line handles, in one undoable edit; return how many."""
        lines = self._detection.shown_lines()
        if lines:
            self._edit(lambda items: items.extend(lines))
        return len(lines)

    def drop_suggestions(self, key: int | None = None) -> None:
        """Stop showing the suggestion ``key``, or all of them (no edit: they were no handles)."""
        self._detection.drop(key)

    def level(self, *, wait: bool = False) -> None:
        """Level the panorama: find the camera's tilt (:func:`omniwidget.detect.level`) in the background and undo it.

        The rotation is applied as one undoable edit (:func:`omniwidget.detect.level_document`:
        ``options.up`` set, the mode kept, the handles' outputs carried by the turn), on the
        handles as they are when it is found. Too few vertical edges: the status says so
        (``status["error"]`` and ``status["level"]``) and nothing changes.

        Parameters
        ----------
        wait : bool
            Block until it is applied, and raise its error (a :class:`~omniwidget.errors.LevelError`), for scripts.

        Raises
        ------
        OmniwidgetError
            If the panorama is being levelled already.
        """
        self._detection.level(wait=wait)

    def straighten(self, *, wait: bool = False) -> None:
        """Straighten the panorama in one step (:func:`omniwidget.straighten`) in the background: level, find the structure, rectify it.

        The handles it used replace the document as one undoable edit (the lines, the
        default mode and ``options.up``); the suggestions shown go. :attr:`status`
        ``["straighten"]`` follows the job (``state`` and ``message``: what was levelled, how
        many lines were straightened and why others were left out). The structure is found
        on the panorama as the detector sees it (:data:`~omniwidget.detect.DETECT_WIDTH` wide
        at most), and checked there by a warp.

        Parameters
        ----------
        wait : bool
            Block until the handles are loaded, and raise the job's error, for scripts.

        Raises
        ------
        OmniwidgetError
            If the panorama is being straightened already.
        """
        self._detection.straighten(wait=wait)

    # --- edits -----------------------------------------------------------------------------
    def undo(self) -> bool:
        """Go back one edit; False when there is none."""
        return self._step(self._history.undo(self.handles))

    def redo(self) -> bool:
        """Redo the edit last undone; False when there is none."""
        return self._step(self._history.redo(self.handles))

    def _step(self, document: dict | None) -> bool:
        if document is None:
            return False
        self.edit(document, record=False)
        return True

    def _edit(self, change: Callable[[list], None]) -> None:
        doc = self.document
        items = list(doc.handles)
        change(items)
        self.edit(replace(doc, handles=tuple(items)))

    def _handle(self, index: int) -> Any:
        items = self.document.handles
        if isinstance(index, bool) or not isinstance(index, (int, np.integer)) or not 0 <= index < len(items):
            raise IndexError(f"handles[{index}]: there are {len(items)} handles")
        return items[index]

    def rectify_all(self) -> None:
        """Rectify every line together (Sec. 3.4): the paper's "rectify all lines"."""
        doc = self.document
        items = tuple(replace(h, rectify=True, targets=None) if isinstance(h, LineHandle) else h for h in doc.handles)
        self.edit(Handles(items, Options(rectify="all")))

    def rectify_line(self, index: int) -> None:
        """Rectify line ``index`` and hold every other handle where it is ("rectify current line")."""
        self._handle(index)
        self.edit(edits.rectify_line(self.document, index))

    def reset(self, index: int) -> None:
        """Undo every transformation of handle ``index``: its output goes back to where it was drawn."""
        h = self._handle(index)
        self._edit(lambda items: items.__setitem__(index, reset_handle(h)))

    def move_arrow(self, index: int, tip: Any, which: Literal["east", "west"] = "east") -> None:
        """Drag point handle ``index``'s output arrow tip to ``tip`` ``[lon, lat]``: it turns and zooms."""
        h = self._handle(index)
        if not isinstance(h, PointHandle):
            raise HandlesError(f"handles[{index}]", f"a {h.kind} handle has no arrows")
        if which not in ("east", "west"):
            raise ValueError(f"which must be 'east' or 'west', got {which!r}")
        moved = h.with_arrow_tip(tip, which)
        self._edit(lambda items: items.__setitem__(index, moved))

    # --- files -------------------------------------------------------------------------------
    def save(self, path: str | os.PathLike[str] | None = None) -> Path:
        """Write the handles file (whole or not at all); return where.

        Parameters
        ----------
        path : path-like, optional
            Default :attr:`handles_path`: ``day1/room.handles.json`` next to ``day1/room.jpg``
            when the editor was opened from a file in a folder it may write to; otherwise
            (an array, the bundled sample, a folder not to write to) ``<stem>.handles.json``
            in the working folder.

        Raises
        ------
        FileExistsError
            If ``path`` is not given, the default file is the working folder's (a name other
            panoramas may share) and it is there already, not saved or loaded by this editor:
            it may hold another panorama's handles, which Save never writes over. Pass a path,
            or set :attr:`handles_path`.
        """
        return self._handles_file.write(self.document, path)

    def load(self, path: str | os.PathLike[str]) -> None:
        """Replace the handles by those of a handles file (an undoable edit)."""
        self.edit(load_handles(path))
        self._handles_file.note(Path(path))

    # --- the front end's commands -----------------------------------------------------------
    def _solve_drag(self, document: Any) -> None:
        """Compute the preview of the handles a drag on the result has reached: no edit (no undo step, no autosave).

        The live frame then draws from this result's weights (:meth:`live_basis_message`); the
        document itself changes when the drag ends.
        """
        self._show(as_document(document), full=False)

    def live_basis_message(self, index: Any) -> None:
        """Send the browser what it needs to redraw the result live while handle ``index`` is dragged (:mod:`omniwidget.raster.live`).

        See :meth:`omniwidget.app.drag.LiveDrag.send_basis`.
        """
        self._drag.send_basis(index)

    def _answer(self, op: Any) -> None:
        """Tell the front end the command ``op`` is done: it starts no edit from the handles before it."""
        self._on_message({"done": op}, [])

    def command(self, content: Any) -> None:
        """Apply a command of the front end (``{"op": ...}``, :data:`COMMANDS`); a refused one is shown in the status, the handles kept.

        Every command is answered ``{"done": op}`` once it has changed the handles, so that the
        front end starts no edit from the handles before it: at once, or when its job ends for
        a command that runs in the background (:data:`ANSWERED_WHEN_DONE`).
        """
        if not isinstance(content, dict):
            return
        op = content.get("op")
        later = False
        try:
            handler = COMMANDS.get(op) if isinstance(op, str) else None
            if handler is None:
                raise ValueError(f"unknown command from the browser: {op!r}")
            handler(self, content)
            later = op in ANSWERED_WHEN_DONE
        except Exception as exc:  # noqa: BLE001 - a person's click: show it, keep the handles
            self._report_error(str(exc) if isinstance(exc, HandlesError) else f"{type(exc).__name__}: {exc}")
        finally:  # after the handles it changed: the browser starts no edit from the handles before it
            if not later:
                self._answer(op)


# --- the commands: name -> handler(session, content) ----------------------------------------------
#: A command's handler: ``handler(session, content)``; what it returns is not looked at.
Command = Callable[[EditingSession, dict], object]


def _sent(content: dict, name: str, default: Any = None) -> Any:
    """A value the front end sent, as it is: the method it goes to checks it, as every value of the front end."""
    return content.get(name, default)


def _level(s: EditingSession, content: dict) -> None:
    s._detection.level(then=lambda: s._answer("level"))  # {"done": "level"} once the rotation is applied


def _straighten(s: EditingSession, content: dict) -> None:
    s._detection.straighten(then=lambda: s._answer("straighten"))  # {"done": "straighten"} once the handles are loaded


def _save(s: EditingSession, content: dict) -> None:
    path = s.save()
    said = f"saved {len(s.document)} handles to {path}"
    s.board.set_status(message=said, save={"state": "done", "message": said})


def _load(s: EditingSession, content: dict) -> None:
    name = str(content.get("name") or "the file")
    try:
        doc = Handles.from_json(content.get("text", ""))
    except HandlesError as exc:
        raise HandlesError(f"{name}: {exc.where}" if exc.where else name, exc.problem) from None
    s.edit(doc)


#: The front end's commands (``{"op": name, ...}``); the values they take are checked by the methods, as every value of the front end.
COMMANDS: dict[str, Command] = {
    "undo": lambda s, c: s.undo(),
    "redo": lambda s, c: s.redo(),
    "rectify_all": lambda s, c: s.rectify_all(),
    "rectify_line": lambda s, c: s.rectify_line(_sent(c, "index")),
    "reset": lambda s, c: s.reset(_sent(c, "index")),
    "arrow": lambda s, c: s.move_arrow(_sent(c, "index"), _sent(c, "tip"), _sent(c, "which", "east")),
    "drag": lambda s, c: s._solve_drag(_sent(c, "handles")),
    "refresh": lambda s, c: s._changed(s.document),
    "live": lambda s, c: s._drag.request(_sent(c, "index")),
    "full": lambda s, c: s.compute_full(),
    "save_image": lambda s, c: s._save_image_in_worker(),
    "save_video": lambda s, c: s.save_video(),
    "cancel_video": lambda s, c: s.cancel_video(),
    "frame": lambda s, c: s.set_frame(_sent(c, "frame")),
    "suggest": lambda s, c: s.suggest_lines(),
    "accept_suggestion": lambda s, c: s.accept_suggestion(_sent(c, "key")),
    "accept_all": lambda s, c: s.accept_all_suggestions(),
    "drop_suggestions": lambda s, c: s.drop_suggestions(_sent(c, "key")),
    "level": _level,
    "straighten": _straighten,
    "save": _save,
    "load": _load,
}
#: The commands answered when their job ends, not at once: the handles change then.
ANSWERED_WHEN_DONE = frozenset({"level", "straighten"})
