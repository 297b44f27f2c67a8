"""Suggested lines and Level in the editor, without a browser: the session and the widget's messages.

A generated room with a known tilt: "Suggest lines" runs in the background and shows the
suggestions; accepting one, or all, is one undoable edit, dropping them is none; "Level"
runs in the background and applies the rotation as one undoable edit; too few vertical
edges leave the handles as they were, with the reason in the status.
"""

from __future__ import annotations

import threading

import numpy as np
import pytest

from omniwidget.app.session import EditingSession
from omniwidget.document.handles import LineHandle, Options
from omniwidget.errors import LevelError
from omniwidget.evaluate.scenes import synthetic_room
from omniwidget.io.images import write_image
from omniwidget.sphere import coords

PITCH, ROLL = 6.0, -4.0
WIDTH = 1024
LINE = {"kind": "line", "start": [-120.0, 20.0], "end": [-100.0, 22.0], "rectify": False}
TIMEOUT = 120


@pytest.fixture(scope="module")
def room_path(tmp_path_factory):
    path = tmp_path_factory.mktemp("room") / "room.png"
    write_image(path, synthetic_room(WIDTH, pitch=PITCH, roll=ROLL).image)
    return path


def _session(image, **kwargs) -> EditingSession:
    kwargs.setdefault("autosave", False)
    kwargs.setdefault("quality", False)
    kwargs.setdefault("preview_width", 256)
    session = EditingSession(image, **kwargs)
    session.start()
    return session


def _up() -> np.ndarray:
    """Where the tilted camera sees the zenith, [lon, lat] (omniwidget.evaluate.scenes: tilted camera)."""
    p, r = np.radians(PITCH), np.radians(ROLL)
    return coords.xyz_to_lonlat(np.array([np.sin(p) * np.cos(r), -np.sin(r), np.cos(p) * np.cos(r)]))


def _flat() -> np.ndarray:
    """A panorama with no edge at all: sky to floor, a little noise."""
    rng = np.random.default_rng(5)
    lat = np.linspace(1.0, 0.0, 256)[:, None, None]
    return np.clip(90 + 100 * lat + rng.normal(0, 2, (256, 512, 3)), 0, 255).astype(np.uint8)


def test_suggest_accept_one_accept_all_drop_and_undo_by_the_front_end_s_commands(room_path, monkeypatch):
    import omniwidget.detect as detect

    release, entered = threading.Event(), threading.Event()
    real = detect.suggest_lines

    def held(*args, **kwargs):
        entered.set()
        assert release.wait(60)
        return real(*args, **kwargs)

    monkeypatch.setattr(detect, "suggest_lines", held)
    sent = []
    s = _session(room_path, handles={"handles": [LINE]}, on_message=lambda content, buffers: sent.append(content))
    s.wait(TIMEOUT)
    s.command({"op": "suggest"})  # in the background: the widget never waits (the detector is held until released)
    assert entered.wait(30)
    assert s.status["suggest"]["state"] == "running"
    release.set()
    assert s.idle(TIMEOUT)
    assert s.status["suggest"]["state"] == "done", s.status["suggest"]
    shown = s.suggestions
    assert 10 <= len(shown) <= 40 and "suggested lines" in s.status["suggest"]["message"]
    assert [x["key"] for x in shown] == sorted(x["key"] for x in shown)  # best first
    assert all(0 <= x["confidence"] <= 1 and x["length"] > 0 for x in shown)
    assert len(s.document) == 1 and s.history["undo"] == 0  # suggestions are no handles

    # accept one: one line handle more, one undoable edit, gone from the dashed set
    first = shown[3]
    s.command({"op": "accept_suggestion", "key": first["key"]})
    assert sent[-1] == {"done": "accept_suggestion"}
    (added,) = s.document.handles[1:]
    assert isinstance(added, LineHandle) and list(added.start) == first["start"] and list(added.end) == first["end"]
    assert s.history["undo"] == 1 and first["key"] not in [x["key"] for x in s.suggestions]
    assert len(s.suggestions) == len(shown) - 1
    # a key no longer shown is refused, the handles kept
    s.command({"op": "accept_suggestion", "key": first["key"]})
    assert "is not shown" in s.status["error"] and len(s.document) == 2

    # undo: the handle goes, the suggestion is shown again
    s.undo()
    assert len(s.document) == 1 and len(s.suggestions) == len(shown)
    s.redo()
    assert len(s.document) == 2

    # accept all: every remaining suggestion in one edit
    s.command({"op": "accept_all"})
    assert len(s.document) == 1 + len(shown) and s.suggestions == [] and s.history["undo"] == 2
    s.undo()
    assert len(s.document) == 2 and len(s.suggestions) == len(shown) - 1

    # drop one, then all: no edit
    s.command({"op": "drop_suggestions", "key": s.suggestions[0]["key"]})
    assert len(s.suggestions) == len(shown) - 2 and s.history["undo"] == 1
    s.command({"op": "drop_suggestions"})
    assert s.suggestions == [] and s.history["undo"] == 1 and len(s.document) == 2
    s.wait(TIMEOUT)
    assert s.status["state"] == "idle"


