"""``runout study bui2008``: the aluminium-bar collapse of Bui et al. (2008), paper section 2.5.

Runs ``projects/examples/bui2008_aluminium_bars.toml`` with each scheme through
:func:`projects.runner.run_project`, then compares the final free surface with the experiment
(``bui2008_final_surface.csv``) and the kinetic energy, momentum and speed with the paper's
Figure 7 and its Table 2 timing ratio. Deposit measures are defined in :mod:`studies.common`.

Full: the paper's resolution (2 mm cells, 4 particles per cell, 20000 particles, dt = 20 us,
1 s). Quick: 5 mm cells (3200 particles) with the time step scaled with the cell (50 us, the same
fraction of the critical step), judged against the coarse tolerances of :data:`COARSE_TARGETS`.

The scene is the paper's (K0 stage, slip back wall, frictional base delta = phi = 19.8 deg,
Drucker-Prager with psi = 0) with two model choices of its own: the mu(I) law of dense granular
flow (Jop, Forterre and Pouliquen 2006's parameters) and the cone matched to tan(phi) in simple
shear, the form in which that law reads phi. :mod:`studies.bui2008_choices` measures each choice.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from projects.measures import REACH_THICKNESS_M
from studies.common import (
    Deposit,
    Note,
    Report,
    RunRecord,
    StudyResult,
    FAILURE_HEIGHTS_M,
    bui_experiment,
    bui_failure_line,
    experiment_centroid,
    experiment_failure_x,
    experiment_toe,
    fmt,
    load_scene,
    machine_line,
    measure_deposit,
    new_figure,
    peak,
    quiet,
    run_project_measured,
    series_finite,
    settle_time,
    write_csv,
    write_json,
    write_series,
)

SCENE = "bui2008_aluminium_bars"
#: The paper's step at 2 mm cells, about 0.2 of the critical step; scaled with the cell size.
DT_PER_CELL_S_M = 2.0e-5 / 0.002
BLOCK_HEIGHT_M = 0.1


@dataclass(frozen=True)
class Targets:
    """Acceptance bounds of the deposit (m): RMS deviation, toe range, crest range; optionally the
    reach and the deposit's centroid (:func:`studies.common.profile_centroid`)."""

    rms_max_m: float
    toe_m: tuple[float, float]
    crest_m: tuple[float, float]
    why: str
    reach_m: tuple[float, float] | None = None
    centroid_m: tuple[float, float] | None = None

    def check(self, dep: Deposit) -> dict[str, bool]:
        out = {
            "rms": bool(dep.rms_m <= self.rms_max_m),
            "toe": bool(self.toe_m[0] <= dep.toe_m <= self.toe_m[1]),
            "crest": bool(self.crest_m[0] <= dep.crest_m <= self.crest_m[1]),
        }
        if self.reach_m is not None:
            out["reach"] = bool(self.reach_m[0] <= dep.reach_m <= self.reach_m[1])
        if self.centroid_m is not None:
            out["centroid"] = bool(self.centroid_m[0] <= dep.centroid_m <= self.centroid_m[1])
        return out


#: The experimental deposit's centroid (studies.common.experiment_centroid) and the allowed distance (m).
EXPERIMENT_CENTROID_M = 0.1322
CENTROID_TOLERANCE_M = 0.005
#: The validation targets at the standard resolution (2 mm cells, 4 particles per cell): the
#: surface within 6 mm RMS, the toe (2 mm thickness) in 0.40-0.48 m about the experiment's
#: 0.429 m, the crest, and the deposit's centroid within 5 mm of the experiment's.
TARGETS = Targets(0.006, (0.40, 0.48), (0.095, 0.101), "the validation targets at 2 mm cells, 4 particles per cell",
                  centroid_m=(EXPERIMENT_CENTROID_M - CENTROID_TOLERANCE_M, EXPERIMENT_CENTROID_M + CENTROID_TOLERANCE_M))
