"""Values typed with a unit ("5 kPa", "10 MPa", "20 kN/m3"), converted to the SI unit a field stores.

Every numeric field of the workbench stores SI (as the project file does) and shows its unit
beside it; what an engineer types may carry another unit of the same kind. A unit weight in
kN/m³ typed into a density field is divided by standard gravity (g = 9.80665 m/s², the
conventional value; the project's own gravity may differ and the stored density does not follow
it). Unit names are matched without regard to case where that is unambiguous ("kpa", "MPA");
``m`` (metre) and ``M`` (mega) only occur inside the names below, so there is no clash.

A stand-in until ``projects.units.parse_quantity`` is in main (then the fields use that).
"""

from __future__ import annotations

import re

from app.gui.document import parse_number

#: Standard gravity (m/s²) for unit weights typed into density fields.
STANDARD_GRAVITY_M_S2 = 9.80665

_PRESSURE = {"pa": 1.0, "kpa": 1e3, "mpa": 1e6, "gpa": 1e9, "n/m2": 1.0, "n/m²": 1.0, "kn/m2": 1e3,
             "kn/m²": 1e3, "mn/m2": 1e6, "mn/m²": 1e6, "bar": 1e5}
_DENSITY = {"kg/m3": 1.0, "kg/m³": 1.0, "t/m3": 1e3, "t/m³": 1e3, "g/cm3": 1e3, "g/cm³": 1e3,
            # unit weights: N/m³ over g
            "kn/m3": 1e3 / STANDARD_GRAVITY_M_S2, "kn/m³": 1e3 / STANDARD_GRAVITY_M_S2,
            "n/m3": 1.0 / STANDARD_GRAVITY_M_S2, "n/m³": 1.0 / STANDARD_GRAVITY_M_S2}
_LENGTH = {"m": 1.0, "cm": 1e-2, "mm": 1e-3, "km": 1e3}
_TIME = {"s": 1.0, "ms": 1e-3, "min": 60.0, "h": 3600.0}
_ANGLE = {"°": 1.0, "deg": 1.0, "degree": 1.0, "degrees": 1.0}

#: Units accepted in a field, by the SI unit the field shows.
ACCEPTED: dict[str, dict[str, float]] = {
    "Pa": _PRESSURE,
    "kg/m³": _DENSITY,
    "m": _LENGTH,
    "s": _TIME,
    "°": _ANGLE,
}
_SHOWN = {"Pa": "Pa, kPa, MPa, GPa, kN/m²", "kg/m³": "kg/m³, t/m³, g/cm³, or a unit weight in kN/m³",
          "m": "m, cm, mm, km", "s": "s, ms, min, h", "°": "° or deg"}


_NUMBER = re.compile(r"^\s*([-+]?[0-9 \u202f.,]*[0-9](?:[eE][-+]?[0-9]+)?)\s*(.*?)\s*$")


def split_unit(text: str) -> tuple[str, str]:
    """``"5 kPa"`` -> ``("5", "kPa")``: the number part and what follows it (``("", text)``
    when it does not start with a number)."""
    match = _NUMBER.match(text)
    return (match.group(1), match.group(2)) if match else ("", text.strip())


def parse_quantity(text: str, unit: str) -> tuple[float | None, str]:
    """A typed value in the field's SI ``unit``.

    Parameters
    ----------
    text : str
        What was typed: a number, optionally followed by a unit (``"5 kPa"``, ``"2.5e6"``,
        ``"20 kN/m3"``, ``"1 000"``, ``"0,3"``).
    unit : str
        The unit the field stores and shows (``"Pa"``, ``"kg/m³"``, ``"m"``, ``"s"``, ``"°"``;
        anything else accepts plain numbers only).

    Returns
    -------
    value : float or None
        In ``unit``; None when the text is not a number (with a unit this field accepts).
    error : str
        What is wrong ("" when nothing is).
    """
    number_text, typed_unit = split_unit(text)
    if not number_text or not typed_unit:
        number = parse_number(text)
        return (number, "") if number is not None else (None, "must be a number")
    number = parse_number(number_text)
    if number is None:
        return None, "must be a number"
    factors = ACCEPTED.get(unit, {})
    key = typed_unit.replace(" ", "")
    factor = factors.get(key, factors.get(key.lower()))
    if factor is None:
        allowed = _SHOWN.get(unit)
        if allowed is None:
            return None, f"must be a number in {unit} (no unit)" if unit and unit != "–" else "must be a number"
        return None, f"unknown unit {typed_unit!r}; allowed: {allowed}"
    return number * factor, ""
