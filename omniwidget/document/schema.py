"""The JSON Schema (draft 2020-12) of the handles file, for editors and other programs.

:func:`handles_schema` describes what :meth:`Handles.from_dict <omniwidget.document.handles.Handles.from_dict>`
accepts, field by field: the types, the required keys, the ranges, the enumerations, and no
key the library does not know (it refuses unknown keys, so every object here has
``additionalProperties: false``). ``null`` is allowed exactly where the library reads it as
"not given" (a handle's optional fields) or as a value (``options.anchor``: no still
background). ``omniwidget schema`` prints it.

A schema cannot say everything the library checks, so a document valid under the schema may
still be refused; every document the schema refuses, the library refuses too. What only the
library checks:

- a line's start and end must be distinct and not antipodal;
- the positions of a cage's ``vertices``, of its ``targets`` and of a line's ``targets``
  must be pairwise distinct (``MIN_SEPARATION`` apart on the sphere);
- a cage's ``targets`` must be as many as its ``vertices``;
- the handles' ``id`` strings must be unique;
- no object may give a key twice, and the JSON may nest at most ``MAX_DEPTH`` (32) arrays and
  objects deep (checked on the text, before parsing);
- a document holds at most ``MAX_HANDLES`` (1000) handles, a cage's vertices counted each
  (``OMNIWIDGET_MAX_HANDLES`` raises it, so the schema gives no ``maxItems``).
"""

from __future__ import annotations

from typing import Any

from .handles import ANCHOR_RANGE, DEFAULT_ANCHOR, FORMAT, REACH_RANGE, ROTATION_RANGE, SCALE_RANGE, UP_LATITUDE_RANGE, VERSION

__all__ = ["DRAFT", "handles_schema"]

#: The JSON Schema dialect :func:`handles_schema` is written in.
DRAFT = "https://json-schema.org/draft/2020-12/schema"


def _range(lo: float, hi: float, *, nullable: bool, description: str, default: float | None = None) -> dict[str, Any]:
    """A finite number in ``[lo, hi]`` (``minimum``/``maximum`` apply to numbers only, so null passes them)."""
    out: dict[str, Any] = {"type": ["number", "null"] if nullable else "number", "minimum": lo, "maximum": hi, "description": description}
    if default is not None:
        out["default"] = default
    return out


