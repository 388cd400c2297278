"""The profiling command of issue #7 (bench/profile.py) runs and counts what it says it counts."""

from bench import profile
from fem_grasp import tracking


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
    assert tracking.relax_contacts.__name__ == "relax_contacts"
    assert tracking.MixedSlipSystem.solve.__name__ == "solve"
    assert tracking.Tracker.trial.__name__ == "trial"
    assert tracking.one_blas_thread.__name__ == "one_blas_thread"


def test_replayed_return_mappings_reach_their_recorded_outcomes(tmp_path, capsys, monkeypatch):
    """bench.replay records a pickup's return mappings and solves them again: the same code reaches the same
    outcome on every call, and a solver that changes one verdict is reported."""
    from bench import replay
    from fem_grasp import relaxation

    path = tmp_path / "calls.pkl"
    calls = replay.capture("steam_bun", path, quick=True)  # ~20 return mappings, some failing
    assert path.exists()
    assert any(c[2][0] == "ok" for c in calls) and any(c[2][0] == "fail" for c in calls)
    again = replay.main(["run", str(path)])
    assert again["calls"] == len(calls) and again["changed"] == []
    polish = again["polish"]  # the sweeps hand over to Newton's method; some attempts converge
    assert polish["attempts"] >= polish["converged"] > 0 and polish["converged_cut_below_eighth"] == 0
    # a replay with another polish setting leaves the library's own in place
    default = relaxation.POLISH_HALVINGS
    replay.main(["run", str(path), "--polish-halvings", "10"])
    assert relaxation.POLISH_HALVINGS == default and relaxation._polish.__name__ == "_polish"

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
