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

Layers
------
A section of several layers (:func:`read_layers`): a CSV with a third column ``layer`` (the
header ``x_m,y_m,layer``; each layer's points in their rows' order), or a DXF drawing whose
polylines lie on several layers (each layer's longest polyline, or its LINE entities chained;
layers without a polyline are left out where others have one). Either every layer is a closed
outline, each a body of its own, or every layer is an open profile, x monotonic: the first line
(the highest) is the ground surface, each line below it the top of the next layer down, and the
bodies are the bands between the lines, the lowest closed down to the base (``base_y_m``, default
the lowest point of any line). Each band is named after the line on its top; where a lower line
rises above an upper one the upper layer pinches out, and a band that the lines cut in two gives
two bodies (the second named ``NAME-2``).

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
import stat
from collections import Counter, defaultdict
from typing import NamedTuple

import numpy as np

from geometry.polygons import (
    counter_clockwise,
    drop_repeated_vertices,
    edge_text,
    is_simple,
    remove_spikes,
    self_intersections,
    signed_area,
)

logger = logging.getLogger(__name__)


class LayerBody(NamedTuple):
    """A body of an imported section (:func:`read_layers`): its name, outline and layer."""

    name: str
    polygon_m: np.ndarray
    #: the layer it belongs to (its name, or ``NAME`` of a part ``NAME-2``)
    layer: str

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


#: The largest file an import reads (bytes): a profile of 20,000 points (the project format's
#: limit per outline) takes under 1 MB as CSV; a DXF drawing holds more than its polylines.
MAX_IMPORT_FILE_BYTES = 64_000_000


def file_kind(mode: int) -> str:
    """What a path that is not a regular file is, from its ``st_mode`` (for one-line refusals)."""
    if stat.S_ISDIR(mode):
        return "a folder"
    if stat.S_ISFIFO(mode):
        return "a FIFO (named pipe)"
    if stat.S_ISCHR(mode):
        return "a character device"
    if stat.S_ISBLK(mode):
        return "a block device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a regular file"


def check_import_file(path: str | os.PathLike, max_bytes: int = MAX_IMPORT_FILE_BYTES) -> str:
    """The name of a file an import may read, or one line saying why not, before a byte is read:
    missing or unreadable, not a regular file (a FIFO with no writer would block the open forever,
    ``/dev/zero`` never ends), empty, or larger than ``max_bytes``.

    Raises
    ------
    ValueError
        ``FILE: cannot read the file: ...``, ``FILE: the file is empty`` or ``FILE: the file is
        ... MB, more than the limit of ... MB``.
    """
    name = os.fspath(path)
    try:
        info = os.stat(name)  # follows links, opens nothing
    except OSError as exc:
        raise ValueError(f"{name}: cannot read the file: {exc.strerror or exc}") from None
    if not stat.S_ISREG(info.st_mode):
        raise ValueError(f"{name}: cannot read the file: it is {file_kind(info.st_mode)}, not a regular file")
    if not os.access(name, os.R_OK):
        raise ValueError(f"{name}: cannot read the file: permission denied")
    if info.st_size == 0:
        raise ValueError(f"{name}: the file is empty; expected a CSV of points, a DXF drawing or a mesh")
    if info.st_size > max_bytes:
        raise ValueError(f"{name}: the file is {info.st_size / 1e6:.3g} MB, more than the limit of "
                         f"{max_bytes / 1e6:.3g} MB for an import")
    return name


def suffix_of(name: str) -> str:
    return os.path.splitext(name)[1].lower().lstrip(".") or "(no suffix)"


def check_point_count(name: str, count: int, max_points: int | None, what: str = "the file") -> None:
    """Refuse more than ``max_points`` points (None: no limit), before the geometry is built."""
    if max_points is not None and count > max_points:
        raise ValueError(f"{name}: {what} has {count:,} points, more than the limit of {max_points:,} per "
                         "outline (docs/project-format.md, size limits); simplify the profile")


def _csv_rows(path: str | os.PathLike) -> tuple[str, list[tuple[float, float]], list[str] | None]:
    """The points of a CSV of points and, with a ``layer`` column, each point's layer."""
    name = check_import_file(path)
    try:
        return _csv_rows_of(name)
    except UnicodeDecodeError as exc:
        raise ValueError(f"{name}: not UTF-8 text ({exc.reason} at byte {exc.start}); expected a CSV of "
                         "points with the header 'x_m,y_m'") from None
    except csv.Error as exc:
        raise ValueError(f"{name}: not a CSV of points ({exc})") from None


