"""A search's result table on disk, written as the rows arrive: ``results.parquet`` and ``results.csv``.

Both files hold every row received so far, sorted by candidate, with the columns of
:data:`fem_grasp.grasp.evaluation.ROW_COLUMNS` in that order, each named with its unit (:data:`FILE_COLUMNS`):
lengths in millimetres (``height_mm``, ``rho_star_mm``, ``xi_mm`` …), forces in newtons (``grip1_N``,
``finger_normal_force_N`` …), times in seconds (``time_s``), angles in degrees (``azimuth_deg``), as the command
line and the report print them; the other columns are counts, words or ratios (``margin`` = w/mg).
:func:`with_units` and :func:`without_units` convert a table between these names and the in-memory SI table of
:class:`~fem_grasp.batch.engine.SearchResult`.  Each write replaces the whole file atomically
(a temporary file, then :func:`os.replace`), so at any moment each file is a complete table; rows are
written at most :attr:`ResultStore.flush_interval` seconds after they arrive and always when the search ends
or is interrupted.  ``--resume`` reads ``results.parquet`` (or, if it is missing or damaged,
``results.csv``) and skips the candidates it holds: a search killed outright loses at most the rows of its
last interval, and computes them again.

The Parquet file is written by pandas through pyarrow (``pip install "fem_grasp[search]"``).
"""

from __future__ import annotations

import io
import logging
import math
import time
from pathlib import Path
from typing import Any

from .._files import atomic_write_bytes, atomic_write_text
from ..grasp.evaluation import ROW_COLUMNS

__all__ = ["CSV_FILE", "FILE_COLUMNS", "FLUSH_INTERVAL", "PARQUET_FILE", "ResultStore", "read_results", "table_of",
           "with_units", "without_units"]

log = logging.getLogger(__name__)

PARQUET_FILE = "results.parquet"
CSV_FILE = "results.csv"
#: Seconds between two writes of the table while rows arrive.
FLUSH_INTERVAL = 1.0

_DTYPES = {"int": "int64", "float": "float64", "str": "object", "bool": "bool"}

_MM = ("height", "max_squeeze", "xi", "yi", "zi", "xj", "yj", "zj", "rho_star", "squeeze_depth", "step")
_N = ("liftable_max", "weight", "grip1", "vertical1", "normal1", "force1", "grip2", "vertical2", "normal2", "force2",
      "finger_normal_force", "rigid_normal_force")
_S = ("time", "cpu_time", "setup_time")
#: The columns of the result files: in-memory (SI) name → (name in the files, with its unit; factor from SI).
FILE_COLUMNS: dict[str, tuple[str, float]] = {
    name: ((f"{name}_mm", 1e3) if name in _MM else (f"{name}_N", 1.0) if name in _N else
           (f"{name}_s", 1.0) if name in _S else (name, 1.0)) for name in ROW_COLUMNS}


def with_units(table: Any) -> Any:
    """A copy of the SI table (:func:`table_of`) with the files' names and units (:data:`FILE_COLUMNS`):
    ``rho_star`` (m) becomes ``rho_star_mm``, ``grip1`` becomes ``grip1_N``, …"""
    out = table.copy()
    for name, (file_name, factor) in FILE_COLUMNS.items():
        if name in out and factor != 1.0:
            out[name] = out[name] * factor
    return out.rename(columns={n: f for n, (f, _) in FILE_COLUMNS.items()})


def without_units(table: Any) -> Any:
    """The inverse of :func:`with_units` (a table read from the files → SI names and values); columns already
    in SI (a file written before the units were in the names) are kept."""
    out = table.rename(columns={f: n for n, (f, _) in FILE_COLUMNS.items() if f != n and f in table})
    for name, (file_name, factor) in FILE_COLUMNS.items():
        if file_name in table and file_name != name and factor != 1.0:
            out[name] = out[name] / factor
    return out


def table_of(rows: list[dict[str, Any]]) -> Any:
    """A pandas DataFrame of result rows: the columns of ``ROW_COLUMNS`` in order, typed, sorted by candidate."""
    import pandas as pd

    blank = {"int": -1, "float": math.nan, "str": "", "bool": False}
    full = [{name: row.get(name, blank[kind]) for name, (kind, _) in ROW_COLUMNS.items()} for row in rows]
    df = pd.DataFrame(full, columns=list(ROW_COLUMNS))
    for name, (kind, _) in ROW_COLUMNS.items():
        if kind == "str":
            df[name] = df[name].fillna("").astype(str)
        elif kind == "bool":
            df[name] = df[name].fillna(False).astype(bool)
        else:
            df[name] = df[name].astype(_DTYPES[kind])
    return df.sort_values("candidate", kind="stable").reset_index(drop=True)


def read_results(out: str | Path) -> Any:
    """The result table of a search folder (Parquet, else CSV), or None when it has neither (or both are damaged)."""
    import pandas as pd

    out = Path(out)
    if (out / PARQUET_FILE).exists():
        try:
            return table_of(without_units(pd.read_parquet(out / PARQUET_FILE)).to_dict("records"))
        except Exception as exc:  # noqa: BLE001 - a damaged file: try the CSV
            log.warning("cannot read %s (%s); trying %s", out / PARQUET_FILE, exc, CSV_FILE)
    if (out / CSV_FILE).exists():
        try:
            floats = [name for name, (kind, _) in ROW_COLUMNS.items() if kind == "float"]
            return table_of(without_units(pd.read_csv(out / CSV_FILE, keep_default_na=False, na_values={
                col: ["nan", "NaN", ""] for name in floats for col in (name, FILE_COLUMNS[name][0])}
            )).to_dict("records"))
        except Exception as exc:  # noqa: BLE001
            log.warning("cannot read %s (%s)", out / CSV_FILE, exc)
    return None


class ResultStore:
    """The rows of a search, kept by candidate key and written to ``out`` as they arrive (module notes).

    Parameters
    ----------
    out : the search folder, or None to keep the rows in memory only
    rows : rows to start from (a resumed search's)
    flush_interval : seconds between writes while rows arrive
    """

    def __init__(self, out: str | Path | None, rows: list[dict[str, Any]] | None = None,
                 flush_interval: float = FLUSH_INTERVAL) -> None:
        self.out = None if out is None else Path(out)
        self.rows: dict[str, dict[str, Any]] = {str(r["key"]): dict(r) for r in rows or []}
        self.flush_interval = float(flush_interval)
        self._dirty = False
        self._last = -math.inf
        self.writes = 0

    def __len__(self) -> int:
        return len(self.rows)

    def __contains__(self, key: str) -> bool:
        return key in self.rows

    def add(self, row: dict[str, Any]) -> None:
        """Keep ``row`` (replacing an earlier row of its candidate) and write the table if the interval has passed."""
        self.rows[str(row["key"])] = dict(row)
        self._dirty = True
        if time.monotonic() - self._last >= self.flush_interval:
            self.flush()

    def table(self) -> Any:
        """The rows as a DataFrame (:func:`table_of`)."""
        return table_of(list(self.rows.values()))

    def flush(self) -> None:
        """Write both files now (when there is something new, or nothing was written yet)."""
        self._last = time.monotonic()
        if self.out is None or (not self._dirty and self.writes):
            return
        df = with_units(self.table())
        buf = io.BytesIO()
        df.to_parquet(buf, index=False)
        atomic_write_bytes(self.out / PARQUET_FILE, buf.getvalue())
        atomic_write_text(self.out / CSV_FILE, df.to_csv(index=False))
        self._dirty = False
        self.writes += 1
