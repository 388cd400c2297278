"""The lift test: liftable weight w(ρ) tracked during the squeeze (paper §III-B, Algorithm 1 step 4).

"Imagine we hypothetically increase the weight of the object from zero.
Beyond certain value w, one finger will slide on the object."  The test
removes the table from the current squeeze configuration — only the finger
contacts 𝕀 ∪ 𝕁 hold the object, at their current contact displacements —
and asks whether the fingers hold a hypothetical weight w.

Hanging at a trial weight (:func:`hang`)
----------------------------------------
The finger configuration is held at the trial weight (gravity load factor
λ = w / mg) and settled in place by a return mapping
(:meth:`~fem_grasp.contact.tracking.Tracker.implicit_step` with the fingers still,
:func:`~fem_grasp.contact.relaxation.relax_contacts`): every contact ends sticking,
sliding onto its cone along its fingertip's great circle (eqs. 7–8), or
released (B); nodes that come to penetrate a fingertip are added (A).
The weight **is held** when a static state is found and each finger keeps at
least one sticking contact; it is **not held** when every contact of one
finger slides (the object slides on that finger), when no static state
exists (gross slip), or when too few contacts remain to fix the body
(Theorem 3).  A load step with no static state is halved, up to
``load_halvings`` times (:class:`~fem_grasp.settings.EngineSettings`, three by
default: steps down to h/8), before the weight counts as not held: a
quasi-static loading path may pass where one jump does not, and the halvings
resolve the path near the weight a finger lets go.  Six (h/64) took twice the
time on the tomato, with w(ρ) higher by 2–3 steps h at 3 of its 23 increments
(the next increment caught up) and the same lift-off depth and forces; with
none, 6 of the tomato's 64 search placements lift one or two squeeze
increments later, 4 of them by more than one (the coarser path lets go
sooner; ``python -m bench.tracker --against settings.load_halvings=0
--search tomato``).

Incremental tracking (:class:`LiftTest`)
----------------------------------------
w(0) = 0.  "Imagine we hypothetically increase the weight of the object from
zero": after each squeeze increment l the hanging configuration at zero
weight is loaded with h, 2h, 3h, …, each weight settled from the state held
at the one before, until a weight kh is not held or mg is reached, and
w(ρ_l) = (k−1)h.  Coulomb friction is path dependent, so the load path is
part of the test's definition: loading in steps of h from zero is the
quasi-static path, and its limit h → 0 is the continuous one (the
convergence study halves h).  The paper instead starts at w(ρ_{l−1}) + h,
which is the same path only if the weights below w(ρ_{l−1}) are applied on
the way; a single jump from zero weight to w(ρ_{l−1}) + h missed weights the
ramp holds (the 893-vertex football held mg at ρ = 12.1 mm by the ramp but
never passed the jump's test, a verdict flip of the convergence study).  The
paper assumes w grows with ρ; here w(ρ_l) may also fall (the contact
configuration changed).  The test passes once w(ρ_l) ≥ mg.  The step h
defaults to mg/20.  Larger steps where the previous increment held
(four steps h at once below w(ρ_{l−1})) cut the tomato's graded lift test
by a third with the same w(ρ), but on its 64 search placements moved ρ*
of five by 1.3–2.3 increments (later: the coarser path lets go sooner),
so the ramp keeps steps of h throughout.
"""

from __future__ import annotations

import contextlib
import logging
import threading
import time
from dataclasses import dataclass
from typing import Callable, NamedTuple

import numpy as np

from ..contact.obstacles import FINGER1, FINGER2, TABLE
from ..contact.tracking import ContactState, Parameter, Tracker
from ..elastic.response import check_contact_set
from ..errors import CollinearContactError, TrackingError
from ..threads import side_by_side

__all__ = ["HangResult", "LiftTest", "LiftTestCancelled", "SpeculativeOutcome", "SpeculativeTest", "hang",
           "hanging_state"]

log = logging.getLogger(__name__)

#: Default lift-test step h as a fraction of the object's weight.
DEFAULT_STEP_FRACTION = 0.05
#: w ≥ mg up to round-off passes (k·h with h = mg/20 lands on mg only to round-off).
PASS_FRACTION = 1.0 - 1e-12


