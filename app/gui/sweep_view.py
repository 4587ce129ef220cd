"""The Sweep tab: a sweep or calibration started as a child process (``runout sweep`` /
``runout calibrate``, :func:`sweeps.spec.command_line`), followed through its folder.

Neither Ray nor Taichi enters the workbench: the child schedules the runs; the workbench rereads
``progress.json`` and ``sweep.csv`` (or ``calibration.csv``) every second
(:func:`sweeps.folder.read_sweep`, :func:`sweeps.calibrate.read_calibration`) and draws, from the
runs completed so far, the exceedance curve of a measure (with its DKW band), the measure against
a parameter (each completed run a point) and the probability profile along the section (with
Wilson bands), with :mod:`sweeps.analysis` (numpy and scipy). A
calibration shows its trials with their misfit and the misfit against each parameter. A run
that ended with the mass still moving (``still_moving`` in the table) has its measures marked
provisional (``*``, amber) and the header counts such runs.
A folder written earlier, or by ``runout sweep`` on the command line, opens the same way
(File ▸ Open sweep).
"""

from __future__ import annotations

import logging
import os
from collections import deque
from pathlib import Path
from typing import Any

import numpy as np
from PySide6.QtCore import QProcess, QProcessEnvironment, Qt, QTimer, QUrl, Signal
from PySide6.QtGui import QColor, QDesktopServices
from PySide6.QtWidgets import (
    QComboBox,
    QHBoxLayout,
    QHeaderView,
    QLabel,
    QProgressBar,
    QPushButton,
    QSplitter,
    QTableWidget,
    QTableWidgetItem,
    QVBoxLayout,
    QWidget,
)

from app.gui.hazard_view import format_value

logger = logging.getLogger(__name__)

POLL_MS = 1000
KILL_AFTER_MS = 15_000
STATUS_COLOURS = {"completed": "#e6f4ea", "failed": "#fce8e6", "error": "#fce8e6", "invalid": "#fef7e0",
                  "running": "#e8f0fe", "pending": "#ffffff"}
#: The background of a provisional measure (the run ended still moving).
PROVISIONAL_COLOUR = "#fff4e5"


def folder_kind(path: Path) -> str | None:
    """``"sweep"``, ``"calibration"`` or None for a folder without either file."""
    if (path / "sweep.csv").is_file():
        return "sweep"
    if (path / "calibration.csv").is_file():
        return "calibration"
    return None