#: Targets at 5 mm cells, 4 particles per cell (quick study, regression test): the same toe window,
#: RMS, crest and centroid as at 2 mm (measured 0.449 m, 1.8 mm, 0.0999 m, 0.1300 m; the source
#: paper's rate-independent model gives a toe of 0.495 m and a centroid of 0.1388 m at 4 mm,
#: 0.517 m and 0.1432 m at 2 mm), and the reach (5 mm thickness) in [0.38, 0.42] m about the
#: experiment's 0.396 m (measured 0.404 m; the paper's model 0.429 m at 4 mm).
COARSE_TARGETS = Targets(0.006, (0.40, 0.48), (0.095, 0.101), "the validation targets at 5 mm cells", reach_m=(0.38, 0.42),
                         centroid_m=TARGETS.centroid_m)

#: The paper's reported numbers (section 2.5, Figure 7, Table 2).
PAPER = {
    "ke_peak_time_s": 0.16,
    "max_speed_m_s": 1.5,
    "slide_duration_s": 0.8,
    "table2_apic_s": 28.66,
    "table2_apic_affine_s": 13.18,
}


def bui_overrides(cell_m: float, per_cell: int, scheme: str, *, time_step_s: float | None = None,
                  cfl: float | None = None, duration_s: float = 1.0, interval_s: float = 0.01,
                  fields: tuple[str, ...] = ("velocity", "displacement")) -> list[str]:
    """``--set`` overrides of the aluminium-bar example for one run.

    Parameters
    ----------
    cell_m : float
        Cell size, m.
    per_cell : int
        Particles per cell per direction.
    scheme : str
    time_step_s, cfl : float, optional
        One of them; default: the paper's step scaled with the cell, ``1e-2 * cell_m`` s.
    duration_s : float
        Length of the collapse stage, s.
    interval_s : float
        Output interval, s.
    fields : tuple of str
        Output fields (positions are always written; the failure line needs ``displacement``).
    """
    sets = [f"domain.cell_size_m={cell_m!r}", f"particles.per_cell={int(per_cell)}", f"numerics.scheme={scheme}",
            f"stages.1.duration_s={duration_s!r}", f"output.interval_s={interval_s!r}",
            "output.fields=[" + ", ".join(f'"{f}"' for f in fields) + "]"]
    if cfl is not None:
        sets.append(f"numerics.cfl={cfl!r}")
    else:
        sets.append(f"numerics.time_step_s={(time_step_s or DT_PER_CELL_S_M * cell_m)!r}")
    return sets


def run_bui(out_dir: Path, label: str, cell_m: float, per_cell: int, scheme: str, experiment: np.ndarray, *,
            keep_frames: bool = False, time_limit_s: float | None = None, sets: tuple[str, ...] = (),
            change: Any = None, **kwargs: Any) -> tuple[RunRecord, Deposit | None]:
    """Run the aluminium-bar scene once and measure its deposit.

    ``sets``: further ``--set`` overrides; ``change``: a callable that returns the loaded project
    changed (a model choice a ``--set`` cannot make, such as removing a key).

    Returns
    -------
    (RunRecord, Deposit or None)
        The deposit is None when the run produced no final frame.
    """
    project = load_scene(SCENE, [*bui_overrides(cell_m, per_cell, scheme, **kwargs), *sets])
    if change is not None:
        project = change(project)
    params = {"scheme": scheme, "cell_mm": 1e3 * cell_m, "per_cell": per_cell,
              "particles_per_cell": per_cell * per_cell}
    if kwargs.get("cfl") is not None:
        params["cfl"] = kwargs["cfl"]
    rec = run_project_measured(project, out_dir, label, params, keep_frames=keep_frames, time_limit_s=time_limit_s)
    dep = None
    if rec.positions is not None and rec.status == "completed":
        dep = measure_deposit(rec.positions, rec.active, rec.spacing_m, experiment,
                              displacement=rec.displacement, failure_line=bui_failure_line())
        rec.extra.update(dep.as_dict())
    ke, t_ke = peak(rec.series, "kinetic_energy_J_per_m")
    vmax, t_v = peak(rec.series, "max_speed_m_s")
    rec.extra.update({"ke_peak_J_per_m": ke, "ke_peak_time_s": t_ke, "max_speed_m_s": vmax, "max_speed_time_s": t_v,
                      "settle_time_s": settle_time(rec.series), "finite": series_finite(rec.series)})
    if rec.series.get("step") is not None and len(rec.series["step"]) and rec.series.get("dt_s") is not None:
        rec.extra["dt_s"] = float(np.median(rec.series["dt_s"][1:])) if len(rec.series["dt_s"]) > 1 else math.nan
    return rec, dep


