"""Placing an imported section in a project so that it stands on its supports.

:func:`place_section` is what the workbench's import does to the project's data (one undo step):

- the layers become bodies (one: the chosen material; several: each layer a material of its own,
  the one of its name where the project has it, else a copy of the chosen one under the layer's
  name, for the engineer to fill in);
- the grid is fitted to the bodies (:func:`geometry.templates.fit_domain`): the base under the
  section, its ends on the side walls (the right end moved onto the wall by less than half a cell);
- a k0 stage under sloping ground becomes gravity loading (:func:`gravity_for_slopes`: K0 is no
  equilibrium under a slope);
- the cell size is chosen from the section (:func:`section_cell_size`): the round size (1, 1.5,
  2, 2.5, 3, 4, 5, 6 or 8 times a power of ten) nearest the one whose run the estimate
  (:func:`projects.build.estimate`) puts at :data:`SECTION_RUN_S` of computing at the machine's
  throughput, with at most :data:`SECTION_MAX_PARTICLES` particles and at least
  :data:`SECTION_MIN_CELLS` cells over the section's height.
"""

from __future__ import annotations

import copy
import math
import re
from collections.abc import Sequence
from typing import Any

import numpy as np

from projects.schema import ProjectError

#: Wall time (s, at the machine's throughput) the estimate of an imported section's run may take.
SECTION_RUN_S = 600.0
#: The most particles an imported section gets (the workbench previews up to 400,000).
SECTION_MAX_PARTICLES = 200_000
#: The fewest cells over an imported section's height.
SECTION_MIN_CELLS = 10
#: Round cell sizes are these times a power of ten.
ROUND_MANTISSAS = (1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0, 8.0)


def round_cell(value: float) -> float:
    """The round number (:data:`ROUND_MANTISSAS` times a power of ten) nearest ``value`` by ratio."""
    if not (math.isfinite(value) and value > 0.0):
        raise ValueError(f"a cell size must be a positive number, got {value!r}")
    power = 10.0 ** math.floor(math.log10(value))
    candidates = [m * power for m in ROUND_MANTISSAS] + [10.0 * power]
    best = min(candidates, key=lambda c: abs(math.log(c / value)))
    return float(f"{best:.12g}")


def section_cell_size(data: dict[str, Any], particle_steps_per_s: float, run_s: float = SECTION_RUN_S,
                      max_particles: int = SECTION_MAX_PARTICLES, min_cells: int = SECTION_MIN_CELLS) -> float:
    """The cell size for a project's section (its bodies as they stand in ``data``), in metres.

    The estimate at the project's cell size ``dx0`` gives ``P0`` particles and ``S0`` steps; the
    particles go as ``dx^-2``, the steps as ``dx^-1`` with a CFL number (a fixed time step: not
    at all), so the largest cell size whose particle-steps fit ``particle_steps_per_s * run_s``
    is ``dx0 (P0 S0 / budget)^(1/3)`` (``^(1/2)``), and ``dx0 (P0 / max_particles)^(1/2)`` keeps
    the particles within ``max_particles``. Of the two the smaller, at most the section's height
    over ``min_cells``, rounded (:func:`round_cell`).

    Raises
    ------
    ProjectError
        The project is not valid as it stands.
    ValueError
        A throughput or budget that is not positive.
    """
    from projects.build import estimate
    from projects.presets import apply_preset
    from projects.schema import validate_project

    if not (particle_steps_per_s > 0 and run_s > 0 and max_particles > 0):
        raise ValueError(f"the throughput and the budget must be positive, got {particle_steps_per_s!r} "
                         f"particle-steps/s for {run_s!r} s and {max_particles!r} particles")
    project = apply_preset(validate_project(data))
    dx0 = project.domain.cell_size_m
    e = estimate(project)
    particles, steps = float(e["particles"]), float(e["steps"])
    budget = particle_steps_per_s * run_s
    power = 1.0 / 3.0 if e["time_step_source"] == "cfl" else 0.5
    by_time = dx0 * (particles * max(steps, 1.0) / budget) ** power
    by_count = dx0 * math.sqrt(particles / max_particles)
    points = np.concatenate([np.asarray(b.polygon_m, dtype=float) for b in project.bodies])
    height = float(np.ptp(points[:, 1])) or float(np.ptp(points[:, 0]))
    return round_cell(min(max(by_time, by_count), height / min_cells))