class SweepView(QWidget):
    """Progress, runs, exceedance curve and probability profile of one sweep folder.

    Signals
    -------
    message(str)
        Status-bar text.
    resultsRequested(str)
        A run's results folder to open (a double-click on its row).
    finished(int)
        The child process ended (its exit code).
    """

    message = Signal(str)
    resultsRequested = Signal(str)
    finished = Signal(int)

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        from matplotlib.backends.backend_qtagg import FigureCanvasQTAgg
        from matplotlib.figure import Figure

        self.path: Path | None = None
        self.kind: str | None = None
        self.data: Any = None
        self.process: QProcess | None = None
        self.exit_code: int | None = None
        self.stderr: deque[str] = deque(maxlen=30)
        self._stamp: tuple[Any, ...] | None = None
        self.header = QLabel("No sweep. Run ▸ Sweep or calibration… defines one from the open project.")
        self.header.setWordWrap(True)
        self.header.setStyleSheet("padding: 3px; color: #3c4043;")
        self.bar = QProgressBar()
        self.bar.setFormat("%v / %m runs")
        self.cancel_button = QPushButton("Stop sweep")
        self.cancel_button.setEnabled(False)
        self.cancel_button.clicked.connect(self.cancel)
        self.report_button = QPushButton("Open report")
        self.report_button.setEnabled(False)
        self.report_button.clicked.connect(self.open_report)
        top = QHBoxLayout()
        top.addWidget(self.bar, 1)
        top.addWidget(self.cancel_button)
        top.addWidget(self.report_button)
        self.table = QTableWidget(0, 0)
        self.table.verticalHeader().setVisible(False)
        self.table.setEditTriggers(QTableWidget.EditTrigger.NoEditTriggers)
        self.table.setSelectionBehavior(QTableWidget.SelectionBehavior.SelectRows)
        self.table.horizontalHeader().setSectionResizeMode(QHeaderView.ResizeMode.ResizeToContents)
        self.table.setToolTip("Double-click a completed run to open its results")
        self.table.cellDoubleClicked.connect(self._open_run)
        self.measure = QComboBox()
        self.measure.setToolTip("The measure whose exceedance curve is drawn, and against the parameter")
        self.measure.currentTextChanged.connect(lambda _t: self._draw())
        self.parameter = QComboBox()
        self.parameter.setToolTip("The parameter the measure is drawn against (each completed run a point)")
        self.parameter.currentTextChanged.connect(lambda _t: self._draw())
        mrow = QHBoxLayout()
        mrow.addWidget(QLabel("Measure"))
        mrow.addWidget(self.measure, 1)
        mrow.addWidget(QLabel("against"))
        mrow.addWidget(self.parameter, 1)
        self.figure = Figure(figsize=(9.0, 3.6))
        self.canvas = FigureCanvasQTAgg(self.figure)
        self.canvas.setMinimumHeight(220)
        plots = QWidget()
        pl = QVBoxLayout(plots)
        pl.setContentsMargins(0, 0, 0, 0)
        pl.addLayout(mrow)
        pl.addWidget(self.canvas, 1)
        split = QSplitter(Qt.Orientation.Vertical)
        split.addWidget(self.table)
        split.addWidget(plots)
        split.setSizes([300, 420])
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.addWidget(self.header)
        layout.addLayout(top)
        layout.addWidget(split, 1)
        self._timer = QTimer(self)
        self._timer.setInterval(POLL_MS)
        self._timer.timeout.connect(self.refresh)
        self._kill_timer = QTimer(self)
        self._kill_timer.setSingleShot(True)
        self._kill_timer.setInterval(KILL_AFTER_MS)
        self._kill_timer.timeout.connect(self._kill)

    # -- the child process ------------------------------------------------------------------------

    @property
    def running(self) -> bool:
        return self.process is not None and self.process.state() != QProcess.ProcessState.NotRunning

    def command(self, spec_path: Path, out_dir: Path, workers: int | None = None) -> list[str]:
        from sweeps.spec import command_line

        return command_line(spec_path, out_dir, workers=workers)

    def start(self, spec_path: Path, out_dir: Path, workers: int | None = None) -> bool:
        """Start ``runout sweep SPEC --out OUT`` (or ``calibrate``) and follow ``OUT``."""
        from app.gui.run_process import REPO_ROOT
        from projects.schema import ProjectError

        if self.running:
            self.message.emit("A sweep is running: stop it first")
            return False
        try:
            cmd = self.command(spec_path, out_dir, workers)
        except ProjectError as err:
            self.header.setText(f"Cannot start the sweep: {err}")
            return False
        self.path = Path(out_dir)
        self.kind = "calibration" if "calibrate" in cmd[:4] else "sweep"
        self.data = None
        self._stamp = None
        self.exit_code = None
        self.stderr.clear()
        self.table.setRowCount(0)
        self.path.mkdir(parents=True, exist_ok=True)
        process = QProcess(self)
        env = QProcessEnvironment.systemEnvironment()
        paths = [str(REPO_ROOT), *[p for p in env.value("PYTHONPATH", "").split(os.pathsep) if p]]
        env.insert("PYTHONPATH", os.pathsep.join(dict.fromkeys(paths)))
        process.setProcessEnvironment(env)
        process.setWorkingDirectory(str(self.path))
        process.readyReadStandardError.connect(self._read_stderr)
        process.finished.connect(self._finished)
        process.errorOccurred.connect(self._error)
        process.setProgram(cmd[0])
        process.setArguments(cmd[1:])
        self.process = process
        process.start()
        self.cancel_button.setEnabled(True)
        self.report_button.setEnabled(False)
        self.header.setText(f"{self.kind.capitalize()} {self.path} starting: {' '.join(cmd[3:])}")
        self._timer.start()
        self.message.emit(f"Started the {self.kind} into {self.path}")
        return True

    def _read_stderr(self) -> None:
        if self.process is None:
            return
        text = bytes(self.process.readAllStandardError()).decode("utf-8", "replace")
        for line in text.replace("\r", "\n").splitlines():
            if line.strip():
                self.stderr.append(line.strip())

    def _error(self, error: QProcess.ProcessError) -> None:
        if error == QProcess.ProcessError.FailedToStart:
            self._timer.stop()
            self.cancel_button.setEnabled(False)
            self.exit_code = -1
            self.header.setText(f"The {self.kind} process did not start: {self.process.errorString()}")
            self.finished.emit(-1)

    def _finished(self, code: int, _status: Any) -> None:
        self._kill_timer.stop()
        self._read_stderr()
        self.exit_code = int(code)
        self.cancel_button.setEnabled(False)
        self._timer.stop()
        self.refresh(force=True)
        if code != 0:
            last = next((line for line in reversed(self.stderr) if "%" not in line), "")
            self.header.setText(self.header.text() + f"   — the {self.kind} process ended with exit code {code}"
                                + (f": {last}" if last else ""))
        self.finished.emit(int(code))

    def cancel(self) -> None:
        """Stop the sweep (SIGTERM: no further run starts; finished runs are kept and reused)."""
        if self.running:
            self.process.terminate()
            self._kill_timer.start()
            self.message.emit("Stopping the sweep (finished runs are kept)")

    def _kill(self) -> None:
        if self.running:
            self.process.kill()

    def wait(self, timeout_ms: int = 60_000) -> bool:
        """Wait for the child (tests and scripts); True when it ended."""
        if self.process is None:
            return True
        done = self.process.waitForFinished(timeout_ms) or not self.running
        return done

    def shutdown(self) -> None:
        self._timer.stop()
        if self.running:
            self.process.terminate()
            if not self.process.waitForFinished(KILL_AFTER_MS):
                self.process.kill()
                self.process.waitForFinished(5000)
        self.figure.clear()

    # -- the folder -------------------------------------------------------------------------------

    def open_folder(self, path: Path) -> None:
        """Show a sweep or calibration folder (one this window did not start).

        Raises
        ------
        sweeps.folder.SweepFolderError
        """
        from sweeps.folder import SweepFolderError

        kind = folder_kind(Path(path))
        if kind is None:
            raise SweepFolderError(f"{path} is not a sweep or calibration folder (no sweep.csv or calibration.csv)")
        if self.running and Path(path) != self.path:
            self.message.emit("A sweep is running: its folder stays followed")
            return
        self.path, self.kind = Path(path), kind
        self._stamp = None
        self.refresh(force=True)
        if self.data is None:
            raise SweepFolderError(f"{path} is not a readable {kind} folder")

    def _files_stamp(self) -> tuple[Any, ...]:
        out = []
        for name in ("sweep.csv", "calibration.csv", "progress.json", "report.html"):
            try:
                out.append((self.path / name).stat().st_mtime_ns)
            except OSError:
                out.append(None)
        return tuple(out)

    def refresh(self, force: bool = False) -> bool:
        """Reread the folder when its files changed; True when something new was shown."""
        if self.path is None:
            return False
        stamp = self._files_stamp()
        if not force and stamp == self._stamp:
            return False
        self._stamp = stamp
        from sweeps.folder import SweepFolderError

        try:
            if self.kind == "calibration":
                from sweeps.calibrate import read_calibration

                data = read_calibration(self.path)
            else:
                from sweeps.folder import read_sweep

                data = read_sweep(self.path)
        except SweepFolderError:
            if self.running:
                self.header.setText(f"{(self.kind or 'sweep').capitalize()} {self.path}: planning the runs, "
                                    "starting Ray…")
            return False
        self.data = data
        self._fill(data)
        self._draw()
        return True

    def _progress(self) -> dict[str, Any]:
        import json

        try:
            return json.loads((self.path / "progress.json").read_text(encoding="utf-8"))
        except (OSError, ValueError):
            return {}

    def _fill(self, data: Any) -> None:
        from sweeps.folder import PROVISIONAL_LEGEND, PROVISIONAL_MARK, row_still_moving

        progress = self._progress()
        rows = data.rows
        if self.kind == "sweep":
            measures = list(data.measures)
            columns = ["run", "status", *data.parameters, *measures, "still_moving", "wall_time_s", "message"]
        else:
            measures = ["misfit"]
            columns = ["trial", "status", *data.parameters, "misfit", "still_moving", "wall_time_s", "message"]
        moving = sum(row_still_moving(r) and r.get("status") == "completed" for r in rows)
        total = int(progress.get("total") or len(rows))
        done = int(progress.get("done") or sum(r.get("status") not in ("pending", "") for r in rows))
        failed = int(progress.get("failed") or 0)
        self.bar.setRange(0, max(total, 1))
        self.bar.setValue(done)
        eta = progress.get("eta_s")
        state = "running" if self.running else ("finished" if done >= total and total else "stopped")
        self.header.setText(
            f"{self.kind.capitalize()} {self.path}   [{state}]   {done} of {total} runs done, {failed} not completed"
            + (f", about {eta:.0f} s left" if self.running and isinstance(eta, (int, float)) and eta > 0 else "")
            + (f", elapsed {progress['elapsed_s']:.0f} s" if progress.get("elapsed_s") else "")
            + (f", {moving} ended still moving (measures provisional, {PROVISIONAL_MARK})" if moving else ""))
        self.report_button.setEnabled((self.path / "report.html").is_file())
        self.table.setColumnCount(len(columns))
        self.table.setHorizontalHeaderLabels(columns)
        self.table.setRowCount(len(rows))
        for r, row in enumerate(rows):
            status = row.get("status", "")
            colour = QColor(STATUS_COLOURS.get(status, "#ffffff"))
            provisional = status == "completed" and row_still_moving(row)
            for c, col in enumerate(columns):
                text = row.get(col, "")
                if col == "still_moving":
                    text = {"true": "yes", "false": "no"}.get(text.strip().lower(), "–")
                elif col not in ("status", "message", "run", "trial"):
                    try:
                        text = format_value(float(text)) if text != "" else "–"
                    except ValueError:
                        pass
                mark = provisional and col in measures and text != "–"
                amber = mark or (provisional and col == "still_moving")
                item = QTableWidgetItem(f"{text} {PROVISIONAL_MARK}" if mark else text)
                item.setBackground(QColor(PROVISIONAL_COLOUR) if amber else colour)
                if col == "message":
                    item.setToolTip(row.get(col, ""))
                elif amber:
                    item.setToolTip(PROVISIONAL_LEGEND)
                self.table.setItem(r, c, item)
        current = self.measure.currentText()
        self.measure.blockSignals(True)
        self.measure.clear()
        self.measure.addItems(measures)
        if current in measures:
            self.measure.setCurrentText(current)
        else:
            preferred = next((m for m in measures if m.endswith("runout_distance_m")), measures[0] if measures else "")
            self.measure.setCurrentText(preferred)
        self.measure.blockSignals(False)
        chosen = self.parameter.currentText()
        self.parameter.blockSignals(True)
        self.parameter.clear()
        self.parameter.addItems(list(data.parameters))
        if chosen in data.parameters:
            self.parameter.setCurrentText(chosen)
        self.parameter.blockSignals(False)
        self.parameter.setVisible(self.kind == "sweep")

    def _open_run(self, row: int, _column: int) -> None:
        if self.data is None or row >= len(self.data.rows):
            return
        folder = self.data.rows[row].get("results_dir", "")
        if folder and Path(folder).is_dir() and self.data.rows[row].get("status") in ("completed", "failed"):
            self.resultsRequested.emit(folder)

    def open_report(self) -> bool:
        if self.path is None or not (self.path / "report.html").is_file():
            return False
        return QDesktopServices.openUrl(QUrl.fromLocalFile(str(self.path / "report.html")))

    # -- plots ------------------------------------------------------------------------------------

    def exceedance(self) -> Any:
        """The exceedance curve of the chosen measure over the completed runs (or None)."""
        from sweeps.analysis import exceedance

        if self.data is None or self.kind != "sweep" or not self.measure.currentText():
            return None
        return exceedance(self.data.column(self.measure.currentText()))

    def measure_against_parameter(self) -> tuple[str, np.ndarray, np.ndarray] | None:
        """The chosen measure of each completed run against the chosen parameter, sorted by the
        parameter: ``(parameter, values, measures)`` (None without a sweep, a measure or a parameter).
        A sweep of a few values (a list, a range, a grid) reads here, where its exceedance curve of
        three samples says little."""
        against = self._against()
        return None if against is None else against[:3]

    def provisional_against_parameter(self) -> np.ndarray | None:
        """Which points of :meth:`measure_against_parameter` are runs that ended still moving
        (their measures provisional), in the same order."""
        against = self._against()
        return None if against is None else against[3]

    def _against(self) -> tuple[str, np.ndarray, np.ndarray, np.ndarray] | None:
        from sweeps.folder import row_still_moving

        if self.data is None or self.kind != "sweep" or not self.measure.currentText() \
                or not self.parameter.currentText():
            return None
        key = self.parameter.currentText()
        x = np.asarray(self.data.column(key), dtype=float)
        y = np.asarray(self.data.column(self.measure.currentText()), dtype=float)
        moving = np.array([row_still_moving(r) for r in self.data.completed()], dtype=bool)
        if len(x) != len(y) or len(moving) != len(x):
            return None
        ok = np.isfinite(x) & np.isfinite(y)
        order = np.argsort(x[ok], kind="stable")
        return key, x[ok][order], y[ok][order], moving[ok][order]

    def probability_profile(self) -> Any:
        """The probability profile of the completed runs (or None without a [profile])."""
        from sweeps.analysis import probability_profile

        if self.data is None or self.kind != "sweep" or not self.data.profile_field():
            return None
        return probability_profile(self.data.profiles(), self.data.thresholds())

    def _draw(self) -> None:
        fig = self.figure
        fig.clear()
        if self.data is None:
            self.canvas.draw_idle()
            return
        if self.kind == "calibration":
            self._draw_calibration()
            return
        left, middle, right = fig.subplots(1, 3)
        ex = self.exceedance()
        name = self.measure.currentText()
        if ex is not None and ex.n:
            xs = np.concatenate([[ex.samples[0]], ex.x])
            ps = np.concatenate([[1.0], ex.p])
            left.step(xs, ps, where="post", color="tab:blue", label=f"P(X > x), n = {ex.n}")
            lo = np.clip(ps - ex.eps, 0, 1)
            hi = np.clip(ps + ex.eps, 0, 1)
            left.fill_between(xs, lo, hi, step="post", color="tab:blue", alpha=0.15, label="95 % DKW band")
            left.plot(ex.samples, np.zeros_like(ex.samples), "|", color="k", ms=10)
            left.legend(fontsize=7)
        else:
            left.text(0.5, 0.5, "no completed run yet", ha="center", va="center", transform=left.transAxes)
        left.set_ylim(-0.02, 1.02)
        left.set_xlabel(name, fontsize=8)
        left.set_ylabel("probability of exceedance", fontsize=8)
        left.set_title("Exceedance curve", fontsize=9)
        against = self.measure_against_parameter()
        if against is not None and len(against[1]):
            key, xs_p, ys_p = against
            middle.plot(xs_p, ys_p, "o-", color="tab:green", ms=5, lw=1, label=f"{len(xs_p)} completed runs")
            moving = self.provisional_against_parameter()
            if moving is not None and moving.any():
                # hollow orange: runs that ended still moving, their measures provisional
                middle.plot(xs_p[moving], ys_p[moving], "o", ms=8, mfc="none", mec="tab:orange", mew=1.5,
                            label=f"{int(moving.sum())} ended still moving (provisional)")
            middle.legend(fontsize=7)
            middle.set_xlabel(key, fontsize=8)
        else:
            middle.text(0.5, 0.5, "no completed run yet" if self.data.parameters else "no parameter",
                        ha="center", va="center", transform=middle.transAxes)
        middle.set_ylabel(name, fontsize=8)
        middle.set_title("Measure against parameter", fontsize=9)
        prof = self.probability_profile()
        field = self.data.profile_field()
        if prof is not None and prof.n:
            for k, t in enumerate(prof.thresholds):
                line, = right.plot(prof.x_m, prof.p[k], label=f"{field} > {t:g}")
                right.fill_between(prof.x_m, prof.lower[k], prof.upper[k], color=line.get_color(), alpha=0.15)
            right.legend(fontsize=7)
            right.set_title(f"Probability profile ({prof.n} runs)", fontsize=9)
            right.text(0.98, 0.02, "bands: Wilson 95 %", ha="right", va="bottom", fontsize=7, color="#5f6368",
                       transform=right.transAxes)
        else:
            right.text(0.5, 0.5, "no profile" if not field else "no completed run yet", ha="center", va="center",
                       transform=right.transAxes)
            right.set_title("Probability profile", fontsize=9)
        right.set_ylim(-0.02, 1.02)
        right.set_xlabel("x (m)", fontsize=8)
        right.set_ylabel("probability", fontsize=8)
        for a in (left, middle, right):
            a.tick_params(labelsize=8)
            a.grid(True, color="#e6e6e6", linewidth=0.6)
        fig.subplots_adjust(left=0.06, right=0.99, top=0.9, bottom=0.16, wspace=0.32)
        self.canvas.draw_idle()

    def _draw_calibration(self) -> None:
        data = self.data
        params = list(data.parameters)
        axes = self.figure.subplots(1, max(1, len(params)), squeeze=False)[0]
        misfit = data.column("misfit")
        for ax, key in zip(axes, params):
            values = data.column(key)
            ok = np.isfinite(misfit) & np.isfinite(values)
            ax.plot(values[ok], misfit[ok], "o", color="tab:blue", ms=4)
            if ok.any():
                best = int(np.flatnonzero(ok)[np.argmin(misfit[ok])])
                ax.plot(values[best], misfit[best], "*", color="tab:red", ms=12,
                        label=f"best {values[best]:.4g} (misfit {misfit[best]:.3g})")
                ax.legend(fontsize=7)
            ax.set_xlabel(key, fontsize=8)
            ax.set_ylabel("misfit", fontsize=8)
            ax.tick_params(labelsize=8)
            ax.grid(True, color="#e6e6e6", linewidth=0.6)
            ax.set_title("Misfit landscape", fontsize=9)
        self.figure.subplots_adjust(left=0.07, right=0.98, top=0.9, bottom=0.16, wspace=0.3)
        self.canvas.draw_idle()
