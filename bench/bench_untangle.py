#!/usr/bin/env python
"""What never folding and never swirling cost: the warm 12-handle warp with and without the untangling and the fill, in one run.

Usage::

    python bench/bench_untangle.py [--repeat 7] [--seed 20240611]

The scene is ``bench/bench_blend.py``'s 12-handle room at 2048 x 1024 (8 lines rectified by
eq. (4), 2 points, a fixed cage), whose blend folds. Each round warps it warm (``previous=``
the last result, as the editor does) twice, interleaved: once as the default mode does now
(the blend filled in between the handles, :mod:`omniwidget.method.harmonic`, and the turned-over
patches untangled, :mod:`omniwidget.raster.untangle`) and once with both off
(``harmonic.FILL = False``, ``pipeline.UNTANGLE_ROUNDS = 0``: the warp with neither).
A warm warp of the same document reuses the weights, and with them the fill's grid; its
per-pixel part is in the time. ``--cold`` warps without ``previous=`` instead (the weights and
the fill solved each time). It prints the medians, their ratio (asked: at most 1.5),
the fold-over each leaves and the untangling's and the fill's own medians. Nothing is asserted;
the machine is shared, so only the ratio within one run means much.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
import warnings
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_blend import SEED, build_scene  # noqa: E402

from omniwidget.method import harmonic  # noqa: E402
from omniwidget.raster import pipeline  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=7)
    parser.add_argument("--seed", type=int, default=SEED)
    parser.add_argument("--cold", action="store_true", help="warp without previous= (weights and fill solved each time)")
    args = parser.parse_args(argv)
    warnings.simplefilter("ignore")
    image, handles = build_scene(args.seed)
    rounds, shares = pipeline.UNTANGLE_ROUNDS, pipeline.GIVE_WAY
    last = pipeline.warp(image, handles)
    times: dict[str, list[float]] = {"untangled": [], "as before": []}
    folds: dict[str, float] = {}
    untangle: list[float] = []
    fill: list[float] = []
    for _ in range(args.repeat):
        for name, n in (("untangled", rounds), ("as before", 0)):
            pipeline.UNTANGLE_ROUNDS, pipeline.GIVE_WAY, harmonic.FILL = n, shares if n else (), bool(n)
            start = time.perf_counter()
            result = pipeline.warp(image, handles, previous=None if args.cold else last)
            times[name].append(time.perf_counter() - start)
            folds[name] = result.folds.area
            if n:
                untangle.append(result.timings.get("untangle", 0.0))
                fill.append(result.timings.get("fill", 0.0) + result.timings.get("fill pixels", 0.0))
    pipeline.UNTANGLE_ROUNDS, pipeline.GIVE_WAY, harmonic.FILL = rounds, shares, True
    now, before = statistics.median(times["untangled"]), statistics.median(times["as before"])
    kind = "cold" if args.cold else "warm"
    print(f"12-handle scene at 2048 x 1024, seed {args.seed}, {args.repeat} {kind} warps each, interleaved")
    print(f"  filled and untangled (the default now): {now:.3f} s median, fold-over {100 * folds['untangled']:.4f}% of the sphere")
    print(f"  as before (neither):                    {before:.3f} s median, fold-over {100 * folds['as before']:.4f}% of the sphere")
    print(
        f"  ratio {now / before:.2f} (asked: at most 1.5); the untangling itself {statistics.median(untangle):.3f} s median, "
        f"the fill (its solve, where the weights were solved anew, and per pixel) {statistics.median(fill):.3f} s"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
