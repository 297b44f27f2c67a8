"""The mesh-and-weights pane: per-handle weights, the pyvista mesh, off-screen renders, the 2D overlay, the notebook pane."""

import os
import subprocess
import sys
import warnings

import numpy as np
import pytest

from tests import requires

# no environment set here: omniwidget.viz.pane itself chooses EGL where there is no display (the test below)
pv = requires.module("pyvista")

import omniwidget as ow  # noqa: E402
from omniwidget.document.handles import LineHandle, PointHandle  # noqa: E402
from omniwidget.method.constraints import build_constraints  # noqa: E402
from omniwidget.sphere import coords  # noqa: E402
from omniwidget.viz import pane  # noqa: E402

POINT = {"kind": "point", "position": [120.0, 0.0], "target": [125.0, 5.0], "scale": 1.5}
SCENE = {
    "format": "omniwidget.handles",
    "version": 1,
    "handles": [
        {"kind": "line", "start": [-4.0, 37.5], "end": [68.0, 36.5]},
        {"kind": "line", "start": [-83.0, 12.0], "end": [-45.5, 12.0]},
        {"kind": "cage", "vertices": [[-28.0, -5.0], [-2.0, -5.0], [-2.0, -50.0], [-28.0, -50.0]]},
        POINT,
    ],
    "options": {"rectify": "all"},
}
SIZE = (240, 240)


def test_importing_the_pane_without_a_display_chooses_egl():
    """What lets the renders below run headless: the library sets ``VTK_DEFAULT_OPENGL_WINDOW``, not the tests.

    In a fresh process without ``DISPLAY``/``WAYLAND_DISPLAY``: set to EGL on import; one given is kept.
    """
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY", "VTK_DEFAULT_OPENGL_WINDOW")}
    code = "import os, omniwidget.viz.pane; print(os.environ.get('VTK_DEFAULT_OPENGL_WINDOW'))"
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True).stdout.split()
    assert out == (["vtkEGLRenderWindow"] if sys.platform.startswith("linux") else ["None"])
    kept = {**env, "VTK_DEFAULT_OPENGL_WINDOW": "vtkOSOpenGLRenderWindow"}
    out = subprocess.run([sys.executable, "-c", code], env=kept, capture_output=True, text=True, check=True).stdout.split()
    assert out == ["vtkOSOpenGLRenderWindow"]


def _warp(document, width=512):
    """The paper's warp of ``document`` (no still background, unless the document asks for one)."""
    document = {**document, "options": {"anchor": None, **document.get("options", {})}}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ow.BlendWarning)
        return ow.warp(ow.sample_image(), ow.Handles.from_dict(document), width=width)


@pytest.fixture(scope="module")
def result():
    return _warp(SCENE)


@pytest.fixture(scope="module")
def crossing():
    """Two crossing lines (each split in two pieces) and a point: more controls than handles."""
    return _warp(
        {
            "format": "omniwidget.handles",
            "version": 1,
            "handles": [
                {"kind": "line", "start": [-40.0, 0.0], "end": [40.0, 10.0]},
                {"kind": "line", "start": [0.0, -30.0], "end": [5.0, 40.0]},
                POINT,
            ],
        }
    )


# --- weights and mesh ----------------------------------------------------------------------
def test_handle_weights_sum_each_handles_controls(result, crossing):
    for r in (result, crossing):
        w = pane.handle_weights(r)
        assert w.shape == (len(r.vertices), len(r.handles)) and w.dtype == np.float64
        expected = np.zeros_like(w)
        for c, control in enumerate(r.controls):
            expected[:, control.handle] += r.weights[:, c]
        np.testing.assert_array_equal(w, expected)
        np.testing.assert_allclose(w.sum(axis=1), 1.0, atol=1e-9)
    assert len(crossing.controls) == 5  # each line split at the crossing
    assert len(result.controls) == 7  # the cage: one control per vertex


