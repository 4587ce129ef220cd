"""Shared pieces of the validation studies: running scenes, measuring deposits, writing reports.

Runs go through the normal path: a shipped example project, ``--set``-style overrides
(:func:`projects.document.apply_overrides`), :func:`projects.build.resolve` and the runner's one
run loop: :func:`projects.runner.run_project` (a results folder, :func:`run_project_measured`) or
:func:`projects.runner.run_resolved` (frames only, :func:`run_built`).

The deposit measures (surface, toe, reach, front, crest, RMS deviation) are
:mod:`projects.measures`; here are the comparisons of the aluminium-bar deposit with the experiment
(:func:`measure_deposit`: the RMS deviation over x in [0, 0.42 m], the surface on a 1 mm grid).
"""

from __future__ import annotations

import csv
import io
import json
import logging
import math
import os
import resource
import shutil
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from projects.atomic import write_atomic
from projects.measures import (
    REACH_THICKNESS_M,
    TOE_THICKNESS_M,
    crest_height,
    front_position,
    read_xy_csv,
    rms_deviation,
    surface_heights,
    toe_position,
)

logger = logging.getLogger(__name__)

REPO = Path(__file__).resolve().parents[1]
EXAMPLES = REPO / "projects" / "examples"
#: The experimental final surface of Bui et al. (2008) (shared data folder of the project).
BUI_SURFACE_CSV_CANDIDATES = (
    REPO / "projects" / "examples" / "bui2008_final_surface.csv",
    REPO.parent / "shared" / "data" / "bui2008_final_surface.csv",
)

#: The experimental failure line of Bui et al. (2008): the edge of the undisturbed wedge.
BUI_FAILURE_CSV_CANDIDATES = (
    REPO / "projects" / "examples" / "bui2008_failure_line.csv",
    REPO.parent / "shared" / "data" / "bui2008_failure_line.csv",
)
#: Heights (m) at which the failure line is compared (the wedge's top, middle and foot).
FAILURE_HEIGHTS_M = (0.08, 0.05, 0.02)
#: A particle has left the undisturbed wedge when it moved more than this horizontally (m).
FAILURE_THRESHOLD_M = 0.001

Note = Callable[[str], None]


class StudyError(Exception):
    """A study cannot run (missing data file, unknown study, bad output folder)."""


def quiet(_: str) -> None:
    """Default progress sink: drop the message."""


# --------------------------------------------------------------------------------------------
# scenes


def example(name: str) -> Path:
    """Path of a shipped example project, ``projects/examples/NAME.toml``."""
    path = EXAMPLES / f"{name}.toml"
    if not path.is_file():
        raise StudyError(f"example project {path} is missing")
    return path


def load_scene(name: str, overrides: Sequence[str] = ()) -> Any:
    """Load a shipped example with ``--set``-style overrides, always on the CPU.

    Parameters
    ----------
    name : str
        Example name without ``.toml`` (``bui2008_aluminium_bars``, ``sand_column``, ...).
    overrides : sequence of str
        ``KEY=VALUE`` as for ``runout run --set``.

    Returns
    -------
    projects.schema.Project
    """
    from projects.document import load_project

    return load_project(example(name), ['numerics.arch="cpu"', *overrides])


def bui_experiment() -> np.ndarray:
    """The experimental final surface of Bui et al. (2008).

    Returns
    -------
    numpy.ndarray, shape (K, 2)
        ``x, y`` in m, origin at the back wall, at the base.
    """
    for path in BUI_SURFACE_CSV_CANDIDATES:
        if path.is_file():
            try:
                return read_xy_csv(path)
            except ValueError as exc:
                raise StudyError(str(exc)) from None
    raise StudyError("the experimental surface bui2008_final_surface.csv was not found in "
                     + " or ".join(str(p.parent) for p in BUI_SURFACE_CSV_CANDIDATES))


