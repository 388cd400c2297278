"""The grasp's options as one immutable record (fem_grasp.grasp.options.PickupOptions)."""

import dataclasses

import numpy as np
import pytest

from fem_grasp import PickupOptions, Scene, pickup, rest
from fem_grasp.contact.obstacles import DEFAULT_RADIUS
from fem_grasp.errors import DirectionError, SceneError
from fem_grasp.grasp.evaluation import SearchSetup
from fem_grasp.grasp.options import DEFAULT_FRICTION, DEFAULT_OPTIONS
from fem_grasp.grasp.placement import DEFAULT_PLACEMENT_RULE, PAPER_SQUEEZE_DIRECTIONS
from fem_grasp.io.scene import SCENE_DIR
from fem_grasp.io.scene_file import read_toml
from tests.helpers import RADIUS, assert_same_pickup, face_centres, pickup_box


def test_the_options_are_immutable_and_a_change_makes_a_new_record():
    options = PickupOptions(mu_finger=0.4, finger_radius=0.015)
    with pytest.raises(dataclasses.FrozenInstanceError):
        options.mu_finger = 0.3
    wider = options.replace(finger_radius=0.02, lift=False)
    assert (wider.mu_finger, wider.finger_radius, wider.lift) == (0.4, 0.02, False)
    assert (options.finger_radius, options.lift) == (0.015, True)  # the original unchanged
    assert PickupOptions.from_overrides({"lift": False}, base=options) == options.replace(lift=False)
    assert options.changed() == {"mu_finger": 0.4, "finger_radius": 0.015}
    assert PickupOptions() == DEFAULT_OPTIONS and hash(PickupOptions()) == hash(DEFAULT_OPTIONS)
    # contact nodes given as an array are held as a tuple: the record stays hashable and cannot be changed behind it
    nodes = np.array([3, 7])
    held = PickupOptions(contacts=nodes)
    nodes[0] = 5
    assert held.contacts == (3, 7) and hash(held) == hash(PickupOptions(contacts=(3, 7)))


def test_the_defaults_are_pickups_documented_ones():
    """μ_𝒫 follows μ_ℱ unless given; R, the paper's directions, s = 1, the paper scenes' placement rule, four lift
    attempts; the lengths, h and the increment are computed from the object (None)."""
    d = PickupOptions()
    assert (d.mu_finger, d.mu_table, d.table_friction) == (DEFAULT_FRICTION, None, DEFAULT_FRICTION)
    assert PickupOptions(mu_finger=0.3).table_friction == 0.3 and PickupOptions(mu_table=0.0).table_friction == 0.0
    assert d.finger_radius == DEFAULT_RADIUS and d.ratio == 1.0
    np.testing.assert_array_equal(np.array(d.directions), np.array(PAPER_SQUEEZE_DIRECTIONS))
    assert (d.placement_rule, d.max_lift_attempts, d.lift, d.backend) == (DEFAULT_PLACEMENT_RULE, 4, True, "sparse")
    assert (d.contacts, d.max_squeeze, d.step, d.lift_test_step, d.max_lift, d.accuracy, d.geometry) == (None,) * 7
    assert PickupOptions(mu_finger=None).mu_finger == DEFAULT_FRICTION  # None: the default, as pickup() took it


def test_an_unknown_option_is_refused_naming_it_and_the_nearest_known_one():
    with pytest.raises(ValueError, match=r"unknown pickup option 'mu_fingr' \(did you mean 'mu_finger'\?\)"):
        PickupOptions.from_overrides({"mu_fingr": 0.3})
    with pytest.raises(ValueError, match=r"unknown pickup options 'finger_radus' \(did you mean 'finger_radius'\?\), "
                                         r"'tol_locate'; the options are mu_finger, "):
        DEFAULT_OPTIONS.replace(finger_radus=0.02, tol_locate=1e-12)
    # pickup() refuses a misspelt keyword the same way, before anything is solved
    with pytest.raises(ValueError, match=r"'max_squeze' \(did you mean 'max_squeeze'\?\)"):
        pickup(pickup_box(), max_squeze=0.01)


