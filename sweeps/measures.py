"""Measures and profiles of one finished run, read from its results folder.

Measure keys are dotted paths (list items by index):

- ``summary.KEY``: a key of ``summary.json`` (``summary.wall_time_s``, ``summary.steps``, ...).
- ``hazard.KEY``: a key of ``hazard.json`` (``hazard.runout_distance_m``, ``hazard.travel_angle_deg``,
  ``hazard.targets.NAME.arrival_time_s``...), where the run wrote one.
- ``deposit.KEY``: measured on the last frame's active particles with the deposit measures of
  :mod:`projects.measures` (lengths in m, heights above y = 0): ``front_m`` (furthest particle edge),
  ``toe_m`` (furthest edge where the deposit is at least 2 mm thick), ``reach_m`` (the same at
  5 mm), ``crest_m`` (highest particle top within 10 mm of x = 0), ``height_m`` (highest particle
  top anywhere), ``max_displacement_m`` (largest particle displacement).

A key that the run did not produce reads as NaN.

Profiles along the section: ``deposit_height_m`` (the final free surface ``h(x)`` of
:func:`projects.measures.surface_heights`, on a grid of one particle spacing over the domain) or any
column of the run's ``hazard_profile.csv`` (the envelopes; the station column is ``x_m``, else the
first column).
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from projects import measures
from sweeps.spec import DEPOSIT_PROFILE_FIELD

DEPOSIT_KEYS = ("front_m", "toe_m", "reach_m", "crest_m", "height_m", "max_displacement_m")


def lookup(data: Any, path: Sequence[str]) -> Any:
    """The value at a dotted path in nested dicts/lists, or None where there is none."""
    node = data
    for part in path:
        if isinstance(node, Mapping) and part in node:
            node = node[part]
        elif isinstance(node, list) and part.isdigit() and int(part) < len(node):
            node = node[int(part)]
        else:
            return None
    return node


def as_number(value: Any) -> float:
    """A float for a JSON value (NaN for null, missing, text or booleans)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return math.nan
    return float(value)


def _read_json(path: Path) -> dict[str, Any] | None:
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None


class _LastFrame:
    """The last frame of a results folder, read once on first use."""

    def __init__(self, results_dir: Path, summary: Mapping[str, Any]) -> None:
        self.dir = results_dir
        self.summary = summary
        self._arrays: dict[str, np.ndarray] | None = None

    @property
    def spacing_m(self) -> float:
        s = as_number(self.summary.get("particle_spacing_m"))
        return s if math.isfinite(s) and s > 0 else 0.0

    def arrays(self) -> dict[str, np.ndarray]:
        if self._arrays is None:
            from projects.results import Results

            self._arrays = dict(Results(self.dir).frame(-1))
        return self._arrays

    def deposit(self, key: str) -> float:
        a = self.arrays()
        pos, active, s = a["positions"], a.get("active"), self.spacing_m
        if key == "front_m":
            return measures.front_position(pos, active, s)
        if key == "toe_m":
            return measures.toe_position(pos, active, s)
        if key == "reach_m":
            return measures.toe_position(pos, active, s, measures.REACH_THICKNESS_M)
        if key == "crest_m":
            return measures.crest_height(pos, active, s)
        if key == "height_m":
            return measures.top_height(pos, active, s)
        if key == "max_displacement_m":
            return measures.max_displacement(a.get("displacement"), active)
        return math.nan

    def surface(self, x_m: np.ndarray) -> np.ndarray:
        a = self.arrays()
        return measures.surface_heights(a["positions"], a.get("active"), self.spacing_m, x_m)


def read_measures(results_dir: str | Path, keys: Iterable[str]) -> dict[str, float]:
    """The values of measure keys for one results folder (NaN where absent).

    Parameters
    ----------
    results_dir : path
    keys : iterable of str
        ``summary.*``, ``hazard.*`` or ``deposit.*`` (see the module docstring).

    Returns
    -------
    dict of str to float
    """
    d = Path(results_dir)
    summary = _read_json(d / "summary.json") or {}
    hazard = None
    frame = _LastFrame(d, summary)
    out: dict[str, float] = {}
    for key in keys:
        head, _, rest = key.partition(".")
        value = math.nan
        try:
            if head == "summary":
                value = as_number(lookup(summary, rest.split(".")))
            elif head == "hazard":
                if hazard is None:
                    hazard = _read_json(d / "hazard.json") or {}
                value = as_number(lookup(hazard, rest.split(".")))
            elif head == "deposit" and rest in DEPOSIT_KEYS:
                value = frame.deposit(rest)
        except (OSError, ValueError, KeyError, IndexError):  # no readable frame: the measure is absent
            value = math.nan
        out[key] = float(value)
    return out


def surface_at(results_dir: str | Path, x_m: Sequence[float]) -> list[float]:
    """The final free-surface height at ``x_m`` (m; :func:`projects.measures.surface_heights`)."""
    d = Path(results_dir)
    frame = _LastFrame(d, _read_json(d / "summary.json") or {})
    return [float(v) for v in frame.surface(np.asarray(x_m, dtype=float))]


def read_profile(results_dir: str | Path, field: str) -> tuple[list[float], list[float]] | None:
    """A profile along the section: ``(x_m, values)``, or None where the run has none.

    ``deposit_height_m``: the final surface on a grid of one particle spacing across the domain;
    else the column ``field`` of ``hazard_profile.csv``.
    """
    d = Path(results_dir)
    if field == DEPOSIT_PROFILE_FIELD:
        summary = _read_json(d / "summary.json") or {}
        frame = _LastFrame(d, summary)
        dom = summary.get("domain") or {}
        try:
            x0 = float(dom["origin_m"][0])
            width = float(dom["size_m"][0])
        except (KeyError, TypeError, IndexError, ValueError):
            return None
        step = frame.spacing_m or width / 200.0
        x = x0 + step * (np.arange(int(math.floor(width / step)) + 1))
        try:
            return [float(v) for v in x], [float(v) for v in frame.surface(x)]
        except (OSError, ValueError, KeyError, IndexError):
            return None
    path = d / "hazard_profile.csv"
    try:
        with open(path, encoding="utf-8", newline="") as fh:
            rows = list(csv.reader(line for line in fh if line.strip() and not line.startswith("#")))
    except OSError:
        return None
    if len(rows) < 2:
        return None
    header = [h.strip() for h in rows[0]]
    if field not in header:
        return None
    ix = header.index("x_m") if "x_m" in header else 0
    iv = header.index(field)
    xs, vs = [], []
    for row in rows[1:]:
        try:
            xs.append(float(row[ix]))
            vs.append(float(row[iv]) if row[iv].strip() else math.nan)
        except (ValueError, IndexError):
            continue
    return (xs, vs) if xs else None
