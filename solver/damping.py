"""Damping in the engine's step: the materials' damping stress and Cundall's local damping.

Material damping (docs/solver.md, material damping): a material with a damping coefficient
``beta`` (s) carries, beside its own stress, a damping stress ``sv`` (plane xx, yy, xy; Pa): a
dashpot on the elastic part of the rate of deformation (Rayleigh's stiffness-proportional damping)
or the stress of a Maxwell arm that relaxes towards it (a standard linear solid tuned to a
frequency; the materials' ``viscous_stress`` computes either). The particle's constitutive update
writes it, the force passes add it to the particle's stress. It is state (a Maxwell arm remembers
it), so a checkpoint holds ``sv``; where no material is damped the field has one row and every
method compiles to nothing.

Local damping (Cundall's, the stage's ``damping`` factor): each component of a free node's
unbalanced force is reduced by ``damping * |f|`` against the node's motion. It is not applied at
the contact nodes, where most of the force is the load the contact carries (the weight of the
material above a base node), which the contact's reaction balances only after this step: damping
it there took up to ``damping`` times that load off or put it on with the sign of the node's small
residual velocity, and a block resting near its friction limit crept down its base.
"""


from solver.runtime import ti


@ti.data_oriented
class Damping:
    """The materials' damping stress (``viscous``: some material may be damped) and local damping.

    Owns ``sv`` (n, 3) float, Pa: each particle's damping stress (one row when not ``viscous``).
    """

    def __init__(self, n_particles: int, viscous: bool):
        self.viscous = bool(viscous)
        self.sv = ti.Vector.field(3, float, max(1, n_particles) if self.viscous else 1)

    def host_fields(self) -> dict:
        """The fields the engine's state holds, by their state names."""
        return {"sv": self.sv}

    @ti.func
    def update(self, materials: ti.template(), p, mat, D, W, dt, before, after, yielded):
        """Particle p's damping stress after its constitutive update at strain rate ``D`` and spin
        ``W`` (its stress ``before`` and ``after`` the update, ``yielded`` where it returned)."""
        if ti.static(self.viscous):
            self.sv[p] = materials.viscous_stress(mat, self.sv[p], D, W, dt, before, after, yielded)

    @ti.func
    def add_stress(self, p, sig):
        """``sig`` (2x2, Pa) with particle p's damping stress added."""
        out = sig
        if ti.static(self.viscous):
            d = self.sv[p]
            out += ti.Matrix([[d[0], d[2]], [d[2], d[1]]])
        return out

    @ti.func
    def local(self, f, v, damping, held):
        """Node force ``f`` after local damping ``damping`` at a node moving with ``v``; unchanged at
        a contact node (``held``) and without damping."""
        out = f
        if damping > 0.0 and not held:
            for d in ti.static(range(2)):
                out[d] -= damping * ti.abs(f[d]) * ti.math.sign(v[d])
        return out
