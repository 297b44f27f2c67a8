"""A worker thread that runs only the newest job, shared by the editor and the pane."""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable

_log = logging.getLogger("omniwidget")


class Latest:
    """A worker thread that runs only the newest job: submitting replaces a job still waiting.

    Parameters
    ----------
    name : str
        The thread's name (it starts with the first job, as a daemon).
    """

    def __init__(self, name: str) -> None:
        self._name = name
        self._cond = threading.Condition()
        self._job: Callable[[], None] | None = None
        self._running = False
        self._thread: threading.Thread | None = None

    def submit(self, job: Callable[[], None]) -> None:
        with self._cond:
            self._job = job
            self._cond.notify_all()
            if self._thread is None:
                self._thread = threading.Thread(target=self._loop, name=self._name, daemon=True)
                self._thread.start()

    def _loop(self) -> None:
        while True:
            with self._cond:
                self._cond.wait_for(lambda: self._job is not None)
                job, self._job = self._job, None
                self._running = True
            try:
                job()
            except Exception:  # a job reports its own errors; one that does not must not stop the worker
                _log.exception("a job of the %s worker failed", self._name)
            finally:
                with self._cond:
                    self._running = False
                    self._cond.notify_all()

    def wait(self, timeout: float | None) -> bool:
        """Block until no job waits or runs; False on timeout."""
        with self._cond:
            return self._cond.wait_for(lambda: self._job is None and not self._running, timeout)
