"""The coupled slip system of eqs. (6)–(8) for one increment of the event tracking (paper §III-A, §III-C).

Each sliding node k moves by δ_k, affine in its own unknowns, and the contact
forces are affine in all of them, ``F(x) = F_held + C δ(x)`` (eq. 5); the
system asks every sliding node to sit on its friction cone — on the table
(eq. 6), sliding by −d_k t̂_k in the plane, or on a fingertip (eq. 7), moving
along the great circle q_k = O + c_k r_k + s_k (N̂_k × r_k) with
c_k² + s_k² = 1 (eq. 8).  :class:`MixedSlipSystem` builds it from the held
prediction of :class:`~fem_grasp.contact.tracking.Tracker` and solves it by
Newton's method (the compiled kernels of
:mod:`~fem_grasp.contact.kernels.slip_newton`), with the Newton-homotopy
continuation of paper footnote 2 (:mod:`~fem_grasp.contact.homotopy`) as
fallback; :meth:`MixedSlipSystem.rates` gives the slip rates that event D
watches.
"""

from __future__ import annotations

import contextlib
import warnings
from typing import Sequence

import numpy as np
import scipy.linalg as la

from ..elastic.response import contact_dofs
from . import homotopy
from .kernels import jit, slip_homotopy, slip_newton, slip_trial
from .kernels.jit import sample_contacts, warm_up_sample
from .obstacles import FINGER1, TABLE, cross_rows, great_circle_axes, tangent_bases

__all__ = ["CompiledSlipSystem", "HOMOTOPY_TOL", "MixedSlipSystem", "NEWTON_MAX_ITER", "NEWTON_TOL",
           "REVERSED_FRICTION", "SINGULAR_PIVOT", "SLIP_HOMOTOPY_MIN_STEP", "SLIP_HOMOTOPY_STEPS", "SlipFailure"]

#: The slip-rate Jacobian is taken as singular (a friction limit: no rates) when its smallest LU pivot is
#: below this fraction of its largest.
SINGULAR_PIVOT = 1e-14
#: A compressive sliding contact whose friction points against its slip direction by more than this fraction
#: of |f_t| sits on the far root through the cone's axis: not admissible.
REVERSED_FRICTION = 1e-6
#: Residual (of the scaled system) at which the homotopy's path ends; Newton polishes to ``tol`` from there.
HOMOTOPY_TOL = 1e-8
#: The homotopy gives up after this many continuation steps, or when its step in t falls below the minimum
#: (the path has a turning point: the sliding set has no root there).
SLIP_HOMOTOPY_STEPS = 200
SLIP_HOMOTOPY_MIN_STEP = 1e-6
#: Newton's method on a slip system: converged when every scaled row is within this (or its round-off floor);
#: it gives up after ``NEWTON_MAX_ITER`` iterations (a root lost beyond a turning point takes ~40 residuals).
NEWTON_TOL = 1e-12
NEWTON_MAX_ITER = 40


class SlipFailure(RuntimeError):
    """A slip system has no admissible root near the held state."""


