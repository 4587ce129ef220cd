"""Results folders: writing them while a run goes on, and reading them back.

A results folder (the public contract in ``docs/project-format.md``) holds::

    particles.pvd          ParaView collection indexing the complete frames, with their times
    frames/frame_00000.vtp one VTK XML PolyData file per output time
    series.csv             one row of diagnostics per output time
    contacts.csv           the force on each closed side and structure per output interval
    summary.json           status and key numbers of the run
    project.toml           the resolved project that ran

Frame files are VTK XML PolyData (version 1.0, little endian, ``UInt64`` headers), every data
array zlib-compressed in raw appended binary. They are encoded here with numpy and zlib rather
than through VTK so that :mod:`projects` stays light to import and the writer thread does not need
VTK; the tests read them back with VTK's own reader. The points hold every particle (float32,
z = 0) in particle order; vertex cells are made only for active particles, so viewers skip
particles that were removed, while point arrays stay aligned with particle ids.

Point arrays (names are fixed): ``displacement`` (3 components, m), ``velocity`` (3, m/s),
``stress`` (4: xx, yy, xy, zz, Pa), ``plastic_strain`` (-), ``material_id`` (int32), ``active``
(uint8) and ``particle_id`` (int32); only the fields the run asked for are present. The field
data ``TimeValue`` holds the simulated time in seconds.

Every file that is rewritten (``particles.pvd``, ``summary.json``, each frame) is written to a
temporary name and moved into place, so a run that is killed leaves a folder that reads up to its
last complete frame; :class:`Results` reports such a run as ``"interrupted"``.
"""

from __future__ import annotations

import contextlib
import csv
import io
import json
import logging
import math
import os
import queue
import re
import threading
import time
import zipfile
import zlib
from collections import OrderedDict
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Any
from xml.etree import ElementTree

import numpy as np

from projects.atomic import write_atomic
from projects.results_folder import (
    BASE_PATTERNS,
    MARKER_NAME,
    RESERVE_NAME,
    FolderLock,
    ResultsError,
    ResultsExistError,
    ResultsLockedError,
    clear_own_files,
    lock_folder,
    open_results_dir,
    read_marker,
    remove_empty_folder,
    remove_temp_files,
    write_marker,
)
from solver.config import ContactForce, Diagnostics, Frame

logger = logging.getLogger(__name__)

FRAMES_DIR = "frames"
PVD_NAME = "particles.pvd"
SERIES_NAME = "series.csv"
CONTACTS_NAME = "contacts.csv"
SUMMARY_NAME = "summary.json"
PROJECT_NAME = "project.toml"
CHECKPOINT_NAME = "checkpoint.npz"

#: Columns of ``series.csv``, in order.
SERIES_COLUMNS: tuple[str, ...] = (
    "frame",
    "time_s",
    "stage",
    "stage_index",
    "stage_time_s",
    "step",
    "dt_s",
    "kinetic_energy_J_per_m",
    "momentum_x",
    "momentum_y",
    "max_speed_m_s",
    "unstable_particles",
    "lost_particles",
    "total_mass_kg_per_m",
    "yielding_particles",
)
#: Columns of ``contacts.csv``, in order: one row per contact and output time. The forces are what the
#: material exerts on the contact (N per metre out of plane): the mean over the output interval that
#: ends at ``time_s`` and the largest of one step in it (magnitude and components); normal and
#: tangential (a side's along its axes, a structure's on the face that carries the force,
#: projects.structure_forces); the mean force's moment about the grid origin
#: (``domain.origin_m``; N m per metre, counter-clockwise positive; older files lack it).
#: See :class:`solver.config.ContactForce`.
CONTACT_COLUMNS: tuple[str, ...] = (
    "time_s",
    "contact",
    "force_x_N_per_m",
    "force_y_N_per_m",
    "force_normal_N_per_m",
    "force_tangential_N_per_m",
    "peak_force_N_per_m",
    "peak_force_x_N_per_m",
    "peak_force_y_N_per_m",
    "moment_N_m_per_m",
)
#: The columns every ``contacts.csv`` has (those of files written before the moment was added).
_CONTACT_COLUMNS_REQUIRED = CONTACT_COLUMNS[:9]
_INT_COLUMNS = frozenset(
    {"frame", "stage_index", "step", "unstable_particles", "lost_particles", "yielding_particles"}
)
_STR_COLUMNS = frozenset({"stage"})

#: Final states of a run as written to ``summary.json``.
FINAL_STATUSES: tuple[str, ...] = ("completed", "stopped", "failed")
RUNNING = "running"
#: The version of the results folder's layout and files (docs/results.md); summary.json carries it.
RESULTS_FORMAT_VERSION = 2
#: What :attr:`Results.status` says for a folder whose run never closed it.
INTERRUPTED = "interrupted"

_STRESS_COMPONENTS = ("xx", "yy", "xy", "zz")
_BLOCK_BYTES = 1 << 16
_END_TAG = b"</VTKFile>\n"
_FRAME_RE = re.compile(r"^frame_(\d+)\.vtp$")
_TIME_RE = re.compile(rb'Name="TimeValue"[^>]*>\s*([^<\s]+)\s*<')
_VTK_TYPES: dict[str, str] = {
    "float32": "Float32",
    "float64": "Float64",
    "int8": "Int8",
    "uint8": "UInt8",
    "int32": "Int32",
    "int64": "Int64",
    "uint32": "UInt32",
    "uint64": "UInt64",
    "int16": "Int16",
    "uint16": "UInt16",
}
_NUMPY_TYPES = {v: np.dtype(k).newbyteorder("<") for k, v in _VTK_TYPES.items()}


def runout_version() -> str:
    """The installed version of Runout, or ``"unknown"`` when it is not installed."""
    from importlib import metadata

    try:
        return metadata.version("runout")
    except metadata.PackageNotFoundError:
        return "unknown"


# --------------------------------------------------------------------------------------------
# small file helpers


def _csv_text(rows: list[list[Any]]) -> str:
    buffer = io.StringIO()
    csv.writer(buffer).writerows(rows)
    return buffer.getvalue()


def write_checkpoint(out_dir: str | os.PathLike[str], checkpoint: Any) -> Path:
    """Write a run's :class:`~solver.simulation.Checkpoint` as ``checkpoint.npz`` (atomically).

    The file holds the engine's state arrays (``state/NAME``), the run's position as JSON
    (``run``) and the fingerprint of the configuration and particles it belongs to.
    """
    path = Path(out_dir) / CHECKPOINT_NAME
    arrays = {f"state/{name}": np.asarray(value) for name, value in checkpoint.arrays.items()}
    arrays["run"] = np.frombuffer(json.dumps(checkpoint.run).encode(), dtype=np.uint8)
    arrays["fingerprint"] = np.frombuffer(checkpoint.fingerprint.encode(), dtype=np.uint8)
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    write_atomic(path, buffer.getvalue())
    return path


def read_checkpoint(path: str | os.PathLike[str]) -> Any:
    """Read ``checkpoint.npz`` (a file, or the results folder holding one) back into a Checkpoint.

    Raises
    ------
    ResultsError
        No checkpoint there, or one that cannot be read.
    """
    from solver.config import Checkpoint

    path = Path(path)
    if not path.exists():  # a mistyped folder: name it, not its parent
        raise ResultsError(f"no such results folder or checkpoint: {path}")
    if path.is_dir():
        path = path / CHECKPOINT_NAME
    if not path.is_file():
        raise ResultsError(f"no checkpoint in {path.parent} (a run writes {CHECKPOINT_NAME} at its checkpoints)")
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {key[len("state/"):]: data[key] for key in data.files if key.startswith("state/")}
            run = json.loads(bytes(data["run"]).decode())
            fingerprint = bytes(data["fingerprint"]).decode()
    except (OSError, ValueError, KeyError, EOFError, zlib.error, zipfile.BadZipFile) as err:
        # a checkpoint cut short (a full disk, an interrupted copy) is not a zip file at all
        raise ResultsError(f"cannot read the checkpoint {path}: {err}") from err
    return Checkpoint(run=run, arrays=arrays, fingerprint=fingerprint)
