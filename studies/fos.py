"""``runout study fos``: factor of safety by strength reduction against the mesh and against Bishop.

Scenes:

- the shipped example ``projects/examples/slope_fos.toml`` (6 m high 45 deg slope, c = 10 kPa,
  phi = 30 deg, psi = 0) without its run-out stage, at several cell sizes (4 particles per
  cell): the strength-reduction factor, its bracket, the trials, Bishop's factor of the same
  section and the cost of the search in equilibrium runs (steps of the search over the steps of
  the initial stress and settling; the same model, so steps measure cost without the machine's
  load or Taichi's start-up);
- an infinite slope: a uniform layer 1 m thick on a rough (fixed) base, gravity rotated so that
  the base is inclined at beta, 4 cells wide between periodic sides (no ends), the default
  failure criteria with a monitor on the surface; against
  ``F = c / (gamma z cos^2 b tan b) + tan(phi) / tan(b)`` (z the vertical depth) with associated
  flow (psi = phi, where the Drucker-Prager plane-strain match mobilises Mohr-Coulomb's strength
  in the layer's simple shear), for cohesive-frictional and purely frictional cases and two
  angles each, the cohesive one also against the cell size; and one psi = 0 case against the
  factor of the materials' cone (:func:`drucker_prager_infinite_slope_factor`).

- ACADS benchmark 1(a) (Giam and Donald 1989; referee factor 1.00) at 0.5 m cells.

Targets: the example's factor within 10 % of Bishop's at the finest cell and ACADS 1(a) within
10 % of its referee factor; the cost of a factor to 0.01 at most 8 equilibrium runs; the
infinite slope within 3 % (reported, with the gap, when not).

Quick: cells of 1.0 and 0.5 m for the example; each infinite slope at its finest cell.
Full: cells of 1.0, 0.5 and 0.25 m; the cohesive infinite slope also at 1/8 and 1/16 m.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from studies.common import (
    Note,
    Report,
    StudyResult,
    fmt,
    load_scene,
    machine_line,
    new_figure,
    quiet,
    write_csv,
    write_json,
)

SCENE = "slope_fos"
#: Targets (see the module docstring).
BISHOP_TOLERANCE = 0.10
COST_LIMIT = 8.0
INFINITE_TOLERANCE = 0.03
#: Infinite-slope cases: beta (deg), c (Pa), phi (deg), psi (deg), cells (m, the last the finest;
#: quick runs only that one), the material's mohr_coulomb_match. With cohesion the bias is about
#: 1.25 dx / t of the cohesive part.
INFINITE_CASES = [
    (30.0, 6000.0, 20.0, 20.0, (1.0 / 8, 1.0 / 16, 1.0 / 32), "plane-strain-associated"),
    (40.0, 10000.0, 30.0, 30.0, (1.0 / 32,), "plane-strain-associated"),
    (25.0, 0.0, 35.0, 35.0, (1.0 / 8,), "plane-strain-associated"),
    (35.0, 0.0, 40.0, 40.0, (1.0 / 8,), "plane-strain-associated"),
    (25.0, 0.0, 35.0, 0.0, (1.0 / 8,), "plane-strain-associated"),
    (25.0, 0.0, 35.0, 0.0, (1.0 / 8,), "plane-strain"),
    (25.0, 0.0, 35.0, 0.0, (1.0 / 8,), "simple-shear"),
]


def infinite_slope(beta_deg: float, cohesion_pa: float, phi_deg: float, *, cell_m: float = 0.125,
                   thickness_m: float = 1.0, width_cells: int = 4, dilatancy_deg: float | None = None,
                   youngs_modulus_pa: float = 20e6, tolerance: float = 0.01, precision: str = "f64",
                   scheme: str = "apic-affine", duration_s: float = 1.0,
                   mohr_coulomb_match: str | None = None) -> tuple[Any, float]:
    """A project of an infinite slope and its closed-form factor of safety.

    A uniform layer ``thickness_m`` thick (normal to the base) on a rough (fixed) base, gravity
    rotated by ``beta_deg`` (``g (sin b, -cos b)``) so that the base is the grid's bottom, and
    periodic left and right sides ``width_cells`` cells apart: the layer repeats without end, no
    strain along the slope. Drucker-Prager with ``dilatancy_deg`` (default ``phi_deg``: associated
    flow, where the materials' plane-strain match reproduces Mohr-Coulomb's strength on the base,
    docs/validation.md) and the material key ``mohr_coulomb_match`` when given (default: the
    project's default match), rho = 2000 kg/m3, nu = 0.3. Stages: gravity 1 s, then the strength
    reduction with its default criteria and a monitor at the surface (the default, the crest of
    a slope, has no meaning on a uniform layer). The closed form:
    ``F = c / (gamma z cos^2 b tan b) + tan(phi) / tan(b)`` with ``z = thickness / cos b`` the
    vertical depth of the base.

    Returns
    -------
    (projects.schema.Project, float)
    """
    from projects.schema import validate_project

    g, rho = 9.81, 2000.0
    b = math.radians(beta_deg)
    width = width_cells * cell_m
    psi = phi_deg if dilatancy_deg is None else dilatancy_deg
    data = {
        "runout": {"schema_version": 1, "title": f"infinite slope beta {beta_deg:g} c {cohesion_pa:g} phi {phi_deg:g}"},
        "domain": {"origin_m": [0.0, 0.0], "size_m": [width, thickness_m + 2 * cell_m],
                   "cell_size_m": cell_m, "gravity_m_s2": [g * math.sin(b), -g * math.cos(b)],
                   "boundaries": {"left": "periodic", "right": "periodic", "bottom": "fixed", "top": "open"}},
        "materials": {"soil": {"model": "drucker-prager", "density_kg_m3": rho, "youngs_modulus_pa": youngs_modulus_pa,
                               "poisson_ratio": 0.3, "cohesion_pa": cohesion_pa, "friction_angle_deg": phi_deg,
                               "dilatancy_angle_deg": psi,
                               **({} if mohr_coulomb_match is None else {"mohr_coulomb_match": mohr_coulomb_match})}},
        "bodies": [{"name": "layer", "material": "soil",
                    "polygon_m": [[0.0, 0.0], [width, 0.0], [width, thickness_m], [0.0, thickness_m]]}],
        "particles": {"per_cell": 2},
        "numerics": {"cfl": 0.5, "arch": "cpu", "precision": precision, "scheme": scheme},
        "stages": [
            {"name": "gravity", "type": "gravity", "duration_s": duration_s},
            {"name": "strength reduction", "type": "strength-reduction", "tolerance": tolerance,
             "limit_equilibrium": False, "failure": {"monitor_point_m": [0.5 * width, thickness_m]}},
        ],
        "output": {"interval_s": 1.0, "fields": ["displacement", "plastic_strain"]},
    }
    return validate_project(data), infinite_slope_factor(beta_deg, cohesion_pa, phi_deg, rho * g, thickness_m)


def drucker_prager_infinite_slope_factor(beta_deg: float, cohesion_pa: float, phi_deg: float, dilatancy_deg: float,
                                         unit_weight_n_m3: float, thickness_m: float,
                                         match: str = "plane-strain-associated") -> float:
    """The factor of safety of the materials' Drucker-Prager cone (solver.materials.drucker_prager,
    matched to Mohr-Coulomb by ``match``) in an infinite slope, by strength reduction.

    At collapse the layer shears along the base with no strain along it or out of plane; the flow
    rule then fixes the stress (``s_xx = s_zz = -2 q alpha_psi``) and the shear stress on planes
    parallel to the base is ``tau = sqrt(1 - 12 alpha_psi^2) (k - 3 alpha sigma_n) / (1 - 12 alpha
    alpha_psi)`` (compression negative). With ``psi = phi`` (any match) this is
    ``c + |sigma_n| tan(phi)``, Mohr-Coulomb's strength (the closed form); with ``psi = 0`` the
    associated match carries ``(c + |sigma_n| tan phi) / sqrt(1 + 4/3 tan^2 phi)``, the
    ``"simple-shear"`` match ``c + |sigma_n| tan(phi)`` for every psi, the ``"plane-strain"``
    match what non-associated Mohr-Coulomb carries (:func:`mohr_coulomb_infinite_slope_factor`).
    F is the factor whose reduced strengths (``c / F``, ``tan(phi) / F``,
    ``psi_F = min(psi, phi_F)``) just carry the base's shear stress ``gamma t sin(b)`` under
    ``sigma_n = -gamma t cos(b)``.
    """
    from solver.materials.drucker_prager import dp_constants

    def strength(phi_f: float, psi_f: float, c_f: float, sigma_n: float) -> float:
        alpha, k, alpha_psi = dp_constants(phi_f, psi_f, c_f, match)
        return math.sqrt(1.0 - 12.0 * alpha_psi ** 2) * (k - 3.0 * alpha * sigma_n) / (1.0 - 12.0 * alpha * alpha_psi)

    return _reduced_factor(strength, beta_deg, cohesion_pa, phi_deg, dilatancy_deg, unit_weight_n_m3, thickness_m)


def mohr_coulomb_infinite_slope_factor(beta_deg: float, cohesion_pa: float, phi_deg: float, dilatancy_deg: float,
                                       unit_weight_n_m3: float, thickness_m: float) -> float:
    """The factor of safety of a Mohr-Coulomb material of dilatancy psi in an infinite slope, by
    strength reduction.

    The base is a velocity characteristic of the simple shear (no extension along it); for a
    coaxial flow rule of dilatancy psi the stress on it is ``tau = c* + |sigma_n| tan(phi*)`` with
    ``tan(phi*) = sin(phi) cos(psi) / (1 - sin(phi) sin(psi))`` and
    ``c* = c cos(phi) cos(psi) / (1 - sin(phi) sin(psi))`` (Davis 1968; Drescher and Detournay
    1993), below ``c + |sigma_n| tan(phi)`` unless psi = phi. The closed form
    (:func:`infinite_slope_factor`) is this with psi = phi.
    """
    def strength(phi_f: float, psi_f: float, c_f: float, sigma_n: float) -> float:
        den = 1.0 - math.sin(phi_f) * math.sin(psi_f)
        return (c_f * math.cos(phi_f) - sigma_n * math.sin(phi_f)) * math.cos(psi_f) / den

    return _reduced_factor(strength, beta_deg, cohesion_pa, phi_deg, dilatancy_deg, unit_weight_n_m3, thickness_m)


def _reduced_factor(strength: Callable[[float, float, float, float], float], beta_deg: float, cohesion_pa: float,
                    phi_deg: float, dilatancy_deg: float, unit_weight_n_m3: float, thickness_m: float) -> float:
    """The factor F whose reduced strengths ``strength(phi_F, psi_F, c / F, sigma_n)`` (Pa) just
    carry the base's shear stress of an infinite slope."""
    from scipy.optimize import brentq

    b = math.radians(beta_deg)
    tau = unit_weight_n_m3 * thickness_m * math.sin(b)
    sigma_n = -unit_weight_n_m3 * thickness_m * math.cos(b)

    def surplus(factor: float) -> float:
        phi_f = math.atan(math.tan(math.radians(phi_deg)) / factor)
        psi_f = min(math.radians(dilatancy_deg), phi_f)
        return strength(phi_f, psi_f, cohesion_pa / factor, sigma_n) - tau

    return float(brentq(surplus, 1e-3, 1e3, xtol=1e-10))


