"""The generalised inverse X of K (fem_grasp.elastic.compliance) with every sparse solver of
fem_grasp.elastic.sparse_solvers: the solvers, the column cache, kept rows."""

import threading

import numpy as np
import pytest
import scipy.sparse as sp

from fem_grasp import Body, ContactResponse, solve_contact
from fem_grasp.elastic import compliance as cp
from fem_grasp.elastic import sparse_solvers as ss
from tests.elastic.test_sparse_solvers import AVAILABLE
from tests.helpers import blas_threads, perturbed_box


@pytest.fixture(scope="module")
def body():
    return Body(perturbed_box(np.random.default_rng(7), divisions=(4, 3, 3)), 3e4, 0.35, weight=1.5)


@pytest.mark.parametrize("solver", AVAILABLE)
def test_compliance_is_a_generalised_inverse(body, rng, solver):
    """K X F = F for every load F orthogonal to the rigid modes; X is symmetric."""
    comp = cp.Compliance(body.stiffness, body.mesh.points, body.rigid_modes, solver=solver)
    assert comp.solver == solver
    q = body.orthonormal_rigid_modes
    f = rng.standard_normal((3 * body.n_nodes, 3))
    f -= q @ (q.T @ f)
    x = comp.apply(f)
    k = body.stiffness
    assert np.abs(k @ x - f).max() <= 1e-9 * np.abs(f).max()
    nodes = np.array([0, 5, 17, 30])
    cols = comp.node_columns(nodes)
    block = cols[(3 * nodes[:, None] + np.arange(3)).ravel()]
    assert np.abs(block - block.T).max() <= 1e-10 * np.abs(block).max()
    assert np.array_equal(comp.contact_block(nodes), block)
    coeffs = rng.standard_normal(3 * len(nodes))
    np.testing.assert_allclose(comp.combine(nodes, coeffs), cols @ coeffs, rtol=1e-13,
                               atol=1e-13 * np.abs(cols).max() * np.abs(coeffs).max())


def test_solvers_agree(body, rng):
    cols = {s: cp.Compliance(body.stiffness, body.mesh.points, body.rigid_modes, solver=s).node_columns([3, 9, 40])
            for s in AVAILABLE}
    ref = cols["superlu"]
    for s, c in cols.items():
        assert np.abs(c - ref).max() <= 1e-9 * np.abs(ref).max(), s


@pytest.mark.parametrize("solver", AVAILABLE)
def test_contact_solutions_agree_across_solvers_and_with_spectral(body, monkeypatch, solver):
    """The environment variable picks the solver of Body.compliance; forces and fields match the paper's route."""
    monkeypatch.setenv(ss.SOLVER_ENV, solver)
    fresh = body.with_material()
    assert fresh.compliance.solver == solver
    nodes = np.array([0, 4, 19, 33, 45])
    disp = np.random.default_rng(1).standard_normal((5, 3)) * 1e-4
    a = solve_contact(fresh, nodes, disp)
    b = solve_contact(body, nodes, disp, backend="spectral")
    assert np.abs(a.forces - b.forces).max() <= 1e-9 * np.abs(b.forces).max()
    assert np.abs(a.displacements - b.displacements).max() <= 1e-9 * np.abs(b.displacements).max()


def test_kept_rows_match_full_columns(body):
    """Compliance(rows=surface) caches only surface rows, equal to the same rows of the full columns."""
    surf = body.mesh.surface_nodes
    full = cp.Compliance(body.stiffness, body.mesh.points, body.rigid_modes, solver="superlu")
    lean = cp.Compliance(body.stiffness, body.mesh.points, body.rigid_modes, solver="superlu", rows=surf)
    nodes = surf[[0, 7, 20]]
    sdofs = (3 * surf[:, None] + np.arange(3)).ravel()
    assert np.array_equal(lean.node_columns(nodes), full.node_columns(nodes)[sdofs])
    assert np.array_equal(lean.contact_block(nodes), full.contact_block(nodes))
    assert np.array_equal(lean.node_columns(nodes, rows=surf[5:9]), full.node_columns(nodes, rows=surf[5:9]))
    assert lean.cache_bytes * body.n_nodes == full.cache_bytes * len(surf)
    interior = np.setdiff1d(np.arange(body.n_nodes), surf)[0]
    with pytest.raises(ValueError, match=f"node {interior} is not among"):
        lean.node_columns(nodes, rows=[interior])


