#!/usr/bin/env python
"""A video cut into time ranges and joined again: what the cuts cost.

Usage::

    python bench/bench_video_ranges.py                       # 2048 x 1024, 150 frames (5 s), ranges of 1 s
    python bench/bench_video_ranges.py --frames 300 --segment-seconds 2 --repeat 3
    python bench/bench_video_ranges.py --keyint 250    # key frames as rare as x264's default

The clip is bench_video.py's (the panorama panning with film grain, H.264 with an AAC tone,
30 fps), with a key frame every ``--keyint`` frames (default 30: a second, as 360° cameras
write them; a range is decoded from the key frame before its start, so rarer key frames
cost decoding). Timed in turns, ``--repeat`` times each, the same map and codec settings (libx264
crf 18, medium):

1. ``warp_video``: the whole video in one call, in this process;
2. ``warp_files`` in-process: the video cut into ranges of about ``--segment-seconds``,
   warped one after another, then joined without re-encoding (``join_video_segments``);
3. ``warp_files`` on a ``LocalCluster`` of two worker processes of one thread each: the
   same ranges as tasks, then the join (its bytes are those of 2).

Prints the medians (wall seconds, frames per second, the join's seconds) and the sizes of
the outputs: each range starts with a key frame, which costs bit rate. This machine has two
cores, which one whole warp already keeps busy (decoding, resampling and encoding overlap on
threads), so a cluster of two processes here shows the cost of the cuts and of the
scheduling, not the speed of many machines. Asserts nothing.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO_ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO_ROOT))
sys.path.insert(0, str(REPO_ROOT / "bench"))

from bench_video import make_clip  # noqa: E402

import omniwidget as ow  # noqa: E402
from omniwidget.app.batch import warp_files  # noqa: E402
from omniwidget.app.cli import DEMO_HANDLES  # noqa: E402
from omniwidget.app.video import warp_video  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--width", type=int, default=2048)
    parser.add_argument("--frames", type=int, default=150)
    parser.add_argument("--segment-seconds", type=float, default=1.0)
    parser.add_argument("--repeat", type=int, default=2)
    parser.add_argument("--keyint", type=int, default=30, help="frames from one key frame of the input to the next (default 30)")
    args = parser.parse_args()
    from distributed import Client, LocalCluster

    handles = ow.Handles.from_dict(DEMO_HANDLES)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        clip = folder / "clip.mp4"
        make_clip(folder / "made.mp4", args.width, args.frames)
        command = ["ffmpeg", "-v", "error", "-i", str(folder / "made.mp4"), "-c:v", "libx264", "-crf", "16", "-preset", "veryfast"]
        subprocess.run([*command, "-g", str(args.keyint), "-c:a", "copy", str(clip)], check=True)
        the_map = ow.warp(np.zeros((args.width // 2, args.width, 3), np.uint8), handles, warn=False).inverse_map()
        np.save(folder / "map.npy", the_map)
        times: dict[str, list[float]] = {"whole": [], "ranges here": [], "ranges on 2 workers": []}
        sizes: dict[str, int] = {}
        segments = 0
        with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0") as cluster, Client(cluster) as client:
            client.wait_for_workers(2)
            for k in range(args.repeat):
                out = folder / f"whole{k}.mp4"
                tick = time.perf_counter()
                warp_video(clip, out, the_map)
                times["whole"].append(time.perf_counter() - tick)
                sizes["whole"] = out.stat().st_size
                for name, run in (("ranges here", {}), ("ranges on 2 workers", {"client": client})):
                    target = folder / f"{name.replace(' ', '_')}{k}"
                    tick = time.perf_counter()
                    report = warp_files([clip], target, map=folder / "map.npy", segment_seconds=args.segment_seconds, **run)
                    times[name].append(time.perf_counter() - tick)
                    if not report.ok:
                        sys.exit(report.summary())
                    segments = report.files[0].segments
                    sizes[name] = (target / "clip.mp4").stat().st_size
        print(f"{args.width} x {args.width // 2}, {args.frames} frames, a key frame every {args.keyint}, {segments} ranges of about {args.segment_seconds:g} s; medians of {args.repeat}")
        print("| run | seconds | frames per second | against the whole | output size against the whole |")
        print("| --- | --- | --- | --- | --- |")
        whole = statistics.median(times["whole"])
        for name, values in times.items():
            m = statistics.median(values)
            print(f"| {name} | {m:.2f} | {args.frames / m:.2f} | {whole / m:.2f}x | {sizes[name] / sizes['whole']:.3f} |")


if __name__ == "__main__":
    main()
