"""What the command line says: the closing line of warp, level, suggest and demo, ``--quiet``, refusals in its own words.

And the demo's pictures: the result as it is, the handles drawn apart.
"""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

import omniwidget as ow
from omniwidget.app.cli import DEMO_HANDLES, main
from omniwidget.evaluate.scenes import synthetic_room
from omniwidget.io.images import read_image, write_image

#: The two demo lines (window top, television top), rectified: straight in the output.
LINES = {"handles": [{"kind": "line", "start": [-4, 37.5], "end": [68, 36.5]}, {"kind": "line", "start": [-83, 12], "end": [-45.5, 12]}]}
#: The window's top edge kept as it is (``rectify: false``): a bent arc in the output, several pixels off straight.
BENT = {"handles": [{"kind": "line", "start": [-4, 37.5], "end": [68, 36.5], "rectify": False}]}

TIME = r"\d+\.\d\d s"
NUMBER = r"(\d+(?:\.\d+)?(?:e-?\d+)?)"


@pytest.fixture(scope="module")
def room():
    """A generated room taken with a tilted camera (pitch 7°, roll -5°), 512 wide: enough vertical edges to level."""
    return synthetic_room(512, pitch=7.0, roll=-5.0)


@pytest.fixture
def files(tmp_path, room):
    write_image(tmp_path / "pano.png", ow.sample_image()[::2, ::2])  # the bundled room at 512 x 256
    write_image(tmp_path / "room.png", room.image)
    (tmp_path / "lines.json").write_text(json.dumps(LINES))
    (tmp_path / "bent.json").write_text(json.dumps(BENT))
    return tmp_path


def _one_line(capsys) -> str:
    """The run's stderr, which must be one line, and nothing on stdout."""
    captured = capsys.readouterr()
    assert captured.out == "", captured.out
    assert captured.err.count("\n") == 1 and captured.err.endswith("\n"), captured.err
    return captured.err.rstrip("\n")


# --- the closing line -----------------------------------------------------------------------------------


def test_warp_says_what_it_wrote_its_size_the_time_and_how_straight_the_lines_are(files, capsys):
    out, inverse = files / "out.png", files / "map.npy"
    assert main(["warp", str(files / "pano.png"), "-H", str(files / "lines.json"), "-o", str(out), "--map", str(inverse), "--width", "256"]) == 0
    line = _one_line(capsys)
    found = re.fullmatch(
        rf"omniwidget warp: wrote {re.escape(str(out))} and {re.escape(str(inverse))} \(256 x 128\) in {TIME}; "
        rf"lines within {NUMBER} px, fold-over 0, no warnings",
        line,
    )
    assert found, line
    assert read_image(out).shape == (128, 256, 3) and np.load(inverse).shape == (128, 256, 2)  # the size it says is the size written
    assert float(found.group(1)) < 0.25  # rectified lines, densely through the map that placed the pixels: 0.16 px at 256 wide


def test_the_straightness_it_prints_is_what_the_quality_figures_measure(files, capsys):
    """An unrectified line is bent in the output: the closing line says by how much, as ``result.quality`` does."""
    assert main(["warp", str(files / "pano.png"), "-H", str(files / "bent.json"), "-o", str(files / "bent.png")]) == 0
    line = _one_line(capsys)
    printed = float(re.search(rf"lines within {NUMBER} px", line).group(1))
    measured = ow.warp(ow.sample_image()[::2, ::2], ow.Handles.from_dict(BENT), warn=False).quality.straightness
    assert measured > 2.0  # the precondition: the arc really is bent (4.2 px at 512 wide)
    assert printed == pytest.approx(measured, rel=0.03), (printed, measured)  # the same figure, printed to .2g


def test_warnings_come_before_the_closing_line_which_names_the_handles(files, capsys):
    conflict = {
        "handles": [
            {"kind": "cage", "vertices": [[20, 20], [60, 20], [60, -20], [20, -20]]},
            {"kind": "point", "position": [40, 0], "target": [45, 5]},  # moves what the cage holds still
        ]
    }
    (files / "conflict.json").write_text(json.dumps(conflict))
    assert main(["warp", str(files / "pano.png"), "-H", str(files / "conflict.json"), "-o", str(files / "c.png"), "--width", "256"]) == 0
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 2 and err[0].startswith("omniwidget: warning: handles[1] (point) moves what handles[0] (cage) holds still"), err
    assert err[1].startswith(f"omniwidget warp: wrote {files / 'c.png'} (256 x 128) in "), err
    assert err[1].endswith("; fold-over 0, 1 warning above (handles[1], handles[0])"), err  # no lines: no straightness to say
    # --quiet keeps the warning (the result is not what was asked) and drops the closing line
    assert main(["warp", str(files / "pano.png"), "-H", str(files / "conflict.json"), "-o", str(files / "c2.png"), "-q", "--width", "256"]) == 0
    assert capsys.readouterr().err.splitlines() == err[:1]


