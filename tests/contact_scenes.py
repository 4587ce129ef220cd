"""Contact scenes shared by the contact tests and the full matrix (benchmarks/contact_matrix.py).

A block starts at rest on a contact under gravity, with the stress of a block at rest on the
slope (:func:`slope_stress`; or stress free), settles on the contact held fixed (local damping,
SETTLE_TRANSITS P-wave transits of the block, so that its free ends are in equilibrium too), and is
released on the frictional contact; the slip is measured from the release. The engine runs
directly (one engine serves every incline and friction angle of a scheme, precision, thickness and
stiffness: gravity, the walls' friction and the particles are data, not compiled).

- :class:`WallIncline`: the contact is a closed side of the grid box. The incline is made by
  rotating gravity, not the geometry (exact and cheap): on the ``bottom`` wall gravity is
  ``g (sin th, -cos th)`` (the block slides towards +x); on the ``left`` wall
  ``g (-cos th, -sin th)``, on the ``right`` wall ``g (cos th, -sin th)`` (it slides down the wall,
  towards -y).
- :class:`RampIncline`: the contact is an inclined rigid structure (a ramp at angle ``th``) under
  vertical gravity; the block sits on it with its base parallel to the ramp surface.

Analytic distance along the slope after ``t`` seconds from rest (rigid block, Coulomb friction
``mu = tan(delta)``): ``s = 1/2 g (sin th - mu cos th) t^2`` when ``tan(th) > mu`` (slides), 0
otherwise (sticks). What is measured is the slip at the contact: the mean displacement along the
slope of the particles of the block's lowest particle row (the row next to the contact), so that
the elastic shear of a sticking block, which moves its upper part, is not counted as slip. The
run lasts until the analytic travel is 20 cells (5 % more); a sticking case runs as long as the
frictionless block would take.

The scale (cell size, density) keeps the steps few: ``dx = 2 m`` for E >= 1e7 Pa and ``0.1 m``
below, density 2000 kg/m3 (a few hundred to two thousand steps a case). The weight-to-stiffness
ratio ``rho g H / E`` of a 20-cell block is then 8e-3 (stiff) and 4e-2 (soft).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from solver.config import Boundary, Grid, Material, Structure  # noqa: F401

G = 9.81
DENSITY = 2000.0
POISSON = 0.3
PPC = 2  # particles per cell along each axis
MIN_LENGTH_CELLS = 40  # block length along the slope: at least this and ASPECT x its thickness
ASPECT = 4.0  # block length / thickness (the scenes' default; ``aspect`` of the scenes changes it)
TRAVEL_CELLS = 20.0  # the sliding cases run until the analytic travel is this many cells (plus margin)
CFL = 0.5
SETTLE_TRANSITS = 3.0  # settling on a fixed contact before the release: P-wave transits of the block
SETTLE_DAMPING = 0.7  # Cundall's local damping while settling


def block_length_cells(thickness_cells: int, aspect: float = ASPECT) -> int:
    """Block length (cells): never tips over (length / thickness > tan th) and long against its
    thickness. A finite block started with the infinite-slope stress is not quite in equilibrium at
    its free ends; the ends relax and the block vibrates, and close to the friction limit that
    makes a short block creep (measured: E = 1e6 Pa, 5 cells thick, 40 deg on 45 deg friction:
    13 cells long slipped 9.6 % of the frictionless distance, 40 cells long 0.06 %)."""
    return max(MIN_LENGTH_CELLS, int(round(aspect * thickness_cells)))


def cell_size_for(youngs_pa: float) -> float:
    return 2.0 if youngs_pa >= 1e7 else 0.1


def analytic_distance(theta_deg: float, delta_deg: float, t: float) -> float:
    th = math.radians(theta_deg)
    a = G * (math.sin(th) - math.tan(math.radians(delta_deg)) * math.cos(th))
    return 0.5 * max(a, 0.0) * t * t


def run_time(theta_deg: float, delta_deg: float, dx: float) -> float:
    """Time for the analytic travel of TRAVEL_CELLS cells (for a sticking case: of the frictionless
    block), plus 5 %."""
    th = math.radians(theta_deg)
    a = G * (math.sin(th) - math.tan(math.radians(delta_deg)) * math.cos(th))
    if a <= 1e-9:
        a = G * math.sin(th)
    return 1.05 * math.sqrt(2.0 * TRAVEL_CELLS * dx / a)


def shear_period(youngs_pa: float, thickness_m: float, poisson: float = POISSON, density: float = DENSITY) -> float:
    """The fundamental shear period ``4 H / c_s`` (s) of a layer ``thickness_m`` thick."""
    return 4.0 * thickness_m / math.sqrt(youngs_pa / (2.0 * (1.0 + poisson)) / density)


def column_wave_slip(youngs_pa: float, thickness_m: float, theta_deg: float, delta_deg: float, duration_s: float,
                     *, poisson: float = POISSON, density: float = DENSITY, cells: int = 160,
                     cfl: float = 0.5) -> float:
    """Slip (m) along the slope after ``duration_s`` of an elastic layer released stress free on a
    rigid frictional incline: the one-dimensional wave solution, the reference for a long block
    (docs/validation.md, a block released stress free).

    At ``t = 0`` gravity acts on the unstressed layer. Across its thickness ``z`` (0 at the base,
    free top) a P-wave carries the normal stress (modulus ``M = E (1 - nu) / ((1 + nu) (1 - 2 nu))``)
    and an S-wave the shear (``G``): ``rho u_tt = G u_zz + rho g sin th``, ``rho w_tt = M w_zz -
    rho g cos th``. The base meets the incline by the unilateral Coulomb law (no penetration,
    separation free, friction at most ``mu`` times the normal impulse, stick, never reversed). The
    base's normal stress swings between 0 and twice the weight with the P-wave's period ``4 H /
    c_p`` while the shear swings with the S-wave's slower one, so the base slips in every low phase
    of the normal stress and the layer creeps down a slope it would stand on at rest. No MPM: linear
    finite elements with lumped masses (``cells`` of them; the slip converges to about 1 % at 80),
    central differences in time at ``cfl`` of the P-wave's step, the contact law at the base node
    after each force update, as the engine applies its own.
    """
    E, nu, rho, H = float(youngs_pa), float(poisson), float(density), float(thickness_m)
    shear = E / (2.0 * (1.0 + nu))
    modulus = E * (1.0 - nu) / ((1.0 + nu) * (1.0 - 2.0 * nu))
    dz = H / cells
    dt = cfl * dz / math.sqrt(modulus / rho)
    steps = max(1, int(math.ceil(duration_s / dt)))
    dt = duration_s / steps
    th = math.radians(theta_deg)
    g_along, g_into = G * math.sin(th), G * math.cos(th)
    mu = math.tan(math.radians(delta_deg))
    mass = np.full(cells + 1, rho * dz)
    mass[[0, -1]] *= 0.5
    vn, vt = np.zeros(cells + 1), np.zeros(cells + 1)  # away from the base; down the slope
    sn, st = np.zeros(cells), np.zeros(cells)  # normal (tension positive) and shear stress per element
    slip = 0.0
    for _ in range(steps):
        fn, ft = np.zeros(cells + 1), np.zeros(cells + 1)
        fn[:-1] += sn
        fn[1:] -= sn
        ft[:-1] += st
        ft[1:] -= st
        vn += dt * (fn / mass - g_into)
        vt += dt * (ft / mass + g_along)
        if vn[0] < 0.0:  # the base node presses: Coulomb with the normal impulse of this step
            allowed = mu * -vn[0]
            vn[0] = 0.0
            speed = abs(vt[0])
            vt[0] = 0.0 if speed <= allowed else vt[0] * (speed - allowed) / speed
        sn += dt * modulus * np.diff(vn) / dz
        st += dt * shear * np.diff(vt) / dz
        slip += dt * vt[0]
    return slip


@dataclass
class Outcome:
    distance_m: float  # measured slip along the slope
    analytic_m: float  # 0 when the block sticks
    frictionless_m: float
    slides: bool
    steps: int
    cell_m: float

    @property
    def error(self) -> float:
        """Relative error against the analytic distance (sliding) or the measured slip as a fraction
        of the frictionless distance (sticking)."""
        if self.slides:
            return self.distance_m / self.analytic_m - 1.0
        return abs(self.distance_m) / self.frictionless_m


def _lattice(nx: int, ny: int, h: float) -> np.ndarray:
    X, Y = np.meshgrid((np.arange(nx) + 0.5) * h, (np.arange(ny) + 0.5) * h)
    return np.c_[X.ravel(), Y.ravel()]


class WallIncline:
    """One engine for blocks of ``thickness_cells`` on the ``side`` wall ("bottom", "left" or "right"),
    ``aspect`` times as long as thick (at least MIN_LENGTH_CELLS long)."""

    def __init__(self, scheme: str, precision: str, thickness_cells: int, youngs_pa: float,
                 side: str = "bottom", scatter: str = "serial", aspect: float = ASPECT, engine_class=None):
        """``engine_class``: an :class:`solver.engine.Engine` subclass (the diagnosis runs the
        node-by-node law of earlier sessions), the engine itself by default."""
        from solver.engine import Engine

        Engine = engine_class or Engine  # noqa: N806

        self.dx = dx = cell_size_for(youngs_pa)
        self.side = side
        self.material = Material("block", "linear-elastic", DENSITY, youngs_pa, POISSON)
        h = dx / PPC
        length = block_length_cells(thickness_cells, aspect)
        self.length_m = length * dx
        base = _lattice(length * PPC, thickness_cells * PPC, h)
        along = (length + TRAVEL_CELLS + 6) * dx
        across = (thickness_cells + 4) * dx
        if side == "bottom":
            self.positions = base + [2 * dx, 0.0]
            size = (along, across)
            self.slope = np.array([1.0, 0.0])
        elif side in ("left", "right"):
            self.positions = base[:, ::-1] + [0.0, (TRAVEL_CELLS + 4) * dx]
            size = (across, along)
            self.slope = np.array([0.0, -1.0])
            if side == "right":
                self.positions[:, 0] = across - self.positions[:, 0]
        else:
            raise ValueError(f"side must be bottom, left or right, got {side!r}")
        normal_axis = 1 if side == "bottom" else 0
        self.normal = np.eye(2)[normal_axis] * (-1.0 if side == "right" else 1.0)
        self.thickness_m = thickness_cells * dx
        self.base_m = size[0] if side == "right" else 0.0  # the contact's line, along the normal
        self.base_row = self.positions @ self.normal - self.normal @ [self.base_m, 0.0] < h
        self.size = size
        self.grid = Grid((0.0, 0.0), size, dx, **self._sides(0.0))
        self.np_float = np.float32 if precision == "f32" else np.float64
        self.engine = Engine(self.grid, (self.material,), len(self.positions), scheme, self.np_float,
                             damping=True, scatter=scatter)

    def _sides(self, phi: float) -> dict:
        """The contact side (and, for a side wall, the bottom) frictional; the others open."""
        sides = dict(left=Boundary("open"), right=Boundary("open"), bottom=Boundary("friction", phi),
                     top=Boundary("open"))
        if self.side != "bottom":
            sides[self.side] = Boundary("friction", phi)
        return sides

    def gravity(self, theta_deg: float) -> tuple[float, float]:
        """Gravity (m/s2) tilted so that the contact is an incline of ``theta_deg``."""
        th = math.radians(theta_deg)
        if self.side == "bottom":
            return (G * math.sin(th), -G * math.cos(th))
        across = -G * math.cos(th) if self.side == "left" else G * math.cos(th)
        return (across, -G * math.sin(th))

    def release(self, theta_deg: float, delta_deg: float, settled: bool = True) -> float:
        """Load the block into ``self.engine``, give it the equilibrium stress (:func:`slope_stress`;
        ``settled``, else stress free), settle it on the contact held fixed and switch to the
        frictional one (:func:`settle_and_release`); the time step (s) of the run that follows."""
        e = self.engine

        def contact(fixed: bool) -> None:
            sides = self._sides(math.radians(delta_deg))
            if fixed:
                sides[self.side] = Boundary("fixed")
            e.set_boundaries(Grid(self.grid.origin_m, self.grid.size_m, self.dx, **sides))

        h = self.dx / PPC
        e.load_particles(self.positions, np.full(len(self.positions), h * h), np.zeros(len(self.positions), np.int32))
        base = float(self.normal @ [self.base_m, 0.0])
        stress = slope_stress(self.positions, self.slope, self.normal, base, self.thickness_m, theta_deg,
                              delta_deg) if settled else None
        return settle_and_release(e, self.material, self.dx, self.gravity(theta_deg), stress, contact, self.length_m)

    def run(self, theta_deg: float, delta_deg: float, settled: bool = True) -> Outcome:
        """One case; ``settled``: start from the equilibrium stress (:func:`slope_stress`), else stress free."""
        dt = self.release(theta_deg, delta_deg, settled)
        return _slide(self.engine, dt, self.gravity(theta_deg), theta_deg, delta_deg, self.slope, self.base_row,
                      self.dx)


class RampIncline:
    """A block on a ramp structure at ``theta_deg`` under vertical gravity (one engine per ramp angle:
    the structure's nodes are set up at construction)."""

    def __init__(self, scheme: str, precision: str, thickness_cells: int, youngs_pa: float, theta_deg: float,
                 delta_deg: float = 0.0, scatter: str = "serial", aspect: float = ASPECT):
        from solver.engine import Engine

        self.dx = dx = cell_size_for(youngs_pa)
        self.theta = theta_deg
        th = math.radians(theta_deg)
        self.material = Material("block", "linear-elastic", DENSITY, youngs_pa, POISSON)
        h = dx / PPC
        length = block_length_cells(thickness_cells, aspect)
        self.length_m = length * dx
        run_along = (length + TRAVEL_CELLS + 4) * dx  # ramp length along the slope
        t_hat = np.array([math.cos(th), -math.sin(th)])  # down the slope
        n_hat = np.array([math.sin(th), math.cos(th)])  # outward normal of the ramp surface
        # the ramp: a right triangle whose hypotenuse (the surface) runs from top to bottom
        top = np.array([2 * dx, 2 * dx + run_along * math.sin(th)])
        foot = top + run_along * t_hat
        below = foot[1] - 2 * dx
        self.polygon = ((top[0] - 2 * dx, top[1]), tuple(top), tuple(foot), (foot[0], below), (top[0] - 2 * dx, below))
        local = _lattice(length * PPC, thickness_cells * PPC, h)
        start = top + 1.0 * dx * t_hat
        self.positions = start + local[:, :1] * t_hat + local[:, 1:] * n_hat
        self.base_row = local[:, 1] < h
        self.slope = t_hat
        self.normal = n_hat
        self.surface_offset = float(top @ n_hat)
        self.thickness_m = thickness_cells * dx
        lo = np.array([0.0, below - 2 * dx])
        hi = np.array([foot[0] + 4 * dx, top[1] + (thickness_cells + 4) * dx])
        self.origin = tuple(lo)
        self.size = tuple(hi - lo)
        self.np_float = np.float32 if precision == "f32" else np.float64
        self.engine = None
        self._scheme, self._scatter = scheme, scatter
        self.delta = delta_deg
        self._build(delta_deg)

    def _build(self, delta_deg: float) -> None:
        from solver.engine import Engine

        contact = Boundary("friction", math.radians(delta_deg))
        grid = Grid(self.origin, self.size, self.dx, left=Boundary("slip"), right=Boundary("open"),
                    bottom=Boundary("slip"), top=Boundary("open"))
        self.structure = Structure("ramp", self.polygon, contact)
        self.engine = Engine(grid, (self.material,), len(self.positions), self._scheme, self.np_float,
                             damping=True, scatter=self._scatter, structures=(self.structure,))

    def run(self, delta_deg: float, settled: bool = True) -> Outcome:
        e = self.engine

        def contact(fixed: bool) -> None:
            e.set_structure_contacts((Boundary("fixed") if fixed else Boundary("friction", math.radians(delta_deg)),))

        h = self.dx / PPC
        e.load_particles(self.positions, np.full(len(self.positions), h * h), np.zeros(len(self.positions), np.int32))
        stress = slope_stress(self.positions, self.slope, self.normal, self.surface_offset, self.thickness_m,
                              self.theta, delta_deg) if settled else None
        dt = settle_and_release(e, self.material, self.dx, (0.0, -G), stress, contact, self.length_m)
        return _slide(e, dt, (0.0, -G), self.theta, delta_deg, self.slope, self.base_row, self.dx)


def slope_stress(positions_m: np.ndarray, slope, normal, base_m: float, thickness_m: float, theta_deg: float,
                 delta_deg: float) -> np.ndarray:
    """The stress of a block at rest on the slope in equilibrium (xx, yy, xy, zz; Pa).

    In the slope's frame (``slope`` down the slope, ``normal`` out of the contact into the block), at
    depth ``d`` below the block's top: ``s_nn = -rho g cos(th) d``, ``s_tt = s_zz = K0 s_nn`` with
    ``K0 = nu / (1 - nu)``, and the shear that the contact holds, ``s_tn = rho g d min(sin th, mu cos th)``
    (static equilibrium when the block sticks; the shear of a block sliding rigidly at
    ``g (sin th - mu cos th)`` when it slides).
    """
    th = math.radians(theta_deg)
    mu = math.tan(math.radians(delta_deg))
    slope, normal = np.asarray(slope, float), np.asarray(normal, float)
    depth = thickness_m - (positions_m @ normal - base_m)
    s_nn = -DENSITY * G * math.cos(th) * depth
    s_tn = DENSITY * G * min(math.sin(th), mu * math.cos(th)) * depth
    k0 = POISSON / (1.0 - POISSON)
    local = np.zeros((len(depth), 2, 2))
    local[:, 0, 0] = k0 * s_nn
    local[:, 1, 1] = s_nn
    local[:, 0, 1] = local[:, 1, 0] = s_tn
    R = np.c_[slope, normal]  # columns: the slope frame in global coordinates
    sig = R[None] @ local @ R.T[None]
    return np.c_[sig[:, 0, 0], sig[:, 1, 1], sig[:, 0, 1], k0 * s_nn]


def settle_and_release(e, material: Material, dx: float, gravity, stress, contact, length_m: float) -> float:
    """Settle the block on a fixed contact (``contact(True)``, local damping, SETTLE_TRANSITS
    transits of a P wave along the block, velocities zeroed after), then switch to the frictional
    contact (``contact(False)``); the time step (s) of the run that follows."""
    if stress is not None:
        e.set_stress(stress)
    dt = CFL * dx / material.p_wave_speed_m_s
    if SETTLE_TRANSITS > 0:
        contact(True)
        for _ in range(int(math.ceil(SETTLE_TRANSITS * length_m / material.p_wave_speed_m_s / dt))):
            e.step(dt, gravity, SETTLE_DAMPING)
        e.bring_to_rest()  # velocities and the damping's memory (a Maxwell arm) dropped
    contact(False)
    return dt


def _slide(e, dt: float, gravity, theta_deg: float, delta_deg: float, slope, base_row, dx: float) -> Outcome:
    """Run the released block for :func:`run_time` (steps of about ``dt``); the slip of its lowest
    particle row is measured from the release."""
    t_end = run_time(theta_deg, delta_deg, dx)
    steps = int(math.ceil(t_end / dt))
    dt = t_end / steps
    x0 = e.x.to_numpy().astype(np.float64)
    for _ in range(steps):
        e.step(dt, gravity)
    x = e.x.to_numpy().astype(np.float64)
    distance = float(((x - x0)[base_row] @ slope).mean())
    analytic = analytic_distance(theta_deg, delta_deg, t_end)
    frictionless = analytic_distance(theta_deg, 0.0, t_end)
    return Outcome(distance, analytic, frictionless, analytic > 0.0, steps, dx)
