"""Sweep statistics against hand-computed values on synthetic measures (no solver, no Ray)."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest

from projects.atomic import write_atomic
from sweeps.analysis import (
    dkw_epsilon,
    exceedance,
    probability_profile,
    sensitivity,
    wilson_interval,
)
from sweeps.calibrate import confidence_threshold, misfit
from sweeps.engine import RunPlan, RunRecord
from sweeps.folder import SPEC_NAME, is_sweep_dir, read_sweep
from sweeps.measures import read_measures, read_profile
from sweeps.report import write_report, write_statistics
from sweeps.spec import parse_spec
from sweeps.sweep import csv_text


def test_exceedance_of_a_small_sample_by_hand():
    ex = exceedance([2.0, 1.0, 3.0, 2.0, math.nan])
    assert ex.n == 4
    assert list(ex.x) == [1.0, 2.0, 3.0]
    assert list(ex.p) == [0.75, 0.25, 0.0]  # P(X > 1) = 3/4, P(X > 2) = 1/4, P(X > 3) = 0
    eps = math.sqrt(math.log(2 / 0.05) / (2 * 4))  # 0.679
    assert ex.eps == pytest.approx(eps)
    assert list(ex.lower) == [pytest.approx(0.75 - eps), 0.0, 0.0]
    assert list(ex.upper) == [1.0, pytest.approx(0.25 + eps), pytest.approx(eps)]
    assert ex.at(0.5) == 1.0 and ex.at(2.5) == 0.25


@pytest.mark.parametrize("n", [10, 100, 1000])
def test_dkw_band_covers_the_true_curve(n):
    rng = np.random.default_rng(n)
    ex = exceedance(rng.exponential(2.0, n))
    true = np.exp(-ex.x / 2.0)
    assert np.all(ex.lower <= true + 1e-12) and np.all(true <= ex.upper + 1e-12)
    assert dkw_epsilon(n, 0.05) == pytest.approx(math.sqrt(math.log(40) / (2 * n)))


@pytest.mark.parametrize("k, n, lo, hi", [
    (0, 10, 0.0, 0.2775),    # Wilson (1927) 95%: 0/10 -> [0, 0.278]
    (5, 10, 0.2366, 0.7634),  # 5/10 -> [0.237, 0.763]
    (10, 10, 0.7225, 1.0),
])
def test_wilson_interval_by_hand(k, n, lo, hi):
    a, b = wilson_interval(k, n)
    assert float(a) == pytest.approx(lo, abs=1e-4) and float(b) == pytest.approx(hi, abs=1e-4)


def test_probability_profile_by_hand():
    x = [0.0, 1.0, 2.0, 3.0]
    runs = [(x, [0.5, 0.3, 0.1, 0.0]), (x, [0.5, 0.5, 0.3, 0.05]), (x, [0.2, 0.2, 0.2, 0.2])]
    pp = probability_profile(runs, [0.15, 0.25])
    assert list(pp.x_m) == x and pp.n == 3
    assert list(pp.p[0]) == pytest.approx([1.0, 1.0, 2 / 3, 1 / 3])
    assert list(pp.p[1]) == pytest.approx([2 / 3, 2 / 3, 1 / 3, 0.0])
    lo, hi = wilson_interval(np.array([2]), 3)
    assert pp.lower[1, 0] == pytest.approx(lo[0]) and pp.upper[1, 0] == pytest.approx(hi[0])


def test_probability_profile_on_different_stations_interpolates_and_is_zero_outside():
    runs = [([0.0, 2.0], [1.0, 1.0]), ([0.0, 1.0], [0.0, 2.0])]
    pp = probability_profile(runs, [0.5])
    assert list(pp.x_m) == [0.0, 1.0, 2.0]
    # run 1: 1, 1, 1; run 2: 0, 2, 0 (no station beyond 1 m)
    assert list(pp.p[0]) == pytest.approx([0.5, 1.0, 0.5])


def test_sensitivity_ranks_monotone_parameters_first():
    rng = np.random.default_rng(0)
    phi = rng.uniform(20, 40, 30)
    noise = rng.uniform(0, 1, 30)
    runout = 10.0 / np.tan(np.radians(phi)) + 0.01 * noise
    ranked = sensitivity({"noise": noise, "phi": phi, "scheme": ["a"] * 30}, {"runout": runout})
    assert [s.parameter for s in ranked] == ["phi", "noise"]  # text parameters are left out
    assert ranked[0].rho == pytest.approx(-1.0, abs=0.02)
    assert abs(ranked[1].rho) < 0.5


def write_results(folder: Path, summary: dict, hazard: dict | None = None, profile: str | None = None) -> Path:
    folder.mkdir(parents=True)
    (folder / "summary.json").write_text(json.dumps(summary), encoding="utf-8")
    if hazard is not None:
        (folder / "hazard.json").write_text(json.dumps(hazard), encoding="utf-8")
    if profile is not None:
        (folder / "hazard_profile.csv").write_text(profile, encoding="utf-8")
    return folder


def test_measures_from_summary_and_hazard_json(tmp_path):
    d = write_results(tmp_path / "r", {"status": "completed", "wall_time_s": 3.5, "steps": 10},
                      {"runout_distance_m": 12.5, "targets": {"road": {"arrival_time_s": 4.0}}, "list": [1.5]},
                      "x_m,peak_flow_height_m,max_pressure_pa\n0,1.0,10\n1,0.5,\n")
    got = read_measures(d, ["summary.wall_time_s", "hazard.runout_distance_m", "hazard.targets.road.arrival_time_s",
                            "hazard.list.0", "hazard.nothing", "summary.status", "deposit.front_m"])
    assert got["summary.wall_time_s"] == 3.5 and got["hazard.runout_distance_m"] == 12.5
    assert got["hazard.targets.road.arrival_time_s"] == 4.0 and got["hazard.list.0"] == 1.5
    assert math.isnan(got["hazard.nothing"]) and math.isnan(got["summary.status"])
    assert math.isnan(got["deposit.front_m"])  # no frames in this folder
    x, v = read_profile(d, "max_pressure_pa")
    assert x == [0.0, 1.0] and v[0] == 10.0 and math.isnan(v[1])
    assert read_profile(d, "no_such_column") is None


def fake_sweep(tmp_path: Path, n: int = 8) -> Path:
    """A sweep folder written by hand: runout = 100 - 2 phi, a profile per run, one failed run."""
    out = tmp_path / "sweep"
    (out / "runs").mkdir(parents=True)
    spec = parse_spec({"sweep": {"project": "p.toml", "runs": n, "measures": ["hazard.runout_distance_m"]},
                       "parameters": {"materials.soil.friction_angle_deg": {"distribution": "uniform", "low": 20,
                                                                             "high": 40}},
                       "profile": {"field": "peak_flow_height_m", "thresholds": [0.5]}}, Path("."))
    plans, records = [], []
    for i in range(n):
        phi = 20.0 + 20.0 * i / (n - 1)
        plans.append(RunPlan(i, {"materials.soil.friction_angle_deg": phi}, (), f"id{i}", "x"))
        status = "failed" if i == n - 1 else "completed"
        rec = RunRecord(f"id{i}", status, "unstable" if status == "failed" else "ok", 1.0, "",
                        {"hazard.runout_distance_m": 100.0 - 2.0 * phi},
                        ([0.0, 1.0, 2.0], [1.0, 0.6 if i < 3 else 0.4, 0.0]))
        records.append(rec)
        write_atomic(out / "runs" / f"id{i}.json", json.dumps(rec.to_json()))
    write_atomic(out / "sweep.csv", csv_text(plans, records, ["hazard.runout_distance_m"]))
    write_atomic(out / SPEC_NAME, json.dumps({"spec": json.loads(spec.model_dump_json()), "settings": {}}))
    return out


def test_statistics_files_of_a_synthetic_sweep(tmp_path):
    out = fake_sweep(tmp_path)
    assert is_sweep_dir(out)
    data = read_sweep(out)
    assert data.parameters == ["materials.soil.friction_angle_deg"]
    assert len(data.completed()) == 7
    write_statistics(data)
    with open(out / "exceedance.csv", encoding="utf-8") as fh:
        ex = list(csv.DictReader(fh))
    assert len(ex) == 7 and float(ex[0]["p_exceed"]) == pytest.approx(6 / 7)
    with open(out / "profile.csv", encoding="utf-8") as fh:
        prof = list(csv.DictReader(fh))
    # P(h > 0.5): at x = 0 all 7 runs, at x = 1 the first three, at x = 2 none
    assert [float(r["p_gt_0.5"]) for r in prof] == pytest.approx([1.0, 3 / 7, 0.0])
    with open(out / "sensitivity.csv", encoding="utf-8") as fh:
        sens = list(csv.DictReader(fh))
    assert float(sens[0]["spearman_rho"]) == pytest.approx(-1.0)
    report = write_report(out)
    text = report.read_text(encoding="utf-8")
    assert "data:image/png;base64" in text and "unstable" in text


def test_calibration_misfits_by_hand():
    cal = parse_spec({"calibration": {"project": "p.toml"},
                      "parameters": {"a": {"distribution": "uniform", "low": 0, "high": 1}},
                      "observation": {"type": "measures", "values": {"hazard.runout_distance_m": 10.0,
                                                                     "hazard.travel_angle_deg": 20.0},
                                      "scales": {"hazard.travel_angle_deg": 2.0}}}, Path("."))
    rec = RunRecord("x", "completed", measures={"hazard.runout_distance_m": 13.0, "hazard.travel_angle_deg": 28.0})
    assert misfit(cal, rec, None) == pytest.approx(math.sqrt((9 + 16) / 2))
    assert math.isnan(misfit(cal, RunRecord("x", "failed"), None))
    prof = parse_spec({"calibration": {"project": "p.toml"}, "parameters": {"a": [1, 2]},
                       "observation": {"type": "deposit-profile", "file": "o.csv"}}, Path("."))
    observed = np.array([[0.0, 0.1], [0.1, 0.05], [0.2, 0.0]])
    rec = RunRecord("x", "completed", surface=[0.1, 0.08, 0.04])
    assert misfit(prof, rec, observed) == pytest.approx(math.sqrt((0 + 0.03**2 + 0.04**2) / 3))


def test_confidence_threshold_by_hand():
    from scipy.stats import f

    assert confidence_threshold(0.002, 41, 1) == pytest.approx(0.002 * math.sqrt(1 + f.ppf(0.95, 1, 40) / 40))
    assert math.isnan(confidence_threshold(0.1, 1, 1))  # one observed value, one parameter: no region


@pytest.mark.parametrize("centre, width", [(19.8, 0.5), (30.0, 2.0)])
def test_quadratic_estimate_recovers_a_parabola(centre, width):
    from sweeps.calibrate import quadratic_estimate

    theta = np.array([10.0, 15.0, centre - 1.3, centre + 0.7, centre + 2.1, 40.0])
    s_min = 1e-6
    rms = np.sqrt(s_min + 1e-7 * (theta - centre) ** 2)
    threshold = math.sqrt(s_min + 1e-7 * width**2)  # the parabola crosses it at centre +- width
    m, lo, hi = quadratic_estimate(theta, rms, threshold, points=3)
    assert m == pytest.approx(centre, abs=1e-6)
    assert lo == pytest.approx(centre - width, abs=1e-6) and hi == pytest.approx(centre + width, abs=1e-6)
    assert quadratic_estimate([1.0, 2.0], [0.1, 0.2], 0.3) is None


def test_a_run_past_its_timeout_is_recorded_as_error(tmp_path):
    """execute_run (the Ray task's body) called directly: the run process is stopped at timeout_s."""
    from projects.document import dumps_project, load_project
    from sweeps.engine import execute_run

    tiny = Path(__file__).resolve().parents[2] / "projects" / "examples" / "tiny_column.toml"
    text = dumps_project(load_project(tiny, ["stages.1.duration_s=100"]))
    data = execute_run({"run_id": "slow", "project_text": text, "runs_dir": str(tmp_path), "threads": 1,
                        "arch": "cpu", "timeout_s": 1.0, "measures": ["summary.steps"], "profile_field": None,
                        "sample_x": None})
    assert data["status"] == "error" and data["message"] == "timed out after 1 s"
    assert data["wall_time_s"] < 30
    assert (tmp_path / "slow.toml").read_text(encoding="utf-8") == text


def test_resume_reads_measures_asked_for_later_from_the_kept_results(tmp_path):
    from sweeps.sweep import _load_record

    runs = tmp_path / "runs"
    write_results(runs / "abc", {"status": "completed", "wall_time_s": 2.0, "steps": 7})
    rec = RunRecord("abc", "completed", "ok", 3.0, str(runs / "abc"), {"summary.steps": 7.0})
    write_atomic(runs / "abc.json", json.dumps(rec.to_json()))
    plan = RunPlan(0, {}, (), "abc", "text")
    again = _load_record(runs, plan, ["summary.steps", "summary.wall_time_s"], None)
    assert again is not None and again.reused
    assert again.measures == {"summary.steps": 7.0, "summary.wall_time_s": 2.0}
    assert json.loads((runs / "abc.json").read_text())["measures"]["summary.wall_time_s"] == 2.0
    # an interrupted ("error") run is not reused; nor is one whose folder is gone when a measure is missing
    write_atomic(runs / "abc.json", json.dumps(RunRecord("abc", "error", "killed").to_json()))
    assert _load_record(runs, plan, ["summary.steps"], None) is None
    write_atomic(runs / "abc.json", json.dumps(rec.to_json()))
    import shutil

    shutil.rmtree(runs / "abc")
    assert _load_record(runs, plan, ["summary.steps"], None) is not None
    assert _load_record(runs, plan, ["summary.status_code"], None) is None
