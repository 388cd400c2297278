import numpy as np
import pytest
import scipy.sparse.linalg as spla

from fem_grasp import Body, CollinearContactError, ContactResponse, TetMesh, solve_contact
from fem_grasp.elastic.response import add_symmetric_product, contact_dofs, norm1, principal_submatrix, symmetrize
from tests.helpers import perturbed_box


def contact_set(body):
    """Five well-spread surface nodes: three on the bottom, two on the sides."""
    p = body.mesh.points
    lo, hi = body.mesh.bounds
    target = np.array([lo, [hi[0], lo[1], lo[2]], [lo[0], hi[1], lo[2]],
                       [hi[0], (lo[1] + hi[1]) / 2, hi[2]], [(lo[0] + hi[0]) / 2, hi[1], hi[2]]])
    return np.array([int(np.argmin(np.sum((p - t) ** 2, axis=1))) for t in target])


def dirichlet_reference(body, nodes, disp):
    """The partitioned solve K_ff Δ_f = G_f − K_fc Δ̄, F̄ = (KΔ − G)_c (DESIGN.md)."""
    k = body.stiffness.tocsr()
    g = body.gravity_loads
    c = contact_dofs(nodes)
    f = np.setdiff1d(np.arange(k.shape[0]), c)
    u = np.zeros(k.shape[0])
    u[c] = disp.ravel()
    u[f] = spla.spsolve(k[f][:, f].tocsc(), g[f] - k[f][:, c] @ u[c])
    return (k @ u - g)[c].reshape(-1, 3), u.reshape(-1, 3)


@pytest.fixture(scope="module")
def body():
    return Body(perturbed_box(np.random.default_rng(7)), 8e4, 0.32, weight=0.9)


def rel(a, b):
    return np.abs(a - b).max() / np.abs(b).max()


def test_backends_agree_with_each_other_and_with_dirichlet_solve(body, rng):
    nodes = contact_set(body)
    disp = 1e-3 * rng.standard_normal((len(nodes), 3))
    sparse = solve_contact(body, nodes, disp)
    spectral = solve_contact(body, nodes, disp, backend="spectral")
    f_ref, u_ref = dirichlet_reference(body, nodes, disp)
    for sol in (sparse, spectral):
        assert rel(sol.forces, f_ref) <= 1e-9
        assert rel(sol.displacements, u_ref) <= 1e-9
        np.testing.assert_array_equal(sol.displacements[nodes], disp)
    assert rel(sparse.forces, spectral.forces) <= 1e-9
    np.testing.assert_allclose(sparse.strain_energy, spectral.strain_energy, rtol=1e-9)


@pytest.mark.parametrize("backend", ["sparse", "spectral"])
def test_equilibrium_to_round_off(body, rng, backend):
    nodes = contact_set(body)
    for scale in (0.0, 1e-3):
        sol = solve_contact(body, nodes, scale * rng.standard_normal((len(nodes), 3)), backend=backend)
        force, torque = sol.equilibrium_residual()
        assert force <= 1e-10 and torque <= 1e-10


def test_reduced_stiffness_properties(body):
    nodes = contact_set(body)
    resp = ContactResponse(body, nodes)
    c = resp.reduced_stiffness
    r = body.rigid_modes[contact_dofs(nodes)]
    assert np.abs(c - c.T).max() == 0.0
    # Rigid motions of the contacts cost nothing (Theorem 1 on the reduced system).
    assert np.abs(c @ r).max() <= 1e-10 * np.abs(c).max() * np.abs(r).max()
    ev = np.linalg.eigvalsh(c)
    assert ev.min() >= -1e-10 * ev.max()
    assert np.sum(ev < 1e-9 * ev.max()) == 6
    # Eq. (5): forces are affine, F̄ = C Δ̄ + F̄₀.
    d = np.random.default_rng(1).standard_normal((len(nodes), 3)) * 1e-3
    np.testing.assert_allclose(resp.forces(d).ravel(), c @ d.ravel() + resp.gravity_forces.ravel(),
                               rtol=0, atol=1e-10 * np.abs(resp.forces(d)).max())
    # Finite difference of the force map reproduces C column by column.
    h = 1e-6
    for j in (0, 4, 7):
        e = np.zeros(3 * len(nodes))
        e[j] = h
        fd = (resp.forces((d.ravel() + e).reshape(-1, 3)) - resp.forces((d.ravel() - e).reshape(-1, 3))) / (2 * h)
        np.testing.assert_allclose(fd.ravel(), c[:, j], rtol=1e-6, atol=1e-8 * np.abs(c).max())


