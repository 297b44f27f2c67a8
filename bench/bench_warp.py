#!/usr/bin/env python
"""Benchmark of omniwidget's Möbius warp, run on demand (not a test).

Usage::

    python bench/bench_warp.py              # everything, 5 runs per figure
    python bench/bench_warp.py --repeat 9   # more runs: steadier medians
    python bench/bench_warp.py --quick      # skip the 12k-pixel-wide memory part

What it measures, each figure printed beside its reference:

1. One Möbius warp of a 2048 x 1024 RGB uint8 image held in memory (the map of every
   output pixel plus the bilinear resampling) with
   :func:`omniwidget.raster.warping.warp_moebius`. Target: at most 0.25 s.
2. The same warp done "the plain vectorised numpy way", written out below: complex
   arithmetic for the source position of every output pixel, then
   ``scipy.ndimage.map_coordinates`` channel by channel. Its output is compared with
   omniwidget's (they should agree within a few grey levels away from the poles), so the
   speed ratio compares two programs that compute the same picture. Target: omniwidget at
   least 5x faster. The same with cubic resampling is printed for information.
3. The command line's whole run, ``python -m omniwidget warp IN -H HANDLES.json -o OUT.png``,
   interpreter start-up and files included, beside the same work done in this process.
4. Peak memory (``ru_maxrss``) of a warp of the 11968 x 5984 photo
   ``../shared/data/brooklyn_street_12k.jpg`` in a fresh subprocess, beside a subprocess
   that only reads the image. Target: under 4 GB.

The machine may be shared and noisy, so every time is the median of ``--repeat`` runs
(after one untimed warm-up run, except for the fresh 12k subprocesses), printed with the
fastest and slowest run and the CPU time; contenders run in turns and are compared by
ratios of medians. omniwidget uses several threads and the reference one, so the
wall-time ratio needs free cores; the CPU-time ratio is the work ratio. The exit status
is 0 whatever the figures: read the table.
"""

from __future__ import annotations

import argparse
import gc
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

REPO_ROOT = Path(__file__).resolve().parents[1]
# Run from a checkout without installing: make ``import omniwidget`` find the repository.
sys.path.insert(0, str(REPO_ROOT))

from omniwidget.io.images import read_image, write_image  # noqa: E402
from omniwidget.raster.warping import WarpResult, warp_moebius  # noqa: E402
from omniwidget.sphere.moebius import Moebius  # noqa: E402

DATA = REPO_ROOT.parent / "shared" / "data"
PHOTO_2K = DATA / "grabodrertorv.jpg"  # a real 2048 x 1024 panorama, if present
PHOTO_12K = DATA / "brooklyn_street_12k.jpg"

WIDTH = 2048
CLI_MODULE = "omniwidget"  # run as ``python -m omniwidget``
#: The benchmarked map: one point handle, as ``Moebius.point_map`` arguments.
POSITION, TARGET, SCALE, ROTATION = [10.0, 20.0], [35.0, -5.0], 1.6, 25.0
HANDLES_DOC = {
    "format": "omniwidget.handles",
    "version": 1,
    "handles": [{"kind": "point", "position": POSITION, "target": TARGET, "rotation": ROTATION, "scale": SCALE}],
}

TARGET_WARP_S = 0.25  # one 2048 x 1024 bilinear warp, seconds
TARGET_SPEEDUP = 5.0  # omniwidget over the numpy + scipy reference
TARGET_AGREEMENT = 3.0  # mean absolute difference, grey levels, away from the poles
TARGET_PEAK_GB = 4.0  # peak resident memory of the 12k warp
#: Output pixels whose source lies within this many degrees of a pole are left out of the
#: agreement check: ``mode='grid-wrap'`` wraps the top row onto the bottom row there, while
#: omniwidget continues over the pole (both are "right" only away from it).
POLE_MARGIN_DEG = 10.0


