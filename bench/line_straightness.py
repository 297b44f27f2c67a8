"""How straight does eq. (4) make a line? Measured by length, for the limit of Fig. 14.

A rectifying Möbius map keeps a line's endpoints and moves its geodesic midpoint to the
midpoint of the endpoints in the lon/lat plane, so three points are collinear. The line's
great circle goes to a circle, and only meridians and parallels are straight in an
equirectangular image, so the rest of the line is straight only approximately. This
script measures the largest distance from the chord (pixels at 2048 x 1024) of:

* random lines: random start within ±60° latitude, random heading and length, the whole
  line within ±60° latitude, bent by 5 px or more in the input;
* room lines: horizontal 3D segments (edges of floors, ceilings, tables) seen from a level
  camera, same selection.

It also reports the best any single Möbius map can do with the endpoints kept: the circle
through the endpoints that is closest to the chord (one free parameter, optimised).

Run: ``python bench/line_straightness.py [--lines 400]``.
"""

from __future__ import annotations

import argparse

import numpy as np
from scipy.optimize import minimize_scalar

from omniwidget.document.handles import LineHandle
from omniwidget.evaluate.quality import straightness
from omniwidget.sphere import coords
from omniwidget.sphere.moebius import Moebius

WIDTH = 2048
BINS = [(5, 10), (10, 20), (20, 30), (30, 40), (40, 50), (50, 60), (60, 90), (90, 120)]


def random_line(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    start = np.array([rng.uniform(-180, 180), rng.uniform(-60, 60)])
    p = coords.lonlat_to_xyz(start)
    east, north = coords.local_frame(start)
    heading, length = rng.uniform(0, 2 * np.pi), np.radians(rng.uniform(5, 120))
    end = np.cos(length) * p + np.sin(length) * (np.cos(heading) * east + np.sin(heading) * north)
    return start, coords.xyz_to_lonlat(end)


def room_line(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    centre = np.array([*rng.uniform(0.5, 5) * np.array([np.cos(a := rng.uniform(0, 2 * np.pi)), np.sin(a)]), rng.uniform(-3, 3)])
    direction = np.array([np.cos(b := rng.uniform(0, 2 * np.pi)), np.sin(b), 0.0]) * rng.uniform(0.2, 15) / 2
    return coords.xyz_to_lonlat(centre - direction), coords.xyz_to_lonlat(centre + direction)


def best_single_map(start: np.ndarray, end: np.ndarray, curve: np.ndarray) -> float:
    """Straightness of the best circle through the endpoints (any Möbius map keeping them)."""
    end_unwrapped = np.array([coords.unwrap_lon(end[0], start[0]), end[1]])
    middle = (start + end_unwrapped) / 2
    chord = end_unwrapped - start
    normal = np.array([-chord[1], chord[0]]) / np.hypot(*chord)
    control = [start, coords.geodesic_midpoint(start, end), end]

    def deviation(shift: float) -> float:
        m = Moebius.from_points(control, [start, middle + shift * normal, end])
        return straightness(m(curve), WIDTH)

    return float(minimize_scalar(deviation, bounds=(-5, 5), method="bounded", options={"xatol": 1e-4}).fun)


def measure(make, rng: np.random.Generator, count: int, optimise: bool) -> dict[tuple[int, int], list[tuple[float, float]]]:
    table: dict[tuple[int, int], list[tuple[float, float]]] = {b: [] for b in BINS}
    for _ in range(count * len(BINS) * 200):  # long lines within ±60° are rare: give up on a bin eventually
        if all(len(rows) >= count for rows in table.values()):
            break
        start, end = make(rng)
        length = float(coords.angular_distance(start, end))
        bin_ = next((b for b in BINS if b[0] <= length < b[1]), None)
        if bin_ is None or len(table[bin_]) >= count or length > 179:
            continue
        curve = coords.geodesic(start, end, np.linspace(0, 1, 400))
        if np.abs(curve[:, 1]).max() > 60 or straightness(curve, WIDTH) < 5:
            continue
        eq4 = straightness(LineHandle(tuple(start), tuple(end)).moebius()(curve), WIDTH)
        table[bin_].append((eq4, best_single_map(start, end, curve) if optimise else np.nan))
    return table


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--lines", type=int, default=200, help="lines per length bin (default 200)")
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    for name, make in (("random lines", random_line), ("room lines (horizontal 3D segments)", room_line)):
        print(f"\n{name}: distance from the chord after eq. (4), pixels at {WIDTH} x {WIDTH // 2}")
        print(f"{'length':>10} {'lines':>6} {'median':>8} {'p95':>8} {'max':>8} {'best map, max':>14}")
        for (lo, hi), rows in measure(make, rng, args.lines, optimise=True).items():
            if not rows:
                continue
            eq4, best = np.array(rows).T
            print(
                f"{lo:>4}-{hi:<3}° {len(rows):>6} {np.median(eq4):8.2f} {np.percentile(eq4, 95):8.2f} {eq4.max():8.2f} {np.nanmax(best):14.2f}"
            )


if __name__ == "__main__":
    main()
