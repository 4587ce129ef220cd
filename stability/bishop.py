"""Bishop's simplified method of slices for circular slip surfaces, with water and a search for the critical circle.

Conventions: SI units, x to the right, y up, gravity along -y (rotate a section first when the
gravity of a model is inclined). Compression is not used here: the normal force on a slice base
follows from the slice's vertical equilibrium.

Geometry
--------
A :class:`Section` is a set of polygons, each of one Mohr-Coulomb :class:`Soil`; where polygons
overlap the *later* one owns the overlap (the same rule as the bodies of a project). The ground
surface is the upper outline of their union, vertical faces included; the lowest material of
each column is the rigid base there. A slip circle is admissible when its arc stays inside the
material and comes out through the ground surface on both sides: through the top of the ground
or through a vertical face (a cut, a step between bodies, the end of a body). The two ends of
the section are walls by default (``free_ends=(False, False)``): the section is cut from ground
that goes on beyond it, or stands against a wall, and no arc may pass through an end below the
ground. ``free_ends=(True, ...)`` makes the left (or right) end a free vertical face: the ground
ends there and an arc may come out through it, above the foot of the face.

The method (Bishop 1955, "The use of the slip circle in the stability analysis of slopes",
Geotechnique 5(1), 7-17), for slices of width ``b``, total weight ``W`` (per metre out of plane),
base inclination ``alpha`` (positive where the base rises in the direction of sliding), pore
pressure ``u`` on the base, effective strength ``c'``, ``phi'`` and circle radius ``R``::

    F = sum[(c' b + (W - u b) tan(phi')) / m_alpha] / (sum[W sin(alpha)] + M_w / R),
    m_alpha = cos(alpha) + sin(alpha) tan(phi') / F

solved by fixed-point iteration from the ordinary (Fellenius 1936) value
``F = sum[c' l + (W - u b) cos(alpha) tan(phi')] / (sum[W sin(alpha)] + M_w / R)`` with
``l = b / cos(alpha)`` (the effective normal force ``(W - u b) cos(alpha)``, Duncan and Wright
2005 ch. 6: the older ``W cos(alpha) - u l`` goes far wrong, even negative, under high pore
pressure and deep free water, Whitman and Bailey 1967). For ``phi = 0`` both reduce to the
same exact moment balance of a circle. ``m_alpha / cos(alpha) = 1 + tan(alpha) tan(phi) / F`` is floored at 0.2 (the usual guard
against steep negative base angles at the toe of deep circles, after Whitman and Bailey 1967);
it never acts where phi = 0. The effective base force ``W - u b`` is floored at 0 (no tension).
In each column ``c' b`` is written ``c' l cos(alpha)`` with the exact length ``l`` of the arc
below the ground in that column, so the steep ends of an arc are integrated exactly.

Water
-----
A :class:`Water` gives a phreatic (piezometric) line and a free-water line (default: the same
line); both are polylines in x, extended horizontally beyond their ends.

- Unit weight: a soil weighs ``unit_weight_n_m3`` above the phreatic line and
  ``saturated_unit_weight_n_m3`` below it (the raster splits each cell the line crosses).
- Pore pressure below the phreatic line, at a point ``h_w`` vertically below it:
  ``u = gamma_w h_w`` or, with ``inclined_correction``, ``u = gamma_w h_w cos^2(theta)`` with
  ``theta`` the local inclination of the line: the pressure head of steady seepage parallel to
  a straight inclined phreatic line, whose equipotentials are normal to it (the automatic
  ``Hu = cos^2`` of Slide2; Duncan and Wright 2005, Soil Strength and Slope Stability, ch. 6).
  No suction above the line (``u = 0``).
- Free water stands wherever the free-water line is above the ground surface (a reservoir, a
  flooded toe). Its weight ``gamma_w (h_fw - y_ground)`` per unit width is added to the weight
  ``W`` of each slice below it (where it covers the ground the phreatic line must be at or above
  its surface, so that the pore pressure below is at least hydrostatic), and the horizontal
  thrust of the free water on each end of the sliding mass, ``P = gamma_w d^2 / 2`` on the
  vertical from the arc's end (depth ``d`` below the free-water surface) up to the surface,
  acting ``d / 3`` above the arc's end, enters the moment balance as ``M_w`` (its moment about the centre, positive where it drives the
  slide). The water outside the sliding mass thus holds it as a buttress. Where the submerged
  end(s) of the mass stand in one level water body (the free water over the mass all at the
  same level ``h``) the water's weight and thrust together are, exactly in the continuum, the
  buoyancy ``gamma_w (min(h, y_ground) - y_base) b`` of each slice's soil below ``h`` (Archimedes
  over the sliding mass): ``M_w`` is evaluated in that form, on the slices' own lever arms, so
  that deep water's large weight and thrust do not cancel through the raster's round-off. Hence
  still water is the same as buoyant weights below it with the pore pressure in excess of
  hydrostatic, and buoyancy alone changes no factor of a cohesionless slope. Rapid drawdown: a
  free-water line below the phreatic line (the reservoir has fallen, the water in the slope has
  not).
- ``ru`` (Bishop and Morgenstern 1960, "Stability coefficients for earth slopes", Geotechnique
  10(4), 129-150): a soil's pore-pressure ratio gives ``u = ru sigma_v`` on a slice base in it,
  ``sigma_v = W / b`` the vertical total stress there (free water standing on it included). Where a water line also applies the
  larger of the two pore pressures is taken.

On an infinite slope of angle ``b`` with a slip plane at depth ``z`` (seepage parallel to the
slope, the line at ``m z`` above the plane, cos^2 correction; ``gamma_m`` the moist unit weight)
these give the closed forms
``F = [c' + (gamma_m (1 - m) z + gamma_sat m z - gamma_w m z) cos^2(b) tan(phi')]
/ [(gamma_m (1 - m) z + gamma_sat m z) sin(b) cos(b)]`` and, with ``ru``,
``F = c' / (gamma z sin(b) cos(b)) + (1 - ru / cos^2(b)) tan(phi') / tan(b)``.

Loads
-----
- A :class:`Surcharge` is a vertical load on the ground surface between two x, linear along it
  (per unit horizontal length): each slice's top takes the part over its stretch of x, which
  adds to its vertical load ``W`` (and so to its base's normal force) and to the driving moment
  where it lies.
- :class:`Seismic` coefficients (the pseudo-static method; Kramer 1996, Geotechnical Earthquake
  Engineering, ch. 10; Duncan and Wright 2005, ch. on seismic stability): each slice's soil, of
  weight ``W`` (water in its pores included), takes a horizontal force ``k_h W`` at its centroid
  and weighs ``(1 - k_v) W``. The horizontal forces enter the moment about the centre (their
  lever arm ``y_c - y_g``), not the slices' vertical equilibrium, so Bishop's factor is
  ``F = sum[(c' b + ((1 - k_v) W + Q - u b) tan(phi')) / m_alpha] / (sum[((1 - k_v) W + Q)
  sin(alpha)] + sum[k_h W (y_c - y_g)] / R + M_w / R)`` (``Q`` a slice's surcharge, the
  horizontal term with the sign of its moment); the ordinary method's base normal force takes
  ``k_h W sin`` of the base's inclination off (or on, the force facing the base). Free water and
  surcharges take no seismic share, and the pore pressures stay static.

On an infinite slope these give ``F = [c' + (V cos^2 b - H sin b cos b) tan(phi')] / [V sin b
cos b + H cos^2 b]``, ``V = (1 - k_v) gamma z + q`` and ``H = k_h gamma z`` per horizontal area.

Slices are the columns of a fine raster over the section (``columns`` of them, default 300):
the weight of a slice is the raster's cumulative weight above the slip surface in its column
(``rows`` cells per column, default 600), its strength that of the soil at the base. Where an
arc comes out of the ground and goes back in (in front of the toe of a cut standing on a floor,
under a hollow) the sliding mass is its run of columns with the most soil above the arc. A slip
circle must cut at least ``MIN_SLICES`` columns, and its driving moment must exceed
``DRIVE_MIN`` of its weight times its radius (a circle in level ground drives nothing; the
raster's round-off is not a mechanism): where no circle is left, the search raises
:class:`NoAdmissibleCircle`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

#: Floor of Bishop's m_alpha / cos(alpha) (after Whitman and Bailey 1967).
M_ALPHA_MIN = 0.2
#: Fewest raster columns (slices) an admissible slip circle cuts.
MIN_SLICES = 8
#: Smallest driving moment of an admissible circle, as a fraction of its weight times its radius.
DRIVE_MIN = 1e-3


class NoAdmissibleCircle(ValueError):
    """No slip circle of the section is admissible (nothing can slide: level ground, walls)."""


def _polyline(key: str, value) -> tuple[tuple[float, float], ...]:
    try:
        pts = np.asarray(value, dtype=np.float64).reshape(-1, 2)
    except (TypeError, ValueError):
        raise ValueError(f"{key} = {value!r}: give an (n, 2) array of x, y points") from None
    if len(pts) < 1 or not np.all(np.isfinite(pts)):
        raise ValueError(f"{key} = {value!r}: give at least one point, all coordinates finite")
    if np.any(np.diff(pts[:, 0]) <= 0.0):
        raise ValueError(f"{key}: x = {pts[:, 0].tolist()} must increase strictly along the line "
                         f"(a line that folds back on itself is not allowed)")
    return tuple((float(x), float(y)) for x, y in pts)


def _level(points: tuple[tuple[float, float], ...], x: np.ndarray) -> np.ndarray:
    p = np.asarray(points)
    return np.interp(x, p[:, 0], p[:, 1])


@dataclass(frozen=True)
class Water:
    """Ground water of a section (see the module docstring for the formulas).

    Attributes
    ----------
    phreatic_line : (n, 2) array_like, m
        The phreatic (piezometric) line, x strictly increasing; horizontal beyond its ends.
    free_water_line : (n, 2) array_like, m, optional
        The surface of free water, which stands where it is above the ground (default: the
        phreatic line). Below the phreatic line in rapid drawdown.
    unit_weight_n_m3 : float, N/m3
        Unit weight of water (default 9810).
    inclined_correction : bool
        ``u = gamma_w h_w cos^2(theta)`` (theta the local inclination of the phreatic line)
        instead of ``u = gamma_w h_w``.
    """

    phreatic_line: tuple = field()
    free_water_line: tuple | None = None
    unit_weight_n_m3: float = 9810.0
    inclined_correction: bool = False

    def __post_init__(self):
        object.__setattr__(self, "phreatic_line", _polyline("phreatic_line", self.phreatic_line))
        if self.free_water_line is not None:
            object.__setattr__(self, "free_water_line", _polyline("free_water_line", self.free_water_line))
        g = self.unit_weight_n_m3
        if not (isinstance(g, (int, float)) and math.isfinite(g) and g > 0.0):
            raise ValueError(f"unit_weight_n_m3 = {g!r}: must be a positive finite number (N/m3)")

    def phreatic_level(self, x) -> np.ndarray:
        """Height of the phreatic line at x (m)."""
        return _level(self.phreatic_line, np.asarray(x, dtype=np.float64))

    def free_level(self, x) -> np.ndarray:
        """Height of the free-water surface at x (m)."""
        return _level(self.phreatic_line if self.free_water_line is None else self.free_water_line,
                      np.asarray(x, dtype=np.float64))

    def head_factor(self, x) -> np.ndarray:
        """cos^2 of the phreatic line's inclination at x with ``inclined_correction``, else 1."""
        x = np.asarray(x, dtype=np.float64)
        if not self.inclined_correction or len(self.phreatic_line) < 2:
            return np.ones_like(x)
        p = np.asarray(self.phreatic_line)
        slope = np.diff(p[:, 1]) / np.diff(p[:, 0])
        k = np.clip(np.searchsorted(p[:, 0], x, side="right") - 1, 0, len(slope) - 1)
        inside = (x >= p[0, 0]) & (x <= p[-1, 0])
        return np.where(inside, 1.0 / (1.0 + slope[k] ** 2), 1.0)

    def pore_pressure(self, x, y) -> np.ndarray:
        """Pore pressure of the phreatic line at points (x, y) (Pa; 0 above the line)."""
        x, y = np.broadcast_arrays(np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64))
        return self.unit_weight_n_m3 * self.head_factor(x) * np.maximum(self.phreatic_level(x) - y, 0.0)


