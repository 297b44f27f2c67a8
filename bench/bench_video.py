#!/usr/bin/env python
"""A whole 360° video warped by one map: frames per second against FFmpeg's own transcode.

Usage::

    python bench/bench_video.py                      # 2048 x 1024 and 4096 x 2048, 3 timed runs each
    python bench/bench_video.py --sizes 2048 --frames 120 --repeat 5
    python bench/bench_video.py --crf 20 --preset fast

The input clips are made first, in a temporary folder: the bundled panorama scaled to the size
(bicubic), turned a little more each frame (a slow pan) with film grain added (Gaussian,
sigma 2.5 levels, new each frame), 30 frames per second, H.264 (libx264, crf 16, veryfast)
with a stereo AAC tone, in MP4. The map is the command-line demo's handles (two rectified
lines and a cage), computed once from the first frame (its time is printed, not counted).

Timed in turns in one run, each ``--repeat`` times, the same codec settings
(libx264, ``--crf``, ``--preset``, audio copied):

1. ``ffmpeg -i in.mp4 -c:v libx264 -crf C -preset P -c:a copy out.mp4``: FFmpeg's own
   transcode (the Debian binary, whole process): the reference of the target (0.8x);
2. ours: :func:`omniwidget.app.video.warp_video` with the map (decode, warp, encode, mux,
   the spherical metadata), the whole call; "frames only" leaves out what it does once before
   the first frame (open the file, turn the map into pixel coordinates for the luma and the
   chroma planes), which a longer video spreads thinner;
3. PyAV's plain transcode, no warp (decode, encode, mux on the same threads): what the
   FFmpeg libraries bundled with PyAV do alone, to tell our overhead from their speed.

Prints the medians in frames per second and the ratios, and the CPU time each takes per frame
(all its threads: ``getrusage`` of the ffmpeg process, ``process_time`` here), which other
processes on a shared machine disturb less than the wall time; asserts nothing. The machine's
load is printed with each run.
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import av
import cv2
import numpy as np

REPO_ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO_ROOT))

import omniwidget as ow  # noqa: E402
from omniwidget.app.cli import DEMO_HANDLES  # noqa: E402
from omniwidget.app.video import warp_video  # noqa: E402
from omniwidget.sphere.moebius import Moebius  # noqa: E402

RATE = 30


def make_clip(path: Path, width: int, frames: int) -> None:
    """The input clip: the panorama panning, film grain, H.264 in MP4 with an AAC tone."""
    base = cv2.resize(ow.sample_image(), (width, width // 2), interpolation=cv2.INTER_CUBIC)
    rng = np.random.default_rng(21)
    with av.open(str(path), "w") as out:
        video = out.add_stream("libx264", rate=RATE, options={"crf": "16", "preset": "veryfast"})
        video.width, video.height, video.pix_fmt = width, width // 2, "yuv420p"
        video.codec_context.thread_type = "AUTO"
        audio = out.add_stream("aac", rate=48000)
        audio.layout = "stereo"
        for i in range(frames):
            image = ow.warp_moebius(base, Moebius.rotation([0.0, 90.0], 0.4 * i)).image.astype(np.float32)
            image += rng.normal(0.0, 2.5, image.shape).astype(np.float32)
            frame = av.VideoFrame.from_ndarray(np.clip(image + 0.5, 0, 255).astype(np.uint8), format="rgb24")
            frame.pts = i
            out.mux(video.encode(frame))
        out.mux(video.encode(None))
        samples = 48000 * frames // RATE
        tone = (0.2 * np.sin(2 * np.pi * 440.0 * np.arange(samples) / 48000)).astype(np.float32)
        step = audio.codec_context.frame_size or 1024
        for start in range(0, samples, step):
            chunk = tone[start : start + step]
            frame = av.AudioFrame.from_ndarray(np.stack([chunk, chunk]), format="fltp", layout="stereo")
            frame.sample_rate, frame.pts = 48000, start
            out.mux(audio.encode(frame))
        out.mux(audio.encode(None))


def _children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def ffmpeg_transcode(src: Path, dst: Path, crf: int, preset: str) -> tuple[float, float]:
    """Wall and CPU seconds (all threads) of the ffmpeg process."""
    start, cpu = time.perf_counter(), _children_cpu()
    command = ["ffmpeg", "-v", "error", "-y", "-i", str(src), "-c:v", "libx264", "-crf", str(crf), "-preset", preset, "-c:a", "copy", str(dst)]
    subprocess.run(command, check=True)
    return time.perf_counter() - start, _children_cpu() - cpu


def ours(src: Path, dst: Path, inverse_map: np.ndarray, crf: int, preset: str) -> tuple[float, float, float]:
    """Wall and CPU seconds of the whole call, and the wall seconds of its frames alone (after the map's pixel coordinates)."""
    start, cpu = time.perf_counter(), time.process_time()
    report = warp_video(src, dst, inverse_map, crf=crf, preset=preset)
    return time.perf_counter() - start, time.process_time() - cpu, report.seconds


def pyav_plain(src: Path, dst: Path, crf: int, preset: str) -> tuple[float, float]:
    """Decode and encode with the libraries PyAV bundles, audio copied, nothing else."""
    start, cpu = time.perf_counter(), time.process_time()
    with av.open(str(src)) as inp, av.open(str(dst), "w") as out:
        vin = inp.streams.video[0]
        vin.thread_type = "AUTO"
        vout = out.add_stream("libx264", rate=vin.average_rate, options={"crf": str(crf), "preset": preset})
        vout.width, vout.height, vout.pix_fmt = vin.codec_context.width, vin.codec_context.height, "yuv420p"
        vout.time_base = vout.codec_context.time_base = vin.time_base
        vout.codec_context.thread_type = "AUTO"
        aout = {a.index: out.add_stream_from_template(a) for a in inp.streams.audio}
        for packet in inp.demux(vin, *inp.streams.audio):
            if packet.stream.type == "audio":
                if packet.size:
                    packet.stream = aout[packet.stream.index]
                    out.mux(packet)
                continue
            for frame in vin.decode(packet):
                out.mux(vout.encode(frame))
        out.mux(vout.encode(None))
    return time.perf_counter() - start, time.process_time() - cpu


def x264_version(path: Path) -> str:
    """x264's build of a file (its SEI text)."""
    data = path.read_bytes()[:2_000_000]
    at = data.find(b"x264 - core ")
    return data[at + 12 : at + 15].decode("latin-1") if at >= 0 else "?"


def measure(width: int, frames: int, repeat: int, crf: int, preset: str, folder: Path) -> dict[str, float | str]:
    src = folder / f"in_{width}.mp4"
    start = time.perf_counter()
    make_clip(src, width, frames)
    made = time.perf_counter() - start
    with av.open(str(src)) as container:
        first = next(container.decode(video=0)).to_ndarray(format="rgb24")
    start = time.perf_counter()
    inverse_map = ow.warp(first, ow.Handles.from_dict(DEMO_HANDLES), warn=False).inverse_map()
    map_seconds = time.perf_counter() - start
    times: dict[str, list[float]] = {"ffmpeg": [], "ours": [], "plain": [], "frames": []}
    cpu: dict[str, list[float]] = {"ffmpeg": [], "ours": [], "plain": []}
    for k in range(repeat):
        load = os.getloadavg()[0]
        for name, run in (
            ("ffmpeg", lambda: ffmpeg_transcode(src, folder / "ffmpeg.mp4", crf, preset)),
            ("ours", lambda: ours(src, folder / "ours.mp4", inverse_map, crf, preset)),
            ("plain", lambda: pyav_plain(src, folder / "plain.mp4", crf, preset)),
        ):
            wall, seconds, *frames_only = run()
            times[name].append(wall)
            cpu[name].append(seconds)
            times["frames"] += frames_only
        print(
            f"  {width} run {k + 1}: ffmpeg {frames / times['ffmpeg'][-1]:.2f} fps, ours {frames / times['ours'][-1]:.2f} fps, "
            f"PyAV plain {frames / times['plain'][-1]:.2f} fps; CPU ms per frame {1e3 * cpu['ffmpeg'][-1] / frames:.0f}, "
            f"{1e3 * cpu['ours'][-1] / frames:.0f}, {1e3 * cpu['plain'][-1] / frames:.0f}; ours before the first frame "
            f"{times['ours'][-1] - times['frames'][-1]:.2f} s (load {load:.1f})",
            flush=True,
        )
    medians = {k: statistics.median(v) for k, v in times.items()}
    return {
        **{f"{k}_fps": frames / v for k, v in medians.items()},
        **{f"{k}_cpu": 1e3 * statistics.median(v) / frames for k, v in cpu.items()},
        "map": map_seconds,
        "made": made,
        "x264_ffmpeg": x264_version(folder / "ffmpeg.mp4"),
        "x264_pyav": x264_version(folder / "ours.mp4"),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[2048, 4096], help="widths (default: 2048 4096)")
    parser.add_argument("--frames", type=int, nargs="+", default=None, help="frames per clip, one per size (default: 90 at 2048, 45 at 4096)")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--crf", type=int, default=18)
    parser.add_argument("--preset", default="medium")
    args = parser.parse_args()
    if shutil.which("ffmpeg") is None:
        sys.exit("bench_video.py needs the ffmpeg binary (apt-get install ffmpeg)")
    frames = args.frames or [90 if w <= 2048 else 45 for w in args.sizes]
    version = subprocess.run(["ffmpeg", "-version"], capture_output=True, text=True).stdout.split("\n")[0]
    print(f"{version}; PyAV {av.__version__} with FFmpeg {av.ffmpeg_version_info}; {os.cpu_count()} CPUs")
    print(f"libx264 crf {args.crf}, preset {args.preset}, audio copied; medians of {args.repeat} runs, in turns")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for width, count in zip(args.sizes, frames, strict=True):
            print(f"{width} x {width // 2}, {count} frames:", flush=True)
            rows.append((width, count, measure(width, count, args.repeat, args.crf, args.preset, Path(tmp))))
    print()
    print("| size | frames | ffmpeg fps | ours fps | ours / ffmpeg | PyAV plain fps | ours / plain | ours, frames only | map (once) |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for width, count, r in rows:
        ff, us, plain, frames_only, map_seconds = (float(r[k]) for k in ("ffmpeg_fps", "ours_fps", "plain_fps", "frames_fps", "map"))
        print(
            f"| {width} x {width // 2} | {count} | {ff:.2f} | {us:.2f} | {us / ff:.2f} | {plain:.2f} | {us / plain:.2f} | "
            f"{frames_only:.2f} | {map_seconds:.2f} s |"
        )
    print()
    print("CPU time per frame, all threads (ms; medians): what the frame rates would be on an idle machine, as ratios")
    print("| size | ffmpeg | ours | PyAV plain | ffmpeg / ours | plain / ours |")
    print("| --- | --- | --- | --- | --- | --- |")
    for width, _, r in rows:
        ff, us, plain = (float(r[k]) for k in ("ffmpeg_cpu", "ours_cpu", "plain_cpu"))
        print(f"| {width} x {width // 2} | {ff:.0f} | {us:.0f} | {plain:.0f} | {ff / us:.2f} | {plain / us:.2f} |")
    print(f"x264: the ffmpeg binary's core {rows[0][2]['x264_ffmpeg']}, PyAV's core {rows[0][2]['x264_pyav']}")


if __name__ == "__main__":
    main()
