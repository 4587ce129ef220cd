"""``[[structures]]``: validation, round trip through TOML, conversion for the solver, seeding
around them; ``contacts.csv`` and the contact peaks of ``summary.json``."""

from __future__ import annotations

import copy
import json
import math

import numpy as np
import pytest

from projects.build import resolve
from projects.document import dumps_project, loads_project
from projects.schema import validate_project
from solver.config import ContactForce, Diagnostics, Frame
from tests.unit.test_project_schema import BASE, problems_of

WALL = {"name": "wall", "polygon_m": [[0.5, 0.0], [0.55, 0.0], [0.55, 0.1], [0.5, 0.1]],
        "contact": {"type": "friction", "friction_angle_deg": 20.0}}


def with_structures(*structures) -> dict:
    data = copy.deepcopy(BASE)
    data["structures"] = [copy.deepcopy(s) for s in structures]
    return data


def test_structures_are_optional_and_round_trip_through_toml():
    assert validate_project(BASE).structures == []
    ramp = {"name": "ramp", "polygon_m": [[0.6, 0.0], [0.8, 0.0], [0.8, 0.05]], "contact": "fixed"}
    project = validate_project(with_structures(WALL, ramp))
    assert [s.name for s in project.structures] == ["wall", "ramp"]
    assert project.structures[1].contact.type == "fixed"
    assert validate_project({**with_structures(WALL), "structures": [{"name": "w", "polygon_m": WALL["polygon_m"]}]}
                            ).structures[0].contact.type == "slip"  # the default
    text = dumps_project(project)
    assert "[[structures]]" in text
    assert loads_project(text) == project
    assert "structures" not in validate_project(BASE).to_dict()


@pytest.mark.parametrize("structure, expected", [
    ({**WALL, "contact": "open"}, 'structures.0.contact = "open": must be "fixed", "slip" or a table'),
    ({**WALL, "contact": 3}, 'structures.0.contact = 3: must be "fixed", "slip" or a table {type = "friction"'),
    ({**WALL, "contact": ["slip"]}, 'structures.0.contact = ["slip"]: must be "fixed", "slip" or a table'),
    ({**WALL, "contact": {"type": "friction"}}, 'structures.0.contact.friction_angle_deg: required for type "friction"'),
    ({**WALL, "contact": {"type": "slip", "friction_angle_deg": 10.0}},
     'structures.0.contact.friction_angle_deg = 10.0: only allowed with type "friction"'),
    ({**WALL, "name": "bottom"}, 'structures.0.name = "bottom": is a side\'s name'),
    ({**WALL, "polygon_m": [[0.5, 0.0], [0.9, 0.0], [0.9, 0.1]]}, "structures.0.polygon_m.1 = [0.9, 0.0]: outside the domain"),
    ({**WALL, "polygon_m": [[0.5, 0.0], [0.55, 0.1], [0.55, 0.0], [0.5, 0.1]]}, "structures.0.polygon_m = "),
])
def test_bad_structures_are_one_line_problems_naming_the_key(structure, expected):
    problems = problems_of(with_structures(structure))
    assert any(p.startswith(expected) for p in problems), problems


def test_structure_names_are_unique():
    problems = problems_of(with_structures(WALL, WALL))
    assert any(p.startswith('structures.1.name = "wall": duplicate') for p in problems), problems


def test_build_converts_structures_and_seeds_no_particle_inside_one():
    # the body (0..0.2 m) is drawn across a structure covering x in 0.1..0.15
    cut = {**WALL, "polygon_m": [[0.1, 0.0], [0.15, 0.0], [0.15, 0.1], [0.1, 0.1]]}
    data = with_structures(cut)
    data["domain"]["cell_size_m"] = 0.01
    built = resolve(validate_project(data))
    (structure,) = built.config.structures
    assert structure.name == "wall" and structure.contact.kind == "friction"
    assert structure.contact.friction_angle_rad == pytest.approx(math.radians(20.0))
    x = built.particles.positions_m[:, 0]
    assert len(x) > 0 and not np.any((x > 0.1) & (x < 0.15))
    assert np.any(x > 0.15)


