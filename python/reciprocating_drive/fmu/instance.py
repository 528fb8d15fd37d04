"""One FMU instance driven from Python through fmpy's low-level FMI 2.0 API.

`Fmu` loads an FMU once (read the model description, unpack, load the shared library) and can be
started many times with different parameters (fmi2Reset between runs), which is what a sweep
worker or a twin needs. Every FMI call that fails raises `FmuError` carrying the FMU's own log
messages (which name the variable, the value and the allowed range).

Two ways to exchange values:

* `set({name: value})`, `get([names])`: by name, any type; convenient, a few µs per call;
* `channel(inputs, outputs)`: a `Channel` with preallocated ctypes arrays for a fixed list of
  Real inputs and outputs, whose `step(t_next, values)` is one fmi2SetReal, one fmi2DoStep and
  one fmi2GetReal straight into a numpy row (the per-sample path of the sweeps), and whose
  `run(t, inputs, outputs)` does the same for many communication points in one call of the
  native batch driver (`batch.py`, tools/fmi2-batch): the path of the digital twin.

Layer: FMU access, below the workflows (docs/architecture.md).
"""

from __future__ import annotations

import ctypes
import pathlib
import shutil
import tempfile
import weakref
from collections.abc import Iterable, Mapping, Sequence

import numpy as np

from .. import artifacts

DEFAULT_FMU = artifacts.fmu()

_STATUS = ["OK", "Warning", "Discard", "Error", "Fatal", "Pending"]


class FmuError(RuntimeError):
    """An FMI call returned fmi2Discard, fmi2Error or fmi2Fatal. `messages` are the FMU's log
    lines of that call (the first one names the variable, value and allowed range)."""

    def __init__(self, function: str, status: int, messages: Sequence[str]):
        label = _STATUS[status] if 0 <= status < len(_STATUS) else str(status)
        text = "; ".join(messages) if messages else "(no message from the FMU)"
        super().__init__(f"{function} returned fmi2{label}: {text}")
        self.function = function
        self.status = status
        self.messages = list(messages)


# The FMI 2.0 logger with the one variadic argument this project's FMUs pass (see _Log).
_LOGGER6 = ctypes.CFUNCTYPE(
    None,
    ctypes.c_void_p,
    ctypes.c_char_p,
    ctypes.c_int,
    ctypes.c_char_p,
    ctypes.c_char_p,
    ctypes.c_char_p,
)


class _Log:
    """Keeps the FMU's log messages.

    The FMI logger is variadic, which ctypes cannot receive. fmpy's native proxy
    (`fmpy.logging.addLoggerProxy`) formats the message but forwards it to one process-wide
    Python callback: every instance that registers replaces it, so messages go to the last
    instance registered, and once that instance is freed the next message calls freed memory.
    This FMU's loggers are therefore taken directly: the FMUs of this project always call them as
    (env, name, status, category, "%s", message), and on x86-64 (System V and Windows) the variadic
    argument arrives where a sixth fixed argument would. Another FMU's format string is kept as
    it is, unformatted."""

    def __init__(self, echo: bool):
        from fmpy.fmi2 import (
            fmi2CallbackAllocateMemoryTYPE,
            fmi2CallbackFreeMemoryTYPE,
            fmi2CallbackFunctions,
            fmi2CallbackLoggerTYPE,
        )

        self.lines: list[tuple[int, str, str]] = []
        self.echo = echo

        def logger(env, name, status, category, fmt, arg):
            raw = arg if fmt == b"%s" else fmt
            text = raw.decode("utf-8", "replace") if raw else ""
            cat = category.decode() if category else ""
            self.lines.append((status, cat, text))
            if self.echo and status > 0:
                print(f"[{_STATUS[status] if status < len(_STATUS) else status}] {text}")

        self.callbacks = fmi2CallbackFunctions()
        # Kept with the instance: ctypes keeps no reference of its own.
        self._fn = _LOGGER6(logger)
        self.callbacks.logger = fmi2CallbackLoggerTYPE(ctypes.cast(self._fn, ctypes.c_void_p).value)
        libc = ctypes.CDLL(None)
        self.callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(libc.calloc)
        self.callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(libc.free)
        self.callbacks.componentEnvironment = None

    def mark(self) -> int:
        return len(self.lines)

    def since(self, mark: int) -> list[str]:
        return [m for (s, _, m) in self.lines[mark:] if s > 0 and m]


