"""Models on their supports: the fitted domain puts the ground on the base and the section's ends on
the side walls at any cell size (geometry.templates.fit_domain); a body that floats above the
closed side gravity pulls it onto, or stands off a closed side by less than a cell, is a warning
with the remedy (projects.checks); an imported section is placed on its supports, under gravity
loading where the ground slopes, at a cell size the estimate can afford, one body per layer
(geometry.importers.read_layers, projects.sections.place_section)."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from geometry.importers import read_layers
from geometry.polygons import is_simple, polygon_area
from geometry.templates import SlopeLayer, fit_domain, slope_profile
from projects.build import estimate
from projects.checks import project_warnings, unsupported_bodies
from projects.schema import validate_project
from projects.sections import SECTION_MAX_PARTICLES, SECTION_RUN_S, place_section, round_cell

#: the slope template's default slope: 10 m high at 45 degrees, crest 10 m, toe 20 m, 2 m foundation
SLOPE = dict(height_m=10.0, angle_deg=45.0, crest_length_m=10.0, toe_length_m=20.0, foundation_depth_m=2.0)


def _project(bodies, origin, size, cell, first="gravity", structures=(), gravity=(0.0, -9.81)):
    stage = ({"name": "initial stress", "type": "gravity", "duration_s": 2.0} if first == "gravity"
             else {"name": "fall", "type": "dynamic", "duration_s": 1.0})
    return validate_project({
        "runout": {"schema_version": 2, "title": "supports"},
        "domain": {"origin_m": list(origin), "size_m": list(size), "cell_size_m": cell, "gravity_m_s2": list(gravity),
                   "boundaries": {"left": "slip", "right": "slip", "bottom": "fixed", "top": "open"}},
        "materials": {"soil": {"model": "drucker-prager", "density_kg_m3": 2000.0, "youngs_modulus_pa": 1e7,
                               "poisson_ratio": 0.3, "cohesion_pa": 5e3, "friction_angle_deg": 30.0,
                               "dilatancy_angle_deg": 0.0}},
        "bodies": [{"name": n, "material": "soil", "polygon_m": np.asarray(p, float).tolist()} for n, p in bodies],
        "structures": [{"name": n, "polygon_m": p} for n, p in structures],
        "stages": [stage, {"name": "run-out", "type": "dynamic", "duration_s": 1.0}] if first == "gravity" else [stage],
    })


def _walls(origin, size, cell):
    """The grid's sides as the solver has them: whole cells from the origin."""
    nx, ny = (math.ceil(s / cell - 1e-9) for s in size)
    return origin[0], origin[1], origin[0] + nx * cell, origin[1] + ny * cell


# -- the fitted domain -------------------------------------------------------------------------------

@pytest.mark.parametrize("cell", [0.1, 0.25, 0.37, 0.5])
@pytest.mark.parametrize("layered", [False, True], ids=["one body", "layers"])
def test_the_fitted_domain_puts_the_ground_on_the_base_and_the_ends_on_the_walls(cell, layered):
    layers = (SlopeLayer("weak", 3.0), SlopeLayer("middle", 4.0)) if layered else ()
    bodies = slope_profile(**SLOPE, layers=layers, origin_m=(3.0, -7.0))
    fit = fit_domain([p for _, p in bodies], cell)
    x0, y0, x1, y1 = _walls(fit.origin_m, fit.size_m, cell)
    points = np.concatenate(fit.polygons)
    tol = 1e-9 * cell
    assert abs(points[:, 1].min() - y0) < tol  # on the base
    assert abs(points[:, 0].min() - x0) < tol and abs(points[:, 0].max() - x1) < tol  # both ends on the walls
    assert y1 - points[:, 1].max() >= 2 * cell - tol and y1 - points[:, 1].max() >= 0.25 * 12.0 - cell
    # the right end moved onto the wall by less than half a cell; the area changes by that strip of the
    # 2 m of foundation at the toe end, nothing else moved
    assert abs(fit.end_shift_m) <= 0.5 * cell + tol
    before, after = sum(polygon_area(p) for _, p in bodies), sum(polygon_area(p) for p in fit.polygons)
    assert after - before == pytest.approx(fit.end_shift_m * 2.0, abs=1e-9)
    assert all(is_simple(p) for p in fit.polygons)
    project = _project(zip([n for n, _ in bodies], fit.polygons), fit.origin_m, fit.size_m, cell)
    assert unsupported_bodies(project) == []
    assert [w for w in project_warnings(project) if "wall" in w] == []


