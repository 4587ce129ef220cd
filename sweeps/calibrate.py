"""Back-analysis: find the parameters that best reproduce an observation (optuna on Ray).

The optimiser is optuna's TPE sampler (Bergstra et al. 2011; seeded, ``constant_liar`` so that a
batch of trials running at once spreads out), or its random sampler. It asks for a batch of trials
(one per worker), the runs go through the same Ray engine as a sweep (:mod:`sweeps.engine`: one
``runout run`` process per trial, resolved projects hashed and reused), and each trial is told its
misfit; a run that fails is told as failed and the search goes on.

Misfits (``observation.type``):

- ``deposit-profile``: ``RMS = sqrt(mean_k (h(x_k) - y_k)^2)`` (m) between the final free surface
  ``h`` of the run (:func:`projects.measures.surface_heights`) and the observed points ``(x_k, y_k)``
  (inside ``x_range_m`` where given).
- ``measures``: ``RMS = sqrt(mean_j ((m_j - o_j) / s_j)^2)`` over the observed measures ``o_j``
  (run-out distance, arrival times...; ``s_j`` from ``scales``, else 1: then in the measures' unit).

Parameter uncertainty: the approximate joint confidence region of nonlinear least squares (Beale
1960; Bates & Watts 1988, eq. 2.30), ``S(theta) <= S_min (1 + p / (n - p) F(p, n - p; 1 - alpha))``
with ``S = n RMS^2``, ``n`` observed points and ``p`` parameters. The interval of a parameter is
the range of the completed trials inside the region; it is as fine as the trials near the best
fit, and it assumes independent errors of equal variance: neighbouring points of a digitised
profile are correlated, so the region is a lower bound on the uncertainty.
"""

from __future__ import annotations

import csv
import html
import io
import json
import math
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from projects.atomic import write_atomic
from sweeps import pages
from sweeps.engine import FINAL_STATUSES, RUNS_DIR, RayEngine, RunRecord, resolve_runs
from sweeps.folder import (
    PROGRESS_NAME,
    PROVISIONAL_LEGEND,
    PROVISIONAL_MARK,
    REPORT_NAME,
    SweepProgress,
    disk_problem,
    fill_still_moving,
    read_table_and_json,
    row_still_moving,
    still_moving_cell,
)
from sweeps.spec import CalibrationSpec, Parameter

CSV_NAME = "calibration.csv"
JSON_NAME = "calibration.json"


def read_observation(spec: CalibrationSpec) -> np.ndarray:
    """The observed profile points ``(x, y)`` (m) inside ``x_range_m``, shape (K, 2).

    Raises
    ------
    ProjectError
        The file is missing, unreadable or holds no points in the range.
    """
    from projects.measures import read_xy_csv
    from projects.schema import Problem, ProjectError

    path = spec.observation_path
    assert path is not None
    try:
        pts = read_xy_csv(path)
    except (OSError, ValueError) as exc:
        raise ProjectError([Problem("observation.file", spec.observation.file, f"cannot read it: {exc}")]) from None
    if spec.observation.x_range_m is not None:
        lo, hi = spec.observation.x_range_m
        pts = pts[(pts[:, 0] >= lo) & (pts[:, 0] <= hi)]
    if len(pts) == 0:
        raise ProjectError([Problem("observation.x_range_m", spec.observation.x_range_m, "no observed point in it")])
    return pts


def misfit(spec: CalibrationSpec, rec: RunRecord, observed: np.ndarray | None) -> float:
    """The misfit of one run (see the module docstring); NaN when it cannot be measured."""
    if rec.status != "completed":
        return math.nan
    if spec.observation.type == "deposit-profile":
        if rec.surface is None or observed is None:
            return math.nan
        d = np.asarray(rec.surface, dtype=float) - observed[:, 1]
        return float(np.sqrt(np.mean(d * d)))
    values = spec.observation.values or {}
    scales = spec.observation.scales or {}
    d = [(rec.measures.get(k, math.nan) - o) / scales.get(k, 1.0) for k, o in values.items()]
    return float(np.sqrt(np.mean(np.square(d))))


def observation_count(spec: CalibrationSpec, observed: np.ndarray | None) -> int:
    """``n``: observed points of a profile, or observed measures."""
    if spec.observation.type == "deposit-profile":
        return 0 if observed is None else len(observed)
    return len(spec.observation.values or {})


