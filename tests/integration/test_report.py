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


def test_report_lists_structure_forces_when_contacts_csv_exists(collapse, tmp_path):
    from app.report import write_report

    folder = tmp_path / "with_contacts.results"
    shutil.copytree(collapse, folder)
    (folder / "contacts.csv").write_text("time_s,wall:force_x_N_per_m,wall:force_y_N_per_m\n"
                                         "0.0,0.0,0.0\n0.1,-35.5,12.0\n0.2,20.0,3.0\n")
    text = write_report(folder).read_text()
    assert "Structures (contacts.csv)" in text and "wall:force_x_N_per_m" in text and "-35.5" in text


def test_report_without_hazard_files_is_a_one_line_error(collapse, tmp_path):
    folder = tmp_path / "plain.results"
    shutil.copytree(collapse, folder)
    (folder / "hazard.json").unlink()
    proc = runout("report", str(folder), cwd=tmp_path)
    assert proc.returncode == 1
    assert proc.stderr.strip().startswith("error: ") and "no hazard.json" in proc.stderr
    assert "Traceback" not in proc.stderr
