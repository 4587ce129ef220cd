"""Ground water in the workbench: the phreatic and free-water lines drawn and edited like a slope
profile (the project's and a stage's), undone, saved and read back; the water's form; the
saturated density and r_u of a material; the water in the scene and results views."""

from __future__ import annotations

import numpy as np
import pytest
from PySide6.QtCore import Qt

from projects.document import load_project

pytestmark = pytest.mark.gui

TABLE = [[0.0, 0.1], [0.3, 0.14], [0.6, 0.12]]


def _click(qtbot, scene, xy):
    qtbot.mouseClick(scene.plotter, Qt.MouseButton.LeftButton, pos=scene.world_to_widget(xy).toPoint())


def test_draw_the_phreatic_line_undo_redo_save_and_reload(window, tiny_file, tmp_path, qtbot):
    assert window.open_project(tiny_file)
    doc, panel, scene = window.doc, window.water_panel, window.scene
    assert window.panels.tabText(window.panels.indexOf(panel)) == "Water"
    assert "water-line-0" not in scene.plotter.actors
    panel.choose(0)
    qtbot.mouseClick(panel.draw_button, Qt.MouseButton.LeftButton)
    assert scene.mode == "draw" and scene.draw_kind == "water" and scene.draw_slot == 0
    for xy in TABLE[:2]:
        _click(qtbot, scene, xy)
    _click(qtbot, scene, (0.2, 0.2))  # left of the last point: refused (one height at each x)
    assert len(scene.draft) == 2
    _click(qtbot, scene, TABLE[2])
    qtbot.keyClick(scene.plotter, Qt.Key.Key_Return)
    assert scene.mode == "select"
    assert doc.get("water.phreatic_line_m") == TABLE  # snapped to half cells (0.01 m)
    assert doc.project is not None and doc.project.water.phreatic_line_m == tuple(map(tuple, TABLE))
    assert doc.undo_stack.count() == 1
    # drawn: the blue line across the domain, the free water shaded where it is above the ground
    # (right of the column, whose top is at 0.24 m: the line is above the floor there)
    assert {"water-line-0", "water-fill", "water-vertices"} <= set(scene.plotter.actors)
    assert panel.table.rowCount() == 3 and panel.table.item(1, 1).text() == "0.14"
    doc.undo_stack.undo()
    assert doc.get("water") is None and "water-line-0" not in scene.plotter.actors
    doc.undo_stack.redo()
    assert doc.get("water.phreatic_line_m") == TABLE
    # saved and read back equal, in the window too
    path = tmp_path / "wet.toml"
    doc.save(path)
    again = load_project(path)
    assert again.water.phreatic_line_m == tuple(map(tuple, TABLE)) and again == doc.project
    assert window.open_project(path, ask=False)
    assert window.doc.project == again and window.doc.get("water.phreatic_line_m") == TABLE


def test_drag_a_water_point_is_one_step_and_keeps_x_increasing(window, tiny_file, qtbot):
    assert window.open_project(tiny_file)
    doc, panel, scene = window.doc, window.water_panel, window.scene
    panel.choose(0)
    panel.set_line(TABLE)
    start = scene.world_to_widget(TABLE[1]).toPoint()
    qtbot.mousePress(scene.plotter, Qt.MouseButton.LeftButton, pos=start)
    assert (doc.selection.kind, doc.selection.index, doc.selection.vertex) == ("water", 0, 1)
    for xy in ((0.35, 0.15), (0.4, 0.16)):
        qtbot.mouseMove(scene.plotter, scene.world_to_widget(xy).toPoint())
    qtbot.mouseRelease(scene.plotter, Qt.MouseButton.LeftButton, pos=scene.world_to_widget((0.4, 0.16)).toPoint())
    assert doc.get("water.phreatic_line_m.1") == [0.4, 0.16]
    assert doc.undo_stack.count() == 2
    # dragged past the next point, it stops short of it
    qtbot.mousePress(scene.plotter, Qt.MouseButton.LeftButton, pos=scene.world_to_widget((0.4, 0.16)).toPoint())
    qtbot.mouseMove(scene.plotter, scene.world_to_widget((0.7, 0.16)).toPoint())
    qtbot.mouseRelease(scene.plotter, Qt.MouseButton.LeftButton, pos=scene.world_to_widget((0.7, 0.16)).toPoint())
    x = doc.get("water.phreatic_line_m.1")[0]
    assert 0.59 < x < 0.6 and doc.project is not None
    doc.undo_stack.undo()
    doc.undo_stack.undo()
    assert doc.get("water.phreatic_line_m") == TABLE
    # the table types a point; Delete removes the selected point
    panel.table.item(0, 1).setText("0.05")
    assert doc.get("water.phreatic_line_m.0") == [0.0, 0.05]
    doc.selection.select("water", 0, 1)
    qtbot.keyClick(scene.plotter, Qt.Key.Key_Delete)
    assert doc.get("water.phreatic_line_m") == [[0.0, 0.05], [0.6, 0.12]]


