"""Grid transfers and boundary conditions of the engine (unit tests on the kernels, f64, CPU)."""

import math

import numpy as np
import pytest

from solver import runtime
from solver.config import Boundary, Grid, Material
from solver.engine import PAD
from tests.engine_hooks import apply_contacts, grid_totals, transfer_only

# the suite runs a covering sample of each matrix below (tests/conftest.py, RUNOUT_FULL_MATRIX)
pytestmark = pytest.mark.matrix

MAT = (Material("e", "linear-elastic", 1000.0, 1e6, 0.3),)


@pytest.fixture(scope="module", autouse=True)
def _runtime():
    runtime.acquire("cpu", "f64")
    yield
    _WALL_ENGINES.clear()
    runtime.release()


def make_engine(scheme="apic-affine", n=200, seed=0, scatter="auto", **sides):
    from solver.engine import Engine

    grid = Grid((0.0, 0.0), (1.0, 1.0), 0.1, **sides)
    eng = Engine(grid, MAT, n, scheme, np.float64, scatter=scatter)
    rng = np.random.default_rng(seed)
    pos = 0.3 + 0.4 * rng.random((n, 2))
    eng.load_particles(pos, np.full(n, 1e-3), np.zeros(n, np.int32), rng.normal(size=(n, 2)))
    return eng, pos


def test_apic_round_trip_reproduces_an_affine_velocity_field():
    eng, pos = make_engine("apic")
    a = np.array([0.3, -0.2])
    B = np.array([[0.5, -1.2], [0.7, 0.2]])
    v = a + pos @ B.T
    eng.set_velocity(v, np.tile(B, (len(pos), 1, 1)))
    transfer_only(eng)
    st = eng.state(("v", "C", "x"))
    np.testing.assert_allclose(st["v"], v, atol=1e-12)
    np.testing.assert_allclose(st["C"], np.tile(B, (len(pos), 1, 1)), atol=1e-11)
    np.testing.assert_allclose(st["x"], pos, atol=0)


@pytest.mark.parametrize("scheme", ["mpm", "apic", "apic-affine"])
def test_transfers_conserve_mass_and_momentum(scheme):
    eng, pos = make_engine(scheme, seed=1)
    rng = np.random.default_rng(2)
    v = rng.normal(size=(len(pos), 2))
    C = rng.normal(size=(len(pos), 2, 2)) if scheme != "mpm" else None
    eng.set_velocity(v, C)
    st = eng.state(("m",))
    mass = st["m"].sum()
    momentum = (st["m"][:, None] * v).sum(axis=0)
    transfer_only(eng)
    grid_mass, grid_momentum = grid_totals(eng)
    assert grid_mass == pytest.approx(mass, rel=1e-12)
    np.testing.assert_allclose(grid_momentum, momentum, rtol=1e-12, atol=1e-14)
    after = eng.state(("v", "m"))
    np.testing.assert_allclose((after["m"][:, None] * after["v"]).sum(axis=0), momentum, rtol=1e-10, atol=1e-12)


def _grid_velocities(eng, v):
    nodes = eng.nodes
    return np.tile(np.asarray(v, float), (nodes[0], nodes[1], 1))


def test_fixed_wall_stops_its_nodes_and_leaves_the_interior():
    eng, _ = make_engine(left=Boundary("fixed"), right=Boundary("open"), bottom=Boundary("open"), top=Boundary("open"))
    out = apply_contacts(eng, _grid_velocities(eng, [0.5, 0.3]))
    np.testing.assert_array_equal(out[: PAD + 1], 0.0)  # ghost and wall nodes
    np.testing.assert_allclose(out[PAD + 1 :], np.broadcast_to([0.5, 0.3], out[PAD + 1 :].shape))


def test_slip_wall_removes_only_the_velocity_into_the_wall():
    eng, _ = make_engine(left=Boundary("open"), right=Boundary("slip"), bottom=Boundary("open"), top=Boundary("open"))
    wall = PAD + eng.cells[0]
    into = apply_contacts(eng, _grid_velocities(eng, [0.5, -0.3]))
    np.testing.assert_allclose(into[wall:], np.broadcast_to([0.0, -0.3], into[wall:].shape))
    np.testing.assert_allclose(into[:wall], np.broadcast_to([0.5, -0.3], into[:wall].shape))
    away = apply_contacts(eng, _grid_velocities(eng, [-0.5, -0.3]))  # separating: untouched
    np.testing.assert_allclose(away, np.broadcast_to([-0.5, -0.3], away.shape))


