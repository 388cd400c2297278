"""Deformation from specified contact displacements (paper §II-C, eqs. 3–5).

For a contact index set C = {i_1, …, i_m}, the contact forces F̄ (on the
object) are affine in the contact displacements Δ̄:

    F̄ = C (Δ̄ − D̄) + (mg/√n) e          (eq. 5)

which :class:`ContactResponse` stores as ``F̄ = C Δ̄ + F̄₀``, F̄₀ being the
forces when every contact node is held at its reference position.  Both
backends solve the bordered system (3)

    ⎡A  B⎤ ⎡F̄⎤   ⎡Δ̄ − D̄    ⎤
    ⎣Bᵀ 0⎦ ⎣b ⎦ = ⎣−V₀ᵀ G   ⎦

with B = V̄₀ the orthonormal rigid modes at the contact DOFs.  ``"spectral"``
uses the paper's A = Σ v̄v̄ᵀ/λ and D; ``"sparse"`` uses a generalised inverse
X of K in their place (:mod:`fem_grasp.elastic.compliance`), which gives the same F̄.
"""

from __future__ import annotations

import copy
import logging
import warnings
from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING, Iterable

import numpy as np
import scipy.linalg as la

from ..errors import CollinearContactError
from ..threads import blas_threads_for

if TYPE_CHECKING:
    from .body import Body

__all__ = ["BACKENDS", "COLLINEAR_TOLERANCE", "CollinearContactError", "ContactResponse", "ContactSolution",
           "MAX_CONDITION", "NEIGHBOUR_BACKWARD_ERROR", "NEIGHBOUR_NODES", "NEIGHBOUR_SHARE",
           "WARN_CONDITION", "check_contact_set", "contact_dofs", "contact_response", "equilibrium_residual",
           "neighbour_limit", "principal_submatrix", "solve_contact", "add_symmetric_product", "symmetrize",
           "norm1", "DENSE_BLOCK"]

log = logging.getLogger(__name__)

BACKENDS = ("sparse", "spectral")

#: Contacts whose spread perpendicular to their best-fit line is below this
#: fraction of their extent along it are collinear (Proposition 2).
COLLINEAR_TOLERANCE = 1e-8


#: cond(M) above which a contact set is refused as numerically collinear, and above which it is
#: logged.  Contact sets of real grasps give ~1e4; M's condition number grows as 1/θ² when the
#: contacts approach a line at angle θ, so 1e12 refuses θ below ~1e-6 rad.
MAX_CONDITION = 1e12
WARN_CONDITION = 1e9
#: A contact response keeps the surface rows of its contacts' compliance columns as one (3s, 3m) block when that
#: takes at most this many bytes, from its third surface field on: a field is then one matrix-vector product
#: instead of m small ones, which pays where numpy's per-call overhead dominates (the tomato's 307 surface nodes
#: and 20 contacts, 442 kB, asked for 5-7 fields per contact set).  Copying the block costs about one field, and
#: a large body's fields are limited by memory bandwidth either way: a block per set made the 10k-vertex orange
#: (~3,000 surface nodes, implicit increments of one or two fields per set) 10 % slower.
SURFACE_BLOCK_BYTES = 2 * 2**20
SURFACE_BLOCK_AFTER = 2
#: A contact response is derived from a neighbouring set's (:meth:`ContactResponse.neighbour`) when the two sets
#: differ by at most this many nodes, or :data:`NEIGHBOUR_SHARE` of the set's, where more: each node that joins
#: or leaves is a rank-3 change of M⁻¹ (O(m²) work against the O(m³) of a fresh factorisation and of M⁻¹); the
#: event tracking changes its sets one or two nodes at a time, an implicit increment on a fine patch by tens.
NEIGHBOUR_NODES = 6
#: ... and this share of the larger set: at 830 contacts (the steam bun's finest level at 5 %, its table patch) a
#: fresh response took 0.45 s, one derived across 100 nodes about a tenth of that.
NEIGHBOUR_SHARE = 0.125


def neighbour_limit(m: int) -> int:
    """How many nodes two contact sets, the larger of ``m``, may differ by for one to be derived from the other."""
    return max(NEIGHBOUR_NODES, int(NEIGHBOUR_SHARE * m))
