"""Reading and writing project files: syntax errors, exact round trips, atomic saves, overrides."""

from __future__ import annotations

import copy
import os
import stat
import struct

import pytest

import projects.atomic as atomic
import projects.document as document
from projects.document import (
    apply_overrides,
    dumps_project,
    load_project,
    loads_project,
    parse_override,
    save_project,
)
from projects.schema import ProjectError, validate_project

MINIMAL = """\
[runout]
schema_version = 1

[domain]
size_m = [0.6, 0.3]
cell_size_m = 0.02

[materials.sand]
model = "drucker-prager"
density_kg_m3 = 2000.0
youngs_modulus_pa = 1.0e6
poisson_ratio = 0.3
cohesion_pa = 0.0
friction_angle_deg = 30.0

[[bodies]]
name = "column"
material = "sand"
polygon_m = [[0.0, 0.0], [0.12, 0.0], [0.12, 0.24], [0.0, 0.24]]

[[stages]]
name = "initial stress"
type = "k0"

[[stages]]
name = "collapse"
type = "dynamic"
duration_s = 0.05
"""


@pytest.fixture
def project():
    return loads_project(MINIMAL)


def problems(exc_info) -> list[str]:
    return [str(p) for p in exc_info.value.problems]


# -- reading ---------------------------------------------------------------------------------


def test_minimal_file_loads_with_defaults(project):
    assert project.runout.title == ""
    assert project.numerics.cfl == 0.5
    assert project.domain.boundaries.bottom.type == "fixed"
    assert project.bodies[0].polygon_m[2] == (0.12, 0.24)


def test_syntax_error_gives_line_and_column():
    text = MINIMAL.replace("cell_size_m = 0.02", "cell_size_m = 0.02 0.03")
    with pytest.raises(ProjectError) as info:
        loads_project(text, source="bad.toml")
    (message,) = problems(info)
    assert message.startswith("TOML syntax error at line 6, column ")
    assert str(info.value).startswith("bad.toml: TOML syntax error at line 6, column ")


def test_duplicate_key_is_a_syntax_error():
    with pytest.raises(ProjectError) as info:
        loads_project(MINIMAL.replace("cell_size_m = 0.02", "cell_size_m = 0.02\ncell_size_m = 0.03"))
    (message,) = problems(info)
    assert message.startswith("TOML syntax error at line 7, column ")


def test_validation_errors_name_the_file(tmp_path):
    path = tmp_path / "p.toml"
    path.write_text(MINIMAL.replace("poisson_ratio = 0.3", "poisson_ratio = 0.5"), encoding="utf-8")
    with pytest.raises(ProjectError) as info:
        load_project(path)
    assert str(info.value) == f"{path}: materials.sand.poisson_ratio = 0.5: must be >= 0 and < 0.5"


def test_missing_file_is_a_project_error(tmp_path):
    with pytest.raises(ProjectError) as info:
        load_project(tmp_path / "nope.toml")
    assert str(info.value) == f"{tmp_path / 'nope.toml'}: cannot read the file: No such file or directory"


def test_load_with_overrides_can_repair_the_file(tmp_path):
    path = tmp_path / "p.toml"
    path.write_text(MINIMAL.replace("poisson_ratio = 0.3", "poisson_ratio = 0.5"), encoding="utf-8")
    project = load_project(path, ["materials.sand.poisson_ratio=0.25"])
    assert project.materials["sand"].poisson_ratio == 0.25


# -- writing ---------------------------------------------------------------------------------


def test_round_trip_text_and_file(project, tmp_path):
    assert loads_project(dumps_project(project)) == project
    path = tmp_path / "p.toml"
    save_project(project, path)
    assert load_project(path) == project
    # Writing what was read gives the same text again.
    assert dumps_project(load_project(path)) == path.read_text(encoding="utf-8")


def test_layout_of_saved_file(project):
    text = dumps_project(project)
    for line in (
        "[runout]",
        "schema_version = 2",
        "[domain.boundaries]",
        'bottom = "fixed"',
        "[materials.sand]",
        "[[bodies]]",
        "polygon_m = [[0.0, 0.0], [0.12, 0.0], [0.12, 0.24], [0.0, 0.24]]",
        "[[stages]]",
        "cfl = 0.5",
        "[output]",
    ):
        assert line in text.splitlines(), line
    assert text.startswith("# Runout project file, schema version 2")


