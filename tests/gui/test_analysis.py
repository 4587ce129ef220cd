"""The Hazard tab, the HTML report export, the Factor-of-safety tab, the Sweep dialog and the Sweep
tab, on synthetic results and sweep folders (no solver, no Ray: the folders are the interface)."""

from __future__ import annotations

import csv
import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest
from PySide6.QtCore import Qt

NX = 16
CELL_M = 0.05


def write_hazard(folder: Path) -> dict:
    """Hazard files of a made-up run beside the synthetic frames: a flow from x = 0.2 m whose
    deposit ends at x = 0.5 m, a road (line) at x = 0.4 m it reaches at t = 0.12 s and a house
    (point) at x = 0.7 m it never reaches."""
    x = (np.arange(NX) + 0.5) * CELL_M
    ground = np.where(x < 0.2, 0.1, 0.0)
    peak = np.where(x < 0.55, 0.08 - 0.1 * x, 0.0).clip(0.0)
    surface = np.where(x < 0.5, 0.06 - 0.1 * x, 0.0).clip(0.0)
    surface = np.maximum(surface, 0.0)
    arrival = np.where(x < 0.55, 0.3 * x, np.nan)
    speed = np.where(x < 0.55, 1.0 + x, 0.0)
    pressure = 2000.0 * speed**2
    cols = {
        "x_m": x, "x_lo_m": x - CELL_M / 2, "x_hi_m": x + CELL_M / 2, "floor_m": np.zeros(NX), "ground_m": ground,
        "surface_m": surface, "peak_flow_height_m": peak, "deposit_m": surface - ground, "arrival_s": arrival,
        "max_speed_m_s": speed, "max_energy_J_m3": 0.5 * pressure, "max_pressure_pa": pressure,
    }
    with open(folder / "hazard_profile.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(list(cols))
        for row in zip(*cols.values()):
            w.writerow(["" if not math.isfinite(v) else repr(float(v)) for v in row])
    t = np.linspace(0.0, 0.3, 7)
    with open(folder / "targets.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["time_s", "kinetic_energy_J_per_m", "max_speed_m_s", "road:height_m", "road:speed_m_s",
                    "road:pressure_pa", "house:height_m", "house:speed_m_s", "house:pressure_pa"])
        for tt in t:
            on = tt >= 0.12
            w.writerow([tt, 10 * tt, 1.0, 0.03 * on, 1.4 * on, 3920 * on, 0.0, 0.0, 0.0])
    doc = {
        "status": "completed", "runout_version": "0.1.0", "release_time_s": 0.0, "time_s": 0.3, "direction": 1,
        "runout_distance_m": 0.3, "runout_x_m": 0.5, "runout_point_m": [0.5, 0.0],
        "runout_distance_envelope_m": 0.35, "runout_x_envelope_m": 0.55, "travel_angle_deg": 11.3099,
        "h_over_l": 0.2, "drop_height_m": 0.1, "travel_length_m": 0.5, "source_top_m": [0.0, 0.1],
        "source_front_x_m": 0.2, "mobilised_area_m2_per_m": 0.02, "slide_duration_s": 0.25,
        "peak_kinetic_energy_J_per_m": 3.0, "max_speed_m_s": 1.55, "max_pressure_pa": 4805.0,
        "max_flow_height_m": 0.08, "centroid_travel_angle_deg": 14.0,
        "thresholds": {"deposit_threshold_m": 0.005, "flow_height_threshold_m": 0.005,
                       "mobilised_displacement_m": 0.001, "kinetic_energy_fraction": 0.01,
                       "cell_size_m": CELL_M, "update_every_steps": 10},
        "targets": {
            "road": {"kind": "line", "x_m": 0.4, "y_m": None, "arrival_time_s": 0.12, "arrival_after_release_s": 0.12,
                     "max_height_m": 0.03, "max_speed_m_s": 1.4, "max_pressure_pa": 3920.0},
            "house": {"kind": "point", "x_m": 0.7, "y_m": 0.01, "arrival_time_s": None,
                      "arrival_after_release_s": None, "max_height_m": 0.0, "max_speed_m_s": 0.0,
                      "max_pressure_pa": 0.0},
        },
        "raster": {"origin_m": [0.0, 0.0], "cell_size_m": CELL_M, "shape": [NX, 3]},
        "sampling": {"every_steps": 10, "updates": 7},
        "files": {"profile": "hazard_profile.csv", "targets": "targets.csv", "raster": "hazard.vti"},
    }
    (folder / "hazard.json").write_text(json.dumps(doc))
    return doc


