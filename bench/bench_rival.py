#!/usr/bin/env python
"""Ours against the paper's strongest rival, [10] (Carroll et al. 2009), per scene family and on the photos.

Usage::

    python bench/bench_rival.py [--seeds 40] [--width 2048] [--families short,long,...]
                                [--photos | --no-photos] [--max-lines 20] [--json PATH]

For each family of :data:`omniwidget.evaluate.scenes.FAMILIES` and each odd seed of
``1 .. --seeds - 1`` (the half held out for reporting, as ``bench_default.py --half report``),
the scene (:func:`~omniwidget.evaluate.scenes.family_scene`, rendered at ``--width``) is
warped three ways with the same handles: ours in the default mode (``Options()``), ours in
the paper's mode (``Options(rectify="all", anchor=None)``), and [10]'s content-preserving
projection (:func:`omniwidget.evaluate.content_preserving.content_preserving`, its
defaults; it uses the line handles only, so in the cage and point families it straightens
the lines and holds nothing else). Then the photos of ``/work/shared/data`` (read there,
never copied), each resized to ``--width`` and given its ``--max-lines`` best suggested lines
(:func:`omniwidget.detect.suggest_lines`).

Every figure is measured as :class:`omniwidget.evaluate.baselines.Comparison` measures it:
ours by ``result.quality``, [10] on its own plane (``ContentPreservingResult.quality``,
:class:`~omniwidget.evaluate.content_preserving.PlaneSummary`):

- lines: each marked line's largest distance from its best straight fit, densely along its
  whole arc, in pixels of an equirectangular panorama ``--width`` wide (for [10], its plane's
  pixels converted at the line's own scale); worst and median over all lines;
- distortion: the median over scenes of the mean and of the 99th percentile;
- fold-over: the largest share of the sphere turned over, %;
- shown: the smallest share of the sphere shown, %; cropped: [10]'s median share of the
  sphere lost when its output is cropped to the largest rectangle inside its border, %;
- moved: the median of the mean displacement of the sphere, degrees (ours only: a plane
  keeps no place);
- time: the median seconds of the method (wall clock after a warm-up; the machine's load
  counts too).

The smoke run is ``python bench/bench_rival.py --seeds 4 --width 512 --families short --no-photos``.
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
sys.path.insert(0, str(Path(__file__).resolve().parent))

import cv2  # noqa: E402
import numpy as np  # noqa: E402
from bench_default import _fmt, _max, _median, _plain  # noqa: E402

from omniwidget.detect import suggest_lines, suggestions_to_handles  # noqa: E402
from omniwidget.document.handles import Handles, LineHandle, Options  # noqa: E402
from omniwidget.evaluate.content_preserving import content_preserving  # noqa: E402
from omniwidget.evaluate.scenes import FAMILIES, family_scene  # noqa: E402
from omniwidget.io.images import read_image  # noqa: E402
from omniwidget.raster.pipeline import warp  # noqa: E402

DATA = Path("/work/shared/data")
METHODS = ("default", "paper", "carroll")
OPTIONS = {"default": Options(), "paper": Options(rectify="all", anchor=None)}


def measure(image: np.ndarray, doc: Handles) -> dict[str, dict[str, Any]]:
    """The three methods' figures on one document."""
    out: dict[str, dict[str, Any]] = {}
    for mode, options in OPTIONS.items():
        start = time.perf_counter()
        result = warp(image, Handles(doc.handles, options))
        seconds = time.perf_counter() - start
        q = result.quality
        out[mode] = {
            "lines": list(q.lines), "distortion_mean": q.distortion_mean, "distortion_p99": q.distortion_p99,
            "fold_over": q.fold_over, "coverage": q.coverage, "cropped_loss": None, "displacement": q.displacement, "seconds": seconds,
        }  # fmt: skip
    lines = Handles(tuple(h for h in doc.handles if isinstance(h, LineHandle)), doc.options)
    start = time.perf_counter()
    theirs = content_preserving(image, lines)
    seconds = time.perf_counter() - start
    q = theirs.quality
    out["carroll"] = {
        "lines": list(q.lines), "lines_output_px": list(q.lines_output_px), "distortion_mean": q.distortion_mean,
        "distortion_p99": q.distortion_p99, "fold_over": q.fold_over, "coverage": q.coverage, "cropped_loss": q.cropped_loss,
        "displacement": None, "seconds": seconds, "iterations": theirs.solution.iterations, "shape": list(theirs.image.shape[:2]),
    }  # fmt: skip
    return out


def _num(v: Any) -> float:
    return math.nan if v is None else float(v)


