"""The grid contact law (docs/solver.md, contact): Coulomb friction on walls and structures, the
force on each contact, and structures that no particle enters (CPU, small scenes).

Inclines: a block at rest, in equilibrium (:func:`tests.contact_scenes.slope_stress`), on a
frictional contact; sliding cases within 3 % of ``1/2 g (sin th - tan d cos th) t^2`` over at least
20 cells of travel, sticking cases slip less than 0.1 % of the frictionless distance (the issue's
tolerances). Walls are made inclines by tilting gravity (exact and cheap); the ramp is an inclined
structure under vertical gravity, its normal no grid axis.

The wall rows are a covering design of the full incline matrix
(docs/validation.md, contact): every value of every axis (3 schemes, f32/f64, 1/5/20 cells thick,
E = 1e6/1e8 Pa, bottom/left/right wall), and every pair of values of any two of those axes in some
row (nine rows: scheme x thickness x side is a Latin square, precision and stiffness spread so
that every pair of theirs occurs too); each row runs one sliding and one sticking case, and the
rows together cover inclines 10-40 degrees and friction 0-45 degrees.

Classic mpm (FLIP) takes the new velocity itself from contact nodes (PIC there, docs/solver.md,
contact); before, FLIP let friction-excited slip and opening waves grow at high friction (sliding up
to +28 %, a stiff sheet -7 %, creep up to 4 %). ``FLIP_ROWS`` are such cases, now within the
tolerances, and mpm is in the covering design like the other schemes.

Known limits (``KNOWN_LIMITS``). A 20-cell block (4 times as long as thick) 5 degrees from the
friction limit (40 on 45 deg) creeps in every scheme and contact: 1.0-1.06 % of the frictionless
distance for E = 1e6 Pa, 0.25-0.34 % for 1e8 (30 on 45 holds, below 0.02 %). Slip pulses start at
its upslope end, which the overturning moment of the weight unloads, and ratchet it down the slope;
the creep grows instead of settling (it runs away after 5-9 times the test's duration), grows with
mesh refinement, and goes on under local damping, so it is no settling transient
(docs/validation.md, contact). The same shows in sliding cases just above the friction limit (not
in the matrix, whose sliding pairs are 10 deg above it): on a 40 or 38 deg incline with 35 or 36
deg friction blocks of 5 to 20 cells slide too far, +3.4 to +25 % at 40/35 and +42 to +135 % at
38/36 (friction deficits of 0.8-10 % of mu, which the small net acceleration magnifies). A one-cell
sheet is within the tolerance there since the mirror walls' normal impulse brings friction with it
(``MIRROR_ROWS``), through the wall column and without pulling the ghost back (apic +1.3 %,
apic-affine -0.6 %, mpm +0.04 % at 38/36). The others are strict xfails: they fail the suite if they ever meet
the tolerances, so that this note is updated. Measured per contact node
(docs/validation.md, contact), neither is friction that changes
direction under elastic waves (no node slips up the slope; slip steps give exactly mu N): the creep
is the upslope part of the base, unloaded by the weight's moment, slipping at mu N (a 20-cell block
twice as long as thick creeps 6.6 %); the excess slide is friction lost at wall nodes that an opening
chatter of the base leaves almost without mass (their normal impulse, the stress of the cell, allows
more friction than their own tangential momentum can give); at low friction too (a 20-cell block at
13 deg on 12 deg: +35 %); that chatter grows with the friction and not from the small-mass
nodes (treating them as MUSL does, or as empty, leaves it; docs/validation.md). ``ASPECT_ROWS``: a 20-cell block twice as
long as thick holds the tolerances at 20/10 and 20/30 deg and creeps 6.4 % at 40/45 (strict xfail).
The chatter's root at high friction is a flutter of the discretised elastic block, not the
contact's time integration (docs/validation.md, contact).
"""

import math

import numpy as np
import pytest

from solver import runtime
from solver.config import (Boundary, Grid, Material, Numerics, Output, Particles, SimulationConfig, Stage,
                           Structure)
from solver.simulation import Simulation
from solver.structures import corner_normals, corner_zone, node_contacts, signed_distance
from tests.contact_scenes import RampIncline, WallIncline

# the suite runs a covering sample of each matrix below (tests/conftest.py, RUNOUT_FULL_MATRIX)
pytestmark = pytest.mark.matrix

SLIDE_TOL = 0.03
STICK_TOL = 1e-3

