"""``runout render`` and ``runout animate`` in a subprocess, on a synthetic results folder."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import REPO

imageio = pytest.importorskip("imageio.v3")


def runout(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(REPO), env.get("PYTHONPATH", "")])
    return subprocess.run(
        [sys.executable, "-m", "app.cli", *args], cwd=cwd, capture_output=True, text=True,
        timeout=180, env=env,
    )


def test_render_png(make_results, tmp_path):
    folder = make_results()
    png = tmp_path / "pics" / "syy.png"
    proc = runout("render", str(folder), "--field", "stress_yy", "--frame", "1", "-o", str(png),
                  "--size", "400x300", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == str(png)
    assert imageio.imread(png).shape[:2] == (300, 400)
    assert "bad X server" not in proc.stderr

    last = runout("render", str(folder), "--size", "320x200", cwd=tmp_path)
    assert last.returncode == 0, last.stderr
    assert Path(last.stdout.strip()) == folder.parent / "synthetic_displacement_00003.png"


def test_render_errors_are_one_line(make_results, tmp_path):
    folder = make_results()
    cases = {
        ("--field", "pressure"): "unknown field 'pressure'; allowed: displacement",
        ("--frame", "abc"): "--frame must be a frame number or 'last'",
        ("--frame", "99"): "out of range",
        ("--size", "big"): "--size must look like 1600x900",
    }
    for args, message in cases.items():
        proc = runout("render", str(folder), *args, cwd=tmp_path)
        assert proc.returncode == 1, (args, proc.stderr)
        assert proc.stderr.startswith("error: ") and message in proc.stderr, proc.stderr
        assert len(proc.stderr.strip().splitlines()) == 1, proc.stderr
    missing = runout("render", str(tmp_path / "nothing.results"), cwd=tmp_path)
    assert missing.returncode == 1
    assert "no such results folder" in missing.stderr and "Traceback" not in missing.stderr


def test_animate_gif(make_results, tmp_path):
    folder = make_results(n_frames=3)
    gif = tmp_path / "run.gif"
    proc = runout("animate", str(folder), "-o", str(gif), "--field", "velocity", "--fps", "4",
                  "--size", "200x120", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert imageio.imread(gif, index=None).shape[0] == 3
    bad = runout("animate", str(folder), "-o", str(tmp_path / "run.avi"), cwd=tmp_path)
    assert bad.returncode == 1 and ".mp4 or .gif" in bad.stderr


def test_help_lists_the_commands(tmp_path):
    proc = runout("--help", cwd=tmp_path)
    assert proc.returncode == 0
    for command in ("run", "validate", "render", "animate", "gui"):
        assert command in proc.stdout


def test_pictures_and_movies_where_nothing_can_be_written_are_one_line_errors(make_results, tmp_path):
    """A picture or movie whose folder cannot be made or written (a read-only disk; here a
    path through a plain file, which fails for root too) is one line, checked before any rendering
    (not a traceback from the screenshot or the report's folder; for a movie not pages of ffmpeg
    output or 'Exception ignored' from the writer; the report: tests/integration/test_report.py)."""
    folder = make_results(n_frames=2)
    blocker = tmp_path / "not-a-folder"
    blocker.write_text("a file\n")
    cases = [
        ("render", str(folder), "-o", str(blocker / "a.png")),
        ("animate", str(folder), "-o", str(blocker / "a.gif")),
        ("animate", str(folder), "-o", str(blocker / "a.mp4")),
    ]
    for args in cases:
        proc = runout(*args, cwd=tmp_path)
        lines = [line for line in proc.stderr.splitlines() if line.strip()]
        assert proc.returncode == 1, (args, proc.stderr)
        assert len(lines) == 1 and lines[0].startswith(f"error: cannot write {blocker}"), (args, proc.stderr)
    assert blocker.read_text() == "a file\n"
