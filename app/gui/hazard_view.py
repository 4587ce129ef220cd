"""The Hazard tab: the envelopes of a run along the section, drawn over the scene, its run-out
measures and its targets, and the export of the HTML report (``runout report``).

Everything here is read from the results folder (``hazard.json``, ``hazard_profile.csv``,
``targets.csv``: :func:`projects.hazard.read_hazard`), the same files ``runout report`` reads;
the report itself is written by :func:`app.report.write_report` in this process (matplotlib and
VTK offscreen; neither imports Taichi).
"""

from __future__ import annotations

import logging
import math
import os
from pathlib import Path
from typing import Any

import numpy as np
from PySide6.QtCore import Qt, QUrl, Signal
from PySide6.QtGui import QDesktopServices
from PySide6.QtWidgets import (
    QHBoxLayout,
    QHeaderView,
    QLabel,
    QPushButton,
    QSplitter,
    QTableWidget,
    QTableWidgetItem,
    QVBoxLayout,
    QWidget,
)

logger = logging.getLogger(__name__)

#: Rows of the target table: (key in hazard.json's target, header, unit).
TARGET_COLUMNS: tuple[tuple[str, str, str], ...] = (
    ("x_m", "x", "m"),
    ("arrival_time_s", "arrival", "s"),
    ("arrival_after_release_s", "after release", "s"),
    ("max_height_m", "max height", "m"),
    ("max_speed_m_s", "max speed", "m/s"),
    ("max_pressure_pa", "max pressure", "kPa"),
)

#: The colour of the header of a run whose measures are provisional (app.gui.run_panel's too).
PROVISIONAL_COLOR = "#e37400"
#: Characters of a measure's name before it wraps (the value column stays in view in the pane).
NAME_CHARS = 26


def format_value(value: Any, unit: str = "", digits: int = 4) -> str:
    """A measure as text: ``-`` for a missing value, ``g`` format with ``digits`` digits."""
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "–"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, (int, float)):
        text = f"{value:.{digits}g}"
    else:
        text = str(value)
    return f"{text} {unit}".strip()


def has_hazard(path: str | os.PathLike[str]) -> bool:
    """Whether a results folder holds the hazard files."""
    from projects.hazard import HAZARD_JSON, PROFILE_CSV

    p = Path(path)
    return (p / HAZARD_JSON).is_file() and (p / PROFILE_CSV).is_file()


def measure_rows(doc: dict[str, Any]) -> list[tuple[str, str, str]]:
    """(label, value with unit, threshold) of each measure of :data:`app.report.MEASURES` in ``doc``;
    every value of a run that is not final (:func:`projects.motion.hazard_provisional`: the mass
    still moving at its end, or the run not completed) is marked "(provisional)"."""
    from app.report import MEASURES, measure_value
    from projects.motion import hazard_provisional

    thresholds = doc.get("thresholds") or {}
    mark = " (provisional)" if hazard_provisional(doc) else ""
    rows = []
    for key, label, unit, threshold in MEASURES:
        if key not in doc:
            continue
        th = f"{threshold} = {thresholds[threshold]:g}" if threshold and threshold in thresholds else ""
        value = format_value(measure_value(doc, key, unit), unit)
        rows.append((label, value + (mark if value != "–" else ""), th))
    return rows


def export_report(results: str | os.PathLike[str], out_dir: str | os.PathLike[str] | None = None) -> Path:
    """Write the hazard report of a results folder (``report.html`` and its PNGs).

    The same function as ``runout report RESULTS`` (:func:`app.report.write_report`); it renders
    offscreen and does not import Taichi.

    Returns
    -------
    Path
        ``report.html``.

    Raises
    ------
    projects.results.ResultsError
        When the folder has no hazard files.
    """
    from app.report import write_report

    return write_report(results, out_dir)


