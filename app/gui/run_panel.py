"""The run panel: what the run will cost, where its results go, progress, and the project's problems."""

from __future__ import annotations

import logging
import math
import re
from pathlib import Path
from typing import Any

from PySide6.QtCore import Qt, Signal
from PySide6.QtWidgets import (
    QFileDialog,
    QFormLayout,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QListWidget,
    QProgressBar,
    QPushButton,
    QVBoxLayout,
    QWidget,
)

from app.gui.document import MAX_SEEDED_PARTICLES, ProjectDocument
from app.gui.settings import Settings

logger = logging.getLogger(__name__)

#: The colour of a run that completed with the mass still moving (its answer is provisional).
PROVISIONAL_COLOR = "#e37400"


def outcome_state(status: str, summary: dict[str, Any] | None) -> str:
    """``completed, still moving`` for a completed run whose mass was still moving at its end
    (projects.motion), else the status."""
    from projects.motion import provisional

    return f"{status}, still moving" if status == "completed" and provisional(summary or {}) else status


class _Counted:
    """A resolved run whose particle count is the one the panel counted (the seeding it shares
    with the particle preview) without holding the particles."""

    def __init__(self, resolved: Any, particles: int) -> None:
        self.project = resolved.project
        self.estimate = resolved.estimate
        self.particle_count = int(particles)


def format_duration(seconds: float) -> str:
    """``42 s``, ``3 min 20 s``, ``2 h 05 min``."""
    if not math.isfinite(seconds):
        return "?"
    seconds = max(0.0, seconds)
    if seconds < 60:
        return f"{seconds:.0f} s" if seconds >= 10 else f"{seconds:.1f} s"
    if seconds < 3600:
        return f"{int(seconds // 60)} min {int(seconds % 60):02d} s"
    return f"{int(seconds // 3600)} h {int(seconds % 3600 // 60):02d} min"


#: the key a warning asks the engineer to set (the near-limit warning's damping), else its first key
_SET_KEY = re.compile(r"\bset ((?:materials|stages)\.[\w.-]+?)\.damping_ratio\b")
_LEADING_KEY = re.compile(r"^((?:runout|domain|materials|bodies|structures|particles|numerics|stages|output|"
                          r"hazard|targets)(?:\.[\w-]+)*)")


class _Line(QLabel):
    """A line of the run's progress: shown only while it says something, so that an idle Run box
    leaves the dock's height to the Problems list. It wraps: a long line (``Speed: 1,587 steps/s
    (0.313 M particle-steps/s)``) widened the Run dock while a run went on, which took the width
    from the Project dock and clipped its panels."""

    def __init__(self) -> None:
        super().__init__("")
        self.setWordWrap(True)
        self.setVisible(False)

    def setText(self, text: str) -> None:  # noqa: N802 - Qt's name
        super().setText(text)
        self.setVisible(bool(text))


def warning_path(text: str) -> str:
    """The key path a warning leads to in the workbench (``""``: none)."""
    found = _SET_KEY.search(text) or _LEADING_KEY.match(text)
    return found.group(1) if found else ""


