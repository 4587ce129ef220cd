"""Warnings about projects that are valid but probably not what the engineer meant.

:func:`project_warnings` lists them (``runout validate`` and ``runout run`` print them, the
workbench shows them):

- a body less than a cell from a closed wall (fixed, slip or friction) or a structure without
  touching it: it falls or slides onto the wall at the start and the settlement
  reads as deformation;
- a body floating above the closed side gravity pulls it onto, at any height, resting on no
  structure and no other body that rests on something, where the first stage is an
  initial-stress stage (k0 or gravity: the bodies are taken as standing on their supports; a
  dynamic first stage may drop a body on purpose);
- a body drawn into a structure over a cell's area or more and half a cell deep: that part of it is not seeded and the
  body starts without it (drawing a slide across a wall by mistake removed 42 % of it unseen);
- a k0 stage where the ground slopes: geostatic stresses are no equilibrium under a slope
  (many particles yield at once); a gravity stage is the initial stress for sloping ground;
- a structure thinner than 1 cell at its thickest: the at-rest thrust on a wall half a cell thick
  was up to 3.7 times the analytic one with faces 0.6-0.9 cells off a node line, and material
  thrown at an inclined one half a cell thick was ejected faster than the stability guard allows
  (apic-affine); from 1 cell on it is within 4.3 % at every offset (a node whose stencil reaches
  past a thin part's far face holds the material beyond it, ``solver.structures.far_normals``);
- a vertical or horizontal structure face a body touches, 0.55 to 0.85 cells from the last node
  line on the material's side (every scheme): the lattice-seeded material stops up to a quarter
  cell short of such a face and the at-rest thrust on it is 2.6-4.3 % low (docs/validation.md,
  thrust); elsewhere within 2.6 %;
- a body resting on an inclined frictional contact (a friction side or a friction structure face
  it touches, inclined to gravity's level, its friction angle at least the incline) while the
  first dynamic or strength-reduction stage has no initial-stress stage before it: it starts
  stress free, is loaded at once, and the waves of that loading make it creep down the contact
  where friction should hold it (docs/validation.md, contact through the project path);
- a gravity stage shorter than the fundamental period ``4 H / c_s`` of the bodies: they cannot
  settle in it, and start the next stage moving (a 20-cell block of 1e6 Pa held by friction 5
  degrees from its limit, after a 0.2 s stage where its period is 0.95 s, crept 3.4 % of the
  frictionless distance; a finite-element model of it 9.6 %);
- a linear-elastic body that slides on an inclined frictional contact just above the friction
  limit at high friction (friction angle at least NEAR_LIMIT_FRICTION_DEG, the friction at least
  NEAR_LIMIT_RATIO times the net driving force): there the undamped elastic body flutters under
  Coulomb friction and slides further than a rigid block would (5 degrees above the limit, blocks
  5 and 20 cells thick: up to +30 % at 40 on 35 degrees, up to +9 % at 35 on 30; one-cell sheets
  within 0.3 %; docs/validation.md, near-limit slides), unless its material is damped by at
  least NEAR_LIMIT_DAMPING of critical at the body's first shear mode on the contact and at twice
  its frequency (NEAR_LIMIT_BAND), which removes the flutter (docs/solver.md, material damping);
  the warning gives the keys to set (a Maxwell arm of NEAR_LIMIT_SUGGESTED at the first mode);
- a Rayleigh damping that overdamps a body's first shear mode (more than OVERDAMPED_RATIO times
  critical there: a damping frequency given far below the body's), which turns its vibration into
  creep and costs time steps in proportion (a Maxwell arm damps no mode by more than its ratio);
- a softening material without ``softening_length_m``: its shear bands are about a cell wide and
  soften with the particles' own strain, so the failure and the run-out depend on the cell size
  (docs/validation.md, strain softening); and one whose length is shorter than the cell size:
  the particles of a band one cell wide then reach the residual strength at a plastic strain
  ``h / l`` times below the law's.

:func:`recommended_initial_stage` is the default initial-stress stage for a new project (the
slope template): gravity loading where the ground slopes, k0 where it is level.

:mod:`projects.plausibility` adds the warnings about inputs that run but cannot give an answer to
trust (a time step past the stability limit, a body too fast for the domain, a hazard raster finer
than the particles); they come first.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from projects.schema import DEFAULT_GRAVITY_DAMPING, Project

#: Faces steeper than this (degrees from the level normal to gravity) make the ground "sloping".
SLOPE_TOLERANCE_DEG = 2.0
#: Faces steeper than this count as walls, not slopes (a column's sides).
WALL_ANGLE_DEG = 88.0
#: Gaps below this fraction of a cell count as touching.
TOUCH_TOLERANCE = 1e-6
#: A body this close to a structure (in cells) touches it (its faces are seldom on round numbers)
STRUCTURE_TOUCH_CELLS = 0.02
#: A gravity stage lasts this many fundamental periods ``4 H / c_s`` of the deposit.
GRAVITY_STAGE_PERIODS = 3.0
#: Structures thinner than this many cells at their thickest are warned about.
STRUCTURE_MIN_CELLS = 1.0
#: Axis-aligned structure faces this far (cells) from the last node line on the material's side
#: (outside the structure) are warned about, in every scheme: walls 1 to 3 cells thick take
#: 0.957-0.974 of the at-rest thrust there (elsewhere 0.974-1.000; docs/validation.md, thrust).
FACE_OFFSET_BAND = (0.55, 0.85)
#: Slides on a frictional contact with at least this friction angle (degrees) and a friction at
#: least NEAR_LIMIT_RATIO times the net driving force, ``tan d / (tan th - tan d)``, are warned
#: about (measured through the project path, docs/validation.md: 40/35 deg (ratio 5.0) +5.7 to
#: +30 %, 35/30 (4.7) up to +9 %, 40/32 (2.9) +5.6 %, 40/30 (2.2) +2.3 %, 30/25 (4.2) +0.8 %,
#: 20/15 (2.8) +0.08 %, 24/21 on a ramp (6.3) +16.5 %, 40/30 on a ramp (2.2) +10.2 % for a soft
#: 20-cell block after the recommended gravity stage). Bodies thinner than NEAR_LIMIT_MIN_CELLS cells
#: along the contact's normal are not: one-cell sheets slide within 0.3 %.
NEAR_LIMIT_FRICTION_DEG = 20.0
NEAR_LIMIT_RATIO = 2.0
NEAR_LIMIT_MIN_CELLS = 1.5
#: Damping (fraction of critical) at the body's first shear mode on the contact, ``c_s / (4 H)``, and
#: at NEAR_LIMIT_BAND[1] times it that takes the flutter away in every scheme (measured 5 degrees
#: above the limit, blocks 5 and 20 cells thick, docs/validation.md, near-limit slides with material
#: damping): Rayleigh damping of 0.1 at the first mode (0.2 at twice it) brings every case within
#: 0.11 % on the walls and 2.5 % on a ramp, 0.05 leaves classic mpm's 20-cell block at 40/35
#: +5.5 %; a Maxwell arm of 0.1 at the first mode (0.074 at twice it) is within 0.84 % on the walls
#: but +13 % on a ramp, one of 0.15 (0.107 at twice it) +0.97 %, one of 0.2 (0.137) within 0.17 %.
NEAR_LIMIT_DAMPING = 0.1
NEAR_LIMIT_BAND = (1.0, 2.0)
#: ... and the damping the warning gives, at the first mode, by this model: the Maxwell arm of 0.2
#: costs 1.4 times the undamped steps (Rayleigh damping of 0.1 up to 10 times for 20-cell blocks).
NEAR_LIMIT_SUGGESTED = 0.2
NEAR_LIMIT_DAMPING_MODEL = "maxwell"

_CLOSED = ("fixed", "slip", "friction")


@dataclass(frozen=True)
class Face:
    """An upward-facing inclined face of a body."""

    body: int
    angle_deg: float
    length_m: float


def _up(project: Project) -> np.ndarray:
    g = np.asarray(project.domain.gravity_m_s2, dtype=np.float64)
    norm = float(np.linalg.norm(g))
    return -g / norm if norm > 0 else np.array([0.0, 1.0])


def sloping_faces(project: Project) -> list[Face]:
    """Upward-facing faces of the bodies' outlines inclined to the level (normal to gravity).

    A face counts when it is steeper than :data:`SLOPE_TOLERANCE_DEG` and less steep than
    :data:`WALL_ANGLE_DEG`, faces up (against gravity), is longer than a cell and is not
    covered by another body (its midpoint lies in no other body).

    Returns
    -------
    list of Face
    """
    from geometry.polygons import counter_clockwise, points_in_polygon

    up = _up(project)
    dx = project.domain.cell_size_m
    polygons = [counter_clockwise(np.asarray(b.polygon_m, dtype=np.float64)) for b in project.bodies]
    lo_sin = math.sin(math.radians(SLOPE_TOLERANCE_DEG))
    hi_sin = math.sin(math.radians(WALL_ANGLE_DEG))
    faces = []
    for index, poly in enumerate(polygons):
        edges = np.roll(poly, -1, axis=0) - poly
        lengths = np.linalg.norm(edges, axis=1)
        keep = lengths > dx
        if not keep.any():
            continue
        t = edges[keep] / lengths[keep, None]
        normal = np.column_stack([t[:, 1], -t[:, 0]])  # outward for a counter-clockwise outline
        rise = np.abs(t @ up)
        facing = normal @ up > 0
        inclined = facing & (rise > lo_sin) & (rise < hi_sin)
        mids = (poly[keep] + 0.5 * edges[keep])[inclined]
        # a hair outside the face: is it covered by another body?
        probe = mids + 1e-6 * dx * normal[inclined]
        covered = np.zeros(len(mids), bool)
        for other, poly2 in enumerate(polygons):
            if other != index and len(mids):
                covered |= points_in_polygon(probe, poly2)
        for rise_k, length_k, hidden in zip(rise[inclined], lengths[keep][inclined], covered):
            if not hidden:
                faces.append(Face(index, math.degrees(math.asin(min(1.0, rise_k))), float(length_k)))
    return faces


def ground_slope_deg(project: Project) -> float:
    """The steepest exposed upward-facing face of the bodies, degrees (0 for level ground)."""
    faces = sloping_faces(project)
    return max((f.angle_deg for f in faces), default=0.0)


def _grid_box(domain) -> tuple[float, float, float, float] | None:
    """The grid's sides ``(x0, y0, x1, y1)``: the grid has whole cells, so its right and top walls
    lie where the last cell ends; None for a grid beyond any size (the size limits report it)."""
    dx = domain.cell_size_m
    x0, y0 = domain.origin_m
    ratios = [size / dx for size in domain.size_m]
    if not all(math.isfinite(r) for r in ratios):
        return None
    cells = [max(1, math.ceil(r - 1e-9)) for r in ratios]
    return x0, y0, x0 + cells[0] * dx, y0 + cells[1] * dx


#: The inward normal of each side (out of the wall into the domain).
_INWARD = {"left": (1.0, 0.0), "right": (-1.0, 0.0), "bottom": (0.0, 1.0), "top": (0.0, -1.0)}


def _down_side(project: Project) -> str | None:
    """The side gravity pulls the bodies onto (the bottom for gravity along -y); None without gravity."""
    g = np.asarray(project.domain.gravity_m_s2, dtype=np.float64)
    if not np.any(g):
        return None
    return max(_INWARD, key=lambda side: -float(np.dot(g, _INWARD[side])))


def _starts_at_rest(project: Project) -> bool:
    """Whether the first stage is an initial-stress stage (k0 or gravity): the bodies are taken as
    standing on their supports, not released to fall."""
    return bool(project.stages) and project.stages[0].type in ("k0", "gravity")


def unsupported_bodies(project: Project) -> list[int]:
    """The bodies that rest on nothing: not on the closed side gravity pulls them onto, on no
    structure and on no body that rests on something (touching within
    :data:`STRUCTURE_TOUCH_CELLS` of a cell; the base within :data:`TOUCH_TOLERANCE`)."""
    return [i for group in _floating_groups(project) for i in group]


def _floating_groups(project: Project) -> list[list[int]]:
    """The bodies that rest on nothing (:func:`unsupported_bodies`), in groups of bodies touching
    each other (a heap on a floating block falls with it)."""
    from shapely.geometry import LineString, Polygon

    domain = project.domain
    side = _down_side(project)
    box = _grid_box(domain)
    if side is None or box is None or not project.bodies:
        return []
    dx = domain.cell_size_m
    x0, y0, x1, y1 = box
    shapes = [Polygon(b.polygon_m) for b in project.bodies]
    supports = [Polygon(st.polygon_m) for st in project.structures]
    if getattr(domain.boundaries, side).type in _CLOSED:
        line = {"left": [(x0, y0), (x0, y1)], "right": [(x1, y0), (x1, y1)],
                "bottom": [(x0, y0), (x1, y0)], "top": [(x0, y1), (x1, y1)]}[side]
        base = LineString(line)
    else:
        base = None
    near = STRUCTURE_TOUCH_CELLS * dx
    held = {i for i, shape in enumerate(shapes)
            if (base is not None and shape.distance(base) <= TOUCH_TOLERANCE * dx)
            or any(shape.distance(st) <= near for st in supports)}
    grown = True
    while grown:
        grown = False
        for i, shape in enumerate(shapes):
            if i not in held and any(shape.distance(shapes[j]) <= near for j in held):
                held.add(i)
                grown = True
    free = [i for i in range(len(shapes)) if i not in held]
    groups: list[list[int]] = []
    for i in free:
        touching = [g for g in groups if any(shapes[i].distance(shapes[j]) <= near for j in g)]
        merged = sorted({i, *(j for g in touching for j in g)})
        groups = [g for g in groups if g not in touching] + [merged]
    return sorted(groups)


def _wall_gaps(project: Project) -> list[str]:
    """A body standing off a closed side by less than a cell; and, where the first stage is an
    initial-stress stage, a body floating at any height above the closed side gravity pulls it
    onto, resting on nothing."""
    domain = project.domain
    dx = domain.cell_size_m
    box = _grid_box(domain)
    if box is None:
        return []
    x0, y0, x1, y1 = box
    down = _down_side(project)

    def side_gaps(body) -> dict[str, tuple[float, str, float]]:
        pts = np.asarray(body.polygon_m, dtype=np.float64)
        return {
            "left": (pts[:, 0].min() - x0, "x", x0),
            "right": (x1 - pts[:, 0].max(), "x", x1),
            "bottom": (pts[:, 1].min() - y0, "y", y0),
            "top": (y1 - pts[:, 1].max(), "y", y1),
        }

    # of a floating group, the body nearest the wall is the one to warn about (the others rest on it)
    floating, carried = set(), set()
    if _starts_at_rest(project) and down is not None:
        for group in _floating_groups(project):
            lowest = min(group, key=lambda i: side_gaps(project.bodies[i])[down][0])
            floating.add(lowest)
            carried.update(i for i in group if i != lowest)
    warnings = []
    for index, body in enumerate(project.bodies):
        gaps = side_gaps(body)
        for side, (gap, axis, wall) in gaps.items():
            kind = getattr(domain.boundaries, side).type
            if kind not in _CLOSED or gap <= TOUCH_TOLERANCE * dx:
                continue
            if side == down and index in carried:
                continue  # it falls with the body it rests on (warned about)
            if side == down and index in floating:
                stage = project.stages[0]
                moved = {"left": f"[{x0 + gap:g}, {y0:g}]", "right": f"[{x0:g}, {y0:g}] with size_m[0] {gap:g} m less",
                         "bottom": f"[{x0:g}, {y0 + gap:g}]", "top": f"[{x0:g}, {y0:g}] with size_m[1] {gap:g} m less"}
                warnings.append(
                    f"bodies.{index} ({body.name!r}) is {gap:.3g} m from the {side} wall ({kind}) without touching it "
                    f"and rests on no structure or other body: stages.0 ({stage.label}, {stage.type}) takes it as "
                    "standing on its support, so it falls onto the wall at the start and the fall reads as "
                    f"settlement and stress; move it onto the wall ({axis} = {wall:g} m) or the wall to it "
                    f"(domain.origin_m = {moved[side]}; the slope template's Fit the domain does it)"
                )
                continue
            if gap >= dx:
                continue
            warnings.append(
                f"bodies.{index} ({body.name!r}) is {gap:.3g} m from the {side} wall ({kind}) without touching "
                f"it, less than a cell ({dx:g} m): it will move onto the wall at the start and the settlement "
                f"looks like deformation; move it to touch the wall ({axis} = {wall:g} m) or leave a gap of "
                "several cells"
            )
    return warnings


def _structure_gaps(project: Project) -> list[str]:
    """A body less than a cell from a structure without touching or overlapping it (as a wall)."""
    from solver.structures import signed_distance

    dx = project.domain.cell_size_m
    warnings = []
    for index, body in enumerate(project.bodies):
        b = np.asarray(body.polygon_m, dtype=np.float64)
        for k, structure in enumerate(project.structures):
            st = np.asarray(structure.polygon_m, dtype=np.float64)
            # apart, the nearest points of two polygons include a vertex of one of them
            d_body, d_struct = signed_distance(b, st), signed_distance(st, b)
            if (d_body < 0).any() or (d_struct < 0).any():
                continue  # overlapping: the structure takes its part of the body
            gap = float(min(d_body.min(), d_struct.min()))
            # touching within 2 % of a cell: a body laid on an inclined structure with rounded
            # coordinates (a few 1e-7 m off) settles by nothing that shows
            if STRUCTURE_TOUCH_CELLS * dx < gap < dx:
                warnings.append(
                    f"bodies.{index} ({body.name!r}) is {gap:.3g} m from structures.{k} ({structure.name!r}) "
                    f"without touching it, less than a cell ({dx:g} m): it will move onto the structure at the "
                    "start and the settlement looks like deformation; move it to touch the structure or leave a "
                    "gap of several cells"
                )
    return warnings


def _bodies_in_structures(project: Project) -> list[str]:
    """A body drawn into a structure over at least a cell's area: that part is not seeded (a body
    covered entirely is an error of the build, projects.build)."""
    if not project.structures:
        return []
    from shapely.geometry import Polygon

    dx = project.domain.cell_size_m
    warnings = []
    for index, body in enumerate(project.bodies):
        shape = Polygon(body.polygon_m)
        for k, structure in enumerate(project.structures):
            overlap = shape.intersection(Polygon(structure.polygon_m))
            inside = overlap.area
            # a sliver under half a cell thick (2 A / P, its depth into the structure) or under a
            # cell's area: a body drawn down to a face with rounded coordinates, or loosely
            thick = 2.0 * inside / overlap.length if overlap.length > 0 else 0.0
            if inside >= dx * dx and thick >= 0.5 * dx and inside < shape.area * (1.0 - 1e-9):
                warnings.append(
                    f"bodies.{index} ({body.name!r}) extends {inside:.3g} m2 ({100 * inside / shape.area:.3g} % of "
                    f"its area) into structures.{k} ({structure.name!r}): that part is not seeded and the body "
                    "starts without it; redraw the body along the structure's face if that is not meant"
                )
    return warnings


def _k0_on_slope(project: Project) -> list[str]:
    k0 = [i for i, stage in enumerate(project.stages) if stage.type == "k0"]
    if not k0:
        return []
    faces = sloping_faces(project)
    if not faces:
        return []
    steepest = max(faces, key=lambda f: f.angle_deg)
    body = project.bodies[steepest.body]
    return [
        f"stages.{k0[0]}.type = \"k0\": the ground slopes ({steepest.angle_deg:.3g} degrees in bodies.{steepest.body}, "
        f"{body.name!r}) and geostatic (K0) stresses are not in equilibrium under a slope (many particles yield "
        "at once); use a gravity stage for sloping ground"
    ]


def structure_thickness_m(polygon_m) -> float:
    """Twice the largest distance from a point inside the polygon to its outline (m): the
    thickness of the structure at its thickest (the diameter of its largest inscribed circle).

    GEOS's maximum inscribed circle (``shapely.maximum_inscribed_circle``; the pole of
    inaccessibility of ``shapely.ops.polylabel`` where shapely is older than 2.1), to 1e-9 of the
    polygon's extent: to round-off for straight walls and slabs (a structure exactly 2 cells thick
    is 2 cells thick). Its cost grows with the vertex count about as ``n log n`` (a 100,000-vertex
    outline in 0.04 s) and its memory with ``n``.
    """
    import shapely
    from shapely.geometry import Polygon

    pts = np.asarray(polygon_m, dtype=np.float64)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    extent = float((hi - lo).max())
    if not extent > 0:
        return 0.0
    shape = Polygon(pts - lo)  # relative to the box: far from the origin keeps its resolution
    if not shape.is_valid:
        shape = shape.buffer(0)
    if shape.is_empty or not shape.area > 0:
        return 0.0
    tolerance = 1e-9 * extent
    if hasattr(shapely, "maximum_inscribed_circle"):
        radius = float(shapely.maximum_inscribed_circle(shape, tolerance=tolerance).length)
    else:  # pragma: no cover - shapely 2.0
        from shapely.ops import polylabel

        pole = polylabel(shape, tolerance=tolerance)
        radius = float(shape.exterior.distance(pole))
    return 2.0 * radius


def _thin_structures(project: Project) -> list[str]:
    dx = project.domain.cell_size_m
    cells = f"{STRUCTURE_MIN_CELLS:g} cell{'' if STRUCTURE_MIN_CELLS == 1 else 's'}"
    warnings = []
    for index, structure in enumerate(project.structures):
        thick = structure_thickness_m(structure.polygon_m)
        # exactly the minimum is enough, as drawn: an inclined wall's coordinates rounded to a micrometre
        # make a wall one 2 cm cell thick 0.0199997 m
        if thick < STRUCTURE_MIN_CELLS * dx * (1.0 - 1e-3):
            warnings.append(
                f"structures.{index} ({structure.name!r}) is {thick:.3g} m thick at its thickest, less than "
                f"{cells} ({STRUCTURE_MIN_CELLS * dx:g} m): the force on it is unreliable "
                "(the at-rest thrust on a wall half a cell thick was up to 3.7 times the analytic one) and material thrown "
                f"at it can be ejected; make it at least {cells} thick or use smaller cells"
            )
    return warnings


def _off_node_faces(project: Project) -> list[str]:
    from geometry.polygons import counter_clockwise

    if not project.structures:
        return []
    dx = project.domain.cell_size_m
    origin = project.domain.origin_m
    lo, hi = FACE_OFFSET_BAND
    # the bodies' outlines, sampled a quarter cell apart (at most 4096 points an edge, also where a
    # subnormal cell size makes the count infinite): a face is judged only where a body touches it
    outline = []
    for body in project.bodies:
        b = np.asarray(body.polygon_m, dtype=np.float64)
        for p, q in zip(b, np.roll(b, -1, axis=0)):
            samples = 4.0 * float(np.hypot(*(q - p))) / dx
            count = min(4096, max(1, int(math.ceil(samples)))) if math.isfinite(samples) else 4096
            outline.append(p + np.linspace(0.0, 1.0, count + 1)[:, None] * (q - p))
    outline = np.concatenate(outline) if outline else np.zeros((0, 2))
    warnings = []
    for index, structure in enumerate(project.structures):
        pts = counter_clockwise(np.asarray(structure.polygon_m, dtype=np.float64))
        for a, b in zip(pts, np.roll(pts, -1, axis=0)):
            for axis, name in ((0, "x"), (1, "y")):  # a face along y sits at one x, and the reverse
                if abs(a[axis] - b[axis]) > 1e-9 * dx or abs(a[1 - axis] - b[1 - axis]) < dx:
                    continue
                # the outward normal of a counter-clockwise outline: (dy, -dx) along the edge
                outward = (b[1] - a[1]) if axis == 0 else (a[0] - b[0])
                ahead = (outline[:, axis] - a[axis]) * math.copysign(1.0, outward)
                span = sorted((a[1 - axis], b[1 - axis]))
                if not np.any((ahead > -STRUCTURE_TOUCH_CELLS * dx) & (ahead < dx)
                              & (outline[:, 1 - axis] > span[0]) & (outline[:, 1 - axis] < span[1])):
                    continue  # no body next to this face
                cells = (a[axis] - origin[axis]) / dx
                below = cells - math.floor(cells)
                offset = 1.0 - below if outward > 0 else below  # from the node line on the material's side
                if lo < offset < hi:
                    line = origin[axis] + math.floor(cells) * dx
                    warnings.append(
                        f"structures.{index} ({structure.name!r}) has a face at {name} = {a[axis]:g} m, "
                        f"{offset:.2f} cells from the last node line on the material's side: the lattice of "
                        f"particles stops short of it and the force on it can be 3-4.5 % below the at-rest value; "
                        f"put it on a node line ({name} = {line:g} m or {line + dx:g} m) or within 0.55 cells "
                        "of the node line on the material's side"
                    )
                    break
            else:
                continue
            break
    return warnings


def _contact_faces(project: Project):
    """Every frictional contact face a body touches: ``(body index, where, friction angle (deg),
    outward unit normal of the contact (into the material))``. ``where`` names the side
    (``"the bottom wall"``) or the structure (``"structures.0 ('ramp')"``)."""
    from geometry.polygons import counter_clockwise

    domain = project.domain
    dx = domain.cell_size_m
    box = _grid_box(domain)
    if box is None:
        return []
    x0, y0, x1, y1 = box
    sides = {"left": (np.array([1.0, 0.0]), 0, x0, 1.0), "right": (np.array([-1.0, 0.0]), 0, x1, -1.0),
             "bottom": (np.array([0.0, 1.0]), 1, y0, 1.0), "top": (np.array([0.0, -1.0]), 1, y1, -1.0)}
    found = []
    for index, body in enumerate(project.bodies):
        pts = np.asarray(body.polygon_m, dtype=np.float64)
        for side, (normal, axis, wall, sign) in sides.items():
            boundary = getattr(domain.boundaries, side)
            if boundary.type == "friction" and (sign * (pts[:, axis] - wall)).min() <= TOUCH_TOLERANCE * dx:
                found.append((index, f"the {side} wall", boundary.friction_angle_deg, normal))
        if not project.structures:
            continue
        # points along the body's outline, a quarter cell apart (at most 4096 an edge), each
        # standing for its share of the outline's length, against each structure face
        samples, spans = [], []
        for a, b in zip(pts, np.roll(pts, -1, axis=0)):
            length = float(np.linalg.norm(b - a))
            if not math.isfinite(length):
                continue
            k = min(4096, max(1, math.ceil(length / (0.25 * dx))))
            samples.append(a + ((np.arange(k) + 0.5) / k)[:, None] * (b - a))
            spans.append(np.full(k, length / k))
        if not samples:
            continue
        samples, spans = np.vstack(samples), np.concatenate(spans)
        for k, structure in enumerate(project.structures):
            if structure.contact.type != "friction":
                continue
            poly = counter_clockwise(np.asarray(structure.polygon_m, dtype=np.float64))
            for a, b in zip(poly, np.roll(poly, -1, axis=0)):
                ab = b - a
                length = float(np.linalg.norm(ab))
                if not length > 0:
                    continue
                t = np.clip((samples - a) @ ab / length**2, 0.0, 1.0)
                gap = np.linalg.norm(samples - (a + t[:, None] * ab), axis=1)
                # touching along at least a cell (not at a corner)
                if spans[gap <= STRUCTURE_TOUCH_CELLS * dx].sum() >= dx * (1 - 1e-6):
                    normal = np.array([ab[1], -ab[0]]) / length  # outward for a counter-clockwise outline
                    found.append((index, f"structures.{k} ({structure.name!r})",
                                  structure.contact.friction_angle_deg, normal))
    return found


def _stress_free_on_friction(project: Project) -> list[str]:
    """A body held by an inclined frictional contact, loaded at once by a first dynamic stage."""
    first = next((i for i, stage in enumerate(project.stages) if stage.type in ("dynamic", "strength-reduction")), None)
    if first is None or any(stage.type in ("k0", "gravity") for stage in project.stages[:first]):
        return []
    if not float(np.linalg.norm(project.domain.gravity_m_s2)) > 0:
        return []
    up = _up(project)
    lo_cos = math.cos(math.radians(WALL_ANGLE_DEG))
    hi_cos = math.cos(math.radians(SLOPE_TOLERANCE_DEG))
    for index, where, friction, normal in _contact_faces(project):
        carries = float(normal @ up)  # cosine of the contact's incline to gravity's level
        if not lo_cos < carries < hi_cos:
            continue  # level (no creep direction) or upright (carries no weight)
        incline = math.degrees(math.acos(min(1.0, carries)))
        if friction is None or friction < incline:
            continue  # it slides anyway
        stage = project.stages[first]
        body = project.bodies[index]
        duration = _gravity_stage(project)["duration_s"]
        return [
            f"stages.{first}.type = \"{stage.type}\" has no initial-stress stage before it, and bodies.{index} "
            f"({body.name!r}) rests on {where} (friction {friction:g} degrees, inclined {incline:.3g} degrees): it "
            "starts stress free and loaded at once, and the waves of that loading make it creep down the contact "
            "where friction should hold it; add a gravity stage before it "
            f"({{type = \"gravity\", duration_s = {duration:g}}} with local damping)"
        ]
    return []


def _short_gravity_stage(project: Project) -> list[str]:
    """A gravity stage shorter than the deposit's fundamental period: it ends before the bodies
    could settle, and the next stage starts with the waves of the load it did not carry."""
    if not float(np.linalg.norm(project.domain.gravity_m_s2)) > 0 or not project.bodies:
        return []
    period = deposit_period(project)
    if not math.isfinite(period):
        return []  # no stiffness to speak of (a wave speed that underflows): the time step's business
    for index, stage in enumerate(project.stages):
        if stage.type == "gravity" and stage.duration_s < period:
            recommended = _gravity_stage(project)["duration_s"]
            return [
                f"stages.{index}.duration_s = {stage.duration_s:g}: shorter than the fundamental period 4 H / c_s of "
                f"the bodies ({period:.2g} s), so they cannot settle in it and start the next stage moving (a "
                f"block held by friction creeps); use duration_s = {recommended:g} (the recommended stage: {GRAVITY_STAGE_PERIODS:g} periods, at least 1 s)"
            ]
    return []


def _first_shear_mode_hz(material, depth_m: float) -> float:
    """A body's first shear mode on its base, ``c_s / (4 H)`` (Hz; infinite for no depth)."""
    c_s = math.sqrt(material.shear_modulus_pa / material.density_kg_m3)
    return c_s / (4.0 * depth_m) if depth_m > 0.0 else math.inf


