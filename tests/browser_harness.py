"""Real-browser test harness for anywidget widgets in JupyterLab, Jupyter Notebook 7 and marimo.

This is a plain helper module (not collected by pytest).  It drives a real
Jupyter server with either front end (:data:`FRONTENDS`: ``"lab"`` for JupyterLab,
``"notebook"`` for Jupyter Notebook 7) and a headless Debian Chromium through
Playwright, so a test can open a notebook, run it, poke the rendered widget, and
inspect the *same* kernel from Python::

    from tests import browser_harness as bh

    bh.require_browser("notebook")  # skip (or fail when OMNIWIDGET_BROWSER_TESTS=1)
    with bh.JupyterServer(name="demo", frontend="notebook") as server, bh.launch_browser() as browser:
        bh.write_notebook(server.root / "demo.ipynb", ["import anywidget", "w = MyWidget()\\nw"])
        with bh.NotebookPage(browser, server, "demo.ipynb") as nb:
            nb.run_all()  # raises CellExecutionError with the traceback if a cell fails
            nb.wait_for_output("button.my-widget").click()
            kc = nb.kernel_client()  # the notebook's own kernel
            bh.wait_until(lambda: bh.run_in_kernel(kc, "print(w.value)") == "1\\n", timeout=20, description="w.value == 1")
            bh.run_in_kernel(kc, "w.value = 5")
            with nb.explain("the button to show 5"):
                expect(nb.output("button.my-widget")).to_have_text("5")  # playwright.sync_api.expect
            nb.screenshot("demo")  # -> test-artifacts/demo-notebook7.png (test-artifacts/demo.png in JupyterLab)
            assert nb.console_errors() == []

In the test suite the session fixture ``jupyter_server`` (tests/conftest.py) is
parametrized over both front ends, so every real-browser test runs in JupyterLab
and in Notebook 7.

marimo, which runs anywidget widgets in a front end of its own, has :class:`MarimoServer`
(``marimo run`` of a notebook file, a subprocess on 127.0.0.1) and :class:`MarimoPage` (the app
in a browser tab, with the ``output``/``wait_for_output``/``diagnostics`` of :class:`NotebookPage`);
``tests/test_editor_marimo_browser.py`` uses them.

Design notes
------------
* Both front ends are JupyterLab applications (Notebook 7 is built from the same
  notebook, output-area and widget-manager packages; only its shell differs).  The
  server exposes the application in the browser (``--LabApp.expose_app_in_browser``
  or ``--JupyterNotebookApp.expose_app_in_browser``), so the page has
  ``window.jupyterapp``; cells are run with the very command the
  "Run > Run All Cells" menu item uses (``notebook:run-all-cells``), invoked
  through the application's command registry.  That avoids flaky menu/keyboard
  focus handling while exercising the same code path.  What differs between the
  front ends (the app, the notebook's URL, the flags) is in :class:`Frontend`.
* Everything that waits polls a condition with a timeout and, on failure,
  raises with what was waited for plus diagnostics (notebook/kernel state,
  console errors, tail of the server log).
* Playwright, nbformat and jupyter_client are imported lazily so this module can
  be imported (and tests skipped) on machines without them.
"""

from __future__ import annotations

import contextlib
import importlib.util
import json
import os
import re
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
import urllib.error
import urllib.parse
import urllib.request
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]

#: Chromium binary used for the tests (Debian package; never ``playwright install``).
CHROMIUM = os.environ.get("OMNIWIDGET_CHROMIUM", "/usr/bin/chromium")

#: Flags that keep Chromium headless, sandbox-free (we run as root) and off the network.
CHROMIUM_ARGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--no-first-run",
    "--disable-sync",
    "--disable-quic",
)

#: Setting ``OMNIWIDGET_BROWSER_TESTS=1`` turns a missing prerequisite into a failure (CI).
STRICT_ENV_VAR = "OMNIWIDGET_BROWSER_TESTS"

#: JupyterLab user settings written into the isolated settings dir of every server.
LAB_USER_SETTINGS: dict[str, dict[str, Any]] = {
    # "none" (the default) makes JupyterLab pop up "Would you like to get notified about
    # official Jupyter news?"; "false" = Never, so no toast and no request to the internet.
    "@jupyterlab/apputils-extension/notification": {"fetchNews": "false", "checkForUpdates": False},
    # Attach every cell to the DOM so widgets in off-screen cells render deterministically.
    "@jupyterlab/notebook-extension/tracker": {"windowingMode": "none"},
    # "Save Widget State Automatically" (off by default): saved notebooks keep widget state.
    "@jupyter-widgets/jupyterlab-manager/plugin": {"saveState": True},
}


@dataclass(frozen=True)
class Frontend:
    """What differs between the two Jupyter front ends the harness drives.

    Everything else (``window.jupyterapp``, the notebook panel, its session context,
    the ``notebook:run-all-cells`` and ``docmanager:save`` commands, the
    ``.jp-OutputArea-output`` nodes the widgets render into, the user settings) is
    the same in both, as both are built from JupyterLab's packages.
    """

    key: str
    """``"lab"`` or ``"notebook"`` (the ``frontend=`` argument of :class:`JupyterServer`)."""
    title: str
    """Human-readable name, for messages."""
    module: str
    """The Python package that is the server application (``python -m <module>``)."""
    app_name: str
    """``window.jupyterapp.name`` in its pages: checked when a notebook opens, so a test id can't lie."""
    notebook_route: str
    """URL path prefix under which a notebook opens (followed by its path)."""
    open_query: tuple[tuple[str, str], ...]
    """Query parameters added to the notebook's URL (JupyterLab: ``?reset``, a fresh workspace)."""
    args: tuple[str, ...]
    """Command-line arguments specific to this front end's server application."""
    artifact_suffix: str
    """Appended to the names of the artifacts a test writes, so both front ends keep theirs."""
    allowed_console_errors: tuple[tuple[str, str], ...] = ()
    """Like :data:`ALLOWED_CONSOLE_ERRORS`, for this front end only, and matched (``re.search``) against
    the whole entry, ``str(ConsoleError)``: its kind, text and location (a page error's stack), so an
    entry can be pinned to the front end's own code."""


