"""Problems as data: every conflict a warp reports is a record with its kind, the handles it names and its message.

The records agree with their messages (the handles a message names are the record's, in
order), each kind is made by its own check, and a warp's ``warnings``, ``warning_kinds`` and
``gave_way`` are read from the records.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from omniwidget.document.handles import CageHandle, Handles, LineHandle, Options, PointHandle
from omniwidget.evaluate.scenes import synthetic_room
from omniwidget.method.deformation import deform
from omniwidget.method.problems import KINDS, Kind, Problem
from omniwidget.raster.pipeline import warp

STRAIGHT = LineHandle((-60.0, 30.0), (60.0, 30.0))
ACROSS = LineHandle((0.0, 5.0), (0.0, 40.0), rectify=False, targets=((0.0, 20.0), (0.0, 40.0), (0.0, 60.0)))
OVER_POLE = LineHandle((-60.0, 70.0), (110.0, 72.0))
STILL_CAGE = CageHandle(((100.0, -30.0), (140.0, -30.0), (140.0, 0.0), (100.0, 0.0)))
INSIDE = PointHandle((120.0, -15.0), target=(122.0, -14.0))


def _named(message: str) -> tuple[int, ...]:
    """The handles a message names, each once, in the order it names them (the words as the oracle)."""
    return tuple(dict.fromkeys(int(i) for i in re.findall(r"handles\[(\d+)\]", message)))


@pytest.fixture(scope="module")
def room():
    return synthetic_room(512).image


def test_a_problem_is_checked_when_made():
    ok = Problem(Kind.CROSSING, (0, 3), "handles[0] (line) and handles[3] (line) cross each other in the output")
    assert ok.handles == (0, 3) and ok.kind in KINDS
    with pytest.raises(ValueError, match="Problem.kind must be one of"):
        Problem("lines in love", (0,), "x")
    with pytest.raises(ValueError, match=r"Problem.handles must be a tuple of handle indices"):
        Problem(Kind.FOLD, (-1,), "x")
    with pytest.raises(ValueError, match=r"Problem.handles must be a tuple of handle indices"):
        Problem(Kind.FOLD, [0], "x")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="names a handle twice"):
        Problem(Kind.FOLD, (2, 2), "x")
    with pytest.raises(ValueError, match="Problem.message must be a non-empty str"):
        Problem(Kind.FOLD, (2,), "")


@pytest.mark.parametrize("anchor", [5.0, None], ids=["still background", "paper"])
def test_the_records_name_the_handles_their_messages_name(room, anchor):
    doc = Handles((STRAIGHT, ACROSS, OVER_POLE, STILL_CAGE, INSIDE), Options(anchor=anchor))
    result = warp(room, doc, warn=False)
    assert result.warnings == tuple(p.message for p in result.problems)
    assert result.warning_kinds == tuple(p.kind for p in result.problems)
    for p in result.problems:
        assert p.handles == _named(p.message), p
    by_kind = {k: [p for p in result.problems if p.kind == k] for k in KINDS}
    assert [p.handles for p in by_kind[Kind.POLE_LINE]] == [(2,)]
    assert [p.handles for p in by_kind[Kind.CAGE]] == [(4, 3)]  # the handle that moves, then the cage
    assert [p.handles for p in by_kind[Kind.CROSSING]] == [(0, 1)]
    assert len(by_kind[Kind.FOLD]) == 1
    # the method's problems come first, in the order of its checks, and are the deformation's
    method = deform(doc).problems
    assert result.problems[: len(method)] == method
    order = [KINDS.index(p.kind) for p in result.problems]
    assert order == sorted(order), result.warning_kinds
    given = sorted({h for p in by_kind[Kind.GIVE_WAY] for h in p.handles})
    assert result.gave_way == tuple(given)
    if anchor is not None:
        assert result.gave_way, "the two crossing lines give way where the blend folded between them"


def test_constraints_on_the_same_point_are_one_problem_naming_the_lines_not_their_pieces():
    # two lines whose outputs meet end to end, each with its own map: their shared end is one mesh vertex
    a = LineHandle((0.0, 0.0), (20.0, 0.0), rectify=False, targets=((0.0, 0.0), (10.0, 5.0), (20.0, 0.0)))
    b = LineHandle((22.0, 1.0), (40.0, 0.0), rectify=False, targets=((20.0, 0.0), (30.0, 5.0), (40.0, 0.0)))
    (same,) = deform(Handles((a, b))).problems
    assert same.kind == Kind.SAME_POINT and same.handles == (0, 1) == _named(same.message)
    assert same.message.startswith("constraints of handles[0] (line), handles[1] (line) fall on the same point (mesh vertex ")
    # a line cut in pieces is named once, by its handle, whichever of its pieces share the point
    from omniwidget.method.background import BACKGROUND
    from omniwidget.method.constraints import Control
    from omniwidget.method.deformation import _merge_duplicates
    from omniwidget.sphere.moebius import Moebius

    one = Moebius.identity()
    controls = (
        Control(one, 0, "handles[0] (line, part 1 of 2)"),
        Control(one, 0, "handles[0] (line, part 2 of 2)"),
        Control(one, 1, "handles[1] (line)"),
        Control(one, BACKGROUND, "the still background"),
    )
    b_index = np.array([7, 7, 7, 9, 9, 3])
    values = np.array([[1.0, 0, 0, 0], [0, 1.0, 0, 0], [0, 0, 1.0, 0], [1.0, 0, 0, 0], [0, 0, 0, 1.0], [0, 0, 1.0, 0]])
    unique, merged, found = _merge_duplicates(b_index, values, controls, Handles((a, b)))
    assert unique.tolist() == [3, 7, 9] and np.allclose(merged[1], [1 / 3, 1 / 3, 1 / 3, 0]) and np.allclose(merged[2], [0.5, 0, 0, 0.5])
    assert [(p.kind, p.handles, p.message) for p in found] == [
        (
            Kind.SAME_POINT,
            (0, 1),
            "constraints of handles[0] (line), handles[1] (line) fall on the same point (mesh vertex 7); their weights were averaged",
        ),
        (
            Kind.SAME_POINT,
            (0,),
            "constraints of handles[0] (line), the still background fall on the same point (mesh vertex 9); their weights were averaged",
        ),
    ]


def test_problems_are_immutable_and_compare_by_value():
    a = Problem(Kind.POLE_LINE, (1,), "handles[1] (line) passes 1.5° from the north pole")
    assert a == Problem(Kind.POLE_LINE, (1,), "handles[1] (line) passes 1.5° from the north pole")
    with pytest.raises(AttributeError):
        a.kind = Kind.FOLD  # type: ignore[misc]
    assert np.array_equal(np.array(a.handles), [1])
