"""Water in the project file: the keys, their one-line errors, and the water each stage leaves."""

import pytest

from projects.build import has_water, solver_config, solver_water
from projects.document import load_project
from projects.schema import ProjectError
from solver.config import Water

TINY = "projects/examples/tiny_column.toml"
LINE = "water.phreatic_line_m=[[0, 0.1], [1, 0.1]]"


def problems(overrides):
    with pytest.raises(ProjectError) as err:
        load_project(TINY, overrides)
    return [str(p) for p in err.value.problems]


@pytest.mark.parametrize("overrides, expected", [
    (["water.phreatic_line_m=[[0, 0.1], [0, 0.2]]"],
     "water.phreatic_line_m = [[0, 0.1], [0, 0.2]]: x must increase from point to point (a water line is one "
     "height at each x): point 1 [0, 0.2] does not lie right of point 0 [0, 0.1]"),
    (["water.phreatic_line_m=[[0, 0.1], [1, 0.2], [0.5, 0.3]]"],
     "water.phreatic_line_m = [[0, 0.1], [1, 0.2], [0.5, 0.3]]: x must increase from point to point (a water line "
     "is one height at each x): point 2 [0.5, 0.3] does not lie right of point 1 [1, 0.2]"),
    (["water.phreatic_line_m=[[0, 0.1]]"], "water.phreatic_line_m = [[0, 0.1]]: needs at least 2 points, got 1"),
    ([LINE, "materials.sand.saturated_density_kg_m3=1500"],
     "materials.sand.saturated_density_kg_m3 = 1500.0: must be >= density_kg_m3 (2000): below the water table a "
     "soil's pores hold water"),
    ([LINE, "materials.sand.ru=1.0"], "materials.sand.ru = 1.0: must be >= 0 and < 1"),
    ([LINE, "water.unit_weight_n_m3=0"], "water.unit_weight_n_m3 = 0: must be > 0"),
    ([LINE, 'water.unit_weight_n_m3="9.81 kg"'],
     "water.unit_weight_n_m3 = \"9.81 kg\": unknown unit 'kg'; use N/m3 or kN/m3"),
    ([LINE, "water.inclined_line_correction=1"], "water.inclined_line_correction = 1: must be true or false"),
    (["stages.1.water.phreatic_line_m=[[0, 0.2], [1, 0.2]]"],
     "stages.1.water: a stage moves the water of [water]: add a [water] table with the phreatic_line_m at the start"),
    ([LINE, "stages.1.water={}"],
     "stages.1.water: needs phreatic_line_m or free_water_line_m (where the stage moves it)"),
    ([LINE, "water.level_m=3"], "water.level_m: unknown key; allowed: phreatic_line_m, free_water_line_m, "
     "unit_weight_n_m3, inclined_line_correction"),
])
def test_bad_water_input_gets_one_line_naming_the_key(overrides, expected):
    assert problems(overrides) == [expected]


def test_a_saturated_density_change_is_checked_against_the_density_in_force():
    assert problems([LINE, "stages.1.material_changes.sand.saturated_density_kg_m3=1000"]) == [
        "stages.1.material_changes.sand.saturated_density_kg_m3 = 1000.0: must be >= density_kg_m3 (2000): below the "
        "water table a soil's pores hold water"]


def test_units_are_read_for_the_water_and_the_saturated_density():
    project = load_project(TINY, [LINE, 'water.unit_weight_n_m3="10 kN/m3"',
                                  'materials.sand.saturated_density_kg_m3="21 kN/m3"'])
    assert project.water.unit_weight_n_m3 == 10000.0
    assert project.materials["sand"].saturated_density_kg_m3 == pytest.approx(21000.0 / 9.81)


def test_each_stage_leaves_the_water_where_it_moved_it():
    project = load_project(TINY, [LINE, "stages.1.water.phreatic_line_m=[[0, 0.3], [1, 0.3]]",
                                  "stages.1.water.free_water_line_m=[[0, 0.05], [1, 0.05]]"])
    start, after_k0, after_run = solver_water(project)
    assert start == Water(((0.0, 0.1), (1.0, 0.1)))
    assert after_k0 == start
    assert after_run.phreatic_line_m == ((0.0, 0.3), (1.0, 0.3))
    assert after_run.free_water == ((0.0, 0.05), (1.0, 0.05))
    config = solver_config(project)
    assert config.water == start and config.stages[0].water is None and config.stages[1].water == after_run
    assert config.has_water and has_water(project)


def test_a_dry_project_has_no_water_anywhere():
    project = load_project(TINY)
    config = solver_config(project)
    assert not has_water(project) and not config.has_water and config.water is None
    assert solver_water(project) == [None] * (len(project.stages) + 1)


def test_ru_alone_makes_a_wet_run():
    project = load_project(TINY, ["materials.sand.ru=0.2"])
    assert has_water(project) and solver_config(project).has_water


def test_a_saved_water_project_reads_back_the_same(tmp_path):
    from projects.document import save_project

    project = load_project(TINY, [LINE, "water.free_water_line_m=[[0, 0.2], [0.5, 0.25], [1, 0.2]]",
                                  "water.inclined_line_correction=true",
                                  "stages.1.water.phreatic_line_m=[[0, 0.3], [1, 0.3]]",
                                  "materials.sand.saturated_density_kg_m3=2200", "materials.sand.ru=0.1"])
    path = tmp_path / "wet.toml"
    save_project(project, path)
    again = load_project(path)
    assert again == project
