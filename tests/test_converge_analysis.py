"""The convergence study's analysis (``verification.converge.analysis``) on records whose answers are known by
construction: the reference, each level's error against it, the cheapest resolution per target, the error of the
liftable-weight curve, and the words a verdict flip is explained with."""

import math
import re
from pathlib import Path

import pytest

pytest.importorskip("verification", reason="the source tree's verification/ package (not installed with fem_grasp)")

from verification.converge.analysis import analyse, explain, flips, liftable_gap, liftable_slope, within

WEIGHT = 1.0


def _record(series, level, *, vertices, rho, force, success=True, step=1e-3, h=0.05, liftable=None, seconds=1.0,
            bracket=None):
    spec = {"object": "orange", "series": series, **level}
    curve = liftable if liftable is not None else [[1e-3 * k, min(0.1 * k, 1.0)] for k in range(1, 11)]
    return {"spec": spec, "vertices": vertices, "seconds": seconds, "pickup_seconds": seconds, "patch_spacing": 1.0 / vertices,
            "bracket": bracket, "answer": {
                "success": success, "reason": "" if success else "the lift test did not pass", "squeeze_depth": rho,
                "finger_force": force, "fingers": [{"resultant": 1.0, "along_squeeze": 1.0, "vertical": 0.5, "nodes": 3}] * 2,
                "table_nodes": 10, "max_liftable": max(w for _, w in curve), "weight": WEIGHT, "step": step,
                "lift_test_step": h * WEIGHT, "liftable": curve}}


def _study(records):
    return analyse({str(i): r for i, r in enumerate(records)}, ("orange",), {})["objects"]["orange"]


def test_errors_are_against_the_finest_level_and_the_cheapest_resolution_keeps_every_finer_level_within_it():
    recs = [_record("uniform", {"target": 600}, vertices=600, rho=0.0130, force=8.0, seconds=2),
            _record("uniform", {"target": 1200}, vertices=1200, rho=0.0108, force=6.3, seconds=5),
            _record("uniform", {"target": 2400}, vertices=2400, rho=0.0104, force=6.1, seconds=11),
            _record("uniform", {"target": 4800}, vertices=4800, rho=0.0100, force=6.0, seconds=30, bracket=[0.0099, 0.0101])]
    obj = _study(recs)
    ref = obj["reference"]
    assert ref["success"] and ref["vertices"] == 4800
    # one run: the bracket's midpoint with half its width
    assert ref["rho"]["method"] == "bracket" and ref["rho"]["value"] == pytest.approx(0.0100)
    rows = {r["vertices"]: r for r in obj["series"]["uniform"]}
    assert rows[600]["rho_error"] == pytest.approx(0.30) and rows[600]["force_error"] == pytest.approx(2 / 6)
    assert rows[2400]["rho_error"] == pytest.approx(0.04)
    res = obj["resolution"]["uniform"]
    assert res["0.1"]["vertices"] == 1200  # 8 % and 5 %, and every finer level within 10 %
    assert res["0.05"]["vertices"] == 2400
    assert res["0.02"]["vertices"] == 4800  # only the reference itself


def test_a_level_with_the_wrong_verdict_is_never_within_a_target():
    recs = [_record("uniform", {"target": 600}, vertices=600, rho=0.0100, force=6.0),
            _record("uniform", {"target": 1200}, vertices=1200, rho=0.020, force=9.0, success=False),
            _record("uniform", {"target": 2400}, vertices=2400, rho=0.0101, force=6.05)]
    obj = _study(recs)
    rows = {r["vertices"]: r for r in obj["series"]["uniform"]}
    assert not rows[1200]["verdict_ok"] and math.isinf(rows[1200]["rho_error"])
    assert obj["resolution"]["uniform"]["0.1"]["vertices"] == 2400  # 600 is within 1 %, but 1,200 flips after it
    assert [f["kind"] for f in obj["flips"]] == ["verdict"]


