"""Dialogs: the problems of a project, the slope template, and export settings."""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

import numpy as np
from PySide6.QtWidgets import (
    QAbstractItemView,
    QCheckBox,
    QComboBox,
    QDialog,
    QDialogButtonBox,
    QDoubleSpinBox,
    QFileDialog,
    QFormLayout,
    QHBoxLayout,
    QHeaderView,
    QLabel,
    QLineEdit,
    QListWidget,
    QPushButton,
    QSpinBox,
    QTableWidget,
    QTableWidgetItem,
    QVBoxLayout,
    QWidget,
)

from app.gui.document import parse_number
from app.gui.fields import unit_label

logger = logging.getLogger(__name__)


class ProblemsDialog(QDialog):
    """Every problem of a project file as a readable list (never a traceback).

    With ``can_open`` the dialog offers to open the file anyway, to fix the problems in the
    workbench; :attr:`open_anyway` says whether the user chose that.
    """

    def __init__(self, title: str, intro: str, problems: list[str], can_open: bool = False,
                 parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setWindowTitle(title)
        self.open_anyway = False
        layout = QVBoxLayout(self)
        label = QLabel(intro)
        label.setWordWrap(True)
        layout.addWidget(label)
        self.list = QListWidget()
        self.list.addItems(problems)
        self.list.setWordWrap(True)
        self.list.setMinimumSize(560, 160)
        layout.addWidget(self.list)
        buttons = QDialogButtonBox(QDialogButtonBox.StandardButton.Close)
        if can_open:
            fix = buttons.addButton("Open anyway to fix", QDialogButtonBox.ButtonRole.AcceptRole)
            fix.clicked.connect(self._fix)
        buttons.rejected.connect(self.reject)
        layout.addWidget(buttons)

    def _fix(self) -> None:
        self.open_anyway = True
        self.accept()


def _spin(value: float, lo: float, hi: float, decimals: int = 3, step: float = 1.0) -> QDoubleSpinBox:
    spin = QDoubleSpinBox()
    spin.setDecimals(decimals)
    spin.setRange(lo, hi)
    spin.setSingleStep(step)
    spin.setValue(value)
    return spin


def _with_unit(widget: QWidget, unit: str) -> QWidget:
    box = QWidget()
    row = QHBoxLayout(box)
    row.setContentsMargins(0, 0, 0, 0)
    row.addWidget(widget, 1)
    row.addWidget(unit_label(unit))
    return box


class SlopeDialog(QDialog):
    """A slope on a foundation, optionally in horizontal layers (``geometry.templates.slope_profile``).

    :meth:`bodies` gives the project bodies; :meth:`domain` a grid box that holds the slope and
    room for the run-out in front of its toe.
    """

    def __init__(self, materials: list[str], parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setWindowTitle("Slope from template")
        self.materials = materials
        layout = QVBoxLayout(self)
        form = QFormLayout()
        self.height = _spin(10.0, 0.001, 1e4)
        self.angle = _spin(45.0, 0.5, 89.5, 2)
        self.crest = _spin(10.0, 0.0, 1e4)
        self.toe = _spin(20.0, 0.0, 1e4)
        self.depth = _spin(2.0, 0.0, 1e4)
        self.origin_x = _spin(0.0, -1e5, 1e5)
        self.origin_y = _spin(0.0, -1e5, 1e5)
        form.addRow("Height", _with_unit(self.height, "m"))
        form.addRow("Face angle", _with_unit(self.angle, "°"))
        form.addRow("Crest length", _with_unit(self.crest, "m"))
        form.addRow("Toe length", _with_unit(self.toe, "m"))
        form.addRow("Foundation depth", _with_unit(self.depth, "m"))
        origin = QWidget()
        row = QHBoxLayout(origin)
        row.setContentsMargins(0, 0, 0, 0)
        row.addWidget(self.origin_x)
        row.addWidget(self.origin_y)
        form.addRow("Lower-left corner", _with_unit(origin, "m"))
        self.material = QComboBox()
        self.material.addItems(materials)
        form.addRow("Material (no layers)", self.material)
        layout.addLayout(form)
        layout.addWidget(QLabel("Layers from the crest down (optional); below the last: foundation"))
        self.layers = QTableWidget(0, 3)
        self.layers.setHorizontalHeaderLabels(["Name", "Thickness (m)", "Material"])
        self.layers.horizontalHeader().setSectionResizeMode(QHeaderView.ResizeMode.Stretch)
        self.layers.setSelectionBehavior(QAbstractItemView.SelectionBehavior.SelectRows)
        self.layers.setMaximumHeight(140)
        layout.addWidget(self.layers)
        row = QHBoxLayout()
        add = QPushButton("Add layer")
        add.clicked.connect(lambda: self.add_layer())
        remove = QPushButton("Remove layer")
        remove.clicked.connect(self._remove_layer)
        self.foundation_material = QComboBox()
        self.foundation_material.addItems(materials)
        row.addWidget(add)
        row.addWidget(remove)
        row.addWidget(QLabel("Foundation material"))
        row.addWidget(self.foundation_material)
        layout.addLayout(row)
        self.replace = QCheckBox("Replace the existing bodies")
        self.replace.setChecked(True)
        self.fit_domain = QCheckBox("Fit the domain around the slope")
        self.fit_domain.setChecked(True)
        layout.addWidget(self.replace)
        layout.addWidget(self.fit_domain)
        self.error = QLabel("")
        self.error.setWordWrap(True)
        self.error.setStyleSheet("color: #b3261e;")
        layout.addWidget(self.error)
        buttons = QDialogButtonBox(QDialogButtonBox.StandardButton.Ok | QDialogButtonBox.StandardButton.Cancel)
        buttons.accepted.connect(self._accept)
        buttons.rejected.connect(self.reject)
        layout.addWidget(buttons)

    def add_layer(self, name: str = "", thickness: float = 2.0, material: str | None = None) -> None:
        r = self.layers.rowCount()
        self.layers.insertRow(r)
        self.layers.setItem(r, 0, QTableWidgetItem(name or f"layer-{r + 1}"))
        self.layers.setItem(r, 1, QTableWidgetItem(f"{thickness:g}"))
        combo = QComboBox()
        combo.addItems(self.materials)
        if material:
            combo.setCurrentText(material)
        self.layers.setCellWidget(r, 2, combo)

    def _remove_layer(self) -> None:
        rows = sorted({i.row() for i in self.layers.selectedIndexes()}, reverse=True)
        for r in rows or [self.layers.rowCount() - 1]:
            if r >= 0:
                self.layers.removeRow(r)

    def bodies(self) -> list[dict[str, Any]]:
        """The slope's bodies as project tables (raises ValueError naming a bad value)."""
        from geometry.templates import SlopeLayer, slope_profile

        layers, materials = [], {}
        for r in range(self.layers.rowCount()):
            name = (self.layers.item(r, 0).text() if self.layers.item(r, 0) else "").strip()
            thickness = parse_number(self.layers.item(r, 1).text() if self.layers.item(r, 1) else "")
            if thickness is None:
                raise ValueError(f"layer {r + 1}: the thickness must be a number of metres")
            layers.append(SlopeLayer(name, thickness))
            materials[name] = self.layers.cellWidget(r, 2).currentText()
        profile = slope_profile(
            self.height.value(), self.angle.value(), self.crest.value(), self.toe.value(), self.depth.value(),
            layers=tuple(layers), origin_m=(self.origin_x.value(), self.origin_y.value()),
        )
        out = []
        for name, polygon in profile:
            if layers:
                material = materials.get(name, self.foundation_material.currentText())
            else:
                material = self.material.currentText()
            out.append({"name": name, "material": material,
                        "polygon_m": [[float(x), float(y)] for x, y in polygon]})
        return out

    def fit(self, bodies: list[dict[str, Any]], cell_size_m: float
            ) -> tuple[list[dict[str, Any]], list[float], list[float]]:
        """The bodies and the grid box fitted to them (:func:`geometry.templates.fit_domain`): the
        ground on the base, the section's ends on the side walls at any cell size (its right end
        moved onto the wall by less than half a cell), a quarter of the height above."""
        from geometry.templates import fit_domain

        fitted = fit_domain([np.asarray(b["polygon_m"], dtype=float) for b in bodies], cell_size_m)
        moved = [{**b, "polygon_m": [[float(x), float(y)] for x, y in polygon]}
                 for b, polygon in zip(bodies, fitted.polygons)]
        return moved, list(fitted.origin_m), list(fitted.size_m)

    def _accept(self) -> None:
        try:
            self.bodies()
        except ValueError as err:
            self.error.setText(str(err))
            return
        self.accept()


class ExportDialog(QDialog):
    """Where and how big: a picture (PNG) or a movie (mp4/gif) of the shown results."""

    def __init__(self, kind: str, default_path: Path, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.kind = kind
        self.setWindowTitle("Export picture" if kind == "picture" else "Export animation")
        form = QFormLayout(self)
        self.path = QLineEdit(str(default_path))
        browse = QPushButton("…")
        browse.clicked.connect(self._browse)
        row = QWidget()
        h = QHBoxLayout(row)
        h.setContentsMargins(0, 0, 0, 0)
        h.addWidget(self.path, 1)
        h.addWidget(browse)
        form.addRow("File", row)
        self.width_ = QSpinBox()
        self.width_.setRange(16, 16384)
        self.height_ = QSpinBox()
        self.height_.setRange(16, 16384)
        if kind == "picture":
            self.width_.setValue(1920)
            self.height_.setValue(1080)
        else:
            self.width_.setValue(1280)
            self.height_.setValue(720)
        size = QWidget()
        h = QHBoxLayout(size)
        h.setContentsMargins(0, 0, 0, 0)
        h.addWidget(self.width_)
        h.addWidget(QLabel("×"))
        h.addWidget(self.height_)
        h.addWidget(unit_label("px"))
        form.addRow("Size", size)
        self.fps = QDoubleSpinBox()
        self.fps.setRange(0.5, 120.0)
        self.fps.setValue(10.0)
        if kind != "picture":
            form.addRow("Frames per second", _with_unit(self.fps, "1/s"))
        buttons = QDialogButtonBox(QDialogButtonBox.StandardButton.Ok | QDialogButtonBox.StandardButton.Cancel)
        buttons.accepted.connect(self.accept)
        buttons.rejected.connect(self.reject)
        form.addRow(buttons)

    def _browse(self) -> None:
        filters = "PNG image (*.png)" if self.kind == "picture" else "MP4 movie (*.mp4);;GIF animation (*.gif)"
        path, _ = QFileDialog.getSaveFileName(self, self.windowTitle(), self.path.text(), filters)
        if path:
            self.path.setText(path)

    @property
    def size_px(self) -> tuple[int, int]:
        return int(self.width_.value()), int(self.height_.value())
