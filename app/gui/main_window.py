"""The workbench's main window: the model view, project panels, the run panel and the results.

Layout: the project panels dock on the left, the run panel (what will run, progress, the runs
of this session, problems) on the right, and the centre holds three tabs: *Model* (the 2D scene
with drawing), *Results* (the followed run, live, then the inspector of its results folder) and
*Compare* (two results side by side, created when first used).

Runs are child processes (:class:`app.gui.run_process.RunProcess`, ``runout run --progress
jsonl``) writing their own folders; several may go on at once. The window follows one of them
by rereading its results folder with the same reader as any finished folder; this process
never imports Taichi.

All questions to the user go through small methods (``ask_save_changes``, ``ask_open_path``,
...) so that scripts and tests can answer them without a modal dialog.
"""

from __future__ import annotations

import logging
import os
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from PySide6.QtCore import QSize, Qt, QTimer, QUrl, qVersion
from PySide6.QtGui import QAction, QActionGroup, QCloseEvent, QDesktopServices, QKeySequence
from PySide6.QtWidgets import (
    QAbstractSpinBox,
    QApplication,
    QDialog,
    QDockWidget,
    QFileDialog,
    QLabel,
    QLineEdit,
    QMainWindow,
    QMessageBox,
    QProgressDialog,
    QTabWidget,
    QWidget,
)

from app.gui.dialogs import ExportDialog, ProblemsDialog, SlopeDialog
from app.gui.document import ProjectDocument, editable_data
from app.gui.fields import TypingUndo
from app.gui.panels import (
    BodiesPanel,
    DomainPanel,
    MaterialsPanel,
    NumericsPanel,
    OutputPanel,
    StagesPanel,
)
from app.gui.results_view import CompareView, ResultsView
from app.gui.run_panel import RunPanel
from app.gui.run_process import RunOutcome, RunProcess
from app.gui.scene_view import SceneView
from app.gui.settings import MaterialLibrary, Settings
from projects.schema import ProjectError

logger = logging.getLogger(__name__)

APP_NAME = "Runout"
PROJECT_FILTER = "Runout project (*.toml);;All files (*)"
#: Shortest time between two live frames drawn during a run (ms).
LIVE_INTERVAL_MS = 200
#: Interval of rereading the followed run's folder between frame events (ms).
POLL_MS = 500


#: Where the documentation is read online when the workbench runs from an installed package.
DOCS_ONLINE = "https://github.com/runout/runout/blob/main/docs/gui.md"


def documentation_url() -> QUrl:
    """The workbench's manual: ``docs/gui.md`` of the checkout it runs from, else online."""
    local = Path(__file__).resolve().parents[2] / "docs" / "gui.md"
    return QUrl.fromLocalFile(str(local)) if local.is_file() else QUrl(DOCS_ONLINE)


def _gravity_for_slopes(data: dict[str, Any]) -> list[str]:
    """Replace a k0 initial stage by gravity loading where the ground slopes
    (:func:`projects.sections.gravity_for_slopes`); what was changed."""
    from projects.sections import gravity_for_slopes

    return gravity_for_slopes(data)


