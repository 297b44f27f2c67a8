"""Bounded biharmonic weights (BBW) on a triangle mesh, with numpy and scipy only (Sec. 3.2).

Each handle ``j`` gets a weight function ``w_j`` on the mesh vertices that minimises the
discrete Laplacian energy ``1/2 w^T Q w`` with ``Q = L M^-1 L`` (:mod:`.laplacian`: ``L``
the cotangent Laplacian, ``M`` the Voronoi mass matrix, the bilaplacian libigl's ``bbw``
uses), takes the
prescribed values on the handle vertices and stays within ``[0, 1]`` elsewhere. As in the
paper the handles are solved independently, without the partition-of-unity constraint;
:func:`normalize_rows` divides each vertex's weights by their sum afterwards.

This module imports scipy: load it lazily from modules that ``import omniwidget`` loads.
"""

from __future__ import annotations

import math
import os
import time
import warnings
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import whole_number
from .._lazy import lazy
from ._cvxpy import cvxpy_bbw
from ._igl import igl_bbw
from .laplacian import DEGENERATE_AREA, as_constraints, as_mesh, checked_bilaplacian
from .locate import locate_points

if TYPE_CHECKING:
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla
    from scipy import spatial
    from scipy.sparse import csgraph
else:
    sp = lazy("scipy.sparse")
    spla = lazy("scipy.sparse.linalg")
    csgraph = lazy("scipy.sparse.csgraph")
    spatial = lazy("scipy.spatial")

__all__ = ["SOLVERS", "bbw", "normalize_rows"]

FloatArray = NDArray[np.float64]
Solver = Literal["active-set", "cvxpy", "igl"]
#: Who may solve the weights (:func:`bbw`'s ``solver``).
SOLVERS: tuple[Solver, ...] = ("active-set", "cvxpy", "igl")
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]

#: Coarsening stops below this many vertices ...
COARSEST_VERTICES = 400
#: ... or when a coarser level would keep more than this fraction of the vertices.
MAX_COARSE_FRACTION = 0.6
#: Global active-set steps on the coarser levels (they only predict the active sets).
COARSE_STEPS = 2
#: Rings around the changed vertices within which a change is settled locally.
LOCAL_RINGS = 2
#: A factorization is bordered (Schur complement) while at most this many vertices differ.
MAX_BORDER = 48
#: A bordered solve whose relative residual exceeds this is redone by a fresh factorization.
BORDER_RESIDUAL = 1e-10
#: A start whose free weights' scaled gradient is at most this already is the minimiser (the
#: handle's problem did not change where its weights are free): it is taken without a solve.
START_RESIDUAL = 1e-12


# --- weights ---------------------------------------------------------------------------
def normalize_rows(W: ArrayLike, *, eps: float = 1e-12) -> FloatArray:
    """Divide each row of weights by its sum (a partition of unity, as the paper does after BBW).

    Parameters
    ----------
    W : array_like, shape (n, k), float64
        Weights, one row per vertex (or sample) and one column per handle.
    eps : float
        A row whose sum is at most ``eps`` in absolute value has no meaningful direction:
        it is replaced by the uniform row ``1/k`` (every handle counts equally), so that
        the result is finite and every row sums to 1. With :func:`bbw` weights this only
        happens at points that no handle reaches.

    Returns
    -------
    numpy.ndarray, shape (n, k), float64
        A new array whose rows sum to 1 (within rounding).
    """
    w = np.array(W, dtype=np.float64)
    if w.ndim != 2 or w.shape[1] < 1:
        raise ValueError(f"W must be an (n, k) array with k >= 1, got shape {w.shape}")
    if not np.all(np.isfinite(w)):
        raise ValueError("W must be finite (found NaN or inf)")
    if not (math.isfinite(eps) and eps >= 0):
        raise ValueError(f"eps must be a non-negative finite number, got {eps}")
    s = w.sum(axis=1)
    empty = np.abs(s) <= eps
    w[~empty] /= s[~empty, None]
    w[empty] = 1.0 / w.shape[1]
    return w


# --- linear algebra helpers ----------------------------------------------------------------
def _factor(a: sp.csr_matrix) -> spla.SuperLU:
    """Sparse LU of a symmetric positive definite matrix, kept symmetric (no pivoting)."""
    # a is exactly symmetric, so its CSR arrays are also the CSC arrays of the same matrix
    csc = sp.csc_matrix((a.data, a.indices, a.indptr), shape=a.shape)
    return spla.splu(csc, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options={"SymmetricMode": True})


