"""The ``runout`` command line (typer + rich).

Commands: ``run``, ``validate``, ``render``, ``report``, ``animate`` and ``gui``. Results and summaries go to
standard output, progress bars and errors to standard error. Bad input (an invalid project, a
missing results folder, an unknown field) is reported as one line per problem, never as a
traceback; ``--verbose`` shows the log, with tracebacks of solver failures.

Exit status: 0 success; 1 invalid input (project problems, unreadable results, bad options,
a results folder that must not be used); 3 the run failed (see the message and
``summary.json``); 130 stopped by Ctrl-C (SIGINT), 143 stopped by SIGTERM, 129 by SIGHUP (the
terminal closed).

User text (names of stages, bodies, files) never goes through rich markup: every message is
printed with ``markup=False`` and progress descriptions are escaped.

``sweep`` and ``calibrate`` are registered on :data:`cli` by :mod:`app.sweep_commands`; the exit
codes, consoles, :func:`~app.console.fail` and :func:`~app.console.stop_on_signals` that all
commands share live in :mod:`app.console`.
"""

from __future__ import annotations

import contextlib
import io
import logging
import math
import os
import signal
import sys
from enum import Enum
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from app.console import (
    EXIT_FAILED,
    EXIT_SIGHUP,
    EXIT_SIGINT,
    EXIT_SIGTERM,
    err,
    fail,
    in_main_thread,
    out,
    stop_on_signals,
)

if TYPE_CHECKING:  # pragma: no cover - typing only
    from projects.runner import RunResult, StopRequest
    from projects.schema import Project

