"""The full incline matrix of the contact law (docs/validation.md, contact).

A block at rest on a frictional contact (:mod:`studies.contact_scenes`): every scheme, precision,
thickness (cells), Young's modulus and contact (bottom, left and right wall, ramp structure) against
inclines and friction angles. Sliding cases: error of the slip against the analytic distance;
sticking cases: the slip as a fraction of the frictionless distance. Rows go to a CSV as they
finish (a long run can be stopped and read), then a summary (max/mean per axis value) is printed.

Usage::

    PYTHONPATH=$PWD python -m benchmarks.contact_matrix --out contact-matrix.csv [--start free]
        [--schemes mpm,apic,apic-affine] [--precisions f32,f64] [--thickness 1,5,20]
        [--youngs 1e6,1e8] [--contacts bottom,left,right,ramp] [--angles 10:0,20:10,...] [--aspect 4]
    PYTHONPATH=$PWD python -m benchmarks.contact_matrix --table a.csv b.csv   # the summary of saved rows

``--path project`` runs the same matrix the way a user does (:func:`project_text`, :func:`run_case`):
a project file (tilted ``domain.gravity_m_s2`` and a friction side, or a ``[[structures]]`` ramp
with a friction contact under vertical gravity), a ``gravity`` stage (``--start gravity``, the
default of that path; ``k0`` or ``free`` for none), a ``dynamic`` stage, run by
:func:`projects.runner.run_project` into a results folder, the slip read from the last frame
(``projects.results.read_vtp``, ``displacement``), at a realistic scale (``--cell 0.05`` m for
both stiffnesses)::

    PYTHONPATH=$PWD python -m benchmarks.contact_matrix --path project --out project-matrix.csv
"""

from __future__ import annotations

import argparse
import csv
import itertools
import sys
import math
import time
from dataclasses import dataclass
from pathlib import Path

from solver.config import DAMPING_MODELS, DEFAULT_DAMPING_MODEL

