"""An elastic body: a tetrahedral mesh with a material and a weight (paper §II-B)."""

from __future__ import annotations

import copy
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp

from ..errors import MaterialError
from ..mesh.tetmesh import TetMesh
from ..validation import check_material, check_positive
from . import fem

__all__ = ["Body", "FULL_COLUMNS_MAX_NODES"]


if TYPE_CHECKING:
    from .compliance import Compliance
    from .spectral import SpectralDecomposition

#: Above this many vertices a body caches only the surface rows of its compliance columns (:attr:`Body.compliance`).
FULL_COLUMNS_MAX_NODES = 20_000


class Body:
    """A homogeneous linear-elastic solid under gravity.

    Parameters
    ----------
    mesh : TetMesh
        Reference (undeformed) shape, metres.
    young : float
        Young's modulus E in pascals, E > 0.
    poisson : float
        Poisson's ratio ν, −1 < ν < ½.
    weight : float, optional
        The object's weight mg in newtons.  Give exactly one of ``weight`` or
        ``density``.
    density : float, optional
        Mass density in kg/m³.
    gravity : float
        Gravitational acceleration g in m/s² (the paper uses 9.8).  Gravity
        always acts along −z.

    Raises
    ------
    MaterialError
        (a ``ValueError``) for E ≤ 0, ν ∉ (−1, ½), a weight, density or g
        that is not a positive finite number, non-numbers, or both/neither
        of weight and density.

    Notes
    -----
    Heavy quantities (K, its factorisation, the eigendecomposition) are
    computed on first use and cached; the body is otherwise immutable.
    """

    def __init__(self, mesh: TetMesh, young: float, poisson: float, *, weight: float | None = None,
                 density: float | None = None, gravity: float = fem.STANDARD_GRAVITY) -> None:
        if not isinstance(mesh, TetMesh):
            raise TypeError(f"mesh must be a TetMesh, got {type(mesh).__name__}")
        young, poisson = check_material(young, poisson)
        gravity = check_positive(gravity, "gravity", "m/s² (an acceleration)")
        if (weight is None) == (density is None):
            raise MaterialError("give exactly one of weight (N) or density (kg/m³)")
        if weight is not None:
            weight = check_positive(weight, "weight", "newtons (a force)")
            density = weight / (gravity * mesh.volume)
        else:
            density = check_positive(density, "density", "kg/m³")
        self.mesh = mesh
        self.young = float(young)
        self.poisson = float(poisson)
        self.density = float(density)
        self.gravity = float(gravity)

    def __repr__(self) -> str:
        return (f"Body({self.mesh!r}, young={self.young:g}, poisson={self.poisson:g}, "
                f"weight={self.weight:.4g} N)")

    def with_material(self, young: float | None = None, poisson: float | None = None) -> "Body":
        """The same shape and weight with another E and/or ν."""
        return Body(self.mesh, self.young if young is None else young,
                    self.poisson if poisson is None else poisson, density=self.density, gravity=self.gravity)

    def transformed(self, rotation: np.ndarray | None = None, translation: np.ndarray | None = None) -> "Body":
        """The same body rigidly moved (see :meth:`TetMesh.transformed`).

        If this body's sparse compliance is already factorised, the moved body shares that
        factorisation, turned with it (:meth:`~fem_grasp.elastic.compliance.Compliance.rotated`), instead of
        factorising its own: the resting pose of a factorised body costs no second factorisation, and
        holds no second factor.
        """
        moved = Body(self.mesh.transformed(rotation, translation), self.young, self.poisson,
                     density=self.density, gravity=self.gravity)
        if "compliance" in self.__dict__:
            moved.__dict__["compliance"] = self.compliance.rotated(np.eye(3) if rotation is None else rotation)
        return moved

    def branch(self) -> "Body":
        """The same body, sharing what it has computed, with compliance column caches of its own
        (:meth:`~fem_grasp.elastic.compliance.Compliance.branch`): for a tracker in a second thread."""
        twin = copy.copy(self)
        if "compliance" in self.__dict__:
            twin.__dict__["compliance"] = self.compliance.branch()
        return twin

    # ------------------------------------------------------------ physics
    @property
    def n_nodes(self) -> int:
        return self.mesh.n_points

    @property
    def mass(self) -> float:
        """m in kg."""
        return self.density * self.mesh.volume

    @property
    def weight(self) -> float:
        """mg in newtons."""
        return self.mass * self.gravity

    @cached_property
    def center_of_mass(self) -> np.ndarray:
        """Centre of mass of the uniform-density mesh (the volume centroid)."""
        p = self.mesh.points[self.mesh.tets].mean(axis=1)
        v = self.mesh.volumes
        return (v @ p) / v.sum()

    @cached_property
    def stiffness(self) -> sp.csr_matrix:
        """K (3n×3n, sparse) with strain energy U = ½ΔᵀKΔ (eq. 2)."""
        return fem.stiffness_matrix(self.mesh.points, self.mesh.tets, self.young, self.poisson)

    @cached_property
    def gravity_loads(self) -> np.ndarray:
        """G (3n,), nodal gravity forces; G·t_z = −mg (§II-B)."""
        return fem.gravity_loads(self.mesh.points, self.mesh.tets, self.density, self.gravity)

    @cached_property
    def rigid_modes(self) -> np.ndarray:
        """(3n, 6) t_x, t_y, t_z, r_x, r_y, r_z of Theorem 1, rotations about the centre of mass."""
        return fem.rigid_modes(self.mesh.points, self.center_of_mass)

    @cached_property
    def orthonormal_rigid_modes(self) -> np.ndarray:
        """(3n, 6) the rigid modes orthonormalised (the paper's v_{3n−5} … v_{3n})."""
        from .spectral import orthonormal_modes

        return orthonormal_modes(self.rigid_modes)

    def strain_energy(self, displacements: np.ndarray) -> float:
        """U = ½ΔᵀKΔ (eq. 2) for a (n, 3) or (3n,) displacement field."""
        u = np.asarray(displacements, dtype=float).reshape(-1)
        if u.size != 3 * self.n_nodes:
            raise ValueError(f"expected {3 * self.n_nodes} displacement components, got {u.size}")
        bad = ~np.isfinite(u)
        if bad.any():
            k = int(np.argmax(bad))
            raise ValueError(f"displacement field has NaN or infinite components; first is node {k // 3}, "
                             f"component {'xyz'[k % 3]}")
        return 0.5 * float(u @ (self.stiffness @ u))

    # ------------------------------------------------------ contact solves
    @cached_property
    def compliance(self) -> "Compliance":
        """Factorised generalised inverse of K (sparse backend).

        Each contact node's compliance columns are cached with all 3n rows up to
        :data:`FULL_COLUMNS_MAX_NODES` vertices, and with the surface rows only above
        (72 n bytes a node: 7.5 MB at 104k vertices, against about 1 MB).  The
        contact tracking reads only the surface; a whole field (a snapshot's
        positions, written out) then costs one sparse solve.
        """
        from .compliance import Compliance

        surface = self.mesh.surface_nodes
        lean = self.n_nodes > FULL_COLUMNS_MAX_NODES
        return Compliance(self.stiffness, self.mesh.points, self.rigid_modes, rows=surface if lean else None,
                          surface=surface)

    @cached_property
    def gravity_compliance_field(self) -> np.ndarray:
        """X G (3n,): the grounded compliance applied to gravity (sparse backend).

        The same for every contact set, so computed once per body (one full solve); each
        :class:`~fem_grasp.elastic.response.ContactResponse` takes its D̄ of eq. (3) and its field from it.
        """
        return self.compliance.apply(self.gravity_loads)

    @cached_property
    def surface_dofs(self) -> np.ndarray:
        """(3s,) the DOFs of ``mesh.surface_nodes``, in that order."""
        return (3 * self.mesh.surface_nodes[:, None] + np.arange(3)).ravel()

    @cached_property
    def surface_field_terms(self) -> tuple[np.ndarray, np.ndarray]:
        """The surface rows of X G and of the orthonormal rigid modes (sparse backend's surface fields)."""
        return self.gravity_compliance_field[self.surface_dofs], self.orthonormal_rigid_modes[self.surface_dofs]

    @cached_property
    def spectral(self) -> "SpectralDecomposition":
        """K = VΛVᵀ and D of §II-B/C (spectral backend; dense, O(n³))."""
        from .spectral import spectral_decomposition

        return spectral_decomposition(self.stiffness, self.rigid_modes, self.gravity_loads)
