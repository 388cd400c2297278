"""Algorithm 1 end to end: squeeze, lift test and lift (paper §III-B, §III-C).

The scenarios use a 3×4×3 cm box on a 3×3×3 grid (64 nodes) squeezed by 2 cm
fingertips at the centres of its y-faces: small enough for a full pickup in a
few seconds, with every kind of event.  Every scenario's result is checked
(:meth:`PickupResult.check`), failures included.
"""

import json
import os

import numpy as np
import pytest

from fem_grasp import Body, box_mesh
from fem_grasp.contact.tracking import FINGER1, TABLE, MixedSlipSystem, SlipFailure, Tracker
from fem_grasp.errors import ContactNodeError, DirectionError, PlacementError, SceneError
from fem_grasp.grasp.lift_test import hang, hanging_state
from fem_grasp.grasp.pickup import PickupResult, pickup
from fem_grasp.grasp.rest import rest
from tests.helpers import RADIUS, WEIGHT, assert_same_pickup, face_centres, pick_up_box, pickup_box


@pytest.fixture(scope="module")
def lifted() -> PickupResult:
    return pick_up_box(0.5)


@pytest.fixture(scope="module")
def lifted_spectral() -> PickupResult:
    return pick_up_box(0.5, backend="spectral")


# ------------------------------------------------------------ the success
def test_box_is_picked_up_and_every_snapshot_obeys_the_contact_laws(lifted):
    assert lifted.success, lifted.reason
    figures = lifted.check()  # raises on any violation
    assert len(figures) == len(lifted.snapshots) >= 10
    assert max(f["force_residual"] for f in figures) < 1e-9
    assert max(f["torque_residual"] for f in figures) < 1e-9
    # Lift-off: no table contact left, the fingers carry the weight.
    final = lifted.final
    assert final.label == "lift-off" and len(final.contact_nodes["table"]) == 0
    np.testing.assert_allclose(final.all_forces.sum(axis=0), [0, 0, WEIGHT], atol=1e-9 * WEIGHT)
    assert lifted.finger_normal_force > 0 and lifted.n_final_contacts >= 3


def test_every_event_type_occurs_and_events_are_ordered(lifted):
    counts = lifted.event_counts()
    assert all(counts[k] > 0 for k in "ABCD"), counts
    squeeze = [e for e in lifted.events if e.phase == "squeeze"]
    lift = [e for e in lifted.events if e.phase == "lift"]
    assert squeeze and lift and lifted.events == squeeze + lift
    assert np.all(np.diff([e.squeeze_depth for e in squeeze]) >= 0)
    assert np.all(np.diff([e.lift_height for e in lift]) >= 0)
    assert all(e.lift_height == 0 for e in squeeze)
    assert all(e.squeeze_depth == pytest.approx(lifted.squeeze_depth) for e in lift)
    # Table contacts break during the lift (event B), fingers establish contacts during the squeeze (A).
    assert any(e.kind == "B" and e.contact == "table" for e in lift)
    assert any(e.kind == "A" and e.contact.startswith("finger") for e in squeeze)


def test_liftable_weight_reaches_the_weight_when_the_lift_starts(lifted):
    rho, w = np.array(lifted.liftable).T
    assert np.all(np.diff(rho) > 0)
    assert w[-1] >= WEIGHT and np.all(w[:-1] < WEIGHT)
    assert rho[-1] == pytest.approx(lifted.squeeze_depth)
    # The tests use steps h = mg/20 from the previous value (§III-B).
    np.testing.assert_allclose(w / (WEIGHT / 20), np.round(w / (WEIGHT / 20)), atol=1e-9)


def test_snapshots_report_the_scene(lifted):
    n = lifted.body.n_nodes
    for s in lifted.snapshots:
        assert s.positions.shape == (n, 3) and s.finger_centers.shape == (2, 3)
        assert s.finger_radius == RADIUS
        assert set(s.contact_nodes) == {"finger1", "finger2", "table"}
        for k in s.contact_nodes:
            assert s.contact_forces[k].shape == (len(s.contact_nodes[k]), 3)
            assert s.sliding[k].shape == (len(s.contact_nodes[k]),)
    # Finger 1 moved by ρ d̂1 during the squeeze and by the lift height upward.
    first, last = lifted.snapshots[0], lifted.final
    d1 = lifted.directions[0]
    expected = first.finger_centers[0] + lifted.squeeze_depth * d1 + [0, 0, last.lift_height]
    np.testing.assert_allclose(last.finger_centers[0], expected, atol=1e-12)
    assert set(lifted.timings) >= {"rest", "closure", "squeeze", "lift_test", "lift", "total"}