def _cells(table) -> list[list[str]]:
    return [[table.item(r, c).text() if table.item(r, c) else "" for c in range(table.columnCount())]
            for r in range(table.rowCount())]


def test_the_hazard_tab_shows_the_measures_and_targets_of_a_results_folder(window, make_results):
    path = make_results()
    write_hazard(path)
    assert window.open_results(path)
    window.tabs.setCurrentWidget(window.hazard_view)
    view = window.hazard_view
    assert view.path == path
    measures = {row[0]: row[1:] for row in _cells(view.measures)}
    assert measures["run-out distance (deposit, from the source front)"] == ["0.3 m", "deposit_threshold_m = 0.005"]
    assert measures["travel angle (Fahrboeschung)"][0] == "11.31 deg"
    assert measures["H / L"][0] == "0.2"
    # pressures in kPa, as in the plots and the targets' table (the measures said Pa)
    assert measures["largest impact pressure"][0] == "4.805 kPa"
    targets = {row[0]: row[1:] for row in _cells(view.targets)}
    assert targets["road (line)"][:2] == ["0.4", "0.12"]
    assert targets["road (line)"][5] == "3.92"  # kPa
    assert targets["house (point)"][1] == "–"  # never reached
    # five profiles along x, sharing the section; the road drawn as a line on each
    axes = view.figure.axes
    assert len(axes) == 5
    assert [a.get_ylabel() for a in axes[1:]] == ["peak speed (m/s)", "peak pressure (kPa)", "arrival (s)",
                                                   "deposit (m)"]
    for ax in axes:
        assert any(len(line.get_xdata()) == 2 and np.allclose(line.get_xdata(), [0.4, 0.4]) for line in ax.lines)
    assert np.nanmax(axes[2].lines[0].get_ydata()) == pytest.approx(2.0 * (1.0 + 0.525) ** 2)
    assert view.export_button.isEnabled()
    assert not window.tabs.isTabVisible(window.tabs.indexOf(window.fos_view))


def test_the_hazard_tables_show_every_header_and_value_whole(window, make_results, qtbot):
    """At the window's default size the tables were cut: the targets' last column kept Qt's
    default 100 px under its header "max pressure (kPa)" (elided) and the measures' value column
    began 250 px into a 300 px wide table. Now each column is as wide as its header and values
    (the measure names wrap), a value stands beside its measure, and a table too narrow for
    its columns scrolls."""
    from PySide6.QtCore import QRect
    from PySide6.QtGui import QFontMetrics

    from app.gui.main_window import MainWindow

    path = make_results()
    write_hazard(path)
    window.resize(MainWindow.DEFAULT_SIZE[0], MainWindow.DEFAULT_SIZE[1])
    window.open_results(path)
    window.tabs.setCurrentWidget(window.hazard_view)
    qtbot.waitUntil(lambda: window.hazard_view.targets.viewport().width() > 50)
    view = window.hazard_view
    for table in (view.measures, view.targets):
        header = table.horizontalHeader()
        fm = QFontMetrics(table.font())
        for c in range(table.columnCount()):
            width = table.columnWidth(c)
            assert width >= header.sectionSizeHint(c), (table.horizontalHeaderItem(c).text(), width)
            for r in range(table.rowCount()):
                text = table.item(r, c).text()
                if table.wordWrap() and c == 0 and table is view.measures:
                    # wrapped at spaces: every word fits, and the row holds the lines
                    words = max(fm.horizontalAdvance(w) for w in text.split())
                    assert words + 8 <= width, text
                    lines = fm.boundingRect(QRect(0, 0, width - 8, 10_000), Qt.TextFlag.TextWordWrap, text)
                    assert lines.height() <= table.rowHeight(r), text
                else:
                    assert fm.horizontalAdvance(text) + 6 <= width, (text, width)
        if header.length() > table.viewport().width():
            assert table.horizontalScrollBar().maximum() > 0  # the rest is a scroll away
    # the value column beside the measures, without scrolling
    measures = view.measures
    assert measures.columnViewportPosition(1) + measures.columnWidth(1) <= measures.viewport().width()