def _submatrix(a: sp.csr_matrix, keep: BoolArray) -> sp.csr_matrix:
    """``a[keep][:, keep]`` for a CSR matrix with sorted indices (stays sorted), without scipy's indexing overhead."""
    rows = np.flatnonzero(keep)
    starts = a.indptr[rows]
    lengths = a.indptr[rows + 1] - starts
    total = int(lengths.sum())
    entries = np.repeat(starts - (np.cumsum(lengths) - lengths), lengths) + np.arange(total)
    cols = a.indices[entries]
    ok = keep[cols]
    new_col = (np.cumsum(keep) - 1)[cols[ok]]
    counts = np.bincount(np.repeat(np.arange(rows.size), lengths)[ok], minlength=rows.size)
    indptr = np.concatenate([[0], np.cumsum(counts)])
    return sp.csr_matrix((a.data[entries[ok]], new_col, indptr), shape=(rows.size, rows.size))


def _rows(a: sp.csr_matrix, rows: IntArray, keep: BoolArray) -> tuple[IntArray, IntArray, FloatArray]:
    """The entries of ``a[rows][:, keep]`` as (row in ``rows``, column in ``keep``, value)."""
    starts = a.indptr[rows]
    lengths = a.indptr[rows + 1] - starts
    entries = np.repeat(starts - (np.cumsum(lengths) - lengths), lengths) + np.arange(int(lengths.sum()))
    cols = a.indices[entries]
    ok = keep[cols]
    return np.repeat(np.arange(rows.size), lengths)[ok], (np.cumsum(keep) - 1)[cols[ok]], a.data[entries[ok]]


def _dense_rows(a: sp.csr_matrix, rows: IntArray, keep: BoolArray) -> FloatArray:
    """``a[rows][:, keep]`` as a dense array."""
    i, j, val = _rows(a, rows, keep)
    out = np.zeros((rows.size, int(keep.sum())))
    out[i, j] = val
    return out


def _sparse_rows(a: sp.csr_matrix, rows: IntArray, keep: BoolArray) -> sp.csr_matrix:
    """``a[rows][:, keep]`` as a CSR matrix."""
    i, j, val = _rows(a, rows, keep)
    return sp.csr_matrix((val, (i, j)), shape=(rows.size, int(keep.sum())))


# --- the box-constrained solver ------------------------------------------------------
@dataclass
class _Problem:
    """The quadratic program of one mesh level, shared by all handles."""

    q: sp.csr_matrix  # (n_free, n_free) Q restricted to the free vertices, sorted indices
    diag: FloatArray  # (n_free,) its diagonal
    rhs: FloatArray  # (n_free, k) -Q[free, b] @ bc: the minimiser of 1/2 x^T q x - rhs^T x is sought
    free: IntArray  # (n_free,) the free vertices
    ring: sp.csr_matrix  # (n_free, n_free) mesh adjacency among free vertices plus identity, 0/1 floats
    norm: float  # infinity norm of q


def _problem(v: FloatArray, f: IntArray, b: IntArray, bc: FloatArray) -> _Problem:
    q = checked_bilaplacian(v, f)
    free_mask = np.ones(v.shape[0], dtype=bool)
    free_mask[b] = False
    free = np.flatnonzero(free_mask)
    q_ff = _submatrix(q, free_mask)
    rhs = -(q[free][:, b] @ bc)
    ring = _submatrix((_adjacency(v.shape[0], f) + sp.eye(v.shape[0], format="csr")).astype(np.float64).tocsr(), free_mask)
    norm = float(np.abs(q_ff).sum(axis=1).max()) if q_ff.nnz else 0.0
    return _Problem(q_ff, q_ff.diagonal(), np.ascontiguousarray(rhs), free, ring, norm)


def _update(prob: _Problem, r: FloatArray, x: FloatArray, lower: BoolArray, upper: BoolArray, tol: float) -> tuple[BoolArray, BoolArray]:
    """One primal-dual active-set step: add the violated bounds, release those with wrong-signed multipliers.

    The multiplier of an active bound is the gradient ``(Q x - r)_i``; divided by ``Q_ii``
    it is the change of ``x_i`` that releasing the bound alone would make, compared with
    ``tol`` in weight units. A multiplier within two rings of a violated bound is not
    trusted (it is about to change), so that bound is kept for now.
    """
    inactive = ~(lower | upper)
    mu = (prob.q @ x - r) / prob.diag
    low = inactive & (x < -tol)
    high = inactive & (x > 1.0 + tol)
    hold = np.zeros_like(lower)
    if low.any() or high.any():
        hold = (prob.q @ (low | high).astype(np.float64)) != 0
    return (lower & ((mu >= -tol) | hold)) | low, (upper & ((mu <= tol) | hold)) | high