def test_result_to_json(lifted, tmp_path):
    path = tmp_path / "pickup.json"
    text = lifted.to_json(path)
    data = json.loads(path.read_text())
    assert data == json.loads(text)
    assert data["success"] is True and len(data["snapshots"]) == len(lifted.snapshots)
    assert data["final"]["contact_nodes"]["table"] == []
    assert data["event_counts"] == lifted.event_counts()
    assert np.asarray(data["snapshots"][0]["positions"]).shape == (lifted.body.n_nodes, 3)


def test_the_same_scene_gives_the_same_json_but_for_wall_times(lifted):
    again = pick_up_box(0.5)

    def without_times(res):
        data = json.loads(res.to_json())
        data.pop("timings")
        return json.dumps(data, sort_keys=True)

    assert without_times(again) == without_times(lifted)  # bit-identical numbers, events and snapshots


def test_snapshots_solve_the_whole_field_only_when_read_and_pickle_with_it():
    """A snapshot holds the deformed surface; its whole field is solved on first read (outputs), equal on the
    surface to what it holds, and a pickled snapshot carries the field instead of the tracker's closure."""
    import pickle

    res = pick_up_box(0.5)
    assert res.check()
    fresh = [s for s in res.snapshots if "positions" not in s.__dict__]
    assert len(fresh) == len(res.snapshots)  # the pickup and its checks never needed a whole field
    snap = res.snapshots[len(res.snapshots) // 2]
    whole = fresh[0].positions
    # The whole field and the surface rows are two solves: equal to round-off, not bit for bit.
    tol = 1e-14 * res.body.mesh.diameter
    np.testing.assert_allclose(whole[fresh[0].surface_nodes], fresh[0].surface_positions, rtol=0, atol=tol)
    k = fresh[0].all_nodes
    np.testing.assert_allclose(fresh[0].node_positions(k), whole[k], rtol=0, atol=tol)
    again = pickle.loads(pickle.dumps(snap))
    assert again.position_source is None
    np.testing.assert_array_equal(again.positions, snap.positions)


def test_rigid_comparison_is_reported(lifted):
    # Table III: the rigid body with the same shape and contacts, two frictional point contacts.
    assert lifted.rigid.feasible
    assert lifted.rigid.total_normal_force == pytest.approx(WEIGHT / 0.5, rel=0.05)  # flat faces: mg/μ


def test_sparse_and_spectral_backends_agree_on_a_full_pickup(lifted, lifted_spectral):
    a, b = lifted, lifted_spectral
    assert b.success and b.check()
    assert_same_pickup(a, b)


def test_implicit_increments_alone_pick_up_the_box_at_the_same_depth(lifted, monkeypatch):
    """With the slip systems of eqs. (6)–(8) switched off, every slip goes through the return mapping
    (Tracker.implicit_step); that independent path must agree with the event tracking."""

    def no_rate_solution(self, *args, **kwargs):
        if len(self.sliding):
            raise SlipFailure("switched off by the test")
        return np.zeros(0)

    calls = []
    original = Tracker.implicit_step
    monkeypatch.setattr(MixedSlipSystem, "solve", no_rate_solution)
    monkeypatch.setattr(Tracker, "implicit_step", lambda self, *a, **k: calls.append(1) or original(self, *a, **k))
    res = pick_up_box(0.5)
    assert res.success, res.reason
    res.check()
    assert len(calls) > 20  # the squeeze really went through implicit increments
    # The implicit path locates events only to an increment: the depths agree to two increments.
    assert abs(res.squeeze_depth - lifted.squeeze_depth) <= 2 * lifted.step
    assert res.finger_normal_force == pytest.approx(lifted.finger_normal_force, rel=0.1)


def test_large_contact_sets_go_by_implicit_increments_to_the_same_depth(lifted, monkeypatch):
    """Above EngineSettings.implicit_contacts contacts every increment is a return mapping; with the threshold at 0
    the whole box pickup goes that way and must agree with the event tracking."""
    from fem_grasp.settings import EngineSettings

    calls = []
    original = Tracker.implicit_step
    monkeypatch.setattr(Tracker, "implicit_step", lambda self, *a, **k: calls.append(1) or original(self, *a, **k))
    res = pick_up_box(0.5, settings=EngineSettings(implicit_contacts=0))
    assert res.success, res.reason
    res.check()
    assert len(calls) >= lifted.squeeze_depth / lifted.step - 1  # every squeeze increment
    assert abs(res.squeeze_depth - lifted.squeeze_depth) <= 2 * lifted.step
    assert res.finger_normal_force == pytest.approx(lifted.finger_normal_force, rel=0.1)


# ------------------------------------------- a zero-force touch released by round-off
def test_a_squeeze_that_starts_with_a_finger_off_the_object_re_establishes_contact_by_event_a(lifted):
    """A fingertip placed tangent carries no force; round-off may release it in the first settle (seen on an
    Intel CPU).  The squeeze must then bring that finger back into contact (event A) and reach the same
    lift-off as when the touch is kept, within an increment."""
    from fem_grasp.grasp.lift_test import LiftTest
    from fem_grasp.grasp.placement import PAPER_SQUEEZE_DIRECTIONS
    from fem_grasp.grasp.squeeze import initial_state, squeeze

    rs = rest(pickup_box(), 0.5)
    tracker = Tracker(rs.body, radius=RADIUS, mu_finger=0.5, mu_table=0.5, table=rs.table)
    hanging = Tracker(rs.body, radius=RADIUS, mu_finger=0.5, mu_table=0.5, table=None)
    vel = np.stack(PAPER_SQUEEZE_DIRECTIONS)
    placed = initial_state(tracker, rs, face_centres(rs))
    keep = placed.owner != FINGER1  # finger 1's touch released
    released = tracker.make_state(phase="squeeze", squeeze_depth=0.0, lift_height=0.0, load=1.0,
                                  centers=placed.centers, nodes=placed.nodes[keep], owner=placed.owner[keep],
                                  disp=placed.disp[keep], sliding=placed.sliding[keep])
    state, _ = tracker.settle(released, vel, phase="squeeze")
    assert not state.on(FINGER1).any()
    out = squeeze(tracker, state, PAPER_SQUEEZE_DIRECTIONS, 1.0, LiftTest(hanging, WEIGHT), max_squeeze=lifted.max_squeeze,
                  step=lifted.step)
    assert out.passed, out.reason
    first = next(e for e in out.events if e.contact == "finger1")
    assert first.kind == "A" and first.node == face_centres(rs)[0] and first.squeeze_depth < 1e-9 * rs.body.mesh.diameter
    assert abs(out.state.squeeze_depth - lifted.squeeze_depth) <= lifted.step


def test_the_squeeze_increment_comes_from_the_placement_not_from_what_the_first_settle_kept(lifted):
    """The default increment (1/20 of mg / (μ k₀)) reads k₀ at finger 1's placement node: it must exist even
    if the first settle released that touch (it was an IndexError), and give the pickup's own increment."""
    from fem_grasp.grasp.pickup import _initial_stiffness
    from fem_grasp.grasp.placement import PAPER_SQUEEZE_DIRECTIONS
    from fem_grasp.grasp.squeeze import initial_state

    rs = rest(pickup_box(), 0.5)
    tracker = Tracker(rs.body, radius=RADIUS, mu_finger=0.5, mu_table=0.5, table=rs.table)
    vel = np.stack(PAPER_SQUEEZE_DIRECTIONS)
    vel /= np.linalg.norm(vel, axis=1, keepdims=True)  # pickup() moves the fingers along unit directions
    k0 = _initial_stiffness(tracker, initial_state(tracker, rs, face_centres(rs)), vel)
    assert k0 > 0
    rho_star = WEIGHT / (0.5 * k0)
    expected = min(0.02 * lifted.max_squeeze, max(rho_star / 20.0, 1e-3 * lifted.max_squeeze))
    assert lifted.step == pytest.approx(expected, rel=1e-12)


@pytest.mark.slow  # a pickup test rerun under OpenBLAS's oldest kernels: over 10 minutes without numba
def test_the_implicit_path_under_another_cpus_blas_kernels_picks_up_the_box(tmp_path):
    """Regression of the crash seen on an Intel Xeon: with OpenBLAS's SSE3 (Prescott) kernels, round-off
    releases finger 1's zero-force touch in the first settle of the implicit-only pickup; it used to die
    with an IndexError, and must now pick the box up at the same depth."""
    import subprocess
    import sys
    from pathlib import Path

    env = dict(os.environ, OPENBLAS_CORETYPE="Prescott", OPENBLAS_L2_SIZE=str(512 * 1024))
    test = "tests/grasp/test_pickup.py::test_implicit_increments_alone_pick_up_the_box_at_the_same_depth"
    out = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", test],
                         cwd=Path(__file__).resolve().parents[2], env=env, capture_output=True, text=True)
    assert out.returncode == 0, out.stdout[-3000:]


