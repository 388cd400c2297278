"""The coverage study's pieces (verification.coverage), without running it: the random objects, the capsule,
the reference's resolution and the coverage arithmetic.  The study itself is ``python -m verification coverage``.
"""

import json
import math

import numpy as np
import pytest

pytest.importorskip("verification", reason="the source tree's verification/ package (not installed with fem_grasp)")

from verification.coverage import (
    RANGES,
    SHAPES,
    CoverageObject,
    capsule_volume,
    combine_draws,
    evaluate,
    passed,
    reference_plan,
    summarise,
)
from verification.coverage.__main__ import main
from verification.coverage.runner import DRAW_STEP, draw_factor, reusable
from verification.coverage.summary import summary_lines


# ------------------------------------------------------------------ the objects
def test_drawn_parameters_lie_in_their_ranges_and_repeat_by_seed():
    objects = [CoverageObject.of_seed(s) for s in range(60)]
    for o in objects:
        d = o.to_dict()
        assert d["shape"] in SHAPES
        for k, (lo, hi) in RANGES.items():
            assert lo <= d[k] <= hi, (k, d[k])
        assert 5e3 <= o.young <= 1e5
    assert {o.shape for o in objects} == set(SHAPES)
    assert [CoverageObject.of_seed(s) for s in range(60)] == objects  # the seed alone decides
    assert len({o.size for o in objects}) == len(objects)  # and different seeds differ


def test_the_ranges_are_the_studys():
    assert RANGES["size"] == (0.02, 0.045)
    assert RANGES["density"] == (300.0, 1500.0)
    assert RANGES["length_ratio"] == (0.5, 2.0)
    assert RANGES["tilt"] == (0.0, 30.0)
    assert 10 ** RANGES["log10_young"][0] == pytest.approx(5e3)
    assert 10 ** RANGES["log10_young"][1] == pytest.approx(1e5)


def test_the_fingertip_is_scaled_by_the_smallest_radius_and_the_squeeze_tilted_down():
    o = CoverageObject.of_seed(3)
    kw = o.pickup_arguments(0.02)
    assert kw["finger_radius"] == pytest.approx(0.02 * o.radius_ratio)
    d1, d2 = kw["directions"]
    assert d1[2] == d2[2] == pytest.approx(-math.sin(math.radians(o.tilt)))
    assert d1[1] == pytest.approx(-d2[1]) and d1[1] > 0


def test_an_unknown_shape_is_refused_by_name():
    o = CoverageObject.of_seed(0)
    bad = CoverageObject(**dict(o.to_dict(), shape="torus"))
    with pytest.raises(ValueError, match="torus"):
        bad.solid()


# ------------------------------------------------------------------ the capsule
def test_the_capsule_is_a_closed_valid_tet_mesh_of_its_volume():
    pytest.importorskip("gmsh")
    from fem_grasp import TetMesh
    from fem_grasp.mesh.remesh import geometry_of_mesh
    from verification.coverage import capsule

    r, length = 0.02, 0.03
    mesh = TetMesh(*capsule(r, length, 0.006))
    assert (mesh.volumes > 0).all()
    faces = mesh.surface_faces
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    assert (counts == 2).all()  # every surface edge between two triangles: closed
    assert len(mesh.surface_nodes) - len(counts) + len(faces) == 2  # a sphere's Euler characteristic
    geometry_of_mesh(mesh)  # closed, manifold, not self-intersecting: the accuracy loop can remesh it
    exact = capsule_volume(r, length)
    assert exact == pytest.approx(math.pi * r * r * length + 4 / 3 * math.pi * r**3)
    assert 0.95 * exact < mesh.volume < exact  # a polyhedron inscribed in a convex solid
    lo, hi = mesh.bounds
    assert hi - lo == pytest.approx([length + 2 * r, 2 * r, 2 * r], rel=0.02)


