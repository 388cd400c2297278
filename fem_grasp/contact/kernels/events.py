"""The event functions of the contact tracking (paper §III-C, events A–D) at one trial state, compiled.

``Tracker.event_values`` evaluates, at every trial state, the penetration of
every surface node into ℱ₁, ℱ₂ and 𝒫 (A), the normal force of every contact
(B), how far each sticking contact's force is outside its cone (C) and each
sliding contact's slip rate (D), each normalised so that > 0 means the
event fires.  :func:`event_functions` is the same arithmetic in one pass
(``tests/contact/test_events.py`` compares it with the numpy reference).
"""

from __future__ import annotations

import math

import numpy as np

from .jit import jit

__all__ = ["ENTRY_POINTS", "contact_normals", "event_functions"]

#: The kernels called from Python (what a warm-up must reach).
ENTRY_POINTS = ("event_functions", "contact_normals")


@jit
def event_functions(surface, centers, radius, has_table, up, height, own, owner, forces, normals, sliding, rates,
                    mu, fscale, diameter, tol_penetration, tol_tensile, tol_cone, tol_force_floor, tol_rate,
                    stick_hysteresis):
    """(A (3s,), B (m,), C (m,), D (m,)) as ``Tracker.event_values`` defines them.

    Parameters
    ----------
    surface : (s, 3) surface node positions; centers : (2, 3) fingertip centres; radius : R
    has_table, up, height : the table plane (ignored without one: its gaps are infinite)
    own : (m,) each contact's position in the surface (−1: interior); owner : (m,) its obstacle
    forces, normals : (m, 3); sliding : (m,) bool; rates : (m,) slip rates; mu : (m,) friction coefficients
    fscale : the state's force scale; diameter : the mesh diameter; the event tolerances (tracking's TOL_*)
    """
    s = surface.shape[0]
    m = forces.shape[0]
    a_val = np.empty(3 * s)
    for i in range(s):
        p0, p1, p2 = surface[i, 0], surface[i, 1], surface[i, 2]
        for f in range(2):
            d0, d1, d2 = p0 - centers[f, 0], p1 - centers[f, 1], p2 - centers[f, 2]
            gap = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2) - radius
            a_val[3 * i + f] = -gap / diameter - tol_penetration
        if has_table:
            gap = (p0 * up[0] + p1 * up[1] + p2 * up[2]) - height
            a_val[3 * i + 2] = -gap / diameter - tol_penetration
        else:
            a_val[3 * i + 2] = -np.inf
    for k in range(m):
        if own[k] >= 0:
            a_val[3 * own[k] + owner[k]] = -np.inf  # its own obstacle
    b_val = np.empty(m)
    c_val = np.empty(m)
    d_val = np.empty(m)
    for k in range(m):
        fn = forces[k, 0] * normals[k, 0] + forces[k, 1] * normals[k, 1] + forces[k, 2] * normals[k, 2]
        t0 = forces[k, 0] - fn * normals[k, 0]
        t1 = forces[k, 1] - fn * normals[k, 1]
        t2 = forces[k, 2] - fn * normals[k, 2]
        ft = math.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
        b_val[k] = -fn / fscale - tol_tensile
        if sliding[k]:
            c_val[k] = -np.inf
            d_val[k] = max(-rates[k] - tol_rate, stick_hysteresis * tol_force_floor - fn / fscale)
        else:
            c_val[k] = (ft - mu[k] * fn - tol_cone * max(fn, 0.0)) / fscale - tol_force_floor
            d_val[k] = -np.inf
    return a_val, b_val, c_val, d_val


@jit
def contact_normals(owner, positions, centers, up, table):
    """(m, 3) inward normals of contacts at ``positions`` (m, 3), as ``Tracker.normals`` defines them: ``up`` on the
    table (owner code ``table``), (p − O)/|p − O| on a fingertip centred at ``centers[owner]``; the same
    arithmetic as the numpy reference (the norm summed in the order x, y, z)."""
    m = positions.shape[0]
    out = np.empty((m, 3))
    for k in range(m):
        o = owner[k]
        if o == table:
            out[k, 0], out[k, 1], out[k, 2] = up[0], up[1], up[2]
            continue
        d0 = positions[k, 0] - centers[o, 0]
        d1 = positions[k, 1] - centers[o, 1]
        d2 = positions[k, 2] - centers[o, 2]
        norm = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        out[k, 0], out[k, 1], out[k, 2] = d0 / norm, d1 / norm, d2 / norm
    return out
