"""Perfectly plastic, non-associated Drucker-Prager return mapping (plane strain, 3D stress state).

Yield function and plastic potential (compression negative, I1 = tr(sigma) over all three
normal components, J2 the second invariant of the deviator):

    f = sqrt(J2) + alpha * I1 - k          g = sqrt(J2) + alpha_psi * I1

matched to Mohr-Coulomb in plane strain (the paper, after Bui et al. 2008):
``alpha = tan(phi) / sqrt(9 + 12 tan^2 phi)``, ``k = 3 c / sqrt(9 + 12 tan^2 phi)`` and
``alpha_psi`` from the dilatancy angle psi in place of phi.

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

import taichi as ti


def dp_constants(friction_angle_rad: float, dilatancy_angle_rad: float, cohesion_pa: float) -> tuple[float, float, float]:
    """(alpha, k, alpha_psi) of the plane-strain Mohr-Coulomb match."""
    tp = math.tan(friction_angle_rad)
    tq = math.tan(dilatancy_angle_rad)
    alpha = tp / math.sqrt(9.0 + 12.0 * tp * tp)
    k = 3.0 * cohesion_pa / math.sqrt(9.0 + 12.0 * tp * tp)
    alpha_psi = tq / math.sqrt(9.0 + 12.0 * tq * tq)
    return alpha, k, alpha_psi


@ti.func
def return_map(s, K, G, alpha, kc, alpha_psi, t_cut):
    """Project the trial stress ``s`` (vec4 xx, yy, xy, zz) back onto the admissible set.

    Returns (stress vec4, equivalent plastic strain increment, yielded 0/1).
    """
    p = (s[0] + s[1] + s[3]) / 3.0
    d0 = s[0] - p
    d1 = s[1] - p
    dz = s[3] - p
    d01 = s[2]
    sq = ti.sqrt(0.5 * (d0 * d0 + d1 * d1 + dz * dz) + d01 * d01)
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
    # tension cut-off on the mean stress
    pm = (out[0] + out[1] + out[3]) / 3.0
    if pm > t_cut:
        shift = pm - t_cut
        out = ti.Vector([out[0] - shift, out[1] - shift, out[2], out[3] - shift])
        yielded = 1
    return out, deq, yielded
