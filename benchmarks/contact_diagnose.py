"""What the wall's contact nodes do in one incline case (docs/validation.md, contact: issue 11's
remaining failures).

One block of :class:`studies.contact_scenes.WallIncline` on the bottom wall, settled and released as
in the matrix, then stepped stage by stage so that the contact law's input and output at the wall
line's nodes can be read at the main grid update (the law acts there on ``v_old + dt f / m``,
apic-affine on its fused momentum; mpm and apic apply it also to the interpolated velocity, which
is not counted here). Printed:

- per wall node under the block, the fraction of steps in stick (tangential velocity cancelled),
  slip down the slope, slip up the slope, separation (trial normal velocity not into the wall);
- the time-mean friction impulse over ``mu`` times the time-mean normal impulse, for the whole
  contact (the recorded contact impulse) and for the wall line's nodes, and how much of the
  friction that ``mu N`` allows is not given in stick steps and in slip steps, with the normal
  and tangential speeds of those steps;
- the wall node's mass at stick and slip steps, against its value at the release;
- the block's kinetic energy of translation and the rest (elastic waves and rotation), over time.

With Cundall's damping (``--damping``) the six-stage schemes' trial velocity read here leaves the
damping out (the counts are then approximate; the slip is the engine's).

Usage::

    PYTHONPATH=$PWD python -m benchmarks.contact_diagnose apic-affine f64 20 1e6 40 45 [--aspect 4]
        [--time 1] [--damping 0] [--cfl 0.5] [--ppc 2] [--transfer]
"""

from __future__ import annotations

import argparse
import math
import sys

import numpy as np


