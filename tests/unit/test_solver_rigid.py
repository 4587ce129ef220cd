"""Rigid bodies moved at a prescribed velocity (solver/rigid.py): a platen's reaction, its motion,
what the run's measures leave out, and the project keys that describe one.

The oedometer: an elastic column between slip sides on a slip base, pressed by a rigid platen
moving down slowly. Its state is uniaxial strain, so the axial stress is ``M eps`` with the
constrained modulus ``M = E (1 - nu) / ((1 + nu)(1 - 2 nu))`` and the platen's force ``M eps W``
(per metre out of plane), ``eps`` the column's strain. The strain is measured from the particles
(the top row's settlement over its height), since the platen meets the column where its stencil
reaches, about a cell before the particles touch.
"""

import numpy as np
import pytest

from projects.build import resolve
from projects.document import loads_project
from projects.schema import ProjectError
from solver.config import Boundary, Grid, Material, Numerics, Output, Particles, SimulationConfig, Stage
from solver.simulation import Simulation

E, NU, RHO = 1.0e6, 0.3, 2000.0
W, H = 0.5, 1.0
M = E * (1 - NU) / ((1 + NU) * (1 - 2 * NU))


def _column(h: float, platen: Material, stages, gravity=(0.0, 0.0), scheme="apic-affine", precision="f64",
            bottom="slip"):
    """The elastic column (0..W x 0..H) with four rows of ``platen`` particles on its top."""
    soil = Material("soil", "linear-elastic", RHO, E, NU)
    s = h / 2
    xs = (np.arange(int(round(W / s))) + 0.5) * s
    ys = (np.arange(int(round(H / s))) + 0.5) * s
    tops = H + (np.arange(4) + 0.5) * s
    X, Y = np.meshgrid(xs, np.r_[ys, tops])
    pos = np.c_[X.ravel(), Y.ravel()]
    mat = (pos[:, 1] > H).astype(np.int32)
    parts = Particles(pos, np.full(len(pos), s * s), mat)
    grid = Grid((0.0, 0.0), (W, 1.5), h, left=Boundary("slip"), right=Boundary("slip"), bottom=Boundary(bottom),
                top=Boundary("open"))
    cfg = SimulationConfig(grid, (soil, platen), stages, gravity,
                           Numerics(scheme=scheme, cfl=0.5, arch="cpu", precision=precision), Output(0.1))
    return cfg, parts


@pytest.mark.matrix  # a covering sample of the six (every scheme, both precisions); RUNOUT_FULL_MATRIX=1: all
@pytest.mark.parametrize("scheme", ["mpm", "apic", "apic-affine"])
@pytest.mark.parametrize("precision", ["f32", "f64"])
def test_a_platen_pressing_an_oedometer_reads_the_constrained_modulus(scheme, precision):
    v = 0.01
    platen = Material("platen", "rigid", 7850.0, 0.0, 0.0, velocity_m_s=(0.0, -v), contact=Boundary("fixed"))
    cfg, parts = _column(0.05, platen, (Stage("press", "dynamic", duration_s=0.5),), scheme=scheme,
                         precision=precision)
    soil = parts.material_ids == 0
    top = soil & (parts.positions_m[:, 1] > parts.positions_m[soil, 1].max() - 1e-9)
    with Simulation(cfg, parts) as sim:
        frames = list(sim.run())
        state = sim.engine.state(("x",))
    last = {c.contact: c for c in frames[-1].contacts}
    before = {c.contact: c for c in frames[-2].contacts}
    # the mean force over the last interval, against the strain at its middle
    settle_now = parts.positions_m[top, 1].mean() - state["x"][top, 1].mean()
    force = last["platen"].force_y_N_per_m
    strain_mid = (settle_now - 0.5 * v * 0.1) / parts.positions_m[top, 1].mean()
    assert force == pytest.approx(M * strain_mid * W, rel=0.05)
    # what the platen takes, the base gives (quasi-static: the column's inertia is small)
    assert -last["bottom"].force_y_N_per_m == pytest.approx(force, rel=0.05)
    assert force > before["platen"].force_y_N_per_m > 0.0  # the load grows with the platen's travel
    # the platen moved at its velocity, as one body (in f32 a position near 1 m takes increments
    # of 1 um a step to within its 0.06 um rounding)
    moved = state["x"][~soil] - parts.positions_m[~soil]
    travel = v * 0.5
    assert np.allclose(moved[:, 1], -travel, rtol=0.0, atol=(1e-9 if precision == "f64" else 0.01) * travel)
    assert np.ptp(moved[:, 1]) < 1e-3 * travel and np.allclose(moved[:, 0], 0.0, atol=1e-6)


