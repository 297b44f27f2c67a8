"""What a test needs that may be missing: skipped on a partial install, a failure where everything must be there.

``module(name)`` is :func:`pytest.importorskip`, except that with ``OMNIWIDGET_BROWSER_TESTS=1`` (CI, where the
test extra installs every optional dependency) a module that does not import fails the test, or the collection
of its file when called at module level, instead of hiding it. ``kernels()`` does the same for the compiled
kernels (numba), failing where ``OMNIWIDGET_REQUIRE_KERNELS=1`` says they must run (a run with
``OMNIWIDGET_NUMBA=0`` tests the numpy path on purpose, so the browser tests' variable does not decide it).
"""

from __future__ import annotations

import importlib
import os
from types import ModuleType

import pytest

#: Set to 1 (CI): a missing optional dependency fails instead of skipping (as for the real-browser tests).
STRICT_ENV_VAR = "OMNIWIDGET_BROWSER_TESTS"
#: Set to 1: the compiled kernels must be available; their tests fail instead of skipping.
KERNELS_ENV_VAR = "OMNIWIDGET_REQUIRE_KERNELS"


def missing(reason: str, env_var: str = STRICT_ENV_VAR) -> None:
    """Skip (the calling test, or its whole file at module level) for ``reason``, or fail when ``env_var`` is 1."""
    if os.environ.get(env_var) == "1":
        pytest.fail(f"{reason} ({env_var}=1 forbids skipping)", pytrace=False)
    pytest.skip(reason, allow_module_level=True)


def module(name: str, why: str = "") -> ModuleType:
    """The module ``name`` imported; skipped without it, a failure with ``OMNIWIDGET_BROWSER_TESTS=1``."""
    try:
        return importlib.import_module(name)
    except ImportError as exc:
        missing(f"{name} does not import ({exc}){': ' + why if why else ''}")
        raise  # not reached: missing() skips or fails


def kernels(why: str = "the compiled kernels (numba) are not available") -> None:
    """Skip the calling test or file without the compiled kernels; fail with ``OMNIWIDGET_REQUIRE_KERNELS=1``."""
    from omniwidget.raster import _kernels

    if not _kernels.available():
        missing(why, KERNELS_ENV_VAR)
