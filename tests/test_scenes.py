"""Tests of the synthetic room: the lines are drawn exactly where the ground truth says."""

from __future__ import annotations

import math

import numpy as np
import pytest

from omniwidget.evaluate.scenes import FACE_COLORS, FACE_NAMES, LINE_COLOR, Scene, SceneLine, subdivide_line, synthetic_room
from omniwidget.sphere import coords

LUMA = np.array([0.299, 0.587, 0.114])


@pytest.fixture(scope="module")
def room() -> Scene:
    """The default room at the default width, rendered once."""
    return synthetic_room()


@pytest.fixture(scope="module")
def small_room() -> Scene:
    return synthetic_room(512)


def luminance_along(scene: Scene, lonlat: np.ndarray) -> np.ndarray:
    """Luminance of the nearest pixel to each ``[lon, lat]``."""
    x, y = np.rint(coords.lonlat_to_px(lonlat, scene.width)).astype(int).T
    height = scene.image.shape[0]
    return scene.image[np.clip(y, 0, height - 1), x % scene.width] @ LUMA


def base_luminance(line: SceneLine) -> float:
    """Luminance of the palest face the line is painted on."""
    return min(float(np.dot(FACE_COLORS[face], LUMA)) for face in line.faces)


def interior_points(line: SceneLine, count: int = 50) -> np.ndarray:
    return coords.geodesic(line.start, line.end, np.linspace(0.0, 1.0, count + 2)[1:-1])


def normal(line: SceneLine) -> np.ndarray:
    """Unit normal of the line's great circle."""
    a, b = coords.lonlat_to_xyz([line.start, line.end])
    n = np.cross(a, b)
    return n / np.linalg.norm(n)


def distance_to_arc(points: np.ndarray, line: SceneLine) -> np.ndarray:
    """Angular distance in degrees from unit vectors ``points`` (N, 3) to the line's arc."""
    a, b = coords.lonlat_to_xyz([line.start, line.end])
    n = normal(line)
    foot = points - np.outer(points @ n, n)  # projection onto the great circle's plane
    on_arc = (np.cross(a, foot) @ n >= 0) & (np.cross(foot, b) @ n >= 0)
    to_circle = np.degrees(np.arcsin(np.clip(np.abs(points @ n), 0.0, 1.0)))
    to_ends = np.minimum(np.degrees(np.arccos(np.clip(points @ a, -1, 1))), np.degrees(np.arccos(np.clip(points @ b, -1, 1))))
    return np.where(on_arc, to_circle, to_ends)


def room_frame(scene: Scene, p: tuple[float, float, float]) -> np.ndarray:
    """A camera-frame point in the room frame: undo the yaw, then add the camera position."""
    c, s = math.cos(math.radians(scene.yaw)), math.sin(math.radians(scene.yaw))
    x, y, z = p
    return np.array([c * x + s * y, -s * x + c * y, z]) + np.array(scene.camera)


# --- the image ------------------------------------------------------------------------


def test_image_shape_and_dtype(small_room: Scene) -> None:
    assert small_room.image.shape == (256, 512, 3)
    assert small_room.image.dtype == np.uint8
    assert small_room.width == 512


def test_render_is_deterministic(small_room: Scene) -> None:
    again = synthetic_room(512)
    assert again.image.tobytes() == small_room.image.tobytes()
    assert again.lines == small_room.lines


def test_noise_is_reproducible_with_a_seed(small_room: Scene) -> None:
    a = synthetic_room(256, noise=4.0, seed=7).image
    b = synthetic_room(256, noise=4.0, seed=7).image
    c = synthetic_room(256, noise=4.0, seed=8).image
    clean = synthetic_room(256).image
    assert a.tobytes() == b.tobytes()
    assert a.tobytes() != c.tobytes()
    assert 3.0 < np.std(a.astype(float) - clean) < 5.0


def test_lines_are_drawn_on_the_ground_truth_arcs(room: Scene) -> None:
    lines = room.lines_where(min_length=20, max_length=60, max_abs_lat=60)
    assert len(lines) >= 10
    assert {line.kind for line in lines} == {"edge", "grid"}
    ratios = np.array([luminance_along(room, interior_points(line)).mean() / base_luminance(line) for line in lines])
    # Even the thinnest (sub-pixel, anti-aliased) lines are well below their face...
    assert ratios.max() < 0.7
    # ... and most are fully dark: LINE_COLOR is 0.18 of the faces' luminance.
    assert np.median(ratios) < 0.3


