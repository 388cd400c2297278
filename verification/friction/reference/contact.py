"""One static frictional contact problem: a semismooth Newton method on the Alart–Curnier equations.

The reference's unit of work.  A :class:`~verification.friction.reference.body.CondensedBody`
at gravity load factor λ touches up to three rigid obstacles — two spheres of
radius R (the fingertips ℱ₁, ℱ₂, centres O_f) and the table plane z = h
(normal +ẑ) — with Coulomb friction μ_ℱ or μ_𝒫.  The obstacles have moved
since the previous (converged) state; this module finds the new static state.

Unknowns and equations
----------------------
For a set of candidate pairs k = (node i, obstacle o) the unknowns are the
pair forces f_k ∈ ℝ³ (on the object) and the rigid part a ∈ ℝ⁶ of the
surface displacement (:mod:`verification.friction.reference.body`)::

    u_s = H (Σ_k B_kᵀ f_k + λ g) + Q a,      x_i = X_i + u_i,
    Qᵀ (Σ_k B_kᵀ f_k + λ g) = 0                          (equilibrium, 6 rows)

and, per pair, with r = x_i − O_o, the exact gap g_k = |r| − R (sphere) or
z_i − h (plane), the inward normal n̂ = r/|r| (sphere) or +ẑ, the incremental
slip s_k = (I − n̂n̂ᵀ)(r − r_ref) measured from the previous contact point
r_ref (the previous relative position, projected onto the obstacle), and
f_N = f·n̂, f_T = f − f_N n̂, the Alart–Curnier conditions (penalty ε_k > 0)::

    f_N = max(0, σ),                σ = f_N − ε g
    f_T = proj_{|·| ≤ μ max(0, σ)} (τ),   τ = f_T − ε s

which hold iff g ≥ 0, f_N ≥ 0, f_N g = 0 (Signorini) and |f_T| ≤ μ f_N with
f_T = −μ f_N s/|s| whenever s ≠ 0 (Coulomb, backward Euler in the slip).
They are written as three equations C_k = 0 in displacement units, one
branch per pair:

* free (σ ≤ 0, and not σ = 0 with g ≤ 0):  C = f / ε
* stick (|τ| ≤ μσ):                         C = g n̂ + s
* slip  (|τ| > μσ):                         C = g n̂ + (f_T − μ σ τ/|τ|) / ε

C is continuous across the branches, and its generalised Jacobian (exact
derivatives of each branch, curvature of the sphere included) gives a
semismooth Newton method: the active set and the stick/slip set are read from
the current iterate, never imposed.  Steps are full (an active-set change is
a jump); when ``MAX_FULL_STEPS`` full steps do not converge, the solve restarts
with an Armijo line search on ½‖residual‖², then with ε ×10 and ×0.1 (the
solution does not depend on ε, the path of the iterates does).  A singular
Newton matrix (a mechanism at the current iterate: too few active or sticking
pairs) gets a minimum-norm least-squares step, plus a move along the
mechanism, in the direction the unbalanced load pushes, until the first free
candidate touches (the contact the body would roll onto).

No static state: every restart fails to converge (an iterate moving a node
more than ``DIVERGED_MOTION`` × diameter counts as diverged), or in the static
state found a contact slides more than ``GROSS_MOTION`` × diameter (gross
slip), or its contacts are fewer than three or
collinear (Theorem 3: the body is not fixed).  Then :class:`NoEquilibrium` is
raised.

Candidate pairs are the surface nodes whose gap, at the previous positions and
the new obstacle positions, is below a margin, plus every pair in contact
before; after convergence any other surface node deeper than ``TOL_PENETRATION``
× diameter becomes a candidate and the solve is repeated.

Nothing here is imported from fem_grasp.
"""

from __future__ import annotations

import logging
import warnings
from dataclasses import dataclass

import numpy as np
import scipy.linalg as la

from .body import CondensedBody

log = logging.getLogger(__name__)

FINGER1, FINGER2, TABLE = 0, 1, 2
NAMES = ("finger1", "finger2", "table")
FREE, STICK, SLIP = 0, 1, 2

