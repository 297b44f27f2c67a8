"""Nothing lost: editors never erase each other's handles, and a FIFO at the autosave path hangs nothing.

Each test sets up what lost work on main before (two editors of one panorama, the last
writer winning; Save of ``day2/room.png`` writing over ``day1/room.png``'s handles; a FIFO
where the autosave goes) and asserts that every editor's handles are still on disk, that the
editor concerned is told, and that nothing waits for ever.
"""

from __future__ import annotations

import json
import os
import select
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path

import cv2
import numpy as np
import pytest

import omniwidget
from omniwidget.app.session import EditingSession
from omniwidget.document.handles import Handles, load_handles, save_handles

AUTOSAVE = "room.png.omniwidget-autosave.json"
SECOND = "room.png.2.omniwidget-autosave.json"


def point(lon: float) -> dict:
    return {"handles": [{"kind": "point", "position": [lon, 0.0], "scale": 1.5}]}


def lon_in(path: Path) -> float:
    """The longitude of the one point handle of the handles file ``path``."""
    return load_handles(path).handles[0].position[0]


def panorama(folder: Path) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    image = (np.random.default_rng(35).random((32, 64, 3)) * 255).astype(np.uint8)
    path = folder / "room.png"
    cv2.imwrite(str(path), image)
    return path