def _clamped_solve(q: sp.csr_matrix, r: FloatArray, x: FloatArray, solve: BoolArray) -> None:
    """Minimise over ``x[solve]`` with the other entries of ``x`` fixed (in place), by a fresh factorization."""
    if solve.any():
        c = (r - q @ np.where(solve, 0.0, x))[solve]
        x[solve] = _factor(_submatrix(q, solve)).solve(c)


class _BorderedSolver:
    """Solves ``Q[I, I] y = c[I]`` for a sequence of index sets ``I``, reusing factorizations.

    ``Q[B, B]`` is factored for a base set ``B``. A later ``I`` borders that factor: the
    vertices dropped from ``B`` are clamped with Lagrange multipliers and those added to it
    are appended, which leaves a dense symmetric system (a Schur complement) of size
    ``|B - I| + |I - B|``. Its columns ``Q[B, B]^-1 e_v`` (dropped ``v``) and
    ``Q[B, B]^-1 Q[B, v]`` (added ``v``) are solved once per vertex and kept. When more
    than ``max_border`` vertices differ, ``Q[I, I]`` is factored and becomes the base.
    """

    def __init__(self, q: sp.csr_matrix, max_border: int, q_norm: float) -> None:
        self.q = q
        self.max_border = max_border
        self.q_norm = q_norm  # infinity norm of q, for the residual check
        self.base: BoolArray | None = None
        self.lu: spla.SuperLU | None = None
        self.position = np.empty(0, dtype=np.int64)
        self.columns: dict[int, FloatArray] = {}
        self.factorizations = 0

    def _refactor(self, inactive: BoolArray) -> None:
        self.base = inactive.copy()
        self.lu = _factor(_submatrix(self.q, inactive))
        self.position = np.cumsum(inactive) - 1
        self.columns = {}
        self.factorizations += 1

    def solve(self, inactive: BoolArray, c: FloatArray) -> FloatArray:
        """``Q[I, I]^-1 c[I]`` for ``I = inactive``; ``c`` has one entry per vertex."""
        if self.base is None or np.count_nonzero(self.base != inactive) > self.max_border:
            self._refactor(inactive)
        assert self.base is not None and self.lu is not None
        base = self.base
        y0 = self.lu.solve(np.where(inactive, c, 0.0)[base])
        dropped = np.flatnonzero(base & ~inactive)
        added = np.flatnonzero(inactive & ~base)
        if dropped.size + added.size == 0:
            return y0
        try:
            y = self._bordered(inactive, c, y0, dropped, added)
        except np.linalg.LinAlgError:  # a singular border
            y = None
        if y is not None:
            # the bordered solve is as accurate as a direct one in practice (relative residual ~1e-15);
            # should it ever not be, start afresh
            full = np.zeros(inactive.shape[0])
            full[inactive] = y
            residual = np.abs((self.q @ full)[inactive] - c[inactive]).max()
            if residual <= BORDER_RESIDUAL * (self.q_norm * np.abs(y).max() + np.abs(c[inactive]).max()):
                return y
        self._refactor(inactive)
        return self.lu.solve(c[inactive])

    def _bordered(self, inactive: BoolArray, c: FloatArray, y0: FloatArray, dropped: IntArray, added: IntArray) -> FloatArray:
        assert self.base is not None and self.lu is not None
        base = self.base
        missing = np.asarray([v for v in (*added.tolist(), *dropped.tolist()) if v not in self.columns], dtype=np.int64)
        if missing.size:
            block = np.zeros((y0.size, missing.size))
            new = ~base[missing]
            if new.any():
                block[:, new] = _dense_rows(self.q, missing[new], base).T  # Q[B, v] = Q[v, B]^T
            old = np.flatnonzero(~new)
            block[self.position[missing[old]], old] = 1.0
            # a few right-hand sides at a time: SuperLU hands wider blocks to multi-threaded BLAS,
            # whose threads then fight the other handles' threads for the cores
            solved = np.concatenate([self.lu.solve(block[:, i : i + 4]) for i in range(0, missing.size, 4)], axis=1)
            for i, v in enumerate(missing.tolist()):
                self.columns[v] = solved[:, i]
        # unknowns: y on B, t = [y_added, multipliers of dropped]; y = y0 - Z t
        z = np.stack([self.columns[v] for v in (*added.tolist(), *dropped.tolist())], axis=1)
        m = added.size
        g_z = np.empty((z.shape[1], z.shape[1]))
        g_y = np.empty(z.shape[1])
        schur = np.zeros_like(g_z)
        if m:
            q_added = _sparse_rows(self.q, added, base)  # sparse products: no BLAS threads to contend with
            g_z[:m] = q_added @ z
            g_y[:m] = q_added @ y0
            in_added = np.zeros(inactive.shape[0], dtype=bool)
            in_added[added] = True
            schur[:m, :m] = _dense_rows(self.q, added, in_added)
        g_z[m:] = z[self.position[dropped]]
        g_y[m:] = y0[self.position[dropped]]
        schur -= 0.5 * (g_z + g_z.T)
        t_rhs = -g_y
        t_rhs[:m] += c[added]
        t = np.linalg.solve(schur, t_rhs)  # symmetric indefinite, small
        out = np.zeros(inactive.shape[0])
        out[base] = y0 - np.einsum("ij,j->i", z, t)  # not z @ t: keep BLAS (and its threads) out of the loop
        out[added] = t[:m]
        return out[inactive]


