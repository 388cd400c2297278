"""The benchmarks' own commands (bench/profile.py, bench/replay.py, bench/tracker.py) run and measure what they say."""

import json
import sys

import pytest

pytest.importorskip("bench", reason="the source tree's bench/ package (not installed with fem_grasp)")

from bench import profile  # noqa: E402
from fem_grasp.contact import implicit_step, tracking
from tests.helpers import perturbed_box


def test_profile_counts_the_return_mappings_and_slip_solves_of_a_pickup(capsys):
    out = profile.main(["football", "--quick", "--top", "3"])
    text = capsys.readouterr().out
    assert "scene football (quick)" in text and "return mappings" in text and "slip systems" in text
    calls = sum(int(n) for n, _ in out["slip"].values())
    assert calls > 0  # the squeeze tracks slip, so the slip systems were solved and counted
    assert all(t >= 0 for _, t in out["slip"].values()) and out["timings"]["total"] > 0
    # every slip solve belongs to a trial state, and each event takes at least the trial that fired it
    assert calls >= out["trials"] >= out["events"] > 0 and "per event" in text
    # the solvers are restored afterwards
    assert implicit_step.relax_contacts.__name__ == "relax_contacts"
    assert tracking.MixedSlipSystem.solve.__name__ == "solve"
    assert tracking.CompiledSlipSystem.solve.__name__ == "solve"
    assert tracking.Tracker.trial.__name__ == "trial"
    assert tracking.one_blas_thread.__name__ == "one_blas_thread"


def test_profile_after_a_first_pickup_counts_the_second_only(capsys):
    """--after-first: the first pickup (factorisation, columns) is timed but neither profiled nor counted; the counters
    hold the second pickup's solves alone (as many trial states as it has, at least one per event)."""
    plain = profile.main(["football", "--quick", "--top", "1"])
    out = profile.main(["football", "--quick", "--top", "1", "--after-first"])
    text = capsys.readouterr().out
    assert out["first_s"] > 0 and "after a first pickup" in text
    assert out["events"] == plain["events"] > 0
    # counted once, not twice: the counters were reset between the pickups
    assert out["events"] <= out["trials"] < 1.5 * plain["trials"]
    assert tracking.Tracker.trial.__name__ == "trial"


def test_replayed_return_mappings_reach_their_recorded_outcomes(tmp_path, capsys, monkeypatch):
    """bench.replay records a pickup's return mappings and solves them again: the same code reaches the same
    outcome on every call, and a solver that changes one verdict is reported."""
    from bench import replay
    from fem_grasp.contact import relaxation

    path = tmp_path / "calls.pkl"
    calls = replay.capture("steam_bun", path, quick=True)  # ~20 return mappings, some failing
    assert path.exists()
    assert any(c[2][0] == "ok" for c in calls) and any(c[2][0] == "fail" for c in calls)
    again = replay.main(["run", str(path)])
    assert again["calls"] == len(calls) and again["changed"] == []
    polish = again["polish"]  # the sweeps hand over to Newton's method; some attempts converge
    assert polish["attempts"] >= polish["converged"] > 0 and polish["converged_cut_below_eighth"] == 0
    # a replay with another polish setting leaves the library's own in place
    replay.main(["run", str(path), "--polish-halvings", "10"])
    assert relaxation._polish.__name__ == "_polish"

    original = relaxation.relax_contacts
    first = []

    def one_verdict_flipped(*args, **kwargs):
        if not first:
            first.append(True)
            raise relaxation.RelaxationFailure("made to fail")
        return original(*args, **kwargs)

    monkeypatch.setattr(relaxation, "relax_contacts", one_verdict_flipped)
    flipped = replay.replay(path)
    assert len(flipped["changed"]) == (1 if calls[0][2][0] == "ok" else 0)


