"""Time ranges of a video warped on their own and joined back without re-encoding.

A long video is cut into ranges so that many machines warp it at once
(:func:`omniwidget.app.batch.warp_files` on Dask): ``warp_video(start=, end=, audio=False)``
writes each range from a key frame, ``join_video_segments`` copies their packets into one
file on the source's timeline with the source's sound. The clips are those of
``test_video.py`` (24 frames at 24 fps, an AAC tone, V1 spherical metadata on ``v1``).
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

import omniwidget as ow
from omniwidget.errors import VideoError
from tests import test_video
from tests.test_video import FRAMES, HANDLES, PSNR_BOUND, RATE, _audio_packets, _decoded, _ffprobe, _psnr, _spherical_side_data

# test_video's fixtures, found by pytest under these names: the clips (made once a session) and the tools check
clips = test_video.clips
_tools = test_video._tools

#: Three ranges of 8, 9 and 7 frames: cuts between frames, and the last one open.
RANGES = [(None, 0.33), (0.33, 0.7), (0.7, None)]


def _map(height: int = 256) -> np.ndarray:
    return ow.warp(np.zeros((height, 2 * height, 3), np.uint8), ow.Handles.from_dict(HANDLES), warn=False).inverse_map()


def _keyframes(path):
    import av

    with av.open(str(path)) as container:
        stream = container.streams.video[0]
        return [p.is_keyframe for p in container.demux(stream) if p.size]


@pytest.fixture(scope="module")
def joined(clips, tmp_path_factory):
    from omniwidget.app.video import warp_video
    from omniwidget.io.video import join_video_segments

    folder = tmp_path_factory.mktemp("ranges")
    the_map = _map()
    segments, reports = [], []
    for k, (start, end) in enumerate(RANGES):
        segment = folder / f"part{k}.mp4"
        reports.append(warp_video(clips.v1, segment, the_map, start=start, end=end, audio=False, spherical=False))
        segments.append(segment)
    out = folder / "joined.mp4"
    report = join_video_segments(segments, out, source=clips.v1)
    return folder, segments, reports, out, report


def test_the_ranges_hold_each_frame_once_from_a_key_frame_at_zero(joined):
    _, segments, reports, _, _ = joined
    assert [r.frames for r in reports] == [8, 9, 7]  # frames at k / 24 s: 0-7 before 0.33 s, 8-16 before 0.7 s
    for segment, count in zip(segments, (8, 9, 7), strict=True):
        frames = _decoded(segment)
        assert [t for t, _ in frames] == [Fraction(i, RATE) for i in range(count)]  # each range starts at 0
        keys = _keyframes(segment)
        assert keys[0] and len(keys) == count
        assert _spherical_side_data(segment) == [] and _audio_packets_or_none(segment) is None


def _audio_packets_or_none(path):
    import av

    with av.open(str(path)) as container:
        return None if not container.streams.audio else _audio_packets(path)


def test_the_joined_video_has_the_sources_frames_times_sound_and_metadata(clips, joined):
    _, _, _, out, report = joined
    before, after = _decoded(clips.v1), _decoded(out)
    assert report.frames == len(after) == FRAMES
    assert [t for t, _ in after] == [t for t, _ in before] == [Fraction(i, RATE) for i in range(FRAMES)]
    assert _keyframes(out)[:9] == [True] + [False] * 7 + [True]  # the ranges' key frames, copied
    assert _audio_packets(out) == _audio_packets(clips.v1)  # byte for byte, with their times
    a, b = _ffprobe(clips.v1, "-show_format"), _ffprobe(out, "-show_format")
    assert b["format"]["duration"] == a["format"]["duration"]
    (kept,) = _spherical_side_data(out)
    assert kept["projection"] == "equirectangular"


def test_each_joined_frame_is_the_warp_of_its_input_frame(clips, joined):
    handles = ow.Handles.from_dict(HANDLES)
    before, after = _decoded(clips.v1), _decoded(joined[3])
    first = ow.warp(before[0][1], handles, warn=False)
    figures = [_psnr(ow.warp(src, handles, warn=False, previous=first).image, out, 255.0) for (_, src), (_, out) in zip(before, after, strict=True)]
    assert min(figures) >= PSNR_BOUND, ", ".join(f"{p:.1f}" for p in figures)


def test_a_range_with_its_sound_starts_at_zero(clips, tmp_path):
    from omniwidget.app.video import warp_video

    out = tmp_path / "range.mp4"
    report = warp_video(clips.v1, out, _map(), start=0.5, end=0.75)
    frames = _decoded(out)
    assert report.frames == len(frames) == 6  # frames 12-17
    assert [t for t, _ in frames] == [Fraction(i, RATE) for i in range(6)]
    source = [p for p in _audio_packets(clips.v1) if Fraction(1, 2) <= p[1] < Fraction(3, 4)]
    got = _audio_packets(out)
    assert [p[0] for p in got] == [p[0] for p in source] and len(got) >= 10  # the packets that start in the range
    assert got[0][1] == source[0][1] - Fraction(1, 2)  # moved by the range's start


def test_joining_refuses_a_missing_range_or_ranges_encoded_unlike(clips, joined, tmp_path):
    from omniwidget.app.video import warp_video
    from omniwidget.io.video import join_video_segments

    folder, segments, _, _, _ = joined
    with pytest.raises(VideoError, match="segments hold 15 frame.*has 24: a range is missing"):
        join_video_segments([segments[0], segments[2]], tmp_path / "x.mp4", source=clips.v1)
    other = tmp_path / "fast.mp4"
    warp_video(clips.v1, other, _map(), start=0.7, audio=False, preset="ultrafast")
    with pytest.raises(VideoError, match="fast.mp4: this segment was encoded unlike part0.mp4"):
        join_video_segments([segments[0], segments[1], other], tmp_path / "x.mp4", source=clips.v1)
    with pytest.raises(VideoError, match="gone.mp4: cannot read this segment .No such file"):
        join_video_segments([segments[0], folder / "gone.mp4"], tmp_path / "x.mp4", source=clips.v1)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fast.mp4"]  # nothing half written


def test_bad_ranges_are_refused(clips, tmp_path):
    from omniwidget.app.video import warp_video

    with pytest.raises(ValueError, match="start .* must come before its end"):
        warp_video(clips.v1, tmp_path / "x.mp4", _map(), start=0.5, end=0.5)
    with pytest.raises(ValueError, match="end must be a finite number of seconds"):
        warp_video(clips.v1, tmp_path / "x.mp4", _map(), end=float("nan"))
    with pytest.raises(VideoError, match="no frame is shown from 5 s to 6 s"):
        warp_video(clips.v1, tmp_path / "x.mp4", _map(), start=5, end=6)
    assert list(tmp_path.iterdir()) == []
