"""Batches of panoramas in-process and on a Dask cluster (omniwidget.app.batch, ``omniwidget warp --dask``).

The cluster is a ``LocalCluster`` of two worker processes of one thread each, shared by the
module. Without dask.distributed its tests are skipped, except when
``OMNIWIDGET_BROWSER_TESTS=1`` (CI), where they fail: the test extra installs it
(``omniwidget[dask]``), so a missing package is a broken install, not a reason to skip.
Every output is compared byte for byte with what ``omniwidget warp`` writes on one machine.
"""

from __future__ import annotations

import faulthandler
import importlib.util
import json
import os
import tempfile
from pathlib import Path

import cv2
import numpy as np
import pytest

from omniwidget.app.batch import BatchReport, warp_files
from omniwidget.app.cli import DEMO_HANDLES, main
from omniwidget.data import sample_image
from omniwidget.io.images import write_image

STRICT_ENV_VAR = "OMNIWIDGET_BROWSER_TESTS"
SMALL = ("a.jpg", "b.png", "c.jpg")  # 256 x 128
LARGE = ("d.jpg", "e.png")  # 512 x 256: another size, another map


def _require_dask() -> None:
    if importlib.util.find_spec("distributed") is not None:
        return
    reason = 'the Dask tests need dask.distributed (pip install "omniwidget[dask]")'
    if os.environ.get(STRICT_ENV_VAR) == "1":
        pytest.fail(f"{reason}; {STRICT_ENV_VAR}=1 forbids skipping", pytrace=False)
    pytest.skip(reason)


#: A test of this module that takes longer has hung (a task waiting for something that never comes):
#: the run then stops with every thread's traceback instead of waiting for CI's limit.
HANG_SECONDS = 300


@pytest.fixture(autouse=True)
def _no_hang():
    faulthandler.dump_traceback_later(HANG_SECONDS, exit=True)
    yield
    faulthandler.cancel_dump_traceback_later()


@pytest.fixture(scope="module")
def files(tmp_path_factory) -> Path:
    """Inputs of two sizes, a truncated JPEG, the demo's handles and the map they make at 256 wide."""
    root = tmp_path_factory.mktemp("batch")
    image = sample_image()
    small = cv2.resize(image, (256, 128), interpolation=cv2.INTER_AREA)
    large = cv2.resize(image, (512, 256), interpolation=cv2.INTER_AREA)
    for name, picture in zip(SMALL, (small, np.roll(small, 40, axis=1), small[:, ::-1]), strict=True):
        write_image(root / name, picture)
    for name, picture in zip(LARGE, (large, np.roll(large, -90, axis=1)), strict=True):
        write_image(root / name, picture)
    whole = (root / "a.jpg").read_bytes()
    (root / "broken.jpg").write_bytes(whole[: len(whole) // 2])  # cut short: refused by name, every time
    (root / "h.json").write_text(json.dumps(DEMO_HANDLES))
    return root


def _run_cli(*argv: object) -> int:
    return main([str(a) for a in argv])


@pytest.fixture(scope="module")
def local(files) -> Path:
    """What ``omniwidget warp`` writes on one machine: each size as a batch of its own, by handles and by a saved map."""
    out = files / "local"
    out.mkdir()
    assert _run_cli("warp", *(files / n for n in SMALL), "-H", files / "h.json", "-o", out / "small", "--map", files / "map.npy") == 0
    assert _run_cli("warp", *(files / n for n in LARGE), "-H", files / "h.json", "-o", out / "large") == 0
    for names in (SMALL, LARGE):  # one size per run on one machine; the map is in degrees, so it serves both
        assert _run_cli("warp", *(files / n for n in names), "--apply-map", files / "map.npy", "-o", out / "mapped") == 0
    return out


def _expected(local: Path, names=SMALL + LARGE) -> dict[str, bytes]:
    return {n: (local / ("small" if n in SMALL else "large") / n).read_bytes() for n in names}


def _written(folder: Path) -> dict[str, bytes]:
    """Every file in ``folder``, temporary ones included (a leftover shows up as an unexpected name)."""
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir())}


