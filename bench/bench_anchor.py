#!/usr/bin/env python
"""The still background's figures: the still background (``options.anchor``) against the paper's method on the same handles.

Usage::

    python bench/bench_anchor.py [--anchor DEGREES] [--width 2048] [--held-out]

For each of ``scenes.LINED_ROOMS`` (6 to 10 marked lines, rectified "all"): the quality
figures of both (``Result.quality``, with the far field's: farther than 30° from every line) and the median time of a warp (5 runs each, the two
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

from omniwidget.document.handles import SUGGESTED_ANCHOR, Handles, LineHandle, Options  # noqa: E402
from omniwidget.evaluate.scenes import LINED_ROOMS, lined_room  # noqa: E402
from omniwidget.raster.pipeline import warp  # noqa: E402

#: Rooms that took no part in choosing the defaults: seed and number of lines.
HELD_OUT = ((6, 6), (7, 7), (8, 8), (9, 9), (10, 10), (11, 8), (12, 6), (13, 10))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--anchor", type=float, default=SUGGESTED_ANCHOR)
    parser.add_argument("--width", type=int, default=2048)
    parser.add_argument("--held-out", action="store_true", help="rooms not used to choose the defaults (seeds 6-13)")
    args = parser.parse_args()
    rooms = HELD_OUT if args.held_out else LINED_ROOMS
    warnings.simplefilter("ignore")
    print(
        "| room | lines | method | worst line px | fold-over | coverage | distortion mean / p99 | displacement ° | far field: share, moved °, distortion p99 | warp s |"
    )
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    ratios = []
    for seed, n in rooms:
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
                f"{q.distortion_mean:.3f} / {q.distortion_p99:.2f} | {q.displacement:.2f} | "
                f"{100 * q.far.share:.0f}%, {q.far.displacement:.2f}, {q.far.distortion_p99:.2f} | {statistics.median(times[name]):.3f} |"
            )
        ours, theirs = (statistics.median(t) for t in times.values())
        ratios.append(ours / theirs)
    print(f"\nwarp time with the background / without, median over the rooms: {statistics.median(ratios):.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
