"""The slip system's equations (6)–(8), their Jacobian and the damped Newton iteration, as array kernels.

:class:`fem_grasp.contact.tracking.MixedSlipSystem` builds, for one increment, the
affine maps from its unknowns x to the sliding nodes' forces and slips; these
functions evaluate the system on them.  A pickup solves thousands of such
systems of 2–100 unknowns, where numpy's per-call overhead is most of the
cost, so they are written in the array subset that numba compiles
(:mod:`fem_grasp.contact.kernels.jit`) and that runs unchanged, as numpy, without it.

Arguments shared by every function (p sliding nodes, N unknowns):

* ``base`` (3p,), ``g`` (3p, N): the sliding nodes' forces f = base + g x;
* ``dmap`` (3p, N): their slips δ = dmap x;
* ``n0`` (p, 3), ``kappa`` (p,): normals n̂ = n̂⁰ + κ δ (κ = 1/R on a fingertip, 0 on the table);
* ``mu`` (p,): friction coefficients;
* ``sph`` (q, k): each fingertip node's unknowns (γ, s) or (γ, u, v), for eq. (8) written as
  2γ + γ² + s² (+ …) = 0 without cancellation;
* ``free``: the free-direction form, with its alignment rows n̂·(f × δ) = 0.
"""

from __future__ import annotations

import math

import numpy as np

from .jit import jit

__all__ = ["ENTRY_POINTS", "residual", "jacobian", "newton"]

#: The kernels called from Python (the others are compiled into them): what a warm-up must reach.
ENTRY_POINTS = ("residual", "jacobian", "newton")


@jit
def _cross(a, b):
    """Row-wise a × b of two (p, 3) arrays."""
    out = np.empty_like(a)
    out[:, 0] = a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1]
    out[:, 1] = a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2]
    out[:, 2] = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    return out


@jit
def _dot(a, b):
    """Row-wise a · b of two (p, 3) arrays (summed in numpy's order)."""
    return a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1] + a[:, 2] * b[:, 2]


@jit
def _rows(v, m3):
    """Σ_i v[k, i] m3[k, i, :] for (p, 3) v and (p, 3, N) m3."""
    return v[:, 0:1] * m3[:, 0, :] + v[:, 1:2] * m3[:, 1, :] + v[:, 2:3] * m3[:, 2, :]


@jit
def residual(x, base, g, dmap, n0, kappa, mu, sph, free):
    """The equations at x: the cone (6)/(7) per sliding node, (8) per fingertip node, alignment if ``free``."""
    p = mu.shape[0]
    f = (base + g @ x).reshape(p, 3)
    d = (dmap @ x).reshape(p, 3)
    n = n0 + kappa.reshape(p, 1) * d
    fn = _dot(f, n)
    cone = (1.0 + mu ** 2) * fn ** 2 - _dot(f, f)
    q, k = sph.shape
    sphere = np.empty(q)
    for i in range(q):
        t = x[sph[i, 0]] ** 2
        for j in range(1, k):
            t += x[sph[i, j]] ** 2
        sphere[i] = 2.0 * x[sph[i, 0]] + t
    if free:
        return np.concatenate((cone, sphere, _dot(n, _cross(f, d))))
    return np.concatenate((cone, sphere))


@jit
def jacobian(x, base, g, dmap, n0, kappa, mu, sph, free):
    """∂residual/∂x (rows in the order of :func:`residual`)."""
    p = mu.shape[0]
    nx = x.shape[0]
    f = (base + g @ x).reshape(p, 3)
    d = (dmap @ x).reshape(p, 3)
    n = n0 + kappa.reshape(p, 1) * d
    fn = _dot(f, n)
    g3 = g.reshape(p, 3, nx)
    d3 = dmap.reshape(p, 3, nx)
    dn = kappa.reshape(p, 1, 1) * d3
    cone = (2.0 * (1.0 + mu ** 2) * fn).reshape(p, 1) * (_rows(n, g3) + _rows(f, dn)) - 2.0 * _rows(f, g3)
    q, k = sph.shape
    sphere = np.zeros((q, nx))
    for i in range(q):
        for j in range(k):
            sphere[i, sph[i, j]] = 2.0 * x[sph[i, j]]
        sphere[i, sph[i, 0]] += 2.0
    if free:
        # ∂[n·(f×δ)] = ∂n·(f×δ) + ∂f·(δ×n) + ∂δ·(n×f)
        align = _rows(_cross(f, d), dn) + _rows(_cross(d, n), g3) + _rows(_cross(n, f), d3)
        return np.concatenate((cone, sphere, align))
    return np.concatenate((cone, sphere))


@jit
def progress(norm, best, since):
    """The damped Newton iterations' give-up rule: (best norm, iterations since it fell by a tenth, give up after
    six such iterations)."""
    if norm < 0.9 * best:
        return norm, 0, False
    return best, since + 1, since + 1 >= 6


@jit
def newton(y, lim, max_iter, scale, row_scale, base, g, dmap, n0, kappa, mu, sph, free):
    """Damped Newton's method (backtracking on ‖P‖) on the scaled system P(y) = row_scale · residual(scale · y).

    Converged when every row |P_j| ≤ lim_j, or when the step stalls within 10 lim.  Gives up when the
    norm has not fallen by a tenth in six iterations (no root near here: the caller falls back).

    Returns
    -------
    (converged, y)
    """
    y = y.copy()
    r = row_scale * residual(scale * y, base, g, dmap, n0, kappa, mu, sph, free)
    best, since = np.inf, 0
    for _ in range(max_iter):
        if not np.isfinite(r).all():
            return False, y
        if np.all(np.abs(r) <= lim):
            return True, y
        norm = math.sqrt(np.dot(r, r))
        best, since, give_up = progress(norm, best, since)
        if give_up:
            break
        jac = row_scale.reshape(-1, 1) * jacobian(scale * y, base, g, dmap, n0, kappa, mu, sph, free) \
            * scale.reshape(1, -1)
        try:
            step = np.linalg.solve(jac, -r)
        except Exception:  # singular (numpy's LinAlgError; numba raises its own)
            return False, y
        if not np.isfinite(step).all():
            return False, y
        lam = 1.0
        found = False
        y_new, r_new = y, r
        for _ in range(12):
            y_new = y + lam * step
            r_new = row_scale * residual(scale * y_new, base, g, dmap, n0, kappa, mu, sph, free)
            if np.isfinite(r_new).all() and math.sqrt(np.dot(r_new, r_new)) < (1.0 - 1e-4 * lam) * norm:
                found = True
                break
            lam *= 0.5
        if not found:  # no decrease: take the full step (round-off regime)
            y_new = y + step
            r_new = row_scale * residual(scale * y_new, base, g, dmap, n0, kappa, mu, sph, free)
        dy = y_new - y
        stalled = math.sqrt(np.dot(dy, dy)) <= 1e-14 * (1.0 + math.sqrt(np.dot(y_new, y_new)))
        y, r = y_new, r_new
        if stalled:
            break
    return bool(np.isfinite(r).all() and np.all(np.abs(r) <= 10.0 * lim)), y
