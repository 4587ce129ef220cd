"""Inspecting results: time slider, fields, colours, picking, exports and side-by-side comparison."""

from __future__ import annotations

import csv

import numpy as np
import pytest
from PySide6.QtCore import Qt

from app.render import field_values

pytestmark = pytest.mark.gui


def test_step_the_slider_and_change_the_field(window, make_results, qtbot):
    path = make_results(n_frames=4)
    assert window.open_results(path)
    view = window.results_view
    assert window.tabs.currentWidget() is view
    assert view.controls.slider.maximum() == 3 and view.frame_index == 3  # opens at the end state
    assert "[completed]" in view.header.text()
    view.controls.slider.setValue(1)
    assert view.frame_index == 1
    assert view.controls.time_label.text().startswith("t = 0.05 s   frame 2/4")
    frame = view.results.frame(1)
    active = frame["active"]
    assert np.allclose(view.scene.values, field_values(frame, "displacement")[active])
    # another field: values, colour bar title and unit follow
    view.set_field("stress_yy")
    assert "Stress yy (kPa)" in view.scene.plotter.scalar_bars
    assert "Displacement (m)" not in view.scene.plotter.scalar_bars
    assert view.controls.unit.text() == "kPa"
    assert np.allclose(view.scene.values, field_values(frame, "stress_yy")[active])
    assert view.scene.actor.mapper.scalar_range == pytest.approx(view.scene.shown_clim)
    # a fixed colour range instead of the frame's own
    view.controls.auto.setChecked(False)
    view.controls.lo.setText("-3")
    view.controls.hi.setText("0")
    view.controls.lo.editingFinished.emit()
    assert view.scene.actor.mapper.scalar_range == pytest.approx((-3.0, 0.0))
    view.controls.cmap.setCurrentText("coolwarm")
    view.controls.cmap.activated.emit(0)
    assert view.scene.cmap == "coolwarm"
    # materials are categories named in the legend
    view.set_field("material")
    assert view.scene.values.max() == 1 and view.controls.unit.text() == ""
    # the last frame lost five particles: they are not drawn
    view.controls.slider.setValue(3)
    assert len(view.scene.positions) == len(active) - 5


def test_play_runs_through_the_frames_and_stops(window, make_results, qtbot):
    window.open_results(make_results(n_frames=4))
    view = window.results_view
    view.controls.slider.setValue(0)
    view.controls.play.setChecked(True)
    # a deadline, not a timing claim: 3 frames at 120 ms each, on a loaded machine
    qtbot.waitUntil(lambda: not view.controls.play.isChecked(), timeout=60_000)
    assert view.frame_index == 3


def test_pick_a_particle_and_export_its_history(window, make_results, qtbot, tmp_path):
    window.open_results(make_results(n_frames=4))
    view = window.results_view
    view.controls.slider.setValue(1)
    target = 123
    xy = view.results.frame(1)["positions"][target]
    pos = view.scene.widget_at(xy).toPoint()
    qtbot.mouseClick(view.scene.plotter, Qt.MouseButton.LeftButton, pos=pos)
    assert view.scene.picked_id == target
    label, times, values = view.history
    assert np.allclose(times, view.results.times)
    expected = [field_values(view.results.frame(j), "displacement")[target] for j in range(4)]
    assert np.allclose(values, expected, rtol=1e-6)
    assert view.side.currentWidget() is view.history_plot
    assert "pick" in view.scene.plotter.actors
    out = view.export_curves(tmp_path / "curves.csv")
    rows = list(csv.reader(out.open()))
    assert rows[0][:2] == ["frame", "time_s"] and "kinetic_energy_J_per_m" in rows[0]
    assert rows[0][-1] == f"particle_{target}_displacement"
    assert len(rows) == 5
    assert float(rows[2][-1]) == pytest.approx(expected[1], rel=1e-6)


def test_export_a_screenshot_offscreen_at_a_chosen_size(window, make_results, tmp_path):
    import imageio.v3 as iio

    window.open_results(make_results(n_frames=4))
    window.results_view.set_field("velocity")
    out = window.results_view.export_screenshot(tmp_path / "shot.png", (800, 450))
    image = iio.imread(out)
    assert image.shape[:2] == (450, 800)
    rgb = image[..., :3].reshape(-1, 3)
    not_white = np.any(rgb < 235, axis=1).mean()
    colours = len(np.unique(rgb, axis=0))
    assert not_white > 0.02 and colours > 50, (not_white, colours)


def test_export_an_animation(window, make_results, tmp_path):
    import imageio.v3 as iio

    window.open_results(make_results(n_frames=4))
    done = []
    out = window.results_view.export_animation(tmp_path / "movie.gif", 5.0, (320, 180),
                                               lambda i, n: done.append((i, n)))
    assert done[-1] == (4, 4)
    frames = iio.imread(out, index=None)
    assert frames.shape[0] == 4 and frames.shape[1:3] == (180, 320)


def test_compare_two_results_with_linked_cameras(window, make_results, qtbot):
    a = make_results("a.results", n_frames=4)
    b = make_results("b.results", n_frames=3, status="stopped")
    compare = window.show_compare()
    compare.open_results(0, a)
    compare.open_results(1, b)
    left, right = compare.scenes
    qtbot.wait(50)  # the new tab's layout settles (the views fit themselves to their size)
    assert left.plotter.renderer.GetActiveCamera() is right.plotter.renderer.GetActiveCamera()
    scale = left.plotter.camera.parallel_scale
    left.plotter.camera.parallel_scale = scale / 2
    qtbot.wait(20)
    assert right.plotter.camera.parallel_scale == pytest.approx(scale / 2)
    compare.controls.slider.setValue(3)
    # B has no frame at t = 0.15 s: it shows its nearest (its last, 0.10 s)
    assert compare.controls.time_label.text() == "t = 0.15 s"
    assert left.actor is not None and right.actor is not None
    assert left.actor.mapper.scalar_range == pytest.approx(right.actor.mapper.scalar_range)
    assert "stopped" in compare.labels[1].text()


