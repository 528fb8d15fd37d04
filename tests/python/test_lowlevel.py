"""The FMI 2.0 C API through fmpy's low-level FMU2Slave: error handling and its messages, recovery
after an error, several instances in one process, instance names, resource locations, a freed
instance (docs/fmi-interface.md, "What importers pass", "State machine", "A freed instance").

Every log message is captured by our own logger callback, which takes the FMU's "%s" format and
its one variadic argument directly (see `Log`).
"""

from __future__ import annotations

import ctypes
import math
import pathlib
import re

import pytest
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import (
    FMU2Slave,
    fmi2CallbackAllocateMemoryTYPE,
    fmi2CallbackFreeMemoryTYPE,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
    fmi2CoSimulation,
    fmi2Error,
)
from freed_child import run_freed_child
from reference import OUTPUTS, Machine

OMEGA = 2 * math.pi * 65 / 60


# The FMI 2.0 logger with its one variadic argument (see Log).
LOGGER6 = ctypes.CFUNCTYPE(
    None,
    ctypes.c_void_p,
    ctypes.c_char_p,
    ctypes.c_int,
    ctypes.c_char_p,
    ctypes.c_char_p,
    ctypes.c_char_p,
)


class Log:
    """Collects (componentEnvironment, instanceName, status, category, message).

    The logger is received with the one variadic argument the FMU passes (it always logs through
    a "%s" format, asserted here), not through fmpy's native proxy, whose single process-wide
    callback would be left pointing at this object after it is freed."""

    def __init__(self, environment: int | None = None):
        self.lines: list[tuple] = []
        self.formats: set = set()

        def logger(env, name, status, category, fmt, message):
            self.formats.add(fmt)
            self.lines.append(
                (
                    env,
                    name.decode() if name else None,
                    status,
                    category.decode() if category else None,
                    message.decode() if fmt == b"%s" and message else "",
                )
            )

        self.callbacks = fmi2CallbackFunctions()
        self._fn = LOGGER6(logger)  # keep a reference: ctypes does not
        self.callbacks.logger = fmi2CallbackLoggerTYPE(ctypes.cast(self._fn, ctypes.c_void_p).value)
        self.callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(ctypes.CDLL(None).calloc)
        self.callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(ctypes.CDLL(None).free)
        self.callbacks.componentEnvironment = environment

    def messages(self, status=None):
        assert self.formats <= {b"%s"}, f"the FMU logged through formats {self.formats}"
        return [m for (_, _, s, _, m) in self.lines if status is None or s == status]

    def text(self):
        return "\n".join(self.messages())


def new_slave(
    md, unzipdir, name="ReciprocatingDrive", logging_on=False, environment=None, log=None
):
    log = log or Log(environment)
    fmu = FMU2Slave(
        guid=md.guid,
        unzipDirectory=unzipdir,
        modelIdentifier=md.coSimulation.modelIdentifier,
        instanceName=name,
    )
    fmu.instantiate(callbacks=log.callbacks, loggingOn=logging_on)
    return fmu, log


def start(fmu, vr, machine: Machine, theta=0.0, omega=OMEGA, eps=0.0):
    fmu.setupExperiment(startTime=0.0)
    for name, value in machine.start_values().items():
        if isinstance(value, int):
            fmu.setInteger([vr[name]], [int(value)])
        else:
            fmu.setReal([vr[name]], [value])
    fmu.enterInitializationMode()
    fmu.setReal(
        [vr["crank.angle"], vr["crank.speed"], vr["crank.acceleration"]], [theta, omega, eps]
    )
    fmu.exitInitializationMode()


def outputs(fmu, vr):
    return dict(zip(OUTPUTS, fmu.getReal([vr[n] for n in OUTPUTS])))


def assert_matches(got, machine: Machine, theta, omega, eps=0.0, f_ext=0.0, rtol=1e-9):
    ref, sc = machine.outputs(theta, omega, eps, f_ext), machine.scales(omega, eps, f_ext)
    for n in OUTPUTS:
        assert abs(got[n] - ref[n]) <= rtol * sc[n], f"{n}: FMU {got[n]!r}, reference {ref[n]!r}"


def names_value(msg: str, name: str, value: float) -> bool:
    """The message names the variable and, right after it, the value ("name = value", "name: value",
    ...): 0.15 as 0.15, NaN as nan, -inf as -inf (not the "-inf" of an interval when +inf is meant)."""
    token = {"nan": "nan", "inf": "(?<!-)inf", "-inf": "-inf"}.get(repr(value).lower())
    if token is None:
        token = re.escape(f"{value:g}") + r"(?![0-9])"
    return re.search(re.escape(name) + r"[^a-zA-Z0-9]{1,5}" + token, msg, re.IGNORECASE) is not None


