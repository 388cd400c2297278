"""Scene files: one TOML file describes one pickup (object, material, friction, fingers, solver).

A scene names the object (a paper object, a volume mesh, a closed surface
scan, or a box), its material, the two friction coefficients μ_ℱ (fingers)
and μ_𝒫 (table), the fingertip radius, the initial contacts (node indices or
the default rule of :func:`fem_grasp.grasp.pickup.default_finger_contacts`), the
squeeze directions and ratio, and the solver settings of
:func:`fem_grasp.grasp.pickup.pickup`.  Example (every key but ``[object]`` is
optional)::

    name = "tomato"
    description = "Table I tomato at the effective modulus"

    [object]
    paper = "tomato"          # or: mesh = "scan.stl" (relative to this file), or box = ["4 cm", "3 cm", "2 cm"]
    vertices = 490            # remesh with gmsh at about this many vertices (paper shapes, scans, volume meshes)
    units = "mm"              # a mesh file's coordinates are in mm (or "cm"; default "m")

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
                              # two successive levels agree within it (fem_grasp.grasp.accuracy); omit for one run
    expected_error = 0.3      # how far a single run of this scene (no accuracy loop, e.g. its [quick] variant) is
                              # from the converged answer, as measured by `make converge`: printed with its answer

    [quick]                   # overrides for `--quick`: same tables, merged over the above
    object = { vertices = 200 }

Unknown keys, wrong types, units of the wrong kind and values out of range
raise :class:`SceneError`, whose message names the file and the key.
Units are spelled exactly as in SI (case matters: ``mPa`` is not ``MPa``): lengths
m, cm, mm, µm; pressures Pa, kPa, MPa, GPa; forces N, mN, kN; masses kg, g, mg;
densities kg/m^3, g/cm^3.  A bare number is in SI units.
"""

from __future__ import annotations

import copy
import logging
import math
import re
import sys
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..elastic.fem import STANDARD_GRAVITY
from ..errors import MeshError, SceneError
from ..grasp.placement import DEFAULT_PLACEMENT_RULE, PLACEMENT_RULES

__all__ = ["SCENE_DIR", "ObjectSpec", "Scene", "SceneError", "check_quantity", "load_scene", "parse_quantity",
           "parse_scene", "pickup_scene", "resolve_scene", "run_scene", "shipped_scenes", "with_overrides"]

if TYPE_CHECKING:
    from ..elastic.body import Body
    from ..grasp.pickup import PickupResult
    from ..mesh.tetmesh import TetMesh

log = logging.getLogger(__name__)

#: Folder of the scenes shipped with the package (``fem-grasp run tomato`` looks here).
SCENE_DIR = Path(__file__).resolve().parents[1] / "scenes"



# ------------------------------------------------------------------ units
#: Units by kind, spelled exactly as SI writes them (case matters: m is milli, M is mega).
_UNITS: dict[str, dict[str, float]] = {
    "length": {"m": 1.0, "cm": 1e-2, "mm": 1e-3, "um": 1e-6, "µm": 1e-6, "μm": 1e-6},
    "pressure": {"Pa": 1.0, "kPa": 1e3, "MPa": 1e6, "GPa": 1e9},
    "force": {"N": 1.0, "mN": 1e-3, "kN": 1e3},
    "mass": {"kg": 1.0, "g": 1e-3, "mg": 1e-6},
    "density": {"kg/m^3": 1.0, "kg/m3": 1.0, "kg/m³": 1.0, "g/cm^3": 1e3, "g/cm3": 1e3, "g/cm³": 1e3},
    "acceleration": {"m/s^2": 1.0, "m/s2": 1.0, "m/s²": 1.0},
}
#: What each unit is called, for messages that suggest the intended one.
_UNIT_NAMES = {"m": "metre", "cm": "centimetre", "mm": "millimetre", "um": "micrometre", "µm": "micrometre",
               "μm": "micrometre", "Pa": "pascal", "kPa": "kilopascal", "MPa": "megapascal", "GPa": "gigapascal",
               "N": "newton", "mN": "millinewton", "kN": "kilonewton", "kg": "kilogram", "g": "gram",
               "mg": "milligram"}
_SI = {"length": "m", "pressure": "Pa", "force": "N", "mass": "kg", "density": "kg/m^3", "acceleration": "m/s^2"}
_QUANTITY = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*([^\s\d].*?)?\s*$")


def _named(unit: str) -> str:
    return f"'{unit}' ({_UNIT_NAMES[unit]})" if unit in _UNIT_NAMES else f"'{unit}'"


