"""The ground-water rules of solver/water.py and the K0 stress under water, against closed forms.

Hydrostatic water below a phreatic line: ``u = gamma_w (h - y)``; below a free-water surface the
total vertical stress carries the water's weight; the effective vertical stress of a column is the
overburden of buoyant weights, ``(gamma_sat - gamma_w) z`` below the line. Exact to round-off here
(the K0 stage sums the particles' bars exactly for lattice seeding).
"""

import math

import numpy as np
import pytest

from solver.config import Material, Particles, Water
from solver.initial_stress import k0_stress
from solver.water import blend_lines, blend_water, below_line, free_water_depth, line_height, pore_pressure

GAMMA_W = 9810.0
G = 9.81


def _soil(density=1800.0, saturated=2100.0, ru=0.0):
    return Material("soil", "drucker-prager", density, 20e6, 0.3, 5000.0, math.radians(30.0),
                    saturated_density_kg_m3=saturated, ru=ru)


def _column(width=1.0, height=4.0, spacing=0.05):
    xs = np.arange(spacing / 2, width, spacing)
    ys = np.arange(spacing / 2, height, spacing)
    X, Y = np.meshgrid(xs, ys)
    pos = np.c_[X.ravel(), Y.ravel()]
    n = len(pos)
    bounds = np.c_[pos - spacing / 2, pos + spacing / 2]
    return Particles(pos, np.full(n, spacing * spacing), np.zeros(n, dtype=np.int32), bounds_m=bounds)


def test_a_line_is_extended_level_beyond_its_ends_and_blends_linearly():
    line = ((0.0, 1.0), (10.0, 3.0))
    assert line_height(line, np.array([-5.0, 0.0, 5.0, 10.0, 20.0])) == pytest.approx([1.0, 1.0, 2.0, 3.0, 3.0])
    half = blend_lines(line, ((5.0, 0.0), (10.0, 1.0)), 0.5)
    xs = np.array([x for x, _ in half])
    assert list(xs) == [0.0, 5.0, 10.0]
    assert line_height(half, xs) == pytest.approx([0.5 * (1.0 + 0.0), 0.5 * (2.0 + 0.0), 0.5 * (3.0 + 1.0)])


def test_blended_water_keeps_the_free_water_and_reaches_the_end():
    a = Water(((0.0, 5.0), (10.0, 5.0)))
    b = Water(((0.0, 5.0), (10.0, 5.0)), free_water_line_m=((0.0, 1.0), (10.0, 1.0)))
    mid = blend_water(a, b, 0.25)
    assert line_height(mid.phreatic_line_m, [3.0]) == pytest.approx([5.0])
    assert line_height(mid.free_water, [3.0]) == pytest.approx([4.0])
    assert blend_water(a, b, 1.0) is b


@pytest.mark.parametrize("level", [0.5, 2.0, 3.7])
@pytest.mark.parametrize("gravity", [(0.0, -9.81), (0.0, -4.0)])
def test_pore_pressure_is_hydrostatic_below_the_line_and_scales_with_gravity(level, gravity):
    y = np.linspace(0.0, 4.0, 41)
    x = np.c_[np.full_like(y, 0.3), y]
    u = pore_pressure(Water(((0.0, level), (1.0, level))), [_soil()], np.zeros(len(y), int), x, gravity,
                      full_gravity_m_s2=(0.0, -9.81))
    expected = GAMMA_W * abs(gravity[1]) / 9.81 * np.maximum(level - y, 0.0)
    assert u == pytest.approx(expected, abs=1e-9)
    assert list(below_line(Water(((0.0, level), (1.0, level))), x, gravity)) == list(level - y > 0)


