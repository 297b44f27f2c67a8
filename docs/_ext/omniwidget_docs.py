"""The documentation build's own steps: the notebooks, the gallery and the command line's help.

- ``notebooks/*.ipynb`` are copied into ``docs/notebooks/`` (git-ignored) when Sphinx starts, so
  myst-nb can read and execute them as pages; the copies keep their sources' modification
  times, so an unchanged notebook is not read (nor run) again by an incremental build.
- ``.. omniwidget-gallery:: NAME`` warps a gallery panorama by its handles file
  (``docs/gallery/NAME.json``) with :func:`omniwidget.warp` and shows it before (the handles
  drawn by :func:`omniwidget.io.draw.draw_handles`) and after. The images are made at build
  time and written into the build's ``_static/gallery/``; nothing generated is committed.
- ``.. omniwidget-straighten:: NAME`` straightens a gallery panorama (:func:`omniwidget.straighten`):
  before and after, the lines it used drawn;
- ``.. omniwidget-suggest:: NAME`` finds the lines in a gallery panorama
  (:func:`omniwidget.detect.suggest_lines`) and levels it (:func:`omniwidget.detect.level`):
  the suggestions dashed on the input and the levelled panorama, made at build time into
  ``_static/gallery/`` as well, with the figures measured.
- ``.. omniwidget-help:: [SUBCOMMAND]`` shows ``python -m omniwidget [SUBCOMMAND] --help``.
- The API reference: ``.. omniwidget-layer:: PACKAGE`` documents a layer and each of its public
  modules (found by walking the package), ``.. omniwidget-module:: MODULE`` one module from its
  ``__all__`` (autodoc, plus the re-exported constants autodoc leaves out), and
  ``.. omniwidget-aliases::`` the names of ``omniwidget.__all__``, each linked to its definition.
- Notebook widgets: their views become a short note and their saved state is left out of the
  pages (no widget JavaScript is loaded); numpydoc is kept from giving module data a signature.
"""

from __future__ import annotations

import filecmp
import inspect
import json
import os
import shutil
import subprocess
import sys
import time
import types
from html import escape
from pathlib import Path

from docutils import nodes
from docutils.statemachine import StringList
from sphinx.application import Sphinx
from sphinx.util import logging
from sphinx.util.docutils import SphinxDirective

logger = logging.getLogger(__name__)

DOCS = Path(__file__).resolve().parents[1]
ROOT = DOCS.parent
NOTEBOOKS = ROOT / "notebooks"
NOTEBOOK_COPIES = DOCS / "notebooks"
GALLERY = DOCS / "gallery"
#: Width of the gallery's pictures (the panoramas are 1024 x 512).
GALLERY_WIDTH = 1024


def copy_notebooks(src: Path = NOTEBOOKS, dst: Path = NOTEBOOK_COPIES) -> list[Path]:
    """Mirror the numbered notebooks ``src/NN_*.ipynb`` into ``dst`` (stale copies removed); return the copies."""
    dst.mkdir(exist_ok=True)
    wanted = sorted(src.glob("[0-9][0-9]_*.ipynb"))
    names = {p.name for p in wanted}
    for stale in dst.glob("*.ipynb"):
        if stale.name not in names:
            stale.unlink()
    for path in wanted:
        target = dst / path.name
        if not target.exists() or not filecmp.cmp(path, target, shallow=False):
            shutil.copy2(path, target)
    return [dst / p.name for p in wanted]


def _relative_static(docname: str, name: str) -> str:
    """The URL of ``_static/gallery/NAME`` from the page ``docname`` (the html builder's layout)."""
    return "../" * docname.count("/") + f"_static/gallery/{name}"


def _gallery_image_path(name: str) -> Path:
    import omniwidget as ow

    if name == "hotel_room":
        return Path(ow.sample_path())
    return GALLERY / f"{name}.jpg"


