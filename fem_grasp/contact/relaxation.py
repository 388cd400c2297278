"""Static frictional contact at fixed obstacles: nodal projected Gauss–Seidel (a return mapping).

The event tracking of :mod:`fem_grasp.contact.tracking` follows the *rate* problem of
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
* **release**: f_k = 0 at a position outside the obstacle (event B): on the
  table, or on a fingertip when δ_k·n̂⁰ ≥ 0; a fingertip contact with no
  slide state also lifts off when its force-free position clears the sphere,
  |r⁰ + δ_k| ≥ R (a node loaded along the surface of the curved tip —
  common on fine meshes, where one node's stiffness couples its tangential
  motion strongly to its normal force);
* **slide**: on the obstacle (in the table plane, or on the fingertip sphere
  along the great circle of its slip, Fig. 1), with the friction on the cone
  and opposite to the slip at the new position: f_t = −μ (f·n̂) ŝ_k.

The coupled problem is solved node by node (projected Gauss–Seidel, the
classical solver of nonsmooth contact mechanics): each visit solves contact
k's own problem exactly with the others frozen — a 2×2 Newton iteration for a
slide, warm-started from the previous sweep — and updates every force by the
rank-3 change C[:, k] Δδ_k (the sweep is :func:`fem_grasp.contact.kernels.gauss_seidel.sweep`,
compiled by numba when it is installed).  Sweeps repeat until no force changes
by more than ``tol`` × the force scale.  For the Tresca (fixed normal force) problem this
is block coordinate descent on a convex energy and converges; the Coulomb
coupling through the normal forces makes it a fixed point that converges
when friction is not too large for the coupling, and the iteration count is
bounded either way.  Once the statuses stop changing, Newton's method on
their smooth system finishes the solve (quadratically).  Where its root puts a
few statuses wrong (a sticking contact just outside its cone), the sweeps go on
from that root rather than from their own iterate (``polish_adoptions``): they
put those statuses right within a sweep or two and the next polish holds, where
the sweeps alone took hundreds (on the orange graded to R/8 at the fingertips this
cuts the lift test's sweeps to a third, to the same static states).  Sliding that
nothing stops shows as a steady drift — the same statuses, no root for
them, and no decay of the motion from sweep to sweep — and is reported as
gross slip, as is a motion per sweep that has decayed over neither half of
``growth_sweeps`` sweeps once a contact has moved a little (the sweeps of a
problem with no static state drift or grow while contacts release one by
one; those of one with a static state contract, after a transient bump on an
ill-conditioned body); statuses that keep cycling without progress (no halving of the
largest force change in 1000 sweeps) are reported too.
"""

from __future__ import annotations

import logging
import warnings
from dataclasses import dataclass
from typing import Callable, NamedTuple

import numpy as np
import scipy.linalg

from ..errors import RelaxationFailure
from ..settings import DEFAULT_SETTINGS, EngineSettings
from ..threads import blas_threads_for
from .kernels import gauss_seidel as gs
from .kernels import jit, polish
from .kernels.gauss_seidel import RELEASE, SLIDE, STICK
from .kernels.jit import as_kernel_data, sample_contacts, warm_up_sample

__all__ = ["RelaxationFailure", "Relaxation", "relax_contacts", "STICK", "SLIDE", "RELEASE"]

log = logging.getLogger(__name__)




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
    motions : (m, 2) each sliding contact's tangential motion (u₁, u₂) in its start frame (zero where it does
        not slide): with ``status`` and ``displacements``, a start for another relaxation from the same start
        positions (``relax_contacts(..., start=...)``)
    """

    displacements: np.ndarray
    forces: np.ndarray
    normals: np.ndarray
    status: np.ndarray
    slips: np.ndarray
    sweeps: int
    motions: np.ndarray | None = None


_EYE3 = np.eye(3)


class Polished(NamedTuple):
    """A converged polish (:func:`_polish`): the smooth system's root, and whether every status holds there."""

    holds: bool
    displacements: np.ndarray  # δ (m, 3)
    motions: np.ndarray  # u (m, 2); a sliding contact's from the root, the others' as given
    forces: np.ndarray  # (m, 3)


