"""Nothing lost: no output names an input, the map or another output; no temporary file is left behind.

Each case is one the issue found on main, run as a person would run it:

- ``omniwidget warp in.npy -H h.json -o out.tif --map in.npy`` wrote the map over the input
  (exit 0); in frames mode the map overwrote a frame before it was read; ``--map`` equal to
  ``-o`` replaced the image by the map. Now: exit 2 before any work, one line naming both
  paths, every file as it was. Also through hard and symbolic links, in ``level``,
  ``suggest``, a video and the Dask batch.
- SIGTERM during a video warp, ``kill -9`` during a write: hidden ``.part`` and ``.tmp``
  files stayed and no later run removed them. Now SIGTERM removes them as Ctrl+C does (exit
  143), and the next run on the same output removes what a ``kill -9`` left (never the file
  of a run still writing: it holds a lock).
"""

from __future__ import annotations

import hashlib
import json
import os
import signal
import stat
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from omniwidget._files import atomic_write_bytes, remove_leftovers, same_file
from omniwidget.app.cli import main
from omniwidget.errors import ImageError
from omniwidget.io.images import write_image
from omniwidget.sphere import coords

HANDLES = {
    "format": "omniwidget.handles",
    "version": 1,
    "handles": [{"kind": "point", "position": [10, 20], "target": [35, -5]}],
    "options": {"anchor": None},  # one Möbius map of the whole sphere: quick
}
ROOT = Path(__file__).resolve().parents[1]


def _panorama(seed: int = 0) -> np.ndarray:
    """256 x 128 RGB: smooth (small as PNG), different per seed."""
    lon, lat = coords.grid_lonlat(256)
    gx, gy = np.meshgrid(lon, lat)
    return np.stack([(gx + 180) / 360 * 255, (gy + 90) / 180 * 255, np.full_like(gx, 40.0 * seed % 256)], axis=-1).astype(np.uint8)


def _identity_map() -> np.ndarray:
    lon, lat = coords.grid_lonlat(256)
    gx, gy = np.meshgrid(lon, lat)
    return np.stack([gx, gy], axis=-1).astype(np.float32)


@pytest.fixture
def d(tmp_path: Path) -> Path:
    np.save(tmp_path / "in.npy", _panorama(1))
    for i in range(3):
        np.save(tmp_path / f"f{i}.npy", _panorama(i + 2))
    write_image(tmp_path / "in.png", _panorama(5))
    (tmp_path / "h.json").write_text(json.dumps(HANDLES))
    np.save(tmp_path / "map.npy", _identity_map())
    return tmp_path


def _state(folder: Path) -> dict[str, str]:
    """Every file under ``folder`` (hidden ones too) and a digest of its bytes: what must not change."""
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.rglob("*")) if p.is_file()}


def _refused(folder: Path, capsys: pytest.CaptureFixture[str], argv: list[str], *named: Path | str) -> str:
    """Run the command line; it must refuse with exit 2 and one line naming ``named``, every file left as it was."""
    before = _state(folder)
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    for path in named:
        assert f" {path}" in err, (path, err)
    assert _state(folder) == before, err
    return err.strip()


# --- part 1: no output over an input, the map or another output ----------------------------------


def test_the_map_over_the_input_is_refused_and_the_input_kept(d, capsys):
    """The issue's first row: the map was written over the input, exit 0."""
    err = _refused(d, capsys, ["warp", f"{d}/in.npy", "-H", f"{d}/h.json", "-o", f"{d}/out.tif", "--map", f"{d}/in.npy"], f"{d}/in.npy")
    assert err == f"omniwidget warp: error: --map {d}/in.npy would overwrite the input {d}/in.npy; choose another file"
    assert not (d / "out.tif").exists()


def test_the_map_over_a_frame_is_refused_before_any_frame_is_read(d, capsys):
    """Frames mode: the map overwrote f1 before it was read, and f1 was then warped as garbage, exit 0."""
    (d / "out").mkdir()
    f = [f"{d}/f{i}.npy" for i in range(3)]
    _refused(d, capsys, ["warp", *f, "-H", f"{d}/h.json", "-o", f"{d}/out", "--map", f[1]], "--map", f[1])
    assert list((d / "out").iterdir()) == []


