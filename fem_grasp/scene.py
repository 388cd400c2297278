"""Scene files: one TOML file describes one pickup (object, material, friction, fingers, solver).

A scene names the object (a paper object, a volume mesh, a closed surface
scan, or a box), its material, the two friction coefficients μ_ℱ (fingers)
and μ_𝒫 (table), the fingertip radius, the initial contacts (node indices or
the default rule of :func:`fem_grasp.pickup.default_finger_contacts`), the
squeeze directions and ratio, and the solver settings of
:func:`fem_grasp.pickup.pickup`.  Example (every key but ``[object]`` is
optional)::

    name = "tomato"
    description = "Table I tomato at the effective modulus"

    [object]
    paper = "tomato"          # or: mesh = "scan.stl" (relative to this file), or box = ["4 cm", "3 cm", "2 cm"]
    vertices = 490            # remesh with gmsh at about this many vertices (paper shapes and scans)

    [material]
    young = "10 kPa"          # numbers are SI (Pa); strings may carry a unit
    poisson = 0.4
    weight = "1.246 N"        # or density = "1000 kg/m^3", or mass = "127 g"

    [friction]
    finger = 0.32             # μ_ℱ
    table = 0.32              # μ_𝒫

    [fingers]
    radius = "1 cm"
    contacts = "auto"         # or a placement rule ("centre-of-mass-height", "least-force"), or [i, j], node indices
    directions = [[0, 0.974, -0.227], [0, -0.974, -0.227]]
    ratio = 1.0

    [solver]
    backend = "sparse"        # "spectral" computes the dense eigendecomposition (paper, eq. 3)
    max_squeeze = "3 cm"
    step = "0.5 mm"
    lift_test_step = "0.05 N"
    max_lift = "5 cm"
    lift = true
    accuracy = 0.05           # relative accuracy of ρ* and the finger force: refine at the contact patches until
                              # two successive levels agree within it (fem_grasp.accuracy); omit for one run
    expected_error = 0.3      # how far a single run of this scene (no accuracy loop, e.g. its [quick] variant) is
                              # from the converged answer, as measured by `make converge`: printed with its answer

    [quick]                   # overrides for `--quick`: same tables, merged over the above
    object = { vertices = 200 }

Unknown keys, wrong types, units of the wrong kind and values out of range
raise :class:`SceneError`, whose message names the file and the key.
Lengths accept m, cm, mm; pressures Pa, kPa, MPa, GPa; forces N, mN; masses
kg, g; densities kg/m^3, g/cm^3.  A bare number is in SI units.
"""

from __future__ import annotations

import copy
import logging
import math
import re
import sys
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from .placement import DEFAULT_PLACEMENT_RULE, PLACEMENT_RULES
from .validation import SceneError as _ValidationSceneError

__all__ = ["SceneError", "Scene", "ObjectSpec", "load_scene", "parse_scene", "shipped_scenes", "resolve_scene",
           "SCENE_DIR", "parse_quantity"]

log = logging.getLogger(__name__)

#: Folder of the scenes shipped with the package (``fem-grasp run tomato`` looks here).
SCENE_DIR = Path(__file__).resolve().parent / "scenes"

STANDARD_GRAVITY = 9.8


class SceneError(_ValidationSceneError):
    """A scene file is missing, unreadable, or has a bad key or value; the message names file and key.

    A subclass of :class:`fem_grasp.validation.SceneError` (and so of ``ValueError``).
    """


# ------------------------------------------------------------------ units
_UNITS: dict[str, dict[str, float]] = {
    "length": {"m": 1.0, "cm": 1e-2, "mm": 1e-3, "um": 1e-6, "µm": 1e-6},
    "pressure": {"pa": 1.0, "kpa": 1e3, "mpa": 1e6, "gpa": 1e9},
    "force": {"n": 1.0, "mn": 1e-3, "kn": 1e3},
    "mass": {"kg": 1.0, "g": 1e-3},
    "density": {"kg/m^3": 1.0, "kg/m3": 1.0, "g/cm^3": 1e3, "g/cm3": 1e3},
    "acceleration": {"m/s^2": 1.0, "m/s2": 1.0},
}
_SI = {"length": "m", "pressure": "Pa", "force": "N", "mass": "kg", "density": "kg/m^3", "acceleration": "m/s^2"}
_QUANTITY = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*([^\s\d].*?)?\s*$")