cli = typer.Typer(
    name="runout",
    help="Runout: landslide run-out analysis with the material point method.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)


class _RichLogHandler(logging.Handler):
    """Log records through rich's handler on ``err``, made at the first record (see LazyConsole)."""

    def __init__(self) -> None:
        super().__init__()
        self._rich: logging.Handler | None = None

    def emit(self, record: logging.LogRecord) -> None:
        if self._rich is None:
            from rich.logging import RichHandler

            self._rich = RichHandler(console=err.get(), show_time=False, show_path=False, markup=False)
        self._rich.handle(record)


class Arch(str, Enum):
    cpu = "cpu"
    gpu = "gpu"


class ProgressMode(str, Enum):
    rich = "rich"
    jsonl = "jsonl"


# --------------------------------------------------------------------------------------------
# shared helpers (also for commands defined in other modules)


def load_or_exit(path: Path, overrides: list[str] | None = None) -> Project:
    """Load and validate a project with ``--set`` overrides; every problem printed on failure."""
    from projects.document import load_project
    from projects.schema import ProjectError

    try:
        return load_project(path, overrides or ())
    except ProjectError as exc:
        fail(str(exc))


def _setup_logging(verbose: bool, quiet: bool = False) -> None:
    level = logging.DEBUG if verbose else logging.ERROR if quiet else logging.WARNING
    root = logging.getLogger()
    if not any(isinstance(h, _RichLogHandler) for h in root.handlers):
        root.addHandler(_RichLogHandler())
    root.setLevel(level)


def _results_path(path: Path) -> Path:
    """A results folder, or the default results folder of a project file."""
    from projects.runner import default_results_dir

    if path.suffix.lower() == ".toml" and path.is_file():
        return default_results_dir(path)
    return path


def _open_results(path: Path):  # noqa: ANN202 - Results, imported lazily
    from projects.results import Results, ResultsError

    try:
        return Results(_results_path(path))
    except ResultsError as exc:
        fail(str(exc))


def _parse_size(text: str) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        fail(f"--size must look like 1600x900, got {text!r}")
    if not (16 <= w <= 16384 and 16 <= h <= 16384):
        fail(f"--size must be between 16 and 16384 pixels per side, got {text!r}")
    return w, h


def _parse_frame(text: str) -> int:
    if text.lower() in ("last", "end"):
        return -1
    try:
        return int(text)
    except ValueError:
        fail(f"--frame must be a frame number or 'last', got {text!r}")


def _rate(value: float) -> str:
    """Particle-steps per second in millions, the unit of the performance notes."""
    return f"{value / 1e6:.3g} M"


# --------------------------------------------------------------------------------------------
# commands


@cli.callback()
def _main(
    verbose: Annotated[bool, typer.Option("--verbose", "-v", help="Show the log (debug level).")] = False,
) -> None:
    """Runout: landslide run-out analysis with the material point method."""
    _setup_logging(verbose)


class _RunProgress:
    """Rich progress bar fed by the solver's Progress callbacks (or nothing when quiet)."""

    def __init__(self, quiet: bool) -> None:
        self.bar = None
        if quiet:  # no bar: rich.progress is not even imported (part of every quiet run's start-up)
            return
        from rich.progress import (
            BarColumn,
            Progress,
            TaskProgressColumn,
            TextColumn,
            TimeRemainingColumn,
        )

        self.bar = Progress(
            TextColumn("{task.description}"),
            BarColumn(),
            TaskProgressColumn(),
            TextColumn("{task.fields[clock]}"),
            TextColumn("{task.fields[rate]}"),
            TextColumn("ETA"),
            TimeRemainingColumn(),
            console=err.get(),
        )
        self.task = self.bar.add_task("preparing", total=None, rate="", clock="")

    def __enter__(self) -> _RunProgress:
        if self.bar is not None:
            self.bar.__enter__()
        return self

    def __exit__(self, *exc: object) -> None:
        if self.bar is not None:
            self.bar.__exit__(None, None, None)

    def finish(self) -> None:
        """Show the bar full (the summed time steps may fall short of the total by round-off)."""
        if self.bar is None:
            return
        task = self.bar.tasks[0]
        if task.total is not None:
            self.bar.update(self.task, completed=task.total)

    def update(self, p: Any) -> None:
        """Show a ``solver.simulation.Progress`` (time_s, total_time_s, stage, steps_per_s)."""
        if self.bar is None:
            return
        total = p.total_time_s if p.total_time_s > 0 else None
        from rich.markup import escape

        self.bar.update(
            self.task,
            description=escape(str(p.stage)),
            total=total,
            completed=min(p.time_s, total) if total else p.time_s,
            rate=f"{p.steps_per_s:,.0f} steps/s",
            clock=f"t = {p.time_s:.3f} / {p.total_time_s:.3f} s",
        )


class _JsonProgress:
    """Machine-readable progress of ``runout run --progress jsonl``: one JSON object per line.

    Events (key ``event``), in this order:

    - ``warning``: ``message``, one per project warning (docs/project-format.md, "Warnings"),
      before anything else (the results folder does not exist yet);
    - ``started``: ``out_dir`` (the results folder), ``particles``, ``total_time_s``,
      ``first_frame`` (the number of the first frame this run writes: 0, or for ``--resume`` the
      frame after the checkpoint's); sent once the results folder exists (before the first
      progress or frame event);
    - ``progress``: ``time_s``, ``total_time_s`` (s), ``stage``, ``step``, ``steps_per_s``,
      ``particle_steps_per_s``; at most every :attr:`INTERVAL_S` seconds;
    - ``frame``: ``index`` (its number in the folder, ``frames/frame_INDEX.vtp``) and ``time_s``
      of a frame handed to the results writer (it is on disk, listed in ``particles.pvd``,
      shortly after);
    - ``finished``: ``status`` ("completed", "stopped", "failed", or "error" when the run could
      not start: invalid project, refused folder), ``message``, ``out_dir`` and the final
      ``summary`` (absent for "error").

    Consumers (the workbench) read the frames themselves from the results folder; this stream
    only says when to look.
    """

    INTERVAL_S = 0.1

    def __init__(self, stream: Any, out_dir: Path) -> None:
        self.stream = stream
        self.out_dir = out_dir
        self.frames = 0
        self._started = False
        self._last = 0.0

    def emit(self, event: str, **fields: Any) -> None:
        import json

        line = json.dumps({"event": event, **fields}, default=str)
        try:
            self.stream.write(line + "\n")
            self.stream.flush()
        except (OSError, ValueError):  # the reader went away: the run goes on regardless
            pass

    def _start(self) -> None:
        if self._started:
            return
        import json

        self._started = True
        summary: dict[str, Any] = {}
        try:
            summary = json.loads((self.out_dir / "summary.json").read_text(encoding="utf-8"))
        except (OSError, ValueError):
            pass
        # a resumed run writes its frames from this number on (they replace those after the
        # checkpoint): ``frame`` events carry the frame's number in the folder
        self.frames = int(summary.get("resumed_at_frame") or 0)
        self.emit("started", out_dir=str(self.out_dir), particles=summary.get("particles"),
                  total_time_s=summary.get("total_time_s"), first_frame=self.frames)

    def progress(self, p: Any) -> None:
        import time

        self._start()
        now = time.perf_counter()
        if now - self._last < self.INTERVAL_S:
            return
        self._last = now
        self.emit("progress", time_s=p.time_s, total_time_s=p.total_time_s, stage=p.stage, step=p.step,
                  steps_per_s=p.steps_per_s, particle_steps_per_s=p.particle_steps_per_s)

    def frame(self, frame: Any) -> None:
        self._start()
        self.emit("frame", index=self.frames, time_s=float(frame.diagnostics.time_s))
        self.frames += 1


def _state(result: RunResult) -> str:
    """The run's status with whether its answer is final: ``completed, still moving (kinetic
    energy 0.46 of its peak, fastest particle 3.2 m/s at t = 2 s)`` or ``completed, at rest (...)``."""
    from projects.motion import motion_numbers

    m = result.summary.get("motion_at_end")
    if not isinstance(m, dict):
        return result.status
    state = "driven" if m.get("driven") else "still moving" if m.get("still_moving") else "at rest"
    return f"{result.status}, {state} ({motion_numbers(m)} at t = {m.get('time_s') or 0.0:.4g} s)"


def _summary_line(result: RunResult) -> str:
    s = result.summary
    return (
        f"{_state(result)}: {s.get('particles', 0):,} particles, {s.get('steps', 0):,} steps, "
        f"t = {s.get('simulated_time_s') or 0.0:.4g} s in {s.get('wall_time_s') or 0.0:.1f} s "
        f"({_rate(s.get('particle_steps_per_s') or 0.0)} particle-steps/s, "
        f"{s.get('arch', '?')} {s.get('precision', '')}) -> {result.out_dir}"
    )


def _factor_line(result: RunResult) -> str:
    """The factor of safety of a strength-reduction run, with Bishop's beside it ("" otherwise)."""
    fos = result.summary.get("factor_of_safety")
    if not fos:
        return ""
    if fos.get("value") is None:
        line = f"factor of safety: not bracketed ({fos.get('message', '')})"
    else:
        line = (f"factor of safety {fos['value']:.3f} (strength reduction, bracket [{fos['lower']:.3f}, "
                f"{fos['upper']:.3f}], {fos.get('criterion', '')}, {len(fos.get('trials', []))} trials)")
    le = result.summary.get("limit_equilibrium") or {}
    if le.get("factor_of_safety") is not None:
        line += f"; Bishop {le['factor_of_safety']:.3f}"
    runout = None
    try:  # the hazard measures of the run-out stage, when the run wrote them
        import json

        runout = json.loads((Path(result.out_dir) / "hazard.json").read_text(encoding="utf-8")).get("runout_distance_m")
    except (OSError, ValueError):
        runout = None
    if runout is not None:
        line += f"; if it fails it runs out {runout:.3g} m (hazard.json runout_distance_m)"
    elif fos.get("runout_max_displacement_m") is not None:
        line += f"; if it fails it runs out {fos['runout_max_displacement_m']:.3g} m (largest displacement)"
    return line


@cli.command()
def run(
    project: Annotated[
        Path | None, typer.Argument(help="Project file (.toml); not with --resume.", show_default=False)
    ] = None,
    out_dir: Annotated[
        Path | None,
        typer.Option("--out", "-o", help="Results folder (default: NAME.results next to the project)."),
    ] = None,
    overrides: Annotated[
        list[str] | None,
        typer.Option("--set", "-s", metavar="KEY=VALUE", help="Override a project key (repeatable)."),
    ] = None,
    arch: Annotated[Arch | None, typer.Option("--arch", help="Run on the CPU or the GPU.")] = None,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="No progress or summary; errors only.")] = False,
    overwrite: Annotated[bool, typer.Option(
        "--overwrite", help="Replace an earlier run's results in the folder (only that run's own files).")] = False,
    force: Annotated[bool, typer.Option(
        "--force", help="Run even beyond the size limits (memory, disk, particles, steps, frames).")] = False,
    resume: Annotated[
        Path | None,
        typer.Option("--resume", help="Continue the killed or stopped run in this results folder "
                     "from its last checkpoint.", show_default=False),
    ] = None,
    start_from: Annotated[
        Path | None,
        typer.Option("--start-from", help="Start the project's stages from the particle state of another "
                     "run's checkpoint (its results folder or checkpoint.npz).", show_default=False),
    ] = None,
    progress_mode: Annotated[
        ProgressMode,
        typer.Option("--progress", help="rich: a progress bar on standard error; jsonl: one JSON object "
                     "per line on standard output (started, warning, progress, frame, finished) for programs."),
    ] = ProgressMode.rich,
    source: Annotated[
        Path | None,
        typer.Option("--source", help="The project file PROJECT is a copy of, named in summary.json instead of "
                     "PROJECT (the workbench runs a temporary copy of its window's project).", show_default=False),
    ] = None,
    unsaved: Annotated[bool, typer.Option(
        "--unsaved", help="PROJECT holds edits not saved in --source, or has no file of its own: "
        "summary.json says so.")] = False,
) -> None:
    """Run a project and write its results folder (or continue one with --resume).

    An earlier run's results in the folder are replaced only with --overwrite; any other
    non-empty folder is refused; a folder another run is writing into is refused.
    """
    from projects.motion import provisional
    from projects.results import ResultsError
    from projects.runner import StopRequest, default_results_dir, resumable, resume_run, run_project
    from projects.schema import ProjectError

    if (project is None) == (resume is None):
        fail("give a project file, or --resume RESULTS (not both)")
    if resume is not None and (out_dir is not None or overrides or start_from is not None or source is not None
                               or unsaved):
        fail("--resume continues a run as it was: no --out, --set, --start-from, --source or --unsaved with it")
    jsonl = progress_mode is ProgressMode.jsonl
    if quiet or jsonl:
        _setup_logging(verbose=False, quiet=True)
    where_to = resume if resume is not None else out_dir if out_dir is not None else default_results_dir(project)
    events = _JsonProgress(sys.stdout, Path(where_to).expanduser().absolute()) if jsonl else None
    stop = StopRequest()
    with stop_on_signals(stop):
        _stop_with_parent(stop)
        try:
            if project is None:
                model = None
                # a folder that cannot be resumed is a one-line error before any progress bar
                checkpoint = resumable(resume)
            elif events is None:
                model = load_or_exit(project, overrides)
            else:
                model = _load_or_report(project, overrides, events)
            if stop.requested:
                if events is not None:
                    events.emit("finished", status="error", message=f"stopped by {stop.reason} before the run started",
                                out_dir=str(events.out_dir))
                fail(f"stopped by {stop.reason} before the run started", _stop_code(stop))
            if model is not None and events is not None:
                from projects.checks import project_warnings

                for warning in project_warnings(model):
                    events.emit("warning", message=str(warning))
            elif not quiet and model is not None:
                _print_warnings(model)
            # Taichi prints "[Taichi] Starting on arch=..." to stdout; keep stdout for results
            chatter = io.StringIO() if quiet else sys.stderr
            with _RunProgress(quiet or jsonl) as progress, contextlib.redirect_stdout(chatter):
                on_progress = progress.update if events is None else events.progress
                on_frame = None if events is None else events.frame
                if resume is not None:
                    result = resume_run(resume, arch=arch.value if arch is not None else None,
                                        cancel=stop, on_progress=on_progress, on_frame=on_frame,
                                        checkpoint=checkpoint, force=force)
                else:
                    result = run_project(
                        model,
                        where_to,
                        # the file the user knows, not the copy that runs (--source); none: unsaved
                        project_path=source if source is not None else None if unsaved else project,
                        unsaved=unsaved,
                        arch=arch.value if arch is not None else None,
                        cancel=stop,
                        on_progress=on_progress,
                        on_frame=on_frame,
                        overwrite=overwrite,
                        force=force,
                        start_from=start_from,
                    )
                if result.status == "completed":
                    progress.finish()
        except (ProjectError, ResultsError) as exc:
            if events is not None:
                events.emit("finished", status="error", message=str(exc), out_dir=str(events.out_dir))
            fail(str(exc))
        except KeyboardInterrupt:
            if events is not None:
                events.emit("finished", status="error", message="stopped before the run started",
                            out_dir=str(events.out_dir))
            fail("stopped before the run started", EXIT_SIGINT)
        # the last lines are printed with the stop handler still installed: a Ctrl-C among them only
        # repeats the request (outside it, one landed in rich's import and ended with an ImportError)
        if events is not None:
            events.emit("finished", status=result.status, message=result.message, out_dir=str(result.out_dir),
                        summary=result.summary)
        _report_equilibrium(result, quiet or jsonl)
        if not quiet and not jsonl:
            for warning in result.summary.get("warnings") or ():  # what the run found (projects.runner)
                err.print(f"warning: {warning}", markup=False)
        if result.status == "completed":
            if not quiet and not jsonl:
                out.print(_summary_line(result), markup=False)
                if provisional(result.summary):
                    from projects.motion import REMEDY

                    err.print(f"warning: the run ended with the mass still moving: its measures are provisional; {REMEDY}",
                              markup=False)
                fos = _factor_line(result)
                if fos:
                    out.print(fos, markup=False)
            return
        where = f"(results so far in {result.out_dir})"
        if result.status == "stopped":
            code = _stop_code(stop)
            err.print(f"stopped: {result.message} {where}", markup=False)
            raise typer.Exit(code)
        err.print(f"failed: {result.message} {where}", markup=False)
        raise typer.Exit(EXIT_FAILED)


