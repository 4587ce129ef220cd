"""Running from the workbench: each run a child process (``runout run --progress jsonl``), followed
through its results folder; cancel (SIGTERM), kill (SIGKILL), several runs, errors, red fields."""

from __future__ import annotations

import os
import shutil
import signal
import sys

import pytest
from PySide6.QtCore import Qt

from projects.results import open_results

pytestmark = pytest.mark.gui


def wait_for_runs(qtbot, win, timeout_s: float = 90.0) -> None:
    qtbot.waitUntil(lambda: not win.running, timeout=int(timeout_s * 1000))


def test_a_run_is_a_child_process_shown_live_from_its_folder(window, tiny_file, qtbot):
    # in a whole-suite process the solver tests' modules (collected first) have loaded Taichi
    # already; the fresh-interpreter check is tests/unit/test_architecture.py's
    taichi_before = "taichi" in sys.modules
    window.open_project(tiny_file)
    window.doc.set_value("runout.title", "edited, not saved")
    saved_text = tiny_file.read_text()
    refreshes = []
    original = window.results_view.refresh
    window.results_view.refresh = lambda: (refreshes.append(window.results_view.live), original())[1]
    assert window.start_run()
    run = window.followed
    assert window.tabs.currentWidget() is window.results_view
    qtbot.waitUntil(lambda: run.pid > 0, timeout=10_000)
    assert run.pid != os.getpid()
    wait_for_runs(qtbot, window)
    result = window.last_result
    assert result.status == "completed", result.message
    assert result.out_dir == tiny_file.with_name("tiny.results")
    # the workbench never loaded the solver's runtime; the child did the work
    assert taichi_before or "taichi" not in sys.modules
    assert result.summary["title"] == "edited, not saved"  # the document ran, unsaved edit included
    # the summary names the user's file (not the temporary copy that ran) and that it was edited
    assert result.summary["project_file"] == str(tiny_file) and result.summary["project_unsaved"] is True
    assert tiny_file.read_text() == saved_text and window.doc.is_dirty
    # the view read the folder while the run went on, then the finished folder
    assert any(refreshes), "the live view never read the running folder"
    assert [e["event"] for e in run.events][:2] == ["started", "frame"]
    assert run.events[-1]["event"] == "finished" and run.frames == 6
    assert len(open_results(result.out_dir)) == 6
    assert window.results_view.results is not None and len(window.results_view.results) == 6
    assert window.results_view.curves.points == 6
    assert window.results_view.controls.slider.maximum() == 5
    assert window.run_panel.status.text().startswith("completed")
    assert not window.run_panel.cancel_button.isEnabled()
    assert window.run_panel.runs.count() == 1 and "completed" in window.run_panel.runs.item(0).text()
    # the throughput of this run feeds the next estimate
    rate, measured = window.settings.throughput("cpu")
    assert measured and rate == pytest.approx(result.summary["particle_steps_per_s"])
    # and its step time the next estimate's cost: the project's own run, at its size
    assert window.settings.step_cost("cpu")[1] == 1
    assert "measured by this project's run (288 particles" in window.run_panel.rate_info.text()
    # the folder holds results now: a new run asks before replacing them
    asked = []
    window.ask_replace_results = lambda path: (asked.append(path), "cancel")[1]
    assert not window.start_run()
    assert asked == [tiny_file.with_name("tiny.results")] and len(window.runs) == 1
    window.ask_replace_results = lambda path: "new"
    assert window.start_run()
    wait_for_runs(qtbot, window)
    assert window.last_result.out_dir == tiny_file.with_name("tiny-2.results")
    assert len(open_results(tiny_file.with_name("tiny.results"))) == 6


def test_cancel_sends_sigterm_and_the_run_closes_its_folder(window, long_file, qtbot):
    window.open_project(long_file)
    assert window.start_run()
    run = window.followed
    qtbot.waitUntil(lambda: run.last_progress is not None and window.run_panel.progress.value() > 0,
                    timeout=60_000)
    assert "steps/s" in window.run_panel.rate.text()
    window.actions_["cancel"].trigger()
    assert run.cancel_requested
    wait_for_runs(qtbot, window, 30.0)
    result = window.last_result
    assert result.status == "stopped", result.message
    assert "SIGTERM" in result.message
    results = open_results(result.out_dir)
    assert results.status == "stopped" and len(results) >= 1
    assert window.results_view.results is not None
    assert window.run_panel.status.text().startswith("stopped")


