"""Perfectly plastic, non-associated Drucker-Prager return mapping (plane strain, 3D stress state).

Yield function and plastic potential (compression negative, I1 = tr(sigma) over all three
normal components, J2 the second invariant of the deviator):

    f = sqrt(J2) + alpha * I1 - k          g = sqrt(J2) + alpha_psi * I1

matched to Mohr-Coulomb (c, phi, psi) in one of three ways, ``dp_constants``'s ``match``. In every
one the potential's coefficient is ``alpha_psi = tan(psi) / sqrt(9 + 12 tan^2 psi)``: the cone then
dilates at psi in plane strain (``sin psi = de_v / de_max-shear`` in the plane, and
``tan psi = de_n / dgamma`` in simple shear; both give this one coefficient). The cone's own
alpha, k are found from plastic flow in plane strain, where the flow rule fixes the out-of-plane
stress (``s_zz = -2 alpha_psi sqrt(J2)``, zero out-of-plane plastic strain):

- ``"plane-strain-associated"`` (the paper, after Bui et al. 2008; the default):
  ``alpha = tan(phi) / sqrt(9 + 12 tan^2 phi)``, ``k = 3 c / sqrt(9 + 12 tan^2 phi)``. Exact for
  psi = phi; with psi < phi the cone is weaker than Mohr-Coulomb in plane strain.
- ``"plane-strain"``: the in-plane Mohr circle (centre ``p``, radius ``t``) at yield under the
  cone's own flow rule, ``t = sqrt(1 - 3 a^2) (k - 3 alpha p) / (1 - 3 alpha a)`` (a = alpha_psi),
  equals Mohr-Coulomb's ``t = c cos(phi) - p sin(phi)``:
  ``alpha = sin(phi) / (3 sqrt(1 - 3 a^2) + 3 a sin(phi))``,
  ``k = c cos(phi) (1 - 3 alpha a) / sqrt(1 - 3 a^2)``. Every plane-strain stress path of the cone
  then fails where a Mohr-Coulomb material does; psi = 0 gives ``alpha = sin(phi) / 3``,
  ``k = c cos(phi)`` (the Abaqus Theory Manual's plane-strain match for non-dilatant flow).
- ``"simple-shear"``: in simple shear (no strain along the shear plane nor out of plane) the cone
  carries ``tau = sqrt(1 - 12 a^2) (k - 3 alpha sigma_n) / (1 - 12 alpha a)`` on the shear plane;
  equal to ``c - sigma_n tan(phi)``: ``alpha = tan(phi) / (3 sqrt(1 - 12 a^2) + 12 a tan(phi))``,
  ``k = c (1 - 12 alpha a) / sqrt(1 - 12 a^2)`` (``= 3 alpha c / tan(phi)``). The direct-shear
  reading of phi, and the limit-equilibrium infinite slope; psi = 0 gives ``alpha = tan(phi) / 3``,
  ``k = c``, which in any other plane-strain path is Mohr-Coulomb with ``sin(phi') = tan(phi)``
  (stronger than Mohr-Coulomb).

All three coincide for psi = phi. docs/solver.md gives the derivation.

Return from an elastic trial state with f > 0 (closed form, one step, exact for linear
elasticity): ``dlam = f / (G + 9 K alpha alpha_psi)``; deviator scaled by
``1 - G dlam / sqrt(J2)``; ``I1 -= 9 K alpha_psi dlam``. When that would overshoot the cone's
apex (scale < 0) the stress returns to the apex, a hydrostatic state with ``I1 = k / alpha``.
Then the tension cut-off caps the mean stress at ``t_cut`` (the smaller of the tensile strength
and the apex), leaving the deviator unchanged (lowering I1 only moves the state inside the cone).

The equivalent plastic strain increment is ``sqrt(2/3 de:de)`` with ``de`` the deviatoric
plastic strain increment, ``(s_trial - s_new) / (2 G)``.
"""

