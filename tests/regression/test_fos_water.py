"""Factors of safety with water against closed forms: strength reduction on the project path.

Infinite slopes (periodic sides, gravity rotated by beta, a layer 1 m thick normal to the base on
a rough base; :func:`studies.fos.infinite_slope`) with a phreatic line parallel to the slope at a
fraction ``m`` of the depth above the slip plane, seepage parallel to the slope (the inclined-line
correction), against

    F = [c' + (gamma_d (1 - m) z + gamma_sat m z - gamma_w m z) cos^2 b tan(phi')]
        / [(gamma_d (1 - m) z + gamma_sat m z) sin b cos b]

(``z`` the vertical depth of the plane), which is ``c' / (gamma z sin b cos b) + (1 - gamma_w m /
gamma) tan(phi') / tan(b)`` for one unit weight above and below the line: within 3 %.

Cells: the layer slides on the lowest particles whose stencils reach the base nodes, about 1.25
cells above the base (test_fos_infinite_slope.py). Where the factor depends on the depth (a line
inside the layer, or cohesion) the wetted fraction there differs from ``m`` by about
``1.25 dx (1 - m) / T`` and the cohesive part is larger by ``1.25 dx / T``, so the cohesionless
cases use 32 cells over the thickness (measured: half wet +1.6 %, line at the surface -0.7 %, two
unit weights +1.9 %; at 8 cells the line at the surface came out +7 %, the surface particles'
pressure resolved too coarsely) and the cohesive one 64 (+1.9 %; at 32 cells +3.0 %, as the bias
above predicts).
"""

import math

import pytest

from projects.runner import run_project
from projects.schema import validate_project
from studies.fos import infinite_slope

pytestmark = pytest.mark.slow

TOLERANCE = 0.03
GAMMA_W = 9810.0
G = 9.81


def wet_factor(beta_deg, cohesion, phi_deg, m, dry_density, saturated_density, thickness=1.0):
    b, phi = math.radians(beta_deg), math.radians(phi_deg)
    z = thickness / math.cos(b)
    weight = G * (dry_density * (1 - m) * z + saturated_density * m * z)
    normal = (weight - GAMMA_W * m * z) * math.cos(b) ** 2
    return (cohesion + normal * math.tan(phi)) / (weight * math.sin(b) * math.cos(b))


def wet_slope(beta, cohesion, phi, m, dry, saturated, cell, youngs_modulus_pa=20e6):
    project, _ = infinite_slope(beta, cohesion, phi, cell_m=cell, duration_s=0.5, youngs_modulus_pa=youngs_modulus_pa)
    data = project.to_dict()
    width = data["domain"]["size_m"][0]
    data["materials"]["soil"]["density_kg_m3"] = dry
    data["materials"]["soil"]["saturated_density_kg_m3"] = saturated
    data["water"] = {"phreatic_line_m": [[0.0, m], [width, m]], "inclined_line_correction": True}
    return validate_project(data)


CASES = [
    # beta, c, phi, m, dry density, saturated density, cell
    pytest.param(25.0, 0.0, 35.0, 0.5, 2000.0, 2000.0, 1.0 / 32, id="half-wet-one-unit-weight"),
    pytest.param(20.0, 0.0, 40.0, 1.0, 2000.0, 2000.0, 1.0 / 32, id="line-at-the-surface"),
    pytest.param(22.0, 0.0, 38.0, 0.6, 1800.0, 2100.0, 1.0 / 32, id="two-unit-weights"),
    pytest.param(30.0, 6000.0, 30.0, 0.3, 2000.0, 2000.0, 1.0 / 64, id="cohesive-one-unit-weight"),
]


def test_the_closed_form_is_the_textbook_one_for_one_unit_weight():
    b, phi = math.radians(25.0), math.radians(30.0)
    z = 1.0 / math.cos(b)
    gamma = 2000.0 * G
    textbook = 5000.0 / (gamma * z * math.sin(b) * math.cos(b)) + (1 - GAMMA_W * 0.4 / gamma) * math.tan(phi) / math.tan(b)
    assert wet_factor(25.0, 5000.0, 30.0, 0.4, 2000.0, 2000.0) == pytest.approx(textbook, rel=1e-12)


# a covering sample of the cases in the suite (tests/conftest.py; RUNOUT_FULL_MATRIX=1: all)
@pytest.mark.matrix
@pytest.mark.parametrize("beta, cohesion, phi, m, dry, saturated, cell", CASES)
def test_strength_reduction_of_an_infinite_slope_with_parallel_seepage(tmp_path, beta, cohesion, phi, m, dry,
                                                                        saturated, cell):
    exact = wet_factor(beta, cohesion, phi, m, dry, saturated)
    assert exact > 1.05  # the layer stands in the gravity stage
    result = run_project(wet_slope(beta, cohesion, phi, m, dry, saturated, cell), tmp_path / "run")
    assert result.status == "completed", result.message
    fos = result.summary["factor_of_safety"]
    assert fos["lower"] is not None and fos["upper"] is not None, fos["message"]
    assert fos["value"] == pytest.approx(exact, rel=TOLERANCE), (
        f"F = {fos['value']:.4f} in [{fos['lower']:.4f}, {fos['upper']:.4f}] against {exact:.4f}")


def test_a_rising_water_table_starts_the_slide_where_the_closed_form_reaches_one(tmp_path):
    """A cohesionless layer (beta 21.07, phi 35, one unit weight, 16 cells, E = 5 MPa) whose water
    table rises from 0.75 to 1.0 of its depth over 7.5 s: F = (1 - gamma_w m / gamma) tan(phi) /
    tan(beta) is 1 at m* = 0.9. The slide starts (the first frame in which the layer moves faster
    than 5 mm/s, far above the creep of its elastic swelling, about 1e-4 m/s) within 5 % of that
    height. Near m = 1 the factor hardly depends on the depth, so the plane the layer slides on
    (1.25 cells above the base) starts it less than 1 % late; the speed threshold about 1 % more."""
    import csv

    from solver.water import line_height

    phi, m_star = 35.0, 0.9
    beta = math.degrees(math.atan(math.tan(math.radians(phi)) * (1 - GAMMA_W * m_star / (2000.0 * G))))
    assert wet_factor(beta, 0.0, phi, m_star, 2000.0, 2000.0) == pytest.approx(1.0, abs=1e-12)
    data = wet_slope(beta, 0.0, phi, 0.75, 2000.0, 2000.0, 1.0 / 16, youngs_modulus_pa=5e6).to_dict()
    width = data["domain"]["size_m"][0]
    data["stages"] = [data["stages"][0],
                      {"name": "rain", "type": "dynamic", "duration_s": 7.5,
                       "water": {"phreatic_line_m": [[0.0, 1.0], [width, 1.0]]}}]
    data["output"] = {"interval_s": 0.1, "fields": ["displacement"]}
    result = run_project(validate_project(data), tmp_path / "run")
    assert result.status == "completed", result.message
    with open(tmp_path / "run" / "series.csv", newline="") as fh:
        rows = [r for r in csv.DictReader(fh) if r["stage"] == "rain"]
    start = next(r for r in rows if float(r["max_speed_m_s"]) > 0.005)
    m_start = 0.75 + 0.25 * float(start["stage_time_s"]) / 7.5
    assert m_start == pytest.approx(m_star, rel=0.05), f"the slide started at m = {m_start:.3f}, closed form {m_star}"
    # and the summary says where the water was
    failure = result.summary["water_at_failure"]
    assert failure is not None and failure["stage"] == "rain"
    assert line_height(failure["phreatic_line_m"], [0.5 * width])[0] >= 0.9 * m_star
