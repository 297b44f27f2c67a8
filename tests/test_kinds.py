"""One kind object per kind of handle (omniwidget.method.kinds): the table, output points and reset."""

from __future__ import annotations

import typing

import numpy as np
import pytest

from omniwidget.document.handles import CageHandle, Handle, Handles, LineHandle, Options, PointHandle
from omniwidget.method.constraints import build_constraints
from omniwidget.method.kinds import KINDS, POINT_HOLD, RIM_SAMPLES, kind_of, output_points, reset
from omniwidget.sphere import coords
from omniwidget.sphere.moebius import Moebius

POINT = PointHandle((10.0, 20.0), (15.0, 18.0), rotation=10.0, scale=1.5, id="p", reach=8.0)
LINE = LineHandle((-60.0, 30.0), (-10.0, 35.0))
EXPLICIT = LineHandle((0.0, 0.0), (20.0, 10.0), rectify=False, targets=((0.0, 0.0), (10.0, 4.0), (20.0, 10.0)))
CAGE = CageHandle(((0.0, -10.0), (20.0, -10.0), (10.0, -30.0)), ((0.0, -10.0), (22.0, -10.0), (10.0, -30.0)))


def test_every_kind_of_record_has_one_kind_object():
    assert set(KINDS) == set(typing.get_args(Handle))
    assert {kind_of(h).name for h in (POINT, LINE, CAGE)} == {"point", "line", "cage"} == {h.kind for h in (POINT, LINE, CAGE)}
    with pytest.raises(TypeError, match="got str"):
        kind_of("point")  # type: ignore[arg-type]


def test_output_points_each_line_by_eq4_and_the_other_kinds_where_their_maps_put_them():
    doc = Handles((POINT, LINE, EXPLICIT, CAGE), Options(rectify="each", anchor=None))
    out = output_points(doc, build_constraints(doc))
    assert [len(p) for p in out] == [3, 3, 3, 3]
    np.testing.assert_allclose(out[0], POINT.target_points(), atol=1e-8)
    assert coords.angular_distance(out[0][1], POINT.position) > 1.0  # the tips went with the point
    # eq. (4): the ends stay, the middle is the middle of the ends in the lon/lat plane
    np.testing.assert_allclose(out[1][0], LINE.start, atol=1e-8)
    np.testing.assert_allclose(out[1][2], LINE.end, atol=1e-8)
    np.testing.assert_allclose(out[1][1], np.add(LINE.start, LINE.end) / 2, atol=1e-8)
    np.testing.assert_allclose(out[2], EXPLICIT.targets, atol=1e-8)
    np.testing.assert_allclose(out[3], CAGE.targets, atol=1e-8)
    assert all(v == round(v, 9) for points in out for p in points for v in p)


def test_output_points_of_lines_split_at_a_crossing_come_from_their_pieces():
    a = LineHandle((-40.0, 10.0), (40.0, 30.0))
    b = LineHandle((-10.0, 40.0), (10.0, 0.0))
    doc = Handles((a, b), Options(rectify="all", anchor=None))
    constraints = build_constraints(doc)
    pieces = [[c.moebius for c in constraints.controls if c.handle == i] for i in (0, 1)]
    assert [len(p) for p in pieces] == [2, 2]  # each cut in two at the crossing
    out = output_points(doc, constraints)
    for h, maps, points in zip((a, b), pieces, out, strict=True):
        np.testing.assert_allclose(points[0], maps[0](np.asarray(h.start)), atol=1e-8)  # the start by the first piece
        np.testing.assert_allclose(points[2], maps[1](np.asarray(h.end)), atol=1e-8)  # the end by the second
        whole = h.moebius()(h.control_points())
        assert coords.angular_distance(points, whole).max() > 1e-3  # not the line's own eq. (4)


@pytest.mark.parametrize("h", [POINT, LINE, EXPLICIT, CAGE])
def test_reset_keeps_the_handle_as_drawn_and_its_maps_become_the_identity(h):
    drawn = reset(h)
    assert type(drawn) is type(h) and drawn.id == h.id
    assert all(m.isclose(Moebius.identity(), 1e-9) for m in kind_of(drawn).maps(drawn))
    assert not all(m.isclose(Moebius.identity(), 1e-6) for m in kind_of(h).maps(h))  # each of these was moved
    if isinstance(h, PointHandle):
        assert (drawn.position, drawn.target, drawn.rotation, drawn.scale, drawn.reach) == (h.position, None, 0.0, 1.0, h.reach)
    elif isinstance(h, LineHandle):
        assert (drawn.start, drawn.end, drawn.rectify, drawn.targets) == (h.start, h.end, False, None)
    else:
        assert (drawn.vertices, drawn.targets) == (h.vertices, None)


def test_a_point_holds_its_map_on_a_disk_only_with_the_still_background():
    for anchor, rows in ((None, 1), (5.0, 1 + RIM_SAMPLES)):
        c = build_constraints(Handles((POINT,), Options(anchor=anchor)))
        assert c.values.shape == (rows, 1) and np.all(c.values == 1.0)
        distance = coords.angular_distance(coords.xyz_to_lonlat(c.points), POINT.final)
        np.testing.assert_allclose(np.sort(distance), [0.0] + [POINT_HOLD] * (rows - 1), atol=1e-9)
        assert len(c.disks) == (rows > 1)


