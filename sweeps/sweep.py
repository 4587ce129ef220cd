"""A sweep: plan the runs, run them on Ray, write the sweep folder (:mod:`sweeps.folder` has its
files and reads it back).

Python API (for the command line and the workbench)::

    spec = load_spec("sweep.toml")                      # validated; ProjectError on bad input
    result = run_sweep(spec, "out", workers=2, on_progress=print, cancel=stop_flag)
    data = sweeps.folder.read_sweep("out")              # rows, measures, statistics
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from projects.atomic import write_atomic
from sweeps.engine import FINAL_STATUSES, RUNS_DIR, RayEngine, RunPlan, RunRecord, resolve_runs
from sweeps.folder import (
    CSV_NAME,
    FIXED_COLUMNS,
    PROGRESS_NAME,
    SPEC_NAME,
    SweepProgress,
    disk_problem,
    fill_still_moving,
    read_sweep,
    still_moving_cell,
)
from sweeps.sampling import sample
from sweeps.spec import SweepSpec


@dataclass
class SweepResult:
    """A finished (or stopped) sweep: its folder, plan and one record per run."""

    out_dir: Path
    plans: list[RunPlan]
    records: list[RunRecord]
    settings: dict[str, Any] = field(default_factory=dict)
    wall_time_s: float = 0.0
    stopped: bool = False

    def count(self, status: str) -> int:
        return sum(r.status == status for r in self.records)

    def still_moving_runs(self) -> list[int]:
        """The runs (their numbers, ``run`` in sweep.csv) that completed with the mass still moving:
        their measures are provisional."""
        return [p.index for p, r in zip(self.plans, self.records) if r.status == "completed" and r.still_moving]


def plan_sweep(spec: SweepSpec) -> list[RunPlan]:
    """Sample the parameters and resolve every run (see :func:`sweeps.engine.resolve_runs`); the
    measures are checked against the base project first (:func:`sweeps.measures.measure_problems`).

    Raises
    ------
    ProjectError
        The base project, the fixed overrides, a parameter key or a measure key is wrong.
    """
    from projects.document import load_project
    from projects.schema import ProjectError
    from sweeps.measures import measure_problems

    base = load_project(spec.project_path, list(spec.sweep.set))
    problems = measure_problems(spec.sweep.measures, base, "sweep.measures")
    if problems:
        raise ProjectError(problems)
    return resolve_runs(spec.project_path, spec.sweep.set, sample(spec), spec.linked)


def disk_problems(plans: Sequence[RunPlan], out_dir: str | os.PathLike[str]) -> list[Any]:
    """Whether the runs to make fit on the disk of the sweep folder: the sum of each run's disk
    estimate (:func:`projects.build.estimate`, as ``runout run`` checks one run) against the free
    disk there. Runs of the same resolved project count once.

    Returns
    -------
    list of Problem
        One, naming the total and the free space, when they do not fit.
    """
    seen: set[str] = set()
    need = 0
    for plan in plans:
        if plan.run_id and plan.run_id not in seen:
            seen.add(plan.run_id)
            need += plan.disk_bytes
    return disk_problem(need, len(seen), out_dir, "sweep.runs", "runs")


def _cell(value: Any) -> Any:
    if isinstance(value, float):
        return "" if not math.isfinite(value) else repr(value)
    return value


def csv_text(plans: Sequence[RunPlan], records: Sequence[RunRecord | None], measures: Sequence[str]) -> str:
    """sweep.csv: ``run, run_id``, a column per parameter (dotted key), the measures, then
    ``status, message, wall_time_s, results_dir, still_moving`` (``true`` where the run ended with
    the mass still moving, so that its measures are provisional; empty without a verdict); empty
    cells for missing numbers."""
    keys = list(plans[0].values) if plans else []
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["run", "run_id", *keys, *measures, *FIXED_COLUMNS])
    for plan, rec in zip(plans, records):
        rec = rec or RunRecord(plan.run_id, "pending")
        w.writerow([plan.index, plan.run_id, *(_cell(plan.values[k]) for k in keys),
                    *(_cell(rec.measures.get(m, math.nan)) for m in measures),
                    rec.status, rec.message, _cell(rec.wall_time_s), rec.results_dir,
                    still_moving_cell(rec.still_moving)])
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
        write_atomic(path, json.dumps(rec.to_json()))
    fill_still_moving(rec, results, path)
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
    from projects.schema import ProjectError

    t0 = time.perf_counter()
    out = Path(out_dir).expanduser().absolute()
    plans = plan_sweep(spec)
    runs_dir = out / RUNS_DIR
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
        rec = _load_record(runs_dir, plans[idx[0]], measures, profile_field) if runs_dir.is_dir() else None
        if rec is None:
            todo.append(plans[idx[0]])
        else:
            reused += len(idx)
            for i in idx:
                records[i] = rec
    # the sizes first, as `runout run` checks one run's: before the folder is made or Ray started
    problems = disk_problems(todo, out)
    if problems:
        raise ProjectError(problems)
    out.mkdir(parents=True, exist_ok=True)
    runs_dir.mkdir(exist_ok=True)

    def progress(last: RunRecord | None) -> None:
        done = sum(r is not None for r in records)
        failed = sum(r is not None and r.status != "completed" for r in records)
        elapsed = time.perf_counter() - t0
        ran = done - reused - sum(1 for p in plans if p.problem)
        left = len(plans) - done
        eta = elapsed / ran * left if ran > 0 else (0.0 if left == 0 else math.nan)
        p = SweepProgress(done, len(plans), failed, reused, elapsed, eta, last)
        write_atomic(out / PROGRESS_NAME, json.dumps(p.to_json()))
        write_atomic(out / CSV_NAME, csv_text(plans, records, measures))
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
            write_atomic(runs_dir / f"{rec.run_id}.json", json.dumps(rec.to_json()))
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
    write_atomic(out / SPEC_NAME, json.dumps(data, indent=1))
