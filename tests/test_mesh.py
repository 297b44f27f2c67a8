"""The adaptive sphere mesh of Sec. 3.5: icosphere, refinement near samples, convex-hull connectivity."""

import dataclasses
import subprocess
import sys

import numpy as np
import pytest

from omniwidget.method.mesh import MERGE_CHORD, SphereMesh, adaptive_mesh, default_thresholds, icosphere, triangle_angles
from omniwidget.sphere import coords

#: Smallest triangle angle (degrees) accepted for realistic sample sets: lines of 50 samples
#: at least ~20 degrees long. Measured: 7.5 degrees for the twelve-handle scene below.
MIN_ANGLE = 5.0


# --- helpers ---------------------------------------------------------------------------------
def arc(start, end, n: int = 50) -> np.ndarray:
    """``n`` samples of the spherical bone from ``start`` to ``end`` ([lon, lat]) as unit vectors."""
    return coords.lonlat_to_xyz(coords.geodesic(start, end, np.linspace(0.0, 1.0, n)))


def twelve_handles() -> np.ndarray:
    """8 lines x 50 samples, a 4-vertex cage with 4 edges x 50 samples, 2 point handles: (602, 3)."""
    lines = [
        ([-170, 10], [170, -5]),  # across the seam
        ([-60, -20], [20, -25]),
        ([100, 60], [-170, 75]),  # near the north pole
        ([30, -70], [150, -80]),  # near the south pole
        ([-120, 0], [-120, 40]),
        ([-90, 30], [-40, 35]),
        ([60, 10], [90, 45]),
        ([120, -10], [160, -30]),
    ]
    cage = [[0, 0], [25, 0], [25, 20], [0, 20]]
    parts = [arc(a, b) for a, b in lines]
    parts += [arc(cage[i], cage[(i + 1) % 4]) for i in range(4)]  # corners appear twice
    parts.append(coords.lonlat_to_xyz([[-150, -40], [170, 50]]))
    return np.concatenate(parts)


@pytest.fixture(scope="module")
def scene() -> tuple[np.ndarray, SphereMesh]:
    samples = twelve_handles()
    return samples, adaptive_mesh(samples)


def undirected_edges(faces: np.ndarray) -> np.ndarray:
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    return np.sort(e, axis=1)