# (scheme, precision, thickness cells, E Pa, side, [(incline deg, friction deg), ...]): a sliding and a
# sticking case each
WALL_ROWS = [
    ("mpm", "f32", 20, 1e8, "bottom", [(20, 10), (20, 30)]),
    ("mpm", "f64", 1, 1e6, "left", [(10, 0), (30, 45)]),
    ("mpm", "f32", 5, 1e8, "right", [(20, 10), (10, 20)]),
    ("apic", "f64", 20, 1e6, "right", [(40, 30), (30, 45)]),
    ("apic", "f32", 1, 1e8, "bottom", [(30, 20), (10, 20)]),
    ("apic", "f64", 5, 1e8, "left", [(40, 30), (30, 45)]),
    ("apic-affine", "f32", 20, 1e6, "left", [(30, 20), (20, 30)]),
    ("apic-affine", "f64", 1, 1e8, "right", [(10, 0), (20, 30)]),
    ("apic-affine", "f64", 5, 1e6, "bottom", [(40, 30), (40, 45)]),
]

_PULSES = pytest.mark.xfail(strict=True, reason="20-cell block 5 deg from the friction limit: slip pulses from its "
                                                "upslope end grow into sliding (module note)")
_NEAR = pytest.mark.xfail(strict=True, reason="sliding 2 deg above the friction limit: the same creep adds to the "
                                              "slide, a small friction deficit is a large error (module note)")
#: outside the tolerances (module note; measured in docs/validation.md, contact)
KNOWN_LIMITS = [
    pytest.param("apic", "f64", 20, 1e6, "right", [(40, 45)], marks=_PULSES, id="apic-soft-thick-40-45"),  # 1.05 %
    pytest.param("mpm", "f64", 20, 1e8, "left", [(40, 45)], marks=_PULSES, id="mpm-stiff-thick-40-45"),  # 0.34 %
    pytest.param("apic", "f64", 5, 1e8, "bottom", [(38, 36)], marks=_NEAR, id="apic-stiff-5-slide-38-36"),  # +44 %
]

# Classic mpm where FLIP's slip and opening waves used to grow (before PIC at contact nodes; module
# note): high friction, stiff blocks, every thickness; each was outside the tolerances before
FLIP_ROWS = [
    ("mpm", "f32", 20, 1e8, "bottom", [(40, 30), (30, 20)]),  # were +26 %, +6.6 %
    ("mpm", "f64", 1, 1e8, "right", [(30, 20), (40, 30), (10, 20)]),  # were -6.9 %, +7.7 %, 0.23 % creep
    ("mpm", "f64", 5, 1e8, "left", [(40, 30)]),  # was +11 %
]


def _check(outcome, label):
    if outcome.slides:
        assert outcome.distance_m >= 20 * outcome.cell_m, label
        assert abs(outcome.error) < SLIDE_TOL, f"{label}: slid {outcome.distance_m:.4g} m, analytic {outcome.analytic_m:.4g} m"
    else:
        assert outcome.error < STICK_TOL, f"{label}: slipped {outcome.distance_m:.3g} m of {outcome.frictionless_m:.3g} m"


def _wall_cases(scheme, precision, thickness, youngs, side, angles, aspect=4.0, arch="cpu", scatter="serial"):
    runtime.acquire(arch, precision)
    try:
        scene = WallIncline(scheme, precision, thickness, youngs, side, scatter=scatter, aspect=aspect)
        for theta, delta in angles:
            _check(scene.run(theta, delta), f"{scheme} {precision} {thickness} cells E={youngs:g} {side} th={theta} d={delta}")
    finally:
        runtime.release()


def test_the_wall_rows_cover_every_pair_of_values():
    axes = list(zip(*[row[:5] for row in WALL_ROWS]))
    for a in range(5):
        for b in range(a + 1, 5):
            pairs = {(row[a], row[b]) for row in WALL_ROWS}
            assert pairs == {(u, v) for u in set(axes[a]) for v in set(axes[b])}, (a, b)
    assert set(axes[2]) == {1, 5, 20} and set(axes[3]) == {1e6, 1e8} and set(axes[4]) == {"bottom", "left", "right"}
    angles = [pair for row in WALL_ROWS for pair in row[5]]
    assert {t for t, _ in angles} == {10, 20, 30, 40} and {d for _, d in angles} >= {0, 10, 20, 30, 45}


@pytest.mark.parametrize("scheme, precision, thickness, youngs, side, angles", WALL_ROWS)
def test_a_block_at_rest_on_a_frictional_wall_slides_or_sticks_as_coulomb_says(scheme, precision, thickness,
                                                                               youngs, side, angles):
    _wall_cases(scheme, precision, thickness, youngs, side, angles)