HEAD = [
    "method",
    "lines worst / median px",
    "distortion mean (median)",
    "distortion p99 (median)",
    "fold-over max %",
    "sphere shown min %",
    "lost to the crop (median) %",
    "moved (median) °",
    "time (median) s",
]
LABELS = {"default": "ours, default mode", "paper": "ours, the paper's mode", "carroll": "[10] content-preserving"}


def table(title: str, records: list[dict[str, dict[str, Any]]]) -> str:
    """One markdown table: a row per method, aggregated over the records (one per scene)."""
    out = [f"### {title}", "", "| " + " | ".join(HEAD) + " |", "| " + " | ".join("---" for _ in HEAD) + " |"]
    for method in METHODS:
        rows = [r[method] for r in records]
        lines = [_num(v) for r in rows for v in r["lines"]]
        cells = [
            LABELS[method],
            f"{_fmt(_max(lines))} / {_fmt(_median(lines))}" if lines else "–",
            _fmt(_median([_num(r["distortion_mean"]) for r in rows]), 3),
            _fmt(_median([_num(r["distortion_p99"]) for r in rows])),
            _fmt(100 * _max([_num(r["fold_over"]) for r in rows]), 3),
            _fmt(100 * min(_num(r["coverage"]) for r in rows), 1),
            _fmt(100 * _median([_num(r["cropped_loss"]) for r in rows]), 1),
            _fmt(_median([_num(r["displacement"]) for r in rows])),
            _fmt(statistics.median(r["seconds"] for r in rows)),
        ]
        out.append("| " + " | ".join(cells) + " |")
    return "\n".join(out)


def photo(path: Path, width: int, max_lines: int) -> tuple[np.ndarray, Handles]:
    """A photo resized to ``width`` and its best suggested lines."""
    image = read_image(path)
    if image.shape[1] != width:
        image = cv2.resize(image, (width, width // 2), interpolation=cv2.INTER_AREA)
    return image, suggestions_to_handles(suggest_lines(image, max_lines=max_lines))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=40, help="seeds 0 .. N-1, of which the odd ones are reported (default 40: 20)")
    parser.add_argument("--width", type=int, default=2048)
    parser.add_argument("--families", default=",".join(FAMILIES), help="comma list, of: " + ", ".join(FAMILIES) + " (empty: none)")
    parser.add_argument("--photos", action=argparse.BooleanOptionalAction, default=True, help=f"also the photos of {DATA}")
    parser.add_argument("--max-lines", type=int, default=20, help="suggested lines per photo")
    parser.add_argument("--json", type=Path, help="write every per-scene figure here")
    args = parser.parse_args(argv)
    families = [f.strip() for f in args.families.split(",") if f.strip()]
    unknown = [f for f in families if f not in FAMILIES]
    if unknown:
        parser.error(f"unknown families {unknown}; choose among {', '.join(FAMILIES)}")
    if args.width < 64 or args.width % 2:
        parser.error("--width must be even and at least 64")
    seeds = list(range(1, args.seeds, 2))
    if families and not seeds:
        parser.error("--seeds must be at least 2 (the odd seeds below it are reported)")
    warnings.simplefilter("ignore")

    scene, doc, _ = family_scene("short", 1, args.width)  # warm-up: compiling the kernels is not timed
    measure(scene.image, doc)

    print(f"bench_rival: seeds {seeds[0] if seeds else '-'}..{seeds[-1] if seeds else '-'} ({len(seeds)} per family), width {args.width}\n")
    everything: list[dict[str, Any]] = []
    for family in families:
        records = []
        for seed in seeds:
            scene, doc, _ = family_scene(family, seed, args.width)
            figures = measure(scene.image, doc)
            records.append(figures)
            everything.append({"family": family, "seed": seed, **figures})
            print(f"  {family} seed {seed} done", file=sys.stderr, flush=True)
        print(table(f"{family} ({len(records)} scenes, {args.width} px)", records) + "\n", flush=True)
    if args.photos:
        paths = sorted(DATA.glob("*.jpg")) if DATA.is_dir() else []
        records = []
        names = []
        for path in paths:
            image, doc = photo(path, args.width, args.max_lines)
            if not doc.handles:
                continue
            figures = measure(image, doc)
            records.append(figures)
            names.append(f"{path.stem} ({len(doc.handles)} lines)")
            everything.append({"family": "photo", "photo": path.name, **figures})
            print(f"  {path.name} done", file=sys.stderr, flush=True)
        if records:
            print(table(f"photos ({len(records)}, {args.width} px, up to {args.max_lines} suggested lines each: {', '.join(names)})", records) + "\n")
    if args.json is not None:
        args.json.write_text(json.dumps(_plain(everything), indent=1) + "\n")
        print(f"per-scene figures written to {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
