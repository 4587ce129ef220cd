"""Outline import from CSV points and from meshio meshes."""

import numpy as np
import pytest

from geometry.importers import outline_from_csv, outline_from_mesh
from geometry.polygons import is_simple, polygon_area, signed_area


def _write(tmp_path, text, name="outline.csv"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_open_profile_is_closed_down_to_the_lowest_point(tmp_path):
    path = _write(tmp_path, "# survey 2021\nx_m,y_m\n0,10\n5,10\n15,2\n20,2\n")
    poly = outline_from_csv(path)
    assert is_simple(poly) and signed_area(poly) > 0
    # Crest 5 x 8 above the base at y = 2, plus the face triangle 10 x 8 / 2.
    assert polygon_area(poly) == pytest.approx(5 * 8 + 40)
    assert poly[:, 1].min() == pytest.approx(2.0)


def test_open_profile_with_explicit_base_and_decreasing_x(tmp_path):
    path = _write(tmp_path, "x,y\n20,2\n15,2\n5,10\n0,10\n")
    poly = outline_from_csv(path, base_y_m=-3.0)
    assert polygon_area(poly) == pytest.approx(80 + 20 * 5)
    assert signed_area(poly) > 0
    assert poly[:, 1].min() == pytest.approx(-3.0)


def test_closed_outline_is_read_as_given(tmp_path):
    path = _write(tmp_path, "x_m,y_m\n0,0\n0,1\n2,1\n2,0\n0,0\n\n")
    poly = outline_from_csv(path)
    assert len(poly) == 4
    assert polygon_area(poly) == pytest.approx(2.0)
    assert signed_area(poly) > 0  # clockwise input comes back counter-clockwise


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("x_m,y_m\n0,0\n1,1\n", r"at least 3 distinct points, got 2"),
        ("x_m,y_m\n0,0\n1,abc\n2,0\n", r"line 3: non-numeric value"),
        ("a,b\n0,0\n1,1\n2,0\n", r"line 1: expected the header 'x_m,y_m'"),
        ("x_m,y_m,z_m\n0,0,0\n", r"expected the header"),
        ("x_m,y_m\n0,0\n1,1,1\n2,0\n", r"line 3: expected 2 values"),
        ("# only a comment\n", r"no header row"),
        ("x_m,y_m\n0,0\n2,1\n1,3\n3,0\n", r"x strictly increasing or decreasing"),
        ("x_m,y_m\n0,1\n1,0\n2,1\n", r"not a simple polygon.*base_y_m below"),
        ("x_m,y_m\n0,0\n1,1\n1,0\n0,1\n0,0\n", r"not a simple polygon: edges \(0, 0\)-\(1, 1\) and \(1, 0\)-\(0, 1\) cross"),
        ("x_m,y_m\n0,0\n1,inf\n2,0\n", r"line 3: non-finite value"),
    ],
)
def test_bad_csv_raises_a_clear_error(tmp_path, text, message):
    with pytest.raises(ValueError, match=message):
        outline_from_csv(_write(tmp_path, text))


def test_base_above_the_profile_is_rejected(tmp_path):
    path = _write(tmp_path, "x_m,y_m\n0,10\n5,10\n15,2\n20,2\n")
    with pytest.raises(ValueError, match=r"base_y_m = 5 m is above the lowest profile point"):
        outline_from_csv(path, base_y_m=5.0)


def _grid_mesh(n, skip=()):
    """Unit quads on an n x n node grid, leaving out the (i, j) cells in skip."""
    xs, ys = np.meshgrid(np.arange(n, dtype=float), np.arange(n, dtype=float))
    points = np.column_stack([xs.ravel(), ys.ravel(), np.zeros(n * n)])
    quads = np.array(
        [
            [j * n + i, j * n + i + 1, (j + 1) * n + i + 1, (j + 1) * n + i]
            for j in range(n - 1)
            for i in range(n - 1)
            if (i, j) not in skip
        ]
    )
    return points, quads


