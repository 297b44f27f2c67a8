"""[10]'s content-preserving projection (omniwidget.evaluate.content_preserving) against its own definition.

Each energy is checked on maps whose value is known on paper, the solver on a problem whose
minimiser is known, the lines on a room whose edges are straight in 3D, and the renderer on
the identity mesh, which must give back the input.
"""

import math

import numpy as np
import pytest

from omniwidget.document.handles import CageHandle, Handles, LineHandle, Options
from omniwidget.errors import ImageError
from omniwidget.evaluate import content_preserving as cp
from omniwidget.evaluate.quality import straightness
from omniwidget.evaluate.scenes import mark_lines, synthetic_room
from omniwidget.sphere import coords


def _identity(mesh: cp.Mesh) -> np.ndarray:
    """The plain lon/lat grid as positions: u = lambda, v = phi, radians."""
    return np.radians(mesh.grid())


def _line(mesh: cp.Mesh, start, end, orientation="free", n=200) -> cp.Line:
    samples = coords.geodesic(start, end, np.linspace(0.0, 1.0, n))
    length = math.radians(float(coords.angular_distance(start, end)))
    ds = np.full(n, length / (n - 1))
    ds[[0, -1]] /= 2
    return cp.Line(np.stack([mesh.to_mesh_lon(samples[:, 0]), samples[:, 1]], axis=1), ds, orientation, 0)


# --- the energies, by hand ----------------------------------------------------------------


@pytest.mark.parametrize(("a", "b"), [(1.0, 1.0), (2.0, 0.5), (0.3, 1.7)])
def test_conformality_energy_of_an_affine_stretch_is_the_sum_on_paper(a, b):
    """u = a lambda, v = b phi: r1 = 0 and r2 = h (a - b cos phi_j) at every vertex, so E_c = (n_lon - 1) h² sum_j cos phi_j (a - b cos phi_j)²."""
    mesh = cp.Mesh(6.0)
    grid = _identity(mesh)
    h = math.radians(mesh.step)
    cos = np.cos(np.radians(mesh.phi[:-1]))
    expected = (mesh.n_lon - 1) * h * h * np.sum(cos * (a - b * cos) ** 2)
    value = cp.conformality_energy(mesh, grid * [a, b])
    assert value == pytest.approx(expected, rel=1e-12) and value > 0
    # a conformal map of the sphere has none: the discrete Mercator v_j+1 - v_j = h / cos(phi_j), on a band clear of the poles
    mesh = cp.Mesh(3.0)
    g = mesh.grid()
    band = np.abs(g[:, 1]) <= 60
    salience = (np.abs(mesh.phi) < 60)[:, None] * np.ones((1, mesh.n_lon))  # rows j with phi_j and phi_j+1 inside the band
    steps = np.where(np.abs(mesh.phi) < 60, math.radians(3.0) / np.cos(np.radians(mesh.phi)), 0.0)  # no pole's 1 / cos 0
    v = np.concatenate([[0.0], np.cumsum(steps[:-1])])
    mercator = np.stack([np.radians(g[:, 0]), np.repeat(v, mesh.n_lon)], axis=1)
    assert band.any() and cp.conformality_energy(mesh, mercator, salience) < 1e-25


def test_smoothness_energy_is_zero_for_affine_maps_and_the_sum_on_paper_for_a_parabola():
    mesh = cp.Mesh(6.0)
    grid = _identity(mesh)
    assert cp.smoothness_energy(mesh, grid @ np.array([[1.3, 0.2], [-0.4, 0.9]]) + [2.0, -1.0]) < 1e-24
    # u = lambda²: every lambda-lambda second difference is 2 h², the others 0; E_s = sum over those stencils of cos(phi_j) (2 h²)² / h²
    h = math.radians(mesh.step)
    parabola = np.stack([grid[:, 0] ** 2, np.zeros(mesh.size)], axis=1)
    cos = np.maximum(np.cos(np.radians(mesh.phi)), 0.0)
    expected = (mesh.n_lon - 2) * np.sum(cos) * 4 * h * h
    assert cp.smoothness_energy(mesh, parabola) == pytest.approx(expected, rel=1e-9)


