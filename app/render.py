"""Offscreen pictures and movies of results folders (no display, no Qt).

Particles are drawn as square points in the xy plane, coloured by one of :data:`FIELDS`, with a
colour bar in engineering units, the simulated time, axes in metres, the grid box outline and
the structures. The point size follows the particles' spacing, and their spread where a moving
mass has drawn them apart (:func:`app.display.display_spacing`), so a body looks continuous at
any image size; stresses may be shown averaged over the cells around each particle (``smooth``,
:func:`app.display.smooth_values`).

VTK tries an X server first and logs "bad X server connection" when there is none; on Linux
without ``DISPLAY`` this module asks VTK for its EGL (headless) window instead.
"""

from __future__ import annotations

import logging
import math
import os
import sys
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from app.display import SMOOTHED_SOURCES, smooth_values
from projects.results import Results, ResultsError

if TYPE_CHECKING:  # pragma: no cover - typing only
    import pyvista

logger = logging.getLogger(__name__)

_KPA = 1.0e-3  # stresses are shown in kPa
#: Line colours of the contacts (matplotlib's tab10 without the material blue and orange first).
CONTACT_COLORS: tuple[str, ...] = ("#d62728", "#2ca02c", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f",
                                   "#bcbd22", "#17becf", "#1f77b4", "#ff7f0e")


@dataclass(frozen=True)
class FieldInfo:
    """One colourable quantity.

    Attributes
    ----------
    name : str
        Key used on the command line and in the GUI.
    label : str
        Human name for colour bars.
    unit : str
        Unit of the shown values ("-" for dimensionless).
    source : str
        Frame array it is computed from.
    categorical : bool
        Discrete values (material) with a legend rather than a continuous bar.
    cmap : str
        Default matplotlib colour map.
    """

    name: str
    label: str
    unit: str
    source: str
    categorical: bool = False
    cmap: str = "viridis"

    @property
    def title(self) -> str:
        """Colour bar title, for example ``"Displacement (m)"``."""
        return self.label if self.categorical else f"{self.label} ({self.unit})"


#: The fields that can be shown, in menu order; shared with the GUI.
FIELDS: dict[str, FieldInfo] = {
    f.name: f
    for f in (
        FieldInfo("displacement", "Displacement", "m", "displacement"),
        FieldInfo("displacement_x", "Horizontal displacement", "m", "displacement", cmap="coolwarm"),
        FieldInfo("displacement_y", "Vertical displacement", "m", "displacement", cmap="coolwarm"),
        FieldInfo("velocity", "Speed", "m/s", "velocity", cmap="plasma"),
        FieldInfo("stress_xx", "Stress xx", "kPa", "stress", cmap="turbo"),
        FieldInfo("stress_yy", "Stress yy", "kPa", "stress", cmap="turbo"),
        FieldInfo("stress_xy", "Shear stress xy", "kPa", "stress", cmap="coolwarm"),
        FieldInfo("stress_zz", "Stress zz", "kPa", "stress", cmap="turbo"),
        FieldInfo("mean_stress", "Mean effective stress", "kPa", "stress", cmap="turbo"),
        FieldInfo("pore_pressure", "Pore pressure", "kPa", "pore_pressure", cmap="cividis"),
        FieldInfo("total_stress_yy", "Total stress yy", "kPa", "stress", cmap="turbo"),
        FieldInfo("mean_total_stress", "Mean total stress", "kPa", "stress", cmap="turbo"),
        FieldInfo("plastic_strain", "Plastic strain", "-", "plastic_strain", cmap="magma_r"),
        FieldInfo("material", "Material", "", "material_id", categorical=True, cmap="tab10"),
    )
}

_STRESS_INDEX = {"stress_xx": 0, "stress_yy": 1, "stress_xy": 2, "stress_zz": 3}


def field_info(field: str) -> FieldInfo:
    """The :class:`FieldInfo` of ``field``; ValueError listing the allowed names otherwise."""
    try:
        return FIELDS[field]
    except KeyError:
        raise ValueError(f"unknown field {field!r}; allowed: {', '.join(FIELDS)}") from None


def field_values(arrays: Mapping[str, np.ndarray], field: str) -> np.ndarray:
    """Per-particle values of ``field`` in the units of :data:`FIELDS`.

    Parameters
    ----------
    arrays : mapping
        One frame as returned by :meth:`projects.results.Results.frame`.
    field : str
        A key of :data:`FIELDS`.

    Returns
    -------
    numpy.ndarray
        (N,) float64 (int for ``material``), for every particle (active or not).
    """
    info = field_info(field)
    if info.source not in arrays:
        raise ValueError(
            f"field {field!r} needs the {info.source!r} output, which this run did not write "
            f"(see [output] fields); available: {', '.join(sorted(arrays))}"
        )
    data = np.asarray(arrays[info.source])
    if field in ("displacement", "velocity"):
        return np.linalg.norm(data[:, :2].astype(np.float64), axis=1)
    if field == "displacement_x":
        return data[:, 0].astype(np.float64)
    if field == "displacement_y":
        return data[:, 1].astype(np.float64)
    if field in _STRESS_INDEX:
        return data[:, _STRESS_INDEX[field]].astype(np.float64) * _KPA
    if field == "mean_stress":
        s = data.astype(np.float64)
        return (s[:, 0] + s[:, 1] + s[:, 3]) / 3.0 * _KPA
    if field in ("total_stress_yy", "mean_total_stress"):
        # the stress frames carry is the effective stress; total = effective - u I (dry: u = 0)
        s = data.astype(np.float64)
        u = np.asarray(arrays.get("pore_pressure", np.zeros(len(s))), dtype=np.float64)
        if field == "total_stress_yy":
            return (s[:, 1] - u) * _KPA
        return ((s[:, 0] + s[:, 1] + s[:, 3]) / 3.0 - u) * _KPA
    if field == "pore_pressure":
        return data.astype(np.float64) * _KPA
    if field == "material":
        return data.astype(np.int64)
    return data.astype(np.float64)


# ------------------------------------------------------------------ ground water in pictures
#: The phreatic line's colour, the free-water line's and the free water's shade (the workbench's too).
WATER_LINE_COLOR = "#1565c0"
FREE_WATER_LINE_COLOR = "#0b8fd6"
FREE_WATER_COLOR = "#a9d8f7"


