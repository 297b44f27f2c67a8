"""The documentation site, as built: figures on the notebook pages, every public name in the API reference.

CI (``.ci/run``) builds the site before pytest runs::

    python -m sphinx -W --keep-going -b html docs docs/_build/html

These tests read what that build wrote into ``docs/_build/html``. Without it they are skipped,
except when ``OMNIWIDGET_BROWSER_TESTS=1`` (CI), where a missing site fails them: the checks
can never silently disappear. The notebooks themselves are checked here too, without any
build: they are committed without outputs (``nbstripout``-style).
"""

from __future__ import annotations

import ast
import importlib
import json
import os
import pkgutil
import re
from html.parser import HTMLParser
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
SITE = DOCS / "_build" / "html"
NOTEBOOKS = sorted((ROOT / "notebooks").glob("[0-9][0-9]_*.ipynb"))
BUILD_COMMAND = "python -m sphinx -W --keep-going -b html docs docs/_build/html"
#: Setting it to 1 (CI) turns a missing site into a failure, as for the real-browser tests.
STRICT_ENV_VAR = "OMNIWIDGET_BROWSER_TESTS"


@pytest.fixture(scope="module")
def site() -> Path:
    """The built site's folder; skips (or fails, in CI) when it has not been built."""
    if not (SITE / "index.html").is_file():
        reason = f"the documentation site is not built ({SITE.relative_to(ROOT)}/index.html is missing; run `{BUILD_COMMAND}`)"
        if os.environ.get(STRICT_ENV_VAR) == "1":
            pytest.fail(f"{reason}; {STRICT_ENV_VAR}=1 forbids skipping", pytrace=False)
        pytest.skip(reason)
    return SITE


# --- reading the pages ------------------------------------------------------------------------


