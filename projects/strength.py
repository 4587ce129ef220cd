"""Factor of safety by strength reduction, the run-out of the failure it finds, and Bishop's check.

A project with a ``strength-reduction`` stage runs in three parts (:meth:`StrengthReduction.run`):

1. the initial-stress stage(s) before it, as usual; their end state is the **equilibrium
   checkpoint** (:meth:`solver.engine.Engine.state`, in memory), computed once;
2. trials: for a trial factor ``F`` the chosen Drucker-Prager materials get ``c / F``,
   ``tan(phi) / F``, ``tensile strength / F`` and a dilatancy ``min(psi, phi_F)`` (never above
   the reduced friction), the checkpoint is restored and the model runs quasi-statically (full
   gravity, local damping) for at most ``trial_duration_s``. The trial **fails** when

   - ``displacement``: the monitor point (default: the crest of the slope) moves more than
     ``failure.displacement_m`` from its equilibrium position, or
   - ``kinetic-energy``: at the end of the budget the kinetic energy has not settled: it is
     still above ``failure.kinetic_energy_ratio`` times the larger of the trial's peak and the
     reference energy ``1/2 M (displacement_m / trial_duration_s)^2`` (``M`` the total mass;
     the energy of the whole model moving at the mean speed that would just reach the
     displacement limit within the budget). This is the non-convergence criterion of
     finite-element strength reduction, in energy form;

   and is **stable** as soon as the energy has settled (after ``failure.min_settle_fraction`` of
   the budget, so that a slow start is not taken for rest). ``F`` is searched by bracketing from
   ``first_trial`` (default: Bishop's factor of the same section) in steps of ``bracket_step``
   (relative, doubling) and then bisection until ``upper - lower <= tolerance``; the bracket
   always holds a stable trial (``lower``) and a failing one (``upper``); the factor of safety
   is their midpoint;
3. the mechanism: the end state of the failing trial at ``upper`` is written as a frame; an
   optional following dynamic stage starts from that state with strengths reduced by
   ``strength_factor`` (default ``upper``), except the values its ``material_changes`` give
   (residual strengths, taken as given), and runs to rest.

Bishop's simplified method (:mod:`stability.bishop`) runs on the same section (the bodies in a
frame where gravity points down, each body's material as a Mohr-Coulomb soil) and its critical
circle is reported beside the strength-reduction factor.
"""

from __future__ import annotations

import csv
import io
import logging
import math
import os
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from projects.schema import SR_DEFAULT_BRACKET_STEP, SR_DEFAULT_MAX_TRIALS, SR_DEFAULT_TOLERANCE
from solver import config as sc

if TYPE_CHECKING:  # pragma: no cover - typing only
    from projects.build import ResolvedRun
    from projects.schema import Project
    from solver.config import Frame
    from solver.simulation import Progress, Simulation

logger = logging.getLogger(__name__)

#: Defaults of a strength-reduction stage (docs/project-format.md; the search's are the schema's,
#: which the run-time estimate reads too).
DEFAULT_TOLERANCE = SR_DEFAULT_TOLERANCE
DEFAULT_BRACKET_STEP = SR_DEFAULT_BRACKET_STEP
DEFAULT_MAX_TRIALS = SR_DEFAULT_MAX_TRIALS
DEFAULT_DAMPING = 0.7
DEFAULT_KE_RATIO = 1e-3
DEFAULT_MIN_SETTLE = 0.2
#: Default displacement limit as a fraction of the model's height along gravity (m/m).
DEFAULT_DISPLACEMENT_FRACTION = 0.05
#: Bounds of the bracketing: below F_MIN the model fails at any strength, above F_MAX it never fails.
F_MIN, F_MAX = 0.05, 50.0
TRIALS_NAME = "fos_trials.csv"
TRIAL_COLUMNS = ("trial", "factor", "verdict", "criterion", "monitor_displacement_m", "max_displacement_m",
                 "kinetic_energy_ratio", "duration_s", "steps", "wall_time_s")


