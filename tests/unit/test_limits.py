"""Sizes are estimated and checked before anything is allocated; errors name key, estimate, limit."""

from __future__ import annotations

import math

import pytest
from typer.testing import CliRunner

from projects.build import MAX_COUNT, estimate
from projects.document import apply_overrides, load_project
from projects.limits import LIMITS, MIN_FREE_DISK_BYTES, check_limits, limit_problems
from projects.runner import check_project
from projects.schema import ProjectError
from tests.conftest import TINY_PROJECT

PLENTY = 1 << 50  # bytes: a machine that never runs out


@pytest.fixture(scope="module")
def tiny():
    return load_project(TINY_PROJECT)


def test_the_estimate_of_the_tiny_example(tiny):
    e = estimate(tiny)
    # 0.12 m x 0.24 m at 2 x 2 points per 0.02 m cell: 6 x 12 cells x 4 = 288, exact for lattice seeding
    assert e["particles"] == 288
    assert e["grid_shape"] == (30, 15) and e["grid_cells"] == 450
    assert e["grid_nodes"] == (30 + 5) * (15 + 5)
    assert e["steps"] == 250 and e["frames"] == 6
    assert e["bytes_per_particle"] > 17 * 4 and e["bytes_per_node"] == 7 * 4
    assert e["memory_bytes"] >= 288 * e["bytes_per_particle"] + e["grid_nodes"] * e["bytes_per_node"]
    assert e["disk_bytes"] >= e["frames"] * e["frame_bytes"]
    check_limits(e, memory_bytes=PLENTY, disk_bytes=PLENTY)


def test_f64_needs_more_memory_per_particle(tiny):
    f32 = estimate(tiny)
    f64 = estimate(apply_overrides(tiny, ["numerics.precision=f64"]))
    assert f64["bytes_per_particle"] > f32["bytes_per_particle"]
    assert f64["bytes_per_node"] == 2 * f32["bytes_per_node"]


def _denormal_flushed(tiny, override):
    """In a process where a library set flush-to-zero (seen in the full suite after Taichi runs),
    5e-324 reads as 0.0 and the schema refuses it (one line): that is an answer too."""
    try:
        return apply_overrides(tiny, [override])
    except ProjectError as err:
        assert "5e-324" in override and "must be > 0" in str(err) and "\n" not in str(err)
        return None


@pytest.mark.parametrize(
    "override, key, what",
    [
        ("domain.cell_size_m=1e-5", "domain.cell_size_m", "grid cells"),
        ("domain.cell_size_m=5e-324", "domain.cell_size_m", "grid cells"),  # denormal: was NaN to int
        ("numerics.time_step_s=1e-300", "numerics.time_step_s", "time steps"),
        ("stages.1.duration_s=1e300", "numerics.time_step_s", "time steps"),
        ("output.interval_s=1e-9", "output.interval_s", "frames"),
    ],
)
def test_runs_beyond_the_stated_limits_are_refused_naming_key_estimate_and_limit(tiny, override, key, what):
    project = _denormal_flushed(tiny, override)
    if project is None:
        return
    e = estimate(project)  # never raises, whatever the sizes
    with pytest.raises(ProjectError) as info:
        check_limits(e, memory_bytes=PLENTY, disk_bytes=PLENTY)
    problems = [p for p in info.value.problems if what in p.message]
    assert problems, str(info.value)
    assert problems[0].path == key
    assert "more than the limit of" in problems[0].message and "--force" in problems[0].message
    assert all("\n" not in str(p) for p in info.value.problems)
    # the determined may, on a disk with room to start (projects.limits.start_problems)
    check_limits(e, force=True, memory_bytes=1, disk_bytes=MIN_FREE_DISK_BYTES)
    with pytest.raises(ProjectError, match="--force cannot make room"):
        check_limits(e, force=True, memory_bytes=1, disk_bytes=MIN_FREE_DISK_BYTES - 1)


def test_a_huge_domain_is_refused_before_anything_is_built(tiny):
    project = apply_overrides(tiny, ["domain.size_m=[1e9, 1e9]"])
    e = estimate(project)
    assert e["grid_cells"] == MAX_COUNT or e["grid_cells"] > 1e20
    with pytest.raises(ProjectError, match="grid cells"):
        check_project(project)


def test_memory_and_disk_of_the_machine(tiny):
    e = estimate(tiny)
    problems = limit_problems(e, memory_bytes=1000, disk_bytes=1000, out_dir="/somewhere/r.results")
    assert [p.path for p in problems] == ["domain.cell_size_m", "output.interval_s"]
    assert "of memory, more than the 1 kB available" in problems[0].message
    assert "of disk" in problems[1].message and "free in /somewhere/r.results" in problems[1].message


