"""A structure's force split into its normal and tangential parts, on the face that carries it.

The solver gives, per output interval, the mean force the material exerts on a structure
(``force_x``, ``force_y``, N per metre) and its moment about the grid origin (``contacts.csv``).
For a check dam the engineer asks for the thrust on its upstream face and the drag along it: the
force's parts along that face's normal and tangent. The **loaded face** of an interval is the face
where the mean force's line of action (the points ``p`` with ``(p - origin) x F = M``) enters the
structure, travelling along ``F`` (the direction the material pushes in): the upstream face of a
dam, the bed of a slide on bedrock. Without a line of action (no moment recorded) it is the face
whose outward normal is most opposed to ``F``, each face weighted by its length.

On that face, with ``n`` its outward unit normal and ``t`` its unit tangent:

- **normal** ``N = -F . n``: positive when the material presses on the face;
- **tangential** ``T = F . t``, ``t`` pointing up (+y) along a face steeper than 45 degrees and
  along +x along a flatter one (the closed sides' convention: +y for left and right, +x for bottom
  and top), so that a slide dragging a dam's face downwards gives ``T < 0``.

A structure loaded on two faces at once (a dam overtopped, its crest carrying weight while its
face takes the thrust) has one resultant: its parts are on the face the resultant passes through.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np


def faces(polygon_m: Sequence[Sequence[float]]) -> list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
    """The faces of a polygon: ``(a, b, n, t)`` per edge, ``n`` the outward unit normal and ``t``
    the tangent of the module's convention; zero-length edges left out."""
    pts = np.asarray(polygon_m, dtype=float).reshape(-1, 2)
    if len(pts) < 3:
        return []
    x, y = pts[:, 0], pts[:, 1]
    ccw = 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y)) > 0
    out = []
    for a, b in zip(pts, np.roll(pts, -1, axis=0), strict=True):
        d = b - a
        length = float(np.hypot(*d))
        if not length > 0:
            continue
        # right of a counter-clockwise edge is outside
        n = np.array([d[1], -d[0]]) / length if ccw else np.array([-d[1], d[0]]) / length
        t = np.array([-n[1], n[0]])
        if abs(n[0]) >= abs(n[1]):  # steeper than 45 degrees: t along +y
            t = t if t[1] >= 0 else -t
        else:
            t = t if t[0] >= 0 else -t
        out.append((a, b, n, t))
    return out


def loaded_face(polygon_m: Sequence[Sequence[float]], force: tuple[float, float], moment: float,
                origin_m: Sequence[float] = (0.0, 0.0)) -> int | None:
    """The index (into :func:`faces`) of the face that carries ``force`` (module docstring); None
    for a zero force or a polygon without faces."""
    fs = faces(polygon_m)
    f = np.asarray(force, dtype=float)
    size = float(np.hypot(*f))
    if not fs or not (size > 0 and math.isfinite(size)):
        return None
    u = f / size
    if math.isfinite(moment):
        o = np.asarray(origin_m, dtype=float)
        # a point of the line of action, relative to the origin: p x F = M with p = off * (fy, -fx)
        p0 = o + (moment / (size * size)) * np.array([f[1], -f[0]])
        best, best_s = None, math.inf
        for k, (a, b, n, _t) in enumerate(fs):
            if float(np.dot(n, u)) >= 0:  # the line leaves the structure here
                continue
            d = b - a
            det = u[0] * (-d[1]) - u[1] * (-d[0])
            if abs(det) < 1e-15:
                continue
            r = a - p0
            s = (r[0] * (-d[1]) - r[1] * (-d[0])) / det
            w = (u[0] * r[1] - u[1] * r[0]) / det
            if -1e-9 <= w <= 1.0 + 1e-9 and s < best_s:
                best, best_s = k, s
        if best is not None:
            return best
    scores = [-float(np.dot(n, u)) * float(np.hypot(*(b - a))) for a, b, n, _t in fs]
    return int(np.argmax(scores))


def components(polygon_m: Sequence[Sequence[float]], force: tuple[float, float], moment: float,
               origin_m: Sequence[float] = (0.0, 0.0), face: int | None = None) -> tuple[float, float, int | None]:
    """``(normal, tangential, face)`` of ``force`` on the loaded face (or on ``face``, the
    index into :func:`faces`, when given); ``(nan, nan, None)`` for a zero force on no given face."""
    fs = faces(polygon_m)
    k = face if face is not None else loaded_face(polygon_m, force, moment, origin_m)
    if k is None or not 0 <= k < len(fs):
        return math.nan, math.nan, None
    _a, _b, n, t = fs[k]
    f = np.asarray(force, dtype=float)
    return float(-np.dot(f, n)) + 0.0, float(np.dot(f, t)) + 0.0, int(k)


def contact_peaks(columns: dict[str, np.ndarray]) -> dict[str, float | None]:
    """The peaks of one contact's rows of :func:`projects.results.read_contacts`: the largest
    single-step force ``peak_force_N_per_m`` with its components and ``peak_time_s`` (the end of
    the interval that held it); the largest interval mean ``max_mean_force_N_per_m`` and its
    time; the largest interval-mean normal force ``max_normal_force_N_per_m`` and the largest
    tangential one by size (signed) ``max_tangential_force_N_per_m``, each with its time (None
    where the rows have no normal or tangential part). N per metre, s."""
    t = np.asarray(columns.get("time_s", []), dtype=float)
    if not len(t):
        return {}
    nan = np.full(len(t), np.nan)

    def col(key: str) -> np.ndarray:
        return np.asarray(columns.get(key, nan), dtype=float)

    peak = np.nan_to_num(col("peak_force_N_per_m"))
    mean = np.hypot(np.nan_to_num(col("force_x_N_per_m")), np.nan_to_num(col("force_y_N_per_m")))
    i, j = int(np.argmax(peak)), int(np.argmax(mean))
    out: dict[str, float | None] = {
        "peak_force_N_per_m": float(peak[i]), "peak_force_x_N_per_m": float(np.nan_to_num(col("peak_force_x_N_per_m")[i])),
        "peak_force_y_N_per_m": float(np.nan_to_num(col("peak_force_y_N_per_m")[i])), "peak_time_s": float(t[i]),
        "max_mean_force_N_per_m": float(mean[j]), "max_mean_force_time_s": float(t[j]),
        "max_normal_force_N_per_m": None, "max_normal_force_time_s": None,
        "max_tangential_force_N_per_m": None, "max_tangential_force_time_s": None,
    }
    normal, tangential = col("force_normal_N_per_m"), col("force_tangential_N_per_m")
    if np.isfinite(normal).any():
        k = int(np.nanargmax(normal))
        out.update(max_normal_force_N_per_m=float(normal[k]), max_normal_force_time_s=float(t[k]))
    if np.isfinite(tangential).any():
        k = int(np.nanargmax(np.abs(tangential)))
        out.update(max_tangential_force_N_per_m=float(tangential[k]) + 0.0, max_tangential_force_time_s=float(t[k]))
    return out