def test_level_says_what_it_wrote_and_the_tilt_it_found(files, capsys):
    out, saved = files / "level.png", files / "level.json"
    assert main(["level", str(files / "room.png"), "-o", str(out), "-H", str(saved)]) == 0
    line = _one_line(capsys)
    found = re.fullmatch(
        rf"omniwidget level: wrote {re.escape(str(out))} and {re.escape(str(saved))} \(512 x 256\) in {TIME}; "
        r"levelled by pitch ([-+]\d+\.\d\d)°, roll ([-+]\d+\.\d\d)° \(tilt \d+\.\d\d°\) from (\d+) vertical edges; fold-over 0, no warnings",
        line,
    )
    assert found, line
    pitch, roll, edges = float(found.group(1)), float(found.group(2)), int(found.group(3))
    assert abs(pitch - 7.0) < 0.5 and abs(roll + 5.0) < 0.5 and edges >= 4, line  # the room's tilt (measured 6.88°, -5.03°)


def test_suggest_says_how_many_lines_it_wrote(files, capsys):
    out = files / "lines-found.json"
    assert main(["suggest", str(files / "room.png"), "-o", str(out), "--max-lines", "12"]) == 0
    line = _one_line(capsys)
    found = re.fullmatch(rf"omniwidget suggest: wrote {re.escape(str(out))} \((\d+) line\(s\), the structure among (\d+) found\) in {TIME}", line)
    assert found, line
    written = ow.load_handles(out).handles
    assert int(found.group(1)) == len(written) == 12 and int(found.group(2)) > 12


def test_many_frames_say_it_in_one_line_too(files, capsys):
    frames = [files / "a.png", files / "b.png"]
    for frame in frames:
        frame.write_bytes((files / "pano.png").read_bytes())
    out = files / "warped"
    assert main(["warp", *map(str, frames), "-H", str(files / "lines.json"), "-o", str(out)]) == 0
    line = _one_line(capsys)
    assert re.fullmatch(
        rf"omniwidget warp: wrote 2 of 2 frame\(s\) to {re.escape(str(out))}/ \(512 x 256\) in {TIME}: \d+\.\d frames per second "
        rf"\(reading and writing included; the map took {TIME}\); lines within {NUMBER} px, fold-over 0, no warnings",
        line,
    ), line


# --- --quiet --------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "argv",
    [
        ["warp", "{d}/pano.png", "-H", "{d}/lines.json", "-o", "{d}/q.png", "--width", "256", "--quiet"],
        ["warp", "{d}/pano.png", "{d}/room.png", "-H", "{d}/lines.json", "-o", "{d}/q", "-q"],
        ["level", "{d}/room.png", "-o", "{d}/q.png", "-q"],
        ["suggest", "{d}/room.png", "-o", "{d}/q.json", "--quiet"],
        ["demo", "-o", "{d}/demo", "--quiet"],
    ],
    ids=["warp", "frames", "level", "suggest", "demo"],
)
def test_quiet_prints_nothing_on_success(files, capsys, argv):
    assert main([a.format(d=files) for a in argv]) == 0
    captured = capsys.readouterr()
    assert captured.err == "" and captured.out == ""
    written = [files / a.format(d="").lstrip("/") for a in argv if a.startswith("{d}/q") or a == "{d}/demo"]
    assert written and all(p.exists() for p in written)


def test_quiet_still_prints_errors(files, capsys):
    code = main(["warp", str(files / "missing.png"), "-H", str(files / "lines.json"), "-o", str(files / "o.png"), "--quiet"])
    err = capsys.readouterr().err
    assert code == 2 and err.startswith("omniwidget warp: error: ") and "missing.png" in err and err.count("\n") == 1


# --- refusals in the command line's words ----------------------------------------------------------------


def test_a_panorama_that_is_not_2_to_1_is_told_the_option_that_fixes_it(files, capsys):
    write_image(files / "band.png", np.zeros((100, 300, 3), np.uint8))  # 3:1, a 360° band cropped in latitude
    write_image(files / "photo.png", np.zeros((200, 300, 3), np.uint8))  # 3:2, taller than 2:1: only stretching makes it 2:1
    for command, output in (("warp", "o.png"), ("level", "o.png"), ("suggest", "o.json")):
        extra = ["-H", str(files / "lines.json")] if command == "warp" else []
        for name, options in (("band.png", ("--fit pad", "--fit stretch")), ("photo.png", ("--fit stretch",))):
            assert main([command, str(files / name), *extra, "-o", str(files / output)]) == 2
            err = capsys.readouterr().err
            assert err.count("\n") == 1 and err.startswith(f"omniwidget {command}: error: {files / name}: "), err
            assert all(option in err for option in options), err
            assert "fit=" not in err and "to_equirectangular" not in err, err  # no Python in it
            if name == "photo.png":
                assert "--fit pad" not in err, err  # padding rows cannot make 3:2 2:1
    assert not (files / "o.png").exists() and not (files / "o.json").exists()
    # and the option does what the message says
    assert main(["warp", str(files / "band.png"), "-H", str(files / "lines.json"), "-o", str(files / "o.png"), "--fit", "pad", "-q"]) == 0
    assert read_image(files / "o.png").shape == (150, 300, 3)