def bui_failure_line() -> np.ndarray | None:
    """The experimental failure line of Bui et al. (2008) (``x, y`` in m, from the wall's top down
    to the base), None where its file is not found."""
    for path in BUI_FAILURE_CSV_CANDIDATES:
        if path.is_file():
            try:
                return read_xy_csv(path)
            except ValueError as exc:
                raise StudyError(str(exc)) from None
    return None


def failure_line_x(initial: np.ndarray, final: np.ndarray, active: np.ndarray | None, spacing_m: float,
                   heights_m: Sequence[float], threshold_m: float = FAILURE_THRESHOLD_M) -> np.ndarray:
    """Where the failure line crosses each height: the edge of the undisturbed wedge.

    In the row of particles that started within half a spacing of the height, the smallest initial
    ``x`` of a particle that moved more than ``threshold_m`` horizontally (the wedge's particles
    did not; those beyond its edge all did). NaN where no particle of the row moved.
    """
    x0, y0 = np.asarray(initial, dtype=float)[:, 0], np.asarray(initial, dtype=float)[:, 1]
    ux = np.asarray(final, dtype=float)[:, 0] - x0
    ok = np.ones(len(x0), bool) if active is None else np.asarray(active, dtype=bool)
    out = []
    for h in heights_m:
        moved = ok & (np.abs(y0 - h) <= 0.5 * spacing_m + 1e-9) & (np.abs(ux) > threshold_m)
        out.append(float(x0[moved].min()) if moved.any() else math.nan)
    return np.asarray(out)


def experiment_failure_x(line: np.ndarray, heights_m: Sequence[float]) -> np.ndarray:
    """The experimental failure line's ``x`` at each height (linear between its points)."""
    f = np.asarray(line, dtype=float)
    f = f[np.argsort(f[:, 1])]
    return np.interp(np.asarray(heights_m, dtype=float), f[:, 1], f[:, 0])


def profile_centroid(x: np.ndarray, h: np.ndarray) -> float:
    """The horizontal centroid of the area under a surface ``h(x)`` (m): where the deposit's
    cross-section balances."""
    x = np.asarray(x, dtype=float)
    h = np.asarray(h, dtype=float)
    area = np.trapezoid(h, x)
    return float(np.trapezoid(x * h, x) / area) if area > 0 else math.nan


def experiment_centroid(experiment: np.ndarray, step_m: float = 0.001) -> float:
    """The experimental deposit's centroid: of the area under its surface, linear between the
    points and zero beyond the last one, on the grid the runs' surfaces use."""
    exp = np.asarray(experiment, dtype=float)
    exp = exp[np.argsort(exp[:, 0])]
    grid = np.arange(0.0, 0.8 + 1e-9, step_m)
    return profile_centroid(grid, np.interp(grid, exp[:, 0], exp[:, 1], right=0.0))


# --------------------------------------------------------------------------------------------
# running


@dataclass
class RunRecord:
    """What one study run produced.

    Attributes
    ----------
    label : str
        Short name of the run in tables.
    params : dict
        The settings that distinguish it (scheme, cell size, ...).
    status : str
        ``completed``, ``stopped`` (wall-clock limit or cancel) or ``failed``.
    message : str
        The solver's or runner's one-line message.
    wall_s, cpu_s : float
        Wall-clock and process CPU seconds of the whole run (set-up, compilation, output).
    steps, particles : int
    simulated_time_s : float
    particle_steps_per_s : float
        From the run's summary (timed loop only).
    series : dict of str to numpy.ndarray
        One entry per output (columns of ``series.csv``).
    positions : numpy.ndarray, shape (N, 2)
        Final positions, m.
    active : numpy.ndarray, shape (N,), bool
    displacement : numpy.ndarray, shape (N, 2), optional
        Final displacements, m, where the run wrote them (the failure line needs them).
    spacing_m : float
        Initial particle spacing ``sqrt(median volume)``, m.
    extra : dict
        Study-specific numbers.
    """

    label: str
    params: dict[str, Any]
    status: str
    message: str
    wall_s: float
    cpu_s: float
    steps: int
    particles: int
    simulated_time_s: float
    particle_steps_per_s: float
    series: dict[str, np.ndarray] = field(default_factory=dict)
    positions: np.ndarray | None = None
    active: np.ndarray | None = None
    spacing_m: float = 0.0
    extra: dict[str, Any] = field(default_factory=dict)
    displacement: np.ndarray | None = None

    @property
    def ok(self) -> bool:
        return self.status == "completed"

    @property
    def particle_steps(self) -> int:
        return int(self.steps) * int(self.particles)

    def row(self) -> dict[str, Any]:
        """Flat JSON-friendly summary (no arrays)."""
        out = {"label": self.label, **self.params, "status": self.status, "message": self.message,
               "wall_s": self.wall_s, "cpu_s": self.cpu_s, "steps": self.steps, "particles": self.particles,
               "particle_steps": self.particle_steps, "simulated_time_s": self.simulated_time_s,
               "particle_steps_per_s": self.particle_steps_per_s}
        out.update(self.extra)
        return out