#: Environment variable a parent sets to its process id so that its ``runout run`` children stop
#: (SIGTERM: a stopped run with its final status) when it dies; the workbench sets it.
STOP_WITH_PARENT_ENV = "RUNOUT_STOP_WITH_PARENT"


def _stop_with_parent(stop: StopRequest) -> None:
    """SIGTERM when the parent named by :data:`STOP_WITH_PARENT_ENV` dies (Linux, PR_SET_PDEATHSIG);
    a parent already gone stops the run at once. Call with the SIGTERM handler installed."""
    parent = os.environ.get(STOP_WITH_PARENT_ENV, "")
    if not parent.isdigit() or not sys.platform.startswith("linux"):
        return
    import ctypes

    try:
        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, int(signal.SIGTERM), 0, 0, 0)  # PR_SET_PDEATHSIG = 1
    except (OSError, AttributeError):
        return
    if os.getppid() != int(parent):  # it died before the request took effect
        stop.request("SIGTERM")


def _load_or_report(path: Path, overrides: list[str] | None, events: _JsonProgress) -> Project:
    """:func:`load_or_exit` that also sends a ``finished`` event with status "error"."""
    from projects.document import load_project
    from projects.schema import ProjectError

    try:
        return load_project(path, overrides or ())
    except ProjectError as exc:
        events.emit("finished", status="error", message=str(exc), out_dir=str(events.out_dir))
        fail(str(exc))


