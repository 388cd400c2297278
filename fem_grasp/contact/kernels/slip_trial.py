"""One trial's slip system (eqs. 6–8) assembled, solved and read out in compiled kernels.

:class:`fem_grasp.contact.slip_system.MixedSlipSystem` builds the affine maps
from the slip unknowns x to the sliding nodes' forces and slips with about
forty numpy operations on arrays of tens of entries, and reads out the slip
rates, amounts, displacements and forces with as many more: at the tomato's
~900 trial states per pickup that overhead, not arithmetic, was half the
tracking.  These kernels do the same in a few calls per trial:

* :func:`assemble` — the system's arrays (both forms, the same unknowns, scales
  and rows as ``MixedSlipSystem``);
* :func:`newton_root` — the damped Newton iteration of
  :func:`~fem_grasp.contact.kernels.slip_newton.newton` (fused residual and Jacobian,
  :mod:`~fem_grasp.contact.kernels.slip_residual`) and the admissibility test
  (no compressive sliding contact on the far root through its cone's axis);
* the Newton-homotopy continuation of paper footnote 2 where Newton's method
  finds no root is :func:`~fem_grasp.contact.kernels.slip_homotopy.homotopy`;
* :func:`outcome` — forces, displacement changes, slip amounts and the slip
  rates of event D by the implicit-function theorem (a partial-pivoting LU
  whose smallest pivot below ``SINGULAR_PIVOT`` of the largest reads as a
  friction limit, as scipy's factors do in ``MixedSlipSystem.rates``);
* :func:`held_prediction` and :func:`newton_trial` — step 1 of an increment, and the
  whole trial in one call where Newton's method from zero slip finds the root.

The arithmetic is that of ``MixedSlipSystem`` in another summation order:
the two agree to round-off (``tests/contact/test_slip_trial.py``), and the
tracker keeps ``MixedSlipSystem`` as its reference path.
"""

from __future__ import annotations

import math

import numpy as np

from . import dense, events, slip_newton, slip_residual
from .jit import jit
from .slip_homotopy import COND_MAX, CORRECTOR_ITERS, CORRECTOR_TOL, HOMOTOPY_REASONS, SINGULAR_DETAILS, homotopy
from .slip_residual import fused_newton

# (homotopy, fused_newton and the homotopy's codes and limits are re-exported for the callers that know them from
# here; their kernels live in slip_homotopy and slip_residual, which list them as entry points)

__all__ = ["COND_MAX", "CORRECTOR_ITERS", "CORRECTOR_TOL", "ENTRY_POINTS", "HOMOTOPY_REASONS", "SINGULAR_DETAILS",
           "TRIAL_NO_DIRECTION", "TRIAL_NO_ROOT", "TRIAL_ROOT", "assemble", "fused_newton",
           "held_prediction", "homotopy", "newton_root", "newton_trial", "outcome"]

#: The kernels called from Python (what a warm-up must reach).
ENTRY_POINTS = ("assemble", "held_prediction", "newton_root", "newton_trial", "outcome")

#: Owner code of a table contact (``fem_grasp.contact.obstacles.TABLE``).
_TABLE = 2
#: As ``slip_system.SINGULAR_PIVOT`` and ``slip_system.REVERSED_FRICTION`` (the same rules, restated here because
#: kernels cannot import the module that imports them).
_SINGULAR_PIVOT = 1e-14
_REVERSED_FRICTION = 1e-6
_EPS = 2.220446049250313e-16


@jit
def _cross3(a, b):
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


@jit
def _norm3(a):
    return math.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])


@jit
def _tangent_basis(normal):
    """(e₁, e₂) ⟂ n̂ with e₁ × e₂ = n̂, as ``obstacles.tangent_bases`` (helper axis: the smallest |n_i|, first)."""
    n = normal / _norm3(normal)
    i = 0
    for k in range(1, 3):
        if abs(n[k]) < abs(n[i]):
            i = k
    helper = np.zeros(3)
    helper[i] = 1.0
    e1 = _cross3(helper, n)
    e1 = e1 / _norm3(e1)
    return e1, _cross3(n, e1)


