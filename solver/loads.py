"""The engine's load component: surcharges, external forces carried by particles.

A surcharge (:class:`solver.config.Surcharge`) is a distributed load on the ground surface
between two x. At the start of a stage the run (solver/simulation.py) gives each particle of the
surface under it a force (N per metre out of plane), its share of the load
(:func:`surface_forces`); the particle carries that force wherever it moves, as it carries its
weight. This component holds the forces on the device: each particle's force at the stage's
start and at its end, and how far the stage has gone from one to the other (moved on each step
by ``dt / duration``, as the ground water's lines are), so that a load that grows over a stage
costs no launch of its own. The force passes add ``w_ip f_p`` to each node of a particle's
stencil, as they add its weight ``w_ip m_p g`` (eq 10). Built only where a run has a surcharge:
dry, unloaded runs compile none of it.

Which particles carry a load: the particles are sorted into columns one particle spacing ``h``
wide (``h = sqrt(V)``, the lattice's columns, aligned on the grid's origin) and the uppermost
particle of each column (highest y) is the surface there. Each surface particle stands for the
stretch of x from half-way to its left neighbour to half-way to its right one (the first and the
last to their columns' outer edges, or ``h / 2`` beyond themselves where that is farther); its
force is the load's pressure integrated over that stretch's part of the segment, along gravity.
So the forces sum to the load's resultant wherever the ground runs under the whole segment (a
column without particles inside it is bridged by its neighbours); a load beyond the ground's end
falls on nothing and is reported.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from solver.config import Surcharge
from solver.runtime import ti


def surface_particles(positions_m: np.ndarray, active: np.ndarray, spacing_m: float, lo_m: float,
                      hi_m: float) -> tuple[np.ndarray, np.ndarray]:
    """The uppermost active particle of each column that reaches into ``[lo_m, hi_m]``.

    Columns are ``spacing_m`` wide, column ``k`` from ``k spacing_m`` to ``(k + 1) spacing_m``
    (in the coordinates of ``positions_m``: the engine's, relative to the grid origin, where the
    lattice's columns lie so).

    Parameters
    ----------
    positions_m : (N, 2) float, m
    active : (N,) bool
    spacing_m : float, m
    lo_m, hi_m : float, m

    Returns
    -------
    particles : numpy.ndarray, (K,) int
        Particle indices, sorted by x.
    columns : numpy.ndarray, (K,) int
        Their columns.
    """
    x = np.asarray(positions_m, dtype=np.float64)
    h = float(spacing_m)
    near = np.flatnonzero(np.asarray(active, bool) & (x[:, 0] >= lo_m - h) & (x[:, 0] <= hi_m + h))
    if near.size == 0:
        return near, near
    column = np.floor(x[near, 0] / h).astype(np.int64)
    # per column the highest particle: sort by column, then by height, take each column's last
    order = np.lexsort((x[near, 1], column))
    col_sorted = column[order]
    last = np.r_[col_sorted[1:] != col_sorted[:-1], True]
    top, cols = near[order[last]], col_sorted[last]
    by_x = np.argsort(x[top, 0], kind="stable")
    return top[by_x], cols[by_x]


def surface_forces(positions_m: np.ndarray, active: np.ndarray, spacing_m: float,
                   surcharges: Sequence[Surcharge], down: Sequence[float],
                   offset_m: Sequence[float] = (0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """Each particle's share of the surcharges (see the module docstring).

    Parameters
    ----------
    positions_m : (N, 2) float, m
        Particle positions; ``positions_m + offset_m`` are in the surcharges' (project) coordinates.
    active : (N,) bool
    spacing_m : float, m
        The particle spacing (the columns' width).
    surcharges : sequence of solver.config.Surcharge
    down : (2,) float
        The unit vector along gravity, the loads' direction.
    offset_m : (2,) float, m
        The grid origin when ``positions_m`` are the engine's (relative) positions.

    Returns
    -------
    forces : numpy.ndarray, (N, 2) float64, N/m
    carried : numpy.ndarray, (len(surcharges),) float64, N/m
        The force each surcharge gives the particles (its resultant, unless part of the segment
        lies beyond the ground).
    """
    x = np.asarray(positions_m, dtype=np.float64)
    ox = float(np.asarray(offset_m, dtype=np.float64)[0])
    forces = np.zeros((len(x), 2))
    carried = np.zeros(len(surcharges))
    d = np.asarray(down, dtype=np.float64)
    h = float(spacing_m)
    for k, load in enumerate(surcharges):
        lo, hi = load.from_m - ox, load.to_m - ox
        top, cols = surface_particles(x, active, h, lo, hi)
        if top.size == 0:
            continue
        xs = x[top, 0]
        # each stands for the stretch half-way to its neighbours; the outer ones to their column's edge
        mids = 0.5 * (xs[1:] + xs[:-1])
        left = np.r_[min(xs[0] - 0.5 * h, cols[0] * h), mids]
        right = np.r_[mids, max(xs[-1] + 0.5 * h, (cols[-1] + 1) * h)]
        a = np.maximum(left, lo)
        b = np.minimum(right, hi)
        length = np.maximum(b - a, 0.0)
        share = length * load.pressure_at(0.5 * (a + b) + ox)  # exact for a linear pressure
        forces[top] += share[:, None] * d[None, :]
        carried[k] = float(share.sum())
    return forces, carried


@ti.data_oriented
class Loads:
    """Per-particle external forces (N/m) on the device, from a stage's start to its end.

    Parameters
    ----------
    n_particles : int
    np_float : numpy float type of the run's precision
    """

    def __init__(self, n_particles: int, np_float=np.float32):
        self.np_float = np_float
        self.n = max(1, int(n_particles))
        self.f_from = ti.Vector.field(2, float, self.n)
        self.f_to = ti.Vector.field(2, float, self.n)
        #: how far the stage has gone from ``f_from`` to ``f_to`` (0-1), and by how much a second
        self.fraction = ti.field(float, ())
        self.rate = ti.field(float, ())
        self.set_forces(None, None, 0.0)

    # ------------------------------------------------------------------ host side
    def set_forces(self, start: np.ndarray | None, end: np.ndarray | None, duration_s: float) -> None:
        """Move the forces from ``start`` to ``end`` (each (N, 2) N/m, None: zeros) over
        ``duration_s`` (0: be at ``end`` now)."""
        zero = np.zeros((self.n, 2), dtype=self.np_float)
        end_f = zero if end is None else np.asarray(end, dtype=self.np_float).reshape(self.n, 2)
        start_f = end_f if duration_s <= 0.0 else (zero if start is None else
                                                    np.asarray(start, dtype=self.np_float).reshape(self.n, 2))
        self.f_from.from_numpy(start_f)
        self.f_to.from_numpy(end_f)
        moving = duration_s > 0.0
        self.fraction[None] = 0.0 if moving else 1.0
        self.rate[None] = 1.0 / duration_s if moving else 0.0

    def forces(self) -> np.ndarray:
        """Each particle's force now (N/m, (N, 2) float64)."""
        s = float(self.fraction[None])
        return (1.0 - s) * self.f_from.to_numpy().astype(np.float64) + s * self.f_to.to_numpy().astype(np.float64)

    def state(self) -> dict[str, np.ndarray]:
        """What a checkpoint keeps: the forces at the stage's start and end and how far it has gone."""
        return {"f_from": self.f_from.to_numpy(), "f_to": self.f_to.to_numpy(),
                "fraction": np.array([self.fraction[None]], dtype=np.float64),
                "rate": np.array([self.rate[None]], dtype=np.float64)}

    def load_state(self, state: dict[str, np.ndarray]) -> None:
        if "f_from" in state:
            self.f_from.from_numpy(np.asarray(state["f_from"], dtype=self.np_float))
            self.f_to.from_numpy(np.asarray(state["f_to"], dtype=self.np_float))
            self.fraction[None] = float(np.asarray(state["fraction"]).ravel()[0])
            self.rate[None] = float(np.asarray(state["rate"]).ravel()[0])

    # ------------------------------------------------------------------ device side
    @ti.func
    def begin_step(self, dt):
        """Move the forces on by one step (once per step, from a serial loop)."""
        self.fraction[None] = ti.min(1.0, self.fraction[None] + self.rate[None] * dt)

    @ti.func
    def force(self, p):
        """Particle p's external force now (N/m)."""
        s = self.fraction[None]
        return (1.0 - s) * self.f_from[p] + s * self.f_to[p]