def test_the_floor_counts_the_factor_that_cholmod_computes():
    """bench.bench's floor section counts L by its columns: the counts are the non-zeros of the dense
    Cholesky factor of the matrix in CHOLMOD's order (not the supernodes' padding), nnz(L) their sum and the
    flops Σ c_j²."""
    import numpy as np
    import pytest

    from bench import bench
    from fem_grasp.elastic import compliance, fem

    sksparse = pytest.importorskip("sksparse.cholmod", reason="the floor section counts scikit-sparse's factor")
    cholesky = sksparse.cholesky

    mesh = perturbed_box(np.random.default_rng(3), divisions=(3, 3, 4))
    k = fem.stiffness_matrix(mesh.points, mesh.tets, 1e4, 0.3)
    free = np.setdiff1d(np.arange(k.shape[0]), compliance.grounding_dofs(mesh.points, fem.rigid_modes(mesh.points)))
    kff = k[free][:, free].tocsc()
    factor = cholesky(kff)
    nnz_l, flops, padded = bench.cholesky_counts(factor)
    p = factor.P()
    dense = np.linalg.cholesky(kff.toarray()[np.ix_(p, p)])
    counts = (np.abs(dense) > 1e-12 * np.abs(dense).max()).sum(axis=0)
    assert nnz_l == counts.sum() and flops == (counts.astype(float) ** 2).sum()
    assert nnz_l > kff.nnz // 2  # fill-in: L holds more than K's lower triangle
    assert padded >= flops  # the supernodes' padding only adds
    assert 1 < bench.dense_peak_gflops(n=300, reps=1) < 1e5


def test_the_nodes_a_pickup_touched_all_have_their_compliance_columns():
    """The floor section charges three columns to each node that touched (bench.bench.touched_nodes): the rest's
    contacts and every snapshot's. The tracking needed each of them, so each must be cached after the pickup,
    and the count cannot exceed what was computed."""
    from bench import bench
    from fem_grasp.grasp.pickup import pickup
    from fem_grasp.io.scene import load_scene, resolve_scene

    scene = load_scene(resolve_scene("football"), quick=True)
    result = pickup(scene.body(), **scene.pickup_kwargs())
    touched = bench.touched_nodes(result.rest, result)
    comp = result.body.compliance
    assert set(result.rest.contact_nodes) <= set(touched.tolist())
    for snap in result.snapshots:
        for nodes in snap.contact_nodes.values():
            assert set(nodes.tolist()) <= set(touched.tolist())
    assert all(comp.is_cached(int(k)) for k in touched)
    assert 0 < len(touched) <= comp.cached_nodes


def _fingerprint(rho=0.01, events=(("A", 3, "finger1", "squeeze"),), forces=None, success=True, step=0.001,
                 fingers=None):
    fp = {"success": success, "reason": "", "rho": rho, "events": [list(e) for e in events], "weight": 2.0,
          "step": step,
          "forces": forces if forces is not None else {"finger1": [[0.0, 1.0, 0.5]], "table": [[0.0, 0.0, 1.0]]}}
    if fingers is not None:
        fp["fingers"] = fingers
    return fp


def test_the_same_answer_is_the_verdict_the_depth_within_an_increment_and_the_finger_forces():
    """"The same answer" at the level of the answer: the verdict, ρ* within one squeeze increment, each finger's
    resultant and Σ f·n̂ within 1 % of mg; identical events are reported, not required."""
    from bench.tracker import SAME_FORCE, SAME_RHO_STEPS, compare

    base = _fingerprint()
    assert compare(base, _fingerprint())["same"]
    assert compare(base, _fingerprint(rho=0.01 + 0.9 * SAME_RHO_STEPS * 0.001))["same"]
    far_rho = compare(base, _fingerprint(rho=0.01 + 1.5 * SAME_RHO_STEPS * 0.001))
    assert not far_rho["same"] and far_rho["rho_steps"] == pytest.approx(1.5)
    moved = {"finger1": [[0.0, 1.0 + 10 * SAME_FORCE * 2.0, 0.5]], "table": [[0.0, 0.0, 1.0]]}
    far = compare(base, _fingerprint(forces=moved))
    assert not far["same"] and far["fingers_mg"] == pytest.approx(10 * SAME_FORCE)
    near = {"finger1": [[0.0, 1.0 + 0.5 * SAME_FORCE * 2.0, 0.5]], "table": [[0.0, 0.0, 1.0]]}
    assert compare(base, _fingerprint(forces=near))["same"]
    other = compare(base, _fingerprint(events=(("A", 4, "finger1", "squeeze"),)))
    assert other["same"] and not other["same_events"] and other["event_changes"]
    one_more = {"finger1": [[0.0, 1.0, 0.5], [0.0, 0.1, 0.0]], "table": [[0.0, 0.0, 1.0]]}
    split = compare(base, _fingerprint(forces=one_more))
    assert split["force_mg"] == float("inf") and not split["same"]  # 0.1 N = 5 % of mg more on finger 1
    normal = compare(_fingerprint(fingers=[[0, 1, 0.5, 1.0], [0, -1, 0.5, 1.0]]),
                     _fingerprint(fingers=[[0, 1, 0.5, 1.0 + 4 * SAME_FORCE], [0, -1, 0.5, 1.0]]))
    assert not normal["same"] and normal["fingers_mg"] == pytest.approx(2 * SAME_FORCE)  # Σ f·n̂ of finger 1
    assert not compare(base, _fingerprint(success=False))["same_verdict"]
    assert not compare(base, _fingerprint(success=False))["same"]


