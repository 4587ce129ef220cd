"""Run Runout's benchmark without the command line: ``python benchmarks/run_bench.py [--quick] [--out FILE.json]``.

The same measurements as ``runout bench`` (see ``benchmarks/bench.py`` and ``docs/performance.md``);
writes FILE.json and FILE.md (default ``benchmarks/results/bench-quick.json`` or
``bench-full.json``) and prints the markdown report.
"""

import argparse
import logging
import os
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="1e3 and 2e4 particles, f32 only (about a minute)")
    parser.add_argument("--out", type=Path, default=None, help="JSON file (markdown next to it)")
    args = parser.parse_args(argv)
    os.environ.setdefault("ENABLE_TAICHI_HEADER_PRINT", "0")
    sys.path.insert(0, str(REPO))
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(message)s", stream=sys.stderr)

    from benchmarks.bench import markdown_report, run_bench

    out = args.out or REPO / "benchmarks" / "results" / f"bench-{'quick' if args.quick else 'full'}.json"
    result = run_bench(args.quick, out)
    print(markdown_report(result))
    print(f"written: {out} and {out.with_suffix('.md')}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
