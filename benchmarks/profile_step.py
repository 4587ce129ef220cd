"""Where one step's time goes: ``python benchmarks/profile_step.py [--particles N] [--steps S] [--precision f32]``.

Runs the yardstick and every scheme on the standard collapse scene with Taichi's kernel profiler
on (switched on for the benchmark only, through ``TI_KERNEL_PROFILER``), and prints the time per
step of each stage (reset, P2G, constitutive + force, grid pass, walls, G2P), the time outside the
kernels (Python and launch overhead) and the constitutive update timed alone.
"""

import argparse
import json
import os
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--particles", type=int, default=20_000)
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--precision", choices=("f32", "f64"), default="f32")
    parser.add_argument("--arch", choices=("cpu", "gpu"), default="cpu")
    parser.add_argument("--json", type=Path, default=None, help="also write the profile as JSON here")
    args = parser.parse_args(argv)
    os.environ.setdefault("ENABLE_TAICHI_HEADER_PRINT", "0")
    sys.path.insert(0, str(REPO))

    from benchmarks.bench import profile_markdown, profile_step

    prof = profile_step(args.particles, args.arch, args.precision, args.steps, rounds=args.rounds,
                        note=lambda msg: print(msg, file=sys.stderr))
    if prof is None:
        print(f"not measured: no {args.arch.upper()}", file=sys.stderr)
        return 1
    if args.json is not None:
        args.json.write_text(json.dumps(prof, indent=2) + "\n", encoding="utf-8")
    print(profile_markdown(prof))
    return 0


if __name__ == "__main__":
    sys.exit(main())
