"""The Water panel: the ground water of the project (``[water]``) and where each stage moves it.

The lines are drawn and edited like bodies: *Draw…* clicks a line's points in the view from left
to right (it replaces the line), the vertices are dragged in the view or typed in the table, and
*Level at* puts a level line across the domain at a typed height. The project's lines hold at the
start of the run; a stage's lines (``[stages.water]``) are where that stage moves the water,
linearly over its duration. Every edit is one undo step of the document
(:func:`app.gui.scene_view.set_water_line`).
"""

from __future__ import annotations

import re

from PySide6.QtCore import Qt, Signal
from PySide6.QtGui import QBrush, QColor
from PySide6.QtWidgets import (
    QAbstractItemView,
    QCheckBox,
    QComboBox,
    QGroupBox,
    QHBoxLayout,
    QHeaderView,
    QLabel,
    QLineEdit,
    QPushButton,
    QTableWidget,
    QTableWidgetItem,
    QVBoxLayout,
    QWidget,
)

from app.gui.document import (
    FIELD_INFO,
    ProjectDocument,
    format_number,
    get_path,
    parse_number,
    water_line_path,
)
from app.gui.fields import NumberField
from app.gui.panels import Panel, _form, _NumberDelegate
from app.gui.scene_view import set_water_line, water_line_noun
from app.gui.units import parse_quantity