ANGLES = "10:0,10:20,20:10,20:30,30:20,30:45,40:30,40:45"
SLIDE_TOLERANCE = 0.03  # the issue's: |slip / analytic - 1|
STICK_TOLERANCE = 0.001  # slip / frictionless distance
COLUMNS = ("contact", "scheme", "precision", "thickness_cells", "youngs_pa", "incline_deg", "friction_deg", "slides",
           "slip_m", "analytic_m", "frictionless_m", "error", "steps", "wall_s", "aspect")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("contact-matrix.csv"))
    ap.add_argument("--schemes", default="mpm,apic,apic-affine")
    ap.add_argument("--precisions", default="f32,f64")
    ap.add_argument("--thickness", default="1,5,20")
    ap.add_argument("--youngs", default="1e6,1e8")
    ap.add_argument("--contacts", default="bottom,left,right,ramp")
    ap.add_argument("--angles", default=ANGLES, help="incline:friction pairs in degrees")
    ap.add_argument("--aspect", type=float, default=4.0,
                    help="block length / thickness (at least 40 cells long; the scenes' default 4)")
    ap.add_argument("--start", choices=("settled", "free", "gravity", "k0"), default=None,
                    help="engine path: settled (default; equilibrium stress at t = 0) or free (stress free, "
                         "elastic waves); project path: gravity (default; a gravity stage first), k0 or free")
    ap.add_argument("--path", choices=("engine", "project"), default="engine",
                    help="engine: the scenes of studies.contact_scenes (2 m / 0.1 m cells); project: project "
                         "files run by projects.runner.run_project (--cell)")
    ap.add_argument("--cell", type=float, default=PROJECT_CELL_M, help="project path: cell size (m)")
    ap.add_argument("--gravity-s", default="recommended",
                    help="project path: the gravity stage's duration (s), or 'recommended' (default): the one "
                         "projects.checks.recommended_initial_stage gives the project, at least 1 s")
    ap.add_argument("--damping-ratio", type=float, default=0.0,
                    help="project path: the block's material damping, this fraction of critical at its first "
                         "shear mode on the base (docs/solver.md, material damping; default 0, undamped)")
    ap.add_argument("--damping-model", choices=DAMPING_MODELS, default=DEFAULT_DAMPING_MODEL,
                    help="project path: the damping model of --damping-ratio (docs/solver.md, material damping)")
    ap.add_argument("--damping-frequency-factor", type=float, default=1.0,
                    help="project path: the damping's frequency in first shear modes of the block (default 1)")
    ap.add_argument("--work", type=Path, default=None, help="project path: results folder (default: a temporary one)")
    ap.add_argument("--table", nargs="+", type=Path, help="print the summary of saved CSVs and stop")
    args = ap.parse_args(argv)
    if args.table:
        rows = []
        for path in args.table:
            with open(path, newline="") as fh:
                for r in csv.DictReader(fh):
                    rows.append((r["contact"], r["scheme"], r["precision"], int(r["thickness_cells"]),
                                 float(r["youngs_pa"]), float(r["incline_deg"]), float(r["friction_deg"]),
                                 r["slides"] == "True", float(r["slip_m"]), float(r["analytic_m"]),
                                 float(r["frictionless_m"]), float(r["error"]), int(r["steps"]), float(r["wall_s"]),
                             float(r.get("aspect") or 4.0)))
        summarise(rows)
        return 0

    angles = [tuple(float(v) for v in pair.split(":")) for pair in args.angles.split(",")]
    if args.path == "project":
        return _project_matrix(args, angles)
    if args.start not in (None, "settled", "free"):
        ap.error(f"--start {args.start}: the engine path takes settled or free")

    from solver import runtime

    settled = args.start in (None, "settled")
    rows = []
    with open(args.out, "w", newline="") as fh:
        out = csv.writer(fh)
        out.writerow(COLUMNS)
        for precision in args.precisions.split(","):
            runtime.acquire("cpu", precision)
            from studies.contact_scenes import RampIncline, WallIncline

            try:
                for contact, scheme, thickness, youngs in itertools.product(
                        args.contacts.split(","), args.schemes.split(","),
                        [int(t) for t in args.thickness.split(",")], [float(e) for e in args.youngs.split(",")]):
                    scenes = {}
                    for theta, delta in angles:
                        t0 = time.perf_counter()
                        if contact == "ramp":
                            if theta not in scenes:
                                scenes[theta] = RampIncline(scheme, precision, thickness, youngs, theta, aspect=args.aspect)
                            o = scenes[theta].run(delta, settled)
                        else:
                            if None not in scenes:
                                scenes[None] = WallIncline(scheme, precision, thickness, youngs, contact, aspect=args.aspect)
                            o = scenes[None].run(theta, delta, settled)
                        _record(rows, out, fh, (contact, scheme, precision, thickness, youngs, theta, delta), o,
                                time.perf_counter() - t0, args.aspect)
            finally:
                runtime.release()
    summarise(rows)
    return 0


def _record(rows: list, out, fh, case: tuple, o, wall_s: float, aspect: float) -> None:
    """One case's row (:data:`COLUMNS`): kept for the summary, written and flushed, printed."""
    row = (*case, o.slides, o.distance_m, o.analytic_m, o.frictionless_m, o.error, o.steps, wall_s, aspect)
    rows.append(row)
    out.writerow(row)
    fh.flush()
    print(" ".join(str(v) for v in row), flush=True)