class _Page(HTMLParser):
    """The parts of a page these tests read: element ids, images, and the images inside each notebook cell."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.ids: set[str] = set()
        self.images: list[str] = []  # every <img src>
        self.cells: list[list[str]] = []  # per code cell (div.cell), the <img src> in it
        self.scripts: list[dict[str, str | None]] = []
        self._open: list[bool] = []  # for each open <div>: does it start a code cell?

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        attributes = dict(attrs)
        if attributes.get("id"):
            self.ids.add(str(attributes["id"]))
        if tag == "div":
            starts_cell = "cell" in (attributes.get("class") or "").split()
            self._open.append(starts_cell)
            if starts_cell:
                self.cells.append([])
        elif tag == "img":
            src = attributes.get("src") or ""
            self.images.append(src)
            if any(self._open):
                self.cells[-1].append(src)
        elif tag == "script":
            self.scripts.append(attributes)

    def handle_endtag(self, tag: str) -> None:
        if tag == "div" and self._open:
            self._open.pop()


def read_page(path: Path) -> _Page:
    page = _Page()
    page.feed(path.read_text(encoding="utf-8"))
    page.close()
    return page


def image_shown(page_path: Path, src: str) -> bool:
    """An <img src> that shows something: inline image data, or a file the site has."""
    if src.startswith("data:image/"):
        return len(src) > 100
    if not src or "://" in src:
        return False
    target = (page_path.parent / src.split("#")[0].split("?")[0]).resolve()
    return target.is_file() and target.stat().st_size > 0


# --- what the notebooks plot --------------------------------------------------------------------


def plotting_calls(source: str) -> list[str]:
    """The calls of a code cell that display a figure when the cell runs.

    The notebooks show every figure through a helper named ``show`` (an image strip, as JPEG)
    or ``display(Image(...))``; matplotlib's ``plt.*`` counts too. Calls inside function
    bodies (the helpers' definitions, widget callbacks) run only when called, so they are
    not counted where they are written.
    """
    found: list[str] = []

    def visit(node: ast.AST) -> None:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda, ast.ClassDef)):
            return
        if isinstance(node, ast.Call):
            func = node.func
            if isinstance(func, ast.Name) and func.id == "show":
                found.append("show(...)")
            elif (
                isinstance(func, ast.Name)
                and func.id == "display"
                and node.args
                and isinstance(node.args[0], ast.Call)
                and isinstance(node.args[0].func, ast.Name)
                and node.args[0].func.id == "Image"
            ):
                found.append("display(Image(...))")
            elif isinstance(func, ast.Attribute) and isinstance(func.value, ast.Name) and func.value.id == "plt":
                found.append(f"plt.{func.attr}(...)")
        for child in ast.iter_child_nodes(node):
            visit(child)

    visit(ast.parse(source))
    return found


def code_cells(path: Path) -> list[dict]:
    """The notebook's code cells that have a place on its page (myst-nb drops those tagged ``remove-cell``)."""
    cells = json.loads(path.read_text(encoding="utf-8"))["cells"]
    return [cell for cell in cells if cell["cell_type"] == "code" and "remove-cell" not in cell.get("metadata", {}).get("tags", [])]


def source(cell: dict) -> str:
    return "".join(cell["source"]) if isinstance(cell["source"], list) else cell["source"]


def test_the_plotting_cells_are_found():
    """The count the page check relies on: the notebooks do plot, and the helper's definition is not a plot."""
    assert plotting_calls("def show(*images):\n    display(Image(data))\n") == []
    assert plotting_calls("for r in results:\n    show(r.image)\n") == ["show(...)"]
    counts = {path.stem: sum(bool(plotting_calls(source(cell))) for cell in code_cells(path)) for path in NOTEBOOKS}
    assert sum(counts.values()) >= 20, counts
    assert counts["00_quickstart"] == 0, counts  # the quickstart shows the editor, a widget


# --- the notebooks, as committed ----------------------------------------------------------------


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_notebooks_are_committed_without_outputs(path):
    """nbstripout-style: no outputs, no execution counts, no saved widget state in ``notebooks/``.

    The documentation build executes them (myst-nb) into ``docs/_build``; outputs committed
    to the repository would be stale figures and large diffs. To strip one: ``jupyter
    nbconvert --clear-output --inplace notebooks/NAME.ipynb`` (or nbstripout).
    """
    nb = json.loads(path.read_text(encoding="utf-8"))
    dirty = [
        f"cell {i}: "
        + ", ".join(k for k, bad in (("outputs", cell.get("outputs")), ("execution_count", cell.get("execution_count") is not None)) if bad)
        for i, cell in enumerate(nb["cells"])
        if cell["cell_type"] == "code" and (cell.get("outputs") or cell.get("execution_count") is not None)
    ]
    assert not dirty, f"{path.name} is committed with outputs: {dirty}"
    assert "widgets" not in nb.get("metadata", {}), f"{path.name} is committed with saved widget state (metadata.widgets)"


def test_there_are_seven_notebooks():
    assert [p.name[:2] for p in NOTEBOOKS] == [f"{i:02d}" for i in range(7)]


# --- the built site -----------------------------------------------------------------------------


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_each_notebook_page_shows_its_figures(site, path):
    """Every code cell that plots has at least one image on the notebook's page, and the images are there."""
    page_path = site / "notebooks" / f"{path.stem}.html"
    assert page_path.is_file(), f"no page for {path.name} in the built site"
    page = read_page(page_path)
    cells = code_cells(path)
    assert len(page.cells) == len(cells), (
        f"{page_path.name}: {len(page.cells)} code cells on the page, {len(cells)} in the notebook (a site built from another "
        f"version of it? rebuild: {BUILD_COMMAND})"
    )
    missing = [
        f"cell {i} ({', '.join(plotting_calls(source(cell)))})"
        for i, (cell, shown) in enumerate(zip(cells, page.cells, strict=True))
        if plotting_calls(source(cell)) and not any(image_shown(page_path, src) for src in shown)
    ]
    assert not missing, f"{page_path.name}: code cells that plot but show no image: {missing}"
    plotting = sum(bool(plotting_calls(source(cell))) for cell in cells)
    shown = sum(image_shown(page_path, src) for srcs in page.cells for src in srcs)
    assert shown >= plotting, f"{page_path.name}: {shown} images for {plotting} plotting cells"


def test_notebook_pages_carry_no_widget_state_or_widget_javascript(site):
    """The widgets' saved state is left out (no JavaScript would read it) and no widget manager is fetched from a CDN."""
    for path in NOTEBOOKS:
        page = read_page(site / "notebooks" / f"{path.stem}.html")
        kinds = [script.get("type") for script in page.scripts]
        assert "application/vnd.jupyter.widget-state+json" not in kinds, path.stem
        remote = [script.get("src") for script in page.scripts if "://" in (script.get("src") or "")]
        assert all("mathjax" in src for src in remote), f"{path.stem} loads {remote}"


def public_api() -> dict[str, list[str]]:
    """``{module: [its __all__]}`` for ``omniwidget`` and every public module of its public packages.

    Found by walking the package, so a new module is checked as soon as it exists: the layers
    (``omniwidget.sphere``, ..., ``omniwidget.viz``) and their modules, ``omniwidget.errors``
    and ``omniwidget.data``. Private modules (``_name``) and ``__main__`` are left out.
    """
    import omniwidget

    api = {"omniwidget": list(omniwidget.__all__)}
    for info in pkgutil.iter_modules(omniwidget.__path__, "omniwidget."):
        short = info.name.rpartition(".")[2]
        if short.startswith("_"):
            continue
        module = importlib.import_module(info.name)
        if not info.ispkg:
            api[info.name] = list(getattr(module, "__all__", []))
            continue
        if info.name == "omniwidget.data":
            api[info.name] = list(module.__all__)
        for sub in pkgutil.iter_modules(module.__path__, f"{info.name}."):
            if not sub.name.rpartition(".")[2].startswith("_"):
                api[sub.name] = list(getattr(importlib.import_module(sub.name), "__all__", []))
    return api


@pytest.mark.slow  # imports every module, the widget and pyvista stacks too (0.8-1.9 s measured)
def test_the_api_reference_has_an_entry_for_every_public_name(site):
    """Each name of ``omniwidget.__all__`` and of each layer module's ``__all__`` is an anchor on the API pages."""
    ids: set[str] = set()
    for page in sorted((site / "api").glob("*.html")):
        ids |= read_page(page).ids
    api = public_api()
    assert {"omniwidget.sphere.coords", "omniwidget.method.bbw", "omniwidget.raster.pipeline", "omniwidget.viz.pane"} <= set(api)
    missing = [f"{module}.{name}" for module, names in api.items() for name in names if f"{module}.{name}" not in ids]
    assert not missing, f"not in the API reference ({site / 'api'}): {missing}"
    assert sum(map(len, api.values())) > 200


def test_the_api_reference_gives_shapes_and_units(site):
    """The numpydoc sections are rendered: parameters with their shapes, ``[lon, lat]`` in degrees."""
    html = (site / "api" / "sphere.html").read_text(encoding="utf-8")
    text = " ".join(re.sub(r"<[^>]+>", " ", html).split())
    assert "Parameters" in text and "Returns" in text
    assert re.search(r"shape \( ?\.\.\., 2\)|shape \( ?n, 2\)", text), "no shapes in the parameter types"
    assert "[lon, lat]" in text


def test_the_gallery_shows_before_and_after_for_each_panorama(site):
    page_path = site / "gallery" / "index.html"
    page = read_page(page_path)
    names = sorted(p.stem for p in (DOCS / "gallery").glob("*.json"))
    assert names == ["city_parking", "courtyard", "hotel_room", "studio_office"]
    for name in names:
        for when in ("before", "after"):
            src = next((s for s in page.images if s.endswith(f"gallery/{name}_{when}.jpg")), None)
            assert src is not None and image_shown(page_path, src), f"the gallery has no {when} image of {name}"


def test_the_gallery_shows_the_suggested_lines_and_each_panorama_levelled(site):
    """The section made by ``omniwidget-suggest``: both pictures of each panorama, and the figures measured at build time."""
    page_path = site / "gallery" / "index.html"
    page = read_page(page_path)
    for name in ("hotel_room", "studio_office", "courtyard", "city_parking"):
        for picture in ("suggested", "levelled"):
            src = next((s for s in page.images if s.endswith(f"gallery/{name}_{picture}.jpg")), None)
            assert src is not None and image_shown(page_path, src), f"the gallery has no {picture} image of {name}"
    text = " ".join(re.sub(r"<[^>]+>", " ", page_path.read_text(encoding="utf-8")).split())
    figures = re.findall(
        r"(\d+) lines found \(\d+ drawn\)\. Level: pitch [-+]\d+\.\d+°, roll [-+]\d+\.\d+°, tilt \d+\.\d+°, from (\d+) vertical", text
    )
    assert len(figures) == 4 and all(int(found) > 0 and int(edges) >= 4 for found, edges in figures), figures


def test_the_command_line_page_shows_the_commands_own_help(site):
    text = (site / "cli.html").read_text(encoding="utf-8")
    for flag in ("--handles", "--apply-map", "--output-dir", "--fit", "--max-lines", "--yaw", "--pitch", "--fov"):
        assert flag in text, flag
    for command in ("warp", "level", "suggest", "view", "demo", "schema"):
        assert f"$ omniwidget {command} --help" in text, command


def test_every_page_of_the_site_is_there(site):
    for page in (
        "index",
        "about",
        "architecture",
        "cli",
        "conventions",
        "handles-file",
        "paper-figures",
        "notebooks",
        "gallery/index",
        "api/index",
        "install",
        "editor",
        "library",
        "detection",
        "video",
        "large",
        "default-mode",
        "inside",
        "reliability",
        "packages",
    ):
        assert (site / f"{page}.html").is_file(), page


# --- what the pages say, checked without a build -----------------------------------------------


def test_the_handles_files_of_the_docs_are_valid():
    """The example on the handles-file page and the gallery's files all load."""
    import omniwidget as ow

    text = (DOCS / "handles-file.md").read_text(encoding="utf-8")
    examples = re.findall(r"```json\n(.*?)```", text, flags=re.DOTALL)
    assert examples
    for example in examples:
        assert len(ow.Handles.from_json(example)) == 4
    for path in sorted((DOCS / "gallery").glob("*.json")):
        assert len(ow.load_handles(path)) >= 3, path.name
        assert (DOCS / "gallery" / f"{path.stem}.jpg").is_file() or path.stem == "hotel_room", f"no panorama for {path.name}"


def test_the_gallerys_hotel_room_is_the_demo():
    import omniwidget as ow
    from omniwidget.app.cli import DEMO_HANDLES

    assert ow.load_handles(DOCS / "gallery" / "hotel_room.json") == ow.Handles.from_dict(DEMO_HANDLES)
