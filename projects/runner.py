"""Running a project: build the solver run, advance it and write the results folder.

:func:`run_project` is what the command line, the GUI worker and the tests call. It never leaves
a results folder without a final status: whichever way the run ends (completed, cancelled,
Ctrl-C, instability, any solver error, a results disk error) the writer is closed and
``summary.json`` says what happened. Problems with the input (an invalid project or one the solver
rejects, a run beyond the size limits, all as :class:`~projects.schema.ProjectError`; an output
folder that must not be used, :class:`~projects.results.ResultsError`) are raised before
anything is written.

Output folder policy (:mod:`projects.results_folder`): by default ``NAME.results/`` next to the
project file ``NAME.toml``. A folder holding an earlier run's results is replaced only with
``overwrite=True`` (the command line's ``--overwrite``), and then only the files that run wrote
are removed; any other non-empty folder is refused; a folder another run is writing into is
refused. The folder is locked while the run writes.
"""

from __future__ import annotations

import logging
import os
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from projects.results import ResultsError, ResultsWriter
from projects.results_folder import check_results_dir
from solver.config import InstabilityError, SolverError

if TYPE_CHECKING:  # pragma: no cover - typing only
    from projects.schema import Project
    from solver.config import Frame
    from solver.simulation import Progress

logger = logging.getLogger(__name__)

RESULTS_SUFFIX = ".results"


@dataclass(frozen=True)
class RunResult:
    """How a run ended.

    Attributes
    ----------
    status : {"completed", "stopped", "failed"}
    message : str
        One line saying why (the solver's message, the error, or who stopped it).
    out_dir : Path
        The results folder.
    summary : dict
        The final content of ``summary.json``.
    """

    status: str
    message: str
    out_dir: Path
    summary: dict[str, Any] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return self.status == "completed"


class StopRequest:
    """A thread-safe cancel flag that remembers who asked; usable as ``cancel=``.

    ``request("SIGTERM")`` from a signal handler or another thread; the run stops at the
    solver's next check and its message names the reason.
    """

    def __init__(self) -> None:
        self._event = threading.Event()
        self.reason = ""

    def request(self, reason: str = "stop requested") -> None:
        if not self._event.is_set():
            self.reason = reason
        self._event.set()

    @property
    def requested(self) -> bool:
        return self._event.is_set()

    def __call__(self) -> bool:
        return self._event.is_set()


def default_results_dir(project_path: str | os.PathLike[str]) -> Path:
    """``NAME.results`` next to the project file ``NAME.toml``."""
    path = Path(project_path)
    return path.with_name(path.stem + RESULTS_SUFFIX)


def _check_out_dir(out_dir: Path, overwrite: bool = False) -> None:
    """Refuse early (before any solver work) an output folder that must not be used."""
    check_results_dir(out_dir, overwrite=overwrite)


def _solver_rejects(err: Exception) -> Exception:
    """The solver's own input check as a project problem (one line for the command line)."""
    from projects.schema import Problem, ProjectError

    return ProjectError([Problem("", None, f"the solver rejects this run: {err}")])


def check_project(
    project: Project,
    *,
    arch: str | None = None,
    force: bool = False,
    out_dir: str | os.PathLike[str] | None = None,
) -> Any:
    """Build a project into a run and apply the solver's input checks, without running it.

    The size of the run is checked first (:func:`projects.limits.check_limits`), before any
    memory is taken for particles.

    Parameters
    ----------
    project : Project
    arch : {"cpu", "gpu", "auto"}, optional
    force : bool
        Skip the size limits (the command line's ``--force``).
    out_dir : path-like, optional
        Where the results would go (for the free-disk check).

    Returns
    -------
    projects.build.BuiltRun

    Raises
    ------
    projects.schema.ProjectError
        For problems of the project and for runs the solver would refuse (particles outside
        the grid, inconsistent stages, ...).
    """
    from projects.build import build_simulation
    from solver.simulation import validate

    check_size(project, force=force, out_dir=out_dir)
    built = build_simulation(project, arch_override=arch)
    try:
        validate(built.config, built.particles)
    except SolverError as err:
        raise _solver_rejects(err) from None
    return built


