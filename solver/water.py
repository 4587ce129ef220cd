"""Ground water: pore pressure from a prescribed phreatic line, effective stress, wet density.

The water is steady and drained: its lines are given (and moved by stages), not solved. Below the
phreatic line the pore pressure is hydrostatic::

    u = gamma_w h                      h: depth of the point below the line, along gravity
    u = gamma_w h cos^2(theta)         with the inclined-line correction

where ``theta`` is the line's inclination from level (from the direction across gravity). The
correction is the usual one for seepage parallel to an inclined line (the equipotentials are
normal to the flow lines, so the pressure head at depth ``h`` below the line is ``h cos^2 theta``;
e.g. Rocscience Slide2's automatic ``Hu = cos^2``). On an infinite slope modelled with periodic
sides and inclined gravity, a line parallel to the slope with the correction is the closed form's
seepage parallel to the slope, ``u = gamma_w m z cos^2 beta``.

A material with a pore-pressure ratio ``r_u > 0`` (Bishop and Morgenstern 1960) also has a pore
pressure in proportion to its overburden, ``u = r_u sigma_v`` with ``sigma_v`` the total vertical
stress (along gravity); in terms of the effective stress the solver carries,
``u = r_u / (1 - r_u) sigma'_v``. Where a line also applies the larger of the two is taken (the
same rule as the limit-equilibrium check, stability/bishop.py).

The solver's stress is the effective stress ``sigma'``: the constitutive update and yield act on it.
The pore pressure's gradient acts on the soil skeleton as a body force, ``-grad u`` per unit
volume, with the total weight of the saturated soil. It is applied in two parts: the free water's
hydrostatic pressure ``p_w`` (``gamma_w`` times the depth below the free-water line, 0 above it)
through its gradient at each particle, ``-V grad p_w`` (buoyancy), and the rest, the excess pore
pressure ``u - p_w``, through the particles' stress in the force passes, ``sigma' - (u - p_w) I``
(seepage forces, whose divergence MPM takes like any stress). Split so, the boundary of the soil
is right without a traction: at a surface under free water ``u = p_w`` and the effective stress
is free; where the pore pressure inside a face exceeds the water outside it (a reservoir drawn
down faster than the slope drains) the surface particles' excess pore pressure pushes the face
out, as the seepage out of it does. Below the phreatic line a particle's mass (its weight and
its inertia) is that of its saturated density.

The water's unit weight ``gamma_w`` is given for the full gravity of the run; in a gravity stage
that ramps gravity up, the pore pressure ramps with it (``u`` in proportion to ``|g|``).

Compiled in only where a run has water (:attr:`solver.config.SimulationConfig.has_water`): a dry run
builds none of this.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from solver.config import Material, Water


# ------------------------------------------------------------------ the lines (numpy)
def line_height(line: Sequence[Sequence[float]], x: np.ndarray) -> np.ndarray:
    """Height of a polyline (x strictly increasing) at ``x``, extended level beyond its ends (m)."""
    pts = np.asarray(line, dtype=np.float64).reshape(-1, 2)
    return np.interp(np.asarray(x, dtype=np.float64), pts[:, 0], pts[:, 1])


def blend_lines(start: Sequence[Sequence[float]], end: Sequence[Sequence[float]], fraction: float
                ) -> tuple[tuple[float, float], ...]:
    """The line a fraction of the way from ``start`` to ``end``: each height moves linearly, on the
    vertices of both lines."""
    xs = np.union1d(np.asarray(start, dtype=np.float64)[:, 0], np.asarray(end, dtype=np.float64)[:, 0])
    ys = (1.0 - fraction) * line_height(start, xs) + fraction * line_height(end, xs)
    return tuple((float(a), float(b)) for a, b in zip(xs, ys))


def blend_water(start: Water | None, end: Water | None, fraction: float) -> Water | None:
    """The water a fraction of the way through a stage that moves it from ``start`` to ``end``."""
    if end is None or start is None:
        return end if fraction >= 1.0 else start
    if fraction >= 1.0:
        return end
    free = blend_lines(start.free_water, end.free_water, fraction)
    return Water(blend_lines(start.phreatic_line_m, end.phreatic_line_m, fraction), free,
                 end.unit_weight_n_m3, end.inclined_correction)


def _depth_along_gravity(line, x: np.ndarray, down: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Depth ``h`` of each point below the line along gravity (negative above it), and the squared
    cosine of the line's inclination from level there."""
    pts = np.asarray(line, dtype=np.float64).reshape(-1, 2)
    y_line = np.interp(x[:, 0], pts[:, 0], pts[:, 1])
    if len(pts) > 1:
        slopes = np.diff(pts[:, 1]) / np.diff(pts[:, 0])
        k = np.clip(np.searchsorted(pts[:, 0], x[:, 0], side="right") - 1, 0, len(slopes) - 1)
        slope = np.where((x[:, 0] < pts[0, 0]) | (x[:, 0] > pts[-1, 0]), 0.0, slopes[k])
    else:
        slope = np.zeros(len(x))
    # from the point up against gravity to the local tangent of the line
    denom = np.maximum(-down[1] + slope * down[0], 1e-9)
    h = (y_line - x[:, 1]) / denom
    level = np.array([-down[1], down[0]])
    cos = (level[0] + slope * level[1]) / np.sqrt(1.0 + slope * slope)
    return h, cos * cos


