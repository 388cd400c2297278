"""The package's public face and its floors: what ``__all__`` promises exists and is documented, imports run one way.

The floors, bottom to top: the ground (``errors``, ``_version``, ``validation``, ``settings``, ``threads``, ``_files``, ``progress``, ``spawn``) < ``mesh`` <
``elastic`` (paper §II) < ``contact`` (§III-A/C) < ``grasp`` (Algorithm 1) < ``io`` < ``batch`` (many pickups:
the placement search on Dask) < the applications (``cli``, ``paper``).  A module may import from its own floor and the floors below, never above; no module
imports another module's private (``_name``) objects; and the modules form no import circle.
"""

from __future__ import annotations

import ast
import importlib
import inspect
import pkgutil
from pathlib import Path

import pytest

import fem_grasp

PACKAGE = Path(fem_grasp.__file__).resolve().parent
#: Floor of each top-level part of the package.
FLOORS = {"errors": 0, "_version": 0, "validation": 0, "settings": 0, "threads": 0, "_files": 0, "progress": 0, "spawn": 0, "mesh": 1,
          "elastic": 2, "contact": 3, "grasp": 4, "io": 5, "batch": 6, "cli": 7, "paper": 7, "__main__": 7, "__init__": 7}


def _modules() -> list[str]:
    names = ["fem_grasp"]
    for info in pkgutil.walk_packages([str(PACKAGE)], prefix="fem_grasp."):
        names.append(info.name)
    return sorted(names)


def _source(name: str) -> Path:
    rel = name.split(".")[1:]
    path = PACKAGE.joinpath(*rel)
    return path / "__init__.py" if path.is_dir() else path.with_suffix(".py")


def _is_module(name: str) -> bool:
    path = PACKAGE.joinpath(*name.split(".")[1:])
    return path.is_dir() or path.with_suffix(".py").exists()


def _floor(name: str) -> int:
    parts = name.split(".")
    return FLOORS["__init__"] if len(parts) == 1 else FLOORS[parts[1]]


def _imports(name: str) -> list[tuple[str, list[str], int]]:
    """(imported fem_grasp module, imported names, line) of every import in a module, outside TYPE_CHECKING."""
    path = _source(name)
    tree = ast.parse(path.read_text(encoding="utf-8"))
    package = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
    skip: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            skip.update(id(n) for n in ast.walk(node))
    out = []
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[:len(base) - node.level + 1]
                module = ".".join(base + ([node.module] if node.module else []))
            else:
                module = node.module or ""
            if module.split(".")[0] != "fem_grasp":
                continue
            names = [a.name for a in node.names]
            # ``from . import x`` imports the module fem_grasp.<…>.x
            subs = [n for n in names if _is_module(f"{module}.{n}")]
            for n in subs:
                out.append((f"{module}.{n}", [], node.lineno))
            rest = [n for n in names if n not in subs]
            if rest or not subs:
                out.append((module, rest, node.lineno))
        elif isinstance(node, ast.Import):
            out += [(a.name, [], node.lineno) for a in node.names if a.name.split(".")[0] == "fem_grasp"]
    return out


MODULES = _modules()
#: Modules that can be imported without running something (``python -m fem_grasp`` and ``python -m fem_grasp.cli`` run
#: the CLI).
IMPORTABLE = [n for n in MODULES if n.rsplit(".", 1)[-1] != "__main__"]


@pytest.mark.parametrize("name", [n for n in MODULES if _source(n).name == "__init__.py"])
def test_every_public_name_exists_and_is_documented(name):
    module = importlib.import_module(name)
    assert module.__doc__ and module.__doc__.strip(), f"{name} has no docstring"
    assert hasattr(module, "__all__"), f"{name} declares no __all__"
    for public in module.__all__:
        obj = getattr(module, public)  # raises if the face promises what it does not have
        if inspect.isclass(obj) or inspect.isfunction(obj) or inspect.ismodule(obj):
            assert obj.__doc__ and obj.__doc__.strip(), f"{name}.{public} is not documented"


@pytest.mark.parametrize("name", IMPORTABLE)
def test_every_module_declares_what_it_exports(name):
    module = importlib.import_module(name)
    assert module.__doc__ and module.__doc__.strip(), f"{name} has no module docstring"
    assert hasattr(module, "__all__"), f"{name} declares no __all__"
    missing = [n for n in module.__all__ if not hasattr(module, n)]
    assert not missing, f"{name}.__all__ names what it does not define: {missing}"


def test_imports_run_one_way_down_the_floors():
    upward = []
    for name in MODULES:
        for target, _, line in _imports(name):
            if target != "fem_grasp" and _floor(target) > _floor(name):
                upward.append(f"{_source(name).relative_to(PACKAGE.parent)}:{line} imports {target}")
    assert not upward, "imports from a higher floor:\n" + "\n".join(upward)


def test_no_module_imports_another_modules_private_names():
    private = []
    for name in MODULES:
        for target, names, line in _imports(name):
            bad = [n for n in names if n.startswith("_") and not n.startswith("__")]
            if bad and target != name:
                private.append(f"{_source(name).relative_to(PACKAGE.parent)}:{line} imports {bad} from {target}")
    assert not private, "\n".join(private)


def test_the_modules_form_no_import_circle():
    graph = {name: {t for t, _, _ in _imports(name) if t in MODULES and t != name} for name in MODULES}
    # a package's face imports its own modules; the modules importing the face back would be a circle too
    state: dict[str, int] = {}
    cycles = []

    def visit(node: str, path: list[str]) -> None:
        state[node] = 1
        for nxt in sorted(graph[node]):
            if state.get(nxt) == 1:
                cycles.append(path[path.index(nxt):] + [nxt] if nxt in path else [node, nxt])
            elif nxt not in state:
                visit(nxt, path + [nxt])
        state[node] = 2

    for name in MODULES:
        if name not in state:
            visit(name, [name])
    assert not cycles, "import circles:\n" + "\n".join(" → ".join(c) for c in cycles)


def test_the_lazy_modules_of_the_face_load_on_first_use():
    assert fem_grasp.objects.load is importlib.import_module("fem_grasp.grasp.objects").load
    assert "objects" in dir(fem_grasp)
    with pytest.raises(AttributeError, match="no attribute 'geometry'"):
        fem_grasp.geometry  # noqa: B018 - the old flat module is gone