def test_friction_wall_reduces_tangential_speed_by_mu_times_normal_and_never_reverses():
    phi = math.radians(20.0)
    mu = math.tan(phi)
    eng, _ = make_engine(bottom=Boundary("friction", phi), left=Boundary("open"), right=Boundary("open"), top=Boundary("open"))
    out = apply_contacts(eng, _grid_velocities(eng, [1.0, -0.5]))
    np.testing.assert_allclose(out[:, : PAD + 1], np.broadcast_to([1.0 - mu * 0.5, 0.0], out[:, : PAD + 1].shape))
    np.testing.assert_allclose(out[:, PAD + 1 :], np.broadcast_to([1.0, -0.5], out[:, PAD + 1 :].shape))
    slow = apply_contacts(eng, _grid_velocities(eng, [-0.1, -0.5]))  # |vt| < mu |vn|: stops, not reversed
    np.testing.assert_allclose(slow[:, : PAD + 1], 0.0, atol=1e-15)


def test_open_sides_do_not_constrain():
    eng, _ = make_engine(left=Boundary("open"), right=Boundary("open"), bottom=Boundary("open"), top=Boundary("open"))
    v = _grid_velocities(eng, [-0.7, -0.2])
    np.testing.assert_allclose(apply_contacts(eng, v), v)


def test_open_boundary_removes_and_counts_leaving_particles():
    from solver.engine import Engine

    grid = Grid((0.0, 0.0), (1.0, 1.0), 0.1, left=Boundary("slip"), right=Boundary("open"),
                bottom=Boundary("slip"), top=Boundary("open"))
    n = 100
    eng = Engine(grid, MAT, n, "apic-affine", np.float64)
    pos = np.c_[np.linspace(0.55, 0.95, n), np.full(n, 0.5)]
    eng.load_particles(pos, np.full(n, 1e-4), np.zeros(n, np.int32), np.tile([2.0, 0.0], (n, 1)))
    for _ in range(300):  # 0.3 s at 2 m/s: everything crosses x = 1 (dt below the critical 2.7e-3 s)
        eng.step(0.001, (0.0, 0.0))
    st = eng.state()
    d = eng.diagnostics()
    assert d["lost"] == n and d["active"] == 0
    assert np.all(st["active"] == 0) and np.all(np.isfinite(st["x"]))
    assert d["kinetic_energy"] == 0.0


def test_closed_walls_keep_particles_inside():
    from solver.engine import Engine

    grid = Grid((0.0, 0.0), (1.0, 1.0), 0.1, left=Boundary("slip"), right=Boundary("slip"),
                bottom=Boundary("fixed"), top=Boundary("slip"))
    n = 50
    eng = Engine(grid, MAT, n, "apic", np.float64)
    pos = np.c_[np.linspace(0.8, 0.95, n), np.full(n, 0.5)]
    eng.load_particles(pos, np.full(n, 1e-4), np.zeros(n, np.int32), np.tile([3.0, 0.0], (n, 1)))
    for _ in range(200):  # dt below the critical 2.7e-3 s
        eng.step(0.001, (0.0, 0.0))
    st = eng.state()
    assert eng.diagnostics()["lost"] == 0
    assert np.all(st["x"][:, 0] <= 1.0) and np.all(st["active"] == 1)


@pytest.mark.parametrize("scheme", ["mpm", "apic-affine"])
def test_one_launch_step_equals_the_stage_by_stage_recipe(scheme):
    a, _ = make_engine(scheme, seed=3)
    b, _ = make_engine(scheme, seed=3)
    for _ in range(5):
        a.step(1e-3, (0.0, -9.81))
        b.step_by_stage(1e-3, (0.0, -9.81))
    # the same arithmetic compiled as one kernel or as one kernel per stage: equal to rounding
    # (LLVM may contract multiply-adds differently in the two; f64 here)
    for name in ("x", "v", "s", "rho"):
        np.testing.assert_allclose(a.state((name,))[name], b.state((name,))[name], rtol=1e-12, atol=1e-15)