def test_a_rigid_body_weighs_nothing_stands_still_in_initial_stress_stages_and_is_no_kinetic_energy():
    platen = Material("platen", "rigid", 7850.0, 0.0, 0.0, velocity_m_s=(0.0, 0.2), contact=Boundary("slip"))
    stages = (Stage("geostatic", "k0"), Stage("settle", "gravity", duration_s=0.2, damping=0.7, ramp_fraction=1e-6),
              Stage("lift", "dynamic", duration_s=0.2))
    cfg, parts = _column(0.1, platen, stages, gravity=(0.0, -9.81), bottom="fixed")
    rigid = parts.material_ids == 1
    y = parts.positions_m[:, 1]
    with Simulation(cfg, parts) as sim:
        first = next(iter(sim.run(stop_before=1)))
        stress = sim.engine.state(("s",))["s"]
        rest = list(sim.run(stop_before=2))
        x_settled = sim.engine.state(("x",))["x"]
        rest += list(sim.run())
        x = sim.engine.state(("x",))["x"]
        motion = sim.motion_at_end()
    # K0: the soil carries its own overburden alone, the platen no stress
    assert np.allclose(stress[rigid], 0.0)
    assert np.allclose(stress[~rigid, 1], -RHO * 9.81 * (H - y[~rigid]), rtol=0.02, atol=0.02 * RHO * 9.81 * 0.1)
    settled = [f for f in rest if f.diagnostics.stage == "settle"][-1]
    assert settled.diagnostics.total_mass_kg_per_m == pytest.approx(RHO * W * H, rel=1e-4)  # the soil's alone
    assert first.diagnostics.total_mass_kg_per_m == pytest.approx(RHO * W * H, rel=1e-4)
    assert np.allclose(x_settled[rigid], parts.positions_m[rigid], atol=1e-6)
    # the platen stood still in the gravity stage, then rose at 0.2 m/s for 0.2 s, leaving the
    # column (slip: it pulls nothing with it)
    assert np.allclose(x[rigid, 1] - y[rigid], 0.04, atol=1e-6)
    # the column stays at rest: the platen's own motion is not kinetic energy of the material
    assert rest[-1].diagnostics.kinetic_energy_J_per_m < 1e-3 * RHO * W * H * 0.2 ** 2
    assert motion["driven"] is True


RIGID_PROJECT = """
[runout]
schema_version = 2
[domain]
size_m = [1.0, 1.5]
cell_size_m = 0.1
gravity_m_s2 = [0.0, 0.0]
[materials.soil]
model = "linear-elastic"
density_kg_m3 = 2000
youngs_modulus_pa = 1e6
poisson_ratio = 0.3
[materials.platen]
model = "rigid"
density_kg_m3 = 7850
velocity_m_s = [0.0, -0.01]
{extra}
[[bodies]]
name = "column"
material = "soil"
polygon_m = [[0, 0], [1, 0], [1, 1], [0, 1]]
[[bodies]]
name = "plate"
material = "platen"
polygon_m = [[0, 1], [1, 1], [1, 1.1], [0, 1.1]]
[[stages]]
name = "press"
type = "dynamic"
duration_s = 0.1
{stage}
"""


def test_a_rigid_material_builds_into_the_solvers_body_with_its_contact():
    project = loads_project(RIGID_PROJECT.format(extra='contact = { type = "friction", friction_angle_deg = 20 }',
                                                 stage=""))
    cfg = resolve(project).config
    platen = next(m for m in cfg.materials if m.name == "platen")
    assert platen.rigid and platen.velocity_m_s == (0.0, -0.01)
    assert platen.contact.kind == "friction" and platen.contact.friction_angle_rad == pytest.approx(np.radians(20))


def problems_of_text(text: str) -> list[str]:
    with pytest.raises(ProjectError) as info:
        loads_project(text)
    return [str(p) for p in info.value.problems]


