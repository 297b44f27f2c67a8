#!/usr/bin/env python
"""Snapshot of ``build_constraints`` on many documents, to show a restructuring changes no number (not a test).

Usage::

    python bench/constraints_snapshot.py take before.pkl      # at one commit
    python bench/constraints_snapshot.py take after.pkl       # at another
    python bench/constraints_snapshot.py compare before.pkl after.pkl

The documents: each scene family of :data:`omniwidget.evaluate.scenes.FAMILIES` at seeds
0, 1 and 2, and three made by hand (crossing lines, a point and a moved cage; a chain of
joined lines, a line over a pole and one with explicit targets; near-vertical lines meeting),
each with four option sets (the defaults, ``anchor: null``, ``rectify: each``, ``up`` set)
and with ``upright`` off and on. Every field of the result is kept: the controls' matrices,
handles and labels, the prescribed points and weights, the line samples, chains, disks,
cages, the lines near a pole, and Sec. 3.4's targets, normal matrix and displacement.
``compare`` says whether every array is equal, and the largest difference otherwise.
"""

from __future__ import annotations

import argparse
import pickle
import sys
import warnings
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from omniwidget.document.handles import CageHandle, Handles, LineHandle, PointHandle  # noqa: E402
from omniwidget.evaluate.scenes import FAMILIES, family_scene  # noqa: E402
from omniwidget.method.constraints import build_constraints  # noqa: E402

BY_HAND = (
    Handles(
        (
            LineHandle((-40.0, 10.0), (40.0, 30.0)),
            LineHandle((-10.0, 40.0), (10.0, 0.0)),
            PointHandle((100.0, 0.0), (104.0, 2.0), 20.0, 1.4),
            CageHandle(((150.0, -10.0), (170.0, -10.0), (160.0, -30.0)), ((151.0, -10.0), (172.0, -10.0), (160.0, -31.0))),
        )
    ),
    Handles(
        (
            LineHandle((-80.0, 20.0), (80.0, 25.0)),
            LineHandle((80.0, 25.0), (120.0, -20.0)),
            LineHandle((0.0, 60.0), (170.0, 70.0)),
            LineHandle((10.0, -5.0), (30.0, -5.0), rectify=False, targets=((10.0, -5.0), (20.0, -3.0), (30.0, -5.0))),
        )
    ),
    Handles((LineHandle((0.0, 10.0), (0.5, 60.0)), LineHandle((0.5, 60.0), (40.0, 40.0)), LineHandle((40.0, 40.0), (40.3, 5.0)))),
)
OPTIONS: tuple[dict[str, Any], ...] = ({}, {"anchor": None}, {"rectify": "each"}, {"up": (10.0, 80.0)})


def documents() -> list[tuple[str, Handles]]:
    """The documents snapshotted, each with a name."""
    out = [(f"{family}{seed}", family_scene(family, seed, width=512)[1]) for family in FAMILIES for seed in (0, 1, 2)]
    return out + [(f"by hand {n}", doc) for n, doc in enumerate(BY_HAND)]


def take(path: Path) -> int:
    """Write the snapshot to ``path``; returns the number of cases."""
    warnings.simplefilter("ignore")
    out = {}
    for name, doc in documents():
        for options in OPTIONS:
            varied = replace(doc, options=replace(doc.options, **options))
            for upright in (False, True):
                c = build_constraints(varied, upright=upright)
                solved = c.rectified
                out[(name, str(options), upright)] = {
                    "controls": [(x.moebius.matrix, x.handle, x.label) for x in c.controls],
                    "points": c.points,
                    "values": c.values,
                    "lines": c.lines,
                    "chains": c.chains,
                    "disks": c.disks,
                    "cages": c.cages,
                    "near_pole": c.near_pole,
                    "targets": None if solved is None else solved.targets,
                    "matrix": None if solved is None else solved.matrix.toarray(),
                    "displacement": None if solved is None else solved.displacement,
                }
    path.write_bytes(pickle.dumps(out))
    return len(out)


def _difference(a: Any, b: Any, where: str) -> float:
    """0 for equal values, the largest absolute difference of numbers otherwise; ValueError where the structure differs."""
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        a, b = np.asarray(a), np.asarray(b)
        if a.shape != b.shape:
            raise ValueError(f"{where}: shapes {a.shape} and {b.shape}")
        return 0.0 if np.array_equal(a, b) else float(np.abs(a - b).max())
    if isinstance(a, (list, tuple)):
        if len(a) != len(b):
            raise ValueError(f"{where}: {len(a)} and {len(b)} items")
        return max((_difference(x, y, f"{where}[{i}]") for i, (x, y) in enumerate(zip(a, b, strict=True))), default=0.0)
    if isinstance(a, dict):
        if a.keys() != b.keys():
            raise ValueError(f"{where}: keys differ")
        return max((_difference(a[k], b[k], f"{where}.{k}") for k in a), default=0.0)
    if isinstance(a, float) and isinstance(b, float):
        return abs(a - b)
    if a != b:
        raise ValueError(f"{where}: {a!r} and {b!r}")
    return 0.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    sub.add_parser("take").add_argument("path", type=Path)
    compare = sub.add_parser("compare")
    compare.add_argument("before", type=Path)
    compare.add_argument("after", type=Path)
    args = parser.parse_args()
    if args.command == "take":
        print(f"{take(args.path)} cases written to {args.path}")
        return
    before, after = (pickle.loads(p.read_bytes()) for p in (args.before, args.after))
    if before.keys() != after.keys():
        raise SystemExit("the snapshots hold different cases")
    worst = max(_difference(before[k], after[k], str(k)) for k in before)
    print(f"{len(before)} cases; every value equal: {worst == 0.0}; largest difference {worst:g}")


if __name__ == "__main__":
    main()
