"""The contact's inner loops, compiled by numba when it is installed and run as plain Python otherwise.

* :mod:`~fem_grasp.contact.kernels.jit` — the decorator that compiles a kernel at its first call (one source,
  run two ways; ``FEM_GRASP_NO_JIT=1`` selects plain Python), and the warm-up registry;
* :mod:`~fem_grasp.contact.kernels.gauss_seidel` — one projected Gauss–Seidel sweep of the return mapping
  and each contact's local stick / slide / release problem (scalar arithmetic on a record per contact);
* :mod:`~fem_grasp.contact.kernels.slip_newton` — the residual, Jacobian and damped Newton iteration of the
  slip systems of eqs. (6)–(8).
"""

__all__: list[str] = []
