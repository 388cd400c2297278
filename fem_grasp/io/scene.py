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
    step_divisions = 1        # squeeze the increment in which the lift test first passes again in this many parts:
                              # ρ* to within step / step_divisions for a few more lift tests
    lift_test_step = "0.05 N"
    max_lift = "5 cm"
    lift = true
    accuracy = 0.05           # relative accuracy of ρ* and the finger force (the default): refine at the contact
                              # patches until the answer's estimated error is within it (fem_grasp.grasp.accuracy);
                              # "off" for one run on the scene's mesh, the paper's Algorithm 1 as printed
    max_finger_contacts = 300 # with accuracy: a level predicted to put more contacts on a fingertip is not run
    max_seconds = 120         # with accuracy: a time budget; a level predicted to overrun it is not run
    refinement = "nested"     # with accuracy: bisect the level before at the patches ("nested", the default)
                              # or mesh the object afresh at each level ("remesh")
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

import math
import re
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..elastic.fem import STANDARD_GRAVITY
from ..errors import SceneError
from ..grasp.accuracy import DEFAULT_ACCURACY
from ..grasp.options import REFINEMENTS, PickupOptions
from ..grasp.placement import DEFAULT_PLACEMENT_RULE
from .quantities import check_quantity, parse_quantity
from .quantities import parse_accuracy as parse_accuracy
from .scene_changes import with_changes, with_overrides
from .scene_file import (
    SCENE_DIR,
    SCHEMA,
    TableReader,
    check_keys,
    merge_tables,
    read_toml,
    resolve_scene,
    shipped_scenes,
)
from .scene_mesh import check_units, scene_mesh
from .scene_run import pickup_scene

__all__ = ["SCENE_DIR", "SCENE_PICKUP_OPTIONS", "ObjectSpec", "Scene", "SceneError", "check_quantity", "load_scene",
           "parse_quantity", "parse_scene", "pickup_scene", "resolve_scene", "run_scene", "shipped_scenes", "with_overrides"]

if TYPE_CHECKING:
    from ..elastic.body import Body
    from ..grasp.pickup import PickupResult
    from ..mesh.tetmesh import TetMesh

