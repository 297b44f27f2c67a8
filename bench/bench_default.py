#!/usr/bin/env python
"""The default mode against the paper's on generated scene families: a markdown table per family.

Usage::

    python bench/bench_default.py [--half report|choose] [--seeds 40] [--width 2048]
                                  [--families short,long,...] [--json PATH]

For each family of :data:`omniwidget.evaluate.scenes.FAMILIES` and each seed of one half
(``--half choose``: the even seeds of ``0 .. --seeds - 1``, for choosing settings;
``--half report``, the default: the odd ones, held out for reporting), the scene's room is
rendered at ``--width`` (:func:`~omniwidget.evaluate.scenes.family_scene`) and warped twice:
by the default mode (``Options()``: rectify "all", the still background) and by the paper's
(``Options(rectify="all", anchor=None)``). Every figure is measured on the output, at its
width; per family and mode the table aggregates over the half's scenes:

- lines: each line's largest distance from its best straight fit in the output, measured
  densely along its whole arc through the map that placed the pixels
  (``result.quality.lines``), worst and median over all lines, px; beside it the same
  under the piece's own single map (``straightness(result.controls[c].moebius(samples), W,
  fit="best")``: what the blend would give if it were that map alone);
- fold-over: the largest share of the sphere turned over, %;
- distortion: the largest mean and the largest 99th percentile (``Result.quality``);
- displacement: the largest mean motion of the sphere, degrees;
- kink: the largest turn of an edge's continuation past its marked piece, degrees of turn
  per degree of arc (:func:`~omniwidget.evaluate.quality.kink`, over every marked line whose
  scene line goes on beyond it), with the input's own figure for the same edges beside it;
- points: the largest centre error (px), zoom error (%) and rotation error (degrees) of
  the point handles (:func:`~omniwidget.evaluate.quality.point_fidelity`);
- cages: the largest error of a cage's rigid motion inside it, px
  (:func:`~omniwidget.evaluate.quality.cage_fidelity`, against the rotation that made its targets);
- reach (a table of its own): each point handle's asked zoom and turn against what is seen at a third of
  its reach (where they should hold to 10% and 2°) and what is left at the reach;
- relaxed lines: how many lines are farther than 0.5 px from straight (``result.quality.relaxed``);
- warp: the median and the largest seconds of ``warp`` (wall clock, after one warm-up warp; the machine's
  other load counts too).

At the end, one table of the default mode's figures per family and mode: medians, the worst
scene, and how many scenes meet every figure the issue asks of the default mode (no
fold-over; distortion mean and p99 and the mean displacement at most 0.05, 0.5 and 0.5°, or
0.1, 1.0 and 1° for the long lines; lines within 0.5 px; points within 0.25 px, 1% and
0.1°; cages within 0.5 px). ``--json PATH`` writes every per-scene figure, and ``--load
PATH`` prints that last table again from such a file. Run on demand, not a test; the smoke
run is ``python bench/bench_default.py --seeds 4 --width 1024``.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
import time
import warnings
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402

from omniwidget.document.handles import Handles, Options, PointHandle  # noqa: E402
from omniwidget.evaluate.quality import cage_fidelity, kink, point_fidelity, point_reach_profile, straightness  # noqa: E402
from omniwidget.evaluate.scenes import FAMILIES, family_scene  # noqa: E402
from omniwidget.method.reach import default_reach  # noqa: E402
from omniwidget.raster import untangle  # noqa: E402
from omniwidget.raster.pipeline import warp  # noqa: E402
from omniwidget.sphere import coords  # noqa: E402

MODES = {"default": Options(), "paper": Options(rectify="all", anchor=None)}
#: A marked line continues when its scene line is longer by at least this (degrees).
CONTINUES = 0.5
#: Degrees: a point handle moved less is counted as held still in the reach table.
STILL = 0.01


def measure(image: np.ndarray, doc: Handles, truth: dict[str, Any]) -> dict[str, Any]:
    """Warp one document and measure every figure of the table, per line, point and cage."""
    start = time.perf_counter()
    result = warp(image, doc)
    seconds = time.perf_counter() - start
    q = result.quality
    width = result.image.shape[1]
    single = [straightness(result.controls[c].moebius(samples), width, fit="best") for c, samples in result.constraints.lines]
    m = result.inverse_map(np.float64)
    kinks = []
    for index, line, parent in zip(truth["line_handles"], truth["lines"], truth["parents"], strict=True):
        if parent.length - line.length >= CONTINUES:
            edge = [parent.start, parent.end]
            kinks.append({"handle": index, "output": kink(m, edge, line.start, line.end), "input": kink(None, edge, line.start, line.end)})
    points = []
    for index in truth["point_handles"]:
        f = point_fidelity(result, index)
        points.append({"handle": index, "centre_px": f.centre_px, "zoom_error": f.zoom_error, "rotation_error": f.rotation_error, **reach(result, index)})
    cages = [
        {"handle": index, "error_px": cage_fidelity(result, index, rotation)}
        for index, rotation in zip(truth["cage_handles"], truth["rotations"], strict=True)
    ]
    return {
        "lines": list(q.lines),
        "lines_single": single,
        "fold_over": q.fold_over,
        "distortion_mean": q.distortion_mean,
        "distortion_p99": q.distortion_p99,
        "displacement": q.displacement,
        "kinks": kinks,
        "points": points,
        "cages": cages,
        "seconds": seconds,
        "untangle_seconds": result.timings.get("untangle", 0.0),
        "relaxed": [list(r) for r in q.relaxed],
        "warnings": list(result.warnings),
    }


def reach(result: Any, index: int) -> dict[str, Any]:
    """What a point handle's turn and zoom are seen to do at a third of its reach and at its reach.

    The magnification (one over the mean singular value of the inverse map) and the turn, on 24 output points
    a ring (:func:`~omniwidget.evaluate.quality.point_reach_profile`), against the handle's own zoom and turn.
    """
    h = result.handles.handles[index]
    if not isinstance(h, PointHandle):
        raise TypeError(f"handles[{index}] is not a point handle")
    radius = h.reach if h.reach is not None else default_reach(result.handles, index)
    profile = point_reach_profile(result, index, [radius / 3.0, radius])
    mag, turn = profile["magnification"], profile["rotation"]
    return {
        "moved": float(coords.angular_distance(h.position, h.final)),
        "reach": radius,
        "scale": h.scale,
        "rotation": h.rotation,
        "inner_zoom_error": float(np.max(np.abs(mag[0] / h.scale - 1.0))),
        "inner_turn_error": float(np.max(np.abs(turn[0] - h.rotation))),
        "outer_zoom_left": float(np.max(np.abs(mag[1] - 1.0))),
        "outer_turn_left": float(np.max(np.abs(turn[1]))),
    }


def reach_table(records: list[dict[str, Any]]) -> str:
    """Rows per family and mode with point handles, the points held still (moved less than :data:`STILL`) apart
    from the moved ones: the asked turn and zoom against what is seen at a third of the reach (where they should
    hold, to 10% and 2°) and at the reach (where they should be gone).

    Only a moved point's zoom is measured here: the turn is measured as a ring's bearing about the target against
    the content's about the position, and where the shift fades the two differ by the shift itself (its zoom and
    turn at the centre are the main table's point columns).
    """
    head = [
        "family",
        "mode",
        "points",
        "reach ° median (range)",
        "asked zoom (range) / turn ° (max)",
        "zoom error at R/3: median / worst %",
        "turn error at R/3: median / worst °",
        "zoom left at R: worst %",
        "turn left at R: worst °",
        "points within 10% and 2° at R/3 (moved: 10%)",
    ]
    out = ["| " + " | ".join(head) + " |", "| " + " | ".join("---" for _ in head) + " |"]
    for family in dict.fromkeys(r["family"] for r in records):
        for mode, still in ((m, still) for m in MODES for still in (True, False)):
            points = [
                p
                for r in records
                if r["family"] == family and r["mode"] == mode
                for p in r["points"]
                if (p["moved"] < STILL) == still
            ]
            if not points:
                continue

            def column(key: str, points: list[dict[str, Any]] = points) -> list[float]:
                return [p[key] for p in points]

            held = sum(p["inner_zoom_error"] <= 0.1 and (p["inner_turn_error"] <= 2.0 or not still) for p in points)
            cells = [
                family,
                mode,
                f"{len(points)} {'still' if still else 'moved'}",
                f"{_fmt(_median(column('reach')), 1)} ({_fmt(min(column('reach')), 1)}-{_fmt(max(column('reach')), 1)})",
                f"{_fmt(min(column('scale')))}-{_fmt(max(column('scale')))} / {_fmt(max(abs(v) for v in column('rotation')), 1)}",
                f"{_fmt(100 * _median(column('inner_zoom_error')), 1)} / {_fmt(100 * _max(column('inner_zoom_error')), 1)}",
                f"{_fmt(_median(column('inner_turn_error')))} / {_fmt(_max(column('inner_turn_error')))}" if still else "–",
                _fmt(100 * _max(column("outer_zoom_left")), 1),
                _fmt(_max(column("outer_turn_left"))) if still else "–",
                f"{held} of {len(points)}",
            ]
            out.append("| " + " | ".join(cells) + " |")
    return "\n".join(out)


def _max(values: list[float]) -> float:
    """The largest value; inf if any is NaN (a line the output does not show), NaN if none."""
    if not values:
        return math.nan
    return math.inf if any(math.isnan(v) for v in values) else max(values)


def _median(values: list[float]) -> float:
    finite = [v for v in values if not math.isnan(v)]
    return statistics.median(finite) if finite else math.nan


def _fmt(value: float, digits: int = 2) -> str:
    if math.isnan(value):
        return "–"
    if math.isinf(value):
        return "inf"
    return f"{value:.{digits}f}"


def table(family: str, rows: dict[str, list[dict[str, Any]]], width: int) -> str:
    """The markdown table of one family: one row per mode."""
    head = [
        "mode",
        "lines worst / median px",
        "single map worst / median px",
        "fold-over max %",
        "distortion mean max",
        "distortion p99 max",
        "displacement max °",
        "kink max (input) °/°",
        "point centre max px",
        "point zoom max %",
        "point rotation max °",
        "cage max px",
        "relaxed lines",
        "warp median / max s",
    ]
    out = [f"### {family} ({len(next(iter(rows.values())))} scenes, {width} px)", "", "| " + " | ".join(head) + " |"]
    out.append("| " + " | ".join("---" for _ in head) + " |")
    for mode, scenes in rows.items():
        lines = [v for s in scenes for v in s["lines"]]
        single = [v for s in scenes for v in s["lines_single"]]
        kinks = [k for s in scenes for k in s["kinks"]]
        points = [p for s in scenes for p in s["points"]]
        cages = [c["error_px"] for s in scenes for c in s["cages"]]
        cells = [
            mode,
            f"{_fmt(_max(lines))} / {_fmt(_median(lines))}" if lines else "–",
            f"{_fmt(_max(single), 3)} / {_fmt(_median(single), 3)}" if single else "–",
            _fmt(100 * _max([s["fold_over"] for s in scenes]), 3),
            _fmt(_max([s["distortion_mean"] for s in scenes]), 3),
            _fmt(_max([s["distortion_p99"] for s in scenes])),
            _fmt(_max([s["displacement"] for s in scenes]), 3),
            f"{_fmt(_max([k['output'] for k in kinks]))} ({_fmt(_max([k['input'] for k in kinks]))})" if kinks else "–",
            _fmt(_max([p["centre_px"] for p in points])),
            _fmt(100 * _max([p["zoom_error"] for p in points])),
            _fmt(_max([p["rotation_error"] for p in points])),
            _fmt(_max(cages)),
            f"{sum(len(s['relaxed']) for s in scenes)} of {len(lines)}",
            f"{_fmt(statistics.median(s['seconds'] for s in scenes))} / {_fmt(max(s['seconds'] for s in scenes))}",
        ]
        out.append("| " + " | ".join(cells) + " |")
    return "\n".join(out)


#: The figures asked of the default mode: (fold-over, distortion mean, distortion p99, displacement °) at most.
LONG_TARGETS = (0.0, 0.1, 1.0, 1.0)
TARGETS = {"long": LONG_TARGETS, "room_edges": LONG_TARGETS, "suggested": LONG_TARGETS}  # the suggestions are 50-180° long
TARGETS_SHORT = (0.0, 0.05, 0.5, 0.5)  # every other family: short lines, cages and points


def targets(records: list[dict[str, Any]]) -> str:
    """One row per family and mode: medians, the worst scene, and how many scenes meet the default mode's figures."""
    head = [
        "family",
        "mode",
        "lines worst px",
        "scenes folding",
        "distortion mean: median / worst",
        "p99: median / worst",
        "moved °: median / worst",
        "kink °/°: median / worst (input's median)",
        "points: centre px / zoom % / turn ° worst",
        "cages worst px",
        "scenes meeting every figure",
    ]
    out = ["| " + " | ".join(head) + " |", "| " + " | ".join("---" for _ in head) + " |"]
    families = list(dict.fromkeys(r["family"] for r in records))
    for family in families:
        fold_max, mean_max, p99_max, moved_max = TARGETS.get(family, TARGETS_SHORT)
        for mode in MODES:
            scenes = [r for r in records if r["family"] == family and r["mode"] == mode]
            if not scenes:
                continue

            def values(key: str, scenes: list[dict[str, Any]] = scenes) -> list[float]:
                return [math.nan if s[key] is None else s[key] for s in scenes]

            lines = [math.nan if v is None else v for s in scenes for v in s["lines"]]
            kinks = [k for s in scenes for k in s["kinks"]]
            points = [p for s in scenes for p in s["points"]]
            cages = [c["error_px"] for s in scenes for c in s["cages"]]
            meeting = sum(
                (s["fold_over"] or 0) <= fold_max
                and s["distortion_mean"] <= mean_max
                and s["distortion_p99"] <= p99_max
                and s["displacement"] <= moved_max
                and all(v is not None and v <= 0.5 for v in s["lines"])
                and all(p["centre_px"] <= 0.25 and p["zoom_error"] <= 0.01 and p["rotation_error"] <= 0.1 for p in s["points"])
                and all(c["error_px"] <= 0.5 for c in s["cages"])
                for s in scenes
            )
            cells = [
                family,
                mode,
                _fmt(_max(lines)) if lines else "–",
                f"{sum((s['fold_over'] or 0) > 0 for s in scenes)} of {len(scenes)}",
                f"{_fmt(_median(values('distortion_mean')), 3)} / {_fmt(_max(values('distortion_mean')), 3)}",
                f"{_fmt(_median(values('distortion_p99')))} / {_fmt(_max(values('distortion_p99')))}",
                f"{_fmt(_median(values('displacement')))} / {_fmt(_max(values('displacement')))}",
                f"{_fmt(_median([k['output'] for k in kinks]), 1)} / {_fmt(_max([k['output'] for k in kinks]), 1)} "
                f"({_fmt(_median([k['input'] for k in kinks]), 1)})"
                if kinks
                else "–",
                f"{_fmt(_max([p['centre_px'] for p in points]))} / {_fmt(100 * _max([p['zoom_error'] for p in points]), 1)} / "
                f"{_fmt(_max([p['rotation_error'] for p in points]))}"
                if points
                else "–",
                _fmt(_max(cages)) if cages else "–",
                f"{meeting} of {len(scenes)}" if mode == "default" else "",
            ]
            out.append("| " + " | ".join(cells) + " |")
    return "\n".join(out)


