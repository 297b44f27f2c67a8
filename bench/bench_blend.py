#!/usr/bin/env python
"""Benchmark of the issue's "12-handle" blended warp, handles to output image, run on demand (not a test).

Usage::

    python bench/bench_blend.py                 # 5 timed warps, 5 runs of our bbw, 3 of igl.bbw
    python bench/bench_blend.py --repeat 9      # steadier medians
    python bench/bench_blend.py --seed 7        # another room turn, other lines and handles

What it measures (the issue: "a 12-handle scene at 2048 x 1024 in at most 2 s on a 2-core
machine; the paper reports 0.4 s per handle, about 4.8 s on a 4-core laptop"):

1. The scene: a :func:`~omniwidget.evaluate.scenes.synthetic_room` 2048 pixels wide turned by a
   seeded yaw; 8 of its straight lines whose image is bent by at least 5 px, picked at
   random as in ``tests/test_warp.py``, each rectified by eq. (4) (``rectify="each"``);
   2 point handles that move a few degrees, zoom and turn; one fixed 4-vertex cage about
   25 degrees wide; points and cage at least ``CLEARANCE`` degrees from every line sample
   and from each other. That is the issue's list: 8 + 2 + 1 = 11 handles (14 Möbius
   maps, one per cage vertex), not the 12 its title counts.
2. :func:`omniwidget.raster.pipeline.warp` of it, ``--repeat`` times after one untimed
   warm-up: the median of every stage in ``Result.timings``, the median total wall time
   (``time.perf_counter`` around ``warp``) and CPU time (``time.process_time``, all
   threads; CPU / wall shows how much the threads helped on a shared machine), the mesh
   size, the numbers of controls and constrained vertices, and the warp's warnings.
3. On that mesh with those boundary conditions, :func:`omniwidget.method.bbw.bbw` (median of
   ``--repeat``) beside ``igl.bbw`` through :mod:`omniwidget.method._igl` (median of
   ``--igl-repeat``), their ratio and the largest difference of the normalised weights.

Nothing is asserted; the exit status is 0 whatever the figures (a scene that cannot be
built as described raises instead).
"""

from __future__ import annotations

import argparse
import gc
import os
import statistics
import sys
import time
import warnings
from collections.abc import Callable
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

REPO_ROOT = Path(__file__).resolve().parents[1]
# Run from a checkout without installing: make ``import omniwidget`` find the repository.
sys.path.insert(0, str(REPO_ROOT))

from omniwidget.document.handles import CageHandle, Handles, LineHandle, Options, PointHandle  # noqa: E402
from omniwidget.evaluate.quality import straightness  # noqa: E402
from omniwidget.evaluate.scenes import synthetic_room  # noqa: E402
from omniwidget.method.bbw import bbw, normalize_rows  # noqa: E402
from omniwidget.raster.pipeline import Result, warp  # noqa: E402
from omniwidget.sphere import coords  # noqa: E402

WIDTH = 2048
SEED = 20240611
LINES = 8
CLEARANCE = 10.0  # degrees from every line sample (and between points and cage)
CAGE_HALF = 12.5  # degrees: the cage spans about 25 degrees each way
TARGET_S = 2.0  # the target on 2 cores
PAPER_S = 4.8  # the issue: 0.4 s per handle, "about 4.8 s for this scene", 4-core laptop
#: The issue's names of the stages in ``Result.timings``; other stages print under their own key.
LABELS = {"weights": "weights (bbw)", "locate": "interpolation (locate)"}


def _far(points: NDArray, others: NDArray) -> bool:
    """Whether every one of ``points`` is at least ``CLEARANCE`` degrees from all ``others``."""
    return bool(coords.angular_distance(points[:, None, :], others[None, :, :]).min() >= CLEARANCE)


def _box(lon: float, lat: float) -> NDArray:
    """Corners, counter-clockwise, of a lon/lat box about ``2 * CAGE_HALF`` degrees wide (in angle) centred at ``(lon, lat)``."""
    dlon = CAGE_HALF / np.cos(np.radians(lat))
    box = np.array(
        [[lon - dlon, lat - CAGE_HALF], [lon + dlon, lat - CAGE_HALF], [lon + dlon, lat + CAGE_HALF], [lon - dlon, lat + CAGE_HALF]]
    )
    box[:, 0] = coords.wrap_lon(box[:, 0])  # handles want longitudes in [-180, 180]
    return box


