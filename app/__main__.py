"""``python -m app`` and the ``runout`` script: the command line, also quiet on an early Ctrl-C.

The command line's module imports typer and rich, which takes a moment; a Ctrl-C then (or any
time before a command installs its own signal handling) ends with one line and status 130
instead of a traceback.
"""

from __future__ import annotations

import sys


def main(argv: list[str] | None = None) -> int:
    """Run ``runout`` with ``argv`` (default: the process arguments); the exit status."""
    try:
        from app.cli import main as cli_main

        cli_main(argv)
    except KeyboardInterrupt:
        sys.stderr.write("error: interrupted (Ctrl-C)\n")
        return 130
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
