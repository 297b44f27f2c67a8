"""Straighten and Level in the editor, in a real browser: JupyterLab and Notebook 7.

On the bundled hotel room a person clicks Straighten: the handles it used appear in the
kernel's document (line handles, ``options.up`` set, the still background on) and the result
changes; Undo brings the empty document back. Then Suggest lines, Accept all, Level: the
still background stays on, and far from the handles the levelled result is the old one
turned by the levelling (measured in the kernel on the two documents, to 0.1 px).
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from tests import browser_harness as bh
from tests.test_editor_browser import Pane, editor_attr, wait_idle

pytestmark = pytest.mark.browser

NAME = "editor_straighten.ipynb"

# In the kernel: the largest distance (output pixels at 512 wide) between the levelled document's warp and the
# levelling after the document's warp before, over the output farther than 30° from every line (where the still background holds).
_FAR_FIELD = """
import numpy as np
from omniwidget.sphere import coords
def _far_moved(before, after, width=512):
    image = np.zeros((width // 2, width), np.uint8)
    turn = ow.Handles.from_dict(after).options.levelling()
    old = coords.lonlat_to_xyz(ow.warp(image, ow.Handles.from_dict(before), warn=False).inverse_map(np.float64))
    new = ow.warp(image, ow.Handles.from_dict(after), warn=False).inverse_map(np.float64)
    lon, lat = coords.grid_lonlat(width)
    back = turn.inverse(np.stack(np.broadcast_arrays(lon[None, :], lat[:, None]), axis=-1))  # where the old output was
    px = coords.lonlat_to_px(back, width)  # the old map read there, bilinearly on unit vectors
    x, y = px[..., 0], np.clip(px[..., 1], 0, width // 2 - 1.000001)
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    fx, fy = (x - x0)[..., None], (y - y0)[..., None]
    at = lambda j, i: old[j, i % width]
    expected = (1 - fy) * ((1 - fx) * at(y0, x0) + fx * at(y0, x0 + 1)) + fy * ((1 - fx) * at(y0 + 1, x0) + fx * at(y0 + 1, x0 + 1))
    lines = np.concatenate([coords.geodesic(h["start"], h["end"], np.linspace(0, 1, 16)) for h in after["handles"]])
    far = (coords.lonlat_to_xyz(back) @ coords.lonlat_to_xyz(lines).T).max(axis=-1) < np.cos(np.radians(30.0))
    far &= np.abs(back[..., 1]) < 75
    moved = coords.angular_distance(new[far], coords.xyz_to_lonlat(expected[far]))
    return int(far.sum()), float(moved.max() * width / 360.0) if far.any() else float("nan")
"""


def kernel_json(client, expression: str):
    return json.loads(bh.run_in_kernel(client, f"print(json.dumps({expression}))"))


def test_straighten_loads_the_handles_undo_takes_them_back_and_level_keeps_the_background(jupyter_server, browser):
    bh.write_notebook(jupyter_server.root / NAME, ["import json\nimport omniwidget as ow\n\ned = ow.Editor(ow.sample_path(), autosave=False)\ned"])
    with bh.NotebookPage(browser, jupyter_server, NAME) as nb:
        nb.run_all()
        nb.wait_for_output(".ow-editor")
        generation = wait_idle(nb, 0, "the first result on screen")
        client = nb.kernel_client()
        empty = kernel_json(client, "ed.handles")
        nb.output('[data-stage="side"]').click()
        nb.output('[data-action="handles"]').click()  # the image itself
        result = Pane(nb, "result")
        before = result.pixels()

        # 1. Straighten: the handles it used appear, one undoable edit, the result changes
        nb.output('[data-action="straighten"]').click()
        bh.wait_until(
            lambda: kernel_json(client, "ed.status.get('straighten', {}).get('state')") in ("done", "error") or None,
            timeout=120,
            description="Straighten done",
            diagnostics=nb.diagnostics,
        )
        job = kernel_json(client, "ed.status['straighten']")
        assert job["state"] == "done" and "lines straightened" in job["message"], job
        doc = kernel_json(client, "ed.handles")
        assert len(doc["handles"]) >= 5 and all(h["kind"] == "line" for h in doc["handles"])
        assert doc["options"]["up"] and doc["options"]["anchor"] == empty["options"]["anchor"]
        assert kernel_json(client, "ed.history['undo']") == 1
        generation = wait_idle(nb, generation, "the straightened result")
        changed = np.abs(result.pixels().astype(int) - before.astype(int)).max(axis=2) > 40
        assert changed.mean() > 0.005, f"only {changed.mean():.2%} of the result changed"
        nb.screenshot("editor_straightened")
        print(f"\n{jupyter_server.frontend.title}: {job['message']}")

        # 2. Undo: the document before Straighten
        nb.output('[data-action="undo"]').click()
        bh.wait_until(lambda: kernel_json(client, "ed.handles") == empty or None, timeout=20, description="the empty document back")
        generation = wait_idle(nb, generation, "the result of the empty document")

        # 3. Suggest lines, Accept all, Level: the mode kept, far from the handles the turn after the old result
        nb.output('[data-action="suggest"]').click()
        bh.wait_until(lambda: int(editor_attr(nb, "data-suggestions") or 0) or None, timeout=60, description="the suggestions shown")
        nb.output('[data-action="accept-all"]').click()
        bh.wait_until(lambda: editor_attr(nb, "data-suggestions") == "0", timeout=30, description="no suggestion left")
        generation = wait_idle(nb, generation, "the result with every suggestion")
        accepted = kernel_json(client, "ed.handles")
        bh.run_in_kernel(client, "_accepted = json.loads(json.dumps(ed.handles))")
        nb.output('[data-action="level"]').click()
        levelled = bh.wait_until(
            lambda: (lambda d: d if d["options"].get("up") else None)(kernel_json(client, "ed.handles")),
            timeout=60,
            description="the levelled document",
            diagnostics=nb.diagnostics,
        )
        assert levelled["options"]["anchor"] == accepted["options"]["anchor"] and len(levelled["handles"]) == len(accepted["handles"])
        bh.run_in_kernel(client, _FAR_FIELD)
        count, moved = kernel_json(client, "_far_moved(_accepted, ed.handles)")
        print(f"far from the handles ({count} pixels at 512 wide) the levelled result is the turn after the old one to {moved:.4f} px")
        assert count > 2000 and moved <= 0.1