class Fmu:
    """A loaded FMU and one co-simulation instance of it."""

    def __init__(
        self,
        path: str | pathlib.Path = DEFAULT_FMU,
        instance_name: str | None = None,
        logging_on: bool = False,
        echo_log: bool = False,
    ):
        from fmpy import extract, read_model_description
        from fmpy.fmi2 import FMU2Slave

        self.path = pathlib.Path(path)
        if not self.path.is_file():
            raise FileNotFoundError(f"{self.path} not found: build it with scripts/build-fmu.sh")
        self.model_description = md = read_model_description(str(self.path))
        self.variables = {v.name: v for v in md.modelVariables}
        self.vr = {v.name: v.valueReference for v in md.modelVariables}
        self.outputs = [v.name for v in md.modelVariables if v.causality == "output"]
        self.inputs = [v.name for v in md.modelVariables if v.causality == "input"]
        self._tmp = tempfile.mkdtemp(prefix="rdfmu-")
        # The extracted FMU (4 MB) goes with the object or, at the latest, when the process
        # exits normally: instances kept for a process's life (a Dask worker's, a command's)
        # are never closed, and each left its copy in the temporary folder.
        self._remove_tmp = weakref.finalize(self, shutil.rmtree, self._tmp, True)
        unzipdir = extract(str(self.path), unzipdir=self._tmp)
        self._log = _Log(echo_log)
        ident = md.coSimulation.modelIdentifier
        self._slave = FMU2Slave(
            guid=md.guid,
            unzipDirectory=unzipdir,
            modelIdentifier=ident,
            instanceName=instance_name or ident,
        )
        self._raw = self._slave._functions
        self._component = None
        self._instantiate(logging_on)
        self._started = False
        self.time = 0.0

    # -- plumbing -------------------------------------------------------------------------------

    def _check(self, function: str, status: int, mark: int) -> None:
        if status > 1:
            raise FmuError(function, status, self._log.since(mark))

    def _call(self, function: str, *args) -> int:
        mark = self._log.mark()
        status = self._raw[function](self._component, *args)
        self._check(function, status, mark)
        return status

    def _instantiate(self, logging_on: bool) -> None:
        from fmpy.fmi1 import FMICallException

        mark = self._log.mark()
        try:
            self._slave.instantiate(callbacks=self._log.callbacks, loggingOn=logging_on)
        except FMICallException as e:
            raise FmuError("fmi2Instantiate", 3, self._log.since(mark)) from e
        self._component = self._slave.component

    def messages(self) -> list[str]:
        """Every message the FMU has logged so far (warnings and errors)."""
        return [m for (s, _, m) in self._log.lines if s > 0]

    # -- life cycle -----------------------------------------------------------------------------

    def start(
        self,
        values: Mapping[str, float] | None = None,
        start_time: float = 0.0,
        tolerance: float | None = None,
        stop_time: float | None = None,
    ) -> None:
        """(Re)initializes the instance: fmi2Reset if it ran before, fmi2SetupExperiment, the
        given parameter and input values in initialization mode, fmi2ExitInitializationMode."""
        if self._started:
            self._call("fmi2Reset")
        self._started = True
        self._call(
            "fmi2SetupExperiment",
            int(tolerance is not None),
            float(tolerance or 0.0),
            float(start_time),
            int(stop_time is not None),
            float(stop_time or 0.0),
        )
        self._call("fmi2EnterInitializationMode")
        if values:
            self.set(values)
        self._call("fmi2ExitInitializationMode")
        self.time = float(start_time)

    def step(self, h: float) -> None:
        """fmi2DoStep from the current time over h."""
        self._call("fmi2DoStep", ctypes.c_double(self.time), ctypes.c_double(h), 1)
        self.time += h

    def step_to(self, t_next: float) -> None:
        """fmi2DoStep to the communication point t_next (variable step size)."""
        self._call("fmi2DoStep", ctypes.c_double(self.time), ctypes.c_double(t_next - self.time), 1)
        self.time = float(t_next)

    def close(self) -> None:
        if self._component is not None:
            try:
                self._slave.freeInstance()
            finally:
                self._component = None
                self._slave.freeLibrary()
        self._remove_tmp()

    def __enter__(self) -> Fmu:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # -- values ---------------------------------------------------------------------------------

    def set(self, values: Mapping[str, float]) -> None:
        """Sets values by name (Real, Integer or Boolean, as the model description declares)."""
        from fmpy.fmi2 import fmi2Boolean, fmi2Integer, fmi2Real, fmi2ValueReference

        groups: dict[str, tuple[list, list]] = {}
        for name, value in values.items():
            var = self.variables.get(name)
            if var is None:
                raise KeyError(f"the FMU has no variable {name!r}")
            vrs, vals = groups.setdefault(var.type, ([], []))
            vrs.append(var.valueReference)
            vals.append(value)
        ctype = {"Real": fmi2Real, "Integer": fmi2Integer, "Boolean": fmi2Boolean}
        for ty, (vrs, vals) in groups.items():
            if ty not in ctype:
                raise TypeError(f"variables of type {ty} are not supported")
            n = len(vrs)
            conv = float if ty == "Real" else int
            self._call(
                f"fmi2Set{ty}", (fmi2ValueReference * n)(*vrs), n, (ctype[ty] * n)(*map(conv, vals))
            )

    def get(self, names: Iterable[str]) -> list[float]:
        """Values by name (Reals as float, Integers as int, Booleans as bool)."""
        from fmpy.fmi2 import fmi2Boolean, fmi2Integer, fmi2Real, fmi2ValueReference

        out = []
        for name in names:
            var = self.variables[name]
            ctype = {"Real": fmi2Real, "Integer": fmi2Integer, "Boolean": fmi2Boolean}[var.type]
            buf = (ctype * 1)()
            self._call(f"fmi2Get{var.type}", (fmi2ValueReference * 1)(var.valueReference), 1, buf)
            out.append(bool(buf[0]) if var.type == "Boolean" else buf[0])
        return out

    def channel(self, inputs: Sequence[str], outputs: Sequence[str]) -> Channel:
        return Channel(self, inputs, outputs)

    # -- FMU state ------------------------------------------------------------------------------

    def get_state(self):
        state = ctypes.c_void_p()
        self._call("fmi2GetFMUstate", ctypes.byref(state))
        return state

    def set_state(self, state) -> None:
        self._call("fmi2SetFMUstate", state)

    def free_state(self, state) -> None:
        self._call("fmi2FreeFMUstate", ctypes.byref(state))

    def serialize(self) -> bytes:
        """The instance's current state as self-contained bytes (fmi2SerializeFMUstate)."""
        state = self.get_state()
        try:
            size = ctypes.c_size_t()
            self._call("fmi2SerializedFMUstateSize", state, ctypes.byref(size))
            buf = (ctypes.c_char * size.value)()
            self._call("fmi2SerializeFMUstate", state, buf, size)
            return bytes(buf)
        finally:
            self.free_state(state)

    def restore(self, data: bytes, time: float) -> None:
        """Sets the instance to serialized bytes from `serialize` (taken at `time`)."""
        state = ctypes.c_void_p()
        buf = (ctypes.c_char * len(data)).from_buffer_copy(data)
        self._call("fmi2DeSerializeFMUstate", buf, ctypes.c_size_t(len(data)), ctypes.byref(state))
        try:
            self.set_state(state)
        finally:
            self.free_state(state)
        self._started = True
        self.time = float(time)


