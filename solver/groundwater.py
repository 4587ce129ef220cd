"""The engine's ground-water component: pore pressure and wet mass at a particle, on the device.

The rules are solver/water.py's (read its docstring for the physics); this is their kernel form.
The phreatic line is sampled at the grid's node columns (exact at every column, linear between
them), once at the start of the water's move and once at its end; each step moves it on by
``dt / duration``, so a stage that raises or lowers the water costs no launch of its own.

Symbols: ``x`` a particle position (engine coordinates, m), ``g`` the step's gravity (m/s2),
``s`` a particle's effective stress vec4 (xx, yy, xy, zz; Pa, tension positive).
"""


from collections.abc import Sequence

import numpy as np
from solver.runtime import ti

from solver.config import Material, Water
from solver.water import line_height, unit_weight_ratio


@ti.data_oriented
class GroundWater:
    """Pore pressure and the saturated mass ratio of particles (built only where a run has water).

    Parameters
    ----------
    columns : int, node columns of the grid
    origin_x_m : float, x of node column 0 (engine coordinates)
    dx : float, cell size (m)
    materials : the material table's rows
    full_gravity_m_s2 : (2,) float, the run's full gravity: the water's unit weight is given for
        its magnitude, and depths are measured along its direction (also while a gravity stage
        ramps gravity up from zero)
    np_float : numpy float type of the run's precision (what the host writes into the fields)
    seismic : some stage may have seismic coefficients: the water's pressure then stays that of
        gravity alone (:meth:`set_seismic`); compiled in only then
    """

    def __init__(self, columns: int, origin_x_m: float, dx: float, materials: Sequence[Material],
                 full_gravity_m_s2, np_float=np.float32, seismic: bool = False):
        self.np_float = np_float  # the fields' float type (the run's precision)
        self.seismic = bool(seismic)
        #: with seismic coefficients: 1 / (1 - k_v), which takes the step's body force back to gravity's
        self.unseismic = ti.field(float, ())
        self.unseismic[None] = 1.0
        self.columns = int(columns)
        self.origin_x = float(origin_x_m)
        self.dx = float(dx)
        self.inv_dx = 1.0 / self.dx
        g = np.asarray(full_gravity_m_s2, dtype=np.float64)
        self.full_g = float(np.linalg.norm(g))
        self.down = tuple(float(v) for v in (g / self.full_g if self.full_g > 0.0 else (0.0, -1.0)))
        n_mat = max(1, len(materials))
        # the phreatic line (row 0) and the free water's level (row 1) at the node columns, where
        # the move starts and where it ends
        self.y_from = ti.field(float, (2, self.columns))
        self.y_to = ti.field(float, (2, self.columns))
        #: how far the lines have moved from ``y_from`` to ``y_to`` (0-1), and by how much a second
        self.fraction = ti.field(float, ())
        self.rate = ti.field(float, ())
        #: the step's gravity (a gravity stage ramps it; the pressures scale with its magnitude)
        self.g_now = ti.Vector.field(2, float, ())
        #: the water's density (kg/m3: its unit weight over the full gravity), 0 where there is no line
        self.rho_w = ti.field(float, ())
        self.correct = ti.field(ti.i32, ())
        self.wet_ratio = ti.field(float, n_mat)
        self.ru = ti.field(float, n_mat)
        self.load_materials(materials)
        self.set_water(None, None, 0.0)

    # ------------------------------------------------------------------ host side
    def column_x(self) -> np.ndarray:
        return self.origin_x + self.dx * np.arange(self.columns)

    def load_materials(self, materials: Sequence[Material]) -> None:
        """The per-material saturated-density ratio and r_u (a stage's material changes)."""
        ratio = np.ones(self.wet_ratio.shape[0])
        ru = np.zeros(self.ru.shape[0])
        ratio[:len(materials)] = unit_weight_ratio(materials)
        ru[:len(materials)] = [m.ru for m in materials]
        self.wet_ratio.from_numpy(ratio.astype(self.np_float))
        self.ru.from_numpy(ru.astype(self.np_float))

    def _sampled(self, water: Water) -> np.ndarray:
        xs = self.column_x()
        return np.stack([line_height(water.phreatic_line_m, xs), line_height(water.free_water, xs)])

    def set_water(self, start: Water | None, end: Water | None, duration_s: float) -> None:
        """Move the water from ``start`` to ``end`` over ``duration_s`` (0: be at ``end`` now);
        lines in engine coordinates. ``None`` for both: no line (r_u only)."""
        end = start if end is None else end
        start = end if start is None else start
        if end is None:
            self.y_from.from_numpy(np.zeros((2, self.columns), dtype=self.np_float))
            self.y_to.from_numpy(np.zeros((2, self.columns), dtype=self.np_float))
            self.rho_w[None] = 0.0
            self.correct[None] = 0
        else:
            self.y_from.from_numpy(self._sampled(start).astype(self.np_float))
            self.y_to.from_numpy(self._sampled(end).astype(self.np_float))
            self.rho_w[None] = end.unit_weight_n_m3 / self.full_g if self.full_g > 0.0 else 0.0
            self.correct[None] = int(end.inclined_correction)
        moving = duration_s > 0.0 and start is not end
        self.fraction[None] = 0.0 if moving else 1.0
        self.rate[None] = 1.0 / duration_s if moving else 0.0

    def set_seismic(self, seismic) -> None:
        """The stage's seismic coefficients (solver.config.Seismic or None): the step's body force
        then holds them, and the water's pressure is still that of gravity alone (pseudo-static
        practice: the coefficients act on the masses, not on the pore pressure)."""
        if not self.seismic:
            if seismic is not None and (seismic.k_h != 0.0 or seismic.k_v != 0.0):
                raise ValueError("this ground water was built without seismic support (seismic=False)")
            return
        self.unseismic[None] = 1.0 if seismic is None else 1.0 / (1.0 - seismic.k_v)

    def state(self) -> dict[str, np.ndarray]:
        """What a checkpoint keeps of the water's move (the lines themselves come from the stages)."""
        return {"fraction": np.array([self.fraction[None]], dtype=np.float64)}

    def load_state(self, state: dict[str, np.ndarray]) -> None:
        if "fraction" in state:
            self.fraction[None] = float(np.asarray(state["fraction"]).ravel()[0])

    # ------------------------------------------------------------------ device side
    @ti.func
    def begin_step(self, dt, g):
        """Move the lines on by one step and keep its gravity (once per step, from a serial loop)."""
        self.fraction[None] = ti.min(1.0, self.fraction[None] + self.rate[None] * dt)
        if ti.static(self.seismic):
            # gravity alone: the body force's part along gravity without its (1 - k_v), and no k_h
            d = ti.Vector(self.down)
            self.g_now[None] = g.dot(d) * self.unseismic[None] * d
        else:
            self.g_now[None] = g

    @ti.func
    def at(self, x):
        """The water state of a particle at x, looked up once per particle per pass and passed to
        :meth:`excess_pressure`, :meth:`mass_ratio` and :meth:`buoyancy`: a vec4 of the depth
        below the phreatic line (m, along the full gravity, negative above), the squared cosine
        of that line's inclination from level, the depth below the free water's level and that
        level's slope. Zeros where there is no line (r_u alone needs none of it)."""
        w = ti.Vector.zero(float, 4)
        if self.rho_w[None] > 0.0:
            X = (x[0] - self.origin_x) * self.inv_dx
            i = ti.max(ti.min(ti.cast(ti.floor(X), ti.i32), self.columns - 2), 0)
            f = ti.max(ti.min(X - ti.cast(i, float), 1.0), 0.0)
            h0, _, c2 = self._depth(x, 0, i, f)
            h1, slope1, _ = self._depth(x, 1, i, f)
            w = ti.Vector([h0, c2, h1, slope1])
        return w

    @ti.func
    def _depth(self, x, row: ti.template(), i, f):
        """Depth of x below line ``row`` (0 phreatic, 1 free water) along the full gravity (m,
        negative above), the line's slope there and the squared cosine of its inclination from
        level; x lies at fraction f (0-1) of the way from node column i to i + 1."""
        s = self.fraction[None]
        ya = (1.0 - s) * self.y_from[row, i] + s * self.y_to[row, i]
        yb = (1.0 - s) * self.y_from[row, i + 1] + s * self.y_to[row, i + 1]
        slope = (yb - ya) * self.inv_dx
        d = ti.Vector(self.down)
        across = ti.max(-d[1] + slope * d[0], 1e-9)
        h = (ya + f * (yb - ya) - x[1]) / across
        c = across / ti.sqrt(1.0 + slope * slope)
        return h, slope, c * c

    @ti.func
    def pressure(self, w, mat, s):
        """Pore pressure u (Pa, positive) of a particle in water state w (:meth:`at`) of material
        mat with effective stress s."""
        u = 0.0
        g = self.g_now[None]
        gn = g.norm()
        if gn > 0.0:
            if self.rho_w[None] > 0.0:
                h = w[0]
                if h > 0.0:
                    u = self.rho_w[None] * gn * h
                    if self.correct[None] != 0:
                        u *= w[1]
            ru = self.ru[mat]
            if ru > 0.0:  # the larger of the line's and the overburden's (solver/water.py)
                d = g / gn
                s_gg = d[0] * d[0] * s[0] + 2.0 * d[0] * d[1] * s[2] + d[1] * d[1] * s[1]
                u = ti.max(u, ru / (1.0 - ru) * ti.max(-s_gg, 0.0))
        return u

    @ti.func
    def excess_pressure(self, w, mat, s):
        """The pore pressure in excess of the free water's hydrostatic pressure, u - p_w (Pa), of a
        particle in water state w (:meth:`at`): what its stress carries in the force passes
        (solver/water.py)."""
        return self.pressure(w, mat, s) - self.free_pressure(w)

    @ti.func
    def free_pressure(self, w):
        """The free water's hydrostatic pressure p_w (Pa; 0 above its level) in water state w."""
        p = 0.0
        if self.rho_w[None] > 0.0:
            p = self.rho_w[None] * self.g_now[None].norm() * ti.max(w[2], 0.0)
        return p

    @ti.func
    def buoyancy(self, w):
        """The body force of the free water's pressure on the skeleton, -grad p_w (N/m3), in water
        state w (:meth:`at`)."""
        g = self.g_now[None]
        f = ti.Vector([0.0, 0.0])
        if self.rho_w[None] > 0.0:
            h = w[2]
            slope = w[3]
            if h > 0.0:
                d = ti.Vector(self.down)
                across = ti.max(-d[1] + slope * d[0], 1e-9)
                # p_w = rho_w |g| h with h = (y_line(x) - y) / across: its gradient is
                # rho_w |g| (slope, -1) / across
                f = -self.rho_w[None] * g.norm() / across * ti.Vector([slope, -1.0])
        return f

    @ti.func
    def mass_ratio(self, w, mat):
        """Saturated over dry density below the phreatic line, 1 above it (water state w, :meth:`at`)."""
        r = 1.0
        if self.rho_w[None] > 0.0:
            if w[0] > 0.0:
                r = self.wet_ratio[mat]
        return r
