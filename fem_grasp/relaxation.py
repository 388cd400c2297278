"""Static frictional contact at fixed obstacles: nodal projected Gauss–Seidel (a return mapping).

The event tracking of :mod:`fem_grasp.tracking` follows the *rate* problem of
§III-C: between events the sliding set ℙ is fixed and its slips solve
eqs. (6)–(8).  Where friction is strong compared with the coupling between
tangential slip and normal force (μ = 0.4–0.5 on coarse P1 patches), that
rate problem can have no solution: a contact leaves its cone when it sticks,
yet its slip rate is negative when it slides, or the slip system of several
coupled sliding nodes loses its root.  The body then reaches a new static
state by a finite slip, as a return mapping (backward-Euler Coulomb) does.

This module finds that state.  With the obstacles fixed and every contact
starting on its obstacle (positions q⁰_k), the unknowns are the changes δ_k
of the contact displacements; the forces are affine in them,
f = f⁰ + C δ (eq. 5).  Each contact k ends in exactly one of three states:

* **stick**: δ_k = 0 with f_k in its friction cone, f·n̂ ≥ 0 and
  |f_t| ≤ μ f·n̂ (+ ``tol`` F_s: closer than that, a slip would be round-off);
* **release**: f_k = 0 at a position outside the obstacle (event B);
* **slide**: on the obstacle (in the table plane, or on the fingertip sphere
  along the great circle of its slip, Fig. 1), with the friction on the cone
  and opposite to the slip at the new position: f_t = −μ (f·n̂) ŝ_k.

The coupled problem is solved node by node (projected Gauss–Seidel, the
classical solver of nonsmooth contact mechanics): each visit solves contact
k's own problem exactly with the others frozen — a 2×2 Newton iteration for a
slide, warm-started from the previous sweep — and updates every force by the
rank-3 change C[:, k] Δδ_k.  Sweeps repeat until no force changes by more than
``tol`` × the force scale.  For the Tresca (fixed normal force) problem this
is block coordinate descent on a convex energy and converges; the Coulomb
coupling through the normal forces makes it a fixed point that converges
when friction is not too large for the coupling, and the iteration count is
bounded either way.  Once the statuses stop changing, Newton's method on
their smooth system finishes the solve (quadratically).  Sliding that
nothing stops shows as a steady drift — the same statuses, no root for
them, and no decay of the motion from sweep to sweep — and is reported as
gross slip; statuses that keep cycling without progress (no halving of the
largest force change in 1000 sweeps) are reported too.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from .geometry import tangent_basis

__all__ = ["RelaxationFailure", "Relaxation", "relax_contacts", "STICK", "SLIDE", "RELEASE"]

log = logging.getLogger(__name__)

STICK, SLIDE, RELEASE = 0, 1, 2


#: Sweeps of unchanged statuses over which a steady drift (no decay of the motion) means gross slip.
DRIFT_SWEEPS = 300
#: ... once some contact has slid this fraction of ``max_slip``.
DRIFT_SLIP = 0.01
#: Consecutive sweeps in which some contact has no local solution before the relaxation gives up.
STUCK_SWEEPS = 50
#: Sweeps without halving the largest force change (statuses that keep cycling) before it gives up.
STALL_SWEEPS = 1000


class RelaxationFailure(RuntimeError):
    """No static stick/slip/release state was found (friction cannot hold the contacts: gross slip)."""


@dataclass(frozen=True)
class Relaxation:
    """The static state found by :func:`relax_contacts`.

    Attributes
    ----------
    displacements : (m, 3) change δ_k of each contact's displacement, metres
    forces : (m, 3) contact forces on the object, f⁰ + C δ, newtons
    normals : (m, 3) inward unit normals at the new positions
    status : (m,) STICK, SLIDE or RELEASE
    slips : (m,) length of each contact's tangential motion, metres
    sweeps : Gauss–Seidel sweeps used
    """

    displacements: np.ndarray
    forces: np.ndarray
    normals: np.ndarray
    status: np.ndarray
    slips: np.ndarray
    sweeps: int


_EYE3 = np.eye(3)


def _cross3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a × b for two 3-vectors (np.cross costs ~30 µs per call in this hot loop)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


class _Contact:
    """One contact: its start position q⁰ on a plane (normal ``up``) or a sphere (centre, radius).

    ``ckk`` is the contact's own 3×3 stiffness block C_kk.  The local solves
    below (:func:`_slide`, :func:`_ray_root`) run in plain float arithmetic:
    they are called millions of times per pickup on 3-vectors, where numpy's
    per-call overhead is most of the cost.
    """

    def __init__(self, q0: np.ndarray, center: np.ndarray | None, up: np.ndarray, ckk: np.ndarray) -> None:
        self.q0 = q0
        self.sphere = center is not None
        if self.sphere:
            self.o = center
            self.r0 = q0 - center
            self.radius = float(np.linalg.norm(self.r0))
            self.n0 = self.r0 / self.radius
        else:
            self.n0 = np.asarray(up, float)
        self.basis = tangent_basis(self.n0)
        self._basis = tuple(tuple(float(x) for x in row) for row in self.basis)
        self._n0 = tuple(float(x) for x in self.n0)
        self._r0 = tuple(float(x) for x in self.r0) if self.sphere else None
        self.ckk = ckk
        self._k = tuple(float(x) for x in ckk.reshape(-1))
        self.kmin = float(np.linalg.eigvalsh(ckk)[0])
        self.a = self.basis @ ckk @ self.basis.T  # tangential stiffness
        self.amax = float(np.abs(self.a).max())
        self.last_ray: tuple | None = None  # (question, answer) of the last _ray_root

    def motion_s(self, u0: float, u1: float) -> tuple[tuple, tuple, tuple]:
        """(δ, n̂, ŝ) as float triples for a tangential motion (u0, u1): along the great circle on a sphere."""
        (a0, a1, a2), (b0, b1, b2) = self._basis
        t0, t1, t2 = u0 * a0 + u1 * b0, u0 * a1 + u1 * b1, u0 * a2 + u1 * b2
        tl = math.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
        h0, h1, h2 = (t0 / tl, t1 / tl, t2 / tl) if tl > 0 else (0.0, 0.0, 0.0)
        if not self.sphere:
            return (t0, t1, t2), self._n0, (h0, h1, h2)
        th = tl / self.radius
        c, s = math.cos(th), math.sin(th)
        # q − q⁰ = (cos θ − 1) r⁰ + R sin θ t̂, written without cancellation for small θ
        cm1, rs = -2.0 * math.sin(0.5 * th) ** 2, self.radius * s
        (r0, r1, r2), (n0, n1, n2) = self._r0, self._n0
        return ((cm1 * r0 + rs * h0, cm1 * r1 + rs * h1, cm1 * r2 + rs * h2),
                (c * n0 + s * h0, c * n1 + s * h1, c * n2 + s * h2),
                (c * h0 - s * n0, c * h1 - s * n1, c * h2 - s * n2))

    def motion(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(δ, n̂, ŝ) for a tangential motion u (2,): along the great circle of length |u| on a sphere."""
        d, n, s = self.motion_s(float(u[0]), float(u[1]))
        return np.array(d), (self.n0 if not self.sphere else np.array(n)), np.array(s)

    def force(self, fs: tuple, d: tuple) -> tuple[float, float, float]:
        """fs + C_kk d as a float triple."""
        k00, k01, k02, k10, k11, k12, k20, k21, k22 = self._k
        d0, d1, d2 = d
        return (fs[0] + k00 * d0 + k01 * d1 + k02 * d2, fs[1] + k10 * d0 + k11 * d1 + k12 * d2,
                fs[2] + k20 * d0 + k21 * d1 + k22 * d2)

    def slide_residual(self, fs: tuple, mu: float, u0: float, u1: float) -> tuple[float, float, float]:
        """The slide equations at motion (u0, u1): f_t + μ f_n ŝ in the tangent plane there (2), and f_n."""
        d, (n0, n1, n2), (s0, s1, s2) = self.motion_s(u0, u1)
        f0, f1, f2 = self.force(fs, d)
        fn = f0 * n0 + f1 * n1 + f2 * n2
        g0, g1, g2 = f0 - fn * n0 + mu * fn * s0, f1 - fn * n1 + mu * fn * s1, f2 - fn * n2 + mu * fn * s2
        a0, a1, a2 = self._basis[0]
        an = a0 * n0 + a1 * n1 + a2 * n2
        e0, e1, e2 = a0 - an * n0, a1 - an * n1, a2 - an * n2
        el = math.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
        e0, e1, e2 = e0 / el, e1 / el, e2 / el
        c0, c1, c2 = n1 * e2 - n2 * e1, n2 * e0 - n0 * e2, n0 * e1 - n1 * e0
        return g0 * e0 + g1 * e1 + g2 * e2, g0 * c0 + g1 * c1 + g2 * c2, fn

    def cone_excess(self, fs: tuple, mu: float, u0: float, u1: float) -> float:
        """|f_t| − μ f_n at motion (u0, u1) (≤ 0: inside the cone)."""
        d, (n0, n1, n2), _ = self.motion_s(u0, u1)
        f0, f1, f2 = self.force(fs, d)
        fn = f0 * n0 + f1 * n1 + f2 * n2
        t0, t1, t2 = f0 - fn * n0, f1 - fn * n1, f2 - fn * n2
        return math.sqrt(t0 * t0 + t1 * t1 + t2 * t2) - mu * fn

    def gap(self, d: np.ndarray) -> float:
        """Separation of q⁰ + d along the start normal (≥ 0: the contact lifts off).

        Signorini's condition in the contact's own frame.  On a sphere the
        exact distance would also grow with a purely tangential motion
        (|r⁰ + t| > R), which would let a pressed contact "release" sideways
        instead of sliding; d·n̂⁰ ≥ 0 still implies |r⁰ + d| ≥ R.
        """
        return float(d @ self.n0)