@pytest.fixture(scope="module")
def client():
    """A client of a LocalCluster of two worker processes, one thread each."""
    _require_dask()
    from distributed import Client, LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0") as cluster, Client(cluster) as c:
        c.wait_for_workers(2)
        yield c


# --- in-process --------------------------------------------------------------------------------


def test_in_process_batches_write_the_bytes_of_omniwidget_warp(files, local, tmp_path):
    inputs = [files / n for n in SMALL + LARGE]
    report = warp_files(inputs, tmp_path / "by-handles", handles=files / "h.json")
    assert isinstance(report, BatchReport) and report.ok and report.scheduler is None
    assert _written(tmp_path / "by-handles") == _expected(local)  # two sizes, each with its own map
    assert [f.output for f in report.files] == [tmp_path / "by-handles" / n for n in SMALL + LARGE]
    assert all(f.seconds is not None and f.seconds > 0 and f.worker == "local" for f in report.files)
    # the map was made once per size, whatever the threads
    assert sum(f.map_seconds > 0 for f in report.files) == 2

    report = warp_files(inputs, tmp_path / "by-map", map=files / "map.npy", workers=1)
    assert report.ok and report.written == tuple(tmp_path / "by-map" / n for n in SMALL + LARGE)
    assert _written(tmp_path / "by-map") == _written(local / "mapped")  # the command line's --apply-map
    # the saved map is the one the handles make at 256 wide: the same bytes either way
    assert {n: (local / "mapped" / n).read_bytes() for n in SMALL} == _expected(local, SMALL)


def test_a_fixed_output_width_serves_inputs_of_both_sizes(files, tmp_path):
    for names in (SMALL, LARGE):
        assert _run_cli("warp", *(files / n for n in names), "-H", files / "h.json", "-o", tmp_path / "cli", "--width", "128") == 0
    report = warp_files([files / n for n in SMALL + LARGE], tmp_path / "batch", handles=files / "h.json", width=128, workers=2)
    assert report.ok
    assert _written(tmp_path / "batch") == _written(tmp_path / "cli")
    assert cv2.imread(str(tmp_path / "batch" / "d.jpg")).shape == (64, 128, 3)


def test_in_process_a_broken_input_is_reported_and_the_others_are_written(files, local, tmp_path):
    report = warp_files([files / "a.jpg", files / "broken.jpg", files / "c.jpg"], tmp_path / "out", handles=files / "h.json", retries=1)
    assert not report.ok
    assert report.written == (tmp_path / "out" / "a.jpg", tmp_path / "out" / "c.jpg")
    ((bad, why),) = report.failed
    assert bad == files / "broken.jpg" and "broken.jpg" in why and "truncated" in why
    assert report.files[1].seconds is None and report.files[1].worker is None
    assert _written(tmp_path / "out") == _expected(local, ("a.jpg", "c.jpg"))
    assert "failed: " in report.summary() and "2 of 3" in report.summary()


def test_a_batch_refuses_what_would_lose_work_before_starting(files, tmp_path):
    from omniwidget.errors import ImageError

    with pytest.raises(ValueError, match="either handles= .* or map="):
        warp_files([files / "a.jpg"], tmp_path, handles=files / "h.json", map=files / "map.npy")
    with pytest.raises(ImageError, match="share the file name"):
        warp_files([files / "a.jpg", files / "local" / "small" / "a.jpg"], tmp_path / "o", handles=files / "h.json")
    with pytest.raises(ImageError, match="a.jpg would overwrite the input"):
        warp_files([files / "a.jpg"], [files / "a.jpg"], handles=files / "h.json")
    with pytest.raises(ImageError, match="output of two inputs"):
        warp_files([files / "a.jpg", files / "c.jpg"], [tmp_path / "x.png", tmp_path / "x.png"], handles=files / "h.json")
    with pytest.raises(ValueError, match="width=128: the map makes outputs 256 wide"):
        warp_files([files / "a.jpg"], tmp_path, map=files / "map.npy", width=128)
    with pytest.raises(ValueError, match="retries"):
        warp_files([files / "a.jpg"], tmp_path, handles=files / "h.json", retries=-1)
    assert list(tmp_path.iterdir()) == []