def parse_quantity(value: Any, kind: str, where: str = "value") -> float:
    """A number (SI) or a string ``"<number> <unit>"`` of the given kind → float in SI units.

    Raises
    ------
    SceneError
        Naming ``where`` when the value is not a number, has no or a wrong unit.
    """
    if isinstance(value, bool):
        raise SceneError(f"{where}: expected a {kind} in {_SI[kind]}, got the boolean {value!r}")
    if isinstance(value, (int, float)):
        return float(value)
    if not isinstance(value, str):
        raise SceneError(f"{where}: expected a {kind} (a number in {_SI[kind]} or a string like "
                         f"\"2 {list(_UNITS[kind])[1] if len(_UNITS[kind]) > 1 else _SI[kind]}\"), got {value!r}")
    m = _QUANTITY.match(value)
    if not m:
        raise SceneError(f"{where}: cannot read {value!r} as a {kind} (write a number and a unit, e.g. "
                         f"\"{_example(kind)}\")")
    number, unit = float(m.group(1)), (m.group(2) or "").strip()
    if not unit:
        return number
    table = _UNITS[kind]
    key = unit.lower() if kind != "length" else unit
    if key in table:
        return number * table[key]
    for other, units in _UNITS.items():
        if unit.lower() in {u.lower() for u in units}:
            raise SceneError(f"{where}: {value!r} is a {other}, but a {kind} is expected (units: "
                             f"{', '.join(_display_units(kind))})")
    raise SceneError(f"{where}: unknown unit {unit!r} in {value!r}; a {kind} takes {', '.join(_display_units(kind))}")


def _display_units(kind: str) -> list[str]:
    return {"length": ["m", "cm", "mm"], "pressure": ["Pa", "kPa", "MPa", "GPa"], "force": ["N", "mN", "kN"],
            "mass": ["kg", "g"], "density": ["kg/m^3", "g/cm^3"], "acceleration": ["m/s^2"]}[kind]


def _example(kind: str) -> str:
    return {"length": "2 cm", "pressure": "10 kPa", "force": "1.2 N", "mass": "120 g", "density": "900 kg/m^3",
            "acceleration": "9.8 m/s^2"}[kind]


# ------------------------------------------------------------------ model
@dataclass(frozen=True)
class ObjectSpec:
    """Where the object's mesh comes from (exactly one of ``paper``, ``mesh``, ``box``).

    Attributes
    ----------
    paper : name of a paper object (Table I), or None
    mesh : path of a volume mesh (any meshio format) or a closed surface (STL, OBJ, PLY)
    box : (3,) box edge lengths, metres
    divisions : (3,) grid cells of the box
    vertices : remesh at about this many vertices (paper shapes, surfaces)
    size : mesh size (edge length, metres) for surfaces
    down : which way is down in the mesh's frame (default −z)
    """

    paper: str | None = None
    mesh: Path | None = None
    box: tuple[float, float, float] | None = None
    divisions: tuple[int, int, int] = (4, 4, 4)
    vertices: int | None = None
    size: float | None = None
    down: tuple[float, float, float] | None = None

    @property
    def kind(self) -> str:
        return "paper" if self.paper else "mesh" if self.mesh else "box"


