"""The value of a field at a point or along a section, at any frame of a results folder
(``runout query``, the workbench's *Query* tab).

A field (:data:`app.render.FIELDS`: displacement, speed, stresses, plastic strain, pore pressure,
material) lives on the particles. Its value at a point is the mean of the particles within one
particle spacing ``s`` of it (``summary.json`` ``particle_spacing_m``), weighted by ``1 - d / s``
(``d`` the particle's distance to the point), so that the particles nearest to it count most; a
point with no particle that near holds no material and has no value. ``material`` takes the
nearest particle's. Along a section the same is done at points every half spacing from one end to
the other. The frames are read with :mod:`projects.results`; with ``smooth`` the stresses and the
pore pressure are first averaged over the cells around each particle, as the views show them
(:func:`app.display.smooth_values`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class PointValue:
    """The value of a field at one point of one frame.

    Attributes
    ----------
    x_m, y_m : float
        The point.
    value : float
        In the field's unit (:data:`app.render.FIELDS`); NaN where no particle is within reach.
    particles : int
        The particles within one spacing that made it.
    nearest : int or None
        The nearest such particle's id (its index in the frames).
    nearest_distance_m : float
        Its distance to the point (NaN without one).
    """

    x_m: float
    y_m: float
    value: float
    particles: int
    nearest: int | None
    nearest_distance_m: float


@dataclass(frozen=True)
class Query:
    """What a query read: the frame, its time, the field with its label and unit, the reach."""

    frame: int
    time_s: float
    field: str
    label: str
    unit: str
    reach_m: float
    smoothed: bool
    points: tuple[PointValue, ...]


def _frame_index(results: Any, frame: int) -> int:
    n = len(results)
    if n == 0:
        raise ValueError(f"{results.path} has no complete frames")
    j = frame + n if frame < 0 else frame
    if not 0 <= j < n:
        raise ValueError(f"--frame {frame}: the results have {n} frames (0..{n - 1}, or -1 for the last)")
    return j


def _reach(results: Any, positions: np.ndarray) -> float:
    spacing = results.summary.get("particle_spacing_m")
    if isinstance(spacing, (int, float)) and spacing > 0:
        return float(spacing)
    if len(positions) < 2:
        return 1.0
    lo, hi = positions.min(axis=0), positions.max(axis=0)
    return math.sqrt(max(float(np.prod(hi - lo)), 1e-12) / len(positions))


def values_at(results: Any, field: str, points: Sequence[Sequence[float]], frame: int = -1,
              smooth: bool = False) -> Query:
    """The value of ``field`` at each of ``points`` ([x, y], m) in frame ``frame`` (negative:
    from the end).

    Raises
    ------
    ValueError
        An unknown field, a field the run did not write, a frame out of range.
    """
    from app.render import shown_values
    from app.render import field_info

    info = field_info(field)
    j = _frame_index(results, frame)
    arrays = results.frame(j)
    domain = results.summary.get("domain") or {}
    cell = domain.get("cell_size_m") if smooth else None
    origin = domain.get("origin_m") or (0.0, 0.0)
    values = np.asarray(shown_values(arrays, field, cell, origin), dtype=float)
    active = np.asarray(arrays["active"], dtype=bool)
    positions = np.asarray(arrays["positions"], dtype=float)
    ids = np.flatnonzero(active & np.all(np.isfinite(positions), axis=1))
    pos = positions[ids]
    reach = _reach(results, pos)
    out = []
    tree = None
    if len(pos):
        from scipy.spatial import cKDTree

        tree = cKDTree(pos)
    for x, y in points:
        near = tree.query_ball_point([float(x), float(y)], reach) if tree is not None else []
        if not near:
            out.append(PointValue(float(x), float(y), math.nan, 0, None, math.nan))
            continue
        near = np.asarray(near, dtype=int)
        d = np.hypot(pos[near, 0] - x, pos[near, 1] - y)
        k = int(np.argmin(d))
        vals = values[ids[near]]
        if info.categorical:
            value = float(vals[k])
        else:
            w = np.clip(1.0 - d / reach, 0.0, None) + 1e-12
            ok = np.isfinite(vals)
            value = float((w[ok] * vals[ok]).sum() / w[ok].sum()) if ok.any() else math.nan
        out.append(PointValue(float(x), float(y), value, len(near), int(ids[near][k]), float(d[k])))
    return Query(j, float(results.times[j]), field, info.label, info.unit, reach,
                 bool(cell) and info.source in ("stress", "pore_pressure"), tuple(out))


def section_points(start: Sequence[float], end: Sequence[float], step_m: float,
                   samples: int | None = None) -> np.ndarray:
    """Points from ``start`` to ``end``, both included: ``samples`` of them, or every ``step_m``."""
    a, b = np.asarray(start, dtype=float), np.asarray(end, dtype=float)
    length = float(np.linalg.norm(b - a))
    if not length > 0:
        raise ValueError("the section's two end points must differ")
    n = int(samples) if samples else max(2, int(math.floor(length / step_m + 1e-9)) + 1)
    if n < 2:
        raise ValueError(f"--samples {samples}: at least 2")
    t = np.linspace(0.0, 1.0, n)
    return a + t[:, None] * (b - a)


def values_along(results: Any, field: str, start: Sequence[float], end: Sequence[float], frame: int = -1,
                 samples: int | None = None, smooth: bool = False) -> Query:
    """The value of ``field`` along the section from ``start`` to ``end`` ([x, y], m): at
    ``samples`` points, or every half particle spacing (:func:`values_at` at each)."""
    j = _frame_index(results, frame)
    arrays = results.frame(j, {"positions", "active"})
    pos = np.asarray(arrays["positions"], dtype=float)[np.asarray(arrays["active"], dtype=bool)]
    reach = _reach(results, pos)
    return values_at(results, field, section_points(start, end, 0.5 * reach, samples), j, smooth)


def distances(query: Query) -> np.ndarray:
    """The distance of each point of a section query from its first point (m)."""
    pts = np.array([[p.x_m, p.y_m] for p in query.points])
    return np.hypot(pts[:, 0] - pts[0, 0], pts[:, 1] - pts[0, 1]) if len(pts) else np.zeros(0)


def csv_text(query: Query) -> str:
    """A section (or points) query as CSV: ``distance_m, x_m, y_m, FIELD_UNIT, particles,
    nearest_particle`` (empty where no material)."""
    unit = query.unit.replace("/", "_per_") if query.unit and query.unit != "-" else ""
    column = f"{query.field}_{unit}" if unit else query.field
    lines = [f"distance_m,x_m,y_m,{column},particles,nearest_particle"]
    for s, p in zip(distances(query), query.points, strict=True):
        value = "" if not math.isfinite(p.value) else repr(float(p.value))
        nearest = "" if p.nearest is None else str(p.nearest)
        lines.append(f"{float(s)!r},{p.x_m!r},{p.y_m!r},{value},{p.particles},{nearest}")
    return "\n".join(lines) + "\n"


def point_text(query: Query) -> str:
    """One line per point: ``Stress yy at (2, 0.5), frame 12 (t = 0.6 s): -12.3 kPa (the mean
    of 4 particles within 0.125 m; the nearest, 812, 0.031 m away)``."""
    lines = []
    for p in query.points:
        where = f"{query.label} at ({p.x_m:g}, {p.y_m:g}), frame {query.frame} (t = {query.time_s:.4g} s)"
        if not math.isfinite(p.value):
            lines.append(f"{where}: no material (no particle within {query.reach_m:.3g} m)")
            continue
        unit = f" {query.unit}" if query.unit and query.unit != "-" else ""
        if query.field == "material":
            lines.append(f"{where}: material {p.value:.0f} (the nearest particle's, {p.nearest}, "
                         f"{p.nearest_distance_m:.3g} m away)")
            continue
        how = "smoothed, " if query.smoothed else ""
        lines.append(f"{where}: {p.value:.6g}{unit} ({how}the mean of {p.particles} particle"
                     f"{'s' if p.particles != 1 else ''} within {query.reach_m:.3g} m; the nearest, {p.nearest}, "
                     f"{p.nearest_distance_m:.3g} m away)")
    return "\n".join(lines)