#: Rows of the covering design run on a GPU (the atomic scatter, the GPU's only one).
GPU_ROWS = [
    ("mpm", "f32", 20, 1e8, "bottom", [(20, 10), (20, 30)]),
    ("apic", "f32", 1, 1e8, "bottom", [(30, 20), (10, 20)]),
    ("apic-affine", "f32", 20, 1e6, "left", [(30, 20), (20, 30)]),
    ("apic-affine", "f64", 5, 1e6, "bottom", [(40, 30), (40, 45)]),
]


@pytest.mark.gpu
@pytest.mark.skipif(not runtime.gpu_available(), reason="needs a GPU")
@pytest.mark.parametrize("scheme, precision, thickness, youngs, side, angles", GPU_ROWS)
def test_on_a_gpu_a_block_at_rest_on_a_frictional_wall_slides_or_sticks_as_coulomb_says(scheme, precision, thickness,
                                                                                        youngs, side, angles):
    _wall_cases(scheme, precision, thickness, youngs, side, angles, arch="gpu", scatter="atomic")


# A sheet sliding just above the friction limit, where a small friction deficit is a large error: the
# mirror walls' normal impulse brings its friction, through the wall column and with no pull (apic
# +1.3 % at 38/36). Measured without that friction (0.42 % less than mu N): +7.4 % at 38/36; with the
# friction at the ghost alone and a pull the friction does not see: apic +2.1 %
MIRROR_ROWS = [
    ("apic", "f64", 1, 1e8, "bottom", [(38, 36)]),
    ("mpm", "f32", 1, 1e8, "right", [(38, 36), (40, 35)]),
    # +4.1 % (+7.9 % before the mirror walls' friction) until friction was decided by wall column
    ("apic-affine", "f32", 1, 1e8, "left", [(38, 36)]),
]


@pytest.mark.parametrize("scheme, precision, thickness, youngs, side, angles", MIRROR_ROWS)
def test_a_sheet_just_above_the_friction_limit_feels_mu_n(scheme, precision, thickness, youngs, side, angles):
    _wall_cases(scheme, precision, thickness, youngs, side, angles)


@pytest.mark.parametrize("scheme, precision, thickness, youngs, side, angles", FLIP_ROWS)
def test_classic_mpm_holds_the_tolerances_where_friction_is_high(scheme, precision, thickness, youngs, side, angles):
    _wall_cases(scheme, precision, thickness, youngs, side, angles)


@pytest.mark.parametrize("scheme, precision, thickness, youngs, side, angles", KNOWN_LIMITS)
def test_known_limits_stay_outside_the_tolerances(scheme, precision, thickness, youngs, side,
                                                                  angles):
    _wall_cases(scheme, precision, thickness, youngs, side, angles)


# Shorter blocks (``aspect``: length / thickness; the scenes' blocks are 4x as long as thick and at
# least 40 cells): a 20-cell block twice as long as thick holds the tolerances away from the friction
# limit; at 40/45 deg its upslope part, unloaded by the weight's moment, slips (module note)
ASPECT_ROWS = [
    pytest.param("mpm", "f64", 20, 1e8, "bottom", [(20, 10), (20, 30)], id="mpm-stiff-thick-aspect2"),
    pytest.param("apic-affine", "f64", 20, 1e6, "bottom", [(40, 45)], id="affine-soft-thick-aspect2-40-45",
                 marks=pytest.mark.xfail(strict=True, reason="aspect 2 at 40/45 deg: 6.4 % (module note)")),
]


@pytest.mark.parametrize("scheme, precision, thickness, youngs, side, angles", ASPECT_ROWS)
def test_a_block_twice_as_long_as_thick(scheme, precision, thickness, youngs, side, angles):
    _wall_cases(scheme, precision, thickness, youngs, side, angles, aspect=2.0)