@jit
def assemble(c, fh, sl, kinds, mu, t, r, up, radius, free):
    """The slip system of one increment (``MixedSlipSystem``'s arrays).

    Parameters
    ----------
    c : (3m, 3m) reduced stiffness; fh : (m, 3) held forces; sl : (p,) sliding positions in the contact set;
    kinds : (p,) obstacle codes; mu : (p,); t : (p, 3) held tangential directions; r : (p, 3) r_k (|r_k| = R) of the
    fingertip nodes; up : (3,); radius : R; free : the free-direction form.

    Returns
    -------
    (g, dmap, n0, kappa, sph, xscale, row_scale, row_noise, own): g (3m, N) = ∂F/∂x; dmap (3p, N) = ∂δ/∂x of the
    sliding nodes; n0 (p, 3), kappa (p,) their normals n̂ = n̂⁰ + κ δ; sph (q, k) each fingertip node's
    unknowns; the unknowns' and rows' scales and the rows' round-off floors; own (p,) the held force sizes.
    """
    m = fh.shape[0]
    p = sl.shape[0]
    n0 = np.empty((p, 3))
    kappa = np.zeros(p)
    loc_e = np.zeros((p, 3, 3))
    sizes = np.zeros(p, np.int64)
    n_sph = 0
    for j in range(p):
        if kinds[j] != _TABLE:
            n_sph += 1
            rj = r[j].copy()
            nrm = rj / radius
            n0[j] = nrm
            kappa[j] = 1.0 / radius
            loc_e[j, :, 0] = rj
            if free:
                e1, e2 = _tangent_basis(nrm)
                loc_e[j, :, 1] = _cross3(e1, rj)
                loc_e[j, :, 2] = _cross3(e2, rj)
                sizes[j] = 3
            else:
                axis = _cross3(nrm, t[j].copy())
                axis = axis / _norm3(axis)
                loc_e[j, :, 1] = _cross3(axis, rj)
                sizes[j] = 2
        else:
            n0[j] = up
            if free:
                e1, e2 = _tangent_basis(up.copy())
                loc_e[j, :, 0] = e1
                loc_e[j, :, 1] = e2
                sizes[j] = 2
            else:
                loc_e[j, :, 0] = -t[j]
                sizes[j] = 1
    n = 0
    for j in range(p):
        n += sizes[j]
    loc_idx = np.full((p, 3), n, np.int64)
    first = 0
    for j in range(p):
        for s in range(sizes[j]):
            loc_idx[j, s] = first + s
        first += sizes[j]
    dmap = np.zeros((3 * p, n))
    g = np.zeros((3 * m, n))
    for j in range(p):
        for s in range(sizes[j]):
            col = loc_idx[j, s]
            for i in range(3):
                dmap[3 * j + i, col] = loc_e[j, i, s]
            for row in range(3 * m):
                g[row, col] = (c[row, 3 * sl[j]] * loc_e[j, 0, s] + c[row, 3 * sl[j] + 1] * loc_e[j, 1, s]
                               + c[row, 3 * sl[j] + 2] * loc_e[j, 2, s])
    fscale = 1.0
    if m > 0:
        fscale = np.abs(fh).max()
    own = np.empty(p)
    floor = 1e-12 * max(fscale, 1e-300)
    for j in range(p):
        own[j] = max(_norm3(fh[sl[j]]), floor)
    xscale = np.ones(n)
    for j in range(p):
        if kinds[j] == _TABLE:
            for s in range(sizes[j]):
                col = loc_idx[j, s]
                gn = 0.0
                for row in range(3 * m):
                    gn += g[row, col] * g[row, col]
                gn = math.sqrt(gn)
                if gn > 0:
                    xscale[col] = own[j] / gn
    row_scale = np.ones(n)
    row_noise = np.zeros(n)
    for j in range(p):
        row_scale[j] = 1.0 / own[j] ** 2
        row_noise[j] = 10.0 * _EPS * fscale / own[j]
    if free:
        for j in range(p):
            if kinds[j] != _TABLE:
                typical = own[j] * radius
            else:
                mean = 0.0
                for s in range(sizes[j]):
                    mean += xscale[loc_idx[j, s]]
                typical = own[j] * (mean / sizes[j])
            row_scale[p + n_sph + j] = 1.0 / max(typical, 1e-300)
            row_noise[p + n_sph + j] = 10.0 * _EPS * fscale / own[j]
    k = 3 if free else 2
    sph = np.zeros((n_sph, k), np.int64)
    i = 0
    for j in range(p):
        if kinds[j] != _TABLE:
            for s in range(k):
                sph[i, s] = loc_idx[j, s]
            i += 1
    return g, dmap, n0, kappa, sph, xscale, row_scale, row_noise, own