def cpu_seconds() -> float:
    """User + system CPU seconds of this process (all threads, Taichi's included)."""
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


class WallClockLimit:
    """A ``cancel`` callable that turns True once ``limit_s`` seconds have passed.

    Used so that no study row can hang: a run past its limit stops with status ``stopped``.
    """

    def __init__(self, limit_s: float | None) -> None:
        self.limit_s = limit_s
        self.start = time.perf_counter()
        self.fired = False

    def __call__(self) -> bool:
        if self.limit_s is not None and time.perf_counter() - self.start > self.limit_s:
            self.fired = True
        return self.fired


def run_project_measured(
    project: Any,
    out_dir: Path,
    label: str,
    params: Mapping[str, Any] | None = None,
    *,
    keep_frames: bool = True,
    time_limit_s: float | None = None,
    on_frame: Callable[[Any], None] | None = None,
) -> RunRecord:
    """Run a project with :func:`projects.runner.run_project` and read back what the studies need.

    Parameters
    ----------
    project : projects.schema.Project
    out_dir : Path
        Its results folder (replaced if it is one already).
    label : str
    params : mapping, optional
    keep_frames : bool
        False deletes the frame files afterwards (sweeps); the final positions are kept in
        ``final.npz`` of the folder either way.
    time_limit_s : float, optional
        Stop the run (status ``stopped``) after this many wall seconds.
    on_frame : callable, optional
        Called with every :class:`solver.config.Frame`.

    Returns
    -------
    RunRecord
    """
    from projects.results import open_results
    from projects.runner import run_project

    limit = WallClockLimit(time_limit_s)
    cpu0 = cpu_seconds()
    wall0 = time.perf_counter()
    result = run_project(project, out_dir, cancel=limit, on_frame=on_frame, overwrite=True)  # a study owns its folders
    wall = time.perf_counter() - wall0
    cpu = cpu_seconds() - cpu0
    res = open_results(out_dir)
    summary = res.summary
    status, message = result.status, result.message
    if limit.fired:
        status, message = "stopped", f"wall-clock limit of {time_limit_s:g} s reached: {message}"
    positions = active = displacement = None
    if len(res):
        wanted = {"positions", "active"} | ({"displacement"} if "displacement" in project.output.fields else set())
        last = res.frame(-1, wanted)
        positions = np.array(last["positions"], dtype=float)
        active = np.array(last["active"], dtype=bool)
        if "displacement" in last:
            displacement = np.array(last["displacement"], dtype=float)[:, :2]
        np.savez_compressed(Path(out_dir) / "final.npz", positions=positions, active=active,
                            **({} if displacement is None else {"displacement": displacement}))
    record = RunRecord(
        label=label, params=dict(params or {}), status=status, message=message, wall_s=wall, cpu_s=cpu,
        steps=int(summary.get("steps", 0)), particles=int(summary.get("particles", 0)),
        simulated_time_s=float(summary.get("simulated_time_s") or 0.0),
        particle_steps_per_s=float(summary.get("particle_steps_per_s") or 0.0),
        series={k: np.asarray(v) for k, v in res.series.items()},
        positions=positions, active=active, spacing_m=float(summary.get("particle_spacing_m") or 0.0),
        displacement=displacement,
    )
    if not keep_frames:
        for name in ("frames",):
            shutil.rmtree(Path(out_dir) / name, ignore_errors=True)
        pvd = Path(out_dir) / "particles.pvd"
        if pvd.is_file():
            pvd.unlink()
    return record


