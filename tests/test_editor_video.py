"""The editor opens a video, in plain Python: a frame to draw on, the slider's frames, Save video.

A tiny synthetic clip (256 x 128, 12 frames, each the bundled sample turned a little more
than the last, so that the frames differ) is opened by :class:`EditingSession` and by
:class:`omniwidget.Editor`: the frame shown by default, by index and by time is the
:class:`~omniwidget.io.video.VideoReader`'s; another frame keeps the handles and recomputes the
preview on it; Save video writes a video of as many frames whose first frame is ``ow.warp``
of the first input frame within the codec's loss, with its progress reported; a cancel leaves
no file; undo and redo are as for an image.
"""

from __future__ import annotations

import threading
from pathlib import Path

import numpy as np
import pytest

import omniwidget as ow
from omniwidget.app.session import EditingSession
from omniwidget.errors import VideoError
from omniwidget.sphere.moebius import Moebius
from tests import requires

av = requires.module("av")

from omniwidget.io.video import VideoReader  # noqa: E402 - after the skip

SIZE = (256, 128)
FRAMES = 12
RATE = 12
HANDLES = {
    "format": "omniwidget.handles",
    "version": 1,
    "handles": [{"kind": "line", "start": [-40.0, 30.0], "end": [40.0, 25.0], "rectify": True}],
    "options": {"rectify": "all", "anchor": None},
}


def _frames() -> list[np.ndarray]:
    import cv2

    base = cv2.resize(ow.sample_image(), SIZE, interpolation=cv2.INTER_AREA)
    return [ow.warp_moebius(base, Moebius.rotation([30.0, 20.0], 3.0 * i)).image for i in range(FRAMES)]


def make_clip(path: Path, frames: list[np.ndarray] | None = None) -> Path:
    """Frames (RGB uint8) to an H.264 MP4 at RATE frames per second, no sound."""
    frames = _frames() if frames is None else frames
    with av.open(str(path), "w") as out:
        video = out.add_stream("libx264", rate=RATE, options={"crf": "12", "preset": "fast"})
        video.width, video.height = frames[0].shape[1], frames[0].shape[0]
        video.pix_fmt = "yuv420p"
        for i, image in enumerate(frames):
            frame = av.VideoFrame.from_ndarray(image, format="rgb24")
            frame.pts = i
            out.mux(video.encode(frame))
        out.mux(video.encode(None))
    return path


@pytest.fixture(scope="module")
def clip(tmp_path_factory) -> Path:
    return make_clip(tmp_path_factory.mktemp("video") / "clip.mp4")


@pytest.fixture
def clip_copy(clip, tmp_path) -> Path:
    """The clip in a folder of the test's own (Save video writes next to it)."""
    copy = tmp_path / clip.name
    copy.write_bytes(clip.read_bytes())
    return copy


def _psnr(a: np.ndarray, b: np.ndarray) -> float:
    mse = float(np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2))
    return float("inf") if mse == 0 else 10.0 * np.log10(255.0**2 / mse)


def _first_frame(path: Path) -> tuple[np.ndarray, int]:
    with av.open(str(path)) as container:
        frames = [f.to_ndarray(format="rgb24") for f in container.decode(video=0)]
    return frames[0], len(frames)


def _session(path, **kwargs) -> EditingSession:
    kwargs.setdefault("autosave", False)
    kwargs.setdefault("quality", False)
    return EditingSession(path, **kwargs)


def test_a_video_opens_on_frame_0_or_the_frame_chosen_by_index_or_by_time(clip):
    with VideoReader(clip) as video:
        expected = {i: video.read(i) for i in (0, 5, 6)}
    s = _session(clip)
    assert (s.frame, s.frame_count) == (0, FRAMES)
    assert s.frame_interval == pytest.approx(1 / RATE)
    np.testing.assert_array_equal(s.image, expected[0])
    s = _session(clip, frame=5)
    assert s.frame == 5
    np.testing.assert_array_equal(s.image, expected[5])
    s = _session(clip, time=0.5)  # 0.5 s at 12 frames per second: frame 6
    assert s.frame == 6 and s.frame_time == pytest.approx(0.5)
    np.testing.assert_array_equal(s.image, expected[6])
    with pytest.raises(IndexError, match="12 frames"):
        _session(clip, frame=FRAMES)
    with pytest.raises(ValueError, match="long"):
        _session(clip, time=60.0)
    with pytest.raises(TypeError, match="not both"):
        _session(clip, frame=1, time=0.1)


def test_frame_and_time_are_refused_for_an_image():
    with pytest.raises(TypeError, match="video"):
        _session(ow.sample_path(), frame=3)


