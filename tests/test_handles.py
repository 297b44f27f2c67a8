import copy
import json
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from omniwidget.document.handles import ARROW_LENGTH, CageHandle, Handles, LineHandle, PointHandle, load_handles, save_handles
from omniwidget.errors import HandlesError
from omniwidget.sphere import coords

DOC = {
    "format": "omniwidget.handles",
    "version": 1,
    "handles": [
        {"kind": "point", "position": [10.0, 20.0], "target": [15.0, 18.0], "rotation": 10.0, "scale": 1.5, "id": "p"},
        {"kind": "line", "start": [170.0, 10.0], "end": [-160.0, 30.0], "rectify": True},
        {"kind": "line", "start": [0.0, 0.0], "end": [20.0, 10.0], "targets": [[0, 0], [10, 4], [20, 10]]},
        {"kind": "cage", "vertices": [[0, -10], [20, -10], [10, -30]], "targets": [[0, -10], [22, -10], [10, -30]]},
    ],
    "options": {"rectify": "each"},
}


def test_round_trip_through_json(tmp_path):
    doc = Handles.from_dict(DOC)
    assert Handles.from_json(doc.to_json()).to_dict() == doc.to_dict()
    save_handles(doc, tmp_path / "h.json")
    assert load_handles(tmp_path / "h.json") == doc
    assert list(tmp_path.iterdir()) == [tmp_path / "h.json"]  # no temporary file left behind


def test_defaults():
    doc = Handles.from_dict(
        {
            "handles": [
                {"kind": "point", "position": [1, 2]},
                {"kind": "line", "start": [0, 0], "end": [10, 0]},
                {"kind": "cage", "vertices": [[0, 0], [1, 0], [0, 1]]},
            ]
        }
    )
    point, line, cage = doc.handles
    assert point.final == (1.0, 2.0) and point.scale == 1.0 and point.rotation == 0.0
    assert line.rectify and line.targets is None
    assert cage.finals == cage.vertices
    assert doc.options.rectify == "all"
    assert all(m.is_identity(1e-12) for m in (point.moebius(), *cage.vertex_maps()))
    with_targets = Handles.from_dict({"handles": [{"kind": "line", "start": [0, 0], "end": [10, 0], "targets": [[0, 0], [5, 1], [10, 0]]}]})
    assert with_targets.handles[0].rectify is False  # explicit targets say where the points go


def _broken(path, value):
    doc = copy.deepcopy(DOC)
    node = doc
    for key in path[:-1]:
        node = node[key]
    if value is KeyError:
        del node[path[-1]]
    else:
        node[path[-1]] = value
    return doc


BAD = [
    (("handles", 0, "colour"), "red", "handles[0].colour: unknown field"),
    (("handles", 0, "position"), [10.0], "handles[0].position: expected [lon, lat]"),
    (("handles", 0, "position"), KeyError, "handles[0].position: missing"),
    (("handles", 0, "target"), [200.0, 0.0], "handles[0].target[0] (longitude): 200 is out of range"),
    (("handles", 0, "target"), [0.0, -91.0], "handles[0].target[1] (latitude): -91 is out of range"),
    (("handles", 0, "scale"), 0.0, "handles[0].scale: 0 is out of range"),
    (("handles", 0, "scale"), "2", "handles[0].scale: expected a number"),
    (("handles", 0, "rotation"), True, "handles[0].rotation: expected a number"),
    (("handles", 0, "id"), 7, "handles[0].id: expected a non-empty string"),
    (("handles", 1, "kind"), "spline", "handles[1].kind: expected 'point', 'line' or 'cage'"),
    (("handles", 1, "end"), [170.0, 10.0], "handles[1].end: the line has zero length"),
    (("handles", 1, "end"), [-10.0, -10.0], "handles[1].end: start and end are antipodal"),
    (("handles", 1, "rectify"), "yes", "handles[1].rectify: expected true or false"),
    (("handles", 2, "targets"), [[0, 0], [0, 0], [20, 10]], "handles[2].targets: positions 0 and 1 coincide"),
    (("handles", 2, "targets"), [[0, 0], [20, 10]], "handles[2].targets: expected 3 positions"),
    (("handles", 2, "rectify"), True, "handles[2].targets: give either explicit targets or rectify: true"),
    (("handles", 3, "vertices"), [[0, 0], [1, 1]], "handles[3].vertices: expected at least 3 positions"),
    (("handles", 3, "vertices"), [[0, 0], [1, 1], [0, 0]], "handles[3].vertices: positions 0 and 2 coincide"),
    (("handles", 3, "targets"), [[0, 0], [1, 1]], "handles[3].targets: expected 3 positions"),
    (("handles", 3), "cage", "handles[3]: expected an object"),
    (("options", "rectify"), "some", "options.rectify: expected 'all' or 'each'"),
    (("options", "anchor"), "far", "options.anchor: expected a number"),
    (("options", "anchor"), 0.5, "options.anchor: 0.5 is out of range [1, 180]"),
    (("options", "blur"), 3, "options.blur: unknown option (allowed: rectify, anchor, up)"),
    (("format",), "other", "format: expected 'omniwidget.handles'"),
    (("version",), 2, "version: this omniwidget reads version 1"),
    (("handles",), {}, "handles: expected a list"),
    (("extra",), 1, "extra: unknown top-level field"),
]


