"""The package's structure: a graph of layers, each importing only the layers it names; no import cycle; no private
name used across modules.

Read from the source (every ``import`` statement, at module level or inside a function,
since a lazy import is a dependency all the same; imports under ``TYPE_CHECKING`` are for
type hints only and do not count).
"""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "omniwidget"


def _modules() -> dict[str, Path]:
    out = {}
    for path in PACKAGE.rglob("*.py"):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        out[name] = path
    return out


MODULES = _modules()


def _type_checking_only(tree: ast.AST) -> set[int]:
    """Line numbers of the statements inside ``if TYPE_CHECKING:`` blocks."""
    lines: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and getattr(node.test, "id", getattr(node.test, "attr", None)) == "TYPE_CHECKING":
            for child in node.body:
                lines.update(range(child.lineno, (child.end_lineno or child.lineno) + 1))
    return lines


def _lazy_import(node: ast.AST) -> str | None:
    """The module a ``lazy("module")`` call names (:mod:`omniwidget._lazy`: an import made at first use), else None."""
    if not isinstance(node, ast.Call) or len(node.args) != 1 or not isinstance(node.args[0], ast.Constant):
        return None
    called = node.func.id if isinstance(node.func, ast.Name) else getattr(node.func, "attr", None)
    return node.args[0].value if called == "lazy" and isinstance(node.args[0].value, str) else None


def _imports(name: str) -> list[tuple[str, str | None, int]]:
    """``(module imported, name imported from it or None, line)`` for every import of ``name``'s source."""
    path = MODULES[name]
    tree = ast.parse(path.read_text(encoding="utf-8"))
    skip = _type_checking_only(tree)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = []
    for node in ast.walk(tree):
        if getattr(node, "lineno", None) in skip:
            continue
        if isinstance(node, ast.Import):
            found += [(alias.name, None, node.lineno) for alias in node.names]
        elif (lazy := _lazy_import(node)) is not None:
            found.append((lazy, None, node.lineno))
        elif isinstance(node, ast.ImportFrom) and node.module != "__future__":
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                module = ".".join(base + ([node.module] if node.module else []))
            else:
                module = node.module or ""
            for alias in node.names:
                submodule = f"{module}.{alias.name}"
                found.append((submodule, None, node.lineno) if submodule in MODULES else (module, alias.name, node.lineno))
    return found


def _graph() -> dict[str, set[str]]:
    return {name: {m for m, _, _ in _imports(name) if m in MODULES and m != name} for name in MODULES}


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_the_checks_see_the_package():
    graph = _graph()
    assert {"omniwidget.raster.pipeline", "omniwidget.widget.editor", "omniwidget.app.session"} <= set(graph)
    assert "omniwidget.method.constraints" in graph["omniwidget.raster.pipeline"]  # relative imports are resolved
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]  # and a cycle is found


def test_no_import_cycle_between_modules():
    assert _cycles(_graph()) == []


def test_no_private_name_is_imported_from_another_module():
    used = [
        f"{name} (line {line}) imports {imported}.{what}"
        for name in MODULES
        for imported, what, line in _imports(name)
        if what is not None and what.startswith("_") and not what.startswith("__") and imported.startswith("omniwidget")
    ]
    assert used == []


#: The layers and the modules each owns (the longest prefix that names a module decides its layer).
LAYERS: dict[str, tuple[str, ...]] = {
    "plumbing": (
        "omniwidget._version",
        "omniwidget.errors",
        "omniwidget._checks",
        "omniwidget._files",
        "omniwidget._timing",
        "omniwidget._blas",
        "omniwidget._native",
        "omniwidget._numba_kernels",
        "omniwidget._lazy",
    ),
    "sphere": ("omniwidget.sphere",),
    "document": ("omniwidget.document",),
    "method": ("omniwidget.method",),
    "raster": ("omniwidget.raster",),
    "detect": ("omniwidget.detect",),
    "evaluate": ("omniwidget.evaluate",),
    "io": ("omniwidget.io", "omniwidget.data"),
    "app": ("omniwidget.app", "omniwidget.batch"),
    "widget": ("omniwidget.widget",),
    "viz": ("omniwidget.viz",),
    "entry": ("omniwidget", "omniwidget.__main__"),
}

_CORE = ("plumbing", "sphere", "document", "method", "raster")

#: The allowed dependencies, a graph: each layer names every layer it may import (its own layer always).
#: ``detect`` and ``evaluate`` are not siblings: ``evaluate`` stands on ``detect`` because its "suggested"
#: scene family is made of the detector's own lines, and the detector needs no figure or scene. ``io`` only reads
#: and writes, low in the house as ``skimage.io`` is: not the per-pixel engine, whose workflows (video, frames,
#: strips) are applications. ``widget`` and ``viz`` are siblings: neither imports the other.
ALLOWED: dict[str, frozenset[str]] = {
    "plumbing": frozenset(),
    "sphere": frozenset({"plumbing"}),
    "document": frozenset({"plumbing", "sphere"}),
    "method": frozenset({"plumbing", "sphere", "document"}),
    "raster": frozenset({"plumbing", "sphere", "document", "method"}),
    "detect": frozenset(_CORE),
    "evaluate": frozenset({*_CORE, "detect"}),
    "io": frozenset({"plumbing", "sphere", "document", "method"}),
    "app": frozenset({*_CORE, "detect", "evaluate", "io"}),
    "widget": frozenset({*_CORE, "detect", "evaluate", "io", "app"}),
    "viz": frozenset({*_CORE, "detect", "evaluate", "io", "app"}),
    "entry": frozenset(LAYERS) - {"entry"},
}

