"""Lattice and Gauss seeding: volumes, the overlap rule and material assignment."""

import itertools
import math

import numpy as np
import pytest

from geometry.polygons import owner_of_points, polygon_area, polygon_perimeter
from geometry.seeding import quad_gauss_points, seed_gauss, seed_lattice
from geometry.templates import SlopeLayer, slope_profile

SLOPE = np.array([[0.0, 0.0], [30.0, 0.0], [30.0, 5.0], [20.0, 5.0], [10.0, 15.0], [0.0, 15.0]])
TRIANGLE = np.array([[0.1, 0.2], [3.3, 0.45], [1.2, 2.9]])


def test_lattice_rectangle_aligned_with_grid_is_exact():
    rect = np.array([[0.2, 0.4], [1.0, 0.4], [1.0, 1.0], [0.2, 1.0]])
    seeds = seed_lattice([rect], origin_m=(0.0, 0.0), cell_size_m=0.2, per_cell=2)
    assert len(seeds) == 4 * 3 * 4  # 4 x 3 cells, 4 points each
    assert seeds.volumes_m2.sum() == pytest.approx(0.48, rel=1e-12)
    np.testing.assert_allclose(seeds.volumes_m2, 0.01)
    # Points sit at the sub-cell centres: a quarter cell (0.05 m) in from the edges.
    assert seeds.positions_m[:, 0].min() == pytest.approx(0.25)
    assert seeds.positions_m[:, 1].max() == pytest.approx(0.95)
    assert np.all(seeds.body_index == 0)


def test_lattice_is_aligned_with_the_grid_origin():
    rect = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    seeds = seed_lattice([rect], origin_m=(0.03, -0.01), cell_size_m=0.1, per_cell=1)
    whole = np.isclose(seeds.volumes_m2, 0.01, rtol=1e-12, atol=0.0)
    assert whole.sum() == 9 * 9  # the sub-cells the rectangle covers entirely
    frac = (seeds.positions_m[whole] - [0.03, -0.01]) / 0.1 - 0.5
    np.testing.assert_allclose(frac, np.round(frac), atol=1e-9)
    # the cut sub-cells along the edges: one point each, at the centroid of the covered part
    assert seeds.volumes_m2.sum() == pytest.approx(1.0, rel=1e-12)
    left = seeds.positions_m[:, 0] < 0.03
    np.testing.assert_allclose(seeds.positions_m[left, 0], 0.015)
    middle = left & (seeds.positions_m[:, 1] > 0.1) & (seeds.positions_m[:, 1] < 0.95)
    np.testing.assert_allclose(seeds.volumes_m2[middle], 0.003)  # 0.03 x 0.1 each
    assert middle.sum() == 9


def _seeded_within_the_body(seeds, polygon, h):
    """Every point lies in the body or on its outline (a centroid of a covered part)."""
    from shapely import Point, Polygon

    outline = Polygon(polygon)
    return all(outline.distance(Point(x, y)) < 1e-9 * h for x, y in seeds.positions_m)


@pytest.mark.parametrize("per_cell", [1, 2, 3])
@pytest.mark.parametrize("origin", [(0.0, 0.0), (0.37, -0.11)])
@pytest.mark.parametrize("polygon", [TRIANGLE, SLOPE / 10.0], ids=["triangle", "slope"])
def test_lattice_volumes_sum_to_the_body_area(polygon, origin, per_cell):
    cell = 0.25
    seeds = seed_lattice([polygon], origin, cell, per_cell)
    assert seeds.volumes_m2.sum() == pytest.approx(polygon_area(polygon), rel=1e-12)
    assert np.all(seeds.volumes_m2 <= (cell / per_cell) ** 2 * (1 + 1e-12))
    assert _seeded_within_the_body(seeds, polygon, cell / per_cell)


