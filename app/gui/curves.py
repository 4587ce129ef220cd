"""Curves against simulated time (matplotlib's Qt canvas): the run's energy, momentum and speed,
live or from ``series.csv``, the force on each contact from ``contacts.csv``, and the history of
one picked particle.

Redraws are throttled (a timer collects updates), so a fast run cannot flood the event loop.
"""

from __future__ import annotations

import csv
import logging
import os
from pathlib import Path
from typing import Any

import numpy as np
from PySide6.QtCore import QTimer
from PySide6.QtWidgets import QVBoxLayout, QWidget

from app.render import CONTACT_COLORS
from projects.results import contact_curves

logger = logging.getLogger(__name__)

REDRAW_MS = 700

#: Curves of the run: (series.csv column, label, unit, axis).
SERIES_CURVES: tuple[tuple[str, str, str, int], ...] = (
    ("kinetic_energy_J_per_m", "kinetic energy", "J/m", 0),
    ("momentum_x", "momentum x", "N·s/m", 1),
    ("momentum_y", "momentum y", "N·s/m", 1),
    ("max_speed_m_s", "max speed", "m/s", 2),
)
_DIAG_ATTR = {
    "kinetic_energy_J_per_m": "kinetic_energy_J_per_m",
    "momentum_x": "momentum_x",
    "momentum_y": "momentum_y",
    "max_speed_m_s": "max_speed_m_s",
}
_AXIS_LABELS = ("Kinetic energy (J/m)", "Momentum (N·s/m)", "Max speed (m/s)")