# --------------------------------------------------------------------------------------
# Timing and reporting helpers
# --------------------------------------------------------------------------------------
@dataclass
class Timing:
    """Wall-clock and CPU times of several runs of the same thing, in seconds.

    Wall time is what a user waits; CPU time adds up the work of all threads (or of the
    child processes). On a busy machine wall time grows while CPU time mostly does not,
    so the two together tell a slow program from a crowded machine.
    """

    times: list[float]
    cpu_times: list[float]

    @property
    def median(self) -> float:
        """The median wall time: the figure that is reported and compared."""
        return statistics.median(self.times)

    @property
    def cpu_median(self) -> float:
        """The median CPU time."""
        return statistics.median(self.cpu_times)

    def __str__(self) -> str:
        return (
            f"{self.median:.3f} s (min {min(self.times):.3f}, max {max(self.times):.3f}, n={len(self.times)}; CPU {self.cpu_median:.3f} s)"
        )


@dataclass
class Row:
    """One line of the final table."""

    figure: str
    measured: str
    reference: str
    verdict: str  # "PASS", "FAIL", "info" or "skipped"


def verdict(ok: bool) -> str:
    """``"PASS"`` or ``"FAIL"``."""
    return "PASS" if ok else "FAIL"


def cpu_time() -> float:
    """CPU seconds used so far by this process (all its threads) and its finished children."""
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time() + children.ru_utime + children.ru_stime


def time_interleaved(fns: list[Callable[[], object]], repeat: int, warmup: int = 1) -> list[tuple[Timing, object]]:
    """Time several functions in turns: ``f, g, f, g, ...``, ``repeat`` timed rounds.

    Taking turns means a burst of load from elsewhere on the machine falls on all
    contenders alike, so the ratio of their medians stays fair. A warm-up round first
    pays for lazy imports, first-touch page faults and thread-pool start-up, which a
    long-lived program pays once. Garbage is collected before each timed call so that a
    collection owed by an earlier call does not land inside it.

    Parameters
    ----------
    fns : list of callables
        The work to time, each without arguments (it may run a subprocess: CPU time
        counts finished children too).
    repeat, warmup : int
        Timed and untimed rounds.

    Returns
    -------
    list of (Timing, result of the last call), one per function.
    """
    results: list[object] = [None] * len(fns)
    times: list[list[float]] = [[] for _ in fns]
    cpu_times: list[list[float]] = [[] for _ in fns]
    for round_ in range(warmup + repeat):
        for k, fn in enumerate(fns):
            gc.collect()
            start, cpu_start = time.perf_counter(), cpu_time()
            results[k] = fn()
            if round_ >= warmup:
                times[k].append(time.perf_counter() - start)
                cpu_times[k].append(cpu_time() - cpu_start)
    return [(Timing(t, c), r) for t, c, r in zip(times, cpu_times, results, strict=True)]


def subprocess_env() -> dict[str, str]:
    """The environment for child Pythons: this repository first on ``PYTHONPATH``."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(REPO_ROOT), env.get("PYTHONPATH")]))
    return env


def heading(text: str) -> None:
    """Print a section heading."""
    print(f"\n== {text} ==")


# --------------------------------------------------------------------------------------
# The benchmarked image and map
# --------------------------------------------------------------------------------------
def synthetic_panorama(width: int) -> NDArray[np.uint8]:
    """A deterministic RGB test panorama: smooth colour gradients under a 10-degree grid."""
    lon = np.linspace(-np.pi, np.pi, width, endpoint=False)[None, :]
    lat = np.linspace(np.pi / 2, -np.pi / 2, width // 2, endpoint=False)[:, None]
    red = 128 + 100 * np.cos(lon) * np.cos(lat)
    green = 128 + 100 * np.sin(2 * lat) + 0 * lon
    blue = 128 + 100 * np.sin(3 * lon) * np.cos(lat)
    image = np.stack(np.broadcast_arrays(red, green, blue), axis=-1)
    step = width // 36  # one grid line every 10 degrees
    image[::step] = 255
    image[:, ::step] = 0
    return np.clip(image, 0, 255).astype(np.uint8)


def benchmark_image(width: int = WIDTH) -> tuple[NDArray[np.uint8], str]:
    """The 2048 x 1024 RGB image to warp: a real photo when available, else a synthetic one.

    A photo is the honest input: its texture is what the two resamplers must agree on.
    """
    if PHOTO_2K.is_file():
        image = read_image(PHOTO_2K)
        if image.shape == (width // 2, width, 3) and image.dtype == np.uint8:
            return image, f"{PHOTO_2K.name} (photo)"
    return synthetic_panorama(width), "synthetic pattern"


def benchmark_map() -> Moebius:
    """The Möbius map of the benchmark's single point handle."""
    return Moebius.point_map(POSITION, TARGET, SCALE, ROTATION)


