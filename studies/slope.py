"""``runout study slope``: the large-displacement slope of paper section 3 (after Sun and Song 2015).

Runs ``projects/examples/slope_sun_song_2015.toml`` (gravity ramped over 10 s with damping,
velocities reset, cohesion set to zero, 40 s of free motion, 10 s with damping) through
:func:`projects.runner.run_project` and puts each reported number beside the paper's:

- initial maximum vertical stress: the largest ``-sigma_yy`` at the end of the gravity stage;
- time of the kinetic-energy peak and the maximum speed (with its time), counted from the trigger
  (the start of the landslide stage);
- the maximum speed 15 s after the trigger;
- maximum horizontal displacement at the end (from the end of the gravity stage);
- final slope angle: a least-squares line through the final free surface (highest particle top in
  a sliding window of two particle spacings) where it lies between 10 % and 90 % of the way from
  the foundation level (27 m) up to its highest point, on the slid face (right of the crest).

The slope's geometry and soil are assumed (Sun and Song's figure is not in the paper's text; see
the example's comments), so the comparison checks the character of the run (stands under
gravity, slides after the trigger, stops below the friction angle), not digits.

Full: the paper's grid (1 m cells, 4 particles per cell, 39051 particles) with dt = 1 ms (0.18 of
the critical step, the fraction the paper uses in its aluminium-bar test) instead of the paper's
0.1 ms, which would take ten times longer on a CPU. Quick: 2 m cells (about 9800 particles),
dt = 2 ms, the same stages shortened to 10 + 20 + 5 s.
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
    load_scene,
    machine_line,
    new_figure,
    peak,
    quiet,
    run_project_measured,
    series_finite,
    write_csv,
    write_json,
    write_series,
)

SCENE = "slope_sun_song_2015"
FOUNDATION_TOP_M = 27.0
#: The paper's numbers (section 3).
PAPER = {
    "initial_max_vertical_stress_kpa": 1345.0,
    "ke_peak_time_s": 5.5,
    "max_speed_m_s": 8.0,
    "max_speed_time_s": 6.4,
    "max_speed_at_15_s_m_s": 1.5,
    "max_horizontal_displacement_m": 63.6,
    "final_slope_angle_deg": 16.0,
}
FRICTION_ANGLE_DEG = 20.0


def slope_angle(positions: np.ndarray, active: np.ndarray | None, spacing_m: float,
                base_m: float = FOUNDATION_TOP_M) -> tuple[float, dict[str, Any]]:
    """Final slope angle (degrees) from a line fitted to the slid face of the free surface.

    Returns
    -------
    (float, dict)
        The angle (NaN if the surface has no face) and the fit (``x``, ``y`` of the surface on a
        0.5 m grid, the fitted points and line coefficients) for plots.
    """
    pos = np.asarray(positions, dtype=float)
    act = np.ones(len(pos), bool) if active is None else np.asarray(active, bool)
    xs = np.arange(0.0, float(pos[act, 0].max()) + 1.0, 0.5)
    hs = surface_heights(pos, act, spacing_m, xs, window_m=2.0 * spacing_m, base_m=0.0)
    top = float(hs.max())
    fit: dict[str, Any] = {"x": xs, "y": hs}
    if top <= base_m + 1.0:
        return math.nan, fit
    lo, hi = base_m + 0.1 * (top - base_m), base_m + 0.9 * (top - base_m)
    crest_i = int(np.nonzero(hs >= hi)[0].max())  # the last point at 90 % height: the face starts after it
    sel = np.zeros_like(hs, dtype=bool)
    sel[crest_i:] = (hs[crest_i:] >= lo) & (hs[crest_i:] <= hi)
    if sel.sum() < 3:
        return math.nan, fit
    a, b = np.polyfit(xs[sel], hs[sel], 1)
    fit.update({"sel": sel, "a": float(a), "b": float(b)})
    return float(math.degrees(math.atan(-a))), fit


def run(out_dir: Path, quick: bool = False, note: Note = quiet) -> StudyResult:
    """Run the slope and write ``report.md``, ``slope.json``, ``series.csv``.

    Parameters
    ----------
    out_dir : Path
    quick : bool
        2 m cells, dt 2 ms, stages 10 + 20 + 5 s (see the module docstring).
    note : callable

    Returns
    -------
    StudyResult
    """
    t0 = time.perf_counter()
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    if quick:
        sets = ["domain.cell_size_m=2.0", "numerics.time_step_s=0.002", "stages.1.duration_s=20.0",
                "stages.2.duration_s=5.0", "output.interval_s=0.5"]
    else:
        sets = ["numerics.time_step_s=0.001", "output.interval_s=0.5"]
    project = load_scene(SCENE, sets)
    gravity_s = project.stages[0].duration_s
    captured: dict[str, Any] = {}

    def on_frame(frame: Any) -> None:
        d = frame.diagnostics
        if d.stage_index == 0:  # keep the last frame of the gravity stage
            captured["initial_stress"] = np.array(frame.fields["stress"][:, 1])
            captured["initial_positions"] = np.array(frame.fields["positions"])
            captured["initial_active"] = np.array(frame.fields["active"])
            captured["initial_time_s"] = d.time_s
        if d.stage_index >= 1 and abs(d.time_s - gravity_s - 15.0) < 0.26:
            captured["speed_15"] = float(d.max_speed_m_s)
        captured["displacement"] = frame.fields.get("displacement")

    note(f"slope: {'quick, 2 m cells' if quick else 'full, 1 m cells'}")
    rec = run_project_measured(project, out_dir / "run", "slope", {"quick": quick}, keep_frames=False,
                               on_frame=on_frame)
    note(f"  {rec.status} in {rec.wall_s:.0f} s: {rec.message}")
    series = rec.series
    t = np.asarray(series.get("time_s", []), dtype=float)
    stage = np.asarray(series.get("stage", []))
    slide = stage != project.stages[0].label
    slide_series = {k: np.asarray(v)[slide] for k, v in series.items()}
    slide_series["time_s"] = t[slide] - gravity_s
    ke, t_ke = peak(slide_series, "kinetic_energy_J_per_m")
    vmax, t_v = peak(slide_series, "max_speed_m_s")
    sig = captured.get("initial_stress")
    sigma_max_kpa = float(-np.min(sig) / 1e3) if sig is not None else math.nan
    disp = captured.get("displacement")
    act = rec.active if rec.active is not None else None
    max_dx = float(np.max(np.abs(disp[act, 0]))) if disp is not None and act is not None else math.nan
    angle, fit = (slope_angle(rec.positions, rec.active, rec.spacing_m) if rec.positions is not None
                  else (math.nan, {}))
    angle0, fit0 = (slope_angle(captured["initial_positions"], captured["initial_active"], rec.spacing_m)
                    if "initial_positions" in captured else (math.nan, {}))
    measured = {
        "initial_max_vertical_stress_kpa": sigma_max_kpa,
        "ke_peak_time_s": t_ke,
        "max_speed_m_s": vmax,
        "max_speed_time_s": t_v,
        "max_speed_at_15_s_m_s": captured.get("speed_15", math.nan),
        "max_horizontal_displacement_m": max_dx,
        "final_slope_angle_deg": angle,
    }
    checks = {
        "completed": rec.ok and series_finite(series),
        "stands_under_gravity": bool(angle0 > 30.0) if math.isfinite(angle0) else False,
        "slides": bool(max_dx > 10.0),
        "stops_below_friction_angle": bool(math.isfinite(angle) and angle < FRICTION_ANGLE_DEG),
    }
    passed = all(checks.values())
    data = {"quick": quick, "overrides": sets, "measured": measured, "paper": PAPER, "checks": checks,
            "passed": passed, "initial_face_angle_deg": angle0, "run": rec.row(),
            "study_wall_s": time.perf_counter() - t0}
    write_json(out_dir / "slope.json", data)
    write_series(out_dir / "series.csv", series)
    if fit:
        write_csv(out_dir / "final_surface.csv", [{"x_m": x, "y_m": y} for x, y in zip(fit["x"], fit["y"])])

    report = Report(out_dir, "Study slope: large-displacement slope (paper section 3, after Sun and Song 2015)")
    report.text(
        ("**quick** (reduced): 2 m cells, 2 x 2 particles per cell, dt = 2 ms, stages 10 s (gravity) + 20 s "
         "(landslide) + 5 s (damped settling)") if quick else
        ("**full**: the paper's grid (1 m cells, 2 x 2 particles per cell, 39051 particles) and stages "
         "(10 s gravity + 40 s landslide + 10 s damped settling), with dt = 1 ms instead of the paper's 0.1 ms "
         "(0.18 of the critical step, ten times fewer steps)"),
        f"Particles {rec.particles:,}, {rec.steps:,} steps, wall time {rec.wall_s:.0f} s, CPU {rec.cpu_s:.0f} s "
        f"({rec.particle_steps_per_s / 1e6:.2f} M particle-steps/s). Machine: {machine_line()}.",
        "Scene: `projects/examples/slope_sun_song_2015.toml`; its geometry and soil are assumptions consistent "
        "with the paper's text (height 42 m, foundation 27 m, face 39.7 deg, c = 80 kPa then 0, phi = 20 deg), "
        "so the numbers below are a plausibility check of the run's character, not a reproduction of digits. "
        "Times are counted from the trigger (start of the landslide stage).",
    )
    report.heading("Verdict")
    report.text(("PASS" if passed else "FAIL") + ": " + ", ".join(f"{k.replace('_', ' ')}: {'yes' if v else 'NO'}"
                                                                   for k, v in checks.items()) + ".")
    labels = {
        "initial_max_vertical_stress_kpa": "initial max vertical stress (kPa)",
        "ke_peak_time_s": "kinetic energy peak at (s after trigger)",
        "max_speed_m_s": "max speed (m/s)",
        "max_speed_time_s": "max speed at (s after trigger)",
        "max_speed_at_15_s_m_s": "max speed 15 s after the trigger (m/s)",
        "max_horizontal_displacement_m": "max horizontal displacement (m)",
        "final_slope_angle_deg": "final slope angle (deg)",
    }
    report.table(["quantity", "measured", "paper"],
                 [[labels[k], fmt(measured[k]), fmt(PAPER[k])] for k in labels])
    report.text(f"Face angle after the gravity stage (same fit): {fmt(angle0)} deg (geometry: 39.7 deg). "
                "The analytic vertical stress under the crest, rho g (69 m - 0.25 m), is 1349 kPa.")
    _plots(report, slide_series, captured, rec, fit, fit0)
    report.text("Raw data: `series.csv` (every 0.5 s), `final_surface.csv`, `slope.json`; results folder `run/`.")
    path = report.write()
    verdict = [f"slope {'PASS' if passed else 'FAIL'} ({'quick' if quick else 'full'}; {time.perf_counter() - t0:.0f} s)",
               f"sigma_v,max {fmt(sigma_max_kpa)} kPa (paper 1345), KE peak at {fmt(t_ke)} s (5.5), "
               f"max speed {fmt(vmax)} m/s (8), max dx {fmt(max_dx)} m (63.6), final angle {fmt(angle)} deg (16)"]
    return StudyResult("slope", passed, verdict, path, time.perf_counter() - t0, data)


def _plots(report: Report, slide: dict[str, np.ndarray], captured: dict[str, Any], rec: Any,
           fit: dict[str, Any], fit0: dict[str, Any]) -> None:
    fig, axes = new_figure(8.0, 4.5, ncols=1, nrows=2)
    t = slide.get("time_s", np.array([]))
    axes[0, 0].plot(t, slide.get("kinetic_energy_J_per_m", []), color="tab:blue")
    axes[0, 0].axvline(PAPER["ke_peak_time_s"], color="k", ls=":", lw=0.8, label="paper: peak at 5.5 s")
    axes[1, 0].plot(t, slide.get("max_speed_m_s", []), color="tab:red")
    axes[1, 0].plot([PAPER["max_speed_time_s"]], [PAPER["max_speed_m_s"]], "k^", label="paper: 8 m/s at 6.4 s")
    axes[1, 0].plot([15.0], [PAPER["max_speed_at_15_s_m_s"]], "kv", label="paper: 1.5 m/s at 15 s")
    axes[0, 0].set_ylabel("kinetic energy (J/m)")
    axes[1, 0].set_ylabel("max speed (m/s)")
    axes[1, 0].set_xlabel("time after the trigger (s)")
    for a in axes[:, 0]:
        a.legend(fontsize=7)
        a.grid(alpha=0.3)
    report.figure(fig, "energy", "Kinetic energy and maximum speed after the trigger.")

    if rec.positions is None:
        return
    fig, ax = new_figure(9.0, 3.5)
    if "initial_positions" in captured:
        p0, a0 = captured["initial_positions"], captured["initial_active"]
        ax.scatter(p0[a0, 0], p0[a0, 1], s=0.2, c="0.8", label="after the gravity stage")
    disp = captured.get("displacement")
    act = rec.active
    colour = np.linalg.norm(disp[act], axis=1) if disp is not None else None
    sc = ax.scatter(rec.positions[act, 0], rec.positions[act, 1], s=0.3, c=colour, cmap="viridis",
                    label="final")
    if colour is not None:
        fig.colorbar(sc, ax=ax, label="displacement (m)")
    for f, style, lab in ((fit0, "k--", "face fit, initial"), (fit, "r-", "face fit, final")):
        if "a" in f:
            xs = f["x"][f["sel"]]
            ax.plot(xs, f["a"] * xs + f["b"], style, lw=1.2, label=lab)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.legend(fontsize=7, loc="upper right")
    report.figure(fig, "deposit", "Slope after the gravity stage (grey) and at the end, coloured by displacement.")