def test_another_frame_keeps_the_handles_and_recomputes_the_preview(clip):
    changes: list[dict] = []
    s = _session(clip, handles=HANDLES, on_change=changes.append)
    s.start()
    s.wait()
    before = s.preview
    handles, history = s.handles, dict(s.history)
    with VideoReader(clip) as video:
        nine = video.read(9)
    s.set_frame(9)
    status = s.wait()
    assert status["state"] == "idle" and s.frame == 9
    np.testing.assert_array_equal(s.image, nine)
    assert s.handles == handles and s.history == history  # no edit: nothing to undo
    assert s.preview != before
    assert any("source" in c and "frame" in c for c in changes)
    np.testing.assert_array_equal(s.result.image, ow.warp(nine, s.document, warn=False).image)  # the full result is of the frame shown
    s.set_frame(time=0.25)
    assert s.frame == 3
    s.command({"op": "frame", "frame": 99})  # a refused frame is shown, the frame stays
    assert s.frame == 3 and "99" in s.status["error"]


def test_undo_and_redo_are_unaffected_by_the_frame(clip):
    s = _session(clip)
    s.start()
    s.edit(HANDLES)
    s.set_frame(4)
    assert s.undo() and len(s.document) == 0 and s.frame == 4
    assert s.redo() and len(s.document) == 1
    s.wait()


def test_save_video_writes_every_frame_warped_with_progress(clip_copy):
    updates: list[dict] = []

    def on_change(changes: dict) -> None:
        if "video" in changes.get("status", {}):
            updates.append(changes["status"]["video"])

    s = _session(clip_copy, handles=HANDLES, frame=7, on_change=on_change)
    target = s.save_video(wait=True)
    assert target == clip_copy.with_name("clip-rectified.mp4") and target.exists()
    video = s.status["video"]
    assert video["state"] == "done" and video["done"] == video["total"] == FRAMES and str(target) in video["message"]
    counts = [u["done"] for u in updates if u["state"] in ("running", "done")]
    assert counts and counts == sorted(counts) and counts[-1] == FRAMES
    first, count = _first_frame(target)
    assert count == FRAMES
    with VideoReader(clip_copy) as reader:
        expected = ow.warp(reader.read(0), s.document, warn=False).image
    psnr = _psnr(first, expected)
    assert psnr >= 30.0, f"the first frame is {psnr:.1f} dB from ow.warp of the first input frame"
    assert [p.name for p in clip_copy.parent.iterdir() if p.name.endswith(".part")] == []


def test_cancelling_a_save_leaves_no_file(clip_copy, monkeypatch):
    from omniwidget.app import video as video_module

    s = _session(clip_copy, handles=HANDLES)
    real = video_module.warp_video
    started = threading.Event()

    def slow(*args, progress, cancel, **kwargs):  # the first frame done, the job waits for the cancel
        def waiting(done, total):
            started.set()
            assert cancel.wait(30)
            return progress(done, total)

        return real(*args, progress=waiting, cancel=cancel, **kwargs)

    monkeypatch.setattr(video_module, "warp_video", slow)
    target = s.save_video()
    assert started.wait(60)
    assert s.status["video"]["state"] in ("map", "running")
    with pytest.raises(VideoError, match="already"):
        s.save_video()
    assert s.cancel_video()
    assert s.wait_video(60) is None
    assert s.status["video"]["state"] == "cancelled" and "cancelled" in s.status["video"]["message"]
    assert not target.exists()
    assert [p.name for p in clip_copy.parent.iterdir()] == [clip_copy.name]
    assert not s.cancel_video()  # nothing to cancel any more


def test_the_editor_widget_syncs_the_frame_and_saves_by_command(clip_copy):
    ed = ow.Editor(clip_copy, handles=HANDLES, frame=2, autosave=False, quality=False)
    ed.wait()
    assert (ed.frame, ed.frame_count) == (2, FRAMES) and ed.frame_interval == pytest.approx(1 / RATE)
    source = ed.source
    ed.frame = 8
    ed.wait()
    assert ed.session.frame == 8 and ed.source != source
    with pytest.raises(IndexError):
        ed.frame = 40
    assert ed.frame == 8
    ed.session.command({"op": "save_video"})
    ed.wait_video(120)
    assert ed.status["video"]["state"] == "done", ed.status["video"]
    assert clip_copy.with_name("clip-rectified.mp4").exists()


def test_a_file_neither_image_nor_video_gives_the_same_error_as_before(tmp_path):
    path = tmp_path / "notes.txt"
    path.write_text("not a panorama\n")
    with pytest.raises(ow.ImageError) as image_error:
        ow.read_image(path)
    with pytest.raises(ow.ImageError) as editor_error:
        ow.Editor(path, autosave=False)
    assert str(editor_error.value) == str(image_error.value)