def infinite_slope_factor(beta_deg: float, cohesion_pa: float, phi_deg: float, unit_weight_n_m3: float,
                          thickness_m: float) -> float:
    """``F = c / (gamma z cos^2 b tan b) + tan(phi) / tan(b)``, ``z = thickness / cos b`` the
    vertical depth of the slip plane (thickness normal to the slope, m; gamma in N/m3)."""
    b = math.radians(beta_deg)
    z = thickness_m / math.cos(b)
    return cohesion_pa / (unit_weight_n_m3 * z * math.cos(b) ** 2 * math.tan(b)) + \
        math.tan(math.radians(phi_deg)) / math.tan(b)


def acads_1a(cell_m: float = 0.5) -> Any:
    """ACADS benchmark 1(a) (Giam and Donald 1989): a 10 m high 2:1 slope on a 5 m foundation,
    c' = 3 kPa, phi' = 19.6 deg, gamma = 20 kN/m3, dry; referee factor 1.00."""
    from projects.schema import validate_project

    return validate_project({
        "runout": {"schema_version": 1, "title": "ACADS 1(a)"},
        "domain": {"origin_m": [20.0, 20.0], "size_m": [50.0, 17.0], "cell_size_m": cell_m,
                   "boundaries": {"left": "slip", "right": "slip", "bottom": "fixed", "top": "open"}},
        "materials": {"soil": {"model": "drucker-prager", "density_kg_m3": 20e3 / 9.81, "youngs_modulus_pa": 10e6,
                               "poisson_ratio": 0.3, "cohesion_pa": 3000.0, "friction_angle_deg": 19.6,
                               "dilatancy_angle_deg": 0.0}},
        "bodies": [{"name": "slope", "material": "soil",
                    "polygon_m": [[20.0, 20.0], [70.0, 20.0], [70.0, 35.0], [50.0, 35.0], [30.0, 25.0],
                                  [20.0, 25.0]]}],
        "numerics": {"cfl": 0.5, "arch": "cpu"},
        "stages": [{"type": "gravity", "duration_s": 3.0},
                   {"type": "strength-reduction", "trial_duration_s": 3.0}],
        "output": {"interval_s": 1.0, "fields": ["displacement", "plastic_strain"]},
    })


