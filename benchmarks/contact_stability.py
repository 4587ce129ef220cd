"""Linear stability of the discrete step while a block slides on a frictional wall (issue 11;
docs/validation.md, contact: "Is the chatter a linear instability of the step?").

One block of :class:`studies.contact_scenes.WallIncline` on the bottom wall, settled and released as
in the matrix. Then two copies of its state are stepped together, the second perturbed by a tiny
random velocity field, and the difference is renormalised every ``--chunk`` steps (Benettin's
method: a power iteration of the step's tangent map along the trajectory). Printed: the growth per
step of the dominant perturbation (``rho``; ``ln rho / dt`` per second), averaged over the run and
over its quarters, and the perturbation's shape at the end (the share of its energy in the particle
rows next to the wall, normal against tangential velocity, its main wavelength along the wall).

The norm is an energy: ``1/2 m |dv|^2 + 1/2 m dx^2/4 |dC|^2`` (APIC's affine part) ``+ 1/2 V
|ds|^2 / E`` (about the elastic energy of a stress difference) ``+ 1/2 m (c_p / dx)^2 |dx_p|^2``.

``--law``:

- ``engine``: the engine's contact law (one-sided, stick/slip/separation switching).
- ``linear``: the law linearised about a steady slide in which every wall node presses and slips
  down the slope: at every contact node (wall line and ghost rows) the normal velocity is removed
  whatever its sign, and the tangential velocity changes by ``mu vn`` along the slope (``vt +
  mu vn s``, ``s`` the slope's direction; bilateral, no stick, sign fixed); the mirror walls'
  ghost velocity always takes the mirror image, with friction ``mu dvn`` of its normal change
  likewise. The step is then an affine map of the particle state (apart from the particles'
  motion through the grid), so the growth measured is that of its amplification matrix.

- ``unilateral``: separation as the engine's, but no stick: friction ``mu |vn|`` against the
  slope's direction while pressing (it may reverse a node's velocity along the wall).
- ``bilateral``: the normal velocity always removed; friction as the engine's (stick, never
  reversed) from the pressing part only.

- ``patch`` (experiment, six-stage schemes): the stick decided for the wall line as a whole: if the
  approaching wall-line nodes' mean trial velocity along the wall exceeds their mean ``mu |vn|``,
  every approaching contact node slips (friction ``mu |vn|`` against that mean, which may reverse
  it), else the engine's law at each node. With ``--radius R``: the means over the wall-line nodes
  within ``R`` cells of the node's column (bottom wall).

``--beta B`` (experiment, six-stage schemes; with ``--law engine`` the engine's law re-coded in the
subclass): after each application of the law, the wall line's pressing nodes (normal velocity
held at zero) relax their velocity along the wall by the fraction ``B`` towards their
mass-weighted mean (a dashpot against the contact's mean slip; momentum unchanged). It acts on the
whole wall line at once, so it would couple separate bodies on one wall: a probe of where the
instability lives, not a law for the engine.

``--radius R`` (with ``--beta``): the mean over the pressing nodes within ``R`` cells instead.
``--eta`` (experiment, mpm and apic): a Kelvin-Voigt viscosity of the block, stress ``2 eta D`` (Pa)
added to the force (explicit: unstable above about ``rho dx^2 / (4 dt)``).

``--fem``: the idealised problem as finite elements (:func:`fem_growth`; numpy only, no MPM), the
block ``thickness`` x ``--aspect`` cells of ``--dx``, for comparison with the MPM growth.

Also (``--slide``): the base trajectory alone, with its elastic (non-translational) kinetic energy
and slip error over time (sticking cases: slip over the frictionless distance), for any law.

Usage::

    PYTHONPATH=$PWD python -m benchmarks.contact_stability apic 5 38 36 [--law linear] [--cfl 0.5]
        [--dx 2] [--youngs 1e8] [--aspect 8] [--time 0.3 | --seconds 1.3] [--chunk 10] [--slide]
        [--samples 8] [--beta 0.2 [--radius 10]] [--eta 4e5] [--seed 1]
"""

