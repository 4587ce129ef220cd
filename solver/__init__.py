"""Runout's MPM solver: Taichi kernels for 2D plane-strain geomaterials (numpy + taichi only).

Public API: the frozen configuration in :mod:`solver.config` and :class:`solver.simulation.Simulation`.
Importing this package does not initialise Taichi.
"""

from solver.config import (
    OUTPUT_FIELDS,
    SCHEMES,
    Boundary,
    Diagnostics,
    Frame,
    Grid,
    InstabilityError,
    Material,
    Numerics,
    Output,
    Particles,
    SimulationConfig,
    SolverError,
    Stage,
)

__all__ = [
    "OUTPUT_FIELDS", "SCHEMES", "Boundary", "Diagnostics", "Frame", "Grid", "InstabilityError", "Material",
    "Numerics", "Output", "Particles", "SimulationConfig", "SolverError", "Stage",
]
