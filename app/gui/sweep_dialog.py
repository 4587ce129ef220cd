"""The Sweep dialog (Run ▸ Sweep or calibration): a sweep or calibration file built from the open
project (docs/sweeps.md, docs/project-format.md "Sweep files").

The parameters are picked by dotted key from the project's numeric keys (the ``--set`` paths,
e.g. ``materials.sand.friction_angle_deg``), each with a distribution and its values; the
sampling, number of runs, seed, the measures and the probability profile (sweep), or the
observation, trials and optimiser (calibration). The file is validated by
:func:`sweeps.spec.parse_spec` (the same rules and messages as ``runout sweep``) before it is
written; the open project is written beside it (as it is in the window, saved or not) and is the
sweep's base project.

Folder written on *Start* (``OUT``)::

    OUT/sweep.toml          the sweep or calibration file (``project = "base_project.toml"``)
    OUT/base_project.toml   the open project
    OUT/...                 what ``runout sweep`` writes there (sweep.csv, runs/, ...)
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from PySide6.QtCore import Qt
from PySide6.QtWidgets import (
    QComboBox,
    QDialog,
    QDialogButtonBox,
    QFileDialog,
    QFormLayout,
    QGroupBox,
    QHBoxLayout,
    QHeaderView,
    QLabel,
    QLineEdit,
    QListWidget,
    QListWidgetItem,
    QPushButton,
    QSpinBox,
    QTableWidget,
    QTableWidgetItem,
    QVBoxLayout,
    QWidget,
)

SPEC_FILE = "sweep.toml"
BASE_PROJECT = "base_project.toml"

#: What the "Values" cell holds for each distribution (comma-separated numbers).
VALUE_FORMS: dict[str, tuple[str, ...]] = {
    "list": (),  # any number of values
    "range": ("low", "high", "count"),
    "uniform": ("low", "high"),
    "normal": ("mean", "std", "low", "high"),
    "lognormal": ("mean_log", "std_log", "low", "high"),
}
#: How many of VALUE_FORMS' numbers are required.
REQUIRED = {"list": 1, "range": 3, "uniform": 2, "normal": 2, "lognormal": 2}

#: Measures offered with a tick box (any other key may be typed).
COMMON_MEASURES: tuple[str, ...] = (
    "hazard.runout_distance_m",
    "hazard.travel_angle_deg",
    "hazard.h_over_l",
    "hazard.max_flow_height_m",
    "hazard.max_speed_m_s",
    "hazard.max_pressure_pa",
    "deposit.front_m",
    "deposit.height_m",
    "summary.factor_of_safety.value",
    "summary.wall_time_s",
)
DEFAULT_MEASURES = ("hazard.runout_distance_m", "hazard.travel_angle_deg", "summary.wall_time_s")
PROFILE_FIELDS = ("peak_flow_height_m", "max_pressure_pa", "max_speed_m_s", "deposit_height_m", "deposit_m")


def numeric_keys(data: Any, prefix: str = "") -> dict[str, float]:
    """Every numeric scalar of a project's data by its dotted key (list items by index), body
    vertices left out: the keys a sweep can vary."""
    out: dict[str, float] = {}
    if isinstance(data, Mapping):
        items = list(data.items())
    elif isinstance(data, list):
        items = list(enumerate(data))
    else:
        return out
    for key, value in items:
        path = f"{prefix}.{key}" if prefix else str(key)
        if key == "polygon_m" or path.startswith("runout."):
            continue
        if isinstance(value, bool):
            continue
        if isinstance(value, (int, float)):
            out[path] = float(value)
        elif isinstance(value, (Mapping, list)):
            out.update(numeric_keys(value, path))
    return out


class SpecInputError(ValueError):
    """A cell of the dialog that is not a number list of the form its distribution needs."""


def _numbers(text: str, where: str) -> list[float]:
    parts = [p for p in text.replace(";", ",").split(",") if p.strip()]
    out = []
    for p in parts:
        try:
            out.append(float(p))
        except ValueError:
            raise SpecInputError(f"{where}: {p.strip()!r} is not a number") from None
    return out


def parameter_table(key: str, distribution: str, values: str, also: str = "") -> dict[str, Any]:
    """The ``[parameters."KEY"]`` table of one dialog row.

    ``values``: comma-separated numbers, as :data:`VALUE_FORMS` names them for ``distribution``
    (list: the values; range: low, high, count; uniform: low, high; normal: mean, std and optional
    low, high; lognormal: mean_log, std_log and optional low, high).

    Raises
    ------
    SpecInputError
        A value that is not a number, or too few or too many of them (one line naming the key).
    """
    where = f'parameters."{key}" ({distribution})'
    nums = _numbers(values, where)
    form = VALUE_FORMS[distribution]
    if len(nums) < REQUIRED[distribution] or (form and len(nums) > len(form)):
        wanted = "one or more values" if not form else ", ".join(form[:REQUIRED[distribution]]) + (
            f" (and optionally {', '.join(form[REQUIRED[distribution]:])})" if len(form) > REQUIRED[distribution] else "")
        raise SpecInputError(f"{where}: needs {wanted}; got {values.strip() or 'nothing'!r}")
    table: dict[str, Any] = {"distribution": distribution}
    if distribution == "list":
        table["values"] = nums
    else:
        for name, v in zip(form, nums):
            table[name] = int(v) if name == "count" else v
    extra = [k.strip() for k in also.split(",") if k.strip()]
    if extra:
        table["also"] = extra
    return table


def default_values(distribution: str, current: float | None) -> str:
    """A starting "Values" text around a key's current value (±10 %)."""
    c = 1.0 if current is None or not math.isfinite(current) else current
    d = abs(c) * 0.1 or 1.0
    g = "{:.6g}".format
    return {
        "list": f"{g(c - d)}, {g(c)}, {g(c + d)}",
        "range": f"{g(c - d)}, {g(c + d)}, 3",
        "uniform": f"{g(c - d)}, {g(c + d)}",
        "normal": f"{g(c)}, {g(d / 2)}",
        "lognormal": f"{g(math.log(abs(c) or 1.0))}, 0.1",
    }[distribution]


