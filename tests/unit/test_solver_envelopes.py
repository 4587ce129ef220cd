"""solver.envelopes: checkpoint state round trip (a resumed run continues the envelopes), the
update schedule and the raster (CPU, f64)."""

import numpy as np
import pytest

from solver import runtime
from solver.config import Boundary, EnvelopeConfig, Grid, Material, Target

MAT = (Material("e", "linear-elastic", 2000.0, 1e6, 0.3),)
GRID = Grid((0.0, 0.0), (1.0, 0.3), 0.02, bottom=Boundary("slip"))
DT = 2e-4


@pytest.fixture(scope="module", autouse=True)
def _runtime():
    runtime.acquire("cpu", "f64")
    yield
    runtime.release()


_ENGINES = {}


def block(every=3, targets=(Target("line", 0.3), Target("pt", 0.35, 0.02)), engine=0):
    """A 0.1 m x 0.06 m block at 2 m/s on engine number ``engine`` (engines are reused: each new
    engine compiles its kernels again)."""
    from solver.engine import Engine
    from solver.envelopes import Envelopes

    xs, ys = np.meshgrid(np.arange(0.055, 0.15, 0.01), np.arange(0.005, 0.06, 0.01))
    pos = np.column_stack([xs.ravel(), ys.ravel()])
    n = len(pos)
    if engine not in _ENGINES:
        _ENGINES[engine] = Engine(GRID, MAT, n, "apic-affine", np.float64, damping=False)
    eng = _ENGINES[engine]
    eng.load_particles(pos, np.full(n, 1e-4), np.zeros(n, np.int32), np.tile([2.0, 0.0], (n, 1)))
    env = Envelopes(eng, EnvelopeConfig(0.02, every, 0.005, targets), GRID)
    return eng, env


def advance(eng, env, steps, t0):
    t = t0
    for _ in range(steps):
        eng.step(DT, (0.0, -9.81))
        t += DT
        env.after_step(t)
    return t


def test_state_round_trip_continues_the_envelopes():
    eng_a, env_a = block()
    env_a.start(0.0)
    t = advance(eng_a, env_a, 40, 0.0)
    saved_engine, saved_env = eng_a.state(), env_a.state()
    eng_b, env_b = block(engine=1)
    eng_b.load_state(saved_engine)
    env_b.load_state(saved_env)
    assert env_b.started and env_b.steps == 40
    advance(eng_a, env_a, 101, t)
    advance(eng_b, env_b, 101, t)
    a, b = env_a.snapshot(), env_b.snapshot()
    for key, value in a.items():
        if isinstance(value, dict):
            for k, v in value.items():
                np.testing.assert_array_equal(v, b[key][k], err_msg=f"{key}.{k}")
        elif isinstance(value, np.ndarray):
            np.testing.assert_array_equal(value, b[key], err_msg=key)
        else:
            assert value == b[key] or (value != value and b[key] != b[key]), key
    # and the resumed series holds the rows from before the restart
    assert len(b["series"]) == 1 + 141 // 3


def test_state_of_other_raster_is_refused():
    _, env_a = block()
    env_a.start(0.0)
    _, env_c = block(targets=(Target("line", 0.3),))
    with pytest.raises(ValueError, match="shape"):
        env_c.load_state(env_a.state())


@pytest.mark.parametrize("every", [1, 7])
def test_updates_every_few_steps_and_on_sync(every):
    eng, env = block(every=every)
    env.start(0.0)
    t = advance(eng, env, 20, 0.0)
    env.sync(t)  # an output frame
    env.sync(t)  # twice at one step: one update
    series = env.series()
    expected = 1 + 20 // every + (1 if 20 % every else 0)
    assert len(series) == expected
    np.testing.assert_allclose(np.diff(series[:, 0]).max(), every * DT, rtol=1e-9)


def test_before_the_release_nothing_accumulates():
    eng, env = block()
    advance(eng, env, 5, 0.0)
    env.sync(5 * DT)
    snap = env.snapshot()
    assert not snap["started"] and len(snap["series"]) == 0 and snap["max_speed_m_s"].max() == 0.0


def test_raster_covers_the_grid_box_with_its_own_cell():
    from solver.envelopes import Envelopes

    eng, _ = block()
    env = Envelopes(eng, EnvelopeConfig(0.03, 1, 0.0), GRID)
    assert env.shape == (34, 10)  # ceil(1.0 / 0.03), ceil(0.3 / 0.03)
    with pytest.raises(ValueError, match="cell size"):
        Envelopes(eng, EnvelopeConfig(0.0, 1, 0.0), GRID)
