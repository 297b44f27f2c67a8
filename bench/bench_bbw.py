#!/usr/bin/env python
"""Benchmark of omniwidget's bounded biharmonic weights against libigl's, run on demand (not a test).

Usage::

    python bench/bench_bbw.py               # both meshes, 5 runs of bbw, igl 3 runs (2k) and 1 run (10k)
    python bench/bench_bbw.py --repeat 9    # more runs of bbw: steadier medians
    python bench/bench_bbw.py --igl-repeat 3  # also 3 runs of igl on the 10k mesh (about 10-15 s each)
    python bench/bench_bbw.py --layout lines  # "bone" handles (chains of vertices) instead of points

What it measures, on two meshes of the unit sphere with 10 handles:

* a ~2,000-vertex mesh: the convex hull of 2,000 Fibonacci-sphere points;
* the 10,242-vertex icosphere (an icosahedron split 1-to-4 five times).

For each: :func:`omniwidget.method.bbw.bbw` with its default threads and with one thread,
and ``igl.bbw`` (libigl's active set, which uses its own threads), all in this process on
the same mesh and constraints; the times are medians (after one untimed warm-up of ours),
the ratio is igl's median over ours, and the largest difference of the weights is printed
beside them. Also the work our solver did: its mesh levels and its factorizations of
``Q_II`` per handle on the input mesh. Nothing is asserted; the exit status is 0 whatever
the figures (a later issue wants ours 10x faster than libigl).
"""

from __future__ import annotations

import argparse
import gc
import math
import os
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra
from scipy.spatial import ConvexHull

REPO_ROOT = Path(__file__).resolve().parents[1]
# Run from a checkout without installing: make ``import omniwidget`` find the repository.
sys.path.insert(0, str(REPO_ROOT))

from omniwidget.method import bbw as bbw_module  # noqa: E402

HANDLES = 10
SEED = 20201121


# --------------------------------------------------------------------------------------
# Meshes and handles
# --------------------------------------------------------------------------------------
def _outward(v: NDArray[np.float64], f: NDArray[np.int64]) -> NDArray[np.int64]:
    a, b, c = (v[f[:, i]] for i in range(3))
    flip = np.einsum("ij,ij->i", np.cross(b - a, c - a), a + b + c) < 0
    f = f.copy()
    f[flip] = f[flip][:, [0, 2, 1]]
    return f


def icosphere(level: int) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """The icosahedron split 1-to-4 ``level`` times, new vertices pushed onto the unit sphere."""
    t = (1 + 5**0.5) / 2
    v = np.array([[s1, s2 * t, 0] for s1 in (-1, 1) for s2 in (-1, 1)], dtype=np.float64)
    v = np.vstack([v, np.roll(v, 1, axis=1), np.roll(v, 2, axis=1)])
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    f = _outward(v, ConvexHull(v).simplices.astype(np.int64))
    for _ in range(level):
        edges = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
        unique, inverse = np.unique(edges, axis=0, return_inverse=True)
        mid = v[unique[:, 0]] + v[unique[:, 1]]
        v = np.vstack([v, mid / np.linalg.norm(mid, axis=1, keepdims=True)])
        m = f.shape[0]
        e = len(v) - len(unique) + inverse.ravel()
        ab, bc, ca = e[:m], e[m : 2 * m], e[2 * m :]
        f = np.vstack([np.c_[f[:, 0], ab, ca], np.c_[f[:, 1], bc, ab], np.c_[f[:, 2], ca, bc], np.c_[ab, bc, ca]])
    return v, f


def fibonacci_sphere(n: int) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """``n`` quasi-uniform points on the unit sphere triangulated by their convex hull."""
    i = np.arange(n) + 0.5
    z = 1 - 2 * i / n
    phi = math.pi * (1 + 5**0.5) * i
    r = np.sqrt(1 - z * z)
    v = np.c_[r * np.cos(phi), r * np.sin(phi), z]
    return v, _outward(v, ConvexHull(v).simplices.astype(np.int64))


def point_handles(v: NDArray[np.float64]) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """``HANDLES`` single-vertex handles at random vertices: weight 1 on their own, 0 on the others."""
    b = np.random.default_rng(SEED).choice(len(v), size=HANDLES, replace=False).astype(np.int64)
    return b, np.eye(HANDLES)


