"""The Sweep tab shows which runs ended with the mass still moving: a ``still_moving`` column, their
measures marked provisional (``*``, amber, the legend as tooltip) and counted in the header; a
folder written before sweep.csv had the column opens as before."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

pytestmark = pytest.mark.gui

MEASURE = "hazard.runout_distance_m"


def write_sweep(folder: Path, verdicts: list[str] | None) -> None:
    """Three completed runs and a failed one; ``verdicts``: their still_moving cells (None: no column)."""
    (folder / "runs").mkdir(parents=True)
    header = ["run", "run_id", "materials.sand.friction_angle_deg", MEASURE, "status", "message", "wall_time_s",
              "results_dir"]
    statuses = ["completed", "completed", "completed", "failed"]
    with open(folder / "sweep.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header + (["still_moving"] if verdicts is not None else []))
        for i, status in enumerate(statuses):
            row = [i, f"r{i}", 25 + i, repr(0.1 * (i + 1)) if status == "completed" else "", status, "", "1.5",
                   str(folder / "runs" / f"r{i}")]
            w.writerow(row + ([verdicts[i]] if verdicts is not None else []))
    (folder / "sweep.json").write_text(json.dumps({"kind": "sweep", "spec": {"sweep": {"measures": [MEASURE]}},
                                                   "settings": {}, "runs": []}))
    (folder / "progress.json").write_text(json.dumps({"done": 4, "total": 4, "failed": 1, "reused": 0,
                                                      "elapsed_s": 6.0, "eta_s": 0.0}))


def _column(view, name: str) -> list[str]:
    headers = [view.table.horizontalHeaderItem(c).text() for c in range(view.table.columnCount())]
    c = headers.index(name)
    return [view.table.item(r, c).text() for r in range(view.table.rowCount())]


def test_the_sweep_tab_marks_the_runs_that_ended_still_moving(window, tmp_path):
    from sweeps.folder import PROVISIONAL_LEGEND

    folder = tmp_path / "moving.sweep"
    write_sweep(folder, ["false", "true", "", "true"])
    assert window.open_sweep(folder)
    view = window.sweep_view
    assert _column(view, "still_moving") == ["no", "yes", "–", "yes"]
    measures = _column(view, MEASURE)
    assert not measures[0].endswith("*") and measures[1].endswith(" *") and not measures[2].endswith("*")
    assert measures[3] == "–"  # the failed run has no measure to mark
    headers = [view.table.horizontalHeaderItem(c).text() for c in range(view.table.columnCount())]
    item = view.table.item(1, headers.index(MEASURE))
    assert item.toolTip() == PROVISIONAL_LEGEND and item.background().color().name() == "#fff4e5"
    # only completed runs count: the failed run's verdict is not a provisional measure
    assert "1 ended still moving (measures provisional, *)" in view.header.text()
    # the plot against the parameter rings the provisional point (the second run's)
    view.parameter.setCurrentText("materials.sand.friction_angle_deg")
    key, x, y = view.measure_against_parameter()
    assert list(x) == [25.0, 26.0, 27.0]
    assert list(view.provisional_against_parameter()) == [False, True, False]
    labels = [line.get_label() for ax in view.figure.axes for line in ax.get_lines()]
    assert "1 ended still moving (provisional)" in labels


def test_a_sweep_folder_without_the_column_opens_as_before(window, tmp_path):
    folder = tmp_path / "old.sweep"
    write_sweep(folder, None)
    assert window.open_sweep(folder)
    view = window.sweep_view
    assert _column(view, "still_moving") == ["–"] * 4
    assert not any(m.endswith("*") for m in _column(view, MEASURE))
    assert "still moving" not in view.header.text()
    assert view.exceedance().n == 3
    view.parameter.setCurrentText("materials.sand.friction_angle_deg")
    assert not view.provisional_against_parameter().any()
