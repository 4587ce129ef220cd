"""Validation of project data: defaults, golden error messages, several problems at once."""

from __future__ import annotations

import copy
import math

import pytest
from pydantic import ValidationError

from projects.schema import (
    Boundary,
    Problem,
    Project,
    ProjectError,
    format_value,
    validate_project,
)

DELETE = object()

BASE = {
    "runout": {"schema_version": 1, "title": "bars"},
    "domain": {
        "size_m": [0.8, 0.15],
        "cell_size_m": 0.002,
        "boundaries": {"bottom": {"type": "friction", "friction_angle_deg": 19.8}},
    },
    "materials": {
        "bars": {
            "model": "drucker-prager",
            "density_kg_m3": 2650.0,
            "youngs_modulus_pa": 0.84e6,
            "poisson_ratio": 0.3,
            "cohesion_pa": 0.0,
            "friction_angle_deg": 19.8,
            "dilatancy_angle_deg": 0.0,
        }
    },
    "bodies": [
        {"name": "block", "material": "bars", "polygon_m": [[0.0, 0.0], [0.2, 0.0], [0.2, 0.1], [0.0, 0.1]]}
    ],
    "numerics": {"time_step_s": 2e-5},
    "stages": [
        {"name": "initial stress", "type": "k0"},
        {"name": "collapse", "type": "dynamic", "duration_s": 1.0},
    ],
}


def changed(path: str, value) -> dict:
    """A copy of BASE with one key set (or deleted with DELETE); tables on the way are created."""
    data = copy.deepcopy(BASE)
    node = data
    parts = path.split(".")
    for part in parts[:-1]:
        node = node[int(part)] if isinstance(node, list) else node.setdefault(part, {})
    last = parts[-1]
    if value is DELETE:
        del node[last]
    elif isinstance(node, list):
        node[int(last)] = value
    else:
        node[last] = value
    return data


def problems_of(data) -> list[str]:
    with pytest.raises(ProjectError) as info:
        validate_project(data)
    return [str(p) for p in info.value.problems]


def test_valid_base_and_defaults():
    project = validate_project(BASE)
    assert isinstance(project, Project)
    assert project.domain.origin_m == (0.0, 0.0)
    assert project.domain.gravity_m_s2 == (0.0, -9.81)
    assert project.domain.boundaries.left == Boundary(type="slip")
    assert project.domain.boundaries.right == Boundary(type="slip")
    assert project.domain.boundaries.top == Boundary(type="open")
    assert project.domain.boundaries.bottom == Boundary(type="friction", friction_angle_deg=19.8)
    assert project.particles.per_cell == 2 and project.particles.seeding == "lattice"
    assert project.numerics.scheme == "apic-affine"
    assert project.numerics.time_step_s == 2e-5 and project.numerics.cfl is None
    assert project.output.interval_s == 0.01
    assert project.output.fields == ("displacement", "velocity", "stress", "plastic_strain", "material", "pore_pressure")
    assert project.stages[1].label == "collapse"
    assert project.material_names == ("bars",)


def test_cfl_default_when_no_time_step():
    project = validate_project(changed("numerics", {}))
    assert project.numerics.cfl == 0.5 and project.numerics.time_step_s is None


def test_ints_are_accepted_for_floats():
    project = validate_project(changed("materials.bars.density_kg_m3", 2650))
    assert project.materials["bars"].density_kg_m3 == 2650.0
    assert isinstance(project.materials["bars"].density_kg_m3, float)


def test_boundary_tables_for_plain_types():
    project = validate_project(changed("domain.boundaries.left", {"type": "fixed"}))
    assert project.domain.boundaries.left == Boundary(type="fixed")


def test_model_is_frozen():
    project = validate_project(BASE)
    with pytest.raises(Exception):
        project.domain.cell_size_m = 0.004  # type: ignore[misc]


def test_to_dict_validates_back_to_equal():
    project = validate_project(BASE)
    data = project.to_dict()
    assert data["domain"]["boundaries"]["left"] == "slip"
    assert data["domain"]["boundaries"]["bottom"] == {"type": "friction", "friction_angle_deg": 19.8}
    assert "cfl" not in data["numerics"]
    assert validate_project(data) == project


