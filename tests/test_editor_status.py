"""The editor's status area, in Python: what the session says, grouped and current.

Each warning comes with a kind (the class of :class:`~omniwidget.raster.pipeline.BlendWarning`
that made it, never read from its text), the widget's groups; the quality line measures the
lines asked to be straight and names the lines kept as they are on purpose apart; a job's
message goes when it is stale (Suggest lines' prompt once no suggestion is left, Level's and
Save's at the next edit).
"""

from __future__ import annotations

import warnings

import pytest

from omniwidget.app.session import EditingSession
from omniwidget.document.handles import CageHandle, Handles, LineHandle, Options, PointHandle
from omniwidget.evaluate.quality import kept_lines
from omniwidget.evaluate.scenes import synthetic_room
from omniwidget.io.images import write_image
from omniwidget.raster.pipeline import (
    BlendWarning,
    CageWarning,
    CrossingWarning,
    FoldWarning,
    GiveWayWarning,
    PoleLineWarning,
    warp,
)

TIMEOUT = 120
STRAIGHT = LineHandle((-60.0, 30.0), (60.0, 30.0))  # rectified: its middle comes down from 49° to about 30°
# below the straight line's arc in the input; its targets carry it up across the line's output
ACROSS = LineHandle((0.0, 5.0), (0.0, 40.0), rectify=False, targets=((0.0, 20.0), (0.0, 40.0), (0.0, 60.0)))
OVER_POLE = LineHandle((-60.0, 70.0), (110.0, 72.0))  # its arc passes about 1.5° from the north pole
STILL_CAGE = CageHandle(((100.0, -30.0), (140.0, -30.0), (140.0, 0.0), (100.0, 0.0)))
INSIDE = PointHandle((120.0, -15.0), target=(122.0, -14.0))  # moves what the cage holds still
HELD = LineHandle((-150.0, -10.0), (-110.0, -25.0), rectify=False)  # a line drawn to be held as it is


@pytest.fixture(scope="module")
def room():
    return synthetic_room(512).image


@pytest.mark.parametrize("anchor", [5.0, None], ids=["still background", "paper"])
def test_every_warning_has_the_kind_of_the_check_that_made_it(room, anchor):
    doc = Handles((STRAIGHT, ACROSS, OVER_POLE, STILL_CAGE, INSIDE), Options(anchor=anchor))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = warp(room, doc)
    issued = [(str(w.message), w.category) for w in caught if issubclass(w.category, BlendWarning)]
    assert [text for text, _ in issued] == list(result.warnings)
    assert [category.kind for _, category in issued] == list(result.warning_kinds)
    by_class = {category: [text for text, c in issued if c is category] for _, category in issued}
    # the text is the oracle here (the kinds never read it): each class holds its own check's warnings
    assert len(by_class[PoleLineWarning]) == 1 and "handles[2] (line) passes" in by_class[PoleLineWarning][0]
    assert by_class[CageWarning] == [
        "handles[4] (point) moves what handles[3] (cage) holds still: the cage's inside cannot stay where it is; "
        "move the handle out of the cage, or give the cage targets"
    ]
    assert by_class[CrossingWarning] == ["handles[0] (line) and handles[1] (line) cross each other in the output"]
    assert len(by_class[FoldWarning]) == 1 and ("folded over" in by_class[FoldWarning][0] or "folds over" in by_class[FoldWarning][0])
    assert all("gives way" in t or "give way" in t for t in by_class.get(GiveWayWarning, []))
    assert BlendWarning not in by_class  # every one has a kind of its own
    if anchor is not None:
        assert GiveWayWarning in by_class  # the two lines give way where the blend folded between them


def test_the_quality_line_measures_the_straightened_lines_and_names_the_kept_ones_apart(room):
    doc = Handles((STRAIGHT, OVER_POLE, HELD))  # the still background: the pole line is kept as it is
    result = warp(room, doc, warn=False)
    q = result.quality
    assert kept_lines(result.handles, result.constraints) == q.kept == ((1, "pole"), (2, "held"))
    by_handle = dict(zip(q.line_handles, q.lines, strict=True))
    assert not by_handle[1] <= 5.0, f"the line over the pole is far from straight (kept as it is): {by_handle[1]} px"
    assert by_handle[0] < 0.5, "the rectified line is straight"
    line = q.line()
    parts = line.split(" · ")
    assert parts[0] == f"lines within {by_handle[0]:.2g} px", line  # the headline: the straightened line only
    assert parts[1:3] == ["1 line over a pole kept as it is", "1 line held as drawn"], line
    assert "relaxed" not in line and "not shown" not in line and f"{by_handle[1]:.2g} px" not in line, line
    assert q.straightness == max(q.lines)  # the figure of every line is unchanged
    # the paper's mode twists the pole line: nothing is kept there but the held line
    paper = warp(room, Handles(doc.handles, Options(anchor=None)), warn=False).quality
    assert paper.kept == ((2, "held"),) and "over a pole" not in paper.line()


