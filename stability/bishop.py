"""Bishop's simplified method of slices for circular slip surfaces, with a search for the critical circle.

Conventions: SI units, x to the right, y up, gravity along -y (rotate a section first when the
gravity of a model is inclined). Compression is not used here: the normal force on a slice base
follows from the slice's vertical equilibrium. No pore pressure (dry or total-stress analyses).

A :class:`Section` is a set of polygons, each of one Mohr-Coulomb :class:`Soil`; where polygons
overlap the *later* one owns the overlap (the same rule as the bodies of a project). The ground
surface is the upper outline of their union and the lowest point of the union is the rigid base:
slip circles must stay inside the section (a circle that would pass below the material of a
column, or reach the left or right end of the section, is not admissible).

The method (Bishop 1955, "The use of the slip circle in the stability analysis of slopes",
Geotechnique 5(1), 7-17), for slices of width ``b``, weight ``W`` (per metre out of plane) and
base inclination ``alpha`` (positive where the base rises in the direction of sliding)::

    F = sum[(c b + W tan(phi)) / m_alpha] / sum[W sin(alpha)],
    m_alpha = cos(alpha) + sin(alpha) tan(phi) / F

solved by fixed-point iteration from the ordinary (Fellenius 1936) value
``F = sum[c l + W cos(alpha) tan(phi)] / sum[W sin(alpha)]`` with ``l = b / cos(alpha)``. For
``phi = 0`` both reduce to the same exact moment balance of a circle. ``m_alpha / cos(alpha) =
1 + tan(alpha) tan(phi) / F`` is floored at 0.2 (the usual guard against steep negative base
angles at the toe of deep circles, after Whitman and Bailey 1967); it never acts where phi = 0.
In each column ``c b`` is written ``c l cos(alpha)`` with the exact length ``l`` of the arc below
the ground in that column, so the steep ends of an arc are integrated exactly.

Slices are the columns of a fine raster over the section (``columns`` of them, default 300):
the weight of a slice is the raster's cumulative weight above the slip surface in its column
(``rows`` cells per column, default 600), its strength that of the soil at the base.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

#: Floor of Bishop's m_alpha / cos(alpha) (after Whitman and Bailey 1967).
M_ALPHA_MIN = 0.2


@dataclass(frozen=True)
class Soil:
    """Mohr-Coulomb strength and unit weight of one soil.

    Attributes
    ----------
    cohesion_pa : float, Pa
    friction_angle_rad : float, rad
    unit_weight_n_m3 : float, N/m3 (density times |g|)
    """

    cohesion_pa: float
    friction_angle_rad: float
    unit_weight_n_m3: float


@dataclass(frozen=True)
class Circle:
    """A slip circle: centre (m) and radius (m)."""

    centre_x_m: float
    centre_y_m: float
    radius_m: float


@dataclass(frozen=True)
class SlipResult:
    """The critical circle of a search.

    Attributes
    ----------
    factor : float
        Bishop's factor of safety of the circle (the minimum found).
    circle : Circle
    entry_x_m, exit_x_m : float, m
        The horizontal extent of the sliding mass.
    circles_tried : int
    fellenius_factor : float
        The ordinary method's factor of the same circle.
    """

    factor: float
    circle: Circle
    entry_x_m: float
    exit_x_m: float
    circles_tried: int
    fellenius_factor: float

    def to_dict(self) -> dict:
        """JSON-ready: ``factor_of_safety``, ``circle`` {``centre_m``, ``radius_m``}, extent, counts."""
        c = self.circle
        return {
            "method": "bishop-simplified",
            "factor_of_safety": float(self.factor),
            "circle": {"centre_m": [float(c.centre_x_m), float(c.centre_y_m)], "radius_m": float(c.radius_m)},
            "entry_x_m": float(self.entry_x_m),
            "exit_x_m": float(self.exit_x_m),
            "fellenius_factor_of_safety": float(self.fellenius_factor),
            "circles_tried": int(self.circles_tried),
        }


def _points_in_polygon(x: np.ndarray, y: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Even-odd rule for points (x, y) (same shape) in one polygon (K, 2)."""
    inside = np.zeros(x.shape, dtype=bool)
    px, py = polygon[:, 0], polygon[:, 1]
    qx, qy = np.roll(px, -1), np.roll(py, -1)
    for x0, y0, x1, y1 in zip(px, py, qx, qy):
        if y0 == y1:
            continue
        crosses = (y0 > y) != (y1 > y)
        xi = x0 + (y - y0) * (x1 - x0) / (y1 - y0)
        inside ^= crosses & (x < xi)
    return inside


