"""Where to grasp: a placement search run as a plain loop or on a Dask cluster (:func:`search`).

A search takes one object (a scene, or a :class:`~fem_grasp.elastic.body.Body` with settings) and

1. rests it on the table once (Algorithm 1 step 2, cached like ``fem-grasp run``'s);
2. makes the candidate placements (:func:`fem_grasp.grasp.candidates.placement_candidates`: heights,
   azimuths, tilts, ratios; antipodal, clear of the table, outside the object, force closure);
3. evaluates Algorithm 1 for each (:func:`fem_grasp.grasp.evaluation.evaluate`) on the engine:

   * ``workers=0``: a plain loop in this process;
   * by default a ``dask.distributed.LocalCluster`` of ``workers`` processes (default: this machine's
     cores) with one thread each, on 127.0.0.1;
   * ``scheduler="tcp://HOST:PORT"``: an existing Dask cluster, the same code unchanged (its workers need
     fem_grasp and its ``search`` extra installed); ``client=``: a ``dask.distributed.Client`` of yours.

   The shared state travels once: the :class:`~fem_grasp.grasp.evaluation.SearchSetup` (plain arrays) is one
   task that every candidate task depends on, so each worker receives it once, and builds the factorised
   body, its compliance columns and the resting state from it once (the factor itself does not pickle);
4. writes the rows as they arrive (:class:`~fem_grasp.batch.store.ResultStore`: ``results.parquet`` and
   ``results.csv``), so that ``resume=True`` skips the candidates already done;
5. ranks the grasps, reruns the best few to write their full results and pickup reports, and writes the
   search's ``report.html`` (:mod:`fem_grasp.batch.report`).

Failures: a candidate whose pickup raises is a row with ``status = "error"`` and the message; a worker
that dies while evaluating one has it rescheduled on another by Dask (up to
``distributed.scheduler.allowed-failures`` deaths, after which the row records that); a scheduler that
cannot be reached, or that has no worker, within ``connect_timeout`` raises :class:`SchedulerError`.
"""

from __future__ import annotations

import contextlib
import datetime
import json
import logging
import math
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterator, Sequence

from ..elastic.body import Body
from ..errors import SceneError, SchedulerError, SearchError, require
from ..grasp.candidates import Candidate, CandidateSet, placement_candidates
from ..grasp.evaluation import SearchSetup, evaluator_for
from ..grasp.options import PickupOptions
from ..io.cache import cached_rest, rest_code_digest
from ..io.output import MARKER, add_to_marker, atomic_write_text, json_safe, package_version, prepare_out_dir
from .cluster import dask_client, run_on_dask, run_serial
from .ranking import ERROR_COLUMNS, RANKINGS, rank_table
from .store import CSV_FILE, FILE_COLUMNS, PARQUET_FILE, ResultStore, read_results

__all__ = ["ERROR_COLUMNS", "MANIFEST", "RANKINGS", "SCHEMA", "SchedulerError", "SearchError", "SearchResult", "rank_table",
           "require_search_extra", "search"]

log = logging.getLogger(__name__)

#: The search folder's description of itself (scene, settings, candidates, engine, times).
MANIFEST = "search.json"
SCHEMA = "fem_grasp.search"
SCHEMA_VERSION = 1


