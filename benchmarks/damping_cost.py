"""What material damping costs per step (docs/solver.md, material damping; docs/performance.md).

The aluminium-bar scene (20,000 particles) at a fixed time step, undamped and with a damped
material, run alternately (the machine's load drifts); prints each scheme's throughputs
(million particle-steps per second) and the damped / undamped ratio of the middle two of each.
The step count a damping needs is the estimate's business (``runout validate``); this measures only
the work the damping stress adds to a step.

Usage::

    PYTHONPATH=$PWD python -m benchmarks.damping_cost [apic-affine apic mpm] [--repeats 4]
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

SCENE = Path(__file__).resolve().parents[1] / "projects" / "examples" / "bui2008_aluminium_bars.toml"


def main(argv: list[str] | None = None) -> int:
    from projects.document import apply_overrides, load_project
    from projects.runner import run_project

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("schemes", nargs="*", default=["apic-affine", "apic", "mpm"])
    ap.add_argument("--repeats", type=int, default=4)
    args = ap.parse_args(argv)
    # a step short enough for the damped material too, so both run the same steps
    base = apply_overrides(load_project(SCENE), ["numerics.time_step_s=2e-6", "stages.1.duration_s=0.01",
                                                 "output.interval_s=0.01"])
    damped = apply_overrides(base, ["materials.bars.damping_ratio=0.001", "materials.bars.damping_frequency_hz=50"])
    with tempfile.TemporaryDirectory() as tmp:
        for scheme in args.schemes:
            rates: dict[str, list[float]] = {"undamped": [], "damped": []}
            for _ in range(args.repeats):
                for name, project in (("undamped", base), ("damped", damped)):
                    project = apply_overrides(project, [f"numerics.scheme={scheme}"])
                    summary = run_project(project, Path(tmp, name), overwrite=True).summary
                    rates[name].append(summary["particle_steps_per_s"] / 1e6)
            middle = {k: sorted(v)[len(v) // 4: len(v) - len(v) // 4] for k, v in rates.items()}
            ratio = sum(middle["damped"]) / len(middle["damped"]) / (sum(middle["undamped"]) / len(middle["undamped"]))
            print(f"{scheme}: undamped {', '.join(f'{r:.2f}' for r in rates['undamped'])}; damped "
                  f"{', '.join(f'{r:.2f}' for r in rates['damped'])} M particle-steps/s; damped / undamped {ratio:.3f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
