"""BLAS threads while two computations run side by side (fem_grasp.threads)."""

import threading

import numpy as np
import pytest

threadpoolctl = pytest.importorskip("threadpoolctl")

from fem_grasp.threads import one_blas_thread, side_by_side  # noqa: E402
from tests.helpers import blas_threads  # noqa: E402


def test_a_side_by_side_section_holds_one_blas_thread_while_either_thread_leaves_its_own_limit():
    """Each thread's tracking enters and leaves one_blas_thread of its own; where one thread leaves its limit
    while the other still computes, the other's BLAS calls keep one thread, and the threads of before come back
    only when the section ends."""
    np.ones((4, 4)) @ np.ones(4)  # BLAS loaded
    seen: list[int] = []
    inside, left = threading.Event(), threading.Event()

    def other() -> None:
        with one_blas_thread():
            inside.set()
            left.wait(timeout=30)
            seen.append(blas_threads())

    with threadpoolctl.threadpool_limits(limits=2, user_api="blas"):
        if blas_threads() != 2:
            pytest.skip("BLAS does not take two threads here")
        with side_by_side():
            assert blas_threads() == 1
            helper = threading.Thread(target=other)
            with one_blas_thread():  # this thread's tracking, begun before the other's
                helper.start()
                assert inside.wait(timeout=30)
            left.set()  # ... and ended while the other computes
            helper.join(timeout=30)
            assert blas_threads() == 1
        assert seen == [1]
        assert blas_threads() == 2
