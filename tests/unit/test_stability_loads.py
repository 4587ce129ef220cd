"""Bishop's simplified method with loads (stability.bishop.Surcharge, Seismic) against closed forms.

- The infinite slope (the planar limit of test_stability_water.py: a 20 m segment of the slope
  with free ends cut by a circle of radius 1e5 m): a vertical surcharge ``q`` per horizontal
  area and the pseudo-static coefficients ``k_h`` (horizontal force ``k_h W`` out of the slope)
  and ``k_v`` (weight ``(1 - k_v) W``) on a slip plane at vertical depth ``z``. A slice's
  equilibrium normal and along the plane (the interslice forces of an infinite slope cancel)
  gives, with ``V = (1 - k_v) gamma z + q`` and ``H = k_h gamma z`` per horizontal area,

      F = [c' + (V cos^2 b - H sin b cos b) tan(phi')] / [V sin b cos b + H cos^2 b]

  (Kramer 1996, Geotechnical Earthquake Engineering, pseudostatic infinite slope; with ``q`` and
  no coefficients the surcharged slope ``[c' + (gamma z + q) cos^2 b tan phi'] / [(gamma z + q)
  sin b cos b]``). Bishop's and the ordinary method's equations of such slices reduce to it.
  Measured within 1e-4; tolerance 1 %.
- Level ground of undrained clay (``phi = 0``), a circle of centre height ``y_c`` above the
  surface and radius ``R``: the weight has no moment, the seismic force ``k_h W`` of the segment
  below the chord (area ``A = R^2 (a - sin a cos a)``, ``cos a = y_c / R``) acts at its centroid,
  ``d = 2 R sin^3 a / (3 (a - sin a cos a))`` below the centre, so
  ``F = c (2 a R) R / (k_h gamma A d) = 3 c a / (k_h gamma R sin^3 a)``. Measured within 3e-5.
- A strip load ``q`` of width ``B`` on level clay (``phi = 0``): the critical circle is centred
  above the strip's edge and ``F = 5.52 c / q`` (Fellenius 1927; Terzaghi 1943, Theoretical Soil
  Mechanics, the circle method of bearing capacity: ``q_ult = 5.52 c`` against Prandtl's 5.14 c
  of the exact mechanism). Measured -9e-5 from the search; tolerance 1 %.
"""

import math

import numpy as np
import pytest

from stability.bishop import (
    Circle,
    Section,
    Seismic,
    Soil,
    Surcharge,
    bishop_factor,
    critical_circle,
    fellenius_factor,
)

L = 20.0  # the infinite slope's segment (m)
R_PLANE = 1e5  # radius of the planar limit (m)
TOLERANCE = 0.01


def planar_section(beta_deg, z, c, phi_deg, gamma, q=0.0, k_h=0.0, k_v=0.0, direction=-1.0):
    """The planar-limit section and circle of a slope rising to the right (sliding to the left, -x)."""
    b = math.radians(beta_deg)
    t = math.tan(b)
    polygon = np.array([[0.0, -2.0 * z], [L, L * t - 2.0 * z], [L, L * t], [0.0, 0.0]])
    loads = [Surcharge(-1.0, L + 1.0, q)] if q else []
    seismic = Seismic(k_h, k_v, direction) if (k_h or k_v) else None
    section = Section([polygon], [Soil(c, math.radians(phi_deg), gamma)], columns=300, rows=800,
                      free_ends=(True, True), surcharges=loads, seismic=seismic)
    normal = np.array([-math.sin(b), math.cos(b)])
    centre = np.array([L / 2, L / 2 * t]) + normal * (R_PLANE - z * math.cos(b))
    return section, Circle(float(centre[0]), float(centre[1]), R_PLANE)


def infinite_slope_factor(beta_deg, z, c, phi_deg, gamma, q=0.0, k_h=0.0, k_v=0.0):
    b, tp = math.radians(beta_deg), math.tan(math.radians(phi_deg))
    V = (1.0 - k_v) * gamma * z + q
    H = k_h * gamma * z
    return (c + (V * math.cos(b) ** 2 - H * math.sin(b) * math.cos(b)) * tp) / (
        V * math.sin(b) * math.cos(b) + H * math.cos(b) ** 2)


SLOPES = [(30.0, 2.0, 5e3, 30.0, 20e3), (25.0, 3.0, 0.0, 35.0, 19e3), (35.0, 3.0, 12e3, 38.0, 18e3)]


