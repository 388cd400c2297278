"""Changing a scene's settings (:meth:`Scene.with_ <fem_grasp.io.scene.Scene.with_>`, :func:`with_overrides`),
each value checked as in a scene file, and the error a scene states for its own settings dropped when a change
moves the answer.
"""

from __future__ import annotations

import logging
from dataclasses import replace
from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import SceneError
from ..grasp.options import REFINEMENTS
from ..grasp.placement import PLACEMENT_RULES
from .quantities import SI_UNITS, UNITS, check_quantity, parse_accuracy, parse_quantity
from .scene_file import close_keys

__all__ = ["CHANGES", "with_changes", "with_overrides"]

if TYPE_CHECKING:
    from .scene import Scene

log = logging.getLogger(__name__)


#: Scene fields whose change leaves the answer of a single run as it was (the backends agree to round-off; the
#: accuracy target and the lift's extent do not change ρ* or the forces at lift-off): a change of any other field
#: makes the scene's stated error (``[solver] expected_error``, measured by the convergence study at the scene's
#: own settings) no longer the run's.
_ERROR_NEUTRAL = frozenset({"backend", "accuracy", "lift", "max_lift", "max_finger_contacts", "max_seconds",
                            "refinement"})


def _without_borrowed_error(scene: Scene, new: Scene, fields: Any) -> Scene:
    """``new`` without the stated error of ``scene`` when one of ``fields`` changes the answer (a changed modulus,
    friction, weight, mesh, … gets no error measured at other settings)."""
    changed = [f for f in fields if f not in _ERROR_NEUTRAL and getattr(new, f) != getattr(scene, f)]
    if changed and new.expected_error is not None:
        log.info("the scene's stated error (%g) was measured at its own settings, not with %s changed: the run "
                 "states none", new.expected_error, ", ".join(changed))
        return replace(new, expected_error=None)
    return new


def with_overrides(scene: Scene, **changes: Any) -> Scene:
    """A copy of ``scene`` with some fields replaced (e.g. ``backend="spectral"``); a change that moves the answer
    drops the error the scene states for its own settings."""
    given = {k: v for k, v in changes.items() if v is not None}
    return _without_borrowed_error(scene, replace(scene, **given), given)


#: The keys of :meth:`Scene.with_`: the field each sets and the kind of its value.
CHANGES: dict[str, tuple[str, str]] = {
    "young": ("young", "pressure"), "poisson": ("poisson", "float"), "weight": ("weight", "force"),
    "mass": ("weight", "mass"), "density": ("density", "density"), "gravity": ("gravity", "acceleration"),
    "mu": ("mu", "friction"), "mu_finger": ("mu_finger", "friction"), "mu_table": ("mu_table", "friction"),
    "finger_radius": ("finger_radius", "length"), "contacts": ("contacts", "contacts"),
    "placement_rule": ("placement_rule", "rule"), "directions": ("directions", "directions"),
    "ratio": ("ratio", "ratio"), "backend": ("backend", "backend"), "max_squeeze": ("max_squeeze", "length"),
    "step": ("step", "length"), "lift_test_step": ("lift_test_step", "force"), "max_lift": ("max_lift", "length"),
    "lift": ("lift", "bool"), "vertices": ("vertices", "int"), "accuracy": ("accuracy", "accuracy"),
    "max_finger_contacts": ("max_finger_contacts", "count"), "step_divisions": ("step_divisions", "count"),
    "max_seconds": ("max_seconds", "seconds"), "refinement": ("refinement", "refinement"),
    "units": ("units", "units"), "allow_implausible_units": ("allow_implausible_units", "allow_units"),
}


