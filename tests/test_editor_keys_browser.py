"""Keys as in JupyterLab, in a real browser: Debian's Chromium through Playwright.

With the keyboard in the editor (a click on its canvas), the notebook's own keys that a
person expects anywhere reach it: Ctrl+S saves the notebook, Ctrl+Enter and Shift+Enter run
the cell. The editor's keys still work (a stage by its letter, named in the status bar;
Ctrl+Z undoes in the editor) and none of them, nor any other key typed there, works the
notebook's command mode ('d d' deletes no cell, 'm' makes no markdown cell, 'z' undoes no
cell operation). Esc with nothing to cancel, or a click on the cell's prompt, gives the
keyboard back to the notebook: the cell has the focus, the notebook is in command mode and
its keys work again.

Which commands the keys ran is read from the application's command registry
(``commandExecuted``), the same in JupyterLab and Notebook 7.
"""

from __future__ import annotations

import json

import pytest

from tests import browser_harness as bh

pytestmark = pytest.mark.browser

NAME = "editor_keys.ipynb"
NOTEBOOK = [
    "import json\nimport omniwidget as ow\n\ned = ow.Editor(ow.sample_path(), height=440)\ned",
    "x = 1",
]
MARKER = "x = 2  # saved with Ctrl+S from the editor"

# Every command the application runs from now on, by id (keys, menus and code alike).
_JS_RECORD_COMMANDS = """() => {
  window.__owCommands = [];
  window.jupyterapp.commands.commandExecuted.connect((_, args) => window.__owCommands.push(args.id));
}"""

_JS_FOCUS = """(panelId) => {
  const active = document.activeElement;
  const notebook = document.getElementById(panelId).querySelector('.jp-Notebook');
  return {
    in_editor: Boolean(active && active.closest('.ow-editor')),
    in_cell: Boolean(active && active.closest('.jp-Cell') && notebook.contains(active)),
    active: active ? active.tagName + '.' + String(active.className) : null,
    command_mode: notebook.classList.contains('jp-mod-commandMode'),
  };
}"""

# Cells of the notebook as the browser holds them: type and source.
_JS_CELLS = """(panelId) => {
  const panel = Array.from(window.jupyterapp.shell.widgets('main')).find(w => w.id === panelId);
  const cells = panel.content.model.cells;
  const out = [];
  for (let i = 0; i < cells.length; i++) out.push([cells.get(i).type, cells.get(i).sharedModel.getSource()]);
  return {cells: out, active: panel.content.activeCellIndex};
}"""

_JS_SET_SOURCE = """([panelId, index, source]) => {
  const panel = Array.from(window.jupyterapp.shell.widgets('main')).find(w => w.id === panelId);
  panel.content.model.cells.get(index).sharedModel.setSource(source);
}"""


def kernel_json(client, expression: str):
    return json.loads(bh.run_in_kernel(client, f"print(json.dumps({expression}))"))


def commands(nb) -> list[str]:
    return nb.page.evaluate("() => window.__owCommands.slice()")


def focus(nb) -> dict:
    return nb.page.evaluate(_JS_FOCUS, nb.panel_id)


def cells(nb) -> dict:
    return nb.page.evaluate(_JS_CELLS, nb.panel_id)


def editor(nb):
    return nb.output(".ow-editor").first


def status_text(nb) -> str:
    return nb.output(".ow-message").first.inner_text()


def wait_for_editor(nb) -> None:
    """Wait until an editor shows its first result (also after its cell ran again)."""
    nb.wait_for_output(".ow-editor")
    bh.wait_until(
        lambda: int(editor(nb).get_attribute("data-generation") or 0) > 0 and editor(nb).get_attribute("data-busy") == "false",
        timeout=60,
        description="the editor's first result on screen",
        diagnostics=nb.diagnostics,
    )


def click_canvas(nb, fx: float = 0.5, fy: float = 0.5) -> None:
    """A click on the input canvas (fx, fy: where, as fractions of its size): the editor has the keyboard."""
    canvas = nb.output('canvas.ow-canvas[data-pane="input"]').first
    canvas.scroll_into_view_if_needed()
    box = canvas.bounding_box()
    nb.page.mouse.click(box["x"] + fx * box["width"], box["y"] + fy * box["height"])
    assert focus(nb)["in_editor"], focus(nb)


