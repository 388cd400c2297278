"""The engine's settings (fem_grasp.settings.EngineSettings): one immutable record the trackers read, not module globals."""

import dataclasses
import importlib

import pytest

from fem_grasp.contact.tracking import Tracker
from fem_grasp.settings import DEFAULT_SETTINGS, EngineSettings
from tests.helpers import assert_same_pickup


def test_the_settings_are_immutable_and_derived_by_replacing_fields():
    with pytest.raises(dataclasses.FrozenInstanceError):
        DEFAULT_SETTINGS.max_slip = 1.0
    strict = DEFAULT_SETTINGS.replace(tol_locate=1e-12, implicit_contacts=0)
    assert (strict.tol_locate, strict.implicit_contacts) == (1e-12, 0)
    assert strict.changed() == {"tol_locate": 1e-12, "implicit_contacts": 0}
    assert DEFAULT_SETTINGS.tol_locate == 1e-10 and DEFAULT_SETTINGS.changed() == {}  # the defaults unchanged
    assert EngineSettings.from_overrides({"max_slip": 0.2}, base=strict).changed() == {
        "tol_locate": 1e-12, "implicit_contacts": 0, "max_slip": 0.2}
    assert EngineSettings() == DEFAULT_SETTINGS and hash(EngineSettings()) == hash(DEFAULT_SETTINGS)


def test_an_unknown_setting_is_refused_naming_it_and_the_nearest_known_one():
    with pytest.raises(ValueError, match=r"unknown engine setting 'implicit_contact' \(did you mean "
                                         r"'implicit_contacts'\?\)"):
        EngineSettings.from_overrides({"implicit_contact": 0})
    with pytest.raises(ValueError, match=r"unknown engine settings 'MAX_SLIP' \(did you mean 'max_slip'\?\), "
                                         r"'no_such_knob'; the settings are "):
        DEFAULT_SETTINGS.replace(MAX_SLIP=0.2, no_such_knob=1)


@pytest.mark.parametrize("field, value", [("implicit_contacts", -1), ("implicit_contacts", 2.5),
                                          ("tol_locate", "1e-10"), ("tol_locate", float("nan")),
                                          ("compiled_trials", 1), ("neighbour_updates", None)])
def test_a_setting_of_the_wrong_kind_is_refused_naming_the_field(field, value):
    with pytest.raises(ValueError, match=f"engine setting {field} must be"):
        EngineSettings.from_overrides({field: value})


def test_the_tracking_modules_keep_no_knobs_of_their_own():
    """The knobs that were module globals read at run time are gone: a tracker reads ``self.settings`` only.
    tracking keeps three documented aliases of the defaults (setting them changes nothing)."""
    gone = ("TOL_PENETRATION", "TOL_TENSILE", "TOL_CONE", "TOL_FORCE_FLOOR", "TOL_RATE", "STICK_HYSTERESIS",
            "INCREMENT_HALVINGS", "MIN_STEP", "MAX_SLIP", "IMPLICIT_CONTACTS", "MAX_SETTLE_TOGGLES", "CHATTER_TOGGLES",
            "CHATTER_WINDOW", "TURNING_PROBE", "TURNING_PROBE_REL", "DIRECTION_FLOOR", "RESPONSE_CACHE",
            "RESPONSE_CACHE_BYTES", "ZERO_FIELD_CACHE", "LATEST_FIELDS", "PREFETCH_NODES")
    for name in ("tracking", "event_location", "implicit_step"):
        module = importlib.import_module(f"fem_grasp.contact.{name}")
        assert not [g for g in gone if hasattr(module, g)], name
    gone_too = {"contact.relaxation": ("DRIFT_SWEEPS", "DRIFT_SLIP", "DRIFT_DECAY", "GROWTH_SWEEPS", "STUCK_SWEEPS",
                                       "STALL_SWEEPS", "POLISH_HALVINGS", "POLISH_ITERATIONS", "CHORD_CONTRACTION",
                                       "COMPILED_POLISH"),
                "grasp.lift_test": ("LOAD_HALVINGS",)}
    for name, names in gone_too.items():
        module = importlib.import_module(f"fem_grasp.{name}")
        assert not [g for g in names if hasattr(module, g)], name
    tracking = importlib.import_module("fem_grasp.contact.tracking")
    assert (tracking.TOL_LOCATE, tracking.CRAWL_TOGGLES) == (DEFAULT_SETTINGS.tol_locate, DEFAULT_SETTINGS.crawl_toggles)


