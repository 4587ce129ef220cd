"""``runout bench``: throughput, memory, overhead and output-stall measurements, with a yardstick.

What is measured (all on the standard granular-collapse scene, see :func:`collapse_scene`):

- **Throughput** in particle-steps per second (particles x steps / wall seconds of the timed
  steps, after compilation and warm-up, without output) for each scheme and for the yardstick,
  per arch (CPU; GPU when Taichi finds one), precision and particle count. All variants of one
  (arch, precision, particles) group live in one Taichi runtime and are timed in interleaved
  rounds from the same initial state. Rates are the best round's; every figure is also given as
  a ratio to the yardstick of its group: the median over rounds of the ratio of two times
  measured back to back (:func:`paired_ratio`), which other work on the machine disturbs least.
- **Memory**: bytes of Taichi fields per particle (from the fields' shapes and dtypes; grid
  fields included) and the process RSS growth while the engine was built and compiled.
- **Profile**: the kernel profiler's time per kernel per step (reset, P2G, constitutive + force,
  grid pass, walls, G2P) and the time outside the kernels (Python and launch overhead: wall time
  per step minus kernel time per step), plus the constitutive update timed alone.
- **Empty domain**: the same scene with the grid box twice as long; ratio of step times.
- **Hazard envelopes**: the cost of updating the envelopes (solver/envelopes.py) every
  ``envelope_every_steps`` steps, as the fraction of the step time it adds: the update kernel and
  the engine step are timed apart in interleaved rounds on the collapsing scene (two targets).
- **Output stall**: the scene run through :meth:`Simulation.run` with frames every 0.01 s written
  by :class:`projects.results.ResultsWriter`, against the same run without frames; ratio of wall
  times.

The **yardstick** (:class:`Yardstick`) is a minimal MLS-MPM step: one weakly compressible fluid
(``sigma = K (J - 1) I``), APIC transfer with the force folded into the affine momentum, the whole
dense grid cleared and updated every step, one kernel per step. It runs on the same grid and the
same particles as the scheme it is compared with.

Use :func:`run_bench` (``quick`` or full presets) or :func:`run_bench_config` with a
:class:`BenchConfig`; :func:`markdown_report` and :func:`rich_tables` format the result.
"""

import json
import logging
import math
import os
import platform
import re
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import asdict, dataclass, replace
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import numpy as np
import taichi as ti

from solver import runtime
from solver.config import (
    OUTPUT_FIELDS,
    SCATTERS,
    SCHEMES,
    Boundary,
    Grid,
    Material,
    Numerics,
    Output,
    Particles,
    SimulationConfig,
    Stage,
)
from solver.engine import Engine
from solver.scatter import resolve_scatter

log = logging.getLogger(__name__)

YARDSTICK = "yardstick"
#: Profile variants: apic-affine with each scatter (solver.config.SCATTERS) the engine would not
#: pick itself, so that the profile shows them all in one run.
SCATTER_VARIANTS = {f"apic-affine, {s} scatter": s for s in SCATTERS if s != "auto"}
NOT_MEASURED_NO_GPU = "not measured: no GPU"
#: Throughput variant: apic-affine with ground water (a phreatic line at half the block's height),
#: timed beside the dry engine: the cost of the pore pressure (solver.groundwater).
WATER_VARIANT = "apic-affine, water"
#: Throughput variants: apic-affine with strain softening (the bars' friction falling to two
#: thirds) and with volumetric averaging, timed beside the plain engine: each component's cost.
SOFTENING_VARIANT = "apic-affine, softening"
AVERAGING_VARIANT = "apic-affine, volumetric averaging"
#: the variants that add a component to the apic-affine engine (their ``ratio_to_dry``)
COMPONENT_VARIANTS = (WATER_VARIANT, SOFTENING_VARIANT, AVERAGING_VARIANT)

#: The scene: the aluminium-bar collapse of Bui et al. (2008) at any particle count.
BLOCK_M = (0.2, 0.1)
DOMAIN_M = (0.8, 0.15)
PARTICLES_PER_CELL_SIDE = 2
#: The paper's step, 20 us at 2 mm cells (about 0.2 of the critical step), scaled with the cell.
DT_PER_CELL_S_M = 2.0e-5 / 0.002
GRAVITY_M_S2 = (0.0, -9.81)
BARS = Material(
    "bars", "drucker-prager", density_kg_m3=2650.0, youngs_modulus_pa=0.84e6, poisson_ratio=0.3,
    cohesion_pa=0.0, friction_angle_rad=math.radians(19.8), dilatancy_angle_rad=0.0,
)

#: The yardstick's one kernel has four loops, reported by Taichi as tasks in this order.
YARDSTICK_TASKS: tuple[str, ...] = ("reset grid", "P2G mass, momentum and force", "grid pass", "G2P")
_KERNEL_NAME = re.compile(r"^(?P<base>.+?)_c\d+_\d+_kernel_(?P<task>\d+)_(?P<kind>[a-z_]+)$")


class BenchError(Exception):
    """The benchmark could not run (bad configuration or a failed measurement)."""


# --------------------------------------------------------------------------------------------
# configuration


@dataclass(frozen=True)
class BenchConfig:
    """What one benchmark run measures.

    ``batch_s`` is the wall time aimed at for one timed batch of steps of the slowest variant of
    a group; the step count is common to the group and clamped to ``[min_steps, max_steps]``.
    Each variant is timed ``rounds`` times (interleaved): rates come from the best round, ratios
    are medians of per-round ratios (:func:`paired_ratio`).
    """

    particle_counts: tuple[int, ...] = (1_000, 20_000)
    precisions: tuple[str, ...] = ("f32",)
    schemes: tuple[str, ...] = SCHEMES
    archs: tuple[str, ...] = ("cpu", "gpu")
    gpu_particle_counts: tuple[int, ...] = (1_000, 20_000)
    batch_s: float = 0.3
    rounds: int = 3
    warmup_steps: int = 3
    min_steps: int = 10
    max_steps: int = 2_000
    profile_particles: tuple[int, ...] = (20_000,)
    profile_steps: int = 100
    empty_domain_particles: int = 20_000
    empty_domain_schemes: tuple[str, ...] = ("apic-affine",)
    stall_particles: int = 20_000
    stall_duration_s: float = 0.03
    stall_interval_s: float = 0.01
    stall_rounds: int = 1
    envelope_particles: int = 20_000
    envelope_every_steps: int = 10
    envelope_steps: int = 200
    gpu_full_run: bool = False
    #: process start to first step (``runout run`` in a child process) with a cold and a warm
    #: kernel cache, ``startup_runs`` warm runs per scene (0: not measured)
    startup_runs: int = 2

    def __post_init__(self) -> None:
        problems = []
        if not self.particle_counts or min(self.particle_counts) < 8:
            problems.append("particle_counts must hold counts of at least 8")
        for p in self.precisions:
            if p not in ("f32", "f64"):
                problems.append(f"unknown precision {p!r}")
        for s in (*self.schemes, *self.empty_domain_schemes):
            if s not in SCHEMES:
                problems.append(f"unknown scheme {s!r}; allowed: {', '.join(SCHEMES)}")
        for a in self.archs:
            if a not in ("cpu", "gpu"):
                problems.append(f"unknown arch {a!r}")
        if self.rounds < 1 or self.min_steps < 1 or self.max_steps < self.min_steps or self.batch_s <= 0:
            problems.append("need rounds >= 1, 1 <= min_steps <= max_steps and batch_s > 0")
        if self.envelope_every_steps < 1 or self.envelope_steps < 1:
            problems.append("need envelope_every_steps >= 1 and envelope_steps >= 1")
        if self.stall_interval_s <= 0 or self.stall_duration_s < 0:
            problems.append("need stall_interval_s > 0 and stall_duration_s >= 0")
        if problems:
            raise BenchError("; ".join(problems))


QUICK = BenchConfig()
FULL = BenchConfig(
    particle_counts=(1_000, 10_000, 20_000, 100_000, 200_000),
    precisions=("f32", "f64"),
    gpu_particle_counts=(1_000, 10_000, 20_000, 100_000, 1_000_000),
    batch_s=0.4,
    rounds=5,
    warmup_steps=5,
    min_steps=20,
    profile_particles=(1_000, 20_000),
    profile_steps=200,
    empty_domain_schemes=SCHEMES,
    stall_duration_s=0.05,
    stall_rounds=3,
    gpu_full_run=True,
)


# --------------------------------------------------------------------------------------------
# the scene