def test_the_legend_leaves_the_target_names_readable(window, make_results):
    """The legend of the scene plot sat in its upper right corner, over the names of the targets
    downstream (the road and the house here, the dam crest and the road of debris_barrier.toml)."""
    path = make_results()
    write_hazard(path)
    window.open_results(path)
    window.tabs.setCurrentWidget(window.hazard_view)
    view = window.hazard_view
    view.canvas.draw()
    renderer = view.canvas.get_renderer()
    names = [t for ax in view.figure.axes for t in ax.texts if t.get_text() in ("road", "house")]
    assert sorted(t.get_text() for t in names) == ["house", "road"]
    legends = [ax.get_legend() for ax in view.figure.axes if ax.get_legend() is not None] + view.figure.legends
    assert legends and "peak flow height" in [t.get_text() for t in legends[0].get_texts()]
    for legend in legends:
        box = legend.get_window_extent(renderer)
        for name in names:
            assert not box.overlaps(name.get_window_extent(renderer)), name.get_text()


def test_a_results_folder_without_hazard_files_says_so(window, make_results):
    assert window.open_results(make_results())
    window.tabs.setCurrentWidget(window.hazard_view)
    assert window.hazard_view.path is None
    assert "no hazard files" in window.hazard_view.header.text()
    assert not window.hazard_view.export_button.isEnabled()
    errors = []
    window.show_error = lambda title, text: errors.append(text)
    assert window.export_report_dialog() is None
    assert "has no hazard files" in errors[0]


def test_export_report_writes_the_html_report_and_opens_it(window, make_results, monkeypatch):
    # in a whole-suite process the solver tests' modules (collected first) have loaded Taichi
    # already; the fresh-interpreter check is tests/unit/test_architecture.py's
    taichi_before = "taichi" in sys.modules
    path = make_results()
    write_hazard(path)
    window.open_results(path)
    opened = []
    monkeypatch.setattr(window.hazard_view, "open_report", lambda html: opened.append(html) or True)
    html = window.export_report_dialog()
    assert html == path / "report" / "report.html" and html.is_file()
    assert opened == [html]
    text = html.read_text()
    assert ">Measures<" in text and "road" in text and "house" in text and "travel angle" in text
    assert 'src="data:image/png;base64,' in text
    assert taichi_before or "taichi" not in sys.modules  # the report is written without Taichi


def test_a_report_no_browser_can_show_is_named_in_the_status_bar(window, make_results, monkeypatch):
    """Without a desktop launcher (Xvfb, a bare session) Qt cannot hand the report to a browser; the
    status bar says so and names the saved report."""
    path = make_results()
    write_hazard(path)
    window.open_results(path)
    monkeypatch.setattr(window.hazard_view, "open_report", lambda html: False)
    html = window.export_report_dialog()
    assert html is not None and html.is_file()
    message = window.statusBar().currentMessage()
    assert str(html) in message and "no web browser" in message


