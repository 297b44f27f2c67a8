#!/usr/bin/env python
"""How long the teaching notebooks take to run top to bottom (the aim: under 5 minutes for all).

Usage::

    python bench/bench_notebooks.py [--runs 1] [NOTEBOOK ...]

Each numbered notebook of ``notebooks/`` (or those named) is executed headless with nbclient
in a fresh kernel, in a temporary folder of its own, as ``tests/test_notebooks.py`` does; the
wall-clock seconds of each (the median of ``--runs``) and their total are printed as a markdown
table. The tests check the notebooks' outputs but assert no time: on a shared machine the wall
clock is a report, not a test. Run on demand, not a test.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def run(path: Path) -> float:
    """Seconds to execute ``path`` top to bottom in a fresh kernel, in a temporary folder."""
    import nbclient
    import nbformat

    nb = nbformat.read(path, as_version=4)
    with tempfile.TemporaryDirectory(prefix=f"bench-{path.stem}-") as folder:
        start = time.perf_counter()
        nbclient.NotebookClient(nb, timeout=600, kernel_name="python3", resources={"metadata": {"path": folder}}).execute()
        return time.perf_counter() - start


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("notebooks", nargs="*", type=Path, help="default: notebooks/[0-9][0-9]_*.ipynb")
    parser.add_argument("--runs", type=int, default=1)
    args = parser.parse_args(argv)
    paths = args.notebooks or sorted((ROOT / "notebooks").glob("[0-9][0-9]_*.ipynb"))
    print("| notebook | seconds |")
    print("| --- | --- |")
    total = 0.0
    for path in paths:
        seconds = statistics.median(run(path) for _ in range(args.runs))
        total += seconds
        print(f"| {path.name} | {seconds:.1f} |", flush=True)
    print(f"| all {len(paths)} | {total:.1f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
