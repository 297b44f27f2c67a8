#!/usr/bin/env python
"""The live drag in a real browser (JupyterLab, Debian's Chromium, WebGL2 in software).

Usage::

    python bench/bench_live.py [--repeat 5]

For two scenes at the 1024 x 512 preview (a point, a line and a cage; the still background,
then the paper's mode, where every handle weighs over the whole sphere), each handle's
control point is dragged on the result by 60 mouse moves 16 ms apart, ``--repeat`` times.
Medians: live frames drawn per second of the drag, the cost of one frame in the browser
(GPU sum, drawing the pane), the region the frame covers, and the time from hovering a
control point to its basis on the GPU. Run on demand on a quiet machine, not a test.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tests import browser_harness as bh  # noqa: E402
from tests.test_editor_browser import Pane, kernel_json, wait_idle  # noqa: E402

SCENES = {
    "still background": "None",
    "paper (anchor null)": "ow.Options(anchor=None)",
}
CELL = (
    "import json\nimport omniwidget as ow\n\n"
    "doc = ow.Handles((ow.PointHandle((20.0, 5.0)), ow.LineHandle((-70.0, 30.0), (-30.0, 36.0)),\n"
    "                  ow.CageHandle(((100.0, -10.0), (130.0, -10.0), (115.0, 15.0)))), options={options} or ow.Options())\n"
    "ed = ow.Editor(ow.sample_path(), doc, height=440, autosave=False)\ned.stage = 'transform'\ned"
)
DRAGS = [("point centre", 0, 0, (60, 10)), ("line end", 1, 2, (20, 30)), ("cage vertex", 2, 2, (40, 20))]


def one_drag(nb, root, pane, outputs, handle, part, by) -> dict:
    generation = int(root.get_attribute("data-generation"))
    start = pane.at(outputs[handle][part])
    t0 = time.perf_counter()
    nb.page.mouse.move(*start)
    bh.wait_until(lambda: root.get_attribute("data-live-basis") == f"{generation}:{handle}", timeout=30, description="the basis")
    ready = time.perf_counter() - t0
    frames = int(root.get_attribute("data-live-frames"))
    nb.page.mouse.down()
    t0 = time.perf_counter()
    for i in range(1, 61):
        nb.page.mouse.move(start[0] + by[0] * i / 60, start[1] + by[1] * i / 60)
        nb.page.wait_for_timeout(16)
    seconds = time.perf_counter() - t0
    drawn = int(root.get_attribute("data-live-frames")) - frames
    region = json.loads(root.get_attribute("data-live-region"))
    nb.page.mouse.up()
    return {
        "rate": drawn / seconds,
        "frame_ms": float(root.get_attribute("data-live-ms")),
        "region": region["width"] * region["height"] / (region["size"] ** 2 / 2),
        "basis_s": ready,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    bh.require_browser()
    print("| scene | drag | live frames per second | one frame (ms) | share of the image redrawn | hover to basis (s) |")
    print("| --- | --- | --- | --- | --- | --- |")
    with bh.JupyterServer(name="bench-live") as server, bh.launch_browser() as browser:
        for scene, options in SCENES.items():
            bh.write_notebook(server.root / "live.ipynb", [CELL.format(options=options)])
            with bh.NotebookPage(browser, server, "live.ipynb") as nb:
                nb.run_all()
                root = nb.wait_for_output(".ow-editor")
                wait_idle(nb, 0, "the first result")
                kc = nb.kernel_client()
                runs: dict[str, list[dict]] = {name: [] for name, *_ in DRAGS}
                for _ in range(args.repeat):
                    for name, handle, part, by in DRAGS:
                        generation = int(root.get_attribute("data-generation"))
                        changed = bh.run_in_kernel(kc, "print(ed.handles != doc.to_dict())\ned.handles = doc.to_dict()")  # every drag from one document
                        if changed.strip() == "True":
                            wait_idle(nb, generation, "the document again")
                        time.sleep(0.5)
                        runs[name].append(one_drag(nb, root, Pane(nb, "result"), kernel_json(kc, "ed.outputs"), handle, part, by))
                        wait_idle(nb, int(root.get_attribute("data-generation")), "the result of the drag")
                for name, rows in runs.items():
                    med = {k: statistics.median(r[k] for r in rows) for k in rows[0]}
                    print(f"| {scene} | {name} | {med['rate']:.0f} | {med['frame_ms']:.0f} | {100 * med['region']:.1f}% | {med['basis_s']:.2f} |")


if __name__ == "__main__":
    main()