#: Newton converges when every C_k is below this × diameter (C is in metres) and equilibrium below this × mg:
#: four orders above round-off of positions (1e-16 × cond), far below any physical displacement.
TOL_NEWTON = 1e-12
#: A surface node deeper than this × diameter inside an obstacle, not yet a candidate, becomes one.
TOL_PENETRATION = 1e-11
#: Candidates: nodes within max(MARGIN_MOTION × obstacle motion, MARGIN_MIN × diameter) of an obstacle.
MARGIN_MOTION = 4.0
MARGIN_MIN = 0.02
#: Newton iterations with full steps before the damped restart, and with the line search.
MAX_FULL_STEPS = 25
MAX_DAMPED_STEPS = 40
#: Penalty factors tried in turn (× the node's own stiffness 1/mean diag H_ii).
EPS_FACTORS = (1.0, 10.0, 0.1)
#: Auxiliary problems of the continuation fallback (:func:`solve_continued`).
CONTINUATION_STEPS = 8
#: Candidate rounds (penetration found after a converged solve) before giving up.
MAX_ROUNDS = 30
#: A solution in which a contact slides further than this × diameter in one increment is gross slip (no static
#: state within small displacements; fem_grasp's bound on one relaxation, applied here to the whole increment).
GROSS_MOTION = 0.1
#: A Newton iterate that moves a node further than this × diameter has diverged (iterates may overshoot the
#: solution on the way, so the bound on iterates is ten times the bound on solutions).
DIVERGED_MOTION = 1.0
#: Smallest step length of the damped Newton's line search.
MIN_STEP = 1.0 / 64
#: Pivots below this × the largest one make the Newton matrix singular (a least-squares step is taken instead).
PIVOT_TOL = 1e-13


class NoEquilibrium(RuntimeError):
    """No static state was found (gross slip, lost support, or a Newton failure on every restart)."""


class PinchedNode(RuntimeError):
    """A node is in contact with two obstacles at once (not modelled, as in fem_grasp)."""


@dataclass(frozen=True)
class Obstacles:
    """Where the obstacles are: fingertip centres (2, 3) (None: no fingers), radius, table height (None: none)."""

    centers: np.ndarray | None
    radius: float
    table: float | None
    mu_finger: float
    mu_table: float

    def present(self) -> list[int]:
        out = [FINGER1, FINGER2] if self.centers is not None else []
        return out + ([TABLE] if self.table is not None else [])

    def origin(self, o: int) -> np.ndarray:
        return np.asarray(self.centers[o], float) if o != TABLE else np.array([0.0, 0.0, float(self.table)])

    def mu(self, o: np.ndarray) -> np.ndarray:
        return np.where(np.asarray(o) == TABLE, self.mu_table, self.mu_finger)

    def gaps(self, x: np.ndarray, o: int) -> np.ndarray:
        """(k,) exact gaps of points x (k, 3) from obstacle o (negative inside)."""
        if o == TABLE:
            return x[:, 2] - float(self.table)
        return np.linalg.norm(x - self.centers[o], axis=1) - self.radius


@dataclass
class StaticState:
    """A converged static state.

    Attributes
    ----------
    load : gravity load factor λ
    obstacles : the obstacles it is in equilibrium with
    nodes, owner : (p,) contact nodes and their obstacle (FINGER1, FINGER2, TABLE); only pairs in contact
    forces : (p, 3) forces on the object, newtons
    status : (p,) STICK or SLIP
    slips : (p, 3) slip of the increment that produced this state, metres
    rigid : (6,) rigid coefficients a
    surface_disp : (s, 3) surface displacements (``body.surface`` order)
    iterations : Newton iterations of the last solve
    residual : final max |C| / diameter
    """

    load: float
    obstacles: Obstacles
    nodes: np.ndarray
    owner: np.ndarray
    forces: np.ndarray
    status: np.ndarray
    slips: np.ndarray
    rigid: np.ndarray
    surface_disp: np.ndarray
    iterations: int = 0
    residual: float = 0.0

    def positions(self, body: CondensedBody) -> np.ndarray:
        """(s, 3) deformed surface positions."""
        return body.points[body.surface] + self.surface_disp

    def normals(self, body: CondensedBody) -> np.ndarray:
        """(p, 3) inward normals at the contacts."""
        x = self.positions(body)[body.slot[self.nodes]]
        out = np.tile([0.0, 0.0, 1.0], (len(self.nodes), 1))
        for f in (FINGER1, FINGER2):
            on = self.owner == f
            if on.any():
                r = x[on] - self.obstacles.centers[f]
                out[on] = r / np.linalg.norm(r, axis=1, keepdims=True)
        return out

    def on(self, o: int) -> np.ndarray:
        return self.owner == o


def _project(r: np.ndarray, kind_sphere: np.ndarray, radius: float) -> np.ndarray:
    """The slip reference: relative positions projected onto their obstacle's surface."""
    out = r.copy()
    if kind_sphere.any():
        out[kind_sphere] *= radius / np.linalg.norm(r[kind_sphere], axis=1, keepdims=True)
    out[~kind_sphere, 2] = 0.0
    return out