def _near_limit_slides(project: Project) -> list[str]:
    """A linear-elastic body sliding on a frictional contact just above a high friction limit (the
    flutter, measured for elastic blocks; a plastic body dissipates and is not warned about), in a
    dynamic stage where its material is damped by less than NEAR_LIMIT_DAMPING at the body's first
    shear mode on the contact or at twice it (NEAR_LIMIT_BAND). One warning per body, naming the
    keys that remove it."""
    from projects.build import damping_table, material_tables, solver_material

    if not float(np.linalg.norm(project.domain.gravity_m_s2)) > 0:
        return []
    dynamic = [i for i, stage in enumerate(project.stages) if stage.type == "dynamic"]
    if not dynamic:
        return []
    tables = material_tables(project)
    up = _up(project)
    lo_cos = math.cos(math.radians(WALL_ANGLE_DEG))
    dx = project.domain.cell_size_m
    warnings: dict[int, str] = {}
    for index, where, friction, normal in _contact_faces(project):
        carries = float(normal @ up)
        if index in warnings or friction is None or not carries > lo_cos or friction < NEAR_LIMIT_FRICTION_DEG:
            continue
        body = project.bodies[index]
        name = body.material
        if project.materials[name].model != "linear-elastic":
            continue
        incline = math.degrees(math.acos(min(1.0, carries)))
        if not incline > friction:
            continue  # held by friction
        ratio = math.tan(math.radians(friction)) / (math.tan(math.radians(incline)) - math.tan(math.radians(friction)))
        if ratio < NEAR_LIMIT_RATIO:
            continue
        depth = float(np.ptp(np.asarray(body.polygon_m, dtype=np.float64) @ normal))
        if not depth >= NEAR_LIMIT_MIN_CELLS * dx:
            continue  # a sheet a cell or so thick has no body modes to flutter with
        for stage_index in dynamic:
            material = solver_material(name, tables[stage_index][name])
            f1 = _first_shear_mode_hz(material, depth)
            if not math.isfinite(f1):
                continue
            damped = [material.damping_ratio_at(k * f1) for k in NEAR_LIMIT_BAND]
            # 0.99: the 3 digits the warning gives
            if min(damped) >= 0.99 * NEAR_LIMIT_DAMPING:
                continue
            path = damping_table(project, name, stage_index)
            suggested = dataclasses.replace(material, damping_ratio=NEAR_LIMIT_SUGGESTED, damping_frequency_hz=f1,
                                            damping_model=NEAR_LIMIT_DAMPING_MODEL)
            shrink = suggested.damping_step_shrink(dx)  # against the undamped step
            now = ("an undamped elastic body" if max(damped) <= 0.0 else
                   f"an elastic body damped {100 * damped[0]:.2g} % of critical at its first mode and "
                   f"{100 * damped[1]:.2g} % at {NEAR_LIMIT_BAND[1]:g} times its frequency")
            stage = project.stages[stage_index]
            warnings[index] = (
                f"bodies.{index} ({body.name!r}) slides on {where} inclined {incline:.3g} degrees against friction "
                f"{friction:g} degrees in stages.{stage_index} ({stage.name!r}), the friction {ratio:.2g} times the "
                f"net driving force: so close to a high friction limit {now} "
                "flutters on the contact and slides further than a rigid block (5 degrees above the limit, blocks "
                "5-20 cells thick, undamped: up to +30 % at 40 on 35 degrees); material damping removes it: set "
                f"{path}.damping_ratio = {NEAR_LIMIT_SUGGESTED:g}, damping_frequency_hz = {f1:.3g} (the body's first "
                f"shear mode) and damping_model = \"{NEAR_LIMIT_DAMPING_MODEL}\" (the time step {shrink:.2g} "
                "times shorter than undamped; docs/validation.md, near-limit slides)"
            )
            break
    return [warnings[k] for k in sorted(warnings)]