def collapse_scene(n_particles: int, precision: str = "f32", scheme: str = "apic-affine", arch: str = "cpu",
                   length_factor: float = 1.0, duration_s: float = 1.0,
                   output: Output | None = None) -> tuple[SimulationConfig, Particles]:
    """The standard granular-collapse scene at about ``n_particles`` particles.

    A Drucker-Prager block like the aluminium bars of Bui et al. (2008), 0.2 m x 0.1 m on a
    0.8 m x 0.15 m grid box (its length times ``length_factor``), slip side walls, frictional
    floor, open top, 2 x 2 particles per cell on a lattice. The particle count sets the
    resolution: the cell is ``2 * 0.2 m / round(sqrt(2 n))`` (2 mm at 20,000 particles, the
    paper's scene) and the time step 20 us per 2 mm of cell. Stages: K0, then a dynamic collapse
    of ``duration_s``.

    Returns
    -------
    (SimulationConfig, Particles)
    """
    nx = max(2, round(math.sqrt(2.0 * n_particles)))
    ny = max(1, nx // 2)
    spacing = BLOCK_M[0] / nx
    dx = PARTICLES_PER_CELL_SIDE * spacing
    xs = (np.arange(nx) + 0.5) * spacing
    ys = (np.arange(ny) + 0.5) * spacing
    X, Y = np.meshgrid(xs, ys)
    positions = np.column_stack([X.ravel(), Y.ravel()])
    particles = Particles(positions, np.full(len(positions), spacing * spacing), np.zeros(len(positions), np.int32))
    friction = Boundary("friction", BARS.friction_angle_rad)
    grid = Grid((0.0, 0.0), (DOMAIN_M[0] * length_factor, DOMAIN_M[1]), dx, left=Boundary("slip"),
                right=Boundary("slip"), bottom=friction, top=Boundary("open"))
    numerics = Numerics(scheme=scheme, time_step_s=scene_time_step(dx), cfl=None, precision=precision, arch=arch)
    stages = (Stage("initial stress", "k0"), Stage("collapse", "dynamic", duration_s=duration_s))
    config = SimulationConfig(grid, (BARS,), stages, GRAVITY_M_S2, numerics, output or Output(duration_s))
    return config, particles


def scene_time_step(cell_size_m: float) -> float:
    """The scene's time step (s) for a cell size (m)."""
    return DT_PER_CELL_S_M * cell_size_m


def _k0_stress(config: SimulationConfig, particles: Particles) -> np.ndarray:
    from solver.initial_stress import k0_stress

    return k0_stress(particles, config.materials, config.gravity_m_s2, config.grid.cell_size_m, None,
                     np.ones(len(particles), bool), particles.positions_m)


# --------------------------------------------------------------------------------------------
# the yardstick


@ti.data_oriented
class Yardstick:
    """A minimal MLS-MPM step: the performance yardstick.

    Symbols (SI): ``x`` position (m), ``v`` velocity (m/s), ``C`` affine velocity matrix (1/s),
    ``J`` volume ratio (-), ``vol`` initial particle area (m2), ``mass`` particle mass (kg/m),
    ``K`` bulk modulus (Pa), ``dx`` cell (m), ``dt`` step (s), ``g`` gravity (m/s2).

    One weakly compressible fluid with ``sigma = K (J - 1) I``. In MLS-MPM the internal force on
    node ``I``, ``-vol sigma grad N_I``, is approximated by ``-vol sigma (4 / dx^2) N_I (x_I - x_p)``,
    so it joins the APIC affine term: node momentum receives
    ``N_I (mass v + (mass C - dt vol (4 / dx^2) sigma) (x_I - x_p))``. One kernel per step with
    four loops: clear the whole (dense) grid, scatter, grid velocity with gravity and slip walls
    on the four sides, gather velocity and C, update J and the position.
    Needs an acquired runtime; nodes are laid out like the engine's (``pad`` ghost layers).
    """

    def __init__(self, grid: Grid, n_particles: int, volume_m2: float, density_kg_m3: float,
                 bulk_modulus_pa: float, pad: int = 2):
        self.n = int(n_particles)
        self.cells = grid.cells
        self.dx = float(grid.cell_size_m)
        self.inv_dx = 1.0 / self.dx
        self.origin = (float(grid.origin_m[0]), float(grid.origin_m[1]))
        self.upper = (self.origin[0] + self.cells[0] * self.dx, self.origin[1] + self.cells[1] * self.dx)
        self.pad = int(pad)
        self.nodes = (self.cells[0] + 1 + 2 * self.pad, self.cells[1] + 1 + 2 * self.pad)
        self.vol = float(volume_m2)
        self.mass = float(volume_m2 * density_kg_m3)
        self.bulk = float(bulk_modulus_pa)
        self.x = ti.Vector.field(2, float, self.n)
        self.v = ti.Vector.field(2, float, self.n)
        self.C = ti.Matrix.field(2, 2, float, self.n)
        self.J = ti.field(float, self.n)
        self.grid_m = ti.field(float, self.nodes)
        self.grid_v = ti.Vector.field(2, float, self.nodes)  # momentum after P2G, velocity after the grid pass

    def load(self, positions_m: np.ndarray) -> None:
        """Reset the state: particles at ``positions_m`` (n, 2), at rest, undeformed."""
        from taichi.lang.util import to_numpy_type

        f = to_numpy_type(self.x.dtype)
        self.x.from_numpy(np.asarray(positions_m, dtype=f))
        self.v.from_numpy(np.zeros((self.n, 2), f))
        self.C.from_numpy(np.zeros((self.n, 2, 2), f))
        self.J.from_numpy(np.ones(self.n, f))

    def step(self, dt: float, gravity: tuple[float, float], damping: float = 0.0) -> None:
        """One step of ``dt`` seconds (``damping`` is ignored; same call as the engine's)."""
        self._substep(dt, ti.Vector([float(gravity[0]), float(gravity[1])]))

    def diagnostics(self) -> dict[str, float]:
        v = self.v.to_numpy().astype(np.float64)
        return {"kinetic_energy": float(0.5 * self.mass * (v * v).sum()), "max_speed": float(np.abs(v).max())}

    @ti.kernel
    def _substep(self, dt: float, g: ti.types.vector(2, float)):
        for I in ti.grouped(self.grid_m):
            self.grid_m[I] = 0.0
            self.grid_v[I] = ti.Vector.zero(float, 2)
        for p in range(self.n):
            X = (self.x[p] - ti.Vector(self.origin)) * self.inv_dx + self.pad
            base = ti.cast(X - 0.5, ti.i32)
            fx = X - ti.cast(base, float)
            w = [0.5 * (1.5 - fx) ** 2, 0.75 - (fx - 1.0) ** 2, 0.5 * (fx - 0.5) ** 2]
            pressure = -dt * self.vol * 4.0 * self.inv_dx * self.inv_dx * self.bulk * (self.J[p] - 1.0)
            affine = pressure * ti.Matrix.identity(float, 2) + self.mass * self.C[p]
            mv = self.mass * self.v[p]
            for i, j in ti.static(ti.ndrange(3, 3)):
                offset = ti.Vector([i, j])
                dpos = (ti.cast(offset, float) - fx) * self.dx
                weight = w[i][0] * w[j][1]
                self.grid_v[base + offset] += weight * (mv + affine @ dpos)
                self.grid_m[base + offset] += weight * self.mass
        for I in ti.grouped(self.grid_m):
            m = self.grid_m[I]
            if m > 0.0:
                v = self.grid_v[I] / m + dt * g
                for d in ti.static(range(2)):
                    if I[d] <= self.pad and v[d] < 0.0:
                        v[d] = 0.0
                    if I[d] >= self.pad + self.cells[d] and v[d] > 0.0:
                        v[d] = 0.0
                self.grid_v[I] = v
        for p in range(self.n):
            X = (self.x[p] - ti.Vector(self.origin)) * self.inv_dx + self.pad
            base = ti.cast(X - 0.5, ti.i32)
            fx = X - ti.cast(base, float)
            w = [0.5 * (1.5 - fx) ** 2, 0.75 - (fx - 1.0) ** 2, 0.5 * (fx - 0.5) ** 2]
            new_v = ti.Vector.zero(float, 2)
            new_C = ti.Matrix.zero(float, 2, 2)
            for i, j in ti.static(ti.ndrange(3, 3)):
                offset = ti.Vector([i, j])
                dpos = (ti.cast(offset, float) - fx) * self.dx
                weight = w[i][0] * w[j][1]
                gv = self.grid_v[base + offset]
                new_v += weight * gv
                new_C += 4.0 * self.inv_dx * self.inv_dx * weight * gv.outer_product(dpos)
            self.v[p] = new_v
            self.C[p] = new_C
            self.J[p] *= 1.0 + dt * new_C.trace()
            x = self.x[p] + dt * new_v
            for d in ti.static(range(2)):
                x[d] = ti.min(ti.max(x[d], self.origin[d]), self.upper[d])
            self.x[p] = x


# --------------------------------------------------------------------------------------------
# measuring helpers


def _rss_bytes() -> int | None:
    """Resident set size of this process (Linux), or None where /proc is not there."""
    try:
        with open("/proc/self/statm", encoding="ascii") as fh:
            return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError):
        return None


