"""Videos in and out: ``omniwidget warp IN.mp4 ... -o OUT.mp4``, :mod:`omniwidget.io.video`, :mod:`omniwidget.io.spherical`.

The clips are made here, once per session, in a temporary folder: the bundled panorama at
512 x 256 turned 2° more each frame (``warp_moebius``), 24 frames at 24 fps, H.264 with a
stereo AAC tone; a 10-bit HEVC clip; and the bad ones (text named .mp4, audio only, 3:2,
cut short, damaged). What the warp writes is checked with tools that share none of its code:
Debian's ``ffprobe`` (time stamps, durations, the "Spherical Mapping" side data, pixel
formats) and PyAV's decoder (frames, audio packets byte for byte).

PyAV and ffprobe are needed: without them the tests are skipped, except when
``OMNIWIDGET_BROWSER_TESTS=1`` (CI), where they fail.

Quality bound. Each warped frame is compared with ``ow.warp`` of the decoded input frame
(PSNR over the RGB frame; the handles are the demo's in the paper's mode, which move the
whole sphere: input and output are 17 dB apart). The differences are the encoder's loss
(libx264 crf 18) and the 4:2:0 chroma: the output's chroma planes are resampled at half
resolution, where ``ow.warp`` resamples full RGB. With a lossless encode (crf 0) that alone
measures 48.4-49.7 dB (converting ``ow.warp``'s RGB output to 4:2:0 with FFmpeg's swscale
instead measures 43.9-44.2 dB). At crf 18 the frames measured 39.5-41.4 dB (crf 23:
37.2-39.0; 10-bit, libx265 crf 20: 40.6-43.2; libx264 10-bit crf 18: 40.9-42.9). The bound
is 37 dB, 2.5 dB under the worst frame; a frame off by one (2° of turn, 3 px) measures
24-25 dB. Chroma weighs little in that figure (chroma planes one chroma pixel off still
measure 38 dB), so the chroma planes are compared on their own too, with ``ow.warp``'s
output converted to YUV by swscale and averaged over 2 x 2: measured 50.2-51.1 dB; planes
one chroma pixel off measure 44.7-45.6 dB; the bound is 47 dB.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import struct
import subprocess
import sys
import threading
import time
from fractions import Fraction
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

import omniwidget as ow
from omniwidget.app.cli import DEMO_HANDLES, main
from omniwidget.sphere import coords
from omniwidget.sphere.moebius import Moebius

STRICT = os.environ.get("OMNIWIDGET_BROWSER_TESTS") == "1"
SIZE = (512, 256)
FRAMES = 24
RATE = 24
PSNR_BOUND = 37.0
CHROMA_PSNR_BOUND = 47.0
#: The demo's handles in the paper's mode (no still background): the whole sphere moves, the
#: output is far from the input (17 dB), so the quality bound cannot be met by doing nothing.
HANDLES = {**DEMO_HANDLES, "options": {"rectify": "all", "anchor": None}}


def _require_tools() -> None:
    missing = []
    try:
        import av  # noqa: F401
    except ImportError:
        missing.append("PyAV (pip install 'omniwidget[video]')")
    if shutil.which("ffprobe") is None or shutil.which("ffmpeg") is None:
        missing.append("ffprobe and ffmpeg (apt-get install ffmpeg)")
    if missing:
        reason = f"the video tests need {' and '.join(missing)}"
        if STRICT:
            pytest.fail(f"{reason}; OMNIWIDGET_BROWSER_TESTS=1 forbids skipping", pytrace=False)
        pytest.skip(reason)


@pytest.fixture(autouse=True)
def _tools():
    _require_tools()


# --- making clips ------------------------------------------------------------------------------


def _frames(count: int, depth: int = 8) -> list[np.ndarray]:
    import cv2

    base = cv2.resize(ow.sample_image(), SIZE, interpolation=cv2.INTER_AREA)
    if depth == 16:
        base = base.astype(np.uint16) * 257
    return [ow.warp_moebius(base, Moebius.rotation([30.0, 20.0], 2.0 * i)).image for i in range(count)]


def _encode(path: Path, frames, *, codec="libx264", pix_fmt="yuv420p", audio=True, options=None, container_options=None, repeat=1):
    """Frames (RGB uint8 or uint16) to a video file; ``repeat`` plays them over that many times."""
    import av

    with av.open(str(path), "w", options=container_options or {}) as out:
        video = out.add_stream(codec, rate=RATE, options={"crf": "16", "preset": "fast", **(options or {})})
        video.width, video.height = frames[0].shape[1], frames[0].shape[0]
        video.pix_fmt = pix_fmt
        if audio:
            sound = out.add_stream("aac", rate=48000)
            sound.layout = "stereo"
        for i in range(len(frames) * repeat):
            image = frames[i % len(frames)]
            frame = av.VideoFrame.from_ndarray(image, format="rgb48le" if image.dtype == np.uint16 else "rgb24")
            frame.pts = i
            out.mux(video.encode(frame))
        out.mux(video.encode(None))
        if audio:
            samples = 48000 * len(frames) * repeat // RATE
            tone = (0.25 * np.sin(2 * np.pi * 440.0 * np.arange(samples) / 48000)).astype(np.float32)
            step = sound.codec_context.frame_size or 1024
            for start in range(0, samples, step):
                chunk = tone[start : start + step]
                frame = av.AudioFrame.from_ndarray(np.stack([chunk, chunk]), format="fltp", layout="stereo")
                frame.sample_rate, frame.pts = 48000, start
                out.mux(sound.encode(frame))
            out.mux(sound.encode(None))


def _boxes(data: bytes, start: int, end: int):
    while start + 8 <= end:
        size, kind = struct.unpack_from(">I4s", data, start)
        yield kind, start, start + size
        start += size


def _add_v1_metadata(path: Path) -> None:
    """Put Spherical Video V1 metadata (XMP in a ``uuid`` box) at the end of the video ``trak``; ``moov`` must be last.

    Written here by hand, not by omniwidget.io.spherical, so that reading it is checked
    against FFmpeg's own reader.
    """
    data = bytearray(path.read_bytes())
    kind, moov, moov_end = [b for b in _boxes(data, 0, len(data)) if b[0] == b"moov"][0]
    assert moov_end == len(data)
    trak = next(b for b in _boxes(data, moov + 8, moov_end) if b[0] == b"trak" and b"vide" in data[b[1] : b[2]])
    xml = (
        b'<rdf:SphericalVideo xmlns:rdf="http://www.w3.org/1999/02/22-rdf-syntax-ns#" '
        b'xmlns:GSpherical="http://ns.google.com/videos/1.0/spherical/">'
        b"<GSpherical:Spherical>true</GSpherical:Spherical><GSpherical:Stitched>true</GSpherical:Stitched>"
        b"<GSpherical:StitchingSoftware>omniwidget tests</GSpherical:StitchingSoftware>"
        b"<GSpherical:ProjectionType>equirectangular</GSpherical:ProjectionType></rdf:SphericalVideo>"
    )
    box = struct.pack(">I4s", 24 + len(xml), b"uuid") + bytes.fromhex("ffcc8263f8554a938814587a02521fdd") + xml
    data[trak[2] : trak[2]] = box
    for start in (moov, trak[1]):
        struct.pack_into(">I", data, start, struct.unpack_from(">I", data, start)[0] + len(box))
    path.write_bytes(bytes(data))


@pytest.fixture(scope="session")
def clips(tmp_path_factory):
    """The clips, made once: ``plain`` (no spherical metadata), ``v1`` (the same with V1 metadata), ``deep`` (10-bit), bad ones."""
    _require_tools()
    import av

    folder = tmp_path_factory.mktemp("clips")
    frames = _frames(FRAMES)
    c = SimpleNamespace(folder=folder)
    c.plain = folder / "plain.mp4"
    _encode(c.plain, frames)
    c.v1 = folder / "v1.mp4"
    shutil.copy(c.plain, c.v1)
    _add_v1_metadata(c.v1)
    c.deep_codec = "libx265" if "libx265" in av.codecs_available else "libx264"
    c.deep = folder / "deep.mp4"
    _encode(c.deep, _frames(12, depth=16), codec=c.deep_codec, pix_fmt="yuv420p10le", audio=False, options={"x265-params": "log-level=error"})
    c.handles = folder / "handles.json"
    c.handles.write_text(json.dumps(HANDLES))

    # bad ones
    c.text = folder / "notes.mp4"
    c.text.write_text("these are notes, not a video\n" * 20)
    c.audio = folder / "sound.mp4"
    with av.open(str(c.audio), "w") as out:
        sound = out.add_stream("aac", rate=48000)
        sound.layout = "mono"
        for start in range(0, 48000, 1024):
            frame = av.AudioFrame.from_ndarray(np.zeros((1, 1024), np.float32), format="fltp", layout="mono")
            frame.sample_rate, frame.pts = 48000, start
            out.mux(sound.encode(frame))
        out.mux(sound.encode(None))
    c.wide = folder / "wide.mp4"
    _encode(c.wide, [np.ascontiguousarray(f[:, 64:448]) for f in frames[:4]], audio=False)  # 384 x 256: 3:2
    c.faststart = folder / "faststart.mp4"  # moov first: the media data after it
    _encode(c.faststart, frames, container_options={"movflags": "+faststart"})
    data = c.faststart.read_bytes()
    c.cut_media = folder / "cut_media.mp4"
    c.cut_media.write_bytes(data[: len(data) // 2])
    data = c.plain.read_bytes()
    c.cut_moov = folder / "cut_moov.mp4"  # moov last: cut, the index is gone
    c.cut_moov.write_bytes(data[: len(data) * 2 // 3])
    c.damaged = folder / "damaged.mp4"  # a fifth of the media data overwritten in the middle
    damaged = bytearray(data)
    rng = np.random.default_rng(21)
    span = slice(len(data) * 2 // 5, len(data) * 3 // 5)
    damaged[span] = rng.integers(0, 256, span.stop - span.start, dtype=np.uint8).tobytes()
    c.damaged.write_bytes(bytes(damaged))
    c.mkv = folder / "clip.mkv"
    subprocess.run(["ffmpeg", "-v", "error", "-y", "-i", str(c.plain), "-c", "copy", str(c.mkv)], check=True)
    data = c.mkv.read_bytes()
    c.cut_mkv = folder / "cut.mkv"  # Matroska has no index to miss: the stream just ends early
    c.cut_mkv.write_bytes(data[: len(data) // 2])
    return c


# --- reading what was written ------------------------------------------------------------------


def _ffprobe(path: Path, *args: str) -> dict:
    out = subprocess.run(["ffprobe", "-v", "error", *args, "-print_format", "json", str(path)], capture_output=True, text=True, check=True)
    return json.loads(out.stdout)


def _spherical_side_data(path: Path) -> list[dict]:
    streams = _ffprobe(path, "-show_streams", "-select_streams", "v")["streams"]
    return [d for d in streams[0].get("side_data_list", []) if d.get("side_data_type") == "Spherical Mapping"]


def _decoded(path: Path, fmt: str = "rgb24"):
    """Each video frame as ``(time stamp in seconds as a Fraction, array)``."""
    import av

    with av.open(str(path)) as container:
        return [(f.pts * f.time_base, f.to_ndarray(format=fmt)) for f in container.decode(video=0)]


def _audio_packets(path: Path):
    import av

    with av.open(str(path)) as container:
        stream = container.streams.audio[0]
        return [(bytes(p), p.pts * p.time_base, p.dts * p.time_base, p.duration * p.time_base) for p in container.demux(stream) if p.size]


def _psnr(a: np.ndarray, b: np.ndarray, peak: float) -> float:
    mse = float(np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2))
    return float("inf") if mse == 0 else 10 * np.log10(peak**2 / mse)


def _chroma_psnr(reference_rgb: np.ndarray, yuv420p: np.ndarray) -> float:
    """PSNR of a decoded frame's two chroma planes against an RGB frame's, made by swscale and averaged over 2 x 2."""
    import av

    h, w = reference_rgb.shape[:2]
    full = av.VideoFrame.from_ndarray(reference_rgb, format="rgb24").reformat(format="yuv444p").to_ndarray().reshape(3, h, w)
    expected = full[1:].astype(np.float64).reshape(2, h // 2, 2, w // 2, 2).mean(axis=(2, 4))
    got = yuv420p[h:].reshape(2, h // 2, w // 2)
    return _psnr(expected, got, 255.0)


def _leftovers(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.endswith(".part"))


# --- the round trip ------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def warped(clips, tmp_path_factory):
    """``omniwidget warp v1.mp4 -H handles.json -o out.mp4 --map map.npy``, in this process."""
    folder = tmp_path_factory.mktemp("warped")
    out, saved = folder / "out.mp4", folder / "map.npy"
    code = main(["warp", str(clips.v1), "-H", str(clips.handles), "-o", str(out), "--map", str(saved)])
    assert code == 0
    return SimpleNamespace(folder=folder, out=out, map=saved)


def test_frames_and_time_stamps_are_kept(clips, warped):
    before, after = _decoded(clips.v1), _decoded(warped.out)
    assert len(after) == len(before) == FRAMES
    assert [t for t, _ in after] == [t for t, _ in before] == [Fraction(i, RATE) for i in range(FRAMES)]
    a = _ffprobe(clips.v1, "-show_format", "-show_streams")
    b = _ffprobe(warped.out, "-show_format", "-show_streams")
    assert b["format"]["duration"] == a["format"]["duration"]
    for sa, sb in zip(a["streams"], b["streams"], strict=True):
        keys = ("codec_type", "duration", "duration_ts", "time_base", "r_frame_rate", "avg_frame_rate", "nb_frames", "start_pts")
        assert {k: sb.get(k) for k in keys} == {k: sa.get(k) for k in keys}
        if sa["codec_type"] == "audio":
            assert {k: sb.get(k) for k in ("codec_name", "sample_rate", "channels")} == {k: sa.get(k) for k in ("codec_name", "sample_rate", "channels")}


def test_the_audio_is_copied_packet_for_packet(clips, warped):
    before, after = _audio_packets(clips.v1), _audio_packets(warped.out)
    assert len(before) > 40
    assert after == before  # the bytes, and the time stamps and durations in seconds


def test_the_spherical_metadata_is_carried_over(clips, warped):
    assert _spherical_side_data(clips.plain) == []
    (given,) = _spherical_side_data(clips.v1)  # version 1 XMP, read by FFmpeg
    assert given["projection"] == "equirectangular"
    (kept,) = _spherical_side_data(warped.out)  # written as version 2 (sv3d)
    assert kept["projection"] == "equirectangular" and (kept.get("yaw"), kept.get("pitch"), kept.get("roll")) == (0, 0, 0)


def test_each_frame_is_the_warp_of_the_input_frame_within_the_codec_loss(clips, warped):
    handles = ow.Handles.from_dict(HANDLES)
    before, after = _decoded(clips.v1), _decoded(warped.out)
    first = ow.warp(before[0][1], handles, warn=False)
    planes = _decoded(warped.out, "yuv420p")
    figures, chroma = [], []
    for (_, src), (_, out), (_, yuv) in zip(before, after, planes, strict=True):
        reference = ow.warp(src, handles, warn=False, previous=first).image  # the weights of the first frame, as they are
        figures.append(_psnr(reference, out, 255.0))
        chroma.append(_chroma_psnr(reference, yuv))
    message = "PSNR per frame (dB): " + ", ".join(f"{p:.1f}" for p in figures) + "; chroma: " + ", ".join(f"{p:.1f}" for p in chroma)
    assert min(figures) >= PSNR_BOUND and min(chroma) >= CHROMA_PSNR_BOUND, message
    # and the frames differ from the input: the warp did something
    assert _psnr(before[0][1], after[0][1], 255.0) < 25, message
    saved = np.load(warped.map)
    assert saved.shape == (256, 512, 2) and np.allclose(saved, first.inverse_map(), atol=1e-4)


def test_the_command_runs_as_a_program_with_a_saved_map_and_gives_the_same_video(clips, warped):
    out = warped.folder / "again.mp4"
    run = subprocess.run(
        [sys.executable, "-m", "omniwidget", "warp", str(clips.v1), "--apply-map", str(warped.map), "-o", str(out), "--progress"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert run.returncode == 0, run.stderr
    *progress, closing = run.stderr.splitlines()
    assert closing.startswith(f"omniwidget warp: wrote {out} ({FRAMES} frame(s) of 512 x 256) in ") and "1 audio stream(s) copied" in closing
    assert f"{FRAMES}/{FRAMES} frames" in progress[-1]  # --progress: lines on a pipe, the last one complete
    assert closing.endswith(f"; by the map {warped.map}") and run.stdout == ""
    first, again = _decoded(warped.out), _decoded(out)
    assert all(np.array_equal(a, b) and ta == tb for (ta, a), (tb, b) in zip(first, again, strict=True))
    assert _audio_packets(out) == _audio_packets(clips.v1)
    assert _leftovers(warped.folder) == []


def test_spherical_adds_the_metadata_to_a_video_without_it(clips, tmp_path, capsys):
    plain, marked = tmp_path / "plain.mp4", tmp_path / "marked.mp4"
    assert main(["warp", str(clips.plain), "-H", str(clips.handles), "-o", str(plain)]) == 0
    assert main(["warp", str(clips.plain), "-H", str(clips.handles), "-o", str(marked), "--spherical", "--crf", "23", "--preset", "veryfast"]) == 0
    assert "spherical metadata written" in capsys.readouterr().err
    assert _spherical_side_data(plain) == []
    (added,) = _spherical_side_data(marked)
    assert added["projection"] == "equirectangular"
    assert len(_decoded(marked)) == FRAMES


def test_ten_bits_in_ten_bits_out(clips, tmp_path):
    out = tmp_path / "deep.mp4"
    assert main(["warp", str(clips.deep), "-H", str(clips.handles), "-o", str(out)]) == 0
    (stream,) = _ffprobe(out, "-show_streams")["streams"]
    assert stream["pix_fmt"] == "yuv420p10le"
    assert stream["codec_name"] == {"libx265": "hevc", "libx264": "h264"}[clips.deep_codec]
    handles = ow.Handles.from_dict(HANDLES)
    before, after = _decoded(clips.deep, "rgb48le"), _decoded(out, "rgb48le")
    assert len(after) == len(before) == 12 and after[0][1].dtype == np.uint16
    first = ow.warp(before[0][1], handles, warn=False)
    figures = [_psnr(ow.warp(a, handles, warn=False, previous=first).image, b, 65535.0) for (_, a), (_, b) in zip(before, after, strict=True)]
    assert min(figures) >= PSNR_BOUND, "PSNR per frame (dB, 16-bit RGB): " + ", ".join(f"{p:.1f}" for p in figures)
    # the samples keep 10 bits: an 8-bit path would leave every 10-bit luma sample a multiple of 4
    import av

    with av.open(str(out)) as container:
        frame = list(container.decode(video=0))[5]
        plane = frame.planes[0]
        luma = np.frombuffer(plane, np.uint16).reshape(plane.height, -1)[:, : plane.width]
    assert luma.max() <= 1023 and np.mean(luma % 4 != 0) > 0.5


def test_a_matroska_input_keeps_its_spherical_metadata_through_ffmpegs_side_data(clips, tmp_path):
    from omniwidget.io.spherical import Spherical, write_spherical
    from omniwidget.io.video import probe_video

    marked, mkv, out = tmp_path / "marked.mp4", tmp_path / "marked.mkv", tmp_path / "out.mp4"
    shutil.copy(clips.plain, marked)
    write_spherical(marked, Spherical(yaw=30.0, pitch=5.0, roll=-2.0))
    subprocess.run(["ffmpeg", "-v", "error", "-y", "-i", str(marked), "-c", "copy", str(mkv)], check=True)  # FFmpeg writes Matroska's Projection
    found = probe_video(mkv).spherical
    assert found is not None and found.source == "side data"
    assert (found.projection, found.yaw, found.pitch, found.roll) == ("equirectangular", 30.0, 5.0, -2.0)
    assert main(["warp", str(mkv), "-H", str(clips.handles), "-o", str(out), "--preset", "veryfast"]) == 0
    (kept,) = _spherical_side_data(out)
    assert (kept["yaw"], kept["pitch"], kept["roll"]) == (30, 5, -2)


# --- bad input -----------------------------------------------------------------------------------

BAD = {
    "text": "not a video FFmpeg can read (it looks like a text file)",
    "audio": "has no video stream (only audio: aac)",
    "wide": "the frames are 384 x 256, not 2:1",
    "cut_media": "the file looks truncated (its 'mdat' box runs",
    "cut_moov": "the file looks truncated (its 'mdat' box runs",  # the moov after it is gone
    "damaged": "the video stream is broken after frame",
    "cut_mkv": "the video stream ends after",
}


@pytest.mark.parametrize("case", list(BAD))
def test_a_bad_video_gives_one_line_exit_2_and_no_output(clips, tmp_path, capsys, case):
    source = getattr(clips, case)
    out = tmp_path / "out.mp4"
    code = main(["warp", str(source), "-H", str(clips.handles), "-o", str(out)])
    err = capsys.readouterr().err
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"omniwidget warp: error: {source}: "), err
    assert BAD[case] in lines[0], lines[0]
    assert not out.exists() and list(tmp_path.iterdir()) == []  # no output and no temporary file


def test_a_video_broken_after_frames_were_encoded_leaves_nothing(clips, tmp_path, capsys):
    """The damaged clip decodes some frames first: they were encoded, and must not be passed off as the video."""
    import av

    from omniwidget.app.video import warp_video

    decodable = 0
    with av.open(str(clips.damaged)) as container, pytest.raises(av.FFmpegError):
        for _ in container.decode(video=0):
            decodable += 1
    assert decodable > 0  # the test's precondition
    done = []
    with pytest.raises(ow.OmniwidgetError, match="broken"):
        warp_video(clips.damaged, tmp_path / "out.mp4", _identity_map(256), progress=lambda d, t: done.append(d))
    assert done and list(tmp_path.iterdir()) == []


def test_wrong_outputs_and_options_are_refused_before_any_work(clips, tmp_path, capsys):
    cases = {
        "the output video must end in .mp4, .m4v, .mov": ["-o", str(tmp_path / "out.mkv")],
        "would overwrite the input": ["-o", str(clips.plain)],
        "no such video encoder": ["-o", str(tmp_path / "o.mp4"), "--codec", "nothing264"],
        "presets are ultrafast": ["-o", str(tmp_path / "o.mp4"), "--preset", "quick"],
        "a multiple of 4": ["-o", str(tmp_path / "o.mp4"), "--width", "258"],
        "--fit is not for videos": ["-o", str(tmp_path / "o.mp4"), "--fit", "pad"],
    }
    for message, argv in cases.items():
        assert main(["warp", str(clips.plain), "-H", str(clips.handles), *argv]) == 2
        err = capsys.readouterr().err
        assert message in err and len(err.strip().splitlines()) == 1, err
    assert main(["warp", str(clips.handles.with_suffix(".png")), "-H", str(clips.handles), "-o", str(tmp_path / "o.mp4")]) == 2
    assert "a video output needs a video input" in capsys.readouterr().err
    assert main(["warp", str(clips.plain), "-H", str(clips.handles), "-o", str(tmp_path / "o.png")]) == 2
    assert "the output video must end in" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


# --- the API the editor uses -------------------------------------------------------------------


def _identity_map(height: int) -> np.ndarray:
    lon, lat = coords.grid_lonlat(2 * height)
    return np.stack(np.meshgrid(lon, lat), axis=-1).astype(np.float32)


def test_a_cancel_leaves_no_output(clips, tmp_path):
    from omniwidget.app.video import VideoCancelled, warp_video

    seen = []
    with pytest.raises(VideoCancelled):
        warp_video(clips.plain, tmp_path / "out.mp4", _identity_map(256), progress=lambda done, total: seen.append((done, total)) or done < 3)
    assert seen == [(1, FRAMES), (2, FRAMES), (3, FRAMES)]
    cancel = threading.Event()
    with pytest.raises(VideoCancelled):
        warp_video(clips.plain, tmp_path / "out.mp4", _identity_map(256), progress=lambda done, total: cancel.set() if done == 5 else None, cancel=cancel)
    assert list(tmp_path.iterdir()) == []


def test_warp_video_from_handles_reports_what_it_did(clips, tmp_path):
    import cv2

    from omniwidget.app.video import warp_video

    threads = cv2.getNumThreads()
    report = warp_video(clips.v1, tmp_path / "out.mov", handles=ow.Handles.from_dict(HANDLES), width=256, order="bicubic", preset="veryfast")
    assert cv2.getNumThreads() == threads  # OpenCV ran on one thread meanwhile, and is as it was
    assert (report.frames, report.size, report.codec, report.pix_fmt, report.planes) == (FRAMES, (256, 128), "libx264", "yuv420p", True)
    assert report.audio == ("aac",) and report.spherical is not None and report.fps > 0
    assert [t for t, _ in _decoded(tmp_path / "out.mov")] == [Fraction(i, RATE) for i in range(FRAMES)]
    assert _spherical_side_data(tmp_path / "out.mov")[0]["projection"] == "equirectangular"


def test_an_identity_map_gives_the_frames_back(clips, tmp_path):
    """Plane by plane through the identity: every plane's samples are only copied, so frames come back within the encoder's loss."""
    from omniwidget.app.video import warp_video

    out = tmp_path / "same.mp4"
    warp_video(clips.plain, out, _identity_map(256), crf=0, preset="ultrafast")  # crf 0: lossless
    assert all(np.array_equal(a, b) for (_, a), (_, b) in zip(_decoded(clips.plain, "yuv420p"), _decoded(out, "yuv420p"), strict=True))


def test_the_reader_gives_frames_by_number_and_by_time(clips):
    from omniwidget.io.video import VideoReader

    frames = [f for _, f in _decoded(clips.plain)]
    with VideoReader(clips.plain) as video:
        assert len(video) == FRAMES and video.info.rate == RATE and video.info.spherical is None
        for index in (0, 5, 6, 23, 3, 12, 11):  # forward, backward, sequential
            assert np.array_equal(video.read(index), frames[index]), index
        assert np.array_equal(video.read_at(10.4 / RATE), frames[10])  # the frame shown then
        assert np.array_equal(video.read_at(-1.0), frames[0]) and np.array_equal(video.read_at(99.0), frames[-1])
        assert all(np.array_equal(a, b) for a, b in zip(video.iter_frames(20), frames[20:], strict=True))
        assert len(list(video.iter_frames(2, 6))) == 4
        with pytest.raises(IndexError):
            video.read(FRAMES)
    with VideoReader(clips.deep) as video:
        assert video.read(4).dtype == np.uint16 and video.info.bits == 10
    with pytest.raises(ow.OmniwidgetError, match="not 2:1"):
        VideoReader(clips.wide)


def test_half_resolution_map_is_the_map_of_the_half_size_grid():
    from omniwidget.app.video import half_resolution_map

    half = half_resolution_map(_identity_map(32))
    expected = _identity_map(16)
    assert np.abs(half - expected).max() < 0.02 * 360 / 32  # within 0.02 of a half-size pixel
    # across the seam: a map turned by half a turn averages on the sphere, not in degrees
    turned = _identity_map(32)
    turned[..., 0] = (turned[..., 0] + 360.0) % 360.0 - 180.0
    lon = half_resolution_map(turned)[..., 0]
    turned_half = (expected[..., 0] + 360.0) % 360.0 - 180.0
    assert np.abs((lon - turned_half + 180) % 360 - 180).max() < 0.02 * 360 / 32


# --- the spherical boxes -------------------------------------------------------------------------


def test_spherical_metadata_round_trips_with_moov_first_and_last(clips, tmp_path):
    import av

    from omniwidget.io.spherical import V1_UUID, Spherical, read_spherical, v1_box, write_spherical

    assert read_spherical(clips.plain) is None
    v1 = read_spherical(clips.v1)
    assert v1 is not None and (v1.projection, v1.stereo, v1.source) == ("equirectangular", "mono", "xmp")
    posed = Spherical(yaw=12.5, pitch=-30.0, roll=4.25)
    for name in ("plain", "faststart"):  # moov after the media data, and before it (its chunk offsets move)
        path = tmp_path / f"{name}.mp4"
        shutil.copy(getattr(clips, name), path)
        write_spherical(path, posed)
        write_spherical(path, posed)  # again: replaced, not added twice
        got = read_spherical(path)
        assert got is not None and (got.yaw, got.pitch, got.roll, got.source) == (12.5, -30.0, 4.25, "sv3d")
        (side,) = _spherical_side_data(path)
        assert (side["projection"], side["yaw"], side["pitch"]) == ("equirectangular", 12, -30)
        assert path.stat().st_size == getattr(clips, name).stat().st_size + 13 + 91 + len(v1_box(posed))
        # version 1's XMP too, once, for players that read only it
        assert path.read_bytes().count(V1_UUID) == 1
        xml = path.read_bytes().split(V1_UUID, 1)[1][: len(v1_box(posed)) - 24]
        assert b"<GSpherical:ProjectionType>equirectangular</GSpherical:ProjectionType>" in xml
        if shutil.which("exiftool") is not None:  # an independent reader of the V1 box
            out = subprocess.run(["exiftool", "-j", "-XMP-GSpherical:all", str(path)], capture_output=True, text=True, check=True)
            (tags,) = json.loads(out.stdout)
            assert (tags["Spherical"], tags["ProjectionType"], tags["StereoMode"]) == (True, "equirectangular", "mono")
        with av.open(str(path)) as a, av.open(str(getattr(clips, name))) as b:  # the media data is where the index says
            assert all(np.array_equal(x.to_ndarray(), y.to_ndarray()) for x, y in zip(a.decode(video=0), b.decode(video=0), strict=True))


# --- Ctrl+C ------------------------------------------------------------------------------------------


@pytest.mark.slow
def test_ctrl_c_leaves_no_partial_output(tmp_path):
    """SIGINT once frames are in the temporary file: exit 130, no output, no temporary file."""
    source, out = tmp_path / "long.mp4", tmp_path / "out.mp4"
    _encode(source, _frames(24), repeat=20, audio=True, options={"preset": "ultrafast"})  # 480 frames, 20 s
    handles = tmp_path / "handles.json"
    handles.write_text(json.dumps(DEMO_HANDLES))
    process = subprocess.Popen(
        [sys.executable, "-m", "omniwidget", "warp", str(source), "-H", str(handles), "-o", str(out), "--progress"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        # as from a terminal: a test worker may ignore SIGINT (something earlier in the process set it so, and a child
        # inherits an ignored signal, so Python would not turn it into KeyboardInterrupt: the warp ran to its end)
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    deadline = time.monotonic() + 120
    size = 0
    while time.monotonic() < deadline and process.poll() is None:
        parts = list(tmp_path.glob(".out.mp4.*.part"))
        size = parts[0].stat().st_size if parts else 0
        if size > 4096:  # encoded frames are in it (past the container's header: 50 kB was sometimes reached only at the end)
            break
        time.sleep(0.01)
    assert process.poll() is None, f"the warp ended before it could be interrupted: {process.communicate()}"
    process.send_signal(signal.SIGINT)
    stdout, stderr = process.communicate(timeout=60)
    assert process.returncode == 130, stderr
    assert stderr.strip().splitlines()[-1] == "omniwidget warp: interrupted", stderr
    assert size > 4096 and not out.exists() and _leftovers(tmp_path) == [], sorted(p.name for p in tmp_path.iterdir())
