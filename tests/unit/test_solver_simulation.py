"""Stage runner: stability guard, auto stop, cancel, frames, runtime ownership (CPU, small scenes)."""

import math
import re
import threading

import numpy as np
import pytest

from solver.config import (Boundary, Grid, InstabilityError, Material, Numerics, Output, Particles,
                           SimulationConfig, SolverError, Stage)
from solver.simulation import Simulation, critical_time_step

SAND = Material("sand", "drucker-prager", 2000.0, 1e6, 0.3, friction_angle_rad=math.radians(30))


def block(width=0.1, height=0.1, dx=0.01, ppc=2, x0=0.0):
    h = dx / ppc
    xs = x0 + np.arange(round(width / h)) * h + h / 2
    ys = np.arange(round(height / h)) * h + h / 2
    X, Y = np.meshgrid(xs, ys)
    pos = np.c_[X.ravel(), Y.ravel()]
    return Particles(pos, np.full(len(pos), h * h), np.zeros(len(pos), np.int32))


def config(stages, dx=0.01, **numerics):
    grid = Grid((0.0, 0.0), (0.4, 0.2), dx, left=Boundary("slip"), right=Boundary("slip"),
                bottom=Boundary("friction", math.radians(30)), top=Boundary("open"))
    nm = {"cfl": 0.5, "arch": "cpu", **numerics}
    return SimulationConfig(grid, (SAND,), stages, (0.0, -9.81), Numerics(**nm), Output(0.02))


def test_guard_stops_a_run_with_a_too_large_time_step_and_names_the_cause():
    cfg = config((Stage("k0", "k0"), Stage("collapse", "dynamic", duration_s=0.5)), cfl=None, time_step_s=None)
    crit = critical_time_step(cfg)
    cfg = config((Stage("k0", "k0"), Stage("collapse", "dynamic", duration_s=0.5)), cfl=None, time_step_s=4.0 * crit)
    frames = []
    with Simulation(cfg, block()) as sim:
        with pytest.raises(InstabilityError) as err:
            for f in sim.run():
                frames.append(f)
        last = sim.last_frame
    msg = str(err.value)
    assert re.match(r"unstable: time step \S+ s is 4\.0x the critical \S+ s \(.* at step \d+, t = \S+ s\)$", msg), msg
    assert err.value.step > 0
    assert frames and last is frames[-1]
    for f in frames:  # no NaN ever reaches a frame
        for name, arr in f.fields.items():
            assert np.all(np.isfinite(arr)), name


def test_remove_mode_counts_unstable_particles_instead_of_stopping():
    cfg = config((Stage("collapse", "dynamic", duration_s=0.1),), cfl=None, time_step_s=4.0 * critical_time_step(
        config((Stage("c", "dynamic", duration_s=0.1),))), guard="remove")
    with Simulation(cfg, block()) as sim:
        frames = list(sim.run())
    d = frames[-1].diagnostics
    assert d.unstable_particles > 0
    assert frames[-1].fields["active"].sum() < len(frames[-1].fields["active"])
    for f in frames:
        act = f.fields["active"]
        assert np.all(np.isfinite(f.fields["velocity"][act]))


def test_auto_stop_ends_the_dynamic_stage_after_the_slide_stops():
    stage = Stage("collapse", "dynamic", duration_s=5.0, stop_when_kinetic_energy_below=0.01, min_duration_s=0.1)
    with Simulation(config((Stage("k0", "k0"), stage), dx=0.02), block(0.08, 0.08, 0.02)) as sim:
        frames = list(sim.run())
        assert sim.status == "completed"
        assert "kinetic energy" in sim.message
        assert sim.time_s < 5.0
        message = sim.message
    # the stop is judged against the peak over all checked steps (every 20 steps), which the frames
    # only sample: the message states it, and it is at least the frames' peak
    stated_peak = float(re.search(r"of its peak ([0-9.e+-]+) J/m", message).group(1))
    assert stated_peak >= 0.999 * max(f.diagnostics.kinetic_energy_J_per_m for f in frames)
    assert frames[-1].diagnostics.kinetic_energy_J_per_m < 0.01 * stated_peak * 1.001  # message rounds to 3 digits


def test_frames_at_output_times_with_requested_fields_only_and_mass_conserved():
    cfg = config((Stage("k0", "k0"), Stage("collapse", "dynamic", duration_s=0.1)))
    cfg = SimulationConfig(cfg.grid, cfg.materials, cfg.stages, cfg.gravity_m_s2, cfg.numerics,
                           Output(0.025, ("velocity",)))
    with Simulation(cfg, block()) as sim:
        frames = list(sim.run())
    times = [f.diagnostics.time_s for f in frames]
    np.testing.assert_allclose(times, [0.0, 0.025, 0.05, 0.075, 0.1], atol=1e-12)
    assert set(frames[-1].fields) == {"positions", "active", "velocity"}
    mass0 = frames[0].diagnostics.total_mass_kg_per_m
    for f in frames:
        assert f.diagnostics.total_mass_kg_per_m == pytest.approx(mass0, rel=1e-5)
    assert frames[-1].diagnostics.kinetic_energy_J_per_m > 0