@pytest.fixture
def room(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    return panorama(tmp_path / "day1")


@pytest.fixture
def no_preview(monkeypatch):
    """Sessions compute no preview: these tests look at files only."""
    monkeypatch.setattr(EditingSession, "_schedule", lambda self, job: None)


def session(image, **kwargs) -> EditingSession:
    return EditingSession(image, autosave=kwargs.pop("autosave", True), quality=False, preview_width=32, **kwargs)


# --- another kernel ---------------------------------------------------------------------------
CHILD = textwrap.dedent(
    """
    import json, os, sys
    from omniwidget.app.session import EditingSession
    EditingSession._schedule = lambda self, job: None
    s = EditingSession(sys.argv[1], autosave=True, quality=False, preview_width=32)
    print(json.dumps({"notice": s._notice}), flush=True)
    for line in sys.stdin:
        s.edit({"handles": [{"kind": "point", "position": [float(line), 0.0], "scale": 1.5}]})
        print(json.dumps({"path": str(s.autosave_path), "notice": s._notice}), flush=True)
    os._exit(0)
    """
)


class Kernel:
    """An editing session in a process of its own (another kernel), driven a line at a time."""

    def __init__(self, image: Path) -> None:
        env = {**os.environ, "PYTHONPATH": str(Path(omniwidget.__file__).parents[1])}
        self.process = subprocess.Popen(
            [sys.executable, "-c", CHILD, str(image)], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=env
        )
        self.opened = self._answer()

    def _answer(self) -> dict:
        assert self.process.stdout is not None
        ready, _, _ = select.select([self.process.stdout], [], [], 120)
        assert ready, "the other kernel's session did not answer within 120 s"
        line = self.process.stdout.readline()
        assert line, f"the other kernel's session ended (exit {self.process.poll()})"
        return json.loads(line)

    def edit(self, lon: float) -> dict:
        assert self.process.stdin is not None
        self.process.stdin.write(f"{lon}\n")
        self.process.stdin.flush()
        return self._answer()

    def end(self) -> None:
        assert self.process.stdin is not None
        self.process.stdin.close()
        self.process.wait(30)


def test_two_editors_in_two_kernels_keep_both_works_and_the_second_is_told(room, no_preview):
    # on main both wrote room.png.omniwidget-autosave.json: the last writer won and the other's handles were gone
    first = Kernel(room)
    try:
        assert first.edit(10.0) == {"path": str(room.with_name(AUTOSAVE)), "notice": ""}
        second = session(room)
        notice = second._notice
        assert notice.startswith(f"restored 1 handle from {room.with_name(AUTOSAVE)}")  # the newest work, to start from
        assert f"another editor (in another kernel or program) has {room.with_name(AUTOSAVE)} open" in notice
        assert "autosaves to a file of its own, so that neither erases the other's" in notice
        second.edit(point(20.0))
        assert second.autosave_path == room.with_name(SECOND)
        assert second._notice.startswith(f"another editor (in another kernel or program) has {room.with_name(AUTOSAVE)} open")
        assert f"autosaved to {room.with_name(SECOND)} instead" in second.status["notice"]
        assert lon_in(room.with_name(AUTOSAVE)) == 10.0 and lon_in(room.with_name(SECOND)) == 20.0
        assert first.edit(11.0) == {"path": str(room.with_name(AUTOSAVE)), "notice": ""}  # the first goes on, undisturbed
        second.edit(point(21.0))
        assert lon_in(room.with_name(AUTOSAVE)) == 11.0 and lon_in(room.with_name(SECOND)) == 21.0
    finally:
        first.end()
    second.close()
    os.utime(room.with_name(AUTOSAVE), ns=(1, 1))  # the first kernel's work is the older one
    again = session(room)  # both kernels gone: the newest is restored, the other is offered
    assert lon_in(room.with_name(SECOND)) == again.document.handles[0].position[0] == 21.0
    assert again.other_autosaves == [room.with_name(AUTOSAVE)]
    assert f"other autosaves of this panorama are kept: {AUTOSAVE} (1 handle); load() takes one" in again._notice
    again.load(again.other_autosaves[0])
    assert again.document.handles[0].position[0] == 11.0
    again.edit(point(30.0))  # it goes on in the file it restored, now its own
    assert again.autosave_path == room.with_name(SECOND) and lon_in(room.with_name(SECOND)) == 30.0
    assert lon_in(room.with_name(AUTOSAVE)) == 11.0


def test_an_autosave_written_by_another_editor_since_this_one_opened_is_never_written_over(room, no_preview):
    # the other editor may be gone (its kernel killed): what it wrote stays all the same
    late = session(room)
    save_handles(Handles.from_dict(point(5.0)), room.with_name(AUTOSAVE))  # another kernel's editor, since ended
    late.edit(point(6.0))
    assert lon_in(room.with_name(AUTOSAVE)) == 5.0 and lon_in(room.with_name(SECOND)) == 6.0
    assert late._notice.startswith(f"{room.with_name(AUTOSAVE)} was written by another editor since this one opened it")
    save_handles(Handles.from_dict(point(7.0)), room.with_name(SECOND))  # even its own file, replaced by someone else
    late.edit(point(8.0))
    assert lon_in(room.with_name(SECOND)) == 7.0
    assert late.autosave_path.name == "room.png.3.omniwidget-autosave.json" and lon_in(late.autosave_path) == 8.0


def test_two_editors_in_one_kernel_the_newer_takes_over_and_the_older_keeps_its_handles_apart(room, no_preview):
    older = session(room)
    older.edit(point(10.0))
    newer = session(room, handles=point(20.0))  # a cell run again, with other handles
    assert "another editor of this panorama is open in this kernel" in newer._notice
    newer.edit(point(21.0))
    assert lon_in(room.with_name(AUTOSAVE)) == 21.0 and newer.autosave_path == room.with_name(AUTOSAVE)
    # the older one is told at once, and its handles are on disk in a file of its own
    assert older.autosave_path == room.with_name(SECOND) and lon_in(room.with_name(SECOND)) == 10.0
    assert older.status["notice"].startswith(f"a newer editor of this panorama in this kernel took over {room.with_name(AUTOSAVE)}")
    older.edit(point(11.0))
    newer.edit(point(22.0))
    assert lon_in(room.with_name(SECOND)) == 11.0 and lon_in(room.with_name(AUTOSAVE)) == 22.0


def test_a_cell_run_again_goes_on_in_the_same_file(room, no_preview):
    """Reopening in the same kernel, from the autosave, is the usual case: no second file then."""
    older = session(room)
    older.edit(point(10.0))
    newer = session(room)
    assert newer.document.handles[0].position[0] == 10.0
    newer.undo()  # the restored handles undone: the older editor's are the ones this one started from
    assert len(load_handles(room.with_name(AUTOSAVE))) == 0
    assert sorted(p.name for p in room.parent.iterdir()) == ["room.png", AUTOSAVE]
    assert "next edit is autosaved to a file of its own" in older._notice
    older.edit(point(12.0))
    assert older.autosave_path == room.with_name(SECOND) and lon_in(room.with_name(SECOND)) == 12.0


def test_the_widget_tells_the_second_editor(room):
    pytest.importorskip("anywidget")
    first = Kernel(room)
    try:
        first.edit(10.0)
        editor = omniwidget.Editor(room, autosave=True, quality=False, preview_width=32)
        assert "another editor (in another kernel or program)" in editor.wait()["notice"]
        editor.handles = point(20.0)
        assert editor.autosave_path == room.with_name(SECOND)
        assert f"autosaved to {room.with_name(SECOND)} instead" in editor.wait()["notice"]
        assert lon_in(room.with_name(AUTOSAVE)) == 10.0
    finally:
        first.end()
    editor.close()
    reopened = omniwidget.Editor(room, autosave=True, quality=False, preview_width=32)
    assert reopened.other_autosaves == [room.with_name(AUTOSAVE)] and reopened.document.handles[0].position[0] == 20.0
    reopened.wait()


# --- Save ----------------------------------------------------------------------------------------
def test_save_of_two_panoramas_of_one_name_writes_two_files(room, no_preview):
    # on main, day1/room.png's and day2/room.png's Save both wrote ./room.handles.json
    other = panorama(room.parent.parent / "day2")
    one, two = session(room, autosave=False), session(other, autosave=False)
    one.edit(point(1.0))
    two.edit(point(2.0))
    assert one.save() == room.with_name("room.handles.json") and two.save() == other.with_name("room.handles.json")
    assert lon_in(room.with_name("room.handles.json")) == 1.0 and lon_in(other.with_name("room.handles.json")) == 2.0
    assert not Path("room.handles.json").exists()


def test_save_in_the_working_folder_never_writes_over_another_panoramas_handles(tmp_path, monkeypatch, no_preview):
    monkeypatch.chdir(tmp_path)
    image = (np.random.default_rng(1).random((32, 64, 3)) * 255).astype(np.uint8)
    one, two = session(image, autosave=False), session(image[:, ::-1].copy(), autosave=False)
    one.edit(point(1.0))
    two.edit(point(2.0))
    assert one.save() == Path("panorama.handles.json")
    with pytest.raises(FileExistsError, match="panorama.handles.json: not saved: that file was not written by this editor"):
        two.save()
    two.command({"op": "save"})  # the Save button: told, nothing written
    assert "may hold another panorama's handles" in two.status["error"]
    assert lon_in(tmp_path / "panorama.handles.json") == 1.0
    one.edit(point(3.0))
    one.save()  # its own file: saved again
    assert lon_in(tmp_path / "panorama.handles.json") == 3.0
    assert two.save("two.handles.json") == Path("two.handles.json")  # a path given: written
    two.load("panorama.handles.json")  # a file it read is one it may save over
    assert two.save() == Path("panorama.handles.json")


# --- a FIFO at the autosave path -----------------------------------------------------------------
def _within(seconds: float, job):
    """``job()``'s value, or a failure when it takes longer (a read of a FIFO would never end)."""
    out: list = []
    worker = threading.Thread(target=lambda: out.append(job()), daemon=True)
    start = time.perf_counter()
    worker.start()
    worker.join(seconds)
    assert not worker.is_alive(), f"still waiting after {seconds} s"
    assert out, "the job raised"
    return out[0], time.perf_counter() - start


@pytest.mark.parametrize("given", [False, True], ids=["default path", "autosave=the FIFO"])
def test_a_fifo_at_the_autosave_path_is_refused_with_a_message_and_never_opened(room, no_preview, given):
    fifo = room.with_name("mine.json" if given else AUTOSAVE)
    os.mkfifo(fifo)
    session(room, autosave=False)  # the image read once: the time below is the autosave's

    def open_and_edit() -> EditingSession:
        s = session(room, autosave=fifo if given else True)
        s.edit(point(4.0))
        return s

    s, seconds = _within(1.0, open_and_edit)
    assert seconds < 1.0
    assert s._notice.startswith(f"{fifo}: cannot read the autosave: it is a FIFO (named pipe), not a regular file; it is left as it is")
    own = fifo.with_name("mine.2.json" if given else SECOND)
    assert s.autosave_path == own and lon_in(own) == 4.0
    assert fifo.is_fifo() and not fifo.with_name(fifo.name + ".bad").exists()  # left alone, not moved aside
    again, _ = _within(1.0, lambda: session(room, autosave=fifo if given else True))  # the next editor restores the handles
    assert again.document.handles[0].position[0] == 4.0
    assert f"{fifo}: cannot read the autosave: it is a FIFO (named pipe), not a regular file: it is left as it is" in again._notice