@pytest.mark.parametrize(("extra", "stage", "expected"), [
    ("youngs_modulus_pa = 1e6", "", 'materials.platen.youngs_modulus_pa = 1000000.0: not used by model "rigid"'),
    ('contact = { type = "friction" }', "", "materials.platen.contact.friction_angle_deg: required for type"),
    ('contact = "open"', "", "materials.platen.contact"),
    ("", "[stages.material_changes.platen]\ncohesion_pa = 1.0",
     "stages.0.material_changes.platen.cohesion_pa = 1.0: a rigid body changes only its velocity_m_s"),
    ("", "[stages.material_changes.soil]\nvelocity_m_s = [0, 1]",
     'stages.0.material_changes.soil.velocity_m_s = [0, 1]: only allowed with model "rigid"'),
])
def test_a_rigid_materials_keys_are_checked_with_one_line_each(extra, stage, expected):
    problems = problems_of_text(RIGID_PROJECT.format(extra=extra, stage=stage))
    assert any(p.startswith(expected) for p in problems), problems


def test_a_project_of_rigid_bodies_alone_is_refused_with_one_line():
    text = RIGID_PROJECT.format(extra="", stage="").replace('material = "soil"', 'material = "platen"')
    assert problems_of_text(text) == ['bodies: every body is of a rigid material: at least one must be of a '
                                      'deformable one ("linear-elastic" or "drucker-prager")']


def test_the_deformable_models_still_need_their_stiffness():
    text = RIGID_PROJECT.format(extra="", stage="").replace("youngs_modulus_pa = 1e6\n", "", 1)
    problems = problems_of_text(text)
    assert any(p.startswith('materials.soil.youngs_modulus_pa: required for model "linear-elastic"') for p in problems)
    text = RIGID_PROJECT.format(extra="", stage="").replace('model = "linear-elastic"',
                                                              'model = "linear-elastic"\nvelocity_m_s = [1, 0]')
    assert any(p.startswith('materials.soil.velocity_m_s = [1, 0]: only allowed with model "rigid"')
               for p in problems_of_text(text))


def test_the_deposit_measures_leave_a_rigid_body_out(tmp_path):
    from projects.measures import top_height
    from projects.results import Results
    from projects.runner import run_project

    project = loads_project(RIGID_PROJECT.format(extra="", stage=""))
    result = run_project(project, tmp_path / "run")
    assert result.status == "completed", result.message
    assert result.summary["rigid_materials"] == ["platen"]
    results = Results(tmp_path / "run")
    frame = results.frame(-1)
    keep = results.measured(frame)
    assert keep.sum() == (np.asarray(frame["material_id"]) == 0).sum() > 0
    spacing = result.summary["particle_spacing_m"]
    # the column's top (1 m, pressed by 1 mm), not the platen's (1.1 m)
    assert top_height(frame["positions"], keep, spacing) == pytest.approx(1.0, abs=0.01)
    assert top_height(frame["positions"], frame["active"], spacing) == pytest.approx(1.1, abs=0.01)


def test_a_run_with_a_rigid_body_resumes_from_a_checkpoint_to_the_same_frames():
    platen = Material("platen", "rigid", 7850.0, 0.0, 0.0, velocity_m_s=(0.0, -0.01), contact=Boundary("fixed"))
    stages = (Stage("geostatic", "k0"), Stage("press", "dynamic", duration_s=0.3))
    cfg, parts = _column(0.1, platen, stages, gravity=(0.0, -9.81), precision="f32")
    frames, checkpoints = [], []
    with Simulation(cfg, parts) as sim:
        for frame in sim.run():
            frames.append(frame)
            checkpoints.append(sim.checkpoint() if sim.can_checkpoint else None)
    index = next(i for i, c in enumerate(checkpoints) if c is not None and 0 < i < len(frames) - 1)
    with Simulation(cfg, parts) as sim:
        sim.restore(checkpoints[index])
        rest = list(sim.run())  # the platen moves on after the restore
    assert len(rest) == len(frames) - index - 1
    for a, b in zip(frames[index + 1:], rest):
        assert a.diagnostics == b.diagnostics
        assert a.contacts == b.contacts
        for name in a.fields:
            np.testing.assert_array_equal(a.fields[name], b.fields[name], err_msg=name)


