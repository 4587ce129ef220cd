"""Context from experience in the hazard report: the published relations as coded, and when they apply."""

import math

import pytest

from app.report import COROMINAS_1996, _column_geometry, context, corominas_h_over_l, lube_height, lube_runout
from projects.document import loads_project

COLUMN = """
[runout]
schema_version = 1
[domain]
origin_m = [0.0, 0.0]
size_m = [0.6, 0.3]
cell_size_m = 0.02
[materials.sand]
model = "drucker-prager"
density_kg_m3 = 2000.0
youngs_modulus_pa = 1.0e6
poisson_ratio = 0.3
cohesion_pa = 0.0
friction_angle_deg = 30.0
[[bodies]]
name = "column"
material = "sand"
polygon_m = {polygon}
[[stages]]
type = "dynamic"
duration_s = 0.05
"""
DOMAIN = {"origin_m": [0.0, 0.0], "size_m": [0.6, 0.3]}


@pytest.mark.parametrize("a", [0.5, 1.0, 2.0, 2.29])
def test_lube_short_columns_run_out_linearly(a):
    # Lube et al. (2005), planar: (L_inf - L0)/L0 = 1.2 a below a = 2.3
    assert lube_runout(a) == pytest.approx(1.2 * a)


@pytest.mark.parametrize("a", [2.31, 5.0, 10.0])
def test_lube_tall_columns_run_out_as_a_power(a):
    assert lube_runout(a) == pytest.approx(1.9 * a ** (2 / 3))


@pytest.mark.parametrize(("a", "expected"), [(0.5, 0.5), (1.1, 1.1), (2.0, 2.0 ** 0.4), (8.0, 8.0 ** 0.4)])
def test_lube_final_height(a, expected):
    assert lube_height(a) == pytest.approx(expected)


@pytest.mark.parametrize("volume", [1e2, 1e4, 1e6, 1e9])
def test_corominas_regression(volume):
    # log10(H/L) = 0.047 - 0.085 log10(V)
    assert math.log10(corominas_h_over_l(volume)) == pytest.approx(0.047 - 0.085 * math.log10(volume))
    assert COROMINAS_1996["volume_range_m3"][0] <= volume <= COROMINAS_1996["volume_range_m3"][1]


@pytest.mark.parametrize(("polygon", "column"), [
    ("[[0.0, 0.0], [0.12, 0.0], [0.12, 0.24], [0.0, 0.24]]", (0.12, 0.24)),   # against the left wall
    ("[[0.5, 0.0], [0.6, 0.0], [0.6, 0.05], [0.5, 0.05]]", (0.1, 0.05)),       # against the right wall
    ("[[0.1, 0.0], [0.2, 0.0], [0.2, 0.1], [0.1, 0.1]]", None),                # free-standing
    ("[[0.0, 0.02], [0.1, 0.02], [0.1, 0.1], [0.0, 0.1]]", None),              # not on the floor
    ("[[0.0, 0.0], [0.3, 0.0], [0.0, 0.2]]", None),                            # a slope, not a column
])
def test_column_collapse_is_recognised(polygon, column):
    project = loads_project(COLUMN.format(polygon=polygon))
    geometry = _column_geometry(project, DOMAIN)
    if column is None:
        assert geometry is None
    else:
        assert geometry == pytest.approx({"L0": column[0], "H0": column[1]})


def test_context_states_sources_and_assumptions():
    project = loads_project(COLUMN.format(polygon="[[0.0, 0.0], [0.12, 0.0], [0.12, 0.24], [0.0, 0.24]]"))
    doc = {"runout_distance_m": 0.27, "mobilised_area_m2_per_m": 0.02, "h_over_l": 0.6, "travel_angle_deg": 31.0,
           "source_top_m": [0.0, 0.24], "source_front_x_m": 0.12, "profile": {}}
    items = context(doc, project, {"domain": DOMAIN})
    names = [i["name"] for i in items]
    assert names == ["Planar granular column collapse", "Volume and travel angle of landslides"]
    lube, coro = items
    assert lube["applies"] and "Lube" in lube["source"] and "wall" in lube["assumption"]
    assert lube["points"]["a"] == pytest.approx(2.0) and lube["points"]["runout"] == pytest.approx(0.27 / 0.12)
    # a laboratory volume is far below the regression's data: stated as not applicable
    assert not coro["applies"] and "width" in coro["assumption"] and "outside" in coro["note"]
    assert [label for label, _ in coro["points"]] == ["W = 1 m", "W = 0.12 m"]