def confidence_threshold(best: float, n: int, p: int, alpha: float = 0.05) -> float:
    """Largest RMS misfit inside the ``1 - alpha`` region: ``best sqrt(1 + p/(n-p) F)``; NaN if n <= p."""
    from scipy.stats import f

    if n <= p or not math.isfinite(best):
        return math.nan
    return best * math.sqrt(1.0 + p / (n - p) * float(f.ppf(1 - alpha, p, n - p)))


def quadratic_estimate(theta: Sequence[float], rms: Sequence[float], threshold: float, points: int = 5
                       ) -> tuple[float, float, float] | None:
    """Minimum and 95% interval of one parameter from a parabola through the best trials.

    ``S = RMS^2`` of the ``points`` trials with the smallest misfit (at least 3, with at least 3
    distinct values) is fitted by ``a theta^2 + b theta + c`` (least squares); with ``a > 0`` the
    minimum is ``theta* = -b / 2a`` and the interval the ``theta`` where the parabola stays below
    ``threshold^2`` (the region of :func:`confidence_threshold`). Exact for one parameter near a
    smooth minimum; with more parameters it ignores the others (a marginal look). None where no
    upward parabola fits.

    Returns
    -------
    (theta_min, low, high) or None
    """
    t = np.asarray(theta, dtype=float)
    r = np.asarray(rms, dtype=float)
    ok = np.isfinite(t) & np.isfinite(r)
    t, r = t[ok], r[ok]
    if len(np.unique(t)) < 3 or not math.isfinite(threshold):
        return None
    order = np.argsort(r)
    pick = order[:max(3, points)]
    if len(np.unique(t[pick])) < 3:
        return None
    a, b, c = np.polyfit(t[pick], r[pick] ** 2, 2)
    if not a > 0:
        return None
    tmin = -b / (2 * a)
    smin = c - b * b / (4 * a)
    half = math.sqrt(max(threshold**2 - smin, 0.0) / a)
    return float(tmin), float(tmin - half), float(tmin + half)


def _quadratic(trials: Sequence[Trial], keys: Sequence[str], threshold: float) -> dict[str, list[float]]:
    out = {}
    for k in keys:
        num = [t for t in trials if isinstance(t.values[k], (int, float)) and not isinstance(t.values[k], bool)]
        q = quadratic_estimate([t.values[k] for t in num], [t.misfit for t in num], threshold)
        if q is not None:
            out[k] = list(q)
    return out


def _suggest(trial: Any, key: str, p: Parameter) -> Any:
    if p.distribution == "uniform":
        return trial.suggest_float(key, float(p.low), float(p.high))
    if p.distribution == "range":
        from sweeps.sampling import levels

        return trial.suggest_categorical(key, levels(p))
    return trial.suggest_categorical(key, list(p.values or []))


@dataclass
class Trial:
    """One trial: its values, run record and misfit."""

    number: int
    values: dict[str, Any]
    run_id: str
    record: RunRecord
    misfit: float


@dataclass
class CalibrationResult:
    """A calibration: trials in order, the best, the confidence region."""

    out_dir: Path
    parameters: list[str]
    trials: list[Trial]
    n_observed: int
    unit: str
    threshold: float = math.nan
    intervals: dict[str, tuple[float, float]] = field(default_factory=dict)
    quadratic: dict[str, list[float]] = field(default_factory=dict)
    settings: dict[str, Any] = field(default_factory=dict)
    wall_time_s: float = 0.0
    stopped: bool = False

    @property
    def best(self) -> Trial | None:
        ok = [t for t in self.trials if math.isfinite(t.misfit)]
        return min(ok, key=lambda t: t.misfit) if ok else None

    def still_moving_trials(self) -> list[Trial]:
        """The trials the search used (a misfit) whose run ended with the mass still moving."""
        return still_moving_trials(self.trials)

    def summary_lines(self) -> list[str]:
        b = self.best
        done = sum(t.record.status == "completed" for t in self.trials)
        lines = [f"{len(self.trials)} trials, {done} completed, in {self.wall_time_s:.0f} s"]
        lines += still_moving_warnings(self.trials, b)
        if b is None:
            return [*lines, "no trial completed: no best fit"]
        lines.append(f"best fit (trial {b.number}): misfit {b.misfit:.4g} {self.unit}; "
                     + ", ".join(f"{k} = {_fmt(v)}" for k, v in b.values.items()))
        for k, (lo, hi) in self.intervals.items():
            lines.append(f"  {k}: trials in the 95% region (RMS <= {self.threshold:.4g} {self.unit}) span "
                         f"{lo:.4g} to {hi:.4g}")
        for k, (m, lo, hi) in self.quadratic.items():
            lines.append(f"  {k}: parabola through the best trials: minimum at {m:.4g}, 95% region {lo:.4g} to {hi:.4g}")
        return lines


