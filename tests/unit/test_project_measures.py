"""The deposit measures of :mod:`projects.measures` on synthetic particle sets with known answers
(lattices of particles of spacing s); tolerances are round-off, or one spacing where the measure is
exact to one spacing by its definition.
"""

import math

import numpy as np
import pytest

from projects.measures import (
    crest_height,
    front_position,
    max_displacement,
    read_xy_csv,
    rms_deviation,
    surface_heights,
    surface_window,
    toe_position,
    top_height,
)


def lattice(x0, x1, y0, y1, s):
    xs = np.arange(x0 + s / 2, x1, s)
    ys = np.arange(y0 + s / 2, y1, s)
    X, Y = np.meshgrid(xs, ys)
    return np.c_[X.ravel(), Y.ravel()]


def test_surface_of_a_block_is_its_top():
    s = 0.001
    pos = lattice(0.0, 0.2, 0.0, 0.1, s)
    h = surface_heights(pos, None, s, np.array([0.0, 0.1, 0.199, 0.3]))
    np.testing.assert_allclose(h, [0.1, 0.1, 0.1, 0.0], atol=1e-12)
    assert crest_height(pos, None, s) == pytest.approx(0.1)
    assert front_position(pos, None, s) == pytest.approx(0.2)


def test_toe_needs_the_stated_thickness():
    s = 0.001
    block = lattice(0.0, 0.2, 0.0, 0.01, s)
    tail2 = lattice(0.2, 0.3, 0.0, 0.002, s)    # two layers: 2 mm thick
    tail1 = lattice(0.3, 0.35, 0.0, 0.001, s)   # one layer: 1 mm thick
    pos = np.vstack([block, tail2, tail1])
    # the local thickness looks one spacing to each side: the toe is exact to one spacing
    assert toe_position(pos, None, s, 0.002) == pytest.approx(0.3, abs=s + 1e-9)
    assert toe_position(pos, None, s, 0.005) == pytest.approx(0.2, abs=s + 1e-9)
    assert front_position(pos, None, s) == pytest.approx(0.35)


def test_inactive_and_non_finite_particles_are_ignored():
    s = 0.001
    pos = np.vstack([lattice(0.0, 0.1, 0.0, 0.05, s), [[0.5, 0.5]], [[np.nan, np.nan]]])
    active = np.ones(len(pos), bool)
    active[-2] = False
    assert front_position(pos, active, s) == pytest.approx(0.1)
    assert surface_heights(pos, active, s, np.array([0.5]))[0] == 0.0


@pytest.mark.parametrize("s", [0.0005, 0.001, 0.004])
def test_the_top_is_the_highest_particle_top_anywhere(s):
    low = lattice(0.0, 0.2, 0.0, 0.02, s)
    high = lattice(0.5, 0.5 + 4 * s, 0.0, 0.06, s)  # a narrow column far from the wall
    pos = np.vstack([low, high])
    assert top_height(pos, None, s) == pytest.approx(0.06, abs=s + 1e-9)
    assert crest_height(pos, None, s) == pytest.approx(0.02, abs=s + 1e-9)  # the wall's 10 mm only
    active = np.r_[np.ones(len(low), bool), np.zeros(len(high), bool)]
    assert top_height(pos, active, s) == pytest.approx(0.02, abs=s + 1e-9)
    assert math.isnan(top_height(np.zeros((0, 2)), None, s))


def test_the_surface_window_is_5_mm_or_two_spacings():
    assert surface_window(0.001) == pytest.approx(0.005)
    assert surface_window(0.004) == pytest.approx(0.008)


def test_the_largest_displacement_is_in_the_plane_of_the_active_particles():
    d = np.array([[3.0, 4.0, 100.0], [0.0, 1.0, 0.0], [10.0, 0.0, 0.0]])
    assert max_displacement(d, None) == pytest.approx(10.0)  # z (the 3rd component) is not counted
    assert max_displacement(d, np.array([True, True, False])) == pytest.approx(5.0)
    assert math.isnan(max_displacement(d, np.zeros(3, bool)))
    assert math.isnan(max_displacement(None, None))


def test_rms_deviation():
    assert rms_deviation(np.array([1.0, 3.0]), np.array([0.0, 0.0])) == pytest.approx(math.sqrt(5.0))
    assert math.isnan(rms_deviation(np.array([]), np.array([])))


def test_an_observed_profile_skips_comments_and_its_header(tmp_path):
    path = tmp_path / "profile.csv"
    path.write_text("# digitised\nx_m,y_m\n0.0,0.1\n0.2,0.05\n\n", encoding="utf-8")
    np.testing.assert_array_equal(read_xy_csv(path), [[0.0, 0.1], [0.2, 0.05]])
    empty = tmp_path / "empty.csv"
    empty.write_text("x_m,y_m\n", encoding="utf-8")
    with pytest.raises(ValueError, match="empty.csv holds no x, y rows"):
        read_xy_csv(empty)