def test_columns_are_cached_once_per_node(body):
    comp = cp.Compliance(body.stiffness, body.mesh.points, body.rigid_modes, solver="superlu")
    calls = []
    inner = comp._solve
    comp._solve = lambda b: calls.append(b.shape) or inner(b)
    comp.node_columns([1, 2, 3])
    comp.node_columns([3, 2, 1, 4])
    assert calls == [(3 * body.n_nodes - 6, 9), (3 * body.n_nodes - 6, 3)]
    assert comp.cached_nodes == 4


def test_bad_solver_names_and_inputs_are_refused(body, monkeypatch):
    with pytest.raises(ValueError, match="unknown sparse solver 'umfpack'"):
        ss.factorize(sp.eye(3).tocsc(), "umfpack")
    monkeypatch.setenv(ss.SOLVER_ENV, "pardiso")
    with pytest.raises(ValueError, match=r"unknown sparse solver 'pardiso' \(\$FEM_GRASP_SOLVER\)"):
        ss.choose_solver()
    monkeypatch.setenv(ss.SOLVER_ENV, "auto")
    assert ss.choose_solver() == ("cholmod" if ss.cholmod_available() else "superlu")
    comp = cp.Compliance(body.stiffness, body.mesh.points, body.rigid_modes, solver="superlu")
    with pytest.raises(ValueError, match="not a node of the body"):
        comp.node_columns([body.n_nodes])
    with pytest.raises(ValueError, match="expected a load with"):
        comp.apply(np.zeros(5))
    with pytest.raises(ValueError, match="rows must be node indices"):
        cp.Compliance(body.stiffness, body.mesh.points, body.rigid_modes, solver="superlu", rows=[-1, 2])


@pytest.mark.parametrize("solver", AVAILABLE)
def test_prefetched_columns_equal_columns_solved_one_node_at_a_time(body, solver):
    """prefetch solves many nodes' columns at once (the rest's likely next contacts); each must equal the
    column of its node solved alone, and be cached."""
    batch = cp.Compliance(body.stiffness, body.mesh.points, body.rigid_modes, solver=solver)
    single = cp.Compliance(body.stiffness, body.mesh.points, body.rigid_modes, solver=solver)
    nodes = [3, 9, 40, 41, 57]
    batch.prefetch(nodes)
    assert all(batch.is_cached(k) for k in nodes) and not batch.is_cached(2) and batch.cached_nodes == 5
    for k in nodes:
        ref = single.node_columns([k])
        np.testing.assert_allclose(batch.node_columns([k]), ref, rtol=0, atol=1e-12 * np.abs(ref).max())


def test_prefetch_fills_up_with_the_likely_next_contacts_in_one_solve(body):
    comp = cp.Compliance(body.stiffness, body.mesh.points, body.rigid_modes, solver="superlu")
    calls = []
    inner = comp._solve
    comp._solve = lambda b: calls.append(b.shape[1]) or inner(b)
    comp.node_columns([9])
    comp.prefetch([3], likely=[3, 9, 2, 2, 40, 41], count=3)  # 3 is asked for; 9 is cached; 2 once
    assert calls == [3, 9] and all(comp.is_cached(k) for k in (3, 2, 40)) and not comp.is_cached(41)
    comp.prefetch([2, 3], likely=[50, 51], count=10)  # nothing new is asked for: no solve at all
    assert calls == [3, 9] and not comp.is_cached(50)


