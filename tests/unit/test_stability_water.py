"""Bishop's simplified method with water (stability.bishop.Water, Soil.ru) against closed forms.

- The infinite slope with seepage parallel to the slope (Duncan and Wright 2005, Soil Strength
  and Slope Stability, ch. 6; Skempton and DeLory 1957): a slip plane at depth ``z`` under a
  slope of angle ``b``, the phreatic line parallel to the slope at ``m z`` above the plane, the
  pressure head ``m z cos^2(b)``:
  ``F = [c' + (g (1 - m) z + g_sat m z - g_w m z) cos^2(b) tan(phi')] / [(g (1 - m) z + g_sat m z) sin(b) cos(b)]``,
  which for ``g_sat = g`` is ``c' / (g z sin b cos b) + (1 - g_w m / g) tan(phi') / tan(b)``.
- The pore-pressure ratio ``ru = u / (g z)`` (Bishop and Morgenstern 1960, Geotechnique 10(4),
  129-150) on the same plane: ``F = c' / (g z sin b cos b) + (1 - ru / cos^2 b) tan(phi') / tan(b)``.

The infinite-slope limit from circles: a segment of the slope, ``L = 20 m`` long, whose two ends
are free faces (``free_ends=(True, True)``: no force on them, as on the equal and opposite
interslice forces of an infinite slope), cut by a circle of radius ``R = 1e5 m`` whose centre
lies on the normal to the slope: within the segment the arc is parallel to the slope within
``L^2 / (8 R) = 0.5 mm`` and its base angles within ``L / (2 R) = 1e-4 rad`` of ``b``. Bishop's
equations of such slices reduce to the infinite slope's (each slice's vertical equilibrium with
``alpha = b`` and the moment about the distant centre becomes the balance along the slope).

Still water: the free water's weight on the slices and its thrust on the ends of the sliding
mass are, for a level water surface, the same as buoyant weights below the water with no water
(Archimedes over the sliding mass); a fully submerged cohesionless slope keeps its dry factor.
"""

import math

import numpy as np
import pytest

from stability.bishop import (
    Circle,
    Section,
    Soil,
    Water,
    bishop_factor,
    critical_circle,
)

GW = 9810.0
L = 20.0  # the infinite slope's segment (m)
R_PLANE = 1e5  # radius of the planar limit (m)


def infinite_slope_factor(beta_deg, z, c, phi_deg, gamma, *, m=None, gamma_sat=None, ru=0.0):
    """Bishop's factor of the planar limit circle at vertical depth z in a segment of the slope."""
    b = math.radians(beta_deg)
    t = math.tan(b)
    polygon = np.array([[0.0, -2.0 * z], [L, L * t - 2.0 * z], [L, L * t], [0.0, 0.0]])
    water = None
    if m is not None:
        line = np.array([[-1.0, -t - (1.0 - m) * z], [L + 1.0, (L + 1.0) * t - (1.0 - m) * z]])
        water = Water(line, unit_weight_n_m3=GW, inclined_correction=True)
    soil = Soil(c, math.radians(phi_deg), gamma, gamma_sat, ru)
    section = Section([polygon], [soil], columns=300, rows=800, water=water, free_ends=(True, True))
    normal = np.array([-math.sin(b), math.cos(b)])
    centre = np.array([L / 2, L / 2 * t]) + normal * (R_PLANE - z * math.cos(b))
    return bishop_factor(section, Circle(float(centre[0]), float(centre[1]), R_PLANE))


@pytest.mark.parametrize("m", [0.0, 0.25, 0.5, 0.75, 1.0])
@pytest.mark.parametrize("beta_deg, z, c, phi_deg, gamma", [(30.0, 2.0, 5e3, 30.0, 20e3), (20.0, 4.0, 0.0, 32.0, 19e3),
                                                            (35.0, 3.0, 12e3, 38.0, 18e3)])
