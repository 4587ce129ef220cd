"""The value of a field at a point or along a section (app.query, `runout query`), on the synthetic
results of tests/conftest.py: a 0.2 m x 0.1 m block whose vertical stress is the overburden
-rho g (0.1 m - y) at the start."""

from __future__ import annotations

import math

import numpy as np
import pytest
from typer.testing import CliRunner

from app.cli import cli
from app.query import csv_text, point_text, values_along, values_at
from projects.results import open_results

RHO_G_KPA = 2650.0 * 9.81 / 1000.0


def test_the_value_at_a_point_is_the_mean_of_the_particles_around_it(make_results):
    results = open_results(make_results())
    answer = values_at(results, "stress_yy", [(0.1, 0.05), (0.5, 0.05)], frame=0)
    inside, outside = answer.points
    # a linear field on a symmetric lattice: the weighted mean is the value at the point
    assert inside.value == pytest.approx(-RHO_G_KPA * 0.05, rel=1e-6)
    assert inside.particles == 4 and inside.nearest_distance_m == pytest.approx(0.0025 * math.sqrt(2))
    assert math.isnan(outside.value) and outside.particles == 0 and outside.nearest is None
    assert answer.frame == 0 and answer.time_s == 0.0 and answer.unit == "kPa" and answer.reach_m == 0.005
    text = point_text(answer).splitlines()
    assert text[0].startswith("Stress yy at (0.1, 0.05), frame 0 (t = 0 s): -1.29982 kPa (the mean of 4 particles")
    assert text[1].endswith("no material (no particle within 0.005 m)")
    last = values_at(results, "displacement", [(0.1, 0.05)], frame=-1)
    assert last.frame == 3 and last.time_s == pytest.approx(0.15) and last.points[0].value > 0


def test_the_value_along_a_section_and_its_csv(make_results):
    results = open_results(make_results())
    answer = values_along(results, "stress_yy", (0.1, 0.0), (0.1, 0.1), frame=0, samples=5)
    values = np.array([p.value for p in answer.points])
    # the overburden along the vertical (the ends, half a spacing from the particles' centres, a
    # little inside the mean of the particles around them)
    assert np.allclose(values[1:4], -RHO_G_KPA * (0.1 - np.array([0.025, 0.05, 0.075])), rtol=1e-6)
    lines = csv_text(answer).splitlines()
    assert lines[0] == "distance_m,x_m,y_m,stress_yy_kPa,particles,nearest_particle" and len(lines) == 6
    assert lines[3].startswith("0.05,0.1,0.05,")
    every = values_along(results, "stress_yy", (0.0, 0.05), (0.3, 0.05), frame=0)
    assert len(every.points) == 121  # every half spacing (2.5 mm) over 0.3 m
    assert sum(math.isnan(p.value) for p in every.points) > 0  # beyond the block: no material


def test_runout_query_at_a_point_and_along_a_section(make_results, tmp_path):
    folder = make_results()
    runner = CliRunner()
    result = runner.invoke(cli, ["query", str(folder), "--field", "stress_yy", "--at", "0.1,0.05", "--frame", "0"])
    assert result.exit_code == 0, result.output
    assert "Stress yy at (0.1, 0.05), frame 0 (t = 0 s): -1.29982 kPa" in result.output
    out = tmp_path / "section.csv"
    result = runner.invoke(cli, ["query", str(folder), "--field", "mean_stress", "--along", "0,0.05,0.2,0.05",
                                 "--samples", "3", "--smooth", "-o", str(out)])
    assert result.exit_code == 0, result.output
    assert "wrote" in result.output and "3 points, 3 in the material, frame 3" in result.output
    assert out.read_text().splitlines()[0] == "distance_m,x_m,y_m,mean_stress_kPa,particles,nearest_particle"
    for args, message in ((["--at", "1"], "--at must be 2 numbers in metres, x,y, got '1'"),
                          (["--field", "nope", "--at", "0,0"], "unknown field 'nope'"),
                          (["--at", "0,0", "--frame", "9"], "--frame 9: the results have 4 frames"),
                          ([], "give --at X,Y (one or more) or --along X0,Y0,X1,Y1")):
        result = runner.invoke(cli, ["query", str(folder), *args])
        assert result.exit_code != 0 and message in result.output, result.output