def shown_values(arrays: Mapping[str, np.ndarray], field: str, smooth_cell_m: float | None = None,
                 origin_m: Sequence[float] = (0.0, 0.0)) -> np.ndarray:
    """:func:`field_values`, smoothed (:func:`smooth_values` over cells of ``smooth_cell_m``,
    active particles only) where asked and the field is a stress or the pore pressure."""
    values = field_values(arrays, field)
    info = field_info(field)
    if not smooth_cell_m or info.source not in SMOOTHED_SOURCES:
        return values
    active = np.asarray(arrays["active"], dtype=bool)
    out = np.asarray(values, dtype=np.float64).copy()
    out[active] = smooth_values(np.asarray(arrays["positions"])[active], out[active], smooth_cell_m, origin_m)
    return out


def water_line_across(line: Any, x0: float, x1: float) -> np.ndarray:
    """A water line's points from ``x0`` to ``x1`` (m): its vertices between them and its height at
    both ends (a line is level beyond its ends, as the solver extends it: solver.water.line_height)."""
    from solver.water import line_height

    pts = np.asarray(line, dtype=np.float64).reshape(-1, 2)
    if not len(pts):
        return np.zeros((0, 2))
    inside = pts[(pts[:, 0] > x0) & (pts[:, 0] < x1)]
    ends = np.array([x0, x1], dtype=np.float64)
    return np.vstack([[x0, float(line_height(pts, ends[:1])[0])], inside, [x1, float(line_height(pts, ends[1:])[0])]])


def free_water_polygons(line: Any, bodies: Sequence[Any], box: tuple[float, float, float, float]
                        ) -> list[np.ndarray]:
    """The free water: where the free-water line is above the ground surface (the upper outline of
    ``bodies``, each a (K, 2) polygon), between the two, inside the domain ``box`` (x0, x1, y0, y1).

    Returns the exterior rings (each (K, 2), m) of the shaded area; none when the line is nowhere
    above the ground.
    """
    from shapely.geometry import Polygon
    from shapely.ops import unary_union

    x0, x1, y0, y1 = box
    if not x1 > x0:
        return []
    top = water_line_across(line, x0, x1)
    if not len(top):
        return []
    bottom = min(y0, float(top[:, 1].min())) - 1.0
    region = Polygon([(x0, bottom), *map(tuple, top), (x1, bottom)])
    shadows = []  # below each edge of each body, down past the region's bottom: under the ground surface
    for poly in bodies:
        pts = np.asarray(poly, dtype=np.float64).reshape(-1, 2)
        if len(pts) < 3:
            continue
        ring = np.vstack([pts, pts[:1]])
        for (ax, ay), (bx, by) in zip(ring[:-1], ring[1:]):
            if abs(bx - ax) > 1e-12:
                shadows.append(Polygon([(ax, ay), (bx, by), (bx, bottom - 1.0), (ax, bottom - 1.0)]))
    if not region.is_valid:
        region = region.buffer(0)
    water = region.difference(unary_union(shadows)) if shadows else region
    water = water.intersection(Polygon([(x0, y0), (x1, y0), (x1, y1), (x0, y1)]))
    parts = getattr(water, "geoms", [water])
    out = []
    for part in parts:
        if getattr(part, "geom_type", "") == "Polygon" and part.area > 1e-9 * (x1 - x0) * max(y1 - y0, 1e-9):
            out.append(np.asarray(part.exterior.coords, dtype=np.float64)[:-1])
    return out


@dataclass(frozen=True)
class WaterShown:
    """The water a picture draws: the phreatic line, the free-water line (None: the phreatic line is
    the free water's level too) and the free water's outlines, m."""

    phreatic_line_m: np.ndarray
    free_water_line_m: np.ndarray | None
    free_water: tuple[np.ndarray, ...]


def water_shown(water: Any, bodies: Sequence[Any], box: tuple[float, float, float, float]) -> WaterShown | None:
    """What to draw of ``water`` (a solver.config.Water, a schema Water or None) across the domain ``box``."""
    if water is None:
        return None
    phreatic = getattr(water, "phreatic_line_m", None)
    if phreatic is None:
        return None
    free = getattr(water, "free_water_line_m", None)
    x0, x1 = box[0], box[1]
    if free is not None and _same_line(free, phreatic):
        free = None  # a blend of two stages' water writes the free level out even where it is the line
    level = free if free is not None else phreatic
    return WaterShown(water_line_across(phreatic, x0, x1),
                      None if free is None else water_line_across(free, x0, x1),
                      tuple(free_water_polygons(level, bodies, box)))


def _same_line(a: Any, b: Any) -> bool:
    from solver.water import line_height

    pa, pb = np.asarray(a, dtype=np.float64).reshape(-1, 2), np.asarray(b, dtype=np.float64).reshape(-1, 2)
    xs = np.union1d(pa[:, 0], pb[:, 0])
    return bool(np.allclose(line_height(pa, xs), line_height(pb, xs), rtol=0.0, atol=1e-9))


class WaterTimeline:
    """Where the ground water of a run was at each of its frames.

    The project that ran (``project.toml`` of the results folder) gives the water at the start and
    at the end of each stage (:func:`projects.build.solver_water`); a stage moves it linearly over
    its duration (a k0 stage at once), so at a frame of stage ``i`` at stage time ``t`` the water is
    :func:`solver.water.blend_water` of the stage's start and end at ``t / duration``.
    """

    def __init__(self, project: Any) -> None:
        from projects.build import solver_water

        self.project = project
        self.stages = list(project.stages) if project is not None else []
        self.waters = solver_water(project) if project is not None else [None]

    @classmethod
    def of(cls, results: Results) -> WaterTimeline | None:
        """The timeline of a results folder; None when the run had no [water] (or no project.toml)."""
        text = getattr(results, "project_text", "")
        if not text:
            return None
        from projects.document import loads_project
        from projects.schema import ProjectError

        try:
            project = loads_project(text, source=str(results.path / "project.toml"))
        except (ProjectError, ValueError) as err:
            logger.warning("%s: the project that ran is not readable (%s); no water drawn", results.path, err)
            return None
        if project.water is None:
            return None
        return cls(project)

    @property
    def moves(self) -> bool:
        """Whether any stage moves the water."""
        return any(a != b for a, b in zip(self.waters[:-1], self.waters[1:]))

    def at(self, stage_index: int | None, stage_time_s: float | None) -> Any:
        """The water (solver.config.Water) at ``stage_time_s`` into stage ``stage_index`` (None:
        the start of the run)."""
        from solver.water import blend_water

        if stage_index is None or not 0 <= int(stage_index) < len(self.stages):
            return self.waters[0]
        i = int(stage_index)
        stage = self.stages[i]
        duration = float(getattr(stage, "duration_s", None) or 0.0) if stage.type != "k0" else 0.0
        t = float(stage_time_s) if stage_time_s is not None and math.isfinite(float(stage_time_s)) else duration
        fraction = 1.0 if duration <= 0.0 else min(max(t / duration, 0.0), 1.0)
        return blend_water(self.waters[i], self.waters[i + 1], fraction)

    def at_frame(self, results: Results, index: int) -> Any:
        """The water at frame ``index`` of ``results`` (its row of ``series.csv``)."""
        stage, time = frame_stage(results, index)
        return self.at(stage, time)