import math

import numpy as np
from solver.materials import softening
from solver.runtime import ti


MATCHES: tuple[str, ...] = ("plane-strain-associated", "plane-strain", "simple-shear")


def dp_constants(friction_angle_rad: float, dilatancy_angle_rad: float, cohesion_pa: float,
                 match: str = "plane-strain-associated") -> tuple[float, float, float]:
    """(alpha, k, alpha_psi) of the cone matched to Mohr-Coulomb (module docstring).

    Parameters
    ----------
    friction_angle_rad, dilatancy_angle_rad : float
        Mohr-Coulomb's phi and psi, rad (0 <= psi <= phi < pi/2).
    cohesion_pa : float
        Mohr-Coulomb's c, Pa.
    match : str
        One of ``MATCHES``.

    Returns
    -------
    alpha : float
        The cone's slope (dimensionless).
    k : float
        The cone's strength at I1 = 0, Pa.
    alpha_psi : float
        The potential's slope (dimensionless).
    """
    tp = math.tan(friction_angle_rad)
    tq = math.tan(dilatancy_angle_rad)
    a = tq / math.sqrt(9.0 + 12.0 * tq * tq)
    if match == "plane-strain-associated":
        alpha = tp / math.sqrt(9.0 + 12.0 * tp * tp)
        k = 3.0 * cohesion_pa / math.sqrt(9.0 + 12.0 * tp * tp)
    elif match == "plane-strain":
        sp = math.sin(friction_angle_rad)
        root = math.sqrt(1.0 - 3.0 * a * a)
        alpha = sp / (3.0 * root + 3.0 * a * sp)
        k = cohesion_pa * math.cos(friction_angle_rad) * (1.0 - 3.0 * alpha * a) / root
    elif match == "simple-shear":
        root = math.sqrt(1.0 - 12.0 * a * a)
        alpha = tp / (3.0 * root + 12.0 * a * tp)
        k = cohesion_pa * (1.0 - 12.0 * alpha * a) / root
    else:
        raise ValueError(f"mohr_coulomb_match {match!r}: must be one of {', '.join(MATCHES)}")
    return alpha, k, a


@ti.func
def _split(s):
    """Mean stress, deviator (xx, yy, zz, xy) and sqrt(J2) of the stress vec4 ``s``."""
    p = (s[0] + s[1] + s[3]) / 3.0
    d0 = s[0] - p
    d1 = s[1] - p
    dz = s[3] - p
    d01 = s[2]
    sq = ti.sqrt(0.5 * (d0 * d0 + d1 * d1 + dz * dz) + d01 * d01)
    return p, d0, d1, dz, d01, sq


@ti.func
def _cut_tension(stress, t_cut):
    """The tension cut-off: the mean stress capped at ``t_cut``, the deviator kept; (stress, 1 where cut)."""
    out = stress
    pm = (out[0] + out[1] + out[3]) / 3.0
    cut = 0
    if pm > t_cut:
        shift = pm - t_cut
        out = ti.Vector([out[0] - shift, out[1] - shift, out[2], out[3] - shift])
        cut = 1
    return out, cut


@ti.func
def return_map(s, K, G, alpha, kc, alpha_psi, t_cut):
    """Project the trial stress ``s`` (vec4 xx, yy, xy, zz) back onto the admissible set.

    Returns (stress vec4, equivalent plastic strain increment, yielded 0/1).
    """
    p, d0, d1, dz, d01, sq = _split(s)
    f = sq + alpha * 3.0 * p - kc
    out = s
    deq = 0.0 * p
    yielded = 0
    tol = 1e-6 * (sq + ti.abs(alpha * 3.0 * p) + kc) + 1e-30
    if f > tol:
        yielded = 1
        dlam = f / (G + 9.0 * K * alpha * alpha_psi)
        scale = 0.0 * p
        p_new = p
        if sq - G * dlam > 0.0:
            scale = (sq - G * dlam) / sq
            p_new = p - 3.0 * K * alpha_psi * dlam
        else:
            # apex: hydrostatic state on the cone tip (alpha > 0 here, see module docstring)
            p_new = kc / (3.0 * ti.max(alpha, 1e-12))
        out = ti.Vector([p_new + scale * d0, p_new + scale * d1, scale * d01, p_new + scale * dz])
        one_minus = 1.0 - scale
        deq = ti.sqrt(2.0 / 3.0 * (d0 * d0 + d1 * d1 + dz * dz + 2.0 * d01 * d01)) * one_minus / (2.0 * G)
    out, cut = _cut_tension(out, t_cut)
    return out, deq, ti.max(yielded, cut)