def _csv_rows_of(name: str) -> tuple[str, list[tuple[float, float]], list[str] | None]:
    points: list[tuple[float, float]] = []
    layers: list[str] | None = None
    header_seen = False
    with open(name, newline="", encoding="utf-8-sig") as handle:
        for line_no, row in enumerate(csv.reader(handle), start=1):
            cells = [c.strip() for c in row]
            if not cells or all(c == "" for c in cells) or cells[0].startswith("#"):
                continue
            if not header_seen:
                header = tuple(c.lower() for c in cells)
                if header[:2] not in _HEADERS or header[2:] not in ((), ("layer",)):
                    raise ValueError(
                        f"{name}: line {line_no}: expected the header 'x_m,y_m' (or 'x,y'), optionally with a "
                        f"third column 'layer', got {','.join(cells)!r}"
                    )
                layers = [] if len(header) == 3 else None
                header_seen = True
                continue
            width = 2 if layers is None else 3
            if len(cells) != width:
                what = "x, y" if layers is None else "x, y, layer"
                raise ValueError(f"{name}: line {line_no}: expected {width} values ({what}), got {len(cells)}")
            try:
                x, y = float(cells[0]), float(cells[1])
            except ValueError:
                raise ValueError(
                    f"{name}: line {line_no}: non-numeric value in {','.join(cells)!r}"
                ) from None
            if not (math.isfinite(x) and math.isfinite(y)):
                raise ValueError(f"{name}: line {line_no}: non-finite value in {','.join(cells)!r}")
            if layers is not None:
                if not cells[2]:
                    raise ValueError(f"{name}: line {line_no}: the layer name is empty")
                layers.append(cells[2])
            points.append((x, y))
    if not header_seen:
        raise ValueError(f"{name}: no header row 'x_m,y_m' (or 'x,y') found")
    return name, points, layers


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
    name, points, layers = _csv_rows(path)
    if layers is not None and len(set(layers)) > 1:
        raise ValueError(f"{name}: {len(set(layers))} layers ({', '.join(dict.fromkeys(layers))}); "
                         "read a section of several layers with read_layers")
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

    name = check_import_file(path)
    try:
        doc = ezdxf.readfile(name)
    except (OSError, ezdxf.DXFError, ValueError) as err:
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


def dxf_layers(path: str | os.PathLike) -> dict[str, np.ndarray]:
    """The points of each layer of a DXF drawing, (K, 2) in drawing units, in the drawing's order
    of layers: per layer its longest polyline (a closed one repeats its first point at the end)
    or, without one, its LINE entities chained end to end. Where any layer has a polyline, the
    layers without one are left out (lines on an annotation layer are no ground).

    Raises
    ------
    ValueError
        The file is not a readable DXF, or holds no polyline and no lines.
    """
    import ezdxf

    name = check_import_file(path)
    try:
        doc = ezdxf.readfile(name)
    except (OSError, ezdxf.DXFError, ValueError) as err:
        raise ValueError(f"{name}: not a readable DXF drawing ({err})") from None
    msp = doc.modelspace()
    polylines: dict[str, list[list[tuple[float, float]]]] = {}
    lines: dict[str, list] = {}
    for entity in msp:
        layer = str(entity.dxf.layer)
        kind = entity.dxftype()
        if kind == "LWPOLYLINE":
            pts = [(float(x), float(y)) for x, y in entity.get_points("xy")]
            if entity.closed and pts:
                pts.append(pts[0])
            polylines.setdefault(layer, []).append(pts)
        elif kind == "POLYLINE":
            pts = [(float(v.dxf.location.x), float(v.dxf.location.y)) for v in entity.vertices]
            if entity.is_closed and pts:
                pts.append(pts[0])
            polylines.setdefault(layer, []).append(pts)
        elif kind == "LINE":
            lines.setdefault(layer, []).append(((float(entity.dxf.start.x), float(entity.dxf.start.y)),
                                                (float(entity.dxf.end.x), float(entity.dxf.end.y))))
    if polylines:
        return {layer: np.array(max(group, key=len), dtype=float) for layer, group in polylines.items()}
    if not lines:
        raise ValueError(f"{name}: no polyline or line in the drawing's model space")
    out = {}
    for layer, segments in lines.items():
        extent = max(max(abs(c) for seg in segments for p in seg for c in p), 1.0)
        out[layer] = np.array(_chain_lines(segments, 1e-9 * extent), dtype=float)
    return out


