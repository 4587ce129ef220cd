"""Offscreen rendering of results folders: pictures, fields, movies, no Qt."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

imageio = pytest.importorskip("imageio.v3")
pytest.importorskip("pyvista")

from app.render import FIELDS, animate, field_values, render_frame  # noqa: E402
from projects.results import Results, ResultsWriter  # noqa: E402
from solver.config import Frame  # noqa: E402
from tests.conftest import REPO, SYNTHETIC_META, synthetic_frames  # noqa: E402

SMALL = (480, 270)


def _colours(img: np.ndarray) -> set[tuple[int, int, int]]:
    return {tuple(c) for c in img[..., :3].reshape(-1, 3)}


def _non_white(img: np.ndarray) -> np.ndarray:
    return np.any(img[..., :3] < 250, axis=-1)


def test_render_writes_a_non_blank_png(make_results, tmp_path):
    path = render_frame(make_results(), -1, "displacement", tmp_path / "d.png", size=(800, 450))
    img = imageio.imread(path)
    assert img.shape[:2] == (450, 800)
    assert (img[0, 0, :3] == 255).all()  # white background
    assert _non_white(img).mean() > 0.03  # particles, axes, colour bar
    assert len(_colours(img)) > 50  # a colour map, not a flat fill


def test_colours_change_with_the_field(make_results, tmp_path):
    res = Results(make_results())
    a = imageio.imread(render_frame(res, -1, "displacement", tmp_path / "a.png", size=SMALL))
    b = imageio.imread(render_frame(res, -1, "stress_yy", tmp_path / "b.png", size=SMALL))
    c = imageio.imread(render_frame(res, -1, "displacement", tmp_path / "c.png", size=SMALL))
    np.testing.assert_array_equal(a, c)  # deterministic
    differ = np.any(a[..., :3] != b[..., :3], axis=-1)
    assert differ.mean() > 0.02  # the particles changed colour, not just the bar title


def test_every_field_renders(make_results, tmp_path):
    res = Results(make_results())
    images = {}
    written = set(res.frame(1))
    for name in FIELDS:
        if FIELDS[name].source not in written:  # pore_pressure: a dry run writes none
            with pytest.raises(ValueError, match="did not write"):
                render_frame(res, 1, name, tmp_path / f"{name}.png", size=SMALL)
            continue
        images[name] = imageio.imread(render_frame(res, 1, name, tmp_path / f"{name}.png", size=SMALL))
        assert _non_white(images[name]).mean() > 0.02, name
    # the categorical material picture has few colours in the body
    assert len(_colours(images["material"])) < len(_colours(images["displacement"]))


def test_default_output_name_is_beside_the_results_folder(make_results):
    folder = make_results()
    path = render_frame(folder, 0, "material", size=SMALL)
    assert path == folder.parent / "synthetic_material_00000.png"  # never inside: a re-run may replace it
    assert path.stat().st_size > 1000


def test_inactive_particles_are_not_drawn(tmp_path):
    frame = synthetic_frames(1, lose_last=0)[0]
    fields = dict(frame.fields)
    n = len(fields["active"])
    positions = np.array(fields["positions"])
    positions[:100] += [0.5, 0.0]  # a far-away group ...
    active = np.ones(n, bool)
    active[:100] = False  # ... that was removed
    with_ghosts = {**fields, "positions": positions, "active": active}
    without = {k: v[100:] for k, v in with_ghosts.items()}
    for name, f in (("ghosts", with_ghosts), ("clean", without)):
        writer = ResultsWriter(tmp_path / name, "", dict(SYNTHETIC_META))
        writer.write_frame(Frame(frame.diagnostics, f))
        writer.close("completed")
    a = imageio.imread(render_frame(tmp_path / "ghosts", 0, "velocity", tmp_path / "a.png", size=SMALL))
    b = imageio.imread(render_frame(tmp_path / "clean", 0, "velocity", tmp_path / "b.png", size=SMALL))
    np.testing.assert_array_equal(a, b)


def test_unknown_and_unavailable_fields(make_results, tmp_path):
    res = make_results()
    with pytest.raises(ValueError, match="unknown field 'pressure'; allowed: displacement, "):
        render_frame(res, -1, "pressure", tmp_path / "x.png")
    frame = synthetic_frames(1)[0]
    writer = ResultsWriter(tmp_path / "bare", "", {})
    writer.write_frame(Frame(frame.diagnostics, {k: frame.fields[k] for k in ("positions", "active")}))
    writer.close("completed")
    with pytest.raises(ValueError, match="needs the 'stress' output"):
        render_frame(tmp_path / "bare", -1, "mean_stress", tmp_path / "x.png")
    with pytest.raises(ValueError, match="out of range"):
        render_frame(res, 10, "displacement", tmp_path / "x.png")


def test_field_values_units():
    arrays = {
        "displacement": np.array([[3.0, 4.0], [0.0, -1.0]]),
        "stress": np.array([[-3000.0, -6000.0, 500.0, -3000.0], [0.0, 0.0, 0.0, 0.0]]),
        "material_id": np.array([1, 0], np.int32),
    }
    np.testing.assert_allclose(field_values(arrays, "displacement"), [5.0, 1.0])
    np.testing.assert_allclose(field_values(arrays, "displacement_y"), [4.0, -1.0])
    np.testing.assert_allclose(field_values(arrays, "stress_yy"), [-6.0, 0.0])  # kPa
    np.testing.assert_allclose(field_values(arrays, "stress_xy"), [0.5, 0.0])
    np.testing.assert_allclose(field_values(arrays, "mean_stress"), [-4.0, 0.0])
    np.testing.assert_array_equal(field_values(arrays, "material"), [1, 0])
    assert FIELDS["stress_xx"].title == "Stress xx (kPa)"
    assert FIELDS["velocity"].unit == "m/s"
    assert FIELDS["material"].categorical


def test_animate_gif_and_mp4(make_results, tmp_path):
    res = Results(make_results(n_frames=4))
    seen = []
    gif = animate(res, tmp_path / "movie.gif", "displacement", fps=5, size=(240, 136),
                  on_frame=lambda done, total: seen.append((done, total)))
    frames = imageio.imread(gif, index=None)
    assert frames.shape[0] == 4
    assert seen[-1] == (4, 4)
    assert not np.array_equal(frames[0], frames[-1])  # the body moves
    mp4 = animate(res, tmp_path / "movie.mp4", "velocity", fps=5, size=(241, 135))  # odd sizes are evened
    assert mp4.stat().st_size > 1000
    with pytest.raises(ValueError, match=".mp4 or .gif"):
        animate(res, tmp_path / "movie.avi")


def test_rendering_does_not_import_qt(make_results, tmp_path):
    folder = make_results()
    code = (
        "import sys; sys.path.insert(0, %r)\n"
        "from app.render import render_frame\n"
        "render_frame(%r, -1, 'displacement', %r, size=(200, 120))\n"
        "bad = [m for m in sys.modules if m.split('.')[0] in ('PySide6', 'PyQt5', 'PyQt6', 'pyvistaqt')]\n"
        "assert not bad, bad\n"
    ) % (str(REPO), str(folder), str(tmp_path / "q.png"))
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "q.png").is_file()
    assert "bad X server" not in proc.stderr


def test_structures_are_drawn_in_pictures(tmp_path):
    # a structure well apart from the particles: its grey fill appears only when it is drawn
    meta = {**SYNTHETIC_META, "structures": [{"name": "dam", "polygon_m": [[0.6, 0.0], [0.7, 0.0], [0.65, 0.12]]}]}
    pictures = {}
    for name, m in (("with", meta), ("without", SYNTHETIC_META)):
        writer = ResultsWriter(tmp_path / f"{name}.results", "", dict(m))
        for frame in synthetic_frames(2):
            writer.write_frame(frame)
        writer.close("completed")
        pictures[name] = imageio.imread(render_frame(tmp_path / f"{name}.results", -1, "displacement",
                                                     tmp_path / f"{name}.png", size=SMALL))
    grey = lambda img: np.all(np.abs(img[..., :3].astype(int) - 180) <= 3, axis=-1)  # noqa: E731 - fill #b4b4b4
    assert grey(pictures["with"]).sum() > grey(pictures["without"]).sum() + 300


@pytest.mark.parametrize("bounds", [(0.0, 1.2, 0.0, 0.8), (0.0, 0.8, 0.0, 0.15), (0.0, 12.0, -3.0, 0.5),
                                    (100.0, 101.3, 0.0, 0.02), (0.0, 0.6, 0.0, 0.3)])
def test_every_axis_label_reads_as_its_tick(bounds):
    """One label format serves both axes: it must have the decimals of the finer-written step
    (x every 0.25 m and y every 0.2 m: "%.2f", not "%.1f", which printed 0.25 as "0.2" and 0.75
    as "0.8")."""
    from app.render import _view

    view = _view(bounds, (1600, 900))
    x0, x1, y0, y1 = view.bounds
    for lo, hi, n in ((x0, x1, view.labels[0]), (y0, y1, view.labels[1])):
        for tick in np.linspace(lo, hi, n):
            assert float(view.label_format % tick) == pytest.approx(tick, abs=1e-9 * max(1.0, abs(tick))), (
                view.label_format, tick)


@pytest.mark.parametrize("lo, hi", [(0.0, 4.54), (0.08169, 0.08181), (2.2, 4.54), (101325.0, 101331.0),
                                    (-1e-6, 1e-6), (0.0, 1.0)])
def test_the_colour_bar_labels_are_distinct(lo, hi):
    """Five colour-bar labels that read differently: a narrow range (a block that moved as one,
    displacements 0.08169 to 0.08181 m) printed "0.0818, 0.0818, 0.0817, 0.0817, 0.0817" with 3
    significant digits; the digits grow until each label differs, 3 where they suffice."""
    from app.render import bar_format

    fmt = bar_format(lo, hi)
    labels = [fmt % v for v in np.linspace(lo, hi, 5)]
    assert len(set(labels)) == 5, labels
    if (lo, hi) == (0.0, 4.54):
        assert fmt == "%.3g"


def test_a_scene_in_real_world_coordinates_is_drawn_as_at_the_origin(tmp_path):
    """Frames in UTM-like coordinates (x ~ 5e5 m, y ~ 4e6 m: float64 in the file) draw the same
    particles and structures as the scene at the origin; only the axis labels differ (VTK draws in
    float32, 0.25 m apart at y = 4e6 m: the 200-particle block of a 0.2 m scene was drawn as one
    row of eight squares and the structures' fills slid off their outlines)."""
    shift = np.array([500000.0, 4000000.0])
    structure = [[0.25, 0.0], [0.4, 0.0], [0.4, 0.06], [0.25, 0.06]]
    pictures = {}
    for name, offset in (("origin", np.zeros(2)), ("utm", shift)):
        domain = {**SYNTHETIC_META["domain"], "origin_m": list(offset)}
        meta = {**SYNTHETIC_META, "domain": domain,
                "structures": [{"name": "dam", "polygon_m": (np.array(structure) + offset).tolist()}]}
        writer = ResultsWriter(tmp_path / f"{name}.results", "", meta)
        for frame in synthetic_frames(2, lose_last=0):
            fields = {**frame.fields, "positions": frame.fields["positions"] + offset}
            writer.write_frame(Frame(frame.diagnostics, fields, frame.contacts))
        writer.close("completed")
        pictures[name] = imageio.imread(render_frame(tmp_path / f"{name}.results", 0, "stress_yy",
                                                     tmp_path / f"{name}.png", size=SMALL))[..., :3].astype(int)
    # inside the axes only (the labels differ, and their anti-aliased edges hold greys)
    h, w = SMALL[1], SMALL[0]
    inside = (slice(int(0.3 * h), int(0.63 * h)), slice(int(0.12 * w), int(0.85 * w)))
    coloured = {k: ((img.max(axis=-1) - img.min(axis=-1)) > 40)[inside] for k, img in pictures.items()}  # particles
    grey = {k: np.all(np.abs(img - 180) <= 3, axis=-1)[inside] for k, img in pictures.items()}  # structure's fill
    for masks in (coloured, grey):
        assert masks["origin"].sum() > 300
        assert (masks["origin"] != masks["utm"]).sum() <= 0.02 * masks["origin"].sum()


def test_structures_are_named_in_pictures(tmp_path):
    """The contact-force curves name each structure; a picture with two grey shapes must say which
    is which (found by a walkthrough): the name stands above the structure's top."""
    from app.render import structure_labels

    dam = [[0.6, 0.0], [0.7, 0.0], [0.65, 0.12]]
    points, names = structure_labels([{"name": "dam", "polygon_m": dam}, {"name": "bad", "polygon_m": []}],
                                     (0.5, 0.0), 0.01)
    assert names == ["dam"] and np.allclose(points, [[0.15, 0.13, 0.05]])
    pictures = {}
    for label in ("dam", ""):
        meta = {**SYNTHETIC_META, "structures": [{"name": label, "polygon_m": dam}]}
        writer = ResultsWriter(tmp_path / f"{label or 'none'}.results", "", dict(meta))
        for frame in synthetic_frames(2):
            writer.write_frame(frame)
        writer.close("completed")
        pictures[label] = imageio.imread(render_frame(tmp_path / f"{label or 'none'}.results", -1, "displacement",
                                                      tmp_path / f"{label or 'none'}.png", size=SMALL))[..., :3]
    dark = {k: (img.astype(int).max(axis=-1) < 110) for k, img in pictures.items()}
    assert dark["dam"].sum() > dark[""].sum() + 20  # the letters
