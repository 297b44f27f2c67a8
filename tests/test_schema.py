"""The JSON Schema of the handles file (omniwidget/document/schema.py) says what the library accepts.

The check, on hand-picked and fuzzed documents: every document :meth:`Handles.from_dict`
accepts is valid under the schema, and every document the schema refuses the library
refuses with a :class:`HandlesError`. Beyond that the two agree exactly on JSON documents,
except where a schema cannot follow the library (the ``GAPS`` below: geometry, a cage's
targets counted against its vertices, unique ids), where the schema accepts what the
library refuses.

The fuzzing reuses the document strategies of tests/test_handles.py, tests/test_robustness.py
and tests/test_cli.py and adds its own: valid documents with up to two things made wrong,
often just across a range's edge. ``OMNIWIDGET_FUZZ=N`` runs N times as many.
"""

from __future__ import annotations

import copy
import json
import math
import os
import re
import subprocess
import sys

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from omniwidget.app.cli import main
from omniwidget.document import handles as handles_module
from omniwidget.document.handles import Handles
from omniwidget.document.schema import DRAFT, handles_schema
from omniwidget.errors import HandlesError
from tests import requires

jsonschema = requires.module("jsonschema")

SCHEMA = handles_schema()
VALIDATOR = jsonschema.Draft202012Validator(SCHEMA)
FUZZ = int(os.environ.get("OMNIWIDGET_FUZZ", "1"))
_FUZZ = settings(deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.filter_too_much])

#: The library's refusals no JSON Schema can say (by the problem's text): the schema accepts these documents.
GAPS = ("coincide", "zero length", "antipodal", "is already the id of")


def _is_json(data) -> bool:
    """Whether ``data`` is a JSON document (NaN and Infinity are not JSON: a JSON parser refuses them before any schema)."""
    try:
        json.dumps(data, allow_nan=False)
    except ValueError:
        return False
    return True


def _gap(exc: HandlesError, data) -> bool:
    """Whether the library's refusal is one the schema cannot make."""
    if any(text in exc.problem for text in GAPS):
        return True
    counted = re.fullmatch(r"handles\[(\d+)\]\.targets", exc.where)
    if counted and re.fullmatch(r"expected \d+ positions, got \d+", exc.problem):
        h = data["handles"][int(counted[1])]
        return h["kind"] == "cage" and len(h["targets"]) >= 3  # fewer than three: the schema's minItems refuses it
    return False


def _library_accepts(data) -> bool:
    try:
        Handles.from_dict(data)
    except HandlesError:
        return False
    return True


def check_agreement(data) -> tuple[bool, bool]:
    """Assert the schema and the library agree on ``data``; ``(library accepts, schema accepts)``."""
    schema_ok = VALIDATOR.is_valid(data)
    try:
        Handles.from_dict(data)  # anything but a HandlesError fails the test here
    except HandlesError as exc:
        if _is_json(data) and not _gap(exc, data):
            assert not schema_ok, f"the library refuses ({exc}) what the schema accepts: {json.dumps(data)}"
        return False, schema_ok
    if not schema_ok:
        error = jsonschema.exceptions.best_match(VALIDATOR.iter_errors(data))
        raise AssertionError(f"the schema refuses ({error.json_path}: {error.message}) what the library accepts: {data!r}")
    return True, schema_ok


# --- the schema itself -------------------------------------------------------------------


def test_the_schema_is_a_valid_draft_2020_12_schema():
    jsonschema.Draft202012Validator.check_schema(SCHEMA)
    assert SCHEMA["$schema"] == DRAFT == "https://json-schema.org/draft/2020-12/schema"
    assert jsonschema.validators.validator_for(SCHEMA) is jsonschema.Draft202012Validator
    assert json.loads(json.dumps(SCHEMA, allow_nan=False)) == SCHEMA  # plain JSON: no tuples, no NaN
    assert handles_schema() == SCHEMA and handles_schema() is not SCHEMA  # a new dict each call, the same content
    for name, definition in SCHEMA["$defs"].items():
        assert definition.get("description"), name