@dataclass
class SearchResult:
    """What :func:`search` found.

    Attributes
    ----------
    table : pandas DataFrame, one row per candidate (:data:`fem_grasp.grasp.evaluation.ROW_COLUMNS`), by candidate
    ranked : the same rows ranked (column ``rank``: 1 for the best grasp; 0 for candidates not grasped)
    candidates : the :class:`~fem_grasp.grasp.candidates.CandidateSet`
    setup : the :class:`~fem_grasp.grasp.evaluation.SearchSetup` every candidate shared
    engine : "serial", "local cluster of N workers" or "scheduler ADDRESS (N workers)"
    out : the search folder, or None
    report : its report.html, or None
    timings : seconds: "rest" and "candidates" (before the engine), "engine start", "evaluate" (all
        candidates, wall), "report", "total"
    resumed : candidates taken from an earlier run of the same search
    best : folders of the best grasps' full results (``best/01``, …)
    rank_by : the ranking (:data:`RANKINGS`)
    rest_positions : (n, 3) the resting shape the candidates were made on
    expected_error : the relative error each one-level answer carries (the scene's ``solver.expected_error``: of ρ*
        and the finger force, one run on its mesh), or None when not stated; without an accuracy target
        ``ranked["within_error"]`` flags the grasps within the combined error of the best (:func:`rank_table`)
    accuracy : the accuracy target of every candidate's answer, or None (one run on the object's mesh); with it each
        row carries its own estimated errors (``error_rho_star``, ``error_finger_force``), and
        ``ranked["within_error"]`` flags the grasps within the sum of their own and the best one's
    """

    table: Any
    ranked: Any
    candidates: CandidateSet
    setup: SearchSetup
    engine: str
    out: Path | None = None
    report: Path | None = None
    timings: dict[str, float] = field(default_factory=dict)
    resumed: int = 0
    best: list[Path] = field(default_factory=list)
    rank_by: str = "force"
    rest_positions: Any = None
    expected_error: float | None = None
    accuracy: float | None = None

    @property
    def n_grasped(self) -> int:
        """Candidates that pick the object up (or pass the lift test, when the lift is not simulated)."""
        return int(self.table["grasped"].sum())

    @property
    def lifts(self) -> bool:
        """Whether the lift is simulated (else a grasp is one whose lift test passes)."""
        return self.setup.options.lift

    @property
    def n_errors(self) -> int:
        return int((self.table["status"] == "error").sum())


# ------------------------------------------------------------------ the object
@dataclass
class _Object:
    name: str
    body: Body
    scene: Any
    options: PickupOptions
    down: Any
    expected_error: float | None = None


#: The pickup options a search of a body takes as keywords (the rest are each candidate's, or not run per
#: candidate: :data:`~fem_grasp.grasp.evaluation.SHARED_OPTIONS` and the candidates' maximum squeeze; with an
#: accuracy target, the loop's ``max_finger_contacts``, ``max_seconds`` and ``geometry``).
_OPTIONS = ("mu_finger", "mu_table", "finger_radius", "max_squeeze", "step", "lift_test_step", "max_lift", "lift",
            "max_lift_attempts", "backend", "max_finger_contacts", "max_seconds", "geometry")


def _object(scene: Any, quick: bool, cache_dir: Path | None, kwargs: dict[str, Any]) -> _Object:
    from ..io.scene import Scene, load_scene, resolve_scene

    if isinstance(scene, Body):
        unknown = set(kwargs) - {"down", "name", "expected_error", *_OPTIONS}
        if unknown:
            raise TypeError(f"search() got unexpected keyword arguments {sorted(unknown)}")
        options = PickupOptions.from_overrides({k: v for k, v in kwargs.items() if k in _OPTIONS and v is not None})
        error = kwargs.get("expected_error")
        return _Object(str(kwargs.get("name", "object")), scene, None, options, kwargs.get("down"),
                       None if error is None else float(error))
    if kwargs:
        raise TypeError(f"search() of a scene takes its settings from the scene; got {sorted(kwargs)}")
    if not isinstance(scene, Scene):
        scene = load_scene(resolve_scene(scene), quick=quick)
    return _Object(scene.name + (" (quick)" if scene.quick else ""), scene.body(cache_dir), scene,
                   scene.pickup_options(), scene.object.down, scene.expected_error)


def _target(accuracy: Any) -> float | None:
    """The search's accuracy target: a relative error (0.05), a percentage ("5%"), or None / "off" (one level)."""
    from ..io.scene import parse_accuracy

    try:
        return parse_accuracy(accuracy, "accuracy")
    except SceneError as exc:
        raise SearchError(str(exc)) from None


def _geometry(obj: _Object, target: float) -> Any:
    """What the accuracy loop remeshes: the options' geometry, the scene's (paper shape, box, scanned surface), or
    the boundary of the object's mesh; a :class:`SearchError` naming the problem when there is none."""
    from ..mesh.remesh import NoGeometryError, geometry_of_mesh

    if obj.options.geometry is not None:
        return obj.options.geometry
    geometry = obj.scene.geometry() if obj.scene is not None else None
    if geometry is not None:
        return geometry
    try:
        return geometry_of_mesh(obj.body.mesh, f"the mesh of {obj.name}")
    except NoGeometryError as exc:
        raise SearchError(f"accuracy {100 * target:g} %: the accuracy loop remeshes the object at the contact patches, "
                          f"but {exc}; give a geometry (a scene's paper shape, box or surface scan, or geometry=), "
                          "or search without an accuracy target") from None


