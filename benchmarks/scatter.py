"""What a P2G scatter costs on this CPU: ``python benchmarks/scatter.py [--particles N] [--threads T]``.

The measurement behind the scatter strategies (``solver/scatter.py``). A bare quadratic B-spline
scatter (mass and a two-component momentum to the 3 x 3 nodes of each particle, 27 adds per
particle; particles on a lattice, 2 x 2 per cell) is timed in three forms, best of 5 rounds of 100 launches:

- ``parallel atomic``: every particle in parallel, float atomic adds (what GPUs do);
- ``serial plain``: one thread, plain adds (``ti.loop_config(serialize=True)``);
- ``parallel plain (racy)``: every particle in parallel with plain adds: wrong results, shown
  only for speed. Taichi hands the threads interleaved blocks of particles, so neighbouring
  threads write the same cache lines; it is no bound for a schedule that gives each thread its
  own band of the grid, as the engine's ``split`` scatter does.

On a CPU with few threads the engine adds with plain adds (``serial``, or ``split`` for large
runs) because there ``serial plain`` already beats ``parallel atomic``.
"""

import argparse
import os
import sys
import time

import numpy as np


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--particles", type=int, default=20_000)
    parser.add_argument("--threads", type=int, default=None, help="Taichi CPU threads (default: all cores)")
    args = parser.parse_args(argv)
    os.environ.setdefault("ENABLE_TAICHI_HEADER_PRINT", "0")
    import taichi as ti

    kwargs = {} if args.threads is None else {"cpu_max_num_threads": args.threads}
    ti.init(arch=ti.cpu, default_fp=ti.f32, log_level=ti.WARN, **kwargs)

    cols = 200
    rows = max(1, args.particles // cols)
    n = cols * rows
    nodes = (cols // 2 + 8, rows // 2 + 8)
    x = ti.Vector.field(2, float, n)
    mass = ti.field(float, nodes)
    momentum = ti.Vector.field(2, float, nodes)
    lattice = np.stack(np.meshgrid(np.arange(cols), np.arange(rows), indexing="xy"), -1).reshape(-1, 2)
    x.from_numpy((lattice * 0.5 + 2.25).astype(np.float32))  # in cell units, 2 x 2 per cell

    @ti.func
    def scatter_one(p, plain: ti.template()):
        xp = x[p]
        base = ti.cast(xp - 0.5, ti.i32)
        fx = xp - ti.cast(base, float)
        w = [0.5 * (1.5 - fx) ** 2, 0.75 - (fx - 1.0) ** 2, 0.5 * (fx - 0.5) ** 2]
        for i, j in ti.static(ti.ndrange(3, 3)):
            node = base + ti.Vector([i, j])
            weight = w[i][0] * w[j][1]
            if ti.static(plain):
                mass[node] = mass[node] + weight
                momentum[node] = momentum[node] + weight * xp
            else:
                mass[node] += weight
                momentum[node] += weight * xp

    @ti.kernel
    def parallel_atomic():
        for p in range(n):
            scatter_one(p, False)

    @ti.kernel
    def serial_plain():
        ti.loop_config(serialize=True)
        for p in range(n):
            scatter_one(p, True)

    @ti.kernel
    def parallel_plain_racy():
        for p in range(n):
            scatter_one(p, True)

    forms = {"parallel atomic": parallel_atomic, "serial plain": serial_plain,
             "parallel plain (racy)": parallel_plain_racy}
    times = {}
    for name, kernel in forms.items():
        kernel()
        ti.sync()
        best = float("inf")
        for _ in range(5):
            t0 = time.perf_counter()
            for _ in range(100):
                kernel()
            ti.sync()
            best = min(best, (time.perf_counter() - t0) / 100)
        times[name] = best
    threads = ti.lang.impl.current_cfg().cpu_max_num_threads
    print(f"scatter of {n:,} particles, {threads} CPU threads, ms per pass (best of 5 x 100):")
    for name, t in times.items():
        print(f"  {name:24s} {t * 1e3:7.3f} ms   {times['parallel atomic'] / t:5.2f}x of parallel atomic")
    return 0


if __name__ == "__main__":
    sys.exit(main())