@dataclass(frozen=True)
class Scene:
    """A parsed, validated scene (SI units throughout).

    ``young``, ``poisson``, ``weight``/``density``/``mass`` and friction may be None
    in the file for a paper object (Table I and :data:`~fem_grasp.objects.EFFECTIVE_YOUNG_ESTIMATE`
    fill them); they are always set on a parsed :class:`Scene`.
    """

    name: str
    object: ObjectSpec
    young: float
    poisson: float
    weight: float | None
    density: float | None
    gravity: float
    mu_finger: float
    mu_table: float
    finger_radius: float
    contacts: tuple[int, int] | None
    directions: tuple[tuple[float, float, float], tuple[float, float, float]]
    ratio: float
    backend: str = "sparse"
    max_squeeze: float | None = None
    step: float | None = None
    lift_test_step: float | None = None
    max_lift: float | None = None
    lift: bool = True
    description: str = ""
    path: Path | None = None
    quick: bool = False
    expect: str | None = None
    placement_rule: str = DEFAULT_PLACEMENT_RULE
    accuracy: float | None = None
    expected_error: float | None = None

    # ------------------------------------------------------------ building
    def load_mesh(self, cache_dir: Path | None = None) -> "Any":
        """The object's :class:`~fem_grasp.mesh.TetMesh` (gmsh meshes are cached in ``cache_dir``)."""
        from .mesh import TetMesh, box_mesh

        spec = self.object
        if spec.kind == "box":
            lx, ly, lz = spec.box
            return box_mesh((-lx / 2, -ly / 2, 0.0), (lx / 2, ly / 2, lz), spec.divisions)
        if spec.kind == "paper":
            if spec.vertices is None:
                from . import objects

                return objects.load_mesh(spec.paper)
            from .shapes import PAPER_SHAPES

            # the shape's spec is in the key: a changed stand-in shape must not be served from the cache
            return _cached_mesh(cache_dir, ("paper", spec.paper, spec.vertices, PAPER_SHAPES[spec.paper]),
                                lambda: _paper_mesh(spec.paper, spec.vertices))
        path = spec.mesh
        from .scan import SURFACE_SUFFIXES

        if path.suffix.lower() in SURFACE_SUFFIXES:
            from . import scan

            data = path.read_bytes()
            return _cached_mesh(cache_dir, ("surface", _digest(data), spec.vertices, spec.size),
                                lambda: scan.mesh_surface(path, target_vertices=spec.vertices, size=spec.size))
        return TetMesh.from_file(path)

    def body(self, cache_dir: Path | None = None) -> "Any":
        """The :class:`~fem_grasp.body.Body` of this scene."""
        from .body import Body

        mesh = self.load_mesh(cache_dir)
        kw = {"weight": self.weight} if self.weight is not None else {"density": self.density}
        return Body(mesh, self.young, self.poisson, gravity=self.gravity, **kw)

    def geometry(self) -> "Any":
        """What ``accuracy`` remeshes (:mod:`fem_grasp.remesh`): the paper shape, the box, the scan's surface;
        None for a volume mesh file (the loop then remeshes the mesh's own boundary)."""
        from . import remesh

        return remesh.geometry_of_scene(self)

    def pickup_kwargs(self) -> dict[str, Any]:
        """Keyword arguments of :func:`fem_grasp.pickup.pickup` (all but ``body`` and ``rest_state``).

        ``accuracy`` is not among them: a caller that wants the converged answer passes
        ``accuracy=scene.accuracy, geometry=scene.geometry()`` (the CLI does).
        """
        return {"mu_finger": self.mu_finger, "mu_table": self.mu_table, "finger_radius": self.finger_radius,
                "contacts": self.contacts, "directions": tuple(np.array(d, float) for d in self.directions),
                "ratio": self.ratio, "max_squeeze": self.max_squeeze, "step": self.step, "backend": self.backend,
                "lift_test_step": self.lift_test_step, "max_lift": self.max_lift, "lift": self.lift,
                "placement_rule": self.placement_rule}

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["object"] = {k: (str(v) if isinstance(v, Path) else v) for k, v in asdict(self.object).items()}
        d["path"] = None if self.path is None else str(self.path)
        return d


def _digest(data: bytes) -> str:
    import hashlib

    return hashlib.sha256(data).hexdigest()[:16]