@dataclass
class BuiltRunOutcome:
    """What :func:`run_built` saw: one diagnostics row per output and the last good frame."""

    status: str
    message: str
    rows: list[dict[str, Any]]
    last_fields: dict[str, np.ndarray]
    wall_s: float
    cpu_s: float
    steps: int
    simulated_time_s: float


def run_built(
    resolved: Any,
    *,
    time_limit_s: float | None = None,
    on_frame: Callable[[Any], None] | None = None,
) -> BuiltRunOutcome:
    """Run a resolved run through the runner's one run loop, without a results folder.

    The instability guard's message is an outcome here, not an error: status ``failed`` with its
    message. Other exceptions become ``failed`` as in any run.

    Parameters
    ----------
    resolved : projects.build.ResolvedRun
    time_limit_s : float, optional
    on_frame : callable, optional

    Returns
    -------
    BuiltRunOutcome
    """
    from projects.runner import run_resolved

    limit = WallClockLimit(time_limit_s)
    rows: list[dict[str, Any]] = []
    last: dict[str, np.ndarray] = {}
    cpu0 = cpu_seconds()
    wall0 = time.perf_counter()

    def collect(frame: Any) -> None:
        nonlocal last
        d = frame.diagnostics
        rows.append({
            "time_s": d.time_s, "stage": d.stage, "step": d.step, "dt_s": d.dt_s,
            "kinetic_energy_J_per_m": d.kinetic_energy_J_per_m, "momentum_x": d.momentum_x,
            "momentum_y": d.momentum_y, "max_speed_m_s": d.max_speed_m_s,
            "unstable_particles": d.unstable_particles, "lost_particles": d.lost_particles,
            "total_mass_kg_per_m": d.total_mass_kg_per_m, "active_particles": int(frame.fields["active"].sum()),
        })
        last = frame.fields
        if on_frame is not None:
            on_frame(frame)

    result = run_resolved(resolved, cancel=limit, on_frame=collect)
    status, message = result.status, result.message
    if limit.fired and status == "stopped":
        status, message = "stopped", f"wall-clock limit of {time_limit_s:g} s reached at t = {result.summary['simulated_time_s']:.4g} s"
    return BuiltRunOutcome(status, message, rows, last, time.perf_counter() - wall0, cpu_seconds() - cpu0,
                           int(result.summary["steps"]), float(result.summary["simulated_time_s"]))


# --------------------------------------------------------------------------------------------
# the aluminium-bar deposit against the experiment


