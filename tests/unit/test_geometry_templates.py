"""The slope template: shape, layers and argument checks."""

import math

import numpy as np
import pytest

from geometry.polygons import is_simple, points_in_polygon, polygon_area, signed_area
from geometry.templates import SlopeLayer, slope_profile


def _analytic_area(height, angle_deg, crest, toe, depth):
    run = height / math.tan(math.radians(angle_deg))
    return (crest + run + toe) * depth + crest * height + 0.5 * run * height


def test_single_body_shape_and_area():
    bodies = slope_profile(10.0, 30.0, 5.0, 8.0, 4.0, origin_m=(100.0, -20.0))
    assert [name for name, _ in bodies] == ["slope"]
    poly = bodies[0][1]
    assert is_simple(poly) and signed_area(poly) > 0  # counter-clockwise
    assert polygon_area(poly) == pytest.approx(_analytic_area(10.0, 30.0, 5.0, 8.0, 4.0))
    run = 10.0 / math.tan(math.radians(30.0))
    # Crest on the left at y0 + D + H, toe surface on the right at y0 + D.
    assert poly[:, 1].max() == pytest.approx(-20.0 + 14.0)
    assert poly[:, 0].min() == pytest.approx(100.0)
    assert poly[:, 0].max() == pytest.approx(100.0 + 5.0 + run + 8.0)
    inside = points_in_polygon(
        [[101.0, -6.5], [100.0 + 5.0 + run + 4.0, -16.5], [100.0 + 5.0 + run + 4.0, -15.5]], poly
    )
    np.testing.assert_array_equal(inside, [True, True, False])


def test_zero_lengths_give_a_triangle():
    poly = slope_profile(3.0, 45.0, 0.0, 0.0, 0.0)[0][1]
    assert len(poly) == 3
    assert polygon_area(poly) == pytest.approx(4.5)


def test_layers_partition_the_profile():
    layers = [SlopeLayer("a", 3.0), SlopeLayer("b", 9.0)]
    bodies = slope_profile(10.0, 45.0, 5.0, 8.0, 4.0, layers=layers)
    assert [name for name, _ in bodies] == ["a", "b", "foundation"]
    for _, poly in bodies:
        assert is_simple(poly) and signed_area(poly) > 0
    areas = [polygon_area(p) for _, p in bodies]
    assert sum(areas) == pytest.approx(_analytic_area(10.0, 45.0, 5.0, 8.0, 4.0))
    # Top layer: crest band 14 -> 11, a trapezoid under the 45-degree face.
    assert areas[0] == pytest.approx(5.0 * 3.0 + 0.5 * 3.0 * 3.0)
    # Layer b reaches 2 m below the toe level, so it spans the full width there.
    assert bodies[1][1][:, 1].min() == pytest.approx(2.0)
    assert bodies[1][1][:, 0].max() == pytest.approx(23.0)
    assert bodies[2][1][:, 1].max() == pytest.approx(2.0)


def test_layers_reaching_the_base_leave_no_remainder():
    bodies = slope_profile(10.0, 45.0, 5.0, 8.0, 4.0, layers=[SlopeLayer("a", 10.0), SlopeLayer("b", 4.0)])
    assert [name for name, _ in bodies] == ["a", "b"]
    assert polygon_area(bodies[1][1]) == pytest.approx(23.0 * 4.0)
    assert all(is_simple(p) for _, p in bodies)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"height_m": 0.0}, r"height_m must be > 0"),
        ({"angle_deg": 90.0}, r"angle_deg must be in the open range \(0, 90\)"),
        ({"angle_deg": 0.0}, r"angle_deg must be in the open range \(0, 90\)"),
        ({"crest_length_m": -1.0}, r"crest_length_m must be >= 0"),
        ({"toe_length_m": float("nan")}, r"toe_length_m must be >= 0"),
        ({"foundation_depth_m": -2.0}, r"foundation_depth_m must be >= 0"),
        ({"layers": [SlopeLayer("a", 20.0)]}, r"layers total thickness 20 m exceeds .* 14 m"),
        ({"layers": [SlopeLayer("a", 1.0), SlopeLayer("a", 1.0)]}, r"layers\[1\].name 'a' is used twice"),
        ({"layers": [SlopeLayer("a", -1.0)]}, r"layers\[0\].thickness_m must be > 0"),
    ],
)
def test_bad_arguments_name_the_argument(kwargs, message):
    args = {
        "height_m": 10.0,
        "angle_deg": 45.0,
        "crest_length_m": 5.0,
        "toe_length_m": 8.0,
        "foundation_depth_m": 4.0,
    }
    args.update(kwargs)
    with pytest.raises(ValueError, match=message):
        slope_profile(**args)
