"""What the views draw beyond the raw particle values (app.display): the squares' size where a
mass has spread, and a stress averaged over the cells around each particle."""

from __future__ import annotations

import numpy as np
import pytest

from app.display import display_spacing, smooth_values


def _lattice(nx: int, ny: int, spacing: float, stretch: float = 1.0) -> np.ndarray:
    x, y = np.meshgrid((np.arange(nx) + 0.5) * spacing * stretch, (np.arange(ny) + 0.5) * spacing)
    return np.column_stack([x.ravel(), y.ravel()])


def test_a_cell_scale_checkerboard_is_shown_as_its_local_mean_and_a_linear_field_unchanged():
    pts = _lattice(40, 20, 0.5)  # 2 x 2 particles per 1 m cell
    cell = (np.floor(pts[:, 0]) + np.floor(pts[:, 1])) % 2
    trend = 100.0 + 10.0 * pts[:, 0] - 3.0 * pts[:, 1]
    noisy = trend + np.where(cell == 0, 30.0, -30.0)  # +-30 kPa alternating from cell to cell
    inside = (pts[:, 0] > 2) & (pts[:, 0] < 18) & (pts[:, 1] > 2) & (pts[:, 1] < 8)
    smoothed = smooth_values(pts, noisy, 1.0)
    assert np.abs(noisy - trend)[inside].min() == pytest.approx(30.0)
    assert np.abs(smoothed - trend)[inside].max() < 1e-9  # the checkerboard averages out exactly here
    assert np.abs(smooth_values(pts, trend, 1.0) - trend)[inside].max() < 1e-9  # a linear field keeps
    # the edge of the mass: still a mean of values of the mass (no zeros from empty cells)
    assert smoothed.min() >= noisy.min() and smoothed.max() <= noisy.max()


def test_smoothing_leaves_values_it_cannot_use_out():
    pts = _lattice(8, 8, 0.5)
    values = np.full(len(pts), 5.0)
    values[3] = np.nan
    out = smooth_values(pts, values, 1.0)
    assert np.allclose(out, 5.0)  # the NaN particle takes its neighbours' value
    assert np.array_equal(smooth_values(pts, values, 0.0), values, equal_nan=True)  # no cell size: unchanged


def test_the_squares_follow_the_spread_of_a_stretched_mass():
    assert display_spacing(_lattice(30, 10, 0.125), 0.125) == pytest.approx(0.125)
    # the columns drawn apart to 1.3 times the spacing along x: squares as wide as the gap's pitch
    assert display_spacing(_lattice(30, 10, 0.125, stretch=1.3), 0.125) == pytest.approx(1.3 * 0.125)
    # a mass compressed below its spacing keeps the initial size; a scattered one at most 2 spacings
    assert display_spacing(_lattice(30, 10, 0.125, stretch=0.8), 0.125) == pytest.approx(0.125)
    assert display_spacing(_lattice(30, 10, 0.125, stretch=5.0), 0.125) == pytest.approx(0.25)
    assert display_spacing(np.zeros((3, 2)), 0.125) == 0.125
