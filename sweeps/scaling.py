"""Wall time of one sweep with 1, 2, ... workers against the same runs one after another.

    python -m sweeps.scaling [SPEC] [--workers 1 2] [--out DIR]

Default SPEC: ``projects/examples/sweeps/tiny_column_friction.toml`` (8 runs). For each worker
count the sweep runs into a fresh folder (nothing reused) with ``threads = cores // workers``;
then every resolved project of the sweep runs once more with ``runout run`` one after another
(default threads: all cores), as a user would without Ray. Printed (markdown): the wall times,
the speed-up, the time ``ray.init`` took in the sweep, and the Ray overhead per run: the time
from submitting a run's task to receiving its result less the run process's own wall time
(scheduling, the task's start, reading the measures), the mean over the runs.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import time
from pathlib import Path

from projects.runner import runout_command

REPO = Path(__file__).resolve().parents[1]
DEFAULT_SPEC = REPO / "projects" / "examples" / "sweeps" / "tiny_column_friction.toml"


def main(argv: list[str] | None = None) -> int:
    from sweeps.spec import load_spec
    from sweeps.sweep import run_sweep

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("spec", nargs="?", type=Path, default=DEFAULT_SPEC)
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--out", type=Path, default=Path("sweep-scaling"))
    args = ap.parse_args(argv)
    spec = load_spec(args.spec)
    cores = os.cpu_count() or 1
    rows = []
    with open("/proc/loadavg", encoding="utf-8") as fh:
        load_before = fh.read().split()[:3]
    last = None
    for w in args.workers:
        folder = args.out / f"workers-{w}"
        shutil.rmtree(folder, ignore_errors=True)
        t0 = time.perf_counter()
        result = run_sweep(spec, folder, workers=w, report=False)
        wall = time.perf_counter() - t0
        proc = sum(r.wall_time_s for r in result.records)
        over = [r.overhead_s for r in result.records]
        rows.append({"workers": w, "threads": result.settings["threads_per_run"], "wall_s": wall,
                     "runs": len(result.records), "completed": result.count("completed"), "sum_run_s": proc,
                     "ray_init_s": result.settings["ray_startup_s"], "overhead_per_run_s": sum(over) / len(over)})
        last = result
    assert last is not None
    seq = args.out / "sequential"
    shutil.rmtree(seq, ignore_errors=True)
    seq.mkdir(parents=True)
    t0 = time.perf_counter()
    for plan in last.plans:
        project = seq / f"{plan.run_id}.toml"
        project.write_text(plan.project_text, encoding="utf-8")
        subprocess.run(runout_command("run", str(project), "--out", str(seq / plan.run_id), "--quiet"),
                       check=False, capture_output=True)
    seq_s = time.perf_counter() - t0
    with open("/proc/loadavg", encoding="utf-8") as fh:
        load_after = fh.read().split()[:3]
    print(f"spec: {args.spec}; {cores} cores; load average before {' '.join(load_before)}, after "
          f"{' '.join(load_after)}")
    print("| how | workers x threads | wall time (s) | speed-up vs one after another | sum of run processes (s) |"
          " ray.init (s) | Ray overhead per run (s) |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    print(f"| `runout run` x {len(last.plans)}, one after another | 1 x {cores} | {seq_s:.1f} | 1.00 | - | - | - |")
    for r in rows:
        print(f"| `runout sweep --workers {r['workers']}` | {r['workers']} x {r['threads']} | {r['wall_s']:.1f} | "
              f"{seq_s / r['wall_s']:.2f} | {r['sum_run_s']:.1f} | {r['ray_init_s']:.1f} | "
              f"{r['overhead_per_run_s']:.2f} |")
    (args.out / "scaling.json").write_text(json.dumps({"sequential_s": seq_s, "rows": rows,
                                                       "load_before": load_before, "load_after": load_after},
                                                      indent=1), encoding="utf-8")
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
