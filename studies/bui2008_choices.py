"""``runout study bui2008-choices``: what each model choice does to the aluminium-bar collapse.

The shipped scene (``projects/examples/bui2008_aluminium_bars.toml``) and the choices an engineer
could make instead, each run once with apic-affine and measured against the experiment (Bui et al.
2008): toe, reach, deposit centroid, the failure line at three heights and its RMS distance, the
surface's RMS deviation and the crest (measures of :mod:`studies.common`). Each row changes one
thing from the source paper's own model (Zhong et al. 2022: the default Drucker-Prager match,
rate-independent friction, K0, frictional base delta = phi), or is the shipped scene:

- ``paper``: that model;
- ``fixed base``: no-slip base, as the open reproductions of the test have it
  (LandslideSIM/MaterialPointSolver.jl, hydraxmpm);
- ``plane-strain`` and ``simple-shear``: the other Drucker-Prager matches (psi = 0);
- ``Maxwell 0.2``: material damping, a Maxwell arm of 20 % at the block's first shear mode
  (``c_s / 4 H`` = 27.6 Hz);
- ``K0 = nu / (1 - nu)``: the elastic K0 (0.43) instead of Jaky's (0.66);
- ``no initial stress``: the block released stress-free, gravity on at t = 0 (the reproductions);
- ``mu(I)``: the rate-dependent friction with the default match;
- ``shipped``: mu(I) with the simple-shear match (the example as shipped).

Full: 2 mm cells, 2 x 2 particles per cell, dt = 20 us (the paper's). Quick: 4 mm cells.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from studies.bui2008 import SCENE, TARGETS, plot_experiment, plot_particles, run_bui
from studies.common import (
    FAILURE_HEIGHTS_M,
    Note,
    Report,
    StudyResult,
    bui_experiment,
    bui_failure_line,
    experiment_centroid,
    experiment_failure_x,
    experiment_toe,
    fmt,
    machine_line,
    new_figure,
    quiet,
    write_csv,
    write_json,
)

#: The keys of the rate-dependent friction in the shipped scene.
_MU_I_KEYS = ("mu_i_friction_increase", "mu_i_reference_number", "grain_diameter_m", "grain_density_kg_m3")


def _bars(project: Any, **update: Any) -> Any:
    bars = project.materials["bars"].model_copy(update=update)
    return project.model_copy(update={"materials": {**project.materials, "bars": bars}})


def paper(project: Any) -> Any:
    """The source paper's model: the default match, no rate dependence."""
    return _bars(project, mohr_coulomb_match=None, **{k: None for k in _MU_I_KEYS})


def _stress_free(project: Any) -> Any:
    """The paper's model released without an initial-stress stage."""
    project = paper(project)
    return project.model_copy(update={"stages": [st for st in project.stages if st.type != "k0"]})


#: label -> (change of the loaded project, further ``--set`` overrides), and what the row is.
CHOICES: dict[str, tuple[Callable[[Any], Any] | None, tuple[str, ...], str]] = {
    "paper": (paper, (), "the source paper's model: default match, rate-independent, K0, base delta = phi"),
    "fixed base": (paper, ('domain.boundaries.bottom="fixed"',), "paper, with a no-slip base"),
    "plane-strain": (lambda p: _bars(paper(p), mohr_coulomb_match="plane-strain"), (),
                     'paper, mohr_coulomb_match = "plane-strain"'),
    "simple-shear": (lambda p: _bars(paper(p), mohr_coulomb_match="simple-shear"), (),
                     'paper, mohr_coulomb_match = "simple-shear"'),
    "Maxwell 0.2": (paper, ("materials.bars.damping_ratio=0.2", "materials.bars.damping_frequency_hz=27.6",
                            'materials.bars.damping_model="maxwell"'),
                    "paper, a Maxwell arm of 20 % at the first shear mode (27.6 Hz)"),
    "K0 = nu/(1-nu)": (paper, ("stages.0.k0=0.4286",), "paper, K0 = 0.43 instead of 1 - sin(phi) = 0.66"),
    "no initial stress": (_stress_free, (), "paper, released stress-free (no k0 stage)"),
    "mu(I)": (lambda p: _bars(p, mohr_coulomb_match=None), (), "paper, with the mu(I) law"),
    "shipped": (None, (), "the shipped scene: mu(I) and the simple-shear match"),
}


