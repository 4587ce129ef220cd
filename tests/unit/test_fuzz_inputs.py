"""Fuzzing the project loader, the size check and ``runout validate``: bad input only ever gives
ProjectError (one line per problem), never another exception or a traceback.

Examples are derandomised and bounded so that the file stays fast and deterministic in CI.
"""

from __future__ import annotations

import copy
import math

import pytest
import tomlkit
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from projects.build import estimate
from projects.checks import project_warnings
from projects.document import loads_project, parse_toml
from projects.limits import limit_problems
from projects.schema import Project, ProjectError
from tests.conftest import TINY_PROJECT

BASE = parse_toml(TINY_PROJECT.read_text(encoding="utf-8"))
FUZZ = settings(max_examples=80, deadline=None, derandomize=True,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])

# values a user (or a broken tool) might put anywhere
NUMBERS = st.one_of(
    st.integers(min_value=-(2**63), max_value=2**63 - 1),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0, -1, 1, 5e-324, 1e-300, 1e-9, 1e9, 1e300, 2**53, 0.5, 89.999, 90.0]),
)
TEXT = st.one_of(
    st.text(max_size=12),
    st.sampled_from(["[/]", "[bold]x", "\ufeff", "5 kPa", "18 kN/m3", "-1 MPa", "1e999 Pa", "", " ",
                     "fixed", "friction", "k0", "gravity", "dynamic", "f64", "gpu", "apic", "nan"]),
)
SCALARS = st.one_of(NUMBERS, TEXT, st.booleans())
VALUES = st.recursive(SCALARS, lambda inner: st.one_of(
    st.lists(inner, max_size=4), st.dictionaries(st.text(max_size=6), inner, max_size=3)), max_leaves=8)


def _paths(node, prefix=()):
    """Every key path of the parsed example project."""
    if isinstance(node, dict):
        for key, value in node.items():
            yield (*prefix, key)
            yield from _paths(value, (*prefix, key))
    elif isinstance(node, list):
        for index, value in enumerate(node):
            yield (*prefix, index)
            yield from _paths(value, (*prefix, index))


PATHS = sorted(_paths(BASE), key=str)


def _mutate(data, path, value, delete):
    node = data
    for part in path[:-1]:
        node = node[part]
    if delete:
        if isinstance(node, list):
            node.pop(path[-1])
        else:
            node.pop(path[-1])
    else:
        node[path[-1]] = value
    return data


def _toml(data) -> str | None:
    try:
        return tomlkit.dumps(data)
    except (ValueError, TypeError, tomlkit.exceptions.TOMLKitError):
        return None  # not representable in TOML (e.g. a key TOML cannot hold): nothing to test


def _check_one_line_each(err: ProjectError) -> None:
    assert err.problems
    for problem in err.problems:
        assert "\n" not in str(problem), str(problem)


def _loads(text: str):
    try:
        return loads_project(text, source="fuzz.toml")
    except ProjectError as err:
        _check_one_line_each(err)
        return None


def _size_check(project: Project) -> None:
    """What validate does before building: estimate, limits, warnings. Never anything but ProjectError."""
    e = estimate(project)
    for key in ("particles", "grid_cells", "steps", "frames", "memory_bytes", "disk_bytes"):
        assert isinstance(e[key], int) and e[key] >= 0
    assert math.isfinite(float(e["time_step_s"])) or e["time_step_s"] == math.inf
    for problem in limit_problems(e, memory_bytes=1 << 40, disk_bytes=1 << 40):
        assert "\n" not in str(problem)
    for warning in project_warnings(project):
        assert "\n" not in warning


@FUZZ
@given(path=st.sampled_from(PATHS), value=VALUES, delete=st.booleans())
def test_one_changed_value_is_a_project_or_a_project_error(path, value, delete):
    data = _mutate(copy.deepcopy(BASE), path, value, delete)
    text = _toml(data)
    if text is None:
        return
    project = _loads(text)
    if project is not None:
        _size_check(project)


@FUZZ
@given(changes=st.lists(st.tuples(st.sampled_from(PATHS), NUMBERS), min_size=1, max_size=4))
def test_several_numbers_changed_at_once(changes):
    data = copy.deepcopy(BASE)
    for path, value in changes:
        try:
            data = _mutate(data, path, value, False)
        except (KeyError, IndexError, TypeError):
            continue
    text = _toml(data)
    if text is None:
        return
    project = _loads(text)
    if project is not None:
        _size_check(project)


SPECIAL_NUMBERS = (0, -1, 5e-324, 1e-300, 1e-9, 1e300, 2**63 - 1, float("nan"), float("inf"), -float("inf"))
def _get(node, path):
    for part in path:
        node = node[part]
    return node