class Channel:
    """Fixed Real inputs and outputs with preallocated buffers: `step(t_next, values, out)` sets
    the inputs, steps to t_next and reads the outputs into `out` (a float64 numpy row), with one
    fmi2SetReal, one fmi2DoStep and one fmi2GetReal."""

    def __init__(self, fmu: Fmu, inputs: Sequence[str], outputs: Sequence[str]):
        from fmpy.fmi2 import fmi2Real, fmi2ValueReference

        for n in list(inputs) + list(outputs):
            if fmu.variables[n].type != "Real":
                raise TypeError(f"{n} is not a Real variable")
        self.fmu = fmu
        self.inputs, self.outputs = list(inputs), list(outputs)
        self._ni, self._no = len(self.inputs), len(self.outputs)
        self._vin = (fmi2ValueReference * self._ni)(*[fmu.vr[n] for n in self.inputs])
        self._vout = (fmi2ValueReference * self._no)(*[fmu.vr[n] for n in self.outputs])
        self._xin = (fmi2Real * self._ni)()
        self._set = fmu._raw["fmi2SetReal"]
        self._get = fmu._raw["fmi2GetReal"]
        self._do = fmu._raw["fmi2DoStep"]

    def set_inputs(self, values: Sequence[float]) -> None:
        f = self.fmu
        self._xin[:] = values
        mark = f._log.mark()
        f._check("fmi2SetReal", self._set(f._component, self._vin, self._ni, self._xin), mark)

    def read(self, out: np.ndarray) -> np.ndarray:
        """The outputs at the current communication point, written into `out` (float64)."""
        f = self.fmu
        mark = f._log.mark()
        f._check(
            "fmi2GetReal",
            self._get(
                f._component,
                self._vout,
                self._no,
                out.ctypes.data_as(ctypes.POINTER(ctypes.c_double)),
            ),
            mark,
        )
        return out

    def advance(self, t_next: float) -> None:
        """fmi2DoStep from the FMU's time to t_next (inputs as last set)."""
        f = self.fmu
        mark = f._log.mark()
        f._check("fmi2DoStep", self._do(f._component, f.time, t_next - f.time, 1), mark)
        f.time = t_next

    def run(
        self, t: np.ndarray, inputs: np.ndarray, outputs: np.ndarray, set_first: bool = False
    ) -> None:
        """Many communication points in one native call: for each k, fmi2DoStep to t[k], fmi2SetReal
        of inputs[k], fmi2GetReal into outputs[k] (with `set_first`, fmi2SetReal before the step,
        as `step` does). `outputs` may be a view whose rows are strided (e.g. columns 1: of a table).
        A call returning fmi2Discard or worse stops the batch: the rows before it are written, the
        FMU's time is that of the last completed step, and FmuError carries the FMU's messages
        (those logged during the batch) and `index`, the sample that failed."""
        from . import batch

        f = self.fmu
        mark = f._log.mark()
        done, status, function = batch.run(
            self._addresses,
            f._component,
            self._vin,
            self._vout,
            f.time,
            t,
            inputs,
            outputs,
            batch.ORDER_SET_STEP_GET if set_first else batch.ORDER_STEP_SET_GET,
        )
        # The FMU's time: the last communication point whose step succeeded.
        stepped = done + int(
            function == "fmi2GetReal" or (function == "fmi2SetReal" and not set_first)
        )
        if stepped > 0:
            f.time = float(t[stepped - 1])
        if function is not None:
            err = FmuError(function, status, f._log.since(mark))
            err.index = done
            raise err

    @property
    def _addresses(self) -> tuple[int, int, int]:
        from .batch import address

        if not hasattr(self, "_addr"):
            self._addr = (address(self._set), address(self._do), address(self._get))
        return self._addr

    def step(self, t_next: float, values: Sequence[float] | None, out: np.ndarray) -> np.ndarray:
        """Inputs `values` (taken as the crank state at the step's start, which the FMU carries
        forward through the step: docs/model.md §2), fmi2DoStep to t_next, outputs into `out`."""
        if values is not None:
            self.set_inputs(values)
        self.advance(t_next)
        return self.read(out)