def field_bytes(obj: Any, _seen: set[int] | None = None) -> dict[str, int]:
    """Bytes of every Taichi field held by ``obj`` and the data-oriented objects it holds.

    Computed from each field's shape, components and dtype. Returns ``{attribute path: bytes}``.
    """
    from taichi.lang.field import Field
    from taichi.lang.util import to_numpy_type

    seen = _seen if _seen is not None else set()
    out: dict[str, int] = {}
    if id(obj) in seen:
        return out
    seen.add(id(obj))
    for name, value in vars(obj).items():
        if isinstance(value, Field):
            comps = getattr(value, "n", 1) * getattr(value, "m", 1)
            elems = int(np.prod(value.shape)) if value.shape else 1
            out[name] = elems * comps * np.dtype(to_numpy_type(value.dtype)).itemsize
        elif getattr(type(value), "_data_oriented", False):
            for sub, nbytes in field_bytes(value, seen).items():
                out[f"{name}.{sub}"] = nbytes
    return out


def _memory(obj: Any, n_particles: int) -> dict[str, Any]:
    sizes = field_bytes(obj)
    nodes = getattr(obj, "nodes", None)
    particle = grid = other = 0
    for name, nbytes in sizes.items():
        field = obj
        for part in name.split("."):
            field = getattr(field, part)
        shape = tuple(field.shape)
        if shape and shape[0] == n_particles and len(shape) == 1:
            particle += nbytes
        elif nodes is not None and shape == tuple(nodes):
            grid += nbytes
        else:
            other += nbytes
    total = particle + grid + other
    return {
        "field_bytes": total,
        "bytes_per_particle": total / n_particles,
        "particle_bytes_per_particle": particle / n_particles,
        "grid_bytes_per_particle": grid / n_particles,
        "other_bytes": other,
        "fields": sizes,
    }


class _Variant:
    """One thing to time in a group: an engine of one scheme, or the yardstick."""

    def __init__(self, name: str, config: SimulationConfig, particles: Particles, np_float: type):
        self.name = name
        self.config = config
        self.particles = particles
        self.dt = config.numerics.time_step_s
        self.gravity = config.gravity_m_s2
        n = len(particles)
        rss0 = _rss_bytes()
        t0 = time.perf_counter()
        if name == YARDSTICK:
            self.obj: Any = Yardstick(config.grid, n, float(particles.volumes_m2.mean()), BARS.density_kg_m3,
                                      BARS.bulk_modulus_pa)
            self.stress = None
        else:
            # the same construction as solver.simulation.Simulation, several engines in one runtime
            grid = config.grid
            height = grid.cells[1] * grid.cell_size_m
            g = math.hypot(*config.gravity_m_s2)
            bound = config.numerics.speed_bound_factor * max(math.sqrt(2.0 * g * height), 1.0)
            # as Simulation builds it for this scene: no stage uses damping, so no grid force field
            scheme, scatter = ("apic-affine", SCATTER_VARIANTS[name]) if name in SCATTER_VARIANTS else (name, "auto")
            water = None
            if name == WATER_VARIANT:
                from solver.config import Water
                from solver.engine import PAD
                from solver.groundwater import GroundWater

                scheme = "apic-affine"
                water = GroundWater(grid.cells[0] + 1 + 2 * PAD, -PAD * grid.cell_size_m, grid.cell_size_m,
                                    config.materials, config.gravity_m_s2, np_float)
                level = 0.5 * BLOCK_M[1]
                water.set_water(Water(((0.0, level), (grid.size_m[0], level))), None, 0.0)
            materials = config.materials
            if name in (SOFTENING_VARIANT, AVERAGING_VARIANT):
                scheme = "apic-affine"
            if name == SOFTENING_VARIANT:
                import dataclasses

                from solver.config import Softening

                materials = tuple(dataclasses.replace(m, softening=Softening(
                    m.cohesion_pa, math.atan(2.0 / 3.0 * math.tan(m.friction_angle_rad)), 0.0, 0.05))
                    for m in materials)
            self.obj = Engine(grid, materials, n, scheme, np_float, speed_bound_m_s=bound, damping=False,
                              scatter=scatter, water=water, volumetric_averaging=name == AVERAGING_VARIANT)
            self.stress = _k0_stress(config, particles)
        self.reset()
        for _ in range(2):  # compile, then run the warm-up steps from a clean state
            self.step()
            ti.sync()
            self.reset()
        self.build_s = time.perf_counter() - t0
        rss1 = _rss_bytes()
        self.rss_delta = None if rss0 is None or rss1 is None else rss1 - rss0
        self.memory = _memory(self.obj, n)
        self.times: list[float] = []

    def reset(self) -> None:
        p = self.particles
        if self.name == YARDSTICK:
            self.obj.load(p.positions_m)
        else:
            self.obj.load_particles(p.positions_m, p.volumes_m2, p.material_ids)
            self.obj.set_stress(self.stress)
        ti.sync()

    def step(self) -> None:
        self.obj.step(self.dt, self.gravity, 0.0)

    def step_by_stage(self) -> None:
        """One launch per stage (the engine's recipe), so the profiler can name each stage."""
        if self.name == YARDSTICK:
            self.step()
        else:
            self.obj.step_by_stage(self.dt, self.gravity, 0.0)

    def timed(self, steps: int) -> float:
        """Wall seconds of ``steps`` steps from the initial state (state reset outside the clock)."""
        self.reset()
        t0 = time.perf_counter()
        for _ in range(steps):
            self.step()
        ti.sync()
        return time.perf_counter() - t0

    def finite(self) -> bool:
        d = self.obj.diagnostics()
        return math.isfinite(d["kinetic_energy"]) and math.isfinite(d["max_speed"])


@contextmanager
def _taichi_runtime(arch: str, precision: str, profiler: bool = False) -> Iterator[str]:
    """Acquire the solver's runtime (with Taichi's kernel profiler on if asked); release it after."""
    old = os.environ.get("TI_KERNEL_PROFILER")
    if profiler:
        # read by ti.init inside runtime.acquire: a bench-only switch, solver/runtime.py unchanged
        os.environ["TI_KERNEL_PROFILER"] = "1"
    try:
        used = runtime.acquire(arch, precision)
    finally:
        if profiler:
            if old is None:
                os.environ.pop("TI_KERNEL_PROFILER", None)
            else:
                os.environ["TI_KERNEL_PROFILER"] = old
    try:
        yield used
    finally:
        runtime.release()


def _np_float(precision: str) -> type:
    return np.float32 if precision == "f32" else np.float64


def paired_ratio(numerator_times: list[float], denominator_times: list[float]) -> float:
    """Median over rounds of ``numerator_times[r] / denominator_times[r]``.

    Times of one round were measured back to back, so their ratio is little affected by load
    that changes between rounds (other work on the machine); the median drops outlying rounds.
    """
    return statistics.median(a / b for a, b in zip(numerator_times, denominator_times, strict=True))


def _common_steps(variants: list[_Variant], cfg: BenchConfig) -> int:
    """A step count that makes the slowest variant's batch last about ``cfg.batch_s``."""
    probe = max(1, min(cfg.warmup_steps, cfg.max_steps))
    # best of two probes: a probe hit by other work on the machine would make every batch short
    slowest = max(min(v.timed(probe), v.timed(probe)) / probe for v in variants)
    return int(min(cfg.max_steps, max(cfg.min_steps, round(cfg.batch_s / max(slowest, 1e-9)))))


