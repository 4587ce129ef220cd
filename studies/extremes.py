"""``runout study extremes``: runs at the edges of the parameter space.

Every row is the tiny granular column (``projects/examples/tiny_column.toml``: 288 particles,
2 cm cells, K0 stage then free collapse) with one setting pushed to an edge, run through
:func:`projects.runner.run_project`:

- time step 0.1, 0.5, 1, 2 and 5 times the critical step ``dx / c_p``;
- Young's modulus 1e4 to 1e10 Pa (time step from ``cfl = 0.5``);
- friction angle 0 to 50 degrees; cohesion 0 to 1 MPa; Poisson's ratio 0 to 0.49;
- 1 to 16 particles per cell; f32 and f64;
- the body touching each side of each boundary type, and particles leaving through open sides.

Outcome of a row:

- **stable**: the run completed, no particle was unstable (``docs/solver.md``), every number
  in the series and the last frame is finite;
- **stopped by the guard**: the stability guard ended the run with its one-line message;
- **rejected**: the project or the solver refused the input with a message before running;
- **unsound**: completed and finite, but the total energy grew by more than
  :data:`ENERGY_GAIN_LIMIT` (numerical energy the guard does not see): a finding, not a crash;
- **failed**: anything else (an exception, NaN that reached the results, a run past the
  wall-clock limit, i.e. a hang). Every failed row is a bug.

Energy drift: the largest gain of the total energy ``E = kinetic + potential + elastic`` over its
initial value, as a fraction of the initial potential energy above the grid's bottom. Potential
energy is ``-sum m g . x``; elastic energy ``sum V/(2E) (s_xx^2 + s_yy^2 + s_zz^2 - 2 nu (s_xx s_yy
+ s_yy s_zz + s_zz s_xx) + 2 (1 + nu) s_xy^2)`` with the initial particle volumes. The run is
dissipative (plasticity, wall friction), so a sound run's energy does not grow: a positive drift
of more than a few percent is numerical energy. Particles lost through an open side take their
energy with them.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from studies.common import (
    Note,
    Report,
    StudyResult,
    quiet,
    fmt,
    load_scene,
    machine_line,
    run_project_measured,
    series_finite,
    write_csv,
    write_json,
)

SCENE = "tiny_column"
SCHEMES = ("apic-affine", "apic", "mpm")
#: Column against the left wall (the example's), against the right wall and touching the top.
COLUMN_RIGHT = "bodies.0.polygon_m=[[0.48, 0.0], [0.6, 0.0], [0.6, 0.24], [0.48, 0.24]]"
COLUMN_TOP = "bodies.0.polygon_m=[[0.0, 0.06], [0.12, 0.06], [0.12, 0.3], [0.0, 0.3]]"
#: Frames every 5 ms (energies are computed on them).
OUTPUT_INTERVAL_S = 0.005
#: A completed run whose total energy grew by more than this fraction of the initial potential
#: energy is reported as "unsound": the numbers are finite but the numerics created energy.
ENERGY_GAIN_LIMIT = 0.05
COLUMN_FLOATING = "bodies.0.polygon_m=[[0.4, 0.02], [0.52, 0.02], [0.52, 0.26], [0.4, 0.26]]"


@dataclass(frozen=True)
class Row:
    """One edge of the parameter space: a group, a label and its ``--set`` overrides.

    ``dt_multiple`` asks for a time step of that many critical steps (computed from the built
    run, since the critical step depends on the material).
    """

    group: str
    label: str
    overrides: tuple[str, ...] = ()
    dt_multiple: float | None = None
    expect: str = ""
    notes: str = field(default="", compare=False)


def rows() -> list[Row]:
    """All rows of the study, in report order."""
    out = [Row("time step", f"{k:g} x critical", dt_multiple=k) for k in (0.1, 0.5, 1.0, 2.0, 5.0)]
    out += [Row("Young's modulus", f"E = {e:.0e} Pa", (f"materials.sand.youngs_modulus_pa={e!r}", "numerics.cfl=0.5"))
            for e in (1e4, 1e6, 1e8, 1e10)]
    out += [Row("friction angle", f"phi = {p:g} deg", (f"materials.sand.friction_angle_deg={p!r}",))
            for p in (0.0, 10.0, 30.0, 50.0)]
    out += [Row("cohesion", f"c = {c:.0e} Pa" if c else "c = 0", (f"materials.sand.cohesion_pa={c!r}",))
            for c in (0.0, 1e3, 1e5, 1e6)]
    out += [Row("Poisson's ratio", f"nu = {nu:g}", (f"materials.sand.poisson_ratio={nu!r}", "numerics.cfl=0.5"))
            for nu in (0.0, 0.3, 0.45, 0.49)]
    out += [Row("particles per cell", f"{n * n} per cell", (f"particles.per_cell={n}",)) for n in (1, 2, 3, 4)]
    out += [Row("precision", p, (f"numerics.precision={p}",)) for p in ("f32", "f64")]
    friction = "{type = \"friction\", friction_angle_deg = 30.0}"
    for side, body in (("left", None), ("bottom", None), ("right", COLUMN_RIGHT), ("top", COLUMN_TOP)):
        for kind in ("fixed", "slip", "friction", "open"):
            value = friction if kind == "friction" else kind
            sets = [f"domain.boundaries.{side}={value}"]
            if body:
                sets.append(body)
            out.append(Row("boundaries", f"body on the {side} side, {kind}", tuple(sets)))
    out.append(Row("outflow", "thrown through an open right side",
                   (COLUMN_FLOATING, "bodies.0.initial_velocity_m_s=[6.0, 0.0]", "domain.boundaries.right=open",
                    "numerics.cfl=0.5")))
    out.append(Row("outflow", "falling through an open bottom",
                   ("domain.boundaries.bottom=open", "domain.boundaries.left=open")))
    return out


def _energy_terms(masses: np.ndarray, volumes: np.ndarray, youngs: np.ndarray, nu: np.ndarray,
                  g: np.ndarray, y_ref: float):
    """A function of a frame returning (kinetic, potential, elastic) energies in J/m."""
    gn = float(np.linalg.norm(g))
    down = g / gn if gn > 0 else np.array([0.0, -1.0])

    def terms(fields: dict[str, np.ndarray]) -> tuple[float, float, float]:
        act = fields["active"]
        m = masses[act]
        x = fields["positions"][act].astype(float)
        v = fields["velocity"][act].astype(float)
        s = fields["stress"][act].astype(float)
        kin = 0.5 * float(np.sum(m * np.sum(v * v, axis=1)))
        height = -(x @ down) - (-(y_ref * down[1]))  # along -g, from the reference level
        pot = gn * float(np.sum(m * height))
        sxx, syy, sxy, szz = s[:, 0], s[:, 1], s[:, 2], s[:, 3]
        w = (sxx ** 2 + syy ** 2 + szz ** 2 - 2 * nu[act] * (sxx * syy + syy * szz + szz * sxx)
             + 2 * (1 + nu[act]) * sxy ** 2) / (2 * youngs[act])
        ela = float(np.sum(volumes[act] * w))
        return kin, pot, ela

    return terms


def run_row(row: Row, scheme: str, out_dir: Path, duration_s: float, time_limit_s: float) -> dict[str, Any]:
    """Run one row with one scheme; returns the table row (never raises for solver trouble)."""
    from projects.build import resolve
    from projects.schema import ProjectError
    from solver.simulation import critical_time_step

    result: dict[str, Any] = {"group": row.group, "row": row.label, "scheme": scheme, "outcome": "failed",
                              "message": "", "max_speed_m_s": math.nan, "energy_drift": math.nan,
                              "lost": 0, "unstable": 0, "steps": 0, "wall_s": 0.0, "dt_s": math.nan}
    sets = [f"numerics.scheme={scheme}", f"stages.1.duration_s={duration_s!r}", f"output.interval_s={OUTPUT_INTERVAL_S!r}",
            'output.fields=["velocity", "stress"]', *row.overrides]
    try:
        project = load_scene(SCENE, sets)
        built = resolve(project)
        if row.dt_multiple is not None:
            dt = row.dt_multiple * critical_time_step(built.config)
            # outputs every whole number of steps, so that no step is shortened to land on one
            interval = dt * math.ceil(OUTPUT_INTERVAL_S / dt - 1e-9)
            project = load_scene(SCENE, [*sets, f"numerics.time_step_s={dt!r}", f"output.interval_s={interval!r}"])
            built = resolve(project)
    except ProjectError as err:
        result.update(outcome="rejected", message=str(err))
        return result
    cfg = built.config
    mats = cfg.materials
    ids = built.particles.material_ids
    vol = np.asarray(built.particles.volumes_m2, dtype=float)
    masses = vol * np.array([m.density_kg_m3 for m in mats])[ids]
    terms = _energy_terms(masses, vol, np.array([m.youngs_modulus_pa for m in mats])[ids],
                          np.array([m.poisson_ratio for m in mats])[ids], np.asarray(cfg.gravity_m_s2, float),
                          cfg.grid.origin_m[1])
    energies: list[tuple[float, float, float, float]] = []
    nonfinite: list[str] = []

    def on_frame(frame: Any) -> None:
        f = frame.fields
        for name, arr in f.items():
            if arr.dtype.kind == "f" and not np.all(np.isfinite(arr[f["active"]])):
                nonfinite.append(f"{name} at t = {frame.diagnostics.time_s:.4g} s")
        if "velocity" in f and "stress" in f:
            energies.append((frame.diagnostics.time_s, *terms(f)))

    try:
        rec = run_project_measured(project, out_dir, f"{row.label} / {scheme}", keep_frames=False,
                                   time_limit_s=time_limit_s, on_frame=on_frame)
    except ProjectError as err:
        result.update(outcome="rejected", message=str(err))
        return result
    ser = rec.series
    finite = series_finite(ser) and not nonfinite
    if rec.positions is not None:
        finite = finite and bool(np.all(np.isfinite(rec.positions[rec.active])))
    unstable = int(np.max(ser.get("unstable_particles", [0]))) if len(ser.get("unstable_particles", [])) else 0
    lost = int(np.max(ser.get("lost_particles", [0]))) if len(ser.get("lost_particles", [])) else 0
    if rec.status == "completed" and finite and unstable == 0:
        outcome = "stable"  # or "unsound" below, once the energy is known
    elif rec.status == "failed" and rec.message.startswith("unstable:") and finite:
        outcome = "stopped by the guard"
    else:
        outcome = "failed"
        if not finite:
            rec.message = f"non-finite values reached the results ({', '.join(nonfinite[:2]) or 'series'}); {rec.message}"
    drift = end = math.nan
    if energies:
        e = np.array(energies)
        total = e[:, 1] + e[:, 2] + e[:, 3]
        scale = e[0, 2] if e[0, 2] > 0 else max(abs(total[0]), 1e-30)
        drift = float((total.max() - total[0]) / scale)
        end = float((total[-1] - total[0]) / scale)
    if outcome == "stable" and math.isfinite(drift) and drift > ENERGY_GAIN_LIMIT:
        outcome = "unsound"
        rec.message = (f"completed, but the total energy grew by {100 * drift:.0f} % of the initial potential "
                       "energy (numerical energy; the guard did not fire)")
    vmax = float(np.nanmax(ser["max_speed_m_s"])) if len(ser.get("max_speed_m_s", [])) else math.nan
    dts = ser.get("dt_s", np.array([]))
    result.update(outcome=outcome, message=rec.message, max_speed_m_s=vmax, energy_drift=drift, energy_change_end=end,
                  lost=lost, unstable=unstable, steps=rec.steps, wall_s=rec.wall_s,
                  dt_s=float(np.max(dts)) if len(dts) else math.nan,
                  critical_dt_s=critical_time_step(cfg), particles=rec.particles,
                  simulated_time_s=rec.simulated_time_s)
    return result


def run(out_dir: Path, quick: bool = False, note: Note = quiet,
        selection: list[Row] | None = None, schemes: tuple[str, ...] | None = None,
        duration_s: float | None = None) -> StudyResult:
    """Run the rows and write ``report.md``, ``extremes.csv`` and ``extremes.json``.

    Parameters
    ----------
    out_dir : Path
    quick : bool
        0.1 s of collapse instead of 0.3 s, and only apic-affine except for the time-step rows
        (all three schemes there).
    note : callable
    selection : list of Row, optional
        Run only these rows (tests).
    schemes : tuple of str, optional
        Schemes for every row (default: see ``quick``).
    duration_s : float, optional
        Length of the collapse stage (default 0.1 s quick, 0.3 s full).

    Returns
    -------
    StudyResult
    """
    t0 = time.perf_counter()
    out_dir = Path(out_dir)
    duration = duration_s if duration_s is not None else (0.1 if quick else 0.3)
    limit = 120.0 if quick else 300.0
    table: list[dict[str, Any]] = []
    for row in (selection if selection is not None else rows()):
        if schemes is not None:
            row_schemes = schemes
        else:
            row_schemes = SCHEMES if (not quick or row.group == "time step") else ("apic-affine",)
        for scheme in row_schemes:
            slug = "".join(ch if ch.isalnum() else "_" for ch in f"{row.group}_{row.label}_{scheme}")
            res = run_row(row, scheme, out_dir / "runs" / slug, duration, limit)
            table.append(res)
            note(f"extremes: {row.group}: {row.label} / {scheme}: {res['outcome']}"
                 + (f" ({res['message']})" if res["outcome"] != "stable" else ""))
    failed = [r for r in table if r["outcome"] == "failed"]
    passed = not failed
    counts = {k: sum(r["outcome"] == k for r in table)
              for k in ("stable", "unsound", "stopped by the guard", "rejected", "failed")}
    data = {"quick": quick, "duration_s": duration, "time_limit_s": limit, "counts": counts, "passed": passed,
            "rows": table, "study_wall_s": time.perf_counter() - t0}
    write_csv(out_dir / "extremes.csv", table)
    write_json(out_dir / "extremes.json", data)

    report = Report(out_dir, "Study extremes: runs at the edges of the parameter space")
    report.text(
        ("**quick** (reduced): 0.1 s of collapse per run; apic-affine only, except the time-step rows (all three "
         "schemes)") if quick else "**full**: 0.3 s of collapse per run, every row with all three schemes",
        f"Scene: `projects/examples/{SCENE}.toml` (288 particles at 2 x 2 per 2 cm cell, E = 1 MPa, phi = 30 deg, "
        "K0 stage, frictional base, slip sides, open top), one setting changed per row. Wall-clock limit per run "
        f"{limit:g} s (a run past it counts as a hang, i.e. failed).",
        "Outcomes: **stable** (completed, no unstable particle, everything finite, energy gain at most "
        f"{100 * ENERGY_GAIN_LIMIT:g} %), **unsound** (completed and finite but with a larger energy gain: the guard "
        "did not see it), **stopped by the guard** (the stability guard's message), **rejected** (input refused with a message), **failed** (anything else: a bug). "
        "Energy drift: largest gain of kinetic + potential + elastic energy over its initial value, as a fraction "
        "of the initial potential energy above the grid bottom (positive = energy created by the numerics).",
        f"Machine: {machine_line()}. Study wall time {data['study_wall_s']:.0f} s.",
    )
    report.heading("Verdict")
    report.text(("PASS" if passed else "FAIL") + ": " + ", ".join(f"{v} {k}" for k, v in counts.items()) + " runs.")
    report.heading("Runs")
    report.table(["group", "row", "scheme", "outcome", "max speed (m/s)", "energy drift", "lost", "dt (s)",
                  "steps", "wall (s)", "message"],
                 [[r["group"], r["row"], r["scheme"], r["outcome"], fmt(r["max_speed_m_s"]), fmt(r["energy_drift"], 2),
                   r["lost"], fmt(r["dt_s"], 2), r["steps"], fmt(r["wall_s"], 2),
                   r["message"] if r["outcome"] != "stable" else ""] for r in table])
    report.text("Raw data: `extremes.csv`, `extremes.json`; results folders under `runs/` (frames removed).")
    path = report.write()
    verdict = [f"extremes {'PASS' if passed else 'FAIL'} ({'quick' if quick else 'full'}; "
               f"{time.perf_counter() - t0:.0f} s): " + ", ".join(f"{v} {k}" for k, v in counts.items())]
    verdict += [f"failed: {r['row']} / {r['scheme']}: {r['message']}" for r in failed[:5]]
    verdict += [f"unsound: {r['row']} / {r['scheme']}: energy gain {100 * r['energy_drift']:.0f} %"
                for r in table if r["outcome"] == "unsound"][:5]
    return StudyResult("extremes", passed, verdict, path, time.perf_counter() - t0, data)
