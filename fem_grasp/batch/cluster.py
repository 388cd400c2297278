"""Where a placement search's candidates run: a plain loop here, or tasks on a Dask cluster (a LocalCluster of
this machine's cores, an existing scheduler, or the caller's client)."""

from __future__ import annotations

import contextlib
import logging
import os
import time
import uuid
from typing import Any, Callable, Iterator, Sequence

from ..errors import SchedulerError, require
from ..grasp.candidates import Candidate
from ..grasp.evaluation import SearchSetup, error_row, evaluate

__all__ = ["dask_client", "run_on_dask", "run_serial"]


def _identity(x: Any) -> Any:
    """The task that hands the setup to the workers (recomputable if the worker holding it dies)."""
    return x


@contextlib.contextmanager
def dask_client(client: Any, scheduler: str | None, workers: int | None, connect_timeout: float
          ) -> Iterator[tuple[Any, str, float]]:
    """A Dask client: the caller's, one connected to ``scheduler``, or one of a LocalCluster; with its name and
    its start-up time."""
    t0 = time.perf_counter()
    distributed = require("dask.distributed", "search", "A search on Dask (workers=0, --workers 0: a plain loop)")
    Client, LocalCluster = distributed.Client, distributed.LocalCluster
    if client is not None:
        yield client, f"the given client ({client.scheduler.address})", 0.0
        return
    if scheduler:
        try:
            c = Client(scheduler, timeout=connect_timeout)
        except (OSError, TimeoutError) as exc:
            raise SchedulerError(f"cannot reach the Dask scheduler at {scheduler} within {connect_timeout:g} s "
                                 f"({type(exc).__name__}: {exc}); start one with `dask scheduler` and workers with "
                                 f"`dask worker {scheduler}`") from None
        try:
            try:
                c.wait_for_workers(1, timeout=connect_timeout)
            except (OSError, TimeoutError):
                raise SchedulerError(f"the Dask scheduler at {scheduler} has no worker after {connect_timeout:g} s; "
                                     f"start some with `dask worker {scheduler} --nthreads 1`") from None
            n = len(c.scheduler_info(n_workers=-1)["workers"])
            yield c, f"scheduler {scheduler} ({n} workers)", time.perf_counter() - t0
        finally:
            c.close()
        return
    n = int(workers) if workers else (os.cpu_count() or 1)
    cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, host="127.0.0.1",
                           dashboard_address=None, silence_logs=logging.ERROR)
    c = Client(cluster)
    try:
        yield c, f"local cluster of {n} worker process{'es' if n != 1 else ''}", time.perf_counter() - t0
    finally:
        c.close()
        cluster.close()


def _killed_message(exc: BaseException) -> str:
    name = type(exc).__name__
    if name == "KilledWorker":
        return (f"KilledWorker: the workers evaluating this candidate died (Dask gave up after "
                f"distributed.scheduler.allowed-failures deaths): {exc}")
    return f"{name}: {exc}"


def run_on_dask(client: Any, setup: SearchSetup, todo: Sequence[Candidate], on_row: Callable[[dict], None]) -> None:
    from dask.distributed import as_completed

    token = uuid.uuid4().hex[:8]
    shared = client.submit(_identity, setup, key=f"fem-grasp-setup-{setup.key[:12]}-{token}", pure=False)
    futures = {client.submit(evaluate, shared, c, key=f"fem-grasp-{c.key}-{token}", pure=False, retries=1): c
               for c in todo}
    try:
        for fut in as_completed(futures):
            cand = futures[fut]
            if fut.status == "finished":
                row = fut.result()
            else:
                exc = fut.exception()
                row = error_row(cand, _killed_message(exc))
                row["worker"] = "?"
            fut.release()
            on_row(row)
    finally:
        client.cancel(list(futures) + [shared])


def run_serial(setup: SearchSetup, todo: Sequence[Candidate], on_row: Callable[[dict], None]) -> None:
    for c in todo:
        on_row(evaluate(setup, c))
