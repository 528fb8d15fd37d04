"""The digital twin's native inner loops (tools/fmi2-batch, `libfmi2_batch.so`) through ctypes:
many communication points of a loaded FMU in one call (`run`, used by `fmu.Channel.run`), many
cases of a design sweep in one call (`fmi2_batch_cases`, used by `sweep_cases`), rows of
numbers as CSV text exactly as Python's repr writes them (`format_csv`), and the local-cubic
estimate of speed and acceleration (`local_cubic`, the algorithm of `conditioning.fit`), and the
clean lines of a CSV (`parse_csv`).

The library is built by `cargo build --release --workspace --lib` (scripts/build-fmu.sh, which
scripts/run.sh and scripts/test.sh call). RD_BATCH_LIB=/path/to/libfmi2_batch.so loads another
build.

Layer: FMU access, below the workflows (docs/architecture.md).
"""

from __future__ import annotations

import ctypes
import math
import os
import pathlib

import numpy as np

from .. import artifacts

DEFAULT_LIB = artifacts.batch_library()

#: Call order at each communication point (tools/fmi2-batch/src/lib.rs).
ORDER_STEP_SET_GET = 0
ORDER_SET_STEP_GET = 1
#: Which call failed.
FUNCTIONS = {1: "fmi2DoStep", 2: "fmi2SetReal", 3: "fmi2GetReal"}
_BAD_ARGUMENTS, _PANICKED = -1, -2


class Failure(ctypes.Structure):
    _fields_ = [("status", ctypes.c_int), ("function", ctypes.c_int)]


#: Which call of a case failed in fmi2_batch_cases (beyond FUNCTIONS; tools/fmi2-batch/src/cases.rs).
CASE_FUNCTIONS = {
    **FUNCTIONS,
    4: "fmi2Reset",
    5: "fmi2SetupExperiment",
    6: "fmi2EnterInitializationMode",
    7: "fmi2Set*",
    8: "fmi2ExitInitializationMode",
}


class CaseFunctions(ctypes.Structure):
    """The addresses of the FMU's functions a case calls (cases.rs, CaseFunctions)."""

    _fields_ = [
        (name, ctypes.c_void_p)
        for name in ("reset", "setup", "enter", "exit", "set_real", "do_step", "get_real")
    ]


class SetGroup(ctypes.Structure):
    """The values of one type set in initialization mode: `set` (fmi2SetReal, fmi2SetInteger or
    fmi2SetBoolean) with the `n` value references `vr` and, for case c, the `n` values of
    `value_bytes` bytes at `values + c * row_bytes` (cases.rs, SetGroup)."""

    _fields_ = [
        ("set", ctypes.c_void_p),
        ("vr", ctypes.c_void_p),
        ("n", ctypes.c_size_t),
        ("values", ctypes.c_void_p),
        ("value_bytes", ctypes.c_size_t),
        ("row_bytes", ctypes.c_size_t),
    ]


class CaseFailure(ctypes.Structure):
    """Where fmi2_batch_cases stopped: the case, the step (or the SetGroup), the status, the
    call (CASE_FUNCTIONS)."""

    _fields_ = [
        ("case", ctypes.c_size_t),
        ("step", ctypes.c_size_t),
        ("status", ctypes.c_int),
        ("function", ctypes.c_int),
    ]


_lib = None