def test_a_stage_moves_the_water_and_bad_lines_get_the_schema_message(window, tiny_file, qtbot):
    from app.gui.document import water_slot
    from projects.build import solver_water

    assert window.open_project(tiny_file)
    doc, panel, scene = window.doc, window.water_panel, window.scene
    panel.choose(0)
    panel.level.setText("15 cm")
    qtbot.mouseClick(panel.level_button, Qt.MouseButton.LeftButton)
    assert doc.get("water.phreatic_line_m") == [[0.0, 0.15], [0.6, 0.15]]
    # the dynamic stage (stage 2) draws the water down to 2 cm, and the free water to 5 cm
    slot = water_slot(1, "phreatic_line_m")
    panel.choose(slot)
    assert panel.line_choice.currentText().startswith("Stage 2 (collapse): phreatic line")
    panel.level.setText("0.02")
    panel.level.returnPressed.emit()
    panel.choose(water_slot(1, "free_water_line_m"))
    qtbot.mouseClick(panel.draw_button, Qt.MouseButton.LeftButton)
    assert scene.draw_slot == water_slot(1, "free_water_line_m")
    for xy in ((0.0, 0.05), (0.6, 0.05)):
        _click(qtbot, scene, xy)
    qtbot.keyClick(scene.plotter, Qt.Key.Key_Return)
    assert doc.get("stages.1.water") == {"phreatic_line_m": [[0.0, 0.02], [0.6, 0.02]],
                                         "free_water_line_m": [[0.0, 0.05], [0.6, 0.05]]}
    after = solver_water(doc.project)[-1]
    assert after.phreatic_line_m == ((0.0, 0.02), (0.6, 0.02)) and after.free_water == ((0.0, 0.05), (0.6, 0.05))
    assert "water" in window.stages_panel.list.item(1).text()
    # the stage's lines are shown (lighter) while one of them is selected
    assert {"water-stage-0", "water-stage-1", "water-line-0"} <= set(scene.plotter.actors)
    # a point typed left of the one before: the schema's one line, under the table, the row red
    panel.choose(slot)
    panel.table.item(1, 0).setText("-0.1")
    assert doc.project is None
    assert "does not lie right of point 0" in panel.line_problems.text()
    assert panel.table.item(1, 0).background().color().name() == "#fde2e1"
    doc.undo_stack.undo()
    assert doc.project is not None
    # removing the stage's line leaves the other; removing the project's phreatic line all water
    assert panel.remove_line() and doc.get("stages.1.water") == {"free_water_line_m": [[0.0, 0.05], [0.6, 0.05]]}
    panel.choose(0)
    assert panel.remove_line()
    assert doc.get("water") is None and doc.get("stages.1.water") is None and doc.project is not None
    doc.undo_stack.undo()
    assert doc.get("stages.1.water.free_water_line_m") == [[0.0, 0.05], [0.6, 0.05]]