def test_room_for_a_run_out_moves_nothing():
    bodies = [p for _, p in slope_profile(**SLOPE)]
    fit = fit_domain(bodies, 0.37, runout_length_m=5.0)
    assert fit.end_shift_m == 0.0 and all(np.array_equal(a, b) for a, b in zip(fit.polygons, bodies))
    assert fit.size_m[0] >= 45.0 and fit.size_m[0] / 0.37 == pytest.approx(round(fit.size_m[0] / 0.37))


# -- floating and standing off -----------------------------------------------------------------------

BLOCK = [[0.0, 0.0], [4.0, 0.0], [4.0, 2.0], [0.0, 2.0]]


def _lifted(dy, dx=0.0):
    return [[x + dx, y + dy] for x, y in BLOCK]


@pytest.mark.parametrize("gap_cells", [0.4, 1.0, 3.0])
def test_a_body_floating_above_the_base_under_an_initial_stress_stage_is_a_warning(gap_cells):
    cell = 0.25
    gap = gap_cells * cell
    project = _project([("block", _lifted(gap))], (0.0, 0.0), (10.0, 5.0), cell)
    assert unsupported_bodies(project) == [0]
    [warning] = [w for w in project_warnings(project) if "wall" in w]
    assert warning.startswith(f"bodies.0 ('block') is {gap:.3g} m from the bottom wall (fixed) without touching it and "
                              "rests on no structure or other body: stages.0 (initial stress, gravity) takes it as standing "
                              "on its support, so it falls onto the wall")
    assert f"move it onto the wall (y = 0 m) or the wall to it (domain.origin_m = [0, {gap:g}]" in warning
    # a first dynamic stage may drop a body on purpose: only a gap of less than a cell is a trap there
    dropped = project_warnings(_project([("block", _lifted(gap))], (0.0, 0.0), (10.0, 5.0), cell, first="dynamic"))
    assert bool([w for w in dropped if "bottom wall" in w]) == (gap_cells < 1.0)


def test_a_body_resting_on_a_supported_body_or_a_structure_does_not_float():
    cell = 0.25
    upper = [[1.0, 2.0], [3.0, 2.0], [3.0, 3.0], [1.0, 3.0]]
    on_body = _project([("ground", BLOCK), ("heap", upper)], (0.0, 0.0), (10.0, 5.0), cell)
    assert unsupported_bodies(on_body) == [] and not [w for w in project_warnings(on_body) if "wall" in w]
    # the same pair lifted: both float, each warned about once
    lifted = _project([("ground", _lifted(1.0)), ("heap", [[x, y + 1.0] for x, y in upper])], (0.0, 0.0),
                      (10.0, 5.0), cell)
    assert unsupported_bodies(lifted) == [0, 1]
    # ... the lower one warned about (the heap rests on it and falls with it)
    [warning] = [w for w in project_warnings(lifted) if "rests on no structure" in w]
    assert warning.startswith("bodies.0 ('ground') is 1 m from the bottom wall")
    # a block on a ledge (a structure) one metre above the base
    ledge = [[0.0, 0.0], [5.0, 0.0], [5.0, 1.0], [0.0, 1.0]]
    on_ledge = _project([("block", _lifted(1.0))], (0.0, 0.0), (10.0, 5.0), cell, structures=[("ledge", ledge)])
    assert unsupported_bodies(on_ledge) == []


def test_a_body_standing_off_a_side_wall_by_less_than_a_cell_is_a_warning():
    cell = 0.25
    off = _project([("block", _lifted(0.0, 0.1))], (0.0, 0.0), (10.0, 5.0), cell)
    [warning] = project_warnings(off)
    assert warning.startswith("bodies.0 ('block') is 0.1 m from the left wall (slip) without touching it, less than a "
                              "cell (0.25 m)") and "move it to touch the wall (x = 0 m)" in warning
    assert project_warnings(_project([("block", _lifted(0.0, 1.0))], (0.0, 0.0), (10.0, 5.0), cell)) == []


