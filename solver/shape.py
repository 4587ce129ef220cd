"""The grid's ghost layers and the quadratic B-spline shape functions, shared by the engine and its
components.

Grid node ``(i, j)`` sits at ``origin + (i - PAD, j - PAD) * dx``; ``PAD`` ghost layers keep every
particle's 3x3 stencil inside the arrays. The weight of stencil node ``i`` (0, 1, 2) at the
fractional offset ``f`` (cell units, from the stencil's base node) is the quadratic B-spline
``N(f - i)``: ``0.5 (1.5 - f)^2``, ``0.75 - (f - 1)^2``, ``0.5 (f - 0.5)^2``.
"""


from solver.runtime import ti

PAD = 2


@ti.func
def bspline(f, i):
    """Quadratic B-spline weight of stencil node ``i`` (0, 1, 2) at fractional offset ``f``."""
    r = 0.5 * (f - 0.5) ** 2
    if i == 0:
        r = 0.5 * (1.5 - f) ** 2
    elif i == 1:
        r = 0.75 - (f - 1.0) ** 2
    return r


@ti.func
def bspline_slope(f, i):
    """Derivative of :func:`bspline` with respect to the position, in cell units."""
    r = f - 0.5
    if i == 0:
        r = f - 1.5
    elif i == 1:
        r = -2.0 * (f - 1.0)
    return r