def reduced_materials(materials: tuple[sc.Material, ...], indices: tuple[int, ...],
                      factor: float) -> tuple[sc.Material, ...]:
    """The material table with the strengths of ``indices`` divided by ``factor``.

    ``c / F``, ``atan(tan(phi) / F)``, tensile strength ``/ F``, dilatancy ``min(psi, phi_F)``;
    a softening material's residual strengths likewise.

    Parameters
    ----------
    materials : tuple of solver.config.Material
    indices : tuple of int
        The materials to reduce (Drucker-Prager ones).
    factor : float
        The trial factor F (> 0).

    Returns
    -------
    tuple of solver.config.Material
    """
    out = list(materials)
    for i in indices:
        m = materials[i]
        phi = math.atan(math.tan(m.friction_angle_rad) / factor)
        out[i] = replace(
            m,
            cohesion_pa=m.cohesion_pa / factor,
            friction_angle_rad=phi,
            dilatancy_angle_rad=min(m.dilatancy_angle_rad, phi),
            tensile_strength_pa=None if m.tensile_strength_pa is None else m.tensile_strength_pa / factor,
            softening=_reduced_softening(m.softening, factor),
            inertial=None if m.inertial is None else replace(
                m.inertial, friction_increase=m.inertial.friction_increase / factor),
        )
    return tuple(out)


def _reduced_softening(softening: sc.Softening | None, factor: float) -> sc.Softening | None:
    """A softening's residual strengths divided by ``factor`` as the peak ones are (the trial
    keeps the material's brittleness, peak over residual)."""
    if softening is None:
        return None
    phi = math.atan(math.tan(softening.residual_friction_angle_rad) / factor)
    return replace(softening, residual_cohesion_pa=softening.residual_cohesion_pa / factor,
                   residual_friction_angle_rad=phi,
                   residual_dilatancy_angle_rad=min(softening.residual_dilatancy_angle_rad, phi))


@dataclass(frozen=True)
class Trial:
    """One trial of the search.

    Attributes
    ----------
    factor : float
        The trial factor F.
    verdict : {"stable", "failed"}
    criterion : str
        What decided: ``settled`` (stable), ``displacement`` or ``kinetic-energy`` (failed).
    monitor_displacement_m : float, m
        Displacement of the monitor point from equilibrium at the end of the trial.
    max_displacement_m : float, m
        The largest particle displacement from equilibrium at the end of the trial.
    kinetic_energy_ratio : float
        Kinetic energy at the end over the larger of the trial's peak and the reference energy.
    duration_s, steps, wall_time_s : float, int, float
        Simulated time, steps and wall-clock seconds the trial took.
    """

    factor: float
    verdict: str
    criterion: str
    monitor_displacement_m: float
    max_displacement_m: float
    kinetic_energy_ratio: float
    duration_s: float
    steps: int
    wall_time_s: float

    @property
    def failed(self) -> bool:
        return self.verdict == "failed"

    def to_dict(self) -> dict[str, Any]:
        return {
            "factor": self.factor, "verdict": self.verdict, "criterion": self.criterion,
            "monitor_displacement_m": self.monitor_displacement_m, "max_displacement_m": self.max_displacement_m,
            "kinetic_energy_ratio": self.kinetic_energy_ratio, "duration_s": self.duration_s,
            "steps": self.steps, "wall_time_s": self.wall_time_s,
        }


@dataclass(frozen=True)
class Settings:
    """The resolved keys of a strength-reduction stage (SI units; see docs/project-format.md)."""

    label: str
    stage_index: int  # in the project's list of stages
    materials: tuple[int, ...]
    tolerance: float = DEFAULT_TOLERANCE
    first_trial: float | None = None  # None: Bishop's factor (1.0 without it)
    bracket_step: float = DEFAULT_BRACKET_STEP
    trial_duration_s: float = 1.0
    max_trials: int = DEFAULT_MAX_TRIALS
    damping: float = DEFAULT_DAMPING
    limit_equilibrium: bool = True
    kinetic_energy_ratio: float = DEFAULT_KE_RATIO
    displacement_m: float | None = None  # None: DEFAULT_DISPLACEMENT_FRACTION of the model height
    monitor_point_m: tuple[float, float] | None = None  # None: the crest
    min_settle_fraction: float = DEFAULT_MIN_SETTLE
    criteria: tuple[str, ...] = ("displacement", "kinetic-energy")


