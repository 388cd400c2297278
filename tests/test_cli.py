"""The fem-grasp command line, in-process: every shipped scene's quick variant, exit statuses, bad input."""

import json
import math
import subprocess
import sys

import pytest

from fem_grasp.cli import main
from fem_grasp.io.scene import shipped_scenes
from tests.helpers import box_scene_toml, cache_dir, cli_run, icosphere, write_stl


@pytest.mark.parametrize("scene", sorted(shipped_scenes()))
def test_every_shipped_scene_runs_quick_and_the_exit_status_matches_the_result(scene):
    code, out = cli_run(scene)  # to the end: squeeze, lift tests and the simulated lift
    assert code in (0, 1)
    doc = json.loads((out / "result.json").read_text())
    assert doc["exit_code"] == code and doc["summary"]["success"] == (code == 0)
    assert doc["scene"]["name"] == scene and doc["scene"]["quick"] is True
    assert doc["command"][:2] == ["run", scene]
    if doc["summary"]["success"]:
        assert doc["result"]["final"]["label"] == "lift-off"
    else:
        assert doc["summary"]["reason"]
    assert (out / "object.pvd").exists()


@pytest.mark.requires("gmsh")
def test_a_run_without_options_is_refined_to_five_per_cent_and_off_is_one_run(tmp_path, capsys):
    """`fem-grasp run SCENE` answers to the default 5 %: levels refined at the patches, an estimated error within
    it, the levels' total time; `--accuracy off` is one run on the shipped mesh, said to be one, with the scene's
    stated error.  The two answers lie within that stated error of each other."""
    assert main(["run", "foam_block", "--no-cache", "--out", str(tmp_path / "a")]) == 0
    text = capsys.readouterr().out
    acc = json.loads((tmp_path / "a" / "result.json").read_text())["accuracy"]
    assert acc["target"] == 0.05 and acc["converged"] and len(acc["levels"]) >= 2
    assert max(acc["estimated_error"].values()) <= 0.05
    assert f"for {len(acc['levels'])} levels; the last:" in text and "target 5 %" in text
    assert main(["run", "foam_block", "--no-cache", "--accuracy", "off", "--out", str(tmp_path / "b")]) == 0
    text = capsys.readouterr().out
    doc = json.loads((tmp_path / "b" / "result.json").read_text())
    assert len(doc["accuracy"]["levels"]) == 1 and not doc["accuracy"]["converged"]
    assert "one run on the scene's mesh (accuracy off)" in text
    stated = doc["accuracy"]["estimated_error"]["squeeze_depth"]
    one, refined = doc["accuracy"]["levels"][0]["squeeze_depth"], acc["levels"][-1]["squeeze_depth"]
    assert abs(one - refined) <= stated * refined


def test_an_answer_short_of_its_target_says_by_how_much_and_why():
    """The summary of a refined answer whose estimate is above the target: the target, that it was not reached,
    the estimated errors and the loop's reason; then one line per level."""
    from fem_grasp.cli.run import _accuracy_lines

    level = {"inner_size": 2e-3, "step": 4e-4, "success": True, "finger_force": 4.5, "seconds": 1.0,
             "mesh_seconds": 0.2}
    acc = {"target": 0.05, "converged": False, "estimated_error": {"squeeze_depth": 0.024, "finger_force": 0.07},
           "note": "stopped before level 2: it would put about 528 contacts on a fingertip",
           "levels": [dict(level, level=0, vertices=700, squeeze_depth=8.7e-3),
                      dict(level, level=1, vertices=2100, squeeze_depth=9.0e-3)]}
    lines = _accuracy_lines(acc, quick=False)
    assert lines[0] == ("accuracy   target 5 %, not reached: estimated error rho* 2.4 %, finger force 7 % (stopped "
                        "before level 2: it would put about 528 contacts on a fingertip)")
    assert [x.split()[:2] for x in lines[1:]] == [["level", "0"], ["level", "1"]] and "2,100 vertices" in lines[2]


