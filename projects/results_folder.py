"""Who owns a results folder: its marker, its lock, and the only files a run may delete.

A results folder belongs to the run that made it. The rules (``docs/project-format.md``):

- A run writes a marker file, :data:`MARKER_NAME`, listing the names and patterns of the files
  it writes (``summary.json``, ``frames/frame_*.vtp``, ...). Only files matching the marker are
  ever deleted; anything else in the folder (notes, figures, a project file) is never touched.
- A folder holding an earlier run's results is replaced only when asked (``overwrite=True``,
  the command line's ``--overwrite``), and then only the earlier run's own files are removed.
  A non-empty folder without a marker is refused outright.
- While a run writes, it holds a lock on the folder: :data:`LOCK_NAME` with its process id,
  locked with ``flock`` (released by the kernel when the process dies, so the lock of a killed
  run is recognised as stale and taken over). A second run into the same folder gets
  :class:`ResultsLockedError` naming the process that holds it. Where ``flock`` is not
  available the lock file is created exclusively and a stale one is recognised by its process
  id no longer running.
"""

from __future__ import annotations

import contextlib
import errno
import json
import logging
import os
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path, PurePosixPath

from projects.atomic import write_atomic

try:
    import fcntl
except ImportError:  # pragma: no cover - Windows
    fcntl = None  # type: ignore[assignment]

logger = logging.getLogger(__name__)

#: The marker file of a results folder (JSON: format, version, own file patterns).
MARKER_NAME = ".runout-results"
#: The lock file a run holds while it writes (its process id inside).
LOCK_NAME = ".runout-results.lock"
#: Space kept free by a run so that its final ``summary.json`` fits on a full disk.
RESERVE_NAME = ".runout-reserve"
MARKER_FORMAT = "runout-results"
MARKER_VERSION = 1
#: Files every run writes, relative to the folder (``fnmatch`` patterns, ``/`` separated).
BASE_PATTERNS: tuple[str, ...] = (
    "particles.pvd",
    "series.csv",
    "summary.json",
    "project.toml",
    "frames/frame_*.vtp",
    "checkpoint.npz",
    "contacts.csv",
    RESERVE_NAME,
)


class ResultsError(Exception):
    """A results folder cannot be written, or what is read is not a results folder."""


class ResultsExistError(ResultsError):
    """The folder holds the results of an earlier run (replace them with ``overwrite=True``)."""


class ResultsLockedError(ResultsError):
    """Another running process writes into the folder."""


# --------------------------------------------------------------------------------------------
# marker


def read_marker(folder: str | os.PathLike[str]) -> dict | None:
    """The marker of a results folder, or None when there is none (or it is not ours)."""
    path = Path(folder) / MARKER_NAME
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError, UnicodeDecodeError):
        return None
    if not isinstance(data, dict) or data.get("format") != MARKER_FORMAT:
        return None
    if not isinstance(data.get("files"), list):
        return None
    return data


def write_marker(folder: str | os.PathLike[str], patterns: Iterable[str]) -> None:
    """Write the marker listing the run's own file patterns (atomically).

    Raises
    ------
    ValueError
        For a pattern that could leave the folder (absolute, ``..``).
    """
    patterns = list(dict.fromkeys(patterns))
    for pattern in patterns:
        _check_pattern(pattern)
    folder = Path(folder)
    text = json.dumps({"format": MARKER_FORMAT, "version": MARKER_VERSION, "files": patterns}, indent=1)
    write_atomic(folder / MARKER_NAME, text + "\n")


def _check_pattern(pattern: str) -> PurePosixPath:
    pure = PurePosixPath(pattern)
    if pure.is_absolute() or ".." in pure.parts or not pure.parts:
        raise ValueError(f"a results file pattern must stay inside the folder, got {pattern!r}")
    return pure


