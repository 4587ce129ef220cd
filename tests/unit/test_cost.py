"""The pre-run estimate of a run's wall time (projects.cost): start-up plus steps costing a + b N,
from the project's own run, the machine's runs or the shipped measurements; `runout validate`
prints it."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from projects.cost import STEP_COSTS, describe, estimate_run_time, machine_step_cost, own_run, run_time, step_cost

EXAMPLES = Path(__file__).resolve().parents[2] / "projects" / "examples"


def test_the_cost_per_particle_step_falls_with_the_size():
    cpu = STEP_COSTS["cpu"]
    # a small model pays the per-step overhead: many times the large model's cost per particle-step
    small, large = cpu.step_s(288) / 288, cpu.step_s(200_000) / 200_000
    assert small > 10 * large
    assert cpu.step_s(20_000) == pytest.approx(2.2e-4 + 6.1e-8 * 20_000)
    assert cpu.step_s(998, structures=True) - cpu.step_s(998) == pytest.approx(8.2e-4)
    assert cpu.run_s(1000, 100) == pytest.approx(cpu.startup_s + 100 * cpu.step_s(1000))


def test_a_projects_own_run_sets_the_cost_near_its_size(tmp_path):
    (tmp_path / "summary.json").write_text(json.dumps(
        {"arch": "cpu", "particles": 1000, "step_time_s": 2.0e-3, "startup_s": 6.0, "structures": []}))
    own = own_run(tmp_path, "cpu")
    assert own == {"particles": 1000.0, "step_time_s": 2.0e-3, "startup_s": 6.0, "structures": False}
    assert own_run(tmp_path, "gpu") is None  # measured on another device
    cost = step_cost("cpu", 1000, own=own)
    assert cost.step_s(1000) == pytest.approx(2.0e-3) and cost.startup_s == 6.0
    # at twice the size along the model's shape through that point
    base = STEP_COSTS["cpu"]
    assert cost.step_s(2000) == pytest.approx(2.0e-3 * base.step_s(2000) / base.step_s(1000))
    # far from its size (more than 4 times) the run says nothing: the model stands
    assert step_cost("cpu", 10_000, own=own) is base


def test_the_machines_runs_scale_the_model_by_their_median_ratio():
    base = STEP_COSTS["cpu"]
    runs = [(288, 3 * base.step_s(288), False), (2000, 2 * base.step_s(2000), False),
            (998, 2.5 * base.step_s(998, True), True)]
    machine = machine_step_cost(runs, base, "measured on this machine (3 runs)")
    assert machine.step_s(5000) == pytest.approx(2.5 * base.step_s(5000))
    assert machine.source == "measured on this machine (3 runs)"
    assert machine_step_cost([], base, "none") is base


def test_the_estimate_of_the_check_dam_example_and_its_line():
    from projects.build import resolve
    from projects.document import load_project

    resolved = resolve(load_project(EXAMPLES / "debris_barrier.toml"))
    cost = estimate_run_time(resolved, arch="cpu")
    assert cost["particles"] == 998 and cost["steps"] == resolved.estimate["steps"]
    assert cost["may_stop_early"]  # stop_when_kinetic_energy_below
    assert cost["run_time_s"] == pytest.approx(5.0 + cost["steps"] * (2.2e-4 + 6.1e-8 * 998 + 8.2e-4))
    line = describe(cost)
    assert line.startswith("at most 11 s on cpu (start-up 5.0 s + 5,251 steps x 1.1 ms")
    assert "us per particle-step at 998 particles" in line


def test_a_strength_reduction_counts_its_trials_apart():
    from projects.build import resolve
    from projects.document import load_project

    resolved = resolve(load_project(EXAMPLES / "slope_fos.toml"), seed=False)
    e = resolved.estimate
    assert e["trial_steps"] == pytest.approx(2.0 / e["time_step_s"], abs=1)
    cost = run_time(e, STEP_COSTS["cpu"])
    assert cost["trial_time_s"] == pytest.approx(e["trial_steps"] * STEP_COSTS["cpu"].step_s(e["particles"]))
    assert "plus each strength-reduction trial up to" in describe(cost)
    # the search's usual count: the first trial and a bracketing step, then bisection of a bracket
    # of F x bracket_step (0.1 of the first trial, Bishop's where not given: 1 for the estimate)
    # to the tolerance 0.01: 2 + ceil(log2(10)) = 6
    assert cost["typical_trials"] == 6 and cost["max_trials"] == 40
    assert "usually about 6 trials, up to" in describe(cost) and "(at most 40 trials)" in describe(cost)


@pytest.mark.parametrize(("sets", "expected"), [
    (("stages.1.tolerance=0.001",), 2 + 7),
    (("stages.1.first_trial=2.0", "stages.1.bracket_step=0.2"), 2 + 6),
    (("stages.1.max_trials=4",), 4),
])
def test_the_usual_number_of_trials_follows_the_search_settings(sets, expected):
    from projects.build import resolve
    from projects.document import load_project

    resolved = resolve(load_project(EXAMPLES / "slope_fos.toml", sets), seed=False)
    assert resolved.estimate["typical_trials"] == expected


def test_runout_validate_prints_the_run_time(tmp_path):
    from typer.testing import CliRunner

    from app.cli import cli

    project = tmp_path / "barrier.toml"
    project.write_text((EXAMPLES / "debris_barrier.toml").read_text())
    result = CliRunner().invoke(cli, ["validate", str(project)])
    assert result.exit_code == 0, result.output
    assert "run time: at most 11 s on cpu" in result.output
    assert "the development machine's measurements" in result.output
    folder = tmp_path / "barrier.results"
    folder.mkdir()
    (folder / "summary.json").write_text(json.dumps(
        {"arch": "cpu", "particles": 998, "step_time_s": 4.5e-3, "startup_s": 6.0, "structures": [{}]}))
    result = CliRunner().invoke(cli, ["validate", str(project)])
    assert "run time: at most 30 s on cpu" in result.output
    assert "measured by this project's run (998 particles, 4.5 ms a step)" in result.output
