"""The compiled (numba) and plain-Python kernels give the same answers (fem_grasp.contact.kernels.jit).

The sweep kernels of :mod:`fem_grasp.contact.kernels.gauss_seidel` and the slip-system
kernels of :mod:`fem_grasp.contact.kernels.slip_newton` are one source run two ways; the
plain-Python run happens in a subprocess with FEM_GRASP_NO_JIT=1 (the choice
is made at import).  The sweeps must reach the same statuses in the same
number of sweeps, with the same forces, or fail with the same message; the
slip systems the same roots.
"""

import json
import os
import pickle
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from fem_grasp.contact.kernels import jit
from fem_grasp.contact.relaxation import RelaxationFailure, relax_contacts
from tests.helpers import box_on_the_table_pushed_sideways, box_squeezed_3mm, squeezed_box_contacts

ROOT = Path(__file__).resolve().parents[2]
UP = np.array([0.0, 0.0, 1.0])


def _problems():

    out = []
    for mu, depth in [(0.5, 2e-3), (0.3, 2e-3), (0.5, 4e-3), (0.2, 1e-3)]:
        c, f0, q0, centers, mu_k, _ = squeezed_box_contacts(mu, depth)
        out.append(((c, f0, q0, centers, UP, mu_k, float(np.abs(f0).max())), {}))
    for tangential in (0.49, 0.6, 1.0):  # held; steady drift; a contact with no local state
        c, f, q, centers, mu_k = box_on_the_table_pushed_sideways(tangential)
        out.append(((c, f, q, centers, UP, mu_k, 1.0), {"max_slip": 1.0}))
    return out


def solve_all():
    """Each problem's (statuses, sweeps, forces, displacements), or its failure message."""
    results = []
    for args, kwargs in _problems():
        try:
            r = relax_contacts(*args, **kwargs)
            results.append((r.status, r.sweeps, r.forces, r.displacements))
        except RelaxationFailure as exc:
            results.append(str(exc))
    return results


def slip_trials():
    """Trial states of the squeezed box (three or more nodes sliding) in both slip forms, over a range of
    increments up to a third of the fingertip radius: each trial's (disp, forces, slip amounts)."""

    _, tracker, state, vel = box_squeezed_3mm()
    out = []
    for free in (False, True):
        tracker.forms = (free,)
        for dt in (1e-6, 1e-4, 1e-3, 3.4e-3):
            t = tracker.trial(state, dt, vel, methods=("newton",))
            out.append((t.state.disp, t.state.forces, t.amounts))
    return out


def in_plain_python(name: str, tmp_path: Path, module: str = "tests.contact.test_jit"):
    """<module>.<name>() run in a subprocess with FEM_GRASP_NO_JIT=1."""
    out = tmp_path / f"{name}.pkl"
    env = dict(os.environ, FEM_GRASP_NO_JIT="1")
    code = ("import pickle, sys; from fem_grasp.contact.kernels import jit; assert not jit.ENABLED; "
            f"from {module} import {name}; pickle.dump({name}(), open(sys.argv[1], 'wb'))")
    subprocess.run([sys.executable, "-c", code, str(out)], cwd=ROOT, env=env, check=True)
    return pickle.loads(out.read_bytes())


NEEDS_NUMBA = pytest.mark.skipif(not jit.ENABLED, reason="numba is not installed (or FEM_GRASP_NO_JIT is set): "
                                                        "only the plain-Python kernels exist here")


@NEEDS_NUMBA
def test_compiled_and_plain_python_sweeps_agree(tmp_path):
    compiled = solve_all()
    python = in_plain_python("solve_all", tmp_path)
    assert len(python) == len(compiled) == 7
    assert sum(isinstance(r, str) for r in compiled) == 2  # the two loads friction cannot hold
    for a, b in zip(compiled, python):
        if isinstance(a, str) or isinstance(b, str):
            assert a == b
            continue
        np.testing.assert_array_equal(a[0], b[0])
        assert a[1] == b[1]
        scale = np.abs(a[2]).max()
        np.testing.assert_allclose(a[2], b[2], rtol=0, atol=1e-12 * scale)
        np.testing.assert_allclose(a[3], b[3], rtol=0, atol=1e-12 * np.abs(a[3]).max() + 1e-300)


#: Compiled against plain-Python slip systems, relative to each array's largest entry: both Newton iterations stop
#: once the scaled residual is <= 1e-12 (``slip_system.MixedSlipSystem.solve``), and rounding in another order can
#: stop them one iterate apart; the slip systems' conditioning (up to ~1e3 here) turns that into ~1e-9.
SLIP_SOLVE_AGREEMENT = 1e-9


@NEEDS_NUMBA
def test_compiled_and_plain_python_slip_systems_agree(tmp_path):
    compiled = slip_trials()
    python = in_plain_python("slip_trials", tmp_path)
    assert len(compiled) == len(python) == 8
    for a, b in zip(compiled, python):
        for u, v in zip(a, b):
            np.testing.assert_allclose(u, v, rtol=0, atol=SLIP_SOLVE_AGREEMENT * np.abs(v).max())


def empty_projections():
    """The polish's slide projections when no contact slides (every non-sticking one released)."""
    from fem_grasp.contact.kernels import gauss_seidel as gs

    proj, delta = gs.SlideGeometry(np.zeros((0, gs.RECORD)), np.zeros(0)).projections(np.zeros((0, 2)))
    return proj.shape, delta.shape


def test_a_polish_with_no_sliding_contact_has_empty_projections_in_both_kernel_modes(tmp_path):
    """Regression (the perturbation harness's plain-Python runs crashed with an IndexError): the plain
    kernels return [] for zero contacts, which must still read as a (0, 9) table."""
    assert empty_projections() == ((0, 2, 3), (0, 3))
    assert in_plain_python("empty_projections", tmp_path) == ((0, 2, 3), (0, 3))


def test_warm_up_compiles_every_entry_point(tmp_path):
    """``make setup`` compiles the kernels with fem_grasp.contact.warm_up: in a fresh process (an empty numba
    cache), every kernel called from Python must then have a compiled signature, and none is left for a pickup
    to compile.  The kernel modules name their entry points; the callers register the samples."""
    import importlib

    from fem_grasp.contact.warm_up import entry_points, warm_up

    points = entry_points()
    assert set(points) == {"fem_grasp.contact.kernels.gauss_seidel", "fem_grasp.contact.kernels.slip_newton",
                           "fem_grasp.contact.kernels.slip_trial", "fem_grasp.contact.kernels.polish",
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