def _stamp(row: dict[str, Any], error: float | None) -> dict[str, Any]:
    """A one-level row with the error the search states for every answer (NaN when none)."""
    if row.get("status") == "ok":
        e = math.nan if error is None else float(error)
        row["error_rho_star"] = row["error_finger_force"] = e
        if not int(row.get("levels", -1)) >= 1:
            row["levels"] = 1
    return row


# ------------------------------------------------------------------ the folder
def _request(count: int, heights: Any, azimuths: Any, tilts: Any, ratios: Any, seed: int, cone: Any) -> dict:
    return json_safe({"count": count, "heights": heights, "azimuths": azimuths, "tilts": tilts, "ratios": ratios,
                      "seed": seed, "cone": cone})


def _read_manifest(out: Path) -> dict[str, Any] | None:
    try:
        return json.loads((out / MANIFEST).read_text())
    except (OSError, ValueError):
        return None


def _write_manifest(out: Path, doc: dict[str, Any]) -> None:
    atomic_write_text(out / MANIFEST, json.dumps(json_safe(doc), indent=1, allow_nan=False))


def _progress(total: int, initial: int, enabled: bool) -> Any:
    if not enabled:
        return None
    try:
        from tqdm import tqdm
    except ImportError:
        return None
    return tqdm(total=total, initial=initial, unit="candidate", file=sys.stderr, leave=False, mininterval=0.2,
                desc="Algorithm 1 per candidate")


# ------------------------------------------------------------------ search
def require_search_extra(*, dask: bool = True, files: bool = True, report: bool = True) -> None:
    """Check, before any work, that what a search needs is installed: pandas (the result table), Dask
    (``dask``: the engine unless ``workers=0``), pyarrow (``files``: results.parquet) and matplotlib (``report``:
    the search's report.html).

    Raises
    ------
    fem_grasp.errors.MissingExtraError
        One of them is not installed (an ImportError naming the extra, ``search`` or ``report``).
    """
    purpose = "A placement search"
    require("pandas", "search", purpose, load=False)
    if dask:
        require("distributed", "search", purpose + " on Dask (workers=0, --workers 0: a plain loop)", load=False)
    if files:
        require("pyarrow", "search", purpose + " writing results.parquet", load=False)
    if report:
        require("matplotlib", "report", "The search's report.html (--no-report: none)", load=False)


