"""The return mapping's Newton polish in one compiled kernel.

Once the Gauss–Seidel sweeps of :func:`fem_grasp.contact.relaxation.relax_contacts`
stop changing the contacts' statuses, Newton's method on the smooth system of
those statuses finishes the solve (``relaxation._polish``): unknowns u_k (2)
of each sliding contact and δ_k (3) of each released one; equations
f_t + μ f_n ŝ = 0 in the tangent plane at the new position (sliding) and
f_k = 0 (released).  The lift test's hanging settles and every implicit
increment end in such a polish, and written with numpy each costs a few
hundred small array operations (the steam bun spent 1.6 s of its 3.7 s profiled
pickup in them).  :func:`polish` is the same iteration — the same Jacobian
(coupling blocks A_i C_ij D_j plus each sliding contact's geometric block by
forward differences), chord steps on the LU factors while a full step cuts
the residual to a quarter, Armijo backtracking to 1/8, and the closing checks
that the statuses still hold — in another summation order; ``relaxation._polish``
stays as its reference (``tests/contact/test_polish.py``).

The factors are single precision (``single``, the setting ``single_precision_factors``): on a fine patch the
Jacobian has 1,100–1,600 unknowns and its factorisation is most of a polish, which LAPACK's sgetrf does in half
dgetrf's time.  The first step from new factors is refined once against the Jacobian in double precision
(mixed-precision iterative refinement: Langou et al., "Exploiting the performance of 32 bit floating point
arithmetic in obtaining 64 bit accuracy", SC 2006), and factors whose refined step is further than
:data:`SINGLE_PRECISION_DEFECT` from the Newton step (Jacobians conditioned beyond ~1e4; the fine patches' are
~1e3) are replaced by double precision's.  Chord steps use the factors as they are: a chord step is an
approximate Newton step anyway.  The residual, the tolerance and the root are double precision's throughout.
"""

from __future__ import annotations

import math

import numpy as np

from . import dense
from . import gauss_seidel as gs
from .jit import jit

__all__ = ["ENTRY_POINTS", "FAILED", "HOLDS", "VIOLATED", "polish"]

#: The kernels called from Python (what a warm-up must reach).
ENTRY_POINTS = ("polish",)

_SLIDE, _RELEASE, _STICK = gs.SLIDE, gs.RELEASE, gs.STICK

#: Outcomes of :func:`polish`: no root of the smooth system found; a root at which every status holds; a root at
#: which some status does not hold (a sticking contact outside its cone, a sliding one pulling or turned back, a
#: released one inside its obstacle): the sweeps go on from it.
FAILED, HOLDS, VIOLATED = 0, 1, 2

#: A Jacobian's single-precision factors serve (``single``) when the Newton step they give, refined once, has a
#: relative defect ‖J s + r‖ / ‖r‖ of at most this (the first solve's is about cond(J) × 6e-8 and the refinement
#: squares it: Jacobians conditioned up to ~1e4; the fine patches' are ~1e3); else the Jacobian is factorised in
#: double precision.  A step this exact converges as Newton's does until the residual is a millionth of the first.
SINGLE_PRECISION_DEFECT = 1e-6


