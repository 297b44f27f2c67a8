"""The adaptive triangle mesh of the sphere on which the blending weights are solved (Sec. 3.5).

Bounded biharmonic weights are computed on a triangulation of the unit sphere that is
fine near the handles, where the weights vary quickly, coarse far from them, and that has
the handles' samples as vertices, so that the boundary conditions can be imposed on them.
The construction follows the paper:

1. start from an icosahedron subdivided ``base_level`` times (:func:`icosphere`);
2. ``rounds`` times, split 1-to-4 every triangle whose barycentre lies within a threshold
   angular distance of a sample, the threshold shrinking from round to round; new edge
   midpoints are projected onto the sphere;
3. add the samples as vertices and take the connectivity from the convex hull of all
   vertices, which for points on a sphere is the spherical Delaunay triangulation.

Only the vertices of step 2 are kept (the split triangles have T-junctions where a split
triangle meets an unsplit one); the convex hull in step 3 rebuilds a conforming, closed
triangulation from scratch. Everything here works on unit vectors (``xyz`` in the sense
of :mod:`omniwidget.sphere.coords`); angles at the public boundary are in degrees.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import whole_number
from .._lazy import lazy

if TYPE_CHECKING:
    from scipy import sparse, spatial
    from scipy.sparse import csgraph
else:
    sparse = lazy("scipy.sparse")
    csgraph = lazy("scipy.sparse.csgraph")
    spatial = lazy("scipy.spatial")

__all__ = [
    "DEFAULT_THRESHOLD_EDGES",
    "DROP_FRACTION",
    "MERGE_CHORD",
    "SphereMesh",
    "adaptive_mesh",
    "default_thresholds",
    "icosphere",
    "triangle_angles",
]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

#: Samples whose chordal distance (on the unit sphere: about the angle in radians) is
#: below this become one vertex. The same tolerance as ``moebius.COINCIDENT``.
MERGE_CHORD = 1e-9

#: A refinement vertex closer to a sample than this fraction of its shortest incident
#: edge is dropped, and the sample takes its place.
DROP_FRACTION = 0.3

#: The default threshold of round ``r`` is this many mean edge lengths of the faces split
#: in that round, that is ``DEFAULT_THRESHOLD_EDGES * h_base / 2**r``.
DEFAULT_THRESHOLD_EDGES = 1.5

_PHI = (1.0 + math.sqrt(5.0)) / 2.0
_ICOSAHEDRON_VERTICES = np.array(
    [
        [-1, _PHI, 0],
        [1, _PHI, 0],
        [-1, -_PHI, 0],
        [1, -_PHI, 0],
        [0, -1, _PHI],
        [0, 1, _PHI],
        [0, -1, -_PHI],
        [0, 1, -_PHI],
        [_PHI, 0, -1],
        [_PHI, 0, 1],
        [-_PHI, 0, -1],
        [-_PHI, 0, 1],
    ],
    dtype=np.float64,
)
_ICOSAHEDRON_FACES = np.array(
    [
        [0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11],
        [1, 5, 9], [5, 11, 4], [11, 10, 2], [10, 7, 6], [7, 1, 8],
        [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9],
        [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1],
    ],
    dtype=np.int64,
)  # fmt: skip


# --- small helpers -------------------------------------------------------------------
def _normalize(p: FloatArray) -> FloatArray:
    return p / np.linalg.norm(p, axis=-1, keepdims=True)


def _chord(angle_rad: ArrayLike) -> FloatArray:
    """Chord length on the unit sphere of an angle in radians (angles beyond pi clip to 2)."""
    return 2.0 * np.sin(np.minimum(np.asarray(angle_rad, dtype=np.float64), math.pi) / 2.0)


def _angle(chord: ArrayLike) -> FloatArray:
    """Angle in radians of a chord length on the unit sphere."""
    return 2.0 * np.arcsin(np.minimum(np.asarray(chord, dtype=np.float64) / 2.0, 1.0))


def _orient_outward(vertices: FloatArray, faces: IntArray) -> IntArray:
    """Reorder each face so that ``(b - a) x (c - a)`` points away from the origin."""
    a, b, c = (vertices[faces[:, i]] for i in range(3))
    flip = np.einsum("ij,ij->i", np.cross(b - a, c - a), a + b + c) < 0
    faces = faces.copy()
    faces[flip] = faces[flip][:, [0, 2, 1]]
    return faces


def _edge_keys(faces: IntArray) -> tuple[IntArray, IntArray, IntArray]:
    """Undirected edges of each face, ``(ab, bc, ca)``: lower index, higher index, packed key."""
    ends = np.stack([faces, np.roll(faces, -1, axis=1)], axis=-1)  # (m, 3, 2)
    lo, hi = ends.min(axis=-1), ends.max(axis=-1)
    return lo, hi, (lo << 32) | hi


class _Splitter:
    """1-to-4 splits of triangles of a growing vertex set, sharing every edge midpoint once.

    A midpoint created when one face is split is reused when its neighbour across that edge
    is split in the same or a later round, so no vertex is ever duplicated.
    """

    def __init__(self, vertices: FloatArray) -> None:
        self.vertices = vertices
        self._keys = np.empty(0, dtype=np.int64)  # sorted packed edge keys
        self._mids = np.empty(0, dtype=np.int64)  # midpoint vertex of each key

    def split(self, faces: IntArray) -> IntArray:
        """The four children, counter-clockwise like their parent, of each face; shape (4 m, 3)."""
        lo, hi, key = _edge_keys(faces)
        ukey, first, inverse = np.unique(key.ravel(), return_index=True, return_inverse=True)
        pos = np.minimum(np.searchsorted(self._keys, ukey), max(len(self._keys) - 1, 0))
        found = (self._keys[pos] == ukey) if len(self._keys) else np.zeros(len(ukey), dtype=bool)
        mid = np.empty(len(ukey), dtype=np.int64)
        mid[found] = self._mids[pos[found]]
        new = ~found
        n = len(self.vertices)
        mid[new] = np.arange(n, n + int(new.sum()), dtype=np.int64)
        ends_lo, ends_hi = lo.ravel()[first[new]], hi.ravel()[first[new]]
        self.vertices = np.concatenate([self.vertices, _normalize(self.vertices[ends_lo] + self.vertices[ends_hi])])
        keys = np.concatenate([self._keys, ukey[new]])
        order = np.argsort(keys, kind="stable")
        self._keys, self._mids = keys[order], np.concatenate([self._mids, mid[new]])[order]

        m_ab, m_bc, m_ca = mid[inverse.reshape(-1, 3)].T
        a, b, c = faces.T
        return np.concatenate(
            [
                np.stack([a, m_ab, m_ca], axis=1),
                np.stack([m_ab, b, m_bc], axis=1),
                np.stack([m_ca, m_bc, c], axis=1),
                np.stack([m_ab, m_bc, m_ca], axis=1),
            ]
        )


def _frozen(array: np.ndarray) -> np.ndarray:
    array = np.ascontiguousarray(array)
    array.setflags(write=False)
    return array


# --- public API ----------------------------------------------------------------------
def icosphere(level: int) -> tuple[FloatArray, IntArray]:
    """An icosahedron subdivided ``level`` times 1-to-4, midpoints projected onto the unit sphere.

    Parameters
    ----------
    level : int
        Number of subdivisions, ``>= 0``; ``0`` is the icosahedron.

    Returns
    -------
    vertices : ndarray of float64, shape (10 * 4**level + 2, 3)
        Unit vectors; the twelve icosahedron vertices come first.
    faces : ndarray of int64, shape (20 * 4**level, 3)
        Vertex indices, counter-clockwise seen from outside the sphere (the normal
        ``(b - a) x (c - a)`` points outwards).
    """
    level = whole_number(level, "level")
    splitter = _Splitter(_normalize(_ICOSAHEDRON_VERTICES))
    faces = _ICOSAHEDRON_FACES.copy()
    for _ in range(level):
        faces = splitter.split(faces)
    return splitter.vertices, faces


def _mean_edge_angle(vertices: FloatArray, faces: IntArray) -> float:
    lo, hi, _ = _edge_keys(faces)
    return float(np.mean(_angle(np.linalg.norm(vertices[lo] - vertices[hi], axis=-1))))


def default_thresholds(base_level: int = 1, rounds: int = 4) -> tuple[float, ...]:
    """The default refinement thresholds of :func:`adaptive_mesh`, in degrees, one per round.

    Round ``r`` (from 0) splits faces of mean edge length about ``h_base / 2**r``, where
    ``h_base`` is the mean edge angle of ``icosphere(base_level)``; its threshold is
    ``DEFAULT_THRESHOLD_EDGES`` (1.5) of those edge lengths, so it halves every round and
    each round refines a band about one and a half triangles wide around every handle.

    Parameters
    ----------
    base_level, rounds : int
        As in :func:`adaptive_mesh`.

    Returns
    -------
    tuple of float, length ``rounds``
        Angular distances in degrees (for ``base_level=1``: about 52, 26, 13 and 6.5).
    """
    base_level = whole_number(base_level, "base_level")
    rounds = whole_number(rounds, "rounds")
    # Edge lengths of an icosphere depend only on the level; level 0 + splits is cheap.
    h_base = math.degrees(_mean_edge_angle(*icosphere(base_level)))
    return tuple(DEFAULT_THRESHOLD_EDGES * h_base / 2.0**r for r in range(rounds))


def triangle_angles(vertices: ArrayLike, faces: ArrayLike) -> FloatArray:
    """Interior angles in degrees of the flat (chordal) triangles of a mesh.

    These are the angles that the cotangent Laplacian of the weights solve sees.

    Parameters
    ----------
    vertices : array_like of float, shape (n, 3)
    faces : array_like of int, shape (m, 3)

    Returns
    -------
    ndarray of float64, shape (m, 3)
        The angle at each corner of each face; a degenerate (zero-length) edge gives NaN.
    """
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    if vertices.ndim != 2 or vertices.shape[1] != 3 or faces.ndim != 2 or faces.shape[1] != 3:
        raise ValueError(f"expected vertices (n, 3) and faces (m, 3), got shapes {vertices.shape} and {faces.shape}")
    p = vertices[faces]  # (m, 3, 3)
    u = np.roll(p, -1, axis=1) - p  # corner i -> next corner
    w = np.roll(p, 1, axis=1) - p  # corner i -> previous corner
    cross = np.linalg.norm(np.cross(u, w), axis=-1)
    dot = np.einsum("mij,mij->mi", u, w)
    with np.errstate(invalid="ignore"):
        angles = np.degrees(np.arctan2(cross, dot))
    degenerate = (np.linalg.norm(u, axis=-1) == 0) | (np.linalg.norm(w, axis=-1) == 0)
    angles[degenerate] = np.nan
    return angles


@dataclass(frozen=True, eq=False)
class SphereMesh:
    """A closed triangle mesh of the unit sphere with the handles' samples as vertices.

    Attributes
    ----------
    vertices : ndarray of float64, shape (n, 3)
        Unit vectors: the kept refinement vertices first, then one vertex per distinct sample
        (in order of first occurrence).
    faces : ndarray of int64, shape (m, 3)
        Counter-clockwise seen from outside; a closed 2-manifold of genus 0
        (``n - m / 2 = 2``).
    sample_index : ndarray of int64, shape (k,)
        ``vertices[sample_index[i]]`` is sample ``i``: bit for bit if it is a unit vector to
        rounding (else normalised), or the first sample it was merged with, at most
        :data:`MERGE_CHORD` away. (Only samples packed more densely than qhull can resolve,
        about 1e-7 rad apart, are sent to the nearest vertex instead.)
    rounds : tuple of (vertices, faces) pairs
        The refinement stages before the samples are added, for teaching: the base
        icosphere, then the mesh after each round (``len(rounds) == rounds + 1``). Their
        faces are the triangles of the 1-to-4 splits as they are, so a split face next to an
        unsplit one leaves a T-junction (an edge midpoint that is a vertex on one side only):
        fine for plotting, not a mesh to solve on.

    All arrays are read-only.
    """

    vertices: FloatArray
    faces: IntArray
    sample_index: IntArray
    rounds: tuple[tuple[FloatArray, IntArray], ...]

    @property
    def n_vertices(self) -> int:
        """Number of vertices ``n``."""
        return int(self.vertices.shape[0])

    @property
    def n_faces(self) -> int:
        """Number of faces ``m``."""
        return int(self.faces.shape[0])

    @property
    def n_samples(self) -> int:
        """Number of samples ``k`` given to :func:`adaptive_mesh` (before merging)."""
        return int(self.sample_index.shape[0])

    def triangle_angles(self) -> FloatArray:
        """Interior angles in degrees of every face, shape (m, 3); see :func:`triangle_angles`."""
        return triangle_angles(self.vertices, self.faces)

    def min_angle_degrees(self) -> float:
        """The smallest interior angle of any face, in degrees (60 for a perfect mesh)."""
        return float(np.min(self.triangle_angles()))


def _samples(samples: ArrayLike) -> FloatArray:
    arr = np.asarray(samples, dtype=np.float64)
    if arr.shape in ((0,), (0, 3)):
        return np.empty((0, 3), dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ValueError(f"samples must be unit vectors of shape (k, 3), got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError("samples must be finite")
    norms = np.linalg.norm(arr, axis=1)
    bad = np.flatnonzero(np.abs(norms - 1.0) > 1e-6)
    if len(bad):
        raise ValueError(f"samples must be unit vectors; sample {bad[0]} has norm {norms[bad[0]]:.6g}")
    # Unit to rounding: used bit for bit, so that vertices[sample_index] == samples exactly.
    off = np.abs(norms - 1.0) > 1e-14
    arr = arr.copy()
    arr[off] /= norms[off, None]
    return arr


def _thresholds(threshold: float | Sequence[float] | None, base_level: int, rounds: int) -> FloatArray:
    if threshold is None:
        values = np.array(default_thresholds(base_level, rounds), dtype=np.float64)
    else:
        arr = np.asarray(threshold, dtype=np.float64)
        if arr.ndim == 0:
            values = float(arr) / 2.0 ** np.arange(rounds, dtype=np.float64)
        elif arr.shape == (rounds,):
            values = arr
        else:
            raise ValueError(f"threshold must be a number or one number per round ({rounds}), got shape {arr.shape}")
        if not (np.all(np.isfinite(values)) and np.all(values > 0)):
            raise ValueError(f"thresholds must be positive finite angles in degrees, got {threshold!r}")
    return values


def _merge_samples(samples: FloatArray) -> tuple[FloatArray, IntArray]:
    """Distinct samples (first of each cluster closer than MERGE_CHORD) and each sample's cluster."""
    k = len(samples)
    pairs = spatial.cKDTree(samples).query_pairs(MERGE_CHORD, output_type="ndarray")
    if len(pairs) == 0:
        return samples, np.arange(k, dtype=np.int64)
    graph = sparse.coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(k, k))
    _, labels = csgraph.connected_components(graph, directed=False)
    _, first, inverse = np.unique(labels, return_index=True, return_inverse=True)
    order = np.argsort(first)  # clusters by first occurrence
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    return samples[first[order]], rank[inverse].astype(np.int64)