def ac_equations(f: np.ndarray, x: np.ndarray, sphere: np.ndarray, origin: np.ndarray, radius: float,
                 rref: np.ndarray, mu: np.ndarray, eps: np.ndarray, jacobian: bool = True):
    """The Alart–Curnier equations C_k(f_k, x_k) of every pair and their derivatives (module notes).

    Compiled by numba when it is installed (:func:`_ac_kernel`, the same formulas pair by pair), else
    :func:`ac_equations_numpy`; the tests check the two against each other and against finite differences.
    """
    if _KERNEL is None:
        return ac_equations_numpy(f, x, sphere, origin, radius, rref, mu, eps, jacobian)
    p = len(f)
    C = np.empty((p, 3))
    branch = np.empty(p, dtype=np.int64)
    Jf = np.zeros((p, 3, 3))
    Jx = np.zeros((p, 3, 3))
    n = np.empty((p, 3))
    g = np.empty(p)
    s = np.empty((p, 3))
    _KERNEL(np.ascontiguousarray(f, float), np.ascontiguousarray(x, float), np.ascontiguousarray(sphere, np.bool_),
            np.ascontiguousarray(origin, float), float(radius), np.ascontiguousarray(rref, float),
            np.ascontiguousarray(mu, float), np.ascontiguousarray(eps, float), bool(jacobian), C, branch, Jf, Jx, n, g,
            s)
    fN = np.einsum("ki,ki->k", n, f)
    extra = {"n": n, "g": g, "s": s, "fN": fN, "fT": f - fN[:, None] * n}
    return (C, branch, Jf, Jx, extra) if jacobian else (C, branch, None, None, extra)


def ac_equations_numpy(f: np.ndarray, x: np.ndarray, sphere: np.ndarray, origin: np.ndarray, radius: float,
                       rref: np.ndarray, mu: np.ndarray, eps: np.ndarray, jacobian: bool = True):
    """:func:`ac_equations` in vectorised numpy (parameters and returns there).

    Parameters
    ----------
    f, x : (p, 3) pair forces and node positions
    sphere : (p,) bool, the pair's obstacle is a sphere (else the plane z = origin_z)
    origin : (p, 3) sphere centres (a point of the plane for plane pairs)
    radius : sphere radius R
    rref : (p, 3) slip reference, relative to origin
    mu, eps : (p,) friction coefficient and penalty

    Returns
    -------
    C : (p, 3)
    branch : (p,) FREE, STICK or SLIP
    Jf, Jx : (p, 3, 3) ∂C/∂f and ∂C/∂x (only with ``jacobian``)
    extra : dict with n, g, s, fN, fT (p-arrays) for reporting
    """
    p = len(f)
    eye = np.broadcast_to(np.eye(3), (p, 3, 3))
    r = x - origin
    n = np.zeros((p, 3))
    n[:, 2] = 1.0
    g = r[:, 2].copy()
    N = np.zeros((p, 3, 3))
    if sphere.any():
        rs = r[sphere]
        rn = np.linalg.norm(rs, axis=1)
        ns = rs / rn[:, None]
        n[sphere] = ns
        g[sphere] = rn - radius
        N[sphere] = (np.eye(3) - ns[:, :, None] * ns[:, None, :]) / rn[:, None, None]
    d = r - rref
    nd = np.einsum("ki,ki->k", n, d)
    s = d - nd[:, None] * n
    fN = np.einsum("ki,ki->k", n, f)
    fT = f - fN[:, None] * n
    sig = fN - eps * g
    tau = fT - eps[:, None] * s
    tn = np.linalg.norm(tau, axis=1)
    active = (sig > 0) | ((sig == 0) & (g <= 0))
    stick = active & (tn <= mu * np.maximum(sig, 0.0))
    slip = active & ~stick
    branch = np.where(stick, STICK, np.where(slip, SLIP, FREE))
    C = f / eps[:, None]
    gn = g[:, None] * n
    C[stick] = gn[stick] + s[stick]
    t = np.zeros((p, 3))
    t[slip] = tau[slip] / tn[slip, None]
    C[slip] = gn[slip] + (fT[slip] - (mu * sig)[slip, None] * t[slip]) / eps[slip, None]
    extra = {"n": n, "g": g, "s": s, "fN": fN, "fT": fT}
    if not jacobian:
        return C, branch, None, None, extra
    nn = n[:, :, None] * n[:, None, :]
    P = eye - nn
    Nd = np.einsum("kij,kj->ki", N, d)
    Nf = np.einsum("kij,kj->ki", N, f)
    ds_dx = P - nd[:, None, None] * N - n[:, :, None] * Nd[:, None, :]
    dfT_dx = -n[:, :, None] * Nf[:, None, :] - fN[:, None, None] * N
    dsig_dx = Nf - eps[:, None] * n  # row vectors
    dtau_dx = dfT_dx - eps[:, None, None] * ds_dx
    dgn_dx = nn + g[:, None, None] * N
    Jf = np.zeros((p, 3, 3))
    Jx = np.zeros((p, 3, 3))
    free = branch == FREE
    Jf[free] = eye[free] / eps[free, None, None]
    Jx[stick] = dgn_dx[stick] + ds_dx[stick]
    if slip.any():
        ts = t[slip]
        Dt = (np.eye(3) - ts[:, :, None] * ts[:, None, :]) / tn[slip, None, None]
        ms = (mu * sig)[slip]
        e = eps[slip]
        Ps = P[slip]
        Jf[slip] = (Ps - mu[slip, None, None] * ts[:, :, None] * n[slip][:, None, :]
                    - ms[:, None, None] * Dt @ Ps) / e[:, None, None]
        Jx[slip] = dgn_dx[slip] + (dfT_dx[slip] - mu[slip, None, None] * ts[:, :, None] * dsig_dx[slip][:, None, :]
                                   - ms[:, None, None] * Dt @ dtau_dx[slip]) / e[:, None, None]
    return C, branch, Jf, Jx, extra