def test_lattice_volumes_exact_on_random_polygons():
    rng = np.random.default_rng(7)
    for _ in range(60):
        k = int(rng.integers(3, 10))
        angles = np.arange(k) * 2 * np.pi / k + rng.uniform(0, 0.9 * 2 * np.pi / k, k)
        radii = rng.uniform(0.4, 1.5, k)
        poly = np.column_stack([radii * np.cos(angles), radii * np.sin(angles)])
        cell, per_cell = float(rng.uniform(0.05, 0.4)), int(rng.integers(1, 4))
        origin = rng.uniform(-1, 1, 2)
        seeds = seed_lattice([poly], tuple(origin), cell, per_cell)
        # exact but for the slivers below a millionth of a sub-cell that get no point (at most
        # nine sub-cells per half sub-cell of outline)
        h = cell / per_cell
        sliver_bound = 1e-6 * h * h * 9 * (2 * polygon_perimeter(poly) / h + len(poly))
        assert seeds.volumes_m2.sum() == pytest.approx(polygon_area(poly), abs=sliver_bound)
        # by rows of sub-cells, then along x (the documented order), cut ones included
        i, j = np.floor((seeds.positions_m - origin) / h).astype(np.int64).T
        assert np.all(np.diff(j * 10**6 + i) > 0)


def test_lattice_overlap_belongs_to_later_body_and_is_counted_once():
    lower = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [0.0, 1.0]])
    upper = np.array([[1.0, 0.5], [3.0, 0.5], [3.0, 2.0], [1.0, 2.0]])
    seeds = seed_lattice([lower, upper], (0.0, 0.0), 0.25, 2)
    volumes = seeds.body_volumes_m2(2)
    assert volumes[0] == pytest.approx(2.0 - 0.5)
    assert volumes[1] == pytest.approx(3.0)
    x, y = seeds.positions_m[:, 0], seeds.positions_m[:, 1]
    in_overlap = (x > 1) & (x < 2) & (y > 0.5) & (y < 1)
    assert in_overlap.any() and np.all(seeds.body_index[in_overlap] == 1)
    # No point is seeded twice.
    assert len(np.unique(seeds.positions_m, axis=0)) == len(seeds)


def test_lattice_rejects_bad_arguments():
    with pytest.raises(ValueError, match="per_cell must be an integer >= 1"):
        seed_lattice([TRIANGLE], (0, 0), 0.1, 0)
    with pytest.raises(ValueError, match="cell_size_m must be a positive"):
        seed_lattice([TRIANGLE], (0, 0), -0.1, 2)
    with pytest.raises(ValueError, match=r"polygons\[1\] is self-intersecting"):
        seed_lattice([TRIANGLE, [[0, 0], [1, 1], [1, 0], [0, 1]]], (0, 0), 0.1, 2)


def test_quad_gauss_points_integrate_a_distorted_quad_exactly():
    nodes = np.array([[0.0, 0.0], [2.0, 0.3], [2.4, 1.9], [-0.2, 1.2]])
    quads = np.array([[0, 1, 2, 3]])
    area = polygon_area(nodes)
    for per_cell in (1, 2, 3):
        positions, volumes = quad_gauss_points(nodes, quads, per_cell)
        assert positions.shape == (per_cell**2, 2)
        assert volumes.sum() == pytest.approx(area, rel=1e-13)
    # One point per quad sits at the image of the reference centre.
    positions, _ = quad_gauss_points(nodes, quads, 1)
    np.testing.assert_allclose(positions[0], nodes.mean(axis=0))


@pytest.mark.parametrize("per_cell", [1, 2])
def test_gauss_volumes_sum_to_slope_area(per_cell):
    seeds = seed_gauss([SLOPE], cell_size_m=2.5, per_cell=per_cell)
    assert seeds.volumes_m2.sum() == pytest.approx(polygon_area(SLOPE), rel=1e-9)
    assert np.all(seeds.volumes_m2 > 0)
    # Every Gauss point lies inside the body.
    assert np.all(owner_of_points(seeds.positions_m, [SLOPE]) == 0)