_WALL_ENGINES = {}


def _wall_scene(scheme, scatter, n, dtype=np.float64, bands=None):
    """An engine for a Drucker-Prager heap in a box with friction walls (particles not loaded).

    Engines are shared by the tests of this module (each new engine compiles its kernels again);
    every use loads its particles, which resets the whole particle state and the split plan."""
    from solver.engine import Engine

    key = (scheme, scatter, n, np.dtype(dtype).name, bands)
    if key in _WALL_ENGINES:
        return _WALL_ENGINES[key]
    grid = Grid((0.0, 0.0), (1.0, 1.0), 0.05, left=Boundary("friction", math.radians(15.0)),
                right=Boundary("friction", math.radians(20.0)), bottom=Boundary("friction", math.radians(25.0)),
                top=Boundary("open"))
    dp = (Material("dp", "drucker-prager", 2000.0, 5e6, 0.3, cohesion_pa=1e3, friction_angle_rad=math.radians(30.0)),)
    eng = Engine(grid, dp, n, scheme, dtype, scatter=scatter, bands=bands)
    assert eng.scatter == scatter
    _WALL_ENGINES[key] = eng
    return eng


def _run(eng, pos, velocity, steps=40, dt=2e-4):
    eng.load_particles(pos, np.full(len(pos), 2.5e-4), np.zeros(len(pos), np.int32), velocity)
    for _ in range(steps):
        eng.step(dt, (0.0, -9.81))
    return eng.state(("x", "v", "s"))


def _lattice(nx, ny, spacing=0.0125, corner=(0.001, 0.001)):
    """Particles on a lattice, row after row from the bottom (the order seeding gives)."""
    X, Y = np.meshgrid(corner[0] + spacing * (np.arange(nx) + 0.5), corner[1] + spacing * (np.arange(ny) + 0.5))
    return np.c_[X.ravel(), Y.ravel()]


def _assert_same_steps(a, b):
    for name in ("x", "v", "s"):
        scale = max(np.abs(a[name]).max(), 1e-30)
        np.testing.assert_allclose(b[name], a[name], rtol=0, atol=1e-9 * scale, err_msg=name)


@pytest.mark.parametrize("scheme", ["mpm", "apic", "apic-affine"])
def test_every_scatter_gives_the_same_steps(scheme):
    """Serial plain adds, parallel atomics and the split scatter (here in 3 bands, so that two band
    cuts are placed) differ only in summation order."""
    pos = _lattice(40, 64)  # 10 x 16 cells, in seeding order
    vel = np.random.default_rng(6).normal(scale=0.3, size=pos.shape)
    states = {}
    for scatter in ("atomic", "serial", "split"):
        eng = _wall_scene(scheme, scatter, len(pos), bands=3 if scatter == "split" else None)
        states[scatter] = _run(eng, pos, vel)
        if scatter == "split":
            plan = eng.to_grid
            assert np.all(np.diff(plan.cut.to_numpy()) >= 0)  # bands never overlap
            assert plan.cut_axis[None] == 1  # across the heap's longer side
            # the particles on the two node lines below each cut are left to the serial
            # remainder: 2 cuts x 2 lines of the heap's 16 cells
            assert (plan.band.to_numpy() >= 3).mean() < 0.35
    _assert_same_steps(states["atomic"], states["serial"])
    _assert_same_steps(states["atomic"], states["split"])


@pytest.mark.parametrize("scheme", ["apic", "apic-affine"])
def test_the_split_scatter_with_local_damping_gives_the_serial_steps(scheme):
    """With damping the forces are kept apart from the momentum (apic-affine then scatters them to
    their own grid field and sums no wall forces): split and serial still agree."""
    pos = _lattice(40, 64)
    vel = np.random.default_rng(6).normal(scale=0.3, size=pos.shape)
    states = {}
    for scatter in ("serial", "split"):
        eng = _wall_scene(scheme, scatter, len(pos), bands=2 if scatter == "split" else None)
        eng.load_particles(pos, np.full(len(pos), 2.5e-4), np.zeros(len(pos), np.int32), vel)
        for _ in range(30):
            eng.step(2e-4, (0.0, -9.81), damping=0.3)
        states[scatter] = eng.state(("x", "v", "s"))
    _assert_same_steps(states["serial"], states["split"])