import argparse
import math
import sys

import numpy as np

FIELDS = ("x", "v", "C", "s")


def _linear_engine_class():
    """An Engine whose contact law is the one linearised about a steady downslope slide (bottom
    wall: slope +x, normal +y). A subclass, so that the engine's code is untouched."""
    from solver.engine import FIXED, PAD, Engine
    from solver.runtime import mat_vec, ti, transpose

    @ti.data_oriented
    class LinearLawEngine(Engine):
        #: "linear": bilateral, always slipping down the slope (friction mu vn, any sign of vn);
        #: "unilateral": separation as the engine's, but no stick (friction mu |vn| down the slope,
        #: may reverse the tangential velocity); "bilateral": the normal velocity always removed,
        #: Coulomb friction as the engine's (stick, never reversed) from the pressing part only
        variant = "linear"
        #: experiment: each step the contact nodes' velocity along the wall relaxes by this fraction
        #: towards the mass-weighted mean of the wall line's (a dashpot against the contact's mean slip)
        beta = 0.0
        radius = 0  #: cells each way over which the mean is taken (0: the whole wall line)
        #: the laws here act node by node (measured before the engine's wall-column law, session 11)
        COLUMN_FRICTION = False

        #: experiment: a Kelvin-Voigt viscosity of the block, stress 2 eta D added to the force (Pa s)
        eta = 0.0

        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            self.sv = ti.Vector.field(3, float, shape=max(1, self.n))
            self.acc = ti.Vector.field(2, ti.f64, shape=())
            self.tmp = ti.field(float, shape=self.nodes[0])
            self.wall = ti.Vector.field(3, ti.f64, shape=())
            self.node_sums = ti.Vector.field(3, ti.f64, shape=self.nodes[0])
            self.local_sums = ti.Vector.field(3, ti.f64, shape=self.nodes[0])

        @ti.func
        def _slip_of_the_wall(self, dt, old: ti.template()):
            """``patch`` variant: the wall line's approaching nodes' mass-weighted mean trial velocity
            along the wall and mean friction allowance ``mu |vn|`` (into ``self.wall``)."""
            lo = self.lo[None]
            width = ti.max(self.hi[None] - lo, 0)
            self.wall[None] = ti.Vector.zero(ti.f64, 3)
            for k in range(width[0]):
                I = ti.Vector([lo[0] + k, PAD])
                mass = self.g_mass[I]
                self.node_sums[I[0]] = ti.Vector.zero(ti.f64, 3)
                if mass > 0.0:
                    v = self.g_mom[I] / mass
                    if ti.static(not old):
                        v = self.g_v_old[I] + dt * self.g_f[I] / mass
                    if v[1] < 0.0:
                        here = ti.Vector([mass * v[0], mass * self.bc_mu[2] * (-v[1]), mass], ti.f64)
                        self.wall[None] += here
                        self.node_sums[I[0]] = here
            if ti.static(self.radius > 0):  # the local version: sums over the nodes within radius cells
                for k in range(width[0]):
                    i = lo[0] + k
                    acc = ti.Vector.zero(ti.f64, 3)
                    for d in range(-ti.static(self.radius), ti.static(self.radius) + 1):
                        if lo[0] <= i + d < lo[0] + width[0]:
                            acc += self.node_sums[i + d]
                    self.local_sums[i] = acc

        @ti.func
        def _grid_velocity(self):
            if ti.static(self.variant == "patch"):
                self._slip_of_the_wall(0.0, True)
            Engine._grid_velocity(self)
            if ti.static(self.beta > 0.0):
                self._relax(self.g_v_old)

        @ti.func
        def _grid_update(self, dt, damping):
            if ti.static(self.variant == "patch"):
                self._slip_of_the_wall(dt, False)
            Engine._grid_update(self, dt, damping)
            if ti.static(self.beta > 0.0):
                self._relax(self.g_mom)

        @ti.func
        def _relax(self, vel: ti.template()):
            """The wall line's pressing nodes (normal velocity held at zero by the law): velocity along
            the wall relaxed by ``beta`` towards their mass-weighted mean (momentum unchanged), or with
            ``radius`` > 0 towards the mean over the pressing nodes within ``radius`` cells (binomial-like
            triangle weights; momentum then only nearly unchanged)."""
            lo = self.lo[None]
            width = ti.max(self.hi[None] - lo, 0)
            if ti.static(self.radius == 0):
                self.acc[None] = ti.Vector.zero(ti.f64, 2)
                for k in range(width[0]):
                    I = ti.Vector([lo[0] + k, PAD])
                    mass = self.g_mass[I]
                    if mass > 0.0 and vel[I][1] == 0.0:
                        self.acc[None] += ti.Vector([mass * vel[I][0], mass], ti.f64)
                for k in range(width[0]):
                    I = ti.Vector([lo[0] + k, PAD])
                    mass = self.g_mass[I]
                    if mass > 0.0 and vel[I][1] == 0.0:
                        vbar = ti.cast(self.acc[None][0] / self.acc[None][1], float)
                        vel[I][0] -= ti.static(self.beta) * (vel[I][0] - vbar)
            else:
                for k in range(width[0]):
                    i = lo[0] + k
                    I = ti.Vector([i, PAD])
                    self.tmp[i] = vel[I][0]
                    if self.g_mass[I] > 0.0 and vel[I][1] == 0.0:
                        num = 0.0
                        den = 0.0
                        for d in range(-ti.static(self.radius), ti.static(self.radius) + 1):
                            J = ti.Vector([i + d, PAD])
                            if lo[0] <= J[0] < lo[0] + width[0]:
                                mj = self.g_mass[J]
                                if mj > 0.0 and vel[J][1] == 0.0:
                                    w = (ti.static(self.radius) + 1.0 - ti.abs(d)) * mj
                                    num += w * vel[J][0]
                                    den += w
                        self.tmp[i] = vel[I][0] - ti.static(self.beta) * (vel[I][0] - num / den)
                for k in range(width[0]):
                    i = lo[0] + k
                    I = ti.Vector([i, PAD])
                    if self.g_mass[I] > 0.0 and vel[I][1] == 0.0:
                        vel[I][0] = self.tmp[i]

        @ti.func
        def _contact(self, I, v, mass, record: ti.template(), trial: ti.template(), dt, damping):
            out = v
            if ti.static(self.variant == "patch" and self.radius > 0):
                # the local patch (bottom wall only): the sums over the wall-line nodes within radius
                # cells of this node's column decide slip or stick
                if I[1] <= PAD and self._closed(self.bc_kind[2]):
                    n = ti.Vector([0.0, 1.0])
                    s = ti.Vector([1.0, 0.0])
                    mu = self.bc_mu[2]
                    vn = v.dot(n)
                    new = v
                    if self.bc_kind[2] == FIXED:
                        new = ti.Vector.zero(float, 2)
                    elif vn < 0.0:
                        vt = v - vn * n
                        acc = self.local_sums[I[0]]
                        mean_v = ti.cast(acc[0] / ti.max(acc[2], 1e-300), float)
                        mean_a = ti.cast(acc[1] / ti.max(acc[2], 1e-300), float)
                        if ti.abs(mean_v) > mean_a:
                            new = vt + mu * vn * ti.math.sign(mean_v) * s
                        else:
                            speed = vt.norm()
                            new = ti.Vector.zero(float, 2)
                            if speed > 0.0:
                                new = vt * (ti.max(speed - mu * (-vn), 0.0) / speed)
                    if ti.static(record):
                        self._record(2, mass * (new - v))
                    out = new
            else:
                out = Engine._contact(self, I, v, mass, record, trial, dt, damping)
            return out

        @ti.func
        def _stress_point(self, p, L, dt):
            D = 0.5 * (L + transpose(L))
            if ti.static(self.eta > 0.0):
                self.sv[p] = 2.0 * ti.static(self.eta) * ti.Vector([D[0, 0], D[1, 1], D[0, 1]])
            return Engine._stress_point(self, p, L, dt)

        @ti.func
        def _force_particle(self, p, vol, g):
            base, fx, w, dw = self._stencil(self.x[p])
            s = self.s[p]
            sig = ti.Matrix([[s[0], s[2]], [s[2], s[1]]])
            if ti.static(self.eta > 0.0):
                sv = self.sv[p]
                sig += ti.Matrix([[sv[0], sv[2]], [sv[2], sv[1]]])
            m = self.m[p]
            for i, j in ti.static(ti.ndrange(3, 3)):
                weight = w[i][0] * w[j][1]
                grad = ti.Vector([dw[i][0] * w[j][1], w[i][0] * dw[j][1]]) * self.inv_dx
                self.to_grid.add(self.g_f, base + ti.Vector([i, j]), -vol * mat_vec(sig, grad) + weight * m * g)

        @ti.func
        def _contact_law(self, v, n, kind, mu, target):
            # the engine's law itself; the variants replace its result where they differ (walls only:
            # target zero)
            out = Engine._contact_law(self, v, n, kind, mu, target)
            if ti.static(self.variant != "engine"):
                if kind != FIXED:
                    vn = v.dot(n)
                    vt = v - vn * n
                    s = ti.Vector([n[1], -n[0]])  # the slope's direction (+x on the bottom wall)
                    if ti.static(self.variant == "patch"):
                        if vn < 0.0:
                            acc = self.wall[None]
                            mean_v = ti.cast(acc[0] / ti.max(acc[2], 1e-300), float)
                            mean_a = ti.cast(acc[1] / ti.max(acc[2], 1e-300), float)
                            if ti.abs(mean_v) > mean_a:  # the wall line slips as a whole: every node slips
                                out = vt + mu * vn * ti.math.sign(mean_v) * s
                            # else it sticks as a whole: the engine's law at each node
                    elif ti.static(self.variant == "linear"):
                        out = vt + mu * vn * s  # vn < 0 pressing: friction mu |vn| against the slide
                    elif ti.static(self.variant == "unilateral"):
                        if vn < 0.0:
                            out = vt + mu * vn * s
                    else:  # bilateral
                        speed = vt.norm()
                        out = ti.Vector.zero(float, 2)
                        if speed > 0.0:
                            out = vt * (ti.max(speed - mu * ti.max(-vn, 0.0), 0.0) / speed)
            return out

        @ti.func
        def _ghost_image(self, kind, axis: ti.template(), inward, vm, vg, mu):
            new = Engine._ghost_image(self, kind, axis, inward, vm, vg, mu)  # engine and patch
            if ti.static(self.variant == "linear" or self.variant == "unilateral" or self.variant == "bilateral"):
                if kind != FIXED:
                    new = vg
                    if ti.static(self.variant == "linear"):
                        new[axis] = -vm[axis]
                        dvn = (new[axis] - vg[axis]) * inward
                        # slope direction along the wall: +x for the bottom wall (the only one used)
                        new[1 - axis] = vg[1 - axis] - mu * dvn
                    elif ti.static(self.variant == "unilateral"):
                        if vm[axis] * inward < 0.0:
                            new[axis] = -vm[axis]
                            dvn = (new[axis] - vg[axis]) * inward
                            if dvn > 0.0:
                                new[1 - axis] = vg[1 - axis] - mu * dvn
                    else:  # bilateral: the image always, the engine's friction on a pressing change
                        new[axis] = -vm[axis]
                        dvn = (new[axis] - vg[axis]) * inward
                        if dvn > 0.0:
                            vt = new[1 - axis]
                            new[1 - axis] = ti.math.sign(vt) * ti.max(ti.abs(vt) - mu * dvn, 0.0)
            return new

    return LinearLawEngine