def test_the_closed_form_is_the_textbook_one():
    b, phi = math.radians(30.0), math.radians(30.0)
    gamma, z, c, q = 20e3, 2.0, 5e3, 30e3
    surcharged = (c + (gamma * z + q) * math.cos(b) ** 2 * math.tan(phi)) / (
        (gamma * z + q) * math.sin(b) * math.cos(b))
    assert infinite_slope_factor(30.0, z, c, 30.0, gamma, q=q) == pytest.approx(surcharged, rel=1e-12)
    k_h = 0.15
    seismic = (c + (gamma * z * math.cos(b) ** 2 - k_h * gamma * z * math.sin(b) * math.cos(b)) * math.tan(phi)) / (
        gamma * z * math.sin(b) * math.cos(b) + k_h * gamma * z * math.cos(b) ** 2)
    assert infinite_slope_factor(30.0, z, c, 30.0, gamma, k_h=k_h) == pytest.approx(seismic, rel=1e-12)
    # cohesionless: (1 - k_h tan b) tan phi / (tan b + k_h)
    assert infinite_slope_factor(30.0, z, 0.0, 30.0, gamma, k_h=k_h) == pytest.approx(
        (1 - k_h * math.tan(b)) * math.tan(phi) / (math.tan(b) + k_h), rel=1e-12)


@pytest.mark.parametrize("q", [10e3, 30e3, 100e3])
@pytest.mark.parametrize("beta_deg, z, c, phi_deg, gamma", SLOPES)
def test_a_surcharged_infinite_slope(q, beta_deg, z, c, phi_deg, gamma):
    section, circle = planar_section(beta_deg, z, c, phi_deg, gamma, q=q)
    exact = infinite_slope_factor(beta_deg, z, c, phi_deg, gamma, q=q)
    assert bishop_factor(section, circle) == pytest.approx(exact, rel=TOLERANCE)
    assert fellenius_factor(section, circle) == pytest.approx(exact, rel=TOLERANCE)


@pytest.mark.parametrize("k_h, k_v", [(0.05, 0.0), (0.1, 0.0), (0.2, 0.0), (0.1, 0.1), (0.15, -0.1), (0.0, 0.2)])
@pytest.mark.parametrize("beta_deg, z, c, phi_deg, gamma", SLOPES)
def test_the_pseudo_static_infinite_slope(k_h, k_v, beta_deg, z, c, phi_deg, gamma):
    section, circle = planar_section(beta_deg, z, c, phi_deg, gamma, k_h=k_h, k_v=k_v)
    exact = infinite_slope_factor(beta_deg, z, c, phi_deg, gamma, k_h=k_h, k_v=k_v)
    assert bishop_factor(section, circle) == pytest.approx(exact, rel=TOLERANCE)
    assert fellenius_factor(section, circle) == pytest.approx(exact, rel=TOLERANCE)


def test_a_surcharge_and_coefficients_together():
    section, circle = planar_section(30.0, 2.0, 5e3, 30.0, 20e3, q=20e3, k_h=0.1, k_v=0.05)
    exact = infinite_slope_factor(30.0, 2.0, 5e3, 30.0, 20e3, q=20e3, k_h=0.1, k_v=0.05)
    assert bishop_factor(section, circle) == pytest.approx(exact, rel=TOLERANCE)


def test_the_horizontal_force_into_the_slope_holds_it():
    none, circle = planar_section(30.0, 2.0, 5e3, 30.0, 20e3)
    out, _ = planar_section(30.0, 2.0, 5e3, 30.0, 20e3, k_h=0.1, direction=-1.0)
    into, _ = planar_section(30.0, 2.0, 5e3, 30.0, 20e3, k_h=0.1, direction=1.0)
    f_none, f_out, f_into = (bishop_factor(s, circle) for s in (none, out, into))
    assert f_out < f_none < f_into
    # into the slope: H = -k_h gamma z in the closed form
    assert f_into == pytest.approx(infinite_slope_factor(30.0, 2.0, 5e3, 30.0, 20e3, k_h=-0.1), rel=TOLERANCE)


def level_clay(k_h=0.0, surcharges=(), gamma=18e3, c=20e3, half=30.0, depth=15.0, columns=600, direction=1.0):
    polygon = np.array([[-half, -depth], [half, -depth], [half, 0.0], [-half, 0.0]])
    return Section([polygon], [Soil(c, 0.0, gamma)], columns=columns, rows=columns,
                   surcharges=surcharges, seismic=Seismic(k_h, 0.0, direction) if k_h else None)