#: Bytes kept on disk during a run for the final ``summary.json`` (see :func:`_write_reserve`).
RESERVE_BYTES = 1 << 16
#: Points are written in float64 when the domain lies farther from zero than this many times
#: its size (float32 would then resolve positions more coarsely than for a domain at the origin).
FAR_FROM_ORIGIN = 16.0


def _write_reserve(path: Path) -> None:
    """Hold :data:`RESERVE_BYTES` of disk that the writer gives up to close on a full disk."""
    with open(path, "wb") as fh:
        fh.write(b"\0" * RESERVE_BYTES)


def points_dtype_for(domain: Mapping[str, Any] | None) -> str | None:
    """The dtype of a results folder's points: ``"<f4"``, or ``"<f8"`` far from the origin.

    Parameters
    ----------
    domain : mapping, optional
        ``origin_m`` and ``size_m`` of the grid box (the summary's ``domain``).

    Returns
    -------
    str or None
        None when the domain is not known (each frame decides from its own positions).
    """
    try:
        origin = np.asarray(domain["origin_m"], dtype=np.float64)  # type: ignore[index]
        size = np.asarray(domain["size_m"], dtype=np.float64)  # type: ignore[index]
    except (TypeError, KeyError, ValueError):
        return None
    return _dtype_for_box(origin, origin + size)


def _dtype_for_box(lo: np.ndarray, hi: np.ndarray) -> str:
    reach = float(np.max(np.abs(np.concatenate([lo, hi])))) if lo.size else 0.0
    extent = float(np.max(hi - lo)) if lo.size else 0.0
    return "<f8" if reach > FAR_FROM_ORIGIN * max(extent, 1e-300) else "<f4"


def _json_default(value: Any) -> Any:
    # numpy scalars and arrays, paths and tuples from dataclasses end up in meta dicts
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"{type(value).__name__} is not JSON serialisable")


def _json_float(value: float) -> float | None:
    # JSON has no NaN/inf; a summary must stay valid JSON for other tools
    value = float(value)
    return value if math.isfinite(value) else None


def is_results_dir(path: str | os.PathLike[str]) -> bool:
    """Whether ``path`` is a folder that looks like a Runout results folder."""
    path = Path(path)
    return path.is_dir() and (
        (path / SUMMARY_NAME).is_file()
        or (path / PVD_NAME).is_file()
        or (path / FRAMES_DIR).is_dir()
    )


def prepare_results_dir(path: str | os.PathLike[str], *, overwrite: bool = False) -> Path:
    """Make ``path`` ready for a new run (see :mod:`projects.results_folder`); no lock is kept.

    A missing folder is created (with its parents); an empty folder is used as is; an earlier
    run's results are replaced only with ``overwrite`` (and then only that run's own files are
    removed); any other non-empty folder is refused.

    Returns
    -------
    Path
        The absolute folder path.

    Raises
    ------
    ResultsExistError, ResultsLockedError, ResultsError
    """
    folder, lock = open_results_dir(path, overwrite=overwrite)
    lock.release()
    return folder


# --------------------------------------------------------------------------------------------
# VTK XML encoding and decoding


