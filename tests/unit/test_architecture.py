"""The direction of dependencies (docs/DESIGN.md): app -> projects -> {geometry, solver}.

Each package is imported in a fresh interpreter and the modules it must not pull in are checked.
"""

import json
import subprocess
import sys

import pytest

FORBIDDEN = {
    "solver": ["PySide6", "pyvista", "vtk", "gmsh", "geometry", "projects", "app"],
    "solver.simulation": ["PySide6", "pyvista", "vtk", "gmsh", "geometry", "projects", "app"],
    "geometry": ["PySide6", "pyvista", "vtk", "taichi", "solver", "projects", "app", "gmsh"],
    "projects.document": ["PySide6", "pyvista", "app"],
    "projects.build": ["PySide6", "pyvista", "app"],
    "projects.runner": ["PySide6", "pyvista", "app"],
    "projects.results": ["PySide6", "app"],
    "projects.results_folder": ["PySide6", "pyvista", "taichi", "app", "solver", "geometry"],
    "projects.limits": ["PySide6", "pyvista", "taichi", "app"],
    "projects.units": ["PySide6", "pyvista", "taichi", "app", "solver", "geometry", "pydantic"],
    "projects.checks": ["PySide6", "pyvista", "taichi", "app"],
    "app.render": ["PySide6"],
    "app.cli": ["PySide6", "pyvista", "taichi", "gmsh"],
    "studies": ["PySide6", "pyvista", "app"],
    "benchmarks.bench": ["PySide6", "pyvista", "app"],
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
