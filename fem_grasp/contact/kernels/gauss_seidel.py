"""One projected Gauss–Seidel sweep of the return mapping, and each contact's local problem.

:func:`fem_grasp.contact.relaxation.relax_contacts` finds the static
stick/slide/release state of all contacts by sweeps over the contacts; each
visit solves contact k's own problem exactly with the others frozen (stick,
release, or slide onto its cone along the great circle of its slip, eqs. 7–8)
and updates every force by the rank-3 change C[:, k] Δδ_k.  This module is
that sweep.  It is called hundreds of thousands of times per pickup on
3-vectors, so it is written in scalar arithmetic that numba compiles when it
is installed (:mod:`fem_grasp.contact.kernels.jit`); without numba the same source runs as
plain Python on lists.

A contact is described by one row of floats (:func:`contact_records`):
the tangent basis (e₁, e₂) of its start normal n̂⁰, n̂⁰ itself, for a
fingertip contact r⁰ = q⁰ − centre and the radius, its own 3×3 stiffness
block C_kk and its inverse, the smallest eigenvalue of C_kk and the largest
entry of the tangential block e C_kk eᵀ.
"""

from __future__ import annotations

import math

import numpy as np

from ..obstacles import tangent_bases
from .jit import as_kernel_data, jit

__all__ = ["ENTRY_POINTS", "FREE_TOO_FAR", "OK", "RECORD", "REC_AMAX", "REC_CINV", "REC_CKK", "REC_E1", "REC_E2",
           "REC_KMIN", "REC_N0", "REC_R0", "REC_RADIUS", "REC_SPHERE", "RELEASE", "SLIDE", "SLIDE_TOO_FAR", "STICK",
           "SlideGeometry", "contact_records", "motion", "outside_sphere", "slide", "slide_projection",
           "slide_projections", "slide_residual", "sweep"]

STICK, SLIDE, RELEASE = 0, 1, 2

# Layout of a contact record: e₁ (3), e₂ (3), n̂⁰ (3), r⁰ (3), radius, sphere flag, C_kk (9, row-major),
# smallest eigenvalue of C_kk, max |e C_kk eᵀ|, C_kk⁻¹ (9).
REC_E1, REC_E2, REC_N0, REC_R0, REC_RADIUS, REC_SPHERE, REC_CKK, REC_KMIN, REC_AMAX, REC_CINV = 0, 3, 6, 9, 12, 13, 14, 23, 24, 25
RECORD = 34

#: The kernels called from Python (the others are compiled into them): what a warm-up must reach.
ENTRY_POINTS = ("sweep", "motion", "slide_projections", "outside_sphere")

# Outcome of a sweep.
OK, FREE_TOO_FAR, SLIDE_TOO_FAR = 0, 1, 2


def contact_records(positions: np.ndarray, centers: list, up: np.ndarray, ckk: np.ndarray) -> np.ndarray:
    """(m, RECORD) rows describing each contact (module notes).

    Parameters
    ----------
    positions : (m, 3) start positions q⁰_k on their obstacles
    centers : m entries: a fingertip centre, or None for a table contact
    up : (3,) the table's normal
    ckk : (m, 3, 3) each contact's own stiffness block C_kk (invertible)
    """
    m = len(positions)
    ckk = np.asarray(ckk, float).reshape(m, 3, 3)
    rec = np.zeros((m, RECORD))
    n0 = np.tile(np.asarray(up, float), (m, 1))
    sphere = np.array([ctr is not None for ctr in centers], dtype=bool)
    if sphere.any():
        r0 = np.asarray(positions, float)[sphere] - np.array([ctr for ctr in centers if ctr is not None], float)
        radius = np.linalg.norm(r0, axis=1)
        n0[sphere] = r0 / radius[:, None]
        rec[sphere, REC_R0:REC_R0 + 3] = r0
        rec[sphere, REC_RADIUS] = radius
        rec[sphere, REC_SPHERE] = 1.0
    basis = tangent_bases(n0)
    rec[:, REC_E1:REC_E1 + 3], rec[:, REC_E2:REC_E2 + 3], rec[:, REC_N0:REC_N0 + 3] = basis[:, 0], basis[:, 1], n0
    rec[:, REC_CKK:REC_CKK + 9] = ckk.reshape(m, 9)
    rec[:, REC_KMIN] = np.linalg.eigvalsh(ckk)[:, 0] if m else 0.0
    rec[:, REC_AMAX] = np.abs(basis @ ckk @ basis.transpose(0, 2, 1)).reshape(m, 4).max(axis=1, initial=0.0)
    rec[:, REC_CINV:REC_CINV + 9] = np.linalg.inv(ckk).reshape(m, 9)
    return rec