def test_different_event_sequences_are_reported_as_the_events_one_removes_and_the_other_adds():
    """A release, re-touch and release of one node at one parameter (the tomato's branch point in the lift)."""
    from bench.tracker import event_changes

    base = [["C", 1, "table", "lift"], ["B", 260, "table", "lift"], ["D", 284, "table", "lift"]]
    new = base[:2] + [["A", 260, "table", "lift"], ["B", 260, "table", "lift"]] + base[2:]
    assert event_changes(base, base) == []
    assert event_changes(base, new) == [{"at": 2, "removed": [], "added": new[2:4]}]
    assert event_changes(new, base) == [{"at": 2, "removed": new[2:4], "added": []}]


def test_the_tracker_section_runs_a_baseline_commit_beside_this_checkout(tmp_path):
    """Two worker processes, one on the exported baseline tree (it checks which fem_grasp it imported), time the
    same scene in turns; against this checkout's own commit the answers are the same and repeatable."""
    from bench.tracker import PHASES, section_tracker

    sec = section_tracker("HEAD", reps=1, scenes=("foam_block",), warm_up=None, quick=True, export_to=tmp_path,
                          large=(400,), mesh_cache=tmp_path / "meshes")
    assert [r["scene"] for r in sec["rows"]] == ["foam_block", "orange 0.4k"]  # a scene, and a uniform orange
    assert (tmp_path / f"baseline-{sec['baseline'][:12]}" / "fem_grasp" / "__init__.py").exists()
    for row in sec["rows"]:
        assert row["answer"]["same"] and row["repeatable"] and row["answer"]["events"][0] > 0
        assert len(row["baseline"]["times"]) == len(row["current"]["times"]) == 2 and row["ratio"] > 0
        # The phases are parts of the timed call: each non-negative, together their total, which the call
        # contains (the set-up, the body's assembly, is the rest of it).  A single run: its median is itself.
        ph = row["current"]["phases"]
        assert set(ph) == set(PHASES) and min(ph.values()) >= 0.0
        assert sum(v for k, v in ph.items() if k != "total") == pytest.approx(ph["total"], rel=0.05)
        assert ph["total"] <= row["current"]["median"]
        assert ph["rest"] > 0.0 and ph["lift_test"] > 0.0
    with pytest.raises(SystemExit, match="not a commit"):
        section_tracker("no-such-commit", export_to=tmp_path)


def test_the_tracker_section_compares_this_checkout_with_a_switch_set(tmp_path):
    """--against: the baseline worker is this checkout with a setting (derived contact responses off) and an
    environment variable set; the switch reaches the worker (a wrong module attribute stops it) and the answers
    agree."""
    from bench.tracker import _against, section_tracker

    assert _against(["fem_grasp.elastic.response.NEIGHBOUR_SHARE=0.5", "ENV:FEM_GRASP_X=1"]) == (
        {"FEM_GRASP_X": "1"}, [["fem_grasp.elastic.response.NEIGHBOUR_SHARE", "0.5"]])
    with pytest.raises(SystemExit, match="expected"):
        _against(["NEIGHBOUR_SHARE"])
    sec = section_tracker(reps=1, scenes=("foam_block",), warm_up=None, quick=True,
                          against=("settings.neighbour_updates=False", "ENV:OMP_NUM_THREADS=1"))
    assert sec["baseline"].startswith("this checkout with settings.neighbour_updates=False")
    row = sec["rows"][0]
    assert row["answer"]["same"] and row["repeatable"] and row["answer"]["events"][0] > 0
    with pytest.raises(RuntimeError, match="no attribute .NO_SUCH_SWITCH."):
        section_tracker(reps=1, scenes=("foam_block",), warm_up=None, quick=True,
                        against=("fem_grasp.elastic.response.NO_SUCH_SWITCH=1",))