def test_the_schema_names_the_fields_and_ranges_of_the_library():
    defs = SCHEMA["$defs"]
    for kind, (required, optional) in handles_module._HANDLE_FIELDS.items():
        assert set(defs[kind]["properties"]) == required | optional, kind
        assert set(defs[kind]["required"]) == required, kind
        assert defs[kind]["additionalProperties"] is False and defs[kind]["properties"]["kind"] == {"const": kind}
    assert defs["handle"]["properties"]["kind"]["enum"] == list(handles_module._HANDLE_FIELDS)
    point = defs["point"]["properties"]
    assert (point["rotation"]["minimum"], point["rotation"]["maximum"]) == handles_module.ROTATION_RANGE
    assert (point["scale"]["minimum"], point["scale"]["maximum"]) == handles_module.SCALE_RANGE
    anchor = defs["options"]["properties"]["anchor"]
    assert (anchor["minimum"], anchor["maximum"]) == handles_module.ANCHOR_RANGE and anchor["default"] == handles_module.DEFAULT_ANCHOR
    assert SCHEMA["properties"]["format"]["const"] == handles_module.FORMAT and SCHEMA["properties"]["version"]["const"] == 1
    assert [(p["minimum"], p["maximum"]) for p in defs["lonlat"]["prefixItems"]] == [(-180.0, 180.0), (-90.0, 90.0)]


def test_the_command_prints_the_schema(capsys):
    assert main(["schema"]) == 0
    out, err = capsys.readouterr()
    assert json.loads(out) == SCHEMA and err == ""
    assert out == json.dumps(SCHEMA, indent=2) + "\n"


def test_python_m_omniwidget_schema_prints_it():
    proc = subprocess.run([sys.executable, "-m", "omniwidget", "schema"], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout) == SCHEMA and proc.stderr == ""


def test_the_files_the_library_writes_are_valid(tmp_path):
    from omniwidget.app.cli import DEMO_HANDLES

    doc = Handles.from_dict(DEMO_HANDLES)
    VALIDATOR.validate(DEMO_HANDLES)
    VALIDATOR.validate(doc.to_dict())  # to_dict writes every field, defaults included
    handles_module.save_handles(doc, tmp_path / "h.json")
    VALIDATOR.validate(json.loads((tmp_path / "h.json").read_text()))


# --- hand-picked documents: each keyword of the schema, on both sides of its edge -------------

P = {"kind": "point", "position": [10.0, 20.0]}
L = {"kind": "line", "start": [0.0, 0.0], "end": [30.0, 10.0]}
C = {"kind": "cage", "vertices": [[0.0, 0.0], [10.0, 0.0], [5.0, 8.0]]}
T3 = [[0.0, 0.0], [15.0, 12.0], [30.0, 10.0]]
UP = math.nextafter(1.0, 2.0) - 1.0  # relative step just past an edge


def _doc(*handles, **top):
    return {"handles": [copy.deepcopy(h) for h in handles], **top}


def _with(h, **fields):
    return {**copy.deepcopy(h), **fields}


