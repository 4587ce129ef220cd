"""Where the start-up of ``runout run`` goes: ``python -m benchmarks.startup_profile [SCENE] [--cold]``.

Runs ``runout run`` on an example (``tiny_column`` or ``bui2008_aluminium_bars``, the scenes of
the start-up rows of :func:`benchmarks.bench.startup`) in this process, with Taichi's kernel
class instrumented, and prints, up to the end of the first step:

- the time to import the command line and what it imports before the run starts, and
  ``ti.init``;
- every Taichi kernel the run compiled before its first step ended: its name, the solver or
  project function that launched it, its front end (Python AST -> Taichi IR, done in every
  process; ``Kernel.materialize``) and its first launch (compiling it, or loading it from the
  offline cache and JIT-linking it, plus running it once);
- the totals per launching function, and what is left (Python outside the kernels).

The kernel cache is ``TI_OFFLINE_CACHE_FILE_PATH`` (default: Taichi's own); ``--cold`` uses a fresh
empty one. Run it twice for the warm figures. The instrumentation adds about 1 ms per kernel.
``python -X importtime -m app run ...`` gives the import tree in detail.
"""

from __future__ import annotations

import argparse
import atexit
import os
import sys
import tempfile
import time
import traceback
from pathlib import Path

#: the clock: wall time, or with ``--cpu`` this process's CPU time (user + system, all threads),
#: which other work on a shared machine disturbs less
CLOCK = time.process_time if "--cpu" in sys.argv else time.perf_counter
T0 = CLOCK()
EXAMPLES = Path(__file__).resolve().parents[1] / "projects" / "examples"
#: the same overrides as the start-up rows of benchmarks.bench
SCENES = {
    "tiny_column": (),
    "bui2008_aluminium_bars": ("stages.1.duration_s=0.002", "output.interval_s=0.001"),
}


