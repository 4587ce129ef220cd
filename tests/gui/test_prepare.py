"""Preparing a project in the workbench: open, edit with undo, draw, validate, save, reopen."""

from __future__ import annotations

import json

import numpy as np
import pytest
from PySide6.QtCore import QPoint, Qt

from projects.document import load_project

pytestmark = pytest.mark.gui


def _click(qtbot, scene, xy, button=Qt.MouseButton.LeftButton):
    pos = scene.world_to_widget(xy).toPoint()
    qtbot.mouseClick(scene.plotter, button, pos=pos)


def test_open_example_shows_its_model(window, tiny_file):
    assert window.open_project(tiny_file)
    doc = window.doc
    assert doc.project is not None and not doc.problems
    assert not doc.is_dirty
    assert window.windowTitle().startswith("tiny.toml")
    assert not window.isWindowModified()
    # panels show the file's values with units
    assert window.domain_panel.cell.edit.text() == "0.02"
    assert window.domain_panel.cell.unit.text() == "m"
    assert window.domain_panel.side_types["bottom"].currentText() == "friction"
    assert window.domain_panel.side_angles["bottom"].edit.text() == "30"
    assert window.materials_panel.list.count() == 1
    assert window.materials_panel.fields["friction_angle_deg"].unit.text() == "°"
    # the view has the grid, the four sides, the body and the seeded particles (288 in the example)
    actors = window.scene.plotter.actors
    for name in ("grid", "side-left", "side-bottom", "fills", "outlines"):
        assert name in actors, name
    qtbot_wait_until(lambda: window.scene.preview_count == 288)
    # what will run: the particles the run seeds, counted by seeding them (as the preview does)
    window.run_panel.update_estimate()
    assert window.run_panel.particles.text() == "288"
    assert window.run_panel.grid.text().startswith("30 × 15")
    assert "250" in window.run_panel.steps.text()
    assert "s on cpu" in window.run_panel.runtime.text()


def qtbot_wait_until(condition, timeout_s=3.0):
    import time

    from PySide6.QtWidgets import QApplication

    end = time.monotonic() + timeout_s
    while not condition():
        assert time.monotonic() < end, "condition not met in time"
        QApplication.processEvents()
        time.sleep(0.01)


@pytest.mark.parametrize(("example", "seeded"), [("debris_barrier.toml", 998), ("slope_sun_song_2015.toml", 39_143)])
def test_the_run_panel_counts_the_particles_the_run_seeds(window, example, seeded):
    """The Run panel said "about 897" for debris_barrier.toml, whose run seeds 998 (the area times
    the particles per cell, while the lattice also seeds the parts of the sub-cells the tilted
    outline cuts); it now counts the seeding the run gets (projects.build.resolve)."""
    from projects.build import resolve

    from tests.gui.conftest import EXAMPLES

    path = EXAMPLES / example
    assert len(resolve(load_project(path)).particles) == seeded  # what `runout run` seeds
    window.open_project(path, ask=False)
    panel = window.run_panel
    panel.update_estimate()
    assert panel.particles.text() == f"{seeded:,}"
    # one seeding per edit, shared with the particle preview
    qtbot_wait_until(lambda: window.scene.preview_count == seeded, timeout_s=10.0)
    assert window.doc.seeded_run() is window.doc.seeded_run()


def test_the_run_panel_estimates_particles_it_would_take_long_to_seed(window, monkeypatch):
    import app.gui.run_panel as run_panel

    from tests.gui.conftest import EXAMPLES

    window.open_project(EXAMPLES / "debris_barrier.toml", ask=False)
    monkeypatch.setattr(run_panel, "MAX_SEEDED_PARTICLES", 500)
    window.run_panel.update_estimate()
    assert window.run_panel.particles.text() == "about 897"  # the bodies' area times the density


