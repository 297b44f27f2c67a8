"""End-to-end check of the real-browser harness with a tiny inline anywidget.

Runs JupyterLab + headless Chromium; skipped when they are unavailable unless
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
