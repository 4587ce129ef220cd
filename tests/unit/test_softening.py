"""Strain softening: the law, its kernel (one material point sheared past peak), its regularisation,
every scheme's particles on the softened cone, and the project keys' rules."""

import math

import numpy as np
import pytest

from projects.document import loads_project as load_project_text
from projects.schema import ProjectError
from solver.config import Boundary, Grid, Material, Numerics, Output, Particles, SimulationConfig, Softening, Stage
from solver.materials import softening as sf
from solver.materials.drucker_prager import MATCHES, dp_constants

E, NU = 20e6, 0.3
PEAK = (20e3, math.radians(25.0), math.radians(5.0))
RESIDUAL = (5e3, math.radians(15.0), 0.0)


def clay(law="linear", match="plane-strain-associated", length=None, e_peak=0.01, e_res=0.1, peak=PEAK,
         residual=RESIDUAL):
    return Material("clay", "drucker-prager", 2000.0, E, NU, cohesion_pa=peak[0], friction_angle_rad=peak[1],
                    dilatancy_angle_rad=peak[2], mohr_coulomb_match=match,
                    softening=Softening(residual_cohesion_pa=residual[0], residual_friction_angle_rad=residual[1],
                                        residual_dilatancy_angle_rad=residual[2], peak_strain=e_peak,
                                        residual_strain=e_res, law=law, length_m=length))


def yield_function(stress, eps, material, scale=1.0):
    """f = sqrt(J2) + alpha I1 - k of the cone softened to each strain, with sqrt(J2) (numpy)."""
    s = np.asarray(stress, np.float64).reshape(-1, 4)
    soft = material.softening
    c, phi, psi = sf.parameters_host(soft.law, np.asarray(eps) * scale, soft.peak_strain, soft.residual_strain,
                                     (material.cohesion_pa, material.friction_angle_rad, material.dilatancy_angle_rad),
                                     (soft.residual_cohesion_pa, soft.residual_friction_angle_rad,
                                      soft.residual_dilatancy_angle_rad))
    cones = np.array([dp_constants(float(a), float(b), float(k), material.mohr_coulomb_match)
                      for a, b, k in zip(np.broadcast_to(phi, len(s)), np.broadcast_to(psi, len(s)),
                                         np.broadcast_to(c, len(s)))])
    p = (s[:, 0] + s[:, 1] + s[:, 3]) / 3.0
    d = s.copy()
    d[:, [0, 1, 3]] -= p[:, None]
    sq = np.sqrt(0.5 * (d[:, 0] ** 2 + d[:, 1] ** 2 + d[:, 3] ** 2) + d[:, 2] ** 2)
    return sq + 3.0 * cones[:, 0] * p - cones[:, 1], sq


# ------------------------------------------------------------------ the law
@pytest.mark.parametrize("law", ["linear", "exponential"])
def test_the_law_falls_from_peak_to_residual_between_its_strains(law):
    e = np.array([0.0, 0.01, 0.055, 0.1, 0.5])
    w = sf.weight_host(law, e, 0.01, 0.1)
    assert w[0] == 0.0 and w[1] == 0.0
    assert np.all(np.diff(w) >= 0.0)
    if law == "linear":
        assert w[2] == pytest.approx(0.5, abs=1e-12) and w[3] == 1.0 and w[4] == 1.0
    else:  # 95 % of the drop at the residual strain
        assert w[3] == pytest.approx(1.0 - math.exp(-3.0), abs=1e-12)
        assert w[4] == pytest.approx(1.0 - math.exp(-3.0 * 0.49 / 0.09), abs=1e-12)


def test_the_regularisation_scale_is_the_cell_over_the_material_length():
    assert sf.regularisation_scale(0.2, 0.05) == pytest.approx(0.25)
    assert sf.regularisation_scale(None, 0.05) == 1.0
    assert sf.regularisation_scale(0.2, None) == 1.0


