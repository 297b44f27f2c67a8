"""``omniwidget level`` and ``omniwidget suggest`` on generated rooms whose edges and tilt are known exactly."""

from __future__ import annotations

import numpy as np
import pytest

from omniwidget.app.cli import main
from omniwidget.detect import level
from omniwidget.document.handles import LineHandle, Options, load_handles
from omniwidget.evaluate.scenes import synthetic_room
from omniwidget.io.images import read_image, write_image
from omniwidget.sphere import coords

PITCH, ROLL = 7.0, -5.0  # the camera's tilt, degrees
WIDTH = 1024


@pytest.fixture(scope="module")
def room():
    return synthetic_room(WIDTH, pitch=PITCH, roll=ROLL)


@pytest.fixture
def files(tmp_path, room):
    write_image(tmp_path / "room.png", room.image)
    return tmp_path


def _vertical_edges(room) -> list:
    """The room's lines that are vertical in 3D: the four vertical edges and the wall grid's vertical lines."""
    up = np.array(
        [
            np.sin(np.radians(PITCH)) * np.cos(np.radians(ROLL)),
            -np.sin(np.radians(ROLL)),
            np.cos(np.radians(PITCH)) * np.cos(np.radians(ROLL)),
        ]
    )
    out = []
    for line in room.lines:
        d = np.subtract(line.end_3d, line.start_3d)
        if abs(d @ up) > 0.9999 * np.linalg.norm(d):
            out.append(line)
    return out


def _samples(start, end, n=64, pole=75.0) -> np.ndarray:
    """Points along the arc, away from the poles (where a meridian's longitude means nothing)."""
    s = coords.geodesic(start, end, np.linspace(0.0, 1.0, n))
    return s[np.abs(s[:, 1]) < pole]


def _arc_distance(points, line) -> np.ndarray:
    """Degrees from each point to the scene line's arc (its great circle, and the nearer end beyond the arc's ends)."""
    a, b = coords.lonlat_to_xyz([line.start, line.end])
    n = np.cross(a, b)
    n /= np.linalg.norm(n)
    p = coords.lonlat_to_xyz(points)
    to_circle = np.degrees(np.arcsin(np.clip(np.abs(p @ n), 0.0, 1.0)))
    inside = (np.cross(a, p) @ n >= 0) & (np.cross(p, b) @ n >= 0)
    to_ends = np.minimum(coords.angular_distance(points, line.start), coords.angular_distance(points, line.end))
    return np.where(inside, to_circle, to_ends)