@jit
def _evaluate(x, rec, c, f0, mu, d, act, slide, offs, with_jacobian):
    """(residual, forces (m, 3), displacement changes (m, 3), Jacobian or an empty matrix) at x."""
    m = f0.shape[0]
    q = act.shape[0]
    n_x = offs[q]
    dd = d.copy()
    proj = np.zeros((q, 9))
    for i in range(q):
        k = act[i]
        o = offs[i]
        if slide[i]:
            a0, a1, a2, b0, b1, b2, d0, d1, d2 = gs.slide_projection(rec[k], mu[k], x[o], x[o + 1])
            proj[i, 0], proj[i, 1], proj[i, 2], proj[i, 3], proj[i, 4], proj[i, 5] = a0, a1, a2, b0, b1, b2
            dd[k, 0], dd[k, 1], dd[k, 2] = d0, d1, d2
        else:
            dd[k, 0], dd[k, 1], dd[k, 2] = x[o], x[o + 1], x[o + 2]
    f = f0 + (c @ dd.reshape(-1)).reshape(m, 3)
    r = np.empty(n_x)
    for i in range(q):
        k = act[i]
        o = offs[i]
        if slide[i]:
            r[o] = proj[i, 0] * f[k, 0] + proj[i, 1] * f[k, 1] + proj[i, 2] * f[k, 2]
            r[o + 1] = proj[i, 3] * f[k, 0] + proj[i, 4] * f[k, 1] + proj[i, 5] * f[k, 2]
        else:
            r[o], r[o + 1], r[o + 2] = f[k, 0], f[k, 1], f[k, 2]
    if not with_jacobian:
        return r, f, dd, np.zeros((0, 0))
    # Row maps A_i (2×3 sliding, I released) and column maps D_j (3×2 sliding, I released), padded to 3×3; each
    # sliding contact's geometric block ∂A_i/∂u f_i by forward differences.
    amap = np.zeros((q, 3, 3))
    dmap = np.zeros((q, 3, 3))
    geo = np.zeros((q, 2, 2))
    for i in range(q):
        k = act[i]
        o = offs[i]
        if not slide[i]:
            for a in range(3):
                amap[i, a, a] = 1.0
                dmap[i, a, a] = 1.0
            continue
        for a in range(3):
            amap[i, 0, a] = proj[i, a]
            amap[i, 1, a] = proj[i, 3 + a]
        u0, u1 = x[o], x[o + 1]
        h = max(1e-7 * math.sqrt(u0 * u0 + u1 * u1), 1e-30)
        for j in range(2):
            v0, v1 = (u0 + h, u1) if j == 0 else (u0, u1 + h)
            p0, p1, p2, p3, p4, p5, e0, e1, e2 = gs.slide_projection(rec[k], mu[k], v0, v1)
            dmap[i, 0, j] = (e0 - dd[k, 0]) / h
            dmap[i, 1, j] = (e1 - dd[k, 1]) / h
            dmap[i, 2, j] = (e2 - dd[k, 2]) / h
            geo[i, 0, j] = ((p0 - proj[i, 0]) * f[k, 0] + (p1 - proj[i, 1]) * f[k, 1] + (p2 - proj[i, 2]) * f[k, 2]) / h
            geo[i, 1, j] = ((p3 - proj[i, 3]) * f[k, 0] + (p4 - proj[i, 4]) * f[k, 1] + (p5 - proj[i, 5]) * f[k, 2]) / h
    # Row by row of the Jacobian: (A_i C_ij) D_j for every j, reading contact i's three rows of C once per row.
    jac = np.empty((n_x, n_x))
    for i in range(q):
        r0 = 3 * act[i]
        for a in range(2 if slide[i] else 3):
            a0, a1, a2 = amap[i, a, 0], amap[i, a, 1], amap[i, a, 2]
            row = offs[i] + a
            for j in range(q):
                c0 = 3 * act[j]
                l0 = a0 * c[r0, c0] + a1 * c[r0 + 1, c0] + a2 * c[r0 + 2, c0]
                l1 = a0 * c[r0, c0 + 1] + a1 * c[r0 + 1, c0 + 1] + a2 * c[r0 + 2, c0 + 1]
                l2 = a0 * c[r0, c0 + 2] + a1 * c[r0 + 1, c0 + 2] + a2 * c[r0 + 2, c0 + 2]
                o = offs[j]
                for b in range(2 if slide[j] else 3):
                    jac[row, o + b] = l0 * dmap[j, 0, b] + l1 * dmap[j, 1, b] + l2 * dmap[j, 2, b]
        if slide[i]:
            for a in range(2):
                for b in range(2):
                    jac[offs[i] + a, offs[i] + b] += geo[i, a, b]
    return r, f, dd, jac


@jit
def _max_abs(r):
    out = 0.0
    for v in r:
        out = max(out, abs(v))
    return out


@jit
def _refined_step(jac, lu32, piv32, r):
    """(Newton step −J⁻¹ r from single-precision factors of J refined once against J in double precision, whether
    it is accurate: its defect ‖J s + r‖ within :data:`SINGLE_PRECISION_DEFECT` of ‖r‖)."""
    step = -dense.lu_solve(lu32, piv32, r)
    step = step - dense.lu_solve(lu32, piv32, jac @ step + r)
    defect = jac @ step + r
    return step, math.sqrt(np.dot(defect, defect)) <= SINGLE_PRECISION_DEFECT * math.sqrt(np.dot(r, r))


