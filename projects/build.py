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


def solver_structure(structure: schema.Structure) -> sc.Structure:
    """Convert one ``[[structures]]`` entry (its contact as a side's boundary)."""
    contact = structure.contact
    angle = math.radians(contact.friction_angle_deg or 0.0) if contact.type == "friction" else 0.0
    return sc.Structure(structure.name, tuple(tuple(p) for p in structure.polygon_m),
                        sc.Boundary(kind=contact.type, friction_angle_rad=angle))


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
        structures=tuple(solver_structure(st) for st in project.structures),
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
    seeds = seed_bodies(project)
    if project.structures:  # a structure takes precedence: no material is seeded inside one
        from solver.structures import signed_distance

        keep = np.ones(len(seeds.body_index), bool)
        for structure in project.structures:
            keep &= signed_distance(np.asarray(seeds.positions_m, float), structure.polygon_m) >= 0.0
        seeds = type(seeds)(**{k: np.asarray(v)[keep] for k, v in vars(seeds).items()})
    counts = np.bincount(seeds.body_index, minlength=len(project.bodies))
    empty = [
        Problem(
            f"bodies.{i}.polygon_m",
            None,
            "receives no particles: smaller than the particle spacing "
            f"({project.domain.cell_size_m / project.particles.per_cell:g} m) or covered by later bodies"
            + (" or structures" if project.structures else ""),
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


def estimate(project: Project) -> dict[str, object]:
    """Cheap size estimates of a run, without seeding (for the GUI and the command line).

    The particle count is the bodies' total area times ``(per_cell / cell_size_m)**2``
    (overlaps counted twice; exact for grid-aligned rectangles with lattice seeding). With
    ``cfl`` the time step is ``cfl * dx / c_p`` with the largest p-wave speed of all
    materials of all stages; the solver also counts the particle speed in the critical step,
    so its steps are at least as many as estimated.

    Parameters
    ----------
    project : Project

    Returns
    -------
    dict
        ``particles`` (int), ``grid_cells`` (int), ``grid_shape`` ((int, int)),
        ``time_step_s`` (float, s), ``time_step_source`` ("time_step_s" or "cfl"),
        ``max_p_wave_speed_m_s`` (float), ``simulated_time_s`` (float, s, all stages),
        ``steps`` (int, all stages), ``frames`` (int, about one per ``output.interval_s``).
    """
    project = apply_preset(project)
    dx = project.domain.cell_size_m
    area = sum(polygon_area(np.asarray(b.polygon_m)) for b in project.bodies)
    particles = int(round(area * (project.particles.per_cell / dx) ** 2))
    grid = sc.Grid(origin_m=project.domain.origin_m, size_m=project.domain.size_m, cell_size_m=dx)
    nx, ny = grid.cells
    speeds = [solver_material(n, m).p_wave_speed_m_s for t in material_tables(project) for n, m in t.items()]
    speeds.extend(solver_material(n, m).p_wave_speed_m_s for n, m in project.materials.items())
    c_p = max(speeds)
    numerics = project.numerics
    if numerics.time_step_s is not None:
        dt, source = numerics.time_step_s, "time_step_s"
    else:
        dt, source = (numerics.cfl or schema.DEFAULT_CFL) * dx / c_p, "cfl"
    durations = [stage.duration_s or 0.0 for stage in project.stages]
    steps = sum(math.ceil(d / dt - 1e-9) for d in durations if d > 0.0)
    total = float(sum(durations))
    return {
        "particles": particles,
        "grid_cells": nx * ny,
        "grid_shape": (nx, ny),
        "time_step_s": dt,
        "time_step_source": source,
        "max_p_wave_speed_m_s": c_p,
        "simulated_time_s": total,
        "steps": steps,
        "frames": int(math.floor(total / project.output.interval_s + 1e-9)) + 1,
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
