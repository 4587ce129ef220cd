"""Building the solver input from a project: units, stages, material ids, seeding, estimates."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from geometry.polygons import polygon_area, polygon_perimeter
from geometry.templates import SlopeLayer, slope_profile
from projects.build import ResolvedRun, estimate, material_tables, resolve, solver_config
from projects.document import apply_overrides, loads_project
from projects.schema import ProjectError, validate_project
from solver import config as sc

CELL = 0.5
PER_CELL = 2


def material(phi: float, rho: float = 2000.0) -> dict:
    return {
        "model": "drucker-prager",
        "density_kg_m3": rho,
        "youngs_modulus_pa": 2.0e7,
        "poisson_ratio": 0.3,
        "cohesion_pa": 1000.0,
        "friction_angle_deg": phi,
        "dilatancy_angle_deg": 0.0,
    }


def layered_data() -> dict:
    """A slope in three layers; the materials are listed in another order than the bodies."""
    bodies = slope_profile(
        height_m=6.0,
        angle_deg=35.0,
        crest_length_m=4.0,
        toe_length_m=5.0,
        foundation_depth_m=3.0,
        layers=[SlopeLayer("top", 2.5), SlopeLayer("middle", 3.0)],
    )
    assert [name for name, _ in bodies] == ["top", "middle", "foundation"]
    layer_material = {"top": "silt", "middle": "sand", "foundation": "rock"}
    return {
        "runout": {"schema_version": 1, "title": "layers"},
        "domain": {
            "size_m": [20.0, 12.0],
            "cell_size_m": CELL,
            "boundaries": {"bottom": {"type": "friction", "friction_angle_deg": 30.0}},
        },
        "materials": {
            "rock": material(40.0, 2500.0),
            "sand": material(30.0),
            "silt": {
                "model": "linear-elastic",
                "density_kg_m3": 1800.0,
                "youngs_modulus_pa": 1.0e7,
                "poisson_ratio": 0.25,
            },
        },
        "bodies": [
            {
                "name": name,
                "material": layer_material[name],
                "polygon_m": polygon.tolist(),
                "initial_velocity_m_s": [1.5, 0.0] if name == "top" else [0.0, 0.0],
            }
            for name, polygon in bodies
        ],
        "particles": {"per_cell": PER_CELL},
        "numerics": {"time_step_s": 1e-4, "arch": "cpu"},
        "stages": [
            {"type": "gravity", "duration_s": 1.0},
            {"name": "trigger", "type": "dynamic", "duration_s": 2.0,
             "material_changes": {"sand": {"cohesion_pa": 0.0, "friction_angle_deg": 25.0}}},
            {"name": "run-out", "type": "dynamic", "duration_s": 3.0,
             "damping": {"type": "local", "coefficient": 0.2},
             "stop_when_kinetic_energy_below": 0.01, "min_duration_s": 1.0},
        ],
    }


@pytest.fixture(scope="module")
def layered():
    project = validate_project(layered_data())
    return project, resolve(project)


def test_material_ids_follow_the_layers(layered):
    project, run = layered
    assert run.material_names == ("rock", "sand", "silt")
    assert run.body_names == ("top", "middle", "foundation")
    y = run.particles.positions_m[:, 1]
    ids = run.particles.material_ids
    # Layer boundaries: crest at 9 m, top layer down to 6.5 m, middle down to 3.5 m.
    assert set(ids[y > 6.5]) == {2}  # silt
    assert set(ids[(y < 6.5) & (y > 3.5)]) == {1}  # sand
    assert set(ids[y < 3.5]) == {0}  # rock
    # Material of each particle = material of its body.
    body_material = np.array([2, 1, 0])
    assert np.array_equal(ids, body_material[run.particle_body])


def test_volumes_sum_to_each_body_area(layered):
    project, run = layered
    h = CELL / PER_CELL
    for index, body in enumerate(project.bodies):
        polygon = np.asarray(body.polygon_m)
        volume = run.particles.volumes_m2[run.particle_body == index].sum()
        assert volume == pytest.approx(polygon_area(polygon), rel=1e-12)
    # whole sub-cells inside, parts of sub-cells along the outlines (the layers' inclined faces)
    volumes = run.particles.volumes_m2
    assert np.all(volumes <= h * h * (1 + 1e-12))
    whole = np.isclose(volumes, h * h, rtol=1e-12, atol=0.0)
    assert 0 < (~whole).sum() < 0.1 * len(volumes)


def test_particles_lie_inside_the_grid_and_bodies(layered):
    project, run = layered
    pos = run.particles.positions_m
    assert pos.shape == (len(run.particles), 2) and len(run.particles) > 1000
    assert np.all(pos >= 0.0) and np.all(pos[:, 0] <= 20.0) and np.all(pos[:, 1] <= 9.0)


def test_initial_velocity_per_body(layered):
    _, run = layered
    v = run.particles.velocities_m_s
    top = run.particle_body == 0
    assert np.all(v[top] == [1.5, 0.0])
    assert np.all(v[~top] == 0.0)


def test_degrees_become_radians_once(layered):
    _, run = layered
    rock, sand, silt = run.config.materials
    assert isinstance(rock, sc.Material)
    assert rock.friction_angle_rad == pytest.approx(math.radians(40.0))
    assert sand.friction_angle_rad == pytest.approx(math.radians(30.0))
    assert silt.model == "linear-elastic" and silt.friction_angle_rad == 0.0 and silt.cohesion_pa == 0.0
    assert silt.tensile_strength_pa is None
    bottom = run.config.grid.bottom
    assert bottom == sc.Boundary("friction", math.radians(30.0))
    assert run.config.grid.left == sc.Boundary("slip") and run.config.grid.top == sc.Boundary("open")


def test_stages_resolve_changes_and_defaults(layered):
    _, run = layered
    gravity, trigger, runout = run.config.stages
    assert gravity == sc.Stage(name="gravity", kind="gravity", duration_s=1.0, damping=0.7)
    assert trigger.kind == "dynamic" and trigger.damping == 0.0 and trigger.duration_s == 2.0
    # The full table, with sand changed and the others as in the file.
    assert trigger.materials is not None and len(trigger.materials) == 3
    assert trigger.materials[0] == run.config.materials[0]
    assert trigger.materials[1].cohesion_pa == 0.0
    assert trigger.materials[1].friction_angle_rad == pytest.approx(math.radians(25.0))
    assert trigger.materials[1].density_kg_m3 == 2000.0
    # No changes: the table in force carries over (the solver keeps the trigger's changes).
    assert runout.materials is None
    assert runout.damping == 0.2
    assert runout.stop_when_kinetic_energy_below == 0.01 and runout.min_duration_s == 1.0


def test_material_tables_persist_changes():
    project = validate_project(layered_data())
    tables = material_tables(project)
    assert tables[0]["sand"].cohesion_pa == 1000.0
    assert tables[1]["sand"].cohesion_pa == 0.0 and tables[2]["sand"].cohesion_pa == 0.0
    assert tables[2]["rock"] == project.materials["rock"]


def test_numerics_output_gravity_and_arch_override(layered):
    project, run = layered
    numerics = run.config.numerics
    assert numerics.time_step_s == 1e-4 and numerics.cfl is None and numerics.arch == "cpu"
    assert run.config.gravity_m_s2 == (0.0, -9.81)
    assert run.config.output == sc.Output(interval_s=0.01, fields=sc.OUTPUT_FIELDS)
    assert solver_config(project, arch_override="gpu").numerics.arch == "gpu"
    with pytest.raises(ProjectError, match='numerics.arch = "tpu": must be one of'):
        solver_config(project, arch_override="tpu")
    adaptive = solver_config(apply_overrides(project, ["numerics.cfl=0.4"]))
    assert adaptive.numerics.cfl == 0.4 and adaptive.numerics.time_step_s is None


def test_k0_stage_value(layered):
    project, _ = layered
    data = project.to_dict()
    data["stages"][0] = {"type": "k0", "k0": 0.45}
    config = solver_config(validate_project(data))
    assert config.stages[0] == sc.Stage(name="k0", kind="k0", k0=0.45)


def test_built_run_is_frozen(layered):
    _, run = layered
    assert isinstance(run, ResolvedRun)
    with pytest.raises(dataclasses.FrozenInstanceError):
        run.particles = None  # type: ignore[misc]


def test_later_body_owns_the_overlap():
    data = layered_data()
    data["bodies"].append(
        {"name": "block", "material": "rock", "polygon_m": [[0.0, 7.0], [2.0, 7.0], [2.0, 9.0], [0.0, 9.0]]}
    )
    run = resolve(validate_project(data))
    pos = run.particles.positions_m
    in_block = (pos[:, 0] < 2.0) & (pos[:, 1] > 7.0)
    assert np.all(run.particle_body[in_block] == 3)
    assert np.all(run.particles.material_ids[in_block] == 0)


def test_body_without_particles_is_an_error():
    data = layered_data()
    # covered entirely by a later body
    data["bodies"].insert(0, {"name": "hidden", "material": "rock", "polygon_m": [[15.0, 1.0], [15.5, 1.0], [15.5, 1.5]]})
    with pytest.raises(ProjectError) as info:
        resolve(validate_project(data))
    assert [str(p) for p in info.value.problems] == [
        "bodies.0.polygon_m: receives no particles: covered by later bodies or too small for the particle "
        "spacing (0.25 m)"
    ]


def test_a_body_smaller_than_a_sub_cell_gets_its_area():
    data = layered_data()
    sliver = [[15.0, 10.0], [15.1, 10.0], [15.1, 10.1]]  # 0.005 m2, under a sub-cell of 0.25 m
    data["bodies"].append({"name": "sliver", "material": "rock", "polygon_m": sliver})
    run = resolve(validate_project(data))
    volumes = run.particles.volumes_m2[run.particle_body == 3]
    assert len(volumes) >= 1 and volumes.sum() == pytest.approx(0.005, rel=1e-9)


def test_gauss_seeding_volumes_sum_to_area():
    data = layered_data()
    data["particles"]["seeding"] = "gauss"
    project = validate_project(data)
    run = resolve(project)
    for index, body in enumerate(project.bodies):
        volume = run.particles.volumes_m2[run.particle_body == index].sum()
        assert volume == pytest.approx(polygon_area(np.asarray(body.polygon_m)), rel=1e-9)


MINIMAL = """\
[runout]
schema_version = 1
[domain]
size_m = [2.0, 1.0]
cell_size_m = 0.1
[materials.soil]
model = "drucker-prager"
density_kg_m3 = 2000.0
youngs_modulus_pa = 2.0e7
poisson_ratio = 0.3
cohesion_pa = 0.0
friction_angle_deg = 30.0
[[bodies]]
name = "b"
material = "soil"
polygon_m = [[0.0, 0.0], [0.5, 0.0], [0.5, 0.4], [0.0, 0.4]]
[[stages]]
type = "k0"
[[stages]]
type = "dynamic"
duration_s = 0.25
[output]
interval_s = 0.1
"""


def test_estimate_with_time_step():
    project = apply_overrides(loads_project(MINIMAL), ["numerics.time_step_s=1e-3"])
    e = estimate(project)
    assert e["particles"] == 80  # 0.2 m2 at 400 particles per m2
    assert e["grid_shape"] == (20, 10) and e["grid_cells"] == 200
    assert e["time_step_s"] == 1e-3 and e["time_step_source"] == "time_step_s"
    assert e["steps"] == 250 and e["simulated_time_s"] == 0.25
    assert e["frames"] == 3
    assert e["particles"] == len(resolve(project).particles)


def test_estimate_with_cfl_uses_the_p_wave_speed():
    project = loads_project(MINIMAL)  # cfl 0.5 by default
    e = estimate(project)
    k = 2.0e7 / (3 * (1 - 0.6))
    g = 2.0e7 / (2 * 1.3)
    c_p = math.sqrt((k + 4 * g / 3) / 2000.0)
    assert e["max_p_wave_speed_m_s"] == pytest.approx(c_p)
    assert e["time_step_s"] == pytest.approx(0.5 * 0.1 / c_p)
    assert e["time_step_source"] == "cfl"
    assert e["steps"] == math.ceil(0.25 / e["time_step_s"])


def test_estimate_counts_stiffer_materials_of_later_stages():
    project = apply_overrides(
        loads_project(MINIMAL), ["stages.1.material_changes.soil.youngs_modulus_pa=8.0e7"]
    )
    base = estimate(loads_project(MINIMAL))
    stiff = estimate(project)
    assert stiff["max_p_wave_speed_m_s"] == pytest.approx(2.0 * base["max_p_wave_speed_m_s"])


@pytest.mark.parametrize("where", ["materials.soil", "stages.1.material_changes.soil"])
@pytest.mark.parametrize("ratio,frequency", [(0.05, 2.0), (0.2, 0.5)])
def test_estimate_counts_the_shorter_step_of_a_damped_material(where, ratio, frequency):
    # the solver's own limit (solver.config.Material.critical_time_step_s), in whichever stage
    project = apply_overrides(loads_project(MINIMAL), [f"{where}.damping_ratio={ratio}",
                                                       f"{where}.damping_frequency_hz={frequency}"])
    base = estimate(loads_project(MINIMAL))
    damped = estimate(project)
    beta = ratio / (math.pi * frequency)
    xi = beta * base["max_p_wave_speed_m_s"] / 0.1
    assert damped["time_step_s"] == pytest.approx(base["time_step_s"] * (math.sqrt(1 + xi * xi) - xi))
    assert damped["steps"] == math.ceil(0.25 / damped["time_step_s"])
    assert damped["memory_bytes"] > base["memory_bytes"]  # the damping stress per particle
    config = solver_config(project)
    assert damped["time_step_s"] == pytest.approx(0.5 * min(
        m.critical_time_step_s(0.1) for m in (*config.materials, *(config.stages[1].materials or ()))))