def test_the_first_mesh_of_each_shape_has_about_500_vertices():
    pytest.importorskip("gmsh")
    seen = set()
    for seed in range(12):
        o = CoverageObject.of_seed(seed)
        if o.shape in seen:
            continue
        seen.add(o.shape)
        mesh, smallest = o.mesh()
        assert 400 <= mesh.n_points <= 600, (o.shape, mesh.n_points)
        assert 0.0 < smallest <= o.size
        if len(seen) == len(SHAPES):
            break
    assert seen == set(SHAPES)


# --------------------------------------------------------------- the reference
def _accuracy(levels_nodes=(10, 20), step=1e-3, h=0.05, converged=True, est=(0.03, 0.04)):
    levels = [{"level": k, "inner_size": 0.004 / 2**k, "outer_size": 0.006 / 2 ** (0.5 * k), "step": step / 2**k,
               "step_divisions": 4 if k else 1, "resolution": step / 2**k / (4 if k else 1),
               "lift_test_step": h / 2**k, "finger_nodes": [n, n - 2], "max_squeeze": 0.02}
              for k, n in enumerate(levels_nodes)]
    return {"target": 0.05, "converged": converged, "levels": levels,
            "estimated_error": {"squeeze_depth": est[0], "finger_force": est[1]}}


def test_the_reference_is_one_level_beyond_the_answers_last():
    acc = _accuracy()
    plan = reference_plan(acc, 600)
    last = acc["levels"][-1]
    assert plan["inner_size"] == pytest.approx(last["inner_size"] / 2)
    assert plan["outer_size"] == pytest.approx(0.006 / 2)  # the loop's level 2 outer spacing
    # ρ* resolved to a quarter of the last level's resolution: its resolution, divided in four
    assert plan["step"] / plan["step_divisions"] == pytest.approx(last["resolution"] / 4)
    assert plan["lift_test_step"] == pytest.approx(last["lift_test_step"] / 2)
    assert plan["max_squeeze"] == 0.02  # as deep as every level of the answer squeezed
    assert plan["predicted_contacts"] == pytest.approx(80) and not plan["too_large"]
    assert reference_plan(_accuracy(levels_nodes=(40, 160)), 600)["too_large"]  # 640 contacts predicted


def _draw(success=True, rho=0.0100, force=2.0, status="ok"):
    return {"status": status, "success": success, "reason": "", "squeeze_depth": rho, "finger_force": force,
            "max_liftable": 1.0, "weight": 1.0, "vertices": 9000, "seconds": 100.0, "step": 1e-4}


def test_the_reference_is_the_mean_of_its_draws_with_their_spread_as_its_uncertainty():
    ref = combine_draws([_draw(rho=0.0100, force=2.0), _draw(rho=0.0106, force=2.2), _draw(rho=0.0097, force=2.0)])
    assert ref["status"] == "ok" and ref["success"] and ref["draws_ok"] == 3 and ref["seconds"] == 300.0
    assert ref["squeeze_depth"] == pytest.approx(0.0101) and ref["finger_force"] == pytest.approx(6.2 / 3)
    # the largest deviation from the mean, relative to it
    assert ref["spread"]["squeeze_depth"] == pytest.approx(0.0005 / 0.0101)
    assert ref["spread"]["finger_force"] == pytest.approx((2.2 - 6.2 / 3) / (6.2 / 3))
    one = combine_draws([_draw(), _draw(status="failed")])  # a draw that raised is left out
    assert one["status"] == "ok" and one["draws_ok"] == 1 and one["spread"] == {"squeeze_depth": 0.0,
                                                                                  "finger_force": 0.0}
    split = combine_draws([_draw(), _draw(success=False)])  # a finer mesh decides either way: no reference
    assert split["status"] == "draws disagree" and "squeeze_depth" not in split
    assert combine_draws([dict(_draw(status="failed"), error="RuntimeError: x")])["status"] == "failed"
    # a draw that stopped before the squeeze (not force closure) says nothing of the lift: left out
    stopped = dict(_draw(success=False, rho=0.0, force=0.0), step=0.0)
    two = combine_draws([_draw(), _draw(rho=0.0102), stopped])
    assert two["status"] == "ok" and two["draws_ok"] == 2 and two["squeeze_depth"] == pytest.approx(0.0101)
    assert combine_draws([stopped])["status"] == "no squeeze"