def _norm2(d: dict, m, vol, dx, youngs, cp) -> float:
    e = 0.5 * (m * (d["v"] ** 2).sum(1)).sum()
    e += 0.5 * (m * dx * dx / 4.0 * (d["C"] ** 2).sum((1, 2))).sum()
    e += 0.5 * (vol * (d["s"] ** 2).sum(1)).sum() / youngs
    e += 0.5 * (m * (cp / dx) ** 2 * (d["x"] ** 2).sum(1)).sum()
    return float(e)


def _shape(d: dict, m, x, dx, normal_axis=1):
    """Where the perturbation lives: energy share by distance from the wall (rows of cells),
    kinetic share normal / tangential, dominant wavelength along the wall (cells) of the normal
    velocity of the lowest particle row."""
    ke_n = 0.5 * (m * d["v"][:, normal_axis] ** 2).sum()
    ke_t = 0.5 * (m * d["v"][:, 1 - normal_axis] ** 2).sum()
    depth = x[:, normal_axis] / dx
    rows = {}
    ke = 0.5 * m * (d["v"] ** 2).sum(1)
    for lo, hi in ((0, 1), (1, 2), (2, 4), (4, 1e9)):
        share = ke[(depth >= lo) & (depth < hi)].sum() / max(ke.sum(), 1e-300)
        rows[f"{lo}-{hi if hi < 1e8 else 'top'}"] = float(share)
    low = depth < 0.5
    order = np.argsort(x[low, 1 - normal_axis])
    sig = d["v"][low, normal_axis][order]
    spec = np.abs(np.fft.rfft(sig - sig.mean())) ** 2
    k = int(np.argmax(spec[1:]) + 1) if len(spec) > 1 else 0
    along = (x[low, 1 - normal_axis].max() - x[low, 1 - normal_axis].min()) / dx
    wavelength = along * len(sig) / (len(sig) - 1) / k if k else float("inf")
    return dict(ke_normal=float(ke_n / max(ke_n + ke_t, 1e-300)), rows=rows, wavelength_cells=float(wavelength))