def _fos_summary(path: Path) -> dict:
    summary = json.loads((path / "summary.json").read_text())
    trials = [(1.2, "stable", 0.01), (1.6, "failed", 0.4), (1.4, "stable", 0.02), (1.5, "failed", 0.15),
              (1.45, "stable", 0.03)]
    summary["factor_of_safety"] = {
        "value": 1.475, "lower": 1.45, "upper": 1.5, "criterion": "displacement", "tolerance": 0.05,
        "message": "factor of safety 1.475 in [1.45, 1.5] after 5 trials", "monitor_point_m": [0.1, 0.1],
        "mechanism_frame": 2,
        "trials": [{"factor": f, "verdict": v, "criterion": "settled" if v == "stable" else "displacement",
                    "monitor_displacement_m": d} for f, v, d in trials],
    }
    summary["limit_equilibrium"] = {"method": "bishop-simplified", "factor_of_safety": 1.41,
                                    "circle": {"centre_m": [0.25, 0.3], "radius_m": 0.25},
                                    "fellenius_factor_of_safety": 1.33, "circles_tried": 500}
    (path / "summary.json").write_text(json.dumps(summary))
    return summary


def test_the_factor_of_safety_tab_shows_factor_bracket_bishop_knee_and_mechanism(window, make_results):
    path = make_results()
    _fos_summary(path)
    assert window.open_results(path)
    index = window.tabs.indexOf(window.fos_view)
    assert window.tabs.isTabVisible(index)
    text = window.fos_view.label.text()
    assert "Factor of safety (strength reduction): 1.475" in text
    assert "bracket [1.45, 1.5]" in text and "displacement criterion" in text and "5 trials" in text
    assert "Bishop's simplified method: <b>1.410</b>" in text and "Fellenius 1.33" in text
    mech, knee, _colour_bar = window.fos_view.figure.axes
    assert "mechanism at F = 1.500 (frame 2)" == mech.get_title()
    # the critical circle's lower arc, and the mechanism frame's particles coloured by plastic strain
    arc = next(line for line in mech.lines if line.get_linestyle() == "--")
    xy = np.column_stack([arc.get_xdata(), arc.get_ydata()])
    assert np.allclose(np.hypot(xy[:, 0] - 0.25, xy[:, 1] - 0.3), 0.25)
    assert len(mech.collections[0].get_offsets()) == int(window.results_view.results.frame(2)["active"].sum())
    # the knee: trials sorted by factor, stable and failed apart
    stable = next(line for line in knee.lines if line.get_label() == "stable")
    failed = next(line for line in knee.lines if line.get_label() == "failed")
    assert list(stable.get_xdata()) == [1.2, 1.4, 1.45] and list(failed.get_xdata()) == [1.5, 1.6]
    # a results folder without a factor hides the tab again
    assert window.open_results(make_results("plain.results"))
    assert not window.tabs.isTabVisible(index)


# -- sweeps -----------------------------------------------------------------------------------------


@pytest.fixture
def tiny_doc(qtbot, tiny_file):
    """The tiny example open in a project document (the dialog needs no main window)."""
    from app.gui.document import ProjectDocument

    doc = ProjectDocument()
    doc.open(tiny_file)
    return doc


def _dialog(qtbot, doc, folder):
    from app.gui.sweep_dialog import SweepDialog

    dialog = SweepDialog(doc, folder)
    qtbot.addWidget(dialog)
    return dialog


def test_numeric_keys_are_the_project_scalars_by_dotted_key(tiny_doc):
    from app.gui.sweep_dialog import numeric_keys

    keys = numeric_keys(tiny_doc.data)
    assert keys["materials.sand.friction_angle_deg"] == 30.0
    assert keys["domain.boundaries.bottom.friction_angle_deg"] == 30.0
    assert keys["stages.1.duration_s"] == 0.05
    assert not any("polygon_m" in k for k in keys)


