"""Scene files (fem_grasp.io.scene): parsing, units, error messages naming file and key, the resting-state cache."""

from pathlib import Path

import numpy as np
import pytest

from fem_grasp import Body, box_mesh
from fem_grasp.errors import SceneError
from fem_grasp.grasp import objects
from fem_grasp.io.cache import cached_rest, rest_key
from fem_grasp.io.scene import load_scene, parse_quantity, resolve_scene, run_scene, shipped_scenes

PAPER = ("tomato", "orange", "steam_bun", "football")


def _write(tmp_path: Path, text: str, name: str = "s.toml") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


BOX = """
[object]
box = ["3 cm", "4 cm", "3 cm"]
divisions = [2, 2, 2]
[material]
young = "20 kPa"
poisson = 0.3
weight = "0.3 N"
[friction]
finger = 0.5
"""


def test_shipped_scenes_parse_full_and_quick_and_paper_ones_carry_table_one():
    scenes = shipped_scenes()
    assert set(PAPER) <= set(scenes) and len(scenes) >= 6
    assert any(load_scene(p).expect == "failure" for p in scenes.values())  # the slippery one
    for name, path in scenes.items():
        full, quick = load_scene(path), load_scene(path, quick=True)
        assert quick.quick and not full.quick
        assert full.object != quick.object, f"{name}: the quick variant must coarsen the mesh"
        if name in PAPER:
            row = objects.TABLE_I[name]
            assert (full.weight, full.poisson, full.mu_finger, full.mu_table) == (row.weight, row.poisson,
                                                                                  row.friction, row.friction)
            # the effective modulus (docs/physics.md, "Units"): 10 kPa for the football, 20 kPa for the others (their scenes
            # say why)
            assert full.young == (1 if name == "football" else 2) * objects.EFFECTIVE_YOUNG_ESTIMATE
            assert full.placement_rule == objects.PAPER_PLACEMENT_RULE and full.contacts is None
            assert full.max_squeeze == objects.PAPER_MAX_SQUEEZE.get(name)  # the meshes are graded for these
            assert full.pickup_kwargs()["placement_rule"] == objects.PAPER_PLACEMENT_RULE
            assert full.object.vertices is None and 100 <= quick.object.vertices <= 250
            np.testing.assert_allclose(np.linalg.norm(full.directions, axis=1), 1.0)


@pytest.mark.parametrize("text, kind, si", [("10 kPa", "pressure", 1e4), ("2 cm", "length", 0.02),
                                           ("0.5mm", "length", 5e-4), ("1.2 N", "force", 1.2),
                                           ("120 g", "mass", 0.12), ("1 g/cm^3", "density", 1000.0),
                                           (3, "length", 3.0), ("1e9 Pa", "pressure", 1e9)])
def test_quantities_convert_to_si(text, kind, si):
    assert parse_quantity(text, kind) == pytest.approx(si)


def test_scene_units_are_converted(tmp_path):
    s = load_scene(_write(tmp_path, BOX))
    assert s.object.box == pytest.approx((0.03, 0.04, 0.03))
    assert (s.young, s.weight, s.mu_finger, s.mu_table) == (2e4, 0.3, 0.5, 0.5)  # μ_table defaults to μ_finger


def _with(table: str, line: str) -> str:
    """BOX with ``line`` added to ``[table]`` (created if absent; "" = top level)."""
    if not table:
        return line + "\n" + BOX
    header = f"[{table}]\n"
    if header in BOX:
        return BOX.replace(header, header + line + "\n", 1)
    return BOX + "\n" + header + line + "\n"


@pytest.mark.parametrize("table, line, key, words", [
    ("object", 'colour = "red"', "object.colour", "unknown key"),
    ("", "speed = 3", "speed", "unknown key"),
    ("material", "youngs = 1e4", "material.youngs", "did you mean 'material.young'"),
    ("solver", 'max_squeeze = "5 kPa"', "solver.max_squeeze", "is a pressure, but a length is expected"),
    ("solver", 'step = "5 parsecs"', "solver.step", "unknown unit"),
    ("fingers", "ratio = -3", "fingers.ratio", "≥ 0"),
    ("object", "vertices = 5", "object.vertices", "at least 20"),
    ("friction", "table = -0.1", "friction.table", "≥ 0"),
    ("fingers", 'radius = "0 mm"', "fingers.radius", "positive"),
    ("fingers", "contacts = [3]", "fingers.contacts", "two node indices"),
    ("fingers", 'contacts = "highest"', "fingers.contacts", '"centre-of-mass-height"'),
    ("fingers", "directions = [[0, 0, 0], [0, 1, 0]]", "fingers.directions[0]", "non-zero"),
    ("solver", 'backend = "dense"', "solver.backend", "sparse"),
    ("solver", "lift = 1", "solver.lift", "true or false"),
    ("quick", "object = { vertex = 10 }", "object.vertex", "unknown key"),
])
def test_bad_values_name_the_file_and_the_key(tmp_path, table, line, key, words):
    path = _write(tmp_path, _with(table, line))
    with pytest.raises(SceneError) as exc:
        load_scene(path, quick=True)
    msg = str(exc.value)
    assert str(path) in msg and key in msg and words in msg, msg