def _stop_code(stop: StopRequest) -> int:
    return {"SIGTERM": EXIT_SIGTERM, "SIGHUP": EXIT_SIGHUP}.get(stop.reason, EXIT_SIGINT)


def _report_equilibrium(result: RunResult, quiet: bool) -> None:
    check = result.summary.get("initial_equilibrium")
    if quiet or not check:
        return
    ratio = check.get("unbalanced_force_ratio")
    plastic = check.get("plastic_points") or 0
    err.print(
        f"initial equilibrium after {check.get('stage')!r}: unbalanced-force ratio "
        f"{ratio if ratio is None else format(ratio, '.3g')}, largest speed at its end "
        f"{check.get('max_speed_m_s', 0.0):.3g} m/s"
        + ("; released into the next stage" if check.get("released") else "")
        + (f"; {plastic} plastic points (K0 stress outside the yield surface, returned to it at the "
           f"first step: K = {check.get('plastic_k0'):.3g})" if plastic else ""),
        markup=False,
    )


def _print_warnings(model: Project) -> None:
    from projects.checks import project_warnings

    for warning in project_warnings(model):
        err.print(f"warning: {warning}", markup=False)


@cli.command()
def validate(
    project: Annotated[Path, typer.Argument(help="Project file (.toml).", show_default=False)],
    overrides: Annotated[
        list[str] | None,
        typer.Option("--set", "-s", metavar="KEY=VALUE", help="Override a project key (repeatable)."),
    ] = None,
    force: Annotated[bool, typer.Option("--force", help="Skip the size limits.")] = False,
) -> None:
    """Check a project: every problem, or what it would run."""
    from projects.runner import check_project, default_results_dir
    from projects.schema import ProjectError

    model = load_or_exit(project, overrides)
    try:
        resolved = check_project(model, force=force, out_dir=default_results_dir(project))
    except ProjectError as exc:
        fail(f"{project}: {exc}")
    _print_warnings(model)
    grid = resolved.config.grid
    nx, ny = grid.cells
    numerics = resolved.config.numerics
    e = resolved.estimate
    if numerics.time_step_s is not None:
        step = f"dt {numerics.time_step_s:g} s"
    else:  # the step cfl gives, and what material damping costs of it (docs/solver.md)
        damping = (f", {e['time_step_shrink_by_damping']:.2g}x shorter for the damping of "
                   f"{e['damping_key'].rsplit('.', 1)[0]}" if e.get("damping_key") else "")
        step = f"cfl {numerics.cfl:g} (dt {e['time_step_s']:.3g} s{damping})"
    preset = f" (preset {resolved.project.numerics.preset})" if resolved.project.numerics.preset else ""
    out.print(
        f"ok: {resolved.particle_count:,} particles, {len(resolved.config.materials)} materials, "
        f"{len(resolved.body_names)} bodies, {len(resolved.project.stages)} stages, "
        f"grid {nx} x {ny} cells of {grid.cell_size_m:g} m, {numerics.scheme} {step}{preset}, "
        f"about {resolved.estimate['steps']:,} steps",
        markup=False,
    )
    # the wall time from the measured cost per step at this size (projects.cost): this project's
    # own run where it has one, else the development machine's measurements
    from projects.cost import describe, estimate_run_time

    out.print(f"run time: {describe(estimate_run_time(resolved, results_dir=default_results_dir(project)))}",
              markup=False)


