"""The paper's spectral quantities (§II-B, §II-C): K = VΛVᵀ and the vector D.

This is the faithful, O(n³) reference route.  It is computed only when a
caller asks for the ``"spectral"`` backend.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import scipy.linalg as la
import scipy.sparse as sp

__all__ = ["SpectralDecomposition", "orthonormal_modes", "spectral_decomposition"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class SpectralDecomposition:
    """Positive eigenpairs of K, its orthonormal null space, and D.

    Attributes
    ----------
    eigenvalues : (3n−6,) λ_1 … λ_{3n−6}
    eigenvectors : (3n, 3n−6) v_1 … v_{3n−6}
    null_space : (3n, 6) v_{3n−5} … v_{3n}, the rigid modes orthonormalised
        by Gram–Schmidt, as in the paper
    gravity_term : (3n,) D = Σ (v_kᵀG / λ_k) v_k
    """

    eigenvalues: np.ndarray
    eigenvectors: np.ndarray
    null_space: np.ndarray
    gravity_term: np.ndarray

    def compliance_block(self, dofs: np.ndarray) -> np.ndarray:
        """The paper's A = Σ_k v̄_k v̄_kᵀ / λ_k restricted to ``dofs``."""
        v = self.eigenvectors[dofs]
        return (v / self.eigenvalues) @ v.T

    def displacement(self, dofs: np.ndarray, forces: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Eq. (4): Δ = Σ (v̄_kᵀF̄/λ_k) v_k + (v_{3n−5} … v_{3n}) b + D."""
        coeff = (self.eigenvectors[dofs].T @ forces) / self.eigenvalues
        return self.eigenvectors @ coeff + self.null_space @ b + self.gravity_term


def orthonormal_modes(modes: np.ndarray) -> np.ndarray:
    """Gram–Schmidt (QR) orthonormalisation of the six rigid modes."""
    q, _ = np.linalg.qr(modes)
    return q


def spectral_decomposition(stiffness: sp.spmatrix, modes: np.ndarray, gravity: np.ndarray) -> SpectralDecomposition:
    """Dense eigendecomposition of K (paper §II-B).  O(n³) time, O(n²) memory."""
    n = stiffness.shape[0]
    log.info("dense eigendecomposition of a %d x %d stiffness matrix", n, n)
    lam, vec = la.eigh(stiffness.toarray())
    null = orthonormal_modes(modes)
    # The six smallest eigenvalues belong to the rigid modes; remove any
    # round-off component along them from the others.
    lam, vec = lam[6:], vec[:, 6:]
    vec = vec - null @ (null.T @ vec)
    d = vec @ ((vec.T @ gravity) / lam)
    return SpectralDecomposition(lam, vec, null, d)
