"""Periodic left and right sides (docs/solver.md, periodic sides): an infinite slope as one strip.

With periodic sides grid node ``i`` and node ``i + cells`` are one physical node: nodes
``PAD .. PAD + cells - 1`` are the canonical ones, the ``PAD`` ghost layers beyond the left side
and the ``PAD + 1`` beyond the right one (the right side's own line included) their images. The
scatters add to whichever array node a particle's stencil covers; :meth:`PeriodicSides.fold` then
adds every image into its canonical node (a gather: each canonical node reads its images in a
fixed order, so a run repeats bit for bit) and narrows the box of nodes the grid stages work on to
the canonical columns, so that each physical node is updated, and meets a contact, once.
:meth:`PeriodicSides.copy` puts the canonical values back into the images for the stages that read
the grid at the particles' stencils (stress update, G2P) and widens the box over every column, so
that the next reset clears the images too. A particle that leaves across the periodic line comes
in at the other side (:meth:`PeriodicSides.wrap`).

Chosen when the engine is built; on a plain box every method compiles to nothing and the recipe
leaves the fold and copy stages out.
"""


from solver.runtime import ti
from solver.shape import PAD


@ti.data_oriented
class PeriodicSides:
    """The fold, copy and wrap of periodic left and right sides (``on``) for ``engine``'s grid."""

    def __init__(self, engine, on: bool):
        self.engine = engine
        self.on = bool(on)

    # ---------------------------------------------------------------- stages of the recipe
    @ti.func
    def fold_momentum(self, dt, g, damping, damped: ti.template()):
        """After P2G: mass and momentum (and apic-affine's force, fused or apart) into the canonical nodes."""
        e = self.engine
        self.fold(True, ti.static(not e.six_stage and not e._fused(damped)), ti.static(e._fused(damped)))

    @ti.func
    def fold_force(self, dt, g, damping, damped: ti.template()):
        """After the six-stage force pass: the force into the canonical nodes."""
        self.fold(False, True, False)

    @ti.func
    def copy_interpolated(self, dt, g, damping, damped: ti.template()):
        """Before the six-stage stress update: the interpolated velocities into the images."""
        self.copy(True)

    @ti.func
    def copy_updated(self, dt, g, damping, damped: ti.template()):
        """Before G2P: the new velocities into the images."""
        self.copy(False)

    # ---------------------------------------------------------------- the pieces
    @ti.func
    def fold(self, momentum: ti.template(), force: ti.template(), wall_force: ti.template()):
        """Add the images into their canonical nodes: mass and momentum (``momentum``), the force
        (``force``) and the fused schemes' wall force beyond the bottom and top (``wall_force``)."""
        e = self.engine
        cells = ti.static(e.cells[0])
        last = ti.static(e.nodes[0])
        lo = e.lo[None]
        hi = e.hi[None]
        height = ti.max(hi[1] - lo[1], 0)
        for k in range(cells * height):
            i = PAD + k // height
            j = lo[1] + k % height
            for shift in ti.static((-cells, cells)):
                image = i + shift
                if 0 <= image < last:
                    if ti.static(momentum):
                        e.g_mass[i, j] += e.g_mass[image, j]
                        e.g_mom[i, j] += e.g_mom[image, j]
                    if ti.static(force):
                        e.g_f[i, j] += e.g_f[image, j]
        if ti.static(wall_force):
            ghost_f = ti.static(e.walls.ghost_f)
            for i in range(PAD, PAD + cells):
                for side in ti.static((2, 3)):
                    for shift in ti.static((-cells, cells)):
                        image = i + shift
                        if 0 <= image < last:
                            ghost_f[side, i] += ghost_f[side, image]
        e.lo[None][0] = PAD
        e.hi[None][0] = PAD + cells

    @ti.func
    def copy(self, old: ti.template()):
        """Copy the canonical nodes' velocities into their images: the interpolated one (after the
        contact's first correction, which FLIP's increment also uses) with ``old``, else the new
        one; then widen the box over every column."""
        e = self.engine
        cells = ti.static(e.cells[0])
        last = ti.static(e.nodes[0])
        images = ti.static(e.nodes[0] - cells)  # PAD columns on the left, PAD + 1 on the right
        lo = e.lo[None]
        height = ti.max(e.hi[None][1] - lo[1], 0)
        for k in range(images * height):
            image = k // height
            if image >= PAD:
                image += cells
            i = image + cells if image < PAD else image - cells
            j = lo[1] + k % height
            if ti.static(old):
                e.g_v_old[image, j] = e.g_v_old[i, j]
                e.contact.copy_hold(image, i, j)
            else:
                e.g_mom[image, j] = e.g_mom[i, j]
        e.lo[None][0] = 0
        e.hi[None][0] = last

    @ti.func
    def wrap(self, p, x):
        """Particle p's new position ``x`` across the periodic line: in at the other side, its
        reference position ``x0`` shifted with it (displacements go on from where they were)."""
        if ti.static(self.on):
            e = self.engine
            width = ti.static(e.upper[0] - e.origin[0])
            shift = 0.0 * width
            if x[0] < e.origin[0]:
                shift = width
            elif x[0] >= e.upper[0]:
                shift = -width
            if shift != 0.0:
                x[0] += shift
                e.x0[p][0] += shift
        return x
