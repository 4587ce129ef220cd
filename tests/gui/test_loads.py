"""Loads in the workbench: a stage's surcharges and seismic coefficients edited in the Stages
panel (one undo step each, bad values refused with the schema's message), carried on to later
stages, drawn in the model view, saved and read back."""

from __future__ import annotations

import pytest

from projects.document import load_project

pytestmark = pytest.mark.gui


def test_surcharges_and_seismic_coefficients_of_a_stage(window, tiny_file, tmp_path, qtbot):
    assert window.open_project(tiny_file)
    doc, panel, scene = window.doc, window.stages_panel, window.scene
    box = panel.loads
    # the k0 stage takes no loads
    panel.select(0)
    assert box.index == 0 and not box.add_button.isEnabled() and "k0 stage takes no loads" in box.status.text()
    assert not box.add_surcharge(0.02, 0.1) and doc.undo_stack.count() == 0
    panel.select(1)
    assert scene.loads_stage == 1 and box.add_button.isEnabled()
    assert box.add_surcharge(0.02, 0.10, 5e3, "block")
    assert doc.get("stages.1.surcharges") == [{"name": "block", "from_m": 0.02, "to_m": 0.1, "pressure_pa": 5e3}]
    assert doc.project is not None and doc.undo_stack.count() == 1
    assert box.table.rowCount() == 1 and box.table.item(0, 3).text() == "5"
    assert {"load-arrows", "load-tails", "load-labels-labels"} <= set(scene.plotter.actors)
    assert scene.drawn_loads == ["block"] and "loads of stage 2" in scene.legend.text()
    # typed in the table: kPa, or with a unit; a second pressure makes it vary along the segment
    box.table.item(0, 3).setText("8")
    assert doc.get("stages.1.surcharges.0.pressure_pa") == 8e3
    box.table.item(0, 4).setText("0.012 MPa")
    assert doc.get("stages.1.surcharges.0.pressure_pa") == [8e3, 12e3]
    box.table.item(0, 2).setText("0.5")  # beyond the column's top (0.12 m wide): the project says so
    assert doc.project is None and any("runs off the ground" in p.message for p in doc.problems)
    doc.undo_stack.undo()
    assert doc.project is not None and doc.get("stages.1.surcharges.0.to_m") == 0.1
    count = doc.undo_stack.count()
    box.table.item(0, 3).setText("-3")  # refused with the schema's message, nothing written
    assert "must be >= 0" in box.message.text() and doc.undo_stack.count() == count
    assert doc.get("stages.1.surcharges.0.pressure_pa") == [8e3, 12e3]
    box.table.item(0, 5).setCheckState(box.table.item(0, 5).checkState().Checked)
    assert doc.get("stages.1.surcharges.0.ramp") is True
    # seismic coefficients: the column's top is level, so out of the slope has no direction
    box.k_h.setText("0.15")
    box.k_h.editingFinished.emit()
    assert doc.get("stages.1.seismic") == {"k_h": 0.15}
    assert doc.project is None and any("as high at both ends" in p.message for p in doc.problems)
    assert box.set_seismic("towards", "right")
    assert doc.project is not None and doc.project.stages[1].seismic.towards == "right"
    assert {"seismic-arrow", "seismic-labels-labels"} <= set(scene.plotter.actors)
    assert not box.set_seismic("k_h", "1.5") and "must be >= 0 and < 1" in box.message.text()
    assert "+ surcharges + seismic" in panel.list.item(1).text()
    # a later stage keeps them until it says otherwise
    panel.add_stage("dynamic")
    assert panel.current == 2 and box.index == 2
    assert "Surcharges of stage 2" in box.status.text() and box.table.rowCount() == 1
    assert scene.drawn_loads == ["block"]  # its loads: the earlier stage's; no seismic (that stage's own)
    assert box.clear_surcharges() and doc.get("stages.2.surcharges") == []
    assert box.table.rowCount() == 0 and scene.drawn_loads == [] and "load-arrows" not in scene.plotter.actors
    assert box.keep_earlier() and "surcharges" not in doc.get("stages.2")
    # editing an inherited load makes the stage's own copy
    assert box.set_surcharge(0, "start", "20")
    assert doc.get("stages.2.surcharges") == [{"name": "block", "from_m": 0.02, "to_m": 0.1,
                                               "pressure_pa": [20e3, 12e3]}]  # at full value: no ramp
    assert doc.project is not None and doc.get("stages.1.surcharges.0.ramp") is True
    # removing a seismic coefficient removes the table with it
    panel.select(1)
    assert box.set_seismic("k_h", "") and doc.get("stages.1.seismic") is None
    # saved and read back equal
    path = tmp_path / "loaded.toml"
    panel.select(2)
    assert box.set_surcharge(0, "ramp", True) and doc.get("stages.2.surcharges.0.ramp") is True
    assert doc.project is not None
    doc.save(path)
    again = load_project(path)
    assert again == doc.project
    assert [s.name for s in again.stages[2].surcharges] == ["block"] and again.stages[2].surcharges[0].ramp
