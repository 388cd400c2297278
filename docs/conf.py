"""Sphinx configuration: the API reference is built from the docstrings (``make docs``; warnings fail the build)."""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

project = "fem_grasp"
author = "the fem_grasp developers"
copyright = "2026, the fem_grasp developers"  # noqa: A001 - Sphinx's name
extensions = ["sphinx.ext.autodoc", "sphinx.ext.napoleon", "sphinx.ext.mathjax", "myst_parser"]
source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
exclude_patterns = ["_build"]
root_doc = "index"
autodoc_member_order = "bysource"
autodoc_typehints = "description"
autodoc_default_options = {"members": True, "show-inheritance": True}
# The optional dependencies are not needed to document the package.
autodoc_mock_imports = ["gmsh", "pyvista", "numba", "sksparse", "matplotlib", "tqdm", "meshio", "dolfinx"]
napoleon_numpy_docstring = True
napoleon_google_docstring = False
napoleon_use_rtype = False
napoleon_use_ivar = True  # "Attributes" sections as fields of the class, not as attributes beside the dataclass fields
myst_heading_anchors = 3
html_theme = "alabaster"
# The docstrings write "name : (m, 3) forces …" on one line; napoleon reads the description as a type and links
# its words, and a word naming several attributes (positions) is ambiguous: not an error of the docstring.
suppress_warnings = ["myst.header", "ref.python"]


def _escape_norm_bars(app, what, name, obj, options, lines):  # noqa: ARG001 - Sphinx's signature
    """Docstrings write norms as |f_t|; reStructuredText would read |…| as a substitution."""
    for i, line in enumerate(lines):
        lines[i] = line.replace("|", r"\|")


def setup(app):
    app.connect("autodoc-process-docstring", _escape_norm_bars, priority=400)