def _backtrack(fun, x: np.ndarray, step: np.ndarray, norm: float, halvings: int) -> tuple[float, tuple] | None:
    """Armijo backtracking on ‖fun(x)[0]‖: (λ, fun(x + λ step)) for the first λ = 1, ½, … that decreases it."""
    lam = 1.0
    for _ in range(halvings):
        out = fun(x + lam * step)
        if np.linalg.norm(out[0]) < (1.0 - 1e-4 * lam) * norm:
            return lam, out
        lam *= 0.5
    return None


def _polish_system(rec: np.ndarray, c: np.ndarray, f0: np.ndarray, mu: np.ndarray, status: np.ndarray,
                   d: np.ndarray, u: np.ndarray) -> tuple[list[int], np.ndarray, np.ndarray, Callable] | None:
    """The smooth system of fixed statuses that :func:`_polish` solves: (active contacts, offsets of their
    unknowns in x, the current x, ``evaluate(x, with_jacobian) -> (residual, forces, δ, Jacobian or None)``);
    None when no contact slides or is released.

    Unknowns: u_k (2) of each sliding contact, δ_k (3) of each released one.
    Equations: f_t + μ f_n ŝ = 0 in the tangent plane at the new position
    (sliding), f_k = 0 (released); sticking contacts keep δ_k = 0.  The
    Jacobian is assembled from per-contact blocks, ∂R_j/∂f_j C_jk ∂δ_k/∂x_k
    plus each contact's own geometric term, the geometric blocks by finite
    differences.
    """
    m = len(rec)
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
    geo = gs.SlideGeometry(rec[k_s], mu[k_s])
    rows = np.concatenate([3 * k + np.arange(3) for k in act])
    q = len(act)
    c_rows = c[np.ix_(rows, rows)].reshape(q, 3, 3 * q)  # C_act, each contact's three rows
    n_x = int(offs[-1])
    # The Jacobian's coupling part, ∂R/∂f C ∂δ/∂x, block by block: each active contact's row map (2×3 sliding,
    # I released) and column map (3×2, I), padded to 3×3; x holds the valid slots (3i + 0, 1[, 2]) in order.
    # (Dense (n_x × 3q) maps multiplied through C cost O(q³): seconds per pickup at 200 contacts.)
    valid = np.concatenate([3 * i + np.arange(sz) for i, sz in enumerate(sizes)])
    a_pad, d_pad = np.zeros((q, 3, 3)), np.zeros((q, 3, 3))
    a_pad[i_r] = _EYE3
    d_pad[i_r] = _EYE3

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
        a_pad[i_s, :2, :] = a
        d_pad[i_s, :, :2] = dj
        left = np.matmul(a_pad, c_rows).reshape(3 * q, q, 3)  # A_i C_ij, then (A_i C_ij) D_j below
        coupled = np.matmul(left.transpose(1, 0, 2), d_pad).transpose(1, 0, 2).reshape(3 * q, 3 * q)
        jac = coupled[np.ix_(valid, valid)]
        jac[xs_idx[:, :, None], xs_idx[:, None, :]] += ej
        return r, f, dd, jac

    return act, offs, x, evaluate


