"""The project panels: domain, materials, bodies, numerics, stages and output.

Each panel is a form of bound editors (:mod:`app.gui.fields`) plus lists for the named or
numbered parts of the project. Panels only read the document and push edits to it; they rebuild
what they show when the document's ``changed`` signal names their section.
"""

from __future__ import annotations

import logging
import re
from collections.abc import Sequence
from typing import Any

from PySide6.QtCore import Qt, Signal
from PySide6.QtGui import QBrush, QColor, QIcon, QPixmap
from PySide6.QtWidgets import (
    QAbstractItemView,
    QCheckBox,
    QComboBox,
    QFormLayout,
    QGridLayout,
    QGroupBox,
    QHBoxLayout,
    QHeaderView,
    QInputDialog,
    QLabel,
    QLineEdit,
    QListWidget,
    QListWidgetItem,
    QMenu,
    QPushButton,
    QRadioButton,
    QScrollArea,
    QStyledItemDelegate,
    QTableWidget,
    QTableWidgetItem,
    QToolButton,
    QVBoxLayout,
    QWidget,
)

from app.gui.document import (
    FIELD_INFO,
    INERTIAL_NUMBER_KEYS,
    MATERIAL_KEYS,
    OPTIONAL_MATERIAL_KEYS,
    PLASTIC_KEYS,
    SOFTENING_NUMBER_KEYS,
    ProjectDocument,
    check_value,
    format_number,
    parse_number,
)
from app.gui.fields import (
    ChoiceField,
    IntField,
    NumberField,
    OptionalChoiceField,
    PairField,
    TextField,
    forget_typing,
)
from app.gui.settings import MaterialLibrary
from app.gui.units import parse_quantity
from projects.schema import (
    ARCHS,
    BOUNDARY_TYPES,
    CONTACT_TYPES,
    DEFAULT_GRAVITY_RAMP_FRACTION,
    DAMPING_MODELS,
    DEFAULT_DAMPING_MODEL,
    DEFAULT_MOHR_COULOMB_MATCH,
    FIRST_TRIALS,
    INERTIAL_KEYS,
    MATERIAL_MODELS,
    MOHR_COULOMB_MATCHES,
    OUTPUT_FIELDS,
    PRECISIONS,
    PRESETS,
    RIGID_KEYS,
    SCHEMES,
    SEEDINGS,
    SIDES,
    SOFTENING_LAWS,
    STAGE_TYPES,
)

logger = logging.getLogger(__name__)

#: The material changes of a stage that are words, not numbers, and the words allowed.
WORD_CHANGES: dict[str, tuple[str, ...]] = {"damping_model": DAMPING_MODELS, "softening_law": SOFTENING_LAWS}

#: Material colours by material id; the same palette (matplotlib's tab10) as the results' "material" field.
MATERIAL_COLORS: tuple[str, ...] = (
    "#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd",
    "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf",
)
_NAME = re.compile(r"^[A-Za-z0-9_-]+$")


def material_color(index: int) -> str:
    return MATERIAL_COLORS[index % len(MATERIAL_COLORS)] if index >= 0 else "#b0b0b0"


def swatch(color: str, size: int = 12) -> QIcon:
    pixmap = QPixmap(size, size)
    pixmap.fill(QColor(color))
    return QIcon(pixmap)


def _small_button(text: str, tip: str) -> QToolButton:
    button = QToolButton()
    button.setText(text)
    button.setToolTip(tip)
    button.setAutoRaise(False)
    return button


