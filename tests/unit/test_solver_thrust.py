"""At-rest thrust of granular columns on vertical structures after a K0 stage.

A Drucker-Prager column (c = 0) between two vertical slip structures gets Jaky's geostatic stress
from a ``k0`` stage (``sigma_h = (1 - sin phi) sigma_v``) and is then left to itself, undamped:
the force on each structure is the at-rest thrust ``1/2 K0 rho g H^2`` (Terzaghi, Theoretical
Soil Mechanics, 1943; Jaky 1944 for K0) as long as the K0 state is in equilibrium on the grid next
to the structures, which the structures' mirror-image particles provide (docs/solver.md, contact).
Without them the six-stage schemes drifted to +4 to +5 % within 0.5 s (docs/validation.md).
The k0 stage's overburden is each particle's own bar of material, exact for lattices at any
alignment with the grid, so faces between node lines start in equilibrium too (before, binned by
grid-cell columns, the particle line next to a face 0.3 cells off the node line had half its
overburden: apic 1.06-1.08).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from solver.config import Boundary, Grid, Material, Numerics, Output, Particles, SimulationConfig, Stage, Structure
from solver.simulation import Simulation

# the suite runs a covering sample of each matrix below (tests/conftest.py, RUNOUT_FULL_MATRIX)
pytestmark = pytest.mark.matrix

RHO, G = 1800.0, 9.81
#: (friction angle deg, height m) of the columns of one run: the range in which the default cone
#: (``plane-strain-associated``) holds Jaky's K0 state (up to about 35 deg; see docs/solver.md)
COLUMNS = ((20.0, 1.2), (35.0, 1.0), (27.0, 0.6))
#: and one it cannot hold: every particle of this column is a plastic point after the k0 stage
BEYOND = (40.0, 1.0)
#: per column (COLUMNS, then BEYOND): the offset of its left face from the node line and its width,
#: in cells. apic-affine: the right faces then lie 0.5, 0.3, 0.7 and 0.7 cells off the node line, so
#: a run has faces at 0, 0.2, 0.3, 0.5 and 0.7 cells on both sides of the material (left of a
#: structure and right of one). mpm and apic: faces 0, 0.1, 0.4 and 0.6 cells off on both sides
#: (right faces 0, 0.4, 0.1, 0.6; before the structures' image reactions and contact target, mpm
#: drifted to 1.08-8 times the thrust at 0.4-0.6). Both faces of a column half a cell off are a
#: known limit in this scene (1.10-1.17; docs/validation.md, thrust); the k0 overburden itself is
#: exact for any alignment (test below)
FACES = {"apic-affine": ((0.0, 4.5), (0.3, 4.0), (0.2, 4.5), (0.7, 4.0)),
         "mpm": ((0.0, 4.0), (0.4, 4.0), (0.6, 4.5), (0.1, 4.5))}
FACES["apic"] = FACES["mpm"]
#: structures' thickness, cells
THICK = 3


def _moved(polygon, origin_m):
    return tuple((px + origin_m[0], py + origin_m[1]) for px, py in polygon)


def _columns(scheme: str, cell_m: float, precision: str, origin_m=(0.0, 0.0), scatter: str = "auto",
             duration_s: float = 0.3, thick: int = THICK, faces=None):
    """One run with a column per COLUMNS row (and BEYOND) between two slip structures ``thick``
    cells thick, placed as ``faces`` (default FACES[scheme]) says, the whole scene moved by
    ``origin_m``; frames of the dynamic stage every ``duration_s / 3``."""
    ox, oy = origin_m
    mats, pos, ids, structures = [], [], [], []
    h = cell_m / 2  # 2 x 2 particles per cell
    x = 3 * cell_m
    for k, ((phi, height), (offset, cells)) in enumerate(zip(COLUMNS + (BEYOND,), faces or FACES[scheme])):
        x, width = x + offset * cell_m, cells * cell_m
        mats.append(Material(f"sand {k}", "drucker-prager", RHO, 2e7, 0.3, cohesion_pa=0.0,
                             friction_angle_rad=math.radians(phi)))
        top = 2 * height
        structures.append(Structure(f"left {k}", _moved(((x - thick * cell_m, -cell_m), (x, -cell_m), (x, top),
                                                         (x - thick * cell_m, top)), origin_m), Boundary("slip")))
        X, Y = np.meshgrid(x + (np.arange(round(width / h)) + 0.5) * h, (np.arange(round(height / h)) + 0.5) * h)
        pos.append(np.c_[X.ravel() + ox, Y.ravel() + oy])
        ids.append(np.full(X.size, k, np.int32))
        x += width
        far = x + thick * cell_m
        structures.append(Structure(f"right {k}", _moved(((x, -cell_m), (far, -cell_m), (far, top), (x, top)), origin_m),
                                    Boundary("slip")))
        x = (math.floor(x / cell_m + 1e-9) + 7) * cell_m
    positions = np.concatenate(pos)
    particles = Particles(positions, np.full(len(positions), h * h), np.concatenate(ids))
    grid = Grid((ox, oy), (x, 1.2 * max(H for _, H in COLUMNS + (BEYOND,))), cell_m, left=Boundary("slip"),
                right=Boundary("slip"), bottom=Boundary("slip"), top=Boundary("open"))
    # the k0 stage: every material's default K0, Jaky's 1 - sin(phi) for drucker-prager
    stages = (Stage("k0", "k0"), Stage("rest", "dynamic", duration_s=duration_s))
    cfg = SimulationConfig(grid, tuple(mats), stages, (0.0, -G),
                           Numerics(scheme=scheme, cfl=0.5, arch="cpu", precision=precision, scatter=scatter),
                           Output(duration_s / 3), tuple(structures))
    with Simulation(cfg, particles) as sim:
        frames = list(sim.run())
        equilibrium = sim.equilibrium
    return frames, equilibrium, np.concatenate(ids)


# every scheme, both precisions, two cell sizes (6-24 cells high); one scene far from (0, 0) (the
# engine works relative to the grid origin, the structures too) with the atomic scatter (the
# mirror particles' parallel path, as on a GPU)
@pytest.mark.parametrize("scheme, cell_m, precision, origin_m, scatter", [
    ("mpm", 0.05, "f64", (0.0, 0.0), "auto"), ("apic", 0.1, "f32", (0.0, 0.0), "auto"),
    ("apic-affine", 0.05, "f32", (250.0, -40.0), "atomic")])
def test_a_granular_column_after_a_k0_stage_pushes_on_vertical_structures_with_the_at_rest_thrust(
        scheme, cell_m, precision, origin_m, scatter):
    frames, equilibrium, ids = _columns(scheme, cell_m, precision, origin_m, scatter)
    # the K0 state is in equilibrium next to the structures (a free top remains)
    assert equilibrium["unbalanced_force_ratio"] < 0.05
    # inside the cone but in the last column, where the report tells the K the return gives
    assert equilibrium["plastic_points"] == np.count_nonzero(ids == len(COLUMNS))
    phi, height = BEYOND
    k_plastic = equilibrium["plastic_k0"]
    assert 1.0 - math.sin(math.radians(phi)) < k_plastic < 0.45
    for frame in frames[1:]:  # and that K gives the thrust of that column
        forces = {c.contact: c for c in frame.contacts}
        for side, sign in (("right", 1.0), ("left", -1.0)):
            force = sign * forces[f"{side} {len(COLUMNS)}"].force_x_N_per_m
            assert force == pytest.approx(0.5 * k_plastic * RHO * G * height ** 2, rel=0.05), side
    for k, (phi, height) in enumerate(COLUMNS):
        thrust = 0.5 * (1.0 - math.sin(math.radians(phi))) * RHO * G * height ** 2
        for frame in frames[1:]:  # the mean force over every output interval of the undamped stage
            forces = {c.contact: c for c in frame.contacts}
            where = f"{scheme} {cell_m} m {precision}, phi {phi}, H {height} m, t {frame.diagnostics.time_s:.2f} s"
            assert forces[f"right {k}"].force_x_N_per_m == pytest.approx(thrust, rel=0.05), where
            assert -forces[f"left {k}"].force_x_N_per_m == pytest.approx(thrust, rel=0.05), where
            assert abs(forces[f"right {k}"].force_y_N_per_m) < 0.01 * thrust, where  # slip: no shear


# walls two cells thick, on node lines (their middle node line is the walls' medial axis) and off
# them: every scheme, both precisions
@pytest.mark.parametrize("scheme, precision, offset_cells", [
    ("mpm", "f64", 0.0), ("apic", "f32", 0.2), ("apic-affine", "f64", 0.3), ("apic-affine", "f32", 0.0)])
def test_walls_two_cells_thick_take_the_at_rest_thrust(scheme, precision, offset_cells):
    """A node on the medial axis of a wall two cells thick is as near the far face as the near one;
    its nearest-face normal, a coin toss that round-off decided, pointed away from the material in
    half the walls, which let the column's approach through there (0.91-1.08 of the thrust,
    unbalanced-force ratio 0.23). Such nodes are held (solver.structures.node_contacts)."""
    faces = ((offset_cells, 4.0),) * (len(COLUMNS) + 1)
    frames, equilibrium, _ids = _columns(scheme, 0.05, precision, thick=2, faces=faces)
    assert equilibrium["unbalanced_force_ratio"] < 0.07
    for k, (phi, height) in enumerate(COLUMNS):
        thrust = 0.5 * (1.0 - math.sin(math.radians(phi))) * RHO * G * height ** 2
        for frame in frames[1:]:
            forces = {c.contact: c for c in frame.contacts}
            where = f"{scheme} {precision} offset {offset_cells}, phi {phi}, t {frame.diagnostics.time_s:.2f} s"
            assert forces[f"right {k}"].force_x_N_per_m == pytest.approx(thrust, rel=0.05), where
            assert -forces[f"left {k}"].force_x_N_per_m == pytest.approx(thrust, rel=0.05), where


def test_medial_nodes_of_facing_surfaces_are_held_and_a_wedge_apex_keeps_its_normals():
    """node_contacts gives the nodes on the medial axis of a wall two cells thick a zero normal (held:
    a fixed contact node) and keeps the nearest face's normal elsewhere: at the faces, in walls of
    other thicknesses away from their middle, and in the tip of a sharp wedge thinner than a cell."""
    from solver.structures import node_contacts

    h = 0.1
    xs, ys = np.arange(0.0, 1.0001, h), np.arange(0.0, 1.0001, h)
    j = 3  # a node row through the walls' height
    _, normal = node_contacts([((0.4, 0.0), (0.6, 0.0), (0.6, 0.8), (0.4, 0.8))], xs, ys, h)  # two cells
    col = {round(x, 2): normal[i, j] for i, x in enumerate(xs)}
    np.testing.assert_array_equal(col[0.5], [0.0, 0.0])
    np.testing.assert_allclose(col[0.4], [-1.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(col[0.6], [1.0, 0.0], atol=1e-9)
    _, normal = node_contacts([((0.4, 0.0), (0.7, 0.0), (0.7, 0.8), (0.4, 0.8))], xs, ys, h)  # three cells
    assert np.all(np.linalg.norm(normal[4:8, j], axis=-1) > 0.99)  # no node within a quarter cell of the middle
    # a tall wedge, faces within 10 deg of facing, its tip below a cell thick: the tip keeps normals
    wedge = ((0.4, 0.0), (0.6, 0.0), (0.52, 1.0))
    index, normal = node_contacts([wedge], xs, ys, h)
    tip = [(i, k) for i in range(len(xs)) for k in range(len(ys)) if index[i, k] == 0 and ys[k] > 0.55]
    assert tip and all(np.linalg.norm(normal[i, k]) > 0.99 for i, k in tip)


@pytest.mark.parametrize("thick_cells, offset_cells, lean_deg", [
    (1.0, 0.0, 0.0), (1.0, 0.75, 0.0), (1.3, 0.1, 0.0), (2.0, 0.7, 0.0), (1.0, 0.2, 45.0), (1.3, 0.5, 25.0)])
def test_far_normals_mark_the_nodes_whose_stencil_reaches_past_a_thin_parts_far_face(thick_cells, offset_cells,
                                                                                   lean_deg):
    """far_normals: a contact node whose stencil (1.5 cells along each axis) reaches the outside
    beyond a thin part's far face gets that face's outward normal, opposite its own; nodes of a
    thicker part, and nodes whose stencil ends inside the part, get none. Checked against the
    geometry directly: the node's own normal's ray, followed against it, leaves the part within the
    stencil's square."""
    from solver.structures import far_normals, node_contacts, signed_distance

    h = 0.1
    xs, ys = np.arange(0.0, 2.0001, h), np.arange(0.0, 2.0001, h)
    t = thick_cells * h / math.cos(math.radians(lean_deg))
    s = 1.6 * math.tan(math.radians(lean_deg))
    x0 = 0.6 + offset_cells * h
    wall = ((x0, -0.2), (x0 + t, -0.2), (x0 + t + s, 1.4), (x0 + s, 1.4))
    index, normal = node_contacts([wall], xs, ys, h)
    far = far_normals([wall], xs, ys, index, normal, h)
    across = np.array([math.cos(math.radians(lean_deg)), -math.sin(math.radians(lean_deg))])  # the right face's
    marked = 0
    for i, x in enumerate(xs):
        for k, y in enumerate(ys):
            if not 0.2 < y < 1.0 or index[i, k] != 0 or not np.linalg.norm(normal[i, k]) > 0.5:
                assert not far[i, k].any() or index[i, k] == 0
                continue
            n = normal[i, k]
            reach = 1.5 * h / np.abs(n).max()
            d = signed_distance(np.array([x, y]) - np.linspace(0.0, reach, 400)[:, None] * n, wall)
            entered = np.maximum.accumulate(d <= 0.0)  # the ray has been inside the part
            beyond = bool(np.any(entered[:-1] & (d[1:] > 0.0)))
            if beyond:
                marked += 1
                # the far face's outward normal: opposite the node's own, one of the wall's two faces
                assert far[i, k] @ n < -0.99
                assert abs(abs(far[i, k] @ across) - 1.0) < 1e-6
            else:
                np.testing.assert_array_equal(far[i, k], [0.0, 0.0])
    assert marked > 0
    # a wall three cells thick on node lines: no node reaches past its far face
    index, normal = node_contacts([((0.6, -0.2), (0.9, -0.2), (0.9, 1.4), (0.6, 1.4))], xs, ys, h)
    assert not far_normals([((0.6, -0.2), (0.9, -0.2), (0.9, 1.4), (0.6, 1.4))], xs, ys, index, normal, h).any()


