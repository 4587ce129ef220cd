"""Runout geometry: 2D body polygons, gmsh quad meshes, particle seeding, slope templates
and outline importers.

Depends on numpy only at import time; gmsh (:mod:`geometry.gmsh_bodies`), meshio
(:func:`geometry.importers.outline_from_mesh`) and ezdxf (:func:`geometry.importers.outline_from_dxf`)
are imported when first used. Never imports
``solver``, ``projects``, ``app``, Qt or pyvista.

Overlap rule: bodies are painted in list order, so where bodies overlap the later body in
the list owns the overlap.
"""

from geometry.importers import outline_from_csv, outline_from_dxf, outline_from_mesh, read_outline
from geometry.polygons import is_simple, owner_of_points, points_in_polygon, polygon_area, self_intersections
from geometry.seeding import Seeds, seed_gauss, seed_lattice
from geometry.templates import DomainFit, SlopeLayer, fit_domain, slope_domain, slope_profile

__all__ = [
    "DomainFit",
    "Seeds",
    "SlopeLayer",
    "fit_domain",
    "is_simple",
    "outline_from_csv",
    "outline_from_dxf",
    "outline_from_mesh",
    "owner_of_points",
    "points_in_polygon",
    "polygon_area",
    "read_outline",
    "seed_gauss",
    "seed_lattice",
    "self_intersections",
    "slope_domain",
    "slope_profile",
]