def test_the_session_sends_a_kind_per_warning(room, tmp_path):
    path = tmp_path / "room.png"
    write_image(path, room)
    doc = Handles((STRAIGHT, ACROSS, OVER_POLE, STILL_CAGE, INSIDE))
    s = EditingSession(path, doc, autosave=False, quality=True, preview_width=256)
    s.start()
    status = s.wait(TIMEOUT)
    assert len(status["warning_kinds"]) == len(status["warnings"]) >= 4
    assert status["warning_kinds"] == list(s.preview_result.warning_kinds)
    assert {"lines over a pole", "lines crossing in the output", "handles moving a still cage's inside"} <= set(status["warning_kinds"])
    assert status["result"] == status["message"] and status["result"].startswith("256 x 128 in ")
    assert s.idle(TIMEOUT)
    assert "1 line over a pole kept as it is" in s.status["quality"]


def test_no_message_is_left_from_a_finished_step(room, tmp_path, monkeypatch):
    import omniwidget.detect as detect
    from omniwidget.detect import Suggestion

    path = tmp_path / "room.png"
    write_image(path, room)
    found = [Suggestion((-40.0 + 20 * k, -5.0), (-30.0 + 20 * k, -8.0), 10.0, 50.0, 0.9) for k in range(3)]
    monkeypatch.setattr(detect, "suggest_lines", lambda *args, **kwargs: found)
    s = EditingSession(path, autosave=False, quality=False, preview_width=256, handles_path=tmp_path / "room.handles.json")
    s.start()
    s.wait(TIMEOUT)
    s.suggest_lines(wait=True)
    assert s.status["suggest"]["message"].startswith("3 suggested lines in ")
    assert "click one to accept it" in s.status["suggest"]["message"]

    s.accept_suggestion(0)  # two left: the prompt says so
    assert s.status["suggest"]["message"] == "2 suggested lines left: click one to accept it, Accept all, or Drop them"
    s.accept_all_suggestions()  # none left: no prompt for buttons that are greyed
    assert s.suggestions == [] and s.status["suggest"]["message"] == "" and s.status["suggest"]["count"] == 0
    s.wait(TIMEOUT)

    s.suggest_lines(wait=True)  # the same lines: all are handles already, nothing to accept
    assert s.suggestions == [] and "none found" in s.status["suggest"]["message"]
    s.command({"op": "save"})
    assert s.status["save"] == {"state": "done", "message": f"saved 3 handles to {tmp_path / 'room.handles.json'}"}
    s.command({"op": "undo"})  # the next edit: Save's message goes; the two lines undone are suggestions again
    assert s.status["save"] == {"state": "done", "message": ""}
    assert len(s.suggestions) == 2 and s.status["suggest"]["message"].startswith("2 suggested lines left: click one")
    s.drop_suggestions()  # dropped: the prompt goes too
    assert s.suggestions == [] and s.status["suggest"]["message"] == ""
    s.wait(TIMEOUT)

    s.suggest_lines(wait=True)  # the same lines again, one of them a handle: two to accept
    assert len(s.suggestions) == 2
    s.edit({**s.handles, "handles": []})  # an edit that leaves them all to accept: the prompt stays, as it was
    assert len(s.suggestions) == 3 and s.status["suggest"]["message"].startswith("3 suggested lines left")


def test_level_s_message_stays_until_the_next_edit(room, tmp_path, monkeypatch):
    import omniwidget.detect as detect
    from omniwidget.detect.level import Level

    found = Level(pitch=6.0, roll=-4.0, up=(30.0, 84.0))  # what detect.level finds (tested in tests/test_editor_detect.py)
    monkeypatch.setattr(detect, "level", lambda image: found)
    path = tmp_path / "room.png"
    write_image(path, room)
    s = EditingSession(path, autosave=False, quality=False, preview_width=256)
    s.start()
    s.level(wait=True)
    s.wait(TIMEOUT)
    assert s.status["level"]["state"] == "done" and "pitch +6.00°" in s.status["level"]["message"]  # its own edit keeps it
    s.edit({**s.handles, "handles": [*s.handles["handles"], {"kind": "point", "position": [10.0, 0.0]}]})
    assert s.status["level"]["state"] == "done" and s.status["level"]["message"] == ""
