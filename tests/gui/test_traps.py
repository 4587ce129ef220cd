"""The workbench's traps of a first hour: units, unknown keys, what a preset runs,
profile imports, monitoring points, cross-sections, movie progress and Help."""

from __future__ import annotations

import numpy as np
import pytest
from PySide6.QtCore import QTimer

pytestmark = pytest.mark.gui


# -- values with units ------------------------------------------------------------------------

@pytest.mark.parametrize("text, unit, expected", [
    ("5 kPa", "Pa", 5e3), ("10 MPa", "Pa", 1e7), ("2.5e6", "Pa", 2.5e6), ("0,3 GPa", "Pa", 3e8),
    ("50 kN/m²", "Pa", 5e4), ("20 kN/m3", "kg/m³", 20e3 / 9.81), ("2.1 t/m³", "kg/m³", 2100.0),
    ("1 800", "kg/m³", 1800.0), ("25 cm", "m", 0.25), ("500 ms", "s", 0.5), ("30 deg", "°", 30.0),
    ("5kpa", "Pa", 5e3), ("-2000", "kg/m³", -2000.0),
])
def test_typed_units_become_si(text, unit, expected):
    from app.gui.units import parse_quantity

    value, error = parse_quantity(text, unit)
    assert error == ""
    assert value == pytest.approx(expected, rel=1e-12)


@pytest.mark.parametrize("text, unit, message", [
    ("5 furlongs", "m", "unknown unit 'furlongs'; use m, cm, mm or km"),
    ("5 kPa", "kg/m³", "unknown unit 'kPa'; use kg/m3"),
    ("5 m", "°", "unknown unit 'm'; use ° or deg"),
    ("abc", "Pa", "must be a number"), ("5 kPa", "–", "must be a number"),
])
def test_wrong_units_are_named(text, unit, message):
    from app.gui.units import parse_quantity

    value, error = parse_quantity(text, unit)
    assert value is None and error.startswith(message)


def test_material_fields_accept_units_and_store_si(window, tiny_file):
    window.open_project(tiny_file)
    window.materials_panel.select("sand")
    fields = window.materials_panel.fields
    fields["cohesion_pa"].set_text("5 kPa")
    fields["youngs_modulus_pa"].set_text("10 MPa")
    fields["density_kg_m3"].set_text("19.62 kN/m3")
    assert window.doc.get("materials.sand.cohesion_pa") == 5000.0
    assert window.doc.get("materials.sand.youngs_modulus_pa") == 1e7
    assert window.doc.get("materials.sand.density_kg_m3") == pytest.approx(2000.0)  # 19.62 kN/m³ over 9.81
    assert fields["cohesion_pa"].edit.text() == "5 kPa"  # shown again in the unit typed
    assert fields["density_kg_m3"].edit.text() == "19.62 kN/m3"  # a unit weight comes back as one
    assert fields["density_kg_m3"].edit.toolTip() == "stored as 2000 kg/m³"
    fields["cohesion_pa"].set_text("5 kPa")  # the same text again: no edit
    assert window.doc.get("materials.sand.cohesion_pa") == 5000.0
    fields["cohesion_pa"].set_text("6000")  # a plain number: the SI unit again
    assert fields["cohesion_pa"].edit.text() == "6000"
    fields["cohesion_pa"].set_text("5 kPa")
    fields["cohesion_pa"].set_text("5 kg")
    assert "unknown unit 'kg'" in fields["cohesion_pa"].error
    assert window.doc.get("materials.sand.cohesion_pa") == 5000.0


# -- unknown keys --------------------------------------------------------------------------------

def test_an_unknown_key_from_a_file_is_shown_and_can_be_removed(window, tiny_file):
    text = tiny_file.read_text()
    text = text.replace("cohesion_pa = 0.0", "cohesion_pa = 0.0\ncohesion_kpa = 5.0")
    text = text.replace("[output]", "[outptu]\ninterval_s = 0.01\n\n[output]")
    tiny_file.write_text(text)
    window.show_project_problems = lambda path, error, can_open: True  # "open anyway"
    assert window.open_project(tiny_file)
    assert sorted(window.doc.unknown_keys()) == ["materials.sand.cohesion_kpa", "outptu"]
    assert window.doc.project is None
    window.run_panel.update_estimate()
    assert window.run_panel.remove_unknown.isVisibleTo(window.run_panel)
    assert any("cohesion_kpa" in window.run_panel.problems.item(i).text()
               for i in range(window.run_panel.problems.count()))
    window.run_panel.remove_unknown.click()
    assert window.doc.unknown_keys() == [] and window.doc.project is not None
    window.run_panel.update_estimate()
    assert not window.run_panel.remove_unknown.isVisibleTo(window.run_panel)
    window.doc.undo_stack.undo()  # one undo step brings them back
    assert len(window.doc.unknown_keys()) == 2