ACADS_REFEREE = 1.00


def _run(project: Any, out: Path) -> dict[str, Any]:
    from projects.runner import run_project

    t0 = time.perf_counter()
    result = run_project(project, out)
    fos = result.summary.get("factor_of_safety") or {}
    le = result.summary.get("limit_equilibrium") or {}
    eq_steps = fos.get("equilibrium_steps") or 0
    return {
        "status": result.status,
        "message": result.message,
        "particles": result.summary.get("particles"),
        "fos": fos.get("value"),
        "lower": fos.get("lower"),
        "upper": fos.get("upper"),
        "criterion": fos.get("criterion"),
        "trials": len(fos.get("trials", [])),
        "bishop": le.get("factor_of_safety"),
        "equilibrium_steps": eq_steps,
        "search_steps": fos.get("search_steps"),
        "cost_equilibrium_runs": (fos.get("search_steps") or 0) / eq_steps if eq_steps else None,
        "cost_initial_stress_runs": ((fos.get("search_steps") or 0) / fos["initial_stress_steps"]
                                     if fos.get("initial_stress_steps") else None),
        "equilibrium_wall_s": fos.get("equilibrium_wall_time_s"),
        "search_wall_s": fos.get("search_wall_time_s"),
        "wall_s": time.perf_counter() - t0,
        "trial_rows": fos.get("trials", []),
    }


