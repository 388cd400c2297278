"""Scene files on disk: where they are (a path or a shipped scene's name), their TOML, and the tables and keys a
file may hold, each read with its type and unit and a message naming the file and the key.

:data:`SCHEMA` lists the keys of each table and their kinds; :class:`TableReader` reads one table against it;
:func:`fem_grasp.io.scene.parse_scene` checks the values and builds the :class:`~fem_grasp.io.scene.Scene`.
"""

from __future__ import annotations

import copy
import math
import sys
from pathlib import Path
from typing import Any

from ..errors import SceneError
from ..grasp.placement import PLACEMENT_RULES
from .quantities import UNITS, parse_accuracy, parse_quantity

__all__ = ["SCENE_DIR", "SCHEMA", "TableReader", "check_keys", "close_keys", "merge_tables", "read_toml",
           "resolve_scene", "shipped_scenes"]

#: Folder of the scenes shipped with the package (``fem-grasp run tomato`` looks here).
SCENE_DIR = Path(__file__).resolve().parents[1] / "scenes"


def shipped_scenes() -> dict[str, Path]:
    """The scenes shipped with the package: name → path."""
    return {p.stem: p for p in sorted(SCENE_DIR.glob("*.toml"))}


def resolve_scene(name_or_path: str | Path) -> Path:
    """A scene file path from a path or the name of a shipped scene (``tomato`` → ``scenes/tomato.toml``)."""
    p = Path(name_or_path).expanduser()
    shipped = shipped_scenes()
    if p.is_dir() and str(name_or_path) in shipped:  # a folder named like a shipped scene (`--out tomato`)
        return shipped[str(name_or_path)]
    if p.exists() or p.suffix == ".toml" or p.parent != Path("."):
        return p
    if str(name_or_path) in shipped:
        return shipped[str(name_or_path)]
    raise SceneError(f"no scene file {str(name_or_path)!r} and no shipped scene of that name; shipped scenes: "
                     f"{', '.join(shipped)}")


#: The tables of a scene file, the keys each takes and their kinds.
SCHEMA: dict[str, dict[str, str]] = {
    "": {"name": "str", "description": "str", "expect": "str", "object": "table", "material": "table",
         "friction": "table", "fingers": "table", "solver": "table", "quick": "table"},
    "object": {"paper": "str", "mesh": "str", "box": "length3", "divisions": "int3", "vertices": "int",
               "size": "length", "down": "vec3", "units": "str", "allow_implausible_units": "bool"},
    "material": {"young": "pressure", "poisson": "float", "weight": "force", "density": "density", "mass": "mass",
                 "gravity": "acceleration"},
    "friction": {"finger": "float", "table": "float"},
    "fingers": {"radius": "length", "contacts": "contacts", "directions": "directions", "ratio": "float"},
    "solver": {"backend": "str", "max_squeeze": "length", "step": "length", "lift_test_step": "force",
               "max_lift": "length", "lift": "bool", "accuracy": "accuracy",
               "expected_error": "float", "max_finger_contacts": "int", "step_divisions": "int",
               "max_seconds": "float", "refinement": "str"},
}


def read_toml(path: Path) -> dict[str, Any]:
    """The tables of the TOML file ``path``; a missing file, a folder, invalid TOML or a binary file raises
    :class:`~fem_grasp.errors.SceneError` naming the file."""
    if sys.version_info >= (3, 11):
        import tomllib
    else:  # pragma: no cover - Python 3.10
        try:
            import tomli as tomllib
        except ImportError:
            raise SceneError(f"{path}: reading TOML on Python < 3.11 needs the package 'tomli'") from None
    if not path.exists():
        raise SceneError(f"scene file {path} does not exist")
    if path.is_dir():
        raise SceneError(f"scene file {path} is a directory")
    try:
        with path.open("rb") as fh:
            return tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"{path}: not valid TOML: {exc}") from None
    except UnicodeDecodeError as exc:
        raise SceneError(f"{path}: not a text file ({exc})") from None


def merge_tables(base: dict[str, Any], over: dict[str, Any]) -> dict[str, Any]:
    """A copy of ``base`` with the tables of ``over`` merged into it key by key (``[quick]`` over the scene)."""
    out = copy.deepcopy(base)
    for k, v in over.items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = merge_tables(out[k], v)
        else:
            out[k] = copy.deepcopy(v)
    return out


def close_keys(key: str, allowed: list[str]) -> list[str]:
    """The keys a mistyped ``key`` probably meant: close spellings (difflib), then keys with its first letters."""
    import difflib

    close = difflib.get_close_matches(key, allowed, n=3, cutoff=0.6)
    close += [a for a in allowed if a.lower().startswith(key.lower()[:3]) and a not in close]
    return close


