"""FEniCSx/dolfinx (0.5.x) reference for fem_grasp's P1 elasticity.

Everything fem_grasp computes from a mesh — the stiffness matrix K, the
gravity vector G, strain energies and Dirichlet contact solves — is recomputed
here with dolfinx's own assembly and PETSc's solvers, then brought into
fem_grasp's node-major numbering (DOF ``3k + i`` is component ``i`` of node
``k``) so the two can be compared entry by entry.

dolfinx reorders vertices and degrees of freedom.  :class:`DolfinxModel` maps
them back by coordinates (a k-d tree over ``V.tabulate_dof_coordinates()``) and
checks that the map is a bijection.

The variational forms are written independently of fem_grasp's formulae:
K from ``a(u, v) = ∫ σ(u):ε(v)`` with ``σ = 2με + λ tr(ε) I``, strain energy
from the paper's eq. (2) in engineering strains, gravity as the consistent P1
load ``∫ ρ g·φ_a`` (which, for P1, charges each element's mass evenly to its
four vertices, exactly as §II-B does).  Material constants enter as dolfinx
``Constant`` objects so the forms compile once per session.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

if TYPE_CHECKING:
    from fem_grasp import TetMesh

log = logging.getLogger(__name__)

#: Two nodes closer than this fraction of the mesh diameter are taken as the same point.
MATCH_TOLERANCE = 1e-10


def lame(young: float, poisson: float) -> tuple[float, float]:
    """(λ, μ) from Young's modulus and Poisson's ratio (written out here, not taken from fem_grasp)."""
    mu = young / (2.0 * (1.0 + poisson))
    lam = young * poisson / ((1.0 + poisson) * (1.0 - 2.0 * poisson))
    return lam, mu


def dolfinx_mesh(mesh: "TetMesh"):
    """A serial dolfinx mesh (``MPI.COMM_SELF``) with the same vertices and tetrahedra."""
    import dolfinx.mesh
    import ufl
    from mpi4py import MPI

    domain = ufl.Mesh(ufl.VectorElement("Lagrange", "tetrahedron", 1))
    return dolfinx.mesh.create_mesh(MPI.COMM_SELF, np.asarray(mesh.tets, dtype=np.int64),
                                    np.asarray(mesh.points, dtype=np.float64), domain)


def match_points(reference: np.ndarray, query: np.ndarray, scale: float) -> np.ndarray:
    """Index into ``reference`` of each row of ``query``, which must be a permutation of it.

    Raises
    ------
    ValueError
        If some query point has no reference point within ``MATCH_TOLERANCE * scale``
        or the match is not one-to-one.
    """
    dist, idx = cKDTree(reference).query(query)
    if len(query) != len(reference) or dist.max(initial=0.0) > MATCH_TOLERANCE * scale:
        raise ValueError(f"dolfinx dof coordinates do not match the mesh points (max distance {dist.max():.3e})")
    if len(np.unique(idx)) != len(idx):
        raise ValueError("dof-to-node map is not a bijection (coincident points?)")
    return idx


def to_scipy(mat) -> sp.csr_matrix:
    """A SciPy CSR copy of an assembled serial PETSc matrix."""
    indptr, indices, data = mat.getValuesCSR()
    return sp.csr_matrix((data.copy(), indices.copy(), indptr.copy()), shape=mat.getSize())


def _mumps(mat, symmetric: bool = True):
    from .linalg import mumps_solver

    return mumps_solver(mat, symmetric=symmetric)


def _solve_linear(a: Any, L: Any, bc: Any, V: Any) -> Any:
    """The solution of the linear problem a(u, v) = L(v) with the Dirichlet condition ``bc`` (MUMPS)."""
    import dolfinx.fem.petsc as fp
    from dolfinx import fem
    from petsc4py import PETSc

    A = fp.assemble_matrix(a, bcs=[bc])
    A.assemble()
    b = fp.assemble_vector(L)
    fp.apply_lifting(b, [a], bcs=[[bc]])
    b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    fp.set_bc(b, [bc])
    uh = fem.Function(V)
    ksp = _mumps(A)
    ksp.solve(b, uh.vector)
    uh.x.scatter_forward()
    for obj in (A, b, ksp):  # PETSc objects are freed by hand
        obj.destroy()
    return uh


@dataclass(frozen=True)
class DolfinxContactSolution:
    """A dolfinx Dirichlet contact solve, in fem_grasp's numbering.

    Attributes
    ----------
    nodes : (m,) contact nodes (fem_grasp numbering)
    forces : (m, 3) forces on the object at the contact nodes, ``(KΔ − G)_c``
    displacements : (n, 3) displacement field Δ
    strain_energy : eq. (2) evaluated by dolfinx on the solution
    seconds : wall time of assembly and solve
    """

    nodes: np.ndarray
    forces: np.ndarray
    displacements: np.ndarray
    strain_energy: float
    seconds: float


class DolfinxModel:
    """dolfinx P1 vector space on a :class:`~fem_grasp.TetMesh`, with fem_grasp's DOF numbering.

    Parameters
    ----------
    mesh : TetMesh

    Attributes
    ----------
    msh : dolfinx.mesh.Mesh
    V : dolfinx.fem.FunctionSpace, P1 vector-valued, block size 3
    node_of_block : (n,) fem_grasp node of each dolfinx block DOF
    perm : (3n,) dolfinx DOF of each fem_grasp DOF, ``perm[3k + i] = 3 b + i``
    """

    def __init__(self, mesh: "TetMesh") -> None:
        import dolfinx.fem as fem
        import ufl

        self.mesh = mesh
        self.msh = dolfinx_mesh(mesh)
        self.V = fem.VectorFunctionSpace(self.msh, ("CG", 1))
        if self.V.dofmap.index_map_bs != 3:
            raise RuntimeError("expected a blocked vector space with block size 3")
        coords = self.V.tabulate_dof_coordinates()
        self.node_of_block = match_points(mesh.points, coords, mesh.diameter)
        block_of_node = np.empty_like(self.node_of_block)
        block_of_node[self.node_of_block] = np.arange(len(self.node_of_block))
        self.block_of_node = block_of_node
        self.perm = (3 * block_of_node[:, None] + np.arange(3)).ravel()
        self._lam = fem.Constant(self.msh, 1.0)
        self._mu = fem.Constant(self.msh, 1.0)
        self._young = fem.Constant(self.msh, 1.0)
        self._poisson = fem.Constant(self.msh, 0.0)
        self._body_force = fem.Constant(self.msh, np.zeros(3))
        u, v = ufl.TrialFunction(self.V), ufl.TestFunction(self.V)
        self._a = fem.form(ufl.inner(self._stress(u), _strain(v)) * ufl.dx)
        self._L = fem.form(ufl.inner(self._body_force, v) * ufl.dx)
        self._field = fem.Function(self.V)
        self._energy = fem.form(paper_energy_density(self._field, self._young, self._poisson) * ufl.dx)

    # ------------------------------------------------------------ helpers
    def _stress(self, w):
        import ufl

        eps = _strain(w)
        return 2.0 * self._mu * eps + self._lam * ufl.tr(eps) * ufl.Identity(3)

    def set_material(self, young: float, poisson: float) -> None:
        lam, mu = lame(young, poisson)
        self._lam.value = lam
        self._mu.value = mu
        self._young.value = young
        self._poisson.value = poisson

    def to_fem(self, vec: np.ndarray) -> np.ndarray:
        """A dolfinx-ordered (3n,) vector in fem_grasp order."""
        return np.asarray(vec)[self.perm]

    def to_dolfinx(self, vec: np.ndarray) -> np.ndarray:
        """A fem_grasp-ordered (3n,) vector in dolfinx order."""
        out = np.empty(len(self.perm))
        out[self.perm] = np.asarray(vec, dtype=float).reshape(-1)
        return out

    def function(self, vec: np.ndarray):
        """A dolfinx Function holding a fem_grasp-ordered (3n,) or (n, 3) field."""
        import dolfinx.fem as fem

        f = fem.Function(self.V)
        f.x.array[:] = self.to_dolfinx(vec)
        return f

    # ------------------------------------------------------- the operators
    def _stiffness_petsc(self, bcs=()):
        import dolfinx.fem.petsc as fp

        mat = fp.assemble_matrix(self._a, bcs=list(bcs))
        mat.assemble()
        return mat

    def stiffness(self, young: float, poisson: float) -> sp.csr_matrix:
        """K assembled by dolfinx, in fem_grasp's numbering."""
        self.set_material(young, poisson)
        k = to_scipy(self._stiffness_petsc())
        p = self.perm
        return k[p][:, p].tocsr()

    def gravity_loads(self, density: float, gravity: float = 9.8) -> np.ndarray:
        """G = ∫ ρ g (0, 0, −1)·φ_a (consistent P1 load), in fem_grasp's numbering."""
        import dolfinx.fem.petsc as fp

        self._body_force.value = np.array([0.0, 0.0, -density * gravity])
        b = fp.assemble_vector(self._L)
        return self.to_fem(b.array.copy())

    def strain_energy(self, displacements: np.ndarray, young: float, poisson: float) -> float:
        """The paper's eq. (2) for a fem_grasp-ordered field, integrated by dolfinx."""
        import dolfinx.fem as fem

        self.set_material(young, poisson)
        self._field.x.array[:] = self.to_dolfinx(displacements)
        return float(fem.assemble_scalar(self._energy))

    # ------------------------------------------------------------ solves
    def solve_contact(self, young: float, poisson: float, density: float, gravity: float,
                      nodes: np.ndarray, displacements: np.ndarray) -> DolfinxContactSolution:
        """Gravity plus prescribed displacements at ``nodes``: a Dirichlet problem solved by PETSc/MUMPS.

        Parameters
        ----------
        young, poisson : material
        density, gravity : body force ρ g (0, 0, −1)
        nodes : (m,) fem_grasp node indices held
        displacements : (m, 3) their prescribed displacements

        Returns
        -------
        DolfinxContactSolution
            Forces are the reactions ``(KΔ − G)`` at the held nodes, K and G
            both assembled by dolfinx without boundary conditions.
        """
        import dolfinx.fem as fem
        import dolfinx.fem.petsc as fp
        from petsc4py import PETSc

        t0 = time.perf_counter()
        nodes = np.asarray(nodes, dtype=np.int64)
        self.set_material(young, poisson)
        self._body_force.value = np.array([0.0, 0.0, -density * gravity])
        g = fem.Function(self.V)
        blocks = self.block_of_node[nodes].astype(np.int32)
        vals = g.x.array.reshape(-1, 3)
        vals[blocks] = np.asarray(displacements, dtype=float).reshape(-1, 3)
        order = np.argsort(blocks)
        bc = fem.dirichletbc(g, blocks[order])
        a_bc = self._stiffness_petsc([bc])
        b = fp.assemble_vector(self._L)
        fp.apply_lifting(b, [self._a], bcs=[[bc]])
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        fp.set_bc(b, [bc])
        ksp = _mumps(a_bc)
        u = fem.Function(self.V)
        ksp.solve(b, u.vector)
        u.x.scatter_forward()
        # Reactions with the unconstrained operators: F = K Δ − G.
        k_full = self._stiffness_petsc()
        r = k_full.createVecLeft()
        k_full.mult(u.vector, r)
        g_full = fp.assemble_vector(self._L)
        reaction = r.array - g_full.array
        seconds = time.perf_counter() - t0
        disp = self.to_fem(u.x.array.copy()).reshape(-1, 3)
        forces = self.to_fem(reaction).reshape(-1, 3)[nodes]
        self._field.x.array[:] = u.x.array
        energy = float(fem.assemble_scalar(self._energy))
        for obj in (a_bc, b, k_full, r, g_full, ksp):
            obj.destroy()
        return DolfinxContactSolution(nodes, forces, disp, energy, seconds)