def still_moving_trials(trials: Sequence[Trial]) -> list[Trial]:
    """The trials with a misfit (the ones the search and the region use) whose run ended with
    the mass still moving: their misfits are measured on a deposit that had not come to rest."""
    return [t for t in trials if math.isfinite(t.misfit) and t.record.still_moving]


def still_moving_warnings(trials: Sequence[Trial], best: Trial | None) -> list[str]:
    """``warning: ...`` lines where trials the search used ended still moving (none otherwise)."""
    from projects.motion import REMEDY

    moving = still_moving_trials(trials)
    if not moving:
        return []
    used = sum(math.isfinite(t.misfit) for t in trials)
    numbers = ", ".join(str(t.number) for t in moving[:10]) + (f" and {len(moving) - 10} more" if len(moving) > 10
                                                               else "")
    lines = [f"warning: {len(moving)} of the {used} trials used ended with the mass still moving (trial"
             f"{'s' if len(moving) > 1 else ''} {numbers}): their misfits are provisional (still_moving in "
             f"calibration.csv); {REMEDY}"]
    if best is not None and best.record.still_moving:
        lines.append(f"warning: the best fit (trial {best.number}) is one of them: its run had not come to rest, "
                     "so the fit and its region are provisional")
    return lines


def _fmt(v: Any) -> str:
    return f"{v:.4g}" if isinstance(v, float) else str(v)


def _intervals(trials: Sequence[Trial], keys: Sequence[str], threshold: float) -> dict[str, tuple[float, float]]:
    out: dict[str, tuple[float, float]] = {}
    if not math.isfinite(threshold):
        return out
    inside = [t for t in trials if math.isfinite(t.misfit) and t.misfit <= threshold]
    for k in keys:
        vals = [t.values[k] for t in inside if isinstance(t.values[k], (int, float)) and not isinstance(t.values[k], bool)]
        if vals:
            out[k] = (float(min(vals)), float(max(vals)))
    return out


