"""Hazard envelopes and run-out measures of whole runs (projects.hazard, solver.envelopes).

- A stiff elastic block sliding at constant speed over a frictionless (slip) base: arrival times
  at line and point targets equal distance / speed within one sampling interval, peak speed the
  block's speed, peak height its height, the deposit its footprint, the run-out its front.
- A column collapse: the run-out equals the toe measured from the last frame within a raster
  cell, and the envelopes are never below the values of any output frame.
- A killed run keeps the hazard files of its last frames, complete and readable; a kill between
  the files leaves them read as of hazard.json (written last).
- The block scene moved far from the origin (real-world coordinates) gives the same measures,
  moved; on a platform structure its floor is the structure's top (flow height = its height).
"""

from __future__ import annotations

import json
import math
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from projects.document import load_project, loads_project
from projects.hazard import HAZARD_JSON, HAZARD_VTI, PROFILE_CSV, TARGETS_CSV, read_hazard
from projects.results import Results
from projects.runner import run_project

BLOCK = """
[runout]
schema_version = 1
[domain]
size_m = [1.0, 0.2]
cell_size_m = 0.02
[domain.boundaries]
bottom = "slip"
left = "open"
right = "open"
[materials.steel]
model = "linear-elastic"
density_kg_m3 = 2000.0
youngs_modulus_pa = 1.0e6
poisson_ratio = 0.3
[[bodies]]
name = "block"
material = "steel"
polygon_m = [[{x0}, 0.0], [{x1}, 0.0], [{x1}, {h}], [{x0}, {h}]]
initial_velocity_m_s = [{v}, 0.0]
[numerics]
time_step_s = 2.0e-4
arch = "cpu"
[[stages]]
type = "dynamic"
duration_s = {duration}
[output]
interval_s = 0.05
fields = ["velocity"]
[hazard]
update_every_steps = {every}
[[targets]]
name = "near"
x_m = {near}
[[targets]]
name = "far"
x_m = {far}
[[targets]]
name = "window"
point_m = [{window}, 0.03]
"""

DT = 2.0e-4
H = 0.06