ACCEPTED = {
    "empty": _doc(),
    "everything": _doc(P, L, C, format="omniwidget.handles", version=1, options={"rectify": "each", "anchor": None}),
    "version 1.0": _doc(version=1.0),
    "options empty": _doc(options={}),
    "anchor at its edges": _doc(options={"anchor": 1}),
    "anchor 180": _doc(options={"anchor": 180.0}),
    "the poles and the seam": _doc(_with(P, position=[-180, 90], target=[180.0, -90.0])),
    "point nulls": _doc(_with(P, target=None, rotation=None, scale=None, id=None)),
    "rotation edges": _doc(_with(P, rotation=-360), _with(P, rotation=360.0, position=[0, 0])),
    "scale edges": _doc(_with(P, scale=1e-3), _with(P, scale=1e3, position=[0, 0])),
    "integers": _doc(_with(P, position=[10, 20], rotation=5, scale=2)),
    "line with targets": _doc(_with(L, targets=T3)),
    "line with targets, rectify false": _doc(_with(L, targets=T3, rectify=False)),
    "line with targets, rectify null": _doc(_with(L, targets=T3, rectify=None)),
    "line rectify true, targets null": _doc(_with(L, rectify=True, targets=None)),
    "line not rectified": _doc(_with(L, rectify=False)),
    "cage with targets": _doc(_with(C, targets=[[1.0, 0.0], [11.0, 0.0], [6.0, 8.0]])),
    "cage targets null": _doc(_with(C, targets=None)),
    "ids": _doc(_with(P, id="a"), _with(L, id=" ")),
}
REFUSED = {
    "not an object": [P],
    "a string": "handles",
    "no handles": {"options": {}},
    "handles null": _doc() | {"handles": None},
    "handles an object": {"handles": {"0": P}},
    "unknown top-level key": _doc(colour="red"),
    "format wrong": _doc(format="omniwidget.handle"),
    "format null": _doc(format=None),
    "version 2": _doc(version=2),
    "version true": _doc(version=True),
    "version '1'": _doc(version="1"),
    "version null": _doc(version=None),
    "options null": _doc(options=None),
    "options a list": _doc(options=[]),
    "unknown option": _doc(options={"speed": 1}),
    "rectify null": _doc(options={"rectify": None}),
    "rectify other": _doc(options={"rectify": "some"}),
    "anchor below": _doc(options={"anchor": 1.0 - UP}),
    "anchor above": _doc(options={"anchor": 180.0 * (1 + UP)}),
    "anchor true": _doc(options={"anchor": True}),
    "anchor a string": _doc(options={"anchor": "5"}),
    "handle not an object": _doc() | {"handles": [5]},
    "handle null": _doc() | {"handles": [None]},
    "kind missing": _doc({"position": [0, 0]}),
    "kind unknown": _doc(_with(P, kind="blob")),
    "kind capitalised": _doc(_with(P, kind="Point")),
    "kind a number": _doc(_with(P, kind=3)),
    "unknown handle key": _doc(_with(P, colour=1)),
    "another kind's key": _doc(_with(P, targets=None)),
    "position missing": _doc({"kind": "point"}),
    "position null": _doc(_with(P, position=None)),
    "position short": _doc(_with(P, position=[1.0])),
    "position long": _doc(_with(P, position=[1.0, 2.0, 3.0])),
    "position an object": _doc(_with(P, position={"lon": 0, "lat": 0})),
    "longitude past 180": _doc(_with(P, position=[math.nextafter(180.0, 200.0), 0.0])),
    "longitude past -180": _doc(_with(P, position=[-181, 0])),
    "latitude past 90": _doc(_with(P, position=[0.0, math.nextafter(90.0, 100.0)])),
    "latitude a string": _doc(_with(P, position=[0.0, "1"])),
    "latitude true": _doc(_with(P, position=[0.0, True])),
    "target short": _doc(_with(P, target=[])),
    "rotation past 360": _doc(_with(P, rotation=360.0 * (1 + UP))),
    "rotation a string": _doc(_with(P, rotation="0")),
    "scale below": _doc(_with(P, scale=1e-3 * (1 - UP))),
    "scale above": _doc(_with(P, scale=1001)),
    "scale zero": _doc(_with(P, scale=0)),
    "scale true": _doc(_with(P, scale=True)),
    "id empty": _doc(_with(P, id="")),
    "id a number": _doc(_with(P, id=5)),
    "line end missing": _doc({"kind": "line", "start": [0, 0]}),
    "line rectify a number": _doc(_with(L, rectify=1)),
    "line rectify a string": _doc(_with(L, rectify="yes")),
    "line targets and rectify true": _doc(_with(L, targets=T3, rectify=True)),
    "line two targets": _doc(_with(L, targets=T3[:2], rectify=False)),
    "line four targets": _doc(_with(L, targets=[*T3, [1, 1]], rectify=False)),
    "line targets a string": _doc(_with(L, targets="none")),
    "cage two vertices": _doc(_with(C, vertices=[[0, 0], [1, 1]])),
    "cage vertices null": _doc(_with(C, vertices=None)),
    "cage vertex out of range": _doc(_with(C, vertices=[[0, 0], [1, 1], [2, 200]])),
    "cage vertex null": _doc(_with(C, vertices=[[0, 0], [1, 1], None])),
    "cage two targets": _doc(_with(C, targets=[[0, 0], [1, 1]])),
    "cage targets a number": _doc(_with(C, targets=3)),
}
#: Refused by the library, accepted by the schema: what a JSON Schema cannot say (see the module's docstring).
GAP_CASES = {
    "line of zero length": _doc(_with(L, end=[0.0, 0.0])),
    "line between antipodes": _doc(_with(L, end=[180.0, 0.0])),
    "line ends across the seam coincide": _doc(_with(L, start=[-180.0, 10.0], end=[180.0, 10.0])),
    "line targets coincide": _doc(_with(L, targets=[[0, 0], [0, 0], [30, 10]])),
    "cage vertices coincide": _doc(_with(C, vertices=[[0, 0], [10, 0], [0, 0]])),
    "cage targets coincide": _doc(_with(C, targets=[[0, 0], [0, 0], [5, 8]])),
    "cage with more targets than vertices": _doc(_with(C, targets=[[0, 0], [10, 0], [5, 8], [5, 9]])),
    "duplicate ids": _doc(_with(P, id="a"), _with(L, id="a")),
}