def test_line_energy_is_zero_for_points_on_a_line():
    mesh = cp.Mesh(3.0)
    grid = _identity(mesh)
    meridian, equator = _line(mesh, (40.0, -50.0), (40.0, 55.0)), _line(mesh, (-70.0, 0.0), (20.0, 0.0))
    assert cp.line_energy(mesh, grid, meridian) < 1e-20
    assert cp.line_energy(mesh, grid, cp.Line(meridian.mulat, meridian.ds, "vertical", 0)) < 1e-20
    assert cp.line_energy(mesh, grid, cp.Line(equator.mulat, equator.ds, "horizontal", 0)) < 1e-20
    assert cp.line_energy(mesh, grid, cp.Line(meridian.mulat, meridian.ds, "horizontal", 0)) > 0.1  # the wrong fixed orientation
    # turned by 30 degrees, the meridian is still on a line (a free one), no longer a vertical one
    t = math.radians(30.0)
    turned = grid @ np.array([[math.cos(t), math.sin(t)], [-math.sin(t), math.cos(t)]])
    assert cp.line_energy(mesh, turned, meridian) < 1e-20
    assert cp.line_energy(mesh, turned, cp.Line(meridian.mulat, meridian.ds, "vertical", 0)) > 0.01
    # a tilted great circle is curved in the lon/lat grid: its energy is that of the bend
    tilted = _line(mesh, (-30.0, 10.0), (40.0, 45.0))
    assert cp.line_energy(mesh, grid, tilted) > 1e-6
    # with a given normal, the distance from the line of that normal
    assert cp.line_energy(mesh, grid, equator, normal=(1.0, 1.0)) > 0.1


# --- the solve ------------------------------------------------------------------------


