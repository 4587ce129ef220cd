"""What material damping costs per step (docs/solver.md, material damping; docs/performance.md).

The aluminium-bar scene (20,000 particles) at a fixed time step, undamped and with the material
damped by each model (Rayleigh, Maxwell), run alternately (the machine's load drifts); prints
each scheme's throughputs (million particle-steps per second) and the damped / undamped ratio of
the middle two of each.
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
    variants = {"undamped": base}
    for model in ("rayleigh", "maxwell"):
        variants[model] = apply_overrides(base, ["materials.bars.damping_ratio=0.001",
                                                 "materials.bars.damping_frequency_hz=50",
                                                 f'materials.bars.damping_model="{model}"'])
    with tempfile.TemporaryDirectory() as tmp:
        for scheme in args.schemes:
            rates: dict[str, list[float]] = {name: [] for name in variants}
            for _ in range(args.repeats):
                for name, project in variants.items():
                    project = apply_overrides(project, [f"numerics.scheme={scheme}"])
                    summary = run_project(project, Path(tmp, name), overwrite=True).summary
                    rates[name].append(summary["particle_steps_per_s"] / 1e6)
            middle = {k: sorted(v)[len(v) // 4: len(v) - len(v) // 4] for k, v in rates.items()}
            mean = {k: sum(v) / len(v) for k, v in middle.items()}
            print(f"{scheme}: " + "; ".join(f"{name} {', '.join(f'{r:.2f}' for r in rates[name])}" for name in rates)
                  + " M particle-steps/s; / undamped: "
                  + ", ".join(f"{name} {mean[name] / mean['undamped']:.3f}" for name in rates if name != "undamped"))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
