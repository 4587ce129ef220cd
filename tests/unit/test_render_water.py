"""Ground water in the pictures of a results folder: the phreatic line in blue, the free water
shaded above the ground, and the water where the stage had moved it at each frame's time."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from app import render
from tests.conftest import SYNTHETIC_META, synthetic_frames

#: The synthetic block (0.2 m x 0.1 m, tests/conftest.py) under a level water table at 0.12 m that
#: the dynamic stage lowers to 0.03 m over its 0.15 s; free water at 0.12 m at the start.
WET_PROJECT = """
[runout]
schema_version = 2
title = "Synthetic shear, wet"

[domain]
origin_m = [0.0, 0.0]
size_m = [0.8, 0.15]
cell_size_m = 0.01

[materials.lower]
model = "drucker-prager"
density_kg_m3 = 2000.0
saturated_density_kg_m3 = 2100.0
youngs_modulus_pa = 1.0e6
poisson_ratio = 0.3
cohesion_pa = 0.0
friction_angle_deg = 30.0
dilatancy_angle_deg = 0.0

[materials.upper]
model = "drucker-prager"
density_kg_m3 = 2000.0
youngs_modulus_pa = 1.0e6
poisson_ratio = 0.3
cohesion_pa = 0.0
friction_angle_deg = 30.0
dilatancy_angle_deg = 0.0

[[bodies]]
name = "block"
material = "lower"
polygon_m = [[0.0, 0.0], [0.2, 0.0], [0.2, 0.1], [0.0, 0.1]]

[water]
phreatic_line_m = [[0.0, 0.12], [0.8, 0.12]]

[[stages]]
name = "initial stress"
type = "k0"

[[stages]]
name = "collapse"
type = "dynamic"
duration_s = 0.15

[stages.water]
phreatic_line_m = [[0.0, 0.03], [0.8, 0.03]]

[output]
interval_s = 0.05
"""


def wet_results(path: Path, n_frames: int = 4, project: str = WET_PROJECT) -> Path:
    """A closed synthetic results folder of :data:`WET_PROJECT` whose frames carry pore pressure."""
    from projects.results import ResultsWriter
    from solver.config import Frame

    writer = ResultsWriter(path, project, dict(SYNTHETIC_META))
    for frame in synthetic_frames(n_frames):
        depth = np.clip(0.12 - frame.fields["positions"][:, 1], 0.0, None)
        writer.write_frame(Frame(frame.diagnostics, {**frame.fields, "pore_pressure": 9810.0 * depth},
                                 frame.contacts))
    writer.close("completed")
    return path


def _blue_line_rows(image: np.ndarray) -> np.ndarray:
    """Rows of the picture holding pixels of the phreatic line's colour."""
    rgb = np.array([int(render.WATER_LINE_COLOR[i:i + 2], 16) for i in (1, 3, 5)])
    hits = np.abs(image[:, :, :3].astype(int) - rgb).sum(axis=2) < 40
    return np.flatnonzero(hits.sum(axis=1) > 20)


DRY_PROJECT = WET_PROJECT.replace("[water]\nphreatic_line_m = [[0.0, 0.12], [0.8, 0.12]]\n", "").replace(
    "[stages.water]\nphreatic_line_m = [[0.0, 0.03], [0.8, 0.03]]\n", "")