@dataclass(frozen=True)
class HangResult:
    """Outcome of :func:`hang` at one trial weight.

    Attributes
    ----------
    weight : trial weight w, newtons
    held : whether the fingers hold it
    reason : why not (empty when held)
    state : the settled finger-only configuration (None when it could not be computed)
    """

    weight: float
    held: bool
    reason: str
    state: ContactState | None


def hanging_state(tracker: Tracker, state: ContactState) -> HangResult:
    """The finger contacts of ``state`` without the table, at zero weight, settled (see module notes)."""
    if tracker.table is not None:
        raise ValueError("the lift test needs a tracker without a table")
    fingers = state.owner != TABLE
    nodes = state.nodes[fingers]
    if fingers.sum() < 3:
        return HangResult(0.0, False, "fewer than three finger contacts cannot fix the body", None)
    try:
        check_contact_set(tracker.points, nodes)
    except CollinearContactError:
        return HangResult(0.0, False, "the finger contacts are collinear: the body could turn about them", None)
    try:
        start = tracker.make_state(phase="lift test", squeeze_depth=state.squeeze_depth,
                                   lift_height=state.lift_height, load=0.0, centers=state.centers, nodes=nodes,
                                   owner=state.owner[fingers], disp=state.disp[fingers],
                                   sliding=state.sliding[fingers], slip=state.slip[fingers])
        settled, _ = tracker.implicit_step(start, 0.0, np.zeros((2, 3)), param=Parameter.LIFT_HEIGHT, phase="lift test")
    except TrackingError as exc:
        return HangResult(0.0, False, f"the fingers cannot hold it: {exc}", None)
    return _verdict(0.0, settled)


def hang(tracker: Tracker, start: ContactState, weight: float, *, max_depth: int | None = None) -> HangResult:
    """Raise the weight of a hanging configuration ``start`` to ``weight`` and settle; held or not.

    ``start`` is a settled finger-only configuration (:func:`hanging_state`
    or an earlier :func:`hang`).  The weight is applied at once and the
    configuration settled; if no static state is found for that jump, the
    load step is halved (up to ``max_depth`` times, default the tracker's ``settings.load_halvings``) and
    applied in two stages, each of which must be held.
    """
    if max_depth is None:
        max_depth = tracker.settings.load_halvings
    load = weight / tracker.body.weight
    try:
        begin = tracker.make_state(phase="lift test", squeeze_depth=start.squeeze_depth,
                                   lift_height=start.lift_height, load=load, centers=start.centers,
                                   nodes=start.nodes, owner=start.owner, disp=start.disp,
                                   sliding=start.sliding, slip=start.slip)
        settled, _ = tracker.implicit_step(begin, 0.0, np.zeros((2, 3)), param=Parameter.LIFT_HEIGHT, phase="lift test")
    except TrackingError as exc:
        if max_depth <= 0:
            return HangResult(weight, False, f"the fingers cannot hold it: {exc}", None)
        mid = hang(tracker, start, 0.5 * (start.load * tracker.body.weight + weight), max_depth=max_depth - 1)
        if not mid.held:
            return mid
        return hang(tracker, mid.state, weight, max_depth=max_depth - 1)
    return _verdict(weight, settled)


def _verdict(weight: float, settled: ContactState) -> HangResult:
    for f in (FINGER1, FINGER2):
        on = settled.owner == f
        if not on.any():
            return HangResult(weight, False, f"finger {f + 1} lost contact", settled)
        if settled.sliding[on].all():
            return HangResult(weight, False, f"every contact of finger {f + 1} slides", settled)
    return HangResult(weight, True, "", settled)


