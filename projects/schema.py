"""The project document, schema version 2: typed models and validation with readable errors.

A project file (TOML, SI units, angles in degrees) is validated into a :class:`Project`. Every
problem found is reported at once as a :class:`Problem` naming the key path (dotted, list
indices as integers, the same syntax as ``--set``), the offending value and what is allowed,
collected in one :class:`ProjectError`. The message texts are part of the interface: tests
compare them verbatim, so change them deliberately.

Validation runs in two passes over the same input:

1. the pydantic models check structure, types, unknown keys and each value on its own
   (ranges, choices, polygon simplicity);
2. :func:`_rule_problems` checks rules that involve several keys (bodies name existing
   materials, polygons lie inside the domain, stage order, model-dependent keys, ...). It
   reads the raw input tolerantly, so it runs even when pass 1 failed and both sets of
   problems are reported together.

``docs/project-format.md`` documents every key; keep it in step with this module.
"""

from __future__ import annotations

import json
import logging
import math
import re
import types
import typing
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import (
    AfterValidator,
    BaseModel,
    BeforeValidator,
    ConfigDict,
    ValidationError,
    ValidationInfo,
    model_validator,
)
from pydantic_core import PydanticCustomError

from geometry.polygons import distinct_vertex_count, edge_text, has_zero_area, self_intersections
from projects.units import QuantityError, parse_quantity
from solver import config as sc

logger = logging.getLogger(__name__)

#: The schema version this module writes.
SCHEMA_VERSION = 2
#: The versions it reads: a version 1 file (no [water], no saturated densities) reads unchanged.
READABLE_SCHEMA_VERSIONS: tuple[int, ...] = (1, 2)

# The solver's vocabularies are the file's: written once, in solver/config.py.
MATERIAL_MODELS = sc.MATERIAL_MODELS
#: How a Drucker-Prager material's cone is matched to its c, phi and psi (docs/solver.md).
MOHR_COULOMB_MATCHES = sc.MOHR_COULOMB_MATCHES
DAMPING_MODELS = sc.DAMPING_MODELS
DEFAULT_DAMPING_MODEL = sc.DEFAULT_DAMPING_MODEL
DEFAULT_MOHR_COULOMB_MATCH = sc.DEFAULT_MOHR_COULOMB_MATCH
BOUNDARY_TYPES = sc.BOUNDARY_KINDS
#: Contact types of a structure (a side's, less "open" and "periodic").
CONTACT_TYPES: tuple[str, ...] = tuple(k for k in sc.BOUNDARY_KINDS if k not in ("open", "periodic"))
SIDES = sc.SIDES
SEEDINGS: tuple[str, ...] = ("lattice", "gauss")
SCHEMES = sc.SCHEMES
PRECISIONS = sc.PRECISIONS
ARCHS = sc.ARCHS
GUARD_MODES = sc.GUARD_MODES
SCATTERS = sc.SCATTERS
VOLUMETRIC_AVERAGING = sc.VOLUMETRIC_AVERAGING
#: Accuracy/cost presets measured by ``runout study tradeoff`` (projects/presets.json).
PRESETS: tuple[str, ...] = ("draft", "standard", "fine")
STAGE_TYPES: tuple[str, ...] = ("k0", "gravity", "dynamic", "strength-reduction")
#: ``first_trial`` of a strength-reduction stage may be a number or this word.
FIRST_TRIALS: tuple[str, ...] = ("limit-equilibrium",)
#: The strength factors a strength-reduction search tries (projects.strength.F_MIN, F_MAX).
STRENGTH_FACTOR_RANGE: tuple[float, float] = (0.05, 50.0)
#: Size limits checked as the file is read, before its entries are (docs/project-format.md, size
#: limits): points of one outline or water line, points of all of them, entries of a list or table.
#: A 100,000-vertex body or structure kept ``validate`` and ``run`` busy for minutes (the geometry
#: of seeding, the warnings and the solver's structure setup grow with the vertices); a project
#: at these limits validates in seconds.
MAX_POLYGON_POINTS = 20_000
MAX_TOTAL_POINTS = 100_000
MAX_ENTRIES: dict[str, int] = {"materials": 256, "bodies": 1000, "structures": 1000, "stages": 1000, "targets": 1000,
                               "surcharges": 100}
DAMPING_TYPES: tuple[str, ...] = ("local",)
OUTPUT_FIELDS = sc.OUTPUT_FIELDS
#: Material keys that only a Drucker-Prager material may have.
SOFTENING_LAWS = sc.SOFTENING_LAWS
#: A material's strain-softening keys (solver/materials/softening.py).
SOFTENING_KEYS: tuple[str, ...] = (
    "softening_law",
    "residual_cohesion_pa",
    "residual_friction_angle_deg",
    "residual_dilatancy_angle_deg",
    "peak_plastic_strain",
    "residual_plastic_strain",
    "softening_length_m",
)
#: A material's rate-dependent friction keys, the mu(I) law (solver.config.InertialFriction).
INERTIAL_KEYS: tuple[str, ...] = (
    "mu_i_friction_increase",
    "mu_i_reference_number",
    "grain_diameter_m",
    "grain_density_kg_m3",
)
#: Material keys that only a Drucker-Prager material may have.
#: The keys of a rigid material (solver/rigid.py)
RIGID_KEYS: tuple[str, ...] = ("model", "density_kg_m3", "velocity_m_s", "contact")
PLASTIC_KEYS: tuple[str, ...] = (
    "cohesion_pa",
    "friction_angle_deg",
    "dilatancy_angle_deg",
    "tensile_strength_pa",
    "mohr_coulomb_match",
) + SOFTENING_KEYS + INERTIAL_KEYS
#: The keys of a dynamic stage that end it when the mass has come to rest (solver.config.Stage).
REST_KEYS: tuple[str, ...] = ("stop_when_kinetic_energy_below", "stop_when_max_speed_below_m_s")
#: Numerics keys of the time step: give one of them (none: cfl = DEFAULT_CFL).
DEFAULT_CFL = sc.DEFAULT_CFL
#: The strength-reduction search's defaults: the tolerance on F, the first bracketing step (a
#: fraction of F, doubled at each step) and the most trials (projects/strength.py)
SR_DEFAULT_TOLERANCE = 0.01
SR_DEFAULT_BRACKET_STEP = 0.1
SR_DEFAULT_MAX_TRIALS = 40
#: Damping coefficient of a gravity stage that gives none.
DEFAULT_GRAVITY_DAMPING = 0.7
#: the part of a gravity stage that ramps gravity up when ``ramp_fraction`` is not given (the solver's)
DEFAULT_GRAVITY_RAMP_FRACTION = sc.GRAVITY_RAMP_FRACTION

_SECTION_ORDER = ("runout", "domain", "materials", "bodies", "structures", "water", "particles", "numerics", "stages", "output",
                  "hazard", "targets")
_BARE_KEY = re.compile(r"^[A-Za-z0-9_-]+$")
_VALUE_WIDTH = 60
# Context flag: the caller runs the multi-key rules itself (on the raw input).
_RULES_DONE = "runout_rules_done"


# --------------------------------------------------------------------------------------------
# Problems and the one exception type


def format_value(value: Any) -> str:
    """Write a value the way it would look in a TOML file, shortened to about 60 characters.

    Parameters
    ----------
    value : Any
        A value read from TOML (or a model value: tuples are written as arrays).

    Returns
    -------
    str
    """
    text = _toml_text(value)
    if len(text) > _VALUE_WIDTH:
        text = text[: _VALUE_WIDTH - 3] + "..."
    return text


def _toml_text(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(value)
    if isinstance(value, int):
        return str(value)
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)
    if isinstance(value, Mapping):
        return "{" + ", ".join(f"{k} = {_toml_text(v)}" for k, v in value.items()) + "}"
    if isinstance(value, (list, tuple)):
        if len(value) > _VALUE_WIDTH:  # shown cut to _VALUE_WIDTH characters: no need to write all of it
            return "[" + ", ".join(_toml_text(v) for v in value[:_VALUE_WIDTH]) + ", ...]"
        return "[" + ", ".join(_toml_text(v) for v in value) + "]"
    if isinstance(value, BaseModel):
        return _toml_text(value.model_dump(exclude_none=True))
    return str(value)


@dataclass(frozen=True)
class Problem:
    """One thing wrong with a project.

    Attributes
    ----------
    path : str
        Dotted key path (``materials.bars.poisson_ratio``, ``bodies.0.material``); empty for
        problems of the file as a whole (TOML syntax).
    value : Any
        The offending value, or None where there is none to show (missing or unknown keys).
    message : str
        What is wrong and what is allowed.
    """

    path: str
    value: Any
    message: str

    def __str__(self) -> str:
        head = self.path
        if self.value is not None:
            head = f"{head} = {format_value(self.value)}"
        return f"{head}: {self.message}" if head else self.message


class ProjectError(Exception):
    """A project could not be read or is not valid; ``problems`` lists every problem found.

    Parameters
    ----------
    problems : sequence of Problem
    source : str, optional
        Where the project came from (a file name), prefixed to the message.
    """

    def __init__(self, problems: Sequence[Problem], source: str | None = None):
        self.problems: list[Problem] = list(problems)
        self.source = source
        super().__init__(self._message())

    def _message(self) -> str:
        lines = [str(p) for p in self.problems]
        prefix = f"{self.source}: " if self.source else ""
        if len(lines) == 1:
            return prefix + lines[0]
        return f"{prefix}{len(lines)} problems\n" + "\n".join("  " + line for line in lines)


# --------------------------------------------------------------------------------------------
# Value types with fixed messages