#: Arguments for the JupyterLab server extension, which every Jupyter server here loads
#: (Notebook 7's too: it also serves /lab): no news feed, no update check, no PyPI
#: extension manager, so no request to the network.
_LAB_OFFLINE_ARGS = (
    "--LabApp.news_url=None",
    "--LabApp.check_for_updates_class=jupyterlab.NeverCheckForUpdate",
    "--LabApp.extension_manager=readonly",
)

#: The front ends, by key.  Both run on the same jupyter_server, kernels and widget manager.
FRONTENDS: dict[str, Frontend] = {
    "lab": Frontend(
        key="lab",
        title="JupyterLab",
        module="jupyterlab",
        app_name="JupyterLab",
        notebook_route="/lab/tree/",
        open_query=(("reset", ""),),
        # window.jupyterapp, used to drive commands and read notebook/kernel state.
        args=(*_LAB_OFFLINE_ARGS, "--LabApp.expose_app_in_browser=True"),
        artifact_suffix="",  # the historical names (bench/ reads test-artifacts/editor_latency.json)
    ),
    "notebook": Frontend(
        key="notebook",
        title="Jupyter Notebook 7",
        module="notebook",
        app_name="Jupyter Notebook",
        notebook_route="/notebooks/",
        open_query=(),  # Notebook 7 keeps no workspace: every page opens fresh
        args=(*_LAB_OFFLINE_ARGS, "--JupyterNotebookApp.expose_app_in_browser=True"),
        artifact_suffix="-notebook7",
        allowed_console_errors=(
            (
                # thrown by Notebook 7's own bundle (the top stack frame), on any notebook, "1 + 1" too
                r"^\[pageerror\] TypeError: Cannot read properties of undefined \(reading 'schema'\) "
                r"\(TypeError: [^\n]*\n\s*at [^\n]*/static/notebook/notebook_core\.[0-9a-f]+\.js",
                "Notebook 7's keyboard-shortcuts settings handler reads registry.plugins['@jupyterlab/shortcuts-extension:shortcuts']"
                " before that plugin's settings are loaded, when another plugin's settings load first"
                " (jupyter/notebook#7862, a race in Notebook 7 itself)",
            ),
        ),
    ),
}


def get_frontend(key: str) -> Frontend:
    """The :class:`Frontend` called ``key`` (``"lab"`` or ``"notebook"``)."""
    try:
        return FRONTENDS[key]
    except KeyError:
        raise ValueError(f"unknown Jupyter front end {key!r}; expected one of {sorted(FRONTENDS)}") from None


#: Console errors that the front end itself emits while running offline/headless and that
#: have nothing to do with widgets.  Each entry is ``(regex, why it is harmless)``; the
#: regex is matched (``re.search``) against the message text.  Keep this list minimal.
#: Those of one front end only are in its :attr:`Frontend.allowed_console_errors`.
ALLOWED_CONSOLE_ERRORS: tuple[tuple[str, str], ...] = ()


# --------------------------------------------------------------------------- prerequisites


def one_front_end(server: Any, what: str) -> None:
    """Skip in Notebook 7 a check that JupyterLab makes as well: the front ends share the widget's code (anywidget), and
    both run the checks where they differ (drawing and undo, the keys, a kernel's restart, the reach ring).
    CI's 30 minutes hold only so."""
    if server.frontend.key != "lab":
        pytest.skip(f"one front end is enough for {what}: JupyterLab")


def require_browser(*frontends: str) -> None:
    """Skip the calling test unless a real-browser run is possible.

    Needs the Chromium binary at :data:`CHROMIUM` and the ``playwright``,
    ``jupyter_client`` and ``nbformat`` packages, plus the server application of each
    front end named in ``frontends`` (``jupyterlab`` for ``"lab"``, the default;
    ``notebook`` for ``"notebook"``).  When the
    environment variable ``OMNIWIDGET_BROWSER_TESTS=1`` is set (CI), a missing
    prerequisite calls :func:`pytest.fail` instead of :func:`pytest.skip`, so
    browser tests can never silently disappear.
    """
    missing = []
    if not (os.path.isfile(CHROMIUM) and os.access(CHROMIUM, os.X_OK)):
        missing.append(f"chromium executable {CHROMIUM}")
    apps = tuple(dict.fromkeys(get_frontend(key).module for key in frontends or ("lab",)))
    for module in ("playwright", *apps, "jupyter_client", "nbformat"):
        if importlib.util.find_spec(module) is None:
            missing.append(f"python package {module!r}")
    _skip_or_fail(missing)


def require_marimo() -> None:
    """Like :func:`require_browser`, for a real-browser test in marimo: Chromium, ``playwright`` and ``marimo``."""
    missing = []
    if not (os.path.isfile(CHROMIUM) and os.access(CHROMIUM, os.X_OK)):
        missing.append(f"chromium executable {CHROMIUM}")
    missing += [f"python package {module!r}" for module in ("playwright", "marimo") if importlib.util.find_spec(module) is None]
    _skip_or_fail(missing)


def _skip_or_fail(missing: Sequence[str]) -> None:
    """Skip (or, with ``OMNIWIDGET_BROWSER_TESTS=1``, fail) naming what is ``missing``; nothing when it is empty."""
    if not missing:
        return None
    reason = "browser tests need " + ", ".join(missing)
    if os.environ.get(STRICT_ENV_VAR) == "1":
        pytest.fail(f"{reason} ({STRICT_ENV_VAR}=1 forbids skipping)", pytrace=False)
    pytest.skip(reason)


def artifact_dir() -> Path:
    """Directory for screenshots and logs (``$OMNIWIDGET_ARTIFACTS``, default ``<repo>/test-artifacts``)."""
    path = Path(os.environ.get("OMNIWIDGET_ARTIFACTS", "test-artifacts"))
    if not path.is_absolute():
        path = REPO_ROOT / path
    path.mkdir(parents=True, exist_ok=True)
    return path


