"""Sweeps and calibrations say which runs ended with the mass still moving: each run's record and
the ``still_moving`` column of sweep.csv / calibration.csv carry summary.json's verdict, the
report marks those runs' measures provisional (``*`` with its legend), the command's last line
counts them, and a calibration warns when trials it used (or its best fit) had not come to rest.
Synthetic run folders and records only: no solver, no Ray."""

from __future__ import annotations

import json
import math
import subprocess
from pathlib import Path

import pytest
from typer.testing import CliRunner

from projects.atomic import write_atomic
from sweeps.calibrate import (
    CSV_NAME as CAL_CSV,
    JSON_NAME as CAL_JSON,
    CalibrationResult,
    Trial,
    _csv_text as calibration_csv,
    read_calibration,
    write_calibration_report,
)
from sweeps.engine import RunPlan, RunRecord, execute_run
from sweeps.folder import PROVISIONAL_LEGEND, SPEC_NAME, read_sweep
from sweeps.measures import read_still_moving, still_moving
from sweeps.report import write_report
from sweeps.spec import parse_spec
from sweeps.sweep import SweepResult, _load_record, csv_text

PHI = "materials.soil.friction_angle_deg"
MEASURE = "hazard.runout_distance_m"
TINY = Path(__file__).resolve().parents[2] / "projects" / "examples" / "tiny_column.toml"


def motion(moving: bool) -> dict:
    return {"still_moving": moving, "stage": "run-out", "time_s": 2.0, "ended_by": "duration" if moving else "rest",
            "kinetic_energy_J_per_m": 46.0 if moving else 0.5, "peak_kinetic_energy_J_per_m": 100.0,
            "kinetic_energy_fraction": 0.46 if moving else 0.005, "max_speed_m_s": 3.2 if moving else 0.01,
            "rest_kinetic_energy_fraction": 0.01, "rest_speed_m_s": 0.157}


def summary(moving: bool | None) -> dict:
    base = {"status": "completed", "message": "ok", "steps": 10}
    if moving is None:  # no dynamic stage ran: no verdict
        return {**base, "still_moving": None, "motion_at_end": None}
    return {**base, "still_moving": moving, "motion_at_end": motion(moving)}


def test_the_verdict_is_read_from_summary_json(tmp_path):
    assert still_moving(summary(True)) is True and still_moving(summary(False)) is False
    assert still_moving(summary(None)) is None and still_moving({"status": "completed"}) is None
    assert still_moving(None) is None
    # the verdict inside motion_at_end alone counts too (projects.motion.provisional)
    assert still_moving({"motion_at_end": motion(True)}) is True
    folder = tmp_path / "r"
    folder.mkdir()
    (folder / "summary.json").write_text(json.dumps(summary(True)), encoding="utf-8")
    assert read_still_moving(folder) is True
    assert read_still_moving(tmp_path / "nothing") is None


@pytest.mark.parametrize("moving", [True, False, None])
def test_a_run_record_carries_the_verdict_of_its_run(tmp_path, monkeypatch, moving):
    """execute_run (the Ray task's body) with the `runout run` process replaced by one that writes
    summary.json: the record says whether the run ended still moving, and keeps it through JSON."""
    def fake_run(cmd, **_kwargs):
        out = Path(cmd[cmd.index("--out") + 1])
        out.mkdir(parents=True)
        (out / "summary.json").write_text(json.dumps(summary(moving)), encoding="utf-8")
        return subprocess.CompletedProcess(cmd, 0, "", "")

    monkeypatch.setattr("sweeps.engine.subprocess.run", fake_run)
    data = execute_run({"run_id": "abc", "project_text": TINY.read_text(encoding="utf-8"), "runs_dir": str(tmp_path),
                        "threads": 1, "arch": "cpu", "timeout_s": None, "measures": ["summary.steps"],
                        "profile_field": None, "sample_x": None})
    assert data["status"] == "completed" and data["still_moving"] is moving
    assert RunRecord.from_json(json.loads(json.dumps(data))).still_moving is moving


def fake_sweep(tmp_path: Path, verdicts: list[bool | None], statuses: list[str] | None = None) -> Path:
    """A sweep folder written as run_sweep writes it, one run per verdict (runout = 100 - 2 phi)."""
    out = tmp_path / "sweep"
    (out / "runs").mkdir(parents=True)
    spec = parse_spec({"sweep": {"project": "p.toml", "runs": len(verdicts), "measures": [MEASURE]},
                       "parameters": {PHI: {"distribution": "uniform", "low": 20, "high": 40}}}, Path("."))
    statuses = statuses or ["completed"] * len(verdicts)
    plans, records = [], []
    for i, (moving, status) in enumerate(zip(verdicts, statuses)):
        phi = 20.0 + 2.0 * i
        plans.append(RunPlan(i, {PHI: phi}, (), f"id{i}", "x"))
        rec = RunRecord(f"id{i}", status, "ok", 1.0, "", {MEASURE: 100.0 - 2.0 * phi}, still_moving=moving)
        records.append(rec)
        write_atomic(out / "runs" / f"id{i}.json", json.dumps(rec.to_json()))
    write_atomic(out / "sweep.csv", csv_text(plans, records, [MEASURE]))
    write_atomic(out / SPEC_NAME, json.dumps({"spec": json.loads(spec.model_dump_json()), "settings": {}}))
    return out


