#!/usr/bin/env python
"""What ``import omniwidget`` and ``omniwidget --help`` cost, against another revision.

Usage::

    python bench/bench_import.py [--against REV] [--repeat 5]

Fresh processes, interleaved (this tree, then ``REV``'s, ``git archive`` into a temporary folder and
put first on ``PYTHONPATH`` and made the working folder), medians of ``--repeat`` rounds:

- ``python -X importtime -c "import omniwidget"``: the cumulative microseconds of ``omniwidget`` (the
  package and everything its import loads);
- ``omniwidget --help`` (the console script's ``main``, run by ``python -c``), wall time of the process;
- the modules ``import omniwidget`` leaves in ``sys.modules``, and the import statements inside functions
  of ``omniwidget/`` (counted in the source, by ``ast``);
- what reading an attribute through a :func:`omniwidget._lazy.lazy` stand-in costs beside reading it from the
  module (``cv2.remap``, median of 7 x 200,000 reads, in this process).

Run on demand, not a test. On a shared machine compare the ratio, not the times.
"""

from __future__ import annotations

import argparse
import ast
import os
import statistics
import subprocess
import sys
import tempfile
import time
import timeit
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
HELP = "import sys; from omniwidget.app.cli import main; sys.argv = ['omniwidget', '--help']; sys.exit(main())"
LOADED = "import sys, omniwidget; print(len(sys.modules), sum(m.split('.')[0] == 'omniwidget' for m in sys.modules))"


def local_imports(package: Path) -> int:
    """The import statements inside a function of ``package``'s sources."""

    def count(node: ast.AST, inside: bool) -> int:
        return sum(
            (inside and isinstance(child, (ast.Import, ast.ImportFrom)))
            + count(child, inside or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)))
            for child in ast.iter_child_nodes(node)
        )

    return sum(count(ast.parse(path.read_text(encoding="utf-8")), False) for path in package.rglob("*.py"))


def _import_us(env: dict[str, str]) -> int:
    err = subprocess.run([sys.executable, "-X", "importtime", "-c", "import omniwidget"], env=env, cwd=env["PYTHONPATH"], capture_output=True, text=True).stderr
    return int([line for line in err.splitlines() if line.rstrip().endswith("| omniwidget")][-1].split("|")[1])


def _help_s(env: dict[str, str]) -> float:
    start = time.perf_counter()
    subprocess.run([sys.executable, "-c", HELP], env=env, cwd=env["PYTHONPATH"], capture_output=True, check=True)
    return time.perf_counter() - start


def attribute_ns() -> tuple[float, float]:
    """Nanoseconds per read of ``cv2.remap``: from the module, and through a lazy() stand-in of it."""
    import cv2

    sys.path.insert(0, str(ROOT))
    from omniwidget._lazy import lazy

    stand_in = lazy("cv2")

    def ns(stmt: str, where: dict) -> float:
        return statistics.median(timeit.repeat(stmt, globals=where, number=200_000, repeat=7)) / 200_000 * 1e9

    return ns("m.remap", {"m": cv2}), ns("m.remap", {"m": stand_in})


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--against", default="HEAD~1", help="the revision compared with (default HEAD~1)")
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as other:
        archive = subprocess.run(["git", "archive", args.against], cwd=ROOT, capture_output=True, check=True).stdout
        subprocess.run(["tar", "-x", "-C", other], input=archive, check=True)
        trees = {"this tree": str(ROOT), args.against: other}
        envs = {name: dict(os.environ, PYTHONPATH=tree) for name, tree in trees.items()}
        imports: dict[str, list[int]] = {name: [] for name in trees}
        helps: dict[str, list[float]] = {name: [] for name in trees}
        for _ in range(args.repeat):
            for name, env in envs.items():
                imports[name].append(_import_us(env))
                helps[name].append(_help_s(env))
        for name, tree in trees.items():
            loaded = subprocess.run([sys.executable, "-c", LOADED], env=envs[name], cwd=tree, capture_output=True, text=True, check=True).stdout.split()
            print(
                f"{name}: import omniwidget {statistics.median(imports[name]) / 1000:.1f} ms, omniwidget --help "
                f"{statistics.median(helps[name]) * 1000:.0f} ms, {loaded[0]} modules loaded ({loaded[1]} of omniwidget), "
                f"{local_imports(Path(tree) / 'omniwidget')} imports inside functions"
            )
        this, that = "this tree", args.against
        print(
            f"ratio this tree / {that}: import {statistics.median(imports[this]) / statistics.median(imports[that]):.3f}, "
            f"--help {statistics.median(helps[this]) / statistics.median(helps[that]):.3f} (medians of {args.repeat})"
        )
    direct, through = attribute_ns()
    print(f"an attribute read: {direct:.0f} ns from the module, {through:.0f} ns through lazy() ({through - direct:.0f} ns more)")


if __name__ == "__main__":
    main()
