"""Modules named at the top of a module and imported when first used: the package's one mechanism for lazy imports.

``import omniwidget`` stays light (no OpenCV, scipy, numba, widgets or plotting:
``tests/test_import_hygiene.py``) while every dependency is still written once, at the top
of the module that has it, where a reader and the layer test (``tests/test_architecture.py``
reads ``lazy("...")`` as an import) see it::

    from typing import TYPE_CHECKING

    from .._lazy import lazy

    if TYPE_CHECKING:  # the real module for type checkers and IDEs
        import cv2
    else:
        cv2 = lazy("cv2")

The proxy has the semantics of an ``import cv2`` statement written inside each function that
uses it: every attribute access looks the module up in :data:`sys.modules` (so a module
replaced or blocked there, as tests do, is seen) and imports it the first time, through
:func:`importlib.import_module`, whose per-module locks make a first use from several threads
safe. A module that is not installed raises :class:`ModuleNotFoundError` naming it and what to
install, when first used and not before.

``lazy("scipy.sparse")`` imports ``scipy.sparse`` (and so ``scipy``) at its first use only,
unlike ``lazy_loader.load``, which imports a submodule's parent package at once.
"""

from __future__ import annotations

import importlib
import sys
from types import ModuleType
from typing import Any, NoReturn

__all__ = ["INSTALL", "LazyModule", "lazy", "resolve"]

#: What to install for each optional top-level module (pip's argument), named in the error when it is missing.
INSTALL: dict[str, str] = {
    "PIL": "pillow",
    "anywidget": "'omniwidget[widget]'",
    "av": "'omniwidget[video]'",
    "cv2": "opencv-python-headless",
    "cvxpy": "cvxpy",
    "distributed": "'omniwidget[dask]'",
    "igl": "libigl",
    "ipywidgets": "'omniwidget[widget]'",
    "llvmlite": "'omniwidget[fast]'",
    "numba": "'omniwidget[fast]'",
    "pyvips": "pyvips pyvips-binary",
    "pyvista": "'omniwidget[pane]'",
    "scipy": "scipy",
    "skimage": "scikit-image",
    "threadpoolctl": "threadpoolctl",
    "tifffile": "tifffile",
    "trame_vtk": "'omniwidget[pane-html]'",
}


class LazyModule:
    """A stand-in for the module ``name``: its attributes are the module's, imported at the first access."""

    __slots__ = ("_lazy_module", "_lazy_name")
    _lazy_name: str
    _lazy_module: ModuleType | None

    def __init__(self, name: str) -> None:
        if not isinstance(name, str) or not all(part.isidentifier() for part in name.split(".")):
            raise ValueError(f"a module name is dotted identifiers, got {name!r}")
        object.__setattr__(self, "_lazy_name", name)
        object.__setattr__(self, "_lazy_module", None)  # the module last resolved: the fast path while sys.modules holds it

    def __getattr__(self, attr: str) -> Any:
        module = sys.modules.get(self._lazy_name)
        if module is None or module is not self._lazy_module:
            module = resolve(self)
        return getattr(module, attr)

    def __setattr__(self, attr: str, value: Any) -> None:
        setattr(resolve(self), attr, value)

    def __delattr__(self, attr: str) -> None:
        delattr(resolve(self), attr)

    def __dir__(self) -> list[str]:
        return dir(resolve(self))

    def __repr__(self) -> str:
        state = "imported" if sys.modules.get(self._lazy_name) is not None else "not imported yet"
        return f"<lazy module {self._lazy_name!r} ({state})>"


def lazy(name: str) -> Any:
    """A stand-in for the module ``name`` (absolute, dotted) that imports it when an attribute is first read.

    Parameters
    ----------
    name : str
        The module's absolute name, e.g. ``"cv2"``, ``"scipy.sparse"`` or ``"omniwidget.evaluate.quality"``.

    Returns
    -------
    LazyModule
        Typed as ``Any``: a module assigns it under ``if TYPE_CHECKING: import name / else:``, so type
        checkers see the real module.

    Raises
    ------
    ValueError
        If ``name`` is not a dotted module name (nothing is imported here).
    """
    return LazyModule(name)


def resolve(module: Any) -> ModuleType:
    """The module a :func:`lazy` stand-in names, imported now if it is not yet (a real module is returned as is).

    Raises
    ------
    ModuleNotFoundError
        If the module (or its package) is not installed, or is blocked in :data:`sys.modules`; the message names it
        and what to install.
    TypeError
        If ``module`` is neither a module nor a :class:`LazyModule`.
    """
    if isinstance(module, ModuleType):
        return module
    if not isinstance(module, LazyModule):
        raise TypeError(f"resolve() takes a module or a lazy() stand-in, got {type(module).__name__}")
    name: str = module._lazy_name
    found = sys.modules.get(name)
    if found is None or getattr(getattr(found, "__spec__", None), "_initializing", False):
        try:
            found = importlib.import_module(name)  # its per-module lock: one import, whole, whichever thread asks first
        except ModuleNotFoundError as exc:
            _missing(name, exc)
    object.__setattr__(module, "_lazy_module", found)
    return found


def _missing(name: str, exc: ModuleNotFoundError) -> NoReturn:
    """Raise the error of a module that cannot be imported: what to install when it is the module (or its package)."""
    missing = exc.name or name
    if name != missing and not name.startswith(missing + "."):
        raise exc  # the module is there; something it imports is not
    top = name.partition(".")[0]
    raise ModuleNotFoundError(f"{name} is needed for this and is not installed (pip install {INSTALL.get(top, top)})", name=name) from exc