def test_cancel_yields_a_last_frame_and_reports_stopped():
    calls = {"n": 0}

    def cancel():
        calls["n"] += 1
        return calls["n"] >= 3

    with Simulation(config((Stage("collapse", "dynamic", duration_s=1.0),)), block()) as sim:
        frames = list(sim.run(cancel=cancel))
        assert sim.status == "stopped"
        assert sim.time_s < 1.0
    assert frames[-1].diagnostics.time_s == pytest.approx(sim.time_s)


def test_bad_input_is_a_solver_error():
    parts = block()
    bad = Particles(parts.positions_m + 10.0, parts.volumes_m2, parts.material_ids)
    with pytest.raises(SolverError, match="outside the grid box"):
        Simulation(config((Stage("c", "dynamic", duration_s=0.1),)), bad)


def test_runtime_can_be_rebuilt_repeatedly_and_in_a_worker_thread():
    cfg = config((Stage("c", "dynamic", duration_s=0.02),))
    results = []
    for scheme in ("apic-affine", "mpm"):
        c = config((Stage("c", "dynamic", duration_s=0.02),), scheme=scheme)
        with Simulation(c, block()) as sim:
            results.append(list(sim.run())[-1].diagnostics.step)

    def worker():
        with Simulation(cfg, block()) as sim:
            results.append(list(sim.run())[-1].diagnostics.step)

    t = threading.Thread(target=worker)
    t.start()
    t.join()
    assert len(results) == 3 and all(r > 0 for r in results)


def test_f32_and_f64_agree_on_a_short_collapse():
    out = {}
    for precision in ("f32", "f64"):
        with Simulation(config((Stage("k0", "k0"), Stage("c", "dynamic", duration_s=0.05)), precision=precision),
                        block()) as sim:
            out[precision] = list(sim.run())[-1].fields["positions"].astype(np.float64)
    assert np.abs(out["f32"] - out["f64"]).max() < 1e-4  # 0.1 mm after 50 ms, cell 10 mm


def _sliding_block(bottom, gravity, v0, duration, rows=10, scheme="apic-affine"):
    h = 0.005
    xs = 0.05 + np.arange(40) * h + h / 2
    ys = np.arange(rows) * h + h / 2
    X, Y = np.meshgrid(xs, ys)
    pos = np.c_[X.ravel(), Y.ravel()]
    parts = Particles(pos, np.full(len(pos), h * h), np.zeros(len(pos), np.int32), np.tile([v0, 0.0], (len(pos), 1)))
    grid = Grid((0.0, 0.0), (1.0, 0.2), 0.01, left=Boundary("open"), right=Boundary("open"), bottom=bottom,
                top=Boundary("open"))
    # soft like the granular materials of the examples (E ~ 1 MPa); stiff blocks, inclines and
    # structures: tests/unit/test_solver_contact.py
    soft = Material("block", "linear-elastic", 2000.0, 1e6, 0.2)
    cfg = SimulationConfig(grid, (soft,), (Stage("k0", "k0"), Stage("slide", "dynamic", duration_s=duration)),
                           gravity, Numerics(scheme=scheme, cfl=0.5, arch="cpu", precision="f64"),
                           Output(duration / 4, ("velocity",)))
    with Simulation(cfg, parts) as sim:
        return list(sim.run())


def test_coulomb_friction_decelerates_a_sliding_block_at_mu_g():
    mu = math.tan(math.radians(20.0))
    frames = _sliding_block(Boundary("friction", math.radians(20.0)), (0.0, -9.81), 1.0, 0.1)
    d = frames[-1].diagnostics
    v_mean = d.momentum_x / d.total_mass_kg_per_m
    # 0.643 m/s; measured 0.6415 (1.004 mu g).
    # The margin is for the block's own vertical motion: released from a k0 stress with free ends
    # it bounces, and the wall's normal impulse over 0.1 s exceeds its weight's by what it gains
    # upwards (20 rows: friction exactly mu N, but N 1.028 W and 1.028 mu g)
    assert v_mean == pytest.approx(1.0 - mu * 9.81 * 0.1, rel=0.10)


@pytest.mark.parametrize("scheme", ["apic-affine", "apic"])
def test_a_thin_sheet_slides_to_a_stop_at_mu_g_in_every_scheme(scheme):
    # one cell thick: the wall's reaction is the sheet's weight, so the deceleration is mu g
    # (measured 1.000 mu g for both; the fused scheme's wall reaction is worked out as the six-stage one's)
    mu = math.tan(math.radians(20.0))
    frames = _sliding_block(Boundary("friction", math.radians(20.0)), (0.0, -9.81), 1.0, 0.1, rows=2, scheme=scheme)
    d = frames[-1].diagnostics
    assert d.momentum_x / d.total_mass_kg_per_m == pytest.approx(1.0 - mu * 9.81 * 0.1, rel=0.01)


def test_gravity_in_any_direction_accelerates_a_block_on_a_frictionless_floor():
    frames = _sliding_block(Boundary("slip"), (2.0, -9.81), 0.0, 0.1)
    d = frames[-1].diagnostics
    assert d.momentum_x / d.total_mass_kg_per_m == pytest.approx(2.0 * 0.1, rel=0.02)
    assert abs(d.momentum_y / d.total_mass_kg_per_m) < 0.01
