"""Sweep files and sampling: validation messages, Latin hypercube strata, seeds, bounds."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from projects.schema import ProjectError
from sweeps.engine import resolve_runs, toml_value
from sweeps.sampling import levels, quantile, sample
from sweeps.spec import Parameter, load_spec, parse_spec

TINY = Path(__file__).resolve().parents[2] / "projects" / "examples" / "tiny_column.toml"


def spec(params: dict, **sweep) -> object:
    table = {"project": str(TINY), "sampling": "latin-hypercube", "runs": 8, "seed": 3, **sweep}
    return parse_spec({"sweep": table, "parameters": params}, Path("."))


@pytest.mark.parametrize("runs", [1, 5, 16])
@pytest.mark.parametrize("seed", [0, 7])
def test_latin_hypercube_hits_each_stratum_once(runs, seed):
    s = spec({"a": {"distribution": "uniform", "low": 10.0, "high": 20.0},
              "b": {"distribution": "uniform", "low": -1.0, "high": 1.0}}, runs=runs, seed=seed)
    rows = sample(s)
    for key, (lo, hi) in {"a": (10.0, 20.0), "b": (-1.0, 1.0)}.items():
        u = (np.array([r[key] for r in rows]) - lo) / (hi - lo)
        strata = np.floor(u * runs).astype(int)
        assert sorted(strata) == list(range(runs))


@pytest.mark.parametrize("sampling", ["random", "latin-hypercube"])
def test_seeds_reproduce_and_differ(sampling):
    p = {"a": {"distribution": "normal", "mean": 30.0, "std": 3.0}, "b": [1, 2, 3]}
    first = sample(spec(p, sampling=sampling, seed=11, runs=12))
    again = sample(spec(p, sampling=sampling, seed=11, runs=12))
    other = sample(spec(p, sampling=sampling, seed=12, runs=12))
    assert first == again
    assert first != other


@pytest.mark.parametrize("sampling", ["random", "latin-hypercube"])
@pytest.mark.parametrize("param, lo, hi", [
    ({"distribution": "uniform", "low": 20.0, "high": 40.0}, 20.0, 40.0),
    ({"distribution": "normal", "mean": 30.0, "std": 10.0, "low": 25.0, "high": 32.0}, 25.0, 32.0),
    ({"distribution": "normal", "mean": 30.0, "std": 10.0, "low": 29.0}, 29.0, math.inf),
    ({"distribution": "lognormal", "mean_log": 8.0, "std_log": 1.5, "high": 5000.0}, 0.0, 5000.0),
    ({"distribution": "lognormal", "mean_log": 0.0, "std_log": 0.5, "low": 1.2, "high": 1.3}, 1.2, 1.3),
])
def test_distributions_respect_their_bounds(sampling, param, lo, hi):
    values = np.array([r["x"] for r in sample(spec({"x": param}, sampling=sampling, runs=400, seed=1))])
    assert values.min() >= lo and values.max() <= hi
    assert np.ptp(values) > 0


def test_truncated_normal_matches_scipy():
    p = Parameter(distribution="normal", mean=30.0, std=5.0, low=28.0, high=40.0)
    u = np.array([0.0, 0.25, 0.5, 0.9])
    a, b = (28.0 - 30.0) / 5.0, (40.0 - 30.0) / 5.0
    expected = stats.truncnorm(a, b, loc=30.0, scale=5.0).ppf(u)
    assert np.allclose(quantile(p, u), expected, rtol=1e-9, atol=1e-9)


def test_lognormal_median_is_exp_mean_log():
    p = Parameter(distribution="lognormal", mean_log=math.log(2000.0), std_log=0.4)
    assert float(quantile(p, np.array([0.5]))[0]) == pytest.approx(2000.0, rel=1e-12)


def test_grid_is_the_product_of_levels():
    s = spec({"a": [1, 2, 3], "b": {"distribution": "range", "low": 10, "high": 30, "count": 3},
              "c": {"distribution": "uniform", "low": 0.0, "high": 1.0, "levels": 2}}, sampling="grid", runs=None)
    rows = sample(s)
    assert len(rows) == 18
    assert {r["b"] for r in rows} == {10, 20, 30} and all(isinstance(r["b"], int) for r in rows)
    assert {r["c"] for r in rows} == {0.25, 0.75}
    assert levels(Parameter(distribution="range", low=0.5, high=1.0, count=3)) == [0.5, 0.75, 1.0]


def test_list_values_are_drawn_evenly():
    rows = sample(spec({"s": ["apic", "apic-affine"]}, runs=10))
    assert sorted(r["s"] for r in rows) == ["apic"] * 5 + ["apic-affine"] * 5


@pytest.mark.parametrize("data, message", [
    ({"sweep": {"project": "p.toml", "runs": 2, "samplng": "grid"}, "parameters": {"a": [1]}},
     "sweep.samplng: unknown key; allowed: project"),
    ({"sweep": {"project": "p.toml", "runs": 2, "sampling": "sobol"}, "parameters": {"a": [1]}},
     'sweep.sampling = "sobol": must be one of "grid", "random", "latin-hypercube"'),
    ({"sweep": {"project": "p.toml"}, "parameters": {"a": [1]}},
     'runs is required with sampling "latin-hypercube"'),
    ({"sweep": {"project": "p.toml", "runs": 2}, "parameters": {"m.phi": {"distribution": "normal", "mean": 1.0}}},
     'parameters."m.phi": a "normal" parameter needs mean, std (missing: std)'),
    ({"sweep": {"project": "p.toml", "runs": 2}, "parameters": {"a": {"distribution": "uniform", "low": 3, "high": 1}}},
     "low must be < high"),
    ({"sweep": {"project": "p.toml", "runs": 2}, "parameters": {"a": {"distribution": "uniform", "low": 0,
                                                                      "high": 1, "mean": 3}}},
     'a "uniform" parameter takes also, high, levels, low (not mean)'),
    ({"sweep": {"project": "p.toml", "runs": 0}, "parameters": {"a": [1]}}, "runs must be >= 1"),
    ({"parameters": {"a": [1]}}, "exactly one of the tables [sweep] or [calibration]"),
])
def test_bad_sweep_files_give_one_line_naming_the_key(data, message):
    with pytest.raises(ProjectError) as info:
        parse_spec(data, Path("."), source="s.toml")
    text = str(info.value)
    assert message in text
    assert "\n" not in text and "Traceback" not in text


def test_unknown_project_key_is_reported_before_anything_runs():
    s = spec({"materials.sand.frction_angle_deg": [20.0, 30.0]}, sampling="grid", runs=None)
    with pytest.raises(ProjectError, match="materials.sand.frction_angle_deg: unknown key; allowed:"):
        resolve_runs(s.project_path, s.sweep.set, sample(s))


def test_values_that_make_one_run_invalid_are_kept_as_problems():
    s = spec({"materials.sand.friction_angle_deg": [30.0, -5.0]}, sampling="grid", runs=None)
    plans = resolve_runs(s.project_path, s.sweep.set, sample(s))
    assert plans[0].problem == "" and len(plans[0].run_id) == 16
    assert "friction_angle_deg" in plans[1].problem and plans[1].run_id == ""


def test_run_ids_hash_the_resolved_project():
    s = spec({"materials.sand.friction_angle_deg": [30.0, 30.0, 31.0]}, sampling="grid", runs=None)
    ids = [p.run_id for p in resolve_runs(s.project_path, s.sweep.set, sample(s))]
    assert ids[0] == ids[1] != ids[2]
    # 30.0 is the file's own value: the same resolved project as no override at all
    assert ids[0] == resolve_runs(s.project_path, [], [{}])[0].run_id


@pytest.mark.parametrize("value, text", [(0.1, "0.1"), (1e-05, "1e-05"), (3, "3"), (True, "true"),
                                         ("apic", '"apic"')])
def test_toml_values_round_trip(value, text):
    assert toml_value(value) == text


def test_load_spec_reads_relative_paths_from_its_folder(tmp_path):
    (tmp_path / "s.toml").write_text(
        '[sweep]\nproject = "p.toml"\nsampling = "grid"\n[parameters]\n"a.b" = [1, 2]\n', encoding="utf-8")
    s = load_spec(tmp_path / "s.toml")
    assert s.project_path == (tmp_path / "p.toml").resolve()
    with pytest.raises(ProjectError, match="TOML syntax error at line 1"):
        (tmp_path / "bad.toml").write_text("[sweep\n", encoding="utf-8")
        load_spec(tmp_path / "bad.toml")


EXAMPLE_SPECS = sorted((TINY.parent / "sweeps").glob("*.toml"))


@pytest.mark.parametrize("path", EXAMPLE_SPECS, ids=lambda p: p.stem)
def test_shipped_sweep_files_load_resolve_and_round_trip(path, tmp_path):
    from projects.document import parse_toml
    from sweeps.spec import command_line, dumps_spec

    s = load_spec(path)
    assert parse_spec(parse_toml(dumps_spec(s)), s.base) == s
    assert s.project_path.is_file()
    if hasattr(s, "sweep"):
        plans = resolve_runs(s.project_path, s.sweep.set, sample(s), s.linked)
        assert len(plans) == s.sweep.runs and all(p.run_id and not p.problem for p in plans)
        assert command_line(path, tmp_path)[3] == "sweep"
    else:
        assert s.observation_path.is_file()
        assert command_line(path, tmp_path)[3] == "calibrate"


def test_also_sets_linked_keys_to_the_same_value():
    s = spec({"materials.sand.friction_angle_deg": {"values": [22.0],
                                                    "also": ["domain.boundaries.bottom.friction_angle_deg"]}},
             sampling="grid", runs=None)
    plan = resolve_runs(s.project_path, s.sweep.set, sample(s), s.linked)[0]
    assert plan.overrides == ("materials.sand.friction_angle_deg=22.0",
                              "domain.boundaries.bottom.friction_angle_deg=22.0")
    assert "friction_angle_deg = 22.0" in plan.project_text


def _runout(*args: str, cwd: Path) -> "subprocess.CompletedProcess[str]":
    import os
    import subprocess
    import sys

    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(TINY.parents[2]), env.get("PYTHONPATH", "")])
    return subprocess.run([sys.executable, "-m", "app.cli", *args], cwd=cwd, capture_output=True, text=True,
                          timeout=120, env=env)


def test_command_line_reports_bad_sweep_files_in_one_line(tmp_path):
    (tmp_path / "s.toml").write_text(f'[sweep]\nproject = "{TINY}"\nsampling = "grid"\n'
                                     '[parameters]\n"materials.sand.friction_angl" = [1.0]\n', encoding="utf-8")
    res = _runout("sweep", "s.toml", cwd=tmp_path)
    assert res.returncode == 1
    assert res.stderr.strip().splitlines() == [
        "error: s.toml: materials.sand.friction_angl: unknown key; allowed: model, density_kg_m3, youngs_modulus_pa, "
        "poisson_ratio, cohesion_pa, friction_angle_deg, dilatancy_angle_deg, tensile_strength_pa, "
        "mohr_coulomb_match, damping_ratio, damping_frequency_hz, damping_model, saturated_density_kg_m3, ru, "
        "softening_law, residual_cohesion_pa, residual_friction_angle_deg, residual_dilatancy_angle_deg, "
        "peak_plastic_strain, residual_plastic_strain, softening_length_m, mu_i_friction_increase, "
        "mu_i_reference_number, grain_diameter_m, grain_density_kg_m3, velocity_m_s, contact"]
    assert not (tmp_path / "s.sweep").exists()
    res = _runout("calibrate", "s.toml", cwd=tmp_path)
    assert res.returncode == 1 and "this is a sweep file" in res.stderr
    res = _runout("report", str(tmp_path), cwd=tmp_path)  # neither a sweep nor a results folder
    assert res.returncode == 1 and len(res.stderr.strip().splitlines()) == 1