def pore_pressure(water: Water | None, materials: Sequence[Material], material_ids: np.ndarray,
                  positions_m: np.ndarray, gravity_m_s2, full_gravity_m_s2=None,
                  vertical_stress_pa: np.ndarray | None = None) -> np.ndarray:
    """Pore pressure at points (Pa, positive in compression of the water), the solver's rule.

    ``vertical_stress_pa``: the total stress along gravity at the points (compression negative),
    for the materials with an ``r_u`` (where it is None they get only the line's).
    """
    x = np.asarray(positions_m, dtype=np.float64).reshape(-1, 2)
    mat = np.asarray(material_ids)
    g = np.asarray(gravity_m_s2, dtype=np.float64)
    gn = float(np.linalg.norm(g))
    full = gn if full_gravity_m_s2 is None else float(np.linalg.norm(full_gravity_m_s2))
    u = np.zeros(len(x))
    if gn == 0.0 or len(x) == 0:
        return u
    ru = np.array([m.ru for m in materials])[mat]
    if water is not None:
        h, c2 = _depth_along_gravity(water.phreatic_line_m, x, g / gn)
        gamma = water.unit_weight_n_m3 * gn / full
        u = gamma * np.maximum(h, 0.0) * (c2 if water.inclined_correction else 1.0)
    if vertical_stress_pa is not None:
        u = np.maximum(u, ru * np.maximum(-np.asarray(vertical_stress_pa, dtype=np.float64), 0.0))
    return u


def below_line(water: Water | None, positions_m: np.ndarray, gravity_m_s2) -> np.ndarray:
    """Whether each point lies below the phreatic line (where its soil is saturated)."""
    x = np.asarray(positions_m, dtype=np.float64).reshape(-1, 2)
    g = np.asarray(gravity_m_s2, dtype=np.float64)
    gn = float(np.linalg.norm(g))
    if water is None or gn == 0.0:
        return np.zeros(len(x), dtype=bool)
    h, _ = _depth_along_gravity(water.phreatic_line_m, x, g / gn)
    return h > 0.0


def free_water_depth(water: Water | None, positions_m: np.ndarray, gravity_m_s2) -> np.ndarray:
    """Depth of points below the free water's level along gravity (m, 0 above it)."""
    x = np.asarray(positions_m, dtype=np.float64).reshape(-1, 2)
    g = np.asarray(gravity_m_s2, dtype=np.float64)
    gn = float(np.linalg.norm(g))
    if water is None or gn == 0.0:
        return np.zeros(len(x))
    h, _ = _depth_along_gravity(water.free_water, x, g / gn)
    return np.maximum(h, 0.0)


def unit_weight_ratio(materials: Sequence[Material]) -> np.ndarray:
    """Per material, the saturated density over the dry one."""
    return np.array([m.wet_density_kg_m3 / m.density_kg_m3 for m in materials], dtype=np.float64)