@dataclass
class _HandleResult:
    x: FloatArray
    converged: bool
    steps: int
    factorizations: int


def _already_solved(prob: _Problem, j: int, x: FloatArray, tol: float) -> bool:
    """Whether ``x`` (in ``[0, 1]``) satisfies handle ``j``'s KKT conditions without a solve.

    The free weights' gradient ``(Q x - r)_i / Q_ii`` must vanish to :data:`START_RESIDUAL`
    (rounding: a start that is the last solution of a problem that did not change around
    the handle's free weights), and the active bounds' multipliers must have the right sign
    to ``tol``, as :func:`_update` asks.
    """
    mu = (prob.q @ x - prob.rhs[:, j]) / prob.diag
    lower, upper = x <= 0.0, x >= 1.0
    free = ~(lower | upper)
    return bool(np.all(np.abs(mu[free]) <= START_RESIDUAL) and np.all(mu[lower] >= -tol) and np.all(mu[upper] <= tol))


def _solve_handle(prob: _Problem, j: int, lower: BoolArray, upper: BoolArray, tol: float, max_steps: int) -> _HandleResult:
    """The active-set iterations for handle ``j``, from the initial active sets ``lower``, ``upper``.

    A global step solves the clamped problem on the whole free set (with
    :class:`_BorderedSolver`) and updates the active sets (:func:`_update`); when they
    changed, the change is first settled locally: within ``LOCAL_RINGS`` rings of the
    changed vertices, with all other weights frozen, clamped solves and updates are
    repeated until that region's active sets are stable. Converged means that a global
    step changed nothing, which is the KKT condition of the whole problem.
    """
    q, r = prob.q, prob.rhs[:, j]
    upper = upper & ~lower
    x = np.zeros(r.shape[0])
    solver = _BorderedSolver(q, MAX_BORDER, prob.norm)
    for step in range(1, max_steps + 1):
        x[lower] = 0.0
        x[upper] = 1.0
        inactive = ~(lower | upper)
        if inactive.any():
            x[inactive] = solver.solve(inactive, r - q @ np.where(inactive, 0.0, x))
        new_lower, new_upper = _update(prob, r, x, lower, upper, tol)
        changed = (new_lower != lower) | (new_upper != upper)
        lower, upper = new_lower, new_upper
        if not changed.any():
            return _HandleResult(x, True, step, solver.factorizations)
        region = changed.astype(np.float64)
        for _ in range(LOCAL_RINGS):
            region = prob.ring @ region
        local = region > 0
        for _ in range(max_steps):
            x[lower] = 0.0
            x[upper] = 1.0
            _clamped_solve(q, r, x, local & ~(lower | upper))
            new_lower, new_upper = _update(prob, r, x, lower, upper, tol)
            if not np.any(((new_lower != lower) | (new_upper != upper)) & local):
                break
            lower = np.where(local, new_lower, lower)
            upper = np.where(local, new_upper, upper)
    x[lower] = 0.0
    x[upper] = 1.0
    return _HandleResult(x, False, max_steps, solver.factorizations)


# --- the hierarchy of coarser sphere meshes -------------------------------------------------
@dataclass
class _Level:
    """One mesh of the hierarchy."""

    vertices: FloatArray  # the input positions (finest level) or unit vectors (coarser levels)
    faces: IntArray
    b: IntArray  # the constrained vertices, in this level's numbering, in the order of the input b
    prolong: sp.csr_matrix | None = None  # (n_finer, n_this) interpolation onto the next finer level