#: Imports outside the graph that are allowed, each inside a function and for a reason.
EXCEPTIONS = {
    ("omniwidget.raster.pipeline", "omniwidget.evaluate.quality"): "Result.quality measures a warp when first asked",
}


def layer_of(module: str, layers: dict[str, tuple[str, ...]] = LAYERS) -> str | None:
    """The layer whose longest prefix owns ``module``, or None when no layer does."""
    best, owner = None, ""
    for layer, prefixes in layers.items():
        for prefix in prefixes:
            if (module == prefix or module.startswith(prefix + ".")) and len(prefix) > len(owner):
                best, owner = layer, prefix
    return best


def forbidden_imports(
    graph: dict[str, set[str]],
    layers: dict[str, tuple[str, ...]] = LAYERS,
    allowed: dict[str, frozenset[str]] = ALLOWED,
    exceptions: dict[tuple[str, str], str] = EXCEPTIONS,
) -> list[str]:
    """Every import of ``graph`` (module -> modules it imports) that the layer graph ``allowed`` does not allow."""
    found = []
    for name, targets in sorted(graph.items()):
        here = layer_of(name, layers)
        for target in sorted(targets):
            there = layer_of(target, layers)
            if here is None or there is None:
                found.append(f"{name} ({here}) imports {target} ({there}): a module without a layer")
            elif there != here and there not in allowed[here] and (name, target) not in exceptions:
                found.append(f"{name} ({here}) imports {target} ({there}), which {here} may not import")
    return found


def test_the_layer_graph_names_every_layer_and_no_cycle():
    assert set(ALLOWED) == set(LAYERS)
    assert all(allowed <= set(LAYERS) and layer not in allowed for layer, allowed in ALLOWED.items())
    assert _cycles({layer: set(allowed) for layer, allowed in ALLOWED.items()}) == []


def test_every_module_has_a_layer():
    assert [m for m in MODULES if layer_of(m) is None] == []
    assert layer_of("omniwidget.method.bbw") == "method" and layer_of("omniwidget.errors") == "plumbing"
    assert layer_of("omniwidget") == "entry" and layer_of("omniwidget.viz.pane") == "viz"


def test_no_module_imports_a_layer_its_layer_may_not_import():
    assert forbidden_imports(_graph()) == []


def test_the_sphere_document_and_method_layers_import_nothing_above_them_at_all():
    """The paper's maths can be read without the engine, the figures or the apps: not even a lazy import upwards."""
    assert [(a, b) for a, b in EXCEPTIONS if layer_of(a) in ALLOWED["raster"]] == []


def test_the_layer_check_catches_upward_and_sibling_imports():
    """The real check, on a synthetic graph: an upward import and the two pairs of siblings are caught, a downward
    import, an import within a layer and the declared exception are not."""
    graph = {
        "omniwidget.sphere.coords": {"omniwidget.raster.pipeline", "omniwidget.sphere.moebius"},
        "omniwidget.detect.lines": {"omniwidget.evaluate.scenes", "omniwidget.method.constraints"},
        "omniwidget.viz.pane": {"omniwidget.widget.editor", "omniwidget.app.session"},
        "omniwidget.widget.editor": {"omniwidget.viz.pane"},
        "omniwidget.evaluate.scenes": {"omniwidget.detect.lines"},
        "omniwidget.raster.pipeline": {"omniwidget.evaluate.quality"},
        "omniwidget.io.images": {"omniwidget.app.cli", "omniwidget.raster.warping"},
        "elsewhere": {"omniwidget.sphere.coords"},
    }
    found = forbidden_imports(graph)
    assert [line.split(" (")[0] + " -> " + line.split(" imports ")[1].split(" (")[0] for line in found] == [
        "elsewhere -> omniwidget.sphere.coords",
        "omniwidget.detect.lines -> omniwidget.evaluate.scenes",
        "omniwidget.io.images -> omniwidget.app.cli",
        "omniwidget.io.images -> omniwidget.raster.warping",
        "omniwidget.sphere.coords -> omniwidget.raster.pipeline",
        "omniwidget.viz.pane -> omniwidget.widget.editor",
        "omniwidget.widget.editor -> omniwidget.viz.pane",
    ]
    assert forbidden_imports(graph, exceptions={}) == sorted(
        [*found, "omniwidget.raster.pipeline (raster) imports omniwidget.evaluate.quality (evaluate), which raster may not import"]
    )


def test_a_lazy_import_is_an_import_and_an_upward_one_is_caught(tmp_path, monkeypatch):
    """``lazy("module")`` (omniwidget._lazy) is read as an import of that module: the graph sees it and the real check
    refuses a lazy import upwards as it refuses an import statement."""
    source = tmp_path / "fake.py"
    source.write_text('from .._lazy import lazy\n\ncv2 = lazy("cv2")\npipeline = lazy("omniwidget.raster.pipeline")\n')
    monkeypatch.setitem(MODULES, "omniwidget.sphere.fake", source)
    assert _imports("omniwidget.sphere.fake") == [("omniwidget._lazy", "lazy", 1), ("cv2", None, 3), ("omniwidget.raster.pipeline", None, 4)]
    graph = {"omniwidget.sphere.fake": {m for m, _, _ in _imports("omniwidget.sphere.fake") if m in MODULES}}
    assert forbidden_imports(graph) == [
        "omniwidget.sphere.fake (sphere) imports omniwidget.raster.pipeline (raster), which sphere may not import"
    ]