class _Canvas(QWidget):
    """A row of matplotlib axes in a widget, redrawn at most every :data:`REDRAW_MS`."""

    def __init__(self, columns: int, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        from matplotlib.backends.backend_qtagg import FigureCanvasQTAgg
        from matplotlib.figure import Figure

        # a fixed layout: constrained layout costs more than the drawing itself
        self.figure = Figure(figsize=(3.2 * columns, 2.2))
        self.figure.subplots_adjust(left=0.06 + 0.02 * columns, right=0.98, top=0.9, bottom=0.2,
                                    wspace=0.42)
        self.canvas = FigureCanvasQTAgg(self.figure)
        self.canvas.setMinimumHeight(150)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.addWidget(self.canvas)
        self.axes = self.figure.subplots(1, columns, sharex=True, squeeze=False)[0, :]
        for ax in self.axes:
            ax.tick_params(labelsize=8)
            ax.ticklabel_format(axis="y", style="sci", scilimits=(-3, 4))
            ax.yaxis.get_offset_text().set_fontsize(7)
            ax.grid(True, color="#e0e0e0", linewidth=0.6)
            ax.set_xlabel("time (s)", fontsize=8)
        self._timer = QTimer(self)
        self._timer.setSingleShot(True)
        self._timer.setInterval(REDRAW_MS)
        self._timer.timeout.connect(self._redraw)
        self.draws = 0

    def schedule(self) -> None:
        if not self._timer.isActive():
            self._timer.start()

    def _redraw(self) -> None:
        for ax in self.axes:
            # the visible lines only: a hidden time marker held the last run's time, so the empty
            # curves of a run before its first frame kept that run's axes (0.0075-0.008 s)
            ax.relim(visible_only=True)
            if any(line.get_visible() and len(line.get_xdata()) for line in ax.lines):
                ax.autoscale(True)  # set_xlim below switched autoscaling off, for good
                ax.autoscale_view()
            else:
                ax.set_xlim(0.0, 1.0)
                ax.set_ylim(0.0, 1.0)
        self.canvas.draw_idle()
        self.draws += 1

    def redraw_now(self) -> None:
        self._timer.stop()
        self._redraw()
        self.canvas.draw()

    def close_canvas(self) -> None:
        self._timer.stop()
        self.figure.clear()


class SeriesCurves(_Canvas):
    """Kinetic energy, momentum (x, y) and max speed against time, with a marker at the shown time."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(3, parent)
        self.lines: dict[str, Any] = {}
        colors = {"kinetic_energy_J_per_m": "#1a73e8", "momentum_x": "#e37400", "momentum_y": "#188038",
                  "max_speed_m_s": "#a142f4"}
        for key, label, _unit, column in SERIES_CURVES:
            (line,) = self.axes[column].plot([], [], color=colors[key], linewidth=1.4, label=label)
            self.lines[key] = line
        for column, text in enumerate(_AXIS_LABELS):
            self.axes[column].set_ylabel(text, fontsize=8)
        self.axes[1].legend(fontsize=7, loc="best")
        self.markers = [ax.axvline(0.0, color="#5f6368", linewidth=0.8, linestyle="--") for ax in self.axes]
        for m in self.markers:
            m.set_visible(False)
        self.data: dict[str, list[float]] = {}
        self.clear()

    def clear(self) -> None:
        self.data = {"time_s": [], **{key: [] for key, *_ in SERIES_CURVES}}
        self._push()

    def append(self, diagnostics: Any) -> None:
        """Add one live point (a solver Diagnostics)."""
        self.data["time_s"].append(float(diagnostics.time_s))
        for key, attr in _DIAG_ATTR.items():
            self.data[key].append(float(getattr(diagnostics, attr)))
        self._push()

    def set_series(self, series: dict[str, np.ndarray], now: bool = True) -> None:
        """Show the columns of a results folder's ``series.csv`` (redrawn at once, or with the
        next scheduled redraw when ``now`` is False: a run under way)."""
        self.data = {"time_s": [float(v) for v in series.get("time_s", [])]}
        for key, *_ in SERIES_CURVES:
            column = series.get(key, [])
            self.data[key] = [float(v) for v in column] if len(column) == len(self.data["time_s"]) else []
        self._push()
        if now:
            self.redraw_now()

    def _push(self) -> None:
        t = self.data["time_s"]
        for key, line in self.lines.items():
            values = self.data.get(key, [])
            line.set_data(t[: len(values)], values)
        self.schedule()

    def set_time(self, time_s: float | None) -> None:
        for m in self.markers:
            m.set_visible(time_s is not None)
            if time_s is not None:
                m.set_xdata([time_s, time_s])
        self.schedule()

    @property
    def points(self) -> int:
        return len(self.data["time_s"])


class HistoryCurve(_Canvas):
    """The value of one field at one particle against time."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(1, parent)
        (self.line,) = self.axes[0].plot([], [], color="#d93025", linewidth=1.4, marker=".", markersize=3)
        self.axes[0].set_title("Pick a particle in the view (click)", fontsize=8)
        self.times: np.ndarray = np.zeros(0)
        self.values: np.ndarray = np.zeros(0)
        self.label = ""

    def show_history(self, particle: int, label: str, times: np.ndarray, values: np.ndarray) -> None:
        self.times, self.values = np.asarray(times, float), np.asarray(values, float)
        self.label = label
        self.line.set_data(self.times, self.values)
        self.axes[0].set_title(f"particle {particle}", fontsize=8)
        self.axes[0].set_ylabel(label, fontsize=8)
        self.redraw_now()

    def clear_history(self) -> None:
        self.times, self.values = np.zeros(0), np.zeros(0)
        self.line.set_data([], [])
        self.axes[0].set_title("Pick a particle in the view (click)", fontsize=8)
        self.redraw_now()


