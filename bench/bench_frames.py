#!/usr/bin/env python
"""Many frames, one map: frames per second at 2048 x 1024 once the map is known.

Usage::

    python bench/bench_frames.py               # 60 JPEG frames, 3 timed runs
    python bench/bench_frames.py --frames 120 --repeat 5 --workers 2

The frames are the bundled panorama at 2048 x 1024, each shifted in brightness (so that no
two are alike), written as JPEG (OpenCV's default quality, 95) to a temporary folder. The
map is the command-line demo's handles (two rectified lines and a cage). Timed, in one run:

1. :func:`omniwidget.app.frames.warp_frames`, reading, resampling and writing every frame
   (what ``omniwidget warp FRAMES... -H handles.json -o folder/`` does after the map);
2. the same work in a plain loop on one thread (``cv2.imread``, ``cv2.remap``, ``cv2.imwrite``),
   the reference.

Prints the medians, frames per second and the ratio; asserts nothing.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

import cv2

REPO_ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO_ROOT))

import omniwidget as ow  # noqa: E402
from omniwidget.app.cli import DEMO_HANDLES  # noqa: E402
from omniwidget.app.frames import map_coordinates, warp_frames  # noqa: E402
from omniwidget.raster.warping import pad_panorama  # noqa: E402

WIDTH = 2048


def measure(count: int = 60, repeat: int = 3, workers: int | None = None) -> dict[str, float]:
    """Write ``count`` frames, compute the map, time both ways; seconds per run (medians) and the map's time."""
    base = cv2.resize(ow.sample_image(), (WIDTH, WIDTH // 2), interpolation=cv2.INTER_CUBIC)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        inputs = []
        for i in range(count):
            path = folder / f"frame{i:04d}.jpg"
            cv2.imwrite(str(path), cv2.convertScaleAbs(base[..., ::-1], alpha=1.0, beta=(i % 20) - 10))
            inputs.append(path)
        (folder / "out").mkdir()
        outputs = [folder / "out" / p.name for p in inputs]

        start = time.perf_counter()
        result = ow.warp(base, ow.Handles.from_dict(DEMO_HANDLES), warn=False)
        coordinates = map_coordinates(result.inverse_map(), WIDTH)
        map_seconds = time.perf_counter() - start

        ours, plain = [], []
        for _ in range(repeat):
            report = warp_frames(inputs, outputs, coordinates, base.shape[:2], workers=workers)
            assert not report.failed, report.failed
            ours.append(report.seconds)
            start = time.perf_counter()
            for src, dst in zip(inputs, outputs, strict=True):
                frame = cv2.imread(str(src))
                cv2.imwrite(str(dst), cv2.remap(pad_panorama(frame), coordinates, None, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE))
            plain.append(time.perf_counter() - start)
    return {"ours": statistics.median(ours), "plain": statistics.median(plain), "map": map_seconds}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=60)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--workers", type=int, default=None)
    args = parser.parse_args()
    n = args.frames
    t = measure(n, args.repeat, args.workers)
    print(f"omniwidget frames benchmark: {n} JPEG frames of {WIDTH} x {WIDTH // 2}, map from the demo's handles in {t['map']:.2f} s")
    print(f"  warp_frames (threads: {args.workers or 'CPUs + 1'}): {t['ours']:.2f} s, {n / t['ours']:.1f} frames per second")
    print(f"  plain loop, one thread:  {t['plain']:.2f} s, {n / t['plain']:.1f} frames per second")
    print(f"  ratio: {t['plain'] / t['ours']:.2f}x; target >= 30 frames per second")


if __name__ == "__main__":
    main()
