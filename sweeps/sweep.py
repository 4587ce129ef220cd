"""A sweep: plan the runs, run them on Ray, write the sweep folder, read it back.

The sweep folder (the one interface to a sweep, live or finished)::

    sweep.json       the spec, the engine settings and the run plan
    progress.json    done / total / failed / elapsed_s / eta_s, rewritten after every run
    sweep.csv        one row per run (rewritten after every run; pending runs included)
    exceedance.csv   P(measure > x) with the DKW band, per measure
    profile.csv      P(profile field > threshold) along the section, with Wilson bands
    sensitivity.csv  Spearman rank correlation of each parameter with each measure
    report.html      plots and tables (``runout report SWEEP_DIR`` writes it again)
    runs/ID.toml     the resolved project of each run, runs/ID/ its results, runs/ID.json its record

Python API (for the command line and the workbench)::

    spec = load_spec("sweep.toml")                      # validated; ProjectError on bad input
    result = run_sweep(spec, "out", workers=2, on_progress=print, cancel=stop_flag)
    data = read_sweep("out")                            # rows, measures, statistics
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from sweeps.engine import FINAL_STATUSES, RUNS_DIR, RayEngine, RunPlan, RunRecord, resolve_runs
from sweeps.sampling import sample
from sweeps.spec import SweepSpec

CSV_NAME = "sweep.csv"
SPEC_NAME = "sweep.json"
PROGRESS_NAME = "progress.json"
FIXED_COLUMNS = ("status", "message", "wall_time_s", "results_dir")


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
class SweepResult:
    """A finished (or stopped) sweep: its folder, plan and one record per run."""

    out_dir: Path
    plans: list[RunPlan]
    records: list[RunRecord]
    settings: dict[str, Any] = field(default_factory=dict)
    wall_time_s: float = 0.0
    stopped: bool = False

    @property
    def csv_path(self) -> Path:
        return self.out_dir / CSV_NAME

    def count(self, status: str) -> int:
        return sum(r.status == status for r in self.records)


def plan_sweep(spec: SweepSpec) -> list[RunPlan]:
    """Sample the parameters and resolve every run (see :func:`sweeps.engine.resolve_runs`)."""
    return resolve_runs(spec.project_path, spec.sweep.set, sample(spec), spec.linked)


def atomic_write(path: Path, text: str) -> None:
    """Write a text file atomically (temporary file in the same folder, then rename)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        os.chmod(tmp, 0o644)  # mkstemp makes it private; these are ordinary result files
        with os.fdopen(fd, "w", encoding="utf-8", newline="") as fh:
            fh.write(text)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _cell(value: Any) -> Any:
    if isinstance(value, float):
        return "" if not math.isfinite(value) else repr(value)
    return value


def csv_text(plans: Sequence[RunPlan], records: Sequence[RunRecord | None], measures: Sequence[str]) -> str:
    """sweep.csv: ``run, run_id``, a column per parameter (dotted key), the measures, then
    ``status, message, wall_time_s, results_dir``; empty cells for missing numbers."""
    keys = list(plans[0].values) if plans else []
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["run", "run_id", *keys, *measures, *FIXED_COLUMNS])
    for plan, rec in zip(plans, records):
        rec = rec or RunRecord(plan.run_id, "pending")
        w.writerow([plan.index, plan.run_id, *(_cell(plan.values[k]) for k in keys),
                    *(_cell(rec.measures.get(m, math.nan)) for m in measures),
                    rec.status, rec.message, _cell(rec.wall_time_s), rec.results_dir])
    return buf.getvalue()


def _load_record(runs_dir: Path, plan: RunPlan, measures: Sequence[str], profile_field: str | None) -> RunRecord | None:
    """A final record of an earlier run of the same resolved project, completed where needed."""
    path = runs_dir / f"{plan.run_id}.json"
    try:
        rec = RunRecord.from_json(json.loads(path.read_text(encoding="utf-8")))
    except (OSError, ValueError, KeyError, TypeError):
        return None
    if rec.status not in FINAL_STATUSES:
        return None
    results = runs_dir / plan.run_id
    missing = [m for m in measures if m not in rec.measures]
    if missing or (profile_field and rec.profile is None and rec.status == "completed"):
        if not results.is_dir():
            return None  # measures asked for now that the earlier run did not read: run again
        from sweeps.measures import read_measures, read_profile

        rec.measures.update(read_measures(results, missing))
        if profile_field and rec.profile is None:
            rec.profile = read_profile(results, profile_field)
        atomic_write(path, json.dumps(rec.to_json()))
    rec.reused = True
    return rec


