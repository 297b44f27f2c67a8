"""One kind object per kind of handle (omniwidget.method.kinds): the table, output points and reset."""

from __future__ import annotations

import typing

import numpy as np
import pytest

from omniwidget.document.handles import CageHandle, Handle, Handles, LineHandle, Options, PointHandle
from omniwidget.method.constraints import build_constraints
from omniwidget.method.kinds import KINDS, kind_of, output_points, reset
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