@dataclass(frozen=True)
class Soil:
    """Mohr-Coulomb strength and unit weight of one soil.

    Attributes
    ----------
    cohesion_pa : float, Pa (effective c' where there is water)
    friction_angle_rad : float, rad (effective phi' where there is water)
    unit_weight_n_m3 : float, N/m3 (density times |g|; above the phreatic line)
    saturated_unit_weight_n_m3 : float, N/m3, optional
        Below the phreatic line (default: ``unit_weight_n_m3``); not less than it.
    ru : float
        Pore-pressure ratio ``u / sigma_v`` on slice bases in this soil, 0 <= ru < 1 (default 0).
    """

    cohesion_pa: float
    friction_angle_rad: float
    unit_weight_n_m3: float
    saturated_unit_weight_n_m3: float | None = None
    ru: float = 0.0

    def __post_init__(self):
        sat = self.saturated_unit_weight_n_m3
        if sat is not None and not (math.isfinite(sat) and sat >= self.unit_weight_n_m3):
            raise ValueError(f"saturated_unit_weight_n_m3 = {sat!r}: must be finite and at least "
                             f"unit_weight_n_m3 = {self.unit_weight_n_m3!r}")
        if not (math.isfinite(self.ru) and 0.0 <= self.ru < 1.0):
            raise ValueError(f"ru = {self.ru!r}: allowed 0 <= ru < 1")

    @property
    def saturated_weight(self) -> float:
        """Unit weight below the phreatic line (N/m3)."""
        return self.unit_weight_n_m3 if self.saturated_unit_weight_n_m3 is None else self.saturated_unit_weight_n_m3


