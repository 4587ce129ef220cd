"""The one owner of the Taichi runtime.

Taichi keeps global state (the backend, the default float type, every field). Runout never calls
``ti.init`` at import time; a :class:`~solver.simulation.Simulation` asks this module for a runtime
when it is built, and the runtime is reset each time, so solvers can be built, run and disposed
repeatedly in one process. Taichi state is tied to the thread that initialised it: build, run and
close a simulation in the same thread.
"""

from __future__ import annotations

import contextlib
import inspect
import io
import linecache
import logging
import threading


def _source_line_frameinfo(frame, context=1):
    """``inspect.getframeinfo`` for the one use Taichi 1.7 makes of it: the source line of a frame.

    Every ``@ti.kernel`` asks, as it is decorated, whether it is defined in a class body; Taichi
    answers by reading the current source line of the enclosing frame with
    ``inspect.getframeinfo``, which resolves the frame's module by scanning every module loaded
    (``inspect.getmodule``) each time. ``import taichi`` decorates about 150 of its own kernels
    that way: 35-60 ms of every process's start-up. This reads the same line from ``linecache``.
    """
    code = frame.f_code
    line = linecache.getline(code.co_filename, frame.f_lineno)
    return inspect.Traceback(code.co_filename, frame.f_lineno, code.co_name, [line] if line else None, 0)


def _import_taichi():
    """Import Taichi with the cheap source-line lookup while it decorates its own kernels, and keep
    that lookup for the kernels Runout decorates (Taichi 1.7.x's ``_inside_class``, same answer)."""
    slow = inspect.getframeinfo
    inspect.getframeinfo = _source_line_frameinfo
    try:
        import taichi
    finally:
        inspect.getframeinfo = slow
    if taichi.__version__[:2] == (1, 7):
        from taichi.lang import kernel_impl

        patterns = kernel_impl._KERNEL_CLASS_STACKFRAME_STMT_RES

        def inside_class(level_of_class_stackframe):
            try:
                frame = kernel_impl.sys._getframe(level_of_class_stackframe)
            except ValueError:
                return False
            first = linecache.getline(frame.f_code.co_filename, frame.f_lineno).strip()
            return any(pattern.match(first) for pattern in patterns)

        kernel_impl._inside_class = inside_class
    return taichi


# Solver modules import Taichi from here (``from solver.runtime import ti``), so the first import
# in a process takes the cheap path above.
ti = _import_taichi()



# Products of 2-vectors and 2x2 matrices for kernels. Taichi's ``@``, ``outer_product`` and
# ``transpose`` are generic Taichi functions the front end builds anew at every use (1-2 ms each
# in every process: the stencil loops use them 9 times each); these do the same products, with
# the same sums in the same order (frames unchanged bit for bit), for the shapes of a 2-D solver.
@ti.func
def mat_vec(a, b):
    """``a @ b`` for a 2x2 matrix and a 2-vector."""
    return ti.Vector([a[0, 0] * b[0] + a[0, 1] * b[1], a[1, 0] * b[0] + a[1, 1] * b[1]])


@ti.func
def mat_mat(a, b):
    """``a @ b`` for two 2x2 matrices."""
    return ti.Matrix([[a[0, 0] * b[0, 0] + a[0, 1] * b[1, 0], a[0, 0] * b[0, 1] + a[0, 1] * b[1, 1]],
                      [a[1, 0] * b[0, 0] + a[1, 1] * b[1, 0], a[1, 0] * b[0, 1] + a[1, 1] * b[1, 1]]])


@ti.func
def outer(a, b):
    """``a.outer_product(b)`` for two 2-vectors."""
    return ti.Matrix([[a[0] * b[0], a[0] * b[1]], [a[1] * b[0], a[1] * b[1]]])


@ti.func
def transpose(a):
    """``a.transpose()`` for a 2x2 matrix."""
    return ti.Matrix([[a[0, 0], a[1, 0]], [a[0, 1], a[1, 1]]])


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
    # with_cuda() only says the wheel was built with CUDA; a driver is needed too. Loading the
    # driver's library answers that at once (ctypes.util.find_library starts ldconfig and a
    # compiler: 30-60 ms of every run's start on a machine without one).
    import ctypes
    import sys

    try:
        ctypes.CDLL("nvcuda.dll" if sys.platform == "win32" else "libcuda.so.1")  # the driver's soname
    except OSError:
        return False
    return True


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


