"""Strain softening of the Drucker-Prager cone: cohesion, friction and dilatancy from peak to residual.

The strength parameters ``X`` (c, phi, psi) fall with the softening strain ``e``:

- ``linear``: ``X = X_p`` up to ``e_p``, ``X = X_p + (X_r - X_p) (e - e_p) / (e_r - e_p)`` between
  ``e_p`` and ``e_r``, ``X = X_r`` beyond;
- ``exponential``: ``X = X_r + (X_p - X_r) exp(-3 (e - e_p) / (e_r - e_p))`` beyond ``e_p``
  (95 % of the drop at ``e_r``).

The angles fall linearly in degrees (as Mohr-Coulomb tables give them); the cone's constants
follow from them by the material's Mohr-Coulomb match (solver/materials/drucker_prager.py), at
every strain.

The softening strain is the particle's equivalent plastic strain ``eps_p`` (the result field
``plastic_strain``) times a regularisation scale: with a material length ``l`` (the band width
the law's strains are measured over) the scale is ``h / l`` for cells of size ``h``, so that a
shear band one cell wide softens over the same displacement jump ``e_r l`` at every cell size
(fracture-energy scaling of the softening modulus; docs/solver.md). Without a length the scale is
one and the softening, and with it the run-out, depends on the cell size.
"""

import numpy as np
from solver.runtime import ti

#: Softening laws and their kernel codes (0: no softening).
LAW_CODES = {"linear": 1, "exponential": 2}
#: The exponential law's rate: ``exp(-3)`` of the drop is left at the residual strain.
EXPONENTIAL_RATE = 3.0
#: Mohr-Coulomb matches and their kernel codes (the order of drucker_prager.MATCHES).
MATCH_CODES = {"plane-strain-associated": 0, "plane-strain": 1, "simple-shear": 2}


def weight_host(law: str | int, e, e_peak: float, e_residual: float):
    """The fraction of the drop from peak to residual at softening strain ``e`` (numpy)."""
    code = LAW_CODES.get(law, law) if isinstance(law, str) else law
    e = np.asarray(e, dtype=np.float64)
    span = max(e_residual - e_peak, 1e-300)
    past = np.maximum(e - e_peak, 0.0) / span
    if code == 1:
        return np.minimum(past, 1.0)
    if code == 2:
        return 1.0 - np.exp(-EXPONENTIAL_RATE * past)
    return np.zeros_like(e)


def parameters_host(law, e, e_peak, e_residual, peak, residual):
    """(c Pa, phi rad, psi rad) at softening strain ``e``; ``peak``, ``residual``: (c, phi, psi)."""
    w = weight_host(law, e, e_peak, e_residual)
    return tuple(p + w * (r - p) for p, r in zip(peak, residual))


@ti.func
def weight(law, e, e_peak, e_residual):
    """:func:`weight_host` in a kernel."""
    span = ti.max(e_residual - e_peak, 1e-30)
    past = ti.max(e - e_peak, 0.0) / span
    w = 0.0 * e
    if law == 1:
        w = ti.min(past, 1.0)
    elif law == 2:
        w = 1.0 - ti.exp(-EXPONENTIAL_RATE * past)
    return w


@ti.func
def cone(match, c, phi, psi):
    """(alpha, k, alpha_psi) of the cone matched to Mohr-Coulomb: drucker_prager.dp_constants in a
    kernel (the same formulas, by the match's code)."""
    tp = ti.tan(phi)
    tq = ti.tan(psi)
    a = tq / ti.sqrt(9.0 + 12.0 * tq * tq)
    alpha = 0.0 * c
    k = 0.0 * c
    if match == 0:
        root = ti.sqrt(9.0 + 12.0 * tp * tp)
        alpha = tp / root
        k = 3.0 * c / root
    elif match == 1:
        sp = ti.sin(phi)
        root = ti.sqrt(1.0 - 3.0 * a * a)
        alpha = sp / (3.0 * root + 3.0 * a * sp)
        k = c * ti.cos(phi) * (1.0 - 3.0 * alpha * a) / root
    else:
        root = ti.sqrt(1.0 - 12.0 * a * a)
        alpha = tp / (3.0 * root + 12.0 * a * tp)
        k = c * (1.0 - 12.0 * alpha * a) / root
    return alpha, k, a


def check_match_codes(matches: tuple[str, ...]) -> None:
    """The kernel's match codes follow drucker_prager.MATCHES (one list decides the order)."""
    assert tuple(MATCH_CODES) == tuple(matches), (MATCH_CODES, matches)


def regularisation_scale(length_m: float | None, cell_size_m: float | None) -> float:
    """The factor from equivalent plastic strain to softening strain: ``h / l`` with a material
    length ``l``, one without (or where the cell size is not known, a single-point test)."""
    if length_m is None or cell_size_m is None:
        return 1.0
    return float(cell_size_m) / float(length_m)


__all__ = ["EXPONENTIAL_RATE", "LAW_CODES", "MATCH_CODES", "cone", "parameters_host", "regularisation_scale",
           "weight", "weight_host"]
