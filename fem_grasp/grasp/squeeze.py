"""Squeezing the object on the table (paper §III-C, Algorithm 1 step 3).

Fingertip ℱ₁ translates by ρ d̂₁ and ℱ₂ by s ρ d̂₂ while ρ, the squeeze depth,
grows from 0.  The contact index sets 𝕀, 𝕁, 𝕂 and the sliding set ℙ change
only at events A–D, tracked by :class:`~fem_grasp.contact.tracking.Tracker` (which
holds the paper's machinery: eqs. (5)–(8), homotopy, event location).  After
every increment ``step`` in ρ (events inside an increment split it but do not
repeat the test) the lift test of §III-B updates the liftable weight w(ρ)
(Algorithm 1 step 4); the squeeze stops when the test passes or ρ reaches
``max_squeeze`` (step 6).

The initial state (:func:`initial_state`) is the resting state of §III-A with
the fingertips placed tangent to the deformed surface at p_i and p_j: the
centre of ℱ₁ is p̃_i + R n̂_out(p̃_i), n̂_out the area-weighted outward vertex
normal of the deformed surface.  The finger nodes join the contact set with
zero force (they only touch).
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ..contact.kernels import jit
from ..contact.obstacles import FINGER1, FINGER2, TABLE
from ..contact.tracking import ContactEvent, ContactState, Parameter, Tracker, run
from ..errors import TrackingError
from .lift_test import LiftTest, SpeculativeOutcome, SpeculativeTest
from .rest import RestState

__all__ = ["PassedAbove", "SqueezeOutcome", "initial_state", "next_passed", "squeeze"]

log = logging.getLogger(__name__)


def initial_state(tracker: Tracker, rest_state: RestState, finger_nodes: tuple[int, int]) -> ContactState:
    """The resting configuration with both fingertips touching at p_i, p_j (ρ = 0)."""
    i, j = (int(k) for k in finger_nodes)
    positions = rest_state.positions
    out = rest_state.body.mesh.outward_normals(positions)
    for k in (i, j):
        if not np.linalg.norm(out[k]) > 0:
            raise ValueError(f"finger contact node {k} is not a surface node")
    if i in set(rest_state.contact_nodes.tolist()) or j in set(rest_state.contact_nodes.tolist()):
        raise ValueError("a finger contact node already touches the table")
    centers = np.stack([positions[i] + tracker.radius * out[i], positions[j] + tracker.radius * out[j]])
    nodes = np.concatenate([rest_state.contact_nodes, [i, j]])
    owner = np.concatenate([np.full(rest_state.n_contacts, TABLE), [FINGER1, FINGER2]])
    disp = np.vstack([rest_state.contact_displacements, rest_state.displacements[[i, j]]])
    sliding = np.concatenate([rest_state.sliding, [False, False]])
    return tracker.make_state(phase="squeeze", squeeze_depth=0.0, lift_height=0.0, load=1.0, centers=centers,
                              nodes=nodes, owner=owner, disp=disp, sliding=sliding)


@dataclass(frozen=True)
class PassedAbove:
    """A squeeze state beyond ρ* whose lift test passed on the walk down from a passing first test: where a lift
    that fails resumes (Algorithm 1 step 6), without squeezing to it and testing it again.

    Attributes
    ----------
    state : the squeeze state at the next end of a sub-increment above the one before (ρ* or the previous
        ``PassedAbove``): the first at or past it + a sub-increment, where squeezing on from it tests next
    steps : the squeeze's events from the state before to this one, as (state, events) per step
    liftable : w(ρ) there, newtons (≥ mg)
    """

    state: ContactState
    steps: tuple[tuple[ContactState, list[ContactEvent]], ...]
    liftable: float


@dataclass
class SqueezeOutcome:
    """Result of :func:`squeeze`.

    Attributes
    ----------
    state : the last state (at lift-off if ``passed``)
    events : every event of the squeeze, in order
    passed : the lift test passed
    reason : why the squeeze stopped without passing (empty if passed)
    failed : the tracking found no quasi-static state (else, without passing, the maximum depth was reached)
    liftable : [(ρ, w(ρ))] after every increment
    lift_test_time : seconds spent in the lift test
    ahead : the tested and passing ends of sub-increments just above ρ*, deepest last (:class:`PassedAbove`;
        empty unless a first test passed and the walk down ended on the sub-increments' ends)
    """

    state: ContactState
    events: list[ContactEvent] = field(default_factory=list)
    passed: bool = False
    reason: str = ""
    liftable: list[tuple[float, float]] = field(default_factory=list)
    lift_test_time: float = 0.0
    failed: bool = False
    ahead: list[PassedAbove] = field(default_factory=list)


def next_passed(previous: SqueezeOutcome,
                on_event: Callable[[ContactState, list[ContactEvent]], None] | None = None) -> SqueezeOutcome | None:
    """The squeeze resumed after a lift from ``previous.state`` failed, where the walk down tested the next
    sub-increment's end already and it passed: that state as a passed squeeze (its events reported to
    ``on_event``), with the rest of ``previous.ahead``; None where there is none.  Squeezing from the lift's start
    again would compute the same state (the same increments from the same state) and the same test, to round-off.
    """
    if not previous.ahead:
        return None
    nxt = previous.ahead[0]
    out = SqueezeOutcome(nxt.state, passed=True, liftable=[(nxt.state.squeeze_depth, nxt.liftable)],
                         ahead=previous.ahead[1:])
    for st, events in nxt.steps:
        out.events.extend(events)
        if on_event is not None:
            on_event(st, events)
    return out


def squeeze(tracker: Tracker, state: ContactState, directions: tuple[np.ndarray, np.ndarray], ratio: float,
            lift_test: LiftTest, *, max_squeeze: float, step: float, divisions: int = 1, first_test: float = 0.0,
            on_event: Callable[[ContactState, list[ContactEvent]], None] | None = None) -> SqueezeOutcome:
    """Squeeze from ``state`` (at ρ = 0) until the lift test passes or ρ = ``max_squeeze``.

    Parameters
    ----------
    tracker : Tracker with the table
    state : the initial state (:func:`initial_state`), settled, or the lift-start state of a lift that
        failed (the squeeze resumes from there)
    directions : unit squeeze directions (d̂₁, d̂₂)
    ratio : s ≥ 0, ℱ₂ moves s ρ d̂₂
    lift_test : the liftable-weight tracker (§III-B)
    max_squeeze : ρ beyond which the pickup is abandoned (Algorithm 1 step 6)
    step : the increment in ρ between lift tests
    divisions : (``PickupOptions.step_divisions``) the increment in which the lift test first passes is squeezed
        again from its start in this many sub-increments, with the lift test after each, and the squeeze stops
        at the first that passes: ρ* is found to within ``step / divisions`` at the cost of a few more lift
        tests, as with that increment throughout wherever w(ρ) crosses mg once within the increment
        (default 1: Algorithm 1 as printed)
    first_test : (``PickupOptions.first_lift_test``) the depth of the first lift test, metres (default 0: a test
        after every increment, Algorithm 1 as printed), made at the first end of a sub-increment ``step /
        divisions`` at or past it: the squeeze reaches the increment below the one in which that falls in untested
        increments, then goes on in sub-increments (:func:`_tests_from`).  Should the first test pass, the ends
        below it are tested from the deepest down to the first that fails, and ρ* is the last that passed (a failing
        increment's end below the sub-increments brackets a whole increment, divided as below); should it fail,
        the next sub-increment is tested, and should that fail too, the squeeze goes on from it as without a
        first test.  ρ* is that of testing every sub-increment wherever w(ρ) crosses mg once; a first test at a
        good guess of ρ* costs two tests, which run side by side (the one below in a second thread,
        :class:`~fem_grasp.grasp.lift_test.SpeculativeTest`; ``EngineSettings.parallel_lift_tests``), and a walk
        further down goes on two ends at a time (each end's test beside the one above it, abandoned where that
        fails)
    on_event : called with the state after every event (of the increments kept: a passing increment squeezed
        again reports its events once, from the second pass)
    """
    d1, d2 = (np.asarray(d, float) / np.linalg.norm(d) for d in directions)
    velocities = np.stack([d1, ratio * d2])
    out = SqueezeOutcome(state)
    if not (isinstance(divisions, (int, np.integer)) and divisions >= 1):
        raise ValueError(f"divisions must be a whole number >= 1, got {divisions!r}")

    next_test = [state.squeeze_depth + step]  # the squeeze may resume from an earlier lift start (in_increments)
    # The events since the last lift test, reported once the increment is kept: an increment in which the test
    # first passes is squeezed again in sub-increments when ``divisions`` > 1, and its first pass is dropped.
    pending: list[tuple[ContactState, list[ContactEvent]]] = []
    tested = [state]  # where the increment in which the test passes begins: the last failing test, or the start
    again = [False]
    passing = [state]  # the end of the increment in which the test passes

    def emit(st: ContactState, events: list[ContactEvent]) -> None:
        out.events.extend(events)
        if on_event is not None:
            on_event(st, events)

    def keep() -> None:
        for st, events in pending:
            emit(st, events)
        pending.clear()

    def recorded(st: ContactState, w: float, seconds: float) -> bool:
        out.lift_test_time += seconds
        out.liftable.append((st.squeeze_depth, w))
        log.debug("ρ = %.6g m: liftable weight %.4g N (%d finger contacts)", st.squeeze_depth, w,
                  int((st.owner != TABLE).sum()))
        return lift_test.passed

    def test(st: ContactState) -> bool:
        t0 = time.perf_counter()
        w = lift_test.update(st)
        return recorded(st, w, time.perf_counter() - t0)

    def adopt(st: ContactState, outcome: SpeculativeOutcome) -> bool:
        """A :class:`SpeculativeTest`'s outcome at ``st``, recorded as :func:`test` records its own (its time: what
        the squeeze waited for it)."""
        lift_test.liftable = outcome.liftable
        lift_test.tests += outcome.weights
        return recorded(st, outcome.liftable, outcome.waited)

    def speculate(st: ContactState) -> SpeculativeTest:
        return SpeculativeTest(lift_test, st, threaded=tracker.settings.parallel_lift_tests and jit.ENABLED)

    def keep_to(rho: float) -> None:
        """Report the events up to depth ``rho``; those beyond stay pending."""
        upto = [(st, ev) for st, ev in pending if st.squeeze_depth <= rho * (1.0 + 1e-12)]
        del pending[:len(upto)]
        for st, ev in upto:
            emit(st, ev)

    def after_step(st: ContactState, events: list[ContactEvent]) -> bool:
        # The lift test runs once per increment of ``step`` in ρ (events split increments; the test is
        # not repeated after each of them).
        below_max = st.squeeze_depth < max_squeeze * (1.0 - 1e-9)
        if st.squeeze_depth < next_test[0] * (1.0 - 1e-9) and below_max:
            return False
        next_test[0] = st.squeeze_depth + step
        passed = test(st)
        passing[0] = st
        if passed and divisions > 1 and not again[0]:
            again[0] = True  # squeezed again from the failing test's state, below
            keep_to(tested[0].squeeze_depth)
            return True
        keep()
        if not passed:
            tested[0] = st
        return passed

    def record(st: ContactState, events: list[ContactEvent]) -> None:
        pending.append((st, events))

    last = [state]

    def after(st: ContactState, events: list[ContactEvent]) -> bool:
        last[0] = st
        return after_step(st, events)

    def in_increments(st: ContactState) -> tuple[ContactState, bool]:
        """On from ``st`` in increments ``step``, a lift test after each: (the last state, whether one passed)."""
        next_test[0] = st.squeeze_depth + step
        final, _, passed = run(tracker, st, velocities, stop=max_squeeze, step=step, param=Parameter.SQUEEZE_DEPTH,
                               phase="squeeze", after_step=after, on_event=record)
        return final, passed

    try:
        if first_test > state.squeeze_depth * (1.0 + 1e-12):
            final, outcome, below, above = _tests_from(tracker, state, velocities, max_squeeze=max_squeeze,
                                                       step=step, divisions=divisions, first_test=first_test,
                                                       test=test, record=record, last=last, speculate=speculate,
                                                       adopt=adopt)
            stopped = outcome == "passed"
            if outcome == "failed twice":  # on in increments from the second test, as without a first test
                keep()
                tested[0] = final
                final, stopped = in_increments(final)
            elif below is None:
                keep_to(final.squeeze_depth)
                out.ahead = _passed_above(above, pending, out.liftable)
                pending.clear()  # beyond ρ*: squeezed on to tests that were not needed, kept for a failed lift
            else:  # w(ρ) crossed mg in an untested increment: divided as in the path without a first test
                again[0] = True
                tested[0], passing[0] = below, final
                keep_to(below.squeeze_depth)
        else:
            final, stopped = in_increments(state)
        if again[0]:
            pending.clear()  # the first pass through the increment is not kept
            end = passing[0].squeeze_depth
            out.liftable[:] = [(r, w) for r, w in out.liftable if r <= tested[0].squeeze_depth * (1.0 + 1e-12)]
            final, stopped = _divide(tracker, tested[0], end, velocities, step / divisions, test, emit, last)
            if not stopped:  # w(ρ) crossed mg and fell back within the increment: squeeze on, undivided
                final, stopped = in_increments(final)
        keep()
    except TrackingError as exc:
        keep()
        out.state = last[0]
        out.failed = True
        out.reason = (f"squeeze failed: {exc}" if "ρ = " in str(exc) else
                      f"squeeze failed at ρ = {1e3 * last[0].squeeze_depth:.4g} mm: {exc}")
        return out
    # in order of ρ, and not beyond where the squeeze stopped (a first test that passed above a lower pass)
    out.liftable[:] = sorted((r, w) for r, w in out.liftable if r <= final.squeeze_depth * (1.0 + 1e-12))
    out.state = final
    out.passed = stopped
    if not stopped:
        out.reason = (f"the lift test did not pass by the maximum squeeze depth ρ = {1e3 * max_squeeze:.4g} mm "
                      f"(liftable weight {lift_test.liftable:.4g} N < weight {lift_test.weight:.4g} N)")
    return out


def _passed_above(above: list[ContactState], pending: list[tuple[ContactState, list[ContactEvent]]],
                  liftable: list[tuple[float, float]]) -> list[PassedAbove]:
    """The walk's passing states above ρ* (``above``, shallowest first) with the event steps that lead to each
    (``pending``, in order of ρ) and their w(ρ) (from ``liftable``)."""
    out: list[PassedAbove] = []
    steps = list(pending)
    for st in above:
        rho = st.squeeze_depth
        upto = [(s, ev) for s, ev in steps if s.squeeze_depth <= rho * (1.0 + 1e-12)]
        del steps[:len(upto)]
        w = [wl for r, wl in liftable if abs(r - rho) <= 1e-12 * rho]
        if not w:  # not recorded as tested: nothing to resume from beyond it
            break
        out.append(PassedAbove(st, tuple(upto), max(w)))
    return out


def _tests_from(tracker: Tracker, state: ContactState, velocities: np.ndarray, *, max_squeeze: float, step: float,
                divisions: int, first_test: float, test: Callable[[ContactState], bool],
                record: Callable[[ContactState, list[ContactEvent]], None],
                last: list, speculate: Callable[[ContactState], SpeculativeTest] | None = None,
                adopt: Callable[[ContactState, SpeculativeOutcome], bool] | None = None,
                ) -> tuple[ContactState, str, ContactState | None, list[ContactState]]:
    """The squeeze with its first lift test at ``first_test`` (see :func:`squeeze`): in increments ``step`` to the
    start of the increment below the one in which it falls, untested, then in sub-increments (``step / divisions``)
    to the first test and, should it fail, the next.

    ``speculate`` starts the lift test of the end below the first test's beside it (:class:`SpeculativeTest`), as
    soon as the squeeze reaches that end, and on the walk down each end's beside the one above it; ``adopt`` records
    its outcome in place of testing that end again, should the one above pass (both None: each end is tested after
    the one above it).

    Returns (state, outcome, bracket, above): outcome ``"passed"`` (the state is at ρ*, or, with a ``bracket``,
    w(ρ) crossed mg in an untested increment from the bracket's state to this one, still to be divided),
    ``"stopped"`` (at the maximum depth, not passed) or ``"failed twice"`` (the first two tests failed, the state
    is the second's: the squeeze goes on from it in increments); ``above``: where the walk down from a passing
    first test ended at ρ* without a bracket, the states it tested and passed one sub-increment after another
    above ρ*, shallowest first (else empty).
    """
    untested: list[ContactState] = []  # the ends of the increments below the sub-increments
    # The first test at the first end of a sub-increment (on the grid of sub-increments from the start) at or past
    # ``first_test``, the sub-increments from the end of the increment before it: the depths tested are those of
    # testing every sub-increment, whatever ``first_test`` is (the accuracy loop's levels compare answers on
    # grids of their own, not on one that a coarser answer chose).
    # The sub-increments begin an increment below the first test's, so that a walk down from a passing first test
    # meets a failing end on their grid where a finer level's ρ* lies a few sub-increments below the coarser's:
    # from the first test's own increment the orange's finest level met an untested increment's end, and squeezed
    # that increment again in sub-increments to test its four ends, the last for the second time.
    start, sub = state.squeeze_depth, step / divisions
    first_sub = math.ceil((first_test - start) / sub * (1.0 - 1e-9))
    c0 = min(start + max((first_sub - 1) // divisions - 1, 0) * step, max_squeeze)
    if c0 > start + 1e-9 * step:
        grid = [start + step]

        def after_increment(st: ContactState, events: list[ContactEvent]) -> bool:
            last[0] = st
            if st.squeeze_depth >= min(grid[0], c0) * (1.0 - 1e-9):
                grid[0] = st.squeeze_depth + step
                untested.append(st)
            return False

        state, _, _ = run(tracker, state, velocities, stop=c0, step=step, param=Parameter.SQUEEZE_DEPTH,
                          phase="squeeze", after_step=after_increment, on_event=record)

    subs: list[ContactState] = []  # the ends of the sub-increments, tested or not
    tests: list[bool] = []
    next_sub = [state.squeeze_depth + sub]
    ahead: list[SpeculativeOutcome] = []  # the outcome of the first end below the first test, tested beside it
    beside_it: list[SpeculativeTest] = []  # that test, while it runs

    def start_beside(at: ContactState) -> None:
        if speculate is not None and not beside_it:
            beside_it.append(speculate(at))

    def cancel_beside() -> None:
        while beside_it:
            beside_it.pop().cancel()

    def below_first() -> list[ContactState]:
        """The ends below the first test, from the deepest down: those a passing first test walks down."""
        return subs[:-1][::-1] + untested[::-1]

    def after_sub(st: ContactState, events: list[ContactEvent]) -> bool:
        last[0] = st
        rho = st.squeeze_depth
        at_max = rho >= max_squeeze * (1.0 - 1e-9)
        if rho < next_sub[0] * (1.0 - 1e-9) and not at_max:
            return False
        next_sub[0] = rho + sub
        subs.append(st)
        if not (tests or rho >= first_test * (1.0 - 1e-9) or at_max):
            if rho + sub >= first_test * (1.0 - 1e-9):
                start_beside(st)  # the next end is the first test's: this one is below it
            return False
        if tests or speculate is None or not below_first():
            tests.append(test(st))
            return tests[-1] or len(tests) == 2
        # The first test, and beside it the end below it, which a pass walks down to first (SpeculativeTest),
        # started while the squeeze went on to this end where it could be.
        if beside_it and beside_it[0].state is not below_first()[0]:
            cancel_beside()
        start_beside(below_first()[0])
        beside = beside_it.pop()
        try:
            tests.append(test(st))
        except BaseException:
            beside.cancel()
            raise
        if tests[-1]:
            ahead.append(beside.result())
        else:
            beside.cancel()
        return tests[-1]

    if untested and state.squeeze_depth >= max_squeeze * (1.0 - 1e-9):
        untested.pop()  # the maximum depth below the first test: the test there, below it the increments' ends
        final = state
        after_sub(state, [])
    else:
        if untested and state.squeeze_depth + sub >= first_test * (1.0 - 1e-9):
            start_beside(untested[-1])  # the first end is the first test's
        try:
            final, _, _ = run(tracker, state, velocities, stop=max_squeeze, step=sub, param=Parameter.SQUEEZE_DEPTH,
                              phase="squeeze", after_step=after_sub, on_event=record)
        finally:
            cancel_beside()  # the squeeze failed, or ended without a first test
    if not tests or not tests[-1]:
        on = len(tests) == 2 and final.squeeze_depth < max_squeeze * (1.0 - 1e-9)
        return final, ("failed twice" if on else "stopped"), None, []
    if len(tests) == 2:  # the first failed, the next passed
        return final, "passed", None, []
    # The first test passed: the ends below it from the deepest down to the first that fails, ρ* the last that
    # passed; where the two are further apart than a sub-increment (increments' ends), their increment is divided.
    walked = [final]  # the passing ends, deepest first
    # The ends that each follow the one before as squeezing on from it would reach them (the first end at or past
    # it + a sub-increment): the sub-increments' from the start of theirs, the increments' too when undivided.
    chain = {id(st) for st in (untested if divisions == 1 else untested[-1:]) + subs}

    def above() -> list[ContactState]:
        """The passing ends above ρ* (walked[-1]), shallowest first, where ρ* is on the chain of ends."""
        return walked[-2::-1] if id(walked[-1]) in chain else []

    # Two ends at a time: while one is tested, the end below it is tested beside it (the walk needs it only if
    # this one passes, and is abandoned otherwise), as the first test's end below was.
    ends = below_first()
    try:
        for n, st in enumerate(ends):
            if n == 0 and ahead and adopt is not None:
                held = adopt(st, ahead[0])
            elif beside_it and beside_it[0].state is st and adopt is not None:
                held = adopt(st, beside_it.pop().result())
            else:
                if n + 1 < len(ends):
                    start_beside(ends[n + 1])
                held = test(st)
            if not held:
                if final.squeeze_depth - st.squeeze_depth > 1.5 * sub:
                    return final, "passed", st, []
                return final, "passed", None, above()
            final = st
            walked.append(st)
    finally:
        cancel_beside()  # the walk ended above the end tested beside it
    return final, "passed", None, above()


def _divide(tracker: Tracker, start: ContactState, end: float, velocities: np.ndarray, sub: float,
            test: Callable[[ContactState], bool], emit: Callable[[ContactState, list[ContactEvent]], None],
            last: list) -> tuple[ContactState, bool]:
    """The passing increment (``start`` to ρ = ``end``) squeezed again in sub-increments ``sub`` with the lift test
    after each, to the first that passes (the increment's own end at the latest, tested again); its events go to
    ``emit``."""
    next_test = [start.squeeze_depth + sub]

    def after(st: ContactState, events: list[ContactEvent]) -> bool:
        last[0] = st
        rho = st.squeeze_depth
        if rho < next_test[0] * (1.0 - 1e-9) and rho < end * (1.0 - 1e-9):
            return False
        next_test[0] = rho + sub
        return test(st)

    last[0] = start
    final, _, stopped = run(tracker, start, velocities, stop=end, step=sub, param=Parameter.SQUEEZE_DEPTH,
                            phase="squeeze", after_step=after, on_event=emit)
    return final, stopped

