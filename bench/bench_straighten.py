#!/usr/bin/env python
"""One click, a straight photo: ``ow.straighten`` on generated box rooms and on the photographs, run on demand.

Usage::

    python bench/bench_straighten.py                          # the report half: odd seeds 1-39 (20 rooms), 1024 px
    python bench/bench_straighten.py --half choose            # the even seeds, for choosing constants
    python bench/bench_straighten.py --rooms 0 --photos ../shared/data --width 2048 --repeat 5

Per room (:func:`omniwidget.evaluate.scenes.box_room`: patterned walls and floors, tilts up
to 20°): the box's edges covered by the lines ``straighten`` used and their precision
(:func:`~omniwidget.evaluate.scenes.edge_coverage`, :func:`~omniwidget.evaluate.scenes.edge_precision`,
within 0.5°), the box's four vertical edges' tilt in the output
(:func:`~omniwidget.evaluate.quality.vertical_tilt`, through the map that placed the
pixels), every used line's distance from straight measured densely (``Result.quality``;
"not shown" counts the lines a sample of which the dense search did not find), the
fold-over, the distortion's 99th percentile, and the time of ``straighten`` against
``warp`` of the same handles (medians of ``--repeat``, in turns, in one process).
``--photos DIR``: every panorama there read at 2048 (a larger one reduced as the
detector does), the same figures without ground truth: the used vertical lines' tilt.
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import time
from pathlib import Path

import numpy as np

import omniwidget as ow
from omniwidget.evaluate.quality import vertical_tilt
from omniwidget.evaluate.scenes import box_room, edge_coverage, edge_precision


def _vertical_edges(scene) -> list:
    """The box's own vertical edges (its four corners), by their 3D direction along the camera's up."""
    p, r = math.radians(scene.pitch), math.radians(scene.roll)
    up = np.array([math.sin(p) * math.cos(r), -math.sin(r), math.cos(p) * math.cos(r)])
    out = []
    for line in scene.lines[:12]:
        d = np.subtract(line.end_3d, line.start_3d)
        if abs(d @ up) > 0.9999 * np.linalg.norm(d):
            out.append(line)
    return out


def _times(image: np.ndarray, repeat: int) -> tuple[float, float, ow.Straightened]:
    """Medians of ``straighten`` and of ``warp`` of the handles it used, in turns."""
    made, warped = [], []
    done = None
    for _ in range(repeat):
        t = time.perf_counter()
        done = ow.straighten(image)
        made.append(time.perf_counter() - t)
        t = time.perf_counter()
        ow.warp(image, done.handles, warn=False)
        warped.append(time.perf_counter() - t)
    assert done is not None
    return statistics.median(made), statistics.median(warped), done


def _row(done: ow.Straightened, made: float, warped: float, tilts: list[float]) -> dict:
    """The figures every scene reports: lines used, worst tilt of ``tilts``, straightness, fold, p99, time."""
    lines = done.result.quality.lines
    shown = [v for v in lines if math.isfinite(v)]
    return {
        "lines": len(done.structure.used),
        "vertical": max(tilts) if tilts else math.nan,
        "straight": max(shown) if shown else math.nan,
        "hidden": len(lines) - len(shown),
        "fold": done.result.folds.area,
        "p99": done.result.quality.distortion_p99,
        "seconds": made,
        "ratio": made / warped,
    }


def rooms(seeds: list[int], width: int, repeat: int) -> list[dict]:
    rows = []
    for seed in seeds:
        scene = box_room(seed, width)
        made, warped, done = _times(scene.image, repeat)
        placed = done.result.placed_map()
        tilts = [vertical_tilt(placed, line.start, line.end) for line in _vertical_edges(scene)]
        row = {
            "seed": seed,
            "tilt": math.hypot(scene.pitch, scene.roll),
            "coverage": edge_coverage(scene, done.structure.used),
            "precision": edge_precision(scene, done.structure.used),
            **_row(done, made, warped, tilts),
        }
        worst, hidden = row["straight"], row["hidden"]
        rows.append(row)
        print(
            f"room {seed:3d} (tilt {row['tilt']:4.1f}°): coverage {row['coverage']:.2f} precision {row['precision']:.2f} "
            f"lines {row['lines']:2d} verticals {row['vertical']:.3f}° straight {worst:.2f} px ({hidden} not shown) "
            f"fold {row['fold']:.4f} p99 {row['p99']:.2f} straighten {made:.2f} s ({row['ratio']:.2f}x warp)",
            flush=True,
        )
    return rows


def photos(folder: Path, repeat: int) -> list[dict]:
    rows = []
    for path in sorted(p for p in folder.iterdir() if p.suffix.lower() in (".jpg", ".jpeg", ".png", ".tif", ".tiff", ".webp")):
        image = ow.read_panorama(path, width=2048)
        if image.shape[1] > 2048:
            import cv2

            image = cv2.resize(image, (2048, 1024), interpolation=cv2.INTER_AREA)
        made, warped, done = _times(image, repeat)
        placed = done.result.placed_map()
        verticals = [vertical_tilt(placed, s.start, s.end) for s in done.structure.used if s.kind == "vertical"]
        row = {"name": path.name, "verticals": len(verticals), "summary": done.structure.summary(), **_row(done, made, warped, verticals)}
        worst, hidden = row["straight"], row["hidden"]
        rows.append(row)
        print(
            f"{path.name}: lines {row['lines']} ({row['verticals']} vertical, worst {row['vertical']:.3f}°) straight {worst:.2f} px "
            f"({hidden} not shown) fold {row['fold']:.4f} p99 {row['p99']:.2f} straighten {made:.2f} s ({row['ratio']:.2f}x warp)\n  {row['summary']}",
            flush=True,
        )
    return rows


def _summary(rows: list[dict]) -> None:
    def worst(key: str, low: bool = False) -> str:
        values = [r[key] for r in rows if math.isfinite(r[key])]
        if not values:
            return "–"
        return f"{(min if low else max)(values):.3f} (median {statistics.median(values):.3f})"

    print("\n| figure | worst (median) |\n| --- | --- |")
    for key, label, low in (
        ("coverage", "coverage of the box's edges", True),
        ("precision", "precision", True),
        ("vertical", "vertical edges' tilt °", False),
        ("straight", "lines' distance from straight px", False),
        ("fold", "fold-over (share of the sphere)", False),
        ("p99", "distortion p99", False),
        ("seconds", "straighten s", False),
        ("ratio", "straighten / warp", False),
    ):
        if key in rows[0]:
            print(f"| {label} | {worst(key, low)} |")
    print(f"| lines not shown whole | {sum(r['hidden'] for r in rows)} of {sum(r['lines'] for r in rows)} |")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--half", choices=("report", "choose"), default="report")
    parser.add_argument("--rooms", type=int, default=20, help="rooms of the half (default 20)")
    parser.add_argument("--width", type=int, default=1024)
    parser.add_argument("--repeat", type=int, default=1)
    parser.add_argument("--photos", type=Path)
    args = parser.parse_args()
    first = 1 if args.half == "report" else 0
    seeds = list(range(first, first + 2 * args.rooms, 2))
    if seeds:
        print(f"box rooms, {args.half} half (seeds {seeds[0]}-{seeds[-1]}), {args.width} px")
        _summary(rooms(seeds, args.width, args.repeat))
    if args.photos is not None:
        print(f"\nphotos of {args.photos}, 2048 px")
        _summary(photos(args.photos, args.repeat))
    return 0


if __name__ == "__main__":
    sys.exit(main())
