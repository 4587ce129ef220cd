"""`runout run --resume` after SIGKILL or a stop reproduces the uninterrupted run (serial scatter: bit
for bit, frames numbered as its); a resume checks the size limits first; `--start-from` takes only a
run of the same particles."""

import os
import signal
import subprocess
import sys
import time

import numpy as np


from projects.document import load_project
from projects.results import CHECKPOINT_NAME, Results
from projects.runner import run_project
from tests.conftest import REPO, TINY_PROJECT

# 1 s of collapse (5,000 steps): the run is killed after its second checkpoint (t = 0.1 s), seconds
# before its end even on a loaded machine; frames every 0.05 s
SETS = ["numerics.advanced.scatter=serial", "stages.1.duration_s=1.0", "output.interval_s=0.05",
        "output.checkpoint_interval_s=0.1"]
FRAMES = 21  # t = 0 (the k0 stage's end) and every 0.05 s of the 1 s collapse


def _cli(*args: str) -> list[str]:
    return [sys.executable, "-m", "app.cli", *args]



def test_resume_after_sigkill_gives_the_frames_of_the_uninterrupted_run(tmp_path):
    killed = tmp_path / "killed"
    sets = [a for s in SETS for a in ("--set", s)]
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    child = subprocess.Popen(_cli("run", str(TINY_PROJECT), "--out", str(killed), "--quiet", *sets),
                             cwd=REPO, env=env)
    deadline = time.monotonic() + 240
    # kill it after its second checkpoint (the first comes with the first frames)
    seen = 0
    last = None
    while time.monotonic() < deadline and child.poll() is None:
        ckpt = killed / CHECKPOINT_NAME
        if ckpt.exists() and ckpt.stat().st_mtime_ns != last:
            last = ckpt.stat().st_mtime_ns
            seen += 1
            if seen >= 2:
                break
        time.sleep(0.02)
    assert child.poll() is None, "the run ended before it could be killed"
    child.send_signal(signal.SIGKILL)
    child.wait(timeout=30)
    interrupted = Results(killed)
    assert interrupted.status in ("interrupted", "running")
    assert 0 < len(interrupted) < FRAMES

    done = subprocess.run(_cli("run", "--resume", str(killed), "--quiet"), cwd=REPO, env=env,
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr

    reference = tmp_path / "reference"
    result = run_project(load_project(TINY_PROJECT, SETS), reference)
    assert result.ok

    # the run is complete now: resuming it again is a one-line error, with no progress bar before it
    again = subprocess.run(_cli("run", "--resume", str(killed)), cwd=REPO, env=env, capture_output=True,
                           text=True, timeout=120)
    assert again.returncode != 0 and again.stderr.strip().splitlines() == [
        f"error: the run in {killed} is complete: nothing to resume"], again.stderr

    a, b = Results(killed), Results(reference)
    assert a.status == "completed" and len(a) == len(b) == FRAMES
    for column in ("time_s", "step", "kinetic_energy_J_per_m", "momentum_x", "momentum_y", "max_speed_m_s"):
        np.testing.assert_array_equal(a.series[column], b.series[column], err_msg=column)
    for i in range(len(b)):
        fa, fb = a.frame(i), b.frame(i)
        assert fa.keys() == fb.keys()
        for name in fb:
            np.testing.assert_array_equal(fa[name], fb[name], err_msg=f"frame {i} {name}")


def test_resume_refuses_what_it_cannot_continue(tmp_path):
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    missing = subprocess.run(_cli("run", "--resume", str(tmp_path)), cwd=REPO, env=env, capture_output=True,
                             text=True, timeout=120)
    assert missing.returncode != 0 and "results folder" in missing.stderr and "Traceback" not in missing.stderr
    both = subprocess.run(_cli("run", str(TINY_PROJECT), "--resume", str(tmp_path)), cwd=REPO, env=env,
                          capture_output=True, text=True, timeout=120)
    assert both.returncode != 0 and "not both" in both.stderr


def test_resume_of_a_stopped_run_gives_the_frames_of_the_uninterrupted_run(tmp_path):
    """A stop (SIGTERM, Ctrl-C, the workbench's Stop) ends the run with a frame at the stop time,
    between two output times. The resumed run continues from that state and gives the frames of
    the uninterrupted run, numbered as they are: the stop frame is not one of them, and the force
    on each contact over the interval the stop cut in two is the whole interval's."""
    from projects.results import read_contacts
    from projects.runner import StopRequest, resume_run

    sets = SETS[:1] + ["stages.1.duration_s=0.3", "output.interval_s=0.05"]
    stop = StopRequest()

    def on_progress(progress):
        if progress.time_s > 0.12:  # mid-way between the frames at 0.10 and 0.15 s
            stop.request("test")

    stopped = tmp_path / "stopped"
    first = run_project(load_project(TINY_PROJECT, sets), stopped, cancel=stop, on_progress=on_progress)
    assert first.status == "stopped"
    times = Results(stopped).series["time_s"]
    assert 0.12 < times[-1] < 0.15 - 1e-6, times  # the stop frame, off the output times
    resumed = resume_run(stopped)
    assert resumed.ok, resumed.message
    reference = tmp_path / "reference"
    assert run_project(load_project(TINY_PROJECT, sets), reference).ok

    a, b = Results(stopped), Results(reference)
    assert a.status == "completed" and len(a) == len(b) == 7  # t = 0 and every 0.05 s of 0.3 s
    for column in ("time_s", "step", "stage"):
        np.testing.assert_array_equal(a.series[column], b.series[column], err_msg=column)
    for i in range(len(b)):
        fa, fb = a.frame(i), b.frame(i)
        for name in fb:
            np.testing.assert_array_equal(fa[name], fb[name], err_msg=f"frame {i} {name}")
    ca, cb = read_contacts(stopped), read_contacts(reference)
    assert ca.keys() == cb.keys()
    for contact in cb:
        for column, values in cb[contact].items():
            np.testing.assert_allclose(ca[contact][column], values, rtol=1e-9, atol=1e-9,
                                       err_msg=f"{contact} {column}")


def test_resume_checks_the_size_limits_before_it_takes_memory(tmp_path):
    """The folder's project.toml is what a resume builds: one edited to a run too large for the
    machine (or a run that needed --force) is refused by the size limits, naming the key, before
    any particle is seeded; `--force` goes past them as for a new run."""
    from projects.runner import StopRequest

    stop = StopRequest()
    stop.request("test")  # stopped at its first check: a checkpoint to resume from
    stopped = tmp_path / "stopped"
    assert run_project(load_project(TINY_PROJECT, SETS[:1]), stopped, cancel=stop).status == "stopped"
    project = stopped / "project.toml"
    project.write_text(project.read_text().replace("cell_size_m = 0.02", "cell_size_m = 1e-06"))
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    done = subprocess.run(_cli("run", "--resume", str(stopped), "--quiet"), cwd=REPO, env=env,
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 1, done.stderr
    assert "domain.cell_size_m = 1e-06: the run would" in done.stderr and "--force" in done.stderr, done.stderr
    assert "Traceback" not in done.stderr


def test_start_from_takes_the_particle_state_of_a_run_of_the_same_particles_only(tmp_path):
    """`--start-from RESULTS` starts a project's stages from another run's particle state; the runs
    must have the same particles: a project of another scene with as many particles (a different
    density, hence masses; another material) is refused with one line, not silently started
    from a state that is not its own."""
    from projects.results import ResultsError

    source = tmp_path / "source"
    assert run_project(load_project(TINY_PROJECT, SETS[:1]), source).ok
    last = Results(source).frame(len(Results(source)) - 1)
    # the same particles: the next run's first frame is the source's last state
    follow = run_project(load_project(TINY_PROJECT, SETS[:1] + ["stages.0.k0=0.5"]), tmp_path / "follow",
                         start_from=source)
    assert follow.ok, follow.message
    np.testing.assert_array_equal(Results(tmp_path / "follow").frame(0)["velocity"], last["velocity"])
    for change in ("materials.sand.density_kg_m3=2500.0", "bodies.0.polygon_m=[[0.2,0],[0.32,0],[0.32,0.24],[0.2,0.24]]"):
        other = load_project(TINY_PROJECT, SETS[:1] + [change])
        try:
            run_project(other, tmp_path / "other", start_from=source)
        except ResultsError as err:
            assert "not this project's" in str(err) and "\n" not in str(err), err
        else:
            raise AssertionError(f"{change}: started from the state of another scene")


def test_start_from_refuses_a_state_with_particles_inside_a_structure_of_the_project(tmp_path):
    """A project that adds a structure where the other run's material has moved to (not where it
    was seeded: the particles are the same) would start with particles inside the structure, which
    the solver then pushes to the nearest face (into a neighbouring structure, out of a thin one):
    refused with one line naming the structure."""
    from projects.results import ResultsError

    source = tmp_path / "source"
    assert run_project(load_project(TINY_PROJECT, SETS[:1] + ["stages.1.duration_s=0.2"]), source).ok
    last = Results(source).frame(len(Results(source)) - 1)["positions"]
    box = ((0.14, 0.0), (0.2, 0.04))  # right of the column as seeded (x <= 0.12); its toe runs into it
    covered = ((last[:, 0] > box[0][0]) & (last[:, 0] < box[1][0]) & (last[:, 1] < box[1][1])).sum()
    assert covered > 0, "the collapse no longer reaches the box: move it"
    wall = ('structures=[{name="wall",polygon_m=[[0.14,0.0],[0.2,0.0],[0.2,0.04],[0.14,0.04]]}]')
    try:
        run_project(load_project(TINY_PROJECT, SETS[:1] + [wall]), tmp_path / "walled", start_from=source)
    except ResultsError as err:
        assert "inside structures.0 ('wall')" in str(err) and "\n" not in str(err), err
        assert f"{covered} of its particles" in str(err), err
    else:
        raise AssertionError("started with particles inside a structure")
    assert not (tmp_path / "walled").exists()  # refused before the results folder was made
