"""Running from the workbench: the solver in a worker thread, live view, cancel, errors, latency."""

from __future__ import annotations

import statistics

import pytest
from PySide6.QtCore import QElapsedTimer, QTimer

from projects.results import open_results

pytestmark = pytest.mark.gui


def wait_for_run(qtbot, win, timeout_s: float = 60.0) -> None:
    qtbot.waitUntil(lambda: win.worker is None, timeout=int(timeout_s * 1000))


def test_run_a_tiny_scene_to_completion(window, tiny_file, qtbot):
    window.open_project(tiny_file)
    frames_drawn = []
    assert window.start_run()
    assert window.run_panel.cancel_button.isEnabled() and not window.run_panel.run_button.isEnabled()
    assert window.tabs.currentWidget() is window.results_view
    original = window.results_view.show_live
    window.results_view.show_live = lambda frame: (frames_drawn.append(frame.diagnostics.time_s), original(frame))
    wait_for_run(qtbot, window)
    result = window.last_result
    assert result.status == "completed", result.message
    assert result.out_dir == tiny_file.with_name("tiny.results")
    # the view was updated live, the curves have every frame, then the folder was opened
    assert frames_drawn, "no live frame was drawn"
    results = open_results(result.out_dir)
    assert len(results) == 6
    assert window.results_view.curves.points == 6
    assert window.results_view.results is not None and len(window.results_view.results) == 6
    assert window.results_view.controls.slider.maximum() == 5
    assert window.run_panel.status.text().startswith("completed")
    assert window.run_panel.run_button.isEnabled() and not window.run_panel.cancel_button.isEnabled()
    # the throughput of this run feeds the next estimate
    rate, measured = window.settings.throughput("cpu")
    assert measured and rate == pytest.approx(result.summary["particle_steps_per_s"])
    assert "measured on this machine" in window.run_panel.runtime.text()


def test_cancel_stops_within_a_second_and_keeps_the_frames(window, long_file, qtbot):
    window.open_project(long_file)
    progress = []
    assert window.start_run()
    window.worker.progressed.connect(progress.append)
    qtbot.waitUntil(lambda: len(progress) >= 2, timeout=30_000)
    assert window.run_panel.progress.value() > 0
    assert "steps/s" in window.run_panel.rate.text()
    window.actions_["cancel"].trigger()
    wait_for_run(qtbot, window, 10.0)
    worker = window.last_worker
    # the solver checks the request every 20 steps; the rest is the last frame and the summary
    assert worker.ended_at - worker.cancelled_at < 1.0
    result = window.last_result
    assert result.status == "stopped"
    assert "the user" in result.message
    results = open_results(result.out_dir)
    assert results.status == "stopped" and len(results) >= 1
    assert window.results_view.results is not None
    assert window.run_panel.status.text().startswith("stopped")


def test_a_second_run_with_other_settings(window, tiny_file, qtbot):
    window.open_project(tiny_file)
    assert window.start_run()
    wait_for_run(qtbot, window)
    assert window.last_result.summary["scheme"] == "apic-affine"
    window.numerics_panel.scheme.choose("mpm")
    window.run_panel.out_dir.setText(str(tiny_file.with_name("mpm.results")))
    assert window.start_run()
    wait_for_run(qtbot, window)
    assert window.last_result.status == "completed", window.last_result.message
    assert window.last_result.summary["scheme"] == "mpm"
    assert open_results(tiny_file.with_name("tiny.results")).summary["scheme"] == "apic-affine"


def test_errors_before_the_run_are_readable_messages(window, tiny_file, qtbot):
    window.open_project(tiny_file)
    occupied = tiny_file.with_name("not-results")
    occupied.mkdir()
    (occupied / "notes.txt").write_text("keep me")
    window.run_panel.out_dir.setText(str(occupied))
    errors = []
    window.show_error = lambda title, text: errors.append((title, text))
    assert window.start_run()
    wait_for_run(qtbot, window)
    assert errors and errors[0][0] == "The run could not start"
    assert "is not a results folder; refusing to overwrite it" in errors[0][1]
    assert "Traceback" not in errors[0][1]
    assert (occupied / "notes.txt").read_text() == "keep me"
    assert window.run_panel.status.text().startswith("failed")


def test_the_window_stays_responsive_during_a_run(window, long_file, qtbot):
    window.open_project(long_file)
    progress = []
    assert window.start_run()
    window.worker.progressed.connect(progress.append)
    qtbot.waitUntil(lambda: len(progress) >= 1, timeout=30_000)  # the solver is stepping
    delays: list[float] = []
    clock = QElapsedTimer()
    timer = QTimer()
    timer.setInterval(20)

    def tick():
        delays.append(max(0.0, clock.restart() - 20.0))

    timer.timeout.connect(tick)
    clock.start()
    timer.start()
    qtbot.wait(2500)
    timer.stop()
    frames = window.results_view.curves.points
    window.cancel_run()
    wait_for_run(qtbot, window, 10.0)
    assert len(delays) > 20
    assert frames > 5, "the run drew too few frames while measuring"
    median = statistics.median(delays)
    assert median < 100.0, f"median event-loop latency {median:.0f} ms"


def test_the_stability_guard_is_reported_readably(window, tiny_file, qtbot):
    window.open_project(tiny_file)
    window.numerics_panel.dt.set_text("0.01")  # 13 times the critical step
    errors = []
    window.show_error = lambda title, text: errors.append((title, text))
    assert window.start_run()
    wait_for_run(qtbot, window)
    assert window.last_result.status == "failed"
    title, text = errors[0]
    assert title == "The run failed"
    assert text.startswith("unstable: time step 0.01 s is 13.0x the critical")
    assert "Traceback" not in text
    # the frames before the guard fired can be inspected
    assert window.results_view.results is not None and len(window.results_view.results) >= 1
    assert "[failed: unstable" in window.results_view.header.text()
