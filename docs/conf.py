"""Sphinx configuration of the documentation site (``python -m sphinx -W docs docs/_build/html``).

Pages are Markdown (MyST); the API reference is generated from the numpydoc docstrings; the gallery is generated
from the figure scripts in ``scripts/`` (``docs/_ext/gallery.py``). ``tests/test_docs.py`` builds the site with
warnings as errors.
"""
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, os.pardir))
sys.path.insert(0, os.path.join(HERE, "_ext"))

import sonar_embree  # noqa: E402

project = "sonar_embree"
author = "the sonar_embree developers"
copyright = "2026, the sonar_embree developers"
release = version = sonar_embree.__version__

extensions = ["sphinx.ext.autodoc", "sphinx.ext.autosummary", "sphinx.ext.mathjax", "sphinx.ext.viewcode",
              "numpydoc", "myst_parser", "gallery"]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
exclude_patterns = ["_build", "Thumbs.db", ".DS_Store", "api/generated/*.md"]
root_doc = "index"

myst_heading_anchors = 3
myst_enable_extensions = ["colon_fence"]
suppress_warnings = ["myst.header"]   # physics.md numbers its sections for citation, not for nesting

autosummary_generate = True
autosummary_imported_members = False
autodoc_default_options = {"members": True, "show-inheritance": False}
autodoc_typehints = "none"               # numpydoc's Parameters sections state types and units
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_validation_checks = set()

html_theme = "pydata_sphinx_theme"
html_title = f"sonar_embree {release}"
html_theme_options = {"navigation_with_keys": False, "show_toc_level": 2}
html_static_path = []
templates_path = ["_templates"]


def _plain_bars(app, what, name, obj, options, lines):
    """Docstrings write |x| for magnitudes; reST would read a substitution. Escape bars outside ``literals``."""
    for i, line in enumerate(lines):
        parts = line.split("``")
        lines[i] = "``".join(p if k % 2 else p.replace("|", "\\|") for k, p in enumerate(parts))


def setup(app):
    app.connect("autodoc-process-docstring", _plain_bars, priority=400)