def run_calibration(
    spec: CalibrationSpec,
    out_dir: str | os.PathLike[str],
    *,
    workers: int | None = None,
    address: str | None = None,
    threads_per_run: int | None = None,
    gpus_per_run: float | None = None,
    on_progress: Callable[[SweepProgress], None] | None = None,
    cancel: Callable[[], bool] | None = None,
    report: bool = True,
) -> CalibrationResult:
    """Run a calibration into ``out_dir`` (calibration.csv, calibration.json, runs/, report.html).

    Engine options as for :func:`sweeps.sweep.run_sweep`. Runs of the same resolved project found
    in ``out_dir/runs`` are reused, so running the same calibration again replays it at once and
    a stopped one goes on.

    Raises
    ------
    ProjectError
        Invalid base project, fixed overrides, parameter keys or observation file.
    """
    import optuna

    t0 = time.perf_counter()
    out = Path(out_dir).expanduser().absolute()
    table = spec.calibration
    keys = list(spec.parameters)
    observed = check_calibration(spec)
    # the sizes first, as `runout run` checks one run's: every trial about the size of the centre's
    from projects.schema import ProjectError

    centre = resolve_runs(spec.project_path, table.set, [{k: _centre(p) for k, p in spec.parameters.items()}],
                          spec.linked)[0]
    problems = disk_problem(centre.disk_bytes * table.trials, table.trials, out, "calibration.trials", "trials")
    if problems:
        raise ProjectError(problems)
    unit = "m" if spec.observation.type == "deposit-profile" else ("(scaled)" if spec.observation.scales else "")
    n_obs = observation_count(spec, observed)
    measures = list((spec.observation.values or {}).keys())
    out.mkdir(parents=True, exist_ok=True)
    runs_dir = out / RUNS_DIR
    runs_dir.mkdir(exist_ok=True)
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    if table.optimizer == "tpe":
        sampler = optuna.samplers.TPESampler(seed=table.seed, n_startup_trials=max(2, min(10, table.trials // 3)),
                                             constant_liar=True)
    else:
        sampler = optuna.samplers.RandomSampler(seed=table.seed)
    study = optuna.create_study(direction="minimize", sampler=sampler)
    trials: list[Trial] = []
    stopped = False
    settings: dict[str, Any] = {}
    sample_x = None if observed is None else [float(x) for x in observed[:, 0]]

    def write(last: RunRecord | None) -> None:
        done = len(trials)
        failed = sum(t.record.status != "completed" for t in trials)
        elapsed = time.perf_counter() - t0
        ran = sum(not t.record.reused for t in trials)
        eta = elapsed / ran * (table.trials - done) if ran else math.nan
        prog = SweepProgress(done, table.trials, failed, done - ran, elapsed, eta, last)
        write_atomic(out / PROGRESS_NAME, json.dumps(prog.to_json()))
        best = min((t for t in trials if math.isfinite(t.misfit)), key=lambda t: t.misfit, default=None)
        threshold = confidence_threshold(best.misfit if best else math.nan, n_obs, len(keys))
        write_atomic(out / CSV_NAME, _csv_text(trials, keys))
        write_atomic(out / JSON_NAME, json.dumps({
            "kind": "calibration", "spec": json.loads(spec.model_dump_json()), "project": str(spec.project_path),
            "settings": settings, "unit": unit, "n_observed": n_obs,
            "observed": None if observed is None else observed.tolist(),
            "best": None if best is None else {"trial": best.number, "values": best.values, "misfit": best.misfit,
                                               "run_id": best.run_id, "still_moving": best.record.still_moving},
            "still_moving_trials": [t.number for t in still_moving_trials(trials)],
            "threshold": None if not math.isfinite(threshold) else threshold,
            "intervals": _intervals(trials, keys, threshold),
            "quadratic": _quadratic(trials, keys, threshold),
        }, indent=1))
        if on_progress is not None:
            on_progress(prog)

    with RayEngine(workers, address, threads_per_run or table.threads_per_run,
                   gpus_per_run if gpus_per_run is not None else table.gpus_per_run) as engine:
        assert engine.settings is not None
        settings = {"workers": engine.settings.workers, "threads_per_run": engine.settings.threads,
                    "gpus_per_run": engine.settings.gpus, "address": address,
                    "batch": table.batch or engine.settings.workers}
        batch = table.batch or engine.settings.workers
        write(None)
        while len(trials) < table.trials and not stopped:
            asked = [study.ask() for _ in range(min(batch, table.trials - len(trials)))]
            values = [{k: _suggest(t, k, spec.parameters[k]) for k in keys} for t in asked]
            plans = resolve_runs(spec.project_path, table.set, values, spec.linked) if values else []
            records: dict[int, RunRecord] = {}
            tasks, task_of = [], []
            for j, plan in enumerate(plans):
                if plan.problem:
                    records[j] = RunRecord("", "invalid", plan.problem)
                    continue
                rec = _reuse(runs_dir, plan.run_id, measures, observed is not None)
                if rec is not None:
                    records[j] = rec
                    continue
                tasks.append({"run_id": plan.run_id, "project_text": plan.project_text, "runs_dir": str(runs_dir),
                              "timeout_s": table.timeout_s, "measures": measures, "profile_field": None,
                              "sample_x": sample_x})
                task_of.append(j)
            for i, data in engine.map(tasks, cancel):
                rec = RunRecord.from_json(data)
                write_atomic(runs_dir / f"{rec.run_id}.json", json.dumps(rec.to_json()))
                records[task_of[i]] = rec
            if len(records) < len(plans):  # cancelled: the unfinished trials are dropped
                stopped = True
            for j, (trial, plan) in enumerate(zip(asked, plans)):
                rec = records.get(j)
                if rec is None:
                    study.tell(trial, state=optuna.trial.TrialState.FAIL)
                    continue
                m = misfit(spec, rec, observed)
                if math.isfinite(m):
                    study.tell(trial, m)
                else:
                    study.tell(trial, state=optuna.trial.TrialState.FAIL)
                trials.append(Trial(len(trials), values[j], plan.run_id, rec, m))
                write(rec)
    result = CalibrationResult(out, keys, trials, n_obs, unit, settings=settings,
                               wall_time_s=time.perf_counter() - t0, stopped=stopped)
    best = result.best
    result.threshold = confidence_threshold(best.misfit if best else math.nan, n_obs, len(keys))
    result.intervals = _intervals(trials, keys, result.threshold)
    result.quadratic = _quadratic(trials, keys, result.threshold)
    if report:
        write_calibration_report(read_calibration(out))
    return result


def check_calibration(spec: CalibrationSpec) -> np.ndarray | None:
    """Check what can be checked before any run: the observation file, the base project, the fixed
    overrides and the parameter keys (at the centres of their ranges). Returns the observed points.

    Raises
    ------
    ProjectError
    """
    from projects.document import load_project
    from projects.schema import ProjectError
    from sweeps.measures import measure_problems

    observed = read_observation(spec) if spec.observation.type == "deposit-profile" else None
    resolve_runs(spec.project_path, spec.calibration.set, [{k: _centre(p) for k, p in spec.parameters.items()}],
                 spec.linked)
    problems = measure_problems(list(spec.observation.values or {}),
                                load_project(spec.project_path, list(spec.calibration.set)), "observation.values")
    if problems:
        raise ProjectError(problems)
    return observed


def _centre(p: Parameter) -> Any:
    if p.distribution == "uniform":
        return 0.5 * (float(p.low) + float(p.high))
    from sweeps.sampling import levels

    lv = levels(p)
    return lv[len(lv) // 2]


def _reuse(runs_dir: Path, run_id: str, measures: Sequence[str], need_surface: bool) -> RunRecord | None:
    try:
        rec = RunRecord.from_json(json.loads((runs_dir / f"{run_id}.json").read_text(encoding="utf-8")))
    except (OSError, ValueError, KeyError, TypeError):
        return None
    if rec.status not in FINAL_STATUSES or any(m not in rec.measures for m in measures):
        return None
    if need_surface and rec.status == "completed" and rec.surface is None:
        return None
    fill_still_moving(rec, runs_dir / run_id, runs_dir / f"{run_id}.json")
    rec.reused = True
    return rec


def _csv_text(trials: Sequence[Trial], keys: Sequence[str]) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["trial", "run_id", *keys, "misfit", "status", "message", "wall_time_s", "results_dir",
                "still_moving"])
    for t in trials:
        w.writerow([t.number, t.run_id, *(repr(t.values[k]) if isinstance(t.values[k], float) else t.values[k]
                                          for k in keys),
                    repr(t.misfit) if math.isfinite(t.misfit) else "", t.record.status, t.record.message,
                    repr(t.record.wall_time_s) if math.isfinite(t.record.wall_time_s) else "", t.record.results_dir,
                    still_moving_cell(t.record.still_moving)])
    return buf.getvalue()


# --------------------------------------------------------------------------------------------
# reading and reporting


@dataclass
class CalibrationData:
    """A calibration folder read back: the rows of calibration.csv and calibration.json."""

    out_dir: Path
    parameters: list[str]
    rows: list[dict[str, str]]
    info: dict[str, Any]

    def column(self, key: str) -> np.ndarray:
        out = []
        for r in self.rows:
            try:
                out.append(float(r.get(key, "")))
            except ValueError:
                out.append(math.nan)
        return np.array(out, dtype=float)


def read_calibration(path: str | os.PathLike[str]) -> CalibrationData:
    """Read a calibration folder.

    Raises
    ------
    sweeps.folder.SweepFolderError
    """
    out = Path(path)
    header, rows, info = read_table_and_json(out, CSV_NAME, JSON_NAME, "calibration")
    params = header[2:header.index("misfit")] if "misfit" in header else []
    return CalibrationData(out, params, rows, info)


def write_calibration_report(data: CalibrationData, output: Path | None = None) -> Path:
    """Write ``report.html``: best fit, misfit landscape, optimisation history, confidence region,
    and the best run's final surface against the observed profile."""
    info = data.info
    unit = info.get("unit", "")
    best = info.get("best")
    thr = info.get("threshold")
    misfits = data.column("misfit")
    spec = info.get("spec") or {}
    cal = spec.get("calibration") or {}
    obs = spec.get("observation") or {}
    settings = info.get("settings") or {}
    rows = [
        ["base project", info.get("project", "")],
        ["fixed --set", ", ".join(cal.get("set") or []) or "none"],
        ["observation", f"{obs.get('type')}: {obs.get('file') or obs.get('values')} "
                        f"({info.get('n_observed')} observed values)"],
        ["optimiser", f"optuna {cal.get('optimizer')} (seed {cal.get('seed')}), {len(data.rows)} trials, "
                      f"batches of {settings.get('batch')}"],
        ["engine", f"{settings.get('workers')} workers x {settings.get('threads_per_run')} threads"],
    ]
    if best:
        rows.append(["best fit", f"trial {best['trial']}: misfit {best['misfit']:.4g} {unit}; "
                     + ", ".join(f"{k} = {_fmt(v)}" for k, v in best["values"].items())
                     + ("; its run ended still moving: provisional" if best.get("still_moving") else "")])
    moving = [r for r in data.rows if row_still_moving(r) and r.get("misfit", "") != ""]
    used = sum(r.get("misfit", "") != "" for r in data.rows)
    rows.append(["ended still moving", f"{len(moving)} of the {used} trials with a misfit"
                 + (f": their misfits are provisional ({PROVISIONAL_MARK} in the trials below)" if moving else "")])
    for k, (lo, hi) in (info.get("intervals") or {}).items():
        rows.append([f"95% region of {k}", f"{lo:.4g} to {hi:.4g} (trials with misfit <= {thr:.4g} {unit})"])
    for k, (m, lo, hi) in (info.get("quadratic") or {}).items():
        rows.append([f"parabola fit of {k}", f"minimum at {m:.4g}, 95% region {lo:.4g} to {hi:.4g} "
                     "(RMS^2 of the 5 best trials fitted by a parabola)"])
    if thr is None:
        rows.append(["95% region", "not determined (needs more observed values than parameters, and a best fit)"])
    parts = ["<h2>Calibration</h2>", pages.table(["key", "value"], rows)]
    if np.isfinite(misfits).any():
        fig, axes = pages.subplots(len(data.parameters))
        for ax, k in zip(axes, data.parameters):
            ax.plot(data.column(k), misfits, "o", ms=4)
            if thr is not None:
                ax.axhline(thr, color="C3", lw=0.8, ls="--", label="95% region")
                ax.legend(fontsize=7)
            ax.set_xlabel(k, fontsize=8)
            ax.set_ylabel(f"misfit ({unit})" if unit else "misfit", fontsize=8)
        parts += ["<h2>Misfit landscape</h2>", pages.png(fig)]
        fig, ax = pages.figure(6.4, 3.0)
        ok = np.isfinite(misfits)
        trial = np.arange(len(misfits))
        ax.plot(trial[ok], misfits[ok], "o", ms=4, label="trial")
        ax.plot(trial[ok], np.minimum.accumulate(misfits[ok]), "-", label="best so far")
        ax.set_xlabel("trial")
        ax.set_ylabel("misfit")
        ax.legend(fontsize=8)
        parts += ["<h2>Optimisation history</h2>", pages.png(fig)]
    observed = info.get("observed")
    if best and observed:
        results = data.out_dir / RUNS_DIR / best["run_id"]
        try:
            from sweeps.measures import surface_at

            pts = np.asarray(observed, dtype=float)
            x = np.linspace(0.0, float(pts[:, 0].max()) * 1.3, 300)
            h = surface_at(results, x)
            fig, ax = pages.figure(7.5, 3.0)
            ax.plot(pts[:, 0], pts[:, 1], "k.", ms=4, label="observed")
            ax.plot(x, h, "C0-", label=f"best fit (trial {best['trial']})")
            ax.set_xlabel("x (m)")
            ax.set_ylabel("surface height (m)")
            ax.set_aspect("equal", adjustable="datalim")
            ax.legend(fontsize=8)
            parts += ["<h2>Best fit against the observation</h2>", pages.png(fig)]
        except (OSError, ValueError, KeyError, IndexError):
            parts.append("<p>The best run's results folder is not readable here.</p>")
    table_rows = [[r["trial"], *(r[k] for k in data.parameters),
                   r["misfit"] + (PROVISIONAL_MARK if row_still_moving(r) and r["misfit"] else ""), r["status"],
                   r["message"]] for r in data.rows]
    parts += ["<h2>Trials</h2>", pages.table(["trial", *data.parameters, "misfit", "status", "message"], table_rows)]
    if moving:
        from projects.motion import REMEDY

        parts.append(f"<p>{html.escape(PROVISIONAL_LEGEND)}. To make them final: {html.escape(REMEDY)}.</p>")
    path = (output or data.out_dir) / REPORT_NAME
    path.parent.mkdir(parents=True, exist_ok=True)
    write_atomic(path, pages.page(f"Calibration report: {data.out_dir.name}", parts))
    return path