def parse_quantity(value: Any, kind: str, where: str = "value") -> float:
    """A number (SI) or a string ``"<number> <unit>"`` of the given kind → float in SI units.

    Units are the exact SI spellings of :data:`_UNITS` (``"kPa"``, ``"mm"``, ``"mN"``): case matters, since
    ``m`` is milli and ``M`` mega.  A unit that matches one only when case is ignored (``"10 mPa"``,
    ``"1 CM"``) is refused with a message that suggests the intended unit; a unit of another kind
    (``"3 mm"`` for a pressure) is refused naming both kinds.

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
                         f"\"{_example(kind)}\"), got {value!r}")
    m = _QUANTITY.match(value)
    if not m:
        raise SceneError(f"{where}: cannot read {value!r} as a {kind} (write a number and a unit, e.g. "
                         f"\"{_example(kind)}\")")
    number, unit = float(m.group(1)), (m.group(2) or "").strip()
    if not unit:
        return number
    table = _UNITS[kind]
    if unit in table:
        return number * table[unit]
    takes = f"a {kind} takes {', '.join(_display_units(kind))}"
    for other, units in _UNITS.items():
        if other != kind and unit in units:
            raise SceneError(f"{where}: {value!r} is a {other}, but a {kind} is expected ({takes})")
    same_kind = [u for u in table if u.lower() == unit.lower()]
    if same_kind:
        milli = " (m is milli, M is mega)" if any(u[0] != unit[0] and u[0] in "mM" for u in same_kind) else ""
        raise SceneError(f"{where}: unknown unit {unit!r} in {value!r}: units are case-sensitive{milli}; did you "
                         f"mean {' or '.join(_named(u) for u in same_kind)}? ({takes})")
    other_kind = [(u, o) for o, units in _UNITS.items() for u in units if u.lower() == unit.lower()]
    if other_kind:
        u, o = other_kind[0]
        raise SceneError(f"{where}: unknown unit {unit!r} in {value!r}; {takes} (units are case-sensitive: "
                         f"{_named(u)} would be a {o})")
    raise SceneError(f"{where}: unknown unit {unit!r} in {value!r}; {takes}")


def _display_units(kind: str) -> list[str]:
    return {"length": ["m", "cm", "mm", "µm"], "pressure": ["Pa", "kPa", "MPa", "GPa"], "force": ["N", "mN", "kN"],
            "mass": ["kg", "g", "mg"], "density": ["kg/m^3", "g/cm^3"], "acceleration": ["m/s^2"]}[kind]


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
    units : the length unit of a mesh file's coordinates, "m" (default), "cm" or "mm" (scans are often in mm)
    allow_implausible_units : compute even when the mesh's size or density says its unit is wrong (an object
        over 1 m across, or with a density outside 10–20,000 kg/m³); by default such a scene is refused with
        a :class:`~fem_grasp.errors.UnitsError` before anything is computed
    """

    paper: str | None = None
    mesh: Path | None = None
    box: tuple[float, float, float] | None = None
    divisions: tuple[int, int, int] = (4, 4, 4)
    vertices: int | None = None
    size: float | None = None
    down: tuple[float, float, float] | None = None
    units: str = "m"
    allow_implausible_units: bool = False

    @property
    def kind(self) -> str:
        return "paper" if self.paper else "mesh" if self.mesh else "box"