def test_the_stated_limits_are_documented():
    text = (TINY_PROJECT.parents[2] / "docs" / "project-format.md").read_text()
    for limit in LIMITS:
        assert f"{limit.maximum:.3g}" in text or f"{limit.maximum:,.0f}" in text, limit


def test_validate_on_the_command_line_refuses_and_force_accepts(tmp_path):
    from app.cli import cli

    runner = CliRunner()
    bad = runner.invoke(cli, ["validate", str(TINY_PROJECT), "--set", "output.interval_s=1e-9"])
    assert bad.exit_code == 1
    assert "output.interval_s = 1e-09: the run would take about" in bad.stderr
    assert "Traceback" not in bad.output
    forced = runner.invoke(cli, ["validate", str(TINY_PROJECT), "--set", "output.interval_s=1e-9", "--force"])
    assert forced.exit_code == 0, forced.output
    assert forced.stdout.startswith("ok: 288 particles")


def test_estimate_counts_are_finite_numbers(tiny):
    project = _denormal_flushed(tiny, "domain.cell_size_m=5e-324")
    if project is None:
        return
    e = estimate(project)
    for key in ("particles", "grid_cells", "steps", "frames", "memory_bytes", "disk_bytes"):
        assert isinstance(e[key], int) and 0 <= e[key] <= MAX_COUNT, key
    assert math.isfinite(e["time_step_s"])


def test_a_denormal_cell_size_past_the_limits_is_still_one_line(tmp_path):
    from app.cli import cli

    result = CliRunner().invoke(cli, ["validate", str(TINY_PROJECT), "--set", "domain.cell_size_m=5e-324", "--force"])
    assert result.exit_code == 1
    assert result.exception is None or isinstance(result.exception, SystemExit), repr(result.exception)
    # "cannot seed the bodies", or "must be > 0" where flush-to-zero is on (see _denormal_flushed)
    assert "domain.cell_size_m = " in result.stderr  # 5e-324, or 0.0 once flushed
    assert len(result.stderr.strip().splitlines()) == 1


@pytest.mark.parametrize("where", ["materials.sand", "stages.1.material_changes.sand"])
def test_a_step_count_driven_by_material_damping_blames_the_damping(tiny, where):
    # 0.99 of critical at 1 mHz damps the grid's modes some 1e5 times critical: the step falls with it
    project = apply_overrides(tiny, ["numerics.cfl=0.5", f"{where}.damping_ratio=0.99",
                                     f"{where}.damping_frequency_hz=0.001"])
    e = estimate(project)
    assert e["time_step_shrink_by_damping"] > 1e4
    with pytest.raises(ProjectError) as info:
        check_limits(e, memory_bytes=PLENTY, disk_bytes=PLENTY)
    [problem] = [p for p in info.value.problems if "time steps" in p.message]
    assert problem.path == f"{where}.damping_ratio"
    assert "times shorter for the material's damping" in problem.message and "\n" not in str(problem)
    # a little damping that costs less than half the step leaves the blame with cfl
    light = estimate(apply_overrides(tiny, ["numerics.cfl=0.5", "materials.sand.damping_ratio=0.01",
                                            "materials.sand.damping_frequency_hz=100",
                                            "stages.1.duration_s=1e300"]))
    assert light["time_step_shrink_by_damping"] < 2.0
    with pytest.raises(ProjectError) as info:
        check_limits(light, memory_bytes=PLENTY, disk_bytes=PLENTY)
    assert [p.path for p in info.value.problems if "time steps" in p.message] == ["numerics.cfl"]


def test_validate_prints_the_time_step_and_what_damping_costs_of_it():
    from app.cli import cli

    runner = CliRunner()
    plain = runner.invoke(cli, ["validate", str(TINY_PROJECT), "--set", "numerics.cfl=0.5"])
    damped = runner.invoke(cli, ["validate", str(TINY_PROJECT), "--set", "numerics.cfl=0.5",
                                 "--set", "materials.sand.damping_ratio=0.1",
                                 "--set", "materials.sand.damping_frequency_hz=5"])
    assert plain.exit_code == 0 and damped.exit_code == 0, damped.output
    assert "cfl 0.5 (dt " in plain.stdout and "shorter" not in plain.stdout
    assert "x shorter for the damping of materials.sand)" in damped.stdout