def test_the_temporaries_of_a_killed_attempt_are_removed_and_no_other_file(tmp_path):
    from omniwidget._files import remove_leftovers

    names = [".a.jpg.ab12_x9z.tmp", ".a.jpg.png.ab12_x9z.tmp", ".b.jpg.ab12_x9z.tmp", "a.jpg", ".a.jpg.tmp", ".a.jpg.abcdefgh.tmp"]
    for n in names:
        (tmp_path / n).write_bytes(b"x")
    remove_leftovers(tmp_path / "a.jpg")
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(set(names) - {".a.jpg.ab12_x9z.tmp", ".a.jpg.abcdefgh.tmp"})


# --- on a Dask cluster -------------------------------------------------------------------------


def test_the_cluster_writes_the_bytes_of_the_local_run(client, files, local, tmp_path):
    inputs = [files / n for n in SMALL + LARGE]
    report = warp_files(inputs, tmp_path / "dask", handles=files / "h.json", client=client)
    assert report.ok, report.summary()
    assert _written(tmp_path / "dask") == _expected(local)
    workers = set(client.scheduler_info()["workers"])
    assert report.scheduler == client.scheduler.address and report.workers == 2
    assert {f.worker for f in report.files} <= workers and all(f.task and f.task.startswith("omniwidget-warp-") for f in report.files)
    # each worker makes each size's map at most once
    assert 2 <= sum(f.map_seconds > 0 for f in report.files) <= 2 * 2

    # a saved map: sent to every worker once, one map for both sizes; the same bytes as --apply-map
    report = warp_files(inputs, tmp_path / "mapped", map=files / "map.npy", client=client)
    assert report.ok, report.summary()
    assert _written(tmp_path / "mapped") == _written(local / "mapped")

    # and the in-process run of the same batch
    assert warp_files(inputs, tmp_path / "here", handles=files / "h.json").ok
    assert _written(tmp_path / "here") == _written(tmp_path / "dask")


