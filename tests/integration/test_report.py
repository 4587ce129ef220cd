"""``runout report``: the hazard report renders headless, every picture in it is non-blank, and a
folder without hazard files gets a one-line error."""

from __future__ import annotations

import base64
import io
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import REPO, TINY_PROJECT

imageio = pytest.importorskip("imageio.v3")
pytest.importorskip("matplotlib")
pytest.importorskip("pyvista")


def runout(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(REPO), env.get("PYTHONPATH", "")])
    return subprocess.run([sys.executable, "-m", "app.cli", *args], cwd=cwd, capture_output=True, text=True,
                          timeout=300, env=env)


@pytest.fixture(scope="module")
def collapse(tmp_path_factory):
    """The tiny column collapsing for 0.3 s, with a line and a point target."""
    from projects.document import load_project
    from projects.runner import run_project

    tmp = tmp_path_factory.mktemp("report")
    text = TINY_PROJECT.read_text() + (
        '\n[[targets]]\nname = "road"\nx_m = 0.2\n\n[[targets]]\nname = "house"\npoint_m = [0.25, 0.01]\n')
    path = tmp / "tiny.toml"
    path.write_text(text)
    project = load_project(path, ["stages.1.duration_s=0.3", "output.interval_s=0.05"])
    result = run_project(project, tmp / "tiny.results", project_path=path)
    assert result.ok, result.message
    return result.out_dir