NUMBER_PATHS = [path for path in PATHS
                if isinstance(_get(BASE, path), (int, float)) and not isinstance(_get(BASE, path), bool)]


@pytest.mark.parametrize("value", SPECIAL_NUMBERS, ids=repr)
def test_every_number_of_the_example_set_to_extremes(value):
    """The systematic part: each numeric key of the example in turn, set to each extreme."""
    assert len(NUMBER_PATHS) > 15
    for path in NUMBER_PATHS:
        text = _toml(_mutate(copy.deepcopy(BASE), path, value, False))
        project = _loads(text)
        if project is not None:
            _size_check(project)


@FUZZ
@given(text=st.one_of(
    st.text(max_size=200),
    st.builds(lambda cut, junk: TINY_PROJECT.read_text()[:cut] + junk,
              st.integers(0, 2000), st.text(max_size=20)),
))
def test_any_text_is_a_project_or_a_project_error(text):
    _loads(text)


@settings(max_examples=15, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(path=st.sampled_from(PATHS), value=VALUES)
def test_runout_validate_never_shows_a_traceback(tmp_path, path, value):
    from app.cli import cli

    data = _mutate(copy.deepcopy(BASE), path, value, False)
    text = _toml(data)
    if text is None:
        return
    file = tmp_path / "fuzz.toml"
    file.write_text(text, encoding="utf-8")
    result = CliRunner().invoke(cli, ["validate", str(file)])
    assert result.exit_code in (0, 1), (result.output, result.exception)
    assert result.exception is None or isinstance(result.exception, SystemExit), repr(result.exception)
    assert "Traceback" not in result.output
    if result.exit_code == 1:
        assert result.stderr.startswith("error: ")


@pytest.mark.parametrize("name", ["[/]", "[bold red]x[/]", "[link=file:///etc/passwd]x[/link]"])
def test_markup_in_user_names_is_shown_as_typed(tmp_path, name):
    from app.cli import cli

    data = copy.deepcopy(BASE)
    data["stages"][1]["name"] = name
    data["bodies"][0]["name"] = name
    data["materials"]["sand"]["cohesion_pa"] = -1.0  # an error that quotes nothing of the name
    data["bodies"][0]["material"] = name  # an error that quotes the name
    file = tmp_path / "markup.toml"
    file.write_text(tomlkit.dumps(data), encoding="utf-8")
    result = CliRunner().invoke(cli, ["validate", str(file)])
    assert result.exit_code == 1
    assert result.exception is None or isinstance(result.exception, SystemExit), repr(result.exception)
    assert f'bodies.0.material = "{name}"' in result.stderr


# --------------------------------------------------------------------------------------------
# sweep and calibration files, fuzzed as the projects are: a spec or one ProjectError line per
# problem, never another exception; a valid spec samples and checks its measures the same way


SWEEP_BASE = {
    "sweep": {"project": str(TINY_PROJECT), "sampling": "latin-hypercube", "runs": 4, "seed": 1,
              "set": ["stages.1.duration_s=0.02"], "threads_per_run": 1, "timeout_s": 60.0,
              "measures": ["hazard.runout_distance_m", "deposit.front_m", "summary.wall_time_s"]},
    "parameters": {
        "materials.sand.friction_angle_deg": {"distribution": "normal", "mean": 30.0, "std": 3.0, "low": 20.0,
                                              "high": 40.0, "levels": 3},
        "materials.sand.cohesion_pa": {"distribution": "range", "low": 0.0, "high": 100.0, "count": 3},
        "numerics.scheme": ["apic", "apic-affine"],
    },
    "profile": {"field": "peak_flow_height_m", "thresholds": [0.01, 0.02]},
}
CALIBRATION_BASE = {
    "calibration": {"project": str(TINY_PROJECT), "trials": 4, "seed": 2, "batch": 2, "optimizer": "tpe"},
    "parameters": {"materials.sand.friction_angle_deg": {"distribution": "uniform", "low": 20.0, "high": 40.0}},
    "observation": {"type": "measures", "values": {"hazard.runout_distance_m": 0.3, "deposit.front_m": 0.4},
                    "scales": {"hazard.runout_distance_m": 0.01}},
}
SPEC_PATHS = sorted([("sweep", p) for p in _paths(SWEEP_BASE)] + [("calibration", p) for p in _paths(CALIBRATION_BASE)],
                    key=str)
#: samples and measure checks only for specs of at most this many runs (each run resolves a project)
FEW_RUNS = 64


def _spec_or_error(text: str):
    from pathlib import Path

    from sweeps.spec import parse_spec

    try:
        return parse_spec(parse_toml(text, source="s.toml"), Path("."), source="s.toml")
    except ProjectError as err:
        _check_one_line_each(err)
        return None


def _use_spec(spec) -> None:
    """What `runout sweep` and `runout calibrate` do with a valid spec before Ray: sample, check
    the measures against the base project. Only ProjectError, one line per problem."""
    from sweeps.measures import measure_problems
    from sweeps.sampling import sample
    from sweeps.spec import MAX_RUNS, grid_runs

    base = loads_project(TINY_PROJECT.read_text())
    if hasattr(spec, "sweep"):
        runs = spec.sweep.runs if spec.sweep.sampling != "grid" else grid_runs(spec.parameters)
        assert runs is None or runs <= MAX_RUNS
        if runs is not None and runs <= FEW_RUNS:
            try:
                values = sample(spec)
            except ProjectError as err:
                _check_one_line_each(err)
            else:
                assert len(values) == runs
        keys = spec.sweep.measures
    else:
        assert spec.calibration.trials <= MAX_RUNS
        keys = list(spec.observation.values or {})
    for problem in measure_problems(keys, base, "measures"):
        assert "\n" not in str(problem)


@FUZZ
@given(pick=st.sampled_from(SPEC_PATHS), value=VALUES, delete=st.booleans())
def test_one_changed_value_of_a_sweep_file_is_a_spec_or_a_project_error(pick, value, delete):
    kind, path = pick
    data = _mutate(copy.deepcopy(SWEEP_BASE if kind == "sweep" else CALIBRATION_BASE), path, value, delete)
    text = _toml(data)
    if text is None:
        return
    spec = _spec_or_error(text)
    if spec is not None:
        _use_spec(spec)


SPEC_NUMBER_PATHS = [(kind, path) for kind, path in SPEC_PATHS
                     if isinstance(_get(SWEEP_BASE if kind == "sweep" else CALIBRATION_BASE, path), (int, float))
                     and not isinstance(_get(SWEEP_BASE if kind == "sweep" else CALIBRATION_BASE, path), bool)]


@pytest.mark.parametrize("value", (*SPECIAL_NUMBERS, 10**9, 2**70, -(2**70)), ids=repr)
def test_every_number_of_a_sweep_file_set_to_extremes(value):
    assert len(SPEC_NUMBER_PATHS) > 10
    for kind, path in SPEC_NUMBER_PATHS:
        data = _mutate(copy.deepcopy(SWEEP_BASE if kind == "sweep" else CALIBRATION_BASE), path, value, False)
        text = _toml(data)
        if text is None:
            continue
        spec = _spec_or_error(text)
        if spec is not None:
            _use_spec(spec)


@FUZZ
@given(text=st.one_of(
    st.text(max_size=200),
    st.builds(lambda cut, junk: tomlkit.dumps(SWEEP_BASE)[:cut] + junk, st.integers(0, 1200), st.text(max_size=20)),
))
def test_any_text_is_a_sweep_spec_or_a_project_error(text):
    _spec_or_error(text)


@settings(max_examples=15, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(pick=st.sampled_from(SPEC_PATHS), value=VALUES)
def test_runout_sweep_and_calibrate_never_show_a_traceback(tmp_path, monkeypatch, pick, value):
    from app.cli import cli

    kind, path = pick
    data = _mutate(copy.deepcopy(SWEEP_BASE if kind == "sweep" else CALIBRATION_BASE), path, value, False)
    text = _toml(data)
    if text is None:
        return
    spec = _spec_or_error(text)
    if spec is not None and hasattr(spec, "sweep"):
        from sweeps.spec import grid_runs

        runs = spec.sweep.runs if spec.sweep.sampling != "grid" else grid_runs(spec.parameters)
        if runs is not None and runs > FEW_RUNS:
            return  # its check resolves every run: seconds per thousand
    import typer

    def stand_in(*args, **kwargs):  # the checks passed: what Ray would run is not this test's
        raise typer.Exit(0)

    monkeypatch.setattr("sweeps.sweep.run_sweep", stand_in)
    monkeypatch.setattr("sweeps.calibrate.run_calibration", stand_in)
    file = tmp_path / "fuzz.toml"
    file.write_text(text, encoding="utf-8")
    command = "sweep" if kind == "sweep" else "calibrate"
    result = CliRunner().invoke(cli, [command, str(file)])
    assert "Traceback" not in result.output
    assert result.exception is None or isinstance(result.exception, SystemExit), repr(result.exception)
    if result.exit_code == 1:
        assert result.stderr.startswith("error: ") and len(result.stderr.strip().splitlines()) >= 1