@dataclass
class LiftTest:
    """Incremental liftable-weight tracker of §III-B (module notes).

    Parameters
    ----------
    tracker : Tracker without a table
    weight : the object's real weight mg, newtons
    step : h, newtons (default mg/20)
    """

    tracker: Tracker
    weight: float
    step: float | None = None
    liftable: float = 0.0
    tests: int = 0

    def __post_init__(self) -> None:
        if self.step is None:
            self.step = DEFAULT_STEP_FRACTION * self.weight
        if not self.step > 0:
            raise ValueError(f"the lift-test step must be positive, got {self.step!r}")

    def update(self, state: ContactState, *, stop: Callable[[], bool] | None = None) -> float:
        """w(ρ_l) from the squeeze state at ρ_l; returns it.

        The finger configuration is hung at zero weight, then loaded with h, 2h, … (module notes), each
        weight from the configuration held at the one before; the ramp stops at the first weight not held or
        at mg.  ``stop``: asked before every weight; when it says True the test is abandoned
        (:class:`LiftTestCancelled`, ``liftable`` unchanged).
        """
        self.tests += 1
        base = hanging_state(self.tracker, state)
        if not base.held:
            self.liftable = 0.0
            return 0.0
        held, k, st = 0.0, 1, base.state
        while held < self.weight * PASS_FRACTION:
            if stop is not None and stop():
                raise LiftTestCancelled(f"the lift test was abandoned at {held:.4g} N")
            self.tests += 1
            res = hang(self.tracker, st, k * self.step)
            if not res.held:
                break
            held, st, k = k * self.step, res.state, k + 1
        self.liftable = held
        return held

    @property
    def passed(self) -> bool:
        return self.liftable >= self.weight * PASS_FRACTION


class SpeculativeOutcome(NamedTuple):
    """What :meth:`SpeculativeTest.result` returns: w(ρ) and the verdict of the state's lift test, the weights it
    tried (:attr:`LiftTest.tests`) and the seconds the caller waited for it."""

    liftable: float
    passed: bool
    weights: int
    waited: float


class LiftTestCancelled(Exception):
    """A lift test abandoned before its verdict (the ``stop`` of :meth:`LiftTest.update`)."""


class SpeculativeTest:
    """The lift test of another squeeze state, made beside the squeeze's own test (on the other core).

    A squeeze with a first lift test at a given depth (``PickupOptions.first_lift_test``: the accuracy loop's finer
    levels, at the coarser level's ρ*) tests the end of the sub-increment below it next whenever that first test
    passes, and that test usually fails (ρ* confirmed): the two tests are independent (each hangs its own squeeze
    state), so this one starts with the first, in a helper thread, and is abandoned if the first fails; a walk
    further down tests each end beside the one above it the same way.  It runs on a branch of the lift test's tracker
    (:meth:`Tracker.branch`: caches of its own) whether or not a thread runs it (``threaded=False``: at
    :meth:`result`, in the calling thread), so both ways give the same numbers; while it lasts BLAS keeps one thread
    (:func:`side_by_side`).  The compiled kernels release the GIL; a sparse solve for new compliance columns waits
    for the other thread's.
    """

    def __init__(self, lift_test: LiftTest, state: ContactState, *, threaded: bool) -> None:
        self.state = state
        self._test = LiftTest(lift_test.tracker.branch(), lift_test.weight, lift_test.step)
        self._stop = threading.Event()
        self._outcome: tuple[float, bool, int] | BaseException | None = None  # (w, passed, weights tried)
        self._section = contextlib.ExitStack()
        self._section.enter_context(side_by_side())
        self._thread = None
        if threaded:
            self._thread = threading.Thread(target=self._run, name="fem_grasp-lift-test", daemon=True)
            self._thread.start()

    def _run(self) -> None:
        try:
            w = self._test.update(self.state, stop=self._stop.is_set)
            self._outcome = (w, self._test.passed, self._test.tests)
        except BaseException as exc:  # re-raised by result() in the caller's thread
            self._outcome = exc

    def result(self) -> SpeculativeOutcome:
        """The state's lift test, once it has ended (or made here: then ``waited`` is its whole time)."""
        t0 = time.perf_counter()
        try:
            if self._thread is None:
                self._run()
            else:
                try:
                    self._thread.join()
                except BaseException:  # interrupted while waiting: the helper stops at its next weight
                    self._stop.set()
                    raise
        finally:
            self._section.close()
        if isinstance(self._outcome, BaseException):
            raise self._outcome
        assert self._outcome is not None
        return SpeculativeOutcome(*self._outcome, time.perf_counter() - t0)

    def cancel(self) -> None:
        """Abandon the test (the helper stops before its next weight)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
        self._section.close()
