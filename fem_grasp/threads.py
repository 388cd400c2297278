"""BLAS threads: one while contacts are tracked, all of them again for the large solves inside.

Tracking solves tens of thousands of small dense systems (3×3 to ~100×100),
for which OpenBLAS's threads cost more than they give: 20 % of a tomato
pickup on a loaded 2-core machine, and a 3×3 inverse took 16× longer.  Two
kinds of solve inside it are the opposite case, and get the threads back:

* the sparse solves for new contacts' compliance columns, which stream a
  factor of hundreds of MB: 10.7 against 11.4 ms per column in batches of
  90, 40 against 55 ms for one node's three (31k-vertex orange, CHOLMOD,
  ``make bench`` section ``columns``);
* dense factorisations and solves of :data:`DENSE_THREADS_MIN` rows or more
  (the contact responses of large contact sets): under
  ``python -m bench.profile --orange 30000`` their LU solves took 0.80 s
  against 1.34 s on one thread.  On the idle 2-core AMD EPYC an LU takes as
  long on two threads as on one up to 840 rows (12 ms; at 400 rows 2.0
  against 1.6 ms) and pays from about 1,200 (26 against 31 ms; 78 against
  129 ms at 2,000); with the other core busy, two threads took 28 against
  17 ms at 840 rows and 20 against 0.2 ms at 150 (the second thread waits
  for a core), so they are kept for sizes where they pay.

While two lift tests run side by side (:func:`side_by_side`, the speculative lift test of
:class:`~fem_grasp.grasp.lift_test.SpeculativeTest`), BLAS keeps one thread from the section's start to its
end and nothing gets the threads back: the limit is one setting of the whole process, so a solve given two
threads by one test would run the other test's BLAS calls on two threads too for as long as it lasts, and
which calls those are would depend on the timing of the two (and with it, where OpenBLAS splits a sum by its
threads, their round-off).  The section holds the limit itself because each thread's tracking enters and
leaves :func:`one_blas_thread` of its own: without an enclosing one, the first thread to leave would restore
the threads of before while the other still computed (and OpenBLAS would change its thread count under a
running call).

threadpoolctl is optional: without it nothing is limited.
"""

from __future__ import annotations

import contextlib
import threading
from typing import Any, Iterator

__all__ = ["one_blas_thread", "outer_blas_threads", "blas_threads_for", "blas_threads_held", "side_by_side",
           "DENSE_THREADS_MIN"]

#: Dense systems of at least this many rows are solved on every BLAS thread, also while tracking (module notes).
DENSE_THREADS_MIN = 1200

#: (controller, BLAS threads before the limit) of each active :func:`one_blas_thread`, outermost first.
_LIMITS: list[tuple[Any, int]] = []
#: How many :func:`side_by_side` sections are active (under ``_SECTIONS_LOCK``).
_SECTIONS = 0
_SECTIONS_LOCK = threading.Lock()


@contextlib.contextmanager
def side_by_side() -> Iterator[None]:
    """A section in which two computations may run in two threads: BLAS on one thread throughout
    (:func:`one_blas_thread`, entered by the thread that opens the section), and :func:`outer_blas_threads`
    changes nothing (module notes)."""
    global _SECTIONS
    with one_blas_thread():
        with _SECTIONS_LOCK:
            _SECTIONS += 1
        try:
            yield
        finally:
            with _SECTIONS_LOCK:
                _SECTIONS -= 1


def blas_threads_held() -> bool:
    """Whether :func:`one_blas_thread` can hold BLAS to one thread (threadpoolctl imports)."""
    try:
        import threadpoolctl  # noqa: F401
    except ImportError:
        return False
    return True


@contextlib.contextmanager
def one_blas_thread() -> Iterator[None]:
    """BLAS limited to one thread (threadpoolctl, when installed) while contacts are tracked."""
    try:
        from threadpoolctl import ThreadpoolController
    except ImportError:  # optional: the core needs only numpy and scipy
        yield
        return
    ctl = ThreadpoolController()  # made here, after the BLAS libraries in use are loaded
    before = max((lib["num_threads"] for lib in ctl.select(user_api="blas").info()), default=1)
    with ctl.limit(limits=1, user_api="blas"):
        _LIMITS.append((ctl, before))
        try:
            yield
        finally:
            _LIMITS.pop()


def outer_blas_threads() -> contextlib.AbstractContextManager:
    """Inside :func:`one_blas_thread`, the BLAS threads in force before it; elsewhere, and inside
    :func:`side_by_side`, no change."""
    if not _LIMITS or _SECTIONS:
        return contextlib.nullcontext()
    ctl, before = _LIMITS[0]
    return ctl.limit(limits=before, user_api="blas")


def blas_threads_for(rows: int) -> contextlib.AbstractContextManager:
    """:func:`outer_blas_threads` for a dense system of ``rows`` ≥ :data:`DENSE_THREADS_MIN`, else no change."""
    return outer_blas_threads() if rows >= DENSE_THREADS_MIN else contextlib.nullcontext()