def run(out_dir: Path, quick: bool = False, note: Note = quiet,
        schemes: tuple[str, ...] = ("apic-affine", "apic", "mpm")) -> StudyResult:
    """Run the study and write ``report.md``, ``bui2008.json``, ``runs.csv`` and the series.

    Parameters
    ----------
    out_dir : Path
        Study folder (created); each run's results folder goes under ``runs/``.
    quick : bool
        5 mm cells instead of 2 mm (see the module docstring).
    note : callable
        Progress lines.
    schemes : tuple of str
        Schemes to run; the first one is judged against the targets.

    Returns
    -------
    StudyResult
    """
    t0 = time.perf_counter()
    out_dir = Path(out_dir)
    experiment = bui_experiment()
    cell = 0.005 if quick else 0.002
    targets = COARSE_TARGETS if quick else TARGETS
    records: list[RunRecord] = []
    deposits: dict[str, Deposit | None] = {}
    for scheme in schemes:
        note(f"bui2008: {scheme}, {cell * 1e3:g} mm cells")
        rec, dep = run_bui(out_dir / "runs" / scheme, scheme, cell, 2, scheme, experiment,
                           keep_frames=False, interval_s=0.005, fields=("velocity", "stress", "displacement"))
        records.append(rec)
        deposits[scheme] = dep
        note(f"  {rec.status} in {rec.wall_s:.0f} s: " + ", ".join(
            f"{k} {fmt(rec.extra.get(k))}" for k in ("rms_mm", "toe_m", "crest_m", "ke_peak_time_s")))

    main = records[0]
    main_dep = deposits[main.label]
    checks = targets.check(main_dep) if main_dep is not None else {"rms": False, "toe": False, "crest": False,
                                                                     "reach": False, "centroid": False}
    passed = main.ok and all(checks.values())
    by = {r.label: r for r in records}
    ratio_wall = (by["apic"].wall_s / by["apic-affine"].wall_s) if {"apic", "apic-affine"} <= by.keys() else math.nan
    ratio_cpu = (by["apic"].cpu_s / by["apic-affine"].cpu_s) if {"apic", "apic-affine"} <= by.keys() else math.nan
    ratio_rate = (by["apic-affine"].particle_steps_per_s / by["apic"].particle_steps_per_s
                  if {"apic", "apic-affine"} <= by.keys() and by["apic"].particle_steps_per_s else math.nan)

    # ---------------------------------------------------------------- raw data
    write_csv(out_dir / "runs.csv", [r.row() for r in records])
    for r in records:
        write_series(out_dir / f"series_{r.label}.csv", r.series)
    surf = {"x_m": main_dep.surface_x} if main_dep is not None else {}
    for label, dep in deposits.items():
        if dep is not None:
            surf[f"y_{label}_m"] = dep.surface_y
    if surf:
        write_series(out_dir / "surface.csv", surf)
    failure = bui_failure_line()
    exp_failure = (experiment_failure_x(failure, FAILURE_HEIGHTS_M) if failure is not None
                   else np.full(len(FAILURE_HEIGHTS_M), math.nan))
    data = {
        "quick": quick, "cell_size_m": cell, "targets": dict(vars(targets)), "checks": checks, "passed": passed,
        "experiment_toe_m": experiment_toe(experiment), "experiment_centroid_m": experiment_centroid(experiment),
        "experiment_failure_x_m": dict(zip((f"{1e3 * h:.0f}mm" for h in FAILURE_HEIGHTS_M), exp_failure.tolist())),
        "experiment_reach_m": experiment_toe(experiment, REACH_THICKNESS_M), "paper": PAPER,
        "runs": [r.row() for r in records],
        "timing": {"apic_over_apic_affine_wall": ratio_wall, "apic_over_apic_affine_cpu": ratio_cpu,
                   "apic_affine_over_apic_rate": ratio_rate,
                   "paper_table2_ratio": PAPER["table2_apic_s"] / PAPER["table2_apic_affine_s"]},
        "study_wall_s": time.perf_counter() - t0,
    }
    write_json(out_dir / "bui2008.json", data)

    # ---------------------------------------------------------------- report
    report = Report(out_dir, "Study bui2008: aluminium-bar collapse (Bui et al. 2008; paper section 2.5)")
    size = ("**quick** (reduced): 5 mm cells, 2 x 2 particles per cell (3200 particles), dt = 50 us "
            "(the paper's 20 us scaled with the cell, the same fraction of the critical step), 1 s; "
            "judged against coarse tolerances") if quick else (
            "**full**: the paper's set-up, 2 mm cells, 2 x 2 particles per cell (20000 particles), dt = 20 us, 1 s")
    report.text(
        f"Size: {size}. Scene: `projects/examples/{SCENE}.toml` (K0 initial stress, slip back wall, "
        "frictional base with delta = phi = 19.8 deg, the cone matched in simple shear, the mu(I) law with "
        "Jop et al.'s (2006) parameters). Each scheme runs through `projects.runner.run_project`; "
        "`runout study bui2008-choices` measures what each of these choices does.",
        f"Machine: {machine_line()}. Study wall time {data['study_wall_s']:.0f} s.",
    )
    report.heading("Verdict")
    report.text(("PASS" if passed else "FAIL") + f": {main.label} against the {targets.why}.")
    report.table(
        ["measure", "target", main.label, "met"],
        [["RMS deviation over x in [0, 0.42] m (mm)", f"<= {targets.rms_max_m * 1e3:g}",
          fmt(main.extra.get("rms_mm")), checks["rms"]],
         ["toe, furthest x with >= 2 mm of deposit (m)", f"{targets.toe_m[0]:g} .. {targets.toe_m[1]:g}",
          fmt(main.extra.get("toe_m")), checks["toe"]],
         ["crest height near the wall (m)", f"{targets.crest_m[0]:g} .. {targets.crest_m[1]:g}",
          fmt(main.extra.get("crest_m"), 4), checks["crest"]]]
        + ([["reach, furthest x with >= 5 mm of deposit (m)", f"{targets.reach_m[0]:g} .. {targets.reach_m[1]:g}",
             fmt(main.extra.get("reach_m")), checks["reach"]]] if targets.reach_m else [])
        + ([["deposit centroid (m)", f"{targets.centroid_m[0]:g} .. {targets.centroid_m[1]:g}",
             fmt(main.extra.get("centroid_m"), 4), checks["centroid"]]] if targets.centroid_m else []),
    )
    report.heading("Deposit and dynamics by scheme")
    report.text(f"Experiment: crest {experiment[0, 1]:.4f} m, toe (2 mm) {data['experiment_toe_m']:.3f} m, "
                f"reach (5 mm) {data['experiment_reach_m']:.3f} m. "
                "Measures as defined in `studies/common.py`: surface = highest particle top in a "
                "sliding 5 mm window (or 2 spacings if wider); toe = furthest particle edge where the local "
                "deposit (particle tops within one spacing) is at least 2 mm thick; reach = the same at 5 mm "
                "(the run-out of the body of the deposit, insensitive to the thin tail); front = furthest particle "
                "edge; crest = highest particle top within 10 mm of the wall.")
    rows = []
    for r in records:
        e = r.extra
        rows.append([r.label, r.status, fmt(e.get("rms_mm")), fmt(e.get("toe_m")), fmt(e.get("reach_m")),
                     fmt(e.get("front_m")),
                     fmt(e.get("crest_m"), 4), fmt(e.get("ke_peak_time_s")), fmt(e.get("ke_peak_J_per_m")),
                     fmt(e.get("max_speed_m_s")), fmt(e.get("settle_time_s"))])
    rows.append(["paper / experiment", "", "", f"{data['experiment_toe_m']:.3f}",
                 f"{data['experiment_reach_m']:.3f}", "", f"{experiment[0, 1]:.4f}",
                 "0.16", "", "about 1.5", "about 0.8"])
    report.table(["scheme", "status", "RMS (mm)", "toe (m)", "reach (m)", "front (m)", "crest (m)", "KE peak at (s)",
                  "KE peak (J/m)", "max speed (m/s)", "KE < 1 % of peak at (s)"], rows)
    report.text("Deposit centroid: the horizontal centroid of the area under the surface. Failure line: the edge "
                "of the undisturbed wedge, where the row of particles that started at that height first holds "
                f"particles that moved more than 1 mm horizontally; its RMS: horizontal distance from the "
                "experiment's line at the experiment's points 5-95 mm high (`studies/common.py`).")
    heights = [f"failure line at {1e3 * h:.0f} mm (m)" for h in FAILURE_HEIGHTS_M]
    report.table(["scheme", "centroid (m)", *heights, "failure line RMS (mm)"],
                 [[r.label, fmt(r.extra.get("centroid_m"), 4),
                   *(fmt(r.extra.get(f"failure_x_{1e3 * h:.0f}mm_m")) for h in FAILURE_HEIGHTS_M),
                   fmt(r.extra.get("failure_rms_mm"))] for r in records]
                 + [["experiment", f"{data['experiment_centroid_m']:.4f}", *(fmt(x) for x in exp_failure), ""]])
    report.heading("Cost (paper Table 2)")
    report.text("Wall time of the whole run (set-up, compilation, 200 frames written) and process CPU time, "
                "measured one after the other in this study on a shared CPU; particle-steps per second from "
                "the timed loop. The paper's ratio is on an RTX 3060 GPU.")
    report.table(["scheme", "particles", "steps", "wall (s)", "CPU (s)", "particle-steps/s"],
                 [[r.label, r.particles, r.steps, fmt(r.wall_s), fmt(r.cpu_s), fmt(r.particle_steps_per_s)]
                  for r in records])
    report.table(["ratio apic / apic-affine", "measured", "paper Table 2"],
                 [["wall time", fmt(ratio_wall), f"{data['timing']['paper_table2_ratio']:.2f} (28.66 s / 13.18 s)"],
                  ["CPU time", fmt(ratio_cpu), ""], ["particle-steps/s (inverse)", fmt(ratio_rate), ""]])
    _plots(report, records, deposits, experiment, cell, failure)
    report.text("Raw data: `runs.csv` (one row per run), `series_SCHEME.csv` (kinetic energy, momentum, "
                "speed every 5 ms), `surface.csv` (surfaces on a 1 mm grid), `bui2008.json` (everything "
                "above); the results folders are under `runs/` (frames removed, final positions in `final.npz`).")
    path = report.write()

    verdict = [f"bui2008 {'PASS' if passed else 'FAIL'} ({'quick, 5 mm' if quick else 'full, 2 mm'} cells; "
               f"{time.perf_counter() - t0:.0f} s)"]
    verdict.append(f"{main.label}: RMS {fmt(main.extra.get('rms_mm'))} mm (<= {targets.rms_max_m * 1e3:g}), "
                   f"toe {fmt(main.extra.get('toe_m'))} m ({targets.toe_m[0]:g}..{targets.toe_m[1]:g}), "
                   f"crest {fmt(main.extra.get('crest_m'), 4)} m ({targets.crest_m[0]:g}..{targets.crest_m[1]:g}), "
                   f"KE peak at {fmt(main.extra.get('ke_peak_time_s'))} s (paper 0.16)")
    if math.isfinite(ratio_wall):
        verdict.append(f"apic / apic-affine wall time {ratio_wall:.2f}x (paper 2.17x)")
    return StudyResult("bui2008", passed, verdict, path, time.perf_counter() - t0, data)