class Section:
    """A 2D section of polygons of soils, rasterised for fast slice integration.

    Parameters
    ----------
    polygons : sequence of (K, 2) array_like, m
        Vertices in order (either orientation); later polygons own overlaps.
    soils : sequence of Soil
        One per polygon.
    columns, rows : int
        Raster resolution (columns are the slices; rows integrate the weight of a column).
    """

    def __init__(self, polygons: Sequence[np.ndarray], soils: Sequence[Soil], columns: int = 300, rows: int = 600):
        if len(polygons) != len(soils) or not polygons:
            raise ValueError("give one soil per polygon and at least one polygon")
        self.polygons = [np.asarray(p, dtype=np.float64).reshape(-1, 2) for p in polygons]
        self.soils = tuple(soils)
        pts = np.vstack(self.polygons)
        self.x_min, self.y_min = pts.min(axis=0)
        self.x_max, self.y_max = pts.max(axis=0)
        self.dx = (self.x_max - self.x_min) / columns
        self.dy = (self.y_max - self.y_min) / rows
        self.x = self.x_min + (np.arange(columns) + 0.5) * self.dx  # column centres
        yc = self.y_min + (np.arange(rows) + 0.5) * self.dy  # cell centres
        X, Y = np.meshgrid(self.x, yc, indexing="ij")
        owner = np.full(X.shape, -1, dtype=np.int64)
        for k, poly in enumerate(self.polygons):
            owner[_points_in_polygon(X, Y, poly)] = k
        self.owner = owner  # (columns, rows), -1 = no material
        gamma = np.array([s.unit_weight_n_m3 for s in self.soils] + [0.0])
        cell_w = gamma[owner] * self.dy
        # weight per unit width of the material above each row node, nodes 0..rows (bottom to top)
        above = np.zeros((columns, rows + 1))
        above[:, :-1] = np.cumsum(cell_w[:, ::-1], axis=1)[:, ::-1]
        self.weight_above = above
        self.cohesion = np.array([s.cohesion_pa for s in self.soils] + [0.0])
        self.tan_phi = np.array([math.tan(s.friction_angle_rad) for s in self.soils] + [0.0])
        filled = owner >= 0
        has = filled.any(axis=1)
        top_index = np.where(has, rows - np.argmax(filled[:, ::-1], axis=1), 0)
        bottom_index = np.where(has, np.argmax(filled, axis=1), rows)
        self.top = self.y_min + top_index * self.dy  # ground surface of each column (m)
        self.bottom = self.y_min + bottom_index * self.dy  # lowest material of each column (m)
        self.height_m = float(self.top.max() - self.top.min()) or float(self.y_max - self.y_min)

    # ------------------------------------------------------------------ slices of circles
    def _slices(self, xc: np.ndarray, yc: np.ndarray, r: np.ndarray, min_depth_m: float):
        """Slice arrays (M, columns) of M circles: the part of each column's arc below the ground.

        Returns offsets of the arc's mid-point from the centre, the arc's angles at its two ends
        (rad, from the downward vertical), slice weights (N/m), soil index, mass mask, validity (M,).
        """
        dxs = self.x[None, :] - xc[:, None]
        half = 0.5 * self.dx
        # the lower arc is below the ground of a column where |d| < d_exit (ground as flat at its top)
        rise = yc[:, None] - self.top[None, :]
        d_exit = np.sqrt(np.clip(r[:, None] ** 2 - np.maximum(rise, 0.0) ** 2, 0.0, None))
        d_lo = np.maximum(dxs - half, -d_exit)
        d_hi = np.minimum(dxs + half, d_exit)
        mass = d_hi > d_lo
        d_lo = np.where(mass, d_lo, 0.0)
        d_hi = np.where(mass, d_hi, 0.0)
        th_lo = np.arcsin(np.clip(d_lo / r[:, None], -1.0, 1.0))
        th_hi = np.arcsin(np.clip(d_hi / r[:, None], -1.0, 1.0))
        d_mid = 0.5 * (d_lo + d_hi)
        ys = yc[:, None] - np.sqrt(np.clip(r[:, None] ** 2 - d_mid ** 2, 0.0, None))
        depth = np.where(mass, self.top[None, :] - ys, 0.0)
        below_base = np.any(mass & (ys < self.bottom[None, :] - 1e-9 * max(1.0, abs(self.y_min))), axis=1)
        at_ends = mass[:, 0] | mass[:, -1]
        # the lower arc must come out through the ground on both sides: its ends (xc -+ r, yc) lie
        # above the ground (else the slip surface would have to turn back over the centre)
        buried = (np.interp(xc - r, self.x, self.top) > yc) | (np.interp(xc + r, self.x, self.top) > yc)
        valid = mass.any(axis=1) & ~below_base & ~at_ends & ~buried & (depth.max(axis=1) >= min_depth_m)
        # weight above the slip surface: linear interpolation in the column's cumulative weight
        rows = self.weight_above.shape[1] - 1
        t = np.clip((ys - self.y_min) / self.dy, 0.0, rows)
        k = np.minimum(t.astype(np.int64), rows - 1)
        f = t - k
        cols = np.broadcast_to(np.arange(len(self.x))[None, :], ys.shape)
        w_above = (1 - f) * self.weight_above[cols, k] + f * self.weight_above[cols, k + 1]
        weight = np.where(mass, w_above * (d_hi - d_lo), 0.0)
        cell = np.clip(np.floor(t).astype(np.int64), 0, rows - 1)
        owner = self.owner[cols, cell]
        soil = np.where(owner >= 0, owner, len(self.soils))
        return d_mid, th_lo, th_hi, weight, soil, mass, valid

    def factors(self, xc, yc, r, min_depth_m: float = 0.0, iterations: int = 60) -> tuple[np.ndarray, np.ndarray]:
        """Bishop's and Fellenius' factors of circles (NaN where a circle is not admissible).

        Parameters
        ----------
        xc, yc, r : array_like, shape (M,), m
        min_depth_m : float, m
            Circles whose sliding mass is nowhere deeper than this are not admissible.

        Returns
        -------
        bishop, fellenius : numpy.ndarray, shape (M,)
        """
        xc, yc, r = (np.atleast_1d(np.asarray(v, dtype=np.float64)) for v in (xc, yc, r))
        positive = r > 0.0
        r = np.where(positive, r, 1.0)
        dxs, th_l, th_r, w, soil, mass, valid = self._slices(xc, yc, r, min_depth_m)
        moment = np.sum(w * dxs, axis=1)
        sign = np.where(moment >= 0.0, 1.0, -1.0)
        length = r[:, None] * (th_r - th_l)  # the arc in each column, exactly (m)
        sin_a = sign[:, None] * np.sin(0.5 * (th_l + th_r))
        cos_a = np.cos(0.5 * (th_l + th_r))
        c = np.where(mass, self.cohesion[soil], 0.0)
        tp = np.where(mass, self.tan_phi[soil], 0.0)
        drive = np.sum(w * sin_a, axis=1)
        valid &= (drive > 0.0) & positive
        drive = np.where(valid, drive, 1.0)
        fellenius = np.sum(np.where(mass, c * length + w * cos_a * tp, 0.0), axis=1) / drive
        f = np.maximum(fellenius, 1e-3)
        # c b is c l cos(alpha) with the column's exact arc length (steep ends of an arc included)
        resist = np.where(mass, c * length * cos_a + w * tp, 0.0)
        f = np.where(valid, f, 1.0)
        for _ in range(iterations):
            m_alpha = cos_a * np.maximum(1.0 + sin_a * tp / (cos_a * f[:, None] + 1e-300), M_ALPHA_MIN)
            f_new = np.maximum(np.sum(resist / m_alpha, axis=1) / drive, 1e-6)
            done = np.all(np.abs(f_new - f) <= 1e-7 * np.abs(f_new))
            f = f_new
            if done:
                break
        return np.where(valid, f, np.nan), np.where(valid, fellenius, np.nan)

    def extent(self, circle: Circle) -> tuple[float, float]:
        """x of the first and last slice of the sliding mass of a circle (m)."""
        _, _, _, _, _, mass, _ = self._slices(np.array([circle.centre_x_m]), np.array([circle.centre_y_m]),
                                        np.array([circle.radius_m]), 0.0)
        xs = self.x[mass[0]]
        if xs.size == 0:
            return (math.nan, math.nan)
        return float(xs.min() - 0.5 * self.dx), float(xs.max() + 0.5 * self.dx)


