"""The shipped example projects: they load, round-trip, build, and match the paper's numbers."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from geometry.polygons import owner_of_points, polygon_area
from projects.build import estimate, resolve
from projects.document import dumps_project, load_project, loads_project, save_project

EXAMPLES = Path(__file__).resolve().parents[2] / "projects" / "examples"
NAMES = ["bui2008_aluminium_bars", "sand_column", "slope_sun_song_2015", "tiny_column", "slope_fos", "debris_barrier",
         "reservoir_drawdown", "rain_water_table", "sensitive_clay_spread", "biaxial_softening_clay"]
PAPER_SCENES = NAMES[:3]


def path_of(name: str) -> Path:
    return EXAMPLES / f"{name}.toml"


def test_the_examples_are_all_there():
    assert sorted(p.stem for p in EXAMPLES.glob("*.toml")) == sorted(NAMES)


@pytest.mark.parametrize("name", NAMES)
def test_round_trip(name, tmp_path):
    project = load_project(path_of(name))
    saved = tmp_path / f"{name}.toml"
    save_project(project, saved)
    again = load_project(saved)
    assert again == project
    assert dumps_project(again) == saved.read_text(encoding="utf-8")
    assert loads_project(dumps_project(project)) == project


@pytest.mark.parametrize("name", PAPER_SCENES)
def test_every_parameter_says_where_it_comes_from(name):
    """Each physical parameter line carries a comment (its source or that it is assumed)."""
    keys = (
        "size_m", "cell_size_m", "density_kg_m3", "youngs_modulus_pa", "poisson_ratio", "cohesion_pa",
        "friction_angle_deg", "dilatancy_angle_deg", "per_cell", "time_step_s", "duration_s",
        "interval_s", "left", "right", "bottom", "top",
    )
    text = path_of(name).read_text(encoding="utf-8")
    for line in text.splitlines():
        key = line.split("=", 1)[0].strip()
        if key in keys:
            assert "#" in line, f"{name}: no comment on {line!r}"
    assert re.search(r"paper|Table 1", text)


def particles_of(name: str):
    project = load_project(path_of(name))
    return project, resolve(project)


def test_bars_match_the_paper():
    project, run = particles_of("bui2008_aluminium_bars")
    assert len(run.particles) == 20000  # paper: 20000 particles, 1 mm apart
    assert project.domain.size_m == (0.8, 0.15) and project.domain.cell_size_m == 0.002
    assert project.numerics.time_step_s == 2e-5
    assert run.config.grid.bottom.friction_angle_rad == pytest.approx(math.radians(19.8))
    assert run.config.grid.left.kind == "slip" and run.config.grid.right.kind == "slip"
    assert run.config.grid.top.kind == "open"
    assert [s.kind for s in run.config.stages] == ["k0", "dynamic"]
    assert run.config.stages[0].k0 is None  # 1 - sin(phi) from the material
    assert run.config.materials[0].default_k0 == pytest.approx(1 - math.sin(math.radians(19.8)))
    assert run.config.stages[1].duration_s == 1.0 and project.output.interval_s == 0.01
    assert run.particles.volumes_m2.sum() == pytest.approx(0.2 * 0.1)


def test_sand_column_matches_the_paper():
    project, run = particles_of("sand_column")
    assert len(run.particles) == 2000  # paper: 2000 particles
    assert run.particles.volumes_m2.sum() == pytest.approx(500.0)
    assert estimate(project)["steps"] == 24000  # paper: 24000 steps of 0.02 ms
    sand = project.materials["sand"]
    assert (sand.density_kg_m3, sand.youngs_modulus_pa, sand.poisson_ratio) == (2000.0, 20.0e6, 0.3)
    assert (sand.cohesion_pa, sand.friction_angle_deg, sand.dilatancy_angle_deg) == (0.0, 19.8, 0.0)
    # The column starts above the ground and lands within the run (free fall over the gap).
    gap = run.particles.positions_m[:, 1].min() - 0.25
    assert 0.0 < gap and math.sqrt(2 * gap / 9.81) < 0.48


def test_slope_matches_the_paper():
    project, run = particles_of("slope_sun_song_2015")
    # paper: 39051 particles, one per sub-cell whose centre lies in the slope; the clipped lattice
    # adds one in each of the 92 sub-cells the slope face cuts with the centre outside, so that the
    # particles' volumes sum to the slope's area
    h = project.domain.cell_size_m / project.particles.per_cell
    sub_cell_centres = (np.floor(run.particles.positions_m / h) + 0.5) * h
    slope = [np.asarray(body.polygon_m) for body in project.bodies]
    assert (owner_of_points(sub_cell_centres, slope) >= 0).sum() == 39051
    assert len(run.particles) == 39051 + 92
    assert run.particles.volumes_m2.sum() == pytest.approx(sum(polygon_area(p) for p in slope), rel=1e-12)
    assert project.domain.cell_size_m == 1.0 and project.particles.per_cell == 2
    assert project.numerics.time_step_s == 1e-3  # 0.18 of its critical step (the slope study's step)
    assert run.config.grid.bottom.kind == "fixed"
    assert run.config.grid.left.kind == "slip" and run.config.grid.right.kind == "slip"
    gravity, landslide, settling = run.config.stages
    assert gravity.kind == "gravity" and gravity.duration_s == 10.0
    assert landslide.kind == "dynamic" and settling.kind == "dynamic"
    assert landslide.duration_s + settling.duration_s == 50.0
    assert landslide.damping == 0.0 and settling.damping > 0.0  # damping from 40 s on
    assert landslide.materials is not None and landslide.materials[0].cohesion_pa == 0.0
    assert run.config.materials[0].cohesion_pa > 0.0
    # Geostatic vertical stress at the deepest particle: about the reported 1345 kPa.
    y = run.particles.positions_m[:, 1]
    rho = project.materials["soil"].density_kg_m3
    sigma_v = rho * 9.81 * (y.max() + 0.25 - y.min())
    assert sigma_v == pytest.approx(1345e3, rel=0.01)
    # Slope height about 63.6 m / 1.5; final angle 16 deg below the friction angle.
    polygon = np.asarray(project.bodies[0].polygon_m)
    toe_level = sorted(set(polygon[:, 1]))[1]
    assert polygon[:, 1].max() - toe_level == pytest.approx(63.6 / 1.5, rel=0.02)
    assert project.materials["soil"].friction_angle_deg > 16.0


def test_tiny_column_is_tiny():
    project, run = particles_of("tiny_column")
    e = estimate(project)
    assert 100 <= len(run.particles) <= 500
    assert e["simulated_time_s"] == 0.05 and e["steps"] <= 500
    assert [s.kind for s in run.config.stages] == ["k0", "dynamic"]


def test_sensitive_clay_spread_softens_regularised_and_stands_at_peak_on_paper():
    project, run = particles_of("sensitive_clay_spread")
    from projects.checks import project_warnings

    clay = project.materials["sensitive_clay"]
    assert clay.softening_law == "linear" and clay.friction_angle_deg == 0.0
    assert clay.cohesion_pa / clay.residual_cohesion_pa == pytest.approx(6.25)
    # regularised with a length of at least the cell size: no softening warning
    assert clay.softening_length_m >= project.domain.cell_size_m
    assert not [w for w in project_warnings(project) if "soften" in w]
    # the trigger remoulds the toe only, to the clay's residual strength
    [trigger] = [s for s in project.stages if s.material_changes]
    assert set(trigger.material_changes) == {"toe"}
    assert trigger.material_changes["toe"].cohesion_pa == clay.residual_cohesion_pa
    # gamma H / c_p = 7.2: a vertical scarp of the bank's 10 m height stands at peak only below
    # 3.83 c_p / gamma = 5.3 m (Taylor), so each scarp the slides leave fails in turn
    height = max(y for _, y in project.bodies[1].polygon_m)
    gamma = clay.density_kg_m3 * 9.81
    assert gamma * height / clay.cohesion_pa == pytest.approx(7.2, rel=0.01)
    assert 3.83 * clay.cohesion_pa / gamma < height
    assert 6_000 < len(run.particles) < 10_000