# -- what will run ----------------------------------------------------------------------------------

def test_the_run_panel_shows_what_a_preset_runs(window, tiny_file):
    window.open_project(tiny_file)
    panel = window.run_panel
    panel.update_estimate()
    assert panel.cell.text() == "0.02 m, 2² per cell"
    assert panel.numerics.text() == "apic-affine, time step 0.0002 s, f32"
    assert panel.preset_note.text() == ""

    def standard(d):
        d["numerics"].pop("time_step_s", None)
        d["numerics"]["preset"] = "standard"

    window.doc.edit("preset", standard)
    panel.update_estimate()
    # the column is 0.24 m high; "standard" asks for 40 cells over the smallest body's height
    assert panel.cell.text().startswith("0.006 m")
    assert panel.numerics.text() == "apic-affine, CFL 0.4, f32"
    assert "Preset 'standard' overrides the panels" in panel.preset_note.text()
    assert "cell size 0.02 → 0.006 m" in panel.preset_note.text()
    assert panel.particles.text() == "3,200"  # 0.12 x 0.24 m at 2 x 2 per 6 mm cell, as seeded


# -- importing a slope profile -----------------------------------------------------------------------

def test_import_a_csv_profile_as_a_body(window, tmp_path):
    window.new_project()
    profile = tmp_path / "survey.csv"
    profile.write_text("x_m,y_m\n0,5\n4,5\n10,1\n16,1\n")
    assert window.import_body(profile, "soil", base_y_m=0.0)
    body = window.doc.get("bodies")[-1]
    assert body["name"] == "survey" and body["material"] == "soil"
    assert sorted(map(tuple, body["polygon_m"])) == sorted([(0.0, 5.0), (4.0, 5.0), (10.0, 1.0), (16.0, 1.0),
                                                            (16.0, 0.0), (0.0, 0.0)])
    assert window.doc.problems == []
    # the section stands on its supports: the domain fitted to it, its ends on the side walls, the
    # base under it; gravity loading under the sloping ground; a cell size chosen from the section
    assert window.doc.get("domain.origin_m") == [0.0, 0.0] and window.doc.get("domain.size_m")[0] == 16.0
    assert window.doc.get("stages")[0]["type"] == "gravity"
    cell = window.doc.get("domain.cell_size_m")
    assert cell != 0.25 and f"cell size 0.25 -> {cell:g} m" in window.statusBar().currentMessage()
    from projects.checks import project_warnings

    assert project_warnings(window.doc.project) == []
    window.doc.undo_stack.undo()  # one undo step takes it all back
    assert window.doc.get("domain.cell_size_m") == 0.25 and window.doc.get("stages")[0]["type"] == "k0"
    assert window.doc.get("bodies") == []
    # a file that cannot be read is refused with one line
    bad = tmp_path / "bad.csv"
    bad.write_text("x_m,y_m\n0,1\n2,oops\n")
    errors = []
    window.show_error = lambda title, text: errors.append((title, text))
    assert not window.import_body(bad, "soil")
    assert errors[0][0] == "Cannot import" and "line 3: non-numeric value" in errors[0][1]
    assert window.doc.get("bodies") == []


def test_import_a_dxf_polyline_with_its_ends_on_the_walls(window, tmp_path):
    import ezdxf

    window.new_project()
    drawing = ezdxf.new()
    drawing.modelspace().add_lwpolyline([(0, 12), (8, 12), (20, 2), (30, 2)])
    drawing.modelspace().add_line((0, 0), (1, 1))  # clutter: the longest polyline is the profile
    path = tmp_path / "slope.dxf"
    drawing.saveas(path)
    assert window.import_body(path, "soil", base_y_m=-1.0)
    polygon = np.array(window.doc.get("bodies")[-1]["polygon_m"])
    assert polygon[:, 1].min() == -1.0 and polygon[:, 0].max() == 30.0
    origin, size = window.doc.get("domain.origin_m"), window.doc.get("domain.size_m")
    assert origin[1] == -1.0 and origin == [0.0, -1.0] and origin[1] + size[1] > 12.0
    cell = window.doc.get("domain.cell_size_m")
    assert abs(origin[0] + round(size[0] / cell) * cell - polygon[:, 0].max()) < 1e-9  # the right end on the wall
    assert window.doc.problems == []


