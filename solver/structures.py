"""Rigid structures on the grid: signed distance and outward normals of polygons, in numpy.

Worked out once at set-up and uploaded to the engine (see docs/solver.md, contact): for every grid
node the structure that overlaps its cell (the square of one cell centred on the node) and the
outward normal there, the gradient of the polygon's signed distance. Inside a polygon the
gradient points from the node to the nearest point of the surface, outward; just outside, away
from it; on the surface it is the edge's outward normal (the mean of the two at a vertex), so
inclined and curved surfaces get their own normals, not grid axes. Near a convex corner a node
carries the two faces' normals instead (:func:`corner_normals`), and the engine takes the one the
material moves least into.

Why the cell and not the node alone: a closed side lies on a node line, so its contact nodes are
on the surface. An inclined surface crosses the node lines; constraining only the nodes on or
inside it leaves the row just outside (up to 0.7 cells from the surface at 45 degrees) carrying
the material next to the surface without support: a block at rest on a 30 degree ramp settled by
0.02 cells and slipped 0.2 % of its frictionless distance (target 0.1 %; now 0.003 %). A straight
surface on a node line keeps exactly the nodes on the line, like a closed side.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

#: Offset of the central differences of the signed distance, in cell sizes.
GRADIENT_STEP_CELLS = 1e-3
#: Two distances (in cell sizes) closer than this are a tie (a node on the bisector of a corner).
TIE_CELLS = 1e-6
#: A node inside a structure is on its medial axis (held, no normal) where, within this many cells
#: of it along its normal, the normal turns to face it (within FACING of opposite, cosine).
MEDIAL_CELLS = 0.25
FACING = 0.9
#: Contact nodes within this many cells of a convex vertex, along both axes, take the normal of the
#: material next to them (:func:`corner_zone`).
CORNER_ZONE_CELLS = 2.0
#: How far a particle's quadratic B-spline weights reach (cells).
STENCIL_CELLS = 1.5


def segments(polygon_m: Sequence[Sequence[float]]) -> tuple[np.ndarray, np.ndarray]:
    """Start and end points (m) of the polygon's edges, shape (K, 2) each (the ring is closed here)."""
    p = np.asarray(polygon_m, dtype=np.float64).reshape(-1, 2)
    if len(p) > 1 and np.allclose(p[0], p[-1]):
        p = p[:-1]
    return p, np.roll(p, -1, axis=0)


