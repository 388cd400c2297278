"""The contact's inner loops, compiled by numba when it is installed and run as plain Python otherwise.

* :mod:`~fem_grasp.contact.kernels.jit` — the decorator that compiles a kernel at its first call (one source,
  run two ways; ``FEM_GRASP_NO_JIT=1`` selects plain Python), and the warm-up registry;
* :mod:`~fem_grasp.contact.kernels.gauss_seidel` — one projected Gauss–Seidel sweep of the return mapping
  and each contact's local stick / slide / release problem (scalar arithmetic on a record per contact);
* :mod:`~fem_grasp.contact.kernels.polish` — the return mapping's Newton polish of fixed statuses;
* :mod:`~fem_grasp.contact.kernels.slip_newton` — the residual, Jacobian and damped Newton iteration of the
  slip systems of eqs. (6)–(8) (the numpy reference path's);
* :mod:`~fem_grasp.contact.kernels.slip_trial` — one trial state of the event tracking: the held prediction,
  the slip system assembled, solved and read out (forces, slips, slip rates);
* :mod:`~fem_grasp.contact.kernels.slip_residual` — the slip system's residual and Jacobian in one pass and the
  damped (fused) Newton iteration on them;
* :mod:`~fem_grasp.contact.kernels.slip_homotopy` — the Newton homotopy of footnote 2 where Newton's method fails;
* :mod:`~fem_grasp.contact.kernels.events` — the event functions A–D at a trial state;
* :mod:`~fem_grasp.contact.kernels.dense` — LAPACK's LU for the kernels' dense systems.

The kernels polish, slip_trial and events replace numpy code that stays as the reference path:
``EngineSettings.compiled_trials`` and ``EngineSettings.compiled_polish`` (both on where numba is installed) choose, and
the tests compare the two.
"""

__all__: list[str] = []