def with_changes(scene: Scene, changes: dict[str, Any]) -> Scene:
    """:meth:`Scene.with_ <fem_grasp.io.scene.Scene.with_>`: ``scene`` with ``changes`` (keys of :data:`CHANGES`,
    values as in a scene file) checked and applied."""
    new: dict[str, Any] = {}
    for key, value in changes.items():
        if key not in CHANGES:
            close = close_keys(key, list(CHANGES))
            hint = f" (did you mean {', '.join(repr(c) for c in close)}?)" if close else ""
            raise SceneError(f"Scene.with_: unknown setting {key!r}{hint}; it takes {', '.join(CHANGES)}")
        field_name, kind = CHANGES[key]
        w = f"Scene.with_({key}=…)"
        if kind in UNITS:
            v = parse_quantity(value, kind, w)
            check_quantity(w, v, SI_UNITS[kind])
            if key == "mass":
                v *= new.get("gravity", scene.gravity)
            if field_name in ("weight", "density"):
                new["weight" if field_name == "density" else "density"] = None
            new[field_name] = v
        elif kind == "float":  # Poisson's ratio
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not -1.0 < value < 0.5:
                raise SceneError(f"{w}: Poisson's ratio must be a number in (-1, 0.5), got {value!r}")
            new[field_name] = float(value)
        elif kind in ("friction", "ratio"):
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise SceneError(f"{w}: expected a number, got {value!r}")
            check_quantity(w, float(value), "dimensionless", allow_zero=True)
            if key in ("mu", "mu_finger") and value == 0:
                from ..validation import FRICTIONLESS_FINGERS

                raise SceneError(f"{w}: μ_F must be > 0, got 0: {FRICTIONLESS_FINGERS}")
            if key == "mu":
                new["mu_finger"] = new["mu_table"] = float(value)
            else:
                new[field_name] = float(value)
        elif kind == "contacts":
            if value == "auto" or value is None:
                new["contacts"] = None
            elif isinstance(value, str):
                if value not in PLACEMENT_RULES:
                    raise SceneError(f"{w}: expected \"auto\", a placement rule ({', '.join(PLACEMENT_RULES)}) or "
                                     f"two node indices, got {value!r}")
                new["contacts"], new["placement_rule"] = None, value
            else:
                ij = tuple(value)
                if (len(ij) != 2 or not all(isinstance(k, (int, np.integer)) and not isinstance(k, bool) for k in ij)
                        or ij[0] == ij[1] or min(ij) < 0):
                    raise SceneError(f"{w}: expected two distinct non-negative node indices, got {value!r}")
                new["contacts"] = (int(ij[0]), int(ij[1]))
        elif kind == "rule":
            if value not in PLACEMENT_RULES:
                raise SceneError(f"{w}: choose one of {', '.join(PLACEMENT_RULES)}, got {value!r}")
            new["placement_rule"] = value
        elif kind == "directions":
            d = np.asarray(value, dtype=float)
            if d.shape != (2, 3) or not np.isfinite(d).all() or not (np.linalg.norm(d, axis=1) > 0).all():
                raise SceneError(f"{w}: expected two non-zero 3-vectors, got {value!r}")
            new["directions"] = tuple(tuple(float(x) for x in row / np.linalg.norm(row)) for row in d)
        elif kind == "backend":
            if value not in ("sparse", "spectral"):
                raise SceneError(f"{w}: \"sparse\" or \"spectral\", got {value!r}")
            new["backend"] = value
        elif kind == "refinement":
            if value not in REFINEMENTS:
                raise SceneError(f"{w}: one of {', '.join(repr(r) for r in REFINEMENTS)}, got {value!r}")
            new["refinement"] = value
        elif kind == "bool":
            if not isinstance(value, bool):
                raise SceneError(f"{w}: expected True or False, got {value!r}")
            new["lift"] = value
        elif kind == "accuracy":
            new["accuracy"] = parse_accuracy(value, w)
        elif kind == "seconds":  # the accuracy loop's time budget
            if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
                    or not (np.isfinite(value) and value > 0):
                raise SceneError(f"{w}: expected a time in seconds > 0, got {value!r}")
            new[field_name] = float(value)
        elif kind == "count":  # contacts per fingertip, sub-increments
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
                raise SceneError(f"{w}: expected a whole number ≥ 1, got {value!r}")
            new[field_name] = int(value)
        elif kind in ("units", "allow_units"):  # the mesh file's length unit, and whether to check it
            from ..mesh.units import LENGTH_UNITS

            if scene.object.kind != "mesh":
                raise SceneError(f"{w}: only a mesh file has a length unit; a {scene.object.kind} object is in "
                                 "metres already")
            if kind == "units" and value not in LENGTH_UNITS:
                raise SceneError(f"{w}: the unit of the mesh file's coordinates is one of "
                                 f"{', '.join(repr(u) for u in LENGTH_UNITS)}, got {value!r}")
            if kind == "allow_units" and not isinstance(value, bool):
                raise SceneError(f"{w}: expected True or False, got {value!r}")
            new["object"] = replace(new.get("object", scene.object), **{field_name: value})
        elif kind == "int":  # vertices: remesh
            if isinstance(value, bool) or not isinstance(value, int) or value < 20:
                raise SceneError(f"{w}: expected an integer ≥ 20, got {value!r}")
            if scene.object.kind == "box":
                raise SceneError(f"{w}: a box is meshed by its divisions, not a vertex count")
            new["object"] = replace(new.get("object", scene.object), vertices=value)
    return _without_borrowed_error(scene, replace(scene, **new), new)