def test_import_a_dxf_of_layers_as_bodies_of_their_own_materials(window, tmp_path):
    import ezdxf

    window.new_project()
    drawing = ezdxf.new()
    for layer, points in (("fill", [(0, 12), (8, 12), (20, 2), (30, 2)]), ("rock", [(0, 5), (30, -1)])):
        drawing.layers.add(layer)
        drawing.modelspace().add_lwpolyline(points, dxfattribs={"layer": layer})
    path = tmp_path / "section.dxf"
    drawing.saveas(path)
    assert window.import_body(path, "soil", base_y_m=-2.0)
    bodies = window.doc.get("bodies")
    assert [(b["name"], b["material"]) for b in bodies] == [("fill", "fill"), ("rock", "rock")]
    assert set(window.doc.material_names) == {"soil", "fill", "rock"}
    assert window.doc.problems == []
    window.doc.undo_stack.undo()
    assert window.doc.get("bodies") == [] and window.doc.material_names == ["soil"]


# -- monitoring points and cross-sections ----------------------------------------------------------

def test_monitoring_points_and_a_cross_section(window, make_results):
    from projects.results import open_results

    folder = make_results()
    assert window.open_results(folder)
    view = window.results_view
    pid = view.add_monitor(0.2, 0.1)
    results = open_results(folder)
    start = results.frame(0)["positions"]
    assert pid == int(np.argmin(((start - [0.2, 0.1]) ** 2).sum(axis=1)))
    (label, times, disp, speed), = view.monitor_plot.histories
    _t, expected = results.particle_history(pid, "displacement")
    assert np.allclose(disp, np.hypot(expected[:, 0], expected[:, 1]))
    assert disp[-1] > 0 and len(times) == len(results)
    view.add_monitor(0.0, 0.0)
    assert len(view.monitor_plot.histories) == 2
    # the points stay for the next results opened, on their particles there
    assert window.open_results(make_results("other.results"))
    assert len(view.monitor_ids) == 2
    # a cross-section shows the field along the line
    view.set_field("displacement")
    view.show_frame(0)
    n0 = view.set_section(0.0, 0.0625, 0.2, 0.0625)
    assert n0 > 0
    assert np.allclose(view.profile_plot.values, 0.0)  # nothing has moved in the first frame
    view.show_frame(3)  # the profile follows the shown frame
    distance, values = view.profile_plot.distance, view.profile_plot.values
    assert np.all(np.diff(distance) >= 0) and distance.max() <= 0.2
    assert values[-1] > values[0] > 0  # the block shears to the right: more at the far end
    assert "section" in view.scene.plotter.actors


# -- movie export ------------------------------------------------------------------------------------

def test_movie_export_shows_progress_can_be_cancelled_and_goes_beside_the_results(window, make_results,
                                                                                     tmp_path):
    assert window.open_results(make_results(n_frames=4))
    out = window.export_animation(tmp_path / "movie.gif", 5.0, (160, 90))
    assert out is not None and out.stat().st_size > 0
    assert window.export_progress.value() in (4, -1)  # reached the end (a closed dialog resets to -1)
    QTimer.singleShot(0, lambda: window.export_progress.cancel())
    assert window.export_animation(tmp_path / "cancelled.gif", 5.0, (160, 90)) is None
    assert not (tmp_path / "cancelled.gif").exists()
    # exports default beside the results folder, never into it (a re-run may replace it)
    folder = window.results_view.results.path
    path = window._export_path(".png")
    assert path.parent == folder.parent and path.name.startswith("synthetic_displacement_")


# -- help ------------------------------------------------------------------------------------------------

def test_help_shows_the_version_and_opens_the_documentation(window, monkeypatch):
    from PySide6.QtGui import QDesktopServices

    from app.gui.main_window import documentation_url
    from projects.results import runout_version

    assert f"Runout {runout_version()}" in window.about_text()
    url = documentation_url()
    assert url.toString() in window.about_text()
    assert url.isLocalFile() and url.toLocalFile().endswith("docs/gui.md")
    opened = []
    monkeypatch.setattr(QDesktopServices, "openUrl", lambda u: opened.append(u) or True)
    window.actions_["docs"].trigger()
    assert opened == [url]


# -- saving what the fields show ----------------------------------------------------------------------

def _focused(window, qtbot, edit):
    """``edit`` on view, focused in the active window and its text selected (typing replaces it)."""
    window.panels.setCurrentWidget(window.materials_panel)
    window.activateWindow()
    qtbot.waitUntil(window.isActiveWindow, timeout=5000)
    edit.setFocus()
    qtbot.waitUntil(edit.hasFocus, timeout=5000)
    edit.selectAll()
    return edit


def test_ctrl_s_with_a_red_field_refuses_and_names_it(window, tiny_file, qtbot):
    from PySide6.QtCore import Qt

    window.open_project(tiny_file)
    window.materials_panel.select("sand")
    before = tiny_file.read_text()
    window.materials_panel.fields["friction_angle_deg"].set_text("31")  # a valid edit: the project is dirty
    edit = _focused(window, qtbot, window.materials_panel.fields["cohesion_pa"].edit)
    qtbot.keyClicks(edit, "5 kg")  # red, and still being typed
    errors = []
    window.show_error = lambda title, text: errors.append((title, text))
    qtbot.keyClick(edit, Qt.Key.Key_S, Qt.KeyboardModifier.ControlModifier)
    assert errors and errors[0][0] == "Cannot save"
    assert "Cohesion (materials.sand.cohesion_pa): unknown unit 'kg'" in errors[0][1]
    assert tiny_file.read_text() == before  # nothing written: not the old cohesion under a "Saved"
    assert not window.statusBar().currentMessage().startswith("Saved")
    assert window.doc.is_dirty