def _slide(c: _Contact, fs: np.ndarray, mu: float, u0: np.ndarray | None, tol: float,
           amax: float) -> np.ndarray | None:
    """Tangential motion u with f_t = −μ f_n ŝ at the new position (f = fs + C_kk δ(u)); None if none."""
    fst = (float(fs[0]), float(fs[1]), float(fs[2]))
    if u0 is not None and np.any(u0):
        return _newton2(c, fst, mu, float(u0[0]), float(u0[1]), tol)
    ft = c.basis @ fs
    ftn = float(np.linalg.norm(ft))
    if ftn == 0.0:
        return None
    # First guess: straight back against f_t, by the linearised cone equation.
    tt = ft / ftn
    fn0 = float(fs @ c.n0)
    stiff = float(tt @ c.a @ tt)
    den = stiff - mu * float(c.n0 @ c.ckk @ c.basis.T @ tt)
    guess = -((ftn - mu * fn0) / den if den > 0 else ftn / stiff) * tt
    out = _newton2(c, fst, mu, float(guess[0]), float(guess[1]), tol)
    if out is None:
        u = _ray_root(c, fst, mu, -tt, amax)
        if u is None:
            return None
        out = _newton2(c, fst, mu, float(u[0]), float(u[1]), tol)
    if out is None:
        # Strongly anisotropic C_kk: the slip turns away from −f_t.  Fixed point on the direction (the
        # friction at the new position sets it), each step a root along a ray, then Newton again.
        for _ in range(100):
            d, n, _s = c.motion(u)
            f = fs + c.ckk @ d
            ft = c.basis @ (f - (f @ n) * n)
            ftn = float(np.linalg.norm(ft))
            if ftn == 0.0:
                return None
            u_new = _ray_root(c, fst, mu, -ft / ftn, amax)
            if u_new is None:
                return None
            done = float(np.linalg.norm(u_new - u)) <= 1e-6 * float(np.linalg.norm(u_new))
            u = u_new
            if done:
                break
        out = _newton2(c, fst, mu, float(u[0]), float(u[1]), tol)
    return out