def _group(arch: str, precision: str, n: int, cfg: BenchConfig,
           note: Callable[[str], None]) -> tuple[str, list[dict[str, Any]]]:
    """Time the yardstick and every scheme at one (arch, precision, particles); return rows."""
    rows: list[dict[str, Any]] = []
    with _taichi_runtime(arch, precision) as used:
        if used != arch:
            return used, rows
        note(f"throughput: {arch} {precision} {n:,} particles")
        variants = []
        wet = COMPONENT_VARIANTS if "apic-affine" in cfg.schemes else ()
        for name in (YARDSTICK, *cfg.schemes, *wet):
            config, particles = collapse_scene(n, precision, name if name in SCHEMES else "apic-affine", arch)
            variants.append(_Variant(name, config, particles, _np_float(precision)))
        steps = _common_steps(variants, cfg)
        for _ in range(cfg.rounds):
            for v in variants:
                v.times.append(v.timed(steps))
        n_real = len(variants[0].particles)
        yard = variants[0]
        apic = next((v for v in variants if v.name == "apic"), None)
        dry = next((v for v in variants if v.name == "apic-affine"), None)
        for v in variants:
            rate = n_real * steps / min(v.times)
            rows.append({
                "arch": arch, "precision": precision, "variant": v.name, "particles": n_real,
                "scatter": getattr(v.obj, "scatter", None), "grid_cells": list(v.config.grid.cells), "steps": steps, "rounds": len(v.times),
                "times_s": list(v.times), "best_s": min(v.times), "median_s": statistics.median(v.times),
                "step_time_s": min(v.times) / steps,
                "particle_steps_per_s": rate,
                "particle_steps_per_s_median": n_real * steps / statistics.median(v.times),
                "ratio_to_yardstick": paired_ratio(yard.times, v.times),
                "ratio_to_yardstick_best": min(yard.times) / min(v.times),
                "ratio_to_apic": None if apic is None else paired_ratio(apic.times, v.times),
                "ratio_to_apic_best": None if apic is None else min(apic.times) / min(v.times),
                # the water variant's throughput over the dry engine's (1: water costs nothing)
                "ratio_to_dry": paired_ratio(dry.times, v.times) if v.name in COMPONENT_VARIANTS and dry else None,
                "build_and_compile_s": v.build_s,
                "bytes_per_particle": v.memory["bytes_per_particle"],
                "particle_bytes_per_particle": v.memory["particle_bytes_per_particle"],
                "grid_bytes_per_particle": v.memory["grid_bytes_per_particle"],
                "field_bytes": v.memory["field_bytes"],
                "fields": v.memory["fields"],
                "rss_delta_bytes": v.rss_delta,
                "rss_delta_bytes_per_particle": None if v.rss_delta is None else v.rss_delta / n_real,
                "finite": v.finite(),
            })
    return used, rows


# --------------------------------------------------------------------------------------------
# profile


def _kernel_records() -> list[tuple[str, float]]:
    """(task name, seconds) of every kernel task since the last clear (the kernel profiler must be on)."""
    # Taichi 1.7 keeps the records in the program; its public API only prints or queries by name.
    prog = ti.lang.impl.get_runtime().prog
    return [(r.name, r.kernel_time * 1e-3) for r in prog.get_kernel_profiler_records()]


def _recipe_stages(records: list[tuple[str, float]], recipe: tuple[str, ...]) -> dict[str, tuple[str, str]]:
    """Kernel instance -> (kernel, stage) for a stage-by-stage step: instances appear in recipe order."""
    order: list[str] = []
    for task, _seconds in records:
        key = task.rsplit("_kernel_", 1)[0]
        if key not in order:
            order.append(key)
    return {key: (f"{stage}", stage) for key, stage in zip(order, recipe)}


def _stage_of(task: str, variant: str) -> tuple[str, str]:
    """(kernel, stage of the step) of one profiler task name."""
    m = _KERNEL_NAME.match(task)
    if m is None:
        return task, "other"
    base = m.group("base")
    index = int(m.group("task"))
    if variant == YARDSTICK and base == "_substep":
        stage = YARDSTICK_TASKS[index] if index < len(YARDSTICK_TASKS) else "other"
        return f"_substep (loop {index})", stage
    # a kernel outside the engine's recipe: report each of its loops
    return f"{base} (loop {index})", f"other: {base}"


def _constitutive_alone(n: int, precision: str, steps: int) -> float:
    """Seconds per update of ``n`` Drucker-Prager points alone (the single-point driver)."""
    from solver.materials import MaterialPointDriver

    config, particles = collapse_scene(n, precision)
    n = len(particles)
    stress = _k0_stress(config, particles)
    rng = np.random.default_rng(6)
    grad = rng.normal(scale=10.0, size=(n, 2, 2))  # 1/s, a collapsing block's order of magnitude
    driver = MaterialPointDriver(config.materials, n, _np_float(precision))
    dt = config.numerics.time_step_s
    driver.run(stress, grad, dt, steps=2)  # compile

    def wall(count: int) -> float:
        t0 = time.perf_counter()
        driver.run(stress, grad, dt, steps=count)
        return time.perf_counter() - t0

    # the difference cancels the copies in and out; best of three of each
    one = min(wall(1) for _ in range(3))
    many = min(wall(1 + steps) for _ in range(3))
    return max(many - one, 0.0) / steps


def profile_step(n: int, arch: str = "cpu", precision: str = "f32", steps: int = 100,
                 schemes: tuple[str, ...] = SCHEMES, rounds: int = 3,
                 note: Callable[[str], None] | None = None) -> dict[str, Any] | None:
    """Where a step's time goes, per variant, from Taichi's kernel profiler.

    Every variant runs ``steps`` steps from the initial state ``rounds`` times (interleaved);
    the round with the least wall time is reported. Returns ``None`` when ``arch`` is not
    available. Otherwise a dict with, per variant: wall time per step (profiler on), kernel time
    per step, the difference (time outside the kernels: Python and launch overhead), kernel tasks
    per step and the time per step of each kernel and each stage; plus the constitutive update of
    the same number of points timed alone.
    """
    note = note or (lambda _msg: None)
    out: dict[str, Any] = {"arch": arch, "precision": precision, "steps": steps, "rounds": rounds, "variants": {}}
    with _taichi_runtime(arch, precision, profiler=True) as used:
        if used != arch:
            return None
        note(f"profile: {arch} {precision} {n:,} particles")
        chosen = resolve_scatter("auto", n)
        extra = tuple(name for name, s in SCATTER_VARIANTS.items() if s != chosen) if "apic-affine" in schemes else ()
        variants = []
        for name in (YARDSTICK, *schemes, *extra):
            config, particles = collapse_scene(n, precision, name if name in SCHEMES else "apic-affine", arch)
            variants.append(_Variant(name, config, particles, _np_float(precision)))
        best: dict[str, tuple[float, list[tuple[str, float]]]] = {}
        for _ in range(rounds):
            for v in variants:
                # stage times from the stage-by-stage recipe; the overhead from the one-launch step
                v.reset()
                ti.profiler.clear_kernel_profiler_info()
                for _ in range(steps):
                    v.step_by_stage()
                ti.sync()
                records = _kernel_records()
                v.reset()
                t0 = time.perf_counter()
                for _ in range(steps):
                    v.step()
                ti.sync()
                wall = (time.perf_counter() - t0) / steps
                if v.name not in best or wall < best[v.name][0]:
                    best[v.name] = (wall, records)
        out["particles"] = len(variants[0].particles)
        for v in variants:
            wall, records = best[v.name]
            kernels: dict[str, float] = {}
            stages: dict[str, float] = {}
            named = {} if v.name == YARDSTICK else _recipe_stages(records, v.obj.recipe)
            for task, seconds in records:
                kernel, stage = named.get(task.rsplit("_kernel_", 1)[0]) or _stage_of(task, v.name)
                kernels[kernel] = kernels.get(kernel, 0.0) + seconds / steps
                stages[stage] = stages.get(stage, 0.0) + seconds / steps
            kernel_time = sum(kernels.values())
            outside = max(wall - kernel_time, 0.0)
            out["variants"][v.name] = {
                "scatter": getattr(v.obj, "scatter", None),
                "wall_s_per_step": wall,
                "kernel_s_per_step": kernel_time,
                "python_s_per_step": outside,
                "python_fraction": outside / wall if wall > 0 else 0.0,
                "tasks_per_step": len(records) / steps,
                "kernels_s_per_step": dict(sorted(kernels.items(), key=lambda kv: -kv[1])),
                "stages_s_per_step": dict(sorted(stages.items(), key=lambda kv: -kv[1])),
            }
        del variants
        out["constitutive_alone_s_per_step"] = _constitutive_alone(n, precision, steps)
    return out


# --------------------------------------------------------------------------------------------
# empty domain and output stall