def test_contacts_csv_rows_and_peaks_in_the_summary(tmp_path):
    from projects.results import CONTACT_COLUMNS, ResultsWriter, read_contacts

    writer = ResultsWriter(tmp_path / "r", "", {"particles": 1})
    pos = np.zeros((1, 2), np.float32)
    for i, (fx, peak) in enumerate([(0.0, 0.0), (10.0, 40.0), (5.0, 12.0)]):
        diag = Diagnostics(0.1 * i, "s", 0, 0.1 * i, i, 1e-3, 0, 0, 0, 0, 0, 0, 1.0, 0)
        contacts = (ContactForce("bottom", fx, -2 * fx, 2 * fx, fx, peak, peak / 2, -peak),
                    ContactForce("wall", -fx, 0.0, None, None, peak / 4, -peak / 4, 0.0))
        writer.write_frame(Frame(diag, {"positions": pos, "active": np.ones(1, bool)}, contacts))
    summary = writer.close("completed")
    header = (tmp_path / "r" / "contacts.csv").read_text().splitlines()[0]
    assert tuple(header.split(",")) == CONTACT_COLUMNS
    # no "-0.0" for a contact that carries nothing (the first row's -2 * 0.0)
    assert ",-0.0," not in (tmp_path / "r" / "contacts.csv").read_text()
    table = read_contacts(tmp_path / "r")
    np.testing.assert_allclose(table["bottom"]["time_s"], [0.0, 0.1, 0.2])
    np.testing.assert_allclose(table["bottom"]["force_y_N_per_m"], [0.0, -20.0, -10.0])
    assert np.isnan(table["wall"]["force_normal_N_per_m"]).all()
    peaks = json.loads((tmp_path / "r" / "summary.json").read_text())["contacts"]
    assert peaks == summary["contacts"]
    assert peaks["bottom"]["peak_force_N_per_m"] == 40.0 and peaks["bottom"]["peak_time_s"] == pytest.approx(0.1)
    assert peaks["wall"]["max_mean_force_N_per_m"] == 10.0


def _warnings(structure, scheme="apic-affine"):
    from projects.checks import project_warnings

    data = with_structures(structure)
    data["numerics"] = {**data.get("numerics", {}), "scheme": scheme}
    return [w for w in project_warnings(validate_project(data)) if w.startswith("structures.")]


# thinner than a cell (the thrust on a wall half a cell thick up to 3.7 times); from one cell on the
# thrust is within 4.3 % (tests/integration/test_project_thrust.py, THIN_WALLS)
@pytest.mark.parametrize("thickness_cells, warned", [(0.5, True), (0.8, True), (0.98, True), (1.2, False), (1.8, False),
                                                     (3.2, False), (6.0, False)])
def test_a_structure_thinner_than_a_cell_is_warned_about(thickness_cells, warned):
    dx = BASE["domain"]["cell_size_m"]  # 2 mm
    t = thickness_cells * dx
    # ~17 deg from vertical: thickness across it t cos(17 deg); the same limit in cells across
    t /= math.cos(math.atan(0.3))
    leaning = {**WALL, "polygon_m": [[0.5, 0.0], [0.5 + t, 0.0], [0.53 + t, 0.1], [0.53, 0.1]]}
    lines = _warnings(leaning)
    assert bool(lines) == warned, lines
    if warned:
        assert len(lines) == 1 and lines[0].startswith("structures.0 ('wall') is ") and "at its thickest" in lines[0]
        assert "\n" not in lines[0]
        from projects.checks import structure_thickness_m
        assert structure_thickness_m(leaning["polygon_m"]) == pytest.approx(thickness_cells * dx, rel=1e-3)


@pytest.mark.parametrize("polygon_cells", [
    [[250, 0], [251, 0], [251, 50], [250, 50]],  # a wall exactly 1 cell thick, 50 high
    [[50, 0], [350, 0], [350, 1], [50, 1]],  # a slab exactly 1 cell thick, 300 long
    [[0, 0], [400, 0], [400, 1], [0, 1]],  # the whole domain's width
    [[250, 0], [252, 0], [252, 50], [250, 50]],  # 2 cells
    [[250, 0], [265, 0], [265, 60], [250, 60]]])  # 15 cells thick: its thickness to 1e-6
