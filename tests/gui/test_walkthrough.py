"""Items of a first afternoon in the workbench, driven under Xvfb as a new engineer would: a run's
progress lines against the Project dock, the Sweep dialog's rows, a sweep of listed values, the
file checks of an import, and the structures' outlines in exported pictures."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest

pytestmark = pytest.mark.gui


def _cut_panels(window) -> list[str]:
    cut = []
    for i in range(window.panels.count()):
        panel = window.panels.widget(i)
        need, have = panel.widget().minimumSizeHint().width(), panel.viewport().width()
        if need > have:
            cut.append(f"{window.panels.tabText(i)}: {need} px in {have}")
    return cut


def test_a_runs_progress_lines_leave_the_project_dock_its_width(window, tiny_file, qtbot):
    from app.gui.main_window import MainWindow

    window.resize(*MainWindow.DEFAULT_SIZE)
    window.open_project(tiny_file, ask=False)
    qtbot.wait(50)
    panel = window.run_panel
    panel.layout().activate()
    need = panel.minimumSizeHint().width()
    for step in (12_345, 13_345):  # the second report adds the Remaining line
        panel.show_progress(dict(total_time_s=21.4, time_s=step / 1000, stage="run-out", step=step,
                                 steps_per_s=1587.0, particle_steps_per_s=313_000.0), step / 1000)
        panel.layout().activate()
        assert panel.minimumSizeHint().width() <= need, panel.rate.text()
    summary = {"simulated_time_s": 3.5, "steps": 2380, "wall_time_s": 21.2, "particle_steps_per_s": 313_000.0,
               "arch": "cpu"}
    panel.show_result("completed", "stage 'run-out' ended by its rest criterion at t = 3.5 s", summary)
    # the lines wrap in the Run dock instead of widening it: on the slope template the Run dock
    # grew from 289 to 330 px during its first run, taking the width from the Project dock, whose
    # Stages panel then scrolled sideways, and the window grew past its size
    panel.layout().activate()
    assert panel.minimumSizeHint().width() <= need, panel.clock.text()
    qtbot.wait(50)
    assert _cut_panels(window) == []


@pytest.mark.parametrize("kind", ["sweep", "calibration"])
def test_the_sweep_dialogs_rows_do_not_overlap(qtbot, tiny_file, tmp_path, kind):
    from PySide6.QtWidgets import QFormLayout

    from app.gui.document import ProjectDocument
    from app.gui.sweep_dialog import SweepDialog

    doc = ProjectDocument()
    doc.open(tiny_file)
    dialog = SweepDialog(doc, tmp_path / "tiny.sweep")
    qtbot.addWidget(dialog)
    dialog.kind.setCurrentText(kind)
    dialog.show()
    qtbot.waitExposed(dialog)
    overlaps = []
    for form in dialog.findChildren(QFormLayout):
        if not form.parentWidget().isVisible():
            continue
        rows = []
        for r in range(form.rowCount()):
            item = form.itemAt(r, QFormLayout.ItemRole.FieldRole)
            if item is not None and (item.widget() is None or item.widget().isVisible()):
                rows.append(item.geometry())
        for a, b in zip(rows, rows[1:]):
            if a.bottom() >= b.top():
                overlaps.append((a.getRect(), b.getRect()))
    # the measures list ran under the fields below it (a word-wrapped hint squeezed the Sweep box)
    assert overlaps == []
    assert dialog.measures.height() >= dialog.measures.minimumHeight()


def test_a_sweep_of_listed_values_runs_each_value_once(qtbot, tiny_file, tmp_path):
    from app.gui.document import ProjectDocument
    from app.gui.sweep_dialog import SweepDialog
    from sweeps.sampling import sample
    from sweeps.spec import load_spec

    doc = ProjectDocument()
    doc.open(tiny_file)
    dialog = SweepDialog(doc, tmp_path / "three.sweep")
    qtbot.addWidget(dialog)
    assert dialog.sampling.currentText() == "latin-hypercube" and dialog.runs.value() == 8
    dialog.params.cellWidget(0, 1).setCurrentText("list")
    dialog.params.item(0, 2).setText("26, 28, 30")
    # a Latin hypercube of 8 runs over 3 values ran some values three times and took 8 runs' time
    assert dialog.sampling.currentText() == "grid" and not dialog.runs.isEnabled()
    assert dialog.runs_note.text().startswith("grid: 3 runs")
    dialog.accept()
    assert dialog.result() == SweepDialog.DialogCode.Accepted, dialog.error.text()
    runs = sample(load_spec(dialog.spec_path))
    assert sorted(r[next(iter(r))] for r in runs) == [26.0, 28.0, 30.0]
    # a continuous parameter beside it: the sampling stays as chosen
    dialog = SweepDialog(doc, tmp_path / "mixed.sweep")
    qtbot.addWidget(dialog)
    dialog.add_parameter("stages.1.duration_s", "list", "0.04, 0.05")
    assert dialog.sampling.currentText() == "latin-hypercube" and dialog.runs.isEnabled()


def test_an_import_of_a_file_it_cannot_read_says_so_in_one_line(window, tmp_path, monkeypatch):
    errors = []
    monkeypatch.setattr(window, "show_error", lambda title, text: errors.append(text))
    fifo = tmp_path / "profile.csv"
    os.mkfifo(fifo)  # no writer: reading it blocked the workbench for good
    damaged = tmp_path / "mesh.vtu"
    damaged.write_text("<VTKFile garbage")  # meshio ended the process (sys.exit) on it
    empty = tmp_path / "empty.dxf"
    empty.write_text("")
    long = tmp_path / "long.csv"
    long.write_text("x_m,y_m\n" + "\n".join(f"{i * 0.001},{5 + 1e-5 * i}" for i in range(20_001)) + "\n")
    bodies = len(window.doc.get("bodies", []))
    for path, message in [(tmp_path / "missing.csv", "cannot read the file: No such file or directory"),
                          (fifo, "it is a FIFO (named pipe), not a regular file"),
                          (damaged, "meshio cannot read this file"),
                          (empty, "the file is empty"),
                          (long, "the file has 20,001 points, more than the limit of 20,000 per outline")]:
        assert window.import_body(path, None, None) is False
        assert errors[-1].startswith(f"{path}: ") and message in errors[-1] and "\n" not in errors[-1], errors[-1]
    assert len(window.doc.get("bodies", [])) == bodies


def test_an_exported_picture_draws_each_structure_with_a_full_outline(window, make_results, tmp_path):
    from PIL import Image

    from app.render import render_frame

    path = make_results()
    summary = json.loads((path / "summary.json").read_text())
    summary["structures"] = [{"name": "wall", "polygon_m": [[0.5, 0.0], [0.56, 0.0], [0.56, 0.1], [0.5, 0.1]]}]
    (path / "summary.json").write_text(json.dumps(summary))
    assert window.open_results(path)  # the workbench's views have drawn in this process
    out = render_frame(path, path=tmp_path / "wall.png", size=(1600, 900))
    image = np.asarray(Image.open(out).convert("RGB")).astype(int)
    fill = np.all(np.abs(image - 180) <= 6, axis=2)  # the structure's grey (#b4b4b4)
    cols = np.nonzero(fill.sum(axis=0) > 50)[0]  # the wall's columns (not a stray grey pixel of a label)
    rows = np.nonzero(fill[:, cols].sum(axis=1) > 10)[0]
    row = image[(rows.min() + rows.max()) // 2]
    dark = np.all(np.abs(row - 80) <= 24, axis=1)  # its outline (#505050)
    edges = []
    for x in range(cols.min() - 6, cols.max() + 7):
        if dark[x] and (not edges or x > edges[-1][1] + 1):
            edges.append([x, x])
        elif dark[x]:
            edges[-1][1] = x
    widths = [b - a + 1 for a, b in edges]
    # both sides of the wall drawn at least 2 px wide (a wide line came out 1 px on one side)
    assert len(widths) == 2 and min(widths) >= 2, widths


SLOPE = [[0.0, 0.0], [16.0, 0.0], [16.0, 1.0], [8.0, 1.0], [4.0, 5.0], [0.0, 5.0]]  # the template's, 4 m high


def test_a_new_surcharge_goes_on_the_crest_and_its_table_shows_its_titles(window, tiny_file, qtbot):
    from app.gui.main_window import MainWindow

    window.resize(*MainWindow.DEFAULT_SIZE)
    window.open_project(tiny_file, ask=False)

    def slope(d):
        d["domain"].update(origin_m=[0.0, 0.0], size_m=[16.0, 6.25], cell_size_m=0.25)
        d["bodies"] = [dict(d["bodies"][0], polygon_m=SLOPE)]

    window.doc.edit("slope", slope)
    window.panels.setCurrentWidget(window.stages_panel)
    window.stages_panel.select(1)
    box = window.stages_panel.loads
    box.add_button.click()
    (load,) = window.doc.get("stages.1.surcharges")
    # on the crest (x 0 to 4 m), not over the middle of the bodies' width (6.4 to 9.6 m: the face
    # and the toe)
    assert (load["from_m"], load["to_m"]) == (1.0, 3.1)
    qtbot.wait(50)
    header = box.table.horizontalHeader()
    clipped = [box.table.horizontalHeaderItem(c).text() for c in range(box.table.columnCount())
               if header.sectionSizeFromContents(c).width() > header.sectionSize(c)]
    assert clipped == []
