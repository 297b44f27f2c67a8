"""The editor widget's model, without a browser: what the kernel does with what the front end sends."""

import json

import cv2
import numpy as np
import pytest

pytest.importorskip("anywidget")

import omniwidget as ow  # noqa: E402
from omniwidget.core import pipeline  # noqa: E402
from omniwidget.core.handles import PointHandle  # noqa: E402
from omniwidget.core.quality import line_straightness  # noqa: E402
from omniwidget.widget import Editor, saved_handles  # noqa: E402
from omniwidget.widget.editor import DISPLAY_WIDTH, HISTORY  # noqa: E402

WINDOW_TOP = {"kind": "line", "start": [-4.0, 37.5], "end": [68.0, 36.5], "rectify": False}


def doc(*handles, rectify="all"):
    return {"format": "omniwidget.handles", "version": 1, "handles": list(handles), "options": {"rectify": rectify}}


def decoded(data: bytes) -> np.ndarray:
    image = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
    assert image is not None
    return image


@pytest.fixture
def editor():
    ed = Editor(ow.sample_path())
    ed.wait()
    return ed


def test_opens_a_path_or_an_array_and_shows_input_and_result(editor):
    assert editor.status["state"] == "idle"
    assert decoded(editor.source).shape == (512, 1024, 3)
    assert decoded(editor.preview).shape == (512, 1024, 3)
    same = Editor(ow.sample_image())
    same.wait()
    assert same.source == editor.source
    assert same.handles_path.name == "panorama.handles.json"
    assert editor.handles_path.name == "hotel_room.handles.json"