def _ray_root(c: _Contact, fs: tuple, mu: float, e: np.ndarray, amax: float) -> np.ndarray | None:
    """u = α e with the smallest α > 0 at which the force reaches its cone, by bracketing and bisection.

    The last answer is kept on the contact: a contact with no local state asks the same question
    twice per sweep (in :func:`_slide` and for its provisional slide), and mostly the answer is None
    after a scan of the whole bracket.
    """
    e0, e1 = float(e[0]), float(e[1])
    key = (fs, mu, e0, e1, amax)
    if c.last_ray is not None and c.last_ray[0] == key:
        return None if c.last_ray[1] is None else c.last_ray[1].copy()
    out = _ray_scan(c, fs, mu, e0, e1, amax)
    c.last_ray = (key, None if out is None else out.copy())
    return out


def _ray_scan(c: _Contact, fs: tuple, mu: float, e0: float, e1: float, amax: float) -> np.ndarray | None:
    lo, hi = 0.0, None
    alpha = amax * 2.0 ** -50
    while alpha <= amax:
        if c.cone_excess(fs, mu, alpha * e0, alpha * e1) <= 0.0:
            hi = alpha
            break
        lo, alpha = alpha, 2.0 * alpha
    if hi is None:
        return None
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if c.cone_excess(fs, mu, mid * e0, mid * e1) <= 0.0:
            hi = mid
        else:
            lo = mid
        if hi - lo <= 1e-12 * hi:
            break
    return np.array([hi * e0, hi * e1])


