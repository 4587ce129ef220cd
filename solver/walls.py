"""The closed sides as mirror planes, and a friction side's Coulomb law by wall column.

A closed side (fixed, slip or friction) sits on a node line. The ghost node one cell beyond it is
reached only by particles within a cell of the wall; the node one cell inside (the mirror node)
misses the share that material beyond the wall would give it, so a uniform stress pushes on it and
the stress oscillates in the boundary cells. The mirror-image method supplies that share
(docs/solver.md, walls as mirror planes):

- mirror forces: the ghost node's force, mirrored, is added at the mirror node (what mirror-image
  particles beyond the wall would give it), and its opposite at the wall node, so that the grid's
  momentum is unchanged and the whole reaction passes through the contact law at the wall's nodes
  (its normal impulse, and so its friction, and the recorded contact force);
- mirror ghosts: after each contact pass the ghost node's velocity becomes the mirror image of the
  mirror node's while the material there approaches the wall, so that the velocity gradient of the
  particles in the wall cell is that of the mirror-image field.

Wall columns: the wall node and the ghost nodes beyond it are one contact point (the ghosts carry
the wall node's support beyond the wall), so a friction side's Coulomb law acts on each column's
summed tangential momentum and normal impulse. Decided node by node, the base's reaction was split
between the wall row and the ghost row with different ratios of tangential to normal force, and a
stiff block resting 5 degrees from its friction limit slid away.

The sides' kinds and friction, the contact law and the record of impulses are the contact
component's (solver.contact); this one owns the ghost nodes' force of the fused P2G (``ghost_f``)
and the columns' normal impulses (``column_dvn``).
"""


from solver.contact import FIXED, FRICTION, SLIP
from solver.runtime import mat_vec, ti
from solver.shape import PAD, bspline, bspline_slope