def frame_stage(results: Results, index: int) -> tuple[int | None, float | None]:
    """(stage index, stage time in s) of frame ``index`` from ``series.csv`` (None, None if unknown)."""
    series = results.series or {}
    frames, stages, times = series.get("frame"), series.get("stage_index"), series.get("stage_time_s")
    if stages is None or times is None or not len(stages):
        return None, None
    row = None
    if frames is not None:
        hits = np.flatnonzero(np.asarray(frames) == index)
        row = int(hits[-1]) if len(hits) else None
    if row is None and index < len(stages):
        row = index
    if row is None:
        return None, None
    return int(stages[row]), float(times[row])


def particle_ground(positions: np.ndarray, spacing_m: float, box: tuple[float, float, float, float]
                    ) -> list[np.ndarray]:
    """The ground a frame's particles make, as columns one particle spacing wide (from the domain's
    floor to half a spacing above the highest particle in each): what the free water of a frame
    stands on once the slope has moved (the bodies are where it started)."""
    pts = np.asarray(positions, dtype=np.float64).reshape(-1, 2)
    x0, x1, y0, _y1 = box
    if not len(pts) or not spacing_m > 0 or not x1 > x0:
        return []
    width = max(float(spacing_m), (x1 - x0) / 4000.0)
    bins = np.clip(((pts[:, 0] - x0) // width).astype(np.int64), 0, math.ceil((x1 - x0) / width) - 1)
    top = np.full(int(bins.max()) + 1, -np.inf)
    np.maximum.at(top, bins, pts[:, 1] + 0.5 * float(spacing_m))
    out = []
    for k in np.flatnonzero(np.isfinite(top)):
        a, b = x0 + k * width, min(x0 + (k + 1) * width, x1)
        out.append(np.array([[a, y0], [b, y0], [b, top[k]], [a, top[k]]]))
    return out


def _quiet_vtk() -> None:
    """Pick VTK's headless window on Linux without a display (avoids the X server warning)."""
    if sys.platform.startswith("linux") and not (
        os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
    ):
        os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")


def _as_results(results: Results | str | os.PathLike[str]) -> Results:
    return results if isinstance(results, Results) else Results(results)


def _nice_step(span: float, ticks: int = 5) -> float:
    """A 1, 2, 2.5 or 5 times a power of ten step giving about ``ticks`` intervals."""
    raw = span / ticks
    power = 10.0 ** math.floor(math.log10(raw))
    for mult in (1.0, 2.0, 2.5, 5.0, 10.0):
        if mult * power >= raw * (1 - 1e-9):
            return mult * power
    return 10.0 * power


def _nice_axis(lo: float, hi: float) -> tuple[float, float, int, float]:
    """Extend ``[lo, hi]`` to whole tick steps; return (lo, hi, number of labels, step).

    Of the nice steps giving 3 to 7 intervals, the one that extends the range least (a 32 m
    domain: 0-35 in steps of 5, not 0-40 in steps of 10); ties go to the coarser step."""
    base = _nice_step(hi - lo)
    power = 10.0 ** math.floor(math.log10(base))
    steps = [m * power * 10.0 ** k for k in (-1, 0, 1) for m in (1.0, 2.0, 2.5, 5.0)]
    best = None
    for step in (st for st in steps if base / 3.0 <= st <= base * 3.0):
        lo2 = math.floor(lo / step + 1e-9) * step
        hi2 = math.ceil(hi / step - 1e-9) * step
        intervals = int(round((hi2 - lo2) / step))
        if not 3 <= intervals <= 7 and step != base:
            continue
        if best is None or hi2 - lo2 < best[1] - best[0] - 1e-9 * (hi - lo) or (
                abs((hi2 - lo2) - (best[1] - best[0])) <= 1e-9 * (hi - lo) and step > best[3]):
            best = (lo2, hi2, intervals + 1, step)
    return best


def _label_format(*steps: float) -> str:
    """printf format with just enough decimals for labels ``steps`` apart (one format for both
    axes: the decimals of the step that needs most, so 0.25 is not printed as 0.2)."""
    decimals = 0
    for step in steps:
        while decimals < 6 and abs(round(step, decimals) - step) > 1e-9 * step:
            decimals += 1
    return f"%.{decimals}f"


def bar_format(lo: float, hi: float, labels: int = 5) -> str:
    """printf format of the colour bar's ``labels`` evenly spaced labels from ``lo`` to ``hi``:
    3 significant digits, more while two labels would read the same (a narrow range)."""
    values = np.linspace(lo, hi, labels)
    for digits in range(3, 10):
        fmt = f"%.{digits}g"
        if len({fmt % v for v in values}) == labels:
            return fmt
    return "%.10g"


def value_range(values: np.ndarray) -> tuple[float, float]:
    """Colour range of the finite values, widened a little when they are all equal."""
    finite = values[np.isfinite(values)]
    if finite.size == 0:
        return 0.0, 1.0
    lo, hi = float(finite.min()), float(finite.max())
    if hi - lo <= 1e-12 * max(1.0, abs(hi)):
        pad = max(abs(hi) * 1e-3, 1e-9)
        lo, hi = lo - pad, hi + pad
    return lo, hi


@dataclass(frozen=True)
class _View:
    """Camera placement: world box to show (whole axis ticks), labels and pixels per metre."""

    bounds: tuple[float, float, float, float]  # xmin, xmax, ymin, ymax (m)
    labels: tuple[int, int]  # number of tick labels along x and y
    label_format: str
    pixels_per_m: float


# Fractions of the image kept for the data; the rest holds the axes labels and colour bar.
_DATA_W, _DATA_H, _DATA_CX = 0.74, 0.74, 0.46


def _domain_box(results: Results) -> tuple[float, float, float, float] | None:
    domain = results.summary.get("domain") or {}
    try:
        (x0, y0), (w, h) = domain["origin_m"], domain["size_m"]
    except (KeyError, TypeError, ValueError):
        return None
    return float(x0), float(x0) + float(w), float(y0), float(y0) + float(h)


def _structures(results: Results, shift: np.ndarray | None = None) -> list[pyvista.PolyData]:
    """The run's rigid structures (``summary.json`` ``structures``) as filled polygons at z = 0,
    less ``shift`` (x, y)."""
    import pyvista as pv

    out = []
    for structure in results.summary.get("structures") or []:
        pts = np.asarray(structure.get("polygon_m") or [], dtype=float).reshape(-1, 2)
        if len(pts) < 3:
            continue
        points = np.c_[pts - (0.0 if shift is None else shift), np.zeros(len(pts))]
        out.append(pv.PolyData(points, faces=np.r_[len(pts), np.arange(len(pts))]))
    return out


def structure_labels(structures, shift=(0.0, 0.0), lift_m: float = 0.0) -> tuple[np.ndarray, list[str]]:
    """Where each structure's name goes (centred above its highest vertex, ``lift_m`` higher, at
    z = 0.05 over the particles; less ``shift``) and the names, so that a picture's structures can
    be matched with the contact-force curves they name."""
    points, names = [], []
    for structure in structures or []:
        pts = np.asarray(structure.get("polygon_m") or [], dtype=float).reshape(-1, 2)
        if len(pts) < 3:
            continue
        top = pts[np.argmax(pts[:, 1])]
        points.append([float(pts[:, 0].mean()) - shift[0], float(top[1]) + lift_m - shift[1], 0.05])
        names.append(str(structure.get("name", "?")))
    return np.asarray(points, dtype=float).reshape(-1, 3), names


def _structure_box(results: Results) -> tuple[float, float, float, float] | None:
    pts = [p for st in results.summary.get("structures") or [] for p in st.get("polygon_m") or []]
    if not pts:
        return None
    a = np.asarray(pts, dtype=float).reshape(-1, 2)
    return (float(a[:, 0].min()), float(a[:, 0].max()), float(a[:, 1].min()), float(a[:, 1].max()))


def _particle_box(positions: np.ndarray) -> tuple[float, float, float, float] | None:
    if len(positions) == 0:
        return None
    lo, hi = positions.min(axis=0), positions.max(axis=0)
    return float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1])