def _parse_numbers(option: str, text: str, count: int) -> list[float]:
    """``"2,0.5"`` -> [2.0, 0.5]: ``count`` numbers separated by commas, or one line naming the option."""
    parts = [p.strip() for p in text.split(",")]
    try:
        numbers = [float(p) for p in parts]
    except ValueError:
        numbers = []
    if len(numbers) != count or not all(math.isfinite(v) for v in numbers):
        shape = ",".join(("x", "y", "x1", "y1")[:count]) if count <= 2 else "x0,y0,x1,y1"
        fail(f"{option} must be {count} numbers in metres, {shape}, got {text!r}")
    return numbers


@cli.command()
def query(
    results: Annotated[Path, typer.Argument(help="Results folder (or its project file).", show_default=False)],
    field: Annotated[str, typer.Option("--field", help="Field (as runout render: displacement, velocity, "
                                       "stress_yy, mean_stress, plastic_strain, pore_pressure, ...).")] = "displacement",
    at: Annotated[list[str] | None, typer.Option("--at", metavar="X,Y", help="A point (m); repeatable.")] = None,
    along: Annotated[str | None, typer.Option("--along", metavar="X0,Y0,X1,Y1",
                                              help="A section from (x0, y0) to (x1, y1), m.")] = None,
    frame: Annotated[str, typer.Option("--frame", "-f", help="Frame number or 'last'.")] = "last",
    samples: Annotated[int | None, typer.Option("--samples", help="Points along the section (default: every "
                                                "half particle spacing).")] = None,
    smooth: Annotated[bool, typer.Option("--smooth", help="Stresses and pore pressure averaged over the cells "
                                         "around each particle, as the views can show them.")] = False,
    output: Annotated[Path | None, typer.Option("-o", "--output", help="Write the section as CSV to this file "
                                                "(default: to the terminal).")] = None,
) -> None:
    """The value of a field at a point or along a section, at any frame."""
    from app.query import csv_text, point_text, values_along, values_at
    from projects.results import ResultsError

    if (not at) == (along is None):
        fail("give --at X,Y (one or more) or --along X0,Y0,X1,Y1")
    index = _parse_frame(frame)
    res = _open_results(results)
    try:
        if at:
            answer = values_at(res, field, [_parse_numbers("--at", text, 2) for text in at], index, smooth)
        else:
            x0, y0, x1, y1 = _parse_numbers("--along", along or "", 4)
            answer = values_along(res, field, (x0, y0), (x1, y1), index, samples, smooth)
    except (ValueError, ResultsError) as err:
        fail(str(err))
    if at and output is None:
        out.print(point_text(answer), markup=False)
        return
    text = csv_text(answer)
    if output is None:
        typer.echo(text, nl=False)
        return
    from projects.atomic import write_atomic

    write_atomic(output, text.encode("utf-8"))
    found = sum(1 for p in answer.points if math.isfinite(p.value))
    out.print(f"wrote {output}: {len(answer.points)} points, {found} in the material, frame {answer.frame} "
              f"(t = {answer.time_s:.4g} s)", markup=False)