def test_ctrl_s_saves_what_a_field_holds_before_enter(window, tiny_file, qtbot):
    from PySide6.QtCore import Qt

    from projects.document import load_project

    window.open_project(tiny_file)
    window.materials_panel.select("sand")
    edit = _focused(window, qtbot, window.materials_panel.fields["cohesion_pa"].edit)
    qtbot.keyClicks(edit, "7 kPa")  # typed, no Enter, no focus change
    qtbot.keyClick(edit, Qt.Key.Key_S, Qt.KeyboardModifier.ControlModifier)
    assert window.statusBar().currentMessage().startswith("Saved")
    assert load_project(tiny_file).materials["sand"].cohesion_pa == 7000.0


def test_a_stage_change_takes_0_kpa_and_shows_a_density_as_a_unit_weight_too(window, tiny_file):
    window.open_project(tiny_file)
    stages = window.stages_panel
    stages.select(1)
    stages.change_material.setCurrentText("sand")
    stages.change_key.setCurrentIndex(stages.change_key.findData("cohesion_pa"))
    stages.change_value.setText("0 kPa")
    stages._set_change()
    assert window.doc.get("stages.1.material_changes.sand.cohesion_pa") == 0.0
    stages.change_key.setCurrentIndex(stages.change_key.findData("density_kg_m3"))
    stages.change_value.setText("20 kN/m3")
    stages._set_change()
    assert window.doc.get("stages.1.material_changes.sand.density_kg_m3") == pytest.approx(20e3 / 9.81)
    shown = [stages.changes.item(r, 2).text() for r in range(stages.changes.rowCount())]
    assert "0 Pa" in shown and "2038.735984 kg/m³ (unit weight 20 kN/m³)" in shown


# -- the strength-reduction stage ----------------------------------------------------------------

def test_the_strength_reduction_stage_has_its_settings(window, tmp_path):
    from tests.gui.conftest import EXAMPLES

    window.open_project(EXAMPLES / "slope_fos.toml")
    stages, doc = window.stages_panel, window.doc
    stages.select(1)
    assert stages.strength_box.isVisibleTo(stages)
    fields = (stages.trial_duration, stages.tolerance, stages.first_trial, stages.bracket_step,
              stages.max_trials, stages.failure_displacement, stages.failure_ke, stages.damping)
    assert all(f.isEnabled() for f in fields)
    assert not stages.stage_form.isRowVisible(stages.duration)  # not allowed here: hidden, not greyed
    assert stages.trial_duration.edit.text() == "2" and stages.first_trial.edit.text() == "limit-equilibrium"
    assert stages.first_trial.commit() is False and stages.first_trial.error == ""  # the word is kept
    stages.tolerance.set_text("0.02")
    stages.failure_displacement.set_text("5 cm")
    stages.max_trials.set_text("12")
    assert doc.get("stages.1.tolerance") == 0.02 and doc.get("stages.1.failure.displacement_m") == 0.05
    assert doc.get("stages.1.max_trials") == 12 and isinstance(doc.get("stages.1.max_trials"), int)
    assert doc.get("stages.1.failure.kinetic_energy_ratio") == 0.001  # the table's other key kept
    stages.max_trials.set_text("12.5")
    assert stages.max_trials.error == "must be an integer"
    stages.max_trials.set_text("1")
    assert "2" in stages.max_trials.error and doc.get("stages.1.max_trials") == 12
    stages.first_trial.set_text("1.4")
    assert doc.get("stages.1.first_trial") == 1.4
    stages.limit_equilibrium.setChecked(False)
    assert doc.get("stages.1.limit_equilibrium") is False
    assert doc.project is not None  # every value the panel wrote is one the schema takes
    stages.select(2)  # the run-out after it: the factor its strengths are reduced by
    assert not stages.strength_box.isVisibleTo(stages) and stages.strength_factor.isEnabled()
    stages.strength_factor.set_text("1.2")
    assert doc.get("stages.2.strength_factor") == 1.2 and doc.project is not None
    stages.select(0)
    assert not stages.strength_factor.isEnabled() and not stages.stage_form.isRowVisible(stages.strength_factor)


# -- a new wall stands on the ground --------------------------------------------------------------

