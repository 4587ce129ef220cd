"""A project's loads (projects/loads.py): the stages' surcharges and seismic coefficients, their
rules (one line each, naming the key, the value and what is allowed), how they carry from stage
to stage, their solver form, the file round trip and Bishop's section of a loaded project."""

import copy
import math

import numpy as np
import pytest

from projects.build import solver_config
from projects.document import dumps_project, loads_project
from projects.loads import describe, ground_height, out_of_slope, stage_loads
from projects.schema import ProjectError, validate_project
from projects.strength import limit_equilibrium, trial_loads
from solver import config as sc

SLOPE = [[0.0, 0.0], [30.0, 0.0], [30.0, 3.0], [18.0, 3.0], [10.0, 8.0], [0.0, 8.0]]  # its toe to the right
BASE = {
    "runout": {"schema_version": 2},
    "domain": {"size_m": [30.0, 12.0], "cell_size_m": 0.5},
    "materials": {"soil": {"model": "drucker-prager", "density_kg_m3": 2000.0, "youngs_modulus_pa": 20e6,
                           "poisson_ratio": 0.3, "cohesion_pa": 10e3, "friction_angle_deg": 30.0}},
    "bodies": [{"name": "slope", "material": "soil", "polygon_m": SLOPE}],
    "stages": [{"name": "initial stress", "type": "gravity", "duration_s": 2.0,
                "surcharges": [{"name": "crest", "from_m": 2.0, "to_m": 8.0, "pressure_pa": "50 kPa"}]},
               {"name": "fos", "type": "strength-reduction", "seismic": {"k_h": 0.15}}],
}


def project(mutate=None):
    data = copy.deepcopy(BASE)
    if mutate is not None:
        mutate(data)
    return validate_project(data)


def problems(mutate) -> list[str]:
    with pytest.raises(ProjectError) as err:
        project(mutate)
    return str(err.value).splitlines()


def surcharge(data, **keys):
    data["stages"][0]["surcharges"][0].update(keys)


@pytest.mark.parametrize("mutate, line", [
    (lambda d: surcharge(d, to_m=35.0), "stages.0.surcharges.0.to_m = 35.0: the segment x = 2 to 35 m runs off the "
                                        "ground at x = 30"),
    (lambda d: surcharge(d, from_m=-4.0), "stages.0.surcharges.0.from_m = -4.0: the segment x = -4 to 8 m runs off"),
    (lambda d: surcharge(d, to_m=1.0), "stages.0.surcharges.0.to_m = 1.0: must be > from_m (2)"),
    (lambda d: surcharge(d, pressure_pa=-5.0), "stages.0.surcharges.0.pressure_pa = -5.0: must be >= 0"),
    (lambda d: surcharge(d, pressure_pa=["5 kPa", "-1 kPa"]), "stages.0.surcharges.0.pressure_pa"),
    (lambda d: surcharge(d, pressure_pa=[1.0, 2.0, 3.0]), "or a pair [at from_m, at to_m]"),
    (lambda d: surcharge(d, pressure_pa="5 kN"), "stages.0.surcharges.0.pressure_pa = \"5 kN\": unknown unit"),
    (lambda d: surcharge(d, ramp=True), "stages.0.surcharges.0.ramp = true: only allowed on a dynamic stage"),
    (lambda d: surcharge(d, weight=3.0), "stages.0.surcharges.0.weight"),
    (lambda d: d["stages"][0]["surcharges"].append({"name": "crest", "from_m": 1.0, "to_m": 2.0, "pressure_pa": 1.0}),
     "stages.0.surcharges.1.name = \"crest\": is used twice in this stage"),
    (lambda d: d["stages"][1]["seismic"].update(k_h=1.0), "stages.1.seismic.k_h = 1.0: must be >= 0 and < 1"),
    (lambda d: d["stages"][1]["seismic"].update(k_h=-0.1), "stages.1.seismic.k_h = -0.1: must be >= 0 and < 1"),
    (lambda d: d["stages"][1]["seismic"].update(k_v=-1.0), "stages.1.seismic.k_v = -1.0: must be > -1 and < 1"),
    (lambda d: d["stages"][1]["seismic"].update(towards="up"), "stages.1.seismic.towards = \"up\": must be one of"),
    (lambda d: d["stages"][1].update(seismic={}), "stages.1.seismic: needs k_h or k_v"),
    (lambda d: d["stages"][0].update(seismic={"k_h": 0.1}), "stages.0.seismic: not allowed on a gravity stage"),
    (lambda d: d["bodies"][0].update(polygon_m=[[0, 0], [30, 0], [30, 8], [0, 8]]),
     "stages.1.seismic.towards = \"out-of-slope\": the ground is as high at both ends"),
    (lambda d: d["domain"].update(gravity_m_s2=[0.0, 0.0]), "stages.0.surcharges: needs a gravity"),
])
def test_bad_loads_are_one_line_problems(mutate, line):
    got = problems(mutate)
    assert any(line in text for text in got), got


