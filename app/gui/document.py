"""The Qt side of the project model: one document, its undo stack and the current selection.

The document holds the project as TOML-shaped data (plain dicts and lists, exactly what
:meth:`projects.schema.Project.to_dict` gives) and validates it with the project schema after
every change, so it can hold an unfinished project (a body still being drawn, a dilatancy above
the friction angle) and say what is wrong with it, while :attr:`ProjectDocument.project` is the
validated model whenever there is nothing wrong.

Every edit is a :class:`SnapshotCommand` on the :class:`QUndoStack`: the data before and after.
Projects are small (kilobytes), so whole snapshots keep undo exact for every kind of edit
(renaming a material also renames its uses) without one command class per edit. Widgets never
change the data themselves: they call :meth:`ProjectDocument.set_value` or
:meth:`ProjectDocument.edit` and redraw when :attr:`ProjectDocument.changed` fires.
"""

from __future__ import annotations

import copy
import logging
import os
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Annotated, Any

from pydantic import TypeAdapter, ValidationError
from PySide6.QtCore import QObject, Signal
from PySide6.QtGui import QUndoCommand, QUndoStack

from projects.document import dumps_project, loads_project, parse_toml, save_project
from projects.schema import PLASTIC_KEYS as FILE_PLASTIC_KEYS
from projects.schema import INERTIAL_KEYS as FILE_INERTIAL_KEYS
from projects.schema import SOFTENING_KEYS as FILE_SOFTENING_KEYS
from projects.schema import (
    OUTPUT_FIELDS,
    SCHEMA_VERSION,
    Problem,
    Project,
    ProjectError,
    schema_kind,
    validate_project,
)

logger = logging.getLogger(__name__)

SECTIONS: tuple[str, ...] = ("runout", "domain", "materials", "bodies", "structures", "water", "particles",
                             "numerics", "stages", "output", "targets")
#: Up to this many particles (the estimate from the bodies' area) the workbench seeds the bodies as
#: the run will, for the particle preview and the Run panel's count (0.3 s at 400,000); above,
#: seeding on every edit would hold the window up for seconds.
MAX_SEEDED_PARTICLES = 400_000
#: The parts of a project drawn as polygons (edited with the same scene tools and vertex table).
POLYGON_KINDS: tuple[str, ...] = ("bodies", "structures")
#: What can be selected: a polygon's kind, ``"targets"`` or ``"water"`` (a water line: its index is
#: a slot of :func:`water_line_path`).
SELECTABLE_KINDS: tuple[str, ...] = (*POLYGON_KINDS, "targets", "water")
#: The two water lines of ``[water]`` and of a stage's ``[stages.water]``, in slot order.
WATER_LINE_KEYS: tuple[str, ...] = ("phreatic_line_m", "free_water_line_m")


def water_line_path(slot: int) -> str:
    """The key path of water line ``slot``: 0 and 1 are the project's phreatic and free-water
    lines (``water.phreatic_line_m``, ``water.free_water_line_m``), 2 + 2 i and 3 + 2 i those
    stage ``i`` moves the water to (``stages.i.water.phreatic_line_m``, ...)."""
    stage, which = divmod(int(slot), 2)
    key = WATER_LINE_KEYS[which]
    return f"water.{key}" if stage == 0 else f"stages.{stage - 1}.water.{key}"


def water_slot(stage: int | None, key: str) -> int:
    """The slot of line ``key`` (``phreatic_line_m`` or ``free_water_line_m``) of the project
    (``stage`` None) or of stage ``stage``."""
    return (0 if stage is None else 2 + 2 * int(stage)) + WATER_LINE_KEYS.index(key)