def test_the_sweep_dialog_writes_a_valid_sweep_file(qtbot, tiny_doc, tmp_path):
    from app.gui.sweep_dialog import BASE_PROJECT, SweepDialog
    from projects.document import load_project
    from sweeps.spec import SweepSpec, load_spec

    dialog = _dialog(qtbot, tiny_doc, tmp_path / "tiny.sweep")
    # a friction angle is offered first, ±10 % around its value
    assert dialog.params.cellWidget(0, 0).currentText().endswith("friction_angle_deg")
    dialog.params.cellWidget(0, 0).setCurrentText("materials.sand.friction_angle_deg")
    assert dialog.params.item(0, 2).text() == "27, 33"
    dialog.params.cellWidget(0, 1).setCurrentText("normal")
    dialog.params.item(0, 2).setText("30, 4, 20, 40")
    dialog.add_parameter("domain.boundaries.bottom.friction_angle_deg", "list", "20, 25, 30")
    dialog.params.item(1, 3).setText("")
    dialog.runs.setValue(6)
    dialog.seed.setValue(3)
    dialog.fixed.setText('numerics.arch="cpu"; stages.1.duration_s=0.02')
    dialog.accept()
    assert dialog.result() == SweepDialog.DialogCode.Accepted, dialog.error.text()
    spec = load_spec(dialog.spec_path)
    assert isinstance(spec, SweepSpec)
    assert dialog.spec_path == tmp_path / "tiny.sweep" / "sweep.toml" and dialog.out_dir == tmp_path / "tiny.sweep"
    p = spec.parameters["materials.sand.friction_angle_deg"]
    assert (p.distribution, p.mean, p.std, p.low, p.high) == ("normal", 30.0, 4.0, 20.0, 40.0)
    assert spec.parameters["domain.boundaries.bottom.friction_angle_deg"].values == [20.0, 25.0, 30.0]
    assert (spec.sweep.sampling, spec.sweep.runs, spec.sweep.seed) == ("latin-hypercube", 6, 3)
    assert spec.sweep.set == ['numerics.arch="cpu"', "stages.1.duration_s=0.02"]
    assert "hazard.runout_distance_m" in spec.sweep.measures
    assert spec.profile is not None and spec.profile.field == "peak_flow_height_m"
    # the base project is the open project, beside the file
    assert spec.project_path == (tmp_path / "tiny.sweep" / BASE_PROJECT).resolve()
    assert load_project(spec.project_path).materials["sand"].friction_angle_deg == 30.0


@pytest.mark.parametrize("distribution, values, message", [
    ("uniform", "10", "needs low, high"),
    ("range", "1, 2, x", "'x' is not a number"),
    ("uniform", "35, 25", "low must be < high"),
])
def test_the_sweep_dialog_refuses_bad_values_with_one_line(qtbot, tiny_doc, tmp_path, distribution, values,
                                                           message):
    from app.gui.sweep_dialog import SweepDialog

    dialog = _dialog(qtbot, tiny_doc, tmp_path / "bad.sweep")
    dialog.params.cellWidget(0, 1).setCurrentText(distribution)
    dialog.params.item(0, 2).setText(values)
    dialog.accept()
    assert dialog.result() != SweepDialog.DialogCode.Accepted
    assert message in dialog.error.text() and "friction_angle_deg" in dialog.error.text()
    assert "Traceback" not in dialog.error.text()
    assert not (tmp_path / "bad.sweep" / "sweep.toml").exists()


def test_the_sweep_dialog_writes_a_calibration(qtbot, tiny_doc, tmp_path):
    from app.gui.sweep_dialog import SweepDialog
    from sweeps.spec import CalibrationSpec, load_spec

    observed = tmp_path / "surface.csv"
    observed.write_text("x_m,y_m\n0.0,0.1\n0.2,0.05\n0.3,0.0\n")
    dialog = _dialog(qtbot, tiny_doc, tmp_path / "tiny.sweep")
    dialog.kind.setCurrentText("calibration")
    dialog.obs_file.setText(str(observed))
    dialog.x_range.setText("0, 0.3")
    dialog.trials.setValue(5)
    dialog.accept()
    assert dialog.result() == SweepDialog.DialogCode.Accepted, dialog.error.text()
    assert dialog.out_dir.name == "tiny.calibration"
    spec = load_spec(dialog.spec_path)
    assert isinstance(spec, CalibrationSpec)
    assert spec.calibration.trials == 5 and spec.observation.type == "deposit-profile"
    assert spec.observation_path == observed.resolve() and spec.observation.x_range_m == [0.0, 0.3]


