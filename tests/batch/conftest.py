"""Fixtures of the placement-search tests."""

import pytest


@pytest.fixture(scope="module")
def client():
    """A real local Dask cluster of two one-thread worker processes, closed after the module's tests."""
    from dask.distributed import Client, LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=None) \
            as cluster, Client(cluster) as c:
        c.wait_for_workers(2, timeout=120)
        yield c