@ti.func
def return_map_softening(s, K, G, eps, scale, law, e_peak, e_residual, match, peak, residual, t_tension,
                         peak_cone):
    """:func:`return_map` for a softening cone (solver/materials/softening.py): the strength at the
    end of the step, implicitly. ``eps``: the equivalent plastic strain before the step, ``scale``
    its factor to the softening strain; ``peak``, ``residual``: (c Pa, phi rad, psi rad);
    ``t_tension``: the tensile strength (Pa, 1e30 for none); ``peak_cone``: (alpha, k, alpha_psi)
    of the peak strength, the material table's (a particle short of the peak strain, most of a
    slope before it fails, then needs no trigonometry for its elastic check).

    The plastic multiplier ``dlam`` adds ``dlam / sqrt(3)`` to the equivalent plastic strain, so
    the consistency condition ``f(dlam) = sqrt(J2) - G dlam + alpha(e) (I1 - 9 K alpha_psi(e)
    dlam) - k(e) = 0`` with ``e = (eps + dlam / sqrt(3)) scale`` is solved for ``dlam`` in
    ``[0, sqrt(J2) / G]`` (the deviator gone: the apex) by the Illinois method, exact in one
    iteration where the strength does not change. Returns what :func:`return_map` returns.
    """
    p, d0, d1, dz, d01, sq = _split(s)
    root3 = ti.sqrt(3.0)
    alpha, kc, apsi = peak_cone[0], peak_cone[1], peak_cone[2]
    if eps * scale > e_peak:
        alpha, kc, apsi = _softened_cone(eps * scale, law, e_peak, e_residual, match, peak, residual)
    f = sq + alpha * 3.0 * p - kc
    out = s
    deq = 0.0 * p
    yielded = 0
    tol = 1e-6 * (sq + ti.abs(alpha * 3.0 * p) + kc) + 1e-30
    if f > tol:
        yielded = 1
        # f(dlam) at the ends of the bracket: f(0) > 0; at the apex end the deviator is gone
        hi = sq / G
        a_hi, k_hi, _ap = _softened_cone((eps + hi / root3) * scale, law, e_peak, e_residual, match, peak,
                                       residual)
        g_hi = a_hi * 3.0 * (p - 3.0 * K * _ap * hi) - k_hi
        lo = 0.0 * p
        g_lo = f
        dlam = hi
        if g_hi < 0.0:
            side = 0
            for _it in range(40):
                dlam = (lo * g_hi - hi * g_lo) / (g_hi - g_lo)
                a, k, ap = _softened_cone((eps + dlam / root3) * scale, law, e_peak, e_residual, match, peak,
                                          residual)
                g = sq - G * dlam + a * 3.0 * (p - 3.0 * K * ap * dlam) - k
                if ti.abs(g) <= tol or hi - lo <= 1e-7 * hi:
                    break
                if g > 0.0:
                    lo = dlam
                    g_lo = g
                    if side == 1:
                        g_hi *= 0.5
                    side = 1
                else:
                    hi = dlam
                    g_hi = g
                    if side == -1:
                        g_lo *= 0.5
                    side = -1
        a, k, ap = _softened_cone((eps + dlam / root3) * scale, law, e_peak, e_residual, match, peak, residual)
        scale_dev = ti.max(sq - G * dlam, 0.0) / ti.max(sq, 1e-30)
        p_new = p - 3.0 * K * ap * dlam
        if scale_dev <= 0.0 and a > 1e-12:
            p_new = k / (3.0 * a)  # the apex of the softened cone
        out = ti.Vector([p_new + scale_dev * d0, p_new + scale_dev * d1, scale_dev * d01, p_new + scale_dev * dz])
        deq = dlam / root3
        alpha = a
        kc = k
    # tension cut-off on the mean stress: the tensile strength, at most the softened cone's apex
    t_cut = t_tension
    if alpha > 0.0:
        t_cut = ti.min(t_cut, kc / (3.0 * alpha))
    out, cut = _cut_tension(out, t_cut)
    return out, deq, ti.max(yielded, cut)