def test_a_rigid_body_stands_still_while_a_strength_reduction_trial_advances_the_state():
    platen = Material("platen", "rigid", 7850.0, 0.0, 0.0, velocity_m_s=(0.0, -0.5), contact=Boundary("fixed"))
    cfg, parts = _column(0.1, platen, (Stage("press", "dynamic", duration_s=0.05),), precision="f64")
    rigid = parts.material_ids == 1
    with Simulation(cfg, parts) as sim:
        list(sim.run())  # the dynamic stage moves the platen down 2.5 cm
        moved = sim.engine.state(("x",))["x"][rigid].copy()
        sim.advance(0.05)  # a trial: the state under full gravity, the body held
        held = sim.engine.state(("x",))["x"][rigid]
    assert np.allclose(moved[:, 1] - parts.positions_m[rigid, 1], -0.025, atol=1e-9)
    assert np.array_equal(held, moved)


def test_a_rigid_body_lifted_out_of_the_grid_drives_nothing_at_the_end():
    platen = Material("platen", "rigid", 7850.0, 0.0, 0.0, velocity_m_s=(0.0, 2.0), contact=Boundary("slip"))
    cfg, parts = _column(0.1, platen, (Stage("lift", "dynamic", duration_s=0.3),))
    with Simulation(cfg, parts) as sim:
        frames = list(sim.run())
        motion = sim.motion_at_end()
    assert frames[-1].diagnostics.lost_particles == int((parts.material_ids == 1).sum())  # out through the top
    assert motion["driven"] is False


@pytest.mark.parametrize(("velocity", "expected"), [
    ("[0.0, -0.01]", None),
    ("[0.0, -50.0]", "is faster than the slowest P-wave speed of the materials (25.9 m/s)"),
    ("[0.0, -1e6]", "the rigid body crosses the whole domain (1.5 m)"),
])
def test_a_rigid_body_driven_too_fast_is_warned_about(velocity, expected):
    from projects.checks import project_warnings

    text = RIGID_PROJECT.format(extra="", stage="").replace("velocity_m_s = [0.0, -0.01]", f"velocity_m_s = {velocity}")
    found = [w for w in project_warnings(loads_project(text)) if w.startswith("materials.platen.velocity_m_s")]
    if expected is None:
        assert found == []
    else:
        assert len(found) == 1 and expected in found[0], found


def test_bishops_section_and_the_surcharged_surface_leave_a_rigid_body_out():
    from projects.strength import limit_equilibrium
    from solver.config import Surcharge

    # a cohesive slope (a face from (0, 1) down to (1, 0.4)) under the plate
    text = RIGID_PROJECT.format(extra="", stage="").replace(
        'model = "linear-elastic"', 'model = "drucker-prager"\ncohesion_pa = 2000\nfriction_angle_deg = 20').replace(
        "polygon_m = [[0, 0], [1, 0], [1, 1], [0, 1]]", "polygon_m = [[0, 0], [1, 0], [1, 0.4], [0, 1]]")
    slope = loads_project(text)
    heavy = loads_project(text.replace('model = "rigid"\ndensity_kg_m3 = 7850\nvelocity_m_s = [0.0, -0.01]\n',
                                       'model = "linear-elastic"\ndensity_kg_m3 = 7850\nyoungs_modulus_pa = 1e9\n'
                                       'poisson_ratio = 0.3\n'))
    alone = loads_project(text.replace('[[bodies]]\nname = "plate"\nmaterial = "platen"\n'
                                       'polygon_m = [[0, 1], [1, 1], [1, 1.1], [0, 1.1]]\n', ''))
    factor = limit_equilibrium(slope, gravity_m_s2=(0.0, -9.81)).factor
    assert factor == pytest.approx(limit_equilibrium(alone, gravity_m_s2=(0.0, -9.81)).factor, rel=1e-12)
    assert factor != pytest.approx(limit_equilibrium(heavy, gravity_m_s2=(0.0, -9.81)).factor, rel=1e-3)
    # a surcharge on the column's top is carried by the column's top particles, not the plate's
    platen = Material("platen", "rigid", 7850.0, 0.0, 0.0, velocity_m_s=(0.0, 0.0), contact=Boundary("fixed"))
    cfg, parts = _column(0.1, platen, (Stage("hold", "dynamic", duration_s=0.01),), gravity=(0.0, -9.81))
    with Simulation(cfg, parts, surcharge_support=True) as sim:
        sim.set_loads((Surcharge("q", 0.0, W, 10e3),))
        forces = sim.surcharge_forces()
    rigid = parts.material_ids == 1
    assert np.allclose(forces[rigid], 0.0)
    assert forces[~rigid, 1].sum() == pytest.approx(-10e3 * W, rel=1e-6)
