"""Tetrahedron quadrature, P1 load vectors and P1 error norms, in NumPy.

Used on the fem_grasp side of the manufactured-solution study, so that no
dolfinx code touches fem_grasp's solution.  The rule is the collapsed
(conical) Gauss–Jacobi product rule (Stroud; Karniadakis & Sherwin §4.1): with
``n`` points per direction it integrates every polynomial of total degree
``2n − 1`` exactly over a tetrahedron.
"""

from __future__ import annotations

from functools import lru_cache
from typing import Callable

import numpy as np
from scipy.special import roots_jacobi

Field = Callable[[np.ndarray], np.ndarray]


@lru_cache(maxsize=None)
def tetrahedron_rule(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Collapsed Gauss–Jacobi rule on the reference tetrahedron {λ ≥ 0, Σλ ≤ 1}.

    Parameters
    ----------
    n : points per direction (``n**3`` points, exact to degree ``2n − 1``)

    Returns
    -------
    bary : (n**3, 4) barycentric coordinates (λ_0, λ_1, λ_2, λ_3) of the points
    weights : (n**3,) weights summing to 1 (the rule integrates the *mean* over the element)
    """
    # Collapsed coordinates a, b, c ∈ [0, 1]; Jacobian (1 − b)(1 − c)² / ... absorbed by Jacobi weights.
    xa, wa = roots_jacobi(n, 0.0, 0.0)
    xb, wb = roots_jacobi(n, 1.0, 0.0)
    xc, wc = roots_jacobi(n, 2.0, 0.0)
    a, b, c = (0.5 * (x + 1.0) for x in (xa, xb, xc))
    wa, wb, wc = 0.5 * wa, 0.25 * wb, 0.125 * wc
    A, B, C = np.meshgrid(a, b, c, indexing="ij")
    W = np.einsum("i,j,k->ijk", wa, wb, wc)
    x = A * (1.0 - B) * (1.0 - C)
    y = B * (1.0 - C)
    z = C
    bary = np.stack([1.0 - x - y - z, x, y, z], axis=-1).reshape(-1, 4)
    w = W.ravel()
    return bary, w / w.sum()


def _chunks(n: int, size: int):
    for start in range(0, n, size):
        yield slice(start, min(start + size, n))


def p1_load_vector(points: np.ndarray, tets: np.ndarray, body_force: Field, n: int = 3,
                   chunk: int = 20000) -> np.ndarray:
    """Consistent P1 load ``F[3a + i] = ∫ f_i φ_a`` (node-major), by quadrature.

    Parameters
    ----------
    points, tets : the mesh
    body_force : callable mapping (N, 3) points to (N, 3) force densities
    n : points per direction of :func:`tetrahedron_rule`
    """
    bary, w = tetrahedron_rule(n)
    out = np.zeros((len(points), 3))
    for sl in _chunks(len(tets), chunk):
        t = tets[sl]
        p = points[t]  # (e, 4, 3)
        vol = np.abs(np.linalg.det(p[:, 1:] - p[:, :1])) / 6.0
        xq = np.einsum("qa,eai->eqi", bary, p)
        fq = body_force(xq.reshape(-1, 3)).reshape(xq.shape)
        fe = np.einsum("q,qa,eqi,e->eai", w, bary, fq, vol)
        for k in range(4):
            np.add.at(out, t[:, k], fe[:, k])
    return out.ravel()


def p1_errors(points: np.ndarray, tets: np.ndarray, uh: np.ndarray, exact: Field, exact_grad: Field,
              lam: float, mu: float, n: int = 4, chunk: int = 20000) -> dict[str, float]:
    """L2 and energy-norm errors of a P1 field against an exact field, and the exact field's norms.

    Parameters
    ----------
    points, tets : the mesh
    uh : (n_nodes, 3) nodal values of the P1 field
    exact : (N, 3) -> (N, 3) exact displacement
    exact_grad : (N, 3) -> (N, 3, 3) its gradient, ``G[:, i, j] = ∂u_i/∂x_j``
    lam, mu : Lamé parameters of the energy norm ∫ σ(e):ε(e)

    Returns
    -------
    dict with ``l2_error``, ``energy_error``, ``l2_norm``, ``energy_norm``
    """
    bary, w = tetrahedron_rule(n)
    acc = dict(l2_error=0.0, energy_error=0.0, l2_norm=0.0, energy_norm=0.0)
    uh = np.asarray(uh, dtype=float).reshape(-1, 3)

    def energy_density(g: np.ndarray) -> np.ndarray:
        eps = 0.5 * (g + np.swapaxes(g, -1, -2))
        tr = np.trace(eps, axis1=-2, axis2=-1)
        return 2.0 * mu * np.sum(eps * eps, axis=(-2, -1)) + lam * tr**2

    for sl in _chunks(len(tets), chunk):
        t = tets[sl]
        p = points[t]
        jac = np.swapaxes(p[:, 1:] - p[:, :1], 1, 2)
        vol = np.abs(np.linalg.det(jac)) / 6.0
        inv = np.linalg.inv(jac)
        grads = np.concatenate([-inv.sum(axis=1, keepdims=True), inv], axis=1)  # (e, 4, 3)
        gh = np.einsum("eai,eaj->eij", uh[t], grads)  # constant ∇u_h per element
        xq = np.einsum("qa,eai->eqi", bary, p)
        uq = np.einsum("qa,eai->eqi", bary, uh[t])
        ue = exact(xq.reshape(-1, 3)).reshape(xq.shape)
        ge = exact_grad(xq.reshape(-1, 3)).reshape(xq.shape + (3,))
        wv = np.einsum("q,e->eq", w, vol)
        acc["l2_error"] += float(np.sum(wv * np.sum((uq - ue) ** 2, axis=-1)))
        acc["l2_norm"] += float(np.sum(wv * np.sum(ue**2, axis=-1)))
        acc["energy_error"] += float(np.sum(wv * energy_density(gh[:, None] - ge)))
        acc["energy_norm"] += float(np.sum(wv * energy_density(ge)))
    return {k: float(np.sqrt(v)) for k, v in acc.items()}
