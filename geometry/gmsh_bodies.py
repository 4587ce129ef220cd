"""Quadrilateral meshes of 2D bodies with gmsh (OpenCASCADE kernel).

This is the only module of Runout that imports gmsh, and it does so inside
:func:`mesh_bodies`, so importing :mod:`geometry` stays cheap.

Each body polygon becomes one plane surface. The surfaces are fragmented together
(``occ.fragment``) so that shared and overlapping parts conform: every fragment is meshed
once and neighbouring bodies share their interface nodes. A fragment covered by several
bodies belongs to the *last* of them in the list (bodies are painted in order, like layers
on a drawing), the same rule as :func:`geometry.polygons.owner_of_points`. Each body is a
physical group named ``body<i>``.
"""

from __future__ import annotations

import logging
import os
import threading
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from geometry.polygons import check_simple

logger = logging.getLogger(__name__)

# gmsh keeps global state: one mesh at a time per process.
_GMSH_LOCK = threading.Lock()

# gmsh element type numbers.
_QUAD4 = 3
_TRIANGLE3 = 2


@dataclass(frozen=True)
class BodyMesh:
    """A conforming quadrilateral mesh of several bodies.

    Attributes
    ----------
    nodes_m : numpy.ndarray, shape (M, 2), float64, m
        Node coordinates.
    quads : numpy.ndarray, shape (Q, 4), int64
        Node indices of each quadrilateral, counter-clockwise.
    quad_body : numpy.ndarray, shape (Q,), int64
        Index of the body (in the list given to :func:`mesh_bodies`) owning each quad.
    """

    nodes_m: np.ndarray
    quads: np.ndarray
    quad_body: np.ndarray

    def quad_areas_m2(self) -> np.ndarray:
        """Area of each quadrilateral (shoelace).

        Returns
        -------
        numpy.ndarray, shape (Q,), float64, m2
        """
        x = self.nodes_m[self.quads, 0]
        y = self.nodes_m[self.quads, 1]
        return 0.5 * np.sum(x * np.roll(y, -1, axis=1) - np.roll(x, -1, axis=1) * y, axis=1)


def mesh_bodies(
    polygons: Sequence[np.ndarray],
    element_size_m: float,
    msh_path: str | os.PathLike | None = None,
) -> BodyMesh:
    """Mesh body polygons into conforming quadrilaterals with gmsh.

    Parameters
    ----------
    polygons : sequence of array_like, each shape (K_i, 2), m
        Simple body outlines in painting order (later bodies own overlaps).
    element_size_m : float, m
        Target edge length of the quadrilaterals.
    msh_path : str or path-like, optional
        Also write the mesh, with its physical groups ``body<i>``, to this gmsh ``.msh``
        file (for inspection in gmsh or ParaView).

    Returns
    -------
    BodyMesh
        Quads counter-clockwise; a body entirely covered by later bodies gets no quads.

    Raises
    ------
    ValueError
        If there are no polygons, a polygon is not simple, or the size is not positive.
    RuntimeError
        If gmsh fails or cannot produce an all-quadrilateral mesh.
    """
    polys = [check_simple(p, f"polygons[{i}]") for i, p in enumerate(polygons)]
    if not polys:
        raise ValueError("polygons must hold at least one body outline")
    try:
        size = float(element_size_m)
    except (TypeError, ValueError):
        size = float("nan")
    if not np.isfinite(size) or size <= 0.0:
        raise ValueError(f"element_size_m must be a positive number of metres, got {element_size_m!r}")

    import gmsh  # lazy: gmsh is heavy and only needed here

    with _GMSH_LOCK:
        own_session = not gmsh.isInitialized()
        if own_session:
            # gmsh's SIGINT handler can only be installed from the main thread.
            on_main = threading.current_thread() is threading.main_thread()
            gmsh.initialize(readConfigFiles=False, interruptible=on_main)
        try:
            gmsh.option.setNumber("General.Terminal", 0)
            # Full-quad recombination at the target size gives the best quads but can fail
            # (it needs an even number of nodes on each boundary loop); then mesh at twice
            # the size and split every element into quads, which always yields quads.
            for subdivide in (False, True):
                try:
                    mesh = _attempt(gmsh, polys, size, subdivide, msh_path)
                except Exception as exc:  # gmsh raises plain Exception
                    if subdivide:
                        raise RuntimeError(f"gmsh failed to mesh the bodies: {exc}") from exc
                    logger.debug("gmsh full-quad meshing failed (%s); subdividing instead", exc)
                    continue
                if mesh is not None:
                    return mesh
                logger.debug("gmsh left triangles; subdividing instead")
            raise RuntimeError("gmsh could not produce an all-quadrilateral mesh")
        finally:
            if own_session:
                gmsh.finalize()


