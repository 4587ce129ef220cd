"""How particle contributions reach the grid: the scatter strategies (docs/solver.md, "Scatter").

A particle pass of the engine (P2G, the force scatter) has two parts per particle: an *update*
that writes the particle's own fields only (the constitutive update; it returns the particle's
volume) and the *adds* of its shares to the 3 x 3 grid nodes around it, which neighbouring
particles share. The physics of both parts is the engine's (``Engine._update_particle``,
``Engine._add_particle``); a strategy decides how the passes run and how an add reaches a node:

- ``atomic``: every particle in parallel, update and adds in one loop, float atomic adds. What a
  GPU (and a CPU with many threads) uses.
- ``serial``: the updates in a parallel loop, then one thread adds every particle's shares with
  plain adds.
- ``split``: the grid is cut into one band of node lines per thread, across the longer side of
  the particles' box, at the quantiles of the particle positions of the last step; each thread
  updates and adds, with plain adds, the particles in its band, except those whose stencil
  crosses a cut, which one thread adds afterwards.

With plain adds (serial, split) every sum comes in a fixed order (which band a particle belongs
to depends on positions only, never on timing), so a run repeats bit for bit. On the CPU a float
atomic add is a compare-and-swap loop: on the development machine the atomic scatter costs about
four times the plain one per particle (benchmarks/scatter.py), so with few threads plain adds win.

The strategy is chosen once, when the engine is built (:func:`make_scatter`). Its ``ti.func``s
take the engine as a template argument and call back into its per-particle physics.
"""


import numpy as np
from solver.runtime import ti

from solver.config import SCATTERS

#: ``auto`` picks ``atomic`` on a GPU and on a CPU with more threads than this.
SERIAL_SCATTER_MAX_THREADS = 4
#: ``auto`` on a CPU with few threads: ``split`` from this many particles on, ``serial`` below (the
#: split recipe takes about 4 s longer to compile, which a small run does not earn back).
SPLIT_MIN_PARTICLES = 10_000
#: Loop iterations a Taichi 1.7 CPU thread takes at a time (measured; see :meth:`Split.particles`).
CPU_GRAIN = 512
#: Larger than any node index: the bounds of an empty node box.
BIG = 1 << 30
#: The particle passes that build the box of written nodes (P2G); the others (the six-stage force
#: pass, the volumetric averaging's dilatation pass) run on the stencils of one of them.
BOX_PASSES = ("momentum", "affine")
#: Every strategy's checkpoint fields (see ``Scatter.STATE``).
SCATTER_STATE = ("band", "cut", "cut_axis", "band_range", "band_count")


def resolve_scatter(scatter: str, n_particles: int) -> str:
    """``atomic``, ``serial`` or ``split`` for the Taichi runtime in use and the particle count
    (see :data:`solver.config.SCATTERS`)."""
    if scatter not in SCATTERS:
        raise ValueError(f"unknown scatter {scatter!r}; allowed: {', '.join(SCATTERS)}")
    cfg = ti.lang.impl.current_cfg()
    cpu = cfg.arch in (ti.x64, ti.arm64)
    if scatter == "auto":
        if not cpu or cfg.cpu_max_num_threads > SERIAL_SCATTER_MAX_THREADS:
            return "atomic"
        return "split" if n_particles >= SPLIT_MIN_PARTICLES else "serial"
    if scatter in ("serial", "split") and not cpu:
        raise ValueError(f"the {scatter} scatter runs on a CPU only; allowed on a GPU: auto, atomic")
    return scatter


def make_scatter(scatter: str, n_particles: int, nodes: tuple[int, int], bands: int | None = None) -> "Scatter":
    """The strategy for ``scatter`` (see :func:`resolve_scatter`) on a grid of ``nodes`` nodes.

    ``bands``: the split scatter's band count (default: one per CPU thread), e.g. to test more
    cuts; ignored by the other strategies.
    """
    if bands is not None and not 1 <= bands <= 63:
        raise ValueError(f"bands must be from 1 to 63, got {bands}")
    name = resolve_scatter(scatter, n_particles)
    if name == "split":
        return Split(n_particles, nodes, bands or min(ti.lang.impl.current_cfg().cpu_max_num_threads, 63))
    return Serial() if name == "serial" else Atomic()


