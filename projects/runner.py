"""Running a project: build the solver run, advance it and write the results folder.

:func:`run_project` is what the command line, the GUI worker and the tests call. It never leaves
a results folder without a final status: whichever way the run ends (completed, cancelled,
Ctrl-C, instability, any solver error, a results disk error) the writer is closed and
``summary.json`` says what happened. Problems with the input (an invalid project or one the solver
rejects, both as :class:`~projects.schema.ProjectError`; an output folder that must not be
replaced, :class:`~projects.results.ResultsError`) are raised before anything is written.

Output folder policy (:mod:`projects.results_folder`): by default ``NAME.results/`` next to the
project file ``NAME.toml``. A folder holding an earlier run's results is replaced only with
``overwrite=True`` (the command line's ``--overwrite``), and then only the files that run wrote
are removed; any other non-empty folder is refused; a folder another run is writing into is
refused. The folder is locked while the run writes.
"""

from __future__ import annotations

import logging
import os
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from projects.results import ResultsError, ResultsWriter, is_results_dir
from projects.results_folder import check_results_dir, lock_holder
from solver.config import InstabilityError, SolverError


def runout_command(*args: str) -> list[str]:
    """``runout ARGS`` as a child process of this Python (the workbench's runs, sweeps' runs).

    ``python -m app`` is the ``runout`` script's own path: it takes ``app.__main__``'s start-up
    settings and the command line's cached bytecode, where ``-m app.cli`` would compile that
    module afresh in every process (a ``__main__`` is never cached).
    """
    return [sys.executable, "-m", "app", *args]