def line_handles(v: NDArray[np.float64], f: NDArray[np.int64]) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """``HANDLES`` disjoint chains of vertices (shortest edge paths ~20 degrees long), weight 1 along their own."""
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    g = csr_matrix((np.linalg.norm(v[e[:, 0]] - v[e[:, 1]], axis=1), (e[:, 0], e[:, 1])), shape=(len(v), len(v)))
    rng = np.random.default_rng(SEED)
    used: set[int] = set()
    chains: list[list[int]] = []
    while len(chains) < HANDLES:
        start = int(rng.integers(len(v)))
        dist, pred = dijkstra(g, directed=False, indices=start, return_predecessors=True)
        end = int(np.argmin(np.abs(dist - math.radians(20))))
        path = [end]
        while path[-1] != start:
            path.append(int(pred[path[-1]]))
        near = set(path) | {int(w) for p in path for w in g[p].indices}
        if near & used:
            continue
        used |= near
        chains.append(path)
    b = np.concatenate(chains).astype(np.int64)
    bc = np.zeros((b.size, HANDLES))
    bc[np.arange(b.size), np.repeat(np.arange(HANDLES), [len(c) for c in chains])] = 1.0
    return b, bc


# --------------------------------------------------------------------------------------
# Timing
# --------------------------------------------------------------------------------------
def timed(fn: Callable[[], object], runs: int, warmup: int) -> tuple[list[float], object]:
    """Wall times of ``runs`` calls after ``warmup`` untimed ones, and the last result."""
    result = None
    times = []
    for i in range(warmup + runs):
        gc.collect()
        start = time.perf_counter()
        result = fn()
        if i >= warmup:
            times.append(time.perf_counter() - start)
    return times, result


def describe(times: list[float]) -> str:
    if len(times) == 1:
        return f"{times[0]:7.3f} s (1 run)"
    return f"{statistics.median(times):7.3f} s (median of {len(times)}, min {min(times):.3f}, max {max(times):.3f})"


def bench_mesh(name: str, v: NDArray[np.float64], f: NDArray[np.int64], layout: str, repeat: int, igl_runs: int) -> None:
    b, bc = point_handles(v) if layout == "points" else line_handles(v, f)
    print(f"\n== {name}: {len(v)} vertices, {len(f)} faces, {bc.shape[1]} {layout} handles ({len(b)} constrained vertices) ==")
    ours, (w, info) = timed(lambda: bbw_module._bbw(v, f, b, bc), repeat, warmup=1)
    ours_1, _ = timed(lambda: bbw_module._bbw(v, f, b, bc, bbw_module._Settings(workers=1)), repeat, warmup=0)
    levels = " -> ".join(str(lv["vertices"]) for lv in reversed(info["levels"]))
    finest = info["levels"][-1]
    print(f"omniwidget bbw ({info['workers']} threads): {describe(ours)}")
    print(f"omniwidget bbw (1 thread):  {describe(ours_1)}")
    print(
        f"  levels {levels} vertices; on the input mesh {statistics.mean(finest['steps']):.1f} global steps and "
        f"{statistics.mean(finest['factorizations']):.1f} factorizations per handle"
    )
    try:
        from omniwidget.method._igl import igl_bbw, igl_version

        theirs, w_igl = timed(lambda: igl_bbw(v, f, b, bc), igl_runs, warmup=0)
    except ImportError as exc:
        print(f"igl.bbw: skipped ({exc})")
        return
    print(f"igl.bbw (libigl {igl_version()}):  {describe(theirs)}")
    ratio = statistics.median(theirs) / statistics.median(ours)
    ratio_1 = statistics.median(theirs) / statistics.median(ours_1)
    print(f"ratio igl / omniwidget: {ratio:.1f}x ({ratio_1:.1f}x against one thread)")
    print(f"max |W - W_igl| = {np.abs(w - np.asarray(w_igl)).max():.2e}")


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5, help="timed runs of omniwidget's bbw per mesh (default 5)")
    parser.add_argument("--igl-repeat", type=int, default=1, help="timed runs of igl.bbw on the 10k mesh (default 1; 3 on the 2k mesh)")
    parser.add_argument("--layout", choices=("points", "lines"), default="points", help="handle layout (default points)")
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    """Run both meshes and print the figures."""
    args = parse_args(argv)
    print(f"omniwidget bbw benchmark: Python {sys.version.split()[0]}, numpy {np.__version__}")
    print(f"CPUs: {os.cpu_count()}; load average before starting: {', '.join(f'{x:.2f}' for x in os.getloadavg())} (1, 5, 15 min)")
    bench_mesh("~2k mesh (Fibonacci sphere hull)", *fibonacci_sphere(2000), args.layout, args.repeat, max(3, args.igl_repeat))
    bench_mesh("10k mesh (icosphere level 5)", *icosphere(5), args.layout, args.repeat, args.igl_repeat)
    return 0


if __name__ == "__main__":
    sys.exit(main())