def test_tables_inside_stages_and_long_polygons_round_trip(project):
    data = project.to_dict()
    data["domain"]["boundaries"]["bottom"] = {"type": "friction", "friction_angle_deg": 25.0}
    data["stages"][1]["damping"] = {"type": "local", "coefficient": 0.3}
    data["stages"][1]["material_changes"] = {"sand": {"cohesion_pa": 0.0, "friction_angle_deg": 25.0}}
    data["bodies"][0]["polygon_m"] = [[0.01 * i, 0.0] for i in range(12)] + [[0.06, 0.2]]
    changed = validate_project(data)
    text = dumps_project(changed)
    assert "bottom = {type = \"friction\", friction_angle_deg = 25.0}" in text
    assert "damping = {type = \"local\", coefficient = 0.3}" in text
    assert "[stages.material_changes.sand]" in text
    assert "    [0.11, 0.0],\n" in text  # long polygons: one point per line
    assert loads_project(text) == changed


def test_floats_survive_exactly(project):
    # smallest normal double, not a denormal: once Taichi has started, the process flushes
    # denormals to zero (FTZ/DAZ), so float('5e-324') parses to 0.0 anywhere after a solver run
    tricky = [0.1 + 0.2, 1 / 3, 2.0e-5, 1e-300, 123456789.123456789e3, 2.2250738585072014e-308, -0.0, 2650.0000000000005]
    data = project.to_dict()
    data["domain"]["origin_m"] = [-1 / 3, -0.0]
    data["domain"]["gravity_m_s2"] = [tricky[4], -9.80665]
    data["materials"]["sand"]["density_kg_m3"] = tricky[7]
    data["materials"]["sand"]["youngs_modulus_pa"] = tricky[3]
    data["materials"]["sand"]["cohesion_pa"] = tricky[5]
    data["materials"]["sand"]["poisson_ratio"] = tricky[0]
    data["numerics"] = {"time_step_s": tricky[2]}
    data["bodies"][0]["polygon_m"] = [[0.0, 0.0], [1 / 3 * 0.3, 0.0], [0.1, 0.1 + 0.2 * 1e-3]]
    original = validate_project(data)
    back = loads_project(dumps_project(original))
    assert back == original

    def bits(x: float) -> bytes:
        return struct.pack("<d", x)

    assert bits(back.domain.origin_m[1]) == bits(-0.0)
    assert bits(back.materials["sand"].cohesion_pa) == bits(2.2250738585072014e-308)
    assert back.bodies[0].polygon_m[1][0] == 1 / 3 * 0.3


def test_save_keeps_permissions(project, tmp_path):
    path = tmp_path / "p.toml"
    path.write_text("old", encoding="utf-8")
    os.chmod(path, 0o640)
    save_project(project, path)
    assert stat.S_IMODE(os.stat(path).st_mode) == 0o640


