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

A key that the run did not produce reads as NaN. Keys are checked before any run
(:func:`measure_problems`): a source other than these three, a deposit measure not listed, a
summary or hazard key no run writes, a target or structure the project does not have, each is one
line naming the key.

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
from sweeps.spec import DEPOSIT_KEYS, DEPOSIT_PROFILE_FIELD

#: The top-level keys of a run's ``summary.json`` (docs/results.md): the writer's, the resolved run's
#: (projects.build.ResolvedRun.meta), the runner's and a strength-reduction run's.
SUMMARY_KEYS = frozenset({
    "status", "message", "title", "scheme", "arch", "precision", "particles", "steps", "simulated_time_s",
    "wall_time_s", "particle_steps_per_s", "frames", "runout_version", "results_format_version", "started_at",
    "finished_at", "resumed_at_frame", "contacts", "total_time_s", "stages", "materials", "bodies", "structures",
    "domain", "particle_spacing_m", "output_interval_s", "preset", "checkpoint_interval_s", "project_file",
    "project_unsaved", "started_from", "setup_time_s", "initial_equilibrium", "water_at_failure",
    "critical_time_step_s", "time_step_shrink_by_damping", "startup_s", "startup_cpu_s", "warnings",
    "still_moving", "motion_at_end", "factor_of_safety", "limit_equilibrium",
})


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
        self._measured: np.ndarray | None = None

    @property
    def spacing_m(self) -> float:
        s = as_number(self.summary.get("particle_spacing_m"))
        return s if math.isfinite(s) and s > 0 else 0.0

    def arrays(self) -> dict[str, np.ndarray]:
        if self._arrays is None:
            from projects.results import Results

            results = Results(self.dir)
            self._arrays = dict(results.frame(-1))
            self._measured = results.measured(self._arrays)  # rigid bodies left out
        return self._arrays

    def deposit(self, key: str) -> float:
        a = self.arrays()
        pos, active, s = a["positions"], self._measured, self.spacing_m
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
        return measures.surface_heights(a["positions"], self._measured, self.spacing_m, x_m)


def _hazard_skeleton(project: Any) -> dict[str, Any] | None:
    """The keys ``hazard.json`` of a run of ``project`` has: the document of a run that released
    nothing (projects.hazard.hazard_document), with the project's targets and structures; None
    where it cannot be made (then hazard keys are not checked)."""
    from projects import hazard
    from solver import config as sc

    snap = {"release_time_s": 0.0, "time_s": 0.0, "started": False, "shape": (1, 1), "origin_m": (0.0, 0.0),
            "cell_size_m": 1.0, "series": np.zeros((0, 1)), "every_steps": 1}
    try:
        targets = tuple(sc.Target(t.name, *t.xy) for t in project.targets)
        doc = hazard.hazard_document(snap, hazard.settings(project), tuple(project.domain.gravity_m_s2), targets,
                                     "completed")
    except Exception:  # noqa: BLE001 - a check that cannot be made is not a problem of the sweep file
        return None
    doc.setdefault("still_moving", None)
    doc.setdefault("motion_at_end", None)
    doc["structures"] = {st.name: None for st in project.structures}
    return doc


def measure_problems(keys: Sequence[str], project: Any, where: str) -> list[Any]:
    """The measure keys no run of ``project`` can produce, one :class:`~projects.schema.Problem` each.

    Parameters
    ----------
    keys : sequence of str
        ``summary.*``, ``hazard.*``, ``deposit.*`` (their syntax checked by sweeps.spec).
    project : projects.schema.Project
        The base project (targets, structures, whether it writes hazard.json).
    where : str
        The key path of the list (``sweep.measures``, ``observation.values``).

    Returns
    -------
    list of Problem
    """
    from projects.schema import Problem

    problems: list[Any] = []
    skeleton: dict[str, Any] | None | bool = False  # made at the first hazard key
    for index, key in enumerate(keys):
        path = f"{where}.{index}" if where.endswith("measures") else f'{where}."{key}"'
        head, _, rest = key.partition(".")
        parts = rest.split(".")
        if head == "summary" and parts[0] not in SUMMARY_KEYS:
            problems.append(Problem(path, key, f"summary.json has no key {parts[0]!r}{_guess(parts[0], SUMMARY_KEYS)} "
                                    "(docs/results.md lists its keys)"))
        elif head == "hazard":
            if not project.hazard.enabled:
                problems.append(Problem(path, key, "hazard.enabled is false in the project: its runs write no "
                                        "hazard.json"))
                continue
            if skeleton is False:
                skeleton = _hazard_skeleton(project)
            if skeleton is None:
                continue
            problem = _hazard_key_problem(parts, skeleton)
            if problem:
                problems.append(Problem(path, key, problem))
    return problems


def _guess(word: str, choices: Iterable[str]) -> str:
    import difflib

    close = difflib.get_close_matches(word, list(choices), n=1)
    return f" (did you mean {close[0]!r}?)" if close else ""


def _hazard_key_problem(parts: list[str], doc: Mapping[str, Any]) -> str:
    """Why ``hazard.PARTS`` names nothing hazard.json holds ("" when it may)."""
    def listed(names: Iterable[str]) -> str:
        names = list(names)
        return ", ".join(names) if names else "none"

    top = parts[0]
    if top not in doc:
        return f"hazard.json has no key {top!r}{_guess(top, doc)}; its measures: " + listed(
            k for k, v in doc.items() if not isinstance(v, Mapping) and k not in ("note", "direction_rule"))
    value = doc[top]
    if len(parts) == 1 or not isinstance(value, Mapping):
        return ""
    name = parts[1]
    if top in ("targets", "structures"):
        if name not in value:
            what = "target" if top == "targets" else "structure"
            return f"the project has no {what} {name!r}; its {top}: {listed(value)}"
        inner = value[name]
        if len(parts) > 2 and isinstance(inner, Mapping) and inner and parts[2] not in inner:
            return f"a target has no key {parts[2]!r}; its keys: {listed(inner)}"
        return ""
    if value and name not in value:
        return f"hazard.json's {top} has no key {name!r}; its keys: {listed(value)}"
    return ""


def still_moving(summary: Mapping[str, Any] | None) -> bool | None:
    """Whether a run ended with the mass still moving, from its ``summary.json`` (``summary``):
    :func:`projects.motion.provisional`; None where it holds no verdict (no dynamic stage ran, an
    older run, no summary)."""
    from projects.motion import provisional

    if not isinstance(summary, Mapping):
        return None
    if not isinstance(summary.get("still_moving"), bool) and not isinstance(summary.get("motion_at_end"), Mapping):
        return None
    return provisional(summary)


def read_still_moving(results_dir: str | Path) -> bool | None:
    """:func:`still_moving` of the ``summary.json`` in a results folder."""
    return still_moving(_read_json(Path(results_dir) / "summary.json"))


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
