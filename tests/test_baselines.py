"""The paper's comparison methods (omniwidget.evaluate.baselines) measured against its own on synthetic rooms.

The figures each test measures are in its assertion messages and printed (pytest -s), e.g.
``BBW folds 0.000% tear 0.31 px straight 0.08 px``.
"""

import warnings

import numpy as np
import pytest

from omniwidget.document.handles import CageHandle, Handles, LineHandle, Options, PointHandle
from omniwidget.errors import ImageError
from omniwidget.evaluate import scenes
from omniwidget.evaluate.baselines import (
    RIVALS,
    BaselineResult,
    Comparison,
    PerspectiveView,
    compare,
    gaussian_2017,
    perspective,
    piecewise_constant,
    single_moebius,
)
from omniwidget.evaluate.content_preserving import ContentPreservingResult, PlaneSummary
from omniwidget.evaluate.quality import coverage, dense_straightness, straightness, tear
from omniwidget.evaluate.scenes import mark_lines, synthetic_room
from omniwidget.raster.pipeline import Result, warp
from omniwidget.sphere import coords

W = 512

#: As in test_blend: a fixed cage and a moved point where no line passes.
CAGE = ((-150.0, -20.0), (-120.0, -20.0), (-120.0, 10.0), (-150.0, 10.0))
POINT = PointHandle((-60.0, -30.0), target=(-55.0, -27.0), scale=1.1, rotation=10.0)
KEEP_CLEAR = ((np.array((*CAGE, (-135.0, -5.0))), 12.0), (np.array([POINT.position, POINT.target]), 12.0))

METHODS = {"BBW": warp, "piecewise": piecewise_constant, "gaussian": gaussian_2017, "single": single_moebius}

#: The baselines are the paper's alternatives: compared with the paper's BBW, without a still background.
PAPER = Options(anchor=None)


def _figures(result) -> dict:
    """Fold-over (% of the sphere), tear (px), the worst line's straightness (px, best fit) at its samples and densely, at W.

    ``"dense"`` measures each line along its whole arc through the map that placed the
    pixels (``placed_map()`` for BBW, the exact inverse map for a baseline), each piece's
    search started from its own map, as ``quality.summary`` does.
    """
    bends = [straightness(result.forward_points(samples, c), W, fit="best") for c, samples in result.constraints.lines]
    placed = result.inverse_map(np.float64) if isinstance(result, BaselineResult) else result.placed_map()
    dense = [
        dense_straightness(placed, samples[0], samples[-1], guess=result.controls[c].moebius) for c, samples in result.constraints.lines
    ]
    return {"folds": 100 * result.folds.area, "tear": tear(result.inverse_map(np.float64)), "straight": max(bends), "dense": max(dense)}


def _describe(figures: dict) -> str:
    return ", ".join(
        f"{name} folds {f['folds']:.3f}% tear {f['tear']:.2f} px straight {f['straight']:.2f} px" for name, f in figures.items()
    )


def _run_all(image, doc) -> tuple[dict, dict]:
    results, figures = {}, {}
    for name, method in METHODS.items():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            results[name] = method(image, doc)
        figures[name] = _figures(results[name])
    print("\n" + _describe(figures))
    return results, figures


@pytest.fixture(scope="module")
def room():
    """test_blend's room (seed 1): six marked lines (chosen as at 2048 wide), a fixed cage, a moved point."""
    rng = np.random.default_rng(1)
    scene = synthetic_room(W, size=(4.0, 3.0, 3.0), camera=(0.3, -0.2, -1.0), yaw=float(rng.uniform(0, 90)))
    lines = mark_lines(scene, 6, seed=1, keep_clear=KEEP_CLEAR, min_bend=5.0 * W / 2048)
    doc = Handles((*(LineHandle(line.start, line.end) for line in lines), CageHandle(CAGE), POINT), Options(rectify="each", anchor=None))
    return scene, doc, *_run_all(scene.image, doc)


@pytest.fixture(scope="module")
def close_pair():
    """Two parallel grid lines on one wall, about 7-9 degrees apart, each rectified by its own map."""
    scene = synthetic_room(W, size=(4.0, 3.0, 3.0), camera=(0.3, -0.2, -1.0), yaw=30.0, grid=0.5)
    a, b = scenes.close_pair(scene)
    doc = Handles((LineHandle(a.start, a.end), LineHandle(b.start, b.end)), Options(rectify="each", anchor=None))
    return scene, doc, *_run_all(scene.image, doc)


# --- the blends compared (notebook 04) --------------------------------------------------------