def _encode_array(array: np.ndarray, level: int) -> bytes:
    """One appended data block: UInt64 header (blocks, block size, last size, sizes) + zlib."""
    raw = np.ascontiguousarray(array).tobytes()
    nbytes = len(raw)
    nblocks = -(-nbytes // _BLOCK_BYTES)
    blocks = [
        zlib.compress(raw[i * _BLOCK_BYTES : (i + 1) * _BLOCK_BYTES], level) for i in range(nblocks)
    ]
    last = nbytes - (nblocks - 1) * _BLOCK_BYTES if nblocks else 0
    if last == _BLOCK_BYTES:
        last = 0  # VTK's convention: 0 means the last block is full
    header = np.array([nblocks, _BLOCK_BYTES, last, *map(len, blocks)], dtype="<u8")
    return header.tobytes() + b"".join(blocks)


def _as_file_array(name: str, values: np.ndarray) -> np.ndarray:
    """Convert one frame field to the dtype and component count stored in the file."""
    values = np.asarray(values)
    if name in ("active",) or values.dtype == np.bool_:
        return values.astype(np.uint8)
    if np.issubdtype(values.dtype, np.integer):
        return values.astype("<i4")
    values = values.astype("<f4")
    if values.ndim == 2 and values.shape[1] == 2:
        # vectors get a zero z so that ParaView treats them as vectors (glyphs, magnitude)
        values = np.concatenate([values, np.zeros((len(values), 1), "<f4")], axis=1)
    return values


def encode_vtp(
    fields: Mapping[str, np.ndarray], time_s: float, level: int = 1, points_dtype: str | None = None
) -> bytes:
    """Encode one frame as a VTK XML PolyData file.

    Parameters
    ----------
    fields : mapping of str to numpy.ndarray
        ``positions`` (N, 2) m and ``active`` (N,) bool are required; every other entry is
        written as a point array (see the module docstring for names and shapes).
    time_s : float
        Simulated time, stored as the field data ``TimeValue``.
    level : int
        zlib compression level (1 is fast and gets most of the gain on float data).
    points_dtype : {"<f4", "<f8"}, optional
        Type of the points. Default: float32, or float64 when the positions lie farther from
        zero than :data:`FAR_FROM_ORIGIN` times their extent (real-world coordinates).

    Returns
    -------
    bytes
        The complete file content.
    """
    positions = np.asarray(fields["positions"], dtype=np.float64)
    n = len(positions)
    if positions.shape != (n, 2):
        raise ValueError(f"positions must have shape (N, 2), got {positions.shape}")
    if points_dtype is None:
        finite = positions[np.all(np.isfinite(positions), axis=1)]
        points_dtype = _dtype_for_box(finite.min(axis=0), finite.max(axis=0)) if len(finite) else "<f4"
    active = np.asarray(fields.get("active", np.ones(n, bool)), dtype=bool)
    points = np.zeros((n, 3), points_dtype)
    points[:, :2] = positions
    connectivity = np.flatnonzero(active).astype("<i8")
    offsets = np.arange(1, len(connectivity) + 1, dtype="<i8")

    point_arrays: dict[str, np.ndarray] = {"active": active.astype(np.uint8)}
    point_arrays["particle_id"] = np.arange(n, dtype="<i4")
    for name, values in fields.items():
        if name in ("positions", "active", "particle_id"):
            continue
        arr = _as_file_array(name, values)
        if arr.shape[0] != n:
            raise ValueError(f"field {name!r} has {arr.shape[0]} rows for {n} particles")
        point_arrays[name] = arr

    from xml.sax.saxutils import quoteattr  # here: it imports urllib, 10 ms of every run's start

    blobs: list[bytes] = []
    offset = 0

    def data_array(name: str, arr: np.ndarray, extra: str = "") -> str:
        nonlocal offset
        comps = 1 if arr.ndim == 1 else arr.shape[1]
        blob = _encode_array(arr, level)
        tag = (
            f'<DataArray type="{_VTK_TYPES[arr.dtype.name]}" Name={quoteattr(name)} '
            f'NumberOfComponents="{comps}"{extra} format="appended" offset="{offset}"/>'
        )
        blobs.append(blob)
        offset += len(blob)
        return tag

    lines = [
        '<?xml version="1.0"?>',
        '<VTKFile type="PolyData" version="1.0" byte_order="LittleEndian" '
        'header_type="UInt64" compressor="vtkZLibDataCompressor">',
        "<PolyData>",
        "<FieldData>",
        '<DataArray type="Float64" Name="TimeValue" NumberOfTuples="1" format="ascii">'
        f"{float(time_s)!r}</DataArray>",
        "</FieldData>",
        f'<Piece NumberOfPoints="{n}" NumberOfVerts="{len(connectivity)}" NumberOfLines="0" '
        'NumberOfStrips="0" NumberOfPolys="0">',
        "<PointData>",
    ]
    for name, arr in point_arrays.items():
        extra = ""
        if name == "stress" and arr.ndim == 2 and arr.shape[1] == 4:
            extra = "".join(
                f' ComponentName{i}="{c}"' for i, c in enumerate(_STRESS_COMPONENTS)
            )
        lines.append(data_array(name, arr, extra))
    lines += [
        "</PointData>",
        "<Points>",
        data_array("Points", points),
        "</Points>",
        "<Verts>",
        data_array("connectivity", connectivity),
        data_array("offsets", offsets),
        "</Verts>",
        "</Piece>",
        "</PolyData>",
        '<AppendedData encoding="raw">',
        "_",
    ]
    head = "\n".join(lines).encode("ascii")
    return head + b"".join(blobs) + b"\n</AppendedData>\n" + _END_TAG


@dataclass(frozen=True)
class _VtpLayout:
    """Where the arrays of one frame file are: XML tree of the header and the data start."""

    root: ElementTree.Element
    data_start: int


def _vtp_layout(data: bytes, path: Path) -> _VtpLayout:
    marker = data.find(b"<AppendedData")
    if marker < 0:
        raise ResultsError(f"{path}: not a Runout frame file (no appended data)")
    underscore = data.find(b"_", data.find(b">", marker))
    try:
        root = ElementTree.fromstring(data[:marker] + b"</VTKFile>")
    except ElementTree.ParseError as err:
        raise ResultsError(f"{path}: damaged frame header ({err})") from err
    return _VtpLayout(root, underscore + 1)


def _decode_array(data: bytes, start: int, element: ElementTree.Element, path: Path) -> np.ndarray:
    dtype = _NUMPY_TYPES[element.get("type", "")]
    comps = int(element.get("NumberOfComponents", "1"))
    try:
        nblocks, _, _ = np.frombuffer(data, "<u8", 3, start)
        sizes = np.frombuffer(data, "<u8", int(nblocks), start + 24)
        pos = start + 24 + 8 * int(nblocks)
        chunks = []
        for size in sizes:
            chunks.append(zlib.decompress(data[pos : pos + int(size)]))
            pos += int(size)
    except (ValueError, zlib.error) as err:
        raise ResultsError(f"{path}: damaged array {element.get('Name')!r} ({err})") from err
    arr = np.frombuffer(b"".join(chunks), dtype)
    if comps > 1:
        arr = arr.reshape(-1, comps)
    return arr


def read_vtp(path: str | os.PathLike[str], names: set[str] | None = None) -> dict[str, np.ndarray]:
    """Read the arrays of a frame file written by :func:`encode_vtp`.

    Parameters
    ----------
    path : path-like
        The ``.vtp`` file.
    names : set of str, optional
        Point arrays to decode (``"Points"`` for the coordinates); all when omitted.

    Returns
    -------
    dict of str to numpy.ndarray
        ``Points`` (N, 3) float32, ``connectivity`` (M,) int64 (the active particles) and the
        point arrays as stored (vectors with 3 components).
    """
    path = Path(path)
    data = path.read_bytes()
    if not data.endswith(_END_TAG):
        raise ResultsError(f"{path}: incomplete frame file (the run was cut off while writing it)")
    layout = _vtp_layout(data, path)
    out: dict[str, np.ndarray] = {}
    piece = layout.root.find("PolyData/Piece")
    if piece is None:
        raise ResultsError(f"{path}: no PolyData piece")
    for element in piece.iter("DataArray"):
        name = element.get("Name", "")
        if names is not None and name not in names:
            continue
        offset = int(element.get("offset", "0"))
        out[name] = _decode_array(data, layout.data_start + offset, element, path)
    return out


def _frame_time(path: Path) -> float | None:
    """The ``TimeValue`` of a frame file (read from its XML header), or None."""
    with open(path, "rb") as fh:
        head = fh.read(4096)
    match = _TIME_RE.search(head)
    return float(match.group(1)) if match else None


def _is_complete(path: Path) -> bool:
    try:
        with open(path, "rb") as fh:
            fh.seek(0, os.SEEK_END)
            size = fh.tell()
            if size < len(_END_TAG):
                return False
            fh.seek(size - len(_END_TAG))
            return fh.read() == _END_TAG
    except OSError:
        return False


def _pvd_text(entries: list[tuple[float, str]]) -> str:
    from xml.sax.saxutils import quoteattr

    rows = "\n".join(
        f'    <DataSet timestep="{t!r}" group="" part="0" file={quoteattr(f)}/>' for t, f in entries
    )
    return (
        '<?xml version="1.0"?>\n'
        '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">\n'
        "  <Collection>\n"
        f"{rows}{chr(10) if rows else ''}"
        "  </Collection>\n"
        "</VTKFile>\n"
    )


# --------------------------------------------------------------------------------------------
# writer


class _Stop:
    """Queue sentinel: no more frames."""


class ResultsWriter:
    """Write a results folder while a run produces frames.

    The caller (the solver thread) hands over each frame with :meth:`write_frame`; encoding and
    writing happen in a background thread fed through a bounded queue, so the solver only waits
    when the disk falls several frames behind. The arrays handed over are owned by the writer
    from then on and must not be modified by the caller.

    Parameters
    ----------
    out_dir : path-like
        The results folder (see :mod:`projects.results_folder`): created when missing, locked
        while the writer is open, marked as a Runout results folder. An earlier run's results
        there are replaced only with ``overwrite`` (only its own files are removed); any other
        non-empty folder is refused.
    project_text : str
        The resolved project (TOML) that runs, saved as ``project.toml``.
    meta : dict
        Entries for ``summary.json`` known before the run: ``title``, ``scheme``, ``arch``,
        ``precision``, ``particles`` and anything else JSON-serialisable (for example
        ``materials``, ``domain``, ``particle_spacing_m``, ``total_time_s``).
    queue_size : int
        Frames that may wait for the writer thread before :meth:`write_frame` blocks.
    compression_level : int
        zlib level of the frame files.
    keep_frames : int, optional
        Resume the results folder of an earlier run instead of starting a new one: its first
        ``keep_frames`` frames (and their ``series.csv`` rows) stay, the later ones (written
        after the checkpoint the run resumes from) are removed, and new frames continue the
        numbering. The summary keeps the earlier run's entries.
    overwrite : bool
        Replace an earlier run's results in ``out_dir``.

    Raises
    ------
    ResultsExistError
        ``out_dir`` holds an earlier run's results and ``overwrite`` is False.
    ResultsLockedError
        Another running process writes into ``out_dir``.
    ResultsError
        ``out_dir`` cannot be used or written (one line naming the folder and the reason).
    """

    def __init__(
        self,
        out_dir: str | os.PathLike[str],
        project_text: str,
        meta: dict[str, Any],
        *,
        queue_size: int = 3,
        compression_level: int = 1,
        overwrite: bool = False,
        keep_frames: int | None = None,
    ) -> None:
        self._patterns: list[str] = list(BASE_PATTERNS)
        if keep_frames is None:
            self.out_dir, self._lock = open_results_dir(out_dir, overwrite=overwrite, patterns=self._patterns)
        else:  # resuming: the earlier run's own folder, locked again, nothing cleared
            self.out_dir = Path(out_dir).expanduser().absolute()
            marker = read_marker(self.out_dir)
            if marker is None:
                raise ResultsError(f"{self.out_dir} is not a results folder of Runout (no {MARKER_NAME})")
            self._lock = lock_folder(self.out_dir)
            self._patterns = list(dict.fromkeys([*self._patterns, *marker["files"]]))
        self._frames_dir = self.out_dir / FRAMES_DIR
        self._level = compression_level
        self._started = time.perf_counter()
        self._pvd_entries: list[tuple[float, str]] = []
        self._submitted = 0
        earlier: dict[str, Any] = {}
        series_rows: list[list[str]] = []
        if keep_frames is not None:
            try:
                earlier, series_rows = self._take_over(keep_frames)
            except BaseException:
                self._lock.release()
                raise
        self._closed = False
        self._error: BaseException | None = None
        self._last: Diagnostics | None = None
        self._points_dtype = points_dtype_for(meta.get("domain"))
        self.summary: dict[str, Any] = {
            "status": RUNNING,
            "message": "",
            "title": "",
            "scheme": "",
            "arch": "",
            "precision": "",
            "particles": 0,
            "steps": 0,
            "simulated_time_s": 0.0,
            "wall_time_s": 0.0,
            "particle_steps_per_s": 0.0,
            "frames": 0,
            "runout_version": runout_version(),
            "results_format_version": RESULTS_FORMAT_VERSION,
            "started_at": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        }
        self.summary.update(earlier)
        self.summary.update(meta)
        if keep_frames is not None:
            self.summary["status"] = RUNNING
            self.summary["resumed_at_frame"] = keep_frames
            # the run's peaks from the rows kept, not the earlier summary's (which counted the rows
            # written over: those after the checkpoint, a stop's frame)
            self.summary.pop("contacts", None)
            for row in self._kept_contact_rows:
                try:
                    time_s = float(row[0])
                    values = [float(v) if v != "" else None for v in row[2:]]
                    moment = values[7] if len(values) > 7 and values[7] is not None else math.nan  # older rows
                    force = ContactForce(row[1], *values[:7], moment_N_m_per_m=moment)
                    if None in (values[0], values[1], values[4], values[5], values[6]):
                        continue
                except (IndexError, ValueError, TypeError):
                    continue  # a row cut short (a kill while it was written)
                self._add_peaks(time_s, force)

        try:
            self._frames_dir.mkdir(exist_ok=True)
            _write_reserve(self.out_dir / RESERVE_NAME)
            write_atomic(self.out_dir / PROJECT_NAME, project_text)
            if keep_frames is not None:  # the kept rows, written whole before the file is replaced
                write_atomic(self.out_dir / SERIES_NAME, _csv_text([list(SERIES_COLUMNS), *series_rows]))
                self._series = open(self.out_dir / SERIES_NAME, "a", newline="", encoding="utf-8")
                self._csv = csv.writer(self._series)
            else:
                self._series = open(self.out_dir / SERIES_NAME, "w", newline="", encoding="utf-8")
                self._csv = csv.writer(self._series)
                self._csv.writerow(SERIES_COLUMNS)
            self._series.flush()
            if keep_frames is not None:
                write_atomic(self.out_dir / CONTACTS_NAME,
                             _csv_text([list(CONTACT_COLUMNS), *(row + [""] * (len(CONTACT_COLUMNS) - len(row))
                                                                 for row in self._kept_contact_rows)]))
                self._contacts = open(self.out_dir / CONTACTS_NAME, "a", newline="", encoding="utf-8")
                self._contacts_csv = csv.writer(self._contacts)
            else:
                self._contacts = open(self.out_dir / CONTACTS_NAME, "w", newline="", encoding="utf-8")
                self._contacts_csv = csv.writer(self._contacts)
                self._contacts_csv.writerow(CONTACT_COLUMNS)
            self._contacts.flush()
            self._write_pvd()
            self._write_summary()
        except OSError as err:
            if keep_frames is None:  # a new run that could not start (a full disk) leaves no results
                with contextlib.suppress(OSError):  # folder behind, which the next run would refuse
                    clear_own_files(self.out_dir, [*self._patterns, MARKER_NAME])
            self._abandon()
            if keep_frames is None and self._lock.created_folder:
                remove_empty_folder(self.out_dir)
            raise ResultsError(f"cannot write results to {self.out_dir}: {err.strerror or err}") from err
        except BaseException:  # a Ctrl-C while the folder is set up: a new run leaves nothing either
            if keep_frames is None:
                with contextlib.suppress(OSError):
                    clear_own_files(self.out_dir, [*self._patterns, MARKER_NAME])
            self._abandon()
            raise

        self._queue: queue.Queue[Any] = queue.Queue(maxsize=max(1, queue_size))
        self._thread = threading.Thread(
            target=self._work, name=f"results-writer:{self.out_dir.name}", daemon=True
        )
        self._thread.start()

    def _take_over(self, keep: int) -> tuple[dict[str, Any], list[list[str]]]:
        """Keep the first ``keep`` frames of the earlier run in this folder; remove its later ones."""
        results = Results(self.out_dir)
        entries = results._entries()
        if len(entries) < keep:
            raise ResultsError(f"{self.out_dir} holds {len(entries)} complete frames and its checkpoint needs {keep}: "
                               "the frames after the last one are lost and the run cannot go on from its checkpoint; "
                               "run the project again into it with --overwrite")
        self._pvd_entries = list(entries[:keep])
        self._submitted = keep
        kept = {Path(name).name for _, name in self._pvd_entries}
        for path in self._frames_dir.glob("frame_*.vtp*"):
            if path.name not in kept:  # written by this run after its checkpoint: written again
                path.unlink()
        rows: list[list[str]] = []
        series = self.out_dir / SERIES_NAME
        if series.is_file():
            with open(series, newline="", encoding="utf-8") as handle:
                reader = csv.reader(handle)
                next(reader, None)
                rows = [row for row in reader if row and row[0].isdigit() and int(row[0]) < keep]
        # contacts.csv: the rows up to the last kept frame's time
        last_time = self._pvd_entries[-1][0] if self._pvd_entries else -math.inf
        self._kept_contact_rows: list[list[str]] = []
        contacts = self.out_dir / CONTACTS_NAME
        if contacts.is_file():
            with open(contacts, newline="", encoding="utf-8") as handle:
                reader = csv.reader(handle)
                next(reader, None)
                for row in reader:
                    try:
                        if row and float(row[0]) <= last_time * (1 + 1e-12) + 1e-300:
                            self._kept_contact_rows.append(row)
                    except ValueError:
                        continue
        return dict(results.summary), rows

    # -- caller side -----------------------------------------------------------------------

    @property
    def closed(self) -> bool:
        """Whether :meth:`close` has been called (the final summary written)."""
        return self._closed

    @property
    def frames_submitted(self) -> int:
        """Frames handed over so far (written or queued)."""
        return self._submitted

    @property
    def frames_written(self) -> int:
        """Frames completely on disk and listed in ``particles.pvd``."""
        return len(self._pvd_entries)

    def write_frame(self, frame: Frame) -> None:
        """Queue one frame for writing (blocks while the queue is full).

        Raises
        ------
        ResultsError
            When the writer is closed or writing an earlier frame failed.
        """
        if self._closed:
            raise ResultsError("the results writer is closed")
        if self._error is not None:
            raise ResultsError(f"writing results failed: {self._error}") from self._error
        index = self._submitted
        self._submitted += 1
        self._queue.put((index, frame.diagnostics, dict(frame.fields), tuple(frame.contacts)))

    def submit(self, job: Callable[[], None]) -> None:
        """Queue ``job()`` to run in the writer thread after the frames queued before it (files that
        accompany the frames, e.g. the hazard envelopes); its errors fail the writer like a frame's."""
        if self._closed:
            raise ResultsError("the results writer is closed")
        self._queue.put(job)

    def flush(self) -> None:
        """Wait until every queued frame is on disk."""
        self._queue.join()

    def close(
        self,
        status: str,
        message: str = "",
        *,
        steps: int | None = None,
        simulated_time_s: float | None = None,
        wall_time_s: float | None = None,
        particle_steps_per_s: float | None = None,
        extra: Mapping[str, Any] | None = None,
    ) -> dict[str, Any]:
        """Write the queued frames, then the final ``summary.json``.

        Parameters
        ----------
        status : {"completed", "stopped", "failed"}
        message : str
            Why the run ended (empty for a plain completion).
        steps, simulated_time_s : optional
            Defaults: the step and time of the last frame.
        wall_time_s : float, optional
            Default: seconds since the writer was created.
        particle_steps_per_s : float, optional
            Default: particles * steps / wall time.
        extra : mapping, optional
            More summary entries.

        Returns
        -------
        dict
            The summary as written. If a frame could not be written the status is
            ``"failed"`` with that reason.
        """
        if status not in FINAL_STATUSES:
            raise ValueError(f"status must be one of {FINAL_STATUSES}, got {status!r}")
        if self._closed:
            return self.summary
        self._closed = True
        self._queue.put(_Stop)
        self._thread.join()
        try:
            self._series.close()  # flushes the last row: may fail on a full disk
        except OSError as err:
            if self._error is None:
                self._error = err
        self._contacts.close()
        if self._error is not None and status != "failed":
            status, message = "failed", f"writing results failed: {self._error}"
        last = self._last
        if steps is None:
            steps = last.step if last is not None else 0
        if simulated_time_s is None:
            simulated_time_s = last.time_s if last is not None else 0.0
        if wall_time_s is None:
            wall_time_s = time.perf_counter() - self._started
        if particle_steps_per_s is None:
            particles = int(self.summary.get("particles") or 0)
            particle_steps_per_s = particles * steps / wall_time_s if wall_time_s > 0 else 0.0
        self.summary.update(
            status=status,
            message=message,
            steps=int(steps),
            simulated_time_s=_json_float(simulated_time_s),
            wall_time_s=_json_float(wall_time_s),
            particle_steps_per_s=_json_float(particle_steps_per_s),
            frames=self.frames_written,
            finished_at=datetime.now(timezone.utc).isoformat(timespec="seconds"),
        )
        if extra:
            self.summary.update(extra)
        try:
            self._write_final_summary()
        finally:
            self._abandon()
        return self.summary

    def own(self, pattern: str) -> None:
        """Record a file (``fnmatch`` pattern relative to the folder) as written by this run.

        Capabilities that add files to the results folder (checkpoints, reports) call this
        before writing them, so that a later ``overwrite`` removes them and nothing else.
        """
        if pattern not in self._patterns:
            self._patterns.append(pattern)
            write_marker(self.out_dir, self._patterns)

    def _write_final_summary(self) -> None:
        """The final summary, also on a full disk: the reserve is given up for it, and as a
        last resort the old summary is overwritten in place."""
        try:
            self._write_summary()
            return
        except OSError as err:
            logger.warning("writing the final summary failed (%s); retrying with the reserved space", err)
        remove_temp_files(self.out_dir, self._patterns)
        with contextlib.suppress(OSError):
            (self.out_dir / RESERVE_NAME).unlink()
        try:
            self._write_summary()
            return
        except OSError:
            remove_temp_files(self.out_dir, self._patterns)
        try:
            with open(self.out_dir / SUMMARY_NAME, "r+b") as fh:
                fh.truncate(0)
                fh.write(self._summary_bytes())
        except OSError as err:
            logger.error("could not write %s: %s", self.out_dir / SUMMARY_NAME, err)

    def _abandon(self) -> None:
        """Leave the folder: no temporary files, no reserve, no lock (idempotent)."""
        with contextlib.suppress(OSError):
            if getattr(self, "_series", None) is not None:
                self._series.close()
        remove_temp_files(self.out_dir, self._patterns, os.getpid())
        with contextlib.suppress(OSError):
            (self.out_dir / RESERVE_NAME).unlink()
        self._lock.release()

    def __enter__(self) -> ResultsWriter:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: Any) -> None:
        if exc_type is None:
            self.close("completed")
        elif issubclass(exc_type, KeyboardInterrupt):
            self.close("stopped", "interrupted")
        else:
            self.close("failed", f"{exc_type.__name__}: {exc}")

    # -- writer thread ---------------------------------------------------------------------

    def _work(self) -> None:
        while True:
            item = self._queue.get()
            try:
                if item is _Stop:
                    return
                if self._error is None:
                    if callable(item):
                        item()
                    else:
                        self._write_one(*item)
            except Exception as err:  # noqa: BLE001 - reported to the caller via write_frame/close
                logger.error("writing a results frame failed: %s", err,
                             exc_info=logger.isEnabledFor(logging.DEBUG))
                self._error = err
            finally:
                self._queue.task_done()

    def _write_one(self, index: int, diag: Diagnostics, fields: dict[str, np.ndarray],
                   contacts: tuple[ContactForce, ...] = ()) -> None:
        name = f"frame_{index:05d}.vtp"
        data = encode_vtp(fields, diag.time_s, self._level, points_dtype=self._points_dtype)
        write_atomic(self._frames_dir / name, data)
        self._csv.writerow(
            [
                index,
                repr(float(diag.time_s)),
                diag.stage,
                diag.stage_index,
                repr(float(diag.stage_time_s)),
                diag.step,
                repr(float(diag.dt_s)),
                repr(float(diag.kinetic_energy_J_per_m)),
                repr(float(diag.momentum_x)),
                repr(float(diag.momentum_y)),
                repr(float(diag.max_speed_m_s)),
                diag.unstable_particles,
                diag.lost_particles,
                repr(float(diag.total_mass_kg_per_m)),
                diag.yielding_particles,
            ]
        )
        self._series.flush()
        self._write_contacts(diag.time_s, contacts)
        self._pvd_entries.append((float(diag.time_s), f"{FRAMES_DIR}/{name}"))
        self._write_pvd()
        self._last = diag
        self.summary.update(
            frames=len(self._pvd_entries),
            steps=int(diag.step),
            simulated_time_s=_json_float(diag.time_s),
            wall_time_s=_json_float(time.perf_counter() - self._started),
        )
        self._write_summary()

    def _write_contacts(self, time_s: float, contacts: tuple[ContactForce, ...]) -> None:
        """Rows of ``contacts.csv``, and the run's peaks per contact in the summary (``contacts``:
        name -> the largest single-step force, its components and the end of its output interval,
        and the largest mean force of an interval)."""
        if not contacts:
            return
        for c in contacts:
            c, peak_parts = self._split(c)

            def num(v: float | None) -> str:
                return "" if v is None else repr(float(v) + 0.0)  # + 0.0: no "-0.0"

            self._contacts_csv.writerow([repr(float(time_s)), c.contact, num(c.force_x_N_per_m), num(c.force_y_N_per_m),
                                         num(c.force_normal_N_per_m), num(c.force_tangential_N_per_m),
                                         num(c.peak_force_N_per_m), num(c.peak_force_x_N_per_m),
                                         num(c.peak_force_y_N_per_m), num(c.moment_N_m_per_m)])
            self._add_peaks(time_s, c, peak_parts)
        self._contacts.flush()

    def _split(self, c: ContactForce) -> tuple[ContactForce, tuple[float, float]]:
        """``c`` with a structure's normal and tangential parts on its loaded face
        (:mod:`projects.structure_forces`), and the normal and tangential parts of the interval's
        peak step (on the same face; along the side's axes for a side)."""
        from dataclasses import replace

        peak = (c.peak_force_x_N_per_m, c.peak_force_y_N_per_m)
        side = {"left": (-1, 0), "right": (1, 0), "bottom": (0, -1), "top": (0, 1)}.get(c.contact)
        if side is not None:
            normal = side[0] * peak[0] + side[1] * peak[1]
            return c, (normal, peak[1] if side[0] else peak[0])
        polygon = next((st.get("polygon_m") for st in self.summary.get("structures") or []
                        if st.get("name") == c.contact), None)
        if polygon is None or c.force_normal_N_per_m is not None:
            return c, (math.nan, math.nan)
        from projects.structure_forces import components

        origin = (self.summary.get("domain") or {}).get("origin_m") or (0.0, 0.0)
        normal, tangential, face = components(polygon, (c.force_x_N_per_m, c.force_y_N_per_m),
                                              c.moment_N_m_per_m, origin)
        if face is None:  # nothing touched it in this interval: no force, no parts
            return replace(c, force_normal_N_per_m=0.0, force_tangential_N_per_m=0.0), (0.0, 0.0)
        pn, pt, _ = components(polygon, peak, math.nan, origin, face=face)
        return replace(c, force_normal_N_per_m=normal, force_tangential_N_per_m=tangential), (pn, pt)

    def _add_peaks(self, time_s: float, c: ContactForce, peak_parts: tuple[float, float] = (math.nan, math.nan)) -> None:
        """Count one row of ``contacts.csv`` into the run's peaks (``summary["contacts"]``): the
        largest single-step force (with its normal and tangential parts ``peak_parts``), the
        largest interval mean with its time and a point of its line of action (on a side, where it
        meets the side: the centre of pressure; on a structure, the point nearest the structure's
        vertex mean), and the largest interval-mean normal and tangential (by size, signed) forces
        with their times."""
        entry = self.summary.setdefault("contacts", {}).setdefault(
            c.contact, {"peak_force_N_per_m": 0.0, "peak_force_x_N_per_m": 0.0, "peak_force_y_N_per_m": 0.0,
                        "peak_force_normal_N_per_m": 0.0, "peak_force_tangential_N_per_m": 0.0,
                        "peak_time_s": 0.0, "max_mean_force_N_per_m": 0.0, "max_mean_force_time_s": 0.0,
                        "max_mean_force_point_m": None, "max_normal_force_N_per_m": 0.0,
                        "max_normal_force_time_s": 0.0, "max_tangential_force_N_per_m": 0.0,
                        "max_tangential_force_time_s": 0.0})
        peak = c.peak_force_N_per_m
        if math.isfinite(peak) and peak > entry["peak_force_N_per_m"]:
            entry.update(peak_force_N_per_m=float(peak), peak_force_x_N_per_m=float(c.peak_force_x_N_per_m),
                         peak_force_y_N_per_m=float(c.peak_force_y_N_per_m), peak_time_s=float(time_s),
                         peak_force_normal_N_per_m=_json_float(peak_parts[0]),
                         peak_force_tangential_N_per_m=_json_float(peak_parts[1]))
        normal, tangential = c.force_normal_N_per_m, c.force_tangential_N_per_m
        if normal is not None and math.isfinite(normal) and normal > (entry.get("max_normal_force_N_per_m") or 0.0):
            entry.update(max_normal_force_N_per_m=float(normal), max_normal_force_time_s=float(time_s))
        if tangential is not None and math.isfinite(tangential) and \
                abs(tangential) > abs(entry.get("max_tangential_force_N_per_m") or 0.0):
            entry.update(max_tangential_force_N_per_m=float(tangential), max_tangential_force_time_s=float(time_s))
        mean = math.hypot(c.force_x_N_per_m, c.force_y_N_per_m)
        if math.isfinite(mean) and mean > entry["max_mean_force_N_per_m"]:
            entry.update(max_mean_force_N_per_m=mean, max_mean_force_time_s=float(time_s),
                         max_mean_force_point_m=self._line_point(c))

    def _line_point(self, c: ContactForce) -> list[float] | None:
        """A point of ``c``'s mean force's line of action in the project's coordinates (see
        :meth:`_add_peaks`; None without the domain in the summary or without a force)."""
        from solver.config import line_of_action

        domain = self.summary.get("domain") or {}
        try:
            (x0, y0), (w, h) = domain["origin_m"], domain["size_m"]
        except (KeyError, TypeError, ValueError):
            return None
        centres = {"left": (x0, y0 + h / 2), "right": (x0 + w, y0 + h / 2), "bottom": (x0 + w / 2, y0),
                   "top": (x0 + w / 2, y0 + h)}
        for structure in self.summary.get("structures") or []:
            points = np.asarray(structure.get("polygon_m") or [], dtype=float).reshape(-1, 2)
            if len(points):
                centres[structure["name"]] = tuple(points.mean(axis=0))
        centre = centres.get(c.contact)
        if centre is None:
            return None
        fx, fy, moment = c.force_x_N_per_m, c.force_y_N_per_m, c.moment_N_m_per_m
        if not math.isfinite(moment):  # a row written before the moment column
            return None
        # relative to the grid origin, about which the moment is taken
        rx, ry = centre[0] - x0, centre[1] - y0
        if c.contact in ("bottom", "top") and abs(fy) > 1e-9 * abs(fx):
            point = ((moment + ry * fx) / fy, ry)  # where the line of action meets the side
        elif c.contact in ("left", "right") and abs(fx) > 1e-9 * abs(fy):
            point = (rx, (rx * fy - moment) / fx)
        else:
            point = line_of_action((fx, fy), moment, (rx, ry))
        return None if point is None else [float(point[0] + x0), float(point[1] + y0)]

    def _write_pvd(self) -> None:
        write_atomic(self.out_dir / PVD_NAME, _pvd_text(self._pvd_entries))

    def _summary_bytes(self) -> bytes:
        return (json.dumps(self.summary, indent=2, default=_json_default) + "\n").encode("utf-8")

    def _write_summary(self) -> None:
        write_atomic(self.out_dir / SUMMARY_NAME, self._summary_bytes())


