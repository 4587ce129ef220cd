"""Reading the text files a user names (project, sweep and calibration files, observations).

:func:`read_text` refuses what would hang or fill memory before reading a byte of it: a name
that is not a regular file (``/dev/zero`` never ends, a FIFO with no writer blocks the open
forever, a folder), and a file larger than the limit given (a project file of more than
:data:`MAX_PROJECT_FILE_BYTES`). The file is opened without blocking and checked again on the
open descriptor, so that a file swapped for a FIFO between the two checks is refused too, and at
most the limit is read. Every refusal is one :class:`~projects.schema.ProjectError` line naming
the file, what it is and what is allowed.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

from geometry.importers import file_kind
from projects.schema import Problem, ProjectError

#: The largest project file read (bytes): 100,000 outline points with full-precision
#: coordinates take about 4.5 MB; 8 MB parses in about 2 s.
MAX_PROJECT_FILE_BYTES = 8_000_000
#: The largest sweep or calibration file read (bytes).
MAX_SPEC_FILE_BYTES = 1_000_000
#: The largest observation file (CSV of points) read (bytes).
MAX_OBSERVATION_FILE_BYTES = 16_000_000


def _size(count: int) -> str:
    for unit, size in (("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if count >= size:
            return f"{count / size:.3g} {unit}"
    return f"{count} B"


def read_bytes(path: str | os.PathLike[str], *, what: str, max_bytes: int) -> bytes:
    """The bytes of a regular file of at most ``max_bytes``.

    Parameters
    ----------
    path : path-like
    what : str
        What the file is, for the messages ("the file", "the sweep file").
    max_bytes : int
        The largest size read.

    Raises
    ------
    ProjectError
        One problem, with the file's name as its source: it cannot be read, is not a regular file,
        or is larger than ``max_bytes``.
    """
    name = str(path)

    def refuse(message: str) -> ProjectError:
        return ProjectError([Problem("", None, message)], name)

    try:
        mode = os.stat(path).st_mode  # follows links; opens nothing (a FIFO's open would block)
    except OSError as exc:
        raise refuse(f"cannot read {what}: {exc.strerror or exc}") from None
    if not stat.S_ISREG(mode):
        raise refuse(f"cannot read {what}: it is {file_kind(mode)}, not a regular file")
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0)
    try:
        fd = os.open(path, flags)
    except OSError as exc:
        raise refuse(f"cannot read {what}: {exc.strerror or exc}") from None
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):  # replaced between the two looks
            raise refuse(f"cannot read {what}: it is {file_kind(info.st_mode)}, not a regular file")
        if info.st_size > max_bytes:
            raise refuse(f"{what} is {_size(info.st_size)}, more than the limit of {_size(max_bytes)}")
        chunks, total = [], 0
        while True:
            chunk = os.read(fd, min(1 << 20, max_bytes + 1 - total))
            if not chunk:
                break
            chunks.append(chunk)
            total += len(chunk)
            if total > max_bytes:  # it grew while read
                raise refuse(f"{what} is more than the limit of {_size(max_bytes)}")
    except OSError as exc:
        raise refuse(f"cannot read {what}: {exc.strerror or exc}") from None
    finally:
        os.close(fd)
    return b"".join(chunks)


def read_text(path: str | os.PathLike[str], *, what: str = "the file", max_bytes: int = MAX_PROJECT_FILE_BYTES) -> str:
    """The UTF-8 text of a regular file of at most ``max_bytes`` (see :func:`read_bytes`).

    Raises
    ------
    ProjectError
        As :func:`read_bytes`, and for text that is not UTF-8.
    """
    data = read_bytes(path, what=what, max_bytes=max_bytes)
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ProjectError([Problem("", None, f"not UTF-8 text: {exc.reason}")], str(Path(path))) from None
    return text.replace("\r\n", "\n").replace("\r", "\n")  # universal newlines, as Path.read_text


__all__ = ["MAX_OBSERVATION_FILE_BYTES", "MAX_PROJECT_FILE_BYTES", "MAX_SPEC_FILE_BYTES", "read_bytes", "read_text"]