@cli.command()
def render(
    results: Annotated[Path, typer.Argument(help="Results folder (or its project file).", show_default=False)],
    frame: Annotated[str, typer.Option("--frame", "-f", help="Frame number or 'last'.")] = "last",
    field: Annotated[str, typer.Option("--field", help="Field to colour by.")] = "displacement",
    output: Annotated[Path | None, typer.Option(
        "-o", "--output", help="PNG file (default: beside the results folder, NAME_FIELD_FRAME.png).")] = None,
    size: Annotated[str, typer.Option("--size", help="Image size WIDTHxHEIGHT in pixels.")] = "1600x900",
    mechanism: Annotated[bool, typer.Option(
        "--mechanism", help="A strength-reduction run's mechanism with Bishop's circle and the trials.")] = False,
    smooth: Annotated[bool, typer.Option("--smooth", help="Stresses and pore pressure averaged over the grid cells "
                                         "around each particle (a display option; the frames are unchanged).")] = False,
) -> None:
    """Render one frame to a PNG (offscreen)."""
    from app.render import render_frame, render_mechanism
    from projects.results import ResultsError

    index = _parse_frame(frame)
    width_height = _parse_size(size)
    res = _open_results(results)
    try:
        if mechanism:
            path = render_mechanism(res, output, size=width_height)
        else:
            path = render_frame(res, index, field, output, size=width_height, smooth=smooth,
                                on_warning=lambda line: err.print(f"warning: {line}", markup=False))
    except (ValueError, ResultsError, OSError) as exc:  # OSError: a read-only or full disk
        fail(str(exc))
    out.print(str(path), markup=False)


