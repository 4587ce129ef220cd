"""A project's loads: the stages' surcharges and seismic coefficients, their rules and their
solver form (docs/project-format.md, loads; docs/solver.md, loads).

- A stage's ``surcharges`` are the distributed loads in force from that stage on: a stage
  without the key keeps those of the stage before, ``surcharges = []`` removes them all. A
  surcharge with ``ramp = true`` grows linearly over its (dynamic) stage from the pressure of
  the load of the same name in force at the stage's start (0 for a new one); in a gravity stage
  every load ramps up with gravity.
- A stage's ``seismic`` coefficients act in that stage only (an earthquake is an event, a load
  is a thing on the ground): in a dynamic stage and in a strength reduction's trials. The
  horizontal force points ``towards`` the side named, or out of the slope: from the ground
  surface's higher end towards its lower one (:func:`out_of_slope`).

Nothing here imports Taichi.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from solver import config as sc

#: Points along a surcharge's segment at which the rules look for ground under it.
GROUND_SAMPLES = 65
#: Below this difference of the ground's height at its two ends (a fraction of the ground's
#: height range) the ground is level and "out of the slope" has no direction.
LEVEL_FRACTION = 1e-3


# ------------------------------------------------------------------------------ geometry
def _frame(gravity) -> tuple[np.ndarray, np.ndarray]:
    """Unit vectors (across, up) of the frame where gravity points down (across: +x for -y gravity)."""
    g = np.asarray(gravity, dtype=float)
    gn = float(np.linalg.norm(g))
    up = -g / gn if gn > 0 else np.array([0.0, 1.0])
    return np.array([up[1], -up[0]]), up


def _edges(polygons: Sequence[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """All edges of the polygons as (E, 2) start and end points."""
    starts = np.vstack([np.asarray(p, dtype=float) for p in polygons])
    ends = np.vstack([np.roll(np.asarray(p, dtype=float), -1, axis=0) for p in polygons])
    return starts, ends


def ground_height(polygons: Sequence[np.ndarray], x: np.ndarray) -> np.ndarray:
    """The highest y of the polygons on vertical lines at ``x`` (NaN where none crosses).

    Parameters
    ----------
    polygons : sequence of (K, 2) array_like, m
    x : (M,) array_like, m

    Returns
    -------
    numpy.ndarray, (M,) float, m
    """
    a, b = _edges(polygons)
    x = np.atleast_1d(np.asarray(x, dtype=float))
    lo, hi = np.minimum(a[:, 0], b[:, 0]), np.maximum(a[:, 0], b[:, 0])
    slanted = hi > lo
    a, b, lo, hi = a[slanted], b[slanted], lo[slanted], hi[slanted]
    crosses = (x[:, None] >= lo[None, :]) & (x[:, None] <= hi[None, :])
    t = (x[:, None] - a[None, :, 0]) / (b[None, :, 0] - a[None, :, 0])
    y = np.where(crosses, a[None, :, 1] + t * (b[None, :, 1] - a[None, :, 1]), -np.inf)
    top = y.max(axis=1) if y.shape[1] else np.full(len(x), -np.inf)
    return np.where(np.isfinite(top), top, np.nan)


def out_of_slope(polygons: Sequence[np.ndarray], gravity) -> float | None:
    """The horizontal direction out of the slope: +1 along ``across`` (the horizontal across
    gravity, +x for gravity along -y), -1 against it; None for ground whose two ends stand as
    high (level ground, a valley, a mound).

    The ground surface is the bodies' upper outline (the highest y over each x, as the
    surcharges see it); its ends lie 2 % of its width in from the outermost x. Out of the slope
    is the way from the higher end to the lower one (along gravity), which is the way gravity
    pulls along the surface on the whole (the work of gravity along a path depends on its ends
    alone): on a slope with gravity along -y, towards its toe; on an infinite slope modelled with
    gravity rotated, down the slope.
    """
    g = np.asarray(gravity, dtype=float)
    gn = float(np.linalg.norm(g))
    pts = np.vstack([np.asarray(p, dtype=float) for p in polygons])
    x_lo, x_hi = float(pts[:, 0].min()), float(pts[:, 0].max())
    width = x_hi - x_lo
    if not (width > 0.0 and gn > 0.0):
        return None
    xs = np.array([x_lo + 0.02 * width, x_hi - 0.02 * width])
    ys = ground_height(polygons, xs)
    if not np.all(np.isfinite(ys)):
        return None
    ends = np.c_[xs, ys]
    drop = float((ends[1] - ends[0]) @ g) / gn  # how far the right end lies below the left, along gravity
    down = pts @ (g / gn)
    if abs(drop) <= LEVEL_FRACTION * max(float(down.max() - down.min()), 1e-12):
        return None
    way = ends[1] - ends[0] if drop > 0.0 else ends[0] - ends[1]
    across, _ = _frame(g)
    return 1.0 if float(way @ across) > 0.0 else -1.0


def _gaps(polygons: Sequence[np.ndarray], lo: float, hi: float) -> float | None:
    """The first x of ``[lo, hi]`` with no ground under it (None: ground all along)."""
    scale = max(abs(lo), abs(hi), hi - lo, 1.0)
    inset = 1e-9 * scale
    xs = np.linspace(lo + inset, hi - inset, GROUND_SAMPLES)
    bare = np.isnan(ground_height(polygons, xs))
    return float(xs[np.argmax(bare)]) if bare.any() else None


# ------------------------------------------------------------------------------ rules
def _num(value: Any) -> float | None:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    number = float(value)
    return number if math.isfinite(number) else None


def _polygons(data: Mapping[str, Any]) -> list[np.ndarray]:
    out = []
    bodies = data.get("bodies")
    for body in bodies if isinstance(bodies, list) else []:
        points = body.get("polygon_m") if isinstance(body, Mapping) else None
        try:
            arr = np.asarray(points, dtype=float)
        except (TypeError, ValueError):
            continue
        if arr.ndim == 2 and arr.shape[1] == 2 and len(arr) >= 3 and np.all(np.isfinite(arr)):
            out.append(arr)
    return out


def _gravity(data: Mapping[str, Any]) -> tuple[float, float] | None:
    domain = data.get("domain")
    value = domain.get("gravity_m_s2", (0.0, -9.81)) if isinstance(domain, Mapping) else (0.0, -9.81)
    if isinstance(value, (list, tuple)) and len(value) == 2 and all(_num(v) is not None for v in value):
        return (float(value[0]), float(value[1]))
    return None


def load_rules(data: Mapping[str, Any]) -> list[tuple[str, Any, str]]:
    """The rules of the stages' ``surcharges`` and ``seismic`` beyond their types and ranges.

    A surcharge lies over the ground (a body under every x of its segment), its names are unique
    within its stage, it ramps only on a dynamic stage; no surcharges on a k0 stage; seismic
    coefficients on dynamic and strength-reduction stages only, with a gravity, and a slope to
    point out of when ``towards = "out-of-slope"``. Each problem as (path, value, message), the
    fields of a projects.schema.Problem (which this module does not import: the schema imports it).
    """
    stages = data.get("stages")
    if not isinstance(stages, list):
        return []
    problems: list[tuple[str, Any, str]] = []
    polygons = None
    gravity = _gravity(data)
    for index, stage in enumerate(stages):
        if not isinstance(stage, Mapping):
            continue
        path = f"stages.{index}"
        kind = stage.get("type")
        loads = stage.get("surcharges")
        if "surcharges" in stage and kind == "k0":
            problems.append((f"{path}.surcharges", None, "not allowed on a k0 stage (it sets the stress from "
                                    "the overburden alone): give the loads on a gravity stage, where they ramp up "
                                    "with gravity, or on a later stage"))
        elif isinstance(loads, list) and loads:
            if gravity is not None and gravity == (0.0, 0.0):
                problems.append((f"{path}.surcharges", None, "needs a gravity (domain.gravity_m_s2): a "
                                        "surcharge acts along it"))
            if polygons is None:
                polygons = _polygons(data)
            seen: dict[str, int] = {}
            for k, load in enumerate(loads):
                if not isinstance(load, Mapping):
                    continue
                here = f"{path}.surcharges.{k}"
                name = load.get("name")
                if isinstance(name, str):
                    if name in seen:
                        problems.append((f"{here}.name", name, f"is used twice in this stage ({path}."
                                                f"surcharges.{seen[name]} is one): a load's name carries it from "
                                                "stage to stage"))
                    seen.setdefault(name, k)
                if load.get("ramp") is True and kind != "dynamic":
                    why = ("its loads ramp up with gravity" if kind == "gravity" else
                           "its trials apply the loads at full value")
                    problems.append((f"{here}.ramp", True, f"only allowed on a dynamic stage ({kind}: {why})"))
                lo, hi = _num(load.get("from_m")), _num(load.get("to_m"))
                if lo is not None and hi is not None and not hi > lo:
                    problems.append((f"{here}.to_m", load.get("to_m"), f"must be > from_m ({lo:g}): the load "
                                            "lies between them"))
                    continue
                if lo is None or hi is None or not polygons:
                    continue
                bare = _gaps(polygons, lo, hi)
                if bare is not None:
                    pts = np.vstack(polygons)
                    side = "to_m" if bare > 0.5 * (lo + hi) else "from_m"
                    problems.append((f"{here}.{side}", load.get(side),
                                            f"the segment x = {lo:g} to {hi:g} m runs off the ground at "
                                            f"x = {bare:.4g} m "
                                            f"(no body under it; the bodies span x = {pts[:, 0].min():g} to "
                                            f"{pts[:, 0].max():g} m)"))
        seismic = stage.get("seismic")
        if "seismic" in stage:
            if kind in ("k0", "gravity"):
                problems.append((f"{path}.seismic", None, f"not allowed on a {kind} stage (the initial stress "
                                        "is static): give the coefficients on the strength-reduction or dynamic "
                                        "stage after it"))
                continue
            if not isinstance(seismic, Mapping):
                continue
            if not any(key in seismic for key in ("k_h", "k_v")):
                problems.append((f"{path}.seismic", None, "needs k_h or k_v (the pseudo-static coefficients)"))
            if gravity is not None and gravity == (0.0, 0.0):
                problems.append((f"{path}.seismic", None, "needs a gravity (domain.gravity_m_s2): the "
                                        "coefficients are fractions of it"))
            k_h = _num(seismic.get("k_h"))
            towards = seismic.get("towards", "out-of-slope")
            if towards == "out-of-slope" and k_h is not None and k_h > 0.0 and gravity is not None \
                    and gravity != (0.0, 0.0):
                if polygons is None:
                    polygons = _polygons(data)
                if polygons and out_of_slope(polygons, gravity) is None:
                    problems.append((f"{path}.seismic.towards", "out-of-slope", "the ground is as high at both "
                                            "ends (no slope to point out of): give towards = \"left\" or \"right\""))
    return problems


# ------------------------------------------------------------------------------ the solver's form
def solver_surcharge(load) -> sc.Surcharge:
    """One ``[[stages.surcharges]]`` entry (projects.schema.Surcharge) in the solver's form."""
    start, end = load.pressures_pa
    return sc.Surcharge(name=load.name, from_m=float(load.from_m), to_m=float(load.to_m), pressure_pa=start,
                        pressure_end_pa=None if end == start else end)