def test_failure_while_writing_leaves_the_old_file(project, tmp_path, monkeypatch):
    path = tmp_path / "p.toml"
    path.write_text("old contents\n", encoding="utf-8")

    class HalfWritten:  # the disk fills half way through the temporary file
        def __init__(self, handle):
            self.handle = handle

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            self.handle.close()

        def write(self, data):
            self.handle.write(data[: len(data) // 2])
            raise OSError(28, "No space left on device")

    monkeypatch.setattr(atomic, "open", lambda *a, **k: HalfWritten(open(*a, **k)), raising=False)
    with pytest.raises(OSError, match="No space left"):
        save_project(project, path)
    assert path.read_text(encoding="utf-8") == "old contents\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["p.toml"]  # no temporary file left


def test_failure_at_rename_leaves_the_old_file(project, tmp_path, monkeypatch):
    path = tmp_path / "p.toml"
    path.write_text("old contents\n", encoding="utf-8")

    def broken_replace(src, dst):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(atomic.os, "replace", broken_replace)
    with pytest.raises(PermissionError):
        save_project(project, path)
    assert path.read_text(encoding="utf-8") == "old contents\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["p.toml"]


def test_save_syncs_before_renaming(project, tmp_path, monkeypatch):
    calls = []
    real_fsync, real_replace = os.fsync, os.replace
    monkeypatch.setattr(atomic.os, "fsync", lambda fd: (calls.append("fsync"), real_fsync(fd))[1])
    monkeypatch.setattr(atomic.os, "replace", lambda a, b: (calls.append("replace"), real_replace(a, b))[1])
    save_project(project, tmp_path / "p.toml")
    assert calls.index("fsync") < calls.index("replace")
    assert load_project(tmp_path / "p.toml") == project


# -- overrides -------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("text", "path", "value"),
    [
        ("numerics.scheme=apic", ["numerics", "scheme"], "apic"),
        ("domain.cell_size_m=0.004", ["domain", "cell_size_m"], 0.004),
        ("particles.per_cell = 3", ["particles", "per_cell"], 3),
        ("numerics.time_step_s=1e-4", ["numerics", "time_step_s"], 1e-4),
        ("runout.title=My run", ["runout", "title"], "My run"),
        ('runout.title="1"', ["runout", "title"], "1"),
        ("runout.title=", ["runout", "title"], ""),
        ("a.b=true", ["a", "b"], True),
        ("bodies.0.polygon_m=[[0,0],[1,0],[1,1]]", ["bodies", "0", "polygon_m"], [[0, 0], [1, 0], [1, 1]]),
        ("x={type = \"local\", coefficient = 0.7}", ["x"], {"type": "local", "coefficient": 0.7}),
        ("x=1\ny = 2", ["x"], "1\ny = 2"),
        ("x=a=b", ["x"], "a=b"),
    ],
)
def test_parse_override(text, path, value):
    assert parse_override(text) == (path, value)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("numerics.scheme", "numerics.scheme: expected KEY=VALUE"),
        ("=3", "(empty): malformed key path; expected names and indices joined by dots"),
        ("numerics..scheme=apic", "numerics..scheme: malformed key path; expected names and indices joined by dots"),
    ],
)
def test_malformed_overrides(text, message):
    with pytest.raises(ProjectError) as info:
        parse_override(text)
    assert problems(info) == [message]


def test_overrides_of_each_kind(project):
    changed = apply_overrides(
        project,
        [
            "numerics.scheme=apic",
            "domain.cell_size_m=0.01",
            "particles.per_cell=3",
            "materials.sand.friction_angle_deg=25",
            "bodies.0.polygon_m=[[0,0],[0.1,0],[0.1,0.1]]",
            "bodies.0.polygon_m.2=[0.05, 0.2]",
            "domain.boundaries.bottom={type = \"friction\", friction_angle_deg = 20}",
            "runout.title=Trial 3",
            "stages.1.damping.coefficient=0.5",
            "stages.1.material_changes.sand.cohesion_pa=100",
            "output.fields=[\"velocity\"]",
        ],
    )
    assert changed.numerics.scheme == "apic"
    assert changed.domain.cell_size_m == 0.01
    assert changed.particles.per_cell == 3
    assert changed.materials["sand"].friction_angle_deg == 25.0
    assert changed.bodies[0].polygon_m == ((0.0, 0.0), (0.1, 0.0), (0.05, 0.2))
    assert changed.domain.boundaries.bottom.friction_angle_deg == 20.0
    assert changed.runout.title == "Trial 3"
    assert changed.stages[1].damping is not None and changed.stages[1].damping.coefficient == 0.5
    assert changed.stages[1].material_changes["sand"].cohesion_pa == 100.0
    assert changed.output.fields == ("velocity",)
    # The original is untouched.
    assert project.numerics.scheme == "apic-affine" and project.domain.cell_size_m == 0.02


def test_time_step_and_cfl_replace_each_other(project):
    fixed = apply_overrides(project, ["numerics.time_step_s=1e-4"])
    assert fixed.numerics.time_step_s == 1e-4 and fixed.numerics.cfl is None
    adaptive = apply_overrides(fixed, ["numerics.cfl=0.3"])
    assert adaptive.numerics.cfl == 0.3 and adaptive.numerics.time_step_s is None


def test_boundary_string_becomes_a_table_when_a_key_inside_is_set(project):
    changed = apply_overrides(project, ["domain.boundaries.bottom.type=friction", "domain.boundaries.bottom.friction_angle_deg=15"])
    assert changed.domain.boundaries.bottom.type == "friction"
    assert changed.domain.boundaries.bottom.friction_angle_deg == 15.0