def test_a_killed_run_shows_its_message_and_frames_and_no_edit_is_lost(window, long_file, qtbot):
    window.open_project(long_file)
    errors = []
    window.show_error = lambda title, text: errors.append((title, text))
    assert window.start_run()
    run = window.followed
    window.doc.set_value("materials.sand.cohesion_pa", 123.0)  # an edit while the run goes on
    qtbot.waitUntil(lambda: window.results_view.results is not None and len(window.results_view.results) >= 2,
                    timeout=60_000)
    os.kill(run.pid, signal.SIGKILL)
    wait_for_runs(qtbot, window, 30.0)
    result = window.last_result
    assert result.status == "killed"
    assert "killed by SIGKILL" in result.message
    assert errors and errors[-1][0] == "The run process ended abnormally"
    assert "SIGKILL" in errors[-1][1] and "Frames written until then" in errors[-1][1]
    results = open_results(result.out_dir)
    assert results.status == "interrupted" and len(results) >= 2
    assert results.frame(-1)["positions"].shape == (288, 2)
    assert window.results_view.results is not None and len(window.results_view.results) == len(results)
    assert window.run_panel.status.text().startswith("killed")
    # the workbench goes on: the edit is there and undoable, and the next run starts
    assert window.doc.get("materials.sand.cohesion_pa") == 123.0 and window.doc.is_dirty
    window.doc.undo_stack.undo()
    assert window.doc.get("materials.sand.cohesion_pa") == 0.0
    window.ask_replace_results = lambda path: "replace"
    assert window.start_run()
    window.followed.cancel()
    wait_for_runs(qtbot, window, 30.0)
    assert window.last_result.status in ("stopped", "killed")


def test_several_runs_at_once_each_in_its_own_folder(window, long_file, tiny_file, qtbot):
    window.open_project(long_file)
    assert window.start_run()
    first = window.followed
    # a second run of the same project: its folder is in use, so the run goes beside it
    window.doc.set_value("stages.1.duration_s", 0.05)
    assert window.start_run()
    second = window.followed
    assert second is not first and second.out_dir == long_file.with_name("long-2.results")
    assert first.is_running()
    qtbot.waitUntil(lambda: second.outcome is not None, timeout=90_000)
    assert second.outcome.status == "completed", second.outcome.message
    assert window.run_panel.runs.count() == 2
    # choosing the first run in the list follows it again (live), and Cancel applies to it
    window.run_panel.runs.setCurrentRow(0)
    assert window.followed is first
    if first.is_running():
        assert window.results_view.live
        window.cancel_run()
    wait_for_runs(qtbot, window, 30.0)
    assert first.outcome.status in ("stopped", "completed")
    assert open_results(first.out_dir).summary["total_time_s"] > open_results(second.out_dir).summary["total_time_s"]


def test_errors_are_readable_messages(window, tiny_file, qtbot):
    window.open_project(tiny_file)
    occupied = tiny_file.with_name("not-results")
    occupied.mkdir()
    (occupied / "notes.txt").write_text("keep me")
    window.run_panel.out_dir.setText(str(occupied))
    errors = []
    window.show_error = lambda title, text: errors.append((title, text))
    assert window.start_run()
    wait_for_runs(qtbot, window)
    assert window.last_result.status == "error"
    assert errors and errors[0][0] == "The run could not start"
    assert "is not a results folder; refusing to overwrite it" in errors[0][1]
    assert "Traceback" not in errors[0][1]
    assert (occupied / "notes.txt").read_text() == "keep me"
    assert window.run_panel.status.text().startswith("error")
    # the stability guard, reported with the solver's message
    window.run_panel.out_dir.clear()
    window.numerics_panel.dt.set_text("0.01")  # 13 times the critical step
    errors.clear()
    assert window.start_run()
    wait_for_runs(qtbot, window)
    assert window.last_result.status == "failed"
    title, text = errors[0]
    assert title == "The run failed"
    assert text.startswith("unstable: time step 0.01 s is 13.0x the critical")
    assert "Traceback" not in text
    # the frames before the guard fired can be inspected
    assert window.results_view.results is not None and len(window.results_view.results) >= 1
    assert "[failed: unstable" in window.results_view.header.text()


