"""Deposit and run-out measures of a set of particles (numpy only), and observed profiles.

Measured on a frame's active particles (all lengths in m, ``s`` the initial particle spacing, a
particle a square of side ``s`` around its position):

- **surface** ``h(x)`` (:func:`surface_heights`): the highest particle top ``y_p + s/2`` among the
  particles whose ``x_p`` lies within ``w/2`` of ``x`` (a sliding window of width
  ``w = max(5 mm, 2 s)``, :func:`surface_window`); the ground height where the window holds no
  particle.
- **thickness** for the toe: the same with a narrow window ``|x_p - x| <= s`` (the neighbouring
  particle columns only).
- **toe** (:func:`toe_position`): the furthest particle edge ``x_p + s/2`` among the particles whose
  local thickness is at least ``thickness_m`` (default 2 mm, :data:`TOE_THICKNESS_M`). A single
  layer of particles is ``s`` thick, so at spacings of 2 mm and more every particle counts: a
  coarse run cannot resolve a 2 mm threshold.
- **reach**: the toe at 5 mm (:data:`REACH_THICKNESS_M`): the run-out of the body of the deposit.
  A deposit's tail may be only a few millimetres thick over several centimetres, so the 2 mm toe
  moves by centimetres when the tail's thickness changes by a fraction of a millimetre; the reach
  is the well-conditioned run-out measure for comparing runs.
- **front** (:func:`front_position`): the furthest particle edge ``x_p + s/2`` (any thickness).
- **crest** (:func:`crest_height`): the highest particle top within 10 mm of the back wall.
- **height** (:func:`top_height`): the highest particle top anywhere.
- **largest displacement** (:func:`max_displacement`): of any active particle, in the plane.
- **RMS deviation** (:func:`rms_deviation`): ``sqrt(mean((h(x_k) - y_k)^2))`` against reference
  heights ``y_k`` (an observed profile's points, or another run's surface).

The run-out measures of a whole run along its run-out direction, from the hazard envelopes, are in
:mod:`projects.hazard`.
"""

from __future__ import annotations

import csv
import math
import os

import numpy as np

#: Toe: the deposit is at least this thick there (m).
TOE_THICKNESS_M = 0.002
#: Thickness of the "reach", the well-conditioned run-out measure (m).
REACH_THICKNESS_M = 0.005
#: Crest: the highest particle top within this distance of the back wall (m).
CREST_WINDOW_M = 0.010
#: Smallest window of the surface envelope (m).
SURFACE_WINDOW_M = 0.005