def plot_particles(ax: Any, rec: RunRecord, label: str) -> None:
    """A run's final particles: grey where they moved more than 1 mm horizontally, blue in the
    undisturbed wedge (grey everywhere without the displacements)."""
    if rec.positions is None:
        return
    act = rec.active if rec.active is not None else np.ones(len(rec.positions), bool)
    still = np.zeros(len(rec.positions), bool)
    if rec.displacement is not None:
        still = np.abs(rec.displacement[:, 0]) <= 1e-3
    ax.scatter(rec.positions[act & ~still, 0], rec.positions[act & ~still, 1], s=0.3, c="0.75",
               label=f"{label} particles")
    if still.any():
        ax.scatter(rec.positions[act & still, 0], rec.positions[act & still, 1], s=0.3, c="lightsteelblue",
                   label=f"{label}: undisturbed wedge (moved <= 1 mm)")


def plot_experiment(ax: Any, experiment: np.ndarray, failure: np.ndarray | None) -> None:
    """The experiment's surface and failure line (Bui et al. 2008) and the initial block."""
    ax.plot(experiment[:, 0], experiment[:, 1], "k^", ms=4, label="experiment: surface (Bui et al. 2008)")
    if failure is not None:
        ax.plot(failure[:, 0], failure[:, 1], "kv--", ms=4, lw=0.8, label="experiment: failure line")
    ax.plot([0, 0.2, 0.2], [0.1, 0.1, 0.0], "k:", lw=0.8, label="initial block")
    ax.set_xlim(0, 0.55)
    ax.set_ylim(0, 0.11)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_aspect("equal")


