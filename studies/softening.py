"""``runout study softening``: a strain-softening slope against the cell size, with and without a
softening length; its run-out against the clay's brittleness.

The scene (:func:`scene`) is a small riverbank of sensitive clay on a rough base (fixed bottom),
10 m high with a 1:2 face from the crest at x = 25 m to the toe at x = 45 m, undrained (phi = 0,
c_p = 25 kPa, 18 kN/m3, E = 5 MPa, nu = 0.45): the clay of x in [15, 39] m softens (linear law,
from peak at a plastic strain of 0.02 to the residual ``residual_pa`` at 0.5); the clay behind
x = 15 m is stiffer (c = 60 kPa, whose 10 m scarp stands: 3.83 c / gamma = 12.8 m) and does not
soften, so that the retrogression has an end the cell size does not set. The bank
stands at peak strength through a damped gravity stage (3 s); at the trigger the toe (the lowest
3 m of the face, x in [39, 45]) is remoulded by the river (its cohesion set to the residual one)
and the bank fails progressively for ``duration_s`` (40 s). It is the example
``projects/examples/sensitive_clay_spread.toml`` in small.

Measures of each run (times from the trigger):

- **failure time**: when the mean displacement of the particles within 1 m of the crest point
  (25 m, 10 m) first exceeds 0.5 m (H / 20), linear between frames (0.25 s apart);
- the time of the kinetic energy's peak;
- **run-out distance**: ``hazard.json``'s ``runout_distance_m``, the deposit's reach beyond the
  source's front (the toe) where it is more than 0.5 m thick, on a raster of 0.25 m cells for
  every cell size;
- **retrogression**: how far behind the crest the slide reached, the crest's x less the smallest
  x (at the release) of the particles that moved more than 1 m (0 where none behind the crest
  did).

Runs: cell sizes h = 1, 0.5, 0.25 m (two particles a cell each way) with ``softening_length_m =
1`` m (regularised) and without (the particles' own strain), at S_t = c_p / c_r = 6.25 (c_r = 4
kPa); then the brittleness S_t = 1 (no softening), 2, 4, 6.25 and 10 at h = 0.5 m, regularised.
Target: with the length, run-out and failure time within 5 % between the three cell sizes
(spread = (largest - smallest) / mean). The runs without a length are reported beside them (no
target: their spread is what the length is for).

Quick: h = 1 and 0.5 m only (each with and without the length); the brittleness at h = 1 m.
"""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any

import numpy as np

from projects.measures import surface_heights
from studies.common import (
    Note,
    Report,
    StudyResult,
    fmt,
    machine_line,
    new_figure,
    peak,
    quiet,
    run_project_measured,
    write_csv,
    write_json,
)

#: Bank geometry (m): height, crest x, toe x, the toe's remoulded part (x from, height), the end of
#: the sensitive clay behind the crest, the domain's length.
HEIGHT_M = 10.0
CREST_X_M = 25.0
TOE_X_M = 45.0
TOE_PART = (39.0, 3.0)
POCKET_START_X_M = 15.0
LENGTH_M = 160.0
#: The clay behind the sensitive pocket (Pa): its scarp of the bank's height stands.
BACK_PA = 60e3
#: Peak undrained strength (Pa) and the standard residual one (S_t = 6.25).
PEAK_PA = 25e3
RESIDUAL_PA = 4e3
#: The softening length of the regularised runs (m): the coarsest cell.
SOFTENING_LENGTH_M = 1.0
CELLS_M = (1.0, 0.5, 0.25)
QUICK_CELLS_M = (1.0, 0.5)
#: Sensitivities S_t = c_p / c_r of the brittleness runs (1: no softening).
SENSITIVITIES = (1.0, 2.0, 4.0, 6.25, 10.0)
DURATION_S = 40.0
OUTPUT_INTERVAL_S = 0.25
#: Failure: the crest particles' mean displacement (m) and the radius (m) that picks them.
FAILURE_DISPLACEMENT_M = 0.5
CREST_RADIUS_M = 1.0
#: Moved: the displacement (m) of a particle that counts as part of the slide.
MOVED_M = 1.0
#: The deposit thickness (m) above which a column counts for the run-out, and the raster's cell.
DEPOSIT_THRESHOLD_M = 0.5
HAZARD_CELL_M = 0.25
#: Target: run-out and failure time within this spread between the cell sizes, with the length.
SPREAD_TARGET = 0.05


