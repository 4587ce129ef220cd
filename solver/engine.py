"""The MPM engine: particle and grid state, and one step as a recipe of named stage kernels.

Symbols inside kernels (SI): ``x`` particle position (m), ``v`` velocity (m/s), ``C`` APIC affine
matrix (1/s), ``s`` stress vec4 (xx, yy, xy, zz; Pa, tension positive), ``m`` mass (kg/m),
``rho`` density (kg/m3), ``eps_p`` equivalent plastic strain (-), ``dx`` cell size (m),
``dt`` time step (s), ``g`` gravity (m/s2). Grid node ``(i, j)`` sits at
``origin + (i - PAD, j - PAD) * dx``; ``PAD`` ghost layers keep every particle's 3x3 stencil
inside the arrays. Quadratic B-splines throughout; APIC inertia ``D_p = dx^2 / 4 I``.

Schemes (chosen once, at construction, and compiled in with ``ti.static``):

- ``mpm``: FLIP transfer, six stages (reset, P2G momentum, grid velocity, stress + force,
  grid momentum update, G2P with FLIP increments; from contact nodes the new velocity itself,
  PIC there, see ``_g2p``).
- ``apic``: APIC transfer (paper eqs 14-17), same six stages.
- ``apic-affine``: improved MPM-APIC: strain rate and spin from the particle's own C
  (eqs 29-30), stress update and force scatter fused into P2G; four stages.

Contact (docs/solver.md): one grid contact law (``_contact``) for the closed sides and the rigid
structures, applied in the grid stages; the mirror-image wall terms (``_mirror_forces``,
``_mirror_ghosts``) pass their reaction through it; ``contact tally`` adds up the force on each
contact; G2P puts particles that ended inside a structure back on its surface, and mpm's
particles take the contact nodes' constrained velocity itself (PIC at contact nodes).

The particle passes (P2G; stress and force for mpm and apic) are written per particle
(``_update_particle``: the particle's own constitutive update; ``_add_particle``: its shares to
the grid); how those shares reach shared grid nodes on a CPU (serial, split, atomic) is the
scatter strategy's, chosen once at construction (``self.to_grid``, solver/scatter.py), which runs
the pass loops and makes every add.

Grid passes run only over the bounding box of the particles' stencils (built in the scatter), so
empty parts of the domain cost nothing.
"""


import numpy as np
from solver.runtime import mat_vec, outer, ti, transpose

from solver.config import SIDES, Boundary, Grid, Material, Structure
from solver.fieldio import FieldIO
from solver.materials import MaterialTable
from solver.scatter import BIG, SCATTER_STATE, make_scatter
from solver.structures import (corner_normals, far_normals, node_contacts, segments, signed_distance, through_sides,
                               zone_nodes)

PAD = 2
BOUNDARY_CODES = {"fixed": 0, "slip": 1, "friction": 2, "open": 3, "periodic": 4}
FIXED, SLIP, FRICTION, OPEN, PERIODIC = (BOUNDARY_CODES[k] for k in ("fixed", "slip", "friction", "open", "periodic"))
#: A particle found inside a structure after its move is put on the nearest point of the surface and
#: this many cell sizes outside it (so that rounding never leaves it inside).
PUSH_OUT_CELLS = 1e-3
#: Particles closer than this many cell sizes to a structure's surface have a mirror image across it
#: (``_mirror_structures``): an image deeper than 1.5 cells along each axis reaches no node outside.
MIRROR_REACH_CELLS = 2.2
#: A contact node near a convex vertex takes its material's mean outward normal where the
#: particles' normals agree this well (the length of their weighted mean; 0.9 = cos 26 deg: material
#: against one face, or spread over a corner's region); else its own normals.
CORNER_COHERENCE = 0.9
#: A thin part's node holds the material both ways across it where each of its faces has more
#: than this share of the node's mass (solver.structures.far_normals, Engine._structure_normal).
TWO_SIDED_SHARE = 0.02
#: The material's normal is the node's own (its surface's) within this cosine (0.8 deg).
OWN_NORMAL = 0.9999
#: Unit normal of each side (SIDES order), out of the wall into the domain.
_INWARD = ((1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0))


@ti.func
def _bspline(f, i):
    """Quadratic B-spline weight of stencil node ``i`` (0, 1, 2) at fractional offset ``f``."""
    r = 0.5 * (f - 0.5) ** 2
    if i == 0:
        r = 0.5 * (1.5 - f) ** 2
    elif i == 1:
        r = 0.75 - (f - 1.0) ** 2
    return r


