"""solver.fieldio.FieldIO: many fields in and out with one kernel, exactly as to_numpy / from_numpy.

Exact (bit-for-bit) copies are what checkpoints and the regression digests rely on, so the tests
compare bits, with random values of every dtype and every field form (scalar, vector, matrix,
0-d, 1-d, 3-d), whole sets and subsets, in both precisions.
"""

import numpy as np
import pytest
import taichi as ti

from solver import runtime
from solver.fieldio import FieldIO


@pytest.fixture(params=["f32", "f64"], scope="module")
def fields(request):
    runtime.acquire("cpu", request.param)
    n = 37
    made = {
        "x": ti.Vector.field(2, float, n), "C": ti.Matrix.field(2, 2, float, n), "m": ti.field(float, n),
        "mat": ti.field(ti.i32, n), "active": ti.field(ti.i8, n), "impulse": ti.Vector.field(2, ti.f64, 6),
        "lost": ti.field(ti.i32, ()), "axis": ti.Vector.field(2, ti.i32, ()), "counts": ti.field(ti.i32, (3, 2, 7)),
        "grid": ti.Vector.field(2, float, (5, 4)), "peak": ti.Vector.field(3, ti.f64, 6),
    }
    yield made, FieldIO(made)
    runtime.release()


def _random(io, seed):
    rng = np.random.default_rng(seed)
    return {name: (rng.standard_normal(io.shapes[name]) * 1e3).astype(io.dtypes[name]) for name in io.fields}


def _bits_equal(a, b):
    return a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()


def test_round_trip_is_exact_and_matches_taichi(fields):
    made, io = fields
    values = _random(io, 1)
    values["m"][0] = np.finfo(values["m"].dtype).tiny / 4  # a subnormal survives too
    values["x"][1, 0] = -0.0
    io.write(values)
    back = io.read()
    for name, field in made.items():
        assert _bits_equal(back[name], values[name]), name
        assert _bits_equal(field.to_numpy(), values[name]), name  # the layout of Taichi's own copy


def test_subsets_leave_the_other_fields_alone(fields):
    made, io = fields
    values = _random(io, 2)
    io.write(values)
    io.write({"m": 2.5, "counts": np.arange(42, dtype=np.int32).reshape(3, 2, 7), "lost": 7})
    assert np.all(made["m"].to_numpy() == 2.5)
    assert made["lost"][None] == 7
    assert np.array_equal(made["counts"].to_numpy(), np.arange(42).reshape(3, 2, 7))
    for name in ("x", "C", "mat", "active", "impulse", "axis", "grid", "peak"):
        assert _bits_equal(made[name].to_numpy(), values[name]), name
    got = io.read(("grid", "lost"))
    assert set(got) == {"grid", "lost"}
    assert got["lost"].shape == () and int(got["lost"]) == 7
    assert _bits_equal(got["grid"], values["grid"])


def test_bad_names_and_shapes_are_refused(fields):
    _made, io = fields
    with pytest.raises(KeyError, match="unknown field 'nope'"):
        io.read(("nope",))
    with pytest.raises(ValueError, match="field 'x' has shape"):
        io.write({"x": np.zeros((3, 2))})


def test_the_kernel_cache_keeps_the_suites_kernels(fields):
    """Taichi's default offline-cache limit (100 MB, then the least recently used quarter dropped)
    is smaller than the kernels of the test suite's grids; the runtime raises it
    (docs/performance.md, kernel compilation)."""
    config = ti.lang.impl.current_cfg()
    assert config.offline_cache
    assert config.offline_cache_max_size_of_files == runtime.KERNEL_CACHE_MAX_BYTES >= 1024 ** 3


def test_cpu_kernels_compile_without_the_advanced_optimization_passes(fields):
    """They were most of the compile time of a scene with structures (47 s against 6.4 s) for a
    runtime cost of 2-3 % (docs/performance.md, kernel compilation)."""
    # the fixture acquired the CPU runtime
    assert ti.lang.impl.current_cfg().advanced_optimization is runtime.CPU_ADVANCED_OPTIMIZATION is False
