"""libigl's bounded biharmonic weights, as the reference for :mod:`omniwidget.method.bbw`.

This is the only module of the package that imports ``igl`` (libigl's Python bindings,
``pip install libigl``), and only when one of its functions is called. The package itself
never needs it: :func:`omniwidget.method.bbw.bbw` solves the same problem with numpy and
scipy; the tests and ``bench/bench_bbw.py`` compare the two.

The bindings changed between releases:

* libigl 2.6 (nanobind): ``igl.bbw(V, Ele, b, bc, W0=..., partition_unity=False,
  verbosity=0, max_iter=100, ...)`` is a plain function returning ``W``; it wants float64
  and int64 arrays. Its ``partition_unity`` flag does nothing (and we do not want it).
* libigl 2.2 - 2.5 (pybind11): a solver class, ``igl.BBW(verbosity, max_iter).solve(V, F,
  b, bc)`` (``igl.BBW(verbosity)`` in the oldest), with 32-bit integer arrays.
"""

from __future__ import annotations

from importlib import metadata
from types import ModuleType
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import whole_number
from .._lazy import lazy, resolve
from .laplacian import as_constraints, as_mesh

if TYPE_CHECKING:
    import igl
else:
    igl = lazy("igl")

__all__ = ["igl_bbw", "igl_version", "load_igl"]

_INSTALL_HINT = "libigl's Python bindings are needed for this (pip install libigl)"


def load_igl() -> ModuleType:
    """Import and return the ``igl`` module.

    Raises
    ------
    ImportError
        If libigl's Python bindings are not installed; the message says ``pip install libigl``.
    """
    try:
        return resolve(igl)
    except ImportError as exc:
        raise ImportError(f"{_INSTALL_HINT}: {exc}") from exc


def igl_version() -> str:
    """The installed libigl bindings' version, e.g. ``"2.6.3"`` (``"unknown"`` if not recorded)."""
    version = getattr(load_igl(), "__version__", None)
    if version:
        return str(version)
    try:
        return metadata.version("libigl")
    except metadata.PackageNotFoundError:
        return "unknown"


def igl_bbw(V: ArrayLike, F: ArrayLike, b: ArrayLike, bc: ArrayLike, *, max_iter: int = 100) -> NDArray[np.float64]:
    """Bounded biharmonic weights by libigl's ``bbw`` (active set), without partition of unity.

    The same problem and the same input checks as :func:`omniwidget.method.bbw.bbw`; the
    inputs are converted to what the installed bindings accept (C-contiguous float64
    ``V`` and ``bc``, int64 or int32 ``F`` and ``b``).

    Parameters
    ----------
    V : array_like, shape (n, 3), float64
        Vertex positions.
    F : array_like, shape (m, 3), int64
        Triangles, indices into ``V``.
    b : array_like, shape (p,), int64
        Constrained vertices, distinct.
    bc : array_like, shape (p, k), float64
        Their weights, in ``[0, 1]``, one column per handle.
    max_iter : int
        libigl's active-set iteration limit per handle (it prints a line on stderr and
        returns its last iterate when reached).

    Returns
    -------
    W : numpy.ndarray, shape (n, k), float64
        libigl's weights, rows not normalised.

    Raises
    ------
    ImportError
        If libigl's Python bindings are not installed (``pip install libigl``).
    ValueError
        For a malformed mesh or constraint, as :func:`omniwidget.method.bbw.bbw`.
    RuntimeError
        If the installed bindings have neither ``igl.bbw`` nor ``igl.BBW``, or return
        weights of the wrong shape.
    """
    v, f = as_mesh(V, F)
    idx, values = as_constraints(v.shape[0], b, bc)
    max_iter = whole_number(max_iter, "max_iter", 1)
    igl = load_igl()
    if hasattr(igl, "BBW"):  # libigl 2.2 - 2.5: a solver class with Eigen::MatrixXi / VectorXi arguments
        try:
            solver = igl.BBW(0, max_iter)
        except TypeError:  # the oldest bindings take the verbosity only
            solver = igl.BBW(0)
        out = solver.solve(v, f.astype(np.int32), idx.astype(np.int32), values)
    elif callable(getattr(igl, "bbw", None)):  # libigl 2.6: a function of float64/int64 arrays
        out = igl.bbw(v, f, idx, values, partition_unity=False, max_iter=max_iter)
    else:
        raise RuntimeError(f"the installed igl module ({getattr(igl, '__file__', '?')}) has neither bbw nor BBW")
    w = np.array(out, dtype=np.float64)
    if w.shape != (v.shape[0], values.shape[1]):
        raise RuntimeError(f"igl.bbw returned shape {w.shape}, expected {(v.shape[0], values.shape[1])}")
    return w