def empty_domain(n: int, cfg: BenchConfig, arch: str = "cpu", precision: str = "f32",
                 note: Callable[[str], None] | None = None) -> dict[str, Any] | None:
    """Step time with the grid box twice as long (empty beyond the block) over the normal box."""
    note = note or (lambda _msg: None)
    with _taichi_runtime(arch, precision) as used:
        if used != arch:
            return None
        note(f"empty domain: {arch} {precision} {n:,} particles")
        pairs = []
        for name in (*cfg.empty_domain_schemes, YARDSTICK):
            scheme = name if name in SCHEMES else "apic-affine"
            base = _Variant(name, *collapse_scene(n, precision, scheme, arch), _np_float(precision))
            long = _Variant(name, *collapse_scene(n, precision, scheme, arch, length_factor=2.0), _np_float(precision))
            pairs.append((name, base, long))
        steps = _common_steps([v for _, b, lg in pairs for v in (b, lg)], cfg)
        for _ in range(cfg.rounds):
            for _, base, long in pairs:
                base.times.append(base.timed(steps))
                long.times.append(long.timed(steps))
        result: dict[str, Any] = {"arch": arch, "precision": precision, "particles": len(pairs[0][1].particles),
                                  "steps": steps, "variants": {}}
        for name, base, long in pairs:
            result["variants"][name] = {
                "step_time_s": min(base.times) / steps,
                "step_time_doubled_s": min(long.times) / steps,
                "ratio": paired_ratio(long.times, base.times),
                "ratio_best": min(long.times) / min(base.times),
                "times_s": list(base.times), "times_doubled_s": list(long.times),
                "grid_cells": list(base.config.grid.cells),
                "grid_cells_doubled": list(long.config.grid.cells),
                "bytes_per_particle": base.memory["bytes_per_particle"],
                "bytes_per_particle_doubled": long.memory["bytes_per_particle"],
            }
    return result


def output_stall(n: int, cfg: BenchConfig, arch: str = "cpu", precision: str = "f32",
                 note: Callable[[str], None] | None = None) -> dict[str, Any] | None:
    """Wall time of a run with frames every ``stall_interval_s`` written to disk over one without.

    Both runs go through :meth:`solver.simulation.Simulation.run` (K0, then the collapse for
    ``stall_duration_s``), after their kernels are compiled. With frames, each is handed to a
    :class:`projects.results.ResultsWriter` in a temporary folder and the time includes closing
    it (every frame on disk). Without, the run yields only its first and last frame, dropped.

    Besides the two wall times (which other work on the machine disturbs), the costs a frame
    adds are timed on their own: copying the frame's fields from the solver (``state``), encoding
    it (the writer thread's work), the solver thread's time in ``write_frame`` and in ``close``.
    ``estimated_ratio`` is ``1 + frames * (copy + encode) / wall without frames``: the stall if
    none of that overlapped the solver.
    """
    from projects.results import ResultsWriter, encode_vtp
    from solver.simulation import Simulation

    note = note or (lambda _msg: None)
    if cfg.stall_duration_s <= 0:
        return None
    config, particles = collapse_scene(n, precision, "apic-affine", arch, duration_s=cfg.stall_duration_s)
    runs: dict[str, list[dict[str, float]]] = {"none": [], "frames": []}
    used = arch
    note(f"output stall: {arch} {precision} {len(particles):,} particles, {cfg.stall_duration_s:g} s simulated")
    for _ in range(cfg.stall_rounds):
        for variant in ("none", "frames"):
            interval = cfg.stall_interval_s if variant == "frames" else cfg.stall_duration_s * 2.0
            run_config = replace(config, output=Output(interval, OUTPUT_FIELDS))
            sim = Simulation(run_config, particles)
            try:
                used = sim.arch
                if used != arch:
                    return None
                sim.engine.step(0.0, (0.0, 0.0), 0.0)  # compile (a zero step leaves a body at rest alone)
                sim.engine.diagnostics()
                sim.engine.state()
                ti.sync()
                with tempfile.TemporaryDirectory(prefix="runout-bench-") as tmp:
                    t0 = time.perf_counter()
                    writer = None
                    if variant == "frames":
                        meta = {"title": "runout bench", "scheme": "apic-affine", "arch": used,
                                "precision": precision, "particles": len(particles)}
                        writer = ResultsWriter(Path(tmp) / "bench.results", "# runout bench\n", meta)
                    frames = 0
                    handing = closing = 0.0
                    last = None
                    for frame in sim.run():
                        frames += 1
                        last = frame
                        if writer is not None:
                            t1 = time.perf_counter()
                            writer.write_frame(frame)
                            handing += time.perf_counter() - t1
                    if writer is not None:
                        t1 = time.perf_counter()
                        writer.close("completed", steps=sim.steps, simulated_time_s=sim.time_s)
                        closing = time.perf_counter() - t1
                    wall = time.perf_counter() - t0
                record = {"wall_s": wall, "steps": sim.steps, "frames": frames}
                if writer is not None:
                    record.update(write_frame_s=handing, close_s=closing)
                    t1 = time.perf_counter()
                    sim.engine.state(("x", "x0", "v", "s", "eps_p", "mat", "active"))
                    record["copy_s_per_frame"] = time.perf_counter() - t1
                    t1 = time.perf_counter()
                    encode_vtp(last.fields, last.diagnostics.time_s)
                    record["encode_s_per_frame"] = time.perf_counter() - t1
                runs[variant].append(record)
            finally:
                sim.close()
    best = {k: min(v, key=lambda r: r["wall_s"]) for k, v in runs.items()}
    return {
        "arch": used, "precision": precision, "particles": len(particles), "scheme": "apic-affine",
        "simulated_s": cfg.stall_duration_s, "interval_s": cfg.stall_interval_s, "rounds": cfg.stall_rounds,
        "wall_s_without_frames": best["none"]["wall_s"], "wall_s_with_frames": best["frames"]["wall_s"],
        "steps_without_frames": best["none"]["steps"], "steps_with_frames": best["frames"]["steps"],
        "frames_written": best["frames"]["frames"],
        "ratio": paired_ratio([r["wall_s"] for r in runs["frames"]], [r["wall_s"] for r in runs["none"]]),
        "ratio_best": best["frames"]["wall_s"] / best["none"]["wall_s"],
        "copy_s_per_frame": min(r["copy_s_per_frame"] for r in runs["frames"]),
        "encode_s_per_frame": min(r["encode_s_per_frame"] for r in runs["frames"]),
        "write_frame_s": min(r["write_frame_s"] for r in runs["frames"]),
        "close_s": min(r["close_s"] for r in runs["frames"]),
        "estimated_ratio": 1.0 + best["frames"]["frames"] * (
            min(r["copy_s_per_frame"] for r in runs["frames"]) + min(r["encode_s_per_frame"] for r in runs["frames"])
        ) / best["none"]["wall_s"],
        "runs": runs,
    }