#: Damping above this fraction of critical at a body's first mode is warned about (overdamped).
OVERDAMPED_RATIO = 1.0


def _overdamped_bodies(project: Project) -> list[str]:
    """A Rayleigh-damped material whose damping overdamps a body's first mode: a frequency given far
    below the body's (``zeta = damping_ratio * f / damping_frequency_hz`` grows with frequency), which
    turns the body's vibration into creep and costs steps in proportion."""
    from projects.build import damping_table, material_tables, solver_material

    up = _up(project)
    found = []
    for stage_index, table in enumerate(material_tables(project)):
        for index, body in enumerate(project.bodies):
            material = solver_material(body.material, table[body.material])
            if material.damping_beta_s <= 0.0 or material.maxwell_stiffening > 0.0:
                continue  # undamped, or a Maxwell arm: it damps no mode by more than its ratio (< 1)
            height = float(np.ptp(np.asarray(body.polygon_m, dtype=np.float64) @ up))
            f1 = _first_shear_mode_hz(material, height)
            damped = material.damping_ratio_at(f1)
            path = damping_table(project, body.material, stage_index)
            if math.isfinite(damped) and damped > OVERDAMPED_RATIO and not any(path in w for w in found):
                found.append(
                    f"{path}.damping_frequency_hz = {table[body.material].damping_frequency_hz:g}: the damping is "
                    f"{damped:.3g} times critical at the first shear mode of bodies.{index} ({body.name!r}, "
                    f"{f1:.3g} Hz), which then creeps instead of vibrating, and the time step is "
                    f"{material.damping_step_shrink(project.domain.cell_size_m):.3g} times shorter; give the frequency of "
                    f"the motion to damp, usually that first mode (docs/project-format.md, material damping)")
    return found