@pytest.mark.parametrize("old, new, key, words", [
    ('young = "20 kPa"', 'young = "5 cm"', "material.young", "is a length, but a pressure is expected"),
    ('young = "20 kPa"', "young = -3", "material.young", "positive"),
    ("poisson = 0.3", "poisson = 0.5", "material.poisson", "(-1, 0.5)"),
    ("finger = 0.5", "finger = -0.1", "friction.finger", "≥ 0"),
    ('weight = "0.3 N"', 'weight = "0.3 kg"', "material.weight", "is a mass, but a force is expected"),
])
def test_bad_values_of_given_keys(tmp_path, old, new, key, words):
    path = _write(tmp_path, BOX.replace(old, new))
    with pytest.raises(SceneError) as exc:
        load_scene(path)
    msg = str(exc.value)
    assert str(path) in msg and key in msg and words in msg, msg


def test_missing_file_bad_toml_missing_mesh_and_object_choice(tmp_path):
    with pytest.raises(SceneError, match="does not exist"):
        load_scene(tmp_path / "nope.toml")
    with pytest.raises(SceneError, match="not valid TOML"):
        load_scene(_write(tmp_path, "[object\npaper = 1"))
    with pytest.raises(SceneError, match=r"object\.mesh: mesh file .*missing\.stl does not exist"):
        load_scene(_write(tmp_path, '[object]\nmesh = "missing.stl"\n' + BOX.split("[object]")[1].split("\n", 3)[3]))
    with pytest.raises(SceneError, match="exactly one of paper, mesh, box; got paper, box"):
        load_scene(_write(tmp_path, '[object]\npaper = "tomato"\nbox = [1, 1, 1]'))
    with pytest.raises(SceneError, match="unknown paper object 'apple'"):
        load_scene(_write(tmp_path, '[object]\npaper = "apple"'))
    with pytest.raises(SceneError, match="material.young .* is required for a box"):
        load_scene(_write(tmp_path, "[object]\nbox = [0.01, 0.01, 0.01]"))
    with pytest.raises(SceneError, match="no shipped scene"):
        resolve_scene("no_such_scene")


def test_quick_table_merges_over_the_scene(tmp_path):
    s = load_scene(_write(tmp_path, BOX + '\n[quick]\nobject = { divisions = [1, 2, 1] }\nsolver = { step = "1 mm" }'),
                   quick=True)
    assert s.object.divisions == (1, 2, 1) and s.object.box == pytest.approx((0.03, 0.04, 0.03))
    assert s.step == pytest.approx(1e-3) and s.quick


def test_resting_state_cache_is_reused_and_equal_and_keyed(tmp_path):
    body = Body(box_mesh((0, 0, 0), (0.03, 0.04, 0.03), (2, 3, 2)), 2e4, 0.3, weight=0.3)
    first, cached = cached_rest(body, 0.5, cache_dir=tmp_path)
    assert not cached and len(list(tmp_path.glob("rest-*.npz"))) == 1
    again, cached = cached_rest(body, 0.5, cache_dir=tmp_path)
    assert cached
    np.testing.assert_array_equal(again.contact_nodes, first.contact_nodes)
    np.testing.assert_allclose(again.contact_forces, first.contact_forces, rtol=0, atol=1e-12 * body.weight)
    np.testing.assert_allclose(again.positions, first.positions, rtol=0, atol=1e-15)
    assert again.check()["ok"]
    # Another μ, modulus or mesh is another key.
    assert rest_key(body, 0.5) != rest_key(body, 0.4) != rest_key(body.with_material(young=3e4), 0.5)
    # A damaged entry is recomputed, not trusted.
    f = next(tmp_path.glob("rest-*.npz"))
    f.write_bytes(b"garbage")
    state, cached = cached_rest(body, 0.5, cache_dir=tmp_path)
    assert not cached and state.n_contacts == first.n_contacts


