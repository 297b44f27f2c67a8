"""No swirl: between the handles, the blend is replaced by the most conformal map that agrees with it around them.

The blend of eq. (2) is exact where one handle's weight is 1 (on its line, inside its cage, on
its point's disk) and the identity where the still background's is; in between it mixes maps
that may differ by degrees, and where their weights change fast the picture is sheared and
swirled (a wall between two straightened edges bends its verticals, a corner between two
walls whirls). Where no handle holds it, this module fills the map in afresh: on a grid of
nodes over the sphere (:data:`GRID_WIDTH` around the equator), the nodes where the blend is
held keep it, and the others move to minimise the conformal energy of the piecewise-linear
map, the squared Cauchy-Riemann residual ``|∂T/∂n - T × ∂T/∂e|²`` integrated over the grid's
triangles (for a map of the sphere ``T``, east and north ``e``, ``n``: zero exactly where the
map is conformal, as every Möbius map is). With the held nodes as boundary conditions its
minimiser is the harmonic map that agrees with the blend around the handles and with the
still background beyond them. A small smoothness term (:data:`SMOOTH`: the displacement's
Jacobian changing from a cell to the next) on the cells next to the held nodes keeps the
held region's corners from kinking the edges that leave it. The whole is solved once,
linearised about the blend (the nodes move in their tangent planes), as one sparse
least-squares problem.

Held nodes, where the blend stays exactly as eq. (2) gives it:

- where one handle's controls carry all the weight, or the still background does;
- within :data:`BAND` grid steps of every marked line's output, so that each line keeps the
  map that makes it straight, and of every cage's edges; inside every cage; within
  :data:`~omniwidget.method.constraints.POINT_HOLD` and the band of every point, and within
  the reach of every point that turns or zooms (its fade is its own);
- on the first and last rows of nodes, round the poles: pixels nearer a pole than these see
  only them, and a ring of filled nodes would gather the whole cap onto itself.

A :class:`HarmonicFill` carries the blend and the filled map at the nodes; at any output
direction the map shown is ``fill(p) + β(p) (blend(p) - blend_nodes(p))``, with ``fill`` and
``blend_nodes`` interpolated bilinearly from the nodes and ``β`` the share of held nodes round
``p``: the blend itself where every node round ``p`` is held, the filled map where none is,
continuous in between. The paper's mode (``"anchor": null``) has no fill.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._lazy import lazy
from ..sphere import coords
from ..sphere.arcs import inside_polygon
from ..sphere.moebius import Moebius
from .constraints import POINT_HOLD, Constraints

if TYPE_CHECKING:
    import scipy.sparse.linalg as spla
    from scipy import sparse, spatial
else:
    sparse = lazy("scipy.sparse")
    spatial = lazy("scipy.spatial")
    spla = lazy("scipy.sparse.linalg")

__all__ = ["BAND", "FILL", "GRID_WIDTH", "HELD", "SMOOTH", "HarmonicFill", "harmonic_fill", "node_directions"]

#: Whether the default mode fills the blend in between the handles (the benches switch it off to compare).
FILL = True

#: Nodes of the fill's grid around the equator (a node every 2 degrees); its rows are half as many.
GRID_WIDTH = 180
#: Grid steps on either side of a marked line's output within which the nodes keep the blend: at least
#: ``sqrt(2) / 2``, so that the four nodes round every pixel of the line are held.
BAND = 1.5
#: Weight of the smoothness term (the Jacobian's change between neighbouring cells) against the conformal energy,
#: as a squared length in radians.
SMOOTH = 0.003
#: A node is held by a handle (or the still background) whose controls' weights there sum to at least this.
HELD = 1.0 - 1e-6


@dataclass(frozen=True, eq=False)
class HarmonicFill:
    """The blend and the filled map on the nodes of a ``w x w/2`` grid of the sphere.

    Attributes
    ----------
    blend : ndarray of float64, shape (w / 2, w, 3)
        The blend of eq. (2) at each node (unit vectors): the input direction it shows.
    filled : ndarray of float64, shape (w / 2, w, 3)
        The filled map at each node: the blend where the node is held.
    held : ndarray of bool, shape (w / 2, w)
        Nodes that keep the blend.

    The nodes sit where the pixels of a ``w`` wide panorama have their centres
    (:func:`omniwidget.sphere.coords.grid_lonlat`).
    """

    blend: NDArray[np.float64]
    filled: NDArray[np.float64]
    held: NDArray[np.bool_]

    @property
    def width(self) -> int:
        """Nodes around the equator."""
        return int(self.held.shape[1])

    def touched(self, lon: ArrayLike, lat: ArrayLike) -> NDArray[np.bool_]:
        """Which directions of a lon/lat grid the fill changes: those with a free node round them.

        Parameters
        ----------
        lon : array_like, shape (w,)
            Longitudes of the grid's columns, degrees.
        lat : array_like, shape (h,)
            Latitudes of its rows, degrees.

        Returns
        -------
        ndarray of bool, shape (h, w)
            Elsewhere :meth:`apply` gives the blend back exactly.
        """
        free_cell = self._free_cells()
        i0, _ = self.column_nodes(np.asarray(lon, dtype=np.float64))
        j0, _ = self.row_nodes(np.asarray(lat, dtype=np.float64))
        return np.asarray(free_cell[j0[:, None], i0[None, :]])

    def apply(self, lonlat: ArrayLike, blend: ArrayLike) -> NDArray[np.float64]:
        """The map shown at output directions, from the blend there.

        Parameters
        ----------
        lonlat : array_like, shape (..., 2)
            Output ``[lon, lat]``, degrees.
        blend : array_like, shape (..., 3)
            The blend of eq. (2) at them: the input directions as unit vectors.

        Returns
        -------
        ndarray of float64, shape (..., 3)
            The input directions shown, unit vectors: ``blend`` itself (as given) wherever
            the four nodes round a direction are held.
        """
        b = np.asarray(blend, dtype=np.float64)
        share, offset, every = self.affine(lonlat)
        out = share[..., None] * b + offset
        out /= np.linalg.norm(out, axis=-1, keepdims=True)
        return np.where(every[..., None], b, out)  # every node round it held: the blend as it came

    def affine(self, lonlat: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
        """The fill at output directions as an affine map of the blend there: ``apply`` is ``normalize(share b + offset)``.

        Parameters
        ----------
        lonlat : array_like, shape (..., 2)
            Output ``[lon, lat]``, degrees.

        Returns
        -------
        share : ndarray of float64, shape (...)
            The held nodes' share round each direction (bilinear weights), in [0, 1].
        offset : ndarray of float64, shape (..., 3)
            ``fill(p) - share(p) blend_nodes(p)``, with ``fill`` and ``blend_nodes`` the nodes' values interpolated.
        every : ndarray of bool, shape (...)
            Whether all four nodes round a direction are held (there the map is the blend itself).
        """
        p = np.asarray(lonlat, dtype=np.float64)
        (i0, fx), (j0, fy) = self.column_nodes(p[..., 0]), self.row_nodes(p[..., 1])
        i1, j1 = (i0 + 1) % self.width, j0 + 1
        corners = ((j0, i0, (1 - fy) * (1 - fx)), (j0, i1, (1 - fy) * fx), (j1, i0, fy * (1 - fx)), (j1, i1, fy * fx))
        shape = p.shape[:-1]
        filled, blend_nodes, share, every = np.zeros(shape + (3,)), np.zeros(shape + (3,)), np.zeros(shape), np.ones(shape, dtype=bool)
        for j, i, w in corners:
            filled += w[..., None] * self.filled[j, i]
            blend_nodes += w[..., None] * self.blend[j, i]
            share += w * self.held[j, i]
            every &= self.held[j, i]
        return share, filled - share[..., None] * blend_nodes, every

    def grid_affine(
        self, lon: ArrayLike, lat: ArrayLike, rows: ArrayLike, cols: ArrayLike
    ) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
        """:meth:`affine`'s ``share`` and ``offset`` at pixels of a lon/lat grid, in single precision.

        Bilinear in the node grid is linear along its rows and then along its columns: the
        grid's rows are interpolated on the nodes' columns first, then along the grid's
        columns (one sparse product), and only the pixels asked for are kept.

        Parameters
        ----------
        lon : array_like, shape (w,)
            Longitudes of the grid's columns, degrees.
        lat : array_like, shape (h,)
            Latitudes of its rows, degrees.
        rows, cols : array_like of int, shape (n,)
            The pixels: row and column indices into the grid.

        Returns
        -------
        share : ndarray of float32, shape (n,)
        offset : ndarray of float32, shape (n, 3)
            As :meth:`affine` gives them, to single precision.
        """
        nodes = np.concatenate([self.held[..., None].astype(np.float64), self.filled, self.blend], axis=-1)
        (i0, fx), (j0, fy) = self.column_nodes(np.asarray(lon, dtype=np.float64)), self.row_nodes(np.asarray(lat, dtype=np.float64))
        along_rows = ((1 - fy)[:, None, None] * nodes[j0] + fy[:, None, None] * nodes[j0 + 1]).astype(np.float32)  # (h, nodes, 7)
        h, w = len(j0), len(i0)
        along = sparse.csr_matrix(  # (w, nodes): each column's two nodes and their weights
            (np.concatenate([1 - fx, fx]).astype(np.float32), (np.tile(np.arange(w), 2), np.concatenate([i0, (i0 + 1) % self.width]))),
            shape=(w, self.width),
        )
        at = (along @ along_rows.transpose(1, 0, 2).reshape(self.width, h * 7)).reshape(w, h, 7)[np.asarray(cols), np.asarray(rows)]
        share = at[:, 0]
        return share, at[:, 1:4] - share[:, None] * at[:, 4:7]

    def column_nodes(self, lon: NDArray[np.float64]) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
        """For longitudes (degrees, any shape): the node column west of each and its share of the next one east (wrapping)."""
        x = (lon + 180.0) * (self.width / 360.0) - 0.5
        i0 = np.floor(x)
        return (i0.astype(np.int64) % self.width), x - i0

    def row_nodes(self, lat: NDArray[np.float64]) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
        """For latitudes (degrees, any shape): the node row north of each and its share of the next one south (clamped at the poles)."""
        rows = self.held.shape[0]
        y = np.clip((90.0 - lat) * (self.width / 360.0) - 0.5, 0.0, rows - 1)
        j0 = np.minimum(np.floor(y), rows - 2)
        return j0.astype(np.int64), y - j0

    def _free_cells(self) -> NDArray[np.bool_]:
        free = ~self.held
        return free[:-1] | free[1:] | np.roll(free[:-1], -1, axis=1) | np.roll(free[1:], -1, axis=1)


def node_directions(width: int = GRID_WIDTH) -> NDArray[np.float64]:
    """The fill's nodes: unit vectors (width / 2, width, 3) at the pixel centres of a ``width`` wide panorama.

    Raises
    ------
    ValueError
        For a width that is not an even number of at least 8.
    """
    if isinstance(width, bool) or not isinstance(width, int) or width < 8 or width % 2:
        raise ValueError(f"width must be an even number of nodes, at least 8, got {width!r}")
    return _grid(width).xyz


def harmonic_fill(
    constraints: Constraints,
    node_weights: NDArray[np.float64],
    node_blend: NDArray[np.float64],
    held_discs: Sequence[tuple[NDArray[np.float64], float]] = (),
    width: int = GRID_WIDTH,
) -> HarmonicFill | None:
    """The blend's fill between the handles (see the module's text), or None where every node is held.

    Parameters
    ----------
    constraints : Constraints
        The controls (their handles) and the marked lines and cages (``constraints.lines``, ``.cages``, ``.disks``).
    node_weights : ndarray of float64, shape (n, k)
        The blend's weights at the nodes of :func:`node_directions` (flattened), one column per control.
    node_blend : ndarray of float64, shape (n, 3)
        The blend of eq. (2) at the nodes: the input directions they show, unit vectors.
    held_discs : sequence of (ndarray of shape (3,), float)
        Output directions (unit vectors) and radii (degrees) within which every node is held too
        (the reach of a point that turns or zooms, whose fade is its own).
    width : int
        Nodes around the equator, even.

    Returns
    -------
    HarmonicFill or None
    """
    grid = _grid(node_directions(width).shape[1])
    xyz = grid.xyz.reshape(-1, 3)
    w, blend = np.asarray(node_weights, dtype=np.float64), np.asarray(node_blend, dtype=np.float64)
    if w.shape != (len(xyz), len(constraints.controls)) or blend.shape != xyz.shape:
        raise ValueError(f"expected weights ({len(xyz)}, {len(constraints.controls)}) and blend ({len(xyz)}, 3) at the nodes, got {w.shape} and {blend.shape}")
    controls = constraints.controls

    handle = np.array([c.handle for c in controls])
    held = np.zeros(len(xyz), dtype=bool)
    for h in np.unique(handle):
        held |= w[:, handle == h].sum(axis=1) >= HELD  # one handle's controls, or the background, carry it all
    band = BAND * 360.0 / width
    curves = [_dense(samples[[0, -1]], band, constraints.controls[c].moebius) for c, samples in constraints.lines]
    for _, polygon in constraints.cages:
        corners = np.asarray(polygon, dtype=np.float64)
        held |= inside_polygon(grid.lonlat.reshape(-1, 2), corners)
        curves += [_dense(np.stack([a, b]), band) for a, b in zip(corners, np.roll(corners, -1, axis=0), strict=True)]
    held |= _near(curves, band, grid)
    discs = [(centre, POINT_HOLD + band) for _, centre in constraints.disks] + list(held_discs)
    for centre, radius in discs:
        held |= xyz @ np.asarray(centre, dtype=np.float64) >= math.cos(math.radians(radius))
    held.reshape(grid.xyz.shape[:2])[[0, -1]] = True  # the rings round the poles: the pixels inside them see only these nodes
    if held.all():
        return None
    filled = _solve(grid, blend, held)
    shape = grid.xyz.shape
    return HarmonicFill(blend.reshape(shape), filled.reshape(shape), held.reshape(shape[:2]))


def _dense(ends: NDArray[np.float64], band: float, moebius: Moebius | None = None) -> NDArray[np.float64]:
    """Unit vectors along the great-circle arc between two ``[lon, lat]`` ends, at most ``band / 4`` degrees apart.

    With ``moebius``, the arc's image through it (a line piece: its input arc through its own map).
    """
    arc = float(coords.angular_distance(ends[0], ends[1]))
    if moebius is not None:
        arc = max(arc, float(coords.angular_distance(*moebius(ends))))
    dense = coords.geodesic(ends[0], ends[1], np.linspace(0.0, 1.0, max(2, math.ceil(4 * arc / band) + 1)))
    return coords.lonlat_to_xyz(dense if moebius is None else moebius(dense))


def _near(curves: list[NDArray[np.float64]], band: float, grid: _Grid) -> NDArray[np.bool_]:
    """Nodes within ``band`` degrees of any of the curves' samples (unit vectors)."""
    near = np.zeros(grid.xyz.shape[0] * grid.xyz.shape[1], dtype=bool)
    if curves:
        found = grid.tree.query_ball_point(np.concatenate(curves), 2 * math.sin(math.radians(band) / 2))
        near[np.unique(np.concatenate([np.asarray(f, dtype=np.int64) for f in found]))] = True
    return near


