"""A body sliding on a curved structure follows the rigid body's motion: inclined and curved
surfaces work, not only axis-aligned ones.

A sector of an annulus (3 cells thick, 10 deg wide) lies on a circular surface of radius R drawn as a
polygon of 1-degree chords: inside a bowl (concave, R = 1 m) or on top of a hump (convex, R = 0.8 m).
Sliding on a circle, a rigid sector turns about the circle's centre O, so its angle ``theta`` from
the bottom (bowl) or top (hump) obeys, per unit mass (I / M = (R^2 + r^2) / 2 about O, r the
sector's other radius; r_cm its centroid's distance from O; N the normal force of the surface):

    I/M theta'' = -+ g r_cm sin(theta) - mu R N sign(theta'),   N = g cos(theta) +- r_cm theta'^2

(upper signs for the bowl), with Coulomb's stick where the friction can cancel the turn. This is
integrated with small steps (:func:`_rigid_angles`; treating the normal forces spread over the 10
degrees as one changes N by 0.4 %). The project's centroid angle must follow it within
ANGLE_TOL_DEG over the whole run: the bowl's swing from 40 deg to its first turning point (to
-40 deg frictionless, 13-23 deg held by friction of 25-30 deg), the hump's slide from 20 deg until
the rigid sector leaves the surface (N = 0, near 50 deg). The hump starts well away from its top:
there the motion leaves an unstable equilibrium, and a start 0.1 deg off grows 7-fold in 0.8 s.
Measured (2 cm cells): in the bowl 0.25-0.57 deg in apic and apic-affine, f32 and
f64, E = 1e6 and 1e7 Pa, friction 0-30 deg; on the hump 0.50 deg (apic-affine, 1e7 Pa,
frictionless). The same curve drawn clockwise or anticlockwise gives the same run (docs/solver.md
on convex vertices). The suite runs the frictionless hump (apic-affine, f32, 1e7 Pa) and the bowl
with 15 deg of friction (apic, f64, 1e6 Pa); ``RUNOUT_FULL_MATRIX=1`` every case.

Classic mpm is not in this matrix: its particles next to a contact take the contact nodes'
velocity as PIC does (docs/solver.md), which damps the sector's turn (its velocity varies across
its thickness as it rounds the curve): frictionless in the bowl it turned at -31 deg instead of
-40 (39 % of its energy lost in one swing), on the hump it lagged 10 deg after 0.8 s. That case
is a strict xfail with those figures.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from projects.document import loads_project
from projects.results import open_results
from projects.runner import run_project
from solver.structures import signed_distance

# the suite runs a covering sample of each matrix below (tests/conftest.py, RUNOUT_FULL_MATRIX)
pytestmark = pytest.mark.matrix

G = 9.81
CELL = 0.02
THICK = 3 * CELL
SPAN_DEG = 10.0
ANGLE_TOL_DEG = 1.0
SHAPES = {  # centre of the circle, radius, sign (+1: bowl, material inside the circle; -1: hump)
    "bowl": ((1.0, 1.1), 1.0, 1.0),
    "hump": ((1.0, 0.0), 0.8, -1.0),
}


def _point(shape, radius, deg):
    (cx, cy), _, sign = SHAPES[shape]
    a = math.radians(deg)
    return (cx + radius * math.sin(a), cy - sign * radius * math.cos(a))


def _project(shape, scheme, precision, youngs, friction_deg, start_deg, duration):
    _, R, sign = SHAPES[shape]
    surface = [_point(shape, R, a) for a in np.linspace(-75.0, 75.0, 151)]
    structure = surface + [(surface[-1][0], 0.0), (surface[0][0], 0.0)]
    other = R - sign * THICK
    lo, hi = start_deg - SPAN_DEG / 2, start_deg + SPAN_DEG / 2
    body = ([_point(shape, R, a) for a in np.linspace(lo, hi, 12)]
            + [_point(shape, other, a) for a in np.linspace(hi, lo, 12)])
    contact = '"slip"' if friction_deg == 0 else '{ type = "friction", friction_angle_deg = %g }' % friction_deg
    text = f"""
