"""The initial equilibrium check at the end of a k0 or gravity stage, in summary.json."""

from __future__ import annotations

import json
from pathlib import Path

from projects.document import apply_overrides, load_project
from projects.runner import run_project


def _box(x0: float, y0: float, w: float, h: float) -> str:
    return f"[[{x0!r},{y0!r}],[{x0 + w!r},{y0!r}],[{x0 + w!r},{y0 + h!r}],[{x0!r},{y0 + h!r}]]"


def _equilibrium(tmp_path: Path, name: str, project) -> dict:
    result = run_project(project, tmp_path / name, arch="cpu")
    assert result.ok, result.message
    check = json.loads((result.out_dir / "summary.json").read_text())["initial_equilibrium"]
    assert check == result.summary["initial_equilibrium"]
    return check


SLOPE = "[[0,0],[0.6,0],[0.6,0.06],[0.36,0.06],[0.2,0.2],[0,0.2]]"


def test_the_initial_equilibrium_check_tells_k0_under_a_slope_from_level_ground(tiny_project, tmp_path):
    from solver.simulation import EQUILIBRIUM_WARN_RATIO

    base = apply_overrides(load_project(tiny_project), ["stages.1.duration_s=0.002"])
    level = _equilibrium(tmp_path, "level", apply_overrides(base, [f"bodies.0.polygon_m={_box(0, 0, 0.6, 0.1)}"]))
    slope_k0 = _equilibrium(tmp_path, "k0", apply_overrides(base, [f"bodies.0.polygon_m={SLOPE}"]))
    slope_gravity = _equilibrium(tmp_path, "gravity", apply_overrides(base, [
        f"bodies.0.polygon_m={SLOPE}", 'stages.0={name = "initial stress", type = "gravity", duration_s = 0.3}']))
    assert level["type"] == slope_k0["type"] == "k0" and slope_gravity["type"] == "gravity"
    # a level layer between walls is geostatic: K0 is (nearly) in equilibrium
    assert level["unbalanced_force_ratio"] < EQUILIBRIUM_WARN_RATIO < slope_k0["unbalanced_force_ratio"]
    # gravity loading brings the slope much closer to equilibrium than K0
    assert slope_gravity["unbalanced_force_ratio"] < 0.5 * slope_k0["unbalanced_force_ratio"]
    assert 0.0 < slope_gravity["max_speed_m_s"] < 0.1  # at the end of the ramp, before the reset
    assert level["max_speed_m_s"] == 0.0
