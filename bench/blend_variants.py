#!/usr/bin/env python
"""Our blend of eq. (2) beside the authors' two shortcuts, on the test rooms, run on demand (not a test).

Usage::

    python bench/blend_variants.py                      # all six scenes, a few minutes on 2 cores
    python bench/blend_variants.py --scenes 1-6 3-12    # only these (names as printed)
    python bench/blend_variants.py --grid 300           # a finer weight grid for the authors' variants

The scenes are those of ``tests/test_blend.py`` at 2048 x 1024: rooms turned by seeds 1, 6,
2 and 3 with 6, 12, 9 and 12 lines marked by :func:`~omniwidget.evaluate.scenes.mark_lines`
(``rectify="each"``); for seeds 1 and 6 the lines kept clear of the tests' fixed CAGE and
moved POINT, warped once with lines only and once with the cage and point added.

Each scene is warped once (:func:`~omniwidget.raster.pipeline.warp`); on its mesh and weights,
four inverse maps are evaluated in double precision (``blended_inverse``):

* ``ours``: weights barycentric from the mesh at every pixel, the 3D sum normalised;
* ``asin``: the same weights, latitude = ``asin`` of the un-normalised sum's ``z``;
* ``grid``: weights bilinear from a 150 x 75 lon/lat grid, the sum normalised;
* ``authors``: both shortcuts (the paper's implementation).

Per variant: over the lines, median and max of ``line_straightness`` (best fit, px at 2048)
and of its excess over the line's own Möbius map alone; the lines the map does not show
whole (NaN, left out of the medians) and those with a sample found in a fold-over (``in
fold``: the input is shown twice there and :func:`~omniwidget.evaluate.quality.forward_points`
may find the other copy, so the figure measures the fold, not a bent line); the fold-over
area (% of the sphere); the conformal distortion's mean and p99 (within 80 degrees
latitude); and, against ``ours``, the area-weighted mean and the max of ``|Δlat|`` and the
mean shift towards the equator (``|lat_ours| - |lat|``), degrees.
Nothing is asserted; the exit status is 0 whatever the figures.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import warnings
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

REPO_ROOT = Path(__file__).resolve().parents[1]
# Run from a checkout without installing: make ``import omniwidget`` find the repository.
sys.path.insert(0, str(REPO_ROOT))

from omniwidget.document.handles import CageHandle, Handles, LineHandle, Options, PointHandle  # noqa: E402
from omniwidget.evaluate.quality import conformal_distortion, fold_over, forward_points, line_straightness, straightness  # noqa: E402
from omniwidget.evaluate.scenes import mark_lines, synthetic_room  # noqa: E402
from omniwidget.method.locate import locate_grid  # noqa: E402
from omniwidget.raster.blend import blended_inverse, grid_pixel_weights, mesh_pixel_weights  # noqa: E402
from omniwidget.raster.pipeline import Result, warp  # noqa: E402
from omniwidget.raster.warping import inverse_lonlat  # noqa: E402
from omniwidget.sphere import coords  # noqa: E402

W = 2048
# As in tests/test_blend.py: a fixed cage and a moved point where no line passes.
CAGE = ((-150.0, -20.0), (-120.0, -20.0), (-120.0, 10.0), (-150.0, 10.0))
POINT = PointHandle((-60.0, -30.0), target=(-55.0, -27.0), scale=1.1, rotation=10.0)
KEEP_CLEAR = ((np.array((*CAGE, (-135.0, -5.0))), 12.0), (np.array([POINT.position, POINT.target]), 12.0))
#: name -> (seed, lines, with the cage and point); seeds 1 and 6 keep their lines clear of both.
SCENES = {
    "1-6": (1, 6, False),
    "1-6+cage+point": (1, 6, True),
    "6-12": (6, 12, False),
    "6-12+cage+point": (6, 12, True),
    "2-9": (2, 9, False),
    "3-12": (3, 12, False),
}
VARIANTS = ("ours", "asin", "grid", "authors")  # (grid weights?, projection) below
SETUP = {"ours": (False, "normalize"), "asin": (False, "asin"), "grid": (True, "normalize"), "authors": (True, "asin")}


def build(seed: int, n_lines: int, extras: bool) -> Result:
    """Warp the room of ``seed`` with its marked lines (and the cage and point) as the tests do."""
    rng = np.random.default_rng(seed)
    scene = synthetic_room(W, size=(4.0, 3.0, 3.0), camera=(0.3, -0.2, -1.0), yaw=float(rng.uniform(0, 90)))
    lines = mark_lines(scene, n_lines, seed=seed, keep_clear=KEEP_CLEAR if seed in (1, 6) else ())
    more = (CageHandle(CAGE), POINT) if extras else ()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # fold-overs are measured below, per variant
        return warp(scene.image, Handles((*(LineHandle(ln.start, ln.end) for ln in lines), *more), Options(rectify="each")))


def variant_maps(result: Result, grid: int) -> dict[str, NDArray[np.float64]]:
    """The four float64 inverse maps (H, W, 2) on the warp's mesh and weights."""
    face, bary = locate_grid(result.vertices, result.faces, W)
    weights = {
        False: mesh_pixel_weights(result.faces, result.weights, face, bary, np.float64),
        True: grid_pixel_weights(result.vertices, result.faces, result.weights, W, grid=grid),
    }
    inverses = [c.moebius.inverse for c in result.controls]
    return {
        name: inverse_lonlat(blended_inverse(inverses, weights[on_grid], precision="double", projection=proj), W)
        for name, (on_grid, proj) in SETUP.items()
    }


