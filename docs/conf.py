"""Sphinx configuration for the omniwidget documentation site.

Build it (offline, warnings as errors) from the repository's root::

    python -m sphinx -W --keep-going -b html docs docs/_build/html

What the build does besides reading the pages here (``docs/_ext/omniwidget_docs.py``):

- copies ``notebooks/*.ipynb`` into ``docs/notebooks/`` (git-ignored) and executes them with
  myst-nb, so their figures are on the pages while the repository keeps them without outputs;
- makes the gallery's before/after images from ``docs/gallery/*.json`` with ``omniwidget.warp``
  and writes them into the build's ``_static/gallery/`` (nothing generated is committed);
- runs ``python -m omniwidget ... --help`` for the command-line page.

Nothing is downloaded: no intersphinx, no remote images; the theme's fonts and icons ship
with it.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent

# The package documented is this checkout's, in Sphinx and in the kernels that run the notebooks.
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(DOCS / "_ext"))
os.environ["PYTHONPATH"] = os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH", "")) if p)

import omniwidget  # noqa: E402

project = "omniwidget"
author = "omniwidget developers"
copyright = "omniwidget developers"
release = omniwidget.__version__
version = release

extensions = [
    "myst_nb",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "numpydoc",
    "omniwidget_docs",
]

source_suffix = {".rst": "restructuredtext", ".md": "myst-nb", ".ipynb": "myst-nb"}
root_doc = "index"
exclude_patterns = [
    "_build",
    "README.md",
    "images",
    "gallery/*.json",
    "**.ipynb_checkpoints",
    "jupyter_execute",
]
templates_path: list[str] = []
html_static_path = ["_static"]
html_css_files = ["omniwidget.css"]

# --- MyST and myst-nb: the notebooks run at build time, every build, nothing cached -------------
myst_enable_extensions = ["dollarmath", "colon_fence", "deflist"]
myst_heading_anchors = 3
nb_execution_mode = "force"  # run each notebook when it is (re)read; no jupyter-cache
nb_execution_in_temp = True  # the editor's autosave and other files go to a temporary folder
nb_execution_timeout = 240  # per cell, as tests/test_notebooks.py
nb_execution_raise_on_error = True  # a failing cell fails the build
nb_execution_show_tb = True
nb_merge_streams = True
# Interactive widgets (the editor, sliders, the ipycanvas view) need a live kernel: the pages
# load no widget JavaScript (none is fetched from a CDN) and show a note in their place
# (omniwidget_docs.widgets_as_notes).
nb_ipywidgets_js: dict[str, dict[str, str]] = {}
# Notebook 04's comparison cells also display their figures as application/json, for
# tests/test_notebooks.py to read; myst-nb has no renderer for it and says so while it reads
# the cell, whatever the priorities. The pages show the same tables as HTML.
suppress_warnings = ["mystnb.unknown_mime_type"]

# --- the API reference: autodoc + numpydoc ----------------------------------------------------
autodoc_default_options = {
    "members": True,
    "undoc-members": True,
    "member-order": "bysource",
    "show-inheritance": True,
}
autodoc_typehints = "none"  # the numpydoc sections give the types, shapes and units
autodoc_inherit_docstrings = False
autosummary_generate = False
numpydoc_show_class_members = False  # autodoc lists the members
numpydoc_class_members_toctree = False
numpydoc_attributes_as_param_list = True
numpydoc_xref_param_type = False
numpydoc_validation_checks: set[str] = set()

# --- HTML: the PyData theme, with nothing fetched from the web ---------------------------------
html_theme = "pydata_sphinx_theme"
html_title = f"omniwidget {release}"
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "secondary_sidebar_items": ["page-toc"],
    "footer_start": ["copyright"],
    "footer_end": ["sphinx-version", "theme-version"],
}
# pages with no pages under them need no section navigation
html_sidebars = {
    page: []
    for page in (
        "index",
        "install",
        "editor",
        "cli",
        "library",
        "detection",
        "video",
        "large",
        "gallery/index",
        "handles-file",
        "conventions",
        "architecture",
        "default-mode",
        "inside",
        "reliability",
        "packages",
        "paper-figures",
        "about",
    )
}
html_show_sourcelink = False
html_copy_source = False