# ------------------------------------------------------------- the failures
def test_too_little_friction_fails_by_slip_on_a_finger():
    res = pick_up_box(0.2)
    assert not res.success
    assert "slides" in res.reason
    res.check()
    assert len(res.snapshots) > 1


def test_bad_placement_fails_by_force_closure():
    res = pick_up_box(0.5, mu_table=0.0)  # a frictionless table cannot twist the box about the finger axis
    assert not res.success and "force closure" in res.reason
    assert res.closure is not None and not res.closure.closed
    assert res.snapshots == [] and res.events == []
    res.check()
    # Both fingers on the same face: not force closure either.
    body = pickup_box()
    rs = rest(body, 0.5)
    i, _ = face_centres(rs)
    p = rs.body.mesh.points
    same = int(np.argmin(np.linalg.norm(p - (p[i] + [0.01, 0, 0]), axis=1)))
    # Both fingers on one face: finger 2's squeeze would pull it off the surface, refused before step 1.
    with pytest.raises(PlacementError, match="points out of the object"):
        pickup(body, mu_finger=0.5, contacts=(i, same), rest_state=rs, finger_radius=0.002)


def test_pickup_refuses_a_bad_scene_with_a_named_error():
    body = pickup_box()
    rs = rest(body, 0.5)
    interior = int(np.setdiff1d(np.arange(body.n_nodes), rs.body.mesh.surface_nodes)[0])
    with pytest.raises(DirectionError, match="upward"):
        pickup(body, directions=([0, 1, 0.2], [0, -1, 0]), rest_state=rs)
    with pytest.raises(ContactNodeError, match="interior"):
        pickup(body, contacts=(interior, 0), rest_state=rs)
    with pytest.raises(ContactNodeError, match="not a node"):
        pickup(body, contacts=(10_000, 0), rest_state=rs)
    with pytest.raises(SceneError, match="radius"):
        pickup(body, finger_radius=-1.0, rest_state=rs)
    with pytest.raises(SceneError, match="mu_finger"):
        pickup(body, mu_finger=-0.1, rest_state=rs)