@dataclass(frozen=True)
class Scene:
    """A parsed, validated scene (SI units throughout).

    ``young``, ``poisson``, ``weight``/``density``/``mass`` and friction may be None
    in the file for a paper object (Table I and :data:`~fem_grasp.grasp.objects.EFFECTIVE_YOUNG_ESTIMATE`
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
    def load_mesh(self, cache_dir: Path | None = None) -> "TetMesh":
        """The object's :class:`~fem_grasp.mesh.TetMesh` (gmsh meshes are cached in ``cache_dir``)."""
        from ..mesh.tetmesh import TetMesh, box_mesh
        from .cache import cached_mesh, digest

        spec = self.object
        if spec.kind == "box":
            lx, ly, lz = spec.box
            return box_mesh((-lx / 2, -ly / 2, 0.0), (lx / 2, ly / 2, lz), spec.divisions)
        if spec.kind == "paper":
            if spec.vertices is None:
                from ..grasp import objects

                return objects.load_mesh(spec.paper)
            from ..mesh.shapes import PAPER_SHAPES

            # the shape's spec is in the key: a changed stand-in shape must not be served from the cache
            return cached_mesh(cache_dir, ("paper", spec.paper, spec.vertices, PAPER_SHAPES[spec.paper]),
                                lambda: _paper_mesh(spec.paper, spec.vertices))
        path = spec.mesh
        from ..mesh import scan
        from ..mesh.units import LENGTH_UNITS

        scale = LENGTH_UNITS[spec.units]
        data = path.read_bytes()
        if path.suffix.lower() in scan.SURFACE_SUFFIXES:
            def surface() -> "TetMesh":
                surf = scan.read_surface(path)
                surf = scan.Surface(surf.points * scale, surf.faces, surf.source)
                return scan.mesh_surface(surf, target_vertices=spec.vertices, size=spec.size)

            return cached_mesh(cache_dir, ("surface", digest(data), spec.vertices, spec.size, spec.units), surface)
        try:
            volume = TetMesh.from_file(path)
        except MeshError:
            raise
        except Exception as exc:  # meshio raises many types for unreadable files
            raise SceneError(f"{self.path or '<scene>'}: object.mesh: cannot read {path} as a volume mesh "
                             f"({type(exc).__name__}: {exc})", file=None if self.path is None else str(self.path),
                             key="object.mesh") from None
        if scale != 1.0:
            volume = TetMesh(volume.points * scale, volume.tets)
        if spec.vertices is None and spec.size is None:
            return volume
        # object.vertices / object.size on a volume mesh: remesh the solid its boundary encloses (gmsh)
        log.info("%s: remeshing the volume mesh's boundary at %s", path,
                 f"about {spec.vertices} vertices" if spec.vertices else f"size {spec.size:g} m")
        boundary = scan.Surface(volume.points, volume.surface_faces, str(path))
        return cached_mesh(cache_dir, ("volume", digest(data), spec.vertices, spec.size, spec.units),
                           lambda: scan.mesh_surface(boundary, target_vertices=spec.vertices, size=spec.size))

    def body(self, cache_dir: Path | None = None) -> "Body":
        """The :class:`~fem_grasp.elastic.body.Body` of this scene."""
        from ..elastic.body import Body

        mesh = self.load_mesh(cache_dir)
        if self.object.kind == "mesh":  # a file's unit is not written in it: refuse when it looks wrong
            self._check_units(mesh)
        kw = {"weight": self.weight} if self.weight is not None else {"density": self.density}
        return Body(mesh, self.young, self.poisson, gravity=self.gravity, **kw)

    def _check_units(self, mesh: "TetMesh") -> None:
        """Refuse a mesh whose size or density says it is in another length unit (:class:`UnitsError`, before
        anything is computed), or warn (:class:`~fem_grasp.errors.UnitsWarning`) when the scene allows it."""
        from ..errors import UnitsError
        from ..mesh.units import density_warning, implausible, size_warning, warn_implausible

        spec = self.object
        mass = None if self.weight is None else self.weight / self.gravity
        problems, guess = implausible(mesh.diameter, mesh.volume, mass, spec.units)
        if not problems:
            return
        src = f"{self.path or '<scene>'}: object.mesh ({spec.mesh.name})"
        if spec.allow_implausible_units:
            warn_implausible(size_warning(mesh.diameter, spec.units, src, hint="object.units"))
            if mass is not None:
                warn_implausible(density_warning(mass, mesh.volume, spec.units, src, hint="object.units"))
            return
        names = {"m": "metres", "cm": "centimetres", "mm": "millimetres"}
        fix = (f"the file is probably in {names[guess]}: set units = \"{guess}\" in the scene's [object] table "
               f"(Python: scene.with_(units=\"{guess}\"))" if guess is not None else
               "check the unit of the mesh (object.units = \"mm\" or \"cm\") and the weight, mass or density")
        read = f"read in {names[spec.units]}"
        file = None if self.path is None else str(self.path)
        raise UnitsError(
            f"{src}: {read}, {' and '.join(problems)}; {fix}. Nothing was computed, as squeeze depths and forces of "
            "an object in the wrong unit mean nothing. If the object really is so, run it anyway with "
            "--allow-implausible-units (scene: allow_implausible_units = true in [object]; Python: "
            "allow_implausible_units=True)", file=file, key="object.units")

    def geometry(self) -> "Any":
        """What ``accuracy`` remeshes (:mod:`fem_grasp.mesh.remesh`): the paper shape, the box, the scan's surface;
        None for a volume mesh file (the loop then remeshes the mesh's own boundary)."""
        from ..mesh import remesh

        return remesh.geometry_of_scene(self)

    def pickup_kwargs(self) -> dict[str, Any]:
        """Keyword arguments of :func:`fem_grasp.grasp.pickup.pickup` (all but ``body`` and ``rest_state``).

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

    # ------------------------------------------------------------ the front door
    @classmethod
    def load(cls, name_or_path: str | Path, quick: bool = False) -> "Scene":
        """A shipped scene by name (``"tomato"``) or a scene file, parsed and checked (``quick``: its ``[quick]``
        overrides).  Same as :func:`load_scene` (:func:`resolve_scene` first)."""
        return load_scene(resolve_scene(name_or_path), quick=quick)

    def with_(self, **changes: Any) -> "Scene":
        """A copy with some settings changed, given as in a scene file: numbers in SI units or strings with a
        unit, checked the same way.

        Keys: ``young``, ``poisson``, ``weight``, ``mass``, ``density``, ``gravity``; ``mu`` (both
        coefficients), ``mu_finger``, ``mu_table``; ``finger_radius``; ``contacts`` ("auto", a placement rule
        or two node indices) or ``placement_rule``; ``directions``, ``ratio``; ``backend``, ``max_squeeze``,
        ``step``, ``lift_test_step``, ``max_lift``, ``lift``; ``vertices`` (remesh); ``accuracy`` (0.05, "5%" or
        None: refine until ρ* and the finger force agree to it, :mod:`fem_grasp.grasp.accuracy`); for a mesh
        file ``units`` ("m", "cm", "mm") and ``allow_implausible_units`` (True: compute even when the object's
        size or density says its unit is wrong, with a warning, instead of refusing it).  Example:
        ``Scene.load("tomato").with_(young="15 kPa", mu=0.4)``.

        Raises
        ------
        SceneError
            An unknown key or a value of the wrong kind or range, naming the key.
        """
        return _with_changes(self, changes)

    def run(self, cache_dir: "Path | str | None | object" = "default") -> "PickupResult":
        """Pick the object up (Algorithm 1) as ``fem-grasp run`` does; returns the
        :class:`~fem_grasp.grasp.PickupResult`.

        ``cache_dir``: where meshes and resting states are cached ("default": the CLI's cache,
        ``~/.cache/fem_grasp``; None: no cache).  A cached resting state is used only after it re-solves to the
        same forces, so the answer does not depend on the cache.
        """
        from .cache import default_cache_dir

        cache = default_cache_dir() if cache_dir == "default" else (None if cache_dir is None else Path(cache_dir))
        return pickup_scene(self, cache)[0]


def _paper_mesh(name: str, vertices: int) -> "TetMesh":
    from ..mesh import shapes

    return shapes.paper_mesh(name, vertices)


# ------------------------------------------------------------------ parsing
_SCHEMA: dict[str, dict[str, str]] = {
    "": {"name": "str", "description": "str", "expect": "str", "object": "table", "material": "table",
         "friction": "table", "fingers": "table", "solver": "table", "quick": "table"},
    "object": {"paper": "str", "mesh": "str", "box": "length3", "divisions": "int3", "vertices": "int",
               "size": "length", "down": "vec3", "units": "str", "allow_implausible_units": "bool"},
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


def _close_keys(key: str, allowed: list[str]) -> list[str]:
    """The keys a mistyped ``key`` probably meant: close spellings (difflib), then keys with its first letters."""
    import difflib

    close = difflib.get_close_matches(key, allowed, n=3, cutoff=0.6)
    close += [a for a in allowed if a.lower().startswith(key.lower()[:3]) and a not in close]
    return close


def _check_keys(data: dict[str, Any], table: str, src: str) -> None:
    allowed = _SCHEMA[table]
    for key in data:
        if key not in allowed:
            full = f"{table}.{key}" if table else key
            close = _close_keys(key, list(allowed))
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


def check_quantity(w: str, v: float | None, unit: str, allow_zero: bool = False) -> None:
    """Raise :class:`SceneError` naming ``w`` unless ``v`` (SI, ``unit``) is finite and > 0.

    With ``allow_zero`` zero passes too; None (a key not given) always passes.
    """
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
    from ..contact.obstacles import DEFAULT_RADIUS
    from ..grasp import objects
    from ..grasp.placement import PAPER_SQUEEZE_DIRECTIONS

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
            check_quantity(f"{o.where('box')}[{i}]", x, "m")
    divisions = o.get("divisions", (4, 4, 4))
    if min(divisions) < 1:
        raise SceneError(f"{o.where('divisions')} must be positive integers, got {list(divisions)}")
    vertices = o.get("vertices")
    if vertices is not None and vertices < 20:
        raise SceneError(f"{o.where('vertices')} must be at least 20 (a tetrahedral mesh to compute on), got {vertices}")
    if vertices is not None and box is not None:
        raise SceneError(f"{o.where('vertices')}: a box is meshed by its divisions, not a vertex count")
    size = o.get("size")
    check_quantity(o.where("size"), size, "m")
    if size is not None and paper is not None:
        raise SceneError(f"{o.where('size')}: a paper object is remeshed by vertex count (object.vertices), not size")
    down = o.get("down")
    if down is not None and not any(down):
        raise SceneError(f"{o.where('down')} must be a non-zero vector, got {list(down)}")
    units = o.get("units", "m")
    from ..mesh.units import LENGTH_UNITS

    if units not in LENGTH_UNITS:
        raise SceneError(f"{o.where('units')}: the unit of the mesh file's coordinates is one of "
                         f"{', '.join(repr(u) for u in LENGTH_UNITS)}, got {units!r}")
    if o.has("units") and mesh_path is None:
        raise SceneError(f"{o.where('units')}: units says what a mesh file's coordinates are in; a "
                         f"{'paper object' if paper else 'box'} is in metres already")
    allow_units = o.get("allow_implausible_units", False)
    if o.has("allow_implausible_units") and mesh_path is None:
        raise SceneError(f"{o.where('allow_implausible_units')}: only a mesh file's size and density are checked "
                         f"for their unit; a {'paper object' if paper else 'box'} needs no permission")
    spec = ObjectSpec(paper, mesh_path, box, tuple(divisions), vertices, size, down, units, allow_units)

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
    check_quantity(m.where("gravity"), gravity, "m/s^2")
    weight = density = None
    if m.has("weight"):
        weight = m.get("weight")
        check_quantity(m.where("weight"), weight, "N")
    elif m.has("mass"):
        mass = m.get("mass")
        check_quantity(m.where("mass"), mass, "kg")
        weight = mass * gravity
    elif m.has("density"):
        density = m.get("density")
        check_quantity(m.where("density"), density, "kg/m^3")
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
    check_quantity(f.where("finger"), mu_f, "friction coefficient", allow_zero=True)
    if mu_f == 0:
        from ..validation import FRICTIONLESS_FINGERS

        raise SceneError(f"{f.where('finger')} (μ_F) must be > 0, got 0: {FRICTIONLESS_FINGERS}")
    check_quantity(f.where("table"), mu_t, "friction coefficient", allow_zero=True)

    # [fingers]
    g = tables["fingers"]
    radius = g.get("radius", DEFAULT_RADIUS)
    check_quantity(g.where("radius"), radius, "m")
    contacts = g.get("contacts")
    rule = DEFAULT_PLACEMENT_RULE
    if isinstance(contacts, str):
        rule, contacts = contacts, None
    directions = g.get("directions", tuple(tuple(float(x) for x in d) for d in PAPER_SQUEEZE_DIRECTIONS))
    ratio = g.get("ratio", 1.0)
    check_quantity(g.where("ratio"), ratio, "dimensionless", allow_zero=True)

    # [solver]
    s = tables["solver"]
    backend = s.get("backend", "sparse")
    if backend not in ("sparse", "spectral"):
        raise SceneError(f"{s.where('backend')} must be \"sparse\" or \"spectral\", got {backend!r}")
    for key, unit in (("max_squeeze", "m"), ("step", "m"), ("lift_test_step", "N"), ("max_lift", "m")):
        check_quantity(s.where(key), s.get(key), unit)
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
    try:
        data = _read_toml(p)
        return parse_scene(data, str(p), p.parent, quick=quick, path=p.resolve())
    except SceneError as exc:
        _locate(exc, str(p))
        raise


#: A dotted scene key (``material.young``, ``quick.object``) as a message names it after the file.
_KEY = re.compile(r"^[A-Za-z_][\w]*(?:\.[A-Za-z_][\w]*)*$")


def _locate(exc: SceneError, src: str) -> None:
    """Fill in ``exc.file`` and ``exc.key`` from a message that starts "<file>: <key>: …"."""
    if exc.file is None:
        exc.file = src
    text = str(exc)
    if exc.key is None and text.startswith(src):
        rest = text[len(src):].removeprefix(" [quick]").removeprefix(": ")
        head = rest.split(": ", 1)[0]
        if ": " in rest and _KEY.match(head):
            exc.key = head


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


#: Scene fields whose change leaves the answer of a single run as it was (the backends agree to round-off; the
#: accuracy target and the lift's extent do not change ρ* or the forces at lift-off): a change of any other field
#: makes the scene's stated error (``[solver] expected_error``, measured by the convergence study at the scene's
#: own settings) no longer the run's.
_ERROR_NEUTRAL = frozenset({"backend", "accuracy", "lift", "max_lift"})


def _without_borrowed_error(scene: Scene, new: Scene, fields: Any) -> Scene:
    """``new`` without the stated error of ``scene`` when one of ``fields`` changes the answer (a changed modulus,
    friction, weight, mesh, … gets no error measured at other settings)."""
    changed = [f for f in fields if f not in _ERROR_NEUTRAL and getattr(new, f) != getattr(scene, f)]
    if changed and new.expected_error is not None:
        log.info("the scene's stated error (%g) was measured at its own settings, not with %s changed: the run "
                 "states none", new.expected_error, ", ".join(changed))
        return replace(new, expected_error=None)
    return new


def with_overrides(scene: Scene, **changes: Any) -> Scene:
    """A copy of ``scene`` with some fields replaced (e.g. ``backend="spectral"``); a change that moves the answer
    drops the error the scene states for its own settings."""
    given = {k: v for k, v in changes.items() if v is not None}
    return _without_borrowed_error(scene, replace(scene, **given), given)


# ------------------------------------------------------------------ running a scene
#: The keys of :meth:`Scene.with_`: the field each sets and the kind of its value.
_CHANGES: dict[str, tuple[str, str]] = {
    "young": ("young", "pressure"), "poisson": ("poisson", "float"), "weight": ("weight", "force"),
    "mass": ("weight", "mass"), "density": ("density", "density"), "gravity": ("gravity", "acceleration"),
    "mu": ("mu", "friction"), "mu_finger": ("mu_finger", "friction"), "mu_table": ("mu_table", "friction"),
    "finger_radius": ("finger_radius", "length"), "contacts": ("contacts", "contacts"),
    "placement_rule": ("placement_rule", "rule"), "directions": ("directions", "directions"),
    "ratio": ("ratio", "ratio"), "backend": ("backend", "backend"), "max_squeeze": ("max_squeeze", "length"),
    "step": ("step", "length"), "lift_test_step": ("lift_test_step", "force"), "max_lift": ("max_lift", "length"),
    "lift": ("lift", "bool"), "vertices": ("vertices", "int"), "accuracy": ("accuracy", "accuracy"),
    "units": ("units", "units"), "allow_implausible_units": ("allow_implausible_units", "allow_units"),
}


def parse_accuracy(value: Any, where: str = "accuracy") -> float | None:
    """An accuracy setting: a relative error (0.05), a percentage ("5%"), or off (None, "off": one run on the
    scene's mesh).  Raises :class:`~fem_grasp.errors.SceneError` naming ``where`` for anything else."""
    if value is None:
        return None
    if isinstance(value, str):
        t = value.strip().lower()
        if t in ("off", "none", "no"):
            return None
        try:
            v = float(t[:-1]) / 100.0 if t.endswith("%") else float(t)
        except ValueError:
            raise SceneError(f"{where}: expected a relative error such as 0.05, a percentage such as 5%, or off; "
                             f"got {value!r}") from None
    elif isinstance(value, bool) or not isinstance(value, (int, float)):
        raise SceneError(f"{where}: expected a relative error such as 0.05, got {value!r}")
    else:
        v = float(value)
    if not 0.0 < v < 1.0:
        raise SceneError(f"{where}: a relative error in (0, 1) (e.g. 0.05 or 5%), got {value!r}")
    return v


def _with_changes(scene: Scene, changes: dict[str, Any]) -> Scene:
    new: dict[str, Any] = {}
    for key, value in changes.items():
        if key not in _CHANGES:
            close = _close_keys(key, list(_CHANGES))
            hint = f" (did you mean {', '.join(repr(c) for c in close)}?)" if close else ""
            raise SceneError(f"Scene.with_: unknown setting {key!r}{hint}; it takes {', '.join(_CHANGES)}")
        field_name, kind = _CHANGES[key]
        w = f"Scene.with_({key}=…)"
        if kind in _UNITS:
            v = parse_quantity(value, kind, w)
            check_quantity(w, v, _SI[kind])
            if key == "mass":
                v *= new.get("gravity", scene.gravity)
            if field_name in ("weight", "density"):
                new["weight" if field_name == "density" else "density"] = None
            new[field_name] = v
        elif kind == "float":  # Poisson's ratio
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not -1.0 < value < 0.5:
                raise SceneError(f"{w}: Poisson's ratio must be a number in (-1, 0.5), got {value!r}")
            new[field_name] = float(value)
        elif kind in ("friction", "ratio"):
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise SceneError(f"{w}: expected a number, got {value!r}")
            check_quantity(w, float(value), "dimensionless", allow_zero=True)
            if key in ("mu", "mu_finger") and value == 0:
                from ..validation import FRICTIONLESS_FINGERS

                raise SceneError(f"{w}: μ_F must be > 0, got 0: {FRICTIONLESS_FINGERS}")
            if key == "mu":
                new["mu_finger"] = new["mu_table"] = float(value)
            else:
                new[field_name] = float(value)
        elif kind == "contacts":
            if value == "auto" or value is None:
                new["contacts"] = None
            elif isinstance(value, str):
                if value not in PLACEMENT_RULES:
                    raise SceneError(f"{w}: expected \"auto\", a placement rule ({', '.join(PLACEMENT_RULES)}) or "
                                     f"two node indices, got {value!r}")
                new["contacts"], new["placement_rule"] = None, value
            else:
                ij = tuple(value)
                if (len(ij) != 2 or not all(isinstance(k, (int, np.integer)) and not isinstance(k, bool) for k in ij)
                        or ij[0] == ij[1] or min(ij) < 0):
                    raise SceneError(f"{w}: expected two distinct non-negative node indices, got {value!r}")
                new["contacts"] = (int(ij[0]), int(ij[1]))
        elif kind == "rule":
            if value not in PLACEMENT_RULES:
                raise SceneError(f"{w}: choose one of {', '.join(PLACEMENT_RULES)}, got {value!r}")
            new["placement_rule"] = value
        elif kind == "directions":
            d = np.asarray(value, dtype=float)
            if d.shape != (2, 3) or not np.isfinite(d).all() or not (np.linalg.norm(d, axis=1) > 0).all():
                raise SceneError(f"{w}: expected two non-zero 3-vectors, got {value!r}")
            new["directions"] = tuple(tuple(float(x) for x in row / np.linalg.norm(row)) for row in d)
        elif kind == "backend":
            if value not in ("sparse", "spectral"):
                raise SceneError(f"{w}: \"sparse\" or \"spectral\", got {value!r}")
            new["backend"] = value
        elif kind == "bool":
            if not isinstance(value, bool):
                raise SceneError(f"{w}: expected True or False, got {value!r}")
            new["lift"] = value
        elif kind == "accuracy":
            new["accuracy"] = parse_accuracy(value, w)
        elif kind in ("units", "allow_units"):  # the mesh file's length unit, and whether to check it
            from ..mesh.units import LENGTH_UNITS

            if scene.object.kind != "mesh":
                raise SceneError(f"{w}: only a mesh file has a length unit; a {scene.object.kind} object is in "
                                 "metres already")
            if kind == "units" and value not in LENGTH_UNITS:
                raise SceneError(f"{w}: the unit of the mesh file's coordinates is one of "
                                 f"{', '.join(repr(u) for u in LENGTH_UNITS)}, got {value!r}")
            if kind == "allow_units" and not isinstance(value, bool):
                raise SceneError(f"{w}: expected True or False, got {value!r}")
            new["object"] = replace(new.get("object", scene.object), **{field_name: value})
        elif kind == "int":  # vertices: remesh
            if isinstance(value, bool) or not isinstance(value, int) or value < 20:
                raise SceneError(f"{w}: expected an integer ≥ 20, got {value!r}")
            if scene.object.kind == "box":
                raise SceneError(f"{w}: a box is meshed by its divisions, not a vertex count")
            new["object"] = replace(new.get("object", scene.object), vertices=value)
    return _without_borrowed_error(scene, replace(scene, **new), new)


def pickup_scene(scene: Scene, cache_dir: Path | None = None, phase: Any = None) -> tuple["PickupResult", bool]:
    """Run a scene as ``fem-grasp run`` does: its body (mesh cached in ``cache_dir``), its resting state (cached,
    re-solved before use), then :func:`~fem_grasp.grasp.pickup.pickup` with its settings.

    ``phase``, when given, is called with a phase name ("meshing the object", "resting on the table",
    "squeeze, lift test, lift") and returns a context manager around that phase (the CLI's progress bar).
    Errors about the fingers (contact nodes, placement, squeeze directions) are raised naming the scene file
    and its key.  ``result.timings["rest"]`` is the time the resting state took (to solve or to check from the
    cache).  Returns (result, whether the resting state came from the cache).
    """
    import contextlib
    import time

    from ..grasp.pickup import pickup
    from .cache import cached_rest

    step = phase if phase is not None else (lambda name: contextlib.nullcontext())
    with step("meshing the object"):
        body = scene.body(cache_dir)
        _check_contacts(scene, body.mesh)
    t0 = time.perf_counter()
    with step("resting on the table"):
        rs, cached = cached_rest(body, scene.mu_table, backend=scene.backend, down=scene.object.down,
                                 cache_dir=cache_dir)
    t_rest = time.perf_counter() - t0
    refine = scene.accuracy is not None and not scene.quick
    with step("squeeze and lift, refining" if refine else "squeeze, lift test, lift"):
        try:
            if refine:
                result = pickup(body, accuracy=scene.accuracy, geometry=scene.geometry(), rest_state=rs,
                                **scene.pickup_kwargs())
            else:
                result = pickup(body, rest_state=rs, **scene.pickup_kwargs())
                from ..grasp.accuracy import single_run_report

                # One run, always said so: not converged; the scene states how far such a run is from the converged
                # answer (its solver.expected_error, measured by the convergence study), or nothing is known.
                result.accuracy = single_run_report(
                    result, scene.accuracy, scene.expected_error,
                    "--quick: one run on the coarse mesh, no refinement" if scene.quick else
                    "one run on the scene's mesh (accuracy off)")
        except SceneError as exc:
            raise _in_scene(scene, exc) from None
    result.timings["rest"] = t_rest
    result.timings["total"] = result.timings.get("total", 0.0) + t_rest
    return result, cached


def run_scene(scene: str | Path | Scene, *, quick: bool = False, cache_dir: Path | str | None | object = "default",
              **changes: Any) -> "PickupResult":
    """One line from a scene to its answer: ``fem_grasp.run_scene("tomato", young="15 kPa")``.

    ``scene`` is a shipped scene's name, a scene file or a :class:`Scene`; ``quick`` applies its ``[quick]``
    overrides; ``changes`` are :meth:`Scene.with_`'s (units as in scene files); ``cache_dir`` as in
    :meth:`Scene.run`.  The same answer as ``fem-grasp run`` with the same settings.
    """
    sc = scene if isinstance(scene, Scene) else Scene.load(scene, quick=quick)
    return sc.with_(**changes).run(cache_dir)


def _check_contacts(scene: Scene, mesh: "TetMesh") -> None:
    """Node indices given in the scene exist and lie on the surface (else a SceneError naming the file and key)."""
    if scene.contacts is None:
        return
    src = scene.path or "<scene>"
    surface = set(mesh.surface_nodes.tolist())
    for k in scene.contacts:
        if k >= mesh.n_points:
            raise SceneError(f"{src}: fingers.contacts: node {k} does not exist (the mesh has {mesh.n_points} nodes, "
                             f"0 … {mesh.n_points - 1}); with --quick the mesh differs, use contacts = \"auto\"",
                             file=str(src), key="fingers.contacts")
        if k not in surface:
            raise SceneError(f"{src}: fingers.contacts: node {k} is not on the surface of the mesh",
                             file=str(src), key="fingers.contacts")


#: The scene key an error about the fingers is about.
_ERROR_KEYS = {"DirectionError": "fingers.directions", "ContactNodeError": "fingers.contacts",
               "PlacementError": "fingers.contacts"}


def _in_scene(scene: Scene, exc: SceneError) -> SceneError:
    """``exc`` (raised by pickup() for the scene's settings) again, its message starting with the file and key."""
    if exc.file is not None:
        return exc
    src = str(scene.path) if scene.path is not None else "<scene>"
    key = _ERROR_KEYS.get(type(exc).__name__, "fingers")
    how = "" if scene.contacts is not None or key != "fingers.contacts" else \
        f" (contacts chosen by the rule {scene.placement_rule!r})"
    return type(exc)(f"{src}: {key}{how}: {exc}", file=src, key=key)