def _strain(w):
    import ufl

    return ufl.sym(ufl.grad(w))


def _dx(degree: int | None = None):
    import ufl

    return ufl.dx if degree is None else ufl.dx(metadata={"quadrature_degree": degree})


def paper_energy_density(u, young, poisson):
    """The integrand of eq. (2) in engineering strains ε_x … γ_yz (a UFL expression).

    ``young`` and ``poisson`` may be numbers or dolfinx ``Constant`` objects.
    """
    import ufl

    g = ufl.grad(u)
    ex, ey, ez = g[0, 0], g[1, 1], g[2, 2]
    gxy, gxz, gyz = g[1, 0] + g[0, 1], g[2, 0] + g[0, 2], g[2, 1] + g[1, 2]
    return young / (2.0 * (1.0 + poisson)) * (
        ex**2 + ey**2 + ez**2
        + poisson / (1.0 - 2.0 * poisson) * (ex + ey + ez) ** 2
        + 0.5 * (gxy**2 + gxz**2 + gyz**2))


# --------------------------------------------------------------------------
# Manufactured solutions (P1 and P2) on any TetMesh, for convergence studies.
# --------------------------------------------------------------------------


@dataclass(frozen=True)
class ManufacturedResult:
    """Errors and cost of one manufactured-solution solve.

    Attributes
    ----------
    degree : polynomial degree of the Lagrange space
    n_dofs : number of unknowns including boundary DOFs
    h : maximum edge length of the mesh
    l2_error, energy_error : ‖u − u_h‖_L2 and ‖u − u_h‖_E = (∫ σ(e):ε(e))^½
    l2_norm, energy_norm : the same norms of the exact field
    seconds : wall time of function space, assembly and solve (no JIT, no error evaluation)
    """

    degree: int
    n_dofs: int
    h: float
    l2_error: float
    energy_error: float
    l2_norm: float
    energy_norm: float
    seconds: float


