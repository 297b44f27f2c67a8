"""Great-circle arcs (omniwidget.sphere.arcs): crossings and polygons, with known answers."""

import numpy as np
import pytest

from omniwidget.sphere import coords
from omniwidget.sphere.arcs import arc_crossing, crossing_pairs, inside_polygon


def xyz(lon, lat):
    return coords.lonlat_to_xyz([lon, lat])


def test_an_arc_of_the_equator_and_a_meridian_cross_where_they_must():
    x = arc_crossing(xyz(-20, 0), xyz(20, 0), xyz(10, -30), xyz(10, 30))
    np.testing.assert_allclose(coords.xyz_to_lonlat(x), [10.0, 0.0], atol=1e-12)
    # across the seam: the arcs are the shorter way round
    x = arc_crossing(xyz(170, 0), xyz(-170, 0), xyz(180, -5), xyz(180, 5))
    assert abs(abs(coords.xyz_to_lonlat(x)[0]) - 180.0) < 1e-9


def test_arcs_that_miss_touch_at_an_end_or_share_a_great_circle_do_not_cross():
    assert arc_crossing(xyz(-20, 0), xyz(20, 0), xyz(30, -30), xyz(30, 30)) is None  # past the end
    assert arc_crossing(xyz(-20, 0), xyz(20, 0), xyz(20, 0), xyz(20, 30)) is None  # a shared end
    assert arc_crossing(xyz(-20, 0), xyz(20, 0), xyz(0, 0), xyz(40, 0)) is None  # overlapping on the equator
    # within the margin of an end: no crossing; just beyond it: one
    assert arc_crossing(xyz(-20, 0), xyz(20, 0), xyz(20 - 1e-7, -1), xyz(20 - 1e-7, 1)) is None
    assert arc_crossing(xyz(-20, 0), xyz(20, 0), xyz(20 - 1e-3, -1), xyz(20 - 1e-3, 1)) is not None


def test_crossing_pairs_of_curves_in_the_panorama_including_across_the_seam():
    t = np.linspace(0, 1, 20)[:, None]
    a = np.hstack([-30 + 60 * t, 0 * t])  # along the equator
    b = np.hstack([0 * t, -20 + 40 * t])  # a meridian through it
    c = np.hstack([100 + 0 * t, -20 + 40 * t])  # far away
    d = np.hstack([170 + 20 * t, 10 + 0 * t])  # across the seam: 170 .. 190
    e = np.hstack([-175 + 0 * t, 0 + 20 * t])  # crosses d at lon -175 (185)
    d[:, 0] = coords.wrap_lon(d[:, 0])
    assert crossing_pairs([a, b, c, d, e]) == [(0, 1), (3, 4)]
    assert crossing_pairs([a, np.vstack([a[-1], [40.0, 10.0]])]) == []  # joined at an end only


@pytest.mark.parametrize("centre", [(0.0, 0.0), (179.0, 10.0), (40.0, 85.0)])
def test_inside_a_spherical_square_anywhere_on_the_sphere(centre):
    frame_east, frame_north = coords.local_frame(centre)
    c = coords.lonlat_to_xyz(centre)

    def at(e, n):
        p = c + np.tan(np.radians(e)) * frame_east + np.tan(np.radians(n)) * frame_north
        return coords.xyz_to_lonlat(p / np.linalg.norm(p))

    square = np.array([at(-10, -10), at(10, -10), at(10, 10), at(-10, 10)])
    inside = np.array([at(0, 0), at(9, 9), at(-9, 5)])
    outside = np.array([at(11, 0), at(0, -11), at(30, 30), coords.xyz_to_lonlat(-c)])  # the antipode too
    assert inside_polygon(inside, square).all() and not inside_polygon(outside, square).any()
    assert np.array_equal(inside_polygon(inside, square[::-1]), inside_polygon(inside, square))  # either way round