def _plain(value: Any) -> Any:
    """JSON-ready: NaN and infinities become None."""
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    if isinstance(value, float | np.floating):
        return float(value) if math.isfinite(value) else None
    return value


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--half", choices=("choose", "report"), default="report", help="even seeds (choose) or odd seeds (report)")
    parser.add_argument("--seeds", type=int, default=40, help="seeds 0 .. N-1, of which the half's (default 40: 20 per half)")
    parser.add_argument("--width", type=int, default=2048)
    parser.add_argument("--families", default=",".join(FAMILIES), help="comma list, of: " + ", ".join(FAMILIES))
    parser.add_argument("--json", type=Path, help="write every per-scene figure here")
    parser.add_argument("--spread", type=float, help="omniwidget.raster.untangle.SPREAD for this run (for choosing it)")
    parser.add_argument("--load", type=Path, help="print the summary of the default mode's figures from a --json file, without warping")
    args = parser.parse_args(argv)
    if args.load is not None:
        records = json.loads(args.load.read_text())
        print(targets(records))
        if any(r["points"] and "reach" in r["points"][0] for r in records):
            print("\n" + reach_table(records))
        return 0
    families = [f.strip() for f in args.families.split(",") if f.strip()]
    unknown = [f for f in families if f not in FAMILIES]
    if unknown or not families:
        parser.error(f"unknown families {unknown}; choose among {', '.join(FAMILIES)}")
    if args.seeds < 1:
        parser.error("--seeds must be at least 1")
    seeds = list(range(0 if args.half == "choose" else 1, args.seeds, 2))
    if not seeds:
        parser.error(f"the {args.half} half of {args.seeds} seeds is empty")
    warnings.simplefilter("ignore")
    if args.spread is not None:
        untangle.SPREAD = args.spread

    # one warm-up warp, so that compiling the kernels is not timed
    scene, doc, _ = family_scene(families[0], seeds[0], args.width)
    warp(scene.image, doc)

    print(f"bench_default: {args.half} half, seeds {seeds[0]}..{seeds[-1]} ({len(seeds)} per family), width {args.width}\n")
    records = []
    for family in families:
        rows: dict[str, list[dict[str, Any]]] = {mode: [] for mode in MODES}
        for seed in seeds:
            scene, doc, truth = family_scene(family, seed, args.width)
            for mode, options in MODES.items():
                figures = measure(scene.image, Handles(doc.handles, options), truth)
                rows[mode].append(figures)
                records.append({"family": family, "seed": seed, "mode": mode, "handles": doc.to_dict()["handles"], **figures})
            print(f"  {family} seed {seed} done", file=sys.stderr, flush=True)
        print(table(family, rows, args.width) + "\n", flush=True)
    print(targets(_plain(records)) + "\n")
    if any(r["points"] for r in records):
        print(reach_table(records) + "\n")
    if args.json is not None:
        args.json.write_text(json.dumps(_plain(records), indent=1) + "\n")
        print(f"per-scene figures written to {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