@ti.data_oriented
class MirrorWalls:
    """Mirror forces, mirror ghosts and wall columns of ``engine``'s four sides.

    Owns ``column_dvn`` (4, nodes along, PAD + 1) float, m/s: a friction side's normal impulse per
    unit mass at each node of a wall column (layer 0 = the wall line), and ``ghost_f`` (4, nodes
    along, 2) float, N/m: apic-affine's force at the ghost nodes beyond each side, summed apart from
    the fused momentum (one row where no scheme fuses it).
    """

    def __init__(self, engine):
        self.engine = engine
        along = max(engine.nodes)
        self.column_dvn = ti.field(float, (4, along, PAD + 1))
        self.ghost_f = ti.Vector.field(2, float, (4, along) if not engine.six_stage else (1, 1))

    # ---------------------------------------------------------------- stages of the recipe
    @ti.func
    def forces(self, dt, g, damping, damped: ti.template()):
        """Mirror forces: each ghost node's force, mirrored, at its mirror node, its opposite at
        the wall node."""
        e = self.engine
        self._mirror_forces(dt, ti.static(e._fused(damped)))

    @ti.func
    def ghosts_interpolated(self, dt, g, damping, damped: ti.template()):
        """Mirror ghosts on the interpolated velocity (six stages; every scheme's particles receive
        this correction, an impulse of the contact)."""
        self._mirror_ghosts(True)

    @ti.func
    def ghosts_updated(self, dt, g, damping, damped: ti.template()):
        """Mirror ghosts on the updated velocity."""
        self._mirror_ghosts(False)

    @ti.func
    def columns_interpolated(self, dt, g, damping, damped: ti.template()):
        """Wall columns on the interpolated velocity (six stages)."""
        self._wall_columns(True)

    @ti.func
    def columns_updated(self, dt, g, damping, damped: ti.template()):
        """Wall columns on the updated velocity."""
        self._wall_columns(False)

    # ---------------------------------------------------------------- called by the contact law and P2G
    @ti.func
    def hold_in_column(self, side, along, layer, dvn):
        """The contact law removed ``dvn`` (per unit mass) of normal velocity at the node ``layer``
        cells beyond friction side ``side``'s line: the column's Coulomb law acts on it."""
        self.column_dvn[side, along, layer] = dvn

    @ti.func
    def ghost_particle(self, p, g):
        """Add particle p's force at ghost nodes beyond closed walls to ``ghost_f``.

        The apic-affine P2G fuses the forces into the momentum; this part of its pass keeps the
        ghost nodes' force apart too (per side, along the wall), so that the mirror forces can pass
        the wall's reaction through the contact law. It reads the stress and density the
        particle's update left. Only particles within a cell of a closed wall reach a ghost node;
        the others cost one test each. A corner ghost (beyond two walls) keeps the fused form.
        """
        e = self.engine
        c = e.contact
        base, fx, w, dw = e._stencil(e.x[p])
        ghost_lo = ti.Vector([0, 0])
        ghost_hi = ti.Vector([0, 0])
        for d in ti.static(range(2)):
            ghost_lo[d] = base[d] == PAD - 1 and c.closed(c.bc_kind[2 * d])
            ghost_hi[d] = base[d] == PAD + e.cells[d] - 1 and c.closed(c.bc_kind[2 * d + 1])
        if ghost_lo[0] or ghost_lo[1] or ghost_hi[0] or ghost_hi[1]:
            wet = e.water_state(p)
            sig = e.force_stress(p, wet)
            m = e.particle_mass(p, wet)
            vol = e.particle_volume(p)
            for k in range(9):  # a runtime loop: this rare path compiles once, not nine times
                i = k // 3
                j = k % 3
                x_side = -1
                y_side = -1
                if i == 0 and ghost_lo[0]:
                    x_side = 0
                if i == 2 and ghost_hi[0]:
                    x_side = 1
                if j == 0 and ghost_lo[1]:
                    y_side = 2
                if j == 2 and ghost_hi[1]:
                    y_side = 3
                if (x_side >= 0) != (y_side >= 0):
                    wx = bspline(fx[0], i)
                    wy = bspline(fx[1], j)
                    grad = ti.Vector([bspline_slope(fx[0], i) * wy,
                                      wx * bspline_slope(fx[1], j)]) * e.inv_dx
                    force = -vol * mat_vec(sig, grad) + wx * wy * m * g
                    if ti.static(e.wet):
                        force += wx * wy * e.water_force(vol, wet)
                    if ti.static(e.loaded):
                        force += wx * wy * e.loads.force(p)
                    I = base + ti.Vector([i, j])
                    # atomic where threads share the pass: few particles get here. In the split
                    # scatter a ghost node, like any node, belongs to one band.
                    if x_side >= 0:
                        self.ghost_f[x_side, I[1]] += force
                    else:
                        self.ghost_f[y_side, I[0]] += force

    # ---------------------------------------------------------------- the pieces
    @ti.func
    def _wall_pairs(self, axis: ti.template(), k):
        """Side, ghost node and mirror node of the k-th node along the two walls normal to ``axis``.

        Both walls of an axis share one loop (k < 2 * nodes along the wall): a loop is a task
        with a fixed cost of its own, and two opposite walls never touch the same nodes.
        """
        e = self.engine
        along = ti.static(e.nodes[1 - axis])
        high = k // along
        side = 2 * axis + high
        wall = PAD + high * ti.static(e.cells[axis])
        step = 1 - 2 * high  # +1 into the domain from the low wall, -1 from the high one
        ghost = ti.Vector([0, 0])
        mirror = ghost
        ghost[axis] = wall - step
        mirror[axis] = wall + step
        ghost[1 - axis] = k % along
        mirror[1 - axis] = k % along
        return side, ti.cast(step, float), ghost, mirror

    @ti.func
    def _wall_columns(self, old: ti.template()):
        """Coulomb friction of a friction side, column by column (docs/solver.md, contact).

        The law acts on the summed tangential momentum ``P`` and normal impulse ``J`` of the
        column's approaching nodes (the contact law removed their normal part and left ``dvn``, per
        unit mass, in ``column_dvn``, and the mirror image added the ghost's): stick when ``|P| <=
        mu J`` (every such node stops along the wall), else every such node slows by the same ``mu
        J / M`` (``M`` their mass), so the column loses exactly ``mu J`` of momentum and its nodes
        keep their relative velocities."""
        e = self.engine
        c = e.contact
        for axis in ti.static(range(2)):
            ti.loop_config(serialize=e.plain)
            for k in range(2 * e.nodes[1 - axis]):
                along = k % e.nodes[1 - axis]
                high = k // e.nodes[1 - axis]
                side = 2 * axis + high
                if c.bc_kind[side] == FRICTION:
                    wall = PAD + high * ti.static(e.cells[axis])
                    step = 1 - 2 * high
                    mass = 0.0
                    momentum = 0.0
                    normal = 0.0
                    for layer in ti.static(range(PAD + 1)):
                        J = self._column_node(axis, wall, step, layer, along)
                        dvn = self.column_dvn[side, along, layer]
                        m = e.g_mass[J]
                        if dvn > 0.0 and m > 0.0:
                            vt = e.g_v_old[J][1 - axis] if ti.static(old) else e.g_mom[J][1 - axis]
                            mass += m
                            momentum += m * vt
                            normal += m * dvn
                    if mass > 0.0:
                        mu = c.bc_mu[side]
                        speed = ti.abs(momentum)
                        slide = speed > mu * normal
                        after = 0.0
                        if slide:
                            after = momentum / mass * (speed - mu * normal) / speed
                        for layer in ti.static(range(PAD + 1)):
                            J = self._column_node(axis, wall, step, layer, along)
                            dvn = self.column_dvn[side, along, layer]
                            m = e.g_mass[J]
                            if dvn > 0.0 and m > 0.0:
                                v = e.g_v_old[J] if ti.static(old) else e.g_mom[J]
                                dv = -v[1 - axis]  # stick: the column stops along the wall
                                if slide:  # every node of the column slows by the same mu J / M
                                    dv = after - momentum / mass
                                v[1 - axis] += dv
                                impulse = ti.Vector.zero(float, 2)
                                impulse[1 - axis] = m * dv
                                c.record(side, impulse, c.side_point(side, J))
                                if ti.static(old):
                                    e.g_v_old[J] = v
                                else:
                                    e.g_mom[J] = v
                    for layer in ti.static(range(PAD + 1)):
                        self.column_dvn[side, along, layer] = 0.0

    @ti.func
    def _column_node(self, axis: ti.template(), wall, step, layer: ti.template(), along):
        """The node ``layer`` cells beyond the wall line ``wall`` (``step`` +1 into the domain from
        the low side, -1 from the high one) at position ``along`` on a wall across ``axis``."""
        J = ti.Vector([0, 0])
        J[axis] = wall - layer * step
        J[1 - axis] = along
        return J

    @ti.func
    def _mirror_ghosts(self, old: ti.template()):
        """The ghost node's velocity across the wall becomes the mirror image of the mirror node's
        while the material there approaches the wall and the image pushes the ghost into the
        material (both components for a fixed wall); the momentum this changes is the wall's
        impulse too. On a friction wall its normal part brings Coulomb friction with it: through the
        ghost's wall column (``column_dvn``, :meth:`_wall_columns` runs next), or at the ghost
        alone (reduced by at most mu times it, never reversed) at a corner of the box."""
        e = self.engine
        c = e.contact
        for axis in ti.static(range(2)):
            ti.loop_config(serialize=e.plain)
            for k in range(2 * e.nodes[1 - axis]):
                side, inward, ghost, mirror = self._wall_pairs(axis, k)
                kind = c.bc_kind[side]
                mass = e.g_mass[ghost]
                if c.closed(kind) and mass > 0.0 and e._in_box(ghost) and e._in_box(mirror):
                    vm = e.g_v_old[mirror] if ti.static(old) else e.g_mom[mirror]
                    vg = e.g_v_old[ghost] if ti.static(old) else e.g_mom[ghost]
                    mu = c.bc_mu[side]
                    column = False
                    if kind == FRICTION:
                        column = c.closed_sides_at(ghost) == 1  # not a corner of the box
                    if column:
                        mu = 0.0  # the ghost is part of its wall column: friction there (_wall_columns)
                    new = self._ghost_image(kind, axis, inward, vm, vg, mu)
                    if column:
                        self.column_dvn[side, k % e.nodes[1 - axis], 1] += (new[axis] - vg[axis]) * inward
                    c.record(side, mass * (new - vg), c.side_point(side, ghost))
                    if ti.static(old):
                        e.g_v_old[ghost] = new
                    else:
                        e.g_mom[ghost] = new

    @ti.func
    def _ghost_image(self, kind, axis: ti.template(), inward, vm, vg, mu):
        """The ghost node's new velocity (see :meth:`_mirror_ghosts`) from the mirror node's ``vm``
        and its own ``vg``, for a wall across ``axis`` whose material lies towards ``inward``.
        Never a pull: where the ghost already moves into the material faster than the image, the
        image would hold it back, a tension on the wall that the friction, taken from the pushing
        impulses, did not see (docs/solver.md, walls as mirror planes)."""
        new = vg
        if kind == FIXED:
            new = -vm
        elif vm[axis] * inward < 0.0:
            dvn = (-vm[axis] - vg[axis]) * inward
            if dvn > 0.0:
                new[axis] = -vm[axis]
                vt = new[1 - axis]
                new[1 - axis] = ti.math.sign(vt) * ti.max(ti.abs(vt) - mu * dvn, 0.0)
        return new

    @ti.func
    def _mirror_forces(self, dt, fused: ti.template()):
        e = self.engine
        c = e.contact
        for axis in ti.static(range(2)):
            # a few hundred nodes: on a CPU with few threads one thread beats waking the pool
            ti.loop_config(serialize=e.plain)
            for k in range(2 * e.nodes[1 - axis]):
                side, inward, ghost, mirror = self._wall_pairs(axis, k)
                along = k % e.nodes[1 - axis]
                if c.closed(c.bc_kind[side]) and e._in_box(ghost) and e._in_box(mirror):
                    wall = (ghost + mirror) // 2
                    # the ghost's force, mirrored: across the wall always reversed; along it kept
                    # for a slip wall (symmetric image) and reversed where the wall holds the
                    # material along it (fixed, friction: antisymmetric image)
                    flip = ti.Vector([-1.0, -1.0])
                    if c.bc_kind[side] == SLIP:
                        flip[1 - axis] = 1.0
                    if ti.static(fused):  # apic-affine: the ghost's force was summed apart
                        f = flip * self.ghost_f[side, along] * dt
                        e.g_mom[mirror] += f
                        e.g_mom[wall] -= f
                    else:
                        f = flip * e.g_f[ghost]
                        e.g_f[mirror] += f
                        e.g_f[wall] -= f
                if ti.static(fused):
                    self.ghost_f[side, along] = ti.Vector.zero(float, 2)  # ready for the next step