def _paper_mesh(name: str, vertices: int) -> Any:
    from . import shapes

    return shapes.paper_mesh(name, vertices)


def _cached_mesh(cache_dir: Path | None, key: tuple, build: Any) -> Any:
    """Build a mesh, or load it from ``cache_dir`` (an .npz keyed by ``key`` and the gmsh version)."""
    from .mesh import TetMesh

    if cache_dir is None:
        return build()
    try:
        import gmsh

        version = getattr(gmsh, "__version__", "?")
    except ImportError:
        version = "none"
    import hashlib

    h = hashlib.sha256(repr((key, version)).encode()).hexdigest()[:20]
    path = Path(cache_dir) / f"mesh-{h}.npz"
    if path.exists():
        try:
            with np.load(path) as z:
                mesh = TetMesh(z["points"], z["tets"])
            log.info("mesh from cache %s", path)
            return mesh
        except Exception as exc:  # a damaged cache entry is rebuilt
            log.warning("ignoring unreadable mesh cache %s: %s", path, exc)
    mesh = build()
    from .output import atomic_write_bytes
    import io

    buf = io.BytesIO()
    np.savez(buf, points=mesh.points, tets=mesh.tets)
    Path(cache_dir).mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(path, buf.getvalue())
    return mesh


# ------------------------------------------------------------------ parsing
_SCHEMA: dict[str, dict[str, str]] = {
    "": {"name": "str", "description": "str", "expect": "str", "object": "table", "material": "table",
         "friction": "table", "fingers": "table", "solver": "table", "quick": "table"},
    "object": {"paper": "str", "mesh": "str", "box": "length3", "divisions": "int3", "vertices": "int",
               "size": "length", "down": "vec3"},
    "material": {"young": "pressure", "poisson": "float", "weight": "force", "density": "density", "mass": "mass",
                 "gravity": "acceleration"},
    "friction": {"finger": "float", "table": "float"},
    "fingers": {"radius": "length", "contacts": "contacts", "directions": "directions", "ratio": "float"},
    "solver": {"backend": "str", "max_squeeze": "length", "step": "length", "lift_test_step": "force",
               "max_lift": "length", "lift": "bool", "accuracy": "float",
               "expected_error": "float"},
}


def _read_toml(path: Path) -> dict[str, Any]:
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


def _merge(base: dict[str, Any], over: dict[str, Any]) -> dict[str, Any]:
    out = copy.deepcopy(base)
    for k, v in over.items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = _merge(out[k], v)
        else:
            out[k] = copy.deepcopy(v)
    return out


def _check_keys(data: dict[str, Any], table: str, src: str) -> None:
    allowed = _SCHEMA[table]
    for key in data:
        if key not in allowed:
            full = f"{table}.{key}" if table else key
            close = [a for a in allowed if a.lower().startswith(key.lower()[:3])]
            hint = f" (did you mean {', '.join(repr(f'{table}.{c}' if table else c) for c in close)}?)" if close else ""
            where = f"[{table}]" if table else "the top level"
            raise SceneError(f"{src}: unknown key {full!r}{hint}; {where} takes: {', '.join(allowed)}")
        if allowed[key] == "table" and not isinstance(data[key], dict):
            raise SceneError(f"{src}: {key!r} must be a table ([{key}]), got {data[key]!r}")


class _Reader:
    """Typed access to one table of the scene, with messages naming the file and key."""

    def __init__(self, data: dict[str, Any], table: str, src: str) -> None:
        _check_keys(data, table, src)
        self.data, self.table, self.src = data, table, src

    def where(self, key: str) -> str:
        return f"{self.src}: {self.table}.{key}" if self.table else f"{self.src}: {key}"

    def has(self, key: str) -> bool:
        return key in self.data

    def get(self, key: str, default: Any = None) -> Any:
        if key not in self.data:
            return default
        kind = _SCHEMA[self.table][key]
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
        if kind in _UNITS:
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