def _union(*boxes: tuple[float, float, float, float] | None) -> tuple[float, float, float, float]:
    real = [b for b in boxes if b is not None]
    if not real:
        return 0.0, 1.0, 0.0, 1.0
    x0, x1, y0, y1 = (min(b[0] for b in real), max(b[1] for b in real),
                      min(b[2] for b in real), max(b[3] for b in real))
    # a degenerate box (one particle, a line) still needs a visible extent
    span = max(x1 - x0, y1 - y0, 1e-3)
    if x1 - x0 < 1e-9 * span:
        x0, x1 = x0 - span / 2, x1 + span / 2
    if y1 - y0 < 1e-9 * span:
        y0, y1 = y0 - span / 2, y1 + span / 2
    return x0, x1, y0, y1


def _view(bounds: tuple[float, float, float, float], size: tuple[int, int]) -> _View:
    x0, x1, nx, xstep = _nice_axis(bounds[0], bounds[1])
    y0, y1, ny, ystep = _nice_axis(bounds[2], bounds[3])
    ppm = min(_DATA_W * size[0] / (x1 - x0), _DATA_H * size[1] / (y1 - y0))
    return _View((x0, x1, y0, y1), (nx, ny), _label_format(xstep, ystep), ppm)


def structure_patches(ax, structures: Sequence[Mapping[str, Any]] | None) -> None:
    """The run's rigid structures (``summary.json`` ``structures``) on a section plot: grey,
    hatched and named as in the scene views, so that a wall or a dam is not read as deposit in the
    surface line that runs over it. One legend entry for them all."""
    from matplotlib.patches import Polygon as PolygonPatch

    first = True
    for structure in structures or []:
        pts = np.asarray(structure.get("polygon_m") or [], dtype=float).reshape(-1, 2)
        if len(pts) < 3:
            continue
        ax.add_patch(PolygonPatch(pts, closed=True, facecolor="#b4b4b4", edgecolor="0.3", hatch="///", lw=0.8,
                                  zorder=3, label="structure" if first else None))
        first = False
    for (x, y, _z), name in zip(*structure_labels(structures)):
        ax.annotate(name, (x, y), xytext=(0, 3), textcoords="offset points", ha="center", va="bottom", fontsize=7,
                    color="0.25", zorder=4)


def _cell_size(results: Results) -> float | None:
    """The grid's cell size from ``summary.json`` (None where it is not recorded)."""
    size = (results.summary.get("domain") or {}).get("cell_size_m")
    return float(size) if isinstance(size, (int, float)) and size > 0 else None


def _particle_spacing(results: Results, arrays: Mapping[str, np.ndarray]) -> float:
    spacing = results.summary.get("particle_spacing_m")
    if isinstance(spacing, (int, float)) and spacing > 0:
        return float(spacing)
    # no spacing recorded: assume the particles tile their bounding box
    pos = arrays["positions"][arrays["active"]]
    box = _particle_box(pos)
    if box is None or len(pos) < 2:
        return 1.0
    area = max((box[1] - box[0]) * (box[3] - box[2]), 1e-12)
    return math.sqrt(area / len(pos))