def analyse(scheme: str, thickness: int, theta: float, delta: float, law: str = "engine", youngs: float = 1e8,
            aspect: float = 8.0, time_factor: float = 0.3, chunk: int = 10, eps: float = 1e-6, seed: int = 1,
            slide: bool = False, samples: int = 8, precision: str = "f64", seconds: float = 0.0,
            beta: float = 0.0, radius: int = 0, eta: float = 0.0) -> dict:
    """One case on the bottom wall. Returns the growth per step over the run and its quarters (or,
    with ``slide``, the base trajectory's elastic kinetic energy and slip over time)."""
    from solver import runtime
    from studies import contact_scenes as cs

    runtime.acquire("cpu", precision)
    try:
        sc = cs.WallIncline(scheme, precision, thickness, youngs, "bottom", aspect=aspect)
        if law in ("linear", "unilateral", "bilateral", "patch") or beta > 0.0 or eta > 0.0:
            cls = _linear_engine_class()
            cls.variant = law
            cls.beta = beta
            cls.radius = radius
            cls.eta = eta
            sc.engine = cls(sc.grid, (sc.material,), len(sc.positions), scheme, sc.np_float, damping=True,
                            scatter="serial")
        elif law != "engine":
            raise ValueError(f"law must be engine, linear, unilateral, bilateral or patch, got {law!r}")
        e = sc.engine

        h = sc.dx / cs.PPC
        g = sc.gravity(theta)
        dt = sc.release(theta, delta)
        t_end = seconds if seconds > 0.0 else cs.run_time(theta, delta, sc.dx) * time_factor
        steps = int(math.ceil(t_end / dt))
        dt = t_end / steps
        n = e.n
        m = e.m.to_numpy()[:n].astype(np.float64)
        vol = np.full(n, h * h)
        cp = sc.material.p_wave_speed_m_s
        x0 = e.x.to_numpy()[:n].astype(np.float64)
        if slide:
            out = []
            every = max(1, steps // samples)
            for k in range(steps):
                e.step(dt, g)
                if (k + 1) % every == 0 or k == steps - 1:
                    v = e.v.to_numpy()[:n].astype(np.float64)
                    vbar = (m[:, None] * v).sum(0) / m.sum()
                    x = e.x.to_numpy()[:n].astype(np.float64)
                    t = (k + 1) * dt
                    slip = float(((x - x0)[sc.base_row] @ sc.slope).mean())
                    an = cs.analytic_distance(theta, delta, t)
                    # sliding: slip / analytic - 1; sticking: slip / frictionless distance
                    err = slip / an - 1.0 if an > 0 else slip / cs.analytic_distance(theta, 0.0, t)
                    out.append((t, 0.5 * float((m * ((v - vbar) ** 2).sum(1)).sum()), err))
            return dict(dt=dt, steps=steps, slide=out)
        rng = np.random.default_rng(seed)
        base = e.state()
        d = {k: np.zeros_like(base[k][:n], dtype=np.float64) for k in FIELDS}
        d["v"] = rng.standard_normal((n, 2))
        scale = math.sqrt(_norm2(d, m, vol, sc.dx, youngs, cp))
        d = {k: v / scale for k, v in d.items()}  # unit energy
        amp = eps * math.sqrt(0.5 * m.sum())  # perturbation energy of a velocity field of rms ``eps`` m/s
        logs = []
        done = 0
        while done < steps:
            K = min(chunk, steps - done)
            pert = {k: np.array(v, copy=True) for k, v in base.items()}
            for k in FIELDS:
                pert[k] = pert[k].copy()
                moved = pert[k][:n].astype(np.float64) + amp * d[k].reshape(pert[k][:n].shape)
                pert[k][:n] = moved.astype(pert[k].dtype)
            e.load_state(base)
            for _ in range(K):
                e.step(dt, g)
            base = e.state()
            e.load_state(pert)
            for _ in range(K):
                e.step(dt, g)
            after = e.state()
            diff = {k: (after[k][:n].astype(np.float64) - base[k][:n].astype(np.float64)) / amp for k in FIELDS}
            r = math.sqrt(_norm2(diff, m, vol, sc.dx, youngs, cp))
            logs.append((K, math.log(max(r, 1e-300))))
            d = {k: v / r for k, v in diff.items()}
            done += K
        xb = base["x"][:n].astype(np.float64)
        shape = _shape(d, m, xb - np.array([0.0, 0.0]), sc.dx)
    finally:
        runtime.release()
    K = np.array([k for k, _ in logs], float)
    L = np.array([lg for _, lg in logs])
    quarters = []
    for q in range(4):
        sel = slice(q * len(L) // 4, (q + 1) * len(L) // 4)
        quarters.append(float(L[sel].sum() / max(K[sel].sum(), 1)))
    lam = float(L.sum() / K.sum())
    return dict(dt=dt, steps=steps, t_end=t_end, per_step=lam, rho=math.exp(lam), per_s=lam / dt,
                quarters=quarters, shape=shape, factor=math.exp(L.sum()))


def _q1_stiffness(h: float, youngs: float, poisson: float) -> np.ndarray:
    """Plane-strain stiffness of a square bilinear element of side ``h`` (2 x 2 Gauss points)."""
    lam = youngs * poisson / ((1 + poisson) * (1 - 2 * poisson))
    shear = youngs / (2 * (1 + poisson))
    D = np.array([[lam + 2 * shear, lam, 0], [lam, lam + 2 * shear, 0], [0, 0, shear]])
    corners = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]])
    K = np.zeros((8, 8))
    g = 1 / math.sqrt(3)
    for a in (-g, g):
        for b in (-g, g):
            dN = np.array([[c[0] * (1 + b * c[1]) / 4, c[1] * (1 + a * c[0]) / 4] for c in corners]) * 2 / h
            B = np.zeros((3, 8))
            for i in range(4):
                B[0, 2 * i], B[1, 2 * i + 1] = dN[i, 0], dN[i, 1]
                B[2, 2 * i], B[2, 2 * i + 1] = dN[i, 1], dN[i, 0]
            K += B.T @ D @ B * (h / 2) ** 2
    return K