def _positive(w: str, v: float | None, unit: str, allow_zero: bool = False) -> None:
    if v is None:
        return
    ok = math.isfinite(v) and (v >= 0 if allow_zero else v > 0)
    if not ok:
        raise SceneError(f"{w} must be {'≥ 0' if allow_zero else 'positive'} ({unit}), got {v!r}")


def parse_scene(data: dict[str, Any], src: str = "<scene>", base_dir: Path | None = None, quick: bool = False,
                path: Path | None = None) -> Scene:
    """Validate a scene dictionary (as read from TOML) and build a :class:`Scene`.

    ``quick`` merges the ``[quick]`` table over the others.  Relative mesh
    paths are taken from ``base_dir``.
    """
    from . import objects
    from .fingertip import DEFAULT_RADIUS
    from .placement import PAPER_SQUEEZE_DIRECTIONS

    _check_keys(data, "", src)
    quick_over = data.get("quick", {})
    for t, sub in quick_over.items():
        if t not in _SCHEMA or t in ("", "quick") or not isinstance(sub, dict):
            raise SceneError(f"{src}: quick.{t}: [quick] overrides the tables object, material, friction, fingers, "
                             f"solver (e.g. quick.object = {{ vertices = 200 }}), got {t!r} = {sub!r}")
        _check_keys(sub, t, f"{src} [quick]")
    if quick:
        data = _merge({k: v for k, v in data.items() if k != "quick"}, quick_over)
    top = _Reader(data, "", src)
    tables = {t: _Reader(data.get(t, {}), t, src) for t in ("object", "material", "friction", "fingers", "solver")}
    if "object" not in data:
        raise SceneError(f"{src}: missing table [object] (give paper = \"tomato\", mesh = \"file\" or box = [...])")

    # [object]
    o = tables["object"]
    given = [k for k in ("paper", "mesh", "box") if o.has(k)]
    if len(given) != 1:
        raise SceneError(f"{src}: [object] needs exactly one of paper, mesh, box; got "
                         f"{', '.join(given) if given else 'none'}")
    paper = o.get("paper")
    if paper is not None and paper not in objects.NAMES:
        raise SceneError(f"{o.where('paper')}: unknown paper object {paper!r}; choose one of {', '.join(objects.NAMES)}")
    mesh_path = None
    if o.has("mesh"):
        mesh_path = Path(o.get("mesh")).expanduser()
        if not mesh_path.is_absolute() and base_dir is not None:
            mesh_path = base_dir / mesh_path
        if not mesh_path.exists():
            raise SceneError(f"{o.where('mesh')}: mesh file {mesh_path} does not exist")
    box = o.get("box")
    if box is not None:
        for i, x in enumerate(box):
            _positive(f"{o.where('box')}[{i}]", x, "m")
    divisions = o.get("divisions", (4, 4, 4))
    if min(divisions) < 1:
        raise SceneError(f"{o.where('divisions')} must be positive integers, got {list(divisions)}")
    vertices = o.get("vertices")
    if vertices is not None and vertices < 20:
        raise SceneError(f"{o.where('vertices')} must be at least 20 (a tetrahedral mesh to compute on), got {vertices}")
    if vertices is not None and box is not None:
        raise SceneError(f"{o.where('vertices')}: a box is meshed by its divisions, not a vertex count")
    size = o.get("size")
    _positive(o.where("size"), size, "m")
    if size is not None and paper is not None:
        raise SceneError(f"{o.where('size')}: a paper object is remeshed by vertex count (object.vertices), not size")
    down = o.get("down")
    if down is not None and not any(down):
        raise SceneError(f"{o.where('down')} must be a non-zero vector, got {list(down)}")
    spec = ObjectSpec(paper, mesh_path, box, tuple(divisions), vertices, size, down)

    # [material]
    m = tables["material"]
    row = objects.TABLE_I.get(paper) if paper else None
    young = m.get("young")
    if young is None:
        if row is None:
            raise SceneError(f"{src}: material.young (Young's modulus, Pa) is required for a {spec.kind} object")
        young = objects.EFFECTIVE_YOUNG_ESTIMATE
    if not (math.isfinite(young) and young > 0):
        raise SceneError(f"{m.where('young')} must be a positive modulus in Pa, got {young!r}")
    poisson = m.get("poisson", row.poisson if row else None)
    if poisson is None:
        raise SceneError(f"{src}: material.poisson (Poisson's ratio) is required for a {spec.kind} object")
    if not -1.0 < poisson < 0.5:
        raise SceneError(f"{m.where('poisson')} must lie in (-1, 0.5), got {poisson!r}")
    mass_keys = [k for k in ("weight", "density", "mass") if m.has(k)]
    if len(mass_keys) > 1:
        raise SceneError(f"{src}: [material] takes one of weight, density, mass; got {', '.join(mass_keys)}")
    gravity = m.get("gravity", STANDARD_GRAVITY)
    _positive(m.where("gravity"), gravity, "m/s^2")
    weight = density = None
    if m.has("weight"):
        weight = m.get("weight")
        _positive(m.where("weight"), weight, "N")
    elif m.has("mass"):
        mass = m.get("mass")
        _positive(m.where("mass"), mass, "kg")
        weight = mass * gravity
    elif m.has("density"):
        density = m.get("density")
        _positive(m.where("density"), density, "kg/m^3")
    elif row is not None:
        weight = row.weight
    else:
        raise SceneError(f"{src}: [material] needs weight (N), mass (kg) or density (kg/m^3) for a {spec.kind} object")

    # [friction]
    f = tables["friction"]
    mu_f = f.get("finger", row.friction if row else None)
    if mu_f is None:
        raise SceneError(f"{src}: friction.finger (μ between object and fingertips) is required")
    mu_t = f.get("table", row.friction if row else mu_f)
    _positive(f.where("finger"), mu_f, "friction coefficient", allow_zero=True)
    _positive(f.where("table"), mu_t, "friction coefficient", allow_zero=True)

    # [fingers]
    g = tables["fingers"]
    radius = g.get("radius", DEFAULT_RADIUS)
    _positive(g.where("radius"), radius, "m")
    contacts = g.get("contacts")
    rule = DEFAULT_PLACEMENT_RULE
    if isinstance(contacts, str):
        rule, contacts = contacts, None
    directions = g.get("directions", tuple(tuple(float(x) for x in d) for d in PAPER_SQUEEZE_DIRECTIONS))
    ratio = g.get("ratio", 1.0)
    _positive(g.where("ratio"), ratio, "dimensionless", allow_zero=True)

    # [solver]
    s = tables["solver"]
    backend = s.get("backend", "sparse")
    if backend not in ("sparse", "spectral"):
        raise SceneError(f"{s.where('backend')} must be \"sparse\" or \"spectral\", got {backend!r}")
    for key, unit in (("max_squeeze", "m"), ("step", "m"), ("lift_test_step", "N"), ("max_lift", "m")):
        _positive(s.where(key), s.get(key), unit)
    accuracy = s.get("accuracy")
    if accuracy is not None and not 0.0 < accuracy < 1.0:
        raise SceneError(f"{s.where('accuracy')} is a relative error in (0, 1), e.g. 0.05 for 5 %; got {accuracy!r}")
    expected_error = s.get("expected_error")
    if expected_error is not None and not expected_error > 0:
        raise SceneError(f"{s.where('expected_error')} is a relative error > 0 (inf: the verdict itself may be wrong); "
                         f"got {expected_error!r}")
    step, max_sq = s.get("step"), s.get("max_squeeze")
    if step is not None and max_sq is not None and step > max_sq:
        raise SceneError(f"{s.where('step')} ({step:g} m) exceeds solver.max_squeeze ({max_sq:g} m)")

    name = top.get("name") or (path.stem if path is not None else "scene")
    expect = top.get("expect")
    if expect is not None and expect not in ("success", "failure"):
        raise SceneError(f"{top.where('expect')} must be \"success\" or \"failure\", got {expect!r}")
    return Scene(name=name, object=spec, young=float(young), poisson=float(poisson), weight=weight, density=density,
                 gravity=float(gravity), mu_finger=float(mu_f), mu_table=float(mu_t), finger_radius=float(radius),
                 contacts=contacts, directions=directions, ratio=float(ratio), backend=backend,
                 max_squeeze=max_sq, step=step, lift_test_step=s.get("lift_test_step"),
                 max_lift=s.get("max_lift"), lift=s.get("lift", True), description=top.get("description", ""),
                 path=path, quick=quick, expect=expect, placement_rule=rule,
                 accuracy=None if accuracy is None else float(accuracy),
                 expected_error=None if expected_error is None else float(expected_error))