# --------------------------------------------------------------------------------------------
# loader


def _to_number(text: str, kind: type) -> Any:
    return kind(text) if kind is int else float(text)


def _read_series(path: Path) -> dict[str, np.ndarray]:
    """Columns of ``series.csv``; rows cut off by a kill (wrong length, bad numbers) are dropped."""
    if not path.is_file():
        return {name: np.array([]) for name in SERIES_COLUMNS}
    with open(path, newline="", encoding="utf-8") as fh:
        text = fh.read()
    rows = list(csv.reader(io.StringIO(text)))
    if not rows:
        return {name: np.array([]) for name in SERIES_COLUMNS}
    header, body = rows[0], rows[1:]
    if not text.endswith("\n") and body:
        body = body[:-1]  # the last line was being written when the run died
    kinds = [
        str if name in _STR_COLUMNS else int if name in _INT_COLUMNS else float for name in header
    ]
    parsed: list[list[Any]] = []
    for row in body:
        if len(row) != len(header):
            continue
        try:
            parsed.append(
                [cell if kind is str else _to_number(cell, kind) for cell, kind in zip(row, kinds)]
            )
        except ValueError:
            continue
    columns: dict[str, np.ndarray] = {}
    for j, (name, kind) in enumerate(zip(header, kinds)):
        values = [row[j] for row in parsed]
        dtype = str if kind is str else np.int64 if kind is int else np.float64
        columns[name] = np.array(values, dtype=dtype)
    return columns