@pytest.mark.parametrize("angle_deg", [0.0, 20.0, 45.0, 70.0])
def test_structure_contact_nodes_are_those_whose_cell_reaches_into_it(angle_deg):
    """A half-plane below a line through (0.5, 0.5) m at ``angle_deg``: a node is a contact node exactly
    when its cell (one cell square) overlaps the half-plane, and its normal is the line's."""
    h = 0.1
    a = math.radians(angle_deg)
    n = np.array([-math.sin(a), math.cos(a)])  # outward, up
    t = np.array([math.cos(a), math.sin(a)])
    c = np.array([0.5, 0.5])
    polygon = [c - 20 * t, c + 20 * t, c + 20 * t - 20 * n, c - 20 * t - 20 * n]
    xs = ys = np.arange(11) * h
    index, normal = node_contacts([polygon], xs, ys, h)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    d = (np.stack([X, Y], -1) - c) @ n
    reach = 0.5 * h * (abs(n[0]) + abs(n[1]))
    expected = d < reach - 1e-9
    assert np.array_equal(index == 0, expected | (np.abs(d - reach) < 1e-9) & (index == 0))
    assert np.allclose(normal[expected], n, atol=1e-6)
    if angle_deg == 0.0:  # a surface on a node line: its nodes and those below, nothing above
        assert np.array_equal(index == 0, Y <= 0.5 + 1e-9)



@pytest.mark.parametrize("h", [0.02, 0.03, 0.05, 0.07, 0.1, 0.25])
def test_a_face_exactly_half_a_cell_from_a_node_line_covers_that_node_whichever_way_round_off_falls(h):
    """A face drawn half a cell from a node line (round numbers: a wall at x = 0.375 m with 3 cm
    cells) leaves the node's cell touching it; the signed distance lands a hair either side of half a
    cell by round-off, and where it fell outside, the node stayed free and the at-rest thrust on the
    face ratcheted up under mpm (1.07 at 0.5 s; tests/integration/test_project_thrust.py). Every
    such tie is a contact node, with the face's normal, for faces looking either way."""
    xs = np.arange(40) * h
    ys = np.array([10 * h])
    for k in range(3, 30):
        face = (k + 0.5) * h
        right = [(face, -h), (face + 5 * h, -h), (face + 5 * h, 30 * h), (face, 30 * h)]  # material at x < face
        index, normal = node_contacts([right], xs, ys, h)
        assert index[k, 0] == 0 and index[k - 1, 0] == -1, (h, k)
        np.testing.assert_allclose(normal[k, 0], (-1.0, 0.0), atol=1e-9)
        left = [(face - 5 * h, -h), (face, -h), (face, 30 * h), (face - 5 * h, 30 * h)]  # material at x > face
        index, normal = node_contacts([left], xs, ys, h)
        assert index[k + 1, 0] == 0 and index[k + 2, 0] == -1, (h, k)
        np.testing.assert_allclose(normal[k + 1, 0], (1.0, 0.0), atol=1e-9)