@pytest.mark.parametrize(("speed", "every"), [(1.5, 4), (-2.5, 10)])
def test_rigid_block_at_constant_speed(tmp_path, speed, every):
    # block 0.1 m long, 0.06 m high; moving right from x = 0.05..0.15 or left from 0.85..0.95
    right = speed > 0
    x0, x1 = (0.05, 0.15) if right else (0.85, 0.95)
    front0 = x1 if right else x0
    duration = 0.2
    targets = {"near": 0.3, "far": 0.4, "window": 0.35} if right else {"near": 0.7, "far": 0.6, "window": 0.65}
    text = BLOCK.format(x0=x0, x1=x1, h=H, v=speed, duration=duration, every=every, **targets)
    result = run_project(loads_project(text), tmp_path / "block.results")
    assert result.ok, result.message
    doc = read_hazard(result.out_dir)
    interval = every * DT
    v = abs(speed)
    for name, x in targets.items():
        t = doc["targets"][name]
        expected = abs(x - front0) / v
        # reached at the first update after the front crosses the target
        assert expected - 1e-6 <= t["arrival_time_s"] <= expected + interval + 1e-6, (name, t, expected)
        assert t["max_speed_m_s"] == pytest.approx(v, rel=0.02)
        assert t["max_pressure_pa"] == pytest.approx(2000.0 * v * v, rel=0.05)
        assert t["max_height_m"] == pytest.approx(H, rel=0.01)
    assert doc["max_speed_m_s"] == pytest.approx(v, rel=0.02)
    assert doc["direction"] == (1 if right else -1)

    prof = doc["profile"]
    lo, hi = prof["x_lo_m"], prof["x_hi_m"]
    front1 = front0 + speed * duration
    fin = (min(front1, front1 - 0.1 if right else front1 + 0.1), max(front1, front1 - 0.1 if right else front1 + 0.1))
    ini = (x0, x1)
    inside_final = (lo >= fin[0] - 1e-9) & (hi <= fin[1] + 1e-9)
    path = (lo >= min(ini[0], fin[0]) - 1e-9) & (hi <= max(ini[1], fin[1]) + 1e-9)
    passed = path & ((hi <= ini[0] + 1e-9) | (lo >= ini[1] - 1e-9))
    away = (hi <= min(ini[0], fin[0]) - 1e-9) | (lo >= max(ini[1], fin[1]) + 1e-9)
    only_initial = (lo >= ini[0] - 1e-9) & (hi <= ini[1] + 1e-9) & ((hi <= fin[0] + 1e-9) | (lo >= fin[1] - 1e-9))
    assert inside_final.sum() >= 4 and passed.sum() >= 10 and away.sum() >= 5 and only_initial.sum() >= 4
    # peak height = the block's height wherever it passed (outside its starting footprint)
    np.testing.assert_allclose(prof["peak_flow_height_m"][passed], H, rtol=0.01)
    assert np.all(prof["peak_flow_height_m"][away] == 0.0)
    # deposit = its footprint: +H under the final block, -H where it left, 0 elsewhere
    np.testing.assert_allclose(prof["deposit_m"][inside_final], H, rtol=0.01)
    np.testing.assert_allclose(prof["deposit_m"][only_initial], -H, rtol=0.01)
    np.testing.assert_allclose(prof["deposit_m"][away], 0.0, atol=1e-9)
    # speed envelope along the path
    np.testing.assert_allclose(prof["max_speed_m_s"][passed], v, rtol=0.02)
    # run-out: the final front, from the source front; travel angle from the rear top corner
    assert doc["runout_x_m"] == pytest.approx(front1, abs=1e-3)
    assert doc["runout_distance_m"] == pytest.approx(v * duration, abs=1e-3)
    assert doc["runout_x_envelope_m"] == pytest.approx(front1, abs=v * interval + 1e-3)
    rear0 = x0 if right else x1
    length = abs(front1 - rear0)
    assert doc["travel_length_m"] == pytest.approx(length, abs=1e-3)
    assert doc["drop_height_m"] == pytest.approx(H, abs=1e-3)
    assert doc["travel_angle_deg"] == pytest.approx(math.degrees(math.atan2(H, length)), abs=0.2)
    assert doc["h_over_l"] == pytest.approx(H / length, rel=0.02)
    assert doc["mobilised_area_m2_per_m"] == pytest.approx(0.1 * H, rel=1e-3)
    assert doc["centroid_travel_m"]["dx_m"] == pytest.approx(speed * duration, abs=1e-3)
    # the block never stops: no slide duration
    assert doc["still_moving"] is True and doc["slide_duration_s"] is None
    # targets.csv: one row per update, the far target's height series jumps to H at its arrival
    series = doc["series"]
    t_upd = series["time_s"]
    assert t_upd[0] == 0.0 and t_upd[-1] == pytest.approx(duration)
    assert np.all(np.diff(t_upd) > 0) and np.diff(t_upd).max() <= interval * (1 + 1e-4)
    far = series["far:height_m"]
    arrived = series["time_s"] >= doc["targets"]["far"]["arrival_time_s"] - 1e-7  # (9 digits in the csv)
    # (at the first update the front corner may still be rounding the line by a fraction of a particle)
    assert np.all(far[~arrived] == 0.0) and far[arrived][0] > 0 and np.all(far[arrived][1:6] > 0.99 * H)


def _frame_columns(res: Results, i: int, c: float, half: float):
    fr = res.frame(i, fields=["positions", "active", "velocity"])
    act = fr["active"].astype(bool)
    pos = fr["positions"][act].astype(np.float32)
    speed = np.linalg.norm(fr["velocity"][act].astype(np.float64), axis=1)
    col = np.floor(pos[:, 0] / np.float32(c)).astype(int)
    return pos, speed, col


