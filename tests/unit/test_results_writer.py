"""ResultsWriter and Results: the results folder contract of docs/DESIGN.md, written and read back."""

from __future__ import annotations

import json
from xml.etree import ElementTree

import numpy as np
import pytest

from projects.results import (
    SERIES_COLUMNS,
    Results,
    ResultsError,
    ResultsWriter,
    encode_vtp,
    open_results,
    prepare_results_dir,
    read_vtp,
)
from tests.conftest import SYNTHETIC_META, SYNTHETIC_PROJECT, synthetic_frames

REQUIRED_SERIES = (
    "time_s", "stage", "step", "kinetic_energy_J_per_m", "momentum_x", "momentum_y",
    "max_speed_m_s", "unstable_particles", "lost_particles",
    "stage_time_s", "dt_s", "total_mass_kg_per_m", "yielding_particles",
)
REQUIRED_SUMMARY = (
    "status", "message", "scheme", "arch", "precision", "particles", "steps",
    "simulated_time_s", "wall_time_s", "particle_steps_per_s", "frames", "title", "runout_version",
)


def test_folder_layout_and_round_trip(make_results):
    path = make_results(n_frames=4)
    frames = synthetic_frames(4)
    assert sorted(p.name for p in path.iterdir()) == [
        ".runout-results", "contacts.csv", "frames", "particles.pvd", "project.toml", "series.csv", "summary.json"
    ]
    assert sorted(p.name for p in (path / "frames").iterdir()) == [
        f"frame_{i:05d}.vtp" for i in range(4)
    ]
    assert (path / "project.toml").read_text() == SYNTHETIC_PROJECT

    res = open_results(path)
    assert len(res) == 4
    np.testing.assert_allclose(res.times, [0.0, 0.05, 0.1, 0.15])
    for i, frame in enumerate(frames):
        got = res.frame(i)
        want = frame.fields
        assert set(got) == {"positions", "active", "particle_id", "displacement", "velocity",
                            "stress", "plastic_strain", "material_id"}
        np.testing.assert_allclose(got["positions"], want["positions"], rtol=1e-6, atol=1e-7)
        np.testing.assert_array_equal(got["active"], want["active"])
        np.testing.assert_allclose(got["displacement"], want["displacement"], rtol=1e-6, atol=1e-7)
        np.testing.assert_allclose(got["velocity"], want["velocity"], rtol=1e-6, atol=1e-7)
        np.testing.assert_allclose(got["stress"], want["stress"], rtol=1e-6)
        np.testing.assert_allclose(got["plastic_strain"], want["plastic_strain"], rtol=1e-6)
        np.testing.assert_array_equal(got["material_id"], want["material_id"])
        np.testing.assert_array_equal(got["particle_id"], np.arange(len(want["active"])))
    assert res.frame(-1)["positions"].shape == (800, 2)
    assert not res.frame(0)["stress"].flags.writeable  # cached arrays are shared: read-only


def test_only_the_fields_a_frame_has_are_written(tmp_path):
    frame = synthetic_frames(1)[0]
    fields = {k: frame.fields[k] for k in ("positions", "active", "velocity")}
    writer = ResultsWriter(tmp_path / "r", "", {})
    writer.write_frame(type(frame)(frame.diagnostics, fields))
    writer.close("completed")
    got = Results(tmp_path / "r").frame(0)
    assert set(got) == {"positions", "active", "particle_id", "velocity"}