class _Scene:
    """An offscreen plotter showing one field; :meth:`show` swaps in another frame."""

    def __init__(
        self,
        results: Results,
        field: str,
        size: tuple[int, int],
        view: _View,
        spacing_m: float,
        cmap: str | None,
        clim: tuple[float, float] | None,
    ) -> None:
        _quiet_vtk()
        import pyvista as pv

        self.results = results
        self.info = field_info(field)
        #: stresses and pore pressure averaged over cells of this size (app.display.smooth_values;
        #: None: as the particles carry them); render_frame and animate set it with ``smooth``
        self.smooth_cell_m: float | None = None
        self._point_px = max(1.0, math.ceil(spacing_m * view.pixels_per_m))
        self.size = (int(size[0]), int(size[1]))
        self.clim = clim
        self.plotter = pv.Plotter(off_screen=True, window_size=list(self.size))
        self.plotter.set_background("white")
        self.cloud = pv.PolyData()
        self._actor = None
        self._spacing_m = spacing_m
        self._view = view
        self._cmap = cmap or self.info.cmap
        self._font = max(8, round(self.size[1] / 56))
        self._text = None
        # Everything is drawn relative to the view's lower-left corner, the axes labelled with the
        # real coordinates: VTK draws in float32, which resolves 0.25 m at y = 4e6 m (UTM), so a
        # scene in real-world coordinates collapsed onto a few rows of squares.
        self._shift = np.array([view.bounds[0], view.bounds[2]], dtype=np.float64)
        self._water = WaterTimeline.of(results)
        self._water_drawn: Any = False  # the water last drawn (False: none yet)

    def close(self) -> None:
        self.plotter.close()

    def _cloud(self, arrays: Mapping[str, np.ndarray]) -> pyvista.PolyData:
        import pyvista as pv

        shown = drawable(arrays)
        pos = np.asarray(arrays["positions"], dtype=np.float64)[shown]
        points = np.zeros((len(pos), 3), np.float32)
        points[:, :2] = pos - self._shift
        cloud = pv.PolyData(points)
        from app.display import display_spacing

        origin = (_domain_box(self.results) or (0.0, 0.0, 0.0, 0.0))[::2]
        cloud.point_data["values"] = shown_values(arrays, self.info.name, self.smooth_cell_m, origin)[shown]
        # squares as large as the particles' spread in this frame: a flowing mass whose columns
        # have parted drawn at its initial spacing showed as separated columns of points
        self._point_px = max(1.0, math.ceil(display_spacing(pos, self._spacing_m) * self._view.pixels_per_m))
        return cloud

    def _add_static(self) -> None:
        import pyvista as pv

        pl = self.plotter
        x0, x1, y0, y1 = self._view.bounds
        sx, sy = self._shift
        domain = _domain_box(self.results)
        if domain is not None:
            dx0, dx1, dy0, dy1 = domain[0] - sx, domain[1] - sx, domain[2] - sy, domain[3] - sy
            outline = [[dx0, dy0, 0], [dx1, dy0, 0], [dx1, dy1, 0], [dx0, dy1, 0], [dx0, dy0, 0]]
            pl.add_mesh(pv.MultipleLines(outline), color="#8c8c8c", line_width=1)
        # each outline a band of polygons (outline_band), not a wide line: an offscreen (EGL) window
        # of a process that has drawn the workbench's Qt window draws wide lines one pixel wide
        width_m = max(2.0, self.size[1] / 400.0) / self._view.pixels_per_m
        for structure in _structures(self.results, self._shift):
            pl.add_mesh(structure.triangulate(), color="#b4b4b4", show_edges=False, lighting=False)
            band = outline_band(np.asarray(structure.points)[:, :2], width_m, z=0.01)
            if band is not None:
                pl.add_mesh(band, color="#505050", lighting=False)
        points, names = structure_labels(self.results.summary.get("structures"), self._shift, 0.01 * (y1 - y0))
        if names:
            pl.add_point_labels(points, names, name="structure-labels", font_size=self._font, text_color="#303030",
                                shape=None, show_points=False, always_visible=True, reset_camera=False,
                                justification_horizontal="center", justification_vertical="bottom")
        pl.show_bounds(
            bounds=[x0 - sx, x1 - sx, y0 - sy, y1 - sy, 0.0, 0.0],
            axes_ranges=[x0, x1, y0, y1, 0.0, 0.0],  # the labels in the project's coordinates
            xtitle="x (m)",
            ytitle="y (m)",
            ztitle="",
            show_zaxis=False,
            show_zlabels=False,
            color="black",
            location="outer",
            use_2d=True,
            grid=False,
            fmt=self._view.label_format,
            n_xlabels=self._view.labels[0],
            n_ylabels=self._view.labels[1],
            font_size=self._font,
        )
        title = str(self.results.summary.get("title") or "")
        if title:
            pl.add_text(title, position="upper_edge", color="#333333", font_size=self._font)

    def _place_camera(self) -> None:
        x0, x1, y0, y1 = self._view.bounds
        x0, x1, y0, y1 = x0 - self._shift[0], x1 - self._shift[0], y0 - self._shift[1], y1 - self._shift[1]
        ppm = self._view.pixels_per_m
        w, h = self.size
        cam = self.plotter.camera
        self.plotter.enable_parallel_projection()
        # shift the focal point so the data sits left of centre, clear of the colour bar
        fx = 0.5 * (x0 + x1) + (0.5 - _DATA_CX) * w / ppm
        fy = 0.5 * (y0 + y1)
        cam.focal_point = (fx, fy, 0.0)
        cam.position = (fx, fy, 10.0 * max(x1 - x0, y1 - y0))
        cam.up = (0.0, 1.0, 0.0)
        cam.parallel_scale = h / (2.0 * ppm)
        self.plotter.renderer.ResetCameraClippingRange()

    def show(self, index: int) -> None:
        """Draw frame ``index`` (only its active particles)."""
        arrays = self.results.frame(index)
        cloud = self._cloud(arrays)
        if self._actor is None:
            self.cloud = cloud
            self._add_points()
            self._add_static()
            self._place_camera()
        else:
            self.cloud.copy_from(cloud)
            self._actor.prop.point_size = self._point_px
        self._draw_water(index)
        time_s = float(self.results.times[index])
        label = f"t = {time_s:.3f} s"
        if self._text is None:
            self._text = self.plotter.add_text(
                label, position=(int(0.012 * self.size[0]), int(self.size[1] - 2.2 * self._font * 1.6)),
                color="black", font_size=self._font,
            )
        else:
            self._text.SetInput(label)

    def _draw_water(self, index: int) -> None:
        """The phreatic line (blue), the free-water line where it differs and the free water
        (light blue, between its line and the ground surface) at frame ``index``'s time."""
        if self._water is None:
            return
        water = self._water.at_frame(self.results, index)
        self._water_drawn = water
        box = _domain_box(self.results) or self._view.bounds
        for name in ("water-fill", "water-line", "free-water-line"):
            self.plotter.remove_actor(name, render=False)
        arrays = self.results.frame(index, {"positions", "active"})
        ground = particle_ground(np.asarray(arrays["positions"])[drawable(arrays)],
                                 self._spacing_m, box)
        shown = water_shown(water, ground, box)
        if shown is None:
            return
        # the lines as filled bands of a fixed width in pixels (see add_water_actors), lifted in
        # proportion to the view so that depth resolution never merges them with the particles
        x0, x1, y0, y1 = self._view.bounds
        lift = max(0.02, 1e-3 * max(x1 - x0, y1 - y0))
        add_water_actors(self.plotter, shown, self._shift, z=(-lift, lift),
                         band_m=max(3.0, self.size[1] / 150.0) / self._view.pixels_per_m)

    def _add_points(self) -> None:
        info = self.info
        point_px = self._point_px
        common: dict[str, Any] = dict(
            scalars="values",
            style="points",
            point_size=point_px,
            render_points_as_spheres=False,
            lighting=False,
        )
        bar: dict[str, Any] = dict(
            title=info.title,
            color="black",
            vertical=True,
            position_x=0.86,
            position_y=0.18,
            height=0.64,
            width=0.035,
            title_font_size=self._font,
            label_font_size=self._font,
            unconstrained_font_size=True,
        )
        if info.categorical:
            names = self.results.material_names
            ids = np.asarray(self.cloud.point_data["values"])
            count = max(len(names), int(ids.max(initial=0)) + 1, 1)
            annotations = {i: (names[i] if i < len(names) else f"material {i}") for i in range(count)}
            bar.update(n_labels=0)
            self._actor = self.plotter.add_mesh(
                self.cloud,
                cmap=self._cmap,
                clim=(-0.5, count - 0.5),
                n_colors=count,
                categories=True,
                annotations=annotations,
                scalar_bar_args=bar,
                **common,
            )
        else:
            clim = self.clim or value_range(np.asarray(self.cloud.point_data["values"]))
            bar.update(fmt=bar_format(*clim, labels=5), n_labels=5)
            self._actor = self.plotter.add_mesh(
                self.cloud, cmap=self._cmap, clim=clim, scalar_bar_args=bar, **common
            )
        # keep the bar's title clear of its top label
        scalar_bar = self.plotter.scalar_bars[info.title]
        scalar_bar.SetVerticalTitleSeparation(int(self._font))

    def screenshot(self) -> np.ndarray:
        """(H, W, 3) uint8 image of what is shown."""
        # pyvista renders by itself only for the first screenshot of an offscreen plotter
        self.plotter.render()
        return self.plotter.screenshot(return_img=True)


