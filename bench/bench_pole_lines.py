#!/usr/bin/env python
"""Where eq. (4) stops helping a line that climbs towards a pole: the figures that choose ``constraints.POLE_LATITUDE``.

Usage::

    python bench/bench_pole_lines.py [--width 1024] [--lengths 40,75,110] [--step 2.5] [--top-at 0.5]
                                     [--save rows.json | --load rows.json]

The lines
---------
For each highest latitude ``L`` from 60° to 90° (every ``--step``), one line of each length
in ``--lengths`` (degrees of arc), north (``L``) and south (``-L``) in turn, at longitudes
spread round the sphere (a golden-angle step). Each is an arc of a great circle whose
highest point (lowest, in the south) is at ``L``, centred on that point (``--top-at``
moves it along the arc): it climbs to ``L`` in its middle and its ends lie lower, at one
latitude. A ceiling edge that runs close over the camera looks like this. At ``L = 90`` it
runs over the pole (two meridians in the panorama).

Each line is warped at ``--width`` on a synthetic room (``scenes.synthetic_room``),
rectified ``"all"``, (a) alone and (b) among 4 ordinary rectified lines of the room,
40-100° long, within ±59.5° of latitude everywhere and kept 10° clear of the pole line and
of its eq. (4) image (``scenes.mark_lines`` with ``piece=100`` on the room's lines of 40°
or more); each three ways:

- **eq4**: the default options (the still background), the rule off
  (``constraints.POLE_LATITUDE = 91``): the line is rectified (Sec. 3.4, least motion);
- **kept**: the default options, the rule on for this line (``POLE_LATITUDE`` just under
  its ``L``, whatever the module's value): its map is the identity;
- **paper**: ``Options(anchor=None)``, the rule off: the paper's eq. (4) and Sec. 3.4.

The figures
-----------
Per latitude bin, the median and the worst over its lines (both hemispheres, all lengths):

- ``middle °``: how far eq. (4) moves the line's geodesic midpoint, degrees on the sphere
  (its own map, ``LineHandle.moebius()``);
- ``in px`` / ``out px``: the line's largest distance from its best straight fit
  (``quality.straightness(..., fit="best")``) in the input, and in the output (its samples
  found in the output by ``Result.forward_points``, its pieces joined in order);
- ``fold %``, ``distortion p99 / mean``, ``moved °``: the warp's fold-over
  (``Result.folds``), conformal distortion within ±80° (``quality.conformal_distortion``)
  and mean displacement of the sphere (``quality.displacement``): ``Result.quality``'s
  figures, measured without its coverage, tear and far field. One Möbius map (the paper's
  mode with one line; a kept line alone, the identity) is conformal and one-to-one: its
  distortion is 0 by construction and is not measured;
- ``others px``: in (b), the other lines' worst distance from their best straight fit
  (measured as the pole line's), and ``without``: the same 4 lines warped without it.

Then, for each length, eq. (4)'s fold-over and distortion p99 by latitude (the line alone).

The criterion
-------------
Eq. (4) straightens these lines (from tens of pixels to none), except over the pole
exactly (``L = 90``: the lon/lat midpoint of ends 180° of longitude apart lies on either
side, and it does not). What grows with ``L`` is the price the rest of the panorama pays:
fold-over, distortion, displacement. Bin by bin it grows steadily (the distortion p99 by
1.0-1.4 times per 2.5°) up to a *knee*, where it jumps (1.9-2.3 times here) and the warp
folds; the longer the line, the lower its knee. A length's knee is the lowest latitude
where its line alone, the rule off, folds the output and has at least :data:`KNEE` (1.5)
times the distortion p99 of the same length one step lower (with the default lengths any
factor from 1.4 to 1.85 finds the same knees). Beyond its knee eq. (4) stops helping: it
buys the line's straightness with a fold-over and a jump of distortion, while the kept
line costs the panorama nothing (no fold-over, the other lines as straight as without it).
The suggestion is the median of the lengths' knees, the typical line's; the lowest knee,
which would also spare the longest lines, is printed with it.

Two other rules were looked at. "The middle moves more than k times its own bend" cannot
tell these lines apart: a centred arc's middle moves by exactly its bend from the chord
(both are ``L`` minus its ends' latitude), at every ``L``. The still background's absolute
targets (``tests/test_anchor.py``: no fold-over, p99 at most 0.5, displacement at most
0.5°) are broken by the 4 ordinary lines themselves (p99 about 0.8 with the pole line kept),
so they choose nothing.

Run on demand, not a test. With the defaults (39 lines, 1024 wide) it takes about 4
minutes of CPU, 4.6 minutes on a shared 2-core machine. ``--save`` keeps the rows and
``--load`` prints their tables again without warping.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
import time
import warnings
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from omniwidget.document.handles import Handles, LineHandle, Options  # noqa: E402
from omniwidget.evaluate import quality
from omniwidget.evaluate.scenes import mark_lines, synthetic_room  # noqa: E402
from omniwidget.method import constraints  # noqa: E402
from omniwidget.raster.pipeline import warp  # noqa: E402
from omniwidget.sphere import coords

#: The knee: eq. (4)'s distortion p99 grows by at least this factor over one latitude step (and the warp folds).
KNEE = 1.5
#: The three ways each line is warped, in the tables' order.
METHODS = ("eq4", "kept", "paper")
#: Ordinary lines: length and latitude.
OTHER_LENGTH = (40.0, 100.0)
OTHER_MAX_LAT = 59.5
#: Degrees the ordinary lines keep from the pole line and its eq. (4) image.
CLEAR = 10.0
#: Samples along a line, for its straightness.
SAMPLES = 200


def top_arc(lon: float, lat: float, length: float, top_at: float = 0.5) -> tuple[tuple[float, float], tuple[float, float]]:
    """The arc of ``length`` degrees through ``(lon, lat)``, where its great circle is highest (lowest for ``lat < 0``).

    There the great circle runs east-west, so the arc runs along the east direction:
    ``top_at * length`` degrees of it before that point (west) and the rest after it (east).
    """
    p = coords.lonlat_to_xyz((lon, lat))
    east, _ = coords.local_frame((lon, lat))

    def at(s: float) -> tuple[float, float]:
        q = coords.xyz_to_lonlat(math.cos(math.radians(s)) * p + math.sin(math.radians(s)) * east)
        return float(q[0]), float(q[1])

    return at(-top_at * length), at((1.0 - top_at) * length)


@dataclass
class Figures:
    """One warp's figures (NaN where not measured)."""

    out_px: float = math.nan
    fold: float = math.nan
    p99: float = math.nan
    mean: float = math.nan
    moved: float = math.nan
    others: float = math.nan
    seconds: float = math.nan


