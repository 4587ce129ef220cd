"""The files a sweep or calibration folder shares, and reading a sweep folder back.

A sweep folder (:mod:`sweeps.sweep` writes it; the one interface to a sweep, live or finished)::

    sweep.json       the spec, the engine settings and the run plan
    progress.json    done / total / failed / elapsed_s / eta_s, rewritten after every run
    sweep.csv        one row per run (rewritten after every run; pending runs included); its
                     still_moving column marks the runs whose measures are provisional
    exceedance.csv   P(measure > x) with the DKW band, per measure
    profile.csv      P(profile field > threshold) along the section, with Wilson bands
    sensitivity.csv  Spearman rank correlation of each parameter with each measure
    report.html      plots and tables (``runout report SWEEP_DIR`` writes it again)
    runs/ID.toml     the resolved project of each run, runs/ID/ its results, runs/ID.json its record

A calibration folder (:mod:`sweeps.calibrate`) has ``calibration.csv``, ``calibration.json``,
the same ``progress.json`` (:class:`SweepProgress`), ``report.html`` and ``runs/``.
"""

from __future__ import annotations

import csv
import json
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from sweeps.engine import RUNS_DIR, RunRecord

CSV_NAME = "sweep.csv"
SPEC_NAME = "sweep.json"
PROGRESS_NAME = "progress.json"
REPORT_NAME = "report.html"
FIXED_COLUMNS = ("status", "message", "wall_time_s", "results_dir", "still_moving")
#: The mark of a provisional measure (a run that ended still moving) in reports and tables, and its legend.
PROVISIONAL_MARK = "*"
PROVISIONAL_LEGEND = ("* provisional: the run ended with the mass still moving, so the measure is where the mass "
                      "was when the run ended, not its final value")


def still_moving_cell(value: bool | None) -> str:
    """The ``still_moving`` cell of a CSV row: ``true``, ``false`` or empty (no verdict)."""
    return "" if value is None else ("true" if value else "false")


def row_still_moving(row: dict[str, str]) -> bool:
    """Whether a sweep.csv or calibration.csv row is a run that ended still moving."""
    return str(row.get("still_moving", "")).strip().lower() == "true"


@dataclass(frozen=True)
class SweepProgress:
    """Where a sweep stands (also written to ``progress.json``).

    Attributes
    ----------
    done, total, failed, reused : int
        Runs finished (any status), in the sweep, not completed, taken from an earlier sweep.
    elapsed_s, eta_s : float
        Wall time so far and estimated remaining, s (NaN before the first run ends).
    last : RunRecord or None
        The run that just ended.
    """

    done: int
    total: int
    failed: int
    reused: int
    elapsed_s: float
    eta_s: float
    last: RunRecord | None = None

    def to_json(self) -> dict[str, Any]:
        return {"done": self.done, "total": self.total, "failed": self.failed, "reused": self.reused,
                "elapsed_s": self.elapsed_s, "eta_s": None if not math.isfinite(self.eta_s) else self.eta_s}


@dataclass
class SweepData:
    """A sweep folder read back (finished or still running).

    Attributes
    ----------
    out_dir : Path
    parameters : list of str
        Parameter key paths (column order of sweep.csv).
    measures : list of str
    rows : list of dict
        sweep.csv rows (strings as written).
    spec : dict
        sweep.json ("spec", "settings", "runs").
    progress : dict
    """

    out_dir: Path
    parameters: list[str]
    measures: list[str]
    rows: list[dict[str, str]]
    spec: dict[str, Any]
    progress: dict[str, Any]

    def completed(self) -> list[dict[str, str]]:
        return [r for r in self.rows if r["status"] == "completed"]

    def still_moving(self) -> list[dict[str, str]]:
        """The completed runs that ended with the mass still moving (provisional measures)."""
        return [r for r in self.completed() if row_still_moving(r)]

    def still_moving_mask(self) -> np.ndarray:
        """Per completed run (in the order of :meth:`column`), whether it ended still moving."""
        return np.array([row_still_moving(r) for r in self.completed()], dtype=bool)

    def column(self, key: str, completed_only: bool = True) -> np.ndarray:
        """A numeric column (NaN for empty or text cells)."""
        rows = self.completed() if completed_only else self.rows
        return np.array([_float(r.get(key, "")) for r in rows], dtype=float)

    def values(self, key: str, completed_only: bool = True) -> list[Any]:
        """A parameter column as numbers where they are numbers, else the text."""
        rows = self.completed() if completed_only else self.rows
        out = []
        for r in rows:
            v = _float(r.get(key, ""))
            out.append(v if math.isfinite(v) else r.get(key, ""))
        return out

    def profile_field(self) -> str | None:
        prof = (self.spec.get("spec") or {}).get("profile")
        return prof.get("field") if prof else None

    def thresholds(self) -> list[float]:
        prof = (self.spec.get("spec") or {}).get("profile")
        return list(prof.get("thresholds") or []) if prof else []

    def profiles(self) -> list[tuple[list[float], list[float]]]:
        """The profile of each completed run (in row order; runs without one left out)."""
        out = []
        for r in self.completed():
            rec = read_record(self.out_dir / RUNS_DIR / f"{r['run_id']}.json")
            if rec is not None and rec.profile is not None:
                out.append(rec.profile)
        return out


