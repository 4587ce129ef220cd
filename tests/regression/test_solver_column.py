"""Elastic column under self-weight: gravity loading and the K0 stage against the analytic solution.

Analytic (uniaxial strain, laterally confined by frictionless walls):
sigma_yy = -rho g (H - y0), sigma_xx = sigma_zz = nu / (1 - nu) sigma_yy.
"""

import numpy as np
import pytest

from solver.config import Boundary, Grid, Material, Numerics, Output, Particles, SimulationConfig, Stage
from solver.simulation import Simulation

RHO, E, NU, G = 1000.0, 1e7, 0.3, 9.81
H, WIDTH, DX, PPC = 1.0, 0.2, 0.05, 2  # H / dx = 20


def column_particles():
    h = DX / PPC
    xs = np.arange(round(WIDTH / h)) * h + h / 2
    ys = np.arange(round(H / h)) * h + h / 2
    X, Y = np.meshgrid(xs, ys)
    pos = np.c_[X.ravel(), Y.ravel()]
    return Particles(pos, np.full(len(pos), h * h), np.zeros(len(pos), np.int32))


def column_config(stages, scheme="apic-affine"):
    grid = Grid((0.0, 0.0), (WIDTH, 1.5), DX, left=Boundary("slip"), right=Boundary("slip"),
                bottom=Boundary("slip"), top=Boundary("open"))
    return SimulationConfig(grid, (Material("soil", "linear-elastic", RHO, E, NU),), stages, (0.0, -G),
                            Numerics(scheme=scheme, cfl=0.5, precision="f64", arch="cpu"), Output(1.0))


def analytic(y0):
    return -RHO * G * (H - y0)


@pytest.mark.parametrize("scheme", ["mpm", "apic", "apic-affine"])
def test_gravity_loading_matches_self_weight_solution(scheme):
    parts = column_particles()
    cfg = column_config((Stage("geostatic", "gravity", duration_s=0.5, damping=0.7),), scheme)
    with Simulation(cfg, parts) as sim:
        frames = list(sim.run())
    last = frames[-1]
    y0 = parts.positions_m[:, 1]
    s = last.fields["stress"]
    exact = analytic(y0)
    l2 = np.sqrt(np.mean((s[:, 1] - exact) ** 2)) / (RHO * G * H)
    assert l2 < 0.02, f"{scheme}: L2 error of sigma_yy {l2:.4f} (normalised by rho g H)"
    # lateral ratio away from the boundary cells (bottom cell and the top free-surface cell)
    inner = (y0 > DX) & (y0 < H - DX)
    ratio = s[inner, 0].sum() / s[inner, 1].sum()
    assert ratio == pytest.approx(NU / (1 - NU), rel=0.05)
    # the gravity stage ends at rest, mass conserved
    assert np.abs(last.fields["velocity"]).max() == 0.0
    assert last.diagnostics.total_mass_kg_per_m == pytest.approx(RHO * WIDTH * H, rel=1e-12)


def test_k0_stage_gives_geostatic_stress_at_time_zero():
    parts = column_particles()
    k0 = 0.55
    cfg = column_config((Stage("initial", "k0", k0=k0), Stage("rest", "dynamic", duration_s=0.001)))
    with Simulation(cfg, parts) as sim:
        first = next(iter(sim.run()))
    assert first.diagnostics.time_s == 0.0
    s = first.fields["stress"]
    exact = analytic(parts.positions_m[:, 1])
    np.testing.assert_allclose(s[:, 1], exact, rtol=1e-12)
    np.testing.assert_allclose(s[:, 0], k0 * exact, rtol=1e-12)
    np.testing.assert_allclose(s[:, 3], k0 * exact, rtol=1e-12)
    np.testing.assert_array_equal(s[:, 2], 0.0)


def test_k0_default_is_jaky_for_drucker_prager_layers():
    """Two layers of different density: sigma_v integrates the weight of both."""
    from solver.initial_stress import k0_stress

    parts = column_particles()
    y = parts.positions_m[:, 1]
    mat_ids = (y < 0.5).astype(np.int32)  # 1 below
    mats = (Material("top", "drucker-prager", 1500.0, E, NU, friction_angle_rad=np.radians(30)),
            Material("bottom", "drucker-prager", 2000.0, E, NU, friction_angle_rad=np.radians(40)))
    parts = Particles(parts.positions_m, parts.volumes_m2, mat_ids)
    s = k0_stress(parts, mats, (0.0, -G), DX)
    exact = np.where(y >= 0.5, -1500 * G * (H - y), -1500 * G * 0.5 - 2000 * G * (0.5 - y))
    np.testing.assert_allclose(s[:, 1], exact, rtol=1e-12)
    k0 = np.where(y >= 0.5, 1 - np.sin(np.radians(30)), 1 - np.sin(np.radians(40)))
    np.testing.assert_allclose(s[:, 0], k0 * exact, rtol=1e-12)