def _backtrack(fun, x: np.ndarray, step: np.ndarray, norm: float, halvings: int) -> tuple[float, tuple] | None:
    """Armijo backtracking on ‖fun(x)[0]‖: (λ, fun(x + λ step)) for the first λ = 1, ½, … that decreases it."""
    lam = 1.0
    for _ in range(halvings):
        out = fun(x + lam * step)
        if np.linalg.norm(out[0]) < (1.0 - 1e-4 * lam) * norm:
            return lam, out
        lam *= 0.5
    return None


def _newton2(c: _Contact, fs: tuple, mu: float, u0: float, u1: float, tol: float) -> np.ndarray | None:
    """Newton's method (finite-difference 2×2 Jacobian, backtracking) on a contact's slide residual."""
    resid = c.slide_residual
    g0, g1, fn = resid(fs, mu, u0, u1)
    hmin = 1e-9 * tol / max(c.amax, 1e-300)
    for _ in range(40):
        if max(abs(g0), abs(g1)) <= tol:
            break
        h = max(1e-7 * math.hypot(u0, u1), hmin)
        p0, p1, _ = resid(fs, mu, u0 + h, u1)
        q0, q1, _ = resid(fs, mu, u0, u1 + h)
        j00, j10, j01, j11 = (p0 - g0) / h, (p1 - g1) / h, (q0 - g0) / h, (q1 - g1) / h
        det = j00 * j11 - j01 * j10
        if det == 0.0:
            return None
        s0, s1 = (j01 * g1 - j11 * g0) / det, (j10 * g0 - j00 * g1) / det
        # Armijo backtracking on the residual norm
        norm = math.hypot(g0, g1)
        lam = 1.0
        for _ in range(30):
            r0, r1, rf = resid(fs, mu, u0 + lam * s0, u1 + lam * s1)
            if math.hypot(r0, r1) < (1.0 - 1e-4 * lam) * norm:
                break
            lam *= 0.5
        else:
            return None
        u0, u1, g0, g1, fn = u0 + lam * s0, u1 + lam * s1, r0, r1, rf
    if not max(abs(g0), abs(g1)) <= tol or fn < 0.0 or (u0 == 0.0 and u1 == 0.0):
        return None
    return np.array([u0, u1])


