"""Periodic left and right sides (docs/solver.md, periodic sides): the grid nodes across the periodic
line are one, material leaving through one side re-enters through the other.

Per scheme, precision and scatter (every scheme, f32 and f64, the three scatters), one model: a
uniform elastic layer (E = 10 MPa, nu = 0.3, 2000 kg/m3) 8 cells thick and 4 cells wide on a
slip base, with periodic sides.

- Under gravity (a damped gravity stage) it must stay a uniform layer with no end: the vertical
  stress ``-rho g (H - y)`` within the weight of half a cell, ``rho g dx / 2`` (the error of the
  particle rows next to the base and the top, as with any closed side), the horizontal stress ``nu / (1 - nu)`` times the vertical one (plane-strain K0 of an
  elastic layer that cannot strain sideways) and no shear stress within 1e-3 relative (1e-2 for
  the f32 mpm scheme), the particles next to the sides like those in the middle, and no lateral
  movement (below 1e-4 cell; with open or slip sides a free layer spreads).
- Then, without gravity, the same particles as a layer moving along the base with a wave on top
  of a mean speed (``v = v0 + a sin(2 pi x / L)``, undamped, crossing the period twice): the
  x-momentum (which the slip base cannot change) is conserved to round-off (1e-5 relative in
  f32, 1e-10 in f64), the grid's canonical nodes carry the whole mass, no particle is lost,
  every particle stays in the grid box, and the displacement goes on through the crossing
  (its mean is ``v0 t`` within a thousandth of the distance); a checkpoint taken then and
  restored repeats the next steps.
"""

import math

import numpy as np
import pytest

from solver import runtime
from solver.config import Boundary, Grid, Material, Numerics, Output, Particles, SimulationConfig, Stage
from solver.engine import PAD
from solver.simulation import Simulation

DX = 0.25
WIDTH, HEIGHT = 4, 8  # cells
RHO, E, NU, G = 2000.0, 1e7, 0.3, 9.81

#: every scheme, precision and scatter once (each case compiles two step kernels: about 10 s of CPU)
CASES = [
    ("mpm", "f32", "serial"),
    ("apic", "f64", "atomic"),
    ("apic-affine", "f64", "split"),
]


def _layer():
    h = DX / 2
    xs, ys = np.meshgrid(np.arange(h / 2, WIDTH * DX, h), np.arange(h / 2, HEIGHT * DX, h), indexing="ij")
    pos = np.c_[xs.ravel(), ys.ravel()]
    return pos, np.full(len(pos), h * h)


def _simulation(scheme, precision, scatter, bottom="slip"):
    grid = Grid((0.0, 0.0), (WIDTH * DX, (HEIGHT + 4) * DX), DX, left=Boundary("periodic"),
                right=Boundary("periodic"), bottom=Boundary(bottom), top=Boundary("open"))
    pos, vol = _layer()
    config = SimulationConfig(grid, (Material("soil", "linear-elastic", RHO, E, NU),),
                              (Stage("gravity", "gravity", 1.0, 0.7),), (0.0, -G),
                              Numerics(scheme=scheme, precision=precision, arch="cpu", scatter=scatter), Output(1.0))
    return Simulation(config, Particles(pos, vol, np.zeros(len(pos), np.int32)))


