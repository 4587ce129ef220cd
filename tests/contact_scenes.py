"""Contact scenes of the contact tests (a test fixture).

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
from pathlib import Path

import numpy as np

from solver.config import DEFAULT_DAMPING_MODEL, Boundary, Grid, Material, Structure  # noqa: F401

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
                 side: str = "bottom", scatter: str = "serial", aspect: float = ASPECT):
        from solver.engine import Engine

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


# ---------------------------------------------------------------------------------------------
# The project path: the same block as a project file, run as a user runs it.

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
        """The :class:`Outcome` of the frame: the mean slip of the lowest row
        along the slope against the analytic (sliding) or frictionless (sticking) distance."""
        import numpy as np

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
    analytic travel of 20 cells plus 5 %, :func:`run_time`); one frame at
    its end. ``start_cells``: on the ramp, how far down the face from the ramp's convex top vertex
    the block's upslope end starts (cells). ``damping_ratio``: the block's material damping
    (docs/solver.md), that fraction of critical at the block's first shear mode on its base,
    ``c_s / (4 H)`` (times ``damping_frequency_factor``), by ``damping_model``.
    """
    import numpy as np

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
