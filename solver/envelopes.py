"""Hazard envelopes accumulated on the device while a run goes on (not from the output frames).

The envelopes live on a raster of square cells (``cell_size_m``, by default the grid's) laid over
the grid box from its origin: ``nx`` columns along x, ``ny`` rows along y. Every ``every_steps``
steps of the dynamic stages, and at every output frame, one kernel reads the engine's particle
fields (``x``, ``v``, ``m``, ``rho``, ``active``; never written) and updates the running values.

Symbols (SI): a particle ``p`` stands for a square of side ``h_p = sqrt(m_p / rho_p)`` (its current
volume per metre) centred on ``x_p``; ``|v_p|`` its speed (m/s); ``rho_p`` its density (kg/m3).

Per raster column ``i`` (x from ``x0 + i c`` to ``x0 + (i + 1) c``):

- ``top``: the current material surface, the highest ``y_p + h_p / 2`` of the particles whose
  centres lie in the column (m); columns without material have none.
- ``ground``: the surface at the release (the start of the first dynamic stage): the initial
  ``top``, or the rigid floor (the grid's bottom, or ``EnvelopeConfig.ground_m``) where that is
  higher or the column is empty.
- flow height ``max(top - ground, 0)`` (m), measured along y (normal to the grid's bottom);
  ``peak_height``: its running maximum; ``arrival``: the first update time at which it exceeded
  ``flow_height_threshold_m`` (-1: never).
- ``edge_hi`` / ``edge_lo``: the current outermost particle edges ``x_p +- h_p / 2`` in the column,
  and ``front_hi`` / ``front_lo`` their running extremes over columns whose flow height exceeded
  the threshold (the run-out of the peak-height envelope, to the particle edge, not the cell).

Per raster cell ``(i, j)``: running maxima of the speed ``|v_p|``, the kinetic energy per unit
volume ``rho_p |v_p|^2 / 2`` (J/m3) and the impact pressure ``rho_p |v_p|^2`` (Pa) of the particles
whose centres lie in it, and the first update time it held a particle centre (-1: never).

Targets (:class:`solver.config.Target`): a vertical line at ``x_t`` is reached by every particle
whose square spans ``x_t``; its height is the highest such ``y_p + h_p / 2`` less the ground at
``x_t`` (the same rule at the release), its speed and pressure the largest of those particles.
A point ``(x_t, y_t)`` takes its height from the line through it, its speed and pressure from
the particles whose squares contain it, and is reached when one does. Each update appends one
row to a time series: time, total kinetic energy (J/m), largest speed, and per target the
current height, speed and pressure. Targets resolve to the particle edge, not the raster cell.

Sampling error: every value is sampled every ``every_steps`` steps of ``dt`` and at every
output frame, so a peak between two updates is missed by at most its change over
``every_steps * dt`` and an arrival is late by less than ``every_steps * dt``; envelopes are
never below the values of any output frame (each frame is an update).
"""

import math

import numpy as np
from solver.runtime import ti

from solver.config import EnvelopeConfig, Grid
from solver.fieldio import FieldIO
from solver.materials import RIGID

_BIG = 1.0e30
#: Updates whose time-series rows are kept on the device before they are copied to the host.
SERIES_CHUNK = 256
#: Columns of the time series before the per-target triples.
SERIES_HEAD = ("time_s", "kinetic_energy_J_per_m", "max_speed_m_s")
TARGET_QUANTITIES = ("height_m", "speed_m_s", "pressure_pa")