def test_a_cage_weighs_its_vertices_linearly_along_each_output_edge():
    c = build_constraints(Handles((CAGE,), Options(anchor=None)), samples=5)
    assert [x.label for x in c.controls] == [f"handles[0] (cage vertex {v})" for v in range(3)]
    assert c.values.shape == (3 * 4, 3)  # 4 samples per edge, the far vertex left to the next edge
    np.testing.assert_allclose(c.values.sum(axis=1), 1.0)
    np.testing.assert_allclose(c.values[:4, :2], [[1.0, 0.0], [0.75, 0.25], [0.5, 0.5], [0.25, 0.75]])
    edge = coords.geodesic(CAGE.targets[0], CAGE.targets[1], np.linspace(0.0, 1.0, 5)[:-1])
    assert coords.angular_distance(coords.xyz_to_lonlat(c.points[:4]), edge).max() < 1e-9


def test_anchors_hold_points_and_cage_edges_where_their_maps_put_them():
    t = np.linspace(0.0, 1.0, 7)
    (point,) = kind_of(POINT).anchors(POINT, t)
    np.testing.assert_allclose(point.outputs, [POINT.final])
    edges = kind_of(CAGE).anchors(CAGE, t)
    assert len(edges) == 3 and kind_of(LINE).anchors(LINE, t) == []
    for v, edge in enumerate(edges):
        assert coords.angular_distance(edge.outputs[[0, -1]], [CAGE.finals[v], CAGE.finals[(v + 1) % 3]]).max() < 1e-9


def test_footprint_covers_input_and_output_and_outline_draws_the_control_points():
    t = np.linspace(0.0, 1.0, 9)
    src, out = kind_of(LINE).footprint(LINE, t)
    np.testing.assert_allclose(out, LINE.moebius()(src))
    assert len(kind_of(CAGE).footprint(CAGE, t)) == 6
    arc = lambda a, b: coords.geodesic(a, b, t)  # noqa: E731
    drawn = kind_of(POINT).outline(POINT, "output", arc)
    np.testing.assert_allclose(drawn.big_dots, [POINT.final], atol=1e-9)
    np.testing.assert_allclose([a[-1] for a in drawn.arcs], POINT.target_points()[1:], atol=1e-9)
    straight = kind_of(LINE).outline(LINE, "output", arc)
    assert straight.dots[1, 1] == pytest.approx((LINE.start[1] + LINE.end[1]) / 2)  # eq. (4)'s middle


def test_carried_turns_what_a_handle_shows_and_leaves_a_rectified_line_to_the_solve():
    turn = Moebius.rotation((0.0, 90.0), 30.0)  # 30° about the vertical: longitudes + 30
    moved = kind_of(POINT).carried(POINT, Moebius.identity(), turn)
    np.testing.assert_allclose(moved.target, (POINT.final[0] + 30.0, POINT.final[1]), atol=1e-9)
    assert moved.rotation == pytest.approx(POINT.rotation, abs=1e-9)  # a turn about the vertical turns no one
    assert kind_of(LINE).carried(LINE, Moebius.identity(), turn) is LINE
    np.testing.assert_allclose(
        kind_of(EXPLICIT).carried(EXPLICIT, Moebius.identity(), turn).targets, np.add(EXPLICIT.targets, [30.0, 0.0]), atol=1e-9
    )
    np.testing.assert_allclose(kind_of(CAGE).carried(CAGE, Moebius.identity(), turn).targets, np.add(CAGE.targets, [30.0, 0.0]), atol=1e-9)


def test_input_turned_moves_every_input_position_and_keeps_the_outputs():
    turn = Moebius.levelling((20.0, 80.0))
    for h in (POINT, LINE, EXPLICIT, CAGE):
        turned = kind_of(h).input_turned(h, turn)
        before, after = kind_of(h).footprint(h, np.zeros(1)), kind_of(turned).footprint(turned, np.zeros(1))
        first, moved = before[0][:1], after[0][:1]  # the first input position
        assert coords.angular_distance(moved, turn(first)).max() < 1e-9
        assert coords.angular_distance(moved, first).max() > 1.0
        if isinstance(h, PointHandle):
            assert turned.target == h.target
        else:
            assert turned.targets == h.targets
    same = kind_of(POINT).input_turned(POINT, Moebius.identity())
    assert coords.angular_distance(same.position, POINT.position) < 1e-9 and same.target == POINT.target


def test_moving_says_which_handles_move_and_where_they_mark():
    assert kind_of(POINT).moving(POINT) == (True, [POINT.position, POINT.final])
    assert kind_of(POINT).moving(reset(POINT)) == (False, [POINT.position, POINT.position])
    assert kind_of(LINE).moving(reset(LINE)) == (True, [LINE.start, LINE.end])
    moves, where = kind_of(CAGE).moving(CAGE)
    assert moves and where == [*CAGE.vertices, *CAGE.finals]
    assert kind_of(CAGE).moving(reset(CAGE))[0] is False