def load_scene(path: str | Path, quick: bool = False) -> Scene:
    """Read and validate a scene file (``quick`` applies its ``[quick]`` overrides).

    Raises
    ------
    SceneError
        Missing file, invalid TOML, unknown key, wrong type, unit or range;
        the message names the file and the key.
    """
    p = Path(path).expanduser()
    data = _read_toml(p)
    return parse_scene(data, str(p), p.parent, quick=quick, path=p.resolve())


def shipped_scenes() -> dict[str, Path]:
    """The scenes shipped with the package: name → path."""
    return {p.stem: p for p in sorted(SCENE_DIR.glob("*.toml"))}


def resolve_scene(name_or_path: str | Path) -> Path:
    """A scene file path from a path or the name of a shipped scene (``tomato`` → ``scenes/tomato.toml``)."""
    p = Path(name_or_path).expanduser()
    if p.exists() or p.suffix == ".toml" or p.parent != Path("."):
        return p
    shipped = shipped_scenes()
    if str(name_or_path) in shipped:
        return shipped[str(name_or_path)]
    raise SceneError(f"no scene file {str(name_or_path)!r} and no shipped scene of that name; shipped scenes: "
                     f"{', '.join(shipped)}")


def with_overrides(scene: Scene, **changes: Any) -> Scene:
    """A copy of ``scene`` with some fields replaced (e.g. ``backend="spectral"``)."""
    return replace(scene, **{k: v for k, v in changes.items() if v is not None})