def close(fmu):
    try:
        fmu.terminate()
    except FMICallException:
        pass
    fmu.freeInstance()


# ---------------------------------------------------------------- parameters rejected at init


@pytest.mark.parametrize(
    "rod_length,offset",
    [
        (0.15, 0.0),  # l < r: the crank cannot turn round
        (0.2, 0.0),  # l = r: assembly needs l > r + |e| strictly (docs/model.md §3.1)
        (0.25, 0.05),  # l = r + |e| with an offset
        (0.0, 0.0),  # non-positive: outside the declared range (0, inf)
        (-1.19, 0.0),
    ],
)
def test_bad_rod_length_rejected_at_exit_initialization(
    model_description, unzipdir, vr, rod_length, offset
):
    fmu, log = new_slave(model_description, unzipdir)
    try:
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        # Compared below with the frictionless reference: the guide model is off.
        fmu.setInteger([vr[f"support_{x}.kind"] for x in "ABC"], [0, 0, 0])
        fmu.setReal([vr["geometry.rod_length"], vr["geometry.slider_offset"]], [rod_length, offset])
        with pytest.raises(FMICallException) as exc:
            fmu.exitInitializationMode()
        assert exc.value.status == fmi2Error
        errors = log.messages(fmi2Error)
        assert errors, "an error must reach the logger even with logging off"
        msg = errors[-1]
        assert names_value(msg, "geometry.rod_length", rod_length), msg
        # The instance stays in initialization mode: correct the value and go on.
        fmu.setReal([vr["geometry.rod_length"], vr["geometry.slider_offset"]], [1.19, offset])
        fmu.exitInitializationMode()
        fmu.doStep(0.0, 0.01)
        assert_matches(outputs(fmu, vr), Machine(e=offset), OMEGA * 0.01, OMEGA)
    finally:
        close(fmu)


def test_other_out_of_range_parameters_name_variable_and_value(model_description, unzipdir, vr):
    for name, bad in [
        ("geometry.crank_radius", -0.2),
        ("mass.reciprocating", -5.0),
        ("guide.velocity_scale", 0.0),
        ("crank.angle_offset", float("inf")),
    ]:
        fmu, log = new_slave(model_description, unzipdir)
        try:
            fmu.setupExperiment(startTime=0.0)
            fmu.enterInitializationMode()
            try:
                fmu.setReal([vr[name]], [bad])
            except FMICallException:
                pass  # rejecting it at once is fine too
            else:
                with pytest.raises(FMICallException):
                    fmu.exitInitializationMode()
            msg = log.messages(fmi2Error)[-1]
            assert names_value(msg, name, bad), msg
        finally:
            fmu.freeInstance()
    fmu, log = new_slave(model_description, unzipdir)
    try:
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        fmu.setInteger([vr["load.profile"]], [7])
        with pytest.raises(FMICallException):
            fmu.exitInitializationMode()
        assert "load.profile" in log.messages(fmi2Error)[-1]
    finally:
        fmu.freeInstance()


# ---------------------------------------------------------------- bad inputs while stepping


@pytest.mark.parametrize("bad", [float("nan"), float("inf"), float("-inf")])
@pytest.mark.parametrize(
    "name", ["crank.angle", "crank.speed", "crank.acceleration", "link.external_force"]
)
def test_non_finite_input_rejected_and_fmu_keeps_working(
    model_description, unzipdir, vr, name, bad
):
    m = Machine(e=0.02)
    fmu, log = new_slave(model_description, unzipdir)
    try:
        start(fmu, vr, m, theta=0.3)
        fmu.doStep(0.0, 0.01)
        theta = 0.3 + OMEGA * 0.01
        before = outputs(fmu, vr)
        assert_matches(before, m, theta, OMEGA)
        with pytest.raises(FMICallException) as exc:
            fmu.setReal([vr[name]], [bad])
        assert exc.value.status == fmi2Error
        msg = log.messages(fmi2Error)[-1]
        assert names_value(msg, name, bad), msg
        # Nothing changed: the input keeps its previous value, outputs are those before the call.
        assert outputs(fmu, vr) == before
        if name == "crank.angle":
            assert fmu.getReal([vr[name]]) == [0.3]  # the value last set (the input itself)
        # Stepping goes on from where it was, with the previous inputs.
        fmu.doStep(0.01, 0.01)
        assert_matches(outputs(fmu, vr), m, theta + OMEGA * 0.01, OMEGA)
        # And a good value is accepted again.
        fmu.setReal([vr["crank.angle"]], [1.0])
        assert_matches(outputs(fmu, vr), m, 1.0, OMEGA)
    finally:
        close(fmu)


