"""The result follows the mouse: a live drag in a real browser (JupyterLab and Notebook 7, Debian's Chromium, WebGL2 in software).

While a control point is dragged on the result, the browser redraws the result every frame
from the kernel's basis (:mod:`omniwidget.raster.live`) and the handle's maps rebuilt in
JavaScript (``moebius.js``, checked against Python by ``tests/test_js.py``); on
release the kernel's exact result replaces it.

The tests assert that every mouse move of a scripted drag (60 moves 16 ms apart) changes
the result image, and that the live frame is the kernel's image where the weights stay; the
frames per second this machine reaches are a figure of ``bench/bench_live.py``, not a timed
assertion on a shared machine (they are printed here too).
"""

from __future__ import annotations

import base64
import json
import time

import cv2
import numpy as np
import pytest

from tests import browser_harness as bh
from tests.test_editor_browser import Pane, kernel_json, wait_idle

pytestmark = pytest.mark.browser

#: A point with its arrows, a line and a fixed cage, in the paper's mode (no still
#: background): turning or pulling the point's arrow changes its map but not the weights.
NOTEBOOK = [
    "import json\nimport omniwidget as ow\n\n"
    "doc = ow.Handles((ow.PointHandle((20.0, 5.0)), ow.LineHandle((-70.0, 30.0), (-30.0, 36.0), rectify=True),\n"
    "                  ow.CageHandle(((100.0, -10.0), (130.0, -10.0), (115.0, 15.0)))), options=ow.Options(anchor=None))\n"
    "ed = ow.Editor(ow.sample_path(), doc, height=440)\ned.stage = 'transform'\ned",
]
MOVES = 60
GAP_MS = 16
#: The live frame against the kernel's result, mean absolute difference in grey levels: measured 0.47 in each of
#: four runs (software WebGL, JupyterLab, a loaded machine); bound 1.2x (it was 2.0).
LIVE_GREY = 0.57
#: Moves of a drag that must each change the image: two moves within one display frame draw once.
FOLLOWED = 0.9


