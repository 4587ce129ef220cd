"""Granular and elastic blocks thrown, dropped and sliding onto structures, through the project path
(the stress test of contacts, docs/validation.md "Extremes").

Each scene is a closed box (slip sides and top, fixed bottom) with `[[structures]]` in the flow
path: a wall one cell thick with faces a quarter cell off the node lines hit at 6 m/s, a platform
floating above the floor that a block is dropped on at 6 m/s, a barrier leaning over the flow hit
from below, a frictional ramp into a wall at its foot, a sand column collapsing against a wall.
Checks per run, all exact statements about a closed scene:

- it completes with every particle (none lost, none removed by the guard, the mass unchanged);
- no particle is inside a structure in any frame (`solver.structures.signed_distance`);
- impulse balance: the impulse recorded on every contact in `contacts.csv` (mean force times
  interval) equals the material's change of momentum less gravity's impulse, within 2 %;
- no energy gained: kinetic plus potential energy at the end at most the start's;
- for the thrown and dropped blocks, the structure's peak force lies between half the
  `rho v^2 h` of a flow of thickness h (the dynamic pressure on the face it hits) and the
  impedance bound `rho c_p v h` (a 1D impact on a rigid face: c_p the P-wave speed,
  `sqrt(E (1 - nu) / ((1 + nu)(1 - 2 nu)) / rho)`), which no impact of speed v can exceed.

The matrix these come from (65 runs over the three schemes, f32/f64, slip/fixed/friction
contacts, 2 and 3 particles per cell, cfl 0.3-0.7, phi 25-40 deg, c 0-500 Pa, elastic E 1e6-1e7)
all passed; the measured figures are in docs/validation.md.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from projects.document import loads_project
from projects.runner import run_project
from tests.scene_checks import check_kept_balanced_and_outside

G = 9.81
RHO = 2000.0
E = 1.0e6
NU = 0.3
SLIP, FIXED = '"slip"', '"fixed"'


def _friction(angle):
    return '{ type = "friction", friction_angle_deg = %s }' % angle


# slope of the ramp scene: from (0, 0.46) down to (0.8, 0), about 30 deg
_T = (0.8 / math.hypot(0.8, 0.46), -0.46 / math.hypot(0.8, 0.46))
_N = (-_T[1], _T[0])


def _on_ramp(s, h):
    return [round(s * _T[0] + h * _N[0], 5), round(0.46 + s * _T[1] + h * _N[1], 5)]


BLOCK = [[0.2, 0.02], [0.36, 0.02], [0.36, 0.14], [0.2, 0.14]]  # 0.16 x 0.12 m
SCENES = {
    # name: size, body, initial velocity, structures, duration, (speed, face width h) for the peak check
    "thin wall": ((1.0, 0.5), BLOCK, (6.0, 0.0),
                  [("barrier", [[0.705, 0.0], [0.725, 0.0], [0.725, 0.3], [0.705, 0.3]], SLIP)], 0.5, (6.0, 0.12)),
    "platform": ((1.0, 0.5), [[0.42, 0.3], [0.58, 0.3], [0.58, 0.42], [0.42, 0.42]], (0.0, -6.0),
                 [("platform", [[0.3, 0.2], [0.7, 0.2], [0.7, 0.26], [0.3, 0.26]], _friction(30))], 0.5, (6.0, 0.16)),
    "overhang": ((1.0, 0.5), BLOCK, (5.0, 3.0),
                 [("barrier", [[0.70, 0.0], [0.76, 0.0], [0.62, 0.3], [0.56, 0.3]], _friction(35))], 0.5, None),
    "ramp": ((1.2, 0.6), [_on_ramp(0.45, 0.005), _on_ramp(0.7, 0.005), _on_ramp(0.7, 0.085), _on_ramp(0.45, 0.085)],
             (3.0 * _T[0], 3.0 * _T[1]),
             [("ramp", [[0.0, 0.0], [0.8, 0.0], [0.0, 0.46]], _friction(20)),
              ("wall", [[0.8, 0.0], [0.86, 0.0], [0.86, 0.3], [0.8, 0.3]], _friction(30))], 0.8, None),
    "dam break": ((1.0, 0.5), [[0.0, 0.0], [0.16, 0.0], [0.16, 0.4], [0.0, 0.4]], (0.0, 0.0),
                  [("wall", [[0.36, 0.0], [0.42, 0.0], [0.42, 0.2], [0.36, 0.2]], FIXED)], 0.8, None),
}


def _project(scene, scheme, precision, ppc, cfl, phi, cohesion):
    size, body, velocity, structures, duration, _ = SCENES[scene]
    text = f"""
[runout]
schema_version = 1
[domain]
size_m = {json.dumps(list(size))}
cell_size_m = 0.02
[domain.boundaries]
left = "slip"
right = "slip"
bottom = "fixed"
top = "slip"
[materials.sand]
model = "drucker-prager"
density_kg_m3 = {RHO}
youngs_modulus_pa = {E}
poisson_ratio = {NU}
cohesion_pa = {cohesion}
friction_angle_deg = {phi}
[[bodies]]
name = "block"
material = "sand"
polygon_m = {json.dumps(body)}
initial_velocity_m_s = [{velocity[0]}, {velocity[1]}]
[particles]
per_cell = {ppc}
[numerics]
scheme = "{scheme}"
precision = "{precision}"
cfl = {cfl}
arch = "cpu"
[[stages]]
type = "dynamic"
duration_s = {duration}
[output]
interval_s = 0.025
fields = ["displacement", "velocity"]
"""
    for name, polygon, contact in structures:
        text += f'[[structures]]\nname = "{name}"\npolygon_m = {json.dumps(polygon)}\ncontact = {contact}\n'
    return loads_project(text)


CASES = [
    # scene, scheme, precision, particles per cell, cfl, phi, cohesion; two engines (apic-affine f32,
    # apic f32) and one mpm f64 so that the file compiles three
    ("thin wall", "apic-affine", "f32", 2, 0.7, 30.0, 0.0),
    ("dam break", "apic-affine", "f32", 2, 0.5, 25.0, 0.0),
    ("platform", "apic", "f32", 2, 0.5, 30.0, 0.0),
    ("overhang", "apic", "f32", 2, 0.5, 25.0, 0.0),
    ("ramp", "mpm", "f64", 2, 0.5, 40.0, 100.0),
]


@pytest.mark.parametrize("scene, scheme, precision, ppc, cfl, phi, cohesion", CASES)
def test_material_hitting_structures_keeps_out_of_them_and_balances_momentum(tmp_path, scene, scheme, precision,
                                                                            ppc, cfl, phi, cohesion):
    result = run_project(_project(scene, scheme, precision, ppc, cfl, phi, cohesion), tmp_path / "r")
    assert result.status == "completed", result.message
    _, _, _, structures, _, impact = SCENES[scene]
    contacts = check_kept_balanced_and_outside(tmp_path / "r", {name: polygon for name, polygon, _ in structures})
    for name, _, _ in structures:
        assert np.abs(contacts[name]["force_x_N_per_m"]).max() + np.abs(contacts[name]["force_y_N_per_m"]).max() > 0
    if impact is not None:
        speed, h = impact
        name = structures[0][0]
        peak = json.loads((tmp_path / "r" / "summary.json").read_text())["contacts"][name]["peak_force_N_per_m"]
        c_p = math.sqrt(E * (1 - NU) / ((1 + NU) * (1 - 2 * NU)) / RHO)
        assert 0.5 * RHO * speed ** 2 * h <= peak <= RHO * c_p * speed * h, (peak, RHO * speed ** 2 * h)
