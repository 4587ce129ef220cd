"""Statistics files and the HTML report of a sweep or a calibration folder (matplotlib, headless).

``write_statistics`` writes ``exceedance.csv``, ``profile.csv`` and ``sensitivity.csv`` (see
:mod:`sweeps.analysis` for the formulas); ``write_sweep_report`` writes ``report.html`` with the
PNG plots embedded, so the one file can be mailed or archived. :func:`write_report` picks the
sweep or calibration report from what the folder holds.
"""

from __future__ import annotations

import csv
import html
import io
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from projects.atomic import write_atomic
from sweeps import pages
from sweeps.analysis import exceedance, probability_profile, sensitivity
from sweeps.folder import PROVISIONAL_LEGEND, PROVISIONAL_MARK, REPORT_NAME, SweepData, read_sweep

def _csv(path: Path, header: Sequence[str], rows: Sequence[Sequence[Any]]) -> Path:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(header)
    for row in rows:
        w.writerow(["" if isinstance(v, float) and not math.isfinite(v) else (repr(v) if isinstance(v, float) else v)
                    for v in row])
    write_atomic(path, buf.getvalue())
    return path


def write_statistics(data: SweepData, alpha: float = 0.05) -> list[Path]:
    """Write exceedance.csv, sensitivity.csv and (with a profile) profile.csv into the sweep folder.

    exceedance.csv: ``measure, value, p_exceed, lower, upper, n`` (DKW band at 1 - alpha).
    profile.csv: ``x_m`` then per threshold T ``p_gt_T, lower_gt_T, upper_gt_T`` (Wilson, pointwise).
    sensitivity.csv: ``measure, parameter, spearman_rho, p_value, n, rank``.
    """
    out = data.out_dir
    written = []
    rows = []
    for m in data.measures:
        ex = exceedance(data.column(m), alpha)
        rows.extend([m, float(x), float(p), float(lo), float(hi), ex.n]
                    for x, p, lo, hi in zip(ex.x, ex.p, ex.lower, ex.upper))
    written.append(_csv(out / "exceedance.csv", ["measure", "value", "p_exceed", "lower", "upper", "n"], rows))
    params = {k: data.values(k) for k in data.parameters}
    sens = sensitivity(params, {m: data.column(m) for m in data.measures})
    rank_rows, rank, last = [], 0, None
    for s in sens:
        rank = 1 if s.measure != last else rank + 1
        last = s.measure
        rank_rows.append([s.measure, s.parameter, s.rho, s.p_value, s.n, rank])
    written.append(_csv(out / "sensitivity.csv", ["measure", "parameter", "spearman_rho", "p_value", "n", "rank"],
                        rank_rows))
    thresholds = data.thresholds()
    profiles = data.profiles()
    if thresholds and profiles:
        pp = probability_profile(profiles, thresholds, alpha)
        header = ["x_m"]
        for t in pp.thresholds:
            header += [f"p_gt_{t:g}", f"lower_gt_{t:g}", f"upper_gt_{t:g}"]
        prow = []
        for j, x in enumerate(pp.x_m):
            row: list[Any] = [float(x)]
            for i in range(len(pp.thresholds)):
                row += [float(pp.p[i, j]), float(pp.lower[i, j]), float(pp.upper[i, j])]
            prow.append(row)
        written.append(_csv(out / "profile.csv", header, prow))
    return written


