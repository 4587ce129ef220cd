"""Results: the live view of a run, the inspector of a results folder, and side-by-side comparison.

:class:`ParticleScene` draws one frame (particles coloured by a field of :data:`app.render.FIELDS`,
with its colour bar in engineering units, the domain outline and the time) in an embedded
:class:`pyvistaqt.QtInteractor`. :class:`ResultsView` adds a time slider, play/pause, field,
colour map and range controls, particle picking with the picked particle's history, the run's
curves, and exports. Exported pictures and movies are rendered offscreen by :mod:`app.render`
(the same code as ``runout render``), not grabbed from the widget. :class:`CompareView` shows
two results folders side by side with one camera.
"""

from __future__ import annotations

import logging
import math
from pathlib import Path
from typing import Any

import numpy as np
from PySide6.QtCore import QEvent, QObject, QPointF, Qt, QTimer, Signal
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QHBoxLayout,
    QHeaderView,
    QLabel,
    QLineEdit,
    QPushButton,
    QSlider,
    QSplitter,
    QStyle,
    QTableWidget,
    QTableWidgetItem,
    QTabWidget,
    QToolButton,
    QVBoxLayout,
    QWidget,
)

from app.gui.curves import ContactCurves, HistoryCurve, MonitorCurves, ProfileCurve, SeriesCurves, write_curves_csv
from app.gui.document import parse_number
from app.display import SMOOTHED_SOURCES, display_spacing
from app.render import shown_values
from app.render import FIELDS, bar_format, field_info, field_values, structure_labels, value_range

logger = logging.getLogger(__name__)

#: The peak-force table's columns: key of projects.results.force_table's rows, header.
FORCE_COLUMNS: tuple[tuple[str, str], ...] = (
    ("contact", "Contact"),
    ("peak_force_N_per_m", "Peak |F|\n(kN/m)"),
    ("peak_force_normal_N_per_m", "its normal\n(kN/m)"),
    ("peak_force_tangential_N_per_m", "its tangential\n(kN/m)"),
    ("peak_time_s", "at\n(s)"),
    ("max_normal_force_N_per_m", "largest mean\nnormal (kN/m)"),
    ("max_normal_force_time_s", "at\n(s)"),
    ("max_tangential_force_N_per_m", "largest mean\ntangential (kN/m)"),
    ("max_tangential_force_time_s", "at\n(s)"),
)
COLORMAPS: tuple[str, ...] = ("viridis", "plasma", "magma_r", "turbo", "coolwarm", "cividis", "Greys")
PLAY_INTERVAL_MS = 120
CLICK_PIXELS = 4


def _left(event: QEvent) -> bool:
    return event.button() == Qt.MouseButton.LeftButton  # type: ignore[attr-defined]


def _field_label(name: str) -> str:
    info = FIELDS[name]
    return info.label if info.categorical else f"{info.label} ({info.unit})"


