"""Structures read as numbers: the deposit measured on the ground, never as a pit under a
structure; each structure's force split into its normal and tangential parts on the face that
carries it, with the peaks and when."""

from __future__ import annotations

import math

import numpy as np
import pytest


def _snapshot(floor, ground, surface):
    nx = len(floor)
    zeros = np.zeros((nx, 3))
    return {"shape": (nx, 3), "cell_size_m": 0.25, "origin_m": (20.0, 0.0), "floor_m": np.asarray(floor, float),
            "ground_m": np.asarray(ground, float), "surface_m": np.asarray(surface, float),
            "peak_height_m": np.zeros(nx), "arrival_s": np.full(nx, -1.0), "max_speed_m_s": zeros,
            "max_energy_J_m3": zeros, "max_pressure_pa": zeros}


def test_the_deposit_under_a_structure_is_measured_on_its_top_not_as_a_pit():
    from projects.hazard import profile

    # columns 20-21 m: debris 1 m deep against a dam whose top (2.5 m) is the floor of the third
    # and fourth columns; a particle beside the dam's face has its centre in the third column
    snap = _snapshot(floor=[0, 0, 2.5, 2.5, 0], ground=[0, 0, 2.5, 2.5, 0], surface=[1.0, 1.0, 0.2, np.nan, np.nan])
    prof = profile(snap)
    assert np.allclose(prof["deposit_m"], [1.0, 1.0, 0.0, 0.0, 0.0])  # it was -2.3 under the dam
    assert np.allclose(prof["surface_m"], [1.0, 1.0, 2.5, 2.5, 0.0])
    # material standing on the dam's crest is a deposit on it
    snap = _snapshot(floor=[0, 0, 2.5], ground=[0, 0, 2.5], surface=[2.6, 2.6, 2.8])
    assert np.allclose(profile(snap)["deposit_m"], [2.6, 2.6, 0.3])


def test_old_profile_files_read_with_the_same_rule(tmp_path):
    from projects.hazard import read_hazard

    (tmp_path / "hazard.json").write_text("{}")
    (tmp_path / "targets.csv").write_text("time_s\n0.0\n")
    (tmp_path / "hazard_profile.csv").write_text(
        "x_m,floor_m,ground_m,surface_m,deposit_m\n20.9,0,0,1.0,1.0\n21.1,2.5,2.5,0.2,-2.3\n")
    prof = read_hazard(tmp_path)["profile"]
    assert np.allclose(prof["deposit_m"], [1.0, 0.0]) and np.allclose(prof["surface_m"], [1.0, 2.5])


DAM = [[21.0, 0.0], [21.5, 0.0], [21.5, 2.5], [21.0, 2.5]]
BEDROCK = [[0.0, 0.0], [16.0, 0.0], [0.0, 13.4]]


def test_a_dams_force_is_split_on_its_loaded_face():
    from projects.structure_forces import components, faces

    # debris pushing on the upstream face at 0.9 m, dragging it down a little: the moment about the
    # origin of a force (fx, fy) acting at (21, 0.9) is 21 fy - 0.9 fx
    fx, fy = 100e3, -2e3
    normal, tangential, face = components(DAM, (fx, fy), 21.0 * fy - 0.9 * fx)
    assert (normal, tangential) == (pytest.approx(100e3), pytest.approx(-2e3))
    a, b, n, t = faces(DAM)[face]
    assert np.allclose(n, [-1, 0]) and np.allclose(t, [0, 1])  # the upstream face, t up along it
    # the same force with its line through the crest (weight on the dam's top): the crest carries it
    down = (0.0, -50e3)
    normal, tangential, face = components(DAM, down, 21.25 * down[1])
    assert np.allclose(faces(DAM)[face][2], [0, 1]) and normal == pytest.approx(50e3) and tangential == 0.0
    # a slide on a 40-degree bedrock face: pressed on and dragged down the slope (t along +x)
    f = (-117.7e3, -295.5e3)
    normal, tangential, face = components(BEDROCK, f, math.nan)
    n = np.array([13.4, 16.0]) / math.hypot(13.4, 16.0)
    assert normal == pytest.approx(-np.dot(f, n)) and normal > 0 and tangential > 0
    assert math.hypot(normal, tangential) == pytest.approx(math.hypot(*f))


def _write_dam_run(folder, with_parts=True):
    from projects.results import ResultsWriter
    from solver.config import ContactForce, Diagnostics, Frame

    meta = {"particles": 1, "domain": {"origin_m": [0.0, 0.0], "size_m": [32.0, 14.5], "cell_size_m": 0.25},
            "structures": [{"name": "check-dam", "polygon_m": DAM}]}
    writer = ResultsWriter(folder, "", meta)
    pos = np.zeros((1, 2), np.float32)
    rows = [(0.0, 0.0, 0.0, 0.0, 0.0), (60e3, -1e3, 70e3, 69e3, -2e3), (100e3, -3e3, 104e3, 103e3, -4e3),
            (90e3, -5e3, 95e3, 94e3, -6e3)]
    for i, (fx, fy, peak, px, py) in enumerate(rows):
        diag = Diagnostics(0.5 * i, "s", 0, 0.5 * i, i, 1e-3, 0, 0, 0, 0, 0, 0, 1.0, 0)
        contacts = (ContactForce("check-dam", fx, fy, None, None, peak, px, py, 21.0 * fy - 0.9 * fx),
                    ContactForce("bottom", 0.0, -2e6, 2e6, 0.0, 2.9e6, 0.0, -2.9e6))
        writer.write_frame(Frame(diag, {"positions": pos, "active": np.ones(1, bool)}, contacts))
    return writer.close("completed")


