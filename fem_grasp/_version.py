"""The version of fem_grasp: the installed distribution's, or the source tree's ``pyproject.toml``.

An installed fem_grasp (a wheel, ``pip install .``) reads its version from its metadata
(:mod:`importlib.metadata`).  A source checkout imported without being installed has no metadata of its
own, and an environment may hold another fem_grasp's: there the ``pyproject.toml`` beside the package
decides.
"""

from __future__ import annotations

import importlib.metadata
import re
from pathlib import Path

__all__ = ["version"]

#: The distribution's name (``pip install fem_grasp``).
DISTRIBUTION = "fem_grasp"


def _source_tree_version() -> str | None:
    """The ``[project] version`` of the pyproject.toml beside the package, when it is fem_grasp's; else None."""
    pyproject = Path(__file__).resolve().parents[1] / "pyproject.toml"
    try:
        text = pyproject.read_text(encoding="utf-8")
    except OSError:
        return None
    project = re.search(r"^\[project\]\s*$(.*?)(?=^\[|\Z)", text, re.M | re.S)
    if project is None or not re.search(rf'^name\s*=\s*"{DISTRIBUTION}"\s*$', project.group(1), re.M):
        return None
    found = re.search(r'^version\s*=\s*"([^"]+)"\s*$', project.group(1), re.M)
    return found.group(1) if found else None


def version() -> str:
    """fem_grasp's version string (``"0.1.0"``); ``"unknown"`` when neither source says.

    A source tree's ``pyproject.toml`` comes first (the code imported is that tree's, whatever is installed),
    then the installed distribution's metadata.
    """
    found = _source_tree_version()
    if found:
        return found
    try:
        return importlib.metadata.version(DISTRIBUTION)
    except importlib.metadata.PackageNotFoundError:
        return "unknown"