def settings_of(project: Project) -> Settings | None:
    """The strength-reduction settings of a project, or None when it has no such stage."""
    index = next((i for i, st in enumerate(project.stages) if st.type == "strength-reduction"), None)
    if index is None:
        return None
    stage = project.stages[index]
    names = project.material_names
    if stage.materials is not None:
        chosen = tuple(names.index(n) for n in stage.materials)
    else:
        chosen = tuple(i for i, m in enumerate(project.materials.values()) if m.model == "drucker-prager")
    gravity_stage = next((st for st in project.stages[:index] if st.type == "gravity"), None)
    duration = stage.trial_duration_s or (gravity_stage.duration_s if gravity_stage is not None else 1.0)
    failure = stage.failure
    first = stage.first_trial if isinstance(stage.first_trial, float) else None
    return Settings(
        label=stage.label,
        stage_index=index,
        materials=chosen,
        tolerance=stage.tolerance or DEFAULT_TOLERANCE,
        first_trial=first,
        bracket_step=stage.bracket_step or DEFAULT_BRACKET_STEP,
        trial_duration_s=float(duration),
        max_trials=stage.max_trials or DEFAULT_MAX_TRIALS,
        damping=stage.damping.coefficient if stage.damping is not None else DEFAULT_DAMPING,
        limit_equilibrium=True if stage.limit_equilibrium is None else stage.limit_equilibrium,
        kinetic_energy_ratio=(failure.kinetic_energy_ratio if failure and failure.kinetic_energy_ratio
                              else DEFAULT_KE_RATIO),
        displacement_m=failure.displacement_m if failure else None,
        monitor_point_m=failure.monitor_point_m if failure else None,
        min_settle_fraction=(failure.min_settle_fraction if failure and failure.min_settle_fraction
                             else DEFAULT_MIN_SETTLE),
        criteria=tuple(failure.criteria) if failure else ("displacement", "kinetic-energy"),
    )


# ------------------------------------------------------------------------------ geometry helpers
def _gravity_frame(gravity_m_s2) -> tuple[np.ndarray, np.ndarray]:
    """Unit vectors (across, up) of the frame where gravity points down."""
    g = np.asarray(gravity_m_s2, dtype=float)
    gn = float(np.linalg.norm(g))
    down = g / gn if gn > 0 else np.array([0.0, -1.0])
    up = -down
    across = np.array([up[1], -up[0]])  # up rotated clockwise: +x when gravity is -y
    return across, up


def crest_point(positions_m: np.ndarray, gravity_m_s2, spacing_m: float) -> np.ndarray:
    """The crest of the particles' upper surface: the top of the steepest stretch of ground.

    The surface is the highest particle (along -gravity) in each strip of width ``spacing_m``
    across gravity, smoothed over three strips; from its steepest point the walk goes uphill
    until the ground is less than a quarter as steep.

    Returns
    -------
    numpy.ndarray, shape (2,), m
    """
    across, up = _gravity_frame(gravity_m_s2)
    u = positions_m @ across
    h = positions_m @ up
    bins = np.floor((u - u.min()) / spacing_m).astype(np.int64)
    n = int(bins.max()) + 1
    top = np.full(n, -np.inf)
    np.maximum.at(top, bins, h)
    filled = np.isfinite(top)
    centres = u.min() + (np.arange(n) + 0.5) * spacing_m
    top = np.interp(centres, centres[filled], top[filled])
    if n < 3:
        k = int(np.argmax(top))
    else:
        smooth = np.convolve(np.pad(top, 1, mode="edge"), np.ones(3) / 3.0, mode="valid")
        slope = np.gradient(smooth, spacing_m)
        k = int(np.argmax(np.abs(slope)))
        steep = abs(slope[k])
        step = 1 if slope[k] > 0 else -1  # uphill direction
        while 0 <= k + step < n and abs(slope[k + step]) > 0.25 * steep:
            k += step
        k = min(max(k + step, 0), n - 1)  # the first strip uphill that is no longer steep
    point_u, point_h = centres[k], top[k]
    return point_u * across + point_h * up


def trial_loads(project: Project) -> tuple[tuple[sc.Surcharge, ...], sc.Seismic | None]:
    """The loads a project's strength-reduction trials stand under: the surcharges in force in
    the strength-reduction stage (at full value) and its seismic coefficients; ``((), None)``
    without such a stage."""
    settings = settings_of(project)
    if settings is None:
        return (), None
    from projects.loads import stage_loads

    surcharges, _start, seismic = stage_loads(project)[settings.stage_index]
    return surcharges, seismic