def test_frame_file_is_compressed_vtk_polydata_readable_by_vtk(make_results):
    pv = pytest.importorskip("pyvista")
    path = make_results(n_frames=3)
    frame = synthetic_frames(3)[2]
    head = (path / "frames" / "frame_00002.vtp").read_bytes()[:400].decode("ascii", "replace")
    assert 'type="PolyData"' in head and 'compressor="vtkZLibDataCompressor"' in head

    mesh = pv.read(path / "frames" / "frame_00002.vtp")
    n = len(frame.fields["active"])
    assert mesh.n_points == n
    assert mesh.points.dtype == np.float32
    np.testing.assert_array_equal(mesh.points[:, 2], 0.0)
    # vertex cells only for the active particles: viewers skip removed ones
    assert mesh.n_cells == int(frame.fields["active"].sum()) == n - 5
    assert mesh.point_data["displacement"].shape == (n, 3)
    assert mesh.point_data["velocity"].shape == (n, 3)
    assert mesh.point_data["stress"].shape == (n, 4)
    assert mesh.point_data["material_id"].dtype == np.int32
    assert mesh.point_data["particle_id"].dtype == np.int32
    assert mesh.point_data["active"].dtype == np.uint8
    np.testing.assert_allclose(mesh.point_data["stress"], frame.fields["stress"], rtol=1e-6)
    np.testing.assert_array_equal(mesh.point_data["displacement"][:, 2], 0.0)
    assert mesh.field_data["TimeValue"][0] == pytest.approx(0.1)


def test_pvd_indexes_frames_with_their_times(make_results):
    pv = pytest.importorskip("pyvista")
    path = make_results(n_frames=3)
    root = ElementTree.parse(path / "particles.pvd").getroot()
    sets = list(root.iter("DataSet"))
    assert [d.get("file") for d in sets] == [f"frames/frame_{i:05d}.vtp" for i in range(3)]
    assert [float(d.get("timestep")) for d in sets] == pytest.approx([0.0, 0.05, 0.1])
    reader = pv.get_reader(path / "particles.pvd")
    assert reader.time_values == pytest.approx([0.0, 0.05, 0.1])


def test_series_columns_and_values(make_results):
    path = make_results(n_frames=4)
    header = (path / "series.csv").read_text().splitlines()[0].split(",")
    assert header == list(SERIES_COLUMNS)
    assert set(REQUIRED_SERIES) <= set(header)
    series = Results(path).series
    np.testing.assert_allclose(series["time_s"], [0.0, 0.05, 0.1, 0.15])
    np.testing.assert_array_equal(series["step"], [0, 50, 100, 150])
    assert series["step"].dtype.kind == "i"
    np.testing.assert_array_equal(series["lost_particles"], [0, 0, 5, 5])
    np.testing.assert_allclose(series["kinetic_energy_J_per_m"], [0.0, 0.5, 1.0, 1.5])
    assert list(series["stage"]) == ["collapse"] * 4


def test_summary_fields(make_results):
    path = make_results(n_frames=4)
    summary = json.loads((path / "summary.json").read_text())
    for key in REQUIRED_SUMMARY:
        assert key in summary, key
    assert summary["status"] == "completed"
    assert summary["frames"] == 4
    assert summary["steps"] == 150  # the last frame's step when the caller gives none
    assert summary["simulated_time_s"] == pytest.approx(0.15)
    assert summary["particles"] == 800
    assert summary["particle_steps_per_s"] > 0
    res = Results(path)
    assert res.status == "completed"
    assert res.material_names == ["lower", "upper"]
    assert res.project_text == SYNTHETIC_PROJECT


def test_summary_says_running_until_closed(tmp_path):
    writer = ResultsWriter(tmp_path / "r", "", dict(SYNTHETIC_META))
    frames = synthetic_frames(2)
    writer.write_frame(frames[0])
    writer.flush()
    summary = json.loads((tmp_path / "r" / "summary.json").read_text())
    assert summary["status"] == "running"
    assert summary["frames"] == 1
    assert Results(tmp_path / "r").status == "interrupted"
    writer.write_frame(frames[1])
    final = writer.close("stopped", "cancelled at t = 0.05 s", steps=60, simulated_time_s=0.06)
    assert final["status"] == "stopped" and final["steps"] == 60
    res = Results(tmp_path / "r")
    assert (res.status, res.message, len(res)) == ("stopped", "cancelled at t = 0.05 s", 2)


