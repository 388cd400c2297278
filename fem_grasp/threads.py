"""BLAS threads: one while contacts are tracked, all of them again for the sparse solves inside.

Tracking solves tens of thousands of small dense systems (3×3 to ~100×100),
for which OpenBLAS's threads cost more than they give: 20 % of a tomato
pickup on a loaded 2-core machine, and a 3×3 inverse took 16× longer.  The
multi-column sparse solves for new contacts' compliance columns that happen
inside it are the opposite case: they stream a factor of hundreds of MB, and
with two threads 180 columns took 1.4 s against 2.5 s with one (31k-vertex
orange, CHOLMOD).  threadpoolctl is optional: without it nothing is limited.
"""

from __future__ import annotations

import contextlib
from typing import Any, Iterator

__all__ = ["one_blas_thread", "sparse_solve_threads"]

#: (controller, BLAS threads before the limit) of each active :func:`one_blas_thread`, outermost first.
_LIMITS: list[tuple[Any, int]] = []


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


def sparse_solve_threads() -> contextlib.AbstractContextManager:
    """Inside :func:`one_blas_thread`, the BLAS threads in force before it; elsewhere no change."""
    if not _LIMITS:
        return contextlib.nullcontext()
    ctl, before = _LIMITS[0]
    return ctl.limit(limits=before, user_api="blas")