@jit
def polish(rec, c, f0, mu, status, d, u, tol, stick_tol, max_slip, iterations, halvings, contraction, single):
    """``relaxation._polish``: Newton's method on the smooth system of fixed statuses.

    Returns
    -------
    (outcome, δ (m, 3), u (m, 2), forces (m, 3)): outcome :data:`FAILED` (δ, u and the forces as given),
    :data:`HOLDS` (converged, the statuses hold) or :data:`VIOLATED` (converged, but some status does not hold
    at the polished state, which is returned)
    """
    m = f0.shape[0]
    q = 0
    for k in range(m):
        if status[k] != _STICK:
            q += 1
    if q == 0:
        return FAILED, d, u, f0
    act = np.empty(q, np.int64)
    slide = np.zeros(q, np.bool_)
    offs = np.zeros(q + 1, np.int64)
    i = 0
    for k in range(m):
        if status[k] != _STICK:
            act[i] = k
            slide[i] = status[k] == _SLIDE
            offs[i + 1] = offs[i] + (2 if slide[i] else 3)
            i += 1
    x = np.empty(offs[q])
    for i in range(q):
        k = act[i]
        if slide[i]:
            x[offs[i]], x[offs[i] + 1] = u[k, 0], u[k, 1]
        else:
            x[offs[i]], x[offs[i] + 1], x[offs[i] + 2] = d[k, 0], d[k, 1], d[k, 2]
    r, f, dd, jac = _evaluate(x, rec, c, f0, mu, d, act, slide, offs, True)
    fresh_lu = False
    have_lu = False
    single_lu = False  # the factors in use: single precision (lu32) or double (lu64)
    lu32, piv32, info = dense.lu_factor(np.zeros((0, 0), np.float32))
    lu64, piv64, info = dense.lu_factor(np.zeros((0, 0)))
    converged = False
    for _ in range(iterations):
        norm = math.sqrt(np.dot(r, r))
        if _max_abs(r) <= tol:
            converged = True
            break
        fresh_lu = not have_lu
        if fresh_lu:
            single_lu = False
            if single:
                lu32, piv32, info = dense.lu_factor(jac.astype(np.float32))  # LAPACK's sgetrf, as scipy's
                if info == 0:
                    step, single_lu = _refined_step(jac, lu32, piv32, r)
            if not single_lu:
                lu64, piv64, info = dense.lu_factor(jac)  # LAPACK's dgetrf, as scipy's lu_factor
                if info > 0:
                    return FAILED, d, u, f0  # exactly singular
                step = -dense.lu_solve(lu64, piv64, r)
            have_lu = True
        elif single_lu:
            step = -dense.lu_solve(lu32, piv32, r)
        else:
            step = -dense.lu_solve(lu64, piv64, r)
        if not np.isfinite(step).all():
            return FAILED, d, u, f0
        # Armijo backtracking on |r| down to 1/8 (a shorter step means wrong statuses: the sweeps go on).
        lam = 1.0
        found = False
        for _h in range(halvings):
            r2, f2, dd2, _j = _evaluate(x + lam * step, rec, c, f0, mu, d, act, slide, offs, False)
            if math.sqrt(np.dot(r2, r2)) < (1.0 - 1e-4 * lam) * norm:
                found = True
                break
            lam *= 0.5
        if not found:
            if fresh_lu:
                return FAILED, d, u, f0
            have_lu = False  # an old Jacobian's step: retry from a new one
            r, f, dd, jac = _evaluate(x, rec, c, f0, mu, d, act, slide, offs, True)
            continue
        x = x + lam * step
        r, f, dd = r2, f2, dd2
        if math.sqrt(np.dot(r, r)) > contraction * norm or lam < 1.0:
            have_lu = False
            r, f, dd, jac = _evaluate(x, rec, c, f0, mu, d, act, slide, offs, True)
    if not converged:
        return FAILED, d, u, f0
    # The statuses must still hold at the polished state.
    u2 = u.copy()
    violated = False
    for i in range(q):
        k = act[i]
        o = offs[i]
        if slide[i]:
            motion = gs.motion(rec[k], x[o], x[o + 1])
            fn = f[k, 0] * motion[3] + f[k, 1] * motion[4] + f[k, 2] * motion[5]
            ul = math.sqrt(x[o] * x[o] + x[o + 1] * x[o + 1])
            if not (fn > 0.0 and 0.0 < ul <= max_slip):
                violated = True
            u2[k, 0], u2[k, 1] = x[o], x[o + 1]
        else:
            along = x[o] * rec[k, gs.REC_N0] + x[o + 1] * rec[k, gs.REC_N0 + 1] + x[o + 2] * rec[k, gs.REC_N0 + 2]
            if along < 0.0 and not gs.outside_sphere(rec[k], x[o], x[o + 1], x[o + 2]):
                violated = True
    for k in range(m):
        if status[k] == _STICK:
            n0, n1, n2 = rec[k, gs.REC_N0], rec[k, gs.REC_N0 + 1], rec[k, gs.REC_N0 + 2]
            fn = f[k, 0] * n0 + f[k, 1] * n1 + f[k, 2] * n2
            t0, t1, t2 = f[k, 0] - fn * n0, f[k, 1] - fn * n1, f[k, 2] - fn * n2
            if fn < 0.0 or math.sqrt(t0 * t0 + t1 * t1 + t2 * t2) > mu[k] * fn + stick_tol:
                violated = True
    return (VIOLATED if violated else HOLDS), dd, u2, f