def _strength_reduction_with_flip(project: Project) -> list[str]:
    """A strength-reduction stage under classic MPM (FLIP): its particles' velocity noise keeps the
    trials' kinetic energy up, and loaded ground "fails" far below its collapse load
    (docs/validation.md, undrained clay: a strip footing at 0.79 of Prandtl's factor)."""
    if project.numerics.scheme != "mpm":
        return []
    index = next((i for i, stage in enumerate(project.stages) if stage.type == "strength-reduction"), None)
    if index is None:
        return []
    return [f"numerics.scheme = \"mpm\" with stages.{index} (strength-reduction): classic MPM's velocity noise "
            "keeps the trials' kinetic energy up, so loaded ground reads as failing well below its collapse load "
            "(a strip footing at 0.79 of Prandtl's factor); use scheme \"apic-affine\" or \"apic\" for the factor "
            "of safety (docs/validation.md, undrained clay)"]


def _softening_without_length(project: Project) -> list[str]:
    """A softening material (in any stage) of a body without a softening length, or with one shorter
    than the cell size; one warning per material, at the table that set the law (or the length)."""
    from projects.build import material_tables

    used = {body.material for body in project.bodies}
    h = project.domain.cell_size_m
    found: dict[str, str] = {}
    for stage_index, table in enumerate(material_tables(project)):
        for name, material in table.items():
            if name in found or name not in used or material.model != "drucker-prager" or material.softening_law is None:
                continue
            length = material.softening_length_m
            if length is None:
                path = _softening_table(project, name, stage_index, "softening_law")
                found[name] = (
                    f"{path}.softening_law = {material.softening_law!r} without softening_length_m: the softening "
                    f"strain is the particles' own plastic strain and a shear band is about one cell wide, so the "
                    f"failure and the run-out depend on the cell size ({h:g} m here; a finer grid softens sooner "
                    f"and runs out further); give softening_length_m, the thickness of the shear band the "
                    f"residual strain was measured over, at least the cell size (docs/project-format.md, strain "
                    f"softening)")
            elif length < h:
                path = _softening_table(project, name, stage_index, "softening_length_m")
                found[name] = (
                    f"{path}.softening_length_m = {length:g} is shorter than the cell size ({h:g} m): a shear band "
                    f"one cell wide is wider than the material's, and its particles reach the residual strength at "
                    f"a plastic strain {h / length:.3g} times below residual_plastic_strain; give a length of at "
                    f"least the cell size, or cells of at most {length:g} m (docs/solver.md, strain softening)")
    return list(found.values())


