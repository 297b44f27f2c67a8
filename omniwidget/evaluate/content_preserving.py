"""The content-preserving projection of Carroll, Agrawala and Agarwala (SIGGRAPH 2009), the paper's [10].

The paper's strongest rival (its Fig. 13): instead of blending Möbius maps on the sphere,
[10] optimises a map of the whole viewing sphere to a *plane*. A regular mesh is laid over
the longitude/latitude domain, each vertex ``(i, j)`` at ``(lambda_i, phi_j)`` gets an
unknown output position ``(u_ij, v_ij)``, and the positions minimise a weighted sum of
quadratic energies by sparse linear least squares:

- :func:`conformality_energy` ``E_c``, the discrete Cauchy-Riemann equations of the map
  from the sphere to the plane;
- :func:`smoothness_energy` ``E_s``, the second differences of the map;
- :func:`line_energy` ``E_l``, for each marked line, the distances of its points from a
  straight line: a line of *fixed orientation* (marked horizontal or vertical: its points
  share one output ``v``, or one ``u``) or of *general orientation* (the line's normal is
  held fixed, the linear least squares solved, the normal updated from the solution, and
  again: their alternating scheme).

:func:`content_preserving` builds the mesh, solves it (:func:`solve_mesh`) and renders the
panorama from the solved mesh (:func:`render_mesh`): the output is the solution's bounding
box, every output pixel shows the input where the mesh cell covering it says, and pixels no
cell covers are black (and ``mask`` False): the irregular border of [10]'s results.

Equation numbers: [10]'s text is not available to this project; the section and equation
numbers cited below are as best I remember the paper (Sec. 4, "energy terms", eqs. 3-8;
Sec. 5, "optimization"), and every formula is written out in full, so each can be checked
against the paper directly.

Measuring it beside the paper's method (:meth:`ContentPreservingResult.quality`): the
project's figures assume an equirectangular output, which [10]'s plane is not. The same
quantities are computed on its own output instead, each documented in
:class:`PlaneSummary`: line straightness densely along each marked arc (found in the plane
exactly, through the piecewise-linear mesh map), converted to the pixels-per-degree of an
equirectangular panorama of the same width; conformal distortion per mesh triangle against
the sphere's metric; fold-over by the sign of each triangle's Jacobian; coverage of the
sphere; and the share of the sphere lost when the output is cropped to the largest
axis-aligned rectangle inside its irregular border, as [10] crops its results.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import check_panorama, whole_number
from .._lazy import lazy
from ..document.handles import CageHandle, Handles, LineHandle
from ..raster.warping import ORDERS, PAD, Order, remap_panorama
from ..sphere import coords
from .quality import Summary, straightness

if TYPE_CHECKING:
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla
else:
    sp = lazy("scipy.sparse")
    spla = lazy("scipy.sparse.linalg")

__all__ = [
    "ITERATIONS",
    "STEP",
    "WEIGHTS",
    "ContentPreservingResult",
    "Line",
    "Mesh",
    "MeshSolution",
    "Orientation",
    "PlaneRender",
    "PlaneSummary",
    "Weights",
    "conformality_energy",
    "content_preserving",
    "largest_rectangle",
    "line_energy",
    "render_image",
    "render_mesh",
    "smoothness_energy",
    "solve_mesh",
]

#: Mesh spacing, degrees of longitude and latitude: 121 x 61 vertices over the sphere.
STEP = 3.0
#: Most alternating solves of the general-orientation lines (Sec. 5 of [10]).
ITERATIONS = 25
#: The alternation stops when no line's normal turns by more than this (radians).
ORIENTATION_TOLERANCE = 1e-6
#: Line samples per mesh step along each marked arc.
LINE_SAMPLES_PER_STEP = 4
#: Conformal distortion is summarised within this latitude (degrees), as :func:`omniwidget.evaluate.quality.conformal_distortion` does.
MAX_ABS_LAT = 80.0

#: ``"free"``: a line of general orientation; ``"horizontal"`` / ``"vertical"``: fixed orientation.
Orientation = Literal["free", "horizontal", "vertical"]
_ORIENTATIONS = ("free", "horizontal", "vertical")


@dataclass(frozen=True)
class Weights:
    """The energies' weights: ``E = w_c² E_c + w_s² E_s + w_l² E_l`` (the total energy of [10], Sec. 4.5, eq. 8 as I recall it).

    Attributes
    ----------
    conformality : float
        ``w_c``.
    smoothness : float
        ``w_s``.
    lines : float
        ``w_l``.

    Notes
    -----
    [10] weights the line energy far above the other two, so that marked lines come out
    straight almost as hard constraints, and smoothness below conformality, only to keep
    the scale from changing abruptly next to a line; as I recall their values were of the
    order ``w_c = 1``, ``w_s`` about ten times smaller in effect, and ``w_l`` in the
    thousands, but I cannot check the paper here, and their energies were plain sums over
    their own mesh, so their numbers would not carry over anyway. Here every energy is
    normalised as an integral over the sphere (or along the line), so the weights do not
    depend on the mesh step, and the defaults :data:`WEIGHTS` (1, 0.1, 2000) were chosen
    the same way: conformality first, smoothness a tenth of it (the no-line solution stays
    within a few percent of the conformality-only one away from the poles), and lines
    heavy enough that a marked line comes out within a tenth of a pixel of straight at
    2048 wide (``tests/test_content_preserving.py``) while the solve stays well
    conditioned in double precision.
    """

    conformality: float = 1.0
    smoothness: float = 0.1
    lines: float = 2000.0

    def __post_init__(self) -> None:
        for name in ("conformality", "smoothness", "lines"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating) or not (math.isfinite(value) and value >= 0):
                raise ValueError(f"weight {name} must be a finite number >= 0, got {value!r}")


#: The default weights (see :class:`Weights`).
WEIGHTS = Weights()


# --- the mesh ---------------------------------------------------------------------------


@dataclass(frozen=True)
class Mesh:
    """A regular mesh over the whole longitude/latitude domain, centred on ``center`` (Sec. 4 of [10]).

    Vertex ``(i, j)``, index ``j * n_lon + i``, sits at mesh longitude
    ``mu_i = -180 + i * step`` (input longitude ``center + mu_i``, wrapped) and latitude
    ``phi_j = -90 + j * step``; the mesh is cut at ``center ± 180`` (the left and right
    borders of the output) and its first and last rows are the poles. Each quad
    ``(i, j)-(i+1, j)-(i+1, j+1)-(i, j+1)`` is split along its diagonal into two triangles,
    ``(a, b, c)`` and ``(a, c, d)``; the map is linear on each (piecewise linear), which is
    what the line samples, the renderer and the figures all use.

    Attributes
    ----------
    step : float
        Degrees; ``90 / step`` is a whole number.
    center : float
        Input longitude (degrees) of the mesh's middle column.
    """

    step: float = STEP
    center: float = 0.0

    def __post_init__(self) -> None:
        step = self.step
        if isinstance(step, bool) or not isinstance(step, int | float | np.integer | np.floating) or not 0 < step <= 30:
            raise ValueError(f"step must be a number of degrees in (0, 30], got {step!r}")
        if abs(90.0 / step - round(90.0 / step)) > 1e-9:
            raise ValueError(f"step must divide 90 degrees (so the equator and the middle meridian are mesh lines), got {step!r}")
        if not (isinstance(self.center, int | float | np.integer | np.floating) and math.isfinite(self.center)):
            raise ValueError(f"center must be a finite longitude in degrees, got {self.center!r}")

    @property
    def n_lon(self) -> int:
        """Vertices along a row, ``360 / step + 1`` (both ends of the cut)."""
        return round(360.0 / self.step) + 1

    @property
    def n_lat(self) -> int:
        """Rows, ``180 / step + 1``, pole to pole."""
        return round(180.0 / self.step) + 1

    @property
    def size(self) -> int:
        """Number of vertices."""
        return self.n_lon * self.n_lat

    @property
    def mu(self) -> NDArray[np.float64]:
        """Mesh longitudes (degrees, relative to ``center``), (n_lon,)."""
        return np.asarray(-180.0 + self.step * np.arange(self.n_lon), dtype=np.float64)

    @property
    def phi(self) -> NDArray[np.float64]:
        """Latitudes (degrees), (n_lat,)."""
        return np.asarray(-90.0 + self.step * np.arange(self.n_lat), dtype=np.float64)

    @property
    def centre_vertex(self) -> int:
        """Index of the vertex at mesh longitude 0 on the equator (the gauge's fixed vertex)."""
        return (self.n_lat // 2) * self.n_lon + self.n_lon // 2

    def gauge(self) -> dict[int, tuple[float | None, float | None]]:
        """The default gauge of :func:`solve_mesh`: vertex index to fixed ``(u, v)`` (None: free).

        The equator's two ends (mesh longitudes -180 and 180) at ``u = -pi`` and ``u = pi``,
        and the centre vertex (mesh longitude 0 on the equator) at ``v = 0``: translation
        and scale, with the equator as wide as the plain lon/lat grid's (one output unit
        is a radian of the equator, on average).
        """
        equator = (self.n_lat // 2) * self.n_lon
        return {equator: (-math.pi, None), equator + self.n_lon - 1: (math.pi, None), self.centre_vertex: (None, 0.0)}

    def grid(self) -> NDArray[np.float64]:
        """``[mu, phi]`` of every vertex in degrees, (size, 2): the lon/lat grid itself."""
        mu, phi = np.meshgrid(self.mu, self.phi)
        return np.stack([mu.ravel(), phi.ravel()], axis=1)

    def lonlat(self) -> NDArray[np.float64]:
        """Input ``[lon, lat]`` of every vertex in degrees, (size, 2)."""
        g = self.grid()
        g[:, 0] = coords.wrap_lon(g[:, 0] + self.center)
        return g

    def triangles(self) -> NDArray[np.int64]:
        """Vertex indices of the triangles, (2 (n_lon - 1)(n_lat - 1), 3), counter-clockwise in (mu, phi)."""
        i, j = np.meshgrid(np.arange(self.n_lon - 1), np.arange(self.n_lat - 1))
        a = (j * self.n_lon + i).ravel()
        b, c, d = a + 1, a + 1 + self.n_lon, a + self.n_lon
        return np.concatenate([np.stack([a, b, c], axis=1), np.stack([a, c, d], axis=1)])

    def to_mesh_lon(self, lon: ArrayLike) -> NDArray[np.float64]:
        """Input longitudes (degrees) as mesh longitudes in ``[-180, 180)``."""
        return np.asarray(coords.wrap_lon(np.asarray(lon, dtype=np.float64) - self.center), dtype=np.float64)

    def interpolation(self, mulat: ArrayLike) -> sp.csr_matrix:
        """The piecewise-linear map at points: ``B @ positions`` are their output positions.

        Parameters
        ----------
        mulat : array_like, shape (k, 2)
            ``[mu, phi]`` in degrees (mesh longitude, latitude).

        Returns
        -------
        scipy.sparse.csr_matrix, shape (k, size)
            Each row holds the barycentric coordinates of its point in the triangle holding it.
        """
        p = np.asarray(mulat, dtype=np.float64).reshape(-1, 2)
        x = np.clip((p[:, 0] + 180.0) / self.step, 0.0, self.n_lon - 1.0)
        y = np.clip((p[:, 1] + 90.0) / self.step, 0.0, self.n_lat - 1.0)
        i = np.minimum(np.floor(x), self.n_lon - 2).astype(np.int64)
        j = np.minimum(np.floor(y), self.n_lat - 2).astype(np.int64)
        s, t = x - i, y - j
        a = j * self.n_lon + i
        b, c, d = a + 1, a + 1 + self.n_lon, a + self.n_lon
        lower = s >= t  # triangle (a, b, c): weights 1 - s, s - t, t; else (a, c, d): 1 - t, s, t - s
        cols = np.stack([a, np.where(lower, b, c), np.where(lower, c, d)], axis=1)
        vals = np.stack([np.where(lower, 1 - s, 1 - t), np.where(lower, s - t, s), np.where(lower, t, t - s)], axis=1)
        rows = np.repeat(np.arange(len(p)), 3)
        return sp.csr_matrix((vals.ravel(), (rows, cols.ravel())), shape=(len(p), self.size))


# --- the energies ------------------------------------------------------------------------


def _check_positions(mesh: Mesh, positions: ArrayLike) -> NDArray[np.float64]:
    p = np.asarray(positions, dtype=np.float64)
    if p.shape != (mesh.size, 2) or not np.all(np.isfinite(p)):
        raise ValueError(f"positions must be finite (u, v) for the {mesh.size} vertices, shape ({mesh.size}, 2), got {p.shape}")
    return p


def _salience(mesh: Mesh, salience: ArrayLike | None) -> NDArray[np.float64]:
    """Per-vertex salience (n_lat, n_lon): 1 everywhere by default."""
    if salience is None:
        return np.ones((mesh.n_lat, mesh.n_lon))
    s = np.asarray(salience, dtype=np.float64)
    if s.shape != (mesh.n_lat, mesh.n_lon) or not np.all(np.isfinite(s)) or np.any(s < 0):
        raise ValueError(f"salience must be finite and >= 0, one per vertex, shape ({mesh.n_lat}, {mesh.n_lon}), got {s.shape}")
    return s


def _conformality_rows(mesh: Mesh, salience: NDArray[np.float64]) -> sp.csr_matrix:
    """Rows ``sqrt(a_ij) r_ij`` of ``E_c``, over the unknowns ``[u, v]`` (2 size columns)."""
    n = mesh.n_lon
    i, j = (g.ravel() for g in np.meshgrid(np.arange(n - 1), np.arange(mesh.n_lat - 1)))
    cos = np.cos(np.radians(mesh.phi))[j]
    weight = np.sqrt(np.maximum(cos, 0.0) * salience[j, i])  # area h² cos(phi) times derivatives ((.)/h)²: sqrt(cos) per difference
    keep = weight > 0
    i, j, cos, weight = i[keep], j[keep], cos[keep], weight[keep]
    k = j * n + i
    east, north = k + 1, k + n
    m, size = len(k), mesh.size
    rows = np.arange(m)
    # r1 = (v[i+1,j] - v[i,j]) + cos(phi_j) (u[i,j+1] - u[i,j]);  r2 = (u[i+1,j] - u[i,j]) - cos(phi_j) (v[i,j+1] - v[i,j])
    r1 = ([rows] * 4, [size + east, size + k, north, k], [weight, -weight, weight * cos, -weight * cos])
    r2 = ([rows + m] * 4, [east, k, size + north, size + k], [weight, -weight, -weight * cos, weight * cos])
    row = np.concatenate([*r1[0], *r2[0]])
    col = np.concatenate([*r1[1], *r2[1]])
    val = np.concatenate([*r1[2], *r2[2]])
    return sp.csr_matrix((val, (row, col)), shape=(2 * m, 2 * size))


def _smoothness_rows(mesh: Mesh, salience: NDArray[np.float64]) -> sp.csr_matrix:
    """Rows of ``E_s``: the three second differences of ``u`` and of ``v`` at each vertex, weighted."""
    n, nl, h = mesh.n_lon, mesh.n_lat, math.radians(mesh.step)
    cos = np.maximum(np.cos(np.radians(mesh.phi)), 0.0)
    stencils = []
    ii, jj = np.meshgrid(np.arange(n), np.arange(nl))
    # (offsets (di, dj), coefficients, which vertices): lambda-lambda, phi-phi, lambda-phi
    for offsets, coefficients, where in (
        (((-1, 0), (0, 0), (1, 0)), (1.0, -2.0, 1.0), (ii >= 1) & (ii <= n - 2)),
        (((0, -1), (0, 0), (0, 1)), (1.0, -2.0, 1.0), (jj >= 1) & (jj <= nl - 2)),
        (((0, 0), (1, 0), (0, 1), (1, 1)), (1.0, -1.0, -1.0, 1.0), (ii <= n - 2) & (jj <= nl - 2)),
    ):
        i, j = ii[where], jj[where]
        weight = np.sqrt(cos[j] * salience[j, i]) / h  # area h² cos(phi), second derivatives (.)/h²
        keep = weight > 0
        i, j, weight = i[keep], j[keep], weight[keep]
        cols = np.stack([(j + dj) * n + (i + di) for di, dj in offsets], axis=1)
        vals = weight[:, None] * np.asarray(coefficients)[None, :]
        stencils.append((cols, vals))
    blocks = []
    for offset in (0, mesh.size):  # u, then v
        for cols, vals in stencils:
            rows = np.repeat(np.arange(len(cols)), cols.shape[1])
            blocks.append(sp.csr_matrix((vals.ravel(), (rows, (cols + offset).ravel())), shape=(len(cols), 2 * mesh.size)))
    return sp.vstack(blocks).tocsr()


def conformality_energy(mesh: Mesh, positions: ArrayLike, salience: ArrayLike | None = None) -> float:
    """[10]'s conformality energy ``E_c`` (Sec. 4.1, eqs. 3-4 as I recall them) of vertex positions.

    The map ``(lambda, phi) -> (u, v)`` from the sphere to the plane is conformal where it
    satisfies the Cauchy-Riemann equations in the sphere's metric
    ``ds² = cos²(phi) dlambda² + dphi²``::

        du/dlambda = cos(phi) dv/dphi,    dv/dlambda = -cos(phi) du/dphi.

    [10] writes them with forward differences at each vertex ``(i, j)`` (``i`` along
    longitude, ``j`` along latitude), and so does this::

        r1_ij = (v[i+1,j] - v[i,j]) + cos(phi_j) (u[i,j+1] - u[i,j])
        r2_ij = (u[i+1,j] - u[i,j]) - cos(phi_j) (v[i,j+1] - v[i,j])

    summed over the vertices with both neighbours, each weighted by its cell's area on the
    sphere (``h² cos(phi_j)``, with ``h`` the step in radians) and its salience, and the
    differences divided by ``h`` so the sum is an integral that does not depend on the mesh::

        E_c = sum_ij s_ij cos(phi_j) (r1_ij² + r2_ij²).

    Parameters
    ----------
    mesh : Mesh
    positions : array_like, shape (size, 2)
        ``(u, v)`` per vertex, ``v`` up.
    salience : array_like, shape (n_lat, n_lon), optional
        ``s_ij >= 0`` (1 by default: the area alone).

    Returns
    -------
    float
        0 for a conformal map, in units of ``(output units / radian)²`` times steradians.
    """
    p = _check_positions(mesh, positions)
    r = _conformality_rows(mesh, _salience(mesh, salience)) @ np.concatenate([p[:, 0], p[:, 1]])
    return float(r @ r)


def smoothness_energy(mesh: Mesh, positions: ArrayLike, salience: ArrayLike | None = None) -> float:
    """[10]'s smoothness energy ``E_s`` (Sec. 4.3, eq. 7 as I recall it): the map's second differences.

    For ``x`` each of ``u`` and ``v``, at every vertex where the stencil fits::

        x[i-1,j] - 2 x[i,j] + x[i+1,j],   x[i,j-1] - 2 x[i,j] + x[i,j+1],
        x[i+1,j+1] - x[i+1,j] - x[i,j+1] + x[i,j],

    each squared, divided by ``h⁴`` (second derivatives) and weighted by the cell's area on
    the sphere ``h² cos(phi_j)`` and the salience: ``E_s = sum s_ij cos(phi_j) d² / h²``.
    Zero exactly for maps affine in ``(lambda, phi)``, the plain lon/lat grid among them.

    Parameters
    ----------
    mesh : Mesh
    positions : array_like, shape (size, 2)
    salience : array_like, shape (n_lat, n_lon), optional

    Returns
    -------
    float
    """
    p = _check_positions(mesh, positions)
    r = _smoothness_rows(mesh, _salience(mesh, salience)) @ np.concatenate([p[:, 0], p[:, 1]])
    return float(r @ r)


@dataclass(frozen=True)
class Line:
    """One marked line as [10]'s line energy sees it: samples along its arc, in mesh coordinates.

    Attributes
    ----------
    mulat : ndarray of float64, shape (k, 2)
        ``[mu, phi]`` (degrees) of the samples, in order, none across the mesh's cut.
    ds : ndarray of float64, shape (k,)
        Arc length each sample stands for, radians (trapezoid weights; they sum to the
        piece's length).
    orientation : {"free", "horizontal", "vertical"}
    handle : int
        Index of the line handle it comes from.
    """

    mulat: NDArray[np.float64] = field(repr=False)
    ds: NDArray[np.float64] = field(repr=False)
    orientation: Orientation
    handle: int


def _normal(orientation: str) -> NDArray[np.float64] | None:
    """The fixed normal of a fixed-orientation line: horizontal lines share ``v``, vertical ones ``u``."""
    return {"horizontal": np.array([0.0, 1.0]), "vertical": np.array([1.0, 0.0])}.get(orientation)


def _fit_normal(points: NDArray[np.float64], ds: NDArray[np.float64]) -> tuple[NDArray[np.float64], float]:
    """The normal and offset of the straight line nearest weighted points (least squares): the smallest principal axis."""
    w = ds / ds.sum()
    mean = w @ points
    centred = points - mean
    cov = (centred * w[:, None]).T @ centred
    normal = np.linalg.eigh(cov)[1][:, 0]
    return normal, float(normal @ mean)


def line_energy(mesh: Mesh, positions: ArrayLike, line: Line, normal: ArrayLike | None = None) -> float:
    """[10]'s straight-line energy ``E_l`` of one line (Sec. 4.2, eqs. 5-6 as I recall them).

    With ``p_k`` the output positions of the line's samples (the piecewise-linear map at
    them), ``n`` the line's unit normal and ``d`` its offset::

        E_l = sum_k ds_k (n . p_k - d)²,

    the squared distances of the samples from the line ``n . p = d``, integrated along the
    arc. A *fixed-orientation* line has ``n = (0, 1)`` (horizontal: all samples share one
    ``v``) or ``(1, 0)`` (vertical: one ``u``); a *general* one has a normal of its own,
    which the solver alternates with the positions (:func:`solve_mesh`). ``d`` is always
    the best offset (the weighted mean of ``n . p_k``), so the energy is 0 exactly when
    the samples lie on a line of that normal.

    Parameters
    ----------
    mesh : Mesh
    positions : array_like, shape (size, 2)
    line : Line
    normal : array_like, shape (2,), optional
        For a general line, the normal to use; by default the best one (the line's
        least-squares straight fit), so the figure is the samples' own distance from
        straight. Ignored for a fixed-orientation line.

    Returns
    -------
    float
        In ``output units² x radians``.
    """
    p = _check_positions(mesh, positions)
    points = mesh.interpolation(line.mulat) @ p
    n = _normal(line.orientation)
    if n is None:
        n = _fit_normal(points, line.ds)[0] if normal is None else np.asarray(normal, dtype=np.float64) / np.linalg.norm(normal)
    along = points @ n
    d = float(line.ds @ along / line.ds.sum())
    return float(line.ds @ (along - d) ** 2)


# --- the solve ---------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class MeshSolution:
    """The solved mesh: per-vertex output positions and how the solve went.

    Attributes
    ----------
    mesh : Mesh
    positions : ndarray of float64, shape (size, 2)
        ``(u, v)`` per vertex, ``v`` up, in the gauge of :meth:`Mesh.gauge`.
    lines : tuple of Line
    normals : ndarray of float64, shape (len(lines), 2)
        Each line's unit normal at the end (fixed for fixed-orientation lines).
    iterations : int
        Linear solves of the alternation (1 with no general line).
    energies : dict of str to float
        ``"conformality"``, ``"smoothness"``, ``"lines"``: each energy at the solution,
        weighted (``w² E``).
    """

    mesh: Mesh
    positions: NDArray[np.float64] = field(repr=False)
    lines: tuple[Line, ...]
    normals: NDArray[np.float64] = field(repr=False)
    iterations: int
    energies: dict[str, float]


def solve_mesh(
    mesh: Mesh,
    lines: Sequence[Line] = (),
    weights: Weights = WEIGHTS,
    *,
    salience: ArrayLike | None = None,
    fixed: dict[int, tuple[float | None, float | None]] | None = None,
    iterations: int = ITERATIONS,
) -> MeshSolution:
    """Minimise ``w_c² E_c + w_s² E_s + w_l² sum E_l`` over the vertex positions (Sec. 5 of [10]).

    Every energy is a sum of squares of terms linear in the unknowns (the positions, and
    one offset ``d`` per line) once each general line's normal is fixed, so the minimum is
    the solution of a sparse linear least-squares problem: its normal equations
    ``AᵀA x = Aᵀb`` are solved directly (a sparse LU of the symmetric system,
    ``scipy.sparse.linalg.splu``; after the first solve with lines, conjugate gradients
    preconditioned by the last factor, since the normals only turn a little). The
    energies are invariant to translations of the plane, and 0 for the map taking
    everything to one point, so the gauge (:meth:`Mesh.gauge`) fixes the equator's ends
    at ``u = -pi`` and ``u = pi`` and the centre vertex at ``v = 0``: translation and
    scale. (A scale fixed at one place, such as one edge's length, lets the optimum shrink
    the rest of the sphere towards nothing, the quadratic energies' way of lowering
    themselves.) The turn of the picture is then what the energies choose: a turned
    solution would need a larger scale to keep the equator's ends that far apart in
    ``u``, and costs more.

    General lines (``"free"``) follow [10]'s alternation: a first solve without the line
    energy gives each line's normal (the least-squares fit of its samples there); then
    solve with the normals held, refit each normal to its samples' new positions, and
    again, until no normal turns by more than :data:`ORIENTATION_TOLERANCE` or after
    ``iterations`` solves. Each step cannot raise the energy (both halves minimise it), so
    it converges.

    Parameters
    ----------
    mesh : Mesh
    lines : sequence of Line
    weights : Weights
    salience : array_like, shape (n_lat, n_lon), optional
        Multiplies the area weights of ``E_c`` and ``E_s``, as [10]'s salience does.
    fixed : dict of int to (float or None, float or None), optional
        Vertex index to fixed ``(u, v)`` (None leaves that coordinate free): replaces the
        default gauge, :meth:`Mesh.gauge`.
    iterations : int
        At most this many linear solves, ``>= 1``.

    Returns
    -------
    MeshSolution

    Raises
    ------
    ValueError
        For bad arguments, or a singular system (a gauge that leaves the map free).
    """
    if not isinstance(mesh, Mesh):
        raise TypeError(f"mesh must be a Mesh, got {type(mesh).__name__}")
    if not isinstance(weights, Weights):
        raise TypeError(f"weights must be a Weights, got {type(weights).__name__}")
    iterations = whole_number(iterations, "iterations", 1)
    lines = tuple(lines)
    system = _System(mesh, lines, weights, salience, mesh.gauge() if fixed is None else fixed)
    normals = np.array([_normal(line.orientation) if line.orientation != "free" else (np.nan, np.nan) for line in lines]).reshape(-1, 2)
    general = [k for k, line in enumerate(lines) if line.orientation == "free"]
    solves = 0
    if general:  # the first normals: from the solve without the general lines
        held = [k for k in range(len(lines)) if k not in general]
        x = system.solve(sp.vstack([system.base, system.line_rows(normals)[_rows_of(lines, held)]]).tocsr() if held else system.base)
        solves += 1
        for k, n in zip(general, system.fitted_normals(general, x), strict=True):
            normals[k] = n
    x = system.solve(sp.vstack([system.base, system.line_rows(normals)]).tocsr())
    solves += 1
    while general and solves < iterations:
        if _turn_normals(normals, general, system.fitted_normals(general, x)) <= ORIENTATION_TOLERANCE:
            break
        x = system.solve(sp.vstack([system.base, system.line_rows(normals)]).tocsr(), reuse=True)
        solves += 1
    positions = system.positions(x)
    energies = {
        "conformality": weights.conformality**2 * conformality_energy(mesh, positions, salience),
        "smoothness": weights.smoothness**2 * smoothness_energy(mesh, positions, salience),
        "lines": weights.lines**2 * sum(line_energy(mesh, positions, line, n) for line, n in zip(lines, normals, strict=True)),
    }
    return MeshSolution(mesh, positions, lines, normals, solves, energies)


def _known_values(
    size: int, count: int, fixed: dict[int, tuple[float | None, float | None]]
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """The unknowns' fixed values (0 where free) and which are free: ``u`` per vertex, ``v`` per vertex, one offset per line."""
    known = np.full(2 * size + count, np.nan)
    for vertex, (u, v) in fixed.items():
        if not (isinstance(vertex, int | np.integer) and 0 <= vertex < size):
            raise ValueError(f"fixed vertices must be indices of the mesh's {size} vertices, got {vertex!r}")
        if u is not None:
            known[vertex] = u
        if v is not None:
            known[size + vertex] = v
    free = np.isnan(known)
    known[free] = 0.0
    return known, free


def _turn_normals(normals: NDArray[np.float64], general: Sequence[int], fitted: Sequence[NDArray[np.float64]]) -> float:
    """Set the general lines' normals to their refits, each signed like the last; the largest turn, radians."""
    turned = 0.0
    for k, n in zip(general, fitted, strict=True):
        n = n if n @ normals[k] >= 0 else -n
        turned = max(turned, float(np.arccos(np.clip(n @ normals[k], -1.0, 1.0))))
        normals[k] = n
    return turned


class _System:
    """:func:`solve_mesh`'s least-squares system: the energies' rows, the gauge, and the last factorisation.

    The unknowns are ``u`` per vertex, ``v`` per vertex and one offset ``d`` per line; the
    rows of ``E_c`` and ``E_s`` (:attr:`base`) stay, the lines' rows change with their normals.
    """

    def __init__(
        self,
        mesh: Mesh,
        lines: tuple[Line, ...],
        weights: Weights,
        salience: ArrayLike | None,
        fixed: dict[int, tuple[float | None, float | None]],
    ) -> None:
        self.size, self.lines, self.weight = mesh.size, lines, weights.lines
        count = len(lines)
        self.known, self.free = _known_values(mesh.size, count, fixed)
        s = _salience(mesh, salience)
        base = sp.vstack([weights.conformality * _conformality_rows(mesh, s), weights.smoothness * _smoothness_rows(mesh, s)]).tocsr()
        self.base = sp.hstack([base, sp.csr_matrix((base.shape[0], count))]).tocsr()
        self.interpolations = [mesh.interpolation(line.mulat) for line in lines]
        self.factor: list[Any] = []  # the last factorisation, and the solution it gave

    def positions(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """The vertices' ``(u, v)`` in a solution ``x``, shape (size, 2)."""
        return np.stack([x[: self.size], x[self.size : 2 * self.size]], axis=1)

    def fitted_normals(self, which: Sequence[int], x: NDArray[np.float64]) -> list[NDArray[np.float64]]:
        """Lines ``which``'s normals fitted to their samples' positions in ``x`` (unsigned)."""
        positions = self.positions(x)
        return [_fit_normal(self.interpolations[k] @ positions, self.lines[k].ds)[0] for k in which]

    def line_rows(self, normals: NDArray[np.float64]) -> sp.csr_matrix:
        """Every line's rows of ``E_l`` with its normal held: ``sqrt(w_l² ds) (n · p - d)`` per sample."""
        count = len(self.lines)
        blocks = []
        for index, (line, b, n) in enumerate(zip(self.lines, self.interpolations, normals, strict=True)):
            root = self.weight * np.sqrt(line.ds)
            rows = sp.diags(root) @ sp.hstack([n[0] * b, n[1] * b]).tocsr()
            offset = sp.csr_matrix((-root, (np.arange(len(root)), np.full(len(root), index))), shape=(len(root), count))
            blocks.append(sp.hstack([rows, offset]))
        return sp.vstack(blocks).tocsr() if blocks else sp.csr_matrix((0, 2 * self.size + count))

    def solve(self, a: sp.csr_matrix, reuse: bool = False) -> NDArray[np.float64]:
        """The least-squares solution of the rows ``a`` with the known unknowns held, every unknown (``known`` where fixed)."""
        free, known = self.free, self.known
        active = free & (a.getnnz(axis=0) > 0)  # the offsets of lines not in this solve stay 0
        a_free, a_known = a[:, active], a[:, ~free]
        rhs = a_free.T @ -(a_known @ known[~free])
        lhs = (a_free.T @ a_free).tocsc()
        x = self._preconditioned(lhs, rhs) if reuse else None
        if x is None:
            x = self._factored(lhs, rhs)
        if not np.all(np.isfinite(x)):
            raise ValueError(_SINGULAR)
        self.factor[1] = x
        out = known.copy()
        out[active] = x
        return out

    def _preconditioned(self, lhs: sp.csc_matrix, rhs: NDArray[np.float64]) -> NDArray[np.float64] | None:
        """Conjugate gradients preconditioned by the last factor (the normals turned a little), or None if that fails."""
        if not (self.factor and self.factor[1].shape == (lhs.shape[0],)):
            return None
        lu, guess = self.factor
        x, info = spla.cg(lhs, rhs, x0=guess, rtol=1e-13, atol=0.0, maxiter=60, M=spla.LinearOperator(lhs.shape, lu.solve))
        return x if info == 0 else None

    def _factored(self, lhs: sp.csc_matrix, rhs: NDArray[np.float64]) -> NDArray[np.float64]:
        """The normal equations solved by a fresh sparse LU (kept for the next solve)."""
        try:
            lu = spla.splu(lhs, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
        except RuntimeError:
            raise ValueError(_SINGULAR) from None
        x = lu.solve(rhs)
        if not (np.all(np.isfinite(x)) and float(np.linalg.norm(lhs @ x - rhs)) <= 1e-6 * max(float(np.linalg.norm(rhs)), 1e-300)):
            raise ValueError(_SINGULAR)
        self.factor[:] = [lu, x]
        return x


_SINGULAR = "the mesh's system is singular: the gauge leaves the map free (fix more vertices)"


def _rows_of(lines: Sequence[Line], which: Sequence[int]) -> NDArray[np.int64]:
    """Row indices of some lines' samples in :func:`solve_mesh`'s stacked line rows."""
    starts = np.concatenate([[0], np.cumsum([len(line.ds) for line in lines])])
    return np.concatenate([np.arange(starts[k], starts[k + 1]) for k in which]).astype(np.int64)


# --- the render -------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class PlaneRender:
    """Where each output pixel lies in the solved mesh (:func:`render_mesh`).

    Output pixel ``(x, y)`` (column, row; integers are pixel centres) is the plane point
    ``u = uc + (x + 0.5 - width / 2) / scale``, ``v = vc - (y + 0.5 - height / 2) / scale``.

    Attributes
    ----------
    width, height : int
    scale : float
        Output pixels per plane unit.
    centre : (float, float)
        ``(uc, vc)``, the middle of the solution's bounding box.
    triangle : ndarray of int64, shape (height, width)
        The mesh triangle covering each pixel; -1 where none does.
    barycentric : ndarray of float64, shape (height, width, 3)
        The pixel's barycentric coordinates in it (NaN where none).
    """

    width: int
    height: int
    scale: float
    centre: tuple[float, float]
    triangle: NDArray[np.int64] = field(repr=False)
    barycentric: NDArray[np.float64] = field(repr=False)

    @property
    def mask(self) -> NDArray[np.bool_]:
        """Pixels some triangle covers, (height, width)."""
        return self.triangle >= 0

    def to_pixels(self, uv: ArrayLike) -> NDArray[np.float64]:
        """Plane positions ``(u, v)`` (..., 2) as output pixel coordinates ``(x, y)``."""
        p = np.asarray(uv, dtype=np.float64)
        x = (p[..., 0] - self.centre[0]) * self.scale + self.width / 2 - 0.5
        y = (self.centre[1] - p[..., 1]) * self.scale + self.height / 2 - 0.5
        return np.stack([x, y], axis=-1)


#: Candidate pixels tested at once by the rasteriser (memory: about 100 bytes each).
_RASTER_CHUNK = 4_000_000


def render_mesh(mesh: Mesh, positions: ArrayLike, width: int) -> PlaneRender:
    """Rasterise the solved mesh: for every output pixel, the triangle covering it and where in it.

    The output is the bounding box of the vertex positions, ``width`` pixels wide and as
    high as keeps pixels square. Each triangle's pixel centres are found in its bounding
    box and kept if their barycentric coordinates are all ``>= -1e-9`` (a vectorised scan,
    a few million candidates at a time); where triangles overlap (a fold-over) the one of
    highest index is kept. No point location structure is needed: the mesh is regular.

    Parameters
    ----------
    mesh : Mesh
    positions : array_like, shape (size, 2)
        ``(u, v)`` per vertex, ``v`` up.
    width : int
        Output width, pixels, ``>= 2``.

    Returns
    -------
    PlaneRender
    """
    p = _check_positions(mesh, positions)
    width = whole_number(width, "width", 2)
    lo, hi = p.min(axis=0), p.max(axis=0)
    extent = hi - lo
    if not extent[0] > 0:
        raise ValueError("the solution has no width: every vertex has the same u")
    scale = width / extent[0]
    height = max(1, round(extent[1] * scale))
    render = PlaneRender(width, height, float(scale), (float((lo[0] + hi[0]) / 2), float((lo[1] + hi[1]) / 2)),
                         np.full((height, width), -1, dtype=np.int64), np.full((height, width, 3), np.nan))  # fmt: skip
    tris = mesh.triangles()
    corners = render.to_pixels(p)[tris]  # (T, 3, 2)
    e1, e2 = corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]
    det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    x0 = np.clip(np.ceil(corners[..., 0].min(axis=1) - 1e-9), 0, width).astype(np.int64)
    x1 = np.clip(np.floor(corners[..., 0].max(axis=1) + 1e-9), -1, width - 1).astype(np.int64)
    y0 = np.clip(np.ceil(corners[..., 1].min(axis=1) - 1e-9), 0, height).astype(np.int64)
    y1 = np.clip(np.floor(corners[..., 1].max(axis=1) + 1e-9), -1, height - 1).astype(np.int64)
    nx, ny = np.maximum(x1 - x0 + 1, 0), np.maximum(y1 - y0 + 1, 0)
    counts = np.where(np.abs(det) > 1e-12, nx * ny, 0)
    order = np.flatnonzero(counts)
    cumulative = np.cumsum(counts[order])
    start = 0
    while start < len(order):
        stop = int(np.searchsorted(cumulative, (cumulative[start - 1] if start else 0) + _RASTER_CHUNK, side="right"))
        stop = max(stop, start + 1)
        chunk = order[start:stop]
        n = counts[chunk]
        tri = np.repeat(chunk, n)
        local = np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n)
        px = x0[tri] + local % nx[tri]
        py = y0[tri] + local // nx[tri]
        dx, dy = px - corners[tri, 0, 0], py - corners[tri, 0, 1]
        b1 = (dx * e2[tri, 1] - dy * e2[tri, 0]) / det[tri]
        b2 = (e1[tri, 0] * dy - e1[tri, 1] * dx) / det[tri]
        b0 = 1.0 - b1 - b2
        inside = (b0 >= -1e-9) & (b1 >= -1e-9) & (b2 >= -1e-9)
        px, py, tri = px[inside], py[inside], tri[inside]
        render.triangle[py, px] = tri
        render.barycentric[py, px] = np.stack([b0[inside], b1[inside], b2[inside]], axis=1)
        start = stop
    return render


# --- the result --------------------------------------------------------------------------


@dataclass(frozen=True)
class PlaneSummary(Summary):
    """:class:`~omniwidget.evaluate.quality.Summary` of [10]'s plane output, each figure measured on its own output.

    The fields mean what they mean in ``Summary``, measured as follows (``W`` is the
    output's width):

    - ``lines``: each marked line's arc is sampled at least twice per output pixel of its
      image and every sample found in the plane exactly (the piecewise-linear mesh map);
      the figure is the minimum-zone straightness of the samples in output pixels
      (:func:`~omniwidget.evaluate.quality.straightness`, ``fit="best"``), divided by the
      line's own scale in the output (pixels per degree of arc: its output length over its
      arc length) and multiplied by ``W / 360``: the bend in pixels of an equirectangular
      panorama ``W`` wide, where the paper's method is measured. ``lines_output_px`` has
      the unconverted figures. A line the mesh's cut crosses is measured in its parts, each
      straight on its own, and its figure is the worst part's.
    - ``distortion_mean``, ``distortion_p99``: ``sigma_max / sigma_min - 1`` of each
      triangle's Jacobian against the sphere's metric (derivatives by east and north arc
      at the triangle's centroid latitude), weighted by the triangle's area on the sphere,
      over the triangles whose centroid lies within ±80° of latitude (as
      :func:`~omniwidget.evaluate.quality.conformal_distortion` is summarised). The ratio is
      the same for a map and its inverse, so this compares with the paper's figure, which
      differentiates the inverse map.
    - ``fold_over``: share of the sphere's area in triangles whose Jacobian determinant is
      ``<= 0``.
    - ``coverage``: share of the sphere's area in triangles of non-zero image (every
      triangle but degenerate ones: [10]'s output shows the whole sphere).
    - ``tear``: the largest second difference of the inverse map (as unit vectors) along
      the rows and columns of covered output pixels, in degrees times ``W / 360``, as
      :func:`~omniwidget.evaluate.quality.tear` (the mesh map is continuous: small).
    - ``displacement``: NaN (a plane keeps no place of the sphere); ``cage_motion``: NaN
      with a fixed cage ([10] has no cages), None without; ``far``: None.

    Attributes
    ----------
    cropped_loss : float
        Share of the sphere's area lost when the output is cropped to the largest
        axis-aligned rectangle inside its covered pixels (:func:`largest_rectangle`), as
        [10] crops its results: 1 minus the sphere area the rectangle's pixels show.
    lines_output_px : tuple of float
        The lines' straightness in the plane's own output pixels.
    crop : (int, int, int, int)
        The rectangle: first row, first column, rows, columns.
    """

    cropped_loss: float = math.nan
    lines_output_px: tuple[float, ...] = ()
    crop: tuple[int, int, int, int] = (0, 0, 0, 0)


@dataclass(frozen=True, eq=False)
class ContentPreservingResult:
    """[10]'s projection of one panorama: the solved mesh, the rendered plane and its figures.

    Attributes
    ----------
    image : ndarray, shape (height, width[, C])
        The output plane, in the input's dtype; black where ``mask`` is False.
    mask : ndarray of bool, shape (height, width)
        Pixels the mesh covers: its irregular border.
    solution : MeshSolution
    render : PlaneRender
    handles : Handles
    source_width : int
    timings : dict of str to float
        Seconds: ``"mesh"``, ``"solve"``, ``"render"``, ``"resampling"``.
    method : str
        ``"content_preserving"``.
    """

    image: NDArray
    mask: NDArray[np.bool_] = field(repr=False)
    solution: MeshSolution = field(repr=False)
    render: PlaneRender = field(repr=False)
    handles: Handles = field(repr=False)
    source_width: int
    timings: dict[str, float]
    method: str = "content_preserving"

    def inverse_map(self, dtype: type[np.floating] = np.float32) -> NDArray[np.floating]:
        """For each output pixel centre, the input ``[lon, lat]`` (degrees) it shows; NaN where no cell covers it.

        Parameters
        ----------
        dtype : {numpy.float32, numpy.float64}

        Returns
        -------
        ndarray, shape (height, width, 2)
            Not on an equirectangular grid: the plane's own pixels.
        """
        if dtype not in (np.float32, np.float64):
            raise ValueError(f"dtype must be numpy.float32 or numpy.float64, got {dtype!r}")
        if "_inverse" not in self.__dict__:
            self.__dict__["_inverse"] = _plane_inverse(self.solution.mesh, self.render)
        return np.asarray(self.__dict__["_inverse"], dtype=dtype)

    def forward_points(self, lonlat: ArrayLike) -> NDArray[np.float64]:
        """Where input positions appear in the output plane: pixel ``(x, y)``, exactly (the piecewise-linear map).

        Parameters
        ----------
        lonlat : array_like, shape (n, 2)
            Input ``[lon, lat]`` in degrees.

        Returns
        -------
        ndarray of float64, shape (n, 2)
            Column and row (integers are pixel centres). A point on the mesh's cut
            (``center ± 180``) is placed on its left border.
        """
        p = np.asarray(lonlat, dtype=np.float64).reshape(-1, 2)
        mesh = self.solution.mesh
        mulat = np.stack([mesh.to_mesh_lon(p[:, 0]), p[:, 1]], axis=1)
        return self.render.to_pixels(mesh.interpolation(mulat) @ self.solution.positions)

    @property
    def quality(self) -> PlaneSummary:
        """The figures of this projection (:class:`PlaneSummary`), measured when first asked."""
        if "_quality" not in self.__dict__:
            self.__dict__["_quality"] = _plane_summary(self)
        quality: PlaneSummary = self.__dict__["_quality"]
        return quality


def _plane_inverse(mesh: Mesh, render: PlaneRender) -> NDArray[np.float64]:
    """``[lon, lat]`` of every output pixel (NaN outside), from its triangle's vertices' lon/lat grid positions."""
    out = np.full((render.height, render.width, 2), np.nan)
    covered = render.mask
    grid = mesh.grid()[mesh.triangles()[render.triangle[covered]]]  # (n, 3, 2) mesh [mu, phi]
    mulat = np.einsum("nk,nkc->nc", render.barycentric[covered], grid)
    out[covered, 0] = coords.wrap_lon(mulat[:, 0] + mesh.center)
    out[covered, 1] = np.clip(mulat[:, 1], -90.0, 90.0)
    out.flags.writeable = False
    return out


def largest_rectangle(mask: ArrayLike) -> tuple[int, int, int, int]:
    """The largest axis-aligned rectangle of True pixels in a mask.

    The classic stack algorithm on the histogram of True runs above each row, ``O(H W)``.

    Parameters
    ----------
    mask : array_like of bool, shape (H, W)

    Returns
    -------
    (int, int, int, int)
        ``(top, left, rows, columns)``; ``(0, 0, 0, 0)`` for a mask with no True pixel.
    """
    m = np.asarray(mask, dtype=bool)
    if m.ndim != 2:
        raise ValueError(f"mask must be 2D, got shape {m.shape}")
    heights = np.zeros(m.shape[1] + 1, dtype=np.int64)
    best = (0, 0, 0, 0)
    best_area = 0
    for row in range(m.shape[0]):
        heights[:-1] = np.where(m[row], heights[:-1] + 1, 0)
        if heights[:-1].max(initial=0) * m.shape[1] <= best_area:
            continue
        stack: list[int] = []
        for col, hgt in enumerate(heights.tolist()):
            while stack and heights[stack[-1]] >= hgt:
                top = stack.pop()
                h_top = int(heights[top])
                left = stack[-1] + 1 if stack else 0
                area = h_top * (col - left)
                if area > best_area:
                    best_area, best = area, (row - h_top + 1, left, h_top, col - left)
            stack.append(col)
    return best


def _triangle_geometry(mesh: Mesh, positions: NDArray[np.float64]) -> dict[str, NDArray[np.float64]]:
    """Per triangle: Jacobian against the sphere's metric, its determinant, sphere area, centroid latitude."""
    tris = mesh.triangles()
    grid = np.radians(mesh.grid())[tris]  # (T, 3, 2) [mu, phi] radians
    uv = positions[tris]
    dg = np.stack([grid[:, 1] - grid[:, 0], grid[:, 2] - grid[:, 0]], axis=2)  # (T, 2, 2): columns are the edges
    du = np.stack([uv[:, 1] - uv[:, 0], uv[:, 2] - uv[:, 0]], axis=2)
    lat = grid[:, :, 1].mean(axis=1)
    g = du @ np.linalg.inv(dg)  # d(u, v) / d(lambda, phi)
    jac = g.copy()
    jac[:, :, 0] /= np.cos(lat)[:, None]  # d / d(east arc) = d / (cos(phi) d lambda)
    det = np.linalg.det(g)
    h = math.radians(mesh.step)
    area = 0.5 * h * h * np.cos(lat)
    return {"jacobian": jac, "det": det, "area": area, "lat": np.degrees(lat), "plane_area": 0.5 * np.abs(det) * h * h}


def _ratio_minus_one(jac: NDArray[np.float64]) -> NDArray[np.float64]:
    """``sigma_max / sigma_min - 1`` of 2 x 2 matrices (..., 2, 2); inf where singular."""
    frob = np.sum(jac**2, axis=(-2, -1))
    det = np.abs(np.linalg.det(jac))
    root = np.sqrt(np.maximum(frob**2 - 4 * det**2, 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        # s_max / s_min = (F + root) / (2 det) = 2 det / (F - root); subtract 1 as (F + root - 2 det) / (2 det)
        return np.asarray((frob + root - 2 * det) / (2 * det), dtype=np.float64)


def _weighted_quantile(values: NDArray[np.float64], weights: NDArray[np.float64], q: float) -> float:
    order = np.argsort(values)
    cumulative = np.cumsum(weights[order])
    return float(values[order][np.searchsorted(cumulative, q * cumulative[-1])])


def _line_pieces(handles: Handles, mesh: Mesh, orientations: Sequence[Orientation], density: float) -> list[Line]:
    """Every rectified line handle as :class:`Line` pieces, sampled ``density`` times per degree, split at the mesh's cut."""
    out: list[Line] = []
    line_index = 0
    for index, handle in enumerate(handles.handles):
        if not isinstance(handle, LineHandle) or not handle.rectify:
            continue
        orientation = orientations[line_index]
        line_index += 1
        length = float(coords.angular_distance(handle.start, handle.end))
        n = max(3, math.ceil(length * density) + 1)
        t = np.linspace(0.0, 1.0, n)
        samples = coords.geodesic(handle.start, handle.end, t)
        mu = mesh.to_mesh_lon(samples[:, 0])
        cuts = np.flatnonzero(np.abs(np.diff(mu)) > 180.0) + 1
        for part in np.split(np.arange(n), cuts):
            if len(part) < 2:
                continue
            ds = np.zeros(len(part))
            step = np.radians(length) / (n - 1)
            ds[:-1] += step / 2
            ds[1:] += step / 2
            out.append(Line(np.stack([mu[part], samples[part, 1]], axis=1), ds, orientation, index))
    return out


def _auto_orientation(handle: LineHandle, tolerance: float = 1.0) -> Orientation:
    """``"vertical"`` for a line along a meridian (its great circle within ``tolerance`` degrees of the poles), else ``"free"``."""
    a, b = coords.lonlat_to_xyz(np.array([handle.start, handle.end], dtype=np.float64))
    normal = np.cross(a, b)
    size = float(np.linalg.norm(normal))
    if size < 1e-12:
        return "free"
    return "vertical" if abs(normal[2] / size) < math.sin(math.radians(tolerance)) else "free"


def _auto_center(handles: Handles) -> float:
    """The mesh's centre longitude: opposite the middle of the widest longitude gap between the lines, so the cut crosses none."""
    lons = []
    for handle in handles.handles:
        if isinstance(handle, LineHandle) and handle.rectify:
            length = float(coords.angular_distance(handle.start, handle.end))
            t = np.linspace(0.0, 1.0, max(3, math.ceil(length * 4) + 1))
            samples = coords.geodesic(handle.start, handle.end, t)
            lons.append(samples[np.abs(samples[:, 1]) < 89.9, 0])
    if not lons or not sum(len(x) for x in lons):
        return 0.0
    values = np.sort(np.mod(np.concatenate(lons), 360.0))
    gaps = np.diff(np.concatenate([values, [values[0] + 360.0]]))
    k = int(np.argmax(gaps))
    seam = values[k] + gaps[k] / 2
    return float(coords.wrap_lon(seam + 180.0))


def content_preserving(  # noqa: PLR0913 - the panorama, its handles and [10]'s documented keyword knobs (the rivals' common call)
    image: NDArray,
    handles: Handles,
    *,
    width: int | None = None,
    order: Order = "bilinear",
    samples: int | None = None,
    step: float = STEP,
    weights: Weights = WEIGHTS,
    orientations: Sequence[Orientation] | Literal["auto", "free"] = "auto",
    center: float | None = None,
    salience: ArrayLike | None = None,
    iterations: int = ITERATIONS,
) -> ContentPreservingResult:
    """Carroll, Agrawala and Agarwala's content-preserving projection of a panorama ([10], the paper's Fig. 13).

    A mesh over the whole longitude/latitude domain (:class:`Mesh`, ``step`` degrees),
    vertex positions in the plane minimising ``w_c² E_c + w_s² E_s + w_l² sum E_l``
    (:func:`conformality_energy`, :func:`smoothness_energy`, :func:`line_energy`, solved by
    :func:`solve_mesh`), and the panorama rendered from the solved mesh
    (:func:`render_mesh`): the output is the solution's bounding box ``width`` pixels wide;
    pixels no mesh cell covers are black (``mask`` False).

    Only line handles take part ([10] has no point handles or cages: those of ``handles``
    are ignored), and only those with ``rectify`` (explicit ``targets`` are ignored: [10]
    asks a line to be straight, not to go somewhere).

    Parameters
    ----------
    image : ndarray, shape (H, W[, C])
        Equirectangular panorama, ``W = 2 H``; uint8, uint16, float32 or float64; 1 to 4 channels.
    handles : Handles
    width : int, optional
        Output width, pixels (default: the input's).
    order : {"nearest", "bilinear", "bicubic"}
    samples : int, optional
        Accepted so :func:`omniwidget.evaluate.baselines.compare` can pass its own; not used
        (the lines are sampled :data:`LINE_SAMPLES_PER_STEP` times per mesh step).
    step : float
        Mesh spacing, degrees, dividing 90 (:data:`STEP`).
    weights : Weights
    orientations : "auto", "free" or sequence of {"free", "horizontal", "vertical"}
        Per rectified line handle, in order: [10]'s fixed-orientation lines
        (``"horizontal"``, ``"vertical"``) or general ones (``"free"``). ``"auto"`` (the
        default) marks a line lying along a meridian (within 1°) vertical, as a person
        marks a vertical edge of a levelled panorama, and the others free.
    center : float, optional
        Input longitude at the middle of the output; by default opposite the widest
        longitude gap between the lines, so the mesh's cut (the output's left and right
        borders) crosses none (0 without lines).
    salience : array_like, shape (n_lat, n_lon), optional
        Per-vertex weights of ``E_c`` and ``E_s`` beside the area (1 by default).
    iterations : int
        At most this many linear solves of the general lines' alternation.

    Returns
    -------
    ContentPreservingResult

    Raises
    ------
    TypeError
        If ``handles`` is not a :class:`Handles`.
    ImageError
        If ``image`` is not a panorama this toolkit reads.
    ValueError
        If an argument is out of range.
    """
    if not isinstance(handles, Handles):
        raise TypeError(f"handles must be a Handles document (see Handles.from_dict), got {type(handles).__name__}")
    check_panorama(image)
    width = whole_number(image.shape[1] if width is None else width, "width", 2)
    if order not in ORDERS:
        raise ValueError(f"order must be one of {', '.join(ORDERS)}, got {order!r}")
    clock = time.perf_counter()
    chosen = _chosen_orientations([h for h in handles.handles if isinstance(h, LineHandle) and h.rectify], orientations)
    mesh = Mesh(step, _auto_center(handles) if center is None else float(center))
    lines = _line_pieces(handles, mesh, chosen, LINE_SAMPLES_PER_STEP / mesh.step)
    timings = {"mesh": time.perf_counter() - clock}
    clock = time.perf_counter()
    solution = solve_mesh(mesh, lines, weights, salience=salience, iterations=iterations)
    timings["solve"] = time.perf_counter() - clock
    out, render, inverse, seconds = render_image(image, mesh, solution.positions, width, order)
    timings.update(seconds)
    result = ContentPreservingResult(out, render.mask, solution, render, handles, image.shape[1], timings)
    result.__dict__["_inverse"] = inverse
    return result


def _chosen_orientations(
    rectified: Sequence[LineHandle], orientations: Sequence[Orientation] | Literal["auto", "free"]
) -> list[Orientation]:
    """:func:`content_preserving`'s ``orientations``, one per rectified line handle, checked."""
    if isinstance(orientations, str):
        if orientations not in ("auto", "free"):
            raise ValueError(f"orientations must be 'auto', 'free' or one of {_ORIENTATIONS} per line, got {orientations!r}")
        return [_auto_orientation(h) if orientations == "auto" else "free" for h in rectified]
    chosen = list(orientations)
    if len(chosen) != len(rectified) or any(o not in _ORIENTATIONS for o in chosen):
        raise ValueError(
            f"orientations must give one of {', '.join(_ORIENTATIONS)} for each of the {len(rectified)} rectified lines, got {orientations!r}"
        )
    return chosen


def render_image(
    image: NDArray, mesh: Mesh, positions: ArrayLike, width: int, order: Order = "bilinear"
) -> tuple[NDArray, PlaneRender, NDArray[np.float64], dict[str, float]]:
    """The panorama drawn through a mesh's vertex positions: [10]'s output picture.

    Parameters
    ----------
    image : ndarray, shape (H, W[, C])
        Equirectangular panorama.
    mesh : Mesh
    positions : array_like, shape (size, 2)
        ``(u, v)`` per vertex, ``v`` up (for example ``MeshSolution.positions``).
    width : int
        Output width, pixels.
    order : {"nearest", "bilinear", "bicubic"}

    Returns
    -------
    image : ndarray, shape (height, width[, C])
        In the input's dtype; 0 (black) where no triangle covers the pixel.
    render : PlaneRender
        Which triangle covers each pixel (:func:`render_mesh`).
    inverse : ndarray of float64, shape (height, width, 2)
        The input ``[lon, lat]`` (degrees) each pixel shows; NaN where none.
    timings : dict of str to float
        Seconds: ``"render"`` (the rasterisation) and ``"resampling"``.
    """
    check_panorama(image)
    if order not in ORDERS:
        raise ValueError(f"order must be one of {', '.join(ORDERS)}, got {order!r}")
    clock = time.perf_counter()
    render = render_mesh(mesh, positions, width)
    inverse = _plane_inverse(mesh, render)
    timings = {"render": time.perf_counter() - clock}
    clock = time.perf_counter()
    covered = render.mask
    px = coords.lonlat_to_px(np.where(covered[..., None], inverse, 0.0), image.shape[1]) + PAD
    out = remap_panorama(image, px.astype(np.float32), order)
    out[~covered] = 0
    timings["resampling"] = time.perf_counter() - clock
    return out, render, inverse, timings


def _plane_summary(result: ContentPreservingResult) -> PlaneSummary:
    """Every figure of :class:`PlaneSummary`, on the plane's own output."""
    solution, render, mesh = result.solution, result.render, result.solution.mesh
    width = render.width
    geometry = _triangle_geometry(mesh, solution.positions)
    total = float(geometry["area"].sum())

    # lines: densely, exactly through the piecewise-linear map, in equirectangular pixels at this width
    per_handle: dict[int, list[tuple[float, float]]] = {}
    for line in solution.lines:
        coarse = render.to_pixels(mesh.interpolation(line.mulat) @ solution.positions)
        out_length = float(np.sum(np.hypot(*np.diff(coarse, axis=0).T)))
        arc = float(np.degrees(line.ds.sum()))
        n = max(len(line.mulat), 2 * math.ceil(out_length) + 1)
        t = np.linspace(0.0, 1.0, n)
        ends = np.stack([line.mulat[0], line.mulat[-1]])
        ends[:, 0] += mesh.center
        dense = coords.geodesic(ends[0], ends[1], t)
        mulat = np.stack([mesh.to_mesh_lon(dense[:, 0]), dense[:, 1]], axis=1)
        if mulat[0, 0] > 179.0 and line.mulat[0, 0] < -179.0:  # a piece starting on the cut: its left border
            mulat[0, 0] = -180.0
        if mulat[-1, 0] < -179.0 and line.mulat[-1, 0] > 179.0:
            mulat[-1, 0] = 180.0
        pixels = render.to_pixels(mesh.interpolation(mulat) @ solution.positions)
        # straightness() counts lon/lat degrees at width / 360 pixels per degree: at width 360 it takes pixels as they are
        bend = straightness(pixels, 360, fit="best")
        per_degree = out_length / arc if arc > 0 else math.nan
        per_handle.setdefault(line.handle, []).append((bend, bend / per_degree * width / 360.0 if per_degree > 0 else math.nan))
    raw = tuple(max(b for b, _ in parts) for parts in per_handle.values())
    scaled = tuple(max(s for _, s in parts) for parts in per_handle.values())

    within = np.abs(geometry["lat"]) <= MAX_ABS_LAT
    distortion = _ratio_minus_one(geometry["jacobian"])
    good = within & np.isfinite(distortion)
    if good.any():
        mean = float(np.sum(distortion[good] * geometry["area"][good]) / np.sum(geometry["area"][good]))
        p99 = _weighted_quantile(distortion[good], geometry["area"][good], 0.99)
    else:
        mean = p99 = math.nan
    folds = float(np.sum(geometry["area"][geometry["det"] <= 0]) / total)
    coverage = float(np.sum(geometry["area"][geometry["plane_area"] > 0]) / total)

    # the crop: the largest rectangle of covered pixels, and the sphere area its pixels show
    mask = render.mask
    top, left, rows, cols = largest_rectangle(mask)
    covered = render.triangle[top : top + rows, left : left + cols]
    density = geometry["area"] / np.maximum(geometry["plane_area"] * render.scale**2, 1e-300)  # sphere area per output pixel
    shown = float(np.sum(density[covered[covered >= 0]])) / total
    cropped_loss = max(0.0, 1.0 - min(shown, 1.0))

    inverse = result.inverse_map(np.float64)
    xyz = coords.lonlat_to_xyz(np.nan_to_num(inverse))
    xyz[~mask] = np.nan
    along_rows = xyz[:, 2:] - 2 * xyz[:, 1:-1] + xyz[:, :-2]
    along_cols = xyz[2:] - 2 * xyz[1:-1] + xyz[:-2]
    steps = np.concatenate([np.linalg.norm(along_rows, axis=-1).ravel(), np.linalg.norm(along_cols, axis=-1).ravel()])
    steps = steps[np.isfinite(steps)]
    tear = float(np.degrees(steps.max()) * width / 360.0) if len(steps) else math.nan

    fixed_cage = any(isinstance(h, CageHandle) and h.finals == h.vertices for h in result.handles.handles)
    return PlaneSummary(
        method=result.method,
        lines=scaled,
        distortion_mean=mean,
        distortion_p99=p99,
        fold_over=folds,
        tear=tear,
        coverage=coverage,
        displacement=math.nan,
        cage_motion=math.nan if fixed_cage else None,
        seconds=float(sum(result.timings.values())),
        width=width,
        far=None,
        cropped_loss=cropped_loss,
        lines_output_px=raw,
        crop=(top, left, rows, cols),
    )
