"""Bad input that used to hang, pass silently or lose work: each case is refused with one line, or
warned about, before any work starts, and the faults leave a folder with a final status and no
lock. Every case has a hard time limit (pytest-timeout), so a hang fails instead of hanging.

Hangs: huge sweeps (runs, grid levels, range counts, seeds), outlines of 100,000 points and more,
/dev/zero and FIFOs as input files. Silent acceptances: measure keys and profile fields that do
not exist, a time step past the stability limit, hazard rasters the size limits did not count,
non-finite or non-boolean strength-reduction keys, a monitor point outside the domain, a body too
fast for its domain, frames of NaN positions. Faults: a resume killed during its start-up,
Ctrl-C pressed again and again, a run started on a full disk.
"""

from __future__ import annotations

import copy
import errno
import json
import math
import os
import signal
import subprocess
import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from projects.build import estimate, resolve
from projects.document import apply_overrides, load_project, loads_project, parse_toml
from projects.schema import MAX_POLYGON_POINTS, MAX_TOTAL_POINTS, ProjectError, validate_project
from sweeps.spec import MAX_RUNS, parse_spec
from tests.conftest import REPO, SYNTHETIC_META, SYNTHETIC_PROJECT, TINY_PROJECT, synthetic_frames

#: in-process cases: seconds each, far above what they take (a hang fails here)
QUICK = pytest.mark.timeout(30)
#: cases that start a `runout run` process
PROCESS = pytest.mark.timeout(120)

BASE = parse_toml(TINY_PROJECT.read_text(encoding="utf-8"))
PHI = "materials.sand.friction_angle_deg"


def _one_line(err: ProjectError) -> str:
    text = str(err)
    assert err.problems and all("\n" not in str(p) for p in err.problems), text
    assert "Traceback" not in text
    return text


def _refused(data) -> str:
    with pytest.raises(ProjectError) as info:
        validate_project(data)
    return _one_line(info.value)


def _tiny(**changes):
    data = copy.deepcopy(BASE)
    for path, value in changes.items():
        node = data
        parts = path.split("__")
        for part in parts[:-1]:
            node = node[int(part)] if part.isdigit() else node[part]
        node[parts[-1]] = value
    return data


def _circle(n: int, centre=(0.3, 0.15), radius=0.1) -> list[list[float]]:
    t = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    return np.column_stack([centre[0] + radius * np.cos(t), centre[1] + radius * np.sin(t)]).tolist()


def _invoke(*args: str):
    from app.cli import cli

    return CliRunner().invoke(cli, list(args))


def _fails_in_one_line(result, *words: str) -> str:
    assert result.exit_code == 1, (result.output, result.exception)
    lines = result.output.strip().splitlines()
    errors = [ln for ln in lines if ln.startswith("error: ")]
    assert len(errors) == 1 and "Traceback" not in result.output, result.output
    for word in words:
        assert word in result.output, result.output
    return result.output


# --------------------------------------------------------------------------------------------
# hangs: sweeps and calibrations sized before anything is sampled


def _sweep(**table) -> dict:
    sweep = {"project": str(TINY_PROJECT), "sampling": "latin-hypercube", "runs": 2, **table}
    return {"sweep": {k: v for k, v in sweep.items() if v is not None},
            "parameters": {PHI: {"distribution": "uniform", "low": 20.0, "high": 35.0}}}


def _calibration(**table) -> dict:
    return {"calibration": {"project": str(TINY_PROJECT), **table},
            "parameters": {PHI: {"distribution": "uniform", "low": 20.0, "high": 35.0}},
            "observation": {"type": "measures", "values": {"hazard.runout_distance_m": 0.3}}}


def _spec_refused(data, *words: str) -> str:
    with pytest.raises(ProjectError) as info:
        parse_spec(data, Path("."), source="s.toml")
    text = _one_line(info.value)
    for word in words:
        assert word in text, text
    return text


@QUICK
@pytest.mark.parametrize("data, words", [
    (_sweep(runs=1_000_000_000), ["sweep.runs", "10,000"]),  # the case
    (_sweep(sampling="random", runs=1_000_000_000), ["sweep.runs", "10,000"]),
    (_sweep(sampling="random", runs=MAX_RUNS + 1), ["sweep.runs"]),
    (_calibration(trials=10**9), ["calibration.trials", "10,000"]),
], ids=["lhs-1e9", "random-1e9", "random-limit+1", "calibration-1e9"])
def test_a_sweep_of_a_billion_runs_is_refused_before_sampling(data, words):
    _spec_refused(data, *words)