def _hull_faces(vertices: FloatArray) -> IntArray:
    return _orient_outward(vertices, spatial.ConvexHull(vertices).simplices.astype(np.int64))


def adaptive_mesh(
    samples: ArrayLike,
    *,
    base_level: int = 1,
    rounds: int = 4,
    threshold: float | Sequence[float] | None = None,
) -> SphereMesh:
    """The adaptive mesh of Sec. 3.5: refined near the samples, with the samples as vertices.

    Parameters
    ----------
    samples : array_like of float, shape (k, 3)
        Unit vectors: the handles' samples at their *final* positions (the weights serve
        the inverse warp), e.g. 50 per line and per cage edge and the point handles'
        centres, concatenated. ``k = 0`` (shape (0, 3) or (0,)) gives the base icosphere.
    base_level : int
        Subdivision level of the starting icosphere (1: 42 vertices, 80 faces).
    rounds : int
        Number of refinement rounds.
    threshold : float, sequence of float or None
        Angular distances in degrees between a face's barycentre and the nearest sample
        below which the face is split. ``None``: :func:`default_thresholds`, i.e. 1.5 mean
        edge lengths of the faces split in that round, halving every round. A number: the
        threshold of the first round, halved every round. A sequence: one per round.

    Returns
    -------
    SphereMesh

    Raises
    ------
    ValueError
        If ``samples`` is not (k, 3), not finite or not unit, if a level is negative, or if a
        threshold is not a positive finite number.

    Notes
    -----
    * Samples closer than :data:`MERGE_CHORD` (1e-9, about radians) to each other become one
      vertex; ``sample_index`` maps every sample to it.
    * A refinement vertex closer to a sample than :data:`DROP_FRACTION` (0.3) of its
      shortest incident edge is dropped and the sample takes its place, so there are no
      near-duplicate vertices and no slivers next to the samples. In particular a sample on
      a refinement vertex replaces it (at exactly the sample's position).
    * The connectivity is the convex hull of all vertices (qhull), i.e. the spherical
      Delaunay triangulation; its faces are oriented outwards. Poles and the ±180° seam are
      ordinary points here. The smallest angles occur where samples are spaced much more
      densely than the final refinement (about ``h_base / 2**rounds``, 2 degrees with the
      defaults), e.g. 50 samples on a line only a few degrees long.

    Examples
    --------
    >>> mesh = adaptive_mesh(np.array([[1.0, 0.0, 0.0]]))
    >>> bool(np.all(mesh.vertices[mesh.sample_index] == [1.0, 0.0, 0.0]))
    True
    """
    base_level = whole_number(base_level, "base_level")
    rounds = whole_number(rounds, "rounds")
    samples = _samples(samples)
    thresholds = _thresholds(threshold, base_level, rounds)

    base_vertices, base_faces = icosphere(base_level)
    if len(samples) == 0:  # nothing to refine towards: the base icosphere as it is
        base = (_frozen(base_vertices), _frozen(base_faces))
        return SphereMesh(*base, sample_index=_frozen(np.empty(0, dtype=np.int64)), rounds=(base,) * (rounds + 1))

    distinct, cluster = _merge_samples(samples)
    tree = spatial.cKDTree(distinct)

    # 1-2. Refinement rounds: split faces whose (normalised) barycentre is near a sample.
    splitter = _Splitter(base_vertices)
    faces = base_faces
    stages = [(base_vertices, base_faces)]
    for limit in thresholds:
        barycentres = _normalize(splitter.vertices[faces].sum(axis=1))
        distance, _ = tree.query(barycentres, distance_upper_bound=float(_chord(math.radians(limit))))
        near = np.isfinite(distance)
        if np.any(near):
            faces = np.concatenate([faces[~near], splitter.split(faces[near])])
        stages.append((splitter.vertices, faces))
    refined = splitter.vertices

    # 3. Drop refinement vertices that crowd a sample, add the samples, triangulate.
    lo, hi, _ = _edge_keys(faces)
    length = np.linalg.norm(refined[lo] - refined[hi], axis=-1).ravel()
    shortest = np.full(len(refined), np.inf)
    np.minimum.at(shortest, lo.ravel(), length)
    np.minimum.at(shortest, hi.ravel(), length)
    nearest, _ = tree.query(refined)
    kept = refined[nearest >= DROP_FRACTION * shortest]
    vertices = np.concatenate([kept, distinct])
    sample_index = len(kept) + cluster

    faces = _hull_faces(vertices)
    used = np.zeros(len(vertices), dtype=bool)
    used[faces.ravel()] = True
    if not np.all(used):
        # qhull left out points it could not separate from a neighbour (far below any
        # realistic spacing): drop them and send their samples to the nearest hull vertex.
        remap = np.cumsum(used) - 1
        nearest_used = np.flatnonzero(used)[spatial.cKDTree(vertices[used]).query(vertices[~used])[1]]
        remap[~used] = remap[nearest_used]
        vertices, faces, sample_index = vertices[used], remap[faces], remap[sample_index]

    return SphereMesh(
        vertices=_frozen(vertices),
        faces=_frozen(faces.astype(np.int64)),
        sample_index=_frozen(sample_index.astype(np.int64)),
        rounds=tuple((_frozen(v), _frozen(f)) for v, f in stages),
    )
