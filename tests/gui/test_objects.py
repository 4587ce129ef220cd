"""Structures and targets in the workbench: drawn, edited, listed, undone and
saved like bodies; shown in the scene and results views; the contact forces in the curves."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest
from PySide6.QtCore import Qt

from projects.document import load_project

pytestmark = pytest.mark.gui

WALL = [[0.3, 0.0], [0.34, 0.0], [0.34, 0.1], [0.3, 0.1]]


def _click(qtbot, scene, xy):
    qtbot.mouseClick(scene.plotter, Qt.MouseButton.LeftButton, pos=scene.world_to_widget(xy).toPoint())


def test_structure_through_its_panel_is_saved_and_undone(window, tiny_file, tmp_path):
    assert window.open_project(tiny_file)
    doc, panel, scene = window.doc, window.structures_panel, window.scene
    assert window.panels.tabText(window.panels.indexOf(panel)) == "Structures"
    assert "structure-fills" not in scene.plotter.actors
    panel.add_structure(WALL, name="barrier")
    assert doc.get("structures") == [{"name": "barrier", "polygon_m": WALL, "contact": "slip"}]
    assert doc.project is not None and doc.project.structures[0].name == "barrier"
    assert doc.selection.kind == "structures" and doc.selection.structure == 0 and doc.selection.body is None
    assert window.panels.currentWidget() is panel
    # listed, with its vertices in the table; drawn grey and hatched in the scene
    assert panel.list.count() == 1 and panel.list.item(0).text() == "barrier   (slip)"
    assert panel.table.rowCount() == 4 and panel.table.item(2, 1).text() == "0.1"
    for name in ("structure-fills", "structure-hatch", "structure-outlines", "structure-labels-labels", "vertices"):
        assert name in scene.plotter.actors, name
    assert "1 structure" in scene.legend.text()
    # contact: friction with its angle, typed in the panel's field
    panel.contact.setCurrentText("friction")
    panel.contact.activated.emit(panel.contact.currentIndex())
    assert doc.get("structures.0.contact") == {"type": "friction", "friction_angle_deg": 20.0}
    panel.angle.edit.setText("25")
    assert panel.angle.commit()
    assert doc.get("structures.0.contact.friction_angle_deg") == 25.0
    assert panel.list.item(0).text() == "barrier   (friction 25°)"
    # to slip and back: the angle typed before comes back, not the default
    assert panel.set_contact("slip") and doc.get("structures.0.contact") == "slip"
    assert panel.set_contact("friction")
    assert doc.get("structures.0.contact") == {"type": "friction", "friction_angle_deg": 25.0}
    # a bad angle is refused where it is typed, and the document keeps the last good one
    panel.angle.edit.setText("95")
    assert not panel.angle.commit()
    assert doc.get("structures.0.contact.friction_angle_deg") == 25.0
    # a vertex outside the domain is a problem, marked in the view and in the table, and leads here
    panel.table.item(1, 0).setText("0.7")
    assert doc.project is None and "bad-points" in scene.plotter.actors
    problem = next(p for p in doc.problems if p.path.startswith("structures.0"))
    assert panel.table.item(1, 0).background().color().name() == "#fde2e1"
    window.panels.setCurrentWidget(window.domain_panel)
    doc.selection.set(None)
    window.go_to_problem(problem.path)
    assert window.panels.currentWidget() is panel and doc.selection.structure == 0
    doc.undo_stack.undo()
    assert doc.project is not None and "bad-points" not in scene.plotter.actors
    # a vertex typed in the table; a rename in the name field
    panel.table.item(2, 1).setText("0.15")
    assert doc.get("structures.0.polygon_m")[2] == [0.34, 0.15]
    # the undo names the vertex by the row number the table shows (1, 2, 3, ...)
    assert panel.table.verticalHeaderItem(2) is None or panel.table.verticalHeaderItem(2).text() == "3"
    assert doc.undo_stack.undoText() == "move vertex 3 of barrier"
    panel.name.set_text("dam")
    assert doc.get("structures.0.name") == "dam"
    # saved as [[structures]]: the file loads back with the same structure
    out = tmp_path / "with-structure.toml"
    doc.save(out)
    saved = load_project(out)
    assert len(saved.structures) == 1
    structure = saved.structures[0]
    assert structure.name == "dam" and structure.contact.type == "friction"
    assert structure.contact.friction_angle_deg == 25.0
    assert np.allclose(structure.polygon_m, [[0.3, 0.0], [0.34, 0.0], [0.34, 0.15], [0.3, 0.1]])
    assert "[[structures]]" in out.read_text(encoding="utf-8")
    # every step undoes, back to no structure at all (no empty list left), and redoes
    stack = doc.undo_stack
    while stack.canUndo():
        stack.undo()
    assert "structures" not in doc.data
    assert not {"structure-fills", "structure-labels-labels"} & set(scene.plotter.actors)
    assert panel.list.count() == 0
    while stack.canRedo():
        stack.redo()
    assert doc.get("structures.0.name") == "dam"
    # deleting removes the list (the file keeps no empty [[structures]]); undo brings it back
    doc.selection.select("structures", 0)
    panel.delete_item()
    assert "structures" not in doc.data and doc.selection.index is None
    stack.undo()
    assert doc.get("structures.0.name") == "dam"


def test_draw_and_drag_a_structure_in_the_view(window, tiny_file, qtbot):
    assert window.open_project(tiny_file)
    doc, scene = window.doc, window.scene
    window.structures_panel.draw_button.click()
    assert scene.mode == "draw" and scene.draw_kind == "structures"
    assert window.actions_["draw"].isChecked()
    for xy in ([0.3, 0.0], [0.34, 0.0], [0.34, 0.1], [0.3, 0.1]):
        _click(qtbot, scene, xy)
    _click(qtbot, scene, [0.3, 0.0])  # the first vertex again closes the polygon
    assert scene.mode == "select"
    assert len(doc.get("structures")) == 1 and len(doc.get("bodies")) == 1
    assert np.allclose(doc.get("structures.0.polygon_m"), WALL)
    assert doc.get("structures.0.contact") == "slip" and doc.project is not None
    # the body drawing tool still draws bodies
    window.actions_["select"].setChecked(True)
    window.actions_["draw"].setChecked(True)
    assert scene.draw_kind == "bodies"
    window.actions_["select"].setChecked(True)
    # drag the structure's top-right vertex: one undo step; the vertex table follows
    start = scene.world_to_widget((0.34, 0.1)).toPoint()
    qtbot.mousePress(scene.plotter, Qt.MouseButton.LeftButton, pos=start)
    assert (doc.selection.kind, doc.selection.index, doc.selection.vertex) == ("structures", 0, 2)
    for xy in ((0.35, 0.11), (0.36, 0.12)):
        qtbot.mouseMove(scene.plotter, scene.world_to_widget(xy).toPoint())
    qtbot.mouseRelease(scene.plotter, Qt.MouseButton.LeftButton, pos=scene.world_to_widget((0.36, 0.12)).toPoint())
    assert np.allclose(doc.get("structures.0.polygon_m")[2], [0.36, 0.12])  # on the half-cell snap
    assert window.structures_panel.table.item(2, 0).text() == "0.36"
    assert doc.get("bodies.0.polygon_m") == load_project(window.doc.path).to_dict()["bodies"][0]["polygon_m"]
    doc.undo_stack.undo()
    assert np.allclose(doc.get("structures.0.polygon_m")[2], [0.34, 0.1])
    # Delete removes the selected vertex of the structure, not of a body
    doc.selection.select("structures", 0, 3)
    scene.delete_selected_vertex()
    assert len(doc.get("structures.0.polygon_m")) == 3 and len(doc.get("bodies.0.polygon_m")) == 4
    # a click inside the structure selects it
    doc.selection.set(None)
    _click(qtbot, scene, (0.325, 0.03))
    assert doc.selection.structure == 0


def test_targets_through_their_panel(window, tiny_file, tmp_path, qtbot):
    assert window.open_project(tiny_file)
    doc, panel, scene = window.doc, window.targets_panel, window.scene
    # a vertical line typed by its x, a point by x and y
    panel.new_x.setText("0.4")
    panel.add_button.click()
    panel.new_kind.setCurrentText("point")
    panel.new_x.setText("0.5")
    panel.new_y.setText("0,02")  # a comma as decimal point is read too
    panel.add_button.click()
    assert doc.get("targets") == [{"name": "target-1", "x_m": 0.4}, {"name": "target-2", "point_m": [0.5, 0.02]}]
    assert doc.project is not None and [t.name for t in doc.project.targets] == ["target-1", "target-2"]
    assert panel.list.count() == 2 and "line at x = 0.4 m" in panel.list.item(0).text()
    assert doc.selection.target == 1 and window.panels.currentWidget() is panel
    for name in ("target-lines", "target-points", "target-labels-labels", "target-selected"):
        assert name in scene.plotter.actors, name
    # rename and move through the form; a name the schema refuses is not taken
    doc.selection.select("targets", 0)
    assert panel.rename("road")
    assert not panel.rename("the road")
    assert doc.get("targets.0.name") == "road"
    panel.x.edit.setText("0.45")
    assert panel.x.commit()
    assert doc.get("targets.0.x_m") == 0.45
    # dragging a line target in the view moves it along x
    start = scene.world_to_widget((0.45, 0.2)).toPoint()
    qtbot.mousePress(scene.plotter, Qt.MouseButton.LeftButton, pos=start)
    assert doc.selection.target == 0
    qtbot.mouseMove(scene.plotter, scene.world_to_widget((0.47, 0.25)).toPoint())
    qtbot.mouseRelease(scene.plotter, Qt.MouseButton.LeftButton, pos=scene.world_to_widget((0.47, 0.25)).toPoint())
    assert doc.get("targets.0.x_m") == pytest.approx(0.47)
    doc.undo_stack.undo()
    assert doc.get("targets.0.x_m") == 0.45
    # saved as [[targets]]
    out = tmp_path / "with-targets.toml"
    doc.save(out)
    saved = load_project(out)
    assert [(t.name, t.x_m, t.point_m) for t in saved.targets] == [("road", 0.45, None),
                                                                     ("target-2", None, (0.5, 0.02))]
    # a target outside the domain is a problem of the project, named by its key
    panel.add_target(2.0)
    problem = next(p for p in doc.problems if p.path.startswith("targets.2"))
    assert doc.project is None
    window.panels.setCurrentWidget(window.domain_panel)
    window.go_to_problem(problem.path)
    assert window.panels.currentWidget() is panel and doc.selection.target == 2
    doc.undo_stack.undo()
    assert doc.project is not None
    # removing both leaves no [[targets]]; undo brings them back
    panel.remove_target()
    panel.remove_target()
    assert "targets" not in doc.data and "target-lines" not in scene.plotter.actors
    doc.undo_stack.undo()
    doc.undo_stack.undo()
    assert [t["name"] for t in doc.get("targets")] == ["road", "target-2"]


def _write_contacts(path, rows):
    from projects.results import CONTACT_COLUMNS

    with open(path, "w", newline="", encoding="utf-8") as fh:
        writer = csv.writer(fh)
        writer.writerow(CONTACT_COLUMNS)
        for row in rows:
            writer.writerow(row)


def test_contact_forces_and_structures_in_the_results(window, make_results, qtbot):
    from projects.results import read_contacts

    path = make_results(n_frames=4)
    summary = json.loads((path / "summary.json").read_text(encoding="utf-8"))
    summary["structures"] = [{"name": "barrier", "polygon_m": WALL}]
    (path / "summary.json").write_text(json.dumps(summary), encoding="utf-8")
    rows = []
    for k, t in enumerate((0.0, 0.05, 0.1, 0.15)):
        rows.append([t, "bottom", 0.0, 100.0 * k, 100.0 * k, 0.0, 150.0 * k, 0.0, 150.0 * k, 50.0 * k])
        rows.append([t, "barrier", 30.0 * k, 40.0 * k, "", "", 80.0 * k, 48.0 * k, 64.0 * k, -12.0 * k])
    _write_contacts(path / "contacts.csv", rows)
    assert window.open_results(path)
    view = window.results_view
    assert view.scene.structure_count == 1 and "structures" in view.scene.plotter.actors
    assert "structure-names-labels" in view.scene.plotter.actors  # named as the curves name it
    plot = view.contact_plot
    assert list(plot.curves) == ["bottom", "barrier"]
    t, mean, peak = plot.curves["barrier"]
    assert np.allclose(t, [0.0, 0.05, 0.1, 0.15])
    assert np.allclose(mean, [0.0, 50.0, 100.0, 150.0])  # |(30k, 40k)| = 50k
    assert np.allclose(peak, [0.0, 80.0, 160.0, 240.0])
    x, y = plot.lines["bottom"][0].get_data()
    assert np.allclose(y, [0.0, 100.0, 200.0, 300.0])
    assert plot.lines["bottom"][0].get_drawstyle() == "steps-pre"  # each mean belongs to the interval before it
    # the legend beside the plots, not over them; the signed components; the sides' normal force
    assert plot.figure.legends and not any(ax.get_legend() for ax in plot.axes)
    plot.set_component("x")
    assert np.allclose(plot.curves["barrier"][1], [0.0, 30.0, 60.0, 90.0])
    assert np.allclose(plot.curves["barrier"][2], [0.0, 48.0, 96.0, 144.0])  # the peak step's x component
    assert plot.axes[0].get_ylabel() == "Mean F x (N/m)"
    plot.set_component("normal")
    # the structure's normal part on the face its force enters (worked out on reading this file,
    # which has none: projects.structure_forces)
    from projects.structure_forces import components

    assert list(plot.curves) == ["bottom", "barrier"]
    expected = [components(WALL, (30.0 * k, 40.0 * k), -12.0 * k)[0] if k else 0.0 for k in range(4)]
    assert np.allclose(plot.curves["barrier"][1], expected)
    assert plot.axes[1].get_ylabel() == "Peak |F| (N/m)"  # no peak vector along the normal
    assert np.allclose(plot.curves["bottom"][1], [0.0, 100.0, 200.0, 300.0])
    plot.set_component("magnitude")
    # a click on a legend entry hides that contact (a large base force flattened the others)
    plot.toggle("bottom")
    assert not plot.lines["bottom"][0].get_visible() and plot.lines["barrier"][0].get_visible()
    plot.redraw_now()
    assert plot.axes[0].get_ylim()[1] < 200.0  # scaled to the barrier's 150 N/m, not the base's 300
    plot.toggle("bottom")
    assert plot.lines["bottom"][0].get_visible()
    view.show_frame(1)
    assert plot.markers[0].get_visible() and plot.markers[0].get_xdata()[0] == pytest.approx(view.results.times[1])
    # the folder is the interface: rows appended while a run goes on show at the next reread
    rows.append([0.2, "barrier", 300.0, 400.0, "", "", 900.0, 540.0, 720.0, -60.0])
    _write_contacts(path / "contacts.csv", rows)
    view._show_contacts(path, live=True)
    assert plot.curves["barrier"][1][-1] == pytest.approx(500.0)
    assert len(read_contacts(path)["barrier"]["time_s"]) == 5


def test_results_without_contacts_show_an_empty_plot(window, make_results):
    path = make_results(n_frames=2)
    assert window.open_results(path)
    plot = window.results_view.contact_plot
    assert plot.curves == {} and plot.lines == {}
    assert "No contacts.csv" in plot.axes[0].get_title()
    assert window.results_view.scene.structure_count == 0


def test_a_body_a_structure_covers_is_a_problem_and_run_refuses_it(window, tiny_file, monkeypatch):
    # valid to the schema, but the run could not seed the body: listed with the problems (not only
    # in the run-time label) and Run says why at once, instead of a process that ends in an error
    assert window.open_project(tiny_file)
    window.structures_panel.add_structure([[0.0, 0.0], [0.14, 0.0], [0.14, 0.26], [0.0, 0.26]], name="cover")
    panel = window.run_panel
    panel.update_estimate()
    assert window.doc.project is not None
    texts = [panel.problems.item(i).text() for i in range(panel.problems.count())]
    assert any(t.startswith("bodies.0.polygon_m") and "receives no particles" in t for t in texts), texts
    assert panel.problems_box.title().startswith("Problems (1)")
    assert panel.runtime.text() == "fix the problems below first"
    errors = []
    monkeypatch.setattr(window, "show_error", lambda title, text: errors.append((title, text)))
    assert window.start_run() is False
    assert errors and errors[0][0] == "Cannot run" and "receives no particles" in errors[0][1]
    assert not window.runs
    # undone, the project builds again: no problem left, a run-time estimate
    window.doc.undo_stack.undo()
    panel.update_estimate()
    assert panel.build_error is None and panel.problems_box.title() == "Problems (none)"
    assert panel.runtime.text().startswith("about ")


@pytest.mark.parametrize("kind", ["structures", "bodies"])
def test_a_name_another_item_has_is_refused_where_it_is_typed(window, tiny_file, kind):
    # the file's rule blames the later of two equal names; typed in the form, the edit itself is
    # refused, naming the item that has the name
    assert window.open_project(tiny_file)
    doc = window.doc
    if kind == "structures":
        panel = window.structures_panel
        panel.add_structure(WALL, name="barrier")
        panel.add_structure([[0.5, 0.0], [0.54, 0.0], [0.54, 0.1], [0.5, 0.1]], name="dam")
    else:
        panel = window.bodies_panel
        body = doc.get("bodies")[0]
        doc.edit("add a body", lambda d: d["bodies"].append({**body, "name": "dam"}))
    first = doc.get(f"{kind}.0.name")
    doc.selection.select(kind, 1)
    before = doc.get(kind)
    panel.name.edit.setText(first)
    assert not panel.name.commit()
    assert doc.get(kind) == before
    assert panel.name.error == f"{kind}.0 is already named {first!r}; names must be unique"
    # its own name, or a free one, is taken
    panel.name.edit.setText("dam")
    assert not panel.name.commit() and panel.name.error == ""
    panel.name.edit.setText("gate")
    assert panel.name.commit() and doc.get(f"{kind}.1.name") == "gate"
