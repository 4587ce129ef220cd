"""Size limits of a run, checked on the estimate before anything is allocated.

:func:`check_limits` compares :func:`projects.build.estimate` (a pure function of the project)
with two kinds of limit and raises :class:`~projects.schema.ProjectError`, one line per limit
exceeded, naming the project key that drives the size, the estimate and the limit:

- stated limits (:data:`LIMITS`): what Runout is meant to run (particles, grid cells, seeding
  candidates, time steps, frames, hazard raster cells);
- what the machine has: the memory available now (``MemAvailable`` of ``/proc/meminfo``) and
  the free disk where the results go.

``force=True`` (the command line's ``--force``) skips the check, for the determined; only a disk
with less than :data:`MIN_FREE_DISK_BYTES` free where the results go is refused even then (a run
with ``--force`` onto a full disk could not write its summary and left its lock file behind).
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from projects.schema import Problem, ProjectError


@dataclass(frozen=True)
class Limit:
    """One stated limit: the estimate's key, its largest allowed value and the project key
    blamed (the one whose value is shown), with words for the message."""

    estimate_key: str
    maximum: float
    project_key: str
    what: str


#: Stated limits (documented in docs/project-format.md, "Size limits").
LIMITS: tuple[Limit, ...] = (
    Limit("grid_cells", 2e8, "domain.cell_size_m", "grid cells (domain.size_m / cell_size_m)"),
    Limit("particles", 1e8, "domain.cell_size_m", "particles (body area x (per_cell / cell_size_m)^2)"),
    Limit("seeding_candidates", 1e9, "domain.cell_size_m", "seeding points tested (the bodies' bounding box)"),
    Limit("steps", 1e8, "numerics.time_step_s", "time steps (simulated time / time step)"),
    Limit("frames", 1e5, "output.interval_s", "frames (simulated time / output.interval_s)"),
    Limit("hazard_cells", 2e8, "hazard.cell_size_m", "hazard raster cells (domain.size_m / hazard.cell_size_m)"),
)


#: Free disk a run needs to start at all, whatever ``--force`` says: the project, the marker, the
#: reserve kept for the final summary (projects.results.RESERVE_BYTES) and the first frames.
MIN_FREE_DISK_BYTES = 1_000_000


def _fmt(value: float) -> str:
    MAX_COUNT = 2**62  # projects.build.MAX_COUNT, the estimate's cap (build imports this module: no import back)

    if value >= MAX_COUNT:
        return f"more than {MAX_COUNT:.3g}"  # the estimate's cap: beyond any number that matters
    return f"{value:,.0f}" if value < 1e7 else f"{value:.3g}"


def _about(value: float) -> str:
    text = _fmt(value)
    return text if text.startswith("more") else f"about {text}"


def _bytes(value: float) -> str:
    for unit, size in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if value >= size:
            return f"{value / size:.3g} {unit}"
    return f"{value:.0f} B"


def available_memory_bytes() -> int | None:
    """Memory available to a new run now (Linux ``MemAvailable``), or None where unknown."""
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_AVPHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return None


def free_disk_bytes(path: str | os.PathLike[str]) -> int | None:
    """Free disk space for the folder ``path`` (or its nearest existing parent), or None."""
    folder = Path(path).expanduser().absolute()
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    try:
        return int(shutil.disk_usage(folder).free)
    except OSError:
        return None


#: A time step this many times shorter for a material's damping is blamed on the damping.
DAMPING_BLAME_SHRINK = 2.0


def _key_value(estimate: Mapping[str, Any], limit: Limit) -> tuple[str, Any]:
    if limit.project_key == "numerics.time_step_s" and estimate.get("time_step_source") == "cfl":
        if estimate.get("damping_key") and estimate.get("time_step_shrink_by_damping", 1.0) >= DAMPING_BLAME_SHRINK:
            return estimate["damping_key"], None
        return "numerics.cfl", None
    value = {"domain.cell_size_m": estimate.get("cell_size_m"),
             "numerics.time_step_s": estimate.get("time_step_s"),
             "output.interval_s": estimate.get("output_interval_s"),
             "hazard.cell_size_m": estimate.get("hazard_cell_size_m")}.get(limit.project_key)
    return limit.project_key, value


def limit_problems(
    estimate: Mapping[str, Any],
    *,
    out_dir: str | os.PathLike[str] | None = None,
    memory_bytes: int | None = None,
    disk_bytes: int | None = None,
) -> list[Problem]:
    """The limits an estimate exceeds, one :class:`Problem` each (empty when none).

    Parameters
    ----------
    estimate : mapping
        :func:`projects.build.estimate` of the project.
    out_dir : path-like, optional
        The results folder (free disk is checked there when given).
    memory_bytes, disk_bytes : int, optional
        What the machine has; default: measured now (memory) and at ``out_dir`` (disk).

    Returns
    -------
    list of Problem
    """
    problems = []
    for limit in LIMITS:
        value = float(estimate.get(limit.estimate_key, 0) or 0)
        if value > limit.maximum:
            key, shown = _key_value(estimate, limit)
            extra = ""
            if limit.estimate_key == "steps":
                extra = (f"; {estimate.get('simulated_time_s', 0):.3g} s simulated with a time step of "
                         f"{estimate.get('time_step_s', 0):.3g} s")
                if key == estimate.get("damping_key"):
                    extra += (f", {estimate['time_step_shrink_by_damping']:.3g} times shorter for the material's "
                              "damping (docs/solver.md, material damping)")
            problems.append(Problem(key, shown, f"the run would take {_about(value)} {limit.what}, more "
                                    f"than the limit of {_fmt(limit.maximum)}{extra}; --force runs it anyway"))
    if memory_bytes is None:
        memory_bytes = available_memory_bytes()
    need = float(estimate.get("memory_bytes", 0) or 0)
    if memory_bytes is not None and need > memory_bytes:
        raster = float(estimate.get("hazard_memory_bytes", 0) or 0)
        key, shown = (("hazard.cell_size_m", estimate.get("hazard_cell_size_m")) if raster > 0.5 * need
                      else ("domain.cell_size_m", estimate.get("cell_size_m")))
        cells = f", {_fmt(float(estimate.get('hazard_cells', 0)))} hazard raster cells" if raster else ""
        problems.append(Problem(
            key, shown,
            f"the run would need about {_bytes(need)} of memory, more than the {_bytes(memory_bytes)} "
            f"available ({_fmt(float(estimate.get('particles', 0)))} particles, "
            f"{_fmt(float(estimate.get('grid_nodes', 0)))} grid nodes{cells}); --force runs it anyway"))
    if disk_bytes is None and out_dir is not None:
        disk_bytes = free_disk_bytes(out_dir)
    need = float(estimate.get("disk_bytes", 0) or 0)
    if disk_bytes is not None and need > disk_bytes:
        where = f" in {Path(out_dir).expanduser().absolute()}" if out_dir is not None else ""
        raster = float(estimate.get("hazard_disk_bytes", 0) or 0)
        key, shown = (("hazard.cell_size_m", estimate.get("hazard_cell_size_m")) if raster > 0.5 * need
                      else ("output.interval_s", estimate.get("output_interval_s")))
        parts = f"{_fmt(float(estimate.get('frames', 0)))} frames of {_bytes(float(estimate.get('frame_bytes', 0)))}"
        if raster:
            parts += f", a hazard raster of {_bytes(raster)}"
        problems.append(Problem(
            key, shown,
            f"the results would take about {_bytes(need)} of disk ({parts}), more than the {_bytes(disk_bytes)} "
            f"free{where}; --force runs it anyway"))
    return problems


def check_limits(
    estimate: Mapping[str, Any],
    *,
    force: bool = False,
    out_dir: str | os.PathLike[str] | None = None,
    memory_bytes: int | None = None,
    disk_bytes: int | None = None,
) -> None:
    """Raise :class:`ProjectError` when the estimated run exceeds a limit (unless ``force``).

    Parameters
    ----------
    estimate : mapping
        :func:`projects.build.estimate` of the (preset-applied) project.
    force : bool
        Skip the check.
    out_dir, memory_bytes, disk_bytes
        See :func:`limit_problems`.

    Raises
    ------
    ProjectError
        One problem per limit exceeded: ``KEY = VALUE: the run would take about N ..., more
        than the limit of M; --force runs it anyway``.
    """
    if force:
        problems = start_problems(out_dir=out_dir, disk_bytes=disk_bytes)
    else:
        problems = limit_problems(estimate, out_dir=out_dir, memory_bytes=memory_bytes, disk_bytes=disk_bytes)
    if problems:
        raise ProjectError(problems)


def start_problems(
    *,
    out_dir: str | os.PathLike[str] | None = None,
    disk_bytes: int | None = None,
) -> list[Problem]:
    """What no ``--force`` gets past: less than :data:`MIN_FREE_DISK_BYTES` free where the results go."""
    if disk_bytes is None and out_dir is not None:
        disk_bytes = free_disk_bytes(out_dir)
    if disk_bytes is None or disk_bytes >= MIN_FREE_DISK_BYTES:
        return []
    where = f" in {Path(out_dir).expanduser().absolute()}" if out_dir is not None else ""
    return [Problem("", None, f"only {_bytes(disk_bytes)} of disk is free{where}, less than the "
                    f"{_bytes(MIN_FREE_DISK_BYTES)} a run needs to start (its project, summary and first frames); "
                    "--force cannot make room")]


__all__ = ["LIMITS", "MIN_FREE_DISK_BYTES", "Limit", "available_memory_bytes", "check_limits", "free_disk_bytes",
           "limit_problems", "start_problems"]
