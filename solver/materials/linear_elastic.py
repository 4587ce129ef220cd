"""Linear isotropic elasticity with the Jaumann (co-rotational) stress rate, plane strain.

Symbols (SI): ``s`` stress as a vec4 (xx, yy, xy, zz) in Pa, tension positive; ``D`` rate of
deformation (sym part of the velocity gradient) and ``W`` spin (skew part), 1/s; ``K`` bulk and
``G`` shear modulus, Pa; ``dt`` time step, s.

Paper eq 26: sigma_dot = C^e : D + W.sigma - sigma.W. In plane strain D_zz = 0, so the
out-of-plane stress changes only through the volumetric term: dsigma_zz = lambda tr(D) dt.
The in-plane spin does not rotate sigma_zz.
"""

from solver.runtime import mat_mat, ti


@ti.func
def trial_stress(s, D, W, dt, K, G):
    """Return the elastic trial stress (vec4) after one step of the Jaumann rate."""
    lam = K - 2.0 * G / 3.0
    tr = D[0, 0] + D[1, 1]
    sig = ti.Matrix([[s[0], s[2]], [s[2], s[1]]])
    rot = mat_mat(W, sig) - mat_mat(sig, W)
    d00 = lam * tr + 2.0 * G * D[0, 0] + rot[0, 0]
    d11 = lam * tr + 2.0 * G * D[1, 1] + rot[1, 1]
    d01 = 2.0 * G * D[0, 1] + rot[0, 1]
    dzz = lam * tr
    return ti.Vector([s[0] + dt * d00, s[1] + dt * d11, s[2] + dt * d01, s[3] + dt * dzz])