def test_a_switched_constant_imported_by_value_elsewhere_is_named(monkeypatch, caplog):
    """--against module.ATTRIBUTE sets the attribute in that module only: the modules that imported the constant by
    value keep the old one, and the worker warns naming them unless the switches name them too.  No module of the
    package copies the batch size PREFETCH_NODES any more (the trackers read their settings), so a stand-in module
    copies it here."""
    import importlib
    import logging
    import types

    from bench.tracker import _apply_switches, by_value_copies

    # (by importlib: the package exports a function named compliance)
    compliance = importlib.import_module("fem_grasp.elastic.compliance")
    importlib.import_module("fem_grasp.contact.tracking")
    assert by_value_copies(compliance, "PREFETCH_NODES") == []  # the engine reads its settings, not the constant
    copy = types.ModuleType("fem_grasp.by_value_copy")
    copy.PREFETCH_NODES = compliance.PREFETCH_NODES  # what `from ..elastic.compliance import PREFETCH_NODES` does
    monkeypatch.setitem(sys.modules, copy.__name__, copy)
    assert by_value_copies(compliance, "PREFETCH_NODES") == [copy.__name__]
    monkeypatch.setattr(compliance, "PREFETCH_NODES", compliance.PREFETCH_NODES)  # restored after the test
    old = compliance.PREFETCH_NODES
    monkeypatch.setenv("BENCH_SWITCHES", json.dumps([["fem_grasp.elastic.compliance.PREFETCH_NODES", "7"]]))
    with caplog.at_level(logging.WARNING, logger="bench"):
        _apply_switches()
    assert compliance.PREFETCH_NODES == 7
    assert copy.PREFETCH_NODES == old  # not named: it keeps its copy ...
    warned = [r.getMessage() for r in caplog.records if r.name == "bench"]
    assert len(warned) == 1 and copy.__name__ in warned[0]  # ... and the worker says so
    caplog.clear()
    monkeypatch.setenv("BENCH_SWITCHES", json.dumps([["fem_grasp.elastic.compliance.PREFETCH_NODES", "8"],
                                                     [f"{copy.__name__}.PREFETCH_NODES", "8"]]))
    with caplog.at_level(logging.WARNING, logger="bench"):
        _apply_switches()
    assert compliance.PREFETCH_NODES == 8 and copy.PREFETCH_NODES == 8
    assert not [r for r in caplog.records if r.name == "bench"]  # every copy named, so no warning


def test_an_engine_setting_switched_by_the_bench_reaches_every_tracker_of_the_worker(monkeypatch):
    """--against settings.FIELD=VALUE: the worker's trackers are built with that field changed (and only it); an
    unknown field is refused naming it."""
    from bench.tracker import _against, _apply_switches
    from fem_grasp.settings import DEFAULT_SETTINGS

    monkeypatch.setattr(tracking.Tracker, "default_settings", DEFAULT_SETTINGS)  # restored after the test
    env, switches = _against(["settings.implicit_contacts=0", "ENV:OMP_NUM_THREADS=1"])
    assert switches == [["settings.implicit_contacts", "0"]] and env == {"OMP_NUM_THREADS": "1"}
    monkeypatch.setenv("BENCH_SWITCHES", json.dumps(switches))
    _apply_switches()
    assert tracking.Tracker.default_settings.changed() == {"implicit_contacts": 0}
    monkeypatch.setenv("BENCH_SWITCHES", json.dumps([["settings.implicit_contact", "0"]]))
    with pytest.raises(ValueError, match="'implicit_contact' .did you mean 'implicit_contacts'"):
        _apply_switches()