def test_the_split_scatter_is_right_and_fast_in_any_particle_order():
    """Its bands follow positions, not particle numbers: in reverse and in shuffled order it leaves
    as few particles to its serial remainder as in seeding order, with bands of equal counts."""
    pos = _lattice(40, 64)
    vel = np.random.default_rng(6).normal(scale=0.3, size=pos.shape)
    reference = _run(_wall_scene("apic-affine", "serial", len(pos)), pos, vel)
    eng = _wall_scene("apic-affine", "split", len(pos), bands=2)
    for perm in (np.arange(len(pos))[::-1], np.random.default_rng(1).permutation(len(pos))):
        state = _run(eng, pos[perm], vel[perm])
        counts = np.bincount(eng.to_grid.band.to_numpy(), minlength=4)
        assert counts[2:].sum() / len(pos) < 0.2  # one cut: 2 node lines of 16 cells, about 12 %
        assert abs(counts[0] + counts[2] - (counts[1] + counts[3])) < 0.1 * len(pos)  # balanced
        _assert_same_steps({k: v[perm] for k, v in reference.items()}, state)


@pytest.mark.parametrize("scheme", ["mpm", "apic", "apic-affine"])
@pytest.mark.parametrize("scatter", ["serial", "split"])
def test_the_plain_add_scatters_repeat_a_run_bit_for_bit(scheme, scatter):
    """Every sum of the serial and split recipes comes in one fixed order (which band a particle
    belongs to depends on positions only): a run repeated on the same engine gives identical bits."""
    rng = np.random.default_rng(7)
    n = 2000  # enough for both threads of the parallel passes to share wall-touching particles
    pos = np.c_[0.001 + 0.998 * rng.random(n), 0.001 + 0.4 * rng.random(n)]
    vel = np.random.default_rng(8).normal(scale=0.5, size=(n, 2))
    eng = _wall_scene(scheme, scatter, n, np.float32)
    runs = [_run(eng, pos, vel, steps=30, dt=1e-4) for _ in range(2)]
    for name in ("x", "v", "s"):
        assert np.array_equal(runs[0][name], runs[1][name]), name


def test_scatter_auto_on_a_cpu_with_few_threads_is_serial_for_small_runs_and_split_for_large_ones():
    from solver.engine import Engine
    from solver.scatter import SERIAL_SCATTER_MAX_THREADS, SPLIT_MIN_PARTICLES, resolve_scatter
    import taichi as ti

    few = ti.lang.impl.current_cfg().cpu_max_num_threads <= SERIAL_SCATTER_MAX_THREADS
    assert resolve_scatter("auto", SPLIT_MIN_PARTICLES - 1) == ("serial" if few else "atomic")
    assert resolve_scatter("auto", SPLIT_MIN_PARTICLES) == ("split" if few else "atomic")
    assert resolve_scatter("atomic", 10) == "atomic"
    with pytest.raises(ValueError, match="unknown scatter 'fast'; allowed: auto, atomic, serial, split"):
        make_engine(scatter="fast")
    with pytest.raises(ValueError, match="bands must be from 1 to 63, got 0"):
        Engine(Grid((0.0, 0.0), (1.0, 1.0), 0.1), MAT, 10, "apic", np.float64, scatter="split", bands=0)


def test_the_recipe_is_the_scatters_own_business_and_a_checkpoint_of_another_scatter_loads():
    """Every scatter runs the same named stages; the split scatter's plan (its ``STATE``) is in its
    checkpoints, and another scatter's engine loads them without it."""
    pos = _lattice(8, 8)
    split = _wall_scene("apic", "split", len(pos), bands=2)
    serial = _wall_scene("apic", "serial", len(pos))
    assert split.recipe == serial.recipe
    split.load_particles(pos, np.full(len(pos), 2.5e-4), np.zeros(len(pos), np.int32))
    saved = split.state()
    assert set(split.to_grid.STATE) <= set(saved) and not set(split.to_grid.STATE) & set(serial.state())
    serial.load_state(saved)
    np.testing.assert_array_equal(serial.state(("x",))["x"], pos)
    with pytest.raises(ValueError, match="unknown state field 'nope'"):
        serial.load_state({"nope": np.zeros(1)})