def test_a_tracker_reads_the_settings_it_is_given(monkeypatch):
    from fem_grasp.contact import tracking
    from fem_grasp.grasp.rest import rest
    from tests.helpers import RADIUS, pickup_box

    rs = rest(pickup_box(), 0.5)
    monkeypatch.setattr(tracking, "CRAWL_TOGGLES", 1)  # an alias: nothing reads it
    default = Tracker(rs.body, radius=RADIUS, mu_finger=0.5, mu_table=0.5, table=rs.table)
    assert default.settings is DEFAULT_SETTINGS
    mine = EngineSettings(compiled_trials=False)
    tracker = Tracker(rs.body, radius=RADIUS, mu_finger=0.5, mu_table=0.5, table=rs.table, settings=mine)
    assert tracker.settings is mine and not tracker.compiled
    with pytest.raises(TypeError, match="settings must be an EngineSettings"):
        Tracker(rs.body, radius=RADIUS, mu_finger=0.5, mu_table=0.5, table=rs.table, settings={"max_slip": 0.2})


def test_every_increment_implicit_gives_the_same_answer_on_the_quick_tomato(monkeypatch):
    """implicit_contacts=0 takes every increment as a return mapping (events located only to the increment):
    the quick tomato's answer is the event tracking's, to the answer-level tolerance."""
    from fem_grasp.grasp.pickup import pickup
    from fem_grasp.io.scene import load_scene, resolve_scene

    scene = load_scene(resolve_scene("tomato"), quick=True)
    body, kw = scene.body(), scene.pickup_kwargs()
    default = pickup(body, **kw)
    calls = []
    original = Tracker.implicit_step
    monkeypatch.setattr(Tracker, "implicit_step", lambda self, *a, **k: calls.append(1) or original(self, *a, **k))
    implicit = pickup(body, settings=EngineSettings(implicit_contacts=0), **kw)
    assert len(calls) >= implicit.squeeze_depth / implicit.step - 1  # every squeeze increment was implicit
    assert_same_pickup(default, implicit)


def test_a_tracker_without_neighbour_updates_factorises_every_contact_set_afresh(monkeypatch):
    """neighbour_updates=False: no response is derived from a cached neighbour's; the responses are the same to
    round-off."""
    import numpy as np

    from fem_grasp.elastic import response
    from fem_grasp.grasp.rest import rest
    from tests.helpers import RADIUS, pickup_box

    asked = []
    neighbour = response.ContactResponse.neighbour
    monkeypatch.setattr(response.ContactResponse, "neighbour",
                        lambda self, nodes: asked.append(1) or neighbour(self, nodes))
    rs = rest(pickup_box(), 0.5)
    others = np.setdiff1d(rs.body.mesh.surface_nodes, rs.contact_nodes)
    sets = [np.concatenate([rs.contact_nodes, others[:i]]) for i in range(3)]
    out = {}
    for updates in (True, False):
        tracker = Tracker(rs.body, radius=RADIUS, mu_finger=0.5, mu_table=0.5, table=rs.table,
                          settings=EngineSettings(neighbour_updates=updates))
        asked.clear()
        out[updates] = [tracker.response(k).reduced_stiffness for k in sets]
        assert bool(asked) == updates
    for a, b in zip(out[True], out[False]):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-10 * np.abs(b).max())


def test_columns_solved_ahead_give_the_same_pickup(monkeypatch):
    """solve_ahead: the squeeze's and the lift's tracker queue the next likely contacts' columns for a background
    thread (with CHOLMOD called directly); the tomato's answer is the same as without, to the answer-level
    tolerance (the columns are solved in other batches), and the section leaves no columns being solved."""
    from fem_grasp.elastic import compliance
    from fem_grasp.grasp.pickup import pickup
    from fem_grasp.io.scene import load_scene, resolve_scene

    scene = load_scene(resolve_scene("tomato"))
    body, kw = scene.body(), scene.pickup_kwargs()
    if not getattr(body.compliance._solve, "releases_gil", False):
        pytest.skip("no CHOLMOD library whose solves release the GIL")
    queued = []
    original = compliance.Compliance.solve_ahead

    def counted(self, likely, count):
        before = len(self._ahead)
        original(self, likely, count)
        queued.append(len(self._ahead) - before)

    monkeypatch.setattr(compliance.Compliance, "solve_ahead", counted)
    from fem_grasp.contact import tracking

    monkeypatch.setattr(compliance, "AHEAD_MIN_NODES", 1)  # a coarse mesh's fingertips touch a few nodes at a time
    monkeypatch.setattr(tracking, "AHEAD_MIN_VERTICES", 0)  # and a coarse mesh queues nothing by default
    implicit = EngineSettings(implicit_contacts=0)  # a return mapping per increment: new contacts at every one
    ahead = pickup(body, settings=implicit, **kw)
    assert sum(queued) > 0
    queued.clear()
    plain = pickup(body, settings=implicit.replace(solve_ahead=False), **kw)
    assert sum(queued) == 0
    assert_same_pickup(ahead, plain)
    posed = ahead.body.compliance
    assert not posed._ahead_on and all(batch.result.done() for batch in posed._ahead.values())
