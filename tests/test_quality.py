"""Quality figures measured from inverse maps, checked on maps whose answers are known exactly."""

import numpy as np
import pytest

from omniwidget.document.handles import LineHandle, Options
from omniwidget.evaluate.quality import (
    FAR_FIELD,
    cage_motion,
    conformal_distortion,
    coverage,
    dense_straightness,
    displacement,
    fold_over,
    forward_points,
    line_straightness,
    straightness,
    summary,
    tear,
)
from omniwidget.raster.warping import grid_inverse, inverse_lonlat
from omniwidget.sphere import coords
from omniwidget.sphere.moebius import Moebius

from .conftest import random_lonlat


def identity_map(width: int) -> np.ndarray:
    lon, lat = coords.grid_lonlat(width)
    return np.stack(np.meshgrid(lon, lat), axis=-1)


def moebius_map(m: Moebius, width: int) -> np.ndarray:
    return inverse_lonlat(grid_inverse(m.inverse), width)


@pytest.mark.slow  # at 2048 (3-4 s): the full suite; the fast loop runs it at 1024 (below)
def test_one_moebius_warp_is_conformal():
    _check_conformal(2048)  # measured mean 1.5e-6, p99 3.4e-6


def test_one_moebius_warp_is_conformal_at_1024():
    _check_conformal(1024)  # measured mean 5.9e-6, p99 1.4e-5


def _check_conformal(width: int) -> None:
    d = conformal_distortion(moebius_map(Moebius.point_map([10, 20], [35, -5], 2.0, 25.0), width))
    assert d.mean < 1e-4 and d.p99 < 1e-4
    assert np.all(np.isfinite(d.per_pixel[1:-1])) and np.isnan(d.per_pixel[[0, -1]]).all()


def test_conformal_distortion_detects_a_non_conformal_map():
    grid = identity_map(512)
    squeezed = grid.copy()
    squeezed[..., 1] = np.degrees(np.arcsin(np.sin(np.radians(grid[..., 1])) * 0.8))  # equal-area-like squeeze
    d = conformal_distortion(squeezed)
    assert d.mean > 0.05 and d.p99 >= d.mean
    assert conformal_distortion(grid).p99 < 1e-6
    with pytest.raises(ValueError, match="max_abs_lat"):
        conformal_distortion(grid, max_abs_lat=0)


def test_fold_over_finds_a_mirrored_band_and_its_area():
    width = 512
    grid = identity_map(width)
    assert fold_over(grid).area == 0 and not fold_over(moebius_map(Moebius.point_map([0, 80], [40, -60], 3.0, 90), width)).mask.any()
    folded = grid.copy()
    band = (grid[..., 0] > 10) & (grid[..., 0] < 40)
    folded[..., 0] = np.where(band, 50 - grid[..., 0], grid[..., 0])  # mirrored between 10 and 40 degrees
    result = fold_over(folded)
    columns = np.flatnonzero(result.mask[100])
    lon = grid[0, :, 0]
    assert lon[columns].min() > 9 and lon[columns].max() < 41
    assert result.area == pytest.approx(30 / 360, rel=0.05)


@pytest.mark.parametrize("width", [512, pytest.param(2048, marks=pytest.mark.slow)])
def test_forward_points_invert_a_moebius_map(rng, width):
    m = Moebius.point_map([170, 40], [-150, -20], 1.7, 30)
    points = np.concatenate([random_lonlat(rng, 300), [[179.99, 0.0], [-180.0, 10.0], [0.0, 85.0], [90.0, -85.0]]])
    expected = m(points)
    inside = np.abs(expected[:, 1]) < 90 - 180 / width  # the first and last rows bound the search
    got = forward_points(moebius_map(m, width), points)
    assert np.all(np.isfinite(got[inside]))
    error = coords.angular_distance(got[inside], expected[inside]) * width / 360
    assert error.max() < 0.01, error.max()
    started = forward_points(moebius_map(m, width), points[inside], start=expected[inside] + [0.4, -0.3])
    assert coords.angular_distance(started, expected[inside]).max() * width / 360 < 0.01


@pytest.mark.slow  # coverage searches for each of the ~32000 cells the map hides (5-7 s): the full suite
def test_points_the_output_does_not_show_are_nan_and_coverage_counts_them():
    grid = identity_map(1024)
    clamped = grid.copy()
    clamped[..., 1] = np.clip(grid[..., 1], -30, 30)  # shows only the band |lat| <= 30
    got = forward_points(clamped, [[20.0, 10.0], [20.0, 60.0], [-100.0, -80.0]])
    assert np.all(np.isfinite(got[0])) and np.isnan(got[1:]).all()
    assert coverage(clamped) == pytest.approx(np.sin(np.radians(30)), abs=0.01)
    assert coverage(grid) == 1.0