def _arm_kill(marker: str) -> None:
    """On a worker: the first write of any worker writes half a temporary file, then kills its process."""
    import omniwidget.io.images as images

    original = getattr(images.atomic_write_bytes, "original", images.atomic_write_bytes)

    def dying(path, data):
        path = Path(path)
        try:
            claim = os.open(marker, os.O_CREAT | os.O_EXCL | os.O_WRONLY)  # one kill in all the cluster
        except FileExistsError:
            return original(path, data)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)  # as atomic_write_bytes does
        os.write(fd, data[: len(data) // 2])
        os.fsync(fd)
        os.write(claim, tmp.encode())
        os.close(claim)
        os._exit(1)  # killed mid-write: no cleanup, no reply

    dying.original = original
    images.atomic_write_bytes = dying


def _disarm() -> None:
    import omniwidget.io.images as images

    images.atomic_write_bytes = getattr(images.atomic_write_bytes, "original", images.atomic_write_bytes)


def test_a_worker_killed_mid_write_loses_and_duplicates_no_output(client, files, local, tmp_path):
    marker = tmp_path / "killed"
    before = set(client.scheduler_info()["workers"])
    client.run(_arm_kill, str(marker))
    try:
        report = warp_files([files / n for n in SMALL + LARGE], tmp_path / "out", handles=files / "h.json", client=client, retries=0)
    finally:
        client.run(_disarm)
    half = Path(marker.read_text())
    assert half.parent == tmp_path / "out" and half.name.endswith(".tmp")  # the kill did happen, mid-write
    assert report.ok, report.summary()  # retries=0: the rerun is Dask's own, for a task whose worker died
    # every output once, each the local run's bytes, and no temporary file left (the rerun removed the half one)
    assert _written(tmp_path / "out") == _expected(local)
    client.wait_for_workers(2)
    assert set(client.scheduler_info()["workers"]) != before  # the nanny started a new worker process


def _arm_flaky(name: str, marker: str) -> None:
    """On a worker: reading ``name`` fails the first time in the whole cluster (a file system's hiccup)."""
    import omniwidget.io.images as images

    original = getattr(images.read_panorama, "original", images.read_panorama)

    def flaky(path, fit=None):
        if Path(path).name == name:
            try:
                os.close(os.open(marker, os.O_CREAT | os.O_EXCL | os.O_WRONLY))
            except FileExistsError:
                pass
            else:
                raise OSError(5, "Input/output error (injected)", str(path))
        return original(path, fit)

    flaky.original = original
    images.read_panorama = flaky


def _disarm_flaky() -> None:
    import omniwidget.io.images as images

    images.read_panorama = getattr(images.read_panorama, "original", images.read_panorama)


def _attempts(client, key: str) -> int:
    """How many times the workers ran ``key`` and it raised (from the cluster's story of the task)."""
    return sum(1 for event in client.story(key) if len(event) > 3 and event[1] == key and event[2:4] == ("executing", "error"))


def test_a_failing_input_is_retried_then_reported_while_the_others_succeed(client, files, local, tmp_path):
    client.run(_arm_flaky, "c.jpg", str(tmp_path / "hiccup"))
    try:
        inputs = [files / "a.jpg", files / "broken.jpg", files / "c.jpg", files / "d.jpg"]
        report = warp_files(inputs, tmp_path / "out", handles=files / "h.json", client=client, retries=2)
    finally:
        client.run(_disarm_flaky)
    assert (tmp_path / "hiccup").exists()  # c.jpg did fail once, and its retry wrote it
    assert report.written == tuple(tmp_path / "out" / n for n in ("a.jpg", "c.jpg", "d.jpg"))
    ((bad, why),) = report.failed
    assert bad == files / "broken.jpg" and "broken.jpg" in why and "truncated" in why, why
    broken = report.files[1]
    assert broken.seconds is None and broken.task is not None
    assert _attempts(client, broken.task) == 3  # tried, then retried twice
    assert _attempts(client, report.files[2].task) == 1
    assert _written(tmp_path / "out") == _expected(local, ("a.jpg", "c.jpg", "d.jpg"))


def test_the_command_line_runs_on_the_cluster(client, files, local, tmp_path, capsys):
    address = client.scheduler.address
    out = tmp_path / "out"
    assert _run_cli("warp", files / "a.jpg", files / "b.png", "-H", files / "h.json", "-o", out, "--dask", address) == 0
    assert _written(out) == _expected(local, ("a.jpg", "b.png"))
    assert f"warped 2 of 2 file(s) on the Dask cluster at {address}" in capsys.readouterr().err  # the closing line

    # a broken input: the others are written, the error names it, the exit status says it
    code = _run_cli("warp", files / "c.jpg", files / "broken.jpg", "-H", files / "h.json", "-o", tmp_path / "bad", "--dask", address)
    err = capsys.readouterr().err
    assert code == 2
    assert "broken.jpg" in err and "truncated" in err and "1 of 2 files were not warped" in err
    assert _written(tmp_path / "bad") == _expected(local, ("c.jpg",))

    # a saved map, as --apply-map on one machine
    assert _run_cli("warp", *(files / n for n in SMALL), "--apply-map", files / "map.npy", "-o", tmp_path / "m", "--dask", address) == 0
    assert _written(tmp_path / "m") == {n: (local / "mapped" / n).read_bytes() for n in SMALL}

    # what cannot work on a cluster is refused before any work, in one line
    for extra, says in ((["--map", tmp_path / "x.npy"], "--map with --dask"), (["--workers", "2"], "--workers sets threads")):
        assert _run_cli("warp", files / "a.jpg", "-H", files / "h.json", "-o", tmp_path / "y.png", "--dask", address, *extra) == 2
        assert says in capsys.readouterr().err
    assert not (tmp_path / "y.png").exists()


def test_a_scheduler_file_names_the_cluster(client, files, local, tmp_path):
    scheduler_file = tmp_path / "scheduler.json"
    scheduler_file.write_text(json.dumps({"address": client.scheduler.address}))
    report = warp_files([files / "a.jpg"], tmp_path / "out", handles=files / "h.json", client=str(scheduler_file))
    assert report.ok and report.scheduler == client.scheduler.address
    assert _written(tmp_path / "out") == _expected(local, ("a.jpg",))


def _pretend_an_old_release() -> None:
    import omniwidget.app.batch as batch

    original = getattr(batch._environment, "original", batch._environment)

    def old():
        return {**original(), "omniwidget": "0.0.1"}

    old.original = original
    batch._environment = old


def _undo_pretending() -> None:
    import omniwidget.app.batch as batch

    batch._environment = getattr(batch._environment, "original", batch._environment)


def test_workers_with_other_versions_are_warned_about(client, files, tmp_path):
    client.run(_pretend_an_old_release)
    try:
        report = warp_files([files / "a.jpg"], tmp_path / "out", handles=files / "h.json", client=client)
    finally:
        client.run(_undo_pretending)
    assert report.ok
    assert len(report.warnings) == 2 and all("runs omniwidget 0.0.1 (here " in w for w in report.warnings), report.warnings


# --- videos: time ranges as tasks, joined without re-encoding -----------------------------------


@pytest.fixture(scope="module")
def clip(files) -> Path:
    """A 24-frame 512 x 256 clip with a tone and V1 spherical metadata (test_video's), and its ranges warped whole in-process."""
    if os.environ.get(STRICT_ENV_VAR) != "1":  # in CI a missing PyAV is a broken install
        pytest.importorskip("av")
    from tests.test_video import _add_v1_metadata, _encode, _frames

    path = files / "clip.mp4"
    _encode(path, _frames(24))
    _add_v1_metadata(path)
    return path


def _video_batch(clip: Path, files: Path, out: Path, **kwargs) -> BatchReport:
    """The clip in three time ranges, with two images, by the demo's handles."""
    return warp_files([clip, files / "a.jpg", files / "d.jpg"], out, handles=files / "h.json", segment_seconds=0.35, **kwargs)


@pytest.fixture(scope="module")
def local_video(clip, files, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("video") / "here"
    report = _video_batch(clip, files, out)
    assert report.ok, report.summary()
    assert [f.segments for f in report.files] == [3, 1, 1]
    return out


def test_in_process_a_video_is_warped_in_ranges_and_joined_whole(clip, files, local, local_video):
    from tests.test_video import _audio_packets, _decoded, _psnr, _spherical_side_data

    written = _written(local_video)
    assert sorted(written) == ["a.jpg", "clip.mp4", "d.jpg"]  # no range or temporary file left
    assert {n: written[n] for n in ("a.jpg", "d.jpg")} == _expected(local, ("a.jpg", "d.jpg"))
    before, after = _decoded(clip), _decoded(local_video / "clip.mp4")
    assert [t for t, _ in after] == [t for t, _ in before] and len(after) == 24
    assert _audio_packets(local_video / "clip.mp4") == _audio_packets(clip)
    (kept,) = _spherical_side_data(local_video / "clip.mp4")
    assert kept["projection"] == "equirectangular"
    # each frame is the warp of its input frame, as the one-machine video warp makes it
    handles = json.loads((files / "h.json").read_text())
    import omniwidget as ow

    doc = ow.Handles.from_dict(handles)
    first = ow.warp(before[0][1], doc, warn=False)
    figures = [_psnr(ow.warp(src, doc, warn=False, previous=first).image, out, 255.0) for (_, src), (_, out) in zip(before, after, strict=True)]
    assert min(figures) >= 37.0, figures


def test_the_cluster_writes_the_video_bytes_of_the_local_run(client, clip, files, local_video, tmp_path):
    report = _video_batch(clip, files, tmp_path / "dask", client=client)
    assert report.ok, report.summary()
    assert _written(tmp_path / "dask") == _written(local_video)
    video = report.files[0]
    assert video.segments == 3 and video.task is not None and video.task.endswith("-0")  # the join's key
    # the plan, three ranges and the join ran as tasks; every range on some worker
    stories = {event[1] for event in client.story(*(f"{video.task}-{k}" for k in range(3))) if len(event) > 1}
    assert {f"{video.task}-{k}" for k in range(3)} <= stories


def _arm_kill_in_a_range(marker: str, after: int) -> None:
    """On a worker: the first range of the cluster to warp its ``after``-th frame kills its process there, mid-encode."""
    import omniwidget.app.video as video

    original = getattr(video._Warper.__call__, "original", video._Warper.__call__)
    seen = [0]

    def dying(self, frame):
        seen[0] += 1
        if seen[0] == after:
            try:
                os.close(os.open(marker, os.O_CREAT | os.O_EXCL | os.O_WRONLY))  # one kill in all the cluster
            except FileExistsError:
                pass
            else:
                os._exit(1)
        return original(self, frame)

    dying.original = original
    video._Warper.__call__ = dying


def _disarm_range_kill() -> None:
    import omniwidget.app.video as video

    video._Warper.__call__ = getattr(video._Warper.__call__, "original", video._Warper.__call__)


def test_a_worker_killed_mid_range_loses_and_duplicates_nothing(client, clip, files, local_video, tmp_path):
    marker = tmp_path / "killed"
    client.run(_arm_kill_in_a_range, str(marker), 4)
    try:
        report = _video_batch(clip, files, tmp_path / "out", client=client, retries=0)
    finally:
        client.run(_disarm_range_kill)
    assert marker.exists()  # a worker did die, four frames into a range
    assert report.ok, report.summary()
    assert _written(tmp_path / "out") == _written(local_video)  # the same bytes, no half-written range left
    client.wait_for_workers(2)


def test_a_broken_video_is_reported_and_the_other_files_written(client, clip, files, local, tmp_path):
    data = clip.read_bytes()
    cut = tmp_path / "cut.mp4"
    cut.write_bytes(data[: len(data) * 2 // 3])  # the index at the end is gone
    for run in ({}, {"client": client}):
        out = tmp_path / ("dask" if run else "here")
        report = warp_files([cut, files / "a.jpg"], out, handles=files / "h.json", segment_seconds=0.35, retries=1, **run)
        ((bad, why),) = report.failed
        assert bad == cut and "cut.mp4" in why, why
        assert _written(out) == _expected(local, ("a.jpg",))


def test_the_command_line_sends_a_videos_ranges_to_the_cluster(client, clip, files, local_video, tmp_path, capsys):
    out = tmp_path / "clip.mp4"
    code = _run_cli("warp", clip, "-H", files / "h.json", "-o", out, "--dask", client.scheduler.address, "--segment-seconds", "0.35")
    assert code == 0, capsys.readouterr().err
    assert out.read_bytes() == (local_video / "clip.mp4").read_bytes()
    assert _run_cli("warp", files / "a.jpg", "-H", files / "h.json", "-o", tmp_path / "x.png", "--segment-seconds", "1") == 2
    assert "--segment-seconds cuts videos for a Dask cluster" in capsys.readouterr().err
