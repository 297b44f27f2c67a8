#!/usr/bin/env python
"""The speed figures, each beside its reference measured in the same run (run on demand, not a test).

Usage::

    python bench/bench_speed.py                  # everything; prints a table at the end
    python bench/bench_speed.py --write          # and writes bench/RESULTS.md (machine, date, table, notes)
    python bench/bench_speed.py --quick          # fewer repeats, no 10k icosphere for libigl

The figures (the issue's numbering):

1. **End to end**: the 12-handle scene of ``bench/bench_blend.py`` (8 lines, 2 points, a fixed
   4-vertex cage; here rectified "all") at 2048 x 1024, handles to image in memory: median
   wall time, with the compiled kernels and without (``omniwidget.raster._kernels``).
2. **BBW**: :func:`omniwidget.method.bbw.bbw` against ``igl.bbw`` on the scene's adaptive mesh
   and on the 10,242-vertex icosphere with 10 point handles (``bench/bench_bbw.py``'s meshes).
3. **The per-pixel stage** of the same warp (locate, blend, resampling, fold check), against a
   bare ``cv2.remap`` of the same image with the same coordinates.
4. **Preview latency**, kernel side: an :class:`omniwidget.Editor` with the scene, one point's
   centre moved by a degree at a time (a drag), until the 1024 x 512 preview is set on the
   widget; each preview starts its weights from the last one's. The browser figure comes
   from ``test-artifacts/editor_latency.json`` when the browser test has run.
5. **Scale**: the scene's handles on ``../shared/data/brooklyn_street_12k.jpg`` (11968 x 5984),
   read and warped twice in a fresh process: wall time of the second warp (the first also
   loads the compiled kernels and touches fresh memory; both are printed) and peak resident memory.
6. **Many frames, one map**: ``bench/bench_frames.py``'s 60 JPEG frames at 2048 x 1024.

Medians everywhere; the machine is shared, so compare ratios within one run.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import statistics
import subprocess
import sys
import time
import warnings
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np

REPO_ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO_ROOT))
sys.path.insert(0, str(REPO_ROOT / "bench"))

import bench_frames  # noqa: E402
from bench_bbw import icosphere, point_handles  # noqa: E402
from bench_blend import SEED, build_scene  # noqa: E402

from omniwidget.document.handles import Options, PointHandle  # noqa: E402
from omniwidget.method.bbw import bbw  # noqa: E402
from omniwidget.raster import _kernels  # noqa: E402
from omniwidget.raster.pipeline import warp  # noqa: E402
from omniwidget.raster.warping import pad_panorama, remap  # noqa: E402

PHOTO_12K = REPO_ROOT.parent / "shared" / "data" / "brooklyn_street_12k.jpg"
PER_PIXEL = ("locate", "blend", "resampling", "fold check")
ROWS: list[tuple[str, str, str, str]] = []  # figure, measured, reference, target


def row(figure: str, measured: str, reference: str, target: str) -> None:
    ROWS.append((figure, measured, reference, target))
    print(f"  {figure}: {measured}  |  {reference}  |  target {target}")


def median_time(fn, repeat: int, warmup: int = 1) -> tuple[float, object]:
    out = None
    for _ in range(warmup):
        out = fn()
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times), out


class numpy_path:
    """Within the block, the pipeline runs without the compiled kernels."""

    def __enter__(self) -> None:
        self.saved = _kernels.available
        _kernels.available = lambda: False

    def __exit__(self, *exc: object) -> None:
        _kernels.available = self.saved


def end_to_end(image, scene, repeat: int):
    print("\n1. end to end, 12-handle scene at 2048 x 1024 (rectify all)")
    runs: dict[bool, list] = {True: [], False: []}

    def quiet(kernels: bool):
        result = warp(image, scene, warn=False)
        runs[kernels].append(result.timings)
        return result

    fast, result = median_time(lambda: quiet(True), repeat)
    with numpy_path():
        slow, _ = median_time(lambda: quiet(False), repeat)
    for kernels, name in ((True, "kernels"), (False, "numpy")):
        stages = {k: round(statistics.median(t.get(k, 0.0) for t in runs[kernels]), 3) for k in runs[kernels][-1]}
        print(f"  stages (medians, {name}): {stages}")
    row("1. end to end", f"{fast:.3f} s", f"numpy path {slow:.3f} s; paper ~4.8 s (4 cores)", "<= 0.3 s")
    per_pixel = {k: statistics.median(sum(t.get(s, 0.0) for s in PER_PIXEL) for t in runs[k]) for k in runs}
    return result, per_pixel


def bbw_figures(image, scene, result, repeat: int, quick: bool) -> None:
    print("\n2. BBW against igl.bbw")
    try:
        from omniwidget.method._igl import igl_bbw
    except ImportError as exc:
        print(f"  skipped: {exc}")
        return
    # as in the editor: a point dragged by a degree, the weights started from the last warp's
    index = next(i for i, h in enumerate(scene.handles) if isinstance(h, PointHandle))
    items = list(scene.handles)
    items[index] = replace(items[index], target=(items[index].target[0] + 1.0, items[index].target[1]))
    dragged = replace(scene, handles=tuple(items))
    warm = [warp(image, dragged, warn=False, previous=result).timings["weights"] for _ in range(repeat)]
    moved = warp(image, dragged, warn=False)
    theirs, _ = median_time(lambda: igl_bbw(moved.vertices, moved.faces, moved.constrained, moved.prescribed), 3, warmup=0)
    row(
        "2. BBW after a drag, started from the last weights",
        f"{statistics.median(warm):.3f} s",
        f"igl.bbw {theirs:.3f} s: {theirs / statistics.median(warm):.1f}x; cold {moved.timings['weights']:.3f} s",
        "(the editor's case)",
    )
    meshes = [("adaptive mesh of the scene", result.vertices, result.faces, result.constrained, result.prescribed)]
    if not quick:
        v, f = icosphere(5)
        meshes.append(("10,242-vertex icosphere, 10 points", v, f, *point_handles(v)))
    for name, v, f, b, bc in meshes:
        ours, w = median_time(lambda v=v, f=f, b=b, bc=bc: bbw(v, f, b, bc), repeat)
        theirs, w_igl = median_time(lambda v=v, f=f, b=b, bc=bc: igl_bbw(v, f, b, bc), 1 if len(v) > 5000 else 3, warmup=0)
        diff = np.abs(np.asarray(w) - np.asarray(w_igl)).max()
        row(
            f"2. BBW, {name} ({len(v)} vertices, {bc.shape[1]} handles)",
            f"{ours:.3f} s",
            f"igl.bbw {theirs:.3f} s: {theirs / ours:.1f}x; weights within {diff:.1e}",
            ">= 10x faster, within 1e-3",
        )


def per_pixel(image, result, stage: dict[bool, float]) -> None:
    print("\n3. the per-pixel stage against a bare cv2.remap")
    from omniwidget.app.frames import map_coordinates

    coordinates = map_coordinates(result.inverse_map(), image.shape[1])
    padded = pad_panorama(image)
    bare, _ = median_time(lambda: cv2.remap(padded, coordinates, None, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE), 7)
    ours, numpy_stage = stage[True], stage[False]  # medians over the end-to-end runs
    ours_remap, _ = median_time(lambda: remap(padded, coordinates), 7)
    row(
        "3. per-pixel stage",
        f"{ours:.3f} s = {ours / bare:.1f}x a bare remap",
        f"cv2.remap {bare * 1000:.0f} ms (ours {ours_remap * 1000:.0f} ms); numpy path {numpy_stage:.3f} s",
        "<= 3x the bare remap",
    )


def preview(image, scene, repeat: int) -> None:
    print("\n4. preview latency, kernel side (1024 x 512)")
    try:
        from omniwidget.widget import Editor
    except ImportError as exc:
        print(f"  skipped: {exc}")
        return
    editor = Editor(image, scene, autosave=False)  # its cost per edit: bench_editor.py
    editor.wait()
    index = next(i for i, h in enumerate(scene.handles) if isinstance(h, PointHandle))
    walls = []
    for i in range(repeat + 1):
        items = list(scene.handles)
        h = items[index]
        items[index] = replace(h, target=(h.target[0] + 1.0 * i, h.target[1]))  # a drag of the point's centre, as in the browser test
        start = time.perf_counter()
        editor.handles = replace(scene, handles=tuple(items))
        editor.wait()
        if i:
            walls.append(time.perf_counter() - start)
    stages = {k: round(v, 3) for k, v in editor.preview_result.timings.items()}
    browser = REPO_ROOT / "test-artifacts" / "editor_latency.json"
    seen = json.loads(browser.read_text())["median_ms"] if browser.is_file() else None
    print(f"  stages of the last preview: {stages}")
    row(
        "4. preview, edit to image set (kernel)",
        f"{statistics.median(walls):.3f} s",
        f"browser, release to image on screen: {seen:.0f} ms (last browser test run)" if seen else "browser: run the browser test",
        "<= 0.15 s in the browser",
    )


CHILD = """
import json, resource, sys, time, warnings
sys.path.insert(0, sys.argv[2]); sys.path.insert(0, sys.argv[2] + "/bench")
from bench_blend import SEED, build_scene
from dataclasses import replace
from omniwidget.document.handles import Options
from omniwidget.io.images import read_image
from omniwidget.raster.pipeline import warp
_, scene = build_scene(SEED)
start = time.perf_counter()
image = read_image(sys.argv[1])
read = time.perf_counter() - start
doc = replace(scene, options=Options(rectify="all"))
result = warp(image, doc, warn=False)
first = time.perf_counter() - start - read
start = time.perf_counter()
result = warp(image, doc, warn=False)
again = time.perf_counter() - start
print(json.dumps({"read_s": read, "first_s": first, "again_s": again, "peak_kb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss,
                  "shape": list(result.image.shape)}))
