"""The Laplacian energy of Sec. 3.2 on a triangle mesh: the cotangent Laplacian, the mass matrix, the bilaplacian.

``1/2 wᵀ Q w`` with ``Q = L M⁻¹ L`` approximates ``1/2 ∫ (Δw)²``, the energy the bounded
biharmonic weights minimise (:mod:`.bbw`; :mod:`._cvxpy` and :mod:`._igl` solve the same
problem as references). Also the checks of a mesh and of boundary conditions all three share.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._lazy import lazy

if TYPE_CHECKING:
    import scipy.sparse as sp
else:
    sp = lazy("scipy.sparse")

__all__ = ["DEGENERATE_AREA", "as_constraints", "as_mesh", "bilaplacian", "checked_bilaplacian", "cotangent_laplacian", "mass_matrix"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

#: A triangle whose doubled area is below this fraction of its longest edge squared is degenerate.
DEGENERATE_AREA = 1e-12


# --- validation ----------------------------------------------------------------------
def as_mesh(V: ArrayLike, F: ArrayLike) -> tuple[FloatArray, IntArray]:
    """Check a triangle mesh; returns ``V`` as C-contiguous float64 and ``F`` as C-contiguous int64."""
    v = np.ascontiguousarray(V, dtype=np.float64)
    if v.ndim != 2 or v.shape[1] != 3 or v.shape[0] < 3:
        raise ValueError(f"V must be an (n, 3) array of vertex positions with n >= 3, got shape {v.shape}")
    if not np.all(np.isfinite(v)):
        raise ValueError("V must be finite (found NaN or inf)")
    f = np.asarray(F)
    if f.ndim != 2 or f.shape[1] != 3 or f.shape[0] < 1:
        raise ValueError(f"F must be an (m, 3) array of triangles with m >= 1, got shape {f.shape}")
    if not np.issubdtype(f.dtype, np.integer):
        raise ValueError(f"F must hold integer vertex indices, got dtype {f.dtype}")
    n = v.shape[0]
    if f.min() < 0 or f.max() >= n:
        raise ValueError(f"F refers to vertices outside 0..{n - 1} (found {f.min()}..{f.max()})")
    f = np.ascontiguousarray(f, dtype=np.int64)
    bad = (f[:, 0] == f[:, 1]) | (f[:, 1] == f[:, 2]) | (f[:, 2] == f[:, 0])
    if bad.any():
        raise ValueError(f"face {int(np.flatnonzero(bad)[0])} repeats a vertex: {f[bad][0].tolist()}")
    used = np.zeros(n, dtype=bool)
    used[f.ravel()] = True
    if not used.all():
        raise ValueError(f"vertex {int(np.flatnonzero(~used)[0])} belongs to no face ({int((~used).sum())} unreferenced vertices)")
    e = [v[f[:, (i + 2) % 3]] - v[f[:, (i + 1) % 3]] for i in range(3)]
    dbl_area = np.linalg.norm(np.cross(e[0], e[1]), axis=1)
    longest = np.max([np.einsum("ij,ij->i", x, x) for x in e], axis=0)
    degenerate = dbl_area <= DEGENERATE_AREA * longest
    if degenerate.any():
        i = int(np.flatnonzero(degenerate)[0])
        raise ValueError(f"face {i} {f[i].tolist()} is degenerate (zero area); {int(degenerate.sum())} such faces")
    return v, f


def as_constraints(n: int, b: ArrayLike, bc: ArrayLike) -> tuple[IntArray, FloatArray]:
    """Check the constrained vertices ``b`` and their values ``bc`` (shape ``(len(b), k)``)."""
    idx = np.asarray(b)
    if idx.ndim != 1 or idx.size == 0:
        raise ValueError(f"b must be a non-empty 1-D array of vertex indices, got shape {idx.shape}")
    if not np.issubdtype(idx.dtype, np.integer):
        raise ValueError(f"b must hold integer vertex indices, got dtype {idx.dtype}")
    idx = idx.astype(np.int64)
    if idx.min() < 0 or idx.max() >= n:
        raise ValueError(f"b refers to vertices outside 0..{n - 1} (found {idx.min()}..{idx.max()})")
    if np.unique(idx).size != idx.size:
        raise ValueError("b must not repeat a vertex")
    values = np.asarray(bc, dtype=np.float64)
    if values.ndim != 2 or values.shape[0] != idx.size or values.shape[1] < 1:
        raise ValueError(f"bc must have shape (len(b), k) = ({idx.size}, k) with k >= 1, got {values.shape}")
    if not np.all(np.isfinite(values)):
        raise ValueError("bc must be finite (found NaN or inf)")
    if values.min() < 0.0 or values.max() > 1.0:
        raise ValueError(f"bc must lie in [0, 1] like the weights, found values in [{values.min():g}, {values.max():g}]")
    return idx, np.ascontiguousarray(values)


# --- discrete operators --------------------------------------------------------------
def _corner_cotangents(v: FloatArray, f: IntArray) -> tuple[FloatArray, FloatArray]:
    """Cotangent of each face corner, shape (m, 3), and the doubled face areas, shape (m,)."""
    p = [v[f[:, i]] for i in range(3)]
    dbl_area = np.linalg.norm(np.cross(p[1] - p[0], p[2] - p[0]), axis=1)
    cot = np.empty((f.shape[0], 3))
    for i in range(3):
        a = p[(i + 1) % 3] - p[i]
        c = p[(i + 2) % 3] - p[i]
        cot[:, i] = np.einsum("ij,ij->i", a, c) / dbl_area
    return cot, dbl_area


def cotangent_laplacian(V: ArrayLike, F: ArrayLike) -> sp.csr_matrix:
    """The cotangent Laplacian, libigl's ``cotmatrix`` (negative semi-definite).

    Parameters
    ----------
    V : array_like, shape (n, 3), float64
        Vertex positions.
    F : array_like, shape (m, 3), int64
        Triangles, indices into ``V``.

    Returns
    -------
    L : scipy.sparse.csr_matrix, shape (n, n), float64
        ``L[i, j] = (cot a_ij + cot b_ij) / 2`` for an edge ``ij`` with opposite angles
        ``a_ij, b_ij`` (one angle on a boundary edge) and ``L[i, i] = -sum_j L[i, j]``.
        Symmetric, rows sum to zero (constants are in the kernel) and
        ``x^T L x = -1/2 sum_ij L_ij (x_i - x_j)^2 <= 0`` when all cotangent weights are
        positive: the sign convention of libigl, where ``-L`` is the stiffness matrix and
        ``M^-1 L`` approximates the Laplace-Beltrami operator.

    Raises
    ------
    ValueError
        If the mesh is malformed (shapes, indices, degenerate or unused vertices).
    """
    v, f = as_mesh(V, F)
    return _laplacian(v, f)


def _laplacian(v: FloatArray, f: IntArray) -> sp.csr_matrix:
    n = v.shape[0]
    cot, _ = _corner_cotangents(v, f)
    rows = np.concatenate([f[:, 1], f[:, 2], f[:, 2], f[:, 0], f[:, 0], f[:, 1]])
    cols = np.concatenate([f[:, 2], f[:, 1], f[:, 0], f[:, 2], f[:, 1], f[:, 0]])
    vals = 0.5 * np.concatenate([cot[:, 0], cot[:, 0], cot[:, 1], cot[:, 1], cot[:, 2], cot[:, 2]])
    off = sp.csr_matrix((vals, (rows, cols)), shape=(n, n))  # duplicates are summed
    return (off - sp.diags(np.asarray(off.sum(axis=1)).ravel())).tocsr()


def mass_matrix(V: ArrayLike, F: ArrayLike, kind: str = "voronoi") -> sp.csr_matrix:
    """The lumped (diagonal) mass matrix: the area each vertex stands for.

    Parameters
    ----------
    V : array_like, shape (n, 3), float64
        Vertex positions.
    F : array_like, shape (m, 3), int64
        Triangles, indices into ``V``.
    kind : {"voronoi", "barycentric"}
        ``"voronoi"`` (default, what libigl's ``massmatrix`` uses for triangles with
        ``MASSMATRIX_TYPE_DEFAULT`` and therefore what its ``bbw`` uses): the mixed Voronoi
        area of Meyer et al. 2003; a non-obtuse triangle gives corner ``i`` its circumcentric
        Voronoi part ``(|e_ij|^2 cot C_k + |e_ik|^2 cot C_j) / 8``, an obtuse one gives half
        its area to the obtuse corner and a quarter to each other corner.
        ``"barycentric"``: a third of each triangle's area to each of its corners.

    Returns
    -------
    M : scipy.sparse.csr_matrix, shape (n, n), float64
        Diagonal, positive; its trace is the surface area (``4 pi`` up to the discretisation
        error for a fine mesh of the unit sphere).
    """
    v, f = as_mesh(V, F)
    if kind not in ("voronoi", "barycentric"):
        raise ValueError(f"kind must be 'voronoi' or 'barycentric', got {kind!r}")
    return sp.diags(_vertex_areas(v, f, kind), format="csr")


def _vertex_areas(v: FloatArray, f: IntArray, kind: str = "voronoi") -> FloatArray:
    n = v.shape[0]
    cot, dbl_area = _corner_cotangents(v, f)
    if kind == "barycentric":
        corner = np.repeat(dbl_area[:, None] / 6.0, 3, axis=1)
    else:
        sq = np.stack(
            [np.einsum("ij,ij->i", d, d) for d in (v[f[:, 2]] - v[f[:, 1]], v[f[:, 0]] - v[f[:, 2]], v[f[:, 1]] - v[f[:, 0]])], axis=1
        )
        # sq[:, i] is the squared length of the edge opposite corner i
        corner = np.empty_like(cot)
        for i in range(3):
            j, k = (i + 1) % 3, (i + 2) % 3
            corner[:, i] = (sq[:, k] * cot[:, k] + sq[:, j] * cot[:, j]) / 8.0
        obtuse = cot < 0
        any_obtuse = obtuse.any(axis=1)
        quarter = dbl_area[any_obtuse, None] / 8.0  # a quarter of the area
        corner[any_obtuse] = np.where(obtuse[any_obtuse], 2.0 * quarter, quarter)
    # float64 already (the weights'); numpy's stub types every bincount as intp
    return np.asarray(np.bincount(f.ravel(), weights=corner.ravel(), minlength=n), dtype=np.float64)


def bilaplacian(V: ArrayLike, F: ArrayLike) -> sp.csr_matrix:
    """The bilaplacian ``Q = L M^-1 L`` of the Laplacian energy (libigl's ``harmonic(V, F, 2, Q)``).

    Parameters
    ----------
    V : array_like, shape (n, 3), float64
        Vertex positions.
    F : array_like, shape (m, 3), int64
        Triangles, indices into ``V``.

    Returns
    -------
    Q : scipy.sparse.csr_matrix, shape (n, n), float64
        Symmetric positive semi-definite (exactly symmetric), with the constants in its
        kernel; ``1/2 x^T Q x`` approximates ``1/2 int (Delta x)^2``. ``L`` is
        :func:`cotangent_laplacian` and ``M`` the Voronoi :func:`mass_matrix`.
    """
    v, f = as_mesh(V, F)
    return checked_bilaplacian(v, f)


def checked_bilaplacian(v: FloatArray, f: IntArray) -> sp.csr_matrix:
    """:func:`bilaplacian` of a mesh :func:`as_mesh` has checked already (the solver's, without checking it twice)."""
    lap = _laplacian(v, f)
    q = (lap @ sp.diags(1.0 / _vertex_areas(v, f)) @ lap).tocsr()
    q = ((q + q.T) * 0.5).tocsr()  # remove the rounding asymmetry of the product
    q.sort_indices()
    return q
