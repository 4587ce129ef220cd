"""What every command of the ``runout`` command line shares: the exit codes, the rich consoles
(standard output for results, standard error for progress and errors), the one-line error exit
and the signal handling that turns Ctrl-C, SIGTERM and SIGHUP into a stop request.

:mod:`app.cli` and :mod:`app.sweep_commands` both take them from here.
"""

from __future__ import annotations

import contextlib
import signal
import sys
from collections.abc import Iterator
from typing import TYPE_CHECKING, Any, NoReturn

import typer

if TYPE_CHECKING:  # pragma: no cover - typing only
    from projects.runner import StopRequest

EXIT_OK = 0
EXIT_INVALID = 1
EXIT_FAILED = 3
EXIT_SIGINT = 128 + signal.SIGINT
EXIT_SIGTERM = 128 + signal.SIGTERM
EXIT_SIGHUP = 128 + getattr(signal, "SIGHUP", 1)
#: Signals that stop a run cleanly (the terminal closing sends SIGHUP).
STOP_SIGNALS = tuple(
    getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name)
)


class LazyConsole:
    """A rich ``Console`` made at its first use: importing rich costs about 20 ms, which every
    ``runout run`` would pay before its first step (docs/performance.md, start-up)."""

    def __init__(self, **options: Any):
        self._options = options
        self._console: Any = None

    def get(self) -> Any:
        """The console itself (for rich objects that take one)."""
        if self._console is None:
            from rich.console import Console

            self._console = Console(**self._options)
        return self._console

    def __getattr__(self, name: str) -> Any:
        return getattr(self.get(), name)


out = LazyConsole(soft_wrap=True, highlight=False)
err = LazyConsole(stderr=True, soft_wrap=True, highlight=False)


def fail(message: str, code: int = EXIT_INVALID) -> NoReturn:
    """Print ``error: message`` on standard error and exit with ``code``."""
    err.print(f"error: {message}", markup=False)
    raise typer.Exit(code)


@contextlib.contextmanager
def stop_on_signals(stop: StopRequest) -> Iterator[StopRequest]:
    """Turn SIGINT, SIGTERM and SIGHUP into a stop request while the block runs.

    A second Ctrl-C raises KeyboardInterrupt, for a solver that does not reach its next check:
    once, and not while the run finishes its results folder (``stop.may_interrupt()``, where the
    request has it: :class:`projects.runner.StopRequest`); later ones only repeat the request.
    Outside the main thread (signals cannot be caught there) the block runs unchanged.
    """

    def handler(signum: int, _frame: object) -> None:
        repeated = stop.requested
        stop.request(signal.Signals(signum).name)
        if repeated and signum == signal.SIGINT:
            may = getattr(stop, "may_interrupt", None)
            if may is None or may():
                raise KeyboardInterrupt

    if sys.platform == "win32" or not in_main_thread():
        yield stop
        return
    previous = {sig: signal.signal(sig, handler) for sig in STOP_SIGNALS}
    try:
        yield stop
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)


def in_main_thread() -> bool:
    import threading

    return threading.current_thread() is threading.main_thread()