class MonitorCurves(_Canvas):
    """Displacement and speed against time at monitoring points (one line per point)."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(2, parent)
        self.axes[0].set_ylabel("Displacement (m)", fontsize=8)
        self.axes[1].set_ylabel("Speed (m/s)", fontsize=8)
        self.axes[0].set_title("Add a point by its coordinates", fontsize=8)
        self.histories: list[tuple[str, np.ndarray, np.ndarray, np.ndarray]] = []

    def show_histories(self, histories: list[tuple[str, np.ndarray, np.ndarray, np.ndarray]]) -> None:
        """``(label, times_s, displacement_m, speed_m_s)`` per point."""
        self.histories = histories
        for ax in self.axes:
            for line in list(ax.lines):
                line.remove()
        for label, t, disp, speed in histories:
            self.axes[0].plot(t, disp, linewidth=1.3, marker=".", markersize=3, label=label)
            self.axes[1].plot(t, speed, linewidth=1.3, marker=".", markersize=3, label=label)
        self.axes[0].set_title(f"{len(histories)} monitoring point(s)" if histories else
                               "Add a point by its coordinates", fontsize=8)
        if histories:
            self.axes[0].legend(fontsize=7, loc="best")
        elif self.axes[0].get_legend() is not None:
            self.axes[0].get_legend().remove()
        self.redraw_now()


class ProfileCurve(_Canvas):
    """A field along a cross-section line, against the distance from its start."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(1, parent)
        (self.line,) = self.axes[0].plot([], [], color="#1a73e8", linewidth=1.2, marker=".", markersize=3)
        self.axes[0].set_xlabel("distance along the section (m)", fontsize=8)
        self.axes[0].set_title("Give the section's end points", fontsize=8)
        self.distance = np.zeros(0)
        self.values = np.zeros(0)

    def show_profile(self, distance_m: np.ndarray, values: np.ndarray, label: str, title: str) -> None:
        self.distance, self.values = np.asarray(distance_m, float), np.asarray(values, float)
        self.line.set_data(self.distance, self.values)
        self.axes[0].set_ylabel(label, fontsize=8)
        self.axes[0].set_title(title, fontsize=8)
        self.redraw_now()