def _attempt(
    gmsh, polys: list[np.ndarray], size: float, subdivide: bool, msh_path: str | os.PathLike | None
) -> BodyMesh | None:
    """Build a fresh model and mesh it; None when triangles are left."""
    gmsh.model.add("runout_bodies")
    try:
        _add_bodies(gmsh, polys, size)
        mesh = _mesh(gmsh, size, subdivide)
        if mesh is not None and msh_path is not None:
            gmsh.write(os.fspath(msh_path))
        return mesh
    finally:
        gmsh.model.remove()


def _add_bodies(gmsh, polys: list[np.ndarray], size: float) -> None:
    """One plane surface per body, fragmented, with a physical group ``body<i>`` per body."""
    occ = gmsh.model.occ
    surfaces = []
    for poly in polys:
        points = [occ.addPoint(float(x), float(y), 0.0, size) for x, y in poly]
        lines = [occ.addLine(points[i], points[(i + 1) % len(points)]) for i in range(len(points))]
        loop = occ.addCurveLoop(lines)
        surfaces.append((2, occ.addPlaneSurface([loop])))
    if len(surfaces) > 1:
        _, fragment_map = occ.fragment(surfaces[:1], surfaces[1:])
    else:
        fragment_map = [surfaces]
    occ.synchronize()
    owner: dict[int, int] = {}
    for body, pieces in enumerate(fragment_map):
        for dim, tag in pieces:
            if dim == 2:
                owner[tag] = body  # later bodies overwrite: they own overlaps
    by_body: dict[int, list[int]] = {}
    for tag, body in sorted(owner.items()):
        by_body.setdefault(body, []).append(tag)
    for body in range(len(polys)):
        tags = by_body.get(body, [])
        if not tags:
            logger.warning("body %d is entirely covered by later bodies and gets no mesh", body)
            continue
        group = gmsh.model.addPhysicalGroup(2, tags)
        gmsh.model.setPhysicalName(2, group, f"body{body}")


def _mesh(gmsh, size: float, subdivide: bool) -> BodyMesh | None:
    """Mesh the current model into quads; None when triangles are left."""
    opt = gmsh.option.setNumber
    target = 2.0 * size if subdivide else size
    opt("Mesh.MeshSizeMin", target)
    opt("Mesh.MeshSizeMax", target)
    opt("Mesh.MeshSizeFactor", 1.0)
    opt("Mesh.MeshSizeFromPoints", 0)
    opt("Mesh.MeshSizeFromCurvature", 0)
    opt("Mesh.MeshSizeExtendFromBoundary", 0)
    opt("Mesh.Algorithm", 8)  # frontal-Delaunay for quads
    opt("Mesh.RecombineAll", 1)
    # Simple full-quad recombination first; blossom when subdividing (the full-quad variants
    # need an even number of boundary nodes, which subdivision breaks).
    opt("Mesh.RecombinationAlgorithm", 1 if subdivide else 2)
    opt("Mesh.SubdivisionAlgorithm", 1 if subdivide else 0)
    gmsh.model.mesh.generate(2)

    node_tags, coords, _ = gmsh.model.mesh.getNodes()
    coords = np.asarray(coords, dtype=np.float64).reshape(-1, 3)[:, :2]
    node_tags = np.asarray(node_tags, dtype=np.int64)
    lookup = np.full(int(node_tags.max()) + 1, -1, dtype=np.int64)
    lookup[node_tags] = np.arange(len(node_tags))

    quads: list[np.ndarray] = []
    quad_body: list[np.ndarray] = []
    for _, group in gmsh.model.getPhysicalGroups(2):
        name = gmsh.model.getPhysicalName(2, group)
        body = int(name.removeprefix("body"))
        for tag in gmsh.model.getEntitiesForPhysicalGroup(2, group):
            types, _, elem_nodes = gmsh.model.mesh.getElements(2, int(tag))
            for etype, enodes in zip(types, elem_nodes):
                if etype == _QUAD4:
                    q = lookup[np.asarray(enodes, dtype=np.int64).reshape(-1, 4)]
                    quads.append(q)
                    quad_body.append(np.full(len(q), body, dtype=np.int64))
                elif etype == _TRIANGLE3 and len(enodes):
                    return None
                else:
                    raise RuntimeError(f"gmsh produced unexpected element type {etype}")

    quads_arr = np.concatenate(quads) if quads else np.zeros((0, 4), dtype=np.int64)
    body_arr = np.concatenate(quad_body) if quad_body else np.zeros(0, dtype=np.int64)
    # Keep only the nodes the quads use, renumbered in order.
    used = np.unique(quads_arr)
    renumber = np.full(len(coords), -1, dtype=np.int64)
    renumber[used] = np.arange(len(used))
    mesh = BodyMesh(nodes_m=coords[used], quads=renumber[quads_arr], quad_body=body_arr)
    flip = mesh.quad_areas_m2() < 0.0
    if np.any(flip):
        mesh.quads[flip] = mesh.quads[flip][:, ::-1]
    return mesh