def test_contacts_csv_and_the_summary_hold_a_structures_normal_and_tangential_peaks(tmp_path):
    import json

    from projects.results import read_contacts

    summary = _write_dam_run(tmp_path / "r")
    dam = read_contacts(tmp_path / "r")["check-dam"]
    np.testing.assert_allclose(dam["force_normal_N_per_m"], [0.0, 60e3, 100e3, 90e3])
    np.testing.assert_allclose(dam["force_tangential_N_per_m"], [0.0, -1e3, -3e3, -5e3])
    peaks = json.loads((tmp_path / "r" / "summary.json").read_text())["contacts"]["check-dam"]
    assert peaks == summary["contacts"]["check-dam"]
    assert peaks["peak_force_N_per_m"] == 104e3 and peaks["peak_time_s"] == pytest.approx(1.0)
    assert peaks["peak_force_normal_N_per_m"] == pytest.approx(103e3)
    assert peaks["peak_force_tangential_N_per_m"] == pytest.approx(-4e3)
    assert peaks["max_normal_force_N_per_m"] == pytest.approx(100e3) and peaks["max_normal_force_time_s"] == 1.0
    assert peaks["max_tangential_force_N_per_m"] == pytest.approx(-5e3)
    assert peaks["max_tangential_force_time_s"] == 1.5
    base = summary["contacts"]["bottom"]  # a side: its own axes
    assert base["peak_force_normal_N_per_m"] == pytest.approx(2.9e6) and base["max_normal_force_N_per_m"] == 2e6


def test_older_contacts_files_get_a_structures_parts_on_reading(tmp_path):
    from projects.results import read_contacts

    _write_dam_run(tmp_path / "r")
    path = tmp_path / "r" / "contacts.csv"
    lines = path.read_text().splitlines()
    old = [lines[0]] + [",".join(cells[:4] + ["", ""] + cells[6:]) if cells[1] == "check-dam" else line
                        for line, cells in ((line, line.split(",")) for line in lines[1:])]
    path.write_text("\n".join(old) + "\n")
    dam = read_contacts(tmp_path / "r")["check-dam"]
    np.testing.assert_allclose(dam["force_normal_N_per_m"], [0.0, 60e3, 100e3, 90e3])


def test_hazard_json_structures_have_their_normal_and_tangential_peaks(tmp_path):
    from projects.hazard import structure_forces

    _write_dam_run(tmp_path / "r")
    dam = structure_forces(tmp_path / "r")["check-dam"]
    assert dam["peak_force_N_per_m"] == 104e3 and dam["peak_time_s"] == 1.0
    assert dam["max_normal_force_N_per_m"] == pytest.approx(100e3) and dam["max_normal_force_time_s"] == 1.0
    assert dam["max_tangential_force_N_per_m"] == pytest.approx(-5e3) and dam["max_tangential_force_time_s"] == 1.5
    assert "bottom" not in structure_forces(tmp_path / "r")


def test_the_reports_force_figure_gives_each_structure_its_own_plot_and_the_sides_theirs(tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    from app.report import _contacts, contacts_png
    from projects.results import read_contacts

    _write_dam_run(tmp_path / "r")  # a dam taking 104 kN/m beside a base taking 2.9 MN/m
    figures = []
    import matplotlib.figure

    keep = matplotlib.figure.Figure.savefig
    matplotlib.figure.Figure.savefig = lambda self, *a, **k: (figures.append(self), keep(self, *a, **k))[1]
    try:
        assert contacts_png(read_contacts(tmp_path / "r"), tmp_path / "contacts.png", ["check-dam"]).is_file()
    finally:
        matplotlib.figure.Figure.savefig = keep
    dam, sides = figures[0].axes
    assert dam.get_title(loc="left") == "check-dam" and sides.get_title(loc="left") == "closed sides: bottom"
    assert dam.get_ylim()[1] < 150.0 and sides.get_ylim()[1] > 2500.0  # kN/m: the dam on its own scale
    assert [line.get_label() for line in dam.get_lines()[:3]] == ["peak |F| of a step", "mean normal",
                                                                  "mean tangential"]
    rows = _contacts(tmp_path / "r", {})
    assert rows[0][:7] == ["check-dam", "104 kN/m (N 103, T -4)", "1 s", "100 kN/m", "1 s", "-5 kN/m", "1.5 s"]
    assert rows[1][0] == "bottom (side)"
