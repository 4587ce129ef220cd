"""What the views draw of a frame beyond its raw particle values: the size of the squares that draw
the particles where a moving mass has spread them apart (:func:`display_spacing`), and a field
averaged over the cells around each particle (:func:`smooth_values`; app.render.shown_values shows them), the
display of a stress that the material point method carries with cell-scale noise in a moving mass.
Display choices only: the frames keep their particles and values. Used by :mod:`app.render`'s
pictures and movies, the workbench's results view and ``runout query`` (numpy and scipy, no VTK).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

#: The frame arrays whose fields may be shown smoothed (:func:`smooth_values`): the stresses and
#: the pore pressure, which a moving mass carries with cell-scale noise.
SMOOTHED_SOURCES = frozenset({"stress", "pore_pressure"})
#: The neighbours of a particle whose halfway points tell how far the particles have spread
#: (display_spacing), and the percentile over the particles that sets the squares' size.
DISPLAY_NEIGHBOURS = 6
DISPLAY_PERCENTILE = 90
#: The point size follows the spread of the particles up to this many initial spacings (a few
#: particles thrown apart do not make the whole mass's points larger).
DISPLAY_SPREAD_MAX = 2.0
#: Above this many particles the spread is measured around a random sample of them.
DISPLAY_SAMPLE = 50_000


def display_spacing(positions: np.ndarray, spacing_m: float) -> float:
    """The side of the squares that draw a frame's particles (m): the particles' spacing at the
    start, or more where the mass has spread.

    A particle stands for the material around it; in a flowing mass the particles drift apart in
    one direction and close up in another (the material points of a grid column keeping together
    while the columns part): squares of the initial spacing then leave gaps, and the mass reads as
    separated columns. Squares of side ``L`` cover the material where every point of it lies within
    ``L / 2`` of a particle along x and y: for each particle the points halfway to its
    :data:`DISPLAY_NEIGHBOURS` nearest neighbours (those within 2.5 spacings) are measured to
    their nearest particle (in that metric) and the largest counts; ``L`` is twice the
    :data:`DISPLAY_PERCENTILE`-th percentile of those over the particles, at least the initial
    spacing and at most :data:`DISPLAY_SPREAD_MAX` times it. On a regular lattice ``L`` is its
    spacing; where columns ``a`` apart hold particles ``b < a`` apart, ``a``. A display choice: the
    frames' positions are drawn as written.
    """
    spacing = float(spacing_m)
    pts = np.asarray(positions, dtype=np.float64).reshape(-1, 2)
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    if not spacing > 0 or len(pts) <= DISPLAY_NEIGHBOURS:
        return spacing
    from scipy.spatial import cKDTree

    tree = cKDTree(pts)
    centres = pts
    if len(pts) > DISPLAY_SAMPLE:
        centres = pts[np.random.default_rng(0).choice(len(pts), DISPLAY_SAMPLE, replace=False)]
    distance, index = tree.query(centres, k=DISPLAY_NEIGHBOURS + 1)
    near = distance[:, 1:] < 2.5 * spacing
    halfway = 0.5 * (centres[:, None, :] + pts[index[:, 1:]])
    gap, _ = tree.query(halfway.reshape(-1, 2), k=1, p=np.inf)
    gap = np.where(near, gap.reshape(near.shape), 0.0).max(axis=1)
    spread = 2.0 * float(np.percentile(gap, DISPLAY_PERCENTILE))
    return float(min(DISPLAY_SPREAD_MAX * spacing, max(spacing, spread)))


def smooth_values(positions: np.ndarray, values: np.ndarray, cell_size_m: float,
                  origin_m: Sequence[float] = (0.0, 0.0)) -> np.ndarray:
    """``values`` averaged over the grid cells around each particle, for display.

    The particle values go to the grid's nodes with the linear weights of MPM's transfers (each
    node the weighted mean of the particles in the four cells around it) and come back to each
    particle from the four nodes of its cell: an average over about two cells in each direction.
    A stress that alternates from cell to cell in a moving mass (the cell-crossing noise of the
    material point method, a checkerboard at the cell scale) is shown as its local mean; a field
    that varies over several cells keeps its shape (a linear field comes back unchanged inside
    the mass). Particles without a finite value are left out and get NaN back only where no
    neighbour has one. Used where the results view or a picture is asked to smooth
    (:data:`SMOOTHED_SOURCES`); the frames keep their particle values.
    """
    pts = np.asarray(positions, dtype=np.float64).reshape(-1, 2)
    vals = np.asarray(values, dtype=np.float64).reshape(-1)
    h = float(cell_size_m)
    out = np.full(len(vals), np.nan)
    good = np.all(np.isfinite(pts), axis=1)
    if not h > 0 or not good.any():
        return vals.copy()
    rel = (pts[good] - np.asarray(origin_m, dtype=np.float64)) / h
    base = np.floor(rel).astype(np.int64)
    frac = rel - base
    lo = base.min(axis=0)
    base -= lo
    nx, ny = base.max(axis=0) + 2
    have = np.isfinite(vals[good])
    v = np.where(have, vals[good], 0.0)
    w_sum = np.zeros(nx * ny)
    v_sum = np.zeros(nx * ny)
    corners = []
    for dx in (0, 1):
        for dy in (0, 1):
            w = (frac[:, 0] if dx else 1.0 - frac[:, 0]) * (frac[:, 1] if dy else 1.0 - frac[:, 1])
            node = (base[:, 0] + dx) * ny + (base[:, 1] + dy)
            np.add.at(w_sum, node, w * have)
            np.add.at(v_sum, node, w * v)
            corners.append((node, w))
    with np.errstate(invalid="ignore", divide="ignore"):
        node_value = v_sum / w_sum
    back = np.zeros(len(rel))
    weight = np.zeros(len(rel))
    for node, w in corners:
        ok = w_sum[node] > 0
        back += np.where(ok, w * np.nan_to_num(node_value[node]), 0.0)
        weight += np.where(ok, w, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        out[good] = np.where(weight > 0, back / weight, np.nan)
    return out