class SweepDialog(QDialog):
    """Define a sweep or a calibration of the open project.

    After ``exec()`` returned Accepted, :attr:`spec_path` is the validated file and
    :attr:`out_dir` the folder to run it into.
    """

    def __init__(self, doc: Any, out_dir: Path, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setWindowTitle("Sweep or calibration")
        self.resize(900, 720)
        self.doc = doc
        self.keys = numeric_keys(doc.data)
        self.spec_path: Path | None = None
        self.out_dir: Path = Path(out_dir)

        self.kind = QComboBox()
        self.kind.addItems(["sweep", "calibration"])
        self.kind.setToolTip("A sweep samples the parameters (Monte Carlo, parameter study); a calibration "
                             "searches the values that best reproduce an observation")
        # parameters
        self.params = QTableWidget(0, 4)
        self.params.setHorizontalHeaderLabels(["Key (dotted)", "Distribution", "Values", "Also set (keys)"])
        self.params.horizontalHeader().setSectionResizeMode(0, QHeaderView.ResizeMode.Stretch)
        self.params.horizontalHeader().setSectionResizeMode(2, QHeaderView.ResizeMode.Stretch)
        self.params.verticalHeader().setVisible(False)
        self.params.setToolTip("Values, comma-separated: list: the values; range: low, high, count; "
                               "uniform: low, high; normal: mean, std[, low, high]; "
                               "lognormal: mean_log, std_log[, low, high]")
        add = QPushButton("Add parameter")
        remove = QPushButton("Remove")
        add.clicked.connect(lambda: self.add_parameter())
        remove.clicked.connect(self._remove_parameter)
        pbuttons = QHBoxLayout()
        pbuttons.addWidget(add)
        pbuttons.addWidget(remove)
        pbuttons.addStretch(1)
        pbox = QGroupBox("Parameters")
        pl = QVBoxLayout(pbox)
        pl.addWidget(self.params)
        pl.addLayout(pbuttons)
        # two lines, not word-wrapped: a wrapped label's height depends on its width, and the
        # dialog's layout then gave the Sweep box less than its height (the measures list ran
        # under the fields below it)
        self.hint = QLabel("Values, comma-separated: list: the values; range: low, high, count; uniform: low, high;\n"
                           "normal: mean, std[, low, high]; lognormal: mean_log, std_log[, low, high]")
        self.hint.setStyleSheet("color: #5f6368; font-size: 11px;")
        pl.addWidget(self.hint)

        self.fixed = QLineEdit('numerics.arch="cpu"')
        self.fixed.setToolTip('Fixed overrides for every run (--set), separated by ";", e.g. numerics.preset="draft"')

        # sweep
        self.sweep_box = QGroupBox("Sweep")
        self.sampling = QComboBox()
        self.sampling.addItems(["latin-hypercube", "random", "grid"])
        from sweeps.spec import MAX_RUNS

        self.runs = QSpinBox()
        self.runs.setRange(1, MAX_RUNS)  # a sweep file's limit (sweeps.spec)
        self.runs.setValue(8)
        #: what the sampling runs: a grid's run count (the product of the levels)
        self.runs_note = QLabel("")
        self.runs_note.setStyleSheet("color: #5f6368;")
        self.sampling.currentTextChanged.connect(lambda _t: self._update_runs())
        self.params.itemChanged.connect(lambda _item: self._discrete_sampling())
        self.seed = QSpinBox()
        self.seed.setRange(0, 2**31 - 1)
        self.measures = QListWidget()
        for m in COMMON_MEASURES:
            item = QListWidgetItem(m)
            item.setFlags(item.flags() | Qt.ItemFlag.ItemIsUserCheckable)
            item.setCheckState(Qt.CheckState.Checked if m in DEFAULT_MEASURES else Qt.CheckState.Unchecked)
            self.measures.addItem(item)
        self.measures.setMinimumHeight(120)
        self.more_measures = QLineEdit()
        self.more_measures.setPlaceholderText("more measure keys, comma-separated (hazard.targets.house.arrival_time_s)")
        self.profile_field = QComboBox()
        self.profile_field.addItems(["(none)", *PROFILE_FIELDS])
        self.profile_field.setCurrentText("peak_flow_height_m")
        self.thresholds = QLineEdit("0.05")
        self.thresholds.setToolTip("P(field > threshold) along the section, per threshold (comma-separated)")
        sf = QFormLayout(self.sweep_box)
        sf.addRow("Sampling", self.sampling)
        runs_row = QHBoxLayout()
        runs_row.addWidget(self.runs, 1)
        runs_row.addWidget(self.runs_note, 2)
        sf.addRow("Runs", runs_row)
        sf.addRow("Seed", self.seed)
        sf.addRow("Measures", self.measures)
        sf.addRow("", self.more_measures)
        sf.addRow("Probability profile of", self.profile_field)
        sf.addRow("Thresholds", self.thresholds)

        # calibration
        self.cal_box = QGroupBox("Calibration")
        self.observation = QComboBox()
        self.observation.addItems(["deposit-profile", "measures"])
        self.obs_file = QLineEdit()
        self.obs_file.setPlaceholderText("CSV of x_m, y_m (the mapped final surface)")
        browse = QPushButton("…")
        browse.clicked.connect(self._browse_observation)
        row = QHBoxLayout()
        row.addWidget(self.obs_file, 1)
        row.addWidget(browse)
        file_row = QWidget()
        file_row.setLayout(row)
        row.setContentsMargins(0, 0, 0, 0)
        self.x_range = QLineEdit()
        self.x_range.setPlaceholderText("optional: low, high (m)")
        self.obs_values = QLineEdit()
        self.obs_values.setPlaceholderText("hazard.runout_distance_m = 12.5, hazard.travel_angle_deg = 24")
        self.trials = QSpinBox()
        self.trials.setRange(1, 10000)
        self.trials.setValue(16)
        self.optimizer = QComboBox()
        self.optimizer.addItems(["tpe", "random"])
        cf = QFormLayout(self.cal_box)
        cf.addRow("Observation", self.observation)
        cf.addRow("File", file_row)
        cf.addRow("x range", self.x_range)
        cf.addRow("Observed values", self.obs_values)
        cf.addRow("Trials", self.trials)
        cf.addRow("Optimiser", self.optimizer)

        # where and how
        self.out = QLineEdit(str(self.out_dir))
        out_browse = QPushButton("…")
        out_browse.clicked.connect(self._browse_out)
        orow = QHBoxLayout()
        orow.addWidget(self.out, 1)
        orow.addWidget(out_browse)
        self.workers_box = QSpinBox()
        self.workers_box.setRange(0, 1024)
        self.workers_box.setSpecialValueText("one per core")
        self.workers_box.setValue(0)
        form = QFormLayout()
        form.addRow("Kind", self.kind)
        form.addRow("Fixed overrides", self.fixed)
        form.addRow("Folder", orow)
        form.addRow("Workers", self.workers_box)

        self.error = QLabel("")
        self.error.setWordWrap(True)
        self.error.setStyleSheet("color: #c5221f;")
        buttons = QDialogButtonBox(QDialogButtonBox.StandardButton.Cancel)
        self.start_button = buttons.addButton("Start", QDialogButtonBox.ButtonRole.AcceptRole)
        buttons.accepted.connect(self.accept)
        buttons.rejected.connect(self.reject)
        layout = QVBoxLayout(self)
        layout.addLayout(form)
        layout.addWidget(pbox, 2)
        layout.addWidget(self.sweep_box)
        layout.addWidget(self.cal_box)
        layout.addWidget(self.error)
        layout.addWidget(buttons)
        self.kind.currentTextChanged.connect(self._kind_changed)
        self._kind_changed(self.kind.currentText())
        first = next((k for k in self.keys if k.endswith("friction_angle_deg")), next(iter(self.keys), ""))
        if first:
            self.add_parameter(first, "uniform")

    # -- rows ---------------------------------------------------------------------------------------

    def add_parameter(self, key: str = "", distribution: str = "uniform", values: str | None = None,
                      also: str = "") -> int:
        """Add a parameter row; ``values`` defaults to ±10 % around the key's current value."""
        r = self.params.rowCount()
        self.params.insertRow(r)
        keys = QComboBox()
        keys.setEditable(True)
        keys.addItems(sorted(self.keys))
        keys.setCurrentText(key)
        keys.setToolTip("A numeric key of the project (or any --set path)")
        dist = QComboBox()
        dist.addItems(list(VALUE_FORMS))
        dist.setCurrentText(distribution)
        self.params.setCellWidget(r, 0, keys)
        self.params.setCellWidget(r, 1, dist)
        self.params.setItem(r, 2, QTableWidgetItem(values if values is not None
                                                   else default_values(distribution, self.keys.get(key))))
        self.params.setItem(r, 3, QTableWidgetItem(also))

        def refill(_text: str, row_keys: QComboBox = keys, row_dist: QComboBox = dist) -> None:
            row = next(i for i in range(self.params.rowCount()) if self.params.cellWidget(i, 0) is row_keys)
            self.params.item(row, 2).setText(default_values(row_dist.currentText(),
                                                            self.keys.get(row_keys.currentText())))

        keys.currentTextChanged.connect(refill)
        dist.currentTextChanged.connect(refill)
        dist.currentTextChanged.connect(lambda _t: self._discrete_sampling())
        self._update_runs()
        return r

    def _levels(self) -> list[int] | None:
        """Each parameter's number of levels where every one is a ``list`` or a ``range`` (None
        where one is continuous or its values do not read)."""
        counts = []
        for r in range(self.params.rowCount()):
            dist = self.params.cellWidget(r, 1).currentText()
            item = self.params.item(r, 2)
            try:
                values = _numbers(item.text() if item else "", "values")
            except SpecInputError:
                return None
            if dist == "list" and values:
                counts.append(len(values))
            elif dist == "range" and len(values) == 3 and values[2] >= 1 and float(values[2]).is_integer():
                counts.append(int(values[2]))
            else:
                return None
        return counts or None

    def _discrete_sampling(self) -> None:
        """Parameters that are all lists or ranges are a grid: a Latin hypercube or random draw of
        8 runs from 3 values repeats runs (the solver is deterministic) and leaves values out."""
        if self._levels() is not None and self.sampling.currentText() != "grid":
            self.sampling.setCurrentText("grid")
        self._update_runs()

    def _update_runs(self) -> None:
        grid = self.sampling.currentText() == "grid"
        self.runs.setEnabled(not grid)
        if not grid:
            self.runs_note.setText("")
            return
        levels = self._levels()
        if levels is None:
            self.runs_note.setText("grid: every combination of the levels")
            return
        self.runs_note.setText(f"grid: {math.prod(levels):,} runs (every combination of the levels: "
                               f"{' × '.join(str(n) for n in levels)})")

    def _remove_parameter(self) -> None:
        r = self.params.currentRow()
        if r < 0:
            r = self.params.rowCount() - 1
        if r >= 0:
            self.params.removeRow(r)

    def _kind_changed(self, kind: str) -> None:
        self.sweep_box.setVisible(kind == "sweep")
        self.cal_box.setVisible(kind == "calibration")
        self.out.setText(str(Path(self.out.text()).with_suffix(".sweep" if kind == "sweep" else ".calibration")))

    def _browse_observation(self) -> None:
        path, _ = QFileDialog.getOpenFileName(self, "Observation", "", "CSV (*.csv);;All files (*)")
        if path:
            self.obs_file.setText(path)

    def _browse_out(self) -> None:
        path = QFileDialog.getExistingDirectory(self, "Sweep folder", str(Path(self.out.text()).parent))
        if path:
            self.out.setText(path)

    def workers(self) -> int | None:
        return self.workers_box.value() or None

    # -- the file -----------------------------------------------------------------------------------

    def spec_data(self) -> dict[str, Any]:
        """The sweep or calibration file's tables as the dialog stands (not yet validated).

        Raises
        ------
        SpecInputError
            A parameter row whose values are not the numbers its distribution needs.
        """
        kind = self.kind.currentText()
        params: dict[str, Any] = {}
        for r in range(self.params.rowCount()):
            key = self.params.cellWidget(r, 0).currentText().strip()
            if not key:
                raise SpecInputError(f"parameter row {r + 1}: no key")
            dist = self.params.cellWidget(r, 1).currentText()
            params[key] = parameter_table(key, dist, self.params.item(r, 2).text(),
                                          (self.params.item(r, 3).text() if self.params.item(r, 3) else ""))
        fixed = [s.strip() for s in self.fixed.text().split(";") if s.strip()]
        execution: dict[str, Any] = {"project": BASE_PROJECT, "set": fixed}
        if kind == "sweep":
            measures = [self.measures.item(i).text() for i in range(self.measures.count())
                        if self.measures.item(i).checkState() == Qt.CheckState.Checked]
            measures += [m.strip() for m in self.more_measures.text().split(",") if m.strip()]
            table = dict(execution, sampling=self.sampling.currentText(), seed=self.seed.value(),
                         measures=measures)
            if self.sampling.currentText() != "grid" or self.runs.value():
                table["runs"] = self.runs.value()
            if self.sampling.currentText() == "grid":
                table.pop("runs", None)
            data: dict[str, Any] = {"sweep": table, "parameters": params}
            if self.profile_field.currentText() != "(none)":
                data["profile"] = {"field": self.profile_field.currentText(),
                                   "thresholds": _numbers(self.thresholds.text(), "profile.thresholds")}
            return data
        table = dict(execution, trials=self.trials.value(), seed=self.seed.value(),
                     optimizer=self.optimizer.currentText())
        obs: dict[str, Any] = {"type": self.observation.currentText()}
        if obs["type"] == "deposit-profile":
            if self.obs_file.text().strip():
                obs["file"] = str(Path(self.obs_file.text().strip()).expanduser().absolute())
            if self.x_range.text().strip():
                obs["x_range_m"] = _numbers(self.x_range.text(), "observation.x_range_m")
        else:
            values: dict[str, float] = {}
            for part in self.obs_values.text().split(","):
                if not part.strip():
                    continue
                key, sep, value = part.partition("=")
                if not sep:
                    raise SpecInputError(f"observation.values: {part.strip()!r} is not KEY = VALUE")
                values[key.strip()] = _numbers(value, f"observation.values.{key.strip()}")[0] if value.strip() \
                    else math.nan
            obs["values"] = values
        return {"calibration": table, "parameters": params, "observation": obs}

    def validate(self) -> Any:
        """The validated spec (base folder: the chosen folder).

        Raises
        ------
        SpecInputError, projects.schema.ProjectError
        """
        from sweeps.spec import parse_spec

        return parse_spec(self.spec_data(), Path(self.out.text()).expanduser().absolute(),
                          source="the sweep dialog")

    def write(self) -> Path:
        """Validate, then write the file and the open project into the chosen folder.

        Raises
        ------
        SpecInputError, projects.schema.ProjectError, OSError
        """
        from sweeps.spec import save_spec

        spec = self.validate()
        out = Path(self.out.text()).expanduser().absolute()
        out.mkdir(parents=True, exist_ok=True)
        from projects.atomic import write_atomic

        write_atomic(out / BASE_PROJECT, self.doc.text())
        self.spec_path = save_spec(spec, out / SPEC_FILE)
        self.out_dir = out
        return self.spec_path

    def accept(self) -> None:  # noqa: D102 - Qt's name
        from projects.schema import ProjectError

        try:
            self.write()
        except (SpecInputError, ProjectError, OSError) as err:
            self.error.setText(str(err))
            return
        super().accept()
