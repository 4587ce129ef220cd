"""Reading results folders whose run was killed part way."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

from projects.results import Results, ResultsWriter
from tests.conftest import REPO, SYNTHETIC_META, synthetic_frames


def _abandoned(tmp_path, n_frames=4):
    """A writer that wrote frames and was never closed (as after a crash)."""
    writer = ResultsWriter(tmp_path / "r", "", dict(SYNTHETIC_META))
    for frame in synthetic_frames(n_frames):
        writer.write_frame(frame)
    writer.flush()
    return tmp_path / "r"


def test_truncated_last_frame_and_missing_pvd(tmp_path):
    path = _abandoned(tmp_path)
    last = path / "frames" / "frame_00003.vtp"
    data = last.read_bytes()
    last.write_bytes(data[: len(data) // 2])  # the run died while writing it
    (path / "particles.pvd").unlink()
    with open(path / "series.csv", "a") as fh:
        fh.write("4,0.2,collapse,1,0.2,2")  # half a row, no newline

    res = Results(path)
    assert res.status == "interrupted"
    assert "killed" in res.message
    assert len(res) == 3
    np.testing.assert_allclose(res.times, [0.0, 0.05, 0.1])  # times from the frame headers
    np.testing.assert_allclose(
        res.frame(-1)["displacement"], synthetic_frames(4)[2].fields["displacement"], rtol=1e-6, atol=1e-8
    )
    assert len(res.series["time_s"]) == 4  # the partial row is dropped
    times, _ = res.particle_history(10, "velocity")
    assert len(times) == 3


def test_pvd_listing_a_damaged_frame_skips_it(tmp_path):
    path = _abandoned(tmp_path)
    (path / "frames" / "frame_00001.vtp").write_bytes(b"<?xml")
    res = Results(path)
    np.testing.assert_allclose(res.times, [0.0, 0.1, 0.15])
    assert res.frame(1)["positions"].shape == (800, 2)


def test_damaged_pvd_falls_back_to_the_frames_folder(tmp_path):
    path = _abandoned(tmp_path)
    text = (path / "particles.pvd").read_text()
    (path / "particles.pvd").write_text(text[: len(text) // 2])
    res = Results(path)
    assert len(res) == 4
    np.testing.assert_allclose(res.times, [0.0, 0.05, 0.1, 0.15])


WRITER_SCRIPT = textwrap.dedent(
    """
    import sys, time
    sys.path.insert(0, {repo!r})
    from projects.results import ResultsWriter
    from tests.conftest import SYNTHETIC_META, synthetic_frames
    frames = synthetic_frames(3)
    writer = ResultsWriter(sys.argv[1], "", dict(SYNTHETIC_META))
    i = 0
    while True:  # write frames until killed
        writer.write_frame(frames[i % 3])
        writer.flush()
        i += 1
        print(i, flush=True)
        time.sleep(0.01)
    """
)


@pytest.mark.skipif(sys.platform == "win32", reason="SIGKILL")
def test_run_killed_with_sigkill_reads_up_to_its_last_frame(tmp_path):
    out = tmp_path / "killed.results"
    proc = subprocess.Popen(
        [sys.executable, "-c", WRITER_SCRIPT.format(repo=str(REPO)), str(out)],
        stdout=subprocess.PIPE, text=True, cwd=tmp_path,
    )
    try:
        deadline = time.monotonic() + 60
        written = 0
        while written < 5 and time.monotonic() < deadline:
            line = proc.stdout.readline()
            if not line:
                break
            written = int(line)
        assert written >= 5, "the writer subprocess did not get going"
    finally:
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)
        proc.stdout.close()

    assert json.loads((out / "summary.json").read_text())["status"] == "running"
    res = Results(out)
    assert res.status == "interrupted"
    assert len(res) >= written
    # every listed frame is complete and has every field
    for i in (0, len(res) - 1):
        arrays = res.frame(i)
        assert arrays["positions"].shape == (800, 2)
        assert np.isfinite(arrays["stress"]).all()
    assert len(res.series["time_s"]) >= len(res)


@pytest.mark.parametrize("damage", ["truncated", "empty", "text", "no-run"])
def test_a_damaged_checkpoint_is_a_one_line_results_error(tmp_path, damage):
    """``--resume`` and ``--start-from`` on a folder whose checkpoint.npz was cut short (a full disk,
    a copy interrupted) or replaced: a ResultsError naming the file, never a traceback."""
    import io

    from projects.results import CHECKPOINT_NAME, ResultsError, read_checkpoint

    buffer = io.BytesIO()
    np.savez(buffer, **{"state/x": np.zeros((4, 2)), "fingerprint": np.frombuffer(b"abc", np.uint8)},
             **({} if damage == "no-run" else {"run": np.frombuffer(b"{}", np.uint8)}))
    good = buffer.getvalue()
    data = {"truncated": good[: len(good) // 2], "empty": b"", "text": b"hello\n", "no-run": good}[damage]
    (tmp_path / CHECKPOINT_NAME).write_bytes(data)
    with pytest.raises(ResultsError, match="cannot read the checkpoint") as err:
        read_checkpoint(tmp_path)
    assert "\n" not in str(err.value)


def test_a_missing_checkpoint_names_the_path_given(tmp_path):
    """``--start-from`` with a mistyped folder names that folder (not "no checkpoint in" its
    parent, which the user never typed)."""
    from projects.results import ResultsError, read_checkpoint

    with pytest.raises(ResultsError) as err:
        read_checkpoint(tmp_path / "slope.reslts")
    assert str(err.value) == f"no such results folder or checkpoint: {tmp_path / 'slope.reslts'}"
    with pytest.raises(ResultsError, match=f"no checkpoint in {tmp_path}"):
        read_checkpoint(tmp_path)  # a folder without one: as before


def test_resume_of_a_run_that_ended_before_its_first_checkpoint_says_what_to_do(tmp_path):
    """A run killed during its start-up has a results folder but no checkpoint: the one line says
    so and how to go on (it said only that a run writes checkpoint.npz at its checkpoints)."""
    from projects.results import ResultsError, ResultsWriter
    from projects.runner import resumable
    from tests.conftest import SYNTHETIC_PROJECT

    ResultsWriter(tmp_path / "r.results", SYNTHETIC_PROJECT, dict(SYNTHETIC_META)).close("failed", "killed")
    with pytest.raises(ResultsError) as err:
        resumable(tmp_path / "r.results")
    assert str(err.value) == (f"no checkpoint in {tmp_path / 'r.results'}: the run ended before its first "
                              "checkpoint; run the project again into it with --overwrite")


def test_resume_of_a_folder_a_live_run_is_writing_names_the_run(tmp_path):
    """`runout run --resume` on the folder of a run that is still going: the folder is in use (one
    line naming the process), not "no checkpoint" (it may not have written one yet)."""
    from projects.results import ResultsError
    from projects.runner import resumable

    writer = ResultsWriter(tmp_path / "live", "", dict(SYNTHETIC_META))
    try:
        with pytest.raises(ResultsError, match=f"in use by another run \\(process {os.getpid()}\\)"):
            resumable(tmp_path / "live")
    finally:
        writer.close("completed")


def test_resume_of_a_strength_reduction_run_says_why_it_cannot(tmp_path):
    """A strength-reduction run keeps its search in memory and writes no checkpoint part-way
    (docs/project-format.md): resuming a stopped one says so and what to do, not only "no
    checkpoint"."""
    from projects.results import ResultsError
    from projects.runner import resumable
    from tests.conftest import EXAMPLES

    writer = ResultsWriter(tmp_path / "fos", (EXAMPLES / "slope_fos.toml").read_text(), dict(SYNTHETIC_META))
    writer.close("stopped")
    with pytest.raises(ResultsError, match="strength-reduction run cannot be resumed") as err:
        resumable(tmp_path / "fos")
    assert "run it again" in str(err.value) and "\n" not in str(err.value)