def test_a_failure_at_the_deepest_squeeze_says_its_rho_is_that_setting():
    """Every level squeezes at most as deep as the body as given: a failure that got there answers the setting, and
    the summary says so rather than "0 %"."""
    from fem_grasp.cli.run import _accuracy_lines

    level = {"inner_size": 2e-3, "step": 4e-4, "success": False, "finger_force": 8.3, "seconds": 1.0,
             "mesh_seconds": 0.2, "squeeze_depth": 0.0226, "max_squeeze": 0.0226}
    acc = {"target": 0.05, "converged": True, "estimated_error": {"squeeze_depth": 0.0, "finger_force": 0.034},
           "note": "", "levels": [dict(level, level=0, vertices=450), dict(level, level=1, vertices=1300)]}
    head = _accuracy_lines(acc, quick=False)[0]
    assert "estimated error rho* none (rho is the deepest squeeze, a setting), finger force 3.4 %" in head
    acc["levels"][-1]["squeeze_depth"] = 0.0201  # stopped short of it (a squeeze that failed at an event)
    assert "estimated error rho* 0 %, finger force 3.4 %" in _accuracy_lines(acc, quick=False)[0]


def test_an_answer_whose_verdict_is_not_settled_says_why():
    """Infinite estimates: the verdict itself is not settled, for the reason the accuracy block gives (a failure
    within its error of the weight), or, in a result written before that block had a reason, the two last levels'
    disagreement."""
    from fem_grasp.cli.run import _accuracy_lines

    level = {"inner_size": 2e-3, "step": 4e-4, "success": False, "finger_force": 22.3, "seconds": 1.0,
             "mesh_seconds": 0.2, "squeeze_depth": 0.035}
    why = "the fingers held up to 3.587 N, and the weight 3.775 N lies within the estimated error of that"
    acc = {"target": 0.1, "converged": False, "note": "stopped after 64 s before level 3",
           "estimated_error": {"squeeze_depth": math.inf, "finger_force": math.inf, "max_liftable": 0.15},
           "verdict": why, "levels": [dict(level, level=0, vertices=1800), dict(level, level=1, vertices=5900)]}
    head = _accuracy_lines(acc, quick=False)[0]
    assert head.startswith("accuracy   the requested 10 % was not reached (stopped after 64 s before level 3)")
    assert why in head and "the verdict itself is not settled" in head
    del acc["verdict"]
    assert "the last two meshes give different verdicts" in _accuracy_lines(acc, quick=False)[0]


def test_the_result_line_says_whether_a_refined_answer_is_short_of_its_target_or_its_verdict_unsettled():
    from types import SimpleNamespace as NS

    import numpy as np

    from fem_grasp.cli.run import _summary_lines

    scene = NS(name="pear", quick=False, young=2e4, poisson=0.4, mu_finger=0.3, mu_table=0.3)
    level = {"inner_size": 2e-3, "step": 4e-4, "success": False, "finger_force": 22.3, "seconds": 1.0,
             "mesh_seconds": 0.2, "squeeze_depth": 0.035, "vertices": 1000}
    acc = {"target": 0.05, "converged": False, "note": "stopped",
           "levels": [dict(level, level=0), dict(level, level=1)],
           "estimated_error": {"squeeze_depth": 0.08, "finger_force": 0.09}}
    result = NS(success=False, outcome="not liftable", reason="the lift test did not pass", squeeze_depth=0.035,
                max_squeeze=0.035, liftable=[(0.03, 3.4)], n_final_contacts=90, finger_forces=None, events=[],
                event_counts=lambda: {k: 0 for k in "ABCD"}, timings={"rest": 0.1, "squeeze": 1.0}, accuracy=acc,
                body=NS(n_nodes=1000, mesh=NS(n_tets=4000), weight=3.775),
                rest=NS(n_contacts=20, sliding=np.zeros(20, bool), max_sag=1e-3))
    assert _summary_lines(scene, result, False)[2].endswith("(less accurate than requested: see accuracy)")
    acc.update(estimated_error={"squeeze_depth": math.inf, "finger_force": math.inf},
               verdict="a finer mesh may lift it")
    lines = _summary_lines(scene, result, False)
    assert lines[2].startswith("result     NOT PICKED UP")
    assert lines[2].endswith("(the verdict is not settled at this resolution: see accuracy)")
    assert "a finer mesh may lift it" in lines[3]