@pytest.mark.parametrize("bound", ["bytes", "nodes"])
def test_many_columns_are_solved_in_blocks_of_bounded_memory(body, monkeypatch, bound):
    """More columns than SOLVE_BLOCK_BYTES allows at once (a flat base of thousands of table contacts), or
    than SOLVE_NODES nodes' (the allocator's reuse), are solved block by block, each block's right-hand sides
    and solution within the bound, with the same columns."""
    comp = cp.Compliance(body.stiffness, body.mesh.points, body.rigid_modes, solver="superlu")
    single = cp.Compliance(body.stiffness, body.mesh.points, body.rigid_modes, solver="superlu")
    per_node = 2 * 8 * 3 * len(comp.free)  # bytes of one node's right-hand sides and solution
    if bound == "bytes":
        monkeypatch.setattr(cp, "SOLVE_BLOCK_BYTES", 2 * per_node)
    else:
        monkeypatch.setattr(cp, "SOLVE_NODES", 2)
    calls = []
    inner = comp._solve
    comp._solve = lambda b: calls.append(b.shape[1]) or inner(b)
    nodes = [3, 9, 40, 41, 57]
    comp.prefetch(nodes)
    assert calls == [6, 6, 3] and all(comp.is_cached(k) for k in nodes)
    for k in nodes:
        ref = single.node_columns([k])
        np.testing.assert_allclose(comp.node_columns([k]), ref, rtol=0, atol=1e-12 * np.abs(ref).max())