def build_scene(seed: int) -> tuple[NDArray[np.uint8], Handles]:
    """The room image and its handles: 8 rectified lines, 2 moving points, a fixed 4-vertex cage."""
    rng = np.random.default_rng(seed)
    scene = synthetic_room(WIDTH, size=(4.0, 3.0, 3.0), camera=(0.3, -0.2, -1.0), yaw=float(rng.uniform(0, 90)))
    t = np.linspace(0, 1, 200)
    bent = [
        ln for ln in scene.lines_where(max_abs_lat=70, max_length=100) if straightness(coords.geodesic(ln.start, ln.end, t), WIDTH) >= 5
    ]
    if len(bent) < LINES:
        raise RuntimeError(f"only {len(bent)} lines of the room are bent >= 5 px; {LINES} are needed")
    lines = [LineHandle(bent[i].start, bent[i].end) for i in sorted(rng.choice(len(bent), size=LINES, replace=False))]
    # every line sample, before and after rectification
    taken = np.concatenate(
        [coords.geodesic(h.start, h.end, t) for h in lines] + [h.moebius()(coords.geodesic(h.start, h.end, t)) for h in lines]
    )
    lon, lat = np.meshgrid(np.arange(-180.0, 180.0, 5.0), np.arange(-60.0, 61.0, 5.0))
    points: list[PointHandle] = []
    for c in rng.permutation(np.c_[lon.ravel(), lat.ravel()]):
        if len(points) < 2:
            target = np.array([coords.wrap_lon(c[0] + rng.uniform(3, 6)), c[1] + rng.uniform(-4, 4)])
            if _far(np.array([c, target]), taken):
                rotation, scale = rng.uniform(-20, 20), rng.uniform(0.8, 1.25)
                points.append(PointHandle(tuple(c.tolist()), tuple(target.tolist()), rotation=float(rotation), scale=float(scale)))
                taken = np.vstack([taken, c, target])
        elif abs(c[1]) <= 50:
            box = _box(*c)
            if _far(np.concatenate([coords.geodesic(box[i], box[(i + 1) % 4], t[::10]) for i in range(4)]), taken):
                corners = tuple(map(tuple, box.tolist()))
                return scene.image, Handles((*lines, *points, CageHandle(corners, targets=corners)), Options(rectify="each"))
    raise RuntimeError("no room left for the points and the cage away from the lines")


def timed(fn: Callable[[], object], repeat: int) -> tuple[list[float], list[float], list[object]]:
    """Wall and CPU times of ``repeat`` calls of ``fn``, and their results."""
    walls, cpus, results = [], [], []
    for _ in range(repeat):
        gc.collect()
        wall, cpu = time.perf_counter(), time.process_time()
        results.append(fn())
        walls.append(time.perf_counter() - wall)
        cpus.append(time.process_time() - cpu)
    return walls, cpus, results


def describe(walls: list[float], cpus: list[float]) -> str:
    """Median wall time, fastest and slowest, median CPU time."""
    n = len(walls)
    return (
        f"{statistics.median(walls):.3f} s (median of {n}, min {min(walls):.3f}, max {max(walls):.3f}; CPU {statistics.median(cpus):.3f} s)"
    )