def test_gauss_overlap_counted_once_and_owned_by_later_body():
    lower = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [0.0, 1.0]])
    upper = np.array([[1.0, 0.5], [3.0, 0.5], [3.0, 2.0], [1.0, 2.0]])
    seeds = seed_gauss([lower, upper], cell_size_m=0.25, per_cell=2)
    volumes = seeds.body_volumes_m2(2)
    assert volumes[0] == pytest.approx(1.5, rel=1e-9)  # its 2 m2 less the 0.5 m2 overlap
    assert volumes[1] == pytest.approx(3.0, rel=1e-9)
    assert volumes.sum() == pytest.approx(4.5, rel=1e-9)  # union area: no double count
    # Points agree with the numpy overlap rule.
    np.testing.assert_array_equal(owner_of_points(seeds.positions_m, [lower, upper]), seeds.body_index)


@pytest.mark.parametrize("method", ["lattice", "gauss"])
def test_material_assignment_on_a_layered_slope(method):
    layers = [SlopeLayer("topsoil", 4.0), SlopeLayer("clay", 6.0)]
    bodies = slope_profile(10.0, 45.0, 6.0, 8.0, 4.0, layers=layers)
    names = [name for name, _ in bodies]
    assert names == ["topsoil", "clay", "foundation"]
    polygons = [poly for _, poly in bodies]
    if method == "lattice":
        seeds = seed_lattice(polygons, (0.0, 0.0), 1.0, 2)
    else:
        seeds = seed_gauss(polygons, 1.0, 2)
    y = seeds.positions_m[:, 1]
    # Crest at y = 14; interfaces at 10 (topsoil/clay) and 4 (clay/foundation, the toe level).
    np.testing.assert_array_equal(seeds.body_index[y > 10.0], 0)
    np.testing.assert_array_equal(seeds.body_index[(y < 10.0) & (y > 4.0)], 1)
    np.testing.assert_array_equal(seeds.body_index[y < 4.0], 2)
    volumes = seeds.body_volumes_m2(3)
    expected = np.array([polygon_area(p) for p in polygons])
    if method == "gauss":
        np.testing.assert_allclose(volumes, expected, rtol=1e-9)
    else:
        # the 45-degree face runs through sub-cell centres: the cut sub-cells are clipped, so
        # the volumes are the areas to round-off here too
        np.testing.assert_allclose(volumes, expected, rtol=1e-12)
        assert volumes[2] == pytest.approx(expected[2])  # the foundation is grid-aligned


def test_a_block_resting_on_an_inclined_structure_keeps_its_whole_area():
    """Blocks lying on a ramp's face (their lower edge on it to round-off), every incline from 10
    to 80 deg, from the ramp's top vertex to 2 cells down it, 1-5 cells thick, two cell sizes and
    three heights of the ramp: the seeded volumes are the block's area, none lost to the ramp.
    GEOS's floating-point overlay, used alone, gave 162 of 2754 such placements a wrong region:
    empty (a sheet on a 40 deg ramp: no particles at all) or 14-61 % of the block (its mass lost)."""
    wrong = []
    for theta, start, cells, h, top in itertools.product(range(10, 81, 10), (0.0, 0.5, 1.0, 2.0), (1, 2, 5),
                                                         (0.05, 0.1), (1.7, 1.0, 0.73)):
        th = math.radians(theta)
        down, up = np.array([math.cos(th), -math.sin(th)]), np.array([math.sin(th), math.cos(th)])
        vertex = np.array([0.1, top])
        foot = vertex + 3.0 * down
        ramp = np.array([(0.0, top), vertex, foot, (foot[0], foot[1] - 1.0), (0.0, foot[1] - 1.0)])
        a = vertex + start * h * down
        length = 20 * h
        block = np.array([a, a + length * down, a + length * down + cells * h * up, a + cells * h * up])
        seeds = seed_lattice([block], (0.0, -5.0), h, 2, [ramp])
        ratio = seeds.volumes_m2.sum() / (length * cells * h)
        if abs(ratio - 1.0) > 1e-6:
            wrong.append((theta, start, cells, h, top, round(float(ratio), 4)))
    assert wrong == []