def test_squeeze_depth_limit_is_a_failure():
    res = pick_up_box(0.5, max_squeeze=0.002)
    assert not res.success and "maximum squeeze depth" in res.reason
    assert "ρ = 2 mm" in res.reason and " m " not in res.reason  # one length unit, mm, in failure reasons
    assert res.squeeze_depth == pytest.approx(0.002)
    res.check()


def test_tracking_messages_give_the_depth_in_millimetres():
    from types import SimpleNamespace

    from fem_grasp.contact.tracking import Parameter, _where

    st = SimpleNamespace(squeeze_depth=0.0123456, lift_height=0.0032, load=0.5)
    assert _where(Parameter.SQUEEZE_DEPTH, st) == "ρ = 12.3456 mm"
    assert _where(Parameter.LIFT_HEIGHT, st) == "lift height 3.2 mm"
    assert _where(Parameter.LOAD, st) == "gravity load λ = 0.5"


def test_a_failed_lift_sends_the_squeeze_on_and_the_next_lift_starts_deeper(monkeypatch, lifted):
    """Algorithm 1 step 6: a simulated lift that fails is followed by more squeeze and another lift."""
    import fem_grasp.grasp.lift as lift_module
    pickup_module = __import__("sys").modules["fem_grasp.grasp.pickup"]
    real = lift_module.lift
    calls = []

    def first_lift_slips(tracker, state, **kw):
        calls.append(state.squeeze_depth)
        out = real(tracker, state, **{**kw, "max_height": 1e-4}) if len(calls) == 1 else real(tracker, state, **kw)
        if len(calls) == 1:  # stop the first lift early and call it a slip
            out.success, out.reason = False, "every contact of finger 1 slides (simulated)"
        return out

    monkeypatch.setattr(pickup_module, "run_lift", first_lift_slips)
    res = pick_up_box(0.5)
    assert res.success, res.reason
    assert [a.success for a in res.lift_attempts] == [False, True]
    first, second = res.lift_attempts
    assert first.squeeze_depth == pytest.approx(lifted.squeeze_depth, rel=1e-9)
    assert second.squeeze_depth >= first.squeeze_depth + 0.99 * res.step  # at least one more increment
    assert calls == [first.squeeze_depth, second.squeeze_depth]
    labels = [s.label for s in res.snapshots]
    assert "lift failed (attempt 1)" in labels and "lift start (attempt 2)" in labels
    # The squeeze resumed from the lift-start state: squeeze events after the failed lift lie beyond it.
    k = labels.index("lift failed (attempt 1)")
    later = [s for s in res.snapshots[k + 1:] if s.phase == "squeeze"]
    assert later and all(s.squeeze_depth >= first.squeeze_depth - 1e-12 and s.lift_height == 0 for s in later)
    assert [w for r, w in res.liftable if r > first.squeeze_depth]  # the lift test ran again
    res.check()
    assert json.loads(res.to_json())["lift_attempts"][0]["success"] is False

    calls.clear()
    once = pick_up_box(0.5, max_lift_attempts=1)
    assert not once.success and "simulated" in once.reason and len(once.lift_attempts) == 1
    once.check()
    with pytest.raises(ValueError, match="max_lift_attempts"):
        pick_up_box(0.5, max_lift_attempts=0)