def test_column_collapse_runout_and_envelopes_bound_every_frame(tiny_project, tmp_path):
    path = Path(shutil.copy(tiny_project, tmp_path / "tiny.toml"))
    project = load_project(path, ["stages.1.duration_s=0.4", "output.interval_s=0.02"])
    result = run_project(project, tmp_path / "tiny.results")
    assert result.ok, result.message
    doc = read_hazard(result.out_dir)
    res = Results(result.out_dir)
    c = doc["raster"]["cell_size_m"]
    half = 0.5 * 0.02 / 2  # half the particle spacing
    # the toe of the last frame: the farthest particle edge
    pos, _, _ = _frame_columns(res, -1, c, half)
    toe = float(pos[:, 0].max()) + half
    assert doc["direction"] == 1
    assert doc["runout_x_m"] == pytest.approx(toe, abs=c)
    assert doc["runout_distance_m"] == pytest.approx(toe - 0.12, abs=c)
    # Lube et al. define the run-out from the column's front: 0.12 m here
    assert doc["source_front_x_m"] == pytest.approx(0.12, abs=1e-6)
    assert doc["source_top_m"] == pytest.approx([0.0, 0.24], abs=1e-6)

    prof = doc["profile"]
    ground = prof["ground_m"]
    nx = len(ground)
    for i in range(len(res)):
        pos, speed, col = _frame_columns(res, i, c, half)
        top = np.full(nx, -np.inf)
        np.maximum.at(top, col, pos[:, 1] + half)
        vmax = np.zeros(nx)
        np.maximum.at(vmax, col, speed)
        height = np.maximum(top - ground, 0.0)
        # the frame's flow height (from the lattice half spacing) and speeds never exceed the envelopes
        assert np.all(height <= prof["peak_flow_height_m"] + 2e-4), i
        assert np.all(vmax <= prof["max_speed_m_s"] * (1 + 1e-6) + 1e-7), i
        reached = height > doc["thresholds"]["flow_height_threshold_m"] + 2e-4
        t = res.times[i]
        assert np.all(prof["arrival_s"][reached] <= t + 1e-9), i
    # the deposit is the change of the surface: it adds up to (about) nothing, mass is conserved
    d = prof["deposit_m"]
    assert abs(float(d.sum()) * c) < 0.1 * float(np.abs(d).sum()) * c
    # the files are there and readable
    for name in (HAZARD_JSON, HAZARD_VTI, PROFILE_CSV, TARGETS_CSV):
        assert (result.out_dir / name).is_file()
    vtk = pytest.importorskip("vtk")
    reader = vtk.vtkXMLImageDataReader()
    reader.SetFileName(str(result.out_dir / HAZARD_VTI))
    reader.Update()
    image = reader.GetOutput()
    assert image.GetNumberOfCells() == nx * doc["raster"]["shape"][1]
    from vtk.util.numpy_support import vtk_to_numpy

    speed_map = vtk_to_numpy(image.GetCellData().GetArray("max_speed_m_s")).reshape(doc["raster"]["shape"][1], nx)
    np.testing.assert_allclose(speed_map.max(axis=0), prof["max_speed_m_s"], rtol=1e-6)
    assert json.loads((result.out_dir / HAZARD_JSON).read_text())["status"] == "completed"

    # a run killed after writing a later update's targets.csv but before hazard.json: the reader
    # gives the series hazard.json was made from, ending at its time
    series = doc["series"]
    assert series["time_s"][-1] == pytest.approx(doc["time_s"])
    targets = result.out_dir / TARGETS_CSV
    last = targets.read_text().splitlines()[-1].split(",")
    later = [repr(doc["time_s"] + 0.002)] + last[1:]
    targets.write_text(targets.read_text() + ",".join(later) + "\n")
    again = read_hazard(result.out_dir)
    assert set(again["series"]) == set(series)
    for name, col in series.items():
        np.testing.assert_array_equal(again["series"][name], col)