def _project_matrix(args, angles) -> int:
    """The matrix through the project path (``--path project``): one project per case."""
    import tempfile

    start = args.start or "gravity"
    if start == "settled":
        raise SystemExit("--start settled: the project path takes gravity, k0 or free")
    rows = []
    with tempfile.TemporaryDirectory(prefix="contact-matrix-") as scratch, open(args.out, "w", newline="") as fh:
        work = args.work or Path(scratch)
        out = csv.writer(fh)
        out.writerow(COLUMNS)
        for precision, contact, scheme, thickness, youngs in itertools.product(
                args.precisions.split(","), args.contacts.split(","), args.schemes.split(","),
                [int(t) for t in args.thickness.split(",")], [float(e) for e in args.youngs.split(",")]):
            for theta, delta in angles:
                t0 = time.perf_counter()
                gravity_s = None if args.gravity_s == "recommended" else float(args.gravity_s)
                case = project_text(contact, scheme, precision, thickness, youngs, theta, delta, cell_m=args.cell,
                                    start=start, aspect=args.aspect, gravity_s=gravity_s,
                                    damping_ratio=args.damping_ratio, damping_model=args.damping_model,
                                    damping_frequency_factor=args.damping_frequency_factor)
                try:
                    o, _ = run_case(case, work / "run")
                except RuntimeError as err:  # a failed run (e.g. the stability guard) is a row, not the end
                    print(f"FAILED {err}", flush=True)
                    continue
                _record(rows, out, fh, (contact, scheme, precision, thickness, youngs, theta, delta), o,
                        time.perf_counter() - t0, args.aspect)
    summarise(rows)
    return 0


def summarise(rows) -> None:
    """Max and mean error per group: overall, per value of each axis, and a markdown table per
    contact and scheme (sliding: |slip / analytic - 1|; sticking: slip / frictionless)."""
    import numpy as np

    def stats(sel):
        e = np.abs([r[11] for r in sel])
        return f"{len(sel)}, max {100 * e.max():.2f} % / mean {100 * e.mean():.2f} %" if sel else "-"

    for slides, what in ((True, "sliding: |slip / analytic - 1|"), (False, "sticking: slip / frictionless")):
        sel = [r for r in rows if r[7] == slides]
        if not sel:
            continue
        print(f"{what}: {stats(sel)}")
        for k, name in ((0, "contact"), (1, "scheme"), (2, "precision"), (3, "thickness"), (4, "E")):
            parts = [f"{value}: {stats([r for r in sel if r[k] == value])}" for value in sorted({r[k] for r in sel}, key=str)]
            print(f"  by {name}: " + "; ".join(parts))
        parts = [f"{t:g}/{d:g}: {stats([r for r in sel if (r[5], r[6]) == (t, d)])}"
                 for t, d in sorted({(r[5], r[6]) for r in sel})]
        print("  by angles: " + "; ".join(parts))
    failed = [r for r in rows if abs(r[11]) > (SLIDE_TOLERANCE if r[7] else STICK_TOLERANCE)]
    print(f"\noutside the tolerance (sliding {100 * SLIDE_TOLERANCE:g} %, sticking {100 * STICK_TOLERANCE:g} %): "
          f"{len(failed)} of {len(rows)}")
    for r in failed:
        print(f"  {r[0]} {r[1]} {r[2]} {r[3]} cells E={r[4]:g} {r[5]:g}/{r[6]:g}: "
              f"{'sliding' if r[7] else 'sticking'} {100 * r[11]:+.2f} %")
    print()
    print("| contact | scheme | precision | sliding: cases, max / mean error | sticking: cases, max / mean slip |")
    print("|---|---|---|---|---|")
    for contact in sorted({r[0] for r in rows}):
        for scheme in sorted({r[1] for r in rows}):
            for precision in sorted({r[2] for r in rows}):
                sel = [r for r in rows if r[:3] == (contact, scheme, precision)]
                if sel:
                    print(f"| {contact} | {scheme} | {precision} | {stats([r for r in sel if r[7]])} | "
                          f"{stats([r for r in sel if not r[7]])} |")


# ---------------------------------------------------------------------------------------------
# The project path: what a user (or a judge) writes, run as a user runs it.

#: The project path's defaults: 5 cm cells, a 0.2 s gravity stage (damped), 2 x 2 particles per
#: cell, the project's default time step (cfl 0.5).
PROJECT_CELL_M = 0.05
GRAVITY_STAGE_S = 0.2
#: A 1-cell sheet is this many cells long (thicker blocks: ``aspect`` x their thickness).
SHEET_LENGTH_CELLS = 20


