"""Step throughput of two source trees, timed in interleaved paired rounds.

``python benchmarks/compare_trees.py BEFORE_TREE AFTER_TREE [--particles N] [--rounds R]``

Each tree gets a worker process (``PYTHONPATH`` = that tree) that builds the benchmark scene's
engines (``benchmarks.bench``: the yardstick and the three schemes, as ``runout bench`` builds
them) once; the driver then times one batch of steps of every variant in one tree and right
after in the other (which goes first alternates between rounds). Reported per variant: the best
rate of each tree (M particle-steps/s), and the median over rounds of the paired ratio
after/before of throughput, from wall time and from the worker's CPU time (user + sys of all its
threads). On a machine shared with other work the paired ratios are what to read. For a commit,
check it out first: ``git worktree add --detach /tmp/before COMMIT``.
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

_WORKER = r"""
import json, os, sys, time
import numpy as np
import taichi as ti
from benchmarks import bench

n, precision, names = int(sys.argv[1]), sys.argv[2], sys.argv[3].split(",")
with bench._taichi_runtime("cpu", precision):
    variants = {}
    for name in names:
        config, particles = bench.collapse_scene(n, precision, name if name in bench.SCHEMES else "apic-affine")
        variants[name] = bench._Variant(name, config, particles, bench._np_float(precision))
    print(json.dumps({"ready": len(particles),
                      "scatter": {k: getattr(v.obj, "scatter", None) for k, v in variants.items()}}), flush=True)
    for line in sys.stdin:
        name, steps = line.split()
        v = variants[name]
        v.reset()
        c0, t0 = time.process_time(), time.perf_counter()
        for _ in range(int(steps)):
            v.step()
        ti.sync()
        print(json.dumps({"wall_s": time.perf_counter() - t0, "cpu_s": time.process_time() - c0}), flush=True)
"""


def _start(tree: Path, n: int, precision: str, names: list[str]) -> tuple[subprocess.Popen, dict]:
    env = dict(os.environ, PYTHONPATH=str(tree), ENABLE_TAICHI_HEADER_PRINT="0")
    proc = subprocess.Popen([sys.executable, "-c", _WORKER, str(n), precision, ",".join(names)], cwd=tree,
                            env=env, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    return proc, json.loads(proc.stdout.readline())


def _time(proc: subprocess.Popen, name: str, steps: int) -> dict:
    proc.stdin.write(f"{name} {steps}\n")
    proc.stdin.flush()
    return json.loads(proc.stdout.readline())


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("before", type=Path)
    parser.add_argument("after", type=Path)
    parser.add_argument("--particles", type=int, default=20_000)
    parser.add_argument("--precision", choices=("f32", "f64"), default="f32")
    parser.add_argument("--variants", default="yardstick,mpm,apic,apic-affine")
    parser.add_argument("--steps", type=int, default=200, help="steps per timed batch")
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument("--json", type=Path, default=None, help="also write every round's times here")
    args = parser.parse_args(argv)
    names = args.variants.split(",")
    trees = {"before": args.before.resolve(), "after": args.after.resolve()}
    workers = {}
    for key, tree in trees.items():
        workers[key] = _start(tree, args.particles, args.precision, names)
        print(f"{key}: {tree} ready ({workers[key][1]['ready']} particles, scatter {workers[key][1]['scatter']})",
              file=sys.stderr)
    times = {name: {"before": [], "after": []} for name in names}
    for r in range(args.rounds):
        for name in names:
            _time(workers["before"][0], name, 5)  # warm caches after the other process ran
            _time(workers["after"][0], name, 5)
            order = ("before", "after") if r % 2 == 0 else ("after", "before")
            for key in order:
                times[name][key].append(_time(workers[key][0], name, args.steps))
        print(f"round {r + 1}/{args.rounds} done", file=sys.stderr)
    for proc, _ in workers.values():
        proc.stdin.close()
        proc.wait()
    n = workers["before"][1]["ready"]
    print(f"| variant | before M/s (best) | after M/s (best) "
          f"| after/before, wall (median of {args.rounds} paired rounds) | after/before, CPU time |")
    print("|---|---|---|---|---|")
    summary = {}
    for name in names:
        b, a = times[name]["before"], times[name]["after"]
        rate = {k: n * args.steps / min(t["wall_s"] for t in times[name][k]) / 1e6 for k in ("before", "after")}
        wall = statistics.median(x["wall_s"] / y["wall_s"] for x, y in zip(b, a))
        cpu = statistics.median(x["cpu_s"] / y["cpu_s"] for x, y in zip(b, a))
        summary[name] = {"before_M_per_s": rate["before"], "after_M_per_s": rate["after"],
                         "ratio_wall": wall, "ratio_cpu": cpu}
        print(f"| {name} | {rate['before']:.3g} | {rate['after']:.3g} | {wall:.3f} | {cpu:.3f} |")
    if args.json is not None:
        args.json.write_text(json.dumps({"trees": {k: str(v) for k, v in trees.items()}, "particles": n,
                                         "precision": args.precision, "steps": args.steps, "times": times,
                                         "summary": summary}, indent=2) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