def write_sweep(folder: Path, distances: list[float], statuses: list[str]) -> None:
    """A sweep folder as ``runout sweep`` writes it: sweep.csv, sweep.json, progress.json and a
    profile per completed run (peak flow height 0.1 m up to x = distance, 0 beyond)."""
    runs = folder / "runs"
    runs.mkdir(parents=True)
    x = [round(0.05 * i, 6) for i in range(11)]
    measures = ["hazard.runout_distance_m"]
    with open(folder / "sweep.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["run", "run_id", "materials.sand.friction_angle_deg", *measures, "status", "message",
                    "wall_time_s", "results_dir"])
        for i, (d, s) in enumerate(zip(distances, statuses)):
            rid = f"r{i}"
            done = s == "completed"
            w.writerow([i, rid, 25 + i, repr(d) if done else "", s, "" if done else f"{s} on purpose",
                        "1.5" if s != "pending" else "", str(runs / rid)])
            if s != "pending":
                profile = {"x_m": x, "values": [0.1 if xx <= d else 0.0 for xx in x]} if done else None
                (runs / f"{rid}.json").write_text(json.dumps({
                    "run_id": rid, "status": s, "message": "", "wall_time_s": 1.5, "results_dir": str(runs / rid),
                    "measures": {"hazard.runout_distance_m": d} if done else {}, "profile": profile}))
    spec = {"kind": "sweep", "spec": {"sweep": {"measures": measures}, "profile": {
        "field": "peak_flow_height_m", "thresholds": [0.05]}}, "settings": {}, "runs": []}
    (folder / "sweep.json").write_text(json.dumps(spec))
    done = sum(s != "pending" for s in statuses)
    (folder / "progress.json").write_text(json.dumps({
        "done": done, "total": len(statuses), "failed": sum(s in ("failed", "error") for s in statuses),
        "reused": 0, "elapsed_s": 12.0, "eta_s": 4.0}))


def test_the_sweep_tab_lists_runs_and_draws_exceedance_and_probability_profile(window, tmp_path):
    folder = tmp_path / "s.sweep"
    write_sweep(folder, [0.1, 0.2, 0.3, 0.4, 0.0], ["completed", "completed", "completed", "failed", "pending"])
    assert window.open_sweep(folder)
    view = window.sweep_view
    assert window.tabs.currentWidget() is view
    assert view.table.rowCount() == 5
    assert _statuses(view) == ["completed", "completed", "completed", "failed", "pending"]
    assert (view.bar.value(), view.bar.maximum()) == (4, 5)
    assert "4 of 5 runs done, 1 not completed" in view.header.text()
    # exceedance over the three completed runs: P(d > 0.1) = 2/3, P(d > 0.2) = 1/3, P(d > 0.3) = 0
    ex = view.exceedance()
    assert ex.n == 3 and np.allclose(ex.x, [0.1, 0.2, 0.3]) and np.allclose(ex.p, [2 / 3, 1 / 3, 0.0])
    # P(peak flow height > 0.05 m) at x: the fraction of runs that reached x
    prof = view.probability_profile()
    assert prof.n == 3
    expected = [sum(xx <= d for d in (0.1, 0.2, 0.3)) / 3 for xx in prof.x_m]
    assert np.allclose(prof.p[0], expected)
    left, middle, right = view.figure.axes
    assert left.get_title() == "Exceedance curve" and "3 runs" in right.get_title()
    assert middle.get_title() == "Measure against parameter"
    # a run completes: the next poll shows it
    write_sweep(tmp_path / "s2.sweep", [0.1, 0.2, 0.3, 0.4, 0.5], ["completed"] * 5)
    for name in ("sweep.csv", "progress.json"):
        (folder / name).write_bytes((tmp_path / "s2.sweep" / name).read_bytes())
    (folder / "runs" / "r4.json").write_bytes((tmp_path / "s2.sweep" / "runs" / "r4.json").read_bytes())
    (folder / "runs" / "r3.json").write_bytes((tmp_path / "s2.sweep" / "runs" / "r3.json").read_bytes())
    assert view.refresh(force=True)
    assert view.exceedance().n == 5 and view.probability_profile().n == 5


