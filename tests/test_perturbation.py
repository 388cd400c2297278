"""Same answer on every machine (verification.roundoff): the quick part of the harness.

The shipped scenes' quick variants, the test box and a small gmsh ellipsoid are picked up in fresh
processes under round-off perturbations — 1e-12 coordinate jitter, the plain-Python kernels, one and
two BLAS threads, OpenBLAS's SSE3 kernels, numpy without its FMA3/AVX2 loops — and each must give the
reference's verdict, its squeeze depth within one increment, its finger forces within the stated
tolerance, and pass check() on every snapshot.  ``make verify`` runs the wider sweep on the full scenes.
"""

import pytest

from verification import roundoff as pt

pytest.importorskip("gmsh")


@pytest.fixture(scope="module")
def quick_sweep():
    return pt.sweep(quick=True)


def test_every_case_gives_the_same_answer_under_every_perturbation(quick_sweep):
    assert not quick_sweep["violations"], "\n".join(quick_sweep["violations"])


def test_the_sweep_ran_every_variant_on_every_case(quick_sweep):
    names = set(pt.cases(quick=True))
    variants = quick_sweep["variants"]
    assert {"reference", "jitter-1", "plain-python", "blas-1-thread", "blas-2-threads"} <= set(variants)
    assert any(v.startswith("openblas-") for v in variants)  # every x86-64 CPU runs the SSE3 kernels
    for v in variants:
        assert set(quick_sweep["runs"][v]) == names
        assert all("error" not in r for r in quick_sweep["runs"][v].values()), quick_sweep["runs"][v]
    # the perturbations are real: some variant's forces differ from the reference's in the last bits
    rows = [r for r in quick_sweep["rows"] if r["variant"] != "reference"]
    assert max(r["force_diff"] for r in rows) > 0


def test_the_comparison_flags_what_it_promises():
    ref = {"success": True, "outcome": "picked up", "squeeze_depth": 0.010, "step": 0.001, "weight": 1.0,
           "finger_normal_force": 3.0, "finger_resultants": {"finger1": [0, 1, 0.5], "finger2": [0, -1, 0.5]},
           "events": "AAC", "checks_ok": True, "check_failures": []}
    assert pt.compare(ref, dict(ref))["problems"] == []
    assert pt.compare(ref, dict(ref, squeeze_depth=0.0109))["problems"] == []  # within one increment
    assert "increments" in pt.compare(ref, dict(ref, squeeze_depth=0.0111))["problems"][0]
    assert "verdict" in pt.compare(ref, dict(ref, success=False, outcome="lift failed"))["problems"][0]
    other = dict(ref, finger_resultants={"finger1": [0, 1, 0.6], "finger2": [0, -1, 0.5]})
    assert "finger forces" in pt.compare(ref, other)["problems"][0]
    assert "check()" in pt.compare(ref, dict(ref, checks_ok=False, check_failures=["x"]))["problems"][0]
    assert "raised" in pt.compare(ref, {"error": "IndexError: index 0"})["problems"][0]


def test_the_variants_use_only_what_this_cpu_has():
    assert pt.openblas_cores({"pni", "ssse3", "sse4_2"}) == ["Prescott", "Nehalem"]
    assert "SkylakeX" not in pt.openblas_cores({"pni", "sse4_2", "avx", "avx2", "fma"})
    from numpy.core._multiarray_umath import __cpu_features__

    assert all(__cpu_features__[f] for f in pt.numpy_features_to_disable())