def test_spectral_reduced_stiffness_matches_sparse(body):
    nodes = contact_set(body)
    a = ContactResponse(body, nodes).reduced_stiffness
    b = ContactResponse(body, nodes, backend="spectral").reduced_stiffness
    assert rel(b, a) <= 1e-9


def test_rigid_contact_motion_adds_rigid_field_and_no_force(body, rng):
    nodes = contact_set(body)
    resp = ContactResponse(body, nodes)
    base = resp.solve(np.zeros((len(nodes), 3)))
    rigid = body.rigid_modes @ (rng.standard_normal(6) * 1e-4)
    moved = resp.solve(rigid.reshape(-1, 3)[nodes])
    assert rel(moved.forces, base.forces) <= 1e-9
    assert rel(moved.displacements - base.displacements, rigid.reshape(-1, 3)) <= 1e-8
    np.testing.assert_allclose(moved.strain_energy, base.strain_energy, rtol=1e-9)


def test_clapeyron_energy_balance(body, rng):
    """For a linear body, 2U = Δᵀ(F + G): work of contact forces and gravity."""
    nodes = contact_set(body)
    disp = 1e-3 * rng.standard_normal((len(nodes), 3))
    sol = solve_contact(body, nodes, disp)
    work = np.sum(sol.forces * disp) + body.gravity_loads @ sol.displacements.ravel()
    np.testing.assert_allclose(2 * sol.strain_energy, work, rtol=1e-9)
    assert sol.strain_energy > 0


def test_scaling_with_young_modulus(body, rng):
    """Prescribed-displacement forces scale with E; held-contact gravity forces do not depend on E."""
    nodes = contact_set(body)
    disp = 1e-3 * rng.standard_normal((len(nodes), 3))
    for factor in (1e-3, 1e7):
        stiff = body.with_material(young=body.young * factor)
        r0, r1 = ContactResponse(body, nodes), ContactResponse(stiff, nodes)
        assert rel(r1.reduced_stiffness, factor * r0.reduced_stiffness) <= 1e-9
        assert rel(r1.gravity_forces, r0.gravity_forces) <= 1e-9
        assert rel(r1.solve(np.zeros_like(disp)).displacements, r0.solve(np.zeros_like(disp)).displacements / factor) <= 1e-9


def test_contact_response_is_reused_for_many_solves(body, rng):
    nodes = contact_set(body)
    resp = ContactResponse(body, nodes)
    d1, d2 = rng.standard_normal((2, len(nodes), 3)) * 1e-3
    sol = resp.solve(d1 + d2)
    lin = resp.forces(d1) + resp.forces(d2) - resp.gravity_forces
    assert rel(sol.forces, lin) <= 1e-9


def test_collinear_and_too_few_contacts_are_refused(body):
    p = body.mesh.points
    lo, hi = body.mesh.bounds
    edge = np.flatnonzero((np.abs(p[:, 1] - lo[1]) < 1e-12) & (np.abs(p[:, 2] - lo[2]) < 1e-12))
    assert len(edge) >= 3
    with pytest.raises(CollinearContactError, match="collinear"):
        solve_contact(body, edge, np.zeros((len(edge), 3)))
    with pytest.raises(CollinearContactError, match="at least three non-collinear"):
        solve_contact(body, edge[:2], np.zeros((2, 3)))
    with pytest.raises(ValueError, match="listed twice"):
        solve_contact(body, np.array([0, 1, 1, 5]), np.zeros((4, 3)))
    with pytest.raises(ValueError, match="is not a node of the mesh"):
        solve_contact(body, np.array([0, 1, 10**6]), np.zeros((3, 3)))
    with pytest.raises(ValueError, match="unknown backend"):
        ContactResponse(body, contact_set(body), backend="dense")
    with pytest.raises(ValueError, match="shape"):
        ContactResponse(body, contact_set(body)).solve(np.zeros((2, 3)))
    with pytest.raises(ValueError, match="NaN"):
        ContactResponse(body, contact_set(body)).solve(np.full((5, 3), np.nan))


