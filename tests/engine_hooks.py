"""Test-only access to engine internals (kept out of the production class :class:`solver.engine.Engine`).

Import after a Taichi runtime is acquired (the kernels here are compiled against it).
"""


import numpy as np
import taichi as ti


def grid_totals(eng) -> tuple[float, np.ndarray]:
    """Total grid mass (kg/m) and momentum (mass x new velocity, kg m/s per m) after the last step."""
    mass = eng.g_mass.to_numpy().astype(np.float64)
    mom = eng.g_mom.to_numpy().astype(np.float64) * mass[..., None]
    return float(mass.sum()), mom.reshape(-1, 2).sum(axis=0)


def transfer_only(eng) -> None:
    """P2G and G2P with zero time step and no gravity: a pure transfer round trip."""
    eng.step(0.0, (0.0, 0.0))


@ti.kernel
def _contact_everywhere(eng: ti.template()):
    for I in ti.grouped(eng.g_mom):
        eng.g_mom[I] = eng.contact.apply(I, eng.g_mom[I], 1.0, False, "updated", 0.0, 0.0)
    eng.walls.columns_updated(0.0, ti.Vector([0.0, 0.0]), 0.0, False)


def apply_contacts(eng, node_velocity: np.ndarray) -> np.ndarray:
    """The contact law of the sides and structures applied to a whole grid of node velocities,
    shape (nx, ny, 2) (every node as if it held material of unit mass), the friction sides' wall
    columns included (solver.walls)."""
    eng.g_mom.from_numpy(np.asarray(node_velocity, dtype=eng.np_float))
    eng.g_mass.fill(1.0)
    _contact_everywhere(eng)
    out = eng.g_mom.to_numpy()
    eng.g_mom.fill(0.0)  # the steps rely on zeros outside the box of written nodes
    eng.g_mass.fill(0.0)
    eng.contact.contact_step.fill(0.0)
    return out
