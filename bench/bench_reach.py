#!/usr/bin/env python
"""A point handle's reach: what a turn and a zoom do with the distance from the handle.

Usage::

    python bench/bench_reach.py [--position 30,20] [--reach 15]

For a lone point handle at ``--position`` with the default options, one warp per zoom
(0.5, 0.7, 1.4, 2) and turn (0 to 90°) and the combinations, measured through the blend
(:func:`omniwidget.evaluate.quality.point_reach_profile`, 24 directions a ring):

- the magnification (one over the mean of the inverse map's singular values) within a third
  of the reach (worst against the asked zoom) and its range from a third to the reach;
- the rotation at a third, two thirds and the reach;
- the most the sphere moved beyond the reach;
- ``before``: the same with the ladder off (the whole map mixed with the identity), at 1°, 2° and 5°;

and the time of the method (``deform``) with and without the ladder, on the lone point
and on the 12-handle room of ``bench/bench_untangle.py``.
"""

from __future__ import annotations

import argparse
import time
from unittest import mock

import numpy as np

from omniwidget.document.handles import Handles, PointHandle
from omniwidget.evaluate.quality import point_reach_profile
from omniwidget.method import deformation
from omniwidget.method import reach as reach_module
from omniwidget.method.deformation import deform


def _without_ladder():  # the method as it was: no rings, no rungs
    return mock.patch.multiple(deformation, reach_samples=lambda handles: np.empty((0, 3)), with_reach=lambda h, c, v, w: (c, w))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--position", default="30,20")
    parser.add_argument("--reach", type=float, default=reach_module.DEFAULT_REACH)
    args = parser.parse_args()
    position = tuple(float(v) for v in args.position.split(","))
    r = args.reach
    print(f"lone point at {position}, reach {r}° ({r / 360 * 2048:.0f} px at 2048 wide; a third: {r / 3 / 360 * 2048:.0f} px)")
    print("zoom  turn | mag <R/3 (worst/asked) | mag R/3..R   | rot R/3  2R/3   R   | moved >R | before: mag at 1°,2°,5°  rot at 1°,2°,5°")
    for scale in (0.5, 0.7, 1.0, 1.4, 2.0):
        for turn in (0.0, 30.0, 45.0, 60.0, 80.0, 90.0):
            if scale == 1.0 and turn == 0.0:
                continue
            doc = Handles((PointHandle(position, scale=scale, rotation=turn, reach=args.reach),))
            d = deform(doc)
            inner = point_reach_profile(d, 0, r * np.linspace(0.05, 1 / 3, 6))["magnification"]
            worst = inner.flat[np.argmax(np.abs(inner / scale - 1))] / scale
            between = point_reach_profile(d, 0, r * np.linspace(1 / 3, 1, 31)[1:])
            rot = point_reach_profile(d, 0, r * np.array([1 / 3, 2 / 3, 0.999]))["rotation"].mean(axis=1)
            moved = point_reach_profile(d, 0, r * np.array([1.0, 1.1, 1.5, 2.0, 3.0]))["moved"].max()
            with _without_ladder():
                old = deform(doc)
            before = point_reach_profile(old, 0, [1.0, 2.0, 5.0])
            bm, br = before["magnification"].mean(axis=1), before["rotation"].mean(axis=1)
            print(
                f"{scale:4.1f} {turn:5.0f} | {worst:6.3f}                 | {between['magnification'].min():.3f}-"
                f"{between['magnification'].max():.3f} | {rot[0]:5.1f} {rot[1]:5.1f} {rot[2]:5.2f} | {moved:.4f}   |"
                f" {bm[0]:.2f} {bm[1]:.2f} {bm[2]:.2f}   {br[0]:5.1f} {br[1]:5.1f} {br[2]:5.1f}"
            )
    from omniwidget.evaluate.scenes import family_scene

    _, room, _ = family_scene("room_edges", 0, 1024)
    room = Handles((*room.handles, PointHandle((20.0, -20.0), scale=1.5, rotation=30.0)), room.options)
    for name, doc in (("lone point (2x, 45°)", Handles((PointHandle(position, scale=2.0, rotation=45.0),))), ("room + point", room)):
        times = {}
        for label, patch in (("ladder", None), ("before", _without_ladder)):
            best = np.inf
            for _ in range(3):
                if patch is None:
                    t = time.perf_counter()
                    d = deform(doc)
                else:
                    with patch():
                        t = time.perf_counter()
                        d = deform(doc)
                best = min(best, time.perf_counter() - t)
            times[label] = (best, len(d.vertices) if d.vertices is not None else 0, len(d.controls))
        print(name, ", ".join(f"{k}: {v[0]:.2f} s, {v[1]} vertices, {v[2]} controls" for k, v in times.items()))


if __name__ == "__main__":
    main()
