"""Strain softening in the workbench: the law chosen in the material form (with "none"), its residual
values, strains and length typed with units, saved and read back from the file; "none" and a
linear-elastic model remove the keys in one undo step; a stage's material changes set the law and
the residual values."""

from __future__ import annotations

import pytest
from PySide6.QtCore import Qt

from projects.document import load_project

pytestmark = pytest.mark.gui

NUMBERS = ("residual_cohesion_pa", "residual_friction_angle_deg", "residual_dilatancy_angle_deg",
           "peak_plastic_strain", "residual_plastic_strain", "softening_length_m")


def test_choose_a_softening_law_type_its_values_save_and_read_back(window, tiny_file, tmp_path):
    assert window.open_project(tiny_file)
    doc, panel = window.doc, window.materials_panel
    panel.select("sand")
    law = panel.softening_law
    assert law.isEnabled() and law.combo.currentText() == "none"
    assert [law.combo.itemText(i) for i in range(law.combo.count())] == ["none", "linear", "exponential"]
    assert not any(panel.fields[k].isEnabled() for k in NUMBERS)  # no law: nothing to soften
    panel.set_softening_law("linear")
    assert doc.get("materials.sand.softening_law") == "linear"
    assert all(panel.fields[k].isEnabled() for k in NUMBERS)
    # a law alone is not enough: the file's rule names the missing residual strain
    assert doc.project is None
    assert any(p.path == "materials.sand.residual_plastic_strain" for p in doc.problems)
    panel.fields["residual_friction_angle_deg"].set_text("12 deg")
    panel.fields["peak_plastic_strain"].set_text("0.01")
    panel.fields["residual_plastic_strain"].set_text("0.2")
    panel.fields["softening_length_m"].set_text("5 cm")
    assert doc.project is not None, doc.problems
    assert doc.get("materials.sand.softening_length_m") == pytest.approx(0.05)
    assert panel.fields["softening_length_m"].unit.text() == "m"
    # a residual value above the peak one: the whole project's rule, on the field
    field = panel.fields["residual_friction_angle_deg"]
    field.set_text("35")
    assert doc.project is None and "must be <= friction_angle_deg (30)" in field.edit.toolTip()
    field.set_text("12")
    # the schema's own rule for one value, at once
    strain = panel.fields["residual_plastic_strain"]
    strain.set_text("0")
    assert strain.error == "must be > 0" and doc.get("materials.sand.residual_plastic_strain") == 0.2
    path = tmp_path / "softening.toml"
    doc.save(path)
    sand = load_project(path).materials["sand"]
    assert sand.softening_law == "linear" and sand.residual_friction_angle_deg == 12.0
    assert (sand.peak_plastic_strain, sand.residual_plastic_strain) == (0.01, 0.2)
    assert sand.softening_length_m == pytest.approx(0.05) and sand.residual_cohesion_pa is None
    assert window.open_project(path, ask=False)
    panel.select("sand")
    assert panel.softening_law.combo.currentText() == "linear"
    assert panel.fields["residual_plastic_strain"].edit.text() == "0.2"


def test_no_softening_removes_its_keys_in_one_step(window, tiny_file):
    assert window.open_project(tiny_file)
    doc, panel = window.doc, window.materials_panel
    panel.select("sand")
    panel.set_softening_law("exponential")
    panel.fields["residual_friction_angle_deg"].set_text("20")
    panel.fields["residual_plastic_strain"].set_text("0.3")
    assert doc.project is not None and doc.project.materials["sand"].softening_law == "exponential"
    steps = doc.undo_stack.count()
    panel.set_softening_law("none")
    assert doc.undo_stack.count() == steps + 1
    table = doc.get("materials.sand")
    assert not any(k in table for k in ("softening_law", *NUMBERS)) and doc.project is not None
    assert not panel.fields["residual_plastic_strain"].isEnabled()
    doc.undo_stack.undo()
    assert doc.get("materials.sand.residual_plastic_strain") == 0.3
    assert panel.softening_law.combo.currentText() == "exponential"
    # a linear-elastic material has no strength to soften: the keys go with the model
    panel.set_model("linear-elastic")
    assert not any(k in doc.get("materials.sand") for k in ("softening_law", *NUMBERS))
    assert not panel.softening_law.isEnabled() and doc.project is not None


def test_a_stage_sets_the_softening_law_and_a_residual_value(window, tiny_file, tmp_path, qtbot):
    assert window.open_project(tiny_file)
    doc, stages = window.doc, window.stages_panel
    stages.select(1)
    stages.change_material.setCurrentText("sand")
    stages.change_key.setCurrentIndex(stages.change_key.findData("softening_law"))
    assert stages.change_value.placeholderText() == "linear or exponential"
    stages.change_value.setText("cubic")
    qtbot.mouseClick(stages.change_set, Qt.MouseButton.LeftButton)
    assert doc.get("stages.1.material_changes") is None and "Softening law" in stages.message.text()
    stages.change_value.setText("linear")
    qtbot.mouseClick(stages.change_set, Qt.MouseButton.LeftButton)
    for key, text in (("residual_friction_angle_deg", "15 deg"), ("residual_plastic_strain", "0.25"),
                      ("softening_length_m", "10 cm")):
        stages.change_key.setCurrentIndex(stages.change_key.findData(key))
        stages.change_value.setText(text)
        qtbot.mouseClick(stages.change_set, Qt.MouseButton.LeftButton)
    labels = [stages.changes.item(r, 1).text() for r in range(stages.changes.rowCount())]
    assert labels == ["Softening law", "Residual friction angle", "Residual plastic strain", "Softening length"]
    assert doc.project is not None, doc.problems
    path = tmp_path / "staged.toml"
    doc.save(path)
    change = load_project(path).stages[1].material_changes["sand"]
    assert change.softening_law == "linear" and change.residual_friction_angle_deg == 15.0
    assert change.residual_plastic_strain == 0.25 and change.softening_length_m == pytest.approx(0.1)