def test_infinite_slope_water_table_parallel_to_the_slope(m, beta_deg, z, c, phi_deg, gamma):
    b, tp = math.radians(beta_deg), math.tan(math.radians(phi_deg))
    closed = c / (gamma * z * math.sin(b) * math.cos(b)) + (1.0 - GW * m / gamma) * tp / math.tan(b)
    assert infinite_slope_factor(beta_deg, z, c, phi_deg, gamma, m=m) == pytest.approx(closed, rel=0.03)


@pytest.mark.parametrize("m", [0.2, 0.5, 1.0])
@pytest.mark.parametrize("gamma, gamma_sat", [(17e3, 20e3), (16e3, 21.5e3)])
def test_infinite_slope_different_unit_weights_above_and_below_the_line(m, gamma, gamma_sat):
    beta_deg, z, c, phi_deg = 28.0, 3.0, 6e3, 34.0
    b, tp = math.radians(beta_deg), math.tan(math.radians(phi_deg))
    total = gamma * (1.0 - m) * z + gamma_sat * m * z
    closed = (c + (total - GW * m * z) * math.cos(b) ** 2 * tp) / (total * math.sin(b) * math.cos(b))
    assert infinite_slope_factor(beta_deg, z, c, phi_deg, gamma, m=m, gamma_sat=gamma_sat) == pytest.approx(closed, rel=0.03)


@pytest.mark.parametrize("ru", [0.0, 0.2, 0.4])
@pytest.mark.parametrize("beta_deg, z, c, phi_deg", [(30.0, 2.0, 5e3, 30.0), (22.0, 5.0, 0.0, 36.0)])
def test_infinite_slope_ru(ru, beta_deg, z, c, phi_deg):
    gamma = 20e3
    b, tp = math.radians(beta_deg), math.tan(math.radians(phi_deg))
    closed = c / (gamma * z * math.sin(b) * math.cos(b)) + (1.0 - ru / math.cos(b) ** 2) * tp / math.tan(b)
    assert infinite_slope_factor(beta_deg, z, c, phi_deg, gamma, ru=ru) == pytest.approx(closed, rel=0.03)


@pytest.mark.parametrize("m, ru", [(0.25, 0.4), (1.0, 0.05), (0.5, 0.2)])
def test_a_line_and_ru_together_the_larger_pore_pressure(m, ru):
    beta_deg, z, c, phi_deg, gamma = 30.0, 2.0, 5e3, 30.0, 20e3
    b, tp = math.radians(beta_deg), math.tan(math.radians(phi_deg))
    u = max(ru * gamma * z, GW * m * z * math.cos(b) ** 2)
    closed = (c + (gamma * z * math.cos(b) ** 2 - u) * tp) / (gamma * z * math.sin(b) * math.cos(b))
    assert infinite_slope_factor(beta_deg, z, c, phi_deg, gamma, m=m, ru=ru) == pytest.approx(closed, rel=0.03)


def simple_slope(height_m, beta_deg, foundation_m=5.0):
    run = height_m / math.tan(math.radians(beta_deg))
    front, back = 2.0 * height_m, 3.0 * height_m
    toe, crest = front, front + run
    end = crest + back
    return np.array([[0.0, -foundation_m], [end, -foundation_m], [end, height_m], [crest, height_m],
                     [toe, 0.0], [0.0, 0.0]]), toe, end


@pytest.mark.parametrize("above_crest_m", [0.0, 5.0, 20.0])
@pytest.mark.parametrize("phi_deg, beta_deg", [(35.0, 30.0), (30.0, 25.0)])
def test_submerged_cohesionless_slope_keeps_its_dry_factor(above_crest_m, phi_deg, beta_deg):
    polygon, _, end = simple_slope(10.0, beta_deg)
    soil = Soil(0.0, math.radians(phi_deg), 18e3, 20e3)
    level = 10.0 + above_crest_m
    water = Water(np.array([[0.0, level], [end, level]]))
    dry = Section([polygon], [soil], columns=250, rows=500)
    wet = Section([polygon], [soil], columns=250, rows=500, water=water)
    f_dry = critical_circle(dry, centres=15, radii=25, refinements=5).factor
    f_wet = critical_circle(wet, centres=15, radii=25, refinements=5).factor
    assert f_wet == pytest.approx(f_dry, rel=0.02)


