"""Detection in an editing session: suggested lines, Level and Straighten, each in a worker of its own.

The suggestions are shown until accepted (each an undoable edit) or dropped; the level
rotation and the straightened handles are one undoable edit each, applied to the handles as
they are when the job ends. None of them is ever in the preview's way, nor one in another's.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Literal, Protocol

import numpy as np
from numpy.typing import NDArray

from .. import detect
from .._checks import whole_number
from ..document.handles import Handles, LineHandle
from ..errors import OmniwidgetError
from . import straighten as app_straighten
from ._latest import Latest
from .source import Source
from .status import Board, JobStatus, exception_text

if TYPE_CHECKING:
    from typing_extensions import Unpack

    from ..detect import Suggestion

__all__ = ["Detection", "Editing"]

#: Called once a job has changed the handles (or failed to): the front end's answer.
Then = Callable[[], None]
#: The jobs of detection, each with its worker and its ``status[job]``.
Job = Literal["suggest", "level", "straighten"]


class Editing(Protocol):
    """What detection needs of the session: its handles and its one way to change them (an undoable edit)."""

    @property
    def handles(self) -> dict:
        """The handles document, JSON-ready."""
        ...

    def edit(self, handles: Handles | dict | str, record: bool = True) -> None:
        """Make ``handles`` the document: an undoable edit."""
        ...


def _line_key(start: Any, end: Any) -> tuple[float, ...]:
    """A line's ends, to 1e-6 degrees and in either order: a suggestion and the handle accepted from it match."""
    a, b = (tuple(round(float(v), 6) for v in p) for p in (start, end))
    return (*min(a, b), *max(a, b))


def _reason(exc: BaseException) -> str:
    return str(exc) if isinstance(exc, OmniwidgetError) else exception_text(exc)


def _answer(then: Then | None) -> None:
    if then is not None:
        then()


