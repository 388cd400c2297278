"""The return mapping's compiled Newton polish (fem_grasp.contact.kernels.polish) against its numpy reference.

``relaxation._polish`` stays as the reference of the kernel the return mappings call where numba is installed
(``EngineSettings.compiled_polish``).  The two run the same iteration in another summation order: on every polish
of the test problems both converge or both give up, to the same state within the polish's own tolerance; the
return mappings that call either reach the same answer (:func:`tests.helpers.assert_same_relaxation`).  Each
comparison runs on the problems as they are and jittered by :data:`tests.helpers.JITTER`, so one that holds only
by bitwise luck fails on every CPU.
"""

import numpy as np
import pytest

from fem_grasp.contact import relaxation
from fem_grasp.settings import DEFAULT_SETTINGS
from tests.helpers import JITTER_SEEDS, assert_same_relaxation, relaxation_problems

#: Compiled against numpy polish, relative to each array's largest entry: both stop once every residual is below
#: ``local_tol`` (1e-3 × tol × the force scale), one chord step apart at most.
POLISH_AGREEMENT = 1e-9


def test_both_polishes_take_their_iteration_limits_from_the_settings(monkeypatch):
    """Each polish of the test problems that converges with the default limits converges in neither path with no
    Newton iteration allowed; the default (None) is the compiled kernel where numba is installed."""
    calls, _ = _polish_calls(monkeypatch, None)
    monkeypatch.undo()
    s = DEFAULT_SETTINGS
    default = (s.polish_iterations, s.polish_halvings, s.chord_contraction, s.single_precision_factors)
    none = (0, s.polish_halvings, 0.25, True)
    converging = [args[:10] for args in calls if relaxation._polish(*args[:10], default) is not None]
    assert len(converging) >= 3
    for args in converging:
        assert relaxation._compiled_polish(*args, default) is not None
        assert relaxation._polish(*args, none) is None and relaxation._compiled_polish(*args, none) is None
    assert DEFAULT_SETTINGS.compiled_polish is None  # compiled where numba is installed


def _outcome(args, kwargs):
    """A return mapping's answer as :func:`tests.helpers.relaxation_outcomes` gives it."""
    try:
        r = relaxation.relax_contacts(*args, **kwargs)
        return r.status, r.forces, r.displacements, args[6]
    except relaxation.RelaxationFailure as exc:
        return exc.kind


def _polish_calls(monkeypatch, seed):
    """Every polish the test problems' return mappings call (their arguments), and the problems' outcomes."""
    calls = []
    reference = relaxation._polish

    def recording(*args):
        calls.append(args)
        return reference(*args)

    monkeypatch.setattr(relaxation, "_polish", recording)
    numpy_polish = DEFAULT_SETTINGS.replace(compiled_polish=False)
    return calls, [_outcome(args, {**kwargs, "settings": numpy_polish}) for args, kwargs in relaxation_problems(seed)]


@pytest.mark.parametrize("seed", JITTER_SEEDS)
def test_every_polish_of_the_test_problems_ends_alike_compiled_and_in_numpy(monkeypatch, seed):
    calls, _ = _polish_calls(monkeypatch, seed)
    monkeypatch.undo()
    assert len(calls) >= 5
    converged = 0
    for args in calls:
        ref = relaxation._polish(*args)
        comp = relaxation._compiled_polish(*args)
        assert (ref is None) == (comp is None)
        if ref is None:
            continue
        converged += 1
        _assert_same_polish(comp, ref)
    assert converged >= 3


def _assert_same_polish(comp, ref):
    """The same root within the polish's tolerance, and the same verdict on whether its statuses hold."""
    assert comp.holds == ref.holds
    for mine, theirs in zip(comp[1:], ref[1:]):
        np.testing.assert_allclose(mine, theirs, rtol=0, atol=POLISH_AGREEMENT * max(float(np.abs(theirs).max()), 1e-300))


@pytest.mark.parametrize("seed", JITTER_SEEDS)
def test_return_mappings_with_the_compiled_polish_reach_the_reference_states(monkeypatch, seed):
    """The test problems' static states (statuses, forces, displacements) with either polish, or the same kind of
    failure."""
    _, reference = _polish_calls(monkeypatch, seed)
    monkeypatch.undo()
    compiled_polish = DEFAULT_SETTINGS.replace(compiled_polish=True)
    compiled = [_outcome(args, {**kwargs, "settings": compiled_polish}) for args, kwargs in relaxation_problems(seed)]
    assert len(compiled) == len(reference) == 7
    for comp, ref in zip(compiled, reference):
        assert_same_relaxation(comp, ref)


@pytest.mark.parametrize("status", [(relaxation.SLIDE,), (relaxation.RELEASE,), (relaxation.STICK,)])
def test_a_one_contact_polish_agrees(status):
    """One fingertip contact: sliding onto its cone, released, or (nothing to polish) sticking."""
    from fem_grasp.contact.kernels import gauss_seidel as gs

    centre = np.array([0.0, 0.0, 0.02])
    rec = gs.contact_records(np.array([centre - [0.0, 0.0, 0.01]]), [centre], np.array([0.0, 0.0, 1.0]),
                             100.0 * np.eye(3)[None])
    c = 100.0 * np.eye(3)
    f0 = np.array([[0.0, 0.3, 1.0]])
    args = (rec, c, f0, np.array([0.2]), np.array(status, dtype=np.int64), np.zeros((1, 3)),
            np.array([[0.0, -1e-3]]), 1e-12, 1e-11, np.inf)
    ref, comp = relaxation._polish(*args), relaxation._compiled_polish(*args)
    assert (ref is None) == (comp is None)
    if status[0] == relaxation.STICK:
        assert ref is None
    if ref is not None:
        assert ref.holds
        _assert_same_polish(comp, ref)


