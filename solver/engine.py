"""The MPM engine: particle and grid state, and one step as a recipe of named stages.

Symbols inside kernels (SI): ``x`` particle position (m), ``v`` velocity (m/s), ``C`` APIC affine
matrix (1/s), ``s`` stress vec4 (xx, yy, xy, zz; Pa, tension positive), ``m`` mass (kg/m),
``rho`` density (kg/m3), ``eps_p`` equivalent plastic strain (-), ``dx`` cell size (m),
``dt`` time step (s), ``g`` gravity (m/s2). Grid node ``(i, j)`` sits at
``origin + (i - PAD, j - PAD) * dx``; ``PAD`` ghost layers keep every particle's 3x3 stencil
inside the arrays. Quadratic B-splines throughout (solver.shape); APIC inertia ``D_p = dx^2 / 4 I``.
Equation numbers are those of Zhong et al. (2022).

Schemes (chosen once, at construction, and compiled in with ``ti.static``):

- ``apic-affine``: improved MPM-APIC, four stages: reset grid; P2G with the stress update (strain
  rate and spin from the particle's own C, eqs 29-30) and the force scatter in the same pass
  (:meth:`Engine.p2g_with_stress`); grid update (:meth:`Engine.grid_update`); G2P
  (:meth:`Engine.g2p`).
- ``apic``: MPM-APIC, six stages: reset grid; P2G of mass and APIC momentum (eqs 14-15); grid
  velocity; stress update from the grid's velocity gradient and force scatter; grid momentum
  update; G2P (eqs 16-17, 28).
- ``mpm``: the same six stages with FLIP's transfer (from contact nodes the new velocity itself,
  PIC there, see :meth:`Engine.g2p`).

Components, chosen once at construction, add their stages to the recipe and are called from the
method's stages (each in its own module): ``contact`` (solver.contact: the contact law of the
closed sides and the structures, their normals, mirror images and the contact tally), ``walls``
(solver.walls: the closed sides as mirror planes and a friction side's wall columns),
``periodic`` (solver.periodic: periodic left and right sides), ``damping`` (solver.damping:
the materials' damping stress and local damping), ``loads`` (solver.loads: the surcharges'
forces on the surface particles, added where the weight is) and ``rigid`` (solver.rigid: rigid
bodies driven at a velocity, whose particles give their nodes a contact instead of mass). :attr:`Engine.recipe` lists the step's stages.

The particle passes (P2G; stress and force for mpm and apic) are written per particle
(``_update_particle``: the particle's own constitutive update; ``_add_particle``: its shares to
the grid); how those shares reach shared grid nodes on a CPU (serial, split, atomic) is the
scatter strategy's, chosen once at construction (``self.to_grid``, solver/scatter.py), which runs
the pass loops and makes every add.

Grid passes run only over the bounding box of the particles' stencils (built in the scatter), so
empty parts of the domain cost nothing.
"""


import numpy as np

from solver.config import SIDES, Boundary, Grid, Material, Structure
from solver.contact import (
    BOUNDARY_CODES,
    FIXED,
    FRICTION,
    OPEN,
    PERIODIC,
    PUSH_OUT_CELLS,
    SLIP,
    Contacts,
)
from solver.damping import Damping
from solver.fieldio import FieldIO
from solver.materials import MaterialTable
from solver.periodic import PeriodicSides
from solver.rigid import RigidBodies
from solver.runtime import mat_vec, outer, ti, transpose
from solver.scatter import BIG, SCATTER_STATE, make_scatter
from solver.shape import PAD
from solver.walls import MirrorWalls

__all__ = [
    "BOUNDARY_CODES",
    "DENSITY_FLOOR",
    "FIXED",
    "FRICTION",
    "OPEN",
    "PAD",
    "PERIODIC",
    "PUSH_OUT_CELLS",
    "SLIP",
    "Engine",
]

#: The particle density never falls below this fraction of its material's (docs/solver.md, schemes:
#: eq 24 alone let grains torn off a cohesionless mass expand without bound and, landing, be
#: stiffer per mass than the time step allows)
DENSITY_FLOOR = 0.5


