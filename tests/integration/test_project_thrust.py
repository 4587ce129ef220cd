"""At-rest thrust on a retaining wall through the project path, as an engineer sets it up.

A granular column (Drucker-Prager, c = 0, phi 30 deg; 12 x 12 cells of 2 cm, 2 x 2 particles per
cell) stands between a slip left side and a vertical slip wall structure on the grid's fixed bottom; a `k0` stage, then 0.075 s undamped. The wall's mean force over each output interval
in `contacts.csv` is Jaky's at-rest thrust `1/2 K0 rho g H^2`, `K0 = 1 - sin(phi)`, within
5 %. The engine-level thrust tests (tests/unit/test_solver_thrust.py) cover more columns,
friction angles and cell sizes; this file checks what a project file, the runner and the results
folder give, over the schemes, wall thicknesses and face positions relative to
the node lines; and that the force's line of action, from its moment in `contacts.csv`, lies at a
third of the column's height, where the resultant of the triangular at-rest pressure acts.

Thin walls (``THIN_WALLS``): walls 1 to 3 cells thick at faces 0 to 0.9 cells off the node line,
every scheme, within the tolerance (0.957-1.000, line of action 0.333-0.348 H; the sweep of 150
runs in docs/validation.md, thrust). A node whose stencil reaches past a thin part's far face
holds the material beyond that face (``solver.structures.far_normals``); a node there with the
other face's normal lets the push through: measured so, a wall one cell thick takes 0.92-0.97
(the bottom's friction the rest, the line of action 0.36-0.40 H), two cells thick with faces
0.55-0.75 cells off 0.935-0.956. Walls under a cell thick are warned about and not tested here
(half a cell: up to 3.7 times with faces 0.6-0.9 off). The particle lattice is clipped at the
outline, which takes the material to the face; a point at each sub-cell centre inside the body
stops 0.1-0.2 cells short of the face or runs past it (measured: 0.935-0.952 with a face 0.6-0.7
cells off, up to 1.054 at 0.8). The project still warns about faces in the band 0.55-0.85 cells
off (3-4.3 % low there). Faces half a cell off hold because the structures' image reactions are
placed opposite the node that takes the image's force and the contact on the stress update's
velocity holds its active nodes both ways (without: a drift of mpm 1.05 -> 1.29 over 0.2 s, apic
1.03 -> 1.07, apic-affine 0.98 -> 0.87; docs/validation.md, thrust).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from projects.checks import project_warnings
from projects.document import loads_project
from projects.results import read_contacts
from projects.runner import run_project
from solver.config import line_of_action

# the suite runs a covering sample of each matrix below (tests/conftest.py, RUNOUT_FULL_MATRIX)
pytestmark = pytest.mark.matrix

CELL = 0.02
HEIGHT = 0.24
WIDTH = 0.24
PHI = 30.0
DENSITY = 1800.0
TOLERANCE = 0.05  # the issue's
#: the thrust's line of action: at H / 3 within 2 % of H (a quarter cell here); measured 0.334-0.346 H
HEIGHT_TOLERANCE = 0.02


def _project(scheme: str, precision: str, thick_cells: float, offset_cells: float, *, cell: float = CELL,
             width: float = WIDTH, duration_s: float = 0.075, low_height: float | None = None):
    """The sand column (``width`` wide, HEIGHT high) against a wall ``thick_cells`` thick whose
    face is ``offset_cells`` off the node line; with ``low_height`` a second column of that height,
    ``width`` wide, on the wall's other face."""
    face = width + offset_cells * cell
    back = face + thick_cells * cell
    size = back + width if low_height is not None else width + 0.2
    low = "" if low_height is None else f"""
[[bodies]]
name = "low"
material = "sand"
polygon_m = [[{back}, 0.0], [{size}, 0.0], [{size}, {low_height}], [{back}, {low_height}]]"""
    text = f"""
[runout]
schema_version = 1
[domain]
size_m = [{size}, 0.4]
cell_size_m = {cell}
[domain.boundaries]
left = "slip"
right = "slip"
bottom = "fixed"
top = "open"
[materials.sand]
model = "drucker-prager"
density_kg_m3 = {DENSITY}
youngs_modulus_pa = 2.0e7
poisson_ratio = 0.3
cohesion_pa = 0.0
friction_angle_deg = {PHI}
dilatancy_angle_deg = 0.0
[[bodies]]
name = "column"
material = "sand"
polygon_m = [[0.0, 0.0], [{face}, 0.0], [{face}, {HEIGHT}], [0.0, {HEIGHT}]]{low}
[[structures]]
name = "wall"
polygon_m = [[{face}, 0.0], [{back}, 0.0], [{back}, 0.4], [{face}, 0.4]]
contact = "slip"
[particles]
per_cell = 2
[numerics]
scheme = "{scheme}"
precision = "{precision}"
arch = "cpu"
[[stages]]
type = "k0"
[[stages]]
type = "dynamic"
duration_s = {duration_s}
[output]
interval_s = 0.025
fields = ["displacement"]
"""
    return loads_project(text)