@dataclass(frozen=True)
class ProjectCase:
    """One case of the project path: its project file's text and how to read its slip.

    ``base_row`` and ``slip`` take the particles' start positions and displacements (m, N x 2)."""

    text: str
    contact: str
    theta_deg: float
    delta_deg: float
    duration_s: float
    cell_m: float
    surface_point: tuple[float, float]  # a point of the contact surface
    normal: tuple[float, float]  # the contact's outward normal (into the block)
    slope: tuple[float, float]  # down the slope

    def base_row(self, start) -> "np.ndarray":
        """The lowest particle row: start positions within half a cell of the contact."""
        import numpy as np

        return (np.asarray(start) - self.surface_point) @ np.asarray(self.normal) < 0.5 * self.cell_m

    def outcome(self, start, displacement):
        """The :class:`studies.contact_scenes.Outcome` of the frame: the mean slip of the lowest row
        along the slope against the analytic (sliding) or frictionless (sticking) distance."""
        import numpy as np

        from studies.contact_scenes import Outcome, analytic_distance

        row = self.base_row(start)
        slip = float((np.asarray(displacement)[row] @ np.asarray(self.slope)).mean())
        analytic = analytic_distance(self.theta_deg, self.delta_deg, self.duration_s)
        frictionless = analytic_distance(self.theta_deg, 0.0, self.duration_s)
        return Outcome(slip, analytic, frictionless, analytic > 0, 0, self.cell_m)


def _f(value: float) -> str:
    return repr(float(value))


