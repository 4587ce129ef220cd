"""geometry depends on numpy (and gmsh/meshio lazily) only."""

import ast
import subprocess
import sys
from pathlib import Path

import geometry

PACKAGE = Path(geometry.__file__).parent
FORBIDDEN = {"solver", "projects", "app", "PySide6", "pyvista", "pyvistaqt", "vtk", "taichi", "qtpy"}


def test_importing_geometry_loads_no_heavy_or_forbidden_module():
    code = (
        "import sys, geometry, geometry.seeding, geometry.gmsh_bodies, geometry.importers\n"
        "print(sorted({m.split('.')[0] for m in sys.modules}))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    loaded = set(ast.literal_eval(out.stdout.strip()))
    assert "numpy" in loaded
    assert not loaded & (FORBIDDEN | {"gmsh", "meshio", "ezdxf"})


def test_module_level_imports_are_numpy_stdlib_or_geometry():
    allowed_third_party = {"numpy"}
    for path in PACKAGE.glob("*.py"):
        tree = ast.parse(path.read_text())
        for node in tree.body:  # module level only: gmsh and meshio are imported in functions
            if isinstance(node, ast.Import):
                roots = {alias.name.split(".")[0] for alias in node.names}
            elif isinstance(node, ast.ImportFrom):
                assert node.level == 0, f"{path.name}: relative import"
                roots = {node.module.split(".")[0]}
            else:
                continue
            for root in roots:
                ok = root in allowed_third_party or root == "geometry" or root in sys.stdlib_module_names
                assert ok or root == "__future__", f"{path.name} imports {root} at module level"
        every = {
            (alias.name if isinstance(n, ast.Import) else n.module).split(".")[0]
            for n in ast.walk(tree)
            if isinstance(n, (ast.Import, ast.ImportFrom))
            for alias in n.names
        }
        assert not every & FORBIDDEN, f"{path.name} imports {every & FORBIDDEN}"
        if "gmsh" in every:
            assert path.name == "gmsh_bodies.py"