def live_frame(nb, under: np.ndarray) -> np.ndarray:
    """The result as the live drag shows it: ``under`` (the result before the drag, RGB) with the live canvas over its region."""
    # the canvas, its region and its step read at once, in the page: a basis or a result arriving meanwhile draws a
    # coarser frame (and the full one a rest later), so the full frame is waited for here, not assumed
    read = """() => { const root = document.querySelector('.ow-editor');
        return [root.dataset.liveStep, root.dataset.liveRegion, root.querySelector('canvas.ow-live').toDataURL('image/png')]; }"""
    _, region_json, url = bh.wait_until(
        lambda: (got := nb.page.evaluate(read))[0] == "1" and got, timeout=30, description="the live frame in full"
    )
    png = base64.b64decode(url.split(",", 1)[1])
    patch = cv2.cvtColor(cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
    region = json.loads(region_json)
    assert patch.shape[:2] == (region["height"], region["width"])
    (row, col), size = region["origin"], region["size"]
    assert under.shape[1] == size
    shown = under[..., :3].copy()
    shown[row : row + patch.shape[0], (col + np.arange(patch.shape[1])) % size] = patch
    return shown


def scripted_drag(nb, start, end, hold: bool = False) -> tuple[int, float]:
    """Press at ``start``, 60 moves 16 ms apart to ``end``; release unless ``hold``. Returns (live frames drawn, seconds)."""
    page, root = nb.page, nb.output(".ow-editor").first
    frames = int(root.get_attribute("data-live-frames"))
    page.mouse.move(*start)
    page.mouse.down()
    t0 = time.perf_counter()
    for i in range(1, MOVES + 1):
        s = i / MOVES
        page.mouse.move(start[0] + s * (end[0] - start[0]), start[1] + s * (end[1] - start[1]))
        page.wait_for_timeout(GAP_MS)
    seconds = time.perf_counter() - t0
    drawn = int(root.get_attribute("data-live-frames")) - frames
    if not hold:
        page.mouse.up()
    return drawn, seconds


def hover_until_basis(nb, root, at, generation: int, handle: int) -> None:
    """Hover ``at`` (a control point of ``handle`` on the result) until its live basis is on the GPU."""
    nb.page.mouse.move(*at)
    expected = f"{generation}:{handle}"
    bh.wait_until(lambda: root.get_attribute("data-live-basis") == expected, timeout=30, description=f"the live basis of handles[{handle}]")


def test_the_result_follows_the_mouse_and_matches_the_kernels_result(jupyter_server, browser):
    bh.one_front_end(jupyter_server, "the live frame against the kernel's")
    bh.write_notebook(jupyter_server.root / "live.ipynb", NOTEBOOK)
    with bh.NotebookPage(browser, jupyter_server, "live.ipynb") as nb:
        nb.run_all()
        root = nb.wait_for_output(".ow-editor")
        generation = wait_idle(nb, 0, "the first result")
        assert root.get_attribute("data-live") == "ready", "WebGL2 is not available in this browser"
        kc = nb.kernel_client()
        outputs = kernel_json(kc, "ed.outputs")
        pane = Pane(nb, "result")

        # hover the point's east arrow tip: the basis comes before the press
        tip = pane.at(outputs[0][1])
        hover_until_basis(nb, root, tip, generation, 0)
        centre = np.array(pane.at(outputs[0][0]))
        end = centre + 1.6 * (np.array(tip) - centre) + [0, -25]  # pulled out and turned: zoom in and turn
        bh.run_in_kernel(kc, "import numpy as np\nnp.save('start.npy', ed.preview_result.image)")
        drawn, seconds = scripted_drag(nb, tip, end, hold=True)
        print(f"arrow drag: {drawn} live frames in {seconds:.2f} s = {drawn / seconds:.1f} per second, last frame {root.get_attribute('data-live-ms')} ms")
        assert drawn >= FOLLOWED * MOVES, f"{drawn} live frames for {MOVES} mouse moves: the result did not follow the mouse"
        bh.wait_until(lambda: root.get_attribute("data-live-step") == "1", timeout=30, description="the live frame in full, the mouse at rest")  # a wait (software WebGL on a loaded machine), not a figure
        bh.run_in_kernel(kc, "import numpy as np\nnp.save('before.npy', ed.preview_result.image)")
        frame = live_frame(nb, np.load(jupyter_server.root / "before.npy"))
        before = kernel_json(kc, "ed.status['generation']")
        nb.page.mouse.up()
        wait_idle(nb, before, "the kernel's result after the arrow drag")
        scale = kernel_json(kc, "ed.document.handles[0].scale")
        assert scale > 1.3, f"the drag should zoom in, scale {scale}"
        exact = kernel_json(kc, "ed.preview_result.image.shape[:2]")
        assert list(frame.shape[:2]) == exact
        bh.run_in_kernel(kc, "import numpy as np\nnp.save('kernel.npy', ed.preview_result.image)")
        kernel = np.load(jupyter_server.root / "kernel.npy")
        difference = np.abs(frame.astype(np.float64) - kernel[..., :3]).mean()
        print(f"live frame against the kernel's result: mean absolute difference {difference:.3f} grey levels")
        assert difference < LIVE_GREY, f"the live frame differs from the kernel's result by {difference:.3f} grey levels on average"
        moved = np.abs(np.load(jupyter_server.root / "start.npy")[..., :3].astype(np.float64) - kernel[..., :3]).mean()
        assert moved > 4 * difference, f"the drag changed the result by {moved:.2f} grey levels on average: too little to tell"
        nb.screenshot("live-arrow-drag")
        assert nb.console_errors() == []


def test_the_live_drag_keeps_its_rate_while_the_kernel_computes(jupyter_server, browser):
    """Default mode (the still background): a cage dragged and a point moved show live frames while a full-size result computes."""
    bh.one_front_end(jupyter_server, "the live drag's rate")
    cells = [
        "import json\nimport omniwidget as ow\n\n"
        "doc = ow.Handles((ow.PointHandle((20.0, 5.0)), ow.CageHandle(((100.0, -10.0), (130.0, -10.0), (115.0, 15.0)))))\n"
        "ed = ow.Editor(ow.sample_path(), doc, height=440)\ned.stage = 'transform'\ned",
    ]
    bh.write_notebook(jupyter_server.root / "live-busy.ipynb", cells)
    with bh.NotebookPage(browser, jupyter_server, "live-busy.ipynb") as nb:
        nb.run_all()
        root = nb.wait_for_output(".ow-editor")
        generation = wait_idle(nb, 0, "the first result")
        kc = nb.kernel_client()
        outputs = kernel_json(kc, "ed.outputs")
        pane = Pane(nb, "result")
        vertex = pane.at(outputs[1][2])
        hover_until_basis(nb, root, vertex, generation, 1)
        # the kernel's worker computes the full-size result, and a thread of the kernel keeps computing till told to stop
        bh.run_in_kernel(
            kc,
            "import threading, numpy as np\nstop = threading.Event()\n"
            "hog = threading.Thread(target=lambda: [np.linalg.svd(np.random.rand(500, 500)) for _ in iter(stop.is_set, True)])\n"
            "hog.start()\ned.compute_full()",
        )
        drawn, seconds = scripted_drag(nb, vertex, (vertex[0] + 40, vertex[1] + 20))
        print(f"cage vertex drag while the kernel computes: {drawn} live frames in {seconds:.2f} s = {drawn / seconds:.1f} per second")
        assert bh.run_in_kernel(kc, "print(hog.is_alive())\nstop.set()").strip() == "True", "the kernel should compute during the whole drag"
        assert drawn >= FOLLOWED * MOVES, f"{drawn} live frames for {MOVES} mouse moves while the kernel computes"
        wait_idle(nb, generation, "the kernel's result after the drag")
        assert nb.console_errors() == []