def _softening_table(project: Project, name: str, stage_index: int, key: str) -> str:
    """Where material ``name``'s ``key`` in force in stage ``stage_index`` is set: the last stage
    change up to it that sets it, else the material itself."""
    path = f"materials.{name}"
    for index, stage in enumerate(project.stages[:stage_index + 1]):
        change = stage.material_changes.get(name)
        if change is not None and getattr(change, key) is not None:
            path = f"stages.{index}.material_changes.{name}"
    return path


def project_warnings(project: Project) -> list[str]:
    """Everything about a valid project that probably is not what the engineer meant.

    Parameters
    ----------
    project : Project

    Returns
    -------
    list of str
        One line each, naming the key and what to do.
    """
    from projects.plausibility import plausibility_warnings

    with np.errstate(all="ignore"):  # absurd coordinates (1e300 m) are the size limits' business
        return [*plausibility_warnings(project), *_wall_gaps(project), *_structure_gaps(project), *_bodies_in_structures(project),
                *_k0_on_slope(project),
                *_thin_structures(project), *_off_node_faces(project), *_stress_free_on_friction(project),
                *_short_gravity_stage(project), *_near_limit_slides(project), *_overdamped_bodies(project),
                *_softening_without_length(project), *_strength_reduction_with_flip(project)]