def test_two_placement_searches_are_compared_placement_by_placement():
    """compare_search: a placement is the same answer when its outcome and event counts are equal and its ρ* and
    finger forces agree to the promised tolerances; no ρ* on either side (not picked up) is no difference; a
    placement found by one search only, or one number beyond its tolerance, is named with what differs."""
    from bench.tracker import SAME_FORCE, SAME_RHO_STEPS, compare_search

    row = {"status": "ok", "outcome": "picked up", "success": True, "events": 80, "events_A": 20, "events_B": 10,
           "events_C": 30, "events_D": 20, "rho_star": 0.01, "step": 0.001, "weight": 2.0, "force1": 3.0,
           "force2": 3.1, "finger_normal_force": 5.0}
    missed = {**row, "outcome": "squeeze failed", "success": False, "rho_star": None}
    base = {"a": row, "b": missed}
    near = {"a": {**row, "rho_star": 0.01 + 0.5 * SAME_RHO_STEPS * 0.001, "force2": 3.1 + 0.5 * SAME_FORCE * 2.0,
                  "events_C": 31},
            "b": dict(missed)}
    same = compare_search(base, near)
    assert same["same"] and not same["same_events"] and not same["placements_differ"]  # event counts: reported
    assert same["placements"] == 2 and same["picked_up"] == [1, 1] and same["events"] == [160, 160]
    far = compare_search(base, {"a": {**row, "rho_star": 0.0115}, "c": missed})
    assert not far["same"] and far["rho_steps"] == pytest.approx(1.5)
    what = {d["key"]: d["what"] for d in far["placements_differ"]}
    assert set(what) == {"a", "b", "c"}
    assert "rho* 10 -> 11.5 mm" in what["a"]
    assert what["b"] == "only in the baseline search" and what["c"] == "only in the current search"
    flipped = compare_search(base, {"a": {**row, "outcome": "lift failed", "success": False}, "b": missed})
    assert not flipped["same"] and "outcome picked up -> lift failed" in flipped["placements_differ"][0]["what"]
    forces = compare_search(base, {"a": {**row, "force1": 3.0 + 4 * SAME_FORCE}, "b": missed})
    assert not forces["same"] and forces["force_mg"] == pytest.approx(2 * SAME_FORCE)
    assert compare_search(base, {"a": {**row, "rho_star": None}, "b": missed})["rho_steps"] == float("inf")


def test_the_tracker_section_runs_a_placement_search_in_both_workers():
    """--search: both workers run the placement search's candidates in their own process (the switch sets the
    lift test's halvings the baseline worker's trackers read, here to their default) and the rows are compared
    placement by placement."""
    from bench.tracker import section_tracker

    sec = section_tracker(reps=1, scenes=(), warm_up=None, quick=True, searches=("foam_block",), candidates=3,
                          against=("settings.load_halvings=3",))
    (row,) = sec["rows"]
    assert row["scene"] == "search foam_block" and row["repeatable"]
    a = row["answer"]
    assert a["same"] and a["placements"] == 3 and a["events"][0] > 0 and a["picked_up"][0] == a["picked_up"][1]
    assert "phases" not in row["current"] or row["current"]["phases"] == {}


def test_the_tracker_section_runs_a_scene_as_fem_grasp_run_does_in_both_workers():
    """--runs: both workers answer the scene as ``run_scene`` does with the spec's changes (here one level on the
    foam block's mesh, the baseline worker's polish factorising in double precision); the answers are compared as a
    pickup's.  A spec whose changes are not key=value pairs stops before any work."""
    from bench.tracker import scene_run_request, section_tracker

    assert scene_run_request("tomato:refinement=nested,max_finger_contacts=600") == {
        "run": "tomato", "changes": {"refinement": "nested", "max_finger_contacts": 600}}
    assert scene_run_request("orange") == {"run": "orange", "changes": {}}
    with pytest.raises(SystemExit, match="expected NAME:key=value"):
        section_tracker(reps=1, scenes=(), warm_up=None, runs=("tomato:nested",))
    sec = section_tracker(reps=1, scenes=(), warm_up=None, runs=("foam_block:accuracy=off",),
                          against=("settings.single_precision_factors=False",))
    (row,) = sec["rows"]
    assert row["scene"] == "foam_block:accuracy=off (run)" and row["repeatable"]
    assert row["answer"]["same"] and row["answer"]["events"][0] > 0
    assert row["current"]["phases"]["total"] > 0


