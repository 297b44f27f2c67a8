#!/usr/bin/env python
"""Suggested lines and levelling against a plain detector on the six cube faces, run on demand (not a test).

Usage::

    python bench/bench_detect.py                 # 2048 x 1024, 5 runs each, in turns
    python bench/bench_detect.py --width 4096 --repeat 3
    python bench/bench_detect.py --detector hough
    python bench/bench_detect.py --photos ../shared/data            # every panorama there, as read
    python bench/bench_detect.py --photos ../shared/data --process  # and the two commands, whole process
    python bench/bench_detect.py --photos ../shared/data --profile grabodrertorv.jpg

The input is a generated room (:func:`omniwidget.evaluate.scenes.synthetic_room`, grid,
noise, tilted) resampled to the width asked, or with ``--photos`` each panorama of a folder
(read as the commands read it; the functions reduce one wider than
:data:`omniwidget.detect.lines.DETECT_WIDTH` themselves). Timed, in turns so that the shared
machine's load falls on all alike: the plain detector on the six cube faces (rendering the
faces and detecting, no lifting or merging: the floor the suggestions cannot go below),
:func:`omniwidget.suggest_lines` (the structure chosen), ``suggest_lines(structure=False)`` (every
line, ranked: what the choice costs is the ratio of the two) and :func:`omniwidget.level` (which
detects too). Printed:
medians in seconds and each one's ratio to the plain detector. ``--process`` also times
``omniwidget suggest IMG -o h.json`` and ``omniwidget level IMG -o out.jpg`` as new
processes (median of ``--process-repeat``); ``--profile NAME`` prints cProfile's top
functions of ``suggest_lines`` and ``level`` on that panorama.
"""

from __future__ import annotations

import argparse
import cProfile
import os
import pstats
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from functools import partial
from pathlib import Path

import numpy as np

import omniwidget as ow
from omniwidget.detect.lines import cube_views, detect_segments, panorama_gray, render_view
from omniwidget.evaluate.scenes import synthetic_room

SUFFIXES = (".jpg", ".jpeg", ".png", ".tif", ".tiff", ".webp")


def plain(image: np.ndarray, detector: str) -> int:
    """The detector alone on the six cube faces; returns the number of segments."""
    gray = panorama_gray(image)
    return sum(len(detect_segments(render_view(gray, view), detector)[0]) for view in cube_views(gray.shape[1]))


def _level(image: np.ndarray) -> object:
    """:func:`omniwidget.level` as the command runs it (its own detection); a refusal is a result too."""
    try:
        return ow.level(image)
    except ow.LevelError as exc:
        return exc


def timed(runs: dict[str, Callable[[], object]], repeat: int) -> dict[str, list[float]]:
    """Each run once to warm up, then ``repeat`` times in turns: the seconds of each."""
    times: dict[str, list[float]] = {name: [] for name in runs}
    for run in runs.values():  # warm up: imports, OpenCV's first calls
        run()
    for _ in range(repeat):
        for name, run in runs.items():
            start = time.perf_counter()
            run()
            times[name].append(time.perf_counter() - start)
    return times


def report(times: dict[str, list[float]], base_name: str, indent: str = "  ") -> dict[str, float]:
    """Print the medians and their ratios to ``base_name``'s; return the medians."""
    medians = {name: statistics.median(v) for name, v in times.items()}
    base = medians[base_name]
    for name, m in medians.items():
        print(
            f"{indent}{name:26s} {m:7.3f} s  ({m / base:4.2f} x the plain detector; fastest {min(times[name]):.3f}, slowest {max(times[name]):.3f})"
        )
    return medians


def process_times(path: Path, repeat: int) -> dict[str, float]:
    """Medians of ``repeat`` runs of ``omniwidget suggest`` and ``omniwidget level`` on ``path``, whole process, seconds."""
    out: dict[str, list[float]] = {"suggest": [], "level": []}
    with tempfile.TemporaryDirectory() as tmp:
        commands = {
            "suggest": [sys.executable, "-m", "omniwidget", "suggest", str(path), "-o", f"{tmp}/h.json"],
            "level": [sys.executable, "-m", "omniwidget", "level", str(path), "-o", f"{tmp}/out.jpg"],
        }
        for _ in range(repeat):
            for name, command in commands.items():
                start = time.perf_counter()
                subprocess.run(command, check=False, capture_output=True)
                out[name].append(time.perf_counter() - start)
    return {name: statistics.median(v) for name, v in out.items()}