def wait_until(
    predicate: Callable[[], Any],
    *,
    timeout: float,
    description: str,
    interval: float = 0.1,
    diagnostics: Callable[[], str] | None = None,
) -> Any:
    """Poll ``predicate`` until it returns something truthy and return that value.

    Exceptions raised by ``predicate`` count as "not yet" (the last one is reported).
    On timeout raise :class:`TimeoutError` naming ``description``, the last value or
    exception, and the output of ``diagnostics()`` if given.
    """
    deadline = time.monotonic() + timeout
    last: str = "never evaluated"
    while True:
        try:
            value = predicate()
        except Exception as exc:  # noqa: BLE001 - reported on timeout
            last = f"raised {type(exc).__name__}: {exc}"
        else:
            if value:
                return value
            last = f"returned {value!r}"
        if time.monotonic() >= deadline:
            break
        time.sleep(interval)
    message = f"timed out after {timeout:g}s waiting for {description} (last check {last})"
    if diagnostics is not None:
        message += "\n" + diagnostics()
    raise TimeoutError(message)


# --------------------------------------------------------------------------- server


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def _launch(server: Any, cmd: list[str], env: dict[str, str], log_path: Path, description: str, what: str) -> None:
    """Start ``server``'s process (its own process group, output to ``log_path``) and wait for ``server._is_up``.

    Sets ``server.log_path``, ``server._log_file`` and ``server.process``; on any failure
    ``server.stop()`` cleans up before the error goes on, naming ``description`` and the
    log's tail (``what``: "server", "marimo").
    """
    server.log_path = log_path
    server._log_file = open(log_path, "wb")  # noqa: SIM115 - closed in stop()
    server.process = subprocess.Popen(
        cmd, cwd=server.root, env=env, stdout=server._log_file, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, start_new_session=True
    )
    try:
        wait_until(
            server._is_up,
            timeout=server.startup_timeout,
            interval=0.2,
            description=description,
            diagnostics=lambda: f"{what} log tail:\n{server.log_tail()}",
        )
    except BaseException:
        server.stop()
        raise


def _tail(path: Path, lines: int, what: str) -> str:
    """The last ``lines`` lines of the log at ``path``, or why there is none."""
    try:
        text = path.read_text(errors="replace")
    except OSError as exc:
        return f"<no {what} log: {exc}>"
    return "\n".join(text.splitlines()[-lines:])


