"""Running a configured analysis stage by stage: time stepping, output, stability guard, auto stop.

Usage::

    with Simulation(config, particles) as sim:      # acquires the Taichi runtime in this thread
        for frame in sim.run(cancel=..., on_progress=...):
            ...                                      # numpy snapshots, never NaN
    sim.status, sim.message

The stability guard (documented bound): a particle is *unstable* when its speed is NaN/inf or
exceeds ``v_bound = factor * (sqrt(2 |g| H) + max |v0|)``, at least ``factor * 1 m/s``, where
``H`` is the extent of the grid box along gravity (the largest possible drop, so the free-fall
speed over it bounds every physical speed of a gravity-driven slide), ``v0`` the initial
velocities and ``factor`` ``Numerics.speed_bound_factor`` (3). The kinetic energy is bounded by
``1/2 M v_bound^2`` (runaway energy). With ``guard = "stop"`` the first unstable particle stops
the run with :class:`InstabilityError`; with ``"remove"`` unstable particles leave the computation
and are counted (the stability studies count survivors this way).

Coordinates: the engine works relative to the grid's origin (its particles and grid start at
zero), so that float32 keeps its resolution for projects in real-world coordinates (UTM metres,
an origin near 500000, 4000000); frames give positions in the project's coordinates again, in
float64 (``origin + relative``). Displacements are differences of relative positions.

Initial equilibrium: at the end of a k0 or gravity stage the run measures how far the initial
state is from equilibrium (:meth:`Simulation.equilibrium_check`): one undamped probe step of the
current time step from rest under full gravity, undone afterwards, gives every particle's
unbalanced force ``m_p dv_p / dt``; the *unbalanced-force ratio* is the sum of their magnitudes
over the total weight ``sum m_p |g|`` (0 in equilibrium, 1 for a body in free fall). It is kept
in :attr:`Simulation.equilibrium` with the largest unbalanced acceleration and, for a gravity
stage, the largest speed at its end (before the velocities are zeroed), and logged.
"""

from __future__ import annotations

import dataclasses
import hashlib
import logging
import math
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np

from solver import runtime
from solver.config import (
    OUTPUT_FIELDS,
    Checkpoint,
    SIDES,
    ContactForce,
    Diagnostics,
    Frame,
    InstabilityError,
    Material,
    Particles,
    SimulationConfig,
    SolverError,
    Stage,
    Water,
    averages_volume,
    body_force_m_s2,
    softens,
)
from solver.initial_stress import k0_stress
from solver.water import blend_water, pore_pressure

log = logging.getLogger(__name__)

#: Steps between guard / CFL / auto-stop checks (each check syncs with the device).
CHECK_EVERY = 20
#: Output fields of a frame read from the engine: (output key, engine field), in frame order.
_FRAME_FIELDS = (("displacement", "x0"), ("velocity", "v"), ("stress", "s"), ("plastic_strain", "eps_p"),
                 ("material", "mat"))
#: Unbalanced-force ratio above which the initial state is reported as out of equilibrium.
EQUILIBRIUM_WARN_RATIO = 0.05


def step_length(time_s: float, target_s: float, dt_s: float) -> float:
    """The next step from ``time_s`` towards ``target_s`` (an output, a stage's end) for a time step
    ``dt_s``: ``dt_s``, except that the steps land exactly on the target and none is shorter than
    half of ``dt_s`` (unless the whole way is). A short last step would be a defect, not only a
    waste: a contact's impulse in one step has a part that does not shrink with the step (the
    grid's approach velocity the contact cancels), so the force of a step of 0.2 % of ``dt_s``
    came out 7.8 times that of the steps around it and became the run's peak force (docs/solver.md,
    contact forces). Where the last full step would leave less than half a step, the last two share the
    way equally."""
    if time_s + dt_s * (1 + 1e-6) >= target_s:
        return target_s - time_s
    if time_s + 1.5 * dt_s > target_s:
        return 0.5 * (target_s - time_s)
    return dt_s


@dataclass
class _Cursor:
    """Where a run stands, besides the engine's state: everything its next step depends on.

    ``phase``: ``start`` (stage ``stage_index`` has not begun), ``loop`` (inside its time loop),
    ``end`` (its time loop is over, its last frame out), ``done`` (the run is complete) or
    ``stopped`` (cancelled; the checkpoint to resume from is the one taken at its last frame).
    """

    stage_index: int = 0
    phase: str = "start"
    stage_start_s: float = 0.0
    stage_steps: int = 0
    peak_ke: float = 0.0
    next_output_s: float = 0.0
    last_output_step: int = -1
    dt_s: float = 0.0
    reason: str = ""
    frames: int = 0
    #: the fastest particle's largest speed in the current stage (m/s)
    peak_speed: float = 0.0
    #: the largest kinetic energy of the dynamic stages so far (J/m)
    run_peak_ke: float = 0.0
    #: the last dynamic stage that ran (-1: none) and whether it ended at rest by its criterion
    last_dynamic: int = -1
    ended_at_rest: bool = False


def fingerprint(config: SimulationConfig, particles: Particles) -> str:
    """A digest of a configuration and its particles (checkpoints belong to one of these)."""
    digest = hashlib.sha256(repr(config).encode())
    for arr in (particles.positions_m, particles.volumes_m2, particles.material_ids, particles.velocities_m_s):
        if arr is not None:
            digest.update(np.ascontiguousarray(arr).tobytes())
    return digest.hexdigest()[:32]


@dataclass(frozen=True)
class Progress:
    time_s: float
    total_time_s: float
    stage: str
    step: int
    steps_per_s: float
    particle_steps_per_s: float


def all_materials(config: SimulationConfig) -> list[Material]:
    """The materials of the run and of every stage's changes."""
    mats = list(config.materials)
    for st in config.stages:
        mats.extend(st.materials or ())
    return mats


def critical_time_step(config: SimulationConfig, max_speed_m_s: float = 0.0) -> float:
    """The smallest stability limit of all materials of all stages
    (:meth:`solver.config.Material.critical_time_step_s`: ``dx / (c_p + v_max)``, less with damping)."""
    return min(m.critical_time_step_s(config.grid.cell_size_m, max_speed_m_s) for m in all_materials(config))


