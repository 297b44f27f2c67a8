#!/usr/bin/env python
"""Which straightening map disturbs least, measured.

Usage::

    python bench/bench_line_maps.py [--width 2048]

A line is as straight for any three targets on one straight segment, so which control
point stays and where the segment lies are a choice (``rectify.solve_bones``'s ``keep``):

- ``endpoints``: the paper's eqs. (9)-(10), the endpoints stay and the middle goes to the
  chord's middle;
- ``points``: the middle goes to the chord where it projects, and all three points share
  the correction;
- ``sphere``: as ``points``, and the lines' maps also move the sphere within
  ``rectify.NEAR_LINE`` degrees of each line least (``rectify.motion_metric``).

Each is run on ``scenes.LINED_ROOMS`` with the still background, with and without its
easing (``background.ease_background``), and measured: how far each line's own map moves the
sphere within 4° and 10° of the line (mean over the lines), and the whole warp's figures
(``Result.quality``). Run on demand, not a test: it swaps the choice in by patching the
function that makes it.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import warnings
from pathlib import Path
from unittest import mock

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from omniwidget.document.handles import SUGGESTED_ANCHOR, Handles, LineHandle, Options  # noqa: E402
from omniwidget.evaluate.scenes import LINED_ROOMS, lined_room  # noqa: E402
from omniwidget.method import constraints, deformation, rectify  # noqa: E402
from omniwidget.raster import pipeline


def near_motion(result, radius: float) -> float:
    """Mean over the lines of the mean distance (degrees) each line's map moves the sphere within ``radius`` of it."""
    moves = []
    for control, samples in result.constraints.lines:
        xyz, area = rectify.line_neighbourhood(samples[0], samples[-1], radius)
        moved = result.controls[control].moebius.apply_xyz(xyz)
        moves.append(float(np.sum(area * np.degrees(np.arccos(np.clip(np.sum(moved * xyz, axis=1), -1.0, 1.0))))))
    return statistics.mean(moves)


def run(image, doc, keep: str, ease: bool):
    solve = rectify.solve_bones

    def chosen(*args, **kwargs):
        kwargs["keep"] = keep
        return solve(*args, **kwargs)

    with mock.patch.object(constraints, "solve_bones", chosen):
        if ease:
            return pipeline.warp(image, doc)
        with mock.patch.object(deformation, "ease_background", lambda weights, power=1.0: weights):
            return pipeline.warp(image, doc)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--width", type=int, default=2048)
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    choices = [("endpoints", False), ("points", False), ("sphere", False), ("points", True), ("sphere", True)]
    print(
        "| keep | eased | room | moved within 4° / 10° of the lines | distortion mean / p99 | displacement ° | far field moved ° | fold-over |"
    )
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    worst = {}
    for seed, n in LINED_ROOMS:
        scene, lines = lined_room(seed, n, args.width)
        doc = Handles(tuple(LineHandle(x.start, x.end) for x in lines), Options(rectify="all", anchor=SUGGESTED_ANCHOR))
        for keep, ease in choices:
            result = run(scene.image, doc, keep, ease)
            q = result.quality
            worst[(keep, ease)] = max(worst.get((keep, ease), 0.0), q.distortion_p99)
            print(
                f"| {keep} | {'yes' if ease else 'no'} | {seed} ({n} lines) | {near_motion(result, 4.0):.2f} / {near_motion(result, 10.0):.2f} | "
                f"{q.distortion_mean:.3f} / {q.distortion_p99:.3f} | {q.displacement:.3f} | {q.far.displacement:.4f} | {100 * q.fold_over:.3f}% |"
            )
    print("\nworst p99 over the rooms: " + ", ".join(f"{k} {'eased' if e else 'plain'} {v:.3f}" for (k, e), v in worst.items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