def signed_distance(points_m: np.ndarray, polygon_m: Sequence[Sequence[float]]) -> np.ndarray:
    """Signed distance (m) of ``points_m`` (..., 2) to the polygon: negative inside, positive outside."""
    pts = np.asarray(points_m, dtype=np.float64)
    flat = pts.reshape(-1, 2)
    a, b = segments(polygon_m)
    ab = b - a
    ap = flat[:, None, :] - a[None, :, :]
    t = np.clip((ap * ab).sum(-1) / np.maximum((ab * ab).sum(-1), 1e-300), 0.0, 1.0)
    nearest = a[None] + t[..., None] * ab[None]
    dist = np.sqrt(((flat[:, None, :] - nearest) ** 2).sum(-1)).min(axis=1)
    # crossing number: edges that straddle the horizontal line through the point, left of it
    y = flat[:, 1:2]
    straddle = (a[None, :, 1] > y) != (b[None, :, 1] > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        x_cross = a[None, :, 0] + (y - a[None, :, 1]) * ab[None, :, 0] / ab[None, :, 1]
    inside = (straddle & (flat[:, 0:1] < x_cross)).sum(axis=1) % 2 == 1
    return np.where(inside, -dist, dist).reshape(pts.shape[:-1])


def through_sides(polygon_m: Sequence[Sequence[float]], lower_m: Sequence[float], upper_m: Sequence[float],
                  depth_m: float, sides: Sequence[bool] = (True, True, True, True)) -> tuple[tuple[float, float], ...]:
    """The polygon with every edge that lies on a side line of the box ``[lower_m, upper_m]``
    continued ``depth_m`` beyond it: the edge ``A -> B`` becomes ``A -> A' -> B' -> B``, ``A'`` and
    ``B'`` moved across the line (sides in SIDES order: left, right, bottom, top; ``sides`` says
    which may be crossed, not periodic ones). Inside the box the outline is unchanged.

    A structure standing on a side (a wall on the grid's bottom) then continues through it, over
    the side's ghost nodes, as if it stood on rock below: its foot has no surface along the side
    line. With that surface, the particles next to both the side and the structure took mirror
    images across the structure's foot corner, and a granular column at rest between a slip side
    and a wall on a slip bottom pushed its at-rest thrust up by 11 % in 0.2 s (0.999 with the foot
    continued). Points within 1e-9 of the box size of a side line count as on it.
    """
    p = [tuple(map(float, v)) for v in np.asarray(polygon_m, dtype=np.float64).reshape(-1, 2)]
    if len(p) > 1 and p[0] == p[-1]:
        p = p[:-1]
    lo, hi = np.asarray(lower_m, float), np.asarray(upper_m, float)
    tol = 1e-9 * float(np.max(hi - lo))
    lines = []  # (axis, coordinate of the line, shift across it)
    for axis in (0, 1):
        if sides[2 * axis]:
            lines.append((axis, lo[axis], -depth_m))
        if sides[2 * axis + 1]:
            lines.append((axis, hi[axis], depth_m))

    def moved(v, axis, shift):
        w = list(v)
        w[axis] += shift
        return (w[0], w[1])

    out = []
    for k, a in enumerate(p):
        b = p[(k + 1) % len(p)]
        out.append(a)
        for axis, at, shift in lines:
            if abs(a[axis] - at) <= tol and abs(b[axis] - at) <= tol and a != b:
                out.extend([moved(a, axis, shift), moved(b, axis, shift)])
                break
    return tuple(out)


def cell_reach(normal: np.ndarray, cell_m: float) -> np.ndarray:
    """How far (m) a node's cell (the square of one cell centred on it) reaches along ``normal``
    (..., 2), unit vectors: ``cell_m / 2 (|n_x| + |n_y|)``; half a cell along a grid axis, 0.71 cells
    at 45 degrees. A node whose signed distance to a straight surface is below this has part of its
    cell (positive area) inside the structure."""
    return 0.5 * cell_m * np.abs(np.asarray(normal, float)).sum(axis=-1)


def _gradient(points_m: np.ndarray, polygon_m, step_m: float) -> np.ndarray:
    """Unit gradient of the signed distance at ``points_m`` (N, 2) by central differences of
    ``step_m``; zero where they cancel (a point on the medial axis)."""
    q = np.asarray(points_m, float)
    grad = np.stack([signed_distance(q + [step_m, 0.0], polygon_m) - signed_distance(q - [step_m, 0.0], polygon_m),
                     signed_distance(q + [0.0, step_m], polygon_m) - signed_distance(q - [0.0, step_m], polygon_m)],
                    axis=-1)
    return grad / np.maximum(np.linalg.norm(grad, axis=-1, keepdims=True), 1e-300)


def node_contacts(polygons: Sequence[Sequence[Sequence[float]]], node_x_m: np.ndarray, node_y_m: np.ndarray,
                  cell_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Which structure covers each grid node, and the outward normal there.

    Parameters
    ----------
    polygons : the structures' polygons (m), in contact order
    node_x_m, node_y_m : node coordinates along x and y (m), shapes (nx,) and (ny,)
    cell_m : cell size (m), for the finite-difference step of the gradient

    Returns
    -------
    index : (nx, ny) int32, the structure that overlaps the node's cell, -1 for none; where two
        overlap, the later one. A node's cell overlaps a structure where its signed distance is below
        :func:`cell_reach` along the outward normal there (exact for a straight surface; near a vertex
        the normal is the direction to the vertex), ties within :data:`TIE_CELLS` included.
    normal : (nx, ny, 2) float64, unit outward normal of that structure at the node (zeros elsewhere)
    """
    X, Y = np.meshgrid(np.asarray(node_x_m, float), np.asarray(node_y_m, float), indexing="ij")
    pts = np.stack([X, Y], axis=-1)
    index = np.full(X.shape, -1, np.int32)
    normal = np.zeros(X.shape + (2,))
    h = GRADIENT_STEP_CELLS * cell_m
    for k, poly in enumerate(polygons):
        a, _ = segments(poly)
        lo, hi = a.min(axis=0) - 2 * cell_m, a.max(axis=0) + 2 * cell_m
        near = np.all((pts >= lo) & (pts <= hi), axis=-1)
        if not near.any():
            continue
        q = pts[near]
        grad = _gradient(q, poly, h)
        inside = signed_distance(q, poly)
        # a node whose cell only touches the surface (a face exactly half a cell from a node line,
        # drawn on round numbers) lands on either side of the strict test by round-off: a tie
        # counts as covered, so that such a face behaves as one a hair nearer (uncovered, the at-rest
        # thrust on it ratcheted up under mpm: 1.07 at 0.5 s, 1.31 at 1.5 s; covered: 1.000)
        covered = inside < cell_reach(grad, cell_m) + TIE_CELLS * cell_m
        # Nodes near the medial axis of a thin part (the middle of a wall two cells thick): within
        # MEDIAL_CELLS of the node along its normal the signed distance's gradient turns to the
        # far face's, facing the near one. Such a node is nearly as close to the far face as to
        # the near one, so its nearest-face normal is a coin toss (round-off decides it on a node
        # line) and, pointing away from the material, let the material's approach through
        # unopposed; it is held instead (zero normal: the engine treats it as a fixed contact
        # node). Only facing surfaces (normals within FACING of opposite: at the apex of a wide
        # wedge the normal of the nearer face is the right one for the material on that side),
        # and only where the part is at least a cell thick (half a cell to either face): a node
        # held in a sharp tip stops material that passes over it (a block thrown over a dam's
        # crest went unstable there).
        medial = np.zeros(len(q), bool)
        deep = inside <= -0.5 * cell_m
        if deep.any():
            step = MEDIAL_CELLS * cell_m
            for sign in (1.0, -1.0):
                other = _gradient(q[deep] + sign * step * grad[deep], poly, h)
                medial[deep] |= (other * grad[deep]).sum(axis=-1) < -FACING
        grad[medial] = 0.0
        where = np.flatnonzero(near.ravel())[covered]
        index.reshape(-1)[where] = k
        normal.reshape(-1, 2)[where] = grad[covered]
    return index, normal


def far_normals(polygons: Sequence[Sequence[Sequence[float]]], node_x_m: np.ndarray, node_y_m: np.ndarray,
                index: np.ndarray, normal: np.ndarray, cell_m: float) -> np.ndarray:
    """The outward normal of a thin part's far face at each contact node whose stencil reaches past it.

    A particle's quadratic B-spline weights reach STENCIL_CELLS (1.5) cells along each axis, so in a
    part thinner than that a contact node takes mass from material on the far side of the part as
    well as on its own side. Its own normal (its nearer face's) points away from that material: a
    granular column against a wall one cell thick pushed its node on the wall's back face, which
    let the push through (0.92-0.97 of the at-rest thrust, the rest taken by the bottom's friction,
    and the line of action 0.38-0.40 H up instead of H / 3). Here, per contact node with a
    normal, the ray from it against its normal is followed to the first point beyond the part,
    within the stencil's reach (the square's edge along that ray); where the surface there faces the
    node's own (normals within FACING of opposite: a plate or wall, not the apex of a wedge), its
    outward normal is the node's far normal. The engine imposes it where the material that the node
    carries lies beyond that face (``Engine._structure_normal``).

    Returns
    -------
    far : (nx, ny, 2) float64, the far face's unit outward normal at such nodes, zeros elsewhere
    """
    X, Y = np.meshgrid(np.asarray(node_x_m, float), np.asarray(node_y_m, float), indexing="ij")
    far = np.zeros(X.shape + (2,))
    h = GRADIENT_STEP_CELLS * cell_m
    tol = TIE_CELLS * cell_m
    for k, poly in enumerate(polygons):
        mine = (index == k) & (np.abs(normal).sum(axis=-1) > 0.0)
        if not mine.any():
            continue
        q = np.c_[X[mine], Y[mine]]
        d = -normal[mine]  # into the part
        reach = STENCIL_CELLS * cell_m / np.abs(d).max(axis=-1)
        # where the ray q + t d crosses each edge a + s e (0 <= s <= 1): one pass over the edges
        a, b = segments(poly)
        e = b - a
        aq = a[None] - q[:, None]
        denom = d[:, None, 0] * e[None, :, 1] - d[:, None, 1] * e[None, :, 0]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (aq[..., 0] * e[None, :, 1] - aq[..., 1] * e[None, :, 0]) / denom
            s_ = (aq[..., 0] * d[:, None, 1] - aq[..., 1] * d[:, None, 0]) / denom
        t = np.where((denom != 0.0) & (s_ >= 0.0) & (s_ <= 1.0) & (t > tol), t, np.inf)
        # the exit: the first crossing from inside (a node on the surface is inside a hair along
        # d); from a node outside (its cell reaches in), the one after the entry (crossings closer
        # than the tie are one, at a vertex)
        first = t.min(axis=1)
        second = np.where(t > first[:, None] + tol, t, np.inf).min(axis=1)
        exit_t = np.where(signed_distance(q + tol * d, poly) <= 0.0, first, second)
        # exactly at the reach the far material's weight vanishes: a tie is not past it, whichever
        # way round-off falls
        found = exit_t < reach - tol
        beyond = q + (np.where(found, exit_t, 0.0) + tol)[:, None] * d
        found[found] = signed_distance(beyond[found], poly) > 0.0
        if not found.any():
            continue
        grad = _gradient(beyond[found], poly, h)
        facing = (grad * -d[found]).sum(axis=-1) < -FACING
        rows = np.flatnonzero(mine.ravel())[np.flatnonzero(found)[facing]]
        far.reshape(-1, 2)[rows] = grad[facing]
    return far


def _outward_normals(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Unit outward normals of the edges ``a -> b`` of a closed polygon (either orientation)."""
    e = b - a
    area = 0.5 * float(np.sum(a[:, 0] * b[:, 1] - b[:, 0] * a[:, 1]))
    out = np.stack([e[:, 1], -e[:, 0]], axis=-1) * (1.0 if area > 0.0 else -1.0)  # right of a CCW edge
    return out / np.maximum(np.linalg.norm(out, axis=-1, keepdims=True), 1e-300)


def convex_vertices(polygon_m: Sequence[Sequence[float]], cell_m: float,
                    box_m: tuple[Sequence[float], Sequence[float]] | None = None) -> np.ndarray:
    """Indices (into :func:`segments`' start points) of the polygon's convex vertices, those
    beyond a side of the grid box ``box_m`` (lower and upper corner) left out: there the structure
    goes on through the side (:func:`through_sides`) and the material, which stays in the box,
    never meets the vertex."""
    a, b = segments(polygon_m)
    e = b - a
    prev = np.roll(np.arange(len(a)), 1)
    turn = e[prev, 0] * e[:, 1] - e[prev, 1] * e[:, 0]
    orient = 1.0 if float(np.sum(a[:, 0] * b[:, 1] - b[:, 0] * a[:, 1])) > 0.0 else -1.0
    lengths = np.linalg.norm(e, axis=-1)
    convex = orient * turn > 1e-9 * lengths[prev] * lengths
    if box_m is not None:
        slack = TIE_CELLS * cell_m
        convex &= np.all((a >= np.asarray(box_m[0], float) - slack) & (a <= np.asarray(box_m[1], float) + slack),
                         axis=-1)
    return np.flatnonzero(convex)


def corner_zone(polygons: Sequence[Sequence[Sequence[float]]], node_x_m: np.ndarray, node_y_m: np.ndarray,
                index: np.ndarray, normal: np.ndarray, cell_m: float,
                box_m: tuple[Sequence[float], Sequence[float]] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The contact nodes near a structure's convex vertex, where the engine takes the normal from
    the material next to the node (``Engine._corner_particle_normals``), and the box the particles
    that reach them lie in.

    A node within CORNER_ZONE_CELLS of a convex vertex along both axes can carry material that lies
    against the corner's other face: a sheet whose upslope end starts on a ramp's convex top vertex
    gives mass to the level top's node one cell back from the vertex; with the top's normal there
    the sheet's slide down the ramp is an approach to the top, which the node stopped, and the stiff
    sheet slid 7-9 % short (mpm, apic; 1-2 % apic-affine). Held nodes (zero normal, the medial axis)
    are left out.

    Returns
    -------
    zone : (nx, ny) int32, the structure's index + 1 at its zone nodes, 0 elsewhere
    boxes : (len(polygons), 4) float64, per structure the box (x min, y min, x max, y max, m) of
        the points whose stencil reaches one of its zone nodes (empty, min > max, where none)
    """
    X, Y = np.meshgrid(np.asarray(node_x_m, float), np.asarray(node_y_m, float), indexing="ij")
    zone = np.zeros(X.shape, np.int32)
    boxes = np.tile(np.array([np.inf, np.inf, -np.inf, -np.inf]), (len(polygons), 1))
    reach = CORNER_ZONE_CELLS * cell_m * (1.0 + 1e-9)
    for k, poly in enumerate(polygons):
        mine = (index == k) & (np.abs(normal).sum(axis=-1) > 0.0)
        a, _ = segments(poly)
        # per vertex over this structure's contact nodes only, not the whole grid (a curve drawn
        # with hundreds of chords has as many convex vertices)
        x, y = X[mine], Y[mine]
        close = np.zeros(x.shape, bool)
        for v in a[convex_vertices(poly, cell_m, box_m)]:
            close |= (np.abs(x - v[0]) <= reach) & (np.abs(y - v[1]) <= reach)
        near = np.zeros(X.shape, bool)
        near[mine] = close
        if near.any():
            zone[near] = k + 1
            boxes[k] = _reach_box(X[near], Y[near], cell_m, boxes[k])
    return zone, boxes


def zone_nodes(polygons: Sequence[Sequence[Sequence[float]]], node_x_m: np.ndarray, node_y_m: np.ndarray,
               index: np.ndarray, normal: np.ndarray, far: np.ndarray, cell_m: float,
               box_m: tuple[Sequence[float], Sequence[float]] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Every contact node whose normal the engine decides from the material next to it: those near a
    convex vertex (:func:`corner_zone`) and those of a part thinner than a stencil (a far normal,
    :func:`far_normals`), and the box the particles that reach them lie in.

    Returns
    -------
    zone : (nx, ny) int32, the structure's index + 1 at its corner-zone nodes, minus that at its
        other thin nodes (``Engine._structure_normal`` tells them apart), 0 elsewhere
    boxes : (len(polygons), 4) float64, as :func:`corner_zone`'s, over both kinds
    """
    zone, boxes = corner_zone(polygons, node_x_m, node_y_m, index, normal, cell_m, box_m)
    thin = (np.abs(far).sum(axis=-1) > 0.0) & (zone == 0)
    zone[thin] = -(index[thin] + 1)
    X, Y = np.meshgrid(np.asarray(node_x_m, float), np.asarray(node_y_m, float), indexing="ij")
    for k in range(len(polygons)):
        mine = thin & (index == k)
        if mine.any():
            boxes[k] = _reach_box(X[mine], Y[mine], cell_m, boxes[k])
    return zone, boxes


def _reach_box(x: np.ndarray, y: np.ndarray, cell_m: float, box: np.ndarray) -> list[float]:
    """``box`` grown to hold every point whose stencil reaches one of the nodes ``(x, y)``."""
    stencil = STENCIL_CELLS * cell_m  # a particle's weights reach this far from it
    return [min(box[0], x.min() - stencil), min(box[1], y.min() - stencil),
            max(box[2], x.max() + stencil), max(box[3], y.max() + stencil)]


def corner_normals(polygons: Sequence[Sequence[Sequence[float]]], node_x_m: np.ndarray, node_y_m: np.ndarray,
                   index: np.ndarray, normal: np.ndarray, cell_m: float,
                   box_m: tuple[Sequence[float], Sequence[float]] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The two normals of every contact node: the faces of a convex corner at a node near one,
    the node's own normal twice elsewhere.

    A node whose nearest surface point is a convex vertex of its structure (the node on the vertex
    and those outside in the vertex's region), a node inside as near to the two faces of a convex
    corner as to each other and to no other face (on the corner's bisector), and a node whose cell (the square of one
    cell centred on it) holds a convex vertex meet the corner, not one surface: the gradient of the
    signed distance there is a blend of the two faces' normals (the bisector on the vertex) or the
    direction to the vertex, and material sliding along either face away from the corner moves into
    it. With it, a sheet sliding down a 40 deg ramp from one cell below the ramp's convex top was
    braked by the node on the vertex (its friction 1.04-1.10 mu N for 0.15 s) and slid 3.4 % short
    (mpm; apic 1.8 %, apic-affine 0.8 %). Such a node takes the two faces' outward normals instead,
    and the engine applies the contact law with the one the node's velocity moves least into
    (``Engine._structure_normal``): the material meets the corner's solid only when it moves into
    both faces. Where several convex vertices qualify the nearest counts; held nodes (zero normal,
    the medial axis) and concave corners keep their normal. A vertex beyond a side of the grid box
    ``box_m`` (lower and upper corner) is no corner for the material, which stays in the box: the
    foot of a wall that reaches below the grid's bottom is the wall going on (with it, the ghost
    node at that foot let a granular column's push into the wall through along the foot's face).

    Parameters
    ----------
    polygons, node_x_m, node_y_m, cell_m : as for :func:`node_contacts`
    index, normal : what :func:`node_contacts` returned for them
    box_m : the grid box (lower, upper corner, m); None: no vertex is beyond it

    Returns
    -------
    normal_a, normal_b : (nx, ny, 2) float64, equal to ``normal`` except at corner nodes
    """
    X, Y = np.meshgrid(np.asarray(node_x_m, float), np.asarray(node_y_m, float), indexing="ij")
    pts = np.stack([X, Y], axis=-1)
    normal_a = np.array(normal, dtype=np.float64, copy=True)
    normal_b = normal_a.copy()
    tie = TIE_CELLS * cell_m
    for k, poly in enumerate(polygons):
        mine = (index == k) & (np.abs(normal_a).sum(axis=-1) > 0.0)
        if not mine.any():
            continue
        a, b = segments(poly)
        outward = _outward_normals(a, b)
        e = b - a
        prev = np.roll(np.arange(len(a)), 1)  # edge prev[v] ends at vertex v, edge v starts there
        convex = convex_vertices(poly, cell_m, box_m)
        if len(convex) == 0:
            continue
        q = pts[mine]
        ap = q[:, None, :] - a[None]
        t = np.clip((ap * e[None]).sum(-1) / np.maximum((e * e).sum(-1), 1e-300)[None], 0.0, 1.0)
        dist = np.linalg.norm(ap - t[..., None] * e[None], axis=-1)  # (nodes, edges)
        near = dist.min(axis=1, keepdims=True) + tie
        to_vertex = q[:, None, :] - a[None, convex]  # (nodes, convex vertices, 2)
        ties = dist <= near
        # a tie of exactly the corner's two faces: not a node in the middle of a wall two cells
        # thick, as near the far face too (the medial axis' business, node_contacts)
        pair = ties[:, convex] & ties[:, prev[convex]] & (ties.sum(axis=1) == 2)[:, None]
        meets = pair | np.all(np.abs(to_vertex) <= 0.5 * cell_m * (1.0 + 1e-9), axis=-1)
        corner = meets.any(axis=1)
        if not corner.any():
            continue
        r = np.where(meets, np.linalg.norm(to_vertex, axis=-1), np.inf)
        v = convex[np.argmin(r, axis=1)][corner]
        where = np.flatnonzero(mine.ravel())[corner]
        normal_a.reshape(-1, 2)[where] = outward[prev[v]]
        normal_b.reshape(-1, 2)[where] = outward[v]
    return normal_a, normal_b
