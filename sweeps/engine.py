"""Running many project runs on Ray: one process per run, resumable, with progress.

Each run is one resolved project (the base project with the fixed and the sampled ``--set``
overrides), written to ``runs/ID.toml`` and run by ``python -m app.cli run runs/ID.toml --out
runs/ID --quiet`` in a subprocess started from a Ray task: the Taichi runtime never enters the Ray
worker and a crash ends only that run. ``ID`` is the first 16 hex digits of the SHA-256 of the
resolved project text, so the same resolved project is run once and reused by later sweeps into
the same folder (``runs/ID.json`` holds its record).

Threads: a CPU run gets ``TI_CPU_MAX_NUM_THREADS`` = its threads (Taichi reads ``ti.init``
settings from ``TI_*`` variables) and asks Ray for as many CPUs, so ``workers x threads`` never
exceeds the CPUs Ray was given. A GPU run asks Ray for ``gpus_per_run`` GPUs (1: one run per
GPU, 0.5: two runs share one) and runs with ``--arch gpu``.
"""

from __future__ import annotations

import hashlib
import json
import logging
import math
import os
import socket
import subprocess
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from projects.runner import runout_command

logger = logging.getLogger(__name__)

#: Statuses of a run record. ``completed``/``failed`` (the solver stopped on an instability) and
#: ``invalid`` (the sampled values make an invalid project) are final and reused on resume;
#: ``error`` (the process crashed, was killed or timed out) is run again.
FINAL_STATUSES = ("completed", "failed", "invalid")

RUNS_DIR = "runs"


@dataclass(frozen=True)
class RunPlan:
    """One run of a sweep before it runs.

    Attributes
    ----------
    index : int
        Position in the sweep (0-based).
    values : dict
        Parameter key path -> value.
    overrides : tuple of str
        Every ``--set`` applied to the base project (fixed ones first).
    run_id : str
        Hash of the resolved project text ("" when the values make an invalid project).
    project_text : str
        The resolved project (TOML), or "" when invalid.
    problem : str
        Why the project is invalid ("" when valid).
    disk_bytes : int
        The run's results folder as :func:`projects.build.estimate` sizes it (0 when invalid).
    """

    index: int
    values: dict[str, Any]
    overrides: tuple[str, ...]
    run_id: str
    project_text: str
    problem: str = ""
    disk_bytes: int = 0


@dataclass
class RunRecord:
    """What one run produced (a row of sweep.csv).

    Attributes
    ----------
    status : str
        ``completed`` | ``failed`` | ``invalid`` | ``error`` | ``pending``.
    wall_time_s : float
        Wall time of the whole run process, s (Python start and compilation included).
    measures : dict of str to float
    profile : (list, list) or None
        ``(x_m, values)`` of the sweep's profile field.
    surface : list of float or None
        Final surface heights at requested stations (calibration), m.
    overhead_s : float
        Time from submitting the task to receiving its result, less the run process's wall time:
        Ray's scheduling, the task's start and reading the measures, s.
    still_moving : bool or None
        The run ended with the mass still moving (``summary.json``'s verdict,
        :func:`projects.motion.provisional`): its measures are provisional. None where the run
        wrote no verdict (no dynamic stage ran, or no results).
    """

    run_id: str
    status: str
    message: str = ""
    wall_time_s: float = math.nan
    results_dir: str = ""
    measures: dict[str, float] = field(default_factory=dict)
    profile: tuple[list[float], list[float]] | None = None
    surface: list[float] | None = None
    host: str = ""
    overhead_s: float = math.nan
    reused: bool = False
    still_moving: bool | None = None

    def to_json(self) -> dict[str, Any]:
        return {
            "run_id": self.run_id, "status": self.status, "message": self.message,
            "wall_time_s": _finite(self.wall_time_s), "results_dir": self.results_dir,
            "measures": {k: _finite(v) for k, v in self.measures.items()},
            "profile": None if self.profile is None else {"x_m": self.profile[0], "values": self.profile[1]},
            "surface": self.surface, "host": self.host, "overhead_s": _finite(self.overhead_s),
            "still_moving": self.still_moving,
        }

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> RunRecord:
        prof = data.get("profile")
        return cls(
            run_id=str(data.get("run_id", "")), status=str(data.get("status", "error")),
            message=str(data.get("message", "")), wall_time_s=_num(data.get("wall_time_s")),
            results_dir=str(data.get("results_dir", "")),
            measures={k: _num(v) for k, v in (data.get("measures") or {}).items()},
            profile=None if not prof else (list(prof["x_m"]), [_num(v) for v in prof["values"]]),
            surface=data.get("surface"), host=str(data.get("host", "")), overhead_s=_num(data.get("overhead_s")),
            still_moving=data["still_moving"] if isinstance(data.get("still_moving"), bool) else None,
        )