@jit
def motion(g, u0, u1):
    """(δ, n̂, ŝ) as 9 floats for a tangential motion (u0, u1): along the great circle on a sphere."""
    t0, t1, t2 = u0 * g[REC_E1] + u1 * g[REC_E2], u0 * g[REC_E1 + 1] + u1 * g[REC_E2 + 1], u0 * g[REC_E1 + 2] + u1 * g[REC_E2 + 2]
    tl = math.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
    h0, h1, h2 = 0.0, 0.0, 0.0
    if tl > 0:
        h0, h1, h2 = t0 / tl, t1 / tl, t2 / tl
    if g[REC_SPHERE] == 0.0:
        return t0, t1, t2, g[REC_N0], g[REC_N0 + 1], g[REC_N0 + 2], h0, h1, h2
    radius = g[REC_RADIUS]
    th = tl / radius
    c, s = math.cos(th), math.sin(th)
    # q − q⁰ = (cos θ − 1) r⁰ + R sin θ t̂, written without cancellation for small θ
    cm1, rs = -2.0 * math.sin(0.5 * th) ** 2, radius * s
    n0, n1, n2 = g[REC_N0], g[REC_N0 + 1], g[REC_N0 + 2]
    return (cm1 * g[REC_R0] + rs * h0, cm1 * g[REC_R0 + 1] + rs * h1, cm1 * g[REC_R0 + 2] + rs * h2,
            c * n0 + s * h0, c * n1 + s * h1, c * n2 + s * h2,
            c * h0 - s * n0, c * h1 - s * n1, c * h2 - s * n2)


@jit
def _force(g, fs0, fs1, fs2, d0, d1, d2):
    """fs + C_kk d as three floats."""
    return (fs0 + g[REC_CKK] * d0 + g[REC_CKK + 1] * d1 + g[REC_CKK + 2] * d2, fs1 + g[REC_CKK + 3] * d0 + g[REC_CKK + 4] * d1 + g[REC_CKK + 5] * d2,
            fs2 + g[REC_CKK + 6] * d0 + g[REC_CKK + 7] * d1 + g[REC_CKK + 8] * d2)


@jit
def _tangent_frame(g, n0, n1, n2):
    """(ê, n̂ × ê): e₁ projected onto the tangent plane of n̂ and normalised, and its turn by 90°."""
    a0, a1, a2 = g[REC_E1], g[REC_E1 + 1], g[REC_E1 + 2]
    an = a0 * n0 + a1 * n1 + a2 * n2
    e0, e1, e2 = a0 - an * n0, a1 - an * n1, a2 - an * n2
    el = math.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
    e0, e1, e2 = e0 / el, e1 / el, e2 / el
    return e0, e1, e2, n1 * e2 - n2 * e1, n2 * e0 - n0 * e2, n0 * e1 - n1 * e0


@jit
def slide_residual(g, fs0, fs1, fs2, mu, u0, u1):
    """The slide equations at motion (u0, u1): f_t + μ f_n ŝ in the tangent plane there (2), and f_n."""
    d0, d1, d2, n0, n1, n2, s0, s1, s2 = motion(g, u0, u1)
    f0, f1, f2 = _force(g, fs0, fs1, fs2, d0, d1, d2)
    fn = f0 * n0 + f1 * n1 + f2 * n2
    g0, g1, g2 = f0 - fn * n0 + mu * fn * s0, f1 - fn * n1 + mu * fn * s1, f2 - fn * n2 + mu * fn * s2
    e0, e1, e2, c0, c1, c2 = _tangent_frame(g, n0, n1, n2)
    return g0 * e0 + g1 * e1 + g2 * e2, g0 * c0 + g1 * c1 + g2 * c2, fn