@cli.command()
def report(
    results: Annotated[Path, typer.Argument(help="Results folder (or its project file).", show_default=False)],
    output: Annotated[Path | None, typer.Option("-o", "--output", help="Folder for report.html and its "
                                                "pictures (default: RESULTS/report).")] = None,
) -> None:
    """Write the report of a run (hazard: measures, envelopes, targets, pictures) or of a sweep or
    calibration folder (exceedance, probability profile, sensitivity; misfit landscape)."""
    from app.report import write_report
    from projects.results import ResultsError
    from sweeps.folder import is_sweep_dir

    if is_sweep_dir(results):  # sweep.csv or calibration.csv: app/sweep_commands.py
        from app.sweep_commands import sweep_report

        sweep_report(results, output)
        return
    res = _open_results(results)
    try:
        path = write_report(res.path, output)
    except (ValueError, ResultsError, OSError) as exc:  # OSError: a read-only or full disk
        fail(str(exc))
    out.print(str(path), markup=False)


@cli.command()
def animate(
    results: Annotated[Path, typer.Argument(help="Results folder (or its project file).", show_default=False)],
    output: Annotated[Path, typer.Option("-o", "--output", help="Movie file, .mp4 or .gif.", show_default=False)],
    field: Annotated[str, typer.Option("--field", help="Field to colour by.")] = "displacement",
    fps: Annotated[float, typer.Option("--fps", help="Frames per second.")] = 10.0,
    size: Annotated[
        str | None, typer.Option("--size", help="Image size WIDTHxHEIGHT (default 1280x720, gif 800x450).")
    ] = None,
    smooth: Annotated[bool, typer.Option("--smooth", help="Stresses and pore pressure averaged over the grid cells "
                                         "around each particle (a display option; the frames are unchanged).")] = False,
) -> None:
    """Write a movie of all frames (mp4 or gif)."""
    from rich.progress import Progress

    from app.render import animate as make_movie
    from projects.results import ResultsError

    if size is None:
        width_height = (800, 450) if output.suffix.lower() == ".gif" else (1280, 720)
    else:
        width_height = _parse_size(size)
    res = _open_results(results)
    try:
        with Progress(console=err.get(), transient=True) as bar:
            task = bar.add_task("rendering", total=len(res))
            path = make_movie(
                res, output, field, fps, size=width_height,
                on_frame=lambda done, total: bar.update(task, completed=done, total=total),
                on_warning=lambda line: err.print(f"warning: {line}", markup=False), smooth=smooth,
            )
    except (ValueError, ResultsError, OSError) as exc:
        fail(str(exc))
    out.print(str(path), markup=False)


@cli.command()
def gui(
    project: Annotated[Path | None, typer.Argument(help="Project file to open.", show_default=False)] = None,
) -> None:
    """Open the Runout workbench."""
    try:
        from app import gui as workbench
    except ImportError as exc:
        fail(f"the workbench cannot start: {exc}")
    code = workbench.main(project)
    raise typer.Exit(int(code or 0))