def test_points_the_output_does_not_show_are_nan():
    """The fast loop's part of the test above: its forward points and the full map's coverage (the clamped map's
    coverage, the expensive part, is left to the full suite: with fewer cells it misses the 0.01 bound)."""
    grid = identity_map(1024)
    clamped = grid.copy()
    clamped[..., 1] = np.clip(grid[..., 1], -30, 30)  # shows only the band |lat| <= 30
    got = forward_points(clamped, [[20.0, 10.0], [20.0, 60.0], [-100.0, -80.0]])
    assert np.all(np.isfinite(got[0])) and np.isnan(got[1:]).all()
    assert coverage(grid) == 1.0


def test_coverage_counts_regions_shown_smaller_than_a_cell():
    m = Moebius.point_map([0, 0], [0, 0], 8.0)  # zoom in 8x: the far side shrinks to a few pixels
    assert coverage(moebius_map(m, 512)) > 0.99


def test_line_straightness_measures_the_output_image_of_a_line(rng):
    width = 2048
    start, end = (-20.0, 30.0), (25.0, 40.0)
    samples = coords.geodesic(start, end, np.linspace(0, 1, 50))
    bent = line_straightness(identity_map(width), samples)
    assert bent == pytest.approx(straightness(samples, width, fit="best"), abs=0.01) and bent > 5
    m = LineHandle(start, end).moebius()
    rectified = line_straightness(moebius_map(m, width), samples)
    assert rectified == pytest.approx(straightness(m(samples), width, fit="best"), abs=0.01) and rectified < bent / 10


def test_best_fit_of_a_circular_arc_is_half_its_sagitta():
    t = np.linspace(-0.3, 0.3, 401)
    arc = np.stack([np.sin(t), np.cos(t) - 1], axis=1) * 10.0  # degrees; chord at both ends
    chord = straightness(arc, 360, fit="chord")
    assert chord == pytest.approx(10 * (1 - np.cos(0.3)), rel=1e-6)
    assert straightness(arc, 360, fit="best") == pytest.approx(chord / 2, rel=1e-3)


def test_cage_motion_is_zero_for_a_still_cage_and_the_shift_for_a_moved_one():
    width = 1024
    cage = [(-30.0, -10.0), (0.0, -10.0), (0.0, 20.0), (-30.0, 20.0)]
    assert cage_motion(identity_map(width), cage) < 1e-9
    shifted = moebius_map(Moebius.rotation([0, 90], 1.0), width)  # everything turns 1 degree east
    assert cage_motion(shifted, cage) == pytest.approx(width / 360, rel=1e-3)
    with pytest.raises(ValueError, match="no output pixel"):
        cage_motion(identity_map(64), [(0.0, 0.0), (0.1, 0.0), (0.0, 0.1)])


def test_bad_maps_are_refused_with_where_they_are_bad():
    grid = identity_map(64)
    grid[5, 7] = np.nan
    with pytest.raises(ValueError, match="row 5, column 7"):
        fold_over(grid)
    with pytest.raises(ValueError, match=r"\(H, 2H, 2\)"):
        coverage(np.zeros((10, 10, 2)))
    with pytest.raises(ValueError, match="cells"):
        coverage(identity_map(64), cells=7)
    with pytest.raises(ValueError, match="fit"):
        straightness([[0, 0], [1, 1]], 360, fit="mean")


def test_fold_signs_from_the_plane_agree_with_the_spheres_jacobians():
    from omniwidget.evaluate.quality import local_jacobians

    grid = identity_map(512)
    swirl = grid.copy()  # squeezed past itself around the seam, in a band of latitudes
    amplitude = 120 * np.exp(-(((grid[..., 1] - 20) / 15) ** 2))
    swirl[..., 0] = coords.wrap_lon(grid[..., 0] - amplitude * np.sin(np.radians(grid[..., 0] - 180)))
    folds = fold_over(swirl)
    assert 0 < folds.area < 0.5
    assert np.array_equal(fold_over(swirl.astype(np.float32)).mask, folds.mask)
    jac = local_jacobians(swirl)
    det = jac[..., 0, 0] * jac[..., 1, 1] - jac[..., 0, 1] * jac[..., 1, 0]
    clear = np.abs(det) > 1e-3  # away from the fold's edges, where the sign is a matter of rounding
    assert np.array_equal((det <= 0)[clear], folds.mask[1:-1][clear])