def scene(cell_m: float, *, length_m: float | None = SOFTENING_LENGTH_M, residual_pa: float | None = RESIDUAL_PA,
          duration_s: float = DURATION_S) -> Any:
    """The softening bank (see the module docstring) as a validated project, on the CPU.

    Parameters
    ----------
    cell_m : float
        Cell size (m).
    length_m : float or None
        ``softening_length_m``; None: the particles' own strain.
    residual_pa : float or None
        Residual cohesion of the softening clay (and of the remoulded toe); None: no softening
        (the toe's cohesion still falls to :data:`RESIDUAL_PA`).
    duration_s : float
        The failure stage's duration (s).
    """
    from projects.schema import validate_project

    clay = {"model": "drucker-prager", "density_kg_m3": "18 kN/m3", "youngs_modulus_pa": 5e6, "poisson_ratio": 0.45,
            "cohesion_pa": PEAK_PA, "friction_angle_deg": 0.0}
    sensitive = dict(clay)
    back = {**clay, "cohesion_pa": BACK_PA}
    if residual_pa is not None:
        sensitive.update({"softening_law": "linear", "residual_cohesion_pa": residual_pa, "peak_plastic_strain": 0.02,
                          "residual_plastic_strain": 0.5})
        if length_m is not None:
            sensitive["softening_length_m"] = length_m
    x_part, y_part = TOE_PART
    h = HEIGHT_M
    return validate_project({
        "runout": {"schema_version": 2, "title": f"softening bank, cells {cell_m:g} m"},
        "domain": {"origin_m": [0.0, 0.0], "size_m": [LENGTH_M, h + 3.0], "cell_size_m": cell_m,
                   "boundaries": {"left": "slip", "right": "slip", "bottom": "fixed", "top": "open"}},
        "materials": {"clay": back, "sensitive_clay": sensitive, "toe": dict(clay)},
        "bodies": [
            {"name": "clay", "material": "clay",
             "polygon_m": [[0.0, 0.0], [POCKET_START_X_M, 0.0], [POCKET_START_X_M, h], [0.0, h]]},
            {"name": "sensitive clay", "material": "sensitive_clay",
             "polygon_m": [[POCKET_START_X_M, 0.0], [x_part, 0.0], [x_part, y_part], [CREST_X_M, h],
                           [POCKET_START_X_M, h]]},
            {"name": "toe", "material": "toe", "polygon_m": [[x_part, 0.0], [TOE_X_M, 0.0], [x_part, y_part]]},
        ],
        "particles": {"per_cell": 2},
        "numerics": {"scheme": "apic-affine", "cfl": 0.5, "arch": "cpu"},
        "stages": [
            {"name": "initial stress", "type": "gravity", "duration_s": 3.0,
             "damping": {"type": "local", "coefficient": 0.7}},
            {"name": "toe erosion", "type": "dynamic", "duration_s": duration_s,
             "material_changes": {"toe": {"cohesion_pa": RESIDUAL_PA if residual_pa is None else residual_pa}}},
        ],
        "output": {"interval_s": OUTPUT_INTERVAL_S, "fields": ["displacement"]},
        "hazard": {"cell_size_m": HAZARD_CELL_M, "deposit_threshold_m": DEPOSIT_THRESHOLD_M,
                   "mobilised_displacement_m": MOVED_M},
    })


def spread(values: list[float]) -> float:
    """``(largest - smallest) / mean`` of finite values (NaN with fewer than two, or a zero mean)."""
    v = [x for x in values if x is not None and math.isfinite(x)]
    if len(v) < 2 or len(v) < len(values):
        return math.nan
    mean = sum(v) / len(v)
    return (max(v) - min(v)) / abs(mean) if mean else math.nan


