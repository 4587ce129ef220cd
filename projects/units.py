"""Quantities typed with units, as engineers type them: "5 kPa", "10 MPa", "18 kN/m3".

:func:`parse_quantity` reads a number with an optional unit and returns it in SI (the unit a
project key's name carries). The project loader uses it for stresses and moduli (keys ending in
``_pa``) and densities (``density_kg_m3``, where a unit weight such as "18 kN/m3" is divided by
:data:`UNIT_WEIGHT_GRAVITY_M_S2`); the workbench's number fields use it too. Files are always
written back in SI numbers.

Units (case does not matter, spaces between number and unit are optional):

=========  =========================================================================
SI unit    accepted
=========  =========================================================================
Pa         Pa, kPa, MPa, GPa, N/m2, kN/m2, MN/m2 (also ``m^2``, ``m²``)
kg/m3      kg/m3, g/cm3, t/m3; unit weights N/m3, kN/m3 (divided by 9.81 m/s2)
N/m3       N/m3, kN/m3 (a unit weight: the water's)
m          m, cm, mm, km
s          s, ms, min, h
=========  =========================================================================
"""

from __future__ import annotations

import math
import re

#: The gravity a unit weight is divided by to give a density, m/s2 (the projects' default).
UNIT_WEIGHT_GRAVITY_M_S2 = 9.81

_PRESSURE = {"pa": 1.0, "kpa": 1e3, "mpa": 1e6, "gpa": 1e9, "n/m2": 1.0, "kn/m2": 1e3, "mn/m2": 1e6}
_DENSITY = {
    "kg/m3": 1.0,
    "g/cm3": 1e3,
    "t/m3": 1e3,
    "n/m3": 1.0 / UNIT_WEIGHT_GRAVITY_M_S2,
    "kn/m3": 1e3 / UNIT_WEIGHT_GRAVITY_M_S2,
}
_WEIGHT = {"n/m3": 1.0, "kn/m3": 1e3}
_LENGTH = {"m": 1.0, "cm": 1e-2, "mm": 1e-3, "km": 1e3}
_TIME = {"s": 1.0, "ms": 1e-3, "min": 60.0, "h": 3600.0}

#: For each SI unit: what it measures and the units accepted, with their factor to SI.
UNITS: dict[str, tuple[str, dict[str, float]]] = {
    "Pa": ("a stress or modulus", _PRESSURE),
    "kg/m3": ("a density or unit weight", _DENSITY),
    "N/m3": ("a unit weight", _WEIGHT),
    "m": ("a length", _LENGTH),
    "s": ("a time", _TIME),
}
_SHOWN = {
    "Pa": "Pa, kPa, MPa or GPa",
    "kg/m3": "kg/m3, g/cm3, t/m3 or a unit weight in kN/m3",
    "N/m3": "N/m3 or kN/m3",
    "m": "m, cm, mm or km",
    "s": "s, ms, min or h",
}
_NUMBER = re.compile(r"^\s*([+-]?(?:\d+(?:[._]\d*)*|\.\d+)(?:[eE][+-]?\d+)?)\s*(.*?)\s*$")


class QuantityError(ValueError):
    """Text that is not a quantity of the wanted kind (one line, naming what is allowed).

    ``reason`` is the message without the text itself (for callers that show the text already).
    """

    def __init__(self, text: object, kind: str, reason: str):
        self.reason = reason
        super().__init__(f"cannot read {text!r} as {kind}: {reason}")


def _normalise_unit(text: str) -> str:
    unit = text.strip().lower().replace(" ", "").replace("^", "").replace("³", "3").replace("²", "2")
    unit = unit.replace("·", "").replace("per", "/")
    return unit


def parse_quantity(text: str | float | int, unit: str) -> float:
    """A number with an optional unit, in the SI unit ``unit``.

    Parameters
    ----------
    text : str or number
        ``"5 kPa"``, ``"10MPa"``, ``"18 kN/m3"``, ``"2.5e4"`` (no unit: already in ``unit``),
        or a number (returned as a float).
    unit : {"Pa", "kg/m3", "m", "s"}
        The SI unit wanted (the unit in the key's name).

    Returns
    -------
    float
        The value in ``unit``; finite.

    Raises
    ------
    QuantityError
        One line: the text, what was expected and the units allowed.
    KeyError
        For an unknown ``unit`` (a programming error).
    """
    kind, table = UNITS[unit]
    if isinstance(text, bool) or not isinstance(text, (int, float, str)):
        raise QuantityError(text, kind, f"expected a number or text such as \"5 {_example(unit)}\"")
    if isinstance(text, (int, float)):
        try:
            value = float(text)
        except OverflowError:
            value = math.inf
        if not math.isfinite(value):
            raise QuantityError(text, kind, "must be a finite number")
        return value
    match = _NUMBER.match(text)
    if match is None:
        raise QuantityError(text, kind, f"expected a number and a unit ({_SHOWN[unit]}), e.g. \"5 {_example(unit)}\"")
    number_text, unit_text = match.groups()
    try:
        number = float(number_text.replace("_", ""))
    except ValueError:
        raise QuantityError(text, kind, f"{number_text!r} is not a number") from None
    if not unit_text:
        factor = 1.0
    else:
        factor = table.get(_normalise_unit(unit_text), math.nan)
        if math.isnan(factor):
            raise QuantityError(text, kind, f"unknown unit {unit_text!r}; use {_SHOWN[unit]}")
    value = number * factor
    if not math.isfinite(value):
        raise QuantityError(text, kind, "must be a finite number")
    return value


def _example(unit: str) -> str:
    return {"Pa": "kPa", "kg/m3": "kN/m3", "N/m3": "kN/m3", "m": "m", "s": "s"}[unit]


def format_quantity(value_si: float, unit: str) -> str:
    """A value in SI written in a readable unit (``5000 Pa`` -> ``"5 kPa"``); the inverse of
    :func:`parse_quantity` to the digits shown (six significant).

    Parameters
    ----------
    value_si : float
    unit : {"Pa", "kg/m3", "m", "s"}

    Returns
    -------
    str
    """
    if unit == "Pa":
        for name, factor in (("GPa", 1e9), ("MPa", 1e6), ("kPa", 1e3)):
            if abs(value_si) >= factor:
                return f"{value_si / factor:.6g} {name}"
        return f"{value_si:.6g} Pa"
    return f"{value_si:.6g} {unit}"
