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
  :func:`~fem_grasp.contact.kernels.slip_newton.newton` and the admissibility test
  (no compressive sliding contact on the far root through its cone's axis);
* :func:`homotopy` — the Newton-homotopy continuation of paper footnote 2 where
  Newton's method finds no root (``homotopy.track`` as ``MixedSlipSystem.solve``
  calls it, its linear solves and condition test included);
* :func:`outcome` — forces, displacement changes, slip amounts and the slip
  rates of event D by the implicit-function theorem (a partial-pivoting LU
  whose smallest pivot below ``SINGULAR_PIVOT`` of the largest reads as a
  friction limit, as scipy's factors do in ``MixedSlipSystem.rates``).

The arithmetic is that of ``MixedSlipSystem`` in another summation order:
the two agree to round-off (``tests/contact/test_slip_trial.py``), and the
tracker keeps ``MixedSlipSystem`` as its reference path.
"""

from __future__ import annotations

import math

import numpy as np

from . import dense, events, slip_newton
from .jit import jit

__all__ = ["COND_MAX", "CORRECTOR_ITERS", "CORRECTOR_TOL", "ENTRY_POINTS", "HOMOTOPY_REASONS", "SINGULAR_DETAILS",
           "TRIAL_NO_DIRECTION", "TRIAL_NO_ROOT", "TRIAL_ROOT", "assemble", "fused_newton",
           "held_prediction", "homotopy", "newton_root", "newton_trial", "outcome"]

#: The kernels called from Python (what a warm-up must reach).
ENTRY_POINTS = ("assemble", "held_prediction", "homotopy", "newton_root", "newton_trial", "outcome")

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
    ok, yy = fused_newton(y, lim, max_iter, scale, row_scale, base, g_sl, dmap, n0, kappa, mu, sph, free)
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


# ------------------------------------------------------------------ homotopy
#: Outcome codes of :func:`homotopy` (``fem_grasp.contact.homotopy.HomotopyError.reason``, in this order).
HOMOTOPY_REASONS = ("", "diverged", "singular_jacobian", "step_too_small", "max_steps", "polish_failed")
#: Why a linear solve of the homotopy failed (``homotopy._Singular``'s messages, in this order).
SINGULAR_DETAILS = ("", "non-finite matrix or right-hand side", "zero matrix", "condition number > 1e+14")
#: The Newton homotopy's limits, here and in its numpy reference (``fem_grasp.contact.homotopy`` imports them): the
#: condition number above which a Jacobian counts as singular, the relative Newton-step size at which the path
#: corrector stops, and its iterations per step.
COND_MAX = 1e14
CORRECTOR_TOL = 1e-9
CORRECTOR_ITERS = 6


@jit
def _lin_solve(a, b):
    """``homotopy._lin_solve``: (detail code, x), code 0 when solved; singular when the matrix or right-hand side is
    not finite, the matrix is zero, or its 1-norm condition number exceeds 1e14 (here ‖A‖₁‖A⁻¹‖₁ itself, where
    LAPACK's gecon estimates ‖A⁻¹‖₁ from below: a matrix within a factor of a few of the limit may be judged
    singular here and not there)."""
    n = a.shape[0]
    if not (np.isfinite(a).all() and np.isfinite(b).all()):
        return 1, b
    anorm = 0.0
    for col in range(n):
        s = 0.0
        for i in range(n):
            s += abs(a[i, col])
        anorm = max(anorm, s)
    if anorm == 0.0:
        return 2, b
    lu, piv, info = dense.lu_factor(a)
    if info > 0:
        return 3, b
    inv_norm = 0.0
    e = np.zeros(n)
    for col in range(n):
        e[:] = 0.0
        e[col] = 1.0
        z = dense.lu_solve(lu, piv, e)
        s = 0.0
        for i in range(n):
            s += abs(z[i])
        inv_norm = max(inv_norm, s)
    if not (np.isfinite(inv_norm) and anorm * inv_norm < COND_MAX):
        return 3, b
    return 0, dense.lu_solve(lu, piv, b)


@jit
def _scaled(y, scale, row_scale, base, g_sl, dmap, n0, kappa, mu, sph, free):
    """P(y) = row_scale · residual(scale · y), the system the homotopy follows (``MixedSlipSystem.solve``'s fun)."""
    p = mu.shape[0]
    out = np.empty(y.shape[0])
    _scaled_residual(y, scale, row_scale, base, g_sl, dmap, n0, kappa, mu, sph, free, np.empty(y.shape[0]), out,
                     np.empty((p, 3)), np.empty((p, 3)), np.empty((p, 3)))
    return out


@jit
def _scaled_with_jacobian(y, scale, row_scale, base, g_sl, dmap, n0, kappa, mu, sph, free):
    """(P(y), ∂P/∂y): the Jacobian row_scale · ∂residual/∂x · scale with the residual it is built on (one evaluation
    for both: ``_scaled`` gives the same numbers)."""
    p = mu.shape[0]
    nx = y.shape[0]
    xs, r = np.empty(nx), np.empty(nx)
    f, d, n = np.empty((p, 3)), np.empty((p, 3)), np.empty((p, 3))
    _scaled_residual(y, scale, row_scale, base, g_sl, dmap, n0, kappa, mu, sph, free, xs, r, f, d, n)
    jac = np.empty((nx, nx))
    _fused_jacobian(xs, g_sl, dmap, kappa, mu, sph, free, f, d, n, jac)
    for i in range(nx):
        for j in range(nx):
            jac[i, j] = row_scale[i] * jac[i, j] * scale[j]
    return r, jac


@jit
def homotopy(y0, tol, initial_step, max_step, max_steps, min_step, max_iter,
             scale, row_scale, base, g_sl, dmap, n0, kappa, mu, sph, free):
    """The Newton homotopy H(y, t) = P(y) − (1 − t)² P(y₀) of paper footnote 2, as ``homotopy.track`` follows it
    for ``MixedSlipSystem.solve`` (start Q = P − P(y₀), γ = 1): Euler predictor, Newton corrector, step in t halved
    on a failed correction and doubled after one of ≤ 3 iterations, Newton polish of P at t = 1.

    Returns
    -------
    (reason, detail, t, value, y, steps): reason 0 and the polished y on success, else an index into
    ``HOMOTOPY_REASONS`` (polish failures: ``detail`` is the polish's own reason), where it stopped (t), the step
    or residual its message quotes (value), the last point, and the continuation steps taken.
    """
    args = (scale, row_scale, base, g_sl, dmap, n0, kappa, mu, sph, free)
    x = y0.copy()
    limit = 1e8 * max(1.0, math.sqrt(np.dot(x, x)))
    p0 = _scaled(x, *args)
    t, h, steps, rejected = 0.0, initial_step, 0, 0
    while t < 1.0:
        if steps + rejected >= max_steps:
            return 4, 0, t, float(max_steps), x, steps
        pv, jx = _scaled_with_jacobian(x, *args)
        jt = 2.0 * (1.0 - t) * (pv - (pv - p0))
        b = (1.0 - t) ** 2
        code, xdot = _lin_solve((1.0 - b) * jx + b * jx, -jt)
        if code:
            return 2, code, t, 0.0, x, steps
        h = min(h, 1.0 - t)
        t_new = 1.0 if h >= 1.0 - t else t + h
        # Newton corrector on H(., t_new): accepted when it contracts and converges within a few iterations.
        xc = x + h * xdot
        bn = (1.0 - t_new) ** 2
        prev = np.inf
        accepted = 0
        for k in range(1, CORRECTOR_ITERS + 1):
            pc, jc = _scaled_with_jacobian(xc, *args)
            code, dx = _lin_solve((1.0 - bn) * jc + bn * jc, -((1.0 - bn) * pc + bn * (pc - p0)))
            if code:
                break
            xc = xc + dx
            step = math.sqrt(np.dot(dx, dx))
            if not np.isfinite(step):
                break
            if step <= CORRECTOR_TOL * (1.0 + math.sqrt(np.dot(xc, xc))):
                accepted = k
                break
            if step > 0.5 * prev:
                break
            prev = step
        if accepted == 0:
            rejected += 1
            h *= 0.5
            if h < min_step:
                return 3, 0, t, h, x, steps
            continue
        x, t = xc, t_new
        steps += 1
        if math.sqrt(np.dot(x, x)) > limit:
            return 1, 0, t, limit, x, steps
        if accepted <= 3:
            h = min(2.0 * h, max_step)
    # Polish: plain Newton on P (``homotopy._newton``); its failures are reported as polish failures.
    res = 0.0
    for it in range(max_iter + 1):
        r = _scaled(x, *args)
        if not np.isfinite(r).all():
            return 5, 1, 1.0, -1.0, x, steps
        res = math.sqrt(np.dot(r, r))
        if res <= tol:
            return 0, 0, 1.0, res, x, steps
        if it == max_iter:
            break
        code, dx = _lin_solve(_scaled_with_jacobian(x, *args)[1], -r)
        if code:
            return 5, 2, 1.0, float(code), x, steps
        x = x + dx
        if not np.isfinite(x).all() or math.sqrt(np.dot(x, x)) > limit:
            return 5, 1, 1.0, limit, x, steps
    return 5, 4, 1.0, res, x, steps


# ------------------------------------------------------------- fused Newton
@jit
def _fused_residual(x, base, g, dmap, n0, kappa, mu, sph, free, out, f, d, n):
    """``slip_newton.residual`` into ``out``, leaving the sliding nodes' forces, slips and normals in f, d, n (p, 3)."""
    p = mu.shape[0]
    nx = x.shape[0]
    for row in range(3 * p):
        sf = 0.0
        sd = 0.0
        for col in range(nx):
            sf += g[row, col] * x[col]
            sd += dmap[row, col] * x[col]
        f[row // 3, row % 3] = base[row] + sf
        d[row // 3, row % 3] = sd
    for j in range(p):
        for i in range(3):
            n[j, i] = n0[j, i] + kappa[j] * d[j, i]
        fn = f[j, 0] * n[j, 0] + f[j, 1] * n[j, 1] + f[j, 2] * n[j, 2]
        out[j] = (1.0 + mu[j] ** 2) * fn ** 2 - (f[j, 0] * f[j, 0] + f[j, 1] * f[j, 1] + f[j, 2] * f[j, 2])
    q, k = sph.shape
    for i in range(q):
        t = x[sph[i, 0]] ** 2
        for jj in range(1, k):
            t += x[sph[i, jj]] ** 2
        out[p + i] = 2.0 * x[sph[i, 0]] + t
    if free:
        for j in range(p):
            c0 = f[j, 1] * d[j, 2] - f[j, 2] * d[j, 1]
            c1 = f[j, 2] * d[j, 0] - f[j, 0] * d[j, 2]
            c2 = f[j, 0] * d[j, 1] - f[j, 1] * d[j, 0]
            out[p + q + j] = n[j, 0] * c0 + n[j, 1] * c1 + n[j, 2] * c2


@jit
def _fused_jacobian(x, g, dmap, kappa, mu, sph, free, f, d, n, jac):
    """``slip_newton.jacobian`` at the state f, d, n of :func:`_fused_residual`, into ``jac``."""
    p = mu.shape[0]
    nx = x.shape[0]
    q, k = sph.shape
    jac[:, :] = 0.0
    for j in range(p):
        fn = f[j, 0] * n[j, 0] + f[j, 1] * n[j, 1] + f[j, 2] * n[j, 2]
        a = 2.0 * (1.0 + mu[j] ** 2) * fn
        r0, r1, r2 = 3 * j, 3 * j + 1, 3 * j + 2
        kap = kappa[j]
        for col in range(nx):
            g0, g1, g2 = g[r0, col], g[r1, col], g[r2, col]
            dn0, dn1, dn2 = kap * dmap[r0, col], kap * dmap[r1, col], kap * dmap[r2, col]
            jac[j, col] = (a * ((n[j, 0] * g0 + n[j, 1] * g1 + n[j, 2] * g2) + (f[j, 0] * dn0 + f[j, 1] * dn1
                                                                              + f[j, 2] * dn2))
                           - 2.0 * (f[j, 0] * g0 + f[j, 1] * g1 + f[j, 2] * g2))
    for i in range(q):
        for jj in range(k):
            jac[p + i, sph[i, jj]] = 2.0 * x[sph[i, jj]]
        jac[p + i, sph[i, 0]] += 2.0
    if free:
        for j in range(p):
            fd0 = f[j, 1] * d[j, 2] - f[j, 2] * d[j, 1]
            fd1 = f[j, 2] * d[j, 0] - f[j, 0] * d[j, 2]
            fd2 = f[j, 0] * d[j, 1] - f[j, 1] * d[j, 0]
            dn_0 = d[j, 1] * n[j, 2] - d[j, 2] * n[j, 1]
            dn_1 = d[j, 2] * n[j, 0] - d[j, 0] * n[j, 2]
            dn_2 = d[j, 0] * n[j, 1] - d[j, 1] * n[j, 0]
            nf0 = n[j, 1] * f[j, 2] - n[j, 2] * f[j, 1]
            nf1 = n[j, 2] * f[j, 0] - n[j, 0] * f[j, 2]
            nf2 = n[j, 0] * f[j, 1] - n[j, 1] * f[j, 0]
            r0, r1, r2 = 3 * j, 3 * j + 1, 3 * j + 2
            kap = kappa[j]
            for col in range(nx):
                jac[p + q + j, col] = ((fd0 * (kap * dmap[r0, col]) + fd1 * (kap * dmap[r1, col])
                                        + fd2 * (kap * dmap[r2, col]))
                                       + (dn_0 * g[r0, col] + dn_1 * g[r1, col] + dn_2 * g[r2, col])
                                       + (nf0 * dmap[r0, col] + nf1 * dmap[r1, col] + nf2 * dmap[r2, col]))


@jit
def _scaled_residual(y, scale, row_scale, base, g, dmap, n0, kappa, mu, sph, free, xs, out, f, d, n):
    for i in range(y.shape[0]):
        xs[i] = scale[i] * y[i]
    _fused_residual(xs, base, g, dmap, n0, kappa, mu, sph, free, out, f, d, n)
    for i in range(out.shape[0]):
        out[i] = row_scale[i] * out[i]


@jit
def _norm(v):
    s = 0.0
    for e in v:
        s += e * e
    return math.sqrt(s)


@jit
def fused_newton(y, lim, max_iter, scale, row_scale, base, g, dmap, n0, kappa, mu, sph, free):
    """:func:`~fem_grasp.contact.kernels.slip_newton.newton` (the same damped iteration, tests and limits) on
    preallocated arrays: residual and Jacobian in loops over the affine maps, the step by LAPACK's LU
    (:mod:`~fem_grasp.contact.kernels.dense`).

    Returns
    -------
    (converged, y)
    """
    nx = y.shape[0]
    p = mu.shape[0]
    y = y.copy()
    xs = np.empty(nx)
    f, d, n = np.empty((p, 3)), np.empty((p, 3)), np.empty((p, 3))
    r = np.empty(nx)
    r_new = np.empty(nx)
    jac = np.empty((nx, nx))
    y_new = np.empty(nx)
    _scaled_residual(y, scale, row_scale, base, g, dmap, n0, kappa, mu, sph, free, xs, r, f, d, n)
    best, since = np.inf, 0
    for _ in range(max_iter):
        if not np.isfinite(r).all():
            return False, y
        done = True
        for i in range(nx):
            if not abs(r[i]) <= lim[i]:
                done = False
                break
        if done:
            return True, y
        norm = _norm(r)
        best, since, give_up = slip_newton.progress(norm, best, since)
        if give_up:
            break
        # The Jacobian at y: xs, f, d and n are those of the latest residual, which was y's.
        _fused_jacobian(xs, g, dmap, kappa, mu, sph, free, f, d, n, jac)
        for i in range(nx):
            for j in range(nx):
                jac[i, j] = row_scale[i] * jac[i, j] * scale[j]
        lu, piv, info = dense.lu_factor(jac)  # as np.linalg.solve's LAPACK gesv
        if info > 0:
            return False, y
        step = dense.lu_solve(lu, piv, -r)
        if not np.isfinite(step).all():
            return False, y
        lam = 1.0
        found = False
        for _h in range(12):
            for i in range(nx):
                y_new[i] = y[i] + lam * step[i]
            _scaled_residual(y_new, scale, row_scale, base, g, dmap, n0, kappa, mu, sph, free, xs, r_new, f, d, n)
            if np.isfinite(r_new).all() and _norm(r_new) < (1.0 - 1e-4 * lam) * norm:
                found = True
                break
            lam *= 0.5
        if not found:  # no decrease: take the full step (round-off regime)
            for i in range(nx):
                y_new[i] = y[i] + step[i]
            _scaled_residual(y_new, scale, row_scale, base, g, dmap, n0, kappa, mu, sph, free, xs, r_new, f, d, n)
        dy = 0.0
        yn = 0.0
        for i in range(nx):
            dy += (y_new[i] - y[i]) ** 2
            yn += y_new[i] ** 2
        stalled = math.sqrt(dy) <= 1e-14 * (1.0 + math.sqrt(yn))
        y[:] = y_new
        r[:] = r_new
        if stalled:
            break
    ok = np.isfinite(r).all()
    for i in range(nx):
        if not abs(r[i]) <= 10.0 * lim[i]:
            ok = False
    return ok, y


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