def test_handle_weights_leave_out_the_still_background(result):
    from dataclasses import replace

    from omniwidget.document.handles import Options
    from omniwidget.method.background import BACKGROUND

    still = ow.warp(result.image, replace(result.handles, options=Options(anchor=5.0)))
    assert still.controls[-1].handle == BACKGROUND
    w = pane.handle_weights(still)
    assert w.shape == (len(still.vertices), len(still.handles))
    np.testing.assert_allclose(w.sum(axis=1) + still.weights[:, -1], 1.0, atol=1e-9)
    # far from the handles the background alone: every vertex 30° or more from each handle's points, lines and edges
    # (measured: 2% of the mesh; at 20°, 83% of them, the point's reach and the cage's inside reaching there)
    t = np.linspace(0.0, 1.0, 50)
    near: list[np.ndarray] = []
    for h in still.handles.handles:
        if isinstance(h, PointHandle):
            near.append(np.array([h.position, h.final]))
        elif isinstance(h, LineHandle):
            near.append(coords.geodesic(h.start, h.end, t))
        else:
            near += [coords.geodesic(a, b, t) for a, b in zip(h.vertices, np.roll(h.vertices, -1, axis=0), strict=True)]
    apart = np.degrees(np.arccos(np.clip(still.vertices @ coords.lonlat_to_xyz(np.vstack(near)).T, -1.0, 1.0))).min(axis=1)
    far = apart >= 30.0
    assert far.sum() > 50 and np.all(still.weights[far, -1] == 1.0), still.weights[far, -1].min()


def test_weights_mesh_has_one_array_per_handle_equal_to_the_weights(result):
    mesh = pane.weights_mesh(result)
    assert isinstance(mesh, pv.PolyData)
    assert mesh.n_points == len(result.vertices) and mesh.n_cells == len(result.faces)
    np.testing.assert_array_equal(mesh.points, result.vertices)
    np.testing.assert_array_equal(mesh.regular_faces, result.faces)
    w = pane.handle_weights(result)
    names = ["handles[0] (line)", "handles[1] (line)", "handles[2] (cage)", "handles[3] (point)"]
    for i, name in enumerate(names):
        np.testing.assert_array_equal(mesh.point_data[name], w[:, i])
    marked = np.flatnonzero(mesh.point_data["constrained"])
    np.testing.assert_array_equal(marked, np.unique(result.constrained))


def test_a_result_without_mesh_or_a_bad_handle_is_refused_clearly(result):
    single = _warp({"format": "omniwidget.handles", "version": 1, "handles": [POINT]})
    assert single.weights is None
    with pytest.raises(ValueError, match="result.weights is None"):
        pane.handle_weights(single)
    with pytest.raises(ValueError, match="no mesh"):
        pane.render_weights(single, 0)
    with pytest.raises(IndexError, match="handle 4 is out of range: the document has 4 handles"):
        pane.render_weights(result, 4)
    with pytest.raises(IndexError, match="out of range"):
        pane.weights_overlay(result, -1)
    with pytest.raises(TypeError, match="must be an int"):
        pane.weights_overlay(result, 1.0)
    with pytest.raises(TypeError, match="Result"):
        pane.weights_mesh(result.image)
    with pytest.raises(ValueError, match="camera"):
        pane.render_weights(result, 0, camera="inside")


def test_final_polylines_are_where_the_handles_end_up(result):
    (point,) = pane.final_polylines(result, 3)
    np.testing.assert_allclose(point, [POINT["target"]], atol=1e-9)
    (cage,) = pane.final_polylines(result, 2)
    np.testing.assert_allclose(cage[0], cage[-1])  # closed
    for piece in pane.final_polylines(result, 0):  # the rectified line's output, straight in lon/lat
        fit = np.polyfit(piece[:, 0], piece[:, 1], 1)
        assert np.abs(np.polyval(fit, piece[:, 0]) - piece[:, 1]).max() < 0.5