def envelope_cost(n: int, cfg: BenchConfig, arch: str = "cpu", precision: str = "f32",
                  note: Callable[[str], None] | None = None) -> dict[str, Any] | None:
    """The hazard envelopes' share of a run: update time / (``envelope_every_steps`` x step time).

    The scene collapses for ``envelope_steps`` steps in batches of ``envelope_every_steps``; in each
    batch the steps and then one envelope update (with two targets) are timed apart (synchronised),
    so both see the same particle state. ``fraction`` is the median over batches of
    ``update / steps``: the run time the envelopes add at that update interval.
    """
    from solver.envelopes import Envelopes
    from solver.config import EnvelopeConfig, Target

    note = note or (lambda _msg: None)
    every = cfg.envelope_every_steps
    with _taichi_runtime(arch, precision) as used:
        if used != arch:
            return None
        config, particles = collapse_scene(n, precision, "apic-affine", arch)
        variant = _Variant("apic-affine", config, particles, _np_float(precision))
        env_config = EnvelopeConfig(config.grid.cell_size_m, every, 0.5 * config.grid.cell_size_m / 2,
                                    (Target("line", 0.3), Target("point", 0.35, 0.01)))
        env = Envelopes(variant.obj, env_config, config.grid)
        note(f"hazard envelopes: {arch} {precision} {len(particles):,} particles, every {every} steps")
        variant.reset()
        variant.step()
        env.start(0.0)  # compiles
        env.update(0.0)
        ti.sync()
        batches = max(1, cfg.envelope_steps // every)
        step_times, update_times, step_cpu, update_cpu = [], [], [], []
        for b in range(batches):
            c0, t0 = time.process_time(), time.perf_counter()
            for _ in range(every):
                variant.step()
            ti.sync()
            c1, t1 = time.process_time(), time.perf_counter()
            env.update(float(b))
            ti.sync()
            c2, t2 = time.process_time(), time.perf_counter()
            step_times.append(t1 - t0)
            update_times.append(t2 - t1)
            step_cpu.append(c1 - c0)
            update_cpu.append(c2 - c1)
        fractions = [u / st for u, st in zip(update_times, step_times)]
        return {
            "arch": used, "precision": precision, "particles": len(particles), "every_steps": every,
            "raster": list(env.shape), "batches": batches,
            "step_time_s": statistics.median(step_times) / every,
            "update_time_s": statistics.median(update_times),
            "fraction": statistics.median(fractions),
            "fraction_best": min(update_times) / (min(step_times)),
            # CPU seconds of the process (all threads): less disturbed by other work on the machine
            "fraction_cpu": sum(update_cpu) / sum(step_cpu) if sum(step_cpu) > 0 else None,
            "load_average": _load_average(),
        }


def gpu_full_run(note: Callable[[str], None] | None = None) -> dict[str, Any] | None:
    """The paper's aluminium-bar run on the GPU: 20,000 particles, 1 s at 20 us, no frames."""
    from solver.simulation import Simulation

    note = note or (lambda _msg: None)
    config, particles = collapse_scene(20_000, "f32", "apic-affine", "gpu", duration_s=1.0)
    sim = Simulation(config, particles)
    try:
        if sim.arch != "gpu":
            return None
        note("GPU: the aluminium-bar run, 1 s simulated")
        sim.engine.step(0.0, (0.0, 0.0), 0.0)
        sim.engine.diagnostics()
        sim.engine.state()
        ti.sync()
        t0 = time.perf_counter()
        for _frame in sim.run():
            pass
        ti.sync()
        wall = time.perf_counter() - t0
        return {"particles": len(particles), "steps": sim.steps, "simulated_s": sim.time_s, "wall_s": wall,
                "status": sim.status}
    finally:
        sim.close()


# --------------------------------------------------------------------------------------------
# the whole benchmark


#: Scenes of the start-up rows: (example, overrides that keep the run short) and the target (s).
STARTUP_SCENES: tuple[tuple[str, tuple[str, ...], float], ...] = (
    ("tiny_column", (), 1.0),
    ("bui2008_aluminium_bars", ("stages.1.duration_s=0.002", "output.interval_s=0.001"), 2.0),
)


def startup(runs: int, note: Callable[[str], None] | None = None) -> list[dict[str, Any]]:
    """Process start to the end of the first step of ``runout run`` (``summary.json: startup_s``).

    Each scene runs once with an empty kernel cache (a fresh ``TI_OFFLINE_CACHE_FILE_PATH``:
    every kernel compiled; Python's bytecode cache as the machine has it) and then ``runs`` times
    with both caches warm; rows give the cold
    figure and the best and median warm figures, in wall seconds (``startup_s``) and in CPU
    seconds of the run process up to the same moment (``startup_cpu_s``: user + system, all its
    threads; what other work on a shared machine disturbs least).
    """
    examples = Path(__file__).resolve().parents[1] / "projects" / "examples"
    rows = []
    for name, sets, goal in STARTUP_SCENES:
        with tempfile.TemporaryDirectory(prefix="runout-startup-") as tmp:
            # A Python installation caches compiled bytecode by default; a machine that sets
            # PYTHONDONTWRITEBYTECODE (this development machine does) would otherwise compile
            # every Runout module from source in every run, which users do not pay.
            env = {**{k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"},
                   "TI_OFFLINE_CACHE_FILE_PATH": str(Path(tmp) / "cache")}
            figures, cpu = [], []
            for i in range(runs + 1):
                out = Path(tmp) / f"run{i}"
                # ``-m app``, as the ``runout`` script does: ``-m app.cli`` would recompile the
                # command line's module in every process (a ``__main__`` is never cached)
                args = [sys.executable, "-m", "app", "run", str(examples / f"{name}.toml"), "--out", str(out),
                        "--quiet", "--set", "numerics.advanced.scatter=serial", *[a for s_ in sets for a in ("--set", s_)]]
                done = subprocess.run(args, env=env, capture_output=True, text=True, timeout=600)
                summary = json.loads((out / "summary.json").read_text()) if (out / "summary.json").is_file() else {}
                if done.returncode != 0 or "startup_s" not in summary:
                    raise BenchError(f"start-up run of {name} failed: {done.stderr.strip()[-300:]}")
                figures.append(float(summary["startup_s"]))
                cpu.append(summary.get("startup_cpu_s"))
            warm = sorted(figures[1:])
            warm_cpu = sorted(c for c in cpu[1:] if c is not None)
            row = {"scene": name, "particles": summary.get("particles"), "cold_s": figures[0],
                   "warm_best_s": warm[0] if warm else None,
                   "warm_median_s": float(np.median(warm)) if warm else None,
                   "cold_cpu_s": cpu[0], "warm_cpu_median_s": float(np.median(warm_cpu)) if warm_cpu else None,
                   "goal_s": goal}
            if note is not None:
                note(f"start-up {name}: cold {row['cold_s']:.2f} s, warm {row['warm_best_s']:.2f} s")
            rows.append(row)
    return rows


def _load_average() -> list[float] | None:
    """1, 5 and 15 minute load averages (other work on the machine disturbs the timings)."""
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except OSError:
        return None


def machine_info() -> dict[str, Any]:
    """CPU model, cores, memory and software versions of this machine."""
    cpu = platform.processor() or platform.machine()
    ram = None
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as fh:
            for line in fh:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
        with open("/proc/meminfo", encoding="utf-8") as fh:
            for line in fh:
                if line.startswith("MemTotal:"):
                    ram = int(line.split()[1]) * 1024
                    break
    except OSError:
        pass
    return {
        "cpu": cpu, "cores": os.cpu_count(), "ram_bytes": ram, "platform": platform.platform(),
        "python": platform.python_version(), "taichi": ".".join(str(p) for p in ti.__version__),
        "numpy": np.__version__, "gpu_available": runtime.gpu_available(),
    }


def _find(rows: list[dict[str, Any]], **match: Any) -> dict[str, Any] | None:
    for row in rows:
        if all(row.get(k) == v for k, v in match.items()):
            return row
    return None


def _nearest(rows: list[dict[str, Any]], particles: int, **match: Any) -> dict[str, Any] | None:
    candidates = [r for r in rows if all(r.get(k) == v for k, v in match.items())]
    if not candidates:
        return None
    return min(candidates, key=lambda r: abs(math.log(r["particles"] / particles)))


def _target(name: str, goal: str, value: float | None, ok: bool | None, where: str, note: str = "") -> dict[str, Any]:
    return {"name": name, "goal": goal, "value": value, "met": ok, "where": where, "note": note}


def evaluate_targets(result: dict[str, Any]) -> list[dict[str, Any]]:
    """The performance targets against the measured figures (``met`` None: not measured)."""
    rows = result["throughput"]
    targets = []
    affine = _nearest(rows, 20_000, arch="cpu", precision="f32", variant="apic-affine")
    where = f"CPU f32 {affine['particles']:,} particles" if affine else "CPU f32"
    ratio = affine["ratio_to_apic"] if affine else None
    targets.append(_target("apic-affine / apic throughput", ">= 2.0", ratio,
                           None if ratio is None else ratio >= 2.0, where, "paper: 2.17"))
    ratio = affine["ratio_to_yardstick"] if affine else None
    targets.append(_target("apic-affine (Drucker-Prager) / yardstick", ">= 1.0", ratio,
                           None if ratio is None else ratio >= 1.0, where))
    wet = _nearest(rows, 20_000, arch="cpu", precision="f32", variant=WATER_VARIANT)
    ratio = wet["ratio_to_dry"] if wet else None
    targets.append(_target("apic-affine with ground water / dry throughput", ">= 0.75", ratio,
                           None if ratio is None else ratio >= 0.75, where,
                           "the pore pressure's cost per step (solver.groundwater)"))
    for variant, what in ((SOFTENING_VARIANT, "the softening return map's cost per step"),
                          (AVERAGING_VARIANT, "the volumetric averaging's pass, per step")):
        row = _nearest(rows, 20_000, arch="cpu", precision="f32", variant=variant)
        ratio = row["ratio_to_dry"] if row else None
        targets.append(_target(f"{variant} / apic-affine throughput", ">= 0.75", ratio,
                               None if ratio is None else ratio >= 0.75, where, what))
    empty = result.get("empty_domain")
    value = empty["variants"]["apic-affine"]["ratio"] if empty and "apic-affine" in empty["variants"] else None
    targets.append(_target("step time, domain twice as long / normal", "< 1.10", value,
                           None if value is None else value < 1.10,
                           f"CPU f32 {empty['particles']:,} particles" if empty else "not measured"))
    value = affine["bytes_per_particle"] if affine else None
    targets.append(_target("solver memory per particle (f32, fields)", "<= 100 B", value,
                           None if value is None else value <= 100.0, where,
                           "grid fields included; the scene's box holds about 1.5 cells per particle"))
    stall = result.get("output_stall")
    value = stall["ratio"] if stall else None
    interval = f"{stall['interval_s']:g}" if stall else "0.01"
    targets.append(_target(f"run time with frames every {interval} s / without", "< 1.10", value,
                           None if value is None else value < 1.10,
                           f"{stall['arch'].upper()} f32 {stall['particles']:,} particles, {stall['simulated_s']:g} s"
                           if stall else "not measured"))
    env = result.get("hazard_envelopes")
    value = env["fraction"] if env else None
    targets.append(_target(f"hazard envelopes every {env['every_steps'] if env else 10} steps: added run time",
                           "< 5 %", value, None if value is None else value < 0.05,
                           f"{env['arch'].upper()} f32 {env['particles']:,} particles" if env else "not measured",
                           "maps updated on the device during the run (solver.envelopes), two targets"))
    gpu = _nearest(rows, 1_000_000, arch="gpu", precision="f32", variant="apic-affine")
    if gpu is not None and gpu["particles"] >= 500_000:
        value = gpu["particle_steps_per_s"]
        targets.append(_target("GPU particle-steps/s at 1e6 f32", ">= 1e9", value, value >= 1e9,
                               f"GPU f32 {gpu['particles']:,} particles"))
    else:
        targets.append(_target("GPU particle-steps/s at 1e6 f32", ">= 1e9", None, None, "GPU", NOT_MEASURED_NO_GPU
                               if not result["machine"]["gpu_available"] else "not measured at 1e6"))
    for row in result.get("startup", []):
        value = row["warm_median_s"]
        targets.append(_target(f"process start to first step, {row['scene']} (warm cache)", f"< {row['goal_s']:g} s",
                               value, None if value is None else value < row["goal_s"],
                               f"CPU, {row['particles']:,} particles",
                               f"cold cache: {row['cold_s']:.2f} s; CPU time warm / cold: "
                               f"{_seconds(row.get('warm_cpu_median_s'))} / {_seconds(row.get('cold_cpu_s'))} s"))
    full = result.get("gpu_full_run")
    if full:
        targets.append(_target("GPU aluminium-bar run (20k, 1 s at 20 us)", "< 1.5 s", full["wall_s"],
                               full["wall_s"] < 1.5, "GPU f32", "paper: 13.18 s on an RTX 3060"))
    else:
        note = NOT_MEASURED_NO_GPU if not result["machine"]["gpu_available"] else "not measured"
        if affine:
            note += f"; on this CPU about {2e4 * 5e4 / affine['particle_steps_per_s']:.0f} s (from the CPU rate)"
        targets.append(_target("GPU aluminium-bar run (20k, 1 s at 20 us)", "< 1.5 s", None, None, "GPU", note))
    return targets


def run_bench_config(cfg: BenchConfig, out: Path | None = None, *,
                     on_progress: Callable[[str], None] | None = None, quick: bool | None = None) -> dict[str, Any]:
    """Run the measurements ``cfg`` asks for; write ``out`` (JSON) and ``out`` with ``.md`` if given.

    Returns the result dict (see ``docs/performance.md`` for its keys).
    """
    def note(msg: str) -> None:
        log.info(msg)
        if on_progress is not None:
            on_progress(msg)

    started = time.perf_counter()
    load_start = _load_average()
    result: dict[str, Any] = {
        "schema": 1,
        "created_at": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "quick": quick,
        "machine": machine_info(),
        "config": asdict(cfg),
        "scene": {"block_m": list(BLOCK_M), "domain_m": list(DOMAIN_M), "material": asdict(BARS),
                  "particles_per_cell": PARTICLES_PER_CELL_SIDE ** 2, "dt_per_cell_s_per_m": DT_PER_CELL_S_M},
        "throughput": [],
        "not_measured": [],
        "profile": [],
    }
    archs = []
    for arch in cfg.archs:
        if arch == "gpu" and not result["machine"]["gpu_available"]:
            result["not_measured"].append({"arch": "gpu", "reason": NOT_MEASURED_NO_GPU})
            continue
        archs.append(arch)
    for arch in archs:
        counts = cfg.gpu_particle_counts if arch == "gpu" else cfg.particle_counts
        skipped = False
        for precision in cfg.precisions:
            for n in counts:
                used, rows = _group(arch, precision, n, cfg, note)
                if used != arch:
                    result["not_measured"].append({"arch": arch, "reason": f"not measured: Taichi fell back to {used}"})
                    skipped = True
                    break
                result["throughput"].extend(rows)
            if skipped:
                break
        if skipped:
            continue
        for n in cfg.profile_particles:
            prof = profile_step(n, arch, "f32", cfg.profile_steps, cfg.schemes, cfg.rounds, note)
            if prof is not None:
                result["profile"].append(prof)
    if "cpu" in archs:
        if cfg.empty_domain_particles > 0:
            result["empty_domain"] = empty_domain(cfg.empty_domain_particles, cfg, "cpu", "f32", note)
        if cfg.stall_particles > 0:
            result["output_stall"] = output_stall(cfg.stall_particles, cfg, "cpu", "f32", note)
        if cfg.envelope_particles > 0:
            result["hazard_envelopes"] = envelope_cost(cfg.envelope_particles, cfg, "cpu", "f32", note)
    if "gpu" in archs and cfg.gpu_full_run:
        result["gpu_full_run"] = gpu_full_run(note)
    if cfg.startup_runs > 0:
        result["startup"] = startup(cfg.startup_runs, note)
    result["targets"] = evaluate_targets(result)
    result["wall_s"] = time.perf_counter() - started
    result["load_average"] = {"start": load_start, "end": _load_average()}
    if out is not None:
        write_result(result, Path(out))
    return result


def run_bench(quick: bool, out: Path | None = None, *,
              on_progress: Callable[[str], None] | None = None) -> dict[str, Any]:
    """The standard benchmark: ``quick`` (1e3 and 2e4 particles, f32, about a minute on two
    cores) or full (1e3 to 2e5 particles, f32 and f64, a few minutes). See :func:`run_bench_config`."""
    return run_bench_config(QUICK if quick else FULL, out, on_progress=on_progress, quick=quick)


def write_result(result: dict[str, Any], out: Path) -> tuple[Path, Path]:
    """Write the result as JSON at ``out`` and as markdown next to it (``.md``)."""
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2, default=_json_default, allow_nan=False) + "\n", encoding="utf-8")
    md = out.with_suffix(".md")
    md.write_text(markdown_report(result), encoding="utf-8")
    return out, md