def test_a_field_shown_red_blocks_the_run_and_names_the_field(window, tiny_file):
    window.open_project(tiny_file)
    window.materials_panel.select("sand")
    density = window.materials_panel.fields["density_kg_m3"]
    density.set_text("-2000")
    assert density.error  # red, and not written to the project
    assert window.doc.get("materials.sand.density_kg_m3") == 2000.0
    errors = []
    window.show_error = lambda title, text: errors.append((title, text))
    assert not window.start_run()
    assert not window.runs
    assert errors[0][0] == "Cannot run"
    assert "Density (materials.sand.density_kg_m3)" in errors[0][1]
    density.set_text("1900")
    assert window.invalid_fields() == []


class _FakeRun:
    """A RunProcess whose child is a small script instead of ``runout run``."""

    @staticmethod
    def make(script: str, tmp_path):
        from app.gui.run_process import RunProcess

        class Fake(RunProcess):
            def command(self):
                import tempfile
                from pathlib import Path

                self._tmp = Path(tempfile.mkdtemp(prefix="runout-run-test-"))
                return [sys.executable, "-c", script]

        return Fake("", tmp_path / "fake.results", "fake")


def test_a_child_that_ignores_sigterm_gets_sigkill(qtbot, tmp_path, monkeypatch):
    import app.gui.run_process as rp

    monkeypatch.setattr(rp, "KILL_AFTER_MS", 300)
    script = ("import json, signal, sys, time; signal.signal(signal.SIGTERM, signal.SIG_IGN); "
              "print(json.dumps({'event': 'started', 'out_dir': 'x', 'particles': 1, 'total_time_s': 1.0}), "
              "flush=True); time.sleep(120)")
    run = _FakeRun.make(script, tmp_path)
    run.start()
    qtbot.waitUntil(lambda: run.started_event is not None, timeout=30_000)
    run.cancel()
    qtbot.waitUntil(lambda: run.outcome is not None, timeout=30_000)
    assert run.outcome.status == "killed"
    assert run.outcome.message.startswith("the run process was killed by SIGKILL after the cancel request")
    assert not run._tmp.exists()  # the temporary project folder is removed


def test_a_child_that_crashes_reports_its_last_words(qtbot, tmp_path):
    script = "import sys; print('Fatal Python error: Segmentation fault', file=sys.stderr); sys.exit(139)"
    run = _FakeRun.make(script, tmp_path)
    run.start()
    qtbot.waitUntil(lambda: run.outcome is not None, timeout=30_000)
    assert run.outcome.status == "crashed" and run.outcome.exit_code == 139
    assert run.outcome.message == ("the run process ended with exit code 139: "
                                   "Fatal Python error: Segmentation fault")


ORPHAN_PARENT = """
import sys, time
from PySide6.QtCore import QCoreApplication
from app.gui.run_process import RunProcess
app = QCoreApplication([])
run = RunProcess(open(sys.argv[1]).read(), sys.argv[2], "orphan")
run.runStarted.connect(lambda e: print(run.pid, flush=True))
run.start()
app.exec()
"""


def test_a_run_stops_when_the_workbench_dies(long_file, tmp_path):
    """The workbench killed with SIGKILL (no chance to stop its runs): its run gets SIGTERM
    and closes its folder as "stopped", instead of going on as an orphan."""
    import json
    import subprocess

    from tests.conftest import REPO

    out = tmp_path / "orphan.results"
    env = dict(os.environ, PYTHONPATH=str(REPO), QT_QPA_PLATFORM="offscreen")
    parent = subprocess.Popen([sys.executable, "-c", ORPHAN_PARENT, str(long_file), str(out)],
                              stdout=subprocess.PIPE, text=True, env=env)
    try:
        child = int(parent.stdout.readline())
    finally:
        parent.kill()
        parent.wait(30)
    import time

    start = time.monotonic()
    try:
        while time.monotonic() - start < 120.0:  # a deadline for a loaded machine, not a timing claim
            os.kill(child, 0)
            time.sleep(0.2)
    except ProcessLookupError:
        pass
    else:
        os.kill(child, signal.SIGKILL)
    status = json.loads((out / "summary.json").read_text())
    assert status["status"] == "stopped", status
    assert "SIGTERM" in status["message"]