def check_size(project: Project, *, force: bool = False, out_dir: str | os.PathLike[str] | None = None) -> None:
    """Estimate the run's size (no allocation) and raise ProjectError beyond the limits."""
    from projects.build import estimate
    from projects.limits import check_limits

    check_limits(estimate(project), force=force, out_dir=out_dir)


def _meta(project: Project, built: Any, sim: Any, project_path: Path | None) -> dict[str, Any]:
    """Summary entries known before the run starts."""
    config = built.config
    grid = config.grid
    cells = grid.cells
    volumes = np.asarray(built.particles.volumes_m2, dtype=float)
    meta: dict[str, Any] = {
        "title": project.runout.title,
        "scheme": config.numerics.scheme,
        "arch": sim.arch,
        "precision": sim.precision,
        "particles": len(built.particles),
        "total_time_s": float(sim.total_time_s),
        "stages": [stage.name for stage in config.stages],
        "materials": list(built.material_names),
        "bodies": list(built.body_names),
        "domain": {
            "origin_m": [float(v) for v in grid.origin_m],
            "size_m": [cells[0] * grid.cell_size_m, cells[1] * grid.cell_size_m],
            "cell_size_m": grid.cell_size_m,
        },
        # side of the square a particle stands for; the renderer sizes points with it
        "particle_spacing_m": float(np.sqrt(np.median(volumes))) if volumes.size else 0.0,
        "output_interval_s": config.output.interval_s,
    }
    if project_path is not None:
        meta["project_file"] = str(project_path)
    return meta


def run_project(
    project: Project,
    out_dir: str | os.PathLike[str] | None = None,
    *,
    project_path: str | os.PathLike[str] | None = None,
    arch: str | None = None,
    cancel: Callable[[], bool] | None = None,
    on_frame: Callable[[Frame], None] | None = None,
    on_progress: Callable[[Progress], None] | None = None,
    overwrite: bool = False,
    force: bool = False,
) -> RunResult:
    """Run a validated project and write its results folder as frames arrive.

    Parameters
    ----------
    project : Project
        The validated project (overrides already applied).
    out_dir : path-like, optional
        Results folder. Default: :func:`default_results_dir` of ``project_path``. An earlier
        run's results there are replaced only with ``overwrite``; another non-empty folder is
        refused.
    project_path : path-like, optional
        The project file (for the default folder and the summary).
    arch : {"cpu", "gpu", "auto"}, optional
        Overrides ``numerics.arch``.
    cancel : callable, optional
        Polled by the solver; returning True stops the run after one last frame (status
        ``"stopped"``). A :class:`StopRequest` adds its reason to the message.
    on_frame : callable, optional
        Called with every frame after it is handed to the writer (live views).
    on_progress : callable, optional
        Called with the solver's :class:`~solver.simulation.Progress`.
    overwrite : bool
        Replace an earlier run's results in ``out_dir`` (only that run's own files).
    force : bool
        Run even beyond the size limits (:mod:`projects.limits`).

    Returns
    -------
    RunResult
        ``status`` is "completed", "stopped" (cancel, Ctrl-C) or "failed" (instability, any
        error during the run, with the reason in ``message``). KeyboardInterrupt during the
        run becomes "stopped"; nothing is raised once the results folder exists.

    Raises
    ------
    ValueError
        Neither ``out_dir`` nor ``project_path`` given.
    projects.schema.ProjectError
        The project cannot be built into a run, the solver rejects the built run, or the run
        is beyond the size limits (without ``force``).
    projects.results.ResultsError
        ``out_dir`` cannot be used: an earlier run's results without ``overwrite``
        (:class:`~projects.results.ResultsExistError`), another run writing into it
        (:class:`~projects.results.ResultsLockedError`), not a results folder, not writable.
    """
    from projects.build import build_simulation
    from projects.document import dumps_project
    from projects.presets import apply_preset

    project = apply_preset(project)  # project.toml records the values the preset stood for
    if out_dir is None:
        if project_path is None:
            raise ValueError("give out_dir or project_path (the results go next to the project file)")
        out_dir = default_results_dir(project_path)
    out_path = Path(out_dir).expanduser().absolute()
    _check_out_dir(out_path, overwrite)
    path = Path(project_path).absolute() if project_path is not None else None

    started = time.perf_counter()
    check_size(project, force=force, out_dir=out_path)
    built = build_simulation(project, arch_override=arch)
    # importing the simulation loads Taichi: do it only when a run really starts
    from solver.simulation import Simulation

    try:
        sim = Simulation(built.config, built.particles)
    except SolverError as err:
        raise _solver_rejects(err) from None
    except (MemoryError, OverflowError, RuntimeError, ValueError) as err:  # e.g. --force past the limits
        first_line = (str(err).strip().splitlines() or [""])[0]
        raise _solver_rejects(f"{type(err).__name__}: {first_line}") from None
    try:
        writer = ResultsWriter(out_path, dumps_project(project), _meta(project, built, sim, path),
                               overwrite=overwrite)
        return _run(sim, built, writer, started, cancel, on_frame, on_progress)
    finally:
        sim.close()


