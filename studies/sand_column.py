"""``runout study sand-column``: the stability test of paper section 2.4 (Figure 4).

Part 1 runs ``projects/examples/sand_column.toml`` (2000 particles, 1 m cells, the paper's step
of 0.02 ms for 24000 steps) with ``mpm``, ``apic`` and ``apic-affine`` and counts the stable
particles against the step, as the paper's Figure 4. Part 2 raises the time step in multiples of
the critical step ``dx / c_p`` (8.6 ms here) up to and beyond the paper's 20 ms claim, over a
longer run that includes the landing and the spreading of the column, and records for each
scheme the largest multiple that stays stable and what happens beyond it.

**Unstable** is the solver's stability guard (``docs/solver.md``): a particle whose speed is
NaN/inf or above ``v_bound = 3 (sqrt(2 |g| H) + max |v0|)`` with ``H`` the height of the grid box
(60 m: ``v_bound`` = 103 m/s). The runs use ``Numerics.guard = "remove"`` (not exposed in project
files, so the built configuration is run directly by :class:`solver.simulation.Simulation`):
unstable particles are taken out and counted, and *stable* = particles still in the computation
(neither removed as unstable nor lost through the open top). A
NaN in the run's totals or a runaway kinetic energy still stops the run; that is reported.

Because the guard's bound is a blow-up criterion, the study also reports an indicator of the
noise the paper describes ("particles move sideways before reaching the ground"): during the
fall (before the base lands at 0.45 s) a stress-free column falls as a rigid body at ``g t``, so
a particle faster than ``1.25 g t + 0.05 m/s`` is *disturbed*. This is a study diagnostic, not a
solver rule.
"""

from __future__ import annotations

import math
import time
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
    new_figure,
    rows_to_series,
    run_built,
    write_csv,
    write_json,
    write_series,
)

SCENE = "sand_column"
SCHEMES = ("mpm", "apic", "apic-affine")
PAPER_DT_S = 2.0e-5
PAPER_STEPS = 24000
PAPER_LARGE_DT_S = 0.02
#: Multiples of the critical step tried in part 2 (the paper's 20 ms is added as its own multiple).
FULL_MULTIPLES = (0.1, 0.25, 0.5, 0.75, 1.0, 1.25, 1.5, 2.0, 3.0, 5.0)
QUICK_MULTIPLES = (0.25, 0.5, 1.0, 1.5, 3.0)
#: The fall ends when the column base (1 m up) reaches the ground: sqrt(2 * 1 / 9.81) s.
FALL_END_S = math.sqrt(2.0 / 9.81)
DISTURBED_FACTOR = 1.25
DISTURBED_MARGIN_M_S = 0.05


def _resolved(scheme: str, dt: float, duration_s: float, interval_s: float) -> Any:
    """The resolved sand-column run (guard "remove": unstable particles are counted, not fatal)."""
    from projects.build import resolve

    return resolve(load_scene(SCENE, [f"numerics.scheme={scheme}", f"numerics.time_step_s={dt!r}",
                                      f"stages.0.duration_s={duration_s!r}", f"output.interval_s={interval_s!r}",
                                      'output.fields=["velocity"]', 'numerics.advanced.guard="remove"']))


def critical_step() -> float:
    """``dx / c_p`` of the sand column (s)."""
    from projects.build import resolve
    from solver.simulation import critical_time_step

    return critical_time_step(resolve(load_scene(SCENE), seed=False).config)


def _output_interval(dt: float, duration_s: float, frames: int) -> float:
    """An output interval that is a whole number of steps (outputs never shorten a step)."""
    return dt * max(1, math.ceil(duration_s / frames / dt - 1e-9))


