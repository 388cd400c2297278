"""Linear P1 finite elements for 3D elasticity (paper §II-A, §II-B).

Pure functions over arrays.  Degrees of freedom are node-major: DOF ``3*k + i``
is component ``i`` (x, y, z) of the displacement δ_k of node ``k``, matching
the paper's Δ = (δ_1ᵀ, …, δ_nᵀ)ᵀ.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..mesh.tetmesh import signed_volumes
from ..validation import check_material

__all__ = ["ASSEMBLY_BLOCK", "STANDARD_GRAVITY", "StiffnessPattern", "element_dofs", "element_stiffness",
           "gravity_loads", "lame_parameters", "lumped_volumes", "rigid_modes", "shape_gradients",
           "stiffness_matrix", "stiffness_pattern"]


#: Gravitational acceleration used by the paper (m/s²).
STANDARD_GRAVITY = 9.8


def lame_parameters(young: float, poisson: float) -> tuple[float, float]:
    """Lamé's λ and shear modulus μ from E and ν.

    Eq. (2) is ``∫ μ ε:ε + (λ/2)(tr ε)² dV`` with μ = E/(2(1+ν)) and
    λ/2 = μ ν/(1−2ν).
    """
    young, poisson = check_material(young, poisson, warn=False)
    mu = young / (2.0 * (1.0 + poisson))
    lam = young * poisson / ((1.0 + poisson) * (1.0 - 2.0 * poisson))
    return lam, mu


def shape_gradients(points: np.ndarray, tets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Gradients of the four P1 shape functions in every tetrahedron.

    With edge vectors e_k = x_k − x_0 (k = 1, 2, 3) and det = e_1·(e_2×e_3),
    ∇φ_1 = (e_2×e_3)/det, ∇φ_2 = (e_3×e_1)/det, ∇φ_3 = (e_1×e_2)/det (the rows
    of the inverse Jacobian, in closed form) and ∇φ_0 = −(∇φ_1+∇φ_2+∇φ_3).

    Returns
    -------
    grads : (t, 4, 3) array
        ``grads[e, a]`` is ∇φ_a on element ``e`` (constant inside it).
    volumes : (t,) array
        Signed element volumes.

    Raises
    ------
    ValueError
        If an element has zero volume (its shape functions are undefined).
    """
    points = np.asarray(points, dtype=float)
    tets = np.asarray(tets)
    x0 = points[tets[:, 0]]
    e1, e2, e3 = (points[tets[:, k]] - x0 for k in (1, 2, 3))
    grads = np.empty((len(tets), 4, 3))
    grads[:, 1] = np.cross(e2, e3)
    grads[:, 2] = np.cross(e3, e1)
    grads[:, 3] = np.cross(e1, e2)
    det = np.einsum("ti,ti->t", e1, grads[:, 1])
    flat = det == 0.0
    if flat.any():
        raise ValueError(f"{int(flat.sum())} tetrahedra have zero volume (first: element {int(np.argmax(flat))}); "
                         "P1 shape gradients are undefined there")
    grads[:, 1:] /= det[:, None, None]
    grads[:, 0] = -(grads[:, 1] + grads[:, 2] + grads[:, 3])
    return grads, det / 6.0


def element_dofs(tets: np.ndarray) -> np.ndarray:
    """(t, 12) global DOF numbers of each element, node-major."""
    return (3 * tets[:, :, None] + np.arange(3)).reshape(len(tets), 12)


def element_stiffness(grads: np.ndarray, volumes: np.ndarray, lam: float, mu: float) -> np.ndarray:
    """(t, 12, 12) element stiffness matrices, the Hessian of eq. (2) on each element.

    ``K_e[a i, b j] = V (λ ∂_iφ_a ∂_jφ_b + μ ∂_jφ_a ∂_iφ_b + μ δ_ij ∇φ_a·∇φ_b)``.

    Every entry is formed from the same products in the same order as its
    transpose partner, so each K_e is exactly symmetric.
    """
    t = len(grads)
    flat = grads.reshape(t, 12)
    outer = (flat[:, :, None] * flat[:, None, :]).reshape(t, 4, 3, 4, 3)  # ∂_iφ_a ∂_jφ_b
    ke = lam * outer
    ke += mu * outer.transpose(0, 1, 4, 3, 2)  # ∂_jφ_a ∂_iφ_b
    dots = mu * np.einsum("tak,tbk->tab", grads, grads)
    for i in range(3):
        ke[:, :, i, :, i] += dots
    ke *= volumes[:, None, None, None, None]
    return ke.reshape(t, 12, 12)