if TYPE_CHECKING:  # pragma: no cover - typing only
    from projects.build import ResolvedRun
    from projects.schema import Project
    from solver.config import Checkpoint, Frame
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

    A repeated Ctrl-C may interrupt a solver that does not reach its next check
    (:func:`app.console.stop_on_signals` raises KeyboardInterrupt when :meth:`may_interrupt`
    says so): once, and never after the run has begun to finish its results folder
    (:meth:`finishing`), so that Ctrl-C pressed three times 20-50 ms apart still leaves a final
    ``summary.json`` and no lock (the third one landed in the writer's close and left the folder
    "running" and locked in 7 of 8 tries).
    """

    def __init__(self) -> None:
        self._event = threading.Event()
        self.reason = ""
        self._interrupted = False
        self._finishing = False

    def may_interrupt(self) -> bool:
        """Whether a repeated Ctrl-C may raise KeyboardInterrupt now (True once, before finishing)."""
        if self._interrupted or self._finishing:
            return False
        self._interrupted = True
        return True

    def finishing(self) -> None:
        """The run is finishing its results folder (or has): Ctrl-C no longer interrupts it."""
        self._finishing = True

    def request(self, reason: str = "stop requested") -> None:
        if not self._event.is_set():
            self.reason = reason
        self._event.set()

    @property
    def requested(self) -> bool:
        return self._event.is_set()

    def __call__(self) -> bool:
        return self._event.is_set()


def process_age_s() -> float | None:
    """Seconds since this process started (Linux ``/proc``; None elsewhere)."""
    try:
        with open("/proc/self/stat", encoding="ascii") as handle:
            start_ticks = int(handle.read().rsplit(")", 1)[1].split()[19])
        with open("/proc/uptime", encoding="ascii") as handle:
            uptime_s = float(handle.read().split()[0])
        return uptime_s - start_ticks / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError):
        return None


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
    project: Project | ResolvedRun,
    *,
    arch: str | None = None,
    force: bool = False,
    out_dir: str | os.PathLike[str] | None = None,
) -> ResolvedRun:
    """Resolve a project into its run and apply the solver's input checks, without running it.

    The size of the run is checked first (:func:`projects.limits.check_limits` on the resolved
    run's estimate), before any memory is taken for particles.

    Parameters
    ----------
    project : Project or ResolvedRun
    arch : {"cpu", "gpu", "auto"}, optional
    force : bool
        Skip the size limits (the command line's ``--force``).
    out_dir : path-like, optional
        Where the results would go (for the free-disk check).

    Returns
    -------
    projects.build.ResolvedRun
        Seeded.

    Raises
    ------
    projects.schema.ProjectError
        For problems of the project, runs beyond the size limits and runs the solver would
        refuse (particles outside the grid, inconsistent stages, ...).
    """
    from projects.build import ResolvedRun, estimate, resolve
    from projects.limits import check_limits
    from projects.presets import apply_preset
    from solver.simulation import validate

    if not isinstance(project, ResolvedRun):
        # the limits before the configuration is built: it holds the hazard raster's floor under
        # the structures, one value per raster column (1e-9 m cells over a 0.6 m domain with a
        # structure took minutes and gigabytes in validate before any limit was looked at)
        check_limits(estimate(apply_preset(project)), force=force, out_dir=out_dir)
    resolved = project if isinstance(project, ResolvedRun) else resolve(project, arch=arch, seed=False)
    if resolved.particles is None:
        check_limits(resolved.estimate, force=force, out_dir=out_dir)
        resolved = resolved.seeded()
    try:
        validate(resolved.config, resolved.particles)
    except SolverError as err:
        raise _solver_rejects(err) from None
    return resolved


def run_project(
    project: Project | ResolvedRun,
    out_dir: str | os.PathLike[str] | None = None,
    *,
    project_path: str | os.PathLike[str] | None = None,
    unsaved: bool = False,
    arch: str | None = None,
    cancel: Callable[[], bool] | None = None,
    on_frame: Callable[[Frame], None] | None = None,
    on_progress: Callable[[Progress], None] | None = None,
    overwrite: bool = False,
    force: bool = False,
    start_from: str | os.PathLike[str] | None = None,
) -> RunResult:
    """Run a project and write its results folder as frames arrive.

    Parameters
    ----------
    project : Project or ResolvedRun
        The validated project (overrides applied), or its resolved run.
    out_dir : path-like, optional
        Results folder. Default: :func:`default_results_dir` of ``project_path``. An earlier
        run's results there are replaced only with ``overwrite``; another non-empty folder is
        refused.
    project_path : path-like, optional
        The project file (for the default folder and the summary's ``project_file``).
    unsaved : bool
        The project holds edits not saved in ``project_path``, or has no file (a run from the
        workbench): the summary's ``project_unsaved``.
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
    start_from : path-like, optional
        A checkpoint (``checkpoint.npz`` or the results folder holding it) of another run of the
        same particles: this run's stages start from its particle state (positions, velocities,
        stresses, plastic strains) instead of the seeded one.

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
        The project cannot be resolved into a run, the solver rejects the run, or the run is
        beyond the size limits (without ``force``).
    projects.results.ResultsError
        ``out_dir`` cannot be used: an earlier run's results without ``overwrite``
        (:class:`~projects.results.ResultsExistError`), another run writing into it
        (:class:`~projects.results.ResultsLockedError`), not a results folder, not writable;
        ``start_from`` holds no usable checkpoint.
    """
    from projects.document import dumps_project
    from projects.results import read_checkpoint

    if out_dir is None:
        if project_path is None:
            raise ValueError("give out_dir or project_path (the results go next to the project file)")
        out_dir = default_results_dir(project_path)
    out_path = Path(out_dir).expanduser().absolute()
    _check_out_dir(out_path, overwrite)
    path = Path(project_path).absolute() if project_path is not None else None
    initial = read_checkpoint(start_from) if start_from is not None else None

    started = time.perf_counter()
    resolved = check_project(project, arch=arch, force=force, out_dir=out_path)
    sim = _simulation(resolved)
    try:
        if initial is not None:
            _start_from(sim, initial, start_from, resolved)
        meta = _meta(resolved, sim, path, unsaved)
        if start_from is not None:
            meta["started_from"] = str(Path(start_from).absolute())
        writer = ResultsWriter(out_path, dumps_project(resolved.project), meta, overwrite=overwrite)
        return _run_finished(sim, resolved, writer, started, cancel, on_frame, on_progress)
    finally:
        sim.close()


def resumable(results_dir: str | os.PathLike[str]) -> Checkpoint:
    """The checkpoint of a run that ``resume_run`` can continue (cheap: no solver is built).

    Raises
    ------
    projects.results.ResultsError
        Not a results folder with its project.toml, no readable checkpoint, or a complete run.
    """
    from projects.results import CHECKPOINT_NAME, PROJECT_NAME, read_checkpoint

    out_path = Path(results_dir).expanduser().absolute()
    if not is_results_dir(out_path) or not (out_path / PROJECT_NAME).is_file():
        raise ResultsError(f"{out_path} is not a results folder with its project.toml")
    holder = lock_holder(out_path)
    if holder is not None:  # still running: it may have no checkpoint yet, and it must not be run twice
        who = f"process {holder}" if holder > 0 else "another process"
        raise ResultsError(f"{out_path} is in use by another run ({who}): it is still running, nothing to resume")
    if not (out_path / CHECKPOINT_NAME).is_file() and _has_strength_reduction(out_path / PROJECT_NAME):
        raise ResultsError(f"{out_path}: a strength-reduction run cannot be resumed (its search lives in memory "
                           "and writes no checkpoint part-way); run it again")
    if not (out_path / CHECKPOINT_NAME).is_file():
        raise ResultsError(f"no checkpoint in {out_path}: the run ended before its first checkpoint; "
                           "run the project again into it with --overwrite")
    checkpoint = read_checkpoint(out_path)
    if checkpoint.run["cursor"]["phase"] == "done":
        raise ResultsError(f"the run in {out_path} is complete: nothing to resume")
    return checkpoint


def _has_strength_reduction(project_file: Path) -> bool:
    """Whether the project file has a strength-reduction stage (False when it cannot be read)."""
    from projects.document import parse_toml
    from projects.schema import ProjectError

    try:
        stages = parse_toml(project_file.read_text(encoding="utf-8")).get("stages") or []
    except (OSError, ValueError, ProjectError):
        return False
    return any(isinstance(st, dict) and st.get("type") == "strength-reduction" for st in stages)


def resume_run(
    results_dir: str | os.PathLike[str],
    *,
    arch: str | None = None,
    cancel: Callable[[], bool] | None = None,
    on_frame: Callable[[Frame], None] | None = None,
    on_progress: Callable[[Progress], None] | None = None,
    checkpoint: Checkpoint | None = None,
    force: bool = False,
) -> RunResult:
    """Continue a killed, stopped or failed run from the last checkpoint in its results folder.

    The run is rebuilt from the folder's ``project.toml`` (the project as it ran), its state
    restored from ``checkpoint.npz``; the frames written after that checkpoint are written
    again. The frames are those of an uninterrupted run (bit for bit with the serial scatter).

    ``checkpoint`` is the folder's checkpoint as :func:`resumable` returned it (read from the
    folder when not given). The size limits are checked as for a new run, before anything is
    allocated (the folder's project.toml may have been edited, or the run needed ``force``).

    Raises
    ------
    projects.results.ResultsError
        Not a results folder, no checkpoint, or a checkpoint of another run.
    projects.schema.ProjectError
        The folder's ``project.toml`` is not a valid project, or beyond the size limits (without
        ``force``).
    """
    from projects.document import dumps_project, load_project
    from projects.results import PROJECT_NAME, write_checkpoint

    started = time.perf_counter()
    out_path = Path(results_dir).expanduser().absolute()
    if checkpoint is None:
        checkpoint = resumable(out_path)
    resolved = check_project(load_project(out_path / PROJECT_NAME), arch=arch, force=force)
    original = checkpoint
    checkpoint = _without_stop_frame(checkpoint, out_path, resolved.config.output.interval_s,
                                     [st.name for st in resolved.config.structures])
    checkpoint = _with_frames_on_disk(checkpoint, out_path, resolved.config.output.interval_s)
    sim = _simulation(resolved)
    try:
        try:
            sim.restore(checkpoint)
        except SolverError as err:
            raise ResultsError(f"cannot resume {out_path}: {err}") from None
        if checkpoint is not original:
            # the folder's checkpoint says what the writer below is about to make of the folder
            # (the stop frame removed) before it does: a resume killed after the writer's take-over
            # and before its first checkpoint left a folder of one frame less than its checkpoint
            # needed, which no later resume could continue ("holds 34 complete frames, the
            # checkpoint needs 35"); now every later resume starts from the same place
            try:
                write_checkpoint(out_path, checkpoint)
            except OSError as err:
                raise ResultsError(f"cannot resume {out_path}: writing its checkpoint failed: "
                                   f"{err.strerror or err}") from None
        meta = _meta(resolved, sim, None)
        writer = ResultsWriter(out_path, dumps_project(resolved.project), meta,
                               keep_frames=int(checkpoint.run["cursor"]["frames"]))
        logger.info("resuming %s at t = %.6g s (step %d)", out_path, sim.time_s, sim.steps)
        return _run_finished(sim, resolved, writer, started, cancel, on_frame, on_progress)
    finally:
        sim.close()


def _without_stop_frame(checkpoint: Checkpoint, out_path: Path, interval_s: float,
                        structures: list[str]) -> Checkpoint:
    """The checkpoint of a stopped run as if its stop frame had not been written.

    A stop (SIGTERM, Ctrl-C, the workbench's Stop) ends a run with one more frame at the stop
    time, between two output times, and its checkpoint there. The uninterrupted run has no frame
    at that time, so the resumed run writes the frames from the one before it on: the stop frame
    and its rows are written over, and the impulse and peak force the stop frame reported go back
    into the contact accumulators, so that the next row of ``contacts.csv`` gives the force over
    the whole output interval, as the uninterrupted run does. Any other checkpoint (at an output
    time, at a stage's early end, at the end of a stage) is returned as it is.
    """
    import dataclasses
    import math

    import numpy as np

    from projects.results import open_results, read_contacts
    from solver.config import SIDES

    run, cursor = checkpoint.run, checkpoint.run.get("cursor", {})
    t = float(run.get("time_s", 0.0))
    previous_output_s = float(cursor.get("next_output_s", 0.0)) - interval_s
    frames = int(cursor.get("frames", 0))
    if (cursor.get("phase") != "loop" or cursor.get("reason") or frames < 2
            or t <= previous_output_s + 1e-6 * interval_s):
        return checkpoint
    try:
        times = open_results(out_path).series["time_s"]
        contacts = read_contacts(out_path) if (out_path / "contacts.csv").is_file() else {}
    except (OSError, ValueError, KeyError):
        return checkpoint
    if len(times) < frames or not math.isclose(float(times[frames - 1]), t, rel_tol=1e-12, abs_tol=1e-12):
        return checkpoint
    since_s = float(times[frames - 2])
    arrays = dict(checkpoint.arrays)
    if "contact_impulse" in arrays and "contact_peak" in arrays:
        impulse = np.zeros_like(arrays["contact_impulse"])
        peak = np.zeros_like(arrays["contact_peak"])
        moment = np.zeros(len(impulse))
        names = list(SIDES) + structures  # the engine's order of contacts
        for c, name in enumerate(names[: len(impulse)]):
            rows = contacts.get(name)
            if rows is None or not len(rows["time_s"]):
                continue
            k = int(np.argmin(np.abs(rows["time_s"] - t)))
            if not math.isclose(float(rows["time_s"][k]), t, rel_tol=1e-12, abs_tol=1e-12):
                continue
            impulse[c] = (rows["force_x_N_per_m"][k] * (t - since_s), rows["force_y_N_per_m"][k] * (t - since_s))
            peak[c] = (rows["peak_force_N_per_m"][k], rows["peak_force_x_N_per_m"][k], rows["peak_force_y_N_per_m"][k])
            if "moment_N_m_per_m" in rows and math.isfinite(rows["moment_N_m_per_m"][k]):
                moment[c] = rows["moment_N_m_per_m"][k] * (t - since_s)
        arrays["contact_impulse"], arrays["contact_peak"] = impulse, peak
        if "contact_moment" in arrays:  # (older checkpoints have none)
            arrays["contact_moment"] = moment
    # last_output_step -1: a stop at a stage's last step still gets that stage's end frame
    run = {**run, "contacts_since_s": since_s, "cursor": {**cursor, "frames": frames - 1, "last_output_step": -1}}
    return dataclasses.replace(checkpoint, run=run, arrays=arrays)


def _with_frames_on_disk(checkpoint: Checkpoint, out_path: Path, interval_s: float) -> Checkpoint:
    """A stop checkpoint whose stop frame is already gone from the folder, continued from the frame
    before it (as :func:`_without_stop_frame` does while the frame is there).

    A resume killed after it had removed the stop frame and before it wrote a checkpoint of its own
    (a folder left so by an earlier version) holds one frame less than its checkpoint says. Its
    run continues from the stop's state with the frames before the stop kept; the contact forces
    of the next output interval are averaged from the stop on (the rows of the stop frame, which
    held the impulse up to it, went with the frame). Any other checkpoint is returned as it is
    (the writer refuses a folder with fewer frames than it needs, naming what to do).
    """
    import dataclasses
    import math

    from projects.results import open_results

    run, cursor = checkpoint.run, checkpoint.run.get("cursor", {})
    t = float(run.get("time_s", 0.0))
    frames = int(cursor.get("frames", 0))
    previous_output_s = float(cursor.get("next_output_s", 0.0)) - interval_s
    if (cursor.get("phase") != "loop" or cursor.get("reason") or frames < 2
            or t <= previous_output_s + 1e-6 * interval_s):
        return checkpoint  # not a stop between two output times
    try:
        times = open_results(out_path).series["time_s"]
    except (OSError, ValueError, KeyError, ResultsError):
        return checkpoint
    if len(times) != frames - 1 or not math.isclose(float(times[-1]), previous_output_s, rel_tol=1e-9,
                                                     abs_tol=1e-9 * interval_s):
        return checkpoint
    logger.warning("%s: the stop frame at t = %.6g s is gone; resuming from the frame before it", out_path, t)
    run = {**run, "contacts_since_s": t, "cursor": {**cursor, "frames": frames - 1, "last_output_step": -1}}
    return dataclasses.replace(checkpoint, run=run)


def run_resolved(
    resolved: ResolvedRun,
    *,
    cancel: Callable[[], bool] | None = None,
    on_frame: Callable[[Frame], None] | None = None,
    on_progress: Callable[[Progress], None] | None = None,
) -> RunResult:
    """Run a resolved run without a results folder (studies that only look at the frames).

    The same run loop as :func:`run_project`; ``out_dir`` of the result is empty and its
    summary holds ``steps``, ``simulated_time_s``, ``wall_time_s`` and ``particle_steps_per_s``.
    """
    started = time.perf_counter()
    check_project(resolved)
    sim = _simulation(resolved)
    try:
        return _run(sim, resolved, None, started, cancel, on_frame, on_progress)
    finally:
        sim.close()


def _simulation(resolved: ResolvedRun) -> Any:
    # importing the simulation loads Taichi: do it only when a run really starts
    from projects.strength import settings_of, trial_loads
    from solver.simulation import Simulation

    try:
        # strength-reduction trials step with local damping whatever the stages say, under their loads
        surcharges, seismic = trial_loads(resolved.project)
        return Simulation(resolved.config, resolved.particles,
                          damping_support=settings_of(resolved.project) is not None,
                          surcharge_support=bool(surcharges), seismic_support=seismic is not None)
    except SolverError as err:
        raise _solver_rejects(err) from None
    except (MemoryError, OverflowError, RuntimeError, ValueError) as err:  # e.g. --force past the limits
        first_line = (str(err).strip().splitlines() or [""])[0]
        raise _solver_rejects(f"{type(err).__name__}: {first_line}") from None


def _start_from(sim: Any, checkpoint: Any, source: Any, resolved: ResolvedRun) -> None:
    """Load another run's particle state into a fresh simulation (its own stages then run).

    The other run must have this project's particles: as many, of the same materials and masses,
    seeded at the same places (checked against its folder's project.toml where there is one), so
    that a folder of another scene with as many particles is refused, not silently taken.
    """
    import numpy as np

    from projects.build import resolve
    from projects.document import load_project
    from projects.schema import ProjectError

    def refuse(why: str) -> ResultsError:
        return ResultsError(f"cannot start from {source}: its particles are not this project's ({why})")

    arrays = {k: v for k, v in checkpoint.arrays.items() if k in sim.engine.PARTICLE_STATE and k != "band"}
    own = sim.engine.state(("mat", "m"))
    if "mat" in arrays and np.shape(arrays["mat"]) == np.shape(own["mat"]):
        if not np.array_equal(arrays["mat"], own["mat"]):
            raise refuse("other materials")
        if "m" in arrays and not np.allclose(arrays["m"], own["m"], rtol=1e-5, atol=0.0):
            raise refuse("other masses: another density or particle volume")
    folder = Path(source)
    folder = folder if folder.is_dir() else folder.parent
    try:
        theirs = resolve(load_project(folder / "project.toml")).seeded().particles
    except (OSError, ProjectError, ValueError):
        theirs = None  # a bare checkpoint file: the engine's checks below
    if theirs is not None and len(theirs.positions_m) == len(resolved.particles.positions_m):
        size = max(resolved.project.domain.size_m)
        if not np.allclose(theirs.positions_m, resolved.particles.positions_m, rtol=0.0, atol=1e-9 * size):
            raise refuse("seeded at other places")
    _outside_structures(arrays, resolved, source)
    try:
        sim.engine.load_state(arrays)
    except ValueError as err:
        raise refuse(str(err)) from None


def _outside_structures(arrays: dict[str, Any], resolved: ResolvedRun, source: Any) -> None:
    """Refuse a state with particles inside this project's structures (a structure added where the
    other run's material has moved to): the solver never leaves a particle inside a structure, and
    one that starts inside has no path to push it back along (it would be pushed to the nearest
    face, into a neighbouring structure or out of a thin one)."""
    import numpy as np

    from solver.engine import PUSH_OUT_CELLS
    from solver.structures import signed_distance

    project = resolved.project
    if not project.structures or "x" not in arrays:
        return
    x = np.asarray(arrays["x"], dtype=np.float64).reshape(-1, 2) + np.asarray(project.domain.origin_m, float)
    if "active" in arrays and np.size(arrays["active"]) == len(x):
        x = x[np.asarray(arrays["active"]).reshape(-1) != 0]
    # the solver leaves pushed-out particles PUSH_OUT_CELLS outside; half of it absorbs rounding
    depth = 0.5 * PUSH_OUT_CELLS * project.domain.cell_size_m
    for i, structure in enumerate(project.structures):
        inside = int(np.count_nonzero(signed_distance(x, structure.polygon_m) < -depth))
        if inside:
            raise ResultsError(
                f"cannot start from {source}: {inside} of its particles lie inside structures.{i} "
                f"({structure.name!r}); move the structure or start without --start-from")


def _meta(resolved: ResolvedRun, sim: Any, project_path: Path | None, unsaved: bool = False) -> dict[str, Any]:
    """Summary entries known before the run starts."""
    meta = resolved.meta()
    meta["arch"] = sim.arch
    meta["total_time_s"] = float(sim.total_time_s)
    meta["checkpoint_interval_s"] = resolved.checkpoint_interval_s
    if project_path is not None:
        meta["project_file"] = str(project_path)
    if unsaved:
        meta["project_unsaved"] = True
    return meta


def _run_finished(sim: Any, resolved: ResolvedRun, writer: ResultsWriter, started: float, cancel: Any,
                  on_frame: Any, on_progress: Any) -> RunResult:
    """:func:`_run` into an open writer, which is closed whatever happens: a Ctrl-C that lands
    before the run loop's own handling (between the writer's start and its first statement) still
    leaves a final ``summary.json`` ("stopped") and no lock."""
    try:
        return _run(sim, resolved, writer, started, cancel, on_frame, on_progress)
    except KeyboardInterrupt:
        if writer.closed:
            raise
        if isinstance(cancel, StopRequest):
            cancel.finishing()
        summary = writer.close("stopped", "interrupted (Ctrl-C) before the first step")
        return RunResult(summary["status"], summary["message"], writer.out_dir, summary)
    except BaseException:
        if not writer.closed:
            writer.close("failed", "the run ended before its first step")
        raise


def _run(
    sim: Any,
    resolved: ResolvedRun,
    writer: ResultsWriter | None,
    started: float,
    cancel: Callable[[], bool] | None,
    on_frame: Callable[[Frame], None] | None,
    on_progress: Callable[[Progress], None] | None,
) -> RunResult:
    from projects.hazard import HazardOutput, settings
    from projects.results import write_checkpoint
    from projects.strength import TRIALS_NAME, strength_reduction

    status, message = "failed", "the run ended unexpectedly"
    setup_s = time.perf_counter() - started
    loop_start = time.perf_counter()
    steps0 = sim.steps
    interval = resolved.checkpoint_interval_s
    last_checkpoint_s = sim.time_s
    driver = hazard = watch = None
    all_lost_at = None  # when every particle had left the grid (a body far too fast, a wrong gravity)

    def save_checkpoint() -> None:
        # frames first: a checkpoint on disk promises every frame up to its own
        writer.flush()
        write_checkpoint(writer.out_dir, sim.checkpoint())

    try:  # from here on every way out finishes the folder (its setup too: a Ctrl-C may land in it)
        driver = strength_reduction(resolved)  # None unless the project has a strength-reduction stage
        if writer is not None:
            from projects import hazard as hazard_files

            for name in (hazard_files.HAZARD_JSON, hazard_files.PROFILE_CSV, hazard_files.TARGETS_CSV,
                         hazard_files.HAZARD_VTI):
                writer.own(name)
            if driver is not None:
                writer.own(TRIALS_NAME)
            hazard = HazardOutput(writer.out_dir, sim, settings(resolved.project), writer.submit)
        watch = _FailureWatch(sim, settings(resolved.project), writer.out_dir if writer is not None else None)
        setup_s = time.perf_counter() - started
        loop_start = time.perf_counter()
        frames = (sim.run(cancel=cancel, on_progress=on_progress) if driver is None
                  else driver.run(sim, cancel=cancel, on_progress=on_progress))
        for frame in frames:
            watch.see(frame)
            if all_lost_at is None and frame.diagnostics.lost_particles >= resolved.particle_count > 0:
                all_lost_at = float(frame.diagnostics.time_s)
            if writer is not None:
                writer.write_frame(frame)
                hazard.write()  # the envelopes with every frame: a killed run keeps them
            if on_frame is not None:
                on_frame(frame)
            t = frame.diagnostics.time_s
            stopping = cancel is not None and cancel()
            # a strength-reduction run is not resumable part-way (its search lives in memory)
            if writer is not None and driver is None and sim.can_checkpoint and (
                    stopping or t >= last_checkpoint_s + interval * (1 - 1e-9)):
                save_checkpoint()
                last_checkpoint_s = t
        if writer is not None and sim.can_checkpoint:  # the end state: later runs may start from it
            save_checkpoint()
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
        if isinstance(cancel, StopRequest):
            cancel.finishing()  # no KeyboardInterrupt from a Ctrl-C from here on: the folder is finished
        motion = _motion(sim, resolved, status)
        if hazard is not None and status in ("completed", "stopped"):
            try:
                hazard.write(status, motion)
            except Exception as err:  # noqa: BLE001 - the run's own outcome stands; say what is missing
                logger.error("writing the hazard files failed: %s", err)
        loop_s = time.perf_counter() - loop_start
        particles = resolved.particle_count
        steps = sim.steps - steps0
        numbers = {
            "steps": int(sim.steps),
            "simulated_time_s": float(sim.time_s),
            "wall_time_s": time.perf_counter() - started,
            "particle_steps_per_s": particles * steps / loop_s if loop_s > 0 else 0.0,
        }
        extra = {"setup_time_s": setup_s, **_equilibrium(sim), **(watch.summary() if watch is not None else {}),
                 # whether the answer is final: the mass at rest at the end (projects.motion)
                 "still_moving": None if motion is None else motion["still_moving"], "motion_at_end": motion,
                 # the stability limit at rest (material damping shortens it: docs/solver.md)
                 "critical_time_step_s": float(sim.critical_time_step()),
                 "time_step_shrink_by_damping": float(resolved.estimate["time_step_shrink_by_damping"])}
        if all_lost_at is not None:
            # the run "completed" while nothing was left in it (an initial velocity of 1e6 m/s): said
            # in summary.json's warnings and on the command line
            extra["warnings"] = [f"every particle had left the grid by t = {all_lost_at:.4g} s (lost_particles in "
                                 "series.csv): the results after that hold nothing to measure"]
        if sim.first_step_at is not None and process_age_s() is not None:
            # process start to the end of its first step: what a run as a process costs to start
            extra["startup_s"] = process_age_s() - (time.perf_counter() - sim.first_step_at)
            # the same span in CPU seconds of the process (less disturbed by other work on the machine)
            extra["startup_cpu_s"] = sim.first_step_cpu_s
        if sim.first_step_at is not None and steps > 1:
            # wall seconds per step after the first (frames, envelopes and checks included): what
            # the pre-run estimate's cost model is measured on (projects.cost)
            extra["step_time_s"] = (loop_start + loop_s - sim.first_step_at) / (steps - 1)
        if driver is not None:
            extra.update(driver.summary())
            if writer is not None:
                try:
                    driver.write_files(writer.out_dir)
                except OSError as err:
                    logger.error("could not write the strength-reduction trials: %s", err)
        if writer is not None:
            summary = writer.close(status, message, **numbers, extra=extra)
        else:
            summary = {"status": status, "message": message, **numbers, **extra}
    logger.info("run %s: %s", summary["status"], summary["message"])
    return RunResult(summary["status"], summary["message"], writer.out_dir if writer else Path(), summary)


class _FailureWatch:
    """Where the ground water was when the slope failed, for ``summary.json``'s ``water_at_failure``.

    The slope has failed when, by the end of the run, a particle has moved more than the hazard's
    ``mobilised_displacement_m`` (one cell by default) in the dynamic stages; the failure began at
    the first frame of a dynamic stage whose kinetic energy reached the hazard's
    ``kinetic_energy_fraction`` of the run's peak (the measure that ends the slide, read from its
    start). A resumed run reads the frames before it from series.csv. Runs without water record
    nothing; a wet slope that did not fail records None.
    """

    def __init__(self, sim: Any, settings: Any, out_dir: Path | None):
        self.sim = sim
        self.threshold_m = float(settings.mobilised_displacement_m)
        self.fraction = float(settings.kinetic_energy_fraction)
        self.wet = getattr(sim.engine, "water", None) is not None
        #: (time, stage index, stage time, kinetic energy) of each frame of a dynamic stage
        self.frames: list[tuple[float, int, float, float]] = []
        self.moved_m = 0.0
        if self.wet and out_dir is not None and sim.time_s > 0.0:
            self._read_earlier(out_dir / "series.csv")

    def _dynamic(self, index: int) -> bool:
        stages = self.sim.config.stages
        return 0 <= index < len(stages) and stages[index].kind == "dynamic"

    def _read_earlier(self, path: Path) -> None:
        import csv

        try:
            with open(path, newline="") as fh:
                for row in csv.DictReader(fh):
                    t, index = float(row["time_s"]), int(row["stage_index"])
                    if t <= self.sim.time_s + 1e-12 and self._dynamic(index):
                        self.frames.append((t, index, float(row["stage_time_s"]), float(row["kinetic_energy_J_per_m"])))
        except (OSError, KeyError, ValueError) as err:
            logger.warning("water at failure: the frames before the resume are not read (%s)", err)

    def see(self, frame: Frame) -> None:
        if not self.wet:
            return
        d = frame.diagnostics
        if not self._dynamic(d.stage_index):
            return
        self.frames.append((float(d.time_s), d.stage_index, float(d.stage_time_s), float(d.kinetic_energy_J_per_m)))
        disp = frame.fields.get("displacement")
        if disp is not None:
            moved = np.linalg.norm(np.asarray(disp, dtype=np.float64), axis=1)[np.asarray(frame.fields["active"], bool)]
            self.moved_m = max(self.moved_m, float(moved.max(initial=0.0)))

    def summary(self) -> dict[str, Any]:
        if not self.wet:
            return {}
        if not self.frames or self.moved_m <= self.threshold_m:
            return {"water_at_failure": None}
        peak = max(ke for *_, ke in self.frames)
        t, index, stage_time, _ = next(f for f in self.frames if f[3] >= self.fraction * peak)
        water = self.sim.water_at(index, stage_time)
        return {"water_at_failure": {
            "time_s": t, "stage": self.sim.config.stages[index].name, "stage_time_s": stage_time,
            "max_displacement_m": self.moved_m,
            "phreatic_line_m": None if water is None else [list(p) for p in water.phreatic_line_m],
            "free_water_line_m": None if water is None else [list(p) for p in water.free_water],
        }}


def _motion(sim: Any, resolved: ResolvedRun, status: str) -> dict[str, Any] | None:
    """The verdict on the motion at the end of the run (projects.motion); None when no dynamic
    stage ran or the run failed before it could say."""
    from projects.hazard import settings
    from projects.motion import default_rest_speed, verdict

    if status not in ("completed", "stopped"):
        return None
    try:
        domain = resolved.project.domain
        return verdict(sim.motion_at_end(), kinetic_energy_fraction=settings(resolved.project).kinetic_energy_fraction,
                       rest_speed_m_s=default_rest_speed(tuple(domain.gravity_m_s2), domain.cell_size_m),
                       status=status)
    except Exception as err:  # noqa: BLE001 - the run's outcome stands without the verdict
        logger.error("the motion at the end is not known: %s", err)
        return None


def _equilibrium(sim: Any) -> dict[str, Any]:
    """The initial equilibrium check of the solver, when it made one (for ``summary.json``)."""
    check = getattr(sim, "equilibrium", None)
    return {"initial_equilibrium": check} if check else {}