def solid_angles(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Signed solid angle of each face seen from the centre (Van Oosterom & Strackee)."""
    a, b, c = (vertices[faces[:, i]] for i in range(3))
    num = np.einsum("ij,ij->i", a, np.cross(b, c))
    den = 1 + np.einsum("ij,ij->i", a, b) + np.einsum("ij,ij->i", b, c) + np.einsum("ij,ij->i", c, a)
    return 2 * np.arctan2(num, den)


def assert_closed_sphere_mesh(vertices: np.ndarray, faces: np.ndarray) -> None:
    """Unit vertices, all used; closed, consistently and outwardly oriented; covers the sphere once."""
    assert vertices.dtype == np.float64 and vertices.ndim == 2 and vertices.shape[1] == 3
    assert faces.dtype == np.int64 and faces.ndim == 2 and faces.shape[1] == 3
    n, m = len(vertices), len(faces)
    np.testing.assert_allclose(np.linalg.norm(vertices, axis=1), 1.0, atol=1e-14)
    assert np.array_equal(np.unique(faces), np.arange(n)), "every vertex belongs to a face"
    assert np.all((faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 2] != faces[:, 0]))
    # closed 2-manifold: every undirected edge in exactly two faces ...
    _, counts = np.unique(undirected_edges(faces), axis=0, return_counts=True)
    assert np.all(counts == 2)
    # ... traversed once in each direction (consistent orientation)
    directed = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    assert len(np.unique(directed, axis=0)) == 3 * m
    assert n - len(counts) + m == 2, "Euler characteristic of the sphere"
    # outward: det[a, b, c] > 0, i.e. normal . centroid > 0
    a, b, c = (vertices[faces[:, i]] for i in range(3))
    assert np.all(np.einsum("ij,ij->i", np.cross(b - a, c - a), a + b + c) > 0)
    # the spherical triangles tile the sphere exactly once (no fold-overs)
    omega = solid_angles(vertices, faces)
    assert np.all(omega > 0)
    assert np.sum(omega) == pytest.approx(4 * np.pi, rel=1e-12)


def assert_samples_are_vertices(mesh: SphereMesh, samples: np.ndarray, atol: float = 1e-15) -> None:
    assert mesh.sample_index.dtype == np.int64 and mesh.sample_index.shape == (len(samples),)
    assert np.all((0 <= mesh.sample_index) & (mesh.sample_index < mesh.n_vertices))
    np.testing.assert_allclose(mesh.vertices[mesh.sample_index], samples, rtol=0, atol=atol)


def vertex_spacing(mesh: SphereMesh) -> np.ndarray:
    """Mean length (degrees) of the edges at each vertex."""
    e = np.unique(undirected_edges(mesh.faces), axis=0)
    length = np.degrees(np.linalg.norm(mesh.vertices[e[:, 0]] - mesh.vertices[e[:, 1]], axis=1))
    total = np.bincount(e.ravel(), weights=np.repeat(length, 2), minlength=mesh.n_vertices)
    return total / np.bincount(e.ravel(), minlength=mesh.n_vertices)


def distance_to_samples(points: np.ndarray, samples: np.ndarray) -> np.ndarray:
    """Angle in degrees from each point to its nearest sample."""
    return np.degrees(np.arccos(np.clip(np.max(points @ samples.T, axis=1), -1, 1)))


# --- icosphere -------------------------------------------------------------------------------
@pytest.mark.parametrize("level", [0, 1, 2, 3, 4])
def test_icosphere_counts_and_closed_outward_manifold(level):
    vertices, faces = icosphere(level)
    assert vertices.shape == (10 * 4**level + 2, 3)
    assert faces.shape == (20 * 4**level, 3)
    assert_closed_sphere_mesh(vertices, faces)
    # the subdivided icosahedron stays well shaped (54.0 degrees at level 4)
    assert np.min(triangle_angles(vertices, faces)) > 50


def test_icosphere_level_zero_is_the_regular_icosahedron():
    vertices, faces = icosphere(0)
    lengths = np.linalg.norm(vertices[faces] - np.roll(vertices[faces], 1, axis=1), axis=-1)
    np.testing.assert_allclose(lengths, lengths[0, 0], rtol=1e-14)
    np.testing.assert_allclose(triangle_angles(vertices, faces), 60.0, atol=1e-12)


def test_icosphere_levels_are_nested():
    coarse, _ = icosphere(2)
    fine, _ = icosphere(3)
    assert np.array_equal(fine[: len(coarse)], coarse)


@pytest.mark.parametrize("level", [-1, 1.5, True, "2"])
def test_icosphere_rejects_bad_levels(level):
    with pytest.raises(ValueError, match="level must be a non-negative integer"):
        icosphere(level)


def test_triangle_angles_sum_to_180():
    vertices, faces = icosphere(2)
    np.testing.assert_allclose(triangle_angles(vertices, faces).sum(axis=1), 180.0, atol=1e-12)
    with pytest.raises(ValueError, match=r"expected vertices \(n, 3\) and faces \(m, 3\)"):
        triangle_angles(vertices[:, :2], faces)


# --- the twelve-handle scene -----------------------------------------------------------------
def test_realistic_scene_is_closed_outward_and_has_samples_as_vertices(scene):
    samples, mesh = scene
    assert_closed_sphere_mesh(mesh.vertices, mesh.faces)
    assert_samples_are_vertices(mesh, samples)
    # the cage's 4 corners are given twice: 602 samples, 598 distinct sample vertices
    assert len(np.unique(mesh.sample_index)) == 598
    # "a few thousand" vertices (measured: 3265 vertices, 6526 faces)
    assert 1000 < mesh.n_vertices < 6000
    assert mesh.n_faces == 2 * mesh.n_vertices - 4


def test_realistic_scene_has_no_thin_triangles(scene):
    _, mesh = scene
    # measured 7.5 degrees, at the 20-degree cage edge (samples 0.4 degrees apart, next
    # refinement vertex about 2.8 degrees away)
    assert mesh.min_angle_degrees() > MIN_ANGLE
    assert np.median(mesh.triangle_angles().min(axis=1)) > 45


def test_realistic_scene_is_denser_near_the_samples(scene):
    samples, mesh = scene
    spacing = vertex_spacing(mesh)
    distance = distance_to_samples(mesh.vertices, samples)
    near = spacing[distance < 3].mean()
    far = spacing[distance > 25].mean()
    assert np.sum(distance > 25) > 10
    assert far > 5 * near, (near, far)  # measured: about 1 vs 13 degrees
    # and no refinement vertex crowds a sample: the closest is a good part of an edge away
    refinement = np.setdiff1d(np.arange(mesh.n_vertices), mesh.sample_index)
    assert distance_to_samples(mesh.vertices[refinement], samples).min() > 0.3


def test_rounds_show_the_refinement_stage_by_stage(scene):
    samples, mesh = scene
    assert len(mesh.rounds) == 5
    base_vertices, base_faces = icosphere(1)
    assert np.array_equal(mesh.rounds[0][0], base_vertices)
    assert np.array_equal(mesh.rounds[0][1], base_faces)
    previous = None
    for vertices, faces in mesh.rounds:
        np.testing.assert_allclose(np.linalg.norm(vertices, axis=1), 1.0, atol=1e-14)
        assert faces.dtype == np.int64 and faces.min() >= 0 and faces.max() < len(vertices)
        a, b, c = (vertices[faces[:, i]] for i in range(3))
        assert np.all(np.einsum("ij,ij->i", np.cross(b - a, c - a), a) > 0)  # outward, like the parent
        # the split triangles tile the sphere once (T-junctions do not change that)
        assert np.sum(solid_angles(vertices, faces)) == pytest.approx(4 * np.pi, rel=1e-12)
        if previous is not None:
            assert len(vertices) > len(previous)  # this scene refines in every round
            assert np.array_equal(vertices[: len(previous)], previous)  # vertices only get added
            assert len(np.unique(vertices, axis=0)) == len(vertices)  # midpoints are shared, not duplicated
        previous = vertices


def test_arrays_are_read_only_and_the_mesh_is_frozen(scene):
    _, mesh = scene
    for array in (mesh.vertices, mesh.faces, mesh.sample_index, *mesh.rounds[-1]):
        assert not array.flags.writeable
    with pytest.raises(dataclasses.FrozenInstanceError):
        mesh.vertices = mesh.vertices  # type: ignore[misc]


# --- seam, poles, special positions -----------------------------------------------------------
SAMPLE_SETS = {
    "arc across the seam": arc([165, -10], [-160, 15]),
    "arc on the seam meridian": arc([180, -40], [180, 40]),
    "arc near the north pole": arc([0, 80], [120, 82]),
    "arc through the north pole": arc([30, 70], [-150, 70]),
    "arc through the south pole": arc([0, -60], [180, -60]),
    "arc across seam and near the south pole": arc([150, -75], [-120, -85]),
    "long arc": arc([-80, 5], [80, -5]),
    "points at poles and seam": coords.lonlat_to_xyz([[0, 90], [0, -90], [-180, 0], [179.5, 20], [-179.5, -20]]),
    "arcs and points": np.concatenate([arc([-30, 0], [10, 0]), arc([-10, -20], [-10, 20]), coords.lonlat_to_xyz([[100, 0], [-100, 30]])]),
}


@pytest.mark.parametrize("name", list(SAMPLE_SETS))
def test_sample_sets_at_poles_and_seam(name):
    samples = SAMPLE_SETS[name]
    mesh = adaptive_mesh(samples)
    assert_closed_sphere_mesh(mesh.vertices, mesh.faces)
    assert_samples_are_vertices(mesh, samples)
    assert mesh.min_angle_degrees() > MIN_ANGLE  # measured >= 7.5 over these sets


def test_arc_through_the_pole_has_the_pole_as_a_vertex():
    samples = SAMPLE_SETS["arc through the north pole"]
    assert np.allclose(samples[24:26], [0, 0, 1], atol=0.05)  # the arc passes over the pole
    mesh = adaptive_mesh(coords.lonlat_to_xyz([[0, 90]]))
    assert_samples_are_vertices(mesh, np.array([[0.0, 0.0, 1.0]]), atol=1e-16)


def test_crossing_arcs_share_one_vertex_at_their_intersection():
    # two bones broken at their crossing point, as the interface does: the joint is a sample of both
    samples = np.concatenate([arc([-20, 0], [0, 0]), arc([0, 0], [20, 0]), arc([0, -20], [0, 0]), arc([0, 0], [0, 20])])
    mesh = adaptive_mesh(samples)
    assert_closed_sphere_mesh(mesh.vertices, mesh.faces)
    joint = mesh.sample_index[[49, 50, 149, 150]]
    assert np.all(joint == joint[0])
    assert mesh.n_vertices == len(np.unique(mesh.sample_index)) + np.sum(~np.isin(np.arange(mesh.n_vertices), mesh.sample_index))


# --- guards ----------------------------------------------------------------------------------
def test_duplicate_samples_are_merged():
    base = SAMPLE_SETS["arcs and points"]
    jitter = base + 1e-11 * np.random.default_rng(1).normal(size=base.shape)  # far below MERGE_CHORD
    jitter /= np.linalg.norm(jitter, axis=1, keepdims=True)
    samples = np.concatenate([base, base[::-1], jitter])
    once, thrice = adaptive_mesh(base), adaptive_mesh(samples)
    k = len(base)
    assert thrice.n_vertices == once.n_vertices
    assert np.array_equal(thrice.sample_index[:k], thrice.sample_index[k : 2 * k][::-1])
    assert np.array_equal(thrice.sample_index[:k], thrice.sample_index[2 * k :])
    assert_samples_are_vertices(thrice, samples, atol=MERGE_CHORD)
    np.testing.assert_array_equal(thrice.vertices[thrice.sample_index[:k]], base)  # the first one is kept
    assert_closed_sphere_mesh(thrice.vertices, thrice.faces)


def test_samples_on_both_sides_of_the_seam_are_merged():
    samples = coords.lonlat_to_xyz([[-180, 10], [180 - 1e-9, 10], [-180 + 1e-9, 10]])  # 1.7e-11 rad apart
    mesh = adaptive_mesh(samples)
    assert len(set(mesh.sample_index.tolist())) == 1
    assert_samples_are_vertices(mesh, samples, atol=MERGE_CHORD)
    assert_closed_sphere_mesh(mesh.vertices, mesh.faces)


def test_samples_just_above_the_merge_tolerance_stay_apart():
    p = coords.lonlat_to_xyz([[40.0, 10.0]])
    east, _ = coords.local_frame([40.0, 10.0])
    q = p + 1e-6 * east
    q /= np.linalg.norm(q)
    mesh = adaptive_mesh(np.concatenate([p, q]))
    assert mesh.sample_index[0] != mesh.sample_index[1]
    assert_samples_are_vertices(mesh, np.concatenate([p, q]))
    assert_closed_sphere_mesh(mesh.vertices, mesh.faces)


@pytest.mark.parametrize("level", [0, 3])
def test_sample_on_a_refinement_vertex_reuses_it(level):
    # an icosahedron vertex (level 0) and an edge midpoint made in the refinement (level 3)
    target = icosphere(level)[0][-1]
    samples = np.concatenate([arc([-30, 10], [30, 10]), target[None]])
    mesh = adaptive_mesh(samples)
    assert_closed_sphere_mesh(mesh.vertices, mesh.faces)
    assert np.array_equal(mesh.vertices[mesh.sample_index[-1]], target)
    # exactly one vertex there, and none crowding it
    distance = np.degrees(np.linalg.norm(mesh.vertices - target, axis=1))
    assert np.sum(distance < 0.3) == 1
    assert mesh.min_angle_degrees() > MIN_ANGLE


def test_refinement_vertex_close_to_a_sample_is_replaced_by_it():
    vertex = icosphere(0)[0][5]
    east, _ = coords.local_frame(coords.xyz_to_lonlat(vertex))
    sample = vertex + 1e-4 * east  # 0.006 degrees from an icosahedron vertex
    sample /= np.linalg.norm(sample)
    mesh = adaptive_mesh(sample[None])
    assert np.sum(np.linalg.norm(mesh.vertices - sample, axis=1) < 0.005) == 1
    assert_samples_are_vertices(mesh, sample[None])
    assert mesh.min_angle_degrees() > 20


def test_samples_closer_than_qhull_can_resolve_still_map_to_a_vertex():
    # 50 samples on a line 1e-4 degrees long (about 4e-8 rad apart): qhull merges some of them
    samples = arc([10, 20], [10.0001, 20.00003])
    mesh = adaptive_mesh(samples)
    assert_closed_sphere_mesh(mesh.vertices, mesh.faces)
    assert_samples_are_vertices(mesh, samples, atol=1e-6)


@pytest.mark.parametrize("empty", [np.empty((0, 3)), [], np.empty(0)])
def test_empty_samples_give_the_base_icosphere(empty):
    mesh = adaptive_mesh(empty, base_level=2, rounds=3)
    vertices, faces = icosphere(2)
    assert np.array_equal(mesh.vertices, vertices) and np.array_equal(mesh.faces, faces)
    assert mesh.sample_index.shape == (0,) and mesh.sample_index.dtype == np.int64
    assert mesh.n_samples == 0 and mesh.n_vertices == 162 and mesh.n_faces == 320
    assert len(mesh.rounds) == 4 and all(np.array_equal(v, vertices) for v, _ in mesh.rounds)


# --- parameters --------------------------------------------------------------------------------
def test_default_thresholds_halve_each_round_from_one_and_a_half_edges():
    t = default_thresholds(1, 4)
    assert len(t) == 4
    np.testing.assert_allclose(np.array(t[1:]) / np.array(t[:-1]), 0.5)
    assert 45 < t[0] < 55  # 1.5 mean edges of icosphere(1), whose edges are about 34 degrees
    assert default_thresholds(0, 2)[0] == pytest.approx(2 * default_thresholds(1, 1)[0], rel=0.1)


def test_threshold_and_rounds_control_the_refinement():
    samples = arc([-20, 0], [20, 10])
    default = adaptive_mesh(samples)
    wider = adaptive_mesh(samples, threshold=2 * default_thresholds()[0])
    explicit = adaptive_mesh(samples, threshold=list(default_thresholds()))
    assert wider.n_vertices > default.n_vertices
    assert np.array_equal(explicit.vertices, default.vertices) and np.array_equal(explicit.faces, default.faces)
    few = adaptive_mesh(samples, rounds=2)
    none = adaptive_mesh(samples, rounds=0)
    assert none.n_vertices < few.n_vertices < default.n_vertices
    assert len(none.rounds) == 1 and len(few.rounds) == 3
    for mesh in (wider, few, none):
        assert_closed_sphere_mesh(mesh.vertices, mesh.faces)
        assert_samples_are_vertices(mesh, samples)


@pytest.mark.parametrize(
    ("samples", "kwargs", "match"),
    [
        (np.ones((4, 2)), {}, r"shape \(k, 3\)"),
        (np.array([1.0, 0.0, 0.0]), {}, r"shape \(k, 3\)"),
        (np.array([[2.0, 0.0, 0.0]]), {}, "sample 0 has norm 2"),
        (np.array([[np.nan, 0.0, 1.0]]), {}, "finite"),
        (np.array([[1.0, 0.0, 0.0]]), {"rounds": -1}, "rounds must be a non-negative integer"),
        (np.array([[1.0, 0.0, 0.0]]), {"base_level": 1.0}, "base_level must be a non-negative integer"),
        (np.array([[1.0, 0.0, 0.0]]), {"threshold": 0.0}, "positive finite"),
        (np.array([[1.0, 0.0, 0.0]]), {"threshold": [10.0, 5.0]}, "one number per round"),
    ],
)
def test_bad_input_is_rejected_with_a_clear_message(samples, kwargs, match):
    with pytest.raises(ValueError, match=match):
        adaptive_mesh(samples, **kwargs)


def test_importing_the_module_does_not_load_scipy():
    code = "import sys, omniwidget.method.mesh; print('scipy' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()
    assert out == "False"
