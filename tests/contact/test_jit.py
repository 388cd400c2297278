"""The compiled (numba) and plain-Python kernels give the same answers (fem_grasp.contact.kernels.jit).

The sweep kernels of :mod:`fem_grasp.contact.kernels.gauss_seidel` and the slip-system
kernels of :mod:`fem_grasp.contact.kernels.slip_newton` are one source run two ways; the
plain-Python run happens in a subprocess with FEM_GRASP_NO_JIT=1 (the choice
is made at import).  What is promised is the answer: a load with a static state gets the same
statuses, forces and displacements within the relaxation's tolerance; a load friction cannot hold
fails with the same kind of failure in both (not at the same contact nor after as many sweeps:
there is no static state, and which contact the sweep order meets first is round-off's choice);
the slip systems have the same roots.  Each comparison also runs on inputs jittered by
:data:`tests.helpers.JITTER`, so one that holds only by bitwise luck fails on every CPU.
"""

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from fem_grasp.contact.kernels import jit
from tests.helpers import (
    JITTER_SEEDS,
    ROOT,
    assert_same_relaxation,
    box_squeezed_3mm,
    in_plain_python,
    jittered,
    relaxation_outcomes,
)

UP = np.array([0.0, 0.0, 1.0])


def slip_trials(seed=None):
    """Trial states of the squeezed box (three or more nodes sliding) in both slip forms, over a range of
    increments up to a third of the fingertip radius: each trial's (disp, forces, slip amounts); the state's
    displacements jittered by :data:`tests.helpers.JITTER` unless ``seed`` is None."""
    from dataclasses import replace

    _, tracker, state, vel = box_squeezed_3mm()
    rng = None if seed is None else np.random.default_rng(seed)
    state = replace(state, disp=jittered(state.disp, rng))
    out = []
    for free in (False, True):
        tracker.forms = (free,)
        for dt in (1e-6, 1e-4, 1e-3, 3.4e-3):
            t = tracker.trial(state, dt, vel, methods=("newton",))
            out.append((t.state.disp, t.state.forces, t.amounts))
    return out


NEEDS_NUMBA = pytest.mark.skipif(not jit.ENABLED, reason="numba is not installed (or FEM_GRASP_NO_JIT is set): "
                                                        "only the plain-Python kernels exist here")


@NEEDS_NUMBA
@pytest.mark.parametrize("seed", JITTER_SEEDS)
def test_compiled_and_plain_python_sweeps_agree(seed):
    compiled = relaxation_outcomes(seed)
    python = in_plain_python("tests.helpers:relaxation_outcomes", seed)
    assert len(python) == len(compiled) == 7
    assert [isinstance(r, str) for r in compiled] == [False] * 5 + [True] * 2  # the two loads friction cannot hold
    assert compiled[5:] == ["gross slip"] * 2
    for a, b in zip(compiled, python):
        assert_same_relaxation(a, b)


#: Compiled against plain-Python slip systems, relative to each array's largest entry: both Newton iterations stop
#: once the scaled residual is <= 1e-12 (``slip_system.MixedSlipSystem.solve``), and rounding in another order can
#: stop them one iterate apart; the slip systems' conditioning (up to ~1e3 here) turns that into ~1e-9.
SLIP_SOLVE_AGREEMENT = 1e-9


@NEEDS_NUMBA
@pytest.mark.parametrize("seed", JITTER_SEEDS)
def test_compiled_and_plain_python_slip_systems_agree(seed):
    compiled = slip_trials(seed)
    python = in_plain_python("tests.contact.test_jit:slip_trials", seed)
    assert len(compiled) == len(python) == 8
    for a, b in zip(compiled, python):
        for u, v in zip(a, b):
            np.testing.assert_allclose(u, v, rtol=0, atol=SLIP_SOLVE_AGREEMENT * np.abs(v).max())


def empty_projections():
    """The polish's slide projections when no contact slides (every non-sticking one released)."""
    from fem_grasp.contact.kernels import gauss_seidel as gs

    proj, delta = gs.SlideGeometry(np.zeros((0, gs.RECORD)), np.zeros(0)).projections(np.zeros((0, 2)))
    return proj.shape, delta.shape


