"""The slip system's residual and Jacobian in one pass, and the damped Newton iteration on them, compiled.

:func:`fused_residual` and :func:`fused_jacobian` evaluate the slip system of eqs. (6)–(8) (the arrays of
:func:`~fem_grasp.contact.kernels.slip_trial.assemble`) as :func:`~fem_grasp.contact.kernels.slip_newton.residual`
and :func:`~fem_grasp.contact.kernels.slip_newton.jacobian` do, sharing the sliding nodes' forces, slips and
normals between the two; :func:`fused_newton` is :func:`~fem_grasp.contact.kernels.slip_newton.newton`'s damped
iteration on them.  The trial kernels (:func:`~fem_grasp.contact.kernels.slip_trial.newton_root`) and the
homotopy (:mod:`~fem_grasp.contact.kernels.slip_homotopy`) call them.
"""

from __future__ import annotations

import math

import numpy as np

from . import dense, slip_newton
from .jit import jit

__all__ = ["ENTRY_POINTS", "fused_jacobian", "fused_newton", "fused_residual", "scaled_residual"]

#: The kernel the others reach (through :func:`~fem_grasp.contact.kernels.slip_trial.newton_root`; the tests call it
#: directly): what a warm-up must compile.
ENTRY_POINTS = ("fused_newton",)


@jit
def fused_residual(x, base, g, dmap, n0, kappa, mu, sph, free, out, f, d, n):
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
def fused_jacobian(x, g, dmap, kappa, mu, sph, free, f, d, n, jac):
    """``slip_newton.jacobian`` at the state f, d, n of :func:`fused_residual`, into ``jac``."""
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
def scaled_residual(y, scale, row_scale, base, g, dmap, n0, kappa, mu, sph, free, xs, out, f, d, n):
    for i in range(y.shape[0]):
        xs[i] = scale[i] * y[i]
    fused_residual(xs, base, g, dmap, n0, kappa, mu, sph, free, out, f, d, n)
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
    scaled_residual(y, scale, row_scale, base, g, dmap, n0, kappa, mu, sph, free, xs, r, f, d, n)
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
        fused_jacobian(xs, g, dmap, kappa, mu, sph, free, f, d, n, jac)
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
            scaled_residual(y_new, scale, row_scale, base, g, dmap, n0, kappa, mu, sph, free, xs, r_new, f, d, n)
            if np.isfinite(r_new).all() and _norm(r_new) < (1.0 - 1e-4 * lam) * norm:
                found = True
                break
            lam *= 0.5
        if not found:  # no decrease: take the full step (round-off regime)
            for i in range(nx):
                y_new[i] = y[i] + step[i]
            scaled_residual(y_new, scale, row_scale, base, g, dmap, n0, kappa, mu, sph, free, xs, r_new, f, d, n)
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
