import subprocess
import sys
from pathlib import Path

HEAVY = ["ipywidgets", "anywidget", "ipycanvas", "pyvista", "vtk", "matplotlib", "IPython", "cv2", "scipy", "igl"]
#: Every optional or heavy third-party module the package uses: each is named with omniwidget._lazy.lazy and loads at first use.
OPTIONAL = [*HEAVY, "numba", "llvmlite", "skimage", "PIL", "av", "pyvips", "tifffile", "cvxpy", "distributed", "trame_vtk", "threadpoolctl"]
PACKAGE = Path(__file__).resolve().parents[1] / "omniwidget"


def test_import_loads_no_widget_plotting_or_imaging_stack():
    code = f"import sys, omniwidget, omniwidget.app.cli; print(' '.join(m for m in {HEAVY!r} if m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()
    assert out == "", f"import omniwidget loaded: {out}"


def test_every_module_imports_without_its_optional_dependencies():
    """Each module but the notebook widget (anywidget is what it is) and the numba kernels (numba is what they are) imports
    with none of them loaded: a dependency is paid for where it is used, never by importing a module that has it."""
    names = sorted(
        ".".join(("omniwidget", *p.relative_to(PACKAGE).with_suffix("").parts)).removesuffix(".__init__") for p in PACKAGE.rglob("*.py")
    )
    names = [n for n in names if not n.startswith(("omniwidget.widget", "omniwidget._numba_kernels", "omniwidget.__main__"))]
    assert "omniwidget.app.session" in names and "omniwidget.viz.pane" in names and "omniwidget.method.bbw" in names
    code = f"import importlib, sys\nfor n in {names!r}:\n    importlib.import_module(n)\nprint(' '.join(m for m in {OPTIONAL!r} if m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()
    assert out == "", f"importing the package's modules loaded: {out}"