def crossing_time(times: list[float], values: list[float], level: float) -> float:
    """The first time ``values`` reaches ``level``, linear between samples (NaN if never)."""
    for i, v in enumerate(values):
        if v >= level:
            if i == 0:
                return times[0]
            t0, t1, v0 = times[i - 1], times[i], values[i - 1]
            return t0 + (t1 - t0) * (level - v0) / (v - v0) if v > v0 else t1
    return math.nan


def run_case(out: Path, label: str, cell_m: float, length_m: float | None, residual_pa: float | None,
             note: Note = quiet) -> dict[str, Any]:
    """Run one case and measure it (the keys of the study's tables)."""
    import json

    project = scene(cell_m, length_m=length_m, residual_pa=residual_pa, duration_s=DURATION_S)
    crest = np.array([CREST_X_M, HEIGHT_M])
    track: dict[str, Any] = {"t": [], "d": [], "last": None}

    def on_frame(frame: Any) -> None:
        d = frame.diagnostics
        if d.stage_index < 1:
            return
        disp = np.asarray(frame.fields["displacement"], dtype=np.float64)
        pos = np.asarray(frame.fields["positions"], dtype=np.float64)
        if "crest" not in track:  # the first dynamic frame: where the particles were at the release
            start = pos - disp
            track["crest"] = np.nonzero(np.linalg.norm(start - crest, axis=1) <= CREST_RADIUS_M)[0]
        track["t"].append(d.stage_time_s)
        track["d"].append(float(np.linalg.norm(disp[track["crest"]], axis=1).mean()))
        track["last"] = (pos, disp, np.asarray(frame.fields["active"], dtype=bool))

    rec = run_project_measured(project, out, label, keep_frames=False, on_frame=on_frame)
    row: dict[str, Any] = {"label": label, "cell_m": cell_m, "regularised": length_m is not None,
                           "softening_length_m": length_m,
                           "sensitivity": PEAK_PA / residual_pa if residual_pa is not None else 1.0,
                           "status": rec.status, "particles": rec.particles, "steps": rec.steps,
                           "wall_s": rec.wall_s}
    row["failure_time_s"] = crossing_time(track["t"], track["d"], FAILURE_DISPLACEMENT_M)
    stage = np.asarray(rec.series.get("stage_index", []))
    dynamic = {k: np.asarray(v)[stage >= 1] for k, v in rec.series.items()}
    if "stage_time_s" in dynamic:
        dynamic["time_s"] = dynamic["stage_time_s"]
    row["ke_peak_time_s"] = peak(dynamic, "kinetic_energy_J_per_m")[1]
    hazard_path = Path(out) / "hazard.json"
    hazard = json.loads(hazard_path.read_text(encoding="utf-8")) if hazard_path.is_file() else {}
    row["runout_m"] = hazard.get("runout_distance_m")
    row["runout_m"] = math.nan if row["runout_m"] is None else float(row["runout_m"])
    row["retrogression_m"] = math.nan
    if track["last"] is not None:
        pos, disp, active = track["last"]
        moved = active & (np.linalg.norm(disp, axis=1) > MOVED_M)
        if moved.any():
            row["retrogression_m"] = max(0.0, float(CREST_X_M - (pos[moved, 0] - disp[moved, 0]).min()))
        np.savez_compressed(Path(out) / "final.npz", positions=pos[active], displacement=disp[active])
    note(f"  {label}: {rec.status}, {rec.particles:,} particles, {rec.steps:,} steps, {rec.wall_s:.0f} s; "
         f"failure {fmt(row['failure_time_s'])} s, run-out {fmt(row['runout_m'])} m, "
         f"retrogression {fmt(row['retrogression_m'])} m")
    return row


