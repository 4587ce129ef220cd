"""Results folders belong to their run: marker, overwrite, lock, full disk, exports beside them."""

from __future__ import annotations

import errno
import json
import os
import subprocess
import sys
import threading

import numpy as np
import pytest

import projects.atomic as atomic
import projects.results as results_module
from projects.results import Results, ResultsWriter, encode_vtp, read_vtp
from projects.results_folder import (
    LOCK_NAME,
    MARKER_NAME,
    ResultsError,
    ResultsExistError,
    ResultsLockedError,
    check_results_dir,
    export_path,
    lock_folder,
    lock_holder,
    own_files,
)
from tests.conftest import SYNTHETIC_META, SYNTHETIC_PROJECT, synthetic_frames


def _write(folder, n_frames=3, **kwargs):
    writer = ResultsWriter(folder, SYNTHETIC_PROJECT, dict(SYNTHETIC_META), **kwargs)
    for frame in synthetic_frames(n_frames):
        writer.write_frame(frame)
    return writer.close("completed")


def test_a_run_marks_its_folder_and_lists_its_own_files(tmp_path):
    folder = tmp_path / "r.results"
    _write(folder)
    marker = json.loads((folder / MARKER_NAME).read_text())
    assert marker["format"] == "runout-results"
    assert "frames/frame_*.vtp" in marker["files"]
    (folder / "notes.txt").write_text("mine")
    owned = {p.relative_to(folder).as_posix() for p in own_files(folder, marker["files"])}
    assert owned == {"particles.pvd", "series.csv", "summary.json", "project.toml", "contacts.csv",
                     "frames/frame_00000.vtp", "frames/frame_00001.vtp", "frames/frame_00002.vtp"}
    assert not (folder / LOCK_NAME).exists()  # released at close


def test_overwrite_removes_only_the_runs_own_files(tmp_path):
    folder = tmp_path / "r.results"
    _write(folder, n_frames=5)
    (folder / "displacement_00004.png").write_bytes(b"a picture")
    (folder / "frames" / "sketch.txt").write_text("note beside the frames")
    (folder / "project.toml.bak").write_text("a backup")
    (folder / ".summary.json.999.tmp").write_text("left by a killed run")
    with pytest.raises(ResultsExistError, match="--overwrite"):
        _write(folder)
    assert len(Results(folder)) == 5  # refused: nothing touched
    _write(folder, n_frames=2, overwrite=True)
    assert len(Results(folder)) == 2
    assert sorted(p.name for p in (folder / "frames").iterdir()) == [
        "frame_00000.vtp", "frame_00001.vtp", "sketch.txt"]
    assert (folder / "displacement_00004.png").read_bytes() == b"a picture"
    assert (folder / "project.toml.bak").read_text() == "a backup"
    assert not (folder / ".summary.json.999.tmp").exists()


@pytest.mark.parametrize("overwrite", [False, True])
def test_a_folder_without_a_marker_is_never_written_into(tmp_path, overwrite):
    project_folder = tmp_path / "project"
    (project_folder / "frames").mkdir(parents=True)  # looks like results, but is not ours
    (project_folder / "slope.toml").write_text("[runout]\n")
    with pytest.raises(ResultsError) as info:
        ResultsWriter(project_folder, "", {}, overwrite=overwrite)
    assert "\n" not in str(info.value)
    assert (project_folder / "slope.toml").read_text() == "[runout]\n"
    assert sorted(p.name for p in project_folder.iterdir()) == ["frames", "slope.toml"]


def test_a_second_writer_into_a_locked_folder_gets_one_line(tmp_path):
    folder = tmp_path / "r.results"
    first = ResultsWriter(folder, "", {})
    try:
        assert lock_holder(folder) == os.getpid()
        for overwrite in (False, True):
            with pytest.raises(ResultsLockedError) as info:
                ResultsWriter(folder, "", {}, overwrite=overwrite)
            assert f"process {os.getpid()}" in str(info.value) and "\n" not in str(info.value)
        with pytest.raises(ResultsLockedError):
            check_results_dir(folder, overwrite=True)
    finally:
        first.close("completed")
    assert lock_holder(folder) is None
    assert Results(folder).status == "completed"