#: Label and unit of each numeric key of the project file (units as shown next to fields).
FIELD_INFO: dict[str, tuple[str, str]] = {
    "density_kg_m3": ("Density", "kg/m³"),
    "youngs_modulus_pa": ("Young's modulus", "Pa"),
    "poisson_ratio": ("Poisson's ratio", "–"),
    "cohesion_pa": ("Cohesion", "Pa"),
    "friction_angle_deg": ("Friction angle", "°"),
    "dilatancy_angle_deg": ("Dilatancy angle", "°"),
    "tensile_strength_pa": ("Tensile strength", "Pa"),
    "damping_ratio": ("Damping ratio", "–"),
    "damping_frequency_hz": ("Damping frequency", "Hz"),
    "damping_model": ("Damping model", ""),
    "cell_size_m": ("Cell size", "m"),
    "duration_s": ("Duration", "s"),
    "k0": ("K0 (empty: 1 − sin φ)", "–"),
    "time_step_s": ("Time step", "s"),
    "cfl": ("CFL number", "–"),
    "interval_s": ("Output interval", "s"),
    "min_duration_s": ("Minimum duration", "s"),
    "stop_when_kinetic_energy_below": ("Stop when kinetic energy below", "× peak"),
    "stop_when_max_speed_below_m_s": ("Stop when the fastest particle is below", "m/s"),
    "coefficient": ("Damping coefficient", "–"),
    "per_cell": ("Particles per cell (per direction)", "–"),
    "saturated_density_kg_m3": ("Saturated density", "kg/m³"),
    "ru": ("Pore-pressure ratio r_u", "–"),
    "unit_weight_n_m3": ("Unit weight of water", "N/m³"),
    "softening_law": ("Softening law", ""),
    "residual_cohesion_pa": ("Residual cohesion", "Pa"),
    "residual_friction_angle_deg": ("Residual friction angle", "°"),
    "residual_dilatancy_angle_deg": ("Residual dilatancy angle", "°"),
    "peak_plastic_strain": ("Peak plastic strain", "–"),
    "residual_plastic_strain": ("Residual plastic strain", "–"),
    "softening_length_m": ("Softening length", "m"),
    "mu_i_friction_increase": ("Friction increase Δμ", "–"),
    "mu_i_reference_number": ("Reference inertial number I₀", "–"),
    "grain_diameter_m": ("Grain diameter", "m"),
    "grain_density_kg_m3": ("Grain density", "kg/m³"),
}
MATERIAL_KEYS: tuple[str, ...] = (
    "density_kg_m3",
    "saturated_density_kg_m3",
    "youngs_modulus_pa",
    "poisson_ratio",
    "cohesion_pa",
    "friction_angle_deg",
    "dilatancy_angle_deg",
    "tensile_strength_pa",
    "damping_ratio",
    "damping_frequency_hz",
    "ru",
)
#: the numbers of a material's strain softening (projects.schema.SOFTENING_KEYS without the law,
#: which is a word), in the form below the softening law
SOFTENING_NUMBER_KEYS: tuple[str, ...] = tuple(k for k in FILE_SOFTENING_KEYS if k != "softening_law")
#: the numbers of a material's rate-dependent friction, the mu(I) law (projects.schema.INERTIAL_KEYS),
#: in the form's own group below the softening
INERTIAL_NUMBER_KEYS: tuple[str, ...] = FILE_INERTIAL_KEYS
#: the keys only a Drucker-Prager material has (the file's rule: projects.schema.PLASTIC_KEYS)
PLASTIC_KEYS: tuple[str, ...] = tuple(k for k in (*MATERIAL_KEYS, *SOFTENING_NUMBER_KEYS, *INERTIAL_NUMBER_KEYS)
                                      if k in FILE_PLASTIC_KEYS)
#: keys a material may leave out, with what an empty field means
OPTIONAL_MATERIAL_KEYS: dict[str, str] = {
    "tensile_strength_pa": "no cut-off",
    "damping_ratio": "undamped",
    "damping_frequency_hz": "none",
    "saturated_density_kg_m3": "= density (no water in the pores)",
    "ru": "none (pore pressure from the water lines)",
    "residual_cohesion_pa": "= cohesion (does not soften)",
    "residual_friction_angle_deg": "= friction angle (does not soften)",
    "residual_dilatancy_angle_deg": "= dilatancy angle (does not soften)",
    "peak_plastic_strain": "0 (softens from first yield)",
    "residual_plastic_strain": "required with a law",
    "softening_length_m": "none: depends on the cell size",
    "mu_i_friction_increase": "none (rate-independent friction)",
    "mu_i_reference_number": "required with a friction increase",
    "grain_diameter_m": "required with a friction increase",
    "grain_density_kg_m3": "= density",
}


