"""What an editing session shows: the status and the changes as typed records, and the board that publishes them.

The front end (``omniwidget/widget/static/``) reads the status as a JSON object and the
changes as traits; these records name every field it reads, with its type, and stay plain
dicts at run time so that what is sent is exactly what the front end expects.
:class:`Board` holds what is shown, publishes every change through ``on_change`` and keeps
the one lock the session's parts share.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Literal, TypedDict, cast

if TYPE_CHECKING:
    from typing_extensions import Unpack

__all__ = [
    "Board",
    "Changes",
    "HistoryCounts",
    "JobState",
    "JobStatus",
    "Progress",
    "Status",
    "VideoStatus",
    "exception_text",
]

#: A job's state in ``status[job]``.
JobState = Literal["running", "done", "error"]


class JobStatus(TypedDict, total=False):
    """``status["save"]``, ``["suggest"]``, ``["level"]``, ``["straighten"]``: a job's state and message, and what it found."""

    state: JobState
    message: str
    count: int  # suggest: the suggestions shown
    pitch: float  # level: the tilt undone, degrees
    roll: float
    edges: int  # level: the vertical edges it was found from
    lines: int  # straighten: the lines used
    dropped: int  # straighten: the lines left out


class VideoStatus(TypedDict, total=False):
    """``status["video"]``: Save video's ``state`` ("map", "running", "done", "cancelled", "error") and progress."""

    state: str
    done: int
    total: int
    fps: float
    path: str
    message: str


class Progress(TypedDict):
    """``status["saving"]``: the rows of an image made in strips written so far, of ``total``."""

    done: int
    total: int


class Status(TypedDict, total=False):
    """:attr:`EditingSession.status`: the status line, the result on screen, and the jobs."""

    state: Literal["busy", "idle", "error"]
    message: str
    error: str
    notice: str
    newest: int  # the newest edit's generation
    generation: int  # the generation shown
    result: str
    warnings: list[str]
    warning_kinds: list[str]
    conflicts: list[int]
    kept: list[int]
    reaches: list[float | None]
    fold_area: float
    seconds: float
    width: int
    quality: str
    save: JobStatus
    saving: Progress | None
    saved: str
    suggest: JobStatus
    level: JobStatus
    straighten: JobStatus
    video: VideoStatus


class HistoryCounts(TypedDict):
    """:attr:`EditingSession.history`: how many edits undo and redo can take."""

    undo: int
    redo: int


class Changes(TypedDict, total=False):
    """What ``on_change`` is told: the fields that changed, each as the front end's trait holds it."""

    handles: dict
    history: HistoryCounts
    status: Status
    preview: bytes
    folds: bytes
    outputs: list[list[list[float]]]
    suggestions: list[dict]
    frame: int
    source: bytes


def exception_text(exc: BaseException) -> str:
    """``Name: message`` of an exception, readable when the message is empty (a bare MemoryError, say)."""
    name = type(exc).__name__
    try:
        detail = str(exc).strip()
    except Exception:  # noqa: BLE001 - a broken __str__ must not hide the error itself
        detail = ""
    if not detail and isinstance(exc, MemoryError):
        detail = "out of memory"
    return f"{name}: {detail}" if detail else name


#: The jobs whose ended messages go when an edit begins.
_ENDED_JOBS = ("level", "save", "suggest", "straighten")


class Board:
    """What the front end is shown (the status, the result, the suggestions, ...) and the lock that guards it.

    Every change goes through :meth:`publish`, which sets the fields and tells ``on_change``;
    the parts of a session hold the board, not the session, and are tested with a board of
    their own.
    """

    def __init__(self, on_change: Callable[[Changes], None] | None = None) -> None:
        self.lock = threading.Lock()
        self._on_change = on_change or (lambda changes: None)
        self.handles: dict = {}
        self.history: HistoryCounts = {"undo": 0, "redo": 0}
        self.status: Status = {}
        self.preview = b""
        self.folds = b""
        self.outputs: list[list[list[float]]] = []
        self.suggestions: list[dict] = []
        self.frame = 0
        self.last_error: BaseException | None = None  # the last error shown, for scripts and tests

    def publish(self, changes: Changes) -> None:
        """Set the fields and tell ``on_change``."""
        for name, value in changes.items():
            if name != "source":  # the source is made on demand (EditingSession.display_source), not kept
                setattr(self, name, value)
        self._on_change(changes)

    def set_status(self, **fields: Unpack[Status]) -> None:
        """Merge ``fields`` into the status and publish it (the caller holds :attr:`lock` where a race matters)."""
        self.publish({"status": {**self.status, **fields}})

    def set_job(self, job: Literal["save", "suggest", "level", "straighten"], fields: JobStatus) -> None:
        """``status[job]`` replaced by ``fields``: a job's state and message."""
        with self.lock:
            self.set_status(**cast(Status, {job: fields}))

    def report_error(self, message: str) -> None:
        """Show a refused command or edit; it stays until the next edit (a result still on its way keeps it)."""
        with self.lock:
            self.set_status(error=message)

    def clear_finished(self) -> None:
        """An edit begins: the messages of the jobs that ended (Level, Save, Suggest lines that found none) go.

        A job still running keeps its message; Suggest lines' prompt stays while suggestions
        are shown (the detection part says how many are left).
        """
        with self.lock:
            cleared: dict[str, JobStatus] = {}
            for job in _ENDED_JOBS:
                fields: Any = self.status.get(job)
                if not fields or fields.get("state") == "running" or not fields.get("message"):
                    continue
                if job == "suggest" and fields.get("state") == "done" and self.suggestions:
                    continue
                cleared[job] = {**fields, "message": ""}
            if cleared:
                self.set_status(**cast(Status, cleared))