@ti.data_oriented
class Engine:
    """State and step kernels of one MPM run (needs an acquired runtime).

    ``damping=False`` promises that no step will use local damping, which lets ``apic-affine``
    fuse the forces into the momentum and skip the grid force field (less memory).
    ``scatter`` chooses how particles add to grid nodes (``auto``, ``atomic``, ``serial``, ``split``;
    see solver/scatter.py; ``bands``: the split scatter's band count).
    ``structures``: rigid polygons inside the domain, contacts like the closed sides.
    ``viscous``: some material may carry a damping stress (default: one of ``materials`` does).
    ``softening``: some material may soften (default: one of ``materials`` does).
    ``volumetric_averaging``: each particle's volumetric strain rate is the volume-weighted
    average of its neighbours' over its stencil (the remedy for volumetric locking, see
    :meth:`average_dilatation`).

    Contacts (see docs/solver.md): the closed sides (index 0-3 in :data:`SIDES` order) and the
    structures (index 4 on). Each step adds, per contact, the impulse the material exerts on it
    (N s/m, x and y) and keeps the largest force of any step; :meth:`read_contacts` returns both
    and starts them afresh.
    """

    def __init__(self, grid: Grid, materials: tuple[Material, ...], n_particles: int, scheme: str,
                 np_float=np.float32, speed_bound_m_s: float = 1e30, remove_unstable: bool = False,
                 damping: bool = True, scatter: str = "auto", bands: int | None = None,
                 structures: tuple[Structure, ...] = (), viscous: bool | None = None, water=None,
                 softening: bool | None = None, volumetric_averaging: bool = False, loads=None):
        if scheme not in ("mpm", "apic", "apic-affine"):
            raise ValueError(f"unknown scheme {scheme!r}; allowed: mpm, apic, apic-affine")
        self.scheme = scheme
        self.np_float = np_float
        self.n = int(n_particles)
        self.cells = grid.cells
        self.dx = float(grid.cell_size_m)
        self.inv_dx = 1.0 / self.dx
        self.origin = (float(grid.origin_m[0]), float(grid.origin_m[1]))
        self.upper = (self.origin[0] + self.cells[0] * self.dx, self.origin[1] + self.cells[1] * self.dx)
        self.nodes = (self.cells[0] + 1 + 2 * PAD, self.cells[1] + 1 + 2 * PAD)
        # how particle contributions reach the grid (solver/scatter.py), chosen once
        self.to_grid = make_scatter(scatter, self.n, self.nodes, bands)
        self.scatter = self.to_grid.name
        # plain adds: no two threads ever add to one value, and the short wall loops run in one thread
        self.plain = self.to_grid.plain
        self.remove_unstable = bool(remove_unstable)
        problem = grid.periodic_problem()
        if problem:
            raise ValueError(problem)
        self.materials = MaterialTable(materials, np_float, shared_io=True, cell_size_m=self.dx,
                                       softening=softening)  # moved by self._io
        self.six_stage = scheme != "apic-affine"

        # particles
        n = max(1, self.n)
        self.x = ti.Vector.field(2, float, n)
        self.x0 = ti.Vector.field(2, float, n)
        self.v = ti.Vector.field(2, float, n)
        self.C = ti.Matrix.field(2, 2, float, n)
        self.s = ti.Vector.field(4, float, n)
        self.m = ti.field(float, n)
        self.rho = ti.field(float, n)
        self.eps_p = ti.field(float, n)
        self.mat = ti.field(ti.i32, n)
        self.active = ti.field(ti.i8, n)
        self.yielded = ti.field(ti.i8, n)
        #: volumetric averaging: each particle's own volumetric strain rate (1/s) and, per node,
        #: the stencil sums of volume and of volume times that rate (compiled out where off)
        self.averaging = bool(volumetric_averaging)
        self.dil = ti.field(float, n if self.averaging else 1)

        # the components, chosen once (each compiles to nothing where it is off)
        self.periodic = PeriodicSides(self, grid.periodic)
        self.damping = Damping(self.n, any(m.damping_beta_s > 0.0 for m in materials) if viscous is None
                               else bool(viscous))
        self.rigid = RigidBodies(self)
        self.contact = Contacts(self, structures, self.rigid.count)
        self.walls = MirrorWalls(self)
        #: ground water (solver.groundwater.GroundWater, built by the caller where a run has water;
        #: None: dry, and none of it is compiled in)
        self.water = water
        self.wet = water is not None
        #: surcharges (solver.loads.Loads, built by the caller where a run has one; None: none compiled in)
        self.loads = loads
        self.loaded = loads is not None
        self.structures = self.contact.structures
        self.n_structures = self.contact.n_structures
        self.n_contacts = self.contact.n_contacts

        # Grid: what every scheme needs, plus the force and old-velocity fields only where used.
        # ``g_mom`` holds momentum after P2G and the new velocity after the grid update.
        # structures: the grid force is kept apart in every scheme, for their mirror forces
        self.separate_forces = self.six_stage or bool(damping) or bool(structures)
        self.g_mass = ti.field(float, self.nodes)
        self.g_mom = ti.Vector.field(2, float, self.nodes)
        self.g_f = ti.Vector.field(2, float, self.nodes if self.separate_forces else (1, 1))
        self.g_v_old = ti.Vector.field(2, float, self.nodes if self.six_stage else (1, 1))
        self.g_dil = ti.Vector.field(2, float, self.nodes if self.averaging else (1, 1))
        # node box [lo, hi) the last scatter wrote (every node outside it holds zeros): built in the
        # scatter, which works out every particle's stencil anyway, and cleared by the next reset
        self.lo = ti.Vector.field(2, ti.i32, ())
        self.hi = ti.Vector.field(2, ti.i32, ())

        self.speed_bound = ti.field(float, ())
        self.lost = ti.field(ti.i32, ())
        self.unstable = ti.field(ti.i32, ())
        self.diag = ti.field(float, 8)

        # every field the host reads or writes, moved by one kernel (solver.fieldio: one kernel
        # per field, as Taichi's own to_numpy / from_numpy are, costs start-up time in every process)
        own = {name: getattr(self, name) for name in self.HOST_FIELDS if hasattr(self, name)}
        host = {**own, **self.damping.host_fields(), **self.contact.host_fields(), **self.rigid.host_fields()}
        assert set(host) == set(self.HOST_FIELDS), sorted(set(host) ^ set(self.HOST_FIELDS))
        io_fields = {**{name: host[name] for name in self.HOST_FIELDS}, **self.to_grid.state_fields()}
        clash = set(io_fields) & set(self.materials.columns)
        assert not clash, f"engine and material fields share names: {sorted(clash)}"
        self._io = FieldIO({**io_fields, **self.materials.columns})
        self.materials.use_io(self._io)
        self.set_boundaries(grid)
        self._io.write(self.contact.geometry_values(np_float))
        self._io.write({"speed_bound": speed_bound_m_s})

    # ------------------------------------------------------------------ set-up and state I/O
    #: Every particle field of the solver state (a checkpoint holds these, the counters and the
    #: scatter strategy's ``STATE``, e.g. the split scatter's plan; the grid is rebuilt from the
    #: particles at every step). ``sv`` is the damping component's, the contact fields the
    #: contact component's: the state names stay the engine's.
    PARTICLE_STATE = ("x", "x0", "v", "C", "s", "sv", "m", "rho", "eps_p", "mat", "active", "yielded")
    COUNTER_STATE = ("lost", "unstable", "contact_impulse", "contact_moment", "contact_peak", "node_hold",
                     "hold_step")
    #: Every field of the engine and its components the host reads or writes (:meth:`state`,
    #: :meth:`load_state` and the set-up); the scatter strategy's ``STATE`` fields are moved with them.
    HOST_FIELDS = PARTICLE_STATE + COUNTER_STATE + (
        "contact_step", "speed_bound", "bc_kind", "bc_mu", "st_kind", "st_mu", "edge_a", "edge_b",
        "st_edges", "st_box", "node_struct", "node_normal", "node_normal_b", "node_sd", "node_zone", "node_far",
        "st_zone_box", "rigid_moving")

    @property
    def viscous(self) -> bool:
        """Whether some material may carry a damping stress (compiled in)."""
        return self.damping.viscous

    def set_boundaries(self, grid: Grid) -> None:
        """The kinds and friction of the four sides (data: no recompilation; whether the left and
        right sides are periodic is fixed at construction)."""
        if grid.periodic != self.periodic.on or grid.periodic_problem():
            raise ValueError(grid.periodic_problem() or "periodic sides are chosen when the engine is built")
        self._io.write(self.contact.side_values(tuple(grid.boundary(side) for side in SIDES)))

    def set_structure_contacts(self, contacts: tuple[Boundary, ...]) -> None:
        """The contact of each structure, in order (data: the geometry stays as constructed)."""
        self._io.write(self.contact.structure_values(tuple(contacts)))

    @property
    def contact_names(self) -> tuple[str, ...]:
        """Names of the contacts in engine order: the four sides, the structures, then the rigid
        bodies (their materials' names)."""
        return SIDES + tuple(st.name for st in self.structures) + self.rigid.names

    def set_rigid_moving(self, moving: bool) -> None:
        """Whether the rigid bodies move at their velocities (dynamic stages) or stand still."""
        self._io.write({"rigid_moving": 1.0 if moving else 0.0})

    def read_contacts(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Impulse on each contact since the last read (N s/m, (n_contacts, 2)), the largest force
        of one step in that time (|F|, Fx, Fy in N/m, (n_contacts, 3)) and the impulse's moment
        about the grid origin (N s, (n_contacts,), counter-clockwise positive); all start afresh.
        Impulse, force and moment are what the material exerts on the contact; each node's share
        acts at its point on the contact's surface (a side's line, a structure's face)."""
        got = self._io.read(("contact_impulse", "contact_peak", "contact_moment"))
        self._io.write({"contact_impulse": 0.0, "contact_peak": 0.0, "contact_moment": 0.0})
        return got["contact_impulse"], got["contact_peak"], got["contact_moment"]

    def load_particles(self, positions_m, volumes_m2, material_ids, velocities_m_s=None,
                       densities_kg_m3=None) -> None:
        """Set the initial particle state (stress zero, C zero, all active)."""
        f = self.np_float
        pos = np.asarray(positions_m, dtype=f).reshape(-1, 2)
        mat = np.asarray(material_ids, dtype=np.int32)
        rho0 = self.materials.host["rho0"][mat] if densities_kg_m3 is None else np.asarray(densities_kg_m3)
        vel = np.zeros_like(pos) if velocities_m_s is None else np.asarray(velocities_m_s, dtype=f)
        self._io.write({
            "x": pos, "x0": pos, "v": vel, "C": 0.0, "s": 0.0, "sv": 0.0,
            "m": (np.asarray(volumes_m2, dtype=np.float64) * rho0).astype(f),
            "rho": rho0.astype(f), "eps_p": 0.0, "mat": mat, "active": 1, "yielded": 0,
            "lost": 0, "unstable": 0, "contact_step": 0.0, "contact_impulse": 0.0, "contact_moment": 0.0,
            "contact_peak": 0.0,
            "node_hold": -1, "hold_step": 0,
            **self.to_grid.start_state(),  # the strategy forgets what earlier steps taught it
        })

    def set_stress(self, stress: np.ndarray) -> None:
        """Overwrite the particle stresses, (N, 4) Pa; a new stress state, so the damping's memory
        of past deformation rates (the Maxwell arm's stress) starts from zero with it."""
        self._io.write({"s": np.asarray(stress, dtype=self.np_float), "sv": 0.0})

    def set_velocity(self, velocity: np.ndarray, affine: np.ndarray | None = None) -> None:
        self._io.write({"v": np.asarray(velocity, dtype=self.np_float),
                        "C": 0.0 if affine is None else np.asarray(affine, dtype=self.np_float)})

    def bring_to_rest(self) -> None:
        """The quasi-static state an initial-stress stage ends in: velocities, affine matrices and
        the damping's memory of past rates (the Maxwell arm's stress, which would otherwise push
        on a body whose velocities were dropped) set to zero, displacements measured from here."""
        self._io.write({"v": 0.0, "C": 0.0, "sv": 0.0, "x0": self._io.read(("x",))["x"]})

    def state(self, names: tuple[str, ...] | None = None) -> dict[str, np.ndarray]:
        """Copies of the named state fields (default: everything a checkpoint needs), as
        ``field.to_numpy()`` gives them; any of :data:`HOST_FIELDS` may be named."""
        return self._io.read(self.PARTICLE_STATE + self.COUNTER_STATE + self.to_grid.STATE
                             if names is None else names)

    def load_state(self, state: dict[str, np.ndarray]) -> None:
        """Restore fields saved by :meth:`state` (same particle count, scheme and precision).

        The fields of another scatter strategy's ``STATE`` (a checkpoint of a run with another
        scatter) are skipped: they order sums, they hold no physics.
        """
        allowed = self.PARTICLE_STATE + self.COUNTER_STATE + self.to_grid.STATE
        kept = {}
        for name, value in state.items():
            if name in SCATTER_STATE and name not in self.to_grid.STATE:
                continue
            if name not in allowed:
                raise ValueError(f"unknown state field {name!r}")
            expected = self._io.shapes[name]
            if name == "sv" and tuple(np.shape(value)) != expected and len(np.shape(value)) == 2 \
                    and 1 in (np.shape(value)[0], expected[0]):
                value = 0.0  # from a run without damping (or into one): the damping starts from rest
            elif tuple(np.shape(value)) != expected:
                raise ValueError(f"state field {name!r} has shape {np.shape(value)}, the engine {expected}")
            kept[name] = value
        self._io.write(kept)


    # ------------------------------------------------------------------ the step
    def step(self, dt: float, gravity: tuple[float, float], damping: float = 0.0) -> None:
        """Advance one explicit step of ``dt`` seconds: the whole recipe in one kernel launch."""
        if damping > 0.0 and not self.separate_forces:
            raise ValueError("this engine was built without damping support (damping=False)")
        self._step(float(dt), float(gravity[0]), float(gravity[1]), float(damping), damping > 0.0)

    def step_by_stage(self, dt: float, gravity: tuple[float, float], damping: float = 0.0) -> None:
        """The same step with one launch per stage, in recipe order (for profiling stage by stage)."""
        if damping > 0.0 and not self.separate_forces:
            raise ValueError("this engine was built without damping support (damping=False)")
        for stage in self.recipe:
            self._stage_kernel(stage, float(dt), float(gravity[0]), float(gravity[1]), float(damping), damping > 0.0)

    @property
    def recipe(self) -> tuple[str, ...]:
        """The names of the stages of one step, in order (see :meth:`_stages`)."""
        return tuple(name for name, _ in self._stages())

    def _stages(self) -> tuple[tuple[str, object], ...]:
        """One step: the method's stages with the components' in their places, as (name, stage).

        Every stage is a ``ti.func`` taking ``(dt, g, damping, damped)``; a component that is off
        (no periodic sides, no structures, no zone nodes near a structure's vertex) leaves its
        stages out. The contact law acts inside the grid stages (on the interpolated and on the
        updated velocity); the mirror walls and wall columns follow each of them.
        """
        c, walls, periodic = self.contact, self.walls, self.periodic
        if self.six_stage:  # mpm, apic: MPM-APIC's six stages
            stages = (
                ("ground water", self.water_step, self.wet),
                ("surcharges", self.loads_step, self.loaded),
                ("reset grid", self.reset_grid, True),                           # 1
                ("corner normals", c.material_normals, c.has_zone),
                ("P2G momentum", self.p2g_momentum, True),                      # 2: eqs 14-15
                ("periodic fold", periodic.fold_momentum, periodic.on),
                ("grid velocity", self.grid_velocity, True),                    # 3, with the contact law
                ("mirror walls (old)", walls.ghosts_interpolated, True),
                ("wall columns (old)", walls.columns_interpolated, True),
                ("periodic copy (velocity)", periodic.copy_interpolated, periodic.on),
                ("volumetric average", self.average_dilatation, self.averaging),
                ("stress and force", self.stress_and_force, True),              # 4: eqs 9-10, 22-27
                ("periodic fold (force)", periodic.fold_force, periodic.on),
                ("mirror forces", walls.forces, True),
                ("structure mirror forces", c.structure_forces, self.n_structures > 0),
                ("grid update", self.grid_update, True),                        # 5: eq 20, contact law
                ("mirror walls", walls.ghosts_updated, True),
                ("wall columns", walls.columns_updated, True),
                ("periodic copy", periodic.copy_updated, periodic.on),
                ("G2P", self.g2p, True),                                        # 6: eqs 16-17, 28
                ("contact tally", c.tally, True),
            )
        else:  # apic-affine: improved MPM-APIC's four stages
            stages = (
                ("ground water", self.water_step, self.wet),
                ("surcharges", self.loads_step, self.loaded),
                ("reset grid", self.reset_grid, True),                           # 1
                ("corner normals", c.material_normals, c.has_zone),
                ("volumetric average", self.average_dilatation, self.averaging),
                ("P2G with stress and force", self.p2g_with_stress, True),      # 2: eqs 14-15, 24-30
                ("periodic fold", periodic.fold_momentum, periodic.on),
                ("mirror forces", walls.forces, True),
                ("structure mirror forces", c.structure_forces, self.n_structures > 0),
                ("grid update", self.grid_update, True),                        # 3: eq 20, contact law
                ("mirror walls", walls.ghosts_updated, True),
                ("wall columns", walls.columns_updated, True),
                ("periodic copy", periodic.copy_updated, periodic.on),
                ("G2P", self.g2p, True),                                        # 4: eqs 16-17, 28
                ("contact tally", c.tally, True),
            )
        return tuple((name, stage) for name, stage, on in stages if on)

    def _fused(self, damped: bool) -> bool:
        """Whether apic-affine's P2G fuses the forces into the momentum: undamped and with no
        structure (damping and the structures' mirror forces need the grid force apart)."""
        return not self.six_stage and not damped and self.n_structures == 0

    @ti.kernel
    def _step(self, dt: float, gx: float, gy: float, damping: float, damped: ti.template()):
        # Each stage is a ti.func whose loops become top-level loops of this kernel, so they run in
        # parallel, in recipe order, from one launch (a launch costs 40-75 us on the CPU, as much as
        # a whole small step).
        g = ti.Vector([gx, gy])
        for _name, stage in ti.static(self._stages()):
            stage(dt, g, damping, damped)

    @ti.kernel
    def _stage_kernel(self, name: ti.template(), dt: float, gx: float, gy: float, damping: float,
                      damped: ti.template()):
        g = ti.Vector([gx, gy])
        for stage_name, stage in ti.static(self._stages()):
            if ti.static(stage_name == name):
                stage(dt, g, damping, damped)

    # ------------------------------------------------------------------ the method's stages
    @ti.func
    def water_step(self, dt, g, damping, damped: ti.template()):
        """The ground water's lines moved on by the step, and the step's gravity for its pressure."""
        for _ in range(1):
            self.water.begin_step(dt, g)

    @ti.func
    def loads_step(self, dt, g, damping, damped: ti.template()):
        """The surcharges' forces moved on by the step (solver.loads)."""
        for _ in range(1):
            self.loads.begin_step(dt)

    @ti.func
    def reset_grid(self, dt, g, damping, damped: ti.template()):
        """Clear the nodes the last step wrote (and the contact's material normals there)."""
        lo = self.lo[None]
        width = ti.max(self.hi[None] - lo, 0)
        for k in range(width[0] * width[1]):
            I = lo + ti.Vector([k // width[1], k % width[1]])
            self.g_mass[I] = 0.0
            self.g_mom[I] = ti.Vector.zero(float, 2)
            if ti.static(self.separate_forces):
                self.g_f[I] = ti.Vector.zero(float, 2)
            if ti.static(self.contact.has_zone):
                self.contact.node_pn[I] = ti.Vector.zero(float, 3)
            if ti.static(self.averaging):
                self.g_dil[I] = ti.Vector.zero(float, 2)
            if ti.static(self.rigid.on):
                self.rigid.clear(I)
        self.lo[None] = ti.Vector([BIG, BIG])  # empty: the scatter widens it
        self.hi[None] = ti.Vector([-BIG, -BIG])

    @ti.func
    def average_dilatation(self, dt, g, damping, damped: ti.template()):
        """Volumetric averaging, before the stress update: each particle's volumetric strain rate
        (from its C in apic-affine, from the grid's velocity in mpm and apic) and its volume to
        its nodes, whose ratio the stress update reads back at the particle (:meth:`_stress_point`)."""
        self.to_grid.particles(self, "dilatation", dt, g, False)

    @ti.func
    def p2g_with_stress(self, dt, g, damping, damped: ti.template()):
        """apic-affine: per particle the stress update from its own C, then its mass, APIC momentum
        and force to the grid; undamped and without structures the forces go into the momentum
        (and the ghost nodes' force apart, for the mirror forces)."""
        self.to_grid.particles(self, "affine", dt, g, ti.static(self._fused(damped)))

    @ti.func
    def p2g_momentum(self, dt, g, damping, damped: ti.template()):
        """mpm, apic: mass and momentum (FLIP or APIC) to the grid."""
        self.to_grid.particles(self, "momentum", dt, g, False)

    @ti.func
    def stress_and_force(self, dt, g, damping, damped: ti.template()):
        """mpm, apic: per particle the stress update from the grid's velocity gradient, then its
        internal and body force to the grid."""
        self.to_grid.particles(self, "force", dt, g, False)

    @ti.func
    def grid_update(self, dt, g, damping, damped: ti.template()):
        """The grid's new velocity from momentum and force (local damping at the free nodes), then
        the contact law."""
        if ti.static(self.six_stage):
            self._grid_update(dt, damping)
        else:
            self._grid_update_fused(dt, damping, ti.static(not self._fused(damped)))

    # ------------------------------------------------------------------ the pieces the stages share
    @ti.func
    def _stencil(self, xp):
        """Base node, fractional offset, weights and weight derivatives of quadratic B-splines."""
        X = (xp - ti.Vector(self.origin)) * self.inv_dx + PAD
        base = ti.cast(X - 0.5, ti.i32)
        # A blown-up particle (NaN or huge position, until the guard stops the run) must still
        # address nodes of the grid: integer clamps hold whatever the float arithmetic did.
        base = ti.max(ti.min(base, ti.Vector([self.nodes[0] - 3, self.nodes[1] - 3])), 0)
        fx = X - ti.cast(base, float)
        w = [0.5 * (1.5 - fx) ** 2, 0.75 - (fx - 1.0) ** 2, 0.5 * (fx - 0.5) ** 2]
        dw = [fx - 1.5, -2.0 * (fx - 1.0), fx - 0.5]
        return base, fx, w, dw

    @ti.func
    def _in_box(self, I):
        """Whether node I lies in the box of nodes the last scatter wrote."""
        lo = self.lo[None]
        hi = self.hi[None]
        return lo[0] <= I[0] < hi[0] and lo[1] <= I[1] < hi[1]

    @ti.func
    def trial_velocity(self, J, trial: ti.template(), dt, damping):
        """The trial velocity of a free node J in the stage ``trial`` (before any contact):
        ``interpolated`` after P2G, ``updated`` after the six-stage grid update, ``fused`` where the
        grid update has already written it."""
        mass = self.g_mass[J]
        out = ti.Vector.zero(float, 2)
        if ti.static(trial == "interpolated"):
            out = self.g_mom[J] / mass
        elif ti.static(trial == "updated"):
            v = self.g_v_old[J]
            out = v + dt * self._damped(J, self.g_f[J], v, damping) / mass
        else:
            out = self.g_mom[J]
        return out

    @ti.func
    def _damped(self, I, f, v, damping):
        """Node I's force ``f`` after local damping (solver.damping; none at contact nodes)."""
        return self.damping.local(f, v, damping, self.contact.held(I))

    @ti.func
    def _stress_point(self, p, L, dt):
        """Constitutive update of particle p from its velocity gradient L; returns its volume.
        With volumetric averaging the rate of deformation's volumetric part is replaced by the
        stencil's average (a B-bar on the rate: the deviatoric part stays the particle's own)."""
        Lt = transpose(L)
        D = 0.5 * (L + Lt)
        W = 0.5 * (L - Lt)
        if ti.static(self.averaging):
            D += 0.5 * (self._averaged_dilatation(p) - (D[0, 0] + D[1, 1])) * ti.Matrix.identity(float, 2)
        before = self.s[p]
        s, deq, yielded = self.materials.stress_update(self.mat[p], before, D, W, dt, self.eps_p[p])
        self.s[p] = s
        self.damping.update(self.materials, p, self.mat[p], D, W, dt, before, s, yielded)
        self.eps_p[p] += deq
        self.yielded[p] = ti.cast(yielded, ti.i8)
        rho = self.rho[p] / (1.0 + (D[0, 0] + D[1, 1]) * dt)  # eq 24
        rho = ti.max(rho, DENSITY_FLOOR * self.materials.rho0[self.mat[p]])
        self.rho[p] = rho
        return self.m[p] / rho

    @ti.func
    def _averaged_dilatation(self, p):
        """The volume-weighted average volumetric strain rate over particle p's stencil: the nodes'
        ``sum V tr(D) / sum V``, interpolated back with p's weights."""
        base, fx, w, dw = self._stencil(self.x[p])
        total = 0.0 * self.dx
        for i, j in ti.static(ti.ndrange(3, 3)):
            node = self.g_dil[base + ti.Vector([i, j])]
            if node[0] > 0.0:
                total += w[i][0] * w[j][1] * node[1] / node[0]
        return total

    @ti.func
    def _dilatation_rate(self, p):
        """Particle p's own volumetric strain rate tr(D) (1/s) in this step's stress update."""
        rate = 0.0 * self.dx
        if ti.static(self.six_stage):
            L = self._grid_velocity_gradient(p)
            rate = L[0, 0] + L[1, 1]
        else:
            rate = self.C[p][0, 0] + self.C[p][1, 1]
        return rate

    @ti.func
    def water_state(self, p):
        """Particle p's ground-water state (solver.groundwater.GroundWater.at: its depths below the
        lines, looked up once per particle per pass), for :meth:`force_stress`,
        :meth:`particle_mass` and :meth:`water_force`; zeros, compiled out, in a dry run."""
        w = ti.Vector.zero(float, 4)
        if ti.static(self.wet):
            w = self.water.at(self.x[p])
        return w

    @ti.func
    def force_stress(self, p, w):
        """The stress particle p contributes to the grid's internal force (2x2, Pa; eq 9): its
        stress plus its damping stress. Every force pass reads it here (P2G, the six-stage force
        scatter, the walls' ghost forces, the structures' mirror images). ``w``: its water state
        (:meth:`water_state`)."""
        s = self.s[p]
        sig = ti.Matrix([[s[0], s[2]], [s[2], s[1]]])
        if ti.static(self.wet):
            # the pore pressure in excess of the free water's (solver/water.py): total stress
            # sigma' - u I, less the free water's pressure, which acts as buoyancy (body_force)
            sig -= self.water.excess_pressure(w, self.mat[p], s) * ti.Matrix.identity(float, 2)
        return self.damping.add_stress(p, sig)

    @ti.func
    def particle_mass(self, p, w):
        """The mass particle p gives the grid (kg/m): in P2G its mass and momentum shares and its
        body force ``weight * m * g`` (eq 10), in every force pass (the six-stage force scatter,
        the walls' ghost forces, the structures' mirror images). Below the phreatic line the
        saturated soil's. ``w``: its water state (:meth:`water_state`)."""
        m = self.m[p]
        if ti.static(self.wet):
            m *= self.water.mass_ratio(w, self.mat[p])
        return m

    @ti.func
    def particle_volume(self, p):
        """Particle p's volume (m2 per m): its own mass over its density."""
        return self.m[p] / self.rho[p]

    @ti.func
    def water_force(self, vol, w):
        """The free water's pressure on a particle of volume vol in water state w
        (:meth:`water_state`), -vol grad p_w (N/m; buoyancy); call only where ``self.wet``."""
        return vol * self.water.buoyancy(w)

    # ------------------------------------------------------------------ particle passes
    # P2G and the force scatter visit every active particle: an update that writes the particle's
    # own fields (its constitutive update), then the adds of its shares to the grid. The scatter
    # strategy (``self.to_grid``, solver/scatter.py) runs the loops and makes the adds.
    @ti.func
    def _update_particle(self, kind: ti.template(), p, dt):
        """The update of particle p in a pass of ``kind`` (see :meth:`_add_particle`); its volume.
        A rigid body's particle keeps its state (solver.rigid)."""
        vol = 0.0 * dt
        if self.rigid.is_rigid(p):
            vol = self.particle_volume(p)
        elif ti.static(kind == "affine"):
            vol = self._stress_point(p, self.C[p], dt)  # eqs 29-30: D = sym(C), W = skew(C)
        elif ti.static(kind == "force"):
            vol = self._stress_from_grid_point(p, dt)
        elif ti.static(kind == "dilatation"):
            self.dil[p] = self._dilatation_rate(p)
            vol = self.particle_volume(p)
        return vol

    @staticmethod
    def pass_parts(kind: str, fuse_force: bool) -> tuple[str, ...]:
        """The adds of a particle pass of ``kind`` in parts, in order (the serial and atomic scatters
        run each part as a loop of its own, the split scatter does them particle by particle).
        The apic-affine P2G with the forces fused into the momentum also sums the force at the ghost
        nodes beyond closed walls apart (``wall forces``, for the mirror forces)."""
        return ("shares", "wall forces") if kind == "affine" and fuse_force else ("shares",)

    @ti.func
    def _add_particle(self, kind: ti.template(), part: ti.template(), p, vol, dt, g, fuse_force: ti.template()):
        """Particle p's adds to the grid, one part of them (see :meth:`pass_parts`). ``affine``
        (apic-affine P2G): mass, APIC momentum and force, the force fused into the momentum with
        ``fuse_force``; ``momentum`` (mpm, apic P2G): mass and momentum; ``force`` (mpm, apic):
        internal and body force. ``vol``: the particle's volume after its update (m2 per m).
        A rigid body's particle gives its weights to the body's nodes instead (solver.rigid)."""
        if self.rigid.is_rigid(p):
            if ti.static(part == "shares" and kind in ("affine", "momentum")):
                self.rigid.share(p)
        elif ti.static(part == "wall forces"):
            self.walls.ghost_particle(p, g)
        elif ti.static(kind == "dilatation"):
            base, fx, w, dw = self._stencil(self.x[p])
            share = ti.Vector([vol, vol * self.dil[p]])
            for i, j in ti.static(ti.ndrange(3, 3)):
                self.to_grid.add(self.g_dil, base + ti.Vector([i, j]), w[i][0] * w[j][1] * share)
        elif ti.static(kind == "affine"):
            self._scatter_particle(p, vol, dt, g, fuse_force)
        elif ti.static(kind == "momentum"):
            self._momentum_particle(p)
        else:
            self._force_particle(p, vol, g)

    # ------------------------------------------------------------------ four-stage (apic-affine)
    @ti.func
    def _scatter_particle(self, p, vol, dt, g, fuse_force: ti.template()):
        """Mass, APIC momentum and (fused or apart) internal and body force of particle p."""
        base, fx, w, dw = self._stencil(self.x[p])
        self.to_grid.cover(self, base)
        wet = self.water_state(p)
        sig = self.force_stress(p, wet)
        m = self.particle_mass(p, wet)
        buoyant = ti.Vector.zero(float, 2)
        if ti.static(self.wet):
            buoyant = self.water_force(vol, wet)
        if ti.static(self.loaded):
            buoyant += self.loads.force(p)  # a surcharge's share (solver.loads), spread as the weight is
        mv = m * self.v[p]
        mC = m * self.C[p]
        for i, j in ti.static(ti.ndrange(3, 3)):
            offset = ti.Vector([i, j])
            dpos = (ti.cast(offset, float) - fx) * self.dx
            weight = w[i][0] * w[j][1]
            grad = ti.Vector([dw[i][0] * w[j][1], w[i][0] * dw[j][1]]) * self.inv_dx
            force = -vol * mat_vec(sig, grad) + weight * m * g
            if ti.static(self.wet or self.loaded):
                force += weight * buoyant
            I = base + offset
            self.to_grid.add(self.g_mass, I, weight * m)
            self.rigid.soil_share(I, vol, grad)  # the normal of a rigid body's contact (solver.rigid)
            if ti.static(fuse_force):
                self.to_grid.add(self.g_mom, I, weight * (mv + mat_vec(mC, dpos)) + dt * force)
            else:
                self.to_grid.add(self.g_mom, I, weight * (mv + mat_vec(mC, dpos)))
                self.to_grid.add(self.g_f, I, force)

    @ti.func
    def _grid_update_fused(self, dt, damping, apart: ti.template()):
        lo = self.lo[None]
        width = ti.max(self.hi[None] - lo, 0)
        for k in range(width[0] * width[1]):
            I = lo + ti.Vector([k // width[1], k % width[1]])
            mass = self.g_mass[I]
            if mass > 0.0:
                v = self.g_mom[I] / mass
                if ti.static(apart):  # forces kept apart (Cundall's local damping, structures)
                    v += dt * self._damped(I, self.g_f[I], v, damping) / mass
                if ti.static(self.n_structures > 0):
                    self.g_mom[I] = v  # the contact in a second loop: it reads the free nodes' v
                else:
                    v = self.contact.apply(I, v, mass, True, "fused", dt, damping)
                    self.g_mom[I] = self.rigid.hold(I, v, mass, True)
            else:
                self.g_mom[I] = ti.Vector.zero(float, 2)
        if ti.static(self.n_structures > 0):
            for k in range(width[0] * width[1]):
                I = lo + ti.Vector([k // width[1], k % width[1]])
                mass = self.g_mass[I]
                if mass > 0.0 and self.contact.held(I):
                    self.g_mom[I] = self.contact.apply(I, self.g_mom[I], mass, True, "fused", dt, damping)
                if ti.static(self.rigid.on):
                    if mass > 0.0:
                        self.g_mom[I] = self.rigid.hold(I, self.g_mom[I], mass, True)

    # ------------------------------------------------------------------ six-stage (mpm, apic)
    @ti.func
    def _momentum_particle(self, p):
        """Mass and momentum (FLIP or APIC) of particle p to its nodes."""
        base, fx, w, dw = self._stencil(self.x[p])
        self.to_grid.cover(self, base)
        m = self.particle_mass(p, self.water_state(p))
        mv = m * self.v[p]
        mC = m * self.C[p]
        for i, j in ti.static(ti.ndrange(3, 3)):
            offset = ti.Vector([i, j])
            weight = w[i][0] * w[j][1]
            I = base + offset
            self.to_grid.add(self.g_mass, I, weight * m)
            if ti.static(self.rigid.on):  # the normal of a rigid body's contact (solver.rigid)
                grad = ti.Vector([dw[i][0] * w[j][1], w[i][0] * dw[j][1]]) * self.inv_dx
                self.rigid.soil_share(I, self.particle_volume(p), grad)
            if ti.static(self.scheme == "apic"):
                dpos = (ti.cast(offset, float) - fx) * self.dx
                self.to_grid.add(self.g_mom, I, weight * (mv + mat_vec(mC, dpos)))
            else:
                self.to_grid.add(self.g_mom, I, weight * mv)

    @ti.func
    def grid_velocity(self, dt, g, damping, damped: ti.template()):
        """mpm, apic: the grid velocity from momentum (the interpolated velocity), then the contact
        law on it; kept in ``g_v_old`` for the stress update and FLIP's increment."""
        lo = self.lo[None]
        width = ti.max(self.hi[None] - lo, 0)
        for k in range(width[0] * width[1]):
            I = lo + ti.Vector([k // width[1], k % width[1]])
            mass = self.g_mass[I]
            v = ti.Vector.zero(float, 2)
            self.contact.clear_hold(I)  # the contact law sets it where a structure holds the node
            if mass > 0.0:
                # the contact law on the interpolated velocity too (Bardenhagen et al. 2000): the
                # stress update sees the constrained velocity. APIC's particles take the new grid
                # velocity, so they receive this correction (an impulse of the contact). FLIP's take
                # the increment v_new - v_old from ordinary nodes but, at contact nodes, the new
                # velocity itself (PIC there, see g2p), so they receive it too: recorded in
                # every scheme.
                v = self.contact.apply(I, self.g_mom[I] / mass, mass, True, "interpolated", 0.0, 0.0)
                v = self.rigid.hold(I, v, mass, True)
            self.g_v_old[I] = v

    @ti.func
    def _stress_from_grid_point(self, p, dt):
        """Velocity gradient from the grid velocities, then the constitutive update; the volume."""
        return self._stress_point(p, self._grid_velocity_gradient(p), dt)

    @ti.func
    def _grid_velocity_gradient(self, p):
        """mpm, apic: the velocity gradient at particle p from the grid's interpolated velocities."""
        base, fx, w, dw = self._stencil(self.x[p])
        L = ti.Matrix.zero(float, 2, 2)
        for i, j in ti.static(ti.ndrange(3, 3)):
            grad = ti.Vector([dw[i][0] * w[j][1], w[i][0] * dw[j][1]]) * self.inv_dx
            J = base + ti.Vector([i, j])
            v = self.contact.with_hold(J, self.g_v_old[J])  # the structures' hold (solver.contact)
            L += outer(v, grad)
        return L

    @ti.func
    def _force_particle(self, p, vol, g):
        base, fx, w, dw = self._stencil(self.x[p])
        wet = self.water_state(p)
        sig = self.force_stress(p, wet)
        m = self.particle_mass(p, wet)
        buoyant = ti.Vector.zero(float, 2)
        if ti.static(self.wet):
            buoyant = self.water_force(vol, wet)
        if ti.static(self.loaded):
            buoyant += self.loads.force(p)  # a surcharge's share (solver.loads)
        for i, j in ti.static(ti.ndrange(3, 3)):
            weight = w[i][0] * w[j][1]
            grad = ti.Vector([dw[i][0] * w[j][1], w[i][0] * dw[j][1]]) * self.inv_dx
            force = -vol * mat_vec(sig, grad) + weight * m * g
            if ti.static(self.wet or self.loaded):
                force += weight * buoyant
            self.to_grid.add(self.g_f, base + ti.Vector([i, j]), force)

    @ti.func
    def _grid_update(self, dt, damping):
        lo = self.lo[None]
        width = ti.max(self.hi[None] - lo, 0)
        for k in range(width[0] * width[1]):
            I = lo + ti.Vector([k // width[1], k % width[1]])
            mass = self.g_mass[I]
            if mass > 0.0:
                v = self.g_v_old[I]
                f = self._damped(I, self.g_f[I], v, damping)
                v = self.contact.apply(I, v + dt * f / mass, mass, True, "updated", dt, damping)
                self.g_mom[I] = self.rigid.hold(I, v, mass, True)
            else:
                self.g_mom[I] = ti.Vector.zero(float, 2)

    # ------------------------------------------------------------------ G2P (all schemes)
    @ti.func
    def g2p(self, dt, g, damping, damped: ti.template()):
        """Every scheme: each particle's new velocity (and C, eq 17; FLIP's increment for mpm) from
        the new grid velocities, its move (eq 28), then the guard, the periodic sides, the box's
        sides (open: the particle leaves) and the structures (pushed back out)."""
        bound2 = self.speed_bound[None] ** 2
        for p in range(self.n):
            if self.active[p]:
                x = self.x[p]
                v = self.v[p]
                rigid = self.rigid.is_rigid(p)
                if rigid:
                    x, v = self.rigid.move(p, dt)  # a rigid body's particle moves with the body
                else:
                    base, fx, w, dw = self._stencil(self.x[p])
                    new_v = ti.Vector.zero(float, 2)
                    new_C = ti.Matrix.zero(float, 2, 2)
                    dv = ti.Vector.zero(float, 2)
                    held = ti.Vector.zero(float, 2)  # mpm: sum over contact nodes of w (v_old - v_p)
                    touched = False
                    for i, j in ti.static(ti.ndrange(3, 3)):
                        offset = ti.Vector([i, j])
                        weight = w[i][0] * w[j][1]
                        gv = self.g_mom[base + offset]  # the new grid velocity
                        new_v += weight * gv
                        if ti.static(self.scheme == "mpm"):
                            old = self.g_v_old[base + offset]
                            dv += weight * (gv - old)
                            if self.contact.held(base + offset) or self.rigid.holds(base + offset):
                                touched = True
                                held += weight * (old - self.v[p])
                        else:
                            dpos = (ti.cast(offset, float) - fx) * self.dx
                            new_C += 4.0 * self.inv_dx * self.inv_dx * weight * outer(gv, dpos)  # eq 17
                    x = self.x[p] + dt * new_v  # eq 28
                    v = new_v
                    if ti.static(self.scheme == "mpm"):
                        v = self.v[p] + dv  # FLIP: particle velocity takes the grid's increment
                        if touched:
                            # PIC at contact nodes (docs/solver.md, contact): the particle takes a contact
                            # node's constrained velocity itself, w v_new, not its own plus the increment,
                            # w (v_p + v_new - v_old); away from contacts this is zero and v is FLIP's
                            v += held
                    else:
                        self.C[p] = new_C
                speed2 = v.dot(v)
                keep = 1
                if not (speed2 <= bound2):  # also true for NaN
                    self.unstable[None] += 1
                    if ti.static(self.remove_unstable):
                        keep = 0
                x = self.periodic.wrap(p, x)  # across the periodic line: in at the other side
                # a particle the guard removed is not also counted lost
                for d in ti.static(range(1 if self.periodic.on else 0, 2)):
                    if x[d] < self.origin[d]:
                        if self.contact.bc_kind[2 * d] == OPEN:
                            keep = -1 if keep == 1 else keep
                        else:
                            x[d] = self.origin[d]
                    if x[d] > self.upper[d]:
                        if self.contact.bc_kind[2 * d + 1] == OPEN:
                            keep = -1 if keep == 1 else keep
                        else:
                            x[d] = self.upper[d]
                if not rigid:
                    x, v = self.contact.push_out(self.x[p], x, v, self.m[p])
                self.x[p] = x
                self.v[p] = v
                if keep == -1:
                    self.active[p] = ti.cast(0, ti.i8)
                    self.lost[None] += 1
                elif keep == 0:
                    self.active[p] = ti.cast(0, ti.i8)
                else:
                    self.to_grid.moved(self, p, x)

    @ti.func
    # ------------------------------------------------------------------ diagnostics
    @ti.kernel
    def _diagnostics(self, out: ti.types.ndarray(dtype=ti.f64, ndim=1)):
        for k in ti.static(range(8)):
            self.diag[k] = 0.0
        # with the plain-add scatters (serial, split) the sums run in one thread, in particle
        # order, so the energies and momenta of series.csv repeat bit for bit as the frames do
        ti.loop_config(serialize=self.plain)
        for p in range(self.n):
            # the measures of the material's motion: a rigid body's prescribed motion is not one
            if self.active[p] and not self.rigid.is_rigid(p):
                m = self.particle_mass(p, self.water_state(p))
                v = self.v[p]
                self.diag[0] += 0.5 * m * v.dot(v)
                self.diag[1] += m * v[0]
                self.diag[2] += m * v[1]
                ti.atomic_max(self.diag[3], v.norm())
                self.diag[4] += m
                self.diag[5] += 1.0
                self.diag[6] += ti.cast(self.yielded[p], float)
        # after the sums: the totals and the counters to the host, in the same launch
        for j in ti.static(range(8)):
            out[j] = self.diag[j]
        out[8] = self.lost[None]
        out[9] = self.unstable[None]

    def diagnostics(self) -> dict[str, float]:
        """Kinetic energy (J/m), momentum (kg m/s per m), max speed, mass, counts."""
        d = np.empty(10, np.float64)
        self._diagnostics(d)  # one launch: the sums and the counters straight into ``d``
        return {
            "kinetic_energy": float(d[0]), "momentum_x": float(d[1]), "momentum_y": float(d[2]),
            "max_speed": float(d[3]), "mass": float(d[4]), "active": int(round(d[5])),
            "yielding": int(round(d[6])), "lost": int(d[8]), "unstable": int(d[9]),
        }


