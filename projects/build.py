"""From a validated project to the solver's input: configuration and particles.

This is where project-file conventions become solver conventions: degrees become radians
(once, here), per-stage ``material_changes`` become complete material tables, defaults of
the file are filled in (gravity-stage damping 0.7, K0 per material), domain sides become
:class:`solver.config.Boundary` constraints, and bodies are seeded into particles by
:mod:`geometry.seeding`. Nothing here imports Taichi.
"""

from __future__ import annotations

import dataclasses
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
    if material.model == "rigid":  # kinematic: no stiffness, no strength (solver/rigid.py)
        return sc.Material(name=name, model="rigid", density_kg_m3=material.density_kg_m3, youngs_modulus_pa=0.0,
                           poisson_ratio=0.0, velocity_m_s=tuple(material.velocity_m_s or (0.0, 0.0)),
                           contact=solver_contact(material.contact or schema.Contact(type="fixed")))
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
        mohr_coulomb_match=(material.mohr_coulomb_match or sc.DEFAULT_MOHR_COULOMB_MATCH) if plastic
        else sc.DEFAULT_MOHR_COULOMB_MATCH,
        damping_ratio=material.damping_ratio or 0.0,
        damping_frequency_hz=material.damping_frequency_hz or 0.0,
        damping_model=material.damping_model or sc.DEFAULT_DAMPING_MODEL,
        saturated_density_kg_m3=material.saturated_density_kg_m3,
        ru=material.ru or 0.0,
        softening=solver_softening(material) if plastic else None,
        inertial=solver_inertial(material) if plastic else None,
    )


def solver_inertial(material: schema.Material) -> sc.InertialFriction | None:
    """A material's mu(I) law in the solver's form (None without ``mu_i_friction_increase``); the
    grains' density defaults to the material's."""
    if material.mu_i_friction_increase is None:
        return None
    return sc.InertialFriction(
        friction_increase=material.mu_i_friction_increase,
        reference_inertial_number=material.mu_i_reference_number,
        grain_diameter_m=material.grain_diameter_m,
        grain_density_kg_m3=material.grain_density_kg_m3 or material.density_kg_m3,
    )


def solver_softening(material: schema.Material) -> sc.Softening | None:
    """A material's strain softening in the solver's units (None without ``softening_law``); a
    residual value not given is the peak one (that parameter does not soften)."""
    if material.softening_law is None:
        return None

    def residual(value: float | None, peak: float | None) -> float:
        return value if value is not None else (peak or 0.0)

    return sc.Softening(
        residual_cohesion_pa=residual(material.residual_cohesion_pa, material.cohesion_pa),
        residual_friction_angle_rad=math.radians(residual(material.residual_friction_angle_deg,
                                                          material.friction_angle_deg)),
        residual_dilatancy_angle_rad=math.radians(residual(material.residual_dilatancy_angle_deg,
                                                           material.dilatancy_angle_deg)),
        residual_strain=material.residual_plastic_strain,
        peak_strain=material.peak_plastic_strain or 0.0,
        law=material.softening_law,
        length_m=material.softening_length_m,
    )


def has_water(project: Project) -> bool:
    """Whether the project has ground water (a [water] table or a material with an r_u)."""
    return project.water is not None or any((m.ru or 0.0) > 0.0 for m in project.materials.values()) or any(
        (c.ru or 0.0) > 0.0 for st in project.stages for c in st.material_changes.values())


def solver_water(project: Project) -> list[sc.Water | None]:
    """The ground water at the start (first entry) and at the end of each stage (one entry per
    stage after it): a stage's ``water`` moves the lines it names, the others stay.

    Parameters
    ----------
    project : Project

    Returns
    -------
    list of solver.config.Water or None
        ``len(project.stages) + 1`` entries; None throughout for a project without [water].
    """
    water = project.water
    if water is None:
        return [None] * (len(project.stages) + 1)
    current = sc.Water(
        phreatic_line_m=tuple(tuple(p) for p in water.phreatic_line_m),
        free_water_line_m=None if water.free_water_line_m is None else tuple(tuple(p) for p in water.free_water_line_m),
        unit_weight_n_m3=water.unit_weight_n_m3,
        inclined_correction=water.inclined_line_correction,
    )
    out = [current]
    for stage in project.stages:
        move = stage.water
        if move is not None:
            free = current.free_water if move.free_water_line_m is None else tuple(tuple(p) for p in move.free_water_line_m)
            line = current.phreatic_line_m if move.phreatic_line_m is None else tuple(tuple(p) for p in move.phreatic_line_m)
            # a free-water line equal to the phreatic line is left implicit (None: it follows it)
            current = dataclasses.replace(current, phreatic_line_m=line,
                                          free_water_line_m=None if free == line else free)
        out.append(current)
    return out


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


