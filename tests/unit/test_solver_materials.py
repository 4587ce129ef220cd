"""Single-point constitutive tests against closed forms (f64, CPU)."""

import math

import numpy as np
import pytest

from solver import runtime
from solver.config import Material
from solver.materials import MaterialPointDriver
from solver.materials.drucker_prager import dp_constants

# the suite runs a covering sample of each matrix below (tests/conftest.py, RUNOUT_FULL_MATRIX)
pytestmark = pytest.mark.matrix

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


MATCHES = ("plane-strain-associated", "plane-strain", "simple-shear")


@pytest.mark.parametrize("match, alpha_of, k_of", [
    ("plane-strain-associated", lambda p: math.tan(p) / math.sqrt(9 + 12 * math.tan(p) ** 2),
     lambda p, c: 3 * c / math.sqrt(9 + 12 * math.tan(p) ** 2)),
    ("plane-strain", lambda p: math.sin(p) / 3, lambda p, c: c * math.cos(p)),  # Abaqus, non-dilatant flow
    ("simple-shear", lambda p: math.tan(p) / 3, lambda p, c: c),
])
def test_dp_constants_with_psi_zero_are_the_closed_forms_of_each_match(match, alpha_of, k_of):
    for phi in (0.0, 10.0, 19.8, 30.0, 45.0):
        p = math.radians(phi)
        alpha, k, alpha_psi = dp_constants(p, 0.0, 10e3, match)
        assert alpha == pytest.approx(alpha_of(p), rel=1e-14, abs=1e-15)
        assert k == pytest.approx(k_of(p, 10e3), rel=1e-14)
        assert alpha_psi == 0.0


@pytest.mark.parametrize("match", MATCHES[1:])
@pytest.mark.parametrize("phi", [5.0, 19.8, 35.0, 50.0])
def test_every_match_is_the_associated_one_when_psi_equals_phi(match, phi):
    p = math.radians(phi)
    np.testing.assert_allclose(dp_constants(p, p, 7e3, match), dp_constants(p, p, 7e3, "plane-strain-associated"),
                               rtol=1e-13)


@pytest.mark.parametrize("match", MATCHES)
def test_every_match_keeps_mohr_coulombs_apex(match):
    """The cone's apex ``k / (3 alpha)`` is Mohr-Coulomb's ``c cot(phi)`` for every psi."""
    for phi in (10.0, 19.8, 35.0):
        for psi in (0.0, phi / 2, phi):
            alpha, k, _ = dp_constants(math.radians(phi), math.radians(psi), 5e3, match)
            assert k / (3 * alpha) == pytest.approx(5e3 / math.tan(math.radians(phi)), rel=1e-12)


def test_an_unknown_match_is_refused():
    with pytest.raises(ValueError, match="mohr_coulomb_match"):
        dp_constants(0.5, 0.0, 1e3, "triaxial")


PSIS = (0.0, 10.0, 30.0)
CONES = ((19.8, 0.0), (35.0, 10e3))  # (phi deg, c Pa)
_DRIVERS: dict[str, MaterialPointDriver] = {}


def _steady_flow(match, phi, c, L, steps=3000, dt=2e-7):
    """Drive one point per psi in PSIS (a stiff cone, so the Jaumann spin is negligible: p / G ~ 1e-5)
    with a constant velocity gradient from -100 kPa isotropic until the stress stops changing.
    One driver per match holds every cone of CONES (a driver compiles its kernel once)."""
    if match not in _DRIVERS:
        mats = tuple(Material("dp", "drucker-prager", 2000.0, 1e10, NU, cohesion_pa=cc,
                              friction_angle_rad=math.radians(ph), dilatancy_angle_rad=math.radians(psi),
                              mohr_coulomb_match=match) for ph, cc in CONES for psi in PSIS)
        _DRIVERS[match] = MaterialPointDriver(mats, len(PSIS))
    drv = _DRIVERS[match]
    ids = CONES.index((phi, c)) * len(PSIS) + np.arange(len(PSIS))
    s0 = np.tile([-100e3, -100e3, 0.0, -100e3], (len(PSIS), 1))
    out = drv.run(s0, L, dt, steps, material_ids=ids)["stress"]
    again = drv.run(out, L, dt, 200, material_ids=ids)["stress"]
    np.testing.assert_allclose(again, out, rtol=1e-6, atol=1e-3)  # steady plastic flow
    return out