def test_open_sweep_refuses_a_folder_that_is_not_a_sweep(window, tmp_path):
    errors = []
    window.show_error = lambda title, text: errors.append(text)
    assert not window.open_sweep(tmp_path)
    assert "is not a sweep or calibration folder" in errors[0]


def test_the_sweep_tab_shows_a_calibration_with_its_best_trial(window, tmp_path):
    folder = tmp_path / "c.calibration"
    folder.mkdir()
    trials = [(20.0, 0.004), (30.0, 0.009), (24.0, 0.002), (27.0, "")]
    with open(folder / "calibration.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["trial", "run_id", "materials.sand.friction_angle_deg", "misfit", "status", "message",
                    "wall_time_s", "results_dir"])
        for i, (phi, misfit) in enumerate(trials):
            w.writerow([i, f"c{i}", phi, misfit, "completed" if misfit != "" else "failed", "", 2.0, ""])
    (folder / "calibration.json").write_text(json.dumps({"kind": "calibration", "spec": {}}))
    assert window.open_sweep(folder)
    view = window.sweep_view
    assert view.kind == "calibration" and view.table.rowCount() == 4
    (ax,) = view.figure.axes
    best = next(line for line in ax.lines if line.get_marker() == "*")
    assert (list(best.get_xdata()), list(best.get_ydata())) == ([24.0], [0.002])
    assert ax.get_xlabel() == "materials.sand.friction_angle_deg"


#: Stands in for ``runout sweep``: writes a 3-run sweep folder, one run more each time the test
#: creates ``go-N``, like the real one rewrites sweep.csv and progress.json after every run.
FAKE_SWEEP = r"""
import csv, json, sys, time
from pathlib import Path
out, n = Path(sys.argv[1]), int(sys.argv[2])
(out / "runs").mkdir(parents=True, exist_ok=True)
(out / "sweep.json").write_text(json.dumps({"kind": "sweep", "spec": {"sweep": {"measures": ["hazard.runout_distance_m"]}}}))
def write(done):
    with open(out / "sweep.csv.tmp", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["run", "run_id", "p", "hazard.runout_distance_m", "status", "message", "wall_time_s", "results_dir"])
        for i in range(n):
            w.writerow([i, f"r{i}", i, 0.1 * (i + 1) if i < done else "", "completed" if i < done else "pending", "", 1.0, ""])
    (out / "sweep.csv.tmp").replace(out / "sweep.csv")
    (out / "progress.json").write_text(json.dumps({"done": done, "total": n, "failed": 0, "elapsed_s": done}))
for done in range(n + 1):
    write(done)
    while done < n and not (out / f"go-{done + 1}").exists():
        time.sleep(0.05)
"""


def _statuses(view) -> list[str]:
    header = [view.table.horizontalHeaderItem(c).text() for c in range(view.table.columnCount())]
    col = header.index("status")
    return [view.table.item(r, col).text() for r in range(view.table.rowCount())]


def _fake_sweep(monkeypatch):
    from app.gui.sweep_view import SweepView

    monkeypatch.setattr(SweepView, "command",
                        lambda self, spec, out, workers=None: [sys.executable, "-c", FAKE_SWEEP, str(out), "3"])


def test_a_sweep_process_is_followed_run_by_run_until_it_ends(window, tmp_path, monkeypatch, qtbot):
    _fake_sweep(monkeypatch)
    out = tmp_path / "f.sweep"
    assert window.start_sweep(tmp_path / "sweep.toml", out)
    view = window.sweep_view
    assert view.running and view.cancel_button.isEnabled()
    for done in range(4):
        qtbot.waitUntil(lambda d=done: view.bar.value() == d and view.table.rowCount() == 3, timeout=20_000)
        assert _statuses(view) == ["completed"] * done + ["pending"] * (3 - done)
        if done < 3:
            (out / f"go-{done + 1}").touch()
    qtbot.waitUntil(lambda: view.exit_code is not None, timeout=20_000)
    assert view.exit_code == 0 and not view.cancel_button.isEnabled()
    assert "[finished]   3 of 3 runs done" in view.header.text()
    assert view.exceedance().n == 3