def _is_closed(pts: np.ndarray) -> bool:
    return bool(np.array_equal(pts[0], pts[-1]) or pts[0, 0] == pts[-1, 0])


def layers_from_points(name: str, groups: dict[str, np.ndarray],
                       base_y_m: float | None = None) -> list[LayerBody]:
    """The bodies of a section given as named point groups (the module docstring, Layers): every
    group a closed outline (a body each), or every group an open profile (the bands between the
    lines, the lowest down to the base). One group is one body, by the CSV rules.

    Returns
    -------
    list of LayerBody
        Named simple polygons (m), counter-clockwise, from the top down for profiles.

    Raises
    ------
    ValueError
        With the file name and what is wrong (one line): closed and open groups mixed, a group
        that is neither, a band that is no simple polygon.
    """
    items = [(str(k), np.asarray(v, dtype=np.float64).reshape(-1, 2)) for k, v in groups.items()]
    if not items:
        raise ValueError(f"{name}: no points")
    if len(items) == 1:
        return [LayerBody(items[0][0], _outline_from_points(name, items[0][1], base_y_m), items[0][0])]
    for layer, pts in items:
        if len(np.unique(pts, axis=0)) < 2:
            raise ValueError(f"{name}: layer {layer!r} needs at least 2 distinct points, got {len(np.unique(pts, axis=0))}")
    closed = [_is_closed(pts) for _, pts in items]
    if all(closed):
        return [LayerBody(layer, _outline_from_points(f"{name}: layer {layer!r}", pts, None), layer)
                for layer, pts in items]
    if any(closed):
        shut = [layer for (layer, _), c in zip(items, closed) if c]
        raise ValueError(f"{name}: layers {', '.join(repr(x) for x in shut)} are closed outlines and the others open "
                         "profiles; give either outlines (a body each) or profiles (the surface and the tops of "
                         "the layers below it)")
    return _bands(name, items, base_y_m)


def _bands(name: str, items: list[tuple[str, np.ndarray]], base_y_m: float | None) -> list[LayerBody]:
    """The bands between open profile lines (the highest the ground surface), the lowest down to the base."""
    from shapely.geometry import Polygon
    from shapely.ops import unary_union

    lines = []
    for layer, pts in items:
        steps = np.diff(pts[:, 0])
        if not (np.all(steps > 0) or np.all(steps < 0)):
            raise ValueError(f"{name}: layer {layer!r}: an open profile needs x strictly increasing or decreasing")
        lines.append((layer, pts[np.argsort(pts[:, 0])]))
    x_all = np.concatenate([p[:, 0] for _, p in lines])
    grid = np.linspace(x_all.min(), x_all.max(), 257)
    lines.sort(key=lambda item: -float(np.interp(grid, item[1][:, 0], item[1][:, 1]).mean()))
    lowest = float(min(p[:, 1].min() for _, p in lines))
    base = lowest if base_y_m is None else float(base_y_m)
    if not math.isfinite(base):
        raise ValueError(f"base_y_m must be finite, got {base_y_m!r}")
    if base > lowest:
        raise ValueError(f"base_y_m = {base:g} m is above the lowest point of the layers (y = {lowest:g} m); "
                         "it must be at or below it")
    surface = lines[0][1]
    x0, x1 = float(surface[0, 0]), float(surface[-1, 0])
    extent = float(max(x1 - x0, np.ptp(np.concatenate([p[:, 1] for _, p in lines])), 1e-300))
    section = Polygon(np.concatenate([surface, [[x1, base], [x0, base]]]))
    if not section.is_valid or section.area <= 0.0:
        raise ValueError(f"{name}: the surface (layer {lines[0][0]!r}) closed down to y = {base:g} m is no simple polygon")
    pad = 1.0 + extent

    def below(pts: np.ndarray):
        # the line carried level beyond its ends to the section's and closed down below the base
        ext = np.concatenate([[[x0 - pad, pts[0, 1]]], pts, [[x1 + pad, pts[-1, 1]]],
                              [[x1 + pad, base - pad], [x0 - pad, base - pad]]])
        return Polygon(ext)

    tops = [section]
    for _layer, pts in lines[1:]:
        tops.append(tops[-1].intersection(below(pts)))  # a layer's top is under every line above it
    bodies: list[LayerBody] = []
    tiny = 1e-9 * section.area
    for k, (layer, _pts) in enumerate(lines):
        band = tops[k] if k + 1 == len(lines) else tops[k].difference(tops[k + 1])
        parts = [g for g in getattr(band, "geoms", [band]) if isinstance(g, Polygon) and g.area > tiny]
        parts.sort(key=lambda g: -g.area)
        for n, part in enumerate(parts):
            part = unary_union([part]).buffer(0)
            if not isinstance(part, Polygon) or part.interiors:
                raise ValueError(f"{name}: layer {layer!r} is no simple polygon between the lines (it encloses another)")
            ring = np.asarray(part.exterior.coords, dtype=np.float64)[:-1]
            ring = remove_spikes(drop_repeated_vertices(ring, 1e-12 * extent), 1e-12 * extent)
            bodies.append(LayerBody(layer if n == 0 else f"{layer}-{n + 1}", counter_clockwise(ring), layer))
    if not bodies:
        raise ValueError(f"{name}: the layers enclose no area")
    return bodies