@pytest.mark.parametrize("seed", JITTER_SEEDS)
def test_going_on_from_a_polish_whose_statuses_do_not_hold_reaches_the_same_static_state(seed):
    """The sweeps may go on from a polished state with a few wrong statuses (``polish_adoptions``) or from their
    own iterate: the test problems reach the same statuses, forces and displacements, or fail alike."""
    discard = DEFAULT_SETTINGS.replace(polish_adoptions=0)
    for args, kwargs in relaxation_problems(seed):
        assert_same_relaxation(_outcome(args, kwargs), _outcome(args, {**kwargs, "settings": discard}))


def test_a_polish_says_when_its_root_breaks_a_status():
    """Two table contacts pushed sideways with one held as sticking: the polish converges, and the sticking
    contact's force then lies outside its cone (statuses do not hold); the sweeps can go on from that root."""
    from fem_grasp.contact.kernels import gauss_seidel as gs

    up = np.array([0.0, 0.0, 1.0])
    positions = np.array([[0.0, 0.0, 0.0], [0.01, 0.0, 0.0]])
    c = 100.0 * np.eye(6)
    rec = gs.contact_records(positions, [None, None], up, np.stack([100.0 * np.eye(3)] * 2))
    f0 = np.array([[0.5, 0.0, 1.0], [0.5, 0.0, 1.0]])
    args = (rec, c, f0, np.array([0.2, 0.2]), np.array([relaxation.SLIDE, relaxation.STICK], dtype=np.int64),
            np.zeros((2, 3)), np.array([[-1e-3, 0.0], [0.0, 0.0]]), 1e-12, 1e-11, np.inf)
    ref, comp = relaxation._polish(*args), relaxation._compiled_polish(*args)
    assert ref is not None and comp is not None
    assert not ref.holds
    _assert_same_polish(comp, ref)
    # the sliding contact's force is on its cone at the root: |f_t| = μ f_n
    f = ref.forces[0]
    assert np.hypot(f[0], f[1]) == pytest.approx(0.2 * f[2], rel=1e-9)
    assert relaxation._adoptable(ref, args[4], np.inf)


@pytest.mark.parametrize("seed", JITTER_SEEDS)
def test_single_precision_factors_reach_the_double_precision_states(seed):
    """The polish's Jacobians factorised in single precision (refined against the double-precision Jacobian) or in
    double: every polish of the test problems that converges both ways reaches the same root within the polish's
    tolerance, and the return mappings reach the same static states (or fail alike), compiled and in numpy."""
    double = DEFAULT_SETTINGS.replace(single_precision_factors=False)
    assert DEFAULT_SETTINGS.single_precision_factors
    compared = 0
    for args, kwargs in relaxation_problems(seed):
        for compiled in (True, False):
            single = DEFAULT_SETTINGS.replace(compiled_polish=compiled)
            assert_same_relaxation(_outcome(args, {**kwargs, "settings": single}),
                                   _outcome(args, {**kwargs, "settings": double.replace(compiled_polish=compiled)}))
            compared += 1
    assert compared == 14


def _ill_conditioned_release(cond: float):
    """A polish of four released table contacts whose stiffness C has condition number ``cond``: its Jacobian is
    C itself, its root δ = −C⁻¹ f⁰ (where every released contact carries no force)."""
    from fem_grasp.contact.kernels import gauss_seidel as gs

    rng = np.random.default_rng(3)
    m = 4
    positions = np.c_[rng.uniform(-0.01, 0.01, (m, 2)), np.zeros(m)]
    q, _ = np.linalg.qr(rng.normal(size=(3 * m, 3 * m)))
    c = 100.0 * q @ np.diag(np.logspace(0.0, -np.log10(cond), 3 * m)) @ q.T
    c = 0.5 * (c + c.T)
    rec = gs.contact_records(positions, [None] * m, np.array([0.0, 0.0, 1.0]),
                             np.stack([c[3 * k:3 * k + 3, 3 * k:3 * k + 3] for k in range(m)]))
    f0 = rng.normal(size=(m, 3))
    args = (rec, c, f0, np.full(m, 0.5), np.full(m, relaxation.RELEASE, dtype=np.int64), np.zeros((m, 3)),
            np.zeros((m, 2)), 1e-7, 1e-7, np.inf)
    return args, -np.linalg.solve(c, f0.ravel()).reshape(m, 3)


def test_a_jacobian_too_ill_conditioned_for_single_precision_is_factorised_in_double(monkeypatch):
    """At cond(J) = 1e9 single-precision factors cannot give a Newton step (their solve is off by ~cond × 6e-8):
    the polish falls back to double precision's and reaches the root, compiled and in numpy, as double precision
    alone does; with the fallback disabled the numpy polish finds no root."""
    from fem_grasp.contact.kernels import polish

    args, root = _ill_conditioned_release(1e9)
    s = DEFAULT_SETTINGS
    limits = (s.polish_iterations, s.polish_halvings, s.chord_contraction)
    for run in (relaxation._polish, relaxation._compiled_polish):
        for single in (True, False):
            out = run(*args, (*limits, single))
            assert out is not None
            assert np.abs(out.forces).max() <= args[7]  # released: no force, to the polish's tolerance
            np.testing.assert_allclose(out.displacements, root, rtol=0, atol=1e-6 * np.abs(root).max())
    monkeypatch.setattr(polish, "SINGLE_PRECISION_DEFECT", np.inf)
    assert relaxation._polish(*args, (*limits, True)) is None