def solver_contact(contact: schema.Contact) -> sc.Boundary:
    """A structure's or a rigid body's contact, as a side's boundary."""
    angle = math.radians(contact.friction_angle_deg or 0.0) if contact.type == "friction" else 0.0
    return sc.Boundary(kind=contact.type, friction_angle_rad=angle)


def solver_structure(structure: schema.Structure) -> sc.Structure:
    """Convert one ``[[structures]]`` entry (its contact as a side's boundary)."""
    return sc.Structure(structure.name, tuple(tuple(p) for p in structure.polygon_m), solver_contact(structure.contact))


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
    reduced = False  # after a strength-reduction stage projects.strength sets the material table
    water = solver_water(project)
    from projects.loads import stage_loads

    loads = stage_loads(project)
    for stage, table, stage_water, (surcharges, surcharges_from, seismic) in zip(
            project.stages, material_tables(project), water[1:], loads):
        if stage.type == "strength-reduction":
            reduced = True
            continue  # driven by projects.strength between the solver's stages
        stage_materials = None
        if stage.material_changes and not reduced:
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
                ramp_fraction=stage.ramp_fraction,
                damping=damping,
                k0=stage.k0,
                materials=stage_materials,
                stop_when_kinetic_energy_below=stage.stop_when_kinetic_energy_below,
                stop_when_max_speed_below_m_s=stage.stop_when_max_speed_below_m_s,
                min_duration_s=stage.min_duration_s or 0.0,
                water=stage_water if stage.water is not None else None,
                surcharges=surcharges,
                surcharges_from=surcharges_from,
                seismic=seismic,
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
        volumetric_averaging=numerics.volumetric_averaging,
    )
    output = sc.Output(interval_s=project.output.interval_s, fields=tuple(project.output.fields))
    from projects.hazard import envelope_config

    return sc.SimulationConfig(
        grid=grid,
        materials=materials,
        stages=tuple(stages),
        gravity_m_s2=domain.gravity_m_s2,
        numerics=solver_numerics,
        output=output,
        envelopes=envelope_config(project),
        structures=tuple(solver_structure(st) for st in project.structures),
        water=water[0],
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
        later body, and the structures take precedence over every body (lattice seeding clips
        the bodies at their outlines; Gauss points inside one are dropped by the caller).
    """
    polygons = [np.asarray(body.polygon_m, dtype=np.float64) for body in project.bodies]
    particles = project.particles
    if particles.seeding == "gauss":
        return seed_gauss(polygons, project.domain.cell_size_m, particles.per_cell)
    holes = [np.asarray(structure.polygon_m, dtype=np.float64) for structure in project.structures]
    return seed_lattice(polygons, project.domain.origin_m, project.domain.cell_size_m, particles.per_cell, holes)


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
        When a body receives no particles (it is entirely covered by later bodies or
        structures, or, seeded on the lattice, of almost no area; with Gauss seeding, thinner
        than the particle spacing).
    """
    try:
        seeds = seed_bodies(project)
    except ValueError as err:  # what the size limits did not stop (--force): one line, no traceback
        raise ProjectError([Problem("domain.cell_size_m", project.domain.cell_size_m, f"cannot seed the bodies: {err}")]) from None
    if project.structures and project.particles.seeding == "gauss":
        # a structure takes precedence: no material is seeded inside one (the lattice is clipped
        # at the structures' outlines already, seed_bodies)
        from solver.structures import signed_distance

        keep = np.ones(len(seeds.body_index), bool)
        for structure in project.structures:
            keep &= signed_distance(np.asarray(seeds.positions_m, float), structure.polygon_m) >= 0.0
        seeds = type(seeds)(**{k: None if v is None else np.asarray(v)[keep] for k, v in vars(seeds).items()})
    counts = np.bincount(seeds.body_index, minlength=len(project.bodies))
    empty = [
        Problem(
            f"bodies.{i}.polygon_m",
            None,
            "receives no particles: covered by later bodies" + (" or structures" if project.structures else "")
            + " or too small for the particle spacing "
            f"({project.domain.cell_size_m / project.particles.per_cell:g} m)",
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
        bounds_m=None if seeds.bounds_m is None else np.asarray(seeds.bounds_m, dtype=np.float64),
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

    def seeded(self) -> ResolvedRun:
        """This run with its particles seeded (itself when they are)."""
        if self.particles is not None:
            return self
        particles, body_index = _seed_particles(self.project, self.config)
        return dataclasses.replace(self, particles=particles, particle_body=body_index)

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
            volumes = np.asarray(self.particles.volumes_m2, dtype=float)
            # the median, without np.median (its NaN check imports numpy.ma: 10-20 ms of a run's start)
            half = len(volumes) // 2
            part = np.partition(volumes, [half - 1, half] if len(volumes) % 2 == 0 else [half])
            median = part[half] if len(volumes) % 2 else 0.5 * (part[half - 1] + part[half])
            return float(np.sqrt(median))
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
            "rigid_materials": [m.name for m in config.materials if m.rigid],
            "bodies": list(self.body_names),
            "structures": [{"name": st.name, "polygon_m": [list(p) for p in st.polygon_m]}
                           for st in config.structures],
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
    resolved = ResolvedRun(project=project, config=config, particles=None, particle_body=None,
                           estimate=estimate(project))
    return resolved.seeded() if seed else resolved


#: Counts beyond this are reported as this (an estimate of 1e300 cells stays a number).
MAX_COUNT = 2**62
#: Engine state per particle: floats (x, x0, v: 2 each; C, stress: 4 each; mass, density,
#: plastic strain) and bytes (material id int32; active, yielded, band int8).
ENGINE_FLOATS_PER_PARTICLE = 17
#: and the damping stress (3 floats) where a material has damping
VISCOUS_FLOATS_PER_PARTICLE = 3
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
FILE_BYTES_PER_FIELD = {"displacement": 12, "velocity": 12, "stress": 16, "plastic_strain": 4, "material": 4,
                        "pore_pressure": 4}
FILE_BYTES_ALWAYS = 12 + 1 + 4 + 16
#: Bytes of one row of series.csv and of the fixed files (pvd entry per frame, summary, project).
SERIES_BYTES_PER_FRAME = 400
FIXED_FILE_BYTES = 1 << 20
#: Bytes per cell of the hazard raster (solver.envelopes, projects.hazard): four fields on the device
#: (largest speed, energy and pressure, first arrival), the host's float64 copies of them in a
#: snapshot, and the seven float32 arrays of hazard.vti with their compressed copies (memory); the
#: seven arrays uncompressed (disk).
HAZARD_FLOATS_PER_CELL = 4
HAZARD_HOST_BYTES_PER_CELL = 4 * 8 + 2 * 7 * 4
HAZARD_FILE_BYTES_PER_CELL = 7 * 4
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


def _typical_trials(project: Project) -> int:
    """How many trials a strength-reduction search usually takes (projects/strength.py): the first
    and one bracketing step, then bisection of a bracket of ``F bracket_step`` to the tolerance
    (F: the first trial where given, else 1: Bishop's factor is not worked out for an estimate)."""
    stage = next(s for s in project.stages if s.type == "strength-reduction")
    first = stage.first_trial if isinstance(stage.first_trial, (int, float)) else 1.0
    step = stage.bracket_step or schema.SR_DEFAULT_BRACKET_STEP
    tolerance = stage.tolerance or schema.SR_DEFAULT_TOLERANCE
    bisections = max(0, math.ceil(math.log2(max(first * step / tolerance, 1.0))))
    return min(2 + bisections, stage.max_trials or schema.SR_DEFAULT_MAX_TRIALS)


def estimate(project: Project) -> dict[str, object]:
    """Size estimates of a run without seeding or allocating (:func:`resolve` gives it).

    A pure function of the project as it runs (preset applied: :func:`resolve` does that). The particle count is the bodies'
    total area times ``(per_cell / cell_size_m)**2`` (overlaps counted twice; exact for
    grid-aligned rectangles with lattice seeding). With ``cfl`` the time step is ``cfl`` times the
    smallest stability limit of all materials of all stages (``dx / c_p``, less for a damped
    material: :meth:`solver.config.Material.critical_time_step_s`); the solver
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
        ``steps`` (int, all stages), ``may_stop_early`` (bool, a stage may end before its duration),
        ``typical_trials`` and ``max_trials`` (the search's usual and largest number of trials, 0
        without one), ``trial_steps`` (int, one strength-reduction trial at most; 0 without one; the search's trials
        come on top of ``steps``; :mod:`projects.cost` turns both into wall time),
        ``frames`` (int, about one per ``output.interval_s``),
        ``bytes_per_particle`` and ``bytes_per_node`` (int, memory), ``memory_bytes`` (int),
        ``frame_bytes`` (int, one frame file), ``disk_bytes`` (int, the results folder),
        ``hazard_cells`` (int, cells of the hazard raster; 0 without hazard output, counted in
        memory and disk), ``hazard_memory_bytes`` and ``hazard_disk_bytes`` (int, the raster's part
        of ``memory_bytes`` and ``disk_bytes``), ``cell_size_m``, ``output_interval_s``, ``hazard_cell_size_m`` (float,
        the inputs the limits name).
    """
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
    materials = [solver_material(n, m) for t in material_tables(project) for n, m in t.items()]
    materials.extend(solver_material(n, m) for n, m in project.materials.items())
    c_p = max(m.p_wave_speed_m_s for m in materials)
    numerics = project.numerics
    if numerics.time_step_s is not None:
        dt, source = numerics.time_step_s, "time_step_s"
    else:  # the solver's own limit (solver.config.Material.critical_time_step_s)
        dt, source = numerics.cfl * min(m.critical_time_step_s(dx) for m in materials), "cfl"
    # how many times shorter material damping makes the stability limit, and whose damping
    undamped_limit = min(_ratio(dx, m.p_wave_speed_m_s) for m in materials)
    damped_limit, damped = min(((m.critical_time_step_s(dx), m) for m in materials), key=lambda x: x[0])
    shrink = _ratio(undamped_limit, damped_limit) if damped.damping_beta_s > 0.0 else 1.0
    durations = [stage.duration_s or 0.0 for stage in project.stages]
    steps = _count(sum(_ratio(d, dt) for d in durations if d > 0.0))
    # what the time above may not hold: a stage that may stop early (at most that), and the trials
    # of a strength reduction (each at most its trial duration; their number is the search's)
    may_stop_early = any(stage.stop_when_kinetic_energy_below is not None
                         or getattr(stage, "stop_when_max_speed_below_m_s", None) is not None
                         for stage in project.stages)
    trial_s = next(((stage.trial_duration_s or next((s.duration_s or 0.0 for s in project.stages
                                                     if s.type == "gravity"), 0.0))
                    for stage in project.stages if stage.type == "strength-reduction"), 0.0)
    trial_steps = _count(_ratio(trial_s, dt)) if trial_s > 0.0 else 0
    trials = _typical_trials(project) if trial_steps else 0
    total = float(sum(durations))
    intervals = _ratio(total, project.output.interval_s)
    frames = _count(math.floor(intervals + 1e-9) + 1.0 if math.isfinite(intervals) else math.inf)

    float_bytes = 8 if numerics.precision == "f64" else 4
    per_particle = (
        (ENGINE_FLOATS_PER_PARTICLE + (VISCOUS_FLOATS_PER_PARTICLE if any(m.damping_beta_s > 0.0 for m in materials)
                                       else 0)) * float_bytes
        + ENGINE_BYTES_PER_PARTICLE + HOST_BYTES_PER_PARTICLE
        + FRAMES_IN_MEMORY * (FRAME_FLOATS_PER_PARTICLE * float_bytes + FRAME_BYTES_PER_PARTICLE)
    )
    per_node = FLOATS_PER_NODE * float_bytes
    memory = _count(float(particles) * per_particle + float(nodes) * per_node
                    + min(float(candidates) * 48.0, SEEDING_BLOCK_BYTES))
    # the hazard raster over the grid's cells (solver.envelopes), at hazard.cell_size_m (default dx)
    hazard_dx = project.hazard.cell_size_m if project.hazard.cell_size_m is not None else dx
    if project.hazard.enabled:
        hazard_cells = _count(float(_count(_ratio(nx * dx, hazard_dx))) * float(_count(_ratio(ny * dx, hazard_dx))))
    else:
        hazard_cells = 0
    hazard_bytes = _count(float(hazard_cells) * (HAZARD_FLOATS_PER_CELL * float_bytes + HAZARD_HOST_BYTES_PER_CELL))
    memory = _count(float(memory) + float(hazard_bytes))
    file_per_particle = FILE_BYTES_ALWAYS + sum(
        FILE_BYTES_PER_FIELD.get(name, 0) for name in project.output.fields
        if name not in sc.WATER_FIELDS or has_water(project)
    )
    frame_bytes = _count(float(particles) * file_per_particle + 2048.0)
    hazard_disk = _count(float(hazard_cells) * HAZARD_FILE_BYTES_PER_CELL)
    disk = _count(float(frames) * (frame_bytes + SERIES_BYTES_PER_FRAME) + FIXED_FILE_BYTES + float(hazard_disk))
    return {
        "particles": particles,
        "grid_cells": cells,
        "grid_shape": (nx, ny),
        "grid_nodes": nodes,
        "seeding_candidates": candidates,
        "time_step_s": dt,
        "time_step_source": source,
        "time_step_shrink_by_damping": shrink,
        "damping_key": f"{damping_table(project, damped.name)}.damping_ratio" if shrink > 1.0 else None,
        "max_p_wave_speed_m_s": c_p,
        "simulated_time_s": total,
        "steps": steps,
        "may_stop_early": may_stop_early,
        "trial_steps": trial_steps,
        "typical_trials": trials,
        "max_trials": next((stage.max_trials or schema.SR_DEFAULT_MAX_TRIALS for stage in project.stages
                            if stage.type == "strength-reduction"), 0),
        "frames": frames,
        "bytes_per_particle": per_particle,
        "bytes_per_node": per_node,
        "memory_bytes": memory,
        "frame_bytes": frame_bytes,
        "disk_bytes": disk,
        "cell_size_m": dx,
        "output_interval_s": project.output.interval_s,
        "hazard_cells": hazard_cells,
        "hazard_memory_bytes": hazard_bytes,
        "hazard_disk_bytes": hazard_disk,
        "hazard_cell_size_m": hazard_dx,
    }


def damping_table(project: Project, name: str, stage_index: int | None = None) -> str:
    """Where material ``name``'s damping in force in stage ``stage_index`` (default: the last) is
    set: the last stage change up to it that sets a damping key, else the material itself."""
    path = f"materials.{name}"
    last = len(project.stages) if stage_index is None else stage_index + 1
    for index, stage in enumerate(project.stages[:last]):
        change = stage.material_changes.get(name)
        if change is not None and any(value is not None for value in (
                change.damping_ratio, change.damping_frequency_hz, change.damping_model)):
            path = f"stages.{index}.material_changes.{name}"
    return path


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
    damping = (f", {e['time_step_shrink_by_damping']:.2g}x shorter for {e['damping_key']}"
               if e["time_step_source"] == "cfl" and e["damping_key"] else "")
    return (
        f"about {e['particles']} particles, {e['grid_shape'][0]} x {e['grid_shape'][1]} cells, "
        f"dt {e['time_step_s']:.3g} s ({e['time_step_source']}{damping}), {e['steps']} steps "
        f"over {e['simulated_time_s']:g} s"
    )
