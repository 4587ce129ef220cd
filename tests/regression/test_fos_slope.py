"""The shipped strength-reduction example against Bishop's simplified method, and its cost.

``projects/examples/slope_fos.toml`` (6 m high 45 deg slope, c = 10 kPa, phi = 30 deg, psi = 0)
at its own 0.5 m cells, without the run-out stage. Measured (docs/validation.md, `runout study
fos`): F = 1.547 in [1.542, 1.552] against Bishop's 1.487 (+4 %), 6 trials costing 3.8
equilibrium runs. Tolerances: within 10 % of Bishop (strength reduction with non-associated
Drucker-Prager on a 12-cell-high slope against limit equilibrium with Mohr-Coulomb; the study
shows the factor falling towards Bishop's as the cells get smaller) and at most 8 equilibrium runs
of steps for a factor to 0.01 (the issue's target; steps, not seconds, so the machine's load does
not matter). About 20 s on 2 idle cores.
"""

import pytest

from projects.runner import run_project
from studies.common import load_scene

pytestmark = pytest.mark.slow


def test_example_factor_against_bishop_and_its_cost(tmp_path):
    project = load_scene("slope_fos")
    project = project.model_copy(update={"stages": project.stages[:2]})
    result = run_project(project, tmp_path / "fos")
    assert result.status == "completed", result.message
    fos = result.summary["factor_of_safety"]
    bishop = result.summary["limit_equilibrium"]["factor_of_safety"]
    assert bishop == pytest.approx(1.487, rel=0.01)
    assert fos["upper"] - fos["lower"] <= 0.01
    assert fos["value"] == pytest.approx(bishop, rel=0.10)
    assert fos["search_steps"] <= 8 * fos["equilibrium_steps"]
    assert fos["initial_stress_runs"] == 1