def _adjacency(n: int, f: IntArray) -> sp.csr_matrix:
    rows = np.concatenate([f[:, 0], f[:, 1], f[:, 2]])
    cols = np.concatenate([f[:, 1], f[:, 2], f[:, 0]])
    a = sp.csr_matrix((np.ones(rows.size, dtype=np.int8), (rows, cols)), shape=(n, n))
    return ((a + a.T) > 0).tocsr()


def _is_sphere_mesh(v: FloatArray, f: IntArray) -> bool:
    """Whether the mesh is a closed genus-0 surface with its vertices on a sphere about the origin."""
    r = np.linalg.norm(v, axis=1)
    if not (r.min() > 0 and r.max() - r.min() <= 1e-6 * r.mean()):
        return False
    lo = np.minimum(f, np.roll(f, -1, axis=1)).ravel()
    hi = np.maximum(f, np.roll(f, -1, axis=1)).ravel()
    _, counts = np.unique(lo * v.shape[0] + hi, return_counts=True)
    return bool(np.all(counts == 2) and v.shape[0] - counts.size + f.shape[0] == 2)


def _coarse_vertices(adj: sp.csr_matrix, forced: IntArray) -> IntArray:
    """A maximal set of pairwise non-adjacent vertices, plus all ``forced`` ones (listed first)."""
    indptr, indices = adj.indptr.tolist(), adj.indices.tolist()
    blocked = bytearray(adj.shape[0])
    for v in forced.tolist():
        blocked[v] = 1
        for w in indices[indptr[v] : indptr[v + 1]]:
            blocked[w] = 1
    chosen = forced.tolist()
    for v in range(adj.shape[0]):
        if not blocked[v]:
            chosen.append(v)
            for w in indices[indptr[v] : indptr[v + 1]]:
                blocked[w] = 1
    return np.asarray(chosen, dtype=np.int64)


def _hull(u: FloatArray) -> IntArray | None:
    """Outward-oriented convex hull triangles of unit vectors, or None if it is not a clean mesh of them."""
    try:
        faces = spatial.ConvexHull(u).simplices.astype(np.int64)
    except Exception:  # qhull errors: too few or degenerate points
        return None
    a, b, c = (u[faces[:, i]] for i in range(3))
    normal = np.cross(b - a, c - a)
    side = np.einsum("ij,ij->i", normal, a + b + c)
    flip = side < 0
    faces[flip] = faces[flip][:, [0, 2, 1]]
    used = np.zeros(u.shape[0], dtype=bool)
    used[faces.ravel()] = True
    longest = np.max([np.sum((x - y) ** 2, axis=1) for x, y in ((a, b), (b, c), (c, a))], axis=0)
    size = np.linalg.norm(normal, axis=1)
    if not used.all() or np.any(size <= 1e3 * DEGENERATE_AREA * longest):
        return None
    # a face whose plane passes through the origin: the points do not surround it (they lie in
    # a hemisphere), and the hull is no mesh of the sphere
    if np.any(np.abs(side) <= 1e-9 * size):
        return None
    return faces


def _prolongation(u_fine: FloatArray, u_coarse: FloatArray, f_coarse: IntArray) -> sp.csr_matrix:
    """Barycentric interpolation from a coarse sphere mesh onto fine points (radial projection), (n_fine, n_coarse)."""
    face, bary = locate_points(u_coarse, f_coarse, u_fine)
    rows = np.repeat(np.arange(u_fine.shape[0]), 3)
    return sp.csr_matrix((bary.ravel(), (rows, f_coarse[face].ravel())), shape=(u_fine.shape[0], u_coarse.shape[0]))


def _hierarchy(v: FloatArray, f: IntArray, b: IntArray) -> list[_Level]:
    """The input mesh followed by ever coarser meshes of the same sphere (finest first).

    Only for a closed genus-0 mesh whose vertices lie on a sphere about the origin (the
    meshes of this package); any other mesh gets the single level. A coarser level keeps
    the constrained vertices and a maximal independent set of the others (about a
    quarter of the vertices), triangulated by their convex hull, until fewer than
    ``COARSEST_VERTICES`` remain.
    """
    levels = [_Level(v, f, b)]
    if not _is_sphere_mesh(v, f):
        return levels
    u = v / np.linalg.norm(v, axis=1, keepdims=True)
    while u.shape[0] > COARSEST_VERTICES:
        fine = levels[-1]
        chosen = _coarse_vertices(_adjacency(u.shape[0], fine.faces), fine.b)
        if chosen.size > MAX_COARSE_FRACTION * u.shape[0] or chosen.size < 4:
            break
        u_c = u[chosen]
        f_c = _hull(u_c)
        if f_c is None:
            break
        # the forced (constrained) vertices come first in `chosen`, in the order of fine.b
        levels.append(_Level(u_c, f_c, np.arange(fine.b.size, dtype=np.int64), _prolongation(u, u_c, f_c)))
        u = u_c
    return levels