def _float(text: str) -> float:
    try:
        return float(text)
    except (TypeError, ValueError):
        return math.nan


def read_record(path: Path) -> RunRecord | None:
    try:
        return RunRecord.from_json(json.loads(path.read_text(encoding="utf-8")))
    except (OSError, ValueError, KeyError, TypeError):
        return None


def fill_still_moving(rec: RunRecord, results: Path, path: Path) -> None:
    """A reused record written before records carried ``still_moving``: its verdict read from the
    kept results folder's ``summary.json``, and the record rewritten at ``path``."""
    if rec.still_moving is not None or not results.is_dir():
        return
    from projects.atomic import write_atomic
    from sweeps.measures import read_still_moving

    rec.still_moving = read_still_moving(results)
    if rec.still_moving is not None:
        write_atomic(path, json.dumps(rec.to_json()))


class SweepFolderError(Exception):
    """A folder is not a readable sweep folder."""


def is_sweep_dir(path: str | os.PathLike[str]) -> bool:
    """Whether a folder holds a sweep (``sweep.csv``) or a calibration (``calibration.csv``)."""
    p = Path(path)
    return p.is_dir() and ((p / CSV_NAME).is_file() or (p / "calibration.csv").is_file())


def read_table_and_json(out: Path, csv_name: str, json_name: str, kind: str) -> tuple[list[str], list[dict], Any]:
    """The header and rows of a folder's CSV table and its JSON file (sweep and calibration folders).

    Raises
    ------
    SweepFolderError
        One line naming the folder and what could not be read.
    """
    try:
        with open(out / csv_name, encoding="utf-8", newline="") as fh:
            reader = csv.DictReader(fh)
            rows = list(reader)
            header = list(reader.fieldnames or [])
        info = json.loads((out / json_name).read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise SweepFolderError(f"{out} is not a readable {kind} folder: {exc}") from None
    return header, rows, info


def read_sweep(path: str | os.PathLike[str]) -> SweepData:
    """Read a sweep folder (sweep.csv, sweep.json, progress.json).

    Raises
    ------
    SweepFolderError
    """
    out = Path(path)
    header, rows, spec = read_table_and_json(out, CSV_NAME, SPEC_NAME, "sweep")
    try:
        progress = json.loads((out / PROGRESS_NAME).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        progress = {}
    measures = list((spec.get("spec") or {}).get("sweep", {}).get("measures") or [])
    params = [h for h in header[2:] if h not in measures and h not in FIXED_COLUMNS]
    return SweepData(out, params, measures, rows, spec, progress)


def disk_problem(need: int, count: int, out_dir: str | os.PathLike[str], key: str, what: str) -> list[Any]:
    """One Problem when ``need`` bytes of results (``count`` runs) exceed the free disk at ``out_dir``."""
    from projects.limits import free_disk_bytes
    from projects.schema import Problem

    free = free_disk_bytes(out_dir)
    if free is None or need <= free:
        return []
    return [Problem(key, count, f"the {count:,} {what} would write about {_bytes(need)} of results, more than "
                    f"the {_bytes(free)} free in {Path(out_dir).expanduser().absolute()}")]


def _bytes(value: float) -> str:
    for unit, size in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if value >= size:
            return f"{value / size:.3g} {unit}"
    return f"{value:.0f} B"