class ParticleScene(QWidget):
    """One embedded view of particles coloured by a field.

    Signals
    -------
    picked(int)
        The id of the particle clicked (a click is a press and release within a few pixels).
    """

    picked = Signal(int)

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        from pyvistaqt import QtInteractor

        self.plotter = QtInteractor(self, auto_update=False)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.addWidget(self.plotter)
        self.plotter.set_background("white")
        self.plotter.enable_parallel_projection()
        self.plotter.enable_custom_trackball_style(
            left="pan", shift_left="pan", control_left="pan", middle="pan", shift_middle="pan",
            control_middle="pan", right="dolly", shift_right="dolly", control_right="dolly",
        )
        self.plotter.installEventFilter(self)
        self.cloud: Any = None
        self.actor: Any = None
        self.domain: tuple[float, float, float, float] | None = None
        self.spacing_m = 0.0
        self.positions = np.zeros((0, 2))
        self.ids = np.zeros(0, dtype=int)
        self.values = np.zeros(0)
        self.field = "displacement"
        self.cmap = "viridis"
        self.clim: tuple[float, float] | None = None
        self.shown_clim: tuple[float, float] = (0.0, 1.0)
        self.material_names: list[str] = []
        self.message = ""
        self._style_key: Any = None
        self._text: Any = None
        self._press: QPointF | None = None
        self._closed = False
        self._fitted = False
        self._auto_fit = True
        self.picked_id: int | None = None
        self.structure_count = 0
        self._water_drawn: Any = False  # the water last drawn (False: none)
        #: stresses and pore pressure averaged over cells of this size (None: as the particles carry them)
        self.smooth_cell_m: float | None = None
        #: the side of the squares that draw the particles in the frame shown (app.display.display_spacing)
        self.shown_spacing_m = 0.0
        #: what is drawn is drawn less this (the grid's corner): VTK draws in float32, which
        #: resolves 0.25 m at y = 4e6 m (real-world coordinates); picking adds it back
        self.offset = np.zeros(2)

    def close_view(self) -> None:
        if self._closed:
            return
        self._closed = True
        self.plotter.removeEventFilter(self)
        self.plotter.close()  # releases the render window; the widget goes with its window

    # -- content ----------------------------------------------------------------------------

    def clear(self) -> None:
        self.plotter.clear_actors()
        for title in list(self.plotter.scalar_bars.keys()):
            self.plotter.remove_scalar_bar(title, render=False)
        self.cloud = self.actor = self._text = None
        self._style_key = None
        self._water_drawn = False
        self.picked_id = None
        self._fitted = False
        self.positions = np.zeros((0, 2))
        self.plotter.render()

    def set_domain(self, box: tuple[float, float, float, float] | None, spacing_m: float,
                   material_names: list[str]) -> None:
        """The grid box (for the outline and the camera), particle spacing and material names."""
        import pyvista as pv

        self.domain = box
        self.spacing_m = spacing_m
        self.material_names = list(material_names)
        self.offset = np.array([box[0], box[2]], dtype=float) if box is not None else np.zeros(2)
        self.plotter.remove_actor("domain", render=False)
        if box is not None:
            x0, x1, y0, y1 = (box[0] - self.offset[0], box[1] - self.offset[0],
                              box[2] - self.offset[1], box[3] - self.offset[1])
            outline = np.array([[x0, y0, 0], [x1, y0, 0], [x1, y1, 0], [x0, y1, 0], [x0, y0, 0]], float)
            self.plotter.add_mesh(pv.MultipleLines(outline), color="#9aa0a6", line_width=1, name="domain",
                                  render=False, reset_camera=False, pickable=False)

    def show_structures(self, structures: list[dict[str, Any]]) -> None:
        """The run's rigid structures (``summary.json`` ``structures``: ``name``, ``polygon_m``), grey
        with an outline, as in :mod:`app.render`'s pictures."""
        import pyvista as pv

        for name in ("structures", "structure-outlines", "structure-names-labels"):
            self.plotter.remove_actor(name, render=False)
        faces, segments = [], []
        for structure in structures:
            pts = np.asarray(structure.get("polygon_m") or [], dtype=float).reshape(-1, 2)
            if len(pts) < 3:
                continue
            xyz = np.column_stack([pts - self.offset, np.full(len(pts), -0.01)])
            face = pv.PolyData(xyz, faces=np.r_[len(pts), np.arange(len(pts))])
            try:
                face = face.triangulate()
            except (RuntimeError, ValueError):
                pass
            faces.append(face)
            segments.append(np.vstack([xyz, xyz[:1]]))
        if faces:
            merged = faces[0].merge(faces[1:]) if len(faces) > 1 else faces[0]
            self.plotter.add_mesh(merged, color="#b4b4b4", name="structures", render=False, reset_camera=False,
                                  pickable=False, lighting=False)
            lines = segments[0] if len(segments) == 1 else None
            outline = pv.MultipleLines(lines) if lines is not None else pv.merge([pv.MultipleLines(r) for r in segments])
            self.plotter.add_mesh(outline, color="#5f6368", line_width=1.5, name="structure-outlines", render=False,
                                  reset_camera=False, pickable=False)
            # named, as the contact-force curves name them
            points, names = structure_labels(structures, tuple(self.offset))
            self.plotter.add_point_labels(points, names, name="structure-names", font_size=10, text_color="#3c4043",
                                          shape=None, show_points=False, always_visible=True, render=False,
                                          reset_camera=False, justification_horizontal="center",
                                          justification_vertical="bottom")
        self.structure_count = len(faces)

    def show_water(self, shown: Any) -> None:
        """The ground water (an :class:`app.render.WaterShown`, None: none): the phreatic line in
        blue, the free-water line and the free water shaded, as :mod:`app.render` draws them."""
        from app.render import add_water_actors

        if shown is self._water_drawn:
            return
        self._water_drawn = shown
        for name in ("water-fill", "water-line", "free-water-line"):
            self.plotter.remove_actor(name, render=False)
        if shown is not None:
            add_water_actors(self.plotter, shown, self.offset, line_width=3.0)

    def show_arrays(self, arrays: dict[str, np.ndarray], time_s: float, caption: str = "") -> None:
        """Draw one frame (``positions``, ``active`` and the field's source array)."""
        import pyvista as pv

        active = np.asarray(arrays["active"], dtype=bool)
        positions = np.asarray(arrays["positions"])[active]
        self.positions = positions
        self.ids = np.flatnonzero(active)
        info = field_info(self.field)
        self.shown_spacing_m = display_spacing(positions, self.spacing_m) if self.spacing_m > 0 else 0.0
        try:
            origin = (self.domain[0], self.domain[2]) if self.domain is not None else (0.0, 0.0)
            values = np.asarray(shown_values(arrays, self.field, self.smooth_cell_m, origin), dtype=float)[active]
            self.message = ""
        except ValueError as err:  # the run did not write this field
            values = np.zeros(len(positions))
            self.message = str(err)
        self.values = values
        points = np.zeros((len(positions), 3), np.float32)
        points[:, :2] = positions - self.offset
        cloud = pv.PolyData(points)
        cloud.point_data["values"] = values
        if info.categorical:
            count = max(len(self.material_names), int(values.max(initial=0)) + 1, 1)
            clim = (-0.5, count - 0.5)
        else:
            clim = self.clim or value_range(values)
        self.shown_clim = clim
        key = (self.field, self.cmap, info.categorical, len(self.material_names))
        if self.actor is None or key != self._style_key:
            self._restyle(cloud, clim)
            self._style_key = key
        else:
            self.cloud.copy_from(cloud)
            self.actor.mapper.scalar_range = clim
        self._set_caption(f"t = {time_s:.4g} s{('   ' + caption) if caption else ''}")
        self._draw_pick()
        if not self._fitted:
            self.fit()
        else:
            self._update_point_size()
            self.plotter.render()

    def _restyle(self, cloud: Any, clim: tuple[float, float]) -> None:
        info = field_info(self.field)
        self.plotter.remove_actor("particles", render=False)
        for title in list(self.plotter.scalar_bars.keys()):
            self.plotter.remove_scalar_bar(title, render=False)
        self.cloud = cloud
        bar = dict(title=info.title, color="black", vertical=True, position_x=0.87, position_y=0.15,
                   height=0.7, width=0.04, title_font_size=12, label_font_size=11,
                   unconstrained_font_size=True)
        kwargs: dict[str, Any] = dict(scalars="values", style="points", point_size=3.0, lighting=False,
                                      render_points_as_spheres=False, name="particles", render=False,
                                      reset_camera=False)
        if info.categorical:
            count = int(round(clim[1] + 0.5))
            names = self.material_names
            annotations = {i: (names[i] if i < len(names) else f"material {i}") for i in range(count)}
            bar.update(n_labels=0)
            self.actor = self.plotter.add_mesh(cloud, cmap="tab10", clim=clim, n_colors=count, categories=True,
                                               annotations=annotations, scalar_bar_args=bar, **kwargs)
        else:
            bar.update(fmt=bar_format(*clim), n_labels=5)
            self.actor = self.plotter.add_mesh(cloud, cmap=self.cmap, clim=clim, scalar_bar_args=bar, **kwargs)

    def _set_caption(self, text: str) -> None:
        if self._text is None:
            self._text = self.plotter.add_text(text, position="upper_left", font_size=11, color="black",
                                               name="caption")
        else:
            self._text.SetText(2, text)

    def fit(self) -> None:
        box = self.domain
        if box is None and len(self.positions):
            lo, hi = self.positions.min(axis=0), self.positions.max(axis=0)
            box = (float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1]))
        if box is None:
            return
        x0, x1, y0, y1 = box
        cx, cy = (x0 + x1) / 2 - self.offset[0], (y0 + y1) / 2 - self.offset[1]
        # the colour bar takes the right eighth of the view
        w, h = (x1 - x0) * 1.3, (y1 - y0) * 1.3
        aspect = max(1, self.plotter.width()) / max(1, self.plotter.height())
        cam = self.plotter.camera
        shift = 0.06 * w
        cam.focal_point = (cx + shift, cy, 0.0)
        cam.position = (cx + shift, cy, 10.0 * max(w, h, 1e-6))
        cam.up = (0.0, 1.0, 0.0)
        cam.parallel_scale = max(h / 2.0, w / 2.0 / aspect, 1e-6)
        self.plotter.renderer.ResetCameraClippingRange()
        self._fitted = True
        self._auto_fit = True
        self._update_point_size()
        self.plotter.render()

    def _update_point_size(self) -> None:
        if self.actor is None or self.spacing_m <= 0:
            return
        scale = self.plotter.camera.parallel_scale
        # the particles' spread in this frame, not only their spacing at the start: a flowing mass
        # drawn at its initial spacing fell apart into separated columns of points
        spacing = max(self.spacing_m, self.shown_spacing_m)
        pixels = spacing * max(1, self.plotter.height()) / (2.0 * max(scale, 1e-12))
        self.actor.prop.point_size = float(min(40.0, max(2.0, math.ceil(pixels))))

    def resizeEvent(self, event: Any) -> None:  # noqa: N802 - Qt's name
        super().resizeEvent(event)
        # follow the window's size until the user pans or zooms; then keep their view
        if not self._closed and self._fitted and self._auto_fit:
            self.fit()

    # -- picking --------------------------------------------------------------------------------

    def world_at(self, pos: QPointF) -> np.ndarray:
        s = float(self.plotter.devicePixelRatioF())
        r = self.plotter.renderer
        r.SetDisplayPoint(pos.x() * s, (self.plotter.height() - pos.y() - 1) * s, 0.0)
        r.DisplayToWorld()
        wx, wy, _wz, w = r.GetWorldPoint()
        return np.array([wx / (w or 1.0), wy / (w or 1.0)]) + self.offset

    def widget_at(self, xy: Any) -> QPointF:
        r = self.plotter.renderer
        r.SetWorldPoint(float(xy[0] - self.offset[0]), float(xy[1] - self.offset[1]), 0.0, 1.0)
        r.WorldToDisplay()
        dx, dy, _ = r.GetDisplayPoint()
        s = float(self.plotter.devicePixelRatioF())
        return QPointF(dx / s, self.plotter.height() - 1 - dy / s)

    def pick(self, xy: Any) -> int | None:
        """The id of the active particle nearest to ``xy`` (metres), if one is close enough."""
        if not len(self.positions):
            return None
        d = np.hypot(*(self.positions - np.asarray(xy, float)).T)
        k = int(np.argmin(d))
        pixel = 2.0 * self.plotter.camera.parallel_scale / max(1, self.plotter.height())
        if d[k] > max(3 * pixel, self.spacing_m):
            return None
        return int(self.ids[k])

    def set_picked(self, particle: int | None) -> None:
        self.picked_id = particle
        self._draw_pick()
        self.plotter.render()

    def show_section(self, section: tuple[float, float, float, float] | None) -> None:
        """Draw the cross-section line (or remove it)."""
        import pyvista as pv

        self.plotter.remove_actor("section", render=False)
        if section is not None:
            x0, y0, x1, y1 = section
            (x0, y0), (x1, y1) = np.array([x0, y0]) - self.offset, np.array([x1, y1]) - self.offset
            self.plotter.add_mesh(pv.Line((x0, y0, 0.01), (x1, y1, 0.01)), color="#d93025", line_width=2,
                                  name="section", render=False, reset_camera=False, pickable=False)
        self.plotter.render()

    def _draw_pick(self) -> None:
        import pyvista as pv

        self.plotter.remove_actor("pick", render=False)
        if self.picked_id is None:
            return
        where = np.flatnonzero(self.ids == self.picked_id)
        if not len(where):
            return
        p = np.zeros((1, 3))
        p[0, :2] = self.positions[where[0]] - self.offset
        p[0, 2] = 0.05
        self.plotter.add_mesh(pv.PolyData(p), color="#d93025", point_size=14, render_points_as_spheres=True,
                              name="pick", render=False, reset_camera=False, pickable=False)

    def eventFilter(self, obj: QObject, event: QEvent) -> bool:  # noqa: N802 - Qt's name
        if obj is not self.plotter or self._closed:
            return False
        kind = event.type()
        if kind == QEvent.Type.MouseButtonPress and _left(event):
            self._press = event.position()  # type: ignore[attr-defined]
        elif kind == QEvent.Type.MouseButtonRelease and _left(event):
            pos = event.position()  # type: ignore[attr-defined]
            if self._press is not None and (pos - self._press).manhattanLength() <= CLICK_PIXELS:
                particle = self.pick(self.world_at(pos))
                if particle is not None:
                    self.picked.emit(particle)
            else:
                self._auto_fit = False
            self._press = None
            QTimer.singleShot(0, self._after_interaction)
        elif kind == QEvent.Type.Wheel:
            self._auto_fit = False
            QTimer.singleShot(0, self._after_interaction)
        elif kind == QEvent.Type.KeyPress:
            return True  # pyvista's keys (q closes, ...) make no sense in an embedded view
        return False

    def _after_interaction(self) -> None:
        if not self._closed:
            self._update_point_size()
            self.plotter.render()