class JupyterServer:
    """A throw-away Jupyter server (JupyterLab or Notebook 7) on 127.0.0.1 with isolated config.

    ``frontend`` picks the application: ``"lab"`` (JupyterLab, the default) or
    ``"notebook"`` (Jupyter Notebook 7); see :data:`FRONTENDS`.

    Use as a context manager (or call :meth:`start` / :meth:`stop`).  The user-level
    Jupyter *config*, *runtime*, lab *settings* and *workspaces* dirs, the notebook
    notary's dir and ``IPYTHONDIR`` point into a temporary directory; the *data* path is left alone so the lab
    extensions (anywidget, ipywidgets) and the ``python3`` kernelspec installed in
    ``sys.prefix/share/jupyter`` are still found.  Kernels inherit the server's
    environment, with the repository root prepended to ``PYTHONPATH`` so notebooks can
    ``import omniwidget`` from the working tree.

    Attributes
    ----------
    frontend : Frontend
        The front end this server runs.
    url : str
        Base URL, e.g. ``http://127.0.0.1:43125``.
    token : str
        Random auth token.
    root : Path
        Server root dir (notebooks live here); also holds ``jupyter-server.log``.
    runtime_dir : Path
        ``JUPYTER_RUNTIME_DIR``; kernel connection files are ``kernel-<id>.json`` here.
    log_path : Path
        Server stdout/stderr.
    """

    def __init__(
        self, *, name: str = "server", frontend: str = "lab", startup_timeout: float = 90.0, extra_args: Sequence[str] = ()
    ) -> None:
        self.frontend = get_frontend(frontend)
        self.name = name
        self.startup_timeout = startup_timeout
        self.extra_args = tuple(extra_args)
        self.token = secrets.token_hex(24)
        self.port = 0
        self.url = ""
        self._base: Path | None = None
        self.root = Path()
        self.runtime_dir = Path()
        self.config_dir = Path()
        self.log_path = Path()
        self._log_file = None
        self.process: subprocess.Popen[bytes] | None = None

    # -- lifecycle ---------------------------------------------------------

    def __enter__(self) -> JupyterServer:
        return self.start()

    def __exit__(self, *exc_info: object) -> None:
        self.stop()

    def start(self) -> JupyterServer:
        """Launch the server and block until ``/api/status`` answers (or raise with the log tail)."""
        if self.process is not None:
            raise RuntimeError("server already started")
        self._base = Path(tempfile.mkdtemp(prefix=f"omniwidget-jupyter-{self.name}-"))
        self.root = self._base / "root"
        self.runtime_dir = self._base / "runtime"
        self.config_dir = self._base / "config"
        for directory in (self.root, self.runtime_dir, self.config_dir, self._base / "notary"):
            directory.mkdir()
        settings_dir = self.config_dir / "lab" / "user-settings"
        for plugin, values in LAB_USER_SETTINGS.items():
            target = settings_dir / f"{plugin}.jupyterlab-settings"
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_text(json.dumps(values, indent=2))

        env = {k: v for k, v in os.environ.items() if not k.startswith(("JUPYTER_", "JUPYTERLAB_", "JPY_"))}
        env.update(
            JUPYTER_CONFIG_DIR=str(self.config_dir),
            JUPYTER_RUNTIME_DIR=str(self.runtime_dir),
            JUPYTERLAB_SETTINGS_DIR=str(settings_dir),
            JUPYTERLAB_WORKSPACES_DIR=str(self.config_dir / "lab" / "workspaces"),
            IPYTHONDIR=str(self._base / "ipython"),
            PYTHONPATH=os.pathsep.join(p for p in (str(REPO_ROOT), os.environ.get("PYTHONPATH", "")) if p),
            PYTHONUNBUFFERED="1",
        )
        self.port = _free_port()
        self.url = f"http://127.0.0.1:{self.port}"
        cmd = [
            sys.executable,
            "-m",
            self.frontend.module,
            "--no-browser",
            "--ip=127.0.0.1",
            f"--port={self.port}",
            "--ServerApp.port_retries=0",  # fail loudly instead of silently moving to another port
            "--allow-root",
            # ServerApp.token is deprecated in jupyter_server 2 (and logs a warning); same effect.
            f"--IdentityProvider.token={self.token}",
            f"--ServerApp.root_dir={self.root}",
            "--ServerApp.disable_check_xsrf=True",
            # Keep the notebook-signing secret/db out of ~/.local/share/jupyter.
            f"--NotebookNotary.data_dir={self._base / 'notary'}",
            # No network, and window.jupyterapp (see FRONTENDS).
            *self.frontend.args,
            *self.extra_args,
        ]
        _launch(self, cmd, env, self.root / "jupyter-server.log", f"{self.frontend.title} at {self.url}/api/status", "server")
        return self

    def _is_up(self) -> bool:
        if self.process is not None and self.process.poll() is not None:
            raise RuntimeError(
                f"{self.frontend.title} server exited with code {self.process.returncode}\nserver log tail:\n{self.log_tail()}"
            )
        try:
            with urllib.request.urlopen(f"{self.url}/api/status?token={self.token}", timeout=2) as resp:
                return resp.status == 200
        except (urllib.error.URLError, OSError):
            return False

    def stop(self) -> None:
        """Shut down all kernels (REST), terminate the server's process group, clean up.

        The server log is copied to ``artifact_dir()/jupyter-server-<name>.log`` before
        the temporary directory is removed.
        """
        process, self.process = self.process, None
        if process is not None:
            if process.poll() is None:
                with contextlib.suppress(Exception):
                    for kernel in self.api("GET", "/api/kernels", timeout=5) or []:
                        with contextlib.suppress(Exception):
                            self.api("DELETE", f"/api/kernels/{kernel['id']}", timeout=10)
            self._kill_group(process)
        if self._log_file is not None:
            self._log_file.close()
            self._log_file = None
        if self._base is not None:
            with contextlib.suppress(OSError):
                shutil.copyfile(self.log_path, artifact_dir() / f"jupyter-server-{self.name}.log")
            shutil.rmtree(self._base, ignore_errors=True)
            self._base = None

    @staticmethod
    def _kill_group(process: subprocess.Popen[bytes]) -> None:
        for sig, grace in ((signal.SIGTERM, 15.0), (signal.SIGKILL, 5.0)):
            with contextlib.suppress(ProcessLookupError):
                os.killpg(process.pid, sig)
            try:
                process.wait(timeout=grace)
                return
            except subprocess.TimeoutExpired:
                continue

    # -- helpers -----------------------------------------------------------

    def log_tail(self, lines: int = 60) -> str:
        """The last ``lines`` lines of the server log."""
        return _tail(self.log_path, lines, "server")

    def api(self, method: str, path: str, body: Any = None, *, timeout: float = 10) -> Any:
        """Call the server REST API (``path`` like ``/api/sessions``); return decoded JSON or None."""
        data = None if body is None else json.dumps(body).encode()
        request = urllib.request.Request(
            self.url + path, data=data, method=method, headers={"Authorization": f"token {self.token}", "Content-Type": "application/json"}
        )
        with urllib.request.urlopen(request, timeout=timeout) as resp:
            payload = resp.read()
        return json.loads(payload) if payload else None

    def lab_url(self, path: str, **query: str) -> str:
        """URL of a notebook (path relative to :attr:`root`) in JupyterLab, with the token.

        Only a JupyterLab server exposes ``window.jupyterapp`` there; use :meth:`notebook_url`
        for the notebook in this server's own front end.
        """
        params = urllib.parse.urlencode({**query, "token": self.token})
        return f"{self.url}/lab/tree/{urllib.parse.quote(path)}?{params}"

    def notebook_url(self, path: str, **query: str) -> str:
        """URL of a notebook (path relative to :attr:`root`) in this server's front end, with the token.

        JupyterLab: ``/lab/tree/<path>?reset`` (a fresh workspace); Notebook 7: ``/notebooks/<path>``.
        """
        params = urllib.parse.urlencode({**dict(self.frontend.open_query), **query, "token": self.token})
        return f"{self.url}{self.frontend.notebook_route}{urllib.parse.quote(path)}?{params}"

    def artifact(self, filename: str) -> Path:
        """``artifact_dir()/<filename>``, with this front end's suffix before the extension.

        JupyterLab keeps the plain name; Notebook 7 gets ``-notebook7`` (``editor.png`` ->
        ``editor-notebook7.png``), so a test running in both keeps both artifacts.
        """
        name = Path(filename)
        return artifact_dir() / f"{name.stem}{self.frontend.artifact_suffix}{name.suffix}"


# --------------------------------------------------------------------------- notebooks


def write_notebook(path: str | os.PathLike[str], cells: Sequence[str]) -> Path:
    """Write a v4 notebook of code ``cells`` with the ``python3`` kernelspec; return its path."""
    import nbformat

    nb = nbformat.v4.new_notebook(
        cells=[nbformat.v4.new_code_cell(source) for source in cells],
        metadata={
            "kernelspec": {"name": "python3", "display_name": "Python 3 (ipykernel)", "language": "python"},
            "language_info": {"name": "python"},
        },
    )
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    nbformat.write(nb, path)
    return path


@contextlib.contextmanager
def launch_browser() -> Iterator[Any]:
    """Start Playwright and the Debian Chromium (fresh temporary profile); yield the ``Browser``."""
    from playwright.sync_api import sync_playwright

    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=CHROMIUM, args=list(CHROMIUM_ARGS), headless=True)
        try:
            yield browser
        finally:
            browser.close()


@dataclass(frozen=True)
class ConsoleError:
    """One browser-side error: a ``console.error`` message or an uncaught page error."""

    kind: str  # "console" or "pageerror"
    text: str
    location: str = ""

    def __str__(self) -> str:
        where = f" ({self.location})" if self.location else ""
        return f"[{self.kind}] {self.text}{where}"