@pytest.mark.parametrize("name", list(ACCEPTED))
def test_hand_picked_documents_both_accept(name):
    assert check_agreement(ACCEPTED[name]) == (True, True)


@pytest.mark.parametrize("name", list(REFUSED))
def test_hand_picked_documents_both_refuse(name):
    assert check_agreement(REFUSED[name]) == (False, False)


@pytest.mark.parametrize("name", list(GAP_CASES))
def test_what_only_the_library_refuses(name):
    data = GAP_CASES[name]
    assert VALIDATOR.is_valid(data)
    with pytest.raises(HandlesError) as info:
        Handles.from_dict(data)
    assert _gap(info.value, data), str(info.value)


def test_nan_and_infinity_are_not_json_and_the_library_refuses_them():
    """Python writes NaN and Infinity (``json.dumps`` by default) and the library reads them, to refuse them by field."""
    for value in (math.nan, math.inf, -math.inf):
        data = _doc(_with(P, rotation=value))
        assert not _is_json(data) and not _library_accepts(data)
        with pytest.raises(HandlesError, match="finite number"):
            Handles.from_json(json.dumps(data))
    assert not VALIDATOR.is_valid(_doc(_with(P, rotation=math.inf)))  # past the maximum; a NaN compares with nothing


def test_an_integer_too_large_for_a_float_is_refused_by_name():
    data = _doc(_with(P, rotation=10**400))
    assert not VALIDATOR.is_valid(data)
    with pytest.raises(HandlesError, match=r"handles\[0\].*rotation.*an integer of 1329 bits is out of range"):
        Handles.from_json(json.dumps(data))


# --- fuzzing -------------------------------------------------------------------------------
from tests.test_cli import json_values  # noqa: E402  (JSON of any shape, keys of a handles document)
from tests.test_handles import documents as loose_documents  # noqa: E402  (every field of any type)
from tests.test_robustness import broken_documents, valid_documents  # noqa: E402  (sound geometry; one thing wrong)
from tests.test_robustness import handles_ as sound_handles  # noqa: E402

