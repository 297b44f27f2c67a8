"""A trusted kernel store: stored machine code, and numba's cache of the kernels, are used only when they are the user's own.

The stored native kernels (:mod:`omniwidget._native`) are machine code that a process loads
and runs; numba's cache holds pickles that numba unpickles. Both are read only from files
and folders owned by the user (or root) that no one else can write, and a stored kernel
only when its HMAC, keyed by the user's own secret, is right. Anything else is compiled
again, with the same result.

The first tests write and read files in this process (no compiler: fake machine code
that is never loaded); the others run real warps in fresh processes on a copy of one store
that a single process compiles for the module (about 20 s).
"""

from __future__ import annotations

import json
import logging
import os
import pickle
import shutil
import stat
import subprocess
import sys
from pathlib import Path

import pytest

from omniwidget import _native
from omniwidget.raster import _kernels

pytestmark = [
    pytest.mark.skipif(not _kernels.available(), reason="numba is not installed (pip install numba)"),
    pytest.mark.skipif(not hasattr(os, "getuid"), reason="owners and modes are POSIX"),
]

OTHER = 65534  # nobody: a user who is not us
NAME, KEY = "fold_rows", (("<f8", 2), "<i8")
CODE = bytes(range(256)) * 4  # stands for machine code; never loaded here


# --- in this process: the rule, file by file --------------------------------------------------
@pytest.fixture
def store(tmp_path, monkeypatch):
    """The store in ``tmp_path/numba`` (``NUMBA_CACHE_DIR``), the user's cache (and key) in ``tmp_path/xdg``; a file written."""
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "numba"))
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    monkeypatch.setattr(_native, "_state", {})
    header = {**_native._stamp(), "kernel": NAME, "key": repr(KEY), "symbol": "kernel"}
    path = _native._write(NAME, KEY, header, CODE)
    assert path == tmp_path / "numba" / "omniwidget-native" / _native._file_name(NAME, KEY)
    return path


def _said(caplog) -> str:
    return "\n".join(r.getMessage() for r in caplog.records)


def test_a_file_of_ours_is_read_back_signed(store, tmp_path):
    header, code = _native._read(NAME, KEY)
    assert code == CODE and header["symbol"] == "kernel"
    key = tmp_path / "xdg" / "omniwidget" / "native.key"
    assert stat.S_IMODE(key.stat().st_mode) == 0o600 and len(key.read_bytes()) == 32
    assert stat.S_IMODE(store.stat().st_mode) & 0o022 == 0


@pytest.mark.parametrize("where", ["code", "header"])
def test_an_altered_file_is_not_read(store, caplog, where):
    data = bytearray(store.read_bytes())
    if where == "code":
        data[-_native._TAG - 10] ^= 0x01  # one bit of the machine code, the header kept
    else:
        at = data.index(b'"symbol": "kernel"')
        data[at : at + 18] = b'"symbol": "kerneL"'
    store.write_bytes(bytes(data))
    with caplog.at_level(logging.DEBUG, "omniwidget"):
        assert _native._read(NAME, KEY) is None
    assert "checksum does not match" in _said(caplog)


@pytest.mark.parametrize("mode", [0o777, 0o775, 0o757])
def test_a_folder_others_can_write_is_not_read_and_not_written(store, caplog, mode, tmp_path):
    folder = store.parent
    os.chown(folder, -1, OTHER)  # its group nogroup, of which the user is not even a member
    folder.chmod(mode)
    with caplog.at_level(logging.DEBUG, "omniwidget"):
        assert _native._read(NAME, KEY) is None
        again = _native._write(NAME, KEY, {**_native._stamp(), "kernel": NAME, "key": repr(KEY)}, CODE)
    assert "writable by" in _said(caplog) and str(folder) in _said(caplog)
    assert again == tmp_path / "xdg" / "omniwidget" / "native" / store.name  # the user's own cache instead


def test_a_folder_above_is_checked_and_a_sticky_one_is_allowed(store, caplog):
    above = store.parent.parent
    above.chmod(0o777)
    with caplog.at_level(logging.DEBUG, "omniwidget"):
        assert _native._read(NAME, KEY) is None
    assert f"{above} is writable by others" in _said(caplog)
    above.chmod(0o1777)  # as /tmp: others cannot rename or remove what is ours in it
    assert _native._read(NAME, KEY) is not None


def test_a_file_not_ours_is_not_read(store, caplog):
    os.chown(store, OTHER, OTHER)
    with caplog.at_level(logging.DEBUG, "omniwidget"):
        assert _native._read(NAME, KEY) is None
    assert f"owned by another user (uid {OTHER})" in _said(caplog)