def test_mesh_outline_keeps_boundary_nodes_and_drops_holes(tmp_path):
    meshio = pytest.importorskip("meshio")
    points, quads = _grid_mesh(5, skip={(1, 1)})  # 4 x 4 square with a hole
    path = tmp_path / "mesh.vtu"
    meshio.write(path, meshio.Mesh(points, [("quad", quads)]))
    poly = outline_from_mesh(path)
    assert len(poly) == 16  # every node on the outer boundary, collinear ones included
    assert polygon_area(poly) == pytest.approx(16.0)
    assert signed_area(poly) > 0 and is_simple(poly)


def test_mesh_outline_from_triangles_in_2d(tmp_path):
    meshio = pytest.importorskip("meshio")
    points, quads = _grid_mesh(4, skip={(2, 2)})  # L-like: 3 x 3 minus a corner cell
    triangles = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    path = tmp_path / "mesh.vtk"
    meshio.write(path, meshio.Mesh(points[:, :2], [("triangle", triangles)]))
    poly = outline_from_mesh(path)
    assert polygon_area(poly) == pytest.approx(8.0)
    assert is_simple(poly) and signed_area(poly) > 0


def test_bad_meshes_raise_value_error(tmp_path):
    meshio = pytest.importorskip("meshio")
    points, quads = _grid_mesh(3)
    lifted = points.copy()
    lifted[:, 2] = lifted[:, 0]
    path = tmp_path / "tilted.vtu"
    meshio.write(path, meshio.Mesh(lifted, [("quad", quads)]))
    with pytest.raises(ValueError, match="not planar"):
        outline_from_mesh(path)
    path = tmp_path / "lines.vtu"
    meshio.write(path, meshio.Mesh(points, [("line", np.array([[0, 1], [1, 2]]))]))
    with pytest.raises(ValueError, match="no triangle or quadrilateral cells"):
        outline_from_mesh(path)
    unknown = _write(tmp_path, "hello", name="mesh.unknownformat")
    with pytest.raises(ValueError, match="meshio cannot read"):
        outline_from_mesh(unknown)
    with pytest.raises(ValueError, match="cannot read the file: No such file"):
        outline_from_mesh(tmp_path / "missing.vtu")


# -- DXF drawings (geometry.importers.outline_from_dxf; the workbench's import calls read_outline) --

def _dxf(tmp_path, add, name="slope.dxf"):
    import ezdxf

    drawing = ezdxf.new()
    add(drawing.modelspace())
    path = tmp_path / name
    drawing.saveas(path)
    return path


def test_dxf_open_polyline_is_a_profile_closed_down_like_a_csv(tmp_path):
    from geometry.importers import outline_from_dxf, read_outline

    def add(msp):
        msp.add_lwpolyline([(0, 10), (5, 10), (15, 2), (20, 2)])
        msp.add_line((0, 0), (1, 1))  # clutter: the polyline with the most vertices is the profile

    path = _dxf(tmp_path, add)
    csv = outline_from_csv(_write(tmp_path, "x_m,y_m\n0,10\n5,10\n15,2\n20,2\n"), base_y_m=-1.0)
    for poly in (outline_from_dxf(path, base_y_m=-1.0), read_outline(path, base_y_m=-1.0)):
        np.testing.assert_array_equal(poly, csv)
        assert polygon_area(poly) == pytest.approx(20 * 3 + 5 * 8 + 40)


def test_dxf_closed_polyline_and_chained_lines_are_outlines(tmp_path):
    from geometry.importers import outline_from_dxf

    closed = _dxf(tmp_path, lambda msp: msp.add_lwpolyline([(0, 0), (2, 0), (2, 1), (0, 1)], close=True),
                  "closed.dxf")
    poly = outline_from_dxf(closed, base_y_m=-5.0)  # a closed outline ignores the base
    assert len(poly) == 4 and polygon_area(poly) == pytest.approx(2.0) and signed_area(poly) > 0

    def lines(msp):  # an open profile drawn as LINE entities, out of order and reversed
        for a, b in (((5, 10), (15, 2)), ((20, 2), (15, 2)), ((0, 10), (5, 10))):
            msp.add_line(a, b)

    poly = outline_from_dxf(_dxf(tmp_path, lines, "lines.dxf"))
    assert polygon_area(poly) == pytest.approx(5 * 8 + 40)