class UFLField(Protocol):
    """An exact displacement field that evaluates itself in NumPy and in UFL."""

    def value(self, x: np.ndarray) -> np.ndarray:
        """(N, 3) displacement at points ``x`` of shape (N, 3)."""

    def ufl(self, x):
        """The same field as a UFL vector of the ``SpatialCoordinate`` ``x``."""


def solve_manufactured(mesh: "TetMesh", field: UFLField, young: float, poisson: float, degree: int,
                       quadrature_degree: int = 8) -> ManufacturedResult:
    """Solve −div σ(u) = f with u = ``field`` on the boundary, in dolfinx P``degree``.

    The body force is derived by UFL from the exact field (f = −div σ(u_ex)),
    independently of the closed form the fem_grasp side uses; the boundary
    data are the Lagrange interpolant of the exact field on every exterior
    facet.

    Parameters
    ----------
    mesh : TetMesh
    field : UFLField
    young, poisson : material
    degree : 1 or 2
    quadrature_degree : for the load and the error integrals

    Returns
    -------
    ManufacturedResult
    """
    import dolfinx.fem as fem
    import dolfinx.mesh as dmesh
    import ufl

    msh = dolfinx_mesh(mesh)
    lam_c = fem.Constant(msh, lame(young, poisson)[0])
    mu_c = fem.Constant(msh, lame(young, poisson)[1])

    def sigma(w):
        e = _strain(w)
        return 2.0 * mu_c * e + lam_c * ufl.tr(e) * ufl.Identity(3)

    x = ufl.SpatialCoordinate(msh)
    u_ex = field.ufl(x)
    f = -ufl.div(sigma(u_ex))
    dxq = _dx(quadrature_degree)

    t0 = time.perf_counter()
    V = fem.VectorFunctionSpace(msh, ("CG", degree))
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    a = fem.form(ufl.inner(sigma(u), _strain(v)) * ufl.dx)
    L = fem.form(ufl.inner(f, v) * dxq)
    msh.topology.create_connectivity(2, 3)
    facets = dmesh.exterior_facet_indices(msh.topology)
    dofs = fem.locate_dofs_topological(V, 2, facets)
    u_d = fem.Function(V)
    u_d.interpolate(lambda p: field.value(p.T).T)
    bc = fem.dirichletbc(u_d, dofs)
    uh = _solve_linear(a, L, bc, V)
    seconds = time.perf_counter() - t0

    e = uh - u_ex

    def integral(expr) -> float:
        return float(fem.assemble_scalar(fem.form(expr * dxq)))

    result = ManufacturedResult(
        degree=degree,
        n_dofs=int(V.dofmap.index_map.size_local * V.dofmap.index_map_bs),
        h=max_edge_length(mesh),
        l2_error=np.sqrt(integral(ufl.inner(e, e))),
        energy_error=np.sqrt(integral(ufl.inner(sigma(e), _strain(e)))),
        l2_norm=np.sqrt(integral(ufl.inner(u_ex, u_ex))),
        energy_norm=np.sqrt(integral(ufl.inner(sigma(u_ex), _strain(u_ex)))),
        seconds=seconds,
    )
    log.debug("dolfinx P%d manufactured: %d dofs, L2 %.3e, energy %.3e, %.2f s", degree, result.n_dofs,
              result.l2_error, result.energy_error, seconds)
    return result


