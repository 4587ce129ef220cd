"""Values typed with a unit ("5 kPa", "10 MPa", "20 kN/m3") in the workbench's number fields.

Every numeric field stores SI (as the project file does) and shows its unit beside it; what an
engineer types may carry another unit of the same kind. The units and their factors are those
of :func:`projects.units.parse_quantity` (the project loader reads the same text the same way;
a unit weight in kN/m³ typed into a density field is divided by
:data:`projects.units.UNIT_WEIGHT_GRAVITY_M_S2`). On top of it the fields accept what people type
in a text box: a comma as decimal point and spaces between thousands ("1 800", "0,3 GPa"), and
degrees ("30 deg", "30°") in angle fields.
"""

from __future__ import annotations

import re

from app.gui.document import parse_number

#: The SI unit of :mod:`projects.units` for each unit a field shows.
_PROJECT_UNITS = {"Pa": "Pa", "kg/m³": "kg/m3", "kg/m3": "kg/m3", "N/m³": "N/m3", "m": "m", "s": "s"}
_ANGLE = {"°", "deg", "degree", "degrees"}
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
        ``"20 kN/m3"``, ``"1 800"``, ``"0,3"``).
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
    from projects.units import QuantityError
    from projects.units import parse_quantity as project_quantity

    number_text, typed_unit = split_unit(text)
    number = parse_number(number_text) if number_text else None
    if number is None:
        return None, "must be a number"
    if not typed_unit:
        return number, ""
    if unit == "°":
        if typed_unit.lower() in _ANGLE:
            return number, ""
        return None, f"unknown unit {typed_unit!r}; use ° or deg"
    si = _PROJECT_UNITS.get(unit)
    if si is None:
        return None, "must be a number (no unit)"
    try:
        return project_quantity(f"{number!r} {typed_unit}", si), ""
    except QuantityError as err:
        return None, err.reason