# --- off-screen renders --------------------------------------------------------------------
def test_render_is_not_blank_and_changes_with_the_handle(result):
    first = pane.render_weights(result, 0, window_size=SIZE, camera=(30.0, 20.0))
    assert first.shape == (SIZE[1], SIZE[0], 3) and first.dtype == np.uint8
    assert first.std() > 20
    assert len(np.unique(first.reshape(-1, 3), axis=0)) > 50
    other = pane.render_weights(result, 3, window_size=SIZE, camera=(30.0, 20.0))  # same view, other weights
    changed = np.abs(first.astype(int) - other.astype(int)).max(axis=2) > 30
    centre = changed[SIZE[1] // 4 : 3 * SIZE[1] // 4, SIZE[0] // 4 : 3 * SIZE[0] // 4]
    assert centre.mean() > 0.3  # the sphere's middle is recoloured
    looking = pane.render_weights(result, 3, window_size=SIZE)  # the camera follows the handle
    assert np.abs(looking.astype(int) - other.astype(int)).max(axis=2).mean() > 10


def test_texture_render_shows_the_panorama(result):
    textured = pane.render_weights(result, 0, window_size=SIZE, texture=True)
    assert textured.shape == (SIZE[1], SIZE[0], 3)
    assert textured.std() > 20
    coloured = pane.render_weights(result, 0, window_size=SIZE)
    assert np.abs(textured.astype(int) - coloured.astype(int)).mean() > 10
    # an image split in two: the top (north) red, the bottom blue; looking at the equator from
    # above, the upper half of the sphere must be red (the texture is not upside down)
    halves = np.zeros((256, 512, 3), np.uint8)
    halves[:128, :, 0] = 255
    halves[128:, :, 2] = 255
    view = pane.render_weights(result, 0, window_size=SIZE, texture=True, image=halves, camera=(150.0, 0.0)).astype(int)
    upper, lower = view[SIZE[1] // 2 - 50, SIZE[0] // 2], view[SIZE[1] // 2 + 50, SIZE[0] // 2]
    assert upper[0] > 150 > upper[2] and lower[2] > 150 > lower[0]


# --- 2D ------------------------------------------------------------------------------------
def test_weights_overlay_is_high_at_a_point_handle(result):
    out = pane.weights_overlay(result, 3, width=512)
    assert out.shape == (256, 512, 3) and out.dtype == np.uint8
    pure = pane.weights_overlay(result, 3, width=512, alpha=1.0, draw=False)  # the colour map alone
    x, y = np.round(coords.lonlat_to_px(POINT["target"], 512)).astype(int)
    near = pure[y - 2 : y + 3, x - 2 : x + 3].reshape(-1, 3).astype(int)
    assert np.all(near[:, 0] > 200) and np.all(near[:, 1] > 200) and np.all(near[:, 2] < 100)  # viridis at 1: yellow
    far = np.round(coords.lonlat_to_px(coords.wrap_lon(np.array([POINT["target"][0] - 180.0, 0.0])), 512)).astype(int)
    r, g, b = pure[far[1], far[0]].astype(int)
    assert r < 100 and b > g  # viridis near 0: dark purple
    with pytest.raises(ValueError, match="alpha"):
        pane.weights_overlay(result, 0, alpha=2.0)


# --- refinement ----------------------------------------------------------------------------
def test_refinement_rounds_grow_and_end_with_the_results_mesh(result):
    rounds = pane.refinement_rounds(result)
    assert len(rounds) == 4 + 2  # the base icosphere, four rounds, the final mesh
    counts = [len(v) for v, _ in rounds]
    assert counts[0] == 42 and bool(np.all(np.diff(counts) > 0))
    np.testing.assert_array_equal(rounds[-1][0], result.vertices)
    np.testing.assert_array_equal(rounds[-1][1], result.faces)
    for v, f in rounds:
        assert v.dtype == np.float64 and v.shape[1] == 3 and f.dtype == np.int64 and f.max() < len(v)
    from_constraints = pane.refinement_rounds(build_constraints(result.handles))
    np.testing.assert_array_equal(from_constraints[-1][0], result.vertices)
    np.testing.assert_array_equal(from_constraints[-1][1], result.faces)


# --- the notebook pane ---------------------------------------------------------------------
def test_pane_on_a_result_shows_a_png_and_recolours(result):
    requires.module("ipywidgets")
    shown = pane.WeightsPane(result, 0, backend="static", window_size=SIZE)
    assert shown.backend == "static" and shown.handle == 0
    assert shown._view.value[:8] == b"\x89PNG\r\n\x1a\n"
    before = shown.image.copy()
    shown.handle = 2
    assert shown.handle == 2 and not np.array_equal(before, shown.image)
    with pytest.raises(IndexError):
        shown.handle = 9
    with pytest.raises(ValueError, match="backend"):
        pane.WeightsPane(result, backend="vtk")


def test_pane_html_backend_exports_a_self_contained_page(result):
    """the trame-vtk export: vtk.js and the scene in one page that fetches nothing (the browser test renders it)."""
    requires.module("trame_vtk")
    import html
    import re

    shown = pane.WeightsPane(result, 1, window_size=SIZE, backend="html")
    assert shown.backend == "html" and shown.image is None
    page = shown.html
    assert page.count("<script") >= 1 and "vtk" in page and len(page) > 100_000
    assert re.findall(r"""(?:src|href)\s*=\s*["']?(https?:[^"'\s>]+)""", page) == [] and "vtk-js/icon" not in page
    prefix = '<iframe class="ow-weights-view" data-handle="1" srcdoc="'
    assert shown._view.value.startswith(prefix)
    assert html.unescape(shown._view.value[len(prefix) : shown._view.value.index('" width=')]) == page
    shown.handle = 2
    assert shown.html != page and 'data-handle="2"' in shown._view.value


def test_auto_backend_is_static_without_trame():
    import importlib.util

    expected = "html" if importlib.util.find_spec("trame_vtk") else "static"
    assert pane._choose_backend("auto") == expected


def test_pane_follows_the_editors_selection():
    requires.module("anywidget")
    editor = ow.Editor(ow.sample_image(), handles=SCENE, preview_width=512)
    editor.wait()
    shown = pane.WeightsPane(editor, window_size=SIZE, backend="static")
    assert shown.handle == 0 and shown.result is editor.preview_result
    before = shown.image.copy()
    editor.selected = 1
    assert shown.wait() and shown.handle == 1
    assert np.abs(shown.image.astype(int) - before.astype(int)).max(axis=2).mean() > 5
    editor.selected = -1  # deselecting keeps the last handle on show
    assert shown.wait() and shown.handle == 1
    # a new preview is followed too
    old = editor.preview_result
    editor.handles = {**SCENE, "handles": SCENE["handles"][1:]}
    editor.wait()
    assert shown.wait() and editor.preview_result is not old and shown.result is editor.preview_result
    assert shown._shown is editor.preview_result and shown.message == ""
    shown.close()
    editor.selected = 2
    assert shown.handle == 1  # no longer following


def test_pane_shows_a_message_until_the_editor_has_a_mesh():
    requires.module("anywidget")
    paper = {**SCENE, "options": {"anchor": None}}  # one point, one map: no mesh (with a still background there would be one)
    editor = ow.Editor(ow.sample_image(), handles={**paper, "handles": [POINT]}, preview_width=512)
    shown = pane.WeightsPane(editor, window_size=SIZE, backend="static")
    assert shown.image is None and "no mesh" in shown.message and "no mesh" in shown._caption.value
    editor.handles = paper
    editor.wait()
    assert shown.wait() and shown.message == "" and shown.image is not None and shown.image.std() > 20