def test_sweep_csv_has_a_still_moving_column_and_the_parameters_stay_the_parameters(tmp_path):
    out = fake_sweep(tmp_path, [False, True, None, True, False])
    header = (out / "sweep.csv").read_text(encoding="utf-8").splitlines()[0].split(",")
    assert header[-1] == "still_moving"
    data = read_sweep(out)
    assert data.parameters == [PHI] and data.measures == [MEASURE]
    assert [r["still_moving"] for r in data.rows] == ["false", "true", "", "true", "false"]
    assert [r["run"] for r in data.still_moving()] == ["1", "3"]
    assert list(data.still_moving_mask()) == [False, True, False, True, False]


def test_the_report_marks_the_measures_of_runs_that_ended_still_moving(tmp_path):
    out = fake_sweep(tmp_path, [False, True, False, True, False])
    text = write_report(out).read_text(encoding="utf-8")
    assert "ended still moving</td><td>2 of 5 completed runs: their measures are provisional" in text
    assert "<h2>Runs that ended still moving</h2>" in text
    # run 1: phi = 22, runout 56; run 3: phi = 26, runout 48; both marked, with the legend line
    assert "<td>1</td><td>22.0</td><td>56*</td>" in text and "<td>3</td><td>26.0</td><td>48*</td>" in text
    assert PROVISIONAL_LEGEND in text
    assert "(n = 5; 2 of them provisional*: ended still moving)" in text


def test_a_sweep_at_rest_has_no_provisional_marks(tmp_path):
    out = fake_sweep(tmp_path, [False, False, None])
    text = write_report(out).read_text(encoding="utf-8")
    assert "ended still moving</td><td>0 of 3 completed runs</td>" in text
    assert "Runs that ended still moving" not in text and PROVISIONAL_LEGEND not in text


def test_a_reused_record_without_a_verdict_reads_it_from_its_results(tmp_path):
    runs = tmp_path / "runs"
    (runs / "abc").mkdir(parents=True)
    (runs / "abc" / "summary.json").write_text(json.dumps(summary(True)), encoding="utf-8")
    old = RunRecord("abc", "completed", "ok", 3.0, str(runs / "abc"), {"summary.steps": 10.0}).to_json()
    del old["still_moving"]  # a record written before records carried it
    write_atomic(runs / "abc.json", json.dumps(old))
    rec = _load_record(runs, RunPlan(0, {}, (), "abc", "text"), ["summary.steps"], None)
    assert rec is not None and rec.reused and rec.still_moving is True
    assert json.loads((runs / "abc.json").read_text(encoding="utf-8"))["still_moving"] is True


def test_the_sweep_command_counts_the_runs_that_ended_still_moving(tmp_path, monkeypatch):
    from app.cli import cli

    spec = tmp_path / "s.toml"
    spec.write_text(f'[sweep]\nproject = "{TINY}"\nsampling = "grid"\n[parameters]\n'
                    f'"materials.sand.friction_angle_deg" = [20.0, 30.0, 35.0, 40.0]\n', encoding="utf-8")
    verdicts = [False, True, None, True]

    def run(spec, folder, **_kwargs):
        plans = [RunPlan(i, {}, (), f"id{i}", "") for i in range(4)]
        records = [RunRecord(f"id{i}", "completed" if i != 2 else "failed", still_moving=v)
                   for i, v in enumerate(verdicts)]
        return SweepResult(Path(folder), plans, records, wall_time_s=1.0)

    monkeypatch.setattr("sweeps.sweep.run_sweep", run)
    res = CliRunner().invoke(cli, ["sweep", str(spec), "--workers", "1"])
    assert res.exit_code == 0, res.output
    last = res.stdout.strip().splitlines()[-1]
    assert last.startswith("3 of 4 runs completed, 1 not (0 reused), 2 ended still moving (provisional measures) in")
    warning = [ln for ln in res.stderr.splitlines() if ln.startswith("warning:")]
    assert len(warning) == 1 and warning[0].startswith(
        "warning: runs 1 and 3 ended with the mass still moving: their measures are provisional")
    verdicts[:] = [False, False, None, False]
    res = CliRunner().invoke(cli, ["sweep", str(spec), "--workers", "1"])
    assert "3 of 4 runs completed, 1 not (0 reused), 0 ended still moving in" in res.stdout
    assert "warning:" not in res.stderr


