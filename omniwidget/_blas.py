"""The method's linear algebra on one BLAS thread.

The method solves many small dense and sparse systems (Sec. 3.4's least squares, the
weights' local solves, the fill's). OpenBLAS runs each on as many threads as there are
cores, and its threads wait for work by spinning: when the cores are busy with anything
else (the editor's other workers, a browser, a second process), a small Cholesky takes
a thousand times longer than on one thread (``bench/RESULTS.md``, "One click"). Nothing of
the method is large enough for BLAS threads to pay, so :func:`one_blas_thread` holds them
to one while it runs (threadpoolctl).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, TypeVar

from ._lazy import lazy

if TYPE_CHECKING:
    import threadpoolctl
else:
    threadpoolctl = lazy("threadpoolctl")

__all__ = ["one_blas_thread"]

F = TypeVar("F", bound=Callable[..., Any])


def one_blas_thread(function: F) -> F:
    """Run ``function`` with every BLAS library of the process limited to one thread (restored after)."""

    @functools.wraps(function)
    def run(*args: Any, **kwargs: Any) -> Any:
        with threadpoolctl.threadpool_limits(limits=1, user_api="blas"):
            return function(*args, **kwargs)

    return run  # type: ignore[return-value]
