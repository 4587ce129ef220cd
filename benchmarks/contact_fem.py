"""The idealised incline problem run in time by finite elements: no MPM (docs/validation.md, contact).

An elastic block (bilinear plane-strain elements, lumped masses, small strain, square elements of
side ``h``) rests on a rigid frictional incline made by tilting gravity, as the project path's
bottom-wall cases do. Its base nodes meet the incline by the engine's node law (unilateral, the
normal impulse of the step, Coulomb friction at most ``mu`` times it, stick, never reversed), with
the gap tracked, since the nodes move with the material. Stages as a project's: a ``gravity``
stage (gravity ramped from zero over ``--gravity`` seconds with Cundall's local damping 0.7, then
every velocity set to zero), then an undamped dynamic stage as long as the contact matrix's
(:func:`studies.contact_scenes.run_time`). Printed: the mean slip of the base nodes over the
dynamic stage against ``1/2 g (sin th - tan d cos th) t^2`` (sliding) or as a fraction of the
frictionless distance (sticking).

It answers whether a failure of the MPM is the idealised problem's or the MPM's own: a 20-cell
block (1 m x 4 m) at 40 deg on 45 deg friction holds here (E = 1e8 Pa after a 0.2 s stage:
0.000 %; E = 1e6 Pa after 2 s: 0.027 %), where the MPM, deciding friction node by node at the wall
row and the ghost row beyond it, let it slide (docs/validation.md). Sliding just above the limit
the finite elements do worse than the MPM (20/10 +2.6 %, 40/30 +33 %): the kinematic node contact of
explicit elements chatters (Carpenter, Taylor and Katona 1991, Int. J. Numer. Meth. Eng. 32:103).

Usage::

    PYTHONPATH=$PWD python -m benchmarks.contact_fem 1e8 40 45 [--gravity 0.2] [--cells 20] [--aspect 4] [--cell 0.05]
"""

from __future__ import annotations

import argparse
import math
import sys

import numpy as np


def run(youngs: float, theta_deg: float, delta_deg: float, *, cells: int = 20, aspect: float = 4.0,
        h: float = 0.05, gravity_s: float = 0.2, duration_s: float | None = None, poisson: float = 0.3,
        density: float = 2000.0, cfl: float = 0.4, damping: float = 0.7) -> dict:
    """Run the block; returns the base's mean slip over the dynamic stage and the reference distances (m)."""
    import scipy.sparse as sparse

    from benchmarks.contact_stability import _q1_stiffness
    from studies.contact_scenes import G, analytic_distance, run_time

    nx, ny = int(round(aspect * cells)), int(cells)
    n_nodes = (nx + 1) * (ny + 1)
    ke = _q1_stiffness(h, youngs, poisson)
    rows, cols, vals = [], [], []
    mass = np.zeros(2 * n_nodes)
    for j in range(ny):
        for i in range(nx):
            nodes = [j * (nx + 1) + i, j * (nx + 1) + i + 1, (j + 1) * (nx + 1) + i + 1, (j + 1) * (nx + 1) + i]
            dofs = np.array([[2 * n, 2 * n + 1] for n in nodes]).ravel()
            rows.append(np.repeat(dofs, 8))
            cols.append(np.tile(dofs, 8))
            vals.append(ke.ravel())
            mass[dofs] += density * h * h / 4
    K = sparse.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                          shape=(2 * n_nodes, 2 * n_nodes))
    c_p = math.sqrt(youngs * (1 - poisson) / ((1 + poisson) * (1 - 2 * poisson)) / density)
    dt = cfl * h / c_p
    th = math.radians(theta_deg)
    mu = math.tan(math.radians(delta_deg))
    gravity = np.zeros(2 * n_nodes)
    gravity[0::2], gravity[1::2] = G * math.sin(th), -G * math.cos(th)
    bx, by = 2 * np.arange(nx + 1), 2 * np.arange(nx + 1) + 1  # the base nodes' degrees of freedom
    u = np.zeros(2 * n_nodes)
    v = np.zeros(2 * n_nodes)

    def step(load: float, damped: bool) -> None:
        nonlocal u, v
        f = mass * gravity * load - K @ u
        if damped:
            f -= damping * np.abs(f) * np.sign(v)
        trial = v + dt * f / mass
        gap, vn, vt = u[by], trial[by], trial[bx]
        hit = gap + dt * vn < 0.0  # the node would reach the incline in this step
        new_vn = np.where(hit, -gap / dt, vn)
        allowed = mu * np.where(hit, new_vn - vn, 0.0)  # friction: mu times the normal impulse
        speed = np.abs(vt)
        new_vt = np.where(speed <= allowed, 0.0, vt * (speed - allowed) / np.maximum(speed, 1e-300))
        trial[by], trial[bx] = new_vn, np.where(hit, new_vt, vt)
        v = trial
        u = u + dt * v

    n_settle = max(1, int(math.ceil(gravity_s / dt)))
    for k in range(n_settle):
        step(min(1.0, (k + 1) / n_settle), True)
    v[:] = 0.0
    start = u[bx].copy()
    duration = run_time(theta_deg, delta_deg, h) if duration_s is None else duration_s
    n_run = int(math.ceil(duration / dt))
    for _ in range(n_run):
        step(1.0, False)
    t = n_run * dt
    slip = float((u[bx] - start).mean())
    analytic = analytic_distance(theta_deg, delta_deg, t)
    frictionless = analytic_distance(theta_deg, 0.0, t)
    return dict(slip_m=slip, analytic_m=analytic, frictionless_m=frictionless, duration_s=t, steps=n_settle + n_run,
                error=slip / analytic - 1.0 if analytic > 0 else slip / frictionless)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("youngs", type=float)
    ap.add_argument("incline", type=float)
    ap.add_argument("friction", type=float)
    ap.add_argument("--gravity", type=float, default=0.2, help="gravity stage (s)")
    ap.add_argument("--cells", type=int, default=20, help="block thickness (elements)")
    ap.add_argument("--aspect", type=float, default=4.0, help="length / thickness")
    ap.add_argument("--cell", type=float, default=0.05, help="element size (m)")
    a = ap.parse_args(argv)
    r = run(a.youngs, a.incline, a.friction, cells=a.cells, aspect=a.aspect, h=a.cell, gravity_s=a.gravity)
    kind = "error" if r["analytic_m"] > 0 else "slip / frictionless"
    print(f"E = {a.youngs:g} Pa, {a.incline:g}/{a.friction:g} deg, {a.cells} x {a.aspect * a.cells:g} elements of "
          f"{a.cell:g} m, gravity stage {a.gravity:g} s: slip {1e3 * r['slip_m']:.3f} mm over {r['duration_s']:.3f} s "
          f"({r['steps']} steps); {kind} {100 * r['error']:+.3f} %")
    return 0


if __name__ == "__main__":
    sys.exit(main())