def test_edit_a_material_and_undo_it(window, tiny_file):
    window.open_project(tiny_file)
    field = window.materials_panel.fields["friction_angle_deg"]
    field.set_text("25")
    assert window.doc.get("materials.sand.friction_angle_deg") == 25.0
    assert window.doc.project.materials["sand"].friction_angle_deg == 25.0
    assert window.doc.is_dirty and window.isWindowModified()
    assert window.doc.undo_stack.undoText() == "change friction angle"
    window.actions_["undo"].trigger()
    assert window.doc.get("materials.sand.friction_angle_deg") == 30.0
    assert field.edit.text() == "30"
    assert not window.doc.is_dirty and not window.isWindowModified()
    window.actions_["redo"].trigger()
    assert window.doc.get("materials.sand.friction_angle_deg") == 25.0


def test_choose_the_mohr_coulomb_match_and_undo_it(window, tiny_file):
    window.open_project(tiny_file)
    panel = window.materials_panel
    assert panel.match.isEnabled() and panel.match.combo.currentText() == "plane-strain-associated"  # the default
    panel.match.choose("simple-shear")
    assert window.doc.get("materials.sand.mohr_coulomb_match") == "simple-shear"
    assert window.doc.project.materials["sand"].mohr_coulomb_match == "simple-shear"
    window.actions_["undo"].trigger()
    assert window.doc.get("materials.sand.mohr_coulomb_match") is None
    assert panel.match.combo.currentText() == "plane-strain-associated"
    panel.match.choose("plane-strain")
    panel.set_model("linear-elastic")  # no cone: the key goes and the field is disabled
    assert window.doc.get("materials.sand.mohr_coulomb_match") is None
    assert not panel.match.isEnabled()


def test_values_are_checked_as_you_type(window, tiny_file, qtbot):
    window.open_project(tiny_file)
    window.panels.setCurrentWidget(window.materials_panel)
    field = window.materials_panel.fields["poisson_ratio"]
    field.edit.setFocus()
    field.edit.selectAll()
    qtbot.keyClicks(field.edit, "0.6")
    # the schema's own message, shown while typing, before anything is committed
    assert field.error == "must be >= 0 and < 0.5"
    assert "must be >= 0 and < 0.5" in window.materials_panel.message.text()
    assert "fde2e1" in field.edit.styleSheet()
    qtbot.keyClick(field.edit, Qt.Key.Key_Return)
    assert window.doc.get("materials.sand.poisson_ratio") == 0.3
    assert window.doc.undo_stack.count() == 0
    field.edit.selectAll()
    qtbot.keyClicks(field.edit, "abc")
    assert field.error == "must be a number"
    field.edit.selectAll()
    qtbot.keyClicks(field.edit, "0.25")
    qtbot.keyClick(field.edit, Qt.Key.Key_Return)
    assert field.error == ""
    assert window.doc.get("materials.sand.poisson_ratio") == 0.25


