import numpy as np
import pytest

from omniwidget.raster.warping import grid_inverse, inverse_lonlat
from omniwidget.sphere import coords
from omniwidget.sphere.moebius import Moebius

from .conftest import random_lonlat

POLES_AND_SEAM = [
    # north pole = the projection point (z = ∞), south pole (z = 0), both sides of the seam
    [[0, 90], [0, -90], [180, 0]],
    [[-180, 0], [179.9999, 0.5], [0, 90]],
    [[45, 90 - 1e-9], [-45, -90 + 1e-9], [-180, 45]],
    [[0, 0], [90, 0], [180, 0]],
]


def _mapped_error(src, dst) -> float:
    m = Moebius.from_points(src, dst)
    return float(np.max(np.linalg.norm(m.apply_xyz(coords.lonlat_to_xyz(src)) - coords.lonlat_to_xyz(dst), axis=1)))


def test_three_random_pairs_are_mapped_exactly(rng):
    for _ in range(300):
        src, dst = random_lonlat(rng, 3), random_lonlat(rng, 3)
        assert _mapped_error(src, dst) < 1e-9  # unit vectors: absolute = relative


@pytest.mark.parametrize("src", POLES_AND_SEAM)
@pytest.mark.parametrize("dst", POLES_AND_SEAM[::-1])
def test_three_pairs_at_poles_seam_and_projection_pole(src, dst):
    assert _mapped_error(src, dst) < 1e-9


def test_identity_and_coincident_points():
    pts = [[10, 10], [20, -5], [-100, 60]]
    assert Moebius.from_points(pts, pts).is_identity(1e-12)
    with pytest.raises(ValueError, match="source points coincide"):
        Moebius.from_points([[10, 10], [10, 10], [0, 0]], pts)
    with pytest.raises(ValueError, match="target points coincide"):
        Moebius.from_points(pts, [[0, 90], [180, 90], [0, 0]])  # the pole at any longitude is one point
    with pytest.raises(ValueError, match="invertible"):
        Moebius([[1, 2], [2, 4]])


def test_inverse_and_composition(rng):
    a = Moebius.from_points(random_lonlat(rng, 3), random_lonlat(rng, 3))
    b = Moebius.point_map([30, -20], [100, 45], 2.5, 40)
    p = np.concatenate([random_lonlat(rng, 2000), [[0, 90], [0, -90], [180, 0], [-180, 33]]])
    xyz = coords.lonlat_to_xyz(p)
    np.testing.assert_allclose(a.apply_xyz(a.inverse.apply_xyz(xyz)), xyz, atol=1e-12)
    np.testing.assert_allclose((a @ b).apply_xyz(xyz), a.apply_xyz(b.apply_xyz(xyz)), atol=1e-12)
    assert (a @ a.inverse).is_identity(1e-12)


def test_no_nan_or_inf_anywhere_on_the_sphere():
    m = Moebius.from_points([[0, 90], [180, 0], [0, -90]], [[-180, 0], [0, 90], [90, 0]])
    lon = np.linspace(-180, 180, 721)
    lat = np.linspace(-90, 90, 361)
    grid = np.stack(np.meshgrid(lon, lat), axis=-1)
    for f in (m, m.inverse):
        out = f(grid)
        assert np.all(np.isfinite(out))
        assert np.all((out[..., 0] >= -180) & (out[..., 0] < 180) & (np.abs(out[..., 1]) <= 90))
    fast = inverse_lonlat(grid_inverse(m), 256)  # the warp's per-pixel path agrees with the reference path
    lon_c, lat_c = coords.grid_lonlat(256)
    slow = m(np.stack(np.meshgrid(lon_c, lat_c), axis=-1))
    assert np.all(np.isfinite(fast))
    assert coords.angular_distance(fast, slow).max() < 1e-9


def test_rotation_matches_the_rotation_matrix():
    m = Moebius.rotation([0, 90], 90)  # about the north pole, counter-clockwise from outside
    np.testing.assert_allclose(m([[0, 0], [90, 0], [10, 50]]), [[90, 0], [-180, 0], [100, 50]], atol=1e-12)
    rot = Moebius.rotation([35, 20], 73)
    assert rot.local_scale_rotation([35, 20]) == pytest.approx((1.0, 73.0))


@pytest.mark.parametrize(
    ("position", "target", "scale", "rotation"),
    [
        ([10, 20], [30, -10], 2.0, 30.0),
        ([170, 5], [-170, -5], 0.5, -120.0),
        ([0, 89.99], [60, 10], 1.0, 0.0),
        ([20, -90], [-45, 90], 3.0, 10.0),
    ],
)
def test_point_map_sends_centre_and_antipode_and_has_the_asked_derivative(position, target, scale, rotation):
    m = Moebius.point_map(position, target, scale, rotation)
    antipode = lambda ll: coords.xyz_to_lonlat(-coords.lonlat_to_xyz(ll))  # noqa: E731
    assert coords.angular_distance(m(np.array(position, float)), target) < 1e-9
    assert coords.angular_distance(m(antipode(position)), antipode(target)) < 1e-9
    s, r = m.local_scale_rotation(position)
    if abs(target[1]) < 90:  # at a pole "east" depends on the longitude used to name it
        assert s == pytest.approx(scale, rel=1e-12)
        assert r == pytest.approx(rotation, abs=1e-9)


def test_translation_looks_like_a_shift():
    m = Moebius.translation([0, 0], [40, 0])
    np.testing.assert_allclose(m([[0, 0], [10, 0], [0, 30]]), [[40, 0], [50, 0], [40, 30]], atol=1e-12)