def gravity_for_slopes(data: dict[str, Any]) -> list[str]:
    """Replace a k0 initial stage of ``data`` by gravity loading where the ground slopes (K0 is
    no equilibrium there: :func:`projects.checks.recommended_initial_stage`); what was changed,
    in words (empty: nothing)."""
    from projects.checks import recommended_initial_stage
    from projects.schema import validate_project

    stages = data.get("stages") or []
    if not stages or not isinstance(stages[0], dict) or stages[0].get("type") != "k0":
        return []
    try:
        recommended = recommended_initial_stage(validate_project(data))
    except (ProjectError, ValueError, ArithmeticError):
        return []
    if recommended.get("type") != "gravity":
        return []
    stages[0] = {**recommended, "name": stages[0].get("name", recommended["name"])}
    return [f"The ground slopes: the initial stress comes from gravity loading over "
            f"{recommended['duration_s']:g} s (K0 is no equilibrium on a slope)"]


def material_name(text: str) -> str:
    """A layer's name as a material name (letters, digits, ``_`` and ``-``; others become ``-``)."""
    name = re.sub(r"[^A-Za-z0-9_-]+", "-", text).strip("-")
    return name or "layer"


def _unique(name: str, taken: set[str]) -> str:
    out, n = name, 2
    while out in taken:
        out, n = f"{name}-{n}", n + 1
    taken.add(out)
    return out


def _fit(data: dict[str, Any]) -> float:
    """Fit the grid of ``data`` to its bodies (their right end onto the right wall); the shift."""
    from geometry.templates import fit_domain

    bodies = data["bodies"]
    cell = float(data["domain"]["cell_size_m"])
    fitted = fit_domain([np.asarray(b["polygon_m"], dtype=float) for b in bodies], cell)
    for body, polygon in zip(bodies, fitted.polygons):
        body["polygon_m"] = [[float(x), float(y)] for x, y in polygon]
    data["domain"]["origin_m"] = [float(v) for v in fitted.origin_m]
    data["domain"]["size_m"] = [float(v) for v in fitted.size_m]
    return fitted.end_shift_m


def place_section(data: dict[str, Any], layers: Sequence[tuple[str, np.ndarray]], material: str, *,
                  particle_steps_per_s: float | None = None) -> list[str]:
    """Put an imported section into a project's data (module docstring); what was done, in words.

    Parameters
    ----------
    data : dict
        The project's data (TOML-shaped), changed in place.
    layers : sequence of (name, array (K, 2)[, layer])
        The section's bodies (:func:`geometry.importers.read_layers`), named; a layer's material
        is named after its layer (a band the lines cut in two: both parts one material).
    material : str
        The material of a one-layer section, and the model for the materials of several layers.
    particle_steps_per_s : float, optional
        The machine's throughput; None keeps the project's cell size.

    Returns
    -------
    list of str
        One sentence per change (the bodies and materials, the domain, the initial stage, the
        cell size).
    """
    notes: list[str] = []
    materials = data.setdefault("materials", {})
    bodies = data.setdefault("bodies", [])
    taken = {b.get("name") for b in bodies}
    new_materials: list[str] = []
    for name, polygon, *layer in layers:
        layer = layer[0] if layer else name
        if len(layers) == 1 or not isinstance(materials.get(material), dict):
            chosen = material
        else:
            chosen = material_name(layer)
            if chosen not in materials:
                materials[chosen] = copy.deepcopy(materials[material])
                new_materials.append(chosen)
        bodies.append({"name": _unique(name, taken), "material": chosen,
                       "polygon_m": [[float(x), float(y)] for x, y in np.asarray(polygon, dtype=float)]})
    names = ", ".join(str(item[0]) for item in layers)
    notes.append(f"Imported {len(layers)} bod{'y' if len(layers) == 1 else 'ies'} ({names})")
    if new_materials:
        notes.append(f"new materials {', '.join(new_materials)}, copies of {material}: give each its own values")
    shift = _fit(data)
    notes.extend(gravity_for_slopes(data))
    if particle_steps_per_s is not None:
        old = float(data["domain"]["cell_size_m"])
        try:
            cell = section_cell_size(data, particle_steps_per_s)
        except (ProjectError, ValueError, ArithmeticError) as err:
            notes.append(f"the cell size stays {old:g} m ({err})")
        else:
            if cell != old:
                data["domain"]["cell_size_m"] = cell
                shift = _fit(data)
                notes.append(f"cell size {old:g} -> {cell:g} m (about {SECTION_RUN_S / 60:g} minutes of computing "
                             "by the estimate)")
    lo = data["domain"]["origin_m"]
    notes.append(f"the domain fitted to the section: the base at y = {lo[1]:g} m, its ends on the side walls"
                 + (f" (the right end moved {shift:+.3g} m onto the wall)" if abs(shift) > 0 else ""))
    return [n for n in notes if n]