def measure(result: Result, inverse: NDArray[np.float64], ours: NDArray[np.float64], own: NDArray[np.float64]) -> dict[str, object]:
    """Line straightness and excess (per line), fold-over, distortion, latitude shift against ``ours``."""
    samples = [s for _, s in result.constraints.lines]
    lines = np.array([line_straightness(inverse, s, width=W) for s in samples])
    folds = fold_over(inverse)
    found = [coords.lonlat_to_px(forward_points(inverse, s), W) for s in samples]
    px = [np.round(f[np.isfinite(f).all(axis=1)]).astype(int) for f in found]
    in_fold = sum(bool(np.any(folds.mask[np.clip(p[:, 1], 0, W // 2 - 1), p[:, 0] % W])) for p in px)
    distortion = conformal_distortion(inverse)
    area = np.broadcast_to(np.cos(np.radians(coords.grid_lonlat(W)[1]))[:, None], inverse.shape[:2])
    dlat = inverse[..., 1] - ours[..., 1]
    towards = np.abs(ours[..., 1]) - np.abs(inverse[..., 1])
    return {
        "lines": lines,
        "excess": lines - own,
        "in_fold": int(in_fold),
        "fold": 100 * folds.area,
        "cd": (distortion.mean, distortion.p99),
        "dlat": (np.sum(np.abs(dlat) * area) / area.sum(), np.abs(dlat).max(), np.sum(towards * area) / area.sum()),
    }


def _med_max(x: NDArray) -> tuple[float, float]:
    return (float(np.nanmedian(x)), float(np.nanmax(x))) if np.isfinite(x).any() else (np.nan, np.nan)


HEADER = (
    f"  {'variant':<8}{'straight med':>13}{'max':>7}{'excess med':>11}{'max':>7}{'NaN':>4}{'in fold':>8}"
    f"{'fold %':>9}{'CD mean':>9}{'CD p99':>8}{'|dlat| mean':>12}{'max':>7}{'to eq':>8}"
)


def report(name: str, result: Result, stats: dict[str, dict[str, object]]) -> None:
    n_lines, k = len(result.constraints.lines), len(result.controls)
    print(f"\n== {name}: {n_lines} line pieces, {k} controls, mesh {len(result.vertices)} vertices ==")
    print(HEADER)
    for variant, s in stats.items():
        (sm, sx), (em, ex) = _med_max(s["lines"]), _med_max(s["excess"])
        nan = int(np.isnan(s["lines"]).sum())
        d_mean, d_max, to_eq = s["dlat"]
        print(
            f"  {variant:<8}{sm:13.3f}{sx:7.2f}{em:11.3f}{ex:7.2f}{nan:4d}{s['in_fold']:8d}{s['fold']:9.4f}{s['cd'][0]:9.4f}{s['cd'][1]:8.3f}"
            f"{d_mean:12.4f}{d_max:7.3f}{to_eq:8.4f}"
        )


def main(argv: list[str] | None = None) -> int:
    """Build the scenes, evaluate the four blends on each, print the tables and a summary."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", choices=list(SCENES), default=list(SCENES), help="scenes to run (default all)")
    parser.add_argument("--grid", type=int, default=150, help="weight grid width of the grid variants, even (default 150 = 150 x 75)")
    args = parser.parse_args(argv)
    if args.grid < 4 or args.grid % 2:
        parser.error("--grid must be even and at least 4")
    print(f"blend variants at {W} x {W // 2}, weight grid {args.grid} x {args.grid // 2}; Python {sys.version.split()[0]}, ", end="")
    print(f"numpy {np.__version__}, {os.cpu_count()} CPUs")
    print("straightness: best-fit px at 2048; excess: over the line's own Möbius map; NaN: lines not shown whole")
    print("in fold: lines with a sample found in a fold-over (the input shown twice: the figure may measure the other copy)")
    print("fold: % of sphere; CD: conformal distortion (|lat| <= 80); dlat vs ours, degrees, area-weighted; to eq: mean |lat| lost")
    pooled: dict[str, dict[str, list]] = {v: {"lines": [], "excess": [], "fold": [], "in_fold": []} for v in VARIANTS}
    for name in args.scenes:
        clock = time.perf_counter()
        result = build(*SCENES[name])
        if result.weights is None:
            print(f"\n== {name}: one map does it all, nothing blended; skipped ==")
            continue
        own = np.array([straightness(result.controls[c].moebius(s), W, fit="best") for c, s in result.constraints.lines])
        maps = variant_maps(result, args.grid)
        stats = {v: measure(result, maps[v], maps["ours"], own) for v in VARIANTS}
        report(name, result, stats)
        print(f"  (own map alone: median {np.median(own):.3f}, max {own.max():.2f} px; {time.perf_counter() - clock:.1f} s)")
        for v in VARIANTS:
            for key in ("lines", "excess"):
                pooled[v][key].extend(stats[v][key])
            pooled[v]["fold"].append(stats[v]["fold"])
            pooled[v]["in_fold"].append(stats[v]["in_fold"])
    if not pooled["ours"]["fold"]:
        return 0
    print(f"\n== all {len(pooled['ours']['lines'])} line pieces of {len(pooled['ours']['fold'])} scenes ==")
    print(f"  {'variant':<8}{'straight med':>13}{'worst':>8}{'excess med':>11}{'worst':>8}{'NaN':>4}{'in fold':>8}{'fold % max':>12}")
    for v in VARIANTS:
        lines, excess = np.array(pooled[v]["lines"]), np.array(pooled[v]["excess"])
        (sm, sx), (em, ex) = _med_max(lines), _med_max(excess)
        print(
            f"  {v:<8}{sm:13.3f}{sx:8.2f}{em:11.3f}{ex:8.2f}{int(np.isnan(lines).sum()):4d}{sum(pooled[v]['in_fold']):8d}{max(pooled[v]['fold']):12.4f}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