# ------------------------------------------------------------ resting state cache
#: Bump when the cached fields change.
REST_CACHE_FORMAT = 1
#: A cached state is used only if re-solving its contact set reproduces its forces to this (relative to mg + Σ|f|).
REST_CACHE_RTOL = 1e-8


def default_cache_dir() -> Path:
    """``$XDG_CACHE_HOME/fem_grasp`` or ``~/.cache/fem_grasp``."""
    import os

    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "fem_grasp"


def _rest_code_digest() -> str:
    """Digest of the source of the modules that compute a resting state (a change invalidates the cache)."""
    import hashlib

    here = Path(__file__).resolve().parent
    h = hashlib.sha256()
    for name in ("rest.py", "pose.py", "friction.py", "homotopy.py", "fem.py", "geometry.py"):
        f = here / name
        h.update(f.read_bytes() if f.exists() else name.encode())
    return h.hexdigest()[:16]


def rest_key(body: Any, mu_table: float, table_z: float = 0.0, down: Any = None) -> str:
    """Hash of everything a resting state depends on: mesh, E, ν, density, g, μ_𝒫, table, down, code."""
    import hashlib

    h = hashlib.sha256()
    h.update(np.ascontiguousarray(body.mesh.points, dtype=np.float64).tobytes())
    h.update(np.ascontiguousarray(body.mesh.tets, dtype=np.int64).tobytes())
    h.update(repr((REST_CACHE_FORMAT, float(body.young), float(body.poisson), float(body.density),
                   float(body.gravity), float(mu_table), float(table_z),
                   None if down is None else [float(x) for x in down], _rest_code_digest())).encode())
    return h.hexdigest()[:24]