def test_the_rest_cache_key_covers_every_module_the_rest_depends_on():
    """The key hashes every source file below io/ and the ground floor, not a hand-kept list (which missed the
    contact response, the compliance, the body and the mesh), and the package version."""
    from fem_grasp.io.cache import rest_code_digest, rest_code_files

    names = {f"{f.parent.name}/{f.name}" for f in rest_code_files()}
    for needed in ("elastic/response.py", "elastic/compliance.py", "elastic/body.py", "mesh/tetmesh.py",
                   "grasp/rest.py", "grasp/pose.py", "contact/tracking.py", "contact/friction.py",
                   "contact/homotopy.py", "elastic/fem.py", "contact/obstacles.py", "fem_grasp/errors.py"):
        assert needed in names, needed
    assert not any(f.parent.name == "io" for f in rest_code_files())  # its own floor: a cache, not physics
    assert rest_code_digest() == rest_code_digest()


# ------------------------------------------------ units: exact SI spellings (issue 25, item 6)
@pytest.mark.parametrize("text, kind, si", [("10 MPa", "pressure", 1e7), ("3 µm", "length", 3e-6),
                                           ("3 μm", "length", 3e-6), ("5 mN", "force", 5e-3),
                                           ("2 kN", "force", 2e3), ("250 mg", "mass", 2.5e-4),
                                           ("1 kg/m³", "density", 1.0)])
def test_exact_si_spellings_are_read(text, kind, si):
    assert parse_quantity(text, kind) == pytest.approx(si)


@pytest.mark.parametrize("text, kind, words", [
    ("10 mPa", "pressure", ["case-sensitive", "m is milli, M is mega", "did you mean 'MPa' (megapascal)"]),
    ("1 CM", "length", ["case-sensitive", "did you mean 'cm' (centimetre)"]),
    ("10 kpa", "pressure", ["case-sensitive", "did you mean 'kPa' (kilopascal)"]),
    ("5 MN", "force", ["did you mean 'mN' (millinewton)"]),
    ("2 PA", "length", ["a length takes m, cm, mm", "'Pa' (pascal) would be a pressure"]),
    ("3 mm", "pressure", ["'3 mm' is a length, but a pressure is expected"]),
])
def test_a_unit_in_the_wrong_case_is_refused_with_the_intended_one(text, kind, words):
    with pytest.raises(SceneError) as exc:
        parse_quantity(text, kind, "material.young")
    msg = str(exc.value)
    for w in words:
        assert w in msg, msg
    assert "is a length, but a length" not in msg and f"is a {kind}, but a {kind}" not in msg  # no self-contradiction


# ------------------------------------------------ the front door (issue 25, item 1)
def test_one_default_placement_rule_for_python_and_the_scenes():
    from fem_grasp import PickupOptions
    from fem_grasp.grasp.placement import DEFAULT_PLACEMENT_RULE

    assert DEFAULT_PLACEMENT_RULE == objects.PAPER_PLACEMENT_RULE == "centre-of-mass-height"
    assert PickupOptions().placement_rule == DEFAULT_PLACEMENT_RULE  # what pickup(body) runs with
    scene = load_scene(_write_box_scene_without_contacts())
    assert scene.placement_rule == DEFAULT_PLACEMENT_RULE and scene.contacts is None


def _write_box_scene_without_contacts() -> Path:
    import tempfile

    return _write(Path(tempfile.mkdtemp()), BOX)


def test_scene_with_takes_units_and_checks_them():
    from fem_grasp import Scene

    base = Scene.load("foam_block", quick=True)
    s = base.with_(young="15 kPa", mu=0.4, mass="40 g", finger_radius="8 mm", contacts="least-force", lift=False)
    assert (s.young, s.mu_finger, s.mu_table, s.finger_radius, s.lift) == (15e3, 0.4, 0.4, 0.008, False)
    assert s.weight == pytest.approx(0.04 * s.gravity) and s.density is None
    assert s.contacts is None and s.placement_rule == "least-force"
    assert base.young == 2e4 and base.contacts == (52, 72)  # a copy: the loaded scene is unchanged
    for bad, words in (({"young": "15 mPa"}, "did you mean 'MPa'"), ({"young": "3 mm"}, "is a length"),
                       ({"poisson": 0.5}, "(-1, 0.5)"), ({"mu": -1}, "≥ 0"), ({"colour": 3}, "unknown setting"),
                       ({"contacts": "highest"}, "placement rule"), ({"yong": 1e4}, "did you mean 'young'"),
                       ({"finger_radus": "1 cm"}, "did you mean 'finger_radius'"),
                       ({"mu_fingers": 0.3}, "did you mean 'mu_finger'")):
        with pytest.raises(SceneError, match=None) as exc:
            base.with_(**bad)
        assert words in str(exc.value) and "Scene.with_" in str(exc.value), str(exc.value)