GOLDEN = [
    ("materials.bars.poisson_ratio", 0.6, "materials.bars.poisson_ratio = 0.6: must be >= 0 and < 0.5"),
    ("numerics.schem", "apic", "numerics.schem: unknown key; allowed: scheme, time_step_s, cfl, precision, arch, preset, volumetric_averaging, advanced"),
    ("bodies.0.material", "sand", 'bodies.0.material = "sand": no such material; defined: bars'),
    ("materials.bars.density_kg_m3", -1, "materials.bars.density_kg_m3 = -1: must be > 0"),
    ("materials.bars.youngs_modulus_pa", 0.0, "materials.bars.youngs_modulus_pa = 0.0: must be > 0"),
    ("domain.cell_size_m", 0, "domain.cell_size_m = 0: must be > 0"),
    ("domain.size_m", [0.8, 0.0], "domain.size_m = [0.8, 0.0]: both components must be > 0"),
    ("domain.size_m", [0.8], "domain.size_m = [0.8]: must be a pair of numbers [x, y]"),
    ("materials.bars.friction_angle_deg", 90.0, "materials.bars.friction_angle_deg = 90.0: must be >= 0 and < 90"),
    (
        "materials.bars.dilatancy_angle_deg",
        25.0,
        "materials.bars.dilatancy_angle_deg = 25.0: must not exceed friction_angle_deg (19.8)",
    ),
    ("materials.bars.cohesion_pa", -5.0, "materials.bars.cohesion_pa = -5.0: must be >= 0"),
    ("materials.bars.tensile_strength_pa", -1.0, "materials.bars.tensile_strength_pa = -1.0: must be >= 0"),
    (
        "bodies.0.polygon_m",
        [[0.0, 0.0], [0.1, 0.0]],
        "bodies.0.polygon_m = [[0.0, 0.0], [0.1, 0.0]]: needs at least 3 points, got 2",
    ),
    (
        "bodies.0.polygon_m",
        [[0.0, 0.0], [0.1, 0.1], [0.1, 0.0], [0.0, 0.1]],
        "bodies.0.polygon_m = [[0.0, 0.0], [0.1, 0.1], [0.1, 0.0], [0.0, 0.1]]: "
        "not a simple polygon: edges (0, 0)-(0.1, 0.1) and (0.1, 0)-(0, 0.1) cross or touch",
    ),
    (
        "bodies.0.polygon_m",
        [[0.0, 0.0], [0.9, 0.0], [0.9, 0.1], [0.0, 0.1]],
        "bodies.0.polygon_m.1 = [0.9, 0.0]: outside the domain (x in [0, 0.8], y in [0, 0.15]) (and 1 more point)",
    ),
    (
        "bodies.0.polygon_m",
        [[0.0, 0.0], [0.1, 0.0], [0.1], [0.0, 0.1]],
        "bodies.0.polygon_m.2 = [0.1]: must be a pair of numbers [x, y]",
    ),
    ("numerics.cfl", 0.5, "numerics.cfl = 0.5: give time_step_s or cfl, not both (time_step_s = 2e-05)"),
    ("stages", [], "stages = []: needs at least one stage ([[stages]])"),
    (
        "stages",
        [{"type": "dynamic", "duration_s": 1.0}, {"type": "k0"}],
        'stages.1.type = "k0": must come before the first dynamic stage (stages.0)',
    ),
    (
        "stages",
        [{"type": "gravity", "duration_s": 1.0}, {"type": "k0"}],
        'stages.1.type = "k0": only one k0 or gravity stage is allowed (stages.0 is one)',
    ),
    ("stages.1.duration_s", DELETE, "stages.1.duration_s: required for a dynamic stage"),
    ("stages.1.duration_s", -1.0, "stages.1.duration_s = -1.0: must be > 0"),
    ("stages.0.duration_s", 1.0, "stages.0.duration_s = 1.0: not allowed on a k0 stage (it takes no time)"),
    ("stages.1.k0", 0.5, "stages.1.k0 = 0.5: only allowed on a k0 stage"),
    ("stages.1.ramp_fraction", 0.5, "stages.1.ramp_fraction = 0.5: only allowed on a gravity stage"),
    (
        "stages",
        [{"type": "gravity", "duration_s": 1.0, "ramp_fraction": 0.0}],
        "stages.0.ramp_fraction = 0.0: must be > 0 and <= 1",
    ),
    (
        "stages",
        [{"type": "gravity", "duration_s": 1.0, "ramp_fraction": 1.5}],
        "stages.0.ramp_fraction = 1.5: must be > 0 and <= 1",
    ),
    (
        "stages.1.min_duration_s",
        0.5,
        "stages.1.min_duration_s = 0.5: only allowed with stop_when_kinetic_energy_below or "
        "stop_when_max_speed_below_m_s",
    ),
    (
        "stages",
        [{"type": "gravity", "duration_s": 1.0, "stop_when_kinetic_energy_below": 0.01}],
        "stages.0.stop_when_kinetic_energy_below = 0.01: only allowed on a dynamic stage",
    ),
    (
        "stages.1.damping",
        {"type": "local", "coefficient": 1.0},
        "stages.1.damping.coefficient = 1.0: must be >= 0 and < 1",
    ),
    ("stages.1.damping", 0.7, "stages.1.damping = 0.7: must be a table"),
    (
        "stages",
        [{"type": "gravity", "duration_s": 1.0, "damping": {"coefficient": 0.0}}],
        "stages.0.damping.coefficient = 0.0: must be > 0 on a gravity stage",
    ),
    (
        "stages.1.type",
        "quasi-static",
        'stages.1.type = "quasi-static": must be one of "k0", "gravity", "dynamic", "strength-reduction"',
    ),
    (
        "stages.1.material_changes",
        {"sand": {"cohesion_pa": 0.0}},
        "stages.1.material_changes.sand: no such material; defined: bars",
    ),
    (
        "stages.1.material_changes",
        {"bars": {"friction_angle": 10.0}},
        "stages.1.material_changes.bars.friction_angle: unknown key; allowed: density_kg_m3, "
        "youngs_modulus_pa, poisson_ratio, cohesion_pa, friction_angle_deg, dilatancy_angle_deg, "
        "tensile_strength_pa, damping_ratio, damping_frequency_hz, damping_model, saturated_density_kg_m3, ru, "
        "softening_law, residual_cohesion_pa, residual_friction_angle_deg, residual_dilatancy_angle_deg, "
        "peak_plastic_strain, residual_plastic_strain, softening_length_m, velocity_m_s",
    ),
    (
        "stages.1.material_changes",
        {"bars": {"damping_ratio": 0.05}},
        "stages.1.material_changes.bars.damping_frequency_hz: required with damping_ratio > 0: the frequency (Hz) "
        "at which the material is damped by that fraction of critical, e.g. the body's first mode",
    ),
    (
        "materials.bars.damping_ratio",
        1.0,
        "materials.bars.damping_ratio = 1.0: must be >= 0 and < 1",
    ),
    (
        "materials.bars.damping_frequency_hz",
        2.0,
        "materials.bars.damping_frequency_hz = 2.0: only allowed with damping_ratio",
    ),
    (
        "stages.1.material_changes",
        {"bars": {"damping_ratio": 0.1, "damping_frequency_hz": 1.0, "damping_model": "kelvin"}},
        'stages.1.material_changes.bars.damping_model = "kelvin": must be one of "rayleigh", "maxwell"',
    ),
    (
        "stages.1.material_changes",
        {"bars": {"friction_angle_deg": -1.0}},
        "stages.1.material_changes.bars.friction_angle_deg = -1.0: must be >= 0 and < 90",
    ),
    (
        "stages.1.material_changes",
        {"bars": {"friction_angle_deg": 10.0, "dilatancy_angle_deg": 15.0}},
        "stages.1.material_changes.bars.dilatancy_angle_deg = 15.0: must not exceed friction_angle_deg (10)",
    ),
    (
        "output",
        {"fields": ["stress", "strain"]},
        'output.fields.1 = "strain": must be one of "displacement", "velocity", "stress", '
        '"plastic_strain", "material", "pore_pressure"',
    ),
    ("output", {"fields": ["stress", "stress"]}, 'output.fields = ["stress", "stress"]: "stress" is listed twice'),
    ("output", {"interval_s": 0}, "output.interval_s = 0: must be > 0"),
    (
        "runout.schema_version",
        3,
        "runout.schema_version = 3: unsupported schema version; this Runout reads schema versions 1, 2 (and writes 2)",
    ),
    ("runout", DELETE, "runout: required key is missing"),
    ("domain.cell_size_m", DELETE, "domain.cell_size_m: required key is missing"),
    (
        "domain.cell_size_m",
        1.0,
        "domain.cell_size_m = 1.0: larger than the domain (0.8 x 0.15 m)",
    ),
    (
        "domain.boundaries.left",
        "slp",
        'domain.boundaries.left = "slp": must be "fixed", "slip", "open", "periodic" (left and right together) or a table '
        '{type = "friction", friction_angle_deg = ...}',
    ),
    (  # neither a word nor a table: the words allowed are named, not just "a table"
        "domain.boundaries.left",
        3,
        'domain.boundaries.left = 3: must be "fixed", "slip", "open", "periodic" (left and right together) or a table '
        '{type = "friction", friction_angle_deg = ...}',
    ),
    (
        "domain.boundaries.bottom",
        {"type": "friction"},
        'domain.boundaries.bottom.friction_angle_deg: required for type "friction"',
    ),
    (
        "domain.boundaries.left",
        {"type": "slip", "friction_angle_deg": 10.0},
        'domain.boundaries.left.friction_angle_deg = 10.0: only allowed with type "friction"',
    ),
    ("domain.gravity_m_s2", "down", 'domain.gravity_m_s2 = "down": must be a pair of numbers [x, y]'),
    ("numerics.scheme", "flip", 'numerics.scheme = "flip": must be one of "mpm", "apic", "apic-affine"'),
    ("numerics.precision", "f16", 'numerics.precision = "f16": must be one of "f32", "f64"'),
    ("materials.bars.poisson_ratio", "0.3", 'materials.bars.poisson_ratio = "0.3": must be a number'),
    ("materials.bars.density_kg_m3", True, "materials.bars.density_kg_m3 = true: must be a number"),
    ("materials.bars.density_kg_m3", math.inf, "materials.bars.density_kg_m3 = inf: must be a finite number"),
    ("particles", {"per_cell": 0}, "particles.per_cell = 0: must be >= 1 and <= 8"),
    ("particles", {"per_cell": 2.0}, "particles.per_cell = 2.0: must be an integer"),
    ("particles", {"seeding": "random"}, 'particles.seeding = "random": must be one of "lattice", "gauss"'),
    (
        "materials.bars.friction_angle_deg",
        DELETE,
        'materials.bars.friction_angle_deg: required for model "drucker-prager"',
    ),
    (
        "simulation",
        {},
        "simulation: unknown key; allowed: runout, domain, materials, bodies, structures, water, particles, numerics, stages, output, hazard, targets",
    ),
    (
        "bodies",
        [BASE["bodies"][0], BASE["bodies"][0]],
        'bodies.1.name = "block": duplicate; bodies.0 has the same name',
    ),
    ("bodies", [], "bodies = []: needs at least one body ([[bodies]])"),
    ("bodies.0", "block", 'bodies.0 = "block": must be a table'),
    ("bodies.0.name", "", 'bodies.0.name = "": must not be empty'),
    # "wall " and "wall" would name two contacts.csv rows that read as one
    ("bodies.0.name", "  block ", 'bodies.0.name = "  block ": must not begin or end with spaces'),
    ("bodies.0.name", "blo\nck", 'bodies.0.name = "blo\\nck": must be one line of printable characters'),
    ("stages.1.name", 3, "stages.1.name = 3: must be a string"),
    (
        "bodies.0.initial_velocity_m_s",
        [1, 2, 3],
        "bodies.0.initial_velocity_m_s = [1, 2, 3]: must be a pair of numbers [x, y]",
    ),
]


