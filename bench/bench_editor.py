#!/usr/bin/env python
"""How long the editor takes from an edit to the new preview, run on demand (not a test).

Usage::

    python bench/bench_editor.py              # kernel side: 5 edits of the 12-handle scene
    python bench/bench_editor.py --browser    # also the real-browser figure (runs tests/test_editor_browser.py)

What it measures (the editor's target: "the time from mouse release to the new result image on screen
for a 12-handle scene at preview size: at most 1 s now"):

1. Kernel side: an :class:`omniwidget.Editor` on the blending benchmark's scene
   (``bench/bench_blend.py``: 8 lines, 2 points, a fixed 4-vertex cage, here rectified
   "all") at 2048 x 1024. Each timed edit changes one point's zoom, as a drag would, and
   waits until the preview (1024 x 512) is computed, encoded and set on the widget: median
   wall time, and the median of the warp's own stages. Beside it, in the same process, the
   full-size warp of the same handles (the reference: the preview should cost a fraction).
2. The autosave's cost per edit: the same scene's document written whole (temporary file
   and rename) after each edit, timed alone and as part of the assignment (which returns
   before the preview is computed), with autosave on and off.
3. With ``--browser``: the real-browser test, which drags a point of the same scene in
   JupyterLab three times and reads the time from ``pointerup`` to the new image drawn on
   the canvas (the front end's own ``performance.now()``), from
   ``test-artifacts/editor_latency.json``.

Nothing is asserted; the exit status is 0 whatever the figures.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO_ROOT))
sys.path.insert(0, str(REPO_ROOT / "bench"))

from bench_blend import SEED, build_scene  # noqa: E402

from omniwidget.document.handles import Options, PointHandle  # noqa: E402
from omniwidget.raster.pipeline import warp  # noqa: E402
from omniwidget.widget import Editor  # noqa: E402


def kernel_side(repeat: int) -> None:
    image, scene = build_scene(SEED)
    scene = replace(scene, options=Options(rectify="all"))
    editor = Editor(image, scene, autosave=False)
    editor.wait()
    index = next(i for i, h in enumerate(scene.handles) if isinstance(h, PointHandle))
    walls, stages = [], []
    for i in range(repeat + 1):
        items = list(scene.handles)
        items[index] = replace(items[index], scale=items[index].scale * (1.05 + 0.01 * i))
        start = time.perf_counter()
        editor.handles = replace(scene, handles=tuple(items))
        status = editor.wait()
        if i:  # the first is a warm-up
            walls.append(time.perf_counter() - start)
            stages.append(editor.preview_result.timings)
    full = []
    for _ in range(max(1, repeat // 2)):
        start = time.perf_counter()
        warp(image, editor.document, warn=False)
        full.append(time.perf_counter() - start)
    print(f"scene: {len(scene.handles)} handles at {image.shape[1]} x {image.shape[0]}, preview {status['width']} px wide")
    print(
        f"edit -> preview set on the widget: median {statistics.median(walls):.3f} s over {repeat} (target for the whole round trip: 1 s)"
    )
    names = stages[0].keys()
    print("  stages (median s): " + ", ".join(f"{n} {statistics.median(s[n] for s in stages):.3f}" for n in names))
    print(f"reference, the full-size warp of the same handles: median {statistics.median(full):.3f} s")
    print(f"  preview / full: {statistics.median(walls) / statistics.median(full):.2f}")


def autosave_cost(edits: int = 200) -> None:
    """Median cost of the autosave per edit of the 12-handle scene, alone and in the assignment."""
    image, scene = build_scene(SEED)
    scene = replace(scene, options=Options(rectify="all"))
    index = next(i for i, h in enumerate(scene.handles) if isinstance(h, PointHandle))

    def edited(i: int):
        items = list(scene.handles)
        items[index] = replace(items[index], scale=1.0 + 0.001 * (i + 1))
        return replace(scene, handles=tuple(items))

    with tempfile.TemporaryDirectory() as folder:
        figures = {}
        for autosave in (False, Path(folder)):
            editor = Editor(image, scene, autosave=autosave)
            editor.wait()
            docs = [edited(i) for i in range(edits)]
            assign, alone = [], []
            for doc in docs:
                start = time.perf_counter()
                editor.handles = doc  # returns once the edit is recorded (and autosaved); the preview computes meanwhile
                assign.append(time.perf_counter() - start)
            editor.wait()
            if autosave:
                for doc in docs:
                    start = time.perf_counter()
                    editor.session._autosave(doc)
                    alone.append(time.perf_counter() - start)
                size = editor.autosave_path.stat().st_size
            previews = []
            for doc in docs[: edits // 10]:
                start = time.perf_counter()
                editor.handles = replace(
                    doc,
                    handles=(
                        *doc.handles[:index],
                        replace(doc.handles[index], scale=2.0 - doc.handles[index].scale),
                        *doc.handles[index + 1 :],
                    ),
                )
                editor.wait()
                previews.append(time.perf_counter() - start)
            figures[bool(autosave)] = (statistics.median(assign), statistics.median(alone) if alone else 0.0, statistics.median(previews))
    on, off = figures[True], figures[False]
    print(f"autosave of the {len(scene.handles)}-handle document ({size} bytes), median of {edits} edits:")
    print(f"  the write alone (temporary file + rename): {1000 * on[1]:.2f} ms")
    print(f"  the assignment (validate, record, schedule, autosave): {1000 * on[0]:.2f} ms with autosave, {1000 * off[0]:.2f} ms without")
    print(f"  edit -> preview set, median of {edits // 10}: {1000 * on[2]:.0f} ms with autosave, {1000 * off[2]:.0f} ms without")


def browser_side() -> None:
    artifacts = Path(os.environ.get("OMNIWIDGET_ARTIFACTS", REPO_ROOT / "test-artifacts"))
    test = REPO_ROOT / "tests" / "test_editor_browser.py"
    subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", str(test)], cwd=REPO_ROOT, check=True)
    figure = json.loads((artifacts / "editor_latency.json").read_text())
    print(
        f"real browser, mouse release -> new image on screen, {figure['handles']} handles at {figure['preview_width']} px: "
        f"median {figure['median_ms']:.0f} ms of {figure['release_to_image_ms']} (target 1000 ms; "
        f"the kernel's computation {1000 * figure['kernel_compute_s']:.0f} ms of it)"
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--browser", action="store_true", help="also run the real-browser test and report its latency")
    args = parser.parse_args(argv)
    kernel_side(args.repeat)
    autosave_cost()
    if args.browser:
        browser_side()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