class ConsoleCollector:
    """Record ``console.error`` messages and uncaught exceptions of a Playwright page.

    Note: Playwright's sync API only dispatches events while a Playwright call is in
    progress (not during ``time.sleep``), so :meth:`errors` first makes a round trip
    to the page (:meth:`flush`) to deliver everything already emitted.
    """

    def __init__(self, page: Any, allowed: Sequence[tuple[str, str]] = ()) -> None:
        self.page = page
        self.allowed_patterns = tuple(allowed)
        self.entries: list[ConsoleError] = []
        page.on("console", self._on_console)
        page.on("pageerror", self._on_pageerror)

    def flush(self) -> None:
        """Deliver pending console/page-error events (a no-op once the page is closed)."""
        if self.page.is_closed():
            return
        with contextlib.suppress(Exception):
            self.page.evaluate("() => new Promise(resolve => setTimeout(resolve, 0))")

    def _on_console(self, message: Any) -> None:
        if message.type != "error":
            return
        loc = message.location or {}
        location = f"{loc.get('url', '')}:{loc.get('lineNumber', '')}" if loc.get("url") else ""
        self.entries.append(ConsoleError("console", message.text, location))

    def _on_pageerror(self, error: Any) -> None:
        text = f"{error.name}: {error.message}" if getattr(error, "name", None) else str(error)
        self.entries.append(ConsoleError("pageerror", text, (getattr(error, "stack", "") or "").strip()))

    def is_allowed(self, entry: ConsoleError) -> bool:
        """Whether ``entry`` matches :data:`ALLOWED_CONSOLE_ERRORS` (its text) or ``allowed`` (the whole entry)."""
        return any(re.search(pattern, entry.text) for pattern, _why in ALLOWED_CONSOLE_ERRORS) or any(
            re.search(pattern, str(entry)) for pattern, _why in self.allowed_patterns
        )

    def errors(self) -> list[str]:
        """Errors seen so far that are not allow-listed, as readable strings."""
        self.flush()
        return [str(e) for e in self.entries if not self.is_allowed(e)]

    def allowed(self) -> list[str]:
        """Errors seen so far that were ignored because they are allow-listed."""
        self.flush()
        return [str(e) for e in self.entries if self.is_allowed(e)]


# JavaScript run in the page.  ``findPanel`` locates the NotebookPanel showing ``path``.
_JS_FIND_PANEL = """
const findPanel = (path) => {
  const app = window.jupyterapp;
  if (!app || !app.shell) return null;
  return Array.from(app.shell.widgets('main')).find(w => w.context && w.context.path === path) || null;
};
"""

_JS_NOTEBOOK_READY = (
    "(path) => {"
    + _JS_FIND_PANEL
    + """
  const panel = findPanel(path);
  if (!panel || !panel.context.isReady || !panel.sessionContext.isReady) return null;
  const kernel = panel.sessionContext.session && panel.sessionContext.session.kernel;
  if (!kernel || kernel.status !== 'idle' || kernel.connectionStatus !== 'connected') return null;
  return panel.id;
}"""
)

_JS_STATE = (
    "(path) => {"
    + _JS_FIND_PANEL
    + """
  const app = window.jupyterapp;
  if (!app) return {jupyterapp: 'not (yet) defined'};
  const open = Array.from(app.shell.widgets('main')).map(w => (w.context ? w.context.path : w.id));
  const panel = findPanel(path);
  if (!panel) return {open_widgets: open, notebook: 'not open'};
  const kernel = panel.sessionContext.session && panel.sessionContext.session.kernel;
  const cells = [];
  const model = panel.content.model;
  for (let i = 0; model && i < model.cells.length; i++) {
    const cell = model.cells.get(i);
    if (cell.type !== 'code') continue;
    const outputs = cell.outputs.toJSON();
    cells.push({
      index: i,
      execution_count: cell.executionCount,
      output_types: outputs.map(o => o.output_type),
      errors: outputs.filter(o => o.output_type === 'error')
                     .map(o => o.ename + ': ' + o.evalue + '\\n' + (o.traceback || []).join('\\n')),
    });
  }
  return {
    open_widgets: open,
    context_ready: panel.context.isReady,
    session_ready: panel.sessionContext.isReady,
    kernel: kernel ? {id: kernel.id, status: kernel.status, connection: kernel.connectionStatus} : null,
    run_all: window.__omniwidgetRunAll || null,
    cells,
  };
}"""
)

_JS_START_RUN_ALL = (
    "(path) => {"
    + _JS_FIND_PANEL
    + """
  const app = window.jupyterapp;
  const panel = findPanel(path);
  if (!panel) throw new Error('notebook ' + path + ' is not open');
  app.shell.activateById(panel.id);
  const state = window.__omniwidgetRunAll = {done: false, ok: null, error: null};
  // Same command as the "Run > Run All Cells" menu item; resolves once every cell is done.
  app.commands.execute('notebook:run-all-cells').then(
    ok => { state.ok = ok; state.done = true; },
    err => { state.error = String((err && err.stack) || err); state.done = true; });
}"""
)

_ANSI = re.compile(r"\x1b\[[0-9;]*[A-Za-z]")


class CellExecutionError(AssertionError):
    """A notebook cell (run from the browser) raised an exception."""