def test_no_surcharges_on_a_k0_stage():
    def k0(d):
        d["stages"][0] = {"type": "k0", "surcharges": d["stages"][0]["surcharges"]}
        d["stages"][1]["trial_duration_s"] = 1.0
    assert any(text.startswith("stages.0.surcharges: not allowed on a k0 stage") for text in problems(k0))


def test_a_level_ground_takes_a_named_direction():
    p = project(lambda d: (d["bodies"][0].update(polygon_m=[[0, 0], [30, 0], [30, 8], [0, 8]]),
                           d["stages"][1]["seismic"].update(towards="left")))
    assert trial_loads(p)[1] == sc.Seismic(0.15, 0.0, -1.0)


def test_surcharges_carry_on_until_a_stage_changes_them():
    def stages(d):
        d["stages"] = [
            d["stages"][0],
            {"name": "quake", "type": "dynamic", "duration_s": 1.0, "seismic": {"k_h": 0.1, "k_v": -0.05}},
            {"name": "build", "type": "dynamic", "duration_s": 2.0,
             "surcharges": [{"name": "crest", "from_m": 2.0, "to_m": 8.0, "pressure_pa": 80e3, "ramp": True},
                            {"name": "fill", "from_m": 20.0, "to_m": 26.0, "pressure_pa": [0.0, 30e3], "ramp": True},
                            {"name": "house", "from_m": 1.0, "to_m": 3.0, "pressure_pa": 10e3}]},
            {"name": "unload", "type": "dynamic", "duration_s": 1.0, "surcharges": []},
        ]
    loads = stage_loads(project(stages))
    crest = sc.Surcharge("crest", 2.0, 8.0, 50e3)
    assert loads[0] == ((crest,), None, None)
    assert loads[1] == ((crest,), None, sc.Seismic(0.1, -0.05, 1.0))  # out of the slope: +x, to the toe
    now, start, seismic = loads[2]
    assert [s.name for s in now] == ["crest", "fill", "house"] and seismic is None
    assert now[0].pressure_pa == 80e3 and now[1].pressure_end_pa == 30e3
    # the crest grows from 50 kPa, the fill from nothing, the house is there at once
    assert start == (crest, sc.Surcharge("house", 1.0, 3.0, 10e3))
    assert loads[3] == ((), None, None)
    config = solver_config(project(stages))
    assert [st.surcharges for st in config.stages] == [load[0] for load in loads]
    assert config.stages[2].surcharges_from == start and config.has_surcharges and config.has_seismic
    rows = describe(project(stages))
    assert rows[2]["surcharges"][1] == {"name": "fill", "from_m": 20.0, "to_m": 26.0, "pressure_pa": [0.0, 30e3],
                                       "force_n_per_m": pytest.approx(90e3), "ramp": True}
    assert rows[1]["seismic"] == {"k_h": 0.1, "k_v": -0.05, "towards": "out-of-slope", "direction": "right"}


def test_an_unloaded_project_is_the_solver_configuration_it_was():
    config = solver_config(project(lambda d: (d["stages"][0].pop("surcharges"), d["stages"][1].pop("seismic"))))
    assert not config.has_surcharges and not config.has_seismic
    assert all(st.surcharges == () and st.surcharges_from is None and st.seismic is None for st in config.stages)