@cli.command()
def bench(
    quick: Annotated[bool, typer.Option("--quick", help="1e3 and 2e4 particles, f32 only (about a minute).")] = False,
    out_file: Annotated[
        Path | None,
        typer.Option("--out", "-o", help="Write the results as JSON here (and as markdown next to it)."),
    ] = None,
) -> None:
    """Measure solver throughput against a yardstick, memory, overhead and output stall."""
    from benchmarks.bench import BenchError, rich_tables, run_bench

    try:
        # progress and Taichi's own messages go to standard error; the tables to standard output
        with contextlib.redirect_stdout(sys.stderr):
            result = run_bench(quick, out_file, on_progress=lambda msg: err.print(msg, markup=False))
    except (BenchError, OSError) as exc:
        fail(str(exc))
    for table in rich_tables(result):
        out.print(table)
    if out_file is not None:
        out.print(f"written: {out_file} and {out_file.with_suffix('.md')}", markup=False)


#: The studies' names for the help (studies.STUDIES is the list; importing it here would load numpy
#: and the studies' harness into every command's start-up).
STUDY_NAMES = "sand-column | bui2008 | bui2008-choices | slope | tradeoff | presets | extremes | fos | softening"


@cli.command()
def study(
    name: Annotated[str, typer.Argument(help=STUDY_NAMES, show_default=False)],
    out_dir: Annotated[Path | None, typer.Option("--out", help="Report folder (default: study-results/NAME).")] = None,
    quick: Annotated[bool, typer.Option("--quick", help="The reduced version: a few minutes on two CPU cores.")] = False,
    budget_min: Annotated[float | None, typer.Option(
        "--budget-min", help="tradeoff only: start no run whose estimated time exceeds what is left of this "
        "many minutes; runs cached in the report folder are reused, so a sweep can be resumed.",
        show_default=False)] = None,
) -> None:
    """Run a validation study: report.md with tables and plots, raw CSV/JSON, a verdict.

    Exit status 0 when every stated target is met, 4 when the study ran but missed one.
    """
    from studies import StudyError, run_study

    if budget_min is not None and not budget_min > 0:
        fail(f"--budget-min must be a positive number of minutes, not {budget_min:g}")
    budget_s = None if budget_min is None else 60.0 * budget_min
    try:
        with contextlib.redirect_stdout(sys.stderr):  # Taichi's messages; the verdict goes to stdout
            result = run_study(name, out_dir, quick, note=lambda msg: err.print(msg, markup=False), budget_s=budget_s)
    except (StudyError, OSError) as exc:
        fail(str(exc))
    for line in result.verdict:
        out.print(line, markup=False)
    out.print(f"report: {result.report} ({result.wall_s:.0f} s)", markup=False)
    raise typer.Exit(0 if result.passed else 4)


def _interrupt(_signum: int, _frame: object) -> None:
    """Ctrl-C outside a run: one line, then the command unwinds (typer exits with 130)."""
    global INTERRUPT_SHOWN
    if not INTERRUPT_SHOWN:
        INTERRUPT_SHOWN = True
        err.print("error: interrupted (Ctrl-C)", markup=False)
    raise KeyboardInterrupt


def _interrupt_swallowed(unraisable: object) -> None:
    """``sys.unraisablehook``: a KeyboardInterrupt raised where Python cannot pass it on (a weakref
    callback of the import system, a ``__del__``) would be printed as "Exception ignored" with a
    traceback and the command would go on as if no Ctrl-C had come; the signal is sent again, to
    be raised at the next ordinary point."""
    if isinstance(getattr(unraisable, "exc_value", None), KeyboardInterrupt):
        signal.raise_signal(signal.SIGINT)
        return
    sys.__unraisablehook__(unraisable)


#: Whether the one line about a Ctrl-C has been printed (``python -m app`` prints none then).
INTERRUPT_SHOWN = False


# sweep and calibrate (sweeps on Ray): app/sweep_commands.py
from app.sweep_commands import register as _register_sweep_commands  # noqa: E402

_register_sweep_commands(cli)


def main(argv: list[str] | None = None) -> None:
    """Console-script entry point (``runout``)."""
    if in_main_thread():
        # `run` turns Ctrl-C into a clean stop while it runs (stop_on_signals) and comes back
        # to this handler afterwards
        signal.signal(signal.SIGINT, _interrupt)
        sys.unraisablehook = _interrupt_swallowed
    # Taichi prints a banner on import; keep standard output for results
    os.environ.setdefault("ENABLE_TAICHI_HEADER_PRINT", "0")
    # `run` redirects stdout around the solver; without this Taichi, imported meanwhile, would
    # take that for a notebook and wrap every kernel call to flush kernel prints
    os.environ.setdefault("TI_ENABLE_PYBUF", "0")
    cli(args=argv, prog_name="runout")


if __name__ == "__main__":  # pragma: no cover
    main()