# Keys released since the last press_all (counted on the window, before any handler can stop them), and what the
# application's command registry still has to do with keys: a chord's first keys (its timer), a modifier's timer,
# or a key binding on its way to run (JupyterLab holds each until its key is released; counted by wrapping the
# registry's _executeKeyBinding). Read after a macrotask, so that a binding released by the last keyup has started.
_JS_RECORD_KEYS = """() => {
  const c = window.jupyterapp.commands;
  if (typeof c._executeKeyBinding !== 'function' || !Array.isArray(c._keystrokes) || typeof c._timerID !== 'number'
      || typeof c._timerModifierID !== 'number')
    throw new Error('the command registry keeps its pending keys elsewhere: update _JS_RECORD_KEYS');
  window.__owKeyups = 0;
  window.__owRunning = 0;
  window.addEventListener('keyup', () => { window.__owKeyups += 1; }, true);
  const execute = c._executeKeyBinding.bind(c);
  c._executeKeyBinding = async (binding) => {
    window.__owRunning += 1;
    try { return await execute(binding); } finally { window.__owRunning -= 1; }
  };
}"""
_JS_KEYS_SETTLED = """async () => {
  await new Promise(resolve => setTimeout(resolve, 0));
  const c = window.jupyterapp.commands;
  const pending = {keystrokes: c._keystrokes.length, chord: c._timerID !== 0, modifier: c._timerModifierID !== 0, running: window.__owRunning};
  return {keyups: window.__owKeyups, ...pending, settled: !pending.keystrokes && !pending.chord && !pending.modifier && !pending.running};
}"""


def press_all(nb, keys) -> None:
    """Press ``keys`` one after the other, then wait until each was released and the command registry holds none of
    them (no chord pending, no binding held): whatever they were going to run has run. An event, not a sleep."""
    nb.page.evaluate("() => { window.__owKeyups = 0; }")
    for key in keys:
        nb.page.keyboard.press(key)
    seen: list[dict] = []

    def settled() -> bool:
        seen.append(nb.page.evaluate(_JS_KEYS_SETTLED))
        return seen[-1]["keyups"] >= len(keys) and seen[-1]["settled"]

    bh.wait_until(
        settled,
        timeout=20,
        description=f"the keys {' '.join(keys)} released and no key binding pending",
        diagnostics=lambda: f"last seen {seen[-1] if seen else None}\n{nb.diagnostics()}",
    )