# --- bbw ---------------------------------------------------------------------------------
def bbw(  # noqa: PLR0913 - the mesh, its constraints and the solve's documented keyword knobs (libigl's bbw and its options)
    V: ArrayLike,
    F: ArrayLike,
    b: ArrayLike,
    bc: ArrayLike,
    *,
    tol: float = 1e-9,
    max_iter: int = 100,
    multilevel: bool = True,
    workers: int | None = None,
    start: ArrayLike | None = None,
    solver: Solver = "active-set",
) -> FloatArray:
    """Bounded biharmonic weights, one column per handle, without partition of unity.

    For each handle ``j`` independently, minimise the Laplacian energy
    ``1/2 w^T Q w`` with ``Q = L M^-1 L`` (:func:`bilaplacian`) subject to
    ``w[b] = bc[:, j]`` and ``0 <= w <= 1``: the problem libigl's ``bbw`` solves (with
    ``partition_unity`` off, the paper's choice). Rows are not normalised; use
    :func:`normalize_rows`.

    Parameters
    ----------
    V : array_like, shape (n, 3), float64
        Vertex positions.
    F : array_like, shape (m, 3), int64
        Triangles, indices into ``V``; every vertex must be used and no triangle degenerate.
    b : array_like, shape (p,), int64
        Constrained vertices (the handles' vertices), distinct; every connected component
        of the mesh needs at least one.
    bc : array_like, shape (p, k), float64
        Their weights, in ``[0, 1]``: column ``j`` belongs to handle ``j``.
    tol : float
        Tolerance of the bound constraints, in weight units, ``(0, 1e-3]``: the iterations
        stop when no free weight lies outside ``[-tol, 1 + tol]`` and no active bound's
        multiplier (scaled by the diagonal of ``Q``, i.e. the move the weight would make
        if that bound alone were released) exceeds ``tol`` with the wrong sign. The result
        is then clipped to ``[0, 1]``; it agrees with ``igl.bbw`` to about ``1e-10``.
    max_iter : int
        Maximum number of global active-set steps per handle on the input mesh.
    multilevel : bool
        Warm-start from coarser meshes (only used for a closed mesh whose vertices lie
        on a sphere about the origin; see Notes). ``False`` starts from the unconstrained
        solution, as libigl does; the result is the same, only slower.
    workers : int or None
        Threads solving handles in parallel (the sparse factorizations release the
        GIL); ``None`` uses one per CPU, at most one per handle.
    start : array_like, shape (n, k), optional
        A guess of the weights (for example the last solution of a slightly different
        problem, interpolated onto this mesh): the active sets start where it is 0 or 1,
        and the coarser levels are skipped. A handle whose start already satisfies its
        optimality conditions (to rounding: its problem did not change where its weights
        are free) is taken as it is, without a solve. The result is the same minimiser;
        only the number of steps to it changes.
    solver : {"active-set", "cvxpy", "igl"}
        Who solves: this module's active set (the package's own, fast); ``"cvxpy"`` the
        quadratic program as the paper states it, in a few lines of cvxpy
        (:func:`omniwidget.method._cvxpy.cvxpy_bbw`: a slow, readable reference); ``"igl"``
        libigl's ``bbw`` (:func:`omniwidget.method._igl.igl_bbw`). The references take
        ``V``, ``F``, ``b`` and ``bc`` only (``max_iter`` goes to libigl too); they need
        ``pip install cvxpy`` or ``libigl``.

    Returns
    -------
    W : numpy.ndarray, shape (n, k), float64
        ``W[b] == bc`` exactly and ``0 <= W <= 1``.

    Raises
    ------
    ValueError
        For a malformed mesh, constraint or option (see the parameters).
    ImportError
        For ``solver="cvxpy"`` or ``"igl"`` without that package.

    Warns
    -----
    RuntimeWarning
        If some handle did not converge in ``max_iter`` steps; its column is then the
        last iterate clipped to ``[0, 1]``.

    Notes
    -----
    With ``f`` the free vertices, each handle's problem is the box-constrained QP
    ``min 1/2 x^T Q_ff x - r_j^T x`` with ``r_j = -Q_fb bc[:, j]`` and ``0 <= x <= 1``;
    ``Q_ff`` is symmetric positive definite, so the minimiser is unique.

    *Active sets.* The solver is a primal-dual active-set method, the iteration of
    libigl's ``active_set``: with the lower and upper active sets fixed at 0 and 1, the
    rest ``I`` solves ``Q_II x_I = r_I - Q_IA x_A`` exactly (sparse LU of ``Q_II``, SuperLU
    with a symmetric minimum-degree ordering and no pivoting); then free weights outside
    ``[0, 1]`` become active and active bounds whose multiplier ``(Q x - r)_i`` has the
    wrong sign are released. When a step changes nothing, the KKT conditions hold and
    ``x`` is the minimiser. Started from the unconstrained solution this needs tens of
    steps, each a factorization (the weights are 0 on large regions whose boundary only
    creeps a ring per step), which is where libigl spends its time. Three things cut it:

    1. *Multilevel warm start* (sphere meshes). Coarser meshes keep the constrained
       vertices and a maximal independent set of the others, triangulated as their
       convex hull, down to about ``COARSEST_VERTICES`` vertices. The coarsest level
       starts from the unconstrained solution (one factorization of ``Q_ff`` shared by
       all handles, ``k`` right-hand sides); each finer level starts from the active sets
       of the coarser weights interpolated barycentrically (0 and 1 where they are exactly
       0 or 1), which puts the free boundary within a ring or two. Coarse levels are only
       predictions: they stop after ``COARSE_STEPS`` global steps.
    2. *Local settling.* After a global step that changed the active sets, the change
       is settled within ``LOCAL_RINGS`` rings of the changed vertices, with the other
       weights frozen (small, cheap factorizations), before the next global step.
    3. *Factorization reuse.* Consecutive global steps differ in few vertices: the
       previous factorization is bordered (a Schur complement) rather than redone while
       at most ``MAX_BORDER`` vertices differ.

    The active set starts from the coarse level's solution, so it needs a few
    factorizations of ``Q_II`` per handle on the input mesh where libigl's active set,
    starting from nothing, needs many; the handles are independent and run in threads.
    ``bench/bench_bbw.py`` compares the times with ``igl.bbw`` (``bench/RESULTS.md``): the
    gain grows with the mesh, since on small meshes libigl needs few steps and
    factorizations are cheap.
    """
    if solver == "cvxpy":
        return cvxpy_bbw(V, F, b, bc)
    if solver == "igl":
        return igl_bbw(V, F, b, bc, max_iter=max_iter)
    if solver != "active-set":
        raise ValueError(f"solver must be one of {', '.join(SOLVERS)}, got {solver!r}")
    settings = _Settings(tol=tol, max_iter=max_iter, multilevel=multilevel, workers=workers)
    return _bbw(V, F, b, bc, settings, start)[0]


