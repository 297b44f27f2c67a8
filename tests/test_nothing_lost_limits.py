"""Issue 35, part 3: limits instead of exhaustion.

Each row of the issue's table is reproduced as the issue says (a FIFO given as ``-H``, a
handles file nested 100,000 deep, duplicate keys, a PNG that declares 46,000 x 23,000
pixels, a ``.npy`` map whose header declares (100000, 200000, 2), 10,000 handles) and the
new behaviour asserted: one line on stderr naming the file, exit 2, within a time and a
memory limit.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from omniwidget._checks import require_regular_file
from omniwidget.document.handles import load_handles
from omniwidget.errors import HandlesError, ImageError, NotRegularFileError, OmniwidgetError
from omniwidget.io.images import read_image, write_image

POINT = {"handles": [{"kind": "point", "position": [10, 20], "target": [30, 10]}]}


def _cli(*argv: str, timeout: float = 60, memory: int | None = None) -> subprocess.CompletedProcess[str]:
    """``python -m omniwidget ARGV`` in a subprocess (under ``ulimit -v`` of ``memory`` bytes when given)."""
    command = [sys.executable, "-m", "omniwidget", *argv]
    if memory is not None:
        command = ["bash", "-c", f'ulimit -v {memory // 1024} && exec "$@"', "bash", *command]
    env = {**os.environ, "OMNIWIDGET_AUTOSAVE": "0"}
    return subprocess.run(command, capture_output=True, text=True, timeout=timeout, env=env)


def _one_line_refusal(run: subprocess.CompletedProcess[str], *words: str) -> None:
    assert run.returncode == 2, run.stderr
    assert run.stderr.count("\n") == 1 and "Traceback" not in run.stderr, run.stderr
    for word in words:
        assert word in run.stderr, (word, run.stderr)


@pytest.fixture
def panorama(tmp_path: Path) -> Path:
    image = np.zeros((32, 64, 3), np.uint8)
    image[..., 0] = np.arange(64, dtype=np.uint8)[None] * 4
    write_image(tmp_path / "in.png", image)
    return tmp_path / "in.png"


# --- special files ----------------------------------------------------------------------------


def test_require_regular_file_names_the_kind(tmp_path: Path) -> None:
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    with pytest.raises(NotRegularFileError, match=r"pipe: cannot read the handles file: it is a FIFO \(named pipe\), not a regular file"):
        require_regular_file(fifo, "handles file")
    with pytest.raises(ValueError, match="it is a character device"):  # a ValueError: the CLI's exit-2 refusals
        require_regular_file(Path("/dev/zero"), "image")
    with pytest.raises(OmniwidgetError, match="it is a folder"):
        require_regular_file(tmp_path, "map")
    (tmp_path / "plain.json").write_text("{}")
    require_regular_file(tmp_path / "plain.json", "handles file")
    require_regular_file(tmp_path / "missing.json", "handles file")  # the read that follows says it is missing


def test_a_fifo_or_a_device_is_refused_by_the_readers(tmp_path: Path) -> None:
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    with pytest.raises(HandlesError, match="pipe: cannot read the handles file: it is a FIFO"):
        load_handles(fifo)
    with pytest.raises(ImageError, match="pipe: cannot read the image: it is a FIFO"):
        read_image(fifo)
    with pytest.raises(ImageError, match="/dev/zero: cannot read the image: it is a character device"):
        read_image("/dev/zero")


def test_a_fifo_given_as_handles_is_one_line_and_exit_2_not_a_hang(tmp_path: Path, panorama: Path) -> None:
    fifo = tmp_path / "h.json"
    os.mkfifo(fifo)  # before: the command line waited for a writer until killed
    run = _cli("warp", str(panorama), "-H", str(fifo), "-o", str(tmp_path / "out.png"), timeout=60)
    _one_line_refusal(run, str(fifo), "FIFO")
    assert not (tmp_path / "out.png").exists()
    (tmp_path / "good.json").write_text(json.dumps(POINT))
    run = _cli("warp", str(fifo), "-H", str(tmp_path / "good.json"), "-o", str(tmp_path / "out.png"), timeout=60)
    _one_line_refusal(run, str(fifo), "cannot read the image: it is a FIFO")


# --- the handles file: depth and duplicate keys --------------------------------------------------


def test_a_file_nested_100000_deep_is_one_line_and_exit_2(tmp_path: Path, panorama: Path) -> None:
    deep = tmp_path / "deep.json"
    deep.write_text('{"handles": ' + "[" * 100_000 + "]" * 100_000 + "}")  # before: a 27-line RecursionError, exit 1
    with pytest.raises(HandlesError, match=r"deep\.json: the JSON is nested deeper than 32 arrays and objects \(at line 1\)"):
        load_handles(deep)
    run = _cli("warp", str(panorama), "-H", str(deep), "-o", str(tmp_path / "out.png"))
    _one_line_refusal(run, str(deep), "nested deeper than 32")
    assert not (tmp_path / "out.png").exists()


def test_the_depth_is_counted_outside_strings_only(tmp_path: Path) -> None:
    brackets = "[{" * 40 + '\\"]'
    doc = {"handles": [{"kind": "point", "position": [10, 20], "id": brackets}]}
    assert load_handles(_write(tmp_path / "h.json", json.dumps(doc))).handles[0].id == brackets
    nested = json.dumps({"handles": [{"kind": "cage", "vertices": [[0, 0], [10, 0], [5, 8]]}]}, indent=2)
    assert len(load_handles(_write(tmp_path / "cage.json", nested)).handles) == 1
    with pytest.raises(HandlesError, match="at line 3"):
        load_handles(_write(tmp_path / "deep.json", '{\n"handles":\n' + "[" * 33 + "]" * 33 + "}"))


def _write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


@pytest.mark.parametrize(
    ("text", "key"),
    [
        ('{"handles": [{"kind": "point", "position": [10, 20], "target": [30, 10]}], "handles": []}', '"handles" appears twice'),
        (
            '{"handles": [{"kind": "point", "position": [10, 20], "position": [30, 10]}]}',
            '"position" appears twice in one object of a point',
        ),
        ('{"handles": [], "options": {"anchor": 5, "anchor": null}}', '"anchor" appears twice'),
    ],
)
def test_duplicate_keys_are_refused(tmp_path: Path, panorama: Path, text: str, key: str) -> None:
    assert isinstance(json.loads(text), dict)  # before: json keeps the last of each key silently (an identity warp, exit 0)
    path = _write(tmp_path / "dup.json", text)
    with pytest.raises(HandlesError, match=rf"dup\.json: the key {key}"):
        load_handles(path)
    if 'handles" appears' in key:
        run = _cli("warp", str(panorama), "-H", str(path), "-o", str(tmp_path / "out.png"))
        _one_line_refusal(run, str(path), "appears twice")
        assert not (tmp_path / "out.png").exists()