def test_large_panoramas_are_sent_downscaled_and_computed_at_preview_size():
    big = cv2.resize(ow.sample_image(), (4096, 2048), interpolation=cv2.INTER_CUBIC)
    ed = Editor(big, doc({"kind": "point", "position": [0.0, 0.0], "scale": 1.5}))
    ed.wait()
    assert decoded(ed.source).shape[:2] == (DISPLAY_WIDTH // 2, DISPLAY_WIDTH)
    assert decoded(ed.preview).shape[:2] == (512, 1024)
    assert ed.source_size == [4096, 2048]
    assert ed.result.image.shape == big.shape  # the full-size result stays in Python


@pytest.mark.parametrize(
    "image",
    [
        np.full((64, 128), 40000, np.uint16),
        np.full((64, 128, 4), 0.5, np.float32),
        np.full((64, 128, 2), 200, np.uint8),
    ],
    ids=["uint16 gray", "float RGBA", "gray+alpha"],
)
def test_any_supported_panorama_is_shown_as_rgb(image):
    ed = Editor(image)
    ed.wait()
    shown = decoded(ed.source)
    assert shown.shape == (64, 128, 3)
    expected = {np.uint16: 40000 >> 8, np.float32: 128, np.uint8: 200}[image.dtype.type]
    assert abs(float(np.median(shown)) - expected) <= 2


def test_handles_set_from_python_are_validated_and_synced(editor):
    editor.handles = doc(WINDOW_TOP)
    assert editor.document.handles[0].start == (-4.0, 37.5)
    editor.handles = ow.Handles([ow.PointHandle(position=(10.0, 5.0))])  # a document object
    assert editor.handles["handles"][0]["kind"] == "point"
    editor.handles = json.dumps(doc(WINDOW_TOP))  # or its JSON text
    assert editor.handles["handles"][0]["kind"] == "line"
    before = editor.handles
    with pytest.raises(ow.HandlesError, match=r"handles\[0\]\.end"):
        editor.handles = doc({"kind": "line", "start": [0, 0], "end": [0, 0]})
    assert editor.handles == before


def test_state_from_the_front_end_is_applied_and_bad_state_is_reported_not_raised(editor):
    editor.set_state({"handles": doc(WINDOW_TOP)})
    assert editor.document.handles[0].end == (68.0, 36.5)
    kept = editor.handles
    editor.set_state({"handles": doc({"kind": "cage", "vertices": [[0, 0], [1, 0]]})})
    assert editor.handles == kept
    assert "handles[0].vertices" in editor.status["error"]


def test_outputs_follow_the_handles(editor):
    point = PointHandle(position=(20.0, 10.0), target=(30.0, 5.0), scale=2.0, rotation=30.0)
    editor.handles = doc(json.loads(ow.Handles([point]).to_json())["handles"][0], {**WINDOW_TOP, "rectify": True})
    editor.wait()
    outputs = editor.outputs
    np.testing.assert_allclose(outputs[0], point.target_points(), atol=1e-8)
    # the rectified line: endpoints kept, middle at the lon/lat midpoint (one line: eq. 4)
    np.testing.assert_allclose(outputs[1], [[-4, 37.5], [32, 37], [68, 36.5]], atol=1e-6)


def test_undo_and_redo_every_edit_wherever_it_came_from(editor):
    first = editor.handles
    editor.set_state({"handles": doc(WINDOW_TOP)})  # drawn in the browser
    editor.handles = doc(WINDOW_TOP, {"kind": "point", "position": [90.0, 0.0]})  # set from Python
    editor._on_message(editor, {"op": "rectify_all"}, [])  # a button
    assert editor.history == {"undo": 3, "redo": 0}
    editor._on_message(editor, {"op": "undo"}, [])
    assert editor.document.handles[0].rectify is False
    assert editor.undo() and editor.undo()
    assert editor.handles == first
    assert not editor.undo()
    assert editor.history == {"undo": 0, "redo": 3}
    assert editor.redo()
    assert len(editor.document) == 1
    editor.handles = doc()  # a new edit forgets what was undone
    assert editor.history == {"undo": 2, "redo": 0}


def test_history_is_bounded_but_deep(editor):
    for i in range(HISTORY + 20):
        editor.handles = doc({"kind": "point", "position": [float(i % 300) - 150, 0.0]})
    assert editor.history["undo"] == HISTORY >= 100


def test_rectify_all_makes_the_drawn_line_straight(editor):
    editor.handles = doc(WINDOW_TOP)
    editor.wait()
    before = decoded(editor.preview)
    editor._on_message(editor, {"op": "rectify_all"}, [])
    status = editor.wait()
    assert status["state"] == "idle"
    line = editor.document.handles[0]
    assert line.rectify and editor.document.options.rectify == "all"
    after = decoded(editor.preview)
    changed = np.abs(after.astype(int) - before.astype(int)).max(axis=2) > 40
    assert changed[40:160, 480:720].mean() > 0.02  # about the window's top edge
    result = editor.result
    samples = ow.core.coords.geodesic(line.start, line.end, np.linspace(0, 1, 60))
    bent = line_straightness(pipeline.warp(ow.sample_image(), ow.Handles()).inverse_map(np.float64), samples)
    straight = line_straightness(result.inverse_map(np.float64), samples, start=result.controls[0].moebius(samples))
    assert bent > 5.0 and straight < 0.3


def test_rectify_selected_line_and_reset(editor):
    other = {"kind": "line", "start": [-83.0, 12.0], "end": [-45.5, 12.0], "rectify": False}
    editor.handles = doc(WINDOW_TOP, other)
    editor._on_message(editor, {"op": "rectify_line", "index": 1}, [])
    line = editor.document.handles[1]
    assert line.targets is not None and not line.rectify
    assert editor.document.handles[0].targets is None  # the other line is left alone
    editor._on_message(editor, {"op": "reset", "index": 1}, [])
    assert editor.document.handles[1].targets is None and not editor.document.handles[1].rectify
    editor._on_message(editor, {"op": "rectify_line", "index": 5}, [])
    assert "handles[5]" in editor.status["error"]
    assert len(editor.document) == 2


def test_dragging_an_arrow_tip_turns_and_zooms_the_point(editor):
    point = PointHandle(position=(40.0, -10.0), target=(45.0, -8.0))
    editor.handles = ow.Handles([point])
    tip = [60.0, 0.0]
    editor._on_message(editor, {"op": "arrow", "index": 0, "which": "east", "tip": tip}, [])
    moved = editor.document.handles[0]
    expected = point.with_arrow_tip(tip, "east")
    assert moved.scale == pytest.approx(expected.scale) and moved.rotation == pytest.approx(expected.rotation)
    assert moved.scale != 1.0 and moved.rotation != 0.0
    editor.wait()
    np.testing.assert_allclose(editor.outputs[0][1], tip, atol=1e-6)  # the tip is where it was dropped


def test_an_error_in_the_kernel_is_shown_and_the_handles_are_kept(editor, monkeypatch):
    def broken(*args, **kwargs):
        raise RuntimeError("the solver gave up")

    editor.handles = doc(WINDOW_TOP)
    editor.wait()
    shown = editor.preview
    monkeypatch.setattr(pipeline, "warp", broken)
    editor.handles = doc({**WINDOW_TOP, "rectify": True})
    status = editor.wait()
    assert status["state"] == "error" and "the solver gave up" in status["error"]
    assert editor.document.handles[0].rectify  # the edit is kept
    assert editor.preview == shown  # the last good image stays


def test_a_newer_edit_supersedes_a_running_computation(editor, monkeypatch):
    import threading

    started, release = threading.Event(), threading.Event()
    real = pipeline.warp
    seen = []

    def slow(image, handles, **kwargs):
        seen.append(handles)
        if len(seen) == 1:
            started.set()
            release.wait(10)
        return real(image, handles, **kwargs)

    monkeypatch.setattr(pipeline, "warp", slow)
    editor.handles = doc(WINDOW_TOP)
    assert started.wait(10)
    editor.handles = doc({**WINDOW_TOP, "rectify": True})  # while the first runs
    editor.handles = doc({**WINDOW_TOP, "rectify": True}, {"kind": "point", "position": [100.0, 0.0]})
    release.set()
    status = editor.wait()
    assert status["state"] == "idle"
    assert len(seen) == 2  # the middle edit was never computed
    assert editor.preview_result.handles == editor.document  # what is shown is the newest edit
    assert status["generation"] == editor._generation


def test_save_and_load_handles_files(editor, tmp_path):
    editor.handles = doc(WINDOW_TOP)
    path = editor.save(tmp_path / "mine.json")
    assert ow.load_handles(path) == editor.document
    editor.handles = doc()
    editor.load(path)
    assert editor.document.handles[0].start == (-4.0, 37.5)
    editor.handles_path = tmp_path / "button.json"
    editor._on_message(editor, {"op": "save"}, [])
    assert ow.load_handles(tmp_path / "button.json") == editor.document
    assert "saved 1 handles" in editor.status["message"]
    editor._on_message(editor, {"op": "load", "name": "broken.json", "text": '{"handles": [{"kind": "point"}]}'}, [])
    assert editor.status["error"].startswith("broken.json: handles[0].position")
    assert len(editor.document) == 1
    editor._on_message(
        editor, {"op": "load", "name": "two.json", "text": json.dumps(doc(WINDOW_TOP, {"kind": "point", "position": [9, 9]}))}, []
    )
    assert len(editor.document) == 2


def test_folds_and_conflicts_are_reported_with_the_handles_named():
    # Fig. 15: a point moved into a fixed cage
    cage = {"kind": "cage", "vertices": [[-20, -15], [20, -15], [20, 15], [-20, 15]]}
    point = {"kind": "point", "position": [40.0, 0.0], "target": [0.0, 0.0]}
    ed = Editor(ow.sample_image(), doc(cage, point))
    status = ed.wait()
    assert status["fold_area"] > 1e-4
    assert status["conflicts"] == [0, 1]
    overlay = decoded(ed.folds)
    assert overlay.shape == (512, 1024, 4) and (overlay[:, :, 3] > 0).mean() == pytest.approx(ed.preview_result.folds.mask.mean())


def test_full_size_on_demand(editor):
    editor.handles = doc({**WINDOW_TOP, "rectify": True})
    editor._on_message(editor, {"op": "full"}, [])
    status = editor.wait()
    assert status["width"] == 1024 and editor.result is editor.preview_result


def test_handles_survive_in_a_saved_notebooks_widget_state(editor, tmp_path):
    import nbformat
    from ipywidgets import Widget

    editor.handles = doc(WINDOW_TOP, {"kind": "point", "position": [100.0, -20.0], "scale": 2.0})
    nb = nbformat.v4.new_notebook()
    nb.cells.append(nbformat.v4.new_code_cell("editor"))
    nb.metadata["widgets"] = {
        "application/vnd.jupyter.widget-state+json": {
            "version_major": 2,
            "version_minor": 0,
            "state": Widget.get_manager_state(drop_defaults=False)["state"],
        }
    }
    path = tmp_path / "work.ipynb"
    nbformat.write(nb, path)
    found = [d for d in saved_handles(path) if d == editor.document]
    assert found
    again = Editor(ow.sample_image(), handles=found[0])
    assert again.handles == editor.handles


def test_outputs_of_lines_split_at_a_crossing_come_from_their_pieces(editor):
    a = {"kind": "line", "start": [-30.0, 0.0], "end": [30.0, 10.0]}
    b = {"kind": "line", "start": [-10.0, -15.0], "end": [5.0, 25.0]}
    editor.handles = doc(a, b)
    editor.wait()
    assert len(editor.preview_result.controls) == 4  # each line split in two at the crossing
    for h, out in zip((a, b), editor.outputs, strict=True):
        assert np.isfinite(out).all() and len(out) == 3
        assert ow.core.coords.angular_distance(out[0], h["start"]) < 1.0
        assert ow.core.coords.angular_distance(out[2], h["end"]) < 1.0


def test_a_refused_command_while_computing_keeps_the_result_coming(editor, monkeypatch):
    import threading

    started, release = threading.Event(), threading.Event()
    real = pipeline.warp

    def slow(image, handles, **kwargs):
        started.set()
        release.wait(10)
        return real(image, handles, **kwargs)

    monkeypatch.setattr(pipeline, "warp", slow)
    editor.handles = doc({**WINDOW_TOP, "rectify": True})
    assert started.wait(10)
    editor._on_message(editor, {"op": "rectify_line", "index": 3}, [])
    release.set()
    status = editor.wait()
    assert status["state"] == "idle" and editor.preview_result.handles == editor.document
    assert "handles[3]" in status["error"]  # the message outlives the result that arrived after it
