"""``python -m app`` and the ``runout`` script: the command line, also quiet on an early Ctrl-C.

The command line's module imports typer and rich, which takes a moment; a Ctrl-C then (or any
time before a command installs its own signal handling) ends with one line and status 130
instead of a traceback.
"""

from __future__ import annotations

import os
import signal
import sys


def _interrupted_while_starting(_signum: int, _frame: object) -> None:
    # nothing is written yet: leave at once, with one line and no interpreter clean-up that
    # could meet a second KeyboardInterrupt
    os.write(2, b"error: interrupted (Ctrl-C) while starting\n")
    os._exit(130)


def main(argv: list[str] | None = None) -> int:
    """Run ``runout`` with ``argv`` (default: the process arguments); the exit status."""
    if hasattr(signal, "SIGINT"):
        signal.signal(signal.SIGINT, _interrupted_while_starting)
    # pydantic looks for plugins among every installed package's entry points at its first model
    # (importlib.metadata: about 20 ms of every run's start); Runout uses none. Setting the
    # variable, even empty, before starting ``runout`` restores the lookup.
    os.environ.setdefault("PYDANTIC_DISABLE_PLUGINS", "__all__")
    try:
        from app.cli import main as cli_main

        cli_main(argv)
    except KeyboardInterrupt:
        cli = sys.modules.get("app.cli")
        if not getattr(cli, "INTERRUPT_SHOWN", False):
            sys.stderr.write("error: interrupted (Ctrl-C)\n")
        return 130
    finally:
        if argv is None:
            _ignore_stop_signals_while_exiting()
            _exit_with_the_status_returned()
    return 0


def _exit_with_the_status_returned() -> None:
    """Keep CPython from ending the process with SIGINT (status -2) after a Ctrl-C that Runout
    handled (one line, status 130). CPython sets a process-wide flag when a KeyboardInterrupt leaves
    code run through its ``PyRun_*`` entry points (which some extension modules use while Runout
    starts), whoever catches the exception later, and at exit kills itself with SIGINT when the
    flag is set (about one Ctrl-C in ten during the first 0.4 s of a run, measured). Clearing it
    leaves the exit status the command chose. CPython only; elsewhere nothing to do."""
    try:
        import ctypes

        ctypes.c_int.in_dll(ctypes.pythonapi, "_Py_UnhandledKeyboardInterrupt").value = 0
    except (AttributeError, ValueError, OSError):
        pass


def _ignore_stop_signals_while_exiting() -> None:
    """The command is done (its results and status written): a Ctrl-C or SIGTERM from now on is
    ignored while the process exits. Python's finalisation puts the default handlers back
    (except "ignore"), so a signal arriving there would kill the process with no word and a
    misleading exit status (-2) although everything was saved. Process-wide: Taichi's worker
    threads would take a signal that one thread blocked."""
    for name in ("SIGINT", "SIGTERM", "SIGHUP"):
        if hasattr(signal, name):
            signal.signal(getattr(signal, name), signal.SIG_IGN)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