def test_ctrl_z_in_a_field_undoes_its_typing_then_the_project(window, tiny_file, qtbot):
    """Ctrl+Z with the keyboard in a text field undoes the typing not yet committed to the
    project (Qt's own undo of the field) and nothing else; once the field holds what the project
    holds (Enter committed it), Ctrl+Z undoes the project's last step. Before, the field kept its
    committed typing in its own history: Ctrl+Z after Enter put the old text back in the field while
    the project kept the new value, and leaving the field committed it again as a new step."""
    window.open_project(tiny_file)
    doc = window.doc
    window.panels.setCurrentWidget(window.materials_panel)
    window.activateWindow()
    qtbot.waitUntil(window.isActiveWindow)
    ctrl = Qt.KeyboardModifier.ControlModifier
    friction = window.materials_panel.fields["friction_angle_deg"]
    friction.set_text("25")  # one project step before the typing
    field = window.materials_panel.fields["cohesion_pa"]
    field.edit.setFocus()
    qtbot.waitUntil(field.edit.hasFocus)
    field.edit.selectAll()
    qtbot.keyClicks(field.edit, "123")
    qtbot.keyClick(field.edit, Qt.Key.Key_Z, ctrl)
    assert field.edit.text() == "0" and field.error == ""  # the typing undone, the field checked again
    assert doc.undo_stack.index() == 1 and doc.get("materials.sand.friction_angle_deg") == 25.0
    qtbot.keyClick(field.edit, Qt.Key.Key_Z, ctrl | Qt.KeyboardModifier.ShiftModifier)  # the typing redone
    assert field.edit.text() == "123" and doc.undo_stack.index() == 1
    # committed with Enter: the typing is the project's step now, undone and redone as one
    qtbot.keyClick(field.edit, Qt.Key.Key_Return)
    assert doc.get("materials.sand.cohesion_pa") == 123.0 and doc.undo_stack.index() == 2
    qtbot.keyClick(field.edit, Qt.Key.Key_Z, ctrl)
    assert doc.get("materials.sand.cohesion_pa") == 0.0 and field.edit.text() == "0"
    assert doc.undo_stack.index() == 1 and field.edit.hasFocus()
    qtbot.keyClick(field.edit, Qt.Key.Key_Z, ctrl | Qt.KeyboardModifier.ShiftModifier)
    assert doc.get("materials.sand.cohesion_pa") == 123.0 and field.edit.text() == "123"
    qtbot.keyClick(field.edit, Qt.Key.Key_Z, ctrl)
    window.scene.setFocus()  # leaving the field adds no step
    assert doc.undo_stack.index() == 1 and doc.undo_stack.count() == 2
    assert doc.get("materials.sand.cohesion_pa") == 0.0
    # outside text fields Ctrl+Z undoes the project's step
    qtbot.keyClick(window.scene, Qt.Key.Key_Z, ctrl)
    assert doc.get("materials.sand.friction_angle_deg") == 30.0 and doc.undo_stack.index() == 0
    # a red (refused) value is typing of the field: Ctrl+Z there takes it back, the project untouched
    field = window.materials_panel.fields["poisson_ratio"]
    field.edit.setFocus()
    qtbot.waitUntil(field.edit.hasFocus)
    field.edit.selectAll()
    qtbot.keyClicks(field.edit, "0.6")
    qtbot.keyClick(field.edit, Qt.Key.Key_Return)
    assert field.error and doc.undo_stack.index() == 0
    qtbot.keyClick(field.edit, Qt.Key.Key_Z, ctrl)
    assert field.edit.text() == "0.3" and field.error == "" and doc.undo_stack.index() == 0
    assert doc.undo_stack.canRedo()  # the project's history is as it was


def test_problems_involving_several_keys_are_flagged(window, tiny_file):
    window.open_project(tiny_file)
    window.materials_panel.fields["dilatancy_angle_deg"].set_text("40")
    assert window.doc.project is None
    assert [p.path for p in window.doc.problems] == ["materials.sand.dilatancy_angle_deg"]
    window.run_panel.update_estimate()
    assert window.run_panel.problems.count() == 1
    assert "must not exceed friction_angle_deg (30)" in window.run_panel.problems.item(0).text()
    assert "fff1d6" in window.materials_panel.fields["dilatancy_angle_deg"].edit.styleSheet()
    errors = []
    window.show_error = lambda title, text: errors.append(text)
    assert not window.start_run()
    assert "dilatancy_angle_deg" in errors[0]


def test_draw_a_polygon_with_the_mouse(window, qtbot):
    scene = window.scene
    window.doc.reset(_empty_project())
    window.actions_["draw"].trigger()
    assert scene.mode == "draw"
    corners = [(2.0, 1.0), (8.0, 1.0), (8.0, 4.0), (2.0, 4.0)]
    for xy in corners:
        # a click a little off the grid point lands on it (snap to half cells of 0.25 m)
        _click(qtbot, scene, (xy[0] + 0.04, xy[1] - 0.03))
    assert np.allclose(scene.draft, corners)
    _click(qtbot, scene, corners[0])  # clicking the first vertex closes the polygon
    bodies = window.doc.get("bodies")
    assert len(bodies) == 1
    assert np.allclose(bodies[0]["polygon_m"], corners)
    assert bodies[0]["material"] == "soil"
    assert scene.mode == "select" and window.actions_["select"].isChecked()
    assert window.doc.project is not None  # the new project is now complete
    # the vertex table beside the view shows the same vertices
    table = window.bodies_panel.table
    assert table.rowCount() == 4
    assert [float(table.item(2, c).text()) for c in range(2)] == [8.0, 4.0]
    assert window.doc.selection.body == 0
    window.doc.undo_stack.undo()
    assert window.doc.get("bodies") == []