def test_with_smoothness_alone_and_an_affine_gauge_the_minimiser_is_the_grid():
    """E_s vanishes exactly on maps affine in (lambda, phi): three fixed vertices of the grid make the grid itself the minimiser."""
    mesh = cp.Mesh(6.0)
    equator = (mesh.n_lat // 2) * mesh.n_lon
    north = (mesh.n_lat - 2) * mesh.n_lon + mesh.n_lon // 2
    fixed = {equator: (-math.pi, 0.0), equator + mesh.n_lon - 1: (math.pi, 0.0), north: (0.0, math.radians(mesh.phi[-2]))}
    solution = cp.solve_mesh(mesh, (), cp.Weights(0.0, 1.0, 0.0), fixed=fixed)
    np.testing.assert_allclose(solution.positions, _identity(mesh), atol=1e-9)


def test_without_lines_the_solution_is_the_energys_minimiser_not_the_grid():
    """With no lines the minimiser of w_c² E_c + w_s² E_s is not the lon/lat grid (whose E_c is > 0, computed above) but a
    Mercator-like map between it and a conformal one: the solve finds the minimum (no perturbation lowers it), one-to-one."""
    mesh = cp.Mesh(6.0)
    w = cp.WEIGHTS
    solution = cp.solve_mesh(mesh)
    assert solution.iterations == 1 and solution.energies["lines"] == 0

    def energy(p):
        return w.conformality**2 * cp.conformality_energy(mesh, p) + w.smoothness**2 * cp.smoothness_energy(mesh, p)

    best = energy(solution.positions)
    assert best == pytest.approx(solution.energies["conformality"] + solution.energies["smoothness"], rel=1e-12)
    grid = _identity(mesh)
    assert energy(grid) > 5 * best  # the gauge holds the grid too: its equator spans -pi .. pi
    gauge = mesh.gauge()
    rng = np.random.default_rng(0)
    for _ in range(5):
        step = rng.normal(size=solution.positions.shape) * 1e-3
        for vertex, (u, v) in gauge.items():
            step[vertex] = [0.0 if u is not None else step[vertex, 0], 0.0 if v is not None else step[vertex, 1]]
        assert energy(solution.positions + step) > best
    p = solution.positions.reshape(mesh.n_lat, mesh.n_lon, 2)
    assert np.all(np.diff(p[1:-1, :, 0], axis=1) > 0) and np.all(np.diff(p[:, 1:-1, 1], axis=0) > 0)  # u grows east, v north
    assert p[mesh.n_lat // 2, 0, 0] == -math.pi and p[mesh.n_lat // 2, -1, 0] == math.pi


# --- the result -----------------------------------------------------------------------


@pytest.fixture(scope="module")
def room_line():
    """A room at 1024 and one marked edge that the panorama bends by several pixels."""
    scene = synthetic_room(1024, size=(4.0, 3.0, 3.0), camera=(0.3, -0.2, -1.0), yaw=25.0)
    line = mark_lines(scene, 1, seed=2, min_bend=5.0 * 1024 / 2048)[0]
    return scene, line


def _bend(result, start, end) -> float:
    """A line's straightness in the plane, in its own output pixels, densely (the piecewise-linear map)."""
    px = result.forward_points(coords.geodesic(start, end, np.linspace(0.0, 1.0, 4000)))
    return straightness(px, 360, fit="best")


def test_a_single_marked_line_comes_out_straight(room_line):
    scene, line = room_line
    bent = straightness(coords.geodesic(line.start, line.end, np.linspace(0, 1, 400)), 1024, fit="best")
    result = cp.content_preserving(scene.image, Handles((LineHandle(line.start, line.end),), Options()))
    q = result.quality
    loose = cp.content_preserving(scene.image, Handles((LineHandle(line.start, line.end, rectify=False),), Options()))
    print(f"\nline bent {bent:.2f} px in the panorama, {_bend(loose, line.start, line.end):.2f} px in the plane without its energy, "
          f"{q.lines_output_px[0]:.3f} px with it ({q.lines[0]:.3f} equirectangular px)")
    assert bent > 2.0 and _bend(loose, line.start, line.end) > 1.0
    assert q.lines_output_px[0] < 0.5 and q.lines[0] < 0.5 and _bend(result, line.start, line.end) < 0.5
    assert isinstance(q, cp.PlaneSummary) and q.fold_over == 0 and q.coverage == pytest.approx(1.0)
    assert 0 < q.cropped_loss < 1 and q.displacement != q.displacement  # NaN: a plane keeps no place
    assert result.solution.iterations >= 2 and np.allclose(np.linalg.norm(result.solution.normals, axis=1), 1.0)


def test_a_vertical_edge_marked_vertical_comes_out_vertical(room_line):
    scene, _ = room_line
    edge = next(e for e in scene.lines_where(kind="edge") if abs(e.start[0] - e.end[0]) < 1e-6 and e.length > 40)
    result = cp.content_preserving(scene.image, Handles((LineHandle(edge.start, edge.end),), Options()))
    assert result.solution.lines[0].orientation == "vertical"  # "auto": along a meridian
    px = result.forward_points(coords.geodesic(edge.start, edge.end, np.linspace(0.0, 1.0, 500)))
    assert np.ptp(px[:, 0]) < 0.5 and np.ptp(px[:, 1]) > 50


def test_the_render_of_the_identity_mesh_is_the_input():
    scene = synthetic_room(256)
    mesh = cp.Mesh(6.0)
    out, render, inverse, _ = cp.render_image(scene.image, mesh, _identity(mesh), 256)
    assert out.shape == scene.image.shape and render.mask.all()
    lon, lat = coords.grid_lonlat(256)
    np.testing.assert_allclose(inverse, np.stack(np.meshgrid(lon, lat), axis=-1), atol=1e-9)
    assert np.array_equal(out[2:-2, 2:-2], scene.image[2:-2, 2:-2])


def test_the_result_maps_agree_and_leave_the_border_black(room_line):
    scene, line = room_line
    result = cp.content_preserving(scene.image, Handles((LineHandle(line.start, line.end),), Options()), width=512)
    inverse = result.inverse_map(np.float64)
    assert inverse.shape == (*result.image.shape[:2], 2) and result.image.shape[1] == 512
    assert np.all(np.isnan(inverse[~result.mask])) and np.all(np.isfinite(inverse[result.mask]))
    assert not result.mask.all() and np.all(result.image[~result.mask] == 0)
    rows, cols = np.nonzero(result.mask)
    pick = np.random.default_rng(1).choice(len(rows), 200, replace=False)
    back = result.forward_points(inverse[rows[pick], cols[pick]])
    np.testing.assert_allclose(back, np.stack([cols[pick], rows[pick]], axis=1), atol=1e-6)


def test_largest_rectangle():
    mask = np.zeros((6, 9), dtype=bool)
    mask[1:5, 2:8] = True
    mask[0, :] = True
    assert cp.largest_rectangle(mask) == (0, 2, 5, 6)  # the full top row joins the block below it
    mask[0, 4] = False
    assert cp.largest_rectangle(mask) == (1, 2, 4, 6)
    assert cp.largest_rectangle(np.zeros((3, 3), bool)) == (0, 0, 0, 0)


def test_cages_and_points_are_ignored_and_arguments_checked(room_line):
    scene, line = room_line
    image = scene.image[::4, ::4]
    doc = Handles((LineHandle(line.start, line.end), CageHandle(((10.0, 10.0), (20.0, 10.0), (20.0, 20.0)))), Options())
    result = cp.content_preserving(image, doc, step=6.0)
    assert len(result.solution.lines) == 1 and result.quality.cage_motion != result.quality.cage_motion  # NaN: a fixed cage, not held
    with pytest.raises(TypeError, match="Handles document"):
        cp.content_preserving(image, {"handles": []})
    with pytest.raises(ImageError):
        cp.content_preserving(image[:, :40], doc)
    with pytest.raises(ValueError, match="step must divide 90"):
        cp.content_preserving(image, doc, step=7.0)
    with pytest.raises(ValueError, match="orientations must give one of"):
        cp.content_preserving(image, doc, orientations=["free", "free"])
    with pytest.raises(ValueError, match="order must be one of"):
        cp.content_preserving(image, doc, order="cubic")
    with pytest.raises(ValueError, match="weight lines must be a finite number"):
        cp.Weights(lines=-1.0)