def _ac_pair(f, x, sphere, o, radius, rref, mu, eps, jac, C, Jf, Jx, n, s):  # pragma: no cover - compiled
    """One pair of :func:`ac_equations` (scalar code for numba); returns (branch, g)."""
    r = np.empty(3)
    for i in range(3):
        r[i] = x[i] - o[i]
    N = np.zeros((3, 3))
    if sphere:
        rn = np.sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2])
        for i in range(3):
            n[i] = r[i] / rn
        g = rn - radius
        for i in range(3):
            for j in range(3):
                N[i, j] = ((1.0 if i == j else 0.0) - n[i] * n[j]) / rn
    else:
        n[0] = 0.0
        n[1] = 0.0
        n[2] = 1.0
        g = r[2]
    d = np.empty(3)
    for i in range(3):
        d[i] = r[i] - rref[i]
    nd = n[0] * d[0] + n[1] * d[1] + n[2] * d[2]
    fN = n[0] * f[0] + n[1] * f[1] + n[2] * f[2]
    fT = np.empty(3)
    tau = np.empty(3)
    for i in range(3):
        s[i] = d[i] - nd * n[i]
        fT[i] = f[i] - fN * n[i]
        tau[i] = fT[i] - eps * s[i]
    sig = fN - eps * g
    tn = np.sqrt(tau[0] * tau[0] + tau[1] * tau[1] + tau[2] * tau[2])
    active = sig > 0 or (sig == 0 and g <= 0)
    if not active:
        for i in range(3):
            C[i] = f[i] / eps
        if jac:
            for i in range(3):
                Jf[i, i] = 1.0 / eps
        return 0, g
    stick = tn <= mu * max(sig, 0.0)
    t = np.zeros(3)
    if stick:
        for i in range(3):
            C[i] = g * n[i] + s[i]
    else:
        for i in range(3):
            t[i] = tau[i] / tn
            C[i] = g * n[i] + (fT[i] - mu * sig * t[i]) / eps
    if not jac:
        return 1 if stick else 2, g
    Nd = N @ d
    Nf = N @ f
    P = np.empty((3, 3))
    ds_dx = np.empty((3, 3))
    dfT_dx = np.empty((3, 3))
    dgn_dx = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            P[i, j] = (1.0 if i == j else 0.0) - n[i] * n[j]
            ds_dx[i, j] = P[i, j] - nd * N[i, j] - n[i] * Nd[j]
            dfT_dx[i, j] = -n[i] * Nf[j] - fN * N[i, j]
            dgn_dx[i, j] = n[i] * n[j] + g * N[i, j]
    if stick:
        for i in range(3):
            for j in range(3):
                Jx[i, j] = dgn_dx[i, j] + ds_dx[i, j]
        return 1, g
    Dt = np.empty((3, 3))
    dtau_dx = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            Dt[i, j] = ((1.0 if i == j else 0.0) - t[i] * t[j]) / tn
            dtau_dx[i, j] = dfT_dx[i, j] - eps * ds_dx[i, j]
    DtP = Dt @ P
    Dtt = Dt @ dtau_dx
    ms = mu * sig
    for i in range(3):
        for j in range(3):
            Jf[i, j] = (P[i, j] - mu * t[i] * n[j] - ms * DtP[i, j]) / eps
            Jx[i, j] = dgn_dx[i, j] + (dfT_dx[i, j] - mu * t[i] * (Nf[j] - eps * n[j]) - ms * Dtt[i, j]) / eps
    return 2, g


