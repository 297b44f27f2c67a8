"""Sec. 3.2's quadratic program written as the paper states it and solved by cvxpy: the slow, readable reference.

For each control ``j``: minimise the Laplacian energy ``1/2 w_jᵀ Q w_j`` (``Q = L M⁻¹ L``,
:func:`omniwidget.method.laplacian.bilaplacian`) subject to the boundary conditions on the
handles (``w_j[b] = bc[:, j]``) and the bounds ``0 <= w_j <= 1``. The package's own solver
(:func:`omniwidget.method.bbw.bbw`, an active set on sparse factorisations) solves the same
problems many times faster; this module exists to show the problem and to check that solver.
It is the only module that imports ``cvxpy`` (``pip install cvxpy``), and only when called.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._lazy import lazy, resolve
from .laplacian import as_constraints, as_mesh, bilaplacian

if TYPE_CHECKING:
    import cvxpy as cp
else:
    cp = lazy("cvxpy")

__all__ = ["cvxpy_bbw"]


def cvxpy_bbw(V: ArrayLike, F: ArrayLike, b: ArrayLike, bc: ArrayLike, *, tolerance: float = 1e-10) -> NDArray[np.float64]:
    """Bounded biharmonic weights as a cvxpy problem per control, without partition of unity.

    Parameters
    ----------
    V : array_like, shape (n, 3), float64
        Vertex positions.
    F : array_like, shape (m, 3), int64
        Triangles, indices into ``V``.
    b : array_like, shape (p,), int64
        Constrained vertices, distinct.
    bc : array_like, shape (p, k), float64
        Their weights, in ``[0, 1]``, one column per control.
    tolerance : float
        The interior-point solver's (Clarabel's) gap and feasibility tolerances.

    Returns
    -------
    W : numpy.ndarray, shape (n, k), float64
        Rows not normalised; clipped to ``[0, 1]`` (the solver meets the bounds to its
        tolerance) and exact on ``b``.

    Raises
    ------
    ImportError
        If cvxpy is not installed (``pip install cvxpy``).
    RuntimeError
        If the solver does not report an optimal solution.
    """
    try:
        resolve(cp)
    except ImportError as exc:
        raise ImportError(f"cvxpy is needed for solver='cvxpy' (pip install cvxpy): {exc}") from exc
    v, f = as_mesh(V, F)
    idx, values = as_constraints(len(v), b, bc)
    q = bilaplacian(v, f)
    q = cp.psd_wrap(q / q.diagonal().max())  # scaled to numbers near 1 (the same minimiser); positive semi-definite
    w = cp.Variable(len(v))
    target = cp.Parameter(len(idx))
    problem = cp.Problem(cp.Minimize(0.5 * cp.quad_form(w, q)), [w[idx] == target, w >= 0, w <= 1])
    out = np.empty((len(v), values.shape[1]))
    for j in range(values.shape[1]):
        target.value = values[:, j]
        problem.solve(solver=cp.CLARABEL, tol_gap_abs=tolerance, tol_gap_rel=tolerance, tol_feas=tolerance)
        if problem.status != cp.OPTIMAL or w.value is None:
            raise RuntimeError(f"cvxpy did not solve the weights of control {j}: {problem.status}")
        out[:, j] = np.clip(w.value, 0.0, 1.0)
        out[idx, j] = values[:, j]
    return out
