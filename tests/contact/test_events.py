"""The compiled event functions (fem_grasp.contact.kernels.events) against Tracker.event_values' numpy reference."""

import numpy as np
import pytest

from fem_grasp.contact import tracking
from tests.helpers import JITTER_SEEDS, box_squeezed_3mm, jittered

#: The same formulas in another summation order (the table's gap as a dot product, not a matrix product): a few
#: units of round-off of each value's own size.
EVENT_AGREEMENT = 1e-12


@pytest.mark.parametrize("seed", JITTER_SEEDS)
@pytest.mark.parametrize("dt", [0.0, 1e-4, 2e-3])
def test_the_compiled_event_functions_are_the_reference_ones(dt, seed):
    """The squeezed box's trial states, near and past events, as they are and with the contact displacements
    jittered: every value of A–D to round-off, and their ids and which ones are infinite (set by each contact's
    owner and status, not by a comparison of values) exactly."""
    from dataclasses import replace

    _, tracker, state, vel = box_squeezed_3mm()
    state = replace(state, disp=jittered(state.disp, None if seed is None else np.random.default_rng(seed)))
    trial = tracker.trial(state, dt, vel)
    fscale = tracker.force_scale(state)
    tracker.compiled = True
    compiled = tracker.event_values(trial, fscale)
    tracker.compiled = False
    reference = tracker.event_values(trial, fscale)
    assert compiled.keys() == reference.keys() == {"A", "B", "C", "D"}
    for kind in "ABCD":
        (mine, my_ids), (theirs, their_ids) = compiled[kind], reference[kind]
        np.testing.assert_array_equal(my_ids, their_ids)
        np.testing.assert_array_equal(np.isinf(mine), np.isinf(theirs))
        finite = np.isfinite(theirs)
        np.testing.assert_allclose(mine[finite], theirs[finite], rtol=EVENT_AGREEMENT, atol=1e-15)
    assert (reference["A"][0] > -np.inf).sum() > 0 and np.isinf(reference["C"][0]).sum() == state.sliding.sum()


def test_the_compiled_event_functions_without_a_table():
    """A hanging configuration (the lift test's tracker has no table): no surface node can touch it."""
    rs, tracker, state, vel = box_squeezed_3mm()
    hanging = tracking.Tracker(rs.body, radius=tracker.radius, mu_finger=0.5, mu_table=0.5, table=None)
    fingers = state.owner != tracking.TABLE
    st = hanging.make_state(phase="lift test", squeeze_depth=state.squeeze_depth, lift_height=0.0, load=0.5,
                            centers=state.centers, nodes=state.nodes[fingers], owner=state.owner[fingers],
                            disp=state.disp[fingers], sliding=np.zeros(fingers.sum(), bool))
    trial = tracking._Trial(st, np.zeros(st.n_contacts), np.zeros(st.n_contacts))
    hanging.compiled = True
    compiled = hanging.event_values(trial, 1.0)
    hanging.compiled = False
    reference = hanging.event_values(trial, 1.0)
    assert np.all(compiled["A"][0].reshape(-1, 3)[:, 2] == -np.inf)
    for kind in "ABCD":
        finite = np.isfinite(reference[kind][0])
        np.testing.assert_array_equal(finite, np.isfinite(compiled[kind][0]))
        np.testing.assert_allclose(compiled[kind][0][finite], reference[kind][0][finite], rtol=EVENT_AGREEMENT,
                                   atol=1e-15)


def test_the_compiled_contact_normals_are_the_reference_ones():
    """The squeezed box's contacts (table and both fingertips) at a moved trial state: unit normals, ``up`` on the
    table, outward from each fingertip's centre through the contact, as the numpy reference gives them."""
    from fem_grasp.contact.obstacles import TABLE

    _, tracker, state, vel = box_squeezed_3mm()
    st = tracker.trial(state, 1e-3, vel).state
    positions = tracker.points[st.nodes] + st.disp
    tracker.compiled = True
    compiled = tracker.normals(st.owner, positions, st.centers)
    tracker.compiled = False
    reference = tracker.normals(st.owner, positions, st.centers)
    assert set(st.owner.tolist()) == {0, 1, TABLE}
    np.testing.assert_allclose(compiled, reference, rtol=0, atol=EVENT_AGREEMENT)
    np.testing.assert_allclose(np.linalg.norm(compiled, axis=1), 1.0, atol=1e-15)
    np.testing.assert_array_equal(compiled[st.owner == TABLE], np.broadcast_to(tracker.up, compiled[st.owner == TABLE].shape))