@pytest.mark.parametrize("rows", [False, True])
def test_columns_of_grounded_nodes_equal_the_compliance_applied_to_unit_loads(body, rows):
    """Columns are solved on the free DOFs only (no padded (3n, k) copies); the grounded DOFs' rows and
    loads are zero, as X applied to the unit loads gives them."""
    surf = body.mesh.surface_nodes
    comp = cp.Compliance(body.stiffness, body.mesh.points, body.rigid_modes, solver="superlu",
                         rows=np.union1d(surf, comp_ground_nodes(body)) if rows else None)
    nodes = np.unique(comp.ground // 3)
    assert len(nodes) >= 2  # the grounded DOFs sit on two or three nodes
    unit = np.zeros((comp.n_dofs, 3 * len(nodes)))
    for j, k in enumerate(nodes):
        unit[3 * k: 3 * k + 3, 3 * j: 3 * j + 3] = np.eye(3)
    ref = comp.apply(unit)
    kept = slice(None) if not rows else (3 * comp.kept_nodes[:, None] + np.arange(3)).ravel()
    np.testing.assert_allclose(comp.node_columns(nodes), ref[kept], rtol=0, atol=1e-14 * np.abs(ref).max())
    assert np.all(comp.node_columns(nodes)[np.searchsorted(np.arange(comp.n_dofs)[kept], comp.ground)] == 0)


def comp_ground_nodes(body):
    return np.unique(cp.grounding_dofs(body.mesh.points, body.rigid_modes) // 3)


def test_column_solves_use_every_blas_thread_inside_the_tracking_limit(body):
    """The tracking runs BLAS on one thread (small dense systems); the multi-column sparse solves inside it
    get the threads back (fem_grasp.threads), as do dense systems of DENSE_THREADS_MIN rows or more."""
    threadpoolctl = pytest.importorskip("threadpoolctl")
    from fem_grasp.threads import one_blas_thread

    comp = cp.Compliance(body.stiffness, body.mesh.points, body.rigid_modes, solver="superlu")
    seen = []
    inner = comp._solve
    comp._solve = lambda b: seen.append(blas_threads()) or inner(b)
    with threadpoolctl.threadpool_limits(limits=2, user_api="blas"):
        outer = blas_threads()
        with one_blas_thread():
            assert blas_threads() == 1
            comp.node_columns([5])
            comp.apply(np.ones(comp.n_dofs))
            assert blas_threads() == 1
        assert blas_threads() == outer
    comp.node_columns([6])
    assert seen[:2] == [outer, outer] and outer == 2
    from fem_grasp.threads import DENSE_THREADS_MIN, blas_threads_for

    with threadpoolctl.threadpool_limits(limits=2, user_api="blas"), one_blas_thread():
        with blas_threads_for(DENSE_THREADS_MIN):
            assert blas_threads() == 2
        with blas_threads_for(DENSE_THREADS_MIN - 1):
            assert blas_threads() == 1
        # two lift tests side by side: the limit is one setting of the process, so neither gets the threads back
        from fem_grasp.threads import side_by_side

        with side_by_side(), blas_threads_for(DENSE_THREADS_MIN):
            comp.node_columns([7])
            assert blas_threads() == 1 and seen[-1] == 1


def test_a_branch_shares_the_factor_and_keeps_columns_of_its_own(body, monkeypatch):
    """Compliance.branch (a tracker in a second thread): no second factorisation, the columns computed so far,
    the same columns as this one's for new nodes, and none of its own added to this one's cache."""
    comp = cp.Compliance(body.stiffness, body.mesh.points, body.rigid_modes, solver="superlu")
    comp.node_columns([3])
    calls = []
    factorize = ss.factorize
    monkeypatch.setattr(cp, "factorize", lambda *a, **k: calls.append(1) or factorize(*a, **k))
    twin = comp.branch()
    assert twin.is_cached(3) and not calls
    np.testing.assert_allclose(twin.node_columns([9]), comp.node_columns([9]), rtol=0, atol=1e-12 * np.abs(
        comp.node_columns([9])).max())
    twin.node_columns([11])
    assert twin.is_cached(11) and not comp.is_cached(11) and not calls
    np.testing.assert_array_equal(twin.combine([3], np.ones(3)), comp.combine([3], np.ones(3)))


def test_a_rigidly_moved_body_shares_the_factorisation_and_solves_the_same(monkeypatch, rng):
    """Body.transformed of a factorised body turns its compliance (X' = Q X Qᵀ) instead of factorising again:
    contact forces and fields equal a fresh factorisation of the moved mesh, and X' inverts the moved K on
    balanced loads."""
    from fem_grasp.grasp.pose import rotation_between

    body = Body(perturbed_box(np.random.default_rng(11), divisions=(4, 3, 3)), 3e4, 0.35, weight=1.5)
    body.compliance
    calls = []
    factorize = ss.factorize
    monkeypatch.setattr(cp, "factorize", lambda *a, **k: calls.append(1) or factorize(*a, **k))
    rot = rotation_between(np.array([0.3, -0.5, 0.8]), np.array([0.0, 0.0, -1.0]))
    moved = body.transformed(rot, np.array([0.1, -0.2, 0.05]))
    twice = moved.transformed(rot.T)  # a rotation of a rotated compliance composes
    nodes, disp = np.array([0, 17, 33, 47]), 1e-3 * rng.standard_normal((4, 3))
    for turned, total in ((moved, rot), (twice, np.eye(3))):
        fresh = Body(turned.mesh, body.young, body.poisson, weight=1.5)
        got, want = ContactResponse(turned, nodes).solve(disp), ContactResponse(fresh, nodes).solve(disp)
        assert calls == [1] * (1 + (turned is twice))  # only the fresh bodies were factorised
        np.testing.assert_allclose(got.forces, want.forces, rtol=0, atol=1e-12 * np.abs(want.forces).max())
        np.testing.assert_allclose(got.displacements, want.displacements, rtol=0,
                                   atol=1e-12 * np.abs(want.displacements).max())
        np.testing.assert_allclose(ContactResponse(turned, nodes).surface_displacements(disp),
                                   got.displacements[turned.mesh.surface_nodes], rtol=0,
                                   atol=1e-12 * np.abs(want.displacements).max())
        load = rng.standard_normal(3 * body.n_nodes)
        modes = turned.orthonormal_rigid_modes
        load -= modes @ (modes.T @ load)
        np.testing.assert_allclose(turned.stiffness @ turned.compliance.apply(load), load, rtol=0,
                                   atol=1e-10 * np.abs(load).max())
        np.testing.assert_allclose(turned.compliance._rotation, total, atol=1e-15)
    # Kept rows (large bodies): the columns are turned on the kept rows only, and equal the full ones there.
    surface = body.mesh.surface_nodes
    kept = cp.Compliance(body.stiffness, body.mesh.points, body.rigid_modes, rows=surface, surface=surface)
    turned_kept = kept.rotated(rot)
    full = moved.compliance.node_columns(nodes)
    dofs = (3 * surface[:, None] + np.arange(3)).ravel()
    np.testing.assert_allclose(turned_kept.node_columns(nodes), full[dofs], rtol=0, atol=1e-12 * np.abs(full).max())
    with pytest.raises(ValueError, match="orthogonal"):
        body.compliance.rotated(2.0 * np.eye(3))


@pytest.mark.parametrize("binding", ["ctypes", "scikit-sparse"])
def test_factors_held_in_reference_cycles_are_freed_without_a_crash(tmp_path, binding):
    """scikit-sparse's Factor crashes the process if the garbage collector clears it before its Common: a
    factor reached twice from cyclic garbage (a moved body's compliance shares it) did so, at a collection
    or at exit.  The module's registry keeps factors out of the garbage; bodies in cycles die cleanly, as
    they do with the ctypes binding's factors (each freed with its own Common)."""
    import subprocess
    import sys

    from fem_grasp.elastic import cholmod

    if binding == "ctypes" and cholmod.library() is None:
        pytest.skip("no CHOLMOD library of a supported version loads")
    if binding == "scikit-sparse":
        pytest.importorskip("sksparse.cholmod", reason="scikit-sparse is not installed")
    script = tmp_path / "cycles.py"
    script.write_text(
        "import copy, gc\n"
        + ("import fem_grasp.elastic.cholmod as c\nc._LIBRARY_TRIED, c._LIBRARY = True, None\n"
           if binding == "scikit-sparse" else "")
        + "from fem_grasp.elastic.cholmod import CholmodFactor\n"
        "from fem_grasp import Body, box_mesh\n"
        "for i in range(20):\n"
        "    b = Body(box_mesh((0, 0, 0), (0.04, 0.03, 0.02), (4, 3, 3)), 5e4, 0.3, weight=1.0)\n"
        "    holder = {'body': b, 'solve': b.compliance._solve, 'copy': copy.copy(b.compliance)}\n"
        "    holder['self'] = holder\n"
        "    if i % 5 == 4:\n"
        "        gc.collect()\n"
        "from fem_grasp.elastic import sparse_solvers\n"
        "gc.collect()\n"
        "print(type(b.compliance._solve.factor) is CholmodFactor, len(sparse_solvers._LIVE_FACTORS))\n")
    env = {**__import__("os").environ, "FEM_GRASP_SOLVER": "cholmod"}
    run = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=120, env=env)
    assert run.returncode == 0, (run.returncode, run.stderr[-2000:])
    direct, registered = run.stdout.split()[-2:]
    assert direct == str(binding == "ctypes")
    assert int(registered) <= 1  # the collected bodies' factors left the registry


def _ahead_compliance(body):
    comp = cp.Compliance(body.stiffness, body.mesh.points, body.rigid_modes, solver="cholmod")
    if not getattr(comp._solve, "releases_gil", False):
        pytest.skip("no CHOLMOD library whose solves release the GIL")
    return comp


@pytest.mark.skipif("cholmod" not in AVAILABLE, reason="CHOLMOD is not installed")
def test_columns_queued_ahead_are_taken_when_asked_for_with_the_round_off_of_their_batch(body):
    """solve_ahead queues the likeliest uncached nodes for the background thread (inside solving_ahead only);
    a queued node counts as cached, and its columns are those of a solve of the same batch, bit for bit, however
    far the thread has got when they are asked for."""
    comp = _ahead_compliance(body)
    likely = body.mesh.surface_nodes[::-1]
    comp.solve_ahead(likely, 12)
    assert not comp.is_cached(int(likely[0]))  # outside a section: nothing queued
    comp.node_columns(likely[:2])
    with comp.solving_ahead():
        comp.solve_ahead(likely, 12)
        queued = [int(k) for k in likely[2:2 + 2 * 12]]  # two batches of 12 (cp.AHEAD_BATCHES), the cached skipped
        assert cp.AHEAD_BATCHES == 2 and all(comp.is_cached(k) for k in queued)
        assert not comp.is_cached(int(likely[2 + 2 * 12]))
        got = comp.node_columns(queued[12:])  # the second batch, taken first
    assert not comp._ahead_on and all(batch.result.done() for batch in comp._ahead.values())
    alone = _ahead_compliance(body)
    alone.prefetch(queued[12:])  # the same batch in one solve
    np.testing.assert_array_equal(got, alone.node_columns(queued[12:]))
    np.testing.assert_allclose(comp.node_columns(queued[:12]), alone.node_columns(queued[:12]), rtol=0,
                               atol=1e-12 * np.abs(got).max())
    assert not comp._ahead  # every queued column taken into the cache


@pytest.mark.skipif("cholmod" not in AVAILABLE, reason="CHOLMOD is not installed")
def test_a_queued_batch_the_contacts_moved_away_from_is_dropped(body):
    """A batch none of whose nodes is among the likeliest uncached any more leaves the queue (its nodes are no
    longer counted as cached); a branch (a lift test's tracker) takes what was queued when it was made."""
    comp = _ahead_compliance(body)
    surface = body.mesh.surface_nodes
    with comp.solving_ahead():
        comp.solve_ahead(surface[:20], 10)
        twin = comp.branch()
        comp.solve_ahead(surface[-20:], 10)
    assert not any(comp.is_cached(int(k)) for k in surface[:20])
    assert all(comp.is_cached(int(k)) for k in surface[-20:])
    assert all(twin.is_cached(int(k)) for k in surface[:20])
    np.testing.assert_allclose(twin.node_columns(surface[:3]), comp.node_columns(surface[:3]), rtol=0,
                               atol=1e-12 * np.abs(comp.node_columns(surface[:3])).max())


@pytest.mark.skipif("cholmod" not in AVAILABLE, reason="CHOLMOD is not installed")
def test_leaving_the_section_waits_for_a_dropped_batch_still_being_solved(body):
    """A batch dropped while the background thread solves it cannot be cancelled; the section must still wait
    for it, or that solve would run on after the section gives BLAS its threads back."""
    comp = _ahead_compliance(body)
    surface = body.mesh.surface_nodes
    started, release = threading.Event(), threading.Event()
    solved = comp._solved_columns

    def held_solve(part):
        started.set()
        release.wait(10.0)
        return solved(part)

    comp._solved_columns = held_solve  # the batches queued below run this in the background thread
    timer = threading.Timer(0.3, release.set)
    with comp.solving_ahead():
        comp.solve_ahead(surface[:10], 10)
        first = next(iter(comp._ahead.values())).result
        assert started.wait(10.0)
        # the first batch is stale now, and running; too few nodes for a new batch (cp.AHEAD_MIN_NODES)
        comp.solve_ahead(surface[-5:], 10)
        assert not comp._ahead and not first.cancelled()
        timer.start()
    assert first.done() and release.is_set()  # the section waited for the held solve to be released
    timer.join()
