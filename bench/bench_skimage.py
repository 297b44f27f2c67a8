#!/usr/bin/env python
"""OpenCV's remap against scikit-image's warp for the resampling of a warp, run on demand (not a test).

Usage::

    python bench/bench_skimage.py              # 2048 x 1024 RGB, 9 runs each, in turns
    python bench/bench_skimage.py --width 4096

Both resample the same panorama at the same source coordinates (a warp of the bundled
sample by the demo's handles, the map computed once): ``cv2.remap`` with bilinear
interpolation, as :func:`omniwidget.raster.warping.remap` does, and
``skimage.transform.warp(..., order=1)`` with ``Result.skimage_inverse_map``. Printed: the
medians, their ratio, and how far apart the images are away from the seam and the poles.
The machine is shared: the two run in turns and are compared by the ratio of medians.
"""

from __future__ import annotations

import argparse
import statistics
import time

import cv2
import numpy as np
from skimage.transform import warp as skimage_warp

import omniwidget as ow
from omniwidget.app.cli import DEMO_HANDLES
from omniwidget.raster.warping import pad_panorama, remap
from omniwidget.sphere import coords


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--width", type=int, default=2048)
    parser.add_argument("--repeat", type=int, default=9)
    args = parser.parse_args()
    image = cv2.resize(ow.sample_image(), (args.width, args.width // 2), interpolation=cv2.INTER_CUBIC)
    result = ow.warp(image, ow.Handles.from_dict(DEMO_HANDLES), warn=False)
    lonlat = result.inverse_map(np.float64)
    xy = (coords.lonlat_to_px(lonlat, image.shape[1]) + 3).astype(np.float32)  # omniwidget pads by 3 rows and columns
    padded = pad_panorama(image)
    inverse = result.skimage_inverse_map(image.shape[2])
    times: dict[str, list[float]] = {"cv2.remap": [], "skimage.transform.warp": []}
    ours = theirs = None
    for _ in range(args.repeat):
        start = time.perf_counter()
        ours = remap(padded, xy, "bilinear")
        times["cv2.remap"].append(time.perf_counter() - start)
        start = time.perf_counter()
        theirs = skimage_warp(image, inverse, order=1, mode="wrap", preserve_range=True)
        times["skimage.transform.warp"].append(time.perf_counter() - start)
    medians = {k: statistics.median(v) for k, v in times.items()}
    away = (np.abs(lonlat[..., 0]) < 179) & (np.abs(lonlat[..., 1]) < 88)
    diff = np.abs(np.rint(theirs) - ours.astype(np.float64)).max(axis=-1)[away]
    print(f"resampling {args.width} x {args.width // 2} RGB uint8, bilinear, medians of {args.repeat} runs in turns")
    for name, m in medians.items():
        print(f"  {name:24s} {1000 * m:8.1f} ms  (fastest {1000 * min(times[name]):.1f}, slowest {1000 * max(times[name]):.1f})")
    print(f"  ratio skimage / cv2: {medians['skimage.transform.warp'] / medians['cv2.remap']:.0f}x")
    print(f"  images apart (away from the seam and poles): at most {diff.max():.0f} grey level(s), {100 * np.mean(diff > 0):.2f}% of pixels differ")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
