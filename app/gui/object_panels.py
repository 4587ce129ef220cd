"""Panels of the objects placed in the scene besides bodies: rigid structures and hazard targets.

A structure is a polygon edited exactly like a body (:class:`app.gui.panels.PolygonPanel`: drawn in
the scene view, vertices dragged there or typed in the table) with a contact instead of a
material. A target is a named vertical line (``x_m``) or point (``point_m``) whose hazard a run
records (docs/project-format.md). Both panels only push edits to the document, so every change
is one undo step and is saved with the project.
"""

from __future__ import annotations

import logging
from typing import Any

from PySide6.QtCore import Signal
from PySide6.QtGui import QIcon
from PySide6.QtWidgets import (
    QComboBox,
    QFormLayout,
    QGroupBox,
    QHBoxLayout,
    QLineEdit,
    QListWidget,
    QPushButton,
    QWidget,
)

from app.gui.document import ProjectDocument, format_number, parse_number
from app.gui.fields import NumberField, PairField, TextField
from app.gui.panels import Panel, PolygonPanel, _form, swatch
from projects.schema import CONTACT_TYPES

logger = logging.getLogger(__name__)

#: The colour of structures in the scene and results views (grey like :mod:`app.render`'s pictures).
STRUCTURE_COLOR = "#b4b4b4"
#: A structure's friction angle when its contact first becomes friction (degrees).
DEFAULT_FRICTION_DEG = 20.0
#: The colour of targets in the scene view.
TARGET_COLOR = "#9334e6"
#: The kinds of target, as the panel names them: ``x_m`` and ``point_m``.
TARGET_KINDS = ("vertical line", "point")


def surface_at(polygons: list[Any], x: float) -> float | None:
    """The highest point at ``x`` of the outlines ``polygons`` (lists of [x, y]): the ground there;
    None where none of them reaches ``x``."""
    top = None
    for polygon in polygons:
        try:
            pts = [(float(p[0]), float(p[1])) for p in polygon]
        except (TypeError, ValueError, IndexError):
            continue
        for (ax, ay), (bx, by) in zip(pts, pts[1:] + pts[:1]):
            if min(ax, bx) <= x <= max(ax, bx):
                y = max(ay, by) if ax == bx else ay + (x - ax) * (by - ay) / (bx - ax)
                top = y if top is None else max(top, y)
    return top


def _kn(value: Any) -> str:
    return "–" if value is None or not isinstance(value, (int, float)) or value != value else f"{value / 1e3:.3g}"


def force_text(row: dict[str, Any]) -> str:
    """``peak 104 kN/m (N 104, T -1.71) at 3.55 s`` and, on a second line, ``mean N up to 103 kN/m
    at 3.55 s`` for a row of :func:`projects.results.force_table`."""
    text = (f"peak {_kn(row.get('peak_force_N_per_m'))} kN/m (N {_kn(row.get('peak_force_normal_N_per_m'))}, "
            f"T {_kn(row.get('peak_force_tangential_N_per_m'))}) at {row.get('peak_time_s', 0.0):.3g} s")
    if row.get("max_normal_force_N_per_m") is not None:  # a line of its own: the list stays narrow
        text += (f"\nmean N up to {_kn(row['max_normal_force_N_per_m'])} kN/m at "
                 f"{row.get('max_normal_force_time_s') or 0.0:.3g} s")
    return text


def contact_kind(contact: Any) -> str:
    """``"fixed"``, ``"slip"`` or ``"friction"`` of a contact as written (a string or a table)."""
    if isinstance(contact, dict):
        return str(contact.get("type", "?"))
    return "slip" if contact is None else str(contact)


def contact_text(contact: Any) -> str:
    """A contact for a label: ``slip``, ``friction 20°``."""
    kind = contact_kind(contact)
    if kind == "friction" and isinstance(contact, dict):
        return f"friction {format_number(contact.get('friction_angle_deg', '?'))}°"
    return kind