@ti.data_oriented
class Envelopes:
    """Running hazard envelopes of one engine (needs an acquired runtime).

    Parameters
    ----------
    engine : solver.engine.Engine
        Its particle fields ``x``, ``v``, ``m``, ``rho`` and ``active`` are read, never written.
    config : solver.config.EnvelopeConfig
    grid : solver.config.Grid
        The raster covers the grid box from its origin, in the engine's coordinates.
    offset_m : (2,) float, m
        Where the engine's coordinate origin lies in the project's (the grid origin when the
        engine works relative to it, as :class:`solver.simulation.Simulation` does). The targets
        and ``config.ground_m`` are given in the project's coordinates, and :meth:`snapshot`
        returns positions and heights in them; inside, everything is in the engine's.
    """

    def __init__(self, engine, config: EnvelopeConfig, grid: Grid, offset_m=(0.0, 0.0)):
        if config.cell_size_m <= 0:
            raise ValueError(f"envelope cell size must be > 0, got {config.cell_size_m}")
        if config.every_steps < 1:
            raise ValueError(f"envelope update interval must be >= 1 step, got {config.every_steps}")
        self.engine = engine
        self.config = config
        self.n = engine.n
        self.cell_size_m = float(config.cell_size_m)
        self.origin_m = (float(grid.origin_m[0]), float(grid.origin_m[1]))
        self.offset_m = (float(offset_m[0]), float(offset_m[1]))
        width = grid.cells[0] * grid.cell_size_m
        height = grid.cells[1] * grid.cell_size_m
        self.shape = (max(1, math.ceil(width / self.cell_size_m - 1e-9)),
                      max(1, math.ceil(height / self.cell_size_m - 1e-9)))
        nx, ny = self.shape
        self.targets = tuple(config.targets)
        self.n_targets = len(self.targets)
        nt = max(1, self.n_targets)
        self.series_width = len(SERIES_HEAD) + len(TARGET_QUANTITIES) * self.n_targets

        self.floor = ti.field(float, nx)
        self.ground = ti.field(float, nx)
        self.top = ti.field(float, nx)
        self.edge_hi = ti.field(float, nx)
        self.edge_lo = ti.field(float, nx)
        self.peak_height = ti.field(float, nx)
        self.arrival = ti.field(float, nx)
        self.front = ti.field(float, 2)  # running max of edge_hi, min of edge_lo (thick columns)
        self.max_speed = ti.field(float, (nx, ny))
        self.max_energy = ti.field(float, (nx, ny))
        self.max_pressure = ti.field(float, (nx, ny))
        self.cell_arrival = ti.field(float, (nx, ny))
        self.t_xy = ti.Vector.field(2, float, nt)
        self.t_point = ti.field(ti.i32, nt)
        self.t_ground = ti.field(float, nt)
        self.t_top = ti.field(float, nt)
        self.t_now = ti.Vector.field(3, float, nt)  # height, speed, pressure
        self.t_max = ti.Vector.field(3, float, nt)
        self.t_arrival = ti.field(float, nt)
        self.t_hit = ti.field(ti.i32, nt)
        self.energy = ti.field(float, ())
        self.speed_now = ti.field(float, ())
        self.rows = ti.field(float, (SERIES_CHUNK, self.series_width))

        # every field the host reads or writes, moved by one kernel (see solver.fieldio)
        self._io = FieldIO({name: getattr(self, name) for name in ("floor", "t_xy", "t_point", "rows") + self.FIELDS})
        floor = np.full(nx, self.origin_m[1])
        if config.ground_m is not None:
            g = np.asarray(config.ground_m, dtype=float)
            if g.shape != (nx,):
                raise ValueError(f"ground_m must have {nx} values (one per raster column), got {g.shape}")
            floor = np.maximum(floor, g - self.offset_m[1])
        self._floor = floor.astype(engine.np_float)
        xy = np.zeros((nt, 2))
        point = np.zeros(nt, np.int32)
        for k, t in enumerate(self.targets):
            xy[k] = (t.x_m - self.offset_m[0], t.y_m - self.offset_m[1] if t.y_m is not None else 0.0)
            point[k] = t.y_m is not None
        self._io.write({"floor": self._floor, "t_xy": xy.astype(engine.np_float), "t_point": point})
        self.reset()

    # ------------------------------------------------------------------ host side
    def reset(self) -> None:
        """Forget everything accumulated (before the release)."""
        self._io.write({
            "peak_height": 0.0, "max_speed": 0.0, "max_energy": 0.0, "max_pressure": 0.0, "t_max": 0.0,
            "arrival": -1.0, "cell_arrival": -1.0, "t_arrival": -1.0,
            "front": np.array([-_BIG, _BIG], self.engine.np_float), "ground": self._floor, "t_ground": 0.0,
            "t_hit": 0,
        })
        self.started = False
        self.release_time_s = 0.0
        self.time_s = 0.0
        self.steps = 0            # steps since the release
        self._updated_at = -1     # value of ``steps`` at the last update
        self._slot = 0            # next row of the device series chunk
        self._series: list[np.ndarray] = []
        self.initial: dict[str, np.ndarray] = {}

    def start(self, time_s: float) -> None:
        """The release: take the ground surface and the initial particle state, then update once."""
        self.initial = self._particles()
        self.started = True
        self.release_time_s = float(time_s)
        self.update(time_s, release=True)

    def after_step(self, time_s: float) -> None:
        """Count one step; update every ``every_steps`` steps."""
        if not self.started:
            return
        self.steps += 1
        if self.steps - self._updated_at >= self.config.every_steps:
            self.update(time_s)

    def sync(self, time_s: float) -> None:
        """Update unless the last update was at this step (called at every output frame)."""
        if self.started and self._updated_at != self.steps:
            self.update(time_s)

    def update(self, time_s: float, release: bool = False) -> None:
        """One update of every envelope at simulated time ``time_s`` (s); at the ``release`` it
        also takes the surface as the ground."""
        e = self.engine
        self._update(e.x, e.v, e.m, e.rho, e.active, float(time_s), float(self.config.flow_height_threshold_m),
                     self._slot, int(release))
        self.time_s = float(time_s)
        self._updated_at = self.steps
        self._slot += 1
        if self._slot == SERIES_CHUNK:
            self._flush()

    def _flush(self) -> None:
        if self._slot:
            self._series.append(self._io.read(("rows",))["rows"][: self._slot].astype(float))
            self._slot = 0

    def series(self) -> np.ndarray:
        """The time series so far, (updates, ``series_width``): columns ``SERIES_HEAD`` then per
        target ``TARGET_QUANTITIES``."""
        self._flush()
        if not self._series:
            return np.zeros((0, self.series_width))
        if len(self._series) > 1:
            self._series = [np.concatenate(self._series)]
        return self._series[0].copy()

    def series_columns(self) -> tuple[str, ...]:
        cols = list(SERIES_HEAD)
        for t in self.targets:
            cols += [f"{t.name}:{q}" for q in TARGET_QUANTITIES]
        return tuple(cols)

    def snapshot(self) -> dict[str, np.ndarray | float | int | bool]:
        """Host copies of every envelope, the time series, the initial and the current particle state.

        Returns
        -------
        dict
            ``origin_m``, ``cell_size_m``, ``shape`` (nx, ny); per column (nx,): ``floor_m``,
            ``ground_m``, ``surface_m`` (now; NaN where empty), ``edge_hi_m``, ``edge_lo_m`` (NaN
            where empty), ``peak_height_m``, ``arrival_s`` (NaN: never); per cell (nx, ny):
            ``max_speed_m_s``, ``max_energy_J_m3``, ``max_pressure_pa``, ``cell_arrival_s``;
            ``front_hi_m``, ``front_lo_m`` (NaN: no column was reached); per target (nt,):
            ``target_ground_m``, ``target_max`` (nt, 3), ``target_arrival_s``; ``series``,
            ``series_columns``; ``initial`` and ``current`` particle states (``positions_m``,
            ``volumes_m2``, ``active``); ``release_time_s``, ``time_s``, ``steps``, ``started``.
        """
        nt = self.n_targets
        host = self._io.read(("floor",) + self.FIELDS)  # one kernel launch for all of them

        def col(name):
            return host[name].astype(float)

        top = col("top")
        empty = top <= -0.5 * _BIG
        surface = np.where(empty, np.nan, top)
        arrival = col("arrival")
        cell_arrival = col("cell_arrival")
        front = col("front")
        edge_hi = np.where(empty, np.nan, col("edge_hi"))
        edge_lo = np.where(empty, np.nan, col("edge_lo"))
        t_arr = col("t_arrival")[:nt]
        ox, oy = self.offset_m  # back to the project's coordinates

        def moved(state):
            return {**state, "positions_m": state["positions_m"] + np.asarray(self.offset_m)} if state else {}

        return {
            "origin_m": (self.origin_m[0] + ox, self.origin_m[1] + oy),
            "cell_size_m": self.cell_size_m,
            "shape": self.shape,
            "floor_m": col("floor") + oy,
            "ground_m": col("ground") + oy,
            "surface_m": surface + oy,
            "edge_hi_m": edge_hi + ox,
            "edge_lo_m": edge_lo + ox,
            "peak_height_m": col("peak_height"),
            "arrival_s": np.where(arrival < 0, np.nan, arrival),
            "max_speed_m_s": col("max_speed"),
            "max_energy_J_m3": col("max_energy"),
            "max_pressure_pa": col("max_pressure"),
            "cell_arrival_s": np.where(cell_arrival < 0, np.nan, cell_arrival),
            "front_hi_m": float(front[0]) + ox if front[0] > -0.5 * _BIG else float("nan"),
            "front_lo_m": float(front[1]) + ox if front[1] < 0.5 * _BIG else float("nan"),
            "target_ground_m": col("t_ground")[:nt] + oy,
            "target_max": col("t_max")[:nt],
            "target_arrival_s": np.where(t_arr < 0, np.nan, t_arr),
            "series": self.series(),
            "series_columns": self.series_columns(),
            "initial": moved({k: v.copy() for k, v in self.initial.items()}),
            "current": moved(self._particles()),
            "release_time_s": self.release_time_s,
            "time_s": self.time_s,
            "steps": self.steps,
            "started": self.started,
            "every_steps": self.config.every_steps,
        }

    def _particles(self) -> dict[str, np.ndarray]:
        """The engine's particle state the envelopes record: positions (m), volumes (m2), active."""
        got = self.engine.state(("x", "m", "rho", "active", "mat"))
        rigid = self.engine.materials.host["model"][got["mat"]] == RIGID  # a rigid body is no flow
        return {"positions_m": got["x"].astype(float),
                "volumes_m2": got["m"].astype(float) / got["rho"].astype(float),
                "active": got["active"].astype(bool) & ~rigid}

    #: Device fields a checkpoint holds (with the host counters, the series and the initial state).
    FIELDS = ("ground", "top", "edge_hi", "edge_lo", "peak_height", "arrival", "front", "max_speed",
              "max_energy", "max_pressure", "cell_arrival", "t_ground", "t_top", "t_now", "t_max", "t_arrival",
              "t_hit")

    def state(self) -> dict[str, np.ndarray]:
        """Everything needed to continue the envelopes after a restart (numpy arrays only)."""
        out = {f"field_{name}": value for name, value in self._io.read(self.FIELDS).items()}
        out["series"] = self.series()
        out["counters"] = np.array([float(self.started), self.release_time_s, self.time_s, float(self.steps),
                                    float(self._updated_at)])
        for k, v in self.initial.items():
            out[f"initial_{k}"] = v
        return out

    def load_state(self, state: dict[str, np.ndarray]) -> None:
        """Restore what :meth:`state` saved (same raster, targets and particle count)."""
        values = {}
        for name in self.FIELDS:
            value = np.asarray(state[f"field_{name}"])
            if tuple(value.shape) != self._io.shapes[name]:
                raise ValueError(f"envelope field {name!r} has shape {value.shape}, expected {self._io.shapes[name]}")
            values[name] = value
        self._io.write(values)
        series = np.asarray(state["series"], dtype=float)
        if series.ndim != 2 or series.shape[1] != self.series_width:
            raise ValueError(f"envelope series has shape {series.shape}, expected (n, {self.series_width})")
        self._series = [series] if len(series) else []
        self._slot = 0
        started, release, time_s, steps, updated = (float(v) for v in state["counters"])
        self.started = bool(started)
        self.release_time_s, self.time_s = release, time_s
        self.steps, self._updated_at = int(steps), int(updated)
        self.initial = {k[len("initial_"):]: np.asarray(v) for k, v in state.items() if k.startswith("initial_")}

    # ------------------------------------------------------------------ kernels
    @ti.func
    def _column(self, xp):
        i = ti.cast(ti.floor((xp[0] - self.origin_m[0]) / self.cell_size_m), ti.i32)
        return ti.min(ti.max(i, 0), self.shape[0] - 1)

    @ti.func
    def _row(self, xp):
        j = ti.cast(ti.floor((xp[1] - self.origin_m[1]) / self.cell_size_m), ti.i32)
        return ti.min(ti.max(j, 0), self.shape[1] - 1)

    @ti.func
    def _raise(self, field: ti.template(), I, value):
        if value > field[I]:
            ti.atomic_max(field[I], value)

    @ti.func
    def _clear_current(self):
        # small loops run in one thread: on a CPU with few threads waking the pool costs more
        ti.loop_config(serialize=True)
        for i in range(self.shape[0]):
            self.top[i] = -_BIG
            self.edge_hi[i] = -_BIG
            self.edge_lo[i] = _BIG
        ti.loop_config(serialize=True)
        for k in range(self.n_targets):
            self.t_top[k] = -_BIG
            self.t_now[k] = ti.Vector.zero(float, 3)
            self.t_hit[k] = 0

    @ti.kernel
    def _update(self, x: ti.template(), v: ti.template(), m: ti.template(), rho: ti.template(),
                active: ti.template(), t: float, threshold: float, slot: ti.i32, release: ti.i32):
        # ``release``: this update is the release's, whose surface is also the ground (the
        # reference of every height); one kernel for both saves compiling a second one per run
        self._clear_current()
        self.energy[None] = 0.0
        self.speed_now[None] = 0.0
        for p in range(self.n):
            if active[p] != 0 and not self.engine.rigid.is_rigid(p):  # a rigid body is no flow
                xp = x[p]
                vp = v[p]
                r = rho[p]
                half = 0.5 * ti.sqrt(m[p] / r)
                v2 = vp.dot(vp)
                speed = ti.sqrt(v2)
                i = self._column(xp)
                j = self._row(xp)
                # read before the atomic: on a CPU an atomic max is a compare-and-swap loop, and most
                # particles do not raise a running maximum
                self._raise(self.top, i, xp[1] + half)
                self._raise(self.edge_hi, i, xp[0] + half)
                if xp[0] - half < self.edge_lo[i]:
                    ti.atomic_min(self.edge_lo[i], xp[0] - half)
                ij = ti.Vector([i, j])
                self._raise(self.max_speed, ij, speed)
                self._raise(self.max_energy, ij, 0.5 * r * v2)
                self._raise(self.max_pressure, ij, r * v2)
                if self.cell_arrival[i, j] < 0.0:
                    self.cell_arrival[i, j] = t  # every writer writes the same value
                self.energy[None] += 0.5 * m[p] * v2
                if speed > self.speed_now[None]:
                    ti.atomic_max(self.speed_now[None], speed)
                for k in range(self.n_targets):
                    txy = self.t_xy[k]
                    if ti.abs(xp[0] - txy[0]) <= half:
                        ti.atomic_max(self.t_top[k], xp[1] + half)
                        if self.t_point[k] == 0 or ti.abs(xp[1] - txy[1]) <= half:
                            ti.atomic_max(self.t_now[k][1], speed)
                            ti.atomic_max(self.t_now[k][2], r * v2)
                            self.t_hit[k] = 1
        ti.loop_config(serialize=True)
        for i in range(self.shape[0]):
            if release != 0:
                self.ground[i] = ti.max(self.floor[i], self.top[i])
            h = ti.max(self.top[i] - self.ground[i], 0.0)
            ti.atomic_max(self.peak_height[i], h)
            if h > threshold:
                if self.arrival[i] < 0.0:
                    self.arrival[i] = t
                ti.atomic_max(self.front[0], self.edge_hi[i])
                ti.atomic_min(self.front[1], self.edge_lo[i])
        ti.loop_config(serialize=True)
        for k in range(self.n_targets):
            if release != 0:
                self.t_ground[k] = ti.max(self.floor[self._column(self.t_xy[k])], self.t_top[k])
            h = ti.max(self.t_top[k] - self.t_ground[k], 0.0)
            self.t_now[k][0] = h
            reached = h > threshold
            if self.t_point[k] != 0:
                reached = self.t_hit[k] != 0
            if reached and self.t_arrival[k] < 0.0:
                self.t_arrival[k] = t
            for q in ti.static(range(3)):
                ti.atomic_max(self.t_max[k][q], self.t_now[k][q])
        self.rows[slot, 0] = t
        self.rows[slot, 1] = self.energy[None]
        self.rows[slot, 2] = self.speed_now[None]
        ti.loop_config(serialize=True)
        for k in range(self.n_targets):
            for q in ti.static(range(3)):
                self.rows[slot, 3 + 3 * k + q] = self.t_now[k][q]
