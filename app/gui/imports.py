"""Body outlines from files for the workbench: a slope profile as CSV or DXF, or a 2D mesh.

CSV and meshes go through :mod:`geometry.importers` (its rules: a header ``x_m,y_m``, an open
profile closed down to a horizontal base, a simple outline). A DXF drawing is read with ezdxf:
the polyline with the most vertices (LWPOLYLINE or POLYLINE, in drawing units taken as metres;
a closed polyline is an outline, an open one a surface profile), or, without polylines, the LINE
entities chained end to end. Its points then follow exactly the CSV rules.

Note for the lead: the DXF reader belongs in ``geometry/importers.py`` (``outline_from_dxf``)
next to the CSV one; it is here because this branch owns only the workbench.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np

#: File filter of the import dialog.
IMPORT_FILTER = ("Slope profile or outline (*.csv *.dxf *.msh *.vtk *.vtu *.xdmf);;CSV points (*.csv);;"
                 "DXF drawing (*.dxf);;Mesh (*.msh *.vtk *.vtu *.xdmf);;All files (*)")
MESH_SUFFIXES = (".msh", ".vtk", ".vtu", ".xdmf", ".xmf", ".med", ".inp")


def _chain_lines(segments: list[tuple[tuple[float, float], tuple[float, float]]], tol: float) -> list[tuple[float, float]]:
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


def dxf_points(path: str | os.PathLike[str]) -> np.ndarray:
    """The points of the profile or outline in a DXF drawing, (K, 2) in drawing units.

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


def read_outline(path: str | os.PathLike[str], base_y_m: float | None = None) -> np.ndarray:
    """A body outline from a CSV, DXF or mesh file.

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
    from geometry.importers import outline_from_csv, outline_from_mesh

    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".csv":
        return outline_from_csv(path, base_y_m)
    if suffix == ".dxf":
        points = dxf_points(path)
        # the same rules as a CSV profile: write the points as one and read them back
        with tempfile.TemporaryDirectory(prefix="runout-dxf-") as tmp:
            csv_path = Path(tmp) / f"{path.stem}.csv"
            csv_path.write_text("x_m,y_m\n" + "".join(f"{float(x)!r},{float(y)!r}\n" for x, y in points), encoding="utf-8")
            try:
                return outline_from_csv(csv_path, base_y_m)
            except ValueError as err:
                raise ValueError(str(err).replace(str(csv_path), str(path))) from None
    if suffix in MESH_SUFFIXES:
        return outline_from_mesh(path)
    raise ValueError(f"{path}: unknown kind of file {suffix or '(no suffix)'!r}; "
                     "import a .csv or .dxf profile or a mesh (.msh, .vtk, .vtu, .xdmf)")