class NotebookPage:
    """A browser tab showing one notebook of a :class:`JupyterServer` in its front end, in its own browser context.

    Parameters
    ----------
    browser
        A Playwright ``Browser`` (see :func:`launch_browser`).
    server
        The running :class:`JupyterServer`.
    name
        Notebook path relative to ``server.root`` (write it with :func:`write_notebook`).
    timeout
        Default timeout in seconds for opening and waiting.

    Opening loads the notebook's URL (:meth:`JupyterServer.notebook_url`: JupyterLab's
    ``/lab/tree/<name>?reset``, a fresh workspace, or Notebook 7's ``/notebooks/<name>``),
    waits until the notebook's kernel is connected and idle, and starts collecting console errors
    (:meth:`console_errors`).  Closing closes the browser context and shuts the
    notebook's kernel down.
    """

    def __init__(self, browser: Any, server: JupyterServer, name: str, *, timeout: float = 60.0) -> None:
        self.browser = browser
        self.server = server
        self.name = name
        self.timeout = timeout
        self.context: Any = None
        self.page: Any = None
        self.console: ConsoleCollector | None = None
        self.panel_id = ""
        self._kernel_client: Any = None

    def __enter__(self) -> NotebookPage:
        return self.open()

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    # -- lifecycle ---------------------------------------------------------

    def open(self) -> NotebookPage:
        """Load the notebook in a fresh browser context and wait for an idle, connected kernel."""
        self.context = self.browser.new_context(viewport={"width": 1280, "height": 900})
        self.context.set_default_timeout(self.timeout * 1000)
        self.page = self.context.new_page()
        self.console = ConsoleCollector(self.page, self.server.frontend.allowed_console_errors)
        self.page.goto(self.server.notebook_url(self.name), wait_until="domcontentloaded")
        self.panel_id = self._wait_js(
            _JS_NOTEBOOK_READY, f"notebook {self.name!r} open with an idle, connected kernel", timeout=self.timeout
        )
        app = self.page.evaluate("() => window.jupyterapp.name")
        if app != self.server.frontend.app_name:
            raise AssertionError(f"{self.page.url} runs {app!r}, not {self.server.frontend.app_name!r} ({self.server.frontend.title})")
        return self

    def close(self, *, shutdown_kernel: bool = True) -> None:
        """Close the browser context, then (by default) delete the notebook's session and kernel."""
        if self._kernel_client is not None:
            self._kernel_client.stop_channels()
            self._kernel_client = None
        if self.context is not None:
            self.context.close()
            self.context = None
        if shutdown_kernel and self.server.process is not None:
            with contextlib.suppress(Exception):
                for session in self.server.api("GET", "/api/sessions") or []:
                    if session.get("path") == self.name:
                        self.server.api("DELETE", f"/api/sessions/{session['id']}")

    # -- running -----------------------------------------------------------

    def run_all(self, *, timeout: float | None = None, raise_on_error: bool = True) -> None:
        """Run all cells (command ``notebook:run-all-cells``) and wait until every cell finished.

        Raises :class:`CellExecutionError` with the traceback(s) if a cell failed
        (unless ``raise_on_error=False``).
        """
        timeout = self.timeout if timeout is None else timeout
        self.page.evaluate(_JS_START_RUN_ALL, self.name)
        self._wait_js("() => window.__omniwidgetRunAll && window.__omniwidgetRunAll.done", "Run All Cells to finish", timeout=timeout)
        state = self.state()
        run = state.get("run_all") or {}
        errors = [_ANSI.sub("", e) for cell in state.get("cells", []) for e in cell["errors"]]
        unexecuted = [cell["index"] for cell in state.get("cells", []) if cell["execution_count"] is None]
        if raise_on_error and (run.get("error") or errors or run.get("ok") is False or unexecuted):
            raise CellExecutionError(
                f"running {self.name!r} failed: command result={run}, unexecuted code cells={unexecuted}\n"
                + "\n\n".join(errors)
                + "\n"
                + self.diagnostics()
            )

    # -- waiting -----------------------------------------------------------

    def output(self, selector: str) -> Any:
        """Playwright locator for ``selector`` inside this notebook's output areas."""
        return self.page.locator(f'[id="{self.panel_id}"] .jp-OutputArea-output').locator(selector)

    def wait_for_output(self, selector: str, *, timeout: float | None = None, state: str = "visible") -> Any:
        """Wait until ``selector`` is ``state`` in an output area of this notebook; return its locator."""
        timeout = self.timeout if timeout is None else timeout
        locator = self.output(selector)
        with self.explain(f"{selector!r} to be {state} in the output area of {self.name!r}"):
            locator.first.wait_for(state=state, timeout=timeout * 1000)
        return locator

    @contextlib.contextmanager
    def explain(self, description: str) -> Iterator[None]:
        """Re-raise Playwright timeouts / assertion errors with what was awaited and diagnostics.

        Use around ``playwright.sync_api.expect(...)`` calls::

            with nb.explain("the button to show 10"):
                expect(nb.output("button.probe")).to_have_text("10")
        """
        from playwright.sync_api import Error as PlaywrightError

        try:
            yield
        except (AssertionError, PlaywrightError) as exc:
            raise AssertionError(f"while waiting for {description}: {exc}\n{self.diagnostics()}") from exc

    def _wait_js(self, expression: str, description: str, *, timeout: float) -> Any:
        """Poll a JS predicate (called with the notebook path) until truthy; return its value."""
        from playwright.sync_api import TimeoutError as PlaywrightTimeoutError

        try:
            handle = self.page.wait_for_function(expression, arg=self.name, timeout=timeout * 1000, polling=100)
        except PlaywrightTimeoutError as exc:
            raise TimeoutError(f"timed out after {timeout:g}s waiting for {description}\n{self.diagnostics()}") from exc
        return handle.json_value()

    # -- inspection --------------------------------------------------------

    def state(self) -> dict[str, Any]:
        """Front-end-side state of this notebook: open widgets, kernel status, per-cell outputs."""
        return self.page.evaluate(_JS_STATE, self.name)

    def console_errors(self) -> list[str]:
        """Browser console errors / page errors seen so far, minus :data:`ALLOWED_CONSOLE_ERRORS` and the front end's own."""
        return self.console.errors() if self.console else []

    def diagnostics(self) -> str:
        """Everything useful for a failure message: page state, console errors, server log tail."""
        try:
            state = json.dumps(self.state(), indent=1, default=str)
        except Exception as exc:  # noqa: BLE001 - diagnostics must not raise
            state = f"<unavailable: {exc}>"
        console = "\n".join(str(e) for e in self.console.entries) if self.console else ""
        return (
            f"--- front end ---\n{self.server.frontend.title} at {self.page.url if self.page else '<no page>'}\n"
            f"--- notebook state ---\n{_ANSI.sub('', state)}\n"
            f"--- browser console errors ---\n{console or '<none>'}\n"
            f"--- server log tail ---\n{self.server.log_tail()}"
        )

    def screenshot(self, name: str) -> Path:
        """Save a PNG screenshot of the page to :meth:`JupyterServer.artifact` ``(<name>.png)``; return the path."""
        path = self.server.artifact(f"{name}.png")
        self.page.screenshot(path=str(path))
        return path

    def kernel_client(self) -> Any:
        """A (cached) :func:`kernel_client` for this notebook's kernel, stopped on :meth:`close`."""
        if self._kernel_client is None:
            self._kernel_client = kernel_client(self.server, self.name, timeout=self.timeout)
        return self._kernel_client


