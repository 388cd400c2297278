"""Compliance of a free body: a generalised inverse of the singular stiffness K.

K has the six rigid modes of Theorem 1 as its null space.  Holding six DOFs
that block every rigid motion ("grounding") leaves a non-singular matrix K_g,
factorised once per body.  Its inverse padded with zeros, X, satisfies
K X F = F for every load F orthogonal to the rigid modes, which is all the
bordered system (3) needs: the paper's A = Σ v̄ v̄ᵀ/λ and D may be replaced by
X_cc and (XG)_c without changing the contact forces (DESIGN.md, "Eq. (3) is a
Dirichlet problem").  Columns of X are computed the first time a node enters
contact and cached, so every later contact set costs a small dense solve.

K_g is factorised by one of the sparse direct solvers of :mod:`~fem_grasp.elastic.sparse_solvers` (CHOLMOD
where it loads, else SuperLU; ``$FEM_GRASP_SOLVER``).

Memory: rows kept per cached column
-----------------------------------
By default a cached column holds all 3n rows of X (what
:class:`~fem_grasp.elastic.response.ContactResponse` uses to rebuild the whole
displacement field).  At 100k vertices that is 7 MB per contact node.  With
``rows=`` a set of nodes (typically ``mesh.surface_nodes``, about a tenth of
the nodes of a large mesh), only those nodes' rows are cached; the whole field
is then recovered when needed by one more solve (:meth:`Compliance.combine`
applies X to the contact forces placed at their DOFs).  :class:`~fem_grasp.elastic.body.Body`
does this above ``body.FULL_COLUMNS_MAX_NODES`` vertices: the contact tracking
reads only the surface (``surface=``, :meth:`Compliance.combine_surface`).

Columns solved ahead
--------------------
A new contact waits for its columns, which cost more than the rest of a fine mesh's implicit increment
(the tomato's 5,901-vertex level: 1.6 of the squeeze's 2.9 s).  Inside :meth:`Compliance.solving_ahead`
(the squeeze and the lift of a pickup) the tracker queues the columns of the nodes about to touch
(:meth:`Compliance.solve_ahead`) and one background thread solves them on the other core while the
tracking goes on; a queued node's columns are taken when asked for.  This needs a solve that releases the
GIL (the ctypes CHOLMOD binding).  What is queued, in which batches, depends only on the calls made, and
BLAS keeps one thread throughout the section, so the columns and their round-off do not depend on timing.
"""

from __future__ import annotations

import contextlib
import copy
import logging
import threading
from concurrent import futures
from dataclasses import dataclass
from typing import Iterator

import numpy as np
import scipy.linalg as la
import scipy.sparse as sp

from ..mesh.tetmesh import check_rotation
from ..settings import DEFAULT_SETTINGS
from ..threads import blas_threads_held, outer_blas_threads, side_by_side
from . import sparse_solvers
from .sparse_solvers import choose_solver, factorize, solve_lock

__all__ = ["Compliance", "PREFETCH_NODES", "grounding_dofs"]

# The solvers' names, importable from here as before they had a module of their own.
SOLVERS, SOLVER_ENV = sparse_solvers.SOLVERS, sparse_solvers.SOLVER_ENV
cholmod_available = sparse_solvers.cholmod_available

log = logging.getLogger(__name__)

#: Nodes whose columns are solved for together when a new contact needs its own (:meth:`Compliance.prefetch`;
#: ``make bench``, section ``columns``, 31k vertices: 10.7 ms per column in batches of 90, 12.2 in batches of
#: 30, 40 for one node's three): the default of ``EngineSettings.prefetch_nodes``, which the contact trackers
#: read (this name stays for the scripts and benchmarks that read it).
PREFETCH_NODES = DEFAULT_SETTINGS.prefetch_nodes
#: :meth:`Compliance.solve_ahead` queues no batch of fewer nodes than this (a solve of few columns costs
#: several times more per column).
AHEAD_MIN_NODES = 10
#: ... and keeps up to this many batches queued.
AHEAD_BATCHES = 2
#: The right-hand sides and solutions of one multi-column solve take at most about this many bytes; more columns
#: are solved in blocks.  (The steam bun's flat base puts 2,714 nodes on the table at 21k vertices: their 8,142
#: columns at once needed two dense 129k × 8,142 arrays, 7.8 GiB each.)
SOLVE_BLOCK_BYTES = 512 * 2**20
#: ... and at most this many nodes' columns (126, within one of CHOLMOD's blocks) are solved at once: the dense
#: arrays of a solve (about 30 MB each at 10k vertices) are then reused by the allocator from one solve to the
#: next, where a few hundred nodes at once (a flat base on the table) mapped a gigabyte of fresh pages, whose
#: page faults took longer than copying the columns out.
SOLVE_NODES = 42


