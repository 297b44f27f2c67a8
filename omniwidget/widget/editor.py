"""The notebook editor: draw handles on a panorama, move their control points, see the result.

The front end (``static/editor.js`` and the ES modules it imports, made one module,
``static/editor.bundle.js``, by ``build.mjs`` at the repository's root) draws the panorama
and the handles and does every drag in the browser. The kernel hears of whole edits only:
the handles document when a drag ends, or a command (undo, rectify, reset, an arrow tip
moved, save, load). Everything else is a plain Python
:class:`~omniwidget.app.session.EditingSession` (undo and redo, autosave, the worker that
computes the newest edit's preview, the status, Save image, the live drag's basis): the
widget syncs its traits with the session and passes the front end's messages to it.

Everything the two sides exchange is in ``[lon, lat]`` degrees (the handles document of
:mod:`omniwidget.document.handles`), never display pixels, whatever size the image is shown at.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any, Literal

import anywidget
import traitlets
from numpy.typing import NDArray

from ..app.session import AUTOSAVE_SUFFIX, DISPLAY_WIDTH, HISTORY, PREVIEW_WIDTH, RESULT_SUFFIX, EditingSession, as_document
from ..app.status import Changes
from ..document.handles import Handles
from ..errors import HandlesError

__all__ = ["AUTOSAVE_SUFFIX", "DISPLAY_WIDTH", "HISTORY", "PREVIEW_WIDTH", "RESULT_SUFFIX", "Editor", "saved_handles"]

_STATIC = Path(__file__).parent / "static"
#: The front end anywidget loads: one ES module, built from ``static/*.js`` and committed. A path, not
#: its text, so that with ``ANYWIDGET_HMR=1`` anywidget watches the file and reloads the open widgets
#: whenever ``npm run watch`` rebuilds it.
_BUNDLE = _STATIC / "editor.bundle.js"


class _RefusedHandles(HandlesError, traitlets.TraitError):
    """A handles document refused by the trait's validation (a TraitError, so traitlets rolls back)."""


class _Document(traitlets.TraitType):
    """A handles document, held as its JSON-ready dict; takes a Handles, a dict or JSON text."""

    info_text = "a handles document (Handles, dict or JSON text)"

    def make_dynamic_default(self) -> dict:
        return Handles().to_dict()

    def validate(self, obj: Any, value: Any) -> dict:
        try:
            return as_document(value).to_dict()
        except HandlesError as exc:
            raise _RefusedHandles(exc.where, exc.problem) from None


