"""An implicit increment of the tracking is one static contact problem.

``Tracker.implicit_step`` relaxes the contacts, adds nodes that come to penetrate an obstacle and releases
tensile ones, and relaxes again.  Every round solves the increment's problem from its held state (the
contacts where the increment began, moved with their finger), its sweeps only starting at the previous
round's state: a contact that slid in an earlier round, while the contact set still missed a node, and sticks
in the final one is back where the increment held it (a contact that slides in an increment ends on its cone;
one that sticks has not moved).  ``PickupResult.check()`` cannot see a violation (it tests cones, not the
pairing of slip and friction); this test does, on the quick foam block, whose lift test settles many hanging
states by implicit steps.  The independent frictional-contact reference found the violation when rounds
relaxed from the previous round's result (10–50 % of the implicit steps of every shipped scene).
"""

from __future__ import annotations

import numpy as np

import fem_grasp.contact.tracking as tracking
from fem_grasp import Body, box_mesh, pickup


def test_sticking_contacts_do_not_move_within_an_implicit_step(monkeypatch):
    moved: list[tuple[str, int, float]] = []
    steps = [0]
    original = tracking.Tracker.implicit_step

    def checked(self, base, dt, velocities, **kw):
        state, events = original(self, base, dt, velocities, **kw)
        steps[0] += 1
        vel = np.zeros((base.n_contacts, 3))
        for f in (tracking.FINGER1, tracking.FINGER2):
            vel[base.owner == f] = np.asarray(velocities, float)[f]
        held = {int(k): base.disp[j] + dt * vel[j] for j, k in enumerate(base.nodes)}
        # Contacts of the start that are sticking at the end must be where the increment held them.
        for j, k in enumerate(state.nodes):
            if int(k) in held and not state.sliding[j]:
                move = float(np.linalg.norm(state.disp[j] - held[int(k)]))
                if move > 1e-9 * self.diameter:
                    moved.append((state.phase, int(k), move / self.diameter))
        return state, events

    monkeypatch.setattr(tracking.Tracker, "implicit_step", checked)
    # The quick foam block of fem_grasp/scenes/foam_block.toml, squeezed until its lift test passes.
    body = Body(box_mesh((-0.015, -0.02, 0.0), (0.015, 0.02, 0.03), (4, 4, 4)), 2e4, 0.3, weight=0.3)
    res = pickup(body, mu_finger=0.5, mu_table=0.5, finger_radius=0.01, contacts=(52, 72), lift=False)
    assert steps[0] > 5, "the lift test should have settled hanging states by implicit steps"
    assert "lift test passed" in res.reason
    assert not moved, f"sticking contacts moved within an implicit step (phase, node, move/diameter): {moved[:5]}"
