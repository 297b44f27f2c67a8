#!/usr/bin/env python
"""Panoramas of any size: warps of panoramas 8k to 64k wide, time and peak memory, run on demand.

Usage::

    python bench/bench_any_size.py                                   # 8192, 16384, 32768 and 64000 wide
    python bench/bench_any_size.py --widths 64000 --engines ours     # one width, the command line only

For each width W a room (``family_scene("mixed", 7)``) is rendered at 4096 and enlarged to W
in strips (bilinear) into a ``.npy`` and a JPEG (quality 95, written in strips). Then, each
in a fresh process whose wall time and peak resident memory (``ru_maxrss``) are measured,
once per figure:

- ``ours``: ``omniwidget warp`` to ``--width 4096`` (a PNG) and to the full width (a tiled
  TIFF; for 64k also a PNG and a JPEG). A panorama above ``STREAM_BYTES`` decoded is left on
  disk for a full-width warp (``omniwidget.io.large``) and decoded reduced for a 4096 one.
- ``mapim``: the same coordinates, strip by strip, resampled by libvips' ``mapim`` from the
  panorama opened by libvips with random access (decoded to a temporary file beyond 100 MB)
  instead of our tiles from ``pread`` patches; written by the same TIFF writer.
- ``numpy``: the naive warp a person writes without a toolkit: the panorama decoded whole,
  the whole output's coordinates at once, numpy's bilinear gather, the output written whole
  (OpenCV). Run only where its own estimate (printed) fits in memory.
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
    """The room enlarged to ``width`` as .npy (in strips) and .jpg (in strips), and its handles: their paths."""
    import cv2

    from omniwidget.evaluate.scenes import family_scene
    from omniwidget.io.large import write_jpeg_strips

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
    del wide
    source = np.load(npy, mmap_mode="r")
    write_jpeg_strips(jpg, source.shape, (np.array(source[r : r + 512]) for r in range(0, source.shape[0], 512)))
    return npy, jpg, handles


def measured(command: list[str]) -> tuple[float, float]:
    """``command`` in a process of its own: (seconds, peak MB)."""
    start = time.perf_counter()
    done = subprocess.run([sys.executable, "-c", PROBE, *command], capture_output=True, text=True, check=False)
    seconds = time.perf_counter() - start
    if done.returncode:
        raise RuntimeError(done.stderr.strip().splitlines()[-1] if done.stderr.strip() else f"exit {done.returncode}")
    return seconds, int(done.stdout) / 1024


def ours(source: Path, handles: Path, width: int, out: Path) -> list[str]:
    return [sys.executable, "-m", "omniwidget", "warp", str(source), "-H", str(handles), "-o", str(out), "--width", str(width)]


def engine(kind: str, source: Path, handles: Path, width: int, out: Path) -> list[str]:
    return [sys.executable, __file__, "--run", kind, str(source), str(handles), str(width), str(out)]


def _strips_for(source: Path, handles_path: Path, width: int):  # noqa: ANN202 - a bench helper
    """The method on the map grid for ``source`` warped to ``width``: (Strips over the panorama's shape, its header)."""
    from omniwidget.document.handles import load_handles
    from omniwidget.io.images import image_header, read_panorama
    from omniwidget.raster.strips import MAP_WIDTH, warp_in_strips

    header = image_header(source)
    map_image = read_panorama(source, width=MAP_WIDTH)

    class Shape:  # the panorama's shape and type, for the strips' coordinates (not read through it)
        shape, dtype = header.shape, header.dtype

    made = warp_in_strips(Shape(), load_handles(handles_path), width=width, map_image=map_image, warn=False)  # type: ignore[arg-type]
    return made, header


def run_mapim(source: Path, handles: Path, width: int, out: Path) -> None:
    """Our strips' coordinates, resampled by libvips' mapim from the panorama opened by libvips."""
    import pyvips

    from omniwidget.io.images import write_image_strips
    from omniwidget.raster.warping import PAD

    pyvips.cache_set_max(0)
    made, header = _strips_for(source, handles, width)
    if source.suffix == ".npy":
        image = pyvips.Image.rawload(str(source), header.width, header.height, header.shape[2], offset=header.offset)
    else:
        image = pyvips.Image.new_from_file(str(source), access="random")
    bilinear = pyvips.Interpolate.new("bilinear")

    def strips():  # noqa: ANN202
        for band in made._bands():
            xy = made.coordinates(band) - np.float32(PAD)
            xy[..., 0] %= header.width  # mapim does not wrap at the seam
            index = pyvips.Image.new_from_array(np.ascontiguousarray(xy))
            yield image.mapim(index, interpolate=bilinear).numpy()

    write_image_strips(out, made.shape, np.uint8, strips())


def run_numpy(source: Path, handles: Path, width: int, out: Path) -> None:
    """The naive warp: the panorama whole, the whole output's coordinates at once, numpy's bilinear gather."""
    import cv2

    from omniwidget.raster.warping import PAD

    made, header = _strips_for(source, handles, width)
    image = np.load(source) if source.suffix == ".npy" else cv2.imread(str(source))[..., ::-1]
    xy = made.coordinates(slice(0, made.shape[0])) - np.float32(PAD + 0.0)
    x, y = xy[..., 0], np.clip(xy[..., 1], 0, header.height - 1)
    x0, y0 = np.floor(x).astype(np.int64), np.floor(y).astype(np.int64)
    fx, fy = (x - x0)[..., None], (y - y0)[..., None]
    x0 %= header.width
    x1, y1 = (x0 + 1) % header.width, np.minimum(y0 + 1, header.height - 1)
    top = image[y0, x0] * (1 - fx) + image[y0, x1] * fx
    bottom = image[y1, x0] * (1 - fx) + image[y1, x1] * fx
    output = np.rint(top * (1 - fy) + bottom * fy).astype(np.uint8)
    if not cv2.imwrite(str(out), np.ascontiguousarray(output[..., ::-1])):
        raise RuntimeError(f"OpenCV could not write {out}")


def numpy_estimate(width_in: int, width_out: int) -> float:
    """Bytes the naive warp holds at its peak: the panorama and 180 bytes an output pixel (measured 6.06 GB for 8192 to 8192)."""
    return 3 * width_in * width_in // 2 + 180 * width_out * width_out // 2


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--widths", type=int, nargs="+", default=[8192, 16384, 32768, 64000])
    parser.add_argument("--engines", nargs="+", default=["ours", "mapim", "numpy"], choices=["ours", "mapim", "numpy"])
    parser.add_argument("--full-up-to", type=int, default=64000, help="warp to the full width only up to this width")
    parser.add_argument("--run", nargs=5, metavar=("ENGINE", "SOURCE", "HANDLES", "WIDTH", "OUT"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.run:
        kind, source, handles, width, out = args.run
        {"mapim": run_mapim, "numpy": run_numpy}[kind](Path(source), Path(handles), int(width), Path(out))
        return

    from omniwidget.io.images import available_memory, memory_needed
    from omniwidget.raster.strips import STREAM_WIDTH

    print("| input | to | engine | output | time | peak | estimate |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for width in args.widths:
        folder = Path(tempfile.mkdtemp(prefix="any-size-"))
        try:
            npy, jpg, handles = make_room(folder, width)
            for source in (npy, jpg):
                kind = "JPEG q95" if source.suffix == ".jpg" else ".npy"
                for to in [4096] + ([width] if width <= args.full_up_to else []):
                    outputs = [".png"] if to <= STREAM_WIDTH else [".tif"] + ([".png", ".jpg"] if width == max(args.widths) and source == jpg else [])
                    for name in args.engines:
                        for suffix in outputs if name == "ours" else outputs[:1]:
                            out = folder / f"out{suffix}"
                            estimate = (
                                memory_needed(source, warp=True, width=to, streamed=to > STREAM_WIDTH)
                                if name == "ours"
                                else numpy_estimate(width, to)
                                if name == "numpy"
                                else None
                            )
                            if name == "numpy" and estimate > (available_memory() or 0) * 0.8:
                                figures = f"not run: needs about {estimate / 2**30:.0f} GB | –"
                            else:
                                try:
                                    command = ours(source, handles, to, out) if name == "ours" else engine(name, source, handles, to, out)
                                    seconds, peak = measured(command)
                                    figures = f"{seconds:.1f} s | {peak:,.0f} MB"
                                except RuntimeError as exc:
                                    figures = f"failed: {exc} | –"
                            shown = "–" if estimate is None else f"{estimate / 2**20:,.0f} MB"
                            print(f"| {width} x {width // 2} RGB {kind} | {to} | {name} | {suffix} | {figures} | {shown} |", flush=True)
                            out.unlink(missing_ok=True)
        finally:
            shutil.rmtree(folder, ignore_errors=True)


if __name__ == "__main__":
    main()