def project_text(contact: str, scheme: str, precision: str, thickness_cells: int, youngs_pa: float,
                 theta_deg: float, delta_deg: float, *, cell_m: float = PROJECT_CELL_M, start: str = "gravity",
                 aspect: float = 4.0, duration_s: float | None = None, gravity_s: float | None = GRAVITY_STAGE_S,
                 per_cell: int = 2, start_cells: float = 1.0, damping_ratio: float = 0.0,
                 damping_model: str = DEFAULT_DAMPING_MODEL, damping_frequency_factor: float = 1.0) -> ProjectCase:
    """A block at rest on a frictional contact as a project file.

    ``contact``: ``"bottom"``, ``"left"`` or ``"right"`` (a friction side, the incline made by
    tilting gravity) or ``"ramp"`` (a friction structure at ``theta_deg`` under vertical gravity).
    ``start``: ``"gravity"`` (a damped gravity stage of ``gravity_s`` first; ``None``: the duration
    :func:`projects.checks.recommended_initial_stage` gives the project), ``"k0"`` or
    ``"free"`` (the dynamic stage only). The dynamic stage lasts ``duration_s`` (default: the
    analytic travel of 20 cells plus 5 %, :func:`studies.contact_scenes.run_time`); one frame at
    its end. ``start_cells``: on the ramp, how far down the face from the ramp's convex top vertex
    the block's upslope end starts (cells). ``damping_ratio``: the block's material damping
    (docs/solver.md), that fraction of critical at the block's first shear mode on its base,
    ``c_s / (4 H)`` (times ``damping_frequency_factor``), by ``damping_model``.
    """
    import numpy as np

    from studies.contact_scenes import DENSITY, G, POISSON, TRAVEL_CELLS, run_time

    dx = cell_m
    n = int(thickness_cells)
    length = SHEET_LENGTH_CELLS if n == 1 else int(round(aspect * n))
    T = run_time(theta_deg, delta_deg, dx) if duration_s is None else duration_s
    if start == "gravity" and gravity_s is None:
        # the recommended stage depends on the block alone, not on the room around it
        probe = project_text(contact, scheme, precision, thickness_cells, youngs_pa, theta_deg, delta_deg,
                             cell_m=cell_m, start=start, aspect=aspect, duration_s=duration_s, gravity_s=1.0,
                             per_cell=per_cell, start_cells=start_cells, damping_ratio=damping_ratio,
                             damping_model=damping_model, damping_frequency_factor=damping_frequency_factor)
        import tomllib

        from projects.checks import recommended_initial_stage
        from projects.schema import validate_project

        gravity_s = recommended_initial_stage(validate_project(tomllib.loads(probe.text))).get("duration_s", 1.0)
    travel = TRAVEL_CELLS * 1.15 + 6  # cells of room down the slope
    if start == "gravity":
        # a sliding block slides during the gravity stage too: undamped at most a r^2 / 6 over the
        # linear ramp of length r, then v h + a h^2 / 2 over the hold h at full gravity; about 0.3
        # of it with the default damping
        from solver.config import GRAVITY_RAMP_FRACTION

        slide = G * (math.sin(math.radians(theta_deg)) - math.tan(math.radians(delta_deg)) * math.cos(math.radians(theta_deg)))
        r = GRAVITY_RAMP_FRACTION * gravity_s
        h = gravity_s - r
        travel += math.ceil(max(slide, 0.0) * (r * r / 6 + r * h / 2 + h * h / 2) / dx)
    th = math.radians(theta_deg)
    s, c = math.sin(th), math.cos(th)
    boundaries = {"left": '"open"', "right": '"open"', "bottom": '"open"', "top": '"open"'}
    friction = f'{{ type = "friction", friction_angle_deg = {_f(delta_deg)} }}'
    structures = ""
    if contact == "bottom":
        gravity = (G * s, -G * c)
        origin, size = (0.0, 0.0), ((length + travel + 2) * dx, (n + 4) * dx)
        x0 = 2 * dx
        block = [(x0, 0.0), (x0 + length * dx, 0.0), (x0 + length * dx, n * dx), (x0, n * dx)]
        surface, normal, slope = (0.0, 0.0), (0.0, 1.0), (1.0, 0.0)
        boundaries["bottom"] = friction
    elif contact in ("left", "right"):
        sign = -1.0 if contact == "left" else 1.0  # gravity's push into the wall
        gravity = (sign * G * c, -G * s)
        origin, size = (0.0, 0.0), ((n + 4) * dx, (length + travel + 2) * dx)
        y0 = travel * dx
        xa, xb = (0.0, n * dx) if contact == "left" else (4 * dx, (n + 4) * dx)
        block = [(xa, y0), (xb, y0), (xb, y0 + length * dx), (xa, y0 + length * dx)]
        wall_x = 0.0 if contact == "left" else (n + 4) * dx
        surface, normal, slope = (wall_x, 0.0), (-sign, 0.0), (0.0, -1.0)
        boundaries[contact] = friction
    elif contact == "ramp":
        gravity = (0.0, -G)
        # the ramp's level and upright faces on node lines (no off-node warning): the run across
        # a whole number of cells, the top a whole number of cells above the bottom face
        across = math.ceil((length + travel) * c)
        run_along = across * dx / c
        t_hat = np.array([c, -s])
        n_hat = np.array([s, c])
        top = np.array([2 * dx, (math.ceil(run_along * s / dx) + 2) * dx])
        foot = top + run_along * t_hat
        below = 0.0
        ramp = [(top[0] - 2 * dx, top[1]), tuple(top), tuple(foot), (foot[0], below), (top[0] - 2 * dx, below)]
        a = top + start_cells * dx * t_hat
        block = [tuple(a), tuple(a + length * dx * t_hat), tuple(a + length * dx * t_hat + n * dx * n_hat),
                 tuple(a + n * dx * n_hat)]
        lo = np.array([0.0, below - 2 * dx])
        hi = np.array([foot[0] + 4 * dx, top[1] + (n + 4) * dx])
        origin, size = tuple(lo), tuple(hi - lo)
        surface, normal, slope = tuple(top), tuple(n_hat), tuple(t_hat)
        boundaries["left"] = boundaries["bottom"] = '"slip"'
        points = ", ".join(f"[{_f(x)}, {_f(y)}]" for x, y in ramp)
        structures = (f'\n[[structures]]\nname = "ramp"\npolygon_m = [{points}]\n'
                      f'contact = {friction}\n')
    else:
        raise ValueError(f"contact {contact!r}: one of bottom, left, right, ramp")
    damping = ""
    if damping_ratio > 0.0:
        c_s = math.sqrt(youngs_pa / (2.0 * (1.0 + POISSON)) / DENSITY)
        damping = f"damping_ratio = {_f(damping_ratio)}\ndamping_frequency_hz = {_f(damping_frequency_factor * c_s / (4.0 * n * dx))}\n"
        if damping_model != DEFAULT_DAMPING_MODEL:
            damping += f'damping_model = "{damping_model}"\n'
    stages = ""
    if start == "gravity":
        stages += '[[stages]]\nname = "initial stress"\ntype = "gravity"\nduration_s = GRAVITY_S\n\n'
    elif start == "k0":
        stages += '[[stages]]\nname = "initial stress"\ntype = "k0"\n\n'
    elif start != "free":
        raise ValueError(f"start {start!r}: one of gravity, k0, free")
    stages += f'[[stages]]\nname = "run"\ntype = "dynamic"\nduration_s = {_f(T)}\n'
    polygon = ", ".join(f"[{_f(x)}, {_f(y)}]" for x, y in block)
    sides = "\n".join(f"{k} = {v}" for k, v in boundaries.items())
    text = f"""[runout]
schema_version = 1
title = "block on a {contact} contact, {theta_deg:g} deg incline, {delta_deg:g} deg friction"

[domain]
origin_m = [{_f(origin[0])}, {_f(origin[1])}]
size_m = [{_f(size[0])}, {_f(size[1])}]
cell_size_m = {_f(dx)}
gravity_m_s2 = [{_f(gravity[0])}, {_f(gravity[1])}]

[domain.boundaries]
{sides}

[materials.block]
model = "linear-elastic"
density_kg_m3 = {_f(DENSITY)}
youngs_modulus_pa = {_f(youngs_pa)}
poisson_ratio = {_f(POISSON)}
{damping}
[[bodies]]
name = "block"
material = "block"
polygon_m = [{polygon}]
{structures}
[particles]
per_cell = {per_cell}

[numerics]
scheme = "{scheme}"
precision = "{precision}"
arch = "cpu"

{stages}
[output]
interval_s = {_f(T)}
fields = ["displacement"]
"""
    if start == "gravity":
        text = text.replace("GRAVITY_S", _f(gravity_s))
    return ProjectCase(text, contact, float(theta_deg), float(delta_deg), T, dx, tuple(map(float, surface)),
                       tuple(map(float, normal)), tuple(map(float, slope)))


def run_case(case: ProjectCase, out_dir: Path):
    """Run a :class:`ProjectCase` through :func:`projects.runner.run_project` into ``out_dir``
    and read its slip from the last frame. Returns ``(Outcome, RunResult)``."""
    import tomllib

    from projects.results import read_vtp
    from projects.runner import run_project
    from projects.schema import validate_project

    project = validate_project(tomllib.loads(case.text))
    result = run_project(project, out_dir, overwrite=True)
    if result.status != "completed":
        raise RuntimeError(f"{case.contact} {case.theta_deg:g}/{case.delta_deg:g}: {result.status}: {result.message}")
    frames = sorted(Path(out_dir, "frames").glob("frame_*.vtp"))
    frame = read_vtp(frames[-1], {"Points", "displacement"})
    displacement = frame["displacement"][:, :2].astype(float)
    start = frame["Points"][:, :2].astype(float) - displacement
    outcome = case.outcome(start, displacement)
    outcome.steps = int(result.summary.get("steps", 0))
    return outcome, result


if __name__ == "__main__":
    sys.exit(main())