def test_bbw_neither_folds_nor_tears_on_the_room(room):
    _, _, results, figures = room
    bbw = figures["BBW"]
    assert bbw["folds"] == 0 and bbw["tear"] < 1.0, _describe(figures)
    assert coverage(results["BBW"].inverse_map(np.float64)) >= 0.99


def test_piecewise_constant_weights_tear_along_their_seams(room):
    _, _, results, figures = room
    assert figures["piecewise"]["tear"] > 20 * max(figures["BBW"]["tear"], 1.0), _describe(figures)
    # each region is shown by its own map: every line as straight as under BBW (both: its own map's bend)
    assert figures["piecewise"]["straight"] <= figures["BBW"]["straight"] + 0.05, _describe(figures)
    # the seams: pixels whose east neighbour belongs to another control, and where the jump is
    result = results["piecewise"]
    label = np.argmax(result.pixel_weights(), axis=-1)
    seam = label != np.roll(label, -1, axis=1)
    inverse = result.inverse_map(np.float64)
    jump = coords.angular_distance(inverse, np.roll(inverse, -1, axis=1)) * W / 360
    assert seam.any() and jump[seam].max() > 20 and jump[~seam][10:-10].max() < 5, (jump[seam].max(), jump[~seam][10:-10].max())


def test_one_map_is_one_to_one_but_bends_the_other_lines(room):
    _, _, _, figures = room
    assert figures["single"]["folds"] == 0 and figures["single"]["tear"] < 0.1, _describe(figures)
    assert figures["single"]["straight"] > 2 * figures["BBW"]["straight"] + 1.0, _describe(figures)


def test_gaussian_2017_bends_lines_that_are_close_together(close_pair):
    _, doc, results, figures = close_pair
    gap = coords.angular_distance(np.array(doc.handles[0].start), np.array(doc.handles[1].start))
    message = f"lines {gap:.1f} deg apart at their starts: " + _describe(figures)
    assert figures["BBW"]["folds"] == 0 and figures["BBW"]["tear"] < 1.0, message
    assert figures["gaussian"]["straight"] > 4 * figures["BBW"]["straight"] + 0.1, message
    assert figures["piecewise"]["tear"] > 10, message


def test_gaussian_2017_bends_the_rooms_lines_more_than_bbw(room):
    _, _, _, figures = room
    assert figures["gaussian"]["straight"] > figures["BBW"]["straight"] + 0.3, _describe(figures)


def test_compare_measures_every_method_as_the_tests_do(room):
    scene, doc, results, figures = room
    table = compare(scene.image, doc)
    assert isinstance(table, Comparison) and list(table.summaries) == ["bbw", "piecewise_constant", "gaussian_2017", "single_moebius"]
    for name, ours in zip(table.summaries, METHODS, strict=True):
        s = table[name]
        assert s.method == name and s.width == W
        assert s.fold_over * 100 == pytest.approx(figures[ours]["folds"], abs=1e-12)
        assert s.tear == pytest.approx(figures[ours]["tear"], rel=1e-6)
        assert s.straightness == pytest.approx(figures[ours]["dense"], rel=1e-6)
        assert np.array_equal(table.results[name].image, results[ours].image)
    bundle = table._repr_mimebundle_()
    assert bundle["application/json"] == table.as_dict() and "<table>" in bundle["text/html"]
    assert bundle["text/plain"].count("\n") == 5 and "BBW (the paper)" in bundle["text/plain"]