def write_sweep_report(data: SweepData, alpha: float = 0.05, output: Path | None = None) -> Path:
    """Write ``report.html`` of a sweep folder: runs, measures against parameters, exceedance
    curves with DKW bands, the probability profile, the sensitivity ranking, failed runs, and the
    runs that ended with the mass still moving (their measures marked provisional, ``*``)."""
    from projects.motion import REMEDY

    rows = data.rows
    moving = data.still_moving()
    moving_mask = data.still_moving_mask()
    n_done = len(data.completed())
    statuses: dict[str, int] = {}
    for r in rows:
        statuses[r["status"]] = statuses.get(r["status"], 0) + 1
    spec = data.spec.get("spec") or {}
    settings = data.spec.get("settings") or {}
    sw = spec.get("sweep") or {}
    walls = np.array([float(r["wall_time_s"]) for r in rows if r["wall_time_s"]], dtype=float)
    parts = [
        "<h2>Sweep</h2>",
        pages.table(["key", "value"], [
            ["base project", data.spec.get("project", "")],
            ["fixed --set", ", ".join(sw.get("set") or []) or "none"],
            ["sampling", f"{sw.get('sampling')} (seed {sw.get('seed')})"],
            ["runs", len(rows)],
            ["status", ", ".join(f"{k}: {v}" for k, v in sorted(statuses.items()))],
            ["ended still moving", f"{len(moving)} of {n_done} completed runs"
             + (f": their measures are provisional ({PROVISIONAL_MARK}, see below)" if moving else "")
             if not rows or "still_moving" in rows[0] else "not recorded (a sweep.csv without the still_moving "
             "column)"],
            ["engine", f"{settings.get('workers')} workers x {settings.get('threads_per_run')} threads, "
                       f"{settings.get('gpus_per_run')} GPU per run, "
                       f"{'cluster ' + str(settings['address']) if settings.get('address') else 'local Ray'}"],
            ["run wall time", f"mean {walls.mean():.3g} s, total {walls.sum():.4g} s" if walls.size else "-"],
        ]),
        "<h2>Parameters</h2>",
        pages.table(["key", "distribution"], [[k, _describe(v)] for k, v in (spec.get("parameters") or {}).items()]),
    ]
    numeric = [k for k in data.parameters if np.isfinite(data.column(k, completed_only=False)).any()]
    for m in data.measures:
        y = data.column(m)
        parts.append(f"<h2>{html.escape(m)}</h2>")
        if not np.isfinite(y).any():
            parts.append("<p>No completed run has this measure.</p>")
            continue
        ex = exceedance(y, alpha)
        fig, ax = pages.figure()
        # P(X > x) = 1 left of the smallest value: start the curve there
        pad = 0.05 * (float(ex.x[-1] - ex.x[0]) or abs(float(ex.x[0])) or 1.0)
        xs = np.concatenate([[ex.x[0] - pad], ex.x, [ex.x[-1] + pad]])
        ps = np.concatenate([[1.0], ex.p, [0.0]])
        lo = np.concatenate([[max(0.0, 1.0 - ex.eps)], ex.lower, [0.0]])
        hi = np.concatenate([[1.0], ex.upper, [min(1.0, ex.eps)]])
        ax.step(xs, ps, where="post", color="C0", label="P(X > x), empirical")
        ax.fill_between(xs, lo, hi, step="post", color="C0", alpha=0.2,
                        label=f"{100 * (1 - alpha):g}% DKW band (+-{ex.eps:.2f})")
        ax.set_xlabel(m)
        ax.set_ylabel("exceedance probability")
        ax.set_ylim(-0.02, 1.02)
        ax.legend(fontsize=8)
        ax.set_title(f"exceedance of {m} ({ex.n} runs)")
        parts.append(pages.png(fig))
        q = np.nanpercentile(y, [5, 50, 95])
        provisional = int((moving_mask & np.isfinite(y)).sum())
        parts.append(f"<p>mean {np.nanmean(y):.4g}, 5% {q[0]:.4g}, median {q[1]:.4g}, 95% {q[2]:.4g} "
                     f"(n = {ex.n}"
                     + (f"; {provisional} of them provisional{PROVISIONAL_MARK}: ended still moving" if provisional
                        else "") + ").</p>")
        if numeric:
            fig, axes = pages.subplots(len(numeric))
            for ax, k in zip(axes, numeric):
                x = data.column(k)
                ax.plot(x[~moving_mask], y[~moving_mask], "o", ms=4, color="C0")
                if moving_mask.any():
                    ax.plot(x[moving_mask], y[moving_mask], "o", ms=5, mfc="none", color="C1",
                            label="ended still moving (provisional)")
                    ax.legend(fontsize=6)
                ax.set_xlabel(k, fontsize=8)
                ax.set_ylabel(m, fontsize=8)
            parts.append(pages.png(fig))
    thresholds = data.thresholds()
    profiles = data.profiles()
    if thresholds:
        parts.append(f"<h2>Probability profile: {html.escape(str(data.profile_field()))}</h2>")
        if profiles:
            pp = probability_profile(profiles, thresholds, alpha)
            fig, ax = pages.figure(7.5, 3.6)
            for i, t in enumerate(pp.thresholds):
                ax.plot(pp.x_m, pp.p[i], color=f"C{i}", label=f"P({data.profile_field()} > {t:g})")
                ax.fill_between(pp.x_m, pp.lower[i], pp.upper[i], color=f"C{i}", alpha=0.15)
            ax.set_xlabel("x (m)")
            ax.set_ylabel("probability")
            ax.set_ylim(-0.02, 1.02)
            ax.legend(fontsize=8)
            ax.set_title(f"{pp.n} runs; bands: {100 * (1 - alpha):g}% Wilson, pointwise")
            parts.append(pages.png(fig))
        else:
            parts.append("<p>No completed run has this profile.</p>")
    sens = sensitivity({k: data.values(k) for k in data.parameters}, {m: data.column(m) for m in data.measures})
    if sens:
        parts.append("<h2>Sensitivity (Spearman rank correlation)</h2>")
        parts.append(pages.table(["measure", "parameter", "rho", "p-value", "n"],
                            [[s.measure, s.parameter, s.rho, s.p_value, s.n] for s in sens]))
    if moving:
        parts.append("<h2>Runs that ended still moving</h2>")
        parts.append(pages.table(["run", *data.parameters, *data.measures],
                                 [[r["run"], *(r[k] for k in data.parameters),
                                   *(_provisional(r.get(m, "")) for m in data.measures)]
                                  for r in moving]))
        parts.append(f"<p>{html.escape(PROVISIONAL_LEGEND)}. To make them final: {html.escape(REMEDY)}.</p>")
    bad = [r for r in rows if r["status"] != "completed"]
    if bad:
        parts.append("<h2>Runs that did not complete</h2>")
        parts.append(pages.table(["run", *data.parameters, "status", "message"],
                            [[r["run"], *(r[k] for k in data.parameters), r["status"], r["message"]] for r in bad]))
    parts.append("<p>Files: sweep.csv, exceedance.csv, profile.csv, sensitivity.csv, runs/.</p>")
    path = (output or data.out_dir) / REPORT_NAME
    path.parent.mkdir(parents=True, exist_ok=True)
    write_atomic(path, pages.page(f"Sweep report: {data.out_dir.name}", parts))
    return path


