"""Runs in a worker thread: the solver (and with it the Taichi runtime) lives and dies in it.

:class:`RunWorker` starts a Python thread that calls :func:`projects.runner.run_project`, so the
Taichi runtime is initialised, used and released in that one thread (docs/DESIGN.md, house
rule 1); a second run is a new worker and a new runtime. The GUI thread only receives signals:

- progress, at most four times per second (the solver reports every few steps);
- frames: the worker keeps the newest frame and the diagnostics of all frames, and signals
  once that something is waiting; the GUI takes them when it is ready
  (:meth:`RunWorker.take`), so a slow view skips frames instead of queueing them;
- the end: ``finishedRun(RunResult)`` when the results folder was written (completed, stopped
  or failed in the solver, with its message), or ``failedToStart(str)`` when the project could
  not be turned into a run (nothing written).

Cancel sets a :class:`projects.runner.StopRequest`, which the solver polls every few steps; the
run then writes one last frame and closes the folder with status "stopped".

A Python thread rather than a QThread: it is joined like any other (``threading.active_count``
tells a leaked one), and the signals it emits reach the GUI thread queued, because the worker
object lives there.
"""

from __future__ import annotations

import logging
import sys
import threading
import time
from pathlib import Path
from typing import Any

from PySide6.QtCore import QObject, Signal

from projects.runner import RunResult, StopRequest

logger = logging.getLogger(__name__)

PROGRESS_INTERVAL_S = 0.25
#: GIL switch interval while a run goes on (s): the GUI thread gets the GIL back sooner.
SWITCH_INTERVAL_S = 0.001


class RunWorker(QObject):
    """One run of a validated project in its own thread.

    Parameters
    ----------
    project : projects.schema.Project
    out_dir : Path
        Results folder (an existing results folder there is replaced).
    project_path : Path, optional
        The project file, recorded in the summary.
    arch : str, optional
        Overrides ``numerics.arch``.
    """

    progressed = Signal(object)  # solver.simulation.Progress
    frameReady = Signal()
    finishedRun = Signal(object)  # RunResult
    failedToStart = Signal(str)

    def __init__(self, project: Any, out_dir: Path, project_path: Path | None = None,
                 arch: str | None = None, parent: Any = None) -> None:
        super().__init__(parent)
        self.setObjectName("runout-solver")
        self._thread: threading.Thread | None = None
        self.project = project
        self.out_dir = Path(out_dir)
        self.project_path = project_path
        self.arch = arch
        self.stop = StopRequest()
        self.result: RunResult | None = None
        self.error: str | None = None
        self._lock = threading.Lock()
        self._frame: Any = None
        self._diagnostics: list[Any] = []
        self._frame_pending = False
        self._last_progress = 0.0
        self.frames_seen = 0
        self.started_at = 0.0
        #: perf_counter times of the cancel request and of the end of the run (for the status line)
        self.cancelled_at: float | None = None
        self.ended_at: float | None = None

    # -- GUI side -------------------------------------------------------------------------------

    def start(self) -> None:
        """Start the run in its thread (once)."""
        if self._thread is not None:
            raise RuntimeError("a RunWorker runs once; make a new one for the next run")
        self._thread = threading.Thread(target=self.run, name="runout-solver", daemon=True)
        self._thread.start()

    def wait(self, timeout_ms: int | None = None) -> bool:
        """Join the thread; True when it has ended."""
        if self._thread is None:
            return True
        self._thread.join(None if timeout_ms is None else timeout_ms / 1000.0)
        return not self._thread.is_alive()

    def is_running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def cancel(self) -> None:
        """Ask the solver to stop at its next check (about every 20 steps)."""
        if self.cancelled_at is None:
            self.cancelled_at = time.perf_counter()
        self.stop.request("the user")

    def take(self) -> tuple[Any, list[Any]]:
        """The newest frame not yet taken (or None) and the diagnostics of every frame since the last call."""
        with self._lock:
            frame, self._frame = self._frame, None
            diagnostics, self._diagnostics = self._diagnostics, []
            self._frame_pending = False
            return frame, diagnostics

    # -- worker side ----------------------------------------------------------------------------

    def _on_frame(self, frame: Any) -> None:
        with self._lock:
            self._frame = frame
            self._diagnostics.append(frame.diagnostics)
            self.frames_seen += 1
            notify = not self._frame_pending
            self._frame_pending = True
        if notify:
            self.frameReady.emit()

    def _on_progress(self, progress: Any) -> None:
        now = time.perf_counter()
        if now - self._last_progress >= PROGRESS_INTERVAL_S:
            self._last_progress = now
            self.progressed.emit(progress)

    def run(self) -> None:
        """The thread's body (call :meth:`start`, not this)."""
        from projects.results import ResultsError
        from projects.runner import run_project
        from projects.schema import ProjectError
        from solver.config import SolverError

        self.started_at = time.perf_counter()
        # Python switches threads every 5 ms by default; each Qt or VTK call of the GUI thread
        # gives up the GIL and then waits up to that long for it while the solver steps
        switch = sys.getswitchinterval()
        sys.setswitchinterval(min(switch, SWITCH_INTERVAL_S))
        try:
            self.result = run_project(
                self.project,
                self.out_dir,
                project_path=self.project_path,
                arch=self.arch,
                cancel=self.stop,
                on_frame=self._on_frame,
                on_progress=self._on_progress,
            )
        except (ProjectError, SolverError, ResultsError, ValueError, OSError) as exc:
            self.error = str(exc)
        except Exception as exc:  # noqa: BLE001 - whatever the solver raises must reach the user
            logger.error("the run could not start: %s", exc, exc_info=True)
            self.error = f"{type(exc).__name__}: {exc}"
        finally:
            sys.setswitchinterval(switch)
            self.ended_at = time.perf_counter()
        if self.result is not None:
            self.finishedRun.emit(self.result)
        else:
            self.failedToStart.emit(self.error or "the run did not start")
