"""Shared fixtures: seeded randomness and small helpers that speak [lon, lat] in degrees."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from omniwidget.sphere import coords

SHARED_DATA = Path(__file__).resolve().parents[2] / "shared" / "data"


# hypothesis: the same draws on every run and no example database, so a failure is reproduced by running the
# test again (tests/test_robustness.py, test_handles.py, test_cli.py). OMNIWIDGET_HYPOTHESIS=hunt draws new
# examples each run, for a longer hunt (with OMNIWIDGET_FUZZ=N); it writes no database either.
try:
    from hypothesis import settings
except ImportError:  # the test extra brings it
    pass
else:
    settings.register_profile("omniwidget", derandomize=True, database=None, print_blob=True)
    settings.register_profile("hunt", derandomize=False, database=None, print_blob=True)
    settings.load_profile(os.environ.get("OMNIWIDGET_HYPOTHESIS", "omniwidget"))


@pytest.fixture(scope="session", autouse=True)
def _no_autosave_by_default():
    """Editors made by tests (and the kernels and Jupyter servers they start) autosave only where a test asks them to.

    Without this, ``Editor(ow.sample_path())`` would write its autosave into the working
    folder and the next test's editor would start from it. The variable is set through a
    ``MonkeyPatch`` and restored when the session ends; a test that wants the default
    undoes it with its own ``monkeypatch.delenv`` (``tests/test_notebooks.py`` runs the
    notebooks with autosave on, each in a folder of its own, and checks the file).
    """
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("OMNIWIDGET_AUTOSAVE", "0")
        yield


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20201121)


def random_lonlat(rng: np.random.Generator, n: int) -> np.ndarray:
    """Points uniformly distributed on the sphere, as [lon, lat] degrees, shape (n, 2)."""
    xyz = rng.normal(size=(n, 3))
    return coords.xyz_to_lonlat(xyz / np.linalg.norm(xyz, axis=1, keepdims=True))


def offset(lonlat, bearing_deg: float, distance_deg: float) -> np.ndarray:
    """The point ``distance_deg`` away from ``lonlat`` heading ``bearing_deg`` (0 east, 90 north)."""
    p = coords.lonlat_to_xyz(lonlat)
    east, north = coords.local_frame(lonlat)
    b, d = np.radians(bearing_deg), np.radians(distance_deg)
    return coords.xyz_to_lonlat(np.cos(d) * p + np.sin(d) * (np.cos(b) * east + np.sin(b) * north))


#: The front ends every real-browser test runs in: ``jupyter_server`` param -> test id.
JUPYTER_FRONTENDS = {"lab": "jupyterlab", "notebook": "notebook7"}


@pytest.fixture(scope="session", params=list(JUPYTER_FRONTENDS), ids=list(JUPYTER_FRONTENDS.values()))
def jupyter_server(request):
    """A Jupyter server for the real-browser tests (tests/browser_harness.py), once per front end.

    Parametrized over JupyterLab (id ``jupyterlab``) and Jupyter Notebook 7 (id ``notebook7``):
    every test using it runs in both, e.g. ``test_draw_rectify_turn_undo[notebook7]``.  pytest
    groups the tests by front end, so each session starts one server per front end; a test
    reads which one from ``jupyter_server.frontend.key`` (``"lab"`` or ``"notebook"``).
    """
    from tests import browser_harness as bh

    bh.require_browser(request.param)
    with bh.JupyterServer(name=f"browser-tests-{JUPYTER_FRONTENDS[request.param]}", frontend=request.param) as server:
        yield server


@pytest.fixture(scope="session")
def browser():
    """Debian's headless Chromium driven by Playwright, shared by the real-browser tests."""
    from tests import browser_harness as bh

    bh.require_browser()
    with bh.launch_browser() as browser:
        yield browser


def pytest_collection_modifyitems(config, items):
    """The real-browser tests (JupyterLab and Notebook 7 each) are slow too: the fast loop, ``-m "not slow"``, leaves them out."""
    for item in items:
        if item.get_closest_marker("browser") is not None:
            item.add_marker(pytest.mark.slow)
