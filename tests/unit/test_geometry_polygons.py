"""Polygon area, simplicity, point location and the overlap rule (pure numpy)."""

import numpy as np
import pytest

from geometry.polygons import (
    check_simple,
    counter_clockwise,
    is_simple,
    owner_of_points,
    points_in_polygon,
    polygon_area,
    polygon_perimeter,
    remove_spikes,
    self_intersections,
    signed_area,
)

SQUARE = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
# L-shape: 2 x 2 square minus its upper-right 1 x 1 quarter.
L_SHAPE = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [1.0, 1.0], [1.0, 2.0], [0.0, 2.0]])
BOW_TIE = np.array([[0.0, 0.0], [1.0, 1.0], [1.0, 0.0], [0.0, 1.0]])


def test_area_of_known_shapes():
    assert polygon_area(SQUARE) == pytest.approx(1.0)
    assert polygon_area(L_SHAPE) == pytest.approx(3.0)
    assert polygon_area(L_SHAPE[::-1]) == pytest.approx(3.0)  # orientation does not matter
    assert signed_area(L_SHAPE) > 0 > signed_area(L_SHAPE[::-1])
    assert polygon_perimeter(L_SHAPE) == pytest.approx(8.0)


def test_area_ignores_repeated_closing_vertex_and_far_offsets():
    closed = np.vstack([SQUARE, SQUARE[:1]])
    assert polygon_area(closed) == pytest.approx(1.0)
    assert polygon_area(SQUARE + 1e6) == pytest.approx(1.0, rel=1e-12)


def test_simple_shapes_are_simple():
    assert is_simple(SQUARE)
    assert is_simple(L_SHAPE)
    assert self_intersections(L_SHAPE) == []


def test_bow_tie_is_not_simple_and_names_the_crossing_edges():
    assert not is_simple(BOW_TIE)
    # Edge 0 (0,0)-(1,1) crosses edge 2 (1,0)-(0,1).
    assert self_intersections(BOW_TIE) == [(0, 2)]


def test_touching_and_folding_edges_are_intersections():
    figure_eight = np.array([[0, 0], [1, 1], [2, 0], [2, 2], [1, 1], [0, 2]], dtype=float)
    assert not is_simple(figure_eight)
    folded = np.array([[0, 0], [2, 0], [1, 0], [1, 1]], dtype=float)
    assert (0, 1) in self_intersections(folded)


def test_degenerate_polygons_are_not_simple():
    assert not is_simple(np.array([[0.0, 0.0], [1.0, 0.0]]))
    assert not is_simple(np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]]))  # no area
    assert not is_simple(np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 0.0], [0.0, 0.0]]))


def test_repeated_consecutive_vertex_is_tolerated():
    assert is_simple(np.array([[0, 0], [1, 0], [1, 0], [1, 1], [0, 1]], dtype=float))


def test_check_simple_messages_name_the_problem():
    with pytest.raises(ValueError, match=r"bodies\[2\].*self-intersecting.*0-2"):
        check_simple(BOW_TIE, "bodies[2]")
    with pytest.raises(ValueError, match="at least 3 distinct points, got 2"):
        check_simple([[0, 0], [1, 1], [0, 0]])
    with pytest.raises(ValueError, match="shape"):
        check_simple(np.zeros((3, 3)))
    with pytest.raises(ValueError, match="non-finite"):
        check_simple([[0, 0], [1, np.nan], [0, 1]])


def test_points_in_polygon_l_shape():
    points = np.array([[0.5, 0.5], [1.5, 0.5], [0.5, 1.5], [1.5, 1.5], [3.0, 0.5], [-0.1, 1.0]])
    expected = np.array([True, True, True, False, False, False])
    np.testing.assert_array_equal(points_in_polygon(points, L_SHAPE), expected)
    np.testing.assert_array_equal(points_in_polygon(points, L_SHAPE[::-1]), expected)


def test_points_on_a_shared_edge_belong_to_exactly_one_side():
    left = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    right = left + [1.0, 0.0]
    on_edge = np.column_stack([np.full(7, 1.0), np.linspace(0.05, 0.95, 7)])
    count = points_in_polygon(on_edge, left).astype(int) + points_in_polygon(on_edge, right)
    np.testing.assert_array_equal(count, 1)


def test_owner_of_points_later_body_wins():
    lower = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [0.0, 1.0]])
    upper = np.array([[1.0, 0.5], [3.0, 0.5], [3.0, 2.0], [1.0, 2.0]])
    points = np.array([[0.5, 0.5], [1.5, 0.75], [2.5, 1.5], [5.0, 5.0]])
    np.testing.assert_array_equal(owner_of_points(points, [lower, upper]), [0, 1, 1, -1])
    # Reversing the painting order hands the overlap to the other body.
    np.testing.assert_array_equal(owner_of_points(points, [upper, lower]), [1, 1, 0, -1])


def test_counter_clockwise_and_spike_removal():
    assert signed_area(counter_clockwise(SQUARE[::-1])) == pytest.approx(1.0)
    spiky = np.array([[0, 0], [2, 0], [3, 0], [2, 0], [2, 1], [0, 1]], dtype=float)
    cleaned = remove_spikes(spiky)
    assert is_simple(cleaned)
    assert polygon_area(cleaned) == pytest.approx(2.0)
    assert len(cleaned) == 4


@pytest.mark.parametrize("edges", [3, 12, 64, 200])
def test_candidate_pairs_are_the_same_with_and_without_the_r_tree(edges, monkeypatch):
    """Few edges take every pair, many take shapely's R-tree: both find the same overlapping boxes
    (touching boxes included), also for boxes that only touch."""
    from geometry import polygons

    rng = np.random.default_rng(edges)
    # a closed chain on a 0.1 m lattice: neighbours share a vertex, other boxes touch exactly
    start = np.round(rng.uniform(0, 10, (edges, 2)), 1)
    end = np.roll(start, -1, axis=0)
    found = {}
    for limit in (0, 10**6):  # R-tree always / never
        monkeypatch.setattr(polygons, "ALL_PAIRS_UP_TO", limit)
        i, j = polygons._candidate_pairs(start, end, 0.0)
        assert np.all(i < j)
        found[limit] = sorted(zip(i.tolist(), j.tolist()))
    assert found[0] == found[10**6]
    assert len(found[0]) > 0
