#!/usr/bin/env python
"""Make the README's picture of the editor: JupyterLab in headless Chromium, side by side.

Usage::

    python docs/make_editor_picture.py        # writes docs/images/editor.png

Runs the real-browser test harness (``tests/browser_harness.py``, which needs JupyterLab,
Playwright and Debian's ``/usr/bin/chromium``): the editor on the bundled panorama with
the command-line demo's handles (two lines rectified together, a cage holding the
armchair), input and result side by side, the window line selected.
"""

from __future__ import annotations

import sys
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO_ROOT))

from tests import browser_harness as bh  # noqa: E402

CELL = """\
import omniwidget as ow
from omniwidget.app.cli import DEMO_HANDLES

ed = ow.Editor(ow.sample_path(), DEMO_HANDLES, height=300)
ed.stage = "side"
ed.selected = 0
ed"""


def main() -> int:
    """Start JupyterLab and Chromium, show the editor, write the screenshot; the exit status."""
    out = REPO_ROOT / "docs" / "images" / "editor.png"
    with bh.JupyterServer(name="editor-picture") as server, bh.launch_browser() as browser:
        bh.write_notebook(server.root / "picture.ipynb", [CELL])
        with bh.NotebookPage(browser, server, "picture.ipynb") as nb:
            nb.page.set_viewport_size({"width": 1500, "height": 900})
            nb.run_all()
            editor = nb.wait_for_output(".ow-editor").first
            bh.wait_until(lambda: editor.get_attribute("data-generation") not in (None, "0"), timeout=60, description="the result")
            nb.page.mouse.move(*_centre(nb.output('canvas[data-pane="result"]').bounding_box()))
            nb.page.wait_for_timeout(300)
            editor.screenshot(path=str(out))
    print(f"wrote {out}")
    return 0


def _centre(box: dict) -> tuple[float, float]:
    return box["x"] + box["width"] * 0.7, box["y"] + box["height"] * 0.3


if __name__ == "__main__":
    raise SystemExit(main())
