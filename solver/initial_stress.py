"""Geostatic (K0) initial stress from the overburden above each particle.

The vertical stress of a particle is the weight per unit width of the material above it in its
column (columns one cell wide, normal to gravity): ``sigma_v = -sum_{q above p} m_q |g| / dx``,
with the particles at the particle's own height counted half. For grid-aligned (lattice) seeding
this is exactly ``-rho |g| (H - y)`` at every particle, also for layered bodies. The horizontal and
out-of-plane stresses are ``K0 sigma_v``; K0 is the stage's value or each material's default
(Jaky's ``1 - sin(phi)``, ``nu / (1 - nu)`` for elastic materials). Compression is negative.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from solver.config import Material, Particles


def k0_stress(particles: Particles, materials: Sequence[Material], gravity_m_s2, cell_size_m: float,
              k0: float | None = None, active: np.ndarray | None = None,
              positions_m: np.ndarray | None = None) -> np.ndarray:
    """Geostatic stress of every particle.

    Returns
    -------
    (N, 4) float64, Pa: xx, yy, xy, zz.
    """
    x = particles.positions_m if positions_m is None else positions_m
    x = np.asarray(x, dtype=np.float64)
    n = len(x)
    stress = np.zeros((n, 4))
    g = np.asarray(gravity_m_s2, dtype=np.float64)
    gn = float(np.linalg.norm(g))
    if gn == 0.0 or n == 0:
        return stress
    down = g / gn
    across = np.array([-down[1], down[0]])
    mat = np.asarray(particles.material_ids)
    rho = np.array([m.density_kg_m3 for m in materials])[mat]
    weight = rho * np.asarray(particles.volumes_m2, dtype=np.float64) * gn / cell_size_m
    if active is not None:
        weight = np.where(active, weight, 0.0)
    height = -(x @ down)
    column = np.floor((x @ across) / cell_size_m).astype(np.int64)
    # group particles at the same height in a column (round-off tolerant), tallest first
    level = np.round(height / (cell_size_m * 1e-6)).astype(np.int64)
    order = np.lexsort((-level, column))
    col_s, lev_s, w_s = column[order], level[order], weight[order]
    new_group = np.r_[True, (col_s[1:] != col_s[:-1]) | (lev_s[1:] != lev_s[:-1])]
    group = np.cumsum(new_group) - 1
    group_weight = np.bincount(group, weights=w_s)
    group_col = col_s[new_group]
    # weight of all groups above, within the column
    csum = np.cumsum(group_weight)
    col_start = np.r_[True, group_col[1:] != group_col[:-1]]
    start_index = np.maximum.accumulate(np.where(col_start, np.arange(len(group_col)), 0))
    before = np.r_[0.0, csum[:-1]]
    above = before - np.r_[0.0, csum][start_index]
    sigma_v_sorted = -(above[group] + 0.5 * group_weight[group])
    sigma_v = np.empty(n)
    sigma_v[order] = sigma_v_sorted
    if k0 is None:
        k0_p = np.array([m.default_k0 for m in materials])[mat]
    else:
        k0_p = np.full(n, float(k0))
    sigma_h = k0_p * sigma_v
    # sigma = sigma_v d d^T + sigma_h a a^T in the plane, sigma_zz = sigma_h
    stress[:, 0] = sigma_v * down[0] ** 2 + sigma_h * across[0] ** 2
    stress[:, 1] = sigma_v * down[1] ** 2 + sigma_h * across[1] ** 2
    stress[:, 2] = sigma_v * down[0] * down[1] + sigma_h * across[0] * across[1]
    stress[:, 3] = sigma_h
    return stress