@ti.data_oriented
class Scatter:
    """What every strategy offers the engine's kernels.

    ``plain``: adds are plain (no two threads ever add to one value); the engine then also runs
    its short loops (a few hundred wall nodes) in one thread, where waking the thread pool costs
    more than the work, and their sums come in a fixed order. ``STATE``: the names of the fields
    a checkpoint must hold to repeat the next steps bit for bit.
    """

    name = ""
    plain = True
    STATE: tuple[str, ...] = ()

    def state_fields(self) -> dict:
        """The fields named in ``STATE`` (the engine moves them with its own, in one kernel)."""
        return {name: getattr(self, name) for name in self.STATE}

    def start_state(self) -> dict:
        """Values of the ``STATE`` fields that forget what earlier steps taught (new particles
        were loaded)."""
        return {}

    @ti.func
    def add(self, field: ti.template(), I, value):
        """Add ``value`` to ``field[I]`` (a grid node)."""
        field[I] = field[I] + value

    @ti.func
    def cover(self, engine: ti.template(), base):
        """Take the stencil ``base .. base + 2`` of a particle into the engine's box of written nodes."""
        engine.lo[None] = ti.min(engine.lo[None], base)
        engine.hi[None] = ti.max(engine.hi[None], base + 3)

    @ti.func
    def moved(self, engine: ti.template(), p, x):
        """Particle ``p`` (still active) has moved to ``x`` (G2P)."""
        pass


@ti.data_oriented
class Atomic(Scatter):
    """All particles in parallel, update and adds in one loop, float atomic adds."""

    name = "atomic"
    plain = False

    @ti.func
    def add(self, field: ti.template(), I, value):
        field[I] += value

    @ti.func
    def cover(self, engine: ti.template(), base):
        # read before writing: an atomic on one shared value from every particle serialises the
        # threads, and once the box is known few particles widen it
        lo = engine.lo[None]
        hi = engine.hi[None]
        if base[0] < lo[0] or base[1] < lo[1]:
            ti.atomic_min(engine.lo[None], base)
        if base[0] + 3 > hi[0] or base[1] + 3 > hi[1]:
            ti.atomic_max(engine.hi[None], base + 3)

    @ti.func
    def particles(self, engine: ti.template(), kind: ti.template(), dt, g, fuse_force: ti.template()):
        """One particle pass of the engine (``kind``: see ``Engine._add_particle``): the update and
        the first part of the adds in one loop, each further part in a loop of its own."""
        for p in range(engine.n):
            if engine.active[p]:
                vol = engine._update_particle(kind, p, dt)
                for part in ti.static(engine.pass_parts(kind, fuse_force)[:1]):
                    engine._add_particle(kind, part, p, vol, dt, g, fuse_force)
        for part in ti.static(engine.pass_parts(kind, fuse_force)[1:]):
            for p in range(engine.n):
                if engine.active[p]:
                    engine._add_particle(kind, part, p, engine.m[p] / engine.rho[p], dt, g, fuse_force)


@ti.data_oriented
class Serial(Scatter):
    """The updates in parallel, then every particle's adds in one thread, in index order."""

    name = "serial"

    @ti.func
    def particles(self, engine: ti.template(), kind: ti.template(), dt, g, fuse_force: ti.template()):
        if ti.static(kind != "momentum"):  # the momentum pass updates nothing
            for p in range(engine.n):
                if engine.active[p]:
                    engine._update_particle(kind, p, dt)
        for part in ti.static(engine.pass_parts(kind, fuse_force)):
            ti.loop_config(serialize=True)
            for p in range(engine.n):
                if engine.active[p]:
                    engine._add_particle(kind, part, p, engine.m[p] / engine.rho[p], dt, g, fuse_force)


