"""Single-point constitutive tests against closed forms (f64, CPU)."""

import math

import numpy as np
import pytest

from solver import runtime
from solver.config import Material
from solver.materials import MaterialPointDriver
from solver.materials.drucker_prager import dp_constants

E, NU = 10e6, 0.3
K = E / (3 * (1 - 2 * NU))
G = E / (2 * (1 + NU))
LAM = K - 2 * G / 3


@pytest.fixture(scope="module", autouse=True)
def _runtime():
    runtime.acquire("cpu", "f64")
    yield
    runtime.release()


def elastic(**kw):
    return Material("e", "linear-elastic", 2000.0, E, NU, **kw)


def dp(c=10e3, phi=30.0, psi=0.0, tension=None):
    return Material("dp", "drucker-prager", 2000.0, E, NU, cohesion_pa=c, friction_angle_rad=math.radians(phi),
                    dilatancy_angle_rad=math.radians(psi), tensile_strength_pa=tension)


def invariants(s):
    p = (s[..., 0] + s[..., 1] + s[..., 3]) / 3
    d0, d1, dz = s[..., 0] - p, s[..., 1] - p, s[..., 3] - p
    j2 = 0.5 * (d0**2 + d1**2 + dz**2) + s[..., 2] ** 2
    return 3 * p, np.sqrt(j2)


def test_dp_constants_match_plane_strain_mohr_coulomb():
    alpha, k, alpha_psi = dp_constants(math.radians(30), 0.0, 10e3)
    t = math.tan(math.radians(30))
    assert alpha == pytest.approx(t / math.sqrt(9 + 12 * t * t), rel=1e-14)
    assert k == pytest.approx(3 * 10e3 / math.sqrt(9 + 12 * t * t), rel=1e-14)
    assert alpha_psi == 0.0


def test_elastic_uniaxial_strain_and_shear_closed_form():
    drv = MaterialPointDriver((elastic(),), 2)
    d, gamma, dt = 1e-2, 2e-2, 1e-3
    L = np.array([[[d, 0.0], [0.0, 0.0]], [[0.0, gamma], [0.0, 0.0]]])
    out = drv.run(np.zeros((2, 4)), L, dt)["stress"]
    np.testing.assert_allclose(out[0], [(LAM + 2 * G) * d * dt, LAM * d * dt, 0.0, LAM * d * dt], rtol=1e-12)
    # simple shear from rest: only sigma_xy = G * gamma * dt (the spin rotates a zero stress)
    np.testing.assert_allclose(out[1], [0.0, 0.0, G * gamma * dt, 0.0], atol=1e-9)


def test_rigid_rotation_keeps_invariants_under_jaumann_rate():
    drv = MaterialPointDriver((elastic(),), 1)
    omega, dt, steps = 1.0, 1e-3, 1000  # one radian in small increments
    s0 = np.array([[-100e3, -40e3, 25e3, -60e3]])
    L = np.array([[[0.0, -omega], [omega, 0.0]]])
    out = drv.run(s0, L, dt, steps)["stress"]
    i1_0, q0 = invariants(s0)
    i1, q = invariants(out)
    assert i1[0] == pytest.approx(i1_0[0], rel=1e-12)  # the spin terms are traceless
    assert q[0] == pytest.approx(q0[0], rel=2e-3)  # forward-Euler drift ~ N (omega dt)^2 = 1e-3
    # and the tensor turned with the body: sigma = R sigma0 R^T with R the rotation by omega t
    a = omega * dt * steps
    R = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    S0 = np.array([[s0[0, 0], s0[0, 2]], [s0[0, 2], s0[0, 1]]])
    S = R @ S0 @ R.T
    np.testing.assert_allclose(out[0, [0, 1, 2]], [S[0, 0], S[1, 1], S[0, 1]], atol=2e-3 * 100e3)
    assert out[0, 3] == pytest.approx(s0[0, 3])


@pytest.mark.parametrize("psi", [0.0, 10.0])
def test_drucker_prager_return_lands_on_yield_surface(psi):
    mat = dp(c=10e3, phi=30.0, psi=psi)
    alpha, k, alpha_psi = dp_constants(mat.friction_angle_rad, mat.dilatancy_angle_rad, mat.cohesion_pa)
    drv = MaterialPointDriver((mat,), 3)
    # confined states, then a large deviatoric increment that yields
    s0 = np.array([[-50e3, -50e3, 0.0, -50e3], [-200e3, -100e3, 0.0, -120e3], [-80e3, -30e3, 20e3, -50e3]])
    L = np.tile(np.array([[1.0, 0.4], [0.0, -1.0]]), (3, 1, 1))
    dt = 0.02
    trial = MaterialPointDriver((Material("t", "linear-elastic", 2000.0, E, NU),), 3).run(s0, L, dt)["stress"]
    res = drv.run(s0, L, dt)
    s = res["stress"]
    i1, q = invariants(s)
    f = q + alpha * i1 - k
    assert np.all(res["yielded"] == 1)
    np.testing.assert_allclose(f, 0.0, atol=1e-6 * k)
    # the deviator keeps its direction (radial return in the deviatoric plane)
    i1_t, q_t = invariants(trial)
    dev_t = trial - np.c_[i1_t, i1_t, np.zeros(3), i1_t] / 3 * np.array([1, 1, 0, 1])
    dev = s - np.c_[i1, i1, np.zeros(3), i1] / 3 * np.array([1, 1, 0, 1])
    np.testing.assert_allclose(dev * (q_t / q)[:, None], dev_t, rtol=1e-9, atol=1e-6)
    # plastic volume change: I1 shifts by 9 K alpha_psi dlam, zero for psi = 0
    dlam = (q_t + alpha * i1_t - k) / (G + 9 * K * alpha * alpha_psi)
    np.testing.assert_allclose(i1, i1_t - 9 * K * alpha_psi * dlam, rtol=1e-10)
    if psi == 0.0:
        np.testing.assert_allclose(i1, i1_t, rtol=1e-12)
    assert np.all(res["plastic_strain"] > 0)


def test_elastic_state_inside_cone_is_untouched():
    drv = MaterialPointDriver((dp(),), 1)
    s0 = np.array([[-100e3, -100e3, 0.0, -100e3]])
    res = drv.run(s0, np.array([[[1e-4, 0.0], [0.0, 0.0]]]), 1e-3)
    assert res["yielded"][0] == 0 and res["plastic_strain"][0] == 0.0


def test_apex_return_is_hydrostatic_at_the_cone_tip():
    mat = dp(c=20e3, phi=25.0, psi=5.0)
    alpha, k, _ = dp_constants(mat.friction_angle_rad, mat.dilatancy_angle_rad, mat.cohesion_pa)
    drv = MaterialPointDriver((mat,), 1)
    # strong isotropic stretching: the trial state lies beyond the apex in tension
    res = drv.run(np.zeros((1, 4)), np.array([[[1.0, 0.1], [0.1, 1.0]]]), 0.05)
    s = res["stress"][0]
    apex = k / (3 * alpha)
    np.testing.assert_allclose(s, [apex, apex, 0.0, apex], rtol=1e-10, atol=1e-6)


def test_tension_cutoff_caps_mean_stress():
    mat = dp(c=50e3, phi=30.0, tension=5e3)
    drv = MaterialPointDriver((mat,), 1)
    res = drv.run(np.zeros((1, 4)), np.array([[[1e-3, 0.0], [0.0, 1e-3]]]), 1.0)
    s = res["stress"][0]
    assert (s[0] + s[1] + s[3]) / 3 == pytest.approx(5e3, rel=1e-10)
    assert res["yielded"][0] == 1