@pytest.mark.parametrize("k_h", [0.1, 0.25])
@pytest.mark.parametrize("y_c, radius", [(2.0, 8.0), (5.0, 12.0), (0.5, 6.0)])
def test_a_circle_in_level_clay_under_a_horizontal_force(k_h, y_c, radius):
    c, gamma = 20e3, 18e3
    a = math.acos(y_c / radius)
    exact = 3.0 * c * a / (k_h * gamma * radius * math.sin(a) ** 3)
    got = bishop_factor(level_clay(k_h), Circle(0.0, y_c, radius))
    assert got == pytest.approx(exact, rel=TOLERANCE)
    # the force the other way turns the mass the other way, as far
    assert bishop_factor(level_clay(k_h, direction=-1.0), Circle(0.0, y_c, radius)) == pytest.approx(got, rel=1e-3)


@pytest.mark.parametrize("ends", [(50e3, 50e3), (0.0, 80e3), (90e3, 10e3)])
def test_a_circle_in_level_clay_under_a_load_that_varies_along_it(ends):
    """phi = 0: ``F = c (2 a R) R / M_q`` with ``M_q`` the load's moment about the centre,
    integrated exactly over the part of the load on the chord."""
    c, y_c, radius, lo, hi = 20e3, 2.0, 8.0, -3.0, 5.0
    load = Surcharge(lo, hi, *ends)
    a = math.acos(y_c / radius)
    chord = radius * math.sin(a)
    x = np.linspace(max(lo, -chord), min(hi, chord), 200001)
    p = ends[0] + (x - lo) / (hi - lo) * (ends[1] - ends[0])
    moment = float(np.trapezoid(p * x, x))
    exact = c * 2.0 * a * radius ** 2 / abs(moment)
    got = bishop_factor(level_clay(surcharges=[load], gamma=1.0, columns=800), Circle(0.0, y_c, radius))
    assert got == pytest.approx(exact, rel=TOLERANCE)


def test_a_strip_load_on_level_clay_has_fellenius_bearing_capacity():
    c, q, width = 20e3, 100e3, 4.0
    section = level_clay(surcharges=[Surcharge(-0.5 * width, 0.5 * width, q)], c=c, half=8.0, depth=6.0,
                         columns=200)
    result = critical_circle(section, min_depth_m=0.25 * width, centres=11, radii=20, refinements=5)
    assert result.factor == pytest.approx(5.52 * c / q, rel=TOLERANCE)
    assert abs(abs(result.circle.centre_x_m) - 0.5 * width) < 0.05 * width  # above an edge of the strip


def test_no_loads_leave_the_factor_as_it_was():
    b = math.radians(30.0)
    polygon = np.array([[0.0, -4.0], [L, L * math.tan(b) - 4.0], [L, L * math.tan(b)], [0.0, 0.0]])
    soil = Soil(5e3, math.radians(30.0), 20e3)
    plain = Section([polygon], [soil], columns=200, rows=200)
    zero = Section([polygon], [soil], columns=200, rows=200, seismic=Seismic(0.0, 0.0, 1.0),
                   surcharges=[Surcharge(2.0, 6.0, 0.0)])
    best = critical_circle(plain, centres=7, radii=10, refinements=2).circle
    xs = best.centre_x_m + np.array([0.0, 0.5, -0.5])
    ys = best.centre_y_m + np.array([0.0, 0.3, 0.6])
    rs = best.radius_m + np.array([0.0, 0.2, 0.4])
    f_plain, f_zero = plain.factors(xs, ys, rs), zero.factors(xs, ys, rs)
    assert np.count_nonzero(np.isfinite(f_plain[0])) >= 2
    assert np.array_equal(f_plain[0], f_zero[0], equal_nan=True)
    assert np.array_equal(f_plain[1], f_zero[1], equal_nan=True)


@pytest.mark.parametrize("make, words", [
    (lambda: Surcharge(1.0, 1.0, 5.0), "must be > x_from_m"),
    (lambda: Surcharge(0.0, 1.0, -5.0), "must be >= 0"),
    (lambda: Seismic(1.0), "0 <= k_h < 1"),
    (lambda: Seismic(-0.1), "0 <= k_h < 1"),
    (lambda: Seismic(0.1, -1.0), "-1 < k_v < 1"),
    (lambda: Seismic(0.1, 0.0, 0.5), "direction"),
])
def test_bad_loads_are_one_line_errors(make, words):
    with pytest.raises(ValueError, match=words):
        make()