def _active_xy(positions: np.ndarray, active: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    pos = np.asarray(positions, dtype=float)
    if active is not None:
        pos = pos[np.asarray(active, dtype=bool)]
    pos = pos[np.all(np.isfinite(pos), axis=1)]
    return pos[:, 0], pos[:, 1]


def surface_window(spacing_m: float) -> float:
    """Width of the surface envelope's sliding window, ``max(5 mm, 2 s)`` (m)."""
    return max(SURFACE_WINDOW_M, 2.0 * spacing_m)


def surface_heights(positions: np.ndarray, active: np.ndarray | None, spacing_m: float,
                    x_query: np.ndarray, window_m: float | None = None, base_m: float = 0.0) -> np.ndarray:
    """Free-surface height at ``x_query``: the highest particle top within half a window.

    Parameters
    ----------
    positions : numpy.ndarray, shape (N, 2)
        Particle positions, m.
    active : numpy.ndarray, shape (N,), bool, optional
    spacing_m : float
        Initial particle spacing ``s``; a particle's top is ``y + s/2``.
    x_query : numpy.ndarray, shape (K,)
        Where to evaluate, m.
    window_m : float, optional
        Window width (default :func:`surface_window`).
    base_m : float
        Height of the ground: the result is at least this (no particle in the window).

    Returns
    -------
    numpy.ndarray, shape (K,)
        Surface heights, m.
    """
    x, y = _active_xy(positions, active)
    w = surface_window(spacing_m) if window_m is None else window_m
    xq = np.asarray(x_query, dtype=float)
    out = np.full(xq.shape, base_m, dtype=float)
    if x.size == 0:
        return out
    order = np.argsort(x)
    xs, ys = x[order], y[order] + 0.5 * spacing_m
    lo = np.searchsorted(xs, xq - 0.5 * w, side="left")
    hi = np.searchsorted(xs, xq + 0.5 * w, side="right")
    for k, (a, b) in enumerate(zip(lo, hi)):
        if b > a:
            out[k] = max(base_m, float(ys[a:b].max()))
    return out


def toe_position(positions: np.ndarray, active: np.ndarray | None, spacing_m: float,
                 thickness_m: float = TOE_THICKNESS_M, base_m: float = 0.0) -> float:
    """Furthest particle edge ``x_p + s/2`` where the deposit is at least ``thickness_m`` thick.

    The local thickness at a particle is the highest particle top (above ``base_m``) within one
    spacing of it in x. Returns NaN when no particle qualifies.
    """
    x, y = _active_xy(positions, active)
    if x.size == 0:
        return math.nan
    local = surface_heights(positions, active, spacing_m, x, window_m=2.0 * spacing_m, base_m=base_m) - base_m
    ok = local >= thickness_m - 1e-9
    return float(x[ok].max() + 0.5 * spacing_m) if ok.any() else math.nan


def front_position(positions: np.ndarray, active: np.ndarray | None, spacing_m: float) -> float:
    """Furthest particle edge ``x_p + s/2`` (m), NaN without particles."""
    x, _ = _active_xy(positions, active)
    return float(x.max() + 0.5 * spacing_m) if x.size else math.nan


def crest_height(positions: np.ndarray, active: np.ndarray | None, spacing_m: float,
                 wall_x_m: float = 0.0, window_m: float = CREST_WINDOW_M) -> float:
    """Highest particle top ``y_p + s/2`` within ``window_m`` of the back wall (m)."""
    x, y = _active_xy(positions, active)
    near = x <= wall_x_m + window_m
    return float(y[near].max() + 0.5 * spacing_m) if near.any() else math.nan


def top_height(positions: np.ndarray, active: np.ndarray | None, spacing_m: float) -> float:
    """Highest particle top ``y_p + s/2`` anywhere (m), NaN without particles."""
    _, y = _active_xy(positions, active)
    return float(np.max(y) + 0.5 * spacing_m) if y.size else math.nan


def max_displacement(displacement: np.ndarray | None, active: np.ndarray | None) -> float:
    """Largest in-plane displacement of the active particles (m), NaN without particles."""
    if displacement is None or not len(displacement):
        return math.nan
    d = np.asarray(displacement, dtype=float)
    if active is not None:
        d = d[np.asarray(active, dtype=bool)]
    return float(np.max(np.linalg.norm(d[:, :2], axis=1))) if len(d) else math.nan


def rms_deviation(heights: np.ndarray, reference: np.ndarray) -> float:
    """Root-mean-square of ``heights - reference`` (m), NaN for no points."""
    d = np.asarray(heights, dtype=float) - np.asarray(reference, dtype=float)
    return float(np.sqrt(np.mean(d * d))) if d.size else math.nan


def read_xy_csv(path: str | os.PathLike[str]) -> np.ndarray:
    """An observed profile: the first two numeric columns of a CSV file, shape (K, 2).

    Lines starting with ``#`` and rows that are not two numbers (a header line) are skipped. The
    file is read as :func:`projects.inputs.read_text` reads it: a regular file of at most
    :data:`projects.inputs.MAX_OBSERVATION_FILE_BYTES` (a FIFO or ``/dev/zero`` would hang).

    Raises
    ------
    ValueError
        The file cannot be read, is not a regular file or too large, holds no ``x, y`` rows, or a
        row with a value that is not a finite number (nan, inf).
    """
    from projects.inputs import MAX_OBSERVATION_FILE_BYTES, read_text
    from projects.schema import ProjectError

    try:
        text = read_text(path, what="the file", max_bytes=MAX_OBSERVATION_FILE_BYTES)
    except ProjectError as exc:
        raise ValueError(exc.problems[0].message) from None
    points = []
    lines = (line for line in text.splitlines() if line.strip() and not line.lstrip().startswith("#"))
    for number, row in enumerate(csv.reader(lines), start=1):
        try:
            x, y = float(row[0]), float(row[1])
        except (ValueError, IndexError):
            continue  # the header line
        if not (math.isfinite(x) and math.isfinite(y)):
            raise ValueError(f"{path}: data row {number} ({', '.join(row[:2])}) is not two finite numbers")
        points.append((x, y))
    if not points:
        raise ValueError(f"{path} holds no x, y rows")
    return np.asarray(points, dtype=float)
