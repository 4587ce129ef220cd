"""Body outlines from files: a CSV of points or a DXF drawing (survey profile or closed outline), or a mesh.

CSV format
----------
A header row ``x_m,y_m`` (or ``x,y``), then one point per row in metres. Blank lines and
lines starting with ``#`` are skipped. The points are either

* a closed outline: the last point repeats the first, or the first and last points share
  the same x (the closing edge is then vertical); or
* an open surface profile: x strictly increasing or strictly decreasing. It is closed into
  a body by vertical sides down to a horizontal base at ``base_y_m`` (default: the lowest
  point of the profile).

DXF format
----------
The polyline with the most vertices (LWPOLYLINE or POLYLINE, drawing units taken as metres), or,
without polylines, the LINE entities chained end to end; its points then follow the CSV rules
(a closed polyline is an outline, an open one a surface profile). Read with ezdxf, imported when
first used.

Mesh format
-----------
Any 2D mesh meshio reads (Gmsh ``.msh``, VTK/VTU, XDMF, ...), with triangles and/or
quadrilaterals (higher-order cells use their corner nodes) and z = 0 if 3D coordinates are
stored. The outline is the outer boundary: the edges used by exactly one cell, chained into
loops, of which the loop enclosing the largest area is returned.
"""

from __future__ import annotations

import csv
import logging
import math
import os
from collections import defaultdict

import numpy as np

from geometry.polygons import (
    counter_clockwise,
    edge_text,
    is_simple,
    remove_spikes,
    self_intersections,
    signed_area,
)

logger = logging.getLogger(__name__)

_HEADERS = {("x_m", "y_m"), ("x", "y")}
# Corner-node count of the 2D meshio cell types we read.
_CELL_CORNERS = {
    "triangle": 3,
    "triangle6": 3,
    "triangle7": 3,
    "quad": 4,
    "quad8": 4,
    "quad9": 4,
}


def outline_from_csv(path: str | os.PathLike, base_y_m: float | None = None) -> np.ndarray:
    """Read a body outline from a CSV of points.

    Parameters
    ----------
    path : str or path-like
        CSV file with a header ``x_m,y_m`` (or ``x,y``); ``#`` lines are comments.
    base_y_m : float or None, m
        For an open surface profile, the height of the horizontal base the body is closed
        down to; None uses the lowest point of the profile. Ignored for closed outlines.

    Returns
    -------
    numpy.ndarray, shape (K, 2), float64, m
        A simple polygon, counter-clockwise, without a repeated closing vertex.

    Raises
    ------
    ValueError
        For a missing or wrong header, a row without exactly two values, a non-numeric or
        non-finite value (with its line number), fewer than 3 points, a base above the
        lowest profile point, an open profile whose x is not monotonic, or an outline that
        is not simple.
    """
    name = os.fspath(path)
    points: list[tuple[float, float]] = []
    header_seen = False
    with open(name, newline="", encoding="utf-8-sig") as handle:
        for line_no, row in enumerate(csv.reader(handle), start=1):
            cells = [c.strip() for c in row]
            if not cells or all(c == "" for c in cells) or cells[0].startswith("#"):
                continue
            if not header_seen:
                header = tuple(c.lower() for c in cells)
                if header not in _HEADERS:
                    raise ValueError(
                        f"{name}: line {line_no}: expected the header 'x_m,y_m' (or 'x,y'), "
                        f"got {','.join(cells)!r}"
                    )
                header_seen = True
                continue
            if len(cells) != 2:
                raise ValueError(f"{name}: line {line_no}: expected 2 values (x, y), got {len(cells)}")
            try:
                x, y = float(cells[0]), float(cells[1])
            except ValueError:
                raise ValueError(
                    f"{name}: line {line_no}: non-numeric value in {','.join(cells)!r}"
                ) from None
            if not (math.isfinite(x) and math.isfinite(y)):
                raise ValueError(f"{name}: line {line_no}: non-finite value in {','.join(cells)!r}")
            points.append((x, y))
    if not header_seen:
        raise ValueError(f"{name}: no header row 'x_m,y_m' (or 'x,y') found")
    return _outline_from_points(name, np.array(points, dtype=np.float64).reshape(-1, 2), base_y_m)


def _outline_from_points(name: str, pts: np.ndarray, base_y_m: float | None) -> np.ndarray:
    """The outline of (K, 2) points read from the file ``name`` (m), by the rules of the CSV format."""
    if len(np.unique(pts, axis=0)) < 3:
        raise ValueError(f"{name}: needs at least 3 distinct points, got {len(np.unique(pts, axis=0))}")

    closed = np.array_equal(pts[0], pts[-1]) or pts[0, 0] == pts[-1, 0]
    if closed:
        if base_y_m is not None:
            logger.info("%s is a closed outline; base_y_m is ignored", name)
        polygon = pts[:-1] if np.array_equal(pts[0], pts[-1]) else pts
    else:
        polygon = _close_profile(name, pts, base_y_m)
    crossings = self_intersections(polygon)
    if crossings or not is_simple(polygon):
        detail = (f": edges {edge_text(polygon, crossings[0][0])} and {edge_text(polygon, crossings[0][1])} cross"
                  if crossings else "")
        hint = (
            "" if closed else "; for a profile with its lowest point inside, pass base_y_m below it"
        )
        raise ValueError(f"{name}: the outline is not a simple polygon{detail}{hint}")
    return counter_clockwise(polygon)