def _fail(message: str) -> PydanticCustomError:
    # No context is passed, so pydantic leaves braces in the message alone.
    return PydanticCustomError("runout", message)


def _to_number(value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise _fail("must be a number")
    try:
        number = float(value)
    except OverflowError:
        raise _fail("must be a finite number") from None
    if not math.isfinite(number):
        raise _fail("must be a finite number")
    return number


def _fmt_bound(x: float) -> str:
    return f"{x:g}"


def _number_type(
    *,
    gt: float | None = None,
    ge: float | None = None,
    lt: float | None = None,
    le: float | None = None,
    optional: bool = False,
    unit: str | None = None,
) -> Any:
    """An annotated float with a range, its message built from the bounds (``must be > 0``).

    With ``unit`` (``"Pa"``, ``"kg/m3"``) a string such as ``"5 kPa"`` is read with
    :func:`projects.units.parse_quantity` and kept in SI.
    """
    parts = []
    if gt is not None:
        parts.append(f"> {_fmt_bound(gt)}")
    if ge is not None:
        parts.append(f">= {_fmt_bound(ge)}")
    if lt is not None:
        parts.append(f"< {_fmt_bound(lt)}")
    if le is not None:
        parts.append(f"<= {_fmt_bound(le)}")
    message = "must be " + " and ".join(parts)

    def before(value: Any) -> Any:
        if value is None and optional:
            return None
        if unit is not None and isinstance(value, str):
            try:
                return parse_quantity(value, unit)
            except QuantityError as err:
                raise _fail(err.reason) from None
        return _to_number(value)

    def after(value: float | None) -> float | None:
        if value is None:
            return value
        ok = (
            (gt is None or value > gt)
            and (ge is None or value >= ge)
            and (lt is None or value < lt)
            and (le is None or value <= le)
        )
        if not ok:
            raise _fail(message)
        return value

    base = float | None if optional else float
    if not parts:
        return Annotated[base, BeforeValidator(before)]
    return Annotated[base, BeforeValidator(before), AfterValidator(after)]


def _to_int(value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise _fail("must be an integer")
    return value


def _to_str(value: Any) -> str:
    if not isinstance(value, str):
        raise _fail("must be a string")
    return value


def _nonempty(value: str) -> str:
    """A name: not empty, one line, no spaces at its ends (it names a column of contacts.csv, a
    curve, a table row: "wall " and "wall" would read as one and be two)."""
    if not value.strip():
        raise _fail("must not be empty")
    if value != value.strip():
        raise _fail("must not begin or end with spaces")
    if any(ord(c) < 32 or ord(c) == 127 for c in value):
        raise _fail("must be one line of printable characters")
    return value


def _choice(choices: Sequence[str]):
    allowed = ", ".join(json.dumps(c) for c in choices)

    def check(value: Any) -> Any:
        if not isinstance(value, str) or value not in choices:
            raise _fail(f"must be one of {allowed}")
        return value

    return BeforeValidator(check)


def _to_pair(value: Any) -> tuple[float, float]:
    if (
        not isinstance(value, (list, tuple))
        or len(value) != 2
        or any(isinstance(v, bool) or not isinstance(v, (int, float)) for v in value)
    ):
        raise _fail("must be a pair of numbers [x, y]")
    x, y = (_to_number(v) for v in value)
    return (x, y)


def _positive_pair(value: tuple[float, float]) -> tuple[float, float]:
    if value[0] <= 0.0 or value[1] <= 0.0:
        raise _fail("both components must be > 0")
    return value


def _points(value: Any) -> Any:
    if not isinstance(value, (list, tuple)):
        raise _fail("must be an array of points [[x, y], ...]")
    if len(value) > MAX_POLYGON_POINTS:  # before each point is read: 4.5 million took minutes
        raise _fail(f"has {len(value):,} points, more than the limit of {MAX_POLYGON_POINTS:,} per outline "
                    "(docs/project-format.md, size limits); simplify it")
    return value


def _at_most(limit: int, what: str):
    """A list or table of at most ``limit`` entries, checked before the entries are read."""
    def check(value: Any) -> Any:
        if isinstance(value, (list, tuple, Mapping)) and len(value) > limit:
            raise _fail(f"has {len(value):,} {what}, more than the limit of {limit:,} "
                        "(docs/project-format.md, size limits)")
        return value

    return BeforeValidator(check)


def _simple_polygon(points: tuple[tuple[float, float], ...]) -> tuple[tuple[float, float], ...]:
    if len(points) < 3:
        raise _fail(f"needs at least 3 points, got {len(points)}")
    arr = np.asarray(points, dtype=np.float64)
    if distinct_vertex_count(arr) < 3:
        raise _fail("needs at least 3 distinct points")
    crossings = self_intersections(arr)
    if crossings:
        shown = ", ".join(f"{edge_text(arr, i)} and {edge_text(arr, j)}" for i, j in crossings[:3])
        more = f" (and {len(crossings) - 3} more pairs)" if len(crossings) > 3 else ""
        raise _fail(f"not a simple polygon: edges {shown} cross or touch{more}")
    if has_zero_area(arr):
        raise _fail("not a simple polygon: it has zero area")
    return points


def _water_line(points: tuple[tuple[float, float], ...]) -> tuple[tuple[float, float], ...]:
    """A water line: at least two points, x strictly increasing (a level cannot fold back)."""
    if len(points) < 2:
        raise _fail(f"needs at least 2 points, got {len(points)}")
    for k in range(1, len(points)):
        if not points[k][0] > points[k - 1][0]:
            raise _fail(f"x must increase from point to point (a water line is one height at each x): "
                        f"point {k} [{points[k][0]:g}, {points[k][1]:g}] does not lie right of point {k - 1} "
                        f"[{points[k - 1][0]:g}, {points[k - 1][1]:g}]")
    return points


def _bare_key(value: str) -> str:
    if not _BARE_KEY.match(value):
        raise _fail("names may only use letters, digits, _ and -")
    return value


def _unique_fields(value: tuple[str, ...]) -> tuple[str, ...]:
    for index, name in enumerate(value):
        if name in value[:index]:
            raise _fail(f"{json.dumps(name)} is listed twice")
    return value


def _nonempty_list(what: str):
    def check(value: Any) -> Any:
        if len(value) == 0:
            raise _fail(f"needs at least one {what}")
        return value

    return AfterValidator(check)


Float = _number_type()
Positive = _number_type(gt=0.0)
OptPositive = _number_type(gt=0.0, optional=True)
OptNonNegative = _number_type(ge=0.0, optional=True)
PoissonRatio = _number_type(ge=0.0, lt=0.5)
OptAngleDeg = _number_type(ge=0.0, lt=90.0, optional=True)
#: a material's damping, the fraction of critical at its frequency (docs/solver.md, material damping)
OptDampingRatio = _number_type(ge=0.0, lt=1.0, optional=True)
#: a body's mode: periods from 1 us to 1000 s (a first shear mode c_s / 4H outside it is no soil
#: body; without bounds a frequency of 1e-320 Hz overflows the damping's time constants)
OptDampingFrequency = _number_type(ge=1e-3, le=1e6, optional=True)
OptCfl = _number_type(gt=0.0, le=1.0, optional=True)
OptFraction = _number_type(gt=0.0, lt=1.0, optional=True)
OptRampFraction = _number_type(gt=0.0, le=1.0, optional=True)
DampingCoefficient = _number_type(ge=0.0, lt=1.0)
# Stresses, moduli and densities also accept text with a unit ("5 kPa", "18 kN/m3"), kept in SI.
PositivePa = _number_type(gt=0.0, unit="Pa")
OptPositivePa = _number_type(gt=0.0, optional=True, unit="Pa")
OptNonNegativePa = _number_type(ge=0.0, optional=True, unit="Pa")
Density = _number_type(gt=0.0, unit="kg/m3")
OptDensity = _number_type(gt=0.0, optional=True, unit="kg/m3")
#: a pore-pressure ratio r_u = u / sigma_v (1 would leave no effective stress)
OptPoreRatio = _number_type(ge=0.0, lt=1.0, optional=True)
UnitWeight = _number_type(gt=0.0, unit="N/m3")
Int = Annotated[int, BeforeValidator(_to_int)]
Str = Annotated[str, BeforeValidator(_to_str)]
OptName = Annotated[
    str | None,
    BeforeValidator(lambda v: v if v is None else _to_str(v)),
    AfterValidator(lambda v: v if v is None else _nonempty(v)),
]
Name = Annotated[str, BeforeValidator(_to_str), AfterValidator(_nonempty)]
MaterialName = Annotated[str, BeforeValidator(_to_str), AfterValidator(_bare_key)]
Vec2 = Annotated[tuple[float, float], BeforeValidator(_to_pair)]
PositiveVec2 = Annotated[tuple[float, float], BeforeValidator(_to_pair), AfterValidator(_positive_pair)]
Polygon = Annotated[tuple[Vec2, ...], BeforeValidator(_points), AfterValidator(_simple_polygon)]
WaterLine = Annotated[tuple[Vec2, ...], BeforeValidator(_points), AfterValidator(_water_line)]


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, validate_default=False)


# --------------------------------------------------------------------------------------------
# The models, one per table of the file


class Header(_Model):
    """``[runout]``: what the file is."""

    schema_version: Int
    title: Str = ""

    @model_validator(mode="after")
    def _version(self) -> Header:
        if self.schema_version not in READABLE_SCHEMA_VERSIONS:
            raise _fail(_VERSION_MESSAGE)
        return self


_VERSION_MESSAGE = ("unsupported schema version; this Runout reads schema versions "
                    + ", ".join(str(v) for v in READABLE_SCHEMA_VERSIONS) + f" (and writes {SCHEMA_VERSION})")


def _boundary_input(value: Any) -> Any:
    # a value that is neither a word nor a table is told the words too, not only "must be a table"
    if not isinstance(value, Mapping):
        if isinstance(value, str) and value in ("fixed", "slip", "open", "periodic"):
            return {"type": value}
        raise _fail('must be "fixed", "slip", "open", "periodic" (left and right together) or a table '
                    '{type = "friction", friction_angle_deg = ...}')
    return value


class Boundary(_Model):
    """One side of the grid: ``"fixed" | "slip" | "open" | "periodic"`` (left and right together) or
    ``{type = "friction", friction_angle_deg = ..}``."""

    type: Annotated[Literal[BOUNDARY_TYPES], _choice(BOUNDARY_TYPES)]
    friction_angle_deg: OptAngleDeg = None

    @model_validator(mode="before")
    @classmethod
    def _from_string(cls, data: Any) -> Any:
        return _boundary_input(data)


class Boundaries(_Model):
    """``[domain.boundaries]``: the four sides (defaults: slip sides, fixed bottom, open top)."""

    left: Boundary = Boundary(type="slip")
    right: Boundary = Boundary(type="slip")
    bottom: Boundary = Boundary(type="fixed")
    top: Boundary = Boundary(type="open")


class Domain(_Model):
    """``[domain]``: the background grid and gravity."""

    origin_m: Vec2 = (0.0, 0.0)
    size_m: PositiveVec2
    cell_size_m: Positive
    gravity_m_s2: Vec2 = (0.0, -9.81)
    boundaries: Boundaries = Boundaries()


def _contact_input(value: Any) -> Any:
    if not isinstance(value, Mapping):
        if isinstance(value, str) and value in ("fixed", "slip"):
            return {"type": value}
        raise _fail('must be "fixed", "slip" or a table {type = "friction", friction_angle_deg = ...}')
    return value


class Contact(_Model):
    """A structure's or a rigid body's contact: ``"fixed" | "slip"`` or ``{type = "friction",
    friction_angle_deg = ..}``."""

    type: Annotated[Literal[CONTACT_TYPES], _choice(CONTACT_TYPES)]
    friction_angle_deg: OptAngleDeg = None

    @model_validator(mode="before")
    @classmethod
    def _from_string(cls, data: Any) -> Any:
        return _contact_input(data)


class Material(_Model):
    """``[materials.<name>]``: one material. The plastic keys are for Drucker-Prager only; a
    ``rigid`` body (a platen, a gate) takes its density, ``velocity_m_s`` and ``contact`` alone."""

    model: Annotated[Literal[MATERIAL_MODELS], _choice(MATERIAL_MODELS)]
    density_kg_m3: Density
    youngs_modulus_pa: OptPositivePa = None
    poisson_ratio: _number_type(ge=0.0, lt=0.5, optional=True) = None
    cohesion_pa: OptNonNegativePa = None
    friction_angle_deg: OptAngleDeg = None
    dilatancy_angle_deg: OptAngleDeg = None
    tensile_strength_pa: OptNonNegativePa = None
    mohr_coulomb_match: Annotated[Literal[MOHR_COULOMB_MATCHES], _choice(MOHR_COULOMB_MATCHES)] | None = None
    damping_ratio: OptDampingRatio = None
    damping_frequency_hz: OptDampingFrequency = None
    damping_model: Annotated[Literal[DAMPING_MODELS], _choice(DAMPING_MODELS)] | None = None
    saturated_density_kg_m3: OptDensity = None
    ru: OptPoreRatio = None
    softening_law: Annotated[Literal[SOFTENING_LAWS], _choice(SOFTENING_LAWS)] | None = None
    residual_cohesion_pa: OptNonNegativePa = None
    residual_friction_angle_deg: OptAngleDeg = None
    residual_dilatancy_angle_deg: OptAngleDeg = None
    peak_plastic_strain: OptNonNegative = None
    residual_plastic_strain: OptPositive = None
    softening_length_m: OptPositive = None
    mu_i_friction_increase: OptPositive = None
    mu_i_reference_number: OptPositive = None
    grain_diameter_m: OptPositive = None
    grain_density_kg_m3: OptDensity = None
    velocity_m_s: Vec2 | None = None
    contact: Contact | None = None


class MaterialChange(_Model):
    """``[stages.material_changes.<name>]``: new values of a material's numeric keys and its
    damping model."""

    density_kg_m3: OptDensity = None
    youngs_modulus_pa: OptPositivePa = None
    poisson_ratio: _number_type(ge=0.0, lt=0.5, optional=True) = None
    cohesion_pa: OptNonNegativePa = None
    friction_angle_deg: OptAngleDeg = None
    dilatancy_angle_deg: OptAngleDeg = None
    tensile_strength_pa: OptNonNegativePa = None
    damping_ratio: OptDampingRatio = None
    damping_frequency_hz: OptDampingFrequency = None
    damping_model: Annotated[Literal[DAMPING_MODELS], _choice(DAMPING_MODELS)] | None = None
    saturated_density_kg_m3: OptDensity = None
    ru: OptPoreRatio = None
    softening_law: Annotated[Literal[SOFTENING_LAWS], _choice(SOFTENING_LAWS)] | None = None
    residual_cohesion_pa: OptNonNegativePa = None
    residual_friction_angle_deg: OptAngleDeg = None
    residual_dilatancy_angle_deg: OptAngleDeg = None
    peak_plastic_strain: OptNonNegative = None
    residual_plastic_strain: OptPositive = None
    softening_length_m: OptPositive = None
    velocity_m_s: Vec2 | None = None


class Body(_Model):
    """``[[bodies]]``: a polygon of one material."""

    name: Name
    material: Str
    polygon_m: Polygon
    initial_velocity_m_s: Vec2 = (0.0, 0.0)


class Structure(_Model):
    """``[[structures]]``: a rigid polygon inside the domain whose surface is a contact like a side's."""

    name: Name
    polygon_m: Polygon
    contact: Contact = Contact(type="slip")


class Water(_Model):
    """``[water]``: the ground water (docs/project-format.md, water; solver/water.py)."""

    phreatic_line_m: WaterLine
    free_water_line_m: WaterLine | None = None
    unit_weight_n_m3: UnitWeight = 9810.0
    inclined_line_correction: Annotated[bool, BeforeValidator(lambda v: _to_bool(v))] = False


class StageWater(_Model):
    """``[stages.water]``: where the stage moves the water (linearly over its duration)."""

    phreatic_line_m: WaterLine | None = None
    free_water_line_m: WaterLine | None = None


class Particles(_Model):
    """``[particles]``: how bodies become material points."""

    per_cell: Annotated[int, BeforeValidator(_to_int), AfterValidator(lambda v: _in_int_range(v, 1, 8))] = 2
    seeding: Annotated[Literal[SEEDINGS], _choice(SEEDINGS)] = "lattice"


def _in_int_range(value: int, lo: int, hi: int) -> int:
    if not lo <= value <= hi:
        raise _fail(f"must be >= {lo} and <= {hi}")
    return value


class Advanced(_Model):
    """``[numerics.advanced]``: solver settings most projects leave alone (docs/project-format.md)."""

    guard: Annotated[Literal[GUARD_MODES], _choice(GUARD_MODES)] = "stop"
    speed_bound_factor: Positive = sc.DEFAULT_SPEED_BOUND_FACTOR
    scatter: Annotated[Literal[SCATTERS], _choice(SCATTERS)] = "auto"


class Numerics(_Model):
    """``[numerics]``: scheme, time step (``time_step_s`` or ``cfl``), precision, device."""

    scheme: Annotated[Literal[SCHEMES], _choice(SCHEMES)] = "apic-affine"
    time_step_s: OptPositive = None
    cfl: OptCfl = None
    precision: Annotated[Literal[PRECISIONS], _choice(PRECISIONS)] = "f32"
    arch: Annotated[Literal[ARCHS], _choice(ARCHS)] = "auto"
    preset: Annotated[Literal[PRESETS], _choice(PRESETS)] | None = None
    volumetric_averaging: Annotated[Literal[VOLUMETRIC_AVERAGING], _choice(VOLUMETRIC_AVERAGING)] = "auto"
    advanced: Advanced = Advanced()

    @model_validator(mode="before")
    @classmethod
    def _default_cfl(cls, data: Any) -> Any:
        if isinstance(data, Mapping) and data.get("time_step_s") is None and data.get("cfl") is None:
            return {**data, "cfl": DEFAULT_CFL}
        return data


class Damping(_Model):
    """``damping = {type = "local", coefficient = ..}``: Cundall's local damping."""

    type: Annotated[Literal[DAMPING_TYPES], _choice(DAMPING_TYPES)] = "local"
    coefficient: DampingCoefficient


def _first_trial(value: Any) -> Any:
    if value is None or (isinstance(value, str) and value in FIRST_TRIALS):
        return value
    if isinstance(value, str) or isinstance(value, bool) or not isinstance(value, (int, float)):
        raise _fail('must be a number > 0 or "limit-equilibrium"')
    if not value > 0:
        raise _fail('must be a number > 0 or "limit-equilibrium"')
    lo, hi = STRENGTH_FACTOR_RANGE
    number = _num(value)
    if number is None or not lo <= number <= hi:  # inf, 1e400, 10**400; the search's own range
        raise _fail(f'must be a number from {lo:g} to {hi:g} (the range the search tries) or "limit-equilibrium"')
    return number


FAILURE_CRITERIA: tuple[str, ...] = ("displacement", "kinetic-energy")
#: The directions of a stage's horizontal seismic force (projects/loads.py).
SEISMIC_DIRECTIONS: tuple[str, ...] = ("out-of-slope", "left", "right")


def _pressure_input(value: Any) -> Any:
    """A surcharge's pressure: one value, or a pair [at from_m, at to_m]; each a number of Pa or
    text with a unit ("50 kPa"), >= 0."""
    def one(v: Any) -> float:
        if isinstance(v, str):
            try:
                number = parse_quantity(v, "Pa")
            except QuantityError as err:
                raise _fail(err.reason) from None
        else:
            number = _to_number(v)
        if number < 0.0:
            raise _fail("must be >= 0 (a surcharge presses on the ground; give a pair [at from_m, at to_m] "
                        "for a load that varies along it)")
        return number

    if isinstance(value, (list, tuple)):
        if len(value) != 2:
            raise _fail("must be a pressure (Pa, or text such as \"50 kPa\") or a pair [at from_m, at to_m]")
        return (one(value[0]), one(value[1]))
    return one(value)


class Surcharge(_Model):
    """``[[stages.surcharges]]``: a distributed load on the ground surface between two x (projects/loads.py)."""

    name: Name
    from_m: Float
    to_m: Float
    pressure_pa: Annotated[float | tuple[float, float], BeforeValidator(_pressure_input)]
    ramp: Annotated[bool | None, BeforeValidator(lambda v: v if v is None else _to_bool(v))] = None

    @property
    def pressures_pa(self) -> tuple[float, float]:
        """The pressure at from_m and at to_m (Pa)."""
        p = self.pressure_pa
        return (float(p[0]), float(p[1])) if isinstance(p, tuple) else (float(p), float(p))


class Seismic(_Model):
    """``seismic = {k_h = .., k_v = .., towards = ..}``: a stage's pseudo-static coefficients."""

    k_h: _number_type(ge=0.0, lt=1.0) = 0.0
    k_v: _number_type(gt=-1.0, lt=1.0) = 0.0
    towards: Annotated[Literal[SEISMIC_DIRECTIONS], _choice(SEISMIC_DIRECTIONS)] = "out-of-slope"


class Failure(_Model):
    """``failure = {..}`` of a strength-reduction stage: when a trial has failed."""

    criteria: Annotated[
        tuple[Annotated[str, _choice(FAILURE_CRITERIA)], ...],
        BeforeValidator(lambda v: v if isinstance(v, (list, tuple)) else _raise_array()),
        AfterValidator(_unique_fields),
        _nonempty_list("criterion"),
    ] = FAILURE_CRITERIA
    kinetic_energy_ratio: OptFraction = None
    displacement_m: OptPositive = None
    monitor_point_m: Vec2 | None = None
    min_settle_fraction: OptFraction = None


class Stage(_Model):
    """``[[stages]]``: one stage of the analysis (see docs/project-format.md)."""

    name: OptName = None
    type: Annotated[Literal[STAGE_TYPES], _choice(STAGE_TYPES)]
    duration_s: OptPositive = None
    #: gravity stages: the part of the stage over which gravity is ramped up (solver.config.Stage)
    ramp_fraction: OptRampFraction = None
    k0: OptPositive = None
    damping: Damping | None = None
    stop_when_kinetic_energy_below: OptFraction = None
    stop_when_max_speed_below_m_s: OptPositive = None
    min_duration_s: OptNonNegative = None
    material_changes: dict[MaterialName, MaterialChange] = {}
    # strength-reduction stages (and strength_factor on the dynamic stage after one)
    materials: tuple[MaterialName, ...] | None = None
    tolerance: OptPositive = None
    first_trial: Annotated[float | str | None, BeforeValidator(_first_trial)] = None
    bracket_step: OptPositive = None
    trial_duration_s: OptPositive = None
    max_trials: Annotated[int | None, BeforeValidator(lambda v: v if v is None else _to_int(v)),
                          AfterValidator(lambda v: v if v is None else _in_int_range(v, 2, 200))] = None
    limit_equilibrium: Annotated[bool | None, BeforeValidator(lambda v: v if v is None else _to_bool(v))] = None
    failure: Failure | None = None
    strength_factor: OptPositive = None
    water: StageWater | None = None
    #: the surcharges in force from this stage on (None: those of the stage before; [] none)
    surcharges: Annotated[list[Surcharge] | None, _at_most(MAX_ENTRIES["surcharges"], "surcharges")] = None
    seismic: Seismic | None = None

    @property
    def label(self) -> str:
        """The stage's name, or its type where it has none."""
        return self.name if self.name is not None else self.type


class Output(_Model):
    """``[output]``: frames every ``interval_s`` with ``fields``."""

    interval_s: Positive = 0.01
    fields: Annotated[
        tuple[Annotated[str, _choice(OUTPUT_FIELDS)], ...],
        BeforeValidator(lambda v: v if isinstance(v, (list, tuple)) else _raise_array()),
        AfterValidator(_unique_fields),
    ] = OUTPUT_FIELDS
    #: simulated seconds between checkpoints (full solver state, ``checkpoint.npz``); default:
    #: every CHECKPOINT_EVERY_OUTPUTS output intervals. A run always writes one at its end.
    checkpoint_interval_s: OptPositive = None


#: Output intervals between checkpoints when ``output.checkpoint_interval_s`` is not given.
CHECKPOINT_EVERY_OUTPUTS = 10


def _raise_array() -> Any:
    raise _fail("must be an array")


def _to_bool(value: Any) -> bool:
    if not isinstance(value, bool):
        raise _fail("must be true or false")
    return value


class Hazard(_Model):
    """``[hazard]``: envelopes, run-out measures and their thresholds (see projects/hazard.py).

    Keys left out take scene-scaled defaults when the run is built (projects.hazard.settings).
    """

    enabled: Annotated[bool, BeforeValidator(_to_bool)] = True
    cell_size_m: OptPositive = None
    update_every_steps: Annotated[
        int, BeforeValidator(_to_int), AfterValidator(lambda v: _in_int_range(v, 1, 100000))
    ] = 10
    flow_height_threshold_m: OptPositive = None
    deposit_threshold_m: OptPositive = None
    mobilised_displacement_m: OptPositive = None
    kinetic_energy_fraction: _number_type(gt=0.0, lt=1.0) = 0.01


class Target(_Model):
    """``[[targets]]``: a named place whose hazard is recorded: a vertical line ``x_m`` or a point
    ``point_m``."""

    name: MaterialName
    x_m: _number_type(optional=True) = None
    point_m: Annotated[tuple[float, float] | None, BeforeValidator(lambda v: v if v is None else _to_pair(v))] = None

    @model_validator(mode="after")
    def _one_place(self) -> Target:
        if (self.x_m is None) == (self.point_m is None):
            raise _fail("give x_m (a vertical line) or point_m (a point [x, y]), exactly one of them")
        return self

    @property
    def xy(self) -> tuple[float, float | None]:
        """(x, y) of a point target, (x, None) of a line."""
        if self.point_m is not None:
            return (self.point_m[0], self.point_m[1])
        return (float(self.x_m), None)


class Project(_Model):
    """A whole project file (schema version 2).

    Build one with :func:`validate_project` (or :mod:`projects.document`), which reports every
    problem at once. ``materials`` keeps the file's order: material ids follow it.
    """

    runout: Header
    domain: Domain
    materials: Annotated[dict[MaterialName, Material], _at_most(MAX_ENTRIES["materials"], "materials"),
                         _nonempty_list("material ([materials.NAME])")]
    bodies: Annotated[list[Body], _at_most(MAX_ENTRIES["bodies"], "bodies"), _nonempty_list("body ([[bodies]])")]
    structures: Annotated[list[Structure], _at_most(MAX_ENTRIES["structures"], "structures")] = []
    water: Water | None = None
    particles: Particles = Particles()
    numerics: Numerics = Numerics()
    stages: Annotated[list[Stage], _at_most(MAX_ENTRIES["stages"], "stages"), _nonempty_list("stage ([[stages]])")]
    output: Output = Output()
    hazard: Hazard = Hazard()
    targets: Annotated[list[Target], _at_most(MAX_ENTRIES["targets"], "targets")] = []

    @model_validator(mode="after")
    def _rules(self, info: ValidationInfo) -> Project:
        if info.context and info.context.get(_RULES_DONE):
            return self
        problems = _rule_problems(self.to_dict())
        if problems:
            raise PydanticCustomError(
                "runout_rules", "{count} problem(s)", {"count": len(problems), "problems": tuple(problems)}
            )
        return self

    @property
    def material_names(self) -> tuple[str, ...]:
        """Material names in file order (material id = position)."""
        return tuple(self.materials)

    def to_dict(self) -> dict[str, Any]:
        """The project as plain TOML-shaped data (lists, dicts, str, int, float).

        Keys with no value are left out, boundaries without a friction angle are written as
        their type string, empty ``material_changes``, a ``[hazard]`` table of defaults and an
        empty ``targets`` list are left out. ``validate_project`` of the
        result gives back an equal project.

        Returns
        -------
        dict
        """
        data = _plain(self.model_dump(mode="python", exclude_none=True))
        for side, boundary in data["domain"]["boundaries"].items():
            if set(boundary) == {"type"}:
                data["domain"]["boundaries"][side] = boundary["type"]
        for structure in data["structures"]:
            if set(structure["contact"]) == {"type"}:
                structure["contact"] = structure["contact"]["type"]
        if not data["structures"]:
            data.pop("structures")
        for stage in data["stages"]:
            if not stage.get("material_changes"):
                stage.pop("material_changes", None)
        # the hazard keys are left out while they hold their defaults (files stay as they were)
        if data.get("hazard") == _plain(Hazard().model_dump(mode="python", exclude_none=True)):
            data.pop("hazard")
        if not data.get("targets"):
            data.pop("targets", None)
        return data


def _plain(value: Any) -> Any:
    if isinstance(value, Mapping):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value


# --------------------------------------------------------------------------------------------
# Validation entry point


def migrate(data: Mapping[str, Any]) -> Mapping[str, Any]:
    """A file of an older readable schema version as the current version's data.

    Version 1 to 2 adds keys only ([water], ``saturated_density_kg_m3``, ``ru``, a stage's
    ``water``, the ``pore_pressure`` field): a version 1 file means the same under version 2.
    """
    header = data.get("runout")
    if isinstance(header, Mapping) and header.get("schema_version") == 1:
        data = {**data, "runout": {**header, "schema_version": SCHEMA_VERSION}}
    return data


def validate_project(data: Mapping[str, Any]) -> Project:
    """Validate TOML-shaped data into a :class:`Project`, reporting every problem at once.

    Parameters
    ----------
    data : mapping
        The parsed file (plain dicts, lists and scalars).

    Returns
    -------
    Project

    Raises
    ------
    ProjectError
        With one :class:`Problem` per thing wrong, in file order.
    """
    if not isinstance(data, Mapping):
        raise ProjectError([Problem("", None, "a project must be a TOML table")])
    header = data.get("runout")
    version = header.get("schema_version") if isinstance(header, Mapping) else None
    if isinstance(version, int) and not isinstance(version, bool) and version not in READABLE_SCHEMA_VERSIONS:
        # Other problems would be judged by the wrong schema; report the version alone.
        raise ProjectError([Problem("runout.schema_version", version, _VERSION_MESSAGE)])
    data = migrate(data)
    too_many = _total_points_rule(data)
    if too_many:  # before any point is read: a size limit, not one problem among others
        raise ProjectError(too_many)
    problems: list[Problem] = []
    project = None
    try:
        project = Project.model_validate(data, context={_RULES_DONE: True})
    except ValidationError as exc:
        problems.extend(_from_pydantic(exc))
    problems.extend(_rule_problems(data))
    if problems:
        raise ProjectError(_in_file_order(problems, data))
    assert project is not None
    return project


def _in_file_order(problems: list[Problem], data: Mapping[str, Any]) -> list[Problem]:
    def key(problem: Problem) -> tuple[int, int]:
        parts = problem.path.split(".")
        section = parts[0]
        first = _SECTION_ORDER.index(section) if section in _SECTION_ORDER else len(_SECTION_ORDER)
        second = 0
        if len(parts) > 1:
            if parts[1].isdigit():
                second = int(parts[1])
            elif section == "materials" and isinstance(data.get("materials"), Mapping):
                names = list(data["materials"])
                second = names.index(parts[1]) if parts[1] in names else len(names)
        return (first, second)

    return sorted(problems, key=key)


def _from_pydantic(exc: ValidationError) -> list[Problem]:
    problems = []
    for error in exc.errors(include_url=False):
        loc = tuple(part for part in error["loc"] if part != "[key]")
        path = ".".join(str(part) for part in loc)
        kind = error["type"]
        # A bad table key is named by the path already.
        value = None if "[key]" in error["loc"] else error.get("input")
        if kind == "runout_rules":
            problems.extend(error["ctx"]["problems"])
        elif kind == "runout":
            problems.append(Problem(path, value, error["msg"]))
        elif kind == "missing":
            problems.append(Problem(path, None, "required key is missing"))
        elif kind == "extra_forbidden":
            allowed = _allowed_keys(loc[:-1])
            problems.append(Problem(path, None, "unknown key; allowed: " + ", ".join(allowed)))
        elif kind in ("model_type", "model_attributes_type", "dict_type"):
            problems.append(Problem(path, value, "must be a table"))
        elif kind in ("list_type", "tuple_type"):
            problems.append(Problem(path, value, "must be an array"))
        else:  # not expected with the value types above; keep pydantic's words
            logger.debug("unmapped pydantic error %s at %s", kind, path)
            problems.append(Problem(path, value, error["msg"]))
    return problems


def _allowed_keys(loc: tuple[Any, ...]) -> list[str]:
    """The keys allowed in the table at ``loc`` (walks the model annotations)."""
    node: Any = Project
    for part in loc:
        node = _child_schema(node, part)
        if node is None:
            return []
    return list(node.model_fields) if _is_model(node) else []


def _is_model(node: Any) -> bool:
    return isinstance(node, type) and issubclass(node, BaseModel)


def _unwrap(annotation: Any) -> Any:
    """Strip Annotated and Optional from a field annotation."""
    while True:
        origin = typing.get_origin(annotation)
        if origin is Annotated:
            annotation = typing.get_args(annotation)[0]
        elif origin in (typing.Union, types.UnionType):
            args = [a for a in typing.get_args(annotation) if a is not type(None)]
            if len(args) != 1:
                return annotation
            annotation = args[0]
        else:
            return annotation


def schema_kind(node: Any) -> tuple[str, Any]:
    """Classify a schema node: ``("model", cls)``, ``("dict", value)``, ``("list", item)``
    or ``("value", annotation)``. Used to walk key paths (errors, overrides)."""
    node = _unwrap(node)
    if _is_model(node):
        return ("model", node)
    origin = typing.get_origin(node)
    if origin is dict:
        return ("dict", typing.get_args(node)[1])
    if origin in (list, tuple):
        args = typing.get_args(node)
        # Pairs (tuple[float, float]) are values; homogeneous tuples and lists are arrays.
        if origin is list or (len(args) == 2 and args[1] is Ellipsis):
            return ("list", args[0])
    return ("value", node)


def _child_schema(node: Any, part: Any) -> Any:
    kind, inner = schema_kind(node)
    if kind == "model":
        field = inner.model_fields.get(part)
        return None if field is None else field.annotation
    if kind in ("dict", "list"):
        return inner
    return None


# --------------------------------------------------------------------------------------------
# Rules that involve several keys, on raw (possibly invalid) data


def _num(value: Any) -> float | None:
    """The value as a float when it is a finite number, else None (judged elsewhere)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    try:
        number = float(value)
    except OverflowError:
        return None
    return number if math.isfinite(number) else None


def _pair(value: Any) -> tuple[float, float] | None:
    if not isinstance(value, (list, tuple)) or len(value) != 2:
        return None
    x, y = _num(value[0]), _num(value[1])
    return None if x is None or y is None else (x, y)


def _table(value: Any) -> Mapping[str, Any]:
    return value if isinstance(value, Mapping) else {}


def _array(value: Any) -> list[Any]:
    return list(value) if isinstance(value, (list, tuple)) else []


def _rule_problems(data: Mapping[str, Any]) -> list[Problem]:
    problems: list[Problem] = []
    domain = _table(data.get("domain"))
    materials = _table(data.get("materials"))
    problems += _domain_rules(domain)
    problems += _material_rules(materials)
    problems += _body_rules(_array(data.get("bodies")), materials, domain)
    problems += _structure_rules(_array(data.get("structures")), domain)
    problems += _numerics_rules(_table(data.get("numerics")))
    problems += _stage_rules(_array(data.get("stages")), materials)
    problems += _hazard_rules(_table(data.get("hazard")), _array(data.get("targets")), domain)
    problems += _water_rules(data.get("water"), _array(data.get("stages")))
    problems += _monitor_rules(_array(data.get("stages")), domain)
    from projects.loads import load_rules  # the surcharges' and seismic coefficients' rules

    problems += [Problem(*problem) for problem in load_rules(data)]
    return problems


def _water_rules(water: Any, stages: list[Any]) -> list[Problem]:
    """A stage moves the water of [water]; it names a line to move; no water move in a strength
    reduction (its trials need one water state)."""
    problems = []
    for index, stage in enumerate(stages):
        if not isinstance(stage, Mapping) or "water" not in stage:
            continue
        path = f"stages.{index}.water"
        move = stage["water"]
        if water is None:
            problems.append(Problem(path, None, "a stage moves the water of [water]: add a [water] table with the "
                                    "phreatic_line_m at the start"))
        if isinstance(move, Mapping) and not move:
            problems.append(Problem(path, None, "needs phreatic_line_m or free_water_line_m (where the stage moves it)"))
        if stage.get("type") == "strength-reduction":
            problems.append(Problem(path, None, "not allowed on a strength-reduction stage (its trials share one "
                                    "water state: move the water in the stage before it)"))
    return problems


def _saturated_rule(path: str, values: Mapping[str, Any]) -> list[Problem]:
    """A saturated density is at least the dry one."""
    wet, dry = _num(values.get("saturated_density_kg_m3")), _num(values.get("density_kg_m3"))
    if wet is not None and dry is not None and wet < dry:
        return [Problem(f"{path}.saturated_density_kg_m3", wet,
                        f"must be >= density_kg_m3 ({dry:g}): below the water table a soil's pores hold water")]
    return []


def _hazard_rules(hazard: Mapping[str, Any], targets: list[Any], domain: Mapping[str, Any]) -> list[Problem]:
    """Hazard raster no larger than the domain; targets inside the domain, names unique."""
    problems = []
    origin = _pair(domain.get("origin_m", (0.0, 0.0)))
    size = _pair(domain.get("size_m"))
    cell = _num(hazard.get("cell_size_m"))
    if size and cell and min(size) > 0.0 and cell > min(size):
        problems.append(Problem("hazard.cell_size_m", cell, f"larger than the domain ({size[0]:g} x {size[1]:g} m)"))
    seen: set[str] = set()
    for i, target in enumerate(targets):
        if not isinstance(target, Mapping):
            continue
        name = target.get("name")
        if isinstance(name, str):
            if name in seen:
                problems.append(Problem(f"targets.{i}.name", name, "another target has this name; names must be unique"))
            seen.add(name)
        if not (origin and size):
            continue
        x = _num(target.get("x_m"))
        if x is not None and not origin[0] <= x <= origin[0] + size[0]:
            problems.append(Problem(f"targets.{i}.x_m", x, f"must lie in the domain, x from {origin[0]:g} "
                                    f"to {origin[0] + size[0]:g} m"))
        point = _pair(target.get("point_m"))
        if point is not None and not (origin[0] <= point[0] <= origin[0] + size[0]
                                      and origin[1] <= point[1] <= origin[1] + size[1]):
            problems.append(Problem(f"targets.{i}.point_m", list(point), "must lie in the domain "
                                    f"[{origin[0]:g}, {origin[0] + size[0]:g}] x [{origin[1]:g}, {origin[1] + size[1]:g}] m"))
    return problems


def _domain_rules(domain: Mapping[str, Any]) -> list[Problem]:
    problems = []
    size = _pair(domain.get("size_m"))
    cell = _num(domain.get("cell_size_m"))
    if size and cell and min(size) > 0.0 and cell > 0.0 and cell > min(size):
        problems.append(
            Problem("domain.cell_size_m", cell, f"larger than the domain ({size[0]:g} x {size[1]:g} m)")
        )
    for side, boundary in _table(domain.get("boundaries")).items():
        if not isinstance(boundary, Mapping) or side not in SIDES:
            continue
        kind = boundary.get("type")
        path = f"domain.boundaries.{side}.friction_angle_deg"
        if kind == "friction" and "friction_angle_deg" not in boundary:
            problems.append(Problem(path, None, 'required for type "friction"'))
        elif kind in ("fixed", "slip", "open", "periodic") and "friction_angle_deg" in boundary:
            problems.append(Problem(path, boundary["friction_angle_deg"], 'only allowed with type "friction"'))
    problems += _periodic_rules(domain, cell, size)
    return problems


def _periodic_rules(domain: Mapping[str, Any], cell: float | None, size) -> list[Problem]:
    """``periodic``: left and right only, both or neither, and at least MIN_PERIODIC_CELLS cells across."""
    kinds = {}
    for side, boundary in _table(domain.get("boundaries")).items():
        kind = boundary.get("type") if isinstance(boundary, Mapping) else boundary
        kinds[side] = kind
    problems = []
    for side in ("bottom", "top"):
        if kinds.get(side) == "periodic":
            problems.append(Problem(f"domain.boundaries.{side}", "periodic",
                                    "only the left and right sides can be periodic (both together); allowed here: "
                                    "fixed, slip, open or friction"))
    left, right = kinds.get("left", "slip"), kinds.get("right", "slip")
    if left not in BOUNDARY_TYPES or right not in BOUNDARY_TYPES:
        return problems  # a kind that is no kind at all has its own message
    if (left == "periodic") != (right == "periodic"):
        side, other = ("right", "left") if left == "periodic" else ("left", "right")
        problems.append(Problem(f"domain.boundaries.{side}", kinds.get(side, "slip"),
                                f'must be "periodic" too: the {other} side is periodic, and periodic sides come as a '
                                "pair (both or neither)"))
    elif left == "periodic" and size and cell and cell > 0.0:
        cells = math.ceil(size[0] / cell - 1e-9)
        if cells < sc.MIN_PERIODIC_CELLS:
            problems.append(Problem("domain.size_m", list(size), f"periodic sides need at least "
                                    f"{sc.MIN_PERIODIC_CELLS} cells across (cell_size_m {cell:g}), got {cells}"))
    return problems


def _material_rules(materials: Mapping[str, Any]) -> list[Problem]:
    problems = []
    for name, material in materials.items():
        if not isinstance(material, Mapping):
            continue
        path = f"materials.{name}"
        model = material.get("model")
        if model == "rigid":
            for key in material:
                if key not in RIGID_KEYS:
                    problems.append(Problem(f"{path}.{key}", material[key], 'not used by model "rigid" (a body moved at '
                                            f'its velocity); allowed: {", ".join(RIGID_KEYS)}'))
            problems += _contact_rule(path, material.get("contact"))
            continue
        for key in ("velocity_m_s", "contact"):
            if key in material:
                problems.append(Problem(f"{path}.{key}", material[key], 'only allowed with model "rigid"'))
        if model in ("drucker-prager", "linear-elastic"):
            for key in ("youngs_modulus_pa", "poisson_ratio"):
                if key not in material:
                    problems.append(Problem(f"{path}.{key}", None, f'required for model "{model}"'))
        if model == "drucker-prager":
            for key in ("cohesion_pa", "friction_angle_deg"):
                if key not in material:
                    problems.append(Problem(f"{path}.{key}", None, 'required for model "drucker-prager"'))
            problems += _dilatancy_rule(path, material, changed=None)
            problems += _softening_rule(path, material, changed=None)
            problems += _inertial_rule(path, material)
        elif model == "linear-elastic":
            for key in PLASTIC_KEYS:
                if key in material:
                    problems.append(
                        Problem(f"{path}.{key}", material[key], 'only allowed with model "drucker-prager"')
                    )
        problems += _damping_rule(path, material)
        problems += _saturated_rule(path, material)
        problems += _wave_speed_rule(path, material, None)
    return problems


def _wave_speed_rule(path: str, values: Mapping[str, Any], changed: Mapping[str, Any] | None) -> list[Problem]:
    """The P-wave speed ``sqrt(E (1 - nu) / ((1 + nu)(1 - 2 nu) rho))`` is a positive number: a
    modulus of 5e-324 Pa underflows to a speed of 0 (the time step's limit dx / c_p divides by it)
    and 1e308 Pa over 1e-300 kg/m3 overflows. With ``changed`` (a stage's change), only when it
    changes one of the three."""
    keys = ("youngs_modulus_pa", "poisson_ratio", "density_kg_m3")
    if changed is not None and not any(k in changed for k in keys):
        return []
    e, nu, rho = (_num(values.get(k)) for k in keys)
    if e is None or nu is None or rho is None or not (e > 0 and rho > 0 and 0 <= nu < 0.5):
        return []  # judged on their own
    try:
        speed = math.sqrt(e * (1.0 - nu) / ((1.0 + nu) * (1.0 - 2.0 * nu)) / rho)
    except (OverflowError, ZeroDivisionError, ValueError):
        speed = math.inf
    if 0.0 < speed < math.inf:
        return []
    key = next((k for k in ("youngs_modulus_pa", "density_kg_m3") if changed is None or k in changed), keys[0])
    return [Problem(f"{path}.{key}", values.get(key), f"gives a P-wave speed of {speed:g} m/s with youngs_modulus_pa "
                    f"{e:g} and density_kg_m3 {rho:g} (the time step's limit is cell_size_m / speed): not a material")]


def _damping_rule(path: str, values: Mapping[str, Any]) -> list[Problem]:
    """A damping ratio above zero needs the frequency it holds at; a frequency needs a ratio."""
    ratio = _num(values.get("damping_ratio"))
    if ratio is not None and 0.0 < ratio < 1.0 and "damping_frequency_hz" not in values:
        return [Problem(f"{path}.damping_frequency_hz", None, "required with damping_ratio > 0: the frequency (Hz) at "
                        "which the material is damped by that fraction of critical, e.g. the body's first mode")]
    # (a damping_model alone is allowed: it says how the material is damped once a ratio is given,
    # and the workbench keeps it while the ratio is cleared and typed again)
    if "damping_frequency_hz" in values and "damping_ratio" not in values:
        return [Problem(f"{path}.damping_frequency_hz", values["damping_frequency_hz"], "only allowed with damping_ratio")]
    return []


def _valid_angle(value: Any) -> float | None:
    angle = _num(value)
    return angle if angle is not None and 0.0 <= angle < 90.0 else None


def _dilatancy_rule(path: str, values: Mapping[str, Any], changed: Mapping[str, Any] | None) -> list[Problem]:
    """Dilatancy must not exceed friction; with ``changed``, blame the key the stage changed."""
    psi = _valid_angle(values.get("dilatancy_angle_deg", 0.0))
    phi = _valid_angle(values.get("friction_angle_deg"))
    if psi is None or phi is None or psi <= phi:
        return []
    if changed is not None and "dilatancy_angle_deg" not in changed:
        return [Problem(f"{path}.friction_angle_deg", phi, f"must not be below dilatancy_angle_deg ({psi:g})")]
    return [Problem(f"{path}.dilatancy_angle_deg", psi, f"must not exceed friction_angle_deg ({phi:g})")]


#: a residual key, the peak key it may not exceed, and the peak's default
_RESIDUALS = (("residual_cohesion_pa", "cohesion_pa"), ("residual_friction_angle_deg", "friction_angle_deg"),
              ("residual_dilatancy_angle_deg", "dilatancy_angle_deg"))


def _softening_rule(path: str, values: Mapping[str, Any], changed: Mapping[str, Any] | None) -> list[Problem]:
    """Softening needs its law and residual strain; residual values at most the peak ones; the
    residual strain beyond the peak strain; residual dilatancy at most residual friction. With
    ``changed`` (a stage's change) only the rules its keys touch."""
    keys = set(values) if changed is None else set(changed)
    if changed is not None and not keys & (set(SOFTENING_KEYS) | {peak for _, peak in _RESIDUALS}):
        return []
    problems = []
    law = values.get("softening_law")
    others = [k for k in SOFTENING_KEYS if k != "softening_law" and k in values]
    if law is None:
        for key in others:
            if key in keys:
                problems.append(Problem(f"{path}.{key}", values[key], 'needs softening_law ("linear" or '
                                        '"exponential") to say how the strength falls'))
        return problems
    if "residual_plastic_strain" not in values:
        problems.append(Problem(f"{path}.residual_plastic_strain", None, "required with softening_law: the "
                                "plastic strain at which the strength reaches its residual values"))
    if not any(k in values for k, _ in _RESIDUALS):
        problems.append(Problem(f"{path}.softening_law", law, "needs a residual value to fall to: "
                                "residual_cohesion_pa, residual_friction_angle_deg or residual_dilatancy_angle_deg"))
    for residual_key, peak_key in _RESIDUALS:
        residual, peak = _num(values.get(residual_key)), _num(values.get(peak_key, 0.0))
        if residual is not None and peak is not None and residual > peak:
            problems.append(Problem(f"{path}.{residual_key}", residual, f"must be <= {peak_key} ({peak:g}): "
                                    "softening lowers the strength from peak to residual"))
    e_peak, e_res = _num(values.get("peak_plastic_strain", 0.0)), _num(values.get("residual_plastic_strain"))
    if e_peak is not None and e_res is not None and e_res <= e_peak:
        problems.append(Problem(f"{path}.residual_plastic_strain", e_res,
                                f"must be > peak_plastic_strain ({e_peak:g})"))
    psi_r = _num(values.get("residual_dilatancy_angle_deg", values.get("dilatancy_angle_deg", 0.0)))
    phi_r = _num(values.get("residual_friction_angle_deg", values.get("friction_angle_deg")))
    if psi_r is not None and phi_r is not None and psi_r > phi_r and not problems:
        problems.append(Problem(f"{path}.residual_dilatancy_angle_deg", psi_r,
                                f"must not exceed the residual friction angle ({phi_r:g})"))
    return problems


def _inertial_rule(path: str, values: Mapping[str, Any]) -> list[Problem]:
    """The mu(I) law needs its friction increase, reference inertial number and grain diameter
    together, a friction angle above zero (the increase is over tan(phi)) and no softening."""
    given = [k for k in INERTIAL_KEYS if k in values]
    if not given:
        return []
    key = "mu_i_friction_increase"
    if key not in values:
        return [Problem(f"{path}.{k}", values[k], "needs mu_i_friction_increase (mu_2 - mu_s of the mu(I) law) "
                        "to make the friction depend on the rate") for k in given]
    problems = [Problem(f"{path}.{k}", None, f"required with {key}: the mu(I) law needs "
                        + ("the reference inertial number I0" if k == "mu_i_reference_number" else
                           "the grain diameter d in I = gamma_dot d / sqrt(p / rho_s)"))
                for k in ("mu_i_reference_number", "grain_diameter_m") if k not in values]
    phi = _num(values.get("friction_angle_deg"))
    if phi is not None and phi <= 0.0:
        problems.append(Problem(f"{path}.{key}", values[key], "needs friction_angle_deg > 0: the friction rises "
                                "with the rate from tan(friction_angle_deg)"))
    if "softening_law" in values:
        problems.append(Problem(f"{path}.{key}", values[key], "not allowed with softening_law: a material's "
                                "friction either softens or depends on the rate"))
    return problems


def _defined(names: Sequence[str]) -> str:
    return ", ".join(names) if names else "none"


def _body_rules(bodies: list[Any], materials: Mapping[str, Any], domain: Mapping[str, Any]) -> list[Problem]:
    problems = []
    origin = _pair(domain.get("origin_m", (0.0, 0.0)))
    size = _pair(domain.get("size_m"))
    box = None
    if origin and size and min(size) > 0.0:
        tol = 1e-9 * max(size)
        box = (origin[0] - tol, origin[0] + size[0] + tol, origin[1] - tol, origin[1] + size[1] + tol)
    seen: dict[str, int] = {}
    for index, body in enumerate(bodies):
        if not isinstance(body, Mapping):
            continue
        path = f"bodies.{index}"
        material = body.get("material")
        if isinstance(material, str) and material not in materials:
            problems.append(
                Problem(f"{path}.material", material, f"no such material; defined: {_defined(list(materials))}")
            )
        name = body.get("name")
        if isinstance(name, str):
            if name in seen:
                problems.append(Problem(f"{path}.name", name, f"duplicate; bodies.{seen[name]} has the same name"))
            else:
                seen[name] = index
        if box is not None:
            problems += _outside_points(path, _array(body.get("polygon_m")), box, origin, size)
    models = [_table(materials.get(b.get("material"))).get("model") for b in bodies
              if isinstance(b, Mapping) and isinstance(b.get("material"), str) and b.get("material") in materials]
    if models and all(m == "rigid" for m in models):
        problems.append(Problem("bodies", None, 'every body is of a rigid material: at least one must be of a '
                                'deformable one ("linear-elastic" or "drucker-prager")'))
    return problems


def _contact_rule(path: str, contact: Any) -> list[Problem]:
    """A friction contact needs its angle; the others take none."""
    if not isinstance(contact, Mapping):
        return []
    kind = contact.get("type")
    if kind == "friction" and "friction_angle_deg" not in contact:
        return [Problem(f"{path}.contact.friction_angle_deg", None, 'required for type "friction"')]
    if kind in ("fixed", "slip") and "friction_angle_deg" in contact:
        return [Problem(f"{path}.contact.friction_angle_deg", contact["friction_angle_deg"],
                        'only allowed with type "friction"')]
    return []


def _structure_rules(structures: list[Any], domain: Mapping[str, Any]) -> list[Problem]:
    """Names unique and no side's name (both name a contact in contacts.csv), friction angle with
    type friction only, every point inside the domain."""
    problems = []
    origin = _pair(domain.get("origin_m", (0.0, 0.0)))
    size = _pair(domain.get("size_m"))
    box = None
    if origin and size and min(size) > 0.0:
        tol = 1e-9 * max(size)
        box = (origin[0] - tol, origin[0] + size[0] + tol, origin[1] - tol, origin[1] + size[1] + tol)
    seen: dict[str, int] = {}
    for index, structure in enumerate(structures):
        if not isinstance(structure, Mapping):
            continue
        path = f"structures.{index}"
        name = structure.get("name")
        if isinstance(name, str):
            if name in SIDES:
                problems.append(Problem(f"{path}.name", name, f"is a side's name; not allowed: {', '.join(SIDES)}"))
            elif name in seen:
                problems.append(Problem(f"{path}.name", name, f"duplicate; structures.{seen[name]} has the same name"))
            else:
                seen[name] = index
        problems += _contact_rule(path, structure.get("contact"))
        if box is not None:
            problems += _outside_points(path, _array(structure.get("polygon_m")), box, origin, size)
    return problems


def _monitor_rules(stages: list[Any], domain: Mapping[str, Any]) -> list[Problem]:
    """A strength-reduction stage's monitor point lies in the domain (the search watches the
    particle nearest to it: one outside would silently watch a particle at the domain's edge)."""
    origin = _pair(domain.get("origin_m", (0.0, 0.0)))
    size = _pair(domain.get("size_m"))
    problems = []
    for index, stage in enumerate(stages):
        failure = stage.get("failure") if isinstance(stage, Mapping) else None
        point = _pair(failure.get("monitor_point_m")) if isinstance(failure, Mapping) else None
        if point is None or not (origin and size):
            continue
        if not (origin[0] <= point[0] <= origin[0] + size[0] and origin[1] <= point[1] <= origin[1] + size[1]):
            problems.append(Problem(f"stages.{index}.failure.monitor_point_m", list(point), "must lie in the domain "
                                    f"[{origin[0]:g}, {origin[0] + size[0]:g}] x [{origin[1]:g}, {origin[1] + size[1]:g}] m"))
    return problems


def _total_points_rule(data: Mapping[str, Any]) -> list[Problem]:
    """At most MAX_TOTAL_POINTS points in all the outlines and water lines together."""
    counts: dict[str, int] = {}
    for section in ("bodies", "structures"):
        for item in _array(data.get(section))[: MAX_ENTRIES[section] + 1]:
            if isinstance(item, Mapping) and isinstance(item.get("polygon_m"), (list, tuple)):
                if len(item["polygon_m"]) > MAX_POLYGON_POINTS:
                    return []  # that outline's own problem says it
                counts[section] = counts.get(section, 0) + len(item["polygon_m"])
    lines = [_table(data.get("water"))] + [_table(_table(st).get("water")) for st in _array(data.get("stages"))]
    for table in lines:
        for key in ("phreatic_line_m", "free_water_line_m"):
            if isinstance(table.get(key), (list, tuple)):
                if len(table[key]) > MAX_POLYGON_POINTS:
                    return []  # that line's own problem says it
                counts["water"] = counts.get("water", 0) + len(table[key])
    total = sum(counts.values())
    if total <= MAX_TOTAL_POINTS:
        return []
    most = max(counts, key=counts.get)
    return [Problem(most, None, f"the outlines and water lines have {total:,} points in all, more than the limit of "
                    f"{MAX_TOTAL_POINTS:,} (docs/project-format.md, size limits); simplify them")]


def _outside_points(path: str, points: list[Any], box: tuple[float, ...], origin: Any, size: Any) -> list[Problem]:
    if len(points) > MAX_POLYGON_POINTS:
        return []  # its own problem, before any point is looked at
    outside = []
    for k, point in enumerate(points):
        xy = _pair(point)
        if xy is not None and not (box[0] <= xy[0] <= box[1] and box[2] <= xy[1] <= box[3]):
            outside.append((k, point))
    if not outside:
        return []
    k, point = outside[0]
    extra = len(outside) - 1
    more = f" (and {extra} more point{'s' if extra > 1 else ''})" if extra else ""
    span = (
        f"x in [{origin[0]:g}, {origin[0] + size[0]:g}], "
        f"y in [{origin[1]:g}, {origin[1] + size[1]:g}]"
    )
    return [Problem(f"{path}.polygon_m.{k}", _plain(point), f"outside the domain ({span}){more}")]


def _numerics_rules(numerics: Mapping[str, Any]) -> list[Problem]:
    if numerics.get("preset") is not None and numerics.get("time_step_s") is not None:
        return [
            Problem(
                "numerics.time_step_s",
                numerics["time_step_s"],
                f"a preset ({numerics['preset']}) sets the time step through its cfl; remove one of them",
            )
        ]
    if numerics.get("time_step_s") is not None and numerics.get("cfl") is not None:
        return [
            Problem(
                "numerics.cfl",
                numerics["cfl"],
                f"give time_step_s or cfl, not both (time_step_s = {format_value(numerics['time_step_s'])})",
            )
        ]
    return []


_INITIAL_STRESS = ("k0", "gravity")
#: Keys only a strength-reduction stage may have.
STRENGTH_KEYS: tuple[str, ...] = ("materials", "tolerance", "first_trial", "bracket_step", "trial_duration_s",
                                  "max_trials", "limit_equilibrium", "failure")


def _stage_rules(stages: list[Any], materials: Mapping[str, Any]) -> list[Problem]:
    problems = []
    first_dynamic = None
    initial = None
    # Material values in force at each stage: changes persist into later stages.
    current = {name: dict(m) for name, m in materials.items() if isinstance(m, Mapping)}
    for index, stage in enumerate(stages):
        if not isinstance(stage, Mapping):
            continue
        path = f"stages.{index}"
        kind = stage.get("type")
        if kind in _INITIAL_STRESS:
            if first_dynamic is not None:
                problems.append(
                    Problem(f"{path}.type", kind, f"must come before the first dynamic stage (stages.{first_dynamic})")
                )
            elif initial is not None:
                problems.append(
                    Problem(f"{path}.type", kind, f"only one k0 or gravity stage is allowed (stages.{initial} is one)")
                )
            else:
                initial = index
        elif kind == "dynamic" and first_dynamic is None:
            first_dynamic = index
        if kind in STAGE_TYPES:
            problems += _stage_keys(path, kind, stage)
        problems += _change_rules(path, _table(stage.get("material_changes")), current)
    problems += _strength_rules(stages, materials)
    return problems


def _strength_rules(stages: list[Any], materials: Mapping[str, Any]) -> list[Problem]:
    """A strength-reduction stage follows the initial stress; at most one dynamic stage follows it."""
    problems = []
    kinds = [stage.get("type") if isinstance(stage, Mapping) else None for stage in stages]
    sr = [i for i, kind in enumerate(kinds) if kind == "strength-reduction"]
    for index, stage in enumerate(stages):
        if not isinstance(stage, Mapping):
            continue
        path = f"stages.{index}"
        if kinds[index] != "strength-reduction":
            for key in STRENGTH_KEYS:
                if key in stage:
                    problems.append(Problem(f"{path}.{key}", stage[key], "only allowed on a strength-reduction stage"))
            if "strength_factor" in stage and not (sr and kinds[index] == "dynamic" and index > sr[0]):
                problems.append(Problem(f"{path}.strength_factor", stage["strength_factor"],
                                        "only allowed on the dynamic stage after a strength-reduction stage"))
    if not sr:
        return problems
    first = sr[0]
    path = f"stages.{first}"
    if len(sr) > 1:
        problems.append(Problem(f"stages.{sr[1]}.type", "strength-reduction",
                                f"only one strength-reduction stage is allowed (stages.{first} is one)"))
    if not any(kind in _INITIAL_STRESS for kind in kinds[:first]) or any(kind == "dynamic" for kind in kinds[:first]):
        problems.append(Problem(f"{path}.type", "strength-reduction",
                                "must follow the initial-stress stage (k0 or gravity) and come before any dynamic stage"))
    after = [i for i in range(first + 1, len(stages)) if kinds[i] != "strength-reduction"]
    if len(after) > 1:
        problems.append(Problem(f"stages.{after[1]}.type", kinds[after[1]],
                                "at most one stage (the dynamic run-out) may follow a strength-reduction stage"))
    stage = stages[first] if isinstance(stages[first], Mapping) else {}
    for key in ("duration_s", "ramp_fraction", "k0", *REST_KEYS, "min_duration_s", "material_changes"):
        if key in stage:
            problems.append(Problem(f"{path}.{key}", stage[key], "not allowed on a strength-reduction stage"))
    names = stage.get("materials")
    if isinstance(names, (list, tuple)):
        plastic = [n for n, m in materials.items() if isinstance(m, Mapping) and m.get("model") == "drucker-prager"]
        for k, name in enumerate(names):
            if isinstance(name, str) and name not in plastic:
                problems.append(Problem(f"{path}.materials.{k}", name,
                                        f"not a drucker-prager material; defined: {_defined(plastic)}"))
        if not names:
            problems.append(Problem(f"{path}.materials", [], "needs at least one material"))
    elif names is None and not any(isinstance(m, Mapping) and m.get("model") == "drucker-prager"
                                   for m in materials.values()):
        problems.append(Problem(f"{path}.type", "strength-reduction", "needs a drucker-prager material to reduce"))
    has_gravity = any(kind == "gravity" for kind in kinds[:first])
    if "trial_duration_s" not in stage and not has_gravity:
        problems.append(Problem(f"{path}.trial_duration_s", None,
                                "required when there is no gravity stage (its duration is the default)"))
    return problems


def _stage_keys(path: str, kind: str, stage: Mapping[str, Any]) -> list[Problem]:
    problems = []
    if kind == "strength-reduction":
        return problems  # its keys are checked by _strength_rules
    if kind == "k0":
        for key in ("duration_s", "damping"):
            if key in stage:
                problems.append(Problem(f"{path}.{key}", stage[key], "not allowed on a k0 stage (it takes no time)"))
    elif "duration_s" not in stage:
        problems.append(Problem(f"{path}.duration_s", None, f"required for a {kind} stage"))
    if kind == "gravity" and _num(_table(stage.get("damping")).get("coefficient")) == 0.0:
        # An undamped gravity stage never settles (and the solver would use 0.7 instead).
        problems.append(Problem(f"{path}.damping.coefficient", 0.0, "must be > 0 on a gravity stage"))
    if kind != "k0" and "k0" in stage:
        problems.append(Problem(f"{path}.k0", stage["k0"], "only allowed on a k0 stage"))
    if kind != "gravity" and "ramp_fraction" in stage:
        problems.append(Problem(f"{path}.ramp_fraction", stage["ramp_fraction"], "only allowed on a gravity stage"))
    if kind != "dynamic":
        for key in (*REST_KEYS, "min_duration_s"):
            if key in stage:
                problems.append(Problem(f"{path}.{key}", stage[key], "only allowed on a dynamic stage"))
    elif "min_duration_s" in stage:
        minimum = _num(stage["min_duration_s"])
        duration = _num(stage.get("duration_s"))
        if not any(key in stage for key in REST_KEYS):
            problems.append(
                Problem(f"{path}.min_duration_s", stage["min_duration_s"],
                        "only allowed with stop_when_kinetic_energy_below or stop_when_max_speed_below_m_s")
            )
        elif minimum is not None and duration is not None and minimum > duration:
            problems.append(Problem(f"{path}.min_duration_s", minimum, f"must not exceed duration_s ({duration:g})"))
    return problems


def _change_rules(path: str, changes: Mapping[str, Any], current: dict[str, dict[str, Any]]) -> list[Problem]:
    problems = []
    for name, change in changes.items():
        change_path = f"{path}.material_changes.{name}"
        if name not in current:
            problems.append(Problem(change_path, None, f"no such material; defined: {_defined(list(current))}"))
            continue
        if not isinstance(change, Mapping):
            continue
        material = current[name]
        if material.get("model") == "rigid":
            for key in change:
                if key != "velocity_m_s":
                    problems.append(Problem(f"{change_path}.{key}", change[key],
                                            'a rigid body changes only its velocity_m_s between stages'))
            continue
        if "velocity_m_s" in change:
            problems.append(Problem(f"{change_path}.velocity_m_s", change["velocity_m_s"], 'only allowed with model "rigid"'))
        problems += _damping_rule(change_path, {**material, **change})
        problems += _wave_speed_rule(change_path, {**material, **change}, change)
        if "saturated_density_kg_m3" in change or "density_kg_m3" in change:
            problems += _saturated_rule(change_path, {**material, **change})
        if material.get("model") == "linear-elastic":
            for key in PLASTIC_KEYS:
                if key in change:
                    problems.append(
                        Problem(f"{change_path}.{key}", change[key], 'only allowed with model "drucker-prager"')
                    )
            continue
        material.update(change)
        touches_angles = "friction_angle_deg" in change or "dilatancy_angle_deg" in change
        if material.get("model") == "drucker-prager" and touches_angles:
            problems += _dilatancy_rule(change_path, material, changed=change)
        if material.get("model") == "drucker-prager":
            problems += _softening_rule(change_path, material, changed=change)
    return problems