@QUICK
@pytest.mark.parametrize("parameters, words", [
    ({PHI: {"distribution": "uniform", "low": 20.0, "high": 35.0, "levels": 100_000},
      "materials.sand.cohesion_pa": {"distribution": "uniform", "low": 0.0, "high": 10.0, "levels": 100_000}},
     ["levels = 100,000", "10,000"]),  # the case
    ({PHI: {"distribution": "uniform", "low": 20.0, "high": 35.0, "levels": 5000},
      "materials.sand.cohesion_pa": {"distribution": "uniform", "low": 0.0, "high": 10.0, "levels": 5000}},
     ["the grid has 25,000,000 runs", "5,000 x 5,000"]),
    ({PHI: {"distribution": "range", "low": 20.0, "high": 35.0, "count": 1_000_000_000}},
     ["count = 1,000,000,000"]),  # the range count
    ({PHI: list(range(101)), "materials.sand.cohesion_pa": list(range(101))},
     ["the grid has 10,201 runs"]),
], ids=["levels-1e5x1e5", "levels-5000x5000", "range-count-1e9", "lists-101x101"])
def test_a_grid_too_large_is_refused_before_its_levels_are_made(parameters, words):
    data = {"sweep": {"project": str(TINY_PROJECT), "sampling": "grid"}, "parameters": parameters}
    _spec_refused(data, *words)


@QUICK
@pytest.mark.parametrize("data", [
    _sweep(seed=2**70), _sweep(seed=-1), _sweep(seed=2**32), _calibration(seed=2**70),
], ids=["2**70", "-1", "2**32", "calibration-2**70"])
def test_seeds_outside_the_generators_range_are_refused(data):
    _spec_refused(data, "seed", "4294967295")


@QUICK
@pytest.mark.parametrize("data, words", [
    (_sweep(threads_per_run=2**40), ["threads_per_run", "1024"]),
    (_sweep(gpus_per_run=1e9), ["gpus_per_run"]),
    (_sweep(timeout_s=1e300), ["timeout_s"]),
    ({**_sweep(), "parameters": {f"a{i}.b": [1] for i in range(65)}}, ["65 parameters"]),
    ({**_sweep(), "parameters": {PHI: [1.0, 2**70]}}, ["64 bits"]),
], ids=["threads", "gpus", "timeout", "parameters", "big-integer"])
def test_other_sizes_of_a_sweep_file_are_bounded(data, words):
    _spec_refused(data, *words)


@QUICK
def test_the_command_line_refuses_a_huge_sweep_before_ray(tmp_path, monkeypatch):
    ran = []
    monkeypatch.setattr("sweeps.sweep.run_sweep", lambda *a, **k: ran.append(1))
    spec = tmp_path / "s.toml"
    spec.write_text(f'[sweep]\nproject = "{TINY_PROJECT}"\nsampling = "random"\nruns = 1000000000\n'
                    f'[parameters]\n"{PHI}" = {{distribution = "uniform", low = 20.0, high = 35.0}}\n', encoding="utf-8")
    _fails_in_one_line(_invoke("sweep", str(spec)), "sweep.runs")
    ok = tmp_path / "ok.toml"
    ok.write_text(f'[sweep]\nproject = "{TINY_PROJECT}"\nsampling = "grid"\n[parameters]\n"{PHI}" = [20.0]\n',
                  encoding="utf-8")
    for option, value in (("--workers", "1000000000"), ("--threads", "100000"), ("--gpus-per-run", "1e9")):
        _fails_in_one_line(_invoke("sweep", str(ok), option, value), option)
    assert not ran


@QUICK
def test_a_sweep_larger_than_the_free_disk_is_refused_before_its_folder(tmp_path, monkeypatch):
    from sweeps.sweep import run_sweep
    from sweeps.spec import SweepSpec

    spec = parse_spec({"sweep": {"project": str(TINY_PROJECT), "sampling": "grid"},
                       "parameters": {PHI: [20.0, 25.0, 30.0]}}, Path("."))
    assert isinstance(spec, SweepSpec)
    monkeypatch.setattr("projects.limits.free_disk_bytes", lambda path: 1000)
    monkeypatch.setattr("sweeps.sweep.RayEngine", lambda *a, **k: pytest.fail("Ray must not start"))
    with pytest.raises(ProjectError) as info:
        run_sweep(spec, tmp_path / "s.sweep")
    text = _one_line(info.value)
    assert text.startswith("sweep.runs = 3: the 3 runs would write about") and "1 kB free" in text
    assert not (tmp_path / "s.sweep").exists()


@QUICK
@pytest.mark.parametrize("nodes, threads, gpus, key", [
    ([{"CPU": 16.0, "GPU": 1.0}], 1, 2.0, "gpus_per_run"),
    ([{"CPU": 16.0}], 1, 0.5, "gpus_per_run"),
    ([{"CPU": 4.0}, {"CPU": 8.0}], 16, 0.0, "threads_per_run"),
    ([{"CPU": 8.0, "GPU": 2.0}], 8, 1.0, None),
], ids=["2-gpus-of-1", "gpu-of-none", "threads-of-8", "feasible"])
def test_a_request_no_ray_node_can_meet_is_named(nodes, threads, gpus, key):
    from sweeps.engine import infeasible

    problem = infeasible(nodes, threads, gpus)
    assert (problem.path if problem else None) == key
    if problem:
        assert "no run could start" in str(problem) and "\n" not in str(problem)