@jit
def slide_projection(g, mu, u0, u1):
    """The 2×3 map f ↦ slide residual at motion (u0, u1) (rows first), then δ: 9 floats.

    :func:`slide_residual` is this map applied to f = fs + C_kk δ; the coupled Newton polish of
    :mod:`fem_grasp.contact.relaxation` applies it to the forces of all contacts.
    """
    d0, d1, d2, n0, n1, n2, s0, s1, s2 = motion(g, u0, u1)
    e0, e1, e2, c0, c1, c2 = _tangent_frame(g, n0, n1, n2)
    # row v of (I − n̂n̂ᵀ + μ ŝn̂ᵀ) applied from the left: v − (v·n̂) n̂ + μ (v·ŝ) n̂
    pe = mu * (e0 * s0 + e1 * s1 + e2 * s2) - (e0 * n0 + e1 * n1 + e2 * n2)
    pc = mu * (c0 * s0 + c1 * s1 + c2 * s2) - (c0 * n0 + c1 * n1 + c2 * n2)
    return (e0 + pe * n0, e1 + pe * n1, e2 + pe * n2, c0 + pc * n0, c1 + pc * n1, c2 + pc * n2, d0, d1, d2)


@jit
def slide_projections(rows, mu, us, out):
    """:func:`slide_projection` of every contact k at its motion us[k], into out[k] (9 floats each)."""
    for k in range(len(mu)):
        a0, a1, a2, b0, b1, b2, d0, d1, d2 = slide_projection(rows[k], mu[k], us[k][0], us[k][1])
        o = out[k]
        o[0], o[1], o[2], o[3], o[4], o[5], o[6], o[7], o[8] = a0, a1, a2, b0, b1, b2, d0, d1, d2


