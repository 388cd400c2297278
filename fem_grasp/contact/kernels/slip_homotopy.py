"""The Newton-homotopy continuation of paper footnote 2 on one trial's slip system, compiled.

Where Newton's method from the held state finds no root of the slip system (eqs. 6–8), :func:`homotopy` follows
the path from the start's residual to the system's root: ``homotopy.track`` as
:meth:`~fem_grasp.contact.slip_system.MixedSlipSystem.solve` calls it, its linear solves and condition test
included, with the residual and Jacobian of :mod:`~fem_grasp.contact.kernels.slip_residual`.  The resting
iteration's table slip (:mod:`~fem_grasp.contact.plane_slip`) follows its path with it too.
"""

from __future__ import annotations

import math

import numpy as np

from . import dense, slip_residual
from .jit import jit

__all__ = ["COND_MAX", "CORRECTOR_ITERS", "CORRECTOR_TOL", "ENTRY_POINTS", "HOMOTOPY_REASONS", "SINGULAR_DETAILS",
           "homotopy"]

#: The kernels called from Python (what a warm-up must reach).
ENTRY_POINTS = ("homotopy",)

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
    not finite, the matrix is zero, or its 1-norm condition number exceeds 1e14, ‖A‖₁ times ‖A⁻¹‖₁ estimated from
    the LU factors as LAPACK's gecon estimates it (:func:`~fem_grasp.contact.kernels.dense.inverse_norm1_estimate`,
    O(n²))."""
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
    inv_norm = dense.inverse_norm1_estimate(lu, piv)
    if not (np.isfinite(inv_norm) and anorm * inv_norm < COND_MAX):
        return 3, b
    return 0, dense.lu_solve(lu, piv, b)


@jit
def _scaled(y, scale, row_scale, base, g_sl, dmap, n0, kappa, mu, sph, free):
    """P(y) = row_scale · residual(scale · y), the system the homotopy follows (``MixedSlipSystem.solve``'s fun)."""
    p = mu.shape[0]
    out = np.empty(y.shape[0])
    slip_residual.scaled_residual(y, scale, row_scale, base, g_sl, dmap, n0, kappa, mu, sph, free, np.empty(y.shape[0]), out,
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
    slip_residual.scaled_residual(y, scale, row_scale, base, g_sl, dmap, n0, kappa, mu, sph, free, xs, r, f, d, n)
    jac = np.empty((nx, nx))
    slip_residual.fused_jacobian(xs, g_sl, dmap, kappa, mu, sph, free, f, d, n, jac)
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