def _fake_answer(success=True, rho=0.011, force=6.6, seconds=2.0, stated=None, vertices=600, max_liftable=2.0):
    return {"seconds": seconds, "later_seconds": 0.75 * seconds, "later_same": True, "vertices": vertices,
            "levels": 1, "converged": False, "note": "",
            "stated": stated if stated is not None else {},
            "answer": {"success": success, "reason": "" if success else "lift test did not pass",
                       "squeeze_depth": rho, "finger_force": force, "max_liftable": max_liftable, "weight": 2.0}}


def test_the_accuracy_section_measures_each_run_against_the_study_reference(monkeypatch, capsys):
    """bench.bench's accuracy section: a run's error is |run − reference| / |reference| for ρ* and Σ f·n̂, the
    stated error covers it only when it is at least as large for both, a wrong verdict is never covered, a run
    beyond the cap is reported as not run, and an object the study has no reference for is skipped (nothing is
    computed for it)."""
    from bench import bench

    reference = {"success": True, "vertices": 50000, "rho": {"value": 0.010, "error": 0.01, "method": "bracket"},
                 "force": {"value": 6.0, "error": 0.02, "method": "band"}, "max_liftable": 2.0, "weight": 2.0,
                 "step": 1e-4}
    asked = []
    monkeypatch.setattr(bench, "study_references", lambda quick, compute, objects: (
        asked.append((quick, compute, objects)) or {"orange": reference, "tomato": None}))
    raw = {"one_level": _fake_answer(rho=0.011, force=6.6, stated={"squeeze_depth": 0.3, "finger_force": 0.3}),
           # states 5 %: covers ρ* (4 %) but not the force (10 %)
           "default": _fake_answer(rho=0.0104, force=6.6, stated={"squeeze_depth": 0.05, "finger_force": 0.05}),
           "adaptive": {"status": "cap", "cap_s": 7.0},
           "remesh": _fake_answer(rho=0.0101, force=6.06, stated={"squeeze_depth": 0.02, "finger_force": 0.02})}
    ran, exponents = [], set()
    # another draw of the default's meshes: 8 % / 3 % off, stating 10 % / 10 %
    drawn = _fake_answer(rho=0.0108, force=6.18, stated={"squeeze_depth": 0.1, "finger_force": 0.1})

    def fake_worker(name, run, cap, draw=0, outer_exponent=None):
        ran.append((name, run, cap, draw))
        exponents.add(outer_exponent)
        return drawn if draw else raw[run]

    monkeypatch.setattr(bench, "run_accuracy_worker", fake_worker)
    monkeypatch.setattr(bench, "default_accuracy", lambda name: None)  # a default of one run: three runs
    sec = bench.section_accuracy(cap=7.0, objects=("orange", "tomato"), draws=2)
    assert asked == [(False, False, ("orange", "tomato"))]  # read only: the study is not started
    # tomato: no reference, not run; the default and the remeshed levels again on two other draws of their meshes
    assert ran == [("orange", run, 7.0, 0) for run, _ in bench.ACCURACY_RUNS] + [
        ("orange", run, 7.0, k) for run in ("default", "remesh") for k in (1, 2)]
    assert sec["objects"]["tomato"] == {"reference": None}
    assert exponents == {None} and sec["outer_exponent"] is None  # the library's rule for the bulk
    rows = sec["objects"]["orange"]["rows"]
    one, default = rows["one_level"], rows["default"]
    assert one["verdict_ok"] and one["error"]["squeeze_depth"] == pytest.approx(0.1)
    assert one["error"]["finger_force"] == pytest.approx(0.1) and one["covers"] is True
    assert default["error"]["squeeze_depth"] == pytest.approx(0.04) and default["covers"] is False
    assert rows["adaptive"]["status"] == "cap"
    assert rows["remesh"]["error"]["squeeze_depth"] == pytest.approx(0.01) and rows["remesh"]["covers"] is True

    # stated 5 % against 6 % off a reference uncertain by 2 %: not covered, but within the two errors
    close = bench.accuracy_errors(_fake_answer(rho=0.0106, force=6.0, stated={"squeeze_depth": 0.05,
                                                                             "finger_force": 0.05}), reference)
    assert close["covers"] is False and close["covers_with_reference"] is True
    assert default["covers_with_reference"] is False  # 5 % + 2 % < 10 %

    # nothing stated (or only an infinite bound): unknown, neither covered nor not
    unknown = bench.accuracy_errors(_fake_answer(stated={"squeeze_depth": float("inf"),
                                                         "finger_force": float("inf")}), reference)
    assert unknown["stated"] is None and unknown["covers"] is None
    # the wrong verdict: infinite error, never covered however large the stated error
    wrong = bench.accuracy_errors(_fake_answer(success=False, stated={"squeeze_depth": 0.9, "finger_force": 0.9}),
                                  reference)
    assert not wrong["verdict_ok"] and wrong["error"]["squeeze_depth"] == float("inf") and wrong["covers"] is False
    # neither picks it up: the same verdict, no ρ* to compare, the largest weight held compared instead
    dropped = dict(reference, success=False, max_liftable=1.6)
    both = bench.accuracy_errors(_fake_answer(success=False, max_liftable=1.8,
                                              stated={"squeeze_depth": 0.2, "finger_force": 0.2}), dropped)
    assert both["verdict_ok"] and both["covers"] is True and both["w_error"] == pytest.approx(0.1)

    bench.print_accuracy(sec)
    text = capsys.readouterr().out
    assert "not run (cap" in text and "no reference" in text
    assert not any("wrong verdict" in line for line in text.splitlines() if "picked up" in line)
    assert "10 %" in text and "yes" in text and "NO" in text
    assert "2.0/1.5" in text  # the first call of the process and a later one
    draws = rows["draws"]
    assert len(draws) == 2 and draws[0]["covers"] is True
    assert draws[0]["error"]["squeeze_depth"] == pytest.approx(0.08)
    # the default and its two draws: the largest error of each quantity, covered by two of the three
    (summary,) = [line for line in text.splitlines() if "Scene.run(), all 3 draws" in line]
    assert "largest error 8 % / 10 %" in summary and "covers it 2/3" in summary and "verdict 3/3" in summary
    # the remeshed levels (1 % / 1 %) and the same two draws: their own line
    assert len(rows["remesh_draws"]) == 2
    (summary,) = [line for line in text.splitlines() if "remeshed levels, all 3 draws" in line]
    assert "largest error 8 % / 3 %" in summary and "covers it 3/3" in summary

    # where the scene's default is the adaptive loop at the target, that run is not made twice: its row repeats
    monkeypatch.setattr(bench, "default_accuracy", lambda name: bench.ACCURACY_TARGET)
    ran.clear()
    again = bench.section_accuracy(cap=7.0, objects=("orange",), draws=0)["objects"]["orange"]["rows"]
    assert ran == [("orange", "one_level", 7.0, 0), ("orange", "default", 7.0, 0), ("orange", "remesh", 7.0, 0)]
    assert again["draws"] == again["remesh_draws"] == []
    assert again["adaptive"]["same_as"] == "default" and again["adaptive"]["error"] == again["default"]["error"]
    bench.print_accuracy({"study": "full", "cap_s": 7.0, "target": 0.05,
                          "objects": {"orange": {"reference": reference, "rows": again}}})
    assert "the same run as Scene.run() as shipped" in capsys.readouterr().out

    # a study of the bulk's rule: every run refines the bulk by the exponent asked for, and the table says so
    exponents.clear()
    study_rule = bench.section_accuracy(cap=7.0, objects=("orange",), draws=1, outer_exponent=0.0)
    assert exponents == {0.0} and study_rule["outer_exponent"] == 0.0
    bench.print_accuracy(study_rule)
    assert "refines the bulk by 2**0 (--accuracy-outer-exponent)" in capsys.readouterr().out