@jit
def _sliding_state(x, base, g_sl, dmap, n0, kappa):
    """Forces f (p, 3), slips δ (p, 3) and normals n̂ (p, 3) of the sliding nodes at x."""
    p = n0.shape[0]
    f = (base + g_sl @ x).reshape(p, 3)
    d = (dmap @ x).reshape(p, 3)
    n = n0 + kappa.reshape(p, 1) * d
    return f, d, n


@jit
def _admissible(x, base, g_sl, dmap, n0, kappa, t_held):
    """No compressive sliding contact has its friction reversed (``MixedSlipSystem.admissible``)."""
    f, _, n = _sliding_state(x, base, g_sl, dmap, n0, kappa)
    for j in range(n0.shape[0]):
        fn = f[j, 0] * n[j, 0] + f[j, 1] * n[j, 1] + f[j, 2] * n[j, 2]
        ft = f[j] - fn * n[j]
        along = ft[0] * t_held[j, 0] + ft[1] * t_held[j, 1] + ft[2] * t_held[j, 2]
        if fn > 0 and along < -_REVERSED_FRICTION * _norm3(ft):
            return False
    return True


@jit
def newton_root(y, lim, scale, row_scale, base, g_sl, dmap, n0, kappa, mu, sph, free, t_held, max_iter):
    """Damped Newton from the scaled start y (:func:`fused_newton`, the iteration of
    :func:`~fem_grasp.contact.kernels.slip_newton.newton`), then the admissibility test: (a root was found, it is
    admissible, x = scale · y)."""
    ok, yy = slip_residual.fused_newton(y, lim, max_iter, scale, row_scale, base, g_sl, dmap, n0, kappa, mu, sph, free)
    x = yy * scale
    if not ok:
        return False, False, x
    return True, _admissible(x, base, g_sl, dmap, n0, kappa, t_held), x


@jit
def _solve_checked(a, b):
    """x with a x = b by LAPACK's LU; (False, ·) when a pivot is below ``_SINGULAR_PIVOT`` of the largest (a friction
    limit: no rates) or the matrix is not finite (``MixedSlipSystem.rates``' test on scipy's factors)."""
    n = a.shape[0]
    if not (np.isfinite(a).all() and np.isfinite(b).all()):
        return False, b
    lu, piv, info = dense.lu_factor(a)
    big, small = 0.0, np.inf
    for k in range(n):
        big = max(big, abs(lu[k, k]))
        small = min(small, abs(lu[k, k]))
    if n and not small > _SINGULAR_PIVOT * big:
        return False, b
    return True, dense.lu_solve(lu, piv, b)