class WaterPanel(Panel):
    """The water lines (the project's and each stage's), the chosen line's points, the water's
    unit weight and the inclined-line correction.

    Signals
    -------
    drawRequested(int)
        The user wants to draw water line ``slot`` in the scene view.
    """

    drawRequested = Signal(int)

    def __init__(self, doc: ProjectDocument, parent: QWidget | None = None) -> None:
        super().__init__(doc, parent)
        self.slot = 0
        self._filling = False
        box = QGroupBox("Water lines")
        vbox = QVBoxLayout(box)
        self.line_choice = QComboBox()
        self.line_choice.setAccessibleName("Water line")
        self.line_choice.currentIndexChanged.connect(self._line_chosen)
        vbox.addWidget(self.line_choice)
        self.line_status = QLabel("")
        self.line_status.setWordWrap(True)
        self.line_status.setStyleSheet("color: #555;")
        vbox.addWidget(self.line_status)
        row = QHBoxLayout()
        self.draw_button = QPushButton("Draw…")
        self.draw_button.setToolTip("Click the line's points in the view from left to right; double-click or "
                                    "Enter to finish. The drawn line replaces this one")
        self.draw_button.clicked.connect(lambda: self.drawRequested.emit(self.slot))
        self.level = QLineEdit()
        self.level.setPlaceholderText("y (m)")
        self.level.setAccessibleName("Level height")
        self.level.setMaximumWidth(90)
        self.level_button = QPushButton("Level at")
        self.level_button.setToolTip("A level line across the domain at the height typed beside")
        self.level_button.clicked.connect(self._level_typed)
        self.level.returnPressed.connect(self._level_typed)
        self.remove_button = QPushButton("Remove")
        self.remove_button.clicked.connect(self.remove_line)
        for w in (self.draw_button, self.level_button, self.level, self.remove_button):
            row.addWidget(w)
        vbox.addLayout(row)
        self.table = QTableWidget(0, 2)
        self.table.setHorizontalHeaderLabels(["x (m)", "y (m)"])
        self.table.horizontalHeader().setSectionResizeMode(QHeaderView.ResizeMode.Stretch)
        self.table.setSelectionBehavior(QAbstractItemView.SelectionBehavior.SelectRows)
        self.table.setSelectionMode(QAbstractItemView.SelectionMode.SingleSelection)
        self.table.setItemDelegate(_NumberDelegate(self.table))
        self.table.setMinimumHeight(140)
        self.table.itemChanged.connect(self._cell_edited)
        self.table.currentCellChanged.connect(self._vertex_chosen)
        vbox.addWidget(self.table)
        row = QHBoxLayout()
        self.insert_button = QPushButton("Insert point")
        self.insert_button.setToolTip("A point halfway to the next one (or past the last)")
        self.insert_button.clicked.connect(self.insert_vertex)
        self.delete_vertex_button = QPushButton("Delete point")
        self.delete_vertex_button.clicked.connect(self.delete_vertex)
        row.addWidget(self.insert_button)
        row.addWidget(self.delete_vertex_button)
        vbox.addLayout(row)
        self.line_problems = QLabel("")
        self.line_problems.setWordWrap(True)
        self.line_problems.setStyleSheet("color: #b3261e;")
        vbox.addWidget(self.line_problems)
        self.layout_.addWidget(box)

        box, form = _form("Water")
        label, unit = FIELD_INFO["unit_weight_n_m3"]
        self.unit_weight = NumberField(doc, None, label, unit, optional=True, placeholder="9810 (9.81 kN/m³)")
        self.unit_weight.setToolTip("gamma_w, for the full gravity of the run; typed in N/m3 or kN/m3")
        form.addRow("Unit weight", self.unit_weight)
        self.inclined = QCheckBox("Inclined-line correction (u = γw h cos²θ)")
        self.inclined.setToolTip("The pore pressure of seepage parallel to an inclined phreatic line: the head "
                                 "at depth h below the line is h cos²θ, θ the line's inclination")
        self.inclined.toggled.connect(self._inclined_toggled)
        form.addRow(self.inclined)
        self.layout_.addWidget(box)
        note = QLabel("The project's lines hold at the start. A stage's lines are where it moves the water, "
                      "linearly over its duration (a k0 stage at once); a line a stage leaves out stays. "
                      "Below the phreatic line the pore pressure is hydrostatic; where the free-water line "
                      "(or else the phreatic line) is above the ground, free water stands on it. The "
                      "saturated density and r_u are in the Materials panel.")
        note.setWordWrap(True)
        note.setStyleSheet("color: #555;")
        self.layout_.addWidget(note)
        self.watch(self.unit_weight)
        self.finish()
        doc.selection.changed.connect(self._selection_changed)
        self._on_changed(frozenset({"water", "stages"}))

    # -- state ----------------------------------------------------------------------------------

    def slots(self) -> list[tuple[int, str]]:
        """Every line the panel offers: (slot, label)."""
        out = [(0, "Project: phreatic line"), (1, "Project: free-water line")]
        for i, stage in enumerate(self.doc.get("stages", []) or []):
            name = stage.get("name") or stage.get("type", "?") if isinstance(stage, dict) else "?"
            out += [(2 + 2 * i, f"Stage {i + 1} ({name}): phreatic line"),
                    (3 + 2 * i, f"Stage {i + 1} ({name}): free-water line")]
        return out

    def line(self) -> list[list[float]] | None:
        value = get_path(self.doc.data, water_line_path(self.slot))
        return value if isinstance(value, list) else None

    def choose(self, slot: int) -> None:
        """Show and select water line ``slot`` (also when it is not drawn yet)."""
        index = self.line_choice.findData(int(slot))
        if index >= 0:
            self.line_choice.setCurrentIndex(index)

    def _line_chosen(self, index: int) -> None:
        if self._filling or index < 0:
            return
        self.slot = int(self.line_choice.itemData(index))
        self.doc.selection.select("water", self.slot if self.line() is not None else None)
        self._fill()

    def _selection_changed(self) -> None:
        sel = self.doc.selection
        if sel.kind == "water" and sel.index is not None and sel.index != self.slot:
            self.slot = sel.index
            self._fill_choice()
        self._fill()

    def _on_changed(self, sections: frozenset) -> None:
        if sections & {"water", "stages", "domain"}:
            self._fill_choice()
            self._fill()

    def _fill_choice(self) -> None:
        self._filling = True
        try:
            self.line_choice.clear()
            for slot, label in self.slots():
                drawn = isinstance(get_path(self.doc.data, water_line_path(slot)), list)
                self.line_choice.addItem(label + ("" if drawn else "  (none)"), slot)
            index = self.line_choice.findData(self.slot)
            if index < 0:
                self.slot, index = 0, 0
            self.line_choice.setCurrentIndex(index)
        finally:
            self._filling = False

    def _fill(self) -> None:
        self._filling = True
        try:
            line = self.line() or []
            self.table.setRowCount(len(line))
            for i, point in enumerate(line):
                for j in range(2):
                    value = point[j] if isinstance(point, list) and len(point) > j else ""
                    cell = QTableWidgetItem(format_number(value))
                    cell.setTextAlignment(Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignVCenter)
                    self.table.setItem(i, j, cell)
            sel = self.doc.selection
            if sel.kind == "water" and sel.index == self.slot and sel.vertex is not None and sel.vertex < len(line):
                self.table.setCurrentCell(sel.vertex, 0)
            else:
                self.table.clearSelection()
            has_water = isinstance(self.doc.get("water"), dict)
            stage = self.slot // 2
            if not line:
                text = ("no ground water: draw the phreatic line, or give it a level" if self.slot == 0 else
                        "none: the free water stands at the phreatic line" if self.slot == 1 else
                        "none: this stage leaves this line where the stages before left it")
            else:
                text = f"{len(line)} points, {water_line_noun(self.slot)}"
                if stage:
                    text += ": where the stage moves it, linearly over its duration"
            if stage and not has_water:
                text += " (give the project's phreatic line first)"
            self.line_status.setText(text)
            self.remove_button.setEnabled(bool(line))
            self.remove_button.setToolTip("Remove the ground water: [water] and every stage's water move"
                                          if self.slot == 0 else f"Remove the {water_line_noun(self.slot)}")
            for b in (self.insert_button, self.delete_vertex_button):
                b.setEnabled(bool(line))
            self.unit_weight.set_path("water.unit_weight_n_m3" if has_water else None)
            self.inclined.blockSignals(True)
            self.inclined.setChecked(bool(self.doc.get("water.inclined_line_correction", False)) is True)
            self.inclined.setEnabled(has_water)
            self.inclined.blockSignals(False)
            self._flag_points()
        finally:
            self._filling = False

    def _flag_points(self) -> None:
        """The problems of the chosen line (a point that does not lie right of the one before, ...)."""
        path = water_line_path(self.slot)
        stage_path = path.rsplit(".", 1)[0]
        problems = [p for p in self.doc.problems if p.path == path or p.path.startswith(path + ".")
                    or (p.path == stage_path and self.slot >= 2)]
        for p in problems:
            found = re.search(r"point (\d+) \[", p.message) if p.path == path else None
            if found and int(found.group(1)) < self.table.rowCount():
                for j in range(2):
                    item = self.table.item(int(found.group(1)), j)
                    if item is not None:
                        item.setBackground(QBrush(QColor("#fde2e1")))
        self.line_problems.setText("\n".join(str(p) for p in problems))

    # -- edits ----------------------------------------------------------------------------------

    def set_line(self, line: list[list[float]] | None, text: str | None = None) -> bool:
        """Set (None: remove) the chosen line as one undo step."""
        noun = water_line_noun(self.slot)
        done = set_water_line(self.doc, self.slot, line, text or (f"set the {noun}" if line else f"remove the {noun}"))
        self.doc.selection.select("water", self.slot if self.line() is not None else None)
        return done

    def set_level(self, y_m: float) -> bool:
        """The chosen line level at ``y_m`` across the domain."""
        origin = self.doc.get("domain.origin_m", [0.0, 0.0])
        size = self.doc.get("domain.size_m", [1.0, 1.0])
        try:
            x0, x1 = float(origin[0]), float(origin[0]) + float(size[0])
        except (TypeError, ValueError, IndexError):
            x0, x1 = 0.0, 1.0
        return self.set_line([[x0, float(y_m)], [x1, float(y_m)]],
                             f"level the {water_line_noun(self.slot)} at {format_number(float(y_m))} m")

    def _level_typed(self) -> None:
        value, error = parse_quantity(self.level.text(), "m")
        if value is None:
            self.show_message(f"Level: {error or 'must be a number'}")
            return
        self.show_message("")
        self.set_level(value)

    def remove_line(self) -> bool:
        return self.set_line(None)

    def _inclined_toggled(self, on: bool) -> None:
        if not self._filling and isinstance(self.doc.get("water"), dict):
            self.doc.set_value("water.inclined_line_correction", bool(on),
                               "inclined-line correction " + ("on" if on else "off"))

    def _vertex_chosen(self, row: int, _col: int, _prow: int, _pcol: int) -> None:
        if not self._filling and self.line() is not None:
            self.doc.selection.select("water", self.slot, row if row >= 0 else None)

    def _cell_edited(self, item: QTableWidgetItem) -> None:
        if self._filling:
            return
        value = parse_number(item.text())
        row, col = item.row(), item.column()
        if value is None:
            self.show_message(f"point {row + 1}: {'x' if col == 0 else 'y'} must be a number")
            self._fill()
            return
        self.set_vertex(row, col, value)

    def set_vertex(self, row: int, col: int, value: float) -> bool:
        """Set coordinate ``col`` (0: x, 1: y) of point ``row`` of the chosen line."""
        line = [list(p) for p in (self.line() or [])]
        if not 0 <= row < len(line):
            return False
        line[row][col] = float(value)
        return self.set_line(line, f"move point {row + 1} of the {water_line_noun(self.slot)}")

    def insert_vertex(self) -> None:
        line = [list(p) for p in (self.line() or [])]
        if not line:
            return
        sel = self.doc.selection
        i = sel.vertex if sel.kind == "water" and sel.index == self.slot and sel.vertex is not None else len(line) - 1
        if i < len(line) - 1:
            a, b = line[i], line[i + 1]
            point = [(a[0] + b[0]) / 2.0, (a[1] + b[1]) / 2.0]
        else:
            cell = self.doc.get("domain.cell_size_m", 1.0)
            point = [line[i][0] + 4.0 * float(cell if isinstance(cell, (int, float)) else 1.0), line[i][1]]
        line.insert(i + 1, point)
        self.set_line(line, f"insert a point in the {water_line_noun(self.slot)}")
        self.doc.selection.select("water", self.slot, i + 1)

    def delete_vertex(self) -> None:
        line = [list(p) for p in (self.line() or [])]
        sel = self.doc.selection
        if not line or sel.kind != "water" or sel.index != self.slot or sel.vertex is None:
            return
        line.pop(sel.vertex)
        self.set_line(line, f"delete point {sel.vertex + 1} of the {water_line_noun(self.slot)}")