def test_level_makes_the_vertical_edges_vertical_and_the_map_reproduces_the_output(files, room, capsys):
    argv = [
        "level",
        str(files / "room.png"),
        "-o",
        str(files / "level.png"),
        "--map",
        str(files / "map.npy"),
        "-H",
        str(files / "level.json"),
    ]
    assert main(argv) == 0
    out = capsys.readouterr().err  # the closing line (tests/test_cli_report.py checks its words)
    assert out.count("\n") == 1 and "pitch" in out and "roll" in out and "vertical edges" in out, out
    assert sorted(p.name for p in files.iterdir()) == ["level.json", "level.png", "map.npy", "room.png"]  # no temporary files

    # the handles file: no handles, options.up set, the default mode otherwise (the rotation alone)
    doc = load_handles(files / "level.json")
    assert doc.handles == () and doc.options.up is not None and doc.options.anchor == Options().anchor
    rotation = doc.options.levelling()
    assert rotation is not None

    # the map is the rotation's inverse at every output pixel: the output is the input seen through it
    inverse = np.load(files / "map.npy")
    assert inverse.dtype == np.float32 and inverse.shape == (WIDTH // 2, WIDTH, 2)
    lon, lat = coords.grid_lonlat(WIDTH)
    grid = np.stack(np.meshgrid(lon, lat), axis=-1)
    assert coords.angular_distance(inverse, rotation.inverse(grid)).max() < 1e-3

    # and warp --apply-map with it gives the same image as level
    assert main(["warp", str(files / "room.png"), "--apply-map", str(files / "map.npy"), "-o", str(files / "again.png")]) == 0
    levelled, again = read_image(files / "level.png"), read_image(files / "again.png")
    assert levelled.shape == room.image.shape
    assert np.abs(levelled.astype(int) - again.astype(int)).max() <= 1

    # every vertical edge of the room is a meridian in the output: its longitude the same all along
    verticals = _vertical_edges(room)
    assert len(verticals) >= 8
    spread = []
    for line in verticals:
        moved = rotation(_samples(line.start, line.end))
        lons = np.unwrap(np.radians(moved[:, 0]))
        spread.append(float(np.degrees(lons.max() - lons.min())))
    before = [float(np.ptp(np.degrees(np.unwrap(np.radians(_samples(v.start, v.end)[:, 0]))))) for v in verticals]
    print(f"\nlevel: vertical edges span {max(spread):.3f}° of longitude at most (before: {max(before):.1f}°), {len(verticals)} edges")
    assert max(before) > 5.0  # the tilt was there to undo
    assert max(spread) < 0.2, spread  # measured 0.036° at 1024 x 512 (edges up to 75° latitude)


def test_level_refuses_a_panorama_without_vertical_edges(tmp_path, capsys):
    rng = np.random.default_rng(3)
    lat = np.linspace(1.0, 0.0, WIDTH // 2)[:, None, None]
    flat = np.clip(90 + 100 * lat + rng.normal(0, 2, (WIDTH // 2, WIDTH, 3)), 0, 255).astype(np.uint8)  # sky to floor, no edge
    write_image(tmp_path / "flat.png", flat)
    listing = sorted(p.name for p in tmp_path.iterdir())
    code = main(["level", str(tmp_path / "flat.png"), "-o", str(tmp_path / "out.png"), "--map", str(tmp_path / "map.npy")])
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("omniwidget level: error: ") and "Traceback" not in err, err
    assert "vertical" in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == listing  # nothing written


def test_suggest_writes_line_handles_that_lie_on_the_room_s_edges(files, room, capsys):
    assert main(["suggest", str(files / "room.png"), "-o", str(files / "lines.json"), "--max-lines", "25"]) == 0
    out = capsys.readouterr().err
    doc = load_handles(files / "lines.json")  # the loader validates it
    lines = doc.handles
    assert out.startswith(f"omniwidget suggest: wrote {files / 'lines.json'} ({len(lines)} line(s), the structure among "), out
    assert 10 <= len(lines) <= 25 and all(isinstance(h, LineHandle) for h in lines)
    distances = []
    for h in lines:
        samples = coords.geodesic(h.start, h.end, np.linspace(0.0, 1.0, 32))
        # the nearest scene line over most of the handle's length (the median sample)
        distances.append(min(float(np.median(_arc_distance(samples, line))) for line in room.lines))
    distances = np.array(distances)
    on_edges = float((distances < 0.5).mean())
    print(f"\nsuggest: {len(lines)} lines, {on_edges:.0%} within 0.5° of a real edge (median distance {np.median(distances):.3f}°)")
    # the structure at 1024 (its figures are at 2048, tests/test_structure.py): 11 of 13 within 0.5° here, the others 0.51° and 0.78°
    assert on_edges >= 0.8, distances


def test_suggest_with_level_sets_up_and_keeps_the_still_background(files, capsys):
    assert main(["suggest", str(files / "room.png"), "-o", str(files / "both.json"), "--max-lines", "10", "--level"]) == 0
    out = capsys.readouterr().err
    doc = load_handles(files / "both.json")
    found = level(read_image(files / "room.png"))
    assert doc.options.up == pytest.approx(found.up, abs=1e-9) and doc.options.anchor == Options().anchor
    assert doc.handles and all(isinstance(h, LineHandle) and h.id != "level" for h in doc.handles)
    assert f"({len(doc.handles)} line(s), the structure among " in out and "; levelled (options.up): pitch " in out and out.count("\n") == 1, out


def test_bad_input_gives_one_line_and_exit_2(files, capsys):
    d = str(files)
    (files / "text.png").write_text("not an image")
    cases = {
        "missing.png": ["level", f"{d}/missing.png", "-o", f"{d}/o.png"],
        "text.png": ["suggest", f"{d}/text.png", "-o", f"{d}/o.json"],
        "would overwrite the input": ["level", f"{d}/room.png", "-o", f"{d}/room.png"],
        "the handles file must end in .json": ["suggest", f"{d}/room.png", "-o", f"{d}/o.txt"],
        "the map file must end in .npy": ["level", f"{d}/room.png", "-o", f"{d}/o.png", "--map", f"{d}/m.png"],
        "does not exist": ["level", f"{d}/room.png", "-o", f"{d}/no/such/o.png"],
        "--max-lines 0: at least one line": ["suggest", f"{d}/room.png", "-o", f"{d}/o.json", "--max-lines", "0"],
        "must name different files": ["level", f"{d}/room.png", "-o", f"{d}/o.npy", "--map", f"{d}/o.npy"],
    }
    for message, argv in cases.items():
        listing = sorted(p.name for p in files.iterdir())
        code = main(argv)
        err = capsys.readouterr().err
        assert code == 2, (message, err)
        assert message in err and err.count("\n") == 1 and "Traceback" not in err, (message, err)
        assert sorted(p.name for p in files.iterdir()) == listing, message  # nothing written
    with pytest.raises(SystemExit) as info:
        main(["level", f"{d}/room.png"])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert "-o/--output" in err and err.count("\n") == 1


def test_the_commands_are_in_the_help(capsys):
    for command in ("level", "suggest"):
        with pytest.raises(SystemExit) as info:
            main([command, "--help"])
        assert info.value.code == 0
        assert f"omniwidget {command}" in capsys.readouterr().out