def _cached_sources() -> None:
    """Read each kernel's and ``ti.func``'s source once per process, not at every use.

    Taichi 1.7 inlines a ``ti.func`` at every call site, and for every call it reads the
    function's source again (``inspect.getsourcelines``, which tokenises the whole file) and
    re-wraps every line with ``textwrap.fill`` before parsing it (``_get_tree_and_ctx``). The
    step kernel calls a few dozen functions, several of them many times (``ti.static`` loops).
    This keeps the source lines of each function after the first read, and its parsed tree: a
    kernel's is parsed again at each instantiation (the transformer rewrites a kernel's argument
    list), an inlined function's serves every call site. What the front end builds from them is
    unchanged (the same IR: the offline cache finds the same kernels, and frames are bit for bit). Applied to Taichi 1.7.x only, whose function this
    replaces.
    """
    try:
        from taichi.lang import kernel_impl
    except ImportError:  # pragma: no cover - another Taichi layout: keep its own behaviour
        return
    if not ti.__version__[:2] == (1, 7) or getattr(kernel_impl, "_runout_cached_sources", False):
        return
    import ast
    import textwrap

    sources: dict[object, tuple[str, list[str], int, str, ast.Module]] = {}
    context = kernel_impl.ASTTransformerContext

    def get_tree_and_ctx(self, excluded_parameters=(), is_kernel=True, arg_features=None, args=None,
                         ast_builder=None, is_real_function=False):
        cached = sources.get(self.func)
        if cached is None:
            file = kernel_impl.getsourcefile(self.func)
            src, start_lineno = kernel_impl.getsourcelines(self.func)
            src = [textwrap.fill(line, tabsize=4, width=9999) for line in src]
            text = textwrap.dedent("\n".join(src))
            cached = sources[self.func] = (file, src, start_lineno, text, ast.parse(text))
        file, src, start_lineno, text, inlined_tree = cached
        if is_kernel or is_real_function:
            tree = ast.parse(text)  # a kernel's transform rewrites its arguments: a fresh tree each time
        else:
            # An inlined ti.func's transform only annotates the nodes it visits (``node.ptr``,
            # written before it is read), so one tree serves every call site.
            tree = inlined_tree
        tree.body[0].decorator_list = []
        global_vars = kernel_impl._get_global_vars(self.func)
        if is_kernel or is_real_function:
            for i in self.template_slot_locations:  # template parameters are globals of the body
                global_vars[self.arguments[i].name] = args[i]
        return tree, context(
            excluded_parameters=excluded_parameters, is_kernel=is_kernel, func=self, arg_features=arg_features,
            global_vars=global_vars, argument_data=args, src=src, start_lineno=start_lineno, file=file,
            ast_builder=ast_builder, is_real_function=is_real_function,
        )

    kernel_impl._get_tree_and_ctx = get_tree_and_ctx
    kernel_impl._runout_cached_sources = True


# Taichi's offline kernel cache keeps at most 100 MB by default and then drops the least recently
# used quarter. Every grid compiles its own kernels (0.1-1.1 MB each; a scene with structures ~1 MB),
# so the test suite's scenes alone overflow it and a second run recompiled most of them (39 min
# instead of about 15 on two cores). 1 GiB holds them with room for a user's projects.
KERNEL_CACHE_MAX_BYTES = 1024 ** 3  # (a 32-bit setting: below 2 GiB)

# Taichi's "advanced optimization" IR passes are most of a kernel's compile time on the CPU: the
# step kernel of a scene with structures compiled in 47 s with them and 6.4 s without (the check-dam
# example, two cores), and a run compiles it afresh for every new grid. The steps run 2-3 % slower
# (paired rounds at 20,000 particles, docs/performance.md, kernel compilation), so the CPU runs
# without them; on a GPU, where the long runs are and nothing was measured, they stay on. The
# results differ from the optimised kernels' in the last bits of f32 only.
CPU_ADVANCED_OPTIMIZATION = False


def _init(**kwargs) -> None:
    _lean_source_positions()
    _cached_sources()
    kwargs.setdefault("offline_cache_max_size_of_files", KERNEL_CACHE_MAX_BYTES)
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
            _init(arch=ti.cpu, default_fp=fp, default_ip=ti.i32, offline_cache=True, log_level=ti.WARN,
                  advanced_optimization=CPU_ADVANCED_OPTIMIZATION)
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
