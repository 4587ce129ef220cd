"""``projects.runner.run_project`` in process: every way a run can end leaves a closed folder."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from projects.results import Results, ResultsError
from projects.runner import RunResult, StopRequest, default_results_dir, run_project


@pytest.fixture
def project(tiny_project, tmp_path):
    from projects.document import load_project

    path = Path(shutil.copy(tiny_project, tmp_path / "tiny.toml"))
    return path, load_project(path)


def test_completed_run_with_default_folder_and_callbacks(project):
    path, model = project
    frames, progress = [], []
    result = run_project(model, project_path=path, arch="cpu",
                         on_frame=frames.append, on_progress=progress.append)
    assert isinstance(result, RunResult) and result.ok
    assert result.out_dir == default_results_dir(path) == path.with_name("tiny.results")
    res = Results(result.out_dir)
    assert len(res) == len(frames) >= 2
    assert res.times[-1] == pytest.approx(frames[-1].diagnostics.time_s)
    assert progress and progress[-1].total_time_s > 0
    assert result.summary["project_file"] == str(path)
    assert result.summary["materials"] and result.summary["domain"]["cell_size_m"] > 0


def test_cancel_stops_after_one_more_frame(project, tmp_path):
    _, model = project
    stop = StopRequest()
    seen = []

    def on_frame(frame):
        seen.append(frame)
        if len(seen) == 2:
            stop.request("the test")

    result = run_project(model, tmp_path / "out", arch="cpu", cancel=stop, on_frame=on_frame)
    assert result.status == "stopped"
    assert result.message.startswith("stopped by the test")
    res = Results(tmp_path / "out")
    assert res.status == "stopped"
    assert len(res) == len(seen) == 3


def test_an_exception_during_the_run_fails_it(project, tmp_path):
    _, model = project

    def on_frame(frame):
        if frame.diagnostics.step > 0:
            raise RuntimeError("boom in a callback")

    result = run_project(model, tmp_path / "out", arch="cpu", on_frame=on_frame)
    assert result.status == "failed"
    assert "RuntimeError: boom in a callback" in result.message
    res = Results(tmp_path / "out")
    assert res.status == "failed" and len(res) == 2


def test_keyboard_interrupt_becomes_stopped(project, tmp_path):
    _, model = project

    def on_frame(frame):
        if frame.diagnostics.step > 0:
            raise KeyboardInterrupt

    result = run_project(model, tmp_path / "out", arch="cpu", on_frame=on_frame)
    assert result.status == "stopped"
    assert "Ctrl-C" in result.message
    assert Results(tmp_path / "out").status == "stopped"


def test_bad_output_locations_are_refused_before_running(project, tmp_path):
    _, model = project
    with pytest.raises(ValueError, match="out_dir or project_path"):
        run_project(model)
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "data.csv").write_text("1,2")
    with pytest.raises(ResultsError, match="refusing to overwrite"):
        run_project(model, tmp_path / "mine", arch="cpu")
    assert (tmp_path / "mine" / "data.csv").read_text() == "1,2"


def test_check_project_builds_without_running(project, tmp_path):
    from projects.runner import check_project

    path, model = project
    built = check_project(model)
    assert len(built.particles) > 0
    assert built.material_names == tuple(model.material_names)
    assert not default_results_dir(path).exists()
