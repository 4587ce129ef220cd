"""Loads in the solver (solver/loads.py, solver.config.body_force_m_s2): surcharges and seismic.

- Which particles carry a surcharge and how much: the uppermost particle of each column under
  the segment, each its share of the segment; the shares sum to the resultant (pressure times
  length, the mean of a linear pressure times length) exactly wherever ground runs under the
  whole segment, and less by the part of the segment beyond the ground's end.
- The seismic body force: ``g + k_h |g| h + k_v |g| u`` (u up, h across gravity), gravity's own
  floats without coefficients.
- One-dimensional compression of a laterally confined elastic column under a uniform surcharge
  (slip sides, fixed base): in equilibrium ``sigma_yy = -(q + rho g z)`` at depth ``z``. Within
  2 % over each cell's pair of particle rows from two cells below the surface down (the top
  cell's two rows, which carry the point forces, alternate about it: a load on one row of
  particles, the MPM surface layer). Measured at 10 cells: gravity stage (the load ramped with
  gravity) at most 0.35 %, then a dynamic stage that ramps it to 2 q, at most 0.4 %; mpm's
  six-stage force scatter the same.
- A run under loads restored from a checkpoint in the middle of a ramp goes on bit for bit.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from solver.config import (
    Boundary,
    Grid,
    Material,
    Numerics,
    Output,
    Particles,
    Seismic,
    SimulationConfig,
    Stage,
    Surcharge,
    body_force_m_s2,
)
from solver.loads import surface_forces, surface_particles

H = 0.1  # particle spacing of the lattice below (m)


def lattice(width, height, h=H, x0=0.0):
    xs = x0 + (np.arange(round(width / h)) + 0.5) * h
    ys = (np.arange(round(height / h)) + 0.5) * h
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    return np.c_[X.ravel(), Y.ravel()]


@pytest.mark.parametrize("lo, hi", [(0.0, 2.0), (0.33, 1.27), (0.05, 0.06), (1.0, 1.95)])
@pytest.mark.parametrize("ends", [(5e3, 5e3), (0.0, 8e3), (12e3, 2e3)])
def test_the_surface_particles_carry_the_resultant(lo, hi, ends):
    pos = lattice(2.0, 1.0)
    load = Surcharge("q", lo, hi, ends[0], ends[1])
    forces, carried = surface_forces(pos, np.ones(len(pos), bool), H, [load], (0.0, -1.0))
    resultant = 0.5 * (ends[0] + ends[1]) * (hi - lo)
    assert carried[0] == pytest.approx(resultant, rel=1e-12)
    assert -forces[:, 1].sum() == pytest.approx(resultant, rel=1e-12)
    assert np.all(forces[:, 0] == 0.0)
    loaded = np.flatnonzero(forces[:, 1] != 0.0)
    assert np.allclose(pos[loaded, 1], 0.95)  # the top row only
    # each carries the pressure at its place times its stretch of the segment
    inside = loaded[(pos[loaded, 0] - 0.5 * H >= lo) & (pos[loaded, 0] + 0.5 * H <= hi)]
    assert np.allclose(-forces[inside, 1], load.pressure_at(pos[inside, 0]) * H, rtol=1e-12)


def test_a_load_beyond_the_grounds_end_falls_on_nothing_and_a_gap_is_bridged():
    pos = lattice(2.0, 1.0)
    active = np.ones(len(pos), bool)
    beyond = Surcharge("q", 1.5, 2.5, 1000.0)
    _, carried = surface_forces(pos, active, H, [beyond], (0.0, -1.0))
    assert carried[0] == pytest.approx(500.0, rel=1e-12)
    hole = active & ~((pos[:, 0] > 0.8) & (pos[:, 0] < 1.2))  # four columns gone
    forces, carried = surface_forces(pos, hole, H, [Surcharge("q", 0.5, 1.5, 1000.0)], (0.0, -1.0))
    assert carried[0] == pytest.approx(1000.0, rel=1e-12)
    assert np.all(forces[~hole] == 0.0)


def test_the_surface_is_the_highest_particle_of_each_column_and_the_load_acts_along_gravity():
    rng = np.random.default_rng(3)
    pos = lattice(1.0, 1.0)
    pos[:, 1] += np.where(pos[:, 0] > 0.5, 0.3, 0.0)  # a step in the ground
    order = rng.permutation(len(pos))
    pos = pos[order]
    top, _ = surface_particles(pos, np.ones(len(pos), bool), H, 0.0, 1.0)
    assert len(top) == 10 and np.all(np.diff(pos[top, 0]) > 0)
    assert np.allclose(pos[top, 1], np.where(pos[top, 0] > 0.5, 1.25, 0.95))
    b = math.radians(30.0)
    down = (math.sin(b), -math.cos(b))
    forces, carried = surface_forces(pos, np.ones(len(pos), bool), H, [Surcharge("q", 0.0, 1.0, 100.0)], down)
    assert forces.sum(axis=0) == pytest.approx([100.0 * math.sin(b), -100.0 * math.cos(b)], rel=1e-12)
    assert carried[0] == pytest.approx(100.0)


def test_particles_of_the_grid_origin_offset_and_two_loads_add():
    pos = lattice(2.0, 1.0)
    loads = [Surcharge("a", 0.0, 1.0, 100.0), Surcharge("b", 0.5, 2.0, 50.0)]
    f0, _ = surface_forces(pos + 1000.0, np.ones(len(pos), bool), H, loads, (0.0, -1.0), offset_m=(-1000.0, -1000.0))
    f1, carried = surface_forces(pos, np.ones(len(pos), bool), H, loads, (0.0, -1.0))
    assert np.allclose(f0, f1)
    assert carried == pytest.approx([100.0, 75.0])


@pytest.mark.parametrize("k_h, k_v, direction", [(0.15, 0.0, 1.0), (0.2, 0.1, -1.0), (0.0, -0.2, 1.0),
                                                 (0.3, 0.05, 1.0)])
def test_the_seismic_body_force(k_h, k_v, direction):
    g = 9.81
    assert body_force_m_s2((0.0, -g), Seismic(k_h, k_v, direction)) == pytest.approx(
        (direction * k_h * g, -(1.0 - k_v) * g), rel=1e-12, abs=1e-12)
    b = math.radians(25.0)
    tilted = (g * math.sin(b), -g * math.cos(b))
    up = np.array([-math.sin(b), math.cos(b)])
    across = np.array([up[1], -up[0]])
    got = np.array(body_force_m_s2(tilted, Seismic(k_h, k_v, direction)))
    assert got @ across == pytest.approx(direction * k_h * g, abs=1e-12)
    assert got @ up == pytest.approx(-(1.0 - k_v) * g, rel=1e-12)


def test_without_coefficients_the_body_force_is_gravitys_own_floats():
    for gravity in ((0.0, -9.81), (4.1457, -8.891)):
        for seismic in (None, Seismic(0.0, 0.0)):
            got = body_force_m_s2(gravity, seismic)
            assert got == gravity and all(type(v) is float for v in got)


def column(scheme: str, q: float):
    """A laterally confined elastic column 0.4 m wide, 1 m high, 10 cells, under a surcharge."""
    dx, width, height, rho = 0.1, 0.4, 1.0, 2000.0
    pos = lattice(width, height, h=dx / 2)
    particles = Particles(pos, np.full(len(pos), (dx / 2) ** 2), np.zeros(len(pos), np.int32))
    material = Material("e", "linear-elastic", rho, 10e6, 0.3)
    load, doubled = Surcharge("q", 0.0, width, q), Surcharge("q", 0.0, width, 2.0 * q)
    grid = Grid((0.0, 0.0), (width, height + 3 * dx), dx, left=Boundary("slip"), right=Boundary("slip"),
                bottom=Boundary("fixed"), top=Boundary("open"))
    stages = (Stage("settle", "gravity", duration_s=1.0, damping=0.7, surcharges=(load,)),
              Stage("load", "dynamic", duration_s=1.0, damping=0.7, surcharges=(doubled,), surcharges_from=(load,)))
    config = SimulationConfig(grid, (material,), stages if scheme == "apic-affine" else stages[:1],
                              numerics=Numerics(scheme=scheme, cfl=0.5, precision="f64", arch="cpu"),
                              output=Output(interval_s=0.5, fields=("stress",)))
    return config, particles, rho * 9.81 * (height - pos[:, 1])


def _cell_rows(frame, expected, depth_cells=2):
    """Per cell's pair of particle rows from ``depth_cells`` below the surface down: the mean
    sigma_yy over the mean expected one, less 1."""
    y = frame.fields["positions"][:, 1]
    s = frame.fields["stress"][:, 1]
    errors = []
    for k in range(depth_cells, 10):
        band = (y < 1.0 - k * 0.1) & (y > 1.0 - (k + 1) * 0.1)
        errors.append(s[band].mean() / expected[band].mean() - 1.0)
    return np.array(errors)


@pytest.mark.parametrize("scheme", ["apic-affine", "mpm"])
def test_a_confined_column_under_a_surcharge_carries_it_in_one_dimensional_compression(scheme):
    from solver.simulation import Simulation

    q = 20e3
    config, particles, weight = column(scheme, q)
    with Simulation(config, particles) as sim:
        ends = {}
        for frame in sim.run():
            ends[frame.diagnostics.stage_index] = frame
            if frame.diagnostics.stage_index == 1 and frame.diagnostics.stage_time_s == pytest.approx(0.5):
                # half-way through the ramp from q to 2 q
                assert -sim.surcharge_forces()[:, 1].sum() == pytest.approx(1.5 * q * 0.4, rel=1e-6)
        forces = sim.surcharge_forces()
    last = 2.0 if scheme == "apic-affine" else 1.0
    assert -forces[:, 1].sum() == pytest.approx(last * q * 0.4, rel=1e-9)
    assert sim.equilibrium["unbalanced_force_ratio"] < 0.01
    errors = _cell_rows(ends[0], -(q + weight))
    assert np.abs(errors).max() < 0.02, errors
    if scheme == "apic-affine":
        errors = _cell_rows(ends[1], -(2.0 * q + weight))
        assert np.abs(errors).max() < 0.02, errors


def test_a_run_under_loads_restored_from_a_checkpoint_goes_on_bit_for_bit():
    """The tiny column with a surcharge on its gravity stage, growing to twice over the dynamic stage
    that also has seismic coefficients: restored from a checkpoint in the middle of that stage's
    ramp, the run gives the same frames (the forces and how far they have grown are in the
    checkpoint; the stage's body force is the stage's again)."""
    from projects.build import resolve
    from projects.document import load_project
    from solver.simulation import Simulation
    from tests.conftest import TINY_PROJECT
    from tests.unit.test_solver_checkpoint import SETS, _frames_and_checkpoints, _same

    loads = ['stages.0.surcharges=[{name="top", from_m=0.0, to_m=0.12, pressure_pa=500.0}]',
             'stages.1.surcharges=[{name="top", from_m=0.0, to_m=0.12, pressure_pa=1000.0, ramp=true}]',
             'stages.1.seismic={k_h=0.1, towards="right"}']
    resolved = resolve(load_project(TINY_PROJECT, [*SETS, *loads]))
    assert resolved.config.stages[1].surcharges_from is not None and resolved.config.stages[1].seismic is not None
    frames, checkpoints, message = _frames_and_checkpoints(resolved)
    inside = [i for i, (_, phase) in sorted(checkpoints.items())
              if phase == "loop" and frames[i].diagnostics.stage_index == 1]
    index = inside[len(inside) // 2]
    with Simulation(resolved.config, resolved.particles) as sim:
        sim.restore(checkpoints[index][0])
        rest = list(sim.run())
        assert sim.message == message
    assert len(rest) == len(frames) - index - 1
    for a, b in zip(frames[index + 1:], rest):
        _same(a, b)