def read_contacts(path: str | os.PathLike[str]) -> dict[str, dict[str, np.ndarray]]:
    """``contacts.csv`` of a results folder (or the file itself) as contact name -> column -> array
    (time order; an empty cell is NaN; rows cut off by a kill are dropped; a file written before the
    moment column has no ``moment_N_m_per_m``). A structure's normal and tangential force, which
    files written before they were recorded leave empty, is worked out on reading from its polygon
    in ``summary.json`` (:mod:`projects.structure_forces`). Empty when the folder has no such file."""
    path = Path(path)
    if path.is_dir():
        path = path / CONTACTS_NAME
    out: dict[str, dict[str, list[float]]] = {}
    if not path.is_file():
        return {}
    with open(path, newline="", encoding="utf-8") as fh:
        rows = list(csv.reader(fh))
    if not rows or tuple(rows[0][: len(_CONTACT_COLUMNS_REQUIRED)]) != _CONTACT_COLUMNS_REQUIRED:
        return {}
    header = tuple(rows[0][: len(CONTACT_COLUMNS)])
    if header != CONTACT_COLUMNS[: len(header)]:
        header = _CONTACT_COLUMNS_REQUIRED
    names = [k for k in header if k != "contact"]
    for row in rows[1:]:
        if len(row) != len(header):
            continue
        try:
            values = [float(v) if v else math.nan for i, v in enumerate(row) if i != 1]
        except ValueError:
            continue
        columns = out.setdefault(row[1], {k: [] for k in names})
        for key, value in zip(names, values):
            columns[key].append(value)
    table = {name: {k: np.asarray(v) for k, v in cols.items()} for name, cols in out.items()}
    _fill_structure_parts(path.parent, table)
    return table