# --------------------------------------------------------- the lift test
def test_lift_test_holds_light_weights_and_not_heavy_ones(lifted):
    body = lifted.body
    tracker = Tracker(body, radius=RADIUS, mu_finger=0.5, mu_table=0.5, table=None)
    squeeze = Tracker(body, radius=RADIUS, mu_finger=0.5, mu_table=0.5, table=lifted.table)
    s = next(s for s in lifted.snapshots if s.label == "lift start")  # the state when the lift starts
    nodes, owner, disp = [], [], []
    for code, name in enumerate(("finger1", "finger2", "table")):
        nodes += list(s.contact_nodes[name])
        owner += [code] * len(s.contact_nodes[name])
        disp += list(s.positions[s.contact_nodes[name]] - body.mesh.points[s.contact_nodes[name]])
    sliding = np.concatenate([s.sliding[k] for k in ("finger1", "finger2", "table")])
    state = squeeze.make_state(phase="squeeze", squeeze_depth=s.squeeze_depth, lift_height=0.0, load=1.0,
                               centers=s.finger_centers, nodes=np.array(nodes), owner=np.array(owner),
                               disp=np.array(disp), sliding=sliding)
    state = squeeze.settle(state, np.zeros((2, 3)), phase="squeeze")[0]
    base = hanging_state(tracker, state)
    assert base.held and not (base.state.owner == TABLE).any()
    np.testing.assert_allclose(base.state.forces.sum(axis=0), 0, atol=1e-12)  # no weight yet
    light = hang(tracker, base.state, WEIGHT)
    assert light.held
    np.testing.assert_allclose(light.state.forces.sum(axis=0), [0, 0, WEIGHT], atol=1e-10)
    heavy = hang(tracker, base.state, 100 * WEIGHT)
    assert not heavy.held and heavy.reason


# ------------------------------------------------------- slip system units


# ------------------------------------------------------------ a paper object
def test_the_football_scene_is_picked_up_and_every_snapshot_obeys_the_contact_laws():
    """The shipped football scene (graded mesh, 10 kPa) end to end: the quickest of the four paper pickups."""
    from fem_grasp.io.scene import load_scene, resolve_scene

    scene = load_scene(resolve_scene("football"))
    res = pickup(scene.body(), **scene.pickup_kwargs())
    assert res.success, res.reason
    res.check()
    at_lift = max(w for r, w in res.liftable if r <= res.squeeze_depth + 1e-12)
    assert at_lift >= res.body.weight * (1 - 1e-12)
    fingers = {k: len(v) for k, v in res.final.contact_nodes.items()}
    assert fingers["table"] == 0 and min(fingers["finger1"], fingers["finger2"]) >= 3
    # the two fingers carry the weight: vertical force balance at lift-off, to round-off
    total = sum(np.asarray(f).sum(axis=0) for f in res.final.contact_forces.values() if len(f))
    np.testing.assert_allclose(total[2], res.body.weight, rtol=1e-9)