def _run(
    sim: Any,
    built: Any,
    writer: ResultsWriter,
    started: float,
    cancel: Callable[[], bool] | None,
    on_frame: Callable[[Frame], None] | None,
    on_progress: Callable[[Progress], None] | None,
) -> RunResult:
    """Advance the run, hand its frames to the writer and close it with the final status,
    whatever happens (the writer removes its temporary files and releases the lock)."""
    setup_s = time.perf_counter() - started
    status, message = "failed", "the run ended unexpectedly"
    loop_start = time.perf_counter()
    try:
        for frame in sim.run(cancel=cancel, on_progress=on_progress):
            writer.write_frame(frame)
            if on_frame is not None:
                on_frame(frame)
        status = sim.status if sim.status in ("completed", "stopped") else "completed"
        message = sim.message
        if status == "stopped" and isinstance(cancel, StopRequest) and cancel.reason:
            message = f"stopped by {cancel.reason}: {message}" if message else f"stopped by {cancel.reason}"
    except KeyboardInterrupt:
        status, message = "stopped", f"interrupted (Ctrl-C) at t = {sim.time_s:.4g} s"
    except InstabilityError as err:
        status, message = "failed", str(err)
    except ResultsError as err:
        status, message = "failed", str(err)
    except OSError as err:  # a results disk error raised outside the writer thread
        status, message = "failed", f"writing results failed: {err.strerror or err}"
    except Exception as err:  # noqa: BLE001 - any solver failure must still close the folder
        # the traceback is for developers; users get the message in the summary
        logger.error("the run failed: %s", err, exc_info=logger.isEnabledFor(logging.DEBUG))
        status, message = "failed", f"{type(err).__name__}: {err}"
    except BaseException as err:  # SystemExit and the like: record it, then let it go on
        status, message = "failed", f"ended by {type(err).__name__}"
        raise
    finally:
        loop_s = time.perf_counter() - loop_start
        particles = len(built.particles)
        summary = writer.close(
            status,
            message,
            steps=int(sim.steps),
            simulated_time_s=float(sim.time_s),
            wall_time_s=time.perf_counter() - started,
            particle_steps_per_s=particles * sim.steps / loop_s if loop_s > 0 else 0.0,
            extra={"setup_time_s": setup_s, **_equilibrium(sim)},
        )
    logger.info("run %s: %s", summary["status"], summary["message"])
    return RunResult(summary["status"], summary["message"], writer.out_dir, summary)


def _equilibrium(sim: Any) -> dict[str, Any]:
    """The initial equilibrium check of the solver, when it made one (for ``summary.json``)."""
    check = getattr(sim, "equilibrium", None)
    return {"initial_equilibrium": check} if check else {}
