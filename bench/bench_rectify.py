#!/usr/bin/env python
"""Benchmark of the rectify-all solve (Sec. 3.4), run on demand (not a test).

Usage::

    python bench/bench_rectify.py              # 20 lines, 50 samples, 21 runs
    python bench/bench_rectify.py --lines 40 --samples 100

What it measures: on a synthetic room at 2048 x 1024, ``--lines`` lines marked as a
person would (:func:`omniwidget.evaluate.scenes.mark_lines`), all rectified together.
The median time of :func:`omniwidget.method.rectify.solve_bones` alone (building the
least-squares terms and solving), of the whole of ``build_constraints`` (which also splits
crossings, finds joints and builds every control's map and boundary conditions), and the
stage times of one whole warp beside them. The paper reports 0.11 s for its example; the
target here is 50 ms for 20 lines. Nothing is asserted.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from omniwidget.document.handles import Handles, LineHandle  # noqa: E402
from omniwidget.evaluate.scenes import mark_lines, synthetic_room  # noqa: E402
from omniwidget.method.constraints import build_constraints  # noqa: E402
from omniwidget.method.rectify import Bone, solve_bones  # noqa: E402
from omniwidget.raster.pipeline import warp  # noqa: E402


def median_time(fn, repeat: int) -> float:
    fn()
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--lines", type=int, default=20)
    parser.add_argument("--samples", type=int, default=50)
    parser.add_argument("--repeat", type=int, default=21)
    args = parser.parse_args()

    scene = synthetic_room(2048, size=(6.0, 4.0, 3.0), camera=(0.3, -0.2, -0.8), grid=0.5)
    lines = mark_lines(scene, args.lines, seed=1, separation=3.0, piece=30.0)
    doc = Handles(tuple(LineHandle(line.start, line.end) for line in lines))
    bones = [Bone(line.start, line.end, True) for line in lines]
    solution = solve_bones(bones, samples=args.samples)
    print(f"{len(lines)} lines (asked {args.lines}), {args.samples} samples each; {solution.matrix.shape[0]} unknowns per coordinate")
    solve = median_time(lambda: solve_bones(bones, samples=args.samples), args.repeat)
    build = median_time(lambda: build_constraints(doc, samples=args.samples), max(3, args.repeat // 3))
    print(f"solve_bones            {1000 * solve:7.1f} ms (median of {args.repeat}; target 50 ms, paper 110 ms)")
    print(f"build_constraints      {1000 * build:7.1f} ms (crossings, joints, solve, maps, boundary conditions)")
    print(f"mean displacement of the endpoints: {solution.displacement:.3f} deg")
    result = warp(scene.image, doc, samples=args.samples)
    print("one warp at 2048 x 1024:")
    for stage, seconds in result.timings.items():
        print(f"  {stage:22s} {seconds:7.3f} s")
    print(f"  {'total':22s} {sum(result.timings.values()):7.3f} s; fold-over {100 * result.folds.area:.3f}% of the sphere")
    print(f"  {len(result.warnings)} warning(s)" + "".join(f"\n    - {w}" for w in result.warnings))


if __name__ == "__main__":
    main()