def test_the_map_over_the_output_is_refused(d, capsys):
    """``--map`` equal to ``-o`` replaced the image by the map."""
    err = _refused(d, capsys, ["warp", f"{d}/in.npy", "-H", f"{d}/h.json", "-o", f"{d}/m.npy", "--map", f"{d}/m.npy"], f"{d}/m.npy")
    assert "must name different files" in err and not (d / "m.npy").exists()


@pytest.mark.parametrize("link", ["hard", "symbolic"])
def test_an_output_that_is_a_link_to_the_input_is_refused(d, capsys, link):
    alias = d / "alias.npy"
    (os.link if link == "hard" else os.symlink)(d / "in.npy", alias)
    assert same_file(alias, d / "in.npy")
    err = _refused(d, capsys, ["warp", f"{d}/in.npy", "-H", f"{d}/h.json", "-o", str(alias)], alias, d / "in.npy")
    assert "(the same file)" in err
    _refused(d, capsys, ["warp", f"{d}/in.npy", "-H", f"{d}/h.json", "-o", f"{d}/o.png", "--map", str(alias)], alias, d / "in.npy")


def test_outputs_over_the_handles_file_or_the_applied_map_are_refused(d, capsys):
    (d / "h.npy").symlink_to(d / "h.json")
    err = _refused(d, capsys, ["warp", f"{d}/in.npy", "-H", f"{d}/h.json", "-o", f"{d}/o.png", "--map", f"{d}/h.npy"], d / "h.npy", d / "h.json")
    assert "the handles file" in err
    err = _refused(d, capsys, ["warp", f"{d}/in.npy", "--apply-map", f"{d}/map.npy", "-o", f"{d}/o.png", "--map", f"{d}/map.npy"], d / "map.npy")
    assert "would overwrite the map" in err
    # a folder of frames in which one output would be another frame's input
    (d / "f0.npy").rename(d / "out.npy")
    (d / "sub").mkdir()
    os.link(d / "out.npy", d / "sub" / "f1.npy")
    _refused(d, capsys, ["warp", f"{d}/out.npy", f"{d}/f1.npy", "-H", f"{d}/h.json", "-o", f"{d}/sub"], d / "sub" / "f1.npy", d / "out.npy")


def test_level_and_suggest_refuse_outputs_over_their_input_or_each_other(d, capsys):
    (d / "in.json").symlink_to(d / "in.png")
    os.link(d / "in.png", d / "twin.npy")
    _refused(d, capsys, ["level", f"{d}/in.png", "-o", f"{d}/o.png", "--map", f"{d}/twin.npy"], d / "twin.npy", d / "in.png")
    _refused(d, capsys, ["level", f"{d}/in.png", "-o", f"{d}/o.png", "-H", f"{d}/in.json"], d / "in.json", d / "in.png")
    _refused(d, capsys, ["level", f"{d}/in.npy", "-o", f"{d}/in.npy"], f"{d}/in.npy")
    err = _refused(d, capsys, ["level", f"{d}/in.png", "-o", f"{d}/o.npy", "--map", f"{d}/o.npy"], f"{d}/o.npy")
    assert "must name different files" in err
    _refused(d, capsys, ["suggest", f"{d}/in.png", "-o", f"{d}/in.json"], d / "in.json", d / "in.png")


def test_a_video_output_or_its_map_over_the_input_is_refused(d, capsys):
    clip = d / "clip.mp4"
    clip.write_bytes(b"\0" * 64)  # refused before it is opened: what it holds does not matter
    (d / "again.mp4").symlink_to(clip)
    os.link(clip, d / "clip.npy")
    _refused(d, capsys, ["warp", str(clip), "-H", f"{d}/h.json", "-o", f"{d}/again.mp4"], d / "again.mp4", clip)
    _refused(d, capsys, ["warp", str(clip), "-H", f"{d}/h.json", "-o", f"{d}/o.mp4", "--map", f"{d}/clip.npy"], d / "clip.npy", clip)


def test_the_dask_batch_refuses_before_it_connects(d, capsys):
    """No scheduler listens at the address: the refusal comes first, from the paths alone."""
    (d / "out").mkdir()
    os.link(d / "f1.npy", d / "out" / "f0.npy")  # out/f0.npy is f1: writing f0's output would destroy f1
    f = [f"{d}/f{i}.npy" for i in range(3)]
    _refused(d, capsys, ["warp", *f, "-H", f"{d}/h.json", "-o", f"{d}/out", "--dask", "tcp://127.0.0.1:9"], d / "out" / "f0.npy", f[1])
    clip = d / "clip.mp4"
    clip.write_bytes(b"\0" * 64)
    (d / "link.mp4").symlink_to(clip)
    _refused(d, capsys, ["warp", str(clip), "-H", f"{d}/h.json", "-o", f"{d}/link.mp4", "--dask", "tcp://127.0.0.1:9"], d / "link.mp4", clip)