@pytest.mark.parametrize("scheme, precision, scatter", CASES)
def test_a_periodic_layer_stays_uniform_under_gravity_and_conserves_momentum_across_the_sides(scheme, precision,
                                                                                               scatter):
    runtime.acquire("cpu", precision)
    try:
        with _simulation(scheme, precision, scatter) as sim:
            for _ in sim.run():
                pass
            assert sim.status == "completed", sim.message
            e = sim.engine
            x0, _ = _layer()
            x = e.x.to_numpy().astype(np.float64)
            s = e.s.to_numpy().astype(np.float64)
            top = HEIGHT * DX
            sig_v = -RHO * G * (top - x0[:, 1])
            scale = RHO * G * top
            assert np.abs(s[:, 1] - sig_v).max() < 0.5 * RHO * G * DX  # the rows next to the base and the top
            k0 = NU / (1.0 - NU)
            assert np.abs(s[:, 0] - k0 * s[:, 1]).max() < 1e-3 * scale
            shear_tol = 1e-2 if (scheme, precision) == ("mpm", "f32") else 1e-3
            assert np.abs(s[:, 2]).max() < shear_tol * scale
            # no end: the particles next to the sides carry the stress of those in the middle
            rows = np.floor(x0[:, 1] / (DX / 2)).astype(int)
            for row in np.unique(rows):
                in_row = s[rows == row, 1]
                assert in_row.max() - in_row.min() < 1e-4 * scale
            assert np.abs(x[:, 0] - x0[:, 0]).max() < 1e-4 * DX

            # the same engine: a wave on a layer sliding along the base, no gravity, undamped
            sim.set_materials((Material("soil", "linear-elastic", RHO, E, NU),))
            pos, vol = _layer()
            length = WIDTH * DX
            v0, amp = 5.0, 0.5
            vel = np.c_[v0 + amp * np.sin(2 * math.pi * pos[:, 0] / length), np.zeros(len(pos))]
            e.load_particles(pos, vol, np.zeros(len(pos), np.int32), vel)
            mass = e.m.to_numpy().astype(np.float64)
            p0 = float(np.sum(mass * vel[:, 0]))
            dt = 0.5 * sim.critical_time_step(v0 + amp)
            steps = int(math.ceil(2.0 * length / v0 / dt))
            for _ in range(steps):
                e.step(dt, (0.0, 0.0))
            d = e.diagnostics()
            rel = 1e-5 if precision == "f32" else 1e-10
            assert d["momentum_x"] == pytest.approx(p0, rel=rel)
            assert d["lost"] == 0 and d["active"] == len(pos) and d["unstable"] == 0
            canonical = e.g_mass.to_numpy()[PAD:PAD + WIDTH].astype(np.float64).sum()
            assert canonical == pytest.approx(mass.sum(), rel=rel)
            x = e.x.to_numpy().astype(np.float64)
            assert x[:, 0].min() >= 0.0 and x[:, 0].max() <= length
            travelled = steps * dt * v0
            moved = (x - e.x0.to_numpy())[:, 0]
            assert moved.mean() == pytest.approx(travelled, rel=1e-3)
            assert np.all(moved > 1.5 * length)  # every particle crossed the side and went on

            # a checkpoint holds all of it: restored, the next steps repeat (bit for bit with the
            # serial and split scatters, whose sums come in a fixed order)
            state = e.state()
            for _ in range(20):
                e.step(dt, (0.0, 0.0))
            first = e.x.to_numpy(), e.x0.to_numpy()
            e.load_state(state)
            for _ in range(20):
                e.step(dt, (0.0, 0.0))
            again = e.x.to_numpy(), e.x0.to_numpy()
            for a, b in zip(first, again):
                if scatter == "atomic":
                    np.testing.assert_allclose(a, b, rtol=0, atol=1e-9 * length)
                else:
                    np.testing.assert_array_equal(a, b)
    finally:
        runtime.release()


def test_periodic_sides_come_as_a_left_right_pair():
    def grid(**sides):
        return Grid((0.0, 0.0), (2.0, 2.0), 0.25, **{k: Boundary(v) for k, v in sides.items()})

    assert grid(left="periodic", right="periodic").periodic_problem() is None
    assert "pair" in grid(left="periodic", right="slip").periodic_problem()
    assert "bottom" in grid(left="periodic", right="periodic", bottom="periodic").periodic_problem()
    narrow = Grid((0.0, 0.0), (0.5, 2.0), 0.25, left=Boundary("periodic"), right=Boundary("periodic"))
    assert "at least 3 cells" in narrow.periodic_problem()


@pytest.mark.parametrize("sides, key, words", [
    ({"left": "periodic", "right": "slip"}, "domain.boundaries.right", "periodic sides come as a pair"),
    ({"left": "fixed", "right": "periodic"}, "domain.boundaries.left", "periodic sides come as a pair"),
    ({"top": "periodic"}, "domain.boundaries.top", "only the left and right sides can be periodic"),
    ({"left": "periodic", "right": "periodic", "bottom": "periodic"}, "domain.boundaries.bottom",
     "only the left and right sides"),
])
def test_a_project_with_an_unpaired_periodic_side_is_refused_in_one_line(sides, key, words):
    from projects.schema import ProjectError, validate_project

    data = {"runout": {"schema_version": 1}, "domain": {"size_m": [2.0, 3.0], "cell_size_m": 0.25, "boundaries": sides},
            "materials": {"s": {"model": "linear-elastic", "density_kg_m3": 2000, "youngs_modulus_pa": 1e7,
                                "poisson_ratio": 0.3}},
            "bodies": [{"name": "b", "material": "s", "polygon_m": [[0, 0], [2, 0], [2, 1], [0, 1]]}],
            "stages": [{"type": "gravity", "duration_s": 1.0}]}
    with pytest.raises(ProjectError) as err:
        validate_project(data)
    text = str(err.value)
    assert len(text.splitlines()) == 1 and text.startswith(key) and words in text


def test_a_narrow_periodic_domain_is_refused():
    from projects.schema import ProjectError, validate_project

    data = {"runout": {"schema_version": 1},
            "domain": {"size_m": [0.5, 3.0], "cell_size_m": 0.25,
                       "boundaries": {"left": "periodic", "right": "periodic"}},
            "materials": {"s": {"model": "linear-elastic", "density_kg_m3": 2000, "youngs_modulus_pa": 1e7,
                                "poisson_ratio": 0.3}},
            "bodies": [{"name": "b", "material": "s", "polygon_m": [[0, 0], [0.5, 0], [0.5, 1], [0, 1]]}],
            "stages": [{"type": "gravity", "duration_s": 1.0}]}
    with pytest.raises(ProjectError, match="domain.size_m .*at least 3 cells across"):
        validate_project(data)