@pytest.mark.parametrize("level_m", [2.0, 5.0, 10.0, 14.0])
@pytest.mark.parametrize("circle", [Circle(30.0, 25.0, 26.0), Circle(26.0, 16.0, 17.0)])
def test_still_water_equals_buoyant_weights_below_it(level_m, circle):
    """Total weights, pore pressure and the free water's thrust = buoyant weights and no water."""
    polygon, _, end = simple_slope(10.0, 30.0)
    c, phi, gamma, gamma_sat = 8e3, math.radians(30.0), 18e3, 20.5e3
    wet = Section([polygon], [Soil(c, phi, gamma, gamma_sat)], columns=300, rows=600,
                  water=Water(np.array([[0.0, level_m], [end, level_m]])))
    # the same section dry, the soil below the level with its buoyant unit weight
    dry = Section([polygon, clip_below(polygon, level_m)], [Soil(c, phi, gamma), Soil(c, phi, gamma_sat - GW)],
                  columns=300, rows=600)
    f_wet, f_dry = bishop_factor(wet, circle), bishop_factor(dry, circle)
    assert math.isfinite(f_wet)
    assert f_wet == pytest.approx(f_dry, rel=0.005)


@pytest.mark.parametrize("level_m", [2.0, 5.0, 8.0])
@pytest.mark.parametrize("circle", [Circle(30.0, 25.0, 26.0), Circle(26.0, 16.0, 17.0)])
def test_free_water_thrust_on_the_ends_equals_buoyant_weights(level_m, circle):
    """A free-water line that is not one level (1 mm of rise over 67 m) takes the thrust on the
    ends of the sliding mass and the weight of the water explicitly: the same factor as buoyant
    weights below the level."""
    polygon, _, end = simple_slope(10.0, 30.0)
    c, phi, gamma, gamma_sat = 8e3, math.radians(30.0), 18e3, 20.5e3
    water = Water(np.array([[0.0, level_m + 1e-3], [end, level_m + 1e-3]]),
                  free_water_line=np.array([[0.0, level_m], [end, level_m + 1e-3]]))
    wet = Section([polygon], [Soil(c, phi, gamma, gamma_sat)], columns=300, rows=600, water=water)
    dry = Section([polygon, clip_below(polygon, level_m)], [Soil(c, phi, gamma), Soil(c, phi, gamma_sat - GW)],
                  columns=300, rows=600)
    assert bishop_factor(wet, circle) == pytest.approx(bishop_factor(dry, circle), rel=0.005)


def clip_below(polygon, level):
    """The part of a polygon below y = level (Sutherland-Hodgman against one edge)."""
    out = []
    for p, q in zip(polygon, np.roll(polygon, -1, axis=0)):
        p_in, q_in = p[1] <= level, q[1] <= level
        if p_in:
            out.append(p)
        if p_in != q_in:
            t = (level - p[1]) / (q[1] - p[1])
            out.append(p + t * (q - p))
    return np.array(out)


@pytest.mark.parametrize("c, phi_deg", [(10e3, 25.0), (4e3, 33.0)])
def test_factor_falls_as_the_phreatic_line_rises(c, phi_deg):
    polygon, toe, end = simple_slope(10.0, 30.0)
    soil = Soil(c, math.radians(phi_deg), 18e3, 20e3)
    factors = []
    for back_level in [0.0, 2.5, 5.0, 7.5, 9.5]:
        # from the ground at the toe up into the slope (below its face), level behind and in front
        water = Water(np.array([[toe, 0.0], [toe + 20.0, back_level], [end, back_level]]))
        section = Section([polygon], [soil], columns=200, rows=400, water=water)
        factors.append(critical_circle(section, centres=11, radii=15, refinements=4).factor)
    # never up (beyond the search's 0.1 % where a low line does not reach the critical circle),
    # and down by more than 10 % once the line is high in the slope
    assert np.all(np.diff(factors) <= 1e-3 * np.array(factors[:-1])), factors
    assert np.all(np.diff(factors[1:]) < 0.0), factors
    assert factors[-1] < 0.9 * factors[0], factors