def _thrust(tmp_path, scheme, precision, thick_cells, offset_cells):
    """Per output interval after the start: the wall's mean force over Jaky's thrust, and the
    height of its line of action over the column's (from the force's moment in contacts.csv)."""
    project = _project(scheme, precision, thick_cells, offset_cells)
    result = run_project(project, tmp_path / "results")
    assert result.status == "completed", result.message
    wall = read_contacts(tmp_path / "results")["wall"]
    later = wall["time_s"] > 0.0
    at_rest = 0.5 * (1.0 - math.sin(math.radians(PHI))) * DENSITY * 9.81 * HEIGHT ** 2
    assert later.sum() == 3
    centre = (WIDTH + (offset_cells + thick_cells / 2) * CELL, 0.2)
    heights = np.array([line_of_action((fx, fy), m, centre)[1] / HEIGHT for fx, fy, m in
                        zip(wall["force_x_N_per_m"][later], wall["force_y_N_per_m"][later],
                            wall["moment_N_m_per_m"][later])])
    return wall["force_x_N_per_m"][later] / at_rest, heights


# A face exactly half a cell from a node line, drawn on round numbers, whose signed distance
# round-off puts a hair outside the node's cell (0.375 - 0.36 > 0.015 in binary). Ties count as
# covered (solver.structures.node_contacts): 1.000-1.001 over the 0.5 s. A node left free there lets
# the thrust ratchet up under mpm: 0.930 -> 1.089 over the 0.5 s here (a 0.36 m column: 1.071 at
# 0.5 s, 1.31 at 1.5 s; apic 1.06 at 1.5 s); the suite's other half-cell cases (0.25 - 0.24 < 0.01)
# round the other way.
def test_a_face_exactly_half_a_cell_off_holds_the_at_rest_thrust_over_half_a_second(tmp_path):
    project = _project("mpm", "f32", 3, 0.5, cell=0.03, width=0.36, duration_s=0.5)
    assert project.structures[0].polygon_m[0][0] == 0.375
    result = run_project(project, tmp_path / "results")
    assert result.status == "completed", result.message
    wall = read_contacts(tmp_path / "results")["wall"]
    later = wall["time_s"] > 0.0
    at_rest = 0.5 * (1.0 - math.sin(math.radians(PHI))) * DENSITY * 9.81 * HEIGHT ** 2
    ratios = wall["force_x_N_per_m"][later] / at_rest
    assert later.sum() == 20
    assert abs(ratios - 1.0).max() < TOLERANCE, f"force / (1/2 K0 gamma H^2) per interval: {ratios.round(3)}"
    assert ratios[-1] - ratios[len(ratios) // 2] < 0.01, f"still rising: {ratios.round(3)}"


CASES = [
    # scheme, precision, wall thickness (cells), face offset from the node line (cells); one
    # precision per scheme, so that the file compiles three engines (the grid is the same)
    ("mpm", "f64", 2, 0.0),
    ("mpm", "f64", 4, 0.25),
    ("apic", "f32", 2, 0.25),
    ("apic", "f32", 4, 0.0),
    ("apic-affine", "f32", 2, 0.0),
    ("apic-affine", "f32", 4, 0.25),
    # half a cell off and beyond (drifted before, docs/validation.md, thrust)
    ("mpm", "f64", 2, 0.5),
    ("apic", "f32", 4, 0.9),
    ("apic-affine", "f32", 4, 0.5),
]


@pytest.mark.parametrize("scheme, precision, thick_cells, offset_cells", CASES)
def test_a_column_pushes_on_a_retaining_wall_with_the_at_rest_thrust(tmp_path, scheme, precision, thick_cells,
                                                                     offset_cells):
    ratios, heights = _thrust(tmp_path, scheme, precision, thick_cells, offset_cells)
    assert abs(ratios - 1.0).max() < TOLERANCE, f"force / (1/2 K0 gamma H^2) per interval: {ratios.round(3)}"
    # the triangular at-rest pressure's resultant acts at a third of the height
    assert abs(heights - 1.0 / 3.0).max() < HEIGHT_TOLERANCE, f"line of action's height / H: {heights.round(4)}"
    # nothing warns about this wall: it is thick enough and its face is not in the warned band
    assert not project_warnings(_project(scheme, precision, thick_cells, offset_cells))


# walls four cells thick with a face in the band warned about (for thinner walls): within the
# tolerance since the lattice is clipped at the bodies' outlines (0.94-1.04 before)
IN_BAND = [("apic", "f32", 4, 0.7), ("mpm", "f64", 4, 0.8), ("apic-affine", "f32", 4, 0.6)]


@pytest.mark.parametrize("scheme, precision, thick_cells, offset_cells", IN_BAND)
def test_a_thick_wall_with_a_face_between_node_lines_takes_the_at_rest_thrust(tmp_path, scheme, precision,
                                                                            thick_cells, offset_cells):
    ratios, heights = _thrust(tmp_path, scheme, precision, thick_cells, offset_cells)
    assert abs(ratios - 1.0).max() < TOLERANCE, f"force / (1/2 K0 gamma H^2) per interval: {ratios.round(3)}"
    assert abs(heights - 1.0 / 3.0).max() < HEIGHT_TOLERANCE, f"line of action's height / H: {heights.round(4)}"


# (scheme, precision, thickness cells, face offset cells): walls a cell to three cells thick, the
# offsets at and between node lines, a covering design (every scheme meets every thickness and every
# kind of offset: on a node line, inside and beyond the warned band). Before far normals: 1 cell
# mpm 0.923 at 0.0, apic 0.922 at 0.75; 2 cells apic-affine 0.942 at 0.7; 1.5 cells in between.
THIN_WALLS = [
    ("mpm", "f64", 1, 0.0), ("mpm", "f64", 1.5, 0.7), ("mpm", "f64", 2, 0.9), ("mpm", "f64", 3, 0.3),
    ("apic", "f32", 1, 0.75), ("apic", "f32", 1.5, 0.4), ("apic", "f32", 2, 0.6), ("apic", "f32", 3, 0.0),
    ("apic-affine", "f32", 1, 0.5), ("apic-affine", "f32", 1.5, 0.1), ("apic-affine", "f32", 2, 0.7),
    ("apic-affine", "f32", 3, 0.8),
]


@pytest.mark.parametrize("scheme, precision, thick_cells, offset_cells", THIN_WALLS)
def test_a_thin_wall_takes_the_at_rest_thrust_at_any_offset(tmp_path, scheme, precision, thick_cells, offset_cells):
    ratios, heights = _thrust(tmp_path, scheme, precision, thick_cells, offset_cells)
    assert abs(ratios - 1.0).max() < TOLERANCE, f"force / (1/2 K0 gamma H^2) per interval: {ratios.round(3)}"
    assert abs(heights - 1.0 / 3.0).max() < HEIGHT_TOLERANCE, f"line of action's height / H: {heights.round(4)}"
    # no thin-structure warning from a cell on
    assert not [w for w in project_warnings(_project(scheme, precision, thick_cells, offset_cells)) if "thick at" in w]


@pytest.mark.parametrize("thick_cells, offset_cells, warned", [(0.5, 0.0, True), (0.8, 0.3, True), (1, 0.0, False),
                                                              (2, 0.7, True), (2, 0.5, False), (4, 0.6, True)])
def test_walls_thinner_than_a_cell_or_with_a_face_in_the_band_are_warned_about(thick_cells, offset_cells, warned):
    assert bool(project_warnings(_project("apic", "f32", thick_cells, offset_cells))) == warned


# A wall with material on both faces takes the difference of the two at-rest thrusts. Thinner than
# a stencil, the images of one column's particles (mirrored across its face) reached the free nodes
# of the other column beyond the far face and pushed on them: 0.43-0.65 of the difference on walls
# 1-1.25 cells thick, 1.3-3.6 times at 0.7 cells off, and guard stops in this static scene at 0.3
# cells off (every scheme). An image now acts only on nodes on its particle's side of the surface:
# 0.959-1.007 over 36 cases (1, 1.25, 1.5 cells; offsets 0-0.7; three schemes).
TWO_SIDED = [("mpm", 1, 0.3), ("mpm", 1.25, 0.7), ("apic", 1, 0.7), ("apic", 1.5, 0.5), ("apic-affine", 1, 0.0),
             ("apic-affine", 1.25, 0.5)]


@pytest.mark.parametrize("scheme, thick_cells, offset_cells", TWO_SIDED)
def test_a_thin_wall_between_two_columns_takes_the_difference_of_their_thrusts(tmp_path, scheme, thick_cells,
                                                                               offset_cells):
    result = run_project(_project(scheme, "f32", thick_cells, offset_cells, low_height=HEIGHT / 2),
                         tmp_path / "results")
    assert result.status == "completed", result.message
    wall = read_contacts(tmp_path / "results")["wall"]
    later = wall["time_s"] > 0.0
    net = 0.5 * (1.0 - math.sin(math.radians(PHI))) * DENSITY * 9.81 * (HEIGHT ** 2 - (HEIGHT / 2) ** 2)
    ratios = wall["force_x_N_per_m"][later] / net
    assert later.sum() == 3
    assert abs(ratios - 1.0).max() < TOLERANCE, f"force / difference of the at-rest thrusts: {ratios.round(3)}"