def test_drag_a_vertex_is_one_undo_step_and_the_table_follows(window, tiny_file, qtbot):
    window.open_project(tiny_file)
    scene = window.scene
    start = scene.world_to_widget((0.12, 0.24)).toPoint()
    qtbot.mousePress(scene.plotter, Qt.MouseButton.LeftButton, pos=start)
    assert window.doc.selection.body == 0 and window.doc.selection.vertex == 2
    for x, y in ((0.13, 0.23), (0.15, 0.21), (0.16, 0.20)):
        qtbot.mouseMove(scene.plotter, scene.world_to_widget((x, y)).toPoint())
    qtbot.mouseRelease(scene.plotter, Qt.MouseButton.LeftButton, pos=scene.world_to_widget((0.16, 0.20)).toPoint())
    # snapped to half cells (0.01 m)
    assert window.doc.get("bodies.0.polygon_m.2") == [0.16, 0.2]
    assert window.doc.undo_stack.count() == 1
    table = window.bodies_panel.table
    assert (table.item(2, 0).text(), table.item(2, 1).text()) == ("0.16", "0.2")
    # typing a coordinate in the table moves the vertex in the model (and the view)
    table.item(2, 1).setText("0.22")
    assert window.doc.get("bodies.0.polygon_m.2") == [0.16, 0.22]
    window.doc.undo_stack.undo()
    window.doc.undo_stack.undo()
    assert window.doc.get("bodies.0.polygon_m.2") == [0.12, 0.24]
    # a slow drag, a pixel at a time, follows the mouse (the vertex does not stick to itself)
    qtbot.mousePress(scene.plotter, Qt.MouseButton.LeftButton, pos=start)
    for step in range(1, 40):
        qtbot.mouseMove(scene.plotter, start + QPoint(step, 0))
    end = scene.widget_to_world(start + QPoint(39, 0))
    qtbot.mouseRelease(scene.plotter, Qt.MouseButton.LeftButton, pos=start + QPoint(39, 0))
    x, y = window.doc.get("bodies.0.polygon_m.2")
    assert x == pytest.approx(round(end[0] / 0.01) * 0.01) and x > 0.13 and y == 0.24
    assert window.doc.undo_stack.count() == 1  # one step (the undone steps were dropped)


def test_invalid_shapes_are_flagged_where_they_are(window, tiny_file):
    window.open_project(tiny_file)
    panel = window.bodies_panel
    window.doc.selection.set(0)
    # swap two vertices: the outline crosses itself
    panel.set_vertex(0, 1, 0, 0.0)
    panel.set_vertex(0, 0, 0, 0.12)
    assert window.doc.project is None
    assert "not a simple polygon" in window.doc.problems[0].message
    assert "bad-edges" in window.scene.plotter.actors
    assert "not a simple polygon" in panel.shape_status.text()
    window.doc.undo_stack.undo()
    window.doc.undo_stack.undo()
    assert "bad-edges" not in window.scene.plotter.actors
    # a vertex outside the domain is marked in the view and in the table
    panel.set_vertex(0, 2, 0, 0.8)
    assert window.doc.problems[0].path == "bodies.0.polygon_m.2"
    assert "bad-points" in window.scene.plotter.actors
    assert panel.table.item(2, 0).background().color().name() == "#fde2e1"