@pytest.mark.parametrize("scheme, precision, bottom", [
    ("apic-affine", "f32", Boundary("fixed")), ("mpm", "f64", Boundary("slip")),
    ("apic", "f32", Boundary("friction", math.radians(30.0))), ("apic-affine", "f64", Boundary("slip"))])
def test_a_wall_standing_on_the_grid_bottom_takes_the_at_rest_thrust(scheme, precision, bottom):
    """A wall structure standing on the grid's bottom side, as a project draws it (a project cannot
    put a structure below the domain), against a granular column after a k0 stage: the wall takes
    the at-rest thrust, the left side the same, the bottom no horizontal force, whatever the bottom's
    contact. The structure continues through the side it stands on (solver.structures.through_sides:
    with its foot a surface on the side line, a slip bottom drifted to +11 % in 0.2 s) and the
    impulse at the nodes both hold is split along their normals (a fixed bottom took the foot
    node's share of the thrust: 0.917)."""
    from solver.config import Grid, Material, Numerics, Output, Particles, SimulationConfig, Stage
    from solver.simulation import Simulation

    cell, width, height, phi = 0.02, 0.3, 0.3, 30.0
    h = cell / 2
    X, Y = np.meshgrid((np.arange(round(width / h)) + 0.5) * h, (np.arange(round(height / h)) + 0.5) * h)
    particles = Particles(np.c_[X.ravel(), Y.ravel()], np.full(X.size, h * h), np.zeros(X.size, np.int32))
    wall = Structure("wall", ((width, 0.0), (width + 0.1, 0.0), (width + 0.1, 0.4), (width, 0.4)), Boundary("slip"))
    grid = Grid((0.0, 0.0), (0.8, 0.5), cell, left=Boundary("slip"), right=Boundary("slip"), bottom=bottom,
                top=Boundary("open"))
    sand = Material("sand", "drucker-prager", 2000.0, 1e7, 0.3, cohesion_pa=0.0, friction_angle_rad=math.radians(phi))
    cfg = SimulationConfig(grid, (sand,), (Stage("k0", "k0"), Stage("rest", "dynamic", duration_s=0.2)), (0.0, -G),
                           Numerics(scheme=scheme, cfl=0.5, arch="cpu", precision=precision), Output(0.05), (wall,))
    with Simulation(cfg, particles) as sim:
        frames = list(sim.run())
    thrust = 0.5 * (1.0 - math.sin(math.radians(phi))) * 2000.0 * G * height ** 2
    for frame in frames[1:]:
        forces = {c.contact: c.force_x_N_per_m for c in frame.contacts}
        where = f"{scheme} {precision} bottom {bottom.kind}, t {frame.diagnostics.time_s:.2f} s"
        assert forces["wall"] == pytest.approx(thrust, rel=0.05), where
        assert -forces["left"] == pytest.approx(thrust, rel=0.05), where
        assert abs(forces["bottom"]) < 0.02 * thrust, where