def test_nearly_collinear_contacts_grow_the_condition_number():
    mesh = TetMesh(np.array([[0.0, 0, 0], [1, 0, 0], [0.5, 1, 0], [0.5, 0.5, 1], [0.5, 0.0, 0.0]]),
                   np.array([[0, 4, 2, 3], [4, 1, 2, 3]]))
    body = Body(mesh, 1e5, 0.3, weight=1.0)
    conds = []
    for off in (1e-1, 1e-3, 1e-5):
        pts = mesh.points.copy()
        pts[4, 1] = off  # node 4 approaches the line through nodes 0 and 1
        b = Body(TetMesh(pts, mesh.tets), 1e5, 0.3, weight=1.0)
        conds.append(ContactResponse(b, np.array([0, 1, 4])).condition_number())
    assert conds[0] < conds[1] < conds[2]
    with pytest.raises(CollinearContactError):
        ContactResponse(body, np.array([0, 1, 4]))  # exactly collinear


def test_numerically_collinear_contacts_are_refused_not_silently_wrong(caplog):
    """cond(M) grows as 1/θ²: logged above WARN_CONDITION, refused above MAX_CONDITION."""
    mesh = TetMesh(np.array([[0.0, 0, 0], [1, 0, 0], [0.5, 1, 0], [0.5, 0.5, 1], [0.5, 0.0, 0.0]]),
                   np.array([[0, 4, 2, 3], [4, 1, 2, 3]]))

    def response(off):
        pts = mesh.points.copy()
        pts[4, 1] = off  # node 4 approaches the line through nodes 0 and 1
        return ContactResponse(Body(TetMesh(pts, mesh.tets), 1e5, 0.3, weight=1.0), np.array([0, 1, 4]))

    conds = [response(off).condition_estimate for off in (1e-2, 1e-3, 1e-4)]
    np.testing.assert_allclose(np.diff(np.log10(conds)), 2.0, atol=0.1)
    assert "nearly collinear" not in caplog.text
    response(1e-5)
    assert "nearly collinear" in caplog.text
    with pytest.raises(CollinearContactError, match="numerically singular"):
        response(1e-6)


@pytest.mark.parametrize("backend", ["sparse", "spectral"])
def test_the_surface_field_is_the_whole_fields_surface_rows(body, rng, backend):
    """surface_displacements (what the tracking reads at every trial) equals the surface rows of solve()'s
    field, the prescribed contact values exactly, also with an interior node in the contact set."""
    surface = body.mesh.surface_nodes
    interior = np.setdiff1d(np.arange(body.n_nodes), surface)
    assert len(interior)
    nodes = np.concatenate([contact_set(body), interior[:1]])
    resp = ContactResponse(body, nodes, backend=backend)
    disp = 1e-3 * rng.standard_normal((len(nodes), 3))
    whole = resp.solve(disp).displacements
    part = resp.surface_displacements(disp)
    assert part.shape == (len(surface), 3)
    assert np.abs(part - whole[surface]).max() <= 1e-14 * np.abs(whole).max()
    on = np.isin(nodes, surface)
    np.testing.assert_array_equal(part[np.searchsorted(surface, nodes[on])], disp[on])