#: Each range's edges, a step either side, and a value a little past each: where a schema's bound is most easily off.
EDGES = sorted(
    {
        x
        for edge in (-360.0, -180.0, -90.0, 0.0, 1e-3, 1.0, 5.0, 90.0, 180.0, 360.0, 1e3)
        for x in (edge, math.nextafter(edge, -math.inf), math.nextafter(edge, math.inf), edge - 0.5 * max(abs(edge), 1e-3), edge + 0.5)
    }
    | {0, 1, -180, 180, 1000, 1e308, -1e308}
)
numbers = st.one_of(
    st.sampled_from(EDGES),
    st.sampled_from(EDGES),  # half the draws
    st.floats(-400, 400),
    st.integers(-1000, 1000),
    st.floats(allow_nan=False, allow_infinity=False),
)
anything = st.one_of(
    numbers,
    st.none(),
    st.booleans(),
    st.sampled_from(["", "a", "all", "each", "point", "line", "cage", "omniwidget.handles", "1"]),
    st.lists(numbers, max_size=4),
    st.lists(st.lists(numbers, min_size=2, max_size=2), max_size=5),
    st.dictionaries(st.sampled_from(["lon", "lat", "kind", "x"]), numbers, max_size=2),
)
lons = st.one_of(st.floats(-180.0, 180.0), st.sampled_from([-180.0, 180.0, -180, 180, 0]))
lats = st.one_of(st.floats(-90.0, 90.0), st.sampled_from([-90.0, 90.0, -90, 90, 0]))
lonlats = st.tuples(lons, lats).map(list)


@st.composite
def handles(draw) -> dict:
    """A sound handle of tests/test_robustness.py, some optional fields it left out given as null, perhaps an id."""
    h = draw(sound_handles)
    for key in sorted(handles_module._HANDLE_FIELDS[h["kind"]][1] - set(h)):
        if draw(st.integers(0, 2)) == 0:
            h[key] = None  # null: not given
    if h["kind"] == "line" and h.get("targets") is not None:
        h["rectify"] = draw(st.sampled_from([False, None, "absent", True]))  # true with targets: refused
        if h["rectify"] == "absent":
            del h["rectify"]
    if draw(st.booleans()):
        h["id"] = draw(st.text(min_size=1, max_size=8))
    return h


RANGES = {
    "lon": (-180.0, 180.0),
    "lat": (-90.0, 90.0),
    "rotation": handles_module.ROTATION_RANGE,
    "scale": handles_module.SCALE_RANGE,
    "anchor": handles_module.ANCHOR_RANGE,
}


def _near(lo: float, hi: float) -> list[float]:
    """The edges of ``[lo, hi]``, one step outside each, and a little further."""
    return [lo, hi, math.nextafter(lo, -math.inf), math.nextafter(hi, math.inf), lo - 0.5 * max(abs(lo), 1e-3), hi + 0.5]


FIELDS = ["kind", "position", "target", "rotation", "scale", "start", "end", "rectify", "targets", "vertices", "id", "colour"]
POSITIONS = ("position", "target", "start", "end")


