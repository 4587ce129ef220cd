"""Geostatic (K0) initial stress from the overburden above each particle.

The vertical stress of a particle is the weight per unit width of the material above it within
its own horizontal extent. Each particle ``q`` stands for a bar of material of width
``s_q = sqrt(V_q)`` (across gravity) centred on it; its weight ``m_q |g|`` is spread evenly over
that width. The overburden of ``p`` is the weight above it inside ``p``'s own bar, divided by its
width, with the particles at ``p``'s own height counted half:

    sigma_v(p) = -1/s_p sum_q m_q |g| overlap(bar_q, bar_p) / s_q     (q above p; half at its level)

The sum is taken over strips: the bars' edges cut the horizontal axis into elementary strips, in
each of which every bar's weight is uniform, so the sum is exact strip by strip. For lattice
seeding (bars tiling each row) this gives ``-rho |g| (H - y)`` at every particle, whatever the
alignment of the lattice with the grid, for layered bodies, for bodies of different particle
spacings and next to a structure face that cuts a grid cell: the particle line next to the face
carries its full column. (The former binning by grid-cell columns assumed the material filled
each column across: a face 0.3 cells off the node line left the particle line next to it at half
its overburden.) With lattice seeding a particle's bar is the box of the material it stands for
(``Particles.bounds_m``: its sub-cell, or the part of it a body's outline leaves), not ``sqrt(V)``
about it, so the bars tile each row next to outlines between sub-cell lines too. Where the bars'
edges are not shared (Gauss seeding, gravity oblique to the lattice) the edges are snapped to
strips of a quarter of the median bar width, so the work stays a few entries per particle.

The horizontal and out-of-plane stresses are ``K0 sigma_v``; K0 is the stage's value or each
material's default (Jaky's ``1 - sin(phi)``, ``nu / (1 - nu)`` for elastic materials). Compression
is negative.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from solver.config import Material, Particles, Water
from solver.water import below_line, free_water_depth, pore_pressure

#: Round-off tolerance of heights and bar edges, in cell sizes.
TOLERANCE_CELLS = 1e-6
#: Above this many strip entries per particle, bar edges are snapped to a quarter of the median width.
MAX_ENTRIES_PER_PARTICLE = 4
SNAP_FRACTION = 0.25


def _strips(lo_m: np.ndarray, hi_m: np.ndarray, tol_m: float):
    """Elementary strips of the bars ``[lo, hi]``: per bar the first strip and the number of strips,
    and the strips' widths (m)."""
    ka = np.round(lo_m / tol_m).astype(np.int64)
    kb = np.round(hi_m / tol_m).astype(np.int64)
    edges, at = np.unique(np.concatenate([ka, kb]), return_index=True)
    first = np.searchsorted(edges, ka)
    count = np.searchsorted(edges, kb) - first
    if count.sum() > MAX_ENTRIES_PER_PARTICLE * len(lo_m) + 16:
        # edges not shared: snap them to a fixed set of strips
        step = SNAP_FRACTION * float(np.median(hi_m - lo_m))
        base = float(lo_m.min())
        first = np.round((lo_m - base) / step).astype(np.int64)
        count = np.maximum(np.round((hi_m - base) / step).astype(np.int64) - first, 1)
        widths = np.full(int((first + count).max()), step)
        return first, count, widths
    # each edge at its first bar's own value (bars that share an edge agree to round-off)
    return first, count, np.diff(np.concatenate([lo_m, hi_m])[at])