def new_project_data() -> dict[str, Any]:
    """A new project: a 20 m x 10 m domain, one soil, no bodies yet, K0 then a dynamic stage that
    runs to rest (at most 20 s)."""
    return {
        "runout": {"schema_version": SCHEMA_VERSION, "title": "Untitled"},
        "domain": {
            "origin_m": [0.0, 0.0],
            "size_m": [20.0, 10.0],
            "cell_size_m": 0.25,
            "gravity_m_s2": [0.0, -9.81],
            "boundaries": {"left": "slip", "right": "slip", "bottom": "fixed", "top": "open"},
        },
        "materials": {
            "soil": {
                "model": "drucker-prager",
                "density_kg_m3": 2000.0,
                "youngs_modulus_pa": 1.0e7,
                "poisson_ratio": 0.3,
                "cohesion_pa": 5000.0,
                "friction_angle_deg": 30.0,
                "dilatancy_angle_deg": 0.0,
            }
        },
        "bodies": [],
        "particles": {"per_cell": 2, "seeding": "lattice"},
        "numerics": {"scheme": "apic-affine", "cfl": 0.5, "precision": "f32", "arch": "auto"},
        "stages": [
            {"name": "initial stress", "type": "k0"},
            # to rest: the stage ends once the mass has come to rest, its fastest particle included;
            # the duration is a safety limit (a run that reaches it ends still moving and says so)
            {"name": "run-out", "type": "dynamic", "duration_s": 20.0, "stop_when_kinetic_energy_below": 0.01,
             "stop_when_max_speed_below_m_s": 0.1, "min_duration_s": 1.0},
        ],
        "output": {"interval_s": 0.05, "fields": list(OUTPUT_FIELDS)},
    }


# --------------------------------------------------------------------------------------------
# key paths


def split_path(path: str) -> list[str | int]:
    """``"bodies.0.name"`` -> ``["bodies", 0, "name"]`` (digits are list indices)."""
    return [int(p) if p.isdigit() else p for p in path.split(".")]


def get_path(data: Any, path: str, default: Any = None) -> Any:
    """The value at a dotted key path, or ``default`` where the path does not exist."""
    node = data
    for part in split_path(path):
        if isinstance(node, Mapping) and part in node:
            node = node[part]
        elif isinstance(node, list) and isinstance(part, int) and 0 <= part < len(node):
            node = node[part]
        else:
            return default
    return node


def set_path(data: Any, path: str, value: Any) -> None:
    """Set the value at a dotted key path in place, creating tables on the way; None removes it."""
    parts = split_path(path)
    node = data
    for part in parts[:-1]:
        if isinstance(node, list):
            node = node[part]
            continue
        if not isinstance(node.get(part), (dict, list)):
            node[part] = {}
        node = node[part]
    last = parts[-1]
    if isinstance(node, list):
        node[last] = value
    elif value is None:
        node.pop(last, None)
    else:
        node[last] = value


def _schema_at(path: str) -> Any:
    """The schema annotation of the value at ``path`` (wildcards allowed for names and indices)."""
    node: Any = Project
    for part in split_path(path):
        kind, inner = schema_kind(node)
        if kind == "model":
            field = inner.model_fields.get(str(part))
            if field is None:
                raise KeyError(f"no key {part!r} in {inner.__name__}")
            node = Annotated[(field.annotation, *field.metadata)] if field.metadata else field.annotation
        elif kind in ("dict", "list"):
            node = inner
        else:
            raise KeyError(f"{path} goes below a value")
    return node