class MixedSlipSystem:
    """The coupled slip system of eqs. (6)–(8) for one increment.

    Each sliding node k moves by δ_k, affine in its own unknowns, and the
    contact forces are affine in all of them, ``F(x) = F_held + C δ(x)``
    (eq. 5).  Two forms are built:

    * **great circle** (``free=False``, the paper's): a table node moves by
      δ_k = −d_k t̂_k (unknown d_k); a fingertip node moves on the great
      circle through it whose plane holds its normal and its tangential
      force, q_k = O + c_k r_k + s_k (N̂_k × r_k) (unknowns c_k, s_k).
      Equations: (6) or (7) at every sliding node, (8) c_k² + s_k² = 1.
    * **free direction** (``free=True``, Coulomb's law with maximum
      dissipation): a table node moves by δ_k = a_k ê₁ + b_k ê₂; a fingertip
      node to q_k = O + c_k r_k + u_k (ê₁ × r_k) + v_k (ê₂ × r_k) — the great
      circle with an unknown axis N̂_k ∝ (u_k ê₁ + v_k ê₂) — with
      c_k² + u_k² + v_k² = 1 (eq. 8).  The extra equation per node,
      n̂_k · (f_k × δ_k) = 0, makes the friction parallel to the slip.  Used
      when the great-circle system has no root near the held state: a node
      that must slide far (e.g. one that starts to slide just after it
      touched) can acquire a friction component across a frozen direction
      that no slip along it removes.

    The fingertip unknown c_k is carried as c_k = 1 + γ_k (held state γ = 0):
    the slip δ_k = γ_k r_k + … then has no −r_k offset, whose force C r_k
    (~E·R) would otherwise bury a lightly loaded contact's force in round-off.

    The cone of a fingertip node uses the normal at its new position,
    n̂_k = (q_k − O)/R; the table normal is ẑ.  r_k = p̃_k − O is the node's
    position relative to the fingertip centre before the increment.

    Parameters
    ----------
    stiffness : (3m, 3m) reduced stiffness C
    held_forces : (m, 3) forces of the held prediction
    force_rate : (m, 3) dF_held/dt (for the slip rates of event D)
    sliding : (p,) positions of the sliding nodes in the contact set
    kinds : (p,) TABLE or a finger code per sliding node
    mu : (p,) friction coefficients
    directions : (p, 3) unit tangential force directions t̂_k of the held prediction
    radii_vectors : (p, 3) finger: r_k (|r_k| = R); ignored for table nodes
    up : (3,) the table's normal
    radius : fingertip radius R
    free : bool, the free-direction form
    """

    def __init__(self, stiffness: np.ndarray, held_forces: np.ndarray, force_rate: np.ndarray,
                 sliding: np.ndarray, kinds: np.ndarray, mu: np.ndarray, directions: np.ndarray,
                 radii_vectors: np.ndarray, up: np.ndarray, radius: float, free: bool = False) -> None:
        self.c = stiffness
        self.fh = held_forces
        self.df = force_rate
        self.sliding = np.asarray(sliding, dtype=np.int64)
        self.kinds = np.asarray(kinds, dtype=np.int64)
        self.mu = np.asarray(mu, dtype=float)
        self.t_held = np.asarray(directions, dtype=float)
        self.radius = float(radius)
        self.free = bool(free)
        m = len(held_forces)
        p = len(self.sliding)
        self.finger = self.kinds != TABLE
        self.n0 = np.broadcast_to(np.asarray(up, float), (p, 3)).copy()
        self.kappa = np.where(self.finger, 1.0 / self.radius, 0.0)
        # Per-node layouts, built for all nodes at once: node j's unknowns are x[loc_idx[j, :k_j]] and
        # its slip is δ_j = loc_e[j] @ x[loc_idx[j]] (index n points at a padding zero).
        fi = np.flatnonzero(self.finger)
        ta = np.flatnonzero(~self.finger)
        r = np.asarray(radii_vectors, dtype=float).reshape(-1, 3)[fi] if len(fi) else np.zeros((0, 3))
        t = self.t_held
        self.loc_e = np.zeros((p, 3, 3))
        if len(fi):
            nrm = r / self.radius
            self.n0[fi] = nrm
            self.loc_e[fi, :, 0] = r
            if free:
                e12 = tangent_bases(nrm)
                self.loc_e[fi, :, 1] = cross_rows(e12[:, 0], r)
                self.loc_e[fi, :, 2] = cross_rows(e12[:, 1], r)
            else:
                axis = great_circle_axes(nrm, t[fi])
                self.loc_e[fi, :, 1] = cross_rows(axis, r)
        if len(ta):
            if free:
                e12 = tangent_bases(self.n0[ta])
                self.loc_e[ta, :, 0] = e12[:, 0]
                self.loc_e[ta, :, 1] = e12[:, 1]
            else:
                self.loc_e[ta, :, 0] = -t[ta]
        # Unknowns (γ_k, s_k) with c_k = 1 + γ_k: δ_k = γ_k r_k + s_k N̂_k × r_k carries no −r_k offset, whose
        # product with C (~E·R) would swamp a small contact force in round-off.  Every unknown starts at 0.
        sizes = np.where(self.finger, 3 if free else 2, 2 if free else 1)
        first = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64)
        n = int(sizes.sum())
        self.n = n
        self.x0 = np.zeros(n)
        slot = np.arange(3)
        valid = slot[None, :] < sizes[:, None]
        self.loc_idx = np.where(valid, first[:, None] + slot[None, :], n)
        # ∂δ_j/∂x: column loc_idx[j, c] of node j's block is loc_e[j, :, c] (padding column n, dropped).
        d_map = np.zeros((p, n + 1, 3))
        d_map[np.arange(p)[:, None], self.loc_idx] = self.loc_e.transpose(0, 2, 1)
        self.d_map = np.ascontiguousarray(d_map[:, :n].transpose(0, 2, 1))
        e = np.zeros((3 * m, n))
        e.reshape(m, 3, n)[self.sliding] = self.d_map
        self.e = e
        self.g = stiffness @ e  # dF/dx
        self.g_sl = self.g.reshape(m, 3, n)[self.sliding]  # (p, 3, N)
        self.base = held_forces.reshape(-1)  # δ(0) = 0: the held state
        # Scales: distance unknowns by the slip that changes the force by its own size; the
        # dimensionless fingertip unknowns by one.
        fscale = float(np.abs(held_forces).max()) if held_forces.size else 1.0
        self.own = np.maximum(np.linalg.norm(held_forces[self.sliding], axis=1), 1e-12 * max(fscale, 1e-300))
        self.xscale = np.ones(n)
        gnorm = np.linalg.norm(self.g, axis=0)
        if len(ta):
            idx = self.loc_idx[ta]
            ok = idx < n
            own_t = np.broadcast_to(self.own[ta, None], idx.shape)[ok]
            g_t = gnorm[idx[ok]]
            self.xscale[idx[ok]] = np.where(g_t > 0, own_t / np.where(g_t > 0, g_t, 1.0), 1.0)
        self.sphere_rows = fi
        self.align_rows = np.arange(p) if free else np.zeros(0, dtype=np.int64)
        n_sph, n_al = len(self.sphere_rows), len(self.align_rows)
        if p + n_sph + n_al != n:
            raise ValueError("the slip system is not square")
        if free:
            xs = np.append(self.xscale, 0.0)[self.loc_idx]  # padding slots read 0
            mean_scale = xs.sum(axis=1) / sizes
            typical = self.own * np.where(self.finger, self.radius, mean_scale)
        else:
            typical = np.zeros(0)
        self.row_scale = np.concatenate([1.0 / self.own**2, np.ones(n_sph), 1.0 / np.maximum(typical, 1e-300)])
        # Round-off in a force is ~ε·max|F|: a lightly loaded node's normalised rows are only
        # resolved to that relative to its own force.
        eps = np.finfo(float).eps
        self.row_noise = np.concatenate([10.0 * eps * fscale / self.own, np.zeros(n_sph),
                                         10.0 * eps * fscale / self.own[self.align_rows]])
        self.sph_idx = self.loc_idx[fi, :3 if free else 2] if n_sph else np.zeros((0, 2), dtype=np.int64)
        self.g_sl2 = self.g_sl.reshape(3 * p, n)
        self.base_sl = self.base.reshape(-1, 3)[self.sliding].reshape(-1)
        self._xpad = np.zeros(n + 1)
        # The arguments of the slip_newton kernels after x.
        self._kernel_args = (np.ascontiguousarray(self.base_sl), np.ascontiguousarray(self.g_sl2),
                             self.d_map.reshape(3 * p, n), np.ascontiguousarray(self.n0),
                             np.ascontiguousarray(self.kappa), np.ascontiguousarray(self.mu),
                             np.ascontiguousarray(self.sph_idx, dtype=np.int64), self.free)

    # --------------------------------------------------------------- maps
    def forces(self, x: np.ndarray) -> np.ndarray:
        return (self.base + self.g @ x).reshape(-1, 3)

    def displacements(self, x: np.ndarray) -> np.ndarray:
        """(m, 3) change of the contact displacements from the held prediction."""
        return (self.e @ x).reshape(-1, 3)

    def slips(self, x: np.ndarray) -> np.ndarray:
        """(p, 3) δ_k of the sliding nodes."""
        xp = self._xpad
        xp[:-1] = x
        xe = xp[self.loc_idx]  # (p, 3)
        return (self.loc_e * xe[:, None, :]).sum(axis=2)

    def _sliding_forces(self, x: np.ndarray) -> np.ndarray:
        return (self.base_sl + self.g_sl2 @ x).reshape(-1, 3)

    def normals(self, x: np.ndarray) -> np.ndarray:
        """(p, 3) normals at the sliding nodes (fingertip: at q_k)."""
        return self.n0 + self.kappa[:, None] * self.slips(x)  # fingertip: (r + δ)/R

    @np.errstate(over="ignore", invalid="ignore")
    def residual(self, x: np.ndarray) -> np.ndarray:
        """The system's equations at x: cone (6)/(7) per sliding node, (8) per fingertip node, alignment."""
        return self._residual(x)

    @np.errstate(over="ignore", invalid="ignore")
    def jacobian(self, x: np.ndarray) -> np.ndarray:
        """∂residual/∂x."""
        return self._jacobian(x)

    # The raw versions run inside an errstate of the caller (solve, once, not once per evaluation).
    def _residual(self, x: np.ndarray) -> np.ndarray:
        return slip_newton.residual(np.ascontiguousarray(x, dtype=float), *self._kernel_args)

    def _jacobian(self, x: np.ndarray) -> np.ndarray:
        return slip_newton.jacobian(np.ascontiguousarray(x, dtype=float), *self._kernel_args)

    def residual_rate(self, x: np.ndarray) -> np.ndarray:
        """∂residual/∂t at fixed x (held forces move at ``force_rate``)."""
        f = self._sliding_forces(x)
        n = self.normals(x)
        df = self.df[self.sliding]
        fn = np.einsum("ki,ki->k", f, n)
        cone = 2.0 * (1.0 + self.mu**2) * fn * np.einsum("ki,ki->k", n, df) - 2.0 * np.einsum("ki,ki->k", f, df)
        out = [cone, np.zeros(len(self.sphere_rows))]
        if len(self.align_rows):
            d = self.slips(x)
            out.append(np.einsum("ki,ki->k", df, cross_rows(d, n)))
        return np.concatenate(out)

    def _friction_directions(self, x: np.ndarray) -> np.ndarray:
        f = self.forces(x)[self.sliding]
        n = self.normals(x)
        ft = f - np.einsum("ki,ki->k", f, n)[:, None] * n
        norm = np.linalg.norm(ft, axis=1, keepdims=True)
        return np.where(norm > 0, ft / np.where(norm > 0, norm, 1.0), self.t_held)

    def amounts(self, x: np.ndarray) -> np.ndarray:
        """(p,) slip of each sliding node against its friction in this increment, −t̂_k·δ_k, metres."""
        return -np.einsum("ki,ki->k", self._friction_directions(x), self.slips(x))

    def rates(self, x: np.ndarray) -> np.ndarray:
        """(p,) d(slip)/dt = −t̂_k·dδ_k/dt by the implicit-function theorem; NaN if the Jacobian is singular."""
        if not len(self.sliding):
            return np.zeros(0)
        jac = self.jacobian(x) * self.row_scale[:, None]
        rhs = -self.residual_rate(x) * self.row_scale
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", la.LinAlgWarning)
                lu = la.lu_factor(jac, check_finite=True)
            if np.abs(np.diag(lu[0])).min() <= SINGULAR_PIVOT * np.abs(np.diag(lu[0])).max():
                raise la.LinAlgError("singular")
            dx = la.lu_solve(lu, rhs)
        except (la.LinAlgError, ValueError):
            return np.full(len(self.sliding), np.nan)
        return -np.einsum("ki,ki->k", self._friction_directions(x), np.einsum("kij,j->ki", self.d_map, dx))

    def outcome(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """What an increment reads at the root x: (forces (m, 3), displacement changes (m, 3), slip amounts (p,),
        slip rates (p,))."""
        return self.forces(x), self.displacements(x), self.amounts(x), self.rates(x)

    def admissible(self, x: np.ndarray) -> bool:
        """No compressive sliding contact has its friction reversed (the far root through the cone's axis).

        A sliding contact whose normal force has become tensile is left to the
        event test B (its root continues through the cone's apex).
        """
        f = self.forces(x)[self.sliding]
        n = self.normals(x)
        fn = np.einsum("ki,ki->k", f, n)
        ft = f - fn[:, None] * n
        along = np.einsum("ki,ki->k", ft, self.t_held)
        return bool(np.all((fn <= 0) | (along >= -REVERSED_FRICTION * np.linalg.norm(ft, axis=1))))

    @np.errstate(over="ignore", invalid="ignore")
    def _newton(self, y: np.ndarray, tol: float, max_iter: int = NEWTON_MAX_ITER) -> np.ndarray | None:
        """Damped Newton's method on the scaled system (:func:`fem_grasp.contact.kernels.slip_newton.newton`); None if it fails.

        Converged when every row |P_j| ≤ max(tol, noise_j) (rows of lightly
        loaded nodes are only resolved to round-off), or when the step
        stalls within 10 times that.
        """
        ok, y = slip_newton.newton(np.array(y, dtype=float), np.maximum(tol, self.row_noise), max_iter, self.xscale,
                                   self.row_scale, *self._kernel_args)
        return y if ok else None

    @np.errstate(over="ignore", invalid="ignore")
    def solve(self, tol: float = NEWTON_TOL, methods: Sequence[str] = ("newton", "homotopy"),
              start: np.ndarray | None = None) -> np.ndarray:
        """The root continuously connected to the held state; raises :class:`SlipFailure`.

        ``"newton"``: damped Newton's method from the held state, then, if
        that fails and ``start`` is given, from ``start`` (the root of the
        same sliding set at a nearby parameter: continuation along the path);
        ``"homotopy"``: the Newton-homotopy continuation
        ``H(y, t) = P(y) − (1−t)² P(y₀)`` of paper footnote 2
        (:func:`fem_grasp.contact.homotopy.track`), whose path shrinks every cone
        residual from its held value to zero.
        """
        if self.n == 0:
            return np.zeros(0)
        scale = self.xscale
        rs = self.row_scale

        def fun(y: np.ndarray) -> np.ndarray:
            return rs * self._residual(y * scale)

        def jac(y: np.ndarray) -> np.ndarray:
            return rs[:, None] * self._jacobian(y * scale) * scale[None, :]

        y0 = self.x0 / scale
        attempts: list[str] = []
        y = None
        if "newton" in methods:
            y = self._newton(y0, tol)
            if y is not None:
                x = y * scale
                if self.admissible(x):
                    return x
                attempts.append("Newton reached a non-physical root")
            else:
                attempts.append("Newton did not converge")
            if start is not None and len(start) == self.n and np.isfinite(start).all():
                y = self._newton(start / scale, tol)
                if y is not None and self.admissible(y * scale):
                    return y * scale
                attempts.append("Newton from the nearby root did not converge")
        if "homotopy" in methods:
            p0 = fun(y0)
            try:
                res = homotopy.track(fun, jac, y0, start=lambda y: fun(y) - p0, start_jac=jac, tol=HOMOTOPY_TOL,
                                     initial_step=homotopy.SLIP_INITIAL_STEP, max_step=homotopy.SLIP_MAX_STEP,
                                     max_steps=SLIP_HOMOTOPY_STEPS, min_step=SLIP_HOMOTOPY_MIN_STEP)
                y = self._newton(np.asarray(res.x, dtype=float), tol)
                if y is not None and self.admissible(y * scale):
                    return y * scale
                attempts.append("homotopy reached a non-physical root")
            except homotopy.HomotopyError as exc:
                attempts.append(f"homotopy: {exc}")
        r = np.abs(fun(y0 if y is None else y))
        worst = int(np.argmax(r))
        j = worst if worst < len(self.sliding) else (
            int(self.sphere_rows[worst - len(self.sliding)]) if worst < len(self.sliding) + len(self.sphere_rows)
            else int(self.align_rows[worst - len(self.sliding) - len(self.sphere_rows)]))
        raise SlipFailure(f"no admissible slip for {len(self.sliding)} sliding node(s) "
                          f"({'free' if self.free else 'great-circle'} form; worst row {worst} at contact "
                          f"{int(self.sliding[j])}, held force {self.own[j]:.3g} N): " + "; ".join(attempts))


def _quiet() -> contextlib.AbstractContextManager:
    """numpy's overflow and invalid-value warnings off around a kernel that runs as plain numpy (without numba,
    whose compiled code raises none)."""
    return contextlib.nullcontext() if jit.ENABLED else np.errstate(over="ignore", invalid="ignore")


#: Newton iterations of the homotopy's final polish (``homotopy.track``'s default, as MixedSlipSystem uses it).
_HOMOTOPY_POLISH_ITER = homotopy.TRACK_MAX_ITER


class CompiledSlipSystem:
    """:class:`MixedSlipSystem` assembled, solved (Newton's method, the Newton homotopy as fallback) and read out in
    compiled kernels (:mod:`~fem_grasp.contact.kernels.slip_trial`): the same unknowns, scales, tolerances and
    messages, a few kernel calls per increment instead of about a hundred numpy operations.

    Parameters are those of :class:`MixedSlipSystem`.
    """

    def __init__(self, stiffness: np.ndarray, held_forces: np.ndarray, force_rate: np.ndarray,
                 sliding: np.ndarray, kinds: np.ndarray, mu: np.ndarray, directions: np.ndarray,
                 radii_vectors: np.ndarray, up: np.ndarray, radius: float, free: bool = False) -> None:
        self.free = bool(free)
        self.sliding = np.ascontiguousarray(sliding, dtype=np.int64)
        self.kinds = np.ascontiguousarray(kinds, dtype=np.int64)
        self.mu = np.ascontiguousarray(mu, dtype=float)
        self.t_held = np.ascontiguousarray(directions, dtype=float)
        self.fh = np.ascontiguousarray(held_forces, dtype=float)
        self.df = np.ascontiguousarray(force_rate, dtype=float)
        (self.g, self.dmap, self.n0, self.kappa, self.sph, self.xscale, self.row_scale, self.row_noise,
         self.own) = slip_trial.assemble(np.ascontiguousarray(stiffness, dtype=float), self.fh, self.sliding,
                                         self.kinds, self.mu, self.t_held,
                                         np.ascontiguousarray(radii_vectors, dtype=float).reshape(-1, 3),
                                         np.ascontiguousarray(up, dtype=float), float(radius), self.free)
        self.n = self.g.shape[1]
        rows = contact_dofs(self.sliding)
        self.base_sl = self.fh.reshape(-1)[rows]
        self.g_sl = self.g[rows]  # (fancy indexing copies: C-contiguous)

    @property
    def sphere_rows(self) -> np.ndarray:
        """Positions in ``sliding`` of the fingertip nodes (one sphere row each); only failure messages read it."""
        return np.flatnonzero(self.kinds != TABLE)

    @property
    def align_rows(self) -> np.ndarray:
        """Positions in ``sliding`` of the alignment rows (the free form's)."""
        return np.arange(len(self.sliding)) if self.free else np.zeros(0, dtype=np.int64)

    def _newton(self, y: np.ndarray, tol: float) -> tuple[bool, bool, np.ndarray]:
        with _quiet():
            return slip_trial.newton_root(np.array(y, dtype=float), np.maximum(tol, self.row_noise), self.xscale,
                                          self.row_scale, self.base_sl, self.g_sl, self.dmap, self.n0, self.kappa,
                                          self.mu, self.sph, self.free, self.t_held, NEWTON_MAX_ITER)

    def solve(self, tol: float = NEWTON_TOL, methods: Sequence[str] = ("newton", "homotopy"),
              start: np.ndarray | None = None, zero_start: tuple[bool, np.ndarray] | None = None) -> np.ndarray:
        """As :meth:`MixedSlipSystem.solve`; raises :class:`SlipFailure`.  ``zero_start``: Newton from zero slip has
        been run already (by :func:`~fem_grasp.contact.kernels.slip_trial.newton_trial`, with this ``tol``) and found
        no admissible root: (whether it found a root, x)."""
        if self.n == 0:
            return np.zeros(0)
        attempts: list[str] = []
        last = None  # the latest root Newton found (admissible or not), as MixedSlipSystem.solve reports it
        if "newton" in methods:
            if zero_start is not None:
                (found, x), ok = zero_start, False
            else:
                found, ok, x = self._newton(np.zeros(self.n), tol)
            if found and ok:
                return x
            last = x if found else None
            attempts.append("Newton reached a non-physical root" if found else "Newton did not converge")
            if start is not None and len(start) == self.n and np.isfinite(start).all():
                found, ok, x = self._newton(start / self.xscale, tol)
                if found and ok:
                    return x
                last = x if found else None
                attempts.append("Newton from the nearby root did not converge")
        if "homotopy" in methods:
            reason, detail, t, value, y, _ = slip_homotopy.homotopy(
                np.zeros(self.n), HOMOTOPY_TOL, homotopy.SLIP_INITIAL_STEP, homotopy.SLIP_MAX_STEP,
                SLIP_HOMOTOPY_STEPS, SLIP_HOMOTOPY_MIN_STEP, _HOMOTOPY_POLISH_ITER, self.xscale, self.row_scale, self.base_sl,
                self.g_sl, self.dmap, self.n0, self.kappa, self.mu, self.sph, self.free)
            if reason == 0:
                found, ok, x = self._newton(y, tol)
                if found and ok:
                    return x
                last = x if found else None
                attempts.append("homotopy reached a non-physical root")
            else:
                error = homotopy.kernel_error(reason, detail, t, value, y, tol=HOMOTOPY_TOL,
                                              min_step=SLIP_HOMOTOPY_MIN_STEP, max_steps=SLIP_HOMOTOPY_STEPS,
                                              max_iter=_HOMOTOPY_POLISH_ITER)
                attempts.append(f"homotopy: {error}")
        with np.errstate(over="ignore", invalid="ignore"):
            r = np.abs(self.row_scale * slip_newton.residual(np.zeros(self.n) if last is None else last,
                                                             self.base_sl, self.g_sl, self.dmap, self.n0,
                                                             self.kappa, self.mu, self.sph, self.free))
        p, n_sph = len(self.sliding), len(self.sphere_rows)
        worst = int(np.argmax(r))
        j = worst if worst < p else (int(self.sphere_rows[worst - p]) if worst < p + n_sph
                                     else int(self.align_rows[worst - p - n_sph]))
        raise SlipFailure(f"no admissible slip for {p} sliding node(s) "
                          f"({'free' if self.free else 'great-circle'} form; worst row {worst} at contact "
                          f"{int(self.sliding[j])}, held force {self.own[j]:.3g} N): " + "; ".join(attempts))

    def outcome(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """As :meth:`MixedSlipSystem.outcome`, in one kernel call."""
        with _quiet():
            return slip_trial.outcome(np.ascontiguousarray(x, dtype=float), self.fh, self.g, self.sliding, self.df,
                                      self.base_sl, self.g_sl, self.dmap, self.n0, self.kappa, self.mu, self.sph,
                                      self.free, self.t_held, self.row_scale)


@warm_up_sample
def _compile_the_slip_systems() -> None:
    """The slip systems of both forms, one table and one fingertip node: Newton, and the residual and Jacobian
    called on their own (the kernels of :mod:`~fem_grasp.contact.kernels.slip_newton`)."""
    s = sample_contacts()
    for free in (False, True):
        system = MixedSlipSystem(100.0 * np.eye(6), s["forces"], np.zeros((2, 3)), np.array([0, 1]),
                                 np.array([TABLE, FINGER1]), s["mu"], np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]),
                                 s["positions"] - [np.zeros(3), s["centre"]], s["up"], 0.01, free)
        system._newton(system.x0 / system.xscale, 1e-12)  # root or not: only the compilation matters
        system.residual(system.x0)
        system.jacobian(system.x0)
        compiled = CompiledSlipSystem(100.0 * np.eye(6), s["forces"], np.zeros((2, 3)), np.array([0, 1]),
                                      np.array([TABLE, FINGER1]), s["mu"],
                                      np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]),
                                      s["positions"] - [np.zeros(3), s["centre"]], s["up"], 0.01, free)
        for method in ("newton", "homotopy"):
            try:
                compiled.outcome(compiled.solve(methods=(method,)))
            except SlipFailure:
                compiled.outcome(np.zeros(compiled.n))