def line_output(result, handle: int) -> np.ndarray:
    """The handle's samples found in the output, its pieces joined in order, ``[lon, lat]``."""
    parts = [result.forward_points(samples, c) for c, samples in result.constraints.lines if result.controls[c].handle == handle]
    return np.concatenate(parts)


def measure(image, lines: list[LineHandle], pole: int | None, options: Options, rule: float) -> Figures:
    """Warp ``lines`` with ``POLE_LATITUDE = rule`` and measure (the pole line is ``lines[pole]``).

    The figures are ``Result.quality``'s (the same functions on the same inverse map),
    without its coverage, tear and far field, which this bench does not need.
    """
    constraints.POLE_LATITUDE = rule
    start = time.perf_counter()
    result = warp(image, Handles(tuple(lines), options), warn=False)
    seconds = time.perf_counter() - start
    width = result.image.shape[1]
    f = Figures(seconds=seconds)
    if pole is not None:
        f.out_px = quality.straightness(line_output(result, pole), width, fit="best")
        kept = [i for i, _ in result.constraints.near_pole] if options.anchor is not None else []
        assert kept == ([pole] if rule < 91 and options.anchor is not None else []), (kept, rule)
    m = result.inverse_map(np.float64)
    f.moved = quality.displacement(m)
    f.fold = result.folds.area
    if result.weights is None:  # one Möbius map: conformal and one-to-one
        f.p99, f.mean = 0.0, 0.0
    else:
        d = quality.conformal_distortion(m)
        f.p99, f.mean = d.p99, d.mean
    others = sorted({result.controls[c].handle for c, _ in result.constraints.lines} - {pole})
    if others:
        f.others = max(quality.straightness(line_output(result, h), width, fit="best") for h in others)
    return f


_ALONE: dict[tuple, float] = {}


def others_alone(image, lines: list[LineHandle]) -> float:
    """The worst straightness of the ordinary lines warped without the pole line (the default options)."""
    key = tuple((x.start, x.end) for x in lines)
    if key not in _ALONE:
        _ALONE[key] = measure(image, lines, None, Options(), 91.0).others
    return _ALONE[key]


