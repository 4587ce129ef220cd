"""What a run will cost in wall time: start-up plus steps of a cost that grows with the particles.

A run's wall time is its **start-up** (the process, Taichi, compiling or loading the kernels, the
first step) plus its **steps**, each costing

    t_step(N) = a + b N        (s per step, N particles)

``a`` is the per-step overhead a small model never amortises (the kernel launches of a step's
stages, the grid passes over the scatter's box, the checks, frames and hazard envelopes), ``b`` the
cost per particle; structures add a cost of their own to each step. The cost per particle-step, ``t_step / N = a / N + b``, therefore falls with the
model's size: a throughput measured on a large model (millions of particle-steps per second)
promises a small one far less time than it takes.

Where the numbers come from, best first (:func:`step_cost`):

1. the project's **own run**: a results folder of this project (its ``summary.json``
   ``step_time_s``, ``startup_s`` and ``particles``, written by every run since
   :mod:`projects.runner` records them) on the same device: its measured step time, carried to
   another particle count along the model's shape;
2. **this machine's runs** (the workbench keeps the step times of its completed runs): the model
   scaled by their median measured-to-modelled ratio (:func:`machine_step_cost`);
3. the **shipped model** :data:`STEP_COSTS`, measured with whole ``runout run`` processes of the
   examples on the development machine (docs/performance.md, "Cost of a run").

The steps are :func:`projects.build.estimate`'s: every stage's duration over the time step, so a
stage that may stop early (``stop_when_kinetic_energy_below``) costs at most that, and a
strength-reduction stage's trials are counted apart (each at most its trial duration).
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any


@dataclass(frozen=True)
class StepCost:
    """The cost of a run on one device: ``step_s(N) = overhead_s + per_particle_s * N``, plus
    ``structure_s`` a step where the run has structures.

    Attributes
    ----------
    arch : str
        "cpu" or "gpu".
    overhead_s : float
        ``a``, seconds per step whatever the size.
    per_particle_s : float
        ``b``, seconds per particle per step.
    structure_s : float
        Seconds a step adds where the run has ``[[structures]]`` (their contact nodes and mirror
        particles).
    startup_s : float
        Process start to the end of the first step (the kernels compiled for a new grid), s.
    source : str
        Where the numbers come from, for the user ("measured by this project's run ...").
    """

    arch: str
    overhead_s: float
    per_particle_s: float
    structure_s: float
    startup_s: float
    source: str

    def step_s(self, particles: float, structures: bool = False) -> float:
        """Seconds per step of a run of ``particles`` particles (with structures or not)."""
        return self.overhead_s + self.per_particle_s * max(0.0, float(particles)) + (
            self.structure_s if structures else 0.0)

    def run_s(self, particles: float, steps: float, structures: bool = False) -> float:
        """Wall seconds of a whole run: start-up plus ``steps`` steps."""
        return self.startup_s + max(0.0, float(steps)) * self.step_s(particles, structures)

    def scaled(self, factor: float, source: str, startup_s: float | None = None) -> StepCost:
        """Every step cost times ``factor`` (a machine, or a run, slower or faster than the model)."""
        return replace(self, overhead_s=self.overhead_s * factor, per_particle_s=self.per_particle_s * factor,
                       structure_s=self.structure_s * factor, source=source,
                       startup_s=self.startup_s if startup_s is None else startup_s)


#: The shipped model, measured on the development machine (2 cores of an AMD EPYC, Taichi 1.7.4,
#: CPU backend, f32, apic-affine; docs/performance.md): ``a`` and ``b`` from the step times of
#: ``runout bench`` on a quiet machine (0.28 ms a step at 990 particles, 1.59 ms at 20,000, 12.3 ms
#: at 199,712; frames and hazard envelopes add 1-2 % to a whole run); ``structure_s`` from the
#: check-dam example as a whole ``runout run`` (998 particles, two structures: 3,080 steps in
#: about 3.4 s after its start-up, 1.1 ms a step against 0.28 ms without structures); the
#: start-up of a process whose grid's kernels are not in the cache yet (5-7 s; 1.6 s warm). No
#: GPU has been measured: its numbers are the CPU's overhead with a per-particle cost 20 times
#: lower, a guess stated as one. A machine's and a project's own runs correct all of it.
STEP_COSTS: dict[str, StepCost] = {
    "cpu": StepCost("cpu", overhead_s=2.2e-4, per_particle_s=6.1e-8, structure_s=8.2e-4, startup_s=5.0,
                    source="the development machine's measurements (docs/performance.md)"),
    "gpu": StepCost("gpu", overhead_s=2.2e-4, per_particle_s=3.0e-9, structure_s=8.2e-4, startup_s=8.0,
                    source="assumed (no GPU measured yet)"),
}

#: A run's measured step time counts for another particle count within this factor of its own
#: (beyond it, the machine's or the shipped model's shape decides).
OWN_RUN_SIZE_RATIO = 4.0


def _positive(value: Any) -> float | None:
    try:
        number = float(value)
    except (TypeError, ValueError):
        return None
    return number if math.isfinite(number) and number > 0 else None


def machine_step_cost(samples: Iterable[tuple[float, float, bool]], base: StepCost, source: str) -> StepCost:
    """``base`` scaled to this machine: by the median ratio of the measured to the modelled step
    time of its runs ``(particles, step_s, structures)`` (a machine two times slower, or busy with
    other work, reads two times slower in every term); ``base`` when none is usable."""
    ratios = sorted(float(t) / base.step_s(float(n), bool(st)) for n, t, st in samples
                    if _positive(n) and _positive(t))
    if not ratios:
        return base
    mid = len(ratios) // 2
    factor = ratios[mid] if len(ratios) % 2 else 0.5 * (ratios[mid - 1] + ratios[mid])
    return base.scaled(factor, source)


def own_run(results_dir: str | Path | None, arch: str) -> dict[str, float] | None:
    """``particles``, ``step_time_s`` and ``startup_s`` of the run in ``results_dir`` on ``arch``
    (None when there is none, it ran elsewhere or recorded no step time)."""
    if results_dir is None:
        return None
    try:
        summary = json.loads((Path(results_dir) / "summary.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(summary, Mapping) or summary.get("arch") != arch:
        return None
    particles, step = _positive(summary.get("particles")), _positive(summary.get("step_time_s"))
    if particles is None or step is None:
        return None
    return {"particles": particles, "step_time_s": step, "startup_s": _positive(summary.get("startup_s")) or 0.0,
            "structures": bool(summary.get("structures"))}


def step_cost(arch: str, particles: float, structures: bool = False, *, own: Mapping[str, Any] | None = None,
              machine: StepCost | None = None) -> StepCost:
    """The step cost for a run of ``particles`` (with ``structures`` or not) on ``arch``: the
    project's own run ``own`` (:func:`own_run`) where its size is within
    :data:`OWN_RUN_SIZE_RATIO` of this one (the model's shape through its measured point), else
    the machine's cost ``machine`` (:func:`machine_step_cost`), else :data:`STEP_COSTS`."""
    base = machine or STEP_COSTS.get(arch, STEP_COSTS["cpu"])
    if own:
        n, t = float(own["particles"]), float(own["step_time_s"])
        if max(n, particles) <= OWN_RUN_SIZE_RATIO * max(1.0, min(n, particles)):
            factor = t / base.step_s(n, bool(own.get("structures", structures)))
            return base.scaled(factor, f"measured by this project's run ({n:,.0f} particles, {t * 1e3:.3g} ms a step)",
                               startup_s=float(own.get("startup_s") or 0.0) or base.startup_s)
    return base


def run_time(estimate: Mapping[str, Any], cost: StepCost, structures: bool = False) -> dict[str, Any]:
    """The wall time of a run of :func:`projects.build.estimate` ``estimate`` (with ``structures``
    or not) at ``cost``.

    Returns
    -------
    dict
        ``run_time_s`` (start-up and every step), ``startup_s``, ``steps``, ``particles``,
        ``step_time_s`` (s per step), ``particle_step_s`` (s per particle-step at this size),
        ``overhead_s``, ``per_particle_s`` and ``structure_s`` (the model, the last 0 without
        structures), ``arch``, ``source``, ``may_stop_early``
        (a stage may end before its duration: the time is at most this), ``trial_steps`` and
        ``trial_time_s`` (a strength-reduction stage: the steps and time of one trial at most,
        on top of ``run_time_s``; 0 without one), ``typical_trials`` and ``max_trials`` (the
        search's usual and largest number of trials).
    """
    particles = float(estimate.get("particles") or 0)
    steps = float(estimate.get("steps") or 0)
    trial_steps = float(estimate.get("trial_steps") or 0)
    step = cost.step_s(particles, structures)
    return {
        "run_time_s": cost.run_s(particles, steps, structures),
        "startup_s": cost.startup_s,
        "steps": int(steps),
        "particles": int(particles),
        "step_time_s": step,
        "particle_step_s": step / max(1.0, particles),
        "overhead_s": cost.overhead_s,
        "per_particle_s": cost.per_particle_s,
        "structure_s": cost.structure_s if structures else 0.0,
        "arch": cost.arch,
        "source": cost.source,
        "may_stop_early": bool(estimate.get("may_stop_early")),
        "trial_steps": int(trial_steps),
        "trial_time_s": trial_steps * step,
        "typical_trials": int(estimate.get("typical_trials") or 0),
        "max_trials": int(estimate.get("max_trials") or 0),
    }


def format_seconds(seconds: float) -> str:
    """``4.7 s``, ``42 s``, ``3 min 20 s``, ``2 h 05 min``."""
    if not math.isfinite(seconds):
        return "?"
    seconds = max(0.0, seconds)
    if seconds < 60:
        return f"{seconds:.0f} s" if seconds >= 10 else f"{seconds:.1f} s"
    if seconds < 3600:
        return f"{int(seconds // 60)} min {int(seconds % 60):02d} s"
    return f"{int(seconds // 3600)} h {int(seconds % 3600 // 60):02d} min"


def describe(cost_time: Mapping[str, Any]) -> str:
    """One line for ``runout validate`` and the workbench: ``about 24 s on cpu (start-up 5 s +
    5,251 steps x 3.7 ms: 0.8 ms + 0.29 us per particle, 3.7 us per particle-step at 998
    particles; from ...)``."""
    c = cost_time
    head = ("at most " if c["may_stop_early"] else "about ") + format_seconds(c["run_time_s"])
    parts = f"{c['overhead_s'] * 1e3:.3g} ms + {c['per_particle_s'] * 1e6:.3g} us per particle"
    if c.get("structure_s"):
        parts += f" + {c['structure_s'] * 1e3:.3g} ms for the structures"
    text = (f"{head} on {c['arch']} (start-up {format_seconds(c['startup_s'])} + {c['steps']:,} steps x "
            f"{c['step_time_s'] * 1e3:.3g} ms: {parts}, {c['particle_step_s'] * 1e6:.3g} us per particle-step "
            f"at {c['particles']:,} particles; {c['source']})")
    if c["trial_steps"]:
        text += f", plus each strength-reduction trial up to {format_seconds(c['trial_time_s'])}"
        if c.get("typical_trials"):
            text += (f": usually about {c['typical_trials']} trials, up to "
                     f"{format_seconds(c['typical_trials'] * c['trial_time_s'])} more (at most {c['max_trials']} trials)")
    return text


def estimate_run_time(resolved: Any, *, arch: str | None = None, results_dir: str | Path | None = None,
                      machine: StepCost | None = None) -> dict[str, Any]:
    """The wall time of a resolved run (:class:`projects.build.ResolvedRun`): its steps and
    particles (the seeded count where it was seeded), on ``arch`` (default: the project's, "auto"
    read as the CPU, which is all a machine without a GPU has), at the cost of the project's own
    run in ``results_dir`` if there is one, else ``machine``, else the shipped model
    (:func:`step_cost`); :func:`run_time`'s dict."""
    estimate = dict(resolved.estimate)
    count = getattr(resolved, "particle_count", None)
    if isinstance(count, int) and count > 0:
        estimate["particles"] = count
    if arch not in ("cpu", "gpu"):
        wanted = getattr(getattr(resolved.project, "numerics", None), "arch", "auto")
        arch = wanted if wanted in ("cpu", "gpu") else "cpu"
    structures = bool(getattr(resolved.project, "structures", None))
    cost = step_cost(arch, float(estimate.get("particles") or 0), structures,
                     own=own_run(results_dir, arch), machine=machine)
    return run_time(estimate, cost, structures)
