"""A worker thread that runs only the newest job, shared by the editor and the pane."""

from __future__ import annotations

import atexit
import logging
import threading
import weakref
from collections.abc import Callable

_log = logging.getLogger("omniwidget")
#: Every worker alive, stopped when the interpreter exits (:func:`_stop_all`).
_workers: weakref.WeakSet[Latest] = weakref.WeakSet()


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
        self._stopped = False
        self._thread: threading.Thread | None = None
        _workers.add(self)

    def submit(self, job: Callable[[], None]) -> None:
        with self._cond:
            if self._stopped:
                return  # the interpreter is exiting
            self._job = job
            self._cond.notify_all()
            if self._thread is None:
                self._thread = threading.Thread(target=self._loop, name=self._name, daemon=True)
                self._thread.start()

    def _loop(self) -> None:
        while True:
            with self._cond:
                self._cond.wait_for(lambda: self._job is not None or self._stopped)
                if self._stopped:
                    return
                job, self._job = self._job, None
                if job is None:  # wait_for saw a job or the stop; this narrows the type
                    continue
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

    def stop(self, timeout: float | None = None) -> bool:
        """Drop a waiting job, let a running one finish and end the thread; False if it is still running after ``timeout``.

        A daemon thread still inside compiled code when the interpreter finalizes can abort
        the process (``FATAL: exception not rethrown``), so every worker is stopped this way
        when the interpreter exits.
        """
        with self._cond:
            self._stopped, self._job = True, None
            self._cond.notify_all()
            return self._cond.wait_for(lambda: not self._running, timeout)


@atexit.register
def _stop_all() -> None:
    """Stop every worker before the interpreter finalizes (atexit runs before daemon threads are cut off)."""
    for worker in list(_workers):
        worker.stop()