def test_a_file_others_can_write_is_not_read(store, caplog):
    store.chmod(0o666)
    with caplog.at_level(logging.DEBUG, "omniwidget"):
        assert _native._read(NAME, KEY) is None
    assert "writable by others" in _said(caplog)


def test_a_symbolic_link_is_not_followed(store, caplog, tmp_path):
    real = tmp_path / "elsewhere.native"
    store.rename(real)  # a good file of ours, but not where the store is
    store.symlink_to(real)
    with caplog.at_level(logging.DEBUG, "omniwidget"):
        assert _native._read(NAME, KEY) is None
    assert "symbolic link" in _said(caplog)


def test_a_fifo_is_refused_without_waiting(store, caplog):
    store.unlink()
    os.mkfifo(store)
    with caplog.at_level(logging.DEBUG, "omniwidget"):
        assert _native._read(NAME, KEY) is None  # a plain open would wait for a writer here
    assert "not a regular file" in _said(caplog)


def test_a_key_others_can_read_is_made_anew_and_its_files_are_not_read(store, caplog, monkeypatch, tmp_path):
    key = tmp_path / "xdg" / "omniwidget" / "native.key"
    key.chmod(0o644)
    monkeypatch.setattr(_native, "_state", {})  # a new process
    with caplog.at_level(logging.DEBUG, "omniwidget"):
        assert _native._read(NAME, KEY) is None
    assert "made anew" in _said(caplog) and "signed with another key" in _said(caplog)
    assert stat.S_IMODE(key.stat().st_mode) == 0o600
    _native._write(NAME, KEY, {**_native._stamp(), "kernel": NAME, "key": repr(KEY)}, CODE)
    assert _native._read(NAME, KEY) is not None


def test_no_key_where_others_can_write_no_store(store, caplog, monkeypatch, tmp_path):
    (tmp_path / "xdg").chmod(0o777)
    monkeypatch.setattr(_native, "_state", {})
    with caplog.at_level(logging.DEBUG, "omniwidget"):
        assert _native._read(NAME, KEY) is None
        assert _native._write(NAME, KEY, {**_native._stamp(), "kernel": NAME, "key": repr(KEY)}, CODE) is None
    assert "the folder of their key" in _said(caplog)


def test_numba_cache_others_can_write_is_moved_to_the_users_own(tmp_path, monkeypatch):
    """Numba's cache folder of a module's kernels, writable by others, is replaced by one in the user's cache before any kernel runs."""
    import importlib.util

    from numba.core import config

    shared = tmp_path / "shared"
    shared.mkdir(mode=0o777)
    shared.chmod(0o777)
    monkeypatch.setattr(config, "CACHE_DIR", str(shared))
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    monkeypatch.setattr(_native, "_state", {})
    source = tmp_path / "some_kernels.py"
    source.write_text("from numba import njit\n\n@njit(cache=True)\ndef twice(x):\n    return 2 * x\n")
    spec = importlib.util.spec_from_file_location("some_kernels", source)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    assert Path(module.twice._cache._cache_path).parent == shared  # numba's choice: NUMBA_CACHE_DIR
    _native.secure_numba_cache(vars(module))
    assert Path(module.twice._cache._cache_path).parent == tmp_path / "xdg" / "omniwidget" / "numba"
    assert config.CACHE_DIR == str(shared)  # for these kernels alone
    assert module.twice(21) == 42
    assert not [p for p in shared.rglob("*") if p.is_file()]  # (numba made its empty folder there when the kernel was defined)
    assert list((tmp_path / "xdg" / "omniwidget" / "numba").rglob("*.nbi"))


# --- fresh processes: real kernels --------------------------------------------------------------
_WARP = """
import hashlib, json, logging, sys, warnings
warnings.simplefilter("ignore")
said = []
class Keep(logging.Handler):
    def emit(self, record):
        said.append(record.getMessage())
logging.getLogger("omniwidget").addHandler(Keep())
logging.getLogger("omniwidget").setLevel(logging.DEBUG)
from omniwidget.evaluate.scenes import family_scene
from omniwidget.raster.pipeline import warp
scene, doc, _ = family_scene("mixed", 1, 512)
image = warp(scene.image, doc).image
print(json.dumps({"numba": "numba" in sys.modules, "image": hashlib.sha256(image.tobytes()).hexdigest(), "said": said}))
"""


def _env(root: Path, **more: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in ("OMNIWIDGET_NATIVE", "OMNIWIDGET_NUMBA", "NUMBA_DISABLE_JIT")}
    return {**env, "NUMBA_CACHE_DIR": str(root / "numba"), "XDG_CACHE_HOME": str(root / "xdg"), **more}


def _fresh(root: Path, **more: str) -> dict:
    """A warp of a 512-wide scene in a new process with the store in ``root``: did it import numba, its image's digest, what was logged."""
    run = subprocess.run([sys.executable, "-c", _WARP], env=_env(root, **more), capture_output=True, text=True, timeout=600, check=True)
    return json.loads(run.stdout.strip().splitlines()[-1])


