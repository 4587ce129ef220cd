"""Bishop's simplified method (stability.bishop) against published limit-equilibrium values.

Sources and values:

- ACADS benchmark 1(a) (Giam and Donald 1989, "Example problems for testing soil slope stability
  programs", Civil Engineering Research Report 8/1989, Monash University; the referee factor of
  safety is 1.00, the mean of 18 Bishop-simplified programs 0.993): a 10 m high 2:1 slope,
  c' = 3 kPa, phi' = 19.6 deg, gamma = 20 kN/m3, dry.
- Taylor (1948, Fundamentals of Soil Mechanics, ch. 16; reproduced in Das, Principles of
  Geotechnical Engineering): for phi = 0 the stability number c / (gamma H F) of the critical
  circle is 0.191 for a 60 deg slope (toe circle) and 0.181 for slopes flatter than 53 deg on a
  deep foundation (midpoint circle).
- The infinite slope: for c = 0 the critical circle of a uniform slope of angle beta is a skin
  slide with F -> tan(phi) / tan(beta) (the search's smallest admissible depth keeps it just above).
- For phi = 0 Bishop's and the ordinary (Fellenius) method are the same exact moment balance.
"""

import math

import numpy as np
import pytest

from stability.bishop import (
    Circle,
    Section,
    Soil,
    bishop_factor,
    critical_circle,
    fellenius_factor,
    slices_factor,
)

GAMMA = 20e3  # N/m3


def simple_slope(height_m, beta_deg, foundation_m=0.0, front_m=None, back_m=None):
    run = height_m / math.tan(math.radians(beta_deg))
    front = 2.0 * height_m if front_m is None else front_m
    back = 3.0 * height_m if back_m is None else back_m
    toe, crest = front, front + run
    end = crest + back
    return np.array([[0.0, -foundation_m], [end, -foundation_m], [end, height_m], [crest, height_m],
                     [toe, 0.0], [0.0, 0.0]])


def test_acads_1a_referee_factor():
    polygon = np.array([[20.0, 20.0], [70.0, 20.0], [70.0, 35.0], [50.0, 35.0], [30.0, 25.0], [20.0, 25.0]])
    section = Section([polygon], [Soil(3e3, math.radians(19.6), GAMMA)], columns=250, rows=500)
    result = critical_circle(section, centres=15, radii=25, refinements=5)
    assert result.factor == pytest.approx(1.00, rel=0.02)
    # a toe-region circle of a c-phi slope: Bishop above Fellenius
    assert result.fellenius_factor < result.factor
    assert 28.0 < result.entry_x_m < 32.0 and 50.0 < result.exit_x_m < 60.0


@pytest.mark.parametrize("beta_deg, foundation_m, stability_number", [(60.0, 0.0, 0.191), (45.0, 30.0, 0.181)])
def test_taylor_phi_zero_stability_numbers(beta_deg, foundation_m, stability_number):
    height, c = 10.0, 10e3
    section = Section([simple_slope(height, beta_deg, foundation_m)], [Soil(c, 0.0, GAMMA)], columns=250, rows=500)
    result = critical_circle(section, centres=15, radii=25, refinements=5)
    assert result.factor == pytest.approx(c / (stability_number * GAMMA * height), rel=0.02)


@pytest.mark.parametrize("phi_deg, beta_deg", [(35.0, 30.0), (30.0, 20.0)])
def test_cohesionless_slope_tends_to_the_infinite_slope(phi_deg, beta_deg):
    section = Section([simple_slope(10.0, beta_deg, 5.0)], [Soil(0.0, math.radians(phi_deg), GAMMA)],
                      columns=250, rows=500)
    result = critical_circle(section, centres=15, radii=25, refinements=5)
    infinite = math.tan(math.radians(phi_deg)) / math.tan(math.radians(beta_deg))
    assert infinite <= result.factor * 1.001
    assert result.factor == pytest.approx(infinite, rel=0.02)


@pytest.mark.parametrize("circle", [Circle(21.0, 14.0, 14.0), Circle(24.0, 18.0, 21.0), Circle(30.0, 25.0, 26.0)])
def test_phi_zero_bishop_equals_fellenius(circle):
    section = Section([simple_slope(10.0, 45.0, 10.0)], [Soil(10e3, 0.0, GAMMA)])
    assert math.isfinite(bishop_factor(section, circle))
    assert bishop_factor(section, circle) == pytest.approx(fellenius_factor(section, circle), rel=1e-9)


def test_layers_weaker_upper_layer_lowers_the_factor():
    base = simple_slope(10.0, 30.0, 5.0)
    strong = Soil(10e3, math.radians(30.0), GAMMA)
    weak = Soil(2e3, math.radians(20.0), GAMMA)
    # a weak upper layer (y > 5 m) inside the slope; the later polygon owns the overlap
    run = 10.0 / math.tan(math.radians(30.0))
    upper = np.array([[20.0 + run / 2, 5.0], [20.0 + run + 30.0, 5.0], [20.0 + run + 30.0, 10.0],
                      [20.0 + run, 10.0]])
    one = Section([base], [strong], columns=200, rows=400)
    two = Section([base, upper], [strong, weak], columns=200, rows=400)
    assert np.allclose(one.top, two.top)
    f_one = critical_circle(one, centres=11, radii=15, refinements=3).factor
    f_two = critical_circle(two, centres=11, radii=15, refinements=3).factor
    assert f_two < 0.8 * f_one


def test_slices_factor_hand_form():
    # phi = 0: both methods give sum(c l) / sum(W sin(alpha)) exactly
    w = np.array([100e3, 200e3, 150e3])
    a = np.radians([-5.0, 20.0, 45.0])
    b = np.array([2.0, 2.0, 2.0])
    c = np.full(3, 20e3)
    expected = float(np.sum(c * b / np.cos(a)) / np.sum(w * np.sin(a)))
    assert slices_factor(w, a, b, c, np.zeros(3)) == pytest.approx(expected, rel=1e-12)
    assert slices_factor(w, a, b, c, np.zeros(3), method="fellenius") == pytest.approx(expected, rel=1e-12)
    # Bishop's F satisfies its own equation
    phi = np.radians([30.0, 30.0, 30.0])
    f = slices_factor(w, a, b, c, phi)
    m = np.cos(a) + np.sin(a) * np.tan(phi) / f
    assert f == pytest.approx(float(np.sum((c * b + w * np.tan(phi)) / m) / np.sum(w * np.sin(a))), rel=1e-9)
    with pytest.raises(ValueError, match="unknown method"):
        slices_factor(w, a, b, c, phi, method="janbu")
