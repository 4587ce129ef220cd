"""The one owner of the Taichi runtime.

Taichi keeps global state (the backend, the default float type, every field). Runout never calls
``ti.init`` at import time; a :class:`~solver.simulation.Simulation` asks this module for a runtime
when it is built, and the runtime is reset each time, so solvers can be built, run and disposed
repeatedly in one process. Taichi state is tied to the thread that initialised it: build, run and
close a simulation in the same thread.
"""

from __future__ import annotations

import contextlib
import io
import logging
import threading

import taichi as ti

log = logging.getLogger(__name__)

_lock = threading.Lock()
_owner: int | None = None
_current: tuple[str, str] | None = None


def gpu_available() -> bool:
    """Whether Taichi can see a CUDA or Vulkan device (cheap, does not initialise Taichi)."""
    if not _probe_gpu():  # asking Taichi first makes it log a warning when there is no driver
        return False
    try:
        from taichi._lib import core as _ti_core

        return bool(_ti_core.with_cuda())
    except (ImportError, AttributeError, RuntimeError):
        return False


def _probe_gpu() -> bool:
    # with_cuda() only says the wheel was built with CUDA; a driver is needed too.
    import ctypes.util

    return ctypes.util.find_library("cuda") is not None


def _lean_source_positions() -> None:
    """Make Taichi's kernel front end cheaper: one line per source position in its debug info.

    Taichi 1.7 builds every kernel's IR from the Python AST at the first launch in each process,
    even when the compiled kernel then comes from its offline cache, and for every AST node it
    formats an excerpt of the source with a caret line (``ASTTransformerContext.get_pos_info``,
    through ``textwrap``). Measured on the tiny example: about half of the 1.5 s front-end time.
    A compile error still names the file, line and function; only the excerpt is left out.
    Applied to Taichi 1.7.x only (the pinned release), whose method this replaces.
    """
    try:
        from taichi.lang.ast import ast_transformer_utils as utils
    except ImportError:  # pragma: no cover - another Taichi layout: keep its own behaviour
        return
    if not ti.__version__[:2] == (1, 7) or getattr(utils.ASTTransformerContext, "_runout_lean", False):
        return

    def get_pos_info(self, node) -> str:
        return f'File "{self.file}", line {node.lineno + self.lineno_offset}, in {self.func.func.__name__}\n'

    utils.ASTTransformerContext.get_pos_info = get_pos_info
    utils.ASTTransformerContext._runout_lean = True


def _init(**kwargs) -> None:
    _lean_source_positions()
    # ti.init prints "[Taichi] Starting on arch=..." to stdout; scripts read stdout, so log it instead
    with contextlib.redirect_stdout(io.StringIO()) as banner:
        ti.init(**kwargs)
    if banner.getvalue().strip():
        log.debug(banner.getvalue().strip())


def acquire(arch: str, precision: str) -> str:
    """(Re)initialise Taichi for this thread; return the arch actually used ("cpu" or "gpu").

    Parameters
    ----------
    arch : "auto" | "cpu" | "gpu"
        ``auto`` and ``gpu`` fall back to the CPU, with a log line, when no GPU is usable.
    precision : "f32" | "f64"
    """
    global _owner, _current
    fp = {"f32": ti.f32, "f64": ti.f64}[precision]
    with _lock:
        if _current is not None:
            ti.reset()
        want_gpu = arch in ("auto", "gpu") and gpu_available()
        if arch == "gpu" and not want_gpu:
            log.warning("no usable GPU found; running on the CPU instead")
        used = "cpu"
        if want_gpu:
            try:
                _init(arch=ti.gpu, default_fp=fp, default_ip=ti.i32, offline_cache=True, log_level=ti.WARN)
                used = "gpu" if ti.lang.impl.current_cfg().arch != ti.x64 else "cpu"
            except RuntimeError as exc:  # driver present but unusable
                log.warning("GPU initialisation failed (%s); running on the CPU instead", exc)
                ti.reset()
                want_gpu = False
        if not want_gpu:
            _init(arch=ti.cpu, default_fp=fp, default_ip=ti.i32, offline_cache=True, log_level=ti.WARN)
        if arch == "auto" and used == "cpu":
            log.info("Taichi runtime on the CPU (no GPU found)")
        _owner = threading.get_ident()
        _current = (used, precision)
        return used


def check_owner() -> None:
    """Raise if the calling thread is not the one that initialised the runtime."""
    if _owner is not None and _owner != threading.get_ident():
        raise RuntimeError(
            "the Taichi runtime belongs to another thread: build, run and close a Simulation in one thread"
        )


def release() -> None:
    """Free every Taichi field; a later :func:`acquire` starts afresh."""
    global _owner, _current
    with _lock:
        if _current is not None:
            ti.reset()
        _owner = None
        _current = None