@pytest.mark.parametrize(("path", "value", "message"), BAD, ids=[m.split(":")[0] + "-" + str(i) for i, (_, _, m) in enumerate(BAD)])
def test_each_bad_field_is_refused_by_name(path, value, message):
    with pytest.raises(HandlesError) as info:
        Handles.from_dict(_broken(path, value))
    assert str(info.value).startswith(message)


def test_duplicate_ids_and_non_json_are_refused(tmp_path):
    doc = copy.deepcopy(DOC)
    doc["handles"][1]["id"] = "p"
    with pytest.raises(HandlesError, match=r"handles\[1\].id: 'p' is already the id of handles\[0\]"):
        Handles.from_dict(doc)
    # NaN and Infinity are not JSON, but Python writes them: refused by the field that holds them
    with pytest.raises(HandlesError, match=r"handles\[0\].position\[0\] \(longitude\): expected a finite number, got nan"):
        Handles.from_json('{"handles": [{"kind": "point", "position": [NaN, 0]}]}')
    with pytest.raises(HandlesError, match=r"handles\[1\].scale: expected a finite number, got -inf"):
        Handles.from_json(
            '{"handles": [{"kind": "line", "start": [0, 0], "end": [9, 0]}, {"kind": "point", "position": [0, 0], "scale": -Infinity}]}'
        )
    with pytest.raises(HandlesError, match="not valid JSON"):
        Handles.from_json("{handles: ")
    bad = tmp_path / "bad.json"
    bad.write_text('{"handles": [{"kind": "point", "position": [1, 2, 3]}]}')
    with pytest.raises(HandlesError, match=r"bad.json: handles\[0\].position"):
        load_handles(bad)
    with pytest.raises(HandlesError, match="cannot read the handles file"):
        load_handles(tmp_path / "missing.json")


def test_handles_built_in_python_are_validated_too():
    with pytest.raises(HandlesError, match=r"handles\[0\].scale"):
        Handles([PointHandle((0.0, 0.0), scale=-1.0)])
    with pytest.raises(HandlesError, match=r"handles\[1\].end: the line has zero length"):
        Handles([PointHandle((0.0, 0.0)), LineHandle((5.0, 5.0), (5.0, 5.0))])


def test_line_control_points_and_eq4_targets_across_the_seam():
    line = LineHandle((170.0, 10.0), (-160.0, 30.0))
    src, dst = line.control_points(), line.target_points()
    np.testing.assert_allclose(src[1], coords.geodesic_midpoint(line.start, line.end))
    np.testing.assert_allclose(dst[[0, 2]], src[[0, 2]])
    np.testing.assert_allclose(dst[1], [-175.0, 20.0])  # midpoint of 170 and 200 (= -160), unwrapped
    m = line.moebius()
    np.testing.assert_allclose(coords.angular_distance(m(src), dst), 0, atol=1e-9)
    assert LineHandle((0.0, 0.0), (10.0, 5.0), rectify=False).moebius().is_identity()


