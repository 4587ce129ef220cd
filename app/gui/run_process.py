"""A run is a process: ``runout run`` as a child of the workbench, followed through a pipe and its folder.

:class:`RunProcess` starts ``python -m app run PROJECT --out DIR --progress jsonl`` with a
:class:`~PySide6.QtCore.QProcess` (no thread of ours: Qt watches the pipes in its event loop). The
child prints one JSON object per line (see :class:`app.cli._JsonProgress`): ``started``,
``progress``, ``frame`` and ``finished``; this object turns them into signals. The frames
themselves are never sent through the pipe: whoever shows the run reads them from the results
folder (:class:`projects.results.Results`), the same way as a finished or a killed run's folder.

The workbench process never imports Taichi; the solver, its runtime and any crash of it live in
the child. The project that runs is a temporary copy of the document (the user's file is left
alone, unsaved edits included). Cancel sends SIGTERM, which ``runout run`` turns into a stopped
run with its final frame and status (so does the death of the workbench: the child asks Linux
for SIGTERM when its parent dies, ``RUNOUT_STOP_WITH_PARENT``); if the child has not ended :data:`KILL_AFTER_MS` later it
gets SIGKILL. A child that dies without a ``finished`` line (killed, crashed) ends with status
``"killed"`` (by a signal) or ``"crashed"`` (an exit code) and a message saying so; its folder
reads up to its last complete frame.
"""

from __future__ import annotations

import json
import logging
import os
import shutil
import signal
import tempfile
import time
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from PySide6.QtCore import QObject, QProcess, QProcessEnvironment, QTimer, Signal

logger = logging.getLogger(__name__)

#: Milliseconds between SIGTERM (cancel) and SIGKILL when the child has not ended.
KILL_AFTER_MS = 10_000
#: Lines of the child's standard error kept for messages.
STDERR_LINES = 40
#: The folder that holds the ``app`` package (put on the child's PYTHONPATH).
REPO_ROOT = Path(__file__).resolve().parents[2]

#: Statuses a run can end with: those of ``summary.json`` plus the ones only a parent can see.
ENDED = ("completed", "stopped", "failed", "error", "killed", "crashed")


@dataclass
class RunOutcome:
    """How a child run ended.

    Attributes
    ----------
    status : str
        One of :data:`ENDED`: "completed", "stopped", "failed" (as in ``summary.json``),
        "error" (it could not start: the message says why, nothing was written), "killed" (by
        a signal, without closing its folder) or "crashed" (exited without a final line).
    message : str
        One line for the user.
    out_dir : Path
    summary : dict
        The final summary ("completed", "stopped", "failed"), else empty.
    exit_code : int
        The child's exit code, or the number of the signal that killed it.
    """

    status: str
    message: str
    out_dir: Path
    summary: dict[str, Any] = field(default_factory=dict)
    exit_code: int = 0


def _signal_name(number: int) -> str:
    try:
        return signal.Signals(number).name
    except ValueError:
        return f"signal {number}"