def test_tear_is_near_zero_for_smooth_maps_across_the_seam_and_the_poles():
    identity = tear(identity_map(512))
    assert abs(identity - np.degrees((2 * np.pi / 512) ** 2) * 512 / 360) < 1e-6  # the step along a meridian turns by h²
    half_turn = tear(moebius_map(Moebius.rotation([0.0, 90.0], 180.0), 512))  # sources wrap at the seam mid-image
    over_the_poles = tear(moebius_map(Moebius.rotation([0.0, 0.0], 90.0), 512))  # rows run through the input's poles
    zoom = tear(moebius_map(Moebius.point_map([10, 20], [35, -5], 3.0, 25.0), 512))
    assert half_turn < 0.02 and over_the_poles < 0.05 and zoom < 0.2, (identity, half_turn, over_the_poles, zoom)


def test_tear_measures_the_gap_where_the_map_jumps():
    torn = identity_map(512)
    torn[:, 256:, 0] += 5.0  # the right half shows the input 5 degrees further east: a gap of 7.1 px at 512 wide
    gap = 5.0 * 512 / 360
    assert abs(tear(torn) - gap) < 0.1, tear(torn)
    assert abs(tear(torn, width=2048) - 4 * gap) < 0.4  # counted in the input's pixels
    torn[:, 256:, 0] = coords.wrap_lon(torn[:, 256:, 0] - 180.0)  # the right half shows the far side: a gap half the sphere wide
    assert tear(torn) > 100
    rows = identity_map(512)
    rows[:20, :, 1] = np.minimum(rows[:20, :, 1] + 3.0, 90.0)  # a jump between rows 19 and 20, near the north pole
    assert abs(tear(rows) - 3.0 * 512 / 360) < 0.3 and tear(rows, max_abs_lat=70.0) < 0.02


def test_tear_refuses_bad_arguments():
    with pytest.raises(ValueError, match=r"max_abs_lat must be in \(0, 90\]"):
        tear(identity_map(64), max_abs_lat=0)
    with pytest.raises(ValueError, match="width must be an integer of at least 2, got 1"):
        tear(identity_map(64), width=1)
    with pytest.raises(ValueError, match=r"\(H, 2H, 2\)"):
        tear(np.zeros((10, 10, 2)))


def test_displacement_of_a_turn_about_the_axis_is_its_mean_chord_angle():
    """A turn by 10 degrees of longitude moves a point at latitude phi by 2 asin(cos(phi) sin(5 deg))."""
    width = 1024
    grid = identity_map(width)
    turned = grid.copy()
    turned[..., 0] = coords.wrap_lon(grid[..., 0] - 10.0)
    phi = np.radians(np.linspace(-90, 90, 200001))
    exact = np.trapezoid(np.degrees(2 * np.arcsin(np.cos(phi) * np.sin(np.radians(5.0)))) * np.cos(phi), phi) / 2
    assert displacement(grid) < 1e-12
    assert abs(displacement(turned) - exact) < 1e-3 * exact, (displacement(turned), exact)


def test_summary_of_a_warp_is_its_figures_one_by_one():
    from omniwidget.document.handles import CageHandle, Handles, PointHandle
    from omniwidget.evaluate.scenes import synthetic_room
    from omniwidget.raster.pipeline import warp

    width = 256
    line = LineHandle((-4.0, 37.5), (68.0, 36.5))
    cage = CageHandle(((-150.0, -20.0), (-120.0, -20.0), (-120.0, 10.0), (-150.0, 10.0)))
    doc = Handles((line, cage, PointHandle((100.0, -30.0), target=(104.0, -28.0))), Options(anchor=None))
    result = warp(synthetic_room(width).image, doc, warn=False)
    s = summary(result)
    m = result.inverse_map(np.float64)
    assert s.method == "bbw" and s.width == width and len(s.lines) == 1
    ((control, samples),) = result.constraints.lines
    # measured densely along the whole arc, through the map that placed the pixels
    dense = dense_straightness(result.placed_map(), line.start, line.end, guess=result.controls[control].moebius)
    assert s.lines[0] == pytest.approx(dense, abs=1e-9) and s.lines[0] == s.straightness
    at_samples = straightness(result.forward_points(samples, control), width, fit="best")
    assert at_samples - 1e-3 <= s.lines[0] < 0.05, (s.lines[0], at_samples)  # the dense figure misses nothing the samples see
    assert s.lines[0] == pytest.approx(line_straightness(m, samples, start=result.controls[control].moebius(samples)), abs=2e-3)
    assert s.distortion_mean == conformal_distortion(m).mean and s.tear == tear(m) and s.coverage == coverage(m)
    assert s.fold_over == result.folds.area and s.displacement == displacement(m) > 0
    assert s.cage_motion == cage_motion(m, cage.vertices) < 1e-9
    assert s.seconds == pytest.approx(sum(result.timings.values()))
    as_dict = s.as_dict()
    assert as_dict["straightness"] == s.straightness and as_dict["lines"] == list(s.lines)
    # the far field: the same figures where every output pixel is farther than 30° from every handle
    from scipy.spatial import cKDTree

    lon, lat = coords.grid_lonlat(width)
    grid = np.stack(np.meshgrid(lon, lat), axis=-1)
    chord, _ = cKDTree(result.constraints.points).query(coords.lonlat_to_xyz(grid).reshape(-1, 3))
    far = (np.degrees(2 * np.arcsin(chord / 2)) > FAR_FIELD).reshape(grid.shape[:2])
    area = np.cos(np.radians(grid[..., 1]))
    moved = coords.angular_distance(m, grid)
    assert s.far.distance == FAR_FIELD and s.far.share == pytest.approx(np.sum(far * area) / np.sum(area), rel=1e-9)
    assert s.far.displacement == pytest.approx(np.sum(moved * far * area) / np.sum(far * area), rel=1e-9)
    assert s.far.displacement > 1.0  # the paper's method: the far field swings with the line and the point
    inside = far & (np.abs(grid[..., 1]) <= 80) & np.isfinite(conformal_distortion(m).per_pixel)
    per_pixel = conformal_distortion(m).per_pixel
    assert s.far.distortion_mean == pytest.approx(np.sum(per_pixel[inside] * area[inside]) / np.sum(area[inside]), rel=1e-9)
    assert as_dict["far"]["displacement"] == s.far.displacement and "far from the handles moved" in s.line()
    still = summary(warp(synthetic_room(width).image, Handles(doc.handles, Options()), warn=False))
    assert still.far.displacement < 1e-9 and still.far.fold_over == 0  # the still background holds it
    assert "far from the handles still" in still.line()