def test_run_scene_gives_the_command_lines_answer(tmp_path, capsys):
    """fem_grasp.run_scene, Scene.load(...).with_(...).run() and `fem-grasp run` agree, and so does pickup() with
    its own default placement."""
    import json

    import fem_grasp
    from fem_grasp.cli import main

    cache = tmp_path / "cache"
    py = fem_grasp.run_scene("football", quick=True, young="12 kPa", lift=False, cache_dir=cache)
    assert main(["run", "football", "--quick", "--young", "12 kPa", "--no-lift", "--quiet", "--cache", str(cache),
                 "--out", str(tmp_path / "o")]) == 1
    doc = json.loads((tmp_path / "o" / "result.json").read_text())
    assert tuple(doc["result"]["finger_nodes"]) == tuple(py.finger_nodes)
    assert doc["summary"]["squeeze_depth"] == pytest.approx(py.squeeze_depth, rel=1e-9)
    assert doc["summary"]["n_events"] == len(py.events) and doc["summary"]["outcome"] == py.outcome
    scene = fem_grasp.Scene.load("football", quick=True).with_(young="12 kPa", lift=False)
    assert tuple(scene.run(cache_dir=None).finger_nodes) == tuple(py.finger_nodes)
    from fem_grasp import pickup

    kw = {k: v for k, v in scene.pickup_kwargs().items() if k != "placement_rule"}
    assert tuple(pickup(scene.body(), **kw).finger_nodes) == tuple(py.finger_nodes)