def _section_loads(project: Project, g: np.ndarray, surcharges, seismic):
    """The loads in the frame where gravity points down (Bishop's section): each surcharge's
    ends at the ground surface under them, rotated, its pressure per unit length of that frame's
    horizontal (the same resultant); the seismic direction along that frame's horizontal."""
    from projects.loads import ground_height
    from stability.bishop import Seismic, Surcharge

    across, up = _gravity_frame(g)
    polygons = [np.asarray(b.polygon_m, dtype=float) for b in project.bodies]
    out = []
    for load in surcharges:
        ends = np.array([load.from_m, load.to_m])
        tops = ground_height(polygons, ends)
        tops = np.where(np.isfinite(tops), tops, 0.0)
        pts = np.c_[ends, tops]
        u = pts @ across
        stretch = (load.to_m - load.from_m) / abs(float(u[1] - u[0]))
        end = load.pressure_pa if load.pressure_end_pa is None else load.pressure_end_pa
        lo, hi = (0, 1) if u[1] > u[0] else (1, 0)
        pressures = (load.pressure_pa * stretch, end * stretch)
        out.append(Surcharge(float(u[lo]), float(u[hi]), pressures[lo], pressures[hi]))
    quake = None
    if seismic is not None:
        quake = Seismic(seismic.k_h, seismic.k_v, 1.0 if seismic.direction > 0 else -1.0)
    return out, quake


def limit_equilibrium(project: Project, gravity_m_s2=None, water: sc.Water | None = None,
                      surcharges: tuple[sc.Surcharge, ...] = (), seismic: sc.Seismic | None = None) -> Any:
    """Bishop's critical circle of the project's bodies (in model coordinates).

    Each body's material is a Mohr-Coulomb soil (``c'``, ``phi'``, ``rho |g|`` above the phreatic
    line, the saturated density below it, its ``ru``; a linear-elastic body is given a strength
    no slip circle will go through; a rigid body, weightless and driven, is left out). ``water`` is the ground water in force (the phreatic and
    free-water lines; None: dry); ``surcharges`` and ``seismic`` the loads (projects.loads: vertical
    loads on the slices' tops, ``k_h W`` at each slice's centroid and ``(1 - k_v) W``). The
    section is rotated so that gravity points down; the circle's centre is rotated back. An end of the section is a free face where the bodies stand
    off that side of the domain or the side is open; else it is a wall no circle passes through.

    Returns
    -------
    stability.bishop.SlipResult, with the circle in model coordinates

    Raises
    ------
    ValueError
        One line: no admissible circle (stability.bishop.NoAdmissibleCircle), or water lines
        that the rotation into gravity's frame folds back.
    """
    from stability.bishop import Circle, Section, Soil, Water, critical_circle

    g = np.asarray(project.domain.gravity_m_s2 if gravity_m_s2 is None else gravity_m_s2, dtype=float)
    gn = float(np.linalg.norm(g))
    across, up = _gravity_frame(g)
    polygons, soils = [], []
    for body in project.bodies:
        m = project.materials[body.material]
        if m.model == "rigid":  # weightless and driven (solver.rigid): not part of the section
            continue
        pts = np.asarray(body.polygon_m, dtype=float)
        polygons.append(np.c_[pts @ across, pts @ up])
        if m.model == "drucker-prager":
            wet = None if m.saturated_density_kg_m3 is None else m.saturated_density_kg_m3 * gn
            soils.append(Soil(m.cohesion_pa or 0.0, math.radians(m.friction_angle_deg or 0.0), m.density_kg_m3 * gn,
                              saturated_unit_weight_n_m3=wet, ru=m.ru or 0.0))
        else:
            soils.append(Soil(1e12, 0.0, m.density_kg_m3 * gn))
    section_water = None
    if water is not None:
        def rotated(line):
            pts = np.asarray(line, dtype=float)
            return np.c_[pts @ across, pts @ up]

        section_water = Water(rotated(water.phreatic_line_m), rotated(water.free_water),
                              unit_weight_n_m3=water.unit_weight_n_m3 * gn / math.hypot(*project.domain.gravity_m_s2),
                              inclined_correction=water.inclined_correction)
    loads, quake = _section_loads(project, g, surcharges, seismic)
    section = Section(polygons, soils, water=section_water, free_ends=_free_ends(project), surcharges=loads,
                      seismic=quake)
    result = critical_circle(section)
    c = result.circle
    centre = c.centre_x_m * across + c.centre_y_m * up
    return replace(result, circle=Circle(float(centre[0]), float(centre[1]), c.radius_m))


def _free_ends(project: Project) -> tuple[bool, bool]:
    """Whether the section's left and right ends are free faces (for Bishop's search): the side is
    open, or the bodies stand off it by more than a cell. Gravity along -y only; otherwise walls."""
    g = project.domain.gravity_m_s2
    if abs(g[0]) > 1e-12 * abs(g[1]):
        return (False, False)
    xs = np.concatenate([np.asarray(b.polygon_m, dtype=float)[:, 0] for b in project.bodies])
    lo = project.domain.origin_m[0]
    hi = lo + project.domain.size_m[0]
    dx = project.domain.cell_size_m
    sides = project.domain.boundaries
    return (sides.left.type == "open" or xs.min() > lo + dx, sides.right.type == "open" or xs.max() < hi - dx)


