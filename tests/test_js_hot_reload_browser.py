"""anywidget's hot reload of the editor's front end, in a real browser (JupyterLab and Notebook 7).

``Editor._esm`` is the bundle's path, so with ``ANYWIDGET_HMR=1`` anywidget watches the file and,
each time ``npm run watch`` rebuilds it, sets the open widgets' ``_esm`` to the new text; their
front end imports the new module and renders every view again with it, cleaning up the old one.
Here the kernel sets ``_esm`` as that watcher does, to the bundle with one label changed: the
editor shown is the new build, there is one editor (the old view gone), and the handles and the
result shown are the kernel's, kept.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests import browser_harness as bh

pytestmark = pytest.mark.browser

BUNDLE = Path(__file__).resolve().parents[1] / "omniwidget" / "widget" / "static" / "editor.bundle.js"
POINT = {"kind": "point", "position": [30.0, 10.0], "target": [40.0, 12.0]}
NOTEBOOK = [
    f"import json\nimport omniwidget as ow\n\ned = ow.Editor(ow.sample_path(), height=440, autosave=False, handles={{'handles': [{POINT!r}]}})\ned",
]
LABEL = '["select", "Select", "V"'
RELOADED = '["select", "Select (reloaded)", "V"'


def _labels(nb: bh.NotebookPage) -> list[str]:
    return [t.strip() for t in nb.output('[data-tool="select"]').all_inner_texts()]


def _shown_generation(nb: bh.NotebookPage) -> int | None:
    """The generation of the result the (only) editor shows, None while it shows none."""
    roots = nb.output(".ow-editor")
    if roots.count() != 1:
        return None
    generation = int(roots.first.get_attribute("data-generation") or 0)
    return generation if generation > 0 and roots.first.get_attribute("data-busy") == "false" else None


def test_a_rebuilt_bundle_replaces_the_editor_shown_and_keeps_its_state(jupyter_server, browser):
    assert LABEL in BUNDLE.read_text(encoding="utf-8")  # the label this test changes is in the bundle
    bh.write_notebook(jupyter_server.root / "reload.ipynb", NOTEBOOK)
    with bh.NotebookPage(browser, jupyter_server, "reload.ipynb") as nb:
        nb.run_all()
        nb.wait_for_output(".ow-editor")
        before = bh.wait_until(lambda: _shown_generation(nb), timeout=60, description="the first result on screen", diagnostics=nb.diagnostics)
        assert _labels(nb) == ["Select"]
        client = nb.kernel_client()

        # what anywidget's file watcher does when the bundle changes on disk
        changed = bh.run_in_kernel(client, f"new = ed._esm.replace({LABEL!r}, {RELOADED!r}, 1)\nprint(new != ed._esm)\ned._esm = new")
        assert changed.strip() == "True"

        bh.wait_until(
            lambda: _labels(nb) == ["Select (reloaded)"] or None,
            timeout=30,
            description="the editor rendered again by the new module",
            diagnostics=nb.diagnostics,
        )
        assert nb.output(".ow-editor").count() == 1, "the old view is still on the page beside the new one"
        after = bh.wait_until(lambda: _shown_generation(nb), timeout=30, description="the result shown again", diagnostics=nb.diagnostics)
        assert after == before  # the kernel's result as it was: nothing recomputed, nothing lost
        handles = json.loads(bh.run_in_kernel(client, "print(json.dumps(ed.handles['handles']))"))
        assert [h["kind"] for h in handles] == ["point"] and handles[0]["position"] == POINT["position"]
        assert nb.console_errors() == [], "\n".join(nb.console_errors())