def test_tracked_states_compute_the_whole_field_only_when_asked(body):
    """A tracked state holds the deformed surface; ContactState.positions solves the whole field on first use
    and agrees with it on the surface."""
    from fem_grasp.contact.tracking import FINGER1, TABLE, Tracker

    tracker = Tracker(body, radius=0.01, mu_finger=0.5, mu_table=0.5, table=None)
    nodes = contact_set(body)
    owner = np.array([TABLE] * (len(nodes) - 1) + [FINGER1])
    state = tracker.make_state(phase="squeeze", squeeze_depth=0.0, lift_height=0.0, load=0.5,
                               centers=np.zeros((2, 3)), nodes=nodes, owner=owner,
                               disp=1e-4 * np.ones((len(nodes), 3)), sliding=np.zeros(len(nodes), bool))
    assert "positions" not in state.__dict__
    whole = state.positions
    assert whole.shape == (body.n_nodes, 3) and "positions" in state.__dict__
    # Two solves (the whole field, the surface rows): equal to round-off, not bit for bit.
    np.testing.assert_allclose(whole[body.mesh.surface_nodes], state.surface_positions, rtol=0,
                               atol=1e-14 * body.mesh.diameter)


def test_a_large_body_caches_surface_rows_and_solves_for_whole_fields(body, rng, monkeypatch):
    """Above FULL_COLUMNS_MAX_NODES vertices the compliance keeps only surface rows (one cache serves the
    surface fields) and a whole field costs a sparse solve: the same forces and fields as the full columns."""
    import fem_grasp.elastic.body as body_module

    monkeypatch.setattr(body_module, "FULL_COLUMNS_MAX_NODES", body.n_nodes - 1)
    lean = body.with_material()
    nodes = contact_set(body)
    disp = 1e-3 * rng.standard_normal((len(nodes), 3))
    a, b = solve_contact(lean, nodes, disp), solve_contact(body, nodes, disp)
    comp = lean.compliance
    assert np.array_equal(comp.kept_nodes, body.mesh.surface_nodes)
    assert comp.cache_bytes == comp.cached_nodes * (3 * len(comp.kept_nodes)) * 3 * 8  # no second copy
    assert rel(a.forces, b.forces) <= 1e-12 and rel(a.displacements, b.displacements) <= 1e-12
    surface = ContactResponse(lean, nodes).surface_displacements(disp)
    assert rel(surface, a.displacements[body.mesh.surface_nodes]) <= 1e-12


#: A response derived from a neighbouring set's M⁻¹ (ContactResponse.neighbour) agrees with a fresh one to this
#: fraction of the largest entry: each update adds round-off of order cond(M) ε (cond ~1e3 here), and the
#: backward-error guard keeps a chain of them there (200 updates on the tomato stayed below 3e-14).
NEIGHBOUR_AGREEMENT = 1e-11


def test_a_neighbouring_sets_response_is_the_fresh_one_to_round_off(body, rng):
    """A chain of 40 derived responses (nodes joining, leaving, both, reordered), each against a fresh one."""
    surface = body.mesh.surface_nodes
    nodes = contact_set(body)
    current = ContactResponse(body, nodes)
    derived = 0
    for step in range(40):
        change = list(nodes)
        if step % 4 == 1 and len(change) > 5:
            change.pop(int(rng.integers(len(change))))
        elif step % 4 == 2:
            change = change[::-1]
        else:
            for k in rng.choice(surface, 2, replace=False):
                if int(k) not in change:
                    change.append(int(k))
            if step % 4 == 3:
                change.pop(0)
        try:
            fresh = ContactResponse(body, np.array(change))
        except CollinearContactError:
            continue
        nodes = np.array(change)
        new = current.neighbour(nodes)
        assert new is not None, f"step {step}: a set {len(change)} nodes from its neighbour was not derived"
        derived += 1
        np.testing.assert_array_equal(new.nodes, nodes)
        assert rel(new.reduced_stiffness, fresh.reduced_stiffness) <= NEIGHBOUR_AGREEMENT
        assert np.array_equal(new.reduced_stiffness, new.reduced_stiffness.T)  # C symmetric, exactly
        assert rel(new.gravity_forces, fresh.gravity_forces) <= NEIGHBOUR_AGREEMENT
        d = rng.standard_normal((len(nodes), 3)) * 1e-3
        assert rel(new.forces(d), fresh.forces(d)) <= NEIGHBOUR_AGREEMENT
        assert rel(new.surface_displacements(d), fresh.surface_displacements(d)) <= NEIGHBOUR_AGREEMENT
        current = new
    assert derived >= 35
    # The derived response is a contact response in its own right: equilibrium to round-off, the six rigid
    # motions of the contacts in C's null space.
    sol = current.solve(rng.standard_normal((len(nodes), 3)) * 1e-3)
    assert max(sol.equilibrium_residual()) <= 1e-10
    c, r = current.reduced_stiffness, body.rigid_modes[contact_dofs(nodes)]
    assert np.abs(c @ r).max() <= 1e-10 * np.abs(c).max() * np.abs(r).max()


