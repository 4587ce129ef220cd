"""``runout sweep`` and ``runout calibrate`` (registered on the command line by :func:`register`), and the sweep report.

The work is done by :mod:`sweeps`; this module parses options, shows a progress bar with ETA on
standard error and prints the result folder on standard output. Ctrl-C (or SIGTERM) stops
starting runs and cancels the running ones; finished runs are kept and reused when the same
command runs again.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated

import typer

from app import console

_ADDRESS = typer.Option("--address", help="Ray cluster address (e.g. ray://HEAD:10001 or auto); default: "
                        "a local Ray on this machine.")
_WORKERS = typer.Option("--workers", "-w", help="Runs at once (default: one per CPU core locally).")
_THREADS = typer.Option("--threads", help="Taichi CPU threads per run (default: cores / workers).")
_GPUS = typer.Option("--gpus-per-run", help="GPUs per run (1: one run per GPU, 0.5: two share one; "
                     "default 1 where Ray sees GPUs, else 0).")


class _Bar:
    """A rich progress bar over runs, with the failed count and the ETA."""

    def __init__(self, what: str) -> None:
        from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

        self.bar = Progress(TextColumn(what), BarColumn(), MofNCompleteColumn(), TextColumn("{task.fields[info]}"),
                            TimeElapsedColumn(), TextColumn("ETA {task.fields[eta]}"), console=console.err.get())
        self.task = self.bar.add_task(what, total=None, info="", eta="-")

    def __enter__(self) -> _Bar:
        self.bar.__enter__()
        return self

    def __exit__(self, *exc: object) -> None:
        self.bar.__exit__(None, None, None)

    def update(self, done: int, total: int, failed: int, eta_s: float) -> None:
        eta = "-" if not math.isfinite(eta_s) else f"{int(eta_s // 60)}:{int(eta_s % 60):02d}"
        self.bar.update(self.task, completed=done, total=total, info=f"{failed} not completed", eta=eta)


def _load_spec(path: Path, kind: str):  # noqa: ANN202 - SweepSpec | CalibrationSpec
    from projects.schema import ProjectError
    from sweeps.spec import load_spec

    try:
        spec = load_spec(path)
    except ProjectError as exc:
        console.fail(str(exc))
    if kind == "sweep" and not hasattr(spec, "sweep"):
        console.fail(f"{path}: this is a calibration file; run it with `runout calibrate`")
    if kind == "calibration" and not hasattr(spec, "calibration"):
        console.fail(f"{path}: this is a sweep file; run it with `runout sweep`")
    return spec


def _check_engine(workers: int | None, threads: int | None, gpus: float | None, address: str | None = None) -> None:
    from sweeps.spec import MAX_GPUS_PER_RUN, MAX_RUNS, MAX_THREADS_PER_RUN

    if workers is not None and workers < 1:
        console.fail(f"--workers must be >= 1, not {workers}")
    if workers is not None and workers > MAX_RUNS:
        console.fail(f"--workers must be at most {MAX_RUNS:,} (a sweep's most runs), not {workers:,}")
    if threads is not None and threads < 1:
        console.fail(f"--threads must be >= 1, not {threads}")
    if threads is not None and threads > MAX_THREADS_PER_RUN:
        console.fail(f"--threads must be at most {MAX_THREADS_PER_RUN}, not {threads:,}")
    if gpus is not None and not gpus >= 0:
        console.fail(f"--gpus-per-run must be >= 0, not {gpus:g}")
    if gpus is not None and not gpus <= MAX_GPUS_PER_RUN:
        console.fail(f"--gpus-per-run must be at most {MAX_GPUS_PER_RUN}, not {gpus:g}")
    if address is not None:
        from sweeps.engine import check_address

        try:
            check_address(address)
        except ConnectionError as exc:
            console.fail(f"cannot reach the Ray cluster at {address}: {exc}")


def _run_on_ray(spec_path: Path, kind: str, out_dir: Path | None, what: str, check, run,  # noqa: ANN001
                address: str | None, workers: int | None, threads: int | None, gpus: float | None):  # noqa: ANN202
    """The common body of ``sweep`` and ``calibrate``: options and ``spec_path`` checked (``check``
    names every problem of the spec before Ray starts), then ``run(spec, folder, ...)`` under a
    progress bar over ``what``, with Ctrl-C and SIGTERM stopping it. Problems are one-line
    errors. Returns (result, stop request)."""
    from projects.runner import StopRequest
    from projects.schema import ProjectError

    _check_engine(workers, threads, gpus, address)
    spec = _load_spec(spec_path, kind)
    try:
        check(spec)
    except ProjectError as exc:
        console.fail(f"{spec_path}: {exc}")
    folder = out_dir or spec_path.with_name(f"{spec_path.stem}.{kind}")
    stop = StopRequest()
    with console.stop_on_signals(stop), _Bar(what) as bar:
        try:
            result = run(spec, folder, workers=workers, address=address, threads_per_run=threads, gpus_per_run=gpus,
                         cancel=stop, on_progress=lambda p: bar.update(p.done, p.total, p.failed, p.eta_s))
        except ProjectError as exc:
            console.fail(f"{spec_path}: {exc}")
        except ConnectionError as exc:
            console.fail(f"cannot reach the Ray cluster at {address}: {exc}")
    return result, stop


def _stopped_exit(stop) -> typer.Exit:  # noqa: ANN001
    """The exit of a stopped sweep or calibration (the signal's code)."""
    return typer.Exit(console.EXIT_SIGTERM if stop.reason == "SIGTERM" else console.EXIT_SIGINT)


def register(cli: typer.Typer) -> None:
    """Add ``sweep`` and ``calibrate`` to the command line ``cli`` (``report`` dispatches to
    :func:`sweep_report` for a sweep folder)."""

    @cli.command()
    def sweep(
        spec_path: Annotated[Path, typer.Argument(metavar="SPEC", help="Sweep file (.toml).", show_default=False)],
        out_dir: Annotated[Path | None, typer.Option("--out", "-o", help="Sweep folder (default: SPEC name + .sweep "
                                                     "next to the file).")] = None,
        address: Annotated[str | None, _ADDRESS] = None,
        workers: Annotated[int | None, _WORKERS] = None,
        threads: Annotated[int | None, _THREADS] = None,
        gpus: Annotated[float | None, _GPUS] = None,
    ) -> None:
        """Run a parameter sweep or Monte Carlo analysis on Ray: sweep.csv, statistics, report.html."""
        from sweeps.sweep import plan_sweep, run_sweep

        result, stop = _run_on_ray(spec_path, "sweep", out_dir, "runs", plan_sweep, run_sweep,
                                   address, workers, threads, gpus)
        if result.stopped:
            console.err.print(f"stopped: {sum(r.status != 'pending' for r in result.records)} of {len(result.records)} "
                             f"runs done (run the same command again to go on) -> {result.out_dir}", markup=False)
            raise _stopped_exit(stop)
        n = len(result.records)
        moving = result.still_moving_runs()
        if moving:
            from projects.motion import REMEDY

            console.err.print(f"warning: {_runs_text(moving)} ended with the mass still moving: their measures are "
                              f"provisional (still_moving in sweep.csv, * in report.html); {REMEDY}", markup=False)
        console.out.print(f"{result.count('completed')} of {n} runs completed, {n - result.count('completed')} not "
                         f"({sum(r.reused for r in result.records)} reused), {len(moving)} ended still moving"
                         f"{' (provisional measures)' if moving else ''} in {result.wall_time_s:.1f} s "
                         f"-> {result.out_dir}/sweep.csv, report.html", markup=False)

    @cli.command()
    def calibrate(
        spec_path: Annotated[Path, typer.Argument(metavar="SPEC", help="Calibration file (.toml).", show_default=False)],
        out_dir: Annotated[Path | None, typer.Option("--out", "-o", help="Calibration folder (default: SPEC name + "
                                                     ".calibration next to the file).")] = None,
        address: Annotated[str | None, _ADDRESS] = None,
        workers: Annotated[int | None, _WORKERS] = None,
        threads: Annotated[int | None, _THREADS] = None,
        gpus: Annotated[float | None, _GPUS] = None,
    ) -> None:
        """Find the parameters that best reproduce an observation (optuna), runs on Ray; report.html."""
        from sweeps.calibrate import check_calibration, run_calibration

        result, stop = _run_on_ray(spec_path, "calibration", out_dir, "trials", check_calibration, run_calibration,
                                   address, workers, threads, gpus)
        for line in result.summary_lines():  # warnings (trials that ended still moving) on standard error
            (console.err if line.startswith("warning:") else console.out).print(line, markup=False)
        console.out.print(f"-> {result.out_dir}/calibration.csv, report.html", markup=False)
        if result.stopped:
            raise _stopped_exit(stop)


def _runs_text(runs: list[int], most: int = 10) -> str:
    """``run 3``, ``runs 3, 5 and 8``, or the first ``most`` and how many more."""
    if len(runs) == 1:
        return f"run {runs[0]}"
    shown = ", ".join(str(r) for r in runs[:most])
    if len(runs) > most:
        return f"{len(runs)} runs ({shown} and {len(runs) - most} more)"
    head, _, last = shown.rpartition(", ")
    return f"runs {head} and {last}"


def sweep_report(folder: Path, output: Path | None = None) -> None:
    """``runout report SWEEP_DIR``: report.html of a sweep or calibration folder (in ``output`` if given)."""
    from sweeps.report import write_report
    from sweeps.folder import SweepFolderError

    try:
        path = write_report(folder, output)
    except (SweepFolderError, OSError) as exc:
        console.fail(str(exc))
    console.out.print(str(path), markup=False)