def test_rapid_drawdown_lowers_the_factor_below_full_and_drained():
    """The reservoir falls to the toe, the water in the slope stays (free-water line below the phreatic one)."""
    polygon, toe, end = simple_slope(10.0, 26.0)
    soil = Soil(8e3, math.radians(30.0), 18e3, 20e3)
    full = Water(np.array([[0.0, 9.0], [end, 9.0]]))
    slope_line = np.array([[0.0, 0.0], [toe, 0.0], [toe + 20.0, 8.0], [end, 9.0]])  # below the face
    drawdown = Water(slope_line, free_water_line=np.array([[0.0, 0.0], [end, 0.0]]))
    drained = Water(np.array([[0.0, 0.0], [end, 0.0]]))
    f = {name: critical_circle(Section([polygon], [soil], columns=200, rows=400, water=w),
                               centres=11, radii=15, refinements=4).factor
         for name, w in (("full", full), ("drawdown", drawdown), ("drained", drained))}
    assert f["drawdown"] < 0.95 * f["drained"], f
    assert f["full"] > f["drained"], f  # still water lightens a c-phi slope's drive more than its strength
    assert f["drawdown"] < 0.85 * f["full"], f


def test_dry_water_none_and_a_line_below_everything_agree():
    polygon, _, end = simple_slope(10.0, 30.0)
    soil = Soil(10e3, math.radians(28.0), 19e3, 21e3)
    low = Water(np.array([[0.0, -50.0], [end, -50.0]]))
    circle = Circle(30.0, 25.0, 26.0)
    dry = bishop_factor(Section([polygon], [soil]), circle)
    assert bishop_factor(Section([polygon], [soil], water=low), circle) == pytest.approx(dry, rel=1e-12)


@pytest.mark.parametrize("kwargs, match", [
    ({"phreatic_line": [[0.0, 1.0], [0.0, 2.0]]}, "phreatic_line: x = .* must increase strictly"),
    ({"phreatic_line": [[0.0, 1.0], [5.0, 2.0]], "free_water_line": [[3.0, 1.0], [1.0, 2.0]]}, "free_water_line: x"),
    ({"phreatic_line": [[0.0, 1.0], [5.0, 2.0]], "unit_weight_n_m3": -1.0}, "unit_weight_n_m3 = -1.0"),
    ({"phreatic_line": "abc"}, "phreatic_line = 'abc'"),
])
def test_water_bad_input_one_line_errors(kwargs, match):
    with pytest.raises(ValueError, match=match):
        Water(**kwargs)


@pytest.mark.parametrize("kwargs, match", [
    ({"saturated_unit_weight_n_m3": 15e3}, "saturated_unit_weight_n_m3 = 15000.0: must be finite and at least"),
    ({"ru": 1.0}, "ru = 1.0: allowed 0 <= ru < 1"),
    ({"ru": -0.1}, "ru = -0.1"),
])
def test_soil_bad_water_keys_one_line_errors(kwargs, match):
    with pytest.raises(ValueError, match=match):
        Soil(5e3, 0.5, 18e3, **kwargs)


def test_free_water_over_a_lower_phreatic_line_is_refused():
    polygon, _, end = simple_slope(10.0, 30.0)
    water = Water(np.array([[0.0, -2.0], [end, -2.0]]), free_water_line=np.array([[0.0, 4.0], [end, 4.0]]))
    with pytest.raises(ValueError, match="the phreatic line must be at or above its surface"):
        Section([polygon], [Soil(5e3, 0.5, 18e3)], water=water)