@pytest.mark.skipif(sys.platform == "win32", reason="SIGKILL")
def test_envelopes_survive_a_killed_run(tiny_project, tmp_path):
    out = tmp_path / "killed.results"
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[2]))
    proc = subprocess.Popen(
        [sys.executable, "-m", "app.cli", "run", str(tiny_project), "--arch", "cpu", "-q", "--out", str(out),
         "--set", "stages.1.duration_s=1000", "--set", "output.interval_s=0.01", "--force"],
        cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
    )
    try:
        deadline = time.monotonic() + 180
        while time.monotonic() < deadline and proc.poll() is None:
            try:  # wait for the hazard files of the fourth frame
                if json.loads((out / HAZARD_JSON).read_text()).get("time_s", 0) >= 0.03:
                    break
            except (OSError, ValueError):
                pass
            time.sleep(0.05)
        assert proc.poll() is None, proc.communicate()[1]
        os.kill(proc.pid, signal.SIGKILL)
        proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    res = Results(out)
    assert res.status == "interrupted"
    doc = read_hazard(out)  # every file complete and readable
    assert doc["status"] == "running"
    # the envelopes are those of a frame that was written (or of the one being written)
    assert doc["time_s"] >= 0.03
    assert min(abs(t - doc["time_s"]) for t in [*res.times, res.times[-1] + 0.01]) < 1e-6
    assert len(doc["series"]["time_s"]) >= 4 and doc["series"]["time_s"][-1] == pytest.approx(doc["time_s"])
    assert doc["max_speed_m_s"] > 0 and np.all(np.isfinite(doc["profile"]["peak_flow_height_m"]))


def test_the_hazard_files_of_a_scene_far_from_the_origin_are_those_of_the_same_scene_at_it(tmp_path):
    """Real-world coordinates (``domain.origin_m`` far from zero, docs/project-format.md): the
    engine works relative to the grid's origin, and so must the envelopes; the hazard files give
    the scene's measures in the project's coordinates, the same as for the scene at (0, 0) moved
    by the origin (before: the raster was placed at the project's origin over the engine's relative
    positions, so nothing was found on it: no flow height, no run-out, targets never reached)."""
    from projects.schema import validate_project

    shift = (1000.0, 200.0)
    text = BLOCK.format(x0=0.05, x1=0.15, h=H, v=1.5, duration=0.2, every=4, near=0.3, far=0.4, window=0.35)
    data = loads_project(text).to_dict()
    data["domain"]["origin_m"] = list(shift)
    data["bodies"][0]["polygon_m"] = [[x + shift[0], y + shift[1]] for x, y in data["bodies"][0]["polygon_m"]]
    for target in data["targets"]:
        if "x_m" in target:
            target["x_m"] += shift[0]
        else:
            target["point_m"] = [target["point_m"][0] + shift[0], target["point_m"][1] + shift[1]]
    docs = []
    for name, project in (("at-origin", loads_project(text)), ("far", validate_project(data))):
        result = run_project(project, tmp_path / name)
        assert result.ok, result.message
        docs.append(read_hazard(result.out_dir))
    near, far = docs
    assert near["runout_x_m"] is not None and near["max_flow_height_m"] == pytest.approx(H, rel=0.01)
    for key in ("runout_x_m", "source_front_x_m", "runout_x_envelope_m"):
        assert far[key] == pytest.approx(near[key] + shift[0], abs=1e-3), key
    for key in ("runout_distance_m", "max_flow_height_m", "drop_height_m", "travel_length_m", "max_speed_m_s",
                "mobilised_area_m2_per_m"):
        assert far[key] == pytest.approx(near[key], rel=1e-3, abs=1e-4), key
    for name, t in near["targets"].items():
        assert far["targets"][name]["arrival_time_s"] == pytest.approx(t["arrival_time_s"], abs=1e-6), name
        assert far["targets"][name]["max_height_m"] == pytest.approx(t["max_height_m"], rel=1e-3), name
    for column, offset in (("x_m", shift[0]), ("floor_m", shift[1]), ("ground_m", shift[1]), ("surface_m", shift[1])):
        np.testing.assert_allclose(far["profile"][column], near["profile"][column] + offset, atol=1e-3, err_msg=column)
    np.testing.assert_allclose(far["profile"]["peak_flow_height_m"], near["profile"]["peak_flow_height_m"], atol=1e-3)