class MainWindow(QMainWindow):
    """The Runout workbench.

    Parameters
    ----------
    settings : Settings, optional
        Recent files and measured throughput (default: the user's config folder).
    library : MaterialLibrary, optional
        The named-material library (default: the user's config folder).
    """

    #: The size a new window opens at (pixels).
    DEFAULT_SIZE = (1500, 900)

    def __init__(self, settings: Settings | None = None, library: MaterialLibrary | None = None) -> None:
        super().__init__()
        self.settings = settings or Settings()
        self.library = library or MaterialLibrary(self.settings.folder)
        self.doc = ProjectDocument(parent=self)
        self.runs: list[RunProcess] = []
        self.followed: RunProcess | None = None
        self.last_run: RunProcess | None = None
        self._live_frames = 0
        self.last_result: RunOutcome | None = None
        self.compare: CompareView | None = None
        self._shut = False
        self.setWindowTitle(APP_NAME)
        self.resize(*self.DEFAULT_SIZE)

        self.scene = SceneView(self.doc)
        self.results_view = ResultsView()
        self.tabs = QTabWidget()
        self.tabs.addTab(self.scene, "Model")
        self.tabs.addTab(self.results_view, "Results")
        self.setCentralWidget(self.tabs)

        self.panels = QTabWidget()
        self.domain_panel = DomainPanel(self.doc)
        self.materials_panel = MaterialsPanel(self.doc, self.library)
        self.bodies_panel = BodiesPanel(self.doc)
        self.numerics_panel = NumericsPanel(self.doc)
        self.stages_panel = StagesPanel(self.doc)
        self.stages_panel.stageChosen.connect(self.scene.set_loads_stage)  # the scene draws its loads
        self.scene.set_loads_stage(self.stages_panel.current)
        self.output_panel = OutputPanel(self.doc)
        for panel, title in ((self.domain_panel, "Domain"), (self.materials_panel, "Materials"),
                             (self.bodies_panel, "Bodies"), (self.numerics_panel, "Numerics"),
                             (self.stages_panel, "Stages"), (self.output_panel, "Output")):
            self.panels.addTab(panel, title)
        self._add_object_panels()
        self.panels.setUsesScrollButtons(True)
        left = QDockWidget("Project", self)
        left.setObjectName("project-dock")
        left.setWidget(self.panels)
        movable = QDockWidget.DockWidgetFeature.DockWidgetMovable | QDockWidget.DockWidgetFeature.DockWidgetFloatable
        left.setFeatures(movable)
        left.setMinimumWidth(380)
        self.addDockWidget(Qt.DockWidgetArea.LeftDockWidgetArea, left)

        self.run_panel = RunPanel(self.doc, self.settings)
        right = QDockWidget("Run", self)
        right.setObjectName("run-dock")
        right.setWidget(self.run_panel)
        right.setFeatures(movable)
        right.setMinimumWidth(280)
        self.addDockWidget(Qt.DockWidgetArea.RightDockWidgetArea, right)
        self.run_dock = right

        self.cursor_label = QLabel("")
        self.statusBar().addPermanentWidget(self.cursor_label)
        self._build_actions()
        self._connect()
        self._estimate_timer = QTimer(self)
        self._estimate_timer.setSingleShot(True)
        self._estimate_timer.setInterval(150)
        self._estimate_timer.timeout.connect(self.run_panel.update_estimate)
        # the followed run's folder is reread after a frame event (at most every LIVE_INTERVAL_MS)
        # and, because frames reach the disk a little after their event, every POLL_MS
        self._refresh_timer = QTimer(self)
        self._refresh_timer.setSingleShot(True)
        self._refresh_timer.setInterval(LIVE_INTERVAL_MS)
        self._refresh_timer.timeout.connect(self._refresh_live)
        self._poll_timer = QTimer(self)
        self._poll_timer.setInterval(POLL_MS)
        self._poll_timer.timeout.connect(self._refresh_live)
        self._update_title()
        self.run_panel.update_estimate()
        self._add_analysis()

    # -- construction -----------------------------------------------------------------------------

    def _action(self, text: str, slot: Any, shortcut: Any = None, tip: str = "", checkable: bool = False) -> QAction:
        action = QAction(text, self)
        if shortcut is not None:
            action.setShortcut(QKeySequence(shortcut))
        if tip:
            action.setStatusTip(tip)
            action.setToolTip(tip)
        action.setCheckable(checkable)
        (action.toggled if checkable else action.triggered).connect(slot)
        return action

    def _build_actions(self) -> None:
        style = self.style()
        from PySide6.QtWidgets import QStyle

        a = self.actions_ = {}
        a["new"] = self._action("&New project", self.new_project, QKeySequence.StandardKey.New)
        a["open"] = self._action("&Open project…", self.open_project_dialog, QKeySequence.StandardKey.Open)
        a["open_results"] = self._action("Open &results…", self.open_results_dialog, "Ctrl+Shift+O",
                                         "Open a results folder (also one written by runout run)")
        a["save"] = self._action("&Save", self.save, QKeySequence.StandardKey.Save)
        a["save_as"] = self._action("Save &as…", self.save_as, QKeySequence.StandardKey.SaveAs)
        a["export_picture"] = self._action("Export &picture…", self.export_picture_dialog,
                                           tip="Render the shown frame offscreen at a chosen size")
        a["export_movie"] = self._action("Export &animation…", self.export_animation_dialog,
                                         tip="Write all frames as mp4 or gif")
        a["export_curves"] = self._action("Export &curves (CSV)…", self.export_curves_dialog)
        a["quit"] = self._action("&Quit", self.close, QKeySequence.StandardKey.Quit)
        a["new"].setIcon(style.standardIcon(QStyle.StandardPixmap.SP_FileIcon))
        a["open"].setIcon(style.standardIcon(QStyle.StandardPixmap.SP_DialogOpenButton))
        a["save"].setIcon(style.standardIcon(QStyle.StandardPixmap.SP_DialogSaveButton))
        undo = self.doc.undo_stack.createUndoAction(self, "&Undo")
        undo.setShortcut(QKeySequence.StandardKey.Undo)
        undo.setIcon(style.standardIcon(QStyle.StandardPixmap.SP_ArrowBack))
        redo = self.doc.undo_stack.createRedoAction(self, "&Redo")
        redo.setShortcut(QKeySequence.StandardKey.Redo)
        redo.setIcon(style.standardIcon(QStyle.StandardPixmap.SP_ArrowForward))
        a["undo"], a["redo"] = undo, redo
        a["select"] = self._action("&Select / edit", lambda on: on and self.scene.set_mode("select"), "S",
                                   "Select bodies, drag vertices, pan", checkable=True)
        a["draw"] = self._action("&Draw body", lambda on: on and self._start_drawing(), "D",
                                 "Click vertices of a new body in the view", checkable=True)
        group = QActionGroup(self)
        group.addAction(a["select"])
        group.addAction(a["draw"])
        a["select"].setChecked(True)
        a["snap"] = self._action("S&nap to grid", self.scene.set_snap, None, "Snap vertices to half cells",
                                 checkable=True)
        a["snap"].setChecked(True)
        a["particles"] = self._action("Show &particles", self.scene.set_show_particles, None,
                                      "Preview the seeded particles", checkable=True)
        a["particles"].setChecked(True)
        a["fit"] = self._action("&Fit view", self.scene.fit, "F")
        a["slope"] = self._action("Slope from &template…", self.slope_dialog)
        a["import_body"] = self._action("&Import slope profile…", self.import_body_dialog, "Ctrl+I",
                                        "A body from a CSV or DXF profile (closed down to a base) or a mesh outline")
        a["delete_vertex"] = self._action("Delete &vertex", self.scene.delete_selected_vertex)
        a["run"] = self._action("&Run", self.start_run, "F5", "Run the project in the background")
        a["run"].setIcon(style.standardIcon(QStyle.StandardPixmap.SP_MediaPlay))
        a["cancel"] = self._action("&Cancel run", self.cancel_run, "Shift+F5")
        a["cancel"].setIcon(style.standardIcon(QStyle.StandardPixmap.SP_MediaStop))
        a["cancel"].setEnabled(False)
        a["resume"] = self._action("Res&ume run", lambda: self.resume_run(), None,
                                   "Continue the shown run, killed or stopped, from its last checkpoint (runout run "
                                   "--resume)")
        a["resume"].setEnabled(False)
        a["compare"] = self._action("&Compare results…", self.show_compare)

        bar = self.menuBar()
        file_menu = bar.addMenu("&File")
        file_menu.addActions([a["new"], a["open"]])
        self.recent_menu = file_menu.addMenu("Open &recent")
        self.recent_menu.aboutToShow.connect(self._fill_recent)
        file_menu.addAction(a["open_results"])
        self.recent_results_menu = file_menu.addMenu("Recent r&esults")
        self.recent_results_menu.aboutToShow.connect(self._fill_recent_results)
        file_menu.addSeparator()
        file_menu.addActions([a["save"], a["save_as"]])
        file_menu.addSeparator()
        file_menu.addActions([a["export_picture"], a["export_movie"], a["export_curves"]])
        file_menu.addSeparator()
        file_menu.addAction(a["quit"])
        edit = bar.addMenu("&Edit")
        edit.addActions([undo, redo])
        edit.addSeparator()
        edit.addAction(a["delete_vertex"])
        model = bar.addMenu("&Model")
        model.addActions([a["select"], a["draw"], a["snap"], a["particles"], a["fit"]])
        model.addSeparator()
        model.addActions([a["slope"], a["import_body"]])
        run = bar.addMenu("&Run")
        run.addActions([a["run"], a["cancel"], a["resume"]])
        view = bar.addMenu("&View")
        view.addAction(a["compare"])
        help_menu = bar.addMenu("&Help")
        a["docs"] = self._action("&Documentation", self.open_documentation, QKeySequence.StandardKey.HelpContents,
                                 "The workbench's manual (docs/gui.md) and the project-file reference")
        a["about"] = self._action("&About Runout", self._about)
        help_menu.addActions([a["docs"], a["about"]])

        tools = self.addToolBar("Main")
        tools.setObjectName("main-toolbar")
        tools.setIconSize(QSize(18, 18))
        tools.setToolButtonStyle(Qt.ToolButtonStyle.ToolButtonTextBesideIcon)
        tools.addActions([a["new"], a["open"], a["save"]])
        tools.addSeparator()
        tools.addActions([undo, redo])
        tools.addSeparator()
        tools.addActions([a["select"], a["draw"], a["snap"], a["particles"], a["fit"]])
        tools.addSeparator()
        tools.addActions([a["run"], a["cancel"]])

    def _connect(self) -> None:
        doc = self.doc
        # Ctrl+Z in a text field undoes its typing, elsewhere (or with none) the project's step
        self._typing_undo = TypingUndo(self)
        QApplication.instance().focusChanged.connect(self._watch_typing)
        doc.cleanChanged.connect(lambda _c: self._update_title())
        doc.pathChanged.connect(self._update_title)
        doc.changed.connect(lambda _s: self._estimate_timer.start())
        self.scene.cursorMoved.connect(lambda x, y: self.cursor_label.setText(f"x = {x:.3f} m   y = {y:.3f} m"))
        self.scene.message.connect(lambda text: self.statusBar().showMessage(text, 6000))
        self.scene.modeChanged.connect(self._mode_changed)
        self.results_view.message.connect(lambda text: text and self.statusBar().showMessage(text, 6000))
        self.bodies_panel.drawRequested.connect(lambda: self.actions_["draw"].setChecked(True))
        self.bodies_panel.templateRequested.connect(self.slope_dialog)
        self.run_panel.runRequested.connect(self.start_run)
        self.run_panel.resumeRequested.connect(lambda: self.resume_run())
        # each structure's peak force from the results shown, in the Structures list
        self.results_view.forcesShown.connect(lambda rows, path: self.structures_panel.set_forces(rows, path))
        self.run_panel.cancelRequested.connect(self.cancel_run)
        self.run_panel.problemActivated.connect(self.go_to_problem)
        self.run_panel.runSelected.connect(self._select_run)
        self.run_panel.removeUnknownRequested.connect(self.remove_unknown_keys)

    def _add_object_panels(self) -> None:
        """The Structures and Targets panels (after Bodies), linked to the scene view's selection."""
        from app.gui.object_panels import StructuresPanel, TargetsPanel

        self.structures_panel = StructuresPanel(self.doc)
        self.targets_panel = TargetsPanel(self.doc)
        at = self.panels.indexOf(self.bodies_panel) + 1
        self.panels.insertTab(at, self.structures_panel, "Structures")
        self.panels.insertTab(at + 1, self.targets_panel, "Targets")
        self.structures_panel.drawRequested.connect(self._start_drawing_structure)
        from app.gui.water_panel import WaterPanel

        self.water_panel = WaterPanel(self.doc)
        self.panels.insertTab(at + 2, self.water_panel, "Water")
        self.water_panel.drawRequested.connect(self._start_drawing_water)
        self.doc.selection.changed.connect(self._show_selection_panel)

    def _show_selection_panel(self) -> None:
        """A body, structure or target picked in the view brings its panel forward."""
        sel = self.doc.selection
        panel = {"bodies": self.bodies_panel, "structures": self.structures_panel,
                 "targets": self.targets_panel, "water": self.water_panel}.get(sel.kind)
        if sel.index is not None and panel is not None and self.panels.currentWidget() is not panel:
            self.panels.setCurrentWidget(panel)

    def _start_drawing_water(self, slot: int) -> None:
        self.tabs.setCurrentWidget(self.scene)
        self.scene.set_mode("draw", "water", slot)

    def _start_drawing_structure(self) -> None:
        self.tabs.setCurrentWidget(self.scene)
        self.scene.set_mode("draw", "structures")

    def _mode_changed(self, mode: str) -> None:
        self.actions_["draw" if mode == "draw" else "select"].setChecked(True)

    def _start_drawing(self) -> None:
        self.tabs.setCurrentWidget(self.scene)
        self.scene.set_mode("draw")

    def _update_title(self) -> None:
        self.setWindowTitle(f"{self.doc.display_name}[*] — {APP_NAME}")
        self.setWindowModified(self.doc.is_dirty)
        default = self._default_out_dir()
        self.run_panel.out_dir.setPlaceholderText(str(default))

    def about_text(self) -> str:
        """Version and where the documentation is (Help ▸ About)."""
        from projects.results import runout_version

        docs = documentation_url()
        return (f"<b>Runout {runout_version()}</b><br>Landslide run-out analysis with the material point method."
                f"<br><br>Documentation: <a href=\"{docs.toString()}\">{docs.toString()}</a>"
                f"<br>Python {sys.version.split()[0]}, Qt {qVersion()}")

    def _about(self) -> None:
        QMessageBox.about(self, "About Runout", self.about_text())

    def open_documentation(self) -> bool:
        """Open the manual in the desktop's viewer (Help ▸ Documentation)."""
        return bool(QDesktopServices.openUrl(documentation_url()))

    # -- questions (replaceable in scripts and tests) -----------------------------------------------

    def ask_save_changes(self) -> str:
        """"save", "discard" or "cancel" for unsaved changes."""
        answer = QMessageBox.question(
            self, APP_NAME, f"{self.doc.display_name} has unsaved changes. Save them?",
            QMessageBox.StandardButton.Save | QMessageBox.StandardButton.Discard | QMessageBox.StandardButton.Cancel,
            QMessageBox.StandardButton.Save,
        )
        return {QMessageBox.StandardButton.Save: "save", QMessageBox.StandardButton.Discard: "discard"}.get(
            answer, "cancel")

    def ask_open_path(self) -> str | None:
        start = str(self.doc.path.parent) if self.doc.path else str(Path.cwd())
        path, _ = QFileDialog.getOpenFileName(self, "Open project", start, PROJECT_FILTER)
        return path or None

    def ask_save_path(self) -> str | None:
        start = str(self.doc.path) if self.doc.path else str(Path.cwd() / "untitled.toml")
        path, _ = QFileDialog.getSaveFileName(self, "Save project as", start, PROJECT_FILTER)
        if path and not path.endswith(".toml"):
            path += ".toml"
        return path or None

    def ask_results_path(self) -> str | None:
        start = str(self._default_out_dir().parent)
        return QFileDialog.getExistingDirectory(self, "Open results folder", start) or None

    def ask_stop_run(self) -> bool:
        answer = QMessageBox.question(self, APP_NAME, "A run is in progress. Stop it and quit?")
        return answer == QMessageBox.StandardButton.Yes

    def ask_save_invalid(self) -> bool:
        answer = QMessageBox.question(
            self, APP_NAME,
            f"The project has {len(self.doc.problems)} problem(s) and will not run until they are fixed. "
            "Save it anyway?")
        return answer == QMessageBox.StandardButton.Yes

    def show_error(self, title: str, text: str) -> None:
        QMessageBox.warning(self, title, text)

    def show_project_problems(self, path: Path, error: ProjectError, can_open: bool) -> bool:
        """List what is wrong with a project file; True when the user wants to open it anyway."""
        dialog = ProblemsDialog(
            f"Cannot open {path.name}",
            f"{path} has {len(error.problems)} problem(s):" if len(error.problems) != 1 else f"{path}:",
            [str(p) for p in error.problems], can_open, self)
        dialog.exec()
        return dialog.open_anyway

    # -- files ----------------------------------------------------------------------------------------

    def maybe_save(self) -> bool:
        """True when it is fine to replace the document (saved, discarded, or nothing to lose)."""
        if not self.doc.is_dirty:
            return True
        answer = self.ask_save_changes()
        if answer == "save":
            return self.save()
        return answer == "discard"

    def new_project(self) -> bool:
        if not self.maybe_save():
            return False
        from app.gui.document import new_project_data

        self.doc.reset(new_project_data())
        self.statusBar().showMessage("New project: draw a body (Model ▸ Draw body) or use Slope from template", 8000)
        self.tabs.setCurrentWidget(self.scene)
        return True

    def open_project_dialog(self) -> bool:
        if not self.maybe_save():
            return False
        path = self.ask_open_path()
        return self.open_project(path, ask=False) if path else False

    def open_project(self, path: str | os.PathLike[str], ask: bool = True) -> bool:
        """Open a project file; its problems are listed (and may be fixed here) instead of a traceback."""
        if ask and not self.maybe_save():
            return False
        path = Path(path)
        try:
            self.doc.open(path)
        except ProjectError as err:
            can_open = self._editable(path)
            if self.show_project_problems(path, err, can_open):
                try:
                    self.doc.open(path, allow_problems=True)
                except ProjectError as again:
                    self.show_error(f"Cannot open {path.name}", str(again))
                    return False
            else:
                return False
        self.settings.add_recent(path, "projects")
        self.run_panel.out_dir.clear()
        self.tabs.setCurrentWidget(self.scene)
        self.scene.fit()
        self.statusBar().showMessage(f"Opened {path}", 5000)
        return True

    def _editable(self, path: Path) -> bool:
        from projects.document import parse_toml

        try:
            return editable_data(parse_toml(path.read_text(encoding="utf-8"))) is not None
        except (ProjectError, OSError, UnicodeDecodeError):
            return False

    def commit_typing(self) -> None:
        """Commit what the focused field holds (a shortcut such as Ctrl+S does not end its editing,
        so its typing would not yet be in the project)."""
        from app.gui.fields import _Bound

        widget = QApplication.focusWidget()
        while widget is not None and not isinstance(widget, _Bound):
            widget = widget.parentWidget()
        if widget is not None:
            commit = getattr(widget, "commit", None) or getattr(widget, "_commit", None)
            if callable(commit):
                commit()

    def _refuse_red_fields(self, what: str) -> bool:
        """True (and the user told why) when fields are red: their values are not in the project,
        so saving or running would use the previous ones."""
        invalid = self.invalid_fields()
        if not invalid:
            return False
        self.statusBar().showMessage(f"Not saved: {len(invalid)} field(s) hold values that are not valid"
                                     if what == "save" else "Not run: fields hold values that are not valid", 8000)
        self.show_error(f"Cannot {what}", "These fields hold values that are not valid (shown red); the "
                        f"project still has the previous values, which the file would get. Correct them (or undo "
                        f"the typing) before you {what}:\n" + "\n".join(invalid))
        return True

    def save(self) -> bool:
        self.commit_typing()
        if self._refuse_red_fields("save"):
            return False
        if self.doc.path is None:
            return self.save_as()
        return self._save_to(self.doc.path)

    def save_as(self) -> bool:
        self.commit_typing()
        if self._refuse_red_fields("save"):
            return False
        path = self.ask_save_path()
        return self._save_to(Path(path)) if path else False

    def _save_to(self, path: Path) -> bool:
        force = False
        if self.doc.project is None:
            if not self.ask_save_invalid():
                return False
            force = True
        try:
            self.doc.save(path, force=force)
        except OSError as err:
            self.show_error("Cannot save", f"{path}: {err.strerror or err}")
            return False
        self.settings.add_recent(path, "projects")
        self.statusBar().showMessage(f"Saved {path}", 5000)
        return True

    def _fill_recent(self) -> None:
        self.recent_menu.clear()
        items = self.settings.recent("projects")
        if not items:
            self.recent_menu.addAction("(none)").setEnabled(False)
        for path in items:
            self.recent_menu.addAction(path).triggered.connect(lambda _c=False, p=path: self.open_project(p))

    def _fill_recent_results(self) -> None:
        self.recent_results_menu.clear()
        items = self.settings.recent("results")
        if not items:
            self.recent_results_menu.addAction("(none)").setEnabled(False)
        for path in items:
            self.recent_results_menu.addAction(path).triggered.connect(lambda _c=False, p=path: self.open_results(p))

    # -- results ---------------------------------------------------------------------------------------

    def open_results_dialog(self) -> bool:
        path = self.ask_results_path()
        return self.open_results(path) if path else False

    def open_results(self, path: str | os.PathLike[str]) -> bool:
        from projects.results import ResultsError

        try:
            self.results_view.open_results(path)
        except (ResultsError, OSError) as err:
            self.show_error("Cannot open results", str(err))
            return False
        self._unfollow()
        self.settings.add_recent(path, "results")
        self.tabs.setCurrentWidget(self.results_view)
        self._update_resume()
        return True

    def _unfollow(self) -> None:
        """Stop showing a run (it goes on, listed in the run panel, where it can be chosen again)."""
        if self.followed is None:
            return
        self.followed = None
        self._refresh_timer.stop()
        self._poll_timer.stop()
        self.actions_["cancel"].setEnabled(False)
        self.run_panel.set_running(False)
        self.run_panel.runs.blockSignals(True)
        self.run_panel.runs.setCurrentRow(-1)
        self.run_panel.runs.blockSignals(False)

    def show_compare(self) -> CompareView:
        if self.compare is None:
            self.compare = CompareView()
            for side, button in enumerate(self.compare.open_buttons):
                button.clicked.connect(lambda _c=False, s=side: self._compare_open(s))
            self.tabs.addTab(self.compare, "Compare")
        self.tabs.setCurrentWidget(self.compare)
        return self.compare

    def _compare_open(self, side: int) -> None:
        from projects.results import ResultsError

        path = self.ask_results_path()
        if not path or self.compare is None:
            return
        try:
            self.compare.open_results(side, path)
        except (ResultsError, OSError) as err:
            self.show_error("Cannot open results", str(err))

    def _export_path(self, suffix: str) -> Path:
        """Default file of an export: beside the results folder, never inside it (a re-run may
        replace the folder)."""
        results = self.results_view.results
        field = self.results_view.controls.field_name
        if results is None:
            return Path.cwd() / f"{field}_{self.results_view.frame_index:05d}{suffix}"
        folder = Path(results.path)
        return folder.parent / f"{folder.stem}_{field}_{self.results_view.frame_index:05d}{suffix}"

    def export_picture_dialog(self) -> None:
        if self.results_view.results is None:
            self.show_error("Nothing to export", "Open a results folder (or run the project) first.")
            return
        dialog = ExportDialog("picture", self._export_path(".png"), self)
        if dialog.exec() != QDialog.DialogCode.Accepted:
            return
        QApplication.setOverrideCursor(Qt.CursorShape.WaitCursor)
        try:
            path = self.results_view.export_screenshot(dialog.path.text(), dialog.size_px)
        except (ValueError, OSError) as err:
            self.show_error("Export failed", str(err))
            return
        finally:
            QApplication.restoreOverrideCursor()
        self.statusBar().showMessage(f"Wrote {path}", 6000)

    def export_animation_dialog(self) -> None:
        if self.results_view.results is None:
            self.show_error("Nothing to export", "Open a results folder (or run the project) first.")
            return
        frame_png = self._export_path(".png")
        movie = frame_png.with_name(frame_png.stem.rsplit("_", 1)[0] + ".mp4")  # without the frame number
        dialog = ExportDialog("movie", movie, self)
        if dialog.exec() != QDialog.DialogCode.Accepted:
            return
        self.export_animation(dialog.path.text(), dialog.fps.value(), dialog.size_px)

    def export_animation(self, path: str | os.PathLike[str], fps: float, size: tuple[int, int]) -> Path | None:
        """Write every frame as a movie with a progress dialog that can cancel it (the partial
        file is removed); None when cancelled or failed (the user was told)."""
        n = len(self.results_view.results) if self.results_view.results is not None else 0
        progress = QProgressDialog("Rendering frames…", "Cancel", 0, max(n, 1), self)
        progress.setWindowTitle("Export animation")
        progress.setWindowModality(Qt.WindowModality.WindowModal)
        progress.setMinimumDuration(0)
        progress.setValue(0)
        progress.show()
        self.export_progress = progress
        QApplication.processEvents()

        class Cancelled(Exception):
            pass

        def step(done: int, total: int) -> None:
            progress.setMaximum(total)
            progress.setValue(done)
            progress.setLabelText(f"Rendering frame {done} of {total}…")
            QApplication.processEvents()
            if progress.wasCanceled():
                raise Cancelled

        target = Path(path)
        try:
            written = self.results_view.export_animation(target, fps, size, step)
        except Cancelled:
            target.unlink(missing_ok=True)
            self.statusBar().showMessage("Export cancelled; no movie written", 6000)
            return None
        except (ValueError, OSError) as err:
            self.show_error("Export failed", str(err))
            return None
        finally:
            progress.close()
        self.statusBar().showMessage(f"Wrote {written}", 6000)
        return written

    def export_curves_dialog(self) -> None:
        frame_csv = self._export_path(".csv")
        start = str(frame_csv.with_name(frame_csv.stem.rsplit("_", 2)[0] + "_curves.csv"))
        path, _ = QFileDialog.getSaveFileName(self, "Export curves", start, "CSV (*.csv)")
        if not path:
            return
        try:
            written = self.results_view.export_curves(path)
        except (ValueError, OSError) as err:
            self.show_error("Export failed", str(err))
            return
        self.statusBar().showMessage(f"Wrote {written}", 6000)

    # -- model tools ----------------------------------------------------------------------------------

    def slope_dialog(self) -> bool:
        dialog = SlopeDialog(self.doc.material_names, self)
        if dialog.exec() != QDialog.DialogCode.Accepted:
            return False
        return self.apply_slope(dialog)

    def apply_slope(self, dialog: SlopeDialog) -> bool:
        """Put the dialog's slope into the project (one undo step, with the domain if asked)."""
        try:
            bodies = dialog.bodies()
        except ValueError as err:
            self.show_error("Slope from template", str(err))
            return False
        cell = self.doc.get("domain.cell_size_m")
        cell = float(cell) if isinstance(cell, (int, float)) and cell > 0 else 0.25
        replace, fit = dialog.replace.isChecked(), dialog.fit_domain.isChecked()
        if fit:
            bodies, origin, size = dialog.fit(bodies, cell)

        def mutate(d: dict[str, Any]) -> None:
            existing = [] if replace else list(d.get("bodies", []))
            names = {b.get("name") for b in existing}
            for body in bodies:
                while body["name"] in names:
                    body["name"] += "-2"
                names.add(body["name"])
            d["bodies"] = existing + bodies
            if fit:
                d["domain"]["origin_m"] = origin
                d["domain"]["size_m"] = size
            changed.extend(_gravity_for_slopes(d))

        changed: list[str] = []
        self.doc.edit("slope from template", mutate)
        self.doc.selection.set(None)
        self.scene.fit()
        if changed:
            self.statusBar().showMessage(changed[0], 10000)
        return True

    def remove_unknown_keys(self) -> list[str]:
        """Remove the keys the schema does not know (typos from a file) as one undo step."""
        removed = self.doc.remove_unknown_keys()
        if removed:
            self.statusBar().showMessage("Removed unknown keys: " + ", ".join(removed), 8000)
        return removed

    def ask_import(self) -> tuple[str, str, float | None] | None:
        """The file, the material and the base height (None: the profile's lowest point) of an import."""
        from PySide6.QtWidgets import QInputDialog

        from app.gui.imports import IMPORT_FILTER

        start = str(self.doc.path.parent) if self.doc.path else str(Path.cwd())
        path, _ = QFileDialog.getOpenFileName(self, "Import slope profile", start, IMPORT_FILTER)
        if not path:
            return None
        names = self.doc.material_names or ["soil"]
        material, ok = QInputDialog.getItem(self, "Import slope profile", "Material of the new body", names, 0, False)
        if not ok:
            return None
        text, ok = QInputDialog.getText(self, "Import slope profile",
                                        "Base height of an open profile (m; empty: its lowest point)")
        if not ok:
            return None
        from app.gui.units import parse_quantity

        base, _err = parse_quantity(text, "m") if text.strip() else (None, "")
        return path, material, base

    def import_body_dialog(self) -> bool:
        answer = self.ask_import()
        return self.import_body(*answer) if answer else False

    def import_body(self, path: str | os.PathLike[str], material: str | None = None,
                    base_y_m: float | None = None) -> bool:
        """Add a section from a CSV or DXF profile (several layers: a body of its own material each)
        or a mesh outline, standing on its supports (one undo step, :func:`projects.sections.place_section`):
        the domain fitted to it (the base under it, its ends on the side walls), gravity loading
        where the ground slopes, a cell size the estimate can afford at this machine's throughput."""
        from geometry.importers import read_layers
        from projects.schema import MAX_POLYGON_POINTS
        from projects.sections import place_section

        try:
            # the file is checked before it is opened (missing, a FIFO or a device, empty, too
            # large) and its lines counted before any geometry: one line naming the file, as the
            # command line's readers say it (projects.inputs)
            layers = read_layers(path, base_y_m, max_points=MAX_POLYGON_POINTS)
        except (ValueError, OSError) as err:
            self.show_error("Cannot import", str(err))
            return False
        except Exception as err:  # a reader's own failure on a damaged file: one line, not a traceback
            logger.exception("import of %s", path)
            self.show_error("Cannot import", f"{os.fspath(path)}: cannot import this file ({type(err).__name__}: {err})")
            return False
        material = material or (self.doc.material_names[0] if self.doc.material_names else "soil")
        name = Path(path).stem
        rate, _measured = self.settings.throughput(self.run_panel.arch())
        notes: list[str] = []

        def mutate(d: dict[str, Any]) -> None:
            notes[:] = place_section(d, layers, material, particle_steps_per_s=rate)

        self.doc.edit(f"import {name}", mutate)
        self.doc.selection.set(len(self.doc.get("bodies", [])) - 1)
        self.tabs.setCurrentWidget(self.scene)
        self.scene.fit()
        self.statusBar().showMessage("; ".join(notes), 15000)
        return True

    def go_to_problem(self, path: str) -> None:
        """Show the panel (and item) a problem's key path names."""
        parts = path.split(".")
        section = parts[0] if parts else ""
        if section == "water" or (section == "stages" and len(parts) > 2 and parts[2] == "water"):
            from app.gui.document import WATER_LINE_KEYS, water_slot

            stage = int(parts[1]) if section == "stages" and parts[1].isdigit() else None
            key = next((p for p in parts if p in WATER_LINE_KEYS), "phreatic_line_m")
            self.panels.setCurrentWidget(self.water_panel)
            self.water_panel.choose(water_slot(stage, key))
            return
        target = {"runout": self.domain_panel, "domain": self.domain_panel, "materials": self.materials_panel,
                  "bodies": self.bodies_panel, "particles": self.numerics_panel, "numerics": self.numerics_panel,
                  "stages": self.stages_panel, "output": self.output_panel,
                  "structures": self.structures_panel, "targets": self.targets_panel}.get(section)
        if target is None:
            return
        self.panels.setCurrentWidget(target)
        if section == "materials" and len(parts) > 1:
            self.materials_panel.select(parts[1])
        elif section == "bodies" and len(parts) > 1 and parts[1].isdigit():
            vertex = int(parts[3]) if len(parts) > 3 and parts[3].isdigit() else None
            self.doc.selection.set(int(parts[1]), vertex)
        elif section in ("structures", "targets") and len(parts) > 1 and parts[1].isdigit():
            vertex = int(parts[3]) if len(parts) > 3 and parts[3].isdigit() else None
            self.doc.selection.select(section, int(parts[1]), vertex)
        elif section == "stages" and len(parts) > 1 and parts[1].isdigit():
            self.stages_panel.select(int(parts[1]))

    # -- runs -------------------------------------------------------------------------------------------

    def _default_out_dir(self) -> Path:
        from projects.runner import default_results_dir

        if self.doc.path is not None:
            return default_results_dir(self.doc.path)
        return Path(tempfile.gettempdir()) / f"runout-untitled-{os.getpid()}.results"

    def out_dir(self) -> Path:
        text = self.run_panel.out_dir.text().strip()
        return Path(text).expanduser() if text else self._default_out_dir()

    @property
    def running(self) -> bool:
        """Whether any run of this window is still going on."""
        return any(run.is_running() for run in self.runs)

    def invalid_fields(self) -> list[str]:
        """Editors shown red (a typed value the schema refuses, not written to the project):
        one line each, naming the field, its key and what is wrong."""
        from app.gui.fields import _Bound

        lines = []
        for editor in self.findChildren(_Bound):
            error = getattr(editor, "error", "")
            if error and editor.path:
                lines.append(f"{editor.label} ({editor.path}): {error}")
        return lines

    def ask_replace_results(self, path: Path) -> str:
        """"replace", "new" (a new folder beside it) or "cancel" for an existing results folder."""
        box = QMessageBox(QMessageBox.Icon.Question, APP_NAME,
                          f"{path} holds the results of an earlier run. Replace them (only the files that "
                          "run wrote are removed; pictures and notes you put there stay) or write this run "
                          "to a new folder beside it?",
                          parent=self)
        new = box.addButton("New folder", QMessageBox.ButtonRole.AcceptRole)
        replace = box.addButton("Replace", QMessageBox.ButtonRole.DestructiveRole)
        box.addButton(QMessageBox.StandardButton.Cancel)
        box.setDefaultButton(new)
        box.exec()
        clicked = box.clickedButton()
        return "new" if clicked is new else "replace" if clicked is replace else "cancel"

    def _free_folder(self, path: Path) -> Path:
        """``NAME-2.results``, ``NAME-3.results``, ...: the first that neither exists nor is in use."""
        busy = {r.out_dir for r in self.runs if r.is_running()}
        stem, suffix = path.stem, path.suffix
        for n in range(2, 10_000):
            candidate = path.with_name(f"{stem}-{n}{suffix}").absolute()
            if not candidate.exists() and candidate not in busy:
                return candidate
        raise OSError(f"no free folder name beside {path}")

    def _choose_out_dir(self) -> tuple[Path, bool] | None:
        """The folder for a new run and whether to replace the results there: the folder asked
        for, or a new one beside it when a run of this window writes there or the user does not
        want earlier results replaced; None: cancelled."""
        from projects.results import is_results_dir

        out = self.out_dir().expanduser().absolute()
        busy = {r.out_dir for r in self.runs if r.is_running()}
        if out in busy:
            new = self._free_folder(out)
            self.statusBar().showMessage(f"{out.name} is in use by a run; this one writes to {new.name}", 8000)
            return new, False
        if is_results_dir(out):
            answer = self.ask_replace_results(out)
            if answer == "cancel":
                return None
            if answer == "new":
                return self._free_folder(out), False
            return out, True
        return out, False

    def start_run(self) -> bool:
        """Run the current document in a child process (``runout run``); the Results tab follows it.

        The document is written to a temporary project file for the run (the user's file and any
        unsaved edits stay as they are). Several runs may go on at once, each in its own folder.
        """
        self.commit_typing()
        invalid = self.invalid_fields()
        if invalid:
            self.run_dock.show()
            self.show_error("Cannot run", "These fields hold values that are not valid (shown red); the "
                            "project still has the previous values. Correct them (or undo the typing) "
                            "before running:\n" + "\n".join(invalid))
            return False
        project = self.doc.project
        if project is None:
            self.run_dock.show()
            self.show_error("Cannot run", "The project has problems:\n" + "\n".join(str(p) for p in self.doc.problems))
            return False
        if self._estimate_timer.isActive():  # an edit's estimate still pending: the panel's view of this project
            self._estimate_timer.stop()
            self.run_panel.update_estimate()
        if self.run_panel.build_error:
            self.run_dock.show()
            self.show_error("Cannot run", "The project cannot be built:\n" + self.run_panel.build_error)
            return False
        if self.scene.mode == "draw":
            self.scene.set_mode("select")
        chosen = self._choose_out_dir()
        if chosen is None:
            return False
        out_dir, overwrite = chosen
        name = self.doc.path.stem if self.doc.path is not None else "untitled"
        run = RunProcess(self.doc.text(), out_dir, name, overwrite=overwrite, source=self.doc.path,
                         unsaved=self.doc.path is None or self.doc.is_dirty, parent=self)
        run.title = project.runout.title or self.doc.display_name  # what the live view's header says
        return self._launch(run, f"Running in a new process… results go to {out_dir}")

    def resumable_folder(self) -> Path | None:
        """The results folder the Resume action would continue (the shown one, or the followed
        run's), when it looks resumable: a checkpoint, not complete, no run of this window in it.
        Cheap; :func:`projects.runner.resumable` checks it in full when asked to resume."""
        from projects.results import CHECKPOINT_NAME

        results = self.results_view.results
        folder = results.path if results is not None else (self.followed.out_dir if self.followed else None)
        if folder is None or not (Path(folder) / CHECKPOINT_NAME).is_file():
            return None
        if any(r.is_running() and r.out_dir == Path(folder).absolute() for r in self.runs):
            return None
        status = results.status if results is not None else None
        return None if status in ("completed", "failed") else Path(folder)

    def _update_resume(self) -> None:
        can = self.resumable_folder() is not None
        self.actions_["resume"].setEnabled(can)
        self.run_panel.resume_button.setEnabled(can)

    def resume_run(self, folder: str | os.PathLike[str] | None = None) -> bool:
        """Continue a killed or stopped run in its own folder from its last checkpoint (a child
        ``runout run --resume FOLDER``), followed as any run. ``folder``: the shown results."""
        from projects.results import ResultsError
        from projects.runner import resumable

        path = Path(folder).expanduser().absolute() if folder is not None else self.resumable_folder()
        if path is None:
            results = self.results_view.results
            self.show_error("Cannot resume", "Show the results of a killed or stopped run first (File ▸ Open "
                            "results)" + (f": {results.path} is {results.status}" if results is not None else "."))
            return False
        if any(r.is_running() and r.out_dir == path.absolute() for r in self.runs):
            self.show_error("Cannot resume", f"{path} is being written by a run of this window")
            return False
        try:
            resumable(path)  # one line on what stands in the way, before a process starts
        except (ResultsError, OSError, ValueError) as err:
            self.show_error("Cannot resume", str(err))
            return False
        run = RunProcess("", path, path.stem, resume=True, parent=self)
        results = self.results_view.results
        run.title = (results.summary.get("title") if results is not None and results.path == path else None) \
            or path.stem
        return self._launch(run, f"Resuming the run in {path} from its last checkpoint…")

    def _launch(self, run: RunProcess, message: str) -> bool:
        """Start ``run``, list it and follow it."""
        run.runStarted.connect(lambda _e, r=run: self._run_started(r))
        run.progressed.connect(lambda e, r=run: self._run_progressed(r, e))
        run.frameWritten.connect(lambda _e, r=run: self._run_frame(r))
        run.ended.connect(lambda o, r=run: self._run_ended(r, o))
        self.runs.append(run)
        self.run_panel.add_run(self._run_text(run))
        self.follow(run)
        self.statusBar().showMessage(message)
        try:
            run.start()
        except OSError as err:
            self.show_error("The run could not start", str(err))
            return False
        self._update_resume()  # not into a folder a run of this window writes
        self._update_run_item(run)
        return True

    def _run_text(self, run: RunProcess) -> str:
        from app.gui.run_panel import outcome_state

        status = run.status
        if run.outcome is not None:
            status = outcome_state(status, run.outcome.summary)
        if status == "running" and run.last_progress:
            total = run.last_progress.get("total_time_s") or 0.0
            fraction = (run.last_progress.get("time_s") or 0.0) / total if total > 0 else 0.0
            status = f"running {100 * min(1.0, fraction):.0f} %"
        pid = f"pid {run.pid}, " if run.is_running() and run.pid else ""
        return f"{run.name} → {run.out_dir.name}\n{status} ({pid}{run.frames} frames)"

    def _update_run_item(self, run: RunProcess) -> None:
        if run in self.runs:
            from projects.motion import provisional

            status = run.status
            if status == "completed" and run.outcome is not None and provisional(run.outcome.summary or {}):
                status = "provisional"
            self.run_panel.set_run_text(self.runs.index(run), self._run_text(run), status)

    def follow(self, run: RunProcess) -> None:
        """Show ``run`` in the Results tab and the run panel (live while it goes on)."""
        self.followed = run
        row = self.runs.index(run)
        if self.run_panel.runs.currentRow() != row:
            self.run_panel.runs.blockSignals(True)
            self.run_panel.runs.setCurrentRow(row)
            self.run_panel.runs.blockSignals(False)
        self.tabs.setCurrentWidget(self.results_view)
        if run.outcome is not None:
            self._refresh_timer.stop()
            self._poll_timer.stop()
            self._show_outcome(run, run.outcome, ask=False)
            return
        self.run_panel.set_running(True)
        self.actions_["cancel"].setEnabled(True)
        self.results_view.follow(run.out_dir, run.title)
        if run.last_progress is not None:
            self.run_panel.show_progress(run.last_progress, time.perf_counter() - run.started_at)
        if run.started_event is not None:
            self._refresh_live()
            self._poll_timer.start()

    def _select_run(self, row: int) -> None:
        if 0 <= row < len(self.runs) and self.runs[row] is not self.followed:
            self.follow(self.runs[row])

    def cancel_run(self) -> None:
        """Stop the followed run (SIGTERM; SIGKILL if it has not ended 10 s later)."""
        run = self.followed
        if run is not None and run.is_running():
            run.cancel()
            self.run_panel.progress.setFormat("stopping…")
            self._update_run_item(run)
            self.statusBar().showMessage("Stopping the run after its current steps…")

    def _run_started(self, run: RunProcess) -> None:
        self._update_run_item(run)
        if run is self.followed and not self._shut:
            self._refresh_live()
            self._poll_timer.start()

    def _run_progressed(self, run: RunProcess, event: dict[str, Any]) -> None:
        if self._shut:
            return
        self._update_run_item(run)
        if run is self.followed and not run.cancel_requested:
            self.run_panel.show_progress(event, time.perf_counter() - run.started_at)

    def _run_frame(self, run: RunProcess) -> None:
        if self._shut:
            return
        self._update_run_item(run)
        if run is not self.followed:
            return
        # the first frame at once, then at most every LIVE_INTERVAL_MS
        if self.results_view.results is None:
            self._refresh_live()
        elif not self._refresh_timer.isActive():
            self._refresh_timer.start()

    def _refresh_live(self) -> None:
        if self._shut or self.followed is None or not self.results_view.live:
            return
        if self.results_view.refresh():
            self._live_frames += 1

    def _run_ended(self, run: RunProcess, outcome: RunOutcome) -> None:
        if self._shut:
            return
        self._update_run_item(run)
        self.last_result = outcome
        self.last_run = run
        summary = outcome.summary or {}
        arch = summary.get("arch")
        if outcome.status == "completed" and arch in ("cpu", "gpu"):
            self.settings.record_throughput(arch, float(summary.get("particle_steps_per_s") or 0.0))
            # the step time at the run's size scales the estimate's cost model to this machine
            self.settings.record_step_time(arch, int(summary.get("particles") or 0),
                                           float(summary.get("step_time_s") or 0.0), bool(summary.get("structures")))
            self.settings.set("last_arch", arch)
            self.run_panel.update_estimate()
        if run is self.followed:
            self._refresh_timer.stop()
            self._poll_timer.stop()
            self._show_outcome(run, outcome, ask=True)
        else:
            self.statusBar().showMessage(f"Run {run.name} → {run.out_dir.name} {outcome.status}: {outcome.message}",
                                         10000)

    def _show_outcome(self, run: RunProcess, outcome: RunOutcome, ask: bool) -> None:
        """Show how a run ended, and its folder (whatever it holds: frames up to a crash too)."""
        from projects.results import ResultsError

        from app.gui.run_panel import outcome_state

        self.actions_["cancel"].setEnabled(False)
        state = outcome_state(outcome.status, outcome.summary)
        self.results_view.end_live(f"{state}: {outcome.message}")
        self.run_panel.show_result(outcome.status, outcome.message, outcome.summary)
        shown = False
        # a run that never reported its folder wrote no frame: what the folder holds (an earlier
        # run's results it was to replace) is not shown as this run's
        if outcome.status != "error" and run.started_event is not None:
            try:
                self.results_view.open_results(outcome.out_dir)
                self.settings.add_recent(outcome.out_dir, "results")
                shown = True
            except (ResultsError, OSError, ValueError) as err:
                logger.warning("cannot show the results: %s", err)
        self.statusBar().showMessage(f"Run {state}: {outcome.message}", 10000)
        self._update_resume()
        if not ask:
            return
        if outcome.status == "error":
            self.show_error("The run could not start", outcome.message)
        elif outcome.status in ("failed", "killed", "crashed"):
            where = (f"Frames written until then are in {outcome.out_dir}." if shown
                     else f"No complete frame was written to {outcome.out_dir}.")
            title = "The run failed" if outcome.status == "failed" else "The run process ended abnormally"
            self.show_error(title, f"{outcome.message}\n\n{where}")

    def wait_for_run(self, timeout_s: float = 60.0) -> bool:
        """Process events until no run of this window goes on (for scripts and tests)."""
        end = time.perf_counter() + timeout_s
        while self.running and time.perf_counter() < end:
            QApplication.processEvents()
            time.sleep(0.01)
        return not self.running

    # -- hazard, factor of safety and sweeps (app/gui/hazard_view.py, fos_view.py, sweep_view.py) --

    def _add_analysis(self) -> None:
        """The Hazard, Factor of safety and Sweep tabs and their actions."""
        from app.gui.fos_view import FosView
        from app.gui.hazard_view import HazardView

        self.hazard_view = HazardView()
        self.fos_view = FosView()
        self.sweep_view: Any = None
        self.tabs.addTab(self.hazard_view, "Hazard")
        self.tabs.addTab(self.fos_view, "Factor of safety")
        self.tabs.setTabVisible(self.tabs.indexOf(self.fos_view), False)
        self.hazard_view.message.connect(lambda text: self.statusBar().showMessage(text, 8000))
        self.results_view.resultsShown.connect(lambda: self._update_analysis(False))
        self.tabs.currentChanged.connect(lambda _i: self._update_analysis(False))
        a = self.actions_
        a["export_report"] = self._action("Export hazard &report…", self.export_report_dialog,
                                          tip="Write the HTML report of the shown results (runout report) and open it")
        a["sweep"] = self._action("S&weep or calibration…", self.sweep_dialog, "Ctrl+Shift+W",
                                  "Run the open project many times with sampled parameters (runout sweep)")
        a["open_sweep"] = self._action("Open s&weep…", self.open_sweep_dialog,
                                       tip="Show a sweep or calibration folder (runout sweep --out)")
        menus = {m.title(): m for m in (act.menu() for act in self.menuBar().actions()) if m is not None}
        if "&File" in menus:
            menus["&File"].insertAction(a["quit"], a["export_report"])
            menus["&File"].insertAction(a["export_report"], a["open_sweep"])
        if "&Run" in menus:
            menus["&Run"].addSeparator()
            menus["&Run"].addAction(a["sweep"])

    def _update_analysis(self, force: bool = True) -> None:
        """Show the open results' hazard files and factor of safety (while a run goes on, only
        in the tab on view)."""
        results = self.results_view.results
        current = self.tabs.currentWidget()
        if results is None:
            return
        if force or not self.results_view.live or current is self.hazard_view:
            self.hazard_view.show_results(results.path, results)
        if force or not self.results_view.live or current is self.fos_view:
            shown = self.fos_view.show_results(results)
            self.tabs.setTabVisible(self.tabs.indexOf(self.fos_view), shown)

    def export_report_dialog(self) -> Path | None:
        """Write the hazard report of the shown results and open it (File ▸ Export hazard report)."""
        results = self.results_view.results
        if results is None:
            self.show_error("Export hazard report", "Open a results folder first (File ▸ Open results).")
            return None
        self.hazard_view.show_results(results.path, results)
        if self.hazard_view.path is None:
            self.show_error("Export hazard report", f"{results.path} has no hazard files: the run wrote no "
                            "hazard envelopes (hazard.enabled = false, or no dynamic stage ran).")
            return None
        html = self.hazard_view.export_and_open()
        if html is not None:  # said where it went, also after the browser came and went
            lost = "" if self.hazard_view.report_opened else "; no web browser could be opened here: open that file in one"
            self.statusBar().showMessage(f"Hazard report written to {html}{lost}")
        return html

    def sweep_dialog(self) -> bool:
        """Define a sweep or calibration of the open project, write its file and start it."""
        from app.gui.sweep_dialog import SweepDialog

        dialog = SweepDialog(self.doc, self._default_sweep_dir(), self)
        if dialog.exec() != SweepDialog.DialogCode.Accepted:
            return False
        return self.start_sweep(dialog.spec_path, dialog.out_dir, dialog.workers())

    def _default_sweep_dir(self) -> Path:
        path = self.doc.path
        if path is not None:
            return path.with_name(path.stem + ".sweep")
        return Path(tempfile.gettempdir()) / "runout.sweep"

    def _sweep_view(self) -> Any:
        if self.sweep_view is None:
            from app.gui.sweep_view import SweepView

            self.sweep_view = SweepView()
            self.sweep_view.message.connect(lambda text: self.statusBar().showMessage(text, 8000))
            self.sweep_view.resultsRequested.connect(self.open_results)
            self.tabs.addTab(self.sweep_view, "Sweep")
        self.tabs.setCurrentWidget(self.sweep_view)
        return self.sweep_view

    def start_sweep(self, spec_path: str | os.PathLike[str], out_dir: str | os.PathLike[str],
                    workers: int | None = None) -> bool:
        """Start ``runout sweep`` (or ``calibrate``) as a child process and follow its folder."""
        return self._sweep_view().start(Path(spec_path), Path(out_dir), workers)

    def open_sweep_dialog(self) -> bool:
        from PySide6.QtWidgets import QFileDialog

        path = QFileDialog.getExistingDirectory(self, "Open sweep folder", str(Path.cwd()))
        return self.open_sweep(path) if path else False

    def open_sweep(self, path: str | os.PathLike[str]) -> bool:
        """Show a sweep or calibration folder."""
        from sweeps.folder import SweepFolderError

        try:
            self._sweep_view().open_folder(Path(path))
        except SweepFolderError as err:
            self.show_error("Cannot open sweep", str(err))
            return False
        return True

    def _close_analysis(self) -> None:
        self.hazard_view.close_view()
        self.fos_view.close_view()
        if self.sweep_view is not None:
            self.sweep_view.shutdown()

    # -- closing ---------------------------------------------------------------------------------------

    def closeEvent(self, event: QCloseEvent) -> None:  # noqa: N802 - Qt's name
        if not self._shut:
            if self.running and not self.ask_stop_run():
                event.ignore()
                return
            if not self.maybe_save():
                event.ignore()
                return
        self.shutdown()
        event.accept()

    def _watch_typing(self, _old: QWidget | None, new: QWidget | None) -> None:
        """Give a text field of this window that takes the focus the :class:`TypingUndo` filter
        (once: installing it again only moves it to the front)."""
        if isinstance(new, (QLineEdit, QAbstractSpinBox)) and new.window() is self:
            new.installEventFilter(self._typing_undo)

    def shutdown(self) -> None:
        """Stop a run, release every VTK view and timer (idempotent)."""
        if self._shut:
            return
        self._shut = True
        QApplication.instance().focusChanged.disconnect(self._watch_typing)
        self._estimate_timer.stop()
        self._refresh_timer.stop()
        self._poll_timer.stop()
        running = [run for run in self.runs if run.is_running()]
        for run in running:
            run.cancel()
        for run in running:
            if not run.wait(15_000):
                run.kill()
                run.wait(5_000)
        self._close_analysis()
        self.scene.close_view()
        self.results_view.close_view()
        if self.compare is not None:
            self.compare.close_view()