[runout]
schema_version = 1
[domain]
size_m = [2.0, 1.2]
cell_size_m = {CELL}
[domain.boundaries]
left = "slip"
right = "slip"
bottom = "slip"
top = "open"
[materials.block]
model = "linear-elastic"
density_kg_m3 = 2000
youngs_modulus_pa = {youngs}
poisson_ratio = 0.3
[[bodies]]
name = "sector"
material = "block"
polygon_m = {json.dumps([list(p) for p in body])}
[[structures]]
name = "{shape}"
polygon_m = {json.dumps([list(p) for p in structure])}
contact = {contact}
[particles]
per_cell = 2
[numerics]
scheme = "{scheme}"
precision = "{precision}"
arch = "cpu"
[[stages]]
type = "dynamic"
duration_s = {duration}
[output]
interval_s = 0.02
fields = ["displacement"]
"""
    return loads_project(text), structure


def _rigid_angles(shape, friction_deg, start_deg, times, dt=2e-5):
    """The rigid sector's angle (deg) at ``times`` and whether it still presses on the surface,
    by semi-implicit Euler steps with Coulomb's stick (converged: halving dt moves it < 0.01 deg)."""
    _, R, sign = SHAPES[shape]
    r = R - sign * THICK
    half = math.radians(SPAN_DEG / 2)
    r_cm = (2.0 / 3.0) * abs(R ** 3 - r ** 3) / abs(R ** 2 - r ** 2) * math.sin(half) / half
    inertia = (R ** 2 + r ** 2) / 2.0
    mu = math.tan(math.radians(friction_deg))
    theta, omega, t = math.radians(start_deg), 0.0, 0.0
    angles, pressing = [], []
    on = True
    for target in times:
        while t < target - 1e-12:
            normal = G * math.cos(theta) + sign * r_cm * omega ** 2
            on = on and normal > 0.0
            trial = omega - sign * dt * G * r_cm * math.sin(theta) / inertia
            grip = dt * mu * R * max(normal, 0.0) / inertia
            omega = 0.0 if abs(trial) <= grip else trial - math.copysign(grip, trial)
            theta += dt * omega
            t += dt
        angles.append(math.degrees(theta))
        pressing.append(on)
    return np.array(angles), np.array(pressing)


CASES = [
    # shape, scheme, precision, E (Pa), friction (deg), start (deg), duration (s); the suite's
    # covering sample is the first two (both shapes, schemes, precisions and stiffnesses, with and
    # without friction)
    ("hump", "apic-affine", "f32", 1e7, 0.0, 20.0, 0.5),
    ("bowl", "apic", "f64", 1e6, 15.0, 40.0, 1.1),
    ("bowl", "apic-affine", "f32", 1e6, 0.0, 40.0, 1.1),
    ("bowl", "apic-affine", "f64", 1e7, 30.0, 40.0, 1.1),
    ("bowl", "apic", "f32", 1e6, 25.0, 40.0, 1.1),
    ("hump", "apic", "f32", 1e6, 10.0, 20.0, 0.65),
    pytest.param("bowl", "mpm", "f32", 1e6, 0.0, 40.0, 1.1, marks=pytest.mark.xfail(
        strict=True, reason="classic mpm's PIC at contact nodes damps the turn: -31 deg for -40 (module note)")),
]


@pytest.mark.matrix(sample=2)
@pytest.mark.parametrize("shape, scheme, precision, youngs, friction, start, duration", CASES)
def test_a_sector_sliding_on_a_curved_structure_moves_as_the_rigid_sector(tmp_path, shape, scheme, precision, youngs,
                                                                         friction, start, duration):
    project, structure = _project(shape, scheme, precision, youngs, friction, start, duration)
    result = run_project(project, tmp_path / "r")
    assert result.status == "completed", result.message
    results = open_results(tmp_path / "r")
    (cx, cy), _, sign = SHAPES[shape]
    angles = []
    for i in range(len(results.times)):
        points = results.frame(i, ["positions"])["positions"][:, :2].astype(float)
        assert signed_distance(points, structure).min() >= -1e-6, f"frame {i}: a particle inside the {shape}"
        x, y = points.mean(axis=0)
        angles.append(math.degrees(math.atan2(x - cx, -sign * (y - cy))))
    times = np.asarray(results.times, float) - float(results.times[0])
    rigid, pressing = _rigid_angles(shape, friction, start, times)
    # the particles' plain mean is not the sector's centroid (the lattice clipped at its curved
    # outline gives the parts there smaller masses): a fixed angle off while it moves as a body
    angles = np.array(angles) - (angles[0] - start)
    assert abs(rigid[pressing][-1] - start) > 10.0  # the case moves (a check that can fail)
    error = np.abs(angles - rigid)[pressing]
    assert error.max() <= ANGLE_TOL_DEG, (f"{shape}: {error.max():.2f} deg off the rigid sector "
                                          f"(at {times[pressing][error.argmax()]:.2f} s)")


def test_a_curved_structure_drawn_either_way_round_gives_the_same_run(tmp_path):
    """The engine orders a convex vertex's two faces as the polygon lists them; the run must not
    depend on that. The stiff sector on the hump after 0.3 s: the two runs agree to f32 round-off
    (a face chosen by listing order where the material lies within 0.8 deg of both would put them
    2.3 mm apart)."""
    import tomllib

    from projects.schema import validate_project

    project, _ = _project("hump", "apic-affine", "f32", 1e7, 0.0, 20.0, 0.3)
    run_project(project, tmp_path / "drawn")
    document = tomllib.loads((tmp_path / "drawn" / "project.toml").read_text())
    document["structures"][0]["polygon_m"] = document["structures"][0]["polygon_m"][::-1]
    run_project(validate_project(document), tmp_path / "reversed")
    drawn = open_results(tmp_path / "drawn").frame(-1, ["positions"])["positions"]
    reversed_ = open_results(tmp_path / "reversed").frame(-1, ["positions"])["positions"]
    moved = np.abs(drawn - open_results(tmp_path / "drawn").frame(0, ["positions"])["positions"]).max()
    assert moved > 0.05  # it slid
    assert np.abs(drawn - reversed_).max() < 1e-5
