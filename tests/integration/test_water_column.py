"""A soil column under a water table, brought to equilibrium by a gravity stage, against hydrostatics.

A 2 m column of elastic soil (1800 kg/m3 above the phreatic line, 2100 below; slip sides, fixed
base; 0.1 m cells, 4 particles a cell) settles under gravity with the pore pressure's gradient
acting on its skeleton. At rest, against the closed forms

    u = gamma_w (h - y),  sigma_v = gamma z (+ gamma_w (h_free - top) where free water stands),
    sigma'_v = sigma_v - u  (= (gamma_sat - gamma_w) z below the line, under free water)

the row means of the particles' pore pressure, effective and total vertical stress are within
2 % of the total stress at the base, in every scheme and precision; with the line inside the
column (no free water) and above it (free water 0.5 m deep, whose weight reaches the soil only
through the surface particles' pore pressure: no traction is applied).
"""

import numpy as np
import pytest

from projects.results import Results
from projects.runner import run_project
from projects.schema import validate_project

G = 9.81
GAMMA_W = 9810.0
TOP = 2.0
TOLERANCE = 0.02


def column(scheme: str, precision: str, line: float):
    return validate_project({
        "runout": {"schema_version": 2, "title": "water column"},
        "domain": {"origin_m": [0.0, 0.0], "size_m": [0.5, 3.0], "cell_size_m": 0.1,
                   "boundaries": {"left": "slip", "right": "slip", "bottom": "fixed", "top": "open"}},
        "materials": {"soil": {"model": "linear-elastic", "density_kg_m3": 1800.0, "saturated_density_kg_m3": 2100.0,
                               "youngs_modulus_pa": 2.0e7, "poisson_ratio": 0.3}},
        "bodies": [{"name": "column", "material": "soil", "polygon_m": [[0, 0], [0.5, 0], [0.5, TOP], [0, TOP]]}],
        "water": {"phreatic_line_m": [[0.0, line], [0.5, line]]},
        "numerics": {"scheme": scheme, "precision": precision, "cfl": 0.5},
        "stages": [{"name": "settle", "type": "gravity", "duration_s": 0.6,
                    "damping": {"type": "local", "coefficient": 0.7}}],
        "output": {"interval_s": 0.6},
        "hazard": {"enabled": False},
    })


def expected(y: np.ndarray, line: float) -> tuple[np.ndarray, np.ndarray]:
    """Total vertical stress (compression positive) and pore pressure at heights y."""
    wet_top = np.clip(np.maximum(line, y), None, TOP)
    total = G * (1800.0 * (TOP - wet_top) + 2100.0 * (wet_top - y)) + GAMMA_W * max(line - TOP, 0.0)
    return total, GAMMA_W * np.maximum(line - y, 0.0)


CASES = [pytest.param(s, p, 2.5, id=f"{s}-{p}-free-water") for s in ("mpm", "apic", "apic-affine")
         for p in ("f32", "f64")]
CASES += [pytest.param("apic-affine", "f32", 1.2, id="apic-affine-f32-line-inside"),
          pytest.param("mpm", "f64", 1.2, id="mpm-f64-line-inside")]


@pytest.mark.matrix(sample=3)  # a covering sample, one case per scheme (RUNOUT_FULL_MATRIX=1: all eight)
@pytest.mark.parametrize("scheme, precision, line", CASES)
def test_a_column_under_water_carries_hydrostatic_pore_pressure_and_buoyant_effective_stress(
        tmp_path, scheme, precision, line):
    result = run_project(column(scheme, precision, line), tmp_path / "run")
    assert result.status == "completed", result.message
    frame = Results(tmp_path / "run").frame(-1)
    y = frame["positions"][:, 1]
    rows = np.round((y - 0.025) / 0.05).astype(int)
    total_exact, u_exact = expected(y, line)
    scale = float(total_exact.max())
    effective = -frame["stress"][:, 1].astype(np.float64)
    u = frame["pore_pressure"].astype(np.float64)
    for name, got, want in (("pore pressure", u, u_exact), ("effective vertical stress", effective, total_exact - u_exact),
                            ("total vertical stress", effective + u, total_exact)):
        worst = max(abs(got[rows == r].mean() - want[rows == r].mean()) for r in np.unique(rows))
        assert worst <= TOLERANCE * scale, f"{name}: worst row {worst / scale:.2%} of the base's total stress"