def _caller() -> str:
    """The innermost Runout function on the stack (outside Taichi and this script)."""
    root = str(Path(__file__).resolve().parents[1])
    for frame in reversed(traceback.extract_stack()[:-2]):
        if frame.filename.startswith(root) and "startup_profile" not in frame.filename:
            return f"{Path(frame.filename).stem}.{frame.name}"
    return "?"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene", nargs="?", default="tiny_column", choices=sorted(SCENES))
    parser.add_argument("--cold", action="store_true", help="a fresh, empty kernel cache")
    parser.add_argument("--all", action="store_true", help="list every kernel, not only the ten slowest")
    parser.add_argument("--cpu", action="store_true", help="CPU time of this process instead of wall time")
    args = parser.parse_args(argv)
    tmp = tempfile.TemporaryDirectory(prefix="runout-startup-profile-")
    if args.cold:
        os.environ["TI_OFFLINE_CACHE_FILE_PATH"] = str(Path(tmp.name) / "cache")

    events: list[tuple[str, str, str, float, float]] = []  # kind, kernel, caller, start, seconds
    marks: dict[str, float] = {}

    from solver.runtime import ti  # noqa: F401 - timed here, as the run imports it (solver.runtime's cheap path)
    from taichi.lang import kernel_impl

    marks["import taichi"] = CLOCK() - T0
    seen: set[int] = set()
    materialize, launch = kernel_impl.Kernel.materialize, kernel_impl.Kernel.launch_kernel

    def timed_materialize(self, key=None, args=None, arg_features=None):
        new = key is None or key not in self.compiled_kernels
        t = CLOCK()
        result = materialize(self, key, args, arg_features)
        if new:
            events.append(("front", self.func.__qualname__, _caller(), t - T0, CLOCK() - t))
        return result

    def timed_launch(self, t_kernel, *a):
        first = id(t_kernel) not in seen
        seen.add(id(t_kernel))
        t = CLOCK()
        result = launch(self, t_kernel, *a)
        if first:
            events.append(("launch", self.func.__qualname__, _caller(), t - T0, CLOCK() - t))
        return result

    kernel_impl.Kernel.materialize = timed_materialize
    kernel_impl.Kernel.launch_kernel = timed_launch

    from solver import runtime, simulation

    init = runtime._init

    def timed_init(**kwargs):
        t = CLOCK()
        init(**kwargs)
        marks["ti.init start"] = t - T0
        marks["ti.init"] = CLOCK() - t

    runtime._init = timed_init
    step = simulation.Simulation.run

    def run(self, *a, **kw):
        marks.setdefault("Simulation.run start", CLOCK() - T0)
        for frame in step(self, *a, **kw):
            yield frame

    simulation.Simulation.run = run

    def report() -> None:
        first = marks.get("first step")
        if first is None:
            print("no step was taken", file=sys.stderr)
            return
        kernels = [e for e in events if e[3] < first]
        fronts = [e for e in kernels if e[0] == "front"]
        launches = [e for e in kernels if e[0] == "launch"]
        clock = "CPU time" if args.cpu else "wall time"
        print(f"\n{args.scene}: start-up {first:.3f} s {clock} in this process (plus the interpreter's own start)")
        for name in ("import taichi", "import app.cli", "ti.init start", "ti.init", "Simulation.run start"):
            if name in marks:
                print(f"  {name:28s} {marks[name]:7.3f} s")
        print(f"  kernels before the first step ended: {len(fronts)} "
              f"(front end {sum(e[4] for e in fronts):.3f} s, first launches {sum(e[4] for e in launches):.3f} s)")
        by_caller: dict[str, list[float]] = {}
        for kind, _name, caller, _t, s in kernels:
            row = by_caller.setdefault(caller, [0, 0.0, 0.0])
            if kind == "front":
                row[0] += 1
                row[1] += s
            else:
                row[2] += s
        print(f"  {'launched from':40s} {'kernels':>7s} {'front s':>8s} {'launch s':>8s}")
        for caller, (count, f, lt) in sorted(by_caller.items(), key=lambda kv: -(kv[1][1] + kv[1][2])):
            print(f"  {caller:40s} {count:7d} {f:8.3f} {lt:8.3f}")
        per_kernel: dict[tuple[str, str], list[float]] = {}
        for kind, name, caller, _t, s in kernels:
            per_kernel.setdefault((name, caller), [0.0, 0.0])[0 if kind == "front" else 1] += s
        rows = sorted(per_kernel.items(), key=lambda kv: -sum(kv[1]))
        print(f"  {'kernel':32s} {'launched from':36s} {'front ms':>8s} {'launch ms':>9s}")
        for (name, caller), (f, lt) in rows if args.all else rows[:10]:
            print(f"  {name:32s} {caller:36s} {f * 1e3:8.1f} {lt * 1e3:9.1f}")
        busy = sum(e[4] for e in kernels)
        start = marks.get("ti.init start", 0.0)
        print(f"  outside kernels and imports between ti.init and the first step: "
              f"{first - start - marks.get('ti.init', 0.0) - busy:.3f} s")
        sys.stderr.flush()

    atexit.register(report)
    import app.cli as cli

    marks["import app.cli"] = CLOCK() - T0
    engine_step = None

    def first_step_hook() -> None:
        nonlocal engine_step
        from solver.engine import Engine

        engine_step = Engine.step

        def stepped(self, *a, **kw):
            engine_step(self, *a, **kw)
            if sys._getframe(1).f_code.co_name == "run":  # Simulation.run's loop, not the equilibrium probe
                marks.setdefault("first step", CLOCK() - T0)

        Engine.step = stepped

    acquire = runtime.acquire

    def acquire_then_hook(*a, **kw):
        used = acquire(*a, **kw)
        if engine_step is None:
            first_step_hook()
        return used

    runtime.acquire = acquire_then_hook
    out = Path(tmp.name) / "run"
    sets = [a for s in ("numerics.advanced.scatter=serial", *SCENES[args.scene]) for a in ("--set", s)]
    sys.argv = ["runout", "run", str(EXAMPLES / f"{args.scene}.toml"), "--out", str(out), "--quiet", *sets]
    try:
        cli.main()
    except SystemExit as done:
        if done.code not in (0, None):
            raise
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
