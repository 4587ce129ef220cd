"""Inputs that used to give tracebacks or go silently wrong: one line each, or a warning."""

from __future__ import annotations

import os
import stat

import numpy as np
import pytest

from geometry.polygons import self_intersections
from geometry.templates import slope_domain, slope_profile
from projects.checks import project_warnings, recommended_initial_stage, sloping_faces
from projects.document import apply_overrides, load_project, loads_project, save_project
from projects.schema import ProjectError
from tests.conftest import EXAMPLES, TINY_PROJECT


@pytest.fixture(scope="module")
def tiny():
    return load_project(TINY_PROJECT)


# --------------------------------------------------------------------------------------------
# reading


@pytest.mark.parametrize("text", [
    "a = " + "[" * 5000 + "]" * 5000,
    "[runout]\nx = " + "{a = " * 3000 + "1" + "}" * 3000,
])
def test_deeply_nested_toml_is_one_line(text):
    with pytest.raises(ProjectError) as info:
        loads_project(text, source="deep.toml")
    assert "\n" not in str(info.value)
    assert str(info.value).startswith("deep.toml: ")


def test_a_byte_order_mark_is_ignored(tmp_path):
    text = TINY_PROJECT.read_text(encoding="utf-8")
    path = tmp_path / "bom.toml"
    path.write_bytes(b"\xef\xbb\xbf" + text.encode("utf-8"))
    assert load_project(path) == load_project(TINY_PROJECT)


# --------------------------------------------------------------------------------------------
# saving through a symbolic link


def test_saving_through_a_symbolic_link_writes_its_target_and_keeps_the_mode(tmp_path, tiny):
    real = tmp_path / "real" / "slope.toml"
    real.parent.mkdir()
    real.write_text(TINY_PROJECT.read_text())
    os.chmod(real, 0o600)
    link = tmp_path / "link.toml"
    link.symlink_to(real)
    chain = tmp_path / "chain.toml"
    chain.symlink_to(link)
    changed = apply_overrides(tiny, ["runout.title=changed"])
    save_project(changed, chain)
    assert chain.is_symlink() and link.is_symlink()
    assert load_project(real).runout.title == "changed"
    assert stat.S_IMODE(os.stat(real).st_mode) == 0o600
    assert sorted(p.name for p in real.parent.iterdir()) == ["slope.toml"]  # no temp file left


# --------------------------------------------------------------------------------------------
# polygons: the R-tree check finds what the all-pairs check finds


def _all_pairs(polygon: np.ndarray) -> list[tuple[int, int]]:
    """The reference: every pair of edges, tested directly (quadratic)."""
    from geometry.polygons import _pairs_intersect

    k = len(polygon)
    d = np.roll(polygon, -1, axis=0) - polygon
    i, j = np.triu_indices(k, 1)
    scale = float(np.max(np.abs(polygon - polygon.mean(axis=0)))) or 1.0
    hit = _pairs_intersect(polygon, d, i, j, k, 1e-12 * scale * scale)
    return sorted(zip(i[hit].tolist(), j[hit].tolist()))


