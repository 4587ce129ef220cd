"""gmsh quad meshes of bodies: conformity, orientation, ownership and physical groups."""

import threading

import numpy as np
import pytest

from geometry.gmsh_bodies import mesh_bodies
from geometry.polygons import polygon_area

LOWER = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [0.0, 1.0]])
UPPER = np.array([[1.0, 0.5], [3.0, 0.5], [3.0, 2.0], [1.0, 2.0]])


def _edge_counts(quads):
    edges = np.sort(np.concatenate([quads[:, [a, (a + 1) % 4]] for a in range(4)]), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    return counts


def test_mesh_is_all_quads_counter_clockwise_and_conforming():
    mesh = mesh_bodies([LOWER, UPPER], element_size_m=0.25)
    assert mesh.quads.shape[1] == 4 and len(mesh.quads) > 20
    assert mesh.quad_body.shape == (len(mesh.quads),)
    assert np.all(mesh.quad_areas_m2() > 0)  # counter-clockwise
    # Conforming: every edge is shared by at most two quads, and the mesh has no
    # hanging nodes (a closed union has boundary edges only on its outline).
    assert _edge_counts(mesh.quads).max() == 2
    # The body interface: nodes on x = 1 between y = 0.5 and 1 are shared by both bodies.
    used_by = [set(mesh.quads[mesh.quad_body == b].ravel()) for b in (0, 1)]
    shared = used_by[0] & used_by[1]
    assert len(shared) >= 3
    assert mesh.nodes_m.shape == (len(np.unique(mesh.quads)), 2)


def test_overlap_is_owned_by_the_later_body():
    mesh = mesh_bodies([LOWER, UPPER], element_size_m=0.25)
    areas = mesh.quad_areas_m2()
    assert areas[mesh.quad_body == 0].sum() == pytest.approx(1.5, rel=1e-12)
    assert areas[mesh.quad_body == 1].sum() == pytest.approx(3.0, rel=1e-12)
    centroids = mesh.nodes_m[mesh.quads].mean(axis=1)
    in_overlap = np.all((centroids > [1.0, 0.5]) & (centroids < [2.0, 1.0]), axis=1)
    assert in_overlap.any() and np.all(mesh.quad_body[in_overlap] == 1)


def test_body_covered_by_a_later_body_gets_no_quads():
    inner = np.array([[0.5, 0.25], [1.0, 0.25], [1.0, 0.75], [0.5, 0.75]])
    mesh = mesh_bodies([inner, LOWER], element_size_m=0.25)
    assert not np.any(mesh.quad_body == 0)
    assert mesh.quad_areas_m2().sum() == pytest.approx(polygon_area(LOWER))


def test_physical_groups_are_written(tmp_path):
    meshio = pytest.importorskip("meshio")
    path = tmp_path / "bodies.msh"
    mesh_bodies([LOWER, UPPER], element_size_m=0.5, msh_path=path)
    written = meshio.read(path)
    assert {"body0", "body1"} <= set(written.field_data)
    assert {block.type for block in written.cells if block.data.ndim == 2} >= {"quad"}


def test_element_size_controls_the_mesh():
    coarse = mesh_bodies([LOWER], element_size_m=0.5)
    fine = mesh_bodies([LOWER], element_size_m=0.125)
    assert len(fine.quads) > 8 * len(coarse.quads)
    mean_area = fine.quad_areas_m2().mean()
    assert 0.5 * 0.125**2 < mean_area < 2.0 * 0.125**2


def test_meshing_works_off_the_main_thread():
    result = {}

    def work():
        result["mesh"] = mesh_bodies([LOWER], element_size_m=0.5)

    thread = threading.Thread(target=work)
    thread.start()
    thread.join(timeout=60)
    assert result["mesh"].quad_areas_m2().sum() == pytest.approx(2.0)


def test_bad_inputs_raise_value_error():
    with pytest.raises(ValueError, match="at least one body"):
        mesh_bodies([], 0.1)
    with pytest.raises(ValueError, match="element_size_m must be a positive"):
        mesh_bodies([LOWER], 0.0)
    with pytest.raises(ValueError, match=r"polygons\[0\] is self-intersecting"):
        mesh_bodies([[[0, 0], [1, 1], [1, 0], [0, 1]]], 0.1)