def _finite(value: float) -> float | None:
    return float(value) if isinstance(value, (int, float)) and math.isfinite(value) else None


def _num(value: Any) -> float:
    return float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) else math.nan


def toml_value(value: Any) -> str:
    """A value as TOML text for ``--set`` (floats with repr, so they round-trip)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return repr(value)
    return json.dumps(str(value))


def resolve_runs(project_path: Path, fixed: Sequence[str], samples: Sequence[dict[str, Any]],
                 linked: dict[str, list[str]] | None = None) -> list[RunPlan]:
    """Resolve every run's project (base + fixed + sampled overrides) and hash it.

    ``linked`` maps a parameter key to more key paths set to the same value.

    A run whose values make an invalid project gets ``problem`` set (it is recorded as
    ``invalid`` and the sweep goes on); when every run is invalid, or the base project or the
    fixed overrides are, the problems are raised.

    Raises
    ------
    ProjectError
    """
    from projects.document import apply_overrides, dumps_project, load_project
    from projects.schema import ProjectError

    base = load_project(project_path, list(fixed))
    plans, first_error = [], None
    for i, values in enumerate(samples):
        sets = tuple(f"{key}={toml_value(v)}" for k, v in values.items() for key in (k, *(linked or {}).get(k, ())))
        try:
            project = apply_overrides(base, sets)
        except ProjectError as exc:
            first_error = first_error or exc
            plans.append(RunPlan(i, dict(values), (*fixed, *sets), "", "", str(exc).replace("\n", "; ")))
            continue
        text = dumps_project(project)
        run_id = hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]
        plans.append(RunPlan(i, dict(values), (*fixed, *sets), run_id, text, disk_bytes=_disk_bytes(project)))
    if plans and all(p.problem for p in plans):
        assert first_error is not None
        raise first_error
    return plans


def _disk_bytes(project: Any) -> int:
    """The results folder of one run, estimated (:func:`projects.build.estimate`, preset applied)."""
    from projects.build import resolve
    from projects.schema import ProjectError

    try:
        return int(resolve(project, seed=False).estimate["disk_bytes"])
    except (ProjectError, ValueError, ArithmeticError):
        return 0


# --------------------------------------------------------------------------------------------
# one run (executed in a Ray worker)


def execute_run(task: dict[str, Any]) -> dict[str, Any]:
    """Run one resolved project in a subprocess and read its measures (the Ray task body).

    Parameters
    ----------
    task : dict
        ``run_id``, ``project_text``, ``runs_dir`` (folder of ``ID.toml`` and ``ID/``),
        ``threads`` (Taichi CPU threads), ``arch`` ("cpu" | "gpu"), ``timeout_s`` (or None),
        ``measures`` (keys), ``profile_field`` (or None), ``sample_x`` (stations for the final
        surface, or None).

    Returns
    -------
    dict
        A :class:`RunRecord` as JSON data.
    """
    from sweeps.measures import read_measures, read_profile, still_moving, surface_at

    runs_dir = Path(task["runs_dir"])
    runs_dir.mkdir(parents=True, exist_ok=True)
    run_id = task["run_id"]
    project = runs_dir / f"{run_id}.toml"
    results = runs_dir / run_id
    project.write_text(task["project_text"], encoding="utf-8")
    env = dict(os.environ)
    threads = str(int(task.get("threads") or 1))
    env.update({"TI_CPU_MAX_NUM_THREADS": threads, "OMP_NUM_THREADS": threads,
                "ENABLE_TAICHI_HEADER_PRINT": "0", "TI_ENABLE_PYBUF": "0"})
    cmd = runout_command("run", str(project), "--out", str(results), "--quiet", "--arch", task.get("arch") or "cpu")
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=task.get("timeout_s"),
                              preexec_fn=_die_with_parent if sys.platform.startswith("linux") else None)
        rc, stderr = proc.returncode, proc.stderr
    except subprocess.TimeoutExpired as exc:
        rc, stderr = None, f"timed out after {exc.timeout:g} s"
    wall = time.perf_counter() - t0
    lines = [ln.strip() for ln in (stderr or "").splitlines() if ln.strip()]
    last = lines[-1] if lines else ""
    summary = {}
    try:
        summary = json.loads((results / "summary.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        pass
    if rc == 0:
        status, message = "completed", str(summary.get("message", ""))
    elif rc == 3:
        status, message = "failed", str(summary.get("message") or last)
    elif rc == 1:
        status, message = "invalid", last
    else:
        status = "error"
        message = last if rc is None else f"exit status {rc}: {last}" if last else f"exit status {rc}"
    rec = RunRecord(run_id=run_id, status=status, message=message, wall_time_s=wall, results_dir=str(results),
                    host=socket.gethostname(), still_moving=still_moving(summary))
    if results.is_dir():
        rec.measures = read_measures(results, task.get("measures") or ())
        if task.get("profile_field"):
            rec.profile = read_profile(results, task["profile_field"])
        if task.get("sample_x") is not None:
            try:
                rec.surface = surface_at(results, task["sample_x"])
            except (OSError, ValueError, KeyError, IndexError):
                rec.surface = None
    else:
        rec.measures = {k: math.nan for k in task.get("measures") or ()}
    return rec.to_json()


def _die_with_parent() -> None:
    """In the child, before exec: SIGTERM when the Ray worker dies (cancelled sweep, ray.shutdown).

    ``runout run`` stops on SIGTERM at its next step and marks its folder "stopped"; without this
    a cancelled task would leave its run going on, orphaned. Linux only (prctl PR_SET_PDEATHSIG).
    """
    import ctypes
    import signal

    try:
        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, int(signal.SIGTERM), 0, 0, 0)  # PR_SET_PDEATHSIG = 1
    except OSError:
        pass


# --------------------------------------------------------------------------------------------
# the engine


def check_address(address: str, timeout_s: float = 5.0) -> None:
    """Fail fast on a cluster address nothing listens at (Ray itself retries for minutes).

    ``HOST:PORT`` (the head's GCS port, 6379 by default) and ``ray://HOST:PORT`` (Ray Client,
    10001) are tried with a TCP connection; ``auto`` and other forms are left to Ray.

    Raises
    ------
    ConnectionError
        With the address and the reason.
    """
    text = address[len("ray://"):] if address.startswith("ray://") else address
    host, sep, port = text.rpartition(":")
    if not sep or not port.isdigit() or not host:
        return
    try:
        with socket.create_connection((host.strip("[]"), int(port)), timeout=timeout_s):
            pass
    except OSError as exc:
        raise ConnectionError(f"nothing answers at {address} ({exc.strerror or exc}); start the head with "
                              "`ray start --head` and give the address it prints") from None


@dataclass(frozen=True)
class EngineSettings:
    """How runs are placed: ``workers`` runs at once, ``threads`` Taichi CPU threads each, or
    ``gpus`` GPUs each (then ``--arch gpu``)."""

    workers: int
    threads: int
    gpus: float
    address: str | None


def infeasible(nodes: Sequence[dict[str, float]], threads: int, gpus: float) -> Any:
    """Why no run could ever start on these Ray nodes (their ``Resources``), or None.

    A run asks one node for ``threads`` CPUs (``gpus`` == 0) or for ``gpus`` GPUs and a CPU; Ray
    waits for ever for a request no node can meet (``gpus_per_run = 2`` where nodes have one GPU).
    """
    from projects.schema import Problem

    if not nodes:
        return None
    if gpus > 0:
        most = max(float(n.get("GPU", 0.0)) for n in nodes)
        if gpus > most:
            return Problem("gpus_per_run", gpus, f"more GPUs than any Ray node has ({most:g}): no run could start; "
                           "give at most that, or 0 for CPU runs")
        return None
    most = max(float(n.get("CPU", 0.0)) for n in nodes)
    if threads > most:
        return Problem("threads_per_run", threads, f"more CPUs than any Ray node has ({most:g}): no run could start; "
                       "give at most that")
    return None


class RayEngine:
    """Runs tasks (:func:`execute_run`) on Ray: an embedded local Ray or a cluster at ``address``.

    Use as a context manager; an embedded Ray started here is shut down at the end, a Ray already
    initialised in this process (tests, notebooks) is used as it is.

    Parameters
    ----------
    workers : int, optional
        Runs at once. Local default: the CPU count divided by ``threads``; on a cluster: no cap.
    address : str, optional
        ``ray://HOST:10001`` or ``HOST:6379`` of a running cluster (``ray start --head``), or
        ``auto``.
    threads_per_run : int, optional
        Taichi CPU threads per run; local default ``max(1, cpu_count // workers)``, cluster 1.
    gpus_per_run : float, optional
        GPUs per run; default 1 where Ray sees GPUs, else 0 (CPU runs).
    """

    def __init__(self, workers: int | None = None, address: str | None = None,
                 threads_per_run: int | None = None, gpus_per_run: float | None = None) -> None:
        self._want = (workers, address, threads_per_run, gpus_per_run)
        self._started = False
        #: Seconds ``ray.init`` took (0 where Ray was running already).
        self.startup_s = 0.0
        self.settings: EngineSettings | None = None
        self._remote: Any = None

    def __enter__(self) -> RayEngine:
        import ray

        workers, address, threads, gpus = self._want
        cpus = os.cpu_count() or 1
        if address is None:
            if threads is None:
                threads = max(1, cpus // workers) if workers else 1
            if workers is None:
                workers = max(1, cpus // threads)
        else:
            threads = threads or 1
        if address is not None and not ray.is_initialized():
            check_address(address)
        if not ray.is_initialized():
            kwargs: dict[str, Any] = {"include_dashboard": False, "log_to_driver": False,
                                      "logging_level": logging.WARNING}
            if address is None:
                # "local": always a new embedded Ray, never a cluster that `ray start` left behind
                kwargs.update(address="local", num_cpus=workers * threads)
            else:
                kwargs["address"] = address
            t0 = time.perf_counter()
            ray.init(**kwargs)
            self.startup_s = time.perf_counter() - t0
            self._started = True
        resources = ray.cluster_resources()
        if gpus is None:
            gpus = 1.0 if resources.get("GPU", 0) > 0 else 0.0
        problem = infeasible([node.get("Resources", {}) for node in ray.nodes() if node.get("Alive", True)],
                             threads, gpus)
        if problem:
            self.__exit__(None, None, None)
            from projects.schema import Problem, ProjectError

            raise ProjectError([problem if isinstance(problem, Problem) else Problem("", None, problem)])
        if address is not None and workers is None:
            workers = max(1, int(resources.get("CPU", 1) // threads)) if gpus == 0 else \
                max(1, int(resources.get("GPU", 1) / gpus))
        self.settings = EngineSettings(int(workers), int(threads), float(gpus), address)
        opts: dict[str, Any] = {"num_cpus": threads if gpus == 0 else 1, "max_retries": 0}
        if gpus > 0:
            opts["num_gpus"] = gpus
        self._remote = ray.remote(**opts)(execute_run)
        return self

    def __exit__(self, *exc: object) -> None:
        if self._started:
            import ray

            ray.shutdown()
            self._started = False

    @property
    def arch(self) -> str:
        assert self.settings is not None
        return "gpu" if self.settings.gpus > 0 else "cpu"

    def map(self, tasks: Sequence[dict[str, Any]], cancel: Callable[[], bool] | None = None
            ) -> Iterator[tuple[int, dict[str, Any]]]:
        """Run tasks, at most ``workers`` at once; yield ``(task index, record data)`` as each ends.

        A task whose worker dies yields an ``error`` record. When ``cancel()`` turns true, no
        further task starts and the running ones are cancelled (and yield nothing).
        """
        import ray

        assert self.settings is not None and self._remote is not None
        todo = list(enumerate(tasks))
        todo.reverse()
        running: dict[Any, int] = {}
        submitted: dict[Any, float] = {}
        while todo or running:
            if cancel is not None and cancel():
                for ref in running:
                    ray.cancel(ref, force=True)
                return
            while todo and len(running) < self.settings.workers:
                i, task = todo.pop()
                task = {**task, "threads": self.settings.threads, "arch": self.arch}
                ref = self._remote.remote(task)
                running[ref] = i
                submitted[ref] = time.perf_counter()
            done, _ = ray.wait(list(running), num_returns=1, timeout=0.5)
            for ref in done:
                i = running.pop(ref)
                elapsed = time.perf_counter() - submitted.pop(ref)
                try:
                    data = ray.get(ref)
                except Exception as exc:  # noqa: BLE001 - a dead worker or a crashed task: record it
                    data = RunRecord(run_id=tasks[i]["run_id"], status="error",
                                     message=f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}"
                                     ).to_json()
                if isinstance(data.get("wall_time_s"), (int, float)):
                    data["overhead_s"] = elapsed - data["wall_time_s"]
                yield i, data
