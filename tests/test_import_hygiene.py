import subprocess
import sys

HEAVY = ["ipywidgets", "anywidget", "ipycanvas", "pyvista", "vtk", "matplotlib", "IPython", "cv2", "scipy", "igl"]


def test_import_loads_no_widget_plotting_or_imaging_stack():
    code = f"import sys, omniwidget, omniwidget.app.cli; print(' '.join(m for m in {HEAVY!r} if m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()
    assert out == "", f"import omniwidget loaded: {out}"
