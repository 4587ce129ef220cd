"""The hazard report lists a run's loads: each stage's surcharges (where, pressure, resultant, how
they are applied) and its seismic coefficients; a run without loads has no such section."""

from __future__ import annotations

from app import report
from tests.unit.test_render_water import DRY_PROJECT, wet_results

LOADED_PROJECT = DRY_PROJECT.replace('''[[stages]]
name = "initial stress"
type = "k0"
''', '''[[stages]]
name = "initial stress"
type = "gravity"
duration_s = 0.05

[[stages.surcharges]]
name = "crest"
from_m = 0.02
to_m = 0.12
pressure_pa = "5 kPa"
''').replace('''duration_s = 0.15
''', '''duration_s = 0.15
seismic = {k_h = 0.1, k_v = -0.05, towards = "right"}

[[stages.surcharges]]
name = "crest"
from_m = 0.02
to_m = 0.12
pressure_pa = [5000.0, 8000.0]
ramp = true
''')


def test_the_report_lists_the_loads_of_each_stage(tmp_path):
    from tests.gui.test_analysis import write_hazard

    assert "[[stages.surcharges]]" in LOADED_PROJECT and "seismic" in LOADED_PROJECT
    path = wet_results(tmp_path / "loaded.results", project=LOADED_PROJECT)
    write_hazard(path)
    html = report.write_report(path).read_text()
    assert ">Loads<" in html
    assert ("<td>1. initial stress</td><td>surcharge crest</td><td>x = 0.02 to 0.12 m</td><td>5 kPa</td>"
            "<td>0.5 kN/m</td><td>ramped up with gravity</td>") in html
    assert ("<td>2. collapse</td><td>surcharge crest</td><td>x = 0.02 to 0.12 m</td><td>5 to 8 kPa</td>"
            "<td>0.65 kN/m</td><td>grows over the stage from the load in force before</td>") in html
    assert "<td>2. collapse</td><td>seismic</td><td>k_h 0.1 towards right</td><td>k_v -0.05</td>" in html


def test_a_run_without_loads_has_no_loads_section(tmp_path):
    from tests.gui.test_analysis import write_hazard

    path = wet_results(tmp_path / "dry.results", project=DRY_PROJECT)
    write_hazard(path)
    assert ">Loads<" not in report.write_report(path).read_text()