def test_point_arrows_come_from_the_exact_map_and_drive_it_back():
    point = PointHandle((30.0, 40.0), (50.0, 10.0), rotation=35.0, scale=2.0)
    centre, east_tip, west_tip = point.control_points()
    assert coords.angular_distance(centre, east_tip) == pytest.approx(math.degrees(ARROW_LENGTH))
    _, out_east, out_west = point.target_points()
    dragged = point.with_arrow_tip(out_east)
    assert dragged.scale == pytest.approx(2.0, rel=1e-9) and dragged.rotation == pytest.approx(35.0, abs=1e-9)
    dragged = point.with_arrow_tip(out_west, which="west")
    assert dragged.scale == pytest.approx(2.0, rel=1e-9) and dragged.rotation == pytest.approx(35.0, abs=1e-9)
    # the opposite arrow follows: after a drag both tips are images of the exact map
    turned = point.with_arrow_tip(out_east + np.array([3.0, 4.0]))
    _, e, w = turned.target_points()
    assert coords.angular_distance(e, out_east + np.array([3.0, 4.0])) < 1e-9
    assert turned.moebius().local_scale_rotation(point.position) == pytest.approx((turned.scale, turned.rotation))
    at_pole = PointHandle((0.0, 90.0))
    assert np.all(np.isfinite(at_pole.target_points()))  # arrows stay defined at a pole


def test_identical_maps_and_cage_vertex_maps():
    cage = CageHandle(((0.0, 0.0), (10.0, 0.0), (5.0, 8.0)), ((1.0, 0.0), (10.0, 0.0), (5.0, 8.0)))
    maps = cage.vertex_maps()
    assert len(maps) == 3 and maps[1].is_identity(1e-12) and not maps[0].is_identity()
    assert coords.angular_distance(maps[0](np.array([0.0, 0.0])), [1.0, 0.0]) < 1e-9


# --- fuzzing: any JSON-like document is either a valid document or a HandlesError ----------

numbers = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-1000, 1000), st.booleans(), st.none(), st.text(max_size=3))
lonlats = st.one_of(st.tuples(st.floats(-180, 180), st.floats(-90, 90)).map(list), st.lists(numbers, max_size=3))
handle_values = st.fixed_dictionaries(
    {"kind": st.sampled_from(["point", "line", "cage", "blob", 3])},
    optional={
        "position": lonlats,
        "target": lonlats,
        "start": lonlats,
        "end": lonlats,
        "rotation": numbers,
        "scale": numbers,
        "rectify": st.one_of(st.booleans(), numbers),
        "targets": st.lists(lonlats, max_size=4),
        "vertices": st.lists(lonlats, max_size=5),
        "id": st.one_of(st.text(max_size=3), numbers),
        "extra": numbers,
    },
)
documents = st.fixed_dictionaries(
    {"handles": st.lists(handle_values, max_size=4)},
    optional={
        "format": st.sampled_from(["omniwidget.handles", "x"]),
        "version": st.sampled_from([1, 2, "1"]),
        "options": st.fixed_dictionaries({}, optional={"rectify": st.sampled_from(["all", "each", "none"])}),
    },
)


@pytest.mark.slow  # 600 documents: the full suite; the fast loop runs 100 (below)
@settings(max_examples=600, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(documents)
def test_fuzzed_documents_are_valid_or_refused_by_name(data):
    _check_fuzzed_document(data)


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(documents)
def test_fuzzed_documents_are_valid_or_refused_by_name_fast(data):
    """The fast loop's twin: the same documents strategy and checks, 100 draws."""
    _check_fuzzed_document(data)


def _check_fuzzed_document(data) -> None:
    text = json.dumps(data, allow_nan=True)
    try:
        doc = Handles.from_json(text)
    except HandlesError as exc:
        assert exc.where or "JSON" in exc.problem or "number" in exc.problem
        return
    for m in doc.maps():
        assert np.all(np.isfinite(m.matrix))
    assert Handles.from_json(doc.to_json()).to_dict() == doc.to_dict()