def line_band(line: Any, width: float) -> np.ndarray:
    """The outline (K, 2) of polyline ``line`` (N, 2) thickened to ``width`` (flat ends, mitred
    corners): a filled band to draw in place of a wide line."""
    from shapely.geometry import LineString

    pts = np.asarray(line, dtype=np.float64).reshape(-1, 2)
    band = LineString(pts).buffer(0.5 * float(width), cap_style="flat", join_style="mitre", mitre_limit=3.0)
    parts = [g for g in getattr(band, "geoms", [band]) if not g.is_empty]
    if not parts:
        return np.zeros((0, 2))
    return np.asarray(max(parts, key=lambda g: g.area).exterior.coords, dtype=np.float64)[:-1]


def outline_band(ring: Any, width: float, z: float = 0.0) -> pyvista.PolyData | None:
    """The outline of the closed polygon ``ring`` (N, 2) as filled polygons ``width`` wide (one
    band per edge, :func:`line_band`, each reaching half the width past its corners so that the
    corners are closed), at height ``z``; None for fewer than two points."""
    import pyvista as pv

    pts = np.asarray(ring, dtype=np.float64).reshape(-1, 2)
    if len(pts) < 2:
        return None
    points: list[np.ndarray] = []
    faces: list[int] = []
    for a, b in zip(pts, np.roll(pts, -1, axis=0)):
        length = float(np.hypot(*(b - a)))
        if length <= 0.0:
            continue
        step = 0.5 * width * (b - a) / length
        quad = line_band([a - step, b + step], width)
        if len(quad) < 3:
            continue
        faces += [len(quad), *range(sum(len(p) for p in points), sum(len(p) for p in points) + len(quad))]
        points.append(quad)
    if not points:
        return None
    xy = np.vstack(points)
    return pv.PolyData(np.c_[xy, np.full(len(xy), z)], faces=np.asarray(faces)).triangulate()


def add_water_actors(plotter: Any, shown: WaterShown, shift: Any = (0.0, 0.0), line_width: float = 3.0,
                     z: tuple[float, float] = (-0.02, 0.02), prefix: str = "", band_m: float | None = None) -> None:
    """Add the water of ``shown`` to a pyvista plotter (drawn less ``shift``): the free water filled
    at ``z[0]`` (behind the particles), the lines at ``z[1]`` (over them). Actors are named
    ``PREFIXwater-fill``, ``PREFIXwater-line`` and ``PREFIXfree-water-line``.

    ``band_m``: the phreatic line's width in metres, drawn as a filled band (the free-water line
    0.7 as wide): what pictures use, since a band is polygons, whose look does not depend on the
    OpenGL context. An offscreen (EGL) window of a process that has created the workbench's Qt
    window reports wide lines but draws them one pixel wide. ``None``: lines ``line_width``
    pixels wide (the interactive views, whose zoom changes the scale)."""
    import pyvista as pv

    shift = np.asarray(shift, dtype=np.float64)

    def polygon(ring: np.ndarray, height: float) -> pyvista.PolyData:
        pts = np.c_[ring - shift, np.full(len(ring), height)]
        face = pv.PolyData(pts, faces=np.r_[len(pts), np.arange(len(pts))])
        try:
            face = face.triangulate()
        except (RuntimeError, ValueError):
            logger.debug("could not triangulate a water polygon")
        return face

    faces = [polygon(ring, z[0]) for ring in shown.free_water]
    common = dict(render=False, reset_camera=False, pickable=False, lighting=False)
    if faces:
        merged = faces[0].merge(faces[1:]) if len(faces) > 1 else faces[0]
        plotter.add_mesh(merged, color=FREE_WATER_COLOR, opacity=0.75, name=f"{prefix}water-fill", **common)
    for key, line, color, scale in (("water-line", shown.phreatic_line_m, WATER_LINE_COLOR, 1.0),
                                    ("free-water-line", shown.free_water_line_m, FREE_WATER_LINE_COLOR, 0.7)):
        if line is None or len(line) < 2:
            continue
        lift = z[1] if key == "water-line" else 0.5 * z[1]  # the phreatic line over the free-water line
        if band_m is not None:
            ring = line_band(line, scale * band_m)
            if len(ring) >= 3:
                plotter.add_mesh(polygon(ring, lift), color=color, name=f"{prefix}{key}", **common)
                continue
        plotter.add_mesh(pv.MultipleLines(np.c_[line - shift, np.full(len(line), lift)]), color=color,
                         line_width=scale * line_width, name=f"{prefix}{key}", **common)
    # the camera's near and far planes were set for the particles at z = 0 (reset_camera=False):
    # widen them to these actors
    renderer = getattr(plotter, "renderer", None)
    if renderer is not None:
        renderer.ResetCameraClippingRange()


