"""The direction of dependencies (docs/DESIGN.md): app -> {studies, benchmarks, sweeps} -> projects ->
{geometry, solver, stability}.

The import-linter contracts of ``.importlinter`` (layers, independence, no Qt/PyVista/VTK below app, no
circles between the modules of a package) are checked on the whole import graph, function-local
imports included. Besides, each package is imported in a fresh interpreter and the modules it must
not pull in at run time are checked.
"""

import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def test_the_import_linter_contracts_are_kept():
    """``lint-imports`` (the venv's own) on ``.importlinter``: exit status 0 only when every contract is kept."""
    lint = Path(sys.executable).with_name("lint-imports")
    if not lint.is_file():
        pytest.fail(f"{lint} is missing: install the test extras (pip install -e .[test])")
    out = subprocess.run([str(lint), str(ROOT / ".importlinter"), "--no-cache"], cwd=ROOT,
                         capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stdout[-6000:] + out.stderr[-2000:]
    assert "0 broken" in out.stdout


def test_a_broken_contract_is_reported(tmp_path):
    """The check can fail: a contract that the tree breaks (the app imports projects) gives a non-zero status."""
    lint = Path(sys.executable).with_name("lint-imports")
    if not lint.is_file():
        pytest.fail(f"{lint} is missing: install the test extras (pip install -e .[test])")
    config = tmp_path / "broken.ini"
    config.write_text("[importlinter]\nroot_packages =\n    app\n    projects\n\n"
                      "[importlinter:contract:upside-down]\nname = upside down\ntype = forbidden\n"
                      "source_modules =\n    app\nforbidden_modules =\n    projects\n", encoding="utf-8")
    out = subprocess.run([str(lint), str(config), "--no-cache"], cwd=ROOT, capture_output=True,
                         text=True, timeout=300)
    assert out.returncode != 0 and "upside down BROKEN" in out.stdout

FORBIDDEN = {
    "solver": ["PySide6", "pyvista", "vtk", "gmsh", "geometry", "projects", "app"],
    "solver.simulation": ["PySide6", "pyvista", "vtk", "gmsh", "geometry", "projects", "app"],
    "geometry": ["PySide6", "pyvista", "vtk", "taichi", "solver", "projects", "app", "gmsh"],
    "projects.document": ["PySide6", "pyvista", "app"],
    "projects.build": ["PySide6", "pyvista", "app"],
    "projects.runner": ["PySide6", "pyvista", "app"],
    "projects.results": ["PySide6", "app"],
    "projects.hazard": ["PySide6", "pyvista", "vtk", "taichi", "matplotlib", "app"],
    "solver.envelopes": ["PySide6", "pyvista", "vtk", "gmsh", "geometry", "projects", "app"],
    "projects.results_folder": ["PySide6", "pyvista", "taichi", "app", "solver", "geometry"],
    "projects.limits": ["PySide6", "pyvista", "taichi", "app"],
    "projects.units": ["PySide6", "pyvista", "taichi", "app", "solver", "geometry", "pydantic"],
    "projects.checks": ["PySide6", "pyvista", "taichi", "app"],
    "app.render": ["PySide6"],
    "app.report": ["PySide6", "taichi"],
    "app.cli": ["PySide6", "pyvista", "taichi", "gmsh"],
    "studies": ["PySide6", "pyvista", "app"],
    "benchmarks.bench": ["PySide6", "pyvista", "app"],
    "projects.measures": ["PySide6", "pyvista", "vtk", "taichi", "app", "solver", "studies", "sweeps"],
    "projects.atomic": ["PySide6", "pyvista", "taichi", "numpy", "app", "solver", "geometry"],
    "sweeps.folder": ["PySide6", "pyvista", "vtk", "app", "taichi"],
    "stability": ["PySide6", "pyvista", "vtk", "gmsh", "taichi", "solver", "geometry", "projects", "app",
                  "scipy", "shapely"],
    # the sweep driver schedules `runout run` processes: no solver runtime, no GUI in it
    "sweeps.sweep": ["PySide6", "pyvista", "vtk", "app", "taichi"],
    "sweeps.calibrate": ["PySide6", "pyvista", "vtk", "app", "taichi"],
    "sweeps.report": ["PySide6", "pyvista", "vtk", "app", "taichi"],
    "sweeps.measures": ["PySide6", "pyvista", "vtk", "app", "taichi"],
}


def loaded_after_import(module: str) -> set[str]:
    code = f"import sys, json; import {module}; print(json.dumps(sorted(sys.modules)))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return {name.split(".")[0] for name in json.loads(out.stdout.strip().splitlines()[-1])}


@pytest.mark.parametrize("module", sorted(FORBIDDEN))
def test_module_does_not_import_what_it_must_not(module):
    loaded = loaded_after_import(module)
    bad = sorted(set(FORBIDDEN[module]) & loaded)
    assert not bad, f"importing {module} also imports {bad}"


def test_importing_the_solver_does_not_initialise_taichi():
    code = "import solver.simulation, taichi.lang.impl as impl; print(impl.get_runtime().prog is None)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip().splitlines()[-1] == "True"


WORKBENCH = """
import json, os, pkgutil, sys, importlib, tempfile
import app.gui
for info in pkgutil.iter_modules(app.gui.__path__):
    importlib.import_module("app.gui." + info.name)
print("IMPORTED", json.dumps(sorted(sys.modules)), flush=True)
from PySide6.QtWidgets import QApplication
from app.gui.main_window import MainWindow
from app.gui.settings import MaterialLibrary, Settings
qapp = QApplication([])
config = tempfile.mkdtemp()
win = MainWindow(settings=Settings(config), library=MaterialLibrary(config))
win.show()
win.open_project(sys.argv[1], ask=False)
win.run_panel.update_estimate()
win.scene.set_show_particles(True)
qapp.processEvents()
loaded = sorted(sys.modules)
win.shutdown()
print("WINDOW", json.dumps(loaded), flush=True)
os._exit(0)
"""


def test_the_workbench_process_never_imports_taichi(tmp_path):
    """Runs are child processes (app.gui.run_process): the workbench itself, every module of it
    imported, and then a window open on an example with its estimate and particle preview, has no
    Taichi (nor the solver's engine) loaded. One process answers both: the modules loaded after
    the imports, then those loaded with the window open."""
    import os

    example = Path(__file__).resolve().parents[2] / "projects" / "examples" / "tiny_column.toml"
    env = dict(os.environ, QT_QPA_PLATFORM="offscreen", QT_API="pyside6", RUNOUT_CONFIG_DIR=str(tmp_path))
    out = subprocess.run([sys.executable, "-c", WORKBENCH, str(example)], capture_output=True, text=True,
                         env=env, timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    lines = {line.split(" ", 1)[0]: line.split(" ", 1)[1] for line in out.stdout.splitlines()
             if line.startswith(("IMPORTED ", "WINDOW "))}
    imported, with_window = set(json.loads(lines["IMPORTED"])), set(json.loads(lines["WINDOW"]))
    for when, loaded in (("import", imported), ("window", with_window)):
        assert "PySide6" in loaded and "app.gui.main_window" in loaded, when
        assert "taichi" not in loaded, when
        assert not {"solver.engine", "solver.simulation", "solver.runtime"} & loaded, when


def test_runout_starts_itself_in_one_way_only():
    """Child runs of Runout (the workbench's, the sweeps') are started by
    ``projects.runner.runout_command`` (``python -m app``), the one place that decides it; no
    production module spells its own ``-m app.cli`` command line."""
    from projects.runner import runout_command

    assert runout_command("run", "p.toml") == [sys.executable, "-m", "app", "run", "p.toml"]
    root = Path(__file__).resolve().parents[2]
    offenders = []
    for package in ("app", "projects", "sweeps", "studies", "benchmarks", "solver", "geometry", "stability"):
        for path in (root / package).rglob("*.py"):
            text = path.read_text(encoding="utf-8")
            if '"-m", "app.cli"' in text or "'-m', 'app.cli'" in text:
                offenders.append(str(path.relative_to(root)))
    assert offenders == []


def test_test_files_have_unique_names():
    """The test folders are not packages, so pytest imports each file under its bare name: two files
    of one name in different folders fail the collection of the second."""
    seen: dict[str, Path] = {}
    clashes = []
    for path in sorted((ROOT / "tests").rglob("test_*.py")):
        if path.name in seen:
            clashes.append(f"{seen[path.name].relative_to(ROOT)} and {path.relative_to(ROOT)}")
        seen.setdefault(path.name, path)
    assert not clashes, clashes