class ContactCurves(_Canvas):
    """The force the material exerts on each closed side and structure against time: the mean
    over each output interval (left) and the largest single-step force in it (right), N/m, one
    line per contact, drawn as steps over the interval each value belongs to.

    Above the plots, the component to show (:data:`projects.results.CONTACT_COMPONENTS`: the
    magnitude, the signed x or y component, which shows a force that reverses, or the normal and
    tangential parts: a side's along its axes, a structure's on the face that carries it); the legend stands beside the plots, not over the curves, and a
    click on a contact's entry hides or shows it (a large base force flattened the curves of the
    walls and dams beside it)."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(2, parent)
        from PySide6.QtWidgets import QComboBox, QHBoxLayout, QLabel

        from projects.results import CONTACT_COMPONENTS

        self.figure.subplots_adjust(right=0.8)  # the legend's room
        self.component = QComboBox()
        for key, (label, _m, _p) in CONTACT_COMPONENTS.items():
            self.component.addItem(label, key)
        self.component.setAccessibleName("Contact force component")
        self.component.setToolTip("The force shown: its magnitude, its signed x or y component (a force that "
                                  "reverses shows as one), or its normal and tangential parts (a side's along "
                                  "its axes, a structure's on the face that carries it)")
        self.component.currentIndexChanged.connect(lambda _i: self.set_contacts(self.contacts))
        row = QHBoxLayout()
        row.addWidget(QLabel("Force"))
        row.addWidget(self.component)
        row.addStretch(1)
        self.layout().insertLayout(0, row)
        self.axes[0].set_title("No contacts.csv in these results", fontsize=8)
        self.contacts: dict[str, dict[str, np.ndarray]] = {}
        self.curves: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        self.lines: dict[str, tuple[Any, Any]] = {}
        #: contacts the user hid (by a click on the legend); kept across rereads of a live run
        self.hidden: set[str] = set()
        self._legend_lines: dict[Any, str] = {}
        self.markers = [ax.axvline(0.0, color="#5f6368", linewidth=0.8, linestyle="--") for ax in self.axes]
        for m in self.markers:
            m.set_visible(False)
        self.canvas.mpl_connect("pick_event", self._picked)
        self._label_axes()

    def _label_axes(self) -> None:
        from projects.results import CONTACT_COMPONENTS

        label, _mean, peak = CONTACT_COMPONENTS[self.component.currentData() or "magnitude"]
        self.axes[0].set_ylabel(f"Mean {label} (N/m)", fontsize=8)
        # normal and tangential: the peak step's magnitude (contacts.csv has no peak vector along them)
        peak_label = label if peak != CONTACT_COMPONENTS["magnitude"][2] else CONTACT_COMPONENTS["magnitude"][0]
        self.axes[1].set_ylabel(f"Peak {peak_label} (N/m)", fontsize=8)

    def clear(self) -> None:
        self.set_contacts({})

    def set_component(self, key: str) -> None:
        """Show another component (a key of :data:`projects.results.CONTACT_COMPONENTS`)."""
        index = self.component.findData(key)
        if index < 0:
            raise ValueError(f"component {key!r}: not one of the choices")
        self.component.setCurrentIndex(index)

    def set_contacts(self, contacts: dict[str, dict[str, np.ndarray]], now: bool = True) -> None:
        """Show ``contacts.csv`` as :func:`projects.results.read_contacts` gives it (redrawn at once,
        or with the next scheduled redraw when ``now`` is False: a run under way)."""
        self.contacts = contacts
        curves = contact_curves(contacts, self.component.currentData() or "magnitude")
        if list(curves) != list(self.curves):
            for first, second in self.lines.values():
                first.remove()
                second.remove()
            self.lines = {}
            for name in curves:
                # a contact keeps its colour whichever component is shown (its place in the file)
                color = CONTACT_COLORS[list(contacts).index(name) % len(CONTACT_COLORS)]
                (mean,) = self.axes[0].plot([], [], color=color, linewidth=1.4, drawstyle="steps-pre", label=name)
                (peak,) = self.axes[1].plot([], [], color=color, linewidth=1.2, drawstyle="steps-pre", label=name)
                self.lines[name] = (mean, peak)
            for legend in self.figure.legends:
                legend.remove()
            self._legend_lines = {}
            if curves:
                legend = self.figure.legend(*self.axes[0].get_legend_handles_labels(), fontsize=7, loc="center right",
                                            title="click: hide", title_fontsize=6)
                for handle, name in zip(legend.legend_handles, curves):
                    handle.set_picker(6)
                    self._legend_lines[handle] = name
        self.curves = curves
        for name, (t, mean, peak) in curves.items():
            for line, values in zip(self.lines[name], (mean, peak)):
                line.set_data(t, values)
                line.set_visible(name not in self.hidden)
        for handle, name in self._legend_lines.items():
            handle.set_alpha(0.25 if name in self.hidden else 1.0)
        if curves:
            title = f"{len(curves)} contact{'' if len(curves) == 1 else 's'}: mean over each output interval"
        elif contacts:
            title = f"No contact has a {self.component.currentText()} component"
        else:
            title = "No contacts.csv in these results"
        self.axes[0].set_title(title, fontsize=8)
        self._label_axes()
        self.schedule()
        if now:
            self.redraw_now()

    def toggle(self, name: str) -> None:
        """Hide a shown contact's curves, or show a hidden one's (the axes rescale to what is shown)."""
        self.hidden ^= {name}
        self.set_contacts(self.contacts)

    def _picked(self, event) -> None:
        name = self._legend_lines.get(event.artist)
        if name is not None:
            self.toggle(name)

    def set_time(self, time_s: float | None) -> None:
        for m in self.markers:
            m.set_visible(time_s is not None)
            if time_s is not None:
                m.set_xdata([time_s, time_s])
        self.schedule()


def write_curves_csv(path: str | os.PathLike[str], series: dict[str, Any],
                     history: tuple[str, np.ndarray, np.ndarray] | None = None) -> Path:
    """Write the run's curves (and a particle history, if given) as one CSV table.

    Parameters
    ----------
    path : path-like
    series : dict
        Columns by name, ``time_s`` first (from ``series.csv`` or live), equal lengths.
    history : (label, times, values), optional
        A particle history; written as two more columns where its times match, else appended
        as its own rows with empty series columns.

    Returns
    -------
    Path
    """
    path = Path(path)
    names = [n for n in series if len(series[n]) == len(series.get("time_s", []))]
    rows = [[series[n][i] for n in names] for i in range(len(series.get("time_s", [])))]
    header = list(names)
    if history is not None:
        label, times, values = history
        header += ["history_time_s", label]
        for i in range(max(len(rows), len(times))):
            if i >= len(rows):
                rows.append([""] * len(names))
            extra = [times[i], values[i]] if i < len(times) else ["", ""]
            rows[i] = list(rows[i]) + list(extra)
    with open(path, "w", newline="", encoding="utf-8") as fh:
        writer = csv.writer(fh)
        writer.writerow(header)
        for row in rows:
            writer.writerow([repr(float(v)) if isinstance(v, (float, np.floating)) else v for v in row])
    return path