def test_a_damping_model_without_a_ratio_is_allowed_and_undamped():
    # the workbench keeps the model while the ratio is cleared and typed again
    from projects.build import solver_material

    data = changed("materials.bars.damping_model", "maxwell")
    material = validate_project(data).materials["bars"]  # no problem raised
    assert material.damping_model == "maxwell" and not solver_material("bars", material).damped


@pytest.mark.parametrize(("path", "value", "expected"), GOLDEN, ids=[f"{i:02d}-{c[0]}" for i, c in enumerate(GOLDEN)])
def test_golden_error_messages(path, value, expected):
    assert problems_of(changed(path, value)) == [expected]


def test_golden_cases_are_distinct_inputs():
    assert len({(p, format_value(v) if v is not DELETE else "<del>") for p, v, _ in GOLDEN}) == len(GOLDEN) >= 20


def test_linear_elastic_rejects_every_plastic_key():
    assert problems_of(changed("materials.bars.model", "linear-elastic")) == [
        'materials.bars.cohesion_pa = 0.0: only allowed with model "drucker-prager"',
        'materials.bars.friction_angle_deg = 19.8: only allowed with model "drucker-prager"',
        'materials.bars.dilatancy_angle_deg = 0.0: only allowed with model "drucker-prager"',
    ]