class Panel(QScrollArea):
    """A scrollable form with a message line for what is wrong with the last typed value."""

    def __init__(self, doc: ProjectDocument, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.doc = doc
        self.setWidgetResizable(True)
        self.setFrameShape(QScrollArea.Shape.NoFrame)
        body = QWidget()
        self.layout_ = QVBoxLayout(body)
        self.layout_.setContentsMargins(6, 6, 6, 6)
        self.setWidget(body)
        self.message = QLabel("")
        self.message.setWordWrap(True)
        self.message.setStyleSheet("color: #b3261e;")
        doc.changed.connect(self._on_changed)

    def finish(self) -> None:
        self.layout_.addWidget(self.message)
        self.layout_.addStretch(1)

    def watch(self, *fields: Any) -> None:
        for field in fields:
            field.message.connect(self.show_message)

    def show_message(self, text: str) -> None:
        self.message.setText(text)

    def _on_changed(self, sections: frozenset) -> None:
        """Rebuild lists; bound fields refresh themselves."""


def _form(title: str) -> tuple[QGroupBox, QFormLayout]:
    box = QGroupBox(title)
    form = QFormLayout(box)
    form.setFieldGrowthPolicy(QFormLayout.FieldGrowthPolicy.AllNonFixedFieldsGrow)
    return box, form


# --------------------------------------------------------------------------------------------
# domain


class DomainPanel(Panel):
    """Title, grid box, cell size, gravity and the four boundaries."""

    def __init__(self, doc: ProjectDocument, parent: QWidget | None = None) -> None:
        super().__init__(doc, parent)
        box, form = _form("Project")
        self.title = TextField(doc, "runout.title", "Title")
        form.addRow("Title", self.title)
        self.layout_.addWidget(box)

        box, form = _form("Background grid")
        self.origin = PairField(doc, "domain.origin_m", "Origin", "m")
        self.size = PairField(doc, "domain.size_m", "Size", "m", names=("w", "h"))
        self.cell = NumberField(doc, "domain.cell_size_m", "Cell size", "m")
        self.grid_info = QLabel("")
        self.grid_info.setStyleSheet("color: #555;")
        form.addRow("Origin", self.origin)
        form.addRow("Size", self.size)
        form.addRow("Cell size", self.cell)
        form.addRow("", self.grid_info)
        self.layout_.addWidget(box)

        box, form = _form("Gravity")
        self.gravity = PairField(doc, "domain.gravity_m_s2", "Gravity", "m/s²", names=("gx", "gy"))
        form.addRow("Acceleration", self.gravity)
        self.layout_.addWidget(box)

        box = QGroupBox("Boundaries")
        grid = QGridLayout(box)
        grid.addWidget(QLabel("Side"), 0, 0)
        grid.addWidget(QLabel("Condition"), 0, 1)
        grid.addWidget(QLabel("Friction angle"), 0, 2)
        self.side_types: dict[str, QComboBox] = {}
        self.side_angles: dict[str, NumberField] = {}
        for row, side in enumerate(SIDES, start=1):
            combo = QComboBox()
            combo.addItems(list(BOUNDARY_TYPES))
            combo.setAccessibleName(f"{side} boundary")
            combo.activated.connect(lambda _i, s=side: self._type_chosen(s))
            angle = NumberField(doc, None, f"{side} friction angle", "°")
            grid.addWidget(QLabel(side), row, 0)
            grid.addWidget(combo, row, 1)
            grid.addWidget(angle, row, 2)
            self.side_types[side] = combo
            self.side_angles[side] = angle
        self.layout_.addWidget(box)
        self.watch(self.title, self.origin, self.size, self.cell, self.gravity, *self.side_angles.values())
        self.finish()
        self._on_changed(frozenset({"domain"}))

    def _boundary(self, side: str) -> Any:
        return self.doc.get(f"domain.boundaries.{side}", "slip")

    def _type_chosen(self, side: str) -> None:
        kind = self.side_types[side].currentText()
        old = self._boundary(side)
        old_kind = old.get("type") if isinstance(old, dict) else old
        if kind == old_kind:
            return
        if kind == "friction":
            # start from the friction angle of the first frictional material, else 20 degrees
            materials = self.doc.get("materials") or {}
            start = next((m.get("friction_angle_deg") for m in materials.values()
                          if isinstance(m, dict) and m.get("friction_angle_deg") is not None), 20.0)
            value: Any = {"type": "friction", "friction_angle_deg": start}
        else:
            value = kind
        self.doc.set_value(f"domain.boundaries.{side}", value, f"set {side} boundary to {kind}")

    def set_boundary(self, side: str, kind: str) -> None:
        """Choose a boundary type as a user would."""
        self.side_types[side].setCurrentText(kind)
        self._type_chosen(side)

    def _on_changed(self, sections: frozenset) -> None:
        if "domain" not in sections:
            return
        for side in SIDES:
            boundary = self._boundary(side)
            kind = boundary.get("type", "slip") if isinstance(boundary, dict) else str(boundary)
            self.side_types[side].setCurrentText(kind)
            friction = kind == "friction"
            self.side_angles[side].set_path(f"domain.boundaries.{side}.friction_angle_deg" if friction else None)
        size = self.doc.get("domain.size_m")
        cell = self.doc.get("domain.cell_size_m")
        try:
            nx, ny = (max(1, round(float(s) / float(cell))) for s in size)
            self.grid_info.setText(f"{nx} × {ny} = {nx * ny:,} cells")
        except (TypeError, ValueError, ZeroDivisionError):
            self.grid_info.setText("")


# --------------------------------------------------------------------------------------------
# materials


def _show_row(widget: QWidget, visible: bool) -> None:
    """Show or hide a form row: the field and its label."""
    widget.setVisible(visible)
    layout = widget.parentWidget().layout() if widget.parentWidget() is not None else None
    if isinstance(layout, QFormLayout):
        label = layout.labelForField(widget)
        if label is not None:
            label.setVisible(visible)


class MaterialsPanel(Panel):
    """The materials (their order is their id), one form for the selected one, and the library."""

    def __init__(self, doc: ProjectDocument, library: MaterialLibrary, parent: QWidget | None = None) -> None:
        super().__init__(doc, parent)
        self.library = library
        self.list = QListWidget()
        self.list.setMaximumHeight(120)
        self.list.currentRowChanged.connect(self._select)
        self.layout_.addWidget(self.list)

        buttons = QHBoxLayout()
        self.add_button = QPushButton("Add")
        self.add_button.clicked.connect(self.add_material)
        self.copy_button = QPushButton("Duplicate")
        self.copy_button.clicked.connect(self.duplicate_material)
        self.remove_button = QPushButton("Remove")
        self.remove_button.clicked.connect(self.remove_material)
        self.library_button = QPushButton("Library")
        self.library_menu = QMenu(self.library_button)
        self.library_menu.aboutToShow.connect(self._fill_library_menu)
        self.library_button.setMenu(self.library_menu)
        for b in (self.add_button, self.copy_button, self.remove_button, self.library_button):
            buttons.addWidget(b)
        self.layout_.addLayout(buttons)

        box, form = _form("Selected material")
        self.name = QLineEdit()
        self.name.setAccessibleName("Material name")
        self.name.editingFinished.connect(self._rename)
        self.model = ChoiceField(doc, None, "Model", MATERIAL_MODELS)
        self.model.combo.activated.disconnect()
        self.model.combo.activated.connect(self._model_chosen)
        form.addRow("Name", self.name)
        form.addRow("Model", self.model)
        self.fields: dict[str, NumberField] = {}
        for key in MATERIAL_KEYS:
            label, unit = FIELD_INFO[key]
            optional = key in OPTIONAL_MATERIAL_KEYS
            field = NumberField(doc, None, label, unit, optional=optional,
                                placeholder=OPTIONAL_MATERIAL_KEYS.get(key, ""))
            self.fields[key] = field
            form.addRow(label, field)
            self.watch(field)
        self.fields["damping_ratio"].setToolTip(
            "Material damping: the fraction of critical damping at the damping frequency; rigid motion is "
            "not damped. Empty: undamped (the paper's model). See the damping model for how it varies with "
            "frequency and what it costs (docs/solver.md, material damping)")
        self.fields["damping_frequency_hz"].setToolTip(
            "The frequency the damping ratio holds at, usually the body's first mode: c_s / (4 H) for a "
            "block or layer of depth H on its base, c_s = sqrt(G / density)")
        self.damping_model = ChoiceField(doc, None, "Damping model", DAMPING_MODELS, default=DEFAULT_DAMPING_MODEL)
        self.damping_model.setToolTip(
            "rayleigh: stiffness-proportional, the damping grows with frequency and the time step shrinks "
            "with it (many times for thick bodies); maxwell: a spring and dashpot in series, the damping "
            "peaks at the damping frequency and the step is about 1.2 times shorter at 10 %, the material a "
            "little stiffer above that frequency. It acts once a damping ratio is given")
        form.addRow("Damping model", self.damping_model)
        # which Drucker-Prager cone stands for the Mohr-Coulomb c and phi (docs/solver.md)
        self.match = ChoiceField(doc, None, "Mohr-Coulomb match", MOHR_COULOMB_MATCHES,
                                 default=DEFAULT_MOHR_COULOMB_MATCH)
        self.match.setToolTip("plane-strain-associated: the paper's fit (default); plane-strain: Mohr-Coulomb's "
                              "plane-strain strength under the material's own flow rule; simple-shear: the "
                              "strength on a shear plane (infinite slopes, psi = 0)")
        form.addRow("Mohr-Coulomb match", self.match)
        # strain softening (Drucker-Prager): the law, then its residual values, strains and length
        self.softening_law = OptionalChoiceField(doc, None, "Softening law", SOFTENING_LAWS,
                                                 on_none=self._remove_softening)
        self.softening_law.setToolTip(
            "Strain softening: cohesion, friction and dilatancy fall from their peak values above to the "
            "residual ones as the plastic strain grows (a sensitive or stiff clay). linear: from the peak "
            "plastic strain to the residual one; exponential: 95 % of the drop at the residual strain. "
            "none removes the softening keys (docs/project-format.md, strain softening)")
        form.addRow("Softening law", self.softening_law)
        self._optional_number_rows(doc, form, SOFTENING_NUMBER_KEYS)
        self.fields["residual_cohesion_pa"].setToolTip(
            "The remoulded (residual) cohesion; empty: the cohesion does not soften. At most the cohesion")
        self.fields["residual_plastic_strain"].setToolTip(
            "The plastic strain at which the strength has fallen to its residual values (required with a law)")
        self.fields["softening_length_m"].setToolTip(
            "The thickness of the shear band the strains are measured over: the strength is then lost over "
            "the same slip at every cell size. Empty: the particles' own strains, and the failure and run-out "
            "depend on the cell size (runout validate warns). Give at least the cell size")
        self.layout_.addWidget(box)
        # rate-dependent friction (Drucker-Prager): the mu(I) law's rise, I0 and the grains
        self.inertial_box, form = _form("Rate-dependent friction (mu(I))")
        self.inertial_box.setToolTip(
            "The mu(I) law of dense granular flow: mu(I) = tan(friction angle) + Δμ I / (I₀ + I), "
            "I = shear rate × d / sqrt(p / grain density). Empty friction increase: rate-independent. "
            "Not with a softening law (docs/project-format.md, rate-dependent friction)")
        self._optional_number_rows(doc, form, INERTIAL_NUMBER_KEYS)
        self.fields["mu_i_friction_increase"].setToolTip(
            "mu_2 - mu_s: how far the friction coefficient rises over tan(friction angle) at high rates "
            "(0.26 for glass beads, Jop et al. 2006). Empty: the friction does not depend on the rate")
        self.fields["mu_i_reference_number"].setToolTip(
            "The inertial number I₀ at which half the rise is reached (0.279 for glass beads)")
        self.fields["grain_diameter_m"].setToolTip("The grain diameter d of the inertial number")
        self.fields["grain_density_kg_m3"].setToolTip(
            "The grains' density of the inertial number; empty: the material's density")
        self.layout_.addWidget(self.inertial_box)
        # a rigid body (a platen, a gate): its velocity in dynamic stages and its contact
        self.rigid_box, form = _form("Rigid body (model rigid)")
        self.rigid_box.setToolTip(
            "A rigid body moves at its velocity in dynamic stages and stands still in initial-stress "
            "stages; it carries no stress and no weight. Its reaction is a contact force named after the "
            "material (docs/project-format.md, rigid bodies)")
        self.velocity = PairField(doc, None, "Velocity", "m/s", names=("vx", "vy"))
        self.velocity.setToolTip("The body's velocity in dynamic stages (a stage may change it)")
        self.contact = ChoiceField(doc, None, "Contact", CONTACT_TYPES, default="fixed")
        self.contact.combo.activated.disconnect()
        self.contact.combo.activated.connect(self._contact_chosen)
        self.contact.setToolTip("fixed: the material sticks to the body (a rough platen); slip: it slides "
                                "along it without friction; friction: Coulomb friction (its angle is "
                                "friction_angle_deg of the contact in the file, 20 degrees when chosen here)")
        form.addRow("Velocity", self.velocity)
        form.addRow("Contact", self.contact)
        self.watch(self.velocity, self.contact)
        self.layout_.addWidget(self.rigid_box)
        self.used_by = QLabel("")
        self.used_by.setWordWrap(True)
        self.used_by.setStyleSheet("color: #555;")
        self.layout_.addWidget(self.used_by)
        self.finish()
        self._current: str | None = None
        self._on_changed(frozenset({"materials"}))

    def _optional_number_rows(self, doc: ProjectDocument, form: Any, keys: Sequence[str]) -> None:
        """An optional number field per material key, with its label, unit and empty-field
        placeholder (document.FIELD_INFO, OPTIONAL_MATERIAL_KEYS), added to ``form``."""
        for key in keys:
            label, unit = FIELD_INFO[key]
            field = NumberField(doc, None, label, unit, optional=True, placeholder=OPTIONAL_MATERIAL_KEYS.get(key, ""))
            self.fields[key] = field
            form.addRow(label, field)
            self.watch(field)

    # -- list ---------------------------------------------------------------------------------

    @property
    def current(self) -> str | None:
        return self._current

    def select(self, name: str) -> None:
        names = self.doc.material_names
        if name in names:
            self.list.setCurrentRow(names.index(name))

    def _select(self, row: int) -> None:
        names = self.doc.material_names
        self._current = names[row] if 0 <= row < len(names) else None
        self._bind()

    def _bind(self) -> None:
        name = self._current
        base = f"materials.{name}" if name is not None else None
        self.name.setText(name or "")
        self.name.setEnabled(name is not None)
        self.model.set_path(f"{base}.model" if base else None)
        plastic = base is not None and self.doc.get(f"{base}.model") == "drucker-prager"
        rigid = base is not None and self.doc.get(f"{base}.model") == "rigid"
        softens = plastic and self.doc.get(f"{base}.softening_law") is not None
        for key, field in self.fields.items():
            enabled = base is not None and (plastic or key not in PLASTIC_KEYS) and (
                softens or key not in SOFTENING_NUMBER_KEYS) and (not rigid or key in RIGID_KEYS)
            field.set_path(f"{base}.{key}" if enabled else None)
            if not enabled:
                field.edit.setText("")
                field.edit.setPlaceholderText("—" if base else "")
        self.match.set_path(f"{base}.mohr_coulomb_match" if plastic else None)
        self.softening_law.set_path(f"{base}.softening_law" if plastic else None)
        self.damping_model.set_path(f"{base}.damping_model" if base and not rigid else None)
        self.velocity.set_path(f"{base}.velocity_m_s" if rigid else None)
        self.contact.set_path(f"{base}.contact.type" if rigid else None)
        self.rigid_box.setVisible(rigid)
        # a rigid body has no stiffness, strength or damping: its rows go, so that its own group
        # (velocity, contact) sits under its density instead of below twenty empty fields
        soil_rows = [w for k, w in self.fields.items() if k not in RIGID_KEYS]
        for widget in (*soil_rows, self.damping_model, self.match, self.softening_law):
            _show_row(widget, not rigid)
        self.inertial_box.setVisible(not rigid)
        if name is not None:
            users = [b.get("name", "?") for b in self.doc.get("bodies", []) if b.get("material") == name]
            self.used_by.setText("Used by: " + (", ".join(users) if users else "no body"))
        else:
            self.used_by.setText("")

    def _on_changed(self, sections: frozenset) -> None:
        if not sections & {"materials", "bodies"}:
            return
        names = self.doc.material_names
        self.list.blockSignals(True)
        self.list.clear()
        for i, name in enumerate(names):
            model = self.doc.get(f"materials.{name}.model", "?")
            item = QListWidgetItem(swatch(material_color(i)), f"{name}   ({model})")
            self.list.addItem(item)
        if self._current not in names:
            self._current = names[0] if names else None
        if self._current is not None:
            self.list.setCurrentRow(names.index(self._current))
        self.list.blockSignals(False)
        self._bind()

    # -- edits --------------------------------------------------------------------------------

    def _free_name(self, base: str) -> str:
        names = set(self.doc.material_names)
        if base not in names:
            return base
        i = 2
        while f"{base}-{i}" in names:
            i += 1
        return f"{base}-{i}"

    def add_material(self, material: dict[str, Any] | None = None, name: str = "material") -> str:
        """Append a material (a copy of the selected one's model defaults) and select it."""
        name = self._free_name(name)
        table = dict(material) if material else {
            "model": "drucker-prager", "density_kg_m3": 2000.0, "youngs_modulus_pa": 1.0e7,
            "poisson_ratio": 0.3, "cohesion_pa": 0.0, "friction_angle_deg": 30.0, "dilatancy_angle_deg": 0.0,
        }
        self.doc.edit(f"add material {name}", lambda d: d.setdefault("materials", {}).__setitem__(name, table))
        self._current = name
        self._on_changed(frozenset({"materials"}))
        return name

    def duplicate_material(self) -> None:
        if self._current is not None:
            self.add_material(dict(self.doc.get(f"materials.{self._current}")), self._current)

    def remove_material(self) -> None:
        name = self._current
        if name is None:
            return
        users = [b.get("name", "?") for b in self.doc.get("bodies", []) if b.get("material") == name]
        if users:
            self.show_message(f"{name} is used by {', '.join(users)}: give them another material first")
            return

        def mutate(d: dict[str, Any]) -> None:
            d["materials"].pop(name, None)
            for stage in d.get("stages", []):
                changes = stage.get("material_changes")
                if isinstance(changes, dict):
                    changes.pop(name, None)
                    if not changes:
                        stage.pop("material_changes")

        self.doc.edit(f"remove material {name}", mutate)

    def _rename(self) -> None:
        old, new = self._current, self.name.text().strip()
        if old is None or new == old:
            forget_typing(self.name)
            return
        if not _NAME.match(new):
            self.show_message("Material names may only use letters, digits, _ and -")
            self.name.setText(old)
            return
        if new in self.doc.material_names:
            self.show_message(f"There is already a material named {new}")
            self.name.setText(old)
            return
        self._current = new
        self.doc.rename_material(old, new)
        forget_typing(self.name)  # the rename is the project's undo step now

    def rename(self, new: str) -> None:
        self.name.setText(new)
        self._rename()

    def _contact_chosen(self, _index: int) -> None:
        """A rigid body's contact: the whole table, so that a friction angle goes with its type."""
        name, kind = self._current, self.contact.combo.currentText()
        path = f"materials.{name}.contact"
        current = self.doc.get(path) or {}
        if name is None or current.get("type") == kind:
            return
        table = {"type": kind}
        if kind == "friction":
            table["friction_angle_deg"] = current.get("friction_angle_deg", 20.0)
        self.doc.set_value(path, table, f"change the contact of {name}")

    def _model_chosen(self, _index: int) -> None:
        self.set_model(self.model.combo.currentText())

    def set_model(self, model: str) -> None:
        """Change the selected material's model; Drucker-Prager gets default strength values."""
        name = self._current
        if name is None or self.doc.get(f"materials.{name}.model") == model:
            return

        def mutate(d: dict[str, Any]) -> None:
            table = d["materials"][name]
            was_rigid = table.get("model") == "rigid"
            table["model"] = model
            if model == "rigid":  # a body moved at its velocity: density, velocity and contact alone
                for key in [k for k in table if k not in RIGID_KEYS]:
                    table.pop(key)
                table.setdefault("velocity_m_s", [0.0, 0.0])
                table.setdefault("contact", {"type": "fixed"})
                for stage in d.get("stages", []):
                    change = stage.get("material_changes", {}).get(name)
                    if isinstance(change, dict):
                        for key in [k for k in change if k != "velocity_m_s"]:
                            change.pop(key)
                return
            if was_rigid:
                for key in ("velocity_m_s", "contact"):
                    table.pop(key, None)
                table.setdefault("youngs_modulus_pa", 1.0e7)
                table.setdefault("poisson_ratio", 0.3)
                for stage in d.get("stages", []):
                    change = stage.get("material_changes", {}).get(name)
                    if isinstance(change, dict):
                        change.pop("velocity_m_s", None)
            if model == "linear-elastic":
                for key in (*PLASTIC_KEYS, "mohr_coulomb_match", "softening_law", *INERTIAL_KEYS):
                    table.pop(key, None)
                for stage in d.get("stages", []):
                    change = stage.get("material_changes", {}).get(name)
                    if isinstance(change, dict):
                        for key in (*PLASTIC_KEYS, "softening_law"):
                            change.pop(key, None)
            else:
                table.setdefault("cohesion_pa", 0.0)
                table.setdefault("friction_angle_deg", 30.0)
                table.setdefault("dilatancy_angle_deg", 0.0)

        self.doc.edit(f"make {name} {model}", mutate)

    def set_softening_law(self, law: str) -> None:
        """Choose the selected material's softening law as a user would (``"none"`` removes it)."""
        self.softening_law.choose(law)

    def _remove_softening(self) -> None:
        """No softening: the law and the keys that go with it leave the material, one undo step."""
        name = self._current
        if name is None:
            return

        def mutate(d: dict[str, Any]) -> None:
            table = d["materials"][name]
            for key in ("softening_law", *SOFTENING_NUMBER_KEYS):
                table.pop(key, None)

        self.doc.edit(f"remove the softening of {name}", mutate)

    # -- library ------------------------------------------------------------------------------

    def _fill_library_menu(self) -> None:
        menu = self.library_menu
        menu.clear()
        save = menu.addAction("Save selected to library…")
        save.setEnabled(self._current is not None)
        save.triggered.connect(self.save_to_library)
        menu.addSeparator()
        names = self.library.names()
        if not names:
            empty = menu.addAction("(library is empty)")
            empty.setEnabled(False)
        for name in names:
            action = menu.addAction(f"Insert {name}")
            action.triggered.connect(lambda _c=False, n=name: self.insert_from_library(n))
        if names:
            menu.addSeparator()
            forget = menu.addMenu("Remove from library")
            for name in names:
                action = forget.addAction(name)
                action.triggered.connect(lambda _c=False, n=name: self.library.remove(n))

    def save_to_library(self, name: str | None = None) -> None:
        if self._current is None:
            return
        if name is None:
            name, ok = QInputDialog.getText(self, "Save to library", "Library name:", text=self._current)
            if not ok or not name.strip():
                return
        self.library.put(name.strip(), dict(self.doc.get(f"materials.{self._current}")))
        self.show_message(f"Saved {self._current} to the library as {name.strip()} ({self.library.path})")

    def insert_from_library(self, name: str) -> str:
        """Add the library material ``name`` to the project (renamed if the name is taken)."""
        safe = re.sub(r"[^A-Za-z0-9_-]+", "-", name).strip("-") or "material"
        return self.add_material(self.library.get(name), safe)


# --------------------------------------------------------------------------------------------
# bodies


class _NumberDelegate(QStyledItemDelegate):
    """Cell editor that shows typed text in red until it is a number."""

    def createEditor(self, parent: QWidget, option: Any, index: Any) -> QWidget:  # noqa: N802
        editor = QLineEdit(parent)
        editor.setAlignment(Qt.AlignmentFlag.AlignRight)
        editor.textEdited.connect(
            lambda text, e=editor: e.setStyleSheet("" if parse_number(text) is not None else "background: #fde2e1;")
        )
        return editor


class PolygonPanel(Panel):
    """A list of polygons of one kind (``bodies`` or ``structures``), the selected one's form and
    its vertex table, bound to the document's selection.

    Subclasses set :attr:`KIND` and :attr:`NOUN`, add their buttons in :meth:`_buttons` and their
    fields in :meth:`_form_rows`, and bind them in :meth:`_bind_item`.

    Signals
    -------
    drawRequested()
        The user wants to draw a new polygon of this kind in the scene view.
    """

    KIND = "bodies"
    NOUN = "body"
    drawRequested = Signal()

    def __init__(self, doc: ProjectDocument, parent: QWidget | None = None) -> None:
        super().__init__(doc, parent)
        self.list = QListWidget()
        self.list.setMaximumHeight(130)
        self.list.currentRowChanged.connect(self._row_chosen)
        self.layout_.addWidget(self.list)

        buttons = QHBoxLayout()
        self.draw_button = QPushButton("Draw…")
        self.draw_button.setToolTip(
            f"Draw a new {self.NOUN} in the view: click vertices, click the first one (or Enter) to close")
        self.draw_button.clicked.connect(self.drawRequested)
        self.delete_button = QPushButton("Delete")
        self.delete_button.clicked.connect(self.delete_item)
        for b in (self.draw_button, *self._buttons(), self.delete_button, *self._order_buttons()):
            buttons.addWidget(b)
        self.layout_.addLayout(buttons)

        box, form = _form(f"Selected {self.NOUN}")
        self.name = TextField(doc, None, f"{self.NOUN.capitalize()} name", taken=self._names_of_others)
        form.addRow("Name", self.name)
        self._form_rows(form)
        self.layout_.addWidget(box)

        box = QGroupBox("Vertices")
        vbox = QVBoxLayout(box)
        self.table = QTableWidget(0, 2)
        self.table.setHorizontalHeaderLabels(["x (m)", "y (m)"])
        self.table.horizontalHeader().setSectionResizeMode(QHeaderView.ResizeMode.Stretch)
        self.table.setSelectionBehavior(QAbstractItemView.SelectionBehavior.SelectRows)
        self.table.setSelectionMode(QAbstractItemView.SelectionMode.SingleSelection)
        self.table.setItemDelegate(_NumberDelegate(self.table))
        self.table.setMinimumHeight(160)
        self.table.itemChanged.connect(self._cell_edited)
        self.table.currentCellChanged.connect(self._vertex_chosen)
        vbox.addWidget(self.table)
        row = QHBoxLayout()
        self.insert_button = QPushButton("Insert vertex")
        self.insert_button.setToolTip("Split the edge after the selected vertex at its midpoint")
        self.insert_button.clicked.connect(self.insert_vertex)
        self.remove_vertex_button = QPushButton("Delete vertex")
        self.remove_vertex_button.clicked.connect(self.delete_vertex)
        row.addWidget(self.insert_button)
        row.addWidget(self.remove_vertex_button)
        vbox.addLayout(row)
        self.layout_.addWidget(box)
        self.shape_status = QLabel("")
        self.shape_status.setWordWrap(True)
        self.layout_.addWidget(self.shape_status)
        self.watch(self.name)
        self.finish()
        doc.selection.changed.connect(self._selection_changed)
        self._filling = False
        self._on_changed(frozenset({self.KIND}))

    # -- hooks for the kinds --------------------------------------------------------------------

    def _buttons(self) -> list[QWidget]:
        return []

    def _order_buttons(self) -> list[QWidget]:
        return []

    def _form_rows(self, form: QFormLayout) -> None:
        """Add the kind's fields below the name."""

    def _bind_item(self, base: str | None) -> None:
        """Point the kind's fields at ``base`` (``"bodies.2"``; None: nothing selected)."""

    def _label(self, item: dict[str, Any]) -> tuple[QIcon | None, str]:
        return None, str(item.get("name", "?"))

    # -- sync ---------------------------------------------------------------------------------

    @property
    def selected(self) -> int | None:
        """The selected item of this panel's kind, or None."""
        sel = self.doc.selection
        return sel.index if sel.kind == self.KIND else None

    def _items(self) -> list[dict[str, Any]]:
        items = self.doc.get(self.KIND, [])
        return items if isinstance(items, list) else []

    def _names_of_others(self) -> dict[str, str]:
        """The names the other items have (name -> ``KIND.index``): the selected item may not take one."""
        return {item.get("name"): f"{self.KIND}.{i}" for i, item in enumerate(self._items())
                if i != self.selected and isinstance(item, dict) and isinstance(item.get("name"), str)}

    def _row_chosen(self, row: int) -> None:
        if not self._filling:
            if row >= 0:
                self.doc.selection.select(self.KIND, row)
            elif self.selected is not None:
                self.doc.selection.select(self.KIND, None)

    def _vertex_chosen(self, row: int, _col: int, _prow: int, _pcol: int) -> None:
        if not self._filling and self.selected is not None:
            self.doc.selection.select(self.KIND, self.selected, row if row >= 0 else None)

    def _selection_changed(self) -> None:
        self._fill()

    def _on_changed(self, sections: frozenset) -> None:
        if sections & {self.KIND, "materials", "domain"}:
            self._fill()

    def _fill(self) -> None:
        self._filling = True
        try:
            items = self._items()
            self.list.clear()
            for item in items:
                icon, text = self._label(item)
                self.list.addItem(QListWidgetItem(icon, text) if icon is not None else QListWidgetItem(text))
            sel = self.selected
            self.list.setCurrentRow(sel if sel is not None else -1)
            base = f"{self.KIND}.{sel}" if sel is not None else None
            self.name.set_path(f"{base}.name" if base else None)
            self._bind_item(base)
            polygon = self.doc.get(f"{base}.polygon_m", []) if base else []
            polygon = polygon if isinstance(polygon, list) else []
            self.table.setRowCount(len(polygon))
            for i, point in enumerate(polygon):
                for j in range(2):
                    cell = QTableWidgetItem(format_number(point[j]))
                    cell.setTextAlignment(Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignVCenter)
                    self.table.setItem(i, j, cell)
            self._flag_vertices(sel)
            vertex = self.doc.selection.vertex if sel is not None else None
            if vertex is not None and vertex < len(polygon):
                self.table.setCurrentCell(vertex, 0)
            else:
                self.table.clearSelection()
            for b in (self.delete_button, *self._order_buttons(), self.insert_button, self.remove_vertex_button):
                b.setEnabled(sel is not None)
        finally:
            self._filling = False

    def _flag_vertices(self, sel: int | None) -> None:
        """Colour the rows of vertices that a problem names; say what is wrong with the shape."""
        if sel is None:
            self.shape_status.setText("")
            return
        problems = self.doc.problems_at(f"{self.KIND}.{sel}")
        bad_rows = set()
        for p in problems:
            parts = p.path.split(".")
            if len(parts) >= 4 and parts[2] == "polygon_m" and parts[3].isdigit():
                bad_rows.add(int(parts[3]))
        for row in bad_rows:
            for j in range(2):
                item = self.table.item(row, j)
                if item is not None:
                    item.setBackground(QBrush(QColor("#fde2e1")))
        self.shape_status.setText("\n".join(str(p) for p in problems))
        self.shape_status.setStyleSheet("color: #b3261e;" if problems else "")

    def _cell_edited(self, item: QTableWidgetItem) -> None:
        sel = self.selected
        if self._filling or sel is None:
            return
        value = parse_number(item.text())
        row, col = item.row(), item.column()
        if value is None:
            self.show_message(f"vertex {row + 1}: {'x' if col == 0 else 'y'} must be a number")  # the table's row
            self._fill()
            return
        self.set_vertex(sel, row, col, value)

    # -- edits --------------------------------------------------------------------------------

    def free_name(self, base: str) -> str:
        """``base-N`` with the first N no item of this kind is named."""
        taken = {item.get("name") for item in self._items()}
        k = len(self._items()) + 1
        while f"{base}-{k}" in taken:
            k += 1
        return f"{base}-{k}"

    def set_vertex(self, index: int, row: int, col: int, value: float) -> None:
        kind = self.KIND

        def mutate(d: dict[str, Any]) -> None:
            d[kind][index]["polygon_m"][row][col] = float(value)

        # numbered as the table's rows (1, 2, ...), not by the list index
        self.doc.edit(f"move vertex {row + 1} of {self._items()[index].get('name', index)}", mutate)

    def delete_item(self) -> None:
        sel, kind = self.selected, self.KIND
        if sel is None:
            return
        name = self._items()[sel].get("name", sel)

        def mutate(d: dict[str, Any]) -> None:
            d[kind].pop(sel)
            if not d[kind] and kind != "bodies":
                d.pop(kind)  # an optional list: no empty table left in the file

        self.doc.edit(f"delete {self.NOUN} {name}", mutate)
        items = self._items()
        self.doc.selection.select(kind, min(sel, len(items) - 1) if items else None)

    def insert_vertex(self) -> None:
        sel, kind = self.selected, self.KIND
        if sel is None:
            return
        vertex = self.doc.selection.vertex
        polygon = self._items()[sel].get("polygon_m", [])
        if len(polygon) < 2:
            return
        i = vertex if vertex is not None else len(polygon) - 1
        a, b = polygon[i], polygon[(i + 1) % len(polygon)]
        mid = [(a[0] + b[0]) / 2.0, (a[1] + b[1]) / 2.0]
        self.doc.edit("insert vertex", lambda d: d[kind][sel]["polygon_m"].insert(i + 1, mid))
        self.doc.selection.select(kind, sel, i + 1)

    def delete_vertex(self) -> None:
        sel, kind, vertex = self.selected, self.KIND, self.doc.selection.vertex
        if sel is None or vertex is None:
            return
        self.doc.edit("delete vertex", lambda d: d[kind][sel]["polygon_m"].pop(vertex))


class BodiesPanel(PolygonPanel):
    """Bodies in painting order (overlaps go to the later body), the selected body's form and vertices.

    Signals
    -------
    drawRequested()
        The user wants to draw a new body in the scene view.
    templateRequested()
        The user wants the slope-from-template dialog.
    """

    KIND = "bodies"
    NOUN = "body"
    templateRequested = Signal()

    def _buttons(self) -> list[QWidget]:
        self.template_button = QPushButton("Slope…")
        self.template_button.setToolTip("Bodies of a slope from a template (height, angle, layers)")
        self.template_button.clicked.connect(self.templateRequested)
        return [self.template_button]

    def _order_buttons(self) -> list[QWidget]:
        if not hasattr(self, "up_button"):
            self.up_button = _small_button("▲", "Paint earlier (overlaps go to the later body)")
            self.up_button.clicked.connect(lambda: self.move_body(-1))
            self.down_button = _small_button("▼", "Paint later")
            self.down_button.clicked.connect(lambda: self.move_body(1))
        return [self.up_button, self.down_button]

    def _form_rows(self, form: QFormLayout) -> None:
        self.material = QComboBox()
        self.material.setAccessibleName("Body material")
        self.material.activated.connect(self._material_chosen)
        self.velocity = PairField(self.doc, None, "Initial velocity", "m/s", names=("vx", "vy"))
        form.addRow("Material", self.material)
        form.addRow("Initial velocity", self.velocity)
        self.watch(self.velocity)

    def _label(self, item: dict[str, Any]) -> tuple[QIcon | None, str]:
        names = self.doc.material_names
        mat = item.get("material", "?")
        index = names.index(mat) if mat in names else -1
        return swatch(material_color(index)), f"{item.get('name', '?')}   ({mat})"

    def _bind_item(self, base: str | None) -> None:
        self.velocity.set_path(f"{base}.initial_velocity_m_s" if base else None)
        if base is not None and self.doc.get(f"{base}.initial_velocity_m_s") is None:
            for edit in self.velocity.edits:
                edit.setText("0")
        self.material.clear()
        self.material.addItems(self.doc.material_names)
        self.material.setEnabled(base is not None)
        if base is not None:
            self.material.setCurrentText(str(self.doc.get(f"{base}.material", "")))

    def _bodies(self) -> list[dict[str, Any]]:
        return self._items()

    def _material_chosen(self, _index: int) -> None:
        sel = self.doc.selection.body
        if sel is not None:
            self.doc.set_value(f"bodies.{sel}.material", self.material.currentText(), "change body material")

    def set_material(self, name: str) -> None:
        self.material.setCurrentText(name)
        self._material_chosen(self.material.currentIndex())

    def delete_body(self) -> None:
        self.delete_item()

    def move_body(self, step: int) -> None:
        sel = self.doc.selection.body
        bodies = self._bodies()
        if sel is None or not 0 <= sel + step < len(bodies):
            return

        def mutate(d: dict[str, Any]) -> None:
            items = d["bodies"]
            items[sel], items[sel + step] = items[sel + step], items[sel]

        self.doc.edit("reorder bodies", mutate)
        self.doc.selection.set(sel + step)


# --------------------------------------------------------------------------------------------
# numerics (with particles)


class NumericsPanel(Panel):
    """Particles per cell and seeding; scheme, time step or CFL, precision and device."""

    def __init__(self, doc: ProjectDocument, parent: QWidget | None = None) -> None:
        super().__init__(doc, parent)
        box, form = _form("Particles")
        self.per_cell = IntField(doc, "particles.per_cell", "Particles per cell", 1, 8, 2, " per direction")
        self.per_cell_info = QLabel("")
        self.per_cell_info.setStyleSheet("color: #555;")
        self.seeding = ChoiceField(doc, "particles.seeding", "Seeding", SEEDINGS, default="lattice")
        form.addRow("Per cell", self.per_cell)
        form.addRow("", self.per_cell_info)
        form.addRow("Seeding", self.seeding)
        self.layout_.addWidget(box)

        box, form = _form("Speed and accuracy")
        self.preset = QComboBox()
        self.preset.addItems(["custom (no preset)", *PRESETS])
        self.preset.setAccessibleName("Preset")
        self.preset.activated.connect(self._preset_chosen)
        self.preset_info = QLabel("")
        self.preset_info.setWordWrap(True)
        self.preset_info.setStyleSheet("color: #555;")
        form.addRow("Preset", self.preset)
        form.addRow("", self.preset_info)
        self.layout_.addWidget(box)

        box, form = _form("Time integration")
        self.scheme = ChoiceField(doc, "numerics.scheme", "Scheme", SCHEMES, default="apic-affine")
        form.addRow("Scheme", self.scheme)
        self.use_cfl = QRadioButton("CFL number (fraction of the critical step)")
        self.use_dt = QRadioButton("Fixed time step")
        self.use_cfl.toggled.connect(self._mode_chosen)
        form.addRow(self.use_cfl)
        self.cfl = NumberField(doc, "numerics.cfl", "CFL number", "–")
        form.addRow("CFL", self.cfl)
        form.addRow(self.use_dt)
        self.dt = NumberField(doc, "numerics.time_step_s", "Time step", "s")
        form.addRow("Time step", self.dt)
        self.layout_.addWidget(box)

        box, form = _form("Computation")
        self.precision = ChoiceField(doc, "numerics.precision", "Precision", PRECISIONS, default="f32")
        self.arch = ChoiceField(doc, "numerics.arch", "Device", ARCHS, default="auto")
        form.addRow("Precision", self.precision)
        form.addRow("Device", self.arch)
        self.layout_.addWidget(box)
        self.watch(self.cfl, self.dt)
        self.finish()
        self._on_changed(frozenset({"numerics", "particles"}))

    def _preset_chosen(self, index: int) -> None:
        name = None if index == 0 else PRESETS[index - 1]
        if name == self.doc.get("numerics.preset"):
            return

        def change(d: dict) -> None:
            if name is None:
                d["numerics"].pop("preset", None)
            else:  # a preset brings its own cfl
                d["numerics"]["preset"] = name
                d["numerics"].pop("time_step_s", None)
                d["numerics"].setdefault("cfl", 0.5)

        self.doc.edit("use no preset" if name is None else f"use the {name} preset", change)

    def _preset_text(self, name: str | None) -> str:
        if name is None:
            return "Cell size, particles per cell, scheme and time step as set below."
        from projects.presets import load_presets
        from projects.schema import ProjectError

        try:
            preset = load_presets()["presets"].get(name)
        except ProjectError as exc:
            return str(exc)
        if not preset:
            return f"{name}: no measured setting"
        measured = preset.get("measured", {})
        cost = measured.get("relative_wall_time")
        return (f"{preset['scheme']}, {preset['per_cell']}x{preset['per_cell']} particles per cell, cfl {preset['cfl']:g}, "
                f"{preset['cells_per_height']:g} cells over the smallest body's height; measured deposit error "
                f"{measured.get('rms_vs_ref_mm', float('nan')):.1f} mm RMS against the finest run"
                + (f", {cost:.2g}x the cost of 'standard'" if cost else "")
                + ". These override the values below.")

    def _mode_chosen(self, cfl: bool) -> None:
        has_dt = self.doc.get("numerics.time_step_s") is not None
        if cfl and has_dt:
            self.doc.edit("use a CFL number", lambda d: (d["numerics"].pop("time_step_s", None),
                                                        d["numerics"].__setitem__("cfl", 0.5)))
        elif not cfl and not has_dt:
            # start from the step the CFL number gives now, so the switch changes nothing at first
            dt = self._current_dt() or 1.0e-4
            self.doc.edit("use a fixed time step", lambda d: (d["numerics"].pop("cfl", None),
                                                             d["numerics"].__setitem__("time_step_s", dt)))

    def _current_dt(self) -> float | None:
        if self.doc.project is None:
            return None
        from projects.build import resolve

        try:
            return float(f"{resolve(self.doc.project, seed=False).estimate['time_step_s']:.3g}")
        except (ValueError, ZeroDivisionError):
            return None

    def _on_changed(self, sections: frozenset) -> None:
        if not sections & {"numerics", "particles"}:
            return
        preset = self.doc.get("numerics.preset")
        self.preset.blockSignals(True)
        self.preset.setCurrentIndex(0 if preset is None else 1 + PRESETS.index(preset))
        self.preset.blockSignals(False)
        self.preset_info.setText(self._preset_text(preset))
        has_dt = self.doc.get("numerics.time_step_s") is not None
        for w in (self.use_cfl, self.use_dt):
            w.blockSignals(True)
        self.use_dt.setChecked(has_dt)
        self.use_cfl.setChecked(not has_dt)
        for w in (self.use_cfl, self.use_dt):
            w.blockSignals(False)
        self.cfl.set_path(None if has_dt else "numerics.cfl")
        self.dt.set_path("numerics.time_step_s" if has_dt else None)
        n = self.doc.get("particles.per_cell", 2)
        if isinstance(n, int):
            self.per_cell_info.setText(f"{n * n} particles in a full cell")


# --------------------------------------------------------------------------------------------
# stages


class StagesPanel(Panel):
    """The stages in order, the selected stage's settings, its loads and its material changes.

    Signals
    -------
    stageChosen(object)
        The stage shown (its index, None: none), e.g. for the scene view to draw its loads.
    """

    stageChosen = Signal(object)

    def __init__(self, doc: ProjectDocument, parent: QWidget | None = None) -> None:
        super().__init__(doc, parent)
        self.list = QListWidget()
        self.list.setMaximumHeight(110)
        self.list.currentRowChanged.connect(self._select)
        self.layout_.addWidget(self.list)
        buttons = QHBoxLayout()
        self.add_button = QPushButton("Add")
        add_menu = QMenu(self.add_button)
        for kind in STAGE_TYPES:
            add_menu.addAction(kind).triggered.connect(lambda _c=False, k=kind: self.add_stage(k))
        self.add_button.setMenu(add_menu)
        self.remove_button = QPushButton("Remove")
        self.remove_button.clicked.connect(self.remove_stage)
        self.up_button = _small_button("▲", "Earlier")
        self.up_button.clicked.connect(lambda: self.move_stage(-1))
        self.down_button = _small_button("▼", "Later")
        self.down_button.clicked.connect(lambda: self.move_stage(1))
        for b in (self.add_button, self.remove_button, self.up_button, self.down_button):
            buttons.addWidget(b)
        self.layout_.addLayout(buttons)

        box, form = _form("Selected stage")
        self.name = TextField(doc, None, "Stage name", optional=True)
        self.kind = ChoiceField(doc, None, "Stage type", STAGE_TYPES)
        self.duration = NumberField(doc, None, "Duration", "s")
        self.k0 = NumberField(doc, None, "K0", "–", optional=True, placeholder="1 − sin φ per material")
        self.damping = NumberField(doc, None, "Local damping", "–", optional=True, placeholder="none")
        self.damping.commit = self._commit_damping  # type: ignore[method-assign]
        self.stop_ke = NumberField(doc, None, "Stop when kinetic energy below", "× peak", optional=True,
                                   placeholder="run the full duration")
        self.stop_speed = NumberField(doc, None, "Stop when the fastest particle is below", "m/s", optional=True,
                                      placeholder="any speed")
        self.min_duration = NumberField(doc, None, "Minimum duration", "s", optional=True)
        self.ramp = NumberField(doc, None, "Gravity ramp", "× duration", optional=True,
                                placeholder=f"{DEFAULT_GRAVITY_RAMP_FRACTION:g} (then held at full value)")
        form.addRow("Name", self.name)
        form.addRow("Type", self.kind)
        form.addRow("Duration", self.duration)
        form.addRow("Gravity ramp", self.ramp)
        form.addRow("K0", self.k0)
        form.addRow("Damping", self.damping)
        form.addRow("Stop at KE below", self.stop_ke)
        form.addRow("and speed below", self.stop_speed)
        form.addRow("Min. duration", self.min_duration)
        self.strength_factor = NumberField(doc, None, "Strength factor", "–", optional=True,
                                           placeholder="F_fail of the search")
        form.addRow("Strength factor", self.strength_factor)
        self.stage_form = form
        self.layout_.addWidget(box)

        # a strength-reduction stage's own settings (docs/project-format.md, strength reduction)
        box, form = _form("Strength reduction (factor of safety)")
        self.trial_duration = NumberField(doc, None, "Trial duration", "s", optional=True,
                                          placeholder="the gravity stage's duration")
        self.tolerance = NumberField(doc, None, "Tolerance", "–", optional=True, placeholder="0.01")
        self.first_trial = NumberField(doc, None, "First trial", "–", optional=True,
                                       placeholder="Bishop's factor", words=FIRST_TRIALS)
        self.first_trial.edit.setToolTip(f"a factor, or {FIRST_TRIALS[0]} (Bishop's factor of the section)")
        self.bracket_step = NumberField(doc, None, "Bracket step", "–", optional=True, placeholder="0.1")
        self.max_trials = NumberField(doc, None, "Largest number of trials", "–", optional=True,
                                      placeholder="40", integer=True)
        self.failure_displacement = NumberField(doc, None, "Failure displacement", "m", optional=True,
                                                placeholder="5 % of the model's height")
        self.failure_ke = NumberField(doc, None, "Kinetic-energy ratio", "–", optional=True, placeholder="0.001")
        self.limit_equilibrium = QCheckBox("Bishop's search beside it")
        self.limit_equilibrium.setToolTip("limit_equilibrium: Bishop's simplified method over the same section "
                                          "(a few seconds); its factor is the first trial by default")
        self.limit_equilibrium.toggled.connect(self._limit_equilibrium_toggled)
        form.addRow("Trial duration", self.trial_duration)
        form.addRow("Tolerance", self.tolerance)
        form.addRow("First trial", self.first_trial)
        form.addRow("Bracket step", self.bracket_step)
        form.addRow("Max. trials", self.max_trials)
        form.addRow("Fails at", self.failure_displacement)
        form.addRow("KE ratio", self.failure_ke)
        form.addRow("", self.limit_equilibrium)
        self.strength_box = box
        self.layout_.addWidget(box)

        from app.gui.loads_panel import StageLoadsBox  # surcharges and seismic coefficients

        self.loads = StageLoadsBox(doc)
        self.layout_.addWidget(self.loads)

        box = QGroupBox("Material changes at the start of this stage")
        self.changes_box = box  # none on a strength-reduction stage: its trials reduce the strengths
        vbox = QVBoxLayout(box)
        self.changes = QTableWidget(0, 3)
        self.changes.setHorizontalHeaderLabels(["Material", "Property", "New value"])
        self.changes.horizontalHeader().setSectionResizeMode(QHeaderView.ResizeMode.Stretch)
        self.changes.setEditTriggers(QAbstractItemView.EditTrigger.NoEditTriggers)
        self.changes.setSelectionBehavior(QAbstractItemView.SelectionBehavior.SelectRows)
        self.changes.setMaximumHeight(120)
        vbox.addWidget(self.changes)
        row = QHBoxLayout()
        self.change_material = QComboBox()
        self.change_material.setAccessibleName("Changed material")
        self.change_material.setMinimumWidth(80)
        self.change_material.setSizeAdjustPolicy(QComboBox.SizeAdjustPolicy.AdjustToContents)
        self.change_key = QComboBox()
        self.change_key.setAccessibleName("Changed property")
        for key in (*MATERIAL_KEYS, *SOFTENING_NUMBER_KEYS):
            self.change_key.addItem(f"{FIELD_INFO[key][0]} ({FIELD_INFO[key][1]})", key)
        # the changes that are words, not numbers (the warning on near-limit slides asks for the damping
        # model); the placeholder names the words
        for key in WORD_CHANGES:
            self.change_key.addItem(FIELD_INFO[key][0], key)
        self.change_value = QLineEdit()
        self.change_value.setPlaceholderText("value")
        self.change_key.currentIndexChanged.connect(lambda _i: self.change_value.setPlaceholderText(
            " or ".join(WORD_CHANGES.get(self.change_key.currentData(), ("value",)))))
        self.change_value.setAccessibleName("New value")
        self.change_set = QPushButton("Set")
        self.change_set.clicked.connect(self._set_change)
        self.change_remove = QPushButton("Remove")
        self.change_remove.clicked.connect(self._remove_change)
        # two rows: what changes, then its value, so that the box fits the dock at the window's
        # default size (one row of five was 520 px wide and cut off Remove and the value field)
        self.change_key.setSizeAdjustPolicy(QComboBox.SizeAdjustPolicy.AdjustToMinimumContentsLengthWithIcon)
        self.change_key.setMinimumContentsLength(12)
        row.addWidget(self.change_material)
        row.addWidget(self.change_key, 1)
        vbox.addLayout(row)
        row = QHBoxLayout()
        row.addWidget(self.change_value, 1)
        row.addWidget(self.change_set)
        row.addWidget(self.change_remove)
        vbox.addLayout(row)
        self.layout_.addWidget(box)
        self.watch(self.name, self.duration, self.k0, self.damping, self.stop_ke, self.stop_speed, self.min_duration,
                   self.strength_factor, self.trial_duration, self.tolerance, self.first_trial, self.bracket_step,
                   self.max_trials, self.failure_displacement, self.failure_ke)
        self.finish()
        self._current: int | None = None
        self._on_changed(frozenset({"stages"}))

    @property
    def current(self) -> int | None:
        return self._current

    def select(self, index: int) -> None:
        self.list.setCurrentRow(index)

    def _stages(self) -> list[dict[str, Any]]:
        return self.doc.get("stages", [])

    def _select(self, row: int) -> None:
        stages = self._stages()
        self._current = row if 0 <= row < len(stages) else None
        self._bind()

    def _bind(self) -> None:
        i = self._current
        base = f"stages.{i}" if i is not None else None
        kind = self.doc.get(f"{base}.type") if base else None
        self.name.set_path(f"{base}.name" if base else None)
        self.kind.set_path(f"{base}.type" if base else None)
        timed = kind in ("gravity", "dynamic")  # the stages that have a duration
        reduction = base is not None and kind == "strength-reduction"
        self.duration.set_path(f"{base}.duration_s" if base and timed else None)
        self.k0.set_path(f"{base}.k0" if base and kind == "k0" else None)
        self.ramp.set_path(f"{base}.ramp_fraction" if base and kind == "gravity" else None)
        self.damping.set_path(f"{base}.damping.coefficient" if base and (timed or reduction) else None)
        if base and kind in ("gravity", "strength-reduction") and self.doc.get(f"{base}.damping") is None:
            self.damping.edit.setPlaceholderText(f"0.7 (default for {kind})")
        else:
            self.damping.edit.setPlaceholderText("none")
        dynamic = base is not None and kind == "dynamic"
        self.stop_ke.set_path(f"{base}.stop_when_kinetic_energy_below" if dynamic else None)
        self.stop_speed.set_path(f"{base}.stop_when_max_speed_below_m_s" if dynamic else None)
        self.min_duration.set_path(f"{base}.min_duration_s" if dynamic else None)
        # the run-out after a strength reduction starts with the strengths reduced by this factor
        after_reduction = dynamic and any(isinstance(st, dict) and st.get("type") == "strength-reduction"
                                          for st in self._stages()[:i])
        self.strength_factor.set_path(f"{base}.strength_factor" if after_reduction else None)
        strength = {self.trial_duration: "trial_duration_s", self.tolerance: "tolerance",
                    self.first_trial: "first_trial", self.bracket_step: "bracket_step",
                    self.max_trials: "max_trials", self.failure_displacement: "failure.displacement_m",
                    self.failure_ke: "failure.kinetic_energy_ratio"}
        for f, key in strength.items():
            f.set_path(f"{base}.{key}" if reduction else None)
        self.limit_equilibrium.blockSignals(True)
        self.limit_equilibrium.setChecked(bool(self.doc.get(f"{base}.limit_equilibrium", True)) if reduction else True)
        self.limit_equilibrium.setEnabled(reduction)
        self.limit_equilibrium.blockSignals(False)
        self.strength_box.setVisible(reduction)
        self.changes_box.setVisible(not reduction)
        # rows a stage of this type has no key for are hidden, not greyed out
        rows = {self.duration: timed, self.ramp: kind == "gravity", self.k0: kind == "k0",
                self.damping: timed or reduction, self.stop_ke: dynamic, self.stop_speed: dynamic,
                self.min_duration: dynamic, self.strength_factor: after_reduction}
        for f, shown in rows.items():
            self.stage_form.setRowVisible(f, shown or base is None)
        for f in (self.duration, self.ramp, self.k0, self.damping, self.stop_ke, self.stop_speed, self.min_duration,
                  self.strength_factor, *strength):
            if f.path is None:
                f.edit.setText("")
        self.change_material.clear()
        self.change_material.addItems(self.doc.material_names)
        changes = self.doc.get(f"{base}.material_changes", {}) if base else {}
        rows = [(m, k, v) for m, table in (changes or {}).items() if isinstance(table, dict) for k, v in table.items()]
        self.changes.setRowCount(len(rows))
        for r, (m, k, v) in enumerate(rows):
            label, unit = FIELD_INFO.get(k, (k, ""))
            shown = f"{format_number(v)} {unit}"
            if unit == "kg/m³" and isinstance(v, (int, float)):  # typed as a unit weight, perhaps: both
                from projects.units import UNIT_WEIGHT_GRAVITY_M_S2

                shown += f" (unit weight {float(v) * UNIT_WEIGHT_GRAVITY_M_S2 / 1e3:.4g} kN/m³)"
            for c, text in enumerate((m, label, shown)):
                item = QTableWidgetItem(text)
                item.setData(Qt.ItemDataRole.UserRole, (m, k))
                self.changes.setItem(r, c, item)
        for w in (self.change_material, self.change_key, self.change_value, self.change_set, self.change_remove,
                  self.remove_button, self.up_button, self.down_button):
            w.setEnabled(base is not None)
        self.loads.bind(i)
        self.stageChosen.emit(i)

    def _limit_equilibrium_toggled(self, on: bool) -> None:
        i = self._current
        if i is not None and self.doc.get(f"stages.{i}.type") == "strength-reduction":
            # true is the default: the key is written only to turn the search off
            self.doc.set_value(f"stages.{i}.limit_equilibrium", None if on else False,
                               "turn Bishop's search " + ("on" if on else "off"))

    def _commit_damping(self) -> bool:
        """Damping is a table ``{type = "local", coefficient = ..}``: write or remove it whole."""
        field = self.damping
        if field.path is None:
            return False
        text = field.edit.text()
        base = field.path.rsplit(".", 1)[0]
        if not text.strip():
            return self.doc.set_value(base, None, "remove damping")
        value = parse_number(text)
        error = "must be a number" if value is None else check_value(field.path, value)
        field.error = error or ""
        field._style()
        if error:
            self.show_message(f"Local damping: {error}")
            return False
        return self.doc.set_value(base, {"type": "local", "coefficient": value}, "change damping")

    def _on_changed(self, sections: frozenset) -> None:
        if not sections & {"stages", "materials"}:
            return
        stages = self._stages()
        self.list.blockSignals(True)
        self.list.clear()
        for i, stage in enumerate(stages):
            name = stage.get("name") or stage.get("type", "?")
            extra = f", {format_number(stage['duration_s'])} s" if "duration_s" in stage else ""
            changes = " + material changes" if stage.get("material_changes") else ""
            changes += " + water" if isinstance(stage.get("water"), dict) else ""
            changes += " + surcharges" if stage.get("surcharges") else ""
            changes += " + seismic" if isinstance(stage.get("seismic"), dict) else ""
            self.list.addItem(f"{i + 1}. {name}  ({stage.get('type', '?')}{extra}){changes}")
        if self._current is None or self._current >= len(stages):
            self._current = (len(stages) - 1) if stages else None
        if self._current is not None:
            self.list.setCurrentRow(self._current)
        self.list.blockSignals(False)
        self._bind()

    def add_stage(self, kind: str) -> None:
        stage: dict[str, Any] = {"name": kind if kind != "k0" else "initial stress", "type": kind}
        if kind in ("gravity", "dynamic"):  # k0 and strength reduction take no duration
            stage["duration_s"] = 1.0
        # initial-stress stages go first, a strength reduction right after them, dynamic ones last
        stages = self._stages()
        initial = 0
        while initial < len(stages) and isinstance(stages[initial], dict) and \
                stages[initial].get("type") in ("k0", "gravity"):
            initial += 1
        index = {"k0": 0, "gravity": 0, "strength-reduction": initial}.get(kind, len(stages))
        if kind == "strength-reduction" and not any(isinstance(st, dict) and st.get("type") == "gravity"
                                                    for st in stages):
            stage["trial_duration_s"] = 1.0  # a trial's budget (a gravity stage's duration by default)
        self.doc.edit(f"add {kind} stage", lambda d: d.setdefault("stages", []).insert(index, stage))
        self._current = index
        self._on_changed(frozenset({"stages"}))

    def remove_stage(self) -> None:
        i = self._current
        if i is not None:
            self.doc.edit("remove stage", lambda d: d["stages"].pop(i))

    def move_stage(self, step: int) -> None:
        i = self._current
        stages = self._stages()
        if i is None or not 0 <= i + step < len(stages):
            return

        def mutate(d: dict[str, Any]) -> None:
            items = d["stages"]
            items[i], items[i + step] = items[i + step], items[i]

        self.doc.edit("reorder stages", mutate)
        self._current = i + step
        self._on_changed(frozenset({"stages"}))

    def set_change(self, material: str, key: str, value: float | str) -> bool:
        """Set ``key`` of ``material`` from the selected stage on."""
        i = self._current
        if i is None:
            return False
        path = f"stages.{i}.material_changes.{material}.{key}"
        error = check_value(path, value)
        if error:
            self.show_message(f"{FIELD_INFO.get(key, (key,))[0]}: {error}")
            return False
        return self.doc.set_value(path, value, f"change {material} {key} in stage {i + 1}")

    def _set_change(self) -> None:
        key = self.change_key.currentData()
        text = self.change_value.text().strip()
        if key in WORD_CHANGES:
            value: Any = text  # the schema checks the word
        else:  # a unit may follow the number, as in the material's own fields ("21 kN/m3", "5 kPa")
            value, error = parse_quantity(text, FIELD_INFO.get(key, ("", ""))[1])
            if value is None:
                self.show_message(f"New value: {error or 'must be a number'}")
                return
        self.set_change(self.change_material.currentText(), key, value)

    def _remove_change(self) -> None:
        i = self._current
        rows = {index.row() for index in self.changes.selectedIndexes()}
        if i is None or not rows:
            return
        pairs = [self.changes.item(r, 0).data(Qt.ItemDataRole.UserRole) for r in rows]

        def mutate(d: dict[str, Any]) -> None:
            changes = d["stages"][i].get("material_changes", {})
            for m, k in pairs:
                changes.get(m, {}).pop(k, None)
                if not changes.get(m, True):
                    changes.pop(m)
            if not changes:
                d["stages"][i].pop("material_changes", None)

        self.doc.edit("remove material change", mutate)


# --------------------------------------------------------------------------------------------
# output


class OutputPanel(Panel):
    """Output interval and the fields written to the results."""

    def __init__(self, doc: ProjectDocument, parent: QWidget | None = None) -> None:
        super().__init__(doc, parent)
        box, form = _form("Frames")
        self.interval = NumberField(doc, "output.interval_s", "Output interval", "s")
        form.addRow("Every", self.interval)
        self.frames_info = QLabel("")
        self.frames_info.setStyleSheet("color: #555;")
        form.addRow("", self.frames_info)
        self.layout_.addWidget(box)
        box = QGroupBox("Fields written (positions always)")
        vbox = QVBoxLayout(box)
        self.checks: dict[str, QCheckBox] = {}
        units = {"displacement": "m", "velocity": "m/s", "stress": "Pa", "plastic_strain": "–", "material": "id",
                 "pore_pressure": "Pa"}
        for name in OUTPUT_FIELDS:
            check = QCheckBox(f"{name.replace('_', ' ')} ({units[name]})")
            check.toggled.connect(lambda on, n=name: self._toggled(n, on))
            vbox.addWidget(check)
            self.checks[name] = check
        self.layout_.addWidget(box)
        self.watch(self.interval)
        self.finish()
        self._on_changed(frozenset({"output"}))

    def _toggled(self, name: str, on: bool) -> None:
        fields = list(self.doc.get("output.fields", list(OUTPUT_FIELDS)))
        if on and name not in fields:
            fields = [f for f in OUTPUT_FIELDS if f in fields or f == name]
        elif not on and name in fields:
            fields.remove(name)
        else:
            return
        self.doc.set_value("output.fields", fields, f"{'write' if on else 'skip'} {name}")

    def _on_changed(self, sections: frozenset) -> None:
        if not sections & {"output", "stages"}:
            return
        fields = self.doc.get("output.fields", list(OUTPUT_FIELDS))
        for name, check in self.checks.items():
            check.blockSignals(True)
            check.setChecked(name in fields)
            check.blockSignals(False)
        total = sum(float(s.get("duration_s") or 0.0) for s in self.doc.get("stages", [])
                    if isinstance(s.get("duration_s", 0.0), (int, float)))
        interval = self.doc.get("output.interval_s", 0.01)
        if isinstance(interval, (int, float)) and interval > 0:
            self.frames_info.setText(f"about {int(total / interval) + 1} frames over {total:g} s")