def trials(verdicts: list[bool | None]) -> list[Trial]:
    out = []
    for i, moving in enumerate(verdicts):
        rec = RunRecord(f"id{i}", "completed", still_moving=moving)
        out.append(Trial(i, {"a": 0.1 * i}, f"id{i}", rec, 0.5 - 0.1 * i))
    out.append(Trial(len(out), {"a": 0.9}, "bad", RunRecord("bad", "failed", still_moving=True), math.nan))
    return out


def test_a_calibration_warns_when_trials_it_used_ended_still_moving(tmp_path):
    used = trials([False, True, False, True])  # trial 3 (misfit 0.2) is the best fit
    result = CalibrationResult(tmp_path, ["a"], used, 3, "m", wall_time_s=2.0)
    assert [t.number for t in result.still_moving_trials()] == [1, 3]  # the failed trial had no misfit
    lines = result.summary_lines()
    warnings = [ln for ln in lines if ln.startswith("warning:")]
    assert warnings[0].startswith("warning: 2 of the 4 trials used ended with the mass still moving (trials 1, 3): "
                                  "their misfits are provisional")
    assert warnings[1].startswith("warning: the best fit (trial 3) is one of them")
    calm = CalibrationResult(tmp_path, ["a"], trials([False, False, None]), 3, "m")
    assert not any(ln.startswith("warning:") for ln in calm.summary_lines())


def test_the_calibration_table_and_report_mark_provisional_misfits(tmp_path):
    used = trials([False, True, False])
    write_atomic(tmp_path / CAL_CSV, calibration_csv(used, ["a"]))
    write_atomic(tmp_path / CAL_JSON, json.dumps({
        "unit": "m", "n_observed": 3, "spec": {}, "settings": {}, "threshold": None, "intervals": {},
        "best": {"trial": 2, "values": {"a": 0.2}, "misfit": 0.3, "run_id": "id2", "still_moving": False},
        "still_moving_trials": [1]}))
    data = read_calibration(tmp_path)
    assert data.parameters == ["a"]
    assert [r["still_moving"] for r in data.rows] == ["false", "true", "false", "true"]
    text = write_calibration_report(data).read_text(encoding="utf-8")
    assert "ended still moving</td><td>1 of the 3 trials with a misfit: their misfits are provisional" in text
    assert "<td>1</td><td>0.1</td><td>0.4*</td>" in text
    assert "<td>3</td><td>0.9</td><td></td><td>failed</td>" in text  # no misfit: nothing to mark
    assert PROVISIONAL_LEGEND in text


def test_the_calibrate_command_prints_the_warnings_on_standard_error(tmp_path, monkeypatch):
    from app.cli import cli

    (tmp_path / "observed.csv").write_text("x_m,y_m\n0.0,0.1\n0.1,0.05\n0.2,0.0\n", encoding="utf-8")
    spec = tmp_path / "c.toml"
    spec.write_text(f'[calibration]\nproject = "{TINY}"\ntrials = 4\n[parameters]\n'
                    '"materials.sand.friction_angle_deg" = {distribution = "uniform", low = 10.0, high = 40.0}\n'
                    '[observation]\ntype = "deposit-profile"\nfile = "observed.csv"\n', encoding="utf-8")
    monkeypatch.setattr("sweeps.calibrate.run_calibration", lambda spec, folder, **_k: CalibrationResult(
        Path(folder), ["a"], trials([True, False, False, True]), 3, "m", wall_time_s=1.0))
    res = CliRunner().invoke(cli, ["calibrate", str(spec), "--workers", "1"])
    assert res.exit_code == 0, res.output
    assert "warning: 2 of the 4 trials used ended with the mass still moving (trials 0, 3)" in res.stderr
    assert "warning: the best fit (trial 3) is one of them" in res.stderr
    assert "warning:" not in res.stdout and "best fit (trial 3): misfit 0.2 m" in res.stdout


def test_a_sweep_folder_from_before_the_column_says_the_verdict_is_not_recorded(tmp_path):
    out = fake_sweep(tmp_path, [False, True])
    lines = (out / "sweep.csv").read_text(encoding="utf-8").splitlines()
    (out / "sweep.csv").write_text("\n".join(ln.rsplit(",", 1)[0] for ln in lines) + "\n", encoding="utf-8")
    data = read_sweep(out)
    assert data.parameters == [PHI] and data.still_moving() == []
    text = write_report(out).read_text(encoding="utf-8")
    assert "ended still moving</td><td>not recorded" in text