def own_files(folder: str | os.PathLike[str], patterns: Iterable[str]) -> list[Path]:
    """The files in ``folder`` that match the run's own patterns, with their temporary files.

    A temporary file of an own file ``NAME`` is ``.NAME.*.tmp`` in the same folder (what the
    atomic writes leave when a run is killed mid-write).

    Returns
    -------
    list of Path
        Existing files (symbolic links count as files; folders never match).
    """
    folder = Path(folder)
    found: dict[Path, None] = {}
    for pattern in patterns:
        try:
            pure = _check_pattern(pattern)
        except ValueError:
            logger.warning("ignoring the marker entry %r of %s", pattern, folder)
            continue
        parent = folder.joinpath(*pure.parts[:-1])
        if not parent.is_dir() or parent.is_symlink():
            continue
        for glob in (pure.name, f".{pure.name}.*.tmp"):
            for path in parent.glob(glob):
                if path.is_symlink() or path.is_file():
                    found[path] = None
    return list(found)


def clear_own_files(folder: str | os.PathLike[str], patterns: Iterable[str]) -> int:
    """Delete the run's own files (see :func:`own_files`) and its folders left empty.

    Returns
    -------
    int
        Files removed.
    """
    folder = Path(folder)
    patterns = list(patterns)
    removed = 0
    for path in own_files(folder, patterns):
        with contextlib.suppress(FileNotFoundError):
            path.unlink()
            removed += 1
    subfolders = {PurePosixPath(p).parts[0] for p in patterns if len(PurePosixPath(p).parts) > 1}
    for name in subfolders:
        with contextlib.suppress(OSError):  # not empty (the user's files) or not there
            (folder / name).rmdir()
    return removed


def remove_temp_files(folder: str | os.PathLike[str], patterns: Iterable[str], pid: int | None = None) -> int:
    """Delete the temporary files of the run's own files (those of process ``pid``, or all).

    Returns
    -------
    int
        Files removed.
    """
    folder = Path(folder)
    removed = 0
    for pattern in patterns:
        pure = PurePosixPath(pattern)
        parent = folder.joinpath(*pure.parts[:-1])
        if not parent.is_dir():
            continue
        middle = "*" if pid is None else str(pid)
        # .NAME.PID.TOKEN.tmp (projects.atomic.write_atomic); .NAME.PID.tmp of older versions
        for glob in (f".{pure.name}.{middle}.*.tmp", f".{pure.name}.{middle}.tmp"):
            for path in parent.glob(glob):
                with contextlib.suppress(OSError):
                    path.unlink()
                    removed += 1
    return removed


# --------------------------------------------------------------------------------------------
# lock


@dataclass
class FolderLock:
    """A held lock on a results folder; :meth:`release` it (idempotent). ``created_folder``: the
    folder did not exist before this run made it (a run that cannot start removes it again)."""

    path: Path
    fd: int | None
    created_folder: bool = False

    def release(self) -> None:
        if self.fd is None:
            return
        fd, self.fd = self.fd, None
        try:
            same = os.stat(self.path).st_ino == os.fstat(fd).st_ino
        except OSError:
            same = False
        if same:
            with contextlib.suppress(OSError):
                self.path.unlink()
        with contextlib.suppress(OSError):
            os.close(fd)


def _read_pid(path: Path) -> int | None:
    try:
        text = path.read_text(encoding="ascii", errors="replace").split()
        return int(text[0]) if text else None
    except (OSError, ValueError):
        return None


def _alive(pid: int) -> bool:
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _locked_message(folder: Path, pid: int | None) -> str:
    who = f"process {pid}" if pid else "another process"
    return f"{folder} is in use by another run ({who}); wait for it to end or choose another folder"