@ti.data_oriented
class Split(Scatter):
    """One band of node lines per thread, plain adds; the particles whose stencil crosses a cut
    are added by one thread afterwards.

    Fields: per band the stencil range (min and max base node) of its particles in the last
    scatter, 16 ints a row so that no two threads write one cache line (``band_range``); how many
    of its particles sat on each node line along either axis (``band_count``); the cuts between
    the bands along ``cut_axis`` (``cut``); and each particle's band code (``band``: b, or
    b + n_bands where its stencil crosses the cut above; one signed byte), assigned in G2P from its
    new position.
    """

    name = "split"
    STATE = SCATTER_STATE

    def __init__(self, n_particles: int, nodes: tuple[int, int], n_bands: int):
        self.n_bands = int(n_bands)
        self.nodes = nodes
        self.band_range = ti.field(ti.i32, (self.n_bands, 16))
        self.band_count = ti.field(ti.i32, (self.n_bands, 2, max(nodes)))
        self.cut = ti.field(ti.i32, self.n_bands + 1)
        self.cut_axis = ti.field(ti.i32, ())
        self.band = ti.field(ti.i8, max(1, n_particles))

    def start_state(self) -> dict:
        ranges = np.zeros((self.n_bands, 16), np.int32)
        ranges[:, :2], ranges[:, 2:4] = BIG, -BIG
        # nothing counted yet: one band over the whole grid, so the first split scatter is one thread's
        return {"band_range": ranges, "band_count": 0, "cut": np.array([-BIG] * self.n_bands + [BIG], np.int32),
                "cut_axis": 0, "band": self.n_bands - 1}

    @ti.func
    def cover(self, engine: ti.template(), base):
        pass  # the box comes from the bands' stencil ranges at the end of the pass

    @ti.func
    def moved(self, engine: ti.template(), p, x):
        self.band[p] = self._band_of(engine, x)

    @ti.func
    def particles(self, engine: ti.template(), kind: ti.template(), dt, g, fuse_force: ti.template()):
        """A particle pass in ``n_bands`` threads with plain adds.

        The ``momentum`` and ``affine`` passes also build the engine's box of written nodes and
        count the particles per node line for the next step's bands; the ``force`` and
        ``dilatation`` passes come with one of those in the same step (same positions, same bands).
        """
        T = ti.static(self.n_bands)
        # One band per thread: Taichi 1.7 hands a CPU thread 512 consecutive iterations of a loop at
        # a time (whatever loop_config's block_dim says) and runs a loop of up to 512 in one thread,
        # so the band loop runs CPU_GRAIN iterations per band and the first of each does the work.
        for t in range(T * CPU_GRAIN):
            if t % CPU_GRAIN != 0:
                continue
            k = t // CPU_GRAIN
            lo = ti.Vector([BIG, BIG])
            hi = ti.Vector([-BIG, -BIG])
            for p in range(engine.n):  # a byte per particle tells each thread which are its own
                b = ti.cast(self.band[p], ti.i32)
                if engine.active[p] and (b == k or b == k + T):
                    vol = engine._update_particle(kind, p, dt)
                    if ti.static(kind in BOX_PASSES):
                        base, fx, w, dw = engine._stencil(engine.x[p])
                        lo = ti.min(lo, base)
                        hi = ti.max(hi, base)
                        for d in ti.static(range(2)):  # positions along both axes, for the next plan
                            self.band_count[k, d, base[d]] = self.band_count[k, d, base[d]] + 1
                    if b == k:
                        for part in ti.static(engine.pass_parts(kind, fuse_force)):
                            engine._add_particle(kind, part, p, vol, dt, g, fuse_force)
            if ti.static(kind in BOX_PASSES):
                for d in ti.static(range(2)):
                    self.band_range[k, d] = lo[d]
                    self.band_range[k, 2 + d] = hi[d]
        if ti.static(kind in BOX_PASSES):
            ti.loop_config(serialize=True)
            for _ in range(1):  # the box of written nodes, and the bands of the next step
                lo = ti.Vector([BIG, BIG])
                hi = ti.Vector([-BIG, -BIG])
                for k in range(T):
                    for d in ti.static(range(2)):
                        lo[d] = ti.min(lo[d], self.band_range[k, d])
                        hi[d] = ti.max(hi[d], self.band_range[k, 2 + d] + 3)
                engine.lo[None] = lo
                engine.hi[None] = hi
                self._plan_bands(hi - lo)
        ti.loop_config(serialize=True)  # the particles whose stencil crosses a cut, in index order
        for p in range(engine.n):
            if engine.active[p] and self.band[p] >= T:
                for part in ti.static(engine.pass_parts(kind, fuse_force)):
                    engine._add_particle(kind, part, p, engine.m[p] / engine.rho[p], dt, g, fuse_force)

    @ti.func
    def _band_of(self, engine: ti.template(), xp):
        """The band code of a particle at ``xp`` (see :class:`Split`)."""
        base, fx, w, dw = engine._stencil(xp)
        u = base[0] if self.cut_axis[None] == 0 else base[1]
        b = 0
        for k in range(1, self.n_bands):
            if u >= self.cut[k]:
                b = k
        if u + 3 > self.cut[b + 1]:  # the stencil crosses the cut above
            b += self.n_bands
        return ti.cast(b, ti.i8)

    @ti.func
    def _plan_bands(self, extent):
        """Cut the grid into one band of node lines per thread, with equal particle counts.

        The bands run across the longer side of the box (``extent``, in nodes; the cuts are then
        short and few particles straddle them) and the cuts sit at the quantiles of the particles'
        stencil positions counted in this scatter. Whatever those counts, the bands never share a
        node: they only decide how many particles are left to the serial remainder.
        """
        axis = 0 if extent[0] >= extent[1] else 1
        self.cut_axis[None] = axis
        lines = self.nodes[0] if axis == 0 else self.nodes[1]
        total = 0
        for u in range(lines):
            for k in range(self.n_bands):
                total += self.band_count[k, axis, u]
        self.cut[0] = -BIG
        self.cut[self.n_bands] = BIG
        j = 1
        below = 0  # particles on node lines below u
        for u in range(lines):
            while j < self.n_bands and below * self.n_bands >= j * total:
                self.cut[j] = u
                j += 1
            for k in range(self.n_bands):
                below += self.band_count[k, axis, u]
        while j < self.n_bands:
            self.cut[j] = lines
            j += 1
        for k in range(self.n_bands):  # counted afresh by the next scatter
            for d in ti.static(range(2)):
                for u in range(self.nodes[d]):
                    self.band_count[k, d, u] = 0