# --------------------------------------------------------------------------- kernel access


class KernelExecutionError(AssertionError):
    """Code sent with :func:`run_in_kernel` raised an exception."""


def kernel_client(server: JupyterServer, notebook_name: str, *, timeout: float = 30.0) -> Any:
    """Return a started ``BlockingKernelClient`` connected to the kernel running ``notebook_name``.

    The kernel is found through ``/api/sessions`` (session path == ``notebook_name``) and
    its connection file ``kernel-<id>.json`` read from ``server.runtime_dir``.  Call
    ``client.stop_channels()`` when done.

    A kernel that is still starting (just after a restart, say) is waited for: a client
    without a kernel manager judges the kernel by its heartbeat, which misses a beat while
    the new process imports, and ``wait_for_ready`` then gives up with "Kernel died before
    replying to kernel_info"; that is retried with a fresh client until ``timeout``.
    """
    from jupyter_client import BlockingKernelClient

    def find_connection_file() -> Path | None:
        for session in server.api("GET", "/api/sessions") or []:
            if session.get("path") == notebook_name and session.get("kernel"):
                path = server.runtime_dir / f"kernel-{session['kernel']['id']}.json"
                return path if path.exists() else None
        return None

    connection_file = wait_until(
        find_connection_file,
        timeout=timeout,
        description=f"a kernel session for {notebook_name!r} and its connection file in {server.runtime_dir}",
        diagnostics=lambda: f"sessions: {server.api('GET', '/api/sessions')}\nserver log tail:\n{server.log_tail()}",
    )
    deadline = time.monotonic() + timeout
    while True:
        client = BlockingKernelClient()
        client.load_connection_file(str(connection_file))
        client.start_channels()
        try:
            client.wait_for_ready(timeout=max(deadline - time.monotonic(), 1.0))
        except RuntimeError as exc:
            client.stop_channels()
            if "died" not in str(exc) or time.monotonic() >= deadline:
                raise
            time.sleep(0.5)  # still starting: its heartbeat missed a beat
        except BaseException:
            client.stop_channels()
            raise
        else:
            return client


def run_in_kernel(client: Any, code: str, timeout: float = 60) -> str:
    """Execute ``code`` in the client's kernel (sharing the notebook's namespace); return its stdout.

    Only output caused by this request is captured.  Raises
    :class:`KernelExecutionError` with the traceback (and any stderr) if the code
    raises, :class:`TimeoutError` if it does not finish within ``timeout`` seconds.
    """
    stdout: list[str] = []
    stderr: list[str] = []

    def on_output(msg: dict[str, Any]) -> None:
        if msg["header"]["msg_type"] == "stream":
            (stdout if msg["content"]["name"] == "stdout" else stderr).append(msg["content"]["text"])

    try:
        reply = client.execute_interactive(
            code, output_hook=on_output, timeout=timeout, store_history=False, allow_stdin=False, stop_on_error=False
        )
    except TimeoutError as exc:
        raise TimeoutError(f"kernel did not finish within {timeout:g}s running:\n{code}") from exc
    content = reply["content"]
    if content["status"] != "ok":
        traceback = _ANSI.sub("", "\n".join(content.get("traceback", [])))
        raise KernelExecutionError(
            f"kernel code failed ({content.get('ename')}: {content.get('evalue')}):\n{code}\n--- traceback ---\n{traceback}"
            + (f"\n--- stderr ---\n{''.join(stderr)}" if stderr else "")
        )
    return "".join(stdout)


# --------------------------------------------------------------------------- marimo


