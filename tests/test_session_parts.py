"""The editing session's parts, each on its own: no session, no widget, no browser.

:class:`~omniwidget.app.session.EditingSession` wires these; here each is driven with a
:class:`~omniwidget.app.status.Board` of its own (or a small stand-in for the session) and
checked by what it writes, shows or sends.
"""

from __future__ import annotations

import json
import re
import typing
from pathlib import Path

import numpy as np
import pytest

from omniwidget.app.autosave import Autosave
from omniwidget.app.detection import Detection
from omniwidget.app.drag import LiveDrag
from omniwidget.app.exports import ImageExport, result_location
from omniwidget.app.handles_file import HandlesFile
from omniwidget.app.history import History
from omniwidget.app.preview import PreviewJob, ResultStatus, render
from omniwidget.app.session import ANSWERED_WHEN_DONE, COMMANDS, EditingSession
from omniwidget.app.source import Source
from omniwidget.app.status import Board, JobStatus, Status, VideoStatus
from omniwidget.detect import Suggestion
from omniwidget.document.handles import Handles, LineHandle, Options, PointHandle
from omniwidget.errors import ImageError
from omniwidget.evaluate.scenes import synthetic_room
from omniwidget.io.images import read_image, write_image
from omniwidget.raster.pipeline import warp

TIMEOUT = 120
STATIC = Path(__file__).resolve().parents[1] / "omniwidget" / "widget" / "static"
MOVED = PointHandle((30.0, 10.0), target=(36.0, 14.0))
LINE = LineHandle((-60.0, 30.0), (60.0, 30.0), rectify=True)


@pytest.fixture(scope="module")
def room():
    return synthetic_room(256).image


def _doc(*handles) -> Handles:
    return Handles(tuple(handles))


def _on_disk(path: Path) -> list:
    return json.loads(path.read_text())["handles"]


# --- the history ---------------------------------------------------------------------------------
def test_undo_and_redo_give_back_the_documents_in_order_and_a_new_edit_forgets_the_undone():
    history = History(limit=3)
    docs = [{"handles": [n]} for n in range(5)]
    for before in docs[:4]:
        history.record(before)
    assert history.counts() == {"undo": 3, "redo": 0}  # the oldest fell off
    assert history.undo(docs[4]) == docs[3] and history.undo(docs[3]) == docs[2]
    assert history.counts() == {"undo": 1, "redo": 2}
    assert history.redo(docs[2]) == docs[3]
    history.record(docs[3])  # an edit: what was undone is gone
    assert history.counts() == {"undo": 3, "redo": 0} and history.redo(docs[0]) is None
    assert [history.undo({}) for _ in range(4)] == [docs[3], docs[2], docs[1], None]
    with pytest.raises(ValueError, match="limit"):
        History(limit=0)


# --- the board -----------------------------------------------------------------------------------
def test_the_board_publishes_what_it_keeps_and_an_edit_clears_only_the_ended_jobs_messages():
    told: list[dict] = []
    board = Board(told.append)
    board.set_status(state="idle", message="ready")
    board.set_job("level", {"state": "done", "message": "levelled"})
    board.set_job("save", {"state": "running", "message": "saving..."})
    board.set_job("suggest", {"state": "done", "message": "3 suggested lines", "count": 3})
    board.publish({"suggestions": [{"key": 0}]})
    assert told[-1] == {"suggestions": [{"key": 0}]} and board.suggestions == [{"key": 0}]
    assert told[0] == {"status": {"state": "idle", "message": "ready"}}
    board.clear_finished()
    assert board.status["level"] == {"state": "done", "message": ""}  # ended: its message goes
    assert board.status["save"]["message"] == "saving..."  # running: kept
    assert board.status["suggest"]["message"] == "3 suggested lines"  # its suggestions are still shown
    board.publish({"suggestions": []})
    board.clear_finished()
    assert board.status["suggest"] == {"state": "done", "message": "", "count": 3}
    assert board.status["message"] == "ready"


