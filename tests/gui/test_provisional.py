"""A run that ends with the mass still moving is not a final answer, and the workbench and the report
say so: the run's status (orange, "still moving", its kinetic energy as a fraction of its peak),
the Hazard tab (a provisional header, every measure marked) and the report's headline; a run that
came to rest is shown final. The runs are the tiny column's (tests/gui/conftest.py): 0.05 s into
its collapse, and the same run to rest."""

from __future__ import annotations

import json

import pytest
from PySide6.QtGui import QColor

from app.gui.run_panel import PROVISIONAL_COLOR
from tests.gui.conftest import _project_file

pytestmark = pytest.mark.gui

TO_REST = ["stages.1.duration_s=2.0", "output.interval_s=0.05", "stages.1.stop_when_kinetic_energy_below=0.01",
           "stages.1.stop_when_max_speed_below_m_s=0.01"]


def _run(window, qtbot, path):
    window.open_project(path)
    assert window.start_run()
    qtbot.waitUntil(lambda: not window.running, timeout=240_000)
    result = window.last_result
    assert result.status == "completed", result.message
    return result


def _values(table) -> list[str]:
    return [table.item(r, 1).text() for r in range(table.rowCount())]


def test_a_run_still_moving_at_its_end_is_shown_provisional(window, tiny_file, qtbot):
    result = _run(window, qtbot, tiny_file)
    m = result.summary["motion_at_end"]
    assert result.summary["still_moving"] is True
    panel = window.run_panel
    text = panel.status.text()
    assert text.startswith("completed, still moving: ")
    assert f"kinetic energy {m['kinetic_energy_fraction']:.2g}" in text and "of its peak" in text
    assert "every hazard measure of this run is provisional" in text
    assert PROVISIONAL_COLOR in panel.status.styleSheet()
    assert panel.progress.format() == "completed, still moving"
    item = panel.runs.item(0)
    assert "completed, still moving" in item.text() and item.foreground().color() == QColor(PROVISIONAL_COLOR)
    # the Hazard tab: a provisional header and every measure marked
    assert window.open_results(result.out_dir)
    view = window.hazard_view
    window.tabs.setCurrentWidget(view)
    assert view.path == result.out_dir
    assert "[completed]" in view.header.text() and "PROVISIONAL: still moving at the end" in view.header.text()
    values = [v for v in _values(view.measures) if v != "–"]
    assert values and all(v.endswith("(provisional)") for v in values)
    # the report's headline
    from app.report import write_report

    html = write_report(result.out_dir).read_text()
    assert "<b>Provisional answer:</b> still moving at the end" in html
    assert "of its peak" in html and "(provisional)</td>" in html


def test_a_run_that_came_to_rest_is_shown_final(window, tmp_path, qtbot):
    result = _run(window, qtbot, _project_file(tmp_path, "rest.toml", TO_REST))
    assert result.summary["still_moving"] is False
    text = window.run_panel.status.text()
    assert text.startswith("completed: stage 'collapse' ended by its rest criterion") and "provisional" not in text
    assert window.run_panel.progress.format() == "completed"
    assert window.open_results(result.out_dir)
    view = window.hazard_view
    assert "PROVISIONAL" not in view.header.text()
    assert not any(v.endswith("(provisional)") for v in _values(view.measures))
    hazard = json.loads((result.out_dir / "hazard.json").read_text())
    from app.report import headline

    assert headline(hazard, result.summary).startswith("<p class='final'><b>Final answer:</b> the mass came to rest")
