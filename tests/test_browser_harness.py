"""End-to-end check of the real-browser harness with a tiny inline anywidget.

Runs in JupyterLab and in Notebook 7 (the ``jupyter_server`` fixture), with headless Chromium; skipped when they are unavailable unless
``OMNIWIDGET_BROWSER_TESTS=1`` (then it fails instead).
"""

from __future__ import annotations

import textwrap

import pytest

from tests import browser_harness as bh

pytestmark = pytest.mark.browser

PROBE_WIDGET = textwrap.dedent(
    '''
    import anywidget
    import traitlets


    class Probe(anywidget.AnyWidget):
        """A button showing ``count``; each click increments it (front end -> kernel)."""

        _esm = """
        function render({ model, el }) {
          const button = document.createElement("button");
          button.className = "probe";
          const sync = () => { button.textContent = String(model.get("count")); };
          button.addEventListener("click", () => {
            model.set("count", model.get("count") + 1);
            model.save_changes();
          });
          model.on("change:count", sync);
          sync();
          el.appendChild(button);
          return () => model.off("change:count", sync);
        }
        export default { render };
        """
        count = traitlets.Int(0).tag(sync=True)


    w = Probe()
    w
    '''
).strip()


def kernel_count(client) -> int:
    return int(bh.run_in_kernel(client, "print(w.count)").strip())


def test_probe_widget_round_trip(jupyter_server, browser):
    from playwright.sync_api import expect

    bh.write_notebook(jupyter_server.root / "probe.ipynb", [PROBE_WIDGET])
    with bh.NotebookPage(browser, jupyter_server, "probe.ipynb") as nb:
        nb.run_all()
        button = nb.wait_for_output("button.probe")
        with nb.explain("the freshly rendered probe to show 0"):
            expect(button).to_have_text("0")

        # Browser -> kernel: three clicks reach the Python object in the notebook's kernel.
        for _ in range(3):
            button.click()
        with nb.explain("the probe to show 3 after three clicks"):
            expect(button).to_have_text("3")
        client = nb.kernel_client()
        bh.wait_until(lambda: kernel_count(client) == 3, timeout=20, description="w.count == 3 in the kernel", diagnostics=nb.diagnostics)

        # Kernel -> browser: a trait set from Python re-renders the button.
        bh.run_in_kernel(client, "w.count = 10")
        with nb.explain("the probe to show 10 after `w.count = 10` in the kernel"):
            expect(button).to_have_text("10")

        screenshot = nb.screenshot("browser_harness_probe")
        assert screenshot.stat().st_size > 0
        assert nb.console_errors() == [], "\n".join(nb.console_errors())


def test_harness_reports_cell_and_console_errors(jupyter_server, browser):
    """The harness must not hide failures: a raising cell and browser errors are reported."""
    bh.write_notebook(jupyter_server.root / "failing.ipynb", ["x = 1", "1 / 0"])
    with bh.NotebookPage(browser, jupyter_server, "failing.ipynb") as nb:
        with pytest.raises(bh.CellExecutionError, match="ZeroDivisionError"):
            nb.run_all()
        assert nb.console_errors() == []

        nb.page.evaluate(
            "() => { console.error('harness probe: console'); setTimeout(() => { throw new Error('harness probe: page'); }); }"
        )
        errors = bh.wait_until(
            lambda: nb.console_errors() if len(nb.console_errors()) == 2 else None, timeout=10, description="two collected errors"
        )
        assert "[console] harness probe: console" in errors[0]
        assert "[pageerror] Error: harness probe: page" in errors[1]

        client = nb.kernel_client()
        assert bh.run_in_kernel(client, "print(x + 1)") == "2\n"
        with pytest.raises(bh.KernelExecutionError, match="NameError"):
            bh.run_in_kernel(client, "undefined_name")


def test_each_front_end_opens_notebooks_at_its_own_url_and_keeps_its_own_artifacts(monkeypatch, tmp_path):
    """No browser: what differs between JupyterLab and Notebook 7 (the ``jupyter_server`` fixture runs both)."""
    monkeypatch.setenv("OMNIWIDGET_ARTIFACTS", str(tmp_path))
    lab, notebook = bh.JupyterServer(frontend="lab"), bh.JupyterServer(frontend="notebook")
    for server in (lab, notebook):
        server.url, server.token = "http://127.0.0.1:8888", "secret"
    assert lab.notebook_url("a b.ipynb") == "http://127.0.0.1:8888/lab/tree/a%20b.ipynb?reset=&token=secret"
    assert notebook.notebook_url("a b.ipynb") == "http://127.0.0.1:8888/notebooks/a%20b.ipynb?token=secret"
    assert lab.frontend.module == "jupyterlab" and "--LabApp.expose_app_in_browser=True" in lab.frontend.args
    assert notebook.frontend.module == "notebook" and "--JupyterNotebookApp.expose_app_in_browser=True" in notebook.frontend.args
    assert lab.artifact("editor_latency.json") == tmp_path / "editor_latency.json"  # the name bench/ reads
    assert notebook.artifact("editor_latency.json") == tmp_path / "editor_latency-notebook7.json"
    with pytest.raises(ValueError, match="unknown Jupyter front end 'classic'"):
        bh.JupyterServer(frontend="classic")


def test_notebook7s_own_error_is_allowed_only_there_and_only_from_its_own_code():
    class Page:
        def on(self, *_):
            pass

    text = "TypeError: Cannot read properties of undefined (reading 'schema')"
    stack = f"{text}\n    at http://127.0.0.1:1/static/notebook/notebook_core.c9a6d9df5de5df84.js?v=c9:501:207"
    own = bh.ConsoleError("pageerror", text, stack)
    widget = bh.ConsoleError("pageerror", text, f"{text}\n    at render (blob:http://127.0.0.1:1/0b6c2d4e:12:5)")
    notebook = bh.ConsoleCollector(Page(), bh.FRONTENDS["notebook"].allowed_console_errors)
    lab = bh.ConsoleCollector(Page(), bh.FRONTENDS["lab"].allowed_console_errors)
    assert notebook.is_allowed(own) and not notebook.is_allowed(widget)
    assert not lab.is_allowed(own)
