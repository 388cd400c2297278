"""Sphinx configuration: the user guide (docs/*.md, MyST) and the API reference from the docstrings
(``make docs``; warnings fail the build).

The command-line reference (docs/cli.md) is generated from :func:`fem_grasp.cli.build_parser` at every build
(:func:`write_cli_reference`), so it cannot drift from the options the command takes.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

project = "fem_grasp"
author = "the fem_grasp developers"
copyright = "2026, the fem_grasp developers"  # noqa: A001 - Sphinx's name
extensions = ["sphinx.ext.autodoc", "sphinx.ext.napoleon", "sphinx.ext.mathjax", "myst_parser"]
source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
exclude_patterns = ["_build", "_generated"]
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

#: Width the generated help is wrapped to (argparse reads $COLUMNS).
CLI_HELP_WIDTH = 100


def _escape_norm_bars(app, what, name, obj, options, lines):  # noqa: ARG001 - Sphinx's signature
    """Docstrings write norms as |f_t|; reStructuredText would read |…| as a substitution."""
    for i, line in enumerate(lines):
        lines[i] = line.replace("|", r"\|")


def cli_reference() -> str:
    """The ``--help`` of ``fem-grasp`` and of each of its subcommands, as Markdown sections."""
    old = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = str(CLI_HELP_WIDTH)
    try:
        from fem_grasp.cli import build_parser

        parser = build_parser()
        parts = ["## fem-grasp", "", "```text", parser.format_help().rstrip(), "```", ""]
        for action in parser._actions:  # argparse keeps the subcommands in its one _SubParsersAction
            if isinstance(action, argparse._SubParsersAction):
                for name, sub in action.choices.items():
                    parts += [f"## fem-grasp {name}", "", "```text", sub.format_help().rstrip(), "```", ""]
    finally:
        if old is None:
            os.environ.pop("COLUMNS", None)
        else:
            os.environ["COLUMNS"] = old
    return "\n".join(parts)


def write_cli_reference(app) -> None:
    """Write docs/_generated/cli_reference.md (included by cli.md) before the sources are read."""
    out = Path(app.srcdir) / "_generated" / "cli_reference.md"
    out.parent.mkdir(exist_ok=True)
    text = cli_reference()
    if not out.exists() or out.read_text(encoding="utf-8") != text:  # unchanged: keep the build incremental
        out.write_text(text, encoding="utf-8")


def setup(app):
    app.connect("autodoc-process-docstring", _escape_norm_bars, priority=400)
    app.connect("builder-inited", write_cli_reference)