def test_a_stage_can_change_the_damping_model(window, tiny_file, qtbot):
    # the near-limit warning may ask for damping_model = "maxwell" in a stage's material changes
    window.open_project(tiny_file)
    panel = window.stages_panel
    panel.select(1)
    panel.change_material.setCurrentText("sand")
    panel.change_key.setCurrentIndex(panel.change_key.findData("damping_model"))
    assert panel.change_value.placeholderText() == "rayleigh or maxwell"
    panel.change_value.setText("kelvin")
    qtbot.mouseClick(panel.change_set, Qt.MouseButton.LeftButton)
    assert window.doc.get("stages.1.material_changes") is None
    assert "Damping model" in panel.message.text() and "maxwell" in panel.message.text()
    panel.change_value.setText(" maxwell ")
    qtbot.mouseClick(panel.change_set, Qt.MouseButton.LeftButton)
    assert window.doc.get("stages.1.material_changes.sand.damping_model") == "maxwell"
    labels = [panel.changes.item(r, 1).text() for r in range(panel.changes.rowCount())]
    assert labels == ["Damping model"]
    assert panel.changes.item(0, 2).text().strip() == "maxwell"


def test_save_and_reopen_is_a_round_trip(window, tiny_file, tmp_path):
    window.open_project(tiny_file)
    window.materials_panel.fields["cohesion_pa"].set_text("1500")
    window.domain_panel.set_boundary("left", "fixed")
    window.stages_panel.select(1)
    assert window.stages_panel.set_change("sand", "friction_angle_deg", 20.0)
    window.numerics_panel.scheme.choose("apic")
    target = tmp_path / "copy.toml"
    window.ask_save_path = lambda: str(target)
    assert window.save_as()
    assert not window.doc.is_dirty and window.windowTitle().startswith("copy.toml")
    saved = load_project(target)
    assert saved == window.doc.project
    assert saved.materials["sand"].cohesion_pa == 1500.0
    assert saved.domain.boundaries.left.type == "fixed"
    assert saved.stages[1].material_changes["sand"].friction_angle_deg == 20.0
    assert saved.numerics.scheme == "apic"
    before = window.doc.data
    window.new_project()
    assert window.open_project(target)
    assert window.doc.data == before
    assert str(target) in window.settings.recent("projects")


def test_a_bad_project_file_lists_its_problems(window, tiny_file, tmp_path):
    text = tiny_file.read_text().replace("poisson_ratio = 0.3", "poisson_ratio = 0.7").replace(
        "density_kg_m3 = 2000.0", "density_kg_m3 = -5.0")
    bad = tmp_path / "bad.toml"
    bad.write_text(text)
    seen = []

    def show(path, error, can_open):
        seen.append((path, [str(p) for p in error.problems], can_open))
        return False

    window.show_project_problems = show
    assert not window.open_project(bad)
    path, problems, can_open = seen[0]
    assert path == bad and can_open
    assert problems == [
        "materials.sand.density_kg_m3 = -5.0: must be > 0",
        "materials.sand.poisson_ratio = 0.7: must be >= 0 and < 0.5",
    ]
    assert window.doc.path is None  # nothing was opened
    # "open anyway" loads it with its problems, to fix them here
    window.show_project_problems = lambda path, error, can_open: True
    assert window.open_project(bad)
    assert len(window.doc.problems) == 2 and window.doc.project is None
    window.materials_panel.fields["density_kg_m3"].set_text("2000")
    window.materials_panel.fields["poisson_ratio"].set_text("0.3")
    assert window.doc.project is not None
    # broken TOML cannot be opened anyway: its syntax error is listed with line and column
    broken = tmp_path / "broken.toml"
    broken.write_text("[runout\nschema_version = 1\n")
    window.ask_save_changes = lambda: "discard"
    window.show_project_problems = show
    assert not window.open_project(broken)
    assert seen[-1][2] is False
    assert seen[-1][1][0].startswith("TOML syntax error at line 1")


def test_unsaved_changes_are_not_lost_without_asking(window, tiny_file):
    window.open_project(tiny_file)
    window.materials_panel.fields["cohesion_pa"].set_text("10")
    answers = ["cancel", "discard"]
    asked = []

    def ask():
        asked.append(True)
        return answers.pop(0)

    window.ask_save_changes = ask
    assert not window.new_project()
    assert window.doc.path == tiny_file and window.doc.get("materials.sand.cohesion_pa") == 10.0
    assert window.new_project()
    assert window.doc.path is None and len(asked) == 2
    assert window.doc.get("bodies") == []