@ti.func
def _softened_cone(e, law, e_peak, e_residual, match, peak, residual):
    """(alpha, k, alpha_psi) at softening strain ``e``."""
    w = softening.weight(law, e, e_peak, e_residual)
    c = peak[0] + w * (residual[0] - peak[0])
    phi = peak[1] + w * (residual[1] - peak[1])
    psi = peak[2] + w * (residual[2] - peak[2])
    return softening.cone(match, c, phi, psi)


def return_map_host(stress, K, G, alpha, kc, alpha_psi, t_cut) -> tuple[np.ndarray, np.ndarray]:
    """:func:`return_map` in numpy (float64), for many stresses at once: the admissible stress and
    whether it yielded (used on the host, e.g. to report the particles a K0 stress puts outside
    the cone; tests/unit/test_solver_thrust.py checks it against the kernel).

    Parameters
    ----------
    stress : (N, 4) Pa, xx, yy, xy, zz (compression negative)
    K, G : bulk and shear moduli, Pa, scalars or (N,)
    alpha, kc, alpha_psi, t_cut : the cone (:func:`dp_constants`; ``t_cut`` Pa), scalars or (N,)

    Returns
    -------
    (N, 4) Pa, the returned stress; (N,) bool, whether the stress was outside (plastic).
    """
    s = np.asarray(stress, dtype=np.float64).reshape(-1, 4)
    K, G, alpha, kc, alpha_psi, t_cut = np.broadcast_arrays(
        *(np.asarray(v, dtype=np.float64) for v in (K, G, alpha, kc, alpha_psi, t_cut)), s[:, 0])[:6]
    p = (s[:, 0] + s[:, 1] + s[:, 3]) / 3.0
    d0, d1, dz, d01 = s[:, 0] - p, s[:, 1] - p, s[:, 3] - p, s[:, 2]
    sq = np.sqrt(0.5 * (d0 * d0 + d1 * d1 + dz * dz) + d01 * d01)
    f = sq + alpha * 3.0 * p - kc
    tol = 1e-6 * (sq + np.abs(alpha * 3.0 * p) + kc) + 1e-30
    plastic = f > tol
    dlam = np.where(plastic, f, 0.0) / (G + 9.0 * K * alpha * alpha_psi)
    cone = sq - G * dlam > 0.0
    scale = np.where(plastic, np.where(cone, (sq - G * dlam) / np.where(sq > 0.0, sq, 1.0), 0.0), 1.0)
    p_new = np.where(plastic, np.where(cone, p - 3.0 * K * alpha_psi * dlam, kc / (3.0 * np.maximum(alpha, 1e-12))), p)
    out = np.stack([p_new + scale * d0, p_new + scale * d1, scale * d01, p_new + scale * dz], axis=1)
    pm = (out[:, 0] + out[:, 1] + out[:, 3]) / 3.0
    cut = pm > t_cut
    shift = np.where(cut, pm - t_cut, 0.0)
    out[:, [0, 1, 3]] -= shift[:, None]
    return out, plastic | cut