def test_a_structure_exactly_a_cell_thick_is_not_warned_about(polygon_cells):
    from projects.checks import structure_thickness_m

    dx = BASE["domain"]["cell_size_m"]
    polygon = [[i * dx, j * dx] for i, j in polygon_cells]
    assert _warnings({**WALL, "polygon_m": polygon}) == []
    xs, ys = zip(*polygon_cells)
    thick = min(max(xs) - min(xs), max(ys) - min(ys)) * dx
    assert structure_thickness_m(polygon) == pytest.approx(thick, rel=1e-6)


@pytest.mark.parametrize("lean_deg", [25.0, 45.0])
def test_an_inclined_wall_a_cell_thick_with_rounded_coordinates_is_not_warned_about(lean_deg):
    """A leaning wall one cell thick, its corners written to 0.1 micrometre (a 2 mm cell; 0.99997
    cells thick): within the drawing's precision of the minimum, not thinner than it (an
    independent tester's 2 cm wall at 25 deg, corners to a micrometre, was warned about)."""
    from projects.checks import structure_thickness_m

    dx = BASE["domain"]["cell_size_m"]
    t = dx / math.cos(math.radians(lean_deg))
    s = 0.1 * math.tan(math.radians(lean_deg))
    polygon = [[round(x, 7), round(y, 7)] for x, y in [(0.5, 0.0), (0.5 + t, 0.0), (0.5 + t + s, 0.1), (0.5 + s, 0.1)]]
    assert structure_thickness_m(polygon) == pytest.approx(dx, rel=1e-4)
    assert _warnings({**WALL, "polygon_m": polygon}) == []


@pytest.mark.parametrize("offset_cells, scheme, warned", [
    (0.0, "mpm", False), (0.25, "apic", False), (0.5, "mpm", False), (0.6, "apic-affine", True), (0.7, "mpm", True),
    (0.8, "apic", True), (0.9, "apic-affine", False)])
def test_a_face_a_body_touches_far_from_the_node_lines_is_warned_about(offset_cells, scheme, warned):
    """The wall's left face touches the block (which ends at x = 0.2 m, on a node line) from
    ``offset_cells`` off the node line on the block's side; its right face, at the same offset,
    touches nothing and is never warned about."""
    dx = BASE["domain"]["cell_size_m"]
    x = 0.2 + offset_cells * dx
    wall = {**WALL, "polygon_m": [[x, 0.0], [x + 10 * dx, 0.0], [x + 10 * dx, 0.1], [x, 0.1]]}
    lines = _warnings(wall, scheme)
    assert bool(lines) == warned, lines
    if warned:
        assert len(lines) == 1 and lines[0].startswith(f"structures.0 ('wall') has a face at x = {x:g} m")
        assert f"{offset_cells:.2f} cells from the last node line on the material's side" in lines[0]


def test_a_resumed_folder_takes_its_contact_peaks_from_the_rows_it_keeps(tmp_path):
    """A resume writes over the frames after its checkpoint (and a stop's frame): the run's peaks in
    summary.json must come from the contacts.csv rows kept, not from the earlier summary, which
    also counted the rows written over."""
    from projects.results import ResultsWriter

    out = tmp_path / "r"
    meta = {"particles": 1, "domain": {"origin_m": [0.0, 0.0], "size_m": [1.0, 1.0]}}
    writer = ResultsWriter(out, "", meta)
    pos = np.zeros((1, 2), np.float32)

    def frame(i, fx, peak):
        diag = Diagnostics(0.1 * i, "s", 0, 0.1 * i, i, 1e-3, 0, 0, 0, 0, 0, 0, 1.0, 0)
        # the force (fx, -2 fx) acting at x = 0.3 on the bottom: moment x Fy - y Fx = -0.6 fx
        contacts = (ContactForce("bottom", fx, -2 * fx, 2 * fx, fx, peak, peak / 2, -peak, -0.6 * fx),)
        return Frame(diag, {"positions": pos, "active": np.ones(1, bool)}, contacts)

    for i, (fx, peak) in enumerate([(0.0, 0.0), (5.0, 12.0), (10.0, 40.0)]):
        writer.write_frame(frame(i, fx, peak))
    assert writer.close("stopped")["contacts"]["bottom"]["peak_force_N_per_m"] == 40.0
    resumed = ResultsWriter(out, "", meta, keep_frames=2)
    assert resumed.summary["contacts"]["bottom"]["peak_force_N_per_m"] == 12.0
    assert resumed.summary["contacts"]["bottom"]["max_mean_force_N_per_m"] == pytest.approx(math.hypot(5.0, 10.0))
    # the centre of pressure from the kept row's moment
    assert resumed.summary["contacts"]["bottom"]["max_mean_force_point_m"] == pytest.approx([0.3, 0.0])
    resumed.write_frame(frame(2, 8.0, 30.0))
    peaks = resumed.close("completed")["contacts"]["bottom"]
    assert peaks["peak_force_N_per_m"] == 30.0 and peaks["peak_time_s"] == pytest.approx(0.2)
    assert json.loads((out / "summary.json").read_text())["contacts"]["bottom"] == peaks