@dataclass(frozen=True)
class Deposit:
    """Measures of one final deposit of the aluminium-bar scene (m).

    Attributes
    ----------
    rms_m : float
        RMS vertical deviation from the experiment over x in [0, ``x_max``].
    toe_m, front_m, crest_m, reach_m : float
    surface_x, surface_y : numpy.ndarray
        The surface on a 1 mm grid (for plots and run-to-run comparison).
    centroid_m : float
        Horizontal centroid of the area under the surface (:func:`profile_centroid`).
    failure_x_m : numpy.ndarray
        Where the failure line crosses :data:`FAILURE_HEIGHTS_M` (:func:`failure_line_x`); NaN
        without the displacements.
    failure_rms_m : float
        RMS horizontal distance of the failure line from the experiment's at the experiment's
        points between 5 mm and 95 mm high; NaN without the displacements or the experiment's line.
    """

    rms_m: float
    toe_m: float
    front_m: float
    crest_m: float
    surface_x: np.ndarray
    surface_y: np.ndarray
    reach_m: float = math.nan
    centroid_m: float = math.nan
    failure_x_m: np.ndarray = field(default_factory=lambda: np.full(len(FAILURE_HEIGHTS_M), math.nan))
    failure_rms_m: float = math.nan

    def as_dict(self) -> dict[str, float]:
        out = {"rms_mm": 1e3 * self.rms_m, "toe_m": self.toe_m, "reach_m": self.reach_m, "front_m": self.front_m,
               "crest_m": self.crest_m, "centroid_m": self.centroid_m, "failure_rms_mm": 1e3 * self.failure_rms_m}
        for h, x in zip(FAILURE_HEIGHTS_M, self.failure_x_m):
            out[f"failure_x_{1e3 * h:.0f}mm_m"] = float(x)
        return out


#: The issue's range of the RMS comparison, m.
RMS_RANGE_M = (0.0, 0.42)


def measure_deposit(positions: np.ndarray, active: np.ndarray | None, spacing_m: float,
                    experiment: np.ndarray, x_range: tuple[float, float] = RMS_RANGE_M,
                    displacement: np.ndarray | None = None, failure_line: np.ndarray | None = None) -> Deposit:
    """All deposit measures of a final frame against the experimental surface (and failure line).

    Parameters
    ----------
    positions : numpy.ndarray, shape (N, 2)
    active : numpy.ndarray, shape (N,), bool, optional
    spacing_m : float
    experiment : numpy.ndarray, shape (K, 2)
        Experimental surface points, m.
    x_range : (float, float)
        Range of the RMS comparison, m.
    displacement : numpy.ndarray, shape (N, 2), optional
        The final displacements (the failure line needs them).
    failure_line : numpy.ndarray, shape (K, 2), optional
        The experimental failure line (for its RMS distance).

    Returns
    -------
    Deposit
    """
    exp = np.asarray(experiment, dtype=float)
    sel = (exp[:, 0] >= x_range[0]) & (exp[:, 0] <= x_range[1])
    h = surface_heights(positions, active, spacing_m, exp[sel, 0])
    grid = np.arange(0.0, 0.8 + 1e-9, 0.001)
    surface = surface_heights(positions, active, spacing_m, grid)
    failure_x = np.full(len(FAILURE_HEIGHTS_M), math.nan)
    failure_rms = math.nan
    if displacement is not None:
        initial = np.asarray(positions, dtype=float) - np.asarray(displacement, dtype=float)[:, :2]
        failure_x = failure_line_x(initial, positions, active, spacing_m, FAILURE_HEIGHTS_M)
        if failure_line is not None:
            line = np.asarray(failure_line, dtype=float)
            inner = line[(line[:, 1] >= 0.005) & (line[:, 1] <= 0.095)]
            xs = failure_line_x(initial, positions, active, spacing_m, inner[:, 1])
            failure_rms = rms_deviation(xs, inner[:, 0])
    return Deposit(
        rms_m=rms_deviation(h, exp[sel, 1]),
        toe_m=toe_position(positions, active, spacing_m),
        front_m=front_position(positions, active, spacing_m),
        crest_m=crest_height(positions, active, spacing_m),
        surface_x=grid,
        surface_y=surface,
        reach_m=toe_position(positions, active, spacing_m, REACH_THICKNESS_M),
        centroid_m=profile_centroid(grid, surface),
        failure_x_m=failure_x,
        failure_rms_m=failure_rms,
    )


def experiment_toe(experiment: np.ndarray, thickness_m: float = TOE_THICKNESS_M) -> float:
    """Furthest x where the experimental surface (linear between points) is ``thickness_m`` high."""
    exp = np.asarray(experiment, dtype=float)
    x, y = exp[:, 0], exp[:, 1]
    above = np.nonzero(y >= thickness_m)[0]
    if above.size == 0:
        return math.nan
    i = int(above.max())
    if i + 1 >= len(x):
        return float(x[i])
    return float(x[i] + (y[i] - thickness_m) / (y[i] - y[i + 1]) * (x[i + 1] - x[i]))


