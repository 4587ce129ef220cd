"""Rigid bodies of particles moved at a prescribed velocity: platens, gates, pistons.

A material of model ``rigid`` is kinematic. Its particles carry no stress and no weight and give
the grid no mass or momentum; each moves at its material's velocity in dynamic stages and stands
still in initial-stress stages (:meth:`RigidBodies.set_moving`). Instead of mass, a rigid particle
adds its B-spline weights times its volume, and their gradients, to ``node_rigid``: a node with
some rigid weight is a contact node of that body. The body's outward normal there is the
difference of the two volume gradients ``sum V_p grad S_i(x_p)`` (each points out of its own
body, from its particles to the node), the body's less the material's (every other particle adds
its own to ``node_soil``), normalised: the multi-material contact of Bardenhagen et al.
(2000, Comput Model Eng Sci 1(1)) with the normal of both fields (Nairn 2013, Comput Model Eng
Sci 92(3)), and the body's velocity known instead of solved for. The body's gradient alone has
no direction at a node inside it that the material's stencil reaches: held there at the body's
velocity both ways, the surface of a specimen was lifted with a slip platen. On the
material's velocity relative to the body the body's contact law acts (solver.contact's ``law``:
fixed, slip or friction, separation allowed except for fixed):

    v = v_b + law(v - v_b, n, kind, mu)

on the interpolated velocity (six stages) and on the updated one, after the sides' and the
structures' contacts. The impulse it gives the node's mass is recorded as the body's contact
(after the four sides and the structures, under the material's name), so the reaction on a platen
is a contact force like a structure's. The contact acts where the body's stencil reaches, up to
1.5 cells beyond its particles, as at any MPM contact between bodies: a platen pressing a
specimen meets it about a cell before their particles touch, a fixed offset of the
force-displacement curve.
"""

from solver.contact import FIXED
from solver.materials import RIGID
from solver.runtime import ti
from solver.shape import PAD

#: A node's normal gradient shorter than this fraction of its rigid weight over a cell has no
#: direction: the node is held at the body's velocity both ways.
FLAT_GRADIENT = 1e-6


@ti.data_oriented
class RigidBodies:
    """The rigid materials of ``engine`` (none: every method compiles to nothing).

    Fields: per node the rigid weight ``sum w_ip V_p`` and its gradient (``node_rigid``, vec3), the
    other particles' volume gradient (``node_soil``) and the rigid material reaching it plus one (``node_rigid_mat``, 0: none; where two bodies reach
    one node the higher index holds it); whether the bodies move (``moving``, 1 in dynamic stages).
    The materials' velocities, contact kinds and friction are the material table's columns.
    """

    def __init__(self, engine):
        self.engine = engine
        self.on = engine.materials.rigid
        self.names = engine.materials.rigid_names
        self.count = len(self.names)
        nodes = engine.nodes if self.on else (1, 1)
        self.node_rigid = ti.Vector.field(3, float, nodes)
        self.node_rigid_mat = ti.field(ti.i32, nodes)
        self.node_soil = ti.Vector.field(2, float, nodes)
        self.moving = ti.field(float, ())

    def host_fields(self) -> dict:
        """The fields the engine's set-up moves, by their state names."""
        return {"rigid_moving": self.moving}

    # ---------------------------------------------------------------- particles
    @ti.func
    def is_rigid(self, p):
        """Whether particle p belongs to a rigid body (always False where no material is rigid)."""
        rigid = False
        if ti.static(self.on):
            rigid = self.engine.materials.model[self.engine.mat[p]] == RIGID
        return rigid

    @ti.func
    def velocity(self, mat):
        """A rigid material's velocity now (zero while the bodies stand still)."""
        v = ti.Vector.zero(float, 2)
        if ti.static(self.on):
            v = self.moving[None] * self.engine.materials.rigid_v[mat]
        return v

    @ti.func
    def share(self, p):
        """Rigid particle p's weights and weight gradients (times its volume) to its nodes."""
        if ti.static(self.on):  # called only for a rigid particle: compiled only where there is one
            e = self.engine
            base, fx, w, dw = e._stencil(e.x[p])
            e.to_grid.cover(e, base)
            vol = e.particle_volume(p)
            tag = e.mat[p] + 1
            for i, j in ti.static(ti.ndrange(3, 3)):
                I = base + ti.Vector([i, j])
                grad = ti.Vector([dw[i][0] * w[j][1], w[i][0] * dw[j][1]]) * e.inv_dx
                e.to_grid.add(self.node_rigid, I, vol * ti.Vector([w[i][0] * w[j][1], grad[0], grad[1]]))
                ti.atomic_max(self.node_rigid_mat[I], tag)

    @ti.func
    def move(self, p, dt):
        """Rigid particle p's new position and velocity (its body's); its affine matrix zero."""
        e = self.engine
        v = self.velocity(e.mat[p])
        if ti.static(self.on):
            e.C[p] = ti.Matrix.zero(float, 2, 2)
        return e.x[p] + dt * v, v

    @ti.func
    def soil_share(self, I, vol, grad):
        """A deformable particle's volume gradient share ``V_p grad w_ip`` at node I."""
        if ti.static(self.on):
            self.engine.to_grid.add(self.node_soil, I, vol * grad)

    # ---------------------------------------------------------------- nodes
    @ti.func
    def clear(self, I):
        self.node_rigid[I] = ti.Vector.zero(float, 3)
        self.node_rigid_mat[I] = 0
        self.node_soil[I] = ti.Vector.zero(float, 2)

    @ti.func
    def holds(self, I):
        """Whether a rigid body reaches node I (its contact node)."""
        held = False
        if ti.static(self.on):
            held = self.node_rigid_mat[I] > 0
        return held

    @ti.func
    def hold(self, I, v, mass, record: ti.template()):
        """The body's contact law at node I on the material's velocity ``v`` (the node's
        ``mass``); with ``record`` the impulse goes to the body's contact. Unchanged where no body
        reaches the node."""
        e = self.engine
        out = v
        if ti.static(self.on):
            tag = self.node_rigid_mat[I]
            if tag > 0 and mass > 0.0:
                mat = tag - 1
                table = e.materials
                vb = self.velocity(mat)
                r = self.node_rigid[I]
                grad = ti.Vector([r[1], r[2]]) - self.node_soil[I]
                size = grad.norm()
                kind = table.rigid_kind[mat]
                n = ti.Vector.zero(float, 2)
                if size > FLAT_GRADIENT * r[0] * e.inv_dx:
                    n = grad / size
                else:
                    kind = FIXED
                out = vb + e.contact.law(v - vb, n, kind, table.rigid_mu[mat], 0.0)
                if ti.static(record):
                    point = ti.Vector(e.origin) + ti.cast(I - PAD, float) * e.dx
                    e.contact.record(4 + e.contact.n_structures + table.rigid_index[mat], mass * (out - v), point)
        return out