def test_dxf_problems_are_one_line_errors_naming_the_file(tmp_path):
    from geometry.importers import outline_from_dxf, read_outline

    bad = _write(tmp_path, "not a drawing\n", "bad.dxf")
    with pytest.raises(ValueError, match=r"bad\.dxf: not a readable DXF drawing"):
        outline_from_dxf(bad)
    empty = _dxf(tmp_path, lambda msp: msp.add_circle((0, 0), 1.0), "empty.dxf")
    with pytest.raises(ValueError, match=r"empty\.dxf: no polyline or line"):
        outline_from_dxf(empty)
    zigzag = _dxf(tmp_path, lambda msp: msp.add_lwpolyline([(0, 1), (2, 3), (1, 2)]), "zigzag.dxf")
    with pytest.raises(ValueError, match=r"zigzag\.dxf: an open surface profile needs x strictly"):
        outline_from_dxf(zigzag)
    with pytest.raises(ValueError, match=r"unknown kind of file '\.txt'"):
        read_outline(_write(tmp_path, "x_m,y_m\n", "profile.txt"))


# -- the file checks of an import (geometry.importers.check_import_file): one line, nothing hangs --

def test_an_import_refuses_what_it_cannot_read_in_one_line_naming_the_file(tmp_path):
    import os

    from geometry.importers import read_layers

    fifo = tmp_path / "fifo.csv"
    os.mkfifo(fifo)  # no writer: an open() would block forever
    nul = tmp_path / "nul.csv"
    nul.write_bytes(b"x_m,y_m\n0,1\x00\n")
    binary = tmp_path / "binary.csv"
    binary.write_bytes(b"x_m,y_m\n\xff\xfe0,1\n")
    cases = [
        (tmp_path / "missing.csv", "cannot read the file: No such file or directory"),
        (tmp_path, "cannot read the file: it is a folder, not a regular file"),
        (fifo, "cannot read the file: it is a FIFO (named pipe), not a regular file"),
        (_write(tmp_path, "", name="empty.csv"), "the file is empty"),
        (binary, "not UTF-8 text"),
        (nul, "line 2: non-numeric value"),
        (_write(tmp_path, "", name="empty.dxf"), "the file is empty"),
        (_write(tmp_path, "not a drawing", name="bad.dxf"), "not a readable DXF drawing"),
        (_write(tmp_path, "", name="empty.vtu"), "the file is empty"),
        (_write(tmp_path, "<VTKFile garbage", name="bad.vtu"), "meshio cannot read this file"),
    ]
    for path, message in cases:
        with pytest.raises(ValueError) as err:
            read_layers(path)
        text = str(err.value)
        assert text.startswith(f"{path}: ") and message in text, (path, text)
        assert "\n" not in text


def test_an_import_refuses_more_points_than_an_outline_may_have(tmp_path):
    from geometry.importers import read_layers

    rows = "\n".join(f"{i * 0.01},{5 + 0.001 * i}" for i in range(301))
    path = _write(tmp_path, "x_m,y_m\n" + rows + "\n", name="long.csv")
    with pytest.raises(ValueError, match=r"long.csv: the file has 301 points, more than the limit of 300 per "
                                         r"outline \(docs/project-format.md, size limits\); simplify the profile"):
        read_layers(path, max_points=300)
    assert len(read_layers(path, max_points=301)[0].polygon_m) >= 301
    layered = _write(tmp_path, "x_m,y_m,layer\n" + "\n".join(f"{i},{9 - 0.01 * i},top" for i in range(5)) + "\n"
                     + "\n".join(f"{i},{5 - 0.01 * i},clay" for i in range(5)) + "\n", name="layers.csv")
    with pytest.raises(ValueError, match="layer 'top' has 5 points, more than the limit of 4"):
        read_layers(layered, max_points=4)