def surface_difference(a: Deposit, b: Deposit, x_range: tuple[float, float] = RMS_RANGE_M,
                       step_m: float = 0.005) -> float:
    """RMS difference of two deposits' surfaces on a ``step_m`` grid over ``x_range`` (m)."""
    xs = np.arange(x_range[0], x_range[1] + 1e-9, step_m)
    return rms_deviation(np.interp(xs, a.surface_x, a.surface_y), np.interp(xs, b.surface_x, b.surface_y))


# --------------------------------------------------------------------------------------------
# series helpers


def peak(series: Mapping[str, np.ndarray], column: str) -> tuple[float, float]:
    """``(value, time)`` of the largest finite value of a series column (NaN, NaN if none)."""
    t = np.asarray(series.get("time_s", []), dtype=float)
    v = np.asarray(series.get(column, []), dtype=float)
    ok = np.isfinite(v)
    if not ok.any():
        return math.nan, math.nan
    i = int(np.argmax(np.where(ok, v, -np.inf)))
    return float(v[i]), float(t[i])


def settle_time(series: Mapping[str, np.ndarray], fraction: float = 0.01) -> float:
    """First time after the kinetic-energy peak when it falls below ``fraction`` of the peak."""
    t = np.asarray(series.get("time_s", []), dtype=float)
    ke = np.asarray(series.get("kinetic_energy_J_per_m", []), dtype=float)
    if ke.size == 0 or not np.isfinite(ke).any():
        return math.nan
    i = int(np.nanargmax(ke))
    below = np.nonzero(ke[i:] < fraction * ke[i])[0]
    return float(t[i + below[0]]) if below.size else math.nan


def series_finite(series: Mapping[str, np.ndarray]) -> bool:
    """True when every numeric column of a series is finite."""
    for values in series.values():
        arr = np.asarray(values)
        if arr.dtype.kind == "f" and not np.all(np.isfinite(arr)):
            return False
    return True


# --------------------------------------------------------------------------------------------
# reports


def fmt(value: Any, digits: int = 3) -> str:
    """A number for a table: ``digits`` significant digits, "-" for None/NaN."""
    if value is None:
        return "-"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, (int, np.integer)):
        return f"{int(value):,}"
    if isinstance(value, (float, np.floating)):
        if not math.isfinite(float(value)):
            return "-" if math.isnan(float(value)) else str(value)
        return f"{float(value):.{digits}g}"
    return str(value)


def md_table(headers: Sequence[str], rows: Iterable[Sequence[Any]]) -> str:
    """A GitHub-flavoured markdown table (cells escaped for ``|``)."""
    def cell(v: Any) -> str:
        return (v if isinstance(v, str) else fmt(v)).replace("|", "\\|").replace("\n", " ")

    lines = ["| " + " | ".join(headers) + " |", "|" + "|".join("---" for _ in headers) + "|"]
    lines += ["| " + " | ".join(cell(v) for v in row) + " |" for row in rows]
    return "\n".join(lines)


class Report:
    """A markdown report being assembled in a folder, with its figures and raw data.

    Parameters
    ----------
    out_dir : Path
        The study's folder (created).
    title : str
    """

    def __init__(self, out_dir: Path, title: str) -> None:
        self.out_dir = Path(out_dir)
        self.out_dir.mkdir(parents=True, exist_ok=True)
        self.parts: list[str] = [f"# {title}", ""]

    def text(self, *paragraphs: str) -> None:
        for p in paragraphs:
            self.parts += [p, ""]

    def heading(self, text: str, level: int = 2) -> None:
        self.parts += ["#" * level + " " + text, ""]

    def table(self, headers: Sequence[str], rows: Iterable[Sequence[Any]]) -> None:
        self.parts += [md_table(headers, rows), ""]

    def figure(self, fig: Any, name: str, caption: str) -> Path:
        """Save a matplotlib figure as ``NAME.png`` and reference it."""
        path = self.out_dir / f"{name}.png"
        fig.savefig(path, dpi=110, bbox_inches="tight")
        self.parts += [f"![{caption}]({path.name})", "", f"*{caption}*", ""]
        return path

    def write(self) -> Path:
        path = self.out_dir / "report.md"
        write_atomic(path, "\n".join(self.parts).rstrip() + "\n")
        return path


