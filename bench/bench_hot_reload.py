#!/usr/bin/env python
"""The editor's hot reload from a saved source to the open widget's ``_esm``: seconds per save.

Usage::

    python bench/bench_hot_reload.py [--saves 5]

Needs Node, esbuild (``npm ci``) and the ``watchfiles`` package (anywidget's file watcher;
``pip install watchfiles``). The package, ``build.mjs`` and ``package.json`` are copied to a
temporary folder (``node_modules`` linked), so the checkout's files are never touched. There,
with ``ANYWIDGET_HMR=1``, an :class:`~omniwidget.Editor` of the bundled sample is opened and
``node build.mjs --watch`` started; then ``status.js`` is saved ``--saves`` times, each time
with another value of one constant, and the time from the save to the editor's ``_esm``
holding the new build is measured. Prints each time, their median, and ``ok`` when every
save arrived.
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
CONSTANT = "export const FOLD_AFTER = 3;"


def _copy(into: Path) -> None:
    """The package and the build files in ``into``, esbuild linked from the checkout."""
    shutil.copytree(REPO / "omniwidget", into / "omniwidget", ignore=shutil.ignore_patterns("__pycache__"))
    for name in ("build.mjs", "package.json"):
        shutil.copy2(REPO / name, into / name)
    (into / "node_modules").symlink_to(REPO / "node_modules")


def _arrival(editor, marker: str, timeout: float) -> float | None:
    """Seconds until the editor's ``_esm`` holds ``marker``, None after ``timeout``."""
    start = time.perf_counter()
    while time.perf_counter() - start < timeout:
        if marker in editor._esm:
            return time.perf_counter() - start
        time.sleep(0.01)
    return None


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--saves", type=int, default=5)
    args = parser.parse_args()
    if not (REPO / "node_modules" / "esbuild").is_dir():
        sys.exit("esbuild is not installed: npm ci")
    if importlib.util.find_spec("watchfiles") is None:
        sys.exit("anywidget watches files with watchfiles, not installed: pip install watchfiles")
    os.environ["ANYWIDGET_HMR"] = "1"
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        _copy(root)
        sys.path.insert(0, str(root))
        import omniwidget as ow  # the copy's

        editor = ow.Editor(ow.sample_path(), autosave=False)
        if not (root / "omniwidget").samefile(Path(ow.__file__).parent):
            sys.exit(f"omniwidget was imported from {ow.__file__}, not the copy")
        watch = subprocess.Popen(["node", "build.mjs", "--watch"], cwd=root, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            time.sleep(2.0)  # its first build
            source = root / "omniwidget" / "widget" / "static" / "status.js"
            text = source.read_text(encoding="utf-8")
            times = []
            for value in range(10, 10 + args.saves):
                source.write_text(text.replace(CONSTANT, f"export const FOLD_AFTER = {value};"), encoding="utf-8")
                times.append(_arrival(editor, f"var FOLD_AFTER = {value};", timeout=20.0))
                time.sleep(0.5)
        finally:
            watch.terminate()
            watch.wait()
            editor.close()
    arrived = [t for t in times if t is not None]
    print("save to _esm, s:", " ".join("-" if t is None else f"{t:.2f}" for t in times))
    if arrived:
        print(f"median {statistics.median(arrived):.2f} s over {len(arrived)} saves")
    print("ok" if len(arrived) == len(times) else f"{len(times) - len(arrived)} saves never arrived")


if __name__ == "__main__":
    main()