#: Largest backward error ‖M x − r‖∞ / (‖M‖∞ ‖x‖∞) of a derived response's solves (x = M⁻¹ r for a probe r)
#: before it is refused and the set factorised afresh.  A fresh LU solve reaches ~2e-17 here, a chain of 100
#: derived tomato sets 3e-16 at worst (median 3e-17); the bound keeps a derived C within cond(M) × 1e-14 (≈ 1e-10
#: at the cond ≈ 1e4 of real grasps) of a fresh one.
NEIGHBOUR_BACKWARD_ERROR = 1e-14


def contact_dofs(nodes: np.ndarray) -> np.ndarray:
    """(3m,) DOF numbers of the contact nodes, node-major (the paper's ā selection)."""
    return (3 * np.asarray(nodes, dtype=np.int64)[:, None] + np.arange(3)).ravel()


def principal_submatrix(a: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """``a[np.ix_(rows, rows)]``, with zero rows and columns where ``rows`` is negative: copied block by block
    over the runs of consecutive indices (a contact set that changes by a few nodes keeps long runs; 0.2 against
    1.6 ms at 800 rows)."""
    n = len(rows)
    out = np.zeros((n, n)) if (rows < 0).any() else np.empty((n, n))
    cut = np.flatnonzero((np.diff(rows) != 1) | (rows[1:] < 0) | (rows[:-1] < 0)) + 1
    starts, ends = np.concatenate([[0], cut]), np.concatenate([cut, [n]])
    runs = [(int(s), int(rows[s]), int(e - s)) for s, e in zip(starts, ends) if rows[s] >= 0]
    for i0, a0, length in runs:
        for j0, b0, width in runs:
            out[i0:i0 + length, j0:j0 + width] = a[a0:a0 + length, b0:b0 + width]
    return out


#: Rows (and columns) per block of :func:`symmetrize` and :func:`norm1`: a few hundred kilobytes, in cache.
DENSE_BLOCK = 128


def add_symmetric_product(a: np.ndarray, u: np.ndarray, w: np.ndarray) -> None:
    """``a += u w uᵀ`` in place, for a C-ordered square ``a`` and a symmetric ``w``: one BLAS dgemm with β = 1 on
    ``aᵀ`` (Fortran-ordered), as (u w uᵀ)ᵀ is u w uᵀ, without the (n, n) temporary of ``a += u @ (w @ u.T)``
    (a third of that time at 1,500 rows)."""
    b = np.ascontiguousarray(w @ u.T)
    gemm = la.get_blas_funcs("gemm", (a, u, b))
    out = gemm(1.0, u, b, beta=1.0, c=a.T, overwrite_c=True)
    if not np.shares_memory(out, a):  # not updated in place (a not C-ordered): copy the result back
        a[...] = out.T


def symmetrize(a: np.ndarray, block: int = DENSE_BLOCK) -> None:
    """``a ← (a + aᵀ) / 2`` in place, block by block (no (n, n) temporary; the same numbers as the formula)."""
    n = len(a)
    for i in range(0, n, block):
        d = a[i:i + block, i:i + block]
        d[...] = 0.5 * (d + d.T)
        for j in range(i + block, n, block):
            m = a[i:i + block, j:j + block] + a[j:j + block, i:i + block].T
            m *= 0.5
            a[i:i + block, j:j + block] = m
            a[j:j + block, i:i + block] = m.T


def norm1(a: np.ndarray, block: int = DENSE_BLOCK) -> float:
    """‖a‖₁, the largest column sum of |a|, summed block of rows by block of rows (no (n, n) temporary)."""
    sums = np.zeros(a.shape[1])
    for i in range(0, len(a), block):
        sums += np.abs(a[i:i + block]).sum(axis=0)
    return float(sums.max(initial=0.0))


def check_contact_set(points: np.ndarray, nodes: np.ndarray) -> np.ndarray:
    """Validate a contact index set and return it as an int array.

    Raises ``ValueError`` for bad indices and :class:`CollinearContactError`
    for fewer than three nodes or collinear ones (Proposition 2, Theorem 3).
    The collinearity test is scale-free: it compares the second singular value
    of the centred contact positions with the first.
    """
    raw = np.asarray(nodes)
    if raw.ndim != 1 or (raw.size and not np.issubdtype(raw.dtype, np.integer)):
        raise ValueError(f"contact nodes must be a 1-D array of integer node indices, got {raw.dtype} {raw.shape}")
    nodes = raw.astype(np.int64)
    n = len(points)
    bad = (nodes < 0) | (nodes >= n)
    if bad.any():
        raise ValueError(f"contact node {int(nodes[bad][0])} is not a node of the mesh (0 … {n - 1})")
    if len(np.unique(nodes)) != len(nodes):
        raise ValueError("contact nodes must be distinct; a node is listed twice")
    if len(nodes) < 3:
        raise CollinearContactError(
            f"{len(nodes)} contact node(s) cannot hold the body: at least three non-collinear contacts are "
            "needed to fix all six rigid motions (paper, Theorem 3)")
    p = points[nodes] - points[nodes].mean(axis=0)
    s = np.linalg.svd(p, compute_uv=False)
    if s[1] <= COLLINEAR_TOLERANCE * s[0]:
        raise CollinearContactError(
            f"the {len(nodes)} contact nodes are collinear (spread off their common line is {s[1] / s[0]:.2e} "
            "of their extent): the body could rotate about that line, so the deformation is not determined "
            "(paper, Proposition 2 and Theorem 3)")
    return nodes


@dataclass(frozen=True)
class ContactSolution:
    """The deformation of a body with prescribed contact displacements.

    Attributes
    ----------
    nodes : (m,) contact node indices
    forces : (m, 3) contact forces F̄ exerted on the object, newtons
    displacements : (n, 3) displacement field Δ, metres
    strain_energy : ½ΔᵀKΔ, joules (computed when first read: contact tracking makes thousands of
        fields and reads none of their energies)
    """

    nodes: np.ndarray
    forces: np.ndarray
    displacements: np.ndarray
    body: "Body"

    @cached_property
    def strain_energy(self) -> float:
        return self.body.strain_energy(self.displacements)

    @property
    def positions(self) -> np.ndarray:
        """(n, 3) deformed positions p̃ = p + δ."""
        return self.body.mesh.points + self.displacements

    def equilibrium_residual(self) -> tuple[float, float]:
        """Relative force and torque imbalance of contact forces plus gravity; see :func:`equilibrium_residual`."""
        return equilibrium_residual(self.body, self.nodes, self.forces)


def equilibrium_residual(body: "Body", nodes: np.ndarray, forces: np.ndarray,
                         points: np.ndarray | None = None) -> tuple[float, float]:
    """Force and torque imbalance of contact forces and gravity, relative to the loads involved.

    The force residual |Σf_k + ΣG| is divided by mg + Σ|f_k| (the sum of the
    magnitudes being balanced, so that round-off on large squeeze forces is
    judged against those forces), the torque residual by that times the
    body's diameter.  Linear elasticity states equilibrium on the reference
    configuration, so torques are taken about the centre of mass at reference
    positions unless ``points`` is given.
    """
    p = body.mesh.points if points is None else points
    g = body.gravity_loads.reshape(-1, 3)
    c = body.center_of_mass
    f_sum = forces.sum(axis=0) + g.sum(axis=0)
    t_sum = np.cross(p[nodes] - c, forces).sum(axis=0) + np.cross(p - c, g).sum(axis=0)
    scale = body.weight + float(np.linalg.norm(forces, axis=1).sum())
    return float(np.linalg.norm(f_sum) / scale), float(np.linalg.norm(t_sum) / (scale * body.mesh.diameter))


class ContactResponse:
    """Eq. (5) for one contact index set: reduced stiffness C and gravity forces F̄₀.

    Parameters
    ----------
    body : Body
    nodes : (m,) int
        Contact index set; at least three non-collinear distinct nodes.
    backend : {"sparse", "spectral"}
        ``"sparse"`` (default) reuses one sparse factorisation of the body
        across contact sets; ``"spectral"`` follows the paper literally with a
        dense eigendecomposition of K.

    Notes
    -----
    Forces are affine in the contact displacements, ``F̄ = C Δ̄ + F̄₀``; this is
    what makes the slip conditions (6)–(8) quadratic.  Construction costs one
    dense factorisation of the (3m+6)-square matrix M; :meth:`neighbour` derives the response of a set that
    differs by a few nodes from this one's M⁻¹ instead.
    """

    def __init__(self, body: "Body", nodes: np.ndarray, backend: str = "sparse", *,
                 _derived: tuple[np.ndarray, np.ndarray, float, np.ndarray, float] | None = None) -> None:
        if backend not in BACKENDS:
            raise ValueError(f"unknown backend {backend!r}; choose one of {BACKENDS}")
        self.body = body
        self.backend = backend
        # (_derived: M, M⁻¹, B's scale, the rigid modes' right-hand side and cond₁(M) of a set that :meth:`neighbour`
        # has derived and checked already.)
        self.nodes = check_contact_set(body.mesh.points, nodes) if _derived is None else np.array(nodes)
        self.dofs = contact_dofs(self.nodes)
        self._surface_fields = 0  # surface fields asked for so far (see SURFACE_BLOCK_AFTER)
        if backend == "sparse":
            self._null = body.orthonormal_rigid_modes
            d_full = self._gravity_displacement
        else:
            spec = body.spectral
            self._null = spec.null_space
            d_full = spec.gravity_term
        self._d_bar = d_full[self.dofs]
        if _derived is not None:
            self._matrix, inverse, self._scale, self._rhs_rigid, self.condition_estimate = _derived
            self._lu = None
            self.__dict__["_inverse"] = inverse
            return
        # X_cc; the columns X[:, c] stay in the body's cache
        a = body.compliance.contact_block(self.nodes) if backend == "sparse" else spec.compliance_block(self.dofs)
        b = self._null[self.dofs]
        # Scale B so both blocks of M have like magnitudes; b absorbs the scale.
        self._scale = max(float(np.abs(np.diag(a)).max()), np.finfo(float).tiny)
        m3 = len(self.dofs)
        mat = np.zeros((m3 + 6, m3 + 6))
        mat[:m3, :m3] = 0.5 * (a + a.T)
        mat[:m3, m3:] = self._scale * b
        mat[m3:, :m3] = self._scale * b.T
        self._matrix = mat
        self._rhs_rigid = -self._scale * (self._null.T @ body.gravity_loads)
        with warnings.catch_warnings(), blas_threads_for(m3 + 6):
            warnings.simplefilter("ignore", la.LinAlgWarning)
            self._lu = la.lu_factor(mat, check_finite=False)
            gecon = la.lapack.get_lapack_funcs("gecon", (self._lu[0],))
            rcond, _ = gecon(self._lu[0], np.abs(mat).sum(axis=0).max(), norm="1")
        self.condition_estimate = float(1.0 / rcond) if rcond > 0 else np.inf
        if not self.condition_estimate < MAX_CONDITION:
            raise CollinearContactError(
                f"the bordered matrix M of eq. (3) is numerically singular for this contact set (condition "
                f"number ~{self.condition_estimate:.1e}); the contacts are collinear or nearly so, and the rotation "
                "about their line is not determined (Theorem 3)")
        if self.condition_estimate > WARN_CONDITION:
            log.warning("contact set of %d nodes is nearly collinear: cond(M) ~ %.1e, forces lose accuracy",
                        len(self.nodes), self.condition_estimate)

    @property
    def _gravity_displacement(self) -> np.ndarray:
        return self.body.gravity_compliance_field

    def branch(self, body: "Body") -> "ContactResponse":
        """This response for ``body``, a :meth:`~fem_grasp.elastic.body.Body.branch` of its own: the factors and
        fields computed so far shared, the count of surface fields its own (a tracker in a second thread)."""
        twin = copy.copy(self)
        twin.body = body
        return twin

    @property
    def nbytes(self) -> int:
        """Memory held by this response's own dense matrices (M, its LU factors, M⁻¹ and C once computed)."""
        own = [self._matrix, *(self._lu or ()), self.__dict__.get("_inverse"), self.__dict__.get("reduced_stiffness"),
               self.__dict__.get("_surface_block")]
        return sum(a.nbytes for a in own if a is not None)

    @property
    def n_contacts(self) -> int:
        return len(self.nodes)

    @property
    def matrix(self) -> np.ndarray:
        """The bordered matrix M of eq. (3) (B scaled by a constant; see module notes)."""
        return self._matrix

    def condition_number(self) -> float:
        """2-norm condition number of M."""
        return float(np.linalg.cond(self._matrix))

    def _solve_bordered(self, rhs_top: np.ndarray, rhs_bottom: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        m3 = len(self.dofs)
        rhs = np.concatenate([rhs_top, rhs_bottom])
        if self._lu is None:
            sol = self._inverse @ rhs
        else:
            lu, piv = self._lu
            sol = la.lu_solve((lu, piv.copy()), rhs, check_finite=False)  # pivots of its own: see _inverse
        return sol[:m3], sol[m3:] * self._scale

    @cached_property
    def _inverse(self) -> np.ndarray:
        """M⁻¹ ((3m+6)-square): from the LU factors (LAPACK's getri: a third of the time of n solves at 850 rows), or
        kept up to date by :meth:`neighbour`.

        scipy's getri and getrs (``lu_solve``) wrappers turn the pivots 1-based in place around the LAPACK call,
        with the GIL released; a response and its :meth:`branch` share the factors, and two lift tests solve with
        them at once, so each call gets a copy of the pivots (two threads on one pivot array corrupted the heap)."""
        n = len(self.dofs) + 6
        lu, piv = self._lu
        getri, getri_lwork = la.lapack.get_lapack_funcs(("getri", "getri_lwork"), (lu,))
        with blas_threads_for(n):
            inverse, info = getri(lu, piv.copy(), lwork=max(int(getri_lwork(n)[0]), 1))
        if info != 0:  # a zero pivot: the constructor's condition test refuses such a set before this is asked
            raise np.linalg.LinAlgError(f"M is singular (getri info {info})")
        return inverse

    @cached_property
    def reduced_stiffness(self) -> np.ndarray:
        """C (3m×3m): the top-left block of M⁻¹ (eq. 5), symmetric with the rigid modes in its null space."""
        m3 = len(self.dofs)
        c = self._inverse[:m3, :m3]
        if self._lu is None:  # derived by neighbour(), which leaves M⁻¹ exactly symmetric: 0.5 (c + cᵀ) is c
            return np.array(c)
        return 0.5 * (c + c.T)

    def neighbour(self, nodes: np.ndarray) -> "ContactResponse | None":
        """The response of the contact set ``nodes`` derived from this one's M⁻¹, or None where that does not pay
        or would not be accurate (then construct it afresh).

        Nodes of this set missing from ``nodes`` leave M⁻¹ by a Schur complement (a rank-3 downdate each), new
        ones join it by a bordered inverse (the 3a×3a Schur complement S = D − VᵀM⁻¹V of the new rows); the
        result is permuted to the order of ``nodes``.  Derived sets keep this set's scaling of B (any positive
        scale gives the same F̄).  Refused (None): the sparse backend only; sets differing by more than
        :func:`neighbour_limit` nodes; an ill-conditioned or singular result (cond₁(M) above
        :data:`WARN_CONDITION`: the fresh construction warns or refuses with its own message); a backward error
        above :data:`NEIGHBOUR_BACKWARD_ERROR`.

        Raises
        ------
        CollinearContactError
            For the sets the constructor refuses by their nodes alone (:func:`check_contact_set`).
        """
        if self.backend != "sparse":
            return None
        nodes = check_contact_set(self.body.mesh.points, nodes)  # refused as a fresh set would be
        new_set = set(nodes.tolist())
        old = self.nodes.tolist()
        kept_pos = [i for i, k in enumerate(old) if k in new_set]
        removed_pos = [i for i, k in enumerate(old) if k not in new_set]
        kept = [old[i] for i in kept_pos]
        old_set = set(old)
        added = [k for k in nodes.tolist() if k not in old_set]
        if (len(removed_pos) + len(added) > neighbour_limit(max(len(old), len(nodes)))
                or len(kept) + len(added) != len(nodes)):
            return None

        m3, n3 = 3 * len(old), 3 * len(nodes)
        keep = np.concatenate([contact_dofs(kept_pos), np.arange(m3, m3 + 6)])  # in this response's M
        at = {k: i for i, k in enumerate(nodes.tolist())}
        to_kept = np.concatenate([contact_dofs([at[k] for k in kept]), np.arange(n3, n3 + 6)])  # ... and the new one
        to_added = contact_dofs([at[k] for k in added])
        # Everything in the new set's order at once: one gather of this M⁻¹ (the added rows and columns zero
        # until set below), then the removal's and the addition's low-rank terms together,
        # inv_KK − G X Gᵀ + W S⁻¹ Wᵀ with G = M⁻¹_KG, X = (M⁻¹_GG)⁻¹ and W = (M⁻¹_KK − G X Gᵀ) V.
        src = np.full(n3 + 6, -1, dtype=np.int64)
        src[to_kept] = keep
        inv = principal_submatrix(self._inverse, src)
        mat = principal_submatrix(self._matrix, src)
        factors, weights = [], []
        with warnings.catch_warnings():
            warnings.simplefilter("error", la.LinAlgWarning)
            try:
                if removed_pos:  # M⁻¹ of the kept rows: the Schur complement of the removed ones
                    gone = contact_dofs(removed_pos)
                    g = np.zeros((n3 + 6, len(gone)))
                    g[to_kept] = self._inverse[np.ix_(keep, gone)]
                    x = la.solve(self._inverse[np.ix_(gone, gone)], np.eye(len(gone)), assume_a="sym",
                                 check_finite=False)
                    factors.append(g)
                    weights.append(-0.5 * (x + x.T))
                if added:  # bordered by the added rows: [[M_K, V], [Vᵀ, D]]
                    comp = self.body.compliance
                    added_arr, kept_arr = np.asarray(added, dtype=np.int64), np.asarray(kept, dtype=np.int64)
                    x_ka = comp.node_columns(added_arr, rows=kept_arr) if kept else np.zeros((0, 3 * len(added)))
                    x_ak = comp.node_columns(kept_arr, rows=added_arr) if kept else np.zeros((3 * len(added), 0))
                    x_aa = comp.contact_block(added_arr)
                    v = np.zeros((n3 + 6, 3 * len(added)))
                    v[to_kept] = np.vstack([0.5 * (x_ka + x_ak.T), self._scale * self._null[contact_dofs(added_arr)].T])
                    d = 0.5 * (x_aa + x_aa.T)
                    w = inv @ v
                    if removed_pos:
                        w += g @ (weights[0] @ (g.T @ v))
                    s_inv = la.inv(d - v.T @ w, check_finite=False)
                    factors.append(w)
                    weights.append(0.5 * (s_inv + s_inv.T))
            except (np.linalg.LinAlgError, la.LinAlgWarning, ValueError):
                return None
        if factors:
            u = np.hstack(factors)
            add_symmetric_product(inv, u, la.block_diag(*weights))
        if added:
            ws = w @ s_inv
            inv[:, to_added] = -ws
            inv[to_added, :] = -ws.T
            inv[np.ix_(to_added, to_added)] = s_inv
            mat[:, to_added] = v
            mat[to_added, :] = v.T
            mat[np.ix_(to_added, to_added)] = d
        symmetrize(inv)  # M⁻¹ is symmetric: without this its round-off drifts along a chain of updates
        mat_norm = norm1(mat)  # M is symmetric: its ∞-norm too
        condition = float(mat_norm * norm1(inv))
        if not condition < WARN_CONDITION:
            return None
        probe = np.cos(np.arange(len(mat)) * 1.618)  # a fixed probe with no structure aligned to the mesh's
        x = inv @ probe
        backward = float(np.abs(mat @ x - probe).max() / (mat_norm * np.abs(x).max()))
        if not backward <= NEIGHBOUR_BACKWARD_ERROR:
            log.debug("derived contact response refused: backward error %.2e", backward)
            return None
        return ContactResponse(self.body, nodes, self.backend, _derived=(mat, inv, self._scale, self._rhs_rigid,
                                                                             condition))

    @cached_property
    def gravity_forces(self) -> np.ndarray:
        """F̄₀ (m, 3): contact forces with every contact node held at its reference position."""
        f, _ = self._solve_bordered(-self._d_bar, self._rhs_rigid)
        return f.reshape(-1, 3)

    def _check_displacements(self, displacements: np.ndarray) -> np.ndarray:
        d = np.asarray(displacements, dtype=float)
        if d.shape not in ((self.n_contacts, 3), (3 * self.n_contacts,)):
            raise ValueError(f"expected contact displacements of shape ({self.n_contacts}, 3), got {d.shape}")
        if not np.isfinite(d).all():
            raise ValueError("contact displacements contain NaN or infinity")
        return d.reshape(-1)

    def forces(self, displacements: np.ndarray) -> np.ndarray:
        """Contact forces F̄ (m, 3) on the object for contact displacements Δ̄ (m, 3): eq. (5)."""
        d = self._check_displacements(displacements)
        f, _ = self._solve_bordered(d - self._d_bar, self._rhs_rigid)
        return f.reshape(-1, 3)

    def solve(self, displacements: np.ndarray) -> ContactSolution:
        """Contact forces and the whole displacement field (eqs. 3–5 and 4)."""
        d = self._check_displacements(displacements)
        f, b = self._solve_bordered(d - self._d_bar, self._rhs_rigid)
        if self.backend == "sparse":
            field = self.body.compliance.combine(self.nodes, f) + self._gravity_displacement + self._null @ b
        else:
            field = self.body.spectral.displacement(self.dofs, f, b)
        # Restore the prescribed values exactly (they hold to round-off anyway).
        field[self.dofs] = d
        return ContactSolution(self.nodes, f.reshape(-1, 3), field.reshape(-1, 3), self.body)

    @cached_property
    def _surface_block(self) -> np.ndarray | None:
        """The surface rows of the contacts' compliance columns, (3s, 3m), or None above ``SURFACE_BLOCK_BYTES``."""
        if 9 * len(self.body.mesh.surface_nodes) * self.n_contacts * 8 > SURFACE_BLOCK_BYTES:
            return None
        return self.body.compliance.surface_block(self.nodes)

    def surface_displacements(self, displacements: np.ndarray) -> np.ndarray:
        """(s, 3) the displacement field of :meth:`solve` at ``mesh.surface_nodes`` only.

        The sparse backend reads only the surface rows of the cached compliance columns
        (:meth:`~fem_grasp.elastic.compliance.Compliance.combine_surface`): what the contact tracking needs
        at every trial state, a fraction of the cost of the whole field on a large mesh.
        """
        d = self._check_displacements(displacements)
        surface = self.body.mesh.surface_nodes
        if self.backend != "sparse":
            return self.solve(d).displacements[surface]
        f, b = self._solve_bordered(d - self._d_bar, self._rhs_rigid)
        grav, null = self.body.surface_field_terms
        self._surface_fields += 1
        block = self._surface_block if self._surface_fields > SURFACE_BLOCK_AFTER else None
        combined = self.body.compliance.combine_surface(self.nodes, f) if block is None else block @ f
        field = (combined + grav + null @ b).reshape(-1, 3)
        rows, contacts = self._surface_contacts
        field[rows] = d.reshape(-1, 3)[contacts]  # the prescribed values, exactly (as in solve)
        return field

    @cached_property
    def _surface_contacts(self) -> tuple[np.ndarray, np.ndarray]:
        """(rows of ``mesh.surface_nodes``, positions in the contact set) of the contact nodes on the surface."""
        pos = self.body.mesh.surface_index[self.nodes]
        on = np.flatnonzero(pos >= 0)
        return pos[on], on


def contact_response(body: "Body", nodes: np.ndarray, *, backend: str = "sparse",
                     cached: Iterable[ContactResponse] = ()) -> ContactResponse:
    """The response of the contact set ``nodes``: derived (:meth:`ContactResponse.neighbour`) from the response
    among ``cached`` whose set differs least from it, by at most :func:`neighbour_limit` nodes (the first such in
    ``cached`` order on a tie), where that derivation is accepted; else constructed afresh.

    Raises
    ------
    CollinearContactError
        As the constructor does.
    """
    nodes = np.asarray(nodes, dtype=np.int64)
    wanted = set(nodes.tolist())
    parent, near = None, None
    for resp in cached:
        differ = len(wanted.symmetric_difference(resp.nodes.tolist()))
        if differ <= neighbour_limit(max(len(nodes), len(resp.nodes))) and (near is None or differ < near):
            parent, near = resp, differ
    derived = parent.neighbour(nodes) if parent is not None else None
    return derived or ContactResponse(body, nodes, backend=backend)


def solve_contact(body: "Body", nodes: np.ndarray, displacements: np.ndarray, backend: str = "sparse") -> ContactSolution:
    """Deform ``body`` under gravity with contact nodes displaced by ``displacements`` (paper §II-C).

    Parameters
    ----------
    body : Body
    nodes : (m,) int
        The contact index set C, m ≥ 3 non-collinear distinct nodes.
    displacements : (m, 3) float
        Prescribed contact displacements Δ̄ in metres.
    backend : {"sparse", "spectral"}

    Returns
    -------
    ContactSolution
        Forces on the object at the contact nodes, the displacement field and
        the strain energy.  Contact forces and gravity are in equilibrium to
        round-off.

    Raises
    ------
    CollinearContactError
        If fewer than three distinct nodes are given or they are collinear.
    """
    return ContactResponse(body, nodes, backend=backend).solve(displacements)