def recommended_initial_stage(project: Project) -> dict[str, Any]:
    """The initial-stress stage a new project should start with (a ``[[stages]]`` table).

    Gravity loading where the ground slopes (:func:`ground_slope_deg` > 0), lasting
    :data:`GRAVITY_STAGE_PERIODS` fundamental periods ``4 H / c_s`` of the deposit (``H`` its
    height along gravity, ``c_s`` the slowest shear-wave speed of its materials), at least one
    second, with the default damping; k0 where the ground is level.

    Parameters
    ----------
    project : Project

    Returns
    -------
    dict
        ``{"name": "initial stress", "type": "gravity", "duration_s": ..., "damping": {...}}``
        or ``{"name": "initial stress", "type": "k0"}``.
    """
    if not sloping_faces(project):
        return {"name": "initial stress", "type": "k0"}
    return _gravity_stage(project)


def deposit_period(project: Project) -> float:
    """The deposit's fundamental period ``4 H / c_s`` (s): ``H`` the bodies' height along gravity,
    ``c_s`` the slowest shear-wave speed of the materials (infinite where that speed underflows to
    zero: a modulus of 5e-324 Pa)."""
    up = _up(project)
    heights = np.concatenate([np.asarray(b.polygon_m, dtype=np.float64) @ up for b in project.bodies])
    height = float(heights.max() - heights.min())
    speeds = []
    for material in project.materials.values():
        if material.model == "rigid":
            continue
        shear = material.youngs_modulus_pa / (2.0 * (1.0 + material.poisson_ratio))
        speeds.append(math.sqrt(shear / material.density_kg_m3))
    slowest = min(speeds, default=0.0)
    return 4.0 * height / slowest if slowest > 0.0 else math.inf


def _gravity_stage(project: Project) -> dict[str, Any]:
    """The gravity stage :func:`recommended_initial_stage` gives for sloping ground."""
    period = deposit_period(project)
    # at least 1 s; an infinite period (no stiffness) gives the 1 s too, the time step refuses it
    duration = max(1.0, float(f"{GRAVITY_STAGE_PERIODS * period:.2g}")) if math.isfinite(period) else 1.0
    return {
        "name": "initial stress",
        "type": "gravity",
        "duration_s": duration,
        "damping": {"type": "local", "coefficient": DEFAULT_GRAVITY_DAMPING},
    }