def save_rest(path: Path, state: Any) -> None:
    """Write what :func:`load_rest` needs to rebuild a :class:`~fem_grasp.rest.RestState` (atomic .npz)."""
    import io

    from .output import atomic_write_bytes

    buf = io.BytesIO()
    np.savez(buf, format=np.array(REST_CACHE_FORMAT), table_z=np.array(state.table_z),
             mu_table=np.array(state.mu_table), rotation=state.pose.rotation, translation=state.pose.translation,
             triangle=state.pose.triangle, margin=np.array(state.pose.margin), positions=state.positions,
             contact_nodes=state.contact_nodes, contact_forces=state.contact_forces,
             contact_displacements=state.contact_displacements, sliding=state.sliding,
             iterations=np.array(state.iterations), wall_time=np.array(state.wall_time))
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(path, buf.getvalue())


def load_rest(path: Path, body: Any, backend: str = "sparse") -> Any:
    """Rebuild a resting state of ``body`` from :func:`save_rest`'s file, or None if it is not valid.

    The posed body is rebuilt from the stored rigid motion; the contact
    solution is recomputed from the stored contact displacements (one solve),
    and the entry is rejected unless that reproduces the stored forces and
    positions and :meth:`~fem_grasp.rest.RestState.check` passes.  The
    iteration history is not stored (``history`` is empty).
    """
    from .pose import RestingPose
    from .rest import RestState

    try:
        with np.load(path) as z:
            d = {k: z[k] for k in z.files}
        if int(d["format"]) != REST_CACHE_FORMAT:
            return None
        posed = body.transformed(d["rotation"], d["translation"])
        nodes = d["contact_nodes"].astype(np.int64)
        sol = posed.contact_response(nodes, backend=backend).solve(d["contact_displacements"])
        scale = posed.weight + float(np.abs(d["contact_forces"]).sum())
        if (np.abs(sol.forces - d["contact_forces"]).max() > REST_CACHE_RTOL * scale
                or np.abs(sol.positions - d["positions"]).max() > 1e-9 * posed.mesh.diameter):
            log.warning("cached resting state %s does not reproduce its forces; recomputing", path)
            return None
        pose = RestingPose(posed, d["triangle"].astype(np.int64), d["rotation"], d["translation"],
                           float(d["margin"]), None)
        state = RestState(posed, float(d["table_z"]), float(d["mu_table"]), sol.positions, sol.displacements, nodes,
                          sol.forces, d["contact_displacements"], d["sliding"].astype(bool),
                          d["triangle"].astype(np.int64), [], int(d["iterations"]), float(d["wall_time"]), pose, sol)
        if not state.check(raise_on_failure=False)["ok"]:
            log.warning("cached resting state %s fails its checks; recomputing", path)
            return None
        return state
    except Exception as exc:  # any damaged or foreign file: recompute
        log.warning("ignoring unreadable resting-state cache %s: %s", path, exc)
        return None


def cached_rest(body: Any, mu_table: float, *, backend: str = "sparse", down: Any = None,
                cache_dir: Path | None = None) -> tuple[Any, bool]:
    """The resting state of ``body`` (:func:`fem_grasp.rest.rest`), reused from ``cache_dir`` when valid.

    Returns
    -------
    (RestState, bool)
        The state and whether it came from the cache.
    """
    from .rest import rest

    path = None
    if cache_dir is not None:
        path = Path(cache_dir) / f"rest-{rest_key(body, mu_table, 0.0, down)}.npz"
        if path.exists():
            state = load_rest(path, body, backend)
            if state is not None:
                log.info("resting state from cache %s", path)
                return state, True
    state = rest(body, mu_table, backend=backend, down=None if down is None else np.asarray(down, float))
    if path is not None:
        try:
            save_rest(path, state)
        except OSError as exc:
            log.warning("could not cache the resting state in %s: %s", path, exc)
    return state, False
