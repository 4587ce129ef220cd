"""Checks and benchmark rows that need a GPU: ``python -m benchmarks.gpu_check --out DIR [--part ...]``.

The test suite runs on the CPU (CI has no GPU), so the GPU path of the solver (CUDA through Taichi,
the atomic scatter) is checked here, on a machine that has one:

- ``examples``: each example project runs a short stretch on the GPU and on the CPU (same
  precision, the CPU with the atomic scatter, as on the GPU); the runs are not bit for bit alike
  (the order of atomic adds differs), so their final states are compared: status, active
  particles, mass, and the largest and RMS difference of the particle positions in cells. Over a
  short stretch (a few hundred steps, before the flows become chaotic) a correct GPU path stays
  within a small fraction of a cell (``EXAMPLE_TOL_CELLS``).
- ``bench``: the GPU rows of ``runout bench`` (throughput of every scheme from 1e3 to 1e6
  particles, f32; the step profile at 2e4; the aluminium-bar run of the paper, 20,000 particles,
  1 s at 20 us) written as ``bench-gpu.json`` / ``.md``.

The contact law on a GPU is a test of the suite (``tests/unit/test_solver_contact.py``, marked
``gpu``, skipped where there is none).

Writes ``gpu-check.json`` (and the bench files) into ``--out`` and prints a summary; the exit
status is 1 when a check failed, 2 when there is no GPU.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

EXAMPLES = Path(__file__).resolve().parents[1] / "projects" / "examples"
#: example, overrides that keep it short (a few hundred steps, no output but the last frame)
EXAMPLE_RUNS: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("tiny_column", ("stages.1.duration_s=0.05", "output.interval_s=0.05")),
    ("bui2008_aluminium_bars", ("stages.1.duration_s=0.01", "output.interval_s=0.01")),
    ("sand_column", ("stages.0.duration_s=0.02", "output.interval_s=0.02")),
    ("slope_sun_song_2015", ("stages.0.duration_s=0.02", "stages.1.duration_s=0.02", "stages.2.duration_s=0.01",
                             "output.interval_s=0.05")),
)
#: largest position difference GPU against CPU after the short stretch, in cells
EXAMPLE_TOL_CELLS = 0.05
#: the arch under test (``--dry-run`` puts the CPU in its place, to try this script without a GPU)
GPU = "gpu"


def check_examples(tmp: Path) -> list[dict[str, Any]]:
    from projects.document import load_project
    from projects.results import Results
    from projects.runner import run_project

    rows = []
    for name, overrides in EXAMPLE_RUNS:
        path = EXAMPLES / f"{name}.toml"
        sets = overrides
        finals = {}
        for k, arch in enumerate((GPU, "cpu")):
            extra = ("numerics.advanced.scatter=atomic",) if arch == "cpu" else ()
            project = load_project(path, [*sets, *extra])
            t0 = time.perf_counter()
            result = run_project(project, tmp / f"{name}-{k}", arch=arch)
            res = Results(result.out_dir)
            last = res.frame(-1)
            finals[k] = {"status": result.status, "wall_s": time.perf_counter() - t0,
                            "arch_used": result.summary.get("arch"), "positions": last["positions"],
                            "active": last["active"], "time_s": res.times[-1],
                            "cell_m": project.domain.cell_size_m}
        g, c = finals[0], finals[1]
        both = g["active"] & c["active"]
        diff = np.linalg.norm(g["positions"][both] - c["positions"][both], axis=1) / c["cell_m"]
        row = {"example": name, "overrides": list(sets), "time_s": c["time_s"],
               "status_gpu": g["status"], "status_cpu": c["status"], "arch_gpu": g["arch_used"],
               "active_gpu": int(g["active"].sum()), "active_cpu": int(c["active"].sum()),
               "max_diff_cells": float(diff.max(initial=0.0)),
               "rms_diff_cells": float(math.sqrt(float(np.mean(diff ** 2)))) if len(diff) else 0.0,
               "wall_gpu_s": g["wall_s"], "wall_cpu_s": c["wall_s"]}
        row["ok"] = bool(row["status_gpu"] == row["status_cpu"] == "completed" and row["arch_gpu"] == GPU
                         and row["active_gpu"] == row["active_cpu"] and row["max_diff_cells"] <= EXAMPLE_TOL_CELLS)
        rows.append(row)
        print(f"example {name}: gpu {g['status']} ({g['arch_used']}), max diff {row['max_diff_cells']:.2e} cells, "
              f"rms {row['rms_diff_cells']:.2e}: {'ok' if row['ok'] else 'FAIL'}", flush=True)
    return rows


def gpu_bench(out: Path) -> dict[str, Any]:
    from benchmarks.bench import BenchConfig, run_bench_config

    cfg = BenchConfig(archs=("gpu",), particle_counts=(1_000,), gpu_particle_counts=(1_000, 20_000, 100_000, 1_000_000),
                      precisions=("f32",), rounds=3, batch_s=0.5, profile_particles=(20_000,),
                      gpu_full_run=True, startup_runs=0, empty_domain_particles=0, stall_particles=0,
                      envelope_particles=0)
    return run_bench_config(cfg, out / "bench-gpu.json", on_progress=lambda m: print(m, flush=True), quick=False)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--part", action="append", choices=("examples", "bench"),
                    help="what to run (repeatable; default: all)")
    ap.add_argument("--dry-run", action="store_true", help="the CPU in place of the GPU (tries the script)")
    args = ap.parse_args(argv)
    from solver import runtime

    global GPU
    if args.dry_run:
        GPU = "cpu"
    elif not runtime.gpu_available():
        print("no GPU: nothing checked", file=sys.stderr)
        return 2
    parts = args.part or ["examples", "bench"]
    args.out.mkdir(parents=True, exist_ok=True)
    report: dict[str, Any] = {"parts": parts}

    def save() -> None:  # after each part: a run cut short keeps what it measured
        (args.out / "gpu-check.json").write_text(json.dumps(report, indent=2, default=str) + "\n", encoding="utf-8")

    with tempfile.TemporaryDirectory(prefix="runout-gpu-check-") as tmp:
        if "examples" in parts:
            report["examples"] = check_examples(Path(tmp))
            save()
    if "bench" in parts and not args.dry_run:
        result = gpu_bench(args.out)
        report["bench_targets"] = result.get("targets")
        save()
    failed = [r for r in report.get("examples", []) if not r["ok"]]
    print(f"{len(failed)} failed check(s)")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
