"""Rate-dependent friction (the mu(I) law of dense granular flow): one material point in steady
simple shear against the closed form, the project keys' rules, the strength reduction."""

import math

import numpy as np
import pytest

from projects.document import loads_project as load_project_text
from projects.schema import ProjectError
from solver.config import InertialFriction, Material
from solver.materials.drucker_prager import MATCHES, dp_constants

PHI = math.radians(20.0)
#: Jop, Forterre and Pouliquen (2006): mu_2 - mu_s = tan(32.76 deg) - tan(20.9 deg), I0 = 0.279
LAW = InertialFriction(friction_increase=0.26, reference_inertial_number=0.279, grain_diameter_m=1e-3,
                       grain_density_kg_m3=2500.0)
P0 = 1000.0


def grains(match="simple-shear", law=LAW):
    return Material("grains", "drucker-prager", 2500.0, 1e6, 0.3, friction_angle_rad=PHI, mohr_coulomb_match=match,
                    inertial=law)


def sheared(material, rate, precision="f64", steps=1500):
    """Stress of one point sheared at ``rate`` (1/s) from an isotropic pressure P0 (xx, yy, xy, zz)."""
    from solver import runtime

    runtime.acquire("cpu", precision)
    from solver.materials import MaterialPointDriver

    driver = MaterialPointDriver((material,), 1, np.float64 if precision == "f64" else np.float32)
    out = driver.run(np.array([[-P0, -P0, 0.0, -P0]]), np.array([[[0.0, rate], [0.0, 0.0]]]), 2e-5, steps=steps)
    return out["stress"][0]


def invariants(s):
    p = -(s[0] + s[1] + s[3]) / 3.0
    d = np.array(s, dtype=np.float64)
    d[[0, 1, 3]] += p
    return p, math.sqrt(0.5 * (d[0] ** 2 + d[1] ** 2 + d[3] ** 2) + d[2] ** 2)


def mu_of(rate, pressure, law=LAW):
    inertial = rate * law.grain_diameter_m / math.sqrt(pressure / law.grain_density_kg_m3)
    return math.tan(PHI) + law.friction_increase * inertial / (law.reference_inertial_number + inertial), inertial


@pytest.mark.parametrize("rate, match, precision", [
    *((rate, match, "f64") for rate in (6.32, 63.2, 632.0) for match in MATCHES),  # I = 0.01, 0.1, 1
    (63.2, "simple-shear", "f32"),
])
def test_steady_shear_flows_at_the_friction_of_its_inertial_number(rate, match, precision):
    """In steady simple shear at constant pressure the cone's slope is ``alpha mu(I) / mu_s``:
    ``sqrt(J2) = 3 alpha p mu(I) / tan(phi)``, which for the simple-shear match (``3 alpha =
    tan(phi)``, psi = 0) is Jop et al.'s ``|tau| = mu(I) p``, and the shear plane carries
    ``tau / sigma_n = mu(I)``. Tolerance: 1e-6 (f64), 1e-4 (f32) of sqrt(J2); 0.2 % on the shear
    plane (the Jaumann rotation of a steady shear tilts the stress a little)."""
    s = sheared(grains(match), rate, precision)
    p, q = invariants(s)
    mu, _ = mu_of(rate, p)
    alpha, _, _ = dp_constants(PHI, 0.0, 0.0, match)
    tol = 1e-6 if precision == "f64" else 1e-4
    assert p == pytest.approx(P0, rel=tol)
    assert q == pytest.approx(3.0 * alpha * p * mu / math.tan(PHI), rel=tol)
    if match == "simple-shear":
        assert s[2] / -s[1] == pytest.approx(mu, rel=2e-3)  # shear (tension positive) over compression


def test_the_friction_rises_with_the_rate_and_tends_to_mu_2():
    ratios = []
    for rate in (0.632, 63.2, 6320.0, 632000.0):  # I = 1e-3 .. 1e3
        p, q = invariants(sheared(grains(), rate))
        ratios.append(q / p)
    assert np.all(np.diff(ratios) > 0.0)
    assert ratios[0] == pytest.approx(math.tan(PHI), rel=0.01)  # quasi-static: mu_s
    assert ratios[-1] == pytest.approx(math.tan(PHI) + LAW.friction_increase, rel=0.01)  # mu_2