@dataclass(eq=False)  # hashed by identity
class _AheadBatch:
    """Nodes queued together by :meth:`Compliance.solve_ahead`, the future of their solved columns, and whether a
    branch holds it too (then it is never cancelled: only a batch nobody can ask for may be)."""

    nodes: tuple[int, ...]
    result: futures.Future
    shared: bool = False


_BACKGROUND: futures.ThreadPoolExecutor | None = None
_BACKGROUND_LOCK = threading.Lock()


def _background() -> futures.ThreadPoolExecutor:
    """The one thread that solves queued columns (:meth:`Compliance.solve_ahead`), started when first needed."""
    global _BACKGROUND
    with _BACKGROUND_LOCK:
        if _BACKGROUND is None:
            _BACKGROUND = futures.ThreadPoolExecutor(max_workers=1, thread_name_prefix="fem_grasp-columns")
        return _BACKGROUND


def grounding_dofs(points: np.ndarray, modes: np.ndarray) -> np.ndarray:
    """Six DOFs whose fixing removes all rigid motion, chosen for good conditioning.

    Candidates are the 9 DOFs of three well-spread nodes (far from the centre,
    far from the first, far from the line of the two); a pivoted QR of the
    rigid modes restricted to them picks the six most independent.
    """
    c = points.mean(axis=0)
    a = int(np.argmax(np.sum((points - c) ** 2, axis=1)))
    b = int(np.argmax(np.sum((points - points[a]) ** 2, axis=1)))
    ab = points[b] - points[a]
    ab /= np.linalg.norm(ab)
    rel = points - points[a]
    off = rel - np.outer(rel @ ab, ab)
    d = int(np.argmax(np.sum(off**2, axis=1)))
    cand = (3 * np.array([a, b, d])[:, None] + np.arange(3)).ravel()
    _, _, piv = la.qr(modes[cand].T, pivoting=True, mode="economic")
    return np.sort(cand[piv[:6]])


def _rotate_nodes(v: np.ndarray, rotation: np.ndarray) -> np.ndarray:
    """Each node's 3-vector of ``v`` ((3n,) or (3n, k)) turned by ``rotation``: Q v with Q = diag(R, …, R)."""
    blocks = v.reshape(-1, 3, *v.shape[1:])
    return np.einsum("ij,nj...->ni...", rotation, blocks).reshape(v.shape)


def _node_dofs(nodes: np.ndarray) -> np.ndarray:
    return (3 * np.asarray(nodes, dtype=np.int64)[:, None] + np.arange(3)).ravel()


def _remove_dofs(matrix: sp.spmatrix, drop: np.ndarray) -> sp.csc_matrix:
    """The symmetric matrix without the rows and columns ``drop`` (sorted), as CSC, in one pass."""
    n = matrix.shape[0]
    keep = np.ones(n, dtype=bool)
    keep[drop] = False
    new_index = np.cumsum(keep) - 1
    coo = sp.coo_matrix(matrix)
    sel = keep[coo.row] & keep[coo.col]
    m = n - len(drop)
    return sp.csc_matrix((coo.data[sel], (new_index[coo.row[sel]], new_index[coo.col[sel]])), shape=(m, m))