def _compile():
    """The numba kernel of :func:`ac_equations`, or None without numba (the numpy version is used then)."""
    try:
        import numba
    except ImportError:  # pragma: no cover - depends on the environment
        return None
    pair = numba.njit(cache=True)(_ac_pair)

    @numba.njit(cache=True)
    def ac_all(f, x, sphere, origin, radius, rref, mu, eps, jac, C, branch, Jf, Jx, n, g, s):  # pragma: no cover
        for k in range(f.shape[0]):
            b, gk = pair(f[k], x[k], sphere[k], origin[k], radius, rref[k], mu[k], eps[k], jac, C[k], Jf[k], Jx[k],
                         n[k], s[k])
            branch[k] = b
            g[k] = gk

    return ac_all


_KERNEL = _compile()


@dataclass
class _Pairs:
    nodes: np.ndarray
    owner: np.ndarray
    rref: np.ndarray
    f0: np.ndarray
    x_prev: np.ndarray


class _System:
    """The Newton system of one candidate set (module notes)."""

    def __init__(self, body: CondensedBody, obst: Obstacles, pairs: _Pairs, load: float, eps_factor: float,
                 extra_load: np.ndarray | None = None):
        self.body = body
        self.obst = obst
        self.pairs = pairs
        self.load = load
        slots = body.slot[pairs.nodes]
        self.dofs = (3 * slots[:, None] + np.arange(3)).ravel()
        self.Hpp = body.H[np.ix_(self.dofs, self.dofs)]
        self.Qp = body.Q[self.dofs]
        self.X = body.points[pairs.nodes]
        self.hgp = load * body.hg[self.dofs]
        # Given loads beside gravity (surface order, (3s,)): the continuation's fading forces (solve_continued).
        self.q_const = load * body.qg
        if extra_load is not None:
            self.hgp = self.hgp + body.H[self.dofs] @ extra_load
            self.q_const = self.q_const + body.Q.T @ extra_load
        diag = np.diagonal(self.Hpp).reshape(-1, 3).mean(axis=1)
        self.eps = eps_factor / diag
        self.eps_eq = float(np.median(self.eps))
        self.sphere = pairs.owner != TABLE
        self.origin = np.array([obst.origin(int(o)) for o in pairs.owner]).reshape(-1, 3)
        self.mu = obst.mu(pairs.owner)
        self.p = len(pairs.nodes)
        self.x_prev = pairs.x_prev

    def x(self, z: np.ndarray) -> np.ndarray:
        f, a = z[:3 * self.p], z[3 * self.p:]
        return self.X + (self.Hpp @ f + self.hgp + self.Qp @ a).reshape(-1, 3)

    def residual(self, z: np.ndarray, jacobian: bool = True):
        p = self.p
        f = z[:3 * p].reshape(-1, 3)
        C, branch, Jf, Jx, extra = ac_equations(f, self.x(z), self.sphere, self.origin, self.obst.radius,
                                                 self.pairs.rref, self.mu, self.eps, jacobian)
        eq = (self.Qp.T @ z[:3 * p] + self.q_const) / self.eps_eq
        res = np.concatenate([C.reshape(-1), eq])
        if not jacobian:
            return res, branch, None, extra
        J = np.zeros((3 * p + 6, 3 * p + 6))
        # Block-diagonal Jx times the pair compliance rows, and Jf on the diagonal blocks.
        J[:3 * p, :3 * p] = np.einsum("kij,kjm->kim", Jx, self.Hpp.reshape(p, 3, 3 * p)).reshape(3 * p, 3 * p)
        idx = np.arange(p)
        blocks = J[:3 * p, :3 * p].reshape(p, 3, p, 3)
        blocks[idx, :, idx, :] += Jf
        J[:3 * p, 3 * p:] = np.einsum("kij,kjm->kim", Jx, self.Qp.reshape(p, 3, 6)).reshape(3 * p, 6)
        J[3 * p:, :3 * p] = self.Qp.T / self.eps_eq
        return res, branch, J, extra

    def converged(self, res: np.ndarray) -> bool:
        p = self.p
        c = np.abs(res[:3 * p]).max(initial=0.0)
        e = np.abs(res[3 * p:]).max() * self.eps_eq
        return c <= TOL_NEWTON * self.body.diameter and e <= TOL_NEWTON * self.body.weight

    def _mechanism_step(self, z: np.ndarray, J: np.ndarray, res: np.ndarray, branch: np.ndarray,
                        extra: dict) -> np.ndarray:
        """Where the active pairs leave a mechanism (J singular: the body can turn or slide rigidly about its
        load-bearing contacts), move along it in the direction the unbalanced load pushes until the first free
        candidate touches: the next contact the body would roll onto.  Zero when no free candidate closes."""
        p = self.p
        _, sv, vt = np.linalg.svd(J)
        v = vt[-1]
        if sv[-1] > 1e-10 * sv[0]:
            return np.zeros_like(z)
        unbalanced = (self.Qp.T @ z[:3 * p] + self.q_const)  # net generalised load on the rigid modes
        push = float(unbalanced @ v[3 * p:])
        if push == 0.0:
            return np.zeros_like(z)
        v = np.sign(push) * v
        dx = (self.Hpp @ v[:3 * p] + self.Qp @ v[3 * p:]).reshape(-1, 3)
        dg = np.einsum("ki,ki->k", extra["n"], dx)
        free = (branch == FREE) & (dg < 0) & (extra["g"] > 0)
        if not free.any():
            return np.zeros_like(z)
        t = float((extra["g"][free] / -dg[free]).min())
        return t * v

    def newton(self, z0: np.ndarray, damped: bool, max_iter: int) -> tuple[np.ndarray, np.ndarray, dict, int]:
        z = z0.copy()
        last_branch = None
        limit = DIVERGED_MOTION * self.body.diameter
        for it in range(1, max_iter + 1):
            res, branch, J, extra = self.residual(z)
            if self.converged(res) and last_branch is not None and np.array_equal(branch, last_branch):
                slip = np.linalg.norm(extra["s"], axis=1)[branch == SLIP]
                if slip.size and slip.max() > GROSS_MOTION * self.body.diameter:
                    raise NoEquilibrium(f"gross slip: in the static state a contact slides "
                                        f"{slip.max() / self.body.diameter:.3g} × diameter in one increment "
                                        f"(more than {GROSS_MOTION})")
                act = self.pairs.nodes[branch != FREE]
                if not _fixes_body(self.body.points[act], self.body.diameter):
                    # A degenerate solution (the body turns about its contacts); another start may find a proper one.
                    raise NoEquilibrium(f"{len(act)} contact(s) left, too few or collinear to hold the body "
                                        "(Theorem 3)")
                return z, branch, extra, it
            last_branch = branch
            if self.p and np.abs(self.x(z) - self.x_prev).max() > limit:
                raise NoEquilibrium(f"Newton diverged: an iterate moves a node more than {DIVERGED_MOTION} × diameter")
            dz, singular = _solve(J, -res)
            if not np.isfinite(dz).all():
                break
            if singular:
                dz = dz + self._mechanism_step(z, J, res, branch, extra)
            if not damped:
                z = z + dz
                continue
            phi = 0.5 * res @ res
            alpha = 1.0
            while alpha > MIN_STEP:
                r2, *_ = self.residual(z + alpha * dz, jacobian=False)
                if 0.5 * r2 @ r2 <= (1 - 1e-4 * alpha) * phi:
                    break
                alpha *= 0.5
            z = z + alpha * dz
        raise NoEquilibrium(f"Newton did not converge in {max_iter} iterations ({self.p} candidate pairs)")


