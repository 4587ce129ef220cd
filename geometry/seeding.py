"""Material points from body polygons: grid-aligned lattice or Gauss points of a quad mesh.

Both seeders take the bodies in painting order (where bodies overlap, the later body owns
the overlap) and return :class:`Seeds`: positions, volumes (area per unit thickness in plane
strain) and the index of the body each point belongs to.

lattice
    Each background-grid cell (square, side ``cell_size_m``, cells start at ``origin_m``) is
    split into ``per_cell x per_cell`` sub-cells of side ``h = cell_size_m / per_cell``; a point
    sits at the centre of every sub-cell a body covers whole, with volume ``h**2``, and at the
    centroid of each body's part of a sub-cell its outline cuts, with that part's area.
gauss
    The bodies are meshed into quadrilaterals of edge ``cell_size_m`` (gmsh, see
    :mod:`geometry.gmsh_bodies`); each quad gets ``per_cell x per_cell`` Gauss-Legendre points
    with volume ``w_i w_j |det J|``. The volumes of a body sum to its area to round-off.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from geometry.polygons import check_simple, owner_of_points

logger = logging.getLogger(__name__)

# Lattice points are located in blocks of rows to bound the temporary memory.
_LATTICE_BLOCK_POINTS = 2_000_000
# Sub-cell indices beyond this cannot be counted (int64 with room to spare).
_MAX_SUBCELL_INDEX = 2.0**60
# Pieces of a cut sub-cell smaller than this fraction of it get no point (their centroid is round-off).
_MIN_PIECE = 1e-6
#: Snap-rounding grid of the bodies' regions where the floating-point overlay fails (sub-cells),
#: and how far (sub-cell areas) the two may differ before it counts as failed (_own_regions).
_SNAP_SUB_CELLS = 1e-9
_OVERLAY_AGREE = 1e-6


@dataclass(frozen=True)
class Seeds:
    """Material points seeded in bodies.

    Attributes
    ----------
    positions_m : numpy.ndarray, shape (N, 2), float64, m
        Point positions.
    volumes_m2 : numpy.ndarray, shape (N,), float64, m2
        Volume of each point per unit thickness (plane strain).
    body_index : numpy.ndarray, shape (N,), int64
        Index of the body (in the list given to the seeder) each point belongs to.
    bounds_m : numpy.ndarray, shape (N, 4), float64, m, or None
        Lattice seeding: the box (x min, y min, x max, y max) of the part of its sub-cell each
        point stands for (the sub-cell itself but along outlines), for the k0 stage's bars.
    """

    positions_m: np.ndarray
    volumes_m2: np.ndarray
    body_index: np.ndarray
    bounds_m: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.volumes_m2)

    def body_volumes_m2(self, n_bodies: int) -> np.ndarray:
        """Total volume of each body's points.

        Parameters
        ----------
        n_bodies : int
            Number of bodies seeded (bodies without points get 0).

        Returns
        -------
        numpy.ndarray, shape (n_bodies,), float64, m2
        """
        return np.bincount(self.body_index, weights=self.volumes_m2, minlength=n_bodies)


def _check_per_cell(per_cell: int) -> int:
    if isinstance(per_cell, bool) or not isinstance(per_cell, (int, np.integer)) or per_cell < 1:
        raise ValueError(
            f"per_cell must be an integer >= 1 (points per cell per direction), got {per_cell!r}"
        )
    return int(per_cell)


def _check_cell_size(cell_size_m: float) -> float:
    try:
        size = float(cell_size_m)
    except (TypeError, ValueError):
        size = float("nan")
    if not np.isfinite(size) or size <= 0.0:
        raise ValueError(f"cell_size_m must be a positive number of metres, got {cell_size_m!r}")
    return size


def _empty() -> Seeds:
    return Seeds(np.zeros((0, 2)), np.zeros(0), np.zeros(0, dtype=np.int64))


def seed_lattice(
    polygons: Sequence[np.ndarray],
    origin_m: tuple[float, float],
    cell_size_m: float,
    per_cell: int,
    holes: Sequence[np.ndarray] = (),
) -> Seeds:
    """Seed points on a lattice aligned with the background grid, clipped by the bodies.

    Every grid cell ``[ox + i dx, ox + (i+1) dx] x [oy + j dx, oy + (j+1) dx]`` is divided into
    ``per_cell x per_cell`` sub-cells of side ``h = dx / per_cell``. A sub-cell no body outline
    passes through gets a point at its centre if a body contains the centre (overlaps go to the
    later body), with volume ``h**2``. A sub-cell an outline passes through gets one point per
    body at the centroid of the part of it that body's own region (its polygon less the later
    bodies) covers, with that part's area (parts below ``_MIN_PIECE`` of a sub-cell get none).

    So a body's volumes sum to its area, less what later bodies cover, to round-off at any
    alignment with the grid, and its material reaches its outline: with centres alone it
    stopped up to half a sub-cell short of an edge or ran past it, which next to a structure
    face off the node lines took 5-6.5 % off the at-rest thrust (docs/geometry.md).

    Parameters
    ----------
    polygons : sequence of array_like, each shape (K_i, 2), m
        Simple body outlines in painting order.
    origin_m : (float, float), m
        Lower-left corner of the background grid (cell corners lie at ``origin + i * dx``).
    cell_size_m : float, m
        Background-grid cell size ``dx``.
    per_cell : int
        Points per cell per direction (``per_cell**2`` points in a full cell).
    holes : sequence of array_like, each shape (K_i, 2), m
        Outlines that take precedence over every body (the structures): no point is seeded in
        them, and the sub-cells their outlines cut are clipped as a body's are.

    Returns
    -------
    Seeds
        Points ordered by row (y), then by x.

    Raises
    ------
    ValueError
        For non-simple polygons, a non-positive cell size or ``per_cell < 1``.
    """
    polys = [check_simple(p, f"polygons[{i}]") for i, p in enumerate(polygons)]
    holes = [check_simple(p, f"holes[{i}]") for i, p in enumerate(holes)]
    dx = _check_cell_size(cell_size_m)
    n = _check_per_cell(per_cell)
    ox, oy = (float(v) for v in origin_m)
    if not polys:
        return _empty()
    h = dx / n
    allpts = np.concatenate(polys)
    lo, hi = allpts.min(axis=0), allpts.max(axis=0)
    # Sub-cell indices whose centres can fall inside the bounding box.
    with np.errstate(all="ignore"):
        spans = np.array([(lo[0] - ox) / h, (hi[0] - ox) / h, (lo[1] - oy) / h, (hi[1] - oy) / h])
    if h <= 0.0 or not np.all(np.isfinite(spans)) or np.max(np.abs(spans)) > _MAX_SUBCELL_INDEX:
        raise ValueError(
            f"cell_size_m = {cell_size_m!r} is too small for bodies {hi[0] - lo[0]:g} x {hi[1] - lo[1]:g} m "
            f"from the grid origin (sub-cells of {h:g} m cannot be numbered)"
        )
    i0 = int(np.floor(spans[0])) - 1
    i1 = int(np.ceil(spans[1])) + 1
    j0 = int(np.floor(spans[2])) - 1
    j1 = int(np.ceil(spans[3])) + 1
    # Centres computed from integer indices, so that no rounding accumulates along a row.
    xs = ox + (np.arange(i0, i1) + 0.5) * h
    ys = oy + (np.arange(j0, j1) + 0.5) * h
    rows_per_block = max(1, _LATTICE_BLOCK_POINTS // max(1, len(xs)))

    cut_cells = _cells_on_outlines(polys + holes, (ox, oy), h, (i0, j0), (len(xs), len(ys)))
    regions = _own_regions(polys, holes, h)
    positions: list[np.ndarray] = []
    volumes: list[np.ndarray] = []
    owners: list[np.ndarray] = []
    order: list[np.ndarray] = []  # sub-cell number (row-major) of each point, for the row-then-x order
    boxes: list[np.ndarray] = []
    for start in range(0, len(ys), rows_per_block):
        rows = ys[start : start + rows_per_block]
        gy, gx = np.meshgrid(rows, xs, indexing="ij")
        centres = np.column_stack([gx.ravel(), gy.ravel()])
        centre = owner_of_points(centres, polys)
        if holes:
            centre[owner_of_points(centres, holes) >= 0] = -1
        centre = centre.reshape(gy.shape)
        cut = np.zeros(gy.shape, dtype=bool)
        here = (cut_cells[:, 1] >= start) & (cut_cells[:, 1] < start + len(rows))
        cut[cut_cells[here, 1] - start, cut_cells[here, 0]] = True
        number = (np.arange(start, start + len(rows))[:, None] * len(xs) + np.arange(len(xs))[None, :])
        full = ~cut & (centre >= 0)
        positions.append(np.column_stack([gx[full], gy[full]]))
        boxes.append(np.column_stack([gx[full] - 0.5 * h, gy[full] - 0.5 * h, gx[full] + 0.5 * h, gy[full] + 0.5 * h]))
        volumes.append(np.full(int(full.sum()), h * h))
        owners.append(centre[full])
        order.append(number[full])
        if np.any(cut):
            piece_xy, piece_area, piece_body, piece_cell, piece_box = _clip_sub_cells(
                gx[cut], gy[cut], number[cut], h, regions)
            positions.append(piece_xy)
            boxes.append(piece_box)
            volumes.append(piece_area)
            owners.append(piece_body)
            order.append(piece_cell)
    cells = np.concatenate(order)
    body = np.concatenate(owners)
    sort = np.lexsort((body, cells))
    pos = np.concatenate(positions)[sort]
    vol = np.concatenate(volumes)[sort]
    body = body[sort]
    bounds = np.concatenate(boxes)[sort]
    _warn_empty(body, len(polys), "lattice")
    return Seeds(positions_m=pos, volumes_m2=vol, body_index=body, bounds_m=bounds)


def _cells_on_outlines(polys, origin, h, first, count) -> np.ndarray:
    """(i, j) of every sub-cell an outline passes through, with its eight neighbours (so that
    sampling each edge every half sub-cell cannot miss one), within ``count`` from ``first``."""
    marks = []
    for polygon in polys:
        for a, b in zip(polygon, np.roll(polygon, -1, axis=0)):
            samples = max(1, int(math.ceil(2.0 * float(np.hypot(*(b - a))) / h)))
            t = np.linspace(0.0, 1.0, samples + 1)[:, None]
            marks.append(np.floor((a + t * (b - a) - origin) / h).astype(np.int64) - first)
    cells = np.unique(np.concatenate(marks), axis=0)
    around = np.array([(di, dj) for di in (-1, 0, 1) for dj in (-1, 0, 1)])
    cells = np.unique((cells[:, None, :] + around[None, :, :]).reshape(-1, 2), axis=0)
    keep = (cells[:, 0] >= 0) & (cells[:, 0] < count[0]) & (cells[:, 1] >= 0) & (cells[:, 1] < count[1])
    return cells[keep]


def _own_regions(polys: Sequence[np.ndarray], holes: Sequence[np.ndarray] = (), h: float = 1.0) -> list:
    """Each body's own region as a shapely geometry: its polygon less the later bodies and the
    holes.

    GEOS's floating-point overlay can fail where edges nearly coincide, the ordinary case of a body
    resting on a structure: a sheet one cell thick on a 40 deg ramp came out empty (GEOS 3.14; the
    difference was the whole sheet's intersection). Each difference is therefore also taken with
    snap rounding to a grid of ``_SNAP_SUB_CELLS`` sub-cells ``h``, which is robust, and that one
    is used where the two areas disagree by more than ``_OVERLAY_AGREE`` of a sub-cell (elsewhere
    the floating result, exact to round-off)."""
    import shapely

    shapes = [shapely.Polygon(p) for p in polys]
    hole_shapes = [shapely.Polygon(p) for p in holes]
    regions = []
    for index, shape in enumerate(shapes):
        later = shapes[index + 1:] + hole_shapes
        region = shape
        if later:
            cover = shapely.union_all(later)
            region = shapely.difference(shape, cover)
            snapped = shapely.difference(shape, cover, grid_size=_SNAP_SUB_CELLS * h)
            if abs(shapely.area(region) - shapely.area(snapped)) > _OVERLAY_AGREE * h * h:
                logger.debug("body %d: the floating-point overlay failed (area %g against %g); snapped",
                             index, shapely.area(region), shapely.area(snapped))
                region = snapped
        shapely.prepare(region)
        regions.append(region)
    return regions


def _clip_sub_cells(cx: np.ndarray, cy: np.ndarray, cells: np.ndarray, h: float, regions: list):
    """The pieces of the sub-cells centred at (cx, cy) that each body's region covers: centroid,
    area, body, sub-cell number and bounding box per piece (pieces below ``_MIN_PIECE`` of a sub-cell are
    dropped; a whole sub-cell keeps its centre and ``h**2`` exactly, as an uncut one)."""
    import shapely

    boxes = shapely.box(cx - 0.5 * h, cy - 0.5 * h, cx + 0.5 * h, cy + 0.5 * h)
    xy, area, body, cell, bound = [], [], [], [], []
    for index, region in enumerate(regions):
        hit = shapely.intersects(region, boxes)
        if not np.any(hit):
            continue
        pieces = shapely.intersection(boxes[hit], region)
        a = shapely.area(pieces)
        keep = a > _MIN_PIECE * h * h
        pieces, a = pieces[keep], a[keep]
        centre = np.column_stack([cx[hit][keep], cy[hit][keep]])
        centroid = shapely.centroid(pieces)
        p = np.column_stack([shapely.get_x(centroid), shapely.get_y(centroid)])
        box = shapely.bounds(pieces)
        entire = a >= (1.0 - 1e-12) * h * h
        p[entire] = centre[entire]
        a[entire] = h * h
        box[entire] = np.column_stack([centre[entire] - 0.5 * h, centre[entire] + 0.5 * h])
        xy.append(p)
        area.append(a)
        body.append(np.full(len(a), index, dtype=np.int64))
        cell.append(cells[hit][keep])
        bound.append(box)
    if not xy:
        return (np.zeros((0, 2)), np.zeros(0), np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64),
                np.zeros((0, 4)))
    return (np.concatenate(xy), np.concatenate(area), np.concatenate(body), np.concatenate(cell),
            np.concatenate(bound))


def gauss_legendre(per_cell: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Legendre points and weights on [-1, 1].

    Parameters
    ----------
    per_cell : int
        Number of points.

    Returns
    -------
    points : numpy.ndarray, shape (per_cell,)
    weights : numpy.ndarray, shape (per_cell,)
        They sum to 2.
    """
    return np.polynomial.legendre.leggauss(_check_per_cell(per_cell))


def quad_gauss_points(
    nodes_m: np.ndarray, quads: np.ndarray, per_cell: int
) -> tuple[np.ndarray, np.ndarray]:
    """Gauss points of bilinear quadrilaterals and their volumes.

    The reference square [-1, 1]^2 maps to each quad by the bilinear map with corners
    (-1, -1), (1, -1), (1, 1), (-1, 1) at the quad's nodes 0..3. The volume of a point is
    ``w_i w_j |det J|`` at that point; ``det J`` is linear in each reference coordinate, so
    the volumes of a quad sum to its area exactly (up to round-off) for any ``per_cell``.

    Parameters
    ----------
    nodes_m : numpy.ndarray, shape (M, 2), m
    quads : numpy.ndarray, shape (Q, 4), int
        Node indices, counter-clockwise.
    per_cell : int
        Points per quad per direction.

    Returns
    -------
    positions_m : numpy.ndarray, shape (Q * per_cell**2, 2), m
        Ordered by quad, then by point.
    volumes_m2 : numpy.ndarray, shape (Q * per_cell**2,), m2
    """
    xi, w = gauss_legendre(per_cell)
    r, s = np.meshgrid(xi, xi, indexing="ij")
    r, s = r.ravel(), s.ravel()
    weights = np.outer(w, w).ravel()
    # Bilinear shape functions and their derivatives at the points: (P, 4).
    sign_r = np.array([-1.0, 1.0, 1.0, -1.0])
    sign_s = np.array([-1.0, -1.0, 1.0, 1.0])
    shape = 0.25 * (1 + np.outer(r, sign_r)) * (1 + np.outer(s, sign_s))
    d_r = 0.25 * sign_r[None, :] * (1 + np.outer(s, sign_s))
    d_s = 0.25 * sign_s[None, :] * (1 + np.outer(r, sign_r))
    corners = np.asarray(nodes_m, dtype=np.float64)[np.asarray(quads)]  # (Q, 4, 2)
    positions = np.einsum("pa,qad->qpd", shape, corners)  # (Q, P, 2)
    j_r = np.einsum("pa,qad->qpd", d_r, corners)
    j_s = np.einsum("pa,qad->qpd", d_s, corners)
    det = j_r[..., 0] * j_s[..., 1] - j_r[..., 1] * j_s[..., 0]  # (Q, P)
    volumes = weights[None, :] * np.abs(det)
    return positions.reshape(-1, 2), volumes.ravel()


def seed_gauss(polygons: Sequence[np.ndarray], cell_size_m: float, per_cell: int) -> Seeds:
    """Seed points at the Gauss points of a conforming quad mesh of the bodies.

    The bodies are meshed together with gmsh (:func:`geometry.gmsh_bodies.mesh_bodies`,
    element size ``cell_size_m``); overlaps are meshed once and belong to the later body,
    so no area is counted twice. Each quad gets ``per_cell x per_cell`` Gauss-Legendre
    points; the volume of a point is its weight times ``|det J|``. The volumes of a body
    sum to its area (less what later bodies cover) to round-off.

    Parameters
    ----------
    polygons : sequence of array_like, each shape (K_i, 2), m
        Simple body outlines in painting order.
    cell_size_m : float, m
        Quad edge length (normally the background-grid cell size).
    per_cell : int
        Points per quad per direction.

    Returns
    -------
    Seeds
        Points ordered by quad.

    Raises
    ------
    ValueError
        For non-simple polygons, a non-positive cell size or ``per_cell < 1``.
    RuntimeError
        If gmsh fails.
    """
    # Imported here so that the lattice path works without gmsh's heavy import.
    from geometry.gmsh_bodies import mesh_bodies

    n = _check_per_cell(per_cell)
    size = _check_cell_size(cell_size_m)
    if len(polygons) == 0:
        return _empty()
    mesh = mesh_bodies(polygons, size)
    positions, volumes = quad_gauss_points(mesh.nodes_m, mesh.quads, n)
    body = np.repeat(mesh.quad_body, n * n)
    _warn_empty(body, len(polygons), "gauss")
    return Seeds(positions_m=positions, volumes_m2=volumes, body_index=body.astype(np.int64))


def _warn_empty(body: np.ndarray, n_bodies: int, method: str) -> None:
    counts = np.bincount(body, minlength=n_bodies) if len(body) else np.zeros(n_bodies, dtype=int)
    for index in np.nonzero(counts == 0)[0]:
        logger.warning("%s seeding placed no points in body %d", method, index)