def seismic_direction(project, towards: str) -> float:
    """+1 or -1 along the horizontal across gravity (+x for gravity along -y) for ``towards``."""
    if towards == "right":
        return 1.0
    if towards == "left":
        return -1.0
    direction = out_of_slope([np.asarray(b.polygon_m, dtype=float) for b in project.bodies],
                             project.domain.gravity_m_s2)
    if direction is None:  # the rules refuse this; a level ground has no out of the slope
        raise ValueError('seismic.towards = "out-of-slope": the ground is as high at both ends; name "left" or "right"')
    return direction


def solver_seismic(project, stage) -> sc.Seismic | None:
    """A project stage's seismic coefficients in the solver's form (None: none)."""
    s = stage.seismic
    if s is None or (s.k_h == 0.0 and s.k_v == 0.0):
        return None
    direction = seismic_direction(project, s.towards) if s.k_h > 0.0 else 1.0
    return sc.Seismic(k_h=float(s.k_h), k_v=float(s.k_v), direction=direction)


def stage_loads(project) -> list[tuple[tuple[sc.Surcharge, ...], tuple[sc.Surcharge, ...] | None, sc.Seismic | None]]:
    """The loads of each stage of a project: ``(surcharges, surcharges_from, seismic)``.

    ``surcharges``: the loads in force during the stage (at its end); ``surcharges_from``: where
    a load ramps, the loads at the stage's start (a ramped load's namesake in force before, none
    for a new one; the others as they are), else None; ``seismic``: the stage's coefficients.
    """
    out = []
    current: tuple[sc.Surcharge, ...] = ()
    for stage in project.stages:
        start = None
        if stage.surcharges is not None:
            before = {load.name: load for load in current}
            new = tuple(solver_surcharge(load) for load in stage.surcharges)
            if any(load.ramp for load in stage.surcharges):
                start = tuple(x for x in (before.get(s.name) if given.ramp else s
                                          for s, given in zip(new, stage.surcharges)) if x is not None)
            current = new
        out.append((current, start, solver_seismic(project, stage)))
    return out


def describe(project) -> list[dict[str, Any]]:
    """The loads of each stage, for reports and the workbench: per stage its ``stage`` label,
    ``surcharges`` (name, from_m, to_m, pressure_pa [at from_m, at to_m], force_n_per_m, ramp)
    and ``seismic`` (k_h, k_v, towards, direction) or None."""
    rows = []
    for stage, (loads, start, seismic) in zip(project.stages, stage_loads(project)):
        ramped = {s.name for s in (stage.surcharges or ()) if s.ramp}
        rows.append({
            "stage": stage.label,
            "surcharges": [{"name": s.name, "from_m": s.from_m, "to_m": s.to_m,
                            "pressure_pa": [s.pressure_pa, s.pressure_pa if s.pressure_end_pa is None
                                            else s.pressure_end_pa],
                            "force_n_per_m": s.force_n_per_m, "ramp": s.name in ramped and start is not None}
                           for s in loads],
            "seismic": None if seismic is None else {
                "k_h": seismic.k_h, "k_v": seismic.k_v, "towards": stage.seismic.towards,
                "direction": "right" if seismic.direction > 0 else "left"},
        })
    return rows