def max_edge_length(mesh: "TetMesh") -> float:
    """Longest edge of any tetrahedron."""
    p = mesh.points[mesh.tets]
    pairs = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)]
    return float(max(np.linalg.norm(p[:, i] - p[:, j], axis=1).max() for i, j in pairs))


def warm_up(field: UFLField | None = None, degrees: tuple[int, ...] = (1, 2)) -> float:
    """Compile (or load from the JIT cache) the forms used here on a one-cell mesh; returns seconds.

    Timing studies call this first so that no JIT cost lands in a measurement.
    """
    from fem_grasp import box_mesh

    t0 = time.perf_counter()
    m = box_mesh(divisions=(1, 1, 1))
    model = DolfinxModel(m)
    model.stiffness(1.0, 0.3)
    model.gravity_loads(1.0)
    model.strain_energy(np.zeros(3 * m.n_points), 1.0, 0.3)
    if field is not None:
        for k in degrees:
            solve_manufactured(box_mesh(divisions=(2, 2, 2)), field, 1.0, 0.3, k)
    return time.perf_counter() - t0



def solve_clamped_gravity(mesh: "TetMesh", degree: int, young: float, poisson: float, density: float,
                          probe: np.ndarray, gravity: float = 9.8) -> dict:
    """A body clamped on its face x = min x, loaded by its weight ρ g (0, 0, −1), in dolfinx P``degree``.

    Parameters
    ----------
    mesh : TetMesh
    degree : 1 or 2
    young, poisson, density, gravity : material and load
    probe : (3,) a mesh vertex where the displacement is reported

    Returns
    -------
    dict with ``probe_displacement`` (3,), ``work`` = ∫ ρ g·u (twice the strain energy at
    equilibrium), ``n_dofs`` and ``seconds``.
    """
    import dolfinx.fem as fem
    import dolfinx.mesh as dmesh
    import ufl

    msh = dolfinx_mesh(mesh)
    lam_c = fem.Constant(msh, lame(young, poisson)[0])
    mu_c = fem.Constant(msh, lame(young, poisson)[1])
    load = fem.Constant(msh, np.array([0.0, 0.0, -density * gravity]))
    x0 = float(mesh.points[:, 0].min())
    tol = 1e-9 * mesh.diameter

    def sigma(w):
        e = _strain(w)
        return 2.0 * mu_c * e + lam_c * ufl.tr(e) * ufl.Identity(3)

    t0 = time.perf_counter()
    V = fem.VectorFunctionSpace(msh, ("CG", degree))
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    a = fem.form(ufl.inner(sigma(u), _strain(v)) * ufl.dx)
    L = fem.form(ufl.inner(load, v) * ufl.dx)
    facets = dmesh.locate_entities_boundary(msh, 2, lambda p: np.abs(p[0] - x0) <= tol)
    bc = fem.dirichletbc(np.zeros(3), fem.locate_dofs_topological(V, 2, facets), V)
    uh = _solve_linear(a, L, bc, V)
    seconds = time.perf_counter() - t0
    coords = V.tabulate_dof_coordinates()
    k = int(np.argmin(np.linalg.norm(coords - np.asarray(probe), axis=1)))
    if np.linalg.norm(coords[k] - probe) > tol:
        raise ValueError("the probe point is not a vertex of the mesh")
    work = float(fem.assemble_scalar(fem.form(ufl.inner(load, uh) * ufl.dx)))
    out = {"probe_displacement": uh.x.array.reshape(-1, 3)[k].copy(), "work": work,
           "n_dofs": int(V.dofmap.index_map.size_local * 3), "seconds": seconds}
    return out