# --------------------------------------------------------------------------------------
# The reference: the plain vectorised numpy way
# --------------------------------------------------------------------------------------
def reference_source_pixels(inverse: NDArray[np.complex128], width: int, src_width: int) -> tuple[NDArray, NDArray, NDArray]:
    """Where each output pixel of a ``width x width/2`` panorama reads the source, the plain way.

    Every step is one numpy expression over the whole grid:
    lon/lat grid -> unit vectors -> stereographic ``z = (x + i y) / (1 - z3)`` ->
    ``(a z + b) / (c z + d)`` with the *inverse* map's matrix -> back to the sphere ->
    lon/lat -> pixel coordinates in the source.

    Parameters
    ----------
    inverse : complex array, shape (2, 2)
        Matrix of the inverse of the warp's map (``m.inverse.matrix``): output to input.
    width, src_width : int
        Output and source widths.

    Returns
    -------
    rows, cols : float64 arrays, shape (width / 2, width)
        Source row and column of each output pixel centre.
    src_lat : float64 array, same shape
        Source latitude in degrees (used to leave the poles out of the comparison).
    """
    (a, b), (c, d) = inverse
    step = 360.0 / width
    lon = np.radians(-180.0 + (np.arange(width) + 0.5) * step)
    lat = np.radians(90.0 - (np.arange(width // 2) + 0.5) * step)
    lon, lat = np.meshgrid(lon, lat)
    x, y, z3 = np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)
    z = (x + 1j * y) / (1.0 - z3)  # the north pole is never a pixel centre: no division by 0
    w = (a * z + b) / (c * z + d)
    r2 = w.real**2 + w.imag**2
    sx, sy, sz = 2 * w.real / (1 + r2), 2 * w.imag / (1 + r2), (r2 - 1) / (r2 + 1)
    src_lon = np.degrees(np.arctan2(sy, sx))
    src_lat = np.degrees(np.arctan2(sz, np.hypot(sx, sy)))
    per_degree = src_width / 360.0
    cols = (src_lon + 180.0) * per_degree - 0.5
    rows = (90.0 - src_lat) * per_degree - 0.5
    return rows, cols, src_lat


def reference_sample(image: NDArray, rows: NDArray, cols: NDArray, order: int) -> NDArray:
    """Resample ``image`` at (``rows``, ``cols``) with scipy, one channel at a time.

    ``mode='grid-wrap'`` wraps both axes: right across the ±180° seam, wrong (but only
    within a pixel of the pole) at the top and bottom rows.
    """
    from scipy import ndimage

    return np.stack(
        [ndimage.map_coordinates(image[..., k], [rows, cols], order=order, mode="grid-wrap") for k in range(image.shape[2])],
        axis=-1,
    )


def reference_warp(image: NDArray, m: Moebius, order: int) -> tuple[NDArray, NDArray, float, float]:
    """The whole reference warp; also returns the source latitudes and the two stages' times.

    Returns
    -------
    warped : ndarray, the image's shape and dtype
    src_lat : float64 array, shape (H, W)
    map_s, sample_s : float
        Seconds spent computing the map and resampling.
    """
    start = time.perf_counter()
    rows, cols, src_lat = reference_source_pixels(m.inverse.matrix, image.shape[1], image.shape[1])
    mapped = time.perf_counter()
    warped = reference_sample(image, rows, cols, order)
    return warped, src_lat, mapped - start, time.perf_counter() - mapped


def agreement(a: NDArray, b: NDArray, src_lat: NDArray) -> tuple[float, int, float]:
    """How far two warped images differ, in grey levels.

    Returns
    -------
    mean_away, max_away : float, int
        Mean and largest absolute difference where the source is away from the poles.
    mean_all : float
        Mean absolute difference over the whole image.
    """
    diff = np.abs(a.astype(np.int16) - b.astype(np.int16))
    away = np.abs(src_lat) <= 90.0 - POLE_MARGIN_DEG
    return float(diff[away].mean()), int(diff[away].max()), float(diff.mean())


# --------------------------------------------------------------------------------------
# Parts 1 and 2: one warp in memory, against the reference
# --------------------------------------------------------------------------------------
@dataclass
class Comparison:
    """omniwidget against the reference for one resampling order."""

    order: str  # omniwidget's name: "bilinear" or "bicubic"
    spline_order: int  # map_coordinates' order: 1 or 3
    ours: Timing
    reference: Timing
    reference_map_s: float  # median time of the reference's map stage
    reference_sample_s: float  # median time of its map_coordinates stage
    mean_away: float  # agreement, see agreement()
    max_away: int
    mean_all: float

    @property
    def speedup(self) -> float:
        """How many times faster omniwidget is: a ratio of medians."""
        return self.reference.median / self.ours.median

    @property
    def cpu_ratio(self) -> float:
        """How many times less CPU time omniwidget uses (its threads added up)."""
        return self.reference.cpu_median / self.ours.cpu_median


def compare(image: NDArray, m: Moebius, order: str, spline_order: int, repeat: int) -> Comparison:
    """Time omniwidget's warp and the reference with the same map and order; check they agree."""
    stages: list[tuple[float, float]] = []

    def run_reference() -> tuple[NDArray, NDArray]:
        warped, src_lat, map_s, sample_s = reference_warp(image, m, spline_order)
        stages.append((map_s, sample_s))
        return warped, src_lat

    def run_ours() -> WarpResult:
        return warp_moebius(image, m, order=order)

    (ours, ours_result), (reference, (ref_image, src_lat)) = time_interleaved([run_ours, run_reference], repeat)
    timed = stages[-repeat:]  # leave out the warm-up run
    return Comparison(
        order,
        spline_order,
        ours,
        reference,
        statistics.median(s[0] for s in timed),
        statistics.median(s[1] for s in timed),
        *agreement(ours_result.image, ref_image, src_lat),
    )


def print_comparison(c: Comparison, channels: int) -> None:
    """Print one comparison's times, their ratio and the agreement."""
    print(f"\n[{c.order}]")
    print(f"  omniwidget warp_moebius(order={c.order!r}): {c.ours}")
    print(f"  reference numpy + map_coordinates(order={c.spline_order}): {c.reference}")
    print(f"    of which map {c.reference_map_s:.3f} s, map_coordinates x{channels} {c.reference_sample_s:.3f} s (medians)")
    print(f"  speed-up (median / median): {c.speedup:.1f}x wall time, {c.cpu_ratio:.1f}x CPU time")
    print(
        f"  agreement: mean |difference| {c.mean_away:.3f} grey levels (max {c.max_away}) where the source is "
        f"within {90 - POLE_MARGIN_DEG:.0f} deg of the equator; mean {c.mean_all:.3f} over the whole image"
    )


def wrong_map_difference(image: NDArray, m: Moebius) -> float:
    """Mean difference to the reference given the forward map by mistake: the scale of a real error.

    It shows that the agreement check has teeth: a wrong map gives another picture.
    """
    ours = warp_moebius(image, m).image
    wrong, _, _, _ = reference_warp(image, m.inverse, 1)
    return float(np.abs(ours.astype(np.int16) - wrong.astype(np.int16)).mean())


def bench_in_memory(repeat: int) -> list[Row]:
    """Parts 1 and 2: omniwidget's in-memory warp against the numpy + scipy reference."""
    heading("1-2. One Möbius warp of a 2048 x 1024 RGB uint8 image in memory")
    image, source = benchmark_image()
    m = benchmark_map()
    print(f"image: {source}, {image.shape[1]} x {image.shape[0]}; map: point_map({POSITION}, {TARGET}, {SCALE}, {ROTATION})")
    print(
        "omniwidget computes the map in several threads and OpenCV resamples in its own; the reference is "
        "single-threaded numpy/scipy, so a crowded machine slows omniwidget more: compare CPU times too"
    )
    linear = compare(image, m, "bilinear", 1, repeat)
    print_comparison(linear, image.shape[2])
    print(f"  (for scale: the reference with the map's inverse by mistake differs by {wrong_map_difference(image, m):.1f} on average)")
    cubic = compare(image, m, "bicubic", 3, repeat)
    print_comparison(cubic, image.shape[2])
    print("  (scipy's order=3 is a prefiltered cubic B-spline, OpenCV's bicubic is Keys' kernel: small differences are expected)")
    agree = f"<= {TARGET_AGREEMENT:g} grey"
    fast = linear.ours.median <= TARGET_WARP_S
    return [
        Row("2k warp, bilinear (median)", f"{linear.ours.median:.3f} s", f"<= {TARGET_WARP_S:g} s", verdict(fast)),
        Row("  agreement with reference", f"{linear.mean_away:.3f} grey", agree, verdict(linear.mean_away <= TARGET_AGREEMENT)),
        Row(
            "  speed-up over numpy+scipy",
            f"{linear.speedup:.1f}x",
            f">= {TARGET_SPEEDUP:g}x (ref {linear.reference.median:.3f} s)",
            verdict(linear.speedup >= TARGET_SPEEDUP),
        ),
        Row("  CPU-time ratio (all threads)", f"{linear.cpu_ratio:.1f}x", f"ref CPU {linear.reference.cpu_median:.3f} s", "info"),
        Row("2k warp, bicubic (median)", f"{cubic.ours.median:.3f} s", "-", "info"),
        Row("  agreement, cubic spline ref", f"{cubic.mean_away:.3f} grey", agree, verdict(cubic.mean_away <= TARGET_AGREEMENT)),
        Row("  speed-up over scipy order=3", f"{cubic.speedup:.1f}x", f"ref {cubic.reference.median:.3f} s", "info"),
    ]


# --------------------------------------------------------------------------------------
# Part 3: the command line, start-up and files included
# --------------------------------------------------------------------------------------
def cli_command(inp: Path, handles: Path, out: Path) -> list[str]:
    """``python -m omniwidget warp IN -H HANDLES.json -o OUT.png`` with this interpreter."""
    return [sys.executable, "-m", CLI_MODULE, "warp", str(inp), "-H", str(handles), "-o", str(out)]


def cli_available() -> tuple[bool, str]:
    """Whether ``python -m omniwidget warp`` exists (its ``--help`` succeeds), and why not."""
    proc = subprocess.run(
        [sys.executable, "-m", CLI_MODULE, "warp", "--help"], capture_output=True, text=True, env=subprocess_env(), cwd=REPO_ROOT
    )
    if proc.returncode == 0:
        return True, ""
    lines = (proc.stderr or proc.stdout).strip().splitlines()
    return False, lines[-1] if lines else f"exit status {proc.returncode}"


def command_runner(make_command: Callable[[int], list[str]]) -> Callable[[], None]:
    """A function without arguments that runs the next command and checks it succeeded.

    ``make_command(i)`` gives the command of call ``i`` (0, 1, ...), so each run can write
    its own file. A failed run raises ``RuntimeError`` with the end of its error output.
    """
    calls = iter(range(1_000_000))

    def run() -> None:
        proc = subprocess.run(make_command(next(calls)), capture_output=True, text=True, env=subprocess_env(), cwd=REPO_ROOT)
        if proc.returncode != 0:
            raise RuntimeError(f"exit status {proc.returncode}: {proc.stderr.strip()[-500:]}")

    return run


def max_difference(a: NDArray, b: NDArray) -> int | None:
    """Largest absolute difference of two images in grey levels; ``None`` if their shapes differ."""
    if a.shape != b.shape:
        return None
    return int(np.abs(a.astype(np.int32) - b.astype(np.int32)).max())


def bench_cli(repeat: int) -> list[Row]:
    """Time the command line's whole run beside the same work in-process and a bare start-up."""
    heading("3. Command line: python -m omniwidget warp IN -H HANDLES.json -o OUT.png")
    available, why = cli_available()
    if not available:
        print(f"CLI: not available ({why})")
        return [Row("CLI whole run", "not available", "-", "skipped")]
    image, source = benchmark_image()
    m = benchmark_map()
    with tempfile.TemporaryDirectory(prefix="omniwidget-bench-") as tmp:
        folder = Path(tmp)
        inp, handles = folder / "in.png", folder / "handles.json"
        write_image(inp, image)  # PNG: lossless, so the CLI's output can be compared exactly
        handles.write_text(json.dumps(HANDLES_DOC))
        print(f"input: {source} written as {inp.name} ({inp.stat().st_size / 1e6:.1f} MB); handles: one point handle")

        def in_process() -> NDArray:
            result = warp_moebius(read_image(inp), m)
            write_image(folder / "in_process.png", result.image)
            return result.image

        cli_run = command_runner(lambda i: cli_command(inp, handles, folder / f"out{i}.png"))
        startup_run = command_runner(lambda i: [sys.executable, "-c", "import cv2, omniwidget.raster.warping"])
        try:
            (cli, _), (same_work, expected), (startup, _) = time_interleaved([cli_run, in_process, startup_run], repeat)
        except RuntimeError as exc:
            print(f"CLI: failed ({exc})")
            return [Row("CLI whole run", "failed", "-", "FAIL")]
        max_diff = max_difference(read_image(folder / f"out{repeat}.png"), expected)  # the last run's output
    print(f"  CLI whole run:                                         {cli}")
    print(f"  same read + warp + write in this process:              {same_work}")
    print(f"  start-up: python -c 'import cv2, omniwidget.raster.warping': {startup}")
    print(f"  CLI minus (in-process + start-up): {cli.median - same_work.median - startup.median:+.3f} s")
    print(f"  CLI output vs in-process warp: max |difference| {'shapes differ' if max_diff is None else max_diff}")
    same = max_diff == 0
    return [
        Row("CLI whole run (median)", f"{cli.median:.3f} s", f"in-proc {same_work.median:.3f} + start {startup.median:.3f} s", "info"),
        Row("  CLI output = in-process", "yes" if same else "no", "identical pixels", verdict(same)),
    ]


# --------------------------------------------------------------------------------------
# Part 4: peak memory of a 72-megapixel warp
# --------------------------------------------------------------------------------------
#: The child program: import everything first (so both modes pay the same imports), read
#: the image, warp it unless in "read" mode, and print times and peak memory as JSON.
CHILD = r"""
import json, resource, sys, time
from omniwidget.io.images import read_image
from omniwidget.sphere.moebius import Moebius
from omniwidget.raster.warping import warp_moebius

path, mode, params = sys.argv[1], sys.argv[2], json.loads(sys.argv[3])
start, cpu = time.perf_counter(), time.process_time()
image = read_image(path)
report = {"shape": list(image.shape), "read_s": time.perf_counter() - start, "read_cpu_s": time.process_time() - cpu}
if mode == "warp":
    m = Moebius.point_map(*params)
    start, cpu = time.perf_counter(), time.process_time()
    result = warp_moebius(image, m)
    report["warp_s"] = time.perf_counter() - start
    report["warp_cpu_s"] = time.process_time() - cpu
usage = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
report["peak_bytes"] = usage if sys.platform == "darwin" else usage * 1024  # macOS: bytes, Linux: KiB
print(json.dumps(report))
"""


def run_child(path: Path, mode: str) -> dict:
    """Run :data:`CHILD` once in a fresh interpreter and return its JSON report."""
    params = json.dumps([POSITION, TARGET, SCALE, ROTATION])
    proc = subprocess.run(
        [sys.executable, "-c", CHILD, str(path), mode, params], capture_output=True, text=True, env=subprocess_env(), cwd=REPO_ROOT
    )
    if proc.returncode != 0:
        raise RuntimeError(f"{mode} child failed, exit status {proc.returncode}: {proc.stderr.strip()[-500:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def bench_big(repeat: int) -> list[Row]:
    """Peak memory and time of warping the 12k photo, beside a child that only reads it."""
    heading(f"4. Peak memory: warp of {PHOTO_12K.name} in a fresh subprocess")
    if not PHOTO_12K.is_file():
        print(f"skipped: {PHOTO_12K} is absent")
        return [Row("12k warp peak memory", "-", "-", "skipped")]
    reads: list[dict] = []
    warps: list[dict] = []
    try:
        for _ in range(repeat):  # in turns, like time_interleaved; fresh children need no warm-up
            reads.append(run_child(PHOTO_12K, "read"))
            warps.append(run_child(PHOTO_12K, "warp"))
    except RuntimeError as exc:
        print(f"failed: {exc}")
        return [Row("12k warp peak memory", "failed", f"< {TARGET_PEAK_GB:g} GB", "FAIL")]
    h, w = warps[0]["shape"][:2]
    read_peak = statistics.median(r["peak_bytes"] for r in reads) / 1e9
    warp_peak = statistics.median(r["peak_bytes"] for r in warps) / 1e9
    read_time = Timing([r["read_s"] for r in reads], [r["read_cpu_s"] for r in reads])
    warp_time = Timing([r["warp_s"] for r in warps], [r["warp_cpu_s"] for r in warps])
    print(f"image: {w} x {h} x {warps[0]['shape'][2]} uint8 = {w * h * 3 / 1e9:.2f} GB of samples; {repeat} children of each kind")
    print(f"  read only:   peak {read_peak:.2f} GB (median), read {read_time}")
    print(f"  read + warp: peak {warp_peak:.2f} GB (median), warp {warp_time}")
    share = warp_peak - read_peak
    print(f"  the warp's own share: {share:.2f} GB = {share * 1e9 / (w * h):.1f} bytes per output pixel")
    small = warp_peak < TARGET_PEAK_GB
    return [
        Row("12k warp peak memory", f"{warp_peak:.2f} GB", f"< {TARGET_PEAK_GB:g} GB (read only {read_peak:.2f})", verdict(small)),
        Row("  12k warp time (median)", f"{warp_time.median:.2f} s", f"read {read_time.median:.2f} s", "info"),
    ]


# --------------------------------------------------------------------------------------
# Putting it together
# --------------------------------------------------------------------------------------
def print_table(rows: list[Row]) -> None:
    """Print the summary: figure, measured, reference or target, verdict."""
    header = Row("figure", "measured", "reference / target", "result")
    widths = [max(len(getattr(r, f)) for r in [header, *rows]) for f in ("figure", "measured", "reference")]
    heading("Summary")
    for r in [header, *rows]:
        print(f"{r.figure:<{widths[0]}}  {r.measured:>{widths[1]}}  {r.reference:<{widths[2]}}  {r.verdict}")


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    """The command-line options."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=5, help="timed runs per figure; medians are reported (default: 5)")
    parser.add_argument("--quick", action="store_true", help="skip the 12k-pixel-wide peak-memory part")
    args = parser.parse_args(argv)
    if args.repeat < 1:
        parser.error("--repeat must be at least 1")
    return args


def main(argv: list[str] | None = None) -> int:
    """Run every part and print the summary table."""
    args = parse_args(argv)
    print(f"omniwidget warp benchmark: Python {sys.version.split()[0]}, numpy {np.__version__}, {args.repeat} timed runs per figure")
    print(f"CPUs: {os.cpu_count()}; load average before starting: {', '.join(f'{x:.2f}' for x in os.getloadavg())} (1, 5, 15 min)")
    rows = bench_in_memory(args.repeat)
    rows += bench_cli(args.repeat)
    if args.quick:
        rows.append(Row("12k warp peak memory", "-", "--quick", "skipped"))
    else:
        rows += bench_big(args.repeat)
    print_table(rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
