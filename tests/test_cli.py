import hashlib
import json
import re
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from omniwidget.app.cli import main
from omniwidget.io.images import read_image, write_image
from omniwidget.sphere import coords
from omniwidget.sphere.moebius import Moebius

POINT = {
    "format": "omniwidget.handles",
    "version": 1,
    "handles": [{"kind": "point", "position": [10, 20], "target": [35, -5], "rotation": 25.0, "scale": 1.6}],
    "options": {"anchor": None},  # the paper's method: one point, one Möbius map of the whole sphere
}


@pytest.fixture
def files(tmp_path):
    lon, lat = coords.grid_lonlat(256)
    gx, gy = np.meshgrid(lon, lat)
    image = np.stack([(gx + 180) / 360 * 255, (gy + 90) / 180 * 255, np.full_like(gx, 128)], axis=-1).astype(np.uint8)
    write_image(tmp_path / "in.png", image)
    (tmp_path / "h.json").write_text(json.dumps(POINT))
    return tmp_path


def _digest(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_warp_writes_the_image_and_the_map(files, capsys):
    before = _digest(files / "in.png")
    code = main(
        [
            "warp",
            str(files / "in.png"),
            "-H",
            str(files / "h.json"),
            "-o",
            str(files / "out.png"),
            "--map",
            str(files / "map.npy"),
            "--width",
            "128",
        ]
    )
    assert code == 0
    assert _digest(files / "in.png") == before  # the input is never modified
    out = read_image(files / "out.png")
    assert out.shape == (64, 128, 3) and out.dtype == np.uint8
    inv = np.load(files / "map.npy")
    assert inv.dtype == np.float32 and inv.shape == (64, 128, 2)
    m = Moebius.point_map([10, 20], [35, -5], 1.6, 25.0)
    lon, lat = coords.grid_lonlat(128)
    assert coords.angular_distance(inv, m.inverse(np.stack(np.meshgrid(lon, lat), axis=-1))).max() < 1e-4
    assert sorted(p.name for p in files.iterdir()) == ["h.json", "in.png", "map.npy", "out.png"]  # no temporary files


def _run_bad(files, capsys, argv):
    listing = sorted(p.name for p in files.iterdir())
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert sorted(p.name for p in files.iterdir()) == listing  # nothing written
    return err


def test_bad_inputs_give_one_line_and_exit_2(files, capsys):
    d = str(files)
    (files / "wide.png").write_bytes((files / "in.png").read_bytes())
    write_image(files / "wide.png", np.zeros((10, 30, 3), np.uint8))
    (files / "empty.jpg").write_bytes(b"")
    (files / "text.png").write_text("not an image")
    (files / "bad.json").write_text('{"handles": [{"kind": "point", "position": [10, 95]}]}')
    (files / "two.json").write_text(json.dumps({"handles": [POINT["handles"][0], {"kind": "line", "start": [0, 0], "end": [30, 10]}]}))
    cases = {
        "missing.png: cannot read": ["warp", f"{d}/missing.png", "-H", f"{d}/h.json", "-o", f"{d}/o.png"],
        "empty.jpg: the file is empty": ["warp", f"{d}/empty.jpg", "-H", f"{d}/h.json", "-o", f"{d}/o.png"],
        "text.png: not an image": ["warp", f"{d}/text.png", "-H", f"{d}/h.json", "-o", f"{d}/o.png"],
        "wide.png: an equirectangular panorama is twice as wide as high, got 30 x 10": [
            "warp",
            f"{d}/wide.png",
            "-H",
            f"{d}/h.json",
            "-o",
            f"{d}/o.png",
        ],
        "bad.json: handles[0].position[1] (latitude): 95 is out of range": [
            "warp",
            f"{d}/in.png",
            "-H",
            f"{d}/bad.json",
            "-o",
            f"{d}/o.png",
        ],
        "nope.json: cannot read the handles file": ["warp", f"{d}/in.png", "-H", f"{d}/nope.json", "-o", f"{d}/o.png"],
        "would overwrite the input": ["warp", f"{d}/in.png", "-H", f"{d}/h.json", "-o", f"{d}/in.png"],
        "does not exist": ["warp", f"{d}/in.png", "-H", f"{d}/h.json", "-o", f"{d}/no/such/dir/o.png"],
        "must end in": ["warp", f"{d}/in.png", "-H", f"{d}/h.json", "-o", f"{d}/o.xyz"],
        "map file must end in .npy": ["warp", f"{d}/in.png", "-H", f"{d}/h.json", "-o", f"{d}/o.png", "--map", f"{d}/m.txt"],
        "--width 101: the width must be even": ["warp", f"{d}/in.png", "-H", f"{d}/h.json", "-o", f"{d}/o.png", "--width", "101"],
        "one of the arguments -H/--handles --apply-map is required": ["warp", f"{d}/in.png", "-o", f"{d}/o.png"],
    }
    for message, argv in cases.items():
        if argv[0] == "warp" and "-H" not in argv:
            with pytest.raises(SystemExit) as info:
                main(argv)
            assert info.value.code == 2
            err = capsys.readouterr().err
            assert message in err and err.count("\n") == 1
            continue
        assert message in _run_bad(files, capsys, argv), message


def test_fit_is_refused_unless_pad_or_stretch_and_the_input_stays_as_it_was(files, capsys):
    before = _digest(files / "in.png")
    with pytest.raises(SystemExit) as info:
        main(["warp", str(files / "in.png"), "-H", str(files / "h.json"), "-o", str(files / "o.png"), "--fit", "crop"])
    err = capsys.readouterr().err
    assert info.value.code == 2 and "argument --fit: invalid choice: 'crop'" in err and err.count("\n") == 1
    # a panorama that is 2:1 already is warped as it is, whatever --fit says
    plain = files / "plain.png"
    assert main(["warp", str(files / "in.png"), "-H", str(files / "h.json"), "-o", str(plain)]) == 0
    for fit in ("pad", "stretch"):
        assert main(["warp", str(files / "in.png"), "-H", str(files / "h.json"), "-o", str(files / f"{fit}.png"), "--fit", fit]) == 0
        assert (files / f"{fit}.png").read_bytes() == plain.read_bytes()
    assert _digest(files / "in.png") == before


def test_several_handles_are_blended(files, capsys):
    doc = {
        "handles": [
            {"kind": "point", "position": [0, 0], "target": [-40, 5]},  # into the cage, which holds still (Fig. 15)
            {"kind": "line", "start": [60, 30], "end": [100, 35]},
            {"kind": "cage", "vertices": [[-60, -10], [-30, -10], [-45, 20]]},
        ]
    }
    (files / "three.json").write_text(json.dumps(doc))
    assert main(["warp", str(files / "in.png"), "-H", str(files / "three.json"), "-o", str(files / "three.png")]) == 0
    assert read_image(files / "three.png").shape == (128, 256, 3)
    err = capsys.readouterr().err.splitlines()  # the conflict and the blend's fold, untangled: one line each, not Python warnings
    assert len(err) == 3 and err[0].startswith("omniwidget: warning: handles[0] (point) moves what handles[2] (cage) holds still"), err
    assert err[1].startswith("omniwidget: warning: the blend folded over near handles[0] (point) and handles[2] (cage)"), err
    assert "untangled" in err[1] and err[1].endswith("the warp is one-to-one"), err
    assert re.search(r"; lines within [\d.e-]+ px, fold-over 0, 2 warnings above \(handles\[0\], handles\[2\]\)$", err[2]), err


def test_the_command_runs_as_a_program(files):
    proc = subprocess.run(
        [sys.executable, "-m", "omniwidget", "warp", str(files / "in.png"), "-H", str(files / "h.json"), "-o", str(files / "o.jpg")],
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 0, proc.stderr
    assert read_image(files / "o.jpg").shape == (128, 256, 3)
    proc = subprocess.run(
        [sys.executable, "-m", "omniwidget", "warp", str(files / "nothing.png"), "-H", str(files / "h.json"), "-o", str(files / "o2.png")],
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr


def test_demo_writes_a_before_and_after(tmp_path, capsys):
    """The pictures themselves: tests/test_cli_report.py (the result as it is, the handles drawn apart)."""
    assert main(["demo", "-o", str(tmp_path), "-q"]) == 0
    before, after = read_image(tmp_path / "before.png"), read_image(tmp_path / "after.png")
    assert before.shape == after.shape == (512, 1024, 3)
    changed = np.abs(before.astype(int) - after.astype(int)).max(axis=-1) > 8
    assert 0.005 < changed.mean() < 0.2  # the lines really moved, and the rest of the room stayed where it was
    assert read_image(tmp_path / "before_after.png").shape == (1032, 1024, 3)
    assert json.loads((tmp_path / "handles.json").read_text())["handles"][0]["kind"] == "line"


json_values = st.recursive(
    st.one_of(st.none(), st.booleans(), st.floats(), st.integers(-400, 400), st.text(max_size=4)),
    lambda kids: st.one_of(
        st.lists(kids, max_size=4),
        st.dictionaries(
            st.sampled_from(["kind", "position", "target", "start", "end", "handles", "vertices", "scale", "x"]), kids, max_size=4
        ),
    ),
    max_leaves=12,
)


FUZZED_FILES = st.one_of(json_values, st.fixed_dictionaries({"handles": st.lists(json_values, max_size=3)}))


@pytest.mark.slow  # 150 files: the full suite; the fast loop runs 30 (below)
@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(FUZZED_FILES)
def test_fuzzed_handles_files_never_give_a_traceback(files, capsys, data):
    _check_fuzzed_file(files, capsys, data)


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(FUZZED_FILES)
def test_fuzzed_handles_files_never_give_a_traceback_fast(files, capsys, data):
    """The fast loop's twin: the same files strategy and checks, 30 draws."""
    _check_fuzzed_file(files, capsys, data)


def _check_fuzzed_file(files, capsys, data) -> None:
    (files / "fuzz.json").write_text(json.dumps(data, allow_nan=True))
    code = main(["warp", str(files / "in.png"), "-H", str(files / "fuzz.json"), "-o", str(files / "fuzz.png"), "--quiet"])
    err = capsys.readouterr().err
    assert code in (0, 2)
    assert (code == 0) == (err == "")  # --quiet: nothing on success (these files draw no conflicts), one error line else
    (files / "fuzz.png").unlink(missing_ok=True)


# --- many frames, one map --------------------------------------------------------------


@pytest.fixture
def frames(files):
    """Five frames of one size: the fixture's panorama shifted in colour, as JPEG and PNG."""
    base = read_image(files / "in.png")
    paths = []
    for i in range(5):
        path = files / "frames" / f"f{i:02d}.{'jpg' if i % 2 else 'png'}"
        path.parent.mkdir(exist_ok=True)
        write_image(path, np.clip(base.astype(int) + 20 * i, 0, 255).astype(np.uint8))
        paths.append(path)
    return paths


LINES = {"handles": [{"kind": "line", "start": [-4, 37.5], "end": [68, 36.5]}, {"kind": "line", "start": [-83, 12], "end": [-45.5, 12]}]}


def test_many_frames_share_one_map_and_keep_their_names(files, frames, capsys):
    (files / "lines.json").write_text(json.dumps(LINES))
    out = files / "out"
    argv = ["warp", *map(str, frames), "-H", str(files / "lines.json"), "-o", str(out), "--map", str(files / "m.npy")]
    assert main(argv) == 0
    printed = capsys.readouterr().err
    assert f"wrote 5 of 5 frame(s) to {out}/ and {files / 'm.npy'} (256 x 128) in " in printed and "frames per second" in printed
    assert sorted(p.name for p in out.iterdir()) == sorted(p.name for p in frames)  # no temporary files either
    # each frame as `omniwidget warp` of it alone makes it (the same blend; float32 coordinates either way)
    for frame in (frames[0], frames[3]):
        alone = files / f"alone{frame.suffix}"
        assert main(["warp", str(frame), "-H", str(files / "lines.json"), "-o", str(alone)]) == 0
        many, one = read_image(out / frame.name).astype(int), read_image(alone).astype(int)
        tolerance = 0.5 if frame.suffix == ".png" else 2.0  # JPEG re-encoding
        assert np.abs(many - one).mean() < tolerance, np.abs(many - one).mean()
    # the saved map applied to the same frames gives the same bytes, on one thread or several
    again = files / "again"
    assert main(["warp", *map(str, frames), "--apply-map", str(files / "m.npy"), "-o", str(again), "--workers", "1"]) == 0
    for frame in frames:
        assert (again / frame.name).read_bytes() == (out / frame.name).read_bytes()


def test_a_bad_frame_is_reported_and_the_others_are_written(files, frames, capsys):
    (files / "lines.json").write_text(json.dumps(LINES))
    (files / "frames" / "f02.png").write_bytes(b"broken")
    write_image(files / "frames" / "f04.png", np.zeros((64, 128, 3), np.uint8))
    out = files / "out"
    assert main(["warp", *map(str, frames), "-H", str(files / "lines.json"), "-o", str(out)]) == 2
    err = capsys.readouterr().err.splitlines()
    assert any("f02.png: not an image" in line for line in err), err
    assert any("f04.png: the frame is 128 x 64, the map is for 256 x 128" in line for line in err), err
    assert err[-1].endswith("2 of 5 frames were not warped (see above)") and not any("Traceback" in line for line in err)
    assert sorted(p.name for p in out.iterdir()) == ["f00.png", "f01.jpg", "f03.jpg"]


def test_many_frames_refuse_what_would_lose_work(files, frames, capsys):
    d = str(files)
    np.save(files / "bad_map.npy", np.zeros((10, 10, 2), np.float32))
    twin = files / "other" / frames[0].name
    twin.parent.mkdir()
    twin.write_bytes(frames[0].read_bytes())
    f = [str(p) for p in frames]
    cases = {
        "with 5 inputs, -o names a folder": ["warp", *f, "-H", f"{d}/h.json", "-o", f"{d}/o.png"],
        "inputs share the file name f00.png": ["warp", f[0], str(twin), "-H", f"{d}/h.json", "-o", f"{d}/out"],
        "frames/f00.png would overwrite the input": ["warp", *f, "-H", f"{d}/h.json", "-o", str(frames[0].parent)],
        "bad_map.npy: a map must have shape (H, 2H, 2)": ["warp", *f, "--apply-map", f"{d}/bad_map.npy", "-o", f"{d}/out"],
        "missing.npy: cannot read the map": ["warp", *f, "--apply-map", f"{d}/missing.npy", "-o", f"{d}/out"],
    }
    for message, argv in cases.items():
        assert message in _run_bad(files, capsys, argv), message
    np.save(files / "frames" / "../m.npy", np.zeros((64, 128, 2), np.float32))
    assert "the map" in _run_bad(files, capsys, ["warp", f[0], "--apply-map", f"{d}/m.npy", "-o", f"{d}/o.png", "--width", "64"])


def test_progress_is_reported_frame_by_frame(files, frames):
    from omniwidget.app.frames import map_coordinates, warp_frames

    calls = []
    inverse = np.stack(np.meshgrid(*coords.grid_lonlat(256)), axis=-1)
    report = warp_frames(
        frames, [files / f"p{i}.png" for i in range(5)], map_coordinates(inverse, 256), (128, 256), progress=lambda *a: calls.append(a)
    )
    assert calls == [(i, 5) for i in range(1, 6)] and len(report.written) == 5 and report.fps > 0
    # the identity map gives each frame back
    assert np.array_equal(read_image(files / "p0.png"), read_image(frames[0]))
