"""Sweep and calibration files (TOML), validated like a project file.

A sweep file has a ``[sweep]`` table, a calibration file a ``[calibration]`` table; both have
``[parameters]`` (one entry per ``--set`` key path). See docs/project-format.md ("Sweep files")
for every key. Bad input raises :class:`projects.schema.ProjectError` with one line per problem
naming the key path, the value and what is allowed.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Annotated, Any

from pydantic import AfterValidator, BaseModel, BeforeValidator, ConfigDict, ValidationError, model_validator
from pydantic_core import PydanticCustomError

from projects.schema import Problem, ProjectError

#: Distributions of a sweep parameter.
DISTRIBUTIONS = ("list", "range", "uniform", "normal", "lognormal")
#: Sampling schemes of a sweep.
SAMPLINGS = ("grid", "random", "latin-hypercube")
#: Kinds of observation a calibration fits.
OBSERVATIONS = ("deposit-profile", "measures")
#: Built-in profile field computed from each run's last frame (else a column of hazard_profile.csv).
DEPOSIT_PROFILE_FIELD = "deposit_height_m"
#: Where a measure key comes from (sweeps.measures): summary.json, hazard.json or the last frame.
MEASURE_SOURCES = ("summary", "hazard", "deposit")
#: Measures of the last frame's deposit (sweeps.measures).
DEPOSIT_KEYS = ("front_m", "toe_m", "reach_m", "crest_m", "height_m", "max_displacement_m")

# Limits of a sweep or calibration file (docs/project-format.md, "Sweep files"), checked when the
# file is read, before anything is sampled, resolved or started: a sweep of a billion runs, a grid
# of 100,000 levels by 2 parameters or a range of a billion points hung while its runs were made.
#: Runs of a sweep (its runs, or the product of a grid's levels) and trials of a calibration.
MAX_RUNS = 10_000
#: Seeds: numpy's and optuna's generators take 0 to 2**32 - 1 (2**70 hung the command in Ray's logging).
MAX_SEED = 2**32 - 1
#: Parameters of one file, and the entries of any other list in it (set, measures, also, thresholds,
#: observed values).
MAX_PARAMETERS = 64
MAX_ENTRIES = 1000
#: Taichi CPU threads and GPUs one run may ask for, and the longest time limit of a run (s).
MAX_THREADS_PER_RUN = 1024
MAX_GPUS_PER_RUN = 8
MAX_TIMEOUT_S = 1e7


def _fail(message: str) -> PydanticCustomError:
    return PydanticCustomError("runout", message)


def _number(value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise _fail("must be a number")
    try:
        finite = math.isfinite(float(value))
    except OverflowError:  # an integer beyond any float (10**400)
        finite = False
    if not finite:
        raise _fail("must be a finite number")
    return value  # ints stay ints (integer parameters such as particles.per_cell)


def _int(value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise _fail("must be an integer")
    return value


def _choice(choices: tuple[str, ...]):
    allowed = ", ".join(f'"{c}"' for c in choices)

    def check(value: Any) -> Any:
        if not isinstance(value, str) or value not in choices:
            raise _fail(f"must be one of {allowed}")
        return value

    return BeforeValidator(check)


def _scalar_list(value: Any) -> Any:
    if not isinstance(value, (list, tuple)) or not value:
        raise _fail("must be a non-empty array of values")
    if len(value) > MAX_RUNS:
        raise _fail(f"has {len(value):,} values, more than the limit of {MAX_RUNS:,} (a sweep's most runs)")
    for v in value:
        if not isinstance(v, (bool, int, float, str)):
            raise _fail("must be an array of numbers, strings or booleans")
        if isinstance(v, int) and not isinstance(v, bool) and abs(v) > 2**63 - 1:
            raise _fail("must hold integers of at most 64 bits (TOML's)")
        if isinstance(v, float) and not math.isfinite(v):
            raise _fail("must hold finite numbers")
    return list(value)


def _str_list(value: Any) -> Any:
    if not isinstance(value, (list, tuple)) or not all(isinstance(v, str) for v in value):
        raise _fail("must be an array of strings")
    if len(value) > MAX_ENTRIES:
        raise _fail(f"has {len(value):,} entries, more than the limit of {MAX_ENTRIES:,}")
    return list(value)


def _measure_key(value: str) -> str:
    """A measure key: ``summary.KEY``, ``hazard.KEY`` or ``deposit.KEY`` (sweeps.measures)."""
    _key_path(value)
    head, _, rest = value.partition(".")
    if head not in MEASURE_SOURCES:
        raise _fail("not a measure: a measure starts with " + ", ".join(f'"{s}."' for s in MEASURE_SOURCES)
                    + ' (summary.json, hazard.json, the last frame), e.g. "hazard.runout_distance_m"')
    if not rest:
        raise _fail(f'name the key after "{head}.", e.g. "hazard.runout_distance_m"')
    if head == "deposit" and rest not in DEPOSIT_KEYS:
        raise _fail("not a deposit measure; deposit measures: " + ", ".join(f"deposit.{k}" for k in DEPOSIT_KEYS))
    return value


def _run_count(value: Any, name: str, what: str) -> int:
    value = _int(value)
    if value < 1:
        raise _fail(f"{name} must be >= 1")
    if value > MAX_RUNS:
        raise _fail(f"more than the limit of {MAX_RUNS:,} {what}")
    return value


def _seed(value: Any) -> Any:
    value = _int(value)
    if not 0 <= value <= MAX_SEED:
        raise _fail(f"must be an integer from 0 to {MAX_SEED} (2**32 - 1)")
    return value


def _key_path(value: Any) -> Any:
    if not isinstance(value, str) or not value.strip() or any(not p for p in value.split(".")):
        raise _fail("must be a dotted key path such as \"hazard.runout_distance_m\"")
    return value


Number = Annotated[int | float, BeforeValidator(_number)]  # ints stay ints
Int = Annotated[int, BeforeValidator(_int)]
Seed = Annotated[int, BeforeValidator(_seed)]
StrList = Annotated[list[str], BeforeValidator(_str_list)]


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Parameter(_Model):
    """One swept parameter: a ``--set`` key path with values or a distribution.

    ``list``: ``values``; ``range``: ``low``, ``high``, ``count`` (evenly spaced, both ends
    included); ``uniform``: ``low``, ``high``; ``normal``: ``mean``, ``std`` and optional
    truncation ``low``/``high``; ``lognormal``: ``mean_log``, ``std_log`` (of ln X) and optional
    ``low``/``high``. ``levels`` (continuous distributions, grid sampling only): how many
    equal-probability levels the grid takes (the quantiles at (i + 1/2)/levels). ``also``: more
    key paths set to the same value (e.g. the base friction angle with the material's).
    """

    distribution: Annotated[str, _choice(DISTRIBUTIONS)] = "list"
    values: Annotated[list[Any], BeforeValidator(_scalar_list)] | None = None
    low: Number | None = None
    high: Number | None = None
    count: Int | None = None
    mean: Number | None = None
    std: Number | None = None
    mean_log: Number | None = None
    std_log: Number | None = None
    levels: Int | None = None
    also: StrList | None = None

    @model_validator(mode="before")
    @classmethod
    def _shorthand(cls, data: Any) -> Any:
        if isinstance(data, (list, tuple)):  # "key" = [1, 2, 3]
            return {"distribution": "list", "values": data}
        if isinstance(data, Mapping) and "distribution" not in data and "values" not in data:
            raise _fail('needs "values" or a "distribution" ("' + '", "'.join(DISTRIBUTIONS) + '")')
        return data

    @model_validator(mode="after")
    def _keys(self) -> Parameter:
        need = {
            "list": ("values",),
            "range": ("low", "high", "count"),
            "uniform": ("low", "high"),
            "normal": ("mean", "std"),
            "lognormal": ("mean_log", "std_log"),
        }[self.distribution]
        allowed = set(need) | {"distribution", "also"}
        if self.distribution in ("normal", "lognormal"):
            allowed |= {"low", "high"}
        if self.distribution in ("uniform", "normal", "lognormal"):
            allowed |= {"levels"}
        given = {k for k in type(self).model_fields if getattr(self, k) is not None and k != "distribution"}
        missing = [k for k in need if getattr(self, k) is None]
        if missing:
            raise _fail(f'a "{self.distribution}" parameter needs ' + ", ".join(need) + f" (missing: {', '.join(missing)})")
        extra = sorted(given - allowed)
        if extra:
            raise _fail(f'a "{self.distribution}" parameter takes ' + ", ".join(sorted(allowed - {"distribution"}))
                        + f" (not {', '.join(extra)})")
        if self.low is not None and self.high is not None and not self.low < self.high:
            raise _fail(f"low must be < high (got {self.low:g} and {self.high:g})")
        if self.count is not None and self.count < 1:
            raise _fail("count must be >= 1")
        if self.levels is not None and self.levels < 1:
            raise _fail("levels must be >= 1")
        for name in ("count", "levels"):
            v = getattr(self, name)
            if v is not None and v > MAX_RUNS:
                raise _fail(f"{name} = {v:,} is more than the limit of {MAX_RUNS:,} (a sweep's most runs)")
        for name in ("std", "std_log"):
            v = getattr(self, name)
            if v is not None and not v > 0:
                raise _fail(f"{name} must be > 0")
        for key in self.also or []:
            _key_path(key)
        if self.distribution == "lognormal" and self.low is not None and self.low < 0:
            raise _fail("low must be >= 0 for a lognormal parameter")
        return self


def _profile_field(value: Any) -> Any:
    from projects.hazard import PROFILE_COLUMNS

    if not isinstance(value, str) or (value != DEPOSIT_PROFILE_FIELD and value not in PROFILE_COLUMNS):
        raise _fail(f'must be "{DEPOSIT_PROFILE_FIELD}" or a column of hazard_profile.csv: '
                    + ", ".join(f'"{c}"' for c in PROFILE_COLUMNS if c != "x_m"))
    return value


class Profile(_Model):
    """The probability profile: P(field > threshold) along the section, per threshold."""

    field: Annotated[str, BeforeValidator(_profile_field)] = DEPOSIT_PROFILE_FIELD
    thresholds: Annotated[list[float], BeforeValidator(lambda v: _positive_list(v))] = [0.01]


def _positive_list(value: Any) -> Any:
    if not isinstance(value, (list, tuple)) or not value:
        raise _fail("must be a non-empty array of numbers")
    if len(value) > MAX_ENTRIES:
        raise _fail(f"has {len(value):,} entries, more than the limit of {MAX_ENTRIES:,}")
    for v in value:
        _number(v)
    return [float(v) for v in value]


class Execution(_Model):
    """Common keys of ``[sweep]`` and ``[calibration]``: the base project and how runs execute."""

    project: Annotated[str, BeforeValidator(lambda v: _nonempty_str(v))]
    set: StrList = []
    threads_per_run: Int | None = None
    gpus_per_run: Number | None = None
    timeout_s: Number | None = None

    @model_validator(mode="after")
    def _ranges(self) -> Execution:
        if self.threads_per_run is not None and not 1 <= self.threads_per_run <= MAX_THREADS_PER_RUN:
            raise _fail(f"threads_per_run must be from 1 to {MAX_THREADS_PER_RUN}")
        if self.gpus_per_run is not None and not 0 <= self.gpus_per_run <= MAX_GPUS_PER_RUN:
            raise _fail(f"gpus_per_run must be from 0 to {MAX_GPUS_PER_RUN} (a fraction shares a GPU)")
        if self.timeout_s is not None and not 0 < self.timeout_s <= MAX_TIMEOUT_S:
            raise _fail(f"timeout_s must be > 0 and at most {MAX_TIMEOUT_S:g} s")
        return self


def _nonempty_str(value: Any) -> Any:
    if not isinstance(value, str) or not value.strip():
        raise _fail("must be a non-empty string (a path)")
    return value


class SweepTable(Execution):
    sampling: Annotated[str, _choice(SAMPLINGS)] = "latin-hypercube"
    runs: Annotated[int | None, BeforeValidator(lambda v: v if v is None else _run_count(v, "runs", "runs of a sweep"))] = None
    seed: Seed = 0
    measures: Annotated[list[Annotated[str, AfterValidator(_measure_key)]], BeforeValidator(_str_list)] = [
        "summary.wall_time_s"]

    @model_validator(mode="after")
    def _runs(self) -> SweepTable:
        if self.sampling != "grid" and self.runs is None:
            raise _fail(f'runs is required with sampling "{self.sampling}"')
        return self


class Observation(_Model):
    """What a calibration fits.

    ``deposit-profile``: ``file`` (CSV of x and surface height, m), optional ``x_range_m``; the
    misfit is the RMS of simulated minus observed surface height at the observed x (m).
    ``measures``: ``values`` = {measure key = observed value}; the misfit is the RMS of the
    differences (each divided by its ``scales`` entry where given).
    """

    type: Annotated[str, _choice(OBSERVATIONS)]
    file: str | None = None
    x_range_m: Annotated[list[float], BeforeValidator(lambda v: _pair(v))] | None = None
    values: dict[str, Number] | None = None
    scales: dict[str, Number] | None = None

    @model_validator(mode="after")
    def _keys(self) -> Observation:
        if self.type == "deposit-profile":
            if self.file is None:
                raise _fail('a "deposit-profile" observation needs file (CSV of x_m, y_m)')
            if self.values is not None or self.scales is not None:
                raise _fail('a "deposit-profile" observation takes file and x_range_m, not values or scales')
        else:
            if not self.values:
                raise _fail('a "measures" observation needs values = { "hazard.runout_distance_m" = ... }')
            if self.file is not None or self.x_range_m is not None:
                raise _fail('a "measures" observation takes values and scales, not file or x_range_m')
            if len(self.values) > MAX_ENTRIES:
                raise _fail(f"values has {len(self.values):,} entries, more than the limit of {MAX_ENTRIES:,}")
            for k in self.values:
                try:
                    _measure_key(k)
                except PydanticCustomError as err:
                    raise _fail(f'values."{k}": {err.message()}') from None
            for k, v in (self.scales or {}).items():
                if k not in self.values:
                    raise _fail(f"scales.{k}: not one of the observed values")
                if not v > 0:
                    raise _fail(f"scales.{k} must be > 0")
        return self


def _pair(value: Any) -> Any:
    if not isinstance(value, (list, tuple)) or len(value) != 2:
        raise _fail("must be a pair [low, high]")
    lo, hi = (float(_number(v)) for v in value)
    if not lo < hi:
        raise _fail("must be [low, high] with low < high")
    return [lo, hi]


class CalibrationTable(Execution):
    trials: Annotated[int, BeforeValidator(lambda v: _run_count(v, "trials", "runs of a calibration"))] = 16
    seed: Seed = 0
    batch: Int | None = None
    optimizer: Annotated[str, _choice(("tpe", "random"))] = "tpe"

    @model_validator(mode="after")
    def _trials(self) -> CalibrationTable:
        if self.batch is not None and not 1 <= self.batch <= self.trials:
            raise _fail(f"batch must be from 1 to trials ({self.trials})")
        return self


class SweepSpec(_Model):
    """A validated sweep file; ``base`` is the folder relative paths are read from."""

    sweep: SweepTable
    parameters: Annotated[dict[str, Parameter], BeforeValidator(lambda v: _few_parameters(v))]
    profile: Profile | None = None
    base: Path = Path(".")

    @model_validator(mode="after")
    def _params(self) -> SweepSpec:
        if not self.parameters:
            raise _fail("parameters: needs at least one parameter")
        for key in self.parameters:
            _key_path(key)
        if self.sweep.sampling == "grid":
            runs = grid_runs(self.parameters)
            if runs > MAX_RUNS:
                sizes = " x ".join(f"{n:,}" for n in (_level_count(p) for p in self.parameters.values()))
                raise _fail(f"parameters: the grid has {runs:,} runs (the product of the levels: {sizes}), more than the limit "
                            f"of {MAX_RUNS:,} runs of a sweep")
        return self

    @property
    def project_path(self) -> Path:
        return (self.base / self.sweep.project).resolve()

    @property
    def linked(self) -> dict[str, list[str]]:
        """Parameter key -> the other key paths set to its value (``also``)."""
        return {k: list(p.also or []) for k, p in self.parameters.items() if p.also}


def _few_parameters(value: Any) -> Any:
    if isinstance(value, Mapping) and len(value) > MAX_PARAMETERS:
        raise _fail(f"has {len(value):,} parameters, more than the limit of {MAX_PARAMETERS}")
    return value


def _level_count(p: Parameter) -> int:
    """How many levels a grid takes of a parameter (1 for a continuous one without ``levels``,
    which sampling names as a problem of its own)."""
    if p.distribution == "list":
        return len(p.values or [])
    if p.distribution == "range":
        return int(p.count or 1)
    return int(p.levels or 1)


def grid_runs(parameters: Mapping[str, Parameter]) -> int:
    """The runs of a grid over ``parameters``: the product of their level counts (exact, no float)."""
    return math.prod(_level_count(p) for p in parameters.values())


class CalibrationSpec(_Model):
    """A validated calibration file (see :class:`Observation`); ``base`` as for SweepSpec."""

    calibration: CalibrationTable
    parameters: Annotated[dict[str, Parameter], BeforeValidator(lambda v: _few_parameters(v))]
    observation: Observation
    base: Path = Path(".")

    @model_validator(mode="after")
    def _params(self) -> CalibrationSpec:
        if not self.parameters:
            raise _fail("parameters: needs at least one parameter")
        for key, p in self.parameters.items():
            _key_path(key)
            if p.distribution not in ("list", "uniform", "range"):
                raise _fail(f'parameters."{key}": a calibration searches "uniform" (low, high), "range" or '
                            f'"list" parameters, not "{p.distribution}"')
        return self

    @property
    def project_path(self) -> Path:
        return (self.base / self.calibration.project).resolve()

    @property
    def linked(self) -> dict[str, list[str]]:
        """Parameter key -> the other key paths set to its value (``also``)."""
        return {k: list(p.also or []) for k, p in self.parameters.items() if p.also}

    @property
    def observation_path(self) -> Path | None:
        f = self.observation.file
        return None if f is None else (self.base / f).resolve()


# --------------------------------------------------------------------------------------------
# loading


def _path_text(loc: tuple[Any, ...]) -> str:
    parts = []
    for part in loc:
        text = str(part)
        parts.append(f'"{text}"' if "." in text else text)
    return ".".join(parts)


def _problems(exc: ValidationError, data: Mapping[str, Any]) -> list[Problem]:
    problems = []
    for error in exc.errors(include_url=False):
        loc = tuple(p for p in error["loc"] if p != "[key]" and not (isinstance(p, str) and "function-" in p))
        # drop pydantic's union/validator tags such as 'list[any]'
        loc = tuple(p for p in loc if not (isinstance(p, str) and ("[" in p and "]" in p and p not in data)))
        path = _path_text(loc)
        value = error.get("input")
        if isinstance(value, Mapping) or error["type"] in ("missing", "extra_forbidden"):
            value = None
        kind = error["type"]
        if kind == "runout":
            message = error["msg"]
        elif kind == "missing":
            message = "required key is missing"
        elif kind == "extra_forbidden":
            message = "unknown key; allowed: " + ", ".join(_allowed(loc[:-1], data))
        elif kind in ("model_type", "dict_type", "model_attributes_type"):
            message = "must be a table"
        elif kind == "string_type":
            message = "must be a string"
        else:
            message = error["msg"]
        problems.append(Problem(path, value, message))
    return problems


def _allowed(loc: tuple[Any, ...], data: Mapping[str, Any]) -> list[str]:
    top = SweepSpec if "sweep" in data else CalibrationSpec
    tables: dict[str, type[BaseModel]] = {
        "sweep": SweepTable, "calibration": CalibrationTable, "profile": Profile, "observation": Observation,
    }
    if not loc:
        return [k for k in top.model_fields if k != "base"]
    if len(loc) == 1 and loc[0] in tables:
        return list(tables[loc[0]].model_fields)
    if len(loc) == 2 and loc[0] == "parameters":
        return list(Parameter.model_fields)
    return []


def parse_spec(data: Mapping[str, Any], base: Path, source: str | None = None) -> SweepSpec | CalibrationSpec:
    """Validate parsed TOML data into a :class:`SweepSpec` or :class:`CalibrationSpec`.

    Raises
    ------
    ProjectError
        One problem per thing wrong (key path, value, what is allowed).
    """
    if not isinstance(data, Mapping):
        raise ProjectError([Problem("", None, "a sweep file must be a TOML table")], source)
    kinds = [k for k in ("sweep", "calibration") if k in data]
    if len(kinds) != 1:
        raise ProjectError([Problem("", None, "a sweep file needs exactly one of the tables [sweep] or "
                                    "[calibration]" + (f"; found {', '.join(kinds)}" if kinds else ""))], source)
    model = SweepSpec if kinds[0] == "sweep" else CalibrationSpec
    try:
        return model.model_validate({**data, "base": base})
    except ValidationError as exc:
        raise ProjectError(_problems(exc, data), source) from None


def load_spec(path: str | os.PathLike[str]) -> SweepSpec | CalibrationSpec:
    """Read and validate a sweep or calibration file; relative paths in it are read from its folder.

    Raises
    ------
    ProjectError
        On a missing file, TOML syntax errors (with line and column) and every invalid key.
    """
    from projects.document import parse_toml

    from projects.inputs import MAX_SPEC_FILE_BYTES, read_text

    p = Path(path)
    # a regular file of at most MAX_SPEC_FILE_BYTES (a FIFO or /dev/zero would hang)
    text = read_text(p, what="the sweep file", max_bytes=MAX_SPEC_FILE_BYTES)
    if text.startswith("\ufeff"):
        text = text[1:]
    data = parse_toml(text, source=str(p))
    return parse_spec(data, p.resolve().parent, source=str(p))


def dumps_spec(spec: SweepSpec | CalibrationSpec) -> str:
    """TOML text of a validated spec (relative paths kept as given; ``base`` left out).

    ``load_spec`` of the text saved next to the same base folder gives an equal spec.
    """
    import tomlkit

    data = spec.model_dump(exclude_none=True, exclude={"base"})
    doc = tomlkit.document()
    for table, values in data.items():
        if table == "parameters":
            params = tomlkit.table(is_super_table=True)
            for key, p in values.items():
                t = tomlkit.table()
                for k, v in p.items():
                    t.add(k, v)
                params.add(key, t)
            doc.add("parameters", params)
        else:
            doc.add(table, values)
    return tomlkit.dumps(doc)


def save_spec(spec: SweepSpec | CalibrationSpec, path: str | os.PathLike[str]) -> Path:
    """Write a spec as a TOML file (atomically), e.g. from the workbench's sweep dialog."""
    from projects.atomic import write_atomic

    p = Path(path)
    write_atomic(p, dumps_spec(spec))
    return p


def command_line(spec_path: str | os.PathLike[str], out_dir: str | os.PathLike[str], *, workers: int | None = None,
                 address: str | None = None) -> list[str]:
    """The process to start for a sweep or calibration file (``runout sweep``/``calibrate``).

    The workbench starts this as a process of its own (it never imports Ray or Taichi) and follows
    ``progress.json`` and ``sweep.csv`` (:func:`sweeps.folder.read_sweep`) in ``out_dir``.
    """
    kind = "calibrate" if "calibration" in load_spec(spec_path).model_fields_set else "sweep"
    from projects.runner import runout_command

    cmd = runout_command(kind, str(spec_path), "--out", str(out_dir))
    if workers is not None:
        cmd += ["--workers", str(workers)]
    if address is not None:
        cmd += ["--address", address]
    return cmd