def library() -> ctypes.CDLL:
    """The loaded native library (loaded once)."""
    global _lib
    if _lib is None:
        path = pathlib.Path(os.environ.get("RD_BATCH_LIB", DEFAULT_LIB))
        if not path.is_file():
            raise FileNotFoundError(
                f"{path} not found: build it with scripts/build-fmu.sh "
                "(or cargo build --release -p fmi2-batch)"
            )
        lib = ctypes.CDLL(str(path))
        vp, sz, dp, ip = ctypes.c_void_p, ctypes.c_size_t, ctypes.c_void_p, ctypes.c_int
        lib.fmi2_batch_run.argtypes = [
            vp,
            vp,
            vp,
            vp,
            vp,
            sz,
            vp,
            sz,
            ctypes.c_double,
            sz,
            dp,
            dp,
            sz,
            dp,
            sz,
            ip,
            ip,
            ctypes.POINTER(Failure),
        ]
        lib.fmi2_batch_run.restype = ctypes.c_ssize_t
        lib.fmi2_batch_cases.argtypes = [
            ctypes.POINTER(CaseFunctions), vp, ip, ctypes.POINTER(SetGroup), sz, vp, vp, sz,
            sz, dp, dp, sz, dp, sz, dp, ip, ctypes.POINTER(CaseFailure),
        ]  # fmt: skip
        lib.fmi2_batch_cases.restype = ctypes.c_ssize_t
        lib.fmi2_batch_format_csv.argtypes = [dp, sz, sz, sz, vp, sz]
        lib.fmi2_batch_format_csv.restype = ctypes.c_ssize_t
        lib.fmi2_batch_max_number_len.restype = sz
        d = ctypes.c_double
        lib.fmi2_batch_local_cubic.argtypes = [dp, dp, sz, d, d, d, sz, sz, dp, dp, vp]
        lib.fmi2_batch_local_cubic.restype = ctypes.c_ssize_t
        lib.fmi2_batch_parse_csv.argtypes = [ctypes.c_char_p, sz, sz, sz, vp, vp, vp, vp, sz]
        lib.fmi2_batch_parse_csv.restype = ctypes.c_ssize_t
        _lib = lib
    return _lib


def address(function) -> int:
    """The C address of a ctypes function (e.g. fmpy's loaded fmi2DoStep)."""
    return ctypes.cast(function, ctypes.c_void_p).value