@pytest.mark.parametrize("change, error, words", [
    ({"mu_finger": 0.0}, SceneError, "must be > 0"),
    ({"mu_table": -0.1}, SceneError, "mu_table must be a finite friction coefficient"),
    ({"finger_radius": -1.0}, SceneError, "radius"),
    ({"ratio": float("nan")}, SceneError, "squeeze ratio"),
    ({"directions": ([0, 1, 0.2], [0, -1, 0])}, DirectionError, "upward"),
    ({"directions": ([0, 1, 0],)}, DirectionError, "two squeeze directions"),
    ({"step": 0.0}, SceneError, "squeeze increment"),
    ({"lift_test_step": -0.01}, SceneError, "lift-test step"),
    ({"max_lift_attempts": 0}, ValueError, "max_lift_attempts"),
    ({"placement_rule": "highest"}, SceneError, "placement rule"),
    ({"backend": "dense"}, ValueError, "backend"),
    ({"accuracy": 1.5}, ValueError, "accuracy"),
])
def test_a_value_out_of_range_is_refused_when_the_record_is_built(change, error, words):
    with pytest.raises(error, match=words):
        PickupOptions(**change)
    with pytest.raises(error, match=words):
        DEFAULT_OPTIONS.replace(**change)


@pytest.fixture(scope="module")
def box_at_rest():
    body = pickup_box()
    return body, rest(body, 0.5)


def test_a_record_and_the_same_options_as_keywords_give_the_same_pickup(box_at_rest):
    body, rs = box_at_rest
    contacts = face_centres(rs)
    by_name = pickup(body, mu_finger=0.5, mu_table=0.5, finger_radius=RADIUS, contacts=contacts, rest_state=rs)
    options = PickupOptions(mu_finger=0.5, mu_table=0.5, finger_radius=RADIUS, contacts=contacts)
    by_record = pickup(body, options, rest_state=rs)
    assert by_name.success and by_name.step > 0
    assert_same_pickup(by_name, by_record)
    # a keyword overrides the record's field
    mixed = pickup(body, options.replace(finger_radius=0.5 * RADIUS), finger_radius=RADIUS, rest_state=rs)
    assert_same_pickup(by_name, mixed)
    # and a record that differs gives another answer: the record is what the run reads
    stopped = pickup(body, options.replace(lift=False), rest_state=rs)
    assert stopped.outcome == "lift not run" and not stopped.success


def test_a_search_setup_carries_the_shared_options_and_takes_the_table_friction_from_the_rest(box_at_rest):
    _, rs = box_at_rest
    given = PickupOptions(mu_finger=0.4, mu_table=0.9, finger_radius=RADIUS, contacts=(1, 2), lift=False,
                          placement_rule="least-force")
    setup = SearchSetup.from_rest(rs, options=given, step=1e-3)
    assert (setup.options.mu_finger, setup.options.lift, setup.options.step) == (0.4, False, 1e-3)
    assert setup.options.mu_table == rs.mu_table == 0.5
    assert setup.options.contacts is None  # each candidate's own
    # the keywords and the record give one setup, with one key
    assert SearchSetup.from_rest(rs, mu_finger=0.4, finger_radius=RADIUS, lift=False, step=1e-3).key == setup.key


def test_a_shipped_scene_hands_its_friction_and_fingertip_to_the_pickup_options():
    """The soapy ball has μ_ℱ ≠ μ_𝒫: both, and the radius, reach PickupOptions as the file states them."""
    raw = read_toml(SCENE_DIR / "slippery_ball.toml")
    scene = Scene.load("slippery_ball")
    options = scene.pickup_options()
    assert isinstance(options, PickupOptions)
    assert (options.mu_finger, options.mu_table) == (raw["friction"]["finger"], raw["friction"]["table"])
    assert options.finger_radius == pytest.approx(0.01) and options.finger_radius == scene.finger_radius
    assert options.placement_rule == scene.placement_rule and options.accuracy is None
    # the keyword form names the same values, and a changed scene changes its options
    kw = scene.pickup_kwargs()
    assert PickupOptions.from_overrides(kw) == options
    wetter = scene.with_(mu_finger=0.05, finger_radius="8 mm").pickup_options()
    assert (wetter.mu_finger, wetter.mu_table, wetter.finger_radius) == (0.05, options.mu_table, 0.008)
