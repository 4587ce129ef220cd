"""Warnings about inputs that run but cannot give an answer to trust, part of
:func:`projects.checks.project_warnings` (``runout validate`` and ``runout run`` print them, the
workbench lists them):

- a ``numerics.time_step_s`` longer than the stability limit of a material in force in some stage
  (:meth:`solver.config.Material.critical_time_step_s` at rest: ``dx / c_p``, shorter with
  damping): the explicit update goes unstable within its first steps (1.0 s on the tiny column,
  1,300 times its limit, passed ``validate`` and failed at the run's first check);
- a body whose initial speed carries it across the whole domain within one output interval: it
  leaves the grid or strikes its sides before the first frame (at 1e6 m/s every particle was lost
  in the first interval of a run that said "completed"); or one faster than its material's P-wave
  speed (an impact no explicit MPM step resolves);
- a hazard raster (``hazard.cell_size_m``) finer than the particle spacing: most raster columns
  hold no particle at a time and the envelopes come out patchy.
"""

from __future__ import annotations

import math

from projects.schema import DEFAULT_CFL, Project


def plausibility_warnings(project: Project) -> list[str]:
    """The warnings of this module, one line each (naming the key, the value and what to do)."""
    return [*time_step_above_limit(project), *fast_bodies(project), *fine_hazard_raster(project)]


def time_step_above_limit(project: Project) -> list[str]:
    """A ``numerics.time_step_s`` longer than the smallest stability limit of the materials in force
    in the stages (the material changes of each stage counted)."""
    dt = project.numerics.time_step_s
    if dt is None:
        return []
    from projects.build import material_tables, solver_material

    dx = project.domain.cell_size_m
    worst = None  # (limit, material name, stage index)
    for index, table in enumerate(material_tables(project)):
        for name, material in table.items():
            try:
                limit = solver_material(name, material).critical_time_step_s(dx)
            except (ArithmeticError, ValueError):
                continue
            if not 0.0 < limit < float("inf"):
                continue  # a degenerate material (its own problem is reported elsewhere)
            if worst is None or limit < worst[0]:
                worst = (limit, name, index)
    if worst is None or not dt > worst[0] * (1.0 + 1e-9):
        return []
    limit, name, index = worst
    ratio = dt / limit
    times = f"{ratio:,.0f}" if 100 <= ratio < 1e9 else f"{ratio:.3g}"
    return [f"numerics.time_step_s = {dt:g}: {times} times the stability limit {limit:.3g} s of "
            f"{_set_at(project, name, index)} (cell_size_m / P-wave speed, shorter with damping): the run goes "
            f"unstable within its first steps; use time_step_s <= {limit:.3g}, or remove it for cfl = {DEFAULT_CFL:g} "
            "(docs/solver.md, the time step)"]


#: The material keys a stability limit depends on.
_LIMIT_KEYS = ("youngs_modulus_pa", "poisson_ratio", "density_kg_m3", "damping_ratio", "damping_frequency_hz",
               "damping_model")


def _set_at(project: Project, name: str, stage_index: int) -> str:
    """Where material ``name``'s stiffness, density and damping in force in stage ``stage_index``
    are set: the last stage change up to it that sets one of them, else the material itself."""
    path = f"materials.{name}"
    for index, stage in enumerate(project.stages[: stage_index + 1]):
        change = stage.material_changes.get(name)
        if change is not None and any(getattr(change, key, None) is not None for key in _LIMIT_KEYS):
            path = f"stages.{index}.material_changes.{name}"
    return path


def fast_bodies(project: Project) -> list[str]:
    """Bodies whose initial speed crosses the domain within one output interval, or is faster than
    their material's P-wave speed."""
    from projects.build import solver_material

    extent = max(project.domain.size_m)
    interval = project.output.interval_s
    found = []
    for index, body in enumerate(project.bodies):
        vx, vy = body.initial_velocity_m_s
        speed = math.hypot(vx, vy)
        if not speed > 0:
            continue
        where = f"bodies.{index}.initial_velocity_m_s = [{vx:g}, {vy:g}]"
        if speed * interval > extent:
            found.append(f"{where}: at {speed:.3g} m/s the body ({body.name!r}) crosses the whole domain ({extent:g} m) "
                         f"in {extent / speed:.3g} s, less than one output interval ({interval:g} s): it leaves the grid "
                         "or strikes its sides before any frame shows it")
            continue
        material = project.materials.get(body.material)
        if material is None or material.model == "rigid":  # a rigid body moves at its own velocity
            continue
        c_p = solver_material(body.material, material).p_wave_speed_m_s
        if speed > c_p:
            found.append(f"{where}: {speed:.3g} m/s is faster than the P-wave speed of materials.{body.material} "
                         f"({c_p:.3g} m/s): an impact no explicit step resolves; the results are not physical")
    found += _fast_rigid_bodies(project, extent, interval)
    return found


def _fast_rigid_bodies(project: Project, extent: float, interval: float) -> list[str]:
    """Rigid materials driven across the domain within one output interval, or faster than the
    P-wave speed of the material they push (a body's velocity holds all its dynamic stages)."""
    from projects.build import solver_material

    speeds = [solver_material(name, m).p_wave_speed_m_s for name, m in project.materials.items()
              if m.model != "rigid"]
    slowest = min(speeds) if speeds else math.inf
    found = []
    for name, material in project.materials.items():
        if material.model != "rigid" or material.velocity_m_s is None:
            continue
        vx, vy = material.velocity_m_s
        speed = math.hypot(vx, vy)
        where = f"materials.{name}.velocity_m_s = [{vx:g}, {vy:g}]"
        if speed * interval > extent:
            found.append(f"{where}: at {speed:.3g} m/s the rigid body crosses the whole domain ({extent:g} m) in "
                         f"{extent / speed:.3g} s, less than one output interval ({interval:g} s)")
        elif speed > slowest:
            found.append(f"{where}: {speed:.3g} m/s is faster than the slowest P-wave speed of the materials "
                         f"({slowest:.3g} m/s): the body strikes them faster than any explicit step resolves; "
                         "the results are not physical")
    return found


def fine_hazard_raster(project: Project) -> list[str]:
    """A hazard raster finer than the particle spacing (``cell_size_m / per_cell``)."""
    cell = project.hazard.cell_size_m
    spacing = project.domain.cell_size_m / project.particles.per_cell
    if not project.hazard.enabled or cell is None or not cell < spacing * (1.0 - 1e-9):
        return []
    return [f"hazard.cell_size_m = {cell:g}: finer than the particle spacing ({spacing:g} m): most raster columns "
            "hold no particle at a time and the envelopes come out patchy; use at least the spacing (default: the "
            "grid's cell)"]