class SlideGeometry:
    """The slide projections of :func:`slide_projection` for many sliding contacts at once (the Newton polish of
    :mod:`fem_grasp.contact.relaxation`); ``records`` are their rows of :func:`contact_records`."""

    def __init__(self, records: np.ndarray, mu: np.ndarray) -> None:
        self.rows = as_kernel_data(np.asarray(records, float).reshape(-1, RECORD))
        self.mu = as_kernel_data(mu)

    def projections(self, us: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(p, 2, 3) maps f ↦ slide residual at the motions ``us`` (p, 2), and the slips δ (p, 3)."""
        p = len(self.mu)
        out = as_kernel_data(np.empty((p, 9)))
        slide_projections(self.rows, self.mu, as_kernel_data(us), out)
        out = np.asarray(out, float).reshape(p, 9)  # plain Python returns [] for p = 0, not (0, 9)
        return out[:, :6].reshape(p, 2, 3), out[:, 6:]


@jit
def _cone_excess(g, fs0, fs1, fs2, mu, u0, u1):
    """|f_t| − μ f_n at motion (u0, u1) (≤ 0: inside the cone)."""
    d0, d1, d2, n0, n1, n2, _s0, _s1, _s2 = motion(g, u0, u1)
    f0, f1, f2 = _force(g, fs0, fs1, fs2, d0, d1, d2)
    fn = f0 * n0 + f1 * n1 + f2 * n2
    t0, t1, t2 = f0 - fn * n0, f1 - fn * n1, f2 - fn * n2
    return math.sqrt(t0 * t0 + t1 * t1 + t2 * t2) - mu * fn


@jit
def _newton2(g, fs0, fs1, fs2, mu, u0, u1, tol):
    """Newton's method (finite-difference 2×2 Jacobian, backtracking) on the slide residual: (ok, u0, u1)."""
    g0, g1, fn = slide_residual(g, fs0, fs1, fs2, mu, u0, u1)
    hmin = 1e-9 * tol / max(g[REC_AMAX], 1e-300)
    for _ in range(40):
        if max(abs(g0), abs(g1)) <= tol:
            break
        h = max(1e-7 * math.hypot(u0, u1), hmin)
        p0, p1, _p = slide_residual(g, fs0, fs1, fs2, mu, u0 + h, u1)
        q0, q1, _q = slide_residual(g, fs0, fs1, fs2, mu, u0, u1 + h)
        j00, j10, j01, j11 = (p0 - g0) / h, (p1 - g1) / h, (q0 - g0) / h, (q1 - g1) / h
        det = j00 * j11 - j01 * j10
        if det == 0.0:
            return False, 0.0, 0.0
        s0, s1 = (j01 * g1 - j11 * g0) / det, (j10 * g0 - j00 * g1) / det
        # Armijo backtracking on the residual norm
        norm = math.hypot(g0, g1)
        lam = 1.0
        found = False
        r0, r1, rf = g0, g1, fn
        for _ in range(30):
            r0, r1, rf = slide_residual(g, fs0, fs1, fs2, mu, u0 + lam * s0, u1 + lam * s1)
            if math.hypot(r0, r1) < (1.0 - 1e-4 * lam) * norm:
                found = True
                break
            lam *= 0.5
        if not found:
            return False, 0.0, 0.0
        u0, u1, g0, g1, fn = u0 + lam * s0, u1 + lam * s1, r0, r1, rf
    if not max(abs(g0), abs(g1)) <= tol or fn < 0.0 or (u0 == 0.0 and u1 == 0.0):
        return False, 0.0, 0.0
    return True, u0, u1


@jit
def _ray_scan(g, fs0, fs1, fs2, mu, e0, e1, amax):
    """u = α e with the smallest α > 0 at which the force reaches its cone (bracket, bisect): (ok, u0, u1)."""
    lo, hi = 0.0, -1.0
    alpha = amax * 2.0 ** -50
    while alpha <= amax:
        if _cone_excess(g, fs0, fs1, fs2, mu, alpha * e0, alpha * e1) <= 0.0:
            hi = alpha
            break
        lo, alpha = alpha, 2.0 * alpha
    if hi < 0.0:
        return False, 0.0, 0.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if _cone_excess(g, fs0, fs1, fs2, mu, mid * e0, mid * e1) <= 0.0:
            hi = mid
        else:
            lo = mid
        if hi - lo <= 1e-12 * hi:
            break
    return True, hi * e0, hi * e1


@jit
def _ray_root(g, fs0, fs1, fs2, mu, e0, e1, amax, memo):
    """:func:`_ray_scan`, remembering the last question and answer in ``memo`` (10 floats).

    A contact with no local state asks the same question twice per sweep (for its slide and for its
    provisional slide), and mostly the answer is "none" after a scan of the whole bracket.
    """
    if (memo[7] == 1.0 and memo[0] == fs0 and memo[1] == fs1 and memo[2] == fs2 and memo[3] == mu
            and memo[4] == e0 and memo[5] == e1 and memo[6] == amax):
        return memo[8] != 0.0 or memo[9] != 0.0, memo[8], memo[9]
    ok, v0, v1 = _ray_scan(g, fs0, fs1, fs2, mu, e0, e1, amax)
    memo[0], memo[1], memo[2], memo[3], memo[4], memo[5], memo[6], memo[7] = fs0, fs1, fs2, mu, e0, e1, amax, 1.0
    memo[8], memo[9] = v0, v1  # (0, 0) when there is no root: a root has α > 0
    return ok, v0, v1


@jit
def slide(g, fs0, fs1, fs2, mu, warm, w0, w1, tol, amax, memo):
    """Tangential motion u with f_t = −μ f_n ŝ at the new position (f = fs + C_kk δ(u)): (ok, u0, u1).

    With ``warm`` and a non-zero (w0, w1), Newton from there only.  Otherwise Newton from the
    linearised cone equation straight back against f_t, then from the ray root along −f_t, then from a
    fixed point on the slip direction (strongly anisotropic C_kk turns the slip away from −f_t).
    """
    if warm and (w0 != 0.0 or w1 != 0.0):
        return _newton2(g, fs0, fs1, fs2, mu, w0, w1, tol)
    ft0 = g[REC_E1] * fs0 + g[REC_E1 + 1] * fs1 + g[REC_E1 + 2] * fs2
    ft1 = g[REC_E2] * fs0 + g[REC_E2 + 1] * fs1 + g[REC_E2 + 2] * fs2
    ftn = math.sqrt(ft0 * ft0 + ft1 * ft1)
    if ftn == 0.0:
        return False, 0.0, 0.0
    # First guess: straight back against f_t, by the linearised cone equation.
    tt0, tt1 = ft0 / ftn, ft1 / ftn
    fn0 = fs0 * g[REC_N0] + fs1 * g[REC_N0 + 1] + fs2 * g[REC_N0 + 2]
    w_0, w_1, w_2 = tt0 * g[REC_E1] + tt1 * g[REC_E2], tt0 * g[REC_E1 + 1] + tt1 * g[REC_E2 + 1], tt0 * g[REC_E1 + 2] + tt1 * g[REC_E2 + 2]
    cw0, cw1, cw2 = _force(g, 0.0, 0.0, 0.0, w_0, w_1, w_2)
    stiff = w_0 * cw0 + w_1 * cw1 + w_2 * cw2
    den = stiff - mu * (g[REC_N0] * cw0 + g[REC_N0 + 1] * cw1 + g[REC_N0 + 2] * cw2)
    step = (ftn - mu * fn0) / den if den > 0 else ftn / stiff
    ok, u0, u1 = _newton2(g, fs0, fs1, fs2, mu, -step * tt0, -step * tt1, tol)
    if ok:
        return ok, u0, u1
    ok, u0, u1 = _ray_root(g, fs0, fs1, fs2, mu, -tt0, -tt1, amax, memo)
    if not ok:
        return False, 0.0, 0.0
    ok, v0, v1 = _newton2(g, fs0, fs1, fs2, mu, u0, u1, tol)
    if ok:
        return ok, v0, v1
    # Fixed point on the direction (the friction at the new position sets it), each step a root along a
    # ray, then Newton again.
    for _ in range(100):
        d0, d1, d2, n0, n1, n2, _s0, _s1, _s2 = motion(g, u0, u1)
        f0, f1, f2 = _force(g, fs0, fs1, fs2, d0, d1, d2)
        fn = f0 * n0 + f1 * n1 + f2 * n2
        p0, p1, p2 = f0 - fn * n0, f1 - fn * n1, f2 - fn * n2
        ft0 = g[REC_E1] * p0 + g[REC_E1 + 1] * p1 + g[REC_E1 + 2] * p2
        ft1 = g[REC_E2] * p0 + g[REC_E2 + 1] * p1 + g[REC_E2 + 2] * p2
        ftn = math.sqrt(ft0 * ft0 + ft1 * ft1)
        if ftn == 0.0:
            return False, 0.0, 0.0
        ok, v0, v1 = _ray_root(g, fs0, fs1, fs2, mu, -ft0 / ftn, -ft1 / ftn, amax, memo)
        if not ok:
            return False, 0.0, 0.0
        done = math.hypot(v0 - u0, v1 - u1) <= 1e-6 * math.hypot(v0, v1)
        u0, u1 = v0, v1
        if done:
            break
    return _newton2(g, fs0, fs1, fs2, mu, u0, u1, tol)


@jit
def outside_sphere(g, x0, x1, x2):
    """A fingertip contact moved by δ = x lies outside its sphere, |r⁰ + δ| ≥ R (exact Signorini); False on the table."""
    if g[REC_SPHERE] == 0.0:
        return False
    p0, p1, p2 = g[REC_R0] + x0, g[REC_R0 + 1] + x1, g[REC_R0 + 2] + x2
    return p0 * p0 + p1 * p1 + p2 * p2 >= g[REC_RADIUS] * g[REC_RADIUS]


@jit
def sweep(rec, ct, f, d, u, has_u, status, mu, stick_tol, local_tol, max_slip, memo, unsolved_force):
    """One Gauss–Seidel sweep over the contacts, in place on f, d, u, has_u, status and memo.

    Parameters
    ----------
    rec : (m, RECORD) contact records
    ct : (3m, 3m) the transpose of the reduced stiffness C (C's columns as rows: the rank-3 update of contact k
        reads three contiguous rows instead of a strided column; the same numbers in the same order)
    f : (m, 3) current forces; d : (m, 3) current displacement changes δ
    u : (m, 2) tangential motion of each sliding contact, valid where has_u (m,) is 1
    status : (m,) STICK, SLIDE or RELEASE
    mu : (m,) friction coefficients
    memo : (m, 10) each contact's last ray-root question and answer
    unsolved_force : (3,) receives the force of the last contact with no local state

    Returns
    -------
    (code, contact, change, move, unsolved) : OK or the failure code with its contact; the largest
    force change |C_kk Δδ_k| and motion |Δδ_k|; the last contact with no local state (−1: none).
    """
    m = len(f)
    change, move, unsolved = 0.0, 0.0, -1
    for k in range(m):
        g = rec[k]
        dk0, dk1, dk2 = d[k][0], d[k][1], d[k][2]
        # the force at k with contact k back at its start
        c0, c1, c2 = _force(g, 0.0, 0.0, 0.0, dk0, dk1, dk2)
        fs0, fs1, fs2 = f[k][0] - c0, f[k][1] - c1, f[k][2] - c2
        n0, n1, n2 = g[REC_N0], g[REC_N0 + 1], g[REC_N0 + 2]
        fn = fs0 * n0 + fs1 * n1 + fs2 * n2
        t0, t1, t2 = fs0 - fn * n0, fs1 - fn * n1, fs2 - fn * n2
        st = STICK
        x0, x1, x2 = 0.0, 0.0, 0.0
        # Within the sweep tolerance of its cone a contact sticks (its slip would be round-off).
        if not (fn >= 0.0 and math.sqrt(t0 * t0 + t1 * t1 + t2 * t2) <= mu[k] * fn + stick_tol):
            x0 = -(g[REC_CINV] * fs0 + g[REC_CINV + 1] * fs1 + g[REC_CINV + 2] * fs2)
            x1 = -(g[REC_CINV + 3] * fs0 + g[REC_CINV + 4] * fs1 + g[REC_CINV + 5] * fs2)
            x2 = -(g[REC_CINV + 6] * fs0 + g[REC_CINV + 7] * fs1 + g[REC_CINV + 8] * fs2)
            if not math.sqrt(x0 * x0 + x1 * x1 + x2 * x2) <= max_slip:  # also catches NaN
                return FREE_TOO_FAR, k, change, move, unsolved
            # Signorini's condition in the contact's own frame: it lifts off when δ·n̂⁰ ≥ 0.  On a sphere the
            # exact distance would also grow with a purely tangential motion (|r⁰ + t| > R), letting a pressed
            # contact "release" sideways instead of sliding; δ·n̂⁰ ≥ 0 still implies |r⁰ + δ| ≥ R.  The exact
            # test is the fallback when no slide exists (below).
            if x0 * n0 + x1 * n1 + x2 * n2 >= 0.0:
                st = RELEASE
            else:
                # With three contacts each C_kk is singular (a rigid turn about the line through the other two
                # moves k alone): its smallest eigenvalue is zero up to round-off, and bounds nothing.
                kmin = g[REC_KMIN]
                amax = min(max_slip, max(abs(fs0), abs(fs1), abs(fs2)) * 1e3 / kmin) if kmin > 0.0 else max_slip
                if g[REC_SPHERE] != 0.0:
                    amax = min(amax, g[REC_RADIUS])
                warm = has_u[k] != 0
                ok, v0, v1 = slide(g, fs0, fs1, fs2, mu[k], warm, u[k][0], u[k][1], local_tol, amax, memo[k])
                if not ok and warm:
                    ok, v0, v1 = slide(g, fs0, fs1, fs2, mu[k], False, 0.0, 0.0, local_tol, amax, memo[k])
                if not ok and outside_sphere(g, x0, x1, x2):
                    # No slide, but the force-free position clears the fingertip: it lifts off sideways
                    # (a tangentially loaded node on a curved obstacle).
                    st = RELEASE
                elif not ok:
                    # No local state with the neighbours frozen.  Provisionally slide it as far as its
                    # force's own cone along −f_t (a ray root) so that the coupled Newton polish can look
                    # for a state in which its neighbours move too; the sweeps cannot converge while this
                    # lasts (the caller counts such sweeps).
                    unsolved = k
                    unsolved_force[0], unsolved_force[1], unsolved_force[2] = fs0, fs1, fs2
                    e0 = g[REC_E1] * fs0 + g[REC_E1 + 1] * fs1 + g[REC_E1 + 2] * fs2
                    e1 = g[REC_E2] * fs0 + g[REC_E2 + 1] * fs1 + g[REC_E2 + 2] * fs2
                    en = math.sqrt(e0 * e0 + e1 * e1)
                    if en > 0:  # the question slide asked: answered from the memo
                        ok, v0, v1 = _ray_root(g, fs0, fs1, fs2, mu[k], -e0 / en, -e1 / en, amax, memo[k])
                    if not ok:
                        continue
                if st != RELEASE:
                    if math.hypot(v0, v1) > max_slip:
                        return SLIDE_TOO_FAR, k, change, move, unsolved
                    u[k][0], u[k][1] = v0, v1
                    has_u[k] = 1
                    x0, x1, x2, _a, _b, _c, _d, _e, _f = motion(g, v0, v1)
                    st = SLIDE
        y0, y1, y2 = x0 - dk0, x1 - dk1, x2 - dk2
        if y0 != 0.0 or y1 != 0.0 or y2 != 0.0:
            kc = 3 * k
            col0, col1, col2 = ct[kc], ct[kc + 1], ct[kc + 2]  # C[:, kc], C[:, kc + 1], C[:, kc + 2]
            for j in range(m):
                for i in range(3):
                    r = 3 * j + i
                    f[j][i] += col0[r] * y0 + col1[r] * y1 + col2[r] * y2
            a0, a1, a2 = _force(g, 0.0, 0.0, 0.0, y0, y1, y2)
            change = max(change, math.sqrt(a0 * a0 + a1 * a1 + a2 * a2))
            move = max(move, math.sqrt(y0 * y0 + y1 * y1 + y2 * y2))
        d[k][0], d[k][1], d[k][2] = x0, x1, x2
        status[k] = st
        if st != SLIDE:
            has_u[k] = 0
    return OK, -1, change, move, unsolved