def ordinary_lines(scene, pole: LineHandle, count: int = 4) -> list[LineHandle]:
    """``count`` ordinary lines of the room, 40-100° long, clear of the pole line and its eq. (4) image."""
    t = np.linspace(0.0, 1.0, 60)
    src = coords.geodesic(pole.start, pole.end, t)
    clear = np.concatenate([src, pole.moebius()(src)])
    long_enough = replace(scene, lines=[x for x in scene.lines if x.length >= OTHER_LENGTH[0]])
    picked = mark_lines(long_enough, count, seed=0, keep_clear=[(clear, CLEAR)], piece=OTHER_LENGTH[1], max_abs_lat=OTHER_MAX_LAT)
    assert all(OTHER_LENGTH[0] - 1e-9 <= x.length <= OTHER_LENGTH[1] + 1e-9 and x.max_abs_lat <= OTHER_MAX_LAT for x in picked)
    return [LineHandle(x.start, x.end) for x in picked]


def run(width: int, lengths: list[float], latitudes: list[float], top_at: float = 0.5) -> list[dict]:
    """Warp every line of the family three ways, alone and among others; one row of plain numbers per line."""
    module_rule = constraints.POLE_LATITUDE
    clock = time.perf_counter()
    scene = synthetic_room(width)
    rows = []
    n = 0
    try:
        for b, lat in enumerate(latitudes):
            for k, length in enumerate(lengths):
                sign = 1.0 if (b + k) % 2 == 0 else -1.0
                lon = float(coords.wrap_lon(-170.0 + 137.508 * n))  # the golden angle: spread round the sphere
                n += 1
                a, e = top_arc(lon, sign * lat, length, top_at)
                pole = LineHandle(a, e)
                rule = coords.arc_max_abs_lat(a, e) - 1e-3  # the rule on for this line (and for none of the others, below 59.5°)
                middle = coords.geodesic_midpoint(a, e)
                row = {
                    "lat": lat,
                    "length": length,
                    "sign": sign,
                    "lon": lon,
                    "middle": float(coords.angular_distance(middle, pole.moebius()(middle[None])[0])),
                    "in_px": quality.straightness(coords.geodesic(a, e, np.linspace(0.0, 1.0, SAMPLES)), width, fit="best"),
                }
                others = ordinary_lines(scene, pole)
                for context, lines in (("alone", [pole]), ("among", [*others, pole])):
                    at = len(lines) - 1
                    row[f"{context} eq4"] = asdict(measure(scene.image, lines, at, Options(), 91.0))
                    row[f"{context} kept"] = asdict(measure(scene.image, lines, at, Options(), rule))
                    row[f"{context} paper"] = asdict(measure(scene.image, lines, at, Options(anchor=None), 91.0))
                row["others alone"] = others_alone(scene.image, others)
                rows.append(row)
                print(f"  L {sign * lat:+5.1f}, {length:5.1f}° long: done ({time.perf_counter() - clock:.0f} s)", file=sys.stderr)
    finally:
        constraints.POLE_LATITUDE = module_rule
    return rows


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--width", type=int, default=1024)
    parser.add_argument("--lengths", default="40,75,110", help="degrees of arc, one line of each per latitude")
    parser.add_argument("--step", type=float, default=2.5, help="degrees between latitude bins, from 60 to 90")
    parser.add_argument("--top-at", type=float, default=0.5, help="where along each line its highest point lies (0.5: the middle)")
    parser.add_argument("--save", type=Path, help="write the measured rows to this JSON file")
    parser.add_argument("--load", type=Path, help="print the tables of rows saved by --save, without warping")
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    clock = time.perf_counter()
    if args.load:
        saved = json.loads(args.load.read_text())
        width, rows = saved["width"], saved["rows"]
        args.top_at = saved.get("top_at", 0.5)
    else:
        width = args.width
        lengths = [float(x) for x in args.lengths.split(",")]
        rows = run(width, lengths, [float(x) for x in np.arange(60.0, 90.0 + 1e-9, args.step)], args.top_at)
        if args.save:
            args.save.write_text(json.dumps({"width": width, "top_at": args.top_at, "rows": rows}))
    report(rows, width, args.top_at)
    print(f"\n({time.perf_counter() - clock:.0f} s)")
    return 0


