"""``runout run --progress jsonl``: the machine-readable progress the workbench reads from its child runs."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

from projects.results import Results
from tests.conftest import REPO


def run_jsonl(*args: str, cwd: Path) -> tuple[subprocess.CompletedProcess[str], list[dict]]:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")]))
    proc = subprocess.run([sys.executable, "-m", "app.cli", "run", *args, "--progress", "jsonl"],
                          cwd=cwd, capture_output=True, text=True, timeout=240, env=env)
    # every line of standard output is one JSON object (Taichi's chatter goes to standard error)
    events = [json.loads(line) for line in proc.stdout.splitlines()]
    return proc, events


def test_jsonl_reports_start_progress_frames_and_the_end(tiny_project, tmp_path):
    out = tmp_path / "tiny.results"
    proc, events = run_jsonl(str(tiny_project), "--out", str(out), cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    kinds = [e["event"] for e in events]
    assert kinds[0] == "started" and kinds[-1] == "finished"
    assert kinds.count("started") == 1 and kinds.count("finished") == 1
    started, finished = events[0], events[-1]
    assert started["out_dir"] == str(out) and started["particles"] == 288
    assert started["total_time_s"] == 0.05
    frames = [e for e in events if e["event"] == "frame"]
    results = Results(out)
    assert [e["index"] for e in frames] == list(range(len(results)))
    assert [e["time_s"] for e in frames] == list(results.times)
    for e in (e for e in events if e["event"] == "progress"):
        assert {"time_s", "total_time_s", "stage", "step", "steps_per_s", "particle_steps_per_s"} <= set(e)
        assert 0.0 <= e["time_s"] <= e["total_time_s"]
    assert finished["status"] == "completed" and finished["summary"]["frames"] == len(results)
    assert finished["summary"] == results.summary


def test_jsonl_reports_a_run_that_cannot_start(tiny_project, tmp_path):
    occupied = tmp_path / "notes"
    occupied.mkdir()
    (occupied / "keep.txt").write_text("keep")
    proc, events = run_jsonl(str(tiny_project), "--out", str(occupied), cwd=tmp_path)
    assert proc.returncode == 1
    assert [e["event"] for e in events] == ["finished"]
    assert events[0]["status"] == "error" and "refusing to overwrite" in events[0]["message"]
    bad = tmp_path / "bad.toml"
    bad.write_text(tiny_project.read_text().replace("density_kg_m3 = 2000.0", "density_kg_m3 = -2000.0"))
    proc, events = run_jsonl(str(bad), cwd=tmp_path)
    assert proc.returncode == 1
    assert events[0]["status"] == "error" and "materials.sand.density_kg_m3" in events[0]["message"]
    assert (occupied / "keep.txt").read_text() == "keep"


def test_jsonl_of_a_resume_numbers_frames_as_the_folder_does(tiny_project, tmp_path):
    """`runout run --resume RESULTS --progress jsonl`: the frame events carry the frames' numbers
    in the folder (not counted from 0 again, which would have a program following the run read
    frame 0 for frame_00003.vtp); `started` says the first."""
    from projects.document import load_project
    from projects.runner import run_project

    out = tmp_path / "stopped.results"
    sets = ["numerics.advanced.scatter=serial", "output.interval_s=0.005", "output.checkpoint_interval_s=0.01"]
    frames_seen = []
    stopped = run_project(load_project(tiny_project, sets), out, on_frame=frames_seen.append,
                          cancel=lambda: len(frames_seen) >= 4)  # stops after its fourth frame
    assert stopped.status == "stopped", stopped.message
    proc, events = run_jsonl("--resume", str(out), cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    started = events[0]
    frames = [e for e in events if e["event"] == "frame"]
    results = Results(out)
    assert started["event"] == "started" and 0 < started["first_frame"] < len(results)
    assert [e["index"] for e in frames] == list(range(started["first_frame"], len(results)))
    assert [e["time_s"] for e in frames] == list(results.times[started["first_frame"]:])