def test_beside_the_ground_truth_arcs_is_pale(room: Scene) -> None:
    """The control for the test above: 2 degrees off the arc, the face shows."""
    for line in room.lines_where(min_length=20, max_length=60, max_abs_lat=60):
        shifted = coords.lonlat_to_xyz(interior_points(line)) + math.tan(math.radians(2.0)) * normal(line)
        ratio = luminance_along(room, coords.xyz_to_lonlat(shifted)).mean() / base_luminance(line)
        assert ratio > 0.85, line


def test_all_lines_are_drawn(room: Scene) -> None:
    for line in room.lines_where(max_abs_lat=80):
        assert luminance_along(room, interior_points(line)).mean() < 0.7 * base_luminance(line), line


def test_pixels_away_from_lines_show_their_face_colour(room: Scene) -> None:
    # Every ray of a pixel lies within half a pixel diagonal of its centre, and painted
    # ink within edge_width / 2 metres of a line, seen from at least the camera's
    # distance to the nearest wall.
    nearest_wall = float(np.min(np.array(room.size) / 2 - np.abs(room.camera)))
    ink_reach = math.degrees(max(room.edge_width, room.line_width) / 2 / nearest_wall)
    margin = ink_reach + math.sqrt(0.5) * 360.0 / room.width + 0.05

    rng = np.random.default_rng(0)
    px = np.stack([rng.integers(0, room.width, 20000), rng.integers(0, room.width // 2, 20000)], axis=-1)
    lonlat = coords.px_to_lonlat(px, room.width)
    points = coords.lonlat_to_xyz(lonlat)
    clearance = np.min([distance_to_arc(points, line) for line in room.lines], axis=0)
    away = clearance > margin
    assert away.mean() > 0.5

    expected = np.array([FACE_COLORS[name] for name in room.face_at(lonlat[away])])
    assert np.array_equal(room.image[px[away, 1], px[away, 0]], expected)


def test_straight_down_and_up(small_room: Scene) -> None:
    assert np.all(small_room.image[-1] == FACE_COLORS["floor"])
    assert np.all(small_room.image[0] == FACE_COLORS["ceiling"])
    assert list(small_room.face_at([[0.0, -89.0], [0.0, 89.0]])) == ["floor", "ceiling"]
    # The room's +x axis is seen at longitude yaw.
    assert small_room.face_at([small_room.yaw, 0.0]) == "east"
    assert small_room.face_at([small_room.yaw + 180.0, 0.0]) == "west"


def test_supersampling_anti_aliases() -> None:
    palette = {tuple(c) for c in FACE_COLORS.values()} | {LINE_COLOR}
    aliased = synthetic_room(256, supersample=1).image.reshape(-1, 3)
    smooth = synthetic_room(256, supersample=3).image.reshape(-1, 3)
    assert {tuple(c) for c in np.unique(aliased, axis=0)} <= palette
    assert len({tuple(c) for c in np.unique(smooth, axis=0)} - palette) > 10


def test_yaw_turns_the_image() -> None:
    """Turning the room by a whole number of pixels moves the image east by as many columns."""
    width, shift = 256, 5
    step = 360.0 / width
    a = synthetic_room(width, yaw=17.0)
    b = synthetic_room(width, yaw=17.0 + shift * step)
    assert np.mean(b.image != np.roll(a.image, shift, axis=1)) < 1e-3
    for la, lb in zip(a.lines, b.lines, strict=True):
        assert coords.wrap_lon(lb.start[0] - la.start[0] - shift * step) == pytest.approx(0.0, abs=1e-9)
        assert lb.start[1] == pytest.approx(la.start[1], abs=1e-9)


# --- the ground truth -----------------------------------------------------------------


def test_line_inventory(small_room: Scene) -> None:
    kinds = [line.kind for line in small_room.lines]
    assert kinds.count("edge") == 12
    # 8 x 6 x 3 m with a 1 m grid: 7 + 5 lines on floor and ceiling, 5 + 2 on the
    # west and east walls, 7 + 2 on the south and north walls.
    assert kinds.count("grid") == 2 * 12 + 2 * 7 + 2 * 9
    assert len(synthetic_room(64, grid=None).lines) == 12


def test_endpoints_project_to_start_and_end(small_room: Scene) -> None:
    for line in small_room.lines:
        lonlat = coords.xyz_to_lonlat([line.start_3d, line.end_3d])
        assert np.allclose(lonlat, [line.start, line.end], atol=1e-12)


def test_segments_lie_on_their_faces(small_room: Scene) -> None:
    half = np.array(small_room.size) / 2
    for line in small_room.lines:
        p, q = room_frame(small_room, line.start_3d), room_frame(small_room, line.end_3d)
        assert np.all(np.abs(p) <= half + 1e-9) and np.all(np.abs(q) <= half + 1e-9)
        for face in line.faces:
            axis, side = divmod(FACE_NAMES.index(face), 2)
            wall = half[axis] if side else -half[axis]
            assert p[axis] == pytest.approx(wall) and q[axis] == pytest.approx(wall), (line, face)
        # Edges and grid lines run parallel to an axis of the room, from wall to wall.
        along = np.flatnonzero(np.abs(q - p) > 1e-9)
        assert len(along) == 1 and abs(q - p)[along[0]] == pytest.approx(2 * half[along[0]])


def test_straight_segments_image_on_the_great_circle(small_room: Scene) -> None:
    """Any point of the 3D segment is seen on the great circle through its endpoints."""
    for line in small_room.lines:
        p, q = np.array(line.start_3d), np.array(line.end_3d)
        for s in (0.1, 0.5, 0.9):
            direction = (1 - s) * p + s * q
            assert abs(direction @ normal(line)) / np.linalg.norm(direction) < 1e-12


def test_lines_where_filters(room: Scene) -> None:
    chosen = room.lines_where(kind="grid", min_length=20, max_length=60, max_abs_lat=60)
    assert chosen
    for line in room.lines:
        dense = coords.geodesic(line.start, line.end, np.linspace(0, 1, 2001))
        assert line.max_abs_lat == pytest.approx(np.abs(dense[:, 1]).max(), abs=1e-3)
        expected = line.kind == "grid" and 20 <= line.length <= 60 and line.max_abs_lat <= 60
        assert (line in chosen) == expected
    assert room.lines_where() == room.lines
    assert all(line.kind == "edge" for line in room.lines_where(kind="edge"))


def test_subdivide_line(room: Scene) -> None:
    line = max(room.lines, key=lambda line: line.length)
    assert line.length > 100
    pieces = subdivide_line(line, 25.0)
    assert len(pieces) == math.ceil(line.length / 25.0)
    assert pieces[0].start == line.start and pieces[-1].end == line.end
    assert sum(piece.length for piece in pieces) == pytest.approx(line.length)
    a, b = np.array(line.start_3d), np.array(line.end_3d)
    for piece, following in zip(pieces, pieces[1:] + [None], strict=True):
        assert piece.length <= 25.0 + 1e-9
        assert piece.kind == line.kind and piece.faces == line.faces
        if following is not None:
            assert piece.end == following.start and piece.end_3d == following.start_3d
        # Every cut point is on the original 3D segment, and so on its great circle.
        for point in (piece.start_3d, piece.end_3d):
            s = np.dot(np.array(point) - a, b - a) / np.dot(b - a, b - a)
            assert 0.0 <= s <= 1.0 + 1e-12
            assert np.allclose(a + s * (b - a), point, atol=1e-12)
        assert np.allclose(coords.xyz_to_lonlat([piece.start_3d, piece.end_3d]), [piece.start, piece.end], atol=1e-12)
        # The piece is still drawn: dark along its own geodesic.
        assert luminance_along(room, interior_points(piece, 20)).mean() < 0.7 * base_luminance(piece)
    assert subdivide_line(line, 180.0) == [line]


# --- bad parameters -------------------------------------------------------------------


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"width": 1023}, "width"),
        ({"width": 6}, "width"),
        ({"width": 512.0}, "width"),
        ({"width": True}, "width"),
        ({"size": (8.0, -6.0, 3.0)}, "size"),
        ({"size": (8.0, 6.0)}, "size"),
        ({"camera": (4.5, 0.0, 0.0)}, "camera"),
        ({"camera": (0.0, 0.0, -1.5)}, "camera"),
        ({"camera": (0.0, 0.0)}, "camera"),
        ({"camera": (0.0, float("nan"), 0.0)}, "camera"),
        ({"yaw": float("inf")}, "yaw"),
        ({"grid": 0.0}, "grid"),
        ({"grid": 0.01}, "grid"),
        ({"line_width": 0.0}, "line_width"),
        ({"line_width": "thin"}, "line_width"),
        ({"edge_width": -0.1}, "edge_width"),
        ({"supersample": 0}, "supersample"),
        ({"supersample": 1.5}, "supersample"),
        ({"noise": -1.0}, "noise"),
        ({"seed": "seven"}, "seed"),
    ],
)
def test_bad_parameters_raise(kwargs: dict, name: str) -> None:
    with pytest.raises(ValueError, match=name):
        synthetic_room(**{"width": 64, **kwargs})


def test_bad_helper_arguments(small_room: Scene) -> None:
    with pytest.raises(ValueError, match="kind"):
        small_room.lines_where(kind="wall")
    with pytest.raises(ValueError, match="max_length"):
        subdivide_line(small_room.lines[0], 0.0)