def run_sweep(
    spec: SweepSpec,
    out_dir: str | os.PathLike[str],
    *,
    workers: int | None = None,
    address: str | None = None,
    threads_per_run: int | None = None,
    gpus_per_run: float | None = None,
    on_progress: Callable[[SweepProgress], None] | None = None,
    cancel: Callable[[], bool] | None = None,
    report: bool = True,
) -> SweepResult:
    """Run a sweep into ``out_dir`` (created; earlier runs there are reused).

    Parameters
    ----------
    spec : SweepSpec
    out_dir : path
    workers, address, threads_per_run, gpus_per_run
        See :class:`sweeps.engine.RayEngine`; the spec's ``threads_per_run``/``gpus_per_run``
        apply where these are None.
    on_progress : callable, optional
        Called with a :class:`SweepProgress` after each run (and once at the start).
    cancel : callable, optional
        Polled about twice a second; when it returns True no further run starts and the running
        ones are cancelled (their records are not written: a later sweep runs them again).
    report : bool
        Write the statistics files and report.html at the end.

    Returns
    -------
    SweepResult

    Raises
    ------
    ProjectError
        Invalid base project, fixed overrides or parameter keys (before anything runs).
    """
    t0 = time.perf_counter()
    out = Path(out_dir).expanduser().absolute()
    plans = plan_sweep(spec)
    out.mkdir(parents=True, exist_ok=True)
    runs_dir = out / RUNS_DIR
    runs_dir.mkdir(exist_ok=True)
    measures = list(spec.sweep.measures)
    profile_field = spec.profile.field if spec.profile else None
    records: list[RunRecord | None] = [None] * len(plans)
    by_id: dict[str, list[int]] = {}
    for plan in plans:
        if plan.problem:
            records[plan.index] = RunRecord("", "invalid", plan.problem)
        else:
            by_id.setdefault(plan.run_id, []).append(plan.index)
    reused = 0
    todo: list[RunPlan] = []
    for run_id, idx in by_id.items():
        rec = _load_record(runs_dir, plans[idx[0]], measures, profile_field)
        if rec is None:
            todo.append(plans[idx[0]])
        else:
            reused += len(idx)
            for i in idx:
                records[i] = rec

    def progress(last: RunRecord | None) -> None:
        done = sum(r is not None for r in records)
        failed = sum(r is not None and r.status != "completed" for r in records)
        elapsed = time.perf_counter() - t0
        ran = done - reused - sum(1 for p in plans if p.problem)
        left = len(plans) - done
        eta = elapsed / ran * left if ran > 0 else (0.0 if left == 0 else math.nan)
        p = SweepProgress(done, len(plans), failed, reused, elapsed, eta, last)
        atomic_write(out / PROGRESS_NAME, json.dumps(p.to_json()))
        atomic_write(out / CSV_NAME, csv_text(plans, records, measures))
        if on_progress is not None:
            on_progress(p)

    settings: dict[str, Any] = {}
    stopped = False
    with RayEngine(workers, address, threads_per_run or spec.sweep.threads_per_run,
                   gpus_per_run if gpus_per_run is not None else spec.sweep.gpus_per_run) as engine:
        assert engine.settings is not None
        settings = {"workers": engine.settings.workers, "threads_per_run": engine.settings.threads,
                    "gpus_per_run": engine.settings.gpus, "address": address, "ray_startup_s": engine.startup_s}
        _write_spec(out, spec, plans, settings)
        progress(None)
        tasks = [{"run_id": p.run_id, "project_text": p.project_text, "runs_dir": str(runs_dir),
                  "timeout_s": spec.sweep.timeout_s, "measures": measures, "profile_field": profile_field,
                  "sample_x": None} for p in todo]
        for i, data in engine.map(tasks, cancel):
            rec = RunRecord.from_json(data)
            atomic_write(runs_dir / f"{rec.run_id}.json", json.dumps(rec.to_json()))
            for j in by_id[todo[i].run_id]:
                records[j] = rec
            progress(rec)
        stopped = any(r is None for r in records)
    result = SweepResult(out, plans, [r or RunRecord(p.run_id, "pending") for p, r in zip(plans, records)],
                         settings, time.perf_counter() - t0, stopped)
    if report:
        from sweeps.report import write_statistics, write_sweep_report

        data = read_sweep(out)
        write_statistics(data)
        write_sweep_report(data)
    return result


def _write_spec(out: Path, spec: SweepSpec, plans: Sequence[RunPlan], settings: dict[str, Any]) -> None:
    data = {
        "kind": "sweep",
        "spec": json.loads(spec.model_dump_json()),
        "project": str(spec.project_path),
        "settings": settings,
        "runs": [{"run": p.index, "run_id": p.run_id, "values": p.values, "overrides": list(p.overrides)}
                 for p in plans],
    }
    atomic_write(out / SPEC_NAME, json.dumps(data, indent=1))


# --------------------------------------------------------------------------------------------
# reading a sweep folder


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
            rec = _read_record(self.out_dir / RUNS_DIR / f"{r['run_id']}.json")
            if rec is not None and rec.profile is not None:
                out.append(rec.profile)
        return out


def _float(text: str) -> float:
    try:
        return float(text)
    except (TypeError, ValueError):
        return math.nan


def _read_record(path: Path) -> RunRecord | None:
    try:
        return RunRecord.from_json(json.loads(path.read_text(encoding="utf-8")))
    except (OSError, ValueError, KeyError, TypeError):
        return None


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