def k0_stress(particles: Particles, materials: Sequence[Material], gravity_m_s2, cell_size_m: float,
              k0: float | None = None, active: np.ndarray | None = None,
              positions_m: np.ndarray | None = None, water: Water | None = None) -> np.ndarray:
    """Geostatic effective stress of every particle.

    Dry (``water`` None and no material with an r_u) the effective stress is the total stress.
    With water the total vertical stress takes saturated densities below the phreatic line and
    the weight of the free water standing above the ground over each particle's bar; the pore
    pressure (solver/water.py) is taken off it, and K0 acts on the effective vertical stress:
    ``sigma'_v = sigma_v + u``, ``sigma'_h = K0 sigma'_v`` (compression negative).

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
    wet = any(m.ru > 0.0 for m in materials) or water is not None
    rho = np.array([m.density_kg_m3 for m in materials])[mat]
    if water is not None:
        rho = np.where(below_line(water, x, g), np.array([m.wet_density_kg_m3 for m in materials])[mat], rho)
    volume = np.asarray(particles.volumes_m2, dtype=np.float64)
    weight = rho * volume * gn  # N per m out of plane
    if active is not None:
        weight = np.where(active, weight, 0.0)
    if wet:
        # the depth of material above each particle (unit weights of 1), for the ground surface
        sigma_v, depth = _overburden(particles, x, volume, cell_size_m, down, across, positions_m,
                                     np.stack([weight, np.where(weight > 0.0, volume, 0.0)]))
        depth = -depth
        if water is not None:
            surface = x - down[None, :] * depth[:, None]
            sigma_v = sigma_v - water.unit_weight_n_m3 * free_water_depth(water, surface, g)
        u = pore_pressure(water, materials, mat, x, g, vertical_stress_pa=sigma_v)
        sigma_v = sigma_v + u
    else:
        sigma_v = _overburden(particles, x, volume, cell_size_m, down, across, positions_m, weight[None, :])[0]
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


def _overburden(particles: Particles, x: np.ndarray, volume: np.ndarray, cell_size_m: float, down: np.ndarray,
                across: np.ndarray, positions_m, weights: np.ndarray) -> tuple[np.ndarray, ...]:
    """The overburden of every particle for each row of ``weights`` ((k, N): what each particle
    weighs), compression negative: one array per row."""
    n = len(x)
    width = np.sqrt(np.maximum(volume, 0.0))
    tol = TOLERANCE_CELLS * cell_size_m
    centre = x @ across
    bounds = particles.bounds_m
    axis = int(np.argmax(np.abs(across)))
    moved = 0.0 if positions_m is None else float(np.max(np.abs(x - particles.positions_m), initial=0.0))
    if bounds is not None and moved <= 1e-3 * cell_size_m and abs(abs(across[axis]) - 1.0) < 1e-12:
        # the lattice's own boxes (gravity along a grid axis): a part of a sub-cell cut by an
        # outline is as wide as it is, not sqrt(V), and its bar lies where it does, so the bars
        # still tile each row
        box = np.asarray(bounds, dtype=np.float64)
        lo = box[:, axis] * across[axis]
        hi = box[:, axis + 2] * across[axis]
        # only where the box differs from the sqrt(V) bar (the cut parts): a whole sub-cell keeps
        # its bar to the last bit
        seeded = np.asarray(particles.positions_m, dtype=np.float64) @ across
        part = (np.abs(np.abs(hi - lo) - width) > tol) | (np.abs(0.5 * (lo + hi) - seeded) > tol)
        centre = np.where(part, 0.5 * (lo + hi), centre)
        width = np.where(part, np.abs(hi - lo), width)
    width = np.maximum(width, 4 * tol)
    first, count, strip_w = _strips(centre - 0.5 * width, centre + 0.5 * width, tol)
    # one entry per (particle, strip it covers); each strip holds the particle's share of its weight
    owner = np.repeat(np.arange(n), count)
    strip = np.repeat(first, count) + (np.arange(owner.size) - np.repeat(np.cumsum(count) - count, count))
    bar_w = np.bincount(owner, weights=strip_w[strip], minlength=n)  # the bar's width on the strips
    height = -(x @ down)
    level = np.round(height / tol).astype(np.int64)[owner]
    # group entries at the same height in a strip (round-off tolerant), tallest first
    order = np.lexsort((-level, strip))
    str_s, lev_s = strip[order], level[order]
    new_group = np.r_[True, (str_s[1:] != str_s[:-1]) | (lev_s[1:] != lev_s[:-1])]
    group = np.cumsum(new_group) - 1
    group_strip = str_s[new_group]
    strip_start = np.r_[True, group_strip[1:] != group_strip[:-1]]
    start_index = np.maximum.accumulate(np.where(strip_start, np.arange(len(group_strip)), 0))
    out = []
    for weight in weights:
        share = weight[owner] * strip_w[strip] / bar_w[owner]
        group_weight = np.bincount(group, weights=share[order])
        # weight of all groups above, within the strip
        csum = np.cumsum(group_weight)
        before = np.r_[0.0, csum[:-1]]
        above = before - np.r_[0.0, csum][start_index]
        entry_above = np.empty(owner.size)
        entry_above[order] = above[group] + 0.5 * group_weight[group]
        out.append(-np.bincount(owner, weights=entry_above, minlength=n) / bar_w)
    return tuple(out)