def test_the_python_batch_refuses_links_and_the_handles_file(d):
    from omniwidget.app.batch import warp_files
    from omniwidget.app.frames import warp_frames

    before = _state(d)
    os.link(d / "f0.npy", d / "hard.npy")
    with pytest.raises(ImageError, match=f"the output {d}/hard.npy would overwrite the input {d}/f0.npy"):
        warp_files([d / "f0.npy"], [d / "hard.npy"], handles=d / "h.json")
    (d / "hlink.npy").symlink_to(d / "h.json")
    with pytest.raises(ImageError, match="would overwrite the handles file"):
        warp_files([d / "f0.npy"], [d / "hlink.npy"], handles=d / "h.json")
    with pytest.raises(ImageError, match="would overwrite the input"):
        warp_frames([d / "f0.npy", d / "f1.npy"], [d / "o.npy", d / "f0.npy"], np.zeros((128, 256, 2), np.float32), (128, 256))
    (d / "hard.npy").unlink()
    (d / "hlink.npy").unlink()
    assert _state(d) == before


# --- part 4: no litter ----------------------------------------------------------------------------


def _hidden(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.startswith("."))


def _omniwidget(*argv: str) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "omniwidget", *argv], cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )


def _wait_for(found, process: subprocess.Popen[str], what: str, timeout: float = 60.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = found()
        if value:
            return value
        if process.poll() is not None:
            pytest.fail(f"the run ended before {what}: {process.communicate()}")
        time.sleep(0.005)
    process.kill()
    pytest.fail(f"waited {timeout} s in vain until {what}")


def _clip(path: Path, frames: int) -> None:
    av = pytest.importorskip("av")
    base = _panorama(3)
    with av.open(str(path), "w") as out:
        video = out.add_stream("libx264", rate=24, options={"preset": "ultrafast", "crf": "30"})
        video.width, video.height, video.pix_fmt = 256, 128, "yuv420p"
        for i in range(frames):
            frame = av.VideoFrame.from_ndarray(np.ascontiguousarray(np.roll(base, 4 * i, axis=1)), format="rgb24")
            frame.pts = i
            out.mux(video.encode(frame))
        out.mux(video.encode(None))


def _slow_video_warp(d: Path) -> subprocess.Popen[str]:
    """A warp of 240 frames by a saved map, slowed by the encoder's slowest preset (about 8 s): long enough to be stopped midway."""
    _clip(d / "long.mp4", 240)
    return _omniwidget("warp", f"{d}/long.mp4", "--apply-map", f"{d}/map.npy", "-o", f"{d}/out.mp4", "--preset", "placebo")


def _part(d: Path) -> list[Path]:
    return [p for p in d.glob(".out.mp4.*.part") if p.stat().st_size > 0]


def test_sigterm_during_a_video_warp_leaves_no_hidden_file(d):
    process = _slow_video_warp(d)
    _wait_for(lambda: _part(d), process, "the video's temporary file was written to")
    process.send_signal(signal.SIGTERM)
    _, err = process.communicate(timeout=60)
    assert process.returncode == 143, err
    assert err.strip().splitlines()[-1] == "omniwidget warp: terminated", err
    assert _hidden(d) == [] and not (d / "out.mp4").exists(), sorted(p.name for p in d.iterdir())


def test_what_a_killed_video_warp_left_is_removed_by_the_next_run(d):
    process = _slow_video_warp(d)
    (left,) = _wait_for(lambda: _part(d), process, "the video's temporary file was written to")
    process.kill()  # kill -9: nothing of ours runs
    process.communicate(timeout=60)
    assert left.exists()  # the litter the issue found
    _clip(d / "short.mp4", 6)
    rerun = _omniwidget("warp", f"{d}/short.mp4", "--apply-map", f"{d}/map.npy", "-o", f"{d}/out.mp4", "--preset", "ultrafast")
    _, err = rerun.communicate(timeout=120)
    assert rerun.returncode == 0, err
    assert _hidden(d) == [] and (d / "out.mp4").stat().st_size > 0


#: A process that writes ``argv[1]`` with atomic_write_bytes and stops just before the rename, as if killed there.
_STUCK_WRITER = """
import os, sys, time
os.replace = lambda *args: (print("stuck", flush=True), time.sleep(120))
from omniwidget._files import atomic_write_bytes
atomic_write_bytes(sys.argv[1], b"half of it")
"""


def test_what_a_killed_write_left_is_removed_by_the_next_run_and_a_live_one_is_not(d):
    out = d / "out.png"
    writer = subprocess.Popen([sys.executable, "-c", _STUCK_WRITER, str(out)], cwd=ROOT, stdout=subprocess.PIPE, text=True)
    assert writer.stdout is not None and writer.stdout.readline() == "stuck\n"
    (left,) = [d / n for n in _hidden(d)]
    assert left.name.startswith(".out.png.") and left.name.endswith(".tmp") and left.read_bytes() == b"half of it"
    assert remove_leftovers(out) == [] and left.exists()  # a live writer holds its file: left alone
    writer.kill()
    writer.communicate(timeout=30)
    assert left.exists()  # kill -9: the litter the issue found
    run = _omniwidget("warp", f"{d}/in.png", "-H", f"{d}/h.json", "-o", str(out))
    _, err = run.communicate(timeout=120)
    assert run.returncode == 0, err
    assert _hidden(d) == [] and out.stat().st_size > 0


def test_sigterm_during_many_frames_stops_them_and_leaves_no_hidden_file(d):
    """400 frames (hard links of one file, so quick to make): SIGTERM once the first is written."""
    (d / "frames").mkdir()
    (d / "out").mkdir()
    write_image(d / "frame.png", _panorama(2))
    names = [str(d / "frames" / f"f{i:03d}.png") for i in range(400)]
    for name in names:
        os.link(d / "frame.png", name)
    process = _omniwidget("warp", *names, "--apply-map", f"{d}/map.npy", "-o", f"{d}/out", "--workers", "1")
    _wait_for(lambda: any(p.suffix == ".png" for p in (d / "out").iterdir()), process, "a frame was written")
    process.send_signal(signal.SIGTERM)
    _, err = process.communicate(timeout=60)
    assert process.returncode == 143, err
    assert err.strip().splitlines()[-1] == "omniwidget warp: terminated", err
    written = list((d / "out").iterdir())
    assert _hidden(d / "out") == [] and 0 < len(written) < len(names), len(written)


def test_remove_leftovers_removes_only_our_unlocked_regular_files(d):
    out = d / "out.png"
    ours = [d / ".out.png.0a1b2c3d.tmp", d / ".out.png.ab_cd12x.tmp", d / ".out.png.0a1b2c3d.part"]
    for p in ours:
        p.write_bytes(b"left")
    others = [d / ".out.png.0a1b2c3.tmp", d / ".other.png.0a1b2c3d.tmp", d / "out.png.0a1b2c3d.tmp", d / ".out.png.0a1b2c3d.tmp~"]
    for p in others:
        p.write_bytes(b"not ours")
    (d / ".out.png.linklink.tmp").symlink_to(d / "in.png")  # a link named as ours: not followed, not removed
    os.mkfifo(d / ".out.png.fifofifo.tmp")  # a FIFO named as ours: not waited on, not removed
    assert sorted(remove_leftovers(out)) == sorted(ours)
    assert all(p.exists() for p in others) and (d / ".out.png.linklink.tmp").is_symlink() and (d / ".out.png.fifofifo.tmp").exists()


def test_atomic_write_syncs_the_file_before_the_rename_and_the_folder_after(d, monkeypatch):
    calls: list[str] = []
    fsync, replace = os.fsync, os.replace

    def record_fsync(fd: int) -> None:
        calls.append("fsync folder" if stat.S_ISDIR(os.fstat(fd).st_mode) else f"fsync a file of {os.fstat(fd).st_size} bytes")
        fsync(fd)

    monkeypatch.setattr(os, "fsync", record_fsync)
    monkeypatch.setattr(os, "replace", lambda *a: (calls.append("rename"), replace(*a))[1])
    atomic_write_bytes(d / "out.bin", b"all of it")
    assert calls == ["fsync a file of 9 bytes", "rename", "fsync folder"]
    assert (d / "out.bin").read_bytes() == b"all of it" and _hidden(d) == []
