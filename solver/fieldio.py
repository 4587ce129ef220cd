"""Copy many Taichi fields to and from numpy in one kernel launch.

Taichi's ``field.to_numpy()`` / ``from_numpy()`` / ``fill()`` compile one kernel per field (the
field is a template argument). Taichi 1.7 builds every kernel from its Python AST in each process
and loads it from the offline cache at its first launch, about 10-20 ms a kernel on the
development machine even with the cache warm; a run that moved its state field by field paid
for 60-90 such kernels before its first step (docs/performance.md, "Start-up").

A :class:`FieldIO` holds a fixed set of fields and moves all of them with one kernel, in either
direction: the values of each dtype travel in one flat numpy buffer of that dtype (no
conversion, so the copies are exact bit for bit), each field at its own offset in the layout
``field.to_numpy()`` gives (C order; a vector field's components, a matrix field's rows, last).
"""


import math
import warnings
from collections.abc import Iterable, Mapping

import numpy as np
from solver.runtime import ti

_TO_NUMPY = {"f32": np.float32, "f64": np.float64, "i32": np.int32, "i8": np.int8}
#: buffer slots of the kernel, one per dtype
_SLOTS = ("f32", "f64", "i32", "i8")


def _dtype_name(field) -> str:
    dt = field.dtype
    for name, ti_type in (("f32", ti.f32), ("f64", ti.f64), ("i32", ti.i32), ("i8", ti.i8)):
        if dt == ti_type:
            return name
    raise TypeError(f"FieldIO handles f32, f64, i32 and i8 fields, not {dt}")


def _element_shape(field) -> tuple[int, ...]:
    """Shape of one element as ``to_numpy`` lays it out: () scalar, (n,) vector, (n, m) matrix."""
    n = getattr(field, "n", None)
    if n is None:
        return ()
    m = getattr(field, "m", 1)
    ndim = getattr(field, "ndim", 2 if m > 1 else 1)
    return (n, m) if ndim == 2 else (n,)


