import subprocess
import sys

import numpy as np
import pytest
from scipy.spatial import ConvexHull

from omniwidget.method.locate import interpolate, locate_grid, locate_points
from omniwidget.sphere import coords

# --- meshes of the unit sphere, built here -------------------------------------------------


def _orient_outwards(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Make every face counter-clockwise seen from outside (valid for vertices in convex position)."""
    f = np.array(f, dtype=np.int64)
    det = np.einsum("ij,ij->i", v[f[:, 0]], np.cross(v[f[:, 1]], v[f[:, 2]]))
    f[det < 0] = f[det < 0][:, [0, 2, 1]]
    return f


def icosphere(level: int) -> tuple[np.ndarray, np.ndarray]:
    """The icosahedron, subdivided 1-to-4 ``level`` times, new vertices projected to the sphere."""
    t = (1 + 5**0.5) / 2
    v = [
        [-1, t, 0],
        [1, t, 0],
        [-1, -t, 0],
        [1, -t, 0],
        [0, -1, t],
        [0, 1, t],
        [0, -1, -t],
        [0, 1, -t],
        [t, 0, -1],
        [t, 0, 1],
        [-t, 0, -1],
        [-t, 0, 1],
    ]
    v = [np.array(p, float) / np.linalg.norm(p) for p in v]
    f = [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4], [11, 10, 2], [10, 7, 6], [7, 1, 8],
         [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]]  # fmt: skip
    midpoints: dict[tuple[int, int], int] = {}  # each edge's midpoint, shared by both of its faces

    def mid(a: int, b: int) -> int:
        key = (min(a, b), max(a, b))
        if key not in midpoints:
            m = v[a] + v[b]
            v.append(m / np.linalg.norm(m))
            midpoints[key] = len(v) - 1
        return midpoints[key]

    for _ in range(level):
        midpoints.clear()
        new = []
        for a, b, c in f:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            new += [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
        f = new
    return np.array(v), np.array(f, dtype=np.int64)


def hull_mesh(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The convex hull of points projected to the sphere, faces outward."""
    v = points / np.linalg.norm(points, axis=1, keepdims=True)
    return v, _orient_outwards(v, ConvexHull(v).simplices)


def uv_sphere(lons, lats) -> tuple[np.ndarray, np.ndarray]:
    """Vertices exactly at both poles and on rings of latitude ``lats`` (north to south) at ``lons``."""
    nl = len(lons)
    ring = np.array([[lon, lat] for lat in lats for lon in lons], float)
    v = np.concatenate([[[0.0, 0.0, 1.0]], coords.lonlat_to_xyz(ring), [[0.0, 0.0, -1.0]]])
    south = len(v) - 1
    f = []
    for i in range(nl):
        j = (i + 1) % nl
        f.append([0, 1 + i, 1 + j])
        last = 1 + (len(lats) - 1) * nl
        f.append([south, last + i, last + j])
        for r in range(len(lats) - 1):
            a, b, c, d = 1 + r * nl + i, 1 + r * nl + j, 1 + (r + 1) * nl + j, 1 + (r + 1) * nl + i
            f += [[a, d, c], [a, c, b]]
    return v, _orient_outwards(v, f)


def random_rotation(rng: np.random.Generator) -> np.ndarray:
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def nonuniform_mesh(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Sparse everywhere, very dense in a small cap on the ±180° seam and around the north pole."""
    sparse = rng.normal(size=(150, 3))
    seam = coords.lonlat_to_xyz([180.0, 10.0]) + 0.03 * rng.normal(size=(3000, 3))
    north = coords.lonlat_to_xyz([0.0, 90.0]) + 0.02 * rng.normal(size=(2000, 3))
    poles = [[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]]
    return hull_mesh(np.concatenate([sparse, seam, north, poles]))


def _meshes():
    rng = np.random.default_rng(7)
    out = {f"icosphere{level}": icosphere(level) for level in range(5)}
    v, f = icosphere(3)
    out["icosphere3-rotated"] = (v @ random_rotation(rng).T, f)
    out["hull"] = hull_mesh(rng.normal(size=(600, 3)))
    out["poles-seam"] = uv_sphere(np.arange(-180.0, 180.0, 30.0), [75.0, 40.0, 0.0, -40.0, -75.0])
    # Vertices at pixel centres and meridian edges through pixel centres for widths 8 * odd.
    out["pixel-centres"] = uv_sphere(np.arange(-157.5, 180.0, 45.0), [67.5, 22.5, -22.5, -67.5])
    out["nonuniform"] = nonuniform_mesh(rng)
    return out


MESHES = _meshes()

# --- checks ----------------------------------------------------------------------------------


def _grid_directions(width: int) -> np.ndarray:
    lon, lat = coords.grid_lonlat(width)
    return coords.lonlat_to_xyz(np.stack(np.meshgrid(lon, lat), axis=-1))


def _edge_planes(v, f, face, p):
    """Normalised edge-plane values p · (v_k × v_{k+1}) / |v_k × v_{k+1}| in each given face."""
    a, b, c = v[f[face, 0]], v[f[face, 1]], v[f[face, 2]]
    planes = [np.cross(a, b), np.cross(b, c), np.cross(c, a)]
    return np.stack([np.einsum("...j,...j", p, n) / np.linalg.norm(n, axis=-1) for n in planes], axis=-1)


def _ray_plane_point(v, f, face, p):
    """Where the ray p meets the flat triangle of its face."""
    a, b, c = v[f[face, 0]], v[f[face, 1]], v[f[face, 2]]
    n = np.cross(b - a, c - a)
    return p * (np.einsum("...j,...j", n, a) / np.einsum("...j,...j", n, p))[..., None]


def _check_location(v, f, face, bary, p, atol):
    assert face.min() >= 0 and face.max() < len(f)
    assert _edge_planes(v, f, face, p).min() >= -1e-9  # p lies in its face's cone
    assert bary.min() >= 0
    np.testing.assert_allclose(bary.sum(axis=-1), 1.0, atol=atol)
    q = _ray_plane_point(v, f, face, p)
    point = np.einsum("...i,...ij->...j", bary.astype(np.float64), v[f[face]])
    np.testing.assert_allclose(point, q, atol=atol)  # the barycentrics reproduce the ray-plane point
    # a linear function of xyz is interpolated exactly (up to the barycentrics' rounding)
    g = np.array([[0.3, -1.2], [2.0, 0.5], [-0.7, 1.1]])
    h = np.array([0.25, -3.0])
    np.testing.assert_allclose(interpolate(v @ g + h, f, face, bary), q @ g + h, atol=4 * atol)
    np.testing.assert_allclose(interpolate(v @ g[:, 0], f, face, bary), q @ g[:, 0], atol=4 * atol)


def _agree(v, f, face_a, bary_a, face_b, bary_b, p):
    """Two locations of the same directions agree: same face, or both valid with the same point."""
    same = face_a == face_b
    interior = _edge_planes(v, f, face_a, p).min(axis=-1) > 1e-7  # in no other face's cone
    assert np.all(same[interior])
    other = ~same
    if np.any(other):
        for face in (face_a[other], face_b[other]):
            assert _edge_planes(v, f, face, p[other]).min() >= -1e-9
    point_a = np.einsum("...i,...ij->...j", bary_a.astype(np.float64), v[f[face_a]])
    point_b = np.einsum("...i,...ij->...j", bary_b.astype(np.float64), v[f[face_b]])
    np.testing.assert_allclose(point_a, point_b, atol=1e-6)


# --- locate_grid -------------------------------------------------------------------------------

SMALL_WIDTHS = [8, 10, 24, 40, 64, 256]


@pytest.mark.parametrize("name", list(MESHES))
@pytest.mark.parametrize("width", SMALL_WIDTHS)
def test_grid_every_pixel_in_its_face(name, width):
    v, f = MESHES[name]
    face, bary = locate_grid(v, f, width)
    assert face.shape == (width // 2, width) and face.dtype == np.int32
    assert bary.shape == (width // 2, width, 3) and bary.dtype == np.float32
    p = _grid_directions(width)
    _check_location(v, f, face, bary, p, atol=1e-6)
    # the same directions located one by one
    face_p, bary_p = locate_points(v, f, p)
    assert face_p.shape == face.shape and bary_p.shape == bary.shape
    _check_location(v, f, face_p, bary_p, p, atol=1e-12)
    _agree(v, f, face, bary, face_p, bary_p, p)


# 2-4 s a mesh on a busy 2-core machine: the full suite (the fast loop's warps at 1024 and 2048 locate their grids too)
@pytest.mark.slow
@pytest.mark.parametrize("name", ["icosphere4", "nonuniform", "poles-seam"])
def test_grid_width_2048(name, rng):
    v, f = MESHES[name]
    face, bary = locate_grid(v, f, 2048)
    p = _grid_directions(2048)
    _check_location(v, f, face, bary, p, atol=1e-6)
    rows, cols = rng.integers(0, 1024, 20000), rng.integers(0, 2048, 20000)
    rows[:2048], cols[:2048] = 0, np.arange(2048)  # the row nearest the north pole
    face_p, bary_p = locate_points(v, f, p[rows, cols])
    _agree(v, f, face[rows, cols], bary[rows, cols], face_p, bary_p, p[rows, cols])


def test_grid_pixels_on_vertices_and_edges():
    """Pixel centres exactly on mesh vertices and meridian edges still get a valid face."""
    v, f = MESHES["pixel-centres"]
    for width in (8, 24, 40, 120):
        face, bary = locate_grid(v, f, width)
        p = _grid_directions(width)
        on_vertex = np.isclose(bary.max(axis=-1), 1.0, atol=1e-6)
        on_edge = np.any(bary < 1e-6, axis=-1)
        assert on_vertex.any() and on_edge.any()
        _check_location(v, f, face, bary, p, atol=1e-6)


def test_grid_pixels_missed_by_the_runs_are_located_one_by_one(monkeypatch):
    import omniwidget.method.locate as locate

    runs = locate._runs

    def every_other_run(*args):
        return tuple(a[::2] for a in runs(*args))

    monkeypatch.setattr(locate, "_runs", every_other_run)
    v, f = MESHES["nonuniform"]
    face, bary = locate_grid(v, f, 64)
    _check_location(v, f, face, bary, _grid_directions(64), atol=1e-6)


def test_zero_area_face_is_never_returned():
    """A face whose three vertices lie on one great circle (a vertex added on an edge) spans no solid angle."""
    v, f = MESHES["pixel-centres"]
    a, b, c = f[0]  # the edge a -> b runs from the north pole down a meridian through pixel centres
    assert a == 0 and np.isclose(coords.xyz_to_lonlat(v[b])[0], -157.5)
    v = np.concatenate([v, [(v[a] + v[b]) / np.linalg.norm(v[a] + v[b])]])
    m = len(v) - 1
    f = np.concatenate([f[1:], [[a, m, c], [m, b, c], [b, m, a]]])
    degenerate = len(f) - 1
    for width in (2, 8, 24, 40):
        face, bary = locate_grid(v, f, width)
        assert not np.any(face == degenerate)
        _check_location(v, f, face, bary, _grid_directions(width), atol=1e-6)
    p = coords.lonlat_to_xyz([coords.xyz_to_lonlat(v[m])])
    face, bary = locate_points(v, f, np.concatenate([p, v[[a, b, m]]]))
    assert not np.any(face == degenerate)


def test_grid_is_deterministic_and_independent_of_face_order(rng):
    v, f = MESHES["hull"]
    face, bary = locate_grid(v, f, 128)
    face2, bary2 = locate_grid(v, f, 128)
    np.testing.assert_array_equal(face, face2)
    np.testing.assert_array_equal(bary, bary2)
    order = rng.permutation(len(f))
    face3, bary3 = locate_grid(v, f[order], 128)
    _agree(v, f, face, bary, order[face3], bary3, _grid_directions(128))


def test_grid_values_continuous_across_the_seam_and_at_vertices():
    v, f = MESHES["poles-seam"]
    values = np.sin(3 * v[:, 0]) + v[:, 2] ** 2
    w = interpolate(values, f, *locate_grid(v, f, 720))
    # first and last columns are neighbours across the seam: no jump beyond the smooth change
    assert np.abs(w[:, 0] - w[:, -1]).max() < 0.05
    face, bary = locate_points(v, f, v)
    np.testing.assert_allclose(interpolate(values, f, face, bary), values, atol=1e-12)


# --- locate_points -------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["icosphere0", "icosphere4", "hull", "poles-seam", "nonuniform"])
def test_points_random_directions(name, rng):
    v, f = MESHES[name]
    p = rng.normal(size=(5000, 3))
    face, bary = locate_points(v, f, p)
    assert face.dtype == np.int32 and bary.dtype == np.float64
    unit = p / np.linalg.norm(p, axis=1, keepdims=True)
    _check_location(v, f, face, bary, unit, atol=1e-12)
    face3, bary3 = locate_points(v, f, 3.0 * p)  # only the direction counts
    np.testing.assert_array_equal(face3, face)
    np.testing.assert_allclose(bary3, bary, atol=1e-14)


def test_points_far_from_the_nearest_centroids():
    """In a huge face beside a dense cluster, the nearest centroids all belong to small faces."""
    rng = np.random.default_rng(3)
    dense = coords.lonlat_to_xyz([0.0, 0.0]) + 0.01 * rng.normal(size=(400, 3))
    v, f = hull_mesh(np.concatenate([dense, [[0, 0, 1], [0, 0, -1], [-1, 0, 0], [0, 1, 0], [0, -1, 0]]]))
    lonlat = np.stack(np.meshgrid(np.linspace(-5, 5, 41), np.linspace(-5, 5, 41)), axis=-1).reshape(-1, 2)
    p = coords.lonlat_to_xyz(lonlat)
    face, bary = locate_points(v, f, p)
    _check_location(v, f, face, bary, p, atol=1e-12)


def test_points_shapes_and_vertices():
    v, f = MESHES["icosphere2"]
    face, bary = locate_points(v, f, v[:12].reshape(3, 4, 3))
    assert face.shape == (3, 4) and bary.shape == (3, 4, 3)
    np.testing.assert_allclose(bary.max(axis=-1), 1.0, atol=1e-12)
    face, bary = locate_points(v, f, np.zeros((0, 3)))
    assert face.shape == (0,) and bary.shape == (0, 3)


# --- interpolate -------------------------------------------------------------------------------


def test_interpolate_dtypes_and_shapes():
    v, f = MESHES["icosphere1"]
    face, bary = locate_grid(v, f, 16)
    w32 = np.ones((len(v), 4), np.float32)
    out = interpolate(w32, f, face, bary)
    assert out.shape == (8, 16, 4) and out.dtype == np.float32
    np.testing.assert_allclose(out, 1.0, atol=1e-6)
    out = interpolate(np.ones(len(v)), f, face[2:5], bary[2:5])
    assert out.shape == (3, 16) and out.dtype == np.float64
    with pytest.raises(ValueError, match="bary must have shape"):
        interpolate(w32, f, face, bary[..., :2])
    with pytest.raises(ValueError, match="values"):
        interpolate(w32[:5], f, face, bary)
    with pytest.raises(ValueError, match="face indices"):
        interpolate(w32, f, face + len(f), bary)


# --- input validation ------------------------------------------------------------------------


def test_rejects_bad_meshes():
    v, f = icosphere(1)
    with pytest.raises(ValueError, match="unit vectors"):
        locate_grid(2 * v, f, 16)
    with pytest.raises(ValueError, match="shape"):
        locate_grid(v[:, :2], f, 16)
    with pytest.raises(ValueError, match="integer"):
        locate_grid(v, f.astype(float), 16)
    with pytest.raises(ValueError, match="indices"):
        locate_grid(v, f + 1, 16)
    with pytest.raises(ValueError, match="repeats a vertex"):
        locate_grid(v, np.concatenate([f, [[0, 0, 1]]]), 16)
    flipped = f.copy()
    flipped[5] = flipped[5, ::-1]
    with pytest.raises(ValueError, match="oriented inwards"):
        locate_grid(v, flipped, 16)
    with pytest.raises(ValueError, match="oriented inwards"):
        locate_points(v, f[:, ::-1], v)
    with pytest.raises(ValueError, match="not closed"):
        locate_grid(v, f[1:], 16)
    with pytest.raises(ValueError, match="same direction"):
        locate_grid(v, np.concatenate([f, f[:1]]), 16)
    twice = (np.concatenate([v, v]), np.concatenate([f, f + len(v)]))
    with pytest.raises(ValueError, match="cover the sphere 2 times"):
        locate_grid(*twice, 16)


def test_rejects_bad_widths_and_directions():
    v, f = icosphere(1)
    for width in (0, 7, 2.0, True):
        with pytest.raises(ValueError, match="width"):
            locate_grid(v, f, width)
    with pytest.raises(ValueError, match="zero vector"):
        locate_points(v, f, [[1, 0, 0], [0, 0, 0]])
    with pytest.raises(ValueError, match="finite"):
        locate_points(v, f, [[np.nan, 0, 1]])
    with pytest.raises(ValueError, match=r"\(\.\.\., 3\)"):
        locate_points(v, f, [[1, 0]])


def test_import_does_not_load_scipy():
    code = "import sys, omniwidget.method.locate; print('scipy' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()
    assert out == "False"