def test_stages_boundaries_numerics_and_output_edit_the_model(window, tiny_file):
    window.open_project(tiny_file)
    doc = window.doc
    window.domain_panel.set_boundary("right", "friction")
    assert doc.get("domain.boundaries.right") == {"type": "friction", "friction_angle_deg": 30.0}
    window.domain_panel.side_angles["right"].set_text("12.5")
    assert doc.get("domain.boundaries.right.friction_angle_deg") == 12.5
    window.domain_panel.size.set_values(0.8, 0.3)
    assert doc.get("domain.size_m") == [0.8, 0.3]
    window.numerics_panel.use_cfl.setChecked(True)
    assert doc.get("numerics.cfl") == 0.5 and doc.get("numerics.time_step_s") is None
    window.stages_panel.add_stage("gravity")
    assert [s["type"] for s in doc.get("stages")][:1] == ["gravity"]
    assert doc.problems and "only one k0 or gravity stage" in doc.problems[0].message
    # the gravity ramp is a gravity stage's own field: bound there, not on the other stages
    window.stages_panel.select(0)
    assert window.stages_panel.ramp.path == "stages.0.ramp_fraction"
    window.stages_panel.ramp.set_text("0.8")
    assert doc.get("stages.0.ramp_fraction") == 0.8
    window.stages_panel.select(2)
    assert window.stages_panel.ramp.path is None and window.stages_panel.ramp.edit.text() == ""
    window.stages_panel.select(0)
    window.stages_panel.remove_stage()
    window.stages_panel.add_stage("strength-reduction")  # after the initial stress, no duration
    assert [s["type"] for s in doc.get("stages")] == ["k0", "strength-reduction", "dynamic"]
    assert "duration_s" not in doc.get("stages.1")
    assert not any(p.path.startswith("stages.1") for p in doc.problems), doc.problems
    window.stages_panel.remove_stage()
    window.stages_panel.select(1)
    window.stages_panel.damping.set_text("0.2")
    assert doc.get("stages.1.damping") == {"type": "local", "coefficient": 0.2}
    window.output_panel.checks["stress"].setChecked(False)
    assert "stress" not in doc.get("output.fields")
    assert doc.project is not None
    count = doc.undo_stack.count()
    for _ in range(count):
        doc.undo_stack.undo()
    assert doc.project == load_project(window.doc.path)


def test_slope_from_template(window):
    from app.gui.dialogs import SlopeDialog

    window.doc.reset(_empty_project())
    window.materials_panel.add_material(name="clay")
    dialog = SlopeDialog(window.doc.material_names, window)
    dialog.height.setValue(6.0)
    dialog.angle.setValue(40.0)
    dialog.crest.setValue(4.0)
    dialog.toe.setValue(10.0)
    dialog.depth.setValue(2.0)
    dialog.add_layer("weak", 2.0, "clay")
    assert window.apply_slope(dialog)
    dialog.deleteLater()
    bodies = window.doc.get("bodies")
    assert [b["name"] for b in bodies] == ["weak", "foundation"]
    assert [b["material"] for b in bodies] == ["clay", "soil"]
    assert window.doc.project is not None, window.doc.problems
    assert window.doc.undo_stack.undoText() == "slope from template"
    # the ground slopes: the k0 stage of the new project became gravity loading, and the
    # project has no K0-on-a-slope warning left
    first = window.doc.get("stages")[0]
    assert first["type"] == "gravity" and first["duration_s"] >= 1.0
    assert first["name"] == _empty_project()["stages"][0]["name"]
    from projects.checks import project_warnings

    assert not [w for w in project_warnings(window.doc.project) if "k0" in w.lower()]
    window.doc.undo_stack.undo()
    assert window.doc.get("bodies") == [] and window.doc.get("domain.size_m") == [20.0, 10.0]
    assert window.doc.get("stages")[0]["type"] == "k0"  # the same undo step