@pytest.mark.parametrize("seed", range(6))
def test_self_intersections_match_the_all_pairs_check(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(4, 60))
    if seed % 2:
        polygon = rng.uniform(-1.0, 1.0, size=(n, 2))  # random: mostly crossing
    else:  # a star-shaped outline, sometimes with a vertex pushed onto another edge
        t = np.sort(rng.uniform(0, 2 * np.pi, n))
        r = rng.uniform(0.5, 1.0, n)
        polygon = np.column_stack([r * np.cos(t), r * np.sin(t)])
        polygon[n // 2] = 0.5 * (polygon[0] + polygon[1])
    polygon = polygon * 100.0 + np.array([5e5, 4e6])  # also far from the origin
    assert self_intersections(polygon) == _all_pairs(polygon)


def test_a_long_outline_validates_and_its_crossing_is_named():
    t = np.linspace(0, 2 * np.pi, 10_000, endpoint=False)
    r = 10.0 + np.sin(7 * t)
    outline = np.column_stack([r * np.cos(t), r * np.sin(t)])
    assert self_intersections(outline) == []
    outline[[10, 5000]] = outline[[5000, 10]]
    assert self_intersections(outline) == [(9, 5000), (10, 4999)]


# --------------------------------------------------------------------------------------------
# the slope template and the warnings


def test_the_slope_template_rests_on_the_base_and_touches_the_walls():
    bodies = slope_profile(5.0, 45.0, 4.0, 6.0, 1.0, origin_m=(100.0, 50.0))
    polygons = [p for _, p in bodies]
    origin, size = slope_domain(polygons, 0.25)
    assert origin == (100.0, 50.0)
    assert size[0] == pytest.approx(15.0)  # crest 4 + run 5 + toe 6: whole cells, the right wall touches
    assert size[1] >= 6.0 * 1.25 and (size[1] / 0.25) == pytest.approx(round(size[1] / 0.25))
    # a width that is no whole number of cells: more than a cell of room, never a sliver
    origin, size = slope_domain(polygons, 0.4)
    assert size[0] - 15.0 >= 0.4 - 1e-9
    origin, size = slope_domain(polygons, 0.25, runout_length_m=10.0)
    assert size[0] == pytest.approx(25.0)
    with pytest.raises(ValueError, match="cell_size_m"):
        slope_domain(polygons, 0.0)


def _slope_project(tiny, polygon, origin=(0.0, 0.0), stage="k0"):
    sets = [f"bodies.0.polygon_m={polygon}", f"domain.origin_m=[{origin[0]}, {origin[1]}]"]
    if stage == "gravity":
        sets.append('stages.0={name = "initial stress", type = "gravity", duration_s = 0.5}')
    return apply_overrides(tiny, sets)


SLOPE = "[[0,0],[0.6,0],[0.6,0.06],[0.36,0.06],[0.2,0.2],[0,0.2]]"


def test_no_warnings_for_the_examples():
    for path in sorted(EXAMPLES.glob("*.toml")):
        assert project_warnings(load_project(path)) == [], path.name


def test_a_body_floating_less_than_a_cell_above_the_base_is_a_warning(tiny):
    floating = _slope_project(tiny, "[[0,0.01],[0.12,0.01],[0.12,0.25],[0,0.25]]")
    warnings = project_warnings(floating)
    assert len(warnings) == 1
    assert warnings[0].startswith("bodies.0 ('column') is 0.01 m from the bottom wall (friction)")
    # beside the left wall too, by half a cell: the slope template's old placement
    shifted = _slope_project(tiny, "[[0.01,0.01],[0.13,0.01],[0.13,0.25],[0.01,0.25]]")
    assert [w.split(" wall")[0].rsplit(" ", 1)[1] for w in project_warnings(shifted)] == ["left", "bottom"]
    # two cells away is a choice, not a trap; an open side is never a wall
    assert project_warnings(_slope_project(tiny, "[[0.04,0],[0.16,0],[0.16,0.24],[0.04,0.24]]")) == []
    top_open = _slope_project(tiny, "[[0,0],[0.12,0],[0.12,0.29],[0,0.29]]")
    assert project_warnings(top_open) == []


def test_k0_on_sloping_ground_is_a_warning_and_gravity_is_recommended(tiny):
    slope = _slope_project(tiny, SLOPE)
    faces = sloping_faces(slope)
    assert len(faces) == 1 and faces[0].angle_deg == pytest.approx(np.degrees(np.arctan2(0.14, 0.16)))
    warnings = project_warnings(slope)
    assert len(warnings) == 1 and warnings[0].startswith('stages.0.type = "k0": the ground slopes (41.2 degrees')
    stage = recommended_initial_stage(slope)
    assert stage["type"] == "gravity" and stage["duration_s"] >= 1.0
    assert stage["damping"]["coefficient"] > 0
    assert project_warnings(_slope_project(tiny, SLOPE, stage="gravity")) == []
    # level ground and a vertical column face are not slopes
    assert recommended_initial_stage(tiny) == {"name": "initial stress", "type": "k0"}
    assert sloping_faces(_slope_project(tiny, "[[0,0],[0.6,0],[0.6,0.1],[0,0.1]]")) == []


def test_a_slope_covered_by_another_body_is_not_exposed(tiny):
    two = apply_overrides(tiny, [
        f"bodies.0.polygon_m={SLOPE}",
        'bodies=[{name = "lower", material = "sand", polygon_m = ' + SLOPE + '}, '
        '{name = "fill", material = "sand", polygon_m = [[0.2,0.2],[0.36,0.06],[0.6,0.06],[0.6,0.2]]}]',
    ])
    assert sloping_faces(two) == []


def test_the_recommended_gravity_stage_lasts_three_periods_of_the_deposit():
    slope = load_project(EXAMPLES / "slope_sun_song_2015.toml")
    material = next(iter(slope.materials.values()))
    c_s = np.sqrt(material.youngs_modulus_pa / (2 * (1 + material.poisson_ratio)) / material.density_kg_m3)
    expected = 3 * 4 * 69.0 / c_s
    assert recommended_initial_stage(slope)["duration_s"] == pytest.approx(expected, rel=0.05)


@pytest.mark.parametrize("fraction,warned", [(0.5, True), (0.99, True), (1.01, False), (3.0, False)])
def test_a_gravity_stage_shorter_than_the_deposits_period_is_warned_about(fraction, warned):
    # the slope of Sun and Song: 69 m high, c_s = sqrt(G / rho); its period 4 H / c_s is 2.8 s
    slope = load_project(EXAMPLES / "slope_sun_song_2015.toml")
    material = next(iter(slope.materials.values()))
    c_s = np.sqrt(material.youngs_modulus_pa / (2 * (1 + material.poisson_ratio)) / material.density_kg_m3)
    period = 4 * 69.0 / c_s
    index = next(i for i, st in enumerate(slope.stages) if st.type == "gravity")
    short = apply_overrides(slope, [f"stages.{index}.duration_s={float(fraction * period)!r}"])
    lines = [w for w in project_warnings(short) if f"stages.{index}.duration_s" in w]
    assert bool(lines) == warned
    if warned:
        assert len(lines) == 1 and "\n" not in lines[0]
        assert f"{period:.2g} s" in lines[0]
        assert f"use duration_s = {recommended_initial_stage(slope)['duration_s']:g}" in lines[0]