@jit
def outcome(x, fh, g, sl, dfh, base, g_sl, dmap, n0, kappa, mu, sph, free, t_held, row_scale):
    """The increment's result at the root x: (forces (m, 3), displacement changes (m, 3), slip amounts (p,),
    slip rates (p,), NaN when the rate Jacobian is singular), as ``MixedSlipSystem.forces``,
    ``displacements``, ``amounts`` and ``rates``."""
    m = fh.shape[0]
    p = sl.shape[0]
    forces = fh + (g @ x).reshape(m, 3)
    f, d, n = _sliding_state(x, base, g_sl, dmap, n0, kappa)
    disp = np.zeros((m, 3))
    dirs = np.empty((p, 3))
    amounts = np.empty(p)
    for j in range(p):
        disp[sl[j]] = d[j]
        fs = forces[sl[j]]
        fn = fs[0] * n[j, 0] + fs[1] * n[j, 1] + fs[2] * n[j, 2]
        ft = fs - fn * n[j]
        nrm = _norm3(ft)
        if nrm > 0:
            dirs[j] = ft / nrm
        else:
            dirs[j] = t_held[j]
        amounts[j] = -(dirs[j, 0] * d[j, 0] + dirs[j, 1] * d[j, 1] + dirs[j, 2] * d[j, 2])
    rates = np.zeros(p)
    if p == 0:
        return forces, disp, amounts, rates
    # ∂residual/∂t at fixed x (the held forces move at dfh), then dx/dt = −J⁻¹ ∂residual/∂t.
    nx = x.shape[0]
    n_sph = sph.shape[0]
    rate = np.zeros(nx)
    for j in range(p):
        dfj = dfh[sl[j]]
        fn = f[j, 0] * n[j, 0] + f[j, 1] * n[j, 1] + f[j, 2] * n[j, 2]
        ndf = n[j, 0] * dfj[0] + n[j, 1] * dfj[1] + n[j, 2] * dfj[2]
        fdf = f[j, 0] * dfj[0] + f[j, 1] * dfj[1] + f[j, 2] * dfj[2]
        rate[j] = 2.0 * (1.0 + mu[j] ** 2) * fn * ndf - 2.0 * fdf
        if free:
            dn = _cross3(d[j].copy(), n[j].copy())
            rate[p + n_sph + j] = dfj[0] * dn[0] + dfj[1] * dn[1] + dfj[2] * dn[2]
    jac = row_scale.reshape(-1, 1) * slip_newton.jacobian(x, base, g_sl, dmap, n0, kappa, mu, sph, free)
    ok, dx = _solve_checked(jac, -rate * row_scale)
    if not ok:
        rates[:] = np.nan
        return forces, disp, amounts, rates
    dd = (dmap @ dx).reshape(p, 3)
    for j in range(p):
        rates[j] = -(dirs[j, 0] * dd[j, 0] + dirs[j, 1] * dd[j, 1] + dirs[j, 2] * dd[j, 2])
    return forces, disp, amounts, rates



# --------------------------------------------------------- held prediction
@jit
def held_prediction(c, f0, disp, owner, velocities, dt, load, load_rate, base_forces, base_normals, sl, kinds,
                    points_sl, centers, radius, direction_floor):
    """Step 1 of an increment (``Tracker.trial``): every finger contact moved with its finger by dt, the held
    forces F_h = C Δ̄_h + λ F̄₀ (eq. 5) and their rate along the parameter, and the slip system's directions.

    Returns
    -------
    (disp_h (m, 3), fh (m, 3), dfh (m, 3), t_hat (p, 3), r (p, 3), every sliding contact has a direction): t_hat from
    the held force's tangential part (the base force's where the held one has none), r_k = R (p̃_k − O)/|p̃_k − O|
    for the fingertip nodes.
    """
    m = disp.shape[0]
    p = sl.shape[0]
    vel = np.zeros((m, 3))
    for k in range(m):
        if owner[k] != _TABLE:
            vel[k] = velocities[owner[k]]
    disp_h = disp + dt * vel
    fh = (c @ disp_h.reshape(-1)).reshape(m, 3) + load * f0
    dfh = (c @ vel.reshape(-1)).reshape(m, 3) + load_rate * f0
    t_hat = np.zeros((p, 3))
    for pass_ in range(2):
        big = 0.0
        for j in range(p):
            for i in range(3):
                v = base_forces[sl[j], i] if pass_ == 0 else fh[sl[j], i]
                big = max(big, abs(v))
        floor = direction_floor * max(big, 1e-300)
        for j in range(p):
            src = base_forces[sl[j]] if pass_ == 0 else fh[sl[j]]
            nb = base_normals[sl[j]]
            fn = src[0] * nb[0] + src[1] * nb[1] + src[2] * nb[2]
            ft = src - fn * nb
            ftn = math.sqrt(ft[0] * ft[0] + ft[1] * ft[1] + ft[2] * ft[2])
            if ftn > floor:
                t_hat[j] = ft / ftn
    ok = True
    for j in range(p):
        if t_hat[j, 0] == 0.0 and t_hat[j, 1] == 0.0 and t_hat[j, 2] == 0.0:
            ok = False
    r = np.zeros((p, 3))
    for j in range(p):
        if kinds[j] != _TABLE:
            rj = points_sl[j] + disp[sl[j]] - centers[kinds[j]]
            r[j] = rj * (radius / _norm3(rj))
    return disp_h, fh, dfh, t_hat, r, ok