# ------------------------------------------------------------------ one material point past peak
SHEAR_PATHS = {
    "simple-shear": np.array([[0.0, 0.2], [0.0, 0.0]]),
    "compression": np.array([[0.1, 0.0], [0.0, -0.1]]),  # plane-strain compression at constant volume
}


@pytest.mark.parametrize("precision", ["f64", "f32"])
@pytest.mark.parametrize("match", MATCHES)
@pytest.mark.parametrize("law", ["linear", "exponential"])
@pytest.mark.parametrize("path", list(SHEAR_PATHS))
def test_a_point_sheared_past_peak_stays_on_the_softening_cone(law, match, path, precision):
    from solver import runtime

    runtime.acquire("cpu", precision)
    from solver.materials import MaterialPointDriver

    material = clay(law, match)
    n_steps = 1500
    driver = MaterialPointDriver((material,), 1, np.float64 if precision == "f64" else np.float32)
    out = driver.run(np.array([[-100e3, -100e3, 0.0, -100e3]]), SHEAR_PATHS[path][None], 1e-3, steps=n_steps,
                     history=True)
    stress, eps = out["stress_history"][:, 0], out["strain_history"][:, 0]
    f, sq = yield_function(stress, eps, material)
    plastic = eps > 0.0
    assert plastic.sum() > 0.9 * n_steps
    tol = 1e-5 if precision == "f64" else 2e-4
    # on the cone of the strength the law gives at the strain reached, at every plastic step
    assert np.max(np.abs(f[plastic]) / sq[plastic]) < tol
    assert eps[-1] > 1.2 * material.softening.residual_strain  # sheared well past the residual strain
    # the strength fell: at the end the residual cone, and well below the peak one
    peak_alpha, peak_k, _ = dp_constants(PEAK[1], PEAK[2], PEAK[0], match)
    p_end = (stress[-1, 0] + stress[-1, 1] + stress[-1, 3]) / 3.0
    assert sq[-1] < 0.9 * (peak_k - 3.0 * peak_alpha * p_end)


def test_without_softening_keys_the_strength_stays_at_its_peak():
    from solver import runtime

    runtime.acquire("cpu", "f64")
    from solver.materials import MaterialPointDriver

    plain = Material("clay", "drucker-prager", 2000.0, E, NU, cohesion_pa=PEAK[0], friction_angle_rad=PEAK[1],
                     dilatancy_angle_rad=PEAK[2])
    out = MaterialPointDriver((plain,), 1).run(np.array([[-100e3, -100e3, 0.0, -100e3]]),
                                               SHEAR_PATHS["simple-shear"][None], 1e-3, steps=800, history=True)
    stress, eps = out["stress_history"][-1:, 0], out["strain_history"][-1:, 0]
    alpha, k, _ = dp_constants(PEAK[1], PEAK[2], PEAK[0])
    p = (stress[0, 0] + stress[0, 1] + stress[0, 3]) / 3.0
    d = stress[0].copy()
    d[[0, 1, 3]] -= p
    sq = math.sqrt(0.5 * (d[0] ** 2 + d[1] ** 2 + d[3] ** 2) + d[2] ** 2)
    assert eps[0] > 0.05
    assert sq + 3.0 * alpha * p - k == pytest.approx(0.0, abs=1e-5 * sq)


@pytest.mark.parametrize("cell, length", [(0.05, 0.2), (0.1, 0.1), (0.02, 0.1)])
def test_the_regularised_point_softens_over_the_strain_scaled_by_length_over_cell(cell, length):
    """With a material length ``l`` and cells of ``h`` the residual strength is reached at the
    plastic strain ``e_r l / h`` (the band one cell wide then opens by ``e_r l`` at every h)."""
    from solver import runtime

    runtime.acquire("cpu", "f64")
    from solver.materials import MaterialPointDriver

    material = clay("linear", length=length, e_peak=0.0, e_res=0.02)
    scale = cell / length
    out = MaterialPointDriver((material,), 1, cell_size_m=cell).run(
        np.array([[-100e3, -100e3, 0.0, -100e3]]), SHEAR_PATHS["simple-shear"][None], 1e-3, steps=1500, history=True)
    stress, eps = out["stress_history"][:, 0], out["strain_history"][:, 0]
    f, sq = yield_function(stress, eps, material, scale)
    plastic = eps > 0.0
    assert np.max(np.abs(f[plastic]) / sq[plastic]) < 1e-5
    # the softening ends where the scaled strain reaches the residual one, not before
    w = sf.weight_host("linear", eps * scale, 0.0, 0.02)
    assert np.any(w < 1.0) and np.any(w == 1.0)
    first_residual = eps[np.argmax(w == 1.0)]
    assert first_residual == pytest.approx(0.02 / scale, rel=0.05)