def search(scene: Any, out: str | Path | None = None, *, candidates: int = 64, heights: Any = None,
           azimuths: Any = None, tilts: Any = None, ratios: Any = None, seed: int = 0, cone: float | None = None,
           workers: int | None = None, scheduler: str | None = None, client: Any = None, resume: bool = False,
           force: bool = False, rank: str = "force", best: int = 3, report: bool = True, quick: bool = False,
           cache_dir: str | Path | None = None, connect_timeout: float = 10.0, progress: bool = False,
           candidate_list: Sequence[Candidate] | None = None, on_row: Callable[[dict[str, Any]], None] | None = None,
           accuracy: float | str | None = None, **settings: Any) -> SearchResult:
    """Where to grasp: Algorithm 1 for many finger placements and squeezes of one object (module notes).

    Parameters
    ----------
    scene : a :class:`~fem_grasp.io.scene.Scene`, a scene file or shipped scene name, or a
        :class:`~fem_grasp.elastic.body.Body` (then ``settings`` give ``mu_finger``, ``mu_table``,
        ``finger_radius``, ``max_squeeze``, ``step``, ``lift_test_step``, ``max_lift``, ``lift``,
        ``max_lift_attempts`` and ``backend``, fields of :class:`~fem_grasp.grasp.options.PickupOptions`
        as :func:`~fem_grasp.grasp.pickup` takes them, and, with ``accuracy``, ``max_finger_contacts`` and
        ``geometry`` (what the loop remeshes; default: the body's boundary); ``down`` and ``name``; and
        ``expected_error``, the relative error of one answer, as a scene's ``solver.expected_error``)
    out : the search folder (results.parquet, results.csv, search.json, report.html, best/), or None
    candidates, heights, azimuths, tilts, ratios, seed, cone : the candidates
        (:func:`~fem_grasp.grasp.candidates.placement_candidates`; angles in degrees)
    workers : 0 for a plain loop in this process; else the LocalCluster's processes (default: the cores).  They
        are spawned, and each imports the calling script: call ``search`` under ``if __name__ == "__main__":``
        in a script (a call outside it raises :class:`~fem_grasp.errors.MainGuardError` before anything starts;
        :mod:`fem_grasp.spawn`); the report's pictures are drawn in a spawned process too
    scheduler : the address of a running Dask scheduler ("tcp://HOST:8786") instead of a LocalCluster
    client : a ``dask.distributed.Client`` to use instead (not closed here)
    resume : skip the candidates whose rows ``out`` already holds (the same search: same object, settings
        and code)
    force : write into a folder that is not empty and was not written by fem_grasp
    rank : how the grasps that pick the object up are ranked (:data:`RANKINGS`)
    best : how many of the best grasps get their full results and pickup report (``best/01`` …)
    report : write report.html (needs matplotlib; pyvista for the pictures of the object)
    quick : a scene's ``[quick]`` variant
    cache_dir : meshes and resting states cached between runs (``fem-grasp run``'s cache), or None
    connect_timeout : seconds to reach a scheduler and find a worker on it
    progress : a tqdm progress bar on stderr
    candidate_list : evaluate these candidates instead of making them
    on_row : called with each result row as it arrives (in this process)
    accuracy : an accuracy target for every candidate's answer: a relative error of ρ* and the finger force in
        (0, 1), 0.05 or "5%" (None or "off": one run of Algorithm 1 per candidate on the object's mesh, the
        default).  Each candidate is then evaluated by the accuracy loop
        (:func:`fem_grasp.grasp.accuracy.converged_pickup`: level 0 on the shared resting state, then meshes
        refined at its contact patches until two agree within the target), on the scene's geometry (its paper
        shape, box or surface scan) or the boundary of the object's mesh; its row carries its estimated errors
        (``error_rho_star``, ``error_finger_force``), ``converged`` and ``levels``, and the ranking's ≈ marks use
        them (:func:`rank_table`).  Each candidate costs several runs of Algorithm 1 on finer meshes (and so do the
        ``best`` reruns); a resumed search keeps only rows of the same target

    Returns
    -------
    SearchResult

    Raises
    ------
    SearchError, SchedulerError
        A search that cannot run as asked (an accuracy that is not a relative error in (0, 1), an accuracy target
        for an object with no geometry to remesh, …); a scheduler that cannot be reached.
    MainGuardError
        Called from a script's top level outside ``if __name__ == "__main__":`` with worker processes or a
        report to start (``workers`` ≠ 0, or ``out`` and ``report``).
    fem_grasp.errors.MissingExtraError
        The ``search`` extra (pandas, Dask, pyarrow) or, for the report, the ``report`` extra is not installed
        (:func:`require_search_extra`).
    """
    t_start = time.perf_counter()
    timings: dict[str, float] = {}
    local_cluster = workers != 0 and client is None and not scheduler
    if local_cluster or (out is not None and report):
        from ..spawn import check_main_guard

        check_main_guard("fem_grasp.search(...)" + (f" with workers={workers}" if local_cluster else " with a report"),
                         "or run the search in this process with workers=0" + (", report=False" if out else ""))
    cache = None if cache_dir is None else Path(cache_dir)
    if rank not in RANKINGS:
        raise SearchError(f"unknown ranking {rank!r}; choose one of {sorted(RANKINGS)}")
    if workers is not None and int(workers) < 0:
        raise SearchError(f"workers must be >= 0 (0: a plain loop in this process), got {workers}")
    if scheduler and (client is not None or workers):
        raise SearchError("give a scheduler address or workers (a local cluster) or a client, not several")
    target = _target(accuracy)
    require_search_extra(dask=not (workers == 0 and client is None and not scheduler), files=out is not None,
                         report=report and out is not None)
    obj = _object(scene, quick, cache, dict(settings))
    options = obj.options
    geometry = None if target is None else _geometry(obj, target)

    t0 = time.perf_counter()
    rest_state, _ = cached_rest(obj.body, options.table_friction, backend=options.backend, down=obj.down,
                                cache_dir=cache)
    timings["rest"] = time.perf_counter() - t0
    setup = SearchSetup.from_rest(rest_state, name=obj.name, options=options,
                                  **({} if target is None else {"accuracy": target, "geometry": geometry}))
    identity = f"{setup.key}-{rest_code_digest()}"
    request = _request(candidates, heights, azimuths, tilts, ratios, seed, cone)

    outp = None if out is None else Path(out)
    previous: list[dict[str, Any]] = []
    manifest = None
    if outp is not None:
        manifest = _read_manifest(outp) if resume else None
        if manifest is not None:
            if manifest.get("identity") != identity:
                before = manifest.get("accuracy")
                if before != target:
                    said = lambda a: "no accuracy target" if a is None else f"accuracy {100 * a:g} %"  # noqa: E731
                    raise SearchError(f"{outp} holds a search with {said(before)}, this one has {said(target)}: its "
                                      f"rows are not this search's answers; resume it with the same accuracy, or start "
                                      "a new search in another folder (or without --resume)")
                raise SearchError(f"{outp} holds a search of another object, settings or fem_grasp code "
                                  f"({manifest.get('object')}); resume it with the same scene and settings, or "
                                  "start a new search in another folder (or without --resume)")
            old = read_results(outp)
            previous = [] if old is None else old.to_dict("records")
        elif resume and outp.exists() and any(outp.iterdir()) and not (outp / MARKER).exists() and not force:
            raise SearchError(f"{outp} is not a search folder (no {MANIFEST}); nothing to resume")
        else:
            prepare_out_dir(outp, force)

    t0 = time.perf_counter()
    if candidate_list is not None:
        cset = CandidateSet(list(candidate_list), len(candidate_list), {}, {}, int(seed))
    elif manifest is not None and manifest.get("request") == request:
        cset = CandidateSet([Candidate.from_dict(c) for c in manifest["candidates"]], int(manifest["valid"]),
                            manifest["grid"], manifest.get("rejected", {}), int(seed))
    else:
        cset = placement_candidates(rest_state, mu_finger=options.mu_finger, mu_table=options.table_friction,
                                    radius=options.finger_radius, count=candidates, heights=heights, azimuths=azimuths,
                                    tilts=tilts, ratios=ratios, seed=seed, max_squeeze=options.max_squeeze,
                                    cone=cone)
    timings["candidates"] = time.perf_counter() - t0
    if not len(cset):
        raise SearchError(f"no candidate placement on {obj.name}: the grid's points were rejected as "
                          + ", ".join(f"{k} ({v})" for k, v in cset.rejected.items()))
    keys = {c.key for c in cset}
    kept = [r for r in previous if r["key"] in keys and r.get("status") == "ok"]
    if len(previous) - len(kept):
        log.info("resume: %d earlier rows are errors or of candidates no longer in the list; evaluating them again",
                 len(previous) - len(kept))
    index = {c.key: c.index for c in cset}
    for r in kept:
        r["candidate"] = index[r["key"]]
        if target is None:
            _stamp(r, obj.expected_error)
    store = ResultStore(outp, kept)
    todo = [c for c in cset if c.key not in store]

    engine = "serial"
    doc = {"schema": SCHEMA, "schema_version": SCHEMA_VERSION, "fem_grasp_version": package_version(),
           "created": datetime.datetime.now().isoformat(timespec="seconds"), "identity": identity,
           "object": obj.name, "scene": None if obj.scene is None else obj.scene.to_dict(),
           "request": request, "grid": cset.grid, "valid": cset.valid, "rejected": cset.rejected, "seed": int(seed),
           "candidates": [c.to_dict() for c in cset], "rank": rank, "expected_error": obj.expected_error,
           "accuracy": target, "geometry": None if geometry is None else geometry.describe(),
           "column_units": {f: f.rsplit("_", 1)[1] if f != n or n.endswith("_deg") else ""
                            for n, (f, _) in FILE_COLUMNS.items()},
           "setup": {"mu_finger": setup.options.mu_finger, "mu_table": setup.options.mu_table,
                     "finger_radius": setup.options.finger_radius,
                     "weight": obj.body.weight, "young": setup.young, "poisson": setup.poisson,
                     "n_nodes": int(len(setup.points)), "rest_contacts": int(len(setup.rest_nodes))}}
    if outp is not None:
        _write_manifest(outp, doc)
        add_to_marker(outp, [MANIFEST, PARQUET_FILE, CSV_FILE])
        store.flush()

    bar = _progress(len(cset), len(cset) - len(todo), progress)

    def arrived(row: dict[str, Any]) -> None:
        if target is None:
            _stamp(row, obj.expected_error)
        store.add(row)
        if bar is not None:
            bar.update(1)
            bar.set_postfix_str(f"{sum(bool(r['grasped']) for r in store.rows.values())} grasped", refresh=False)
        if on_row is not None:
            on_row(row)

    t0 = time.perf_counter()
    try:
        if todo and workers == 0 and client is None and not scheduler:
            timings["engine start"] = 0.0
            t0 = time.perf_counter()
            run_serial(setup, todo, arrived)
        elif todo:
            with dask_client(client, scheduler, workers, connect_timeout) as (c, engine, started):
                timings["engine start"] = started
                t0 = time.perf_counter()
                run_on_dask(c, setup, todo, arrived)
        else:
            timings["engine start"] = 0.0
            engine = "none (every candidate was done)"
    finally:
        timings["evaluate"] = time.perf_counter() - t0
        store.flush()
        if bar is not None:
            bar.close()
    table = store.table()
    error = obj.expected_error
    ranked = rank_table(table, rank, per_row=True) if target is not None else rank_table(table, rank, error)
    result = SearchResult(table, ranked, cset, setup, engine, outp, timings=timings,
                          resumed=len(cset) - len(todo), rank_by=rank, rest_positions=rest_state.positions,
                          expected_error=error, accuracy=target)
    if outp is not None:
        t0 = time.perf_counter()
        with _render_process(best > 0 or report) as pool:  # one process draws every picture of the search
            if best > 0:
                result.best = _write_best(outp, setup, cset, ranked, int(best), obj.scene, pool)
            if report:
                from .report import write_search_report

                result.report = write_search_report(outp, result, pool)
        timings["report"] = time.perf_counter() - t0
    timings["total"] = time.perf_counter() - t_start
    if outp is not None:
        doc.update({"engine": engine, "timings": timings, "resumed": result.resumed,
                    "grasped": result.n_grasped, "errors": result.n_errors})
        _write_manifest(outp, doc)
    return result