def _solve(J: np.ndarray, rhs: np.ndarray) -> tuple[np.ndarray, bool]:
    """J⁻¹ rhs by LU, or a least-squares (minimum-norm) step when J is singular (a mechanism at this iterate);
    returns the step and whether J was singular."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", la.LinAlgWarning)  # singular J is handled below
        lu, piv = la.lu_factor(J, check_finite=False)
    d = np.abs(np.diagonal(lu))
    if d.size and d.min() > PIVOT_TOL * d.max():
        return la.lu_solve((lu, piv), rhs, check_finite=False), False
    return la.lstsq(J, rhs, check_finite=False, cond=1e-12)[0], True


def _fixes_body(points: np.ndarray, diameter: float) -> bool:
    """Theorem 3: three or more contacts, not collinear."""
    if len(points) < 3:
        return False
    sv = np.linalg.svd(points - points.mean(axis=0), compute_uv=False)
    return bool(sv[1] > 1e-9 * diameter)


def solve_static(body: CondensedBody, obst: Obstacles, prev_positions: np.ndarray, prev_obst: Obstacles,
                 prev_nodes: np.ndarray, prev_owner: np.ndarray, prev_forces: np.ndarray, prev_rigid: np.ndarray,
                 load: float, extra_load: np.ndarray | None = None, warm_positions: np.ndarray | None = None
                 ) -> StaticState:
    """The static state after the obstacles moved from ``prev_obst`` to ``obst`` (module notes).

    Parameters
    ----------
    body : CondensedBody
    obst, prev_obst : obstacles now and at the previous state (same set of obstacles present, or fewer now)
    prev_positions : (s, 3) surface positions of the previous state (the slip references)
    prev_nodes, prev_owner, prev_forces : the previous contacts and forces (warm start; always candidates)
    prev_rigid : (6,) previous rigid coefficients (warm start)
    load : gravity load factor λ
    extra_load : (3s,) given forces on the surface nodes besides gravity (the continuation's), or None
    warm_positions : (s, 3) where the candidates are looked for when the warm start is not the previous state
        (the continuation's intermediate solutions); default ``prev_positions``

    Raises
    ------
    NoEquilibrium
        No static state found.
    PinchedNode
        A node ends in contact with two obstacles.
    """
    diam = body.diameter
    present = obst.present()
    surf = body.surface
    prev_pairs = {(int(k), int(o)): np.asarray(fv, float) for k, o, fv in zip(prev_nodes, prev_owner, prev_forces)
                  if int(o) in present}
    cand: dict[tuple[int, int], None] = {key: None for key in prev_pairs}
    for o in present:
        if o == TABLE:
            motion = abs(float(obst.table) - float(prev_obst.table)) if prev_obst.table is not None else 0.0
        else:
            motion = float(np.linalg.norm(obst.centers[o] - prev_obst.centers[o]))
        margin = max(MARGIN_MOTION * motion, MARGIN_MIN * diam)
        for j in np.flatnonzero(obst.gaps(prev_positions, o) < margin):
            cand[(int(surf[j]), o)] = None
        if warm_positions is not None:
            for j in np.flatnonzero(obst.gaps(warm_positions, o) < margin):
                cand[(int(surf[j]), o)] = None
    rigid0 = np.asarray(prev_rigid, float)
    for rnd in range(MAX_ROUNDS):
        keys = sorted(cand)
        nodes = np.array([k for k, _ in keys], dtype=np.int64)
        owner = np.array([o for _, o in keys], dtype=np.int64)
        f0 = np.array([prev_pairs.get(key, np.zeros(3)) for key in keys]).reshape(-1, 3)
        r_prev = prev_positions[body.slot[nodes]] - np.array([prev_obst.origin(int(o)) for o in owner]).reshape(-1, 3)
        rref = _project(r_prev, owner != TABLE, obst.radius)
        pairs = _Pairs(nodes, owner, rref, f0, prev_positions[body.slot[nodes]])
        z0 = np.concatenate([f0.reshape(-1), rigid0])
        errors = []
        for factor in EPS_FACTORS:
            system = _System(body, obst, pairs, load, factor, extra_load)
            for damped, iters in ((False, MAX_FULL_STEPS), (True, MAX_DAMPED_STEPS)):
                try:
                    z, branch, extra, its = system.newton(z0, damped, iters)
                    break
                except NoEquilibrium as exc:
                    errors.append(str(exc))
            else:
                continue
            break
        else:
            raise NoEquilibrium(f"no static state at λ = {load:.6g}: " + "; ".join(errors[-2:]))
        p = len(nodes)
        f = z[:3 * p].reshape(-1, 3)
        a = z[3 * p:]
        us = body.surface_displacements(nodes, f, load, a)
        if extra_load is not None:
            us = us + (body.H @ extra_load).reshape(-1, 3)
        pos = body.points[surf] + us
        active = branch != FREE
        # Penetration of nodes that are not candidates for that obstacle.
        added = False
        have = set(keys)
        for o in present:
            deep = np.flatnonzero(obst.gaps(pos, o) < -TOL_PENETRATION * diam)
            for j in deep:
                key = (int(surf[j]), o)
                if key not in have:
                    cand[key] = None
                    added = True
        if added:
            prev_pairs.update({key: fv for key, fv in zip(keys, f)})
            rigid0 = a
            continue
        act_nodes = nodes[active]
        if len(np.unique(act_nodes)) < len(act_nodes):
            dup = act_nodes[np.flatnonzero(np.diff(np.sort(act_nodes)) == 0)[0]]
            raise PinchedNode(f"node {int(dup)} touches two obstacles at once (pinched nodes are not modelled)")
        if not _fixes_body(body.points[act_nodes], diam):
            raise NoEquilibrium(f"{len(act_nodes)} contact(s) left, too few or collinear to hold the body (Theorem 3)")
        res, *_ = system.residual(z, jacobian=False)
        return StaticState(load, obst, nodes[active], owner[active], f[active].copy(), branch[active].copy(),
                           extra["s"][active].copy(), a.copy(), us, its,
                           float(np.abs(res[:3 * p]).max(initial=0.0)) / diam)
    raise NoEquilibrium(f"contacts kept appearing after {MAX_ROUNDS} rounds at λ = {load:.6g}")


def solve_continued(body: CondensedBody, obst: Obstacles, prev: StaticState, load: float, *,
                    fade: tuple[np.ndarray, np.ndarray] | None = None, steps: int = CONTINUATION_STEPS
                    ) -> StaticState:
    """The same static problem as :func:`solve_static` from ``prev`` (slip measured from ``prev``), found by
    continuation in its data: a sequence of auxiliary static problems, **all with the slip reference of
    ``prev``**, in which the load factor goes from ``prev.load`` to ``load`` and the forces ``fade`` = (nodes,
    forces) of contacts that the new problem no longer has (the table's, when the lift test removes it) fade
    from their value to zero; each solve starts from the one before.  The last auxiliary problem *is* the
    problem, so its solution is a solution of the one static problem — the branch connected to ``prev``,
    which a Newton iteration started far from it may miss.  Raises :class:`NoEquilibrium` when a step fails.
    """
    ref_pos = prev.positions(body)
    cur = prev
    ext0 = None
    if fade is not None and len(fade[0]):
        ext0 = np.zeros(3 * body.n_surface)
        slots = body.slot[np.asarray(fade[0], dtype=np.int64)]
        np.add.at(ext0.reshape(-1, 3), slots, np.asarray(fade[1], float))
    for j in range(1, steps + 1):
        t = j / steps
        lam = prev.load + t * (load - prev.load)
        extra = None if ext0 is None or j == steps else (1.0 - t) * ext0
        cur = solve_static(body, obst, ref_pos, prev.obstacles, cur.nodes, cur.owner, cur.forces, cur.rigid, lam,
                           extra, warm_positions=cur.positions(body))
    return cur


def incremental_residual(body: CondensedBody, state: StaticState, prev_positions: np.ndarray,
                         prev_obst: Obstacles, *, eps_factor: float = 1.0) -> dict[str, float]:
    """How far a state (from any solver) is from solving the incremental problem from a previous state.

    The state's contacts are taken as the candidate pairs, every other surface node as free; the
    Alart–Curnier equations C_k = 0 are evaluated with the state's own forces and positions and the slip
    measured from ``prev_positions`` (the previous increment's contact points).  Returns the largest |C_k| over
    the contacts (× 1/diameter), the largest penetration of the other surface nodes (× 1/diameter), the
    equilibrium residual (× 1/mg), and the branch each contact lands on (stick or slip), which need not be the
    one the other solver reported: a contact on its cone with zero slip is both.
    """
    nodes, owner = state.nodes, state.owner
    r_prev = prev_positions[body.slot[nodes]] - np.array([prev_obst.origin(int(o)) for o in owner]).reshape(-1, 3)
    rref = _project(r_prev, owner != TABLE, state.obstacles.radius)
    pairs = _Pairs(nodes, owner, rref, state.forces, prev_positions[body.slot[nodes]])
    system = _System(body, state.obstacles, pairs, state.load, eps_factor)
    z = np.concatenate([state.forces.reshape(-1), state.rigid])
    res, branch, _, extra = system.residual(z, jacobian=False)
    p = len(nodes)
    pos = state.positions(body)
    pen = 0.0
    for o in state.obstacles.present():
        mine = np.zeros(len(pos), bool)
        mine[body.slot[nodes[owner == o]]] = True
        g = state.obstacles.gaps(pos, o)
        if (~mine).any():
            pen = max(pen, float(max(0.0, -g[~mine].min())))
    # The state's displacement field must be the elastic response to its forces (else C is meaningless).
    fit = body.surface_displacements(nodes, state.forces, state.load, state.rigid)
    return {"contact": float(np.abs(res[:3 * p]).max(initial=0.0)) / body.diameter,
            "penetration": pen / body.diameter,
            "equilibrium": float(np.abs(res[3 * p:]).max()) * system.eps_eq / body.weight,
            "field": float(np.abs(fit - state.surface_disp).max()) / body.diameter,
            "branch": branch}