def check_keys(data: dict[str, Any], table: str, src: str) -> None:
    """Refuse a key that ``table`` ('' for the top level) does not take, suggesting the one probably meant, and
    a key that should hold a table but does not (:class:`~fem_grasp.errors.SceneError` naming the file ``src``)."""
    allowed = SCHEMA[table]
    for key in data:
        if key not in allowed:
            full = f"{table}.{key}" if table else key
            close = close_keys(key, list(allowed))
            hint = f" (did you mean {', '.join(repr(f'{table}.{c}' if table else c) for c in close)}?)" if close else ""
            where = f"[{table}]" if table else "the top level"
            raise SceneError(f"{src}: unknown key {full!r}{hint}; {where} takes: {', '.join(allowed)}")
        if allowed[key] == "table" and not isinstance(data[key], dict):
            raise SceneError(f"{src}: {key!r} must be a table ([{key}]), got {data[key]!r}")


class TableReader:
    """Typed access to one table of the scene, with messages naming the file and key."""

    def __init__(self, data: dict[str, Any], table: str, src: str) -> None:
        check_keys(data, table, src)
        self.data, self.table, self.src = data, table, src

    def where(self, key: str) -> str:
        return f"{self.src}: {self.table}.{key}" if self.table else f"{self.src}: {key}"

    def has(self, key: str) -> bool:
        return key in self.data

    def get(self, key: str, default: Any = None) -> Any:
        if key not in self.data:
            return default
        kind = SCHEMA[self.table][key]
        v = self.data[key]
        w = self.where(key)
        if kind == "str":
            if not isinstance(v, str):
                raise SceneError(f"{w}: expected a string, got {v!r}")
            return v
        if kind == "bool":
            if not isinstance(v, bool):
                raise SceneError(f"{w}: expected true or false, got {v!r}")
            return v
        if kind == "int":
            if isinstance(v, bool) or not isinstance(v, int):
                raise SceneError(f"{w}: expected an integer, got {v!r}")
            return v
        if kind == "float":
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                raise SceneError(f"{w}: expected a number, got {v!r}")
            return float(v)
        if kind == "accuracy":  # 0.05, "5%" or "off" (None)
            return parse_accuracy(v, w)
        if kind in UNITS:
            return parse_quantity(v, kind, w)
        if kind in ("length3", "vec3", "int3"):
            if not isinstance(v, list) or len(v) != 3:
                raise SceneError(f"{w}: expected a list of three values, got {v!r}")
            if kind == "length3":
                return tuple(parse_quantity(x, "length", f"{w}[{i}]") for i, x in enumerate(v))
            if kind == "int3":
                if not all(isinstance(x, int) and not isinstance(x, bool) for x in v):
                    raise SceneError(f"{w}: expected three integers, got {v!r}")
                return tuple(v)
            if not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v):
                raise SceneError(f"{w}: expected three numbers, got {v!r}")
            return tuple(float(x) for x in v)
        if kind == "contacts":

            if v == "auto":
                return None
            if isinstance(v, str) and v in PLACEMENT_RULES:
                return v
            if (not isinstance(v, list) or len(v) != 2
                    or not all(isinstance(x, int) and not isinstance(x, bool) for x in v)):
                rules = ", ".join(f'"{r}"' for r in PLACEMENT_RULES)
                raise SceneError(f"{w}: expected \"auto\", a placement rule ({rules}) or two node indices "
                                 f"[i, j], got {v!r}")
            if v[0] == v[1] or min(v) < 0:
                raise SceneError(f"{w}: the two contact nodes must be distinct non-negative indices, got {v!r}")
            return (int(v[0]), int(v[1]))
        if kind == "directions":
            ok = (isinstance(v, list) and len(v) == 2 and all(isinstance(d, list) and len(d) == 3 for d in v)
                  and all(isinstance(x, (int, float)) and not isinstance(x, bool) for d in v for x in d))
            if not ok:
                raise SceneError(f"{w}: expected two 3-vectors [[x, y, z], [x, y, z]], got {v!r}")
            out = []
            for i, d in enumerate(v):
                n = math.sqrt(sum(x * x for x in d))
                if not n > 0 or not math.isfinite(n):
                    raise SceneError(f"{w}[{i}]: a squeeze direction must be a non-zero vector, got {d!r}")
                out.append(tuple(float(x) / n for x in d))
            return tuple(out)
        raise AssertionError(kind)  # pragma: no cover