_CHECKERS: dict[str, TypeAdapter] = {}


def check_value(path: str, value: Any) -> str | None:
    """Check one value against the schema's rule for its key; the schema's message, or None if fine.

    Parameters
    ----------
    path : str
        Dotted key path; material names and list indices may be anything (``materials.x.cohesion_pa``).
    value : Any
        The value as it would be written in the file (None: the key is left out).

    Returns
    -------
    str or None
    """
    parts = [("*" if isinstance(p, int) else p) for p in split_path(path)]
    if len(parts) > 1 and parts[0] == "materials":
        parts[1] = "*"
    if len(parts) > 3 and parts[2] == "material_changes":
        parts[3] = "*"
    key = ".".join(str(p) for p in parts)
    adapter = _CHECKERS.get(key)
    if adapter is None:
        schema_path = ".".join("0" if p == "*" else str(p) for p in parts)
        adapter = _CHECKERS[key] = TypeAdapter(_schema_at(schema_path))
    try:
        adapter.validate_python(value)
    except ValidationError as err:
        errors = err.errors(include_url=False)
        return str(errors[0]["msg"]) if errors else str(err)
    return None


def parse_number(text: str) -> float | None:
    """A number typed by a user (``2.5e6``, ``1 000``, a comma as decimal point), or None."""
    cleaned = text.strip().replace(" ", "").replace("\u202f", "").replace(",", ".")
    if not cleaned:
        return None
    try:
        return float(cleaned)
    except ValueError:
        return None


def format_number(value: Any) -> str:
    """A number for a text field: short, exact for what was typed (10 significant digits); a value
    written with more by a script (2.9000000000000004) shows rounded, and the fields keep it
    unless its text is edited (:func:`typed_or_kept`)."""
    if isinstance(value, bool) or value is None:
        return "" if value is None else str(value)
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return f"{value:.10g}"
    return str(value)


def typed_or_kept(text: str, typed: Any, current: Any) -> Any:
    """What a field's ``text`` stands for: ``current`` while the text is still the one shown for it
    (a rounded long decimal is not rewritten by a focus change), else the ``typed`` value."""
    if current is not None and not isinstance(current, bool) and text.strip() == format_number(current):
        return current
    return typed


def editable_data(data: Any) -> dict[str, Any] | None:
    """``data`` when its tables have the shapes the panels can show (maybe with bad values), else None.

    A file with wrong values (a negative density, a dilatancy above friction, a body outside the
    domain) or unknown keys (typos: listed as problems, removable in the run panel) can be
    opened and fixed in the workbench; one whose structure is broken (``bodies``
    is not an array of tables) can only be fixed in a text editor.
    """
    if not isinstance(data, Mapping):
        return None
    shapes = {
        "runout": Mapping,
        "domain": Mapping,
        "materials": Mapping,
        "bodies": list,
        "particles": Mapping,
        "numerics": Mapping,
        "stages": list,
        "output": Mapping,
    }
    optional_lists = ("structures", "targets")
    if "water" in data and not isinstance(data["water"], Mapping):
        return None
    for key in optional_lists:
        if key in data and (not isinstance(data[key], list) or any(not isinstance(t, Mapping) for t in data[key])):
            return None
    for key, shape in shapes.items():
        if key in data and not isinstance(data[key], shape):
            return None
    for material in dict(data.get("materials", {})).values():
        if not isinstance(material, Mapping):
            return None
    for key in ("bodies", "stages"):
        if any(not isinstance(item, Mapping) for item in data.get(key, [])):
            return None
    for body in [*data.get("bodies", []), *data.get("structures", [])]:
        polygon = body.get("polygon_m", [])
        if not isinstance(polygon, list) or any(
            not isinstance(p, list) or len(p) != 2 or not all(_is_number(c) for c in p) for p in polygon
        ):
            return None
    filled = copy.deepcopy(dict(data))
    for key, shape in shapes.items():
        filled.setdefault(key, {} if shape is Mapping else [])
    filled["runout"].setdefault("schema_version", SCHEMA_VERSION)
    domain = filled["domain"]
    if not isinstance(domain.get("boundaries", {}), Mapping):
        return None
    return filled


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