def _close_profile(name: str, pts: np.ndarray, base_y_m: float | None) -> np.ndarray:
    """Close an open surface profile down to a horizontal base."""
    steps = np.diff(pts[:, 0])
    if not (np.all(steps > 0) or np.all(steps < 0)):
        raise ValueError(
            f"{name}: an open surface profile needs x strictly increasing or decreasing; "
            "for a closed outline repeat the first point at the end"
        )
    lowest = float(pts[:, 1].min())
    base = lowest if base_y_m is None else float(base_y_m)
    if not math.isfinite(base):
        raise ValueError(f"base_y_m must be finite, got {base_y_m!r}")
    if base > lowest:
        raise ValueError(
            f"base_y_m = {base:g} m is above the lowest profile point (y = {lowest:g} m); "
            "it must be at or below it"
        )
    corners = np.array([[pts[-1, 0], base], [pts[0, 0], base]])
    # A profile end on the base leaves a repeated corner, a flat stretch on the base a spike.
    extent = float(np.ptp(pts, axis=0).max())
    return remove_spikes(np.concatenate([pts, corners]), 1e-12 * extent)


def _chain_lines(segments: list[tuple[tuple[float, float], tuple[float, float]]],
                 tol: float) -> list[tuple[float, float]]:
    """LINE entities joined end to end, starting from a free end (an open profile) if there is one."""
    if not segments:
        return []
    remaining = list(segments)
    ends = [p for seg in remaining for p in seg]

    def count(p: tuple[float, float]) -> int:
        return sum(1 for q in ends if abs(q[0] - p[0]) <= tol and abs(q[1] - p[1]) <= tol)

    start = next((p for p in ends if count(p) == 1), remaining[0][0])
    chain = [start]
    while remaining:
        last = chain[-1]
        for i, (a, b) in enumerate(remaining):
            if abs(a[0] - last[0]) <= tol and abs(a[1] - last[1]) <= tol:
                chain.append(b)
                break
            if abs(b[0] - last[0]) <= tol and abs(b[1] - last[1]) <= tol:
                chain.append(a)
                break
        else:
            break  # the rest is not connected to this chain
        remaining.pop(i)
    return chain


def dxf_points(path: str | os.PathLike) -> np.ndarray:
    """The points of the profile or outline in a DXF drawing, (K, 2) in drawing units.

    The polyline with the most vertices (LWPOLYLINE or POLYLINE; a closed one repeats its first
    point at the end), or, without polylines, the LINE entities chained end to end.

    Raises
    ------
    ValueError
        The file is not a readable DXF, or holds no polyline and no lines.
    """
    import ezdxf

    name = os.fspath(path)
    try:
        doc = ezdxf.readfile(name)
    except (OSError, ezdxf.DXFError) as err:
        raise ValueError(f"{name}: not a readable DXF drawing ({err})") from None
    msp = doc.modelspace()
    polylines: list[list[tuple[float, float]]] = []
    for entity in msp.query("LWPOLYLINE"):
        pts = [(float(x), float(y)) for x, y in entity.get_points("xy")]
        if entity.closed and pts:
            pts.append(pts[0])
        polylines.append(pts)
    for entity in msp.query("POLYLINE"):
        pts = [(float(v.dxf.location.x), float(v.dxf.location.y)) for v in entity.vertices]
        if entity.is_closed and pts:
            pts.append(pts[0])
        polylines.append(pts)
    if polylines:
        return np.array(max(polylines, key=len), dtype=float)
    segments = [((float(e.dxf.start.x), float(e.dxf.start.y)), (float(e.dxf.end.x), float(e.dxf.end.y)))
                for e in msp.query("LINE")]
    if not segments:
        raise ValueError(f"{name}: no polyline or line in the drawing's model space")
    extent = max(max(abs(c) for seg in segments for p in seg for c in p), 1.0)
    return np.array(_chain_lines(segments, 1e-9 * extent), dtype=float)


def outline_from_dxf(path: str | os.PathLike, base_y_m: float | None = None) -> np.ndarray:
    """Read a body outline from a DXF drawing (ezdxf, imported on first use).

    The points (:func:`dxf_points`, drawing units taken as metres) follow exactly the rules of
    a CSV of points (:func:`outline_from_csv`): a closed polyline is an outline, an open one a
    surface profile closed down to a horizontal base at ``base_y_m`` (m; default its lowest point).

    Returns
    -------
    numpy.ndarray, shape (K, 2), float64, m
        A simple polygon, counter-clockwise, without a repeated closing vertex.

    Raises
    ------
    ValueError
        With the file name and what is wrong (one line).
    """
    return _outline_from_points(os.fspath(path), dxf_points(path), base_y_m)


#: Suffixes :func:`read_outline` reads as meshes (meshio).
MESH_SUFFIXES = (".msh", ".vtk", ".vtu", ".xdmf", ".xmf", ".med", ".inp")


