"""The edits of a session that undo and redo go through: the handles documents before each, as JSON-ready dicts."""

from __future__ import annotations

from .status import HistoryCounts

__all__ = ["HISTORY", "History"]

#: Edits kept for undo.
HISTORY = 500


class History:
    """Undo and redo over handles documents (JSON-ready dicts): at most ``limit`` edits are kept for undo.

    An edit :meth:`record` s the document it replaces and forgets what was undone;
    :meth:`undo` and :meth:`redo` trade the document shown for the one they give back.
    """

    def __init__(self, limit: int = HISTORY) -> None:
        if isinstance(limit, bool) or not isinstance(limit, int) or limit < 1:
            raise ValueError(f"limit must be a whole number of edits, 1 or more, got {limit!r}")
        self.limit = limit
        self._undo: list[dict] = []
        self._redo: list[dict] = []

    def record(self, before: dict) -> None:
        """An edit replaced ``before``: it can be undone; what was undone can no longer be redone."""
        self._undo.append(before)
        del self._undo[: -self.limit]
        self._redo.clear()

    def undo(self, shown: dict) -> dict | None:
        """The document before the last edit (``shown`` goes to redo), or None when there is none."""
        return self._step(self._undo, self._redo, shown)

    def redo(self, shown: dict) -> dict | None:
        """The document last undone (``shown`` goes to undo), or None when there is none."""
        return self._step(self._redo, self._undo, shown)

    @staticmethod
    def _step(source: list[dict], target: list[dict], shown: dict) -> dict | None:
        if not source:
            return None
        target.append(shown)
        return source.pop()

    def counts(self) -> HistoryCounts:
        """How many edits undo and redo can take, as the front end shows them."""
        return {"undo": len(self._undo), "redo": len(self._redo)}