# --------------------------------------------------------------------------------------------
# undo commands and the document


class SnapshotCommand(QUndoCommand):
    """One edit: the project data before and after it.

    Consecutive commands with the same ``merge_key`` (the steps of one vertex drag, the keys
    typed into one field) merge into one undo step.
    """

    MERGEABLE_ID = 1

    def __init__(self, doc: ProjectDocument, before: dict, after: dict, text: str, merge_key: str | None) -> None:
        super().__init__(text)
        self._doc = doc
        self._before = before
        self._after = after
        self.merge_key = merge_key

    def id(self) -> int:  # noqa: A003 - Qt's name
        return self.MERGEABLE_ID if self.merge_key else -1

    def mergeWith(self, other: QUndoCommand) -> bool:  # noqa: N802 - Qt's name
        if not isinstance(other, SnapshotCommand) or other.merge_key != self.merge_key:
            return False
        self._after = other._after
        return True

    def redo(self) -> None:
        self._doc._apply(self._after)

    def undo(self) -> None:
        self._doc._apply(self._before)


class Selection(QObject):
    """The object and vertex the user works on, shared by the scene view and the panels.

    ``kind`` is ``"bodies"``, ``"structures"`` (polygons, with a vertex) or ``"targets"``;
    ``index`` is the position in that list. :attr:`body` (and :attr:`structure`,
    :attr:`target`) is the index when the selection is of that kind, else None.
    """

    changed = Signal()

    def __init__(self, parent: QObject | None = None) -> None:
        super().__init__(parent)
        self.kind = "bodies"
        self.index: int | None = None
        self.vertex: int | None = None

    def _of(self, kind: str) -> int | None:
        return self.index if self.kind == kind else None

    @property
    def body(self) -> int | None:
        return self._of("bodies")

    @property
    def structure(self) -> int | None:
        return self._of("structures")

    @property
    def target(self) -> int | None:
        return self._of("targets")

    def set(self, body: int | None, vertex: int | None = None) -> None:
        """Select body ``body`` (None: nothing) and its vertex ``vertex``."""
        self.select("bodies", body, vertex)

    def select(self, kind: str, index: int | None, vertex: int | None = None) -> None:
        """Select item ``index`` of ``kind`` (one of :data:`SELECTABLE_KINDS`; None: nothing)."""
        if kind not in SELECTABLE_KINDS:
            raise ValueError(f"cannot select {kind!r}: one of {', '.join(SELECTABLE_KINDS)}")
        if index is None:
            vertex = None
        if (kind, index, vertex) != (self.kind, self.index, self.vertex):
            self.kind, self.index, self.vertex = kind, index, vertex
            self.changed.emit()