def _cell_of(summary: dict[str, Any]) -> float | None:
    """The grid's cell size of a results folder's summary (None where it is not recorded)."""
    size = (summary.get("domain") or {}).get("cell_size_m")
    return float(size) if isinstance(size, (int, float)) and size > 0 else None


def _domain_of(summary: dict[str, Any]) -> tuple[float, float, float, float] | None:
    domain = summary.get("domain") or {}
    try:
        (x0, y0), (w, h) = domain["origin_m"], domain["size_m"]
        return float(x0), float(x0) + float(w), float(y0), float(y0) + float(h)
    except (KeyError, TypeError, ValueError):
        return None


class _Controls(QWidget):
    """Play, time slider, field, colour map and range: shared by the inspector and the comparison."""

    frameChosen = Signal(int)
    styleChanged = Signal()

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        row1 = QHBoxLayout()
        self.play = QToolButton()
        self.play.setCheckable(True)
        self.play.setIcon(self.style().standardIcon(QStyle.StandardPixmap.SP_MediaPlay))
        self.play.setToolTip("Play / pause")
        self.play.toggled.connect(self._play_toggled)
        self.slider = QSlider(Qt.Orientation.Horizontal)
        self.slider.setRange(0, 0)
        self.slider.valueChanged.connect(self.frameChosen)
        self.time_label = QLabel("no results")
        self.time_label.setMinimumWidth(190)
        row1.addWidget(self.play)
        row1.addWidget(self.slider, 1)
        row1.addWidget(self.time_label)
        row2 = QHBoxLayout()
        self.field = QComboBox()
        self.field.setAccessibleName("Field")
        for name in FIELDS:
            self.field.addItem(_field_label(name), name)
        self.field.activated.connect(lambda _i: self.styleChanged.emit())
        self.cmap = QComboBox()
        self.cmap.setAccessibleName("Colour map")
        self.cmap.addItems(list(COLORMAPS))
        self.cmap.activated.connect(lambda _i: self.styleChanged.emit())
        self.auto = QCheckBox("auto range")
        self.auto.setChecked(True)
        self.auto.toggled.connect(self._auto_toggled)
        self.lo = QLineEdit()
        self.hi = QLineEdit()
        for edit, tip in ((self.lo, "colour range minimum"), (self.hi, "colour range maximum")):
            # wide enough for a 4-digit value with its exponent (a range of 0.0002828 m showed
            # its tail, "828", when the field was 90 px and scrolled to the end)
            edit.setMinimumWidth(edit.fontMetrics().horizontalAdvance("-0.0002828") + 14)
            edit.setMaximumWidth(max(90, edit.minimumWidth()))
            edit.setToolTip(tip)
            edit.setAccessibleName(tip)
            edit.setEnabled(False)
            edit.editingFinished.connect(self.styleChanged)
        self.unit = QLabel("")
        self.unit.setMinimumWidth(30)
        self.smooth = QCheckBox("smooth")
        self.smooth.setToolTip("Stresses and pore pressure averaged over the cells around each particle "
                               "(app.display.smooth_values): the cell-scale checkerboard of a moving mass shown "
                               "as its local mean. The frames keep their particle values.")
        self.smooth.toggled.connect(lambda _on: self.styleChanged.emit())
        row2.addWidget(QLabel("Field"))
        row2.addWidget(self.field, 1)
        row2.addWidget(self.smooth)
        row2.addWidget(QLabel("Colours"))
        row2.addWidget(self.cmap)
        row2.addWidget(self.auto)
        row2.addWidget(self.lo)
        row2.addWidget(QLabel("to"))
        row2.addWidget(self.hi)
        row2.addWidget(self.unit)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(4, 2, 4, 2)
        layout.addLayout(row1)
        layout.addLayout(row2)
        self.timer = QTimer(self)
        self.timer.setInterval(PLAY_INTERVAL_MS)
        self.timer.timeout.connect(self._tick)
        self._sync_unit()

    @property
    def field_name(self) -> str:
        return str(self.field.currentData())

    def set_field(self, name: str) -> None:
        index = self.field.findData(name)
        if index < 0:
            raise ValueError(f"unknown field {name!r}")
        self.field.setCurrentIndex(index)
        info = FIELDS[name]
        self.cmap.setCurrentText(info.cmap if info.cmap in COLORMAPS else self.cmap.currentText())
        self._sync_unit()
        self.styleChanged.emit()

    def set_available(self, arrays: Any) -> None:
        """Grey out the fields whose source the frames lack (``pore_pressure`` of a dry run), saying why."""
        model = self.field.model()
        for i in range(self.field.count()):
            info = FIELDS[self.field.itemData(i)]
            item = model.item(i)
            ok = info.source in arrays
            item.setEnabled(ok)
            item.setToolTip("" if ok else f"this run did not write {info.source!r}"
                            + (" (a run without ground water)" if info.source == "pore_pressure" else ""))

    def _sync_unit(self) -> None:
        info = FIELDS[self.field_name]
        self.unit.setText("" if info.categorical else info.unit)
        self.smooth.setEnabled(info.source in SMOOTHED_SOURCES)
        self.cmap.setEnabled(not info.categorical)
        self.auto.setEnabled(not info.categorical)

    def clim(self) -> tuple[float, float] | None:
        if self.auto.isChecked() or FIELDS[self.field_name].categorical:
            return None
        lo, hi = parse_number(self.lo.text()), parse_number(self.hi.text())
        if lo is None or hi is None or not hi > lo:
            return None
        return lo, hi

    def show_range(self, clim: tuple[float, float]) -> None:
        if self.auto.isChecked():
            for edit, value in ((self.lo, clim[0]), (self.hi, clim[1])):
                edit.setText(f"{value:.4g}")
                edit.setCursorPosition(0)  # the number's start, never only its tail

    def _auto_toggled(self, on: bool) -> None:
        self.lo.setEnabled(not on)
        self.hi.setEnabled(not on)
        self.styleChanged.emit()

    def _play_toggled(self, on: bool) -> None:
        icon = QStyle.StandardPixmap.SP_MediaPause if on else QStyle.StandardPixmap.SP_MediaPlay
        self.play.setIcon(self.style().standardIcon(icon))
        if on:
            if self.slider.value() >= self.slider.maximum():
                self.slider.setValue(0)
            self.timer.start()
        else:
            self.timer.stop()

    def _tick(self) -> None:
        if self.slider.value() >= self.slider.maximum():
            self.play.setChecked(False)
        else:
            self.slider.setValue(self.slider.value() + 1)

    def stop(self) -> None:
        self.play.setChecked(False)
        self.timer.stop()


