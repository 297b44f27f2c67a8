#!/usr/bin/env python
"""Pictures of each family's worst scene, before and after: the input with its handles, the paper's mode, the default's blend alone, the default.

Usage::

    python bench/bench_default.py --json /tmp/report.json        # the report half's figures
    python bench/make_worst_pictures.py /tmp/report.json [--width 1024] [--out docs/images/worst]

For every family in the file, the scene whose default-mode distortion p99 is the largest is
warped again at ``--width`` and written as one PNG of four rows (the input with the handles
drawn; the paper's mode with its turned-over pixels in red; the default mode without the
harmonic fill, its blend alone untangled, as it was before the fill; the default mode), each
row ``--width`` wide, and a markdown line per family is printed for ``bench/RESULTS.md``. Run
on demand, not a test.
"""

from __future__ import annotations

import argparse
import json
import sys
import warnings
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402

from omniwidget.document.handles import Handles, Options  # noqa: E402
from omniwidget.evaluate.scenes import family_scene  # noqa: E402
from omniwidget.io.draw import display_rgb, draw_handles  # noqa: E402
from omniwidget.io.images import write_image  # noqa: E402
from omniwidget.method import harmonic  # noqa: E402
from omniwidget.raster.pipeline import warp  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("figures", type=Path, help="a --json file of bench/bench_default.py")
    parser.add_argument("--width", type=int, default=1024)
    parser.add_argument("--out", type=Path, default=Path("docs/images/worst"))
    args = parser.parse_args(argv)
    warnings.simplefilter("ignore")
    records = json.loads(args.figures.read_text())
    args.out.mkdir(parents=True, exist_ok=True)
    for family in dict.fromkeys(r["family"] for r in records):
        scenes = [r for r in records if r["family"] == family and r["mode"] == "default"]
        worst = max(scenes, key=lambda r: r["distortion_p99"] or 0.0)
        scene, doc, _ = family_scene(family, worst["seed"], args.width)
        paper = warp(scene.image, Handles(doc.handles, Options(rectify="all", anchor=None)), warn=False)
        default = warp(scene.image, doc, warn=False)
        harmonic.FILL = False
        try:
            blend = warp(scene.image, doc, warn=False)
        finally:
            harmonic.FILL = True
        turned = display_rgb(paper.image).copy()
        turned[paper.folds.mask] = (255, 0, 0)
        rows = [draw_handles(display_rgb(scene.image), doc), turned, display_rgb(blend.image), display_rgb(default.image)]
        path = args.out / f"{family}.png"
        write_image(path, np.vstack(rows))
        print(
            f"- {family}, seed {worst['seed']} (p99 {worst['distortion_p99']:.2f} default, {blend.quality.distortion_p99:.2f} "
            f"its blend alone, {paper.quality.distortion_p99:.2f} paper; the paper's fold-over {100 * paper.folds.area:.2f}%, "
            f"the default's {100 * default.folds.area:.2f}%): ![{family}: input with handles, the paper's mode, the blend alone, "
            f"the default]"
            f"(../{path.as_posix()})"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