@contextlib.contextmanager
def _render_process(wanted: bool) -> Iterator[Any]:
    """A :func:`fem_grasp.io.report.render_process` when pictures are wanted and pyvista is there, else None."""
    try:
        if not wanted:
            raise ImportError
        import pyvista  # noqa: F401
    except ImportError:
        yield None
        return
    from ..io.report import render_process

    with render_process() as pool:
        yield pool


def _write_best(out: Path, setup: SearchSetup, cset: CandidateSet, ranked: Any, count: int, scene: Any,
                pool: Any = None) -> list[Path]:
    """The best grasps' full results (result.json, the ParaView series) in ``out/best/01`` …, rerun in this
    process on the shared setup (the same answer as their rows; with an accuracy target, the accuracy loop's, its
    levels in result.json); each with its pickup report when pyvista is there."""
    from ..io.output import write_run
    from ..io.scene import with_overrides

    by_index = {c.index: c for c in cset}
    picked = ranked[ranked["rank"] > 0].head(count)
    folders = []
    ev, _ = evaluator_for(setup)
    for rank, idx in zip(picked["rank"], picked["candidate"]):
        cand = by_index[int(idx)]
        folder = out / "best" / f"{int(rank):02d}"
        result = ev.pickup(cand)
        sc = None
        if scene is not None:
            sc = with_overrides(scene, contacts=cand.finger_nodes, ratio=cand.ratio, accuracy=setup.accuracy,
                                directions=tuple(tuple(float(x) for x in d) for d in cand.directions),
                                name=f"{scene.name}, grasp {int(rank)} of the search")
        write_run(folder, result, sc, force=True, extra={"search_candidate": cand.to_dict()})
        try:
            import pyvista  # noqa: F401

            from ..io.report import write_report

            write_report(folder, pool=pool)
        except ImportError:
            log.warning("pyvista is not installed (the 'report' extra: pip install \"fem_grasp[report]\"): no "
                        "pictures for %s", folder)
        folders.append(folder)
    if folders:
        add_to_marker(out, [str(p.relative_to(out)) for f in folders for p in f.rglob("*") if p.is_file()])
    return folders
