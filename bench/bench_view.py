#!/usr/bin/env python
"""``omniwidget view`` on a large panorama: reading it whole against reading it only as sharp as the still needs.

Usage::

    python bench/bench_view.py                                            # the 12k street of ../shared/data
    python bench/bench_view.py PANORAMA.jpg --width 1280 --fov 90 --repeat 5

The command reads the panorama at ``2 pi f`` pixels wide (``f`` the still's focal length in
pixels, the sharpest the still needs, at its centre): a JPEG twice that wide or more is
decoded reduced by libjpeg's DCT scaling. Timed here in one process, in turns (whole, then
reduced), medians of ``--repeat``: reading plus :func:`omniwidget.view`; and the two stills'
mean absolute difference in grey levels.
"""

from __future__ import annotations

import argparse
import math
import statistics
import time
from pathlib import Path

import numpy as np

import omniwidget as ow
from omniwidget.io.images import read_panorama

DEFAULT = Path(__file__).resolve().parents[2] / "shared" / "data" / "brooklyn_street_12k.jpg"


def main() -> None:
    """Run the comparison and print it."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("panorama", type=Path, nargs="?", default=DEFAULT)
    parser.add_argument("--width", type=int, default=1280)
    parser.add_argument("--fov", type=float, default=90.0)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    height = round(args.width * 9 / 16)
    need = math.ceil(2 * math.pi * args.width / (2 * math.tan(math.radians(args.fov) / 2)))
    times: dict[str, list[float]] = {"whole": [], "reduced": []}
    stills: dict[str, np.ndarray] = {}
    shapes: dict[str, tuple[int, ...]] = {}
    for _ in range(args.repeat):
        for label, width in (("whole", None), ("reduced", need)):
            start = time.perf_counter()
            image = read_panorama(args.panorama, width=width)
            stills[label] = ow.view(image, yaw=0.0, pitch=0.0, fov=args.fov, width=args.width, height=height).image
            times[label].append(time.perf_counter() - start)
            shapes[label] = image.shape
            del image
    for label, values in times.items():
        print(f"{label:8s} read {shapes[label][1]} x {shapes[label][0]}: " + ", ".join(f"{v:.2f}" for v in values) + f" s, median {statistics.median(values):.2f} s")
    ratio = statistics.median(times["whole"]) / statistics.median(times["reduced"])
    difference = np.abs(stills["whole"].astype(float) - stills["reduced"]).mean()
    print(f"whole / reduced: {ratio:.2f}x; the stills differ by {difference:.2f} grey levels on average (the reduced decode averages, the whole one aliases)")


if __name__ == "__main__":
    main()