def test_a_saved_reference_is_used_again_only_for_its_object_and_a_coarser_answer():
    acc = _accuracy()
    obj = CoverageObject.of_seed(0).to_dict()
    saved = dict(combine_draws([_draw()]), plan=reference_plan(acc, 600), object=obj)
    assert reusable(saved, obj, acc)
    assert not reusable(saved, CoverageObject.of_seed(1).to_dict(), acc)  # another object
    assert not reusable(saved, obj, _accuracy(levels_nodes=(10, 20, 30)))  # the answer went as fine
    assert not reusable(dict(saved, status="timed out"), obj, acc) and not reusable(None, obj, acc)
    # draws that disagree on the verdict are a reference's finding too (running them again finds it again)
    split = dict(combine_draws([_draw(), _draw(success=False)]), plan=saved["plan"], object=obj)
    assert split["status"] == "draws disagree" and reusable(split, obj, acc)
    # squeezed to another deepest squeeze: a failure there stopped elsewhere
    deeper = dict(saved, plan=dict(saved["plan"], max_squeeze=0.021))
    assert not reusable(deeper, obj, acc)
    # saved before plans recorded it (the reference's own 40 %): used where it lifted the object short of the
    # answer's deepest squeeze, which the reference's squeeze then never reached
    old = dict(saved, plan={k: v for k, v in saved["plan"].items() if k != "max_squeeze"})
    assert reusable(old, obj, acc)
    assert not reusable(dict(combine_draws([_draw(success=False, rho=0.0199)]), plan=old["plan"], object=obj), obj, acc)
    assert not reusable(dict(old, squeeze_depth=0.0201), obj, acc)


def test_a_reference_that_runs_out_of_time_keeps_its_plan_for_reuse():
    """The supervisor records a reference that overran its cap with the plan it was run to, so that a later run's
    ``--references`` can take the draws it finished (one real object, in a spawned process, its cap a millisecond)."""
    pytest.importorskip("gmsh")
    from verification.coverage import CONFIGS
    from verification.coverage.runner import supervised

    config = dict(CONFIGS["quick"], accuracy=0.3, reference_seconds=1e-3, reference_draws=1)
    row = supervised(0, config, poll=0.2)
    assert row["answer"]["status"] == "ok"
    assert row["reference"]["status"] == "timed out"
    assert row["reference"]["plan"] == reference_plan(row["answer"]["accuracy"], config["max_reference_contacts"])


def test_the_draws_of_the_reference_scale_its_spacings_about_the_plans():
    factors = [draw_factor(k) for k in range(5)]
    assert factors == pytest.approx([1.0, 1 - DRAW_STEP, 1 + DRAW_STEP, 1 - 2 * DRAW_STEP, 1 + 2 * DRAW_STEP])
    assert np.mean(factors[:3]) == pytest.approx(1.0) and np.mean(factors) == pytest.approx(1.0)


# ---------------------------------------------------------------- the arithmetic
def _row(seed=0, ans=(True, 0.0100, 2.00), ref=(True, 0.0102, 2.05), est=(0.05, 0.05), ref_status="ok"):
    o = CoverageObject.of_seed(seed).to_dict()
    answer = {"status": "ok", "success": ans[0], "squeeze_depth": ans[1], "finger_force": ans[2], "seconds": 10.0,
              "reason": "", "accuracy": _accuracy(est=est)}
    reference = {"status": ref_status, "seconds": 30.0}
    if ref_status == "ok":
        reference.update(success=ref[0], squeeze_depth=ref[1], finger_force=ref[2], reason="")
    return {"seed": seed, "object": o, "answer": answer, "reference": reference}