@pytest.mark.parametrize("reverse", [False, True])
def test_a_node_at_a_convex_corner_takes_the_normals_of_both_faces(reverse):
    """corner_normals: the node on a ramp's convex top vertex (its signed-distance normal the
    bisector), the node inside on the bisector of a square corner and the nodes whose cell holds a
    convex vertex off the node lines get the two faces' outward normals; nodes on one face, the
    concave foot, the middle of a wall two cells thick (as near to a third face) and the foot of a
    wall below the grid box keep theirs. Either orientation of the polygon."""
    h = 0.1
    xs = ys = np.arange(0.0, 2.0001, h)
    th = math.radians(40.0)
    up, down = np.array([0.0, 1.0]), np.array([math.sin(th), math.cos(th)])  # top face, ramp face

    def normals(polygon, box=None):
        polygon = polygon[::-1] if reverse else polygon
        index, normal = node_contacts([polygon], xs, ys, h)
        a, b = corner_normals([polygon], xs, ys, index, normal, h, box)
        at = lambda x, y: (round(x / h), round(y / h))  # noqa: E731
        return index, normal, a, b, at

    def pair(a, b, ij):
        return sorted([tuple(np.round(a[ij], 9)), tuple(np.round(b[ij], 9))])

    # a ramp: top face from (0, 1.5) to the vertex (0.5, 1.5), then down at 40 deg to the ground
    foot = np.array([0.5, 1.5]) + 1.4 * np.array([math.cos(th), -math.sin(th)])
    ramp = [(0.0, 1.5), (0.5, 1.5), tuple(foot), (foot[0], 0.0), (0.0, 0.0)]
    index, normal, a, b, at = normals(ramp)
    np.testing.assert_allclose(normal[at(0.5, 1.5)], (up + down) / np.linalg.norm(up + down), atol=1e-6)
    assert pair(a, b, at(0.5, 1.5)) == pair(np.array([up]), np.array([down]), 0)
    for x, y in ((0.3, 1.5), (0.7, 1.4), (0.8, 1.2), (0.5, 1.4)):  # on or next to one face
        assert index[at(x, y)] == 0
        np.testing.assert_array_equal(a[at(x, y)], normal[at(x, y)])
        np.testing.assert_array_equal(b[at(x, y)], normal[at(x, y)])
    # a square block: the inside node on a corner's bisector, and a vertex off the node lines
    index, normal, a, b, at = normals([(0.5, 0.5), (1.5, 0.5), (1.5, 1.5), (0.5, 1.5)])
    assert pair(a, b, at(1.4, 1.4)) == [(0.0, 1.0), (1.0, 0.0)]
    index, normal, a, b, at = normals([(0.52, 0.52), (1.52, 0.52), (1.52, 1.53), (0.52, 1.53)])
    assert pair(a, b, at(1.5, 1.5)) == [(0.0, 1.0), (1.0, 0.0)]
    np.testing.assert_array_equal(a[at(1.0, 1.5)], b[at(1.0, 1.5)])
    # a wall two cells thick: the node one cell below the middle of its top is as near to three faces
    index, normal, a, b, at = normals([(0.4, 0.0), (0.6, 0.0), (0.6, 0.8), (0.4, 0.8)])
    np.testing.assert_array_equal(a[at(0.5, 0.7)], b[at(0.5, 0.7)])
    # a wall from one cell below the grid's bottom (y = 0.1): its foot's corners are not the material's
    index, normal, a, b, at = normals([(0.4, 0.0), (0.6, 0.0), (0.6, 0.8), (0.4, 0.8)], ((0.0, 0.1), (2.0, 2.0)))
    np.testing.assert_array_equal(a[at(0.4, 0.0)], b[at(0.4, 0.0)])
    assert pair(a, b, at(0.4, 0.8)) == [(-1.0, 0.0), (0.0, 1.0)]
    # a V-shaped valley: its concave corner keeps the gradient's normal
    index, normal, a, b, at = normals([(0.0, 0.0), (2.0, 0.0), (2.0, 1.5), (1.0, 0.5), (0.0, 1.5)])
    np.testing.assert_array_equal(a[at(1.0, 0.5)], b[at(1.0, 0.5)])

# (scheme, precision, thickness cells, E Pa, ramp angle deg, [(friction deg, slides), ...])
RAMP_CASES = [
    ("apic-affine", "f64", 5, 1e6, 30, [(20, True), (40, False)]),
    ("apic", "f32", 1, 1e8, 40, [(30, True), (45, False)]),
    ("mpm", "f64", 20, 1e6, 20, [(10, True), (30, False)]),
    ("mpm", "f32", 20, 1e8, 40, [(30, True)]),  # was +28 % (FLIP, before PIC at contact nodes)
]


@pytest.mark.parametrize("scheme, precision, thickness, youngs, theta, cases", RAMP_CASES)
def test_a_block_on_an_inclined_structure_slides_or_sticks_as_coulomb_says(scheme, precision, thickness, youngs,
                                                                           theta, cases):
    runtime.acquire("cpu", precision)
    try:
        scene = RampIncline(scheme, precision, thickness, youngs, theta)
        for delta, slides in cases:
            outcome = scene.run(delta)
            assert outcome.slides == slides
            _check(outcome, f"ramp {scheme} {precision} {thickness} cells E={youngs:g} th={theta} d={delta}")
            # never inside the ramp
            x = scene.engine.x.to_numpy().astype(np.float64)
            assert signed_distance(x, scene.polygon).min() >= -1e-6 * scene.dx
    finally:
        runtime.release()


# ---------------------------------------------------------------------------- forces and momentum
SOFT = Material("soft", "linear-elastic", 1000.0, 2e6, 0.3)
WALL = ((0.6, 0.0), (0.7, 0.0), (0.7, 0.5), (0.6, 0.5))


def _box(scheme, precision, structures, velocity, duration=0.3, gravity=(1.5, -9.81)):
    dx = 0.02
    h = dx / 2
    X, Y = np.meshgrid(0.2 + (np.arange(20) + 0.5) * h, 0.05 + (np.arange(16) + 0.5) * h)
    pos = np.c_[X.ravel(), Y.ravel()]
    parts = Particles(pos, np.full(len(pos), h * h), np.zeros(len(pos), np.int32), np.tile(velocity, (len(pos), 1)))
    grid = Grid((0.0, 0.0), (1.0, 0.6), dx, left=Boundary("friction", math.radians(25)),
                right=Boundary("slip"), bottom=Boundary("friction", math.radians(30)), top=Boundary("fixed"))
    cfg = SimulationConfig(grid, (SOFT,), (Stage("move", "dynamic", duration_s=duration),), gravity,
                           Numerics(scheme=scheme, cfl=0.4, arch="cpu", precision=precision), Output(duration / 6),
                           structures)
    return cfg, parts