def handles_schema() -> dict[str, Any]:
    """The JSON Schema of a handles document (the handles file), draft 2020-12.

    Returns
    -------
    dict
        A new JSON-ready dict each call: ``json.dumps(handles_schema(), indent=2)`` is what
        ``omniwidget schema`` prints. Its ``$defs`` are ``lonlat`` (a ``[lon, lat]`` pair),
        ``point``, ``line``, ``cage`` (the handle kinds), ``handle`` (any of them, chosen by
        ``kind``) and ``options``.

    Notes
    -----
    The schema refuses nothing that :meth:`Handles.from_dict
    <omniwidget.document.handles.Handles.from_dict>` accepts. It is looser than the library
    only where JSON Schema cannot follow it: the geometric checks (a line of zero length or
    between antipodes, coinciding positions), a cage's ``targets`` counted against its
    ``vertices``, and unique handle ids (see the module's docstring).

    The ranges are the library's own constants: longitude in [-180, 180] and latitude in
    [-90, 90] degrees (neither is wrapped: a value outside is refused), a point's
    ``rotation`` in ``ROTATION_RANGE`` degrees and ``scale`` in ``SCALE_RANGE``, ``reach`` in ``REACH_RANGE``,
    ``options.anchor`` in ``ANCHOR_RANGE`` degrees or null, ``options.up``'s latitude in ``UP_LATITUDE_RANGE``.

    Examples
    --------
    >>> import json
    >>> schema = handles_schema()
    >>> schema["properties"]["version"]
    {'const': 1, 'description': 'The file format version this omniwidget reads.'}
    >>> sorted(schema["$defs"])
    ['cage', 'handle', 'line', 'lonlat', 'options', 'point']
    """
    lonlat = {
        "type": "array",
        "description": "A position on the sphere, [lon, lat] in degrees: longitude east of the image centre, latitude north.",
        "prefixItems": [
            {"type": "number", "minimum": -180.0, "maximum": 180.0, "description": "Longitude, degrees."},
            {"type": "number", "minimum": -90.0, "maximum": 90.0, "description": "Latitude, degrees."},
        ],
        "minItems": 2,
        "maxItems": 2,
    }
    ref = {"$ref": "#/$defs/lonlat"}
    handle_id = {
        "type": ["string", "null"],
        "minLength": 1,
        "description": "A name for the handle, unique in the document (uniqueness is checked by the library, not the schema).",
    }
    point = {
        "type": "object",
        "description": "A point handle (Sec. 3.3): translates, turns and zooms the sphere near its position.",
        "properties": {
            "kind": {"const": "point"},
            "position": {**ref, "description": "The centre in the input image."},
            "target": {
                "anyOf": [ref, {"type": "null"}],
                "description": "Where the centre goes in the output; null or left out: its position.",
            },
            "rotation": _range(
                *ROTATION_RANGE, nullable=True, default=0.0, description="Degrees, counter-clockwise as seen in the image; null: 0."
            ),
            "scale": _range(*SCALE_RANGE, nullable=True, default=1.0, description="Magnification at the target, > 1 zooms in; null: 1."),
            "reach": _range(
                *REACH_RANGE,
                nullable=True,
                description=(
                    "Degrees: with the still background the turn and zoom hold within a third of it and are gone beyond it; "
                    "null or left out: half the way to the nearest other handle, at most 15."
                ),
            ),
            "id": handle_id,
        },
        "required": ["kind", "position"],
        "additionalProperties": False,
    }
    line = {
        "type": "object",
        "description": (
            "A line handle, the paper's spherical bone (eq. 3): the geodesic from start to end, which must be distinct and not "
            "antipodal (checked by the library). With rectify its midpoint goes by eq. (4) and the line comes out straight; "
            "explicit targets say instead where start, midpoint and end go."
        ),
        "properties": {
            "kind": {"const": "line"},
            "start": ref,
            "end": ref,
            "rectify": {
                "type": ["boolean", "null"],
                "description": "Straighten the line (eq. 4); null or left out: true without targets, false with them.",
            },
            "targets": {
                "type": ["array", "null"],
                "items": ref,
                "minItems": 3,
                "maxItems": 3,
                "description": "Output positions of start, midpoint and end, pairwise distinct; null or left out: none.",
            },
            "id": handle_id,
        },
        "required": ["kind", "start", "end"],
        "additionalProperties": False,
        # explicit targets and rectify: true are exclusive
        "if": {"properties": {"targets": {"type": "array"}}, "required": ["targets"]},
        "then": {"properties": {"rectify": {"enum": [False, None]}}},
    }
    cage = {
        "type": "object",
        "description": "A spherical cage (Sec. 3.3): a closed polygon of geodesic edges whose vertices act as point handles.",
        "properties": {
            "kind": {"const": "cage"},
            "vertices": {
                "type": "array",
                "items": ref,
                "minItems": 3,
                "description": "The polygon's corners in the input, pairwise distinct.",
            },
            "targets": {
                "type": ["array", "null"],
                "items": ref,
                "minItems": 3,
                "description": "Where each vertex goes, as many as the vertices, pairwise distinct; null or left out: the cage stays.",
            },
            "id": handle_id,
        },
        "required": ["kind", "vertices"],
        "additionalProperties": False,
    }
    handle = {
        "type": "object",
        "description": "A handle: its kind says which fields it has.",
        "properties": {"kind": {"enum": ["point", "line", "cage"]}},
        "required": ["kind"],
        "allOf": [
            {"if": {"properties": {"kind": {"const": kind}}, "required": ["kind"]}, "then": {"$ref": f"#/$defs/{kind}"}}
            for kind in ("point", "line", "cage")
        ],
    }
    options = {
        "type": "object",
        "description": "Document-wide options.",
        "properties": {
            "rectify": {
                "enum": ["all", "each"],
                "default": "all",
                "description": "all: the lines' targets from the joint solve of Sec. 3.4; each: eq. (4) line by line.",
            },
            "anchor": _range(
                *ANCHOR_RANGE,
                nullable=True,
                default=DEFAULT_ANCHOR,
                description="The still background: the sphere farther than this many degrees from every handle keeps its place; "
                "null: no background map (the paper's method).",
            ),
            "up": {
                "type": ["array", "null"],
                "description": "Where the input sees the true vertical, [lon, lat] degrees (omniwidget level): the method works on "
                "the input turned so that it is at the zenith (the yaw kept); null or left out: the input as it is.",
                "prefixItems": [
                    {"type": "number", "minimum": -180.0, "maximum": 180.0, "description": "Longitude, degrees."},
                    {"type": "number", "minimum": UP_LATITUDE_RANGE[0], "maximum": UP_LATITUDE_RANGE[1], "description": "Latitude, degrees."},
                ],
                "minItems": 2,
                "maxItems": 2,
            },
        },
        "additionalProperties": False,
    }
    return {
        "$schema": DRAFT,
        "title": "omniwidget handles document",
        "description": (
            "The handles file of omniwidget: points, lines and cages on an equirectangular panorama, each defining a Möbius "
            "transformation. Positions are [lon, lat] in degrees. Only the library checks the geometry (distinct and "
            "non-antipodal line ends, distinct positions), that a cage has as many targets as vertices, and unique ids."
        ),
        "type": "object",
        "properties": {
            "format": {"const": FORMAT, "description": "Names the file's kind; may be left out."},
            "version": {"const": VERSION, "description": "The file format version this omniwidget reads."},
            "handles": {"type": "array", "items": {"$ref": "#/$defs/handle"}, "description": "The handles in order; may be empty."},
            "options": {"$ref": "#/$defs/options"},
        },
        "required": ["handles"],
        "additionalProperties": False,
        "$defs": {"lonlat": lonlat, "point": point, "line": line, "cage": cage, "handle": handle, "options": options},
    }