# --------------------------------------------------------------------------------------------
# hangs: outlines with very many points


@QUICK
@pytest.mark.parametrize("where, n", [
    ("bodies", 100_000), ("structures", 100_000), ("bodies", MAX_POLYGON_POINTS + 1), ("water", 100_000),
], ids=["body-1e5", "structure-1e5", "body-limit+1", "water-line-1e5"])
def test_an_outline_of_100000_points_is_refused_before_it_is_read(where, n):
    data = copy.deepcopy(BASE)
    if where == "bodies":
        data["bodies"][0]["polygon_m"] = _circle(n)
        path = "bodies.0.polygon_m"
    elif where == "structures":
        data["structures"] = [{"name": "wall", "polygon_m": _circle(n, (0.45, 0.1), 0.05)}]
        path = "structures.0.polygon_m"
    else:
        x = np.linspace(0.0, 0.6, n)
        data["water"] = {"phreatic_line_m": np.column_stack([x, 0.1 + 0 * x]).tolist()}
        path = "water.phreatic_line_m"
    text = _refused(data)
    assert path in text and f"{n:,} points" in text and f"{MAX_POLYGON_POINTS:,}" in text


@QUICK
def test_outlines_of_more_points_in_all_than_the_limit_are_refused():
    data = copy.deepcopy(BASE)
    n = MAX_POLYGON_POINTS
    data["bodies"] = [{"name": f"b{i}", "material": "sand", "polygon_m": _circle(n, (0.05 + 0.1 * i, 0.1), 0.04)}
                      for i in range(MAX_TOTAL_POINTS // n + 1)]
    text = _refused(data)
    assert text == (f"bodies: the outlines and water lines have {n * (MAX_TOTAL_POINTS // n + 1):,} points in all, "
                    f"more than the limit of {MAX_TOTAL_POINTS:,} (docs/project-format.md, size limits); simplify them")


@QUICK
@pytest.mark.parametrize("command, n", [("validate", 100_000), ("run", 30_000)])
def test_validate_and_run_refuse_a_100000_vertex_body_in_one_line(tmp_path, command, n):
    text = TINY_PROJECT.read_text().replace("polygon_m = [[0.0, 0.0], [0.12, 0.0], [0.12, 0.24], [0.0, 0.24]]",
                                             "polygon_m = " + json.dumps(np.round(_circle(n), 6).tolist()))
    path = tmp_path / "many.toml"
    path.write_text(text, encoding="utf-8")
    args = [command, str(path)] + (["--arch", "cpu", "-q"] if command == "run" else [])
    _fails_in_one_line(_invoke(*args), "bodies.0.polygon_m", f"{n:,} points")
    assert not (tmp_path / "many.results").exists()


@QUICK
def test_a_project_file_of_a_45_million_point_body_is_refused_by_its_size(tmp_path):
    from projects.inputs import MAX_PROJECT_FILE_BYTES

    path = tmp_path / "huge.toml"
    with open(path, "wb") as fh:  # sparse: 4.5 million points of about 25 bytes each
        fh.write(TINY_PROJECT.read_bytes())
        fh.truncate(4_500_000 * 25)
    with pytest.raises(ProjectError) as info:
        load_project(path)
    text = _one_line(info.value)
    assert text.startswith(f"{path}: the file is 112 MB, more than the limit of {MAX_PROJECT_FILE_BYTES / 1e6:g} MB")


@QUICK
def test_a_structure_of_16000_vertices_is_checked_in_little_memory():
    from projects.checks import structure_thickness_m

    n = 16_000
    t = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    ring = np.column_stack([0.3 + 0.05 * np.cos(t), 0.15 + 0.05 * np.sin(t)])
    tracemalloc.start()
    try:
        thick = structure_thickness_m(ring)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    # the inscribed circle of a 16,000-gon of radius 5 cm: 10 cm across to round-off
    assert thick == pytest.approx(0.1 * math.cos(math.pi / n), rel=1e-6)
    assert peak < 100e6, peak  # the lattice of signed distances took 10.7 GB


# --------------------------------------------------------------------------------------------
# hangs: input files that are not regular files


@pytest.fixture
def fifo(tmp_path):
    if not hasattr(os, "mkfifo"):
        pytest.skip("no FIFOs here")
    path = tmp_path / "pipe.toml"
    os.mkfifo(path)
    return path


def _special(kind: str, tmp_path: Path, fifo: Path | None = None) -> Path:
    if kind == "fifo":
        return fifo
    if kind == "folder":
        return tmp_path
    return Path({"zero": "/dev/zero", "urandom": "/dev/urandom", "null": "/dev/null"}[kind])


SPECIALS = ["zero", "fifo", "urandom", "null", "folder"]


@QUICK
@pytest.mark.parametrize("kind", SPECIALS)
def test_a_project_file_that_is_no_regular_file_is_one_line(kind, tmp_path, request):
    path = _special(kind, tmp_path, request.getfixturevalue("fifo") if kind == "fifo" else None)
    if not path.exists():
        pytest.skip(f"{path} is not on this system")
    with pytest.raises(ProjectError) as info:
        load_project(path)
    assert "not a regular file" in _one_line(info.value)
    _fails_in_one_line(_invoke("validate", str(path)), "not a regular file")


@QUICK
@pytest.mark.parametrize("kind", ["zero", "fifo"])
def test_a_sweep_or_observation_file_that_is_no_regular_file_is_one_line(kind, tmp_path, request):
    from sweeps.calibrate import read_observation
    from sweeps.spec import load_spec

    path = _special(kind, tmp_path, request.getfixturevalue("fifo") if kind == "fifo" else None)
    with pytest.raises(ProjectError) as info:
        load_spec(path)
    assert "not a regular file" in _one_line(info.value)
    data = {"calibration": {"project": str(TINY_PROJECT)},
            "parameters": {PHI: {"distribution": "uniform", "low": 20.0, "high": 35.0}},
            "observation": {"type": "deposit-profile", "file": str(path)}}
    spec = parse_spec(data, Path("."))
    with pytest.raises(ProjectError) as info:
        read_observation(spec)
    assert "not a regular file" in _one_line(info.value)


# --------------------------------------------------------------------------------------------
# silent acceptances: sweep measures and profile fields


@QUICK
@pytest.mark.parametrize("measure, words", [
    ("foo.bar", ["not a measure", '"summary."']),  # the case
    ("runout_distance_m", ["not a measure"]),  # a key without its prefix gave "-" for every run
    ("deposit.fornt_m", ["not a deposit measure", "deposit.front_m"]),
    ("summary", ['name the key after "summary."']),
], ids=["foo.bar", "no-prefix", "deposit-misspelt", "prefix-alone"])
def test_a_measure_that_is_no_measure_is_refused_in_the_file(measure, words):
    text = _spec_refused(_sweep(measures=["summary.steps", measure]), "sweep.measures.1", *words)
    assert "sweep.measures.0" not in text


@QUICK
@pytest.mark.parametrize("measure, words", [
    ("hazard.runout_distnce_m", ["hazard.json has no key 'runout_distnce_m'", "did you mean 'runout_distance_m'"]),
    ("summary.wall_time", ["summary.json has no key 'wall_time'", "did you mean 'wall_time_s'"]),
    ("hazard.targets.road.arrival_time_s", ["no target 'road'"]),
    ("hazard.thresholds.cell_size", ["thresholds has no key 'cell_size'"]),
], ids=["hazard-misspelt", "summary-misspelt", "no-such-target", "nested-misspelt"])
def test_a_measure_no_run_of_the_project_writes_is_refused_before_the_runs(measure, words):
    from sweeps.sweep import plan_sweep

    spec = parse_spec(_sweep(measures=["hazard.runout_distance_m", "summary.wall_time_s", measure]), Path("."))
    with pytest.raises(ProjectError) as info:
        plan_sweep(spec)
    text = _one_line(info.value)
    assert text.startswith(f'sweep.measures.2 = "{measure}": ')
    for word in words:
        assert word in text, text


@QUICK
def test_measures_of_a_project_with_targets_and_without_hazard_output(tmp_path):
    from sweeps.measures import measure_problems

    with_target = apply_overrides(load_project(TINY_PROJECT), ['targets=[{name = "road", x_m = 0.5}]'])
    assert measure_problems(["hazard.targets.road.arrival_time_s", "hazard.runout_distance_m",
                             "summary.steps", "deposit.front_m"], with_target, "sweep.measures") == []
    no_hazard = apply_overrides(load_project(TINY_PROJECT), ["hazard.enabled=false"])
    (problem,) = measure_problems(["hazard.runout_distance_m"], no_hazard, "sweep.measures")
    assert "hazard.enabled is false" in str(problem)


@QUICK
def test_a_calibration_observing_a_measure_without_its_prefix_is_refused():
    data = _calibration()
    data["observation"]["values"] = {"runout_distance_m": 0.3}
    _spec_refused(data, 'values."runout_distance_m"', "not a measure")


@QUICK
@pytest.mark.parametrize("field", ["peak_flow_heigth_m", "foo.bar", "deposit_height"])
def test_a_profile_field_that_does_not_exist_is_refused(field):
    data = _sweep()
    data["profile"] = {"field": field}
    _spec_refused(data, "profile.field", "peak_flow_height_m")


# --------------------------------------------------------------------------------------------
# silent acceptances: project keys


def _warnings(data) -> list[str]:
    from projects.checks import project_warnings

    return project_warnings(validate_project(data))


@QUICK
@pytest.mark.parametrize("changes, warned", [
    ({"numerics__time_step_s": 1.0}, "1,297 times the stability limit"),  # the case
    ({"numerics__time_step_s": 1e-3}, "1.3 times the stability limit"),
    ({"numerics__time_step_s": 7.5e-4}, None),  # just below dx / c_p = 7.7e-4 s
], ids=["1s", "1ms", "below"])
def test_a_time_step_past_the_stability_limit_is_warned_about(changes, warned):
    lines = [w for w in _warnings(_tiny(**changes)) if w.startswith("numerics.time_step_s")]
    if warned is None:
        assert lines == []
    else:
        assert len(lines) == 1 and warned in lines[0] and "materials.sand" in lines[0], lines


@QUICK
def test_a_time_step_past_the_limit_of_a_later_stage_is_warned_about():
    data = _tiny()
    data["stages"][1]["material_changes"] = {"sand": {"youngs_modulus_pa": 1e8}}  # c_p 10 x higher
    (line,) = [w for w in _warnings(data) if w.startswith("numerics.time_step_s")]
    assert "stages.1.material_changes.sand" in line


@QUICK
def test_validate_prints_the_time_step_warning_and_still_says_what_it_would_run():
    result = _invoke("validate", str(TINY_PROJECT), "--set", "numerics.time_step_s=1.0")
    assert result.exit_code == 0
    assert "warning: numerics.time_step_s = 1: 1,297 times the stability limit" in result.output


@QUICK
@pytest.mark.parametrize("cell, key, what", [
    (1e-7, "hazard.cell_size_m", "hazard raster cells"),  # the case: 288 TB allocated later
    (2e-5, "hazard.cell_size_m", "hazard raster cells"),
    (1e-6, "hazard.cell_size_m", "of memory"),
], ids=["1e-7", "2e-5", "1e-6-memory"])
def test_a_hazard_raster_is_counted_by_the_size_limits(cell, key, what):
    from projects.limits import check_limits

    project = validate_project(_tiny(hazard={"cell_size_m": cell}))
    e = estimate(project)
    assert e["hazard_cells"] == pytest.approx((0.6 / cell) * (0.3 / cell), rel=1e-6)
    with pytest.raises(ProjectError) as info:
        check_limits(e, memory_bytes=8 * 10**9, disk_bytes=10**15)
    problems = [p for p in info.value.problems if what in p.message]
    assert problems and problems[0].path == key, str(info.value)
    assert estimate(validate_project(_tiny(hazard={"enabled": False, "cell_size_m": cell})))["hazard_cells"] == 0


@QUICK
def test_a_hazard_raster_past_the_limits_over_a_structure_is_refused_before_its_floor_is_built():
    from projects.runner import check_project

    data = _tiny(hazard={"cell_size_m": 1e-9})
    data["structures"] = [{"name": "wall", "polygon_m": _circle(5000, (0.45, 0.1), 0.05)}]
    project = validate_project(data)
    with pytest.raises(ProjectError) as info:  # the floor: one value per column, 6e8 of them
        check_project(project, out_dir=Path("/nonexistent/r.results"))
    assert "hazard raster cells" in _one_line(info.value)
    assert resolve(project, seed=False).config.envelopes.ground_m is None  # a live estimate resolves it too
    fine = validate_project(_tiny(structures=data["structures"]))
    assert len(resolve(fine, seed=False).config.envelopes.ground_m) == 30  # one per grid column


@QUICK
def test_a_hazard_raster_finer_than_the_particles_is_warned_about():
    (line,) = [w for w in _warnings(_tiny(hazard={"cell_size_m": 2e-4})) if w.startswith("hazard.cell_size_m")]
    assert "finer than the particle spacing (0.01 m)" in line
    assert [w for w in _warnings(_tiny(hazard={"cell_size_m": 0.01})) if w.startswith("hazard.")] == []


def _strength(**keys):
    data = _tiny()
    data["stages"].insert(1, {"type": "strength-reduction", "trial_duration_s": 0.1, **keys})
    return data


@QUICK
@pytest.mark.parametrize("keys, path, words", [
    ({"limit_equilibrium": "yes"}, "stages.1.limit_equilibrium", "must be true or false"),  # the case
    ({"limit_equilibrium": 1}, "stages.1.limit_equilibrium", "must be true or false"),
    ({"first_trial": float("inf")}, "stages.1.first_trial", "from 0.05 to 50"),  # 1e400 in TOML is inf
    ({"first_trial": 10**400}, "stages.1.first_trial", "from 0.05 to 50"),
    ({"first_trial": 1e-9}, "stages.1.first_trial", "from 0.05 to 50"),
    ({"first_trial": 1e9}, "stages.1.first_trial", "from 0.05 to 50"),
    ({"failure": {"monitor_point_m": [5.0, 0.1]}}, "stages.1.failure.monitor_point_m", "must lie in the domain"),
    ({"failure": {"monitor_point_m": [0.3, -0.5]}}, "stages.1.failure.monitor_point_m", "must lie in the domain"),
], ids=["le-yes", "le-1", "first-inf", "first-10**400", "first-tiny", "first-huge", "monitor-right",
        "monitor-below"])
def test_strength_reduction_keys_are_checked(keys, path, words):
    text = _refused(_strength(**keys))
    assert f"{path} = " in text and words in text, text


@QUICK
def test_first_trial_1e400_in_a_file_is_refused():
    text = TINY_PROJECT.read_text().replace(
        '[[stages]]\nname = "collapse"',
        '[[stages]]\ntype = "strength-reduction"\ntrial_duration_s = 0.1\nfirst_trial = 1e400\n\n'
        '[[stages]]\nname = "collapse"')
    with pytest.raises(ProjectError) as info:
        loads_project(text, source="p.toml")
    assert "stages.1.first_trial = inf: must be a number from 0.05 to 50" in _one_line(info.value)
    ok = validate_project(_strength(first_trial=1.5, limit_equilibrium=True,
                                    failure={"monitor_point_m": [0.05, 0.2]}))
    assert ok.stages[1].first_trial == 1.5


@QUICK
@pytest.mark.parametrize("velocity, words", [
    ([1e6, 0.0], "crosses the whole domain"),  # the case
    ([0.0, -5e3], "crosses the whole domain"),
    ([40.0, 0.0], "faster than the P-wave speed of materials.sand"),
], ids=["1e6", "down-5e3", "supersonic"])
def test_a_body_too_fast_for_its_domain_is_warned_about(velocity, words):
    data = _tiny(output={"interval_s": 0.001})  # at 40 m/s the column crosses 0.6 m in 15 ms
    data["bodies"][0]["initial_velocity_m_s"] = velocity
    (line,) = [w for w in _warnings(data) if w.startswith("bodies.0.initial_velocity_m_s")]
    assert words in line
    data["bodies"][0]["initial_velocity_m_s"] = [2.0, 0.0]
    assert [w for w in _warnings(data) if w.startswith("bodies.0")] == []


@QUICK
@pytest.mark.parametrize("where", ["material", "stage-change"])
def test_a_material_whose_wave_speed_underflows_is_refused(where):
    data = _tiny()
    if where == "material":
        data["materials"]["sand"]["youngs_modulus_pa"] = 5e-324
        path = "materials.sand.youngs_modulus_pa"
    else:
        data["stages"][1]["material_changes"] = {"sand": {"youngs_modulus_pa": 5e-324}}
        path = "stages.1.material_changes.sand.youngs_modulus_pa"
    text = _refused(data)
    assert text.startswith(f"{path} = 5e-324: gives a P-wave speed of 0 m/s"), text


# --------------------------------------------------------------------------------------------
# silent acceptances: a frame of NaN positions


def _nan_results(tmp_path: Path, how: str) -> Path:
    import dataclasses

    from projects.results import ResultsWriter

    out = tmp_path / f"{how}.results"
    writer = ResultsWriter(out, SYNTHETIC_PROJECT, dict(SYNTHETIC_META))
    for k, frame in enumerate(synthetic_frames(3, lose_last=0)):
        fields = dict(frame.fields)
        if k == 2:
            positions = fields["positions"].copy()
            positions[: len(positions) if how == "all" else 10] = np.nan
            fields["positions"] = positions
            if how == "values":
                d = fields["displacement"].copy()
                d[20:25] = np.inf
                fields["displacement"] = d
        writer.write_frame(dataclasses.replace(frame, fields=fields))
    writer.close("failed", "unstable on purpose")
    return out


@QUICK
@pytest.mark.parametrize("how", ["some", "values"])
def test_a_frame_of_nan_positions_is_said_not_drawn_silently(tmp_path, how):
    from app.render import _particle_box, _say_undrawable, drawable
    from projects.results import Results

    res = Results(_nan_results(tmp_path, how))
    said: list[str] = []
    arrays = res.frame(2)
    _say_undrawable(arrays, 2, "displacement", said.append, alone=True)
    assert said[0] == ("frame 2: 10 of 800 particles have positions that are NaN or inf (the run went unstable: "
                       "see its summary.json); they are not drawn")
    if how == "values":
        assert said[1] == "frame 2: 5 particles have a displacement that is NaN or inf; they are drawn in the no-data colour"
    shown = drawable(arrays)
    assert int(shown.sum()) == 790
    box = _particle_box(np.asarray(arrays["positions"])[shown])
    assert all(math.isfinite(v) for v in box)  # the picture's bounds: NaN made them NaN
    said.clear()
    _say_undrawable(res.frame(1), 1, "displacement", said.append, alone=False)
    assert said == []


@QUICK
def test_a_frame_of_nothing_but_nan_positions_is_an_error_for_render(tmp_path):
    from app.render import render_frame

    out = _nan_results(tmp_path, "all")
    with pytest.raises(ValueError, match="frame 2: all 800 particle positions are NaN or inf, nothing to draw"):
        render_frame(out, 2, "displacement", tmp_path / "x.png", size=(320, 200))
    _fails_in_one_line(_invoke("render", str(out), "--frame", "2", "-o", str(tmp_path / "x.png")),
                       "nothing to draw")
    assert not (tmp_path / "x.png").exists()


# --------------------------------------------------------------------------------------------
# faults: a resume killed during its start-up


INTERVAL = 0.05


def _stopped_folder(tmp_path: Path) -> Path:
    """A run stopped between two output times: frames at 0, 0.05, 0.1 and the stop frame at 0.12,
    its checkpoint at the stop (4 frames), as a SIGTERM leaves it."""
    import dataclasses

    from projects.results import ResultsWriter, write_checkpoint
    from solver.config import Checkpoint

    out = tmp_path / "stopped.results"
    writer = ResultsWriter(out, TINY_PROJECT.read_text(), dict(SYNTHETIC_META))
    frames = synthetic_frames(4, lose_last=0)
    for k, frame in enumerate(frames):
        t = 0.12 if k == 3 else INTERVAL * k
        writer.write_frame(dataclasses.replace(frame, diagnostics=dataclasses.replace(frame.diagnostics, time_s=t)))
    writer.close("stopped", "stopped by SIGTERM")
    cursor = {"stage_index": 1, "phase": "loop", "next_output_s": 0.15, "last_output_step": 60, "frames": 4,
              "reason": "", "dt_s": 1e-3}
    write_checkpoint(out, Checkpoint(run={"time_s": 0.12, "cursor": cursor, "contacts_since_s": 0.12},
                                     arrays={"x": np.zeros((4, 2))}, fingerprint="f"))
    return out


def _checkpoint_frames(out: Path) -> int:
    from projects.results import read_checkpoint

    return int(read_checkpoint(out).run["cursor"]["frames"])


@QUICK
def test_a_resume_writes_its_checkpoint_before_it_removes_the_stop_frame(tmp_path, monkeypatch):
    import types

    from projects import runner

    out = _stopped_folder(tmp_path)
    seen = {}

    class Sim:
        def restore(self, checkpoint):
            seen["restored"] = checkpoint.run["cursor"]["frames"]

        def close(self):
            pass

    def killed_writer(out_dir, text, meta, keep_frames=None, **kwargs):
        # what a kill at this moment leaves: the checkpoint on disk says what the writer keeps
        seen["on_disk"], seen["keep"] = _checkpoint_frames(out), keep_frames
        raise KeyboardInterrupt

    resolved = types.SimpleNamespace(config=types.SimpleNamespace(output=types.SimpleNamespace(interval_s=INTERVAL),
                                                                  structures=[]),
                                     project=load_project(TINY_PROJECT))
    monkeypatch.setattr(runner, "check_project", lambda *a, **k: resolved)
    monkeypatch.setattr(runner, "_simulation", lambda r: Sim())
    monkeypatch.setattr(runner, "_meta", lambda *a, **k: {})
    monkeypatch.setattr(runner, "ResultsWriter", killed_writer)
    with pytest.raises(KeyboardInterrupt):
        runner.resume_run(out)
    assert seen == {"restored": 3, "on_disk": 3, "keep": 3}


@QUICK
@pytest.mark.parametrize("kept", [3, 4], ids=["stop-frame-gone", "stop-frame-there"])
def test_a_folder_left_one_frame_short_of_its_checkpoint_goes_on(tmp_path, kept):
    from projects.results import Results, ResultsWriter
    from projects.runner import _with_frames_on_disk, _without_stop_frame, resumable

    out = _stopped_folder(tmp_path)
    if kept == 3:  # an earlier version's resume killed after the writer's take-over
        ResultsWriter(out, TINY_PROJECT.read_text(), {}, keep_frames=3).close("stopped", "killed")
    checkpoint = resumable(out)
    assert checkpoint.run["cursor"]["frames"] == 4 and len(Results(out)) == kept
    fixed = _with_frames_on_disk(_without_stop_frame(checkpoint, out, INTERVAL, []), out, INTERVAL)
    assert fixed.run["cursor"]["frames"] == 3 and fixed.run["cursor"]["last_output_step"] == -1
    writer = ResultsWriter(out, TINY_PROJECT.read_text(), {}, keep_frames=3)  # it holds what the checkpoint needs
    writer.close("stopped", "checked")


@QUICK
def test_a_folder_short_of_frames_otherwise_says_what_to_do(tmp_path):
    from projects.results import ResultsError, ResultsWriter

    out = _stopped_folder(tmp_path)
    with pytest.raises(ResultsError) as info:
        ResultsWriter(out, TINY_PROJECT.read_text(), {}, keep_frames=9)
    assert "holds 4 complete frames and its checkpoint needs 9" in str(info.value)
    assert "--overwrite" in str(info.value) and "\n" not in str(info.value)
    assert not (out / ".runout-results.lock").exists()


# --------------------------------------------------------------------------------------------
# faults: Ctrl-C again and again


@QUICK
def test_a_repeated_ctrl_c_interrupts_once_and_never_while_the_folder_is_finished():
    from app.console import stop_on_signals
    from projects.runner import StopRequest

    stop = StopRequest()
    raised = 0
    with stop_on_signals(stop):
        for _ in range(4):
            try:
                os.kill(os.getpid(), signal.SIGINT)
                time.sleep(0.01)  # the handler runs at the next bytecode
            except KeyboardInterrupt:
                raised += 1
        assert raised == 1 and stop.requested and stop.reason == "SIGINT"
        late = StopRequest()
        late.request("SIGINT")
        late.finishing()
        assert not late.may_interrupt()


def _runout(*args: str, **kwargs) -> subprocess.Popen:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")]),
               ENABLE_TAICHI_HEADER_PRINT="0")
    return subprocess.Popen([sys.executable, "-m", "app", *args], env=env, cwd=REPO, text=True, **kwargs)


@PROCESS
def test_three_ctrl_c_50_ms_apart_leave_a_final_status_and_no_lock(tmp_path):
    out = tmp_path / "r.results"
    proc = _runout("run", str(TINY_PROJECT), "--out", str(out), "--arch", "cpu", "-q",
                   "--set", "stages.1.duration_s=5.0", stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 90
        while not ((out / "frames").is_dir() and len(list((out / "frames").glob("*.vtp"))) >= 2):
            assert proc.poll() is None, proc.communicate()[1]
            assert time.monotonic() < deadline, "the run wrote no frames"
            time.sleep(0.05)
        for _ in range(3):
            proc.send_signal(signal.SIGINT)
            time.sleep(0.05)
        stderr = proc.communicate(timeout=60)[1]
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "stopped" and ("SIGINT" in summary["message"] or "Ctrl-C" in summary["message"])
    assert not (out / ".runout-results.lock").exists()
    assert "Traceback" not in stderr and "Error" not in stderr, stderr
    # the run had started: the second Ctrl-C stopped it, the third changed nothing (it was said to
    # have stopped "before the run started")
    assert stderr.strip().splitlines()[-1].startswith("stopped: "), stderr


# --------------------------------------------------------------------------------------------
# faults: a full disk


@QUICK
def test_a_run_with_force_onto_a_full_disk_is_refused_before_anything_is_built(tmp_path, monkeypatch):
    from projects.runner import check_project

    monkeypatch.setattr("projects.limits.free_disk_bytes", lambda path: 0)
    with pytest.raises(ProjectError) as info:
        check_project(load_project(TINY_PROJECT), force=True, out_dir=tmp_path / "r.results")
    assert "only 0 B of disk is free" in _one_line(info.value) and "--force cannot make room" in str(info.value)
    result = _invoke("run", str(TINY_PROJECT), "--out", str(tmp_path / "r.results"), "--force", "-q")
    _fails_in_one_line(result, "--force cannot make room")
    assert not (tmp_path / "r.results").exists()


def _no_space(*args, **kwargs):
    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


@QUICK
@pytest.mark.parametrize("where", ["lock", "marker", "writer"])
def test_a_disk_that_fills_as_the_run_starts_leaves_no_lock_and_no_folder(tmp_path, monkeypatch, where):
    from projects import results, results_folder
    from projects.results import ResultsError, ResultsWriter

    if where == "lock":
        monkeypatch.setattr(results_folder.os, "write", _no_space)
    elif where == "marker":
        monkeypatch.setattr(results_folder, "write_marker", _no_space)
    else:
        monkeypatch.setattr(results, "write_atomic", _no_space)
    out = tmp_path / "new.results"
    with pytest.raises(ResultsError, match="No space left on device"):
        ResultsWriter(out, SYNTHETIC_PROJECT, dict(SYNTHETIC_META))
    assert not out.exists()
    # an existing folder of the user's is kept, without a lock or files of the run
    out.mkdir()
    with pytest.raises(ResultsError, match="No space left on device"):
        ResultsWriter(out, SYNTHETIC_PROJECT, dict(SYNTHETIC_META))
    assert out.is_dir() and list(out.iterdir()) == []


# --------------------------------------------------------------------------------------------
# a run that completes with nothing left in it


@PROCESS
def test_a_run_whose_particles_all_leave_says_so(tmp_path):
    out = tmp_path / "fast.results"
    proc = _runout("run", str(TINY_PROJECT), "--out", str(out), "--arch", "cpu",
                   "--set", "bodies.0.initial_velocity_m_s=[1e6, 0]", stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    stdout, stderr = proc.communicate(timeout=110)
    assert proc.returncode == 0, stderr
    assert "warning: bodies.0.initial_velocity_m_s = [1e+06, 0]: at 1e+06 m/s the body" in stderr
    assert "warning: every particle had left the grid by t = 0.01 s" in stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["warnings"] == ["every particle had left the grid by t = 0.01 s (lost_particles in series.csv): "
                                   "the results after that hold nothing to measure"]
    assert resolve(load_project(TINY_PROJECT), seed=False).particle_count == summary["particles"]