class Detection:
    """Suggest lines, Level and Straighten for one session, each in a worker of its own.

    Parameters
    ----------
    source : Source
        The panorama looked at (:data:`~omniwidget.detect.DETECT_WIDTH` wide at most).
    board : Board
        Where the suggestions and each job's ``status[job]`` are shown.
    editing : Editing
        The session whose handles the jobs change.
    """

    def __init__(self, source: Source, board: Board, editing: Editing) -> None:
        self.source = source
        self.board = board
        self.editing = editing
        self.suggested: list[Suggestion] = []  # the last suggest_lines, best first; shown unless accepted or dropped
        self.dropped: set[int] = set()
        self.workers = {job: Latest(f"omniwidget-editor-{job}") for job in ("suggest", "level", "straighten")}
        self._running = {"level": False, "straighten": False}
        self._errors: dict[str, BaseException | None] = {"suggest": None, "level": None, "straighten": None}  # for wait=True

    def detect_source(self) -> NDArray:
        """The panorama the detector looks at (:data:`~omniwidget.detect.DETECT_WIDTH` wide at most, as it would reduce it): kept, made once."""
        with self.board.lock:
            return self.source.downscaled(detect.DETECT_WIDTH)

    def _set(self, job: Job, **fields: Unpack[JobStatus]) -> None:
        self.board.set_job(job, fields)

    def _failed(self, job: Job, exc: BaseException) -> None:
        self._errors[job] = self.board.last_error = exc

    def _start(self, job: Job, run: Callable[[], None], message: str, wait: bool) -> None:
        """Run ``run`` in the job's worker (the status says ``message`` meanwhile); with ``wait``, block and raise its error."""
        self._errors[job] = None
        self._set(job, state="running", message=message)
        worker = self.workers[job]
        worker.submit(run)
        if wait:
            worker.wait(None)
            error = self._errors[job]
            if error is not None:
                raise error

    def _claim(self, job: str, doing: str) -> None:
        """Mark ``job`` running; OmniwidgetError when it is already."""
        with self.board.lock:
            if self._running[job]:
                raise OmniwidgetError(f"the panorama is being {doing} already; one moment")
            self._running[job] = True

    # --- suggested lines ---------------------------------------------------------------------
    def shown(self, doc: Handles | None = None) -> list[dict]:
        """The suggestions not dropped and not in the document (as line handles), JSON-ready; ``key`` names one."""
        doc = Handles.from_dict(self.editing.handles) if doc is None else doc
        lines = {_line_key(h.start, h.end) for h in doc.handles if isinstance(h, LineHandle)}
        return [
            {
                "key": key,
                "start": [float(v) for v in s.start],
                "end": [float(v) for v in s.end],
                "length": round(float(s.length), 3),
                "confidence": round(float(s.confidence), 3),
            }
            for key, s in enumerate(self.suggested)
            if key not in self.dropped and _line_key(s.start, s.end) not in lines
        ]

    def suggest(self, max_lines: int = 40, wait: bool = False) -> None:
        """Find straight edges in the background and show them (see :meth:`EditingSession.suggest_lines`)."""
        max_lines = whole_number(max_lines, "max_lines", minimum=1)
        self._start("suggest", lambda: self._suggest_job(max_lines), "finding straight edges...", wait)

    def _suggest_job(self, max_lines: int) -> None:
        start = time.perf_counter()
        try:
            found = detect.suggest_lines(self.detect_source(), max_lines=max_lines)
        except Exception as exc:  # noqa: BLE001 - shown in the widget; the handles stay
            self._failed("suggest", exc)
            self._set("suggest", state="error", message=f"could not suggest lines: {_reason(exc)}")
            return
        seconds = time.perf_counter() - start
        self.suggested, self.dropped = list(found), set()
        shown = self.shown()
        self.board.publish({"suggestions": shown})
        what = "click one to accept it, Accept all, or Drop them" if shown else "none found"  # the prompt: show
        self._set("suggest", state="done", count=len(shown), message=f"{len(shown)} suggested lines in {seconds:.2f} s: {what}")

    def suggestion(self, key: Any) -> Suggestion:
        """The suggestion shown as ``key``; IndexError when none is."""
        shown = {s["key"] for s in self.board.suggestions}
        if isinstance(key, bool) or not isinstance(key, (int, np.integer)) or int(key) not in shown:
            raise IndexError(f"suggestion {key!r} is not shown (accepted or dropped already, or suggested before the last Suggest lines)")
        return self.suggested[int(key)]

    def shown_lines(self) -> list[LineHandle]:
        """Every suggestion shown, as a line handle."""
        return [self.suggested[s["key"]].handle() for s in self.board.suggestions]

    def drop(self, key: int | None = None) -> None:
        """Stop showing the suggestion ``key``, or all of them (no edit: they were no handles)."""
        if key is None:
            self.dropped = set(range(len(self.suggested)))
        else:
            self.suggestion(key)
            self.dropped.add(int(key))
        self.show(self.shown())

    def forget(self) -> None:
        """The panorama changed (another frame): the suggestions found on the one before go."""
        self.suggested, self.dropped = [], set()

    def edited(self, doc: Handles) -> None:
        """An edit made ``doc`` the document: the suggestions it took in as handles are no longer shown."""
        if self.suggested:
            self.show(self.shown(doc))

    def show(self, shown: list[dict]) -> None:
        """Publish the suggestions shown and make Suggest lines' prompt say how many are left, or go when none is.

        The prompt ("click one to accept it, Accept all, or Drop them") is for suggestions
        on screen only: once every one was accepted or dropped it is cleared, so that no
        message asks for a click on buttons that are greyed.
        """
        before = len(self.board.suggestions)
        self.board.publish({"suggestions": shown})
        job: JobStatus = self.board.status.get("suggest") or {}
        if job.get("state") != "done" or len(shown) == before:
            return
        if shown:
            message = f"{len(shown)} suggested line{'s' * (len(shown) > 1)} left: click one to accept it, Accept all, or Drop them"
        else:
            message = ""
        self.board.set_job("suggest", {**job, "count": len(shown), "message": message})

    # --- level -----------------------------------------------------------------------------------
    def level(self, wait: bool = False, then: Then | None = None) -> None:
        """Level the panorama in the background (see :meth:`EditingSession.level`); ``then()`` once the handles changed (or did not)."""
        self._claim("level", "levelled")
        self._start("level", lambda: self._claimed("level", self._level, then), "levelling: finding the vertical edges...", wait)

    def _claimed(self, job: Job, work: Callable[[], None], then: Then | None) -> None:
        """Run a job :meth:`_claim` marked running: ``work()``, then free the job and answer ``then``, whatever happened."""
        try:
            work()
        finally:
            self._running[job] = False
            _answer(then)

    def _level(self) -> None:
        start = time.perf_counter()
        try:
            found = detect.level(self.detect_source())
            seconds = time.perf_counter() - start
            self._apply_level(found)
        except Exception as exc:  # noqa: BLE001 - shown in the widget; the handles stay
            self._job_failed("level", exc, f"could not level the panorama: {_reason(exc)}; the handles are unchanged")
            return
        message = (
            f"levelled: pitch {found.pitch:+.2f}°, roll {found.roll:+.2f}° from {len(found.edges)} vertical edges "
            f"found in {seconds:.2f} s (undo to take it back)"
        )
        pitch, roll = round(float(found.pitch), 4), round(float(found.roll), 4)
        self._set("level", state="done", message=message, pitch=pitch, roll=roll, edges=len(found.edges))

    def _apply_level(self, found: Any) -> None:
        """Apply the rotation found to the handles as they are: an edit made while it is applied is never undone."""
        for _ in range(3):
            base = self.editing.handles
            levelled = detect.level_document(Handles.from_dict(base), found)
            if self.editing.handles == base:
                self.editing.edit(levelled)
                return
        raise OmniwidgetError("the handles kept changing while the rotation was applied to them; click Level again")

    def _job_failed(self, job: Job, exc: BaseException, message: str) -> None:
        self._failed(job, exc)
        self._set(job, state="error", message=message)
        self.board.report_error(message)

    # --- straighten --------------------------------------------------------------------------
    def straighten(self, wait: bool = False, then: Then | None = None) -> None:
        """Straighten the panorama in the background (see :meth:`EditingSession.straighten`); ``then()`` once the handles changed (or did not)."""
        self._claim("straighten", "straightened")
        message = "straightening: levelling, finding the structure, rectifying it..."
        self._start("straighten", lambda: self._claimed("straighten", self._straighten, then), message, wait)

    def _straighten(self) -> None:
        start = time.perf_counter()
        try:
            done = app_straighten.straighten(self.detect_source())
            self.drop()  # the structure replaces them
            self.editing.edit(done.handles)
        except Exception as exc:  # noqa: BLE001 - shown in the widget; the handles stay
            self._job_failed("straighten", exc, f"could not straighten the panorama: {_reason(exc)}; the handles are unchanged")
            return
        seconds = time.perf_counter() - start
        message = f"straightened in {seconds:.1f} s: {done.structure.summary()} (undo to take it back)"
        self._set("straighten", state="done", message=message, lines=len(done.structure.used), dropped=len(done.structure.dropped))