def test_a_polish_with_no_sliding_contact_has_empty_projections_in_both_kernel_modes():
    """Regression (the perturbation harness's plain-Python runs crashed with an IndexError): the plain
    kernels return [] for zero contacts, which must still read as a (0, 9) table."""
    assert empty_projections() == ((0, 2, 3), (0, 3))
    assert in_plain_python("tests.contact.test_jit:empty_projections") == ((0, 2, 3), (0, 3))


def test_warm_up_compiles_every_entry_point(tmp_path):
    """``make setup`` compiles the kernels with fem_grasp.contact.warm_up: in a fresh process (an empty numba
    cache), every kernel called from Python must then have a compiled signature, and none is left for a pickup
    to compile.  The kernel modules name their entry points; the callers register the samples."""
    import importlib

    from fem_grasp.contact.warm_up import entry_points, warm_up

    points = entry_points()
    assert set(points) == {"fem_grasp.contact.kernels.gauss_seidel", "fem_grasp.contact.kernels.slip_newton",
                           "fem_grasp.contact.kernels.slip_trial", "fem_grasp.contact.kernels.slip_residual",
                           "fem_grasp.contact.kernels.slip_homotopy", "fem_grasp.contact.kernels.polish",
                           "fem_grasp.contact.kernels.events", "fem_grasp.contact.kernels.dense"}
    for module, names in points.items():
        mod = importlib.import_module(module)
        assert names and all(callable(getattr(mod, n)) for n in names)
    if not jit.ENABLED:
        assert warm_up() == 0.0
        return
    code = ("import importlib, json; from fem_grasp.contact.warm_up import entry_points, warm_up; warm_up(); "
            "print(json.dumps({m: {n: len(getattr(importlib.import_module(m), n).signatures) for n in names} "
            "for m, names in entry_points().items()}))")
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path))
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, check=True, capture_output=True, text=True)
    counts = json.loads(out.stdout.strip().splitlines()[-1])
    assert all(n >= 1 for names in counts.values() for n in names.values()), counts


@NEEDS_NUMBA
def test_a_pickup_after_the_warm_up_compiles_nothing():
    """Regression (the first tomato pickup after ``make setup`` spent 11 s compiling): the warm-up's samples must
    have the argument types a pickup passes (a read-only table normal was a second signature of four kernels).
    In a fresh process, a pickup on the table after :func:`warm_up` adds no signature to any entry point."""
    code = ("import importlib, json; from fem_grasp.contact.warm_up import entry_points, warm_up; warm_up(); "
            "count = lambda: {f'{m}.{n}': len(getattr(importlib.import_module(m), n).signatures) "
            "for m, names in entry_points().items() for n in names}; before = count(); "
            "from tests.helpers import pick_up_box; r = pick_up_box(0.8); "
            "print(json.dumps([r.success, len(r.events), before, count()]))")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, check=True, capture_output=True, text=True)
    success, n_events, before, after = json.loads(out.stdout.strip().splitlines()[-1])
    assert n_events > 0  # the pickup tracked events (it ran the trial kernels)
    assert after == before, {k: (before[k], after[k]) for k in after if after[k] != before[k]}


def test_kernels_cached_under_other_options_are_dropped_once(tmp_path):
    """numba's cache does not record nogil: entries of a cache without the marker of jit.OPTIONS (kernels cached by
    an earlier version, which held the GIL) are removed before compiling, once; with the marker they stay."""
    cache = tmp_path / "__pycache__"
    cache.mkdir()
    for name in ("polish.polish-129.py311.nbi", "polish.polish-129.py311.1.nbc", "keep.txt"):
        (cache / name).write_text("x")
    jit._drop_stale_cache(cache)
    assert sorted(p.name for p in cache.iterdir()) == sorted(["keep.txt", jit.OPTIONS_MARKER])
    (cache / "sweep-317.py311.nbi").write_text("x")
    jit._drop_stale_cache(cache)  # marked: numba's own entries are left to numba
    assert (cache / "sweep-317.py311.nbi").exists()
    jit._drop_stale_cache(tmp_path / "absent" / "__pycache__")  # nothing to drop, nowhere to write: no error