def bench_warp(image: NDArray, handles: Handles, repeat: int) -> Result:
    """Time ``warp`` after one untimed warm-up; print its stages and totals; return the last result."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # printed from Result.warnings instead
        warp(image, handles)
        walls, cpus, results = timed(lambda: warp(image, handles), repeat)
    result = results[-1]
    if result.weights is None:
        raise RuntimeError("the warp took the single-map path: no blend was timed")
    print(f"mesh: {len(result.vertices)} vertices, {len(result.faces)} faces; {len(result.controls)} controls; ", end="")
    print(f"{len(result.constrained)} constrained vertices")
    print(f"warnings: {len(result.warnings)}" + "".join(f"\n  - {w}" for w in result.warnings))
    print(f"\n== warp(), {repeat} timed runs after one warm-up: medians ==")
    for key in result.timings:
        print(f"  {LABELS.get(key, key):<24}{statistics.median(r.timings.get(key, 0.0) for r in results):7.3f} s")
    wall, cpu = statistics.median(walls), statistics.median(cpus)
    outside = statistics.median(w - sum(r.timings.values()) for w, r in zip(walls, results, strict=True))
    print(f"  {'outside the stages':<24}{outside:7.3f} s")
    print(f"  {'total':<26}{describe(walls, cpus)}")
    print(f"  target <= {TARGET_S:g} s on 2 cores; paper ~{PAPER_S:g} s on 4 cores (0.4 s per handle)")
    print(f"  CPU / wall = {cpu / wall:.2f} on {os.cpu_count()} CPUs; {wall / len(handles):.3f} s per handle")
    return result


def bench_bbw(result: Result, repeat: int, igl_repeat: int) -> None:
    """Our bbw and igl.bbw on the warp's mesh and boundary conditions."""
    v, f, b, bc = result.vertices, result.faces, result.constrained, result.prescribed
    print(f"\n== BBW on the warp's mesh: {len(v)} vertices, {len(b)} constrained, {bc.shape[1]} controls ==")
    walls, cpus, out = timed(lambda: bbw(v, f, b, bc), repeat)
    w = out[-1]
    print(f"omniwidget bbw: {describe(walls, cpus)}")
    print(f"  max |normalised W - Result.weights| = {np.abs(normalize_rows(w) - result.weights).max():.2e}")
    try:
        from omniwidget.method._igl import igl_bbw, igl_version

        igl_walls, igl_cpus, igl_out = timed(lambda: igl_bbw(v, f, b, bc), igl_repeat)
    except ImportError as exc:
        print(f"igl.bbw: skipped ({exc})")
        return
    w_igl = igl_out[-1]
    print(f"igl.bbw (libigl {igl_version()}): {describe(igl_walls, igl_cpus)}")
    print(f"ratio igl / omniwidget: {statistics.median(igl_walls) / statistics.median(walls):.1f}x (medians of wall time)")
    print(
        f"max |W - W_igl| = {np.abs(w - w_igl).max():.2e} raw, {np.abs(normalize_rows(w) - normalize_rows(w_igl)).max():.2e} rows normalised"
    )


def main(argv: list[str] | None = None) -> int:
    """Build the scene, time the warps and the two BBW solvers, print the figures."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5, help="timed warps and runs of our bbw (default 5)")
    parser.add_argument("--igl-repeat", type=int, default=3, help="timed runs of igl.bbw (default 3)")
    parser.add_argument("--seed", type=int, default=SEED, help=f"seed of the room's turn and of the handles (default {SEED})")
    args = parser.parse_args(argv)
    if args.repeat < 1 or args.igl_repeat < 1:
        parser.error("--repeat and --igl-repeat must be at least 1")
    print(f"omniwidget blend benchmark: Python {sys.version.split()[0]}, numpy {np.__version__}")
    print(f"CPUs: {os.cpu_count()}; load average before starting: {', '.join(f'{x:.2f}' for x in os.getloadavg())} (1, 5, 15 min)")
    image, handles = build_scene(args.seed)
    counts = tuple(sum(h.kind == k for h in handles.handles) for k in ("line", "point", "cage"))
    corners = sum(len(h.vertices) for h in handles.handles if isinstance(h, CageHandle))
    print(f"\nscene (seed {args.seed}): {image.shape[1]} x {image.shape[0]} room; {len(handles)} handles: ", end="")
    print(f"{counts[0]} lines (rectify='each'), {counts[1]} points, {counts[2]} cage of {corners} vertices")
    if counts != (LINES, 2, 1) or corners != 4:
        raise RuntimeError(f"the scene has {counts} lines, points, cages and {corners} cage vertices, not (8, 2, 1) and 4")
    result = bench_warp(image, handles, args.repeat)
    bench_bbw(result, args.repeat, args.igl_repeat)
    return 0


if __name__ == "__main__":
    sys.exit(main())