class HazardView(QWidget):
    """Envelope profiles over the scene, the measures and the target table of a results folder.

    Signals
    -------
    message(str)
        Status-bar text.
    """

    message = Signal(str)

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        from matplotlib.backends.backend_qtagg import FigureCanvasQTAgg
        from matplotlib.figure import Figure

        self.path: Path | None = None
        self.doc: dict[str, Any] | None = None
        self._stamp: float | None = None
        self.last_report: Path | None = None
        self.report_opened: bool | None = None  # whether a browser took the last report
        self.header = QLabel("Open a results folder with hazard files (a run with a dynamic stage).")
        self.header.setWordWrap(True)
        self.header.setStyleSheet("padding: 3px; color: #3c4043;")
        self.export_button = QPushButton("Export report…")
        self.export_button.setToolTip("Write the HTML report (runout report) and open it")
        self.export_button.setEnabled(False)
        top = QHBoxLayout()
        top.addWidget(self.header, 1)
        top.addWidget(self.export_button)
        #: where the last report went, stays on view (the browser it opens in covers the window)
        self.report_label = QLabel("")
        self.report_label.setTextFormat(Qt.TextFormat.RichText)
        self.report_label.setTextInteractionFlags(Qt.TextInteractionFlag.TextBrowserInteraction)
        self.report_label.setOpenExternalLinks(True)
        self.report_label.setWordWrap(True)
        self.report_label.setStyleSheet("padding: 0 3px 3px 3px; color: #3c4043;")
        self.report_label.setVisible(False)

        # constrained: the legend above the plots takes its room from them (_draw)
        self.figure = Figure(figsize=(8.0, 9.0), layout="constrained")
        self.canvas = FigureCanvasQTAgg(self.figure)
        self.canvas.setMinimumHeight(300)
        self.measures = QTableWidget(0, 3)
        self.measures.setHorizontalHeaderLabels(["Measure", "Value", "Threshold"])
        self.targets = QTableWidget(0, 1 + len(TARGET_COLUMNS))
        # the unit on a second line: the headers, not the values, set these columns' widths
        self.targets.setHorizontalHeaderLabels(
            ["Target"] + [f"{h}\n({u})" for _k, h, u in TARGET_COLUMNS])
        for table in (self.measures, self.targets):
            table.verticalHeader().setVisible(False)
            table.verticalHeader().setSectionResizeMode(QHeaderView.ResizeMode.ResizeToContents)
            table.setEditTriggers(QTableWidget.EditTrigger.NoEditTriggers)
            # every column as wide as its header and values, never elided: a stretched last
            # section kept Qt's default 100 px where there was no room to stretch ("max pressure
            # (k…"); a table narrower than its columns scrolls
            table.horizontalHeader().setSectionResizeMode(QHeaderView.ResizeMode.ResizeToContents)
            table.setHorizontalScrollMode(QTableWidget.ScrollMode.ScrollPerPixel)
        # the measures' names wrap, so that each value stands beside its name in a narrow pane
        self.measures.horizontalHeader().setSectionResizeMode(0, QHeaderView.ResizeMode.Interactive)
        self.measures.setWordWrap(True)
        self.context = QLabel("")
        self.context.setWordWrap(True)
        self.context.setStyleSheet("color: #5f6368; font-size: 11px;")
        side = QWidget()
        side_layout = QVBoxLayout(side)
        side_layout.setContentsMargins(0, 0, 0, 0)
        side_layout.addWidget(QLabel("<b>Run-out measures</b>"))
        side_layout.addWidget(self.measures, 3)
        side_layout.addWidget(QLabel("<b>Targets</b>"))
        side_layout.addWidget(self.targets, 1)
        side_layout.addWidget(self.context)
        split = QSplitter(Qt.Orientation.Horizontal)
        split.addWidget(self.canvas)
        split.addWidget(side)
        split.setStretchFactor(0, 3)
        split.setStretchFactor(1, 2)
        split.setSizes([760, 560])
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.addLayout(top)
        layout.addWidget(self.report_label)
        layout.addWidget(split, 1)
        self.export_button.clicked.connect(self.export_and_open)

    # -- reading ----------------------------------------------------------------------------------

    def clear(self, text: str = "") -> None:
        self.report_label.setVisible(False)
        self.path = None
        self.doc = None
        self._stamp = None
        self.figure.clear()
        self.canvas.draw_idle()
        self.measures.setRowCount(0)
        self.targets.setRowCount(0)
        self.context.setText("")
        self.export_button.setEnabled(False)
        self.header.setText(text or "This results folder has no hazard files (no dynamic stage ran, "
                            "or hazard.enabled = false).")

    def show_results(self, path: str | os.PathLike[str], results: Any = None) -> bool:
        """Show the hazard files of a results folder; reread only when ``hazard.json`` changed.

        Parameters
        ----------
        path : path-like
            The results folder.
        results : projects.results.Results, optional
            The open results (its last frame is drawn as the scene under the envelopes).

        Returns
        -------
        bool
            Whether the folder has hazard files.
        """
        from projects.hazard import HAZARD_JSON, read_hazard

        p = Path(path)
        if not has_hazard(p):
            self.clear()
            return False
        try:
            stamp = (p / HAZARD_JSON).stat().st_mtime_ns
        except OSError:
            stamp = None
        if self.path == p and stamp is not None and stamp == self._stamp:
            return True
        try:
            doc = read_hazard(p)
        except (OSError, ValueError, KeyError) as err:
            self.clear(f"Cannot read the hazard files of {p}: {err}")
            return False
        if self.path != p:
            self.report_label.setVisible(False)  # the report named there is another folder's
        self.path, self.doc, self._stamp = p, doc, stamp
        scene = None
        structures = results.summary.get("structures") if results is not None else None
        if results is not None and len(results):
            try:
                frame = results.frame(len(results) - 1)
                keep = frame["active"]
                scene = np.asarray(frame["positions"])[keep]
            except Exception:  # a frame being written: the envelopes are drawn without the scene
                logger.debug("no scene under the envelopes", exc_info=True)
        self._draw(doc, scene, structures)
        self._fill_tables(doc)
        from projects.motion import hazard_provisional, motion_text

        status = doc.get("status", "?")
        text = (f"Hazard of {p}   [{status}]   released at t = {format_value(doc.get('release_time_s'), 's')}, "
                f"envelopes to t = {format_value(doc.get('time_s'), 's')}")
        if hazard_provisional(doc) and status in ("completed", "stopped"):
            why = motion_text(doc.get("motion_at_end")) or "the mass was still moving at the end"
            text += f"\nPROVISIONAL: {why}. Every measure below is provisional, not the run-out."
            self.header.setStyleSheet(f"padding: 3px; color: {PROVISIONAL_COLOR}; font-weight: bold;")
        else:
            self.header.setStyleSheet("padding: 3px; color: #3c4043;")
        self.header.setText(text)
        self.export_button.setEnabled(True)
        return True

    def _fill_tables(self, doc: dict[str, Any]) -> None:
        rows = measure_rows(doc)
        self.measures.setRowCount(len(rows))
        for r, row in enumerate(rows):
            for c, text in enumerate(row):
                self.measures.setItem(r, c, QTableWidgetItem(text))
        self._fit_names(self.measures)
        targets = doc.get("targets") or {}
        self.targets.setRowCount(len(targets))
        for r, (name, t) in enumerate(targets.items()):
            self.targets.setItem(r, 0, QTableWidgetItem(f"{name} ({t.get('kind', '')})"))
            for c, (key, _h, unit) in enumerate(TARGET_COLUMNS, start=1):
                value = t.get(key)
                if unit == "kPa" and isinstance(value, (int, float)):
                    value = value / 1000.0
                self.targets.setItem(r, c, QTableWidgetItem(format_value(value)))
        notes = [doc["note"]] if doc.get("note") else []
        sampling = doc.get("sampling") or {}
        if sampling.get("every_steps"):
            notes.append(f"Envelopes updated every {sampling['every_steps']} steps "
                         f"({sampling.get('updates', '?')} updates).")
        self.context.setText(" ".join(notes))

    @staticmethod
    def _fit_names(table: QTableWidget) -> None:
        """The name column as wide as its names, but at most :data:`NAME_CHARS` characters (the
        longer names wrap) and never narrower than a name's longest word."""
        fm = table.fontMetrics()
        margin = 2 * table.style().pixelMetric(table.style().PixelMetric.PM_FocusFrameHMargin) + 8
        texts = [table.item(r, 0).text() for r in range(table.rowCount()) if table.item(r, 0) is not None]
        words = max((fm.horizontalAdvance(w) for t in texts for w in t.split()), default=0) + margin
        widest = max([fm.horizontalAdvance(t) + margin for t in texts]
                     + [table.horizontalHeader().sectionSizeHint(0)])
        table.setColumnWidth(0, max(words, min(widest, fm.averageCharWidth() * NAME_CHARS)))
        table.resizeRowsToContents()

    def _draw(self, doc: dict[str, Any], scene: np.ndarray | None, structures: list | None = None) -> None:
        from app.report import _target_lines, structure_patches

        p = doc["profile"]
        fig = self.figure
        fig.clear()
        if "x_m" not in p or not len(p["x_m"]):
            self.canvas.draw_idle()
            return
        x = p["x_m"]
        axes = fig.subplots(5, 1, sharex=True, gridspec_kw={"height_ratios": [2.2, 1, 1, 1, 1]})
        ax = axes[0]
        ax.fill_between(x, p["floor_m"], p["ground_m"], color="0.88", step="mid", label="material at the release")
        structure_patches(ax, structures)
        if scene is not None and len(scene):
            ax.plot(scene[:, 0], scene[:, 1], ",", color="0.45", alpha=0.6, label="particles (last frame)")
        ax.fill_between(x, p["ground_m"], p["ground_m"] + np.nan_to_num(p["peak_flow_height_m"]), step="mid",
                        color="tab:orange", alpha=0.35, label="peak flow height")
        ax.step(x, p["surface_m"], where="mid", color="tab:brown", lw=1.4, label="surface at the end")
        if doc.get("runout_point_m"):
            ax.plot(*doc["runout_point_m"], marker="v", color="k", ms=8, ls="none", label="run-out (deposit)")
        if doc.get("source_top_m"):
            ax.plot(*doc["source_top_m"], marker="^", color="k", ms=7, ls="none", label="source top")
            if doc.get("runout_point_m"):
                (x0, y0), (x1, y1) = doc["source_top_m"], doc["runout_point_m"]
                ax.plot([x0, x1], [y0, y1], color="k", lw=0.8, ls="--",
                        label=f"travel angle {format_value(doc.get('travel_angle_deg'), '°', 3)}")
        ax.set_ylabel("y (m)", fontsize=8)
        ax.set_aspect("auto")
        # above the plots, not in them: in the upper right corner it covered the names of the
        # targets downstream, where they usually are
        fig.legend(*ax.get_legend_handles_labels(), fontsize=7, loc="outside upper center", ncols=2)
        series = (
            (axes[1], p["max_speed_m_s"], 1.0, "peak speed (m/s)", "tab:blue"),
            (axes[2], p["max_pressure_pa"], 1e-3, "peak pressure (kPa)", "tab:red"),
            (axes[3], p["arrival_s"], 1.0, "arrival (s)", "tab:green"),
            (axes[4], p["deposit_m"], 1.0, "deposit (m)", "tab:brown"),
        )
        for a, values, scale, label, colour in series:
            a.step(x, values * scale, where="mid", color=colour, lw=1.2)
            a.set_ylabel(label, fontsize=8)
        axes[4].axhline(0.0, color="0.6", lw=0.6)
        axes[4].set_xlabel("x (m)", fontsize=8)
        for a in axes:
            a.tick_params(labelsize=8)
            a.grid(True, color="#e6e6e6", linewidth=0.6)
            _target_lines(a, doc, label=a is axes[0])
        fig.get_layout_engine().set(h_pad=0.02, hspace=0.0)
        self.canvas.draw_idle()

    # -- the report -------------------------------------------------------------------------------

    def export_report(self, out_dir: str | os.PathLike[str] | None = None) -> Path | None:
        """Write the report of the shown folder (default ``RESULTS/report``); None on an error."""
        from projects.results import ResultsError

        if self.path is None:
            return None
        from PySide6.QtWidgets import QApplication

        QApplication.setOverrideCursor(Qt.CursorShape.WaitCursor)
        try:
            html = export_report(self.path, out_dir)
        except (ResultsError, OSError, ValueError) as err:
            self.message.emit(f"Cannot write the report: {err}")
            return None
        finally:
            QApplication.restoreOverrideCursor()
        self.last_report = html
        self.show_report_place(html)
        self.message.emit(f"Wrote {html}")
        return html

    def show_report_place(self, html: Path, opened: bool | None = None) -> None:
        """Say where the report is, in the tab, until another folder is shown: the file (a link
        that opens it) and its folder (a link that opens the folder)."""
        from html import escape

        file_url = QUrl.fromLocalFile(str(html)).toString()
        folder_url = QUrl.fromLocalFile(str(html.parent)).toString()
        note = "" if opened is None else (" (opened in the web browser)" if opened else
                                          " (no web browser could be opened here: open the file in one)")
        self.report_label.setText(f"Report written to <a href=\"{escape(file_url)}\">{escape(str(html))}</a>"
                                  f"{escape(note)} · <a href=\"{escape(folder_url)}\">open its folder</a>")
        self.report_label.setToolTip(str(html))
        self.report_label.setVisible(True)
        self.report_opened = opened

    def open_report(self, html: Path) -> bool:
        return QDesktopServices.openUrl(QUrl.fromLocalFile(str(html)))

    def export_and_open(self) -> Path | None:
        html = self.export_report()
        if html is None:
            return None
        opened = self.open_report(html)
        self.show_report_place(html, opened)
        if not opened:
            # no browser to hand it to (no desktop launcher): say where the report is
            self.message.emit(f"Wrote {html}; no web browser could be opened here: open that file in one")
        return html

    def close_view(self) -> None:
        self.figure.clear()