def test_an_estimate_above_the_actual_error_covers_it():
    e = evaluate(_row())
    assert e["status"] == "compared" and e["verdicts_agree"]
    assert e["actual"]["squeeze_depth"] == pytest.approx(0.0002 / 0.0102)
    assert e["actual"]["finger_force"] == pytest.approx(0.05 / 2.05)
    assert e["covered"] == {"squeeze_depth": True, "finger_force": True} and e["covered_both"]


def test_an_estimate_below_the_actual_error_does_not_cover_it():
    e = evaluate(_row(ref=(True, 0.0120, 2.05)))  # rho* off by 17 %, estimated 5 %
    assert not e["covered"]["squeeze_depth"] and e["covered"]["finger_force"] and not e["covered_both"]


def test_an_answer_equal_to_its_reference_but_for_round_off_is_covered_by_a_stated_zero():
    """A failure at the deepest squeeze states no error for ρ, the setting the reference shares; the mean of the
    reference's draws at that depth may differ from it in the last bit."""
    rho = 0.022608287768529568
    ref = (rho + rho + rho) / 3 * (1 + 2e-16)
    e = evaluate(_row(ans=(False, rho, 8.26), ref=(False, ref, 8.30), est=(0.0, 0.05)))
    assert e["actual"]["squeeze_depth"] > 0.0 and e["covered"]["squeeze_depth"]
    assert not evaluate(_row(ans=(False, rho, 8.26), ref=(False, rho * (1 + 1e-9), 8.30), est=(0.0, 0.05)))[
        "covered"]["squeeze_depth"]  # a billionth is not round-off


def test_a_verdict_that_differs_is_not_covered_unless_the_estimate_is_infinite():
    e = evaluate(_row(ref=(False, 0.0100, 2.00)))  # same numbers, the reference drops the object
    assert not e["verdicts_agree"] and not any(e["covered"].values())
    e = evaluate(_row(ref=(False, 0.0100, 2.00), est=(math.inf, None)))  # None: inf written as JSON null
    assert all(e["covered"].values())
    assert e["estimated"]["finger_force"] == math.inf