def test_rejected_multi_value_set_changes_nothing(model_description, unzipdir, vr):
    """fmi2SetReal with a good and a bad value: the good one is not applied either."""
    m = Machine()
    fmu, log = new_slave(model_description, unzipdir)
    try:
        start(fmu, vr, m, theta=0.5)
        with pytest.raises(FMICallException):
            fmu.setReal([vr["crank.angle"], vr["crank.speed"]], [2.0, float("nan")])
        assert fmu.getReal([vr["crank.angle"], vr["crank.speed"]]) == [0.5, OMEGA]
        assert_matches(outputs(fmu, vr), m, 0.5, OMEGA)
    finally:
        close(fmu)


def test_direct_feedthrough_without_step(model_description, unzipdir, vr):
    """docs/model.md §2: outputs reflect inputs set since the last step (GetReal after SetReal)."""
    m = Machine(e=-0.03, angle_offset=0.1, load_mean=500.0)
    fmu, log = new_slave(model_description, unzipdir)
    try:
        start(fmu, vr, m)
        assert_matches(outputs(fmu, vr), m, 0.0, OMEGA)
        for theta, w, eps, f in [
            (1.1, 4.0, 0.0, 0.0),
            (2.5, -3.0, 7.0, 1.0e4),
            (-4.0, 12.0, -1.0, -2e3),
        ]:
            fmu.setReal(
                [
                    vr["crank.angle"],
                    vr["crank.speed"],
                    vr["crank.acceleration"],
                    vr["link.external_force"],
                ],
                [theta, w, eps, f],
            )
            assert_matches(outputs(fmu, vr), m, theta, w, eps, f)
    finally:
        close(fmu)


def test_illegal_calls_are_errors_not_crashes(model_description, unzipdir, vr):
    fmu, log = new_slave(model_description, unzipdir)
    try:
        with pytest.raises(FMICallException):
            fmu.doStep(0.0, 0.01)  # before initialization
        assert "fmi2DoStep" in log.messages(fmi2Error)[-1]
        start(fmu, vr, Machine())
        with pytest.raises(FMICallException):
            fmu.doStep(0.0, 0.0)  # non-positive step
        with pytest.raises(FMICallException):
            fmu.doStep(0.5, 0.01)  # not the FMU's time
        with pytest.raises(FMICallException):
            fmu.setReal([vr["suspension.position"]], [1.0])  # an output
        with pytest.raises(FMICallException):
            fmu.setReal([vr["geometry.rod_length"]], [2.0])  # fixed parameter after init
        with pytest.raises(FMICallException):
            fmu.getReal([10_000])  # unknown value reference
        fmu.doStep(0.0, 0.01)
        assert_matches(outputs(fmu, vr), Machine(), OMEGA * 0.01, OMEGA)
    finally:
        close(fmu)