def run_case(scheme: str, dt: float, duration_s: float, frames: int = 100,
             time_limit_s: float | None = None) -> dict[str, Any]:
    """One sand-column run; returns its series (with the disturbed count) and outcome.

    Parameters
    ----------
    scheme : str
    dt : float
        Time step, s.
    duration_s : float
        Simulated time, s.
    frames : int
        About this many outputs.
    time_limit_s : float, optional
        Wall-clock limit.

    Returns
    -------
    dict
        ``status``, ``message``, ``series`` (columns incl. ``stable`` and ``disturbed``),
        ``particles``, ``steps``, ``wall_s``, ``cpu_s``, ``first_unstable_step`` (or None),
        ``stable_end``, ``max_speed_m_s``.
    """
    interval = _output_interval(dt, duration_s, frames)
    resolved = _resolved(scheme, dt, duration_s, interval)
    n = resolved.particle_count
    g = float(np.linalg.norm(resolved.config.gravity_m_s2))
    disturbed: list[int] = []

    def on_frame(frame: Any) -> None:
        t = frame.diagnostics.time_s
        v = frame.fields.get("velocity")
        act = frame.fields["active"]
        if v is None or t > FALL_END_S:
            disturbed.append(-1)
            return
        speed = np.linalg.norm(v[act], axis=1)
        disturbed.append(int((speed > DISTURBED_FACTOR * g * t + DISTURBED_MARGIN_M_S).sum()))

    out = run_built(resolved, time_limit_s=time_limit_s, on_frame=on_frame)
    series = rows_to_series(out.rows)
    if series:
        # stable = still in the computation. Not n - unstable - lost: the solver counts a particle
        # that is unstable and leaves through an open side in the same step in both counters.
        series["stable"] = series["active_particles"]
        series["double_counted"] = series["unstable_particles"] + series["lost_particles"] - (n - series["active_particles"])
        series["disturbed"] = np.asarray(disturbed[: len(out.rows)])
    unstable = series.get("unstable_particles", np.array([0]))
    first = None
    if len(unstable) and unstable.max() > 0:
        first = int(series["step"][int(np.argmax(unstable > 0))])
    stable_end = int(series["stable"][-1]) if series else 0
    vmax = float(np.nanmax(series["max_speed_m_s"])) if series else math.nan
    dist = series.get("disturbed", np.array([-1]))
    return {
        "scheme": scheme, "dt_s": dt, "duration_s": duration_s, "status": out.status, "message": out.message,
        "series": series, "particles": n, "steps": out.steps, "simulated_time_s": out.simulated_time_s,
        "wall_s": out.wall_s, "cpu_s": out.cpu_s, "first_unstable_step": first, "stable_end": stable_end,
        "max_speed_m_s": vmax, "max_disturbed": int(dist.max()) if len(dist) else -1,
        "unstable_counted": int(series["unstable_particles"][-1]) if series else 0,
        "lost_counted": int(series["lost_particles"][-1]) if series else 0,
        "double_counted": int(series["double_counted"][-1]) if series else 0,
    }


def _stays_stable(case: dict[str, Any]) -> bool:
    return case["status"] == "completed" and case["stable_end"] == case["particles"]