class StructuresPanel(PolygonPanel):
    """Rigid structures (walls, barriers, bedrock): list, contact, friction angle and vertices.

    Signals
    -------
    drawRequested()
        The user wants to draw a new structure in the scene view.
    """

    KIND = "structures"
    NOUN = "structure"
    drawRequested = Signal()

    def _buttons(self) -> list[QWidget]:
        self.add_button = QPushButton("Add wall")
        self.add_button.setToolTip("A vertical wall (2 cells wide, a quarter of the domain high) at the middle "
                                   "of the domain, standing on the ground there (the bodies' and structures' "
                                   "top, else the base); edit its vertices in the table or drag them in the view")
        self.add_button.clicked.connect(lambda: self.add_structure())
        return [self.add_button]

    def _form_rows(self, form: QFormLayout) -> None:
        #: each structure's last friction angle (by name), for a return to friction after slip or fixed
        self._angles: dict[str, float] = {}
        self.contact = QComboBox()
        self.contact.addItems(list(CONTACT_TYPES))
        self.contact.setAccessibleName("Structure contact")
        self.contact.activated.connect(lambda _i: self.set_contact(self.contact.currentText()))
        self.angle = NumberField(self.doc, None, "Structure friction angle", "°")
        form.addRow("Contact", self.contact)
        form.addRow("Friction angle", self.angle)
        self.watch(self.angle)

    def _label(self, item: dict[str, Any]) -> tuple[QIcon | None, str]:
        text = f"{item.get('name', '?')}   ({contact_text(item.get('contact'))})"
        force = getattr(self, "forces", {}).get(item.get("name"))
        if force:
            text += "".join(f"\n    {line}" for line in force.splitlines())
        return swatch(STRUCTURE_COLOR), text

    def set_forces(self, rows: list[dict[str, Any]], source: str = "") -> None:
        """Show each structure's peak force from the results shown (``rows``:
        :func:`projects.results.force_table`) under its name in the list: the peak of a
        step with its normal and tangential parts and when, and the largest interval-mean normal
        force and when. ``source`` names the results folder (the list's tooltip)."""
        self.forces = {str(r["contact"]): force_text(r) for r in rows if r.get("kind") == "structure"}
        self.list.setToolTip(f"Peak forces from {source}" if self.forces and source else "")
        self._fill()

    def _bind_item(self, base: str | None) -> None:
        self.contact.setEnabled(base is not None)
        kind = contact_kind(self.doc.get(f"{base}.contact")) if base else "slip"
        self.contact.setCurrentText(kind)
        friction = base is not None and kind == "friction"
        self.angle.set_path(f"{base}.contact.friction_angle_deg" if friction else None)
        if not friction:
            self.angle.edit.setText("")
            self.angle.edit.setPlaceholderText("only with friction" if base else "")

    # -- edits ------------------------------------------------------------------------------------

    def add_structure(self, polygon: list[list[float]] | None = None, name: str | None = None,
                      contact: Any = "slip") -> int:
        """Append a structure (by default a wall in the middle of the domain, standing on the ground:
        its foot follows the top of the bodies and structures there, never inside them) and select
        it; its index."""
        if polygon is None:
            origin = self.doc.get("domain.origin_m", [0.0, 0.0])
            size = self.doc.get("domain.size_m", [1.0, 1.0])
            cell = self.doc.get("domain.cell_size_m", 0.1)
            try:
                x0 = float(origin[0]) + round(float(size[0]) / 2.0 / float(cell)) * float(cell)
                y0, width, height = float(origin[1]), 2.0 * float(cell), float(size[1]) / 4.0
                y_top = float(origin[1]) + float(size[1])
            except (TypeError, ValueError, IndexError, ZeroDivisionError):
                x0, y0, width, height, y_top = 0.0, 0.0, 0.1, 0.25, 1.0
            outlines = [item.get("polygon_m") or [] for kind in ("bodies", "structures")
                        for item in (self.doc.get(kind) or []) if isinstance(item, dict)]
            feet = []
            for x in (x0, x0 + width):
                ground = surface_at(outlines, x)
                feet.append(y0 if ground is None else max(y0, ground))
            top = min(max(feet) + height, y_top)
            if top <= max(feet):  # no room above the ground: a wall of what room there is
                top = max(feet) + 0.5 * (y_top - max(feet)) if y_top > max(feet) else max(feet) + height
            polygon = [[x0, feet[0]], [x0 + width, feet[1]], [x0 + width, top], [x0, top]]
        item = {"name": name or self.free_name("structure"), "polygon_m": [list(map(float, p)) for p in polygon],
                "contact": contact}
        self.doc.edit(f"add structure {item['name']}", lambda d: d.setdefault("structures", []).append(item))
        index = len(self._items()) - 1
        self.doc.selection.select("structures", index)
        return index

    def set_contact(self, kind: str) -> bool:
        """Give the selected structure the contact ``kind`` (friction at the angle it had before in
        this session, else DEFAULT_FRICTION_DEG)."""
        sel = self.selected
        if sel is None or kind not in CONTACT_TYPES:
            return False
        old = self.doc.get(f"structures.{sel}.contact")
        if contact_kind(old) == kind:
            return False
        name = self._items()[sel].get("name", sel)
        if contact_kind(old) == "friction":  # kept for a return to friction in this session
            self._angles[name] = old.get("friction_angle_deg", DEFAULT_FRICTION_DEG)
        angle = self._angles.get(name, DEFAULT_FRICTION_DEG)
        value: Any = {"type": "friction", "friction_angle_deg": angle} if kind == "friction" else kind
        return self.doc.set_value(f"structures.{sel}.contact", value, f"set {name} contact to {kind}")

    def set_friction_angle(self, angle_deg: float) -> bool:
        sel = self.selected
        if sel is None or contact_kind(self.doc.get(f"structures.{sel}.contact")) != "friction":
            return False
        return self.doc.set_value(f"structures.{sel}.contact.friction_angle_deg", float(angle_deg),
                                  f"change {self._items()[sel].get('name', sel)} friction angle")


