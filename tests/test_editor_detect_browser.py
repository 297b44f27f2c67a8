"""Suggest lines and Level in a real browser: JupyterLab, Debian's Chromium, a person's mouse (Playwright).

The editor opens a generated room taken with a tilted camera (known pitch and roll, written
to a file). Suggest lines shows the suggestions dashed on the input; a click on one accepts
it (one line handle more in the kernel), Accept all adds the rest, Level sets the document's
``options.up`` (the still background kept) and the result changes, Undo takes the level back: the kernel's document is checked
after each step.
"""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from omniwidget.evaluate.scenes import synthetic_room
from omniwidget.io.images import write_image
from omniwidget.sphere import coords
from tests import browser_harness as bh
from tests.test_editor_browser import Pane, editor_attr, wait_idle

pytestmark = pytest.mark.browser

NAME = "editor_detect.ipynb"
PITCH, ROLL = 6.0, -4.0


def kernel_json(client, expression: str):
    return json.loads(bh.run_in_kernel(client, f"print(json.dumps({expression}))"))


def pane_pixels(nb, name: str) -> np.ndarray:
    canvas = nb.output(f'canvas.ow-canvas[data-pane="{name}"]')
    return cv2.imdecode(np.frombuffer(canvas.screenshot(), np.uint8), cv2.IMREAD_COLOR)


def _clear_spot(pane: Pane, suggestions: list[dict]) -> tuple[dict, tuple[float, float]]:
    """A suggestion and a point on it (screen pixels) at least 15 px from every other suggestion and the panorama's borders."""
    arcs = {s["key"]: np.array([pane.at(q) for q in coords.geodesic(s["start"], s["end"], np.linspace(0, 1, 60))]) for s in suggestions}
    for s in suggestions:
        for t in (0.5, 0.35, 0.65):
            spot = np.array(pane.at(coords.geodesic(s["start"], s["end"], [t])[0]))
            inside = pane.x0 + 15 < spot[0] < pane.x0 + pane.w - 15 and pane.y0 + 15 < spot[1] < pane.y0 + pane.h - 15
            others = min((np.hypot(*(a - spot).T).min() for k, a in arcs.items() if k != s["key"]), default=np.inf)
            if inside and others > 15:
                return s, (float(spot[0]), float(spot[1]))
    raise AssertionError("no suggestion stands clear of the others to click on")


def test_suggest_accept_one_accept_all_level_undo(jupyter_server, browser):
    if jupyter_server.frontend.key != "lab":
        pytest.skip("one front end is enough for the suggestions and Level: JupyterLab")
    image = jupyter_server.root / "tilted_room.png"
    write_image(image, synthetic_room(1024, pitch=PITCH, roll=ROLL).image)
    bh.write_notebook(
        jupyter_server.root / NAME,
        [
            f"import json\nimport omniwidget as ow\n\ned = ow.Editor({str(image)!r}, height=400, autosave=False, quality=False, preview_width=512)\ned"
        ],
    )
    with bh.NotebookPage(browser, jupyter_server, NAME) as nb:
        nb.run_all()
        nb.wait_for_output(".ow-editor")
        generation = wait_idle(nb, 0, "the first result on screen")
        client = nb.kernel_client()
        assert kernel_json(client, "ed.handles['handles']") == []

        # 1. Suggest lines: the suggestions come from the background job and are drawn dashed on the input
        pane = Pane(nb, "input")
        plain = pane.pixels()
        nb.output('[data-action="suggest"]').click()
        count = bh.wait_until(
            lambda: int(editor_attr(nb, "data-suggestions") or 0) or None,
            timeout=60,
            description="the suggestions shown",
            diagnostics=nb.diagnostics,
        )
        suggestions = kernel_json(client, "ed.suggestions")
        assert count == len(suggestions) >= 10
        assert kernel_json(client, "ed.status['suggest']['state']") == "done"
        assert kernel_json(client, "ed.handles['handles']") == []  # suggestions are no handles
        dashed = pane.pixels()
        changed = np.abs(dashed.astype(int) - plain.astype(int)).max(axis=2) > 40
        assert changed.mean() > 0.005, f"only {changed.mean():.2%} of the input pane changed when the suggestions were drawn"
        nb.screenshot("editor_suggestions")

        # 2. a click on one accepts it: one line handle, where the suggestion was
        chosen, spot = _clear_spot(pane, suggestions)
        nb.page.mouse.click(*spot)
        handles = bh.wait_until(
            lambda: (lambda hs: hs if len(hs) == 1 else None)(kernel_json(client, "ed.handles['handles']")),
            timeout=20,
            description="the accepted suggestion in the kernel",
            diagnostics=nb.diagnostics,
        )
        assert handles[0]["kind"] == "line" and handles[0]["start"] == chosen["start"] and handles[0]["end"] == chosen["end"]
        bh.wait_until(lambda: int(editor_attr(nb, "data-suggestions")) == count - 1, timeout=20, description="one suggestion fewer")
        generation = wait_idle(nb, generation, "the result with the accepted line")

        # 3. Accept all: every other suggestion, in one edit
        undo_before = kernel_json(client, "ed.history['undo']")
        nb.output('[data-action="accept-all"]').click()
        bh.wait_until(
            lambda: len(kernel_json(client, "ed.handles['handles']")) == count,
            timeout=20,
            description=f"all {count} suggestions as handles",
            diagnostics=nb.diagnostics,
        )
        assert kernel_json(client, "ed.history['undo']") == undo_before + 1
        bh.wait_until(lambda: editor_attr(nb, "data-suggestions") == "0", timeout=20, description="no suggestion left")
        generation = wait_idle(nb, generation, "the result with every suggestion")

        # 4. Level: options.up set, the still background kept, the result changes
        nb.output('[data-stage="side"]').click()
        nb.output('[data-action="handles"]').click()  # the image itself
        result = Pane(nb, "result")
        before_level = kernel_json(client, "ed.handles")
        result_before = result.pixels()
        nb.output('[data-action="level"]').click()
        levelled = bh.wait_until(
            lambda: (lambda d: d if d["options"].get("up") else None)(kernel_json(client, "ed.handles")),
            timeout=60,
            description="options.up in the kernel's document",
            diagnostics=nb.diagnostics,
        )
        assert len(levelled["handles"]) == count and levelled["options"]["anchor"] == before_level["options"]["anchor"]
        assert kernel_json(client, "ed.status['level']['state']") == "done"
        generation = wait_idle(nb, generation, "the levelled result")
        result_after = result.pixels()
        moved = np.abs(result_after.astype(int) - result_before.astype(int)).max(axis=2) > 40
        assert moved.mean() > 0.02, f"only {moved.mean():.2%} of the result changed when levelled"
        nb.screenshot("editor_levelled")

        # 5. Undo: the document before Level
        nb.output('[data-action="undo"]').click()
        bh.wait_until(
            lambda: kernel_json(client, "ed.handles") == before_level,
            timeout=20,
            description="the document before Level",
            diagnostics=nb.diagnostics,
        )
        wait_idle(nb, generation, "the result after undo")
        assert nb.console_errors() == [], "\n".join(nb.console_errors())