def _plots(report: Report, records: list[RunRecord], deposits: dict[str, Deposit | None],
           experiment: np.ndarray, cell: float, failure: np.ndarray | None = None) -> None:
    colours = {"apic-affine": "tab:blue", "apic": "tab:orange", "mpm": "tab:green"}
    fig, ax = new_figure(8.0, 3.2)
    main = records[0]
    plot_particles(ax, main, main.label)
    for label, dep in deposits.items():
        if dep is not None:
            ax.plot(dep.surface_x, dep.surface_y, color=colours.get(label), lw=1.2, label=f"{label} surface")
    plot_experiment(ax, experiment, failure)
    ax.legend(fontsize=7, loc="upper right")
    report.figure(fig, "surface", f"Final free surface and failure line at t = 1 s against the experiment "
                  f"({cell * 1e3:g} mm cells).")

    fig, axes = new_figure(8.0, 6.0, ncols=1, nrows=3)
    for r in records:
        t = r.series.get("time_s", np.array([]))
        c = colours.get(r.label)
        axes[0, 0].plot(t, r.series.get("kinetic_energy_J_per_m", []), color=c, label=r.label)
        axes[1, 0].plot(t, r.series.get("momentum_x", []), color=c, label=f"{r.label} x")
        axes[1, 0].plot(t, r.series.get("momentum_y", []), color=c, ls="--", label=f"{r.label} y")
        axes[2, 0].plot(t, r.series.get("max_speed_m_s", []), color=c, label=r.label)
    axes[0, 0].axvline(0.16, color="k", ls=":", lw=0.8, label="paper: peak at 0.16 s")
    axes[2, 0].axhline(1.5, color="k", ls=":", lw=0.8, label="paper: about 1.5 m/s")
    axes[0, 0].set_ylabel("kinetic energy (J/m)")
    axes[1, 0].set_ylabel("momentum (kg m/s per m)")
    axes[2, 0].set_ylabel("max speed (m/s)")
    axes[2, 0].set_xlabel("t (s)")
    for a in axes[:, 0]:
        a.legend(fontsize=7)
        a.grid(alpha=0.3)
    report.figure(fig, "energy", "Kinetic energy, momentum and maximum particle speed (paper Figure 7).")