@dataclass(frozen=True, eq=False)
class _Grid:
    """A node grid's directions and its triangles' Cauchy-Riemann operators (per grid width, made once)."""

    xyz: NDArray[np.float64]  # (h, w, 3)
    lonlat: NDArray[np.float64]  # (h, w, 2), degrees
    triangles: NDArray[np.int64]  # (t, 3) node indices
    root_area: NDArray[np.float64]  # (t,) square roots of the triangles' areas
    d_east: Any  # scipy.sparse (t, nodes): the east derivative of a node function on each triangle
    d_north: Any
    pairs: Any  # scipy.sparse (p, t): the difference between a triangle and its twin in the next cell east or south
    twins: NDArray[np.int64]  # (p, 2): the two triangles of each pair
    tree: Any  # scipy.spatial.cKDTree of the nodes


@lru_cache(maxsize=4)
def _grid(width: int) -> _Grid:
    lon, lat = coords.grid_lonlat(width)
    xyz = coords.lonlat_to_xyz(np.stack(np.meshgrid(lon, lat), axis=-1))
    rows = width // 2
    j, i = np.meshgrid(np.arange(rows - 1), np.arange(width), indexing="ij")
    a, b = (j * width + i).ravel(), (j * width + (i + 1) % width).ravel()
    c, d = a + width, b + width
    # each cell in four triangles (both diagonals): no odd-even mode escapes the energy
    tri = np.concatenate([np.stack(t, axis=1) for t in ((a, c, b), (b, c, d), (a, c, d), (a, d, b))])
    p = xyz.reshape(-1, 3)
    centre = p[tri].mean(axis=1)
    east, north = coords.local_frame(coords.xyz_to_lonlat(centre))
    e1, e2 = p[tri[:, 1]] - p[tri[:, 0]], p[tri[:, 2]] - p[tri[:, 0]]
    edges = np.stack([np.stack([np.sum(e1 * east, -1), np.sum(e1 * north, -1)], -1), np.stack([np.sum(e2 * east, -1), np.sum(e2 * north, -1)], -1)], -1)
    det = edges[:, 0, 0] * edges[:, 1, 1] - edges[:, 0, 1] * edges[:, 1, 0]
    inv = np.stack([np.stack([edges[:, 1, 1], -edges[:, 0, 1]], -1), np.stack([-edges[:, 1, 0], edges[:, 0, 0]], -1)], -2) / det[:, None, None]
    # [d/de, d/dn] of a linear function = [f1 - f0, f2 - f0] @ inv
    coef = np.stack([-(inv[:, 0] + inv[:, 1]), inv[:, 0], inv[:, 1]], axis=1)  # (t, corner, e/n)
    r = np.repeat(np.arange(len(tri)), 3)
    shape = (len(tri), len(p))
    d_east = sparse.csr_matrix((coef[..., 0].ravel(), (r, tri.ravel())), shape=shape)
    d_north = sparse.csr_matrix((coef[..., 1].ravel(), (r, tri.ravel())), shape=shape)
    cells = (rows - 1) * width
    kind, cj, ci = np.meshgrid(np.arange(4), np.arange(rows - 1), np.arange(width), indexing="ij")
    here = kind * cells + cj * width + ci
    first = np.concatenate([here.ravel(), here[:, :-1].ravel()])
    second = np.concatenate([(kind * cells + cj * width + (ci + 1) % width).ravel(), (here + width)[:, :-1].ravel()])
    root = np.sqrt(np.abs(det) / 2)
    w = np.sqrt(root[first] * root[second])
    n = len(first)
    pairs = sparse.csr_matrix((np.concatenate([w, -w]), (np.tile(np.arange(n), 2), np.concatenate([first, second]))), shape=(n, len(tri)))
    twins = np.stack([first, second], axis=1)
    return _Grid(xyz, np.stack(np.meshgrid(lon, lat), axis=-1), tri, root, d_east, d_north, pairs, twins, spatial.cKDTree(p))