def test_stop_sweep_ends_the_process_and_keeps_the_finished_runs(window, tmp_path, monkeypatch, qtbot):
    _fake_sweep(monkeypatch)
    out = tmp_path / "f.sweep"
    assert window.start_sweep(tmp_path / "sweep.toml", out)
    view = window.sweep_view
    (out / "go-1").touch()
    qtbot.waitUntil(lambda: view.bar.value() == 1, timeout=20_000)
    view.cancel()
    qtbot.waitUntil(lambda: view.exit_code is not None, timeout=20_000)
    assert not view.running
    assert _statuses(view) == ["completed", "pending", "pending"]
    assert "1 of 3 runs done" in view.header.text() and "[stopped]" in view.header.text()


def test_a_run_of_the_workbench_ends_with_its_hazard_tab_filled(window, tiny_file, qtbot):
    """End to end: a real run (a child process) with a line target; when it ends the Hazard tab
    shows its hazard.json, the same numbers `runout run` wrote."""
    from projects.hazard import read_hazard

    text = tiny_file.read_text() + '\n[[targets]]\nname = "gauge"\nx_m = 0.13\n'
    tiny_file.write_text(text)
    window.open_project(tiny_file, ask=False)
    window.tabs.setCurrentWidget(window.hazard_view)
    assert window.start_run()
    qtbot.waitUntil(lambda: not window.running, timeout=120_000)
    assert window.last_result.status == "completed", window.last_result.message
    doc = read_hazard(window.last_result.out_dir)
    view = window.hazard_view
    assert view.path == window.last_result.out_dir
    measures = {row[0]: row[1] for row in _cells(view.measures)}
    # the tiny column is still collapsing at its end: every measure is provisional (test_provisional.py)
    assert doc["still_moving"] is True
    assert measures["largest speed"] == f"{doc['max_speed_m_s']:.4g} m/s (provisional)"
    targets = _cells(view.targets)
    assert targets[0][0] == "gauge (line)" and targets[0][1] == "0.13"
    # the report built from the workbench names the project the user opened, not the temporary
    # copy the run was started from (it named /tmp/runout-run-.../tiny.toml)
    assert window.last_result.summary["project_file"] == str(tiny_file)
    html = view.export_report()
    provenance = html.read_text().split("Settings and provenance")[1]
    assert f"<td>project file</td><td>{tiny_file}</td>" in provenance and "runout-run-" not in provenance


def test_the_hazard_profile_draws_the_structures(window, make_results):
    # a wall on the section was only a step of the "surface at the end" line, read as deposit
    path = make_results()
    write_hazard(path)
    summary = json.loads((path / "summary.json").read_text(encoding="utf-8"))
    wall = [[0.5, 0.0], [0.54, 0.0], [0.54, 0.06], [0.5, 0.06]]
    summary["structures"] = [{"name": "wall", "polygon_m": wall}]
    (path / "summary.json").write_text(json.dumps(summary), encoding="utf-8")
    assert window.open_results(path)
    window.tabs.setCurrentWidget(window.hazard_view)
    ax = window.hazard_view.figure.axes[0]
    hatched = [p for p in ax.patches if p.get_hatch()]
    assert len(hatched) == 1 and np.allclose(hatched[0].get_xy()[:4], wall)
    assert "wall" in [t.get_text() for t in ax.texts]
    assert "structure" in [t.get_text() for legend in window.hazard_view.figure.legends for t in legend.get_texts()]


def test_the_mechanism_legend_hides_few_of_the_particles(window, make_results):
    path = make_results()
    _fos_summary(path)
    assert window.open_results(path)
    figure = window.fos_view.figure
    figure.canvas.draw()
    mech = figure.axes[0]
    box = mech.get_legend().get_window_extent()
    points = mech.transData.transform(mech.collections[0].get_offsets())
    hidden = np.mean((points[:, 0] >= box.x0) & (points[:, 0] <= box.x1) & (points[:, 1] >= box.y0)
                     & (points[:, 1] <= box.y1))
    assert hidden <= 0.05, hidden