class _SlideGeometry:
    """:meth:`_Contact.motion` and the slide projection for many sliding contacts at once (the polish)."""

    def __init__(self, contacts: list, mu: np.ndarray) -> None:
        p = len(contacts)
        self.mu = np.asarray(mu, float)
        self.e1 = np.array([ct.basis[0] for ct in contacts]).reshape(p, 3)
        self.e2 = np.array([ct.basis[1] for ct in contacts]).reshape(p, 3)
        self.n0 = np.array([ct.n0 for ct in contacts]).reshape(p, 3)
        self.sphere = np.array([ct.sphere for ct in contacts], dtype=bool)
        self.radius = np.array([ct.radius if ct.sphere else 1.0 for ct in contacts])
        self.r0 = np.array([ct.r0 if ct.sphere else np.zeros(3) for ct in contacts]).reshape(p, 3)

    def motion(self, us: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(δ, n̂, ŝ), each (p, 3), for tangential motions ``us`` (p, 2)."""
        t = us[:, :1] * self.e1 + us[:, 1:] * self.e2
        tl = np.linalg.norm(t, axis=1)
        h = np.divide(t, tl[:, None], out=np.zeros_like(t), where=tl[:, None] > 0)
        delta, n, s = t, self.n0.copy(), h.copy()
        sph = self.sphere
        if sph.any():
            th = tl[sph] / self.radius[sph]
            co, si = np.cos(th)[:, None], np.sin(th)[:, None]
            cm1 = -2.0 * np.sin(0.5 * th)[:, None] ** 2
            delta = delta.copy()
            delta[sph] = cm1 * self.r0[sph] + (self.radius[sph][:, None] * si) * h[sph]
            n[sph] = co * self.n0[sph] + si * h[sph]
            s[sph] = co * h[sph] - si * self.n0[sph]
        return delta, n, s

    def projections(self, us: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(p, 2, 3) maps f ↦ slide residual at the motions ``us``, and the slips δ (p, 3)."""
        delta, n, s = self.motion(us)
        b1 = self.e1 - np.einsum("ki,ki->k", self.e1, n)[:, None] * n
        b1 /= np.linalg.norm(b1, axis=1, keepdims=True)
        b = np.stack([b1, np.cross(n, b1)], axis=1)
        proj = _EYE3[None] - n[:, :, None] * n[:, None, :] + self.mu[:, None, None] * s[:, :, None] * n[:, None, :]
        return b @ proj, delta


def _polish(contacts: list, c: np.ndarray, f0: np.ndarray, mu: np.ndarray, status: np.ndarray,
            d: np.ndarray, u: list, tol: float, stick_tol: float, max_slip: float
            ) -> tuple[np.ndarray, list, np.ndarray] | None:
    """Newton's method on the smooth system of fixed statuses; None unless it converges and they hold.

    Unknowns: u_k (2) of each sliding contact, δ_k (3) of each released one.
    Equations: f_t + μ f_n ŝ = 0 in the tangent plane at the new position
    (sliding), f_k = 0 (released); sticking contacts keep δ_k = 0.  The
    Jacobian is assembled from per-contact blocks, ∂R_j/∂f_j C_jk ∂δ_k/∂x_k
    plus each contact's own geometric term, the geometric blocks by finite
    differences.
    """
    m = len(contacts)
    act = [k for k in range(m) if status[k] != STICK]
    if not act:
        return None
    sizes = [2 if status[k] == SLIDE else 3 for k in act]
    offs = np.concatenate([[0], np.cumsum(sizes)])
    x = np.concatenate([u[k] if status[k] == SLIDE else d[k] for k in act])
    # Per-contact data of the sliding and released contacts, for evaluations of all of them at once.
    i_s = np.array([i for i, k in enumerate(act) if status[k] == SLIDE], dtype=np.int64)
    i_r = np.array([i for i, k in enumerate(act) if status[k] == RELEASE], dtype=np.int64)
    k_s = np.array([act[i] for i in i_s], dtype=np.int64)
    k_r = np.array([act[i] for i in i_r], dtype=np.int64)
    xs_idx = offs[i_s][:, None] + np.arange(2)[None, :]  # (p, 2) positions of u_k in x
    xr_idx = offs[i_r][:, None] + np.arange(3)[None, :]  # (q, 3) positions of δ_k in x
    geo = _SlideGeometry([contacts[k] for k in k_s], mu[k_s])
    rows = np.concatenate([3 * k + np.arange(3) for k in act])
    c_act = c[np.ix_(rows, rows)]
    n_x, n_a = int(offs[-1]), 3 * len(act)
    eye_r = np.broadcast_to(_EYE3, (len(i_r), 3, 3))

    def evaluate(x: np.ndarray, with_jacobian: bool):
        us = x[xs_idx]
        a, ds = geo.projections(us)
        dd = d.copy()
        dd[k_s] = ds
        dd[k_r] = x[xr_idx]
        f = f0 + (c @ dd.reshape(-1)).reshape(m, 3)
        r = np.empty(n_x)
        r[xs_idx] = np.einsum("kij,kj->ki", a, f[k_s])
        r[xr_idx] = f[k_r]
        if not with_jacobian:
            return r, f, dd, None
        # Geometric blocks by forward differences, all sliding contacts at once.
        h = np.maximum(1e-7 * np.linalg.norm(us, axis=1), 1e-30)
        dj, ej = np.empty((len(k_s), 3, 2)), np.empty((len(k_s), 2, 2))
        for j in range(2):
            up = us.copy()
            up[:, j] += h
            ap, dp = geo.projections(up)
            dj[:, :, j] = (dp - ds) / h[:, None]
            ej[:, :, j] = np.einsum("kij,kj->ki", ap - a, f[k_s]) / h[:, None]
        amat = np.zeros((n_x, n_a))
        dmat = np.zeros((n_a, n_x))
        jac = np.zeros((n_x, n_x))
        cs = 3 * i_s[:, None] + np.arange(3)[None, :]
        cr = 3 * i_r[:, None] + np.arange(3)[None, :]
        amat[xs_idx[:, :, None], cs[:, None, :]] = a
        amat[xr_idx[:, :, None], cr[:, None, :]] = eye_r
        dmat[cs[:, :, None], xs_idx[:, None, :]] = dj
        dmat[cr[:, :, None], xr_idx[:, None, :]] = eye_r
        jac[xs_idx[:, :, None], xs_idx[:, None, :]] = ej
        jac += amat @ c_act @ dmat
        return r, f, dd, jac

    r, f, dd, jac = evaluate(x, True)
    for _ in range(20):
        norm = float(np.linalg.norm(r))
        if np.abs(r).max() <= tol:
            break
        try:
            step = -np.linalg.solve(jac, r)
        except np.linalg.LinAlgError:
            return None
        found = _backtrack(lambda y: evaluate(y, False), x, step, norm, 10)
        if found is None:
            return None
        x = x + found[0] * step
        r, f, dd, jac = evaluate(x, True)
    else:
        return None
    if np.abs(r).max() > tol:
        return None
    # The statuses must still hold at the polished state.
    u2 = list(u)
    for i, k in enumerate(act):
        xk = x[offs[i]:offs[i + 1]]
        if status[k] == SLIDE:
            _, n, _ = contacts[k].motion(xk)
            if not (f[k] @ n > 0.0 and 0.0 < float(np.linalg.norm(xk)) <= max_slip):
                return None
            u2[k] = xk
        elif contacts[k].gap(xk) < 0.0:
            return None
    for k in range(m):
        if status[k] == STICK:
            n = contacts[k].n0
            fn = float(f[k] @ n)
            if fn < 0.0 or float(np.linalg.norm(f[k] - fn * n)) > mu[k] * fn + stick_tol:
                return None
    return dd, u2, f


def relax_contacts(stiffness: np.ndarray, forces: np.ndarray, positions: np.ndarray, centers: list,
                   up: np.ndarray, mu: np.ndarray, force_scale: float, *, tol: float = 1e-11,
                   max_sweeps: int = 5000, max_slip: float = np.inf) -> Relaxation:
    """Static stick/slide/release state of every contact at fixed obstacles (module notes).

    Parameters
    ----------
    stiffness : (3m, 3m) reduced stiffness C of eq. (5) for the contact set
    forces : (m, 3) forces f⁰ at the start (every contact held at its start position)
    positions : (m, 3) start positions q⁰_k, each on its obstacle
    centers : m entries: the fingertip centre of a fingertip contact, None for a table contact
    up : (3,) the table's normal
    mu : (m,) friction coefficients
    force_scale : F_s, newtons; sweeps stop when no force changes by more than ``tol`` F_s
    max_slip : a contact sliding further than this, metres, is taken as gross slip (failure)

    Raises
    ------
    RelaxationFailure
        A contact has no stick, release or slide state with the others frozen (friction cannot hold
        it), or the sweeps do not settle within ``max_sweeps``.
    """
    c = np.asarray(stiffness, float)
    f = np.array(forces, float)
    m = len(f)
    c4 = c.reshape(m, 3, m, 3)
    ckk = [np.ascontiguousarray(c4[k, :, k, :]) for k in range(m)]
    cols = [np.ascontiguousarray(c4[:, :, k, :]) for k in range(m)]
    try:
        ckk_inv = np.linalg.inv(np.array(ckk))
    except np.linalg.LinAlgError:
        raise RelaxationFailure("a contact's own stiffness block C_kk is singular") from None
    contacts = [_Contact(np.asarray(positions[k], float), None if centers[k] is None else
                         np.asarray(centers[k], float), up, ckk[k]) for k in range(m)]
    fs_scale = max(float(force_scale), 1e-300)
    d = np.zeros((m, 3))
    u = [None] * m
    status = np.full(m, STICK)
    local_tol = 1e-3 * tol * fs_scale
    stick_tol = tol * fs_scale
    last_status = status.copy()
    next_polish, polish_fails = 2, 0
    moves: list[float] = []
    stuck = 0
    best_change, best_sweep = np.inf, 0
    for sweep in range(1, max_sweeps + 1):
        change, move = 0.0, 0.0
        unsolved = None
        for k in range(m):
            ct = contacts[k]
            fs = f[k] - ckk[k] @ d[k]  # force at k with contact k back at its start
            fn = float(fs @ ct.n0)
            ft = fs - fn * ct.n0
            # Within the sweep tolerance of its cone a contact sticks (its slip would be round-off).
            if fn >= 0.0 and float(np.sqrt(ft @ ft)) <= mu[k] * fn + stick_tol:
                dk, st = np.zeros(3), STICK
            else:
                d_free = -(ckk_inv[k] @ fs)
                if not float(np.sqrt(d_free @ d_free)) <= max_slip:  # also catches NaN
                    raise RelaxationFailure(f"contact {k} would move more than {max_slip:.3g} m to carry no "
                                            "force: the remaining contacts no longer hold the object")
                if ct.gap(d_free) >= 0.0:
                    dk, st = d_free, RELEASE
                else:
                    amax = min(max_slip, ct.radius if ct.sphere else np.inf,
                               1e3 * float(np.abs(fs).max()) / ct.kmin)
                    uk = _slide(ct, fs, float(mu[k]), u[k], local_tol, amax)
                    if uk is None and u[k] is not None:
                        uk = _slide(ct, fs, float(mu[k]), None, local_tol, amax)
                    if uk is None:
                        # No local state with the neighbours frozen.  Provisionally slide it as far as its
                        # force's own cone along −f_t (a ray root) so that the coupled Newton polish can
                        # look for a state in which its neighbours move too; the sweeps cannot converge
                        # while this lasts, and fail if it lasts STUCK_SWEEPS sweeps.
                        unsolved = (k, fs)
                        ft = ct.basis @ fs
                        ftn = float(np.linalg.norm(ft))
                        guess = (_ray_root(ct, tuple(float(x) for x in fs), float(mu[k]), -ft / ftn, amax)
                                 if ftn > 0 else None)  # the question _slide asked: answered from the contact
                        if guess is None:
                            continue
                        uk = guess
                    if float(np.sqrt(uk @ uk)) > max_slip:
                        raise RelaxationFailure(f"contact {k} slides more than {max_slip:.3g} m: friction cannot "
                                                "hold the object (gross slip)")
                    u[k] = uk
                    dk = ct.motion(uk)[0]
                    st = SLIDE
            dd = dk - d[k]
            if np.any(dd):
                f += cols[k] @ dd
                change = max(change, float(np.linalg.norm(ckk[k] @ dd)))
                move = max(move, float(np.sqrt(dd @ dd)))
            d[k] = dk
            status[k] = st
            if st != SLIDE:
                u[k] = None
        if unsolved is not None:
            stuck += 1
            if stuck > STUCK_SWEEPS:
                k, fs = unsolved
                raise RelaxationFailure(
                    f"contact {k} can neither stick, slide nor lift off with its neighbours held "
                    f"(force {fs.round(12).tolist()} N, μ = {mu[k]:g}): friction cannot hold it")
        else:
            stuck = 0
        if change <= tol * fs_scale and unsolved is None:
            break
        if change < 0.5 * best_change:
            best_change, best_sweep = change, sweep
        elif sweep - best_sweep > STALL_SWEEPS:
            raise RelaxationFailure(f"the stick/slip state stops settling after {sweep} Gauss–Seidel sweeps "
                                    f"(no progress in the last {STALL_SWEEPS}): friction cannot hold the "
                                    "contacts in a static state")
        # Once the statuses stop changing, Newton's method on their smooth system finishes the job
        # (Gauss–Seidel converges only linearly, slowly when the contacts are strongly coupled).
        if sweep >= next_polish and np.array_equal(status, last_status):
            polished = _polish(contacts, c, np.asarray(forces, float), mu, status, d, u, local_tol, stick_tol,
                               max_slip)
            if polished is not None:
                d, u, f = polished
                break
            polish_fails += 1
            next_polish = sweep + 10 * 2 ** min(polish_fails, 6)
        if not np.array_equal(status, last_status):
            moves = []
        moves.append(move)
        # Same statuses, no root for them, and the contacts move as much per sweep as 100 sweeps ago: they
        # drift together at a steady rate, which is sliding that nothing stops (gross slip).
        slid = max((float(np.sqrt(v @ v)) for v in u if v is not None), default=0.0)
        if (len(moves) > DRIFT_SWEEPS and moves[-1] > 0.5 * moves[-1 - DRIFT_SWEEPS]
                and slid > DRIFT_SLIP * max_slip):
            raise RelaxationFailure(f"the contacts keep sliding at a steady rate after {sweep} Gauss–Seidel "
                                    "sweeps: friction cannot hold the object (gross slip)")
        last_status = status.copy()
    else:
        raise RelaxationFailure(f"the stick/slip state did not settle in {max_sweeps} Gauss–Seidel sweeps "
                                "(the contacts keep sliding: friction cannot hold the object here)")
    f = np.asarray(forces, float) + (c @ d.reshape(-1)).reshape(m, 3)
    if not (np.isfinite(f).all() and np.isfinite(d).all()):
        raise RelaxationFailure("the relaxation produced non-finite forces or displacements")
    normals = np.array([contacts[k].motion(u[k])[1] if status[k] == SLIDE else contacts[k].n0 for k in range(m)])
    slips = np.array([0.0 if u[k] is None else float(np.linalg.norm(u[k])) for k in range(m)])
    log.debug("relaxation: %d sweeps, %d stick, %d slide, %d release", sweep, int((status == STICK).sum()),
              int((status == SLIDE).sum()), int((status == RELEASE).sum()))
    return Relaxation(d, f, normals, status, slips, sweep)