def test_cancel_during_the_run_process_start_up_is_a_stop_not_an_abnormal_end(window, tiny_file, long_file, qtbot):
    """Run, then Cancel at once, while the child is still starting (its SIGTERM handler not yet
    installed, or before it reported its folder): the run is "stopped", with no error dialog, and
    the results folder it was to replace is not shown as its frames (not "The run process ended
    abnormally: killed by SIGTERM after the cancel request ... Frames written until then are in
    ..." over the earlier run's results)."""
    window.open_project(tiny_file)
    assert window.start_run()
    wait_for_runs(qtbot, window, 90.0)
    assert window.last_result.status == "completed"
    window.open_project(long_file)
    window.ask_replace_results = lambda path: "replace"
    window.run_panel.out_dir.setText(str(window.last_result.out_dir))  # the earlier run's folder
    for _ in range(3):
        assert window.start_run()
        run = window.followed
        qtbot.waitUntil(lambda: run.pid is not None and run.pid > 0, timeout=10_000)
        run.cancel()  # show_error would fail the test (no dialog answered)
        wait_for_runs(qtbot, window, 60.0)
        result = window.last_result
        assert result.status == "stopped", result.message
        if run.started_event is None:  # the usual case: cancelled within the child's start-up
            assert result.message == "cancelled before the run started"
            assert window.results_view.results is None
            assert "no frame was written" in window.results_view.header.text()


def test_the_run_is_told_which_file_it_is_a_copy_of(qtbot, tmp_path):
    """The run starts from a temporary copy of the window's project; it records the user's file
    (``--source``) and whether the window held edits not saved in it (``--unsaved``) in
    summary.json, whose project_file named the temporary copy (and so did the report)."""
    from app.gui.run_process import RunProcess

    saved = RunProcess("", tmp_path / "a.results", "slope", source=tmp_path / "slope.toml", unsaved=False)
    args = saved.command()
    assert args[args.index("--source") + 1] == str(tmp_path / "slope.toml") and "--unsaved" not in args
    untitled = RunProcess("", tmp_path / "b.results", "untitled", source=None, unsaved=True)
    args = untitled.command()
    assert "--source" not in args and "--unsaved" in args
    for run in (saved, untitled):  # never started: remove their temporary copies here
        shutil.rmtree(run._tmp)


def _open_near_limit_block(window, tmp_path):
    """A soft 5-cell block sliding 5 degrees above a 35-degree friction limit (the near-limit
    warning), opened in the workbench; its Run panel, estimate up to date."""
    from tests.contact_scenes import project_text

    path = tmp_path / "block.toml"
    path.write_text(project_text("bottom", "apic-affine", "f32", 5, 1e6, 40, 35, gravity_s=None).text, encoding="utf-8")
    assert window.open_project(path)
    window.run_panel.update_estimate()
    return window.run_panel


def test_a_double_click_on_the_flutter_warning_opens_the_material_to_damp(window, tmp_path):
    # the near-limit warning names the keys to set: its item leads to that material
    panel = _open_near_limit_block(window, tmp_path)
    items = [panel.problems.item(i) for i in range(panel.problems.count())]
    [item] = [i for i in items if "flutters" in i.text()]
    assert item.data(Qt.ItemDataRole.UserRole) == "materials.block"
    window.panels.setCurrentWidget(window.domain_panel)
    panel.problems.itemDoubleClicked.emit(item)
    assert window.panels.currentWidget() is window.materials_panel
    assert window.materials_panel.current == "block"
    # the values it gives, typed in, take the warning away
    materials = window.materials_panel
    ratio = item.text().split(".damping_ratio = ")[1].split(",")[0]
    materials.fields["damping_ratio"].set_text(ratio)
    frequency = item.text().split("damping_frequency_hz = ")[1].split(" ")[0]
    materials.fields["damping_frequency_hz"].set_text(frequency)
    assert materials.damping_model.isEnabled() and materials.damping_model.combo.currentText() == "rayleigh"
    model = item.text().split('damping_model = "')[1].split('"')[0]
    materials.damping_model.choose(model)
    assert window.doc.get("materials.block.damping_model") == "maxwell"
    panel.update_estimate()
    assert not any("flutters" in panel.problems.item(i).text() for i in range(panel.problems.count()))


def test_an_idle_run_box_leaves_the_height_to_a_long_warning(window, tmp_path):
    # the progress lines are hidden while empty and the Problems list takes the dock's free height,
    # so the near-limit warning is read to its end (the keys to set come last)
    panel = _open_near_limit_block(window, tmp_path)
    assert not any(w.isVisible() for w in (panel.stage, panel.clock, panel.rate, panel.eta, panel.status))
    assert panel.problems.maximumHeight() > 1000
    panel.status.setText("completed: 10 steps")
    assert panel.status.isVisibleTo(panel)
