"""Checks of numbers that no later stage can repair: materials, friction, positive quantities, vectors, names.

Each check raises a specific exception (a ``ValueError`` subclass from :mod:`fem_grasp.errors`) whose
message names the offending quantity and value, so that bad input never surfaces as a traceback from
inside numpy/scipy or as a NaN in a result.  The functions are pure: they take numbers and arrays and
return the cleaned values.

Where they are called
---------------------
* :func:`check_material`, :func:`check_positive` — by :class:`fem_grasp.elastic.Body` (and the assembly);
* :func:`check_friction` — by :class:`fem_grasp.grasp.options.PickupOptions` (what
  :func:`~fem_grasp.grasp.pickup.pickup` runs with) and :func:`~fem_grasp.grasp.rest.rest`;
* :func:`check_finger_friction` — μ_F > 0, by :class:`~fem_grasp.grasp.options.PickupOptions`, the scene files and
  :meth:`fem_grasp.io.scene.Scene.with_`;
* :func:`check_names` — the names of :class:`~fem_grasp.settings.EngineSettings` and
  :class:`~fem_grasp.grasp.options.PickupOptions` overrides.

The checks of a finger placement (directions, contact nodes, fingertip spheres) are in
:mod:`fem_grasp.grasp.placement`; mesh validity (shapes, NaN, zero volume, folds, pieces, non-manifold
surfaces) is checked where meshes are made, :class:`fem_grasp.mesh.TetMesh`.
"""

from __future__ import annotations

import difflib
import warnings
from typing import Any, Iterable, Sequence

import numpy as np

from .errors import LockingWarning, MaterialError, SceneError

__all__ = ["LOCKING_POISSON", "check_finger_friction", "check_friction", "check_material", "check_names", "check_positive",
           "check_real", "check_vector"]

#: ν above which :class:`fem_grasp.elastic.body.Body` warns that P1 tetrahedra lock (docs/verification.md: a coarse
#: cantilever's P1 deflection is 0.32 of P2's at ν = 0.45, 0.14 at 0.49, 0.053 at 0.4999).
LOCKING_POISSON = 0.45


# ------------------------------------------------------------------ numbers
def check_real(value: Any, what: str, error: type[ValueError]) -> float:
    """``value`` as a Python float (a real number, not a boolean), or ``error`` naming ``what``."""
    if isinstance(value, (bool, np.bool_)):
        raise error(f"{what} must be a number, got the boolean {value!r}")
    try:
        arr = np.asarray(value)
        if arr.size != 1 or np.iscomplexobj(arr):
            raise TypeError
        return float(arr.reshape(()))
    except (TypeError, ValueError):
        raise error(f"{what} must be a real number, got {value!r}") from None


def check_positive(value: Any, what: str, unit: str, error: type[ValueError] = MaterialError) -> float:
    """``value`` as a float if it is finite and > 0, else ``error`` naming ``what``."""
    x = check_real(value, what, error)
    if not np.isfinite(x) or x <= 0:
        raise error(f"{what} must be a positive number of {unit}, got {value!r}")
    return x


def check_material(young: Any, poisson: Any, *, warn: bool = True) -> tuple[float, float]:
    """(E, ν) as floats if E > 0 is finite and −1 < ν < ½ (paper eq. 2), else :class:`MaterialError`.

    ν = ½ (incompressible) makes λ infinite; ν ≤ −1 makes the shear modulus
    E/(2(1+ν)) infinite or negative: eq. (2) is then not a positive
    semi-definite energy.  With ``warn``, ν > :data:`LOCKING_POISSON` gives a
    :class:`LockingWarning` (the body warns once; the assembly checks quietly).
    """
    e = check_positive(young, "Young's modulus E", "pascals")
    nu = check_real(poisson, "Poisson's ratio ν", MaterialError)
    if not np.isfinite(nu) or not -1.0 < nu < 0.5:
        raise MaterialError(f"Poisson's ratio ν must lie strictly inside (-1, 1/2), got {poisson!r}")
    if warn and nu > LOCKING_POISSON:
        warnings.warn(f"Poisson's ratio ν = {nu:g} > {LOCKING_POISSON:g}: P1 tetrahedra lock as ν → 1/2 and "
                      "underestimate displacements (a coarse cantilever deflects 0.14 of the P2 value at ν = 0.49); "
                      "refine the mesh and read the locking study (make verify) before trusting absolute squeeze "
                      "depths", LockingWarning, stacklevel=3)
    return e, nu


def check_friction(mu: Any, name: str = "mu") -> float:
    """A friction coefficient as a float if it is finite and ≥ 0, else :class:`SceneError`."""
    m = check_real(mu, name, SceneError)
    if not np.isfinite(m) or m < 0:
        raise SceneError(f"{name} must be a finite friction coefficient >= 0, got {mu!r}")
    return m


#: Why μ_F must be positive, in the words of the error.
FRICTIONLESS_FINGERS = (
    "two fingertips without friction push only along the two contact normals, so they cannot carry the object's "
    "weight nor resist a twist about the line between them: no two-finger grasp is force closure (the first step "
    "of the pickup) and the object cannot be lifted. Give a positive coefficient (typical values 0.2–1)")


def check_finger_friction(mu: Any, name: str = "mu_finger") -> float:
    """The fingers' friction coefficient μ_F as a float if it is finite and > 0, else :class:`SceneError`
    saying why a two-finger grasp needs friction (:data:`FRICTIONLESS_FINGERS`)."""
    m = check_friction(mu, name)
    if m == 0:
        raise SceneError(f"{name} (μ_F, the friction between the object and the fingertips) must be > 0, got {mu!r}: "
                         f"{FRICTIONLESS_FINGERS}")
    return m


def check_vector(v: Any, what: str, error: type[ValueError]) -> np.ndarray:
    """``v`` as a finite (3,) float array, or ``error`` naming ``what``."""
    try:
        a = np.asarray(v, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise error(f"{what} must be a 3-vector of real numbers, got {v!r}") from None
    if a.shape != (3,):
        raise error(f"{what} must be a 3-vector, got shape {np.shape(v)}")
    if not np.isfinite(a).all():
        raise error(f"{what} has NaN or infinite components: {a.tolist()}")
    return a


# ------------------------------------------------------------------ names
def check_names(names: Iterable[Any], known: Sequence[str], what: str, listing: str) -> None:
    """Refuse the ``names`` that are not ``known``, each named with the nearest known name where one is close.

    For records built from keyword overrides (:meth:`fem_grasp.settings.EngineSettings.from_overrides`,
    :meth:`fem_grasp.grasp.options.PickupOptions.from_overrides`): a misspelt name is an error, never ignored.

    Parameters
    ----------
    names : the names given
    known : the names accepted, in the order the message lists them
    what : what one name is called in the message ("engine setting")
    listing : what the known names are called in the message ("settings")

    Raises
    ------
    ValueError
        "unknown engine setting 'implicit_contact' (did you mean 'implicit_contacts'?); the settings are …".
    """
    unknown = [name for name in names if name not in known]
    if not unknown:
        return
    parts = []
    for name in unknown:
        near = difflib.get_close_matches(str(name).lower(), known, n=1)
        parts.append(f"{name!r}" + (f" (did you mean {near[0]!r}?)" if near else ""))
    raise ValueError(f"unknown {what}{'s' if len(unknown) > 1 else ''} {', '.join(parts)}; "
                     f"the {listing} are {', '.join(known)}")
