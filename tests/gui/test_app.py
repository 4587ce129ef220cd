"""The workbench as ``runout gui PROJECT`` starts it: app.gui.main opens the project and returns on quit."""

from __future__ import annotations

import threading

import pytest
from PySide6.QtCore import QTimer
from PySide6.QtWidgets import QApplication

from tests.conftest import KEPT_WIDGETS

pytestmark = pytest.mark.gui


def test_main_opens_the_project_and_returns_when_the_window_closes(qtbot, tiny_file, tmp_path, monkeypatch):
    from app.gui import main
    from app.gui.main_window import MainWindow

    monkeypatch.setenv("RUNOUT_CONFIG_DIR", str(tmp_path / "config"))
    from pyvista.plotting import plotter

    threads = threading.active_count()
    plotters = len(plotter._ALL_PLOTTERS)
    seen = {}

    def close_it():
        windows = [w for w in QApplication.topLevelWidgets() if isinstance(w, MainWindow) and w.isVisible()]
        seen["title"] = windows[0].windowTitle() if windows else None
        seen["bodies"] = len(windows[0].doc.get("bodies")) if windows else 0
        for w in windows:
            w.close()
            KEPT_WIDGETS.append(w)  # not deleted when main() returns: see tests/conftest.py

    QTimer.singleShot(1500, close_it)
    assert main(tiny_file) == 0
    assert seen == {"title": "tiny.toml[*] — Runout", "bodies": 1}
    assert threading.active_count() == threads
    assert len(plotter._ALL_PLOTTERS) == plotters