def run(out_dir: Path, quick: bool = False, note: Note = quiet) -> StudyResult:
    """Run every choice, write ``report.md``, ``choices.csv``, ``choices.json`` and the plots.

    Passed: the shipped scene meets the validation targets (:data:`studies.bui2008.TARGETS`) at
    the full size; the quick size is reported only (its toe, at 2 mm particle spacing, counts
    single particles).
    """
    t0 = time.perf_counter()
    out_dir = Path(out_dir)
    experiment = bui_experiment()
    failure = bui_failure_line()
    cell = 0.004 if quick else 0.002
    rows, records = [], {}
    for label, (change, sets, what) in CHOICES.items():
        note(f"bui2008-choices: {label}, {cell * 1e3:g} mm cells")
        rec, dep = run_bui(out_dir / "runs" / label.replace(" ", "_").replace("/", "-"), label, cell, 2,
                           "apic-affine", experiment, interval_s=0.02, change=change, sets=sets)
        records[label] = (rec, dep)
        rows.append({"choice": label, "what": what, "status": rec.status, "wall_s": rec.wall_s, **rec.extra})
        note(f"  {rec.status} in {rec.wall_s:.0f} s: toe {fmt(rec.extra.get('toe_m'))} m, "
             f"centroid {fmt(rec.extra.get('centroid_m'), 4)} m")
    exp_failure = (experiment_failure_x(failure, FAILURE_HEIGHTS_M) if failure is not None
                   else np.full(len(FAILURE_HEIGHTS_M), math.nan))
    experiment_row = {"choice": "experiment", "toe_m": experiment_toe(experiment),
                      "reach_m": experiment_toe(experiment, 0.005), "centroid_m": experiment_centroid(experiment),
                      "crest_m": float(experiment[0, 1]),
                      **{f"failure_x_{1e3 * h:.0f}mm_m": float(x) for h, x in zip(FAILURE_HEIGHTS_M, exp_failure)}}
    shipped = records["shipped"][1]
    checks = TARGETS.check(shipped) if shipped is not None else {}
    passed = bool(not quick and checks and all(checks.values()))
    write_csv(out_dir / "choices.csv", rows + [experiment_row])
    write_json(out_dir / "choices.json", {"quick": quick, "cell_size_m": cell, "rows": rows,
                                          "experiment": experiment_row, "checks": checks, "passed": passed,
                                          "study_wall_s": time.perf_counter() - t0})

    report = Report(out_dir, "Study bui2008-choices: what each model choice does to the aluminium-bar collapse")
    report.text(f"Scene `projects/examples/{SCENE}.toml`, apic-affine, {cell * 1e3:g} mm cells, 2 x 2 particles "
                f"per cell, dt = {1e4 * cell:g} us (the paper's 20 us at 2 mm, scaled with the cell), 1 s. "
                f"Machine: {machine_line()}. Study wall time {time.perf_counter() - t0:.0f} s.")
    report.heading("Verdict")
    report.text(("PASS" if passed else ("reported (quick)" if quick else "FAIL"))
                + ": the shipped scene against the validation targets (toe 0.40-0.48 m, RMS <= 6 mm, crest "
                "0.095-0.101 m at 2 mm cells).")
    heights = [f"failure at {1e3 * h:.0f} mm (m)" for h in FAILURE_HEIGHTS_M]
    table = []
    for r in rows + [experiment_row]:
        table.append([r["choice"], fmt(r.get("toe_m")), fmt(r.get("reach_m")), fmt(r.get("centroid_m"), 4),
                      *(fmt(r.get(f"failure_x_{1e3 * h:.0f}mm_m")) for h in FAILURE_HEIGHTS_M),
                      fmt(r.get("failure_rms_mm")), fmt(r.get("rms_mm")), fmt(r.get("crest_m"), 4),
                      fmt(r.get("max_speed_m_s")), fmt(r.get("wall_s"))])
    report.table(["choice", "toe (m)", "reach (m)", "centroid (m)", *heights, "failure RMS (mm)",
                  "surface RMS (mm)", "crest (m)", "max speed (m/s)", "wall (s)"], table)
    report.text("\n".join(f"- **{label}**: {what}" for label, (_, _, what) in CHOICES.items()))
    for group, labels in (("surfaces", list(CHOICES)[:5]), ("surfaces_rate", list(CHOICES)[5:])):
        fig, axes = new_figure(8.0, 2.0 * len(labels), ncols=1, nrows=len(labels))
        for ax, label in zip(axes[:, 0], labels):
            rec, dep = records[label]
            plot_particles(ax, rec, label)
            if dep is not None:
                ax.plot(dep.surface_x, dep.surface_y, color="tab:blue", lw=1.0, label=f"{label}: surface")
            plot_experiment(ax, experiment, failure)
            ax.set_title(f"{label}: toe {fmt(rec.extra.get('toe_m'))} m, centroid "
                         f"{fmt(rec.extra.get('centroid_m'), 4)} m", fontsize=8)
            if label == labels[0]:
                ax.legend(fontsize=5, loc="upper right")
        report.figure(fig, group, "Final surface and undisturbed wedge of each choice over the experiment's "
                      "surface and failure line.")
    path = report.write()
    verdict = [f"bui2008-choices {'PASS' if passed else 'reported' if quick else 'FAIL'} ({cell * 1e3:g} mm cells; "
               f"{time.perf_counter() - t0:.0f} s)"]
    verdict += [f"{r['choice']}: toe {fmt(r.get('toe_m'))} m, centroid {fmt(r.get('centroid_m'), 4)} m, "
                f"RMS {fmt(r.get('rms_mm'))} mm" for r in rows]
    return StudyResult("bui2008-choices", passed, verdict, path, time.perf_counter() - t0,
                       {"rows": rows, "experiment": experiment_row})