def _number(text: str) -> str:
    """A CSV cell shown with 4 significant digits where it is a number ("-" where empty)."""
    try:
        value = float(text)
    except (TypeError, ValueError):
        return str(text) or "-"
    return f"{value:.4g}" if math.isfinite(value) else "-"


def _provisional(text: str) -> str:
    """A provisional measure's cell: the number and the mark ("-" where the run has none)."""
    shown = _number(text)
    return shown if shown == "-" else shown + PROVISIONAL_MARK


def _describe(p: dict[str, Any]) -> str:
    d = p.get("distribution")
    keys = [k for k in ("values", "low", "high", "count", "mean", "std", "mean_log", "std_log", "levels")
            if p.get(k) is not None]
    return f"{d}: " + ", ".join(f"{k} = {p[k]}" for k in keys)


def write_report(path: str | Path, output: str | Path | None = None) -> Path:
    """Write ``report.html`` for a sweep folder (sweep.csv) or a calibration folder (calibration.csv),
    into the folder itself or into ``output``.

    Raises
    ------
    sweeps.folder.SweepFolderError
    """
    p = Path(path)
    if (p / "calibration.csv").is_file():
        from sweeps.calibrate import read_calibration, write_calibration_report

        return write_calibration_report(read_calibration(p), Path(output) if output else None)
    data = read_sweep(p)
    write_statistics(data)
    return write_sweep_report(data, output=Path(output) if output else None)
