"""Volumetric locking: an undrained vertical cut's stability number, with the averaging and
without, in every scheme; and the setting's rules.

The cut (tests/data/vertical_cut_undrained.toml: c = 20 kPa, phi = psi = 0, 20 kN/m3, H = 2 m,
0.1 m cells, 4 particles a cell) has the stability number ``N = gamma H F / c`` between the
lower bound 3.77 and the upper bound 3.83 (Pastor 1978; Chen 1975, Limit Analysis and Soil
Plasticity); tolerance: within those bounds widened by 3 %. Measured (docs/validation.md,
volumetric locking): averaging on N = 3.90 (apic-affine), off 4.02; plain apic 3.96 either way
(a strict xfail).
"""

import os
from pathlib import Path

import pytest

from projects.document import load_project
from projects.runner import run_project
from solver.config import Material, averages_volume
from tests.conftest import FULL_MATRIX

DATA_DIR = Path(__file__).resolve().parents[1] / "data"

pytestmark = [pytest.mark.slow, pytest.mark.matrix]

LOWER, UPPER, TOLERANCE = 3.77, 3.83, 0.03
GAMMA_H_OVER_C = 20e3 * 2.0 / 20e3


#: the search starts inside the bounds (F = 1.9, N = 3.8) with steps of 3 %: it brackets and bisects
#: to the file's tolerance (0.01) as from the file's 2.0 with 10 % steps, in five trials instead of
#: seven or eight (two of them failing, a whole trial_duration_s each)
SEARCH = ["stages.1.first_trial=1.9", "stages.1.bracket_step=0.03"]


#: plain APIC (the stress from the grid's velocity gradient) reads N = 3.96, +3.4 % over the upper
#: bound with the averaging on or off (docs/validation.md): outside the tolerance, a strict xfail
#: (with RUNOUT_FULL_MATRIX=1, beside the other schemes' full runs) that says when it comes within
APIC_ABOVE = pytest.mark.xfail(strict=True, reason="plain apic: N = 3.96, +3.4 % over the upper bound 3.83")


SCHEMES = ["apic-affine", "mpm"] + ([pytest.param("apic", marks=APIC_ABOVE)] if os.environ.get(FULL_MATRIX) else [])


@pytest.mark.parametrize("scheme", SCHEMES)
def test_an_undrained_vertical_cut_has_the_limit_analysis_stability_number(tmp_path, scheme):
    project = load_project(DATA_DIR / "vertical_cut_undrained.toml", [f"numerics.scheme={scheme}", *SEARCH])
    result = run_project(project, tmp_path / "cut")
    assert result.status == "completed", result.message
    number = result.summary["factor_of_safety"]["value"] * GAMMA_H_OVER_C
    assert LOWER * (1.0 - TOLERANCE) <= number <= UPPER * (1.0 + TOLERANCE), number


def test_auto_averages_only_where_a_material_flows_at_constant_volume_without_friction():
    clay = Material("clay", "drucker-prager", 2000.0, 1e7, 0.3, cohesion_pa=2e4)
    sand = Material("sand", "drucker-prager", 2000.0, 1e7, 0.3, friction_angle_rad=0.5)
    rock = Material("rock", "linear-elastic", 2600.0, 1e9, 0.25)
    assert averages_volume("auto", [sand, clay])
    assert not averages_volume("auto", [sand, rock])
    assert averages_volume("on", [sand]) and not averages_volume("off", [clay])
    with pytest.raises(ValueError, match="volumetric_averaging 'yes'"):
        averages_volume("yes", [clay])