def test_under_tilted_gravity_the_side_it_pulls_onto_is_the_base():
    # gravity along -x mostly: the left wall carries the block; a gap there floats it
    project = _project([("block", _lifted(0.0, 1.0))], (0.0, 0.0), (10.0, 5.0), 0.25, gravity=(-9.0, -1.0))
    assert unsupported_bodies(project) == [0]
    assert [w.split(" wall")[0].rsplit(" ", 1)[1] for w in project_warnings(project) if "rests on no" in w] == ["left"]


# -- imported sections -------------------------------------------------------------------------------

def _new_project() -> dict:
    return {
        "runout": {"schema_version": 2, "title": "import"},
        "domain": {"origin_m": [0.0, 0.0], "size_m": [20.0, 10.0], "cell_size_m": 0.25, "gravity_m_s2": [0.0, -9.81],
                   "boundaries": {"left": "slip", "right": "slip", "bottom": "fixed", "top": "open"}},
        "materials": {"soil": {"model": "drucker-prager", "density_kg_m3": 2000.0, "youngs_modulus_pa": 1e7,
                               "poisson_ratio": 0.3, "cohesion_pa": 5e3, "friction_angle_deg": 30.0,
                               "dilatancy_angle_deg": 0.0}},
        "bodies": [],
        "stages": [{"name": "initial stress", "type": "k0"},
                   {"name": "run-out", "type": "dynamic", "duration_s": 20.0, "stop_when_kinetic_energy_below": 0.01,
                    "stop_when_max_speed_below_m_s": 0.1, "min_duration_s": 1.0}],
        "output": {"interval_s": 0.05},
    }


#: a 130 m survey section 30 m high: at the old 0.25 m cells about 45,000 particles
SURVEY = "x_m,y_m\n0,30\n40,30\n80,6\n130,6\n"


@pytest.mark.parametrize("rate", [3.0e6, 2.0e7])
def test_an_imported_section_stands_on_its_supports_under_gravity_at_an_affordable_cell_size(tmp_path, rate):
    path = tmp_path / "survey.csv"
    path.write_text(SURVEY)
    data = _new_project()
    notes = place_section(data, read_layers(path, base_y_m=-5.0), "soil", particle_steps_per_s=rate)
    project = validate_project(data)
    cell = project.domain.cell_size_m
    x0, y0, x1, _ = _walls(project.domain.origin_m, project.domain.size_m, cell)
    poly = np.asarray(project.bodies[0].polygon_m)
    assert (poly[:, 0].min(), poly[:, 1].min()) == (x0, y0) == (0.0, -5.0)
    assert abs(poly[:, 0].max() - x1) < 1e-9 * cell  # the cut end against the right roller
    assert project.stages[0].type == "gravity"  # sloping ground: no K0
    assert project_warnings(project) == []
    # the cell size: round, and the estimate of its run about the budget of computing at the throughput
    assert cell == round_cell(cell)
    e = estimate(project)
    minutes = e["particles"] * e["steps"] / rate / 60.0
    assert minutes < SECTION_RUN_S / 60.0 * 2.0, (cell, minutes)  # within one rounding step of the budget
    assert e["particles"] <= SECTION_MAX_PARTICLES
    # the budget or the particle cap decides: a cell one round step finer would exceed it
    assert minutes > SECTION_RUN_S / 60.0 / 2.0 or e["particles"] > SECTION_MAX_PARTICLES / 1.8, (cell, minutes)
    assert any(n.startswith("cell size 0.25 -> ") for n in notes) == (cell != 0.25)
    assert any("gravity loading" in n for n in notes)


def test_a_big_section_is_held_to_the_particle_cap(tmp_path):
    path = tmp_path / "big.csv"
    path.write_text(SURVEY)
    data = _new_project()
    place_section(data, read_layers(path, base_y_m=-5.0), "soil", particle_steps_per_s=1e12)  # a machine of no limit
    assert estimate(validate_project(data))["particles"] <= SECTION_MAX_PARTICLES * 1.2  # one rounding step
    data = _new_project()
    place_section(data, read_layers(path, base_y_m=-5.0), "soil", particle_steps_per_s=None)
    assert data["domain"]["cell_size_m"] == 0.25  # no throughput: the cell size stays


