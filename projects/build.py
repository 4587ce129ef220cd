"""From a validated project to the solver's input: configuration and particles.

This is where project-file conventions become solver conventions: degrees become radians
(once, here), per-stage ``material_changes`` become complete material tables, defaults of
the file are filled in (gravity-stage damping 0.7, K0 per material), domain sides become
:class:`solver.config.Boundary` constraints, and bodies are seeded into particles by
:mod:`geometry.seeding`. Nothing here imports Taichi.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from geometry.polygons import polygon_area
from geometry.seeding import Seeds, seed_gauss, seed_lattice
from projects import schema
from projects.presets import apply_preset
from projects.schema import DEFAULT_GRAVITY_DAMPING, Problem, Project, ProjectError
from solver import config as sc

logger = logging.getLogger(__name__)


@dataclass(frozen=True, eq=False)
class BuiltRun:
    """Everything the solver needs for one run, plus names for reporting.

    Attributes
    ----------
    config : solver.config.SimulationConfig
        Grid, materials (file order), stages, gravity, numerics, output; SI units, radians.
    particles : solver.config.Particles
        Initial positions (N, 2) m, volumes (N,) m2, material ids (N,) and velocities (N, 2) m/s.
    material_names : tuple of str
        Name of each material id.
    body_names : tuple of str
        Name of each body, in file order.
    particle_body : numpy.ndarray, shape (N,), int64
        Index into ``body_names`` of each particle.
    """

    config: sc.SimulationConfig
    particles: sc.Particles
    material_names: tuple[str, ...]
    body_names: tuple[str, ...]
    particle_body: np.ndarray


def solver_material(name: str, material: schema.Material) -> sc.Material:
    """Convert one material of the file (degrees) to the solver's (radians).

    Parameters
    ----------
    name : str
    material : projects.schema.Material

    Returns
    -------
    solver.config.Material
    """
    plastic = material.model == "drucker-prager"
    return sc.Material(
        name=name,
        model=material.model,
        density_kg_m3=material.density_kg_m3,
        youngs_modulus_pa=material.youngs_modulus_pa,
        poisson_ratio=material.poisson_ratio,
        cohesion_pa=(material.cohesion_pa or 0.0) if plastic else 0.0,
        friction_angle_rad=math.radians(material.friction_angle_deg or 0.0) if plastic else 0.0,
        dilatancy_angle_rad=math.radians(material.dilatancy_angle_deg or 0.0) if plastic else 0.0,
        tensile_strength_pa=material.tensile_strength_pa if plastic else None,
    )


def solver_boundary(boundary: schema.Boundary) -> sc.Boundary:
    """Convert one side of the domain.

    Parameters
    ----------
    boundary : projects.schema.Boundary

    Returns
    -------
    solver.config.Boundary
    """
    angle = math.radians(boundary.friction_angle_deg or 0.0) if boundary.type == "friction" else 0.0
    return sc.Boundary(kind=boundary.type, friction_angle_rad=angle)


def material_tables(project: Project) -> list[dict[str, schema.Material]]:
    """The material table in force during each stage (changes persist into later stages).

    Parameters
    ----------
    project : Project

    Returns
    -------
    list of dict
        One table per stage, materials in file order.
    """
    current = dict(project.materials)
    tables = []
    for stage in project.stages:
        for name, change in stage.material_changes.items():
            updates = change.model_dump(exclude_none=True)
            current[name] = current[name].model_copy(update=updates)
        tables.append(dict(current))
    return tables


def solver_config(project: Project, *, arch_override: str | None = None) -> sc.SimulationConfig:
    """The solver configuration of a project (no particles).

    Parameters
    ----------
    project : Project
    arch_override : {"auto", "cpu", "gpu"}, optional
        Replaces ``numerics.arch`` (the command line's ``--arch``).

    Returns
    -------
    solver.config.SimulationConfig
    """
    names = project.material_names
    materials = tuple(solver_material(n, m) for n, m in project.materials.items())
    domain = project.domain
    sides = {side: solver_boundary(getattr(domain.boundaries, side)) for side in schema.SIDES}
    grid = sc.Grid(origin_m=domain.origin_m, size_m=domain.size_m, cell_size_m=domain.cell_size_m, **sides)

    stages = []
    for stage, table in zip(project.stages, material_tables(project)):
        stage_materials = None
        if stage.material_changes:
            stage_materials = tuple(solver_material(n, table[n]) for n in names)
        if stage.damping is not None:
            damping = stage.damping.coefficient
        else:
            damping = DEFAULT_GRAVITY_DAMPING if stage.type == "gravity" else 0.0
        stages.append(
            sc.Stage(
                name=stage.label,
                kind=stage.type,
                duration_s=stage.duration_s or 0.0,
                damping=damping,
                k0=stage.k0,
                materials=stage_materials,
                stop_when_kinetic_energy_below=stage.stop_when_kinetic_energy_below,
                min_duration_s=stage.min_duration_s or 0.0,
            )
        )

    numerics = project.numerics
    arch = arch_override if arch_override is not None else numerics.arch
    if arch not in schema.ARCHS:
        allowed = ", ".join(f'"{a}"' for a in schema.ARCHS)
        raise ProjectError([Problem("numerics.arch", arch, f"must be one of {allowed}")])
    solver_numerics = sc.Numerics(
        scheme=numerics.scheme,
        time_step_s=numerics.time_step_s,
        cfl=None if numerics.time_step_s is not None else numerics.cfl,
        precision=numerics.precision,
        arch=arch,
    )
    output = sc.Output(interval_s=project.output.interval_s, fields=tuple(project.output.fields))
    return sc.SimulationConfig(
        grid=grid,
        materials=materials,
        stages=tuple(stages),
        gravity_m_s2=domain.gravity_m_s2,
        numerics=solver_numerics,
        output=output,
    )


def seed_bodies(project: Project) -> Seeds:
    """Seed the project's bodies with its ``[particles]`` settings.

    Parameters
    ----------
    project : Project

    Returns
    -------
    geometry.seeding.Seeds
        Positions (N, 2) m, volumes (N,) m2 and body index (N,); overlaps belong to the
        later body.
    """
    polygons = [np.asarray(body.polygon_m, dtype=np.float64) for body in project.bodies]
    particles = project.particles
    if particles.seeding == "gauss":
        return seed_gauss(polygons, project.domain.cell_size_m, particles.per_cell)
    return seed_lattice(polygons, project.domain.origin_m, project.domain.cell_size_m, particles.per_cell)


def build_simulation(project: Project, *, arch_override: str | None = None) -> BuiltRun:
    """Build the solver input of a project: configuration and seeded particles.

    Parameters
    ----------
    project : Project
    arch_override : {"auto", "cpu", "gpu"}, optional
        Replaces ``numerics.arch``.

    Returns
    -------
    BuiltRun

    Raises
    ------
    ProjectError
        When a body receives no particles (it is thinner than the particle spacing or
        entirely covered by later bodies).
    """
    project = apply_preset(project)
    config = solver_config(project, arch_override=arch_override)
    try:
        seeds = seed_bodies(project)
    except ValueError as err:  # what the size limits did not stop (--force): one line, no traceback
        raise ProjectError([Problem("domain.cell_size_m", project.domain.cell_size_m, f"cannot seed the bodies: {err}")]) from None
    counts = np.bincount(seeds.body_index, minlength=len(project.bodies))
    empty = [
        Problem(
            f"bodies.{i}.polygon_m",
            None,
            "receives no particles: smaller than the particle spacing "
            f"({project.domain.cell_size_m / project.particles.per_cell:g} m) or covered by later bodies",
        )
        for i, count in enumerate(counts)
        if count == 0
    ]
    if empty:
        raise ProjectError(empty)

    names = project.material_names
    body_material = np.array([names.index(body.material) for body in project.bodies], dtype=np.int64)
    body_velocity = np.array([body.initial_velocity_m_s for body in project.bodies], dtype=np.float64)
    body_index = np.asarray(seeds.body_index, dtype=np.int64)
    particles = sc.Particles(
        positions_m=np.asarray(seeds.positions_m, dtype=np.float64),
        volumes_m2=np.asarray(seeds.volumes_m2, dtype=np.float64),
        material_ids=body_material[body_index],
        velocities_m_s=body_velocity[body_index],
    )
    logger.info(
        "built %d particles in %d bodies on a %d x %d grid",
        len(particles), len(project.bodies), *config.grid.cells,
    )
    return BuiltRun(
        config=config,
        particles=particles,
        material_names=names,
        body_names=tuple(body.name for body in project.bodies),
        particle_body=body_index,
    )


#: Counts beyond this are reported as this (an estimate of 1e300 cells stays a number).
MAX_COUNT = 2**62
#: Engine state per particle: floats (x, x0, v: 2 each; C, stress: 4 each; mass, density,
#: plastic strain) and bytes (material id int32; active, yielded, band int8).
ENGINE_FLOATS_PER_PARTICLE = 17
ENGINE_BYTES_PER_PARTICLE = 7
#: Host copies per particle: the built particles (float64 positions, volumes, velocities,
#: int64 material and body ids), bytes.
HOST_BYTES_PER_PARTICLE = 56
#: Frames in memory at once: the writer's queue (3), the one being encoded and its encoding.
FRAMES_IN_MEMORY = 5
#: Floats and bytes per particle of one frame in memory (positions, displacement, velocity:
#: 2 each; stress 4; plastic strain 1 / material id 4, active 1, float64 world positions 16).
FRAME_FLOATS_PER_PARTICLE = 11
FRAME_BYTES_PER_PARTICLE = 21
#: Grid fields per node (mass; momentum, force, old velocity: 2 each) and ghost layers.
FLOATS_PER_NODE = 7
GRID_PAD = 2
#: Bytes per particle of a frame file, uncompressed, for each output field, and what every
#: frame holds (points 12 - 24 far from the origin -, active 1, particle id 4, vertex cell 16).
FILE_BYTES_PER_FIELD = {"displacement": 12, "velocity": 12, "stress": 16, "plastic_strain": 4, "material": 4}
FILE_BYTES_ALWAYS = 12 + 1 + 4 + 16
#: Bytes of one row of series.csv and of the fixed files (pvd entry per frame, summary, project).
SERIES_BYTES_PER_FRAME = 400
FIXED_FILE_BYTES = 1 << 20
#: Bytes per seeding candidate: lattice seeding tests sub-cell centres of the bodies' bounding
#: box in blocks (positions, owners and masks of one block).
SEEDING_BLOCK_BYTES = 2_000_000 * 48


def _count(value: float) -> int:
    """A non-negative count from a float estimate; inf and NaN become :data:`MAX_COUNT`."""
    if not math.isfinite(value) or value >= MAX_COUNT:
        return MAX_COUNT
    return max(0, int(math.ceil(value - 1e-9)))


def _ratio(numerator: float, denominator: float) -> float:
    """``numerator / denominator`` without ZeroDivision or OverflowError (inf instead)."""
    try:
        value = numerator / denominator
    except (ZeroDivisionError, OverflowError):
        return math.inf
    return value if math.isfinite(value) else math.inf


def estimate(project: Project) -> dict[str, object]:
    """Size estimates of a run without seeding or allocating (GUI, command line, limits).

    A pure function of the project (its preset applied). The particle count is the bodies'
    total area times ``(per_cell / cell_size_m)**2`` (overlaps counted twice; exact for
    grid-aligned rectangles with lattice seeding). With ``cfl`` the time step is
    ``cfl * dx / c_p`` with the largest p-wave speed of all materials of all stages; the solver
    also counts the particle speed in the critical step, so its steps are at least as many as
    estimated. Memory counts the engine's particle and grid fields, the host copies of the
    particles and the frames in flight; disk counts the frame files uncompressed (zlib saves
    some of it) plus ``series.csv``. Counts too large for a number are :data:`MAX_COUNT`.

    Parameters
    ----------
    project : Project

    Returns
    -------
    dict
        ``particles`` (int), ``grid_cells`` (int), ``grid_shape`` ((int, int)),
        ``grid_nodes`` (int, with ghost layers), ``seeding_candidates`` (int, lattice points
        tested), ``time_step_s`` (float, s), ``time_step_source`` ("time_step_s" or "cfl"),
        ``max_p_wave_speed_m_s`` (float), ``simulated_time_s`` (float, s, all stages),
        ``steps`` (int, all stages), ``frames`` (int, about one per ``output.interval_s``),
        ``bytes_per_particle`` and ``bytes_per_node`` (int, memory), ``memory_bytes`` (int),
        ``frame_bytes`` (int, one frame file), ``disk_bytes`` (int, the results folder),
        ``cell_size_m``, ``output_interval_s`` (float, the inputs the limits name).
    """
    project = apply_preset(project)
    dx = project.domain.cell_size_m
    per_cell = project.particles.per_cell
    polygons = [np.asarray(b.polygon_m, dtype=np.float64) for b in project.bodies]
    area = sum(polygon_area(p) for p in polygons)
    linear = _ratio(per_cell, dx)
    density = linear * linear  # (per_cell / dx)**2 without OverflowError
    particles = _count(area * density if math.isfinite(density) else math.inf)
    lo = np.min([p.min(axis=0) for p in polygons], axis=0)
    hi = np.max([p.max(axis=0) for p in polygons], axis=0)
    box = float(np.prod(hi - lo + 2.0 * dx / per_cell))
    candidates = _count(box * density if math.isfinite(density) else math.inf)
    nx = _count(_ratio(project.domain.size_m[0], dx))
    ny = _count(_ratio(project.domain.size_m[1], dx))
    nx, ny = max(1, nx), max(1, ny)
    cells = _count(float(nx) * float(ny))
    nodes = _count(float(nx + 1 + 2 * GRID_PAD) * float(ny + 1 + 2 * GRID_PAD))
    speeds = [solver_material(n, m).p_wave_speed_m_s for t in material_tables(project) for n, m in t.items()]
    speeds.extend(solver_material(n, m).p_wave_speed_m_s for n, m in project.materials.items())
    c_p = max(speeds)
    numerics = project.numerics
    if numerics.time_step_s is not None:
        dt, source = numerics.time_step_s, "time_step_s"
    else:
        dt, source = (numerics.cfl or schema.DEFAULT_CFL) * dx / c_p, "cfl"
    durations = [stage.duration_s or 0.0 for stage in project.stages]
    steps = _count(sum(_ratio(d, dt) for d in durations if d > 0.0))
    total = float(sum(durations))
    intervals = _ratio(total, project.output.interval_s)
    frames = _count(math.floor(intervals + 1e-9) + 1.0 if math.isfinite(intervals) else math.inf)

    float_bytes = 8 if numerics.precision == "f64" else 4
    per_particle = (
        ENGINE_FLOATS_PER_PARTICLE * float_bytes + ENGINE_BYTES_PER_PARTICLE + HOST_BYTES_PER_PARTICLE
        + FRAMES_IN_MEMORY * (FRAME_FLOATS_PER_PARTICLE * float_bytes + FRAME_BYTES_PER_PARTICLE)
    )
    per_node = FLOATS_PER_NODE * float_bytes
    memory = _count(float(particles) * per_particle + float(nodes) * per_node
                    + min(float(candidates) * 48.0, SEEDING_BLOCK_BYTES))
    file_per_particle = FILE_BYTES_ALWAYS + sum(
        FILE_BYTES_PER_FIELD.get(name, 0) for name in project.output.fields
    )
    frame_bytes = _count(float(particles) * file_per_particle + 2048.0)
    disk = _count(float(frames) * (frame_bytes + SERIES_BYTES_PER_FRAME) + FIXED_FILE_BYTES)
    return {
        "particles": particles,
        "grid_cells": cells,
        "grid_shape": (nx, ny),
        "grid_nodes": nodes,
        "seeding_candidates": candidates,
        "time_step_s": dt,
        "time_step_source": source,
        "max_p_wave_speed_m_s": c_p,
        "simulated_time_s": total,
        "steps": steps,
        "frames": frames,
        "bytes_per_particle": per_particle,
        "bytes_per_node": per_node,
        "memory_bytes": memory,
        "frame_bytes": frame_bytes,
        "disk_bytes": disk,
        "cell_size_m": dx,
        "output_interval_s": project.output.interval_s,
    }


def describe(project: Project) -> str:
    """One line summarising :func:`estimate` (for logs and the command line).

    Parameters
    ----------
    project : Project

    Returns
    -------
    str
    """
    e = estimate(project)
    return (
        f"about {e['particles']} particles, {e['grid_shape'][0]} x {e['grid_shape'][1]} cells, "
        f"dt {e['time_step_s']:.3g} s ({e['time_step_source']}), {e['steps']} steps "
        f"over {e['simulated_time_s']:g} s"
    )