def test_compare_shows_content_preserving_beside_both_modes(room):
    """[10] beside the default mode and the paper's (the paper's Fig. 13): its lines as straight, its border irregular."""
    scene, doc, _, _ = room
    lines_only = Handles(tuple(h for h in doc.handles if isinstance(h, LineHandle)), Options())
    table = compare(scene.image, lines_only, RIVALS)
    assert list(table.summaries) == ["default", "paper", "content_preserving"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        default = warp(scene.image, Handles(lines_only.handles, Options()))
        paper = warp(scene.image, Handles(lines_only.handles, Options(rectify="all", anchor=None)))
    assert table["default"].lines == pytest.approx(default.quality.lines, rel=1e-9)
    assert table["paper"].lines == pytest.approx(paper.quality.lines, rel=1e-9)
    theirs = table["content_preserving"]
    result = table.results["content_preserving"]
    assert isinstance(result, ContentPreservingResult) and isinstance(theirs, PlaneSummary) and theirs.width == W
    print(f"\n[10]: lines {theirs.straightness:.3f} px, distortion {theirs.distortion_mean:.3f} (p99 {theirs.distortion_p99:.2f}), "
          f"cropped {theirs.cropped_loss:.1%} lost; paper's mode lines {table['paper'].straightness:.3f} px")
    assert len(theirs.lines) == len(lines_only.handles) and theirs.straightness < 0.5
    assert theirs.fold_over == 0 and theirs.coverage == pytest.approx(1.0) and 0.05 < theirs.cropped_loss < 0.9
    assert not result.mask.all() and np.isnan(theirs.displacement)
    text = table.to_markdown()
    assert "content-preserving [10]" in text and "sphere lost to the crop" in text and text.count("\n") == 4
    assert table.as_dict()["content_preserving"]["cropped_loss"] == pytest.approx(theirs.cropped_loss)


def test_compare_refuses_unknown_methods():
    image = synthetic_room(64).image
    doc = Handles((LineHandle((-4.0, 37.5), (68.0, 36.5)),), PAPER)
    with pytest.raises(ValueError, match="unknown: 'bbw2'"):
        compare(image, doc, ("bbw", "bbw2"))
    with pytest.raises(ValueError, match="non-empty"):
        compare(image, doc, ())


# --- the Result interface -------------------------------------------------------------


@pytest.mark.parametrize("name", ["piecewise", "gaussian", "single"])
def test_baselines_are_results_whose_points_agree_with_their_map(room, name):
    _, doc, results, _ = room
    result = results[name]
    assert isinstance(result, BaselineResult) and isinstance(result, Result)
    assert result.weights is None and result.vertices is None and result.source_width == W
    assert len(result.controls) == len(results["BBW"].controls) and result.handles is doc
    inverse = result.inverse_map(np.float64)
    assert inverse.shape == (W // 2, W, 2) and np.all(np.isfinite(inverse)) and inverse.dtype == np.float64
    assert result.inverse_map().dtype == np.float32 and result.folds.mask.shape == (W // 2, W)
    lon, lat = coords.grid_lonlat(W)
    rows, cols = np.arange(3, W // 2, 29), np.arange(5, W, 41)
    at = result.inverse_points(np.stack(np.meshgrid(lon[cols], lat[rows]), axis=-1))
    diff = at - inverse[np.ix_(rows, cols)]
    diff[..., 0] = coords.wrap_lon(diff[..., 0])
    assert np.abs(diff).max() < 1e-9
    weights = result.pixel_weights(slice(0, 8))
    assert weights.shape == (8, W, len(result.controls)) and np.all(weights >= 0) and np.all(weights <= 1)


# --- single_moebius ---------------------------------------------------------------------


def test_single_moebius_of_one_handle_is_warp_bit_for_bit():
    scene = synthetic_room(W)
    doc = Handles((LineHandle((-4.0, 37.5), (68.0, 36.5)),), PAPER)
    ours, theirs = single_moebius(scene.image, doc), warp(scene.image, doc)
    assert ours.image.tobytes() == theirs.image.tobytes()
    assert np.array_equal(ours.inverse_map(np.float64), theirs.inverse_map(np.float64))
    assert ours.moebius.isclose(theirs.moebius) and ours.folds.area == 0


def test_single_moebius_uses_the_chosen_handles_map(room):
    scene, doc, results, _ = room
    own = results["BBW"].controls
    for handle in (0, 3, len(doc.handles) - 1):
        result = single_moebius(scene.image, doc, handle=handle)
        expected = next(c.moebius for c in own if c.handle == handle)
        assert result.moebius is not None and result.moebius.isclose(expected)
        assert all(c.moebius.isclose(expected) for c in result.controls)
        assert sum("its own map" in c.label for c in result.controls) == 1


# --- piecewise_constant -----------------------------------------------------------------


def test_piecewise_constant_with_one_handle_is_its_map():
    scene = synthetic_room(W)
    doc = Handles((LineHandle((-4.0, 37.5), (68.0, 36.5)),), PAPER)
    ours, theirs = piecewise_constant(scene.image, doc), warp(scene.image, doc)
    diff = ours.inverse_map(np.float64) - theirs.inverse_map(np.float64)
    diff[..., 0] = coords.wrap_lon(diff[..., 0])
    assert np.abs(diff).max() < 1e-9
    # the image differs only by float32 rounding of the sample positions
    assert np.abs(ours.image.astype(int) - theirs.image).max() <= 1 and ours.folds.area == 0
    assert np.all(ours.pixel_weights() == 1)


def test_piecewise_constant_regions_hold_their_handles(room):
    _, _, results, _ = room
    result = results["piecewise"]
    labels = np.argmax(result.pixel_weights(), axis=-1)
    for control, samples in result.constraints.lines:
        out = result.controls[control].moebius(samples[1:-1])
        col, row = np.floor(coords.lonlat_to_px(out, W) + 0.5).astype(int).T
        label = labels[row % (W // 2), col % W]
        assert np.mean(label == control) > 0.9, result.controls[control].label


# --- gaussian_2017 ----------------------------------------------------------------------


def test_gaussian_2017_is_each_map_on_its_own_handle_and_identity_far_away():
    scene = synthetic_room(W)
    line = LineHandle((-4.0, 37.5), (68.0, 36.5))
    point = PointHandle((-120.0, -20.0), target=(-115.0, -18.0), scale=1.2)
    result = gaussian_2017(scene.image, Handles((line, point), PAPER))
    samples = result.constraints.lines[0][1]
    m = result.controls[0].moebius
    np.testing.assert_allclose(result.inverse_points(m(samples)), samples, atol=1e-9)  # its weight is 1 there, the point's 0
    np.testing.assert_allclose(result.inverse_points([point.target]), [point.position], atol=1e-9)
    far = np.array([[150.0, -60.0], [100.0, 0.0]])
    np.testing.assert_allclose(result.inverse_points(far), far, atol=1e-6)
    # the Gaussian: 1 at the point's target, exp(-4.5) at its radius (the arrows' output length)
    radius = coords.angular_distance(*point.target_points()[:2])
    at = coords.xyz_to_lonlat(
        coords.lonlat_to_xyz(point.target) * np.cos(np.radians(radius)) + coords.local_frame(point.target)[1] * np.sin(np.radians(radius))
    )
    col, row = np.floor(coords.lonlat_to_px(np.array([point.target, at]), W) + 0.5).astype(int).T
    weights = result.pixel_weights()[row, col, 1]
    assert weights[0] > 0.97 and abs(weights[1] - np.exp(-4.5)) < 0.01, weights


def test_gaussian_2017_radius_sets_the_reach():
    scene = synthetic_room(W)
    doc = Handles((PointHandle((0.0, 0.0), target=(5.0, 0.0)),), PAPER)
    narrow, wide = gaussian_2017(scene.image, doc, radius=5.0), gaussian_2017(scene.image, doc, radius=40.0)
    probe = [[25.0, 0.0]]
    assert abs(narrow.inverse_points(probe)[0, 0] - 25.0) < 1e-6 and abs(wide.inverse_points(probe)[0, 0] - 25.0) > 1.0


# --- perspective ----------------------------------------------------------------------


@pytest.mark.parametrize("center", [(30.0, 10.0), (179.0, -35.0), (-90.0, 90.0), (0.0, -90.0)])
def test_perspective_centre_pixel_shows_the_centre(center):
    image = synthetic_room(64).image
    view = perspective(image, center, 90.0, 41, 31)
    assert isinstance(view, PerspectiveView) and view.image.shape == (31, 41, 3) and view.image.dtype == np.uint8
    assert coords.angular_distance(view.lonlat[15, 20], center) < 1e-9
    assert view.center == center and view.fov == 90.0 and abs(view.focal - 20.5) < 1e-12
    yy, xx = np.mgrid[0:31, 0:41]
    np.testing.assert_allclose(view.project(view.inverse_map(np.float64)), np.stack([xx, yy], axis=-1), atol=1e-9)


def test_perspective_draws_great_circles_straight():
    """Projected: exact; drawn: the rendered edge's centre line is straight within 0.5 px where the panorama bends it by 15 px."""
    scene = synthetic_room(1024, grid=None)
    view = perspective(scene.image, (20.0, 10.0), 100.0, 401, 301)
    edge = min(scene.lines_where(kind="edge"), key=lambda line: coords.angular_distance(line.start, (-21.2, 17.2)))  # ceiling edge
    samples = coords.geodesic(edge.start, edge.end, np.linspace(0, 1, 400))
    px = view.project(samples)
    a, b = px[0], px[-1]
    chord = (b - a) / np.hypot(*(b - a))
    off_chord = np.abs(chord[0] * (px[:, 1] - a[1]) - chord[1] * (px[:, 0] - a[0]))
    bend = straightness(samples, 1024)
    assert off_chord.max() < 0.1 and bend > 10, (off_chord.max(), bend)
    # what the view shows: the dark band's centroid, column by column, fits a straight line
    dark = 255.0 - view.image.astype(float).mean(axis=-1)
    order = np.argsort(px[:, 0])
    xs = np.arange(int(px[:, 0].min()) + 10, int(px[:, 0].max()) - 10)
    ys = []
    for x in xs:
        y0 = int(round(np.interp(x, px[order, 0], px[order, 1])))
        window = np.arange(y0 - 8, y0 + 9)
        d = np.clip(dark[window, x] - np.median(dark[[y0 - 12, y0 + 12], x]), 0, None)
        ys.append(np.sum(d * window) / np.sum(d))
    fit = np.polyfit(xs, ys, 1)
    residual = np.abs(np.polyval(fit, xs) - ys).max()
    print(f"\nedge bent {bend:.1f} px in the panorama, {residual:.2f} px from straight in the view ({len(xs)} columns)")
    assert len(xs) > 200 and residual < 0.5, (residual, bend)


def test_perspective_stretches_towards_the_edges():
    view = perspective(synthetic_room(64).image, (0.0, 0.0), 120.0, 201, 101)
    step = coords.angular_distance(view.lonlat[50, 1:], view.lonlat[50, :-1])  # degrees per pixel along the middle row
    assert step[100] / step[0] > 3.5  # 1 / cos²(60°) = 4 at the edge


# --- validation -------------------------------------------------------------------------


def test_baselines_refuse_bad_arguments():
    image = synthetic_room(64).image
    doc = Handles((LineHandle((-4.0, 37.5), (68.0, 36.5)), PointHandle((10.0, 10.0))), PAPER)
    with pytest.raises(TypeError, match="handles must be a Handles document"):
        piecewise_constant(image, {"handles": []})
    with pytest.raises(ValueError, match=r"handle must be the index of one of the 2 handles \(0 to 1\), got 2"):
        single_moebius(image, doc, handle=2)
    with pytest.raises(ValueError, match="handle must be a non-negative integer, got -1"):
        single_moebius(image, doc, handle=-1)
    with pytest.raises(ValueError, match="handle must be a non-negative integer, got True"):
        single_moebius(image, doc, handle=True)
    for method in (single_moebius, piecewise_constant, gaussian_2017):
        with pytest.raises(ValueError, match="handles has no handles"):
            method(image, Handles((), PAPER))
        with pytest.raises(ValueError, match="width must be an even integer of at least 2, got 63"):
            method(image, doc, width=63)
        with pytest.raises(ValueError, match="order must be one of"):
            method(image, doc, order="cubic")
        with pytest.raises(ImageError, match="twice as wide as high"):
            method(image[:, :40], doc)
    for radius in (0, -3.0, 200.0, "5", True, float("nan")):
        with pytest.raises(ValueError, match=r"radius must be a number of degrees in \(0, 180\]"):
            gaussian_2017(image, doc, radius=radius)


def test_perspective_refuses_bad_arguments():
    image = synthetic_room(64).image
    for fov in (0, 180, -10.0, float("nan"), "90", True):
        with pytest.raises(ValueError, match=r"fov must be a number of degrees in \(0, 180\)"):
            perspective(image, (0.0, 0.0), fov, 10, 10)
    with pytest.raises(ValueError, match=r"center\[0\] \(longitude\): 200 is out of range \[-180, 180\]"):
        perspective(image, (200.0, 0.0), 90.0, 10, 10)
    with pytest.raises(ValueError, match=r"center\[1\] \(latitude\): -95 is out of range \[-90, 90\]"):
        perspective(image, (0.0, -95.0), 90.0, 10, 10)
    for center in ("ab", (1.0, 2.0, 3.0), (np.nan, 0.0), None):
        with pytest.raises(ValueError, match="center must be"):
            perspective(image, center, 90.0, 10, 10)
    with pytest.raises(ValueError, match="width must be a positive integer, got 0"):
        perspective(image, (0.0, 0.0), 90.0, 0, 10)
    with pytest.raises(ValueError, match="height must be a positive integer, got 2.5"):
        perspective(image, (0.0, 0.0), 90.0, 10, 2.5)
    with pytest.raises(ValueError, match="order must be one of"):
        perspective(image, (0.0, 0.0), 90.0, 10, 10, order="cubic")
    with pytest.raises(ImageError):
        perspective(image[:, :40], (0.0, 0.0), 90.0, 10, 10)


def test_compare_without_lines_gives_strict_json():
    """No line: straightness is NaN in the summary, None (null) in the JSON a notebook saves."""
    import json

    doc = Handles((PointHandle((0.0, 0.0), target=(5.0, 0.0)), PointHandle((90.0, 0.0), target=(92.0, 3.0))), PAPER)
    table = compare(synthetic_room(128).image, doc, ("bbw", "gaussian_2017"))
    assert np.isnan(table["bbw"].straightness) and table["bbw"].lines == ()
    figures = json.loads(json.dumps(table._repr_mimebundle_()["application/json"], allow_nan=False))
    assert figures["bbw"]["straightness"] is None and figures["bbw"]["cage_motion"] is None
    assert "–" in table.to_markdown()
