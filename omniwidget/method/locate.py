"""Where each direction lies on a triangle mesh of the unit sphere.

The blend's weights are solved on the vertices of a closed triangle mesh of the sphere and
must be interpolated to every output pixel. A direction ``p`` lies in the face whose cone
from the origin contains it, that is ``p · (v_k × v_{k+1}) >= 0`` for the face's three edge
planes (faces counter-clockwise seen from outside). Its barycentric coordinates are those of
the point where the ray ``p`` meets the flat triangle: they are the three edge-plane values
``s_k = p · (v_k × v_{k+1})`` themselves, normalised to sum to 1 (``b_i ∝ s_{i+1}``), so the
interpolation is continuous across the edges and exact at the vertices, and a linear
function of ``xyz`` is reproduced exactly at the ray-plane point.

:func:`locate_grid` rasterises the mesh on an equirectangular grid row by row: in a row of
latitude ``φ``, an edge plane's condition ``cos φ (N_x cos λ + N_y sin λ) + N_z sin φ >= 0``
is an arc of longitudes in closed form, so a face covers at most three runs of columns of
the row (the intersection of its three arcs), and painting those runs needs no per-pixel
test. Only the barycentric coordinates are computed per pixel.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import _native
from .._checks import whole_number
from .._lazy import lazy
from ..sphere import coords

if TYPE_CHECKING:
    from scipy import spatial
else:
    spatial = lazy("scipy.spatial")

__all__ = [
    "DEGENERATE",
    "EDGE_TOLERANCE",
    "UNIT_TOLERANCE",
    "barycentric",
    "face_neighbours",
    "interpolate",
    "locate_faces",
    "locate_grid",
    "locate_points",
]

#: A direction within this distance (radians) outside a face's edge plane still counts as in it,
#: so directions on shared edges are never lost to rounding.
EDGE_TOLERANCE = 1e-12
#: Faces with ``v0 · (v1 × v2)`` at most this span no solid angle; they are never returned.
DEGENERATE = 1e-14
#: Largest allowed deviation of a vertex's norm from 1.
UNIT_TOLERANCE = 1e-6
#: Pixels handled at once in the per-pixel passes (keeps temporaries in cache).
_BLOCK_PIXELS = 1 << 16
#: Latitude padding (degrees) of the rows searched per face, far above rounding.
_LAT_PAD = 1e-7

IntArray = NDArray[np.int64]
FloatArray = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class _Mesh:
    """A validated mesh with its edge planes.

    ``normals[f, k] = v_k × v_{k+1}`` (``k + 1`` modulo 3), ``lengths`` their norms, and
    ``usable`` the faces that span a solid angle.
    """

    vertices: FloatArray  # (n, 3)
    faces: IntArray  # (m, 3)
    normals: FloatArray  # (m, 3, 3)
    lengths: FloatArray  # (m, 3)
    usable: NDArray[np.bool_]  # (m,)


def _check_closed(faces: IntArray, n: int) -> None:
    """Raise unless every directed edge occurs once and its reverse occurs once."""
    edges = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    key = np.sort(edges[:, 0] * n + edges[:, 1])
    if np.any(key[1:] == key[:-1]):
        dup = key[1:][key[1:] == key[:-1]][0]
        raise ValueError(
            f"the edge {dup // n} -> {dup % n} occurs twice in the same direction: the faces are not "
            "consistently oriented or the mesh is not a manifold"
        )
    reverse = np.sort(edges[:, 1] * n + edges[:, 0])
    if not np.array_equal(key, reverse):
        missing = np.setdiff1d(key, reverse, assume_unique=True)[0]
        raise ValueError(f"the mesh is not closed: the edge {missing // n} -> {missing % n} has no opposite edge")


def face_neighbours(faces: ArrayLike) -> NDArray[np.int32]:
    """The face across each edge of a closed, consistently oriented triangle mesh.

    Parameters
    ----------
    faces : array_like of int, shape (m, 3)
        Triangles; edge ``k`` of face ``f`` runs from corner ``k`` to corner ``k + 1`` (mod 3),
        the edge whose plane is ``planes[f, k]`` in :func:`locate_faces`.

    Returns
    -------
    ndarray of int32, shape (m, 3)
        ``out[f, k]`` is the face that holds edge ``k`` of face ``f`` reversed.

    Raises
    ------
    ValueError
        If some edge has no reversed twin (an open or inconsistently oriented mesh).
    """
    f = np.asarray(faces, dtype=np.int64)
    if f.ndim != 2 or f.shape[1] != 3:
        raise ValueError(f"faces must have shape (m, 3), got {f.shape}")
    n = int(f.max()) + 1
    start, end = f.ravel(), np.roll(f, -1, axis=1).ravel()
    key = start * n + end
    order = np.argsort(key)
    at = np.searchsorted(key[order], end * n + start)
    found = at < key.size
    found[found] = key[order[at[found]]] == (end * n + start)[found]
    if not found.all():
        i = int(np.flatnonzero(~found)[0])
        raise ValueError(f"the edge {start[i]} -> {end[i]} of face {i // 3} has no opposite edge: the mesh is not closed")
    return (order[at] // 3).astype(np.int32).reshape(f.shape)


def _prepare(vertices: ArrayLike, faces: ArrayLike) -> _Mesh:
    """Validate a closed, outward-oriented triangle mesh of the unit sphere."""
    v = np.asarray(vertices, dtype=np.float64)
    if v.ndim != 2 or v.shape[1] != 3 or len(v) < 4:
        raise ValueError(f"vertices must have shape (n, 3) with n >= 4, got {v.shape}")
    if not np.all(np.isfinite(v)):
        raise ValueError("vertices must be finite")
    norms = np.linalg.norm(v, axis=1)
    off = np.abs(norms - 1.0)
    if np.any(off > UNIT_TOLERANCE):
        i = int(np.argmax(off))
        raise ValueError(f"vertices must be unit vectors; vertex {i} has norm {norms[i]:.9g}")
    f = np.asarray(faces)
    if f.ndim != 2 or f.shape[1] != 3 or len(f) < 4:
        raise ValueError(f"faces must have shape (m, 3) with m >= 4, got {f.shape}")
    if not np.issubdtype(f.dtype, np.integer):
        raise ValueError(f"faces must hold integer vertex indices, got dtype {f.dtype}")
    f = f.astype(np.int64)
    if f.min() < 0 or f.max() >= len(v):
        raise ValueError(f"face indices must lie in [0, {len(v)}), got [{f.min()}, {f.max()}]")
    repeated = (f[:, 0] == f[:, 1]) | (f[:, 1] == f[:, 2]) | (f[:, 2] == f[:, 0])
    if np.any(repeated):
        raise ValueError(f"face {int(np.argmax(repeated))} repeats a vertex")
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    normals = np.stack([np.cross(a, b), np.cross(b, c), np.cross(c, a)], axis=1)
    det = np.einsum("ij,ij->i", a, normals[:, 1])
    inward = det < -DEGENERATE
    if np.any(inward):
        raise ValueError(
            f"{int(inward.sum())} face(s) are oriented inwards, e.g. face {int(np.argmax(inward))}: "
            "faces must be counter-clockwise seen from outside the sphere"
        )
    _check_closed(f, len(v))
    # Solid angles (Van Oosterom & Strackee): a closed mesh of positive faces covers the
    # sphere a whole number of times; it must be once.
    u = v / norms[:, None]
    ua, ub, uc = u[f[:, 0]], u[f[:, 1]], u[f[:, 2]]
    udet = np.einsum("ij,ij->i", ua, np.cross(ub, uc))
    dots = 1.0 + np.einsum("ij,ij->i", ua, ub) + np.einsum("ij,ij->i", ub, uc) + np.einsum("ij,ij->i", uc, ua)
    cover = float(np.sum(2.0 * np.arctan2(udet, dots))) / (4.0 * math.pi)
    if abs(cover - 1.0) > 1e-6:
        raise ValueError(f"the faces cover the sphere {cover:.6g} times; a mesh of the sphere covers it exactly once")
    lengths = np.linalg.norm(normals, axis=2)
    return _Mesh(v, f, normals, lengths, det > DEGENERATE)


# --- barycentric coordinates ---------------------------------------------------------


def _bary_from_planes(s0: FloatArray, s1: FloatArray, s2: FloatArray) -> FloatArray:
    """Barycentric coordinates from the edge-plane values ``s_k = p · (v_k × v_{k+1})``.

    ``b_i ∝ s_{i+1}``; the tolerated tiny negatives are clamped to 0, so the result is
    nonnegative and sums to 1. Shape ``s0.shape + (3,)``, float64.
    """
    out = np.empty(s0.shape + (3,), np.float64)
    np.maximum(s1, 0.0, out=out[..., 0])
    np.maximum(s2, 0.0, out=out[..., 1])
    np.maximum(s0, 0.0, out=out[..., 2])
    total = out.sum(axis=-1, keepdims=True)
    out /= np.maximum(total, np.finfo(np.float64).tiny)
    return out


def _bary(mesh: _Mesh, face: IntArray, p: FloatArray) -> FloatArray:
    """Barycentric coordinates of directions ``p`` (N, 3) in faces ``face`` (N,)."""
    return barycentric(mesh.normals, face, p)


def barycentric(planes: ArrayLike, face: ArrayLike, xyz: ArrayLike) -> FloatArray:
    """Barycentric coordinates of directions in the faces that hold them, from the faces' edge planes.

    Parameters
    ----------
    planes : array_like, shape (m, 3, 3)
        Edge planes of the faces (:func:`locate_faces`).
    face : array_like of int, shape (N,)
        The face of each direction (from :func:`locate_faces` or :func:`locate_points`).
    xyz : array_like, shape (N, 3)
        The directions.

    Returns
    -------
    ndarray of float64, shape (N, 3)
        Nonnegative, summing to 1.
    """
    s = np.einsum("nkj,nj->nk", np.asarray(planes)[np.asarray(face)], np.asarray(xyz, dtype=np.float64))
    return _bary_from_planes(s[:, 0], s[:, 1], s[:, 2])


# --- arbitrary directions ------------------------------------------------------------


def _scores(mesh: _Mesh, p: FloatArray, face: IntArray) -> FloatArray:
    """The smallest normalised edge-plane value of ``p`` (..., 3) in ``face`` (...): ``>= 0`` inside the cone."""
    s = np.einsum("...kj,...j->...k", mesh.normals[face], p) / mesh.lengths[face]
    return np.where(mesh.usable[face], s.min(axis=-1), -np.inf)


def _best_of(mesh: _Mesh, p: FloatArray, cand: IntArray) -> tuple[IntArray, FloatArray]:
    """Of the candidate faces ``cand`` (N, k) of ``p`` (N, 3), the most interior one and its score."""
    score = _scores(mesh, p[:, None, :], cand)
    best = np.argmax(score, axis=1)
    rows = np.arange(len(p))
    return cand[rows, best], score[rows, best]


def _cap_pairs(mesh: _Mesh, p: FloatArray, usable: IntArray, centroids: FloatArray) -> tuple[IntArray, IntArray]:
    """All (point, face) pairs where ``p[point]`` lies in the face's bounding cap.

    A face's cap is centred on its centroid direction with the chordal radius of its farthest
    vertex; it contains the face's spherical triangle (when no larger than a hemisphere).
    Faces are grouped by radius, within a factor of two, so that each group's range search
    finds few faces that are not candidates.
    """
    radius = np.linalg.norm(mesh.vertices[mesh.faces[usable]] - centroids[:, None, :], axis=2).max(axis=1)
    radius = np.where(radius > math.sqrt(2.0), 2.0, radius) + 1e-9
    group = np.floor(np.log2(radius / radius.min())).astype(np.int64)
    points = spatial.cKDTree(p)
    point_idx, face_idx = [np.zeros(0, np.int64)], [np.zeros(0, np.int64)]
    for g in np.unique(group):
        members = np.flatnonzero(group == g)
        near = points.sparse_distance_matrix(spatial.cKDTree(centroids[members]), float(radius[members].max()), output_type="ndarray")
        i, j = near["i"].astype(np.int64), near["j"].astype(np.int64)
        inside = near["v"] <= radius[members][j]
        point_idx.append(i[inside])
        face_idx.append(usable[members][j[inside]])
    return np.concatenate(point_idx), np.concatenate(face_idx)


def _locate(mesh: _Mesh, p: FloatArray) -> IntArray:
    """The face containing each unit direction of ``p`` (N, 3).

    The faces with the nearest centroids are tried first. The directions in none of them
    (on strongly non-uniform meshes, beside a dense region) are tested against every face
    whose bounding cap contains them; on a direction shared by several faces, the one it is
    deepest in wins.
    """
    n_points = len(p)
    face = np.zeros(n_points, np.int64)
    if n_points == 0:
        return face
    usable = np.flatnonzero(mesh.usable)
    centroids = mesh.vertices[mesh.faces[usable]].sum(axis=1)
    centroids /= np.linalg.norm(centroids, axis=1, keepdims=True)
    k = min(8, len(usable))
    tree = spatial.cKDTree(centroids)
    found = np.zeros(n_points, bool)
    for start in range(0, n_points, 8192):
        block = slice(start, start + 8192)
        _, near = tree.query(p[block], k=k)
        face[block], score = _best_of(mesh, p[block], usable[near.reshape(-1, k)])
        found[block] = score >= -EDGE_TOLERANCE
    remaining = np.flatnonzero(~found)
    if len(remaining) == 0:
        return face
    point_idx, face_idx = _cap_pairs(mesh, p[remaining], usable, centroids)
    score = _scores(mesh, p[remaining][point_idx], face_idx)
    order = np.lexsort((-score, point_idx))  # per point, best score first
    first = order[np.r_[True, point_idx[order][1:] != point_idx[order][:-1]]]
    face[remaining[point_idx[first]]] = face_idx[first]
    found[remaining[point_idx[first]]] = score[first] >= -EDGE_TOLERANCE
    # Only rounding can leave a direction outside every face: take the face nearest to containing it.
    remaining = np.flatnonzero(~found)
    chunk = max(1, (1 << 16) // len(usable))
    for start in range(0, len(remaining), chunk):
        idx = remaining[start : start + chunk]
        face[idx], _ = _best_of(mesh, p[idx], np.broadcast_to(usable, (len(idx), len(usable))))
    return face


def locate_points(vertices: ArrayLike, faces: ArrayLike, xyz: ArrayLike) -> tuple[NDArray[np.int32], FloatArray]:
    """The face containing each direction, and the direction's barycentric coordinates in it.

    Parameters
    ----------
    vertices : array_like, shape (n, 3)
        Unit vectors of the mesh vertices (float64).
    faces : array_like of int, shape (m, 3)
        A closed mesh of the sphere, each face counter-clockwise seen from outside.
    xyz : array_like, shape (..., 3)
        Nonzero direction vectors (need not be unit).

    Returns
    -------
    face : ndarray of int32, shape (...)
        A face whose cone from the origin contains the direction (within
        :data:`EDGE_TOLERANCE`); on an edge or at a vertex, the face in which it lies
        deepest.
    bary : ndarray of float64, shape (..., 3)
        Barycentric coordinates of the point where the ray meets the flat triangle:
        nonnegative, summing to 1.

    Raises
    ------
    ValueError
        If the mesh is not a closed, outward-oriented mesh of the unit sphere, or a
        direction is zero or not finite.
    """
    mesh = _prepare(vertices, faces)
    p = np.asarray(xyz, dtype=np.float64)
    if p.shape[-1:] != (3,):
        raise ValueError(f"expected directions of shape (..., 3), got {p.shape}")
    shape = p.shape[:-1]
    p = p.reshape(-1, 3)
    if not np.all(np.isfinite(p)):
        raise ValueError("directions must be finite")
    norms = np.linalg.norm(p, axis=1)
    if np.any(norms == 0):
        raise ValueError(f"direction {int(np.argmin(norms))} is the zero vector")
    unit = p / norms[:, None]
    face = _locate(mesh, unit)
    bary = _bary(mesh, face, unit)
    return face.astype(np.int32).reshape(shape), bary.reshape(shape + (3,))


# --- the equirectangular grid --------------------------------------------------------


def _face_latitudes(mesh: _Mesh) -> tuple[FloatArray, FloatArray]:
    """Exact latitude range (degrees) of each face's spherical triangle, shape (m,) each.

    The vertices' latitudes, widened by each edge's great-circle extreme where that lies on
    the edge's arc, and to ±90 where the face contains a pole.
    """
    v, f, normals = mesh.vertices, mesh.faces, mesh.normals
    lat = coords.xyz_to_lonlat(v)[:, 1][f]
    lo, hi = lat.min(axis=1), lat.max(axis=1)
    start, end = v[f], v[f[:, [1, 2, 0]]]  # edge k runs from vertex k to vertex k + 1
    nx, ny, nz = normals[..., 0], normals[..., 1], normals[..., 2]
    horizontal = nx * nx + ny * ny
    # The northernmost point of the edge's great circle: z projected onto its plane.
    top = np.stack([-nz * nx, -nz * ny, horizontal], axis=-1)
    after_start = np.einsum("fkj,fkj->fk", np.cross(start, top), normals)
    before_end = np.einsum("fkj,fkj->fk", np.cross(top, end), normals)
    top_lat = coords.xyz_to_lonlat(top)[..., 1]
    tilted = horizontal > 0
    on_arc = tilted & (after_start >= 0) & (before_end >= 0)
    hi = np.maximum(hi, np.where(on_arc, top_lat, -90.0).max(axis=1))
    on_arc = tilted & (after_start <= 0) & (before_end <= 0)  # the southernmost point, -top
    lo = np.minimum(lo, np.where(on_arc, -top_lat, 90.0).min(axis=1))
    slack = EDGE_TOLERANCE * mesh.lengths
    hi[np.all(nz >= -slack, axis=1)] = 90.0
    lo[np.all(nz <= slack, axis=1)] = -90.0
    return lo, hi


def _runs(mesh: _Mesh, width: int, cos_lat: FloatArray, sin_lat: FloatArray) -> tuple[IntArray, IntArray, IntArray]:
    """The runs of pixel columns each face covers in each row.

    Returns
    -------
    face, flat_start, length : ndarray of int64, shape (r,)
        Run ``i`` paints ``length[i]`` pixels of face ``face[i]`` from the flat (row-major)
        index ``flat_start[i]`` on, within one row (runs across the seam are split).
    """
    height = width // 2
    lo_lat, hi_lat = _face_latitudes(mesh)
    zero = np.zeros_like(lo_lat)
    first_row = np.ceil(coords.lonlat_to_px(np.stack([zero, hi_lat + _LAT_PAD], axis=-1), width)[:, 1])
    last_row = np.floor(coords.lonlat_to_px(np.stack([zero, lo_lat - _LAT_PAD], axis=-1), width)[:, 1])
    first_row = np.clip(first_row, 0, height).astype(np.int64)
    last_row = np.clip(last_row, -1, height - 1).astype(np.int64)
    counts = np.where(mesh.usable, np.maximum(last_row - first_row + 1, 0), 0)

    # One (face, row) pair per row a face may reach.
    pair_face = np.repeat(np.arange(len(counts)), counts)
    offsets = np.cumsum(counts) - counts
    pair_row = np.arange(len(pair_face)) - np.repeat(offsets - first_row, counts)

    # Edge plane k in row φ: cos φ R_k cos(λ - θ_k) + sin φ N_z,k >= -tolerance |N_k|,
    # an arc of half-width α_k = arccos(c_k) around θ_k (all λ if c_k <= -1, none if c_k > 1).
    # Edge-major layout (3, pairs): each edge's row of values is contiguous.
    n = mesh.normals.transpose(1, 2, 0)  # (edge, component, face)
    theta = np.arctan2(n[:, 1], n[:, 0])[:, pair_face]
    radius = np.hypot(n[:, 0], n[:, 1])[:, pair_face]
    num = -sin_lat[pair_row] * n[:, 2][:, pair_face] - (EDGE_TOLERANCE * mesh.lengths.T)[:, pair_face]
    den = cos_lat[pair_row] * radius
    c = np.divide(num, den, out=np.where(num <= 0, -np.inf, np.inf), where=den > 0)
    some = np.all(c <= 1.0, axis=0)
    if not np.all(some):
        pair_face, pair_row, c, theta = pair_face[some], pair_row[some], c[:, some], theta[:, some]
    half = np.arccos(np.clip(c, -1.0, 1.0))
    lo = theta - half

    # Intersect the three arcs on the line, in the window [lo_0, lo_0 + 2π) of arc 0: arc k
    # (k = 1, 2) appears there as [lo_k, hi_k] and, if it wraps, also as [lo_0, wrap_k].
    two_pi = 2.0 * math.pi
    lo0, hi0 = lo[0], lo[0] + 2.0 * half[0]
    lo1 = lo0 + np.mod(lo[1] - lo0, two_pi)
    lo2 = lo0 + np.mod(lo[2] - lo0, two_pi)
    hi1 = lo1 + 2.0 * half[1]
    hi2 = lo2 + 2.0 * half[2]
    lo_parts = [np.maximum(np.maximum(lo0, lo1), lo2)]
    hi_parts = [np.minimum(np.minimum(hi0, hi1), hi2)]
    face_parts, row_parts = [pair_face], [pair_row]
    wrap1, wrap2 = hi1 - two_pi, hi2 - two_pi
    wraps = np.flatnonzero((wrap1 >= lo0) | (wrap2 >= lo0))
    if len(wraps):
        lo0, hi0, lo1, hi1, lo2, hi2 = lo0[wraps], hi0[wraps], lo1[wraps], hi1[wraps], lo2[wraps], hi2[wraps]
        wrap1, wrap2 = wrap1[wraps], wrap2[wraps]
        lo_parts += [np.maximum(lo0, lo2), np.maximum(lo0, lo1), lo0]
        hi_parts += [
            np.minimum(np.minimum(hi0, wrap1), hi2),
            np.minimum(np.minimum(hi0, hi1), wrap2),
            np.minimum(np.minimum(hi0, wrap1), wrap2),
        ]
        face_parts += [pair_face[wraps]] * 3
        row_parts += [pair_row[wraps]] * 3
        run_lo, run_hi = np.concatenate(lo_parts), np.concatenate(hi_parts)
        run_face, run_row = np.concatenate(face_parts), np.concatenate(row_parts)
    else:
        run_lo, run_hi, run_face, run_row = lo_parts[0], hi_parts[0], face_parts[0], row_parts[0]
    keep = run_lo <= run_hi
    if not np.all(keep):
        run_lo, run_hi, run_face, run_row = run_lo[keep], run_hi[keep], run_face[keep], run_row[keep]

    # Pixel columns whose centres lie in [lo, hi], at most one full turn.
    x = coords.lonlat_to_px(np.stack([np.degrees(np.concatenate([run_lo, run_hi])), np.zeros(2 * len(run_lo))], axis=-1), width)[:, 0]
    first = np.ceil(x[: len(run_lo)]).astype(np.int64)
    length = np.minimum(np.floor(x[len(run_lo) :]).astype(np.int64) - first + 1, width)
    keep = length > 0
    first, length, run_face, run_row = np.mod(first[keep], width), length[keep], run_face[keep], run_row[keep]
    # Split the runs that cross the seam.
    over = np.maximum(first + length - width, 0)
    crossing = over > 0
    flat_start = np.concatenate([run_row * width + first, run_row[crossing] * width])
    length = np.concatenate([length - over, over[crossing]])
    run_face = np.concatenate([run_face, run_face[crossing]])
    return run_face, flat_start, length


def _grid_faces(mesh: _Mesh, width: int) -> tuple[NDArray[np.int32], FloatArray, FloatArray, FloatArray, FloatArray]:
    """Each pixel's face (H, W), and the grid's ``cos lon, sin lon`` (W,) and ``cos lat, sin lat`` (H,)."""
    lon, lat = coords.grid_lonlat(width)
    height = width // 2
    # Pixel directions factor as cos(lat) (cos lon, sin lon, 0) + sin(lat) z: the products
    # coords.lonlat_to_xyz forms, from W + H trigonometric values.
    east = coords.lonlat_to_xyz(np.stack([lon, np.zeros_like(lon)], axis=-1))
    meridian = coords.lonlat_to_xyz(np.stack([np.zeros_like(lat), lat], axis=-1))
    cos_lon, sin_lon = east[:, 0], east[:, 1]
    cos_lat, sin_lat = meridian[:, 0], meridian[:, 2]

    run_face, flat_start, length = _runs(mesh, width, cos_lat, sin_lat)

    if _native.available():  # paint the runs in one pass, without index arrays
        face = np.full(height * width, -1, np.int32)
        _native.kernels().paint_runs(run_face.astype(np.int32), flat_start.astype(np.int64), length.astype(np.int64), face)
    else:
        face = np.full(height * width, -1, np.int32)
        offsets = np.cumsum(length) - length
        face[np.repeat(flat_start - offsets, length) + np.arange(int(length.sum()))] = np.repeat(run_face.astype(np.int32), length)
    missed = np.flatnonzero(face < 0)
    if len(missed):  # only by rounding far beyond EDGE_TOLERANCE; never expected
        rows, cols = np.divmod(missed, width)
        p = np.stack([cos_lat[rows] * cos_lon[cols], cos_lat[rows] * sin_lon[cols], sin_lat[rows]], axis=-1)
        face[missed] = _locate(mesh, p)
    return face.reshape(height, width), cos_lon, sin_lon, cos_lat, sin_lat


def locate_faces(vertices: ArrayLike, faces: ArrayLike, width: int) -> tuple[NDArray[np.int32], FloatArray]:
    """The face of every pixel centre of an equirectangular grid, and the mesh's edge planes.

    :func:`locate_grid` without the barycentric coordinates, for callers that compute them
    themselves per pixel (:mod:`omniwidget.raster._kernels`).

    Parameters
    ----------
    vertices, faces, width
        As in :func:`locate_grid`.

    Returns
    -------
    face : ndarray of int32, shape (H, W)
        As in :func:`locate_grid`.
    planes : ndarray of float64, shape (m, 3, 3)
        ``planes[f, k] = v_k × v_{k+1}`` of face ``f``'s corners: a direction ``p`` has
        barycentric coordinates ``b_i ∝ max(p · planes[f, i + 1], 0)`` (indices mod 3).
    """
    width = whole_number(width, "width", 2, even=True)
    mesh = _prepare(vertices, faces)
    return _grid_faces(mesh, width)[0], mesh.normals


def locate_grid(vertices: ArrayLike, faces: ArrayLike, width: int) -> tuple[NDArray[np.int32], NDArray[np.float32]]:
    """The face and barycentric coordinates of every pixel centre of an equirectangular grid.

    Parameters
    ----------
    vertices : array_like, shape (n, 3)
        Unit vectors of the mesh vertices (float64).
    faces : array_like of int, shape (m, 3)
        A closed mesh of the sphere, each face counter-clockwise seen from outside.
    width : int
        Grid width ``W`` (even); the height is ``W / 2`` and the pixel centres are those of
        :func:`omniwidget.sphere.coords.grid_lonlat`.

    Returns
    -------
    face : ndarray of int32, shape (H, W)
        For each pixel, a face whose cone from the origin contains the pixel's direction
        (within :data:`EDGE_TOLERANCE`). A pixel on a shared edge or at a vertex gets one of
        the faces there, with barycentric coordinates in that face.
    bary : ndarray of float32, shape (H, W, 3)
        Barycentric coordinates of the point where the pixel's ray meets the flat triangle:
        nonnegative, summing to 1 (up to float32 rounding).

    Raises
    ------
    ValueError
        If ``width`` is not even and positive, or the mesh is not a closed, outward-oriented
        mesh of the unit sphere.

    Notes
    -----
    Each face's runs of columns per row are found in closed form and painted; only the
    barycentric coordinates cost per-pixel work. Use :func:`interpolate` to turn them into
    per-pixel values.
    """
    width = whole_number(width, "width", 2, even=True)
    mesh = _prepare(vertices, faces)
    height = width // 2
    face, cos_lon, sin_lon, cos_lat, sin_lat = _grid_faces(mesh, width)

    # Barycentric coordinates, b_i ∝ s_{i+1}, in blocks of rows with per-edge face tables.
    table = [np.ascontiguousarray(mesh.normals[:, k, j]) for k in (1, 2, 0) for j in range(3)]
    bary = np.empty((height, width, 3), np.float32)
    block = max(1, _BLOCK_PIXELS // width)
    for r0 in range(0, height, block):
        rows = slice(r0, min(r0 + block, height))
        f = face[rows]
        px = cos_lat[rows, None] * cos_lon
        py = cos_lat[rows, None] * sin_lon
        pz = sin_lat[rows, None]
        s = []
        for i in range(3):
            si = np.take(table[3 * i], f) * px
            si += np.take(table[3 * i + 1], f) * py
            si += np.take(table[3 * i + 2], f) * pz
            s.append(np.maximum(si, 0.0, out=si))
        inverse = s[0] + s[1]
        inverse += s[2]
        np.maximum(inverse, np.finfo(np.float64).tiny, out=inverse)  # > 0 inside a face anyway
        np.divide(1.0, inverse, out=inverse)
        out = bary[rows]
        for i in range(3):
            s[i] *= inverse
            out[..., i] = s[i]
    return face, bary


# --- interpolation -------------------------------------------------------------------


def interpolate(values: ArrayLike, faces: ArrayLike, face: ArrayLike, bary: ArrayLike) -> NDArray[np.floating]:
    """Per-vertex values interpolated at located directions: ``Σ_i bary_i values[faces[face, i]]``.

    Parameters
    ----------
    values : array_like, shape (n,) or (n, k)
        Values at the mesh vertices (e.g. the blend weights).
    faces : array_like of int, shape (m, 3)
        The mesh's faces.
    face : array_like of int, shape (...)
        Faces from :func:`locate_grid` or :func:`locate_points`.
    bary : array_like of float, shape (..., 3)
        The matching barycentric coordinates.

    Returns
    -------
    ndarray, shape (...) or (..., k)
        Floating dtype of ``values`` and ``bary`` combined (float32 values with float32
        barycentric coordinates stay float32).
    """
    values = np.asarray(values)
    faces = np.asarray(faces)
    face = np.asarray(face)
    bary = np.asarray(bary)
    if values.ndim not in (1, 2):
        raise ValueError(f"values must have shape (n,) or (n, k), got {values.shape}")
    if faces.ndim != 2 or faces.shape[1] != 3 or not np.issubdtype(faces.dtype, np.integer):
        raise ValueError(f"faces must be integers of shape (m, 3), got {faces.dtype} {faces.shape}")
    if faces.size and (faces.min() < 0 or faces.max() >= len(values)):
        raise ValueError(f"faces index vertices up to {faces.max()} but there are {len(values)} values")
    if not np.issubdtype(face.dtype, np.integer):
        raise ValueError(f"face must hold integer face indices, got dtype {face.dtype}")
    if bary.shape != face.shape + (3,):
        raise ValueError(f"bary must have shape {face.shape + (3,)} to match face, got {bary.shape}")
    if face.size and (face.min() < 0 or face.max() >= len(faces)):
        raise ValueError(f"face indices must lie in [0, {len(faces)}), got [{face.min()}, {face.max()}]")
    dtype = np.result_type(values.dtype, bary.dtype, np.float32)
    values = values.astype(dtype, copy=False)
    columns = values.shape[1:]
    out = np.empty(face.shape + columns, dtype)
    flat_face = face.reshape(-1)
    flat_bary = bary.reshape(-1, 3).astype(dtype, copy=False)
    flat_out = out.reshape((-1,) + columns)
    expand = (slice(None),) + (None,) * len(columns)
    for start in range(0, len(flat_face), _BLOCK_PIXELS):
        block = slice(start, start + _BLOCK_PIXELS)
        corner = faces[flat_face[block]]
        b = flat_bary[block]
        acc = b[:, 0][expand] * values[corner[:, 0]]
        acc += b[:, 1][expand] * values[corner[:, 1]]
        acc += b[:, 2][expand] * values[corner[:, 2]]
        flat_out[block] = acc
    return out