def diagnose(scheme: str, precision: str, thickness: int, youngs: float, theta: float, delta: float,
             aspect: float = 4.0, time_factor: float = 1.0, damping: float = 0.0, samples: int = 12,
             transfer: bool = False) -> dict:
    """One case (bottom wall); ``transfer``: the experiment of docs/validation.md (contact; not the
    engine's law): after the grid update, the friction a stuck wall node left unused is applied to
    the node one cell inside it, never reversing that node's velocity along the wall."""
    from solver import runtime
    from solver.config import Boundary, Grid
    from solver.engine import PAD
    from studies import contact_scenes as cs

    runtime.acquire("cpu", precision)
    try:
        sc = cs.WallIncline(scheme, precision, thickness, youngs, "bottom", aspect=aspect)
        e = sc.engine

        def contact(fixed: bool) -> None:
            sides = sc._sides(math.radians(delta))
            if fixed:
                sides["bottom"] = Boundary("fixed")
            e.set_boundaries(Grid(sc.grid.origin_m, sc.grid.size_m, sc.dx, **sides))

        h = sc.dx / cs.PPC
        e.load_particles(sc.positions, np.full(len(sc.positions), h * h), np.zeros(len(sc.positions), np.int32))
        e.set_stress(cs.slope_stress(sc.positions, sc.slope, sc.normal, 0.0, sc.thickness_m, theta, delta))
        dt = cs.CFL * sc.dx / sc.material.p_wave_speed_m_s
        g = sc.gravity(theta)
        contact(True)
        for _ in range(int(math.ceil(cs.SETTLE_TRANSITS * sc.length_m / sc.material.p_wave_speed_m_s / dt))):
            e.step(dt, g, cs.SETTLE_DAMPING)
        e.set_velocity(np.zeros((e.n, 2)))
        contact(False)
        t_end = cs.run_time(theta, delta, sc.dx) * time_factor
        steps = int(math.ceil(t_end / dt))
        dt = t_end / steps
        x0 = e.x.to_numpy().astype(np.float64)
        m = e.m.to_numpy()[: e.n].astype(np.float64)
        mu = math.tan(math.radians(delta))
        e.read_contacts()
        recipe = e.recipe
        cut = recipe.index("grid update")
        counts = None
        lost = {"stick": 0.0, "slip": 0.0}
        speeds = {"stick_vn": [], "stick_vt": [], "slip_vn": [], "stick_m": [], "slip_m": [], "stick_lost": []}
        full = None
        normal = friction = 0.0
        energy = []
        every = max(1, steps // samples)

        def kernel(stage):
            e._stage_kernel(stage, dt, g[0], g[1], damping, damping > 0.0)

        for k in range(steps):
            for stage in recipe[:cut]:
                kernel(stage)
            M = e.g_mass.to_numpy()[:, PAD]
            if e.six_stage:
                trial = e.g_v_old.to_numpy()[:, PAD] + dt * e.g_f.to_numpy()[:, PAD] / np.maximum(M, 1e-300)[:, None]
            else:
                trial = e.g_mom.to_numpy()[:, PAD] / np.maximum(M, 1e-300)[:, None]
                if damping > 0.0:
                    trial = trial + dt * e.g_f.to_numpy()[:, PAD] / np.maximum(M, 1e-300)[:, None]
            kernel("grid update")
            if transfer:
                G = e.g_mom.to_numpy()
                new = G[:, PAD]
                M0 = M
                vn0, vt0 = trial[:, 1], trial[:, 0]
                left = np.where((M0 > 0) & (vn0 < 0), mu * M0 * np.maximum(-vn0, 0) - M0 * np.abs(vt0 - new[:, 0]), 0.0)
                left = np.maximum(left, 0.0)
                M1 = e.g_mass.to_numpy()[:, PAD + 1]
                v1 = G[:, PAD + 1, 0]
                dv = np.where(M1 > 0, np.minimum(left / np.maximum(M1, 1e-300), np.abs(v1)), 0.0)
                G[:, PAD + 1, 0] = v1 - np.sign(v1) * dv
                e.g_mom.from_numpy(G)
            new = e.g_mom.to_numpy()[:, PAD]
            for stage in recipe[cut + 1:]:
                kernel(stage)
            live = M > 0.0
            vn, vt, vt_new = trial[:, 1], trial[:, 0], new[:, 0]
            if counts is None:
                counts = np.zeros((len(M), 4))
            sep = live & (vn >= 0.0)
            held = live & ~sep
            stick = held & (vt_new == 0.0)
            down = held & (vt_new > 0.0)
            up = held & (vt_new < 0.0)
            for c, sel in enumerate((stick, down, up, sep)):
                counts[:, c] += sel
            allowed = M * np.maximum(-vn, 0.0) * mu
            given = M * np.abs(vt - vt_new)
            normal += float(allowed[held].sum())
            friction += float(given[held].sum())
            lost["stick"] += float((allowed - given)[stick].sum())
            lost["slip"] += float((allowed - given)[down | up].sum())
            speeds["stick_vn"] += (-vn[stick]).tolist()
            speeds["stick_vt"] += np.abs(vt[stick]).tolist()
            speeds["slip_vn"] += (-vn[down | up]).tolist()
            if full is None:
                full = float(np.median(M[M > 0]))
            speeds["stick_m"] += (M[stick] / full).tolist()
            speeds["slip_m"] += (M[down | up] / full).tolist()
            speeds["stick_lost"] += (allowed - given)[stick].tolist()
            if k % every == 0 or k == steps - 1:
                v = e.v.to_numpy()[: e.n].astype(np.float64)
                vbar = (m[:, None] * v).sum(0) / m.sum()
                x = e.x.to_numpy().astype(np.float64)
                energy.append(((k + 1) * dt, 0.5 * (m * ((v - vbar) ** 2).sum(1)).sum(), 0.5 * m.sum() * vbar @ vbar,
                               float(((x - x0)[sc.base_row] @ sc.slope).mean())))
        impulse, _ = e.read_contacts()
        x = e.x.to_numpy().astype(np.float64)
    finally:
        runtime.release()
    slip = float(((x - x0)[sc.base_row] @ sc.slope).mean())
    total = counts.sum(1)
    under = total > 0.5 * total.max()
    bottom = impulse[2]
    return dict(
        steps=steps, t_end=t_end, slip_m=slip, analytic_m=cs.analytic_distance(theta, delta, t_end),
        frictionless_m=cs.analytic_distance(theta, 0.0, t_end), fractions=counts[under] / total[under, None],
        contact_ratio=abs(bottom[0]) / (mu * abs(bottom[1])) if mu > 0 else float("nan"),
        wall_ratio=friction / normal if normal > 0 else float("nan"),
        lost_stick=lost["stick"] / normal if normal > 0 else 0.0, lost_slip=lost["slip"] / normal if normal > 0 else 0.0,
        speeds={k: np.asarray(v) for k, v in speeds.items()}, energy=energy,
        demand=math.tan(math.radians(theta)) / mu if mu > 0 else float("inf"))


def report(r: dict, label: str) -> None:
    print(label + f": {r['steps']} steps, {r['t_end']:.3f} s")
    if r["analytic_m"] > 0:
        print(f"  slip {r['slip_m']:.5g} m, analytic {r['analytic_m']:.5g} m: {r['slip_m'] / r['analytic_m'] - 1:+.2%}")
    else:
        print(f"  slip {r['slip_m']:.5g} m = {r['slip_m'] / r['frictionless_m']:.3%} of the frictionless {r['frictionless_m']:.4g} m")
    print(f"  friction / (mu N): whole contact {r['contact_ratio']:.5f}, wall line {r['wall_ratio']:.5f} "
          f"(tan th / mu = {r['demand']:.5f}); not given of mu N: in stick steps {r['lost_stick']:.4%}, "
          f"in slip steps {r['lost_slip']:.4%}")
    s = r["speeds"]
    if len(s["stick_vn"]) and len(s["slip_vn"]):
        print(f"  stick steps: |vn| median {np.median(s['stick_vn']):.3g} m/s (p90 {np.percentile(s['stick_vn'], 90):.3g}), "
              f"|vt| median {np.median(s['stick_vt']):.3g}; slip steps: |vn| median {np.median(s['slip_vn']):.3g} "
              f"(p90 {np.percentile(s['slip_vn'], 90):.3g})")
    if len(s["stick_m"]) and len(s["slip_m"]):
        lost = np.asarray(s["stick_lost"])
        order = np.argsort(-lost)
        heavy = order[: max(1, int(0.1 * len(order)))]
        print(f"  wall-node mass / its value at the release (median): stick steps {np.median(s['stick_m']):.3g}, "
              f"slip steps {np.median(s['slip_m']):.3g}; the 10 % of stick steps that lose most friction "
              f"({lost[heavy].sum() / max(lost.sum(), 1e-300):.0%} of the loss): mass {np.median(np.asarray(s['stick_m'])[heavy]):.3g}")
    f = r["fractions"]
    print(f"  wall nodes under the block: {len(f)}; fraction of steps stick / slip down / slip up / separate:")
    print("    all nodes   " + " ".join(f"{v:.3f}" for v in f.mean(0)))
    n = len(f)
    for q, name in ((0, "upslope end"), (n // 4, "quarter"), (n // 2, "middle"), (3 * n // 4, "3 quarters"),
                    (n - 1, "downslope end")):
        print(f"    {name:12s}" + " ".join(f"{v:.3f}" for v in f[q]))
    print("  t s, kinetic energy J/m: elastic (not translation), translation; slip m")
    for t, el, tr, sl in r["energy"]:
        print(f"    {t:8.3f} {el:10.4g} {tr:10.4g} {sl:10.4g}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scheme")
    ap.add_argument("precision")
    ap.add_argument("thickness", type=int)
    ap.add_argument("youngs", type=float)
    ap.add_argument("incline", type=float)
    ap.add_argument("friction", type=float)
    ap.add_argument("--aspect", type=float, default=4.0)
    ap.add_argument("--time", type=float, default=1.0, help="run time as a multiple of the matrix's")
    ap.add_argument("--damping", type=float, default=0.0, help="Cundall's local damping after the release")
    ap.add_argument("--cfl", type=float, default=None, help="time step as a fraction of dx / c_p (the scenes': 0.5)")
    ap.add_argument("--ppc", type=int, default=None, help="particles per cell along each axis (the scenes': 2)")
    ap.add_argument("--transfer", action="store_true",
                    help="experiment: a stuck wall node's unused friction to the node inside it (not the engine's law)")
    a = ap.parse_args(argv)
    from studies import contact_scenes as cs

    if a.cfl is not None:
        cs.CFL = a.cfl
    if a.ppc is not None:
        cs.PPC = a.ppc
    r = diagnose(a.scheme, a.precision, a.thickness, a.youngs, a.incline, a.friction, a.aspect, a.time, a.damping,
                 transfer=a.transfer)
    report(r, f"{a.scheme} {a.precision} {a.thickness} cells E={a.youngs:g} aspect {a.aspect:g} "
              f"{a.incline:g}/{a.friction:g} deg, damping {a.damping:g}, cfl {a.cfl or 0.5:g}, ppc {a.ppc or 2}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
