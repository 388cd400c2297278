"""The reference's pickup: rest, squeeze, lift test and lift as sequences of static contact problems.

Every phase of Algorithm 1 of *Picking up Soft 3D Objects with Two Fingers*
is a quasi-static, path-dependent frictional contact problem; here each
increment of its parameter — the gravity load factor λ (rest), the squeeze
depth ρ, the hanging weight w (lift test) or the lift height — is **one**
static problem solved by :func:`verification.friction.reference.contact.solve_static`, with
the slip measured from the previous increment's contact points.  No event is
located: contact sets and stick/slip states are whatever each static problem
finds.

* **Rest (§III-A).**  The posed body, undeformed, touches the table at its
  support triangle; λ rises from 0 to 1 in ``n`` equal increments.
* **Squeeze (§III-C).**  ℱ₁'s centre moves by ρ d̂₁ and ℱ₂'s by sρ d̂₂ from the
  fingertip centres at ρ = 0 (taken from fem_grasp's result: placement is not
  what is verified); λ = 1, the table stays.  The squeeze between two lift
  tests ρ_{l−1} → ρ_l is cut into ``M`` equal increments.
* **Lift test (§III-B).**  At each ρ_l, the table is removed and gravity
  switched off (λ = 0) with the fingers where they are: one static problem
  from the squeeze state (the *hanging base*, solved by continuation as the
  table's forces fade out, so that of the zero-weight states — a family when
  the body can turn about two load-bearing contacts — the one connected to
  the squeeze state is taken).  Then the weights h, 2h, 3h, … are applied
  in turn from zero, each one static problem from the previous hanging state
  (the load path of fem_grasp's lift test, reimplemented here: friction is
  path dependent), until one is **not held** or mg is reached; w(ρ_l) = the
  last held weight.  Held: a static state exists, each finger keeps at least
  one contact and at least one of them sticks.  A weight with no static state
  is retried through its midpoint, up to three halvings (the same rule).
  With fewer than three finger contacts, or
  collinear ones (Theorem 3), w = 0.  The test passes when w ≥ mg.
* **Lift (§III-C, last paragraph).**  From the state at the passing ρ, both
  fingertips move up in increments of (fem_grasp's increment)/M; success when
  no table contact remains, failure when every contact of one finger slides
  or no static state exists.  A failed lift sends the squeeze on from the
  lift-start state (Algorithm 1 step 6), up to four lifts, as fem_grasp does.

Every static problem is solved by Newton's method from the previous state,
and, when that finds no static state, again by continuation in its data (the
load factor, and the forces of the table contacts that the lift test removes,
faded out) with the slip reference unchanged — the same problem, so the same
answer when both succeed.  A squeeze or lift increment whose problem has no
solution even so is split in halves, up to ``MAX_SPLITS`` times, before the
phase fails (a reference-side safeguard; it only refines the path).
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np

from .body import CondensedBody
from .contact import (
    FINGER1,
    FINGER2,
    SLIP,
    STICK,
    TABLE,
    NoEquilibrium,
    Obstacles,
    PinchedNode,
    StaticState,
    solve_continued,
    solve_static,
)

log = logging.getLogger(__name__)

#: Halvings of an increment with no static state before a squeeze or lift fails.
MAX_SPLITS = 4
#: Halvings of a lift-test weight step with no static state (fem_grasp's rule: three).
HANG_HALVINGS = 3
#: Lifts tried before the pickup fails (fem_grasp's default).
MAX_LIFT_ATTEMPTS = 4
#: Finger contacts closer to a line than this × diameter are collinear (Theorem 3).
COLLINEAR_TOL = 1e-9
#: w ≥ mg (1 − this) passes the lift test (the weights are sums of steps h).
PASS_RTOL = 1e-12


@dataclass(frozen=True)
class Scenario:
    """What the reference takes from a scene and fem_grasp's result (the placement), in SI units.

    Attributes
    ----------
    points, tets : the posed mesh
    young, poisson, density, gravity : material and load
    table_z : table height
    radius, mu_finger, mu_table : fingertips and friction
    centers0 : (2, 3) fingertip centres at ρ = 0
    velocities : (2, 3) d̂₁ and s d̂₂
    finger_nodes : (p_i, p_j)
    weight : mg of fem_grasp's body, newtons
    lift_test_step : h, newtons
    max_squeeze, step, max_lift : metres (step: fem_grasp's squeeze and lift increment)
    test_depths : squeeze depths of fem_grasp's lift tests, ascending
    """

    points: np.ndarray
    tets: np.ndarray
    young: float
    poisson: float
    density: float
    gravity: float
    table_z: float
    radius: float
    mu_finger: float
    mu_table: float
    centers0: np.ndarray
    velocities: np.ndarray
    finger_nodes: tuple[int, int]
    weight: float
    lift_test_step: float
    max_squeeze: float
    step: float
    max_lift: float
    test_depths: tuple[float, ...]

    def test_schedule(self) -> Callable[[float], float]:
        """The next lift-test depth after ρ: fem_grasp's test depths, then every ``step`` up to ``max_squeeze``."""
        depths = np.array(sorted(set(self.test_depths)), float)

        def nxt(rho: float) -> float:
            later = depths[depths > rho * (1 + 1e-12) + 1e-15]
            if len(later):
                return float(later[0])
            return float(min(rho + self.step, self.max_squeeze))

        return nxt


@dataclass
class Record:
    """One state of the reference path.

    phase : "rest", "squeeze" or "lift"; rho, lift : parameters; attempt : lift attempt (1-based) for lifts
    state : the StaticState; sample : a side state at a requested parameter (not on the path)
    """

    phase: str
    rho: float
    lift: float
    state: StaticState
    attempt: int = 0
    sample: bool = False


@dataclass
class RefOutcome:
    """The reference's pickup.

    Attributes
    ----------
    success, reason : verdict
    squeeze_depth : ρ at the (last) lift start, or where the squeeze stopped
    liftable : [(ρ_l, w(ρ_l))]
    path : squeeze and lift states on the increment grid, in order
    samples : side states at requested parameters: {("squeeze", ρ) or ("lift", ρ_start, h): Record}
    lift_attempts : [(ρ, success, reason, height)]
    lift_off_height : lift height at success (first increment with no table contact), else nan
    final : the last state (lift-off on success)
    solves : static problems solved; splits : increments split; continued : problems found by continuation;
    seconds : wall time
    """

    success: bool = False
    reason: str = ""
    squeeze_depth: float = 0.0
    liftable: list[tuple[float, float]] = field(default_factory=list)
    path: list[Record] = field(default_factory=list)
    samples: dict[tuple, Record] = field(default_factory=dict)
    lift_attempts: list[tuple[float, bool, str, float]] = field(default_factory=list)
    lift_off_height: float = float("nan")
    final: StaticState | None = None
    hangs: int = 0
    splits: int = 0
    solves: int = 0
    continued: int = 0
    seconds: float = 0.0


class ReferencePickup:
    """Algorithm 1 with the reference solver (module notes).

    Parameters
    ----------
    scenario : Scenario
    body : CondensedBody of the scenario's mesh and material (built when not given)
    """

    def __init__(self, scenario: Scenario, body: CondensedBody | None = None) -> None:
        from .body import condense

        self.sc = scenario
        self.body = body if body is not None else condense(scenario.points, scenario.tets, scenario.young,
                                                           scenario.poisson, scenario.density, scenario.gravity)
        self.mg = scenario.weight
        self.solves = 0
        self.splits = 0
        self.continued = 0

    # ------------------------------------------------------------ geometry
    def obstacles(self, rho: float, lift: float, *, table: bool = True, fingers: bool = True) -> Obstacles:
        sc = self.sc
        centers = sc.centers0 + rho * sc.velocities + np.array([0.0, 0.0, lift]) if fingers else None
        return Obstacles(None if centers is None else np.asarray(centers, float), sc.radius,
                         sc.table_z if table else None, sc.mu_finger, sc.mu_table)

    def solve(self, prev: StaticState, obst: Obstacles, load: float,
              fade: tuple[np.ndarray, np.ndarray] | None = None) -> StaticState:
        """One static problem from ``prev`` (its positions are the slip references).

        Newton from ``prev``; if that finds no static state, the same problem by continuation in its data
        (:func:`~verification.friction.reference.contact.solve_continued`, the load and the ``fade`` forces of contacts the
        problem drops), which finds the branch connected to ``prev`` when a direct Newton misses it.
        """
        self.solves += 1
        try:
            return solve_static(self.body, obst, prev.positions(self.body), prev.obstacles, prev.nodes, prev.owner,
                                prev.forces, prev.rigid, load)
        except NoEquilibrium as first:
            try:
                st = solve_continued(self.body, obst, prev, load, fade=fade)
            except NoEquilibrium:
                raise first from None
            self.continued += 1
            return st

    def advance(self, prev: StaticState, obst_of: Callable[[float], Obstacles], t0: float, t1: float,
                load_of: Callable[[float], float] = lambda t: 1.0, splits: int = MAX_SPLITS) -> StaticState:
        """One increment t0 → t1 of a parameter; halved (recursively, ``splits`` times) when it has no solution."""
        try:
            return self.solve(prev, obst_of(t1), load_of(t1))
        except NoEquilibrium:
            if splits <= 0:
                raise
        self.splits += 1
        mid = 0.5 * (t0 + t1)
        half = self.advance(prev, obst_of, t0, mid, load_of, splits - 1)
        return self.advance(half, obst_of, mid, t1, load_of, splits - 1)

    # ---------------------------------------------------------------- rest
    def undeformed(self) -> StaticState:
        """The posed body, undeformed, with no contact and no load (λ = 0)."""
        s = self.body.n_surface
        return StaticState(0.0, self.obstacles(0.0, 0.0, fingers=False), np.zeros(0, np.int64), np.zeros(0, np.int64),
                           np.zeros((0, 3)), np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros(6), np.zeros((s, 3)))

    def rest(self, n: int) -> StaticState:
        """The resting state: gravity ramped from 0 to 1 in ``n`` equal increments of λ."""
        st = self.undeformed()
        obst = st.obstacles
        for j in range(1, n + 1):
            st = self.advance(st, lambda t: obst, (j - 1) / n, j / n, load_of=lambda t: t)
        return st

    def from_state(self, nodes: np.ndarray, owner: np.ndarray, forces: np.ndarray, sliding: np.ndarray,
                   displacements: np.ndarray, load: float, obst: Obstacles) -> tuple[StaticState, float]:
        """A StaticState from another solver's contact forces and displacement field (n, 3).

        The rigid part is recovered as a = Qᵀ(u_s − H(f + λg)); returns the state and the relative misfit
        ‖u_s − H(f + λg) − Qa‖ / ‖u_s‖ (zero when the field is the elastic response to those forces).
        """
        b = self.body
        us = np.asarray(displacements, float)[b.surface]
        el = b.surface_displacements(nodes, forces, load, np.zeros(6))
        a = b.Q.T @ (us - el).reshape(-1)
        fit = el + (b.Q @ a).reshape(-1, 3)
        misfit = float(np.linalg.norm(us - fit) / max(np.linalg.norm(us), 1e-300))
        status = np.where(np.asarray(sliding, bool), SLIP, STICK)
        st = StaticState(load, obst, np.asarray(nodes, np.int64), np.asarray(owner, np.int64),
                         np.asarray(forces, float).reshape(-1, 3), status, np.zeros((len(nodes), 3)), a, us)
        return st, misfit

    def with_fingers(self, rest: StaticState) -> StaticState:
        """The resting state with both fingertips touching p_i, p_j (zero force) at ρ = 0."""
        i, j = self.sc.finger_nodes
        nodes = np.concatenate([rest.nodes, [i, j]]).astype(np.int64)
        owner = np.concatenate([rest.owner, [FINGER1, FINGER2]]).astype(np.int64)
        forces = np.vstack([rest.forces, np.zeros((2, 3))])
        status = np.concatenate([rest.status, [STICK, STICK]]).astype(np.int64)
        return replace(rest, obstacles=self.obstacles(0.0, 0.0), nodes=nodes, owner=owner, forces=forces,
                       status=status, slips=np.zeros((len(nodes), 3)))

    # ------------------------------------------------------------ lift test
    def _collinear(self, nodes: np.ndarray) -> bool:
        if len(nodes) < 3:
            return True
        p = self.body.points[nodes]
        sv = np.linalg.svd(p - p.mean(axis=0), compute_uv=False)
        return bool(sv[1] <= COLLINEAR_TOL * self.body.diameter)

    def _held(self, st: StaticState) -> tuple[bool, str]:
        for f in (FINGER1, FINGER2):
            on = st.owner == f
            if not on.any():
                return False, f"finger {f + 1} lost contact"
            if not (st.status[on] == STICK).any():
                return False, f"every contact of finger {f + 1} slides"
        return True, ""

    def hang(self, start: StaticState, weight: float, depth: int = HANG_HALVINGS) -> tuple[bool, str, StaticState | None]:
        """Raise the hanging weight from ``start`` to ``weight`` in one static problem; held or not."""
        load = weight / self.mg
        try:
            st = self.solve(start, start.obstacles, load)
        except (NoEquilibrium, PinchedNode) as exc:
            if depth <= 0:
                return False, f"no static state: {exc}", None
            mid = self.hang(start, 0.5 * (start.load * self.mg + weight), depth - 1)
            if not mid[0]:
                return mid
            return self.hang(mid[2], weight, depth - 1)
        held, why = self._held(st)
        return held, why, st

    def hanging_base(self, squeezed: StaticState) -> tuple[bool, str, StaticState | None]:
        """The squeeze state's finger contacts without the table, at zero weight, settled."""
        fing = squeezed.owner != TABLE
        nodes = squeezed.nodes[fing]
        if fing.sum() < 3:
            return False, "fewer than three finger contacts", None
        if self._collinear(nodes):
            return False, "collinear finger contacts", None
        obst = replace(squeezed.obstacles, table=None)
        table = squeezed.owner == TABLE
        # Removing the table and the weight at once is a large jump, and at zero weight the problem can have a
        # family of solutions (the body free to turn about two load-bearing contacts): the branch connected to
        # the squeeze state (continuation, the table's forces faded out) first, Newton from it directly second.
        try:
            self.solves += 1
            st = solve_continued(self.body, obst, squeezed, 0.0, fade=(squeezed.nodes[table], squeezed.forces[table]))
        except (NoEquilibrium, PinchedNode):
            try:
                st = self.solve(squeezed, obst, 0.0)
            except (NoEquilibrium, PinchedNode) as exc:
                return False, f"no static state: {exc}", None
        held, why = self._held(st)
        return held, why, st

    def liftable(self, squeezed: StaticState) -> float:
        """w(ρ_l) from the squeeze state at ρ_l: the weight raised from zero in steps of h (module notes)."""
        h = self.sc.lift_test_step
        ok, _, st = self.hanging_base(squeezed)
        if not ok:
            return 0.0
        w, k = 0.0, 1
        while w < self.mg * (1.0 - 1e-12):
            held, _, nxt = self.hang(st, k * h)
            if not held:
                break
            w, st, k = k * h, nxt, k + 1
        return w

    # ----------------------------------------------------------------- run
    def run(self, start: StaticState, increments: int, *, samples: dict | None = None,
            max_attempts: int = MAX_LIFT_ATTEMPTS) -> RefOutcome:
        """Squeeze, lift tests and lift from ``start`` (ρ = 0), ``increments`` per lift-test interval.

        ``samples`` = {"squeeze": [ρ, …], "lift": {ρ_start: [h, …]}}: parameters where side states are solved
        from the preceding grid state (for comparison with another solver's path) without changing the path.
        """
        t_start = time.perf_counter()
        sc = self.sc
        m = int(increments)
        if m < 1:
            raise ValueError(f"increments must be ≥ 1, got {increments!r}")
        out = RefOutcome()
        sq_samples = sorted(set((samples or {}).get("squeeze", [])))
        lift_samples = (samples or {}).get("lift", {})
        nxt = sc.test_schedule()
        state, rho, w, attempt = start, 0.0, 0.0, 0
        out.path.append(Record("squeeze", 0.0, 0.0, state))

        def squeeze_obst(t: float) -> Obstacles:
            return self.obstacles(t, 0.0)

        def sample_squeeze(prev: StaticState, r0: float, r1: float) -> None:
            for rs in sq_samples:
                if r0 < rs <= r1 * (1 + 1e-13) and ("squeeze", rs) not in out.samples:
                    try:
                        st = state_at(prev, r0, rs)
                        out.samples[("squeeze", rs)] = Record("squeeze", rs, 0.0, st, sample=True)
                    except (NoEquilibrium, PinchedNode) as exc:
                        log.debug("sample at ρ = %.6g: %s", rs, exc)

        def state_at(prev: StaticState, r0: float, rs: float) -> StaticState:
            return self.advance(prev, squeeze_obst, r0, rs)

        while True:
            target = nxt(rho)
            if target <= rho:
                out.reason = (f"the lift test did not pass by the maximum squeeze depth ρ = {sc.max_squeeze:.4g} m "
                              f"(liftable weight {w:.4g} N < weight {self.mg:.4g} N)")
                break
            try:
                for j in range(1, m + 1):
                    r1 = rho + (target - rho) * j / m if j < m else target
                    r0 = out.path[-1].rho
                    prev = state
                    state = self.advance(state, squeeze_obst, r0, r1)
                    sample_squeeze(prev, r0, r1)
                    out.path.append(Record("squeeze", r1, 0.0, state))
            except (NoEquilibrium, PinchedNode) as exc:
                out.reason = f"squeeze failed at ρ = {out.path[-1].rho:.4g} m: {exc}"
                break
            rho = target
            w = self.liftable(state)
            out.liftable.append((rho, w))
            log.debug("reference ρ = %.6g: w = %.4g", rho, w)
            if w < self.mg * (1 - PASS_RTOL):
                continue
            # Lift.
            attempt += 1
            lift_start = state
            ok, why, height, last = self._lift(lift_start, rho, m, attempt, out, lift_samples.get(rho, []))
            out.lift_attempts.append((rho, ok, why, height))
            out.final = last
            out.squeeze_depth = rho
            if ok:
                out.success = True
                out.lift_off_height = height
                break
            if attempt >= max_attempts or rho >= sc.max_squeeze * (1 - 1e-9):
                out.reason = why
                break
            state = lift_start
        if out.final is None:
            out.final = state
            out.squeeze_depth = out.path[-1].rho
        out.solves, out.splits, out.continued = self.solves, self.splits, self.continued
        out.seconds = time.perf_counter() - t_start
        return out

    def squeeze_state_at(self, out: RefOutcome, rho: float, increments: int) -> StaticState | None:
        """The reference's squeeze state at ``rho``: from its path, or by squeezing on from its last squeeze
        state (``increments`` per lift-test interval, no lift test); None when that squeeze fails."""
        recs = [r for r in out.path if r.phase == "squeeze" and not r.sample]
        for r in recs:
            if abs(r.rho - rho) <= 1e-12 * max(rho, 1e-12):
                return r.state
        last = recs[-1]
        if last.rho > rho:
            return None
        nxt = self.sc.test_schedule()
        state, r0 = last.state, last.rho
        try:
            while r0 < rho * (1 - 1e-12):
                target = min(nxt(r0), rho)
                t_prev = r0
                for j in range(1, increments + 1):
                    r1 = r0 + (target - r0) * j / increments if j < increments else target
                    state = self.advance(state, lambda t: self.obstacles(t, 0.0), t_prev, r1)
                    t_prev = r1
                r0 = target
        except (NoEquilibrium, PinchedNode):
            return None
        return state

    def forced_lift(self, out: RefOutcome, rho: float, increments: int, heights: list[float]
                    ) -> tuple[bool, str, float, StaticState] | None:
        """A lift from the reference's squeeze state at ``rho`` whatever its own lift test says (to compare the
        lift mechanics where the other solver lifted); its records have ``attempt`` 0."""
        st = self.squeeze_state_at(out, rho, increments)
        if st is None:
            return None
        return self._lift(st, rho, increments, 0, out, heights)

    def _lift(self, start: StaticState, rho: float, m: int, attempt: int, out: RefOutcome,
              heights: list[float]) -> tuple[bool, str, float, StaticState]:
        sc = self.sc
        dh = sc.step / m
        obst_of = lambda t: self.obstacles(rho, t)  # noqa: E731
        state, h, j = start, 0.0, 0
        out.path.append(Record("lift", rho, 0.0, start, attempt))
        pending = sorted(heights)
        while h < sc.max_lift * (1 - 1e-12):
            j += 1
            h1 = min(j * dh, sc.max_lift)
            prev = state
            try:
                state = self.advance(state, obst_of, h, h1)
            except (NoEquilibrium, PinchedNode) as exc:
                return False, f"lift failed at height {h:.4g} m: {exc}", h, prev
            for hs in [x for x in pending if h < x <= h1 * (1 + 1e-13)]:
                try:
                    side = self.advance(prev, obst_of, h, hs)
                    out.samples[("lift", rho, hs)] = Record("lift", rho, hs, side, attempt, sample=True)
                except (NoEquilibrium, PinchedNode) as exc:
                    log.debug("lift sample at %.6g: %s", hs, exc)
                pending.remove(hs)
            h = h1
            out.path.append(Record("lift", rho, h, state, attempt))
            for f in (FINGER1, FINGER2):
                on = state.owner == f
                if on.any() and (state.status[on] == SLIP).all():
                    return (False, f"every contact of finger {f + 1} slides at lift height {h:.4g} m: "
                            "the object slides on the finger", h, state)
            if not (state.owner == TABLE).any():
                return True, "", h, state
        return (False, f"the object is still on the table after lifting the fingers {sc.max_lift:.4g} m", h, state)