def test_a_folder_that_is_not_results_is_refused_readably(window, tmp_path):
    errors = []
    window.show_error = lambda title, text: errors.append(text)
    assert not window.open_results(tmp_path)
    assert "is not a results folder" in errors[0]


def test_the_auto_colour_range_shows_whole_numbers(window, make_results):
    """The colour range fields show the number from its start, whole (a displacement range of
    0.0002828 m read '828' in a 90-pixel field scrolled to its end)."""
    path = make_results(n_frames=2)
    assert window.open_results(path)
    controls = window.results_view.controls
    controls.show_range((-0.0002828, 0.0002828))
    for edit in (controls.lo, controls.hi):
        assert edit.cursorPosition() == 0
        room = edit.contentsRect().width() - 8  # the frame's and the text margins
        assert edit.fontMetrics().horizontalAdvance(edit.text()) <= room, (edit.text(), room)


def test_results_in_real_world_coordinates_are_drawn_and_picked_where_they_are(window, tmp_path, qtbot):
    """Frames in UTM-like coordinates (y ~ 4e6 m) are drawn relative to the grid's corner: in
    float32, as VTK draws, the 800 particles of the synthetic block fell onto 0.25 m rows (a few
    squares) and the structure's fill slid off its outline; picking adds the corner back."""
    from projects.results import ResultsWriter
    from solver.config import Frame
    from tests.conftest import SYNTHETIC_META, synthetic_frames

    offset = np.array([500000.0, 4000000.0])
    meta = {**SYNTHETIC_META, "domain": {**SYNTHETIC_META["domain"], "origin_m": list(offset)},
            "structures": [{"name": "dam", "polygon_m": (np.array([[0.3, 0.0], [0.4, 0.0], [0.4, 0.05]]) + offset).tolist()}]}
    writer = ResultsWriter(tmp_path / "utm.results", "", meta)
    for frame in synthetic_frames(2, lose_last=0):
        writer.write_frame(Frame(frame.diagnostics, {**frame.fields, "positions": frame.fields["positions"] + offset},
                                 frame.contacts))
    writer.close("completed")
    assert window.open_results(tmp_path / "utm.results")
    scene = window.results_view.scene
    positions = window.results_view.results.frame(1)["positions"]
    corner = getattr(scene, "offset", 0.0)
    drawn = np.asarray(scene.cloud.points, dtype=float)[:, :2] + corner
    assert np.abs(drawn - positions).max() < 1e-6  # float32 at 4e6 m: 0.25 m
    fill = np.asarray(scene.plotter.actors["structures"].mapper.dataset.points, dtype=float)[:, :2] + corner
    assert np.abs(fill - np.array(meta["structures"][0]["polygon_m"])[:, None, :]).sum(-1).min(0).max() < 1e-6
    target = 123
    pos = scene.widget_at(positions[target]).toPoint()
    qtbot.mouseClick(scene.plotter, Qt.MouseButton.LeftButton, pos=pos)
    assert scene.picked_id == target


def test_curves_of_a_run_before_its_first_frame_show_no_axes_of_the_last_run(qtbot):
    """The run curves and the contact forces, cleared for a run that has no frame yet (or never
    gets one), show a plain 0-1 range, not the axes of the run shown before (a hidden time marker
    at its last time held them: 0.0075-0.008 s)."""
    from app.gui.curves import ContactCurves, SeriesCurves

    series = SeriesCurves()
    contacts = ContactCurves()
    qtbot.addWidget(series)
    qtbot.addWidget(contacts)
    times = np.array([0.0075, 0.0078, 0.008])
    series.set_series({"time_s": times, **{k: np.array([1.0, 2.0, 3.0]) for k in
                                           ("kinetic_energy_J_per_m", "momentum_x", "momentum_y", "max_speed_m_s")}})
    contacts.set_contacts({"left": {"time_s": times, "force_x_N_per_m": np.ones(3), "force_y_N_per_m": np.ones(3),
                                    "peak_force_N_per_m": np.ones(3)}})
    for canvas in (series, contacts):
        canvas.set_time(0.008)
        canvas.redraw_now()
        assert canvas.axes[0].get_xlim()[1] == pytest.approx(0.008, abs=1e-3)
        canvas.clear()
        canvas.set_time(None)
        canvas.redraw_now()
        for ax in canvas.axes:
            assert ax.get_xlim() == (0.0, 1.0) and ax.get_ylim() == (0.0, 1.0)
    # and the next run's curves get axes that hold them again (the 0-1 range switches matplotlib's
    # autoscaling off; left off, every later run would show its curves through a 0-1 window)
    later = np.array([0.0, 2.0, 4.0])
    big = np.array([10.0, 250.0, 90.0])
    series.set_series({"time_s": later, **{k: big for k in
                                           ("kinetic_energy_J_per_m", "momentum_x", "momentum_y", "max_speed_m_s")}})
    contacts.set_contacts({"dam": {"time_s": later, "force_x_N_per_m": big, "force_y_N_per_m": 0 * big,
                                   "peak_force_N_per_m": big}})
    for canvas in (series, contacts):
        canvas.redraw_now()
        for ax in canvas.axes:
            (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
            assert x0 <= 0.0 and x1 >= 4.0 and y1 >= 250.0, (ax.get_xlim(), ax.get_ylim())