def test_the_sweep_example_returns_a_dataframe():
    pd = pytest.importorskip("pandas")
    import importlib.util

    spec = importlib.util.spec_from_file_location("sweep", Path(__file__).resolve().parents[2] / "examples" / "sweep.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    table = mod.sweep("foam_block", youngs=("20 kPa", "40 kPa"), mus=(0.5,), lift=False)
    assert isinstance(table, pd.DataFrame) and len(table) == 2
    assert list(table["E (Pa)"]) == [2e4, 4e4] and (table["mu"] == 0.5).all()
    assert (table["rho (mm)"] > 0).all() and (table["outcome"] == "lift not run").all()
    assert table["sum f.n (N)"].iloc[1] > table["sum f.n (N)"].iloc[0]  # stiffer: more force at the same weight


# ------------------------------------------------ scans in millimetres, remeshing volume meshes (items 5, 7)
def _ball_scene(tmp_path: Path, surface: str, extra: str = "", weight: str = '"0.1 N"') -> Path:
    return _write(tmp_path, f"""
[object]
mesh = "{surface}"
vertices = 150
{extra}
[material]
young = "20 kPa"
poisson = 0.3
weight = {weight}
[friction]
finger = 0.5
""", "ball.toml")


@pytest.mark.gmsh
def test_a_scan_in_millimetres_is_refused_naming_the_unit_and_object_units_fixes_it(tmp_path):
    pytest.importorskip("gmsh")
    import warnings

    from fem_grasp.errors import UnitsError, UnitsWarning
    from tests.helpers import icosphere, write_stl

    p, f = icosphere(30.0, 2)  # a 6 cm ball written in millimetres
    write_stl(tmp_path / "ball_mm.stl", p, f)
    scene = load_scene(_ball_scene(tmp_path, "ball_mm.stl"))
    with pytest.raises(UnitsError) as info:
        scene.body(tmp_path / "cache")
    text = str(info.value)
    assert "over 1 m" in text and 'units = "mm"' in text and "millimetres" in text, text
    assert "density" in text and "kg/m^3" in text and "--allow-implausible-units" in text, text
    assert info.value.key == "object.units" and isinstance(info.value, SceneError)
    # the Python front doors refuse it too, before any pickup
    with pytest.raises(UnitsError):
        run_scene(scene, cache_dir=tmp_path / "cache")
    # insisting: the scene key or the Python keyword run it, with the warnings
    for insisted in (load_scene(_ball_scene(tmp_path, "ball_mm.stl", "allow_implausible_units = true")),
                     scene.with_(allow_implausible_units=True)):
        with pytest.warns(UnitsWarning) as record:
            body = insisted.body(tmp_path / "cache")
        warned = " ".join(str(w.message) for w in record)
        assert "larger than 1 m" in warned and 'object.units = "mm"' in warned, warned
        assert body.mesh.diameter > 50
    for fixed in (load_scene(_ball_scene(tmp_path, "ball_mm.stl", 'units = "mm"')), scene.with_(units="mm")):
        with warnings.catch_warnings():
            warnings.simplefilter("error", UnitsWarning)
            good = fixed.body(tmp_path / "cache")
        assert good.mesh.diameter == pytest.approx(body.mesh.diameter * 1e-3, rel=0.05)
    with pytest.raises(SceneError, match="object.units"):
        load_scene(_ball_scene(tmp_path, "ball_mm.stl", 'units = "inch"'))
    with pytest.raises(SceneError, match="allow_implausible_units"):
        load_scene(_write(tmp_path, '[object]\nbox = [0.04, 0.03, 0.02]\nallow_implausible_units = true\n'
                          '[material]\nyoung = 2e4\npoisson = 0.3\ndensity = 500\n[friction]\nfinger = 0.5\n',
                          "box.toml"))


@pytest.mark.gmsh
def test_the_cli_refuses_a_millimetre_scan_with_exit_2_unless_told_to_allow_it(tmp_path, capsys):
    pytest.importorskip("gmsh")
    from fem_grasp.cli import main
    from tests.helpers import icosphere, write_stl

    p, f = icosphere(30.0, 2)
    write_stl(tmp_path / "ball_mm.stl", p, f)
    path = _ball_scene(tmp_path, "ball_mm.stl")
    assert main(["run", str(path), "--cache", str(tmp_path / "cache"), "-q"]) == 2
    err = capsys.readouterr().err
    assert "over 1 m" in err and 'units = "mm"' in err and "Nothing was computed" in err, err
    # the resting state alone is quick: with the flag it is computed, and the units are still warned about
    assert main(["rest", str(path), "--cache", str(tmp_path / "cache"), "--allow-implausible-units"]) == 0
    captured = capsys.readouterr()
    assert "millimetres" in captured.err and "rest " in captured.out, captured


@pytest.mark.gmsh
def test_object_vertices_remeshes_a_volume_mesh(tmp_path):
    pytest.importorskip("gmsh")
    from fem_grasp import TetMesh
    from fem_grasp.mesh.scan import mesh_surface
    from tests.helpers import icosphere, write_stl

    p, f = icosphere(0.03, 3)
    write_stl(tmp_path / "ball.stl", p, f)
    fine = mesh_surface(tmp_path / "ball.stl")
    fine.write(tmp_path / "ball.vtu")
    scene = load_scene(_ball_scene(tmp_path, "ball.vtu"))
    mesh = scene.load_mesh(tmp_path / "cache")
    assert isinstance(mesh, TetMesh) and abs(mesh.n_points - 150) <= 15 < abs(fine.n_points - 150)
    assert mesh.volume == pytest.approx(fine.volume, rel=0.05)


def test_a_changed_setting_gets_no_error_measured_at_the_scenes_own_settings():
    """The error a scene states for a single run was measured by the convergence study at its own modulus,
    friction, weight and mesh: a run with any of them changed states none (never a borrowed one); a change that
    cannot move the answer (the backend, the lift's extent) keeps it."""
    from fem_grasp import Scene
    from fem_grasp.io.scene import with_overrides

    tomato = Scene.load("tomato")
    assert tomato.expected_error is not None
    for change in ({"young": "10 kPa"}, {"mu_finger": 0.4}, {"weight": "2 N"}, {"finger_radius": "8 mm"},
                   {"vertices": 2000}, {"step": "0.5 mm"}):
        assert tomato.with_(**change).expected_error is None, change
    assert tomato.with_(young=tomato.young).expected_error == tomato.expected_error  # no change: kept
    assert tomato.with_(backend="spectral", lift=False).expected_error == tomato.expected_error
    assert with_overrides(tomato, young=1e4).expected_error is None  # the CLI's --young
    assert with_overrides(tomato, backend="spectral", young=None).expected_error == tomato.expected_error


def test_a_single_run_of_a_scene_that_states_no_error_says_it_is_one_level_and_unmeasured():
    """A user's own scene run once (accuracy off) that states no error for such a run: its result says so (one
    level, error unknown) instead of no accuracy statement at all."""
    scene = load_scene(_write_box_scene_without_contacts())
    assert scene.accuracy == 0.05 and scene.expected_error is None  # refined unless asked otherwise
    scene = scene.with_(accuracy="off")
    res = scene.run(cache_dir=None)
    acc = res.accuracy
    assert acc is not None and not acc["converged"] and len(acc["levels"]) == 1
    assert acc["expected_error_stated"] is False and acc["estimated_error"]["squeeze_depth"] == float("inf")
