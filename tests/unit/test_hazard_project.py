"""The [hazard] and [[targets]] project keys: defaults, errors naming key, value and what is allowed,
saving, and how they resolve into the solver's envelope configuration."""

from __future__ import annotations

import copy

import pytest

from projects.document import dumps_project, loads_project
from projects.hazard import envelope_config, settings
from projects.schema import ProjectError, validate_project
from tests.unit.test_project_schema import BASE


def with_(**sections):
    data = copy.deepcopy(BASE)
    data.update(sections)
    return data


def problems(data) -> list[str]:
    with pytest.raises(ProjectError) as info:
        validate_project(data)
    return [str(p) for p in info.value.problems]


def test_defaults_scale_with_the_scene():
    project = validate_project(with_())
    s = settings(project)
    assert s.enabled and s.update_every_steps == 10 and s.kinetic_energy_fraction == 0.01
    assert s.cell_size_m == 0.002 and s.mobilised_displacement_m == 0.002
    # half the particle spacing (2 x 2 particles per cell): any material counts
    assert s.flow_height_threshold_m == pytest.approx(0.0005) and s.deposit_threshold_m == pytest.approx(0.0005)
    config = envelope_config(project)
    assert config.cell_size_m == 0.002 and config.every_steps == 10 and config.targets == ()


def test_keys_and_targets_resolve_into_the_envelope_config():
    project = validate_project(with_(
        hazard={"cell_size_m": 0.01, "update_every_steps": 3, "flow_height_threshold_m": 0.002,
                "deposit_threshold_m": 0.003, "mobilised_displacement_m": 0.004, "kinetic_energy_fraction": 0.05},
        targets=[{"name": "road", "x_m": 0.4}, {"name": "house", "point_m": [0.5, 0.01]}]))
    s = settings(project)
    assert (s.cell_size_m, s.update_every_steps, s.deposit_threshold_m, s.mobilised_displacement_m,
            s.kinetic_energy_fraction) == (0.01, 3, 0.003, 0.004, 0.05)
    config = envelope_config(project)
    assert config.flow_height_threshold_m == 0.002
    assert [(t.name, t.x_m, t.y_m) for t in config.targets] == [("road", 0.4, None), ("house", 0.5, 0.01)]
    assert envelope_config(validate_project(with_(hazard={"enabled": False}))) is None


def test_saved_project_reads_back_equal():
    project = validate_project(with_(hazard={"update_every_steps": 4},
                                     targets=[{"name": "road", "x_m": 0.4}, {"name": "house", "point_m": [0.5, 0.01]}]))
    text = dumps_project(project)
    assert "[[targets]]" in text and "[hazard]" in text
    assert loads_project(text) == project


@pytest.mark.parametrize(("sections", "expected"), [
    ({"hazard": {"update_every_steps": 0}}, "hazard.update_every_steps = 0: must be >= 1 and <= 100000"),
    ({"hazard": {"cell_size_m": -1.0}}, "hazard.cell_size_m = -1.0: must be > 0"),
    ({"hazard": {"cell_size_m": 1.0}}, "hazard.cell_size_m = 1.0: larger than the domain (0.8 x 0.15 m)"),
    ({"hazard": {"kinetic_energy_fraction": 1.0}}, "hazard.kinetic_energy_fraction = 1.0: must be > 0 and < 1"),
    ({"hazard": {"enabled": "yes"}}, 'hazard.enabled = "yes": must be true or false'),
    ({"hazard": {"treshold": 1.0}}, "hazard.treshold: unknown key; allowed: enabled, cell_size_m, "
                                    "update_every_steps, flow_height_threshold_m, deposit_threshold_m, "
                                    "mobilised_displacement_m, kinetic_energy_fraction"),
    ({"targets": [{"name": "road"}]},
     'targets.0 = {name = "road"}: give x_m (a vertical line) or point_m (a point [x, y]), exactly one of them'),
    ({"targets": [{"name": "road", "x_m": 0.1, "point_m": [0.1, 0.0]}]},
     'targets.0 = {name = "road", x_m = 0.1, point_m = [0.1, 0.0]}: give x_m (a vertical line) or point_m (a point [x, y]), exactly one of them'),
    ({"targets": [{"name": "road", "x_m": 2.0}]}, "targets.0.x_m = 2.0: must lie in the domain, x from 0 to 0.8 m"),
    ({"targets": [{"name": "house", "point_m": [0.1, 0.5]}]},
     "targets.0.point_m = [0.1, 0.5]: must lie in the domain [0, 0.8] x [0, 0.15] m"),
    ({"targets": [{"name": "a b", "x_m": 0.1}]}, None),
])
def test_bad_values_name_key_value_and_what_is_allowed(sections, expected):
    found = problems(with_(**sections))
    assert len(found) == 1
    if expected is None:
        assert found[0].startswith('targets.0.name = "a b"')
    else:
        assert found == [expected]


def test_target_names_are_unique():
    found = problems(with_(targets=[{"name": "road", "x_m": 0.1}, {"name": "road", "x_m": 0.2}]))
    assert found == ['targets.1.name = "road": another target has this name; names must be unique']


def test_hazard_json_sums_up_each_structures_force_history(tmp_path):
    """hazard.json's ``structures``: peak and largest mean force of each structure, from contacts.csv
    (the closed sides are left out)."""
    from projects.hazard import structure_forces
    from projects.results import CONTACT_COLUMNS, CONTACTS_NAME

    rows = [",".join(CONTACT_COLUMNS)]
    blank = ["" for _ in CONTACT_COLUMNS[4:]]

    def row(t, name, fx, fy, peak):
        values = [repr(t), name, repr(fx), repr(fy), "", ""] + [repr(peak)] + blank[3:]
        return ",".join(values[: len(CONTACT_COLUMNS)])

    rows += [row(0.1, "bottom", 0.0, -500.0, 600.0), row(0.1, "dam", 30.0, 40.0, 90.0),
             row(0.2, "bottom", 0.0, -500.0, 650.0), row(0.2, "dam", 60.0, 80.0, 250.0),
             row(0.3, "dam", 6.0, 8.0, 20.0)]
    (tmp_path / CONTACTS_NAME).write_text("\n".join(rows) + "\n")
    forces = structure_forces(tmp_path)
    assert set(forces) == {"dam"}
    assert forces["dam"]["peak_force_N_per_m"] == 250.0 and forces["dam"]["peak_time_s"] == 0.2
    assert forces["dam"]["max_mean_force_N_per_m"] == pytest.approx(100.0)
    assert structure_forces(tmp_path / "missing") == {}
