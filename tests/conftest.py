"""Shared fixtures, and how the suite runs where an optional part is not installed.

A test that needs an extra which is not installed skips, saying which: ``@pytest.mark.requires("gmsh")`` before it
runs, or, when the library raises :class:`~fem_grasp.errors.MissingExtraError` for a module that is really absent
(not one a test hides on purpose), as it runs.  ``make test-pip`` runs the suite so against a bare wheel.
"""

import importlib.util
import os
import sys
from pathlib import Path

import numpy as np
import pytest

import fem_grasp
from fem_grasp import Body, box_mesh
from fem_grasp.errors import MissingExtraError

#: The extra that brings each optional module (for the skip reasons).
EXTRA_OF = {"gmsh": "mesh", "numba": "fast", "pyvista": "report", "matplotlib": "report", "pandas": "search",
            "dask": "search", "distributed": "search", "pyarrow": "search", "h5py": "xdmf", "sksparse": "cholmod", "tqdm": "report"}


def _absent(module: str) -> bool:
    """``module`` is not installed (a module a test hides with ``sys.modules[name] = None`` does not count)."""
    top = module.split(".")[0]
    if top in sys.modules:
        return False
    try:
        return importlib.util.find_spec(top) is None
    except (ImportError, ValueError):
        return True


def _reason(module: str) -> str:
    extra = EXTRA_OF.get(module.split(".")[0])
    return f"{module} is not installed" + (f" (the {extra!r} extra)" if extra else "")


def pytest_runtest_setup(item: pytest.Item) -> None:
    for mark in item.iter_markers("requires"):
        for module in mark.args:
            if _absent(module):
                pytest.skip(_reason(module))


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo):
    outcome = yield
    report = outcome.get_result()
    if call.excinfo is not None and call.excinfo.errisinstance(MissingExtraError):
        exc = call.excinfo.value
        if exc.name and _absent(exc.name):
            report.outcome = "skipped"
            report.longrepr = (str(item.path), item.location[1] or 0, f"Skipped: {_reason(exc.name)}")


def pytest_report_header(config: pytest.Config) -> str:
    return f"fem_grasp {fem_grasp.__version__} from {Path(fem_grasp.__file__).parent}"


def pytest_configure(config: pytest.Config) -> None:
    """``make test-pip`` (FEM_GRASP_INSTALLED=1) tests the installed wheel: fem_grasp must come from the venv, not
    from a source tree on sys.path.  Tests of what the wheel leaves out (the extras, dolfinx, the source tree's
    verification/, bench/ and examples/) skip there, each saying what is missing."""
    package = Path(fem_grasp.__file__).resolve()
    if os.environ.get("FEM_GRASP_INSTALLED") and not package.is_relative_to(Path(sys.prefix).resolve()):
        raise pytest.UsageError(f"FEM_GRASP_INSTALLED is set but fem_grasp is imported from {package.parent}, "
                                f"not from the environment {sys.prefix}")


@pytest.fixture(scope="session")
def box_body() -> Body:
    """A 4×3×2 cm box of 1 N, mildly soft, on a 4×3×3 grid."""
    mesh = box_mesh((0, 0, 0), (0.04, 0.03, 0.02), (4, 3, 3))
    return Body(mesh, young=5e4, poisson=0.3, weight=1.0)


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(12345)
