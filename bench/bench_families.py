#!/usr/bin/env python
"""How long ``scenes.family_scene`` takes to make a scene's handles at a tiny width (no rendering at full size).

Usage::

    python bench/bench_families.py [--seeds 3] [--width 16]

Prints, per family (``suggested`` left out: it runs the detector on a 2048 render), the median and
the largest time over the seeds, and the same over every family. ``tests/test_fidelity.py`` checks
what the scenes are; this measures how long they take (no test asserts a wall-clock time).
"""

from __future__ import annotations

import argparse
import statistics
import time

from omniwidget.evaluate.scenes import FAMILIES, family_scene


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--width", type=int, default=16)
    args = parser.parse_args()
    every = []
    for family in FAMILIES:
        if family == "suggested":
            continue
        times = []
        for seed in range(args.seeds):
            start = time.perf_counter()
            family_scene(family, seed, args.width)
            times.append(time.perf_counter() - start)
        every += times
        print(f"{family:12s} median {statistics.median(times):.3f} s, max {max(times):.3f} s")
    print(f"{'all':12s} median {statistics.median(every):.3f} s, max {max(every):.3f} s")


if __name__ == "__main__":
    main()