# ------------------------------------------------------------------ every scheme's particles
def _column(dx=0.01, ppc=2, width=0.1, height=0.1):
    h = dx / ppc
    xs = np.arange(round(width / h)) * h + h / 2
    ys = np.arange(round(height / h)) * h + h / 2
    X, Y = np.meshgrid(xs, ys)
    pos = np.c_[X.ravel(), Y.ravel()]
    return Particles(pos, np.full(len(pos), h * h), np.zeros(len(pos), np.int32))


@pytest.mark.matrix
@pytest.mark.parametrize("precision", ["f64", "f32"])
@pytest.mark.parametrize("scheme", ["apic-affine", "apic", "mpm"])
def test_a_softening_column_collapses_with_every_particle_inside_its_softened_cone(scheme, precision):
    from solver.simulation import Simulation

    weak = clay("linear", peak=(400.0, math.radians(10.0), 0.0), residual=(50.0, math.radians(5.0), 0.0),
                e_peak=0.0, e_res=0.05)
    weak = Material(weak.name, weak.model, 2000.0, 2e6, 0.3, weak.cohesion_pa, weak.friction_angle_rad,
                    weak.dilatancy_angle_rad, softening=weak.softening)
    grid = Grid((0.0, 0.0), (0.4, 0.2), 0.01, left=Boundary("slip"), right=Boundary("slip"),
                bottom=Boundary("friction", math.radians(20)), top=Boundary("open"))
    config = SimulationConfig(grid, (weak,), (Stage("collapse", "dynamic", duration_s=0.25),), (0.0, -9.81),
                              Numerics(scheme=scheme, precision=precision, cfl=0.5, arch="cpu"),
                              Output(0.25, fields=("stress", "plastic_strain")))
    with Simulation(config, _column()) as sim:
        frames = list(sim.run())
    last = frames[-1].fields
    active = last["active"].astype(bool)
    eps = last["plastic_strain"][active]
    f, sq = yield_function(last["stress"][active], eps, weak)
    tol = 1e-4 if precision == "f64" else 2e-3
    past = eps > weak.softening.residual_strain
    assert past.sum() > 10  # the collapse softened a band to its residual strength
    # inside or on the cone of the strength each particle's own plastic strain leaves it (on the
    # peak cone, with the strength not softened, the softened particles would lie outside)
    assert np.all(f <= tol * np.maximum(sq, 1.0) + 1e-6 * weak.cohesion_pa)
    assert np.sum(np.abs(f) <= tol * np.maximum(sq, 1.0) + 1e-6 * weak.cohesion_pa) > 10  # some on it


# ------------------------------------------------------------------ the project keys
BASE = """
[runout]
schema_version = 2
[domain]
size_m = [1.0, 1.0]
cell_size_m = 0.1
[materials.clay]
model = "drucker-prager"
density_kg_m3 = 2000
youngs_modulus_pa = 1e7
poisson_ratio = 0.3
cohesion_pa = 20000
friction_angle_deg = 20
dilatancy_angle_deg = 0
{extra}
[[bodies]]
name = "b"
material = "clay"
polygon_m = [[0, 0], [1, 0], [1, 0.5], [0, 0.5]]
[[stages]]
name = "run"
type = "dynamic"
duration_s = 0.1
{stage}
"""


def _load(extra="", stage=""):
    return load_project_text(BASE.format(extra=extra, stage=stage))


