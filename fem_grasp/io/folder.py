"""Output folders: ``--out`` names a folder, not a file; a folder that is not empty and was not written by fem_grasp
is refused unless ``force`` is given; and a marker file (:data:`MARKER`) lists the files fem_grasp wrote there, so
that the next run into the folder removes them (no stale step of an earlier run remains) and touches nothing else.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Sequence

from .._files import atomic_write_text
from .._version import version
from ..errors import OutputError
from .xdmf import has_h5py

__all__ = ["FILE_SUFFIXES", "MARKER", "add_to_marker", "check_out_path", "package_version", "prepare_out_dir",
           "write_marker"]

#: Marker file naming the files fem_grasp wrote into an output folder.
MARKER = ".fem_grasp.json"
#: Names that look like a file, not a folder: ``--out x.xdmf`` is refused rather than made a folder.
FILE_SUFFIXES = (".xdmf", ".xmf", ".h5", ".hdf5", ".vtu", ".vtk", ".pvd", ".json", ".png", ".html", ".msh")


def package_version() -> str:
    """fem_grasp's version (``fem_grasp.__version__``: the installed metadata, or the source tree's pyproject.toml)."""
    return version()


def check_out_path(path: str | Path) -> Path:
    """Refuse an output *folder* name that ends like a file (``out.xdmf``): say what is written instead.

    Raises
    ------
    OutputError
        The name ends in one of :data:`FILE_SUFFIXES` and is not an existing folder.
    """
    out = Path(path)
    if out.suffix.lower() in FILE_SUFFIXES and not out.is_dir():
        xdmf = (" The XDMF/HDF5 time series is written inside the folder as object.xdmf + object.h5"
                + ("" if has_h5py() else ' (with h5py: pip install "fem_grasp[xdmf]")') + ".")
        raise OutputError(f"--out {out}: --out names a folder, not a file (it would create a folder called "
                          f"{out.name!r}); give a folder such as {str(out.with_suffix('')) or 'out'!r}. fem_grasp "
                          f"writes result.json, object.pvd (ParaView) and the steps there.{xdmf}")
    return out


def prepare_out_dir(path: str | Path, force: bool = False) -> Path:
    """Create ``path`` or check that it may be written into.

    A folder that exists, is not empty and has no :data:`MARKER` was not
    written by fem_grasp: it is refused unless ``force``.  Files listed in a
    previous marker are removed (so that no stale step of an earlier run
    remains); nothing else is touched.

    Raises
    ------
    OutputError
        The folder is a file, is not ours and not empty (without ``force``), or cannot be created.
    """
    out = Path(path)
    if out.exists() and not out.is_dir():
        raise OutputError(f"output path {out} exists and is not a folder")
    marker = out / MARKER
    if out.is_dir() and any(out.iterdir()):
        if marker.exists():
            try:
                old = json.loads(marker.read_text()).get("files", [])
            except (OSError, ValueError):
                old = []
            for rel in old:
                f = (out / rel).resolve()
                if out.resolve() in f.parents and f.is_file():
                    f.unlink()
        elif not force:
            raise OutputError(f"output folder {out} is not empty and was not written by fem_grasp (no {MARKER}); "
                              "choose another folder or pass --force to write into it")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"cannot create output folder {out}: {exc}") from None
    return out


def write_marker(out: Path, files: Sequence[str]) -> None:
    """Write the folder's :data:`MARKER`, listing exactly ``files`` (relative to ``out``) as written by fem_grasp."""
    atomic_write_text(out / MARKER, json.dumps({"written_by": "fem_grasp", "version": package_version(),
                                                "files": sorted(set(files))}, indent=1))


def add_to_marker(out: Path, files: Sequence[str]) -> None:
    """Record ``files`` (relative to ``out``) in the folder's :data:`MARKER` as written by fem_grasp."""
    old: list[str] = []
    if (out / MARKER).exists():
        try:
            old = json.loads((out / MARKER).read_text()).get("files", [])
        except (OSError, ValueError):
            old = []
    write_marker(out, list(old) + list(files))
