"""Contact: the grid contact law of the closed sides and the rigid structures (docs/solver.md, contact).

Every contact acts on the grid nodes it holds: a closed side (fixed, slip or friction) the nodes
on its line and beyond (the ghost layers), normal the side's inward axis; a structure (a rigid
polygon inside the domain) the nodes whose cell reaches into it
(:func:`solver.structures.node_contacts`), normal its outward normal there. The law
(:meth:`Contacts.law`): fixed stops the node; slip and friction raise a normal velocity below the
contact's target to it and take at most ``mu`` times that normal impulse off the tangential speed,
never reversing it; a separating node is free. It acts on the interpolated velocity too
(Bardenhagen et al. 2000: the stress update sees the constrained velocity) and on the updated one.

At a structure's node the target is not zero but the material's normal velocity continued linearly
to zero at the surface (so a surface between node lines is felt where it lies), and the node's
normal is chosen from the faces it meets (a convex corner's two faces, the material's own normal
near a vertex, both faces of a thin part). The structures' mirror-image particles supply the
share of force that material beyond the surface would give the free nodes, their reaction passing
through the law at the contact nodes; a particle that ends a step inside a structure is put back
on its surface (:meth:`Contacts.push_out`).

Each step adds, per contact, the impulse the material exerts on it and its moment, and keeps the
largest force of any step (:meth:`Contacts.tally`). Contacts are indexed as the engine reports
them: the four sides in :data:`solver.config.SIDES` order, then the structures.

Symbols as in solver.engine. The sides' kinds and friction are data (no recompilation); the
structures' geometry is fixed at construction, and without structures their parts compile to
nothing.
"""


import numpy as np

from solver.config import Boundary, Structure
from solver.runtime import mat_vec, ti
from solver.shape import PAD, bspline
from solver.structures import (
    corner_normals,
    far_normals,
    node_contacts,
    segments,
    signed_distance,
    through_sides,
    zone_nodes,
)

BOUNDARY_CODES = {"fixed": 0, "slip": 1, "friction": 2, "open": 3, "periodic": 4}
FIXED, SLIP, FRICTION, OPEN, PERIODIC = (BOUNDARY_CODES[k] for k in ("fixed", "slip", "friction", "open", "periodic"))
#: A particle found inside a structure after its move is put on the nearest point of the surface and
#: this many cell sizes outside it (so that rounding never leaves it inside).
PUSH_OUT_CELLS = 1e-3
#: Particles closer than this many cell sizes to a structure's surface have a mirror image across it
#: (``structure_forces``): an image deeper than 1.5 cells along each axis reaches no node outside.
MIRROR_REACH_CELLS = 2.2
#: A contact node near a convex vertex takes its material's mean outward normal where the
#: particles' normals agree this well (the length of their weighted mean; 0.9 = cos 26 deg: material
#: against one face, or spread over a corner's region); else its own normals.
CORNER_COHERENCE = 0.9
#: A thin part's node holds the material both ways across it where each of its faces has more
#: than this share of the node's mass (solver.structures.far_normals, Contacts._structure_normal).
TWO_SIDED_SHARE = 0.02
#: The material's normal is the node's own (its surface's) within this cosine (0.8 deg).
OWN_NORMAL = 0.9999
#: Unit normal of each side (SIDES order), out of the wall into the domain.
_INWARD = ((1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0))


def contact_codes(contacts) -> tuple[np.ndarray, np.ndarray]:
    """Kind codes and friction coefficients (zero unless ``friction``) of a list of Boundary."""
    kinds = np.array([BOUNDARY_CODES[c.kind] for c in contacts], np.int32)
    mus = np.array([np.tan(c.friction_angle_rad) if c.kind == "friction" else 0.0 for c in contacts])
    return kinds, mus