# --- the autosave --------------------------------------------------------------------------------
def test_a_newer_autosave_of_the_same_file_takes_it_over_and_the_older_keeps_its_handles_apart(tmp_path):
    path = tmp_path / "room.png.omniwidget-autosave.json"
    older_board, newer_board = Board(), Board()
    older = Autosave(path, older_board)
    assert older.open(Handles(), given=False) is None and older.notice == ""
    older_board.handles = _doc(MOVED).to_dict()
    older.write(_doc(MOVED))
    assert _on_disk(path)[0]["position"] == [30.0, 10.0]
    newer = Autosave(path, newer_board)
    restored = newer.open(Handles(), given=False)
    assert restored == _doc(MOVED) and newer.path == path
    assert "another editor of this panorama is open in this kernel" in newer.notice
    moved = _doc(PointHandle((50.0, 0.0), scale=2.0))
    newer.write(moved)  # the newer one takes the file over; the older's handles are what it restored: not written again
    assert _on_disk(path)[0]["position"] == [50.0, 0.0]
    assert "next edit is autosaved to a file of its own" in older.notice
    assert older_board.status["notice"] == older.notice  # shown in the older editor's status
    older.write(_doc(MOVED, LINE))
    assert older.path == tmp_path / "room.png.2.omniwidget-autosave.json" and len(_on_disk(older.path)) == 2
    assert _on_disk(path)[0]["position"] == [50.0, 0.0]  # never written over
    older.release()
    newer.release()


def test_an_unreadable_autosave_is_said_and_kept_aside_at_the_first_write(tmp_path):
    path = tmp_path / "room.png.omniwidget-autosave.json"
    path.write_text("{not json")
    save = Autosave(path, Board())
    assert save.open(Handles(), given=False) is None
    assert save.notice.startswith("could not restore the autosave: ") and "room.png.omniwidget-autosave.json.bad" in save.notice
    save.write(_doc(MOVED))
    assert (tmp_path / "room.png.omniwidget-autosave.json.bad").read_text() == "{not json"
    assert _on_disk(path)[0]["target"] == [36.0, 14.0] and save.notice.startswith("the unreadable autosave was kept as ")
    save.release()


# --- the handles file -----------------------------------------------------------------------------
def test_the_handles_file_goes_next_to_the_panorama_and_never_over_a_shared_name_it_did_not_write(tmp_path, monkeypatch):
    (tmp_path / "day1").mkdir()
    beside = HandlesFile(tmp_path / "day1" / "room.jpg")
    assert beside.write(_doc(MOVED)) == tmp_path / "day1" / "room.handles.json"
    assert _on_disk(beside.path)[0]["target"] == [36.0, 14.0]
    monkeypatch.chdir(tmp_path)
    shared = HandlesFile(None)  # an array: the working folder's panorama.handles.json, a name others share
    assert shared.write(_doc(MOVED)) == Path("panorama.handles.json")
    other = HandlesFile(None)
    with pytest.raises(FileExistsError, match="not saved: that file was not written by this editor"):
        other.write(_doc(LINE))
    assert _on_disk(tmp_path / "panorama.handles.json")[0]["kind"] == "point"  # untouched
    other.note(Path("panorama.handles.json"))  # loaded by this editor: its own to write over now
    other.write(_doc(LINE))
    assert _on_disk(tmp_path / "panorama.handles.json")[0]["kind"] == "line"
    assert other.write(_doc(MOVED), tmp_path / "mine.json") == tmp_path / "mine.json"


# --- the source ----------------------------------------------------------------------------------
def test_the_source_makes_each_copy_once_and_keys_results_by_the_handles(room):
    source = Source(room, preview_width=64)
    assert source.preview_width == 64 and source.preview_source.shape[:2] == (64, 128)
    assert source.downscaled(128) is source.preview_source and source.downscaled(4096) is source.working  # never upscaled
    assert source.display_source()[:2] == b"\xff\xd8"  # a JPEG
    assert source.key({"handles": []}) == source.key({"handles": []}) != source.key({"handles": [1]})
    with pytest.raises(TypeError, match="not a video"):
        source.frame_of(1, None)
    with pytest.raises(TypeError, match="given an image"):
        Source(room, preview_width=64, frame=2)
    with pytest.raises(ValueError, match="preview_width"):
        Source(room, preview_width=63)


