"""Runs that must not lose data or go silently wrong: concurrent runs, real-world coordinates,
user text in the terminal, an early Ctrl-C, and the initial equilibrium check."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from projects.document import apply_overrides, load_project
from projects.results import Results
from projects.runner import run_project
from tests.conftest import REPO

UTM = (500_000.0, 4_000_000.0)


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(REPO), env.get("PYTHONPATH", "")])
    env.setdefault("COLUMNS", "200")
    return env


def _cli(*args: str) -> list[str]:
    return [sys.executable, "-m", "app", *args]


def _box(x0: float, y0: float, w: float, h: float) -> str:
    return f"[[{x0!r},{y0!r}],[{x0 + w!r},{y0!r}],[{x0 + w!r},{y0 + h!r}],[{x0!r},{y0 + h!r}]]"


def test_a_second_run_into_a_folder_in_use_is_refused_in_one_line(tiny_project, tmp_path):
    out = tmp_path / "shared.results"
    first = subprocess.Popen(
        _cli("run", str(tiny_project), "--arch", "cpu", "-q", "--out", str(out), "--set", "stages.1.duration_s=100"),
        cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=_env(),
    )
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and first.poll() is None:
            try:
                if json.loads((out / "summary.json").read_text()).get("frames", 0) >= 1:
                    break
            except (OSError, ValueError):
                pass
            time.sleep(0.1)
        assert first.poll() is None, first.communicate()[1]
        second = subprocess.run(
            _cli("run", str(tiny_project), "--arch", "cpu", "-q", "--out", str(out), "--overwrite"),
            cwd=tmp_path, capture_output=True, text=True, env=_env(), timeout=240,
        )
        assert second.returncode == 1
        assert second.stderr.count("\n") == 1, second.stderr
        assert "in use by another run" in second.stderr and f"process {first.pid}" in second.stderr
        first.send_signal(signal.SIGTERM)
        first.communicate(timeout=120)
    finally:
        if first.poll() is None:
            first.kill()
            first.communicate()
    res = Results(out)
    assert res.status == "stopped"  # the first run's results, whole and alone
    assert len(res) >= 1 and np.isfinite(res.frame(-1)["positions"]).all()
    assert not (out / ".runout-results.lock").exists()


def test_utm_coordinates_and_markup_in_names_run_through_the_command_line(tiny_project, tmp_path):
    project = tmp_path / "utm.toml"
    project.write_text(tiny_project.read_text())
    overrides = [
        f"domain.origin_m=[{UTM[0]!r}, {UTM[1]!r}]",
        f"bodies.0.polygon_m={_box(UTM[0], UTM[1], 0.12, 0.24)}",
        'stages.1.name="[/]"',  # rich markup that is not valid
        "stages.1.duration_s=0.02",
    ]
    sets = [arg for item in overrides for arg in ("--set", item)]
    proc = subprocess.run(_cli("run", str(project), "--arch", "cpu", *sets), cwd=tmp_path,
                          capture_output=True, text=True, env=_env(), timeout=240)
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stderr and "MarkupError" not in proc.stderr
    assert "initial equilibrium after 'initial stress'" in proc.stderr
    res = Results(project.with_suffix(".results"))
    positions = res.frame(-1)["positions"]
    assert positions.dtype == np.float64
    assert len(np.unique(positions, axis=0)) == res.summary["particles"] == 288
    assert res.series["stage"][-1] == "[/]"


def test_real_world_coordinates_give_the_run_at_the_origin(tiny_project, tmp_path):
    base = load_project(tiny_project)
    common = ["stages.1.duration_s=0.02", "numerics.precision=f32"]
    near = apply_overrides(base, common)
    far = apply_overrides(base, [*common, f"domain.origin_m=[{UTM[0]!r}, {UTM[1]!r}]",
                                 f"bodies.0.polygon_m={_box(UTM[0], UTM[1], 0.12, 0.24)}"])
    a = run_project(near, tmp_path / "near.results", arch="cpu")
    b = run_project(far, tmp_path / "far.results", arch="cpu")
    assert a.ok and b.ok, (a.message, b.message)
    ra, rb = Results(a.out_dir), Results(b.out_dir)
    assert rb.summary["domain"]["origin_m"] == list(UTM)
    pa, pb = ra.frame(-1)["positions"], rb.frame(-1)["positions"]
    # the solver works relative to the grid origin: the same run to round-off of the local
    # coordinates (1e-6 of the 0.3 m scene), not of 4e6 m (0.25 m in float32)
    np.testing.assert_allclose(pb - np.array(UTM), pa, rtol=0, atol=1e-6)
    np.testing.assert_allclose(rb.frame(-1)["displacement"], ra.frame(-1)["displacement"], rtol=0, atol=1e-6)


@pytest.mark.parametrize("delay_s", [0.3, 0.6, 1.5])
def test_ctrl_c_at_any_moment_of_the_start_is_one_line(tiny_project, tmp_path, delay_s):
    proc = subprocess.Popen(_cli("run", str(tiny_project), "--arch", "cpu", "-q", "--out", str(tmp_path / "r")),
                            cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=_env())
    time.sleep(delay_s)
    proc.send_signal(signal.SIGINT)
    try:
        _, stderr = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    if "init_import_site" in stderr:
        pytest.skip("the signal came while the Python interpreter itself was starting")
    assert "Traceback" not in stderr, stderr
    assert proc.returncode in (0, 1, 130), stderr  # 0: it finished before the signal came
    assert stderr.count("error: ") <= 1, stderr
    if proc.returncode == 130:
        assert "interrupted" in stderr or "stopped" in stderr, stderr
