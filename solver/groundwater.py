"""The engine's ground-water component: pore pressure and wet mass at a particle, on the device.

The rules are solver/water.py's (read its docstring for the physics); this is their kernel form.
The phreatic line is sampled at the grid's node columns (exact at every column, linear between
them), once at the start of the water's move and once at its end; each step moves it on by
``dt / duration``, so a stage that raises or lowers the water costs no launch of its own.

Symbols: ``x`` a particle position (engine coordinates, m), ``g`` the step's gravity (m/s2),
``s`` a particle's effective stress vec4 (xx, yy, xy, zz; Pa, tension positive).
"""

from __future__ import annotations

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
    """

    def __init__(self, columns: int, origin_x_m: float, dx: float, materials: Sequence[Material],
                 full_gravity_m_s2):
        self.columns = int(columns)
        self.origin_x = float(origin_x_m)
        self.dx = float(dx)
        self.inv_dx = 1.0 / self.dx
        g = np.asarray(full_gravity_m_s2, dtype=np.float64)
        self.full_g = float(np.linalg.norm(g))
        self.down = tuple(float(v) for v in (g / self.full_g if self.full_g > 0.0 else (0.0, -1.0)))
        n_mat = max(1, len(materials))
        self.y_from = ti.field(float, self.columns)
        self.y_to = ti.field(float, self.columns)
        #: how far the line has moved from ``y_from`` to ``y_to`` (0-1), and by how much a second
        self.fraction = ti.field(float, ())
        self.rate = ti.field(float, ())
        #: the water's density (kg/m3: its unit weight over the full gravity), 0 where there is no line
        self.rho_w = ti.field(float, ())
        self.correct = ti.field(ti.i32, ())
        self.wet_ratio = ti.field(float, n_mat)
        self.ru = ti.field(float, n_mat)
        self._water: tuple[Water | None, Water | None] = (None, None)
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
        self.wet_ratio.from_numpy(ratio)
        self.ru.from_numpy(ru)

    def set_water(self, start: Water | None, end: Water | None, duration_s: float) -> None:
        """Move the water from ``start`` to ``end`` over ``duration_s`` (0: be at ``end`` now);
        lines in engine coordinates. ``None`` for both: no line (r_u only)."""
        end = start if end is None else end
        start = end if start is None else start
        xs = self.column_x()
        if end is None:
            self.y_from.from_numpy(np.zeros(self.columns))
            self.y_to.from_numpy(np.zeros(self.columns))
            self.rho_w[None] = 0.0
            self.correct[None] = 0
        else:
            self.y_from.from_numpy(line_height(start.phreatic_line_m, xs))
            self.y_to.from_numpy(line_height(end.phreatic_line_m, xs))
            self.rho_w[None] = end.unit_weight_n_m3 / self.full_g if self.full_g > 0.0 else 0.0
            self.correct[None] = int(end.inclined_correction)
        moving = duration_s > 0.0 and start is not end
        self.fraction[None] = 0.0 if moving else 1.0
        self.rate[None] = 1.0 / duration_s if moving else 0.0
        self._water = (start, end)

    def state(self) -> dict[str, np.ndarray]:
        """What a checkpoint keeps of the water's move (the lines themselves come from the stages)."""
        return {"fraction": np.array([self.fraction[None]], dtype=np.float64)}

    def load_state(self, state: dict[str, np.ndarray]) -> None:
        if "fraction" in state:
            self.fraction[None] = float(np.asarray(state["fraction"]).ravel()[0])

    # ------------------------------------------------------------------ device side
    @ti.func
    def advance(self, dt):
        """Move the line on by one step (call once per step, from a serial part of the kernel)."""
        self.fraction[None] = ti.min(1.0, self.fraction[None] + self.rate[None] * dt)

    @ti.func
    def _line(self, x0):
        """Height of the line and its slope at x0."""
        X = (x0 - self.origin_x) * self.inv_dx
        i = ti.max(ti.min(ti.cast(ti.floor(X), ti.i32), self.columns - 2), 0)
        f = ti.max(ti.min(X - ti.cast(i, float), 1.0), 0.0)
        s = self.fraction[None]
        ya = (1.0 - s) * self.y_from[i] + s * self.y_to[i]
        yb = (1.0 - s) * self.y_from[i + 1] + s * self.y_to[i + 1]
        return ya + f * (yb - ya), (yb - ya) * self.inv_dx

    @ti.func
    def _depth(self, x):
        """Depth below the line along the full gravity (m, negative above) and cos^2 of the line's
        inclination from level there."""
        d = ti.Vector(self.down)
        y, slope = self._line(x[0])
        across = -d[1] + slope * d[0]
        h = (y - x[1]) / ti.max(across, 1e-9)
        c = across / ti.sqrt(1.0 + slope * slope)
        return h, c * c

    @ti.func
    def pressure(self, x, mat, s, g):
        """Pore pressure (Pa, positive) of a particle at x of material mat with effective stress s."""
        u = 0.0
        gn = g.norm()
        ru = self.ru[mat]
        if gn > 0.0:
            if ru > 0.0:
                d = g / gn
                s_gg = d[0] * d[0] * s[0] + 2.0 * d[0] * d[1] * s[2] + d[1] * d[1] * s[1]
                u = ru / (1.0 - ru) * ti.max(-s_gg, 0.0)
            elif self.rho_w[None] > 0.0:
                h, c2 = self._depth(x)
                if h > 0.0:
                    u = self.rho_w[None] * gn * h
                    if self.correct[None] != 0:
                        u *= c2
        return u

    @ti.func
    def mass_ratio(self, x, mat):
        """Saturated over dry density below the line, 1 above it."""
        r = 1.0
        if self.rho_w[None] > 0.0:
            h, _ = self._depth(x)
            if h > 0.0:
                r = self.wet_ratio[mat]
        return r