def test_young_override_reaches_the_scene():
    from argparse import Namespace

    from fem_grasp.cli.common import scene_of

    args = Namespace(scene="orange", quick=True, backend=None, no_lift=False, young="12.5 kPa")
    assert scene_of(args).young == 12500.0
    args.young = None
    assert scene_of(args).young == 20000.0  # the scene's own


def test_the_refinements_contact_bound_reaches_the_pickup_options_without_dropping_the_stated_error():
    from argparse import Namespace

    from fem_grasp.cli.common import scene_of

    args = Namespace(scene="orange", quick=False, backend=None, no_lift=False, young=None, accuracy="5%",
                     max_finger_contacts=600)
    scene = scene_of(args)
    assert scene.pickup_options().max_finger_contacts == 600 and scene.accuracy == 0.05
    assert scene.expected_error is not None  # the bound changes no single run's answer
    args.max_finger_contacts = None
    assert scene_of(args).pickup_options().max_finger_contacts == 300


def test_step_divisions_reach_the_pickup_options_from_the_command_line_and_the_scene_file(tmp_path):
    from argparse import Namespace

    from fem_grasp.cli.common import scene_of
    from fem_grasp.io.scene import load_scene

    args = Namespace(scene="orange", quick=False, backend=None, no_lift=False, young=None, step_divisions=4)
    assert scene_of(args).pickup_options().step_divisions == 4
    args.step_divisions = None
    assert scene_of(args).pickup_options().step_divisions == 1  # the paper's Algorithm 1 as printed
    f = tmp_path / "s.toml"
    f.write_text('[object]\npaper = "tomato"\n[solver]\nstep_divisions = 3\n')
    assert load_scene(f).pickup_options().step_divisions == 3


def test_the_accuracy_loops_time_budget_reaches_the_pickup_options_without_dropping_the_stated_error(tmp_path):
    from argparse import Namespace

    from fem_grasp.cli.common import scene_of
    from fem_grasp.io.scene import load_scene

    args = Namespace(scene="orange", quick=False, backend=None, no_lift=False, young=None, accuracy="5%",
                     max_seconds=30.0)
    scene = scene_of(args)
    assert scene.pickup_options().max_seconds == 30.0 and scene.expected_error is not None
    args.max_seconds = None
    assert scene_of(args).pickup_options().max_seconds is None  # no budget
    f = tmp_path / "s.toml"
    f.write_text('[object]\npaper = "tomato"\n[solver]\nmax_seconds = 45\n')
    assert load_scene(f).pickup_options().max_seconds == 45.0
    assert load_scene(f).with_(max_seconds=10).pickup_options().max_seconds == 10.0


@pytest.mark.requires("gmsh")  # the quick scene remeshes its object
def test_summary_printed_and_quiet_prints_nothing(capsys, tmp_path):
    args = ["run", "football", "--quick", "--cache", str(cache_dir()), "--no-lift"]
    code = main(args)
    text = capsys.readouterr().out
    assert code in (0, 1) and "scene      football (quick)" in text and "rho =" in text and "events" in text
    assert main(args + ["--quiet"]) == code
    assert capsys.readouterr().out == ""


@pytest.mark.requires("gmsh")  # the quick scene remeshes its object
def test_rest_command_uses_the_cache_and_writes_rest_files(capsys, tmp_path):
    args = ["rest", "orange", "--quick", "--cache", str(tmp_path / "c"), "--out", str(tmp_path / "o")]
    assert main(args) == 0
    first = capsys.readouterr().out
    assert main(args) == 0
    second = capsys.readouterr().out
    assert "[cached]" not in first and "[cached]" in second and "checks     pass" in second
    doc = json.loads((tmp_path / "o" / "rest.json").read_text())
    assert doc["check"]["ok"] and doc["rest_from_cache"] is True
    # rest.vtu: the table's forces on the object hold its weight; each contact node carries its force of rest.json
    import meshio
    import numpy as np

    m = meshio.read(tmp_path / "o" / "rest.vtu")
    assert m.cells[0].type == "tetra" and set(m.cell_data) == {"von_mises", "strain_energy_density"}
    weight = doc["scene"]["weight"]
    np.testing.assert_allclose(m.point_data["contact_force"].sum(axis=0), [0.0, 0.0, weight], atol=1e-9 * weight)
    np.testing.assert_allclose(m.point_data["contact_force"][doc["contact_nodes"]], doc["contact_forces"], rtol=0,
                               atol=1e-15)
    assert (m.point_data["contact_body"][doc["contact_nodes"]] == 3).all()