LAYERS = ("x_m,y_m,layer\n"
          "0,20,sand\n30,20,sand\n60,5,sand\n100,5,sand\n"
          "0,12,clay\n40,10,clay\n100,2,clay\n"
          "0,4,rock\n100,-2,rock\n")


def _check_layers(bodies, base):
    names = [b.name for b in bodies]
    # the clay's top rises above the ground beyond x = 53 m: the sand pinches out there and its toe
    # part, cut off, is a body of its own of the same layer
    assert names == ["sand", "sand-2", "clay", "rock"] and [b.layer for b in bodies] == ["sand", "sand", "clay", "rock"]
    assert all(is_simple(b.polygon_m) for b in bodies)
    # the bands partition the section: the ground surface closed down to the base
    section = 30 * (20 - base) + 0.5 * (20 + 5 - 2 * base) * 30 + 40 * (5 - base)
    assert sum(polygon_area(b.polygon_m) for b in bodies) == pytest.approx(section)
    rock = next(b.polygon_m for b in bodies if b.name == "rock")
    assert polygon_area(rock) == pytest.approx(100 * (1.0 - base))  # under the straight line from 4 to -2
    assert rock[:, 1].min() == pytest.approx(base)


def test_a_csv_of_layers_gives_a_body_and_a_material_per_layer(tmp_path):
    path = tmp_path / "section.csv"
    path.write_text(LAYERS)
    bodies = read_layers(path, base_y_m=-10.0)
    _check_layers(bodies, -10.0)
    data = _new_project()
    data["materials"]["rock"] = {**copy.deepcopy(data["materials"]["soil"]), "cohesion_pa": 1e6}
    notes = place_section(data, bodies, "soil", particle_steps_per_s=3e6)
    project = validate_project(data)
    assert [(b.name, b.material) for b in project.bodies] == [("sand", "sand"), ("sand-2", "sand"), ("clay", "clay"),
                                                             ("rock", "rock")]
    assert project.materials["rock"].cohesion_pa == 1e6  # a material of the layer's name is the layer's
    assert project.materials["clay"] == project.materials["soil"]  # the others start as copies of the chosen one
    assert "new materials sand, clay, copies of soil: give each its own values" in notes
    assert project_warnings(project) == []


def test_a_dxf_with_layers_gives_the_same_bodies(tmp_path):
    import ezdxf

    drawing = ezdxf.new()
    msp = drawing.modelspace()
    for layer, points in (("sand", [(0, 20), (30, 20), (60, 5), (100, 5)]), ("clay", [(0, 12), (40, 10), (100, 2)]),
                          ("rock", [(100, -2), (0, 4)])):
        drawing.layers.add(layer)
        msp.add_lwpolyline(points, dxfattribs={"layer": layer})
    drawing.layers.add("notes")
    msp.add_line((10, 25), (20, 25), dxfattribs={"layer": "notes"})  # an annotation: no ground
    path = tmp_path / "section.dxf"
    drawing.saveas(path)
    _check_layers(read_layers(path, base_y_m=-10.0), -10.0)


def test_closed_layers_are_bodies_as_drawn_and_mixed_layers_are_refused(tmp_path):
    path = tmp_path / "blocks.csv"
    path.write_text("x_m,y_m,layer\n0,0,a\n2,0,a\n2,1,a\n0,1,a\n0,0,a\n2,0,b\n4,0,b\n4,1,b\n2,1,b\n2,0,b\n")
    assert [(b.name, polygon_area(b.polygon_m)) for b in read_layers(path)] == [("a", 2.0), ("b", 2.0)]
    path.write_text("x_m,y_m,layer\n0,0,a\n2,0,a\n2,1,a\n0,1,a\n0,0,a\n0,3,b\n4,3,b\n")
    with pytest.raises(ValueError, match=r"layers 'a' are closed outlines and the others open profiles"):
        read_layers(path)
    path.write_text("x_m,y_m,layer\n0,0,a\n1,1\n")
    with pytest.raises(ValueError, match=r"line 3: expected 3 values \(x, y, layer\), got 2"):
        read_layers(path)