def _json_default(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, (tuple, set)):
        return list(value)
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


# --------------------------------------------------------------------------------------------
# tables


def _m(rate: float | None) -> str:
    return "-" if rate is None else f"{rate / 1e6:.3g}"


def _x(ratio: float | None) -> str:
    return "-" if ratio is None else f"{ratio:.2f}x"


def _ms(seconds: float | None) -> str:
    return "-" if seconds is None else f"{seconds * 1e3:.3g}"


def _profile_table(prof: dict[str, Any]) -> tuple[str, list[str], list[list[str]]]:
    names = list(prof["variants"])
    stages: list[str] = []
    for v in names:
        for s in prof["variants"][v]["stages_s_per_step"]:
            if s not in stages:
                stages.append(s)
    header = ["stage (ms per step)"] + names
    body = [[s] + [_ms(prof["variants"][v]["stages_s_per_step"].get(s)) for v in names] for s in stages]
    body.append(["kernels, total"] + [_ms(prof["variants"][v]["kernel_s_per_step"]) for v in names])
    body.append(["outside the kernels (Python, launches)"] + [
        f"{_ms(prof['variants'][v]['python_s_per_step'])} ({prof['variants'][v]['python_fraction']:.0%})"
        for v in names])
    body.append(["wall per step (profiler on)"] + [_ms(prof["variants"][v]["wall_s_per_step"]) for v in names])
    body.append(["kernel tasks per step"] + [f"{prof['variants'][v]['tasks_per_step']:.0f}" for v in names])
    body.append(["constitutive update alone (same points)"] + [
        _ms(prof["constitutive_alone_s_per_step"]) if v != YARDSTICK else "-" for v in names])
    title = (f"Profile: {prof['arch']} {prof['precision']} {prof['particles']:,} particles, "
             f"{prof['steps']} steps, best of {prof.get('rounds', 1)}")
    return title, header, body