def _solve(grid: _Grid, blend: NDArray[np.float64], held: NDArray[np.bool_]) -> NDArray[np.float64]:
    """The free nodes moved in their tangent planes to minimise the linearised conformal energy; unit vectors (nodes, 3)."""
    free = np.flatnonzero(~held)
    used = (~held)[grid.triangles].any(axis=1)
    scale = sparse.diags(grid.root_area[used])
    d_east, d_north = scale @ grid.d_east[used], scale @ grid.d_north[used]
    tri = grid.triangles[used]
    normal = blend[tri].sum(axis=1)
    normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
    t1 = np.cross(blend, [0.0, 0.0, 1.0])
    polar = np.linalg.norm(t1, axis=-1) < 1e-6
    t1[polar] = np.cross(blend[polar], [1.0, 0.0, 0.0])
    t1 /= np.linalg.norm(t1, axis=-1, keepdims=True)
    t2 = np.cross(blend, t1)
    # residual R = D_n T - N x D_e T, component k: D_n T_k - N_{k+1} D_e T_{k+2} + N_{k+2} D_e T_{k+1}
    de_free, dn_free = d_east[:, free], d_north[:, free]
    blocks, rhs = [], []
    for k in range(3):
        k1, k2 = (k + 1) % 3, (k + 2) % 3
        n1, n2 = sparse.diags(normal[:, k1]), sparse.diags(normal[:, k2])
        row = [
            dn_free @ sparse.diags(t[free, k]) - n1 @ de_free @ sparse.diags(t[free, k2]) + n2 @ de_free @ sparse.diags(t[free, k1])
            for t in (t1, t2)
        ]
        blocks.append(sparse.hstack(row))
        rhs.append(normal[:, k1] * (d_east @ blend[:, k2]) - normal[:, k2] * (d_east @ blend[:, k1]) - d_north @ blend[:, k])
    if SMOOTH > 0:  # the displacement's Jacobian changing from cell to cell next to the held nodes: no corner of theirs kinks the map
        moved = blend - grid.xyz.reshape(-1, 3)
        touching = np.asarray(held[grid.triangles].any(axis=1))
        at_held = touching[grid.twins].any(axis=1)
        for d in (grid.d_east, grid.d_north):
            change = (math.sqrt(SMOOTH) * grid.xyz.shape[1] / (2 * math.pi)) * (grid.pairs[at_held] @ d)
            change = change[np.asarray(abs(change[:, free]).sum(axis=1)).ravel() > 0]
            change_free = change[:, free]
            for k in range(3):
                blocks.append(sparse.hstack([change_free @ sparse.diags(t1[free, k]), change_free @ sparse.diags(t2[free, k])]))
                rhs.append(-(change @ moved[:, k]))
    a = sparse.vstack(blocks).tocsr()
    step = spla.spsolve((a.T @ a).tocsc(), a.T @ np.concatenate(rhs), permc_spec="MMD_AT_PLUS_A")  # symmetric: an ordering of AᵀA suits it better than COLAMD
    out = blend.copy()
    moved = blend[free] + step[: len(free), None] * t1[free] + step[len(free) :, None] * t2[free]
    out[free] = moved / np.linalg.norm(moved, axis=-1, keepdims=True)
    return out