"""


def scale() -> None:
    print(f"\n5. scale: {PHOTO_12K.name}, the scene's handles, in a fresh process")
    if not PHOTO_12K.is_file():
        print(f"  skipped: {PHOTO_12K} is absent")
        return
    proc = subprocess.run([sys.executable, "-c", CHILD, str(PHOTO_12K), str(REPO_ROOT)], capture_output=True, text=True)
    if proc.returncode:
        print(f"  failed: {proc.stderr[-400:]}")
        return
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    row(
        "5. 12k panorama, read + warp",
        f"{out['again_s']:.2f} s warp ({out['first_s']:.2f} s the first in a process), peak {out['peak_kb'] / 1e6:.2f} GB",
        f"reading it {out['read_s']:.2f} s; {out['shape'][1]} x {out['shape'][0]}",
        "<= 3 s, <= 4 GB",
    )


def frames() -> None:
    print("\n6. many frames, one map: 60 JPEG frames at 2048 x 1024")
    t = bench_frames.measure(60, 3)
    row("6. frames per second, map known", f"{60 / t['ours']:.0f} /s", f"plain one-thread OpenCV loop {60 / t['plain']:.0f} /s", ">= 30 /s")


def write_results() -> None:
    lines = [
        "# Speed figures",
        "",
        f"Made by `python bench/bench_speed.py --write` on {datetime.date.today().isoformat()}: "
        f"{platform.platform()}, Python {platform.python_version()}, {os.cpu_count()} CPUs, "
        f"numpy {np.__version__}, numba {'yes' if _kernels.available() else 'no'}. Medians; references measured in the same run.",
        "",
        "| figure | measured | reference (same run) | target |",
        "| --- | --- | --- | --- |",
        *(f"| {a} | {b} | {c} | {d} |" for a, b, c, d in ROWS),
        "",
    ]
    notes = REPO_ROOT / "bench" / "RESULTS_NOTES.md"
    if notes.is_file():
        lines += [notes.read_text().rstrip(), ""]
    (REPO_ROOT / "bench" / "RESULTS.md").write_text("\n".join(lines))
    print("\nwrote bench/RESULTS.md")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--write", action="store_true", help="write bench/RESULTS.md")
    parser.add_argument("--quick", action="store_true", help="3 repeats, no 10k icosphere")
    args = parser.parse_args()
    repeat = 3 if args.quick else 5
    warnings.simplefilter("ignore")
    print(
        f"omniwidget speed suite: {os.cpu_count()} CPUs, load {', '.join(f'{x:.2f}' for x in os.getloadavg())}; kernels: {_kernels.available()}"
    )
    image, scene = build_scene(SEED)
    scene = replace(scene, options=Options(rectify="all"))
    result, stage = end_to_end(image, scene, repeat)
    bbw_figures(image, scene, result, repeat, args.quick)
    per_pixel(image, result, stage)
    preview(image, scene, repeat)
    scale()
    frames()
    print("\n| figure | measured | reference (same run) | target |")
    for r in ROWS:
        print("| " + " | ".join(r) + " |")
    if args.write:
        write_results()
    return 0


if __name__ == "__main__":
    sys.exit(main())
