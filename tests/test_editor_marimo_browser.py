"""The editor in marimo, in a real browser: ``marimo run notebooks/marimo_editor.py``, Debian's Chromium, the mouse (Playwright).

marimo runs anywidget widgets in its own front end: no Jupyter comm manager (the model's
changes, the custom messages and their binary buffers go through marimo's websocket), no
widget state saved in the notebook, and the widget drawn inside a shadow root, where a
listener on the window is told the host element as an event's target. The story: the
editor opens on the bundled panorama; the help opens and stays open when clicked inside,
and a click on the panorama closes it and does nothing else (no point drawn); a line drawn
with the mouse over the bent top edge of the window wall; "Rectify all lines" changes the
result about the line; Save writes the handles the kernel holds (the line where it was
drawn, and nothing else); Save image writes the full-size result into the kernel's working
folder, the rectified panorama of those handles, pixel for pixel, and offers the same file
as a download; a control point dragged on the result is followed live (the kernel's basis
comes as a custom message with a binary buffer).

``marimo run`` takes no code from outside, so the kernel's side is read from the files
its buttons write.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import omniwidget as ow
from omniwidget.raster import pipeline
from omniwidget.sphere import coords
from tests import browser_harness as bh
from tests.test_editor_browser import WINDOW_TOP, Pane, drag, wait_idle

pytestmark = pytest.mark.browser

NOTEBOOK = Path(__file__).resolve().parents[1] / "notebooks" / "marimo_editor.py"


@pytest.fixture(scope="module")
def marimo_server():
    bh.require_marimo()
    with bh.MarimoServer(NOTEBOOK, name="editor") as server:
        yield server


def shown_handles(nb) -> list[dict]:
    """The handles the editor draws (its root's ``data-handles``, the browser's copy of the document)."""
    return json.loads(nb.output(".ow-editor").first.get_attribute("data-handles") or "{}").get("handles", [])


def test_draw_rectify_and_save_image_in_marimo(marimo_server, browser):
    from playwright.sync_api import expect

    root_dir = marimo_server.root
    with bh.MarimoPage(browser, marimo_server) as nb:
        page = nb.page
        nb.wait_for_output(".ow-editor", timeout=90)
        generation = wait_idle(nb, 0, "the first result on screen")
        assert page.evaluate("() => !!document.querySelector('marimo-anywidget')?.shadowRoot?.querySelector('.ow-editor')"), (
            "the editor is not in marimo's anywidget host's shadow root: the test no longer checks what it says"
        )
        root = nb.output(".ow-editor").first

        # 1. the help: a click inside it keeps it open; a click on the panorama closes it and draws nothing
        nb.output('[data-tool="point"]').click()
        nb.output('[data-action="help"]').click()
        assert root.get_attribute("data-help") == "true"
        help_box = nb.output(".ow-help").first.bounding_box()
        page.mouse.click(help_box["x"] + help_box["width"] / 2, help_box["y"] + help_box["height"] / 2)
        assert root.get_attribute("data-help") == "true", "a click inside the help closed it"
        pane = Pane(nb, "input")
        below = pane.at((100.0, -70.0))
        assert below[1] > help_box["y"] + help_box["height"] + 5, "the click meant outside the help is under it"
        page.mouse.click(*below)
        assert root.get_attribute("data-help") == "false", "a click on the panorama left the help open"
        page.wait_for_timeout(500)
        assert shown_handles(nb) == [], "the click that closed the help drew a point too"

        # 2. a line drawn with the mouse over the bent edge, as a person would
        nb.output('[data-tool="line"]').click()
        path = coords.geodesic(*WINDOW_TOP, np.linspace(0.0, 1.0, 12))
        drag(page, [pane.at(p) for p in path])
        generation = wait_idle(nb, generation, "the result after drawing the line")
        drawn = shown_handles(nb)
        assert [h["kind"] for h in drawn] == ["line"], drawn
        # the notebook's next cell reads `editor`: marimo runs it again with the kernel's handles
        with nb.explain("the cell reading the editor to count the line"):
            expect(nb.output("text=Handles drawn: 1 (line)")).to_be_visible(timeout=30_000)

        # 3. "Rectify all lines" changes the result about the line (handles hidden, to see the image itself)
        nb.output('[data-stage="transform"]').click()
        nb.output('[data-action="handles"]').click()
        result = Pane(nb, "result")
        rows, cols = result.box_around(path)
        before = result.pixels()
        nb.output('[data-action="rectify-all"]').click()
        generation = wait_idle(nb, generation, "the rectified result")
        after = result.pixels()
        changed = np.abs(after.astype(int) - before.astype(int)).max(axis=2) > 30
        share = changed[rows, cols].mean()
        print(f"\nmarimo: {share:.1%} of the result's pixels about the line changed by Rectify all lines")
        assert share > 0.02, f"only {share:.3%} of the pixels about the line changed"

        # 4. Save: the kernel holds the line where it was drawn, and nothing else
        nb.output('[data-action="save"]').click()
        saved = root_dir / "hotel_room.handles.json"
        bh.wait_until(saved.exists, timeout=30, description="the handles file written by Save", diagnostics=nb.diagnostics)
        handles = ow.load_handles(saved)
        assert handles.to_dict()["handles"] == shown_handles(nb)
        (line,) = handles.handles
        for end, expected in zip((line.start, line.end), WINDOW_TOP, strict=True):
            assert coords.angular_distance(end, expected) < 0.5, (end, expected)
        assert line.rectify, "Rectify all lines did not reach the kernel"

        # 5. Save image: the full-size rectified panorama of those handles in the working folder, and as a download
        target = root_dir / "hotel_room-rectified.jpg"
        with page.expect_download(timeout=90_000) as download_info:
            nb.output('[data-action="save-image"]').click()
        download = download_info.value
        assert download.suggested_filename == target.name
        assert target.exists(), sorted(p.name for p in root_dir.iterdir())
        assert Path(download.path()).read_bytes() == target.read_bytes()  # the download is the file written
        written = ow.read_image(target)
        assert written.shape == ow.sample_image().shape == (512, 1024, 3)
        expected = root_dir / "expected.jpg"
        ow.write_image(expected, pipeline.warp(ow.sample_image(), handles, warn=False).image)
        assert np.array_equal(written, ow.read_image(expected)), "the saved image is not the rectified panorama of the saved handles"
        def saying() -> str | None:
            text = nb.output(".ow-message").first.inner_text()
            return text if "saved to" in text else None

        said = bh.wait_until(
            saying,
            timeout=20,
            description="the status line saying where the image went",
            diagnostics=nb.diagnostics,
        )
        assert target.name in said and "1024 x 512" in said, said

        # 6. the live drag: the kernel's basis (a custom message with a binary buffer) comes at a hover, and the
        # result follows the mouse (measured: the basis in 0.02 s, 30 frames for 30 moves)
        nb.output('[data-action="handles"]').click()  # shown again: their control points can be grabbed
        start = result.at(WINDOW_TOP[0])
        page.mouse.move(*start)
        page.mouse.move(start[0] + 1.0, start[1])
        bh.wait_until(
            lambda: root.get_attribute("data-live-basis"), timeout=30, description="the live basis of the line", diagnostics=nb.diagnostics
        )
        assert root.get_attribute("data-live") == "ready", "WebGL2 is not available in this browser"
        frames = int(root.get_attribute("data-live-frames"))
        page.mouse.down()
        for step in range(1, 21):
            page.mouse.move(start[0], start[1] + step)
            page.wait_for_timeout(16)
        drawn = int(root.get_attribute("data-live-frames")) - frames
        page.mouse.up()
        print(f"marimo: {drawn} live frames for 20 mouse moves 16 ms apart")
        assert drawn >= 5, f"{drawn} live frames for 20 mouse moves: the result did not follow the mouse"
        wait_idle(nb, generation, "the kernel's result after the drag")

        nb.screenshot("editor")
        assert nb.console_errors() == [], "\n".join(nb.console_errors())