def test_the_accuracy_section_measures_against_the_pinned_reference_where_an_object_has_one(monkeypatch, capsys):
    """Where an object has a reference at the placement rule's own grasp points (pinned), every run's error and
    whether its statement covers it are against that one; the study's reference (each mesh grasping at its own
    nodes) gives the second error beside it, and both references are printed."""
    from bench import bench

    study = {"success": True, "vertices": 50000, "rho": {"value": 0.0107, "error": 0.01, "method": "bracket"},
             "force": {"value": 6.1, "error": 0.02, "method": "band"}, "max_liftable": 2.0, "weight": 2.0,
             "step": 1e-4}
    pinned = {"success": True, "vertices": 31000, "rho": {"value": 0.0100, "error": 0.03, "method": "two meshes"},
              "force": {"value": 5.6, "error": 0.02, "method": "two meshes"}, "max_liftable": 2.0, "weight": 2.0,
              "step": 1.5e-4, "source": {"command": "python scripts/pinned_reference.py orange --write-reference",
                                         "date": "2026-12-04", "machine": "test"}}
    monkeypatch.setattr(bench, "study_references", lambda quick, compute, objects: {
        "orange": dict(study, pinned=pinned), "tomato": {"pinned": pinned}})
    monkeypatch.setattr(bench, "run_accuracy_worker", lambda name, run, cap, draw=0, outer_exponent=None: _fake_answer(
        rho=0.0102, force=5.88, stated={"squeeze_depth": 0.03, "finger_force": 0.06}))
    sec = bench.section_accuracy(cap=7.0, objects=("orange", "tomato"))
    orange, tomato = sec["objects"]["orange"], sec["objects"]["tomato"]
    assert orange["reference"]["kind"] == "pinned" and orange["study_reference"]["vertices"] == 50000
    row = orange["rows"]["default"]
    assert row["error"]["squeeze_depth"] == pytest.approx(0.02) and row["error"]["finger_force"] == pytest.approx(0.05)
    assert row["covers"] is True  # 3 % / 6 % stated against 2 % / 5 % off the rule's grasp
    assert row["error_study"]["squeeze_depth"] == pytest.approx(0.5 / 10.7, rel=1e-6)
    # an object with only a pinned reference is measured against it, with no study error beside
    assert tomato["study_reference"] is None and "error_study" not in tomato["rows"]["default"]
    bench.print_accuracy(sec)
    text = capsys.readouterr().out
    assert "reference, rule's grasp" in text and "study, grasps at own nodes" in text
    assert "pinned_reference.py orange" in text and "(study's: 4.7 % / 3.6 %)" in text


