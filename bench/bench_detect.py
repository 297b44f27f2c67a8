#!/usr/bin/env python
"""Suggested lines and levelling against a plain detector on the six cube faces, run on demand (not a test).

Usage::

    python bench/bench_detect.py                 # 2048 x 1024, 5 runs each, in turns
    python bench/bench_detect.py --width 4096 --repeat 3
    python bench/bench_detect.py --detector hough

The input is a generated room (:func:`omniwidget.evaluate.scenes.synthetic_room`, grid,
noise, tilted) resampled to the width asked. Timed, in turns so that the shared machine's
load falls on all alike: the plain detector on the six cube faces (rendering the faces and
detecting, no lifting or merging: the floor the suggestions cannot go below),
:func:`omniwidget.suggest_lines` and :func:`omniwidget.level` (which detects too). Printed:
medians in seconds and each one's ratio to the plain detector.
"""

from __future__ import annotations

import argparse
import statistics
import time

import omniwidget as ow
from omniwidget.detect.lines import cube_views, detect_segments, panorama_gray, render_view
from omniwidget.evaluate.scenes import synthetic_room


def plain(image, detector: str) -> int:
    """The detector alone on the six cube faces; returns the number of segments."""
    gray = panorama_gray(image)
    return sum(len(detect_segments(render_view(gray, view), detector)[0]) for view in cube_views(gray.shape[1]))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--width", type=int, default=2048)
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--detector", choices=("lsd", "hough"), default="lsd")
    args = parser.parse_args()
    image = synthetic_room(args.width, grid=1.0, noise=4.0, seed=0, pitch=6.0, roll=-4.0).image
    runs = {
        "plain detector, 6 faces": lambda: plain(image, args.detector),
        "suggest_lines": lambda: ow.suggest_lines(image, detector=args.detector),
        "level": lambda: ow.level(image, suggestions=ow.suggest_lines(image, max_lines=None, detector=args.detector)),
    }
    times: dict[str, list[float]] = {name: [] for name in runs}
    for run in runs.values():  # warm up: imports, OpenCV's first calls
        run()
    for _ in range(args.repeat):
        for name, run in runs.items():
            start = time.perf_counter()
            run()
            times[name].append(time.perf_counter() - start)
    medians = {name: statistics.median(v) for name, v in times.items()}
    base = medians["plain detector, 6 faces"]
    print(f"{args.width} x {args.width // 2}, detector {args.detector}, medians of {args.repeat} runs in turns")
    for name, m in medians.items():
        print(
            f"  {name:26s} {m:7.3f} s  ({m / base:4.2f} x the plain detector; fastest {min(times[name]):.3f}, slowest {max(times[name]):.3f})"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
