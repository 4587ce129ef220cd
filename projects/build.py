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
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from geometry.polygons import polygon_area
from geometry.seeding import Seeds, seed_gauss, seed_lattice
from projects import schema
from projects.presets import apply_preset
from projects.schema import DEFAULT_GRAVITY_DAMPING, Problem, Project, ProjectError
from solver import config as sc

logger = logging.getLogger(__name__)


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
        guard=numerics.advanced.guard,
        speed_bound_factor=numerics.advanced.speed_bound_factor,
        scatter=numerics.advanced.scatter,
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


def _seed_particles(project: Project, config: sc.SimulationConfig) -> tuple[sc.Particles, np.ndarray]:
    """Seed the bodies of a (preset-applied) project into the solver's particles.

    Returns
    -------
    particles : solver.config.Particles
    body_index : numpy.ndarray, shape (N,), int64
        The body of each particle.

    Raises
    ------
    ProjectError
        When a body receives no particles (it is thinner than the particle spacing or
        entirely covered by later bodies).
    """
    seeds = seed_bodies(project)
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
    logger.info("seeded %d particles in %d bodies on a %d x %d grid",
                len(particles), len(project.bodies), *config.grid.cells)
    return particles, body_index


@dataclass(frozen=True, eq=False)
class ResolvedRun:
    """Everything one run is: the one place where a project, its overrides and its preset become
    the settings, particles and numbers that run (docs/DESIGN.md, "One resolved run").

    Attributes
    ----------
    project : projects.schema.Project
        The project as it runs: overrides applied and the preset's values filled in (what a
        results folder records as ``project.toml``).
    config : solver.config.SimulationConfig
        Grid, materials (file order), stages, gravity, numerics, output; SI units, radians.
    particles : solver.config.Particles or None
        Initial positions (N, 2) m, volumes (N,) m2, material ids (N,) and velocities (N, 2) m/s;
        None when resolved with ``seed=False``.
    particle_body : numpy.ndarray, shape (N,), int64, or None
        Index into ``body_names`` of each particle.
    estimate : dict
        :func:`estimate` of the project (size and cost before seeding).
    """

    project: Project
    config: sc.SimulationConfig
    particles: sc.Particles | None
    particle_body: np.ndarray | None
    estimate: dict

    @property
    def material_names(self) -> tuple[str, ...]:
        return self.project.material_names

    @property
    def body_names(self) -> tuple[str, ...]:
        return tuple(body.name for body in self.project.bodies)

    @property
    def particle_count(self) -> int:
        """Seeded particles, or the estimate's count when not seeded."""
        return len(self.particles) if self.particles is not None else int(self.estimate["particles"])

    @property
    def spacing_m(self) -> float:
        """Side of the square one particle stands for (m): what views size points with."""
        if self.particles is not None and len(self.particles):
            return float(np.sqrt(np.median(np.asarray(self.particles.volumes_m2, dtype=float))))
        return self.project.domain.cell_size_m / self.project.particles.per_cell

    @property
    def box_m(self) -> tuple[float, float, float, float]:
        """The grid box ``(x0, y0, x1, y1)`` in metres (whole cells; may exceed ``domain.size_m``)."""
        grid = self.config.grid
        x0, y0 = (float(v) for v in grid.origin_m)
        nx, ny = grid.cells
        return (x0, y0, x0 + nx * grid.cell_size_m, y0 + ny * grid.cell_size_m)

    @property
    def checkpoint_interval_s(self) -> float:
        """Simulated seconds between checkpoints (``output.checkpoint_interval_s`` or its default)."""
        output = self.project.output
        if output.checkpoint_interval_s is not None:
            return output.checkpoint_interval_s
        return schema.CHECKPOINT_EVERY_OUTPUTS * output.interval_s

    def meta(self) -> dict[str, object]:
        """Summary entries known before the run starts (``summary.json``)."""
        x0, y0, x1, y1 = self.box_m
        config = self.config
        meta: dict[str, object] = {
            "title": self.project.runout.title,
            "scheme": config.numerics.scheme,
            "precision": config.numerics.precision,
            "particles": self.particle_count,
            "total_time_s": float(sum(st.duration_s for st in config.stages if st.kind != "k0")),
            "stages": [stage.name for stage in config.stages],
            "materials": list(self.material_names),
            "bodies": list(self.body_names),
            "domain": {"origin_m": [x0, y0], "size_m": [x1 - x0, y1 - y0], "cell_size_m": config.grid.cell_size_m},
            "particle_spacing_m": self.spacing_m,
            "output_interval_s": config.output.interval_s,
        }
        if self.project.numerics.preset is not None:
            meta["preset"] = self.project.numerics.preset
        return meta


def resolve(project: Project, overrides: Sequence[str] = (), *, arch: str | None = None,
            seed: bool = True) -> ResolvedRun:
    """Resolve a project into the one run it stands for.

    Overrides are applied, then the preset (``numerics.preset``), once; everything a run, a
    preview, an estimate or a study needs is derived from the result and from nothing else.

    Parameters
    ----------
    project : Project
        A validated project.
    overrides : sequence of str
        ``KEY=VALUE`` overrides (the command line's ``--set``), applied before the preset.
    arch : {"auto", "cpu", "gpu"}, optional
        Replaces ``numerics.arch`` (the command line's ``--arch``).
    seed : bool
        Seed the particles (False: only the configuration and the estimate, for live previews
        of the cost while a project is edited).

    Returns
    -------
    ResolvedRun

    Raises
    ------
    ProjectError
        Invalid overrides, an unknown preset, a body that receives no particles.
    """
    if overrides:
        from projects.document import apply_overrides

        project = apply_overrides(project, overrides)
    project = apply_preset(project)
    config = solver_config(project, arch_override=arch)
    particles, body_index = _seed_particles(project, config) if seed else (None, None)
    return ResolvedRun(project=project, config=config, particles=particles, particle_body=body_index,
                       estimate=estimate(project))


def estimate(project: Project) -> dict[str, object]:
    """Cheap size estimates of a run, without seeding (:func:`resolve` gives it for a project).

    ``project`` is the project as it runs (preset applied: :func:`resolve` does that).

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
        dt, source = numerics.cfl * dx / c_p, "cfl"
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
    e = resolve(project, seed=False).estimate
    return (
        f"about {e['particles']} particles, {e['grid_shape'][0]} x {e['grid_shape'][1]} cells, "
        f"dt {e['time_step_s']:.3g} s ({e['time_step_source']}), {e['steps']} steps "
        f"over {e['simulated_time_s']:g} s"
    )