# ------------------------------------------------------------ whole trial
#: :func:`newton_trial`'s outcome codes: a root was found (its slip rates NaN at a friction limit, as
#: :func:`outcome` gives them); Newton found no admissible root of the first form (the caller goes on with the
#: other methods and forms); a sliding contact has no slip direction.
TRIAL_ROOT, TRIAL_NO_ROOT, TRIAL_NO_DIRECTION = 0, 1, 2


@jit
def newton_trial(c, f0, disp, owner, velocities, dt, load, load_rate, base_forces, base_normals, sl, kinds,
                 points_sl, centers, radius, direction_floor, mu_sl, up, free, tol, max_iter, points, new_centers,
                 table):
    """One trial state of the event tracking in one call, where Newton's method from zero slip finds the root
    of the first slip form (77–91 % of the shipped scenes' trial states): :func:`held_prediction`,
    :func:`assemble`, :func:`newton_root`, :func:`outcome` and the contact normals at the new positions
    (:func:`~fem_grasp.contact.kernels.events.contact_normals`), the calls ``Tracker.trial`` made one by one, in
    the same order on the same arrays.

    Parameters
    ----------
    c … direction_floor : as :func:`held_prediction`; mu_sl : (p,) friction of the sliding contacts; up : (3,);
    free : the form tried; tol, max_iter : Newton's (``CompiledSlipSystem.solve``); points : (m, 3) the contact
    nodes' reference positions; new_centers : (2, 3) the fingertip centres after the increment; table : the table's
    owner code

    Returns
    -------
    (code, disp_h, fh, dfh, t_hat, r, found, x, forces, disp, normals, amounts, rates): ``code`` one of
    ``TRIAL_*``; the held prediction (always); Newton's result (``found``, x unscaled); with ``TRIAL_ROOT`` the
    trial's forces, contact displacements, normals and each contact's slip amount and rate (0 where it sticks).
    """
    m = disp.shape[0]
    p = sl.shape[0]
    disp_h, fh, dfh, t_hat, r, has_directions = held_prediction(
        c, f0, disp, owner, velocities, dt, load, load_rate, base_forces, base_normals, sl, kinds, points_sl,
        centers, radius, direction_floor)
    forces = np.zeros((m, 3))
    new_disp = np.zeros((m, 3))
    normals = np.zeros((m, 3))
    amounts = np.zeros(m)
    rates = np.zeros(m)
    if not has_directions:
        return TRIAL_NO_DIRECTION, disp_h, fh, dfh, t_hat, r, False, np.zeros(0), forces, new_disp, normals, \
            amounts, rates
    g, dmap, n0, kappa, sph, xscale, row_scale, row_noise, own = assemble(c, fh, sl, kinds, mu_sl, t_hat, r, up,
                                                                           radius, free)
    n = g.shape[1]
    base_sl = np.empty(3 * p)
    g_sl = np.empty((3 * p, n))
    for j in range(p):
        for i in range(3):
            base_sl[3 * j + i] = fh[sl[j], i]
            g_sl[3 * j + i] = g[3 * sl[j] + i]
    found, ok = True, True
    x = np.zeros(n)
    if n:
        lim = np.maximum(tol, row_noise)
        found, ok, x = newton_root(np.zeros(n), lim, xscale, row_scale, base_sl, g_sl, dmap, n0, kappa, mu_sl, sph,
                                   free, t_hat, max_iter)
    if not (found and ok):
        return TRIAL_NO_ROOT, disp_h, fh, dfh, t_hat, r, found, x, forces, new_disp, normals, amounts, rates
    forces, change, amounts_s, rates_s = outcome(x, fh, g, sl, dfh, base_sl, g_sl, dmap, n0, kappa, mu_sl, sph, free,
                                                 t_hat, row_scale)
    new_disp = disp_h + change
    normals = events.contact_normals(owner, points + new_disp, new_centers, up, table)
    for j in range(p):
        amounts[sl[j]] = amounts_s[j]
        rates[sl[j]] = rates_s[j]
    return TRIAL_ROOT, disp_h, fh, dfh, t_hat, r, found, x, forces, new_disp, normals, amounts, rates