def _lu_factors(a: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """scipy's LU factors of ``a`` in its own precision; None when a pivot is exactly zero."""
    with blas_threads_for(len(a)), warnings.catch_warnings():
        warnings.simplefilter("ignore", scipy.linalg.LinAlgWarning)  # a zero pivot is checked below
        lu = scipy.linalg.lu_factor(a, check_finite=False)
    return lu if np.all(np.diagonal(lu[0])) else None


def _fresh_step(jac: np.ndarray, r: np.ndarray, single: bool) -> tuple[tuple | None, np.ndarray | None]:
    """(LU factors of a new Jacobian for the chord steps, the Newton step −J⁻¹ r), or (None, None) when J is exactly
    singular: with ``single``, single-precision factors and the step refined once against J, where its defect is
    within :data:`~fem_grasp.contact.kernels.polish.SINGLE_PRECISION_DEFECT` of r (the kernel's ``_refined_step``);
    else double precision's."""
    if single:
        lu = _lu_factors(jac.astype(np.float32))
        if lu is not None:
            step = -scipy.linalg.lu_solve(lu, r, check_finite=False)  # in r's precision (dgetrs)
            step = step - scipy.linalg.lu_solve(lu, jac @ step + r, check_finite=False)
            if np.linalg.norm(jac @ step + r) <= polish.SINGLE_PRECISION_DEFECT * np.linalg.norm(r):
                return lu, step
    lu = _lu_factors(jac)
    return (None, None) if lu is None else (lu, -scipy.linalg.lu_solve(lu, r, check_finite=False))


def _polish_limits(cfg: EngineSettings) -> tuple[int, int, float, bool]:
    """The polish's settings as :func:`_polish` takes them: (iterations, step halvings, chord contraction, single
    precision factors)."""
    return cfg.polish_iterations, cfg.polish_halvings, cfg.chord_contraction, cfg.single_precision_factors


DEFAULT_POLISH_LIMITS = _polish_limits(DEFAULT_SETTINGS)


def _polish(rec: np.ndarray, c: np.ndarray, f0: np.ndarray, mu: np.ndarray, status: np.ndarray,
            d: np.ndarray, u: np.ndarray, tol: float, stick_tol: float, max_slip: float,
            limits: tuple[int, int, float, bool] = DEFAULT_POLISH_LIMITS) -> Polished | None:
    """Newton's method on the smooth system of fixed statuses (:func:`_polish_system`): the polished state, and
    whether every status holds there; None when it does not converge.  ``limits``: (iterations, step halvings,
    chord contraction, single precision), the settings ``polish_iterations``, ``polish_halvings``,
    ``chord_contraction`` and ``single_precision_factors``."""
    iterations, halvings, contraction, single = limits
    system = _polish_system(rec, c, f0, mu, status, d, u)
    if system is None:
        return None
    act, offs, x, evaluate = system
    m = len(rec)
    r, f, dd, jac = evaluate(x, True)
    lu = None  # the LU factors of the latest Jacobian, reused while they still contract the residual
    for _ in range(iterations):
        norm = float(np.linalg.norm(r))
        if np.abs(r).max() <= tol:
            break
        fresh = lu is None
        try:
            if fresh:
                lu, step = _fresh_step(jac, r, single)
                if lu is None:
                    return None  # exactly singular, as numpy's solve would say
            else:
                step = -scipy.linalg.lu_solve(lu, r, check_finite=False)
        except (np.linalg.LinAlgError, ValueError):
            return None
        if not np.isfinite(step).all():
            return None
        # A Newton step cut below 1/8 means the statuses are wrong (the sweeps go on): in the steam bun's
        # return mappings 3 of 220 polishes that converged ever cut a step below 1/8, 306 of 572 that failed
        # did so within three steps (halving on to 1/512 only delayed the failure).
        found = _backtrack(lambda y: evaluate(y, False), x, step, norm, halvings)
        if found is None:
            if fresh:
                return None
            lu = None  # an old Jacobian's step: retry from a new one
            r, f, dd, jac = evaluate(x, True)
            continue
        x = x + found[0] * step
        r, f, dd, _ = found[1]
        if float(np.linalg.norm(r)) > contraction * norm or found[0] < 1.0:
            lu = None
            r, f, dd, jac = evaluate(x, True)
    else:
        return None
    if np.abs(r).max() > tol:
        return None
    # The statuses must still hold at the polished state.
    u2 = u.copy()
    holds = True
    for i, k in enumerate(act):
        xk = x[offs[i]:offs[i + 1]]
        if status[k] == SLIDE:
            n = np.array(gs.motion(rec[k], float(xk[0]), float(xk[1]))[3:6])
            holds = holds and f[k] @ n > 0.0 and 0.0 < float(np.linalg.norm(xk)) <= max_slip
            u2[k] = xk
        elif float(xk @ rec[k, gs.REC_N0:gs.REC_N0 + 3]) < 0.0 and not gs.outside_sphere(rec[k], *map(float, xk)):
            holds = False  # Signorini: in the contact's own frame, or clear of its fingertip (see the sweep)
    for k in range(m):
        if status[k] == STICK:
            n = rec[k, gs.REC_N0:gs.REC_N0 + 3]
            fn = float(f[k] @ n)
            if fn < 0.0 or float(np.linalg.norm(f[k] - fn * n)) > mu[k] * fn + stick_tol:
                holds = False
    return Polished(bool(holds), dd, u2, f)


def _compiled_polish(rec: np.ndarray, c: np.ndarray, f0: np.ndarray, mu: np.ndarray, status: np.ndarray,
                     d: np.ndarray, u: np.ndarray, tol: float, stick_tol: float, max_slip: float,
                     limits: tuple[int, int, float, bool] = DEFAULT_POLISH_LIMITS) -> Polished | None:
    """:func:`_polish` in one kernel call (:mod:`~fem_grasp.contact.kernels.polish`)."""
    with np.errstate(over="ignore", invalid="ignore"):
        outcome, dd, u2, f = polish.polish(np.ascontiguousarray(rec), np.ascontiguousarray(c), np.ascontiguousarray(f0),
                                      np.ascontiguousarray(mu, dtype=float), status, np.ascontiguousarray(d),
                                      np.ascontiguousarray(u), float(tol), float(stick_tol), float(max_slip),
                                      int(limits[0]), int(limits[1]), float(limits[2]), bool(limits[3]))
    return None if outcome == polish.FAILED else Polished(outcome == polish.HOLDS, dd, u2, f)


def _adoptable(polished: Polished, status: np.ndarray, max_slip: float) -> bool:
    """The sweeps may go on from a polished state whose statuses do not all hold when no contact in it has slid
    or been released further than ``max_slip`` (the sweeps would take that for gross slip or lost support)."""
    moving = status != STICK
    travel = np.linalg.norm(np.asarray(polished.displacements, float)[moving], axis=1)
    slid = np.linalg.norm(np.asarray(polished.motions, float)[status == SLIDE], axis=1)
    return bool(np.isfinite(polished.forces).all() and (travel <= max_slip).all() and (slid <= max_slip).all())


def _adopt(polished: Polished, status: np.ndarray, f, d, u, has_u) -> None:
    """Put a polished state into the sweeps' working arrays (in place: arrays compiled, lists otherwise)."""
    sliding = status == SLIDE
    values = (np.asarray(polished.forces, float), np.asarray(polished.displacements, float),
              np.asarray(polished.motions, float), np.where(sliding, 1.0, np.asarray(has_u, float)))
    for target, value in zip((f, d, u, has_u), values):
        target[:] = value if isinstance(target, np.ndarray) else value.tolist()


def relax_contacts(stiffness: np.ndarray, forces: np.ndarray, positions: np.ndarray, centers: list,
                   up: np.ndarray, mu: np.ndarray, force_scale: float, *, tol: float = 1e-11,
                   max_sweeps: int = 5000, max_slip: float = np.inf,
                   start: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
                   settings: EngineSettings | None = None) -> Relaxation:
    """Static stick/slide/release state of every contact at fixed obstacles (module notes).

    Parameters
    ----------
    stiffness : (3m, 3m) reduced stiffness C of eq. (5) for the contact set (symmetric)
    forces : (m, 3) forces f⁰ at the start (every contact held at its start position)
    positions : (m, 3) start positions q⁰_k, each on its obstacle
    centers : m entries: the fingertip centre of a fingertip contact, None for a table contact
    up : (3,) the table's normal
    mu : (m,) friction coefficients
    force_scale : F_s, newtons; sweeps stop when no force changes by more than ``tol`` F_s
    max_slip : a contact sliding further than this, metres, is taken as gross slip (failure)
    start : (status, displacements, motions) to start the sweeps from instead of every contact held at its start
        position: a nearby state (a relaxation of the same start positions with fewer contacts, say). Only where
        the sweeps begin: the static state they find is a property of the problem, wherever they begin.
    settings : the iteration bounds (``drift_*``, ``growth_sweeps``, ``stuck_sweeps``, ``stall_sweeps``) and the
        polish (``polish_*``, ``chord_contraction``, ``single_precision_factors``, ``compiled_polish``) of
        :class:`~fem_grasp.settings.EngineSettings` (default: the defaults)

    Raises
    ------
    RelaxationFailure
        A contact has no stick, release or slide state with the others frozen (friction cannot hold
        it), or the sweeps do not settle within ``max_sweeps``.
    """
    cfg = DEFAULT_SETTINGS if settings is None else settings
    compiled_polish = jit.ENABLED if cfg.compiled_polish is None else cfg.compiled_polish
    limits = _polish_limits(cfg)
    c = np.asarray(stiffness, float)
    f0 = np.array(forces, float)
    m = len(f0)
    idx = np.arange(m)
    ckk = np.ascontiguousarray(c.reshape(m, 3, m, 3)[idx, :, idx, :])  # (m, 3, 3): each contact's own block
    if m and np.any(np.linalg.det(ckk) == 0.0):
        raise RelaxationFailure("a contact's own stiffness block C_kk is singular", "singular")
    try:
        rec = gs.contact_records(np.asarray(positions, float).reshape(m, 3), centers, up, ckk)
    except np.linalg.LinAlgError:
        raise RelaxationFailure("a contact's own stiffness block C_kk is singular", "singular") from None
    fs_scale = max(float(force_scale), 1e-300)
    local_tol = 1e-3 * tol * fs_scale
    stick_tol = tol * fs_scale
    mu = np.asarray(mu, float)
    # The sweep's working state, as arrays (compiled) or lists (plain Python): see fem_grasp.contact.kernels.jit.
    # The sweep reads C's columns; C is symmetric (eq. 5, and ContactResponse.reduced_stiffness exactly), so its
    # rows serve, read in place: a transposed copy of C cost a sixth of a fine patch's return mappings.
    k_rec, k_mu = as_kernel_data(rec), as_kernel_data(mu)
    k_ct = np.ascontiguousarray(c) if isinstance(k_rec, np.ndarray) else as_kernel_data(c)
    if start is None:
        f, d, u = as_kernel_data(f0), as_kernel_data(np.zeros((m, 3))), as_kernel_data(np.zeros((m, 2)))
        has_u, status = as_kernel_data(np.zeros(m), np.int64), as_kernel_data(np.full(m, STICK), np.int64)
    else:
        s0 = np.asarray(start[0], dtype=np.int64).reshape(m)
        d0 = np.where((s0 == SLIDE)[:, None], np.asarray(start[1], float).reshape(m, 3), 0.0)
        u0 = np.where((s0 == SLIDE)[:, None], np.asarray(start[2], float).reshape(m, 2), 0.0)
        s0 = np.where(s0 == SLIDE, SLIDE, STICK)  # a released start is swept afresh from held
        f = as_kernel_data(f0 + (c @ d0.reshape(-1)).reshape(m, 3))
        d, u = as_kernel_data(d0), as_kernel_data(u0)
        has_u, status = as_kernel_data((s0 == SLIDE).astype(float), np.int64), as_kernel_data(s0, np.int64)
    memo, unsolved_force = as_kernel_data(np.zeros((m, 10))), as_kernel_data(np.zeros(3))
    last_status = status.tobytes() if isinstance(status, np.ndarray) else list(status)
    next_polish, polish_fails, adopted = 2, 0, 0
    moves: list[float] = []
    history: list[float] = []
    stuck = 0
    best_change, best_sweep = np.inf, 0
    polished = None
    for sweep in range(1, max_sweeps + 1):
        code, k, change, move, unsolved = gs.sweep(k_rec, k_ct, f, d, u, has_u, status, k_mu, stick_tol, local_tol,
                                                   float(max_slip), memo, unsolved_force)
        if code == gs.FREE_TOO_FAR:
            raise RelaxationFailure(f"contact {k} would move more than {1e3 * max_slip:.3g} mm to carry no "
                                    "force: the remaining contacts no longer hold the object", "lost support", k)
        if code == gs.SLIDE_TOO_FAR:
            raise RelaxationFailure(f"contact {k} slides more than {1e3 * max_slip:.3g} mm: friction cannot "
                                    "hold the object (gross slip)", "gross slip", k)
        if unsolved >= 0:
            stuck += 1
            if stuck > cfg.stuck_sweeps:
                fs = np.asarray(unsolved_force, float)
                raise RelaxationFailure(
                    f"contact {unsolved} can neither stick, slide nor lift off with its neighbours held "
                    f"(force {fs.round(12).tolist()} N, μ = {mu[unsolved]:g}; sweep {sweep}): friction cannot "
                    "hold it", "gross slip", unsolved)
        else:
            stuck = 0
        if change <= tol * fs_scale and unsolved < 0:
            break
        if change < 0.5 * best_change:
            best_change, best_sweep = change, sweep
        elif sweep - best_sweep > cfg.stall_sweeps:
            raise RelaxationFailure(f"the stick/slip state stops settling after {sweep} Gauss–Seidel sweeps "
                                    f"(no progress in the last {cfg.stall_sweeps}): friction cannot hold the "
                                    "contacts in a static state")
        now_status = status.tobytes() if isinstance(status, np.ndarray) else list(status)  # (compiled: an array)
        same = now_status == last_status
        # Once the statuses stop changing, Newton's method on their smooth system finishes the job
        # (Gauss–Seidel converges only linearly, slowly when the contacts are strongly coupled).
        if sweep >= next_polish and same:
            now = np.asarray(status, dtype=np.int64)
            polished = (_compiled_polish if compiled_polish else _polish)(
                rec, c, f0, mu, now, np.asarray(d, float), np.asarray(u, float), local_tol, stick_tol, max_slip,
                limits)
            if polished is not None and polished.holds:
                break
            if polished is not None and adopted < cfg.polish_adoptions and _adoptable(polished, now, max_slip):
                # The root of these statuses with a few of them wrong: nearer the static state than the sweeps'
                # iterate, so the sweeps go on from it (they put the wrong statuses right) and polish again.
                adopted += 1
                _adopt(polished, now, f, d, u, has_u)
                next_polish = sweep + 2
            else:
                polish_fails += 1
                next_polish = sweep + 10 * 2 ** min(polish_fails, 6)
            polished = None
        if not same:
            moves = []
        moves.append(move)
        # Same statuses, no root for them, and the motion per sweep decays too slowly for the contacts to stop
        # within the slip bound: sliding that nothing stops (gross slip).  An ill-conditioned static problem
        # (ν → ½) also converges slowly, but geometrically: its remaining motion, extrapolated at the observed
        # rate, stays small, and the sweeps go on.
        history.append(move)
        # No decay over either half of the window: a transient bump of the motion (statuses settling on an
        # ill-conditioned body, ν → ½) decays again within the window's second half.
        w = cfg.growth_sweeps
        if len(history) > w and history[-1] >= history[-1 - w // 2] >= history[-1 - w]:
            travel = np.linalg.norm(np.asarray(d, float).reshape(m, 3), axis=1)
            if float(travel.max()) > cfg.drift_slip * max_slip:
                k = int(np.argmax(travel))
                raise RelaxationFailure(f"the contacts move no slower after {sweep} Gauss–Seidel sweeps than "
                                        f"{cfg.growth_sweeps} sweeps before (contact {k} has moved furthest): nothing "
                                        "stops them, friction cannot hold the object (gross slip)", "gross slip", k)
        if len(moves) > cfg.drift_sweeps and moves[-1] > cfg.drift_decay * moves[-1 - cfg.drift_sweeps]:
            uu = np.asarray(u, float)[np.asarray(has_u) != 0]  # (only here: a sweep costs less than this)
            slid = float(np.sqrt((uu ** 2).sum(axis=1)).max()) if len(uu) else 0.0
            rate = (moves[-1] / max(moves[-1 - cfg.drift_sweeps], 1e-300)) ** (1.0 / cfg.drift_sweeps)
            ahead = np.inf if rate >= 1.0 else moves[-1] * rate / (1.0 - rate)
            if slid > cfg.drift_slip * max_slip and slid + ahead > max_slip:
                raise RelaxationFailure(f"the contacts keep sliding at a steady rate after {sweep} Gauss–Seidel "
                                        "sweeps: friction cannot hold the object (gross slip)")
        last_status = now_status
    else:
        raise RelaxationFailure(f"the stick/slip state did not settle in {max_sweeps} Gauss–Seidel sweeps "
                                "(the contacts keep sliding: friction cannot hold the object here)")
    status = np.asarray(status, dtype=np.int64)
    if polished is not None:
        d, u, f = polished.displacements, polished.motions, polished.forces
    d, u = np.asarray(d, float).reshape(m, 3), np.asarray(u, float).reshape(m, 2)
    sliding = status == SLIDE
    u[~sliding] = 0.0
    f = f0 + (c @ d.reshape(-1)).reshape(m, 3)
    if not (np.isfinite(f).all() and np.isfinite(d).all()):
        raise RelaxationFailure("the relaxation produced non-finite forces or displacements", "non-finite")
    normals = rec[:, gs.REC_N0:gs.REC_N0 + 3].copy()
    for k in np.flatnonzero(sliding):
        normals[k] = gs.motion(rec[k], float(u[k, 0]), float(u[k, 1]))[3:6]
    slips = np.where(sliding, np.linalg.norm(u, axis=1), 0.0)
    log.debug("relaxation: %d sweeps, %d stick, %d slide, %d release", sweep, int((status == STICK).sum()),
              int((status == SLIDE).sum()), int((status == RELEASE).sum()))
    return Relaxation(d, f, normals, status, slips, sweep, u)


@warm_up_sample
def _compile_the_return_mapping() -> None:
    """A return mapping of one table and one fingertip contact: its sweep, its Newton polish (both kernels) and what
    its end calls per contact (the kernels of :mod:`~fem_grasp.contact.kernels.gauss_seidel` and
    :mod:`~fem_grasp.contact.kernels.polish`)."""
    s = sample_contacts()
    up, centre, positions, mu = s["up"], s["centre"], s["positions"], s["mu"]
    relax_contacts(100.0 * np.eye(6), s["forces"], positions, [None, centre], up, mu, 1.0)
    records = gs.contact_records(positions, [None, centre], up, np.stack([np.eye(3), np.eye(3)]))
    gs.SlideGeometry(records, mu).projections(np.zeros((2, 2)))
    gs.outside_sphere(records[1], 0.0, 0.0, 0.0)
    gs.motion(records[1], 0.0, 0.0)
    _compiled_polish(records, 100.0 * np.eye(6), s["forces"], mu, np.array([SLIDE, RELEASE], dtype=np.int64),
                     np.zeros((2, 3)), np.full((2, 2), 1e-3), 1e-9, 1e-9, np.inf)
