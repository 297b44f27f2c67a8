"""The package's metadata: license (PEP 639), citation, and dependency ranges that stop at what was tested.

Nothing is built here: pyproject.toml, LICENSE and CITATION.cff are read as text.
"""

from __future__ import annotations

import importlib.metadata
import re
import sys
from pathlib import Path

import pytest

import omniwidget

tomllib = pytest.importorskip("tomllib") if sys.version_info >= (3, 11) else pytest.importorskip("tomli")
requirements = pytest.importorskip("packaging.requirements")
version = pytest.importorskip("packaging.version")
specifiers = pytest.importorskip("packaging.specifiers")

ROOT = Path(__file__).resolve().parents[1]
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
PROJECT = PYPROJECT["project"]
PAPER_TITLE = "Bounded Biharmonic Blending of Möbius Transformations for Flexible Omnidirectional Image Rectification"
#: The developers' extras (tests, documentation): their tools are not bounded above, so CI meets their new releases.
DEVELOPER_EXTRAS = {"test", "docs"}


def _user_requirements() -> list:
    """What a user's install can bring: the dependencies and every extra but the developers' (the package's own extras left out)."""
    specs = list(PROJECT["dependencies"])
    for extra, items in PROJECT["optional-dependencies"].items():
        if extra not in DEVELOPER_EXTRAS:
            specs += items
    reqs = [requirements.Requirement(s) for s in specs]
    return [r for r in reqs if r.name != PROJECT["name"]]


def _requirement(name: str):
    found = {str(r.specifier) for r in _user_requirements() if r.name == name}
    assert len(found) == 1, (name, found)  # one range, wherever it is listed
    return requirements.Requirement(f"{name}{found.pop()}")


def _citation() -> dict:
    """CITATION.cff as data: with PyYAML when it is there, else the few top-level keys read from the text."""
    text = (ROOT / "CITATION.cff").read_text(encoding="utf-8")
    try:
        import yaml
    except ImportError:
        data: dict = {m[1]: m[2].strip().strip("\"'") for m in re.finditer(r"^([a-z-]+):[ \t]*(.*)$", text, re.M)}
        data["preferred-citation"] = {"title": PAPER_TITLE} if "preferred-citation:" in text and PAPER_TITLE.split()[0] in text else {}
        return data
    return yaml.safe_load(text)


def test_the_license_is_a_pep_639_expression_with_its_file():
    assert PROJECT["license"] == "BSD-3-Clause"
    assert PROJECT["license-files"] == ["LICENSE"]
    for pattern in PROJECT["license-files"]:
        assert list(ROOT.glob(pattern)), pattern
    text = (ROOT / "LICENSE").read_text(encoding="utf-8")
    assert text.startswith("BSD 3-Clause License") and "Copyright (c) 2026, omniwidget developers" in text
    assert "Neither the name of the copyright holder" in text  # the third clause
    assert not [c for c in PROJECT["classifiers"] if c.startswith("License ::")]  # PEP 639: the expression, not a classifier
    (hatchling,) = [requirements.Requirement(r) for r in PYPROJECT["build-system"]["requires"] if r.startswith("hatchling")]
    assert not hatchling.specifier.contains("1.26.3") and hatchling.specifier.contains("1.27.0")  # license-files needs 1.27


def test_the_classifiers_say_the_pythons_that_requires_python_allows():
    allowed = specifiers.SpecifierSet(PROJECT["requires-python"])
    pythons = [c.rsplit(" :: ", 1)[1] for c in PROJECT["classifiers"] if re.fullmatch(r"Programming Language :: Python :: 3\.\d+", c)]
    assert pythons == ["3.10", "3.11", "3.12"]
    assert all(allowed.contains(f"{p}.0") for p in pythons) and not allowed.contains("3.9.0")
    for prefix in ("Development Status ::", "Intended Audience ::", "Operating System ::", "Topic ::"):
        assert any(c.startswith(prefix) for c in PROJECT["classifiers"]), prefix
    assert "Framework :: Jupyter :: JupyterLab" in PROJECT["classifiers"]


def test_the_citation_names_this_version_and_the_paper():
    cff = _citation()
    assert str(cff["cff-version"]) == "1.2.0"
    assert cff["title"] == "omniwidget" and cff["license"] == PROJECT["license"]
    assert str(cff["version"]) == omniwidget.__version__
    for key in ("message", "authors"):
        assert cff.get(key), key
    paper = cff["preferred-citation"]
    assert " ".join(str(paper["title"]).split()) == PAPER_TITLE
    if "authors" in paper:  # read with PyYAML
        assert [a["family-names"] for a in paper["authors"]] == ["Souto Ferreira", "Sacht"] and paper["year"] == 2020
        assert "doi" not in paper and "doi" not in cff  # none is known (the paper's text gives none)


def test_the_citation_names_the_paper_as_the_shared_text_does():
    readme = ROOT.parent / "shared" / "paper" / "README.md"
    if not readme.exists():
        pytest.skip("shared/paper is not beside this checkout")
    assert PAPER_TITLE in " ".join(readme.read_text(encoding="utf-8").split())


def test_every_dependency_stops_below_an_untested_version():
    unbounded = [str(r) for r in _user_requirements() if not any(s.operator in ("<", "<=", "==", "~=") for s in r.specifier)]
    assert unbounded == []
    for r in _user_requirements():
        assert any(s.operator == ">=" for s in r.specifier), f"{r}: no lower bound"


def test_trame_vtk_is_pinned_to_the_minor_version_tested():
    """omniwidget/viz/pane.py imports trame-vtk's serializers, which are not its public API."""
    assert "trame_vtk.modules.vtk.serializers" in (ROOT / "omniwidget" / "viz" / "pane.py").read_text(encoding="utf-8")
    spec = _requirement("trame-vtk").specifier
    (low,) = [version.Version(s.version) for s in spec if s.operator == ">="]
    (high,) = [version.Version(s.version) for s in spec if s.operator == "<"]
    assert (high.major, high.minor) == (low.major, low.minor + 1), str(spec)


def test_both_opencv_lines_are_allowed():
    spec = _requirement("opencv-python-headless").specifier
    assert spec.contains("4.13.0.92") and spec.contains("4.14.0.94") and spec.contains("5.0.0.93")
    assert not spec.contains("4.12.0.88")  # writes a float32 RGB TIFF lossily (tests/test_io.py), and below 4.10 needs numpy 1
    assert not spec.contains("6.0.0")
    run = (ROOT / ".ci" / "run").read_text(encoding="utf-8")
    assert "--system-site-packages" in run and "opencv-python-headless>=4.13,<5" in run and "opencv-python-headless>=5,<6" in run


def test_what_is_installed_is_in_the_ranges():
    """The versions this environment tests are ones the ranges allow (packages not installed here are skipped)."""
    outside = []
    for r in _user_requirements():
        if r.marker is not None and not r.marker.evaluate():
            continue
        try:
            installed = importlib.metadata.version(r.name)
        except importlib.metadata.PackageNotFoundError:
            continue
        if not r.specifier.contains(installed, prereleases=True):
            outside.append(f"{r.name} {installed} not in {r.specifier}")
    assert outside == []


def test_the_schema_checker_is_in_the_test_extra():
    names = {requirements.Requirement(s).name for s in PROJECT["optional-dependencies"]["test"]}
    assert "jsonschema" in names