def read_outline(path: str | os.PathLike, base_y_m: float | None = None) -> np.ndarray:
    """A body outline from a CSV or DXF profile or outline, or a 2D mesh, by the file's suffix.

    Parameters
    ----------
    path : path-like
    base_y_m : float, optional, m
        For an open surface profile (CSV or DXF): the height of the horizontal base it is
        closed down to (default: its lowest point).

    Returns
    -------
    numpy.ndarray
        (K, 2) float, m: a simple polygon, counter-clockwise.

    Raises
    ------
    ValueError
        With the file name and what is wrong (one line).
    """
    name = os.fspath(path)
    suffix = os.path.splitext(name)[1].lower()
    if suffix == ".csv":
        return outline_from_csv(path, base_y_m)
    if suffix == ".dxf":
        return outline_from_dxf(path, base_y_m)
    if suffix in MESH_SUFFIXES:
        return outline_from_mesh(path)
    raise ValueError(f"{name}: unknown kind of file {suffix or '(no suffix)'!r}; "
                     "import a .csv or .dxf profile or a mesh (.msh, .vtk, .vtu, .xdmf)")


def outline_from_mesh(path: str | os.PathLike) -> np.ndarray:
    """Read the outer boundary of a 2D mesh as a body outline.

    Parameters
    ----------
    path : str or path-like
        A mesh file meshio can read, with triangle and/or quadrilateral cells.

    Returns
    -------
    numpy.ndarray, shape (K, 2), float64, m
        The outer boundary loop, counter-clockwise, without a repeated closing vertex;
        every boundary node is kept, including those on straight stretches.

    Raises
    ------
    ValueError
        If meshio cannot read the file, the mesh has no triangle or quad cells, its nodes
        are not in the plane z = 0, or its boundary edges do not form a closed loop.
    """
    import meshio  # lazy: only the importer needs it

    name = os.fspath(path)
    if not os.path.isfile(name):
        raise FileNotFoundError(f"{name}: no such mesh file")
    try:
        mesh = meshio.read(name)
    except meshio.ReadError as exc:
        raise ValueError(f"{name}: meshio cannot read this file: {exc}") from exc
    points = np.asarray(mesh.points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] not in (2, 3):
        raise ValueError(f"{name}: expected 2D or 3D point coordinates, got shape {points.shape}")
    if points.shape[1] == 3:
        extent = float(np.ptp(points[:, :2], axis=0).max()) if len(points) else 0.0
        if np.any(np.abs(points[:, 2]) > 1e-9 * max(extent, 1.0)):
            raise ValueError(f"{name}: the mesh is not planar: nodes have z != 0")
    xy = points[:, :2]

    edges: list[np.ndarray] = []
    for block in mesh.cells:
        corners = _CELL_CORNERS.get(block.type)
        if corners is None:
            continue
        cells = np.asarray(block.data, dtype=np.int64)[:, :corners]
        for a in range(corners):
            edges.append(np.column_stack([cells[:, a], cells[:, (a + 1) % corners]]))
    if not edges:
        raise ValueError(f"{name}: the mesh has no triangle or quadrilateral cells")
    all_edges = np.concatenate(edges)
    undirected = np.sort(all_edges, axis=1)
    unique, counts = np.unique(undirected, axis=0, return_counts=True)
    boundary = unique[counts == 1]
    if len(boundary) < 3:
        raise ValueError(f"{name}: the mesh has no closed boundary")

    loops = _chain_loops(name, boundary)
    areas = [abs(signed_area(xy[loop])) for loop in loops]
    best = int(np.argmax(areas))
    if len(loops) > 1:
        logger.info(
            "%s: %d boundary loops (holes or separate parts); keeping the outer one", name, len(loops)
        )
    return counter_clockwise(xy[loops[best]])


def _chain_loops(name: str, boundary: np.ndarray) -> list[np.ndarray]:
    """Chain undirected boundary edges (E, 2) into closed loops of node indices."""
    neighbours: dict[int, list[int]] = defaultdict(list)
    for a, b in boundary:
        neighbours[int(a)].append(int(b))
        neighbours[int(b)].append(int(a))
    odd = [n for n, nb in neighbours.items() if len(nb) % 2]
    if odd:
        raise ValueError(f"{name}: the mesh boundary is not closed (open at node {odd[0]})")
    used: set[tuple[int, int]] = set()
    loops: list[np.ndarray] = []
    for start in sorted(neighbours):
        for first in neighbours[start]:
            if (min(start, first), max(start, first)) in used:
                continue
            loop = [start]
            cur = start
            nxt = first
            used.add((min(cur, nxt), max(cur, nxt)))
            cur = nxt
            while cur != start:
                loop.append(cur)
                nxt = next(
                    (n for n in neighbours[cur] if (min(cur, n), max(cur, n)) not in used), None
                )
                if nxt is None:
                    raise ValueError(f"{name}: the mesh boundary is not closed (stuck at node {cur})")
                used.add((min(cur, nxt), max(cur, nxt)))
                cur = nxt
            loops.append(np.array(loop, dtype=np.int64))
    return loops