@st.composite
def mutated_documents(draw) -> dict:  # noqa: C901, PLR0912 - one branch per way a document can be broken, listed for review
    """A sound document of up to three :func:`handles` with 0 to 2 things changed, each in one of the ways listed here."""
    doc: dict = {"handles": draw(st.lists(handles(), min_size=1, max_size=3) if draw(st.integers(0, 7)) else st.just([]))}
    for key, values in {
        "format": st.just("omniwidget.handles"),
        "version": st.sampled_from([1, 1.0]),
        "options": st.fixed_dictionaries(
            {}, optional={"rectify": st.sampled_from(["all", "each"]), "anchor": st.one_of(st.none(), st.floats(1.0, 180.0), st.just(180))}
        ),
    }.items():
        if draw(st.booleans()):
            doc[key] = draw(values)
    for _ in range(draw(st.integers(0, 9).map(lambda k: (k > 0) + (k > 8)))):  # mostly one
        how = draw(
            st.sampled_from(
                [
                    "field",
                    "number",
                    "coordinate",
                    "edge",
                    "edge",
                    "id",
                    "delete",
                    "top",
                    "top",
                    "option",
                    "option",
                    "handle",
                    "rectify",
                    "count",
                ]
            )
        )
        hs = [h for h in doc["handles"] if isinstance(h, dict)] if isinstance(doc.get("handles"), list) else []
        h = draw(st.sampled_from(hs)) if hs else {}
        if how == "field" and hs:
            h[draw(st.sampled_from(FIELDS))] = draw(anything)
        elif how == "number" and hs:
            h[draw(st.sampled_from(["rotation", "scale"]))] = draw(numbers)
        elif how == "coordinate" and hs:
            pairs = [v for k in POSITIONS if isinstance(h.get(k), list) for v in [h[k]]]
            pairs += [v for k in ("targets", "vertices") if isinstance(h.get(k), list) for v in h[k]]
            pairs = [v for v in pairs if isinstance(v, list) and v]
            if pairs:
                pair = draw(st.sampled_from(pairs))
                pair[draw(st.integers(0, len(pair) - 1))] = draw(numbers)
        elif how == "edge":  # a number at its range's edge, or just past it
            field = draw(st.sampled_from(sorted(RANGES)))
            value = draw(st.sampled_from(_near(*RANGES[field])))
            if field == "anchor":
                doc["options"] = {**doc["options"], "anchor": value} if isinstance(doc.get("options"), dict) else {"anchor": value}
            elif field in ("rotation", "scale") and hs:
                h.update(kind="point", position=h.get("position", [0.0, 0.0]), **{field: value})
            elif hs:
                pairs = [h[k] for k in POSITIONS if isinstance(h.get(k), list) and len(h[k]) == 2]
                if pairs:
                    draw(st.sampled_from(pairs))[field == "lat"] = value
        elif how == "id" and hs:
            h["id"] = draw(st.sampled_from(["", None, "an id", 0]))
        elif how == "delete" and hs:
            del h[draw(st.sampled_from(sorted(h)))]
        elif how == "top":
            key = draw(st.sampled_from(["format", "version", "handles", "options", "extra"]))
            if draw(st.booleans()):
                doc[key] = draw(anything)
            else:
                doc.pop(key, None)
        elif how == "option":
            options = doc.setdefault("options", {})
            if isinstance(options, dict):
                options[draw(st.sampled_from(["rectify", "anchor", "speed"]))] = draw(st.one_of(numbers, anything))
        elif how == "handle" and isinstance(doc.get("handles"), list) and doc["handles"]:
            doc["handles"][draw(st.integers(0, len(doc["handles"]) - 1))] = draw(anything)
        elif how == "rectify" and hs:  # a line's explicit targets against its rectify
            h.update(kind="line", start=[0.0, 0.0], end=[40.0, 10.0], targets=[[0.0, 0.0], [20.0, 9.0], [40.0, 10.0]])
            for key in ("position", "target", "rotation", "scale", "vertices"):
                h.pop(key, None)
            h["rectify"] = draw(st.sampled_from([True, False, None, "true", 0]))
        elif how == "count" and hs:  # a list of positions one or two too long or too short
            key = draw(st.sampled_from([k for k in ("targets", "vertices") if isinstance(h.get(k), list)] or ["targets"]))
            items = h.get(key) if isinstance(h.get(key), list) else []
            size = max(0, len(items) + draw(st.sampled_from([-2, -1, 1, 2])))
            h[key] = (items + draw(st.lists(lonlats, min_size=size, max_size=size)))[:size]
    return doc


def _check_fuzzed(data):
    check_agreement(data)
    check_agreement(json.loads(json.dumps(data, allow_nan=True)))  # as a file gives it (tuples become lists)


@settings(_FUZZ, max_examples=200 * FUZZ)
@given(mutated_documents())
def test_fuzzed_documents_the_library_accepts_are_valid_and_the_rest_refused_alike(data):
    _check_fuzzed(data)


@settings(_FUZZ, max_examples=100 * FUZZ)
@given(st.one_of(loose_documents, valid_documents, st.builds(lambda case: case[0], broken_documents())))
def test_the_other_fuzzers_documents_agree_too(data):
    _check_fuzzed(data)


@pytest.mark.slow  # a longer hunt: the fast loop runs the same checks on fewer documents
@settings(_FUZZ, max_examples=1000 * FUZZ)
@given(st.one_of(mutated_documents(), loose_documents, valid_documents, st.builds(lambda case: case[0], broken_documents()), json_values))
def test_many_fuzzed_documents_agree(data):
    _check_fuzzed(data)