def bishop_factor(section: Section, circle: Circle) -> float:
    """Bishop's simplified factor of safety of one circle (NaN if not admissible)."""
    return float(section.factors([circle.centre_x_m], [circle.centre_y_m], [circle.radius_m])[0][0])


def fellenius_factor(section: Section, circle: Circle) -> float:
    """The ordinary (Fellenius) method's factor of safety of one circle (NaN if not admissible)."""
    return float(section.factors([circle.centre_x_m], [circle.centre_y_m], [circle.radius_m])[1][0])


def slices_factor(weight_n: np.ndarray, alpha_rad: np.ndarray, width_m: np.ndarray, cohesion_pa: np.ndarray,
                  friction_angle_rad: np.ndarray, pore_pressure_pa: np.ndarray | float = 0.0,
                  method: str = "bishop", iterations: int = 100) -> float:
    """Factor of safety of a slip circle given as a table of slices (hand-calculation form).

    Parameters
    ----------
    weight_n : (S,) N per metre out of plane
    alpha_rad : (S,) rad, base inclination, positive where the base rises in the direction of sliding
    width_m : (S,) m
    cohesion_pa, friction_angle_rad : (S,) Pa, rad
    pore_pressure_pa : (S,) or float, Pa, on the slice bases
    method : {"bishop", "fellenius"}

    Returns
    -------
    float
    """
    w, a, b, c, phi = (np.asarray(v, dtype=np.float64) for v in (weight_n, alpha_rad, width_m, cohesion_pa,
                                                                   friction_angle_rad))
    u = np.broadcast_to(np.asarray(pore_pressure_pa, dtype=np.float64), w.shape)
    tp = np.tan(phi)
    drive = float(np.sum(w * np.sin(a)))
    if drive <= 0.0:
        raise ValueError("the slices drive no sliding (sum of W sin(alpha) <= 0)")
    length = b / np.cos(a)
    fellenius = float(np.sum(c * length + (w * np.cos(a) - u * length) * tp) / drive)
    if method == "fellenius":
        return fellenius
    if method != "bishop":
        raise ValueError(f"unknown method {method!r}; allowed: bishop, fellenius")
    f = max(fellenius, 1e-3)
    resist = c * b + (w - u * b) * tp
    for _ in range(iterations):
        m_alpha = np.cos(a) * np.maximum(1.0 + np.tan(a) * tp / f, M_ALPHA_MIN)
        f_new = float(np.sum(resist / m_alpha) / drive)
        if abs(f_new - f) <= 1e-10 * abs(f_new):
            return f_new
        f = f_new
    return f