def run(out_dir: Path, quick: bool = False, note: Note = quiet) -> StudyResult:
    """Run the study and write ``report.md``, ``softening.json``, ``mesh.csv``, ``brittleness.csv``.

    Parameters
    ----------
    out_dir : Path
    quick : bool
        Cells of 1 and 0.5 m only, the brittleness at 1 m (see the module docstring).
    note : callable

    Returns
    -------
    StudyResult
    """
    t0 = time.perf_counter()
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    cells = QUICK_CELLS_M if quick else CELLS_M
    brittle_cell = cells[0] if quick else 0.5
    note(f"softening: cells {', '.join(f'{c:g}' for c in cells)} m with and without the length; "
         f"brittleness at {brittle_cell:g} m")
    mesh: list[dict[str, Any]] = []
    for length in (SOFTENING_LENGTH_M, None):
        for cell in cells:
            tag = f"h{cell:g}-{'l' if length else 'nol'}"
            mesh.append(run_case(out_dir / "runs" / tag, tag, cell, length, RESIDUAL_PA, note))
    brittle: list[dict[str, Any]] = []
    for s_t in SENSITIVITIES:
        residual = None if s_t == 1.0 else PEAK_PA / s_t
        same = [r for r in mesh if r["cell_m"] == brittle_cell and r["regularised"] and residual == RESIDUAL_PA]
        if same:
            brittle.append(dict(same[0]))
            continue
        tag = f"h{brittle_cell:g}-St{s_t:g}"
        brittle.append(run_case(out_dir / "runs" / tag, tag, brittle_cell, SOFTENING_LENGTH_M, residual, note))

    measures = ("failure_time_s", "ke_peak_time_s", "runout_m", "retrogression_m")
    spreads = {}
    for regularised in (True, False):
        rows = [r for r in mesh if r["regularised"] == regularised]
        spreads["with length" if regularised else "without length"] = {m: spread([r[m] for r in rows])
                                                                       for m in measures}
    reg = spreads["with length"]
    completed = all(r["status"] == "completed" for r in mesh + brittle)
    checks = {
        "completed": completed,
        "runout_within_5_percent": bool(math.isfinite(reg["runout_m"]) and reg["runout_m"] <= SPREAD_TARGET),
        "failure_time_within_5_percent": bool(math.isfinite(reg["failure_time_s"])
                                              and reg["failure_time_s"] <= SPREAD_TARGET),
    }
    passed = all(checks.values())
    write_csv(out_dir / "mesh.csv", mesh)
    write_csv(out_dir / "brittleness.csv", brittle)
    data = {"quick": quick, "cells_m": list(cells), "softening_length_m": SOFTENING_LENGTH_M,
            "residual_pa": RESIDUAL_PA, "peak_pa": PEAK_PA, "mesh": mesh, "brittleness": brittle,
            "spreads": spreads, "checks": checks, "passed": passed, "study_wall_s": time.perf_counter() - t0}
    write_json(out_dir / "softening.json", data)

    report = Report(out_dir, "Study softening: a strain-softening slope against the cell size")
    report.text(
        f"{'**quick** (reduced): cells of 1 and 0.5 m' if quick else '**full**: cells of 1, 0.5 and 0.25 m'}, "
        "two particles a cell each way, apic-affine, cfl 0.5, f32. Machine: " + machine_line() + ".",
        "Scene: a riverbank of sensitive clay 10 m high, 1:2 face (crest x = 25 m, toe x = 45 m) on a rough base, "
        "undrained (phi = 0, c_p = 25 kPa, 18 kN/m3, E = 5 MPa, nu = 0.45); the clay between x = 15 m and the toe "
        "softens linearly from a plastic strain of 0.02 to the residual cohesion at 0.5, the clay behind x = 15 m "
        "is stiffer (60 kPa) and does not soften. A gravity stage (3 s, damped) at peak strength, then the toe's lowest 3 m remoulded (the "
        "trigger) and 40 s of failure. Failure time: the crest particles' mean displacement past 0.5 m; run-out: "
        "hazard.json's runout_distance_m (deposit over 0.5 m thick, beyond the toe); retrogression: the crest's x "
        "less the rearmost start of the particles that moved more than 1 m. Times from the trigger.",
    )
    report.heading("Verdict")
    report.text(("PASS" if passed else "FAIL") + ": " + ", ".join(
        f"{k.replace('_', ' ')}: {'yes' if v else 'NO'}" for k, v in checks.items()) + f" (target: spread at "
        f"most {SPREAD_TARGET:.0%} between the cell sizes with softening_length_m = {SOFTENING_LENGTH_M:g} m).")
    report.heading("Cell sizes")
    header = ["softening length", "cell (m)", "particles", "failure time (s)", "KE peak (s)", "run-out (m)",
              "retrogression (m)", "wall (s)"]
    rows = [[fmt(r["softening_length_m"]) + " m" if r["regularised"] else "none", fmt(r["cell_m"]),
             fmt(r["particles"]), fmt(r["failure_time_s"]), fmt(r["ke_peak_time_s"]), fmt(r["runout_m"]),
             fmt(r["retrogression_m"]), fmt(r["wall_s"])] for r in mesh]
    report.table(header, rows)
    report.table(["softening length", "failure time", "KE peak", "run-out", "retrogression"],
                 [[name] + [f"{100 * s[m]:.1f} %" if math.isfinite(s[m]) else "-" for m in measures]
                  for name, s in spreads.items()])
    report.text("Spread: (largest - smallest) / mean over the cell sizes.")
    report.heading("Brittleness")
    report.table(["S_t = c_p / c_r", "residual cohesion (kPa)", "failure time (s)", "run-out (m)",
                  "retrogression (m)"],
                 [[fmt(r["sensitivity"]), fmt(PEAK_PA / r["sensitivity"] / 1e3) if r["sensitivity"] > 1 else
                   "no softening", fmt(r["failure_time_s"]), fmt(r["runout_m"]), fmt(r["retrogression_m"])]
                  for r in brittle])
    report.text(f"At {brittle_cell:g} m cells with softening_length_m = {SOFTENING_LENGTH_M:g} m; S_t = 1: the "
                "clay does not soften (only the toe is remoulded).")
    _plots(report, out_dir, mesh, brittle)
    report.text("Raw data: `mesh.csv`, `brittleness.csv`, `softening.json`; runs under `runs/` (final.npz each).")
    path = report.write()
    verdict = [f"softening {'PASS' if passed else 'FAIL'} ({'quick' if quick else 'full'}; "
               f"{time.perf_counter() - t0:.0f} s)"]
    for name, s in spreads.items():
        verdict.append(f"{name}: spread of failure time {fmt(100 * s['failure_time_s'])} %, run-out "
                       f"{fmt(100 * s['runout_m'])} %, retrogression {fmt(100 * s['retrogression_m'])} %")
    verdict.append("run-out by S_t: " + ", ".join(f"{fmt(r['sensitivity'])}: {fmt(r['runout_m'])} m" for r in brittle))
    return StudyResult("softening", passed, verdict, path, time.perf_counter() - t0, data)


