"""``runout sweep`` and ``runout calibrate`` share one body (app.sweep_commands._run_on_ray): the same
checks and one-line errors before Ray starts, the same default folder, run arguments and stop
exit. In-process (typer's CliRunner) with the run replaced by a stand-in; the real runs on Ray
are tests/integration/test_sweeps_ray.py."""

from __future__ import annotations

import types
from pathlib import Path

import pytest
from typer.testing import CliRunner

from app.cli import EXIT_SIGINT, cli

TINY = Path(__file__).resolve().parents[2] / "projects" / "examples" / "tiny_column.toml"
PHI = "materials.sand.friction_angle_deg"
SPECS = {
    "sweep": f'[sweep]\nproject = "{TINY}"\nsampling = "grid"\n[parameters]\n"{PHI}" = [20.0, 30.0]\n',
    "calibrate": (f'[calibration]\nproject = "{TINY}"\ntrials = 2\n[parameters]\n'
                  f'"{PHI}" = {{distribution = "uniform", low = 10.0, high = 40.0}}\n'
                  '[observation]\ntype = "deposit-profile"\nfile = "observed.csv"\n'),
}
RUNNERS = {"sweep": ("sweeps.sweep", "run_sweep", "sweep"), "calibrate": ("sweeps.calibrate", "run_calibration",
                                                                          "calibration")}


@pytest.fixture
def specs(tmp_path):
    (tmp_path / "observed.csv").write_text("x_m,y_m\n0.0,0.1\n0.1,0.05\n0.2,0.0\n", encoding="utf-8")
    for command, text in SPECS.items():
        (tmp_path / f"{command}.toml").write_text(text, encoding="utf-8")
    return tmp_path


def _invoke(*args: str):
    return CliRunner().invoke(cli, list(args))


@pytest.mark.parametrize("command", ["sweep", "calibrate"])
def test_both_commands_check_options_and_files_alike_before_any_run(command, specs, monkeypatch):
    module, name, _ = RUNNERS[command]
    ran = []
    monkeypatch.setattr(f"{module}.{name}", lambda *a, **k: ran.append(1))
    spec = str(specs / f"{command}.toml")
    other = str(specs / ("calibrate.toml" if command == "sweep" else "sweep.toml"))
    for args, message in (
        (["--workers", "0"], "error: --workers must be >= 1, not 0"),
        (["--threads", "0"], "error: --threads must be >= 1, not 0"),
        (["--gpus-per-run", "-1"], "error: --gpus-per-run must be >= 0, not -1"),
    ):
        res = _invoke(command, spec, *args)
        assert res.exit_code == 1 and res.output.strip().splitlines() == [message], res.output
    res = _invoke(command, other)
    kind = "calibration file" if command == "sweep" else "sweep file"
    assert res.exit_code == 1 and f"this is a {kind}" in res.output and len(res.output.strip().splitlines()) == 1
    bad = specs / "bad.toml"
    bad.write_text(SPECS[command].replace(PHI, "materials.sand.friction_angl"), encoding="utf-8")
    res = _invoke(command, str(bad))
    assert res.exit_code == 1 and res.output.startswith(f"error: {bad}: ") and "friction_angl" in res.output
    assert len(res.output.strip().splitlines()) == 1
    assert not ran


@pytest.mark.parametrize("command", ["sweep", "calibrate"])
def test_both_commands_run_into_the_default_folder_and_exit_on_a_stop(command, specs, monkeypatch):
    module, name, suffix = RUNNERS[command]
    calls = []

    def run(spec, folder, **kwargs):
        calls.append((Path(folder), kwargs))
        kwargs["on_progress"](types.SimpleNamespace(done=1, total=2, failed=0, eta_s=float("inf")))
        return types.SimpleNamespace(stopped=True, records=[types.SimpleNamespace(status="completed")] * 2,
                                     out_dir=Path(folder), summary_lines=lambda: ["2 trials"])

    monkeypatch.setattr(f"{module}.{name}", run)
    res = _invoke(command, str(specs / f"{command}.toml"), "--workers", "2", "--threads", "1")
    (folder, kwargs), = calls
    assert folder == specs / f"{command}.{suffix}"
    assert {k: kwargs[k] for k in ("workers", "address", "threads_per_run", "gpus_per_run")} == {
        "workers": 2, "address": None, "threads_per_run": 1, "gpus_per_run": None}
    assert res.exit_code == EXIT_SIGINT  # stopped, as by Ctrl-C (no SIGTERM seen)