class ProjectDocument(QObject):
    """The open project: data, validation, file, undo stack and selection.

    Signals
    -------
    changed(frozenset)
        The data changed; the argument names the top-level sections that differ
        (``"materials"``, ``"bodies"``, ...). Emitted after :attr:`problems` is up to date.
    pathChanged()
        The file the document belongs to changed (Save As, Open, New).
    cleanChanged(bool)
        Whether the document equals the saved file (the undo stack's clean state).
    """

    changed = Signal(object)
    pathChanged = Signal()
    cleanChanged = Signal(bool)

    def __init__(self, data: Mapping[str, Any] | None = None, path: str | os.PathLike[str] | None = None,
                 parent: QObject | None = None) -> None:
        super().__init__(parent)
        self.undo_stack = QUndoStack(self)
        self.undo_stack.cleanChanged.connect(self.cleanChanged)
        self.selection = Selection(self)
        self._data: dict[str, Any] = {}
        self.project: Project | None = None
        self.problems: list[Problem] = []
        self.path: Path | None = None
        self._seeded: tuple[Project, Any] | None = None  # (project, its seeded run or the error)
        self.reset(data if data is not None else new_project_data(), path)

    # -- state ------------------------------------------------------------------------------

    @property
    def data(self) -> dict[str, Any]:
        """The project data; treat as read-only (edit through :meth:`edit`)."""
        return self._data

    def get(self, path: str, default: Any = None) -> Any:
        return get_path(self._data, path, default)

    @property
    def is_dirty(self) -> bool:
        return not self.undo_stack.isClean()

    @property
    def display_name(self) -> str:
        return self.path.name if self.path is not None else "untitled.toml"

    @property
    def material_names(self) -> list[str]:
        return list(self._data.get("materials", {}))

    def unknown_keys(self) -> list[str]:
        """Key paths the schema does not know (typos in a file), as its problems name them."""
        return [p.path for p in self.problems if p.path and p.message.startswith("unknown key")]

    def remove_unknown_keys(self) -> list[str]:
        """Remove every unknown key (one undo step); the paths removed."""
        paths = self.unknown_keys()
        if paths:
            self.edit("remove unknown keys", lambda d: [set_path(d, path, None) for path in paths])
        return paths

    def problems_at(self, prefix: str) -> list[Problem]:
        """Problems whose key path is ``prefix`` or below it."""
        return [p for p in self.problems if p.path == prefix or p.path.startswith(prefix + ".")]

    def seeded_run(self) -> Any:
        """The run the valid project stands for, its particles seeded as ``runout run`` seeds them
        (:func:`projects.build.resolve`: overrides, preset and all). Kept until the project
        changes, so that the particle preview and the Run panel's count share one seeding.

        Returns
        -------
        projects.build.ResolvedRun

        Raises
        ------
        ProjectError, ValueError, ArithmeticError
            As :func:`projects.build.resolve` (a body that receives no particles); ValueError
            while the project has problems.
        """
        project = self.project
        if project is None:
            raise ValueError("the project has problems")
        if self._seeded is None or self._seeded[0] is not project:
            from projects.build import resolve

            try:
                outcome: Any = resolve(project, seed=True)
            except (ProjectError, ValueError, ArithmeticError) as err:
                outcome = err
            self._seeded = (project, outcome)
        outcome = self._seeded[1]
        if isinstance(outcome, Exception):
            raise outcome
        return outcome

    # -- files ------------------------------------------------------------------------------

    def reset(self, data: Mapping[str, Any], path: str | os.PathLike[str] | None = None) -> None:
        """Replace the whole document (New, Open): clears undo history and selection."""
        self.undo_stack.clear()
        self.path = Path(path).absolute() if path is not None else None
        self.selection.set(None)
        self._apply(copy.deepcopy(dict(data)))
        self.undo_stack.setClean()
        self.pathChanged.emit()
        self.cleanChanged.emit(True)

    def open(self, path: str | os.PathLike[str], *, allow_problems: bool = False) -> None:
        """Read a project file into the document.

        Raises
        ------
        ProjectError
            When the file cannot be read or is invalid (with ``allow_problems``: only when it
            cannot be read or its structure is too broken to edit; other problems are then kept
            in :attr:`problems`).
        """
        path = Path(path)
        try:
            text = path.read_text(encoding="utf-8")
        except OSError as exc:
            raise ProjectError([Problem("", None, f"cannot read the file: {exc.strerror or exc}")], str(path)) from None
        except UnicodeDecodeError as exc:
            raise ProjectError([Problem("", None, f"not UTF-8 text: {exc.reason}")], str(path)) from None
        try:
            project = loads_project(text, source=str(path))
        except ProjectError:
            if not allow_problems:
                raise
            data = editable_data(parse_toml(text, str(path)))
            if data is None:
                raise
            self.reset(data, path)
            return
        self.reset(project.to_dict(), path)

    def save(self, path: str | os.PathLike[str] | None = None, *, force: bool = False) -> Path:
        """Write the project (atomically) to ``path`` or its own file and mark it clean.

        An invalid project is written only with ``force`` (as plain TOML of what is there),
        otherwise ProjectError lists its problems.
        """
        target = Path(path).absolute() if path is not None else self.path
        if target is None:
            raise ValueError("the project has no file yet: give a path")
        if self.project is not None:
            save_project(self.project, target)
        elif force:
            import tomlkit

            from projects.atomic import write_atomic

            write_atomic(target, tomlkit.dumps(self._data), durable=True, follow_links=True)
        else:
            raise ProjectError(self.problems, str(target))
        if target != self.path:
            self.path = target
            self.pathChanged.emit()
        self.undo_stack.setClean()
        logger.info("saved %s", target)
        return target

    def text(self) -> str:
        """The project as TOML text (the valid project's layout when valid)."""
        if self.project is not None:
            return dumps_project(self.project)
        import tomlkit

        return tomlkit.dumps(self._data)

    # -- edits ------------------------------------------------------------------------------

    def edit(self, text: str, mutate: Callable[[dict[str, Any]], None], merge_key: str | None = None) -> bool:
        """Apply ``mutate`` to a copy of the data as one undoable step.

        Parameters
        ----------
        text : str
            What the step does, for the Edit menu ("Undo change cohesion").
        mutate : callable
            Changes the copy in place.
        merge_key : str, optional
            Consecutive edits with the same key become one undo step.

        Returns
        -------
        bool
            False when ``mutate`` changed nothing (no step is recorded).
        """
        after = copy.deepcopy(self._data)
        mutate(after)
        if after == self._data:
            return False
        self.undo_stack.push(SnapshotCommand(self, copy.deepcopy(self._data), after, text, merge_key))
        return True

    def set_value(self, path: str, value: Any, text: str | None = None, merge_key: str | None = None) -> bool:
        """Set one key (None removes it) as one undoable step."""
        label = text or f"set {path}"
        return self.edit(label, lambda d: set_path(d, path, value), merge_key)

    def rename_material(self, old: str, new: str) -> bool:
        """Rename a material, keeping its place (its id) and renaming its uses."""
        if old == new or new in self._data.get("materials", {}):
            return False

        def mutate(d: dict[str, Any]) -> None:
            d["materials"] = {(new if k == old else k): v for k, v in d["materials"].items()}
            for body in d.get("bodies", []):
                if body.get("material") == old:
                    body["material"] = new
            for stage in d.get("stages", []):
                changes = stage.get("material_changes")
                if isinstance(changes, dict) and old in changes:
                    stage["material_changes"] = {(new if k == old else k): v for k, v in changes.items()}

        return self.edit(f"rename material {old} to {new}", mutate)

    def _apply(self, data: dict[str, Any]) -> None:
        old = self._data
        self._data = copy.deepcopy(data)
        sections = frozenset(k for k in set(old) | set(data) if old.get(k) != data.get(k))
        try:
            self.project = validate_project(self._data)
            self.problems = []
        except ProjectError as exc:
            self.project = None
            self.problems = list(exc.problems)
        self._clamp_selection()
        self.changed.emit(sections)

    def _clamp_selection(self) -> None:
        sel = self.selection
        if sel.kind == "water":
            line = get_path(self._data, water_line_path(sel.index)) if sel.index is not None else None
            if not isinstance(line, list):
                sel.select("water", None)
            elif sel.vertex is not None and sel.vertex >= len(line):
                sel.select("water", sel.index, len(line) - 1 if line else None)
            return
        items = self._data.get(sel.kind, [])
        items = items if isinstance(items, list) else []
        index, vertex = sel.index, sel.vertex
        if index is not None and index >= len(items):
            sel.select(sel.kind, len(items) - 1 if items else None)
        elif index is not None and vertex is not None:
            count = len(items[index].get("polygon_m", []) or [])
            if vertex >= count:
                sel.select(sel.kind, index, count - 1 if count else None)