@pytest.mark.parametrize("scheme, precision", [("mpm", "f64"), ("apic", "f32"), ("apic-affine", "f64")])
def test_the_impulse_on_the_contacts_is_the_change_of_momentum_less_gravity(scheme, precision):
    structures = (Structure("barrier", WALL, Boundary("friction", math.radians(20))),)
    gravity = (1.5, -9.81)
    cfg, parts = _box(scheme, precision, structures, (3.0, -1.0), gravity=gravity)
    with Simulation(cfg, parts) as sim:
        frames = list(sim.run())
    mass = frames[0].diagnostics.total_mass_kg_per_m
    p0 = np.array([frames[0].diagnostics.momentum_x, frames[0].diagnostics.momentum_y])
    p1 = np.array([frames[-1].diagnostics.momentum_x, frames[-1].diagnostics.momentum_y])
    t = frames[-1].diagnostics.time_s
    on_contacts = np.zeros(2)
    for prev, frame in zip(frames, frames[1:]):
        interval = frame.diagnostics.time_s - prev.diagnostics.time_s
        for c in frame.contacts:
            on_contacts += interval * np.array([c.force_x_N_per_m, c.force_y_N_per_m])
    names = {c.contact for c in frames[-1].contacts}
    assert names == {"left", "right", "bottom", "top", "barrier"}
    # the material's momentum changes by gravity's impulse less the impulse it gives the contacts
    expected = p1 - p0 - mass * np.asarray(gravity) * t
    assert np.linalg.norm(-on_contacts - expected) < 0.02 * np.linalg.norm(expected)
    # the barrier was hit: a peak force at least the mean
    barrier = [c for f in frames for c in f.contacts if c.contact == "barrier"]
    assert max(c.peak_force_N_per_m for c in barrier) > 0
    for c in barrier:
        assert c.peak_force_N_per_m >= math.hypot(c.force_x_N_per_m, c.force_y_N_per_m) * (1 - 1e-9)


@pytest.mark.parametrize("scheme", ["mpm", "apic-affine"])
def test_an_elastic_column_at_rest_pushes_on_a_vertical_structure_with_the_at_rest_thrust(scheme):
    # elastic column under gravity loading, confined by frictionless contacts: uniaxial strain, so the
    # lateral stress is K0 sigma_v with K0 = nu / (1 - nu) (no yield: Jaky's 1 - sin(phi) is an
    # empirical rule for normally consolidated soil, not what this material does)
    rho, nu, height, dx = 1800.0, 0.25, 1.0, 0.05
    mat = Material("column", "linear-elastic", rho, 5e6, nu)
    h = dx / 2
    X, Y = np.meshgrid((np.arange(8) + 0.5) * h, (np.arange(40) + 0.5) * h)
    pos = np.c_[X.ravel(), Y.ravel()]
    parts = Particles(pos, np.full(len(pos), h * h), np.zeros(len(pos), np.int32))
    wall = Structure("retaining wall", ((0.2, -0.1), (0.35, -0.1), (0.35, 1.5), (0.2, 1.5)), Boundary("slip"))
    grid = Grid((0.0, 0.0), (0.5, 1.4), dx, left=Boundary("slip"), right=Boundary("slip"),
                bottom=Boundary("slip"), top=Boundary("open"))
    # settled with local damping, then read over an undamped interval: while Cundall's damping acts
    # it carries part of the load (its force is |f|-sized even at tiny speeds), so the contacts
    # would not balance the weight
    stages = (Stage("settle", "gravity", duration_s=0.6, damping=0.7), Stage("rest", "dynamic", duration_s=0.1))
    cfg = SimulationConfig(grid, (mat,), stages, (0.0, -9.81),
                           Numerics(scheme=scheme, cfl=0.5, arch="cpu", precision="f64"), Output(0.1), (wall,))
    with Simulation(cfg, parts) as sim:
        frames = list(sim.run())
    forces = {c.contact: c for c in frames[-1].contacts}
    force = forces["retaining wall"]
    weight = rho * 9.81 * 0.2 * height
    assert -forces["bottom"].force_y_N_per_m == pytest.approx(weight, rel=0.02)  # at rest: the base holds it
    k0 = nu / (1 - nu)
    thrust = 0.5 * k0 * rho * 9.81 * height ** 2
    assert force.force_x_N_per_m == pytest.approx(thrust, rel=0.05)
    assert abs(force.force_y_N_per_m) < 0.05 * thrust  # frictionless: no shear


