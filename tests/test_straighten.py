"""``ow.straighten`` and ``omniwidget straighten``: level, find the structure, rectify it, hand back the handles.

Generated rooms whose camera tilt and edges are known exactly: the result is one-to-one,
every line used is straight along its whole length, the room's vertical edges come out
vertical, and the handles document handed back reproduces the result.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

import omniwidget as ow
from omniwidget.app.cli import main
from omniwidget.evaluate.quality import vertical_tilt
from omniwidget.evaluate.scenes import synthetic_room
from omniwidget.io.images import read_image, write_image

PITCH, ROLL = 8.0, -6.0
WIDTH = 1024


@pytest.fixture(scope="module")
def room():
    return synthetic_room(WIDTH, pitch=PITCH, roll=ROLL, noise=2.0, seed=3, yaw=25.0)


@pytest.fixture(scope="module")
def done(room):
    return ow.straighten(room.image)


def _up() -> np.ndarray:
    p, r = math.radians(PITCH), math.radians(ROLL)
    return np.array([math.sin(p) * math.cos(r), -math.sin(r), math.cos(p) * math.cos(r)])


def _vertical_edges(room) -> list:
    """The box's own vertical edges (the room's four corners)."""
    up = _up()
    out = []
    for line in room.lines:
        d = np.subtract(line.end_3d, line.start_3d)
        if line.kind == "edge" and abs(d @ up) > 0.9999 * np.linalg.norm(d):
            out.append(line)
    return out


def test_straighten_levels_rectifies_and_hands_back_the_handles(room, done):
    s = done.structure
    assert s.level is not None and s.level.tilt == pytest.approx(math.hypot(PITCH, ROLL), abs=0.3)
    doc = done.handles
    assert doc.options.up == s.level.up and doc.options.anchor == ow.Options().anchor  # levelled, the default mode
    assert len(doc.handles) == len(s.used) >= 8 and all(h.kind == "line" and h.rectify for h in doc.handles)
    assert {x.kind for x in s.used} >= {"vertical", "horizontal"}
    assert all(isinstance(why, str) and why for _, why in s.dropped)
    kinds = {"texture", "crossing a kept line", "beside a kept line", "short and neither vertical nor horizontal"}
    kinds |= {"beyond the first ones kept", "over a pole", "crossing in the output", "gave way in the warp"}
    assert {why.kind for _, why in s.dropped} <= kinds and "texture" in {why.kind for _, why in s.dropped}
    assert s.summary().endswith(")") and " texture" in s.summary()  # counted by kind
    # one-to-one, and every line used straight along its whole length (measured densely through the map that placed the pixels)
    q = done.result.quality
    assert done.result.folds.area == 0 and done.result.gave_way == ()
    shown = [v for v in q.lines if math.isfinite(v)]
    assert len(q.lines) == len(doc.handles) and max(shown) <= 0.5, q.lines
    # a line whose few samples next to a room corner the dense search does not find is "not shown whole" (NaN):
    # measured 2 of 10 here, 4 samples of 350-450 each, at the corners where a floor edge meets a vertical one
    assert len(shown) >= len(q.lines) - 2, q.lines
    print(f"\nstraighten: {done.summary()}")
    # the handles handed back are the warp: warped again they give the same image
    again = ow.warp(room.image, ow.Handles.from_json(doc.to_json()), warn=False)
    assert np.abs(again.image.astype(int) - done.image.astype(int)).max() <= 1


def test_the_rooms_vertical_edges_come_out_vertical(room, done):
    placed = done.result.placed_map()
    tilts = [vertical_tilt(placed, line.start, line.end) for line in _vertical_edges(room)]
    print(f"\nvertical edges' tilt after straighten: {np.round(tilts, 3)}° (before: {math.hypot(PITCH, ROLL):.1f}°)")
    assert len(tilts) == 4 and max(tilts) < 0.2
    # and measured before, the same way: the tilt of the camera
    unwarped = ow.warp(room.image, ow.Handles(), warn=False).placed_map()
    before = [vertical_tilt(unwarped, line.start, line.end) for line in _vertical_edges(room)]
    assert min(before) > 1.0 and max(before) > 5.0, before  # each edge leans as much as its direction sees of the tilt


def test_straighten_without_levelling_keeps_the_vertical_and_says_what_it_could_not():
    flat = np.full((256, 512, 3), 120, np.uint8)  # nothing to find: not levelled, no line, the panorama as it was
    done = ow.straighten(flat)
    assert done.structure.level is None and done.structure.notes and done.structure.notes[0].startswith("not levelled: ")
    assert done.handles.handles == () and done.handles.options.up is None
    assert np.array_equal(done.image, flat)
    assert done.structure.summary().startswith("not levelled; 0 lines straightened")
    with pytest.raises(ValueError, match="max_lines"):
        ow.straighten(flat, max_lines=0)


def test_the_command_writes_the_result_the_handles_and_the_map(tmp_path, room, done, capsys):
    write_image(tmp_path / "room.png", room.image)
    argv = ["straighten", str(tmp_path / "room.png"), "-o", str(tmp_path / "out.png"), "-H", str(tmp_path / "used.json"), "--map", str(tmp_path / "m.npy")]
    assert main(argv) == 0
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 2 and err[0].startswith("omniwidget straighten: levelled by pitch ") and "lines straightened" in err[0], err
    assert err[1].startswith("omniwidget straighten: wrote ") and "fold" in err[1], err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.npy", "out.png", "room.png", "used.json"]
    used = ow.load_handles(tmp_path / "used.json")
    assert used == done.handles  # what the function finds on the same image
    out = read_image(tmp_path / "out.png")
    assert np.abs(out.astype(int) - done.image.astype(int)).max() <= 1
    # the map saved reproduces the output: warp --apply-map
    assert main(["warp", str(tmp_path / "room.png"), "--apply-map", str(tmp_path / "m.npy"), "-o", str(tmp_path / "again.png")]) == 0
    assert np.abs(read_image(tmp_path / "again.png").astype(int) - out.astype(int)).max() <= 1
    # refused before any work: an output over the input, a handles file that is not JSON
    capsys.readouterr()
    assert main(["straighten", str(tmp_path / "room.png"), "-o", str(tmp_path / "room.png")]) == 2
    assert main(["straighten", str(tmp_path / "room.png"), "-o", str(tmp_path / "o.png"), "-H", str(tmp_path / "used.txt")]) == 2
    assert main(["straighten", str(tmp_path / "room.png"), "-o", str(tmp_path / "o.png"), "--max-lines", "0"]) == 2
    err = capsys.readouterr().err
    assert "would overwrite the input" in err and ".json" in err and "--max-lines 0" in err and "Traceback" not in err
    assert not (tmp_path / "o.png").exists()
    json.loads((tmp_path / "used.json").read_text())  # left as it was


def test_the_editing_session_straightens_as_one_undoable_edit(tmp_path, room, done):
    from omniwidget.app.session import EditingSession

    path = tmp_path / "room.png"
    write_image(path, room.image)
    sent: list = []
    s = EditingSession(path, autosave=False, quality=False, preview_width=256, on_message=lambda content, buffers: sent.append(content))
    s.start()
    s.edit({"handles": [{"kind": "point", "position": [10.0, 0.0], "target": [12.0, 1.0]}]})
    before = s.handles
    s.command({"op": "straighten"})
    assert s.idle(120)
    assert sent.count({"done": "straighten"}) == 1
    job = s.status["straighten"]
    assert job["state"] == "done" and "lines straightened" in job["message"] and job["lines"] == len(s.document.handles), job
    assert s.document == done.handles  # the handles the function finds on the same panorama (the detector's width: 1024 here)
    assert s.history["undo"] == 2
    s.undo()
    assert s.handles == before
    # a second Straighten while one runs is refused, the handles kept
    s.straighten()
    with pytest.raises(ow.OmniwidgetError, match="being straightened already"):
        s.straighten()
    assert s.idle(120) and s.status["straighten"]["state"] == "done"