def test_the_floor_under_a_structure_is_its_top(tmp_path):
    """A block sliding on a structure (bedrock, a platform: a rigid sliding surface) flows
    over the structure's top, not over the grid's bottom: its flow height is its own height and
    it drops nothing (flow heights and drop measured from the grid's bottom under the structure
    would be 0.12 m here instead of 0.06 m)."""
    from projects.schema import validate_project

    base = 0.06  # the platform's top: 3 cells, on a node line
    text = BLOCK.format(x0=0.05, x1=0.15, h=H, v=1.5, duration=0.2, every=4, near=0.3, far=0.4, window=0.35)
    data = loads_project(text).to_dict()
    data["bodies"][0]["polygon_m"] = [[x, y + base] for x, y in data["bodies"][0]["polygon_m"]]
    data["targets"][2]["point_m"][1] += base
    data["structures"] = [{"name": "platform", "polygon_m": [[0.0, 0.0], [1.0, 0.0], [1.0, base], [0.0, base]],
                           "contact": "slip"}]
    result = run_project(validate_project(data), tmp_path / "platform")
    assert result.ok, result.message
    doc = read_hazard(result.out_dir)
    prof = doc["profile"]
    np.testing.assert_allclose(prof["floor_m"], base, atol=1e-9)
    passed = (prof["x_lo_m"] >= 0.15 - 1e-9) & (prof["x_hi_m"] <= 0.35 + 1e-9)
    np.testing.assert_allclose(prof["peak_flow_height_m"][passed], H, rtol=0.01)
    assert doc["max_flow_height_m"] == pytest.approx(H, rel=0.01)
    assert doc["drop_height_m"] == pytest.approx(H, abs=1e-3)  # from its top to the platform
    assert doc["runout_distance_m"] == pytest.approx(1.5 * 0.2, abs=1e-3)
    for name in ("near", "far"):
        assert doc["targets"][name]["max_height_m"] == pytest.approx(H, rel=0.01), name


def test_the_floor_of_each_raster_column_is_the_top_of_the_structures_at_its_centre():
    from projects.hazard import structure_floor_m
    from projects.schema import validate_project

    data = loads_project(BLOCK.format(x0=0.05, x1=0.15, h=H, v=1.5, duration=0.2, every=4, near=0.3, far=0.4,
                                      window=0.35)).to_dict()
    # a ramp falling from 0.1 m at x = 0.2 to 0 at x = 0.6, and a wall from 0.7 to 0.76, 0.15 high
    data["structures"] = [{"name": "ramp", "polygon_m": [[0.2, 0.0], [0.6, 0.0], [0.2, 0.1]]},
                          {"name": "wall", "polygon_m": [[0.7, 0.0], [0.76, 0.0], [0.76, 0.15], [0.7, 0.15]]}]
    project = validate_project(data)
    floor = structure_floor_m(project, 0.02)
    assert floor.shape == (50,)  # 1.0 m of 0.02 m columns
    x = (np.arange(50) + 0.5) * 0.02
    expected = np.where((x > 0.2) & (x < 0.6), 0.1 * (0.6 - x) / 0.4, 0.0)
    expected = np.where((x > 0.7) & (x < 0.76), 0.15, expected)
    np.testing.assert_allclose(floor, expected, atol=1e-12)
    assert structure_floor_m(validate_project(loads_project(BLOCK.format(
        x0=0.05, x1=0.15, h=H, v=1.5, duration=0.2, every=4, near=0.3, far=0.4, window=0.35)).to_dict()), 0.02) is None
