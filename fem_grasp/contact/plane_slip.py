"""Table slip of the resting iteration (paper §III-A steps 6–7, eq. 6): slip systems and their settlement.

With the contact set fixed the forces are affine in the contact
displacements, ``F̄ = C Δ̄ + F̄₀`` (eq. 5, :class:`~fem_grasp.elastic.response.ContactResponse`).
If the contact displacements are in turn affine in some slip unknowns x,
``Δ̄ = Δ̄_held + E x + e₀``, then every sliding node's force is affine in x and
each cone-boundary condition of eq. (6) is one quadratic equation in x.
:class:`SlipSystem` holds exactly this structure:

* table slip (eq. 6): one unknown per sliding node, its slip distance d_k ≥ 0;
  node k moves by ``−d_k t̂_k`` in the plane, t̂_k the unit tangential force
  direction at the start of the slip (:func:`plane_slip_system`);
* table slip with free directions (:func:`plane_free_slip_system`): two
  in-plane unknowns per node, eq. (6) plus "friction parallel to the slip"
  ``n̂·(f_k × u_k) = 0`` (Coulomb's law with maximum dissipation);
* further quadratic equations in the unknowns enter as
  :class:`QuadraticConstraint`.

:func:`solve_slip` solves the square system with the homotopy continuation of
:mod:`fem_grasp.contact.homotopy` (paper footnote 2).  (The fingertip slip of
eqs. 7–8 during the squeeze and the lift is :mod:`~fem_grasp.contact.slip_system`.)

With the directions t̂_k frozen, eq. (6) may have no real root: when several
coupled nodes slide, a slip changes the others' friction *across* their t̂, and
no slip along t̂ can remove that component.  :func:`settle_plane_slip` then
falls back to free directions, or to sliding the worst node alone, and
repeats with fresh directions until every contact is in its cone (see its
notes).  The gross-sliding limit is exact: when every contact is on the plane
and the load's tangential part exceeds μ times its normal part, it raises
:class:`~fem_grasp.errors.FrictionError` at once.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from ..elastic.response import contact_dofs
from ..errors import FrictionError
from . import homotopy
from .friction import CONE_RTOL, cone_residual, cone_violation, normal_component, slip_directions, tangential_component
from .kernels import jit, slip_trial
from .obstacles import tangent_basis

__all__ = ["FrictionError", "PlaneSettlement", "PlaneSlip", "QuadraticConstraint", "SlipSolution", "SlipSystem",
           "frictionless_tangential_displacements", "plane_free_slip_system", "plane_slip_system",
           "settle_plane_slip", "solve_plane_slip", "solve_slip"]

log = logging.getLogger(__name__)

#: :func:`solve_slip` follows its homotopy path in one compiled kernel (:func:`~fem_grasp.contact.kernels.slip_trial.
#: homotopy`, the event tracking's) where numba is installed and the system is eq. (6) with frozen or free directions
#: (no extra constraints); False: with :func:`fem_grasp.contact.homotopy.track` (numpy), the reference.
COMPILED_HOMOTOPY = jit.ENABLED


# ------------------------------------------------------------- slip systems
@dataclass(frozen=True)
class QuadraticConstraint:
    """An extra equation ``xᵀQx + q·x + c = 0`` on the slip unknowns, e.g. eq. (8) c_k² + s_k² = 1."""

    quadratic: np.ndarray
    linear: np.ndarray
    constant: float = 0.0

    def value(self, x: np.ndarray) -> float:
        return float(x @ self.quadratic @ x + self.linear @ x + self.constant)

    def gradient(self, x: np.ndarray) -> np.ndarray:
        return (self.quadratic + self.quadratic.T) @ x + self.linear


@dataclass(frozen=True)
class SlipSystem:
    """Square quadratic system for the slip unknowns x of a fixed contact set.

    The contact displacements change by ``E x + e₀`` from the held state, so
    the contact forces are

        F̄(x) = F̄_held + C (E x + e₀)                          (eq. 5)

    and the residual stacks, for each sliding node k, the cone-boundary
    equation (6)/(7) ``(1+μ_k²)(f_k·n̂_k)² − f_k·f_k`` followed by the extra
    quadratic constraints (eq. 8).

    Parameters
    ----------
    stiffness : (3m, 3m) array
        Reduced stiffness C of the contact set (``ContactResponse.reduced_stiffness``).
    held_forces : (m, 3) array
        Contact forces F̄_held with the contacts held (x = 0, e₀ = 0).
    displacement_map : (3m, N) array
        E: change of the contact displacement vector per unit of each unknown.
    sliding : (p,) int
        Positions (0 … m−1 in the contact set) of the sliding nodes.
    normals : (p, 3) array
        Unit inward normals n̂_k at the sliding nodes.
    mu : (p,) array
        Friction coefficient at each sliding node.
    displacement_offset : (3m,) array, optional
        e₀ (zero for table slip).
    constraints : sequence of QuadraticConstraint
        Extra equations on x alone (eq. 8).
    aligned : (a,) int, optional
        Positions in the contact set of nodes whose friction must be
        anti-parallel to their slip (maximum dissipation): one row
        ``n̂_k · (f_k × u_k)`` each, u_k = (E x + e₀)_k the node's displacement
        change.  ``p + len(constraints) + a`` must equal N.
    aligned_normals : (a, 3) array, optional
        The unit normals n̂_k of the aligned rows.
    unknown_scale : (N,) array, optional
        Typical magnitude of each unknown, used only to non-dimensionalise the
        solve.  Default: the slip that changes the force by the largest held
        force, ``max|F̄_held| / ‖C E_j‖`` (right for slip distances; pass ones
        for dimensionless unknowns such as c_k, s_k).
    """

    stiffness: np.ndarray
    held_forces: np.ndarray
    displacement_map: np.ndarray
    sliding: np.ndarray
    normals: np.ndarray
    mu: np.ndarray
    displacement_offset: np.ndarray | None = None
    constraints: Sequence[QuadraticConstraint] = ()
    aligned: np.ndarray | None = None
    aligned_normals: np.ndarray | None = None
    unknown_scale: np.ndarray | None = None
    _force_map: np.ndarray = field(init=False, repr=False)
    _force_base: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        c = np.asarray(self.stiffness, dtype=float)
        f0 = np.asarray(self.held_forces, dtype=float)
        e = np.asarray(self.displacement_map, dtype=float)
        m = f0.shape[0]
        if f0.shape != (m, 3) or c.shape != (3 * m, 3 * m):
            raise ValueError(f"held_forces must be (m, 3) and stiffness (3m, 3m); got {f0.shape} and {c.shape}")
        if e.ndim != 2 or e.shape[0] != 3 * m:
            raise ValueError(f"displacement_map must be (3m, N) = ({3 * m}, N), got {e.shape}")
        sliding = np.asarray(self.sliding, dtype=np.int64).reshape(-1)
        p = len(sliding)
        if np.any((sliding < 0) | (sliding >= m)):
            raise ValueError("sliding positions must index the contact set")
        normals = np.broadcast_to(np.asarray(self.normals, dtype=float), (p, 3)).copy()
        normals /= np.linalg.norm(normals, axis=1, keepdims=True)
        mu = np.broadcast_to(np.asarray(self.mu, dtype=float), (p,)).copy()
        if np.any(mu < 0) or not np.isfinite(mu).all():
            raise ValueError(f"friction coefficients must be finite and non-negative, got {mu}")
        n_unknowns = e.shape[1]
        aligned = np.zeros(0, np.int64) if self.aligned is None else np.asarray(self.aligned, np.int64).reshape(-1)
        if np.any((aligned < 0) | (aligned >= m)):
            raise ValueError("aligned positions must index the contact set")
        if len(aligned) and self.aligned_normals is None:
            raise ValueError("aligned rows need aligned_normals")
        a_normals = (np.zeros((0, 3)) if not len(aligned) else
                     np.broadcast_to(np.asarray(self.aligned_normals, dtype=float), (len(aligned), 3)).copy())
        if len(aligned):
            a_normals /= np.linalg.norm(a_normals, axis=1, keepdims=True)
        if p + len(self.constraints) + len(aligned) != n_unknowns:
            raise ValueError(f"the slip system is not square: {p} cone equations + {len(self.constraints)} "
                             f"constraints + {len(aligned)} alignment rows for {n_unknowns} unknowns")
        e0 = np.zeros(3 * m) if self.displacement_offset is None else np.asarray(self.displacement_offset, float)
        force_map = c @ e  # dF̄/dx
        force_base = f0.reshape(-1) + c @ e0
        if self.unknown_scale is None:
            fscale = max(float(np.abs(f0).max()), np.finfo(float).tiny)
            col = np.linalg.norm(force_map, axis=0)
            scale = fscale / np.where(col > 0, col, 1.0)
        else:
            scale = np.broadcast_to(np.asarray(self.unknown_scale, dtype=float), (n_unknowns,)).copy()
        for name, value in (("sliding", sliding), ("normals", normals), ("mu", mu), ("stiffness", c),
                            ("held_forces", f0), ("displacement_map", e), ("displacement_offset", e0),
                            ("aligned", aligned), ("aligned_normals", a_normals), ("unknown_scale", scale), ("_force_map", force_map), ("_force_base", force_base)):
            object.__setattr__(self, name, value)

    # -- the affine map x -> forces and the residual ------------------------
    @property
    def n_unknowns(self) -> int:
        return self.displacement_map.shape[1]

    @property
    def n_contacts(self) -> int:
        return self.held_forces.shape[0]

    def displacements(self, x: np.ndarray) -> np.ndarray:
        """(m, 3) change E x + e₀ of the contact displacements."""
        return (self.displacement_map @ np.asarray(x, dtype=float) + self.displacement_offset).reshape(-1, 3)

    def forces(self, x: np.ndarray) -> np.ndarray:
        """(m, 3) contact forces F̄(x) on the object (eq. 5)."""
        return (self._force_base + self._force_map @ np.asarray(x, dtype=float)).reshape(-1, 3)

    @property
    def n_rows(self) -> tuple[int, int, int]:
        """Numbers of cone rows, constraint rows and alignment rows."""
        return len(self.sliding), len(self.constraints), len(self.aligned)

    def residual(self, x: np.ndarray) -> np.ndarray:
        """(N,) eqs. (6)/(7) at the sliding nodes, the extra constraints (eq. 8), the alignment rows."""
        x = np.asarray(x, dtype=float)
        forces = self.forces(x)
        cone = cone_residual(forces[self.sliding], self.normals, self.mu)
        extra = np.asarray([con.value(x) for con in self.constraints], dtype=float)
        u = self.displacements(x)[self.aligned]
        align = np.einsum("ki,ki->k", self.aligned_normals, np.cross(forces[self.aligned], u))
        return np.concatenate([cone, extra, align])

    def jacobian(self, x: np.ndarray) -> np.ndarray:
        """(N, N) ∂residual/∂x.

        For a cone row, with G_k = ∂f_k/∂x (3 × N):
        ``2(1+μ²)(f_k·n̂_k)(n̂_kᵀG_k) − 2 f_kᵀG_k``.
        """
        x = np.asarray(x, dtype=float)
        f = self.forces(x)[self.sliding]  # (p, 3)
        g = self._force_map.reshape(self.n_contacts, 3, -1)[self.sliding]  # (p, 3, N)
        fn = np.einsum("ki,ki->k", f, self.normals)
        rows = (2.0 * (1.0 + self.mu**2) * fn)[:, None] * np.einsum("ki,kij->kj", self.normals, g)
        rows -= 2.0 * np.einsum("ki,kij->kj", f, g)
        extra = [con.gradient(x) for con in self.constraints]
        if extra:
            rows = np.vstack([rows, np.asarray(extra)])
        if len(self.aligned):
            # d/dx n·(f × u) = n·(G_j × u) + n·(f × E_j)
            forces = self.forces(x)
            u = self.displacements(x)[self.aligned]  # (a, 3)
            ga = self._force_map.reshape(self.n_contacts, 3, -1)[self.aligned]  # (a, 3, N)
            ea = self.displacement_map.reshape(self.n_contacts, 3, -1)[self.aligned]
            nrm = self.aligned_normals
            fa = forces[self.aligned]
            # n·(a × b) = a·(b × n)
            ucn = np.cross(u, nrm)  # (a, 3): n·(G_j × u) = G_j·(u × n)
            ncf = np.cross(nrm, fa)  # n·(f × E_j) = E_j·(n × f)
            arow = np.einsum("kij,ki->kj", ga, ucn) + np.einsum("kij,ki->kj", ea, ncf)
            rows = np.vstack([rows, arow])
        return rows


@dataclass(frozen=True)
class SlipSolution:
    """A root of a :class:`SlipSystem`.

    Attributes
    ----------
    x : (N,) the slip unknowns
    forces : (m, 3) contact forces F̄(x)
    displacements : (m, 3) change E x + e₀ of the contact displacements
    residual : float, largest non-dimensional residual (cone rows relative to |f_k|²)
    method : "homotopy", "newton" or "none" (no unknowns)
    steps : homotopy steps taken
    """

    x: np.ndarray
    forces: np.ndarray
    displacements: np.ndarray
    residual: float
    method: str
    steps: int


def solve_slip(system: SlipSystem, x0: np.ndarray | None = None, *, tol: float = 1e-13) -> SlipSolution:
    """Solve a slip system with homotopy continuation (paper eqs. 6–8, footnote 2).

    The unknowns and residual are non-dimensionalised (``y = x / unknown_scale``,
    each cone row divided by its node's squared held force).  The root is tracked from
    the held state ``x0`` (default 0) with the Newton homotopy
    ``Q(y) = P(y) − P(y₀)``, i.e. ``H(y, t) = P(y) − (1−t)² P(y₀)``: every
    cone residual shrinks from its stick value to zero along the path, so the
    root reached is the one continuously connected to the held state — the
    smallest slip that brings each node back onto its cone.  If that path
    fails, :func:`fem_grasp.contact.homotopy.solve` (Newton, then the default
    homotopy) is tried.  The path is followed in one compiled kernel (the event tracking's
    :func:`~fem_grasp.contact.kernels.slip_trial.homotopy`, the same steps and tolerances) where numba is
    installed and the system has no extra constraints (:data:`COMPILED_HOMOTOPY`).

    Raises
    ------
    FrictionError
        If neither route converges.
    """
    n = system.n_unknowns
    if n == 0:
        z = np.zeros(0)
        return SlipSolution(z, system.forces(z), system.displacements(z), 0.0, "none", 0)
    scale = system.unknown_scale
    fscale = max(float(np.abs(system.held_forces).max()), np.finfo(float).tiny)
    n_cone, n_con, n_align = system.n_rows
    # Each cone row (a force squared) is divided by its own node's squared held force, so that the
    # polish tolerance bounds the *relative* cone error of every node, however lightly loaded; the
    # alignment rows (force × length) by that force times the typical unknown.
    own = np.maximum(np.linalg.norm(system.held_forces, axis=1), 1e-6 * fscale)
    row_scale = np.concatenate([1.0 / own[system.sliding] ** 2, np.ones(n_con),
                                1.0 / (own[system.aligned] * float(np.median(scale)))])
    x0 = np.zeros(n) if x0 is None else np.asarray(x0, dtype=float)
    y0 = x0 / scale

    def fun(y: np.ndarray) -> np.ndarray:
        return row_scale * system.residual(y * scale)

    def jac(y: np.ndarray) -> np.ndarray:
        return row_scale[:, None] * system.jacobian(y * scale) * scale[None, :]

    kernel = _kernel_arrays(system) if COMPILED_HOMOTOPY else None
    try:
        if kernel is not None:
            reason, detail, t, value, y, steps = slip_trial.homotopy(
                y0, float(tol), homotopy.SLIP_INITIAL_STEP, homotopy.SLIP_MAX_STEP, homotopy.TRACK_MAX_STEPS,
                homotopy.TRACK_MIN_STEP, homotopy.TRACK_MAX_ITER, np.ascontiguousarray(scale, dtype=float),
                row_scale, *kernel)
            if reason:
                raise homotopy.kernel_error(reason, detail, t, value, y, tol=tol, min_step=homotopy.TRACK_MIN_STEP,
                                            max_steps=homotopy.TRACK_MAX_STEPS, max_iter=homotopy.TRACK_MAX_ITER)
            res_x, method = y, "homotopy"
        else:
            p0 = fun(y0)
            res = homotopy.track(fun, jac, y0, start=lambda y: fun(y) - p0, start_jac=jac, tol=tol,
                                 initial_step=homotopy.SLIP_INITIAL_STEP, max_step=homotopy.SLIP_MAX_STEP)
            res_x, method, steps = res.x, res.method, res.steps
    except homotopy.HomotopyError as exc:
        log.debug("Newton-homotopy path from the held state failed (%s); trying homotopy.solve", exc)
        try:
            res = homotopy.solve(fun, jac, y0, tol=tol)
        except homotopy.HomotopyError as exc2:
            raise FrictionError(f"the slip system of {len(system.sliding)} sliding node(s) could not be solved: "
                                f"{exc2} (reason {exc2.reason!r})") from exc2
        res_x, method, steps = res.x, res.method, res.steps
    x = np.asarray(res_x, dtype=float) * scale
    r = float(np.abs(fun(res_x)).max())
    return SlipSolution(x, system.forces(x), system.displacements(x), r, method, int(steps))


def _kernel_arrays(system: SlipSystem) -> tuple | None:
    """The arrays of :func:`~fem_grasp.contact.kernels.slip_trial.homotopy` after its scales (base forces, force
    and displacement maps and normals of the sliding nodes, no curvature, no sphere rows, the free form's
    alignment rows), or None for a system the kernel does not model (extra constraints, alignment rows other
    than the sliding nodes', a displacement offset)."""
    free = len(system.aligned) > 0
    if (system.constraints or np.any(system.displacement_offset)
            or (free and not np.array_equal(system.aligned, system.sliding))):
        return None
    m, n, p = system.n_contacts, system.n_unknowns, len(system.sliding)
    rows = contact_dofs(system.sliding)
    return (np.ascontiguousarray(system._force_base[rows]),
            np.ascontiguousarray(system._force_map.reshape(3 * m, n)[rows]),
            np.ascontiguousarray(system.displacement_map[rows]), np.ascontiguousarray(system.normals),
            np.zeros(p), np.ascontiguousarray(system.mu, dtype=float), np.zeros((0, 2), dtype=np.int64), free)


# ------------------------------------------------------------ table slip, eq. (6)
def plane_slip_system(stiffness: np.ndarray, held_forces: np.ndarray, sliding: np.ndarray,
                      normal: np.ndarray, mu: float, directions: np.ndarray | None = None) -> SlipSystem:
    """Eq. (6): nodes sliding on a plane with inward normal ``normal``, directions frozen.

    Node ``sliding[j]`` moves by ``−d_j t̂_j`` (d_j ≥ 0 the unknown slip
    distance), t̂_j the unit tangential force direction at the start of the
    slip (default: from ``held_forces``).  Every force is then affine in d:
    ``f_k(d) = f_k,held − Σ_j C_{k,sliding[j]} t̂_j d_j``, and the system is
    one equation (6) per sliding node.
    """
    f0 = np.asarray(held_forces, dtype=float)
    sliding = np.asarray(sliding, dtype=np.int64).reshape(-1)
    normal = np.asarray(normal, dtype=float)
    normal = normal / np.linalg.norm(normal)
    if directions is None:
        directions = slip_directions(f0[sliding], normal)
    t = np.asarray(directions, dtype=float).reshape(len(sliding), 3)
    e = np.zeros((3 * len(f0), len(sliding)))
    for j, k in enumerate(sliding):
        e[3 * k:3 * k + 3, j] = -t[j]
    return SlipSystem(stiffness, f0, e, sliding, np.broadcast_to(normal, (len(sliding), 3)),
                      np.full(len(sliding), float(mu)))


def plane_free_slip_system(stiffness: np.ndarray, held_forces: np.ndarray, sliding: np.ndarray,
                           normal: np.ndarray, mu: float) -> SlipSystem:
    """Table slip with free in-plane directions (Coulomb's law with maximum dissipation).

    Node ``sliding[j]`` moves by an unknown in-plane vector
    ``u_j = a_j e₁ + b_j e₂``; its force must lie on the cone boundary (eq. 6)
    *and* its friction must be parallel to u_j, ``n̂·(f_j × u_j) = 0``
    (admissible roots have it opposite, ``f_t·u_j < 0``).  Two quadratic
    equations per node.  Used when eq. (6) with frozen directions t̂ has no
    real root (see :func:`settle_plane_slip`).
    """
    f0 = np.asarray(held_forces, dtype=float)
    sliding = np.asarray(sliding, dtype=np.int64).reshape(-1)
    normal = np.asarray(normal, dtype=float)
    normal = normal / np.linalg.norm(normal)
    basis = tangent_basis(normal)
    p = len(sliding)
    e = np.zeros((3 * len(f0), 2 * p))
    for j, k in enumerate(sliding):
        e[3 * k:3 * k + 3, 2 * j] = basis[0]
        e[3 * k:3 * k + 3, 2 * j + 1] = basis[1]
    normals = np.broadcast_to(normal, (p, 3))
    return SlipSystem(stiffness, f0, e, sliding, normals, np.full(p, float(mu)), aligned=sliding,
                      aligned_normals=normals)


@dataclass(frozen=True)
class PlaneSlip:
    """Outcome of :func:`solve_plane_slip`.

    Attributes
    ----------
    sliding : (p,) positions in the contact set of the nodes that slid
    distances : (p,) slip distances d_k ≥ 0, metres
    directions : (p, 3) t̂_k; node k moved by −d_k t̂_k
    forces : (m, 3) contact forces after the slip
    displacements : (m, 3) change of the contact displacements
    stuck : positions proposed as sliding that turned out to stick
    residual : relative residual of the system
    free : whether the directions were free (maximum dissipation) or frozen (eq. 6)
    """

    sliding: np.ndarray
    distances: np.ndarray
    directions: np.ndarray
    forces: np.ndarray
    displacements: np.ndarray
    stuck: np.ndarray
    residual: float
    free: bool = False


def solve_plane_slip(stiffness: np.ndarray, held_forces: np.ndarray, candidates: np.ndarray,
                     normal: np.ndarray, mu: float, *, free: bool = False) -> PlaneSlip:
    """Slip the contacts ``candidates`` (outside their cones) back onto their cones.

    With ``free=False`` solves the paper's eq. (6) with directions frozen at
    the start of the slip (:func:`plane_slip_system`); with ``free=True`` the
    directions are unknowns too (:func:`plane_free_slip_system`).  Either is
    solved by :func:`solve_slip` (homotopy continuation).  A node whose root
    has it moving *with* its friction (a negative distance along −t̂, or
    ``f_t·u > 0``) would have to be pushed back: the other slips already put
    it inside its cone, so the worst such node is taken out of the sliding
    set (it sticks) and the system solved again.  For frozen directions, a
    root on the far side of the cone (tangential force reversed,
    ``f_t·t̂ < 0``) is rejected.

    Raises
    ------
    FrictionError
        If the system cannot be solved or only a non-physical root is found.
    """
    f0 = np.asarray(held_forces, dtype=float)
    normal = np.asarray(normal, dtype=float) / np.linalg.norm(normal)
    sliding = np.asarray(candidates, dtype=np.int64).reshape(-1)
    directions = slip_directions(f0[sliding], normal) if len(sliding) else np.zeros((0, 3))
    stuck: list[int] = []
    fscale = max(float(np.abs(f0).max()), np.finfo(float).tiny)
    while True:
        if free:
            system = plane_free_slip_system(stiffness, f0, sliding, normal, mu)
        else:
            system = plane_slip_system(stiffness, f0, sliding, normal, mu, directions)
        sol = solve_slip(system)
        u = sol.displacements[sliding]
        ft = tangential_component(sol.forces[sliding], normal)
        if free:
            dist = np.linalg.norm(u, axis=1)
            # Power of the friction force: must be ≤ 0 (friction opposes the slip).
            power = np.einsum("ki,ki->k", ft, u) / np.maximum(dist * fscale, np.finfo(float).tiny)
            wrong = power
        else:
            dist = sol.x
            wrong = -dist / max(float(np.abs(dist).max()), np.finfo(float).tiny)
        if len(sliding) and wrong.max() > 1e-12:
            j = int(np.argmax(wrong))
            stuck.append(int(sliding[j]))
            log.debug("node at contact position %d sticks (moves with its friction)", sliding[j])
            sliding = np.delete(sliding, j)
            directions = np.delete(directions, j, axis=0)
            continue
        break
    dist = np.maximum(dist, 0.0) if len(sliding) else np.zeros(0)
    if free and len(sliding):
        directions = -u / np.where(dist > 0, dist, 1.0)[:, None]
    if len(sliding) and not free:
        along = np.einsum("ki,ki->k", ft, directions)
        ftn = np.linalg.norm(ft, axis=1)
        fn = normal_component(sol.forces[sliding], normal)
        # With μ > 0 a root on the boundary must keep the friction opposing the slip.
        bad = (along < -1e-9 * np.maximum(ftn, 1e-300)) & (mu * fn > 1e-9 * fscale)
        if bad.any():
            raise FrictionError(f"the slip solution reverses the friction force at {int(bad.sum())} node(s): "
                                "only a non-physical root of eq. (6) was found")
    return PlaneSlip(sliding, dist, directions, sol.forces, sol.displacements, np.asarray(stuck, dtype=np.int64),
                     sol.residual, free)


@dataclass(frozen=True)
class PlaneSettlement:
    """Outcome of :func:`settle_plane_slip`.

    Attributes
    ----------
    displacements : (m, 3) total change of the contact displacements
    forces : (m, 3) contact forces afterwards, every compressive one inside its cone
    slid : (q,) positions in the contact set of every node that slid
    rounds : number of slip systems solved
    fallbacks : rounds in which the full system (6) had no admissible root and
        only the most violating solvable node was slid
    """

    displacements: np.ndarray
    forces: np.ndarray
    slid: np.ndarray
    rounds: int
    fallbacks: int


def settle_plane_slip(stiffness: np.ndarray, held_forces: np.ndarray, normal: np.ndarray, mu: float, *,
                      on_plane: np.ndarray | None = None, rtol: float = CONE_RTOL,
                      min_normal_force: float = 0.0, max_rounds: int = 200) -> PlaneSettlement:
    """Slide contacts on a plane until every compressive contact is inside its friction cone.

    Repeats, on a fixed contact set, paper steps 6–7: the contacts outside
    their cones, together with the contacts that slid in an earlier round and
    still sit on their cone boundary, form P, and eq. (6) is solved for them
    with the slip directions t̂_k frozen at the start of the slip
    (:func:`solve_plane_slip`; a node whose slip comes out negative sticks).
    With frozen directions, (6) need not have a real root: when several
    coupled nodes slide at once, or when a node's own slip turns its
    friction, the force component across t̂_k cannot be relaxed.  The round
    then falls back, in this order, to

    1. the same set P with free directions (:func:`plane_free_slip_system`,
       Coulomb's law with maximum dissipation);
    2. the most violating node alone, frozen direction, then free direction.

    The next round recomputes P and the directions from the new forces;
    rounds continue until no compressive contact violates its cone by more
    than ``rtol · f·n̂``.

    Parameters
    ----------
    stiffness : (3m, 3m) reduced stiffness C of the contact set
    held_forces : (m, 3) contact forces with every contact held
    normal : (3,) the plane's normal pointing into the object
    mu : friction coefficient of the plane
    on_plane : (q,) int, optional
        Positions in the contact set of the nodes touching this plane (default
        all); the others (e.g. fingertip contacts) stay held.
    rtol : relative cone tolerance
    min_normal_force : contacts with a smaller normal force (N) are not tested
        (a contact that has just touched carries zero force up to round-off)
    max_rounds : budget of slip systems

    Raises
    ------
    FrictionError
        If no candidate can be slid or ``max_rounds`` is exhausted.
    """
    c = np.asarray(stiffness, dtype=float)
    mask = np.zeros(len(held_forces), dtype=bool)
    if on_plane is None:
        mask[:] = True
    else:
        mask[np.asarray(on_plane, dtype=np.int64)] = True
    forces = np.asarray(held_forces, dtype=float).copy()
    normal = np.asarray(normal, dtype=float) / np.linalg.norm(normal)
    disp = np.zeros_like(forces)
    slid: set[int] = set()
    fallbacks = 0
    if mask.all():
        # Every contact is on this plane, so their resultant is fixed (it balances the load) whatever
        # the slips: if its tangential part exceeds μ times its normal part, no slip state can hold.
        total = forces.sum(axis=0)
        tn = float(total @ normal)
        tt = float(np.linalg.norm(total - tn * normal))
        if tt > (mu + rtol) * max(tn, 0.0):
            raise FrictionError(f"gross sliding: the contacts' resultant has tangential part {tt:.4g} N > μ × normal part "
                                f"{mu:.4g} × {tn:.4g} N, so friction on this plane cannot hold the object")
    for rounds in range(max_rounds + 1):
        fn = normal_component(forces, normal)
        viol = cone_violation(forces, normal, mu)
        out = np.flatnonzero(mask & (fn > min_normal_force) & (viol > rtol * fn))
        if not len(out):
            return PlaneSettlement(disp, forces, np.array(sorted(slid), dtype=np.int64), rounds, fallbacks)
        if rounds == max_rounds:
            break
        # Nodes that slid earlier and still sit on their cone keep sliding with the new ones.
        boundary = np.array([k for k in sorted(slid) if fn[k] > min_normal_force and abs(viol[k]) <= rtol * fn[k]],
                            dtype=np.int64)
        pset = np.union1d(out, boundary)
        worst = out[np.argsort(-(viol[out] / fn[out]))]
        attempts = [(pset, False), (pset, True)]
        if len(boundary):
            attempts += [(out, False), (out, True)]
        attempts += [(np.array([j]), free) for j in worst for free in (False, True)]
        step, errors = None, []
        for cand, free in attempts:
            try:
                trial = solve_plane_slip(c, forces, cand, normal, mu, free=free)
            except FrictionError as exc:
                errors.append(str(exc))
                continue
            if len(trial.sliding):
                step = trial
                break
            errors.append("every proposed slip moves with the friction")
        if step is None:
            raise FrictionError(f"{len(out)} contact(s) lie outside their friction cones and none can slide back "
                                f"onto its cone; first failure: {errors[0]}")
        if len(cand) != len(pset) or free:
            fallbacks += 1
            log.debug("slip round %d: eq. (6) for all %d nodes had no admissible root; slid %d node(s), free=%s",
                      rounds, len(out), len(step.sliding), free)
        disp += step.displacements
        forces = step.forces
        slid.update(int(k) for k in step.sliding)
    raise FrictionError(f"contacts still outside their friction cones after {max_rounds} slip rounds")


# ------------------------------------------------------------ frictionless (μ = 0)
def frictionless_tangential_displacements(stiffness: np.ndarray, held_forces: np.ndarray, normal: np.ndarray,
                                          gauge: np.ndarray) -> np.ndarray:
    """Tangential contact displacements that remove every friction force (μ = 0).

    With μ = 0 the cone degenerates to its axis and every contact slides
    freely in the plane.  Solve ``(C u)_t = −(F̄_held)_t`` for tangential
    increments u (m, 3), u·n̂ = 0.  The tangential block of C is singular: the
    in-plane rigid motions (two translations and the spin about n̂) change no
    force.  They are fixed by the gauge condition ``gaugeᵀ u = 0``, where
    ``gauge`` (3m, g) holds those rigid motions at the contact DOFs; the
    caller may add any rigid in-plane motion afterwards.

    Returns
    -------
    (m, 3) displacement increments; the forces ``F̄_held + C u`` are normal.
    """
    f0 = np.asarray(held_forces, dtype=float)
    m = len(f0)
    c = np.asarray(stiffness, dtype=float)
    normal = np.asarray(normal, dtype=float) / np.linalg.norm(normal)
    basis = tangent_basis(normal)  # (2, 3)
    # Tangential block of C and of the loads, in the (e1, e2) coordinates of every node.
    ctt = np.einsum("pa,kalb,qb->kplq", basis, c.reshape(m, 3, m, 3), basis, optimize=True).reshape(2 * m, 2 * m)
    rhs = -(f0 @ basis.T).reshape(-1)
    g = np.einsum("pa,kag->kpg", basis, np.asarray(gauge, dtype=float).reshape(m, 3, -1)).reshape(2 * m, -1)
    q, _ = np.linalg.qr(g)
    # Scale the border like the block it borders.
    s = max(float(np.abs(np.diag(ctt)).max()), np.finfo(float).tiny)
    ng = q.shape[1]
    mat = np.block([[ctt, s * q], [s * q.T, np.zeros((ng, ng))]])
    sol = np.linalg.solve(mat, np.concatenate([rhs, np.zeros(ng)]))
    return sol[:2 * m].reshape(m, 2) @ basis
