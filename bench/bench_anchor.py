#!/usr/bin/env python
"""Issue 9's figures: the still background (``options.anchor``) against the paper's method on the same handles.

Usage::

    python bench/bench_anchor.py [--anchor DEGREES] [--width 2048]

For each of ``scenes.LINED_ROOMS`` (6 to 10 marked lines, rectified "all"): the quality
figures of both (``Result.quality``) and the median time of a warp (5 runs each, the two
interleaved in one process), then the ratio of the times. Run on demand, not a test.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
import warnings
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from omniwidget.core.handles import SUGGESTED_ANCHOR, Handles, LineHandle, Options  # noqa: E402
from omniwidget.core.pipeline import warp  # noqa: E402
from omniwidget.core.scenes import LINED_ROOMS, lined_room  # noqa: E402


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--anchor", type=float, default=SUGGESTED_ANCHOR)
    parser.add_argument("--width", type=int, default=2048)
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    print("| room | lines | method | worst line px | fold-over | coverage | distortion mean / p99 | displacement ° | warp s |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    ratios = []
    for seed, n in LINED_ROOMS:
        scene, lines = lined_room(seed, n, args.width)
        docs = {
            f"anchor {args.anchor:g}": Handles(
                tuple(LineHandle(x.start, x.end) for x in lines), Options(rectify="all", anchor=args.anchor)
            ),
            "paper (null)": Handles(tuple(LineHandle(x.start, x.end) for x in lines), Options(rectify="all", anchor=None)),
        }
        times: dict[str, list[float]] = {k: [] for k in docs}
        results = {}
        for _ in range(5):
            for name, doc in docs.items():
                start = time.perf_counter()
                results[name] = warp(scene.image, doc)
                times[name].append(time.perf_counter() - start)
        for name, result in results.items():
            q = result.quality
            print(
                f"| {seed} | {len(lines)} | {name} | {q.straightness:.2f} | {100 * q.fold_over:.3f}% | {100 * q.coverage:.2f}% | "
                f"{q.distortion_mean:.3f} / {q.distortion_p99:.2f} | {q.displacement:.2f} | {statistics.median(times[name]):.3f} |"
            )
        ours, theirs = (statistics.median(t) for t in times.values())
        ratios.append(ours / theirs)
    print(f"\nwarp time with the background / without, median over the rooms: {statistics.median(ratios):.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
