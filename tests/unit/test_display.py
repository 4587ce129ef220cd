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
    # a mass compressed below its spacing keeps the initial size; a spread one at most 2 spacings
    assert display_spacing(_lattice(30, 10, 0.125, stretch=0.8), 0.125) == pytest.approx(0.125)
    assert display_spacing(_lattice(30, 10, 0.125, stretch=2.2), 0.125) == pytest.approx(0.25)
    # columns five spacings apart are columns: no square grows to bridge them
    assert display_spacing(_lattice(30, 10, 0.125, stretch=5.0), 0.125) == pytest.approx(0.125)
    assert display_spacing(np.zeros((3, 2)), 0.125) == 0.125


def test_runout_render_smooths_on_request_and_draws_the_spread(tmp_path):
    """A picture of a stress checkerboard: with --smooth the stressed block is one colour."""
    from PIL import Image
    from typer.testing import CliRunner

    from app.cli import cli
    from projects.results import ResultsWriter
    from solver.config import Diagnostics, Frame
    from tests.conftest import SYNTHETIC_META, SYNTHETIC_PROJECT

    p0 = _lattice(40, 20, 0.005)
    cell = (np.floor(p0[:, 0] / 0.01) + np.floor(p0[:, 1] / 0.01)) % 2
    syy = -10_000.0 + np.where(cell == 0, 3000.0, -3000.0)
    writer = ResultsWriter(tmp_path / "board.results", SYNTHETIC_PROJECT, dict(SYNTHETIC_META))
    diag = Diagnostics(time_s=0.0, stage="run", stage_index=0, stage_time_s=0.0, step=0, dt_s=1e-3,
                       kinetic_energy_J_per_m=0.0, momentum_x=0.0, momentum_y=0.0, max_speed_m_s=0.0,
                       unstable_particles=0, lost_particles=0, total_mass_kg_per_m=1.0, yielding_particles=0)
    writer.write_frame(Frame(diag, {"positions": p0, "active": np.ones(len(p0), bool),
                                    "stress": np.column_stack([syy, syy, 0 * syy, syy]),
                                    "material_id": np.zeros(len(p0), np.int32)}))
    writer.close("completed", "")
    colours = []
    for smooth in ([], ["--smooth"]):
        out = tmp_path / f"board{len(smooth)}.png"
        result = CliRunner().invoke(cli, ["render", str(tmp_path / "board.results"), "--field", "stress_yy",
                                          "--size", "800x400", "-o", str(out), *smooth])
        assert result.exit_code == 0, result.output
        image = np.asarray(Image.open(out).convert("RGB"), dtype=int)
        # inside the block (x 0.02-0.17 m, y 0.01-0.08 m: pixels 90-200 across, 195-240 down)
        middle = image[195:240, 90:200].reshape(-1, 3)
        colours.append(len({tuple(c) for c in middle if c.sum() < 700}))  # not the white background
    assert colours[0] > 1 and colours[1] == 1