@ti.data_oriented
class FieldIO:
    """Read and write a fixed set of fields with one kernel (compiled once per set).

    Parameters
    ----------
    fields : mapping of name -> Taichi field
        Scalar, vector or matrix fields of f32, f64, i32 or i8, of any shape (0-d included).
    """

    def __init__(self, fields: Mapping[str, object]):
        self.fields = dict(fields)
        sizes = {slot: 0 for slot in _SLOTS}
        layout = []  # (name, field, slot, offset, shape, element shape)
        for name, field in self.fields.items():
            slot = _dtype_name(field)
            shape = tuple(field.shape)
            element = _element_shape(field)
            layout.append((name, field, slot, sizes[slot], shape, element))
            sizes[slot] += math.prod(shape) * math.prod(element)
        self.layout = tuple(layout)
        self._index = {entry[0]: k for k, entry in enumerate(layout)}
        self.entries = tuple((field, slot, offset, shape, element) for _n, field, slot, offset, shape, element in layout)
        # fields of one shape share the bound test and the multi-index of element i in the kernel
        groups: dict[tuple[int, ...], list[int]] = {}
        for k, (*_r, shape, _e) in enumerate(layout):
            groups.setdefault(shape, []).append(k)
        self.groups = tuple((shape, tuple(ks)) for shape, ks in groups.items())
        self._counts = [math.prod(shape) for *_r, shape, _e in layout]  # elements per field
        self.sizes = sizes
        self.shapes = {name: shape + element for name, _f, _s, _o, shape, element in layout}
        self.dtypes = {name: _TO_NUMPY[slot] for name, _f, slot, *_ in layout}

    # ------------------------------------------------------------------ host side
    def read(self, names: Iterable[str] | None = None) -> dict[str, np.ndarray]:
        """Copies of the fields (all, or the named ones) as ``to_numpy`` would return them."""
        wanted = tuple(self.fields) if names is None else tuple(names)
        buf = self._buffers(wanted)
        self._launch(0, self._mask(wanted), buf)
        out = {}
        for name in wanted:
            _n, _f, slot, offset, shape, element = self._entry(name)
            size = math.prod(shape) * math.prod(element)
            out[name] = buf[slot][offset: offset + size].reshape(shape + element)
        return out

    def write(self, values: Mapping[str, np.ndarray]) -> None:
        """Set the named fields from arrays of their ``to_numpy`` shape, or scalars (cast to the
        field's dtype); fields not named keep their values."""
        buf = self._buffers(values)
        for name, value in values.items():
            _n, _f, slot, offset, shape, element = self._entry(name)
            full = shape + element
            value = np.asarray(value)
            if value.ndim == 0:
                value = np.broadcast_to(value, full)
            elif value.shape != full:
                raise ValueError(f"field {name!r} has shape {full}, got an array of shape {value.shape}")
            buf[slot][offset: offset + math.prod(full)] = value.astype(_TO_NUMPY[slot], copy=False).ravel()
        self._launch(1, self._mask(values), buf)

    def _launch(self, into_fields: int, mask: np.ndarray, buf: Mapping[str, np.ndarray]) -> None:
        with warnings.catch_warnings():
            # the loop over the fields is unrolled on purpose (one straight-line body), which
            # Taichi warns about beyond 32 iterations at the first launch
            warnings.filterwarnings("ignore", message=".*unrolling more than", category=SyntaxWarning)
            extent = max((self._counts[k] for k in np.flatnonzero(mask)), default=0)  # the longest named field
            self._copy(into_fields, extent, mask, buf["f32"], buf["f64"], buf["i32"], buf["i8"])

    def _buffers(self, names: Iterable[str]) -> dict[str, np.ndarray]:
        """Flat buffers, one per dtype, long enough for the named fields (at least one element:
        Taichi wants a pointer); a dtype none of them uses gets a one-element dummy."""
        ends = {slot: 1 for slot in _SLOTS}
        for name in names:
            _n, _f, slot, offset, shape, element = self._entry(name)
            ends[slot] = max(ends[slot], offset + math.prod(shape) * math.prod(element))
        return {slot: np.empty(ends[slot], _TO_NUMPY[slot]) for slot in _SLOTS}

    def _mask(self, names: Iterable[str]) -> np.ndarray:
        mask = np.zeros(len(self.layout), np.int32)
        for name in names:
            mask[self._index[name]] = 1
        return mask

    def _entry(self, name: str):
        try:
            return self.layout[self._index[name]]
        except KeyError:
            raise KeyError(f"unknown field {name!r}; known: {', '.join(self.fields)}") from None

    # ------------------------------------------------------------------ the kernel
    # One parallel loop over the elements of the longest field named; element i of every field that has one
    # is copied in the same iteration. The compiled kernel is one task with straight-line code:
    # Taichi's own copies (a struct-for per field) load about four times slower from the offline
    # cache per field, and a loop per field shape costs a task each. The same kernel serves both
    # directions and any subset of the fields (``mask``), so a process compiles it once.
    @ti.kernel
    def _copy(self, into_fields: ti.i32, extent: ti.i32, mask: ti.types.ndarray(dtype=ti.i32, ndim=1),
              f32: ti.types.ndarray(dtype=ti.f32, ndim=1), f64: ti.types.ndarray(dtype=ti.f64, ndim=1),
              i32: ti.types.ndarray(dtype=ti.i32, ndim=1), i8: ti.types.ndarray(dtype=ti.i8, ndim=1)):
        for i in range(extent):
            for g in ti.static(range(len(self.groups))):
                shape, members = ti.static(self.groups[g])
                if i < ti.static(math.prod(shape)):
                    I = ti.Vector([0] * ti.static(max(len(shape), 1)))
                    if ti.static(len(shape) > 0):
                        rest = i
                        for d in ti.static(range(len(shape) - 1, -1, -1)):
                            I[d] = rest % shape[d]
                            rest //= shape[d]
                    for k in ti.static(members):
                        field, slot, offset, _shape, element = ti.static(self.entries[k])
                        buf = ti.static((f32, f64, i32, i8)[_SLOTS.index(slot)])
                        if mask[k]:
                            base = offset + i * ti.static(math.prod(element))
                            if ti.static(len(shape) == 0):
                                self._copy_element(into_fields, field, None, buf, base, element)
                            else:
                                self._copy_element(into_fields, field, I, buf, base, element)

    @ti.func
    def _copy_element(self, into_fields, field: ti.template(), I: ti.template(), buf: ti.template(), base,
                      element: ti.template()):
        if ti.static(len(element) == 0):
            if into_fields:
                field[I] = buf[base]
            else:
                buf[base] = field[I]
        elif ti.static(len(element) == 1):
            for c in ti.static(range(element[0])):
                if into_fields:
                    field[I][c] = buf[base + c]
                else:
                    buf[base + c] = field[I][c]
        else:
            for r, c in ti.static(ti.ndrange(element[0], element[1])):
                if into_fields:
                    field[I][r, c] = buf[base + r * element[1] + c]
                else:
                    buf[base + r * element[1] + c] = field[I][r, c]
