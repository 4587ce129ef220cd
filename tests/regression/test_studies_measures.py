"""The aluminium-bar deposit against the experiment, the slope angle, Pareto front and preset choice
of the validation studies (fast, no solver).

Synthetic particle sets with known answers; tolerances are round-off only.
"""


import numpy as np
import pytest

from studies.common import StudyError, bui_experiment, experiment_toe, measure_deposit
from studies.slope import slope_angle
from studies.tradeoff import choose_presets, pareto_front


def lattice(x0, x1, y0, y1, s):
    xs = np.arange(x0 + s / 2, x1, s)
    ys = np.arange(y0 + s / 2, y1, s)
    X, Y = np.meshgrid(xs, ys)
    return np.c_[X.ravel(), Y.ravel()]


def test_experiment_and_rms():
    try:
        exp = bui_experiment()
    except StudyError as err:
        pytest.skip(str(err))
    assert exp.shape[1] == 2 and len(exp) > 10
    assert exp[0, 1] == pytest.approx(0.0992, abs=5e-4)
    assert 0.42 < experiment_toe(exp) < 0.44        # 2 mm between the digitised 2.24 and 1.52 mm points
    # a deposit equal to the experiment (a dense column under each point) has a near-zero RMS
    s = 0.0005
    cols = [lattice(x - 0.0025, x + 0.0025, 0.0, y, s) for x, y in exp if y > s]
    dep = measure_deposit(np.vstack(cols), None, s, exp)
    assert dep.rms_m < 0.001


def test_slope_angle_of_a_planar_face():
    s = 0.5
    pos = lattice(0.0, 200.0, 0.0, 27.0, s)
    face = lattice(0.0, 120.0, 27.0, 70.0, s)
    keep = face[:, 1] <= 70.0 - np.tan(np.radians(25.0)) * np.maximum(face[:, 0] - 30.0, 0.0)
    angle, _ = slope_angle(np.vstack([pos, face[keep]]), None, s)
    assert angle == pytest.approx(25.0, abs=1.0)


def test_pareto_front_and_presets():
    cost = np.array([1.0, 2.0, 3.0, 4.0, 5.0, np.nan])
    err = np.array([5.0, 6.0, 2.0, 2.0, 1.0, 0.1])
    assert pareto_front(cost, err).tolist() == [0, 2, 4]
    rows = [
        {"label": "a", "status": "completed", "wall_s": 1.0, "rms_vs_ref_m": 0.004},
        {"label": "b", "status": "completed", "wall_s": 3.0, "rms_vs_ref_m": 0.002},
        {"label": "c", "status": "failed", "wall_s": 0.5, "rms_vs_ref_m": 0.0},
        {"label": "d", "status": "completed", "wall_s": 9.0, "rms_vs_ref_m": 0.0, "is_reference": True},
        {"label": "e", "status": "completed", "wall_s": 0.2, "rms_vs_ref_m": 0.0, "cfl": 0.8},  # no margin
    ]
    chosen = choose_presets(rows, {"draft": {"rms_vs_ref_m": 0.005}, "standard": {"rms_vs_ref_m": 0.0025},
                                   "fine": {"rms_vs_ref_m": 0.001}})
    assert chosen["draft"]["label"] == "a"
    assert chosen["standard"]["label"] == "b"
    assert chosen["fine"] is None


def test_drift_check_repeats_the_cached_run_nearest_half_a_minute(tmp_path, monkeypatch):
    """The tradeoff report says how the machine's speed now compares with when cached runs were timed."""
    from types import SimpleNamespace

    import studies.tradeoff as tradeoff

    calls = []

    def fake_run_bui(out_dir, label, cell_m, per_cell, scheme, experiment, **kwargs):
        calls.append((label, cell_m, per_cell, scheme, kwargs["cfl"]))
        return SimpleNamespace(wall_s=45.0), None

    monkeypatch.setattr(tradeoff, "run_bui", fake_run_bui)
    row = {"status": "completed", "per_cell": 2, "cfl": 0.4}
    rows = [dict(row, label="a", cell_mm=5.0, scheme="apic-affine", wall_s=7.0),
            dict(row, label="b", cell_mm=2.5, scheme="apic-affine", wall_s=40.0, run_at="2026-11-21 22:19 UTC"),
            dict(row, label="c", cell_mm=2.0, scheme="apic", wall_s=30.0),
            dict(row, label="d", cell_mm=4.0, scheme="apic-affine", wall_s=31.0, status="stopped")]
    drift = tradeoff._drift_check(tmp_path, rows, np.zeros((2, 2)), lambda *_: None)
    assert calls == [("apic-affine_2.5mm_4ppc_cfl0.4", 0.0025, 2, "apic-affine", 0.4)]
    assert drift["label"] == "b"
    assert drift["fresh_over_cached"] == pytest.approx(45.0 / 40.0)
    assert drift["cached_at"] == "2026-11-21 22:19 UTC"
    assert (tmp_path / "drift" / "drift.json").is_file()
    assert tradeoff._drift_check(tmp_path, [], np.zeros((2, 2)), lambda *_: None) is None