# --- the preview -----------------------------------------------------------------------------------
def test_render_puts_a_points_centre_on_its_target_and_refuses_outputs_that_are_not_finite(room):
    doc = _doc(MOVED, LINE)
    result = warp(room, doc, width=128, warn=False)
    rendered = render(result, doc)
    assert rendered.outputs[0][0] == [36.0, 14.0]  # the point's centre, where it was moved
    latitudes = [lat for _, lat in rendered.outputs[1]]
    assert max(latitudes) - min(latitudes) < 0.01  # the rectified line's start, middle and end on one row of the output
    assert latitudes[1] < 40.0  # its middle came down from about 49°
    assert rendered.preview[:2] == b"\xff\xd8" and isinstance(rendered.folds, bytes)
    floats = warp(room.astype(np.float32) / 255, doc, width=128, warn=False)
    floats.image[5, 7] = np.nan
    with pytest.raises(FloatingPointError, match="pixels that are not finite"):
        render(floats, doc)
    status = ResultStatus.of(result, 0.5, generation=7).to_message({"notice": "kept", "error": "refused"})
    assert status["notice"] == "kept" and status["error"] == "refused" and status["generation"] == 7
    assert status["message"] == status["result"] == "128 x 64 in 0.50 s" and status["state"] == "idle"
    assert set(status) <= set(typing.get_type_hints(Status))


def test_only_the_newest_generation_is_shown_and_a_failure_keeps_the_last_good_result(room):
    told: list[dict] = []
    board = Board(told.append)
    job = PreviewJob(Source(room, preview_width=64), board, measure=False)
    first, second = _doc(MOVED), _doc(PointHandle((30.0, 10.0), target=(40.0, 10.0)))
    job.schedule(lambda generation: job.compute(first, "first", generation - 1, full=False))  # a stale generation
    job.schedule(lambda generation: job.compute(second, "second", generation, full=False))
    assert job.worker.wait(TIMEOUT)
    previews = [c for c in told if "preview" in c]
    assert len(previews) == 1 and board.outputs[0][0] == [40.0, 10.0] and board.status["generation"] == 2
    shown = board.preview
    job.source.preview_source = None  # type: ignore[assignment]  # the next warp fails
    job.schedule(lambda generation: job.compute(_doc(MOVED), "broken", generation, full=False))
    assert job.worker.wait(TIMEOUT)
    assert board.status["state"] == "error" and board.status["error"].startswith("could not compute the result (")
    assert board.preview == shown and isinstance(board.last_error, Exception)


# --- save image ------------------------------------------------------------------------------------
def test_save_image_writes_the_full_size_result_and_never_the_input(room, tmp_path):
    write_image(tmp_path / "room.png", room)
    source = Source(tmp_path / "room.png", preview_width=64)
    board, sent = Board(), []
    preview = PreviewJob(source, board, measure=False)
    images = ImageExport(source, preview, board, lambda content, buffers: sent.append((content, buffers)))
    doc = _doc(MOVED)
    written = images.save(doc, "key", None)
    assert written == result_location(tmp_path / "room.png", room) == tmp_path / "room-rectified.png"
    np.testing.assert_array_equal(read_image(written), warp(room, doc, warn=False).image)
    assert board.status["save"] == {"state": "done", "message": f"256 x 128 saved to {written}"} and board.status["saved"] == str(written)
    with pytest.raises(ImageError, match="is the input panorama"):
        images.save(doc, "key", tmp_path / "room.png")
    assert board.status["error"].startswith("could not save the image: ") and read_image(tmp_path / "room.png").shape == room.shape
    images.job(doc, "key", preview.generation)  # the button: shown, written, sent for download
    assert sent[-1][0] == {"op": "image_file", "name": "room-rectified.png", "mime": "image/png"}
    assert sent[-1][1] == [written.read_bytes()]


# --- detection -------------------------------------------------------------------------------------
class _Editing:
    """The session as detection sees it: its handles and its edits."""

    def __init__(self) -> None:
        self.handles: dict = Handles().to_dict()
        self.edits = 0

    def edit(self, handles, record: bool = True) -> None:
        self.handles = (handles if isinstance(handles, Handles) else Handles.from_dict(handles)).to_dict()
        self.edits += 1


def test_suggestions_in_the_document_or_dropped_are_no_longer_shown_and_the_prompt_counts_the_rest(room):
    board, editing = Board(), _Editing()
    detection = Detection(Source(room, preview_width=64), board, editing)
    detection.suggested = [Suggestion((-40.0 + 20 * k, 5.0), (-30.0 + 20 * k, 25.0), 20.0, 1.0, 0.9) for k in range(4)]
    detection.show(detection.shown())
    board.set_job("suggest", {"state": "done", "message": "4 suggested lines", "count": 4})
    assert [s["key"] for s in board.suggestions] == [0, 1, 2, 3]
    editing.edit(_doc(detection.suggestion(1).handle()))
    detection.edited(Handles.from_dict(editing.handles))
    assert [s["key"] for s in board.suggestions] == [0, 2, 3]
    assert board.status["suggest"]["message"] == "3 suggested lines left: click one to accept it, Accept all, or Drop them"
    detection.drop(2)
    assert [s["key"] for s in board.suggestions] == [0, 3] and len(detection.shown_lines()) == 2
    with pytest.raises(IndexError, match="suggestion 2 is not shown"):
        detection.suggestion(2)
    detection.drop()
    assert board.suggestions == [] and board.status["suggest"]["message"] == ""