# ------------------------------------------------------------------------------ the driver
@dataclass
class StrengthReduction:
    """Drives a project with a strength-reduction stage (see the module docstring).

    Attributes after :meth:`run`: ``trials`` (in the order run), ``lower``/``upper`` (the
    bracket), ``value``, ``criterion``, ``limit`` (Bishop's result or None),
    ``initial_stress_runs`` (how often the initial stress was computed: 1),
    ``mechanism_frame`` (index of the mechanism frame in the results).
    """

    project: Project
    built: ResolvedRun
    settings: Settings
    trials: list[Trial] = field(default_factory=list)
    lower: float | None = None
    upper: float | None = None
    limit: Any = None
    limit_error: str = ""
    initial_stress_runs: int = 0
    mechanism_frame: int | None = None
    monitor_point_m: tuple[float, float] | None = None
    monitor_particle: int | None = None
    displacement_limit_m: float | None = None
    runout_factor: float | None = None
    runout_max_displacement_m: float | None = None
    search_wall_time_s: float = 0.0
    equilibrium_steps: int = 0
    initial_stress_steps: int = 0
    equilibrium_wall_time_s: float = 0.0
    message: str = ""
    _frames: int = 0

    # -------------------------------------------------------------- parts of the configuration
    @property
    def water(self) -> sc.Water | None:
        """The ground water the trials stand in: where the stages before this one left it."""
        from projects.build import solver_water

        return solver_water(self.project)[self.settings.stage_index]

    @property
    def solver_split(self) -> int:
        """Number of solver stages before the strength-reduction stage."""
        return sum(1 for st in self.project.stages[:self.settings.stage_index] if st.type != "strength-reduction")

    @property
    def initial_stages(self) -> tuple[sc.Stage, ...]:
        return self.built.config.stages[:self.solver_split]

    @property
    def runout_stage(self) -> sc.Stage | None:
        rest = self.built.config.stages[self.solver_split:]
        return rest[0] if rest else None

    @property
    def value(self) -> float | None:
        if self.lower is None or self.upper is None:
            return None
        return 0.5 * (self.lower + self.upper)

    @property
    def criterion(self) -> str:
        failing = self._trial_at(self.upper)
        return failing.criterion if failing is not None else ""

    def _trial_at(self, factor: float | None) -> Trial | None:
        if factor is None:
            return None
        return next((t for t in reversed(self.trials) if t.factor == factor), None)

    # -------------------------------------------------------------- the run
    def _yield(self, frame: Frame) -> Frame:
        self._frames += 1
        return frame

    def run(self, sim: Simulation, cancel: Callable[[], bool] | None = None,
            on_progress: Callable[[Progress], None] | None = None) -> Iterator[Frame]:
        """Run the initial stress, the search and the run-out, yielding the frames to write."""
        s = self.settings
        cfg = sim.config
        surcharges, seismic = trial_loads(self.project)
        if s.limit_equilibrium:
            try:
                self.limit = limit_equilibrium(self.project, water=self.water, surcharges=surcharges, seismic=seismic)
            except ValueError as err:
                self.limit_error = str(err)
                logger.warning("limit equilibrium: %s", err)
        # 1. the initial stress, once
        wall = time.perf_counter()
        steps0 = sim.steps
        for frame in sim.run(cancel=cancel, on_progress=on_progress, stop_before=self.solver_split):
            yield self._yield(frame)
        self.initial_stress_runs += 1
        self.initial_stress_steps = sim.steps - steps0
        if sim.status == "stopped":
            return
        # settle at full gravity and the file's strengths (a gravity stage ramped to its end,
        # ramp_fraction = 1, ends while still loading; a k0 stress is not in equilibrium on a
        # slope), then from rest
        st = sim.engine.state(("active", "m", "x"))
        active = st["active"].astype(bool)
        mass = float(np.sum(st["m"][active]))
        if s.displacement_m is not None:
            d_lim = s.displacement_m
        else:
            _, up = _gravity_frame(cfg.gravity_m_s2)
            heights = st["x"][active].astype(np.float64) @ up
            d_lim = max(DEFAULT_DISPLACEMENT_FRACTION * float(heights.max() - heights.min()), cfg.grid.cell_size_m)
        self.displacement_limit_m = d_lim
        e_ref = 0.5 * mass * (d_lim / s.trial_duration_s) ** 2
        peak0 = [0.0]

        def settled(elapsed: float, d: dict) -> str | None:
            peak0[0] = max(peak0[0], d["kinetic_energy"])
            if elapsed >= s.min_settle_fraction * s.trial_duration_s and \
                    d["kinetic_energy"] < s.kinetic_energy_ratio * max(peak0[0], e_ref):
                return "settled"
            return None

        sim.set_materials(cfg.materials)
        if sim.advance(s.trial_duration_s, damping=s.damping, check=settled, cancel=cancel) == "cancelled":
            sim.status = "stopped"
            self.message = "cancelled while settling the initial stress"
            return
        sim.engine.bring_to_rest()
        self.equilibrium_wall_time_s = time.perf_counter() - wall
        self.equilibrium_steps = sim.steps - steps0
        checkpoint = sim.engine.state()
        # the trials stand under the strength-reduction stage's loads, at full value from the start
        # (none where it removes them: the settling above kept those of the stages before)
        sim.set_loads(surcharges, seismic)
        t0, label_index = sim.time_s, len(self.initial_stages)
        # the engine works relative to the grid's origin; the project's coordinates are origin + x
        origin = np.asarray(getattr(sim, "origin_m", (0.0, 0.0)), dtype=np.float64)
        x_eq = checkpoint["x"].astype(np.float64)
        active = checkpoint["active"].astype(bool)
        spacing = float(np.sqrt(np.median(self.built.particles.volumes_m2)))
        if s.monitor_point_m is not None:
            point = np.asarray(s.monitor_point_m, dtype=float) - origin
        else:
            point = crest_point(x_eq[active], cfg.gravity_m_s2, max(spacing, cfg.grid.cell_size_m))
        candidates = np.flatnonzero(active)
        idx = int(candidates[np.argmin(np.linalg.norm(x_eq[candidates] - point, axis=1))])
        self.monitor_point_m = (float(x_eq[idx, 0] + origin[0]), float(x_eq[idx, 1] + origin[1]))
        self.monitor_particle = idx
        use_displacement = "displacement" in s.criteria
        use_energy = "kinetic-energy" in s.criteria
        base = cfg.materials
        states: dict[float, dict] = {}

        def trial(factor: float) -> Trial:
            sim.engine.load_state(checkpoint)
            sim.time_s = t0
            sim.set_materials(reduced_materials(base, s.materials, factor))
            peak = [0.0]
            started_steps, started = sim.steps, time.perf_counter()

            def check(elapsed: float, d: dict) -> str | None:
                ke = d["kinetic_energy"]
                peak[0] = max(peak[0], ke)
                # from the reference position (the equilibrium's), which a particle crossing a
                # periodic side takes along, so that the displacement goes on through the crossing
                pos, ref = sim.engine.x[idx], sim.engine.x0[idx]
                if use_displacement and math.hypot(float(pos[0] - ref[0]), float(pos[1] - ref[1])) > d_lim:
                    return "displacement"
                if use_energy and elapsed >= s.min_settle_fraction * s.trial_duration_s and \
                        ke < s.kinetic_energy_ratio * max(peak[0], e_ref):
                    return "settled"
                return None

            reason = sim.advance(s.trial_duration_s, damping=s.damping, check=check, cancel=cancel)
            if reason == "cancelled":
                raise _Cancelled()
            d = sim.engine.diagnostics()
            disp = _displacements(sim.engine)
            ratio = d["kinetic_energy"] / max(peak[0], e_ref, 1e-300)
            if reason == "displacement":
                verdict, criterion = "failed", "displacement"
            elif reason == "settled":
                verdict, criterion = "stable", "settled"
            elif not use_energy:  # the budget ran out and the monitor stayed within its limit
                verdict, criterion = "stable", "displacement"
            else:
                verdict, criterion = "failed", "kinetic-energy"
            result = Trial(float(factor), verdict, criterion, float(disp[idx]),
                           float(disp[active].max(initial=0.0)), float(ratio), float(sim.time_s - t0),
                           int(sim.steps - started_steps), time.perf_counter() - started)
            self.trials.append(result)
            if result.failed:
                states[float(factor)] = sim.engine.state()
                states[float(factor)]["__time_s"] = np.array(sim.time_s)
            logger.info("strength reduction: F = %.4f %s (%s), monitor %.3g m, %d steps", factor, verdict,
                        criterion, result.monitor_displacement_m, result.steps)
            if on_progress is not None:
                from solver.simulation import Progress
                rate = result.steps / result.wall_time_s if result.wall_time_s > 0 else 0.0
                on_progress(Progress(t0, max(sim.total_time_s, t0), f"{s.label}: F = {factor:.3f} {verdict}",
                                     sim.steps, rate, rate * len(self.built.particles)))
            return result

        wall = time.perf_counter()
        try:
            self._search(trial)
        except _Cancelled:
            sim.status = "stopped"
            self.message = "cancelled during the strength reduction"
            self.search_wall_time_s = time.perf_counter() - wall
            return
        self.search_wall_time_s = time.perf_counter() - wall
        # 3. the mechanism and the run-out
        if self.upper is None:
            sim.engine.load_state(checkpoint)
            sim.time_s = t0
            sim.set_materials(base)
            self.mechanism_frame = None
            self.message = f"no failure up to F = {self.lower:.3g}" if self.lower is not None else "no trial"
            return
        state = dict(states[self.upper])
        sim.time_s = float(state.pop("__time_s"))
        sim.engine.load_state(state)
        runout = self.runout_stage
        self.mechanism_frame = self._frames
        if runout is None:
            sim.set_materials(reduced_materials(base, s.materials, self.upper))
            mech = sc.Stage(name=f"{s.label}: mechanism at F = {self.upper:.3f}", kind="dynamic")
            yield self._yield(sim.snapshot(mech, label_index, sim.time_s - t0))
            return
        project_stage = self.project.stages[s.stage_index + 1]
        self.runout_factor = project_stage.strength_factor or self.upper
        sim.set_materials(self._runout_materials(base, project_stage))
        # the solver goes on with the run-out stage from this state (a frame at its start first)
        c = sim.cursor
        c.stage_index, c.phase, c.next_output_s, c.last_output_step = self.solver_split, "start", sim.time_s, -1
        last = None
        for frame in sim.run(cancel=cancel, on_progress=on_progress):
            last = frame
            yield self._yield(frame)
        if last is not None:  # from the equilibrium (the reference a periodic crossing takes along)
            moved = _displacements(sim.engine)
            self.runout_max_displacement_m = float(moved[last.fields["active"]].max(initial=0.0))

    def _runout_materials(self, base, project_stage) -> tuple[sc.Material, ...]:
        """Strengths reduced by the run-out factor, with the stage's material changes as given."""
        from projects.build import material_tables, solver_material

        table = list(reduced_materials(base, self.settings.materials, self.runout_factor))
        names = self.built.material_names
        file_table = material_tables(self.project)[self.settings.stage_index + 1]
        to_solver = {"cohesion_pa": "cohesion_pa", "friction_angle_deg": "friction_angle_rad",
                     "dilatancy_angle_deg": "dilatancy_angle_rad", "tensile_strength_pa": "tensile_strength_pa",
                     "density_kg_m3": "density_kg_m3", "youngs_modulus_pa": "youngs_modulus_pa",
                     "poisson_ratio": "poisson_ratio", "damping_ratio": "damping_ratio",
                     "damping_frequency_hz": "damping_frequency_hz"}
        for name, change in project_stage.material_changes.items():
            i = names.index(name)
            given = solver_material(name, file_table[name])  # the file's values with the changes
            keys = [to_solver[k] for k in change.model_dump(exclude_none=True)]
            m = replace(table[i], **{k: getattr(given, k) for k in keys})
            table[i] = replace(m, dilatancy_angle_rad=min(m.dilatancy_angle_rad, m.friction_angle_rad))
        return tuple(table)

    def _search(self, trial: Callable[[float], Trial]) -> None:
        """Bracketing from the first trial, then bisection to the tolerance."""
        s = self.settings
        first = s.first_trial
        if first is None:
            first = float(self.limit.factor) if self.limit is not None else 1.0
        first = min(max(first, F_MIN), F_MAX)
        step = s.bracket_step
        f = first
        result = trial(f)
        budget = s.max_trials - 1
        if result.failed:
            self.upper = f
            while budget > 0 and f > F_MIN:
                f = max(f / (1.0 + step), F_MIN)
                step *= 2.0
                budget -= 1
                if trial(f).failed:
                    self.upper = f
                else:
                    self.lower = f
                    break
        else:
            self.lower = f
            while budget > 0 and f < F_MAX:
                f = min(f * (1.0 + step), F_MAX)
                step *= 2.0
                budget -= 1
                if trial(f).failed:
                    self.upper = f
                    break
                self.lower = f
        if self.lower is None or self.upper is None:
            self.message = ("the model fails at every trial factor down to F = {:.3g}".format(self.upper)
                            if self.lower is None else
                            "the model is stable at every trial factor up to F = {:.3g}".format(self.lower))
            return
        while budget > 0 and self.upper - self.lower > s.tolerance:
            mid = 0.5 * (self.lower + self.upper)
            budget -= 1
            if trial(mid).failed:
                self.upper = mid
            else:
                self.lower = mid
        if self.upper - self.lower > s.tolerance:
            self.message = f"trial budget ({s.max_trials}) spent before the tolerance {s.tolerance:g}"
        else:
            self.message = (f"factor of safety {self.value:.3f} in [{self.lower:.3f}, {self.upper:.3f}] "
                            f"after {len(self.trials)} trials")

    # -------------------------------------------------------------- results
    def summary(self) -> dict[str, Any]:
        """``factor_of_safety`` and ``limit_equilibrium`` entries of summary.json."""
        s = self.settings
        fos: dict[str, Any] = {
            "value": self.value,
            "lower": self.lower,
            "upper": self.upper,
            "criterion": self.criterion,
            "tolerance": s.tolerance,
            "message": self.message,
            "trials": [t.to_dict() for t in self.trials],
            "materials": [self.built.material_names[i] for i in s.materials],
            "monitor_point_m": list(self.monitor_point_m) if self.monitor_point_m else None,
            "monitor_particle": self.monitor_particle,
            "displacement_limit_m": self.displacement_limit_m,
            "kinetic_energy_ratio": s.kinetic_energy_ratio,
            "trial_duration_s": s.trial_duration_s,
            "damping": s.damping,
            "mechanism_frame": self.mechanism_frame,
            "runout_factor": self.runout_factor,
            "runout_max_displacement_m": self.runout_max_displacement_m,
            "initial_stress_runs": self.initial_stress_runs,
            "equilibrium_wall_time_s": self.equilibrium_wall_time_s,
            "search_wall_time_s": self.search_wall_time_s,
            "equilibrium_steps": self.equilibrium_steps,
            "initial_stress_steps": self.initial_stress_steps,
            "search_steps": int(sum(t.steps for t in self.trials)),
            "trials_file": TRIALS_NAME,
        }
        surcharges, seismic = trial_loads(self.project)
        if surcharges:  # the loads the trials stood under (and Bishop's slices)
            fos["surcharges"] = [{"name": q.name, "from_m": q.from_m, "to_m": q.to_m,
                                  "pressure_pa": [q.pressure_pa, q.pressure_pa if q.pressure_end_pa is None
                                                  else q.pressure_end_pa], "force_n_per_m": q.force_n_per_m}
                                 for q in surcharges]
        if seismic is not None:
            fos["seismic"] = {"k_h": seismic.k_h, "k_v": seismic.k_v,
                              "direction": "right" if seismic.direction > 0 else "left"}
        out: dict[str, Any] = {"factor_of_safety": fos}
        if self.limit is not None:
            out["limit_equilibrium"] = self.limit.to_dict()
        elif self.limit_error:
            out["limit_equilibrium"] = {"error": self.limit_error}
        return out

    def trials_csv(self) -> str:
        """The trials as CSV text (columns :data:`TRIAL_COLUMNS`), in the order they ran."""
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(TRIAL_COLUMNS)
        for k, t in enumerate(self.trials):
            w.writerow([k, repr(t.factor), t.verdict, t.criterion, repr(t.monitor_displacement_m),
                        repr(t.max_displacement_m), repr(t.kinetic_energy_ratio), repr(t.duration_s), t.steps,
                        repr(t.wall_time_s)])
        return buf.getvalue()

    def write_files(self, out_dir: str | os.PathLike[str]) -> None:
        """Write ``fos_trials.csv`` into the results folder (atomically)."""
        from projects.atomic import write_atomic

        write_atomic(Path(out_dir) / TRIALS_NAME, self.trials_csv())


class _Cancelled(Exception):
    pass


def strength_reduction(resolved: ResolvedRun) -> StrengthReduction | None:
    """The driver of a resolved run with a strength-reduction stage, or None."""
    settings = settings_of(resolved.project)
    return None if settings is None else StrengthReduction(resolved.project, resolved, settings)


def _displacements(engine) -> np.ndarray:
    """Each particle's displacement from its reference position (m), read in one launch."""
    st = engine.state(("x", "x0"))
    return np.linalg.norm(st["x"].astype(np.float64) - st["x0"].astype(np.float64), axis=1)
