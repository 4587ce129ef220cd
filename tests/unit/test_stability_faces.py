"""Bishop's search through faces anywhere on the ground surface (stability.bishop) against Taylor.

Sources and values (phi = 0, the stability number ``N = gamma H F / c`` of the critical circle):

- A vertical cut: ``N = 3.83`` (Taylor 1948, Fundamentals of Soil Mechanics, ch. 16, the toe
  circle of a 90 deg slope, stability number c / (gamma H F) = 0.261; the circular mechanism's
  upper bound 3.83, between which and the lower bound 3.77 the exact value lies).
- Simple slopes on a firm base at the toe's level, toe circles: ``c / (gamma H F) = 0.219`` for
  75 deg and ``0.191`` for 60 deg (Taylor 1948, the same table; reproduced in Das, Principles of
  Geotechnical Engineering).

The toe or face lies on the end of the section (a body with nothing in front of it) or on a step
of the ground surface inside it (a cut in clay on a strong floor).
"""

import math

import numpy as np
import pytest

from stability.bishop import NoAdmissibleCircle, Section, Soil, critical_circle

GAMMA = 20e3  # N/m3


def block(x0, x1, y0, y1):
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])


@pytest.mark.parametrize("side", ["left", "right"])
@pytest.mark.parametrize("height_m, cohesion_pa, width_m", [(2.0, 20e3, 6.0), (10.0, 50e3, 30.0), (5.0, 15e3, 20.0)])
def test_vertical_cut_at_the_end_of_a_body(side, height_m, cohesion_pa, width_m):
    section = Section([block(0.0, width_m, 0.0, height_m)], [Soil(cohesion_pa, 0.0, GAMMA)],
                      free_ends=(side == "left", side == "right"))
    result = critical_circle(section)
    assert GAMMA * height_m * result.factor / cohesion_pa == pytest.approx(3.83, rel=0.03)
    # the sliding mass comes out through the face
    face = 0.0 if side == "left" else width_m
    assert min(abs(result.entry_x_m - face), abs(result.exit_x_m - face)) <= 2.0 * section.dx


@pytest.mark.parametrize("height_m, cohesion_pa", [(10.0, 50e3), (4.0, 25e3)])
def test_vertical_cut_inside_the_section_on_a_strong_floor(height_m, cohesion_pa):
    floor = block(-2.0 * height_m, 3.0 * height_m, -0.5 * height_m, 0.0)
    clay = block(0.0, 3.0 * height_m, 0.0, height_m)
    section = Section([floor, clay], [Soil(1e9, 0.0, GAMMA), Soil(cohesion_pa, 0.0, GAMMA)])
    result = critical_circle(section)
    assert GAMMA * height_m * result.factor / cohesion_pa == pytest.approx(3.83, rel=0.03)


@pytest.mark.parametrize("free", [False, True])
@pytest.mark.parametrize("beta_deg, stability_number", [(75.0, 0.219), (60.0, 0.191)])
def test_toe_at_the_end_of_the_section(free, beta_deg, stability_number):
    height, c = 10.0, 10e3
    run = height / math.tan(math.radians(beta_deg))
    end = run + 3.0 * height
    polygon = np.array([[0.0, 0.0], [end, 0.0], [end, height], [run, height]])
    section = Section([polygon], [Soil(c, 0.0, GAMMA)], columns=250, rows=500, free_ends=(free, False))
    result = critical_circle(section, centres=15, radii=25, refinements=5)
    assert result.factor == pytest.approx(c / (stability_number * GAMMA * height), rel=0.03)
    assert result.entry_x_m <= 2.0 * section.dx  # a toe circle


@pytest.mark.parametrize("polygon, kwargs", [
    (block(0.0, 40.0, 0.0, 5.0), {}),  # level ground between walls
    (block(-10.0, 10.0, -3.0, 0.0), {}),
    (np.array([[0.0, 0.0], [30.0, 0.0], [30.0, 10.0], [20.0, 10.0], [10.0, 0.0]]), {"min_depth_m": 50.0}),
])
def test_no_admissible_circle_is_said_not_numbered(polygon, kwargs):
    section = Section([polygon], [Soil(20e3, math.radians(20.0), GAMMA)])
    with pytest.raises(NoAdmissibleCircle, match="^no admissible slip circle in this section") as err:
        critical_circle(section, centres=11, radii=15, refinements=2, **kwargs)
    assert isinstance(err.value, ValueError) and "\n" not in str(err.value)


def test_free_ends_bad_input():
    with pytest.raises(ValueError, match="free_ends = "):
        Section([block(0.0, 1.0, 0.0, 1.0)], [Soil(1e3, 0.0, GAMMA)], free_ends=(True,))