class ResultsView(QWidget):
    """The run's live view and the inspector of a results folder.

    Signals
    -------
    message(str)
        Status-bar text.
    """

    message = Signal(str)
    resultsShown = Signal()
    #: the rows of the peak-force table (projects.results.force_table) and the folder
    forcesShown = Signal(list, str)

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.results: Any = None
        self._water: Any = None  # (timeline, ground, box, cache) of a run with ground water
        self.live = False
        self.live_path: Path | None = None
        self.live_title = ""
        #: particle histories read so far: (folder, particle, field) -> (times, values)
        self._histories: dict[tuple[str, int, str], tuple[list[float], list[np.ndarray]]] = {}
        self.frame_index = 0
        self.live_time = 0.0
        self.history: tuple[str, np.ndarray, np.ndarray] | None = None
        self.header = QLabel("Open a results folder (File ▸ Open results) or run the project.")
        self.header.setWordWrap(True)
        self.header.setStyleSheet("padding: 3px; color: #3c4043;")
        self.controls = _Controls()
        self.controls.frameChosen.connect(self.show_frame)
        self.controls.styleChanged.connect(self._restyle)
        self.controls.field.activated.connect(lambda _i: self._field_picked())
        self.scene = ParticleScene()
        self.scene.picked.connect(self.pick_particle)
        self.curves = SeriesCurves()
        self.contact_plot = ContactCurves()
        self.history_plot = HistoryCurve()
        self.monitor_plot = MonitorCurves()
        self.profile_plot = ProfileCurve()
        #: monitoring points (label, x_m, y_m) and their particles in the open results
        self.monitors: list[tuple[str, float, float]] = []
        self.monitor_ids: list[int] = []
        #: the cross-section (x0, y0, x1, y1), m
        self.section: tuple[float, float, float, float] | None = None
        self.side = QTabWidget()
        self.side.addTab(self.curves, "Run curves")
        self.side.addTab(self.contact_plot, "Contact forces")
        self.forces_table = QTableWidget(0, len(FORCE_COLUMNS))
        self.forces_table.setHorizontalHeaderLabels([h for _k, h in FORCE_COLUMNS])
        self.forces_table.verticalHeader().setVisible(False)
        self.forces_table.setEditTriggers(QTableWidget.EditTrigger.NoEditTriggers)
        self.forces_table.horizontalHeader().setSectionResizeMode(QHeaderView.ResizeMode.ResizeToContents)
        self.forces_table.setToolTip("Per structure (then per closed side): the largest force of one step with its "
                                     "normal and tangential parts on the face that carried it and when, and the "
                                     "largest interval-mean normal and tangential forces and when (contacts.csv)")
        self.force_rows: list[dict[str, Any]] = []
        self.side.addTab(self.forces_table, "Peak forces")
        self.side.addTab(self.history_plot, "Particle history")
        self.monitor_tab = self._with_inputs(self.monitor_plot, "monitor")
        self.section_tab = self._with_inputs(self.profile_plot, "section")
        self.query_tab = self._query_tab()
        self.side.addTab(self.monitor_tab, "Monitoring points")
        self.side.addTab(self.section_tab, "Cross-section")
        self.side.addTab(self.query_tab, "Query")
        #: the point whose value the Query tab shows (it follows the frame, field and smoothing)
        self.query_point: tuple[float, float] | None = None
        self.query_answer: Any = None
        # landslide domains are wide: the curves go below the view, in a row
        split = QSplitter(Qt.Orientation.Vertical)
        split.addWidget(self.scene)
        split.addWidget(self.side)
        split.setStretchFactor(0, 3)
        split.setStretchFactor(1, 1)
        split.setSizes([600, 260])
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.addWidget(self.header)
        layout.addWidget(self.controls)
        layout.addWidget(split, 1)
        self._set_enabled(False)

    def close_view(self) -> None:
        self.controls.stop()
        self.scene.close_view()
        self.curves.close_canvas()
        self.contact_plot.close_canvas()
        self.history_plot.close_canvas()
        self.monitor_plot.close_canvas()
        self.profile_plot.close_canvas()

    def particle_history(self, particle: int, field: str) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`projects.results.Results.particle_history`, kept per particle and field so
        that a run under way (its folder reread as frames arrive) reads only the new frames."""
        results = self.results
        key = (str(results.path), int(particle), field)
        times, values = self._histories.get(key, ([], []))
        if len(times) > len(results):  # another folder of the same name: start again
            times, values = [], []
        for j in range(len(times), len(results)):
            arrays = results.frame(j, {field})
            if field not in arrays:
                raise KeyError(f"frame {j} has no field {field!r}; it has {sorted(arrays)}")
            column = arrays[field]
            if not 0 <= particle < len(column):
                raise IndexError(f"particle {particle} out of range (0..{len(column) - 1})")
            times.append(float(results.times[j]))
            values.append(np.array(column[particle]))
        self._histories[key] = (times, values)
        return np.array(times), np.array(values)

    def _with_inputs(self, canvas: QWidget, kind: str) -> QWidget:
        """A canvas with the coordinate fields that drive it above it."""
        box = QWidget()
        layout = QVBoxLayout(box)
        layout.setContentsMargins(0, 0, 0, 0)
        row = QHBoxLayout()
        if kind == "monitor":
            self.monitor_x, self.monitor_y = QLineEdit(), QLineEdit()
            for edit, name in ((self.monitor_x, "x"), (self.monitor_y, "y")):
                edit.setPlaceholderText(f"{name} (m)")
                edit.setMaximumWidth(90)
                row.addWidget(QLabel(name))
                row.addWidget(edit)
            add = QPushButton("Add point")
            add.setToolTip("Follow the particle nearest to this point at the start of the run")
            add.clicked.connect(self._add_monitor_typed)
            clear = QPushButton("Clear")
            clear.clicked.connect(self.clear_monitors)
            row.addWidget(add)
            row.addWidget(clear)
        else:
            self.section_edits = [QLineEdit() for _ in range(4)]
            for edit, name in zip(self.section_edits, ("x0", "y0", "x1", "y1"), strict=True):
                edit.setPlaceholderText(f"{name} (m)")
                edit.setMaximumWidth(80)
                row.addWidget(QLabel(name))
                row.addWidget(edit)
            show = QPushButton("Show profile")
            show.setToolTip("The shown field along the line, from the particles within one particle "
                            "spacing of it, in the frame shown")
            show.clicked.connect(self._section_typed)
            row.addWidget(show)
            self.section_csv = QPushButton("Export CSV…")
            self.section_csv.setToolTip("The shown field along the line at points every half particle spacing, "
                                        "in the frame shown (as runout query --along), to a CSV file")
            self.section_csv.clicked.connect(self._export_section_dialog)
            row.addWidget(self.section_csv)
        row.addStretch(1)
        layout.addLayout(row)
        layout.addWidget(canvas, 1)
        return box

    def _query_tab(self) -> QWidget:
        """The value of the shown field at a typed point (``runout query --at``)."""
        box = QWidget()
        layout = QVBoxLayout(box)
        layout.setContentsMargins(4, 4, 4, 4)
        row = QHBoxLayout()
        self.query_x, self.query_y = QLineEdit(), QLineEdit()
        for edit, name in ((self.query_x, "x"), (self.query_y, "y")):
            edit.setPlaceholderText(f"{name} (m)")
            edit.setMaximumWidth(90)
            edit.returnPressed.connect(self._query_typed)
            row.addWidget(QLabel(name))
            row.addWidget(edit)
        ask = QPushButton("Value here")
        ask.setToolTip("The shown field at this point in the frame shown: the mean of the particles within one "
                       "particle spacing, nearest counting most (runout query --at)")
        ask.clicked.connect(self._query_typed)
        row.addWidget(ask)
        row.addStretch(1)
        layout.addLayout(row)
        self.query_label = QLabel("Type a point and press Value here: the value follows the time slider, the "
                                  "field and the smoothing.")
        self.query_label.setWordWrap(True)
        self.query_label.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        layout.addWidget(self.query_label)
        layout.addStretch(1)
        return box

    def _query_typed(self) -> None:
        x, y = parse_number(self.query_x.text()), parse_number(self.query_y.text())
        if x is None or y is None:
            self.message.emit("query: give x and y in metres")
            return
        self.query_at(x, y)

    def query_at(self, x_m: float, y_m: float) -> Any:
        """The shown field at (x_m, y_m) in the shown frame (:func:`app.query.values_at`); the
        Query tab says it and follows the frame from now on. The :class:`app.query.PointValue`."""
        self.query_point = (float(x_m), float(y_m))
        self.query_x.setText(f"{x_m:g}")
        self.query_y.setText(f"{y_m:g}")
        self.side.setCurrentWidget(self.query_tab)
        return self.update_query()

    def update_query(self) -> Any:
        from app.query import point_text, values_at

        if self.query_point is None or self.results is None:
            return None
        try:
            answer = values_at(self.results, self.controls.field_name, [self.query_point], self.frame_index,
                               smooth=self.controls.smooth.isChecked())
        except ValueError as err:
            self.query_label.setText(str(err))
            self.query_answer = None
            return None
        self.query_answer = answer
        # frames counted as the slider counts them (runout query's --frame counts from 0)
        self.query_label.setText(point_text(answer).replace(
            f", frame {answer.frame} (", f", frame {answer.frame + 1}/{len(self.results)} ("))
        return answer.points[0]

    def _export_section_dialog(self) -> None:
        from PySide6.QtWidgets import QFileDialog

        if self.section is None or self.results is None:
            self.message.emit("cross-section: show a profile first")
            return
        path, _f = QFileDialog.getSaveFileName(self, "Export the section", str(self._section_csv_path()),
                                               "CSV (*.csv)")
        if path:
            self.export_section(path)

    def _section_csv_path(self) -> Path:
        from projects.results_folder import export_path

        return export_path(self.results.path, f"section_{self.controls.field_name}_{self.frame_index:05d}",
                           ".csv")

    def export_section(self, path: str | Path) -> Path:
        """The shown field along the cross-section in the shown frame, as ``runout query --along``
        writes it (:func:`app.query.csv_text`)."""
        from app.query import csv_text, values_along
        from projects.atomic import write_atomic

        if self.section is None or self.results is None:
            raise ValueError("show a cross-section first")
        x0, y0, x1, y1 = self.section
        answer = values_along(self.results, self.controls.field_name, (x0, y0), (x1, y1), self.frame_index,
                              smooth=self.controls.smooth.isChecked())
        out = Path(path)
        write_atomic(out, csv_text(answer).encode("utf-8"))
        self.message.emit(f"wrote {out}")
        return out

    # -- monitoring points and cross-sections ---------------------------------------------------

    def _add_monitor_typed(self) -> None:
        x, y = parse_number(self.monitor_x.text()), parse_number(self.monitor_y.text())
        if x is None or y is None:
            self.message.emit("monitoring point: give x and y in metres")
            return
        self.add_monitor(x, y)

    def add_monitor(self, x_m: float, y_m: float, label: str | None = None) -> int | None:
        """Follow the particle nearest to (x_m, y_m) at the start of the run; its id (None
        without results). The point is kept for the next results shown (a re-run, say)."""
        self.monitors.append((label or f"P{len(self.monitors) + 1} ({x_m:g}, {y_m:g})", float(x_m), float(y_m)))
        self.update_monitors()
        self.side.setCurrentWidget(self.monitor_tab)
        return self.monitor_ids[-1] if len(self.monitor_ids) == len(self.monitors) else None

    def clear_monitors(self) -> None:
        self.monitors, self.monitor_ids = [], []
        self.monitor_plot.show_histories([])

    def update_monitors(self) -> None:
        """Recompute the monitoring points' particles and histories from the open results."""
        if self.results is None or not self.monitors:
            self.monitor_ids = []
            self.monitor_plot.show_histories([])
            return
        first = self.results.frame(0, {"positions", "active"})
        positions, active = first["positions"], first["active"]
        candidates = np.flatnonzero(active) if active.any() else np.arange(len(positions))
        ids, histories = [], []
        for label, x, y in self.monitors:
            d2 = ((positions[candidates] - [x, y]) ** 2).sum(axis=1)
            pid = int(candidates[int(np.argmin(d2))])
            ids.append(pid)
            try:
                times, disp = self.particle_history(pid, "displacement")
                _t, vel = self.particle_history(pid, "velocity")
            except (KeyError, IndexError) as err:  # a run that did not write these fields
                self.message.emit(f"monitoring point {label}: {err}")
                continue
            histories.append((f"{label}: particle {pid}", times, np.hypot(disp[:, 0], disp[:, 1]),
                              np.hypot(vel[:, 0], vel[:, 1])))
        self.monitor_ids = ids
        self.monitor_plot.show_histories(histories)

    def _section_typed(self) -> None:
        values = [parse_number(e.text()) for e in self.section_edits]
        if any(v is None for v in values):
            self.message.emit("cross-section: give x0, y0, x1, y1 in metres")
            return
        self.set_section(*values)  # type: ignore[arg-type]

    def set_section(self, x0: float, y0: float, x1: float, y1: float) -> int:
        """Show the field along the line from (x0, y0) to (x1, y1) in the shown frame; the
        number of particles on it (within one particle spacing of the line)."""
        if (x0, y0) == (x1, y1):
            self.message.emit("cross-section: the two end points must differ")
            return 0
        self.section = (float(x0), float(y0), float(x1), float(y1))
        for edit, v in zip(self.section_edits, self.section, strict=True):
            edit.setText(f"{v:g}")
        self.side.setCurrentWidget(self.section_tab)
        return self.update_section()

    def update_section(self) -> int:
        if self.section is None or self.results is None:
            return 0
        x0, y0, x1, y1 = self.section
        arrays = self.results.frame(self.frame_index)
        field = self.controls.field_name
        origin = (_domain_of(self.results.summary) or (0.0, 0.0, 0.0, 0.0))[::2]
        values = np.asarray(shown_values(arrays, field, self.smooth_cell_m(), origin), float)
        start, end = np.array([x0, y0]), np.array([x1, y1])
        length = float(np.linalg.norm(end - start))
        along = (end - start) / length
        rel = arrays["positions"] - start
        s_m = rel @ along
        off = np.abs(rel @ np.array([-along[1], along[0]]))
        spacing = float(self.results.summary.get("particle_spacing_m") or 0.0) or 0.02 * length
        on = arrays["active"] & (off <= spacing) & (s_m >= 0) & (s_m <= length)
        order = np.argsort(s_m[on])
        label = _field_label(field)
        time_s = float(self.results.times[self.frame_index])
        self.profile_plot.show_profile(s_m[on][order], values[on][order], label,
                                       f"({x0:g}, {y0:g}) → ({x1:g}, {y1:g}), t = {time_s:.4g} s, "
                                       f"{int(on.sum())} particles")
        if not on.any():
            self.message.emit("cross-section: no particle within one particle spacing of the line")
        self.scene.show_section(self.section)
        return int(on.sum())

    def _set_enabled(self, on: bool) -> None:
        self.controls.play.setEnabled(on)
        self.controls.slider.setEnabled(on)

    # -- live runs --------------------------------------------------------------------------------
    # A run under way is shown from its results folder, read the same way as a finished one:
    # follow() names the folder, refresh() reopens it whenever the run says a frame was written
    # (and on a timer), and the view jumps to the newest frame unless the user moved the slider.

    def follow(self, path: str | Path, title: str) -> None:
        """Show the run writing to ``path`` as its frames arrive (call :meth:`refresh` to look)."""
        self.controls.stop()
        self.results = None
        self.live = True
        self.live_path = Path(path)
        self.live_title = title
        self.history = None
        self.history_plot.clear_history()
        self.scene.clear()
        self.curves.clear()
        self.curves.set_time(None)
        self.contact_plot.clear()
        self.contact_plot.set_time(None)
        self.controls.slider.blockSignals(True)
        self.controls.slider.setRange(0, 0)
        self.controls.slider.blockSignals(False)
        self._set_enabled(False)
        self.header.setText(f"Running: {title} — {path}")
        self.controls.time_label.setText("starting…")

    def refresh(self) -> bool:
        """Reread the followed folder; True when it shows a frame it did not show before."""
        if not self.live or self.live_path is None:
            return False
        from projects.results import ResultsError

        before = len(self.results) if self.results is not None else 0
        try:
            self._show_folder(self.live_path, live=True)
        except (ResultsError, OSError) as err:  # not there yet, or no complete frame yet
            logger.debug("live results not readable yet: %s", err)
            return False
        return len(self.results) > before

    def end_live(self, how: str = "") -> None:
        """The followed run has ended (``how``: its status and message): stop following (its
        folder stays open). A run that ended before its first frame says so in the header, which
        said "Running" until another folder was opened."""
        self.live = False
        if self.results is None and self.live_path is not None:
            self.header.setText(f"Ended: {self.live_title} — {self.live_path}   "
                                f"[{how + '; ' if how else ''}no frame was written]")
            self.controls.time_label.setText("no frame")

    # -- results folders ----------------------------------------------------------------------------

    def open_results(self, path: str | Path) -> None:
        """Show a results folder (also one a killed run left), from its last frame.

        Raises
        ------
        projects.results.ResultsError
            When ``path`` is not a results folder or has no complete frame.
        """
        self.live = False
        self.live_path = None
        self._show_folder(Path(path), live=False)

    def _show_folder(self, path: Path, live: bool) -> None:
        from projects.results import ResultsError, open_results

        results = open_results(path)
        if len(results) == 0:
            raise ResultsError(f"{results.path} has no complete frames to show")
        previous = self.results
        same = (previous is not None and previous.path == results.path and live
                and self.scene.picked_id is not None)
        at_end = previous is None or self.frame_index >= len(previous) - 1 or not live
        if not live or previous is None or previous.path != results.path:
            self._histories.clear()
            self.controls.stop()
            self.history = None
            self.history_plot.clear_history()
            spacing = results.summary.get("particle_spacing_m") or 0.0
            self.scene.clear()
            self.scene.set_domain(_domain_of(results.summary), float(spacing), results.material_names)
            self.scene.show_structures(results.summary.get("structures") or [])
            self._water = self._water_of(results)
        self.results = results
        self._show_contacts(results.path, live)
        if live:
            self.curves.set_series(results.series, now=False)
        else:
            self.curves.set_series(results.series)
        status = results.status
        title = results.summary.get("title") or results.path.name
        if live:
            state = "running"
        else:
            state = status + (": " + results.message if results.message and status != "completed" else "")
        info = (f"{title} — {results.path}   [{state}]   "
                f"{results.summary.get('particles', '?')} particles, {results.summary.get('scheme', '?')}, "
                f"{results.summary.get('arch', '?')} {results.summary.get('precision', '')}")
        self.header.setText(info)
        self._set_enabled(True)
        slider = self.controls.slider
        index = len(results) - 1 if at_end else min(self.frame_index, len(results) - 1)
        slider.blockSignals(True)
        slider.setRange(0, len(results) - 1)
        slider.setValue(index)
        slider.blockSignals(False)
        self.show_frame(index)
        if same and self.history is not None:
            self.pick_particle(self.scene.picked_id)
        if self.monitors:
            self.update_monitors()
        self.resultsShown.emit()

    def _show_contacts(self, path: Path, live: bool) -> None:
        """The force on each contact from the folder's ``contacts.csv`` (reread while a run goes on)."""
        from projects.results import read_contacts

        try:
            contacts = read_contacts(path)
        except (OSError, ValueError) as err:
            logger.debug("contacts.csv not readable: %s", err)
            contacts = {}
        self.contact_plot.set_contacts(contacts, now=not live)
        from projects.results import force_table

        try:
            rows = force_table(path) if contacts else []
        except (OSError, ValueError) as err:
            logger.debug("no force table: %s", err)
            rows = []
        self.force_rows = rows
        self.forces_table.setRowCount(len(rows))
        for r, row in enumerate(rows):
            for c, (key, _h) in enumerate(FORCE_COLUMNS):
                value = row.get(key)
                if key == "contact":
                    text = f"{value}" + ("" if row.get("kind") == "structure" else " (side)")
                elif key.endswith("_s"):
                    text = "–" if value is None else f"{value:.3g}"
                else:
                    text = "–" if value is None or value != value else f"{value / 1e3:.4g}"
                item = QTableWidgetItem(text)
                if key != "contact":
                    item.setTextAlignment(Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignVCenter)
                self.forces_table.setItem(r, c, item)
        self.forcesShown.emit(rows, str(path))

    def show_frame(self, index: int) -> None:
        """Show frame ``index`` of the open results folder (also while its run goes on)."""
        if self.results is None:
            return
        n = len(self.results)
        index = max(0, min(int(index), n - 1))
        self.frame_index = index
        if self.controls.slider.value() != index:
            self.controls.slider.blockSignals(True)
            self.controls.slider.setValue(index)
            self.controls.slider.blockSignals(False)
        time_s = float(self.results.times[index])
        self._apply_style()
        caption = f"frame {index + 1}/{n}" + ("   (live)" if self.live else "")
        arrays = self.results.frame(index)
        self.controls.set_available(arrays)
        self.scene.show_water(self._water_shown(index, arrays))
        self.scene.show_arrays(arrays, time_s, caption)
        self.controls.show_range(self.scene.shown_clim)
        stage = self._stage_at(index)
        self.controls.time_label.setText(f"t = {time_s:.4g} s   frame {index + 1}/{n}{stage}")
        self.curves.set_time(time_s)
        self.contact_plot.set_time(time_s)
        if self.section is not None:
            self.update_section()
        if self.query_point is not None:
            self.update_query()
        self.message.emit(self.scene.message)

    @staticmethod
    def _water_of(results: Any) -> Any:
        """(timeline, ground polygons, domain box) of a run with [water], else None."""
        from app.render import WaterTimeline

        timeline = WaterTimeline.of(results)
        box = _domain_of(results.summary)
        if timeline is None or box is None:
            return None
        return timeline, box, float(results.summary.get("particle_spacing_m") or 0.0)

    def _water_shown(self, index: int, arrays: Any) -> Any:
        """What to draw of the water at frame ``index``: its lines, and the free water on the ground
        the frame's particles make (:func:`app.render.particle_ground`)."""
        from app.render import particle_ground, water_shown

        if self._water is None:
            return None
        timeline, box, spacing = self._water
        active = np.asarray(arrays["active"], dtype=bool)
        ground = particle_ground(np.asarray(arrays["positions"])[active], spacing, box)
        return water_shown(timeline.at_frame(self.results, index), ground, box)

    def _stage_at(self, index: int) -> str:
        stages = self.results.series.get("stage") if self.results is not None else None
        if stages is not None and index < len(stages):
            return f"   {stages[index]}"
        return ""

    def _apply_style(self) -> None:
        self.scene.field = self.controls.field_name
        self.scene.cmap = self.controls.cmap.currentText()
        self.scene.clim = self.controls.clim()
        self.scene.smooth_cell_m = self.smooth_cell_m()

    def smooth_cell_m(self) -> float | None:
        """The cell size the shown stresses are averaged over (None: not smoothed)."""
        if self.results is None or not self.controls.smooth.isChecked():
            return None
        return _cell_of(self.results.summary)

    def _field_picked(self) -> None:
        self.controls.set_field(self.controls.field_name)

    def _restyle(self) -> None:
        self.controls._sync_unit()
        if self.results is not None:
            self.show_frame(self.frame_index)
            if self.history is not None and self.scene.picked_id is not None:
                self.pick_particle(self.scene.picked_id)

    def set_field(self, name: str) -> None:
        """Colour by ``name`` (a key of :data:`app.render.FIELDS`)."""
        self.controls.set_field(name)

    # -- particle history ---------------------------------------------------------------------------

    def pick_particle(self, particle: int) -> None:
        """Plot the history of ``particle`` (for the shown field) and mark it in the view."""
        self.scene.set_picked(particle)
        if self.results is None:
            return
        field = self.controls.field_name
        info = field_info(field)
        try:
            times, raw = self.particle_history(particle, info.source)
            values = field_values({info.source: raw}, field)
        except (KeyError, IndexError, ValueError) as err:
            self.message.emit(str(err))
            return
        label = _field_label(field)
        self.history = (f"particle_{particle}_{field}", times, np.asarray(values, float))
        self.history_plot.show_history(particle, label, times, values)
        self.side.setCurrentWidget(self.history_plot)
        self.message.emit(f"particle {particle}: {label} from {values[0]:.4g} to {values[-1]:.4g}")

    # -- exports ----------------------------------------------------------------------------------

    def export_screenshot(self, path: str | Path, size: tuple[int, int]) -> Path:
        """Render the shown frame offscreen at ``size`` pixels (as ``runout render``) to a PNG."""
        from app.render import render_frame

        if self.results is None:
            raise ValueError("open a results folder first")
        field = self.controls.field_name
        cmap = None if FIELDS[field].categorical else self.controls.cmap.currentText()
        return render_frame(self.results, self.frame_index, field, path, size=size, cmap=cmap,
                            clim=self.controls.clim())

    def export_animation(self, path: str | Path, fps: float, size: tuple[int, int],
                         on_frame: Any = None) -> Path:
        """Write every frame as an mp4 or gif movie (offscreen, as ``runout animate``)."""
        from app.render import animate

        if self.results is None:
            raise ValueError("open a results folder first")
        field = self.controls.field_name
        cmap = None if FIELDS[field].categorical else self.controls.cmap.currentText()
        return animate(self.results, path, field, fps, size=size, cmap=cmap, clim=self.controls.clim(),
                       on_frame=on_frame)

    def export_curves(self, path: str | Path) -> Path:
        """Write the run's curves (and the picked particle's history) as CSV."""
        if self.results is not None:
            series = {k: v for k, v in self.results.series.items() if k != "stage"}
        else:
            series = {k: np.asarray(v) for k, v in self.curves.data.items()}
        if not len(series.get("time_s", [])):
            raise ValueError("there are no curves to export yet")
        return write_curves_csv(path, series, self.history)