class Compliance:
    """Generalised inverse X of K, applied and cached column by column.

    Parameters
    ----------
    stiffness : (3n, 3n) sparse matrix
    points : (n, 3) reference coordinates
    modes : (3n, 6) rigid modes spanning the null space of ``stiffness``
    solver : {"cholmod", "superlu", "mumps", "auto"}, optional
        Sparse solver (see :func:`factorize`).
    rows : (s,) int, optional
        Nodes whose rows of X are kept in the column cache (module notes,
        "Memory"); default all nodes.  With ``rows`` set,
        :meth:`node_columns` can only return rows of those nodes.
    surface : (s,) int, optional
        Nodes whose rows are also cached compactly, for
        :meth:`combine_surface` (the contact tracking needs the deformed
        surface at every trial state, the whole field far less often); must
        be among ``rows``.

    Attributes
    ----------
    solver : name of the sparse solver used
    ground : the six grounded DOFs
    """

    def __init__(self, stiffness: sp.spmatrix, points: np.ndarray, modes: np.ndarray, *,
                 solver: str | None = None, rows: np.ndarray | None = None,
                 surface: np.ndarray | None = None) -> None:
        n = stiffness.shape[0]
        self.n_dofs = n
        self.n_nodes = n // 3
        self.ground = grounding_dofs(points, modes)
        free = np.ones(n, dtype=bool)
        free[self.ground] = False
        self.free = np.flatnonzero(free)
        self._free_position = np.where(free, np.cumsum(free) - 1, -1)  # each DOF's row in K_g (−1: grounded)
        self.solver = choose_solver(solver)
        kff = _remove_dofs(stiffness, self.ground)
        # verification.dolfinx.linalg swaps `factorize` for a one-argument MUMPS variant: call it that way by default.
        self._solve = factorize(kff) if solver is None else factorize(kff, self.solver)
        if rows is None:
            self.kept_nodes: np.ndarray | None = None
            self._row_dofs = None
        else:
            kept = np.unique(np.asarray(rows, dtype=np.int64))
            if kept.size == 0 or kept[0] < 0 or kept[-1] >= self.n_nodes:
                raise ValueError(f"rows must be node indices in 0 … {self.n_nodes - 1}, got {kept.size} values "
                                 f"from {kept.min(initial=0)} to {kept.max(initial=0)}")
            self.kept_nodes = kept
            self._row_dofs = _node_dofs(kept)
        # Where each kept row's value is in a solve's solution: the kept rows that are free, and their rows there
        # (None where those are the solution's rows in order: all rows kept); the grounded ones stay 0.
        kept_rows = self._free_position if self._row_dofs is None else self._free_position[self._row_dofs]
        self._n_kept_rows = len(kept_rows)
        self._kept_free = np.flatnonzero(kept_rows >= 0)
        source = kept_rows[self._kept_free]
        self._kept_source = None if np.array_equal(source, np.arange(len(self.free))) else source
        self._position = None if rows is None else np.full(self.n_nodes, -1, dtype=np.int64)
        if self._position is not None:
            self._position[self.kept_nodes] = np.arange(len(self.kept_nodes))
        self._columns: dict[int, np.ndarray] = {}
        self._ahead: dict[int, _AheadBatch] = {}  # nodes queued by solve_ahead, not yet taken into _columns
        self._ahead_on = False  # inside solving_ahead()
        self._submitted: list[futures.Future] = []  # every batch the open section queued, dropped ones too
        self._rotation: np.ndarray | None = None  # see rotated()
        self.surface_nodes = None if surface is None else np.unique(np.asarray(surface, dtype=np.int64))
        self._surface_rows = None if surface is None else self._row_positions(self.surface_nodes)
        self._surface_columns: dict[int, np.ndarray] = {}
        if self._surface_rows is not None and self.kept_nodes is not None \
                and np.array_equal(self.surface_nodes, self.kept_nodes):
            self._surface_columns = self._columns  # the kept rows are the surface rows: one cache
        log.debug("factorised K (%s) with %d DOFs grounded at %s", self.solver, n, self.ground)

    def apply(self, load: np.ndarray) -> np.ndarray:
        """X @ load for one (3n,) vector or a (3n, k) block."""
        load = np.asarray(load, dtype=float)
        if load.shape[0] != self.n_dofs:
            raise ValueError(f"expected a load with {self.n_dofs} rows, got shape {load.shape}")
        if self._rotation is None:
            return self._apply_unturned(load)
        # Q X Qᵀ load: into the factorised body's frame and back.
        return _rotate_nodes(self._apply_unturned(_rotate_nodes(load, self._rotation.T)), self._rotation)

    def _apply_unturned(self, load: np.ndarray) -> np.ndarray:
        """X @ load in the frame of the factorised body (:meth:`rotated`)."""
        out = np.zeros_like(load)
        with outer_blas_threads():  # inside the tracking's one-thread limit too
            with self._solve_lock():
                out[self.free] = self._solve(np.ascontiguousarray(load[self.free]))
        return out

    def _solve_lock(self) -> contextlib.AbstractContextManager:
        """:func:`~fem_grasp.elastic.sparse_solvers.solve_lock` of this factor's solve."""
        return solve_lock(self._solve)

    def branch(self) -> "Compliance":
        """The same compliance with column caches of its own (copies of this one's): a second tracker in another
        thread (:class:`~fem_grasp.grasp.lift_test.SpeculativeTest`) reads and adds columns without touching
        this one's, and what it computes does not depend on when this one's columns were added."""
        for batch in self._ahead.values():
            batch.shared = True
        return self._sharing_factor(dict(self._columns), dict(self._surface_columns), dict(self._ahead))

    def _sharing_factor(self, columns: dict, surface_columns: dict, ahead: dict) -> "Compliance":
        """A copy sharing this one's factor (its solves hold :func:`~fem_grasp.elastic.sparse_solvers.solve_lock`),
        with the given column caches (one cache where this one's kept rows are its surface rows) and queued
        columns."""
        new = copy.copy(self)
        new._columns = columns
        new._submitted = []
        new._surface_columns = columns if self._surface_columns is self._columns else surface_columns
        new._ahead = ahead
        return new

    def rotated(self, rotation: np.ndarray) -> "Compliance":
        """The compliance of the same body rigidly rotated by ``rotation`` (3, 3), sharing this factorisation.

        With Q = diag(R, …, R) the rotated body's stiffness is Q K Qᵀ (K depends on the points only through
        their differences, and its blocks turn with them), so X' = Q X Qᵀ is a generalised inverse of it
        with the same property, K' X' F = F for every load F orthogonal to its rigid modes: the contact
        forces and fields of eq. (3) follow from it unchanged (module notes).  Its column caches start
        empty; its grounded DOFs are this one's, in the unrotated frame.
        """
        rotation = check_rotation(rotation)
        new = self._sharing_factor({}, {}, {})  # and the free DOFs and the kept rows
        new._rotation = rotation if self._rotation is None else rotation @ self._rotation
        return new

    def _row_positions(self, nodes: np.ndarray) -> np.ndarray:
        """Positions, within the cached rows, of the DOFs of ``nodes``."""
        nodes = np.asarray(nodes, dtype=np.int64)
        if self._position is None:
            return _node_dofs(nodes)
        pos = self._position[nodes]
        if (pos < 0).any():
            raise ValueError(f"node {int(nodes[pos < 0][0])} is not among the {len(self.kept_nodes)} nodes whose "
                             "compliance rows are kept (Compliance(rows=...)); its rows need a full solve (apply)")
        return _node_dofs(pos)

    def _ensure(self, nodes: np.ndarray) -> None:
        wanted = [k for k in dict.fromkeys(int(k) for k in np.asarray(nodes).tolist()) if k not in self._columns]
        for batch in dict.fromkeys(self._ahead[k] for k in wanted if k in self._ahead):
            self._take(batch)
        new = [k for k in wanted if k not in self._columns]
        if not new:
            return
        bad = [k for k in new if not 0 <= k < self.n_nodes]
        if bad:
            raise ValueError(f"node {bad[0]} is not a node of the body (0 … {self.n_nodes - 1})")
        block = max(1, min(SOLVE_NODES, SOLVE_BLOCK_BYTES // (2 * 8 * 3 * len(self.free))))  # nodes per solve
        for start in range(0, len(new), block):
            self._solve_columns(new[start:start + block])

    def _solve_columns(self, new: list[int]) -> None:
        """Solve for and cache the columns of the nodes ``new`` (none cached yet) in one multi-column solve."""
        self._keep(self._solved_columns(new))

    def _keep(self, solved: list[tuple[int, np.ndarray, np.ndarray | None]]) -> None:
        for k, column, surface_column in solved:
            self._columns[k] = column
            if surface_column is not None:
                self._surface_columns[k] = surface_column

    def _solved_columns(self, new: list[int]) -> list[tuple[int, np.ndarray, np.ndarray | None]]:
        """(node, its kept rows, its surface rows or None) of the nodes ``new``, by one multi-column solve; reads
        nothing that changes, so it may run in another thread (:meth:`solve_ahead`)."""
        # The unit loads (Qᵀ of them when rotated) on the free DOFs only, and only the kept rows of the
        # solution: at 100k vertices each (3n, 90) array is 225 MB.
        unit = np.eye(3) if self._rotation is None else self._rotation.T
        rhs = np.zeros((len(self.free), 3 * len(new)), order="F")  # CHOLMOD's layout: not copied again
        for j, k in enumerate(new):
            at = self._free_position[3 * k: 3 * k + 3]
            rhs[at[at >= 0], 3 * j: 3 * j + 3] = unit[at >= 0]
        with outer_blas_threads():  # inside the tracking's one-thread limit too
            with self._solve_lock():
                sol = self._solve(rhs)
        del rhs
        apart = self._surface_rows is not None and self._surface_columns is not self._columns
        kept, source = self._kept_free, self._kept_source
        out = []
        # Node by node from CHOLMOD's columns (Fortran order: each one contiguous), into a C-ordered (rows, 3) block
        # each: one pass over the solution (the whole block gathered row-wise, then copied column-wise, took three:
        # a third of a 9,700-vertex level's column time).
        for j, k in enumerate(new):
            column = np.zeros((self._n_kept_rows, 3))
            column[kept] = sol[:, 3 * j: 3 * j + 3] if source is None else sol[source, 3 * j: 3 * j + 3]
            if self._rotation is not None:  # Q on the kept rows only (whole node blocks): a tenth of them above 20k
                column = _rotate_nodes(column, self._rotation)
            out.append((k, column, np.ascontiguousarray(column[self._surface_rows]) if apart else None))
        return out

    @contextlib.contextmanager
    def solving_ahead(self) -> Iterator[None]:
        """A section in which :meth:`solve_ahead` queues columns for a background thread (module notes, "Columns
        solved ahead"); with a solver that holds the GIL it changes nothing.

        BLAS keeps one thread throughout and no solve gets the threads back (:func:`~fem_grasp.threads.side_by_side`),
        so every column has the same round-off whichever thread solves it and whenever; on leaving, the section
        waits for every batch it queued, those dropped while being solved too: no column solve outlives the
        section's one-thread limit (leaving it gives BLAS its threads back, a process-wide setting).
        """
        if not getattr(self._solve, "releases_gil", False) or self._ahead_on or not blas_threads_held():
            yield
            return
        with side_by_side():
            self._ahead_on = True
            try:
                yield
            finally:
                self._ahead_on = False
                futures.wait(self._submitted)
                self._submitted = []

    @property
    def solving_ahead_now(self) -> bool:
        """Whether a :meth:`solving_ahead` section is open (where :meth:`solve_ahead` queues)."""
        return self._ahead_on

    def solve_ahead(self, likely: np.ndarray, count: int) -> None:
        """In a :meth:`solving_ahead` section, keep about ``count`` of the likeliest uncached nodes of ``likely``
        (most likely first) queued for a background thread, which solves each batch in one multi-column solve;
        a queued node's columns are taken when first asked for (waiting for its batch if need be).  Up to
        :data:`AHEAD_BATCHES` batches of ``count`` nodes are queued; a batch none of whose nodes is among the
        ``2 × AHEAD_BATCHES × count`` likeliest uncached any more is dropped.  Outside a section, nothing.

        What is queued depends only on the calls made, never on how far the background thread has got, so the
        columns (and their round-off) are the same in every run.
        """
        if not self._ahead_on:
            return
        fresh: list[int] = []
        for k in np.asarray(likely).tolist():
            if len(fresh) >= 2 * AHEAD_BATCHES * count:
                break
            if k not in self._columns:
                fresh.append(int(k))
        near = set(fresh)
        for batch in dict.fromkeys(self._ahead.values()):
            if near.isdisjoint(batch.nodes):  # stale: the contacts went elsewhere
                if not batch.shared:
                    batch.result.cancel()  # not solved yet: spare the thread (nobody takes it either way)
                for k in batch.nodes:
                    self._ahead.pop(k, None)
        nodes = [k for k in fresh if k not in self._ahead][:AHEAD_BATCHES * count - len(self._ahead)]
        for start in range(0, len(nodes), count):
            part = nodes[start:start + count]
            if len(part) < AHEAD_MIN_NODES:
                break
            batch = _AheadBatch(tuple(part), _background().submit(self._solved_columns, part))
            self._submitted.append(batch.result)
            for k in part:
                self._ahead[k] = batch

    def _take(self, batch: "_AheadBatch") -> None:
        """Move a queued batch's columns into the cache (waiting for its solve)."""
        solved = batch.result.result()
        for k in batch.nodes:
            self._ahead.pop(k, None)
        self._keep([entry for entry in solved if entry[0] not in self._columns])

    def prefetch(self, nodes: np.ndarray, likely: np.ndarray | None = None, count: int = 0) -> None:
        """Compute and cache the columns of every uncached node of ``nodes`` in one multi-column solve,
        with those of the first uncached nodes of ``likely`` (the likely next contacts, most likely
        first) up to ``count`` nodes in all.

        A sparse solve streams the whole factor once whatever the number of right-hand sides, so
        90 columns at once cost several times less per column than 3 (:data:`PREFETCH_NODES`).
        """
        nodes = [k for k in dict.fromkeys(int(k) for k in np.asarray(nodes).tolist())
                 if k not in self._columns and k not in self._ahead]
        if not nodes:
            return
        if likely is not None and len(nodes) < count:
            chosen = set(nodes)
            for k in np.asarray(likely).tolist():
                if len(nodes) >= count:
                    break
                if k not in chosen and k not in self._columns and k not in self._ahead:
                    nodes.append(int(k))
                    chosen.add(k)
        self._ensure(np.asarray(nodes, dtype=np.int64))

    def is_cached(self, node: int) -> bool:
        """Whether the node's columns are cached or queued (:meth:`solve_ahead`)."""
        return int(node) in self._columns or int(node) in self._ahead

    def node_columns(self, nodes: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
        """Columns of X for the DOFs of ``nodes``, computed once per node and cached.

        Parameters
        ----------
        nodes : (m,) int
            Nodes whose three columns are wanted (the contact nodes).
        rows : (r,) int, optional
            Nodes whose rows are wanted.  Default: every kept row, i.e. all 3n
            rows, or those of the ``rows`` given to the constructor.

        Returns
        -------
        (3n, 3m), (3s, 3m) or (3r, 3m) array
        """
        self._ensure(nodes)
        if rows is None:
            return np.concatenate([self._columns[int(k)] for k in nodes], axis=1)
        pos = self._row_positions(rows)  # rows first: no (3n, 3m) temporary
        return np.concatenate([self._columns[int(k)][pos] for k in nodes], axis=1)

    def contact_block(self, nodes: np.ndarray) -> np.ndarray:
        """X_cc (3m, 3m): the compliance among the DOFs of ``nodes`` (which must be kept rows)."""
        return self.node_columns(nodes, rows=nodes)

    def combine(self, nodes: np.ndarray, coefficients: np.ndarray) -> np.ndarray:
        """X[:, c] @ coefficients for the DOFs c of ``nodes``: (3n,), from the cached columns (no (3n, 3m) copy),
        or by one solve when only some rows are kept (``rows=``).

        A contact response calls this for every displacement field; keeping a
        (3n, 3m) block per contact set instead took 4 GiB at 10k vertices.
        """
        if self.kept_nodes is not None:
            load = np.zeros(self.n_dofs)
            load[_node_dofs(np.asarray(nodes, dtype=np.int64))] = np.asarray(coefficients, dtype=float).reshape(-1)
            return self.apply(load)
        return self._combine(self._columns, nodes, coefficients)

    def combine_surface(self, nodes: np.ndarray, coefficients: np.ndarray) -> np.ndarray:
        """:meth:`combine` on the rows of the ``surface`` nodes only: (3s,), in ``surface_nodes`` order."""
        if self._surface_rows is None:
            raise ValueError("this Compliance keeps no surface rows (Compliance(surface=...))")
        return self._combine(self._surface_columns, nodes, coefficients)

    def surface_block(self, nodes: np.ndarray) -> np.ndarray:
        """(3s, 3m) the surface rows of the columns of ``nodes``, as one array (what :meth:`combine_surface` sums
        column block by column block)."""
        if self._surface_rows is None:
            raise ValueError("this Compliance keeps no surface rows (Compliance(surface=...))")
        self._ensure(nodes)
        return np.concatenate([self._surface_columns[int(k)] for k in nodes], axis=1)

    def _combine(self, columns: dict[int, np.ndarray], nodes: np.ndarray, coefficients: np.ndarray) -> np.ndarray:
        self._ensure(nodes)
        a = np.asarray(coefficients, dtype=float).reshape(-1, 3)
        out = columns[int(nodes[0])] @ a[0]
        for k, ak in zip(nodes[1:], a[1:]):
            out += columns[int(k)] @ ak
        return out

    @property
    def cached_nodes(self) -> int:
        return len(self._columns)

    @property
    def cache_bytes(self) -> int:
        """Memory held by the column cache."""
        extra = self._surface_columns.values() if self._surface_columns is not self._columns else ()
        return sum(c.nbytes for c in self._columns.values()) + sum(c.nbytes for c in extra)
