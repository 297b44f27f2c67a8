#!/usr/bin/env python
"""A fresh process, with the compiled kernels read from disk.

Usage::

    python bench/bench_fresh.py [--repeat 5]

Interleaved runs in fresh processes, medians:

- the command line, ``omniwidget warp`` on the 12-handle scene of ``bench/bench_blend.py`` at
  2048 x 1024 (a PNG in, a PNG out, reading and writing included);
- a plain numpy single-map warp script in the same conditions (OpenCV reads and writes the
  PNG; one Möbius map evaluated with numpy and resampled by ``scipy.ndimage.map_coordinates``),
  the reference the issue names. Both write the PNG with OpenCV's default settings (the
  fastest here: levels 0-3 and the RLE, Huffman-only strategies all encode the command
  line's output slower);
- the first result of an :class:`omniwidget.Editor` made in a fresh process: from making the
  editor to its first preview, then the imports before it (``import omniwidget`` and the
  widget stack: anywidget, ipywidgets), and the whole from the process's start.

The ratio is given two ways: of the medians, and the median of each round's ratio (the
command line and the reference run one after the other; on a busy machine the load changes
from one round to the next more than between two runs).

Run once beforehand so that the kernels are compiled and stored (numba's cache, and their
native copies, :mod:`omniwidget._native`); the script does one warm-up run of the
command line. Run on demand, not a test.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench_blend import SEED, build_scene  # noqa: E402

from omniwidget.io.images import write_image  # noqa: E402

NUMPY_WARP = """
import sys
import cv2, numpy as np
from scipy.ndimage import map_coordinates
from omniwidget.sphere import coords
from omniwidget.sphere.moebius import Moebius
image = cv2.imread(sys.argv[1], cv2.IMREAD_UNCHANGED)
width = image.shape[1]
lon, lat = coords.grid_lonlat(width)
source = Moebius.point_map((0.0, 0.0), (10.0, 5.0), 1.5, 10.0).inverse(np.stack(np.meshgrid(lon, lat), axis=-1))
x, y = coords.lonlat_to_px(source, width).transpose(2, 0, 1)
out = np.stack([map_coordinates(image[..., c], [y, x], order=1, mode="grid-wrap") for c in range(image.shape[2])], axis=-1)
cv2.imwrite(sys.argv[2], out)
"""

FIRST_RESULT = """
import sys, time
start = time.perf_counter()
import omniwidget as ow
from omniwidget import Editor  # the widget stack (anywidget, ipywidgets): omniwidget's imports, timed apart
imported = time.perf_counter()
ed = Editor(sys.argv[1], ow.load_handles(sys.argv[2]), autosave=False)
ed.wait()
done = time.perf_counter()
print(done - imported, done - start, imported - start)
"""


def timed(args: list[str]) -> float:
    start = time.perf_counter()
    subprocess.run(args, check=True, capture_output=True)
    return time.perf_counter() - start


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    image, scene = build_scene(SEED)
    with tempfile.TemporaryDirectory() as folder:
        root = Path(folder)
        src, handles = root / "scene.png", root / "handles.json"
        write_image(src, image)
        handles.write_text(scene.to_json())
        cli = [sys.executable, "-m", "omniwidget", "warp", str(src), "-H", str(handles), "-o", str(root / "out.png")]
        plain = [sys.executable, "-c", NUMPY_WARP, str(src), str(root / "plain.png")]
        editor = [sys.executable, "-c", FIRST_RESULT, str(src), str(handles)]
        timed(cli)  # the kernels into numba's cache, if they are not there yet
        times: dict[str, list[float]] = {"cli": [], "plain": [], "editor": [], "editor_process": [], "editor_imports": []}
        for _ in range(args.repeat):
            times["cli"].append(timed(cli))
            times["plain"].append(timed(plain))
            out = subprocess.run(editor, check=True, capture_output=True, text=True).stdout.split()
            times["editor"].append(float(out[0]))
            times["editor_process"].append(float(out[1]))
            times["editor_imports"].append(float(out[2]))
    m = {k: statistics.median(v) for k, v in times.items()}
    # the machine's load changes from minute to minute: each round's ratio is of two runs made one after the other
    paired = statistics.median(c / p for c, p in zip(times["cli"], times["plain"], strict=True))
    print(f"{len(scene.handles)} handles at {image.shape[1]} x {image.shape[0]}, medians of {args.repeat} fresh processes")
    print(
        f"command line: {m['cli']:.2f} s; plain numpy single-map warp: {m['plain']:.2f} s; "
        f"ratio {m['cli'] / m['plain']:.2f} (median of the rounds' ratios {paired:.2f})"
    )
    print(
        f"editor's first result: {m['editor']:.2f} s after making it; before that, importing omniwidget and its "
        f"widget stack {m['editor_imports']:.2f} s ({m['editor_process']:.2f} s from the process's start)"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