def run(out_dir: Path, quick: bool = False, note: Note = quiet) -> StudyResult:
    """Run the study and write ``report.md``, ``fos.json``, ``mesh.csv``, ``infinite.csv``."""
    t0 = time.perf_counter()
    cells = [1.0, 0.5] if quick else [1.0, 0.5, 0.25]
    mesh_rows = []
    for cell in cells:
        note(f"fos: example slope, {cell:g} m cells")
        project = load_scene(SCENE, [f"domain.cell_size_m={cell}"])
        project = project.model_copy(update={"stages": project.stages[:2]})  # no run-out here
        row = {"cell_size_m": cell, **_run(project, out_dir / f"slope-{cell:g}")}
        rows = row.pop("trial_rows")
        write_csv(out_dir / f"trials-{cell:g}.csv", rows)
        row["bishop_difference"] = (row["fos"] / row["bishop"] - 1.0) if row["fos"] and row["bishop"] else None
        mesh_rows.append(row)
        note(f"fos: {cell:g} m: F = {fmt(row['fos'])} (Bishop {fmt(row['bishop'])}), "
             f"{row['trials']} trials, cost {fmt(row['cost_equilibrium_runs'])} equilibrium runs")
    note("fos: ACADS 1(a), 0.5 m cells")
    acads = _run(acads_1a(0.5), out_dir / "acads-1a")
    write_csv(out_dir / "trials-acads-1a.csv", acads.pop("trial_rows"))
    acads["referee"] = ACADS_REFEREE
    acads["error"] = acads["fos"] / ACADS_REFEREE - 1.0 if acads["fos"] else None
    note(f"fos: ACADS 1(a): F = {fmt(acads['fos'])} (referee 1.00, Bishop {fmt(acads['bishop'])})")
    inf_rows = []
    for beta, c, phi, psi, cells, match in INFINITE_CASES:
        for cell in (cells[-1:] if quick else cells):
            note(f"fos: infinite slope beta {beta:g} c {c:g} phi {phi:g} psi {psi:g} {match}, {cell:g} m cells")
            project, exact = infinite_slope(beta, c, phi, cell_m=cell, dilatancy_deg=psi, duration_s=0.5,
                                            mohr_coulomb_match=match)
            dp = drucker_prager_infinite_slope_factor(beta, c, phi, psi, 2000.0 * 9.81, 1.0, match)
            tag = f"{beta:g}-{c:g}-{phi:g}-{psi:g}-{cell:g}-{match}"
            row = {"beta_deg": beta, "cohesion_pa": c, "phi_deg": phi, "dilatancy_deg": psi, "match": match,
                   "cell_size_m": cell, "exact": exact, "drucker_prager": dp,
                   **_run(project, out_dir / f"infinite-{tag}")}
            write_csv(out_dir / f"trials-infinite-{tag}.csv", row.pop("trial_rows"))
            row["error"] = row["fos"] / exact - 1.0 if row["fos"] else None
            row["error_drucker_prager"] = row["fos"] / dp - 1.0 if row["fos"] else None
            inf_rows.append(row)
            note(f"fos: infinite slope: F = {fmt(row['fos'])} against {fmt(exact)} (Drucker-Prager {fmt(dp)})")
    write_csv(out_dir / "mesh.csv", mesh_rows)
    write_csv(out_dir / "infinite.csv", inf_rows)
    finest = mesh_rows[-1]
    bishop_ok = finest["bishop_difference"] is not None and abs(finest["bishop_difference"]) <= BISHOP_TOLERANCE
    cost_ok = all(r["cost_equilibrium_runs"] is not None and r["cost_equilibrium_runs"] <= COST_LIMIT
                  for r in mesh_rows)
    # the target: the closed form at the finest cell of each case whose cone carries Mohr-Coulomb's
    # tan(phi) on the base (associated flow, or the "simple-shear" match for any psi)
    finest_inf = {}
    for r in inf_rows:
        if r["dilatancy_deg"] == r["phi_deg"] or r["match"] == "simple-shear":
            finest_inf[(r["beta_deg"], r["cohesion_pa"], r["phi_deg"], r["dilatancy_deg"], r["match"])] = r
    inf_ok = all(r["error"] is not None and abs(r["error"]) <= INFINITE_TOLERANCE for r in finest_inf.values())
    acads_ok = acads["error"] is not None and abs(acads["error"]) <= BISHOP_TOLERANCE
    passed = bishop_ok and cost_ok and inf_ok and acads_ok
    data = {"quick": quick, "mesh": mesh_rows, "acads_1a": acads, "infinite": inf_rows, "targets": {
        "bishop_tolerance": BISHOP_TOLERANCE, "cost_limit_equilibrium_runs": COST_LIMIT,
        "infinite_tolerance": INFINITE_TOLERANCE}, "passed": {"bishop": bishop_ok, "cost": cost_ok,
                                                              "infinite": inf_ok, "acads_1a": acads_ok}}
    write_json(out_dir / "fos.json", data)

    report = Report(out_dir, "Study fos: factor of safety by strength reduction")
    report.text(machine_line(), "Quick version." if quick else "Full version.")
    report.heading("Verdict")
    report.text(("PASS" if passed else "FAIL") + f": example within {BISHOP_TOLERANCE:.0%} of Bishop at the finest "
                f"cell: {'yes' if bishop_ok else 'NO'}; search cost <= {COST_LIMIT:g} equilibrium runs: "
                f"{'yes' if cost_ok else 'NO'}; infinite slope within {INFINITE_TOLERANCE:.0%}: "
                f"{'yes' if inf_ok else 'NO'}.")
    report.heading("Example slope against the cell size")
    report.table(["cell (m)", "particles", "F (SRM)", "bracket", "criterion", "trials", "Bishop", "SRM/Bishop - 1",
                  "cost (equilibrium runs)", "cost (gravity stages)", "search wall (s)", "equilibrium wall (s)"],
                 [[r["cell_size_m"], r["particles"], fmt(r["fos"], 4), f"[{fmt(r['lower'], 4)}, {fmt(r['upper'], 4)}]",
                   r["criterion"], r["trials"], fmt(r["bishop"], 4),
                   fmt(r["bishop_difference"]), fmt(r["cost_equilibrium_runs"]), fmt(r["cost_initial_stress_runs"]),
                   fmt(r["search_wall_s"]),
                   fmt(r["equilibrium_wall_s"])] for r in mesh_rows])
    report.text("Cost: steps of all trials over the steps of one equilibrium run, the initial stress and its "
                "settling at full gravity (the same model, so steps measure cost whatever the machine's load); "
                "also over the gravity stage alone. The equilibrium wall time includes Taichi's kernel "
                "compilation on the first run.")
    report.heading("ACADS benchmark 1(a)")
    report.text("Giam and Donald (1989): 10 m high 2:1 slope, c' = 3 kPa, phi' = 19.6 deg, gamma = 20 kN/m3, "
                "dry; referee factor of safety 1.00. Here with 0.5 m cells (20 over the height), psi = 0, "
                "E = 10 MPa, nu = 0.3.")
    report.table(["referee", "F (SRM)", "bracket", "SRM / referee - 1", "Bishop (here)", "trials",
                  "cost (equilibrium runs)", "particles"],
                 [[ACADS_REFEREE, fmt(acads["fos"], 4), f"[{fmt(acads['lower'], 4)}, {fmt(acads['upper'], 4)}]",
                   fmt(acads["error"]), fmt(acads["bishop"], 4), acads["trials"], fmt(acads["cost_equilibrium_runs"]),
                   acads["particles"]]])
    report.heading("Infinite slope")
    report.table(["beta (deg)", "c (Pa)", "phi (deg)", "psi (deg)", "match", "cell (m)", "closed form",
                  "Drucker-Prager",
                  "F (SRM)", "bracket", "error (closed form)", "error (Drucker-Prager)", "trials", "run"],
                 [[r["beta_deg"], r["cohesion_pa"], r["phi_deg"], r["dilatancy_deg"], r["match"], r["cell_size_m"],
                   fmt(r["exact"], 4), fmt(r["drucker_prager"], 4), fmt(r["fos"], 4),
                   f"[{fmt(r['lower'], 4)}, {fmt(r['upper'], 4)}]", fmt(r["error"]), fmt(r["error_drucker_prager"]),
                   r["trials"], r["status"] if r["status"] == "completed" else f"{r['status']}: {r['message']}"]
                  for r in inf_rows])
    report.text("A layer 1 m thick, 4 cells wide between periodic sides, on a fixed base, gravity rotated by beta; "
                "closed form F = c / (gamma z cos^2 b tan b) + tan(phi) / tan(b). 'Drucker-Prager': the factor of "
                "the material's cone (its mohr_coulomb_match) in the same simple shear: the closed form for "
                "psi = phi and for the 'simple-shear' match, non-associated Mohr-Coulomb's lower factor for the "
                "'plane-strain' match, lower still for the default match with psi = 0 (docs/validation.md). The "
                "target (3 %) is for the cases whose cone carries tan(phi) on the base, at the finest cell. "
                "With cohesion the factor is biased high by about 1.25 dx / t times the cohesive share of F: "
                "the particles within 1.5 cells of the base all shear, the highest 1.25 cells above it.")
    fig, ax = new_figure(6.0, 4.0)
    ax.plot([r["cell_size_m"] for r in mesh_rows], [r["fos"] for r in mesh_rows], "o-", label="strength reduction")
    ax.axhline(mesh_rows[0]["bishop"] or float("nan"), color="c", ls="--", label="Bishop (simplified)")
    ax.set_xlabel("cell size (m)")
    ax.set_ylabel("factor of safety")
    ax.invert_xaxis()
    ax.legend()
    report.figure(fig, "mesh", "Factor of safety of the example slope against the cell size.")
    report.text("Raw data: `mesh.csv`, `infinite.csv`, `trials-*.csv` (also `trials-acads-1a.csv`), `fos.json`; "
                "results folders beside them.")
    path = report.write()
    verdict = [
        ("PASS" if passed else "FAIL") + f": F = {fmt(finest['fos'])} at {finest['cell_size_m']:g} m cells "
        f"(Bishop {fmt(finest['bishop'])}), cost {fmt(finest['cost_equilibrium_runs'])} equilibrium runs",
        f"ACADS 1(a): F = {fmt(acads['fos'])} against the referee 1.00 (Bishop here {fmt(acads['bishop'])})",
        *(f"infinite slope beta {r['beta_deg']:g} c {r['cohesion_pa']:g} phi {r['phi_deg']:g} psi {r['dilatancy_deg']:g} "
          f"at {r['cell_size_m']:g} m: "
          f"F = {fmt(r['fos'])} against {fmt(r['exact'])} ({fmt(r['error'])})" for r in inf_rows),
    ]
    return StudyResult("fos", passed, verdict, path, time.perf_counter() - t0, data)
