"""Plane polygons as numpy arrays: area, simplicity, point location and body ownership.

A polygon is an array of shape (K, 2) holding its vertices in metres, in order, without
repeating the first vertex at the end (a repeated closing vertex is accepted and ignored).
Edge ``i`` runs from vertex ``i`` to vertex ``(i + 1) % K``.

Overlap rule
------------
Bodies are painted in list order, like layers on a drawing: where bodies overlap, the
*later* body in the list owns the overlap. :func:`owner_of_points` and
:func:`geometry.gmsh_bodies.mesh_bodies` both follow this rule.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence

import numpy as np

logger = logging.getLogger(__name__)

# Relative tolerance for orientation tests, scaled by the polygon's size.
_REL_TOL = 1e-12


def as_polygon(polygon_m: np.ndarray, name: str = "polygon_m") -> np.ndarray:
    """Return a polygon as a float64 (K, 2) array without a repeated closing vertex.

    Parameters
    ----------
    polygon_m : array_like, shape (K, 2), m
        Vertices in order.
    name : str
        Name used in error messages.

    Returns
    -------
    numpy.ndarray, shape (K, 2) or (K - 1, 2), float64, m
        The vertices; the last one is dropped when it repeats the first.

    Raises
    ------
    ValueError
        If the array is not (K, 2) or holds non-finite values.
    """
    try:
        arr = np.asarray(polygon_m, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be an array of (x, y) pairs in metres: {exc}") from exc
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise ValueError(f"{name} must have shape (K, 2), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} holds non-finite coordinates")
    if len(arr) > 1 and np.array_equal(arr[0], arr[-1]):
        arr = arr[:-1]
    return arr


def signed_area(polygon_m: np.ndarray) -> float:
    """Signed area by the shoelace formula: positive when counter-clockwise.

    Parameters
    ----------
    polygon_m : array_like, shape (K, 2), m

    Returns
    -------
    float, m2
    """
    p = as_polygon(polygon_m)
    if len(p) < 3:
        return 0.0
    # Shift to the first vertex so that far-away polygons keep their digits.
    q = p - p[0]
    x, y = q[:, 0], q[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def polygon_area(polygon_m: np.ndarray) -> float:
    """Absolute area of a simple polygon.

    Parameters
    ----------
    polygon_m : array_like, shape (K, 2), m

    Returns
    -------
    float, m2
        The area, whatever the orientation of the vertices.
    """
    return abs(signed_area(polygon_m))


def polygon_perimeter(polygon_m: np.ndarray) -> float:
    """Length of the closed boundary.

    Parameters
    ----------
    polygon_m : array_like, shape (K, 2), m

    Returns
    -------
    float, m
    """
    p = as_polygon(polygon_m)
    if len(p) < 2:
        return 0.0
    return float(np.sum(np.linalg.norm(np.roll(p, -1, axis=0) - p, axis=1)))


def counter_clockwise(polygon_m: np.ndarray) -> np.ndarray:
    """The polygon with its vertices in counter-clockwise order.

    Parameters
    ----------
    polygon_m : array_like, shape (K, 2), m

    Returns
    -------
    numpy.ndarray, shape (K, 2), float64, m
        A copy, reversed when the input was clockwise.
    """
    p = as_polygon(polygon_m).copy()
    if signed_area(p) < 0.0:
        p = p[::-1].copy()
    return p


def drop_repeated_vertices(polygon_m: np.ndarray, tol_m: float = 0.0) -> np.ndarray:
    """Drop vertices that coincide with the previous one (cyclically).

    Parameters
    ----------
    polygon_m : array_like, shape (K, 2), m
    tol_m : float, m
        Vertices closer than this to the previous one are dropped.

    Returns
    -------
    numpy.ndarray, shape (K', 2), float64, m
    """
    p = as_polygon(polygon_m)
    if len(p) < 2:
        return p
    keep = np.linalg.norm(p - np.roll(p, 1, axis=0), axis=1) > tol_m
    return p[keep]


def remove_spikes(polygon_m: np.ndarray, tol_m: float = 0.0) -> np.ndarray:
    """Drop vertices where the outline runs out and straight back (zero-width spikes).

    Such spikes appear when an outline is clipped or closed along a line that already
    carries some of its edges, e.g. closing a survey profile down to a base at the height of
    its flat toe. Repeated vertices are dropped too.

    Parameters
    ----------
    polygon_m : array_like, shape (K, 2), m
    tol_m : float, m
        Distance below which points count as coincident or collinear.

    Returns
    -------
    numpy.ndarray, shape (K', 2), float64, m
    """
    poly = drop_repeated_vertices(polygon_m, tol_m)
    while len(poly) > 3:
        to_prev = np.roll(poly, 1, axis=0) - poly
        to_next = np.roll(poly, -1, axis=0) - poly
        cross = _cross(to_prev[:, 0], to_prev[:, 1], to_next[:, 0], to_next[:, 1])
        longer = np.maximum(np.linalg.norm(to_prev, axis=1), np.linalg.norm(to_next, axis=1))
        # Both neighbours on the same side along one line: the vertex is a spike tip.
        spike = (np.abs(cross) <= tol_m * longer) & (np.sum(to_prev * to_next, axis=1) > 0)
        if not np.any(spike):
            break
        poly = drop_repeated_vertices(poly[~spike], tol_m)
    return poly


def _cross(ax, ay, bx, by):
    return ax * by - ay * bx


def edge_text(polygon_m: np.ndarray, i: int) -> str:
    """Edge ``i`` (vertex ``i`` to the next) by its end points, ``"(0, 0)-(0.1, 0.1)"``: what a
    message names it by, the same to a reader of the file (who counts points from 0) and of the
    workbench's table (from 1)."""
    p = as_polygon(polygon_m)
    a, b = p[i % len(p)], p[(i + 1) % len(p)]
    return f"({a[0]:g}, {a[1]:g})-({b[0]:g}, {b[1]:g})"


def self_intersections(polygon_m: np.ndarray) -> list[tuple[int, int]]:
    """Pairs of edges that cross or touch where they should not.

    Two edges that are not neighbours intersect when their closed segments have any point
    in common (crossing, touching at a vertex, or overlapping). Two neighbouring edges
    intersect when they fold back over each other (collinear and overlapping beyond the
    shared vertex). Zero-length edges (repeated consecutive vertices) are skipped, so the
    edges on either side of one count as neighbours.

    Parameters
    ----------
    polygon_m : array_like, shape (K, 2), m

    Returns
    -------
    list of (int, int)
        Pairs ``(i, j)`` with ``i < j`` of edge indices, sorted. Edge ``i`` runs from vertex
        ``i`` to vertex ``(i + 1) % K`` of the polygon as given.
    """
    p = as_polygon(polygon_m)
    if len(p) < 3:
        return []
    scale = float(np.max(np.abs(p - p.mean(axis=0)))) or 1.0
    tol = _REL_TOL * scale * scale
    edges = np.roll(p, -1, axis=0) - p
    lengths = np.hypot(edges[:, 0], edges[:, 1])  # no overflow warning for huge coordinates
    # Work on the edges of non-zero length; keep their original numbers for the report.
    edge_ids = np.nonzero(lengths > _REL_TOL * scale)[0]
    k = len(edge_ids)
    if k < 3:
        return []
    a = p[edge_ids]
    d = np.roll(a, -1, axis=0) - a
    i, j = _candidate_pairs(a, a + d, max(tol, tol / scale))
    hit = _pairs_intersect(a, d, i, j, k, tol)
    return sorted(zip(edge_ids[i[hit]].tolist(), edge_ids[j[hit]].tolist()))


#: Up to this many edges the candidate pairs come from testing all pairs (cheaper than importing
#: shapely, 30-40 ms of a run's start, for the few-vertex polygons of most projects).
ALL_PAIRS_UP_TO = 64


def _candidate_pairs(start: np.ndarray, end: np.ndarray, pad: float) -> tuple[np.ndarray, np.ndarray]:
    """Edge pairs ``i < j`` whose bounding boxes (grown by ``pad``) overlap: an R-tree query
    (shapely's STRtree), so the work grows with the edges and their near neighbours, not with
    all pairs; for a few edges, every pair tested."""
    lo = np.minimum(start, end) - pad
    hi = np.maximum(start, end) + pad
    if len(lo) <= ALL_PAIRS_UP_TO:
        i, j = np.triu_indices(len(lo), k=1)
        overlap = np.all((lo[i] <= hi[j]) & (lo[j] <= hi[i]), axis=1)
        return i[overlap].astype(np.int64), j[overlap].astype(np.int64)
    import shapely

    boxes = shapely.box(lo[:, 0], lo[:, 1], hi[:, 0], hi[:, 1])
    tree = shapely.STRtree(boxes)
    query, found = tree.query(boxes)  # envelopes overlap: for boxes that is the test itself
    keep = query < found
    return query[keep].astype(np.int64), found[keep].astype(np.int64)


def _pairs_intersect(a: np.ndarray, d: np.ndarray, i: np.ndarray, j: np.ndarray, k: int, tol: float) -> np.ndarray:
    """Exact orientation test of edge pairs (i, j): crossing or touching, or folding back for
    neighbours (which always share a vertex)."""
    ax, ay = a[i, 0], a[i, 1]
    dx, dy = d[i, 0], d[i, 1]
    bx, by = ax + dx, ay + dy
    cx, cy = a[j, 0], a[j, 1]
    ex, ey = d[j, 0], d[j, 1]
    fx, fy = cx + ex, cy + ey
    # Orientation of each segment's end points relative to the other segment.
    o1 = _cross(dx, dy, cx - ax, cy - ay)
    o2 = _cross(dx, dy, fx - ax, fy - ay)
    o3 = _cross(ex, ey, ax - cx, ay - cy)
    o4 = _cross(ex, ey, bx - cx, by - cy)
    s1, s2, s3, s4 = (np.where(np.abs(o) <= tol, 0.0, np.sign(o)) for o in (o1, o2, o3, o4))
    proper = (s1 * s2 < 0) & (s3 * s4 < 0)
    touch = (
        ((s1 == 0) & _within_box(ax, ay, bx, by, cx, cy, tol))
        | ((s2 == 0) & _within_box(ax, ay, bx, by, fx, fy, tol))
        | ((s3 == 0) & _within_box(cx, cy, fx, fy, ax, ay, tol))
        | ((s4 == 0) & _within_box(cx, cy, fx, fy, bx, by, tol))
    )
    hit = proper | touch
    adjacent = (j == i + 1) | ((i == 0) & (j == k - 1))
    fold = (s1 == 0) & (s2 == 0) & (dx * ex + dy * ey < 0)
    return np.where(adjacent, fold, hit)


def _within_box(px, py, qx, qy, rx, ry, tol):
    """Whether r lies in the bounding box of segment pq (r is known to be collinear with it)."""
    return (
        (np.minimum(px, qx) - tol <= rx)
        & (rx <= np.maximum(px, qx) + tol)
        & (np.minimum(py, qy) - tol <= ry)
        & (ry <= np.maximum(py, qy) + tol)
    )


def distinct_vertex_count(polygon_m: np.ndarray) -> int:
    """Number of distinct vertices.

    Parameters
    ----------
    polygon_m : array_like, shape (K, 2), m

    Returns
    -------
    int
    """
    # a set of rows, not np.unique(axis=0): that costs 20 ms at its first call in a process
    return len({(float(x), float(y)) for x, y in as_polygon(polygon_m)})


def is_simple(polygon_m: np.ndarray) -> bool:
    """Whether a polygon is simple: at least 3 distinct vertices, non-zero area, no edges
    crossing or touching each other (see :func:`self_intersections`).

    Parameters
    ----------
    polygon_m : array_like, shape (K, 2), m

    Returns
    -------
    bool
    """
    p = as_polygon(polygon_m)
    if distinct_vertex_count(p) < 3 or has_zero_area(p):
        return False
    return not self_intersections(p)


def has_zero_area(polygon_m: np.ndarray) -> bool:
    """Whether a polygon's area is zero to round-off (relative to its size squared).

    Parameters
    ----------
    polygon_m : array_like, shape (K, 2), m

    Returns
    -------
    bool
    """
    p = as_polygon(polygon_m)
    if len(p) < 3:
        return True
    scale = float(np.max(np.abs(p - p.mean(axis=0)))) or 1.0
    return polygon_area(p) <= _REL_TOL * scale * scale


def check_simple(polygon_m: np.ndarray, name: str = "polygon_m") -> np.ndarray:
    """Validate a polygon and return it as float64 (K, 2).

    Parameters
    ----------
    polygon_m : array_like, shape (K, 2), m
    name : str
        Name used in error messages.

    Returns
    -------
    numpy.ndarray, shape (K, 2), float64, m

    Raises
    ------
    ValueError
        Naming ``name`` when the polygon has fewer than 3 distinct vertices, no area, or
        crossing edges (the first few edge pairs are listed).
    """
    p = as_polygon(polygon_m, name)
    n = distinct_vertex_count(p)
    if n < 3:
        raise ValueError(f"{name} needs at least 3 distinct points, got {n}")
    crossings = self_intersections(p)
    if crossings:
        shown = ", ".join(f"{i}-{j}" for i, j in crossings[:5])
        more = f" and {len(crossings) - 5} more" if len(crossings) > 5 else ""
        raise ValueError(f"{name} is self-intersecting: edges {shown}{more} cross")
    if has_zero_area(p):
        raise ValueError(f"{name} has zero area")
    return p


def points_in_polygon(points_m: np.ndarray, polygon_m: np.ndarray) -> np.ndarray:
    """Which points lie inside a polygon (even-odd crossing rule, vectorised over points).

    Points exactly on the boundary follow the half-open convention of the crossing test
    (points on a left or bottom edge count as inside, on a right or top edge as outside),
    so two polygons sharing an edge never both claim a point on it.

    Parameters
    ----------
    points_m : array_like, shape (N, 2), m
    polygon_m : array_like, shape (K, 2), m

    Returns
    -------
    numpy.ndarray, shape (N,), bool
    """
    pts = np.asarray(points_m, dtype=np.float64).reshape(-1, 2)
    poly = as_polygon(polygon_m)
    inside = np.zeros(len(pts), dtype=bool)
    if len(poly) < 3 or len(pts) == 0:
        return inside
    lo, hi = poly.min(axis=0), poly.max(axis=0)
    box = np.all((pts >= lo) & (pts <= hi), axis=1)
    if not np.any(box):
        return inside
    sel = np.nonzero(box)[0]
    x, y = pts[sel, 0], pts[sel, 1]
    crossings = np.zeros(len(sel), dtype=bool)
    xi, yi = poly[:, 0], poly[:, 1]
    xj, yj = np.roll(xi, 1), np.roll(yi, 1)
    for k in range(len(poly)):
        if yi[k] == yj[k]:
            continue  # horizontal edges never straddle a scan line
        straddle = (yi[k] > y) != (yj[k] > y)
        x_cross = xi[k] + (y - yi[k]) * (xj[k] - xi[k]) / (yj[k] - yi[k])
        crossings ^= straddle & (x < x_cross)
    inside[sel] = crossings
    return inside


def owner_of_points(points_m: np.ndarray, polygons: Sequence[np.ndarray]) -> np.ndarray:
    """Index of the body that owns each point; where bodies overlap the later body wins.

    Parameters
    ----------
    points_m : array_like, shape (N, 2), m
    polygons : sequence of array_like, each shape (K_i, 2), m
        Body outlines in painting order.

    Returns
    -------
    numpy.ndarray, shape (N,), int64
        Body index for each point, -1 where no body contains it.
    """
    pts = np.asarray(points_m, dtype=np.float64).reshape(-1, 2)
    owner = np.full(len(pts), -1, dtype=np.int64)
    for index, polygon in enumerate(polygons):
        owner[points_in_polygon(pts, polygon)] = index
    return owner