def test_a_level_that_fails_says_why_answers_and_changes_nothing():
    board, editing, answered = Board(), _Editing(), []
    flat = np.full((128, 256, 3), 0.5, np.float32)  # no edge to level by
    detection = Detection(Source(flat, preview_width=64), board, editing)
    with pytest.raises(Exception, match="vertical edges|edges"):
        detection.level(wait=True, then=lambda: answered.append("level"))
    assert answered == ["level"] and editing.edits == 0
    assert board.status["level"]["state"] == "error" and board.status["error"] == board.status["level"]["message"]
    assert board.status["level"]["message"].startswith("could not level the panorama: ")


# --- the live drag ---------------------------------------------------------------------------------
def test_the_live_basis_is_sent_for_a_handle_of_the_result_on_screen_only(room):
    sent: list = []
    preview = PreviewJob(Source(room, preview_width=64), Board(), measure=False)
    drag = LiveDrag(preview, lambda content, buffers: sent.append((content, buffers)))
    drag.send_basis(0)
    assert sent == []  # no result on screen
    preview.schedule(lambda generation: preview.compute(_doc(MOVED), "k", generation, full=False))
    assert preview.worker.wait(TIMEOUT)
    drag.send_basis(3)
    assert sent == []  # no such handle
    drag.request(0)
    assert drag.worker.wait(TIMEOUT)
    (header, buffers), = sent
    assert header["op"] == "live" and header["index"] == 0 and header["generation"] == 1 and header["width"] > 0
    assert len(buffers) == 1 and len(buffers[0]) > 0


# --- the commands ----------------------------------------------------------------------------------
def test_every_command_the_front_end_sends_has_a_handler():
    source = (STATIC / "editor.js").read_text() + "".join(p.read_text() for p in STATIC.glob("*.js") if p.name != "editor.bundle.js")
    sent = set(re.findall(r'\bcommand(?:Selected)?\(ed, (?:[^,]*\? )?"(\w+)"', source)) | set(re.findall(r'\bop: "(\w+)"', source))
    sent |= set(re.findall(r'\? "(\w+)" : "\w+"', source)) & set(COMMANDS)
    assert {"undo", "redo", "drag", "live", "load", "arrow", "level"} <= sent, sent
    assert sent <= set(COMMANDS), sent - set(COMMANDS)
    assert ANSWERED_WHEN_DONE <= set(COMMANDS)


def test_an_unknown_command_is_refused_with_its_name_and_answered(room):
    sent: list = []
    s = EditingSession(room, autosave=False, quality=False, preview_width=64, on_message=lambda content, buffers: sent.append(content))
    s.command({"op": "fly"})
    assert s.status["error"] == "ValueError: unknown command from the browser: 'fly'" and sent == [{"done": "fly"}]
    s.command({"op": "undo"})
    assert sent[-1] == {"done": "undo"} and s.history == {"undo": 0, "redo": 0}
    s.command({"op": "reset", "index": 4})
    assert s.status["error"] == "IndexError: handles[4]: there are 0 handles" and sent[-1] == {"done": "reset"}


def test_the_status_and_its_jobs_hold_only_the_fields_their_records_name(room, tmp_path):
    write_image(tmp_path / "room.png", room)
    s = EditingSession(tmp_path / "room.png", _doc(MOVED), autosave=True, quality=False, preview_width=64)
    s.start()
    s.wait(TIMEOUT)
    s.save_image()
    s.command({"op": "save"})
    s.edit(_doc(MOVED, LINE))
    s.wait(TIMEOUT)
    assert set(s.status) <= set(typing.get_type_hints(Status)), set(s.status) - set(typing.get_type_hints(Status))
    assert {"state", "message", "notice", "warnings", "generation", "save"} <= set(s.status)
    assert set(s.status["save"]) <= set(typing.get_type_hints(JobStatus))
    assert set(typing.get_type_hints(VideoStatus)) == {"state", "done", "total", "fps", "path", "message"}
    assert Options() == s.document.options
    s.close()
