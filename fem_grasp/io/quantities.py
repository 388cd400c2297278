"""Quantities in scene files and options: a number in SI units or a string with its unit ("10 kPa", "2 cm").

Units are spelled exactly as in SI (case matters: ``mPa`` is not ``MPa``): lengths m, cm, mm, µm; pressures Pa,
kPa, MPa, GPa; forces N, mN, kN; masses kg, g, mg; densities kg/m^3, g/cm^3; accelerations m/s^2.  A bare number
is in SI units.  A value of the wrong kind, with an unknown unit or out of range raises
:class:`~fem_grasp.errors.SceneError` naming where it was given (a scene key, an option).
"""

from __future__ import annotations

import math
import re
from typing import Any

from ..errors import SceneError

__all__ = ["SI_UNITS", "UNITS", "check_quantity", "parse_accuracy", "parse_quantity"]


#: Units by kind, spelled exactly as SI writes them (case matters: m is milli, M is mega).
UNITS: dict[str, dict[str, float]] = {
    "length": {"m": 1.0, "cm": 1e-2, "mm": 1e-3, "um": 1e-6, "µm": 1e-6, "μm": 1e-6},
    "pressure": {"Pa": 1.0, "kPa": 1e3, "MPa": 1e6, "GPa": 1e9},
    "force": {"N": 1.0, "mN": 1e-3, "kN": 1e3},
    "mass": {"kg": 1.0, "g": 1e-3, "mg": 1e-6},
    "density": {"kg/m^3": 1.0, "kg/m3": 1.0, "kg/m³": 1.0, "g/cm^3": 1e3, "g/cm3": 1e3, "g/cm³": 1e3},
    "acceleration": {"m/s^2": 1.0, "m/s2": 1.0, "m/s²": 1.0},
}
#: What each unit is called, for messages that suggest the intended one.
_UNIT_NAMES = {"m": "metre", "cm": "centimetre", "mm": "millimetre", "um": "micrometre", "µm": "micrometre",
               "μm": "micrometre", "Pa": "pascal", "kPa": "kilopascal", "MPa": "megapascal", "GPa": "gigapascal",
               "N": "newton", "mN": "millinewton", "kN": "kilonewton", "kg": "kilogram", "g": "gram",
               "mg": "milligram"}
#: The SI unit of each kind (a bare number is in it).
SI_UNITS = {"length": "m", "pressure": "Pa", "force": "N", "mass": "kg", "density": "kg/m^3",
            "acceleration": "m/s^2"}
_QUANTITY = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*([^\s\d].*?)?\s*$")


def _named(unit: str) -> str:
    return f"'{unit}' ({_UNIT_NAMES[unit]})" if unit in _UNIT_NAMES else f"'{unit}'"


def parse_quantity(value: Any, kind: str, where: str = "value") -> float:
    """A number (SI) or a string ``"<number> <unit>"`` of the given kind → float in SI units.

    Units are the exact SI spellings of :data:`UNITS` (``"kPa"``, ``"mm"``, ``"mN"``): case matters, since
    ``m`` is milli and ``M`` mega.  A unit that matches one only when case is ignored (``"10 mPa"``,
    ``"1 CM"``) is refused with a message that suggests the intended unit; a unit of another kind
    (``"3 mm"`` for a pressure) is refused naming both kinds.

    Raises
    ------
    SceneError
        Naming ``where`` when the value is not a number, has no or a wrong unit.
    """
    if isinstance(value, bool):
        raise SceneError(f"{where}: expected a {kind} in {SI_UNITS[kind]}, got the boolean {value!r}")
    if isinstance(value, (int, float)):
        return float(value)
    if not isinstance(value, str):
        raise SceneError(f"{where}: expected a {kind} (a number in {SI_UNITS[kind]} or a string like "
                         f"\"{_example(kind)}\"), got {value!r}")
    m = _QUANTITY.match(value)
    if not m:
        raise SceneError(f"{where}: cannot read {value!r} as a {kind} (write a number and a unit, e.g. "
                         f"\"{_example(kind)}\")")
    number, unit = float(m.group(1)), (m.group(2) or "").strip()
    if not unit:
        return number
    table = UNITS[kind]
    if unit in table:
        return number * table[unit]
    takes = f"a {kind} takes {', '.join(_display_units(kind))}"
    for other, units in UNITS.items():
        if other != kind and unit in units:
            raise SceneError(f"{where}: {value!r} is a {other}, but a {kind} is expected ({takes})")
    same_kind = [u for u in table if u.lower() == unit.lower()]
    if same_kind:
        milli = " (m is milli, M is mega)" if any(u[0] != unit[0] and u[0] in "mM" for u in same_kind) else ""
        raise SceneError(f"{where}: unknown unit {unit!r} in {value!r}: units are case-sensitive{milli}; did you "
                         f"mean {' or '.join(_named(u) for u in same_kind)}? ({takes})")
    other_kind = [(u, o) for o, units in UNITS.items() for u in units if u.lower() == unit.lower()]
    if other_kind:
        u, o = other_kind[0]
        raise SceneError(f"{where}: unknown unit {unit!r} in {value!r}; {takes} (units are case-sensitive: "
                         f"{_named(u)} would be a {o})")
    raise SceneError(f"{where}: unknown unit {unit!r} in {value!r}; {takes}")


def _display_units(kind: str) -> list[str]:
    return {"length": ["m", "cm", "mm", "µm"], "pressure": ["Pa", "kPa", "MPa", "GPa"], "force": ["N", "mN", "kN"],
            "mass": ["kg", "g", "mg"], "density": ["kg/m^3", "g/cm^3"], "acceleration": ["m/s^2"]}[kind]


def _example(kind: str) -> str:
    return {"length": "2 cm", "pressure": "10 kPa", "force": "1.2 N", "mass": "120 g", "density": "900 kg/m^3",
            "acceleration": "9.8 m/s^2"}[kind]


def check_quantity(w: str, v: float | None, unit: str, allow_zero: bool = False) -> None:
    """Raise :class:`SceneError` naming ``w`` unless ``v`` (SI, ``unit``) is finite and > 0.

    With ``allow_zero`` zero passes too; None (a key not given) always passes.
    """
    if v is None:
        return
    ok = math.isfinite(v) and (v >= 0 if allow_zero else v > 0)
    if not ok:
        raise SceneError(f"{w} must be {'≥ 0' if allow_zero else 'positive'} ({unit}), got {v!r}")


def parse_accuracy(value: Any, where: str = "accuracy") -> float | None:
    """An accuracy setting: a relative error (0.05), a percentage ("5%"), or off (None, "off": one run on the
    scene's mesh).  Raises :class:`~fem_grasp.errors.SceneError` naming ``where`` for anything else."""
    if value is None:
        return None
    if isinstance(value, str):
        t = value.strip().lower()
        if t in ("off", "none", "no"):
            return None
        try:
            v = float(t[:-1]) / 100.0 if t.endswith("%") else float(t)
        except ValueError:
            raise SceneError(f"{where}: expected a relative error such as 0.05, a percentage such as 5%, or off; "
                             f"got {value!r}") from None
    elif isinstance(value, bool) or not isinstance(value, (int, float)):
        raise SceneError(f"{where}: expected a relative error such as 0.05, got {value!r}")
    else:
        v = float(value)
    if not 0.0 < v < 1.0:
        raise SceneError(f"{where}: a relative error in (0, 1) (e.g. 0.05 or 5%), got {value!r}")
    return v