def _plots(report: Report, out_dir: Path, mesh: list[dict[str, Any]], brittle: list[dict[str, Any]]) -> None:
    fig, axes = new_figure(9.0, 4.0, ncols=1, nrows=2)
    for ax, regularised in zip(axes[:, 0], (True, False)):
        for r in (r for r in mesh if r["regularised"] == regularised):
            path = out_dir / "runs" / r["label"] / "final.npz"
            if not path.is_file():
                continue
            pos = np.load(path)["positions"]
            xs = np.arange(0.0, LENGTH_M + 1e-9, 0.5)
            spacing = r["cell_m"] / 2.0
            ax.plot(xs, surface_heights(pos, None, spacing, xs, window_m=max(1.0, 2.0 * spacing)), lw=1.0,
                    label=f"h = {r['cell_m']:g} m")
        ax.set_title(f"softening_length_m = {SOFTENING_LENGTH_M:g} m" if regularised else "no softening length",
                     fontsize=9)
        ax.set_aspect("equal")
        ax.set_ylabel("y (m)")
        ax.legend(fontsize=7, loc="upper right")
    axes[1, 0].set_xlabel("x (m)")
    report.figure(fig, "deposits", "Final surface (highest particle top within 1 m) at each cell size, with and "
                  "without the softening length.")
    fig, ax = new_figure(5.0, 3.2)
    s = [r["sensitivity"] for r in brittle]
    ax.plot(s, [r["runout_m"] for r in brittle], "o-", label="run-out")
    ax.plot(s, [r["retrogression_m"] for r in brittle], "s--", label="retrogression")
    ax.set_xlabel("sensitivity S_t = c_p / c_r")
    ax.set_ylabel("m")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    report.figure(fig, "brittleness", "Run-out and retrogression against the clay's sensitivity.")