def _fill_structure_parts(folder: Path, table: dict[str, dict[str, np.ndarray]]) -> None:
    """The normal and tangential force of the structures whose rows have none (older files)."""
    try:
        summary = json.loads((folder / SUMMARY_NAME).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return
    if not isinstance(summary, dict):
        return
    from projects.structure_forces import components

    origin = (summary.get("domain") or {}).get("origin_m") or (0.0, 0.0)
    for structure in summary.get("structures") or []:
        columns = table.get(structure.get("name")) if isinstance(structure, dict) else None
        if columns is None or np.isfinite(columns["force_normal_N_per_m"]).any():
            continue
        moment = columns.get("moment_N_m_per_m", np.full(len(columns["time_s"]), np.nan))
        parts = [components(structure.get("polygon_m") or [], (fx, fy), m, origin)[:2] if math.hypot(fx, fy) > 0
                 else (0.0, 0.0) for fx, fy, m in zip(columns["force_x_N_per_m"], columns["force_y_N_per_m"], moment)]
        columns["force_normal_N_per_m"] = np.array([p[0] for p in parts], dtype=float)
        columns["force_tangential_N_per_m"] = np.array([p[1] for p in parts], dtype=float)


#: The force components :func:`contact_curves` gives: key -> (label, mean column, peak column).
#: The mean of a component is its interval mean; the peak's, the component of the largest single
#: step's force (normal and tangential have no peak vector: the peak's magnitude there).
CONTACT_COMPONENTS = {
    "magnitude": ("|F|", None, "peak_force_N_per_m"),
    "x": ("F x", "force_x_N_per_m", "peak_force_x_N_per_m"),
    "y": ("F y", "force_y_N_per_m", "peak_force_y_N_per_m"),
    "normal": ("F normal", "force_normal_N_per_m", "peak_force_N_per_m"),
    "tangential": ("F tangential", "force_tangential_N_per_m", "peak_force_N_per_m"),
}


def contact_curves(contacts: dict[str, dict[str, np.ndarray]],
                   component: str = "magnitude") -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Per contact ``(time_s, mean_N_per_m, peak_N_per_m)`` from :func:`projects.results.read_contacts`.

    ``component`` (:data:`CONTACT_COMPONENTS`): ``"magnitude"``, the magnitude of the interval's
    mean components ``hypot(force_x, force_y)`` (N per metre out of plane) and the largest
    single-step force in it (``peak_force_N_per_m``); ``"x"`` or ``"y"``, that signed component of
    both (a force that reverses shows as one); ``"normal"`` or ``"tangential"``, those parts of the
    mean (a side's along its axes, a structure's on the face that carries it; a contact without
    them is left out) and the peak magnitude. Each value belongs to the interval that *ends* at its
    time.
    """
    if component not in CONTACT_COMPONENTS:
        raise ValueError(f"component {component!r}: one of {', '.join(CONTACT_COMPONENTS)}")
    _label, mean_key, peak_key = CONTACT_COMPONENTS[component]
    out = {}
    for name, columns in contacts.items():
        t = np.asarray(columns.get("time_s", []), dtype=float)
        nan = np.full(len(t), np.nan)
        if mean_key is None:
            mean = np.hypot(np.asarray(columns.get("force_x_N_per_m", nan), dtype=float),
                            np.asarray(columns.get("force_y_N_per_m", nan), dtype=float))
        else:
            mean = np.asarray(columns.get(mean_key, nan), dtype=float)
            if component in ("normal", "tangential") and not np.isfinite(mean).any():
                continue  # none recorded (nothing to split them with)
        peak = np.asarray(columns.get(peak_key, nan), dtype=float)
        if not (len(t) == len(mean) == len(peak)):
            continue
        out[name] = (t, mean, peak)
    return out


#: A closed side's outward axis (the material pushing along it presses on the side) and the axis
#: of its tangential force (contacts.csv's convention).
_SIDE_AXES = {"left": ((-1.0, 0.0), (0.0, 1.0)), "right": ((1.0, 0.0), (0.0, 1.0)),
              "bottom": ((0.0, -1.0), (1.0, 0.0)), "top": ((0.0, 1.0), (1.0, 0.0))}


def force_table(results_dir: str | os.PathLike[str]) -> list[dict[str, object]]:
    """One row per contact of a results folder that carried any force, the structures first (in
    the project's order), then the closed sides: ``contact``, ``kind`` ("structure" or "side"),
    :func:`projects.structure_forces.contact_peaks`, and the peak step's ``peak_force_normal_N_per_m`` and
    ``peak_force_tangential_N_per_m`` (on the face that carried its interval's mean force; a
    side's along its axes). N per metre, s. Empty without ``contacts.csv``."""
    from projects.structure_forces import components, contact_peaks, loaded_face

    folder = Path(results_dir)
    contacts = read_contacts(folder)
    if not contacts:
        return []
    try:
        summary = json.loads((folder / SUMMARY_NAME).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        summary = {}
    polygons = {st.get("name"): st.get("polygon_m") for st in (summary.get("structures") or [])
                if isinstance(st, dict)}
    origin = (summary.get("domain") or {}).get("origin_m") or (0.0, 0.0)
    order = [n for n in polygons if n in contacts] + [n for n in contacts if n not in polygons]
    rows = []
    for name in order:
        cols = contacts[name]
        peaks = contact_peaks(cols)
        if not peaks or not peaks["peak_force_N_per_m"] and not peaks["max_mean_force_N_per_m"]:
            continue  # never touched
        i = int(np.argmax(np.nan_to_num(np.asarray(cols["peak_force_N_per_m"], dtype=float))))
        peak = (peaks["peak_force_x_N_per_m"], peaks["peak_force_y_N_per_m"])
        if name in _SIDE_AXES:
            n, t = (np.asarray(v) for v in _SIDE_AXES[name])
            pn, pt = float(np.dot(peak, n)), float(np.dot(peak, t))
            kind = "side"
        elif name in polygons:
            mean = (float(np.nan_to_num(cols["force_x_N_per_m"][i])), float(np.nan_to_num(cols["force_y_N_per_m"][i])))
            moment = float(cols.get("moment_N_m_per_m", np.full(len(cols["time_s"]), np.nan))[i])
            face = loaded_face(polygons[name], mean if math.hypot(*mean) > 0 else peak, moment, origin)
            pn, pt, _ = components(polygons[name], peak, math.nan, origin, face=face)
            kind = "structure"
        else:
            pn, pt, kind = math.nan, math.nan, "structure"
        rows.append({"contact": name, "kind": kind, **peaks, "peak_force_normal_N_per_m": pn + 0.0,
                     "peak_force_tangential_N_per_m": pt + 0.0})
    return rows


class Results:
    """Read a results folder, also one whose run was killed part way.

    Parameters
    ----------
    path : path-like
        The results folder (or its ``particles.pvd``).

    Attributes
    ----------
    path : Path
        The folder.
    times : numpy.ndarray
        (F,) float, simulated time of each complete frame, s.
    summary : dict
        ``summary.json`` as written (empty if missing).
    series : dict of str to numpy.ndarray
        Columns of ``series.csv`` (``stage`` is a string array), one entry per row.
    project_text : str
        The resolved project that ran ("" if missing).

    Notes
    -----
    Frames come from ``particles.pvd``; if it is missing or damaged the ``frames/`` folder is
    scanned instead. Frame files that are missing or were cut off are skipped.
    """

    def __init__(self, path: str | os.PathLike[str], *, cache_frames: int = 4) -> None:
        path = Path(path)
        if path.is_file() and path.name == PVD_NAME:
            path = path.parent
        if not path.is_dir():
            raise ResultsError(f"{path}: no such results folder")
        if not is_results_dir(path):
            raise ResultsError(f"{path} is not a results folder (no {SUMMARY_NAME}, {PVD_NAME} or {FRAMES_DIR}/)")
        self.path = path
        self.summary: dict[str, Any] = self._read_summary()
        self.series = _read_series(path / SERIES_NAME)
        project = path / PROJECT_NAME
        self.project_text = project.read_text(encoding="utf-8") if project.is_file() else ""
        entries = self._entries()
        self._files = [path / f for _, f in entries]
        self.times = np.array([t for t, _ in entries], dtype=np.float64)
        self._cache: OrderedDict[int, dict[str, np.ndarray]] = OrderedDict()
        self._cache_size = cache_frames

    def _read_summary(self) -> dict[str, Any]:
        summary_path = self.path / SUMMARY_NAME
        if not summary_path.is_file():
            return {}
        try:
            return json.loads(summary_path.read_text(encoding="utf-8"))
        except (json.JSONDecodeError, UnicodeDecodeError) as err:
            logger.warning("%s is damaged (%s); ignoring it", summary_path, err)
            return {}

    def _entries(self) -> list[tuple[float, str]]:
        entries: list[tuple[float, str]] | None = None
        pvd = self.path / PVD_NAME
        if pvd.is_file():
            try:
                root = ElementTree.parse(pvd).getroot()
                entries = [
                    (float(ds.get("timestep", "nan")), ds.get("file", ""))
                    for ds in root.iter("DataSet")
                ]
            except (ElementTree.ParseError, ValueError) as err:
                logger.warning("%s is damaged (%s); scanning %s/ instead", pvd, err, FRAMES_DIR)
        if entries is None:
            entries = []
            frames_dir = self.path / FRAMES_DIR
            files = sorted(
                (int(m.group(1)), p)
                for p in (frames_dir.iterdir() if frames_dir.is_dir() else [])
                if (m := _FRAME_RE.match(p.name))
            )
            for _, file in files:
                if _is_complete(file):
                    t = _frame_time(file)
                    entries.append((t if t is not None else math.nan, f"{FRAMES_DIR}/{file.name}"))
        kept = []
        for t, f in entries:
            if _is_complete(self.path / f):
                kept.append((t, f))
            else:
                logger.warning("skipping incomplete frame file %s", self.path / f)
        return kept

    # -- public ---------------------------------------------------------------------------

    @property
    def status(self) -> str:
        """``completed``, ``stopped`` or ``failed``; ``interrupted`` when the run never closed
        the folder (killed, or still writing)."""
        status = self.summary.get("status")
        return status if status in FINAL_STATUSES else INTERRUPTED

    @property
    def message(self) -> str:
        if self.status == INTERRUPTED:
            return "the run ended without closing its results (killed or still running)"
        return str(self.summary.get("message", ""))

    @property
    def material_names(self) -> list[str]:
        """Material names by ``material_id`` (from the summary; may be empty)."""
        return [str(m) for m in self.summary.get("materials", [])]

    def measured(self, arrays: Mapping[str, np.ndarray]) -> np.ndarray | None:
        """The particles of a frame (:meth:`frame`) that the deposit measures count: the active
        ones less the rigid bodies' (their motion is the loading, not the material's), told by
        ``material_id`` and ``summary.json``'s ``rigid_materials`` (a frame written without
        ``material_id`` keeps them); None where the frame has no ``active`` and no rigid body."""
        active = arrays.get("active")
        names = set(self.summary.get("rigid_materials", []))
        rigid = [i for i, name in enumerate(self.material_names) if name in names]
        if not rigid or "material_id" not in arrays:
            return active
        keep = ~np.isin(np.asarray(arrays["material_id"]), rigid)
        return keep if active is None else np.asarray(active, dtype=bool) & keep

    @property
    def frame_files(self) -> list[Path]:
        return list(self._files)

    def __len__(self) -> int:
        return len(self._files)

    def __repr__(self) -> str:
        return f"Results({str(self.path)!r}, frames={len(self)}, status={self.status!r})"

    def _index(self, i: int) -> int:
        n = len(self._files)
        if n == 0:
            raise IndexError(f"{self.path} has no complete frames")
        j = int(i) + n if int(i) < 0 else int(i)
        if not 0 <= j < n:
            raise IndexError(f"frame {i} out of range: {self.path} has {n} frames")
        return j

    def frame(self, i: int = -1, fields: Iterable[str] | None = None) -> dict[str, np.ndarray]:
        """Arrays of frame ``i`` (negative counts from the end), read-only.

        Parameters
        ----------
        i : int
            Frame index.
        fields : iterable of str, optional
            Decode only these arrays (faster when scanning many frames); all when omitted.
            Only full reads are cached.

        Returns
        -------
        dict of str to numpy.ndarray
            ``positions`` (N, 2) m, ``active`` (N,) bool, ``particle_id`` (N,) int32 and what the
            run wrote of ``displacement`` (N, 2) m, ``velocity`` (N, 2) m/s, ``stress`` (N, 4) Pa
            (xx, yy, xy, zz), ``plastic_strain`` (N,), ``material_id`` (N,) int32.
        """
        j = self._index(i)
        if fields is not None:
            wanted = set(fields)
            if j in self._cache:
                return {k: v for k, v in self._cache[j].items() if k in wanted}
            return self._frame_arrays(j, wanted)
        if j in self._cache:
            self._cache.move_to_end(j)
            return self._cache[j]
        arrays = self._frame_arrays(j, None)
        self._cache[j] = arrays
        while len(self._cache) > self._cache_size:
            self._cache.popitem(last=False)
        return arrays

    def _frame_arrays(self, j: int, names: set[str] | None) -> dict[str, np.ndarray]:
        file_names = None
        if names is not None:
            file_names = {"Points" if n == "positions" else n for n in names}
        raw = read_vtp(self._files[j], file_names)
        out: dict[str, np.ndarray] = {}
        for name, arr in raw.items():
            if name in ("connectivity", "offsets"):
                continue
            if name == "Points":
                name, arr = "positions", arr[:, :2]
            elif name == "active":
                arr = arr.astype(bool)
            elif arr.ndim == 2 and arr.shape[1] == 3 and name != "stress":
                arr = arr[:, :2]
            arr = np.array(arr)  # own, contiguous copy (frombuffer views are read-only anyway)
            arr.flags.writeable = False
            out[name] = arr
        return out

    def particle_history(self, particle_id: int, field: str) -> tuple[np.ndarray, np.ndarray]:
        """One particle's value of ``field`` in every frame.

        Parameters
        ----------
        particle_id : int
            Index of the particle (stable for the whole run).
        field : str
            A key of :meth:`frame` (``positions``, ``displacement``, ``stress``, ...).

        Returns
        -------
        times : numpy.ndarray
            (F,) s.
        values : numpy.ndarray
            (F,) or (F, k), the particle's values, in the units of :meth:`frame`.
        """
        values = []
        for j in range(len(self)):
            arrays = self.frame(j, {field})
            if field not in arrays:
                raise KeyError(f"frame {j} has no field {field!r}; it has {sorted(arrays)}")
            column = arrays[field]
            if not 0 <= particle_id < len(column):
                raise IndexError(f"particle {particle_id} out of range (0..{len(column) - 1})")
            values.append(column[particle_id])
        return self.times.copy(), np.array(values)


def open_results(path: str | os.PathLike[str]) -> Results:
    """Open a results folder; see :class:`Results`."""
    return Results(path)