def thrown_block_frames(scheme, precision, structures, duration_s, interval_s):
    """The frames of the block of :func:`_box` thrown along +x at 0.9 of the guard's speed bound
    (the bound itself is computed from the block at rest: v0 does not raise it here) towards the
    ``structures``, with the guard removing what outruns it."""
    from solver.simulation import Simulation

    cfg, parts = _box(scheme, precision, structures, (0.0, 0.0), duration=duration_s)
    with Simulation(cfg, parts) as sim:
        speed = 0.9 * sim.speed_bound_m_s / math.sqrt(2)
    fast = Particles(parts.positions_m, parts.volumes_m2, parts.material_ids, np.tile([speed, 0.0], (len(parts), 1)))
    cfg = SimulationConfig(cfg.grid, cfg.materials, cfg.stages, cfg.gravity_m_s2,
                           Numerics(scheme=scheme, cfl=0.4, arch="cpu", precision=precision, guard="remove"),
                           Output(interval_s), structures)
    with Simulation(cfg, fast) as sim:
        return list(sim.run())


@pytest.mark.parametrize("scheme, precision", [("mpm", "f32"), ("apic", "f64"), ("apic-affine", "f32")])
def test_a_block_thrown_at_a_structure_never_ends_inside_it(scheme, precision):
    polygon = ((0.6, 0.0), (0.75, 0.0), (0.68, 0.45))  # inclined faces, a sharp top
    structures = (Structure("dam", polygon, Boundary("friction", math.radians(30))),)
    frames = thrown_block_frames(scheme, precision, structures, 0.25, 0.01)
    mass0 = frames[0].diagnostics.total_mass_kg_per_m
    for f in frames:
        act = f.fields["active"]
        assert act.all()
        assert f.diagnostics.total_mass_kg_per_m == pytest.approx(mass0, rel=1e-5)
        sd = signed_distance(f.fields["positions"].astype(np.float64), polygon)
        assert sd.min() >= -1e-6, f"a particle {-sd.min():.3g} m inside the structure at t = {f.diagnostics.time_s}"
    assert max(c.peak_force_N_per_m for f in frames for c in f.contacts if c.contact == "dam") > 0


# ---------------------------------------------------------------------------- classic mpm at contacts
def _weights(x_m, origin, dx, pad):
    """Base node and the 3 x 3 quadratic B-spline weights of each particle (as the engine's stencil)."""
    X = (x_m - origin) / dx + pad
    base = np.floor(X - 0.5).astype(int)
    f = X - base
    w = np.stack([0.5 * (1.5 - f) ** 2, 0.75 - (f - 1.0) ** 2, 0.5 * (f - 0.5) ** 2], axis=1)  # (n, 3, 2)
    return base, w[:, :, 0][:, :, None] * w[:, :, 1][:, None, :]