class RunPanel(QWidget):
    """Estimate, results folder, Run/Cancel, progress and problems.

    Signals
    -------
    runRequested()
    cancelRequested()
        Cancel the run selected in the run list.
    resumeRequested()
        Continue the shown run, killed or stopped, from its checkpoint.
    problemActivated(str)
        The key path of a problem the user double-clicked.
    runSelected(int)
        The row of the run list the user chose (the window follows that run).
    removeUnknownRequested()
        Remove the keys the schema does not know (typos in a file) from the project.
    """

    runRequested = Signal()
    cancelRequested = Signal()
    resumeRequested = Signal()
    problemActivated = Signal(str)
    runSelected = Signal(int)
    removeUnknownRequested = Signal()

    def __init__(self, doc: ProjectDocument, settings: Settings, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.doc = doc
        self.settings = settings
        layout = QVBoxLayout(self)
        layout.setContentsMargins(6, 6, 6, 6)

        box = QGroupBox("What will run")
        form = QFormLayout(box)
        self.particles = QLabel("–")
        self.grid = QLabel("–")
        self.cell = QLabel("–")
        self.numerics = QLabel("–")
        self.steps = QLabel("–")
        self.frames = QLabel("–")
        self.runtime = QLabel("–")
        self.rate_info = QLabel("")
        self.preset_note = QLabel("")
        # short values, one line each: word-wrapped labels in a form get no room in a dock
        self.preset_note.setWordWrap(True)
        self.rate_info.setWordWrap(True)
        self.preset_note.setStyleSheet("color: #e37400;")
        form.addRow("Particles", self.particles)
        form.addRow("Cell size", self.cell)
        form.addRow("Grid", self.grid)
        form.addRow("Numerics", self.numerics)
        form.addRow("Time steps", self.steps)
        form.addRow("Frames", self.frames)
        form.addRow("Run time", self.runtime)
        form.addRow("", self.rate_info)
        layout.addWidget(box)
        layout.addWidget(self.preset_note)

        box = QGroupBox("Run")
        vbox = QVBoxLayout(box)
        row = QHBoxLayout()
        row.addWidget(QLabel("Results"))
        self.out_dir = QLineEdit()
        self.out_dir.setPlaceholderText("NAME.results next to the project file")
        self.out_dir.setToolTip("Results folder; if one is there already you are asked whether to replace "
                                "it or to use a new folder beside it")
        browse = QPushButton("…")
        browse.setMaximumWidth(30)
        browse.clicked.connect(self._browse)
        row.addWidget(self.out_dir, 1)
        row.addWidget(browse)
        vbox.addLayout(row)
        row = QHBoxLayout()
        self.run_button = QPushButton("Run")
        self.run_button.setToolTip("Run the project (F5)")
        self.run_button.clicked.connect(self.runRequested)
        self.cancel_button = QPushButton("Cancel")
        self.cancel_button.setEnabled(False)
        self.cancel_button.clicked.connect(self.cancelRequested)
        self.resume_button = QPushButton("Resume")
        self.resume_button.setToolTip("Continue the shown run, killed or stopped, from its last checkpoint "
                                      "in its own folder (runout run --resume)")
        self.resume_button.setEnabled(False)
        self.resume_button.clicked.connect(self.resumeRequested)
        row.addWidget(self.run_button)
        row.addWidget(self.cancel_button)
        row.addWidget(self.resume_button)
        vbox.addLayout(row)
        self.progress = QProgressBar()
        self.progress.setRange(0, 1000)
        self.progress.setValue(0)
        self.progress.setFormat("")
        self.progress.setTextVisible(True)
        vbox.addWidget(self.progress)
        self.stage = _Line()
        self.clock = _Line()
        self.rate = _Line()
        self.eta = _Line()
        for w in (self.stage, self.clock, self.rate, self.eta):
            vbox.addWidget(w)
        self.status = _Line()
        self.status.setWordWrap(True)
        self.status.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        vbox.addWidget(self.status)
        layout.addWidget(box)

        box = QGroupBox("Runs (each a process with its own folder)")
        vbox = QVBoxLayout(box)
        self.runs = QListWidget()
        self.runs.setWordWrap(True)
        self.runs.setToolTip("Runs of this session; choose one to follow it (progress, live view, Cancel)")
        self.runs.setMaximumHeight(110)
        self.runs.currentRowChanged.connect(lambda row: row >= 0 and self.runSelected.emit(row))
        vbox.addWidget(self.runs)
        layout.addWidget(box)

        self.problems_box = QGroupBox("Problems")
        vbox = QVBoxLayout(self.problems_box)
        self.problems = QListWidget()
        self.problems.setWordWrap(True)
        self.problems.itemDoubleClicked.connect(
            lambda item: self.problemActivated.emit(item.data(Qt.ItemDataRole.UserRole) or ""))
        vbox.addWidget(self.problems)
        self.problems.setMaximumHeight(220)
        self.warnings: list[str] = []
        #: why a valid project still cannot be built for a run (update_estimate), or None
        self.build_error: str | None = None
        self.remove_unknown = QPushButton("Remove unknown keys")
        self.remove_unknown.setToolTip("Keys the project format does not know (a typo in the file) are "
                                       "never used; remove them so that the project can run")
        self.remove_unknown.clicked.connect(self.removeUnknownRequested)
        self.remove_unknown.setVisible(False)
        vbox.addWidget(self.remove_unknown)
        layout.addWidget(self.problems_box)
        layout.addStretch(1)
        self._layout = layout
        self._t0: tuple[float, float] | None = None

    # -- estimate ---------------------------------------------------------------------------------

    def arch(self) -> str:
        """The device the run will most likely use: as set, or for "auto" the last one used."""
        project = self.doc.project
        arch = project.numerics.arch if project is not None else "auto"
        if arch == "auto":
            arch = str(self.settings.get("last_arch", "cpu"))
        return arch

    def update_estimate(self) -> dict[str, Any] | None:
        """Particles, grid, steps and run time of the current project (from the measured cost per step)."""
        project = self.doc.project
        self.problems.clear()
        for p in self.doc.problems:
            self.problems.addItem(str(p))
            self.problems.item(self.problems.count() - 1).setData(Qt.ItemDataRole.UserRole, p.path)
        n = len(self.doc.problems)
        warnings: list[str] = []
        if project is not None:
            from projects.checks import project_warnings

            try:
                warnings = project_warnings(project)  # what runs but is probably not meant
            except (ValueError, ArithmeticError) as err:
                logger.debug("no warnings: %s", err)
        from PySide6.QtGui import QColor

        for text in warnings:
            self.problems.addItem(f"warning: {text}")
            item = self.problems.item(self.problems.count() - 1)
            item.setForeground(QColor("#b06000"))
            item.setData(Qt.ItemDataRole.UserRole, warning_path(text))  # a double click goes there
        self.warnings = warnings
        self.build_error = None
        title = f"Problems ({n})" if n else "Problems (none)"
        self.problems_box.setTitle(title + (f", {len(warnings)} warning(s)" if warnings else ""))
        self.remove_unknown.setVisible(bool(self.doc.unknown_keys()))
        self._fit_problems(bool(n or warnings))
        if project is None:
            for w in (self.particles, self.grid, self.steps, self.cell, self.numerics, self.frames):
                w.setText("–")
            self.rate_info.setText("")
            self.preset_note.setText("")
            self.runtime.setText("fix the problems below first")
            return None
        from projects.build import resolve
        from projects.schema import DEFAULT_CFL, ProjectError

        try:
            resolved = resolve(project, seed=False)  # what the run will use, preset applied
        except (ValueError, ZeroDivisionError, ProjectError) as err:
            self._build_problem(err)
            return None
        e = dict(resolved.estimate)
        effective = resolved.project
        nx, ny = e["grid_shape"]
        dx = effective.domain.cell_size_m
        num = effective.numerics
        self.cell.setText(f"{dx:.4g} m, {effective.particles.per_cell}² per cell")
        step = f"time step {num.time_step_s:g} s" if num.time_step_s is not None else f"CFL {num.cfl or DEFAULT_CFL:g}"
        self.numerics.setText(f"{num.scheme}, {step}, {num.precision}")
        self.numerics.setToolTip("scheme, time step, precision as the run will use them")
        changed = []
        if project.numerics.preset is not None:
            if dx != project.domain.cell_size_m:
                changed.append(f"cell size {project.domain.cell_size_m:g} → {dx:.4g} m")
            if effective.particles.per_cell != project.particles.per_cell:
                changed.append(f"particles per cell {project.particles.per_cell} → {effective.particles.per_cell}")
            if num.scheme != project.numerics.scheme:
                changed.append(f"scheme {project.numerics.scheme} → {num.scheme}")
            if num.cfl != project.numerics.cfl:
                changed.append(f"CFL {project.numerics.cfl or DEFAULT_CFL:g} → {num.cfl:g}")
        self.preset_note.setText(
            f"Preset '{project.numerics.preset}' overrides the panels: " + "; ".join(changed) if changed else "")
        e["effective"] = effective
        self.grid.setText(f"{nx} × {ny} = {e['grid_cells']:,} cells")
        self.steps.setText(f"{e['steps']:,} of {e['time_step_s']:.3g} s")
        self.frames.setText(f"{e['frames']:,}, every {effective.output.interval_s:g} s")
        if e["particles"] <= MAX_SEEDED_PARTICLES:  # else the estimate from the area
            # the estimate is the bodies' area times the density; the lattice also seeds the
            # parts of the sub-cells an outline cuts (897 against 998 in debris_barrier.toml):
            # count the seeding the run gets (shared with the particle preview)
            try:
                e["particles"] = len(self.doc.seeded_run().particles)
            except (ProjectError, ValueError, ArithmeticError) as err:
                self.particles.setText("–")
                self._build_problem(err)  # what the run would stop at
                return None
            self.particles.setText(f"{e['particles']:,}")
        else:
            self.particles.setText(f"about {e['particles']:,}")
        # the wall time from the measured cost of a step at this size (projects.cost): this
        # project's own last run, else this machine's runs, else the development machine's
        from projects.cost import estimate_run_time

        arch = self.arch()
        machine, _count = self.settings.step_cost(arch)
        cost = estimate_run_time(_Counted(resolved, e["particles"]), arch=arch, machine=machine,
                                 results_dir=self.results_dir())
        seconds = cost["run_time_s"]
        head = "at most" if cost["may_stop_early"] else "about"
        self.runtime.setText(f"{head} {format_duration(seconds)} on {arch}")
        self.rate_info.setText(
            f"start-up {format_duration(cost['startup_s'])} + {cost['steps']:,} steps × {cost['step_time_s'] * 1e3:.3g} ms "
            f"({cost['particle_step_s'] * 1e6:.3g} µs per particle-step at this size); {cost['source']}"
            + (f"; each strength-reduction trial up to {format_duration(cost['trial_time_s'])} more"
               if cost["trial_steps"] else ""))
        e["run_time_s"] = seconds
        e["cost"] = cost
        return e

    def results_dir(self) -> Path | None:
        """Where the run will write: the folder typed, or the project's default folder."""
        text = self.out_dir.text().strip()
        if text:
            return Path(text).expanduser()
        if self.doc.path is not None:
            from projects.runner import default_results_dir

            return default_results_dir(self.doc.path)
        return None

    def _build_problem(self, err: Exception) -> None:
        """A valid project the run could still not build (a body every particle of which a later
        body or a structure covers): listed with the problems, so that Run refuses it up front
        instead of starting a process that ends at once."""
        from PySide6.QtGui import QColor

        problems = list(getattr(err, "problems", None) or [])
        lines = [str(p) for p in problems] or [str(err)]
        first = len(self.doc.problems)  # after the schema's problems, before the warnings
        for k, line in enumerate(lines):
            self.problems.insertItem(first + k, line)
            item = self.problems.item(first + k)
            item.setForeground(QColor("#b3261e"))
            if k < len(problems):
                item.setData(Qt.ItemDataRole.UserRole, problems[k].path)
        self.build_error = "\n".join(lines)
        n = len(self.doc.problems) + len(lines)
        self.problems_box.setTitle(f"Problems ({n})" + (f", {len(self.warnings)} warning(s)" if self.warnings else ""))
        self._fit_problems(True)
        self.runtime.setText("fix the problems below first")

    def _fit_problems(self, listed: bool) -> None:
        """With something listed the Problems box takes the dock's free height (a long warning, such
        as the near-limit one whose keys come last, is read whole); empty it stays one line."""
        self.problems.setMaximumHeight(16777215 if listed else 48)  # QWIDGETSIZE_MAX
        self._layout.setStretchFactor(self.problems_box, 1 if listed else 0)
        self._layout.setStretch(self._layout.count() - 1, 0 if listed else 1)

    # -- progress ---------------------------------------------------------------------------------

    def _browse(self) -> None:
        path = QFileDialog.getExistingDirectory(self, "Results folder", self.out_dir.text() or str(Path.cwd()))
        if path:
            self.out_dir.setText(path)

    def add_run(self, text: str) -> None:
        """List a new run and choose it."""
        self.runs.addItem(text)
        self.runs.blockSignals(True)
        self.runs.setCurrentRow(self.runs.count() - 1)
        self.runs.blockSignals(False)

    def set_run_text(self, row: int, text: str, status: str) -> None:
        item = self.runs.item(row)
        if item is None:
            return
        item.setText(text)
        color = {"completed": "#188038", "stopped": "#e37400", "running": "#1a73e8",
                 "starting": "#1a73e8", "stopping": "#e37400", "provisional": PROVISIONAL_COLOR}.get(status, "#b3261e")
        from PySide6.QtGui import QColor

        item.setForeground(QColor(color))

    def set_running(self, running: bool) -> None:
        """Show the chosen run as running (Cancel on, progress reset) or not."""
        self.cancel_button.setEnabled(running)
        if running:
            self.progress.setValue(0)
            self.progress.setFormat("starting (compiling the solver)…")
            self.status.setText("")
            for w in (self.stage, self.clock, self.rate, self.eta):
                w.setText("")
            self._t0 = None

    def show_progress(self, progress: Any, wall_s: float) -> None:
        """Show a ``progress`` event of a run (a dict, or an object with the same attributes);
        ``wall_s`` is the time since the run started."""
        if isinstance(progress, dict):
            from types import SimpleNamespace

            progress = SimpleNamespace(**progress)
        total = progress.total_time_s
        fraction = progress.time_s / total if total > 0 else 0.0
        self.progress.setValue(int(round(1000 * min(1.0, fraction))))
        self.progress.setFormat(f"{100 * fraction:.0f} %")
        self.stage.setText(f"Stage: {progress.stage}")
        self.clock.setText(f"Simulated: {progress.time_s:.4g} of {total:.4g} s (step {progress.step:,})")
        self.rate.setText(f"Speed: {progress.steps_per_s:,.0f} steps/s "
                          f"({progress.particle_steps_per_s / 1e6:.3g} M particle-steps/s)")
        # simulated seconds per wall second since the first report (compilation excluded)
        if self._t0 is None:
            self._t0 = (wall_s, progress.time_s)
            self.eta.setText("Remaining: estimating…")
            return
        dt_wall, dt_sim = wall_s - self._t0[0], progress.time_s - self._t0[1]
        if dt_wall > 0 and dt_sim > 0:
            self.eta.setText(f"Remaining: about {format_duration((total - progress.time_s) * dt_wall / dt_sim)}")

    def show_result(self, status: str, message: str, summary: dict[str, Any] | None = None) -> None:
        """Show how a run ended; a completed run that ended with the mass still moving is shown
        provisional (orange, with its kinetic energy as a fraction of the peak and its fastest
        particle at the end: projects.motion)."""
        from projects.motion import motion_text, provisional

        self.set_running(False)
        summary = summary or {}
        still = status == "completed" and provisional(summary)
        if summary.get("simulated_time_s") is not None:
            self.clock.setText(f"Simulated: {summary['simulated_time_s']:.4g} s in {summary.get('steps', 0):,} steps, "
                               f"{format_duration(summary.get('wall_time_s') or 0.0)} of wall time")
            rate = summary.get("particle_steps_per_s") or 0.0
            self.rate.setText(f"Speed: {rate / 1e6:.3g} M particle-steps/s on {summary.get('arch', '?')}")
        color = {"completed": "#188038", "stopped": "#e37400", "running": "#1a73e8"}.get(status, "#b3261e")
        text = f"{status}: {message}"
        if still:
            color = PROVISIONAL_COLOR
            text = (f"{outcome_state(status, summary)}: {message}\n{motion_text(summary.get('motion_at_end'))}. "
                    "Not a final answer: every hazard measure of this run is provisional.")
        self.status.setStyleSheet(f"color: {color};")
        self.status.setText(text)
        if status == "completed":
            self.progress.setValue(1000)
            self.progress.setFormat(outcome_state(status, summary))
        else:
            self.progress.setFormat(status)
        self.eta.setText("")
