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
    # the solvers are restored afterwards
    assert tracking.relax_contacts.__name__ == "relax_contacts"
    assert tracking.MixedSlipSystem.solve.__name__ == "solve"
    assert tracking.one_blas_thread.__name__ == "one_blas_thread"
