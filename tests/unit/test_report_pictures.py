"""The hazard report's pictures and provenance, without a run: a made-up hazard document."""

import numpy as np
import pytest

from app import report


def _doc() -> dict:
    """A slide down a slope from x = 0 to a dam at x = 21.25 m and a road at 26 m (as in
    projects/examples/debris_barrier.toml): the targets stand in the right half of the section."""
    x = np.arange(0.125, 32.0, 0.25)
    ground = np.clip(13.4 - 0.84 * x, 0.0, None)
    peak = np.where(x < 21.0, 2.0, 0.0)
    surface = ground + np.where((x > 14.0) & (x < 21.0), 2.5, 0.0)
    arrival = np.where(x < 21.0, 0.1 * x, np.nan)
    speed = np.where(x < 21.0, 0.6 * x, 0.0)
    profile = {"x_m": x, "floor_m": np.zeros_like(x), "ground_m": ground, "peak_flow_height_m": peak,
               "surface_m": surface, "max_speed_m_s": speed, "max_pressure_pa": 2000.0 * speed**2,
               "deposit_m": surface - ground, "arrival_s": arrival}
    target = {"arrival_time_s": None, "arrival_after_release_s": None, "max_height_m": 0.0, "max_speed_m_s": 0.0,
              "max_pressure_pa": 0.0, "kind": "line", "y_m": None}
    return {"profile": profile, "runout_point_m": [21.0, 0.0], "runout_x_envelope_m": 21.25,
            "source_top_m": [2.8, 13.6], "travel_angle_deg": 36.7, "thresholds": {"deposit_threshold_m": 0.0625},
            "targets": {"dam-crest": dict(target, x_m=21.25), "road": dict(target, x_m=26.0)}}


def test_the_profiles_legend_leaves_the_target_names_readable(tmp_path, monkeypatch):
    """The legend of the surfaces plot sat in its upper right corner, over the names of the
    targets downstream (the road of debris_barrier.toml was hidden under it)."""
    figures = []
    make = report._figure
    monkeypatch.setattr(report, "_figure", lambda *size: figures.append(make(*size)) or figures[-1])
    report.profiles_png(_doc(), tmp_path / "profiles.png")
    fig = figures[0]
    renderer = fig.canvas.get_renderer()
    names = [t for ax in fig.axes for t in ax.texts if t.get_text() in ("dam-crest", "road")]
    assert sorted(t.get_text() for t in names) == ["dam-crest", "road"]
    legends = [ax.get_legend() for ax in fig.axes if ax.get_legend() is not None] + fig.legends
    assert any("surface at the end" in [t.get_text() for t in legend.get_texts()] for legend in legends)
    for legend in legends:
        box = legend.get_window_extent(renderer)
        for name in names:
            assert not box.overlaps(name.get_window_extent(renderer)), (name.get_text(), legend)


@pytest.mark.parametrize(("summary", "shown"), [
    ({"project_file": "/work/slope.toml"}, "/work/slope.toml"),
    ({"project_file": "/work/slope.toml", "project_unsaved": True}, "/work/slope.toml, with edits not saved in it"),
    ({"project_unsaved": True}, "unsaved project"),
    ({}, "-"),  # a folder written before runs recorded their file
])
def test_the_provenance_names_the_project_the_user_had(summary, shown):
    assert report.project_source(summary) == shown


def test_the_profiles_show_the_structures_named_and_in_the_legend(tmp_path, monkeypatch):
    """A dam on the section was only a step of the surface line, read as deposit beyond the run-out
    point (found by a walkthrough): it is drawn as the scene views draw it, hatched and named."""
    figures = []
    make = report._figure
    monkeypatch.setattr(report, "_figure", lambda *size: figures.append(make(*size)) or figures[-1])
    dam = {"name": "check-dam", "polygon_m": [[21.0, 0.0], [21.5, 0.0], [21.5, 2.5], [21.0, 2.5]]}
    bedrock = {"name": "bedrock", "polygon_m": [[0.0, 0.0], [16.0, 0.0], [0.0, 13.4]]}
    report.profiles_png(_doc(), tmp_path / "profiles.png", [bedrock, dam])
    ax = figures[0].axes[0]
    patches = [p for p in ax.patches if p.get_hatch()]
    assert len(patches) == 2
    assert np.allclose(patches[1].get_xy()[:4], dam["polygon_m"])
    assert {"check-dam", "bedrock"} <= {t.get_text() for t in ax.texts}
    labels = [t.get_text() for legend in figures[0].legends for t in legend.get_texts()]
    assert labels.count("structure") == 1
    # none: the plot as before
    figures.clear()
    report.profiles_png(_doc(), tmp_path / "none.png", None)
    assert not [p for p in figures[0].axes[0].patches if p.get_hatch()]