def test_close_rejects_unknown_status(tmp_path):
    writer = ResultsWriter(tmp_path / "r", "", {})
    with pytest.raises(ValueError, match="completed"):
        writer.close("done")
    writer.close("completed")


def test_write_failure_surfaces_and_fails_the_run(tmp_path):
    writer = ResultsWriter(tmp_path / "r", "", {})
    frame = synthetic_frames(1)[0]
    bad = type(frame)(frame.diagnostics, {**frame.fields, "velocity": np.zeros((3, 2))})
    writer.write_frame(bad)  # wrong row count: fails in the writer thread
    writer.flush()
    with pytest.raises(ResultsError, match="writing results failed"):
        writer.write_frame(frame)
    summary = writer.close("completed")
    assert summary["status"] == "failed"
    assert "3 rows for 800 particles" in summary["message"]


def test_context_manager_records_an_exception_as_failed(tmp_path):
    with pytest.raises(RuntimeError):
        with ResultsWriter(tmp_path / "r", "", {}) as writer:
            writer.write_frame(synthetic_frames(1)[0])
            raise RuntimeError("solver exploded")
    res = Results(tmp_path / "r")
    assert res.status == "failed"
    assert "solver exploded" in res.message
    assert len(res) == 1


def test_existing_results_folder_is_replaced_other_folders_are_refused(tmp_path, make_results):
    old = make_results("old.results", n_frames=4)
    with pytest.raises(ResultsError, match="--overwrite"):
        ResultsWriter(old, "", {})
    assert len(Results(old)) == 4
    writer = ResultsWriter(old, "", {}, overwrite=True)
    writer.write_frame(synthetic_frames(1)[0])
    writer.close("completed")
    assert len(Results(old)) == 1  # no frames left over from the old run

    precious = tmp_path / "documents"
    precious.mkdir()
    (precious / "thesis.tex").write_text("do not delete")
    with pytest.raises(ResultsError, match="not a results folder"):
        prepare_results_dir(precious, overwrite=True)
    assert (precious / "thesis.tex").read_text() == "do not delete"
    (tmp_path / "afile").write_text("x")
    with pytest.raises(ResultsError, match="not a folder"):
        prepare_results_dir(tmp_path / "afile")


def test_particle_history(make_results):
    path = make_results(n_frames=4)
    frames = synthetic_frames(4)
    times, values = Results(path).particle_history(799, "displacement")
    np.testing.assert_allclose(times, [0.0, 0.05, 0.1, 0.15])
    want = np.array([f.fields["displacement"][799] for f in frames])
    np.testing.assert_allclose(values, want, rtol=1e-6, atol=1e-8)
    assert values.shape == (4, 2)
    _, stress_yy = Results(path).particle_history(0, "stress")
    assert stress_yy.shape == (4, 4)
    with pytest.raises(KeyError, match="no field 'pressure'"):
        Results(path).particle_history(0, "pressure")
    with pytest.raises(IndexError):
        Results(path).particle_history(800, "displacement")


def test_frame_index_errors(make_results):
    res = Results(make_results(n_frames=2))
    with pytest.raises(IndexError, match="out of range"):
        res.frame(2)
    with pytest.raises(IndexError):
        res.frame(-3)


def test_not_a_results_folder(tmp_path):
    with pytest.raises(ResultsError, match="not a results folder"):
        Results(tmp_path)
    with pytest.raises(ResultsError, match="no such results folder"):
        Results(tmp_path / "missing")


def test_encode_vtp_validates_shapes(tmp_path):
    with pytest.raises(ValueError, match="positions"):
        encode_vtp({"positions": np.zeros((3, 3)), "active": np.ones(3, bool)}, 0.0)
    data = encode_vtp({"positions": np.zeros((0, 2)), "active": np.zeros(0, bool)}, 1.5)
    (tmp_path / "empty.vtp").write_bytes(data)
    arrays = read_vtp(tmp_path / "empty.vtp")
    assert arrays["Points"].shape == (0, 3)
