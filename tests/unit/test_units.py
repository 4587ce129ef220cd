"""Quantities as engineers type them: parse_quantity and the project keys that accept units."""

from __future__ import annotations

import pytest

from projects.document import apply_overrides, dumps_project, load_project, loads_project
from projects.schema import ProjectError
from projects.units import UNIT_WEIGHT_GRAVITY_M_S2, QuantityError, format_quantity, parse_quantity
from tests.conftest import TINY_PROJECT


@pytest.mark.parametrize(
    "text, unit, expected",
    [
        ("5 kPa", "Pa", 5e3),
        ("5kPa", "Pa", 5e3),
        ("10 MPa", "Pa", 10e6),
        ("10 mpa", "Pa", 10e6),  # nobody means millipascal
        ("0.84e6 Pa", "Pa", 0.84e6),
        ("2.1 GPa", "Pa", 2.1e9),
        ("25 kN/m2", "Pa", 25e3),
        ("25 kN/m^2", "Pa", 25e3),
        ("25 kN/m²", "Pa", 25e3),
        ("  -3.5  kPa ", "Pa", -3.5e3),
        ("1500", "Pa", 1500.0),
        ("1_000 Pa", "Pa", 1000.0),
        ("2650 kg/m3", "kg/m3", 2650.0),
        ("2.65 g/cm3", "kg/m3", 2650.0),
        ("2.65 t/m3", "kg/m3", 2650.0),
        ("18 kN/m3", "kg/m3", 18e3 / UNIT_WEIGHT_GRAVITY_M_S2),
        ("18 kN/m³", "kg/m3", 18e3 / UNIT_WEIGHT_GRAVITY_M_S2),
        ("18000 N/m3", "kg/m3", 18e3 / UNIT_WEIGHT_GRAVITY_M_S2),
        ("20 cm", "m", 0.2),
        ("5 mm", "m", 0.005),
        ("2 min", "s", 120.0),
        ("20 ms", "s", 0.02),
        (42, "Pa", 42.0),
        (4.5, "m", 4.5),
    ],
)
def test_parse_quantity(text, unit, expected):
    assert parse_quantity(text, unit) == pytest.approx(expected, rel=1e-12)


def test_a_unit_weight_with_the_default_gravity_gives_back_its_weight():
    density = parse_quantity("18 kN/m3", "kg/m3")
    assert density * 9.81 == pytest.approx(18e3, rel=1e-12)  # the projects' default |g|


@pytest.mark.parametrize(
    "text, unit, words",
    [
        ("5 kpsi", "Pa", "unknown unit 'kpsi'; use Pa, kPa, MPa or GPa"),
        ("5 kg/m3", "Pa", "unknown unit"),  # a density where a stress belongs
        ("18 kPa", "kg/m3", "unknown unit"),
        ("kPa", "Pa", "expected a number and a unit"),
        ("", "Pa", "expected a number and a unit"),
        ("1.2.3 Pa", "Pa", "is not a number"),
        ("1e999 Pa", "Pa", "finite"),
        ("nan", "Pa", "expected a number"),
        (float("inf"), "Pa", "finite"),
        (True, "Pa", "expected a number"),
        (None, "Pa", "expected a number"),
        ([5], "Pa", "expected a number"),
    ],
)
def test_bad_quantities_are_one_line_naming_the_units(text, unit, words):
    with pytest.raises(QuantityError) as info:
        parse_quantity(text, unit)
    assert words in str(info.value)
    assert "\n" not in str(info.value)
    assert isinstance(info.value, ValueError)


def test_format_quantity_reads_back():
    for value in (5e3, 10e6, 2.1e9, 12.5, 0.0):
        assert parse_quantity(format_quantity(value, "Pa"), "Pa") == pytest.approx(value)
    assert format_quantity(5e3, "Pa") == "5 kPa"


def test_project_keys_accept_units_and_are_stored_in_si():
    project = load_project(TINY_PROJECT)
    changed = apply_overrides(project, [
        "materials.sand.cohesion_pa=5 kPa",
        "materials.sand.youngs_modulus_pa=10 MPa",
        "materials.sand.density_kg_m3=18 kN/m3",
        "stages.1.material_changes.sand.cohesion_pa=0.5 kPa",
    ])
    sand = changed.materials["sand"]
    assert sand.cohesion_pa == 5e3 and sand.youngs_modulus_pa == 10e6
    assert sand.density_kg_m3 == pytest.approx(1834.862385, rel=1e-9)
    assert changed.stages[1].material_changes["sand"].cohesion_pa == 500.0
    text = dumps_project(changed)
    assert "kPa" not in text and "cohesion_pa = 5000.0" in text
    assert loads_project(text) == changed


def test_a_bad_unit_in_a_project_is_one_line_under_its_key():
    project = load_project(TINY_PROJECT)
    with pytest.raises(ProjectError) as info:
        apply_overrides(project, ["materials.sand.cohesion_pa=5 kpsi"])
    assert str(info.value) == (
        "materials.sand.cohesion_pa = \"5 kpsi\": unknown unit 'kpsi'; use Pa, kPa, MPa or GPa"
    )
    with pytest.raises(ProjectError, match="must be >= 0"):
        apply_overrides(project, ["materials.sand.cohesion_pa=-5 kPa"])
    with pytest.raises(ProjectError, match="must be a number"):  # lengths take numbers only
        apply_overrides(project, ["domain.cell_size_m=2 cm"])