def _files(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


@pytest.fixture(scope="module")
def built(tmp_path_factory) -> tuple[Path, dict]:
    """One store compiled from nothing (numba's cache, the native kernels, the key): the behaviour when nothing is stored."""
    root = tmp_path_factory.mktemp("built")
    first = _fresh(root)
    assert first["numba"] and not [s for s in first["said"] if "not used" in s], first
    return root, first


@pytest.fixture
def copy(built, tmp_path) -> tuple[Path, dict]:
    """A copy of the built store of this test's own (modes kept)."""
    root, first = built
    shutil.copytree(root, tmp_path / "s", symlinks=True)
    return tmp_path / "s", first


def _native_files(root: Path) -> list[Path]:
    files = sorted((root / "numba" / "omniwidget-native").glob("*.native"))
    assert files
    return files


def test_a_good_store_is_loaded_and_nothing_compiled(copy):
    root, first = copy
    before = _files(root)
    again = _fresh(root)
    assert not again["numba"] and again["image"] == first["image"] and again["said"] == [], again
    assert _files(root) == before  # nothing rewritten


def test_a_store_others_can_write_is_not_loaded(copy):
    root, first = copy
    folder = root / "numba" / "omniwidget-native"
    folder.chmod(0o777)
    before = _files(folder)
    again = _fresh(root)
    assert again["numba"] and again["image"] == first["image"], again  # compiled again (numba's cache: no recompilation)
    assert any(f"{folder} is writable by others" in s for s in again["said"]), again["said"]
    assert _files(folder) == before  # nothing written where others can write
    assert sorted(p.name for p in (root / "xdg" / "omniwidget" / "native").iterdir()) == sorted(before)


def test_an_altered_stored_kernel_is_not_loaded_and_is_stored_again(copy):
    root, first = copy
    for path in _native_files(root):
        data = bytearray(path.read_bytes())
        data[-_native._TAG - 64] ^= 0xFF  # a byte of the machine code; the header as it was
        path.write_bytes(bytes(data))
    again = _fresh(root)
    assert again["numba"] and again["image"] == first["image"], again
    assert any("checksum does not match" in s for s in again["said"]), again["said"]
    healed = _fresh(root)  # stored again, in place
    assert not healed["numba"] and healed["image"] == first["image"] and healed["said"] == [], healed


@pytest.mark.slow  # a fresh process building the native kernels again (15 s): the rule itself is tested above
def test_a_stored_kernel_not_ours_is_not_loaded(copy):
    root, first = copy
    for path in _native_files(root):
        os.chown(path, OTHER, OTHER)
    again = _fresh(root)
    assert again["numba"] and again["image"] == first["image"], again
    assert any(f"owned by another user (uid {OTHER})" in s for s in again["said"]), again["said"]
    assert all(p.stat().st_uid == os.getuid() for p in _native_files(root))  # replaced by the user's own


def _plant(index: Path, marker: Path) -> None:
    """Make numba's index file ``index`` run code when numba unpickles it, then read on as if nothing had happened."""
    with index.open("rb") as f:
        pickle.load(f)  # numba's version
        rest = f.read()

    class Payload:
        def __reduce__(self):
            return eval, (f"open({str(marker)!r}, 'w').close() or __import__('numba').__version__",)

    index.write_bytes(pickle.dumps(Payload()) + rest)


@pytest.mark.slow  # two fresh processes, one building the native kernels again (30 s): the rule itself is tested above
def test_numba_cache_others_can_write_is_not_unpickled(copy):
    """Numba unpickles its index files: one others can write is planted here, and not read, while one of ours is."""
    root, first = copy
    shared = root / "numba"
    (cached,) = [p for p in shared.iterdir() if p.name.startswith("omniwidget_")]
    own = root / "xdg" / "omniwidget" / "numba"
    own.mkdir()
    shutil.copytree(cached, own / cached.name)  # numba's good cache, where it is to be kept instead (no recompilation)
    marker = root / "ran"
    for index in cached.glob("*.nbi"):
        _plant(index, marker)
    shared.chmod(0o777)
    again = _fresh(root)
    assert not marker.exists(), "numba unpickled an index file that others could write"
    assert again["numba"] and again["image"] == first["image"], again
    assert any(f"{shared} is writable by others; it is kept in {own} instead" in s for s in again["said"]), again["said"]
    # the same planted files in a folder of ours are unpickled: what the rule keeps out (native kernels off: numba runs)
    shared.chmod(0o755)
    control = _fresh(root, OMNIWIDGET_NATIVE="0")
    assert marker.exists() and control["image"] == first["image"], control