def test_without_the_law_the_friction_does_not_depend_on_the_rate():
    slow, fast = (invariants(sheared(grains(law=None), rate)) for rate in (6.32, 632.0))
    assert slow[1] / slow[0] == pytest.approx(math.tan(PHI), rel=1e-6)
    assert fast[1] / fast[0] == pytest.approx(math.tan(PHI), rel=1e-6)


# ------------------------------------------------------------------ project keys
BASE = """
[runout]
schema_version = 2
[domain]
size_m = [1.0, 0.5]
cell_size_m = 0.05
[materials.sand]
model = "drucker-prager"
density_kg_m3 = 2000.0
youngs_modulus_pa = 1e6
poisson_ratio = 0.3
cohesion_pa = 0.0
friction_angle_deg = 30.0
mohr_coulomb_match = "simple-shear"
{extra}
[[bodies]]
name = "b"
material = "sand"
polygon_m = [[0.1, 0.0], [0.4, 0.0], [0.4, 0.2], [0.1, 0.2]]
[[stages]]
type = "dynamic"
duration_s = 0.1
"""
LAW_KEYS = "mu_i_friction_increase = 0.26\nmu_i_reference_number = 0.279\ngrain_diameter_m = 0.001\n"


def test_the_keys_give_the_solver_its_law_and_the_grains_density_defaults_to_the_materials():
    from projects.build import solver_material

    project = load_project_text(BASE.format(extra=LAW_KEYS))
    law = solver_material("sand", project.materials["sand"]).inertial
    assert law == InertialFriction(0.26, 0.279, 0.001, 2000.0)
    project = load_project_text(BASE.format(extra=LAW_KEYS + "grain_density_kg_m3 = 2650.0\n"))
    assert solver_material("sand", project.materials["sand"]).inertial.grain_density_kg_m3 == 2650.0
    assert solver_material("sand", load_project_text(BASE.format(extra="")).materials["sand"]).inertial is None


@pytest.mark.parametrize("extra, key, words", [
    ("mu_i_reference_number = 0.279\ngrain_diameter_m = 0.001\n", "mu_i_reference_number",
     "needs mu_i_friction_increase"),
    ("mu_i_friction_increase = 0.26\ngrain_diameter_m = 0.001\n", "mu_i_reference_number", "required with"),
    ("mu_i_friction_increase = 0.26\nmu_i_reference_number = 0.279\n", "grain_diameter_m", "required with"),
    (LAW_KEYS.replace("0.26", "-0.1"), "mu_i_friction_increase", ""),
    (LAW_KEYS + 'softening_law = "linear"\nresidual_friction_angle_deg = 20.0\nresidual_plastic_strain = 0.1\n',
     "mu_i_friction_increase", "not allowed with softening_law"),
])
def test_bad_keys_are_refused_with_a_line_naming_the_key(extra, key, words):
    with pytest.raises(ProjectError) as err:
        load_project_text(BASE.format(extra=extra))
    text = str(err.value)
    assert f"materials.sand.{key}" in text and words in text


def test_a_frictionless_or_elastic_material_cannot_have_the_law():
    text = BASE.format(extra=LAW_KEYS).replace("friction_angle_deg = 30.0", "friction_angle_deg = 0.0")
    with pytest.raises(ProjectError, match="needs friction_angle_deg > 0"):
        load_project_text(text)
    elastic = BASE.format(extra=LAW_KEYS).replace('model = "drucker-prager"', 'model = "linear-elastic"').replace(
        'cohesion_pa = 0.0\nfriction_angle_deg = 30.0\nmohr_coulomb_match = "simple-shear"\n', "")
    with pytest.raises(ProjectError, match='mu_i_friction_increase.*only allowed with model "drucker-prager"'):
        load_project_text(elastic)


def test_the_strength_reduction_divides_the_friction_increase_with_tan_phi():
    from projects.strength import reduced_materials

    (m,) = reduced_materials((grains(),), (0,), 2.0)
    assert math.tan(m.friction_angle_rad) == pytest.approx(math.tan(PHI) / 2.0)
    assert m.inertial.friction_increase == pytest.approx(LAW.friction_increase / 2.0)