def lock_folder(folder: str | os.PathLike[str]) -> FolderLock:
    """Lock a results folder for this process.

    Parameters
    ----------
    folder : path-like
        An existing folder.

    Returns
    -------
    FolderLock

    Raises
    ------
    ResultsLockedError
        When a running process holds the lock.
    ResultsError
        When the lock file cannot be created (read-only folder, ...).
    """
    folder = Path(folder)
    path = folder / LOCK_NAME
    for _ in range(5):
        try:
            if fcntl is None:
                return _lock_exclusive(folder, path)
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as err:
            raise ResultsError(f"cannot write results to {folder}: {err.strerror or err}") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            raise ResultsLockedError(_locked_message(folder, _read_pid(path))) from None
        except OSError as err:
            os.close(fd)
            if err.errno in (errno.ENOLCK, errno.EOPNOTSUPP, errno.ENOSYS):
                return _lock_exclusive(folder, path)
            raise ResultsError(f"cannot lock {path}: {err.strerror or err}") from None
        try:
            same = os.stat(path).st_ino == os.fstat(fd).st_ino
        except FileNotFoundError:
            same = False
        if not same:  # the holder released it between our open and flock: try again
            os.close(fd)
            continue
        old = _read_pid(path)
        if old is not None and old != os.getpid():
            logger.info("taking over the stale lock of %s (process %d is not running)", folder, old)
        try:
            os.ftruncate(fd, 0)
            os.write(fd, f"{os.getpid()}\n".encode("ascii"))
        except OSError as err:
            # a full disk: the empty file is no lock of anyone's (a run with --force onto a full
            # disk left it behind, and no summary.json)
            FolderLock(path, fd).release()
            raise ResultsError(f"cannot write results to {folder}: {err.strerror or err}") from None
        return FolderLock(path, fd)
    raise ResultsLockedError(_locked_message(folder, _read_pid(path)))


def _lock_exclusive(folder: Path, path: Path) -> FolderLock:
    """The fallback without ``flock``: create the lock file exclusively, break stale ones."""
    for _ in range(2):
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_EXCL, 0o644)
        except FileExistsError:
            pid = _read_pid(path)
            if pid is not None and _alive(pid):
                raise ResultsLockedError(_locked_message(folder, pid)) from None
            logger.info("removing the stale lock of %s (process %s is not running)", folder, pid)
            with contextlib.suppress(FileNotFoundError):
                path.unlink()
            continue
        except OSError as err:
            raise ResultsError(f"cannot write results to {folder}: {err.strerror or err}") from None
        try:
            os.write(fd, f"{os.getpid()}\n".encode("ascii"))
        except OSError as err:
            FolderLock(path, fd).release()
            raise ResultsError(f"cannot write results to {folder}: {err.strerror or err}") from None
        return FolderLock(path, fd)
    raise ResultsLockedError(_locked_message(folder, _read_pid(path)))


def lock_holder(folder: str | os.PathLike[str]) -> int | None:
    """The process id of a live run holding ``folder``'s lock, or None (no lock, or stale)."""
    path = Path(folder) / LOCK_NAME
    if not path.is_file():
        return None
    pid = _read_pid(path)
    if fcntl is not None:
        try:
            fd = os.open(path, os.O_RDONLY)
        except OSError:
            return None
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except BlockingIOError:
            return pid or -1
        except OSError:
            return pid if pid is not None and _alive(pid) else None
        finally:
            os.close(fd)
        return None
    return pid if pid is not None and _alive(pid) else None


# --------------------------------------------------------------------------------------------
# the policy


def _contents(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name != LOCK_NAME)


def _looks_like_results(names: list[str]) -> bool:
    return any(n in ("summary.json", "particles.pvd", "frames") for n in names)


def check_results_dir(path: str | os.PathLike[str], *, overwrite: bool = False) -> Path:
    """Whether a run may write into ``path`` (changes nothing; the writer checks again, locked).

    Parameters
    ----------
    path : path-like
    overwrite : bool
        Whether an earlier run's results there may be replaced.

    Returns
    -------
    Path
        The absolute folder path.

    Raises
    ------
    ResultsExistError
        The folder holds an earlier run's results and ``overwrite`` is False.
    ResultsLockedError
        A running process writes into it.
    ResultsError
        The path is a file, or a non-empty folder that is not a Runout results folder.
    """
    folder = Path(path).expanduser().absolute()
    if not folder.exists():
        if folder.is_symlink():
            raise ResultsError(f"{folder} is a broken symbolic link")
        return folder
    if not folder.is_dir():
        raise ResultsError(f"{folder} exists and is not a folder")
    pid = lock_holder(folder)
    if pid is not None:
        raise ResultsLockedError(_locked_message(folder, pid if pid > 0 else None))
    _judge_contents(folder, overwrite)
    return folder