@ti.data_oriented
class Contacts:
    """The contacts of ``engine``'s grid: its four sides and ``structures``.

    Fields (the engine's state dict holds them under these names): per side its kind code and
    friction coefficient (``bc_kind``, ``bc_mu``); per structure its kind and friction (``st_kind``,
    ``st_mu``), its edges and bounding box (``edge_a``, ``edge_b``, ``st_edges``, ``st_box``); per
    grid node the structure whose contact node it is (``node_struct``, -1: none), that structure's
    outward normal there (``node_normal``; near a convex corner also the other face's,
    ``node_normal_b``), its signed distance to the surface (``node_sd``, m, negative inside), the
    zone near a convex vertex or in a thin part it belongs to (``node_zone``, ``st_zone_box``) with
    the material's weighted normal there (``node_pn``, rebuilt every step), the far face's normal
    in a thin part (``node_far``), and the step after the last in which the structure held it
    (``node_hold``, against ``hold_step``) with what that hold adds to the stress update's velocity
    (``node_hold_dv``, six stages only). Per contact the impulse on the material in this step with
    its moment (``contact_step``), the impulse on the contact since the last read, its moment and
    the largest force of one step (``contact_impulse``, ``contact_moment``, ``contact_peak``), in
    f64 whatever the precision.
    """

    def __init__(self, engine, structures: tuple[Structure, ...], rigid_bodies: int = 0):
        self.engine = engine
        self.structures = tuple(structures)
        self.n_structures = len(self.structures)
        #: the contacts: the four sides, the structures, then the rigid bodies (solver.rigid), whose
        #: impulses this component records and tallies with the others
        self.n_contacts = 4 + self.n_structures + int(rigid_bodies)
        ns = max(1, self.n_structures)
        has = self.n_structures > 0
        nodes = engine.nodes if has else (1, 1)
        self.bc_kind = ti.field(ti.i32, 4)
        self.bc_mu = ti.field(float, 4)
        self.st_kind = ti.field(ti.i32, ns)
        self.st_mu = ti.field(float, ns)
        # a structure standing on a side continues through it (solver.structures.through_sides)
        crossable = (not engine.periodic.on, not engine.periodic.on, True, True)
        self.solid_polygons = tuple(through_sides(st.polygon_m, engine.origin, engine.upper, PAD * engine.dx, crossable)
                                    for st in self.structures)
        self._edges = [segments(polygon) for polygon in self.solid_polygons]
        n_edges = max(1, sum(len(a) for a, _ in self._edges))
        self.edge_a = ti.Vector.field(2, float, n_edges)
        self.edge_b = ti.Vector.field(2, float, n_edges)
        self.st_edges = ti.field(ti.i32, (ns, 2))  # first edge, edge count
        self.st_box = ti.Vector.field(4, float, ns)  # x min, y min, x max, y max
        self.node_struct = ti.field(ti.i32, nodes)
        self.node_normal = ti.Vector.field(2, float, nodes)
        self.node_normal_b = ti.Vector.field(2, float, nodes)
        self.node_sd = ti.field(float, nodes)
        #: any zone node at all (set with the geometry): the material normals' stage runs only then
        self.has_zone = False
        self.node_zone = ti.field(ti.i32, nodes)
        self.node_pn = ti.Vector.field(3, float, nodes)
        self.node_far = ti.Vector.field(2, float, nodes)
        self.st_zone_box = ti.Vector.field(4, float, ns)
        self.node_hold = ti.field(ti.i32, nodes)
        self.hold_step = ti.field(ti.i32, ())
        self.node_hold_dv = ti.Vector.field(2, float, nodes if has and engine.six_stage else (1, 1))
        self.contact_step = ti.Vector.field(3, ti.f64, self.n_contacts)
        self.contact_impulse = ti.Vector.field(2, ti.f64, self.n_contacts)
        self.contact_moment = ti.field(ti.f64, self.n_contacts)
        self.contact_peak = ti.Vector.field(3, ti.f64, self.n_contacts)

    #: the fields the engine's state and set-up move, by their state names
    HOST_FIELDS = ("contact_impulse", "contact_moment", "contact_peak", "node_hold", "hold_step", "contact_step",
                   "bc_kind", "bc_mu", "st_kind", "st_mu", "edge_a", "edge_b", "st_edges", "st_box", "node_struct",
                   "node_normal", "node_normal_b", "node_sd", "node_zone", "node_far", "st_zone_box")

    def host_fields(self) -> dict:
        return {name: getattr(self, name) for name in self.HOST_FIELDS}

    # ---------------------------------------------------------------- host set-up
    def side_values(self, boundaries: tuple[Boundary, ...]) -> dict:
        """The fields' values for the four sides' contacts (SIDES order)."""
        kinds, mus = contact_codes(boundaries)
        return {"bc_kind": kinds, "bc_mu": mus}

    def structure_values(self, contacts: tuple[Boundary, ...]) -> dict:
        """The fields' values for the structures' contacts, in order (the geometry stays as built)."""
        if len(contacts) != self.n_structures:
            raise ValueError(f"{self.n_structures} structure contacts expected, got {len(contacts)}")
        if any(c.kind in ("open", "periodic") for c in contacts):
            raise ValueError("a structure's contact is fixed, slip or friction, not open or periodic")
        if not self.n_structures:
            return {}
        kinds, mus = contact_codes(contacts)
        return {"st_kind": kinds, "st_mu": mus}

    def geometry_values(self, np_float) -> dict:
        """The fields' values for the structures' geometry on the engine's grid (sets :attr:`has_zone`)."""
        e = self.engine
        if not self.n_structures:
            return {}
        f = np_float
        edges = self._edges
        counts = np.array([len(a) for a, _ in edges], np.int32)
        xs = e.origin[0] + (np.arange(e.nodes[0]) - PAD) * e.dx
        ys = e.origin[1] + (np.arange(e.nodes[1]) - PAD) * e.dx
        index, normal = node_contacts(self.solid_polygons, xs, ys, e.dx)
        normal, normal_b = corner_normals(self.solid_polygons, xs, ys, index, normal, e.dx, (e.origin, e.upper))
        far = far_normals(self.solid_polygons, xs, ys, index, normal, e.dx)
        zone, zone_boxes = zone_nodes(self.solid_polygons, xs, ys, index, normal, far, e.dx, (e.origin, e.upper))
        self.has_zone = bool(zone.any())
        X, Y = np.meshgrid(xs, ys, indexing="ij")
        sd = np.zeros(index.shape)
        for k, polygon in enumerate(self.solid_polygons):
            mine = index == k
            pts = np.c_[X[mine], Y[mine]]
            dist = signed_distance(pts, polygon)
            # where the structure is less than a cell thick beyond the node's surface point the node
            # keeps the plain law (zero: its contact target, _surface_target, is then zero): a
            # block thrown at a leaning barrier half a cell thick went unstable with the target
            deeper = pts - (dist + e.dx)[:, None] * normal[mine]
            dist[signed_distance(deeper, polygon) > 0.0] = 0.0
            sd[mine] = dist
        return {
            **self.structure_values(tuple(st.contact for st in self.structures)),
            "edge_a": np.concatenate([a for a, _ in edges]).astype(f),
            "edge_b": np.concatenate([b for _, b in edges]).astype(f),
            "st_edges": np.c_[np.cumsum(counts) - counts, counts].astype(np.int32),
            "st_box": np.array([[*a.min(axis=0), *a.max(axis=0)] for a, _ in edges]).astype(f),
            "node_struct": index,
            "node_normal": normal.astype(f),
            "node_normal_b": normal_b.astype(f),
            "node_sd": sd.astype(f),
            "node_zone": zone,
            "node_far": far.astype(f),
            "st_zone_box": np.nan_to_num(zone_boxes, posinf=1e30, neginf=-1e30).astype(f),
        }

    # ---------------------------------------------------------------- called by the engine's grid stages
    @ti.func
    def clear_hold(self, I):
        """Before the six-stage contact on the interpolated velocity: no hold at node I yet."""
        if ti.static(self.n_structures > 0 and self.engine.six_stage):
            self.node_hold_dv[I] = ti.Vector.zero(float, 2)

    @ti.func
    def with_hold(self, J, v):
        """Node J's velocity ``v`` for the six-stage stress update, with what the structures' hold
        adds to it (see :meth:`apply`)."""
        out = v
        if ti.static(self.n_structures > 0 and self.engine.six_stage):
            out += self.node_hold_dv[J]
        return out

    @ti.func
    def copy_hold(self, image, i, j):
        """Node (i, j)'s hold into its periodic image (image, j) (solver.periodic)."""
        if ti.static(self.n_structures > 0 and self.engine.six_stage):
            self.node_hold_dv[image, j] = self.node_hold_dv[i, j]

    @ti.func
    def apply(self, I, v, mass, record: ti.template(), trial: ti.template(), dt, damping):
        """The contact law at node I for every contact that holds it: its trial velocity ``v`` in,
        the constrained velocity out; with ``record`` the impulse each contact gives the node's
        ``mass`` is added to ``contact_step``.

        Contact nodes of a closed side: the nodes on its line and beyond (ghost layers); normal the
        side's inward axis. Of a structure: the nodes whose cell reaches into it
        (:func:`solver.structures.node_contacts`); normal its outward normal there.
        A node on a side and in a structure meets both, side first; the impulse they give it
        together is recorded split along their two normals.

        At a structure's node the normal velocity the law allows is not zero but the material's
        normal velocity continued linearly to zero at the surface (``_surface_target``; zero for a
        node on the surface), and on the interpolated velocity (``trial = "interpolated"``) a node
        the structure held at the end of the last step is held at that target both ways for the
        stress update alone (``node_hold_dv``, no impulse). ``trial`` says how to read the free
        nodes' trial velocities in this stage, ``dt`` and ``damping`` are the update's.
        """
        e = self.engine
        v_in = v
        held_by = -1  # the side that holds the node (the last, at a corner of the box)
        sides_holding = 0
        side_n = ti.Vector.zero(float, 2)
        corner = self.closed_sides_at(I)
        for side in ti.static(range(4)):
            axis = ti.static(side // 2)
            low = ti.static(side % 2 == 0)
            wall = ti.static(PAD if low else PAD + e.cells[axis])
            on_wall = (I[axis] <= wall) if ti.static(low) else (I[axis] >= wall)
            kind = self.bc_kind[side]
            if on_wall and self.closed(kind):
                n = ti.Vector(ti.static(_INWARD[side]), float)
                mu = self.bc_mu[side]
                if kind == FRICTION and corner == 1:
                    # the wall node and the ghosts beyond it are one contact point: here the
                    # normal part only; the column's Coulomb law follows (solver.walls)
                    mu = 0.0
                    layer = (wall - I[axis]) if ti.static(low) else (I[axis] - wall)
                    e.walls.hold_in_column(side, I[1 - axis], layer, ti.max(-v.dot(n), 0.0))
                new = self.law(v, n, kind, mu, 0.0)
                if ti.static(record):
                    self.record(side, mass * (new - v), self.side_point(side, I))
                v = new
                held_by = side
                sides_holding += 1
                side_n = n
        if ti.static(self.n_structures > 0):
            s = self.node_struct[I]
            if s >= 0:
                n, own = self._structure_normal(I, v)
                # a node on the structure's medial axis (the middle node line of a wall an even
                # number of cells thick) has no outward direction (zero normal): it is held
                kind = self.st_kind[s] if n.dot(n) > 0.25 else FIXED
                target = 0.0 * mass
                if kind != FIXED and own:
                    # the target continues the material's velocity to the surface along the
                    # node's own normal (its signed distance runs along it): a node that takes
                    # its material's normal (another face's) takes the plain law
                    target = self._surface_target(I, n, trial, dt, damping)
                new = self.law(v, n, kind, self.st_mu[s], target)
                if ti.static(trial == "interpolated"):
                    # the stress update's velocity: where the structure held the node at the end
                    # of the last step (the contact in compression), it holds it at the target
                    # either way; the one-sided law here (held while the material approaches,
                    # free while it recedes) ratcheted mpm's stress update: +14 to +50 % in 0.3 s
                    # with faces 0.6-0.7 cells off a node line. For the stress update only
                    # (node_hold_dv): as an impulse the hold pulled receding material back, the
                    # push that undid it brought friction of its own, and a block sliding on a
                    # 40 deg ramp slid 2-17 % short
                    if kind != FIXED and self.node_hold[I] == self.hold_step[None] and v.dot(n) >= target:
                        self.node_hold_dv[I] = (target - v.dot(n)) * n
                elif kind != FIXED and v.dot(n) < target:
                    self.node_hold[I] = self.hold_step[None] + 1  # read by the next step
                if ti.static(record):
                    det = side_n[0] * n[1] - side_n[1] * n[0]
                    if sides_holding == 1 and ti.abs(det) > 0.5:
                        # a node held by a side and a structure (the foot of a wall standing on the
                        # grid's bottom): the side acted first and may have taken everything (a
                        # fixed side), so the whole impulse is split along the two normals, each
                        # contact taking its own normal reaction (and the friction along the other's)
                        total = mass * (new - v_in)
                        a = (total[0] * n[1] - total[1] * n[0]) / det
                        b = (side_n[0] * total[1] - side_n[1] * total[0]) / det
                        self.record(held_by, a * side_n - mass * (v - v_in), self.side_point(held_by, I))
                        self.record(4 + s, b * n, self.surface_point(I))
                    else:
                        self.record(4 + s, mass * (new - v), self.surface_point(I))
                v = new
        return v

    @ti.func
    def _structure_normal(self, I, v):
        """The normal of structure contact node I for its trial velocity ``v``, and whether it is
        the node's own (its surface's, along which its signed distance runs) or its material's.

        The node's one normal; at a node that meets a convex corner (solver.structures.
        corner_normals) of the corner's two faces the one ``v`` moves least into (the material meets
        the corner's solid only when it moves into both faces; sliding along either face away from
        the corner moves into neither), their mean where it moves into both alike.

        Near a convex vertex (a zone node, solver.structures.corner_zone) the material the node
        carries says where it lies, when its particles' outward normals agree (the length of their
        weighted mean at least CORNER_COHERENCE): at a corner node, on one of the corner's faces,
        that face alone (the velocity's choice let a block resting flush with a platform's edge
        slide off it: 3.4 mm in 0.5 s, apic, 1e6 Pa); elsewhere the material's normal is one more
        face to choose from by the velocity (a sheet sliding away from a ramp's top vertex, on the
        level top's node one cell back: its slide is no approach to the ramp's face). Imposed there
        instead, the material's normal drove the block at the platform's edge up and aside."""
        n = self.node_normal[I]
        nb = self.node_normal_b[I]
        own = True
        material = ti.Vector.zero(float, 2)
        lies = False
        beyond = False
        both = False
        far = ti.Vector.zero(float, 2)
        if ti.static(self.has_zone):
            zone = self.node_zone[I]
            if zone != 0:
                pn = self.node_pn[I]
                mean = ti.Vector([pn[0], pn[1]])
                size = mean.norm()
                far = self.node_far[I]
                if pn[2] > 0.0 and far.dot(far) > 0.25:
                    # the node's mass beyond the far face and on its own side (the particles'
                    # outward normals are the two faces': the sum along far is their difference)
                    beyond_mass = 0.5 * (pn[2] + mean.dot(far))
                    both = ti.min(beyond_mass, pn[2] - beyond_mass) > TWO_SIDED_SHARE * pn[2]
                if pn[2] > 0.0 and size >= CORNER_COHERENCE * pn[2]:
                    material = mean / size
                    beyond = material.dot(far) >= CORNER_COHERENCE
                    lies = zone > 0
        corner = (nb - n).norm_sqr() > 0.0
        on_a = material.dot(n)
        on_b = material.dot(nb)
        if both:
            # material on both faces of a thin part: held both ways across it (by the face the
            # velocity moves into), so that neither side's push passes through to the other
            if v.dot(far) < v.dot(n):
                n = far
            own = False
        elif beyond:
            # the material lies beyond a thin part's far face (solver.structures.far_normals)
            n = far
            own = False
        elif lies and corner and ti.max(on_a, on_b) >= OWN_NORMAL:
            # the material lies on one of the corner's faces: the nearer one (both faces within
            # OWN_NORMAL of it, as on a curve drawn with chords under a degree apart, must not
            # leave it to the polygon's orientation, which orders the two)
            if on_b > on_a:
                n = nb
            elif on_b == on_a:
                n = (n + nb).normalized()
        else:
            va = v.dot(n)
            vb = v.dot(nb)
            if vb > va:
                n = nb
            elif vb == va and corner:
                n = (n + nb).normalized()
            if lies and material.dot(self.node_normal[I]) < OWN_NORMAL and v.dot(material) > v.dot(n):
                n = material
                own = False
        return n, own

    @ti.func
    def on_closed_side(self, I, side: ti.template()):
        """Whether node I lies on or beyond ``side`` (0-3: left, right, bottom, top) and that side is
        closed (a contact)."""
        e = self.engine
        axis = ti.static(side // 2)
        low = ti.static(side % 2 == 0)
        wall = ti.static(PAD if low else PAD + e.cells[axis])
        on_wall = (I[axis] <= wall) if ti.static(low) else (I[axis] >= wall)
        return on_wall and self.closed(self.bc_kind[side])

    @ti.func
    def closed_sides_at(self, I):
        """How many closed sides node I lies on or beyond (2: a corner of the box, where the
        friction law acts node by node, not by wall column)."""
        count = 0
        for side in ti.static(range(4)):
            if self.on_closed_side(I, side):
                count += 1
        return count

    @ti.func
    def held(self, I):
        """Whether node I is a contact node of a closed side or of a structure (where
        :meth:`apply` acts)."""
        held = self.closed_sides_at(I) > 0
        if ti.static(self.n_structures > 0):
            if self.node_struct[I] >= 0:
                held = True
        return held

    @ti.func
    def closed(self, kind):
        """Whether a side of this kind is a contact (not open, not periodic)."""
        return kind != OPEN and kind != PERIODIC

    @ti.func
    def law(self, v, n, kind, mu, target):
        """Velocity after a contact with unit normal ``n`` (out of the contact, into the material).

        fixed: zero. slip and friction: when the node's normal velocity ``vn = v.n`` is below
        ``target`` (the normal velocity the contact allows there: zero at a side and at a node on a
        structure's surface) it is raised to it (an impulse ``target - vn`` per unit mass) and the
        tangential speed is reduced by at most ``mu (target - vn)``, never reversed; otherwise
        (separating) unchanged. ``mu`` is zero for slip.
        """
        out = v
        if kind == FIXED:
            out = ti.Vector.zero(float, 2)
        else:
            vn = v.dot(n)
            if vn < target:
                vt = v - vn * n
                speed = vt.norm()
                out = target * n
                if speed > 0.0:
                    out += vt * (ti.max(speed - mu * (target - vn), 0.0) / speed)
        return out

    @ti.func
    def _surface_target(self, I, n, trial: ti.template(), dt, damping):
        """The normal velocity a structure's contact node I may not fall below: that of the
        material's velocity field continued linearly to zero at the surface (mirror image across it
        for a node inside), ``v_n(x_r) sd / d_r``, with ``sd`` the node's signed distance and
        ``v_n(x_r)`` the material's normal velocity one cell out from the surface point nearest to
        the node, the mass-weighted mean over the free nodes of that point's stencil, ``d_r`` their
        mean distance from the surface. Zero with no free node there."""
        e = self.engine
        sd = self.node_sd[I]
        xi = ti.Vector(e.origin) + ti.cast(I - PAD, float) * e.dx
        q = xi - sd * n
        base, fx, w, dw = e._stencil(q + e.dx * n)
        mw = 0.0 * sd
        mv = 0.0 * sd
        md = 0.0 * sd
        for k in range(9):  # a runtime loop: compiled once per stage, not nine times
            J = base + ti.Vector([k // 3, k % 3])
            mass = e.g_mass[J]
            if mass > 0.0 and not self.held(J):
                wm = bspline(fx[0], k // 3) * bspline(fx[1], k % 3) * mass
                xj = ti.Vector(e.origin) + ti.cast(J - PAD, float) * e.dx
                mw += wm
                mv += wm * e.trial_velocity(J, trial, dt, damping).dot(n)
                md += wm * (xj - q).dot(n)
        target = 0.0 * sd
        if mw > 0.0 and md > 0.0 and sd > -e.dx:
            target = mv / md * sd
        return target

    @ti.func
    def record(self, c, impulse, point):
        """Add an impulse on the material at ``point`` to contact ``c``'s step, with its moment."""
        j = ti.cast(impulse, ti.f64)
        p = ti.cast(point, ti.f64)
        self.contact_step[c] += ti.Vector([j[0], j[1], p[0] * j[1] - p[1] * j[0]])

    @ti.func
    def side_point(self, side, I):
        """Node I's point on the line of ``side`` (the wall nodes and ghosts beyond it act there)."""
        e = self.engine
        p = ti.Vector(e.origin) + ti.cast(I - PAD, float) * e.dx
        if side == 0:
            p[0] = e.origin[0]
        elif side == 1:
            p[0] = e.upper[0]
        elif side == 2:
            p[1] = e.origin[1]
        else:
            p[1] = e.upper[1]
        return p

    @ti.func
    def surface_point(self, I):
        """Node I's point on its structure's surface: along its normal by its signed distance."""
        e = self.engine
        p = ti.Vector(e.origin) + ti.cast(I - PAD, float) * e.dx
        return p - self.node_sd[I] * self.node_normal[I]

    @ti.func
    def tally(self, dt, g, damping, damped: ti.template()):
        """Turn this step's impulses on the material into the contacts' impulse and peak force."""
        self.hold_step[None] += 1
        ti.loop_config(serialize=True)  # a handful of contacts
        for c in range(self.n_contacts):
            step = -self.contact_step[c]  # what the material exerts on the contact
            self.contact_step[c] = ti.Vector.zero(ti.f64, 3)
            on_contact = ti.Vector([step[0], step[1]])
            self.contact_impulse[c] += on_contact
            self.contact_moment[c] += step[2]
            if dt > 0.0:
                force = on_contact / ti.cast(dt, ti.f64)
                size = force.norm()
                if size > self.contact_peak[c][0]:
                    self.contact_peak[c] = ti.Vector([size, force[0], force[1]])

    @ti.func
    def structure_forces(self, dt, g, damping, damped: ti.template()):
        """The mirror-image particles of the structures (docs/solver.md, contact).

        A particle within MIRROR_REACH_CELLS of a structure's surface has an image across it: at
        ``2 q - x`` (``q`` the nearest point of the surface), with the reflected stress and body
        force, ``F sigma R`` and ``F m g`` (``R = I - 2 n n^T``, ``n`` the outward normal
        ``(x - q) / |x - q|``; ``F = R`` for slip, the symmetric image, ``F = -I`` for fixed and
        friction, the antisymmetric one, as at the closed sides). Its force goes to the free nodes
        of its stencil (the share that material beyond the surface would give them, which their
        truncated support misses) and its opposite to the particle's own contact nodes of that
        structure, by their weights: momentum is unchanged and the reaction passes through the
        contact law there. Particles share nodes: with plain adds (serial and split scatters) the
        loop runs in one thread, so the sums repeat bit for bit (a bounding-box test per particle,
        the image work only near a structure); with the atomic scatter (GPU) in parallel, with
        atomic adds.
        """
        e = self.engine
        reach = ti.static(MIRROR_REACH_CELLS * e.dx)
        ti.loop_config(serialize=e.plain)
        for p in range(e.n):
            if e.active[p] and not e.rigid.is_rigid(p):
                x = e.x[p]
                for st in range(self.n_structures):
                    box = self.st_box[st]
                    if box[0] - reach <= x[0] <= box[2] + reach and box[1] - reach <= x[1] <= box[3] + reach:
                        self._mirror_particle(p, st, x, g)

    @ti.func
    def material_normals(self, dt, g, damping, damped: ti.template()):
        """The weighted outward normal of the material at each zone node (see
        :meth:`_structure_normal`): every particle in a structure's zone box adds its weight x mass
        x the outward normal at its nearest surface point, ``(x - q) / |x - q|``, and its weight
        x mass, to its stencil's zone nodes of that structure (node_pn, cleared by the grid reset).
        As in :meth:`structure_forces`: in one thread with plain adds (serial and split scatters),
        so the sums repeat bit for bit; in parallel with atomic adds (GPU)."""
        e = self.engine
        ti.loop_config(serialize=e.plain)
        for p in range(e.n):
            if e.active[p] and not e.rigid.is_rigid(p):
                x = e.x[p]
                for st in range(self.n_structures):
                    box = self.st_zone_box[st]
                    if box[0] <= x[0] <= box[2] and box[1] <= x[1] <= box[3]:
                        q, best, inside = self.nearest_surface_point(st, x)
                        dist = ti.sqrt(best)
                        if inside == 0 and dist > 0.0:
                            n = (x - q) / dist
                            base, fx, w, dw = e._stencil(x)
                            m = e.m[p]
                            for k in range(9):  # a runtime loop: compiled once, not nine times
                                I = base + ti.Vector([k // 3, k % 3])
                                if ti.abs(self.node_zone[I]) == st + 1:
                                    wm = bspline(fx[0], k // 3) * bspline(fx[1], k % 3) * m
                                    self.node_pn[I] += ti.Vector([wm * n[0], wm * n[1], wm])

    @ti.func
    def nearest_surface_point(self, st, x):
        """The point of structure ``st``'s outline nearest to ``x``, its squared distance (m2), and
        whether ``x`` lies inside the structure (1) or not (0; crossing number)."""
        best = ti.cast(1e30, float)
        nearest = x
        inside = 0
        first = self.st_edges[st, 0]
        for k in range(first, first + self.st_edges[st, 1]):
            a = self.edge_a[k]
            ab = self.edge_b[k] - a
            t = ti.min(ti.max((x - a).dot(ab) / ti.max(ab.dot(ab), 1e-30), 0.0), 1.0)
            c = a + t * ab
            d2 = (x - c).norm_sqr()
            if d2 < best:
                best = d2
                nearest = c
            if (a[1] > x[1]) != (a[1] + ab[1] > x[1]):
                if x[0] < a[0] + (x[1] - a[1]) * ab[0] / ab[1]:
                    inside = 1 - inside
        return nearest, best, inside

    @ti.func
    def _mirror_particle(self, p, st, x, g):
        """Particle p's image across structure ``st`` (see :meth:`structure_forces`)."""
        e = self.engine
        q, best, inside = self.nearest_surface_point(st, x)
        dist = ti.sqrt(best)
        reach = ti.static(MIRROR_REACH_CELLS * e.dx)
        if inside == 0 and dist > 0.0 and dist < reach:
            n = (x - q) / dist
            R = ti.Matrix.identity(float, 2) - 2.0 * n.outer_product(n)
            F = -ti.Matrix.identity(float, 2)
            if self.st_kind[st] == SLIP:
                F = R
            wet = e.water_state(p)
            sig = F @ e.force_stress(p, wet) @ R
            m = e.particle_mass(p, wet)
            vol = e.particle_volume(p)
            body = F @ (m * g)
            if ti.static(e.wet):
                body += F @ e.water_force(vol, wet)
            if ti.static(e.loaded):
                body += F @ e.loads.force(p)
            # only where the particle's stencil reaches a contact node of this structure
            base, fx, w, dw = e._stencil(x)
            held = 0.0
            for i, j in ti.static(ti.ndrange(3, 3)):
                if self.node_struct[base + ti.Vector([i, j])] == st:
                    held += w[i][0] * w[j][1]
            if held > 0.0:
                ibase, ifx, iw, idw = e._stencil(2.0 * q - x)
                for i, j in ti.static(ti.ndrange(3, 3)):
                    I = ibase + ti.Vector([i, j])
                    if e._in_box(I) and not self.held(I):
                        # only nodes on the particle's side of the surface: beyond a thin part
                        # the image's stencil reaches the material on its far side
                        xi = ti.Vector(e.origin) + ti.cast(I - PAD, float) * e.dx
                        if e.g_mass[I] > 0.0 and (xi - q).dot(n) > 0.0:
                            grad = ti.Vector([idw[i][0] * iw[j][1], iw[i][0] * idw[j][1]]) * e.inv_dx
                            f = -vol * mat_vec(sig, grad) + iw[i][0] * iw[j][1] * body
                            e.g_f[I] += f
                            self._mirror_reaction(st, I, q, n, f, base, fx, held)

    @ti.func
    def _mirror_reaction(self, st, I, q, n, f, base, fx, held):
        """The opposite of an image's force ``f`` at free node I goes to the contact nodes of
        structure ``st`` around I's mirror point (across the surface's tangent at ``q``), by their
        weights there: so the reaction stays opposite the node that took the force. (Given to the
        particle's own contact nodes instead, the images' weight, which their stress carries down
        to the bottom along the free nodes, came back up at the contact nodes at every height: a
        slip wall's contact nodes lifted the particles next to them, and the column's horizontal
        stress drifted: +60 % in 0.3 s half a cell off the node line.) Where no contact node is
        near that point, the particle's own contact nodes take it (by its weights ``fx`` from ``base``)."""
        e = self.engine
        xi = ti.Vector(e.origin) + ti.cast(I - PAD, float) * e.dx
        mbase, mfx, mw, mdw = e._stencil(xi - 2.0 * (xi - q).dot(n) * n)
        near = 0.0 * held
        for k in range(9):  # runtime loops: this path runs 9 times per image, compiled once
            K = mbase + ti.Vector([k // 3, k % 3])
            if self._takes_reaction(K, st, n):
                near += bspline(mfx[0], k // 3) * bspline(mfx[1], k % 3) * e.g_mass[K]
        for k in range(9):
            if near > 0.0:
                K = mbase + ti.Vector([k // 3, k % 3])
                if self._takes_reaction(K, st, n):
                    e.g_f[K] -= (bspline(mfx[0], k // 3) * bspline(mfx[1], k % 3) * e.g_mass[K] / near) * f
            else:
                K = base + ti.Vector([k // 3, k % 3])
                if self.node_struct[K] == st:
                    e.g_f[K] -= (bspline(fx[0], k // 3) * bspline(fx[1], k % 3) / held) * f

    @ti.func
    def _takes_reaction(self, K, st, n):
        """Whether node K, near the mirror point of a free node, takes the reaction of an image of
        structure ``st`` whose surface normal is ``n``: a contact node of it that holds mass (the
        contact law acts only there) and does not face the other way (a thin wall's far face)."""
        e = self.engine
        return self.node_struct[K] == st and e.g_mass[K] > 0.0 and self.node_normal[K].dot(n) >= 0.0

    @ti.func
    def push_out(self, x_old, x, v, mass):
        """A particle that ended inside a structure goes back to where its move ``x_old -> x``
        entered it: the first crossing of the path with the outline, PUSH_OUT_CELLS cells out on
        the side it came from, never through a thin structure to its far face (with no crossing,
        a particle that started inside, the nearest point of the surface). Its velocity into the
        structure (along the crossed edge's normal) is removed: an impulse of that structure's
        contact."""
        e = self.engine
        if ti.static(self.n_structures > 0):
            for s in range(self.n_structures):
                box = self.st_box[s]
                if box[0] <= x[0] <= box[2] and box[1] <= x[1] <= box[3]:
                    nearest, _d2, inside = self.nearest_surface_point(s, x)
                    if inside == 1:
                        out = nearest - x
                        path = x - x_old
                        t_first = 2.0
                        first = self.st_edges[s, 0]
                        for k in range(first, first + self.st_edges[s, 1]):
                            a = self.edge_a[k]
                            ab = self.edge_b[k] - a
                            den = path[0] * ab[1] - path[1] * ab[0]
                            if den != 0.0:
                                ao = a - x_old
                                t = (ao[0] * ab[1] - ao[1] * ab[0]) / den  # along the path
                                u = (ao[0] * path[1] - ao[1] * path[0]) / den  # along the edge
                                if 0.0 <= t <= 1.0 and 0.0 <= u <= 1.0 and t < t_first:
                                    t_first = t
                                    nearest = x_old + t * path
                                    out = ti.Vector([ab[1], -ab[0]])  # the edge's normal, against the path
                                    if out.dot(path) > 0.0:
                                        out = -out
                        size = out.norm()
                        if size > 0.0:
                            n = out / size
                            x = nearest + (PUSH_OUT_CELLS * e.dx) * n
                            vn = v.dot(n)
                            if vn < 0.0:
                                v -= vn * n
                                self.record(4 + s, -mass * vn * n, x)
        return x, v