def test_add_wall_stands_on_the_ground_not_in_the_soil(window, tiny_file):
    window.open_project(tiny_file)
    # soil over the base right of the column, 0.1 m deep, rising to 0.14 m at the right end
    window.doc.edit("soil", lambda d: d["bodies"].append(
        {"name": "soil", "material": "sand", "polygon_m": [[0.12, 0.0], [0.6, 0.0], [0.6, 0.14], [0.12, 0.1]]}))
    seeded = len(window.doc.seeded_run().particles.positions_m)
    index = window.structures_panel.add_structure()
    wall = np.array(window.doc.get(f"structures.{index}.polygon_m"))
    assert wall[:, 0].min() == pytest.approx(0.3) and wall[:, 0].max() == pytest.approx(0.34)
    ground = [0.1 + (x - 0.12) * 0.04 / 0.48 for x in (0.3, 0.34)]
    assert wall[0, 1] == pytest.approx(ground[0]) and wall[1, 1] == pytest.approx(ground[1])  # on the surface
    assert wall[:, 1].max() == pytest.approx(max(ground) + 0.075)  # a quarter of the domain high
    assert len(window.doc.seeded_run().particles.positions_m) == seeded  # it took no particle of the soil
    assert window.doc.problems == []
    window.doc.undo_stack.undo()
    window.doc.edit("no soil", lambda d: d["bodies"].pop())
    bare = np.array(window.doc.get(f"structures.{window.structures_panel.add_structure()}.polygon_m"))
    assert bare[0, 1] == 0.0 and bare[1, 1] == 0.0  # on the base where nothing lies


# -- targets: the form is the selected target's, the next one starts afresh ----------------------

def test_the_target_forms_follow_the_target_not_the_last_one(window, tiny_file):
    window.open_project(tiny_file)
    panel = window.targets_panel
    panel.new_kind.setCurrentText("point")
    panel.new_x.setText("0.3")
    panel.new_y.setText("0.01")
    panel._add_typed()
    assert window.doc.get("targets.0.point_m") == [0.3, 0.01]
    # the Add form does not keep the point's kind or its y for the next target
    assert panel.new_kind.currentText() == "vertical line" and not panel.new_y.isEnabled()
    assert panel.new_x.text() == "" and panel.new_y.text() == ""
    panel.new_x.setText("0.4")
    panel._add_typed()
    assert window.doc.get("targets.1") == {"name": "target-2", "x_m": 0.4}
    # the selected target's form shows its kind and only its row
    assert panel.kind.currentText() == "vertical line"
    assert panel.target_form.isRowVisible(panel.x) and not panel.target_form.isRowVisible(panel.point)
    window.doc.selection.select("targets", 0)
    assert panel.kind.currentText() == "point"
    assert panel.target_form.isRowVisible(panel.point) and not panel.target_form.isRowVisible(panel.x)
    # and turns a target into the other kind, as one undo step
    assert panel.set_kind("vertical line")
    assert window.doc.get("targets.0") == {"name": "target-1", "x_m": 0.3}
    assert panel.kind.currentText() == "vertical line" and panel.x.edit.text() == "0.3"
    window.doc.selection.select("targets", 1)
    assert panel.set_kind("point")
    assert window.doc.get("targets.1.point_m") == [0.4, 0.15]  # at mid-height: no body reaches x = 0.4
    window.doc.undo_stack.undo()
    assert window.doc.get("targets.1") == {"name": "target-2", "x_m": 0.4}


# -- export report says where it wrote -----------------------------------------------------------

def test_export_report_says_where_it_wrote_and_keeps_saying_it(window, make_results, monkeypatch):
    from tests.gui.test_analysis import write_hazard

    path = make_results()
    write_hazard(path)
    window.open_results(path)
    window.tabs.setCurrentWidget(window.results_view)  # exported from the Results tab (File menu)
    monkeypatch.setattr(window.hazard_view, "open_report", lambda html: True)  # a browser took it
    html = window.export_report_dialog()
    assert html == path / "report" / "report.html"
    label = window.hazard_view.report_label
    assert label.isVisibleTo(window.hazard_view) and str(html) in label.text()
    assert "open its folder" in label.text() and "opened in the web browser" in label.text()
    assert window.statusBar().currentMessage() == f"Hazard report written to {html}"
    window.open_results(make_results("other.results"))  # another folder: that report is not its own
    window.hazard_view.show_results(window.results_view.results.path, window.results_view.results)
    assert not label.isVisibleTo(window.hazard_view)


# -- the left panel at the window's default size -------------------------------------------------

