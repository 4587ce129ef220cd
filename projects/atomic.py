"""The one atomic file writer of Runout: project files, results files, reports, sweep folders.

:func:`write_atomic` writes the data to a temporary file beside the target, named
``.NAME.PID.TOKEN.tmp`` (the pattern :mod:`projects.results_folder` clears after a killed run), and
renames it over the target (``os.replace``): a reader sees the old file or the new one, never a
partial one. A failure removes the temporary file and leaves the old file untouched; the error
goes on. The new file keeps the permission bits of the file it replaces (a new file gets the
process's default, ``0o666`` less the umask).

The standard library only: every module of ``projects`` and above may use it.
"""

from __future__ import annotations

import contextlib
import os
import secrets
import stat
from pathlib import Path

__all__ = ["write_atomic"]


def write_atomic(path: str | os.PathLike[str], data: str | bytes, *, durable: bool = False,
                 follow_links: bool = False) -> Path:
    """Replace the file ``path`` with ``data`` atomically.

    Parameters
    ----------
    path : path-like
        The target; its folder must exist.
    data : str or bytes
        Text is written as UTF-8, its line ends as given (no translation).
    durable : bool
        Flush and sync the file before the rename and the folder after it, so the new file
        survives a power cut (project files); off for the many files of a run.
    follow_links : bool
        A symbolic link (also a chain of them) is followed: the file it points to is replaced
        and the link stays a link. Off: the name itself is replaced (a results folder never
        writes through a link to outside itself).

    Returns
    -------
    Path
        The file written (a link's target where ``follow_links``).

    Raises
    ------
    OSError
        When the folder is not writable or the disk is full (the target is unchanged).
    """
    target = Path(path).expanduser()
    if follow_links:
        target = Path(os.path.realpath(target))
    payload = data.encode("utf-8") if isinstance(data, str) else bytes(data)
    try:
        st = os.lstat(target)
        # a link's own bits mean nothing: the new file is an ordinary one
        mode = None if stat.S_ISLNK(st.st_mode) else stat.S_IMODE(st.st_mode)
    except FileNotFoundError:
        mode = None
    tmp = target.with_name(f".{target.name}.{os.getpid()}.{secrets.token_hex(4)}.tmp")
    try:
        with open(tmp, "xb") as handle:
            handle.write(payload)
            if durable:
                handle.flush()
                os.fsync(handle.fileno())
        if mode is not None:
            os.chmod(tmp, mode)
        os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
    if durable:
        _sync_folder(target.parent)
    return target


def _sync_folder(folder: Path) -> None:
    """Make the rename durable where the platform allows syncing a directory."""
    flags = getattr(os, "O_DIRECTORY", None)
    if flags is None:
        return
    with contextlib.suppress(OSError):
        fd = os.open(folder, os.O_RDONLY | flags)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
