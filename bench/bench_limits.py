#!/usr/bin/env python
"""How time and memory grow with the handles and the panorama's size (the method's limits), run on demand.

Usage::

    python bench/bench_limits.py handles            # point handles and lines at 512 x 256, 10 to 1000
    python bench/bench_limits.py handles --kind line --counts 10 30 100
    python bench/bench_limits.py pixels             # the command line's warp, 1024 to 8192 wide: bytes per output pixel
    python bench/bench_limits.py one --kind point --count 300 --width 512   # a single run, as JSON

Every figure is one run in a fresh subprocess: its wall time of ``omniwidget.warp`` and
its peak resident memory (``VmHWM``) beside the same subprocess's before the warp, so
that the growth is the warp's own; ``pixels`` runs the command line and gives its peak. Handles are drawn with a fixed seed: points anywhere on
the sphere moved 2 degrees, lines 5 to 15 degrees long, rectified. The figures chose the
caps of :mod:`omniwidget.method.limits` and the memory estimate of
:func:`omniwidget.io.images.warp_bytes` (bench/RESULTS.md, "Limits").
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

REPO_ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO_ROOT))


def _document(kind: str, count: int, seed: int = 35) -> dict:
    rng = np.random.default_rng(seed)
    xyz = rng.normal(size=(count, 3))
    lat = np.degrees(np.arcsin(xyz[:, 2] / np.linalg.norm(xyz, axis=1))) * 0.9  # off the poles
    lon = rng.uniform(-179.0, 179.0, count)
    handles = []
    for i in range(count):
        if kind == "point":
            handles.append(
                {
                    "kind": "point",
                    "position": [lon[i], lat[i]],
                    "target": [(lon[i] + 181.5) % 360 - 180, float(np.clip(lat[i] + 1.0, -89, 89))],
                }
            )
        else:
            length, turn = rng.uniform(5.0, 15.0), rng.uniform(0.0, np.pi)
            dlon = length * np.cos(turn) / max(np.cos(np.radians(lat[i])), 0.2)
            end = [float(np.clip(lon[i] + dlon, -180, 180)), float(np.clip(lat[i] + length * np.sin(turn), -89, 89))]
            handles.append({"kind": "line", "start": [lon[i], lat[i]], "end": end})
    return {"handles": handles}


def _peak_mb() -> float:
    """This process's peak resident memory, MB: ``VmHWM``, which starts afresh at ``exec`` (``ru_maxrss`` keeps the parent's at the fork)."""
    with open("/proc/self/status") as fh:
        return int(next(line for line in fh if line.startswith("VmHWM")).split()[1]) / 1024


def _one(kind: str, count: int, width: int) -> dict:
    """One warp in this process: seconds and peak memory (MB) before and after."""
    import omniwidget as ow

    doc = ow.Handles.from_dict(_document(kind, count))
    image = np.zeros((width // 2, width, 3), np.uint8)
    image[..., 0] = (np.arange(width) % 256)[None]
    ow.warp(np.zeros((8, 16, 3), np.uint8), ow.Handles.from_dict(_document("line", 2)), warn=False)  # imports, kernels
    before = _peak_mb()
    start = time.perf_counter()
    result = ow.warp(image, doc, warn=False)
    seconds = time.perf_counter() - start
    after = _peak_mb()
    return {
        "kind": kind,
        "count": count,
        "width": width,
        "seconds": round(seconds, 2),
        "peak_mb": round(after),
        "growth_mb": round(after - before),
        "controls": len(result.controls),
        "mesh_vertices": 0 if result.vertices is None else len(result.vertices),
        "constraint_points": len(result.constraints.points),
        "timings": {k: round(v, 2) for k, v in result.timings.items() if v >= 0.05},
    }


#: The demo's handles (two lines, a cage) and a moved point, in the default mode: the command line's warp of a panorama.
FOUR = {
    "handles": [
        {"kind": "line", "start": [-4.0, 37.5], "end": [68.0, 36.5]},
        {"kind": "line", "start": [-83.0, 12.0], "end": [-45.5, 12.0]},
        {"kind": "point", "position": [120.0, -10.0], "target": [125.0, -8.0]},
        {"kind": "cage", "vertices": [[-28.0, -5.0], [-2.0, -5.0], [-2.0, -50.0], [-28.0, -50.0]]},
    ]
}

CLI = """
import json, sys, time
from omniwidget.app.cli import main
from omniwidget.raster import _kernels
start = time.perf_counter()
code = main(sys.argv[1:])
seconds = time.perf_counter() - start
peak = int(next(line for line in open("/proc/self/status") if line.startswith("VmHWM")).split()[1])
print(json.dumps({"code": code, "seconds": seconds, "peak_kib": peak, "compiled": _kernels.available()}))
"""


def _cli_peak(width: int, out_width: int | None, folder: Path, timeout: float) -> dict:
    """The command line's warp of a ``width`` x ``width / 2`` JPEG by :data:`FOUR`: its wall time and peak memory."""
    from omniwidget.io.images import write_image

    source = folder / f"in{width}.jpg"
    if not source.exists():
        y, x = np.mgrid[0 : width // 2, 0:width].astype(np.float32)
        waves = [np.cos(2 * np.pi * x / 256), np.sin(2 * np.pi * y / 200), np.cos(2 * np.pi * (x + y) / 300)]
        write_image(source, np.stack([127 + 100 * w for w in waves], axis=-1).astype(np.uint8))
        del x, y, waves
    (folder / "h.json").write_text(json.dumps(FOUR))
    argv = ["warp", str(source), "-H", str(folder / "h.json"), "-o", str(folder / "out.jpg"), "-q"]
    if out_width is not None:
        argv += ["--width", str(out_width)]
    try:
        out = subprocess.run([sys.executable, "-c", CLI, *argv], capture_output=True, text=True, timeout=timeout, check=True)
    except subprocess.TimeoutExpired:
        return {"width": width, "out_width": out_width, "seconds": f">{timeout:g}"}
    except subprocess.CalledProcessError as exc:
        return {"width": width, "out_width": out_width, "error": exc.stderr.strip().splitlines()[-1]}
    report = json.loads(out.stdout.strip().splitlines()[-1])
    return {
        "width": width,
        "out_width": out_width or width,
        "seconds": round(report["seconds"], 2),
        "peak_mb": round(report["peak_kib"] / 1024),
        "compiled": report["compiled"],  # the numpy path (no numba) needs more
    }


def _run(kind: str, count: int, width: int, timeout: float) -> dict:
    command = [sys.executable, __file__, "one", "--kind", kind, "--count", str(count), "--width", str(width)]
    try:
        out = subprocess.run(command, capture_output=True, text=True, timeout=timeout, check=True)
    except subprocess.TimeoutExpired:
        return {"kind": kind, "count": count, "width": width, "seconds": f">{timeout:g}"}
    except subprocess.CalledProcessError as exc:
        return {"kind": kind, "count": count, "width": width, "error": exc.stderr.strip().splitlines()[-1]}
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("what", choices=["handles", "pixels", "one"])
    parser.add_argument("--kind", choices=["point", "line"])
    parser.add_argument("--count", type=int, default=1)
    parser.add_argument("--counts", type=int, nargs="+", default=[10, 30, 100, 300, 1000])
    parser.add_argument("--width", type=int, default=512)
    parser.add_argument("--widths", type=int, nargs="+", default=[1024, 2048, 4096, 8192])
    parser.add_argument("--timeout", type=float, default=600.0)
    args = parser.parse_args()
    if args.what == "one":
        print(json.dumps(_one(args.kind, args.count, args.width)))
        return
    if args.what == "handles":
        for kind in [args.kind] if args.kind else ["point", "line"]:
            for count in args.counts:
                print(json.dumps(_run(kind, count, args.width, args.timeout)), flush=True)
    else:
        import tempfile

        with tempfile.TemporaryDirectory() as folder:
            print(json.dumps(_cli_peak(64, None, Path(folder), args.timeout)), flush=True)  # the process alone
            for width in args.widths:
                for out_width in (None, width // 2):
                    print(json.dumps(_cli_peak(width, out_width, Path(folder), args.timeout)), flush=True)


if __name__ == "__main__":
    main()