def test_the_water_form_and_the_wet_material_keys_take_units(window, tiny_file, tmp_path):
    assert window.open_project(tiny_file)
    doc, panel = window.doc, window.water_panel
    assert not panel.unit_weight.isEnabled()  # no [water] yet
    panel.choose(0)
    panel.set_level(0.1)
    panel.unit_weight.set_text("10 kN/m3")
    assert doc.get("water.unit_weight_n_m3") == 10000.0
    panel.unit_weight.set_text("9.81 kg")
    assert panel.unit_weight.error == "unknown unit 'kg'; use N/m3 or kN/m3"
    assert doc.get("water.unit_weight_n_m3") == 10000.0
    panel.unit_weight.set_text("0")
    assert panel.unit_weight.error == "must be > 0"
    panel.inclined.setChecked(True)
    assert doc.get("water.inclined_line_correction") is True
    # the material: saturated density typed as a unit weight, stored in kg/m3, reads back as typed
    materials = window.materials_panel
    materials.select("sand")
    field = materials.fields["saturated_density_kg_m3"]
    field.set_text("21 kN/m3")
    assert doc.get("materials.sand.saturated_density_kg_m3") == pytest.approx(21000.0 / 9.81)
    assert field.edit.text() == "21 kN/m3"
    field.set_text("1500")  # below the dry density: the whole project's rule, orange on the field
    assert doc.project is None
    assert "must be >= density_kg_m3 (2000)" in field.edit.toolTip()
    field.set_text("2.2 t/m3")
    assert doc.get("materials.sand.saturated_density_kg_m3") == pytest.approx(2200.0) and doc.project is not None
    ru = materials.fields["ru"]
    ru.set_text("1")
    assert ru.error == "must be >= 0 and < 1" and doc.get("materials.sand.ru") is None
    ru.set_text("0.2")
    assert doc.get("materials.sand.ru") == 0.2
    # a stage's material change, with a unit too
    stages = window.stages_panel
    stages.select(1)
    stages.change_material.setCurrentText("sand")
    stages.change_key.setCurrentIndex(stages.change_key.findData("saturated_density_kg_m3"))
    stages.change_value.setText("22 kN/m3")
    stages._set_change()
    assert doc.get("stages.1.material_changes.sand.saturated_density_kg_m3") == pytest.approx(22000.0 / 9.81)
    stages.change_key.setCurrentIndex(stages.change_key.findData("ru"))
    stages.change_value.setText("1.5")
    stages._set_change()
    assert stages.message.text() == "Pore-pressure ratio r_u: must be >= 0 and < 1"
    path = tmp_path / "wet.toml"
    doc.save(path)
    again = load_project(path)
    assert again.materials["sand"].saturated_density_kg_m3 == pytest.approx(2200.0)
    assert again.water.unit_weight_n_m3 == 10000.0 and again.water.inclined_line_correction
    assert again.stages[1].material_changes["sand"].saturated_density_kg_m3 == pytest.approx(22000.0 / 9.81)


def test_the_results_view_offers_pore_pressure_where_the_frames_have_it(window, tmp_path, make_results):
    from app.render import FIELDS
    from tests.unit.test_render_water import wet_results

    wet = wet_results(tmp_path / "wet.results")
    assert window.open_results(wet)
    view = window.results_view
    combo = view.controls.field
    names = [combo.itemData(i) for i in range(combo.count())]
    assert {"pore_pressure", "total_stress_yy", "mean_total_stress", "mean_stress"} <= set(names)
    item = combo.model().item(combo.findData("pore_pressure"))
    assert item.isEnabled()
    view.set_field("pore_pressure")
    arrays = view.results.frame(view.frame_index)
    assert np.allclose(view.scene.values, np.clip(0.12 - arrays["positions"][arrays["active"], 1], 0, None) * 9.81)
    # the water at the frame shown: frame 3 is the end of the drawdown, at 0.03 m
    assert "water-line" in view.scene.plotter.actors
    line = np.asarray(view.scene.plotter.actors["water-line"].mapper.dataset.points)
    assert np.allclose(line[:, 1] + view.scene.offset[1], 0.03)
    view.show_frame(0)
    line = np.asarray(view.scene.plotter.actors["water-line"].mapper.dataset.points)
    assert np.allclose(line[:, 1] + view.scene.offset[1], 0.12)
    # a dry run: the pore pressure is not offered (greyed out, saying why)
    assert window.open_results(make_results())
    item = combo.model().item(combo.findData("pore_pressure"))
    assert not item.isEnabled() and "did not write" in item.toolTip()
    assert "water-line" not in view.scene.plotter.actors
    assert combo.model().item(combo.findData("total_stress_yy")).isEnabled()
    assert FIELDS["pore_pressure"].source == "pore_pressure"


def test_a_picture_made_beside_the_results_view_draws_the_phreatic_line_at_full_width(window, tmp_path):
    """Once the results view has drawn, an offscreen (EGL) window of the same process draws wide
    lines one pixel wide, which blend into the rows beside them: a picture made from the workbench
    (a report, an export) draws the phreatic line as a band, at least two full pixel rows of its
    blue, the line's row within 3 pixels of the level's."""
    import imageio.v2 as imageio

    from app import render
    from tests.unit.test_render_water import _blue_line_rows, wet_results

    wet = wet_results(tmp_path / "wet.results")
    assert window.open_results(wet)
    window.results_view.scene.plotter.render()
    results = render.Results(wet)
    size = (800, 450)
    rows = _blue_line_rows(imageio.imread(render.render_frame(results, 0, "displacement", tmp_path / "f0.png",
                                                              size=size)))
    assert len(rows) >= 2, rows
    view = render._view(render._domain_box(results), size)
    expected = size[1] / 2.0 - (0.12 - 0.5 * (view.bounds[2] + view.bounds[3])) * view.pixels_per_m
    assert abs(float(np.median(rows)) - expected) <= 3.0, (rows, expected)