@pytest.mark.parametrize("model", ["linear-elastic", "drucker-prager"])
def test_material_damping_takes_a_ratio_below_one_and_a_frequency_of_a_body(model):
    data = copy.deepcopy(BASE)
    data["materials"]["bars"]["damping_ratio"] = 0.05
    data["materials"]["bars"]["damping_frequency_hz"] = 0.0
    if model == "linear-elastic":
        data["materials"]["bars"] = {k: v for k, v in data["materials"]["bars"].items()
                                     if k not in ("cohesion_pa", "friction_angle_deg", "dilatancy_angle_deg")}
        data["materials"]["bars"]["model"] = model
    assert problems_of(data) == ["materials.bars.damping_frequency_hz = 0.0: must be >= 0.001 and <= 1e+06"]
    data["materials"]["bars"]["damping_frequency_hz"] = 1e-320
    assert problems_of(data) == ["materials.bars.damping_frequency_hz = 1e-320: must be >= 0.001 and <= 1e+06"]
    data["materials"]["bars"]["damping_frequency_hz"] = 3.5
    material = validate_project(data).materials["bars"]
    assert (material.damping_ratio, material.damping_frequency_hz) == (0.05, 3.5)
    data["materials"]["bars"]["damping_ratio"] = 0.0  # zero: undamped, no frequency needed
    del data["materials"]["bars"]["damping_frequency_hz"]
    assert validate_project(data).materials["bars"].damping_ratio == 0.0


