"""Lazy imports in one mechanism (omniwidget._lazy): a module named at the top, imported when first used.

The package keeps ``import omniwidget`` light with :func:`omniwidget._lazy.lazy` rather than with
imports written inside functions; the last test counts those and fails on a new one.
"""

from __future__ import annotations

import ast
import builtins
import subprocess
import sys
import textwrap
import threading
from pathlib import Path

import pytest

from omniwidget._lazy import LazyModule, lazy, resolve

PACKAGE = Path(__file__).resolve().parents[1] / "omniwidget"


def _run(code: str) -> str:
    return subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True, text=True, check=True).stdout.strip()


def test_a_lazy_module_is_imported_at_its_first_attribute_and_is_the_module():
    out = _run(
        """
        import sys
        from omniwidget._lazy import lazy, resolve
        colorsys = lazy("colorsys")
        before = "colorsys" in sys.modules
        value = colorsys.rgb_to_hsv(1.0, 0.0, 0.0)
        import colorsys as real
        print(before, "colorsys" in sys.modules, value, resolve(colorsys) is real, colorsys.rgb_to_hsv is real.rgb_to_hsv)
        """
    )
    assert out == "False True (0.0, 1.0, 1.0) True True"


def test_a_submodule_loads_its_package_only_when_used():
    out = _run(
        """
        import sys
        from omniwidget._lazy import lazy
        sparse = lazy("scipy.sparse")
        before = [m for m in ("scipy", "scipy.sparse") if m in sys.modules]
        print(before, sparse.eye(3).shape, [m for m in ("scipy", "scipy.sparse") if m in sys.modules])
        """
    )
    assert out == "[] (3, 3) ['scipy', 'scipy.sparse']"


def test_a_missing_module_names_itself_and_what_to_install(monkeypatch):
    igl = lazy("igl")  # nothing happens yet
    monkeypatch.setitem(sys.modules, "igl", None)  # as if libigl were not installed
    with pytest.raises(ModuleNotFoundError, match=r"igl is needed for this and is not installed \(pip install libigl\)") as info:
        igl.bbw  # noqa: B018 - the first use imports
    assert info.value.name == "igl"
    with pytest.raises(ModuleNotFoundError, match=r"no_such_module_here.sub is needed .*\(pip install no_such_module_here\)"):
        resolve(lazy("no_such_module_here.sub"))


def test_a_module_whose_own_import_fails_keeps_its_error(tmp_path, monkeypatch):
    (tmp_path / "broken_for_lazy.py").write_text("import missing_inside_broken\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(ModuleNotFoundError, match="missing_inside_broken") as info:
        lazy("broken_for_lazy").anything  # noqa: B018
    assert info.value.name == "missing_inside_broken" and "pip install" not in str(info.value)
    monkeypatch.delitem(sys.modules, "broken_for_lazy", raising=False)


def test_a_module_replaced_in_sys_modules_is_the_one_used(monkeypatch):
    """As an import statement inside a function: each use looks the module up again (the tests of libigl's two APIs rely on it)."""
    proxy = lazy("colorsys")
    fake = type(sys)("colorsys")
    fake.rgb_to_hsv = lambda *rgb: "fake"
    monkeypatch.setitem(sys.modules, "colorsys", fake)
    assert proxy.rgb_to_hsv(1, 0, 0) == "fake" and resolve(proxy) is fake


def test_threads_using_a_module_first_at_once_import_it_once(tmp_path, monkeypatch):
    (tmp_path / "slow_for_lazy.py").write_text("import time\nimport builtins\nbuiltins.slow_for_lazy_runs = getattr(builtins, 'slow_for_lazy_runs', 0) + 1\ntime.sleep(0.2)\nVALUE = 7\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    proxy, seen = lazy("slow_for_lazy"), []
    threads = [threading.Thread(target=lambda: seen.append(proxy.VALUE)) for _ in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert seen == [7] * 8 and builtins.slow_for_lazy_runs == 1  # every thread saw the whole module, run once
    del builtins.slow_for_lazy_runs
    monkeypatch.delitem(sys.modules, "slow_for_lazy", raising=False)


def test_a_name_that_is_no_module_name_is_refused_and_repr_says_the_state():
    for bad in ("", "a..b", "1cv2", "cv2 "):
        with pytest.raises(ValueError, match="dotted identifiers"):
            lazy(bad)
    with pytest.raises(TypeError, match="module or a lazy"):
        resolve("cv2")
    assert isinstance(lazy("json"), LazyModule) and repr(lazy("json")) == "<lazy module 'json' (imported)>"
    assert repr(lazy("no_such_module_here")) == "<lazy module 'no_such_module_here' (not imported yet)>"


def test_the_package_attaches_its_public_names_when_first_read():
    out = _run(
        """
        import sys, omniwidget as ow
        loaded = "omniwidget.raster.pipeline" in sys.modules
        warp = ow.warp
        from omniwidget.raster.pipeline import warp as real
        print(loaded, warp is real, "warp" in dir(ow), all(hasattr(ow, n) for n in ow.__all__ if n != "Editor"))
        try:
            ow.no_such_name
        except AttributeError as e:
            print(e)
        """
    )
    assert out.splitlines() == ["False True True True", "module 'omniwidget' has no attribute 'no_such_name'"]


# --- no import statement inside a function --------------------------------------------------------------------------------
def _local_imports(path: Path) -> list[int]:
    """Lines of the import statements inside a function of ``path`` (under ``if TYPE_CHECKING`` or not)."""
    found: list[int] = []

    def visit(node: ast.AST, inside: bool) -> None:
        for child in ast.iter_child_nodes(node):
            if inside and isinstance(child, (ast.Import, ast.ImportFrom)):
                found.append(child.lineno)
            visit(child, inside or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)))

    visit(ast.parse(path.read_text(encoding="utf-8")), False)
    return found


def test_no_import_inside_a_function():
    """A dependency is written at the top of its module, as ``import`` or as ``lazy("module")`` (omniwidget._lazy)."""
    found = {str(p.relative_to(PACKAGE)): lines for p in sorted(PACKAGE.rglob("*.py")) if (lines := _local_imports(p))}
    assert found == {}, f"imports inside functions (name the module at the top, with omniwidget._lazy.lazy if it is heavy): {found}"


def test_the_local_import_counter_counts(tmp_path):
    source = tmp_path / "m.py"
    source.write_text("import os\n\n\ndef f():\n    import json\n    if os:\n        from os import path\n\n\nclass C:\n    def g(self):\n        import re\n")
    assert _local_imports(source) == [5, 7, 12]
