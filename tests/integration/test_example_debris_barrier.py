"""The check-dam example (projects/examples/debris_barrier.toml) run to its end through the project
path: the debris comes to rest against the dam, nothing reaches the road behind it, no particle
ends inside the bedrock or the dam, and the forces recorded on the contacts balance the debris's
change of momentum (tests/scene_checks.py)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from projects.document import load_project
from projects.runner import run_project
from tests.scene_checks import check_kept_balanced_and_outside

EXAMPLE = Path(__file__).resolve().parents[2] / "projects" / "examples" / "debris_barrier.toml"


def test_the_debris_comes_to_rest_against_the_check_dam_and_the_forces_balance(tmp_path):
    project = load_project(EXAMPLE)
    result = run_project(project, tmp_path / "r")
    assert result.status == "completed", result.message
    assert "kinetic energy" in result.message  # ended because the debris came to rest, not by its duration
    structures = {s.name: [list(p) for p in s.polygon_m] for s in project.structures}
    contacts = check_kept_balanced_and_outside(tmp_path / "r", structures)
    dam_face = min(x for x, _ in structures["check-dam"])
    hazard = json.loads((tmp_path / "r" / "hazard.json").read_text())
    assert hazard["targets"]["road"]["arrival_time_s"] is None
    # the run-out is read on the envelopes' raster: within one of its cells of the dam's face
    assert dam_face - 1.0 < hazard["runout_x_m"] <= dam_face + hazard["thresholds"]["cell_size_m"]
    summary = json.loads((tmp_path / "r" / "summary.json").read_text())["contacts"]
    dam = contacts["check-dam"]
    assert summary["check-dam"]["peak_force_N_per_m"] == np.max(dam["peak_force_N_per_m"])
    # the debris pushes the dam downstream (+x), and rests on it at the end
    assert dam["force_x_N_per_m"].min() >= 0.0 and dam["force_x_N_per_m"][-1] > 0.0
    # the bedrock carries the debris from the first interval on; the dam only once it arrives
    assert contacts["bedrock"]["force_y_N_per_m"][1] < 0.0 and dam["force_x_N_per_m"][1] == 0.0