class TargetsPanel(Panel):
    """Hazard targets: named vertical lines (a road, a gauge) or points (a house wall), added by
    their coordinates, renamed, moved and removed; the selection is shared with the scene view."""

    def __init__(self, doc: ProjectDocument, parent: QWidget | None = None) -> None:
        super().__init__(doc, parent)
        self.list = QListWidget()
        self.list.setMaximumHeight(130)
        self.list.currentRowChanged.connect(self._row_chosen)
        self.layout_.addWidget(self.list)

        box = QGroupBox("Add a target")
        row = QHBoxLayout(box)
        self.new_kind = QComboBox()
        self.new_kind.addItems(list(TARGET_KINDS))
        self.new_kind.setAccessibleName("New target kind")
        self.new_kind.currentTextChanged.connect(lambda t: self.new_y.setEnabled(t == "point"))
        self.new_x = QLineEdit()
        self.new_x.setPlaceholderText("x (m)")
        self.new_x.setAccessibleName("New target x")
        self.new_y = QLineEdit()
        self.new_y.setPlaceholderText("y (m)")
        self.new_y.setAccessibleName("New target y")
        self.new_y.setEnabled(False)
        self.add_button = QPushButton("Add")
        self.add_button.clicked.connect(self._add_typed)
        for w in (self.new_kind, self.new_x, self.new_y, self.add_button):
            row.addWidget(w)
        self.layout_.addWidget(box)

        box, form = _form("Selected target")
        self.name = TextField(doc, None, "Target name")
        self.kind = QComboBox()
        self.kind.addItems(list(TARGET_KINDS))
        self.kind.setAccessibleName("Target kind")
        self.kind.setToolTip("The selected target's kind: choosing the other one turns it into that kind at the "
                             "same x (a point at the ground there)")
        self.kind.activated.connect(lambda _i: self.set_kind(self.kind.currentText()))
        self.x = NumberField(doc, None, "Target x", "m")
        self.point = PairField(doc, None, "Target point", "m", names=("x", "y"))
        form.addRow("Name", self.name)
        form.addRow("Kind", self.kind)
        form.addRow("Line at x", self.x)
        form.addRow("Point", self.point)
        self.target_form = form
        self.layout_.addWidget(box)
        self.remove_button = QPushButton("Remove")
        self.remove_button.clicked.connect(self.remove_target)
        self.layout_.addWidget(self.remove_button)
        self.watch(self.name, self.x, self.point)
        self.finish()
        self._filling = False
        doc.selection.changed.connect(self._fill)
        self._fill()

    @property
    def selected(self) -> int | None:
        return self.doc.selection.target

    def _targets(self) -> list[dict[str, Any]]:
        items = self.doc.get("targets", [])
        return items if isinstance(items, list) else []

    def _row_chosen(self, row: int) -> None:
        if not self._filling:
            if row >= 0:
                self.doc.selection.select("targets", row)
            elif self.selected is not None:
                self.doc.selection.select("targets", None)

    def _on_changed(self, sections: frozenset) -> None:
        if sections & {"targets", "domain"}:
            self._fill()

    @staticmethod
    def describe(target: dict[str, Any]) -> str:
        """``road   (line at x = 0.4 m)``, ``house   (point 0.55, 0.02 m)``."""
        name = target.get("name", "?")
        point = target.get("point_m")
        if isinstance(point, list) and len(point) == 2:
            return f"{name}   (point {format_number(point[0])}, {format_number(point[1])} m)"
        return f"{name}   (line at x = {format_number(target.get('x_m', '?'))} m)"

    def _fill(self) -> None:
        self._filling = True
        try:
            targets = self._targets()
            self.list.clear()
            for target in targets:
                self.list.addItem(self.describe(target))
            sel = self.selected
            self.list.setCurrentRow(sel if sel is not None else -1)
            base = f"targets.{sel}" if sel is not None else None
            is_point = base is not None and self.doc.get(f"{base}.point_m") is not None
            self.name.set_path(f"{base}.name" if base else None)
            self.x.set_path(f"{base}.x_m" if base and not is_point else None)
            self.point.set_path(f"{base}.point_m" if is_point else None)
            # the form is the selected target's: its kind, and only the row of that kind
            self.kind.setCurrentText(TARGET_KINDS[1] if is_point else TARGET_KINDS[0])
            self.kind.setEnabled(base is not None)
            self.target_form.setRowVisible(self.x, base is None or not is_point)
            self.target_form.setRowVisible(self.point, base is None or is_point)
            if base is None or is_point:
                self.x.edit.setText("")
            if not is_point:
                for edit in self.point.edits:
                    edit.setText("")
            self.remove_button.setEnabled(base is not None)
        finally:
            self._filling = False

    # -- edits ------------------------------------------------------------------------------------

    def _free_name(self) -> str:
        taken = {t.get("name") for t in self._targets()}
        k = len(taken) + 1
        while f"target-{k}" in taken:
            k += 1
        return f"target-{k}"

    def _add_typed(self) -> None:
        x = parse_number(self.new_x.text())
        point = self.new_kind.currentText() == "point"
        y = parse_number(self.new_y.text()) if point else None
        if x is None or (point and y is None):
            self.show_message("New target: type its x" + (" and y" if point else "") + " in metres")
            return
        self.show_message("")
        self.add_target(x, y)
        # the next target starts from the default again: neither this one's kind nor its y carries over
        self.new_kind.setCurrentText(TARGET_KINDS[0])
        self.new_x.clear()
        self.new_y.clear()

    def set_kind(self, kind: str) -> bool:
        """Make the selected target a vertical line or a point (at the ground at its x, else at
        mid-height of the domain), as one undo step."""
        sel = self.selected
        if sel is None or kind not in TARGET_KINDS:
            return False
        target = dict(self._targets()[sel])
        point = target.get("point_m")
        if (kind == TARGET_KINDS[1]) == isinstance(point, list):
            return False
        if kind == TARGET_KINDS[0]:
            target.pop("point_m", None)
            target["x_m"] = float(point[0])
        else:
            x = float(target.pop("x_m", 0.0))
            outlines = [b.get("polygon_m") or [] for b in (self.doc.get("bodies") or []) if isinstance(b, dict)]
            ground = surface_at(outlines, x)
            if ground is None:
                origin, size = self.doc.get("domain.origin_m", [0.0, 0.0]), self.doc.get("domain.size_m", [1.0, 1.0])
                ground = float(origin[1]) + float(size[1]) / 2.0
            target["point_m"] = [x, float(ground)]

        def mutate(d: dict[str, Any]) -> None:
            d["targets"][sel] = target

        return self.doc.edit(f"make target {target.get('name', sel)} a {kind}", mutate)

    def add_target(self, x_m: float, y_m: float | None = None, name: str | None = None) -> int:
        """Add a vertical line at ``x_m`` (or the point ``(x_m, y_m)``) and select it; its index."""
        target: dict[str, Any] = {"name": name or self._free_name()}
        if y_m is None:
            target["x_m"] = float(x_m)
        else:
            target["point_m"] = [float(x_m), float(y_m)]
        self.doc.edit(f"add target {target['name']}", lambda d: d.setdefault("targets", []).append(target))
        index = len(self._targets()) - 1
        self.doc.selection.select("targets", index)
        return index

    def rename(self, new: str) -> bool:
        """Rename the selected target (the schema checks the name: letters, digits, _ and -)."""
        sel = self.selected
        if sel is None:
            return False
        self.name.edit.setText(new)
        return bool(self.name.commit())

    def remove_target(self) -> None:
        sel = self.selected
        if sel is None:
            return
        name = self._targets()[sel].get("name", sel)

        def mutate(d: dict[str, Any]) -> None:
            d["targets"].pop(sel)
            if not d["targets"]:
                d.pop("targets")

        self.doc.edit(f"remove target {name}", mutate)
        targets = self._targets()
        self.doc.selection.select("targets", min(sel, len(targets) - 1) if targets else None)