def test_fmu_state_roll_back_and_serialize(model_description, unzipdir, vr):
    m = Machine()
    fmu, log = new_slave(model_description, unzipdir)
    try:
        start(fmu, vr, m, theta=0.2, eps=0.5)
        fmu.doStep(0.0, 0.1)
        state = fmu.getFMUstate()
        fmu.doStep(0.1, 0.1)
        first = outputs(fmu, vr)
        fmu.setFMUstate(state)
        fmu.doStep(0.1, 0.1)
        assert outputs(fmu, vr) == first
        blob = fmu.serializeFMUstate(state)
        fmu.freeFMUstate(state)
        fmu.doStep(0.2, 0.3)
        state2 = fmu.deSerializeFMUstate(blob)
        fmu.setFMUstate(state2)
        fmu.freeFMUstate(state2)
        fmu.doStep(0.1, 0.1)
        assert outputs(fmu, vr) == first
        # θ(0.2) = 0.2 + 0.2 ω + 0.5·0.2²/2, ω(0.2) = ω + 0.1
        assert_matches(first, m, 0.2 + OMEGA * 0.2 + 0.25 * 0.04, OMEGA + 0.1, 0.5)
        # A corrupted byte string is rejected, not trusted.
        bad = bytearray(blob)
        bad[len(bad) // 2] ^= 0xFF
        with pytest.raises(FMICallException):
            fmu.deSerializeFMUstate(bytes(bad))
        fmu.doStep(0.2, 0.1)
    finally:
        close(fmu)


# ---------------------------------------------------------------- instances, names, resources


def test_multiple_instances_in_one_process_are_independent(model_description, unzipdir, vr):
    machines = [Machine(), Machine(r=0.1, l=0.45, e=0.02, m=80.0), Machine(angle_offset=1.0)]
    slaves = [new_slave(model_description, unzipdir, name=f"pump {i}")[0] for i in range(3)]
    try:
        for i, (fmu, m) in enumerate(zip(slaves, machines)):
            start(fmu, vr, m, theta=0.1 * i, omega=3.0 + i)
        t = 0.0
        for _ in range(20):
            for fmu in slaves:  # interleaved
                fmu.doStep(t, 0.05)
            t += 0.05
            for i, (fmu, m) in enumerate(zip(slaves, machines)):
                assert_matches(outputs(fmu, vr), m, 0.1 * i + (3.0 + i) * t, 3.0 + i)
        # Freeing one leaves the others working.
        close(slaves.pop(0))
        machines.pop(0)
        for fmu in slaves:
            fmu.doStep(t, 0.05)
        for i, (fmu, m) in enumerate(zip(slaves, machines), start=1):
            assert_matches(outputs(fmu, vr), m, 0.1 * i + (3.0 + i) * (t + 0.05), 3.0 + i)
    finally:
        for fmu in slaves:
            close(fmu)


def test_instance_name_with_spaces_and_component_environment(model_description, unzipdir, vr):
    """The compliance checker's case: a name with spaces, loggingOn, a non-NULL
    componentEnvironment that every logger call must return unchanged."""
    name = "Mud pump #2 (crank drive) – UNB-600A"
    env = 0x5EED1234
    fmu, log = new_slave(model_description, unzipdir, name=name, logging_on=True, environment=env)
    try:
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        fmu.setReal([vr["geometry.rod_length"]], [0.1])
        with pytest.raises(FMICallException):
            fmu.exitInitializationMode()
        assert log.lines, "nothing was logged"
        for e, n, *_ in log.lines:
            assert e == env
            assert n == name
    finally:
        fmu.freeInstance()


@pytest.mark.parametrize(
    "form",
    ["file:///{p}", "file:///{p}/", "file:/{p}", "file://localhost/{p}", "file:///{q}", "none"],
)
def test_resource_location_forms(model_description, unzipdir, vr, tmp_path, form):
    """docs/fmi-interface.md: file:///, file:/, file://host/, percent-encoding, a trailing slash and NULL are all
    accepted. With loggingOn the FMU reports the folder it resolved."""
    res = tmp_path / "a dir" / "resources"
    res.mkdir(parents=True)
    posix = str(res).lstrip("/")
    location = (
        None
        if form == "none"
        else form.format(p=posix, q=pathlib.Path(res).as_uri()[len("file:///") :])
    )
    if form == "file:///{q}":
        assert "%20" in location
    log = Log()
    fmu = FMU2Slave(
        guid=model_description.guid,
        unzipDirectory=unzipdir,
        modelIdentifier="ReciprocatingDrive",
        instanceName="res test",
    )
    fmu.callbacks = log.callbacks
    fmu.component = fmu.fmi2Instantiate(
        b"res test",
        fmi2CoSimulation,
        model_description.guid.encode(),
        None if location is None else location.encode(),
        ctypes.byref(log.callbacks),
        0,
        1,
    )
    assert fmu.component, f"fmi2Instantiate refused {location!r}: {log.text()}"
    try:
        if location is not None:
            assert any(str(res) in msg for msg in log.messages()), log.text()
        start(fmu, vr, Machine())
        fmu.doStep(0.0, 0.01)
        assert_matches(outputs(fmu, vr), Machine(), OMEGA * 0.01, OMEGA)
    finally:
        close(fmu)


def test_instantiate_refuses_wrong_guid_and_type_with_a_message(model_description, unzipdir):
    log = Log()
    fmu = FMU2Slave(
        guid=model_description.guid,
        unzipDirectory=unzipdir,
        modelIdentifier="ReciprocatingDrive",
        instanceName="x",
    )
    try:
        loc = pathlib.Path(unzipdir, "resources").as_uri().encode()
        c = fmu.fmi2Instantiate(
            b"x", fmi2CoSimulation, b"{not-the-guid}", loc, ctypes.byref(log.callbacks), 0, 0
        )
        assert not c and "GUID" in log.text()
        # An fmuType that is neither Model Exchange (0) nor co-simulation (1).
        c = fmu.fmi2Instantiate(
            b"x", 7, model_description.guid.encode(), loc, ctypes.byref(log.callbacks), 0, 0
        )
        assert not c and log.messages(fmi2Error)
        assert "fmuType 7 is not supported" in log.text()
        c = fmu.fmi2Instantiate(
            b"",
            fmi2CoSimulation,
            model_description.guid.encode(),
            loc,
            ctypes.byref(log.callbacks),
            0,
            0,
        )
        assert not c
    finally:
        fmu.freeLibrary()


# ---------------------------------------------------------------- a freed instance

# Driven in a child process: on a binary that reads the freed instance the child dies (SIGSEGV)
# or returns what the freed memory happens to hold, and the test fails either way.
_FREED_CHILD = r"""
import ctypes as C, json, re, sys

so, header, guid, kind = sys.argv[1:5]
lib = C.CDLL(so)
# Every function of the standard's header (fmpy ships the official fmi2Functions.h).
names = re.findall(r"FMI2_Export\s+fmi2\w+TYPE\s+(fmi2\w+)\s*;", open(header).read())
V = C.c_void_p
# The logger with the one variadic argument the FMU passes (its format is always "%s").
LOG = C.CFUNCTYPE(None, V, C.c_char_p, C.c_int, C.c_char_p, C.c_char_p, C.c_char_p)
messages = []
logger = LOG(lambda env, name, status, category, fmt, message: messages.append(message.decode()))


class Callbacks(C.Structure):
    _fields_ = [("logger", V), ("allocateMemory", V), ("freeMemory", V), ("stepFinished", V),
                ("componentEnvironment", V)]


callbacks = Callbacks(C.cast(logger, V).value, None, None, None, None)
lib.fmi2Instantiate.restype = V


def instantiate(name):
    return lib.fmi2Instantiate(name, C.c_int(0 if kind == "me" else 1), guid.encode(), None,
                               C.byref(callbacks), 0, 1)


inst = instantiate(b"freed")
assert inst, messages
lib.fmi2FreeInstance.restype = None
lib.fmi2FreeInstance(V(inst))
logged = len(messages)
status = {}
for n in names:
    if n in ("fmi2GetTypesPlatform", "fmi2GetVersion", "fmi2Instantiate"):
        continue  # no instance argument
    f = getattr(lib, n)
    if n == "fmi2FreeInstance":
        f(V(inst))  # a second free: void, it must simply return
        status[n] = None
        continue
    f.restype = C.c_int
    # The instance, then NULL for every other argument: a freed instance is refused first.
    status[n] = f(V(inst), *[V(None)] * 7)
# The freed instance's logger is not called any more (the importer may have released it).
after = messages[logged:]
# Another instance is unharmed by all this.
live = instantiate(b"live")
for n in ("fmi2SetupExperiment", "fmi2EnterInitializationMode", "fmi2ExitInitializationMode"):
    getattr(lib, n).restype = C.c_int
ok = [lib.fmi2SetupExperiment(V(live), 0, C.c_double(0.0), C.c_double(0.0), 0, C.c_double(0.0)),
      lib.fmi2EnterInitializationMode(V(live)),
      lib.fmi2ExitInitializationMode(V(live))]
lib.fmi2FreeInstance(V(live))
print(json.dumps({"names": names, "status": status, "after": after, "ok": ok}))
"""


@pytest.mark.parametrize("kind", ["cs", "me"])
@pytest.mark.parametrize("model", ["ReciprocatingDrive", "DriveTrain"])
def test_a_freed_instance_is_refused_by_every_function(fmu_path, tmp_path, model, kind):
    """After fmi2FreeInstance, a second fmi2FreeInstance and every other function of the
    standard's fmi2Functions.h that takes an instance return fmi2Error (3) without touching freed
    memory: the process lives on, another instance still works, the freed instance's logger is not
    called again, and one line on standard error names the first function called on it
    (docs/fmi-interface.md "A freed instance")."""
    path = pathlib.Path(fmu_path).parent / f"{model}.fmu"
    r, stderr = run_freed_child(
        path, "linux64", model, "fmi2Functions.h", _FREED_CHILD, kind, tmp_path
    )
    assert len(r["names"]) == 44, len(r["names"])  # FMI 2.0: 44 functions
    refused = {n: s for n, s in r["status"].items() if s is not None}
    # 44 less the three without an instance and fmi2FreeInstance (void).
    assert len(refused) == 40 and all(s == fmi2Error for s in refused.values()), {
        n: s for n, s in refused.items() if s != fmi2Error
    }
    assert "fmi2FreeInstance" in r["status"]
    assert r["after"] == [] and r["ok"] == [0, 0, 0], r
    lines = stderr.strip().splitlines()
    first = next(iter(r["status"]))
    assert len(lines) == 1, lines
    assert (
        lines[0].startswith(f"{model}: {first}: instance ")
        and "was freed by fmi2FreeInstance; no call is allowed on it (fmi2Error)" in lines[0]
    ), lines