def _scene_for(
    results: Results,
    field: str,
    frames: list[int],
    size: tuple[int, int],
    cmap: str | None,
    clim: tuple[float, float] | None,
    on_warning: Callable[[str], None] | None = None,
) -> _Scene:
    info = field_info(field)
    first = results.frame(frames[0])
    field_values(first, field)  # fail early when the run lacks the needed output
    boxes = [_domain_box(results), _structure_box(results)]
    values = []
    for i in frames:
        arrays = results.frame(i, {"positions", "active", info.source})
        shown = drawable(arrays)
        _say_undrawable(arrays, i, field, on_warning, alone=len(frames) == 1)
        boxes.append(_particle_box(np.asarray(arrays["positions"])[shown]))
        if clim is None and not info.categorical:
            values.append(field_values(arrays, field)[shown])
    if clim is None and values:
        clim = value_range(np.concatenate(values))
    view = _view(_union(*boxes), size)
    return _Scene(results, field, size, view, _particle_spacing(results, first), cmap, clim)


def drawable(arrays: Mapping[str, np.ndarray]) -> np.ndarray:
    """The particles of a frame a picture shows: active, at finite positions, shape (N,) bool.

    A frame of an unstable run can hold NaN or infinite positions; they are left out of the
    picture, its bounds and its colour range (and said: :func:`_say_undrawable`)."""
    active = np.asarray(arrays["active"], dtype=bool)
    return active & np.isfinite(np.asarray(arrays["positions"], dtype=np.float64)).all(axis=1)


def _say_undrawable(arrays: Mapping[str, np.ndarray], index: int, field: str,
                    on_warning: Callable[[str], None] | None, alone: bool) -> None:
    """One line about the particles of frame ``index`` a picture cannot show as they are; a single
    frame none of whose active particles has a finite position is an error (nothing to draw)."""
    active = np.asarray(arrays["active"], dtype=bool)
    shown = drawable(arrays)
    bad = int(active.sum() - shown.sum())
    if bad and alone and not shown.any():
        raise ValueError(f"frame {index}: all {bad:,} particle positions are NaN or inf, nothing to draw "
                         "(the run went unstable: see its summary.json)")
    lines = []
    if bad:
        lines.append(f"frame {index}: {bad:,} of {int(active.sum()):,} particles have positions that are NaN or inf "
                     "(the run went unstable: see its summary.json); they are not drawn")
    info = field_info(field)
    if not info.categorical and info.source in arrays:
        values = np.asarray(field_values(arrays, field), dtype=np.float64)[shown]
        nan = int((~np.isfinite(values)).sum())
        if nan:
            lines.append(f"frame {index}: {nan:,} particles have a {field} that is NaN or inf; they are drawn in the "
                         "no-data colour")
    for line in lines:
        if on_warning is not None:
            on_warning(line)
        else:
            logger.warning(line)


def _frame_index(results: Results, frame: int) -> int:
    if len(results) == 0:
        raise ResultsError(f"{results.path} has no complete frames to show")
    n = len(results)
    j = frame + n if frame < 0 else frame
    if not 0 <= j < n:
        raise ValueError(f"frame {frame} out of range: the results have {n} frames (0..{n - 1})")
    return j


def render_frame(
    results: Results | str | os.PathLike[str],
    frame: int = -1,
    field: str = "displacement",
    path: str | os.PathLike[str] | None = None,
    size: tuple[int, int] = (1600, 900),
    cmap: str | None = None,
    clim: tuple[float, float] | None = None,
    on_warning: Callable[[str], None] | None = None,
    smooth: bool = False,
) -> Path:
    """Render one frame of a results folder to a PNG, offscreen.

    Parameters
    ----------
    results : Results or path-like
        An open results folder or its path.
    frame : int
        Frame index; negative counts from the end (-1: the end state).
    field : str
        A key of :data:`FIELDS`.
    path : path-like, optional
        Output PNG. Default: beside the results folder (never inside it, a re-run may replace
        it): ``NAME_<field>_<frame>.png`` for ``NAME.results``
        (:func:`projects.results_folder.export_path`).
    size : (int, int)
        Image width and height, pixels.
    cmap : str, optional
        Matplotlib colour map (default per field).
    clim : (float, float), optional
        Colour range in the field's units (default: the frame's range).
    on_warning : callable, optional
        Called with one line about particles the picture cannot show as they are (positions or
        values that are NaN or inf: left out, or drawn in the no-data colour).
    smooth : bool
        Show a stress or the pore pressure averaged over the grid cells around each particle
        (:func:`app.display.smooth_values`; other fields as they are).

    Returns
    -------
    Path
        The written image.

    Raises
    ------
    ValueError
        An unknown field, a frame out of range, or a frame with no active particle at a finite
        position (an unstable run's last frame: nothing to draw).
    """
    res = _as_results(results)
    field_info(field)
    j = _frame_index(res, frame)
    from projects.results_folder import check_writable, export_path

    out = check_writable(Path(path) if path is not None else export_path(res.path, f"{field}_{j:05d}"))
    scene = _scene_for(res, field, [j], size, cmap, clim, on_warning)
    scene.smooth_cell_m = _cell_size(res) if smooth else None
    try:
        scene.show(j)
        scene.plotter.screenshot(str(out))
    finally:
        scene.close()
    logger.info("wrote %s", out)
    return out


