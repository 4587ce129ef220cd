"""A cohesionless block dropped or thrown onto the floor lands, throws a few grains up and comes to
rest, in every scheme (the matrix in docs/validation.md, "Extremes").

The grains thrown up are stress free at the Drucker-Prager cone's apex and, by eq 24, kept
expanding (53 times their volume); landing again they were that much stiffer per mass than the
time step allows. The particle density now stops at half the material's (docs/solver.md). Checks
per run: it completes with every particle (none lost, none removed by the guard), inside the box,
and with no energy gained: kinetic plus potential energy at the end at most the start's (the
landing dissipates most of it; a blown-up run gains orders of magnitude).
"""

from __future__ import annotations

import numpy as np
import pytest

from projects.document import loads_project
from projects.results import open_results
from projects.runner import run_project

G = 9.81
DROP = """
[runout]
schema_version = 1
[domain]
size_m = [1.0, 0.8]
cell_size_m = 0.02
[domain.boundaries]
left = "slip"
right = "slip"
bottom = "fixed"
top = "slip"
[materials.sand]
model = "drucker-prager"
density_kg_m3 = 2000.0
youngs_modulus_pa = 1.0e6
poisson_ratio = 0.3
cohesion_pa = 0.0
friction_angle_deg = 30.0
[[bodies]]
name = "block"
material = "sand"
polygon_m = [[0.3, 0.5], [0.7, 0.5], [0.7, 0.7], [0.3, 0.7]]
initial_velocity_m_s = [0.0, {vy}]
[particles]
per_cell = {ppc}
[numerics]
scheme = "{scheme}"
precision = "{precision}"
cfl = 0.5
arch = "cpu"
[[stages]]
type = "dynamic"
duration_s = {duration}
[output]
interval_s = {duration}
fields = ["displacement", "velocity"]
"""


@pytest.mark.parametrize("scheme, precision, ppc, vy, duration", [
    ("apic-affine", "f32", 2, -3.0, 0.5),  # guard at 0.40 s before
    ("apic-affine", "f64", 3, 0.0, 0.75),  # NaN at 0.67 s before
    ("apic", "f32", 2, -3.0, 0.7),  # guard at 0.64 s before
    ("mpm", "f64", 2, -3.0, 0.7),  # completed before too
])
def test_a_granular_block_dropped_or_thrown_onto_the_floor_lands_and_comes_to_rest(tmp_path, scheme, precision, ppc,
                                                                                 vy, duration):
    project = loads_project(DROP.format(scheme=scheme, precision=precision, ppc=ppc, vy=vy, duration=duration))
    result = run_project(project, tmp_path / "r")
    assert result.status == "completed", result.message
    results = open_results(tmp_path / "r")
    assert results.series["lost_particles"].max() == 0, "lost"
    assert results.series["unstable_particles"].max() == 0, "unstable"
    first, last = results.frame(0), results.frame(-1)
    y0, y1 = first["positions"][:, 1], last["positions"][:, 1]
    v0, v1 = first["velocity"][:, :2], last["velocity"][:, :2]
    assert len(y1) == len(y0) and last["active"].all()
    assert 0.0 <= y1.min() and y1.max() < 0.8 and np.all(np.abs(last["positions"][:, 0] - 0.5) <= 0.5)
    # energy per unit mass (the particles have equal masses): never more at the end than at the start
    start = np.mean(G * y0 + 0.5 * (v0 ** 2).sum(1))
    end = np.mean(G * y1 + 0.5 * (v1 ** 2).sum(1))
    assert end <= start