def _rows(a: np.ndarray, width: int, name: str) -> tuple[int, int]:
    """(pointer, row stride in elements) of a 2-D float64 array whose rows are contiguous."""
    if (
        a.dtype != np.float64
        or a.ndim != 2
        or a.shape[1] != width
        or (a.shape[0] > 1 and a.strides[0] % 8)
        or (width > 1 and a.strides[1] != 8)
    ):
        raise ValueError(f"{name}: a 2-D float64 array of {width} contiguous columns is needed")
    return a.ctypes.data, (a.strides[0] // 8 if a.shape[0] > 1 else width)


def run(
    functions: tuple,
    component: int,
    vr_in,
    vr_out,
    t_start: float,
    t: np.ndarray,
    inputs: np.ndarray,
    outputs: np.ndarray,
    order: int = ORDER_STEP_SET_GET,
    worst_ok: int = 1,
) -> tuple[int, int, str | None]:
    """Communication points t[k] through the native driver; `functions` are the addresses of
    fmi2SetReal, fmi2DoStep and fmi2GetReal, vr_in/vr_out ctypes arrays of value references.
    Returns (samples completed, status, name of the failed call or None)."""
    t = np.ascontiguousarray(t, dtype=np.float64)
    n = len(t)
    if inputs.shape[0] != n or outputs.shape[0] != n:
        raise ValueError("t, inputs and outputs must have the same number of rows")
    xin, sin = _rows(inputs, len(vr_in), "inputs")
    xout, sout = _rows(outputs, len(vr_out), "outputs")
    fail = Failure()
    done = library().fmi2_batch_run(
        *functions,
        component,
        ctypes.addressof(vr_in),
        len(vr_in),
        ctypes.addressof(vr_out),
        len(vr_out),
        float(t_start),
        n,
        t.ctypes.data,
        xin,
        sin,
        xout,
        sout,
        order,
        worst_ok,
        ctypes.byref(fail),
    )
    if done < 0:
        raise RuntimeError(
            "fmi2_batch_run: " + ("bad arguments" if done == _BAD_ARGUMENTS else "internal error")
        )
    return done, fail.status, FUNCTIONS.get(fail.function)


def format_csv(rows: np.ndarray, buffer: bytearray | None = None) -> bytes | memoryview:
    """CSV lines of a 2-D float64 array, each number as repr() writes it (reads back exactly).
    With `buffer`, the text is written into it (grown as needed) and a view of it is returned,
    valid until the buffer's next use: no allocation of a fresh buffer and no copy per call (the
    twin's writer formats ~2000 rows of ~40 numbers per call). Release the view before the next
    call (as `out.write(format_csv(rows, buffer))` does): a bytearray with a live view cannot
    grow."""
    lib = library()
    rows = np.asarray(rows, dtype=np.float64)
    if rows.ndim != 2:
        raise ValueError("format_csv wants a 2-D array")
    if rows.shape[0] == 0:
        return b""
    if rows.strides[1] != 8:
        rows = np.ascontiguousarray(rows)
    ptr, stride = _rows(rows, rows.shape[1], "rows")
    cap = rows.shape[0] * rows.shape[1] * (lib.fmi2_batch_max_number_len() + 1)
    own = buffer is None
    if own:
        buffer = bytearray(cap)
    elif len(buffer) < cap:
        buffer.extend(bytes(cap - len(buffer)))
    address = ctypes.addressof(ctypes.c_char.from_buffer(buffer))
    n = lib.fmi2_batch_format_csv(ptr, rows.shape[0], rows.shape[1], stride, address, cap)
    if n < 0:
        raise RuntimeError("fmi2_batch_format_csv failed")
    view = memoryview(buffer)[:n]
    return bytes(view) if own else view


def local_cubic(
    t: np.ndarray,
    theta: np.ndarray,
    half: float,
    first: int,
    count: int,
    t_start: float,
    t_end: float = math.inf,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """ω and ε at samples first .. first + count - 1 of a segment spanning t_start .. t_end
    (infinite while it goes on), and the number of samples within each one's window
    (conditioning.window and conditioning.fit: a cubic fitted by least squares to the samples
    within ±half seconds of each, shifted inward at the ends; fewer than
    conditioning.MIN_SAMPLES make a sparse window, fitted to the samples nearest in time).
    Raises ValueError naming the sample whose window is singular."""
    t = np.ascontiguousarray(t, dtype=np.float64)
    theta = np.ascontiguousarray(theta, dtype=np.float64)
    w, e = np.empty(count), np.empty(count)
    inside = np.empty(count, dtype=np.uint64)
    k = library().fmi2_batch_local_cubic(
        t.ctypes.data,
        theta.ctypes.data,
        len(t),
        half,
        t_start,
        t_end,
        first,
        count,
        w.ctypes.data,
        e.ctypes.data,
        inside.ctypes.data,
    )
    if k < 0:
        raise ValueError(
            f"local_cubic: bad arguments (n = {len(t)}, half = {half!r} s, "
            f"samples {first}..{first + count})"
        )
    if k < count:
        raise ValueError(f"the smoothing window of sample {first + k} is singular")
    return w, e, inside


def parse_csv(
    text: bytes, n_fields: int, columns: list[int], defaults: list[float | None], max_lines: int
) -> list:
    """The leading clean lines of `text` (lines of at least n_fields fields whose wanted fields,
    at `columns`, are finite numbers; an empty field takes its default unless that is None): one
    float64 array per column, as many rows as clean lines. Parsing stops at the first other line,
    for the caller to read in Python (blank lines, bad fields and their messages)."""
    m = len(columns)
    out = [np.empty(max_lines) for _ in range(m)]
    ptrs = (ctypes.c_void_p * m)(*[o.ctypes.data for o in out])
    cols = (ctypes.c_size_t * m)(*columns)
    req = (ctypes.c_int * m)(*[int(d is None) for d in defaults])
    dft = (ctypes.c_double * m)(*[0.0 if d is None else d for d in defaults])
    k = library().fmi2_batch_parse_csv(
        text, len(text), n_fields, m, cols, req, dft, ptrs, max_lines
    )
    if k < 0:
        raise ValueError("parse_csv: bad arguments")
    return [o[:k] for o in out]
