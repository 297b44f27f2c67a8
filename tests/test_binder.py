"""binder/ installs what the notebooks need, in the ranges pyproject.toml allows."""

import sys
from pathlib import Path

import pytest

# Python 3.11 has tomllib; on 3.10, the floor pyproject.toml states, the same parser as the tomli package
tomllib = pytest.importorskip("tomllib") if sys.version_info >= (3, 11) else pytest.importorskip("tomli")
requirements = pytest.importorskip("packaging.requirements")

ROOT = Path(__file__).resolve().parents[1]


def _extras(project: dict, name: str) -> list[str]:
    """An extra's requirements, with the package's own extras (``omniwidget[a,b]``) expanded."""
    out = []
    for spec in project["optional-dependencies"][name]:
        req = requirements.Requirement(spec)
        if req.name == project["name"]:
            for extra in sorted(req.extras):
                out += _extras(project, extra)
        else:
            out.append(spec)
    return out


def test_binder_requirements_are_the_packages_and_the_notebook_extras():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    wanted = {}
    for spec in [
        *project["dependencies"],
        *_extras(project, "notebooks"),
        *_extras(project, "pane-html"),
        *_extras(project, "fast"),
        "jupyterlab>=4.0",
    ]:
        req = requirements.Requirement(spec)
        wanted[req.name] = str(req.specifier)
    lines = [line.split("#")[0].strip() for line in (ROOT / "binder" / "requirements.txt").read_text().splitlines()]
    listed = {req.name: str(req.specifier) for req in map(requirements.Requirement, filter(None, lines))}
    assert listed == wanted
    test_extra = {requirements.Requirement(s).name: str(requirements.Requirement(s).specifier) for s in _extras(project, "test")}
    assert test_extra["libigl"] == wanted["libigl"] and test_extra["jupyterlab"] == wanted["jupyterlab"]


def test_binder_post_build_installs_the_package():
    post_build = ROOT / "binder" / "postBuild"
    assert post_build.stat().st_mode & 0o111, "postBuild must be executable"
    assert "pip install --no-deps ." in post_build.read_text()