def read_layers(path: str | os.PathLike, base_y_m: float | None = None,
                max_points: int | None = None) -> list[LayerBody]:
    """The bodies of a section from a file: several layers of a CSV (a ``layer`` column) or a DXF
    drawing (its layers), or the one outline of any file :func:`read_outline` reads, named after
    the file (module docstring, Layers).

    Parameters
    ----------
    path : path-like
    base_y_m : float, optional, m
        The base open profiles are closed down to (default: the lowest point of any line).
    max_points : int, optional
        The most points a line (a layer, the profile) may have; more is refused before any
        geometry is built (the workbench passes the project format's limit per outline).

    Returns
    -------
    list of LayerBody
        Named simple polygons (m), counter-clockwise; one for a file of one outline.

    Raises
    ------
    ValueError
        With the file name and what is wrong (one line).
    """
    name = check_import_file(path)
    stem = os.path.splitext(os.path.basename(name))[0]
    suffix = os.path.splitext(name)[1].lower()
    if suffix == ".csv":
        _name, points, layers = _csv_rows(path)
        pts = np.array(points, dtype=np.float64).reshape(-1, 2)
        if layers is None:
            check_point_count(name, len(pts), max_points)
        else:
            for layer, count in Counter(layers).items():
                check_point_count(name, count, max_points, f"layer {layer!r}")
        if layers is None or len(set(layers)) == 1:
            label = stem if layers is None else layers[0]
            return [LayerBody(label, _outline_from_points(name, pts, base_y_m), label)]
        groups: dict[str, list] = {}
        for point, layer in zip(pts, layers):
            groups.setdefault(layer, []).append(point)
        return layers_from_points(name, {k: np.array(v) for k, v in groups.items()}, base_y_m)
    if suffix == ".dxf":
        found = dxf_layers(path)
        for layer, pts in found.items():
            check_point_count(name, len(pts), max_points, f"layer {layer!r}" if len(found) > 1 else "the drawing")
        if len(found) == 1:
            return [LayerBody(stem, outline_from_dxf(path, base_y_m), stem)]
        return layers_from_points(name, found, base_y_m)
    outline = read_outline(path, base_y_m)
    check_point_count(name, len(outline), max_points, "the outline")
    return [LayerBody(stem, outline, stem)]


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
    name = check_import_file(path)
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

    name = check_import_file(path)
    try:
        mesh = meshio.read(name)
    except (meshio.ReadError, ValueError, KeyError, IndexError, TypeError, EOFError, OSError) as exc:
        # a damaged file fails anywhere in meshio's readers, not only with its ReadError
        raise ValueError(f"{name}: meshio cannot read this file: {exc}") from None
    except SystemExit:
        # meshio ends the process (sys.exit(1)) when no reader of the suffix reads the file: that
        # closed the workbench, unsaved edits and all
        raise ValueError(f"{name}: meshio cannot read this file as {suffix_of(name)}") from None
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
