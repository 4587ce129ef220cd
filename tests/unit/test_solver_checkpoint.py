"""Checkpoints: a run restored from any checkpoint continues bit for bit like the uninterrupted one.

Every scheme, with a gravity-loading stage (ramped gravity, damping, velocities reset at its end)
and a dynamic stage that stops early on its kinetic-energy criterion, so that every phase of the
run loop (stage start, time loop, stage end) is a checkpoint at least once; mpm also with a
structure the column leans on, apic-affine also with a Maxwell arm. The suite runs apic-affine in
f64 and mpm in f32; ``RUNOUT_FULL_MATRIX=1`` every case. Serial scatter: its
sums come in a fixed order, so equal states give equal steps.
"""

import numpy as np
import pytest

from projects.build import resolve
from projects.document import load_project
from solver.simulation import Simulation
from tests.conftest import TINY_PROJECT

# the suite runs a covering sample of each matrix below (tests/conftest.py, RUNOUT_FULL_MATRIX)
pytestmark = pytest.mark.matrix

SETS = [
    "numerics.advanced.scatter=serial",
    'stages.0 = {name = "settle", type = "gravity", duration_s = 0.015}',
    "stages.1.duration_s=0.4",
    "stages.1.stop_when_kinetic_energy_below=0.5",
    "stages.1.min_duration_s=0.03",
    "output.interval_s=0.02",
]


def _frames_and_checkpoints(resolved):
    frames, checkpoints = [], {}
    with Simulation(resolved.config, resolved.particles) as sim:
        for i, frame in enumerate(sim.run()):
            frames.append(frame)
            if sim.can_checkpoint:
                checkpoints[i] = (sim.checkpoint(), sim.cursor.phase)
        checkpoints[len(frames) - 1] = (sim.checkpoint(), sim.cursor.phase)  # the end of the run
        message = sim.message
    return frames, checkpoints, message


def _same(a, b):
    assert a.diagnostics == b.diagnostics
    assert a.fields.keys() == b.fields.keys()
    for name in a.fields:
        np.testing.assert_array_equal(a.fields[name], b.fields[name], err_msg=name)


#: a friction wall the column leans on from the start, its face half a cell off the node line: the
#: structure contact's state that outlives a step (``Engine.node_hold``, the step stamps of the
#: nodes it held) is in the checkpoint
WALL = ('structures=[{name="wall",polygon_m=[[0.13,0.0],[0.19,0.0],[0.19,0.1],[0.13,0.1]],'
        'contact={type="friction",friction_angle_deg=20.0}}]')


#: a Maxwell arm's damping stress relaxes over steps: it is particle state (``Engine.sv``)
MAXWELL = ["materials.sand.damping_ratio=0.1", "materials.sand.damping_frequency_hz=20",
           'materials.sand.damping_model="maxwell"']


# the suite's covering sample is the first two (every precision, apic-affine and mpm);
# RUNOUT_FULL_MATRIX=1 runs all six
@pytest.mark.matrix(sample=2)
@pytest.mark.parametrize(("scheme", "precision", "extra"),
                         [("apic-affine", "f64", []), ("mpm", "f32", []), ("mpm", "f32", [WALL]),
                          ("apic", "f32", []), ("apic-affine", "f32", []), ("apic-affine", "f32", MAXWELL)])
def test_restore_from_every_checkpoint_gives_the_same_frames(scheme, precision, extra):
    project = load_project(TINY_PROJECT, [*SETS, f"numerics.scheme={scheme}", f"numerics.precision={precision}",
                                          *extra])
    resolved = resolve(project)
    frames, checkpoints, message = _frames_and_checkpoints(resolved)
    phases = {phase for _, phase in checkpoints.values()}
    assert {"loop", "end", "done"} <= phases, phases
    assert "kinetic energy" in message  # the dynamic stage ended on its criterion
    # the first checkpoint of each phase and the last of the time loop (each restore replays the rest)
    chosen = {}
    for index, (_, phase) in sorted(checkpoints.items()):
        chosen.setdefault(phase, [index, index])[1] = index
    for index in sorted({pair[0] for pair in chosen.values()} | {chosen["loop"][1]}):
        checkpoint = checkpoints[index][0]
        with Simulation(resolved.config, resolved.particles) as sim:
            sim.restore(checkpoint)
            rest = list(sim.run())
            assert sim.message == message
        assert len(rest) == len(frames) - index - 1
        for a, b in zip(frames[index + 1:], rest):
            _same(a, b)


def test_a_checkpoint_is_refused_by_another_run():
    resolved = resolve(load_project(TINY_PROJECT, SETS))
    _, checkpoints, _ = _frames_and_checkpoints(resolved)
    other = resolve(load_project(TINY_PROJECT, [*SETS, "materials.sand.friction_angle_deg=25"]))
    from solver.config import SolverError

    with Simulation(other.config, other.particles) as sim, pytest.raises(SolverError, match="another configuration"):
        sim.restore(next(iter(checkpoints.values()))[0])