def critical_circle(section: Section, *, centres: int = 21, radii: int = 40, refinements: int = 6,
                    min_depth_m: float | None = None, batch: int = 4000) -> SlipResult:
    """Search the circle of least Bishop factor: a grid of centres and radii, then refined grids.

    The first grid spans centres over the section's width (plus half of it on either side) and
    from the lowest ground point to three section heights above the highest; for each centre,
    the circles through ``radii`` evenly spaced points of the ground surface and through each
    vertex of the polygons that lies on the surface (toe, crest, breaks of slope), and the circle
    tangent to the base. The best circles of the three best centres each start a pattern search: a 7 x 7 x 7
    grid of centres and radii around the best circle so far, in a box half as large each round.

    Parameters
    ----------
    section : Section
    centres : int
        Grid points per centre axis.
    radii : int
        Evenly spaced ground points the circles of each centre pass through.
    refinements : int
    min_depth_m : float, optional, m
        Smallest admissible depth of a sliding mass (default 2 % of the section's height, at
        least two raster rows): excludes skin slides that the raster cannot resolve.

    Returns
    -------
    SlipResult

    Raises
    ------
    ValueError
        When no admissible circle is found.
    """
    height = section.height_m
    if min_depth_m is None:
        min_depth_m = max(0.02 * height, 2.0 * section.dy)
    width = section.x_max - section.x_min
    x_lo, x_hi = section.x_min - 0.5 * width, section.x_max + 0.5 * width
    y_lo, y_hi = float(section.top.min()), float(section.top.max()) + 3.0 * max(height, section.y_max - section.y_min)
    best: tuple[float, tuple[float, float, float] | None] = (math.inf, None)
    tried = 0
    found: list[tuple[float, tuple[float, float, float]]] = []

    def evaluate(xs, ys, rs, keep: int = 1):
        nonlocal tried
        for s in range(0, len(xs), batch):
            f, _ = section.factors(xs[s:s + batch], ys[s:s + batch], rs[s:s + batch], min_depth_m)
            tried += int(np.count_nonzero(np.isfinite(f)))
            order = np.argsort(np.where(np.isfinite(f), f, np.inf))[:keep]
            found.extend((float(f[k]), (float(xs[s + k]), float(ys[s + k]), float(rs[s + k])))
                         for k in order if np.isfinite(f[k]))

    gx = np.linspace(x_lo, x_hi, centres)
    gy = np.linspace(y_lo, y_hi, centres)
    X, Y = np.meshgrid(gx, gy, indexing="ij")
    X, Y = X.ravel(), Y.ravel()
    # radii: circles through points of the ground surface (its vertices, where slope breaks
    # are, and ``radii`` evenly spaced ones), plus circles tangent to the base
    verts = np.vstack(section.polygons)
    on_top = np.abs(verts[:, 1] - np.interp(verts[:, 0], section.x, section.top)) <= 1.01 * section.dy
    px = np.concatenate([np.linspace(section.x_min, section.x_max, radii + 2)[1:-1], verts[on_top, 0]])
    px = np.clip(px, section.x[0], section.x[-1])
    py = np.interp(px, section.x, section.top)
    R = np.hypot(X[:, None] - px[None, :], Y[:, None] - py[None, :])
    R = np.concatenate([R, (Y - section.y_min)[:, None]], axis=1)
    n_r = R.shape[1]
    # the best circle of each centre starts a refinement if it is among the ``starts`` best
    fac, _ = section.factors(np.repeat(X, n_r), np.repeat(Y, n_r), R.ravel(), min_depth_m)
    tried += int(np.count_nonzero(np.isfinite(fac)))
    fac = np.where(np.isfinite(fac), fac, np.inf).reshape(-1, n_r)
    per_centre = np.argmin(fac, axis=1)
    best_f = fac[np.arange(len(X)), per_centre]
    if not np.isfinite(best_f).any():
        raise ValueError("no admissible slip circle in this section")
    starts = [int(i) for i in np.argsort(best_f)[:3] if np.isfinite(best_f[i])]
    h0 = ((x_hi - x_lo) / (centres - 1), (y_hi - y_lo) / (centres - 1))
    for i in starts:
        # pattern search in (xc, yc, r) around a start, the box shrinking each round
        cur = (float(best_f[i]), (float(X[i]), float(Y[i]), float(R[i, per_centre[i]])))
        hx, hy = h0
        hr = max(hx, hy)
        for _ in range(refinements):
            cx, cy, cr = cur[1]
            n = 7
            A, B, C = np.meshgrid(cx + np.linspace(-hx, hx, n), cy + np.linspace(-hy, hy, n),
                                  cr + np.linspace(-hr, hr, n), indexing="ij")
            keep = C.ravel() > 0
            found.clear()
            evaluate(A.ravel()[keep], B.ravel()[keep], C.ravel()[keep])
            if found and min(found)[0] < cur[0]:
                cur = min(found)
            hx, hy, hr = hx / 2.0, hy / 2.0, hr / 2.0
        if cur[0] < best[0]:
            best = cur
    cx, cy, cr = best[1]
    circle = Circle(cx, cy, cr)
    fel = float(section.factors([cx], [cy], [cr], min_depth_m)[1][0])
    entry, exit_ = section.extent(circle)
    return SlipResult(best[0], circle, entry, exit_, tried, fel)