@dataclass(frozen=True)
class StiffnessPattern:
    """The sparsity of K for one mesh topology, at the level of 3×3 node blocks.

    Built once per ``tets`` by :func:`stiffness_pattern` and reusable for any
    material or node positions.  Only the blocks (I, J) with I ≤ J are
    computed; the others are their transposes, which makes K exactly
    symmetric.

    Attributes
    ----------
    n_points : number of nodes n (K is 3n × 3n)
    indptr, indices : node-level CSR structure of K (sorted column indices)
    entries : (10t,) element blocks, coded e·16 + 4a + b (row node a, column node b of element e,
        oriented so that node a ≤ node b), grouped by the upper block they add to
    starts : (n_upper,) where each upper block's group begins in ``entries``
    source : (n_blocks,) the upper block each block of K copies
    transposed : (n_blocks,) whether it copies it transposed (the blocks below the diagonal)
    """

    n_points: int
    indptr: np.ndarray
    indices: np.ndarray
    entries: np.ndarray
    starts: np.ndarray
    source: np.ndarray
    transposed: np.ndarray

    @property
    def n_blocks(self) -> int:
        return len(self.indices)

    @property
    def n_upper(self) -> int:
        return len(self.starts)


#: The ten node pairs (a, b), a ≤ b, of a tetrahedron.
_PAIR_A = np.array([0, 0, 0, 0, 1, 1, 1, 2, 2, 3])
_PAIR_B = np.array([0, 1, 2, 3, 1, 2, 3, 2, 3, 3])


def stiffness_pattern(tets: np.ndarray, n_points: int) -> StiffnessPattern:
    """Node-block sparsity pattern of K and the element blocks summed into each block (:class:`StiffnessPattern`)."""
    tets = np.asarray(tets, dtype=np.int64)
    node_a, node_b = tets[:, _PAIR_A], tets[:, _PAIR_B]
    swap = node_a > node_b
    low, high = np.where(swap, node_b, node_a), np.where(swap, node_a, node_b)
    local_a, local_b = np.where(swap, _PAIR_B, _PAIR_A), np.where(swap, _PAIR_A, _PAIR_B)
    codes = (np.arange(len(tets))[:, None] * 16 + 4 * local_a + local_b).ravel()
    keys = (low * n_points + high).ravel()
    del node_a, node_b, swap, low, high, local_a, local_b
    order = np.argsort(keys)
    sorted_keys = keys[order]
    entries = codes[order]
    del keys, codes, order
    first = np.empty(len(sorted_keys), dtype=bool)
    first[0] = True
    np.not_equal(sorted_keys[1:], sorted_keys[:-1], out=first[1:])
    starts = np.flatnonzero(first)
    up_rows, up_cols = np.divmod(sorted_keys[starts], n_points)
    del sorted_keys, first
    off = np.flatnonzero(up_rows != up_cols)
    rows = np.concatenate([up_rows, up_cols[off]])
    cols = np.concatenate([up_cols, up_rows[off]])
    source = np.concatenate([np.arange(len(up_rows)), off])
    transposed = np.concatenate([np.zeros(len(up_rows), dtype=bool), np.ones(len(off), dtype=bool)])
    perm = np.argsort(rows * n_points + cols)
    rows, cols, source, transposed = rows[perm], cols[perm], source[perm], transposed[perm]
    indptr = np.zeros(n_points + 1, dtype=np.int64)
    np.cumsum(np.bincount(rows, minlength=n_points), out=indptr[1:])
    small = 9 * len(cols) < np.iinfo(np.int32).max and len(entries) < np.iinfo(np.int32).max
    index_type = np.int32 if small else np.int64
    return StiffnessPattern(int(n_points), indptr.astype(index_type), cols.astype(index_type),
                            entries.astype(index_type), starts.astype(np.int64), source.astype(index_type),
                            transposed)


#: Element blocks (3×3) formed per pass of the assembly: bounds its temporaries to ~20 MB each.
ASSEMBLY_BLOCK = 262144


