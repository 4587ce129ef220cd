"""Parametric scenes: a slope on a foundation, optionally in horizontal layers.

The slope profile, with the crest on the left and the toe on the right (origin at the
lower-left corner ``(x0, y0)``)::

    y0+D+H  +-----------+
            |    crest   \\   face at angle_deg
            |              \\
    y0+D    |                +-----------+
            |                       toe  |
    y0      +----------------------------+
            x0          x0+Lc   x0+Lc+H/tan(angle)   x0+Lc+H/tan(angle)+Lt

with ``H = height_m``, ``D = foundation_depth_m``, ``Lc = crest_length_m``,
``Lt = toe_length_m``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from geometry.polygons import counter_clockwise, drop_repeated_vertices, remove_spikes

# Lengths below this fraction of the profile's size count as zero (coincident vertices).
_REL_TOL = 1e-9


@dataclass(frozen=True)
class SlopeLayer:
    """A horizontal soil layer, counted from the top of the slope down.

    Attributes
    ----------
    name : str
        Body name given to the layer's polygon.
    thickness_m : float, m
        Vertical thickness.
    """

    name: str
    thickness_m: float


def _check_number(name: str, value: float, allow_zero: bool) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a number, got {value!r}") from exc
    if not math.isfinite(v) or v < 0.0 or (v == 0.0 and not allow_zero):
        allowed = ">= 0" if allow_zero else "> 0"
        raise ValueError(f"{name} must be {allowed} (metres), got {value!r}")
    return v


def slope_profile(
    height_m: float,
    angle_deg: float,
    crest_length_m: float,
    toe_length_m: float,
    foundation_depth_m: float,
    layers: Sequence[SlopeLayer] = (),
    origin_m: tuple[float, float] = (0.0, 0.0),
    remainder_name: str = "foundation",
) -> list[tuple[str, np.ndarray]]:
    """Named body polygons of a slope on a foundation.

    Without layers the whole profile (slope and foundation together) is one body named
    ``"slope"``. With layers, each layer is the horizontal band of the profile between its
    top and bottom (the first layer starts at the crest, ``y0 + D + H``, and the layers follow
    downwards), clipped to the profile and named after the layer; what remains below the last
    layer is one more body named ``remainder_name``, omitted when the layers reach the base.
    A band may extend below the toe level, where it spans the full width.

    Parameters
    ----------
    height_m : float, m
        Slope height from the toe surface to the crest, > 0.
    angle_deg : float, degrees
        Face angle from the horizontal, 0 < angle_deg < 90.
    crest_length_m : float, m
        Horizontal length of the crest, >= 0.
    toe_length_m : float, m
        Horizontal length of the ground in front of the toe, >= 0.
    foundation_depth_m : float, m
        Depth of the foundation below the toe surface, >= 0.
    layers : sequence of SlopeLayer
        Layers from the crest down; thicknesses > 0, unique names, total thickness at most
        ``height_m + foundation_depth_m``.
    origin_m : (float, float), m
        Lower-left corner of the profile.
    remainder_name : str
        Name of the body below the last layer.

    Returns
    -------
    list of (str, numpy.ndarray of shape (K, 2), m)
        Bodies from top to bottom, each polygon counter-clockwise without a repeated vertex.

    Raises
    ------
    ValueError
        Naming the argument and the allowed range when an argument is out of range.
    """
    height = _check_number("height_m", height_m, allow_zero=False)
    try:
        angle = float(angle_deg)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"angle_deg must be a number, got {angle_deg!r}") from exc
    if not (0.0 < angle < 90.0):
        raise ValueError(f"angle_deg must be in the open range (0, 90) degrees, got {angle_deg!r}")
    crest = _check_number("crest_length_m", crest_length_m, allow_zero=True)
    toe = _check_number("toe_length_m", toe_length_m, allow_zero=True)
    depth = _check_number("foundation_depth_m", foundation_depth_m, allow_zero=True)
    try:
        x0, y0 = (float(v) for v in origin_m)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"origin_m must be a pair of numbers (x, y) in metres, got {origin_m!r}") from exc
    if not (math.isfinite(x0) and math.isfinite(y0)):
        raise ValueError(f"origin_m must be finite, got {origin_m!r}")

    run = height / math.tan(math.radians(angle))
    width = crest + run + toe
    top = y0 + depth + height
    toe_y = y0 + depth
    profile = drop_repeated_vertices(
        np.array(
            [
                [x0, y0],
                [x0 + width, y0],
                [x0 + width, toe_y],
                [x0 + crest + run, toe_y],
                [x0 + crest, top],
                [x0, top],
            ]
        ),
        _REL_TOL * max(width, depth + height),
    )
    if not layers:
        return [("slope", counter_clockwise(profile))]

    total_height = depth + height
    tol = _REL_TOL * max(width, total_height)
    names: set[str] = set()
    bodies: list[tuple[str, np.ndarray]] = []
    upper = top
    for index, layer in enumerate(layers):
        if not isinstance(layer, SlopeLayer):
            raise ValueError(f"layers[{index}] must be a SlopeLayer, got {type(layer).__name__}")
        if not layer.name or not isinstance(layer.name, str):
            raise ValueError(f"layers[{index}].name must be a non-empty string, got {layer.name!r}")
        if layer.name in names or layer.name == remainder_name:
            raise ValueError(f"layers[{index}].name {layer.name!r} is used twice")
        names.add(layer.name)
        thickness = _check_number(f"layers[{index}].thickness_m", layer.thickness_m, allow_zero=False)
        lower = upper - thickness
        if lower < y0 - tol:
            total = top - lower
            raise ValueError(
                f"layers total thickness {total:g} m exceeds the profile height "
                f"height_m + foundation_depth_m = {total_height:g} m"
            )
        lower = max(lower, y0)
        bodies.append((layer.name, counter_clockwise(_clip_band(profile, lower, upper, tol))))
        upper = lower
    if upper > y0 + tol:
        bodies.append((remainder_name, counter_clockwise(_clip_band(profile, y0, upper, tol))))
    return bodies


def _clip_band(polygon: np.ndarray, y_lo: float, y_hi: float, tol: float) -> np.ndarray:
    """Clip a polygon to the band y_lo <= y <= y_hi (Sutherland-Hodgman, two half-planes).

    The result is connected because every horizontal line cuts the slope profile in a single
    interval.
    """
    clipped = _clip_half_plane(polygon, y_lo, keep_above=True)
    clipped = _clip_half_plane(clipped, y_hi, keep_above=False)
    return remove_spikes(drop_repeated_vertices(clipped, tol), tol)


def _clip_half_plane(polygon: np.ndarray, y_cut: float, keep_above: bool) -> np.ndarray:
    out: list[np.ndarray] = []
    n = len(polygon)
    for i in range(n):
        cur, nxt = polygon[i], polygon[(i + 1) % n]
        cur_in = cur[1] >= y_cut if keep_above else cur[1] <= y_cut
        nxt_in = nxt[1] >= y_cut if keep_above else nxt[1] <= y_cut
        if cur_in:
            out.append(cur)
        if cur_in != nxt_in:
            t = (y_cut - cur[1]) / (nxt[1] - cur[1])
            out.append(np.array([cur[0] + t * (nxt[0] - cur[0]), y_cut]))
    return np.array(out)


def slope_domain(
    polygons: Sequence[np.ndarray],
    cell_size_m: float,
    runout_length_m: float = 0.0,
    headroom_fraction: float = 0.25,
) -> tuple[tuple[float, float], tuple[float, float]]:
    """The grid box for a slope template: the bodies rest on the base and touch the walls.

    The grid origin is the lower-left corner of the bodies' bounding box, so the foundation
    lies on the bottom wall and against the left wall (no gap a body could fall or slide
    across: such a gap reads as settlement of a slope that should stand still). On the right
    the wall touches the bodies when their width is a whole number of cells and
    ``runout_length_m`` is 0; otherwise the box reaches at least one whole cell beyond them
    (a gap below a cell would also be a fall). Above, ``headroom_fraction`` of the height is
    added, at least two cells. Sizes are whole numbers of cells.

    Parameters
    ----------
    polygons : sequence of array_like, each shape (K_i, 2), m
        The body outlines (e.g. from :func:`slope_profile`).
    cell_size_m : float, m
        Background-grid cell size, > 0.
    runout_length_m : float, m
        Extra room to the right of the bodies, >= 0.
    headroom_fraction : float
        Room above the bodies as a fraction of their height, >= 0.

    Returns
    -------
    origin_m : (float, float), m
    size_m : (float, float), m

    Raises
    ------
    ValueError
        Naming the argument for a bad cell size, length or fraction, or no polygons.
    """
    dx = _check_number("cell_size_m", cell_size_m, allow_zero=False)
    extra = _check_number("runout_length_m", runout_length_m, allow_zero=True)
    room = _check_number("headroom_fraction", headroom_fraction, allow_zero=True)
    if len(polygons) == 0:
        raise ValueError("polygons must hold at least one body outline")
    points = np.concatenate([np.asarray(p, dtype=np.float64).reshape(-1, 2) for p in polygons])
    lo, hi = points.min(axis=0), points.max(axis=0)
    width, height = float(hi[0] - lo[0]), float(hi[1] - lo[1])
    tol = 1e-9 * max(width, height, dx)
    cells_x = math.ceil((width + extra) / dx - 1e-9)
    if cells_x * dx - width > tol and cells_x * dx - width < dx - tol:
        cells_x += 1  # a gap of a fraction of a cell: make it more than a cell
    cells_y = math.ceil((height * (1.0 + room)) / dx - 1e-9)
    cells_y = max(cells_y, math.ceil(height / dx - 1e-9) + 2)
    return (float(lo[0]), float(lo[1])), (cells_x * dx, cells_y * dx)


@dataclass(frozen=True)
class DomainFit:
    """A grid box fitted to a section, and the section fitted to the box (:func:`fit_domain`).

    Attributes
    ----------
    polygons : tuple of numpy.ndarray, each (K_i, 2), m
        The bodies, their right end moved onto the right wall (the others unchanged).
    origin_m, size_m : (float, float), m
        The grid box: whole cells, the origin at the bodies' lower-left corner.
    end_shift_m : float, m
        How far the right end moved (positive: out; less than half a cell either way).
    """

    polygons: tuple[np.ndarray, ...]
    origin_m: tuple[float, float]
    size_m: tuple[float, float]
    end_shift_m: float


def fit_domain(
    polygons: Sequence[np.ndarray],
    cell_size_m: float,
    runout_length_m: float = 0.0,
    headroom_fraction: float = 0.25,
) -> DomainFit:
    """Fit the grid box to a section so that it stands on its supports, at any cell size.

    The origin is the bodies' lower-left corner: the ground lies on the base and its left end
    against the left wall. The width is the nearest whole number of cells (at least one), and the
    vertices at the section's right end (those within a millionth of a cell of its largest x) move
    onto the right wall, by less than half a cell: the end stands against the wall, with no sliver
    of air between (the first stage would drop or slump the section into it) and no material cut
    off. With ``runout_length_m`` the box reaches that much beyond the bodies instead (whole cells
    again, nothing moved): room for material to run out over an open end. Above, the box has
    ``headroom_fraction`` of the bodies' height, at least two cells.

    Parameters
    ----------
    polygons : sequence of array_like, each (K_i, 2), m
        The body outlines (a slope template's, an imported section's layers).
    cell_size_m : float, m
        Background-grid cell size, > 0.
    runout_length_m : float, m
        Room to the right of the bodies, >= 0 (0: the right end on the right wall).
    headroom_fraction : float
        Room above the bodies as a fraction of their height, >= 0.

    Returns
    -------
    DomainFit

    Raises
    ------
    ValueError
        Naming the argument for a bad cell size, length or fraction, or no polygons.
    """
    dx = _check_number("cell_size_m", cell_size_m, allow_zero=False)
    extra = _check_number("runout_length_m", runout_length_m, allow_zero=True)
    room = _check_number("headroom_fraction", headroom_fraction, allow_zero=True)
    if len(polygons) == 0:
        raise ValueError("polygons must hold at least one body outline")
    bodies = [np.array(p, dtype=np.float64).reshape(-1, 2) for p in polygons]
    points = np.concatenate(bodies)
    lo, hi = points.min(axis=0), points.max(axis=0)
    width, height = float(hi[0] - lo[0]), float(hi[1] - lo[1])
    shift = 0.0
    if extra > 0.0:
        cells_x = math.ceil((width + extra) / dx - 1e-9)
    else:
        cells_x = max(1, round(width / dx))
        wall = _tidy(lo[0] + cells_x * dx)
        shift = float(wall - hi[0])
        if shift != 0.0:
            at_end = 1e-6 * dx
            for body in bodies:
                body[body[:, 0] >= hi[0] - at_end, 0] = wall
    cells_y = max(math.ceil(height * (1.0 + room) / dx - 1e-9), math.ceil(height / dx - 1e-9) + 2)
    return DomainFit(tuple(bodies), (float(lo[0]), float(lo[1])), (_tidy(cells_x * dx), _tidy(cells_y * dx)), shift)


def _tidy(value: float) -> float:
    """A sum of whole cells without its last bits of rounding (99.9, not 99.89999999999999)."""
    return float(f"{value:.12g}")