@pytest.mark.parametrize("polygon, gravity, expected", [
    (SLOPE, (0.0, -9.81), 1.0),
    ([[-x, y] for x, y in SLOPE[::-1]], (0.0, -9.81), -1.0),
    ([[0, 0], [30, 0], [30, 8], [0, 8]], (0.0, -9.81), None),
    ([[0, 0], [30, 0], [30, 3], [15, 8], [0, 3]], (0.0, -9.81), None),  # a mound
    # an infinite slope: a flat layer under gravity rotated by 30 degrees (down the slope: +x)
    ([[0, 0], [0.5, 0], [0.5, 1], [0, 1]], (9.81 * 0.5, -9.81 * math.sqrt(0.75)), 1.0),
    ([[0, 0], [0.5, 0], [0.5, 1], [0, 1]], (-9.81 * 0.5, -9.81 * math.sqrt(0.75)), -1.0),
])
def test_out_of_the_slope(polygon, gravity, expected):
    assert out_of_slope([np.asarray(polygon, float)], gravity) == expected


def test_the_ground_height_is_the_highest_outline_over_each_x():
    got = ground_height([np.asarray(SLOPE, float)], np.array([5.0, 14.0, 25.0, 31.0]))
    assert got[:3] == pytest.approx([8.0, 5.5, 3.0]) and np.isnan(got[3])


def test_the_loads_survive_the_file():
    def more(d):
        d["stages"][0]["surcharges"].append({"name": "fill", "from_m": 20.0, "to_m": 28.0, "pressure_pa": [0, 30e3]})
        d["stages"].append({"type": "dynamic", "duration_s": 1.0, "surcharges": [], "seismic": {"k_v": 0.1}})
    p = project(more)
    text = dumps_project(p)
    assert "[[stages.surcharges]]" in text and "seismic = {k_h = 0.15" in text and "surcharges = []" in text
    assert loads_project(text) == p


def test_bishop_stands_under_the_strength_reductions_loads(monkeypatch):
    import stability.bishop as bishop
    from stability.bishop import Circle, Section, Seismic, Soil, Surcharge, bishop_factor

    search = bishop.critical_circle
    monkeypatch.setattr(bishop, "critical_circle", lambda section: search(section, centres=9, radii=12, refinements=3))
    loaded = project()
    surcharges, seismic = trial_loads(loaded)
    result = limit_equilibrium(loaded, surcharges=surcharges, seismic=seismic)
    c = result.circle
    circle = Circle(c.centre_x_m, c.centre_y_m, c.radius_m)
    # the same as the section built by hand with these loads; less than without them
    soil = [Soil(10e3, math.radians(30.0), 2000.0 * 9.81)]
    polygon = [np.asarray(SLOPE, float)]
    by_hand = Section(polygon, soil, surcharges=[Surcharge(2.0, 8.0, 50e3)], seismic=Seismic(0.15, 0.0, 1.0))
    assert bishop_factor(by_hand, circle) == pytest.approx(result.factor, rel=1e-9)
    surcharged = bishop_factor(Section(polygon, soil, surcharges=[Surcharge(2.0, 8.0, 50e3)]), circle)
    plain = bishop_factor(Section(polygon, soil), circle)
    assert result.factor < surcharged < plain


def test_a_surcharge_under_rotated_gravity_keeps_its_resultant_in_bishops_frame():
    from projects.strength import _section_loads

    b = math.radians(30.0)
    gravity = (9.81 * math.sin(b), -9.81 * math.cos(b))
    p = project(lambda d: (d["domain"].update(gravity_m_s2=list(gravity)),
                           d["stages"][1]["seismic"].update(towards="left")))
    surcharges, seismic = trial_loads(p)
    loads, quake = _section_loads(p, np.asarray(gravity), surcharges, seismic)
    (q,) = loads
    assert 0.5 * (q.pressure_from_pa + q.pressure_to_pa) * (q.x_to_m - q.x_from_m) == pytest.approx(50e3 * 6.0)
    assert q.x_to_m - q.x_from_m == pytest.approx(6.0 * math.cos(b))  # the flat crest, turned
    assert quake.direction == -1.0