def test_centre_of_mass_rule_skips_heights_where_no_rigid_grasp_exists():
    """On a half-spheroid bun the side at the centre of mass's height leans beyond the friction angle
    (μ = 0.4): two fingers could not hold even a rigid bun there, so the rule moves down to where they
    could; if no height clearing the table allows it, the first valid pair is kept."""
    pytest.importorskip("gmsh", reason="gmsh's Python module is not installed (Debian package python3-gmsh)")
    from fem_grasp.grasp import placement
    from fem_grasp.grasp.pickup import default_finger_contacts
    from fem_grasp.grasp.rigid import rigid_grasp
    from fem_grasp.mesh import shapes
    from fem_grasp.mesh.tetmesh import TetMesh

    body = Body(TetMesh(*shapes.dome(0.05, 0.035, 0.008)), 1e4, 0.2, weight=0.467)
    rs = rest(body, 0.4)
    mesh, pos = rs.body.mesh, rs.positions
    out = mesh.outward_normals(pos)
    com = (mesh.volumes @ pos[mesh.tets].mean(axis=1)) / mesh.volume
    d1, d2 = (np.asarray(d) / np.linalg.norm(d) for d in placement.PAPER_SQUEEZE_DIRECTIONS)

    def feasible(ij):
        return rigid_grasp(pos[list(ij)], -out[list(ij)], com, body.weight, 0.4).feasible

    at_com = placement.finger_contact_nodes(mesh, com[2], d1)
    assert not feasible(at_com)
    low, _ = default_finger_contacts(rs, d1, 0.4, 0.4, 0.01, np.stack([d1, d2]), rule="centre-of-mass-height",
                                     max_squeeze=0.004)
    assert feasible(low) and pos[list(low), 2].max() < com[2] - 0.002
    # a long squeeze keeps the fingertips high above the table: no feasible height, the first valid pair
    high, _ = default_finger_contacts(rs, d1, 0.4, 0.4, 0.01, np.stack([d1, d2]), rule="centre-of-mass-height",
                                      max_squeeze=0.02)
    assert tuple(high) == tuple(at_com)


@pytest.mark.parametrize("rule", ["least-force", "centre-of-mass-height"])
def test_default_placement_on_a_box_takes_the_middle_of_the_faces_not_an_edge(rule):
    """A flat face across the squeeze direction ties every node on it; the fingers go to the middle of the
    face at the chosen height (an edge node's normal leans 45°, and no placement there was force closure)."""
    from fem_grasp.grasp import placement
    from fem_grasp.grasp.pickup import default_finger_contacts

    body = Body(box_mesh((-0.015, -0.02, 0.0), (0.015, 0.02, 0.03), (6, 8, 6)), 2e4, 0.3, weight=WEIGHT)
    rs = rest(body, 0.5)
    d1, d2 = (np.asarray(d) / np.linalg.norm(d) for d in placement.PAPER_SQUEEZE_DIRECTIONS)
    ij, closure = default_finger_contacts(rs, d1, 0.5, 0.5, 0.01, np.stack([d1, d2]), rule=rule)
    assert closure.closed
    p = rs.positions[list(ij)]
    np.testing.assert_allclose(p[:, 1], [-0.02, 0.02], atol=1e-4)  # on the two faces across the squeeze
    np.testing.assert_allclose(p[:, 0], 0.0, atol=1e-4)  # in the middle of each face, not at its edges
    out = rs.body.mesh.outward_normals(rs.positions)[list(ij)]
    np.testing.assert_allclose(out, [[0, -1, 0], [0, 1, 0]], atol=1e-2)  # facing each other




# ------------------------------------------------------ the finger force, four ways
def test_each_fingers_force_is_reported_four_ways_and_the_two_carry_the_weight_at_lift_off(lifted):
    f1, f2 = lifted.finger_forces
    final = lifted.final
    for f, name in ((f1, "finger1"), (f2, "finger2")):
        np.testing.assert_allclose(f.resultant, final.contact_forces[name].sum(axis=0), rtol=0, atol=1e-15 * WEIGHT)
        assert f.magnitude == pytest.approx(np.linalg.norm(f.resultant), rel=1e-15)
        assert f.contacts == len(final.contact_nodes[name]) >= 1
        assert 0 < f.grip <= f.magnitude and f.normal_sum > 0
    # at lift-off the fingers alone hold the object: their vertical parts add up to its weight
    assert f1.vertical + f2.vertical == pytest.approx(WEIGHT, rel=1e-9)
    # … and their horizontal parts cancel (the box hangs in equilibrium); Σ f·n̂ is Table III's measure
    np.testing.assert_allclose(f1.resultant[:2] + f2.resultant[:2], 0.0, rtol=0, atol=1e-9 * WEIGHT)
    assert f1.normal_sum + f2.normal_sum == pytest.approx(lifted.finger_normal_force, rel=1e-12)
    doc = lifted.to_dict()
    assert doc["finger_forces"][0]["grip"] == pytest.approx(f1.grip) and "normal sum" in doc["table_iii_measure"]