def test_level_applies_the_rotation_as_one_undoable_edit_carrying_the_handles(room_path):
    sent = []
    s = _session(room_path, handles={"handles": [LINE]}, on_message=lambda content, buffers: sent.append(content))
    s.wait(TIMEOUT)
    before = s.handles
    s.command({"op": "level"})
    assert s.idle(TIMEOUT)
    assert sent.count({"done": "level"}) == 1
    assert s.status["level"]["state"] == "done", s.status
    assert "pitch" in s.status["level"]["message"] and "roll" in s.status["level"]["message"]
    doc = s.document
    assert len(doc) == 1 and doc.options.up is not None and doc.options.anchor == Options().anchor and s.history["undo"] == 1  # the mode kept
    # the rotation takes where the camera saw the zenith to the north pole
    error = 90.0 - float(doc.options.levelling()(_up())[1])
    print(f"\nlevel in the editor: the zenith lands {error:.3f}° from the pole")
    assert error < 0.3
    s.wait(TIMEOUT)
    assert s.status["state"] == "idle"
    s.undo()
    assert s.handles == before


def test_level_never_blocks_and_lands_on_the_handles_as_they_are_then(room_path, monkeypatch):
    import omniwidget.detect as detect

    release, entered = threading.Event(), threading.Event()
    real = detect.level

    def slow(*args, **kwargs):
        entered.set()
        assert release.wait(60)
        return real(*args, **kwargs)

    monkeypatch.setattr(detect, "level", slow)
    s = _session(room_path)
    s.level()  # returns while the detector is held: it runs in the background
    assert entered.wait(30)
    assert s.status["level"]["state"] == "running"
    with pytest.raises(ValueError, match="being levelled already"):
        s.level()
    s.edit({"handles": [LINE]})  # an edit meanwhile: kept under the rotation
    release.set()
    assert s.idle(TIMEOUT)
    assert [h.kind for h in s.document.handles] == ["line"] and s.document.options.up is not None
    assert s.history["undo"] == 2
    s.undo()
    assert [h.kind for h in s.document.handles] == ["line"] and s.document.options.up is None


def test_an_edit_made_while_the_rotation_is_applied_is_not_undone_by_it(room_path, monkeypatch):
    import omniwidget.detect as detect

    real = detect.level_document
    s = _session(room_path)
    calls = []

    def racing(doc, rotation):
        calls.append(len(doc))
        if len(calls) == 1:
            s.edit({"handles": [LINE]})  # the person's edit arrives while the first document is being levelled
        return real(doc, rotation)

    monkeypatch.setattr(detect, "level_document", racing)
    s.level(wait=True)
    assert calls == [0, 1]  # levelled again, on the handles with the edit
    assert [h.kind for h in s.document.handles] == ["line"] and s.document.options.up is not None
    assert s.status["level"]["state"] == "done"


def test_too_few_vertical_edges_is_said_and_changes_nothing():
    sent = []
    s = _session(_flat(), handles={"handles": [LINE]}, on_message=lambda content, buffers: sent.append(content))
    s.wait(TIMEOUT)
    before, history = s.handles, dict(s.history)
    s.command({"op": "level"})
    assert s.idle(TIMEOUT)
    assert s.handles == before and s.history == history
    assert s.status["level"]["state"] == "error"
    assert "vertical" in s.status["error"] and s.status["error"].startswith("could not level the panorama: ")
    assert isinstance(s.last_error, LevelError)
    assert sent.count({"done": "level"}) == 1
    with pytest.raises(LevelError):
        s.level(wait=True)
    s.command({"op": "suggest"})
    assert s.idle(TIMEOUT)
    assert s.status["suggest"]["state"] == "done" and s.suggestions == []
    assert "none found" in s.status["suggest"]["message"]


def test_the_widget_syncs_the_suggestions_and_levels_from_python(room_path):
    pytest.importorskip("anywidget")
    from omniwidget.widget import Editor

    ed = Editor(room_path, autosave=False, quality=False, preview_width=256)
    ed.wait()
    ed.suggest_lines(max_lines=4, wait=True)  # a few: every edit after is recomputed with them
    assert 1 <= len(ed.suggestions) <= 4 and ed.suggestions == ed.session.suggestions
    key = ed.suggestions[0]["key"]
    ed.accept_suggestion(key)
    assert len(ed.handles["handles"]) == 1 and key not in [x["key"] for x in ed.suggestions]
    remaining = len(ed.suggestions)
    assert ed.accept_all_suggestions() == remaining
    assert ed.suggestions == [] and len(ed.handles["handles"]) >= 2
    ed.level(wait=True)
    assert ed.handles["options"]["up"][1] > 45 and ed.handles["options"]["anchor"] == Options().anchor
    ed.wait()
    ed.undo()
    assert "up" not in ed.handles["options"]
    ed.session.idle(TIMEOUT)