def test_linear_elastic_material_without_plastic_keys_is_valid():
    data = copy.deepcopy(BASE)
    data["materials"]["plate"] = {
        "model": "linear-elastic",
        "density_kg_m3": 7800.0,
        "youngs_modulus_pa": 2.0e11,
        "poisson_ratio": 0.3,
    }
    assert validate_project(data).material_names == ("bars", "plate")


def test_lowering_friction_below_dilatancy_blames_the_changed_key():
    data = changed("materials.bars.dilatancy_angle_deg", 10.0)
    data["stages"][1]["material_changes"] = {"bars": {"friction_angle_deg": 5.0}}
    assert problems_of(data) == [
        "stages.1.material_changes.bars.friction_angle_deg = 5.0: must not be below dilatancy_angle_deg (10)"
    ]


def test_material_changes_persist_into_later_stages_for_checks():
    # Stage 1 raises dilatancy to 15 (friction 19.8: fine); stage 2 lowers friction to 12: now wrong.
    data = copy.deepcopy(BASE)
    data["stages"][1]["material_changes"] = {"bars": {"dilatancy_angle_deg": 15.0}}
    data["stages"].append(
        {"type": "dynamic", "duration_s": 1.0, "material_changes": {"bars": {"friction_angle_deg": 12.0}}}
    )
    assert problems_of(data) == [
        "stages.2.material_changes.bars.friction_angle_deg = 12.0: must not be below dilatancy_angle_deg (15)"
    ]


def test_bad_material_name_key():
    data = copy.deepcopy(BASE)
    data["materials"]["my bars"] = data["materials"]["bars"]
    assert problems_of(data) == ["materials.my bars: names may only use letters, digits, _ and -"]


def test_long_values_are_shortened():
    polygon = [[0.0, 0.0], [0.1, 0.1], [0.1, 0.0], [0.0, 0.1]] + [[0.05, 0.05 + i * 1e-3] for i in range(10)]
    message = problems_of(changed("bodies.0.polygon_m", polygon))[0]
    value = message.split(" = ", 1)[1].split(": not a simple", 1)[0]
    assert len(value) == 60 and value.endswith("...")