@ti.func
def _bspline_slope(f, i):
    """Derivative of :func:`_bspline` with respect to the position, in cell units."""
    r = f - 0.5
    if i == 0:
        r = f - 1.5
    elif i == 1:
        r = -2.0 * (f - 1.0)
    return r


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

    Contacts (see docs/solver.md): the closed sides (index 0-3 in :data:`SIDES` order) and the
    structures (index 4 on). Each step adds, per contact, the impulse the material exerts on it
    (N s/m, x and y) and keeps the largest force of any step; :meth:`read_contacts` returns both
    and starts them afresh.
    """

    #: A friction side's Coulomb law acts on each wall column (the wall node and its ghosts) as one
    #: contact point (:meth:`_wall_columns`); subclasses that replace the law node by node (the
    #: stability benchmark's variants) switch it off.
    COLUMN_FRICTION = True

    def __init__(self, grid: Grid, materials: tuple[Material, ...], n_particles: int, scheme: str,
                 np_float=np.float32, speed_bound_m_s: float = 1e30, remove_unstable: bool = False,
                 damping: bool = True, scatter: str = "auto", bands: int | None = None,
                 structures: tuple[Structure, ...] = (), viscous: bool | None = None):
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
        #: left and right sides periodic (compiled in: the fold and copy stages, wrapping in G2P)
        self.periodic = grid.periodic
        self.materials = MaterialTable(materials, np_float, shared_io=True)  # moved by self._io

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
        # the materials' damping stress (docs/solver.md, material damping), only where a material
        # has some (``viscous``: in any stage; by default, in the materials given here). Written by
        # the constitutive update, read by the force passes; state where a Maxwell arm remembers it.
        self.viscous = (any(m.damping_beta_s > 0.0 for m in materials) if viscous is None else bool(viscous))
        self.sv = ti.Vector.field(3, float, n if self.viscous else 1)

        # Grid: what every scheme needs, plus the force and old-velocity fields only where used.
        # ``g_mom`` holds momentum after P2G and the new velocity after the grid update.
        self.six_stage = scheme != "apic-affine"
        # structures: the grid force is kept apart in every scheme, for their mirror forces
        self.separate_forces = self.six_stage or bool(damping) or bool(structures)
        self.g_mass = ti.field(float, self.nodes)
        self.g_mom = ti.Vector.field(2, float, self.nodes)
        self.g_f = ti.Vector.field(2, float, self.nodes if self.separate_forces else (1, 1))
        self.g_v_old = ti.Vector.field(2, float, self.nodes if self.six_stage else (1, 1))

        # contacts: the four sides, then the structures. Per structure its contact kind and friction
        # coefficient, its edges (for pushing particles out) and bounding box; per grid node the
        # structure whose contact node it is (-1: none) and that structure's outward normal there
        self.structures = tuple(structures)
        self.n_structures = len(self.structures)
        self.n_contacts = 4 + self.n_structures
        ns = max(1, self.n_structures)
        self.st_kind = ti.field(ti.i32, ns)
        self.st_mu = ti.field(float, ns)
        # a structure standing on a side continues through it (solver.structures.through_sides)
        crossable = (not self.periodic, not self.periodic, True, True)
        self.solid_polygons = tuple(through_sides(st.polygon_m, self.origin, self.upper, PAD * self.dx, crossable)
                                    for st in self.structures)
        edges = [segments(polygon) for polygon in self.solid_polygons]
        n_edges = max(1, sum(len(a) for a, _ in edges))
        self.edge_a = ti.Vector.field(2, float, n_edges)
        self.edge_b = ti.Vector.field(2, float, n_edges)
        self.st_edges = ti.field(ti.i32, (ns, 2))  # first edge, edge count
        self.st_box = ti.Vector.field(4, float, ns)  # x min, y min, x max, y max
        has = self.n_structures > 0
        self.node_struct = ti.field(ti.i32, self.nodes if has else (1, 1))
        self.node_normal = ti.Vector.field(2, float, self.nodes if has else (1, 1))
        # near a convex corner the normals of its two faces (solver.structures.corner_normals);
        # elsewhere node_normal_b is node_normal
        self.node_normal_b = ti.Vector.field(2, float, self.nodes if has else (1, 1))
        # and its signed distance to that structure's surface (m, negative inside)
        self.node_sd = ti.field(float, self.nodes if has else (1, 1))
        # near a convex vertex or in a thin part (solver.structures.zone_nodes): the structure's index
        # + 1 at such a node (negated at a thin part's node away from a vertex), per structure the
        # box of the particles that reach its zone nodes, and at each zone node the sums over those
        # particles of weight x mass x their outward normal and of weight x mass (rebuilt every
        # step: _corner_particle_normals). has_zone: any zone node at all
        self.has_zone = False
        self.node_zone = ti.field(ti.i32, self.nodes if has else (1, 1))
        self.node_pn = ti.Vector.field(3, float, self.nodes if has else (1, 1))
        # in a part thinner than a stencil the outward normal of the far face a node's stencil reaches
        # past (solver.structures.far_normals; zero elsewhere)
        self.node_far = ti.Vector.field(2, float, self.nodes if has else (1, 1))
        self.st_zone_box = ti.Vector.field(4, float, ns)
        # the step (``hold_step``, counted from the load) after the last one in which the
        # structure held the node at the end of its update (``_contact``)
        self.node_hold = ti.field(ti.i32, self.nodes if has else (1, 1))
        self.hold_step = ti.field(ti.i32, ())
        # what that hold adds to the stress update's velocity at the node in this step (zero where
        # it does not hold; written with the interpolated velocity, read by the stress update)
        self.node_hold_dv = ti.Vector.field(2, float, self.nodes if has and self.six_stage else (1, 1))
        # impulse on the material in this step (N s/m) with its moment about the grid origin (N s:
        # x Jy - y Jx of each node's impulse at its point on the contact's surface), impulse on the
        # contact since the last read and its moment, and the largest force of one step since then
        # (|F|, Fx, Fy; N/m): in f64 whatever the precision
        self.contact_step = ti.Vector.field(3, ti.f64, self.n_contacts)
        # a friction side's normal impulse per unit mass at each node of a wall column (the wall
        # node and the ghost nodes beyond it, layer 0 = the wall line), for the column's Coulomb law
        self.column_dvn = ti.field(float, (4, max(self.nodes), PAD + 1))
        self.contact_impulse = ti.Vector.field(2, ti.f64, self.n_contacts)
        self.contact_moment = ti.field(ti.f64, self.n_contacts)
        self.contact_peak = ti.Vector.field(3, ti.f64, self.n_contacts)
        # apic-affine fuses the forces into the momentum; the force at the ghost nodes beyond the
        # closed walls is also summed apart (per side, along the wall) for the mirror forces
        self.ghost_f = ti.Vector.field(2, float, (4, max(self.nodes)) if not self.six_stage else (1, 1))

        # node box [lo, hi) the last scatter wrote (every node outside it holds zeros): built in the
        # scatter, which works out every particle's stencil anyway, and cleared by the next reset
        self.lo = ti.Vector.field(2, ti.i32, ())
        self.hi = ti.Vector.field(2, ti.i32, ())

        self.bc_kind = ti.field(ti.i32, 4)
        self.bc_mu = ti.field(float, 4)
        self.speed_bound = ti.field(float, ())
        self.lost = ti.field(ti.i32, ())
        self.unstable = ti.field(ti.i32, ())
        self.diag = ti.field(float, 8)

        # every field the host reads or writes, moved by one kernel (solver.fieldio: one kernel
        # per field, as Taichi's own to_numpy / from_numpy are, costs start-up time in every process)
        io_fields = {**{name: getattr(self, name) for name in self.HOST_FIELDS}, **self.to_grid.state_fields()}
        clash = set(io_fields) & set(self.materials.columns)
        assert not clash, f"engine and material fields share names: {sorted(clash)}"
        self._io = FieldIO({**io_fields, **self.materials.columns})
        self.materials.use_io(self._io)
        self.set_boundaries(grid)
        if has:
            self._set_up_structures(edges)
        self._io.write({"speed_bound": speed_bound_m_s})

    # ------------------------------------------------------------------ set-up and state I/O
    #: Every particle field of the solver state (a checkpoint holds these, the counters and the
    #: scatter strategy's ``STATE``, e.g. the split scatter's plan; the grid is rebuilt from the
    #: particles at every step).
    PARTICLE_STATE = ("x", "x0", "v", "C", "s", "sv", "m", "rho", "eps_p", "mat", "active", "yielded")
    COUNTER_STATE = ("lost", "unstable", "contact_impulse", "contact_moment", "contact_peak", "node_hold",
                     "hold_step")
    #: Every field of the engine the host reads or writes (:meth:`state`, :meth:`load_state` and
    #: the set-up); the scatter strategy's ``STATE`` fields are moved with them.
    HOST_FIELDS = PARTICLE_STATE + COUNTER_STATE + (
        "contact_step", "speed_bound", "bc_kind", "bc_mu", "st_kind", "st_mu", "edge_a", "edge_b",
        "st_edges", "st_box", "node_struct", "node_normal", "node_normal_b", "node_sd", "node_zone", "node_far",
        "st_zone_box")

    def set_boundaries(self, grid: Grid) -> None:
        """The kinds and friction of the four sides (data: no recompilation; whether the left and
        right sides are periodic is fixed at construction)."""
        if grid.periodic != self.periodic or grid.periodic_problem():
            raise ValueError(grid.periodic_problem() or "periodic sides are chosen when the engine is built")
        kinds, mus = _contact_codes([grid.boundary(side) for side in SIDES])
        self._io.write({"bc_kind": kinds, "bc_mu": mus})

    def set_structure_contacts(self, contacts: tuple[Boundary, ...]) -> None:
        """The contact of each structure, in order (data: the geometry stays as constructed)."""
        if len(contacts) != self.n_structures:
            raise ValueError(f"{self.n_structures} structure contacts expected, got {len(contacts)}")
        if any(c.kind in ("open", "periodic") for c in contacts):
            raise ValueError("a structure's contact is fixed, slip or friction, not open or periodic")
        if self.n_structures:
            kinds, mus = _contact_codes(contacts)
            self._io.write({"st_kind": kinds, "st_mu": mus})

    def _node_coordinates(self) -> tuple[np.ndarray, np.ndarray]:
        return (self.origin[0] + (np.arange(self.nodes[0]) - PAD) * self.dx,
                self.origin[1] + (np.arange(self.nodes[1]) - PAD) * self.dx)

    def _set_up_structures(self, edges) -> None:
        self.set_structure_contacts(tuple(st.contact for st in self.structures))
        f = self.np_float
        counts = np.array([len(a) for a, _ in edges], np.int32)
        xs, ys = self._node_coordinates()
        index, normal = node_contacts(self.solid_polygons, xs, ys, self.dx)
        normal, normal_b = corner_normals(self.solid_polygons, xs, ys, index, normal, self.dx,
                                          (self.origin, self.upper))
        far = far_normals(self.solid_polygons, xs, ys, index, normal, self.dx)
        zone, zone_boxes = zone_nodes(self.solid_polygons, xs, ys, index, normal, far, self.dx,
                                      (self.origin, self.upper))
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
            deeper = pts - (dist + self.dx)[:, None] * normal[mine]
            dist[signed_distance(deeper, polygon) > 0.0] = 0.0
            sd[mine] = dist
        self._io.write({
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
        })

    @property
    def contact_names(self) -> tuple[str, ...]:
        """Names of the contacts in engine order: the four sides, then the structures."""
        return SIDES + tuple(st.name for st in self.structures)

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

    # ------------------------------------------------------------------ the step recipes
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
        """The named stages of one step, in order (paper: six stages for mpm/apic, four for apic-affine;
        the contact law acts inside the grid stages, "contact tally" adds up the contact forces).
        The particle passes (P2G, stress and force) run as the scatter strategy drives them."""
        # periodic sides: the images of the nodes across the periodic line are folded into their
        # canonical nodes after every scatter, and the canonical values copied back to them after
        # the grid stages (docs/solver.md, periodic sides)
        fold = ("periodic fold",) if self.periodic else ()
        fold_force = ("periodic fold (force)",) if self.periodic else ()
        copy_old = ("periodic copy (velocity)",) if self.periodic else ()
        copy = ("periodic copy",) if self.periodic else ()
        columns_old = ("wall columns (old)",) if self.COLUMN_FRICTION else ()
        columns = ("wall columns",) if self.COLUMN_FRICTION else ()
        corners = ("corner normals",) if self.has_zone else ()
        if self.six_stage:
            return ("reset grid", *corners, "P2G momentum", *fold, "grid velocity", "mirror walls (old)", *columns_old,
                    *copy_old,
                    "stress and force", *fold_force, "mirror forces", "grid update", "mirror walls", *columns, *copy,
                    "G2P", "contact tally")
        return ("reset grid", *corners, "P2G with stress and force", *fold, "mirror forces", "grid update",
                "mirror walls", *columns, *copy, "G2P", "contact tally")

    def _fused(self, damped: bool) -> bool:
        """Whether apic-affine's P2G fuses the forces into the momentum: undamped and with no
        structure (damping and the structures' mirror forces need the grid force apart)."""
        return not self.six_stage and not damped and self.n_structures == 0

    @ti.kernel
    def _step(self, dt: float, gx: float, gy: float, damping: float, damped: ti.template()):
        # Each stage is a ti.func whose loops become top-level loops of this kernel, so they run in
        # parallel, in recipe order, from one launch (a launch costs 40-75 us on the CPU, as much as
        # a whole small step).
        for stage in ti.static(self.recipe):
            self._run_stage(stage, dt, ti.Vector([gx, gy]), damping, damped)

    @ti.kernel
    def _stage_kernel(self, stage: ti.template(), dt: float, gx: float, gy: float, damping: float,
                      damped: ti.template()):
        self._run_stage(stage, dt, ti.Vector([gx, gy]), damping, damped)

    @ti.func
    def _run_stage(self, stage: ti.template(), dt, g, damping, damped: ti.template()):
        if ti.static(stage == "reset grid"):
            self._reset_grid()
        elif ti.static(stage == "corner normals"):
            self._corner_particle_normals()
        elif ti.static(stage == "P2G momentum"):
            self.to_grid.particles(self, "momentum", dt, g, False)
        elif ti.static(stage == "grid velocity"):
            self._grid_velocity()
        elif ti.static(stage == "stress and force"):
            self.to_grid.particles(self, "force", dt, g, False)
        elif ti.static(stage == "P2G with stress and force"):
            # undamped, the forces go into the momentum (and the ghost nodes' force into ghost_f)
            self.to_grid.particles(self, "affine", dt, g, ti.static(self._fused(damped)))
        elif ti.static(stage == "grid update" and self.six_stage):
            self._grid_update(dt, damping)
        elif ti.static(stage == "grid update"):
            self._grid_update_fused(dt, damping, ti.static(not self._fused(damped)))
        elif ti.static(stage == "mirror forces"):
            self._mirror_forces(dt, g, ti.static(self._fused(damped)))
        elif ti.static(stage == "wall columns (old)"):
            self._wall_columns(True)
        elif ti.static(stage == "wall columns"):
            self._wall_columns(False)
        elif ti.static(stage == "mirror walls (old)"):
            # every scheme's particles receive this first correction (see _grid_velocity): an impulse
            self._mirror_ghosts(True, True)
        elif ti.static(stage == "mirror walls"):
            self._mirror_ghosts(False, True)
        elif ti.static(stage == "G2P"):
            self._g2p(dt)
        elif ti.static(stage == "contact tally"):
            self._contact_tally(dt)
        elif ti.static(stage == "periodic fold"):
            self._periodic_fold(True, ti.static(not self.six_stage and not self._fused(damped)),
                                ti.static(self._fused(damped)))
        elif ti.static(stage == "periodic fold (force)"):
            self._periodic_fold(False, True, False)
        elif ti.static(stage == "periodic copy (velocity)"):
            self._periodic_copy(True)
        elif ti.static(stage == "periodic copy"):
            self._periodic_copy(False)

    # ------------------------------------------------------------------ periodic sides
    # With periodic left and right sides node i and node i + cells are one physical node: nodes
    # PAD .. PAD + cells - 1 are the canonical ones, the PAD ghost layers beyond the left side and
    # the PAD + 1 beyond the right one (the right side's own line included) their images. The
    # scatters add to whichever array node a particle's stencil covers; the fold then adds every
    # image into its canonical node (a gather: each canonical node reads its images in a fixed
    # order, so a run repeats bit for bit) and narrows the box of nodes the grid stages work on to
    # the canonical columns, so that each physical node is updated, and meets a contact, once. The
    # copy puts the canonical values back into the images for the stages that read the grid at
    # the particles' stencils (stress update, G2P) and widens the box over every column, so that
    # the next reset clears the images too.
    @ti.func
    def _periodic_fold(self, momentum: ti.template(), force: ti.template(), wall_force: ti.template()):
        """Add the images into their canonical nodes: mass and momentum (``momentum``), the force
        (``force``) and the fused schemes' wall force beyond the bottom and top (``wall_force``)."""
        cells = ti.static(self.cells[0])
        last = ti.static(self.nodes[0])
        lo = self.lo[None]
        hi = self.hi[None]
        height = ti.max(hi[1] - lo[1], 0)
        for k in range(cells * height):
            i = PAD + k // height
            j = lo[1] + k % height
            for shift in ti.static((-cells, cells)):
                image = i + shift
                if 0 <= image < last:
                    if ti.static(momentum):
                        self.g_mass[i, j] += self.g_mass[image, j]
                        self.g_mom[i, j] += self.g_mom[image, j]
                    if ti.static(force):
                        self.g_f[i, j] += self.g_f[image, j]
        if ti.static(wall_force):
            for i in range(PAD, PAD + cells):
                for side in ti.static((2, 3)):
                    for shift in ti.static((-cells, cells)):
                        image = i + shift
                        if 0 <= image < last:
                            self.ghost_f[side, i] += self.ghost_f[side, image]
        self.lo[None][0] = PAD
        self.hi[None][0] = PAD + cells

    @ti.func
    def _periodic_copy(self, old: ti.template()):
        """Copy the canonical nodes' velocities into their images: the interpolated one (after the
        contact's first correction, which FLIP's increment also uses) with ``old``, else the new
        one; then widen the box over every column."""
        cells = ti.static(self.cells[0])
        last = ti.static(self.nodes[0])
        images = ti.static(self.nodes[0] - cells)  # PAD columns on the left, PAD + 1 on the right
        lo = self.lo[None]
        height = ti.max(self.hi[None][1] - lo[1], 0)
        for k in range(images * height):
            image = k // height
            if image >= PAD:
                image += cells
            i = image + cells if image < PAD else image - cells
            j = lo[1] + k % height
            if ti.static(old):
                self.g_v_old[image, j] = self.g_v_old[i, j]
                if ti.static(self.n_structures > 0 and self.six_stage):
                    self.node_hold_dv[image, j] = self.node_hold_dv[i, j]
            else:
                self.g_mom[image, j] = self.g_mom[i, j]
        self.lo[None][0] = 0
        self.hi[None][0] = last

    # ------------------------------------------------------------------ shared pieces
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

    # ------------------------------------------------------------------ contact (docs/solver.md)
    @ti.func
    def _contact(self, I, v, mass, record: ti.template(), trial: ti.template(), dt, damping):
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
        v_in = v
        held_by = -1  # the side that holds the node (the last, at a corner of the box)
        sides_holding = 0
        side_n = ti.Vector.zero(float, 2)
        corner = self._closed_sides_at(I)
        for side in ti.static(range(4)):
            axis = ti.static(side // 2)
            low = ti.static(side % 2 == 0)
            wall = ti.static(PAD if low else PAD + self.cells[axis])
            on_wall = (I[axis] <= wall) if ti.static(low) else (I[axis] >= wall)
            kind = self.bc_kind[side]
            if on_wall and self._closed(kind):
                n = ti.Vector(ti.static(_INWARD[side]), float)
                mu = self.bc_mu[side]
                if ti.static(self.COLUMN_FRICTION) and kind == FRICTION and corner == 1:
                    # the wall node and the ghosts beyond it are one contact point: here the
                    # normal part only; the column's Coulomb law follows (_wall_columns)
                    mu = 0.0
                    layer = (wall - I[axis]) if ti.static(low) else (I[axis] - wall)
                    self.column_dvn[side, I[1 - axis], layer] = ti.max(-v.dot(n), 0.0)
                new = self._contact_law(v, n, kind, mu, 0.0)
                if ti.static(record):
                    self._record(side, mass * (new - v), self._side_point(side, I))
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
                new = self._contact_law(v, n, kind, self.st_mu[s], target)
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
                        self._record(held_by, a * side_n - mass * (v - v_in), self._side_point(held_by, I))
                        self._record(4 + s, b * n, self._surface_point(I))
                    else:
                        self._record(4 + s, mass * (new - v), self._surface_point(I))
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
    def _on_closed_side(self, I, side: ti.template()):
        """Whether node I lies on or beyond ``side`` (0-3: left, right, bottom, top) and that side is
        closed (a contact)."""
        axis = ti.static(side // 2)
        low = ti.static(side % 2 == 0)
        wall = ti.static(PAD if low else PAD + self.cells[axis])
        on_wall = (I[axis] <= wall) if ti.static(low) else (I[axis] >= wall)
        return on_wall and self._closed(self.bc_kind[side])

    @ti.func
    def _closed_sides_at(self, I):
        """How many closed sides node I lies on or beyond (2: a corner of the box, where the
        friction law acts node by node, not by wall column)."""
        count = 0
        for side in ti.static(range(4)):
            if self._on_closed_side(I, side):
                count += 1
        return count

    @ti.func
    def _held(self, I):
        """Whether node I is a contact node of a closed side or of a structure (where
        :meth:`_contact` acts)."""
        held = self._closed_sides_at(I) > 0
        if ti.static(self.n_structures > 0):
            if self.node_struct[I] >= 0:
                held = True
        return held

    @ti.func
    def _closed(self, kind):
        """Whether a side of this kind is a contact (not open, not periodic)."""
        return kind != OPEN and kind != PERIODIC

    @ti.func
    def _contact_law(self, v, n, kind, mu, target):
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
    def _trial(self, J, trial: ti.template(), dt, damping):
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
    def _surface_target(self, I, n, trial: ti.template(), dt, damping):
        """The normal velocity a structure's contact node I may not fall below: that of the
        material's velocity field continued linearly to zero at the surface (mirror image across it
        for a node inside), ``v_n(x_r) sd / d_r``, with ``sd`` the node's signed distance and
        ``v_n(x_r)`` the material's normal velocity one cell out from the surface point nearest to
        the node, the mass-weighted mean over the free nodes of that point's stencil, ``d_r`` their
        mean distance from the surface. Zero with no free node there."""
        sd = self.node_sd[I]
        xi = ti.Vector(self.origin) + ti.cast(I - PAD, float) * self.dx
        q = xi - sd * n
        base, fx, w, dw = self._stencil(q + self.dx * n)
        mw = 0.0 * sd
        mv = 0.0 * sd
        md = 0.0 * sd
        for k in range(9):  # a runtime loop: compiled once per stage, not nine times
            J = base + ti.Vector([k // 3, k % 3])
            mass = self.g_mass[J]
            if mass > 0.0 and not self._held(J):
                wm = _bspline(fx[0], k // 3) * _bspline(fx[1], k % 3) * mass
                xj = ti.Vector(self.origin) + ti.cast(J - PAD, float) * self.dx
                mw += wm
                mv += wm * self._trial(J, trial, dt, damping).dot(n)
                md += wm * (xj - q).dot(n)
        target = 0.0 * sd
        if mw > 0.0 and md > 0.0 and sd > -self.dx:
            target = mv / md * sd
        return target

    @ti.func
    def _record(self, c, impulse, point):
        """Add an impulse on the material at ``point`` to contact ``c``'s step, with its moment."""
        j = ti.cast(impulse, ti.f64)
        p = ti.cast(point, ti.f64)
        self.contact_step[c] += ti.Vector([j[0], j[1], p[0] * j[1] - p[1] * j[0]])

    @ti.func
    def _side_point(self, side, I):
        """Node I's point on the line of ``side`` (the wall nodes and ghosts beyond it act there)."""
        p = ti.Vector(self.origin) + ti.cast(I - PAD, float) * self.dx
        if side == 0:
            p[0] = self.origin[0]
        elif side == 1:
            p[0] = self.upper[0]
        elif side == 2:
            p[1] = self.origin[1]
        else:
            p[1] = self.upper[1]
        return p

    @ti.func
    def _surface_point(self, I):
        """Node I's point on its structure's surface: along its normal by its signed distance."""
        p = ti.Vector(self.origin) + ti.cast(I - PAD, float) * self.dx
        return p - self.node_sd[I] * self.node_normal[I]

    @ti.func
    def _contact_tally(self, dt):
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
    def _damped(self, I, f, v, damping):
        """Cundall's local damping: each force component reduced by damping * |f| against the motion,
        at every node but the contact nodes.

        The damping is meant for the unbalanced force. At a contact node (:meth:`_held`) most of
        the force is the load the contact carries (the weight of the material above a base node),
        which the contact's reaction balances only after this, so damping it there took up to
        ``damping`` times that load off or put it on with the sign of the node's small residual
        velocity: the normal impulse, and with it the friction, swung between 0.3 and 1.7 times
        its value, and a 20-cell block at 40 degrees on 45 degrees of friction slid 5 mm down the
        base during a 1 s gravity stage and on in the dynamic stage (0.40 % of the frictionless
        distance; docs/validation.md). The material next to the contact is damped through its
        other nodes."""
        out = f
        if damping > 0.0 and not self._held(I):
            for d in ti.static(range(2)):
                out[d] -= damping * ti.abs(f[d]) * ti.math.sign(v[d])
        return out

    @ti.func
    def _stress_point(self, p, L, dt):
        """Constitutive update of particle p from its velocity gradient L; returns its volume."""
        Lt = transpose(L)
        D = 0.5 * (L + Lt)
        W = 0.5 * (L - Lt)
        before = self.s[p]
        s, deq, yielded = self.materials.stress_update(self.mat[p], before, D, W, dt)
        self.s[p] = s
        if ti.static(self.viscous):
            self.sv[p] = self.materials.viscous_stress(self.mat[p], self.sv[p], D, W, dt, before, s, yielded)
        self.eps_p[p] += deq
        self.yielded[p] = ti.cast(yielded, ti.i8)
        rho = self.rho[p] / (1.0 + (D[0, 0] + D[1, 1]) * dt)  # eq 24
        rho = ti.max(rho, DENSITY_FLOOR * self.materials.rho0[self.mat[p]])
        self.rho[p] = rho
        return self.m[p] / rho

    @ti.func
    def _force_stress(self, p):
        """The stress particle p's force passes use (2x2, Pa): its stress, plus its damping stress."""
        s = self.s[p]
        sig = ti.Matrix([[s[0], s[2]], [s[2], s[1]]])
        if ti.static(self.viscous):
            d = self.sv[p]
            sig += ti.Matrix([[d[0], d[2]], [d[2], d[1]]])
        return sig

    @ti.func
    def _reset_grid(self):
        lo = self.lo[None]
        width = ti.max(self.hi[None] - lo, 0)
        for k in range(width[0] * width[1]):
            I = lo + ti.Vector([k // width[1], k % width[1]])
            self.g_mass[I] = 0.0
            self.g_mom[I] = ti.Vector.zero(float, 2)
            if ti.static(self.separate_forces):
                self.g_f[I] = ti.Vector.zero(float, 2)
            if ti.static(self.has_zone):
                self.node_pn[I] = ti.Vector.zero(float, 3)
        self.lo[None] = ti.Vector([BIG, BIG])  # empty: the scatter widens it
        self.hi[None] = ti.Vector([-BIG, -BIG])

    # ------------------------------------------------------------------ walls as mirror planes
    # A closed wall sits on a node line. The ghost node one cell beyond it is reached only by
    # particles within a cell of the wall; the node one cell inside (the mirror node) misses the
    # share that material beyond the wall would give it, so a uniform stress pushes on it and the
    # stress oscillates in the boundary cells. The mirror-image method supplies that share: the
    # ghost node's force, mirrored, is added at the mirror node (what mirror-image particles beyond
    # the wall would give it), and its opposite at the wall node, so that the grid's momentum is
    # unchanged and the whole reaction passes through the contact law at the wall's nodes (its
    # normal impulse, and so its friction, and the recorded contact force).
    @ti.func
    def _wall_pairs(self, axis: ti.template(), k):
        """Side, ghost node and mirror node of the k-th node along the two walls normal to ``axis``.

        Both walls of an axis share one loop (k < 2 * nodes along the wall): a loop is a task
        with a fixed cost of its own, and two opposite walls never touch the same nodes.
        """
        along = ti.static(self.nodes[1 - axis])
        high = k // along
        side = 2 * axis + high
        wall = PAD + high * ti.static(self.cells[axis])
        step = 1 - 2 * high  # +1 into the domain from the low wall, -1 from the high one
        ghost = ti.Vector([0, 0])
        mirror = ghost
        ghost[axis] = wall - step
        mirror[axis] = wall + step
        ghost[1 - axis] = k % along
        mirror[1 - axis] = k % along
        return side, ti.cast(step, float), ghost, mirror

    @ti.func
    def _in_box(self, I):
        lo = self.lo[None]
        hi = self.hi[None]
        return lo[0] <= I[0] < hi[0] and lo[1] <= I[1] < hi[1]

    @ti.func
    def _wall_columns(self, old: ti.template()):
        """Coulomb friction of a friction side, column by column (docs/solver.md, contact).

        The wall node and the ghost nodes beyond it are one contact point (the ghosts carry the
        wall node's support beyond the wall), so the law acts on the summed tangential momentum
        ``P`` and normal impulse ``J`` of the column's approaching nodes (:meth:`_contact` removed
        their normal part and left ``dvn``, per unit mass, in ``column_dvn``, and the mirror image
        added the ghost's, :meth:`_mirror_ghosts`): stick when ``|P| <=
        mu J`` (every such node stops along the wall), else every such node slows by the same ``mu
        J / M`` (``M`` their mass), so the column loses exactly ``mu J`` of momentum and its nodes
        keep their relative velocities. Decided node by node, the base's reaction split between the
        wall row and the ghost row, with different ratios of tangential to normal force: most wall
        nodes of a stiff block resting 5 degrees from the friction limit slipped while the ghosts
        stuck, and the block slid away (a finite-element model of the same block holds)."""
        for axis in ti.static(range(2)):
            ti.loop_config(serialize=self.plain)
            for k in range(2 * self.nodes[1 - axis]):
                along = k % self.nodes[1 - axis]
                high = k // self.nodes[1 - axis]
                side = 2 * axis + high
                if self.bc_kind[side] == FRICTION:
                    wall = PAD + high * ti.static(self.cells[axis])
                    step = 1 - 2 * high
                    mass = 0.0
                    momentum = 0.0
                    normal = 0.0
                    for layer in ti.static(range(PAD + 1)):
                        J = self._column_node(axis, wall, step, layer, along)
                        dvn = self.column_dvn[side, along, layer]
                        m = self.g_mass[J]
                        if dvn > 0.0 and m > 0.0:
                            vt = self.g_v_old[J][1 - axis] if ti.static(old) else self.g_mom[J][1 - axis]
                            mass += m
                            momentum += m * vt
                            normal += m * dvn
                    if mass > 0.0:
                        mu = self.bc_mu[side]
                        speed = ti.abs(momentum)
                        slide = speed > mu * normal
                        after = 0.0
                        if slide:
                            after = momentum / mass * (speed - mu * normal) / speed
                        for layer in ti.static(range(PAD + 1)):
                            J = self._column_node(axis, wall, step, layer, along)
                            dvn = self.column_dvn[side, along, layer]
                            m = self.g_mass[J]
                            if dvn > 0.0 and m > 0.0:
                                v = self.g_v_old[J] if ti.static(old) else self.g_mom[J]
                                dv = -v[1 - axis]  # stick: the column stops along the wall
                                if slide:  # every node of the column slows by the same mu J / M
                                    dv = after - momentum / mass
                                v[1 - axis] += dv
                                impulse = ti.Vector.zero(float, 2)
                                impulse[1 - axis] = m * dv
                                self._record(side, impulse, self._side_point(side, J))
                                if ti.static(old):
                                    self.g_v_old[J] = v
                                else:
                                    self.g_mom[J] = v
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
    def _mirror_ghosts(self, old: ti.template(), record: ti.template()):
        """The ghost node's velocity across the wall becomes the mirror image of the mirror node's
        while the material there approaches the wall and the image pushes the ghost into the
        material (both components for a fixed wall), so that the velocity gradient of the particles
        in the wall cell is that of the mirror-image field; the momentum this changes is the wall's
        impulse too. On a friction wall its normal part brings Coulomb friction with it: through the
        ghost's wall column (``column_dvn``, :meth:`_wall_columns` runs next), or at the ghost
        alone (reduced by at most mu times it, never reversed) at a corner of the box."""
        for axis in ti.static(range(2)):
            ti.loop_config(serialize=self.plain)
            for k in range(2 * self.nodes[1 - axis]):
                side, inward, ghost, mirror = self._wall_pairs(axis, k)
                kind = self.bc_kind[side]
                mass = self.g_mass[ghost]
                if self._closed(kind) and mass > 0.0 and self._in_box(ghost) and self._in_box(mirror):
                    vm = self.g_v_old[mirror] if ti.static(old) else self.g_mom[mirror]
                    vg = self.g_v_old[ghost] if ti.static(old) else self.g_mom[ghost]
                    mu = self.bc_mu[side]
                    column = False
                    if ti.static(self.COLUMN_FRICTION) and kind == FRICTION:
                        column = self._closed_sides_at(ghost) == 1  # not a corner of the box
                    if column:
                        mu = 0.0  # the ghost is part of its wall column: friction there (_wall_columns)
                    new = self._ghost_image(kind, axis, inward, vm, vg, mu)
                    if column:
                        self.column_dvn[side, k % self.nodes[1 - axis], 1] += (new[axis] - vg[axis]) * inward
                    if ti.static(record):
                        self._record(side, mass * (new - vg), self._side_point(side, ghost))
                    if ti.static(old):
                        self.g_v_old[ghost] = new
                    else:
                        self.g_mom[ghost] = new

    @ti.func
    def _ghost_image(self, kind, axis: ti.template(), inward, vm, vg, mu):
        """The ghost node's new velocity (see :meth:`_mirror_ghosts`) from the mirror node's ``vm``
        and its own ``vg``, for a wall across ``axis`` whose material lies towards ``inward``.
        Never a pull: where the ghost already moves into the material faster than the image, the
        image would hold it back, a tension on the wall that the friction, taken from the pushing
        impulses, did not see (classic mpm's stiff sheets, docs/solver.md, walls as mirror planes)."""
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
    def _mirror_forces(self, dt, g, fused: ti.template()):
        for axis in ti.static(range(2)):
            # a few hundred nodes: on a CPU with few threads one thread beats waking the pool
            ti.loop_config(serialize=self.plain)
            for k in range(2 * self.nodes[1 - axis]):
                side, inward, ghost, mirror = self._wall_pairs(axis, k)
                along = k % self.nodes[1 - axis]
                if self._closed(self.bc_kind[side]) and self._in_box(ghost) and self._in_box(mirror):
                    wall = (ghost + mirror) // 2
                    # the ghost's force, mirrored: across the wall always reversed; along it kept
                    # for a slip wall (symmetric image) and reversed where the wall holds the
                    # material along it (fixed, friction: antisymmetric image)
                    flip = ti.Vector([-1.0, -1.0])
                    if self.bc_kind[side] == SLIP:
                        flip[1 - axis] = 1.0
                    if ti.static(fused):  # apic-affine: the ghost's force was summed apart
                        f = flip * self.ghost_f[side, along] * dt
                        self.g_mom[mirror] += f
                        self.g_mom[wall] -= f
                    else:
                        f = flip * self.g_f[ghost]
                        self.g_f[mirror] += f
                        self.g_f[wall] -= f
                if ti.static(fused):
                    self.ghost_f[side, along] = ti.Vector.zero(float, 2)  # ready for the next step
        if ti.static(self.n_structures > 0):
            self._mirror_structures(g)

    @ti.func
    def _mirror_structures(self, g):
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
        reach = ti.static(MIRROR_REACH_CELLS * self.dx)
        ti.loop_config(serialize=self.plain)
        for p in range(self.n):
            if self.active[p]:
                x = self.x[p]
                for st in range(self.n_structures):
                    box = self.st_box[st]
                    if box[0] - reach <= x[0] <= box[2] + reach and box[1] - reach <= x[1] <= box[3] + reach:
                        self._mirror_particle(p, st, x, g)

    @ti.func
    def _corner_particle_normals(self):
        """The weighted outward normal of the material at each zone node (see
        :meth:`_structure_normal`): every particle in a structure's zone box adds its weight x mass
        x the outward normal at its nearest surface point, ``(x - q) / |x - q|``, and its weight
        x mass, to its stencil's zone nodes of that structure (node_pn, cleared by the grid reset).
        As in :meth:`_mirror_structures`: in one thread with plain adds (serial and split scatters),
        so the sums repeat bit for bit; in parallel with atomic adds (GPU)."""
        ti.loop_config(serialize=self.plain)
        for p in range(self.n):
            if self.active[p]:
                x = self.x[p]
                for st in range(self.n_structures):
                    box = self.st_zone_box[st]
                    if box[0] <= x[0] <= box[2] and box[1] <= x[1] <= box[3]:
                        q, best, inside = self._nearest_surface_point(st, x)
                        dist = ti.sqrt(best)
                        if inside == 0 and dist > 0.0:
                            n = (x - q) / dist
                            base, fx, w, dw = self._stencil(x)
                            m = self.m[p]
                            for k in range(9):  # a runtime loop: compiled once, not nine times
                                I = base + ti.Vector([k // 3, k % 3])
                                if ti.abs(self.node_zone[I]) == st + 1:
                                    wm = _bspline(fx[0], k // 3) * _bspline(fx[1], k % 3) * m
                                    self.node_pn[I] += ti.Vector([wm * n[0], wm * n[1], wm])

    @ti.func
    def _nearest_surface_point(self, st, x):
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
        """Particle p's image across structure ``st`` (see :meth:`_mirror_structures`)."""
        q, best, inside = self._nearest_surface_point(st, x)
        dist = ti.sqrt(best)
        reach = ti.static(MIRROR_REACH_CELLS * self.dx)
        if inside == 0 and dist > 0.0 and dist < reach:
            n = (x - q) / dist
            R = ti.Matrix.identity(float, 2) - 2.0 * n.outer_product(n)
            F = -ti.Matrix.identity(float, 2)
            if self.st_kind[st] == SLIP:
                F = R
            sig = F @ self._force_stress(p) @ R
            m = self.m[p]
            vol = m / self.rho[p]
            body = F @ (m * g)
            # only where the particle's stencil reaches a contact node of this structure
            base, fx, w, dw = self._stencil(x)
            held = 0.0
            for i, j in ti.static(ti.ndrange(3, 3)):
                if self.node_struct[base + ti.Vector([i, j])] == st:
                    held += w[i][0] * w[j][1]
            if held > 0.0:
                ibase, ifx, iw, idw = self._stencil(2.0 * q - x)
                for i, j in ti.static(ti.ndrange(3, 3)):
                    I = ibase + ti.Vector([i, j])
                    if self._in_box(I) and not self._held(I):
                        # only nodes on the particle's side of the surface: beyond a thin part
                        # the image's stencil reaches the material on its far side
                        xi = ti.Vector(self.origin) + ti.cast(I - PAD, float) * self.dx
                        if self.g_mass[I] > 0.0 and (xi - q).dot(n) > 0.0:
                            grad = ti.Vector([idw[i][0] * iw[j][1], iw[i][0] * idw[j][1]]) * self.inv_dx
                            f = -vol * mat_vec(sig, grad) + iw[i][0] * iw[j][1] * body
                            self.g_f[I] += f
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
        xi = ti.Vector(self.origin) + ti.cast(I - PAD, float) * self.dx
        mbase, mfx, mw, mdw = self._stencil(xi - 2.0 * (xi - q).dot(n) * n)
        near = 0.0 * held
        for k in range(9):  # runtime loops: this path runs 9 times per image, compiled once
            K = mbase + ti.Vector([k // 3, k % 3])
            if self._takes_reaction(K, st, n):
                near += _bspline(mfx[0], k // 3) * _bspline(mfx[1], k % 3) * self.g_mass[K]
        for k in range(9):
            if near > 0.0:
                K = mbase + ti.Vector([k // 3, k % 3])
                if self._takes_reaction(K, st, n):
                    self.g_f[K] -= (_bspline(mfx[0], k // 3) * _bspline(mfx[1], k % 3) * self.g_mass[K] / near) * f
            else:
                K = base + ti.Vector([k // 3, k % 3])
                if self.node_struct[K] == st:
                    self.g_f[K] -= (_bspline(fx[0], k // 3) * _bspline(fx[1], k % 3) / held) * f

    @ti.func
    def _takes_reaction(self, K, st, n):
        """Whether node K, near the mirror point of a free node, takes the reaction of an image of
        structure ``st`` whose surface normal is ``n``: a contact node of it that holds mass (the
        contact law acts only there) and does not face the other way (a thin wall's far face)."""
        return self.node_struct[K] == st and self.g_mass[K] > 0.0 and self.node_normal[K].dot(n) >= 0.0

    @ti.func
    def _ghost_particle(self, p, g):
        """Add particle p's force at ghost nodes beyond closed walls to ``ghost_f``.

        The apic-affine P2G fuses the forces into the momentum; this part of its pass keeps the
        ghost nodes' force apart too (per side, along the wall), so that the mirror forces can pass
        the wall's reaction through the contact law. It reads the stress and density the
        particle's update left. Only particles within a cell of a closed wall reach a ghost node;
        the others cost one test each. A corner ghost (beyond two walls) keeps the fused form.
        """
        base, fx, w, dw = self._stencil(self.x[p])
        ghost_lo = ti.Vector([0, 0])
        ghost_hi = ti.Vector([0, 0])
        for d in ti.static(range(2)):
            ghost_lo[d] = base[d] == PAD - 1 and self._closed(self.bc_kind[2 * d])
            ghost_hi[d] = base[d] == PAD + self.cells[d] - 1 and self._closed(self.bc_kind[2 * d + 1])
        if ghost_lo[0] or ghost_lo[1] or ghost_hi[0] or ghost_hi[1]:
            sig = self._force_stress(p)
            m = self.m[p]
            vol = m / self.rho[p]
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
                    wx = _bspline(fx[0], i)
                    wy = _bspline(fx[1], j)
                    grad = ti.Vector([_bspline_slope(fx[0], i) * wy,
                                      wx * _bspline_slope(fx[1], j)]) * self.inv_dx
                    force = -vol * mat_vec(sig, grad) + wx * wy * m * g
                    I = base + ti.Vector([i, j])
                    # atomic where threads share the pass: few particles get here. In the split
                    # scatter a ghost node, like any node, belongs to one band.
                    if x_side >= 0:
                        self.ghost_f[x_side, I[1]] += force
                    else:
                        self.ghost_f[y_side, I[0]] += force

    # ------------------------------------------------------------------ particle passes
    # P2G and the force scatter visit every active particle: an update that writes the particle's
    # own fields (its constitutive update), then the adds of its shares to the grid. The scatter
    # strategy (``self.to_grid``, solver/scatter.py) runs the loops and makes the adds.
    @ti.func
    def _update_particle(self, kind: ti.template(), p, dt):
        """The update of particle p in a pass of ``kind`` (see :meth:`_add_particle`); its volume."""
        vol = 0.0 * dt
        if ti.static(kind == "affine"):
            vol = self._stress_point(p, self.C[p], dt)  # eqs 29-30: D = sym(C), W = skew(C)
        elif ti.static(kind == "force"):
            vol = self._stress_from_grid_point(p, dt)
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
        internal and body force. ``vol``: the particle's volume after its update (m2 per m)."""
        if ti.static(part == "wall forces"):
            self._ghost_particle(p, g)
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
        sig = self._force_stress(p)
        m = self.m[p]
        mv = m * self.v[p]
        mC = m * self.C[p]
        for i, j in ti.static(ti.ndrange(3, 3)):
            offset = ti.Vector([i, j])
            dpos = (ti.cast(offset, float) - fx) * self.dx
            weight = w[i][0] * w[j][1]
            grad = ti.Vector([dw[i][0] * w[j][1], w[i][0] * dw[j][1]]) * self.inv_dx
            force = -vol * mat_vec(sig, grad) + weight * m * g
            I = base + offset
            self.to_grid.add(self.g_mass, I, weight * m)
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
                    self.g_mom[I] = self._contact(I, v, mass, True, "fused", dt, damping)
            else:
                self.g_mom[I] = ti.Vector.zero(float, 2)
        if ti.static(self.n_structures > 0):
            for k in range(width[0] * width[1]):
                I = lo + ti.Vector([k // width[1], k % width[1]])
                mass = self.g_mass[I]
                if mass > 0.0 and self._held(I):
                    self.g_mom[I] = self._contact(I, self.g_mom[I], mass, True, "fused", dt, damping)

    # ------------------------------------------------------------------ six-stage (mpm, apic)
    @ti.func
    def _momentum_particle(self, p):
        """Mass and momentum (FLIP or APIC) of particle p to its nodes."""
        base, fx, w, dw = self._stencil(self.x[p])
        self.to_grid.cover(self, base)
        m = self.m[p]
        mv = m * self.v[p]
        mC = m * self.C[p]
        for i, j in ti.static(ti.ndrange(3, 3)):
            offset = ti.Vector([i, j])
            weight = w[i][0] * w[j][1]
            I = base + offset
            self.to_grid.add(self.g_mass, I, weight * m)
            if ti.static(self.scheme == "apic"):
                dpos = (ti.cast(offset, float) - fx) * self.dx
                self.to_grid.add(self.g_mom, I, weight * (mv + mat_vec(mC, dpos)))
            else:
                self.to_grid.add(self.g_mom, I, weight * mv)

    @ti.func
    def _grid_velocity(self):
        lo = self.lo[None]
        width = ti.max(self.hi[None] - lo, 0)
        for k in range(width[0] * width[1]):
            I = lo + ti.Vector([k // width[1], k % width[1]])
            mass = self.g_mass[I]
            v = ti.Vector.zero(float, 2)
            if ti.static(self.n_structures > 0 and self.six_stage):
                self.node_hold_dv[I] = ti.Vector.zero(float, 2)  # _contact sets it where it holds
            if mass > 0.0:
                # the contact law on the interpolated velocity too (Bardenhagen et al. 2000): the
                # stress update sees the constrained velocity. APIC's particles take the new grid
                # velocity, so they receive this correction (an impulse of the contact). FLIP's take
                # the increment v_new - v_old from ordinary nodes but, at contact nodes, the new
                # velocity itself (PIC there, see _g2p), so they receive it too: recorded in
                # every scheme.
                v = self._contact(I, self.g_mom[I] / mass, mass, True, "interpolated", 0.0, 0.0)
            self.g_v_old[I] = v

    @ti.func
    def _stress_from_grid_point(self, p, dt):
        """Velocity gradient from the grid velocities, then the constitutive update; the volume."""
        base, fx, w, dw = self._stencil(self.x[p])
        L = ti.Matrix.zero(float, 2, 2)
        for i, j in ti.static(ti.ndrange(3, 3)):
            grad = ti.Vector([dw[i][0] * w[j][1], w[i][0] * dw[j][1]]) * self.inv_dx
            J = base + ti.Vector([i, j])
            v = self.g_v_old[J]
            if ti.static(self.n_structures > 0 and self.six_stage):
                v += self.node_hold_dv[J]  # the structures' hold (_contact)
            L += outer(v, grad)
        return self._stress_point(p, L, dt)

    @ti.func
    def _force_particle(self, p, vol, g):
        base, fx, w, dw = self._stencil(self.x[p])
        sig = self._force_stress(p)
        m = self.m[p]
        for i, j in ti.static(ti.ndrange(3, 3)):
            weight = w[i][0] * w[j][1]
            grad = ti.Vector([dw[i][0] * w[j][1], w[i][0] * dw[j][1]]) * self.inv_dx
            self.to_grid.add(self.g_f, base + ti.Vector([i, j]), -vol * mat_vec(sig, grad) + weight * m * g)

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
                self.g_mom[I] = self._contact(I, v + dt * f / mass, mass, True, "updated", dt, damping)
            else:
                self.g_mom[I] = ti.Vector.zero(float, 2)

    # ------------------------------------------------------------------ G2P (all schemes)
    @ti.func
    def _g2p(self, dt):
        bound2 = self.speed_bound[None] ** 2
        for p in range(self.n):
            if self.active[p]:
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
                        if self._held(base + offset):
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
                if ti.static(self.periodic):  # across the periodic line: in at the other side
                    width = ti.static(self.upper[0] - self.origin[0])
                    shift = 0.0 * width
                    if x[0] < self.origin[0]:
                        shift = width
                    elif x[0] >= self.upper[0]:
                        shift = -width
                    if shift != 0.0:
                        x[0] += shift
                        self.x0[p][0] += shift  # displacements go on from where they were
                # a particle the guard removed is not also counted lost
                for d in ti.static(range(1 if self.periodic else 0, 2)):
                    if x[d] < self.origin[d]:
                        if self.bc_kind[2 * d] == OPEN:
                            keep = -1 if keep == 1 else keep
                        else:
                            x[d] = self.origin[d]
                    if x[d] > self.upper[d]:
                        if self.bc_kind[2 * d + 1] == OPEN:
                            keep = -1 if keep == 1 else keep
                        else:
                            x[d] = self.upper[d]
                if ti.static(self.n_structures > 0):
                    x, v = self._push_out(self.x[p], x, v, self.m[p])
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
    def _push_out(self, x_old, x, v, mass):
        """A particle that ended inside a structure goes back to where its move ``x_old -> x``
        entered it: the first crossing of the path with the outline, PUSH_OUT_CELLS cells out on
        the side it came from, never through a thin structure to its far face (with no crossing,
        a particle that started inside, the nearest point of the surface). Its velocity into the
        structure (along the crossed edge's normal) is removed: an impulse of that structure's
        contact."""
        for s in range(self.n_structures):
            box = self.st_box[s]
            if box[0] <= x[0] <= box[2] and box[1] <= x[1] <= box[3]:
                nearest, _d2, inside = self._nearest_surface_point(s, x)
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
                        x = nearest + (PUSH_OUT_CELLS * self.dx) * n
                        vn = v.dot(n)
                        if vn < 0.0:
                            v -= vn * n
                            self._record(4 + s, -mass * vn * n, x)
        return x, v

    # ------------------------------------------------------------------ diagnostics
    @ti.kernel
    def _diagnostics(self, out: ti.types.ndarray(dtype=ti.f64, ndim=1)):
        for k in ti.static(range(8)):
            self.diag[k] = 0.0
        # with the plain-add scatters (serial, split) the sums run in one thread, in particle
        # order, so the energies and momenta of series.csv repeat bit for bit as the frames do
        ti.loop_config(serialize=self.plain)
        for p in range(self.n):
            if self.active[p]:
                m = self.m[p]
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


def _contact_codes(contacts) -> tuple[np.ndarray, np.ndarray]:
    """Kind codes and friction coefficients (zero unless ``friction``) of a list of Boundary."""
    kinds = np.array([BOUNDARY_CODES[c.kind] for c in contacts], np.int32)
    mus = np.array([np.tan(c.friction_angle_rad) if c.kind == "friction" else 0.0 for c in contacts])
    return kinds, mus