@pytest.mark.parametrize("match", MATCHES)
@pytest.mark.parametrize("phi, c", CONES)
def test_in_plane_flow_meets_mohr_coulomb_in_plane_strain_where_the_match_says(match, phi, c):
    """Plane-strain flow (no rotation) dilating at psi (``de_v = sin(psi) de_max-shear``, Mohr-Coulomb's
    rate): at steady flow the in-plane Mohr circle (centre p, radius t) touches Mohr-Coulomb's line
    ``t = c cos(phi) - p sin(phi)`` under "plane-strain" for every psi, under the others for psi = phi;
    out of plane ``s_zz = -2 alpha_psi sqrt(J2)``."""
    shear = 1.0
    L = np.array([[[0.5 * (math.sin(math.radians(psi)) + 1.0) * shear, 0.0],
                   [0.0, 0.5 * (math.sin(math.radians(psi)) - 1.0) * shear]] for psi in PSIS])
    s = _steady_flow(match, phi, c, L)
    p_in = 0.5 * (s[:, 0] + s[:, 1])
    t = np.hypot(0.5 * (s[:, 0] - s[:, 1]), s[:, 2])
    mc = c * math.cos(math.radians(phi)) - p_in * math.sin(math.radians(phi))
    i1, q = invariants(s)
    for n, psi in enumerate(PSIS):
        _, _, a = dp_constants(math.radians(phi), math.radians(psi), c, match)
        assert s[n, 3] - i1[n] / 3 == pytest.approx(-2 * a * q[n], rel=1e-6, abs=1e-3)
        if match == "plane-strain" or psi == phi:
            assert t[n] == pytest.approx(mc[n], rel=1e-6)
        elif match == "plane-strain-associated":
            assert t[n] < mc[n] * (1 - 1e-5)  # weaker than Mohr-Coulomb
        else:
            assert t[n] > mc[n] * (1 + 1e-5)  # stronger than Mohr-Coulomb


@pytest.mark.parametrize("match", MATCHES)
@pytest.mark.parametrize("phi, c", CONES)
def test_simple_shear_meets_tan_phi_on_the_shear_plane_where_the_match_says(match, phi, c):
    """Simple shear along x dilating at psi (``de_yy = tan(psi) dgamma``): at steady flow the shear
    plane carries ``tau = c - sigma_yy tan(phi)`` under "simple-shear" for every psi, under the
    others for psi = phi; under "plane-strain" what a coaxial Mohr-Coulomb material carries there,
    ``(c cos(phi) - sigma_yy sin(phi)) cos(psi) / (1 - sin(phi) sin(psi))`` (Davis 1968)."""
    gamma = 1.0
    L = np.array([[[0.0, gamma], [0.0, math.tan(math.radians(psi)) * gamma]] for psi in PSIS])
    s = _steady_flow(match, phi, c, L)
    f = math.radians(phi)
    for n, psi in enumerate(PSIS):
        y = math.radians(psi)
        tau, sigma_n = s[n, 2], s[n, 1]
        lem = c - sigma_n * math.tan(f)
        davis = (c * math.cos(f) - sigma_n * math.sin(f)) * math.cos(y) / (1 - math.sin(f) * math.sin(y))
        if match == "simple-shear" or psi == phi:
            assert tau == pytest.approx(lem, rel=1e-4)
        if match == "plane-strain":
            assert tau == pytest.approx(davis, rel=1e-4)
        if match == "plane-strain-associated" and psi < phi:
            assert tau < davis * (1 - 1e-5)


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