def test_a_neighbour_is_refused_where_it_would_not_pay_or_is_not_a_contact_set(body, monkeypatch):
    from fem_grasp.elastic import response

    nodes = contact_set(body)
    resp = ContactResponse(body, nodes)
    others = [int(k) for k in body.mesh.surface_nodes if int(k) not in set(nodes.tolist())]
    far = np.concatenate([nodes, others[:response.NEIGHBOUR_NODES + 1]])
    assert resp.neighbour(far) is None  # more nodes changed than updates pay for
    assert resp.neighbour(np.concatenate([nodes, others[:1]])) is not None
    with pytest.raises(CollinearContactError):
        resp.neighbour(nodes[:2])  # refused as the constructor refuses it
    assert ContactResponse(body, nodes, backend="spectral").neighbour(nodes[:4]) is None
    # with no cached set to derive from (EngineSettings.neighbour_updates=False), a set is factorised afresh
    fresh = response.contact_response(body, nodes[:4], cached=())
    assert fresh._lu is not None and resp.neighbour(nodes[:4])._lu is None


def test_a_large_set_is_derived_across_a_share_of_its_nodes(rng):
    """An implicit increment on a fine patch changes tens of nodes at once: a set of m nodes is derived across up to
    neighbour_limit(m) = max(6, m/8) of them (here 12 of 96), and agrees with a fresh one; one more is refused."""
    from fem_grasp.elastic import response

    big = Body(perturbed_box(np.random.default_rng(5), divisions=(5, 5, 5)), 8e4, 0.32, weight=0.9)
    surface = [int(k) for k in big.mesh.surface_nodes]
    nodes = np.array(surface[:96])
    assert response.neighbour_limit(100) == 12 > response.NEIGHBOUR_NODES
    resp = ContactResponse(big, nodes)
    changed = np.concatenate([nodes[5:], surface[96:96 + 8]])  # 5 leave, 8 join: 13 differ, sets of 96 and 99
    assert resp.neighbour(changed) is None
    within = np.concatenate([nodes[4:], surface[96:96 + 8]])  # 4 leave, 8 join: 12
    derived = resp.neighbour(within)
    assert derived is not None
    fresh = ContactResponse(big, within)
    assert rel(derived.reduced_stiffness, fresh.reduced_stiffness) <= NEIGHBOUR_AGREEMENT
    d = 1e-3 * rng.standard_normal((len(within), 3))
    assert rel(derived.forces(d), fresh.forces(d)) <= NEIGHBOUR_AGREEMENT


@pytest.mark.parametrize("rows", [[0, 1, 2, 3], [3, 4, 0, 1, 2], [-1, 0, 1, -1, 4, 5, 2], [5, -1, -1, 6], [2]])
def test_principal_submatrix_is_fancy_indexing_with_zero_placeholders(rows, rng):
    a = rng.standard_normal((7, 7))
    rows = np.array(rows)
    got = principal_submatrix(a, rows)
    ok = rows >= 0
    assert np.array_equal(got[np.ix_(ok, ok)], a[np.ix_(rows[ok], rows[ok])])
    assert not got[~ok].any() and not got[:, ~ok].any()


