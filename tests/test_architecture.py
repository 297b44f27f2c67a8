"""The package's structure: layers that import only downwards, no import cycle, no private name used across modules.

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


#: The layers from the bottom up (README, Layout): a module imports its own layer and the ones below.
LAYERS: list[tuple[str, tuple[str, ...]]] = [
    (
        "plumbing",
        (
            "omniwidget._version",
            "omniwidget.errors",
            "omniwidget._checks",
            "omniwidget._files",
            "omniwidget._timing",
            "omniwidget._blas",
            "omniwidget._native",
            "omniwidget._numba_kernels",
        ),
    ),
    ("sphere", ("omniwidget.sphere",)),
    ("document", ("omniwidget.document",)),
    ("method", ("omniwidget.method",)),
    ("raster", ("omniwidget.raster",)),
    ("detect", ("omniwidget.detect",)),  # below evaluate: the "suggested" scene family is the detector's own lines
    ("evaluate", ("omniwidget.evaluate", "omniwidget.evaluate.content_preserving")),
    ("io", ("omniwidget.io", "omniwidget.data")),
    ("app", ("omniwidget.app", "omniwidget.batch")),
    ("widget and pane", ("omniwidget.widget", "omniwidget.viz", "omniwidget.__main__")),
    ("the package's names", ("omniwidget",)),
]

#: Imports upwards that are allowed, each inside a function and for a reason.
UPWARDS = {
    ("omniwidget.raster.pipeline", "omniwidget.evaluate.quality"): "Result.quality measures a warp when first asked",
}


def _layer(module: str) -> int:
    """Index in :data:`LAYERS` of the longest prefix that owns ``module``."""
    best, owner = -1, ""
    for i, (_, prefixes) in enumerate(LAYERS):
        for prefix in prefixes:
            if (module == prefix or module.startswith(prefix + ".")) and len(prefix) > len(owner):
                best, owner = i, prefix
    return best


def test_every_module_has_a_layer():
    assert [m for m in MODULES if _layer(m) < 0] == []
    assert _layer("omniwidget.method.bbw") == 3 and _layer("omniwidget.errors") == 0 and _layer("omniwidget") == len(LAYERS) - 1


def test_no_layer_imports_a_layer_above_it():
    upward = [
        f"{name} ({LAYERS[_layer(name)][0]}) imports {target} ({LAYERS[_layer(target)][0]})"
        for name, targets in _graph().items()
        for target in sorted(targets)
        if _layer(target) > _layer(name) and (name, target) not in UPWARDS
    ]
    assert upward == []


def test_the_sphere_document_and_method_layers_import_nothing_above_them_at_all():
    """The paper's maths can be read without the engine, the figures or the apps: not even a lazy import upwards."""
    method = _layer("omniwidget.method")
    assert [(a, b) for a, b in UPWARDS if _layer(a) <= method] == []


def test_the_layer_check_catches_an_upward_import(tmp_path):
    graph = {"omniwidget.sphere.coords": {"omniwidget.raster.pipeline"}}
    assert [t for n, ts in graph.items() for t in ts if _layer(t) > _layer(n)] == ["omniwidget.raster.pipeline"]