def test_the_accuracy_section_runs_a_shipped_scene_in_a_subprocess_within_its_cap():
    """The accuracy section's worker runs the shipped foam block on its own grid (accuracy off): it picks the
    block up, on the scene's mesh, and states the error the scene states for such a run; the later call in the
    same process gives the same answer to the bit; a cap shorter than the run stops it and says so."""
    from bench import bench
    from fem_grasp.io.scene import Scene

    scene = Scene.load("foam_block")
    raw = bench.run_accuracy_worker("foam_block", "one_level", cap=600.0)
    assert raw["answer"]["success"] and raw["answer"]["squeeze_depth"] > 0 and raw["answer"]["finger_force"] > 0
    assert raw["vertices"] == scene.load_mesh().n_points and raw["levels"] == 1 and raw["seconds"] > 0
    assert raw["later_seconds"] > 0 and raw["later_same"] is True
    assert raw["stated"] == {"squeeze_depth": scene.expected_error, "finger_force": scene.expected_error}
    assert bench.run_accuracy_worker("foam_block", "one_level", cap=0.5) == {"status": "cap", "cap_s": 0.5}
    # a worker that fails: its last stderr line as the error, the lines before it kept for a post-mortem
    failed = bench.run_accuracy_worker("foam_block", "no_such_run", cap=600.0)
    assert failed["status"] == "error" and "unknown run 'no_such_run'" in failed["error"]
    assert failed["stderr_tail"][-1] == failed["error"] and len(failed["stderr_tail"]) <= bench.STDERR_TAIL


def test_the_divisions_section_measures_the_three_increments_of_a_scene(capsys):
    """One shipped scene, one repetition: the divided increment's ρ* lies within one sub-increment of the s/4 run's,
    it runs fewer lift tests than s/4, and the table prints its distance in sub-increments."""
    from bench import divisions

    sec = divisions.measure(("football",), divisions=4, reps=1)
    sc = sec["scenes"]["football"]
    rows = sc["rows"]
    assert set(rows) == {"s", "s divided", "s/4"}
    assert abs(rows["s divided"]["squeeze_depth"] - rows["s/4"]["squeeze_depth"]) <= sc["step"] / 4 * (1 + 1e-9)
    assert rows["s divided"]["lift_tests"] < rows["s/4"]["lift_tests"]
    divisions.print_divisions(sec)
    assert "sub-increments" in capsys.readouterr().out