@pytest.mark.parametrize("beta_deg", [10.0, 25.0, 40.0])
def test_the_inclined_correction_is_seepage_parallel_to_the_line(beta_deg):
    """A line inclined at beta over a point a vertical depth h below it: u = gamma_w h cos^2(beta)
    with the correction, gamma_w h without; the same in the rotated frame of an infinite slope
    (a level line, gravity inclined by beta)."""
    b = math.radians(beta_deg)
    line = ((0.0, 0.0), (10.0, 10.0 * math.tan(b)))
    point = np.array([[4.0, 4.0 * math.tan(b) - 1.5]])
    wet = pore_pressure(Water(line, inclined_correction=True), [_soil()], np.zeros(1, int), point, (0.0, -9.81))
    dry_rule = pore_pressure(Water(line), [_soil()], np.zeros(1, int), point, (0.0, -9.81))
    assert wet[0] == pytest.approx(GAMMA_W * 1.5 * math.cos(b) ** 2, rel=1e-12)
    assert dry_rule[0] == pytest.approx(GAMMA_W * 1.5, rel=1e-12)
    # the slope's frame: the layer level, gravity rotated; a point 0.8 m (normal) below the line
    g = (9.81 * math.sin(b), -9.81 * math.cos(b))
    rotated = pore_pressure(Water(((0.0, 2.0), (5.0, 2.0)), inclined_correction=True), [_soil()], np.zeros(1, int),
                            np.array([[1.0, 1.2]]), g)
    vertical_depth = 0.8 / math.cos(b)
    assert rotated[0] == pytest.approx(GAMMA_W * vertical_depth * math.cos(b) ** 2, rel=1e-12)


def test_ru_gives_the_larger_of_its_pressure_and_the_lines():
    mats = [_soil(), _soil(ru=0.3)]
    x = np.array([[0.5, 1.0], [0.5, 1.0]])
    sigma_v = np.array([-50e3, -50e3])
    u = pore_pressure(Water(((0.0, 3.0), (1.0, 3.0))), mats, np.array([0, 1]), x, (0.0, -9.81),
                      vertical_stress_pa=sigma_v)
    assert u == pytest.approx([GAMMA_W * 2.0, GAMMA_W * 2.0])
    low = pore_pressure(Water(((0.0, 1.5), (1.0, 1.5))), mats, np.array([0, 1]), x, (0.0, -9.81),
                        vertical_stress_pa=sigma_v)
    assert low == pytest.approx([GAMMA_W * 0.5, 0.3 * 50e3])
    high = pore_pressure(Water(((0.0, 9.0), (1.0, 9.0))), mats, np.array([0, 1]), x, (0.0, -9.81),
                         vertical_stress_pa=sigma_v)
    assert high == pytest.approx([GAMMA_W * 8.0, GAMMA_W * 8.0])


@pytest.mark.parametrize("line, free", [(2.5, None), (4.0, None), (6.0, None), (4.0, 5.5), (6.0, 3.0)])
def test_k0_stress_under_water_is_the_buoyant_overburden(line, free):
    """Column 4 m high, dry 1800 above the line, 2100 below; free water where its level is above
    the top. Total ``sigma_v = overburden + gamma_w (free - top)``, ``u = gamma_w (line - y)``,
    effective = total - u; horizontal effective = K0 times vertical effective."""
    particles = _column()
    soil = _soil()
    water = Water(((0.0, line), (1.0, line)),
                  free_water_line_m=None if free is None else ((0.0, free), (1.0, free)))
    stress = k0_stress(particles, [soil], (0.0, -G), 0.1, k0=0.5, water=water)
    y = particles.positions_m[:, 1]
    top = 4.0
    free_level = line if free is None else free

    def overburden(y):
        wet_top = min(max(line, y), top)
        return G * (1800.0 * (top - wet_top) + 2100.0 * (wet_top - y))

    total = np.array([overburden(v) for v in y]) + GAMMA_W * max(free_level - top, 0.0)
    u = GAMMA_W * np.maximum(line - y, 0.0)
    effective = total - u
    assert -stress[:, 1] == pytest.approx(effective, rel=1e-9, abs=1e-6)
    assert -stress[:, 0] == pytest.approx(0.5 * effective, rel=1e-9, abs=1e-6)


def test_free_water_depth_is_measured_to_the_free_level():
    water = Water(((0.0, 5.0), (1.0, 5.0)), free_water_line_m=((0.0, 2.0), (1.0, 2.0)))
    depth = free_water_depth(water, np.array([[0.5, 1.0], [0.5, 3.0]]), (0.0, -9.81))
    assert depth == pytest.approx([1.0, 0.0])
