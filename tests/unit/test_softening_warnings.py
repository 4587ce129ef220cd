"""``runout validate``'s warnings on strain softening: a softening material without a softening length
(the result depends on the cell size; the remedy named), and one whose length is shorter than the
cell size; none where the length is given and at least a cell, or where nothing softens."""

from __future__ import annotations

import copy

from typer.testing import CliRunner

from projects.checks import project_warnings
from projects.document import save_project
from projects.schema import validate_project

CLAY = {"model": "drucker-prager", "density_kg_m3": 1800.0, "youngs_modulus_pa": 6.0e6, "poisson_ratio": 0.45,
        "cohesion_pa": 25000.0, "friction_angle_deg": 0.0, "softening_law": "linear",
        "residual_cohesion_pa": 2500.0, "residual_plastic_strain": 0.5, "softening_length_m": 1.0}
BASE = {
    "runout": {"schema_version": 2, "title": "softening"},
    "domain": {"origin_m": [0.0, 0.0], "size_m": [20.0, 6.0], "cell_size_m": 0.5},
    "materials": {"clay": CLAY, "sand": {"model": "drucker-prager", "density_kg_m3": 2000.0,
                                         "youngs_modulus_pa": 1.0e7, "poisson_ratio": 0.3, "cohesion_pa": 0.0,
                                         "friction_angle_deg": 30.0}},
    "bodies": [{"name": "ground", "material": "clay", "polygon_m": [[0, 0], [20, 0], [20, 4], [0, 4]]}],
    "stages": [{"name": "initial stress", "type": "k0"}, {"name": "run", "type": "dynamic", "duration_s": 1.0}],
}


def _warnings(edit=None) -> list[str]:
    data = copy.deepcopy(BASE)
    if edit is not None:
        edit(data)
    return [w for w in project_warnings(validate_project(data)) if "soften" in w]


def test_a_length_of_at_least_a_cell_is_not_warned_about():
    assert _warnings() == []

    def coarse_as_the_length(d):
        d["domain"]["cell_size_m"] = 1.0

    assert _warnings(coarse_as_the_length) == []


def test_no_length_warns_that_the_result_depends_on_the_cell_size_and_names_the_remedy():
    def no_length(d):
        del d["materials"]["clay"]["softening_length_m"]

    [warning] = _warnings(no_length)
    assert warning.startswith("materials.clay.softening_law = 'linear' without softening_length_m")
    assert "depend on the cell size (0.5 m here" in warning
    assert "give softening_length_m" in warning and "at least the cell size" in warning


def test_a_length_shorter_than_the_cell_is_warned_about_with_the_factor():
    def short(d):
        d["materials"]["clay"]["softening_length_m"] = 0.2

    [warning] = _warnings(short)
    assert warning.startswith("materials.clay.softening_length_m = 0.2 is shorter than the cell size (0.5 m)")
    assert "2.5 times below residual_plastic_strain" in warning and "cells of at most 0.2 m" in warning


def test_softening_set_by_a_stage_is_warned_about_at_that_stage():
    def staged(d):
        clay = d["materials"]["clay"]
        law = {k: clay.pop(k) for k in ("softening_law", "residual_cohesion_pa", "residual_plastic_strain",
                                        "softening_length_m")}
        del law["softening_length_m"]
        d["stages"][1]["material_changes"] = {"clay": law}

    [warning] = _warnings(staged)
    assert warning.startswith("stages.1.material_changes.clay.softening_law = 'linear' without softening_length_m")

    def staged_short(d):
        staged(d)
        d["stages"][1]["material_changes"]["clay"]["softening_length_m"] = 0.25

    [warning] = _warnings(staged_short)
    assert warning.startswith("stages.1.material_changes.clay.softening_length_m = 0.25 is shorter")


def test_a_material_no_body_uses_or_that_does_not_soften_is_not_warned_about():
    def unused(d):
        d["materials"]["spare"] = {**d["materials"].pop("clay"), "softening_length_m": 0.1}
        d["bodies"][0]["material"] = "sand"

    assert _warnings(unused) == []


def test_runout_validate_prints_the_warning(tmp_path):
    from app.cli import cli

    data = copy.deepcopy(BASE)
    del data["materials"]["clay"]["softening_length_m"]
    path = tmp_path / "clay.toml"
    save_project(validate_project(data), path)
    result = CliRunner().invoke(cli, ["validate", str(path)])
    assert result.exit_code == 0, result.output
    assert "warning: materials.clay.softening_law = 'linear' without softening_length_m" in result.output
