"""Cost of one Taichi kernel launch on this machine: ``python benchmarks/launch_overhead.py``.

Evidence for the engine recommendations in ``docs/performance.md``: a step of ``apic-affine``
launches six kernels (nine tasks), the yardstick one. Times tiny kernels (1,000 elements, so the
work is negligible) called from Python: with no arguments, with the engine's ``(dt, gravity
vector)`` arguments (the vector built per call, as ``Engine.step`` does, or once), with gravity
as two floats, with a template argument, and six such loops fused in one kernel. Prints
microseconds per launch (best of 3).
"""

import os
import sys
import time


def main() -> int:
    os.environ.setdefault("ENABLE_TAICHI_HEADER_PRINT", "0")
    import taichi as ti

    ti.init(arch=ti.cpu, log_level=ti.WARN)

    @ti.data_oriented
    class Probe:
        def __init__(self, n: int):
            self.n = n
            self.f = ti.field(float, n)

        @ti.kernel
        def plain(self):
            for i in range(self.n):
                self.f[i] += 1.0

        @ti.kernel
        def with_vector(self, dt: float, g: ti.types.vector(2, float)):
            for i in range(self.n):
                self.f[i] += dt * g[1]

        @ti.kernel
        def with_floats(self, dt: float, gx: float, gy: float):
            for i in range(self.n):
                self.f[i] += dt * gy

        @ti.kernel
        def with_template(self, dt: float, flag: ti.template()):
            for i in range(self.n):
                self.f[i] += dt if ti.static(flag) else 0.0

        @ti.kernel
        def six_loops(self, dt: float):
            for i in range(self.n):
                self.f[i] += dt
            for i in range(self.n):
                self.f[i] += dt
            for i in range(self.n):
                self.f[i] += dt
            for i in range(self.n):
                self.f[i] += dt
            for i in range(self.n):
                self.f[i] += dt
            for i in range(self.n):
                self.f[i] += dt

    probe = Probe(1_000)
    gravity = ti.Vector([0.0, -9.81])
    cases = [
        ("kernel, no arguments", probe.plain),
        ("kernel(dt, ti.Vector built per call)", lambda: probe.with_vector(1e-3, ti.Vector([0.0, -9.81]))),
        ("kernel(dt, ti.Vector built once)", lambda: probe.with_vector(1e-3, gravity)),
        ("kernel(dt, gx, gy) with two floats", lambda: probe.with_floats(1e-3, 0.0, -9.81)),
        ("kernel(dt, template flag)", lambda: probe.with_template(1e-3, True)),
        ("one kernel holding six loops", lambda: probe.six_loops(1e-3)),
    ]
    calls = 3_000
    for name, fn in cases:
        for _ in range(50):
            fn()
        ti.sync()
        best = float("inf")
        for _ in range(3):
            t0 = time.perf_counter()
            for _ in range(calls):
                fn()
            ti.sync()
            best = min(best, (time.perf_counter() - t0) / calls)
        print(f"{name:40s} {best * 1e6:7.1f} us per launch")
    return 0


if __name__ == "__main__":
    sys.exit(main())