def test_every_project_panel_fits_the_dock_at_the_default_window_size(window, qtbot):
    from app.gui.main_window import MainWindow
    from tests.gui.conftest import EXAMPLES

    window.resize(*MainWindow.DEFAULT_SIZE)
    qtbot.wait(50)
    cut = []
    for example in ("tiny_column", "debris_barrier", "slope_fos"):
        window.open_project(EXAMPLES / f"{example}.toml", ask=False)
        for stage in range(len(window.doc.get("stages"))):
            window.stages_panel.select(stage)
            for i in range(window.panels.count()):
                window.panels.setCurrentIndex(i)
                panel = window.panels.widget(i)
                need, have = panel.widget().minimumSizeHint().width(), panel.viewport().width()
                if need > have:
                    cut.append(f"{example}, stage {stage}, {window.panels.tabText(i)}: {need} px in {have}")
    assert cut == []


# -- a sweep of a few values: the measure against the parameter ---------------------------------

def test_a_three_value_sweep_plots_the_measure_against_the_parameter(window, tmp_path):
    from tests.gui.test_analysis import write_sweep

    folder = tmp_path / "three.sweep"
    write_sweep(folder, [0.3, 0.1, 0.2], ["completed"] * 3)  # friction 25, 26, 27 degrees
    assert window.open_sweep(folder)
    view = window.sweep_view
    assert view.parameter.currentText() == "materials.sand.friction_angle_deg"
    key, x, y = view.measure_against_parameter()
    assert key == "materials.sand.friction_angle_deg"
    assert np.allclose(x, [25, 26, 27]) and np.allclose(y, [0.3, 0.1, 0.2])
    middle = next(a for a in view.figure.axes if a.get_title() == "Measure against parameter")
    line = middle.get_lines()[0]
    assert np.allclose(line.get_xdata(), [25, 26, 27]) and np.allclose(line.get_ydata(), [0.3, 0.1, 0.2])
    assert middle.get_xlabel() == key and middle.get_ylabel() == "hazard.runout_distance_m"


# -- a killed run is resumed from the workbench -------------------------------------------------

def test_a_killed_run_is_resumed_from_the_workbench(window, tmp_path, qtbot):
    import os
    import signal

    from projects.results import open_results
    from tests.gui.conftest import _project_file

    project = _project_file(tmp_path, "resumed.toml", ["stages.1.duration_s=3.0", "output.interval_s=0.05"])
    window.open_project(project)
    errors = []
    window.show_error = lambda title, text: errors.append((title, text))
    assert not window.run_panel.resume_button.isEnabled()
    assert window.start_run()
    run = window.followed
    checkpoint = run.out_dir / "checkpoint.npz"
    qtbot.waitUntil(lambda: checkpoint.is_file() and window.results_view.results is not None
                    and len(window.results_view.results) >= 3, timeout=90_000)
    os.kill(run.pid, signal.SIGKILL)
    qtbot.waitUntil(lambda: not window.running, timeout=30_000)
    assert window.last_result.status == "killed"
    killed_frames = len(open_results(run.out_dir))
    # the killed run's folder is shown, and Resume is offered for it
    assert window.run_panel.resume_button.isEnabled() and window.actions_["resume"].isEnabled()
    window.run_panel.resume_button.click()
    resumed = window.followed
    assert resumed is not run and resumed.resume and resumed.out_dir == run.out_dir
    assert "--resume" in resumed.command()
    assert not window.run_panel.resume_button.isEnabled()  # not twice into one folder
    qtbot.waitUntil(lambda: not window.running, timeout=120_000)
    assert window.last_result.status == "completed", window.last_result.message
    assert resumed.started_event["first_frame"] > 0  # from the checkpoint, not from the start
    results = open_results(run.out_dir)
    assert results.status == "completed" and len(results) == 61 and len(results) > killed_frames
    assert results.times[-1] == pytest.approx(3.0, abs=1e-6)
    assert not window.run_panel.resume_button.isEnabled()  # complete: nothing to resume
    window.resume_run(run.out_dir)
    assert errors[-1][0] == "Cannot resume" and "complete: nothing to resume" in errors[-1][1]


# -- the pre-run estimate ----------------------------------------------------------------------------

