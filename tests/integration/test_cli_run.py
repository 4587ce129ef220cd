"""``runout run`` and ``runout validate`` end to end, in a subprocess, on the tiny example."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import tomlkit

from projects.results import Results
from tests.conftest import REPO

REQUIRED_SERIES = (
    "time_s", "stage", "step", "kinetic_energy_J_per_m", "momentum_x", "momentum_y",
    "max_speed_m_s", "unstable_particles", "lost_particles",
)
REQUIRED_SUMMARY = (
    "status", "message", "scheme", "arch", "precision", "particles", "steps",
    "simulated_time_s", "wall_time_s", "particle_steps_per_s",
)


def runout(*args: str, cwd: Path, timeout: float = 240) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "app.cli", *args],
        cwd=cwd, capture_output=True, text=True, timeout=timeout, env=_env(),
    )


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(REPO), env.get("PYTHONPATH", "")])
    env.setdefault("COLUMNS", "200")
    return env


@pytest.fixture
def project(tiny_project, tmp_path) -> Path:
    """A copy of the tiny example in a scratch folder (results go next to it)."""
    return Path(shutil.copy(tiny_project, tmp_path / "tiny.toml"))


def _data(project: Path) -> dict:
    return tomlkit.parse(project.read_text()).unwrap()


def _last_dynamic_stage(project: Path) -> int:
    stages = _data(project)["stages"]
    return max(i for i, st in enumerate(stages) if st.get("type") == "dynamic")


def test_run_writes_a_complete_results_folder(project, tmp_path):
    proc = runout("run", str(project), "--arch", "cpu", "--set", "numerics.scheme=mpm", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.strip().splitlines()
    # the tiny column is still collapsing at its end: the status says so (tests/integration/test_run_to_rest.py)
    assert len(lines) == 1 and lines[0].startswith("completed, still moving (kinetic energy "), proc.stdout
    assert "Traceback" not in proc.stderr

    out = tmp_path / "tiny.results"  # default: next to the project
    assert str(out) in lines[0]
    for name in ("particles.pvd", "series.csv", "summary.json", "project.toml", "frames"):
        assert (out / name).exists(), name

    summary = json.loads((out / "summary.json").read_text())
    for key in REQUIRED_SUMMARY:
        assert key in summary, key
    assert summary["status"] == "completed"
    assert summary["scheme"] == "mpm"  # the override ran ...
    assert _data(out / "project.toml")["numerics"]["scheme"] == "mpm"  # ... and is recorded
    assert summary["arch"] == "cpu"
    assert summary["steps"] > 0 and summary["particles"] > 0
    assert summary["particle_steps_per_s"] > 0

    header = (out / "series.csv").read_text().splitlines()[0].split(",")
    assert set(REQUIRED_SERIES) <= set(header)

    res = Results(out)
    assert res.status == "completed"
    assert len(res) >= 2
    assert len(res.series["time_s"]) == len(res)
    assert res.times[-1] == pytest.approx(summary["simulated_time_s"])
    assert res.frame(-1)["positions"].shape == (summary["particles"], 2)
    assert np.isfinite(res.frame(-1)["stress"]).all()
    assert res.series["kinetic_energy_J_per_m"].max() > 0  # it moved


def test_rerun_needs_overwrite_and_keeps_what_the_run_did_not_write(project, tmp_path):
    out = tmp_path / "custom"
    first = runout("run", str(project), "--arch", "cpu", "--out", str(out), "--quiet", cwd=tmp_path)
    assert first.returncode == 0, first.stderr
    (out / "notes.txt").write_text("mine")
    (out / "frames" / "sketch.png").write_bytes(b"png")
    frames = sorted(p.name for p in (out / "frames").glob("frame_*.vtp"))

    again = runout("run", str(project), "--arch", "cpu", "--out", str(out), "--quiet", cwd=tmp_path)
    assert again.returncode == 1
    assert again.stderr.count("\n") == 1 and "--overwrite" in again.stderr
    assert "Traceback" not in again.stderr
    assert sorted(p.name for p in (out / "frames").glob("frame_*.vtp")) == frames

    proc = runout("run", str(project), "--arch", "cpu", "--out", str(out), "--quiet", "--overwrite", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout == ""
    assert (out / "notes.txt").read_text() == "mine"
    assert (out / "frames" / "sketch.png").read_bytes() == b"png"
    assert Results(out).status == "completed"
    assert not list(out.rglob("*.tmp")) and not (out / ".runout-results.lock").exists()


def test_run_refuses_an_unrelated_folder(project, tmp_path):
    precious = tmp_path / "precious"
    precious.mkdir()
    (precious / "notes.txt").write_text("keep")
    proc = runout("run", str(project), "--arch", "cpu", "--out", str(precious), cwd=tmp_path)
    assert proc.returncode == 1
    assert "refusing to overwrite" in proc.stderr
    assert "Traceback" not in proc.stderr
    assert (precious / "notes.txt").read_text() == "keep"


def test_unstable_run_fails_with_a_one_line_reason(project, tmp_path):
    # a step about 60x the critical one, for enough steps to blow up
    stage = _last_dynamic_stage(project)
    proc = runout(
        "run", str(project), "--arch", "cpu", "-q", "--set", "numerics.time_step_s=0.05",
        "--set", "output.interval_s=0.05", "--set", f"stages.{stage}.duration_s=2", cwd=tmp_path,
    )
    assert proc.returncode == 3, proc.stderr
    failed = [ln for ln in proc.stderr.splitlines() if ln.startswith("failed: ")]
    assert len(failed) == 1 and "unstable" in failed[0]
    assert "Traceback" not in proc.stderr
    summary = json.loads((tmp_path / "tiny.results" / "summary.json").read_text())
    assert summary["status"] == "failed"
    assert "unstable" in summary["message"]
    assert Results(tmp_path / "tiny.results").status == "failed"


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")
@pytest.mark.parametrize("sig, code", [(signal.SIGTERM, 143), (signal.SIGINT, 130), (signal.SIGHUP, 129)],
                         ids=["SIGTERM", "SIGINT", "SIGHUP"])
def test_signals_stop_the_run_cleanly(project, tmp_path, sig, code):
    stage = _last_dynamic_stage(project)
    out = tmp_path / "long.results"
    proc = subprocess.Popen(
        [sys.executable, "-m", "app.cli", "run", str(project), "--arch", "cpu", "-q", "--out", str(out),
         "--set", f"stages.{stage}.duration_s=100"],
        cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=_env(),
    )
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and proc.poll() is None:
            try:  # wait for the second frame: the solver is stepping
                if json.loads((out / "summary.json").read_text()).get("frames", 0) >= 2:
                    break
            except (OSError, ValueError):
                pass
            time.sleep(0.1)
        assert proc.poll() is None, proc.communicate()[1]
        proc.send_signal(sig)
        _, stderr = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == code, stderr
    assert f"stopped by {signal.Signals(sig).name}" in stderr
    res = Results(out)
    assert res.status == "stopped"
    assert len(res) >= 2
    assert res.times[-1] == pytest.approx(res.summary["simulated_time_s"])
    assert not list(out.rglob("*.tmp")) and not (out / ".runout-results.lock").exists()


def test_validate_ok_and_problems(project, tmp_path):
    ok = runout("validate", str(project), cwd=tmp_path)
    assert ok.returncode == 0, ok.stderr
    assert ok.stdout.startswith("ok: ") and "particles" in ok.stdout
    assert not (tmp_path / "tiny.results").exists()

    material = next(iter(_data(project)["materials"]))
    bad = runout(
        "validate", str(project), "--set", f"materials.{material}.poisson_ratio=0.7",
        "--set", "numerics.scheme=flip", cwd=tmp_path,
    )
    assert bad.returncode == 1
    assert f"materials.{material}.poisson_ratio = 0.7" in bad.stderr
    assert 'numerics.scheme = "flip"' in bad.stderr
    assert "Traceback" not in bad.stderr

    missing = runout("validate", str(tmp_path / "nope.toml"), cwd=tmp_path)
    assert missing.returncode == 1
    assert "nope.toml" in missing.stderr and "Traceback" not in missing.stderr


def test_run_with_an_invalid_project_writes_nothing(project, tmp_path):
    proc = runout("run", str(project), "--set", "domain.cell_size_m=-1", cwd=tmp_path)
    assert proc.returncode == 1
    assert proc.stderr.startswith("error: ") and "domain.cell_size_m" in proc.stderr
    assert "Traceback" not in proc.stderr
    assert not (tmp_path / "tiny.results").exists()


@pytest.mark.parametrize("args, message", [
    (["study", "bui2008", "--budget-min", "5"], "a budget applies to the tradeoff sweep only"),
    (["study", "tradeoff", "--budget-min", "-1"], "--budget-min must be a positive number of minutes, not -1"),
    (["study", "no-such-study"], "unknown study 'no-such-study'; choose one of: sand-column"),
])
def test_study_refuses_bad_arguments_before_running_anything(tmp_path, args, message):
    proc = runout(*args, "--out", str(tmp_path / "out"), cwd=tmp_path)
    assert proc.returncode == 1, proc.stderr
    assert message in " ".join(proc.stderr.split())
    assert not any((tmp_path / "out").rglob("report.md"))


def test_the_study_help_names_every_study():
    from app.cli import STUDY_NAMES
    from studies import STUDIES

    assert STUDY_NAMES.split(" | ") == list(STUDIES)