def test_softening_keys_reach_the_solver_with_the_peak_as_the_residual_not_given():
    from projects.build import solver_material

    project = _load('softening_law = "exponential"\nresidual_cohesion_pa = "2 kPa"\nresidual_plastic_strain = 0.1\n'
                    'softening_length_m = 0.5')
    soft = solver_material("clay", project.materials["clay"]).softening
    assert soft.law == "exponential" and soft.residual_cohesion_pa == 2000.0
    assert soft.residual_friction_angle_rad == pytest.approx(math.radians(20.0))  # not given: the peak
    assert soft.peak_strain == 0.0 and soft.residual_strain == 0.1 and soft.length_m == 0.5
    assert solver_material("clay", _load().materials["clay"]).softening is None


@pytest.mark.parametrize("extra, key, words", [
    ('residual_cohesion_pa = 1000', "residual_cohesion_pa", "needs softening_law"),
    ('softening_law = "linear"\nresidual_cohesion_pa = 1000', "residual_plastic_strain", "required"),
    ('softening_law = "linear"\nresidual_plastic_strain = 0.1', "softening_law", "needs a residual value"),
    ('softening_law = "linear"\nresidual_cohesion_pa = 30000\nresidual_plastic_strain = 0.1', "residual_cohesion_pa",
     "must be <= cohesion_pa"),
    ('softening_law = "linear"\nresidual_friction_angle_deg = 25\nresidual_plastic_strain = 0.1',
     "residual_friction_angle_deg", "must be <= friction_angle_deg"),
    ('softening_law = "linear"\nresidual_cohesion_pa = 1\npeak_plastic_strain = 0.2\nresidual_plastic_strain = 0.1',
     "residual_plastic_strain", "must be > peak_plastic_strain"),
    ('softening_law = "cubic"\nresidual_cohesion_pa = 1\nresidual_plastic_strain = 0.1', "softening_law", "linear"),
    ('softening_law = "linear"\nresidual_cohesion_pa = 1\nresidual_plastic_strain = 0.1\nsoftening_length_m = 0',
     "softening_length_m", "must be > 0"),
    ('softening_law = "linear"\nresidual_cohesion_pa = 1\nresidual_plastic_strain = -0.1', "residual_plastic_strain",
     "must be > 0"),
])
def test_bad_softening_keys_are_one_line_errors_naming_the_key(extra, key, words):
    with pytest.raises(ProjectError) as err:
        _load(extra)
    text = str(err.value)
    assert f"materials.clay.{key}" in text and words in text, text


def test_a_stage_that_lowers_the_peak_below_the_residual_is_refused():
    extra = 'softening_law = "linear"\nresidual_cohesion_pa = 5000\nresidual_plastic_strain = 0.1'
    stage = "[stages.material_changes.clay]\ncohesion_pa = 1000"
    with pytest.raises(ProjectError) as err:
        _load(extra, stage)
    assert "stages.0.material_changes.clay.residual_cohesion_pa" in str(err.value)
    _load(extra, stage + "\nresidual_cohesion_pa = 500")  # lowering both is fine


def test_softening_keys_on_an_elastic_material_are_refused():
    text = BASE.format(extra="", stage="").replace('model = "drucker-prager"', 'model = "linear-elastic"').replace(
        "cohesion_pa = 20000\nfriction_angle_deg = 20\ndilatancy_angle_deg = 0\n",
        'softening_law = "linear"\n')
    with pytest.raises(ProjectError) as err:
        load_project_text(text)
    assert "materials.clay.softening_law" in str(err.value) and "drucker-prager" in str(err.value)


def test_strength_reduction_divides_the_residual_strengths_too():
    from projects.strength import reduced_materials

    (out,) = reduced_materials((clay(),), (0,), 2.0)
    assert out.softening.residual_cohesion_pa == pytest.approx(RESIDUAL[0] / 2.0)
    assert math.tan(out.softening.residual_friction_angle_rad) == pytest.approx(math.tan(RESIDUAL[1]) / 2.0)
