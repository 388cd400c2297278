"""Many pickups of one object: the placement search ("where to grasp?"), serially or on a Dask cluster.

The paper's Algorithm 1 answers "will this grasp lift?" for one placement; :func:`search` asks it for many
(candidate placements and evaluation: :mod:`fem_grasp.grasp.candidates`, :mod:`fem_grasp.grasp.evaluation`)
and runs them where there is room:

* :mod:`~fem_grasp.batch.engine` — :func:`search`: a plain loop, a ``dask.distributed.LocalCluster`` of
  worker processes, or an existing Dask scheduler; the shared state sent once per worker, failures recorded,
  dying workers' candidates retried elsewhere;
* :mod:`~fem_grasp.batch.cluster` — where the candidates run: a plain loop, or tasks on a Dask cluster;
* :mod:`~fem_grasp.batch.ranking` — the grasps ranked, and those that could be the best within their errors;
* :mod:`~fem_grasp.batch.store` — the result table written as rows arrive (``results.parquet``,
  ``results.csv``), read back to resume;
* :mod:`~fem_grasp.batch.report` — the search's ``report.html``.

dask, pandas and pyarrow are the ``search`` extra (``pip install "fem_grasp[search]"``); they are imported
when a search runs, not with fem_grasp.
"""

from ..errors import SchedulerError, SearchError
from .engine import SearchResult, search
from .ranking import RANKINGS, rank_table
from .report import write_search_report
from .store import ResultStore, read_results, table_of

__all__ = ["RANKINGS", "ResultStore", "SchedulerError", "SearchError", "SearchResult", "rank_table", "read_results",
           "search", "table_of", "write_search_report"]