def report(rows: list[dict], width: int, top_at: float) -> None:
    """Print the tables, each length's knee and the suggestion."""
    latitudes = sorted({r["lat"] for r in rows})
    lengths = sorted({r["length"] for r in rows})

    def cell(values: list[float], fmt: str, scale: float = 1.0) -> str:
        values = [scale * v for v in values]
        return f"{statistics.median(values):{fmt}} / {max(values):{fmt}}"

    where = "its middle" if top_at == 0.5 else f"{top_at:g} of its length along"
    print(
        f"Lines climbing to L (north and south; their highest point {where}), {len(lengths)} per bin "
        f"({', '.join(f'{x:g}' for x in lengths)}° long), {width} wide, rectified all. Each cell: median / worst over the bin's lines."
    )
    print("eq4: the default options, the rule off; kept: the rule on (the line's map is the identity); paper: anchor null, the rule off.\n")
    for context, title in (("alone", "(a) the line alone"), ("among", "(b) among 4 ordinary lines")):
        print(f"### {title}\n")
        head = (
            "| L ° | middle ° | in px | out px eq4 · kept · paper | fold % eq4 · kept · paper | "
            "distortion p99 eq4 · kept · paper | distortion mean eq4 | moved ° eq4 · kept · paper |"
        )
        if context == "among":
            head += " others px eq4 · kept · paper · without |"
        print(head)
        print("| " + " | ".join(["---"] * (head.count("|") - 1)) + " |")
        for lat in latitudes:
            r = [x for x in rows if x["lat"] == lat]

            def fig(method: str, name: str, r=r, context=context) -> list[float]:
                return [x[f"{context} {method}"][name] for x in r]

            line = (
                f"| {lat:g} | {cell([x['middle'] for x in r], '.1f')} | {cell([x['in_px'] for x in r], '.1f')} | "
                + " · ".join(cell(fig(m, "out_px"), ".2f") for m in METHODS)
                + " | "
                + " · ".join(cell(fig(m, "fold"), ".2f", 100) for m in METHODS)
                + " | "
                + " · ".join(cell(fig(m, "p99"), ".2f") for m in METHODS)
                + f" | {cell(fig('eq4', 'mean'), '.3f')} | "
                + " · ".join(cell(fig(m, "moved"), ".2f") for m in METHODS)
                + " |"
            )
            if context == "among":
                line += " " + " · ".join(cell(fig(m, "others"), ".2f") for m in METHODS) + f" · {cell([x['others alone'] for x in r], '.2f')} |"
            print(line)
        print()

    print("### eq. (4) by length: the line alone, the rule off\n")
    print("Each cell: fold-over % · distortion p99 (its ratio to the same length 2.5° lower); * marks the knee.\n")
    print("| L ° | " + " | ".join(f"{x:g}° long" for x in lengths) + " |")
    print("| --- | " + " | ".join("---" for _ in lengths) + " |")
    knees = {length: knee([x for x in rows if x["length"] == length]) for length in lengths}
    for lat in latitudes:
        cells = []
        for length in lengths:
            line = [x for x in rows if x["length"] == length]
            here = [x for x in line if x["lat"] == lat]
            if not here:
                cells.append("")
                continue
            f = here[0]["alone eq4"]
            below = [x for x in line if x["lat"] < lat]
            ratio = f" ({f['p99'] / max(below, key=lambda x: x['lat'])['alone eq4']['p99']:.2f}x)" if below else ""
            cells.append(f"{100 * f['fold']:.3f} · {f['p99']:.2f}{ratio}{' *' if knees[length] == lat else ''}")
        print(f"| {lat:g} | " + " | ".join(cells) + " |")
    print()
    found = [k for k in knees.values() if k is not None]
    print("knee by length: " + ", ".join(f"{length:g}° long: {'none' if k is None else f'{k:g}°'}" for length, k in knees.items()))
    if not found:
        print("suggestion: none (no length reaches a knee below 90°)")
        return
    suggestion = sorted(found)[(len(found) - 1) // 2]
    print(
        f"suggestion: POLE_LATITUDE = {suggestion:g} (the median of the lengths' knees; {min(found):g} would also keep the "
        f"longest lines from theirs; now {constraints.POLE_LATITUDE:g})"
    )


def knee(line: list[dict]) -> float | None:
    """The lowest latitude where eq. (4)'s cost jumps for lines of one length (rows of one length, any order).

    Alone, the rule off: the distortion p99 is at least :data:`KNEE` times that of the next
    lower latitude measured, and the warp folds.
    """
    line = sorted(line, key=lambda x: x["lat"])
    for lower, here in zip(line[:-1], line[1:], strict=True):
        a, b = lower["alone eq4"], here["alone eq4"]
        if b["fold"] > 0 and b["p99"] >= KNEE * a["p99"]:
            return float(here["lat"])
    return None


if __name__ == "__main__":
    sys.exit(main())