@pytest.mark.parametrize("frame, level_m", [(0, 0.12), (2, 0.12 + (0.03 - 0.12) * 0.10 / 0.15), (3, 0.03)])
def test_a_picture_draws_the_water_where_the_stage_had_moved_it(tmp_path, frame, level_m):
    """Frame i is at 0.05 i s into the stage that lowers the line from 0.12 m to 0.03 m over 0.15 s:
    the blue line's row in the picture is that of the blended level, within 3 pixels."""
    import imageio.v2 as imageio

    results = render.Results(wet_results(tmp_path / "wet.results"))
    water = render.WaterTimeline.of(results).at_frame(results, frame)
    assert np.allclose(np.asarray(water.phreatic_line_m)[:, 1], level_m)
    size = (800, 450)
    out = render.render_frame(results, frame, "displacement", tmp_path / f"f{frame}.png", size=size)
    rows = _blue_line_rows(imageio.imread(out))
    # a band 3 pixels wide: at least two full rows of its blue (a line one pixel wide blends into
    # the rows beside it and has none)
    assert len(rows) >= 2, rows
    view = render._view(render._domain_box(results), size)  # the particles stay inside the domain
    y0, y1 = view.bounds[2], view.bounds[3]
    expected = size[1] / 2.0 - (level_m - 0.5 * (y0 + y1)) * view.pixels_per_m
    assert abs(float(np.median(rows)) - expected) <= 3.0, (rows, expected)


def test_a_dry_run_has_no_water_in_its_pictures(tmp_path):
    import imageio.v2 as imageio

    results = render.Results(wet_results(tmp_path / "dry.results", project=DRY_PROJECT))
    assert render.WaterTimeline.of(results) is None
    out = render.render_frame(results, 0, "displacement", tmp_path / "dry.png", size=(800, 450))
    assert not len(_blue_line_rows(imageio.imread(out)))


def test_a_line_band_is_the_line_thickened_to_its_width():
    """A bent line (two segments, 0.5 m and 0.5 m long) thickened to 0.02 m: the band's area is its
    length times the width within the mitre's 1e-3, it holds the line's points and ends at its ends."""
    from shapely.geometry import LineString, Point, Polygon

    line = np.array([[0.0, 0.0], [0.3, 0.4], [0.8, 0.4]])
    band = Polygon(render.line_band(line, 0.02))
    assert band.is_valid
    assert band.area == pytest.approx(1.0 * 0.02, rel=1e-3)
    assert band.buffer(1e-9).contains(LineString(line))
    assert not band.contains(Point(0.3, 0.42)) and band.bounds[2] == pytest.approx(0.8, abs=1e-12)


def test_the_free_water_lies_between_its_line_and_the_ground_surface():
    box = (0.0, 0.8, 0.0, 0.15)
    block = np.array([[0.0, 0.0], [0.2, 0.0], [0.2, 0.1], [0.0, 0.1]])
    rings = render.free_water_polygons([[0.0, 0.12], [0.8, 0.12]], [block], box)
    from shapely.geometry import Polygon

    area = sum(Polygon(r).area for r in rings)
    # over the block 0.2 x 0.02, beside it 0.6 x 0.12
    assert area == pytest.approx(0.2 * 0.02 + 0.6 * 0.12, rel=1e-9)
    assert render.free_water_polygons([[0.0, 0.05], [0.8, 0.05]], [np.array([[0, 0], [0.8, 0], [0.8, 0.1], [0, 0.1]])],
                                      box) == []


def test_a_frame_s_free_water_stands_on_its_particles():
    """Particles of a 0.2 m x 0.1 m block moved 0.3 m right (spacing 0.01 m): the free water under a
    level line at 0.12 m lies over the block where it now is and down to the floor where it was."""
    xs, ys = np.meshgrid(np.arange(0.005, 0.2, 0.01) + 0.3, np.arange(0.005, 0.1, 0.01))
    ground = render.particle_ground(np.column_stack([xs.ravel(), ys.ravel()]), 0.01, (0.0, 0.8, 0.0, 0.15))
    rings = render.free_water_polygons([[0.0, 0.12], [0.8, 0.12]], ground, (0.0, 0.8, 0.0, 0.15))
    from shapely.geometry import Point, Polygon

    water = [Polygon(r) for r in rings]
    assert sum(w.area for w in water) == pytest.approx(0.2 * 0.02 + 0.6 * 0.12, rel=1e-6)
    assert any(w.contains(Point(0.1, 0.05)) for w in water)  # where the block was
    assert not any(w.contains(Point(0.4, 0.05)) for w in water)  # where it is