def _judge_contents(folder: Path, overwrite: bool) -> dict | None:
    """The marker when the folder may be used; raise when it may not."""
    try:
        names = _contents(folder)
    except OSError as err:
        raise ResultsError(f"cannot read {folder}: {err.strerror or err}") from None
    if not names:
        return None
    marker = read_marker(folder)
    if marker is None:
        if _looks_like_results(names):
            raise ResultsError(
                f"{folder} holds results without a Runout marker (an older version's?); "
                "delete them yourself or choose another output folder"
            )
        raise ResultsError(
            f"{folder} is not empty and is not a results folder; refusing to overwrite it "
            "(choose another output folder)"
        )
    if not overwrite:
        raise ResultsExistError(
            f"{folder} holds the results of an earlier run; use --overwrite to replace them "
            "(only that run's own files are removed) or choose another folder"
        )
    return marker


def open_results_dir(
    path: str | os.PathLike[str], *, overwrite: bool = False, patterns: Iterable[str] = BASE_PATTERNS
) -> tuple[Path, FolderLock]:
    """Create or take over a results folder for a new run, locked.

    The folder is created when missing; an earlier run's own files are removed when
    ``overwrite`` (nothing else is touched); the marker is written with ``patterns``.

    Returns
    -------
    (Path, FolderLock)
        The absolute folder and the held lock (release it when the run ends).

    Raises
    ------
    ResultsExistError, ResultsLockedError, ResultsError
        As :func:`check_results_dir`, and when the folder cannot be created or written.
    """
    folder = check_results_dir(path, overwrite=overwrite)
    created = not folder.exists()
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise ResultsError(f"cannot write results to {folder}: {err.strerror or err}") from None
    try:
        lock = lock_folder(folder)
    except ResultsError:
        if created:
            remove_empty_folder(folder)
        raise
    lock.created_folder = created
    try:
        marker = _judge_contents(folder, overwrite)
        if marker is not None:
            removed = clear_own_files(folder, [*marker["files"], MARKER_NAME])
            logger.info("replaced the earlier results in %s (%d files)", folder, removed)
        write_marker(folder, patterns)
    except OSError as err:
        with contextlib.suppress(OSError):
            clear_own_files(folder, [MARKER_NAME])
        lock.release()
        if created:
            remove_empty_folder(folder)
        raise ResultsError(f"cannot write results to {folder}: {err.strerror or err}") from None
    except BaseException:
        lock.release()
        raise
    return folder, lock


def remove_empty_folder(folder: str | os.PathLike[str]) -> None:
    """Remove ``folder`` when it is empty (a results folder a run made and could not start in)."""
    with contextlib.suppress(OSError):
        os.rmdir(folder)


def export_path(results_dir: str | os.PathLike[str], label: str, suffix: str = ".png") -> Path:
    """Default file for a picture or movie exported from a results folder: *beside* the folder.

    Exports never default into the results folder itself (a re-run may replace it); for
    ``slope.results`` and label ``displacement_00012`` it is ``slope_displacement_00012.png``
    in the folder's parent.

    Parameters
    ----------
    results_dir : path-like
    label : str
        What the file shows (field and frame).
    suffix : str
        File extension with its dot.

    Returns
    -------
    Path
    """
    folder = Path(results_dir).expanduser().absolute()
    stem = folder.name[: -len(".results")] if folder.name.endswith(".results") and folder.name != ".results" else folder.name
    return folder.parent / f"{stem}_{label}{suffix}"


def check_writable(path: str | os.PathLike[str]) -> Path:
    """Make the folder of the file ``path`` and check that a file can be created there, before any
    work goes into what it will hold (a picture, a movie, a report on a read-only disk).

    Raises
    ------
    OSError
        With one line: ``cannot write PATH: REASON``.
    """
    import tempfile

    out = Path(path).expanduser().absolute()
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        fd, probe = tempfile.mkstemp(prefix=f".{out.name}.", suffix=".tmp", dir=out.parent)
        os.close(fd)
        os.unlink(probe)
    except OSError as err:
        raise OSError(f"cannot write {out}: {err.strerror or err}") from None
    return out
