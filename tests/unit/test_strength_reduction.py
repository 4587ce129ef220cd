"""Strength reduction (projects.strength): the reduction, the search's bookkeeping, a small run end to end.

The infinite-slope comparison with the closed form is in tests/regression/test_infinite_slope.py.
"""

from __future__ import annotations

import csv
import json
import math

import pytest

from projects.schema import ProjectError, validate_project
from projects.strength import Settings, StrengthReduction, Trial, reduced_materials
from solver import config as sc


def test_reduction_divides_c_and_tan_phi_and_caps_dilatancy():
    soil = sc.Material("soil", "drucker-prager", 2000.0, 1e7, 0.3, cohesion_pa=10e3,
                       friction_angle_rad=math.radians(30.0), dilatancy_angle_rad=math.radians(10.0),
                       tensile_strength_pa=4e3)
    rock = sc.Material("rock", "linear-elastic", 2500.0, 1e9, 0.25)
    for factor in (0.8, 1.0, 1.5, 3.0):
        out = reduced_materials((soil, rock), (0,), factor)
        assert out[1] == rock  # not chosen: unchanged
        assert out[0].cohesion_pa == pytest.approx(10e3 / factor)
        assert math.tan(out[0].friction_angle_rad) == pytest.approx(math.tan(math.radians(30.0)) / factor)
        assert out[0].tensile_strength_pa == pytest.approx(4e3 / factor)
        assert out[0].dilatancy_angle_rad == pytest.approx(min(math.radians(10.0), out[0].friction_angle_rad))
        assert out[0].dilatancy_angle_rad <= out[0].friction_angle_rad
    # at F = 3 the reduced friction (10.9 deg) is still above psi; at F = 4 (8.2 deg) psi follows it
    assert reduced_materials((soil,), (0,), 4.0)[0].dilatancy_angle_rad == pytest.approx(
        math.atan(math.tan(math.radians(30.0)) / 4.0))


@pytest.mark.parametrize("match", sc.MOHR_COULOMB_MATCHES)
def test_each_trial_rebuilds_the_cone_with_the_materials_own_match(match):
    """A trial's cone is the match's cone of the reduced c, phi, psi (here psi = 0)."""
    from solver.materials import material_rows
    from solver.materials.drucker_prager import dp_constants

    soil = sc.Material("soil", "drucker-prager", 2000.0, 1e7, 0.3, cohesion_pa=10e3,
                       friction_angle_rad=math.radians(30.0), mohr_coulomb_match=match)
    for factor in (0.8, 1.4):
        out = reduced_materials((soil,), (0,), factor)[0]
        assert out.mohr_coulomb_match == match
        rows = material_rows((out,))
        phi_f = math.atan(math.tan(math.radians(30.0)) / factor)
        alpha, k, _ = dp_constants(phi_f, 0.0, 10e3 / factor, match)
        assert rows["alpha"][0] == pytest.approx(alpha, rel=1e-12)
        assert rows["kc"][0] == pytest.approx(k, rel=1e-12)


def _driver(first, tolerance=0.01, step=0.1, max_trials=40):
    settings = Settings(label="fos", stage_index=1, materials=(0,), tolerance=tolerance, first_trial=first,
                        bracket_step=step, max_trials=max_trials)
    return StrengthReduction(project=None, built=None, settings=settings)


def _fake(driver, critical):
    def trial(factor):
        failed = factor > critical
        t = Trial(factor, "failed" if failed else "stable", "displacement" if failed else "settled",
                  0.0, 0.0, 0.0, 0.0, 0, 0.0)
        driver.trials.append(t)
        return t
    return trial


@pytest.mark.parametrize("first", [0.3, 1.0, 1.37, 1.9, 7.0])
@pytest.mark.parametrize("critical", [0.62, 1.2345, 2.5])
def test_bisection_bookkeeping(first, critical):
    d = _driver(first)
    d._search(_fake(d, critical))
    assert d.lower is not None and d.upper is not None
    assert d.upper - d.lower <= 0.01
    assert d.lower <= critical < d.upper
    # the bracket holds a stable and a failing trial that really ran
    assert d._trial_at(d.lower).verdict == "stable" and d._trial_at(d.upper).verdict == "failed"
    # every stable trial lies at or below the lower end, every failing one at or above the upper end
    assert all(t.factor <= d.lower for t in d.trials if not t.failed)
    assert all(t.factor >= d.upper for t in d.trials if t.failed)
    assert d.value == pytest.approx(0.5 * (d.lower + d.upper))
    assert d.criterion == "displacement"
    # reproducible: the same trials in the same order
    again = _driver(first)
    again._search(_fake(again, critical))
    assert [t.factor for t in again.trials] == [t.factor for t in d.trials]


def test_search_reports_when_it_cannot_bracket():
    d = _driver(1.0, max_trials=4)
    d._search(_fake(d, 100.0))
    assert d.upper is None and "stable at every trial factor" in d.message
    d = _driver(1.0)
    d._search(_fake(d, 0.0))
    assert d.lower is None and "fails at every trial factor" in d.message


def _project(**sr):
    return {
        "runout": {"schema_version": 1},
        "domain": {"size_m": [12.0, 6.0], "cell_size_m": 0.5},
        "materials": {"soil": {"model": "drucker-prager", "density_kg_m3": 2000.0, "youngs_modulus_pa": 1e7,
                               "poisson_ratio": 0.3, "cohesion_pa": 5e3, "friction_angle_deg": 25.0},
                      "rock": {"model": "linear-elastic", "density_kg_m3": 2500.0, "youngs_modulus_pa": 1e9,
                               "poisson_ratio": 0.25}},
        "bodies": [{"name": "slope", "material": "soil",
                    "polygon_m": [[0.0, 0.0], [12.0, 0.0], [12.0, 1.5], [7.0, 1.5], [4.0, 4.5], [0.0, 4.5]]}],
        "numerics": {"cfl": 0.5},
        "stages": [{"type": "k0"}, {"type": "strength-reduction", "trial_duration_s": 0.6, **sr},
                   {"type": "dynamic", "duration_s": 0.2}],
        "output": {"interval_s": 0.1},
    }