@dataclass(frozen=True)
class Surcharge:
    """A vertical distributed load on the ground surface between ``x_from_m`` and ``x_to_m``:
    ``pressure_from_pa`` at ``x_from_m``, ``pressure_to_pa`` at ``x_to_m`` (default: the same),
    linear between, per unit horizontal length (Pa = N/m per metre). A force, not a mass: no
    seismic share."""

    x_from_m: float
    x_to_m: float
    pressure_from_pa: float
    pressure_to_pa: float | None = None

    def __post_init__(self):
        end = self.pressure_from_pa if self.pressure_to_pa is None else self.pressure_to_pa
        values = (self.x_from_m, self.x_to_m, self.pressure_from_pa, end)
        if not all(isinstance(v, (int, float)) and math.isfinite(v) for v in values):
            raise ValueError(f"surcharge {values!r}: give finite numbers")
        if not self.x_to_m > self.x_from_m:
            raise ValueError(f"surcharge x_to_m = {self.x_to_m!r} must be > x_from_m = {self.x_from_m!r}")
        if self.pressure_from_pa < 0.0 or end < 0.0:
            raise ValueError(f"surcharge pressures {self.pressure_from_pa!r}, {end!r}: must be >= 0 (Pa)")
        object.__setattr__(self, "pressure_to_pa", float(end))

    def on(self, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The load on the stretches ``[lo, hi]`` of x (N/m) and where it acts (x, m)."""
        a = np.maximum(lo, self.x_from_m)
        b = np.minimum(hi, self.x_to_m)
        width = np.maximum(b - a, 0.0)
        mid = 0.5 * (a + b)
        t = (mid - self.x_from_m) / (self.x_to_m - self.x_from_m)
        return width * (self.pressure_from_pa + t * (self.pressure_to_pa - self.pressure_from_pa)), mid


@dataclass(frozen=True)
class Seismic:
    """Pseudo-static seismic coefficients: each slice's soil (its weight ``W``, water in its
    pores included) takes a horizontal force ``k_h W`` at its centroid, towards ``+x`` with
    ``direction = 1`` and ``-x`` with ``-1``, and weighs ``(1 - k_v) W`` (``k_v > 0``: an upward
    inertial force). Free water and surcharges take none (the water's pressure stays static)."""

    k_h: float = 0.0
    k_v: float = 0.0
    direction: float = 1.0

    def __post_init__(self):
        if not (isinstance(self.k_h, (int, float)) and math.isfinite(self.k_h) and 0.0 <= self.k_h < 1.0):
            raise ValueError(f"k_h = {self.k_h!r}: allowed 0 <= k_h < 1 (the direction is direction's)")
        if not (isinstance(self.k_v, (int, float)) and math.isfinite(self.k_v) and -1.0 < self.k_v < 1.0):
            raise ValueError(f"k_v = {self.k_v!r}: allowed -1 < k_v < 1")
        if self.direction not in (1.0, -1.0):
            raise ValueError(f"direction = {self.direction!r}: 1 (+x) or -1 (-x)")


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


class _Slices(NamedTuple):
    d_mid: np.ndarray  # (M, C) offset of the slice base's mid-point from the centre (m)
    th_lo: np.ndarray  # (M, C) arc angles at the slice's two ends (rad, from the downward vertical)
    th_hi: np.ndarray
    d_lo: np.ndarray  # (M, C) offsets of the slice's two sides from the centre (m)
    d_hi: np.ndarray
    weight: np.ndarray  # (M, C) slice weights (N/m)
    w_above: np.ndarray  # (M, C) vertical total stress at the slice base (Pa)
    ys: np.ndarray  # (M, C) height of the slice base's mid-point (m)
    soil: np.ndarray  # (M, C) soil index (len(soils) = none)
    mass: np.ndarray  # (M, C) the slice is part of the sliding mass
    valid: np.ndarray  # (M,)
    load: np.ndarray | None = None  # (M, C) surcharge on the slice's top (N/m), None without any
    load_d: np.ndarray | None = None  # (M, C) where it acts, offset from the centre (m)
    w_soil: np.ndarray | None = None  # (M, C) the slice's soil weight, free water not included (N/m)
    y_g: np.ndarray | None = None  # (M, C) the height of the soil's centroid (m)


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
    water : Water, optional
        Phreatic and free-water lines (default: dry, or ``ru`` alone).
    free_ends : (bool, bool)
        Whether the left and right ends of the section are free vertical faces that a slip
        circle may come out through (default: both are walls or cuts of continuing ground).
    surcharges : sequence of Surcharge
        Vertical distributed loads on the ground surface (default: none).
    seismic : Seismic, optional
        Pseudo-static seismic coefficients (default: none).
    """

    def __init__(self, polygons: Sequence[np.ndarray], soils: Sequence[Soil], columns: int = 300, rows: int = 600,
                 *, water: Water | None = None, free_ends: tuple[bool, bool] = (False, False),
                 surcharges: Sequence[Surcharge] = (), seismic: Seismic | None = None):
        if len(polygons) != len(soils) or not polygons:
            raise ValueError("give one soil per polygon and at least one polygon")
        if water is not None and not isinstance(water, Water):
            raise ValueError(f"water = {water!r}: give a stability.bishop.Water or None")
        if len(free_ends) != 2:
            raise ValueError(f"free_ends = {free_ends!r}: give two booleans (left end, right end)")
        self.water = water
        self.free_ends = (bool(free_ends[0]), bool(free_ends[1]))
        if any(not isinstance(q, Surcharge) for q in surcharges):
            raise ValueError(f"surcharges = {surcharges!r}: give stability.bishop.Surcharge entries")
        if seismic is not None and not isinstance(seismic, Seismic):
            raise ValueError(f"seismic = {seismic!r}: give a stability.bishop.Seismic or None")
        self.surcharges = tuple(surcharges)
        self.seismic = seismic if seismic is not None and (seismic.k_h > 0.0 or seismic.k_v != 0.0) else None
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
        if water is None:
            cell_w = gamma[owner] * self.dy
        else:
            # moist above the phreatic line, saturated below; the fraction of each cell below it
            gamma_sat = np.array([s.saturated_weight for s in self.soils] + [0.0])
            level = water.phreatic_level(self.x)
            below = np.clip((level[:, None] - (yc[None, :] - 0.5 * self.dy)) / self.dy, 0.0, 1.0)
            cell_w = (gamma[owner] + below * (gamma_sat[owner] - gamma[owner])) * self.dy
        # weight per unit width of the material above each row node, nodes 0..rows (bottom to top)
        above = np.zeros((columns, rows + 1))
        above[:, :-1] = np.cumsum(cell_w[:, ::-1], axis=1)[:, ::-1]
        if self.seismic is not None:
            # the soil's own weight above each row node (free water is added below) and its first
            # moment about y = 0, for the seismic forces at the slices' centroids
            self.soil_above = above.copy()
            self.moment_above = np.zeros((columns, rows + 1))
            self.moment_above[:, :-1] = np.cumsum((cell_w * yc[None, :])[:, ::-1], axis=1)[:, ::-1]
        self.cohesion = np.array([s.cohesion_pa for s in self.soils] + [0.0])
        self.tan_phi = np.array([math.tan(s.friction_angle_rad) for s in self.soils] + [0.0])
        self.ru = np.array([s.ru for s in self.soils] + [0.0])
        filled = owner >= 0
        has = filled.any(axis=1)
        self.has_material = has
        top_index = np.where(has, rows - np.argmax(filled[:, ::-1], axis=1), 0)
        bottom_index = np.where(has, np.argmax(filled, axis=1), rows)
        self.top = self.y_min + top_index * self.dy  # ground surface of each column (m)
        self.bottom = self.y_min + bottom_index * self.dy  # lowest material of each column (m)
        self.height_m = float(self.top.max() - self.top.min()) or float(self.y_max - self.y_min)
        if water is not None:
            # free water above the ground adds its weight to the column's; pore pressures per column
            self.free_level = water.free_level(self.x)
            self.free_depth = np.where(has, np.maximum(self.free_level - self.top, 0.0), 0.0)
            above += (water.unit_weight_n_m3 * self.free_depth)[:, None]
            self.phreatic = water.phreatic_level(self.x)
            self.head_factor = water.head_factor(self.x)
            tol = 1e-6 * max(1.0, float(self.y_max - self.y_min))
            low = np.flatnonzero((self.free_depth > tol) & (self.phreatic < self.free_level - tol))
            if low.size:
                x0 = float(self.x[low[0]])
                raise ValueError(f"water.phreatic_line: at x = {x0:.6g} m free water stands on the ground up to "
                                 f"y = {float(self.free_level[low[0]]):.6g} m but the phreatic line is at "
                                 f"y = {float(self.phreatic[low[0]]):.6g} m; where free water covers the ground "
                                 f"the phreatic line must be at or above its surface")
        self.weight_above = above
        #: a step of the ground between neighbouring columns higher than this is a vertical face
        self._face_step = max(4.0 * self.dy, 5.0 * self.dx)
        self.wet = water is not None or bool(np.any(self.ru > 0.0))

    # ------------------------------------------------------------------ slices of circles
    def _ground_beyond(self, x: np.ndarray) -> np.ndarray:
        """The ground's height at x, beyond the section's ends the foot of a free end's face."""
        left = self.bottom[0] if self.free_ends[0] else self.top[0]
        right = self.bottom[-1] if self.free_ends[1] else self.top[-1]
        return np.interp(x, self.x, self.top, left=left, right=right)

    def _slices(self, xc: np.ndarray, yc: np.ndarray, r: np.ndarray, min_depth_m: float) -> _Slices:
        """Slice arrays (M, columns) of M circles: the part of each column's arc below the ground."""
        dxs = self.x[None, :] - xc[:, None]
        half = 0.5 * self.dx
        # the lower arc is below the ground of a column where |d| < d_exit (ground as flat at its top)
        rise = yc[:, None] - self.top[None, :]
        d_exit = np.sqrt(np.clip(r[:, None] ** 2 - np.maximum(rise, 0.0) ** 2, 0.0, None))
        d_exit = np.where(self.has_material[None, :], d_exit, -np.inf)
        d_lo = np.maximum(dxs - half, -d_exit)
        d_hi = np.minimum(dxs + half, d_exit)
        mass = d_hi > d_lo
        if mass.shape[1] > 1:
            # where the arc comes out of the ground and goes back in (in front of a cut's toe, under
            # a hollow), the sliding mass is its run of columns with the most weight of soil above
            # the arc; the soil above the other runs is not part of it
            starts = mass & ~np.concatenate([np.zeros((mass.shape[0], 1), dtype=bool), mass[:, :-1]], axis=1)
            run = np.where(mass, np.cumsum(starts, axis=1), 0)
            if np.any(run.max(axis=1) > 1):
                area = np.where(mass, (self.top[None, :] - (yc[:, None] - np.sqrt(np.clip(
                    r[:, None] ** 2 - dxs ** 2, 0.0, None)))) * (d_hi - d_lo), 0.0)
                ids = run + np.arange(mass.shape[0])[:, None] * mass.shape[1]
                sums = np.bincount(ids.ravel(), weights=area.ravel(), minlength=mass.size).reshape(mass.shape)
                sums[:, 0] = -np.inf
                mass &= run == np.argmax(sums, axis=1)[:, None]
        d_lo = np.where(mass, d_lo, 0.0)
        d_hi = np.where(mass, d_hi, 0.0)
        th_lo = np.arcsin(np.clip(d_lo / r[:, None], -1.0, 1.0))
        th_hi = np.arcsin(np.clip(d_hi / r[:, None], -1.0, 1.0))
        d_mid = 0.5 * (d_lo + d_hi)
        ys = yc[:, None] - np.sqrt(np.clip(r[:, None] ** 2 - d_mid ** 2, 0.0, None))
        depth = np.where(mass, self.top[None, :] - ys, 0.0)
        tol = 1e-9 * max(1.0, abs(self.y_min))
        below_base = np.any(mass & (ys < self.bottom[None, :] - tol), axis=1)
        # an arc that passes through an end of the section below the ground there: not admissible
        # at a wall; at a free end it comes out through the face, above the face's foot
        ends_ok = np.ones(len(xc), dtype=bool)
        for col, edge, side, free, inner in ((0, self.x_min, -half, self.free_ends[0], 1),
                                             (-1, self.x_max, half, self.free_ends[1], -2)):
            through = mass[:, col] & (np.abs(dxs[:, col] + side) < d_exit[:, col])
            y_edge = yc - np.sqrt(np.clip(r ** 2 - (edge - xc) ** 2, 0.0, None))
            if free:
                ends_ok &= ~through | (y_edge >= self.bottom[col] - tol)
            else:
                # the ground at the wall: the end column's top carried on to the edge along the
                # surface's slope there (a toe at the section's corner), unless a face is there
                top, step = self.top[col], self.top[inner] - self.top[col] if len(self.x) > 1 else 0.0
                at_wall = top if abs(step) > self._face_step else max(top - 0.5 * step, self.bottom[col])
                ends_ok &= ~through | (y_edge >= at_wall - tol)
        # the lower arc must come out through the ground on both sides: its ends (xc -+ r, yc) lie
        # above the ground (else the slip surface would have to turn back over the centre)
        buried = (self._ground_beyond(xc - r) > yc) | (self._ground_beyond(xc + r) > yc)
        valid = (np.count_nonzero(mass, axis=1) >= MIN_SLICES) & ~below_base & ends_ok & ~buried \
            & (depth.max(axis=1) >= min_depth_m)
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
        load = load_d = w_soil = y_g = None
        if self.surcharges:
            # each slice's top takes the loads over its stretch of x, acting where they lie
            lo, hi = xc[:, None] + d_lo, xc[:, None] + d_hi
            load = np.zeros_like(weight)
            first = np.zeros_like(weight)
            for q in self.surcharges:
                force, at = q.on(lo, hi)
                load += force
                first += force * (at - xc[:, None])
            load = np.where(mass, load, 0.0)
            load_d = np.where(load > 0.0, first / np.where(load > 0.0, load, 1.0), d_mid)
        if self.seismic is not None:
            soil_w = (1 - f) * self.soil_above[cols, k] + f * self.soil_above[cols, k + 1]
            moment = (1 - f) * self.moment_above[cols, k] + f * self.moment_above[cols, k + 1]
            w_soil = np.where(mass, soil_w * (d_hi - d_lo), 0.0)
            y_g = np.where(soil_w > 0.0, moment / np.where(soil_w > 0.0, soil_w, 1.0), ys)
        return _Slices(d_mid, th_lo, th_hi, d_lo, d_hi, weight, w_above, ys, soil, mass, valid, load, load_d, w_soil,
                       y_g)

    def _pore_pressure(self, s: _Slices) -> np.ndarray:
        """Pore pressure on the slice bases (Pa): the water lines' and ``ru``'s, the larger."""
        u = self.ru[s.soil] * s.w_above
        if self.water is not None:
            g = self.water.unit_weight_n_m3
            u = np.maximum(u, g * self.head_factor[None, :] * np.maximum(self.phreatic[None, :] - s.ys, 0.0))
        return np.where(s.mass, u, 0.0)

    def _free_water_moment(self, s: _Slices, xc, yc, r) -> np.ndarray:
        """Moment about the centre (N m / m, positive the way weights to the right of the centre
        turn) of the free water that the slices do not carry: its thrust on the ends of the
        sliding mass, and its weight above the arc where the arc runs above a column's top
        inside the mass (the raster's steps), which water below the arc holds up."""
        g = self.water.unit_weight_n_m3
        m = s.mass
        pad = np.zeros((m.shape[0], 1), dtype=bool)
        starts = m & ~np.concatenate([pad, m[:, :-1]], axis=1)  # a run of the mass begins (its left end)
        ends = m & ~np.concatenate([m[:, 1:], pad], axis=1)  # a run ends (its right end)
        level = self.free_level[None, :]
        total = np.zeros(m.shape[0])
        for sel, d, push in ((starts, s.d_lo, 1.0), (ends, s.d_hi, -1.0)):
            y_end = yc[:, None] - np.sqrt(np.clip(r[:, None] ** 2 - d ** 2, 0.0, None))
            depth = np.where(sel, np.maximum(level - y_end, 0.0), 0.0)
            thrust = 0.5 * g * depth ** 2  # towards the mass: +x on a left end, -x on a right end
            total -= np.sum(push * thrust * (yc[:, None] - (y_end + depth / 3.0)), axis=1)
        half = 0.5 * self.dx
        offsets = self.x[None, :] - xc[:, None]
        for lo, hi in ((np.where(starts, s.d_lo, offsets - half), s.d_lo), (s.d_hi, np.where(ends, s.d_hi, offsets + half))):
            width = np.where(m, np.maximum(hi - lo, 0.0), 0.0)
            mid = 0.5 * (lo + hi)
            y_arc = yc[:, None] - np.sqrt(np.clip(r[:, None] ** 2 - mid ** 2, 0.0, None))
            total += np.sum(g * np.maximum(level - y_arc, 0.0) * width * mid, axis=1)
        # one level water body at the submerged end(s): the free water's weight and thrust together
        # are the buoyancy of the soil below its level (the same in the continuum), which is taken
        # instead, free of the cancellation between deep water's weight and its thrust
        first, last = np.argmax(starts, axis=1), m.shape[1] - 1 - np.argmax(ends[:, ::-1], axis=1)
        rows = np.arange(m.shape[0])
        y_l = yc - np.sqrt(np.clip(r ** 2 - s.d_lo[rows, first] ** 2, 0.0, None))
        y_r = yc - np.sqrt(np.clip(r ** 2 - s.d_hi[rows, last] ** 2, 0.0, None))
        h_l, h_r = self.free_level[first], self.free_level[last]
        sub_l, sub_r = h_l > y_l, h_r > y_r
        h = np.where(sub_l, h_l, h_r)
        tol = 1e-9 * max(1.0, float(self.y_max - self.y_min))
        covered = m & (self.free_depth > 0.0)[None, :]
        level_body = (sub_l | sub_r) & (~(sub_l & sub_r) | (np.abs(h_l - h_r) <= tol)) \
            & ~np.any(covered & (np.abs(level - h[:, None]) > tol), axis=1)
        if np.any(level_body):
            b = s.d_hi - s.d_lo
            buoyant = g * np.clip(np.minimum(h[:, None], self.top[None, :]) - s.ys, 0.0, None) * b
            carried = g * self.free_depth[None, :] * b  # the free water the slices' weights hold
            arm = r[:, None] * np.sin(0.5 * (s.th_lo + s.th_hi))  # the slices' own lever arm
            buoyancy = -np.sum(np.where(m, (buoyant + carried) * arm, 0.0), axis=1)
            total = np.where(level_body, buoyancy, total)
        return total

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
        s = self._slices(xc, yc, r, min_depth_m)
        dxs, th_l, th_r, w, soil, mass, valid = s.d_mid, s.th_lo, s.th_hi, s.weight, s.soil, s.mass, s.valid
        weights = np.sum(w, axis=1)
        # the vertical load on each slice: its weight, less k_v of its soil's, and its surcharge
        # (the surcharge's moment taken where it acts); the seismic horizontal forces' moment
        moment = np.sum(w * dxs, axis=1)
        extra = np.zeros(len(xc))  # moments (N m / m) beside the weights' and the free water's
        horizontal = None
        if s.load is not None:
            extra += np.sum(s.load * s.load_d, axis=1)
            w = w + s.load
        if s.w_soil is not None:
            q = self.seismic
            extra -= q.k_v * np.sum(s.w_soil * dxs, axis=1)
            w = w - q.k_v * s.w_soil
            horizontal = q.direction * q.k_h * s.w_soil  # along +x (N/m)
            extra += np.sum(horizontal * (s.y_g - yc[:, None]), axis=1)
        moment_w = self._free_water_moment(s, xc, yc, r) if self.water is not None else np.zeros(len(xc))
        # the slide turns the way the weights, the loads and the free water drive it together
        sign = np.where(moment + extra + moment_w >= 0.0, 1.0, -1.0)
        length = r[:, None] * (th_r - th_l)  # the arc in each column, exactly (m)
        sin_t = np.sin(0.5 * (th_l + th_r))
        sin_a = sign[:, None] * sin_t
        cos_a = np.cos(0.5 * (th_l + th_r))
        c = np.where(mass, self.cohesion[soil], 0.0)
        tp = np.where(mass, self.tan_phi[soil], 0.0)
        # the driving moment over R: sum W sin(alpha) of the slices' own lever arms, the rest
        # (the loads' offsets from their slices' mid-points, the seismic forces, the free water) whole
        drive = np.sum(w * sin_a, axis=1) + sign * (extra - np.sum((w - s.weight) * dxs, axis=1) + moment_w) / r
        valid &= (drive > DRIVE_MIN * weights) & positive
        drive = np.where(valid, drive, 1.0)
        u_b = self._pore_pressure(s) * (s.d_hi - s.d_lo) if self.wet else 0.0
        # Fellenius: the base's normal force from the slice alone, its vertical load and the
        # horizontal force (k_h W pushes the slice onto a base that faces it)
        normal = np.maximum(w - u_b, 0.0) * cos_a if self.wet else w * cos_a
        if horizontal is not None:
            normal = np.maximum(normal + horizontal * sin_t, 0.0)
        fellenius = np.sum(np.where(mass, c * length + normal * tp, 0.0), axis=1) / drive
        # Bishop: c b is c l cos(alpha) with the column's exact arc length (steep ends of an arc included)
        resist = np.where(mass, c * length * cos_a + (np.maximum(w - u_b, 0.0) if self.wet else w) * tp, 0.0)
        f = np.maximum(fellenius, 1e-3)
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
        s = self._slices(np.array([circle.centre_x_m]), np.array([circle.centre_y_m]), np.array([circle.radius_m]), 0.0)
        xs = self.x[s.mass[0]]
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
    fellenius = float(np.sum(c * length + (w - u * b) * np.cos(a) * tp) / drive)
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


def _surface_points(section: Section, radii: int) -> tuple[np.ndarray, np.ndarray]:
    """Points of the ground surface that trial circles pass through: ``radii`` evenly spaced ones,
    the polygons' vertices on the surface (toe, crest, breaks of slope) and points up each
    vertical face (steps of the surface between columns, and the free ends), its foot first."""
    verts = np.vstack(section.polygons)
    on_top = np.abs(verts[:, 1] - np.interp(verts[:, 0], section.x, section.top)) <= 1.01 * section.dy
    px = np.concatenate([np.linspace(section.x_min, section.x_max, radii + 2)[1:-1], verts[on_top, 0]])
    px = np.clip(px, section.x[0], section.x[-1])
    py = np.interp(px, section.x, section.top)
    fx, fy = [], []
    levels = np.array([0.0, 0.1, 0.25, 0.5, 0.75])
    top, has = section.top, section.has_material
    step = np.abs(np.diff(top))
    for j in np.flatnonzero((step > section._face_step) & has[:-1] & has[1:]):
        lo, hi = sorted((top[j], top[j + 1]))
        fx.extend([section.x_min + (j + 1) * section.dx] * len(levels))
        fy.extend(lo + levels * (hi - lo))
    for col, edge, free in ((0, section.x_min, section.free_ends[0]), (-1, section.x_max, section.free_ends[1])):
        if free and section.top[col] > section.bottom[col]:
            fx.extend([edge] * len(levels))
            fy.extend(section.bottom[col] + levels * (section.top[col] - section.bottom[col]))
    return np.concatenate([px, fx]), np.concatenate([py, fy])


def critical_circle(section: Section, *, centres: int = 21, radii: int = 40, refinements: int = 6,
                    min_depth_m: float | None = None, batch: int = 4000) -> SlipResult:
    """Search the circle of least Bishop factor: a grid of centres and radii, then refined grids.

    The first grid spans centres over the section's width (plus half of it on either side) and
    from the lowest ground point to three section heights above the highest; for each centre,
    the circles through ``radii`` evenly spaced points of the ground surface, through each
    vertex of the polygons that lies on the surface (toe, crest, breaks of slope) and through
    points up each vertical face (its foot, the toe of a cut, first), and the circle tangent to
    the base. The best circles of the three best centres each start a pattern search: a 7 x 7 x 7
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
    NoAdmissibleCircle
        (a ValueError) when no circle of the search is admissible: nothing in the section can
        slide (level ground between walls, a sliding mass thinner than ``min_depth_m``).
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
    # radii: circles through points of the ground surface, plus circles tangent to the base
    px, py = _surface_points(section, radii)
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
        raise NoAdmissibleCircle("no admissible slip circle in this section: no circle through its ground surface "
                                 "drives a sliding mass (level ground between walls, or every mass thinner than "
                                 f"min_depth_m = {min_depth_m:.3g} m)")
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