def _non_blank(png: bytes | Path) -> None:
    img = imageio.imread(png)
    rgb = img[..., :3].astype(int)
    non_white = np.any(rgb < 245, axis=-1).mean()
    colours = len({tuple(c) for c in rgb.reshape(-1, 3)[:: max(1, rgb.size // 3 // 200_000)]})
    assert non_white > 0.02 and colours > 20, (non_white, colours)


def test_report_renders_headless_and_every_picture_is_non_blank(collapse, tmp_path):
    out = tmp_path / "rep"
    proc = runout("report", str(collapse), "-o", str(out), cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    html = Path(proc.stdout.strip())
    assert html == out / "report.html" and html.is_file()
    text = html.read_text()
    pngs = sorted(out.glob("*.png"))
    names = {p.stem for p in pngs}
    assert {"scene_before", "scene_after", "profiles", "energy", "targets", "context"} <= names
    for png in pngs:
        _non_blank(png)
    # self-contained: every picture is embedded, and those embedded are non-blank too
    embedded = re.findall(r'src="data:image/png;base64,([^"]+)"', text)
    assert len(embedded) == len(pngs)
    for data in embedded:
        _non_blank(io.BytesIO(base64.b64decode(data)).getvalue())
    for heading in ("Measures", "Scene before and after", "Envelopes along the section", "Targets", "Energy",
                    "Context from experience", "Settings and provenance"):
        assert f">{heading}<" in text, heading
    # the measures and targets of hazard.json are in the tables; the context names its sources
    assert "road" in text and "house" in text and "travel angle" in text
    assert "Lube, Huppert, Sparks &amp; Freundt (2005)" in text and "Corominas (1996)" in text
    assert "apic-affine" in text and "wall time" in text


def test_report_lists_the_contact_forces_of_contacts_csv(collapse, tmp_path):
    """The force on each side and structure, from contacts.csv as runs write it (one row per contact
    and output time, docs/project-format.md): the largest single-step force with its components
    and the largest interval mean, each with its time. (The table used to read a wide file no run
    writes, and showed nothing for a real one.)"""
    from app.report import write_report
    from projects.results import CONTACT_COLUMNS

    folder = tmp_path / "with_contacts.results"
    shutil.copytree(collapse, folder)
    # a file without the moment column (older runs): still read
    rows = [",".join(CONTACT_COLUMNS[:9]),
            "0.0,bottom,0.0,0.0,0.0,0.0,0.0,0.0,0.0", "0.0,wall,0.0,0.0,,,0.0,0.0,0.0",
            "0.1,bottom,1.0,-50.0,50.0,1.0,80.0,2.0,-79.9", "0.1,wall,-35.5,12.0,,,61.25,-60.0,12.3",
            "0.2,bottom,2.0,-49.0,49.0,2.0,70.0,1.0,-69.9", "0.2,wall,20.0,3.0,,,25.0,24.0,7.0"]
    (folder / "contacts.csv").write_text("\n".join(rows) + "\n")
    text = write_report(folder).read_text()
    assert "Forces on the structures and sides (contacts.csv)" in text
    body = re.sub(r"<[^>]+>", "|", text[text.index("Forces on the structures"):])
    cells = [c.strip() for c in body.split("|") if c.strip()]
    wall = cells[cells.index("wall"):][:8]
    # a contact the summary does not list as a structure (no polygon): no normal and tangential
    # parts, no line of action
    assert wall == ["wall", "61.2 N/m (N -, T -)", "0.1 s", "-", "-", "-", "-", "-"], wall
    bottom = cells[cells.index("bottom (side)"):][:7]
    # the side's parts along its axes: N = -F y of the peak step, T = F x
    assert bottom == ["bottom (side)", "80 N/m (N 79.9, T 2)", "0.1 s", "50 N/m", "0.1 s", "2 N/m", "0.2 s"], bottom
    # and their history as a figure, embedded, one line per contact that took any force in each panel
    picture = folder / "report" / "contacts.png"
    _non_blank(picture)
    assert base64.b64encode(picture.read_bytes()).decode("ascii") in text


def test_report_plots_only_the_contacts_that_took_a_force(tmp_path, monkeypatch):
    from matplotlib.figure import Figure

    from app import report

    shown = []
    real = Figure.savefig

    def spy(fig, path, *args, **kwargs):
        shown.append({line.get_label() for ax in fig.axes for line in ax.get_lines()
                      if not line.get_label().startswith("_")})  # not the zero line
        return real(fig, path, *args, **kwargs)

    t = np.array([0.0, 0.1, 0.2])
    zero = np.zeros(3)
    table = {"left": {"time_s": t, "force_x_N_per_m": zero, "force_y_N_per_m": zero, "peak_force_N_per_m": zero},
             "dam": {"time_s": t, "force_x_N_per_m": np.array([0.0, 5.0, 7.0]), "force_y_N_per_m": zero,
                     "peak_force_N_per_m": np.array([0.0, 6.0, 9.0])}}
    monkeypatch.setattr(Figure, "savefig", spy)
    assert report.contacts_png(table, tmp_path / "c.png") == tmp_path / "c.png"
    assert report.contacts_png({"left": table["left"]}, tmp_path / "none.png") is None
    assert shown == [{"peak |F| of a step"}]  # the dam's plot alone (no normal or tangential here)
    assert not (tmp_path / "none.png").exists()


def test_report_without_hazard_files_is_a_one_line_error(collapse, tmp_path):
    folder = tmp_path / "plain.results"
    shutil.copytree(collapse, folder)
    (folder / "hazard.json").unlink()
    proc = runout("report", str(folder), cwd=tmp_path)
    assert proc.returncode == 1
    assert proc.stderr.strip().startswith("error: ") and "no hazard.json" in proc.stderr
    assert "Traceback" not in proc.stderr


def test_report_where_nothing_can_be_written_is_a_one_line_error(collapse, tmp_path):
    """A report whose folder cannot be made or written (a read-only results folder; here a path
    through a plain file, which fails for root too) is one line before any picture is rendered
    (not a traceback from the folder's mkdir)."""
    blocker = tmp_path / "not-a-folder"
    blocker.write_text("a file\n")
    proc = runout("report", str(collapse), "-o", str(blocker / "report"), cwd=tmp_path)
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert proc.returncode == 1, proc.stderr
    assert lines == [f"error: cannot write {blocker / 'report' / 'report.html'}: Not a directory"], proc.stderr