def test_the_estimate_is_the_cost_of_a_step_at_this_size_and_the_projects_own_run(window, tmp_path):
    import json

    from projects.document import apply_overrides, load_project, save_project
    from projects.runner import default_results_dir
    from tests.gui.conftest import EXAMPLES

    path = tmp_path / "barrier.toml"
    save_project(apply_overrides(load_project(EXAMPLES / "debris_barrier.toml"), ["numerics.arch=cpu"]), path)
    window.open_project(path)
    panel = window.run_panel
    e = panel.update_estimate()
    # the shipped cost model: 0.22 ms + 0.061 us per particle + 0.82 ms for the structures a step
    step = 2.2e-4 + 6.1e-8 * 998 + 8.2e-4
    assert e["cost"]["step_time_s"] == pytest.approx(step)
    assert e["run_time_s"] == pytest.approx(5.0 + 5251 * step)  # not 3 s + N x steps / 3e6 = 4.7 s
    assert panel.runtime.text() == "at most 11 s on cpu"  # the run stops when the debris is at rest
    assert "development machine's measurements" in panel.rate_info.text()
    assert "µs per particle-step at this size" in panel.rate_info.text()
    # a run of this project measured 4.5 ms a step: the next estimate is that run's own cost
    folder = default_results_dir(path)
    folder.mkdir()
    (folder / "summary.json").write_text(json.dumps({"arch": "cpu", "particles": 998, "step_time_s": 4.5e-3,
                                                     "startup_s": 6.0, "structures": [{"name": "dam"}]}))
    e = panel.update_estimate()
    assert e["run_time_s"] == pytest.approx(6.0 + 5251 * 4.5e-3)
    assert panel.runtime.text() == "at most 30 s on cpu"
    assert "measured by this project's run (998 particles, 4.5 ms a step)" in panel.rate_info.text()


# -- particles of a spread mass, smoothed stress, the results query ------------------------------

def _stretched_results(tmp_path, stretch: float = 1.4):
    """A block of 40 x 20 particles (5 mm apart) whose second frame is drawn apart along x by
    ``stretch`` (the columns of a flowing mass parting), with a cell-scale checkerboard on its
    vertical stress (+-3 kPa from cell to cell of 1 cm)."""
    from projects.results import ResultsWriter
    from solver.config import Diagnostics, Frame
    from tests.conftest import SYNTHETIC_META, SYNTHETIC_PROJECT

    x, y = np.meshgrid((np.arange(40) + 0.5) * 0.005, (np.arange(20) + 0.5) * 0.005)
    p0 = np.column_stack([x.ravel(), y.ravel()])
    writer = ResultsWriter(tmp_path / "stretched.results", SYNTHETIC_PROJECT, dict(SYNTHETIC_META))
    for i, s in enumerate((1.0, stretch)):
        pos = p0 * [s, 1.0]
        cell = (np.floor(pos[:, 0] / 0.01) + np.floor(pos[:, 1] / 0.01)) % 2
        syy = -10_000.0 + np.where(cell == 0, 3000.0, -3000.0)
        stress = np.column_stack([0.5 * syy, syy, np.zeros(len(p0)), 0.5 * syy])
        diag = Diagnostics(time_s=0.1 * i, stage="run", stage_index=0, stage_time_s=0.1 * i, step=10 * i, dt_s=1e-3,
                           kinetic_energy_J_per_m=0.0, momentum_x=0.0, momentum_y=0.0, max_speed_m_s=0.0,
                           unstable_particles=0, lost_particles=0, total_mass_kg_per_m=1.0, yielding_particles=0)
        writer.write_frame(Frame(diag, {"positions": pos, "active": np.ones(len(p0), bool), "displacement": pos - p0,
                                        "velocity": np.zeros_like(p0), "stress": stress,
                                        "plastic_strain": np.zeros(len(p0)), "material_id": np.zeros(len(p0), np.int32)}))
    writer.close("completed", "")
    return tmp_path / "stretched.results"


def test_particles_of_a_spread_mass_are_drawn_without_gaps(window, tmp_path):
    import math

    assert window.open_results(_stretched_results(tmp_path))
    view, scene = window.results_view, window.results_view.scene
    view.show_frame(0)
    pixels_per_m = scene.plotter.height() / (2.0 * scene.plotter.camera.parallel_scale)
    assert scene.actor.prop.point_size == max(2.0, math.ceil(0.005 * pixels_per_m))
    view.show_frame(1)  # the columns 7 mm apart: squares of 7 mm, not 5 mm with 2 mm gaps between
    assert scene.shown_spacing_m == pytest.approx(0.007)
    assert scene.actor.prop.point_size >= 0.007 * pixels_per_m


def test_the_stress_may_be_shown_smoothed_over_the_cells(window, tmp_path):
    assert window.open_results(_stretched_results(tmp_path, stretch=1.0))
    view = window.results_view
    view.set_field("stress_yy")
    view.show_frame(1)
    inside = (view.scene.positions[:, 0] > 0.03) & (view.scene.positions[:, 0] < 0.17) & \
        (view.scene.positions[:, 1] > 0.02) & (view.scene.positions[:, 1] < 0.08)
    assert np.ptp(view.scene.values[inside]) == pytest.approx(6.0)  # the checkerboard, +-3 kPa
    assert view.controls.smooth.isEnabled()
    view.controls.smooth.setChecked(True)
    assert np.allclose(view.scene.values[inside], -10.0)  # its local mean
    view.set_field("displacement")
    assert not view.controls.smooth.isEnabled()  # only stresses and pore pressure are smoothed