def test_the_summary_counts_only_objects_with_a_reference():
    rows = [_row(0), _row(1, ref=(True, 0.0120, 2.05)), _row(2, ref=(False, 0.0100, 2.0)),
            _row(3, ref=(False, 0.0100, 2.0), est=(math.inf, math.inf)), _row(4, ref_status="too large"),
            _row(5, ref_status="timed out")]
    rows.append({"seed": 6, "object": rows[0]["object"], "answer": {"status": "timed out", "seconds": 450.0}})
    s = summarise(rows)
    assert s["objects"] == 7 and s["answered"] == 6 and s["with_reference"] == 4
    assert s["reference_status"] == {"ok": 4, "too large": 1, "timed out": 1}
    assert s["answer_status"] == {"ok": 6, "timed out": 1}
    assert s["verdicts_agree"] == 2 and s["verdicts_differ"] == 2
    assert s["verdicts_differ_settled"] == 1  # the other said it did not know (both estimates infinite)
    assert s["covered"] == {"squeeze_depth": 2, "finger_force": 3, "both": 2}
    assert s["coverage"]["both"] == pytest.approx(0.5)
    assert s["coverage"]["finger_force"] == pytest.approx(0.75)
    assert s["answer_seconds"]["median"] == pytest.approx(10.0)
    assert passed(s) == (False, False)
    good = summarise([_row(k) for k in range(10)])
    assert good["coverage"]["both"] == 1.0 and passed(good) == (True, True)
    nine = summarise([_row(k) for k in range(9)] + [_row(9, ref=(True, 0.0120, 2.05))])
    assert passed(nine) == (True, True)  # 90 % is enough
    crashed = _row(7)
    crashed["answer"] = {"status": "failed", "error": "ZeroDivisionError: float division by zero", "seconds": 1.0}
    assert summarise(rows + [crashed])["errors"] == {"answer: ZeroDivisionError": 1}
    # a verdict the reference overturns fails the study where the answer called it settled, not where it said
    # it was not (the accuracy block's "verdict"; its estimated errors are then infinite)
    overturned = _row(9, ref=(False, 0.0100, 2.00))
    assert passed(summarise([_row(k) for k in range(9)] + [overturned])) == (True, False)
    overturned["answer"]["accuracy"].update(verdict="the last two levels give different verdicts",
                                            estimated_error={"squeeze_depth": None, "finger_force": None})
    warned = summarise([_row(k) for k in range(9)] + [overturned])
    assert warned["verdicts_differ"] == 1 and warned["verdicts_differ_settled"] == 0 and passed(warned) == (True, True)
    assert any("1 said the verdict is not settled" in line for line in summary_lines(warned))
    # the reference's own spread: a shortfall within it is counted apart, the gate stays the strict count
    spread = _row(1, ref=(True, 0.0120, 2.05))
    spread["reference"].update(spread={"squeeze_depth": 0.15, "finger_force": 0.0}, draws_ok=3)
    with_spread = summarise([_row(0), spread])
    assert with_spread["covered"]["both"] == 1 and with_spread["covered_with_reference"] == 2
    assert with_spread["reference_draws"] == [1, 3]
    assert with_spread["reference_spread"]["squeeze_depth"]["max"] == pytest.approx(0.15)
    assert any("both covered on 2/2" in line for line in summary_lines(with_spread))
    # a saved row's draws are combined again; the reference keeps the time it took (an unfinished draw's too)
    drawn = _row(2)
    drawn["reference"].update(draws=[_draw(rho=0.0102, force=2.05)], seconds=450.0)
    assert summarise([drawn])["reference_seconds"]["max"] == 450.0 and evaluate(drawn)["covered_both"]
    # draws of the reference that split on the verdict: no reference, and counted where the answer was sure
    split = summarise([_row(0), _row(1, ref_status="draws disagree")])
    assert split["with_reference"] == 1 and split["draws_disagree_settled"] == 1
    assert any("1 answer(s) called theirs settled" in line for line in summary_lines(split))
    empty = summarise([_row(0, ref_status="too large")])
    assert math.isnan(empty["coverage"]["both"]) and passed(empty) == (False, False)


def test_reanalyse_reads_a_saved_run_and_says_whether_it_passes(tmp_path, capsys):
    path = tmp_path / "coverage.json"
    path.write_text(json.dumps({"rows": [_row(k) for k in range(3)]}))
    assert main(["--reanalyse", str(path)]) == 0
    out = capsys.readouterr().out
    assert "both 3/3" in out and "PASS" in out
    path.write_text(json.dumps({"rows": [_row(0, ref=(False, 0.01, 2.0))]}))
    assert main(["--reanalyse", str(path)]) == 1
    with pytest.raises(SystemExit):
        main(["--reanalyse", str(tmp_path / "missing.json")])


def test_the_report_stage_keeps_the_summary_and_its_checks_can_fail(tmp_path, monkeypatch):
    import verification.coverage as study
    from verification._common.run import json_safe

    rows = [_row(0), _row(1, ref=(False, 0.0100, 2.0)), _row(2, ref_status="too large")]
    monkeypatch.setattr(study, "sweep", lambda cfg: {"config": cfg, "seed": 0, "summary": summarise(rows),
                                                     "rows": rows})

    class Stages:
        def run(self, name, fn, store):
            store(fn())

    part, images = study.run(True, tmp_path, Stages())
    assert images == {} and (tmp_path / "coverage_rows.json").exists()
    assert [o["comparison"]["status"] for o in part["coverage"]["objects"]] == ["compared", "compared",
                                                                                 "no reference"]
    checks = study.checks(part)
    assert [c["ok"] for c in checks] == [False, False]  # 1 of 2 covered; one verdict differs
    assert checks[0]["value"] == pytest.approx(0.5) and checks[1]["value"] == 1
    html = study.section(json_safe(part), {})
    assert CoverageObject.of_seed(1).shape in html
    assert "too large" in html
    assert study.checks({}) == [] and study.section({}, {}) == ""
