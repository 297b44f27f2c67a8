"""The look-around view in a real browser (JupyterLab and Notebook 7, Debian's Chromium, WebGL2 in software).

Look around switches the result pane to the result seen through a perspective camera
(``static/look.js``); a drag turns it, the wheel zooms it. What it shows is checked against
``omniwidget view``'s camera: the canvas's pixels against ``ow.view`` of the same result image
(the JPEG the browser decoded, decoded in the kernel) at the canvas's size, for the look the
canvas's ``data-yaw``, ``data-pitch`` and ``data-fov`` give.
"""

from __future__ import annotations

import base64
import math

import cv2
import numpy as np
import pytest

from tests import browser_harness as bh
from tests.test_editor_browser import kernel_json, wait_idle

pytestmark = pytest.mark.browser

NOTEBOOK = [
    "import json\nimport cv2\nimport numpy as np\nimport omniwidget as ow\n\n"
    "doc = ow.Handles((ow.LineHandle((-4.0, 37.5), (68.0, 36.5), rectify=True),))\n"
    "ed = ow.Editor(ow.sample_path(), doc, height=360)\ned",
]
#: The canvas against ow.view of the same image: mean absolute difference in grey levels, at most (the brief's bound).
GREY = 2.0
#: The drag, CSS pixels: left and down (the camera turns right and up).
DRAG = (-120.0, 45.0)
#: One wheel step of the test, deltaY: the field of view times exp(0.0015 deltaY) (look.js).
WHEEL = -200.0

RESULT = 'canvas.ow-canvas[data-pane="result"]'


def look_of(canvas) -> tuple[float, float, float]:
    return tuple(float(canvas.get_attribute(f"data-{name}")) for name in ("yaw", "pitch", "fov"))  # type: ignore[return-value]


def canvas_pixels(nb) -> np.ndarray:
    """The result pane's canvas, RGB, its own pixels (not a screenshot)."""
    url = nb.page.evaluate(f"() => document.querySelector('{RESULT}').toDataURL('image/png')")
    png = base64.b64decode(url.split(",", 1)[1])
    return cv2.cvtColor(cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)


def kernel_view(nb, kc, look, shape) -> np.ndarray:
    """``ow.view`` of the result image the browser shows (the editor's JPEG, decoded in the kernel), at the canvas's size."""
    yaw, pitch, fov = look
    height, width = shape[:2]
    bh.run_in_kernel(
        kc,
        "shown = cv2.cvtColor(cv2.imdecode(np.frombuffer(ed.preview, np.uint8), cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)\n"
        f"np.save('still.npy', ow.view(shown, yaw={yaw!r}, pitch={pitch!r}, fov={fov!r}, width={width}, height={height}).image)",
    )
    return np.load(nb.server.root / "still.npy")


def test_look_around_turns_with_the_mouse_and_shows_what_omniwidget_view_draws(jupyter_server, browser):
    bh.write_notebook(jupyter_server.root / "look.ipynb", NOTEBOOK)
    with bh.NotebookPage(browser, jupyter_server, "look.ipynb") as nb:
        nb.run_all()
        root = nb.wait_for_output(".ow-editor")
        wait_idle(nb, 0, "the first result")
        kc = nb.kernel_client()
        flat = nb.output(RESULT)

        nb.output('[data-action="look"]').click()
        bh.wait_until(lambda: flat.get_attribute("data-yaw") is not None, timeout=20, description="the look-around view drawn")
        assert kernel_json(kc, "ed.stage") == "transform"  # the result pane shown, alone
        assert "ow-on" in nb.output('[data-action="look"]').get_attribute("class")
        assert look_of(flat) == (0.0, 0.0, 90.0)
        before = canvas_pixels(nb)
        height, width = before.shape[:2]
        box = flat.bounding_box()
        assert (round(box["width"]), round(box["height"])) == (width, height), "a device pixel per CSS pixel expected"
        first = kernel_view(nb, kc, (0.0, 0.0, 90.0), before.shape)
        difference = np.abs(before.astype(float) - first).mean()
        print(f"\nthe look-around view at yaw 0, pitch 0, 90° across ({width} x {height}) against ow.view: {difference:.3f} grey levels")
        assert difference < GREY

        # a drag turns it: by dx / f and dy / f radians, against the drag (the scene follows the pointer)
        centre = (box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
        nb.page.mouse.move(*centre)
        nb.page.mouse.down()
        nb.page.mouse.move(centre[0] + DRAG[0], centre[1] + DRAG[1], steps=12)
        nb.page.mouse.up()
        f = width / (2 * math.tan(math.radians(90.0) / 2))
        expected = (-math.degrees(DRAG[0] / f), math.degrees(DRAG[1] / f), 90.0)
        look = bh.wait_until(
            lambda: (got := look_of(flat)) and np.allclose(got, expected, atol=1e-3) and got,
            timeout=20,
            description=f"the view turned to {expected}",
            diagnostics=lambda: f"data-yaw/pitch/fov {look_of(flat)}",
        )
        turned = canvas_pixels(nb)
        changed = np.abs(turned.astype(float) - before).mean()
        shown = kernel_view(nb, kc, look, turned.shape)
        difference = np.abs(turned.astype(float) - shown).mean()
        print(f"dragged by {DRAG} px: yaw {look[0]:.3f}°, pitch {look[1]:.3f}° (expected {expected[0]:.3f}°, {expected[1]:.3f}°); "
              f"the pixels changed by {changed:.2f} grey levels, against ow.view {difference:.3f}")
        assert changed > 10 * GREY, f"the drag changed the view by {changed:.2f} grey levels on average"
        off = np.abs(turned.astype(float) - kernel_view(nb, kc, (look[0] + 0.5, look[1], look[2]), turned.shape)).mean()
        print(f"  (ow.view half a degree further: {off:.3f} grey levels; pixels differing {np.mean(turned != shown):.4f}, at most {np.abs(turned.astype(int) - shown).max()})")
        assert off > 2 * GREY, f"half a degree off differs by {off:.3f} grey levels only: the comparison cannot tell"
        assert difference < GREY, f"the turned view differs from ow.view by {difference:.3f} grey levels on average"

        # the wheel zooms it (up: narrower), within 20-120 degrees
        nb.page.mouse.move(*centre)
        nb.page.mouse.wheel(0, WHEEL)
        fov = 90.0 * math.exp(0.0015 * WHEEL)
        look = bh.wait_until(
            lambda: (got := look_of(flat)) and abs(got[2] - fov) < 1e-3 and got, timeout=20, description=f"the view zoomed to {fov:.2f}°"
        )
        zoomed = canvas_pixels(nb)
        difference = np.abs(zoomed.astype(float) - kernel_view(nb, kc, look, zoomed.shape)).mean()
        print(f"zoomed to {look[2]:.2f}° across: against ow.view {difference:.3f} grey levels")
        assert difference < GREY
        for _ in range(8):
            nb.page.mouse.wheel(0, 400)
        bh.wait_until(lambda: look_of(flat)[2] == 120.0, timeout=20, description="the field of view held at 120°")
        nb.screenshot("look-around")

        # and back to the flat panorama
        nb.output('[data-action="look"]').click()
        bh.wait_until(lambda: np.abs(canvas_pixels(nb).astype(float) - zoomed).mean() > 10 * GREY, timeout=20, description="the flat result again")
        assert "ow-on" not in (nb.output('[data-action="look"]').get_attribute("class") or "")
        assert root.get_attribute("data-busy") == "false"
        assert nb.console_errors() == []
