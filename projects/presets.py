"""Accuracy/cost presets (``numerics.preset``): measured settings a project can ask for by name.

The presets come from ``runout study tradeoff`` (the aluminium-bar collapse swept over schemes,
cell sizes, particles per cell and time steps): each is the cheapest setting whose deposit
differs from the finest run by less than a stated error. They are stored in
``projects/presets.json`` with their measured errors and relative cost (see docs/validation.md).

A preset sets ``numerics.scheme``, ``numerics.cfl``, ``particles.per_cell`` and the cell size,
which scales with the scene: ``cell_size_m = (height of the smallest body) / cells_per_height``.
These preset values take precedence over the file's; ``time_step_s`` cannot be combined with a
preset (the schema says so).
"""

from __future__ import annotations

import json
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from projects.schema import Problem, Project, ProjectError

PRESETS_FILE = Path(__file__).with_name("presets.json")


@lru_cache(maxsize=1)
def load_presets() -> dict[str, Any]:
    """The presets file as a dict (``presets``: name -> settings and measured errors)."""
    try:
        return json.loads(PRESETS_FILE.read_text())
    except (OSError, ValueError) as exc:
        raise ProjectError([Problem("numerics.preset", None, f"presets are not available ({exc})")]) from exc


def apply_preset(project: Project) -> Project:
    """The project with its preset's values filled in (the project itself when it has none).

    Raises
    ------
    ProjectError
        The preset is not in the presets file (or the study found no setting for it).
    """
    name = project.numerics.preset
    if name is None:
        return project
    preset = load_presets().get("presets", {}).get(name)
    if not preset:
        raise ProjectError([Problem("numerics.preset", name, "no measured setting for this preset in presets.json")])
    heights = [float(np.ptp(np.asarray(b.polygon_m, dtype=float)[:, 1])) for b in project.bodies]
    cell = min(heights) / float(preset["cells_per_height"])
    return project.model_copy(update={
        "domain": project.domain.model_copy(update={"cell_size_m": cell}),
        "particles": project.particles.model_copy(update={"per_cell": int(preset["per_cell"])}),
        "numerics": project.numerics.model_copy(
            update={"scheme": preset["scheme"], "cfl": float(preset["cfl"]), "time_step_s": None}),
    })
