#!/usr/bin/env python
"""Panoramas of any size (issue 38): the command line's warp of panoramas 8k to 64k wide, run on demand.

Usage::

    python bench/bench_any_size.py                          # 8192, 16384, 34000 and 64000 wide, RGB (full width up to 34000)
    python bench/bench_any_size.py --widths 34000 64000 --full-up-to 64000   # full width in strips too

For each width W a room (``family_scene("mixed", 7)``) is rendered at 4096, enlarged to W
in strips (bilinear) into a memory-mapped ``.npy`` and written as a JPEG (quality 95);
then ``omniwidget warp`` runs in a fresh process on each file, to ``--width 4096`` and,
for W up to ``--full-up-to``, to its full width (wider than
:data:`~omniwidget.raster.strips.STREAM_WIDTH`: made in strips, written as a tiled TIFF). Each figure is one run: the command's
wall time and its peak resident memory (``ru_maxrss`` of the child). The ``.npy`` is
decoded whole (a plain array), the JPEG at the size asked (1/2 to 1/8 by libjpeg's DCT
scaling, :func:`omniwidget.io.images.asked_reduction`); a source 32,767 px or wider is
resampled in tiles (:func:`omniwidget.raster.warping.remap_panorama`). The estimate is
:func:`omniwidget.io.images.memory_needed`, which the command line refuses by.
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO_ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO_ROOT))

PROBE = (
    "import resource, subprocess, sys; subprocess.run(sys.argv[1:], check=True, stdout=subprocess.DEVNULL); "
    "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)"
)


def make_room(folder: Path, width: int) -> tuple[Path, Path, Path]:
    """The room enlarged to ``width`` as .npy (in strips) and .jpg, and its handles: their paths."""
    import cv2

    from omniwidget.evaluate.scenes import family_scene

    scene, doc, _ = family_scene("mixed", 7, width=4096)
    small = scene.image
    npy, jpg, handles = folder / f"room{width}.npy", folder / f"room{width}.jpg", folder / "h.json"
    handles.write_text(doc.to_json())
    wide = np.lib.format.open_memmap(npy, mode="w+", dtype=np.uint8, shape=(width // 2, width, 3))
    x = ((np.arange(width) + 0.5) * small.shape[1] / width - 0.5).astype(np.float32)
    step = min(width, 16384)  # OpenCV's limit on a map's side
    for r0 in range(0, width // 2, 1000):
        y = ((np.arange(r0, min(r0 + 1000, width // 2)) + 0.5) * small.shape[0] / (width // 2) - 0.5).astype(np.float32)
        for c0 in range(0, width, step):
            map_x, map_y = np.meshgrid(x[c0 : c0 + step], y)
            wide[r0 : r0 + len(y), c0 : c0 + step] = cv2.remap(small, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
    wide.flush()
    if not cv2.imwrite(str(jpg), np.ascontiguousarray(wide[..., ::-1]), [cv2.IMWRITE_JPEG_QUALITY, 95]):
        raise RuntimeError(f"OpenCV could not write {jpg}")
    del wide
    return npy, jpg, handles


def run(source: Path, handles: Path, width: int, out: Path) -> tuple[float, float]:
    """``omniwidget warp`` in a process of its own: (seconds, peak MB)."""
    command = [sys.executable, "-m", "omniwidget", "warp", str(source), "-H", str(handles), "-o", str(out), "--width", str(width)]
    start = time.perf_counter()
    done = subprocess.run([sys.executable, "-c", PROBE, *command], capture_output=True, text=True, check=False)
    seconds = time.perf_counter() - start
    if done.returncode:
        raise RuntimeError(done.stderr.strip().splitlines()[-1] if done.stderr.strip() else f"exit {done.returncode}")
    return seconds, int(done.stdout) / 1024


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--widths", type=int, nargs="+", default=[8192, 16384, 34000, 64000])
    parser.add_argument("--full-up-to", type=int, default=34000, help="warp to the full width only up to this width")
    args = parser.parse_args()

    from omniwidget.io.images import memory_needed
    from omniwidget.raster.strips import STREAM_WIDTH

    print("| input | to | time | peak | estimate |")
    print("| --- | --- | --- | --- | --- |")
    for width in args.widths:
        folder = Path(tempfile.mkdtemp(prefix="any-size-"))
        try:
            npy, jpg, handles = make_room(folder, width)
            for source in (npy, jpg):
                for to in [4096] + ([width] if width <= args.full_up_to else []):
                    try:
                        out = folder / ("out.tif" if to > STREAM_WIDTH else "out.png")  # a TIFF is written strip by strip
                        seconds, peak = run(source, handles, to, out)
                        figures = f"{seconds:.1f} s | {peak:,.0f} MB"
                    except RuntimeError as exc:
                        figures = f"failed: {exc} | –"
                    estimate = memory_needed(source, warp=True, width=to) / 2**20
                    kind = "JPEG q95" if source.suffix == ".jpg" else ".npy"
                    print(f"| {width} x {width // 2} RGB {kind} | {to} | {figures} | {estimate:,.0f} MB |", flush=True)
        finally:
            shutil.rmtree(folder, ignore_errors=True)


if __name__ == "__main__":
    main()