@dataclass(frozen=True)
class _Settings:
    """The active-set solve's knobs: :func:`bbw`'s parameters of the same names."""

    tol: float = 1e-9
    max_iter: int = 100
    multilevel: bool = True
    workers: int | None = None

    def checked(self, k: int) -> _Settings:
        """These settings validated (the errors name the parameter), ``workers`` resolved for ``k`` handles."""
        try:
            tol = float(self.tol)
        except (TypeError, ValueError):
            raise ValueError(f"tol must be a number in (0, 1e-3], got {self.tol!r}") from None
        if not (0.0 < tol <= 1e-3):
            raise ValueError(f"tol must be a number in (0, 1e-3], got {tol!r}")
        max_iter = whole_number(self.max_iter, "max_iter", 1)
        workers = min(k, os.cpu_count() or 1) if self.workers is None else min(k, whole_number(self.workers, "workers", 1))
        return _Settings(tol, max_iter, self.multilevel, workers)


def _bbw(
    V: ArrayLike,
    F: ArrayLike,
    b: ArrayLike,
    bc: ArrayLike,
    settings: _Settings | None = None,
    start: ArrayLike | None = None,
) -> tuple[FloatArray, dict]:
    """:func:`bbw` and a record of the work done (levels, steps, factorizations, seconds).

    The levels are solved coarsest first, each from the weights of the one below it
    (:func:`_level_guess`), the input mesh last; only its handles may fail to converge.
    """
    v, f = as_mesh(V, F)
    n = v.shape[0]
    idx, values = as_constraints(n, b, bc)
    k = values.shape[1]
    settings = (settings or _Settings()).checked(k)
    _check_components(n, f, idx)
    guess = _checked_start(start, n, k)
    levels = _hierarchy(v, f, idx) if settings.multilevel and guess is None else [_Level(v, f, idx)]
    info: dict = {"levels": [], "workers": settings.workers}
    w: FloatArray | None = None
    failed: list[int] = []
    for depth in range(len(levels) - 1, -1, -1):
        t0 = time.perf_counter()
        prob = _problem(levels[depth].vertices, levels[depth].faces, levels[depth].b, values)
        steps = settings.max_iter if depth == 0 else COARSE_STEPS
        results = _solve_handles(prob, _level_guess(levels, depth, prob, w, guess), settings, steps, warm=guess is not None)
        w = _level_weights(levels[depth], prob, values, results)
        if depth == 0:
            failed = [j for j, res in enumerate(results) if not res.converged]
        info["levels"].append(
            {
                "vertices": levels[depth].vertices.shape[0],
                "steps": [res.steps for res in results],
                "factorizations": [res.factorizations for res in results],
                "seconds": time.perf_counter() - t0,
            }
        )
    if failed:
        warnings.warn(
            f"bbw: the active-set iterations did not converge in max_iter={settings.max_iter} steps for handles {failed}; "
            "their weights are the last iterate clipped to [0, 1]",
            RuntimeWarning,
            stacklevel=3,
        )
    assert w is not None
    return w, info