def fem_growth(thickness_m: float, length_m: float, h: float, mu: float, youngs: float = 1e8,
               poisson: float = 0.3, density: float = 2000.0, slow_rad_s: float = 100.0) -> dict:
    """An independent check of the idealised problem (not MPM): the elastic block as bilinear finite
    elements (plane strain, lumped mass, square elements of side ``h``), its base held along the
    normal (bilateral) with the Coulomb coupling of a steady downslope slide, friction ``mu`` times
    the normal reaction against the slope (the base's tangential rows get ``mu`` times their normal
    rows). Eigenvalues ``lambda`` of ``M^-1 K'``; a mode grows at ``|Im sqrt(lambda)|`` per second.
    Returned: the fastest growth overall and among the modes slower than ``slow_rad_s`` (the body's
    modes), with their angular frequencies. Dense: a few thousand degrees of freedom at most."""
    nx, ny = int(round(length_m / h)), int(round(thickness_m / h))
    n_nodes = (nx + 1) * (ny + 1)
    K = np.zeros((2 * n_nodes, 2 * n_nodes))
    M = np.zeros(2 * n_nodes)
    ke = _q1_stiffness(h, youngs, poisson)
    for j in range(ny):
        for i in range(nx):
            nodes = [j * (nx + 1) + i, j * (nx + 1) + i + 1, (j + 1) * (nx + 1) + i + 1, (j + 1) * (nx + 1) + i]
            dofs = np.array([[2 * n, 2 * n + 1] for n in nodes]).ravel()
            K[np.ix_(dofs, dofs)] += ke
            M[dofs] += density * h * h / 4
    coupled = K.copy()
    for n in range(nx + 1):  # the base's nodes: tangential row + mu x the normal reaction's row
        coupled[2 * n, :] += mu * K[2 * n + 1, :]
    keep = np.ones(2 * n_nodes, bool)
    keep[[2 * n + 1 for n in range(nx + 1)]] = False  # normal displacement held at the base
    lam = np.linalg.eigvals(coupled[np.ix_(keep, keep)] / M[keep][:, None])
    root = np.sqrt(lam.astype(complex))
    grow, omega = np.abs(root.imag), np.abs(root.real)
    fast = int(np.argmax(grow))
    slow = int(np.argmax(np.where(omega < slow_rad_s, grow, -1.0)))
    return dict(growth=float(grow[fast]), omega=float(omega[fast]), body_growth=float(grow[slow]),
                body_omega=float(omega[slow]), omega_max=float(omega.max()))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scheme")
    ap.add_argument("thickness", type=int)
    ap.add_argument("incline", type=float)
    ap.add_argument("friction", type=float)
    ap.add_argument("--law", default="engine", choices=("engine", "linear", "unilateral", "bilateral", "patch"))
    ap.add_argument("--youngs", type=float, default=1e8)
    ap.add_argument("--aspect", type=float, default=8.0)
    ap.add_argument("--time", type=float, default=0.3, help="run time as a multiple of the matrix's")
    ap.add_argument("--seconds", type=float, default=0.0, help="run time (s; overrides --time)")
    ap.add_argument("--cfl", type=float, default=None, help="the scenes' 0.5")
    ap.add_argument("--dx", type=float, default=None, help="cell size (m; the scenes': 2 for E >= 1e7 Pa)")
    ap.add_argument("--chunk", type=int, default=10, help="steps between renormalisations")
    ap.add_argument("--eps", type=float, default=1e-6, help="perturbation: rms velocity (m/s)")
    ap.add_argument("--samples", type=int, default=8, help="--slide: samples over the run")
    ap.add_argument("--beta", type=float, default=0.0,
                    help="experiment: contact nodes' velocity along the wall relaxed by this fraction a step "
                         "towards the wall line's mean (with --law engine: the engine's law in the subclass)")
    ap.add_argument("--radius", type=int, default=0,
                    help="experiment: --beta's mean over the pressing nodes within this many cells (0: all)")
    ap.add_argument("--eta", type=float, default=0.0,
                    help="experiment: Kelvin-Voigt viscosity of the block (Pa s; mpm, apic): stress 2 eta D added")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--slide", action="store_true", help="the base trajectory only: elastic energy and slip error")
    ap.add_argument("--fem", action="store_true",
                    help="the idealised problem as finite elements instead (numpy; scheme ignored): the block "
                         "thickness x --aspect cells of --dx, bilateral base with the Coulomb coupling")
    a = ap.parse_args(argv)
    from studies import contact_scenes as cs

    if a.fem:
        h = a.dx or cs.cell_size_for(a.youngs)
        length = cs.block_length_cells(a.thickness, a.aspect) * h
        r = fem_growth(a.thickness * h, length, h, math.tan(math.radians(a.friction)), a.youngs)
        print(f"finite elements, block {a.thickness * h:g} m x {length:g} m, elements {h:g} m, mu "
              f"{math.tan(math.radians(a.friction)):.3f}: fastest growth {r['growth']:.2f} /s at "
              f"{r['omega']:.0f} rad/s (omega max {r['omega_max']:.0f}); body modes (below 100 rad/s) "
              f"{r['body_growth']:.2f} /s at {r['body_omega']:.1f} rad/s")
        return 0

    if a.dx is not None:
        cs.cell_size_for = lambda youngs_pa: a.dx
    if a.cfl is not None:
        cs.CFL = a.cfl
    r = analyse(a.scheme, a.thickness, a.incline, a.friction, a.law, a.youngs, a.aspect, a.time, a.chunk, a.eps,
                a.seed, a.slide, a.samples, seconds=a.seconds,
                beta=a.beta, radius=a.radius, eta=a.eta)
    probes = (f" beta {a.beta:g} radius {a.radius}" if a.beta else "") + (f" eta {a.eta:g}" if a.eta else "")
    label = (f"{a.scheme} {a.thickness} cells {a.incline:g}/{a.friction:g} deg law={a.law}{probes} "
             f"cfl {a.cfl or 0.5:g} dx {a.dx or cs.cell_size_for(a.youngs):g} E={a.youngs:g}")
    if a.slide:
        print(label, f"dt {r['dt']:.3e} s, {r['steps']} steps")
        for t, ke, err in r["slide"]:
            print(f"  t {t:8.3f} s  elastic KE {ke:10.3e} J/m  slip error {100 * err:+8.2f} % "
                  "(sticking: of the frictionless distance)")
        return 0
    s = r["shape"]
    print(f"{label}: dt {r['dt']:.3e} s, {r['steps']} steps; growth per step {r['rho']:.5f} "
          f"({r['per_s']:+.2f} /s; x{r['factor']:.3g} over the run); quarters per step "
          + " ".join(f"{math.exp(q):.5f}" for q in r["quarters"])
          + f"; shape: KE normal {s['ke_normal']:.2f}, rows " + " ".join(f"{k}:{v:.2f}" for k, v in s["rows"].items())
          + f", wavelength {s['wavelength_cells']:.1f} cells")
    return 0


if __name__ == "__main__":
    sys.exit(main())
