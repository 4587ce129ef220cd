"""The hazard report of a run with ground water: the water in its words and pictures, and where the
water was when the slope failed (``summary.json`` ``water_at_failure``)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from app import report
from tests.unit.test_render_water import (
    DRY_PROJECT,
    WET_PROJECT,
    _blue_line_rows,
    wet_results,
)


def _with_failure(path, failure):
    summary = json.loads((path / "summary.json").read_text())
    summary["water_at_failure"] = failure
    (path / "summary.json").write_text(json.dumps(summary))


@pytest.mark.parametrize("failure, sentence", [
    ({"time_s": 0.1, "stage": 1, "phreatic_line_m": [[0.0, 0.06], [0.8, 0.06]], "free_water_line_m": None},
     "The slope failed at t = 0.1 s, in stage 2 (collapse), with the phreatic line level at y = 0.06 m."),
    ({"time_s": 0.125, "stage": "collapse", "phreatic_line_m": [[0.0, 0.08], [0.4, 0.05], [0.8, 0.04]],
      "free_water_line_m": [[0.0, 0.09], [0.8, 0.09]]},
     ("The slope failed at t = 0.125 s, in stage 2 (collapse), with the phreatic line from y = 0.08 m at x = 0 m "
      "to y = 0.04 m at x = 0.8 m (points (0, 0.08), (0.4, 0.05), (0.8, 0.04) m) and the free water level at "
      "y = 0.09 m.")),
    (None, "The slope did not fail under the water of this run."),
])
def test_the_report_says_where_the_water_was_at_the_failure(tmp_path, failure, sentence):
    from tests.gui.test_analysis import write_hazard

    path = wet_results(tmp_path / "wet.results")
    write_hazard(path)
    _with_failure(path, failure)
    html = report.write_report(path).read_text()
    assert ">Ground water<" in html
    assert "At the start the phreatic line is level at y = 0.12 m (unit weight of water 9.81 kN/m3)." in html
    assert "Stage 2 (collapse) moves the phreatic line to level at y = 0.03 m, over 0.15 s." in html
    assert sentence in html


def test_the_report_pictures_draw_the_water(tmp_path, monkeypatch):
    import imageio.v2 as imageio

    from tests.gui.test_analysis import write_hazard

    path = wet_results(tmp_path / "wet.results")
    write_hazard(path)
    _with_failure(path, {"time_s": 0.1, "stage": 1, "phreatic_line_m": [[0.0, 0.06], [0.8, 0.06]],
                         "free_water_line_m": None})
    report.write_report(path)
    for name in ("scene_before.png", "scene_after.png"):
        assert len(_blue_line_rows(imageio.imread(path / "report" / name))), name
    figures = []
    make = report._figure
    project = report.Results(path)
    from projects.document import loads_project

    lines = report.water_lines(loads_project(project.project_text), project.summary)
    assert [label for label, _p, _f in lines] == ["water at the start", "water at the failure (t = 0.1 s)",
                                                  "water at the end"]
    monkeypatch.setattr(report, "_figure", lambda *size: figures.append(make(*size)) or figures[-1])
    report.profiles_png(report.read_hazard(path), tmp_path / "profiles.png", None, lines)
    ax = figures[0].axes[0]
    drawn = {line.get_label(): line.get_ydata() for line in ax.get_lines()}
    assert np.allclose(drawn["phreatic line, water at the start"], 0.12)
    assert np.allclose(drawn["phreatic line, water at the failure (t = 0.1 s)"], 0.06)
    assert np.allclose(drawn["phreatic line, water at the end"], 0.03)
    assert any(c.get_label() == "free water" for c in ax.collections)


def test_a_dry_report_has_no_water(tmp_path):
    from tests.gui.test_analysis import write_hazard

    path = wet_results(tmp_path / "dry.results", project=DRY_PROJECT)
    write_hazard(path)
    html = report.write_report(path).read_text()
    assert "Ground water" not in html and "phreatic" not in html
    assert WET_PROJECT != DRY_PROJECT