def new_figure(width: float = 7.0, height: float = 4.0, ncols: int = 1, nrows: int = 1) -> tuple[Any, Any]:
    """A matplotlib figure (Agg canvas, no pyplot state) and its axes."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(nrows, ncols, squeeze=False)
    return fig, (axes[0, 0] if nrows == ncols == 1 else axes)


def _json_default(value: Any) -> Any:
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (np.floating,)):
        v = float(value)
        return v if math.isfinite(v) else None
    if isinstance(value, (np.integer,)):
        return int(value)
    if isinstance(value, (np.bool_,)):
        return bool(value)
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"cannot write {type(value).__name__} as JSON")


def _finite_or_none(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _finite_or_none(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite_or_none(v) for v in value]
    return value


def write_json(path: Path, data: Any) -> Path:
    """Write JSON (NaN/inf as null, numpy values as Python ones)."""
    write_atomic(path, json.dumps(_finite_or_none(data), indent=2, default=_json_default) + "\n")
    return path


def write_csv(path: Path, rows: Sequence[Mapping[str, Any]]) -> Path:
    """Write dict rows as CSV (the union of their keys as columns, in first-seen order)."""
    columns: list[str] = []
    for r in rows:
        for k in r:
            if k not in columns:
                columns.append(k)
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=columns, extrasaction="ignore")
    w.writeheader()
    for r in rows:
        w.writerow({k: _csv_cell(r.get(k)) for k in columns})
    write_atomic(path, buf.getvalue())
    return path


def _csv_cell(value: Any) -> Any:
    if value is None:
        return ""
    if isinstance(value, (float, np.floating)):
        return repr(float(value))
    if isinstance(value, (list, tuple, dict)):
        return json.dumps(_finite_or_none(value), default=_json_default)
    return value


def write_series(path: Path, series: Mapping[str, np.ndarray]) -> Path:
    """Write a series (dict of equal-length columns) as CSV."""
    keys = list(series)
    n = len(next(iter(series.values()))) if series else 0
    return write_csv(path, [{k: series[k][i] for k in keys} for i in range(n)])


def rows_to_series(rows: Sequence[Mapping[str, Any]]) -> dict[str, np.ndarray]:
    """Dict rows (as from :func:`run_built`) to columns."""
    if not rows:
        return {}
    return {k: np.asarray([r[k] for r in rows]) for k in rows[0]}


@dataclass
class StudyResult:
    """What a study hands back to its caller (the command line prints the verdict).

    Attributes
    ----------
    name : str
    passed : bool
        Every stated target met.
    verdict : list of str
        A few lines, the first one the headline.
    report : Path
        The ``report.md``.
    wall_s : float
        Wall-clock seconds of the whole study.
    data : dict
        The numbers behind the verdict (also in the study's JSON file).
    """

    name: str
    passed: bool
    verdict: list[str]
    report: Path
    wall_s: float
    data: dict[str, Any] = field(default_factory=dict)


def machine_line() -> str:
    """CPU count and load of this machine, for reports (timings depend on them)."""
    import platform

    try:
        load = os.getloadavg()
        load_text = f", load average {load[0]:.1f} (1 min) at the end"
    except OSError:
        load_text = ""
    return f"{platform.processor() or platform.machine()}, {os.cpu_count()} logical CPUs{load_text}, Python {platform.python_version()}"