def test_a_reference_that_is_not_picked_up_measures_the_levels_by_their_liftable_weight():
    low = [[1e-3 * k, min(0.1 * k, 0.8)] for k in range(1, 21)]  # peaks at 0.8 mg
    lower = [[1e-3 * k, min(0.1 * k, 0.72)] for k in range(1, 21)]
    recs = [_record("uniform", {"target": 600}, vertices=600, rho=0.006, force=4.0),  # picked up: wrong verdict
            _record("uniform", {"target": 1200}, vertices=1200, rho=0.02, force=9.0, success=False, liftable=lower),
            _record("uniform", {"target": 2400}, vertices=2400, rho=0.02, force=9.0, success=False, liftable=low)]
    obj = _study(recs)
    ref = obj["reference"]
    assert not ref["success"] and ref["max_liftable"] == pytest.approx(0.8)
    rows = {r["vertices"]: r for r in obj["series"]["uniform"]}
    assert not rows[600]["verdict_ok"]
    assert rows[1200]["verdict_ok"] and rows[1200]["w_error"] == pytest.approx(0.08)
    assert not within(rows[1200], 0.05, picked=False) and within(rows[1200], 0.10, picked=False)
    assert obj["resolution"]["uniform"]["0.1"]["vertices"] == 1200


def test_the_liftable_weight_error_is_the_largest_gap_over_the_common_depths():
    ref = [[0.0, 0.0], [2.0, 1.0], [4.0, 1.0]]
    assert liftable_gap([[1.0, 0.5], [3.0, 0.7], [5.0, 0.0]], ref, weight=2.0) == pytest.approx(0.15)  # 0.3 at ρ = 3
    assert math.isnan(liftable_gap([[5.0, 1.0]], ref, weight=1.0))  # no common depth
    # the slope of w about ρ* (the secant over two increments): how far an error in w moves ρ*
    assert liftable_slope([[1.0, 0.1], [2.0, 0.3], [3.0, 0.5], [4.0, 0.7]], 3.5) == pytest.approx(0.2)


def test_jumps_that_reverse_the_trend_are_flagged():
    recs = [_record("graded", {"inner": 0.5}, vertices=600, rho=0.010, force=6.0),
            _record("graded", {"inner": 0.25}, vertices=1200, rho=0.014, force=8.0),
            _record("graded", {"inner": 0.125}, vertices=2400, rho=0.011, force=6.5)]
    obj = _study(recs)
    found = flips(obj["series"])
    assert [(f["kind"], f["row"]["vertices"]) for f in found] == [("jump", 1200)]


def test_a_flip_is_explained_as_the_lift_test_step_or_as_a_physical_outcome_of_the_mesh():
    row = {"step": 1e-3}
    near = {"weight": 1.0, "slow_pass": 0.012, "test_pass": None, "slow_peak": 1.0,
            "rows": [{"rho": 0.012, "test_w": 0.95, "slow_w": 1.0}]}
    assert explain({"kind": "verdict", "row": row}, near).startswith("within the lift test's step h")
    short = {"weight": 1.0, "slow_pass": None, "slow_peak": 0.8, "slow_peak_rho": 0.015, "peak_reason": "gross slip",
             "rows": [{"rho": 0.015, "test_w": 0.75, "slow_w": 0.8}]}
    text = explain({"kind": "verdict", "row": row}, short)
    assert text.startswith("physical outcome of this mesh") and "0.80 mg" in text


def test_the_reference_states_how_far_the_finest_levels_of_the_other_series_are_from_it():
    recs = [_record("uniform", {"target": 1200}, vertices=1200, rho=0.0110, force=6.6),
            _record("uniform", {"target": 4800}, vertices=4800, rho=0.0100, force=6.0, bracket=[0.0099, 0.0101]),
            _record("graded", {"inner": 0.5}, vertices=700, rho=0.0130, force=9.0),  # coarser: not the finest graded
            _record("graded", {"inner": 0.25}, vertices=1400, rho=0.0092, force=6.3),
            _record("graded_table", {"inner": 0.5}, vertices=800, rho=0.0, force=0.0, success=False)]  # not picked up
    band = _study(recs)["reference"]["mesh_band"]
    assert [(x["series"], x["vertices"]) for x in band["levels"]] == [("uniform", 1200), ("graded", 1400)]
    assert band["rho"] == pytest.approx(0.10) and band["force"] == pytest.approx(0.10)