def validate(config: SimulationConfig, particles: Particles) -> None:
    """Raise :class:`SolverError` for inconsistent input (the project layer reports nicer errors)."""
    problems = []
    if config.grid.cell_size_m <= 0:
        problems.append(f"cell size must be > 0, got {config.grid.cell_size_m}")
    if not config.materials:
        problems.append("at least one material is needed")
    if not config.stages:
        problems.append("at least one stage is needed")
    n = len(particles)
    if n == 0:
        problems.append("no particles")
    else:
        if particles.material_ids.min() < 0 or particles.material_ids.max() >= len(config.materials):
            problems.append(f"material ids must be in [0, {len(config.materials) - 1}]")
        if not np.all(np.isfinite(particles.positions_m)):
            problems.append("particle positions must be finite")
        if np.any(particles.volumes_m2 <= 0):
            problems.append("particle volumes must be > 0")
        lo = np.asarray(config.grid.origin_m)
        hi = lo + np.asarray(config.grid.cells) * config.grid.cell_size_m
        outside = np.any((particles.positions_m < lo) | (particles.positions_m > hi), axis=1)
        if outside.any():
            problems.append(f"{int(outside.sum())} particles lie outside the grid box {lo.tolist()}..{hi.tolist()}")
    periodic = config.grid.periodic_problem()
    if periodic:
        problems.append(periodic)
    nm = config.numerics
    if (nm.time_step_s is None) == (nm.cfl is None):
        problems.append("give exactly one of time_step_s and cfl")
    if nm.time_step_s is not None and nm.time_step_s <= 0:
        problems.append(f"time step must be > 0, got {nm.time_step_s}")
    if nm.cfl is not None and not 0 < nm.cfl <= 1.0:
        problems.append(f"cfl must be in (0, 1], got {nm.cfl}")
    for f in config.output.fields:
        if f not in OUTPUT_FIELDS:
            problems.append(f"unknown output field {f!r}; allowed: {', '.join(OUTPUT_FIELDS)}")
    if config.output.interval_s <= 0:
        problems.append("output interval must be > 0")
    for st in config.stages:
        if st.kind in ("gravity", "dynamic") and st.duration_s <= 0:
            problems.append(f"stage {st.name!r}: duration must be > 0")
        if st.materials is not None and len(st.materials) != len(config.materials):
            problems.append(f"stage {st.name!r}: material table must have {len(config.materials)} rows")
    names = [st.name for st in config.structures]
    for m in all_materials(config):
        if m.rigid and m.contact.kind in ("open", "periodic"):
            problems.append(f"rigid material {m.name!r}: contact must be fixed, slip or friction, not {m.contact.kind}")
    rigid_names = [m.name for m in config.materials if m.rigid]
    for name in rigid_names:
        if name in names or name in SIDES:
            problems.append(f"rigid material {name!r}: its contact's name is a structure's or a side's")
    if config.materials and len(rigid_names) == len(config.materials):
        problems.append("every material is rigid: at least one must deform")
    for st in config.stages:
        if st.materials is not None and [m.rigid for m in st.materials] != [m.rigid for m in config.materials]:
            problems.append(f"stage {st.name!r}: a stage's materials keep which of them are rigid")
    for st in config.structures:
        if len(st.polygon_m) < 3:
            problems.append(f"structure {st.name!r}: a polygon needs at least 3 points")
        if st.contact.kind in ("open", "periodic"):
            problems.append(f"structure {st.name!r}: contact must be fixed, slip or friction, not {st.contact.kind}")
        if names.count(st.name) > 1 or st.name in SIDES:
            problems.append(f"structure name {st.name!r} is used twice or is a side's name")
    if problems:
        raise SolverError("; ".join(problems))