class Editor(anywidget.AnyWidget):
    """Draw handles on an equirectangular panorama and see the rectified result as you go.

    Parameters
    ----------
    image : ndarray or path-like
        The panorama, ``W = 2 H`` (an array as :func:`omniwidget.read_image` gives, or a
        file), or a 360° video file (``.mp4``, ``.mov``, ``.mkv``, ...; PyAV needed): its
        frames are shown one at a time, and :meth:`save_video` (the widget's Save video)
        writes the whole video warped by the current handles. It stays in Python at full size; the browser gets a copy at most
        :data:`DISPLAY_WIDTH` wide.
    handles : Handles, dict, str or path-like, optional
        The handles to start from: a document, its JSON-ready dict or text, or a handles file
        (:func:`saved_handles` reads those of a saved notebook's widget state). Without them
        the editor starts from the image's autosave, when there is one.
    preview_width : int
        Width of the result computed after each edit (even).
    handles_path : path-like, optional
        Where the Save button writes the handles; default ``<image stem>.handles.json`` next
        to the image when it was opened from a file in a writable folder (``day1/room.jpg``
        gives ``day1/room.handles.json``, as Save image writes next to it); otherwise (an
        array, the bundled sample, a read-only folder) in the working folder, where Save never
        writes over a file this editor did not save or load (it may be another panorama's):
        it says so and writes nothing.
    height : int
        Height of the drawing area in CSS pixels.
    autosave : bool or path-like, optional
        Write the handles document (whole, through a temporary file and a rename) after
        every edit, undo and redo, so that a kernel restart or a crash loses nothing. True
        (the default, unless the environment variable ``OMNIWIDGET_AUTOSAVE`` is ``0``):
        next to the image as ``<image file name>.omniwidget-autosave.json`` when it was
        opened from a file in a writable folder; otherwise (an array, the bundled sample,
        a read-only folder) in the working folder as
        ``<image stem>-<digest>.omniwidget-autosave.json``, the digest being of the image's
        path, or of an array's pixels. A folder puts that second name there; any other path
        is the file itself. False: no autosave. An editor opened without ``handles`` starts
        from the autosave and says so in :attr:`status` (undo goes back to no handles);
        given ``handles`` win, and the autosave is left alone until the first edit. An
        unreadable autosave never stops the editor opening: it opens with no handles, the
        status says what is wrong with the file, and the file is kept, renamed to
        ``<name>.bad`` at the first edit.

        An autosave is one editor's: it holds a lock on the file while it lives, and writes
        over it only while the file is the one it last wrote or read. An editor that finds it
        open in another kernel, or written by another editor since it opened it, autosaves to
        a file of its own beside it, ``<name>.2.omniwidget-autosave.json``, and says so in the
        status; a newer editor of the same panorama in the same kernel (a cell run again)
        takes the file over, and the older one keeps its handles in a file of its own.
        Opening restores the newest of these files and names the others
        (:attr:`other_autosaves`). A FIFO or a device at the autosave path is never opened:
        the status says so, and the editor autosaves to a file of its own.

    quality : bool
        Measure each result's quality figures after it is shown (straightness, fold-over,
        coverage, displacement, distortion: :attr:`omniwidget.Result.quality`) and show them
        in one line under the image (``status["quality"]``), in a thread of its own,
        skipped when a newer edit comes first.

    frame : int, optional
        For a video (``Editor("clip.mp4")``, any file :func:`omniwidget.io.video.is_video_path`
        names): the index of the frame shown to draw the handles on (from 0; default 0).
    time : float, optional
        For a video, instead of ``frame``: the frame shown at this many seconds from the
        video's start (``time=2.5``).

    Attributes
    ----------
    frame : int
        The frame of the video shown (0 for an image); assign it, or move the widget's
        slider, to show another one: the handles stay, the preview is recomputed on it.
    frame_count : int
        Frames of the video, 0 for an image (the slider is shown only for a video).
    frame_interval : float
        Seconds between frames, 0.0 for an image.
    handles : dict
        The handles document (JSON-ready), synced both ways: drawing in the browser updates
        it, assigning a document (dict, :class:`~omniwidget.Handles` or JSON text) redraws.
        Invalid documents are refused with a :class:`~omniwidget.HandlesError` and the
        handles stay as they were.
    stage : {"draw", "transform", "side"}
        Draw handles on the input, move their control points on the result, or both side
        by side.
    selected : int
        Index of the selected handle, -1 for none.
    suggestions : list
        The suggested lines shown dashed on the input (:meth:`suggest_lines`), best first:
        ``key`` (to accept or drop it), ``start`` and ``end`` ``[lon, lat]``, ``length``
        (degrees) and ``confidence`` (0 to 1); an accepted or dropped one leaves the list.
    outputs : list
        For each handle, where its control points are in the shown result, ``[lon, lat]``
        (a point: centre and arrow tips; a line: start, middle, end; a cage: its vertices);
        updated with the result image.
    status : dict
        ``state`` ("busy", "idle" or "error": the last computation failed), ``message``,
        ``error`` (why the computation, or a command or edit since the last edit, failed; the
        handles are kept whatever fails, with the edit that could not be computed, and the
        last good result stays on screen), ``notice`` (the autosave: handles restored from
        it, a file that could not be read or written), ``warnings`` (conflicts and
        fold-overs, naming handles), ``warning_kinds`` (one per warning, what it is about:
        the ``kind`` of its :class:`~omniwidget.raster.pipeline.BlendWarning` class, "lines
        crossing in the output", "constraints on the same point", ..., which the widget groups
        them by), ``conflicts`` (their indices), ``kept`` (the indices of
        rectified lines over or close to a pole that the still background keeps as they are:
        drawn dashed in green, their warning shown on hover), ``reaches`` (per handle a
        point's reach in degrees, its ``reach`` or the default the method takes, None for
        lines and cages: the dashed ring drawn round the selected point, which a drag sets
        as one edit), ``fold_area`` (share of
        the sphere shown turned over), ``result`` (the result shown: its size and time),
        ``seconds`` and ``width`` of the last computation, ``generation`` (the edit it
        answers) and ``newest`` (the newest edit asked for: the widget times a person's
        action to the first image newer than that);
        for a video, ``video`` once Save video was asked for: ``state`` ("map", "running",
        "done", "cancelled" or "error"), ``done`` and ``total`` frames, ``fps``, ``path``
        and ``message``; ``suggest``, ``level`` and ``save`` (Save, Save image) once asked
        for: ``state`` ("running", "done" or "error") and ``message``. A job's message goes
        when it is stale: Level's, Save's (and Suggest lines' "none found") when the next
        edit begins, Suggest lines' prompt once no suggestion is left to accept (it says how
        many are left meanwhile).
    autosave_path : Path or None
        The autosave file (see ``autosave``), None when autosave is off.
    other_autosaves : list of Path
        This panorama's other autosaves, not restored (other editors', or older): ``load`` one.
    last_error : BaseException or None
        The exception of the last computation that failed, with its traceback, for a closer
        look (the widget shows its type and message).

    Examples
    --------
    >>> import omniwidget as ow
    >>> editor = ow.Editor(ow.sample_path())  # doctest: +SKIP
    >>> editor  # doctest: +SKIP
    """

    _esm = _BUNDLE
    _css = _STATIC / "editor.css"

    handles = _Document().tag(sync=True)
    stage = traitlets.Enum(("draw", "transform", "side"), default_value="draw").tag(sync=True)
    selected = traitlets.Int(-1).tag(sync=True)
    height = traitlets.Int(480).tag(sync=True)
    source = traitlets.Bytes(b"").tag(sync=True)
    source_size = traitlets.List([0, 0]).tag(sync=True)
    preview = traitlets.Bytes(b"").tag(sync=True)
    folds = traitlets.Bytes(b"").tag(sync=True)
    outputs: traitlets.List[list[list[float]]] = traitlets.List().tag(sync=True)
    status = traitlets.Dict().tag(sync=True)
    history = traitlets.Dict({"undo": 0, "redo": 0}).tag(sync=True)
    frame = traitlets.Int(0).tag(sync=True)
    frame_count = traitlets.Int(0).tag(sync=True)
    frame_interval = traitlets.Float(0.0).tag(sync=True)
    suggestions: traitlets.List[dict] = traitlets.List().tag(sync=True)

    def __init__(  # noqa: PLR0913 - the editor's documented keyword options, as a notebook cell writes them
        self,
        image: NDArray | str | os.PathLike[str],
        handles: Handles | dict | str | os.PathLike[str] | None = None,
        *,
        preview_width: int = PREVIEW_WIDTH,
        handles_path: str | os.PathLike[str] | None = None,
        height: int = 480,
        autosave: bool | str | os.PathLike[str] | None = None,
        quality: bool = True,
        frame: int | None = None,
        time: float | None = None,
    ) -> None:
        self._ready = False  # traits set by the session are no edits
        self._session = EditingSession(
            image,
            handles,
            preview_width=preview_width,
            handles_path=handles_path,
            autosave=autosave,
            quality=quality,
            frame=frame,
            time=time,
            on_change=self._apply,
            on_message=lambda content, buffers: self.send(content, buffers or None),
        )
        s = self._session
        super().__init__(
            handles=s.handles,
            height=height,
            source=s.display_source(),
            source_size=list(s.image_size),
            history=s.history,
            status=s.status,
            frame=s.frame,
            frame_count=s.frame_count,
            frame_interval=s.frame_interval,
            suggestions=s.suggestions,
        )
        self.on_msg(lambda _widget, content, _buffers: self._session.command(content))
        self._ready = True
        self._session.start()

    def _apply(self, changes: Changes) -> None:
        """The session's changes, onto the traits (sent to the browser together)."""
        if not self._ready:
            return  # the session's first state is the traits' first value
        with self.hold_sync():
            for name, value in changes.items():
                setattr(self, name, value)
            if "handles" in changes and self.selected >= len(changes["handles"]["handles"]):
                self.selected = -1

    @traitlets.observe("handles")
    def _on_handles(self, change: dict) -> None:
        # from the browser or from Python: an edit; the session's own change (an undo, say) is none
        if self._ready and change["new"] != self._session.handles:
            self._session.edit(change["new"])

    @traitlets.observe("frame")
    def _on_frame(self, change: dict) -> None:
        # assigned in Python (``editor.frame = 12``): show that frame; the session's own change is none
        if self._ready and change["new"] != self._session.frame:
            try:
                self._session.set_frame(change["new"])
            except Exception:
                self.frame = self._session.frame
                raise

    def set_state(self, sync_data: dict) -> None:
        """Apply state sent by the front end; a refused document (or value) is reported, not raised."""
        try:
            super().set_state(sync_data)
        except (HandlesError, traitlets.TraitError) as exc:
            self._session._report_error(f"that edit was refused: {exc}")
            keys = [key for key in sync_data if key in self.keys] or None
            self.send_state(keys)  # the browser goes back to what is kept here

    # --- the session, as the editor's own API ----------------------------------------------
    @property
    def session(self) -> EditingSession:
        """The plain Python session this widget shows (undo, autosave, results, commands)."""
        return self._session

    @property
    def image(self) -> NDArray:
        """The input panorama at full size (read-only)."""
        return self._session.image

    @property
    def document(self) -> Handles:
        """The handles as a validated :class:`~omniwidget.Handles` document."""
        return self._session.document

    @property
    def handles_path(self) -> Path:
        """Where the Save button writes the handles (assignable)."""
        return self._session.handles_path

    @handles_path.setter
    def handles_path(self, path: str | os.PathLike[str]) -> None:
        self._session.handles_path = Path(path)

    @property
    def autosave_path(self) -> Path | None:
        """The autosave file, None when autosave is off."""
        return self._session.autosave_path

    @property
    def other_autosaves(self) -> list[Path]:
        """The panorama's other autosaves, not restored when the editor opened (other editors', or older)."""
        return list(self._session.other_autosaves)

    def close(self) -> None:
        """Close the widget and let go of the autosave file (it stays, for the next editor to restore)."""
        session = getattr(self, "_session", None)
        if session is not None:
            session.close()
        super().close()

    @property
    def last_error(self) -> BaseException | None:
        """The exception of the last computation that failed, with its traceback."""
        return self._session.last_error

    @property
    def result(self):  # noqa: ANN201 - Result, imported lazily
        """The full-resolution :class:`~omniwidget.Result` of the current handles (computed on demand)."""
        return self._session.result

    @property
    def preview_result(self):  # noqa: ANN201
        """The :class:`~omniwidget.Result` last shown in the widget, or None."""
        return self._session.preview_result

    def wait(self, timeout: float | None = 120.0) -> dict:
        """Block until the newest edit's result is shown (or failed); return :attr:`status`."""
        return self._session.wait(timeout)

    def compute_full(self) -> None:
        """Compute the full-resolution result in the background and show it."""
        self._session.compute_full()

    def save_image(self, path: str | os.PathLike[str] | None = None) -> Path:
        """Write the full-size result (:meth:`EditingSession.save_image`); return where."""
        return self._session.save_image(path)

    def set_frame(self, frame: int | None = None, *, time: float | None = None) -> None:
        """Show another frame of the video, by index or by ``time`` in seconds; the handles stay (:meth:`EditingSession.set_frame`)."""
        self._session.set_frame(frame, time=time)

    def save_video(self, path: str | os.PathLike[str] | None = None, *, wait: bool = False) -> Path:
        """Warp the whole video by the current handles' map in the background; return where (:meth:`EditingSession.save_video`)."""
        return self._session.save_video(path, wait=wait)

    def cancel_video(self) -> bool:
        """Stop the video being saved (nothing is written); False when none is."""
        return self._session.cancel_video()

    def wait_video(self, timeout: float | None = None):  # noqa: ANN201 - VideoReport or None
        """Block until the video being saved is written, failed or cancelled; its report (None unless written)."""
        return self._session.wait_video(timeout)

    def suggest_lines(self, *, max_lines: int = 40, wait: bool = False) -> None:
        """Find straight edges in the background and show them dashed on the input (:meth:`EditingSession.suggest_lines`)."""
        self._session.suggest_lines(max_lines=max_lines, wait=wait)

    def accept_suggestion(self, key: int) -> None:
        """Add the suggestion ``key`` as a line handle: one undoable edit."""
        self._session.accept_suggestion(key)

    def accept_all_suggestions(self) -> int:
        """Add every suggestion shown as line handles in one undoable edit; return how many."""
        return self._session.accept_all_suggestions()

    def drop_suggestions(self, key: int | None = None) -> None:
        """Stop showing the suggestion ``key``, or all of them."""
        self._session.drop_suggestions(key)

    def level(self, *, wait: bool = False) -> None:
        """Level the panorama in the background: its tilt undone as one undoable edit (:meth:`EditingSession.level`)."""
        self._session.level(wait=wait)

    def straighten(self, *, wait: bool = False) -> None:
        """Level, find the structure and rectify it in the background: the handles used loaded as one undoable edit (:meth:`EditingSession.straighten`)."""
        self._session.straighten(wait=wait)

    def undo(self) -> bool:
        """Go back one edit; False when there is none."""
        return self._session.undo()

    def redo(self) -> bool:
        """Redo the edit last undone; False when there is none."""
        return self._session.redo()

    def rectify_all(self) -> None:
        """Rectify every line together (Sec. 3.4): the paper's "rectify all lines"."""
        self._session.rectify_all()

    def rectify_line(self, index: int) -> None:
        """Rectify line ``index`` and hold every other handle where it is ("rectify current line")."""
        self._session.rectify_line(index)

    def reset(self, index: int) -> None:
        """Undo every transformation of handle ``index``: its output goes back to where it was drawn."""
        self._session.reset(index)

    def move_arrow(self, index: int, tip: Any, which: Literal["east", "west"] = "east") -> None:
        """Drag point handle ``index``'s output arrow tip to ``tip`` ``[lon, lat]``: it turns and zooms."""
        self._session.move_arrow(index, tip, which)

    def save(self, path: str | os.PathLike[str] | None = None) -> Path:
        """Write the handles file (whole or not at all); default :attr:`handles_path`."""
        return self._session.save(path)

    def load(self, path: str | os.PathLike[str]) -> None:
        """Replace the handles by those of a handles file (an undoable edit)."""
        self._session.load(path)


def saved_handles(notebook: str | os.PathLike[str]) -> list[Handles]:
    """The handles of every editor whose state a saved notebook keeps.

    JupyterLab and Notebook save widget state in the notebook's metadata (with "Save
    Widget State Automatically" on, or from the menu); this reads it back, e.g. after the
    kernel was restarted: ``Editor(image, handles=saved_handles("work.ipynb")[0])``.
    """
    data = json.loads(Path(notebook).read_text(encoding="utf-8"))
    state = data.get("metadata", {}).get("widgets", {}).get("application/vnd.jupyter.widget-state+json", {}).get("state", {})
    found = []
    for model in state.values():
        value = model.get("state", {}).get("handles")
        if isinstance(value, dict) and value.get("format") == "omniwidget.handles":
            found.append(Handles.from_dict(value))
    return found