class CompareView(QWidget):
    """Two results folders side by side: one camera, one time, one field and colour range."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.results: list[Any] = [None, None]
        self.controls = _Controls()
        self.controls.frameChosen.connect(self.show_frame)
        self.controls.styleChanged.connect(lambda: self.show_frame(self.controls.slider.value()))
        self.controls.field.activated.connect(lambda _i: self.controls.set_field(self.controls.field_name))
        self.labels = [QLabel("A: choose a results folder"), QLabel("B: choose a results folder")]
        self.scenes = [ParticleScene(), ParticleScene()]
        self.open_buttons = [QPushButton("Open A…"), QPushButton("Open B…")]
        panes = QSplitter(Qt.Orientation.Horizontal)
        for label, scene, button in zip(self.labels, self.scenes, self.open_buttons, strict=True):
            pane = QWidget()
            v = QVBoxLayout(pane)
            v.setContentsMargins(0, 0, 0, 0)
            h = QHBoxLayout()
            label.setWordWrap(True)
            h.addWidget(label, 1)
            h.addWidget(button)
            v.addLayout(h)
            v.addWidget(scene, 1)
            panes.addWidget(pane)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.addWidget(self.controls)
        layout.addWidget(panes, 1)
        # one camera object for both renderers: panning or zooming either moves both
        a, b = self.scenes
        b.plotter.renderer.camera = a.plotter.renderer.camera
        self._pending = False
        self._camera_tag = a.plotter.renderer.GetActiveCamera().AddObserver("ModifiedEvent", self._camera_moved)

    def close_view(self) -> None:
        self.controls.stop()
        camera = self.scenes[0].plotter.renderer.GetActiveCamera() if not self.scenes[0]._closed else None
        if camera is not None:
            camera.RemoveObserver(self._camera_tag)
        for scene in self.scenes:
            scene.close_view()

    def _camera_moved(self, *_args: Any) -> None:
        if not self._pending:
            self._pending = True
            QTimer.singleShot(0, self._render_both)

    def _render_both(self) -> None:
        self._pending = False
        for scene in self.scenes:
            if not scene._closed:
                scene._update_point_size()
                scene.plotter.render()

    def open_results(self, side: int, path: str | Path) -> None:
        """Show a results folder on side 0 (A) or 1 (B)."""
        from projects.results import ResultsError, open_results

        results = open_results(path)
        if len(results) == 0:
            raise ResultsError(f"{results.path} has no complete frames to show")
        self.results[side] = results
        scene = self.scenes[side]
        scene.clear()
        scene.set_domain(_domain_of(results.summary), float(results.summary.get("particle_spacing_m") or 0.0),
                         results.material_names)
        scene.show_structures(results.summary.get("structures") or [])
        s = results.summary
        self.labels[side].setText(f"{'AB'[side]}: {s.get('title') or results.path.name} — {results.path.name} "
                                  f"({s.get('scheme', '?')}, {s.get('particles', '?')} particles, {results.status})")
        longest = max(len(r) for r in self.results if r is not None)
        self.controls.slider.setRange(0, longest - 1)
        self.show_frame(self.controls.slider.value())
        self.scenes[0].fit()

    def _index_at(self, results: Any, time_s: float) -> int:
        return int(np.argmin(np.abs(results.times - time_s)))

    def show_frame(self, index: int) -> None:
        """Show both sides at the time of frame ``index`` of the longer run (nearest frame each)."""
        present = [r for r in self.results if r is not None]
        if not present:
            return
        ref = max(present, key=len)
        index = max(0, min(int(index), len(ref) - 1))
        time_s = float(ref.times[index])
        field = self.controls.field_name
        arrays = [None, None]
        for side, results in enumerate(self.results):
            if results is not None:
                arrays[side] = results.frame(self._index_at(results, time_s))
        clim = self.controls.clim()
        if clim is None and not FIELDS[field].categorical:
            # one range for both sides, so equal colours mean equal values
            ranges = []
            for a in arrays:
                if a is not None:
                    try:
                        ranges.append(value_range(np.asarray(field_values(a, field), float)[np.asarray(a["active"], bool)]))
                    except ValueError:
                        continue
            if ranges:
                clim = (min(r[0] for r in ranges), max(r[1] for r in ranges))
        for side, results in enumerate(self.results):
            if results is None:
                continue
            scene = self.scenes[side]
            scene.field, scene.cmap, scene.clim = field, self.controls.cmap.currentText(), clim
            scene.smooth_cell_m = _cell_of(results.summary) if self.controls.smooth.isChecked() else None
            j = self._index_at(results, time_s)
            scene.show_arrays(arrays[side], float(results.times[j]), f"frame {j + 1}/{len(results)}")
        if clim is not None:
            self.controls.show_range(clim)
        self.controls.time_label.setText(f"t = {time_s:.4g} s")