def test_help_of_every_command_explains_units(capsys):
    for cmd in ("run", "rest", "mesh", "info", "report", "scenes"):
        assert main([cmd, "--help"]) == 0
    text = capsys.readouterr().out
    assert "metres" in text and "Exit status" in text
    assert main([]) == 2  # no command: usage error


def test_top_level_help_lists_every_command(capsys):
    from fem_grasp.cli import build_parser

    assert main(["--help"]) == 0
    text = capsys.readouterr().out
    commands = next(a for a in build_parser()._actions if a.dest == "command").choices
    assert "search" in commands
    for cmd in commands:
        assert f"    {cmd} " in text, cmd


def test_info_of_a_scene_prints_labelled_lines_with_units_not_dicts(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # a folder named tomato in the working directory would be read instead
    assert main(["info", "tomato"]) == 0
    text = capsys.readouterr().out
    assert "{" not in text and "None" not in text, text
    for label in ("scene", "object", "material", "friction", "fingers", "solver", "accuracy"):
        assert any(line.startswith(f"{label} ") for line in text.splitlines()), label
    assert "E 20 kPa" in text and "radius 10 mm" in text and "weight 1.246 N" in text, text
    assert "mu_F 0.32" in text and "13.1 deg below the horizontal" in text, text


@pytest.mark.requires("gmsh")
def test_mesh_and_info_on_a_generated_scan(capsys, tmp_path):
    p, f = icosphere(0.03, 2)
    stl = write_stl(tmp_path / "ball.stl", p, f)
    vtu = tmp_path / "ball.vtu"
    assert main(["mesh", str(stl), "-o", str(vtu), "--vertices", "200"]) == 0
    assert main(["info", str(vtu)]) == 0
    assert main(["info", str(stl)]) == 0
    text = capsys.readouterr().out
    assert "closed and manifold" in text and "vertices" in text and "quality" in text
    assert main(["mesh", str(stl), "-o", str(vtu)]) == 2  # exists, no --force
    assert "exists; pass --force" in capsys.readouterr().err


def _bad(capsys, argv, *words):
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2, err
    for w in words:
        assert w in err, err
    return err


def test_bad_input_exits_2_with_a_message_that_names_it(capsys, tmp_path):
    scene = tmp_path / "bad.toml"
    scene.write_text('[object]\npaper = "tomato"\nsqueeze = 3\n')
    _bad(capsys, ["run", str(scene)], str(scene), "object.squeeze", "unknown key")
    scene.write_text('[object]\npaper = "tomato"\n[material]\nyoung = "3 mm"\n')
    _bad(capsys, ["run", str(scene)], "material.young", "is a length, but a pressure is expected")
    scene.write_text('[object]\npaper = "tomato"\n[material]\npoisson = 0.7\n')
    _bad(capsys, ["info", str(scene)], "material.poisson", "(-1, 0.5)")
    _bad(capsys, ["run", str(tmp_path / "missing.toml")], "missing.toml", "does not exist")
    scene.write_text('[object]\nmesh = "scan.stl"\n')
    _bad(capsys, ["run", str(scene)], "object.mesh", "scan.stl does not exist")
    scene.write_text('[object]\npaper = "tomato"\n[fingers]\ncontacts = [0, 99999]\n')
    _bad(capsys, ["run", str(scene), "--no-cache"], "fingers.contacts", "node 99999 does not exist")
    _bad(capsys, ["run", "tomato", "--report"], "--report needs --out")
    _bad(capsys, ["run", "tomato", "--young", "3 mm"], "--young", "is a length, but a pressure is expected")
    _bad(capsys, ["run", "tomato", "--young", "-5"], "--young", "positive")
    _bad(capsys, ["run", "tomato", "--accuracy", "5%", "--max-finger-contacts", "0"], "--max-finger-contacts", "≥ 1")
    scene.write_text('[object]\npaper = "tomato"\n[solver]\nmax_finger_contacts = 0\n')
    _bad(capsys, ["run", str(scene)], "solver.max_finger_contacts", "≥ 1")
    _bad(capsys, ["run", "tomato", "--step-divisions", "0"], "--step-divisions", "≥ 1")
    _bad(capsys, ["run", "tomato", "--accuracy", "5%", "--max-seconds", "0"], "--max-seconds", "> 0")
    scene.write_text('[object]\npaper = "tomato"\n[solver]\nmax_seconds = -5.0\n')
    _bad(capsys, ["run", str(scene)], "solver.max_seconds", "> 0")
    scene.write_text('[object]\npaper = "tomato"\n[solver]\nstep_divisions = 2.5\n')
    _bad(capsys, ["run", str(scene)], "solver.step_divisions", "integer")
    scene.write_text('[object]\npaper = "tomato"\n[solver]\nstep_divisions = 0\n')
    _bad(capsys, ["run", str(scene)], "solver.step_divisions", "≥ 1")
    # Surfaces: not closed, self-intersecting.
    p, f = icosphere(0.03, 2)
    _bad(capsys, ["mesh", str(write_stl(tmp_path / "open.stl", p, f[1:])), "-o", str(tmp_path / "o.vtu")],
         "open.stl", "not closed")
    q = p.copy()
    q[q[:, 2].argmax()] = [0, 0, -0.06]
    _bad(capsys, ["mesh", str(write_stl(tmp_path / "cross.stl", q, f)), "-o", str(tmp_path / "o.vtu")],
         "cross.stl", "intersects itself")
    assert main(["info", str(tmp_path / "cross.stl")]) == 2
    # A folder that is not ours.
    foreign = tmp_path / "foreign"
    foreign.mkdir()
    (foreign / "thesis.tex").write_text("precious")
    _bad(capsys, ["run", "football", "--quick", "--out", str(foreign)], "not written by fem_grasp", "--force")
    assert (foreign / "thesis.tex").read_text() == "precious"
    _bad(capsys, ["report", str(tmp_path)], "result.json does not exist")


def test_python_dash_m_entry_point():
    r = subprocess.run([sys.executable, "-m", "fem_grasp", "scenes"], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and "tomato" in r.stdout and "slippery_ball" in r.stdout


def test_scene_demo_example_writes_the_same_outputs(tmp_path):
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parent.parent / "examples" / "scene_demo.py"
    if not path.exists():
        pytest.skip("examples/ is in the source tree, not in the installed package")
    spec = importlib.util.spec_from_file_location("scene_demo", path)
    demo = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(demo)
    result = demo.run("football", quick=True, out=tmp_path / "o", report=False, lift=False)
    doc = json.loads((tmp_path / "o" / "result.json").read_text())
    assert doc["summary"]["success"] == result.success and doc["summary"]["n_events"] == len(result.events)


def test_main_leaves_logging_as_it_found_it():
    import logging

    lg = logging.getLogger("fem_grasp")
    before = (lg.level, lg.propagate, list(lg.handlers))
    assert main(["scenes", "--quiet"]) == 0 and main(["scenes", "-vv"]) == 0
    assert (lg.level, lg.propagate, list(lg.handlers)) == before


@pytest.mark.requires("gmsh")  # the quick scene remeshes its object
def test_the_same_scene_writes_the_same_files_but_for_wall_times(tmp_path):
    """Determinism (issue #8): two runs of one scene into one folder (the mesh and the resting state recomputed
    each time) write byte-identical time series and a result.json that differs only in its creation time
    and the timings."""
    import hashlib

    out = tmp_path / "o"
    argv = ["run", "football", "--quick", "--no-lift", "--no-cache", "--quiet", "--out", str(out)]

    def written():
        files = {str(p.relative_to(out)): hashlib.sha256(p.read_bytes()).hexdigest()
                 for p in sorted(out.rglob("*")) if p.is_file()}
        doc = json.loads((out / "result.json").read_text())
        return files, doc

    assert main(argv) == 1  # --no-lift: the run stops when the lift test passes
    first, doc1 = written()
    assert main(argv) == 1
    second, doc2 = written()
    assert set(first) == set(second) and len(first) > 10
    assert {k for k in first if first[k] != second[k]} <= {"result.json"}
    assert doc1["summary"]["timings"]["total"] > 0
    for doc in (doc1, doc2):
        doc.pop("created")
        doc["summary"].pop("timings")
        doc["result"].pop("timings")
        for level in (doc.get("accuracy") or {}).get("levels", []):  # wall times of the accuracy levels
            level.pop("seconds"), level.pop("mesh_seconds")
        (doc.get("accuracy") or {}).pop("seconds", None)
    assert doc1 == doc2
    assert doc1["result"]["events"] and doc1["result"]["snapshots"]


@pytest.mark.requires("gmsh")  # the quick scene remeshes its object
@pytest.mark.parametrize("error", ["friction", "convergence"])
def test_an_object_that_cannot_rest_exits_1_with_the_reason_not_as_an_internal_error(capsys, monkeypatch, tmp_path,
                                                                                     error):
    import fem_grasp.io.cache as cache_mod
    from fem_grasp.errors import FrictionError, RestConvergenceError

    exc = (FrictionError("gross sliding on the table: 3 contacts slide without bound") if error == "friction"
           else RestConvergenceError("the resting iteration did not settle in 2 iterations"))

    def no_rest(*a, **k):
        raise exc

    monkeypatch.setattr(cache_mod, "cached_rest", no_rest)
    code = main(["run", "football", "--quick", "--no-cache", "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert code == 1, err
    assert "does not come to rest on the table" in err and str(exc) in err and "internal error" not in err


# ------------------------------------------------ issue 25: what a user touches
def test_the_summary_gives_each_fingers_force_and_says_what_table_iii_compares(capsys, tmp_path):
    args = ["run", "foam_block", "--quick", "--no-lift", "--cache", str(tmp_path / "c")]
    assert main(args) == 1  # --no-lift: not lifted, so exit 1 …
    first = capsys.readouterr().out
    # … but it says the lift test passed, not a red NOT PICKED UP
    assert "lift test passed at rho = " in first and "lift not simulated" in first and "NOT PICKED UP" not in first
    for words in ("finger 1 (", "finger 2 (", "grip ", "vertical ", "normal sum ",
                  "table III  compares Σ f·n̂ over both fingers", "for a rigid object at the same contacts"):
        assert words in first, first
    assert "rest 0." in first and "(solved)" in first
    assert main(args) == 1
    second = capsys.readouterr().out
    assert "(checked from the cache)" in second and "(solved)" not in second


def test_info_reads_a_result_and_a_time_series(capsys, tmp_path):
    code, out = cli_run("foam_block", "--no-lift")
    assert main(["info", str(out / "result.json")]) == 0
    text = capsys.readouterr().out
    assert "foam_block (quick)" in text and "lift test passed" in text and "finger 1 resultant" in text
    assert "time = finger path" in text
    assert main(["info", str(out)]) == 0  # the folder: its result.json
    assert main(["info", str(out / "object.pvd")]) == 0
    text = capsys.readouterr().out
    assert "ParaView time series" in text and "field data phase 0" in text and "squeeze_depth" in text
    # Not a mesh: a message, not an internal error.  (A file of our own: this process may have loaded dolfinx's
    # HDF5, and then the run wrote no object.h5.)
    junk = tmp_path / "series.h5"
    junk.write_bytes(b"\x89HDF\r\n\x1a\n" + bytes(512))
    assert main(["info", str(junk)]) == 2
    err = capsys.readouterr().err
    assert "cannot read it as a volume mesh" in err and "internal error" not in err


def test_mesh_takes_units_and_warns_about_a_scan_in_millimetres(capsys, tmp_path):
    pytest.importorskip("gmsh")
    p, f = icosphere(30.0, 2)  # a 6 cm ball written in millimetres
    stl = write_stl(tmp_path / "ball_mm.stl", p, f)
    assert main(["mesh", str(stl), "-o", str(tmp_path / "raw.vtu"), "--vertices", "150"]) == 0
    err = capsys.readouterr().err
    assert "larger than 1 m" in err and "pass --units mm" in err and "millimetres" in err, err
    log_file = tmp_path / "mesh.log"
    assert main(["mesh", str(stl), "-o", str(tmp_path / "m.vtu"), "--vertices", "150", "--units", "mm",
                 "--log-file", str(log_file)]) == 0
    captured = capsys.readouterr()
    assert "larger than 1 m" not in captured.err and "read in mm and written in metres" in captured.out
    from fem_grasp import TetMesh

    assert TetMesh.from_file(tmp_path / "m.vtu").diameter == pytest.approx(0.06 * 3 ** 0.5, rel=0.05)
    assert "INFO" in log_file.read_text() and "vertices" in log_file.read_text()  # the library's log, with times


def test_verbose_logs_the_library_to_stderr(capsys, tmp_path):
    pytest.importorskip("gmsh")
    p, f = icosphere(0.03, 2)
    stl = write_stl(tmp_path / "ball.stl", p, f)
    assert main(["mesh", str(stl), "-o", str(tmp_path / "m.vtu"), "--vertices", "150", "-v"]) == 0
    assert "INFO: " in capsys.readouterr().err
    assert main(["mesh", str(stl), "-o", str(tmp_path / "n.vtu"), "--vertices", "150"]) == 0
    assert "INFO: " not in capsys.readouterr().err


@pytest.mark.parametrize("line, key, words", [
    ("directions = [[0, 1, 0.5], [0, -1, 0.5]]", "fingers.directions", "upward"),
    ("contacts = [0, 4]", "fingers.contacts", "finger 2"),
])
def test_errors_about_the_fingers_name_the_scene_file_and_key(capsys, tmp_path, line, key, words):
    scene = tmp_path / "box.toml"
    scene.write_text(box_scene_toml((2, 2, 2), f"[fingers]\n{line}\n"))
    err = _bad(capsys, ["run", str(scene), "--no-cache"], f"{scene}: {key}", words)
    assert "internal error" not in err


@pytest.mark.requires("tqdm")
def test_progress_bars_only_on_a_terminal_and_never_in_ci(monkeypatch):
    from fem_grasp.progress import PhaseBar, progress, progress_enabled

    class Tty:
        def isatty(self):
            return True

    monkeypatch.delenv("CI", raising=False)
    monkeypatch.delenv("FEM_GRASP_PROGRESS", raising=False)
    assert progress_enabled(stream=Tty())
    assert not progress_enabled(quiet=True, stream=Tty())
    monkeypatch.setenv("CI", "true")
    assert not progress_enabled(stream=Tty())
    monkeypatch.delenv("CI")
    monkeypatch.setenv("FEM_GRASP_PROGRESS", "0")
    assert not progress_enabled(stream=Tty())
    monkeypatch.delenv("FEM_GRASP_PROGRESS")
    assert not progress_enabled()  # pytest captures stderr: not a terminal
    items = [1, 2, 3]
    assert progress(items) is items and PhaseBar(["a"]).bar is None


def test_the_accuracy_levels_are_shown_as_they_finish_unless_quiet(capsys):
    """A refinement can take minutes: each level's line reaches stderr at the default verbosity (other INFO records
    do not), and nothing does with --quiet; the logger's level is restored afterwards."""
    import argparse
    import logging

    from fem_grasp.cli import _logging

    levels = logging.getLogger("fem_grasp.grasp.accuracy")
    before = levels.level
    for quiet in (False, True):
        with _logging(argparse.Namespace(quiet=quiet, verbose=0, log_file=None)):
            levels.info("accuracy level %d: %d vertices", 1, 4985)
            logging.getLogger("fem_grasp.grasp.rest").info("rest: 12 iterations")
        err = capsys.readouterr().err
        assert ("accuracy level 1: 4985 vertices" in err) is not quiet
        assert "rest: 12 iterations" not in err
    assert levels.level == before