def test_the_closed_form_singular_value_ratio_matches_an_svd_and_is_exact_near_conformal():
    from omniwidget.evaluate.quality import _singular_value_ratio_minus_one as ratio

    jac = np.random.default_rng(3).normal(size=(200, 300, 2, 2))
    sv = np.linalg.svd(jac, compute_uv=False)
    np.testing.assert_allclose(ratio(jac), sv[..., 0] / sv[..., 1] - 1, rtol=1e-9)
    # a rotation scaled by 3 is conformal; a shear of 1e-9 distorts by 1e-9 (+ 5e-19), which an SVD gets to 1e-7 only
    near = np.array([[[0.0, -3.0], [3.0, 0.0]], [[1.0, 1e-9], [0.0, 1.0]], [[1.0, 0.0], [0.0, -2.0]]])
    np.testing.assert_allclose(ratio(near), [0.0, 1e-9 + 0.5e-18, 1.0], rtol=1e-12, atol=1e-24)  # k + k²/2 + O(k³)


def test_dense_straightness_sees_a_bend_between_the_samples():
    """A map straight at a line's 50 samples and bent between two of them: only the dense figure sees the bend."""
    width = 1024
    grid = coords.grid_lonlat(width)
    lon, lat = np.meshgrid(*grid)
    samples = coords.geodesic((-60.0, 0.0), (60.0, 0.0), np.linspace(0.0, 1.0, 50))
    a, b = samples[24, 0], samples[25, 0]  # 2.4° apart, 7 pixels
    across = np.clip((lon - a) / (b - a), 0.0, 1.0)
    bump = 0.5 * np.sin(np.pi * across) ** 2 * np.exp(-0.5 * (lat / 5.0) ** 2)  # 0 at every sample, 0.5° between two
    inverse = np.stack([lon, lat + bump], axis=-1)  # the output row at the equator shows a little below it
    at_samples = line_straightness(inverse, samples)
    dense = dense_straightness(inverse, (-60.0, 0.0), (60.0, 0.0), guess=lambda p: p)
    assert at_samples < 0.01, at_samples  # the bump reaches the samples only by the map's bilinear interpolation
    # the line dips 0.5° (1.42 px) between two samples; the best fit's strip is half that deep
    assert dense == pytest.approx(0.5 * 0.5 * width / 360.0, rel=0.05), dense
    # a straight map: the equator stays straight, and a tilted great circle shows its own bend
    identity = np.stack([lon, lat], axis=-1)
    assert dense_straightness(identity, (-60.0, 0.0), (60.0, 0.0)) < 1e-3
    tilted = coords.geodesic((-60.0, 10.0), (60.0, 10.0), np.linspace(0.0, 1.0, 2001))
    expected = straightness(tilted, width, fit="best")
    assert dense_straightness(identity, (-60.0, 10.0), (60.0, 10.0)) == pytest.approx(expected, rel=1e-3, abs=1e-3)