def photos(folder: Path, args: argparse.Namespace) -> None:
    """The medians on every panorama of ``folder`` (and the commands' whole-process times with ``--process``)."""
    from omniwidget.io.images import read_panorama

    paths = sorted(p for p in folder.iterdir() if p.suffix.lower() in SUFFIXES)
    rows = []
    for path in paths:
        image = read_panorama(path)
        if args.profile is not None:
            if path.name != args.profile:
                continue
            calls: tuple[tuple[str, Callable[[], object]], ...] = (
                ("suggest_lines", partial(ow.suggest_lines, image)),
                ("level", partial(_level, image)),
            )
            for what, call in calls:
                profile = cProfile.Profile()
                profile.runcall(call)
                print(f"{path.name}: {what}")
                pstats.Stats(profile).sort_stats("cumulative").print_stats(25)
            continue
        runs: dict[str, Callable[[], object]] = {
            "plain detector, 6 faces": partial(plain, image, args.detector),
            "suggest_lines": partial(ow.suggest_lines, image, detector=args.detector),
            "suggest_lines, raw": partial(ow.suggest_lines, image, detector=args.detector, structure=False),
            "level": partial(_level, image),
        }
        load = " / ".join(f"{x:.1f}" for x in os.getloadavg())
        print(f"{path.name} ({image.shape[1]} x {image.shape[0]}), medians of {args.repeat} runs in turns (load average {load})")
        medians = report(timed(runs, args.repeat), "plain detector, 6 faces", "    ")
        print(f"    the structure's choice: {medians['suggest_lines'] / medians['suggest_lines, raw']:.2f} x suggest_lines(structure=False)")
        whole = process_times(path, args.process_repeat) if args.process else {}
        if whole:
            print(f"    whole process: suggest {whole['suggest']:.2f} s, level {whole['level']:.2f} s (medians of {args.process_repeat})")
        rows.append((path.name, image.shape, medians, whole))
    if rows:
        print("\n| panorama | size | plain LSD | `suggest_lines` | `level` | `omniwidget suggest` | `omniwidget level` |")
        print("| --- | --- | --- | --- | --- | --- | --- |")
        for name, shape, m, whole in rows:
            base = m["plain detector, 6 faces"]
            cells = [f"{m[k]:.3f} s ({m[k] / base:.2f}x)" for k in ("suggest_lines", "level")]
            procs = [f"{whole[k]:.2f} s" if whole else "" for k in ("suggest", "level")]
            print(f"| {name} | {shape[1]} x {shape[0]} | {base:.3f} s | {' | '.join(cells)} | {' | '.join(procs)} |")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--width", type=int, default=2048)
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--detector", choices=("lsd", "hough"), default="lsd")
    parser.add_argument("--photos", type=Path, help="time every panorama of this folder instead of a generated room")
    parser.add_argument("--process", action="store_true", help="with --photos: the two commands' whole-process times too")
    parser.add_argument("--process-repeat", type=int, default=3)
    parser.add_argument("--profile", metavar="NAME", help="with --photos: cProfile suggest_lines and level on this panorama only")
    args = parser.parse_args()
    if args.photos is not None:
        photos(args.photos, args)
        return 0
    image = synthetic_room(args.width, grid=1.0, noise=4.0, seed=0, pitch=6.0, roll=-4.0).image
    runs = {
        "plain detector, 6 faces": lambda: plain(image, args.detector),
        "suggest_lines": lambda: ow.suggest_lines(image, detector=args.detector),
        "suggest_lines, raw": lambda: ow.suggest_lines(image, detector=args.detector, structure=False),
        "level": lambda: ow.level(image, suggestions=ow.suggest_lines(image, max_lines=None, detector=args.detector, structure=False)),
    }
    times = timed(runs, args.repeat)
    print(f"{args.width} x {args.width // 2}, detector {args.detector}, medians of {args.repeat} runs in turns")
    medians = report(times, "plain detector, 6 faces")
    print(f"  the structure's choice: suggest_lines {medians['suggest_lines'] / medians['suggest_lines, raw']:.2f} x suggest_lines(structure=False)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