def run(out_dir: Path, quick: bool = False, note: Note = quiet) -> StudyResult:
    """Run both parts and write ``report.md``, ``sand_column.json`` and CSV files.

    Parameters
    ----------
    out_dir : Path
    quick : bool
        Part 1 with 4x the paper's step (6000 steps over the same 0.48 s); part 2 over 3 s of
        simulated time with 5 multiples instead of 10 s with 10 (plus the paper's 20 ms).
    note : callable

    Returns
    -------
    StudyResult
    """
    t0 = time.perf_counter()
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    crit = critical_step()
    part1_dt = PAPER_DT_S * (4 if quick else 1)
    part1_T = PAPER_STEPS * PAPER_DT_S
    sweep_T = 3.0 if quick else 10.0
    multiples = list(QUICK_MULTIPLES if quick else FULL_MULTIPLES)
    paper_multiple = PAPER_LARGE_DT_S / crit
    multiples = sorted(set(multiples) | {round(paper_multiple, 4)})

    # ---------------------------------------------------------------- part 1
    part1: dict[str, dict[str, Any]] = {}
    for scheme in SCHEMES:
        note(f"sand-column part 1: {scheme}, dt = {part1_dt:g} s, {part1_T / part1_dt:.0f} steps")
        part1[scheme] = run_case(scheme, part1_dt, part1_T, frames=120)
        c = part1[scheme]
        note(f"  {c['status']}: {c['stable_end']} of {c['particles']} stable, max speed {c['max_speed_m_s']:.3g} m/s, "
             f"up to {c['max_disturbed']} disturbed ({c['wall_s']:.0f} s)")
        write_series(out_dir / f"part1_{scheme}.csv", c["series"])

    # ---------------------------------------------------------------- part 2
    sweep: list[dict[str, Any]] = []
    for scheme in SCHEMES:
        for k in multiples:
            dt = k * crit
            note(f"sand-column part 2: {scheme}, dt = {k:g} x critical = {dt * 1e3:.3g} ms")
            case = run_case(scheme, dt, sweep_T, frames=100, time_limit_s=600.0)
            case["multiple"] = k
            sweep.append(case)
            write_series(out_dir / f"part2_{scheme}_{k:g}.csv", case["series"])
            note(f"  {case['status']}: {case['stable_end']} of {case['particles']} stable"
                 + (f", first unstable at step {case['first_unstable_step']}" if case["first_unstable_step"] else ""))

    largest: dict[str, float | None] = {}
    beyond: dict[str, str] = {}
    for scheme in SCHEMES:
        cases = [c for c in sweep if c["scheme"] == scheme]
        ok = [c["multiple"] for c in cases if _stays_stable(c)]
        # the largest multiple below which every tried multiple stayed stable
        best = None
        for c in sorted(cases, key=lambda c: c["multiple"]):
            if not _stays_stable(c):
                break
            best = c["multiple"]
        largest[scheme] = best
        nxt = [c for c in sorted(cases, key=lambda c: c["multiple"]) if not _stays_stable(c)]
        if nxt:
            c = nxt[0]
            beyond[scheme] = (f"{c['multiple']:g}x: {c['stable_end']} of {c['particles']} stable at the end"
                              + (f", first unstable at step {c['first_unstable_step']}" if c["first_unstable_step"] else "")
                              + (f"; {c['message']}" if c["status"] != "completed" else ""))
        else:
            beyond[scheme] = "stable at every multiple tried"
        if ok and best is not None and max(ok) > best:
            beyond[scheme] += f" (stable again at {', '.join(f'{m:g}x' for m in ok if m > best)})"

    paper_row = {c["scheme"]: c for c in sweep if abs(c["multiple"] - round(paper_multiple, 4)) < 1e-9}
    aff1 = part1["apic-affine"]
    passed = _stays_stable(aff1)
    data = {
        "quick": quick, "critical_step_s": crit, "part1_dt_s": part1_dt, "part1_steps": round(part1_T / part1_dt),
        "sweep_duration_s": sweep_T, "multiples": multiples, "paper_20ms_multiple": paper_multiple,
        "speed_bound_m_s": None, "part1": {s: {k: v for k, v in c.items() if k != "series"} for s, c in part1.items()},
        "sweep": [{k: v for k, v in c.items() if k != "series"} for c in sweep],
        "largest_stable_multiple": largest, "beyond": beyond, "passed": passed,
        "study_wall_s": time.perf_counter() - t0,
    }
    write_csv(out_dir / "part2.csv", data["sweep"])
    write_json(out_dir / "sand_column.json", data)

    report = Report(out_dir, "Study sand-column: stability of the three schemes (paper section 2.4, Figure 4)")
    report.text(
        ("**quick** (reduced): part 1 with dt = 0.08 ms (4x the paper's, 6000 steps over the paper's 0.48 s); "
         f"part 2 over {sweep_T:g} s with {len(multiples)} multiples.") if quick else
        (f"**full**: part 1 with the paper's dt = 0.02 ms and 24000 steps; part 2 over {sweep_T:g} s "
         f"of simulated time (fall, landing and spreading) with {len(multiples)} multiples."),
        "Scene: `projects/examples/sand_column.toml`: a 10 m x 50 m column (2000 particles, 1 m cells, "
        "2 x 2 particles per cell) released stress-free 1 m above a fixed ground; slip sides, open top; "
        "the paper's Table 1 sand. The column size is assumed (the paper gives 2000 particles only).",
        f"Critical step dx / c_p = {crit * 1e3:.3f} ms (c_p = {1.0 / crit:.1f} m/s); the paper's 20 ms is "
        f"{paper_multiple:.2f}x critical.",
        "**Unstable** (the solver's stability guard, `docs/solver.md`): speed NaN/inf or above "
        "3 (sqrt(2 |g| H) + max |v0|) = 103 m/s with H = 60 m, the grid height. Runs use the guard's "
        "`remove` mode (the built configuration is run with `Numerics.guard = \"remove\"`): unstable particles "
        "are removed and counted; *stable* = particles still in the computation (neither removed as unstable nor "
        "lost through the open top). **Disturbed** (study indicator of the "
        "paper's sideways noise, only during the fall, t < 0.45 s): speed above 1.25 g t + 0.05 m/s, faster than "
        "the rigid free fall of the stress-free column.",
        f"Machine: {machine_line()}. Study wall time {data['study_wall_s']:.0f} s.",
    )
    report.heading("Verdict")
    report.text(("PASS" if passed else "FAIL") + ": apic-affine keeps "
                f"{aff1['stable_end']} of {aff1['particles']} particles stable in part 1 (paper: all stable).")
    report.heading("Part 1: the paper's time step (Figure 4)")
    report.table(["scheme", "status", "stable at the end", "first unstable step", "lost (open top)",
                  "max speed (m/s)", "most disturbed during the fall", "wall (s)"],
                 [[s, c["status"], f"{c['stable_end']} / {c['particles']}", fmt(c["first_unstable_step"]),
                   c["lost_counted"], fmt(c["max_speed_m_s"]), fmt(c["max_disturbed"]), fmt(c["wall_s"])]
                  for s, c in part1.items()])
    report.text("Paper: with classic MPM only 157 particles remain stable at step 1304 and all leave the grid "
                "afterwards; with the improved MPM-APIC all stay stable.")
    fig, axes = new_figure(8.0, 5.0, ncols=1, nrows=2)
    colours = {"apic-affine": "tab:blue", "apic": "tab:orange", "mpm": "tab:green"}
    for s, c in part1.items():
        ser = c["series"]
        if not ser:
            continue
        axes[0, 0].plot(ser["step"], ser["stable"], color=colours[s], label=f"{s}: stable (guard)")
        fall = ser["disturbed"] >= 0
        axes[0, 0].plot(ser["step"][fall], c["particles"] - ser["disturbed"][fall], color=colours[s], ls="--",
                        label=f"{s}: not disturbed")
        axes[1, 0].plot(ser["step"], ser["max_speed_m_s"], color=colours[s], label=s)
    t = np.linspace(0, part1_T, 100)
    axes[1, 0].plot(t / part1_dt, 9.81 * t, "k:", label="free fall g t")
    axes[0, 0].set_ylabel("particles")
    axes[0, 0].set_ylim(bottom=0)
    axes[1, 0].set_ylabel("max speed (m/s)")
    axes[1, 0].set_xlabel("step")
    for a in axes[:, 0]:
        a.legend(fontsize=7)
        a.grid(alpha=0.3)
    report.figure(fig, "stable_particles", "Stable particles against step (paper Figure 4) and maximum speed.")

    report.heading("Part 2: raising the time step")
    report.table(["scheme", "largest stable multiple", "largest stable dt (ms)", "beyond it"],
                 [[s, fmt(largest[s]), fmt(None if largest[s] is None else largest[s] * crit * 1e3), beyond[s]]
                  for s in SCHEMES])
    report.table(["scheme", "x critical", "dt (ms)", "status", "stable at the end", "removed as unstable",
                  "lost (open top)", "first unstable step", "max speed (m/s)", "steps", "message"],
                 [[c["scheme"], fmt(c["multiple"]), fmt(c["dt_s"] * 1e3), c["status"],
                   f"{c['stable_end']} / {c['particles']}", c["unstable_counted"], c["lost_counted"],
                   fmt(c["first_unstable_step"]), fmt(c["max_speed_m_s"]), c["steps"],
                   c["message"] if c["status"] != "completed" else ""] for c in sweep])
    report.text("\"Removed as unstable\" and \"lost\" are the solver's counters; a particle that is unstable and "
                "leaves through the open top in the same step is counted in both (a solver bug, reported), so they "
                "can add up to more than the particles that left; \"stable\" counts the particles still in the "
                "computation.")
    if paper_row:
        report.text("The paper's claim (improved MPM-APIC stable at dt = 20 ms): " + "; ".join(
            f"{s}: {'stable' if _stays_stable(c) else 'not stable'} ({c['stable_end']} / {c['particles']})"
            for s, c in paper_row.items()) + ".")
    fig, ax = new_figure(7.0, 3.5)
    for s in SCHEMES:
        cs = sorted((c for c in sweep if c["scheme"] == s), key=lambda c: c["multiple"])
        ax.plot([c["multiple"] for c in cs], [c["stable_end"] for c in cs], "o-", color=colours[s], label=s)
    ax.axvline(paper_multiple, color="k", ls=":", lw=0.8, label="paper's 20 ms")
    ax.set_xscale("log")
    ax.set_xlabel("time step / critical step")
    ax.set_ylabel(f"stable particles after {sweep_T:g} s")
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    report.figure(fig, "time_step_sweep", "Stable particles at the end of the run against the time step.")
    report.text("Raw data: `part1_SCHEME.csv`, `part2_SCHEME_MULTIPLE.csv` (series), `part2.csv`, `sand_column.json`.")
    path = report.write()

    verdict = [f"sand-column {'PASS' if passed else 'FAIL'} ({'quick' if quick else 'full'}; {time.perf_counter() - t0:.0f} s)"]
    verdict.append("part 1 stable at the end: " + ", ".join(f"{s} {c['stable_end']}/{c['particles']}" for s, c in part1.items()))
    verdict.append("largest stable dt: " + ", ".join(
        f"{s} {fmt(largest[s])}x critical" for s in SCHEMES) + f" (paper's 20 ms = {paper_multiple:.2f}x)")
    return StudyResult("sand-column", passed, verdict, path, time.perf_counter() - t0, data)