@pytest.mark.parametrize("n", [1, 5, 127, 128, 129, 300])
def test_the_in_place_dense_updates_are_their_formulas(n):
    """What a derived response does to M⁻¹ in place, block by block: a symmetric rank-k update u w uᵀ (one dgemm
    on the transpose), the symmetric part (the same numbers as (a + aᵀ)/2, exactly symmetric) and ‖a‖₁, at sizes
    below, at and across the block."""
    rng = np.random.default_rng(n)
    a = rng.standard_normal((n, n))
    u = rng.standard_normal((n, 7))
    w = rng.standard_normal((7, 7))
    w = w + w.T
    updated = a.copy()
    add_symmetric_product(updated, u, w)
    expected = a + u @ w @ u.T
    assert np.abs(updated - expected).max() <= 1e-13 * np.abs(expected).max()
    sym = a.copy()
    symmetrize(sym)
    assert np.array_equal(sym, 0.5 * (a + a.T)) and np.array_equal(sym, sym.T)
    assert norm1(a) == pytest.approx(np.abs(a).sum(axis=0).max(), rel=1e-14)
    assert norm1(a) == pytest.approx(np.linalg.norm(a, 1), rel=1e-14)
    strided = np.asfortranarray(a)  # not C-ordered: updated all the same
    add_symmetric_product(strided, u, w)
    assert np.abs(strided - expected).max() <= 1e-13 * np.abs(expected).max()


def test_two_threads_solving_with_one_factorisation_get_the_same_forces(tmp_path):
    """A response and its branch share M's LU factors, and two lift tests solve with them at once.  scipy's LAPACK
    wrappers turn the pivots 1-based in place with the GIL released, so two threads on one pivot array shifted them
    twice: row swaps past the matrix's end, wrong forces, and a corrupted heap (glibc aborts the process within a
    second here).  Run in a process of its own: the forces of 3,000 solves per thread equal a sequential solve's."""
    import subprocess
    import sys
    from pathlib import Path

    script = tmp_path / "race.py"
    script.write_text(
        "import sys, threading\n"
        f"sys.path.insert(0, {str(Path(__file__).resolve().parents[2])!r})\n"
        "import numpy as np\n"
        "from fem_grasp import Body, ContactResponse\n"
        "from tests.helpers import perturbed_box\n"
        "body = Body(perturbed_box(np.random.default_rng(7), divisions=(8, 8, 8)), 8e4, 0.32, weight=0.9)\n"
        "p, (lo, hi) = body.mesh.points, body.mesh.bounds\n"
        "nodes = np.union1d(np.flatnonzero(p[:, 2] <= lo[2] + 1e-9), np.flatnonzero(p[:, 0] >= hi[0] - 1e-9)[:20])\n"
        "resp = ContactResponse(body, nodes)\n"
        "twin = resp.branch(body.branch())\n"
        "rng = np.random.default_rng(1)\n"
        "disp = [1e-4 * rng.standard_normal((len(nodes), 3)) for _ in range(4)]\n"
        "ref = [resp.forces(d) for d in disp]\n"
        "worst = [0.0, 0.0]\n"
        "def work(k, r):\n"
        "    for i in range(3000):\n"
        "        f = r.forces(disp[i % 4])\n"
        "        worst[k] = max(worst[k], float(np.abs(f - ref[i % 4]).max() / np.abs(ref[i % 4]).max()))\n"
        "threads = [threading.Thread(target=work, args=(k, r)) for k, r in enumerate((resp, twin))]\n"
        "[t.start() for t in threads]\n"
        "[t.join() for t in threads]\n"
        "print(len(nodes), max(worst))\n")
    run = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, (run.returncode, run.stderr[-2000:])
    contacts, worst = run.stdout.split()[-2:]
    assert int(contacts) > 50 and float(worst) <= 1e-12