def test_keys_as_in_jupyterlab(jupyter_server, browser):
    path = jupyter_server.root / NAME
    bh.write_notebook(path, NOTEBOOK)
    with bh.NotebookPage(browser, jupyter_server, NAME) as nb:
        nb.run_all()
        wait_for_editor(nb)
        page = nb.page
        client = nb.kernel_client()
        page.evaluate(_JS_RECORD_COMMANDS)
        page.evaluate(_JS_RECORD_KEYS)
        before = cells(nb)["cells"]
        assert [t for t, _ in before] == ["code", "code"]

        # 1. a stage by its letter, named in the status bar; 'd d' is the draw stage, not "delete cell"
        click_canvas(nb)
        assert kernel_json(client, "ed.stage") == "draw"
        page.keyboard.press("b")
        bh.wait_until(lambda: kernel_json(client, "ed.stage") == "side", timeout=20, description="the side-by-side stage after 'b'")
        assert "stage Side by side (B)" in status_text(nb)
        page.keyboard.press("d")
        page.keyboard.press("d")
        bh.wait_until(lambda: kernel_json(client, "ed.stage") == "draw", timeout=20, description="the draw stage after 'd d'")
        assert "stage Draw (D)" in status_text(nb)
        # ... and the notebook's other command-mode letters do nothing either
        press_all(nb, ("m", "x", "z", "y", "j", "a"))
        assert cells(nb)["cells"] == before, "a key typed in the editor changed the notebook"
        assert commands(nb) == [], f"keys typed in the editor ran JupyterLab commands: {commands(nb)}"
        assert focus(nb)["in_editor"]
        # the same with a toolbar button focused (it is the ":focus" of the command-mode bindings' selector)
        nb.output('[data-stage="side"]').click()
        bh.wait_until(lambda: kernel_json(client, "ed.stage") == "side", timeout=20, description="the side-by-side stage by its button")
        assert focus(nb)["in_editor"]
        press_all(nb, ("d", "d", "m", "x", "z", "j", "a"))
        bh.wait_until(lambda: kernel_json(client, "ed.stage") == "draw", timeout=20, description="the draw stage after 'd d' on a button")
        assert cells(nb)["cells"] == before, "a key typed on the editor's toolbar changed the notebook"
        assert commands(nb) == [], f"keys typed on the editor's toolbar ran JupyterLab commands: {commands(nb)}"
        # 'a' (rectify all lines) and 'y' did nothing to the (empty) handles either
        bh.wait_until(lambda: editor(nb).get_attribute("data-pending") in (None, "0"), timeout=20, description="no command pending")

        # 2. Ctrl+Z undoes in the editor: a point placed with the Point tool (P, named), then undone
        page.keyboard.press("p")
        assert "tool Point (P)" in status_text(nb)
        click_canvas(nb, 0.3, 0.6)
        bh.wait_until(lambda: len(kernel_json(client, "ed.handles['handles']")) == 1, timeout=20, description="the point in the kernel")
        page.keyboard.press("Control+z")
        bh.wait_until(lambda: kernel_json(client, "ed.handles['handles']") == [], timeout=20, description="Ctrl+Z to undo the point")
        assert commands(nb) == [], f"Ctrl+Z in the editor ran JupyterLab commands: {commands(nb)}"

        # 3. the help lists every key, those passed to JupyterLab too; Esc closes it and keeps the keyboard
        page.keyboard.press("?")
        help_box = nb.output(".ow-help").first
        assert help_box.is_visible()
        text = help_box.inner_text()
        keys = ("V P L C", "D T B", "Ctrl+Z", "Ctrl+Y", "Delete", "Enter", "Esc", "Space", "F", "H", "A / S / R", "?")
        for key in (*keys, "Ctrl+S", "Shift+Enter", "Ctrl+Enter"):
            assert key in text, f"{key!r} missing from the help"
        page.keyboard.press("Escape")
        assert not help_box.is_visible()
        assert focus(nb)["in_editor"], "Esc closing the help gave the keyboard away"

        # 4. Esc drops a half-drawn cage and keeps the keyboard; the next Esc gives it to the notebook
        page.keyboard.press("c")
        click_canvas(nb, 0.3, 0.3)
        click_canvas(nb, 0.4, 0.3)
        page.keyboard.press("Escape")
        assert focus(nb)["in_editor"], "Esc dropping a half-drawn cage gave the keyboard away"
        page.keyboard.press("Escape")
        state = focus(nb)
        assert not state["in_editor"] and state["in_cell"] and state["command_mode"], state
        assert cells(nb)["active"] == 0
        page.keyboard.press("j")  # the notebook's keys work again: select the next cell
        bh.wait_until(lambda: cells(nb)["active"] == 1, timeout=10, description="'j' to select the next cell after Esc")
        assert commands(nb) == ["notebook:move-cursor-down"], commands(nb)
        page.keyboard.press("k")
        bh.wait_until(lambda: cells(nb)["active"] == 0, timeout=10, description="'k' to select the editor's cell again")
        assert kernel_json(client, "ed.handles['handles']") == [], "the half-drawn cage reached the kernel"

        # 5. a click on the cell's prompt gives the keyboard to the notebook too
        click_canvas(nb)
        prompt = page.locator(f'[id="{nb.panel_id}"] .jp-Cell').first.locator(".jp-InputPrompt").first
        prompt.click()
        state = focus(nb)
        assert not state["in_editor"] and state["command_mode"], state

        # 6. Ctrl+S saves the notebook from the editor
        click_canvas(nb)
        page.evaluate(_JS_SET_SOURCE, [nb.panel_id, 1, MARKER])
        assert MARKER not in path.read_text()
        assert focus(nb)["in_editor"]
        page.keyboard.press("Control+s")
        bh.wait_until(lambda: MARKER in path.read_text(), timeout=20, description="Ctrl+S to save the notebook", diagnostics=nb.diagnostics)
        assert "docmanager:save" in commands(nb), commands(nb)
        saved = json.loads(path.read_text())
        assert saved["cells"][0]["execution_count"] is not None
        assert kernel_json(client, "ed.stage") == "draw", "Ctrl+S reached the editor's S (rectify the selected line)"

        # 7. Ctrl+Enter runs the editor's cell, Shift+Enter runs it and selects the next
        count = nb.state()["cells"][0]["execution_count"]
        page.keyboard.press("Control+Enter")
        bh.wait_until(
            lambda: (nb.state()["cells"][0]["execution_count"] or 0) > count, timeout=60, description="Ctrl+Enter to run the cell"
        )
        assert "notebook:run-cell" in commands(nb), commands(nb)
        assert cells(nb)["active"] == 0
        bh.wait_until(lambda: nb.state()["kernel"]["status"] == "idle", timeout=60, description="the kernel idle again")
        wait_for_editor(nb)
        count = nb.state()["cells"][0]["execution_count"]
        click_canvas(nb)
        page.keyboard.press("Shift+Enter")
        bh.wait_until(
            lambda: (nb.state()["cells"][0]["execution_count"] or 0) > count, timeout=60, description="Shift+Enter to run the cell"
        )
        assert {"runmenu:run", "notebook:run-cell-and-select-next"} & set(commands(nb)), commands(nb)
        bh.wait_until(lambda: cells(nb)["active"] == 1, timeout=10, description="Shift+Enter to select the next cell")
        bh.wait_until(lambda: nb.state()["kernel"]["status"] == "idle", timeout=60, description="the kernel idle again")
        wait_for_editor(nb)

        assert [t for t, _ in cells(nb)["cells"]] == ["code", "code"]
        nb.screenshot("editor_keys")
        assert nb.console_errors() == []
