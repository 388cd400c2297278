"""Length units of mesh files, and warnings for objects whose size or density says the unit is wrong.

fem_grasp computes in metres.  Scanners often write millimetres, and a 95 mm bean read as metres is a
95 m object: its volume is 10⁹ times too large, its density from a 100 g weight absurdly small, and a
pickup of it fails with forces of hundreds of newtons.  Nothing in the file says which unit it is in,
so ``fem-grasp mesh --units mm`` and a scene's ``object.units = "mm"`` say it, and :func:`size_warning` and
:func:`density_warning` flag an object that is larger than :data:`MAX_PLAUSIBLE_SIZE` or whose density
lies outside :data:`PLAUSIBLE_DENSITY`, naming the unit that would make it plausible.
"""

from __future__ import annotations

import math
import warnings

from ..errors import UnitsWarning

__all__ = ["LENGTH_UNITS", "MAX_PLAUSIBLE_SIZE", "MIN_PLAUSIBLE_SIZE", "PLAUSIBLE_DENSITY", "UnitsWarning",
           "density_warning", "implausible", "length_scale", "size_warning", "warn_implausible"]

#: Length units a mesh file may be in, and their size in metres.
LENGTH_UNITS = {"m": 1.0, "cm": 1e-2, "mm": 1e-3}
_NAMES = {"m": "metres", "cm": "centimetres", "mm": "millimetres"}
#: An object larger than this (its bounding-box diagonal, metres) is probably not in metres.
MAX_PLAUSIBLE_SIZE = 1.0
#: … and one smaller than this probably was scaled twice.
MIN_PLAUSIBLE_SIZE = 1e-3
#: Densities (kg/m³) of things two fingers pick up: from aerogel-like foams to metals.
PLAUSIBLE_DENSITY = (10.0, 20000.0)


def length_scale(unit: str, where: str = "units") -> float:
    """The size in metres of one ``unit`` ("m", "cm", "mm"); ``ValueError`` naming ``where`` otherwise."""
    if unit not in LENGTH_UNITS:
        raise ValueError(f"{where}: unknown length unit {unit!r}; choose one of {', '.join(LENGTH_UNITS)} "
                         "(the unit the file's coordinates are in)")
    return LENGTH_UNITS[unit]


def _likely(values: dict[str, float], target: float, lo: float, hi: float) -> str | None:
    """The unit whose value lies in [lo, hi] and closest to ``target`` on a log scale."""
    ok = {u: v for u, v in values.items() if lo <= v <= hi}
    if not ok:
        return None
    return min(ok, key=lambda u: abs(math.log10(ok[u] / target)))


def size_warning(diameter: float, unit: str = "m", source: str = "the object", hint: str = "--units") -> str | None:
    """A message when an object of ``diameter`` metres (its coordinates read in ``unit``) is implausibly large or
    small, naming the unit the file is likely in; None when it is plausible."""
    if not (math.isfinite(diameter) and diameter > 0):
        return None
    if MIN_PLAUSIBLE_SIZE <= diameter <= MAX_PLAUSIBLE_SIZE:
        return None
    raw = diameter / LENGTH_UNITS[unit]  # the file's own numbers
    guess = _likely({u: raw * s for u, s in LENGTH_UNITS.items()}, 0.1, MIN_PLAUSIBLE_SIZE, MAX_PLAUSIBLE_SIZE)
    size = f"{diameter:.3g} m across" if diameter >= 1e-2 else f"{diameter * 1e3:.3g} mm across"
    where = "larger than 1 m" if diameter > MAX_PLAUSIBLE_SIZE else "smaller than 1 mm"
    if guess is None or guess == unit:
        return f"{source} is {size} ({where}): check the unit of its coordinates"
    return f"{source} is {size} ({where}): the file is probably in {_NAMES[guess]}; {_advice(hint, guess)}"


def _advice(hint: str, unit: str) -> str:
    return f"pass {hint} {unit}" if hint.startswith("--") else f"set {hint} = \"{unit}\""


def density_warning(mass: float, volume: float, unit: str = "m", source: str = "the object",
                    hint: str = "object.units") -> str | None:
    """A message when ``mass`` (kg) over ``volume`` (m³, coordinates read in ``unit``) is outside
    :data:`PLAUSIBLE_DENSITY`, naming the length unit that would make it plausible; None when plausible."""
    if not (mass > 0 and volume > 0):
        return None
    rho = mass / volume
    lo, hi = PLAUSIBLE_DENSITY
    if lo <= rho <= hi:
        return None
    raw = volume / LENGTH_UNITS[unit] ** 3
    guess = _likely({u: mass / (raw * s ** 3) for u, s in LENGTH_UNITS.items()}, 1000.0, lo, hi)
    msg = (f"{source}: its density from the weight and the volume is {rho:.3g} kg/m^3, outside the "
           f"{lo:g}–{hi:,.0f} kg/m^3 of solid objects")
    if guess is not None and guess != unit:
        return msg + f": the mesh is probably in {_NAMES[guess]}; {_advice(hint, guess)}"
    return msg + ": check the weight (N), mass (kg) or density and the unit of the mesh"


def implausible(diameter: float, volume: float, mass: float | None, unit: str = "m") -> tuple[list[str], str | None]:
    """What is implausible about an object read in ``unit``: its size (``diameter``, metres) and, when ``mass``
    (kg) is known, its density from ``volume`` (m³); and the length unit that would make it plausible.

    Returns (the problems as phrases such as "it is 102 m across (over 1 m)", empty when plausible; the likely
    unit of the file, or None when no unit makes it plausible or it is ``unit`` itself).
    """
    problems: list[str] = []
    guess = None
    if math.isfinite(diameter) and diameter > 0 and not MIN_PLAUSIBLE_SIZE <= diameter <= MAX_PLAUSIBLE_SIZE:
        size = f"{diameter:.3g} m across" if diameter >= 1e-2 else f"{diameter * 1e3:.3g} mm across"
        problems.append(f"it is {size} ({'over 1 m' if diameter > MAX_PLAUSIBLE_SIZE else 'under 1 mm'})")
        raw = diameter / LENGTH_UNITS[unit]
        guess = _likely({u: raw * s for u, s in LENGTH_UNITS.items()}, 0.1, MIN_PLAUSIBLE_SIZE, MAX_PLAUSIBLE_SIZE)
    lo, hi = PLAUSIBLE_DENSITY
    if mass is not None and mass > 0 and volume > 0 and not lo <= mass / volume <= hi:
        problems.append(f"its density from the weight and the volume is {mass / volume:.3g} kg/m^3 (solid objects: "
                        f"{lo:g}–{hi:,.0f} kg/m^3)")
        if guess is None:
            raw = volume / LENGTH_UNITS[unit] ** 3
            guess = _likely({u: mass / (raw * s ** 3) for u, s in LENGTH_UNITS.items()}, 1000.0, lo, hi)
    return problems, (None if guess == unit else guess)


def warn_implausible(message: str | None) -> None:
    """Issue ``message`` as a :class:`~fem_grasp.errors.UnitsWarning` (nothing when None)."""
    if message:
        warnings.warn(message, UnitsWarning, stacklevel=3)