def test_a_structure_on_a_side_continues_through_it():
    """through_sides continues the edges that lie on a side line beyond it and leaves the outline
    inside the box as it was (an inclined face ending on the line keeps its slope); periodic sides
    are not crossed."""
    from solver.structures import through_sides

    box = ((0.0, 0.0), (0.8, 0.5))
    wall = ((0.3, 0.0), (0.4, 0.0), (0.4, 0.4), (0.3, 0.4))
    assert through_sides(wall, *box, 0.04) == ((0.3, 0.0), (0.3, -0.04), (0.4, -0.04), (0.4, 0.0), (0.4, 0.4),
                                                (0.3, 0.4))
    ramp = ((0.3, 0.0), (0.42, 0.0), (0.42, 0.04))  # its inclined face ends on the bottom at (0.3, 0)
    got = through_sides(ramp, *box, 0.04)
    assert got == ((0.3, 0.0), (0.3, -0.04), (0.42, -0.04), (0.42, 0.0), (0.42, 0.04))
    inside = np.array([[0.36, 0.01], [0.41, 0.035], [0.35, -0.02]])
    outside = np.array([[0.33, 0.02], [0.29, -0.01]])  # above the inclined face; beside the strip
    np.testing.assert_array_equal(_sides_of(got, inside), -1)
    np.testing.assert_array_equal(_sides_of(got, outside), 1)
    corner = ((0.0, 0.3), (0.2, 0.3), (0.2, 0.5), (0.0, 0.5))  # in the top-left corner
    left_top = through_sides(corner, *box, 0.04)
    assert (-0.04, 0.3) in left_top and (0.2, 0.54) in left_top
    assert (-0.04, 0.3) not in through_sides(corner, *box, 0.04, (False, False, True, True))
    floating = ((0.3, 0.1), (0.4, 0.1), (0.35, 0.3))
    assert through_sides(floating, *box, 0.04) == floating