#: The :class:`~fem_grasp.grasp.options.PickupOptions` fields a scene sets (:meth:`Scene.pickup_kwargs`): all but
#: ``max_lift_attempts`` (the default), ``accuracy`` and ``geometry`` (added by a caller that refines).
SCENE_PICKUP_OPTIONS = ("mu_finger", "mu_table", "finger_radius", "contacts", "directions", "ratio", "max_squeeze",
                        "step", "backend", "lift_test_step", "max_lift", "lift", "placement_rule")


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
    accuracy: float | None = DEFAULT_ACCURACY
    expected_error: float | None = None
    max_finger_contacts: int | None = None
    step_divisions: int | None = None
    max_seconds: float | None = None
    refinement: str | None = None

    # ------------------------------------------------------------ building
    def load_mesh(self, cache_dir: Path | None = None) -> "TetMesh":
        """The object's :class:`~fem_grasp.mesh.TetMesh` (gmsh meshes are cached in ``cache_dir``)."""
        return scene_mesh(self, cache_dir)

    def body(self, cache_dir: Path | None = None) -> "Body":
        """The :class:`~fem_grasp.elastic.body.Body` of this scene."""
        from ..elastic.body import Body

        mesh = self.load_mesh(cache_dir)
        if self.object.kind == "mesh":  # a file's unit is not written in it: refuse when it looks wrong
            check_units(self, mesh)
        kw = {"weight": self.weight} if self.weight is not None else {"density": self.density}
        return Body(mesh, self.young, self.poisson, gravity=self.gravity, **kw)

    def geometry(self) -> "Any":
        """What ``accuracy`` remeshes (:mod:`fem_grasp.mesh.remesh`): the paper shape, the box, the scan's surface;
        None for a volume mesh file (the loop then remeshes the mesh's own boundary)."""
        from ..mesh import remesh

        return remesh.geometry_of_scene(self)

    def pickup_options(self) -> PickupOptions:
        """The scene's options of :func:`fem_grasp.grasp.pickup.pickup`
        (:class:`~fem_grasp.grasp.options.PickupOptions`: friction, fingers, solver): ``pickup(scene.body(),
        scene.pickup_options())``.

        ``accuracy`` is not among them: a caller that wants the converged answer adds it,
        ``scene.pickup_options().replace(accuracy=scene.accuracy, geometry=scene.geometry())`` (the CLI does,
        except with ``--quick``).
        """
        return PickupOptions(mu_finger=self.mu_finger, mu_table=self.mu_table, finger_radius=self.finger_radius,
                             contacts=self.contacts, directions=self.directions, ratio=self.ratio,
                             max_squeeze=self.max_squeeze, step=self.step, lift_test_step=self.lift_test_step,
                             max_lift=self.max_lift, lift=self.lift, placement_rule=self.placement_rule,
                             backend=self.backend,
                             **({} if self.max_finger_contacts is None else
                                {"max_finger_contacts": self.max_finger_contacts}),
                             step_divisions=self.step_divisions or 1, max_seconds=self.max_seconds,
                             **({} if self.refinement is None else {"refinement": self.refinement}))

    def pickup_kwargs(self) -> dict[str, Any]:
        """:meth:`pickup_options` as keyword arguments of :func:`fem_grasp.grasp.pickup.pickup`, by name: the fields
        a scene sets (all but ``max_lift_attempts``, ``accuracy`` and ``geometry``), for callers that change one
        before the call (``pickup(body, **kw)``)."""
        options = self.pickup_options()
        return {name: getattr(options, name) for name in SCENE_PICKUP_OPTIONS}

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
        ``step``, ``lift_test_step``, ``max_lift``, ``lift``; ``vertices`` (remesh); ``accuracy`` (0.05 or "5%":
        refine until the answer's estimated error is within it, :mod:`fem_grasp.grasp.accuracy`, 5 % unless the
        scene says otherwise; None or "off": one run on the scene's mesh),
        ``max_finger_contacts`` (the refinement's bound on one fingertip's contacts), ``max_seconds`` (its time
        budget) and ``refinement`` ("nested" or "remesh",
        :attr:`~fem_grasp.grasp.options.PickupOptions.refinement`); for a mesh file ``units`` ("m", "cm", "mm")
        and ``allow_implausible_units`` (True: compute even when the object's size or density says its unit is
        wrong, with a warning, instead of refusing it).  Example:
        ``Scene.load("tomato").with_(young="15 kPa", mu=0.4)``.

        Raises
        ------
        SceneError
            An unknown key or a value of the wrong kind or range, naming the key.
        """
        return with_changes(self, changes)

    def run(self, cache_dir: "Path | str | None | object" = "default") -> "PickupResult":
        """Pick the object up (Algorithm 1) as ``fem-grasp run`` does, refined to the scene's ``accuracy`` (5 %
        unless the scene says otherwise; ``with_(accuracy="off")``: one run on its mesh); returns the
        :class:`~fem_grasp.grasp.PickupResult`, whose ``accuracy`` holds the estimated error.

        ``cache_dir``: where meshes and resting states are cached ("default": the CLI's cache,
        ``~/.cache/fem_grasp``; None: no cache).  A cached resting state is used only after it re-solves to the
        same forces, so the answer does not depend on the cache.
        """
        from .cache import default_cache_dir

        cache = default_cache_dir() if cache_dir == "default" else (None if cache_dir is None else Path(cache_dir))
        return pickup_scene(self, cache)[0]


def parse_scene(data: dict[str, Any], src: str = "<scene>", base_dir: Path | None = None, quick: bool = False,
                path: Path | None = None) -> Scene:
    """Validate a scene dictionary (as read from TOML) and build a :class:`Scene`.

    ``quick`` merges the ``[quick]`` table over the others.  Relative mesh
    paths are taken from ``base_dir``.
    """
    from ..contact.obstacles import DEFAULT_RADIUS
    from ..grasp import objects
    from ..grasp.placement import PAPER_SQUEEZE_DIRECTIONS

    check_keys(data, "", src)
    quick_over = data.get("quick", {})
    for t, sub in quick_over.items():
        if t not in SCHEMA or t in ("", "quick") or not isinstance(sub, dict):
            raise SceneError(f"{src}: quick.{t}: [quick] overrides the tables object, material, friction, fingers, "
                             f"solver (e.g. quick.object = {{ vertices = 200 }}), got {t!r} = {sub!r}")
        check_keys(sub, t, f"{src} [quick]")
    if quick:
        data = merge_tables({k: v for k, v in data.items() if k != "quick"}, quick_over)
    top = TableReader(data, "", src)
    tables = {t: TableReader(data.get(t, {}), t, src) for t in ("object", "material", "friction", "fingers", "solver")}
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
    accuracy = s.get("accuracy", DEFAULT_ACCURACY)
    max_contacts = s.get("max_finger_contacts")
    if max_contacts is not None and not (isinstance(max_contacts, int) and max_contacts >= 1):
        raise SceneError(f"{s.where('max_finger_contacts')} is a whole number of contacts ≥ 1; got {max_contacts!r}")
    divisions = s.get("step_divisions")
    if divisions is not None and not (isinstance(divisions, int) and divisions >= 1):
        raise SceneError(f"{s.where('step_divisions')} is a whole number of sub-increments ≥ 1; got {divisions!r}")
    max_seconds = s.get("max_seconds")
    if max_seconds is not None and not (math.isfinite(max_seconds) and max_seconds > 0):
        raise SceneError(f"{s.where('max_seconds')} is a time budget in seconds > 0; got {max_seconds!r}")
    refinement = s.get("refinement")
    if refinement is not None and refinement not in REFINEMENTS:
        raise SceneError(f"{s.where('refinement')} must be one of {', '.join(repr(r) for r in REFINEMENTS)}; "
                         f"got {refinement!r}")
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
                 accuracy=accuracy,
                 expected_error=None if expected_error is None else float(expected_error),
                 max_finger_contacts=max_contacts, step_divisions=divisions,
                 max_seconds=None if max_seconds is None else float(max_seconds), refinement=refinement)


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
        data = read_toml(p)
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


def run_scene(scene: str | Path | Scene, *, quick: bool = False, cache_dir: Path | str | None | object = "default",
              **changes: Any) -> "PickupResult":
    """One line from a scene to its answer: ``fem_grasp.run_scene("tomato", young="15 kPa")``.

    ``scene`` is a shipped scene's name, a scene file or a :class:`Scene`; ``quick`` applies its ``[quick]``
    overrides; ``changes`` are :meth:`Scene.with_`'s (units as in scene files); ``cache_dir`` as in
    :meth:`Scene.run`.  The same answer as ``fem-grasp run`` with the same settings.
    """
    sc = scene if isinstance(scene, Scene) else Scene.load(scene, quick=quick)
    return sc.with_(**changes).run(cache_dir)