def make_gallery_images(name: str, outdir: Path) -> dict[str, object]:
    """Warp the gallery panorama ``name`` by ``docs/gallery/NAME.json``; write before and after JPEGs into ``outdir``.

    Returns what the page says about the warp: the handles, the figures measured and the time.
    """
    import cv2

    import omniwidget as ow
    from omniwidget.io.draw import display_rgb, draw_handles

    image = ow.read_panorama(_gallery_image_path(name))
    if image.shape[1] != GALLERY_WIDTH:
        image = cv2.resize(image, (GALLERY_WIDTH, GALLERY_WIDTH // 2), interpolation=cv2.INTER_AREA)
    doc = ow.load_handles(GALLERY / f"{name}.json")
    start = time.perf_counter()
    result = ow.warp(image, doc, warn=False)  # its conflicts are in result.warnings, shown on the page
    seconds = time.perf_counter() - start
    before = draw_handles(image, doc, stage="input")
    after = display_rgb(result.image)
    outdir.mkdir(parents=True, exist_ok=True)
    for label, picture in (("before", before), ("after", after)):
        ok, data = cv2.imencode(".jpg", picture[:, :, ::-1], [cv2.IMWRITE_JPEG_QUALITY, 88])
        if not ok:
            raise RuntimeError(f"could not encode the gallery's {name} {label} image")
        (outdir / f"{name}_{label}.jpg").write_bytes(data.tobytes())
    return {
        "handles": doc,
        "quality": result.quality.line(),
        "seconds": seconds,
        "warnings": [str(w) for w in result.warnings],
    }


class GalleryDirective(SphinxDirective):
    """``.. omniwidget-gallery:: NAME``: one panorama of the gallery, before and after."""

    required_arguments = 1

    def run(self) -> list[nodes.Node]:
        """The nodes that stand for the directive."""
        name = self.arguments[0]
        handles_file = GALLERY / f"{name}.json"
        image_file = _gallery_image_path(name)
        for path in (handles_file, image_file):
            if not path.exists():
                raise self.error(f"omniwidget-gallery: {path} does not exist")
            self.env.note_dependency(str(path))
        builder = self.env.app.builder
        if builder.format != "html":
            return [nodes.paragraph(text=f"(the {name} before/after pictures are in the HTML build)")]
        outdir = Path(builder.outdir) / "_static" / "gallery"
        made = make_gallery_images(name, outdir)
        kinds = [h.kind for h in made["handles"].handles]
        counts = ", ".join(f"{kinds.count(k)} {k}{'s' if kinds.count(k) > 1 else ''}" for k in ("line", "point", "cage") if k in kinds)
        html = "\n".join(
            [
                '<div class="omniwidget-gallery">',
                f'<figure><img src="{_relative_static(self.env.docname, f"{name}_before.jpg")}" '
                f'alt="{escape(name)} before: the handles drawn on the input" loading="lazy">'
                "<figcaption>before: the handles on the input</figcaption></figure>",
                f'<figure><img src="{_relative_static(self.env.docname, f"{name}_after.jpg")}" '
                f'alt="{escape(name)} after: the result of omniwidget warp" loading="lazy">'
                "<figcaption>after: <code>omniwidget warp</code>'s result</figcaption></figure>",
                "</div>",
            ]
        )
        out: list[nodes.Node] = [nodes.raw("", html, format="html")]
        summary = nodes.paragraph()
        summary += nodes.Text(
            f"{counts}; warped at {GALLERY_WIDTH} x {GALLERY_WIDTH // 2} in {made['seconds']:.2f} s at build time. Measured: "
        )
        summary += nodes.literal(text=str(made["quality"]))
        summary += nodes.Text(".")
        out.append(summary)
        for message in made["warnings"]:
            out.append(nodes.paragraph(text=f"Warning: {message}"))
        text = handles_file.read_text(encoding="utf-8")
        json.loads(text)  # a broken handles file fails here, named, before omniwidget sees it
        block = nodes.literal_block(text, text, language="json")
        container = nodes.container("", literal_block=True, classes=["literal-block-wrapper"])
        caption = nodes.caption(f"docs/gallery/{name}.json", f"docs/gallery/{name}.json")
        container += caption
        container += block
        out.append(container)
        return out


#: How the gallery draws suggested lines: the editor's colour for them (``COLORS.suggestion``) and its dashes.
SUGGESTION_RGB = (191, 90, 242)
SUGGESTION_DASH = (8.0, 5.0)
#: The vertical edges the levelling rests on, drawn where the levelled panorama shows them.
VERTICAL_RGB = (40, 220, 255)
#: How many suggestions the pictures draw: as many as ``omniwidget suggest`` writes by default.
SUGGESTED_SHOWN = 40


def make_suggest_images(name: str, outdir: Path) -> dict[str, object]:
    """Suggest lines on the gallery panorama ``name`` and level it; write the two JPEGs into ``outdir``.

    ``NAME_suggested.jpg``: the :data:`SUGGESTED_SHOWN` best suggestions (what ``omniwidget
    suggest`` writes), dashed. ``NAME_levelled.jpg``: ``omniwidget.warp(image,
    level(image).handles())`` (what ``omniwidget level`` writes), with the vertical edges the
    estimate rests on drawn where they are now; not written when the panorama cannot be
    levelled. Returns the figures the page gives.
    """
    import cv2
    import numpy as np

    import omniwidget as ow
    from omniwidget.detect import LevelError, level, suggest_lines, suggestions_to_handles
    from omniwidget.document.handles import Handles, LineHandle
    from omniwidget.io.draw import draw_handles

    image = ow.read_panorama(_gallery_image_path(name))
    if image.shape[1] != GALLERY_WIDTH:
        image = cv2.resize(image, (GALLERY_WIDTH, GALLERY_WIDTH // 2), interpolation=cv2.INTER_AREA)
    start = time.perf_counter()
    suggestions = suggest_lines(image, max_lines=None)  # all of them, as omniwidget suggest and level look among
    found_in = time.perf_counter() - start
    pictures = {
        "suggested": draw_handles(
            image, suggestions_to_handles(suggestions[:SUGGESTED_SHOWN]), colour=SUGGESTION_RGB, dash=SUGGESTION_DASH, dots=False
        )
    }
    made: dict[str, object] = {"found": len(suggestions), "shown": min(len(suggestions), SUGGESTED_SHOWN), "seconds": found_in}
    start = time.perf_counter()
    try:
        found = level(image, suggestions=suggestions)
    except LevelError as error:
        made["error"] = str(error)
    else:
        result = ow.warp(image, found.handles(), warn=False)
        made["seconds"] = found_in + time.perf_counter() - start
        rotation = found.moebius()
        moved = tuple(
            LineHandle(start=tuple(map(float, rotation(np.array(e.start)))), end=tuple(map(float, rotation(np.array(e.end)))))
            for e in found.edges
        )
        pictures["levelled"] = draw_handles(result.image, Handles(moved), colour=VERTICAL_RGB, thickness=1, dots=False)
        made.update(pitch=found.pitch, roll=found.roll, tilt=found.tilt, edges=len(found.edges), residual=found.residual)
    outdir.mkdir(parents=True, exist_ok=True)
    for label, picture in pictures.items():
        ok, data = cv2.imencode(".jpg", picture[:, :, ::-1], [cv2.IMWRITE_JPEG_QUALITY, 88])
        if not ok:
            raise RuntimeError(f"could not encode the gallery's {name} {label} image")
        (outdir / f"{name}_{label}.jpg").write_bytes(data.tobytes())
    return made


class SuggestDirective(SphinxDirective):
    """``.. omniwidget-suggest:: NAME``: a gallery panorama's suggested lines, and the panorama levelled."""

    required_arguments = 1

    def run(self) -> list[nodes.Node]:
        """The nodes that stand for the directive."""
        name = self.arguments[0]
        image_file = _gallery_image_path(name)
        if not image_file.exists():
            raise self.error(f"omniwidget-suggest: {image_file} does not exist")
        self.env.note_dependency(str(image_file))
        builder = self.env.app.builder
        if builder.format != "html":
            return [nodes.paragraph(text=f"(the {name} suggested-lines and levelled pictures are in the HTML build)")]
        made = make_suggest_images(name, Path(builder.outdir) / "_static" / "gallery")
        figures = [
            '<div class="omniwidget-gallery">',
            f'<figure><img src="{_relative_static(self.env.docname, f"{name}_suggested.jpg")}" '
            f'alt="{escape(name)}: the lines omniwidget suggest finds, dashed on the input" loading="lazy">'
            f"<figcaption>the {made['shown']} best suggested lines, dashed: <code>omniwidget suggest</code>'s handles</figcaption>"
            "</figure>",
        ]
        if "error" not in made:
            figures.append(
                f'<figure><img src="{_relative_static(self.env.docname, f"{name}_levelled.jpg")}" '
                f'alt="{escape(name)} levelled by omniwidget level, the vertical edges it used drawn" loading="lazy">'
                "<figcaption>levelled: <code>omniwidget level</code>'s result, the vertical edges it rests on drawn</figcaption>"
                "</figure>"
            )
        figures.append("</div>")
        summary = nodes.paragraph()
        summary += nodes.Text(f"{made['found']} lines found ({made['shown']} drawn). ")
        if "error" in made:
            summary += nodes.Text("Not levelled: ")
            summary += nodes.literal(text=str(made["error"]))
            summary += nodes.Text(f". Found at {GALLERY_WIDTH} x {GALLERY_WIDTH // 2} in {made['seconds']:.2f} s at build time.")
        else:
            summary += nodes.Text(
                f"Level: pitch {made['pitch']:+.2f}°, roll {made['roll']:+.2f}°, tilt {made['tilt']:.2f}°, "
                f"from {made['edges']} vertical edges ({made['residual']:.2f}° rms off the vertical found). "
                f"Found and levelled at {GALLERY_WIDTH} x {GALLERY_WIDTH // 2} in {made['seconds']:.2f} s at build time."
            )
        return [nodes.raw("", "\n".join(figures), format="html"), summary]


def make_straighten_images(name: str, outdir: Path) -> dict[str, object]:
    """Straighten the gallery panorama ``name`` (:func:`omniwidget.straighten`); write before and after JPEGs, the lines used drawn.

    Returns the summary line and the time.
    """
    import cv2

    import omniwidget as ow

    image = ow.read_panorama(_gallery_image_path(name))
    if image.shape[1] != GALLERY_WIDTH:
        image = cv2.resize(image, (GALLERY_WIDTH, GALLERY_WIDTH // 2), interpolation=cv2.INTER_AREA)
    start = time.perf_counter()
    done = ow.straighten(image)
    seconds = time.perf_counter() - start
    outdir.mkdir(parents=True, exist_ok=True)
    for label, picture in zip(("straighten_before", "straighten_after"), done.pictures(image), strict=True):
        ok, data = cv2.imencode(".jpg", picture[:, :, ::-1], [cv2.IMWRITE_JPEG_QUALITY, 88])
        if not ok:
            raise RuntimeError(f"could not encode the gallery's {name} {label} image")
        (outdir / f"{name}_{label}.jpg").write_bytes(data.tobytes())
    return {"summary": done.summary(), "seconds": seconds}


class StraightenDirective(SphinxDirective):
    """``.. omniwidget-straighten:: NAME``: a gallery panorama before and after ``omniwidget straighten``, the lines used drawn."""

    required_arguments = 1

    def run(self) -> list[nodes.Node]:
        """The nodes that stand for the directive."""
        name = self.arguments[0]
        image_file = _gallery_image_path(name)
        if not image_file.exists():
            raise self.error(f"omniwidget-straighten: {image_file} does not exist")
        self.env.note_dependency(str(image_file))
        builder = self.env.app.builder
        if builder.format != "html":
            return [nodes.paragraph(text=f"(the {name} straightened pictures are in the HTML build)")]
        made = make_straighten_images(name, Path(builder.outdir) / "_static" / "gallery")
        html = (
            '<div class="omniwidget-gallery">'
            f'<figure><img src="{_relative_static(self.env.docname, f"{name}_straighten_before.jpg")}" '
            f'alt="{escape(name)}: the lines omniwidget straighten used, on the input" loading="lazy">'
            "<figcaption>the input, the lines used drawn (verticals cyan, horizontals amber, others magenta)</figcaption></figure>"
            f'<figure><img src="{_relative_static(self.env.docname, f"{name}_straighten_after.jpg")}" '
            f'alt="{escape(name)} straightened, the lines where they are now" loading="lazy">'
            "<figcaption><code>omniwidget straighten</code>'s result, each line where its pixels landed</figcaption></figure>"
            "</div>"
        )
        return [nodes.raw("", html, format="html"), nodes.paragraph(text=f"{made['summary']} ({made['seconds']:.1f} s when this page was built)")]


def _summary(obj: object) -> str:
    """The first sentence-paragraph of ``obj``'s docstring, on one line."""
    doc = inspect.getdoc(obj) or ""
    return " ".join(doc.split("\n\n", 1)[0].split())


def _short_signature(obj: object) -> str:
    """``(a, b=1, *, c=None)``: the call signature without annotations."""
    try:
        sig = inspect.signature(obj)
    except (TypeError, ValueError):
        return ""
    params = [p.replace(annotation=inspect.Parameter.empty) for p in sig.parameters.values()]
    return str(sig.replace(parameters=params, return_annotation=inspect.Signature.empty))


class AliasesDirective(SphinxDirective):
    """``.. omniwidget-aliases::`` with names of ``omniwidget.__all__`` as content.

    Each name gets an entry of its own (``omniwidget.NAME``, an anchor and an index entry) with
    its summary line and a link to where it is defined and documented in full, so the top-level
    page lists the names without repeating every member's documentation.
    """

    has_content = True

    def run(self) -> list[nodes.Node]:
        """The nodes that stand for the directive."""
        import omniwidget

        lines: list[str] = []
        for name in " ".join(self.content).split():
            if name not in omniwidget.__all__:
                raise self.error(f"omniwidget-aliases: {name!r} is not in omniwidget.__all__")
            obj = getattr(omniwidget, name)
            if name == "__version__":
                lines += [f".. py:data:: {name}", "   :module: omniwidget", f"   :value: {obj!r}", "", "   The package's version.", ""]
                continue
            module = obj.__module__
            if isinstance(obj, type):
                kind, role = ("exception", "exc") if issubclass(obj, BaseException) else ("class", "class")
                signature = ""
            else:
                kind, role, signature = "function", "func", _short_signature(obj)
            where = f"{module}.{obj.__qualname__}"
            lines += [
                f".. py:{kind}:: {name}{signature}",
                "   :module: omniwidget",
                "",
                f"   {_summary(obj)}",
                "",
                f"   Defined in :{role}:`{where}`, documented there in full.",
                "",
            ]
        text = "\n".join(lines)
        container = nodes.section()
        container.document = self.state.document
        self.state.nested_parse(StringList(text.splitlines(), source="omniwidget-aliases"), self.content_offset, container)
        return list(container.children)


def _import_origins(module_name: str) -> dict[str, str]:
    """``{name: module}`` for the ``from X import name`` statements of a module (absolute module names)."""
    import ast
    import importlib.util

    spec = importlib.util.find_spec(module_name)
    if spec is None or spec.origin is None or not spec.origin.endswith(".py"):
        return {}
    package = module_name if spec.submodule_search_locations else module_name.rpartition(".")[0]
    origins: dict[str, str] = {}
    for node in ast.walk(ast.parse(Path(spec.origin).read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom):
            base = importlib.util.resolve_name("." * node.level + (node.module or ""), package) if node.level else node.module
            for alias in node.names:
                origins[alias.asname or alias.name] = base or ""
    return origins


def _short_value(obj: object) -> str:
    """A data entry's value as the page shows it: one line, module paths dropped, at most 80 characters."""
    import re

    text = " ".join((str(obj) if isinstance(obj, (types.UnionType, types.GenericAlias)) else repr(obj)).split())
    text = re.sub(r"\b(?:[A-Za-z_]\w*\.)+([A-Za-z_]\w*)", r"\1", text) if not isinstance(obj, str) else text
    return text if len(text) <= 80 else text[:77] + "..."


class ModuleDirective(SphinxDirective):
    """``.. omniwidget-module:: MODULE``: ``automodule`` (members from ``__all__``) and the data autodoc leaves out.

    autodoc documents a module's data only where the module's own source documents it with a
    ``#:`` comment; a constant re-exported from another module, or an alias without a
    comment, would be missing from the page. Each such name in ``__all__`` gets an entry
    here (its value, the ``#:`` comment where it is defined, and where that is), so every
    public name has one.
    """

    required_arguments = 1

    def run(self) -> list[nodes.Node]:
        """The nodes that stand for the directive."""
        import importlib

        from sphinx.pycode import ModuleAnalyzer

        name = self.arguments[0]
        module = importlib.import_module(name)
        attr_docs = ModuleAnalyzer.for_module(name).find_attr_docs()
        origins = _import_origins(name)
        lines = [f".. automodule:: {name}", ""]
        for member in getattr(module, "__all__", []):
            obj = getattr(module, member)
            if inspect.isclass(obj) or inspect.isroutine(obj) or inspect.ismodule(obj) or ("", member) in attr_docs:
                continue
            lines += [f".. py:data:: {member}", f"   :module: {name}", f"   :value: {_short_value(obj)}", ""]
            origin = origins.get(member)
            if origin and origin != name:
                comment = ModuleAnalyzer.for_module(origin).find_attr_docs().get(("", member), [])
                lines += [f"   {line}" for line in comment] + [""]
                public = not any(part.startswith("_") for part in origin.split("."))
                where = f":data:`{origin}.{member}`" if public else f"``{origin}.{member}``"
                lines += [f"   Re-exported from {where}.", ""]
        container = nodes.section()
        container.document = self.state.document
        self.state.nested_parse(StringList(lines, source=f"omniwidget-module {name}"), self.content_offset, container)
        return list(container.children)


def public_modules(package: str) -> list[str]:
    """The public modules of a layer package: ``PACKAGE.name`` for each module not named ``_*``.

    In the order the package's docstring first names them (``:mod:`.name```), then the rest
    alphabetically, so a new module is documented as soon as it exists.
    """
    import importlib
    import pkgutil
    import re

    pkg = importlib.import_module(package)
    names = [m.name for m in pkgutil.iter_modules(pkg.__path__) if not m.name.startswith("_")]
    named = [n for n in dict.fromkeys(re.findall(r":mod:`\.(\w+)`", pkg.__doc__ or "")) if n in names]
    return [f"{package}.{n}" for n in named + sorted(set(names) - set(named))]


class LayerDirective(SphinxDirective):
    """``.. omniwidget-layer:: PACKAGE``: a layer's docstring, then a section per public module (``omniwidget-module``)."""

    required_arguments = 1

    def run(self) -> list[nodes.Node]:
        """The nodes that stand for the directive."""
        from sphinx.util.nodes import nested_parse_with_titles

        package = self.arguments[0]
        lines = [f".. automodule:: {package}", "   :no-members:", ""]
        for module in public_modules(package):
            title = f"``{module}``"
            lines += [title, "-" * len(title), "", f".. omniwidget-module:: {module}", ""]
        container = nodes.section()
        container.document = self.state.document
        nested_parse_with_titles(self.state, StringList(lines, source=f"omniwidget-layer {package}"), container)
        return list(container.children)


def no_signature_for_data(
    app: Sphinx, what: str, name: str, obj: object, options: object, signature: str | None, return_annotation: str | None
) -> tuple[None, None] | None:
    """Module data and attributes have no call signature: keep numpydoc from giving them one.

    numpydoc's ``autodoc-process-signature`` handler gives a callable value (a type alias such as
    ``list[...]``) the signature of what it calls, and Sphinx 9's autodoc, which keeps no
    signature for data, then fails on it ("list assignment index out of range"). Runs before
    numpydoc's handler (priority 400 < 500); ``(None, None)`` leaves the signature alone.
    """
    if what in ("data", "attribute"):
        return (None, None)
    return None


class HelpDirective(SphinxDirective):
    """``.. omniwidget-help:: [SUBCOMMAND]``: the command line's own ``--help`` text."""

    optional_arguments = 1

    def run(self) -> list[nodes.Node]:
        """The nodes that stand for the directive."""
        args = [*self.arguments, "--help"]
        env = {**os.environ, "COLUMNS": "100"}
        proc = subprocess.run([sys.executable, "-m", "omniwidget", *args], capture_output=True, text=True, env=env, cwd=ROOT, check=False)
        if proc.returncode != 0:
            raise self.error(f"omniwidget {' '.join(args)} exited with {proc.returncode}: {proc.stderr.strip()}")
        text = f"$ omniwidget {' '.join(args)}\n{proc.stdout.rstrip()}"
        return [nodes.literal_block(text, text, language="text")]


WIDGET_VIEW = '<script type="application/vnd.jupyter.widget-view+json">'
WIDGET_NOTE = (
    "An interactive widget is shown here when the notebook runs in Jupyter (JupyterLab, "
    "Notebook 7 or Binder); a static page cannot run its kernel side."
)


def widgets_as_notes(app: Sphinx, doctree: nodes.document) -> None:
    """Replace each notebook widget's view (a script no JavaScript reads here) by a short note.

    The pages load no widget JavaScript (``nb_ipywidgets_js = {}`` in conf.py): nothing is
    fetched from a CDN, and an editor or a slider could not work without a kernel anyway.
    """
    for raw in list(doctree.findall(nodes.raw)):
        if raw.astext().lstrip().startswith(WIDGET_VIEW):
            note = nodes.paragraph(classes=["omniwidget-widget-note"])
            note += nodes.emphasis(text=WIDGET_NOTE)
            raw.replace_self(note)


def drop_widget_state(app: Sphinx, pagename: str, templatename: str, context: dict, doctree: object) -> None:
    """Leave the notebooks' saved widget state out of the pages: with no widget JavaScript nothing would read it."""
    metadata = getattr(app.env, "nb_metadata", {}).get(pagename, {})
    metadata.get("js_files", {}).pop("ipywidgets_state", None)


def always_reread(app: Sphinx, env: object, added: set[str], changed: set[str], removed: set[str]) -> list[str]:
    """The pages made from the package itself, read again by every build, incremental ones too.

    Sphinx sees a page's own source change, not the package's: a new module, a changed
    docstring or a changed warp would otherwise leave the API pages and the gallery stale. They
    take a few seconds; the notebooks are re-run only when they change (or on a clean build).
    """
    return sorted(doc for doc in getattr(env, "found_docs", ()) if doc.startswith("api/") or doc == "gallery/index")


def _copy_on_init(app: Sphinx, config: object) -> None:
    copied = copy_notebooks()
    logger.info(f"omniwidget_docs: {len(copied)} notebooks mirrored into {NOTEBOOK_COPIES}")


def setup(app: Sphinx) -> dict[str, object]:
    """Register the directives and the event handlers (Sphinx's entry point of an extension)."""
    app.connect("config-inited", _copy_on_init)
    app.connect("doctree-read", widgets_as_notes)
    app.connect("env-get-outdated", always_reread)
    app.connect("html-page-context", drop_widget_state, priority=400)
    app.add_directive("omniwidget-gallery", GalleryDirective)
    app.add_directive("omniwidget-suggest", SuggestDirective)
    app.add_directive("omniwidget-straighten", StraightenDirective)
    app.add_directive("omniwidget-help", HelpDirective)
    app.add_directive("omniwidget-aliases", AliasesDirective)
    app.add_directive("omniwidget-module", ModuleDirective)
    app.add_directive("omniwidget-layer", LayerDirective)
    app.connect("autodoc-process-signature", no_signature_for_data, priority=400)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