def test_records_made_for_another_version_of_a_scene_are_not_read(tmp_path):
    """A cached run is an answer to one problem: when a shipped scene's file (its modulus, say) or its committed
    mesh changes, the records made for the old one are left out, whatever their code digest says."""
    import json

    from verification.converge.runner import load_records
    from verification.converge.specs import scene_digest

    now = scene_digest("orange")
    for key, scene in (("current", now), ("old", "0" * 12), ("unstamped", None)):
        rec = _record("uniform", {"target": 600}, vertices=600, rho=0.01, force=6.0)
        if scene is not None:
            rec["scene"] = scene
        (tmp_path / f"{key}.json").write_text(json.dumps(rec))
    assert sorted(load_records(tmp_path)) == ["current", "unstamped"]
    assert scene_digest("tomato") != now and scene_digest("orange") == now


def test_a_scene_s_comments_and_stated_error_are_not_its_problem(tmp_path):
    """Writing the study's findings into a scene (its comments, ``[solver] expected_error``) keeps the records
    made for it; a changed modulus does not."""
    from fem_grasp.io.scene import resolve_scene
    from verification.converge.specs import scene_problem

    text = Path(resolve_scene("orange")).read_text()
    edited = text.replace("[solver]\n", "[solver]\n# a new comment\n")
    edited = re.sub(r"^expected_error = [^\n]*", "expected_error = 0.01   # restated", edited, flags=re.M)
    softer = re.sub(r'^young = "[^"]*"', 'young = "5 kPa"', text, flags=re.M)
    assert edited != text and softer != text
    paths = {}
    for key, body in (("shipped", text), ("edited", edited), ("softer", softer)):
        paths[key] = tmp_path / f"{key}.toml"
        paths[key].write_text(body)
    assert scene_problem(paths["edited"]) == scene_problem(paths["shipped"])
    assert scene_problem(paths["softer"]) != scene_problem(paths["shipped"])


def test_the_reference_is_on_the_mesh_its_increments_were_refined_on():
    """When the refined increments ran on a coarser uniform level than the finest (the finest was too slow to
    rerun), the reference is that level's, and the finest uniform level counts in the mesh band."""
    recs = [_record("uniform", {"target": 1200}, vertices=1200, rho=0.0110, force=6.6),
            _record("uniform", {"target": 4800}, vertices=4800, rho=0.0100, force=6.0),
            _record("uniform", {"target": 9600}, vertices=9600, rho=0.0150, force=9.0),
            _record("reference", {"target": 4800, "divisor": 2}, vertices=4800, rho=0.0098, force=5.9, step=5e-4,
                    bracket=[0.0097, 0.0099])]
    ref = _study(recs)["reference"]
    assert ref["vertices"] == 4800 and ref["rho"]["value"] == pytest.approx(0.0098)
    assert ("uniform", 9600) in [(x["series"], x["vertices"]) for x in ref["mesh_band"]["levels"]]
    assert ref["mesh_band"]["rho"] == pytest.approx(0.0150 / 0.0098 - 1)


def test_the_adaptive_answer_at_a_coarser_target_follows_the_loop_s_own_rule():
    """A level "meets" a target as the loop decides: three times its change from the level before (two levels may
    agree by chance) plus one squeeze increment (relative to ρ*), not the change alone — and for ρ* that part at
    least one increment: two levels that find ρ* at the same increment are only known to agree within it.  The
    force states at least ρ*'s error times its exponent over ρ, which the level records (Hertz's 3/2 where an older
    record does not)."""
    from verification.converge.analysis import adaptive_at

    levels = [{"success": True, "squeeze_depth": 0.002, "finger_force": 0.60, "step": 2e-4, "seconds": 1.0},
              {"success": True, "squeeze_depth": 0.002, "finger_force": 0.605, "step": 4e-5, "seconds": 2.0,
               "change": {"squeeze_depth": 0.0, "finger_force": 0.008}, "force_exponent": 1.0}]
    at = adaptive_at({"levels": levels}, 0.05)
    assert at is not None and at["seconds"] == pytest.approx(3.0)
    assert at["estimated_error"]["squeeze_depth"] == pytest.approx(0.04)  # twice the increment, 4e-5 / 2e-3
    assert at["estimated_error"]["finger_force"] == pytest.approx(3 * 0.008 + 0.02)
    assert adaptive_at({"levels": levels}, 0.03) is None  # the change plus the increment (2.8 %) would have met 3 %
    # a force growing as ρ^1.4 states 1.4 × ρ*'s 4 %, above 5 %; a record without the exponent takes Hertz's
    levels[1]["force_exponent"] = 1.4
    assert adaptive_at({"levels": levels}, 0.05) is None
    assert adaptive_at({"levels": levels}, 0.07)["estimated_error"]["finger_force"] == pytest.approx(1.4 * 0.04)
    del levels[1]["force_exponent"]
    assert adaptive_at({"levels": levels}, 0.07)["estimated_error"]["finger_force"] == pytest.approx(1.5 * 0.04)