def test_several_problems_at_once_in_file_order():
    data = copy.deepcopy(BASE)
    data["output"] = {"interval_s": -1.0}
    data["stages"].append({"type": "gravity", "duration_s": 1.0})
    data["numerics"]["schem"] = "apic"
    data["numerics"]["cfl"] = 0.3
    data["bodies"][0]["material"] = "sand"
    data["bodies"][0]["polygon_m"][2] = [0.2, 0.5]
    data["materials"]["bars"]["poisson_ratio"] = 0.6
    data["materials"]["bars"]["dilatancy_angle_deg"] = 30.0
    data["domain"]["boundaries"]["left"] = "sticky"
    assert problems_of(data) == [
        'domain.boundaries.left = "sticky": must be "fixed", "slip", "open", "periodic" (left and right together) or a table '
        '{type = "friction", friction_angle_deg = ...}',
        "materials.bars.poisson_ratio = 0.6: must be >= 0 and < 0.5",
        "materials.bars.dilatancy_angle_deg = 30.0: must not exceed friction_angle_deg (19.8)",
        'bodies.0.material = "sand": no such material; defined: bars',
        "bodies.0.polygon_m.2 = [0.2, 0.5]: outside the domain (x in [0, 0.8], y in [0, 0.15])",
        "numerics.schem: unknown key; allowed: scheme, time_step_s, cfl, precision, arch, preset, volumetric_averaging, advanced",
        "numerics.cfl = 0.3: give time_step_s or cfl, not both (time_step_s = 2e-05)",
        'stages.2.type = "gravity": must come before the first dynamic stage (stages.1)',
        "output.interval_s = -1.0: must be > 0",
    ]


def test_schema_version_problem_is_reported_alone():
    data = changed("runout.schema_version", 3)
    data["materials"]["bars"]["poisson_ratio"] = 0.6
    assert problems_of(data) == [
        "runout.schema_version = 3: unsupported schema version; this Runout reads schema versions 1, 2 (and writes 2)"
    ]


def test_a_schema_1_file_reads_as_schema_2():
    data = changed("runout.schema_version", 1)
    assert validate_project(data).runout.schema_version == 2


def test_not_a_table():
    with pytest.raises(ProjectError) as info:
        validate_project([1, 2])  # type: ignore[arg-type]
    assert str(info.value) == "a project must be a TOML table"


def test_error_message_format():
    one = ProjectError([Problem("a.b", 1.5, "must be > 2")], source="p.toml")
    assert str(one) == "p.toml: a.b = 1.5: must be > 2"
    two = ProjectError([Problem("a", None, "required key is missing"), Problem("", None, "whole file")])
    assert str(two) == "2 problems\n  a: required key is missing\n  whole file"
    assert two.problems[0].path == "a" and two.problems[0].value is None


def test_direct_model_validation_runs_the_rules_too():
    with pytest.raises(ValidationError) as info:
        Project.model_validate(changed("bodies.0.material", "sand"))
    (error,) = info.value.errors()
    assert [str(p) for p in error["ctx"]["problems"]] == [
        'bodies.0.material = "sand": no such material; defined: bars'
    ]


@pytest.mark.parametrize(
    ("value", "text"),
    [
        (True, "true"),
        (3, "3"),
        (0.1, "0.1"),
        (2e-5, "2e-05"),
        ("a\"b", '"a\\"b"'),
        ([1, [2.5, "x"]], '[1, [2.5, "x"]]'),
        ({"type": "local", "coefficient": 0.7}, '{type = "local", coefficient = 0.7}'),
        (-math.inf, "-inf"),
    ],
)
def test_format_value(value, text):
    assert format_value(value) == text


def test_mohr_coulomb_match_is_one_of_the_matches_and_for_drucker_prager_only():
    from projects.schema import validate_project

    for match in ("plane-strain-associated", "plane-strain", "simple-shear"):
        validate_project(changed("materials.bars.mohr_coulomb_match", match))
    assert problems_of(changed("materials.bars.mohr_coulomb_match", "triaxial")) == [
        'materials.bars.mohr_coulomb_match = "triaxial": must be one of "plane-strain-associated", '
        '"plane-strain", "simple-shear"'
    ]
    data = changed("materials.bars.mohr_coulomb_match", "plane-strain")
    data["materials"]["bars"] = {k: v for k, v in data["materials"]["bars"].items()
                                 if k not in ("cohesion_pa", "friction_angle_deg", "dilatancy_angle_deg")}
    data["materials"]["bars"]["model"] = "linear-elastic"
    assert problems_of(data) == [
        'materials.bars.mohr_coulomb_match = "plane-strain": only allowed with model "drucker-prager"'
    ]


def test_the_match_reaches_the_solver_material_and_defaults_to_the_associated_one():
    from projects.build import solver_material
    from projects.schema import validate_project

    given = validate_project(changed("materials.bars.mohr_coulomb_match", "simple-shear"))
    assert solver_material("bars", given.materials["bars"]).mohr_coulomb_match == "simple-shear"
    assert solver_material("bars", validate_project(copy.deepcopy(BASE)).materials["bars"]).mohr_coulomb_match == \
        "plane-strain-associated"
