"""The Runout workbench: a PySide6 desktop application with embedded PyVista views.

``runout gui [PROJECT]`` calls :func:`main`. Qt, VTK and pyvistaqt are imported only here
and below (never by ``solver``, ``geometry`` or ``projects``), and only when the workbench starts.

Modules: :mod:`~app.gui.main_window` (the window), :mod:`~app.gui.document` (the project model
and its undo stack), :mod:`~app.gui.panels` and :mod:`~app.gui.fields` (the editors),
:mod:`~app.gui.scene_view` (the 2D model view and drawing), :mod:`~app.gui.run_process` and
:mod:`~app.gui.run_panel` (runs: each a ``runout run`` child process; this process never imports
Taichi), :mod:`~app.gui.results_view` and :mod:`~app.gui.curves`
(results), :mod:`~app.gui.dialogs`, :mod:`~app.gui.settings` (recent files, material library).
"""

from __future__ import annotations

import logging
import os
import sys
from pathlib import Path

logger = logging.getLogger(__name__)


def configure_environment() -> None:
    """Environment the embedded views need; call before Qt or VTK is imported."""
    # pyvistaqt goes through qtpy: make it pick PySide6 even when another binding is installed
    os.environ.setdefault("QT_API", "pyside6")


def main(project_path: str | os.PathLike[str] | None = None, argv: list[str] | None = None) -> int:
    """Start the workbench, optionally with a project file or a results folder open.

    Parameters
    ----------
    project_path : path-like, optional
        A project file (``.toml``) to open, or a results folder to inspect.
    argv : list of str, optional
        Arguments for Qt (default: the program name only).

    Returns
    -------
    int
        The application's exit status.
    """
    configure_environment()
    from PySide6.QtWidgets import QApplication

    from app.gui.main_window import MainWindow

    app = QApplication.instance() or QApplication(argv if argv is not None else sys.argv[:1])
    app.setApplicationName("Runout")
    app.setOrganizationName("Runout")
    window = MainWindow()
    window.show()
    if project_path is not None:
        path = Path(project_path)
        if path.is_dir():
            window.open_results(path)
        else:
            window.open_project(path, ask=False)
    return int(app.exec())


__all__ = ["main", "configure_environment"]