def test_a_frame_that_is_not_2_to_1_among_many_is_told_the_option_too(files, capsys):
    write_image(files / "band.png", np.zeros((128, 384, 3), np.uint8))
    out = files / "warped"
    assert main(["warp", str(files / "pano.png"), str(files / "band.png"), "-H", str(files / "lines.json"), "-o", str(out), "-q"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert any("band.png" in e and "--fit pad" in e and "fit=" not in e for e in err), err
    assert err[-1] == "omniwidget warp: 1 of 2 frames were not warped (see above)"


def test_a_jpeg_with_alpha_is_not_told_to_slice_an_array(files, capsys):
    write_image(files / "alpha.png", np.zeros((256, 512, 4), np.uint8))
    assert main(["warp", str(files / "alpha.png"), "-H", str(files / "lines.json"), "-o", str(files / "o.jpg")]) == 2
    err = capsys.readouterr().err
    assert "JPEG has no alpha channel; write .png, .tif, .webp or .npy to keep it" in err and "[..." not in err, err


# --- the demo's pictures --------------------------------------------------------------------------------


def test_the_demo_writes_the_result_as_it_is_and_the_handles_drawn_apart(tmp_path, capsys):
    assert main(["demo", "-o", str(tmp_path)]) == 0
    line = _one_line(capsys)
    assert line.startswith(f"omniwidget demo: wrote {tmp_path / 'after.png'} (1024 x 512), the handles drawn apart"), line
    assert re.search(rf"in {TIME}; lines within {NUMBER} px, fold-over 0, no warnings$", line), line
    names = ["after-handles.png", "after.png", "before-handles.png", "before.png", "before_after.png", "handles.json"]
    assert sorted(p.name for p in tmp_path.iterdir()) == names

    image = ow.sample_image()
    handles = ow.Handles.from_dict(DEMO_HANDLES)
    plain = ow.warp(image, handles, warn=False).image
    after, after_drawn = read_image(tmp_path / "after.png"), read_image(tmp_path / "after-handles.png")
    before, before_drawn = read_image(tmp_path / "before.png"), read_image(tmp_path / "before-handles.png")
    # after.png is the warp as it is, pixel for pixel (PNG is lossless; the same warp, so no resampling apart)
    assert after.shape == plain.shape == (512, 1024, 3) and np.array_equal(after, plain)
    assert np.array_equal(before, image)  # before.png: the bundled panorama as it is
    # the handles' ink is in the -handles pictures only: red lines and a white cage (anti-aliased), 0.8% of the picture
    for clean, drawn in ((after, after_drawn), (before, before_drawn)):
        inked = np.any(clean != drawn, axis=-1)
        assert 0.003 < inked.mean() < 0.02, inked.mean()
        red = (drawn[..., 0] > 200) & (drawn[..., 1] < 80) & (drawn[..., 2] < 80)  # the lines' (230, 40, 40)
        white = np.all(drawn > 230, axis=-1)  # the cage's
        assert red[inked].mean() > 0.2 and white[inked].mean() > 0.2, (red[inked].mean(), white[inked].mean())  # measured 0.28, 0.35
        assert not red[~inked].any() and not np.any((clean[..., 0] > 200) & (clean[..., 1] < 80) & (clean[..., 2] < 80))  # no red in the room
    # the ink follows the handles: on the input where they were marked, on the result where their maps put them
    assert np.any(before_drawn != after_drawn)
    stacked = read_image(tmp_path / "before_after.png")
    assert stacked.shape == (1032, 1024, 3) and np.array_equal(stacked[:512], before_drawn) and np.array_equal(stacked[520:], after_drawn)
    assert ow.load_handles(tmp_path / "handles.json") == handles


def test_a_bad_dask_scheduler_or_output_is_said_before_any_work(files, capsys):
    """No cluster needed: a scheduler file that is not there, an address without a port, several videos into one file."""
    frames = [str(files / "pano.png"), str(files / "room.png")]
    cases = {
        f"--dask {files / 'none.json'}: no scheduler file there": [*frames, "-o", str(files / "out"), "--dask", str(files / "none.json")],
        "--dask tcp://scheduler: give the scheduler's address with its port (tcp://host:8786)": [
            *frames,
            "-o",
            str(files / "out"),
            "--dask",
            "tcp://scheduler",
        ],
        f"{files / 'o.mp4'}: with 2 inputs, -o names a folder for their outputs": [
            str(files / "a.mp4"),
            str(files / "b.mp4"),
            "-o",
            str(files / "o.mp4"),
            "--dask",
            "tcp://127.0.0.1:8786",
        ],
    }
    listing = sorted(p.name for p in files.iterdir())
    for message, argv in cases.items():
        assert main(["warp", *argv[:-4], "-H", str(files / "lines.json"), *argv[-4:]]) == 2, message
        err = capsys.readouterr().err
        assert err.startswith(f"omniwidget warp: error: {message}") and err.count("\n") == 1, err
        assert "Traceback" not in err and "outputs=" not in err, err
    assert sorted(p.name for p in files.iterdir()) == listing  # nothing written, no folder made