class Simulation:
    """One analysis: builds the engine in the calling thread and advances it stage by stage."""

    def __init__(self, config: SimulationConfig, particles: Particles, *, damping_support: bool = False,
                 surcharge_support: bool = False, seismic_support: bool = False):
        """``damping_support`` builds the engine for local damping even when no stage of the
        configuration uses it (the steps of :meth:`advance` may); ``surcharge_support`` and
        ``seismic_support`` build it for surcharges and seismic coefficients likewise
        (:meth:`set_loads` may give them)."""
        validate(config, particles)
        self.config = config
        self.particles = particles
        self.precision = config.numerics.precision
        self.arch = runtime.acquire(config.numerics.arch, self.precision)
        from solver.engine import PAD, Engine  # defines Taichi kernels; import after the runtime exists

        np_float = np.float32 if self.precision == "f32" else np.float64
        g = np.asarray(config.gravity_m_s2, dtype=float)
        self.speed_bound_m_s = self._speed_bound(g)
        #: the grid origin, m: the engine works in coordinates relative to it (float64 here)
        self.origin_m = np.asarray(config.grid.origin_m, dtype=np.float64)
        local_grid = dataclasses.replace(config.grid, origin_m=(0.0, 0.0))
        # ground water (solver/water.py): compiled in only where the run has some
        groundwater = None
        if config.has_water:
            from solver.groundwater import GroundWater

            groundwater = GroundWater(local_grid.cells[0] + 1 + 2 * PAD, -PAD * local_grid.cell_size_m,
                                      local_grid.cell_size_m, config.materials, config.gravity_m_s2, np_float,
                                      seismic=config.has_seismic or seismic_support)
        # surcharges (solver/loads.py): compiled in only where the run has some
        loads = None
        if config.has_surcharges or surcharge_support:
            from solver.loads import Loads

            loads = Loads(len(particles), np_float)
        self.engine = Engine(
            local_grid, config.materials, len(particles), config.numerics.scheme, np_float,
            speed_bound_m_s=self.speed_bound_m_s, remove_unstable=config.numerics.guard == "remove",
            damping=damping_support or any(st.damping > 0 for st in config.stages), scatter=config.numerics.scatter,
            viscous=any(m.damping_beta_s > 0.0 for m in all_materials(config)),
            softening=softens(all_materials(config)),
            volumetric_averaging=averages_volume(config.numerics.volumetric_averaging, all_materials(config)),
            # the structures in the engine's coordinates too (relative to the grid origin)
            structures=tuple(dataclasses.replace(st, polygon_m=tuple(
                (float(x - self.origin_m[0]), float(y - self.origin_m[1])) for x, y in st.polygon_m))
                for st in config.structures),
            water=groundwater,
            loads=loads,
        )
        #: the body force of the steps (m/s2): the stage's gravity with its seismic coefficients
        #: (solver.config.body_force_m_s2); :meth:`advance` steps with it
        self._body_force = tuple(float(v) for v in config.gravity_m_s2)
        #: the water's move in force: (start, end, duration) in the project's coordinates; the
        #: engine moves it on step by step (its ``water.fraction``)
        self._water_move: tuple[Water | None, Water | None, float] = (config.water, config.water, 0.0)
        if groundwater is not None:
            groundwater.set_water(self._local_water(config.water), None, 0.0)
        #: the gravity of the last step (a gravity stage ramps it), for the frames' pore pressure
        self._gravity_now = np.asarray(config.gravity_m_s2, dtype=float)
        self.engine.load_particles(np.asarray(particles.positions_m, dtype=np.float64) - self.origin_m,
                                   particles.volumes_m2, particles.material_ids,
                                   particles.velocities_m_s)
        self.total_time_s = float(sum(st.duration_s for st in config.stages if st.kind != "k0"))
        self.time_s = 0.0
        self.steps = 0
        self.status = "ready"
        self.message = ""
        self.last_frame: Frame | None = None
        #: the initial equilibrium check of the k0 or gravity stage (empty without one)
        self.equilibrium: dict[str, Any] = {}
        self._materials = config.materials
        # hazard envelopes (solver.envelopes): started at the first dynamic stage, updated every few
        # steps and at every frame
        self.envelopes = None
        if config.envelopes is not None:
            from solver.envelopes import Envelopes

            # on the engine's grid (relative to the origin); targets and results in the project's coordinates
            self.envelopes = Envelopes(self.engine, config.envelopes, local_grid, offset_m=self.origin_m)
        self._closed = False
        self.cursor = _Cursor()
        #: ``time.perf_counter()`` at the end of this process's first step (None before it)
        self.first_step_at: float | None = None
        #: this process's CPU time (user + system, all threads) at that moment, s
        self.first_step_cpu_s: float | None = None
        self.fingerprint = fingerprint(config, particles)
        # contacts reported in frames: the closed sides, the structures, then the rigid bodies (engine order)
        self._contacts = [i for i, side in enumerate(SIDES) if config.grid.boundary(side).kind not in ("open", "periodic")]
        self._contacts += [4 + k for k in range(len(config.structures) + self.engine.rigid.count)]
        self._contacts_since_s = 0.0

    # ------------------------------------------------------------------ helpers
    def _local_water(self, water: Water | None) -> Water | None:
        """The water in the engine's coordinates (relative to the grid origin)."""
        if water is None:
            return None
        ox, oy = (float(v) for v in self.origin_m)
        shift = lambda line: None if line is None else tuple((x - ox, y - oy) for x, y in line)  # noqa: E731
        return dataclasses.replace(water, phreatic_line_m=shift(water.phreatic_line_m),
                                   free_water_line_m=shift(water.free_water_line_m))

    def _water_before(self, index: int) -> Water | None:
        """Where the stages before stage ``index`` left the water (project coordinates)."""
        water = self.config.water
        for stage in self.config.stages[:index]:
            water = stage.water if stage.water is not None else water
        return water

    def _start_water_move(self, index: int) -> None:
        """At the start of stage ``index``: the water it moves, from where the stages before left it."""
        start = self._water_before(index)
        stage = self.config.stages[index]
        if stage.water is None:
            self._water_move = (start, start, 0.0)
            if self.engine.water is not None:
                self.engine.water.set_water(self._local_water(start), None, 0.0)
            return
        duration = stage.duration_s if stage.kind != "k0" else 0.0
        self._water_move = (start, stage.water, duration)
        self.engine.water.set_water(self._local_water(start), self._local_water(stage.water), duration)

    def water_now(self) -> Water | None:
        """Where the ground water is now (project coordinates; None: no line)."""
        start, end, duration = self._water_move
        if self.engine.water is None or duration <= 0.0:
            return end
        return blend_water(start, end, float(self.engine.water.fraction[None]))

    def water_at(self, stage_index: int, stage_time_s: float) -> Water | None:
        """Where the ground water was (or will be) at a time of a stage (project coordinates)."""
        start = self._water_before(stage_index)
        stage = self.config.stages[min(stage_index, len(self.config.stages) - 1)]
        if stage.water is None or stage_index >= len(self.config.stages):
            return start
        if stage.kind == "k0" or stage.duration_s <= 0.0:
            return stage.water
        return blend_water(start, stage.water, min(1.0, max(0.0, stage_time_s / stage.duration_s)))

    def _speed_bound(self, g: np.ndarray) -> float:
        gn = float(np.linalg.norm(g))
        lo = np.asarray(self.config.grid.origin_m)
        hi = lo + np.asarray(self.config.grid.cells) * self.config.grid.cell_size_m
        if gn > 0:
            corners = np.array([[lo[0], lo[1]], [hi[0], lo[1]], [lo[0], hi[1]], [hi[0], hi[1]]])
            along = corners @ (g / gn)
            height = float(along.max() - along.min())
        else:
            height = 0.0
        v0 = 0.0 if self.particles.velocities_m_s is None else float(np.abs(self.particles.velocities_m_s).max(initial=0.0) * math.sqrt(2))
        factor = self.config.numerics.speed_bound_factor
        return factor * max(math.sqrt(2.0 * gn * height) + v0, 1.0)

    def critical_time_step(self, max_speed_m_s: float = 0.0) -> float:
        return critical_time_step(self.config, max_speed_m_s)

    def _time_step(self, max_speed: float) -> float:
        nm = self.config.numerics
        if nm.time_step_s is not None:
            return nm.time_step_s
        return nm.cfl * self.critical_time_step(max_speed)

    def _frame(self, stage: Stage, index: int, stage_time: float, dt: float, d: dict) -> Frame:
        diag = Diagnostics(
            time_s=self.time_s, stage=stage.name, stage_index=index, stage_time_s=stage_time, step=self.steps,
            dt_s=dt, kinetic_energy_J_per_m=d["kinetic_energy"], momentum_x=d["momentum_x"],
            momentum_y=d["momentum_y"], max_speed_m_s=d["max_speed"], unstable_particles=d["unstable"],
            lost_particles=d["lost"], total_mass_kg_per_m=d["mass"], yielding_particles=d["yielding"],
        )
        if self.envelopes is not None:
            self.envelopes.sync(self.time_s)  # envelopes are never below a frame's values
        want = self.config.output.fields
        names = ["x", "active"] + [name for key, name in _FRAME_FIELDS if key in want]
        wet = self.engine.water is not None and "pore_pressure" in want
        if wet:
            names += ["s", "mat"]
        got = self.engine.state(tuple(dict.fromkeys(names)))  # one kernel launch for all of them
        relative = got["x"]
        fields: dict[str, np.ndarray] = {"positions": relative.astype(np.float64) + self.origin_m,
                                         "active": got["active"].astype(bool)}
        if "displacement" in want:
            fields["displacement"] = relative - got["x0"]
        for key, name in _FRAME_FIELDS:
            if key in want and key != "displacement":
                fields["material_id" if key == "material" else key] = got[name]
        if wet:
            fields["pore_pressure"] = self._pore_pressure(fields["positions"], got["mat"], got["s"])
        for name, arr in fields.items():
            if arr.dtype.kind == "f" and not np.all(np.isfinite(arr[fields["active"]])):
                raise InstabilityError(
                    f"unstable: non-finite {name} at step {self.steps}, t = {self.time_s:.6g} s", self.steps, self.time_s)
        frame = Frame(diag, fields, self._contact_forces())
        self.last_frame = frame
        self.cursor.frames += 1
        return frame

    def _pore_pressure(self, positions_m: np.ndarray, mat: np.ndarray, stress: np.ndarray) -> np.ndarray:
        """The particles' pore pressure now (Pa, float32), by the engine's rule (solver/water.py)."""
        g = self._gravity_now
        gn = float(np.linalg.norm(g))
        s = np.asarray(stress, dtype=np.float64)
        ru = np.array([m.ru for m in self._materials])[np.asarray(mat)]
        if gn > 0.0:
            d = g / gn
            s_gg = d[0] ** 2 * s[:, 0] + 2.0 * d[0] * d[1] * s[:, 2] + d[1] ** 2 * s[:, 1]
        else:
            s_gg = np.zeros(len(s))
        total_v = s_gg / (1.0 - np.minimum(ru, 0.999999))
        u = pore_pressure(self.water_now(), self._materials, mat, positions_m, g, self.config.gravity_m_s2,
                          vertical_stress_pa=total_v)
        return u.astype(s.dtype if s.dtype == np.float64 else np.float32)

    def _contact_forces(self) -> tuple[ContactForce, ...]:
        """Mean and peak force on each contact since the last frame (see :class:`ContactForce`)."""
        impulse, peak, moment = self.engine.read_contacts()
        interval = self.time_s - self._contacts_since_s
        self._contacts_since_s = self.time_s
        names = self.engine.contact_names
        out = []
        for c in self._contacts:
            fx, fy = (float(v) / interval for v in impulse[c]) if interval > 0 else (0.0, 0.0)
            mz = float(moment[c]) / interval if interval > 0 else 0.0
            normal = tangential = None
            if c < 4:
                axis = c // 2
                outward = -1.0 if c % 2 == 0 else 1.0  # from the material into the wall
                normal = (fx, fy)[axis] * outward
                tangential = (fx, fy)[1 - axis]
            out.append(ContactForce(names[c], fx, fy, normal, tangential, float(peak[c, 0]), float(peak[c, 1]),
                                    float(peak[c, 2]), mz))
        return tuple(out)

    def _check(self, dt: float, d: dict) -> None:
        """The stability guard; raises InstabilityError naming the cause, step and time."""
        bad = d["unstable"] > 0 and self.config.numerics.guard == "stop"
        nan = not all(math.isfinite(d[k]) for k in ("kinetic_energy", "momentum_x", "momentum_y", "max_speed"))
        energy_cap = 0.5 * d["mass"] * self.speed_bound_m_s ** 2
        runaway = math.isfinite(d["kinetic_energy"]) and d["kinetic_energy"] > energy_cap
        if not (bad or nan or runaway):
            return
        where = f"at step {self.steps}, t = {self.time_s:.6g} s"
        if nan:
            cause = "NaN/inf in the particle state"
        elif bad:
            cause = (f"{d['unstable']} particle(s) faster than the bound {self.speed_bound_m_s:.3g} m/s "
                     f"({self.config.numerics.speed_bound_factor:g}x the free-fall speed over the scene height)")
        else:
            cause = f"runaway kinetic energy {d['kinetic_energy']:.3g} J/m > {energy_cap:.3g} J/m"
        crit = self.critical_time_step()
        if dt > crit:
            msg = f"unstable: time step {dt:.2g} s is {dt / crit:.1f}x the critical {crit:.2g} s ({cause} {where})"
        else:
            msg = f"unstable: {cause} {where} (time step {dt:.2g} s, critical {crit:.2g} s)"
        raise InstabilityError(msg, self.steps, self.time_s)

    # ------------------------------------------------------------------ checkpoints
    @property
    def can_checkpoint(self) -> bool:
        """Whether the run, suspended at the frame it just yielded, can be saved and resumed
        from here (every frame of a stage's time loop and of a stage's end, and the end of the run)."""
        return self.cursor.phase in ("loop", "end", "done")

    def checkpoint(self) -> Checkpoint:
        """The full state of the run at the frame it just yielded (see :attr:`can_checkpoint`).

        A new :class:`Simulation` of the same configuration and particles given this to
        :meth:`restore` continues exactly as this one would: the same steps, bit for bit.
        """
        if not self.can_checkpoint:
            raise SolverError(f"no checkpoint can be taken in phase {self.cursor.phase!r}")
        run = {"time_s": self.time_s, "steps": self.steps, "total_time_s": self.total_time_s,
               "message": self.message, "cursor": dataclasses.asdict(self.cursor),
               "contacts_since_s": self._contacts_since_s}
        arrays = self.engine.state()
        if self.engine.water is not None:  # how far the water has moved
            arrays.update({f"water/{k}": v for k, v in self.engine.water.state().items()})
        if self.envelopes is not None:  # a resumed run continues its envelopes
            arrays.update({f"envelopes/{k}": v for k, v in self.envelopes.state().items()})
        if self.engine.loads is not None:  # the surcharges' forces and how far they have grown
            arrays.update({f"loads/{k}": v for k, v in self.engine.loads.state().items()})
        return Checkpoint(run=run, arrays=arrays, fingerprint=self.fingerprint)

    def restore(self, checkpoint: Checkpoint) -> None:
        """Continue from ``checkpoint`` (taken from a run of the same configuration and particles)."""
        if checkpoint.fingerprint != self.fingerprint:
            raise SolverError("the checkpoint belongs to another configuration or particle set")
        self.engine.load_state({k: v for k, v in checkpoint.arrays.items() if "/" not in k})
        if self.envelopes is not None:
            self.envelopes.load_state({k.split("/", 1)[1]: v for k, v in checkpoint.arrays.items()
                                       if k.startswith("envelopes/")})
        run = checkpoint.run
        self.time_s = float(run["time_s"])
        self.steps = int(run["steps"])
        self.total_time_s = float(run["total_time_s"])
        self.message = str(run["message"])
        self.cursor = _Cursor(**run["cursor"])
        self._contacts_since_s = float(run.get("contacts_since_s", self.time_s))
        table = self.config.materials
        for stage in self.config.stages[: self.cursor.stage_index + 1]:
            table = stage.materials if stage.materials is not None else table
        if table != self._materials:
            self._load_materials(table)
        if self.cursor.stage_index < len(self.config.stages):
            stage = self.config.stages[self.cursor.stage_index]
            self._body_force = body_force_m_s2(self.config.gravity_m_s2, stage.seismic)
            if self.engine.water is not None:
                self.engine.water.set_seismic(stage.seismic)
        if self.engine.loads is not None:
            self.engine.loads.load_state({k.split("/", 1)[1]: v for k, v in checkpoint.arrays.items()
                                          if k.startswith("loads/")})
        if self.engine.water is not None and self.cursor.stage_index < len(self.config.stages):
            # the stage's water move, then how far it had gone (the engine's state holds it)
            self._start_water_move(self.cursor.stage_index)
            self.engine.water.load_state({k.split("/", 1)[1]: v for k, v in checkpoint.arrays.items()
                                          if k.startswith("water/")})
    def _rigid_particles(self) -> np.ndarray:
        """Which particles belong to a rigid body (solver.rigid)."""
        rigid = np.array([m.rigid for m in self._materials], dtype=bool)
        return rigid[np.asarray(self.particles.material_ids)]

    def equilibrium_check(self, stage: Stage, dt: float, max_speed_m_s: float,
                          released: bool = False) -> dict[str, Any]:
        """Measure the unbalanced force of the current state (the engine is left as it was).

        Parameters
        ----------
        stage : Stage
            The initial-stress stage that just ended.
        dt : float, s
            The probe step (the run's current time step).
        max_speed_m_s : float, m/s
            The largest particle speed at the end of the stage (0 for k0).
        released : bool
            The state is released at once into free motion (a retained body's collapse): an
            imbalance is reported, not warned about.

        Returns
        -------
        dict
            ``stage``, ``type``, ``unbalanced_force_ratio`` (-), ``max_unbalanced_acceleration_m_s2``,
            ``max_speed_m_s``, ``probe_time_step_s``.
        """
        e = self.engine
        g = np.asarray(self.config.gravity_m_s2, dtype=float)
        saved = e.state()
        water = None if e.water is None else e.water.state()
        try:
            active = saved["active"].astype(bool)
            mass = saved["m"].astype(np.float64)[active]
            v0 = saved["v"].astype(np.float64)
            e.step(dt, (g[0], g[1]), 0.0)
            dv = (e.state(("v",))["v"].astype(np.float64) - v0)[active]
        finally:
            e.load_state(saved)
            if water is not None:
                e.water.load_state(water)
        accel = np.linalg.norm(dv, axis=1) / dt if dt > 0 else np.zeros(len(dv))
        weight = float(mass.sum() * np.linalg.norm(g))
        unbalanced = float((mass * accel).sum())
        ratio = unbalanced / weight if weight > 0 else 0.0
        check = {
            "stage": stage.name,
            "type": stage.kind,
            "unbalanced_force_ratio": ratio if math.isfinite(ratio) else None,
            "max_unbalanced_acceleration_m_s2": float(accel.max(initial=0.0)),
            "max_speed_m_s": float(max_speed_m_s),
            "probe_time_step_s": float(dt),
        }
        text = (f"initial equilibrium after stage {stage.name!r}: unbalanced-force ratio {ratio:.3g}, "
                f"largest unbalanced acceleration {check['max_unbalanced_acceleration_m_s2']:.3g} m/s2, "
                f"largest speed at its end {max_speed_m_s:.3g} m/s")
        if released:
            check["released"] = True
            log.info("%s (the retained body is released into the next stage)", text)
        elif not ratio <= EQUILIBRIUM_WARN_RATIO:
            # what leaves each kind of stage out of equilibrium
            cause = ("free faces, or K0 under sloping ground: use a gravity stage there" if stage.kind == "k0" else
                     "a body its contacts cannot hold, sliding on (friction below the slope), or a stage too "
                     "short for the bodies to settle in")
            log.warning("%s: above %g, the initial state is not in equilibrium and the next stage starts "
                        "with motion of its own (%s)", text, EQUILIBRIUM_WARN_RATIO, cause)
        else:
            log.info(text)
        return check

    def plastic_points(self, stage: Stage, stress: np.ndarray, active: np.ndarray) -> dict[str, Any]:
        """The particles whose K0 stress lies outside their material's yield surface ("plastic
        points", as geotechnical codes call them after a K0 procedure), and the K they reach.

        The run keeps the K0 stress as set; the first step's stress update returns these particles
        to the yield surface (at rest, with a negligible strain increment), which is the
        correction such codes make. Here the same return (``drucker_prager.return_map_host``)
        tells what ``K = sigma_h / sigma_v`` results, and the log says so.

        Returns
        -------
        dict
            ``plastic_points`` (int) and ``plastic_k0`` (the median K of those particles after
            the return, None without any).
        """
        from solver.materials import MODEL_CODES, drucker_prager, material_rows  # Taichi: after the runtime

        rows = material_rows(self._materials)
        mat = np.asarray(self.particles.material_ids)
        dp = active & (rows["model"][mat] == MODEL_CODES["drucker-prager"])
        if not dp.any():
            return {"plastic_points": 0, "plastic_k0": None}
        cols = {k: rows[k][mat[dp]] for k in ("K", "G", "alpha", "kc", "alpha_psi", "t_cut")}
        returned, plastic = drucker_prager.return_map_host(stress[dp], **cols)
        count = int(plastic.sum())
        if not count:
            return {"plastic_points": 0, "plastic_k0": None}
        g = np.asarray(self.config.gravity_m_s2, dtype=float)
        down = g / max(float(np.linalg.norm(g)), 1e-300)
        across = np.array([-down[1], down[0]])

        def ratio(s):
            sig = np.stack([np.stack([s[:, 0], s[:, 2]], -1), np.stack([s[:, 2], s[:, 1]], -1)], -2)
            return (sig @ across @ across) / np.minimum(sig @ down @ down, -1e-300)

        before = float(np.median(ratio(stress[dp][plastic])))
        after = float(np.median(ratio(returned[plastic])))
        log.warning("stage %r: the K0 stress lies outside the yield surface at %d of %d particles (plastic "
                    "points); the first step returns them to it: K = sigma_h / sigma_v %.3g -> %.3g (median). "
                    "The cone cannot hold this K0 (docs/solver.md, plastic points after a k0 stage)",
                    stage.name, count, int(active.sum()), before, after)
        return {"plastic_points": count, "plastic_k0": after}

    # ------------------------------------------------------------------ the run
    def run(self, cancel: Callable[[], bool] | None = None,
            on_progress: Callable[[Progress], None] | None = None, *,
            stop_before: int | None = None) -> Iterator[Frame]:
        """Yield frames at t = 0, every output interval and the end of each stage.

        Raises InstabilityError when the guard fires; the frames yielded before are good.
        ``cancel()`` returning True ends the run after one last frame (status "stopped").
        After :meth:`restore` the run continues after the checkpoint's frame.
        ``stop_before`` ends the run at the start of that stage (a driver then works on the
        state, e.g. strength-reduction trials, and calls ``run`` again to go on from there).
        """
        runtime.check_owner()
        cfg = self.config
        e = self.engine
        c = self.cursor
        interval = cfg.output.interval_s
        g_static = np.asarray(cfg.gravity_m_s2, dtype=float)
        n = len(self.particles)
        wall0 = time.perf_counter()
        self.status = "running"
        cancelled = False
        if c.dt_s == 0.0:  # a fresh run (a restored one keeps its step)
            c.dt_s = self._time_step(e.diagnostics()["max_speed"])
        last = len(cfg.stages) if stop_before is None else min(stop_before, len(cfg.stages))
        for index in range(c.stage_index, last):
            stage = cfg.stages[index]
            c.stage_index = index
            if c.phase == "start":
                if stage.materials is not None and stage.materials != self._materials:
                    self._load_materials(stage.materials)
                    log.info("stage %r: material parameters changed", stage.name)
                if e.water is not None:
                    self._start_water_move(index)
                self._start_loads(stage)
                if stage.kind == "k0":
                    now = e.state(("active", "x"))
                    # a rigid body (solver.rigid) weighs nothing and carries no stress
                    soil = now["active"].astype(bool) & ~self._rigid_particles()
                    stress = k0_stress(self.particles, self._materials, cfg.gravity_m_s2,
                                       cfg.grid.cell_size_m, stage.k0, soil, now["x"],
                                       water=self._local_water(self.water_now()))
                    stress[~soil] = 0.0
                    e.set_stress(stress)
                    # a k0 state followed at once by free motion, with no trigger of its own, is a
                    # retained body released (a column or dam-break collapse): its imbalance is the
                    # analysis, not a defect of the initial state
                    after = cfg.stages[index + 1] if index + 1 < len(cfg.stages) else None
                    released = (after is not None and after.kind == "dynamic" and after.materials is None
                                and after.water is None)
                    self.equilibrium = {**self.equilibrium_check(stage, c.dt_s, float(e.diagnostics()["max_speed"]),
                                                                 released=released),
                                        **self.plastic_points(stage, stress, now["active"].astype(bool))}
                    continue
                if stage.kind == "dynamic" and self.envelopes is not None and not self.envelopes.started:
                    self.envelopes.start(self.time_s)  # the release: ground surface and initial state
                c.phase, c.stage_start_s, c.stage_steps, c.peak_ke, c.reason = "loop", self.time_s, 0, 0.0, ""
                c.peak_speed = 0.0
                if stage.kind == "dynamic":
                    c.last_dynamic, c.ended_at_rest = index, False
                if c.next_output_s <= self.time_s + 1e-12 and c.last_output_step != self.steps:
                    frame = self._frame(stage, index, 0.0, c.dt_s, e.diagnostics())
                    c.last_output_step = self.steps
                    c.next_output_s = self.time_s + interval
                    yield frame
            stage_end = c.stage_start_s + stage.duration_s
            if c.phase == "loop":
                damping = stage.damping
                e.set_rigid_moving(stage.kind == "dynamic")  # initial-stress stages hold them still
                g_full = np.asarray(body_force_m_s2(cfg.gravity_m_s2, stage.seismic), dtype=float)
                while not c.reason and self.time_s < stage_end - 1e-12 * max(1.0, stage_end):
                    # step size: the configured one, landing exactly on outputs and the stage end
                    h = step_length(self.time_s, min(c.next_output_s, stage_end), c.dt_s)
                    if stage.kind == "gravity":
                        ramp = min(1.0, (self.time_s + h - c.stage_start_s) / stage.ramp_s)
                        gravity = g_full * ramp
                    else:
                        ramp = 1.0
                        gravity = g_full
                    # the frames' pore pressure: the water's own gravity (no seismic share)
                    self._gravity_now = g_static * ramp if stage.seismic is not None else gravity
                    e.step(h, (gravity[0], gravity[1]), damping)
                    if self.first_step_at is None:  # start-up ends here (kernels compiled or loaded)
                        self.first_step_at = time.perf_counter()
                        self.first_step_cpu_s = time.process_time()
                    self.steps += 1
                    c.stage_steps += 1
                    self.time_s += h
                    if self.envelopes is not None:
                        self.envelopes.after_step(self.time_s)
                    at_output = self.time_s >= c.next_output_s - 1e-9 * interval
                    if c.stage_steps % CHECK_EVERY == 0 or at_output:
                        d = e.diagnostics()
                        self._check(c.dt_s, d)
                        if cfg.numerics.time_step_s is None:
                            c.dt_s = self._time_step(d["max_speed"])
                        c.peak_ke = max(c.peak_ke, d["kinetic_energy"])
                        c.peak_speed = max(c.peak_speed, d["max_speed"])
                        if stage.kind == "dynamic":
                            c.run_peak_ke = max(c.run_peak_ke, d["kinetic_energy"])
                        stage_time = self.time_s - c.stage_start_s
                        if stage.ends_at_rest and stage_time >= stage.min_duration_s and self._at_rest(stage, d):
                            c.reason = self._rest_reason(stage, d)
                            c.ended_at_rest = True
                            log.info(c.reason)
                        if on_progress is not None:
                            wall = time.perf_counter() - wall0
                            rate = self.steps / wall if wall > 0 else 0.0
                            on_progress(Progress(self.time_s, self.total_time_s, stage.name, self.steps, rate, rate * n))
                        if cancel is not None and cancel():
                            cancelled = True
                        if at_output or c.reason or cancelled:
                            frame = self._frame(stage, index, stage_time, h, d)
                            c.last_output_step = self.steps
                            if at_output:
                                c.next_output_s += interval
                            yield frame
                        if c.reason or cancelled:
                            break
                if cancelled:  # the checkpoint of a stopped run is the one at its last frame
                    c.phase = "stopped"
                    break
                if stage.kind == "gravity":
                    # quasi-static initial state: drop the velocities, measure displacement from here
                    end_speed = float(e.diagnostics()["max_speed"])
                    e.bring_to_rest()
                    self.equilibrium = self.equilibrium_check(stage, c.dt_s, end_speed)
                c.phase = "end"
                if c.last_output_step != self.steps:
                    d = e.diagnostics()
                    self._check(c.dt_s, d)
                    frame = self._frame(stage, index, self.time_s - c.stage_start_s, c.dt_s, d)
                    c.last_output_step = self.steps
                    yield frame
            if c.reason:
                self.message = c.reason
                self.total_time_s -= stage_end - self.time_s
            c.phase, c.reason = "start", ""
            c.stage_index = index + 1
        if not cancelled and (c.last_output_step != self.steps or c.frames == 0):
            # e.g. a project with only a k0 stage
            st = cfg.stages[last - 1]
            d = e.diagnostics()
            c.last_output_step = self.steps
            yield self._frame(st, last - 1, 0.0, c.dt_s, d)
        if not cancelled and last == len(cfg.stages):
            c.phase = "done"
        self.status = "stopped" if cancelled else "completed"
        if cancelled:
            self.message = f"cancelled at t = {self.time_s:.4g} s"
        elif not self.message:
            self.message = f"completed {self.steps} steps, t = {self.time_s:.4g} s"

    # ------------------------------------------------------------------ coming to rest
    def _at_rest(self, stage: Stage, d: dict) -> bool:
        """Whether the mass has come to rest by ``stage``'s criterion: the kinetic energy below its
        fraction of the stage's peak and the fastest particle below its speed, each where given; a
        speed alone counts once some particle was faster than it in the stage (not at the release)."""
        c = self.cursor
        frac, speed = stage.stop_when_kinetic_energy_below, stage.stop_when_max_speed_below_m_s
        if frac is not None and not (c.peak_ke > 0 and d["kinetic_energy"] < frac * c.peak_ke):
            return False
        if speed is not None:
            if d["max_speed"] >= speed:
                return False
            if frac is None and c.peak_speed < speed:
                return False  # nothing has moved yet
        return True

    def _rest_reason(self, stage: Stage, d: dict) -> str:
        c = self.cursor
        parts = [f"kinetic energy {d['kinetic_energy']:.3g} J/m"]
        if stage.stop_when_kinetic_energy_below is not None:
            parts[0] += (f", {d['kinetic_energy'] / c.peak_ke:.2g} of its peak {c.peak_ke:.3g} J/m "
                         f"(below {stage.stop_when_kinetic_energy_below:g})")
        parts.append(f"fastest particle {d['max_speed']:.3g} m/s")
        if stage.stop_when_max_speed_below_m_s is not None:
            parts[1] += f" (below {stage.stop_when_max_speed_below_m_s:g} m/s)"
        return f"stage {stage.name!r} ended by its rest criterion at t = {self.time_s:.4g} s: " + ", ".join(parts)

    def motion_at_end(self) -> dict[str, Any] | None:
        """How the mass moves at the end of the run (now), for the verdict whether its answer is
        final: the last dynamic stage that ran (``stage``, its index ``stage_index``, its rest
        criterion ``stop_when_kinetic_energy_below`` and ``stop_when_max_speed_below_m_s``, None
        where not given), ``ended_at_rest`` (it ended by that criterion), the kinetic energy now
        and the largest of the dynamic stages (J/m), the fastest particle now (m/s) and the time
        (s), and whether a rigid body moves now (``driven``). None when no dynamic stage ran."""
        c = self.cursor
        if c.last_dynamic < 0:
            return None
        stage = self.config.stages[c.last_dynamic]
        d = self.engine.diagnostics()
        return {
            "stage": stage.name, "stage_index": c.last_dynamic, "ended_at_rest": bool(c.ended_at_rest),
            "stop_when_kinetic_energy_below": stage.stop_when_kinetic_energy_below,
            "stop_when_max_speed_below_m_s": stage.stop_when_max_speed_below_m_s,
            "time_s": float(self.time_s), "kinetic_energy_J_per_m": float(d["kinetic_energy"]),
            "peak_kinetic_energy_J_per_m": float(max(c.run_peak_ke, d["kinetic_energy"])),
            "max_speed_m_s": float(d["max_speed"]),
            "driven": self._driven_now(),
        }

    def _driven_now(self) -> bool:
        """Whether a rigid body still in the grid moves at a velocity of its own now (a gate lifted
        out of the grid drives nothing)."""
        moving = np.array([m.rigid and any(m.velocity_m_s) for m in self._materials], dtype=bool)
        if not moving.any():
            return False
        active = self.engine.state(("active",))["active"].astype(bool)
        return bool((active & moving[np.asarray(self.particles.material_ids)]).any())

    # ------------------------------------------------------------------ driving from outside
    def advance(self, duration_s: float, *, damping: float = 0.0,
                check: Callable[[float, dict], str | None] | None = None,
                cancel: Callable[[], bool] | None = None) -> str:
        """Step the current state for up to ``duration_s`` with full gravity and the loads in
        force (those of the last stage that ran at their end values, or :meth:`set_loads`'),
        yielding no frames.

        Every :data:`CHECK_EVERY` steps the stability guard runs and ``check(elapsed_s,
        diagnostics)`` is called; a non-empty string it returns ends the advance early and is
        returned (also from the check after the last step). ``cancel()`` returning True ends it
        with ``"cancelled"``. Returns ``""`` when the whole duration ran. The clock (``time_s``,
        ``steps``) advances; callers that restore a checkpoint restore it too. Raises
        InstabilityError like :meth:`run`. Rigid bodies (solver.rigid) stand still.
        """
        runtime.check_owner()
        e = self.engine
        g = self._body_force
        e.set_rigid_moving(False)  # a strength-reduction trial loads a state: rigid bodies stand still
        d = e.diagnostics()
        dt = self._time_step(d["max_speed"])
        elapsed = 0.0
        count = 0
        while elapsed < duration_s - 1e-12 * max(1.0, duration_s):
            h = step_length(elapsed, duration_s, dt)
            e.step(h, g, damping)
            self.steps += 1
            count += 1
            elapsed += h
            self.time_s += h
            if count % CHECK_EVERY == 0:
                d = e.diagnostics()
                self._check(dt, d)
                if self.config.numerics.time_step_s is None:
                    dt = self._time_step(d["max_speed"])
                if check is not None:
                    reason = check(elapsed, d)
                    if reason:
                        return reason
                if cancel is not None and cancel():
                    return "cancelled"
        d = e.diagnostics()
        self._check(dt, d)
        if check is not None:
            return check(elapsed, d) or ""
        return ""

    # ------------------------------------------------------------------ loads
    def _surface_forces(self, surcharges) -> np.ndarray | None:
        """Each particle's share of ``surcharges`` now (N/m, (N, 2)); None without any."""
        if not surcharges:
            return None
        from solver.loads import surface_forces

        now = self.engine.state(("x", "active"))
        # the particle spacing: the width of the columns whose top particles carry a load
        spacing = float(np.sqrt(np.median(np.asarray(self.particles.volumes_m2, dtype=np.float64))))
        g = np.asarray(self.config.gravity_m_s2, dtype=float)
        gn = float(np.linalg.norm(g))
        down = g / gn if gn > 0.0 else np.array([0.0, -1.0])
        # the ground's surface: a rigid body (a platen) carries no load of its own
        ground = now["active"].astype(bool) & ~self._rigid_particles()
        forces, carried = surface_forces(now["x"], ground, spacing, surcharges, down, offset_m=self.origin_m)
        for load, got in zip(surcharges, carried):
            want = load.force_n_per_m
            if abs(got - want) > 1e-3 * abs(want):
                log.warning("surcharge %r: the particles under it carry %.4g N/m of its %.4g N/m (part of "
                            "x = %g..%g m lies beyond the ground)", load.name, got, want, load.from_m, load.to_m)
        return forces

    def _start_loads(self, stage: Stage) -> None:
        """At the start of ``stage``: its body force and its surcharges' forces on the surface
        particles (ramped up with gravity in a gravity stage, from ``surcharges_from`` over the
        stage where given, else at once; none in a k0 stage)."""
        self._body_force = body_force_m_s2(self.config.gravity_m_s2, stage.seismic)
        e = self.engine
        if e.water is not None:
            e.water.set_seismic(stage.seismic)
        if e.loads is None:
            return
        if stage.kind == "k0":
            e.loads.set_forces(None, None, 0.0)
        elif stage.kind == "gravity":
            e.loads.set_forces(None, self._surface_forces(stage.surcharges), stage.ramp_s)
        elif stage.surcharges_from is not None:
            e.loads.set_forces(self._surface_forces(stage.surcharges_from), self._surface_forces(stage.surcharges),
                               stage.duration_s)
        else:
            e.loads.set_forces(None, self._surface_forces(stage.surcharges), 0.0)

    def set_loads(self, surcharges=(), seismic=None) -> None:
        """The loads of the following steps of :meth:`advance`, at once and at full value:
        ``surcharges`` (solver.config.Surcharge, on the surface particles now) and ``seismic``
        (solver.config.Seismic or None). The strength reduction's trials stand under these."""
        if surcharges and self.engine.loads is None:
            raise SolverError("this engine was built without surcharges (surcharge_support=False)")
        self._body_force = body_force_m_s2(self.config.gravity_m_s2, seismic)
        if self.engine.water is not None:
            self.engine.water.set_seismic(seismic)
        if self.engine.loads is not None:
            self.engine.loads.set_forces(None, self._surface_forces(tuple(surcharges)), 0.0)

    def surcharge_forces(self) -> np.ndarray | None:
        """Each particle's surcharge force now (N/m, (N, 2) float64); None where none is compiled in."""
        return None if self.engine.loads is None else self.engine.loads.forces()

    def set_materials(self, materials: tuple[Material, ...]) -> None:
        """Replace the material table now (one row per material of the configuration)."""
        if len(materials) != len(self.config.materials):
            raise SolverError(f"the material table must have {len(self.config.materials)} rows")
        self._load_materials(tuple(materials))

    def _load_materials(self, materials: tuple[Material, ...]) -> None:
        self.engine.materials.load(materials)
        if self.engine.water is not None:
            self.engine.water.load_materials(materials)
        self._materials = materials

    def snapshot(self, stage: Stage, index: int, stage_time_s: float = 0.0) -> Frame:
        """A frame of the current state, labelled with ``stage`` (number ``index``)."""
        d = self.engine.diagnostics()
        return self._frame(stage, index, stage_time_s, self._time_step(d["max_speed"]), d)

    # ------------------------------------------------------------------ lifetime
    def close(self) -> None:
        if not self._closed:
            self._closed = True
            self.engine = None
            runtime.release()

    def __enter__(self) -> Simulation:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
