"""The editor opens a video, in a real browser: JupyterLab, Debian's Chromium (Playwright).

``Editor(clip)`` on a tiny synthetic clip (tests/test_editor_video.py's): the frame slider is
shown; moving it to another frame shows that frame in the input pane (its pixels change, the
kernel's ``frame`` follows) and the handles stay; Save video shows its progress in the status
bar, then where it wrote the video, and the file is there with every frame; saved again
(slowed down in the kernel), Cancel stops it midway and nothing is written.
"""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from tests import browser_harness as bh
from tests import requires

pytestmark = pytest.mark.browser

av = requires.module("av")

from tests.test_editor_video import FRAMES, HANDLES, make_clip  # noqa: E402 - after the skip

NAME = "editor_video.ipynb"

# Every text the status bar shows from now on (Save video's progress comes and goes quickly).
_JS_RECORD_STATUS = """() => {
  const message = document.querySelector('.ow-editor .ow-message');
  window.__owMessages = [message.textContent];
  new MutationObserver(() => window.__owMessages.push(message.textContent)).observe(message, {childList: true, characterData: true, subtree: true});
}"""


def kernel_json(client, expression: str):
    return json.loads(bh.run_in_kernel(client, f"print(json.dumps({expression}))"))


def pane_pixels(nb, name: str) -> np.ndarray:
    canvas = nb.output(f'canvas.ow-canvas[data-pane="{name}"]')
    return cv2.imdecode(np.frombuffer(canvas.screenshot(), np.uint8), cv2.IMREAD_COLOR)


def test_the_slider_shows_another_frame_and_save_video_writes_the_video(jupyter_server, browser):
    if jupyter_server.frontend.key != "lab":
        pytest.skip("one front end is enough for the video: JupyterLab")
    clip = make_clip(jupyter_server.root / "clip.mp4")
    output = clip.with_name("clip-rectified.mp4")
    output.unlink(missing_ok=True)
    bh.write_notebook(
        jupyter_server.root / NAME,
        [f"import json\nimport omniwidget as ow\n\ned = ow.Editor({str(clip)!r}, handles={HANDLES!r}, height=360, autosave=False, quality=False)\ned"],
    )
    with bh.NotebookPage(browser, jupyter_server, NAME) as nb:
        nb.run_all()
        nb.wait_for_output(".ow-editor")
        root = nb.output(".ow-editor").first
        bh.wait_until(
            lambda: int(root.get_attribute("data-generation") or 0) > 0 and root.get_attribute("data-busy") == "false",
            timeout=60,
            description="the first result on screen",
            diagnostics=nb.diagnostics,
        )
        client = nb.kernel_client()
        slider = nb.output("input.ow-frame-slider")
        assert slider.is_visible() and slider.get_attribute("max") == str(FRAMES - 1)
        assert "frame 1 / 12" in nb.output(".ow-frame-label").text_content()

        # the slider to frame 6 (18° more turned): the input pane shows it, the handles stay
        nb.output('[data-action="handles"]').click()  # the image itself, without the handles drawn over it
        before = pane_pixels(nb, "input")
        handles = kernel_json(client, "ed.handles")
        generation = int(root.get_attribute("data-generation"))
        slider.fill("6")
        bh.wait_until(lambda: kernel_json(client, "ed.frame") == 6, timeout=30, description="the kernel's frame 6", diagnostics=nb.diagnostics)
        bh.wait_until(
            lambda: int(root.get_attribute("data-generation") or 0) > generation and root.get_attribute("data-busy") == "false",
            timeout=60,
            description="the preview of frame 6",
            diagnostics=nb.diagnostics,
        )
        assert root.get_attribute("data-frame") == "6"
        assert "frame 7 / 12" in nb.output(".ow-frame-label").text_content()

        def changed():
            after = pane_pixels(nb, "input")
            return after.shape == before.shape and (np.abs(after.astype(int) - before.astype(int)).max(axis=2) > 30).mean() > 0.05

        bh.wait_until(changed, timeout=20, description="the input pane showing frame 6", diagnostics=nb.diagnostics)
        assert kernel_json(client, "ed.handles") == handles and len(handles["handles"]) == 1
        assert kernel_json(client, "ed.history") == {"undo": 0, "redo": 0}  # a frame is no edit

        # Save video: its progress in the status bar, then where it went
        nb.page.evaluate(_JS_RECORD_STATUS)
        save = nb.output('[data-action="save-video"]')
        assert save.is_visible()
        save.click()
        bh.wait_until(lambda: root.get_attribute("data-video") == "done", timeout=120, description="the video saved", diagnostics=nb.diagnostics)
        messages = nb.page.evaluate("() => window.__owMessages")
        assert any(f"{FRAMES} / {FRAMES} frames" in m and "fps" in m for m in messages), messages
        assert str(output) in nb.output(".ow-message").text_content()
        assert not nb.output('[data-action="cancel-video"]').is_visible()
        nb.screenshot("editor_video_saved")
        with av.open(str(output)) as container:
            assert sum(1 for _ in container.decode(video=0)) == FRAMES

        # Save video again, each frame slowed to 0.4 s in the kernel, and Cancel it midway: nothing is written
        output.unlink()
        bh.run_in_kernel(
            client,
            "import time, omniwidget.app.video as _video\n"
            "_warp_frame = _video._Warper.__call__\n"
            "_video._Warper.__call__ = lambda self, frame: (time.sleep(0.4), _warp_frame(self, frame))[1]\n"
            "print('slowed')",
        )
        save.click()
        cancel = nb.output('[data-action="cancel-video"]')
        bh.wait_until(
            lambda: cancel.is_visible() and (kernel_json(client, "ed.status['video']").get("done") or 0) >= 2,
            timeout=60,
            description="Cancel offered while frames are saved",
            diagnostics=nb.diagnostics,
        )
        cancel.click()
        bh.wait_until(lambda: root.get_attribute("data-video") == "cancelled", timeout=60, description="the save cancelled", diagnostics=nb.diagnostics)
        job = kernel_json(client, "ed.status['video']")
        assert 2 <= job["done"] < FRAMES, job
        assert "cancelled" in nb.output(".ow-message").text_content()
        assert not cancel.is_visible()
        bh.run_in_kernel(client, "_video._Warper.__call__ = _warp_frame\nprint('restored')")
    assert not output.exists()
    assert [p.name for p in output.parent.iterdir() if p.name.startswith(f".{output.name}")] == []  # no temporary file left