class MarimoServer:
    """``marimo run`` of one notebook (a marimo app file) on 127.0.0.1, as a subprocess killed on :meth:`stop`.

    marimo runs anywidget widgets in its own front end (no Jupyter server, no comm manager: the
    widget's model goes through marimo's websocket, and the widget is drawn in a shadow root).
    ``marimo run`` serves the notebook as an app: each page load is a session of its own that runs
    every cell, and no code can be sent to its kernel from outside, so a test reads the kernel's
    work from what the widget shows and the files it writes (into :attr:`root`, the kernel's
    working folder).

    The server asks for a token (``--token-password``, random; the page's URL carries it as
    ``access_token``), keeps marimo's config and state in a temporary directory
    (``XDG_CONFIG_HOME``, ``XDG_STATE_HOME``), skips marimo's update check, and gives the kernel the
    repository on ``PYTHONPATH``. Use as a context manager.

    Attributes
    ----------
    url : str
        The app's address with the token, e.g. ``http://127.0.0.1:43125/?access_token=...``.
    root : Path
        The working folder of the server and its kernels (Save image writes there); holds ``marimo.log``.
    """

    #: What differs from the Jupyter front ends that the tests need to know: artifacts' names.
    artifact_suffix = "-marimo"

    def __init__(self, notebook: str | os.PathLike[str], *, name: str = "marimo", startup_timeout: float = 90.0) -> None:
        self.notebook = Path(notebook).resolve()
        self.name = name
        self.startup_timeout = startup_timeout
        self.token = secrets.token_hex(24)
        self.port = 0
        self.base = ""
        self.url = ""
        self._tmp: Path | None = None
        self.root = Path()
        self.log_path = Path()
        self.process: subprocess.Popen[bytes] | None = None
        self._log_file: Any = None

    def __enter__(self) -> MarimoServer:
        return self.start()

    def __exit__(self, *exc_info: object) -> None:
        self.stop()

    def start(self) -> MarimoServer:
        """Start ``python -m marimo run NOTEBOOK --headless`` and wait until ``/health`` answers."""
        if self.process is not None:
            raise RuntimeError("server already started")
        self._tmp = Path(tempfile.mkdtemp(prefix=f"omniwidget-marimo-{self.name}-"))
        self.root = self._tmp / "root"
        self.root.mkdir()
        env = dict(os.environ)
        env.update(
            XDG_CONFIG_HOME=str(self._tmp / "config"),
            XDG_STATE_HOME=str(self._tmp / "state"),
            MARIMO_SKIP_UPDATE_CHECK="1",
            PYTHONPATH=os.pathsep.join(p for p in (str(REPO_ROOT), os.environ.get("PYTHONPATH", "")) if p),
            PYTHONUNBUFFERED="1",
        )
        self.port = _free_port()
        self.base = f"http://127.0.0.1:{self.port}"
        self.url = f"{self.base}/?access_token={self.token}"
        cmd = [
            sys.executable,
            "-m",
            "marimo",
            "run",
            str(self.notebook),
            "--headless",
            "--host=127.0.0.1",
            f"--port={self.port}",
            f"--token-password={self.token}",
        ]
        _launch(self, cmd, env, self.root / "marimo.log", f"marimo at {self.base}/health", "marimo")
        return self

    def _is_up(self) -> bool:
        if self.process is not None and self.process.poll() is not None:
            raise RuntimeError(f"marimo exited with code {self.process.returncode}\nmarimo log tail:\n{self.log_tail()}")
        try:
            with urllib.request.urlopen(f"{self.base}/health", timeout=2) as resp:
                return resp.status == 200
        except (urllib.error.URLError, OSError):
            return False

    def stop(self) -> None:
        """Terminate the server's process group (SIGTERM, then SIGKILL); keep its log in :func:`artifact_dir`; clean up."""
        process, self.process = self.process, None
        if process is not None:
            JupyterServer._kill_group(process)
        if self._log_file is not None:
            self._log_file.close()
            self._log_file = None
        if self._tmp is not None:
            with contextlib.suppress(OSError):
                shutil.copyfile(self.log_path, artifact_dir() / f"marimo-{self.name}.log")
            shutil.rmtree(self._tmp, ignore_errors=True)
            self._tmp = None

    def log_tail(self, lines: int = 60) -> str:
        """The last ``lines`` lines of the server's log."""
        return _tail(self.log_path, lines, "marimo")

    def artifact(self, filename: str) -> Path:
        """``artifact_dir()/<stem>-marimo<suffix>``: a test's artifacts, apart from the Jupyter front ends'."""
        name = Path(filename)
        return artifact_dir() / f"{name.stem}{self.artifact_suffix}{name.suffix}"


class MarimoPage:
    """A browser tab showing a :class:`MarimoServer`'s app, in its own browser context.

    Speaks as :class:`NotebookPage` does where the editor's tests need it (:meth:`output`,
    :meth:`wait_for_output`, :meth:`explain`, :meth:`diagnostics`, :meth:`console_errors`,
    :meth:`screenshot`), so their helpers (``Pane``, ``wait_idle``) work on it unchanged.
    Playwright's CSS selectors go into shadow roots, where marimo draws anywidget widgets.
    Downloads are accepted.
    """

    def __init__(self, browser: Any, server: MarimoServer, *, timeout: float = 60.0) -> None:
        self.browser = browser
        self.server = server
        self.timeout = timeout
        self.context: Any = None
        self.page: Any = None
        self.console: ConsoleCollector | None = None

    def __enter__(self) -> MarimoPage:
        self.context = self.browser.new_context(viewport={"width": 1280, "height": 900}, accept_downloads=True)
        self.context.set_default_timeout(self.timeout * 1000)
        self.page = self.context.new_page()
        self.console = ConsoleCollector(self.page)
        self.page.goto(self.server.url, wait_until="domcontentloaded")
        return self

    def __exit__(self, *exc_info: object) -> None:
        if self.context is not None:
            self.context.close()
            self.context = None

    def output(self, selector: str) -> Any:
        """Playwright locator for ``selector`` in the app (shadow roots included)."""
        return self.page.locator(selector)

    def wait_for_output(self, selector: str, *, timeout: float | None = None, state: str = "visible") -> Any:
        """Wait until ``selector`` is ``state`` in the app; return its locator."""
        timeout = self.timeout if timeout is None else timeout
        locator = self.output(selector)
        with self.explain(f"{selector!r} to be {state} in the marimo app"):
            locator.first.wait_for(state=state, timeout=timeout * 1000)
        return locator

    @contextlib.contextmanager
    def explain(self, description: str) -> Iterator[None]:
        """Re-raise Playwright timeouts / assertion errors with what was awaited and diagnostics."""
        from playwright.sync_api import Error as PlaywrightError

        try:
            yield
        except (AssertionError, PlaywrightError) as exc:
            raise AssertionError(f"while waiting for {description}: {exc}\n{self.diagnostics()}") from exc

    def console_errors(self) -> list[str]:
        """Browser console errors / page errors seen so far, minus :data:`ALLOWED_CONSOLE_ERRORS`."""
        return self.console.errors() if self.console else []

    def diagnostics(self) -> str:
        """The page's address, its console errors and the tail of marimo's log."""
        console = "\n".join(str(e) for e in self.console.entries) if self.console else ""
        return (
            f"--- front end ---\nmarimo at {self.page.url if self.page else '<no page>'}\n"
            f"--- browser console errors ---\n{console or '<none>'}\n"
            f"--- marimo log tail ---\n{self.server.log_tail()}"
        )

    def screenshot(self, name: str) -> Path:
        """Save a PNG screenshot of the page to :meth:`MarimoServer.artifact` ``(<name>.png)``; return the path."""
        path = self.server.artifact(f"{name}.png")
        self.page.screenshot(path=str(path))
        return path
