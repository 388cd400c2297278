"""Independent verification of :mod:`fem_grasp` (issue #3).

Everything here sits beside the package and imports it, never the other way
round.  The reference solver is FEniCSx/dolfinx (0.5.x) with PETSc; the
modules are:

``dolfinx_ref``   dolfinx mesh, stiffness, gravity and Dirichlet contact solves in
                  fem_grasp's node-major numbering
``linalg``        sparse SPD solves through PETSc/MUMPS (scipy fallback)
``quadrature``    tetrahedron quadrature, P1 load vectors and error norms
``manufactured``  manufactured-solution convergence (fem_grasp P1, dolfinx P1/P2)
``crosscheck``    entry-by-entry comparison of fem_grasp with dolfinx on one mesh
``hertz``         sphere indentation against Hertz theory
``stability``     Poisson locking, Young's-modulus scaling, near-collinear contacts,
                  sliver meshes
``render``        pyvista off-screen pictures
``plots``         matplotlib figures
``report``        HTML report
``run``           ``python -m verification.run [--quick]``
"""
