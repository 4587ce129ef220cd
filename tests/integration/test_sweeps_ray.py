"""A tiny sweep and a tiny calibration on a local Ray with 2 CPUs (real runs of the tiny column).

Ray starts once for the module. The scene is ``tiny_column.toml`` cut to 0.1 s of collapse (500
steps of 288 particles, a few seconds a run).
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest

from sweeps.spec import parse_spec

TINY = Path(__file__).resolve().parents[2] / "projects" / "examples" / "tiny_column.toml"
SHORT = ["stages.1.duration_s=0.1", "output.interval_s=0.05"]
PHI = "materials.sand.friction_angle_deg"
DT = "numerics.time_step_s"

pytestmark = pytest.mark.timeout(600)


@pytest.fixture(scope="module")
def ray_local():
    ray = pytest.importorskip("ray")
    ray.init(address="local", num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield ray
    ray.shutdown()


@pytest.fixture(scope="module")
def sweep_dir(tmp_path_factory):
    return tmp_path_factory.mktemp("sweep")


def sweep_spec(params: dict, measures=("hazard.runout_distance_m", "deposit.front_m", "summary.steps"), **extra):
    return parse_spec({"sweep": {"project": str(TINY), "sampling": "grid", "set": SHORT,
                                 "measures": list(measures), **extra},
                       "parameters": params, "profile": {"field": "peak_flow_height_m", "thresholds": [0.02, 0.1]}},
                      Path("."))


def rows(folder: Path) -> list[dict[str, str]]:
    with open(folder / "sweep.csv", encoding="utf-8", newline="") as fh:
        return list(csv.DictReader(fh))


def test_tiny_sweep_runout_falls_with_friction(ray_local, sweep_dir):
    from sweeps.sweep import run_sweep

    seen = []
    result = run_sweep(sweep_spec({PHI: [15.0, 30.0, 45.0]}), sweep_dir, workers=2, threads_per_run=1,
                       on_progress=seen.append)
    table = rows(sweep_dir)
    assert len(table) == 3
    assert [r["status"] for r in table] == ["completed"] * 3, [r["message"] for r in table]
    for r in table:
        assert r["deposit.front_m"] and r["wall_time_s"] and float(r["summary.steps"]) == 500
        assert (Path(r["results_dir"]) / "summary.json").is_file()
    front = [float(r["deposit.front_m"]) for r in table]
    assert all(a > b for a, b in zip(front, front[1:])), front
    assert front[0] > 0.12 + 0.005  # the column (0.12 m wide) spread
    runout = [float(r["hazard.runout_distance_m"]) for r in table]
    assert all(a > b for a, b in zip(runout, runout[1:])), runout
    with open(sweep_dir / "profile.csv", encoding="utf-8") as fh:
        prof = list(csv.DictReader(fh))
    p_low = np.array([float(r["p_gt_0.02"]) for r in prof])
    p_high = np.array([float(r["p_gt_0.1"]) for r in prof])
    assert len(prof) > 10 and np.all(p_high <= p_low) and p_low.max() == 1.0 and p_low.min() == 0.0
    assert [p.done for p in seen] == [0, 1, 2, 3]
    assert result.settings["workers"] == 2 and result.settings["threads_per_run"] == 1
    for name in ("exceedance.csv", "sensitivity.csv", "profile.csv", "report.html", "progress.json"):
        assert (sweep_dir / name).is_file(), name
    with open(sweep_dir / "sensitivity.csv", encoding="utf-8") as fh:
        sens = {r["measure"]: r for r in csv.DictReader(fh)}
    assert float(sens["deposit.front_m"]["spearman_rho"]) == pytest.approx(-1.0)
    assert float(sens["hazard.runout_distance_m"]["spearman_rho"]) == pytest.approx(-1.0)


def test_failing_run_is_recorded_and_finished_runs_are_reused(ray_local, sweep_dir):
    from sweeps.sweep import run_sweep

    before = {r[PHI]: (r["run_id"], (Path(r["results_dir"]) / "summary.json").stat().st_mtime_ns)
              for r in rows(sweep_dir)}
    # friction 15 and 45 with the shipped step were run above; a step 65x the critical one blows up
    spec = sweep_spec({PHI: [15.0, 45.0], DT: [2e-4, 0.05]})
    result = run_sweep(spec, sweep_dir, workers=2, threads_per_run=1)
    table = rows(sweep_dir)
    assert len(table) == 4
    by = {(r[PHI], r[DT]): r for r in table}
    for phi in ("15.0", "45.0"):
        ok, bad = by[(phi, "0.0002")], by[(phi, "0.05")]
        assert ok["status"] == "completed" and ok["run_id"] == before[phi][0]
        assert (Path(ok["results_dir"]) / "summary.json").stat().st_mtime_ns == before[phi][1]  # not run again
        assert bad["status"] == "failed" and "unstable" in bad["message"]
    assert sum(r.reused for r in result.records) == 2
    assert result.count("failed") == 2


def test_calibration_recovers_the_friction_angle_of_a_synthetic_deposit(ray_local, sweep_dir, tmp_path):
    from sweeps.calibrate import run_calibration
    from sweeps.measures import surface_at

    # the observation, made by the model itself: the final surface of the 15-degree run of the sweep above
    truth = next(r for r in rows(sweep_dir) if r[PHI] == "15.0" and r["status"] == "completed")
    x = np.linspace(0.0, 0.2, 41)
    h = surface_at(Path(truth["results_dir"]), x)
    obs = tmp_path / "observed.csv"
    obs.write_text("x_m,y_m\n" + "".join(f"{float(a)!r},{float(b)!r}\n" for a, b in zip(x, h)), encoding="utf-8")
    spec = parse_spec({"calibration": {"project": str(TINY), "set": SHORT, "trials": 8, "seed": 1},
                       "parameters": {PHI: {"distribution": "uniform", "low": 10.0, "high": 40.0}},
                       "observation": {"type": "deposit-profile", "file": str(obs)}}, Path("."))
    out = tmp_path / "cal"
    result = run_calibration(spec, out, workers=2, threads_per_run=1)
    assert len(result.trials) == 8
    best = result.best
    assert best is not None and best.misfit < 0.01
    assert abs(best.values[PHI] - 15.0) < 5.0, [(t.values[PHI], t.misfit) for t in result.trials]
    assert (out / "report.html").is_file() and (out / "calibration.csv").is_file()
    assert math.isfinite(result.threshold)