@pytest.mark.parametrize(("change", "path", "message"), [
    ({"materials": ["rock"]}, "stages.1.materials.0", "not a drucker-prager material; defined: soil"),
    ({"duration_s": 1.0}, "stages.1.duration_s", "not allowed on a strength-reduction stage"),
    ({"first_trial": "bishop"}, "stages.1.first_trial", 'must be a number > 0 or "limit-equilibrium"'),
    ({"failure": {"criteria": ["speed"]}}, "stages.1.failure.criteria.0", "must be one of"),
])
def test_bad_strength_reduction_keys_are_named(change, path, message):
    with pytest.raises(ProjectError) as err:
        validate_project(_project(**change))
    assert any(p.path == path and message in p.message for p in err.value.problems), str(err.value)


def test_stage_order_rules():
    data = _project()
    data["stages"] = [data["stages"][1], data["stages"][0]]
    with pytest.raises(ProjectError, match="must follow the initial-stress stage"):
        validate_project(data)
    data = _project()
    data["stages"].append({"type": "dynamic", "duration_s": 0.2})
    with pytest.raises(ProjectError, match="at most one stage"):
        validate_project(data)
    data = _project()
    data["stages"][0]["tolerance"] = 0.1
    with pytest.raises(ProjectError, match="only allowed on a strength-reduction stage"):
        validate_project(data)


def test_a_small_run_end_to_end(tmp_path, monkeypatch):
    """k0, strength reduction, run-out: summary, trials file, mechanism frame; one initial stress."""
    import solver.simulation as simulation
    from projects.results import read_vtp
    from projects.runner import run_project

    calls = []
    original = simulation.k0_stress
    monkeypatch.setattr(simulation, "k0_stress", lambda *a, **k: calls.append(1) or original(*a, **k))
    project = validate_project(_project(tolerance=0.05, failure={"displacement_m": 0.1}))
    result = run_project(project, tmp_path / "out")
    assert result.status == "completed", result.message
    fos = result.summary["factor_of_safety"]
    assert calls == [1] and fos["initial_stress_runs"] == 1  # the checkpoint is reused by every trial
    assert fos["upper"] - fos["lower"] <= 0.05 and fos["lower"] < fos["value"] < fos["upper"]
    trials = {t["factor"]: t for t in fos["trials"]}
    assert trials[fos["lower"]]["verdict"] == "stable" and trials[fos["upper"]]["verdict"] == "failed"
    assert fos["criterion"] in ("displacement", "kinetic-energy")
    le = result.summary["limit_equilibrium"]
    assert le["factor_of_safety"] > 0 and le["circle"]["radius_m"] > 0
    # Bishop's factor is the first trial (the comparison of the two is `runout study fos`)
    assert fos["trials"][0]["factor"] == pytest.approx(le["factor_of_safety"])
    assert fos["value"] > 1.0  # this slope stands under its own strength
    with open(tmp_path / "out" / "fos_trials.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [float(r["factor"]) for r in rows] == [t["factor"] for t in fos["trials"]]
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["factor_of_safety"]["mechanism_frame"] == fos["mechanism_frame"]
    frames = sorted((tmp_path / "out" / "frames").glob("*.vtp"))
    mechanism = read_vtp(frames[fos["mechanism_frame"]])
    assert mechanism["plastic_strain"].max() > 0.0
    assert fos["runout_factor"] == fos["upper"]
    # the faces: the command line's line and the mechanism picture
    from app.cli import _factor_line
    from app.render import render_mechanism

    line = _factor_line(result)
    assert line.startswith(f"factor of safety {fos['value']:.3f}") and "Bishop" in line and "runs out" in line
    picture = render_mechanism(tmp_path / "out")
    assert picture.is_file() and picture.stat().st_size > 10_000


@pytest.mark.parametrize("gravity_angle_deg", [0.0, 20.0])
def test_crest_is_the_top_of_the_slope_face(gravity_angle_deg):
    """The default monitor point: a slope drawn in a frame where gravity points down, rotated."""
    import numpy as np

    from geometry.seeding import seed_lattice
    from projects.strength import crest_point

    polygon = np.array([[0.0, 0.0], [30.0, 0.0], [30.0, 3.0], [14.0, 3.0], [8.0, 9.0], [0.0, 9.0]])
    seeds = seed_lattice([polygon], (0.0, 0.0), 0.5, 2)
    a = math.radians(gravity_angle_deg)
    rot = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    points = seeds.positions_m @ rot.T
    gravity = rot @ np.array([0.0, -9.81])
    crest = np.linalg.solve(rot, crest_point(points, gravity, 0.5))
    assert crest[0] == pytest.approx(8.0, abs=1.0) and crest[1] == pytest.approx(9.0, abs=0.5)


@pytest.mark.parametrize("scheme", ["mpm", "apic", "apic-affine"])
def test_strength_reduction_under_classic_mpm_is_warned_about(scheme):
    from projects.checks import project_warnings
    from projects.schema import validate_project

    data = _project()
    data["numerics"]["scheme"] = scheme
    found = [w for w in project_warnings(validate_project(data)) if "strength-reduction" in w and "scheme" in w]
    if scheme == "mpm":
        assert len(found) == 1 and found[0].startswith('numerics.scheme = "mpm" with stages.1 (strength-reduction)')
        assert "apic-affine" in found[0]
    else:
        assert found == []