def test_the_references_written_from_the_study_are_read_back_by_the_benchmarks_where_the_cache_has_none(
        tmp_path, monkeypatch):
    """``--write-references`` keeps each object's reference from the analysis (not its w(ρ)) with the study's
    source, merges it into the file without dropping the other objects, and the accuracy benchmark measures
    against it when this machine's study cache has no reference of its own; the quick study's are refused."""
    from verification.converge import references

    recs = [_record("uniform", {"target": 600}, vertices=600, rho=0.0130, force=8.0),
            _record("uniform", {"target": 4800}, vertices=4800, rho=0.0100, force=6.0, bracket=[0.0099, 0.0101])]
    analysis = {"quick": False, "objects": {"orange": _study(recs), "tomato": {"reference": None}}}
    path = tmp_path / "references.json"
    other = {"success": True, "vertices": 9, "rho": {"value": 0.02, "error": None, "method": "band"},
             "force": {"value": 1.0, "error": 0.1, "method": "band"}}
    path.write_text(__import__("json").dumps({"objects": {"football": other}}))
    assert references.write(analysis, path, machine="test machine") == ["orange"]
    kept = references.load(path)
    assert set(kept) == {"football", "orange"}
    assert math.isinf(kept["football"]["rho"]["error"])  # null in the file: unknown
    orange = kept["orange"]
    assert orange["vertices"] == 4800 and orange["rho"]["value"] == pytest.approx(0.0100)
    assert orange["source"]["machine"] == "test machine" and "liftable" not in orange
    with pytest.raises(ValueError, match="quick"):
        references.write(dict(analysis, quick=True), path)

    from bench import bench
    from verification import converge

    monkeypatch.setattr(references, "REFERENCES", path)
    monkeypatch.setattr(converge, "study", lambda quick=False, compute=True, **kw: analysis)
    refs = bench.study_references(objects=("orange", "football", "tomato"))
    assert refs["orange"]["source"] == "cache"  # this machine's study first
    assert refs["football"]["vertices"] == 9  # the committed one
    assert refs["tomato"] is None
    assert bench.study_references(quick=True, objects=("football",))["football"] is None  # quick: the cache only

    # a pinned reference (the rule's grasp) joins the object's entry; the study's rewrite keeps it
    pinned = {"success": True, "vertices": 31000, "rho": {"value": 0.0101, "error": None, "method": "a single mesh"},
              "force": {"value": 5.6, "error": 0.03, "method": "a single mesh"}, "points": [[0, 0.03, 0]]}
    references.write_pinned("orange", pinned, path, machine="test machine")
    references.write_pinned("steam_bun", pinned, path, machine="test machine")
    references.write(analysis, path, machine="test machine")
    kept = references.load(path)
    assert kept["orange"]["vertices"] == 4800 and kept["orange"]["pinned"]["vertices"] == 31000
    assert math.isinf(kept["orange"]["pinned"]["rho"]["error"])
    assert "pinned_reference.py orange" in kept["orange"]["pinned"]["source"]["command"]
    refs = bench.study_references(objects=("orange", "steam_bun"))
    assert refs["orange"]["source"] == "cache" and refs["orange"]["pinned"]["force"]["value"] == 5.6
    assert refs["steam_bun"] == {"pinned": kept["steam_bun"]["pinned"]}  # no study reference, the pinned one


def test_the_plots_of_a_study_with_no_records_are_drawn_without_warnings(tmp_path):
    # What the benchmarks draw on a machine whose cache holds no study: empty axes, no legend to complain about.
    pytest.importorskip("matplotlib")
    import warnings

    from verification.converge.report import plots

    analysis = analyse({}, ("orange", "tomato"), {})
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        images = plots(analysis, tmp_path)
    assert sorted(images) == ["converge_error_time", "converge_liftable"]
    assert all((tmp_path / name).stat().st_size > 0 for name in images.values())
