import numpy as np
import pytest

from omniwidget.sphere import coords

from .conftest import random_lonlat


def test_pixel_centres_follow_the_written_convention():
    lon, lat = coords.grid_lonlat(8)
    np.testing.assert_allclose(lon, -180 + (np.arange(8) + 0.5) * 45)
    np.testing.assert_allclose(lat, 90 - (np.arange(4) + 0.5) * 45)
    np.testing.assert_allclose(coords.px_to_lonlat([[0, 0], [7, 3]], 8), [[-157.5, 67.5], [157.5, -67.5]])
    np.testing.assert_allclose(coords.lonlat_to_px([[-180, 90], [180, -90]], 8), [[-0.5, -0.5], [7.5, 3.5]])


def test_pixels_and_lonlat_round_trip(rng):
    px = rng.uniform([-0.5, -0.5], [2047.5, 1023.5], size=(1000, 2))
    np.testing.assert_allclose(coords.lonlat_to_px(coords.px_to_lonlat(px, 2048), 2048), px, atol=1e-9)


def test_direction_convention():
    np.testing.assert_allclose(
        coords.lonlat_to_xyz([[0, 0], [90, 0], [0, 90], [180, -90]]), [[1, 0, 0], [0, 1, 0], [0, 0, 1], [0, 0, -1]], atol=1e-15
    )


def test_xyz_round_trip_keeps_precision_near_the_poles(rng):
    ll = random_lonlat(rng, 1000)
    np.testing.assert_allclose(coords.xyz_to_lonlat(coords.lonlat_to_xyz(ll)), ll, atol=1e-10)
    near_pole = np.array([[37.0, 90 - 1e-9], [-120.0, -90 + 1e-9]])
    np.testing.assert_allclose(coords.xyz_to_lonlat(coords.lonlat_to_xyz(near_pole)), near_pole, atol=1e-12)


def test_wrap_and_unwrap_longitude():
    np.testing.assert_array_equal(coords.wrap_lon([180.0, -180.0, 540.0, 179.5, -360.0]), [-180.0, -180.0, -180.0, 179.5, 0.0])
    tiny = coords.wrap_lon([-1e-300, 1e-300, 180 - 1e-13])
    assert np.all((tiny >= -180) & (tiny < 180))
    assert coords.unwrap_lon(-170.0, 175.0) == pytest.approx(190.0)
    assert coords.unwrap_lon(170.0, -175.0) == pytest.approx(-190.0)


def test_homogeneous_stereographic_is_finite_and_exact_everywhere(rng):
    special = np.array([[0, 90], [0, -90], [180, 0], [-180, 0], [90, 89.999999], [0, 0]], dtype=float)
    ll = np.concatenate([random_lonlat(rng, 500), special])
    u, v = coords.xyz_to_homogeneous(coords.lonlat_to_xyz(ll))
    assert np.all(np.isfinite(u)) and np.all(np.isfinite(v))
    assert np.all(np.maximum(abs(u), abs(v)) >= 1 - 1e-12)  # well conditioned: never near [0 : 0]
    back = coords.homogeneous_to_xyz(u, v)
    np.testing.assert_allclose(back, coords.lonlat_to_xyz(ll), atol=1e-15)
    z = coords.stereographic([[0, -90], [0, 90], [0, 0], [90, 0]])
    assert abs(z[0]) < 1e-16 and abs(z[1]) > 1e15  # cos(90°) is 6e-17 in floating point
    np.testing.assert_allclose(z[2:], [1, 1j], atol=1e-15)
    np.testing.assert_allclose(coords.inverse_stereographic(z), [[0, -90], [0, 90], [0, 0], [90, 0]], atol=1e-12)


def test_local_frame_is_orthonormal_and_right_handed_at_the_poles_too(rng):
    ll = np.concatenate([random_lonlat(rng, 200), [[30, 90], [-60, -90]]])
    east, north = coords.local_frame(ll)
    p = coords.lonlat_to_xyz(ll)
    np.testing.assert_allclose(np.cross(east, north), p, atol=1e-15)
    np.testing.assert_allclose(np.sum(east * north, axis=1), 0, atol=1e-15)
    np.testing.assert_allclose(np.linalg.norm(east, axis=1), 1)


def test_east_is_the_direction_of_increasing_longitude():
    east, north = coords.local_frame([20.0, 40.0])
    step = coords.lonlat_to_xyz([20.001, 40.0]) - coords.lonlat_to_xyz([20.0, 40.0])
    assert np.dot(step, east) > 0.99 * np.linalg.norm(step)
    step = coords.lonlat_to_xyz([20.0, 40.001]) - coords.lonlat_to_xyz([20.0, 40.0])
    assert np.dot(step, north) > 0.99 * np.linalg.norm(step)


def test_geodesic_follows_eq3_and_crosses_the_seam():
    pts = coords.geodesic([170.0, 0.0], [-170.0, 0.0], np.linspace(0, 1, 5))
    np.testing.assert_allclose(pts[[0, 2, 4]], [[170, 0], [-180, 0], [-170, 0]], atol=1e-12)
    assert np.all(np.diff(np.unwrap(pts[:, 0], period=360)) > 0)  # monotone across the seam
    np.testing.assert_allclose(pts[:, 1], 0, atol=1e-12)
    # eq. (3) parametrises by the chord, not by arc length: t = 1/4 lies short of a quarter of the arc
    assert np.unwrap(pts[:, 0], period=360)[1] == pytest.approx(180 - np.degrees(np.arctan(0.5 * np.tan(np.radians(10)))))
    assert coords.angular_distance([170.0, 0.0], [-170.0, 0.0]) == pytest.approx(20.0)
    with pytest.raises(ValueError, match="antipodal"):
        coords.geodesic([0.0, 0.0], [180.0, 0.0], [0.5])


def test_bad_shapes_are_refused():
    with pytest.raises(ValueError, match="lon, lat"):
        coords.lonlat_to_xyz([1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match="even"):
        coords.grid_lonlat(7)
