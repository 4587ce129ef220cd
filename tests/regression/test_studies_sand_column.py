"""Sand-column stability (paper section 2.4), reduced.

The paper's column (2000 particles, 1 m cells) with the solver's stability guard in "remove" mode
(``docs/solver.md``: unstable = speed NaN/inf or above 103 m/s here):

- apic-affine at 4x the paper's step (0.08 ms, 6000 steps over the paper's 0.48 s) keeps every
  particle stable, and none is faster than 1.25 g t + 0.05 m/s during the fall (the rigid free
  fall of the stress-free column; the paper's classic MPM fails this);
- apic-affine over 3 s (fall and landing) at half the critical step stays stable (measured: stable
  up to 1x critical);
- 3x the critical step is unstable and the guard sees it: unstable particles are counted, the run
  ends without an exception and without NaN in the series.
About 20 s on 2 CPU cores.
"""

import numpy as np
import pytest

from studies.common import series_finite
from studies.sand_column import critical_step, run_case

pytestmark = pytest.mark.slow


def test_apic_affine_keeps_every_particle_stable_during_the_fall():
    case = run_case("apic-affine", 8e-5, 0.48, frames=24)
    assert case["status"] == "completed", case["message"]
    assert case["stable_end"] == case["particles"] == 2000
    assert case["max_disturbed"] == 0
    assert case["max_speed_m_s"] <= 1.1 * 9.81 * 0.48
    assert series_finite(case["series"])


def test_apic_affine_is_stable_at_half_the_critical_step():
    case = run_case("apic-affine", 0.5 * critical_step(), 3.0, frames=10)
    assert case["status"] == "completed", case["message"]
    assert case["stable_end"] == 2000


def test_a_step_beyond_the_limit_is_caught_by_the_guard():
    case = run_case("apic-affine", 3.0 * critical_step(), 1.0, frames=10)
    assert case["stable_end"] < 2000
    assert case["first_unstable_step"] is not None
    assert series_finite(case["series"])
    assert np.all(np.asarray(case["series"]["active_particles"]) <= 2000)