@pytest.mark.parametrize("scheme", ["mpm", "apic-affine"])
def test_a_blown_up_particle_stays_inside_the_grid_arrays_until_the_guard_acts(scheme):
    """NaN stress -> NaN grid velocity -> NaN positions: the engine must keep every stencil inside
    the grid arrays (no crash, no write elsewhere) and the damage must be visible to the guard."""
    eng, pos = make_engine(scheme, n=100, seed=4)
    stress = np.zeros((len(pos), 4))
    stress[7] = np.nan
    eng.set_stress(stress)
    for _ in range(30):
        eng.step(1e-3, (0.0, -9.81))
    st = eng.state(("x", "v"))
    d = eng.diagnostics()
    damaged = ~np.isfinite(st["v"]).all(axis=1)
    assert damaged[7] and (d["unstable"] > 0 or not np.isfinite(d["kinetic_energy"]))
    # the stencils (and the grid box built from them) stayed inside the arrays
    lo, hi = eng.lo.to_numpy(), eng.hi.to_numpy()
    assert np.all(lo >= 0) and np.all(hi <= np.array(eng.nodes))


def test_a_particle_the_guard_removes_as_it_leaves_is_counted_once():
    from solver.engine import Engine

    grid = Grid((0.0, 0.0), (1.0, 1.0), 0.1, left=Boundary("slip"), right=Boundary("open"),
                bottom=Boundary("slip"), top=Boundary("slip"))
    eng = Engine(grid, MAT, 1, "apic-affine", np.float64, speed_bound_m_s=1.0, remove_unstable=True)
    eng.load_particles([[0.95, 0.5]], [1e-3], [0], [[5.0, 0.0]])
    eng.step(0.02, (0.0, 0.0))
    d = eng.diagnostics()
    assert (d["active"], d["unstable"], d["lost"]) == (0, 1, 0)


@pytest.mark.parametrize("scheme", ["mpm", "apic", "apic-affine"])
def test_a_particle_pulled_apart_keeps_at_least_half_its_material_density(scheme):
    """eq 24 follows the velocity's divergence; a particle torn off a cohesionless mass (stress
    free at the cone's apex) would otherwise grow without bound (53 times its volume in the
    dropped-block scene of docs/validation.md) and be that much stiffer per mass when it lands
    again (the wave speed goes as 1 / sqrt(rho)): the density stops at DENSITY_FLOOR of the
    material's (docs/solver.md, schemes: density)."""
    from solver.engine import DENSITY_FLOOR, Engine

    grid = Grid((0.0, 0.0), (2.0, 2.0), 0.1)
    side = (np.arange(8) + 0.5) * 0.05 + 0.8
    pos = np.stack(np.meshgrid(side, side), -1).reshape(-1, 2)
    rho0 = MAT[0].density_kg_m3

    def expand(rate, steps, dt=1e-3):
        """Impose the uniform expansion v = rate (x - centre) before every step; the densities."""
        eng = Engine(grid, MAT, len(pos), scheme, np.float64)
        eng.load_particles(pos, np.full(len(pos), 0.05 ** 2), np.zeros(len(pos), np.int32))
        for _ in range(steps):
            x = eng.x.to_numpy()
            eng.set_velocity(rate * (x - x.mean(axis=0)), np.tile(rate * np.eye(2), (len(x), 1, 1)))
            eng.step(dt, (0.0, 0.0))
        return eng.rho.to_numpy()

    inner = np.all(np.abs(pos - pos.mean(axis=0)) < 0.1, axis=1)  # away from the block's edges
    # a gentle expansion is eq 24's own: rho0 / (1 + 2 rate dt) per step
    gentle = expand(1.0, 5)[inner]
    assert gentle == pytest.approx(rho0 / (1.0 + 2e-3) ** 5, rel=2e-3)
    # pulled apart (eq 24 alone: 0.2 rho0 after 40 steps) it stops at the floor
    torn = expand(20.0, 40)
    assert torn.min() == pytest.approx(DENSITY_FLOOR * rho0, rel=1e-12)
    assert np.all(torn >= DENSITY_FLOOR * rho0)