def stiffness_matrix(points: np.ndarray, tets: np.ndarray, young: float, poisson: float,
                     pattern: StiffnessPattern | None = None) -> sp.csr_matrix:
    """Assemble the 3n×3n stiffness matrix K with U = ½ΔᵀKΔ (eq. 2), vectorised over elements.

    Each 3×3 block of K is the sum over the elements e sharing nodes I = e_a
    and J = e_b of ``V_e (λ ∇φ_a ∇φ_bᵀ + μ ∇φ_b ∇φ_aᵀ + μ (∇φ_a·∇φ_b) I₃)``
    (:func:`element_stiffness`).  The blocks with I ≤ J are formed in the
    order of a precomputed sparsity pattern, a few hundred thousand element
    blocks at a time, and summed with ``np.add.reduceat``; the blocks below
    the diagonal are their transposes.  No (t, 12, 12) array and no COO
    duplicates are built, so peak memory stays near the size of K, and K is
    exactly symmetric.

    Parameters
    ----------
    points : (n, 3) node coordinates
    tets : (t, 4) node indices of each tetrahedron
    young, poisson : E (Pa) and ν
    pattern : StiffnessPattern, optional
        From :func:`stiffness_pattern` for these ``tets``; built here when
        omitted (a third to a half of the assembly time; pass it when
        assembling the same mesh repeatedly).
    """
    lam, mu = lame_parameters(young, poisson)
    n = len(points)
    if pattern is None:
        pattern = stiffness_pattern(tets, n)
    elif pattern.n_points != n or len(pattern.entries) != 10 * len(tets):
        raise ValueError(f"stiffness pattern is for {pattern.n_points} nodes and {len(pattern.entries) // 10} "
                         f"elements, not for this mesh ({n} nodes, {len(tets)} elements)")
    grads, vol = shape_gradients(points, tets)
    grads = grads.reshape(-1, 3)  # row 4e + a is ∇φ_a on element e
    vol = np.abs(vol)
    nu = pattern.n_upper
    n_entries = len(pattern.entries)
    upper = np.empty((nu, 3, 3))
    starts = pattern.starts
    first = 0
    while first < nu:
        # Whole upper blocks per pass, about ASSEMBLY_BLOCK element blocks each.
        lo = int(starts[first])
        last = int(np.searchsorted(starts, lo + ASSEMBLY_BLOCK, side="left"))
        last = min(max(last, first + 1), nu)
        hi = int(starts[last]) if last < nu else n_entries
        ent = pattern.entries[lo:hi].astype(np.int64)
        elem = ent >> 4
        ga = grads[(elem << 2) + ((ent >> 2) & 3)]
        gb = grads[(elem << 2) + (ent & 3)]
        outer = ga[:, :, None] * gb[:, None, :]  # ∂_iφ_a ∂_jφ_b
        blk = lam * outer
        blk += mu * outer.transpose(0, 2, 1)  # ∂_jφ_a ∂_iφ_b
        dots = mu * np.einsum("ki,ki->k", ga, gb)
        for i in range(3):
            blk[:, i, i] += dots
        blk *= vol[elem][:, None, None]
        upper[first:last] = np.add.reduceat(blk, starts[first:last] - lo, axis=0)
        first = last
    blocks = upper[pattern.source]
    lower = pattern.transposed
    blocks[lower] = blocks[lower].transpose(0, 2, 1)
    k = sp.bsr_matrix((blocks, pattern.indices, pattern.indptr), shape=(3 * n, 3 * n))
    return k.tocsr()


def lumped_volumes(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """(n,) volume charged to each node: a quarter of each adjacent element's volume."""
    v = np.abs(signed_volumes(points, tets))
    return np.bincount(tets.ravel(), weights=np.repeat(v / 4.0, 4), minlength=len(points))


def gravity_loads(points: np.ndarray, tets: np.ndarray, density: float, gravity: float = STANDARD_GRAVITY,
                  down: np.ndarray | None = None) -> np.ndarray:
    """Nodal gravity vector G (3n,) of §II-B: each element's mass charged evenly to its four vertices.

    ``down`` is the unit direction of gravity (default −z).
    """
    down = np.array([0.0, 0.0, -1.0]) if down is None else np.asarray(down, dtype=float)
    m = density * lumped_volumes(points, tets)
    return (gravity * m[:, None] * down[None, :]).ravel()


def rigid_modes(points: np.ndarray, center: np.ndarray | None = None) -> np.ndarray:
    """(3n, 6) rigid-body fields of Theorem 1: t_x, t_y, t_z, r_x, r_y, r_z.

    Rotations are taken about ``center`` (the paper puts the origin at the
    centre of mass); r_x displaces (x, y, z) by (0, −z, y), and so on.
    """
    c = np.zeros(3) if center is None else np.asarray(center, dtype=float)
    x, y, z = (points - c).T
    n = len(points)
    zero, one = np.zeros(n), np.ones(n)
    fields = [
        (one, zero, zero),
        (zero, one, zero),
        (zero, zero, one),
        (zero, -z, y),
        (z, zero, -x),
        (-y, x, zero),
    ]
    return np.stack([np.stack(f, axis=1).ravel() for f in fields], axis=1)