def test_the_slope_template_fits_the_domain_on_its_supports_at_any_cell_size(window):
    import math

    from app.gui.dialogs import SlopeDialog
    from projects.checks import project_warnings, unsupported_bodies

    for cell in (0.1, 0.25, 0.37, 0.5):
        window.doc.reset(_empty_project())
        window.doc.set_value("domain.cell_size_m", cell)
        dialog = SlopeDialog(window.doc.material_names, window)  # the defaults: 10 m at 45 degrees on 2 m
        assert dialog.fit_domain.isChecked()
        assert window.apply_slope(dialog)
        dialog.deleteLater()
        origin, size = window.doc.get("domain.origin_m"), window.doc.get("domain.size_m")
        points = np.array([p for b in window.doc.get("bodies") for p in b["polygon_m"]])
        right = origin[0] + math.ceil(size[0] / cell - 1e-9) * cell
        assert points[:, 1].min() == origin[1] and points[:, 0].min() == origin[0], cell  # base, left wall
        assert abs(points[:, 0].max() - right) < 1e-9, cell  # right wall
        project = window.doc.project
        assert unsupported_bodies(project) == [] and project_warnings(project) == [], cell


def test_material_library_saves_and_inserts(window, tiny_file, tmp_path):
    window.open_project(tiny_file)
    window.materials_panel.save_to_library("dense sand")
    data = json.loads((tmp_path / "config" / "materials.json").read_text())
    assert data["materials"]["dense sand"]["friction_angle_deg"] == 30.0
    window.doc.reset(_empty_project())
    name = window.materials_panel.insert_from_library("dense sand")
    assert name == "dense-sand"
    assert window.doc.get("materials.dense-sand.density_kg_m3") == 2000.0
    # a material in use cannot be removed; an unused one can, as one undo step
    window.materials_panel.select("dense-sand")
    window.materials_panel.remove_material()
    assert "dense-sand" not in window.doc.material_names


def _empty_project():
    from app.gui.document import new_project_data

    return new_project_data()


def test_choosing_a_preset_drops_the_fixed_step_and_undo_restores_it(window, tiny_file):
    window.open_project(tiny_file)
    doc = window.doc
    dt = doc.get("numerics.time_step_s")
    panel = window.numerics_panel
    index = panel.preset.findText("draft")
    panel.preset.setCurrentIndex(index)  # as the user picks it
    panel.preset.activated.emit(index)
    assert doc.get("numerics.preset") == "draft" and doc.get("numerics.time_step_s") is None
    assert panel.preset.currentText() == "draft" and panel.preset_info.text()
    doc.undo_stack.undo()
    assert doc.get("numerics.preset") is None and doc.get("numerics.time_step_s") == dt
    assert panel.preset.currentIndex() == 0


def test_a_long_decimal_shows_short_and_is_kept_until_edited(window, tiny_file, tmp_path):
    # a script wrote 29.000000000000004 (0.1 + ...): the field shows 29, a focus change does not
    # rewrite the value, and typing changes it; a pair keeps its untouched component
    text = tiny_file.read_text(encoding="utf-8").replace("friction_angle_deg = 30.0", "friction_angle_deg = 29.000000000000004")
    assert "29.000000000000004" in text
    path = tmp_path / "long.toml"
    path.write_text(text, encoding="utf-8")
    window.open_project(path)
    field = window.materials_panel.fields["friction_angle_deg"]
    assert field.edit.text() == "29"
    assert not field.commit()  # what leaving the field does
    assert window.doc.get("materials.sand.friction_angle_deg") == 29.000000000000004 and not window.doc.is_dirty
    field.set_text("29.5")
    assert window.doc.get("materials.sand.friction_angle_deg") == 29.5
    window.doc.set_value("domain.gravity_m_s2", [0.30000000000000004, -9.81], "gravity")
    gravity = window.domain_panel.gravity
    assert [e.text() for e in gravity.edits] == ["0.3", "-9.81"]
    gravity.edits[1].setText("-9.8")
    gravity.commit()
    assert window.doc.get("domain.gravity_m_s2") == [0.30000000000000004, -9.8]
