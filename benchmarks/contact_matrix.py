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
"""

from __future__ import annotations

import argparse
import csv
import itertools
import sys
import time
from pathlib import Path

ANGLES = "10:0,10:20,20:10,20:30,30:20,30:45,40:30,40:45"
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
    ap.add_argument("--start", choices=("settled", "free"), default="settled",
                    help="settled: equilibrium stress at t = 0; free: stress free (elastic waves)")
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

    from solver import runtime

    angles = [tuple(float(v) for v in pair.split(":")) for pair in args.angles.split(",")]
    settled = args.start == "settled"
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
                        row = (contact, scheme, precision, thickness, youngs, theta, delta, o.slides, o.distance_m,
                               o.analytic_m, o.frictionless_m, o.error, o.steps, time.perf_counter() - t0, args.aspect)
                        rows.append(row)
                        out.writerow(row)
                        fh.flush()
                        print(" ".join(str(v) for v in row), flush=True)
            finally:
                runtime.release()
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


if __name__ == "__main__":
    sys.exit(main())
