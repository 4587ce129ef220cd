"""numerics.preset: schema rules, overrides and what a preset does to the build."""

import json
from pathlib import Path

import pytest

from projects import presets
from projects.build import estimate, resolve
from projects.document import apply_overrides, load_project
from projects.schema import ProjectError

EXAMPLES = Path(__file__).resolve().parents[2] / "projects" / "examples"

FAKE = {
    "format": 1,
    "presets": {
        "draft": {"scheme": "apic-affine", "per_cell": 1, "cfl": 0.5, "cells_per_height": 8},
        "standard": {"scheme": "apic", "per_cell": 2, "cfl": 0.4, "cells_per_height": 20},
        "fine": None,
    },
}


@pytest.fixture
def fake_presets(tmp_path, monkeypatch):
    path = tmp_path / "presets.json"
    path.write_text(json.dumps(FAKE))
    monkeypatch.setattr(presets, "PRESETS_FILE", path)
    presets.load_presets.cache_clear()
    yield FAKE
    presets.load_presets.cache_clear()


def tiny():
    return load_project(EXAMPLES / "tiny_column.toml")


def test_preset_and_time_step_together_are_an_error():
    from projects.schema import validate_project

    data_with_both = tiny().to_dict()  # tiny_column gives time_step_s
    data_with_both["numerics"]["preset"] = "draft"
    with pytest.raises(ProjectError) as err:
        validate_project(data_with_both)
    assert str(err.value.problems[0].path) == "numerics.time_step_s"
    assert "a preset (draft) sets the time step through its cfl" in err.value.problems[0].message


def test_unknown_preset_names_the_allowed_ones():
    with pytest.raises(ProjectError) as err:
        apply_overrides(tiny(), ["numerics.preset=rough"])
    assert "draft" in str(err.value) and "fine" in str(err.value)


def test_override_to_a_preset_drops_the_time_step_and_the_build_follows_the_preset(fake_presets):
    project = apply_overrides(tiny(), ["numerics.preset=standard"])
    assert project.numerics.time_step_s is None and project.numerics.preset == "standard"
    resolved = presets.apply_preset(project)
    height = min(max(p[1] for p in b.polygon_m) - min(p[1] for p in b.polygon_m) for b in project.bodies)
    assert resolved.domain.cell_size_m == pytest.approx(height / 20)
    assert resolved.particles.per_cell == 2 and resolved.numerics.scheme == "apic"
    built = resolve(project)
    assert built.config.grid.cell_size_m == pytest.approx(height / 20)
    assert built.config.numerics.cfl == 0.4 and built.config.numerics.time_step_s is None
    assert built.config.numerics.scheme == "apic"
    assert built.estimate["time_step_source"] == "cfl"
    assert built.spacing_m == pytest.approx(height / 20 / 2)


def test_a_preset_the_study_could_not_fill_is_a_clear_error(fake_presets):
    with pytest.raises(ProjectError, match="no measured setting for this preset"):
        presets.apply_preset(apply_overrides(tiny(), ["numerics.preset=fine"]))