def test_the_results_view_answers_a_query_at_a_point_and_exports_a_section(window, tmp_path):
    assert window.open_results(_stretched_results(tmp_path, stretch=1.0))
    view = window.results_view
    view.set_field("stress_yy")
    view.show_frame(0)
    value = view.query_at(0.1, 0.05)
    assert value.value == pytest.approx(-10.0) and value.particles == 4  # two +3 and two -3 kPa around it
    assert view.query_label.text().startswith("Stress yy at (0.1, 0.05), frame 1/2 (t = 0 s): -10 kPa")
    view.set_field("displacement")  # the answer follows the field and the frame
    assert view.query_label.text().startswith("Displacement at (0.1, 0.05), frame 1/2")
    assert view.query_at(0.5, 0.05).particles == 0 and "no material" in view.query_label.text()
    view.set_section(0.0, 0.05, 0.2, 0.05)
    out = view.export_section(tmp_path / "section.csv")
    lines = out.read_text().splitlines()
    assert lines[0] == "distance_m,x_m,y_m,displacement_m,particles,nearest_particle" and len(lines) == 82


# -- structures read as numbers ------------------------------------------------------------------------

def test_each_structures_peak_force_is_a_number_in_the_list_and_a_table(window, tmp_path):
    from tests.gui.conftest import EXAMPLES
    from tests.unit.test_structure_answers import _write_dam_run

    window.open_project(EXAMPLES / "debris_barrier.toml")
    _write_dam_run(tmp_path / "dam.results")
    assert window.open_results(tmp_path / "dam.results")
    view = window.results_view
    table = view.forces_table
    cells = [[table.item(r, c).text() for c in range(table.columnCount())] for r in range(table.rowCount())]
    assert cells[0] == ["check-dam", "104", "103", "-4", "1", "100", "1", "-5", "1.5"]
    assert cells[1][0] == "bottom (side)" and cells[1][1] == "2900" and cells[1][2] == "2900"
    # the Structures list: the dam's peak under its name (the bedrock, which carried nothing here, bare)
    panel = window.structures_panel
    texts = [panel.list.item(i).text() for i in range(panel.list.count())]
    dam = next(t for t in texts if t.startswith("check-dam"))
    assert [line.strip() for line in dam.splitlines()[1:]] == ["peak 104 kN/m (N 103, T -4) at 1 s",
                                                              "mean N up to 100 kN/m at 1 s"]
    assert next(t for t in texts if t.startswith("bedrock")).count("\n") == 0


def test_the_mechanism_pictures_draw_the_structures(window, make_results, tmp_path):
    import json

    from matplotlib.patches import Polygon

    from app.render import render_mechanism
    from tests.gui.test_analysis import _fos_summary

    path = make_results()
    _fos_summary(path)
    summary = json.loads((path / "summary.json").read_text())
    wall = [[0.3, 0.0], [0.34, 0.0], [0.34, 0.08], [0.3, 0.08]]  # beyond the block (0 to 0.2 m)
    summary["structures"] = [{"name": "wall", "polygon_m": wall}]
    (path / "summary.json").write_text(json.dumps(summary))
    assert window.open_results(path)
    mech = window.fos_view.figure.axes[0]
    patches = [p for p in mech.patches if isinstance(p, Polygon)]
    assert len(patches) == 1 and np.allclose(patches[0].get_xy()[:4], wall)
    assert mech.get_xlim()[1] > 0.34  # the view holds the wall too
    assert any(t.get_text() == "wall" for t in mech.texts)
    # and the picture of runout render --mechanism
    import matplotlib.figure

    drawn = []
    keep = matplotlib.figure.Figure.savefig
    matplotlib.figure.Figure.savefig = lambda self, *a, **k: (drawn.append(self), keep(self, *a, **k))[1]
    try:
        render_mechanism(path, tmp_path / "mechanism.png", size=(900, 400))
    finally:
        matplotlib.figure.Figure.savefig = keep
    assert any(isinstance(p, Polygon) for p in drawn[0].axes[0].patches)


# -- a sweep measure key without its prefix -------------------------------------------------------------

def test_the_sweep_dialog_refuses_a_measure_without_its_prefix(qtbot, tmp_path, tiny_file):
    from app.gui.document import ProjectDocument
    from app.gui.sweep_dialog import SweepDialog

    doc = ProjectDocument()
    doc.open(tiny_file)
    dialog = SweepDialog(doc, tmp_path / "bad.sweep")
    qtbot.addWidget(dialog)
    dialog.more_measures.setText("runout_distance_m")  # hazard.runout_distance_m meant
    dialog.accept()
    assert dialog.result() != SweepDialog.DialogCode.Accepted
    assert "runout_distance_m" in dialog.error.text() and '"hazard."' in dialog.error.text()
    assert "Traceback" not in dialog.error.text()
    assert not (tmp_path / "bad.sweep" / "sweep.toml").exists()
