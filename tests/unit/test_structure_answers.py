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
