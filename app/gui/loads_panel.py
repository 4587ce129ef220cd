"""The loads of a stage in the Stages panel: its surcharges and its seismic coefficients.

A stage's surcharges (``[[stages.surcharges]]``) are the distributed loads in force from that
stage on; a stage that gives none keeps those of the stage before (shown greyed, with the stage
they come from). Editing them there, or *Add*, makes them this stage's own (a copy of the loads
in force, then the change); *Keep earlier* removes the stage's own list again, *None from here*
removes every load from this stage on. Pressures are shown in kPa and may be typed with a unit
("50 kPa", "0.05 MPa"); a second pressure makes the load vary linearly to ``to``. *Ramp* (a
dynamic stage only) grows a load over the stage from the one of its name in force before. The
seismic coefficients act in their stage only (dynamic and strength-reduction stages). Every edit
is one undo step of the document; the scene view draws the loads of the chosen stage.
"""

from __future__ import annotations

import copy
from typing import Any

from PySide6.QtCore import Qt
from PySide6.QtGui import QBrush, QColor
from PySide6.QtWidgets import (
    QAbstractItemView,
    QComboBox,
    QFormLayout,
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

from app.gui.document import ProjectDocument, check_value, format_number, get_path
from app.gui.units import parse_quantity
from projects.schema import SEISMIC_DIRECTIONS

#: The table's columns: (title, key); the pressures in kPa. The units on a second line: in one
#: line the titles were clipped in the dock's width ("rom (m" once the row was selected).
COLUMNS = (("Name", "name"), ("From\n(m)", "from_m"), ("To\n(m)", "to_m"), ("q\n(kPa)", "start"),
           ("q at To\n(kPa)", "end"), ("Ramp", "ramp"))
KPA = 1e3


def loads_in_force(data: Any, index: int) -> tuple[list[dict[str, Any]], int | None]:
    """The surcharges in force during stage ``index`` of project data (plain dicts, maybe not
    valid) and the stage that gave them (None: no stage up to it gave any)."""
    stages = data.get("stages") if isinstance(data, dict) else None
    current: list[dict[str, Any]] = []
    source = None
    for k, stage in enumerate(stages if isinstance(stages, list) else []):
        if k > index:
            break
        if isinstance(stage, dict) and isinstance(stage.get("surcharges"), list):
            current = [s for s in stage["surcharges"] if isinstance(s, dict)]
            source = k
    return current, source


def pressures(load: dict[str, Any]) -> tuple[float | None, float | None]:
    """A surcharge's pressure at ``from_m`` and at ``to_m`` (Pa; None where not a number)."""
    p = load.get("pressure_pa")
    if isinstance(p, (list, tuple)) and len(p) == 2:
        a, b = p
    else:
        a = b = p
    number = (lambda v: float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else None)
    return number(a), number(b)


def pressure_text(load: dict[str, Any]) -> str:
    """``"50 kPa"`` or ``"0 to 30 kPa"``."""
    a, b = pressures(load)
    if a is None or b is None:
        return "? kPa"
    if a == b:
        return f"{format_number(a / KPA)} kPa"
    return f"{format_number(a / KPA)} to {format_number(b / KPA)} kPa"



def crest_span(bodies: Any) -> tuple[float, float]:
    """Where a new surcharge goes: the middle half of the highest stretch of the ground (the bodies'
    upper outline within 2 % of its height range of its top: a slope's crest, a flat block's whole
    top), where a load is first put (a building, a fill). The middle fifth of the bodies' width, the
    default before, lay on the face and the toe of a slope."""
    import numpy as np

    from projects.loads import ground_height

    polygons = [np.asarray(b["polygon_m"], dtype=float) for b in bodies or []
                if isinstance(b, dict) and len(b.get("polygon_m") or []) >= 3]
    if not polygons:
        return 0.4, 0.6
    xs = np.concatenate([p[:, 0] for p in polygons])
    lo, hi = float(xs.min()), float(xs.max())
    x = np.linspace(lo, hi, 401)
    y = ground_height(polygons, x)
    if not np.isfinite(y).any():
        return lo + 0.4 * (hi - lo), lo + 0.6 * (hi - lo)
    top, bottom = np.nanmax(y), np.nanmin(y)
    high = np.isfinite(y) & (y >= top - max(0.02 * (top - bottom), 1e-9 * max(abs(top), 1.0)))
    best, start = (0, 0), None
    for i, flag in enumerate([*high, False]):  # the longest run of samples at the top
        if flag and start is None:
            start = i
        elif not flag and start is not None:
            best = max(best, (i - start, start))
            start = None
    count, first = best
    a, b = float(x[first]), float(x[first + count - 1])
    if b <= a:
        return lo + 0.4 * (hi - lo), lo + 0.6 * (hi - lo)
    step = 10.0 ** np.floor(np.log10((hi - lo) / 100.0))  # round ends: 1 and 3.1 m, not 1.02 and 3.06
    f, t = (float(np.round(v / step) * step) for v in (a + 0.25 * (b - a), a + 0.75 * (b - a)))
    return (f, t) if t > f else (a + 0.25 * (b - a), a + 0.75 * (b - a))

class StageLoadsBox(QGroupBox):
    """The surcharges and seismic coefficients of one stage (:meth:`bind` chooses it)."""

    def __init__(self, doc: ProjectDocument, parent: QWidget | None = None) -> None:
        super().__init__("Loads in this stage", parent)
        self.doc = doc
        self.index: int | None = None
        self._filling = False
        vbox = QVBoxLayout(self)
        self.status = QLabel("")
        self.status.setWordWrap(True)
        self.status.setStyleSheet("color: #555;")
        vbox.addWidget(self.status)
        self.table = QTableWidget(0, len(COLUMNS))
        self.table.setHorizontalHeaderLabels([title for title, _ in COLUMNS])
        self.table.horizontalHeader().setSectionResizeMode(QHeaderView.ResizeMode.Stretch)
        self.table.horizontalHeader().setMinimumSectionSize(36)
        for c, tip in enumerate(("a load's name carries it from stage to stage", "x where it begins (m)",
                                 "x where it ends (m)", "pressure at From (kPa, or typed with a unit)",
                                 "pressure at To: linear between (empty: uniform)",
                                 "grow over this (dynamic) stage from the load of its name in force before")):
            self.table.horizontalHeaderItem(c).setToolTip(tip)
        self.table.setSelectionBehavior(QAbstractItemView.SelectionBehavior.SelectRows)
        self.table.setSelectionMode(QAbstractItemView.SelectionMode.SingleSelection)
        self.table.setMaximumHeight(130)
        self.table.setAccessibleName("Surcharges")
        self.table.itemChanged.connect(self._cell_edited)
        vbox.addWidget(self.table)
        row = QHBoxLayout()
        self.add_button = QPushButton("Add")
        self.add_button.setToolTip("A surcharge of 10 kPa over the middle fifth of the ground")
        self.add_button.clicked.connect(lambda: self.add_surcharge())
        self.remove_button = QPushButton("Remove")
        self.remove_button.clicked.connect(self._remove_selected)
        self.keep_button = QPushButton("Inherit")
        self.keep_button.setToolTip("This stage keeps the surcharges of the stage before (its own list goes)")
        self.keep_button.clicked.connect(self.keep_earlier)
        self.none_button = QPushButton("Clear")
        self.none_button.setToolTip("No surcharge from this stage on")
        self.none_button.clicked.connect(self.clear_surcharges)
        for b in (self.add_button, self.remove_button, self.keep_button, self.none_button):
            row.addWidget(b)
        vbox.addLayout(row)
        form = QFormLayout()
        self.k_h = QLineEdit()
        self.k_h.setPlaceholderText("none")
        self.k_h.setAccessibleName("Seismic coefficient k_h")
        self.k_h.setToolTip("k_h: a horizontal force k_h W on each mass (0 <= k_h < 1)")
        self.k_v = QLineEdit()
        self.k_v.setPlaceholderText("none")
        self.k_v.setAccessibleName("Seismic coefficient k_v")
        self.k_v.setToolTip("k_v: the weight becomes (1 - k_v) W; positive upwards (-1 < k_v < 1)")
        self.towards = QComboBox()
        self.towards.addItems(SEISMIC_DIRECTIONS)
        self.towards.setAccessibleName("Seismic force towards")
        self.towards.setToolTip("The horizontal force's direction: out of the slope (from the ground's higher "
                                "end to its lower), or a side")
        for edit, key in ((self.k_h, "k_h"), (self.k_v, "k_v")):
            edit.editingFinished.connect(lambda e=edit, k=key: self.set_seismic(k, e.text()))
        self.towards.activated.connect(lambda _i: self.set_seismic("towards", self.towards.currentText()))
        form.addRow("Seismic k_h", self.k_h)
        form.addRow("Seismic k_v", self.k_v)
        form.addRow("towards", self.towards)
        vbox.addLayout(form)
        self.message = QLabel("")
        self.message.setWordWrap(True)
        self.message.setStyleSheet("color: #b3261e;")
        vbox.addWidget(self.message)
        doc.changed.connect(self._on_changed)
        self.bind(None)

    # -------------------------------------------------------------- reading
    def _stage(self) -> dict[str, Any] | None:
        if self.index is None:
            return None
        stage = get_path(self.doc.data, f"stages.{self.index}")
        return stage if isinstance(stage, dict) else None

    def _kind(self) -> str | None:
        stage = self._stage()
        return stage.get("type") if stage else None

    def loads(self) -> tuple[list[dict[str, Any]], bool]:
        """The surcharges in force in the bound stage and whether they are its own."""
        if self.index is None:
            return [], False
        loads, source = loads_in_force(self.doc.data, self.index)
        return loads, source == self.index

    # -------------------------------------------------------------- showing
    def bind(self, index: int | None) -> None:
        """Show the loads of stage ``index`` (None: none)."""
        self.index = index
        self._fill()

    def _on_changed(self, sections: frozenset) -> None:
        if "stages" in sections or "bodies" in sections:
            self._fill()

    def _fill(self) -> None:
        kind = self._kind()
        loads, own = self.loads()
        self._filling = True
        self.table.setRowCount(len(loads))
        for r, load in enumerate(loads):
            start, end = pressures(load)
            values = {"name": str(load.get("name", "")), "from_m": format_number(load.get("from_m", "")),
                      "to_m": format_number(load.get("to_m", "")),
                      "start": "" if start is None else format_number(start / KPA),
                      "end": "" if end is None or end == start else format_number(end / KPA)}
            for c, (_title, key) in enumerate(COLUMNS):
                if key == "ramp":
                    item = QTableWidgetItem("")
                    flags = Qt.ItemFlag.ItemIsSelectable | Qt.ItemFlag.ItemIsEnabled
                    if own and kind == "dynamic":
                        flags |= Qt.ItemFlag.ItemIsUserCheckable
                    item.setFlags(flags)
                    item.setCheckState(Qt.CheckState.Checked if own and load.get("ramp") else Qt.CheckState.Unchecked)
                else:
                    item = QTableWidgetItem(values[key])
                if not own:
                    item.setForeground(QBrush(QColor("#80868b")))
                self.table.setItem(r, c, item)
        self._filling = False
        stage_loads = kind not in (None, "k0")
        for w in (self.table, self.add_button, self.remove_button, self.none_button):
            w.setEnabled(stage_loads)
        self.keep_button.setEnabled(stage_loads and own)
        if self.index is None:
            self.status.setText("")
        elif kind == "k0":
            self.status.setText("A k0 stage takes no loads (its stress is the overburden's): give them on a "
                                "gravity stage, where they ramp up with gravity, or a later stage.")
        elif own:
            self.status.setText(f"{len(loads)} surcharge{'' if len(loads) == 1 else 's'} from this stage on"
                                + (" (ramped with gravity)" if kind == "gravity" and loads else ""))
        else:
            _loads, source = loads_in_force(self.doc.data, self.index)
            self.status.setText("No surcharge" if source is None else
                                f"Surcharges of stage {source + 1}, in force here too (edit to change them here)")
        seismic = self._stage().get("seismic") if self._stage() else None
        seismic = seismic if isinstance(seismic, dict) else {}
        quake = kind in ("dynamic", "strength-reduction")
        for edit, key in ((self.k_h, "k_h"), (self.k_v, "k_v")):
            edit.setText(format_number(seismic[key]) if key in seismic else "")
            edit.setEnabled(quake)
        self.towards.setCurrentText(str(seismic.get("towards", SEISMIC_DIRECTIONS[0])))
        self.towards.setEnabled(quake)
        self.message.setText("")

    # -------------------------------------------------------------- editing
    def _edit(self, text: str, change) -> bool:
        """Change the bound stage's own surcharges (made from those in force first) as one step."""
        if self.index is None or self._kind() in (None, "k0"):
            return False
        index = self.index
        inherited, _ = self.loads()

        def mutate(d: dict[str, Any]) -> None:
            stage = d["stages"][index]
            if not isinstance(stage.get("surcharges"), list):
                # the loads in force, at their full values (an earlier stage's ramp was that stage's)
                stage["surcharges"] = [{k: v for k, v in load.items() if k != "ramp"}
                                       for load in copy.deepcopy(inherited)]
            change(stage["surcharges"])

        return self.doc.edit(text, mutate)

    def _free_name(self) -> str:
        names = {str(s.get("name")) for s in self.loads()[0]}
        k = 1
        while f"load{k}" in names:
            k += 1
        return f"load{k}"

    def add_surcharge(self, from_m: float | None = None, to_m: float | None = None, pressure_pa: Any = 10e3,
                      name: str | None = None) -> bool:
        """Add a surcharge to the bound stage (default: 10 kPa over the middle half of the crest,
        :func:`crest_span`)."""
        if from_m is None or to_m is None:
            from_m, to_m = crest_span(self.doc.get("bodies", []))
        load = {"name": name or self._free_name(), "from_m": float(from_m), "to_m": float(to_m),
                "pressure_pa": pressure_pa}
        return self._edit(f"add surcharge {load['name']}", lambda loads: loads.append(load))

    def remove_surcharge(self, row: int) -> bool:
        loads, _ = self.loads()
        if not 0 <= row < len(loads):
            return False
        return self._edit(f"remove surcharge {loads[row].get('name', row + 1)}", lambda ls: ls.pop(row))

    def _remove_selected(self) -> None:
        row = self.table.currentRow()
        if row >= 0:
            self.remove_surcharge(row)

    def keep_earlier(self) -> bool:
        """The bound stage keeps the surcharges of the stage before (its own list removed)."""
        if self.index is None or not self.loads()[1]:
            return False
        return self.doc.set_value(f"stages.{self.index}.surcharges", None, "keep the earlier surcharges")

    def clear_surcharges(self) -> bool:
        """No surcharge from the bound stage on (``surcharges = []``)."""
        if self.index is None or self._kind() in (None, "k0"):
            return False
        return self.doc.set_value(f"stages.{self.index}.surcharges", [], "no surcharges from this stage on")

    def set_surcharge(self, row: int, key: str, text: Any) -> bool:
        """Set one value of surcharge ``row``: ``name``, ``from_m``, ``to_m`` (m), ``start`` and ``end``
        (the pressures at from and to, kPa unless a unit is typed; an empty ``end``: uniform),
        ``ramp`` (bool). A value the schema refuses is shown, not written."""
        loads, own = self.loads()
        if not 0 <= row < len(loads):
            return False
        load = loads[row] if own else {k: v for k, v in loads[row].items() if k != "ramp"}
        if key == "ramp":
            value = bool(text)
            new = {**load, "ramp": True} if value else {k: v for k, v in load.items() if k != "ramp"}
        elif key == "name":
            new = {**load, "name": str(text).strip()}
        elif key in ("from_m", "to_m"):
            number, error = parse_quantity(str(text), "m")
            if number is None:
                return self._refuse(f"{key}: {error}")
            new = {**load, key: number}
        else:
            start, end = pressures(load)
            typed = str(text).strip()
            if key == "end" and not typed:
                value = None
            else:
                value, error = parse_quantity(typed if any(c.isalpha() for c in typed) else f"{typed} kPa", "Pa")
                if value is None:
                    return self._refuse(f"pressure: {error}")
            if key == "start":
                end = value if end == start else end  # a uniform load stays uniform
                start = value
            else:
                end = value
            pressure: Any = start if end is None or end == start else [start, end]
            new = {**load, "pressure_pa": pressure}
        error = check_value(f"stages.{self.index}.surcharges.{row}", new)
        if error:
            return self._refuse(error)
        return self._edit(f"change surcharge {new.get('name', row + 1)}", lambda ls: ls.__setitem__(row, new))

    def _refuse(self, text: str) -> bool:
        self.message.setText(text)
        self._fill_soon()
        return False

    def _fill_soon(self) -> None:
        message = self.message.text()
        self._fill()
        self.message.setText(message)

    def _cell_edited(self, item: QTableWidgetItem) -> None:
        if self._filling:
            return
        key = COLUMNS[item.column()][1]
        if key == "ramp":
            self.set_surcharge(item.row(), "ramp", item.checkState() == Qt.CheckState.Checked)
        else:
            self.set_surcharge(item.row(), key, item.text())

    def set_seismic(self, key: str, text: Any) -> bool:
        """Set ``k_h``, ``k_v`` (text or a number; empty removes it) or ``towards`` of the bound
        stage's seismic coefficients; the table goes when neither coefficient is left."""
        if self.index is None or self._kind() not in ("dynamic", "strength-reduction"):
            return False
        stage = self._stage() or {}
        seismic = dict(stage.get("seismic") or {})
        if key == "towards":
            value: Any = str(text)
        elif isinstance(text, (int, float)) and not isinstance(text, bool):
            value = float(text)
        elif not str(text).strip():
            value = None
        else:
            value, error = parse_quantity(str(text), "")
            if value is None:
                return self._refuse(f"{key}: {error}")
        if value is None:
            seismic.pop(key, None)
        else:
            seismic[key] = value
        if not any(k in seismic for k in ("k_h", "k_v")):
            new = None
        else:
            new = seismic
            error = check_value(f"stages.{self.index}.seismic", new)
            if error:
                return self._refuse(f"seismic: {error}")
        if new == stage.get("seismic"):
            return False
        return self.doc.set_value(f"stages.{self.index}.seismic", new, "change the seismic coefficients")