def test_concurrent_writers_one_wins_the_other_is_refused(tmp_path):
    folder = tmp_path / "r.results"
    outcomes: list[str] = []
    barrier = threading.Barrier(4)
    writers = []

    def start() -> None:
        barrier.wait()
        try:
            writers.append(ResultsWriter(folder, "", {}, overwrite=True))
            outcomes.append("writing")
        except ResultsLockedError:
            outcomes.append("locked")
        except ResultsExistError:
            outcomes.append("exists")

    threads = [threading.Thread(target=start) for _ in range(4)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert outcomes.count("writing") == 1, outcomes
    for writer in writers:
        writer.close("completed")


def test_the_lock_of_a_dead_process_is_stale(tmp_path):
    folder = tmp_path / "r.results"
    folder.mkdir()
    # a process that takes the lock and dies without releasing it (as a SIGKILL would)
    code = ("import os, sys; from projects.results_folder import lock_folder; "
            "lock_folder(sys.argv[1]); os._exit(0)")
    env = dict(os.environ, PYTHONPATH=os.getcwd())
    subprocess.run([sys.executable, "-c", code, str(folder)], check=True, env=env)
    dead_pid = int((folder / LOCK_NAME).read_text())
    assert dead_pid != os.getpid()
    assert lock_holder(folder) is None
    lock = lock_folder(folder)
    assert int((folder / LOCK_NAME).read_text()) == os.getpid()
    lock.release()
    assert not (folder / LOCK_NAME).exists()


def test_exports_default_beside_the_results_folder(tmp_path):
    assert export_path(tmp_path / "slope.results", "displacement_00012") == tmp_path / "slope_displacement_00012.png"
    assert export_path(tmp_path / "out", "run", ".mp4") == tmp_path / "out_run.mp4"


# --------------------------------------------------------------------------------------------
# failures: every path ends with a final summary and no temporary files


def _fail_after(monkeypatch, calls: int, err: int = errno.ENOSPC) -> None:
    """Make the writer's temporary files fail half way with ``err`` (a full disk) after
    ``calls`` of them were written whole; the writer's own clean-up code runs as it would."""
    real_open = open
    count = {"n": 0}

    class Full:
        def __init__(self, handle):
            self.handle = handle

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            self.handle.close()

        def write(self, data):
            self.handle.write(data[: len(data) // 2])
            raise OSError(err, os.strerror(err))

    def fake_open(path, mode="r", *args, **kwargs):
        handle = real_open(path, mode, *args, **kwargs)
        if ("w" in mode or "x" in mode) and str(path).endswith(".tmp"):
            count["n"] += 1
            if count["n"] > calls:
                return Full(handle)
        return handle

    monkeypatch.setattr(atomic, "open", fake_open, raising=False)


def test_disk_full_while_writing_frames_ends_failed_without_temp_files(tmp_path, monkeypatch):
    folder = tmp_path / "r.results"
    writer = ResultsWriter(folder, SYNTHETIC_PROJECT, dict(SYNTHETIC_META))
    _fail_after(monkeypatch, calls=4)
    frames = synthetic_frames(6)
    with pytest.raises(ResultsError, match="No space left"):
        for frame in frames:
            writer.write_frame(frame)
            writer.flush()
    summary = writer.close("completed")
    monkeypatch.undo()
    assert summary["status"] == "failed" and "No space left" in summary["message"]
    on_disk = json.loads((folder / "summary.json").read_text())
    assert on_disk["status"] == "failed"
    assert not list(folder.rglob("*.tmp"))
    assert not (folder / ".runout-reserve").exists() and not (folder / LOCK_NAME).exists()
    assert Results(folder).status == "failed"


def test_a_new_run_that_cannot_start_on_a_full_disk_leaves_no_results_folder_behind(tmp_path, monkeypatch):
    """The disk full before the first summary: the writer removes the marker and the folders it
    made (a marker and an empty frames/ left behind would make the folder read as an interrupted
    run, and the next run, once space was freed, would be refused as 'holds the results of an
    earlier run')."""
    folder = tmp_path / "r.results"
    _fail_after(monkeypatch, calls=0)  # the first atomic write (project.toml) fails
    with pytest.raises(ResultsError, match="No space left"):
        ResultsWriter(folder, SYNTHETIC_PROJECT, dict(SYNTHETIC_META))
    monkeypatch.undo()
    assert not folder.exists()  # the run made it: gone again, with nothing of the run's in it
    ResultsWriter(folder, SYNTHETIC_PROJECT, dict(SYNTHETIC_META)).close("completed")  # no --overwrite
    assert Results(folder).status == "completed"


def test_the_final_summary_is_written_even_when_the_disk_stays_full(tmp_path, monkeypatch):
    folder = tmp_path / "r.results"
    writer = ResultsWriter(folder, SYNTHETIC_PROJECT, dict(SYNTHETIC_META))
    writer.write_frame(synthetic_frames(1)[0])
    writer.flush()
    _fail_after(monkeypatch, calls=0)  # no atomic write succeeds any more
    writer.close("completed")
    monkeypatch.undo()
    assert json.loads((folder / "summary.json").read_text())["status"] == "completed"
    assert not list(folder.rglob("*.tmp")) and not (folder / LOCK_NAME).exists()


def test_the_real_atomic_write_removes_its_temp_file_on_failure(tmp_path, monkeypatch):
    target = tmp_path / "summary.json"

    _fail_after(monkeypatch, calls=0)
    with pytest.raises(OSError):
        atomic.write_atomic(target, b"{}")
    monkeypatch.undo()
    assert list(tmp_path.iterdir()) == []


def test_a_folder_that_cannot_be_written_is_one_line_and_leaves_nothing(tmp_path, monkeypatch):
    folder = tmp_path / "r.results"

    def read_only(*args, **kwargs):
        raise OSError(errno.EROFS, "Read-only file system")

    monkeypatch.setattr(results_module, "_write_reserve", read_only)
    with pytest.raises(ResultsError) as info:
        ResultsWriter(folder, "", {})
    monkeypatch.undo()
    assert "Read-only file system" in str(info.value) and "\n" not in str(info.value)
    assert not (folder / LOCK_NAME).exists()
    ResultsWriter(folder, "", {}, overwrite=True).close("completed")  # the lock was released


# --------------------------------------------------------------------------------------------
# real-world coordinates


def test_points_far_from_the_origin_are_written_in_float64(tmp_path):
    rng = np.random.default_rng(1)
    local = rng.uniform(0.0, 10.0, size=(50, 2))
    origin = np.array([500_000.0, 4_000_000.0])  # UTM metres
    data = encode_vtp({"positions": origin + local}, 0.0)
    path = tmp_path / "f.vtp"
    path.write_bytes(data)
    points = read_vtp(path, {"Points"})["Points"]
    assert points.dtype == np.float64
    np.testing.assert_allclose(points[:, :2] - origin, local, rtol=0, atol=1e-9)
    near = tmp_path / "g.vtp"
    near.write_bytes(encode_vtp({"positions": local}, 0.0))
    assert read_vtp(near, {"Points"})["Points"].dtype == np.float32


def test_the_writer_chooses_float64_points_from_the_domain(tmp_path):
    meta = dict(SYNTHETIC_META, domain={"origin_m": [500_000.0, 4_000_000.0], "size_m": [0.8, 0.15]})
    writer = ResultsWriter(tmp_path / "utm", "", meta)
    frame = synthetic_frames(1)[0]
    shifted = dict(frame.fields, positions=frame.fields["positions"] + np.array([500_000.0, 4_000_000.0]))
    writer.write_frame(type(frame)(frame.diagnostics, shifted))
    writer.close("completed")
    positions = Results(tmp_path / "utm").frame(0)["positions"]
    assert positions.dtype == np.float64
    assert len(np.unique(positions, axis=0)) == len(positions)
