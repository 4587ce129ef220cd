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
    Diagnostics,
    Frame,
    InstabilityError,
    Particles,
    SimulationConfig,
    SolverError,
    Stage,
)
from solver.initial_stress import k0_stress

log = logging.getLogger(__name__)

#: Steps between guard / CFL / auto-stop checks (each check syncs with the device).
CHECK_EVERY = 20
#: Unbalanced-force ratio above which the initial state is reported as out of equilibrium.
EQUILIBRIUM_WARN_RATIO = 0.05


@dataclass(frozen=True)
class Progress:
    time_s: float
    total_time_s: float
    stage: str
    step: int
    steps_per_s: float
    particle_steps_per_s: float


def critical_time_step(config: SimulationConfig, max_speed_m_s: float = 0.0) -> float:
    """``dx / (c_p + v_max)`` with the largest p-wave speed of all materials of all stages."""
    mats = list(config.materials)
    for st in config.stages:
        mats.extend(st.materials or ())
    c_p = max(m.p_wave_speed_m_s for m in mats)
    return config.grid.cell_size_m / (c_p + max_speed_m_s)


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
    if problems:
        raise SolverError("; ".join(problems))


class Simulation:
    """One analysis: builds the engine in the calling thread and advances it stage by stage."""

    def __init__(self, config: SimulationConfig, particles: Particles):
        validate(config, particles)
        self.config = config
        self.particles = particles
        self.precision = config.numerics.precision
        self.arch = runtime.acquire(config.numerics.arch, self.precision)
        from solver.engine import Engine  # defines Taichi kernels; import after the runtime exists

        np_float = np.float32 if self.precision == "f32" else np.float64
        g = np.asarray(config.gravity_m_s2, dtype=float)
        self.speed_bound_m_s = self._speed_bound(g)
        #: the grid origin, m: the engine works in coordinates relative to it (float64 here)
        self.origin_m = np.asarray(config.grid.origin_m, dtype=np.float64)
        local_grid = dataclasses.replace(config.grid, origin_m=(0.0, 0.0))
        self.engine = Engine(
            local_grid, config.materials, len(particles), config.numerics.scheme, np_float,
            speed_bound_m_s=self.speed_bound_m_s, remove_unstable=config.numerics.guard == "remove",
            damping=any(st.damping > 0 for st in config.stages),
        )
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
        self._closed = False

    # ------------------------------------------------------------------ helpers
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
        want = self.config.output.fields
        e = self.engine
        relative = e.x.to_numpy()
        fields: dict[str, np.ndarray] = {"positions": relative.astype(np.float64) + self.origin_m,
                                         "active": e.active.to_numpy().astype(bool)}
        if "displacement" in want:
            fields["displacement"] = relative - e.x0.to_numpy()
        if "velocity" in want:
            fields["velocity"] = e.v.to_numpy()
        if "stress" in want:
            fields["stress"] = e.s.to_numpy()
        if "plastic_strain" in want:
            fields["plastic_strain"] = e.eps_p.to_numpy()
        if "material" in want:
            fields["material_id"] = e.mat.to_numpy()
        for name, arr in fields.items():
            if arr.dtype.kind == "f" and not np.all(np.isfinite(arr[fields["active"]])):
                raise InstabilityError(
                    f"unstable: non-finite {name} at step {self.steps}, t = {self.time_s:.6g} s", self.steps, self.time_s)
        frame = Frame(diag, fields)
        self.last_frame = frame
        return frame

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

    def equilibrium_check(self, stage: Stage, dt: float, max_speed_m_s: float) -> dict[str, Any]:
        """Measure the unbalanced force of the current state (the engine is left as it was).

        Parameters
        ----------
        stage : Stage
            The initial-stress stage that just ended.
        dt : float, s
            The probe step (the run's current time step).
        max_speed_m_s : float, m/s
            The largest particle speed at the end of the stage (0 for k0).

        Returns
        -------
        dict
            ``stage``, ``type``, ``unbalanced_force_ratio`` (-), ``max_unbalanced_acceleration_m_s2``,
            ``max_speed_m_s``, ``probe_time_step_s``.
        """
        e = self.engine
        g = np.asarray(self.config.gravity_m_s2, dtype=float)
        saved = e.state()
        try:
            active = saved["active"].astype(bool)
            mass = saved["m"].astype(np.float64)[active]
            v0 = saved["v"].astype(np.float64)
            e.step(dt, (g[0], g[1]), 0.0)
            dv = (e.v.to_numpy().astype(np.float64) - v0)[active]
        finally:
            for name, value in saved.items():  # Engine.load_state's shape check trips on vector fields
                getattr(e, name).from_numpy(value)
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
        if not ratio <= EQUILIBRIUM_WARN_RATIO:
            log.warning("%s: above %g, the initial state is not in equilibrium and the next stage starts "
                        "with motion of its own (free faces, or K0 under sloping ground: use a gravity "
                        "stage there)", text, EQUILIBRIUM_WARN_RATIO)
        else:
            log.info(text)
        return check

    # ------------------------------------------------------------------ the run
    def run(self, cancel: Callable[[], bool] | None = None,
            on_progress: Callable[[Progress], None] | None = None) -> Iterator[Frame]:
        """Yield frames at t = 0, every output interval and the end of each stage.

        Raises InstabilityError when the guard fires; the frames yielded before are good.
        ``cancel()`` returning True ends the run after one last frame (status "stopped").
        """
        runtime.check_owner()
        cfg = self.config
        e = self.engine
        interval = cfg.output.interval_s
        g_full = np.asarray(cfg.gravity_m_s2, dtype=float)
        n = len(self.particles)
        wall0 = time.perf_counter()
        self.status = "running"
        cancelled = False
        next_output = 0.0
        last_output_step = -1
        d = e.diagnostics()
        dt = self._time_step(d["max_speed"])
        for index, stage in enumerate(cfg.stages):
            if stage.materials is not None and stage.materials != self._materials:
                e.materials.load(stage.materials)
                self._materials = stage.materials
                log.info("stage %r: material parameters changed", stage.name)
            if stage.kind == "k0":
                e.set_stress(k0_stress(self.particles, self._materials, cfg.gravity_m_s2,
                                       cfg.grid.cell_size_m, stage.k0, e.active.to_numpy().astype(bool),
                                       e.x.to_numpy()))
                self.equilibrium = self.equilibrium_check(stage, dt, float(e.diagnostics()["max_speed"]))
                continue
            if next_output <= self.time_s + 1e-12 and last_output_step != self.steps:
                d = e.diagnostics()
                yield self._frame(stage, index, 0.0, dt, d)
                last_output_step = self.steps
                next_output = self.time_s + interval
            stage_start = self.time_s
            stage_end = stage_start + stage.duration_s
            damping = stage.damping
            peak_ke = 0.0
            stage_steps = 0
            reason = ""
            while self.time_s < stage_end - 1e-12 * max(1.0, stage_end):
                # step size: the configured one, shortened to land exactly on outputs and the stage end
                target = min(next_output, stage_end)
                h = dt if self.time_s + dt * (1 + 1e-6) < target else target - self.time_s
                if stage.kind == "gravity":
                    ramp = min(1.0, (self.time_s + h - stage_start) / stage.duration_s)
                    gravity = g_full * ramp
                else:
                    gravity = g_full
                e.step(h, (gravity[0], gravity[1]), damping)
                self.steps += 1
                stage_steps += 1
                self.time_s += h
                at_output = self.time_s >= next_output - 1e-9 * interval
                if stage_steps % CHECK_EVERY == 0 or at_output:
                    d = e.diagnostics()
                    self._check(dt, d)
                    if cfg.numerics.time_step_s is None:
                        dt = self._time_step(d["max_speed"])
                    peak_ke = max(peak_ke, d["kinetic_energy"])
                    stop_frac = stage.stop_when_kinetic_energy_below
                    stage_time = self.time_s - stage_start
                    if (stage.kind == "dynamic" and stop_frac is not None and stage_time >= stage.min_duration_s
                            and peak_ke > 0 and d["kinetic_energy"] < stop_frac * peak_ke):
                        reason = (f"stage {stage.name!r} ended at t = {self.time_s:.4g} s: kinetic energy "
                                  f"{d['kinetic_energy']:.3g} J/m below {stop_frac:g} of its peak {peak_ke:.3g} J/m")
                        log.info(reason)
                    if on_progress is not None:
                        wall = time.perf_counter() - wall0
                        rate = self.steps / wall if wall > 0 else 0.0
                        on_progress(Progress(self.time_s, self.total_time_s, stage.name, self.steps, rate, rate * n))
                    if cancel is not None and cancel():
                        cancelled = True
                    if at_output or reason or cancelled:
                        yield self._frame(stage, index, stage_time, h, d)
                        last_output_step = self.steps
                        if at_output:
                            next_output += interval
                    if reason or cancelled:
                        break
            if stage.kind == "gravity":
                # quasi-static initial state: drop the velocities, measure displacement from here
                end_speed = float(e.diagnostics()["max_speed"])
                e.set_velocity(np.zeros((n, 2)))
                e.reset_reference()
                if not cancelled:
                    self.equilibrium = self.equilibrium_check(stage, dt, end_speed)
            if last_output_step != self.steps:
                d = e.diagnostics()
                self._check(dt, d)
                yield self._frame(stage, index, self.time_s - stage_start, dt, d)
                last_output_step = self.steps
            if reason:
                self.message = reason
                self.total_time_s -= stage_end - self.time_s
            if cancelled:
                break
        if last_output_step != self.steps or self.last_frame is None:
            # e.g. a project with only a k0 stage
            st = cfg.stages[-1]
            d = e.diagnostics()
            yield self._frame(st, len(cfg.stages) - 1, 0.0, dt, d)
        self.status = "stopped" if cancelled else "completed"
        if cancelled:
            self.message = f"cancelled at t = {self.time_s:.4g} s"
        elif not self.message:
            self.message = f"completed {self.steps} steps, t = {self.time_s:.4g} s"

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