def _sides_of(polygon, points):
    from solver.structures import signed_distance

    return np.sign(signed_distance(points, polygon))


def test_the_host_return_map_is_the_kernels():
    """``return_map_host`` (the k0 stage's plastic-point report) returns stresses as the kernel does."""
    from solver import runtime
    from solver.materials import MaterialPointDriver, drucker_prager, material_rows

    runtime.acquire("cpu", "f64")
    rng = np.random.default_rng(3)
    n = 400
    stress = rng.normal(0.0, 1e4, (n, 4)) - np.array([2e4, 3e4, 0.0, 2e4]) * rng.random((n, 1))
    mats = [Material("a", "drucker-prager", RHO, 2e7, 0.3, cohesion_pa=c, friction_angle_rad=math.radians(phi),
                     dilatancy_angle_rad=math.radians(psi), tensile_strength_pa=t)
            for c, phi, psi, t in ((0.0, 40.0, 0.0, None), (5e3, 25.0, 10.0, 1e3))]
    ids = np.arange(n) % 2
    kernel = MaterialPointDriver(mats, n).run(stress, np.zeros((n, 2, 2)), 1e-4, material_ids=ids)
    rows = material_rows(mats)
    host, plastic = drucker_prager.return_map_host(
        stress, **{k: rows[k][ids] for k in ("K", "G", "alpha", "kc", "alpha_psi", "t_cut")})
    assert 0 < plastic.sum() < n
    np.testing.assert_array_equal(plastic, kernel["yielded"] == 1)
    np.testing.assert_allclose(host, kernel["stress"], rtol=1e-10, atol=1e-6)