def _check_components(n: int, f: IntArray, idx: IntArray) -> None:
    """Raise unless every connected component of the mesh has a constrained vertex (else its weights are free)."""
    n_comp, label = csgraph.connected_components(_adjacency(n, f), directed=False)
    if n_comp > 1:
        missing = np.setdiff1d(np.arange(n_comp), label[idx])
        if missing.size:
            raise ValueError(f"the mesh has {n_comp} connected components and {missing.size} of them have no vertex in b")


def _checked_start(start: ArrayLike | None, n: int, k: int) -> FloatArray | None:
    """``start`` as a finite float64 array of shape ``(n, k)``, or None."""
    if start is None:
        return None
    out = np.asarray(start, dtype=np.float64)
    if out.shape != (n, k) or not np.all(np.isfinite(out)):
        raise ValueError(f"start must be a finite array of shape {(n, k)} (a guess of the weights), got {out.shape}")
    return out


def _level_guess(levels: list[_Level], depth: int, prob: _Problem, coarser: FloatArray | None, start: FloatArray | None) -> FloatArray:
    """The free weights a level's active sets start from, ``(free, k)``.

    The coarser level's weights interpolated onto this one, or on the coarsest level the
    caller's ``start``, else the unconstrained solution (one factorization, ``k`` right-hand
    sides). Empty when the level has no free vertex.
    """
    if not prob.free.size:
        return np.empty((0, prob.rhs.shape[1]))
    if coarser is None:
        return start[prob.free] if start is not None else _factor(prob.q).solve(prob.rhs)
    prolong = levels[depth + 1].prolong
    if prolong is None:  # _hierarchy gives every coarser level one
        raise RuntimeError(f"level {depth + 1} of the multilevel solve has no prolongation")
    return (prolong @ coarser)[prob.free]


def _solve_handles(prob: _Problem, guess: FloatArray, settings: _Settings, steps: int, *, warm: bool) -> list[_HandleResult]:
    """Each handle's box-constrained problem from its column of ``guess``, in ``settings.workers`` threads.

    With ``warm`` (the guess is the caller's start) a handle whose start already satisfies
    its optimality conditions is taken as it is, without a solve.
    """
    if not prob.free.size:
        return []
    tol = settings.tol

    def run(j: int) -> _HandleResult:
        if warm:  # a drag leaves the handles far from what moved as they were
            x = np.clip(guess[:, j], 0.0, 1.0)
            if _already_solved(prob, j, x, tol):
                return _HandleResult(x, True, 0, 0)
        return _solve_handle(prob, j, guess[:, j] <= tol, guess[:, j] >= 1.0 - tol, tol, steps)

    k = guess.shape[1]
    if settings.workers is not None and settings.workers > 1:
        with ThreadPoolExecutor(settings.workers) as pool:
            return list(pool.map(run, range(k)))
    return [run(j) for j in range(k)]


def _level_weights(level: _Level, prob: _Problem, values: FloatArray, results: list[_HandleResult]) -> FloatArray:
    """A level's weights at every vertex: ``values`` at the constrained ones, the solved ones clipped to ``[0, 1]``."""
    w = np.empty((level.vertices.shape[0], values.shape[1]))
    w[level.b] = values
    for j, res in enumerate(results):
        w[prob.free, j] = np.clip(res.x, 0.0, 1.0)
    return w