@pytest.mark.parametrize("side", ["bottom", "left", "structure"])
def test_classic_mpm_is_flip_away_from_contacts_and_pic_at_contact_nodes(side):
    """One mpm step of particles with scattered velocities: a particle whose stencil reaches no contact
    node takes FLIP's increment exactly, ``v_p + sum w (v_new - v_old)``; one that reaches contact nodes
    takes their new velocity itself, ``sum_(not contact) w (v_p + v_new - v_old) + sum_(contact) w v_new``."""
    from solver.engine import PAD, Engine

    runtime.acquire("cpu", "f64")
    try:
        dx = 0.1
        rng = np.random.default_rng(7)
        h = dx / 2
        X, Y = np.meshgrid(0.1 + (np.arange(24) + 0.5) * h, (np.arange(10) + 0.5) * h)
        pos = np.c_[X.ravel(), Y.ravel()]
        structures = ()
        sides = dict(left=Boundary("open"), right=Boundary("open"), bottom=Boundary("open"), top=Boundary("open"))
        if side == "structure":  # a block standing on a slab structure, its surface 0.3 m up
            pos = pos + [0.0, 0.3]
            structures = (Structure("slab", ((-1.0, -1.0), (3.0, -1.0), (3.0, 0.3), (-1.0, 0.3)),
                                    Boundary("friction", math.radians(30))),)
        elif side == "left":
            pos = pos[:, ::-1] + [0.0, 0.1]
            sides["left"] = Boundary("friction", math.radians(30))
        else:
            sides["bottom"] = Boundary("friction", math.radians(30))
        grid = Grid((0.0, 0.0), (2.0, 2.0), dx, **sides)
        e = Engine(grid, (SOFT,), len(pos), "mpm", np.float64, scatter="serial", structures=structures)
        e.load_particles(pos, np.full(len(pos), h * h), np.zeros(len(pos), np.int32))
        v0 = rng.normal(0.0, 0.5, (len(pos), 2)) + [0.3, -1.0 if side != "left" else 0.0]
        e.set_velocity(v0)
        e.step(1e-4, (0.0, -9.81))
        v1 = e.v.to_numpy()
        g_new = e.g_mom.to_numpy()
        g_old = e.g_v_old.to_numpy()
        held = (e.contact.node_struct.to_numpy() >= 0) if structures else np.zeros(g_new.shape[:2], bool)
        if side == "bottom":
            held[:, :PAD + 1] = True
        elif side == "left":
            held[:PAD + 1, :] = True
        base, w = _weights(pos, np.zeros(2), dx, PAD)
        expected = np.empty_like(v0)
        touched = np.zeros(len(pos), bool)
        for p in range(len(pos)):
            I = np.s_[base[p, 0]:base[p, 0] + 3, base[p, 1]:base[p, 1] + 3]
            wp, c = w[p][..., None], held[I][..., None]
            expected[p] = (wp * np.where(c, g_new[I], v0[p] + g_new[I] - g_old[I])).sum(axis=(0, 1))
            touched[p] = c.any()
        assert 0 < touched.sum() < len(pos)
        assert np.allclose(v1, expected, rtol=0, atol=1e-9)
        # FLIP's increment alone would leave the particles next to the contact their own velocity
        flip = v0.copy()
        for p in np.flatnonzero(touched):
            I = np.s_[base[p, 0]:base[p, 0] + 3, base[p, 1]:base[p, 1] + 3]
            flip[p] += (w[p][..., None] * (g_new[I] - g_old[I])).sum(axis=(0, 1))
        assert np.abs(v1 - flip)[touched].max() > 0.1
    finally:
        runtime.release()


def test_the_nodes_near_a_convex_vertex_form_its_zone():
    """corner_zone: the contact nodes within 2 cells of a ramp's convex top vertex along both axes
    (the level top's nodes one and two cells back included), none near the concave foot or far
    along a face, none beyond the grid box; the particle box reaches 1.5 cells past the zone."""
    h = 0.1
    xs = ys = np.arange(0.0, 2.0001, h)
    th = math.radians(40.0)
    foot = np.array([0.5, 1.5]) + 1.8 / math.sin(th) * np.array([math.cos(th), -math.sin(th)])  # below the box
    ramp = [(-0.3, 1.5), (0.5, 1.5), tuple(foot), (-0.3, foot[1])]  # one convex vertex in the box
    index, normal = node_contacts([ramp], xs, ys, h)
    zone, boxes = corner_zone([ramp], xs, ys, index, normal, h, ((0.0, 0.0), (2.0, 2.0)))
    at = lambda x, y: (round(x / h), round(y / h))  # noqa: E731
    for x, y in ((0.5, 1.5), (0.4, 1.5), (0.3, 1.5), (0.6, 1.4), (0.5, 1.4)):
        assert zone[at(x, y)] == 1, (x, y)
    for x, y in ((0.2, 1.5), (0.5, 1.6), (1.2, 0.9)):  # 3 cells back, off the structure, down the face
        assert zone[at(x, y)] == 0, (x, y)
    assert np.all(zone[index < 0] == 0)
    np.testing.assert_allclose(boxes[0], [0.3 - 0.15, 1.3 - 0.15, 0.7 + 0.15, 1.5 + 0.15], atol=1e-9)
    # a platform through the grid's bottom: its foot's corners are beyond the box, no zone there
    platform = [(0.0, -0.3), (1.0, -0.3), (1.0, 0.5), (0.0, 0.5)]
    index, normal = node_contacts([platform], xs, ys, h)
    zone, boxes = corner_zone([platform], xs, ys, index, normal, h, ((0.0, 0.0), (2.0, 2.0)))
    assert zone[at(1.0, 0.5)] == 1 and zone[at(1.0, 0.3)] == 1 and zone[at(1.0, 0.2)] == 0
    assert zone[at(0.0, 0.5)] == 1  # its top-left corner is on the box's side, still a corner