def _markdown_table(title: str, header: list[str], body: list[list[str]]) -> list[str]:
    lines = [f"### {title}", "", "| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines.extend("| " + " | ".join(row) + " |" for row in body)
    lines.append("")
    return lines


def profile_markdown(prof: dict[str, Any]) -> str:
    """One :func:`profile_step` result as a markdown table."""
    return "\n".join(_markdown_table(*_profile_table(prof)))


def _seconds(value: float | None) -> str:
    return "-" if value is None else f"{value:.2f}"


def report_tables(result: dict[str, Any]) -> list[tuple[str, list[str], list[list[str]]]]:
    """The result as (title, header, rows) tables, for markdown and rich."""
    tables = []
    if result.get("startup"):
        tables.append(("Start-up: process start to the end of the first step (runout run)",
                       ["scene", "particles", "cold cache s", "warm best s", "warm median s", "cold CPU s",
                        "warm median CPU s", "goal s"],
                       [[r["scene"], f"{r['particles']:,}", f"{r['cold_s']:.2f}", f"{r['warm_best_s']:.2f}",
                         f"{r['warm_median_s']:.2f}", _seconds(r.get("cold_cpu_s")),
                         _seconds(r.get("warm_cpu_median_s")), f"< {r['goal_s']:g}"] for r in result["startup"]]))
    rows = result["throughput"]
    variants = [YARDSTICK, *[s for s in (*SCHEMES, *COMPONENT_VARIANTS) if any(r["variant"] == s for r in rows)]]
    groups = sorted({(r["arch"], r["precision"], r["particles"]) for r in rows},
                    key=lambda g: (g[0], g[1], g[2]))
    header = ["arch", "prec", "particles", "cells"] + [
        f"{v} M/s" + ("" if v == YARDSTICK else " (x yard)") for v in variants] + [
        "affine / apic", "B/particle", "RSS B/particle"]
    body = []
    for arch, prec, n in groups:
        line = [arch, prec, f"{n:,}"]
        first = _find(rows, arch=arch, precision=prec, particles=n)
        line.append("x".join(str(c) for c in first["grid_cells"]) if first else "-")
        affine = None
        for v in variants:
            r = _find(rows, arch=arch, precision=prec, particles=n, variant=v)
            if r is None:
                line.append("-")
                continue
            if v == "apic-affine":
                affine = r
            line.append(_m(r["particle_steps_per_s"]) + ("" if v == YARDSTICK else f" ({_x(r['ratio_to_yardstick'])})"))
        line.append(_x(affine["ratio_to_apic"]) if affine else "-")
        line.append(f"{affine['bytes_per_particle']:.0f}" if affine else "-")
        rss = affine["rss_delta_bytes_per_particle"] if affine else None
        line.append("-" if rss is None else f"{rss:.0f}")
        body.append(line)
    for item in result["not_measured"]:
        body.append([item["arch"], "-", "-", "-"] + [item["reason"]] + ["-"] * (len(header) - 5))
    tables.append(("Throughput (million particle-steps/s, best round; ratios: median of paired rounds)",
                   header, body))

    body = []
    for t in result["targets"]:
        value = t["value"]
        if value is None:
            shown = "-"
        elif "memory" in t["name"]:
            shown = f"{value:.0f} B"
        elif "particle-steps" in t["name"]:
            shown = f"{value:.3g}"
        elif t["goal"].endswith(" s"):  # a time (start-up, the GPU aluminium-bar run), not a ratio
            shown = f"{value:.2f} s"
        else:
            shown = f"{value:.2f}x"
        met = "not measured" if t["met"] is None else ("yes" if t["met"] else "no")
        body.append([t["name"], t["goal"], shown, met, t["where"] + (f"; {t['note']}" if t["note"] else "")])
    tables.append(("Targets", ["target", "goal", "measured", "met", "where / note"], body))

    tables.extend(_profile_table(prof) for prof in result.get("profile", []))

    empty = result.get("empty_domain")
    if empty:
        body = [[v, _ms(e["step_time_s"]), _ms(e["step_time_doubled_s"]), _x(e["ratio"]),
                 f"{e['bytes_per_particle']:.0f} -> {e['bytes_per_particle_doubled']:.0f}"]
                for v, e in empty["variants"].items()]
        tables.append((f"Empty domain: {empty['arch']} {empty['precision']} {empty['particles']:,} particles, "
                       f"box {'x'.join(map(str, next(iter(empty['variants'].values()))['grid_cells']))} -> "
                       f"{'x'.join(map(str, next(iter(empty['variants'].values()))['grid_cells_doubled']))} cells",
                       ["variant", "ms/step", "ms/step, twice as long", "ratio", "B/particle"], body))
    stall = result.get("output_stall")
    if stall:
        body = [["without frames", f"{stall['wall_s_without_frames']:.2f}", str(stall["steps_without_frames"]), "-"],
                ["frames every " + f"{stall['interval_s']:g} s", f"{stall['wall_s_with_frames']:.2f}",
                 str(stall["steps_with_frames"]), str(stall["frames_written"])],
                ["ratio (median of paired rounds)", _x(stall["ratio"]), "", ""],
                ["per frame: copy from the solver + encode (ms)",
                 f"{_ms(stall['copy_s_per_frame'])} + {_ms(stall['encode_s_per_frame'])}", "", ""],
                ["solver thread in write_frame / close (ms, whole run)",
                 f"{_ms(stall['write_frame_s'])} / {_ms(stall['close_s'])}", "", ""],
                ["ratio if nothing overlapped (estimate)", _x(stall["estimated_ratio"]), "", ""]]
        tables.append((f"Output stall: {stall['arch']} {stall['precision']} {stall['particles']:,} particles, "
                       f"{stall['simulated_s']:g} s simulated", ["run", "wall s", "steps", "frames"], body))
    env = result.get("hazard_envelopes")
    if env:
        body = [["engine step", _ms(env["step_time_s"]), ""],
                ["envelope update", _ms(env["update_time_s"]), ""],
                [f"added run time, update every {env['every_steps']} steps (median of batches)",
                 f"{100 * env['fraction']:.2f} %", f"best: {100 * env['fraction_best']:.2f} %"],
                ["the same in CPU seconds of the process", "-" if env.get("fraction_cpu") is None
                 else f"{100 * env['fraction_cpu']:.2f} %", ""]]
        tables.append((f"Hazard envelopes: {env['arch']} {env['precision']} {env['particles']:,} particles, "
                       f"raster {env['raster'][0]}x{env['raster'][1]}", ["what", "ms / %", ""], body))
    full = result.get("gpu_full_run")
    if full:
        tables.append(("GPU aluminium-bar run", ["particles", "steps", "simulated s", "wall s"],
                       [[f"{full['particles']:,}", str(full["steps"]), f"{full['simulated_s']:.3g}",
                         f"{full['wall_s']:.2f}"]]))
    return tables


def markdown_report(result: dict[str, Any]) -> str:
    """The result as markdown: the machine, then one table per measurement."""
    m = result["machine"]
    ram = f"{m['ram_bytes'] / 2**30:.1f} GiB" if m.get("ram_bytes") else "unknown"
    lines = [
        f"Runout benchmark ({'quick' if result.get('quick') else 'full' if result.get('quick') is False else 'custom'}), "
        f"{result['created_at']}, {result.get('wall_s', 0.0):.0f} s",
        "",
        f"Machine: {m['cpu']}, {m['cores']} cores, {ram} RAM; {m['platform']}; Python {m['python']}, "
        f"Taichi {m['taichi']}, numpy {m['numpy']}; GPU: {'yes' if m['gpu_available'] else 'none'}",
        "",
    ]
    load = result.get("load_average")
    if load and load.get("start") and load.get("end"):
        lines += [f"Load average (1, 5, 15 min) at the start {load['start']}, at the end {load['end']} "
                  f"on {m['cores']} cores.", ""]
    for title, header, body in report_tables(result):
        lines.extend(_markdown_table(title, header, body))
    return "\n".join(lines)


def rich_tables(result: dict[str, Any]) -> list[Any]:
    """The result as rich tables (for the command line)."""
    from rich.table import Table

    tables = []
    for title, header, body in report_tables(result):
        table = Table(title=title, title_justify="left")
        for i, name in enumerate(header):
            table.add_column(name, justify="left" if i == 0 else "right")
        for row in body:
            table.add_row(*row)
        tables.append(table)
    return tables
