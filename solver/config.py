"""Frozen configuration of one solver run, in SI units (angles in radians).

This is the whole input contract of :mod:`solver`: ``projects`` builds these objects from a
project file; tests build them directly. Nothing here imports Taichi.

Conventions
-----------
- 2D plane strain, x to the right, y up (gravity may point anywhere).
- Stress is positive in tension (compression negative), components ``xx, yy, xy, zz``.
- Masses, energies and momenta are per metre out of plane.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

Scheme = Literal["mpm", "apic", "apic-affine"]
SCHEMES: tuple[str, ...] = ("mpm", "apic", "apic-affine")
MaterialModel = Literal["linear-elastic", "drucker-prager", "rigid"]
#: ``rigid``: a kinematic body moved at a prescribed velocity (a platen, a gate; solver/rigid.py)
MATERIAL_MODELS: tuple[str, ...] = ("linear-elastic", "drucker-prager", "rigid")
#: How a Drucker-Prager cone is matched to Mohr-Coulomb's c and phi (solver/materials/drucker_prager.py).
MOHR_COULOMB_MATCHES: tuple[str, ...] = ("plane-strain-associated", "plane-strain", "simple-shear")
DEFAULT_MOHR_COULOMB_MATCH = "plane-strain-associated"
#: Material damping models (docs/solver.md, material damping): ``rayleigh`` a stiffness-proportional
#: dashpot, damping in proportion to frequency; ``maxwell`` a spring and dashpot in series (a
#: standard linear solid) whose damping peaks at the given frequency and costs the step little.
DAMPING_MODELS: tuple[str, ...] = ("rayleigh", "maxwell")
DEFAULT_DAMPING_MODEL = "rayleigh"
#: Strain-softening laws of a Drucker-Prager material (solver/materials/softening.py).
SOFTENING_LAWS: tuple[str, ...] = ("linear", "exponential")
BoundaryKind = Literal["fixed", "slip", "friction", "open", "periodic"]
Side = Literal["left", "right", "bottom", "top"]
SIDES: tuple[str, ...] = ("left", "right", "bottom", "top")
StageKind = Literal["k0", "gravity", "dynamic"]
Precision = Literal["f32", "f64"]
Arch = Literal["auto", "cpu", "gpu"]
GuardMode = Literal["stop", "remove"]
GUARD_MODES: tuple[str, ...] = ("stop", "remove")
PRECISIONS: tuple[str, ...] = ("f32", "f64")
ARCHS: tuple[str, ...] = ("auto", "cpu", "gpu")
STAGE_KINDS: tuple[str, ...] = ("k0", "gravity", "dynamic")
BOUNDARY_KINDS: tuple[str, ...] = ("fixed", "slip", "open", "friction", "periodic")
#: Sides that may be ``periodic`` (as a pair: both or neither).
PERIODIC_SIDES: tuple[str, ...] = ("left", "right")
#: The fewest cells across a periodic pair of sides (a particle's stencil must not reach its own image).
MIN_PERIODIC_CELLS = 3
#: How particle contributions reach shared grid nodes (solver/engine.py explains each).
SCATTERS: tuple[str, ...] = ("auto", "atomic", "serial", "split")
#: Volumetric averaging (the remedy for volumetric locking, docs/solver.md): ``auto`` turns it on
#: where a material flows plastically at constant volume without friction (see
#: :func:`averages_volume`), ``on`` and ``off`` for every run.
VOLUMETRIC_AVERAGING: tuple[str, ...] = ("auto", "on", "off")
#: Fraction of the critical time step when a project gives neither ``time_step_s`` nor ``cfl``.
DEFAULT_CFL = 0.5
#: The stability guard's speed bound in units of the free-fall speed over the scene (docs/solver.md).
DEFAULT_SPEED_BOUND_FACTOR = 3.0

#: Frame fields a run may be asked for (``positions`` and ``active`` are always present).
OUTPUT_FIELDS: tuple[str, ...] = ("displacement", "velocity", "stress", "plastic_strain", "material",
                                   "pore_pressure")
#: Fields written only where the run has water (``pore_pressure``: none in a dry run).
WATER_FIELDS: tuple[str, ...] = ("pore_pressure",)


@dataclass(frozen=True)
class Softening:
    """Strength falling from a material's peak (its cohesion, friction and dilatancy) to these
    residual values with the equivalent plastic strain (solver/materials/softening.py).

    ``law``: one of :data:`SOFTENING_LAWS`; ``peak_strain``, ``residual_strain``: where the drop
    starts and where it ends (linear) or is 95 % done (exponential), as strains of a band of width
    ``length_m``; ``length_m``: the material length that regularises the softening (None: the
    strains are the particles' own, and the result depends on the cell size).
    """

    residual_cohesion_pa: float
    residual_friction_angle_rad: float
    residual_dilatancy_angle_rad: float
    residual_strain: float
    peak_strain: float = 0.0
    law: str = "linear"
    length_m: float | None = None


@dataclass(frozen=True)
class InertialFriction:
    """The rate dependence of a granular material's friction, the mu(I) law of dense granular flow
    (GDR MiDi 2004; Jop, Forterre and Pouliquen 2006, Nature 441:727):

        mu(I) = mu_s + friction_increase * I / (reference_inertial_number + I)
        I = gamma_dot d / sqrt(p / rho_s)

    ``mu_s = tan(phi)`` the material's own friction, ``gamma_dot = sqrt(2 D':D')`` the shear rate
    (the deviator of the rate of deformation, out-of-plane component included), ``p`` the mean
    pressure, ``d`` the grain diameter and ``rho_s`` the grains' density. The cone's slope follows
    the friction coefficient, ``alpha(I) = alpha mu(I) / mu_s`` (solver/materials/__init__.py).
    """

    friction_increase: float
    reference_inertial_number: float
    grain_diameter_m: float
    grain_density_kg_m3: float


@dataclass(frozen=True)
class Material:
    """Parameters of one material (one row of the per-material tables).

    ``tensile_strength_pa`` caps the mean stress (tension cut-off); ``None`` means the
    Drucker-Prager apex is the only limit. ``mohr_coulomb_match`` picks how the cone's constants
    follow from c, phi and psi (one of ``MOHR_COULOMB_MATCHES``, see
    ``solver.materials.drucker_prager.dp_constants``).
    """

    name: str
    model: MaterialModel
    density_kg_m3: float
    youngs_modulus_pa: float
    poisson_ratio: float
    cohesion_pa: float = 0.0
    friction_angle_rad: float = 0.0
    dilatancy_angle_rad: float = 0.0
    tensile_strength_pa: float | None = None
    mohr_coulomb_match: str = DEFAULT_MOHR_COULOMB_MATCH
    #: material damping: the critical-damping fraction ``damping_ratio`` at ``damping_frequency_hz``
    #: (0: undamped), by ``damping_model`` (one of DAMPING_MODELS; docs/solver.md, material damping)
    damping_ratio: float = 0.0
    damping_frequency_hz: float = 0.0
    damping_model: str = DEFAULT_DAMPING_MODEL
    #: density below the phreatic line (None: ``density_kg_m3`` there too; solver/water.py)
    saturated_density_kg_m3: float | None = None
    #: pore-pressure ratio ``r_u = u / sigma_v`` (total vertical stress), the engineers' shortcut
    #: for a pore pressure in proportion to the overburden (0: none; solver/water.py)
    ru: float = 0.0
    #: strain softening (None: the strength stays at its peak)
    softening: Softening | None = None
    #: rate-dependent friction, the mu(I) law (None: the friction does not depend on the rate)
    inertial: InertialFriction | None = None
    #: a rigid material's velocity (m/s) in dynamic stages, and its contact with the material it
    #: touches (solver/rigid.py); unused by the other models
    velocity_m_s: tuple[float, float] = (0.0, 0.0)
    contact: Boundary = field(default_factory=lambda: Boundary("fixed"))

    @property
    def rigid(self) -> bool:
        """Whether the material is a rigid body moved at its velocity (no stress, no weight)."""
        return self.model == "rigid"

    @property
    def wet_density_kg_m3(self) -> float:
        """The density below the phreatic line."""
        return self.density_kg_m3 if self.saturated_density_kg_m3 is None else self.saturated_density_kg_m3

    @property
    def damped(self) -> bool:
        """Whether the material has a damping (a ratio above zero at a frequency)."""
        return self.damping_ratio > 0.0 and self.damping_frequency_hz > 0.0

    @property
    def maxwell_stiffening(self) -> float:
        """The Maxwell arm's spring as a fraction ``a`` of the elastic stiffness (0 for Rayleigh
        damping). A mode of natural angular frequency ``omega`` (of the elastic stiffness) of a
        standard linear solid decays at most by ``(sqrt(1 + a) - 1) / 2`` of critical, when the arm
        relaxes in ``t = (1 + a)^(-3/4) / omega`` (from the roots of
        ``T s^3 + s^2 + (1 + a) T s + 1``, ``T = omega t``, ``s`` in units of ``omega``); this ``a``,
        ``4 zeta (1 + zeta)``, makes that maximum ``damping_ratio`` at ``damping_frequency_hz``.
        The mode then vibrates ``sqrt(1 + 2 zeta)`` times faster (the arm's spring)."""
        if not self.damped or self.damping_model != "maxwell":
            return 0.0
        return 4.0 * self.damping_ratio * (1.0 + self.damping_ratio)

    @property
    def damping_relaxation_s(self) -> float:
        """The Maxwell arm's relaxation time ``t`` (s), which makes its damping peak at
        ``damping_frequency_hz`` (0 for Rayleigh damping: the dashpot alone)."""
        a = self.maxwell_stiffening
        if a <= 0.0:
            return 0.0
        return (1.0 + a) ** -0.75 / (2.0 * math.pi * self.damping_frequency_hz)

    @property
    def damping_beta_s(self) -> float:
        """The damping's viscosity as a multiple of the elastic stiffness (s): the damping stress
        is ``beta C : D`` for Rayleigh damping, ``beta = zeta / (pi f)``, which damps a mode of
        angular frequency ``omega`` by ``beta omega / 2`` of critical, ``zeta`` at ``f``; for the
        Maxwell arm, ``beta = a t``, its dashpot, which the arm's spring relaxes in ``t``."""
        if not self.damped:
            return 0.0
        if self.damping_model == "maxwell":
            return self.maxwell_stiffening * self.damping_relaxation_s
        return self.damping_ratio / (math.pi * self.damping_frequency_hz)

    @property
    def bulk_modulus_pa(self) -> float:
        return self.youngs_modulus_pa / (3.0 * (1.0 - 2.0 * self.poisson_ratio))

    @property
    def shear_modulus_pa(self) -> float:
        return self.youngs_modulus_pa / (2.0 * (1.0 + self.poisson_ratio))

    @property
    def p_wave_speed_m_s(self) -> float:
        """Speed of the dilatational wave, sqrt((K + 4G/3) / rho)."""
        constrained = self.bulk_modulus_pa + 4.0 * self.shear_modulus_pa / 3.0
        return math.sqrt(constrained / self.density_kg_m3)

    def damping_ratio_at(self, frequency_hz: float) -> float:
        """The fraction of critical damping of a mode of natural frequency ``frequency_hz`` (of
        the elastic stiffness): ``beta omega / 2`` (Rayleigh); from the free vibration of the
        standard linear solid (Maxwell), 1 where it no longer vibrates."""
        omega = 2.0 * math.pi * frequency_hz
        a = self.maxwell_stiffening
        if a > 0.0:
            T = omega * self.damping_relaxation_s
            roots = np.roots([T, 1.0, (1.0 + a) * T, 1.0])
            vibrating = roots[np.abs(roots.imag) > 1e-12 * np.abs(roots)]
            if not len(vibrating):
                return 1.0
            return float(-vibrating[0].real / abs(vibrating[0]))
        return 0.5 * self.damping_beta_s * omega

    def damping_step_shrink(self, cell_size_m: float) -> float:
        """How many times shorter the damping makes this material's stability limit (1: undamped)."""
        return (dataclasses.replace(self, damping_ratio=0.0).critical_time_step_s(cell_size_m)
                / self.critical_time_step_s(cell_size_m))

    def critical_time_step_s(self, cell_size_m: float, max_speed_m_s: float = 0.0) -> float:
        """The explicit step's stability limit in this material: ``dx / (c_p + v_max)``; with
        Rayleigh damping shortened by ``sqrt(1 + xi^2) - xi`` (the central-difference limit under
        stiffness-proportional damping, ``omega_max dt <= 2 (sqrt(1 + xi^2) - xi)`` with
        ``xi = beta omega_max / 2`` the damping fraction of the grid's highest mode,
        ``omega_max = 2 c_p / dx``; Belytschko, Liu and Moran, Nonlinear Finite Elements for
        Continua and Structures, 2000, sec. 6.3); with the Maxwell arm, by ``1 / sqrt(1 + a)``:
        at the grid's highest frequencies the arm is its spring alone, which stiffens the material
        by ``1 + a``, and a one-degree-of-freedom model of the update (force from the stresses,
        then both stresses from the new velocity, the arm's exactly) is stable up to
        ``omega sqrt(1 + a) dt = 2`` and beyond where the damping peak nears the grid's frequency
        (measured: a bar damped 0.9 is stable to 1.1 times this step, unstable from 1.5 times)."""
        if self.rigid:  # no wave: only its own motion across the cells limits the step
            speed = math.hypot(*self.velocity_m_s) + max_speed_m_s
            return cell_size_m / speed if speed > 0.0 else math.inf
        a = self.maxwell_stiffening
        step = cell_size_m / (self.p_wave_speed_m_s * math.sqrt(1.0 + a) + max_speed_m_s)
        beta = self.damping_beta_s
        if beta > 0.0 and a == 0.0:
            xi = beta * self.p_wave_speed_m_s / cell_size_m
            step /= math.hypot(1.0, xi) + xi  # times sqrt(1 + xi^2) - xi, without the cancellation
        return step

    @property
    def default_k0(self) -> float:
        """Jaky's K0 = 1 - sin(phi) for frictional soil, nu/(1-nu) for an elastic solid."""
        if self.model == "drucker-prager" and self.friction_angle_rad > 0.0:
            return 1.0 - math.sin(self.friction_angle_rad)
        return self.poisson_ratio / (1.0 - self.poisson_ratio)


def locks(material) -> bool:
    """Whether a material's plastic flow keeps its volume without friction (phi = psi = 0, an
    undrained clay), the flow that locks quadratic B-spline MPM most (docs/solver.md, volumetric
    locking)."""
    return material.model == "drucker-prager" and material.friction_angle_rad == 0.0 \
        and material.dilatancy_angle_rad == 0.0


def averages_volume(setting: str, materials) -> bool:
    """Whether a run averages the volumetric strain rate: ``on``, ``off``, or ``auto`` where one of
    ``materials`` (those of every stage) :func:`locks`."""
    if setting not in VOLUMETRIC_AVERAGING:
        raise ValueError(f"volumetric_averaging {setting!r}: must be one of {', '.join(VOLUMETRIC_AVERAGING)}")
    return setting == "on" or (setting == "auto" and any(locks(m) for m in materials))


def softens(materials) -> bool:
    """Whether some of ``materials`` softens (the softening return map is compiled in only then)."""
    return any(m.model == "drucker-prager" and m.softening is not None for m in materials)


def has_rigid(materials) -> bool:
    """Whether some of ``materials`` is a rigid body (solver/rigid.py, compiled in only then)."""
    return any(m.model == "rigid" for m in materials)


def flows_inertially(materials) -> bool:
    """Whether some of ``materials`` has a rate-dependent friction (mu(I), compiled in only then)."""
    return any(m.model == "drucker-prager" and m.inertial is not None for m in materials)


@dataclass(frozen=True)
class Boundary:
    """Velocity constraint of one side of the grid box.

    - ``fixed``: no-slip, both velocity components of the wall nodes are zero.
    - ``slip``: frictionless contact; the velocity component into the wall is removed,
      separation is allowed (symmetry plane / roller for material pressing on it).
    - ``friction``: as ``slip`` plus Coulomb friction: the tangential speed is reduced by
      ``tan(friction_angle) * |normal velocity removed|``, never reversed.
    - ``open``: no constraint; particles that leave the box are removed and counted as lost.
    - ``periodic``: left and right only, and both together: the two sides are one line, the
      material leaving through one re-enters through the other, and grid nodes on either side of
      it are shared (an infinitely long model repeating every domain width; docs/solver.md).
    """

    kind: BoundaryKind = "slip"
    friction_angle_rad: float = 0.0


@dataclass(frozen=True)
class Grid:
    """The background grid: a box of square cells. ``size_m`` is rounded up to whole cells."""

    origin_m: tuple[float, float]
    size_m: tuple[float, float]
    cell_size_m: float
    left: Boundary = Boundary()
    right: Boundary = Boundary()
    bottom: Boundary = Boundary("fixed")
    top: Boundary = Boundary("open")

    @property
    def cells(self) -> tuple[int, int]:
        return (
            max(1, math.ceil(self.size_m[0] / self.cell_size_m - 1e-9)),
            max(1, math.ceil(self.size_m[1] / self.cell_size_m - 1e-9)),
        )

    def boundary(self, side: str) -> Boundary:
        return getattr(self, side)

    @property
    def periodic(self) -> bool:
        """Whether the left and right sides are a periodic pair."""
        return self.left.kind == "periodic"

    def periodic_problem(self) -> str | None:
        """Why the sides' ``periodic`` kinds are inconsistent (None when they are fine)."""
        for side in SIDES:
            if self.boundary(side).kind == "periodic" and side not in PERIODIC_SIDES:
                return f"the {side} side cannot be periodic; allowed: left and right together"
        if (self.left.kind == "periodic") != (self.right.kind == "periodic"):
            return (f"left is {self.left.kind} and right is {self.right.kind}: periodic sides come as a pair, "
                    "both or neither")
        if self.periodic and self.cells[0] < MIN_PERIODIC_CELLS:
            return f"a periodic pair of sides needs at least {MIN_PERIODIC_CELLS} cells across, got {self.cells[0]}"
        return None


@dataclass(frozen=True)
class Structure:
    """A rigid body inside the domain: a simple polygon (metres, either orientation) whose surface is a
    contact like a closed side: ``contact`` is a :class:`Boundary` of kind ``fixed``, ``slip`` or
    ``friction`` (never ``open``). Grid nodes on or inside the polygon are constrained with the
    polygon's outward normal (see docs/solver.md, contact), and no particle ends a step inside it.
    """

    name: str
    polygon_m: tuple[tuple[float, float], ...]
    contact: Boundary = Boundary("slip")


#: The part of a gravity stage over which gravity is ramped up when the stage does not say; the
#: rest holds it with damping so that the model settles under the full load. Ramped to the very end
#: (the source paper's procedure, 1.0) a 20-cell elastic block 5 degrees inside its friction limit
#: still moved at 9 mm/s (unbalanced-force ratio 0.004) and slipped 1.1 mm, 0.1 % of the frictionless
#: distance, in the next 0.5 s (apic); ramped over half: 0.0002 (0.3 mm/s) and 0.000 mm (docs/validation.md).
GRAVITY_RAMP_FRACTION = 0.5


@dataclass(frozen=True)
class Water:
    """Steady, drained ground water, prescribed (not solved): solver/water.py and docs/solver.md.

    ``phreatic_line_m`` is the piezometric line of the water in the ground, a polyline with x
    strictly increasing, extended level beyond its ends. Below it the pore pressure is
    hydrostatic, ``u = gamma_w h`` with ``h`` the depth below the line along gravity, or
    ``gamma_w h cos^2(theta)`` with ``inclined_correction`` (``theta`` the line's inclination
    from level: seepage parallel to an inclined line). ``free_water_line_m`` is the level of
    free water standing above the ground (a reservoir, a pond; None: the phreatic line); it
    differs from the phreatic line where the water in the slope lags the free water (rapid
    drawdown). ``unit_weight_n_m3`` is the water's unit weight under the full gravity of the
    configuration.
    """

    phreatic_line_m: tuple[tuple[float, float], ...]
    free_water_line_m: tuple[tuple[float, float], ...] | None = None
    unit_weight_n_m3: float = 9810.0
    inclined_correction: bool = False

    @property
    def free_water(self) -> tuple[tuple[float, float], ...]:
        """The free water's level (the phreatic line where none is given)."""
        return self.phreatic_line_m if self.free_water_line_m is None else self.free_water_line_m


@dataclass(frozen=True)
class Surcharge:
    """A distributed load on the ground surface (solver/loads.py, docs/solver.md, loads).

    It acts along gravity on the uppermost particles (highest y) of the ground between
    ``x = from_m`` and ``x = to_m`` (project coordinates, ``from_m < to_m``), ``pressure_pa`` at
    ``from_m`` and ``pressure_end_pa`` at ``to_m`` (None: ``pressure_pa`` throughout), linear
    between them, per unit length of x (with gravity along -y: per horizontal area, a fill's
    ``gamma t``). It is a force, not a mass: it has no inertia and no seismic share. The particles
    under it at the start of a stage carry it, wherever they move.
    """

    name: str
    from_m: float
    to_m: float
    pressure_pa: float
    pressure_end_pa: float | None = None

    def pressure_at(self, x_m):
        """The pressure at ``x_m`` (Pa; linear between the ends, the end values beyond them)."""
        end = self.pressure_pa if self.pressure_end_pa is None else self.pressure_end_pa
        t = np.clip((np.asarray(x_m, dtype=np.float64) - self.from_m) / (self.to_m - self.from_m), 0.0, 1.0)
        return self.pressure_pa + t * (end - self.pressure_pa)

    @property
    def force_n_per_m(self) -> float:
        """The load's resultant, N per metre out of plane: the pressure integrated over the segment."""
        end = self.pressure_pa if self.pressure_end_pa is None else self.pressure_end_pa
        return 0.5 * (self.pressure_pa + end) * (self.to_m - self.from_m)


@dataclass(frozen=True)
class Seismic:
    """Pseudo-static seismic coefficients of a stage (docs/solver.md, loads).

    The body force per unit mass is ``g + k_h |g| h + k_v |g| u``: ``u = -g / |g|`` points up,
    ``h`` is horizontal (across gravity) with ``direction`` +1 along ``(u_y, -u_x)`` (+x when
    gravity points along -y) and -1 against it. So a mass ``m`` feels ``k_h m |g|`` horizontally
    and weighs ``(1 - k_v) m |g|``: ``k_v > 0`` is an upward inertial force.
    """

    k_h: float = 0.0
    k_v: float = 0.0
    direction: float = 1.0


def body_force_m_s2(gravity_m_s2, seismic: Seismic | None) -> tuple[float, float]:
    """The body force per unit mass of a stage (m/s2): gravity, with its seismic coefficients.

    This is the one place where a stage's seismic coefficients enter the solver (the run's steps,
    the strength-reduction trials). Without them, gravity itself (the same floats)."""
    gx, gy = float(gravity_m_s2[0]), float(gravity_m_s2[1])
    if seismic is None or (seismic.k_h == 0.0 and seismic.k_v == 0.0):
        return (gx, gy)
    gn = math.hypot(gx, gy)
    if gn == 0.0:
        return (gx, gy)
    ux, uy = -gx / gn, -gy / gn
    hx, hy = seismic.direction * uy, -seismic.direction * ux
    return (gx + gn * (seismic.k_h * hx + seismic.k_v * ux), gy + gn * (seismic.k_h * hy + seismic.k_v * uy))


@dataclass(frozen=True)
class Stage:
    """One stage of the analysis.

    - ``k0``: no time passes; geostatic stress from the overburden, horizontal = K0 * vertical.
      ``k0`` overrides every material's default K0.
    - ``gravity``: gravity ramped linearly from zero over the first ``ramp_fraction`` of
      ``duration_s`` (default :data:`GRAVITY_RAMP_FRACTION`), then held at full value to the
      stage's end, all with local damping (``damping``; the project layer fills in 0.7 when the
      file gives none); then all velocities are set to zero. The hold lets the model settle
      under the full load: at the end of a ramp the deformation still lags the load.
    - ``dynamic``: free motion for ``duration_s``; may end early once the mass has come to rest,
      after ``min_duration_s``: when the kinetic energy is below ``stop_when_kinetic_energy_below``
      times the stage's peak and the fastest particle slower than ``stop_when_max_speed_below_m_s``
      (each where given; a speed alone counts once some particle was faster than it in the stage).

    ``materials`` replaces the material table at the start of the stage (``None``: unchanged);
    this is how a trigger such as "cohesion to zero" is expressed.
    ``damping`` is Cundall's local damping coefficient (0 = none).
    """

    name: str
    kind: StageKind
    duration_s: float = 0.0
    damping: float = 0.0
    k0: float | None = None
    materials: tuple[Material, ...] | None = None
    stop_when_kinetic_energy_below: float | None = None
    min_duration_s: float = 0.0
    stop_when_max_speed_below_m_s: float | None = None
    ramp_fraction: float | None = None
    #: where the stage moves the ground water: linearly from its position at the stage's start to
    #: this one over ``duration_s`` (None: unchanged; at once in a k0 stage)
    water: Water | None = None
    #: the surcharges in force during the stage (solver/loads.py): at once, or, in a gravity stage,
    #: ramped up with gravity
    surcharges: tuple[Surcharge, ...] = ()
    #: a load that changes over the stage: the surcharges at its start, from which those of
    #: ``surcharges`` are reached linearly over ``duration_s`` (None: at once)
    surcharges_from: tuple[Surcharge, ...] | None = None
    #: pseudo-static seismic coefficients (None: gravity alone)
    seismic: Seismic | None = None

    @property
    def ramp_s(self) -> float:
        """How long a gravity stage ramps gravity up (s): ``ramp_fraction`` (None: the default
        :data:`GRAVITY_RAMP_FRACTION`) of ``duration_s``."""
        fraction = GRAVITY_RAMP_FRACTION if self.ramp_fraction is None else self.ramp_fraction
        return fraction * self.duration_s

    @property
    def ends_at_rest(self) -> bool:
        """Whether the stage may end when the mass has come to rest (a dynamic stage with a criterion)."""
        return self.kind == "dynamic" and (self.stop_when_kinetic_energy_below is not None
                                           or self.stop_when_max_speed_below_m_s is not None)


@dataclass(frozen=True)
class Numerics:
    """Time integration and runtime choices. Give ``time_step_s`` or ``cfl``, not both.

    ``cfl`` is the fraction of the critical step ``dx / (c_p + max particle speed)``.
    ``guard``: what the stability guard does with particles faster than the physical bound:
    ``stop`` ends the run with a message; ``remove`` takes them out of the computation and
    counts them (used by the stability studies). NaN always stops the run.
    """

    scheme: Scheme = "apic-affine"
    time_step_s: float | None = None
    cfl: float | None = DEFAULT_CFL
    precision: Precision = "f32"
    arch: Arch = "auto"
    guard: GuardMode = "stop"
    speed_bound_factor: float = DEFAULT_SPEED_BOUND_FACTOR
    scatter: str = "auto"
    volumetric_averaging: str = "auto"


@dataclass(frozen=True)
class Output:
    """Frames every ``interval_s`` of simulated time with the named ``fields`` (OUTPUT_FIELDS)."""

    interval_s: float = 0.01
    fields: tuple[str, ...] = OUTPUT_FIELDS


@dataclass(frozen=True)
class Target:
    """A place whose hazard history is recorded: a vertical line at ``x_m`` (``y_m`` None) or the
    point ``(x_m, y_m)``."""

    name: str
    x_m: float
    y_m: float | None = None


@dataclass(frozen=True)
class EnvelopeConfig:
    """Hazard envelopes accumulated on the device during the dynamic stages (solver.envelopes).

    ``cell_size_m`` is the raster cell (square, from the grid's origin over the grid box);
    ``every_steps`` the steps between updates (every output frame is an update too);
    ``flow_height_threshold_m`` the flow height above which a column counts as reached (first
    arrival, run-out of the peak-height envelope); ``targets`` the places whose time series are
    recorded; ``ground_m`` optional (nx,) heights of rigid ground under the raster columns (m),
    raised to wherever the initial material surface is higher.
    """

    cell_size_m: float
    every_steps: int = 10
    flow_height_threshold_m: float = 0.0
    targets: tuple[Target, ...] = ()
    ground_m: tuple[float, ...] | None = None


@dataclass(frozen=True)
class SimulationConfig:
    grid: Grid
    materials: tuple[Material, ...]
    stages: tuple[Stage, ...]
    gravity_m_s2: tuple[float, float] = (0.0, -9.81)
    numerics: Numerics = Numerics()
    output: Output = Output()
    #: rigid structures in the domain (contact like the closed sides)
    structures: tuple[Structure, ...] = ()
    #: hazard envelopes (None: none are accumulated)
    envelopes: EnvelopeConfig | None = None
    #: the ground water at the start (None: dry, unless a stage brings water)
    water: Water | None = None

    @property
    def has_water(self) -> bool:
        """Whether any pore pressure is compiled in: a water line here or in a stage, or an r_u."""
        return (self.water is not None or any(st.water is not None for st in self.stages)
                or any(m.ru > 0.0 for m in self.materials)
                or any(m.ru > 0.0 for st in self.stages for m in (st.materials or ())))

    @property
    def has_surcharges(self) -> bool:
        """Whether some stage has a surcharge (the load component is compiled in only then)."""
        return any(st.surcharges or st.surcharges_from for st in self.stages)

    @property
    def has_seismic(self) -> bool:
        """Whether some stage has seismic coefficients."""
        return any(st.seismic is not None for st in self.stages)


@dataclass(frozen=True, eq=False)
class Particles:
    """Initial particle state.

    Attributes
    ----------
    positions_m : (N, 2) float
    volumes_m2 : (N,) float, area per metre out of plane
    material_ids : (N,) int, index into ``SimulationConfig.materials``
    velocities_m_s : (N, 2) float, optional (zeros)
    bounds_m : (N, 4) float, optional: the box (x min, y min, x max, y max) of the material each
        particle stands for (lattice seeding), for the k0 stage's bars; otherwise ``sqrt(V)`` wide
    """

    positions_m: np.ndarray
    volumes_m2: np.ndarray
    material_ids: np.ndarray
    velocities_m_s: np.ndarray | None = None
    bounds_m: np.ndarray | None = None

    def __post_init__(self) -> None:
        n = len(self.positions_m)
        if np.shape(self.positions_m) != (n, 2):
            raise ValueError(f"positions_m must have shape (N, 2), got {np.shape(self.positions_m)}")
        if np.shape(self.volumes_m2) != (n,) or np.shape(self.material_ids) != (n,):
            raise ValueError("volumes_m2 and material_ids must have shape (N,) matching positions_m")
        if self.velocities_m_s is not None and np.shape(self.velocities_m_s) != (n, 2):
            raise ValueError("velocities_m_s must have shape (N, 2) matching positions_m")
        if self.bounds_m is not None and np.shape(self.bounds_m) != (n, 4):
            raise ValueError("bounds_m must have shape (N, 4) matching positions_m")

    def __len__(self) -> int:
        return len(self.positions_m)


@dataclass(frozen=True)
class Diagnostics:
    """Scalar state of the run at one output time (per metre out of plane)."""

    time_s: float
    stage: str
    stage_index: int
    stage_time_s: float
    step: int
    dt_s: float
    kinetic_energy_J_per_m: float
    momentum_x: float
    momentum_y: float
    max_speed_m_s: float
    unstable_particles: int
    lost_particles: int
    total_mass_kg_per_m: float
    yielding_particles: int


@dataclass(frozen=True)
class ContactForce:
    """The force the material exerts on one contact (a closed side or a structure), N per metre out of
    plane, over the output interval that ends at the frame's time.

    ``force_*`` is the mean force: the impulse transmitted in the interval divided by its length, so
    no impact falls between outputs. ``peak_*`` is the largest force of any single step in the
    interval (its magnitude and components). For sides, ``force_normal`` is the component pressing
    on the wall (along the wall's outward normal, positive when the material pushes on it) and
    ``force_tangential`` the component along +x (bottom, top) or +y (left, right); both are None
    for structures. ``moment`` is the mean force's moment about the grid origin (the domain's
    ``origin_m``; N m per metre, counter-clockwise positive), each node's share taken at its
    point on the contact's surface: with the mean force it gives the force's line of action
    (:func:`line_of_action`). Zero at t = 0 and for an interval in which nothing touched the
    contact.
    """

    contact: str
    force_x_N_per_m: float
    force_y_N_per_m: float
    force_normal_N_per_m: float | None
    force_tangential_N_per_m: float | None
    peak_force_N_per_m: float
    peak_force_x_N_per_m: float
    peak_force_y_N_per_m: float
    moment_N_m_per_m: float = 0.0


def line_of_action(force: tuple[float, float], moment: float, near: tuple[float, float]) -> tuple[float, float] | None:
    """The point of a force's line of action nearest to ``near``: the line of the points ``p``
    with ``p x F = M`` (``moment`` about the same origin as ``near``'s coordinates). None for a
    zero force."""
    fx, fy = force
    size2 = fx * fx + fy * fy
    if not size2 > 0.0:
        return None
    # p = near + off (fy, -fx), perpendicular to F, with p x F = near x F + off |F|^2 = M
    off = (moment - (near[0] * fy - near[1] * fx)) / size2
    return near[0] + off * fy, near[1] - off * fx


@dataclass(frozen=True, eq=False)
class Frame:
    """A snapshot at one output time.

    ``fields`` always holds ``positions`` (N, 2) and ``active`` (N,) bool; plus what the
    output asked for: ``displacement`` (N, 2) m, ``velocity`` (N, 2) m/s, ``stress`` (N, 4) Pa
    as xx, yy, xy, zz, ``plastic_strain`` (N,), ``material_id`` (N,) int.
    Particles keep their index for the whole run; removed ones have ``active`` False.
    ``contacts``: the force on every closed side and structure (see :class:`ContactForce`).
    """

    diagnostics: Diagnostics
    fields: dict[str, np.ndarray] = field(default_factory=dict)
    contacts: tuple[ContactForce, ...] = ()


@dataclass(frozen=True, eq=False)
class Checkpoint:
    """The full state of a run at an output frame (:meth:`Simulation.checkpoint`).

    ``run``: time, step count, cursor (JSON-serialisable); ``arrays``: the engine's state fields;
    ``fingerprint``: what the run was built from (configuration and particles), so that a
    checkpoint is never restored into another run.
    """

    run: dict
    arrays: dict
    fingerprint: str


class SolverError(Exception):
    """Bad solver input (inconsistent configuration or particles)."""


class InstabilityError(Exception):
    """The stability guard stopped the run. ``step`` and ``time_s`` say where."""

    def __init__(self, message: str, step: int, time_s: float):
        super().__init__(message)
        self.step = step
        self.time_s = time_s