def test_structure_contact_string_becomes_a_table_when_a_key_inside_is_set(project):
    data = project.to_dict()
    data["structures"] = [{"name": "wall", "polygon_m": [[0.5, 0.0], [0.55, 0.0], [0.55, 0.1], [0.5, 0.1]]}]
    changed = apply_overrides(data, ["structures.0.contact.type=friction",
                                     "structures.0.contact.friction_angle_deg=25"])
    assert changed.structures[0].contact.type == "friction"
    assert changed.structures[0].contact.friction_angle_deg == 25.0
    data["structures"][0]["contact"] = "fixed"
    with pytest.raises(ProjectError) as info:  # the angle alone: the type the file gave stays
        apply_overrides(data, ["structures.0.contact.friction_angle_deg=25"])
    assert [str(p) for p in info.value.problems] == [
        'structures.0.contact.friction_angle_deg = 25: only allowed with type "friction"']


def test_overrides_on_raw_data_do_not_modify_it():
    data = document.parse_toml(MINIMAL)
    before = copy.deepcopy(data)
    changed = apply_overrides(data, ["numerics.scheme=mpm"])
    assert changed.numerics.scheme == "mpm"
    assert data == before


@pytest.mark.parametrize(
    ("override", "message"),
    [
        ("numerics.schem=apic", "numerics.schem: unknown key; allowed: scheme, time_step_s, cfl, precision, arch, preset, volumetric_averaging, advanced"),
        ("bodies.3.name=x", "bodies.3: no such item; bodies has indices 0 to 0"),
        ("bodies.first.name=x", "bodies.first: no such item; bodies has indices 0 to 0"),
        ("bodies.-1.name=x", "bodies.-1: no such item; bodies has indices 0 to 0"),
        # a list the file does not have: no items (was "structures is a value, not a table")
        ("structures.0.name=x", "structures.0: no such item; structures has no items"),
        ("targets.0.x_m=1", "targets.0: no such item; targets has no items"),
        ("materials.bars.cohesion_pa=0", "materials.bars: no such material; defined: sand"),
        ("domain.cell_size_m.x=1", "domain.cell_size_m.x: domain.cell_size_m is a value, not a table"),
        ("domain.origin_m.0=1", "domain.origin_m.0: domain.origin_m is a value, not a table"),
        (
            "materials.sand.colour=red",
            "materials.sand.colour: unknown key; allowed: model, density_kg_m3, youngs_modulus_pa, "
            "poisson_ratio, cohesion_pa, friction_angle_deg, dilatancy_angle_deg, tensile_strength_pa, "
            "mohr_coulomb_match, damping_ratio, damping_frequency_hz, damping_model, saturated_density_kg_m3, ru, "
            "softening_law, residual_cohesion_pa, residual_friction_angle_deg, residual_dilatancy_angle_deg, "
            "peak_plastic_strain, residual_plastic_strain, softening_length_m, mu_i_friction_increase, "
            "mu_i_reference_number, grain_diameter_m, grain_density_kg_m3, velocity_m_s, contact",
        ),
        ("stages.1.material_changes.sand.model=x", "stages.1.material_changes.sand.model: unknown key; allowed: "
         "density_kg_m3, youngs_modulus_pa, poisson_ratio, cohesion_pa, friction_angle_deg, dilatancy_angle_deg, "
         "tensile_strength_pa, damping_ratio, damping_frequency_hz, damping_model, saturated_density_kg_m3, ru, "
         "softening_law, residual_cohesion_pa, residual_friction_angle_deg, residual_dilatancy_angle_deg, "
         "peak_plastic_strain, residual_plastic_strain, softening_length_m, velocity_m_s"),
        ("materials.sand.poisson_ratio=0.6", "materials.sand.poisson_ratio = 0.6: must be >= 0 and < 0.5"),
        ("numerics.scheme=flip", 'numerics.scheme = "flip": must be one of "mpm", "apic", "apic-affine"'),
        ("runout.title=1", "runout.title = 1: must be a string"),
        ("particles.per_cell=two", 'particles.per_cell = "two": must be an integer'),
        ("bodies.0.material=clay", 'bodies.0.material = "clay": no such material; defined: sand'),
    ],
)
def test_override_errors_name_the_key(project, override, message):
    with pytest.raises(ProjectError) as info:
        apply_overrides(project, [override])
    assert problems(info) == [message]


def test_several_bad_override_paths_reported_together(project):
    with pytest.raises(ProjectError) as info:
        apply_overrides(project, ["numerics.schem=apic", "nothing", "stages.5.duration_s=1"])
    assert problems(info) == [
        "numerics.schem: unknown key; allowed: scheme, time_step_s, cfl, precision, arch, preset, volumetric_averaging, advanced",
        "nothing: expected KEY=VALUE",
        "stages.5: no such item; stages has indices 0 to 1",
    ]