class RunProcess(QObject):
    """One run of a project in a child process.

    Parameters
    ----------
    project_text : str
        The project (TOML) to run, written to a temporary file for the child.
    out_dir : Path
        The results folder (``--out``).
    name : str
        What the run list calls it (the project file's stem).
    arch : str, optional
        ``--arch`` for the child.
    overwrite : bool
        ``--overwrite``: replace an earlier run's results in ``out_dir`` (the user said so).
    source : Path, optional
        ``--source``: the user's project file, which the run's summary names (not the temporary
        copy it runs).
    unsaved : bool
        ``--unsaved``: the project holds edits not saved in ``source``, or has no file.
    resume : bool
        ``--resume OUT_DIR``: continue the killed or stopped run in ``out_dir`` from its last
        checkpoint (``project_text`` is not used: the folder's ``project.toml`` runs).

    Signals
    -------
    runStarted(dict)
        The ``started`` event: the folder exists (``out_dir``, ``particles``, ``total_time_s``).
    progressed(dict)
        A ``progress`` event (``time_s``, ``total_time_s``, ``stage``, ``step``, ``steps_per_s``,
        ``particle_steps_per_s``).
    frameWritten(dict)
        A ``frame`` event (``index``, ``time_s``).
    ended(RunOutcome)
        The child has ended, whichever way.
    """

    runStarted = Signal(dict)
    progressed = Signal(dict)
    frameWritten = Signal(dict)
    ended = Signal(object)

    def __init__(self, project_text: str, out_dir: Path, name: str = "untitled", arch: str | None = None,
                 overwrite: bool = False, source: Path | None = None, unsaved: bool = False,
                 resume: bool = False, parent: QObject | None = None) -> None:
        super().__init__(parent)
        self.resume = resume
        self.name = name
        self.source = source
        self.unsaved = unsaved
        self.title = name
        self.out_dir = Path(out_dir).expanduser().absolute()
        self.project_text = project_text
        self.arch = arch
        self.overwrite = overwrite
        self.process = QProcess(self)
        self.process.readyReadStandardOutput.connect(self._read_stdout)
        self.process.readyReadStandardError.connect(self._read_stderr)
        self.process.finished.connect(self._finished)
        self.process.errorOccurred.connect(self._error)
        self._stdout = b""
        self._stderr = b""
        self.stderr_lines: deque[str] = deque(maxlen=STDERR_LINES)
        self.events: list[dict[str, Any]] = []
        self.warnings: list[str] = []
        self.started_event: dict[str, Any] | None = None
        self.last_progress: dict[str, Any] | None = None
        self.finished_event: dict[str, Any] | None = None
        self.frames = 0
        self.outcome: RunOutcome | None = None
        self.cancel_requested = False
        self.started_at = 0.0
        self.ended_at: float | None = None
        self._tmp: Path | None = None
        self._kill_timer = QTimer(self)
        self._kill_timer.setSingleShot(True)
        self._kill_timer.timeout.connect(self.kill)

    # -- control --------------------------------------------------------------------------------

    def command(self) -> list[str]:
        """The child's command line (after writing the temporary project file)."""
        if self._tmp is None:
            self._tmp = Path(tempfile.mkdtemp(prefix="runout-run-"))
        from projects.runner import runout_command

        if self.resume:  # the folder's own project.toml, provenance and settings: nothing else is given
            args = runout_command("run", "--resume", str(self.out_dir), "--progress", "jsonl")
            if self.arch in ("cpu", "gpu"):
                args += ["--arch", self.arch]
            return args
        project_file = self._tmp / f"{self.name}.toml"
        project_file.write_text(self.project_text, encoding="utf-8")
        args = runout_command("run", str(project_file), "--out", str(self.out_dir), "--progress", "jsonl")
        if self.arch in ("cpu", "gpu"):
            args += ["--arch", self.arch]
        if self.overwrite:
            args.append("--overwrite")  # the user chose to replace an earlier run's results there
        # the provenance is the user's project, not the temporary copy above
        if self.source is not None:
            args += ["--source", str(self.source)]
        if self.unsaved:
            args.append("--unsaved")
        return args

    def start(self) -> None:
        """Start the child (once)."""
        if self.process.state() != QProcess.ProcessState.NotRunning or self.started_at:
            raise RuntimeError("a RunProcess runs once; make a new one for the next run")
        program, *args = self.command()
        env = QProcessEnvironment.systemEnvironment()
        paths = [str(REPO_ROOT), *[p for p in env.value("PYTHONPATH", "").split(os.pathsep) if p]]
        env.insert("PYTHONPATH", os.pathsep.join(dict.fromkeys(paths)))
        env.insert("PYTHONUNBUFFERED", "1")
        env.insert("ENABLE_TAICHI_HEADER_PRINT", "0")
        # the run stops (SIGTERM, a "stopped" folder) if the workbench dies without stopping it
        env.insert("RUNOUT_STOP_WITH_PARENT", str(os.getpid()))
        self.process.setProcessEnvironment(env)
        self.process.setWorkingDirectory(str(self._tmp))
        self.started_at = time.perf_counter()
        logger.info("starting %s", " ".join([program, *args]))
        self.process.start(program, args)

    @property
    def pid(self) -> int:
        return int(self.process.processId())

    def is_running(self) -> bool:
        return self.outcome is None and self.started_at > 0

    def cancel(self) -> None:
        """Ask the run to stop (SIGTERM: it writes a last frame and closes its folder as
        "stopped"); SIGKILL follows if it has not ended :data:`KILL_AFTER_MS` later."""
        if not self.is_running():
            return
        self.cancel_requested = True
        if self.process.state() != QProcess.ProcessState.NotRunning:
            self.process.terminate()  # SIGTERM on POSIX
            if not self._kill_timer.isActive():
                self._kill_timer.start(KILL_AFTER_MS)

    def kill(self) -> None:
        """End the child at once (SIGKILL); its folder stays readable up to its last frame."""
        if self.process.state() != QProcess.ProcessState.NotRunning:
            self.process.kill()

    def wait(self, timeout_ms: int = 30_000) -> bool:
        """Block until the child has ended (scripts, shutdown); True when it has."""
        if self.outcome is not None or not self.started_at:
            return True
        if self.process.state() != QProcess.ProcessState.NotRunning:
            self.process.waitForFinished(timeout_ms)
        if self.process.state() == QProcess.ProcessState.NotRunning and self.outcome is None:
            self._finished(self.process.exitCode(), self.process.exitStatus())
        return self.outcome is not None

    @property
    def status(self) -> str:
        """"starting", "running", "stopping" or how it ended."""
        if self.outcome is not None:
            return self.outcome.status
        if self.cancel_requested:
            return "stopping"
        return "running" if self.started_event is not None else "starting"

    # -- the pipes ------------------------------------------------------------------------------

    def _read_stdout(self) -> None:
        self._stdout += bytes(self.process.readAllStandardOutput().data())
        *lines, self._stdout = self._stdout.split(b"\n")
        for line in lines:
            self._handle_line(line)

    def _read_stderr(self) -> None:
        self._stderr += bytes(self.process.readAllStandardError().data())
        *lines, self._stderr = self._stderr.split(b"\n")
        for line in lines:
            text = line.decode("utf-8", "replace").rstrip()
            if text:
                self.stderr_lines.append(text)

    def _handle_line(self, line: bytes) -> None:
        text = line.decode("utf-8", "replace").strip()
        if not text:
            return
        try:
            event = json.loads(text)
        except json.JSONDecodeError:
            logger.debug("run %s printed: %s", self.name, text)
            return
        if not isinstance(event, dict):
            return
        kind = event.get("event")
        if kind != "progress":
            self.events.append(event)
        if kind == "started":
            self.started_event = event
            self.runStarted.emit(event)
        elif kind == "progress":
            self.last_progress = event
            self.progressed.emit(event)
        elif kind == "frame":
            self.frames += 1
            self.frameWritten.emit(event)
        elif kind == "warning":
            self.warnings.append(str(event.get("message", "")))
        elif kind == "finished":
            self.finished_event = event

    def _error(self, error: QProcess.ProcessError) -> None:
        if error == QProcess.ProcessError.FailedToStart and self.outcome is None:
            self._end(RunOutcome("error", f"the run process could not start: {self.process.errorString()}",
                                 self.out_dir, {}, -1))

    def _finished(self, exit_code: int, exit_status: QProcess.ExitStatus) -> None:
        if self.outcome is not None:
            return
        self._read_stdout()
        self._read_stderr()
        if self._stdout:
            self._handle_line(self._stdout)
            self._stdout = b""
        if self._stderr:
            self.stderr_lines.append(self._stderr.decode("utf-8", "replace").rstrip())
            self._stderr = b""
        event = self.finished_event
        # Cancelled before the child reported its results folder: it ended on the SIGTERM during its
        # start-up (before its handler was installed, or with "stopped ... before the run started").
        # That is the stop the user asked for, not an abnormal end; this run wrote no frame.
        early_stop = self.cancel_requested and self.started_event is None and (
            (event is not None and event.get("status") == "error")
            or (event is None and exit_status == QProcess.ExitStatus.CrashExit and int(exit_code) == signal.SIGTERM))
        if early_stop:
            outcome = RunOutcome("stopped", "cancelled before the run started", self.out_dir, {}, int(exit_code))
        elif event is not None:
            outcome = RunOutcome(str(event.get("status", "failed")), str(event.get("message", "")),
                                 Path(event.get("out_dir") or self.out_dir), dict(event.get("summary") or {}),
                                 int(exit_code))
        elif exit_status == QProcess.ExitStatus.CrashExit:
            name = _signal_name(int(exit_code))
            outcome = RunOutcome("killed", f"the run process was killed by {name}"
                                 f"{' after the cancel request' if self.cancel_requested else ''}, "
                                 "without closing its results folder", self.out_dir, {}, int(exit_code))
        else:
            last = next((line for line in reversed(self.stderr_lines) if line.strip()), "")
            outcome = RunOutcome("crashed", f"the run process ended with exit code {exit_code}"
                                 f"{': ' + last if last else ''}", self.out_dir, {}, int(exit_code))
        self._end(outcome)

    def _end(self, outcome: RunOutcome) -> None:
        self._kill_timer.stop()
        self.outcome = outcome
        self.ended_at = time.perf_counter()
        if self._tmp is not None:
            shutil.rmtree(self._tmp, ignore_errors=True)
        logger.info("run %s %s: %s", self.name, outcome.status, outcome.message)
        self.ended.emit(outcome)