@pytest.mark.parametrize("offset_cells", [0.0, 0.3, 0.5, 0.7])
def test_the_k0_overburden_is_exact_for_lattices_at_any_alignment(offset_cells):
    """``k0_stress`` gives every particle of a lattice the weight of its own column of material,
    ``rho g (top - y)``, wherever the lattice lies on the grid (a face between node lines leaves a
    partial grid column: the former binning by cell columns halved the particle line next to it),
    for layers of different particle spacings (2 x 2 below, 3 x 3 above, the lines not aligned) and
    under a sloping surface (each particle line its own column: a staircase of lattice lines)."""
    from solver.initial_stress import k0_stress

    dx = 0.1
    ox = offset_cells * dx
    rho = (1800.0, 2400.0)
    mats = [Material(f"m{k}", "elastic", r, 1e7, 0.25) for k, r in enumerate(rho)]
    pos, vol, ids = [], [], []
    # layer 0: 2 x 2 per cell, 10 cells wide, 0.6 m thick
    s0 = dx / 2
    X, Y = np.meshgrid(ox + (np.arange(20) + 0.5) * s0, (np.arange(12) + 0.5) * s0)
    pos.append(np.c_[X.ravel(), Y.ravel()]), vol.append(np.full(X.size, s0 * s0)), ids.append(np.zeros(X.size, int))
    # layer 1: 3 x 3 per cell on top, its lines shifted by a third of its spacing; the surface slopes
    # down to the right by one particle per line
    s1 = dx / 3
    for i in range(30):
        rows = 18 - i // 2
        xs = ox + (i + 0.5) * s1
        ys = 0.6 + (np.arange(rows) + 0.5) * s1
        pos.append(np.c_[np.full(rows, xs), ys]), vol.append(np.full(rows, s1 * s1)), ids.append(np.ones(rows, int))
    pos, vol, ids = np.concatenate(pos), np.concatenate(vol), np.concatenate(ids)
    particles = Particles(pos, vol, ids.astype(np.int32))
    stress = k0_stress(particles, mats, (0.0, -G), dx, k0=0.5)
    # exact: the weight of the material above each particle within its own width
    expected = np.empty(len(pos))
    for p, (x, y) in enumerate(pos):
        width = math.sqrt(vol[p])
        lo, hi = x - width / 2, x + width / 2
        load = 0.0
        for q in np.flatnonzero(pos[:, 1] >= y - 1e-12):
            wq = math.sqrt(vol[q])
            overlap = max(0.0, min(hi, pos[q, 0] + wq / 2) - max(lo, pos[q, 0] - wq / 2))
            share = 0.5 if abs(pos[q, 1] - y) < 1e-12 else 1.0
            load += share * rho[ids[q]] * G * vol[q] * overlap / wq
        expected[p] = -load / width
    np.testing.assert_allclose(stress[:, 1], expected, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(stress[:, 0], 0.5 * expected, rtol=1e-9, atol=1e-9)
    # and in the lower layer, below the level part of the surface, the closed form
    deep = (ids == 0) & (pos[:, 0] < ox + 2 * s1 - 1e-9)
    top = 0.6 + 18 * s1
    closed = -(rho[0] * G * (0.6 - pos[deep, 1]) + rho[1] * G * (top - 0.6))
    np.testing.assert_allclose(stress[deep, 1], closed, rtol=1e-12)


@pytest.mark.parametrize("per_cell", [2, 3])
@pytest.mark.parametrize("offset_cells", [0.0, 0.3, 0.55, 0.7, 0.8])
def test_the_k0_overburden_is_exact_next_to_a_clipped_outline(offset_cells, per_cell):
    """The project path: a column seeded on the lattice clipped at its outline (the face of a
    structure between node lines cuts the last sub-cells) gets ``rho g (top - y)`` at every
    particle, the parts of the cut sub-cells included: their bars are their own boxes
    (``Particles.bounds_m``), not ``sqrt(V)`` about their centroids (0.85-0.95 of the overburden in
    the particle line against the face, 1.07 beside it)."""
    from geometry.seeding import seed_lattice
    from solver.initial_stress import k0_stress

    dx, height, rho = 0.02, 0.24, 1800.0
    face = 0.24 + offset_cells * dx
    column = np.array([[0.0, 0.0], [face, 0.0], [face, height], [0.0, height]])
    wall = np.array([[face, 0.0], [face + 4 * dx, 0.0], [face + 4 * dx, 0.4], [face, 0.4]])
    seeds = seed_lattice([column], (0.0, 0.0), dx, per_cell, holes=[wall])
    cut = seeds.volumes_m2 < (dx / per_cell) ** 2 * (1 - 1e-9)
    assert cut.any() == (offset_cells * per_cell % 1 != 0)
    particles = Particles(seeds.positions_m, seeds.volumes_m2, np.zeros(len(seeds), np.int32),
                          bounds_m=seeds.bounds_m)
    stress = k0_stress(particles, [Material("sand", "elastic", rho, 2e7, 0.3)], (0.0, -G), dx, k0=0.5)
    closed = -rho * G * (height - seeds.positions_m[:, 1])
    np.testing.assert_allclose(stress[:, 1], closed, rtol=1e-9)
    np.testing.assert_allclose(stress[:, 0], 0.5 * closed, rtol=1e-9)