@pytest.mark.parametrize("gap_cells, warned", [(0.0, False), (0.01, False), (0.3, True), (0.9, True), (1.5, False),
                                               (-2.0, False)])
@pytest.mark.parametrize("where", ["beside", "above"])
def test_a_body_within_a_cell_of_a_structure_is_warned_about_as_near_a_wall(gap_cells, warned, where):
    """As for a closed side: a body less than a cell from a structure without touching it drops or
    slides onto it at the start (structures act like walls). Overlapping (the structure
    takes its part) or touching is fine, to 2 % of a cell (a body laid on an inclined structure with
    rounded coordinates)."""
    from projects.checks import project_warnings

    dx = BASE["domain"]["cell_size_m"]
    g = gap_cells * dx  # the block is [0, 0.2] x [0, 0.1]
    polygon = ([[0.2 + g, 0.0], [0.26 + g, 0.0], [0.26 + g, 0.1], [0.2 + g, 0.1]] if where == "beside"
               else [[0.0, 0.1 + g], [0.3, 0.1 + g], [0.3, 0.14], [0.0, 0.14]])
    lines = [w for w in project_warnings(validate_project(with_structures({**WALL, "polygon_m": polygon})))
             if "without touching" in w]
    assert bool(lines) == warned, lines
    if warned:
        assert lines[0].startswith(f"bodies.0 ('block') is {g:.3g} m from structures.0 ('wall') without touching it")
        assert "\n" not in lines[0]


# the block is [0, 0.2] x [0, 0.1] m in 2 mm cells: a wall dragged across it by d cells
@pytest.mark.parametrize("overlap_cells, warned", [(-1.0, False), (0.0, False), (0.3, False), (1.0, True),
                                                   (5.0, True), (30.0, True)])
@pytest.mark.parametrize("where", ["beside", "above"])
def test_a_body_drawn_into_a_structure_is_warned_about(overlap_cells, warned, where):
    """The part of a body inside a structure is not seeded (docs/project-format.md): meant for a
    slide drawn loosely into bedrock, a surprise for a wall dragged across a body. Warned about from
    a cell's area on (under it: a body drawn to a face with rounded coordinates); the warning says
    how much of the body is lost."""
    from projects.checks import project_warnings

    dx = BASE["domain"]["cell_size_m"]
    d = overlap_cells * dx
    polygon = ([[0.2 - d, 0.0], [0.26 - d, 0.0], [0.26 - d, 0.1], [0.2 - d, 0.1]] if where == "beside"
               else [[0.0, 0.1 - d], [0.3, 0.1 - d], [0.3, 0.14], [0.0, 0.14]])
    lines = [w for w in project_warnings(validate_project(with_structures({**WALL, "polygon_m": polygon})))
             if "into structures" in w]
    assert bool(lines) == warned, lines
    if warned:
        area = d * (0.1 if where == "beside" else 0.2)
        assert lines[0].startswith(f"bodies.0 ('block') extends {area:.3g} m2 ({100 * area / 0.02:.3g} % of its "
                                   "area) into structures.0 ('wall'): that part is not seeded")
        assert "\n" not in lines[0]