def animate(
    results: Results | str | os.PathLike[str],
    path: str | os.PathLike[str],
    field: str = "displacement",
    fps: float = 10.0,
    size: tuple[int, int] = (1280, 720),
    cmap: str | None = None,
    clim: tuple[float, float] | None = None,
    on_frame: Callable[[int, int], None] | None = None,
    on_warning: Callable[[str], None] | None = None,
    smooth: bool = False,
) -> Path:
    """Write a movie of every frame: ``.mp4`` (H.264 via imageio-ffmpeg) or ``.gif`` (pillow).

    The camera and colour range are fixed over the whole movie (the range of all frames unless
    ``clim`` is given). ``on_frame(done, total)`` reports progress; ``on_warning`` gets a line
    per frame with particles at NaN or infinite positions (left out) or values (no-data colour).
    ``smooth``: stresses and pore pressure averaged over the cells around each particle, as
    :func:`render_frame`.

    Returns
    -------
    Path
        The written movie.
    """
    import imageio.v2 as imageio

    res = _as_results(results)
    field_info(field)
    out = Path(path)
    suffix = out.suffix.lower()
    if suffix not in (".mp4", ".gif"):
        raise ValueError(f"movie must be .mp4 or .gif, got {out.name!r}")
    if fps <= 0:
        raise ValueError(f"fps must be > 0, got {fps}")
    if len(res) == 0:
        raise ResultsError(f"{res.path} has no complete frames to show")
    # H.264 in yuv420p needs even dimensions
    size = (int(size[0]) // 2 * 2, int(size[1]) // 2 * 2)
    frames = list(range(len(res)))
    from projects.results_folder import check_writable

    out = check_writable(out)  # before the writer: ffmpeg on a read-only disk prints pages of noise
    scene = _scene_for(res, field, frames, size, cmap, clim, on_warning)
    scene.smooth_cell_m = _cell_size(res) if smooth else None
    if suffix == ".mp4":
        writer = imageio.get_writer(out, format="FFMPEG", fps=fps, codec="libx264",
                                    quality=8, macro_block_size=1, pixelformat="yuv420p")
    else:
        writer = imageio.get_writer(out, format="GIF", mode="I", duration=1000.0 / fps, loop=0)
    try:
        for done, j in enumerate(frames, start=1):
            scene.show(j)
            writer.append_data(scene.screenshot())
            if on_frame is not None:
                on_frame(done, len(frames))
    finally:
        writer.close()
        scene.close()
    logger.info("wrote %s (%d frames)", out, len(frames))
    return out


def render_mechanism(results: Results | str | os.PathLike[str], path: str | os.PathLike[str] | None = None,
                     size: tuple[int, int] = (1600, 700)) -> Path:
    """The failure mechanism of a strength-reduction run: plastic strain at ``F_fail`` with
    Bishop's critical circle and the monitor point, beside the knee curve (monitor
    displacement against the trial factor). Matplotlib, offscreen.

    Parameters
    ----------
    results : Results or path-like
    path : path-like, optional
        Output PNG. Default: beside the results folder, ``NAME_mechanism.png`` (never inside it,
        a re-run may replace it: :func:`projects.results_folder.export_path`).
    size : (int, int)
        Image width and height, pixels.

    Returns
    -------
    Path

    Raises
    ------
    ValueError
        When the results hold no factor of safety (not a strength-reduction run).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    import json

    res = _as_results(results)
    summary = json.loads((res.path / "summary.json").read_text(encoding="utf-8"))
    fos = summary.get("factor_of_safety")
    if not fos:
        raise ValueError(f"{res.path} holds no factor of safety (no strength-reduction stage ran)")
    from projects.results_folder import check_writable, export_path

    out = check_writable(Path(path) if path is not None else export_path(res.path, "mechanism"))
    frame = fos.get("mechanism_frame")
    fig, (ax, knee) = plt.subplots(1, 2, figsize=(size[0] / 100, size[1] / 100), dpi=100,
                                   gridspec_kw={"width_ratios": [2.2, 1]})
    try:
        if frame is not None:
            arrays = res.frame(int(frame))
            keep = arrays["active"]
            xy = arrays["positions"][keep]
            eps = arrays.get("plastic_strain", np.zeros(len(keep)))[keep]
            spacing = float(summary.get("particle_spacing_m") or 0.0)
            dots = ax.scatter(xy[:, 0], xy[:, 1], c=eps, s=max(1.0, 4000.0 * spacing / max(np.ptp(xy[:, 0]), 1e-9)),
                              cmap="inferno", marker="s", linewidths=0)
            fig.colorbar(dots, ax=ax, label="equivalent plastic strain", shrink=0.8)
            ax.set_title(f"mechanism at F = {fos['upper']:.3f}")
        le = summary.get("limit_equilibrium") or {}
        circle = le.get("circle")
        if circle:
            cx, cy = circle["centre_m"]
            t = np.linspace(np.pi, 2.0 * np.pi, 361)  # the lower arc: the slip surface
            ax.plot(cx + circle["radius_m"] * np.cos(t), cy + circle["radius_m"] * np.sin(t), "c--", lw=1.5,
                    label=f"Bishop critical circle, F = {le['factor_of_safety']:.3f}")
        if fos.get("monitor_point_m"):
            ax.plot(*fos["monitor_point_m"], "o", mfc="none", mec="lime", ms=10, label="monitor point")
        structures = summary.get("structures") or []
        structure_patches(ax, structures)  # the walls and dams the mechanism runs against
        if frame is not None:
            box = np.vstack([xy, *[np.asarray(st.get("polygon_m") or np.zeros((0, 2)), dtype=float).reshape(-1, 2)
                                   for st in structures]])
            pad = 0.05 * max(np.ptp(box[:, 0]), np.ptp(box[:, 1]))
            ax.set_xlim(box[:, 0].min() - pad, box[:, 0].max() + pad)
            ax.set_ylim(box[:, 1].min() - pad, box[:, 1].max() + pad)
        ax.set_aspect("equal")
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        ax.legend(loc="lower left", fontsize=8)
        trials = sorted(fos.get("trials", []), key=lambda tr: tr["factor"])
        for verdict, style in (("stable", "bo"), ("failed", "rx")):
            pts = [(tr["factor"], tr["monitor_displacement_m"]) for tr in trials if tr["verdict"] == verdict]
            if pts:
                knee.plot(*zip(*pts), style, label=verdict)
        if trials:
            knee.plot([tr["factor"] for tr in trials], [tr["monitor_displacement_m"] for tr in trials], "k-", lw=0.5)
        if fos.get("value") is not None:
            knee.axvline(fos["value"], color="k", ls=":", label=f"F = {fos['value']:.3f}")
        if le.get("factor_of_safety") is not None:
            knee.axvline(le["factor_of_safety"], color="c", ls="--", label="Bishop")
        knee.set_xlabel("trial factor F")
        knee.set_ylabel("monitor displacement (m)")
        knee.legend(fontsize=8)
        knee.set_title("strength reduction trials")
        fig.tight_layout()
        out.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(out)
    finally:
        plt.close(fig)
    logger.info("wrote %s", out)
    return out
