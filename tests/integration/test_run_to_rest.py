"""Whether a run's answer is final (projects.motion): a stage that ends while the mass still moves
says so in summary.json, hazard.json and the command line's final status line, with the kinetic
energy at the end as a fraction of its peak and the fastest particle; a stage with a rest criterion
ends by itself once the mass has come to rest, its fastest particle included.

The scene is the tiny column (projects/examples/tiny_column.toml, 288 particles): 0.05 s into its
collapse it moves at its peak; it comes to rest by about 0.55 s.
"""

from __future__ import annotations

import json
import math
import re

import pytest

from projects.document import load_project
from projects.motion import default_rest_speed, verdict
from projects.runner import run_project
from tests.conftest import TINY_PROJECT

#: the tiny column's collapse run long enough to come to rest, ending at rest
TO_REST = ["stages.1.duration_s=2.0", "output.interval_s=0.05", "stages.1.stop_when_kinetic_energy_below=0.01",
           "stages.1.stop_when_max_speed_below_m_s=0.01"]


def _run(tmp_path, overrides, name="r"):
    result = run_project(load_project(TINY_PROJECT, overrides), tmp_path / name)
    assert result.status == "completed", result.message
    summary = json.loads((tmp_path / name / "summary.json").read_text())
    hazard = json.loads((tmp_path / name / "hazard.json").read_text())
    return result, summary, hazard


def test_a_short_stage_ends_still_moving_and_says_so(tmp_path):
    _result, summary, hazard = _run(tmp_path, [])  # 0.05 s: the column is still collapsing
    m = summary["motion_at_end"]
    assert summary["still_moving"] is True and m["still_moving"] is True
    assert m["ended_by"] == "duration" and m["stage"] == "collapse" and m["time_s"] == pytest.approx(0.05)
    # the kinetic energy at the end as a fraction of its peak: the collapse speeds up to the end
    assert m["kinetic_energy_fraction"] == pytest.approx(m["kinetic_energy_J_per_m"] / m["peak_kinetic_energy_J_per_m"])
    assert m["kinetic_energy_fraction"] > 0.5
    # the thresholds applied: the hazard's fraction and the default rest speed 0.1 sqrt(g dx)
    assert m["rest_kinetic_energy_fraction"] == 0.01
    assert m["rest_speed_m_s"] == pytest.approx(0.1 * math.sqrt(9.81 * 0.02))
    assert m["max_speed_m_s"] > m["rest_speed_m_s"]
    # hazard.json agrees: no end of the slide, its measures provisional
    assert hazard["still_moving"] is True and hazard["slide_end_time_s"] is None
    assert hazard["motion_at_end"] == m


def test_a_stage_with_a_rest_criterion_ends_by_itself_at_rest(tmp_path):
    result, summary, hazard = _run(tmp_path, TO_REST)
    m = summary["motion_at_end"]
    assert m["ended_by"] == "rest" and summary["still_moving"] is False and hazard["still_moving"] is False
    assert 0.2 < summary["simulated_time_s"] < 1.0  # well before its 2 s safety limit
    assert "ended by its rest criterion" in result.message and "kinetic energy" in result.message
    assert m["max_speed_m_s"] < 0.01 and m["kinetic_energy_fraction"] < 0.01
    assert m["rest_speed_m_s"] == 0.01  # the stage's own thresholds
    assert hazard["slide_end_time_s"] is not None


def test_the_end_criterion_sees_the_fastest_particle(tmp_path):
    # the energy alone ends the stage earlier than energy and speed together: with the speed the
    # stage waits for its fastest particle
    energy_only = [o for o in TO_REST if "max_speed" not in o]
    _, alone, _ = _run(tmp_path, energy_only, "energy")
    _, both, _ = _run(tmp_path, TO_REST, "both")
    assert alone["simulated_time_s"] < both["simulated_time_s"]
    # ... and a speed alone does not end the stage at its start, where nothing moves yet
    speed_only = [o for o in TO_REST if "kinetic_energy" not in o]
    _, speed, _ = _run(tmp_path, speed_only, "speed")
    assert speed["motion_at_end"]["ended_by"] == "rest" and speed["simulated_time_s"] > 0.2
    assert speed["motion_at_end"]["max_speed_m_s"] < 0.01


def test_the_verdict_needs_both_energy_and_speed_below_their_rest_values():
    base = {"stage": "run-out", "ended_at_rest": True, "time_s": 4.18, "stop_when_kinetic_energy_below": 0.01,
            "stop_when_max_speed_below_m_s": None, "kinetic_energy_J_per_m": 7.4e3,
            "peak_kinetic_energy_J_per_m": 8.0e5, "max_speed_m_s": 10.1}
    # the check dam's stage ended by its energy criterion while five particles still slid at 10 m/s
    m = verdict(base, kinetic_energy_fraction=0.01, rest_speed_m_s=default_rest_speed((0.0, -9.81), 0.25))
    assert m["still_moving"] is True and m["ended_by"] == "rest"
    assert m["rest_speed_m_s"] == pytest.approx(0.1566, abs=1e-4)
    slow = verdict({**base, "max_speed_m_s": 0.09}, kinetic_energy_fraction=0.01, rest_speed_m_s=0.1566)
    assert slow["still_moving"] is False
    energetic = verdict({**base, "max_speed_m_s": 0.09, "kinetic_energy_J_per_m": 1e5},
                        kinetic_energy_fraction=0.01, rest_speed_m_s=0.1566)
    assert energetic["still_moving"] is True
    assert verdict(None, kinetic_energy_fraction=0.01, rest_speed_m_s=0.1) is None


def test_the_command_line_says_whether_the_answer_is_final(tmp_path):
    from tests.integration.test_cli_run import runout

    moving = runout("run", str(TINY_PROJECT), "--out", str(tmp_path / "moving"), cwd=tmp_path)
    assert moving.returncode == 0, moving.stderr
    summary = json.loads((tmp_path / "moving" / "summary.json").read_text())
    fraction = summary["motion_at_end"]["kinetic_energy_fraction"]
    lines = moving.stdout.splitlines()
    final = next(line for line in lines if line.startswith("completed"))
    said = re.match(r"completed, still moving \(kinetic energy (\S+) of its peak, fastest particle (\S+) m/s", final)
    assert said, final
    assert float(said[1]) == pytest.approx(fraction, rel=0.05)
    assert float(said[2]) == pytest.approx(summary["motion_at_end"]["max_speed_m_s"], rel=0.005)
    assert "its measures are provisional" in moving.stderr and "stop_when_max_speed_below_m_s" in moving.stderr
    rest = runout("run", str(TINY_PROJECT), "--out", str(tmp_path / "rest"), *[a for o in TO_REST for a in ("--set", o)],
                  cwd=tmp_path)
    assert rest.returncode == 0, rest.stderr
    final = next(line for line in rest.stdout.splitlines() if line.startswith("completed"))
    assert final.startswith("completed, at rest (kinetic energy ") and "provisional" not in rest.stdout + rest.stderr
