"""The FMI 3.0 co-simulation FMUs (target/fmu/<id>-fmi3.fmu, docs/fmi-interface.md "FMI 3.0"):
generated from the same variable table as the FMI 2.0 ones and run by the same instance core, so
they must say the same things about every variable and give the same numbers.

* fmpy's validator reports nothing; every variable has the FMI 2.0 description's name, value
  reference, causality, variability, unit, start and description, and the output dependencies
  are the same;
* fmpy simulates both standards to bit-identical results (same binary code path; any difference
  is a fault of the 3.0 layer), for a rigid machine, an elastic rod (kvo630, integrated) and the
  drive train (integrated);
* FMU state get/set and serialize/deserialize repeat a run bit for bit, and a state serialized
  by the FMI 2.0 FMU continues in the FMI 3.0 one identically;
* the x86_64-windows DLL under wine (tests/win64/host3.c) agrees with the x86_64-linux binary to
  the tolerances of test_win64.py (libm differences), and the Linux host of 3.0 prints exactly
  what the 2.0 host prints;
* the aarch64-linux binary (cross-compiled) run under qemu-user agrees with the x86_64 one (to
  the win64 tolerances; measured bit-identical, 2026-11-26, qemu-aarch64 7.2 on x86_64);
* errors through 3.0 name the 3.0 function.
"""

from __future__ import annotations

import ctypes
import os
import pathlib
import shutil
import subprocess
import sys
import zipfile

import numpy as np
import pytest
from conftest import ROOT
from freed_child import run_freed_child
from reciprocating_drive import preset_values

MODELS = ["ReciprocatingDrive", "DriveTrain"]


def fmu2(fmu_path, model):
    return pathlib.Path(fmu_path).parent / f"{model}.fmu"


def fmu3(fmu_path, model):
    p = pathlib.Path(fmu_path).parent / f"{model}-fmi3.fmu"
    assert p.is_file(), f"scripts/build-fmu.sh builds {p.name}"
    return p


@pytest.mark.parametrize("model", MODELS)
def test_fmpy_validate_reports_nothing(fmu_path, model):
    from fmpy.validation import validate_fmu

    problems = validate_fmu(str(fmu3(fmu_path, model)))
    assert problems == [], "\n".join(problems)
    # The command line as a user runs it (fmpy's console script is fmpy.cli:main).
    p = subprocess.run(
        [sys.executable, "-c", "import sys; from fmpy.cli import main; sys.exit(main())"]
        + ["validate", str(fmu3(fmu_path, model))],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert p.returncode == 0 and "No problems found." in p.stdout, p.stdout + p.stderr


@pytest.mark.parametrize("model", MODELS)
def test_same_variables_as_fmi2(fmu_path, model):
    from fmpy import read_model_description

    md2 = read_model_description(str(fmu2(fmu_path, model)))
    md3 = read_model_description(str(fmu3(fmu_path, model)))
    assert md3.fmiVersion == "3.0" and md3.coSimulation.modelIdentifier == model
    # Model Exchange: the drive train with its states θ and ω, the pump's rigid mechanisms.
    assert md3.modelExchange is not None and md3.modelExchange.modelIdentifier == model
    assert md3.coSimulation.canGetAndSetFMUstate and md3.coSimulation.canSerializeFMUstate
    # FMI 3.0's independent variable comes first, with the value reference after the table's,
    # then the state derivatives (Model Exchange).
    time = md3.modelVariables[0]
    assert (time.name, time.causality, time.unit) == ("time", "independent", "s")
    ders = [v for v in md3.modelVariables if v.valueReference > time.valueReference]
    assert [v.name for v in ders] == (
        ["der(crank.angle)", "der(crank.speed)"]
        if model == "DriveTrain"
        else ["der(rod.cage_angle)", "der(rod.cage_rate)", "rod.cage_angle", "rod.cage_rate"]
    )
    # The FMI 2.0 file (Model Exchange beside co-simulation) has the same derivatives, last.
    assert time.valueReference == len(md2.modelVariables) - len(ders)
    assert len(md2.modelVariables) + 1 == len(md3.modelVariables)
    types = {"Real": "Float64", "Integer": "Int32", "Boolean": "Boolean"}
    for a, b in zip(md2.modelVariables, md3.modelVariables[1:]):
        assert (a.name, a.valueReference, a.causality, a.description) == (
            b.name,
            b.valueReference,
            b.causality,
            b.description,
        )
        assert types[a.type] == b.type, a.name
        assert (a.unit, a.displayUnit, a.min, a.max, a.start) == (
            b.unit,
            b.displayUnit,
            b.min,
            b.max,
            b.start,
        ), a.name
        # Continuous is for Float variables only in FMI 3.0.
        assert a.variability == b.variability or (
            a.variability == "continuous" and b.variability == "discrete" and b.type != "Float64"
        ), a.name
    # Both list the inputs and the continuous states an output or a state derivative depends on
    # (Model Exchange: the knowns are the inputs and the states).
    deps2 = {o.variable.name: sorted(d.name for d in o.dependencies) for o in md2.outputs}
    deps3 = {o.variable.name: sorted(d.name for d in o.dependencies) for o in md3.outputs}
    assert deps2 == deps3
    der2 = {d.variable.name: sorted(x.name for x in d.dependencies or []) for d in md2.derivatives}
    der3 = {d.variable.name: sorted(x.name for x in d.dependencies or []) for d in md3.derivatives}
    assert der2 == der3 and len(der2) == 2
    init2 = sorted(u.variable.name for u in md2.initialUnknowns)
    # Both list the state derivatives (Model Exchange) as initial unknowns.
    init3 = sorted(u.variable.name for u in md3.initialUnknowns)
    assert init2 == init3


def crank_input(stop, h, omega):
    """crank.angle = ω·t and crank.speed = ω at every communication point (fmpy's input)."""
    t = np.arange(0.0, stop + h / 2, h)
    sig = np.zeros(len(t), dtype=[("time", float), ("crank.angle", float), ("crank.speed", float)])
    sig["time"], sig["crank.angle"], sig["crank.speed"] = t, omega * t, omega
    return sig


CASES = [
    ("ReciprocatingDrive", "default", 1.0, 1e-3),
    ("ReciprocatingDrive", "kvo630", 0.05, 2e-4),
    ("DriveTrain", "run-up", 1.0, 1e-3),
]


@pytest.mark.parametrize("model,machine,stop,h", CASES)
def test_fmpy_simulates_fmi3_like_fmi2_bit_for_bit(fmu_path, model, machine, stop, h):
    from fmpy import read_model_description, simulate_fmu

    md = read_model_description(str(fmu2(fmu_path, model)))
    outputs = [v.name for v in md.modelVariables if v.causality == "output"]
    if model == "DriveTrain":
        start = {"crank.speed_start": 0.0, "load.torque": 600.0}
        inp = None
    else:
        start = {k: v for k, v in preset_values(machine).items() if k != "crank.angle"}
        omega = float(
            start.get(
                "crank.speed", next(v.start for v in md.modelVariables if v.name == "crank.speed")
            )
        )
        start.pop("crank.speed", None)
        inp = crank_input(stop, h, omega)
    runs = []
    for path in (fmu2(fmu_path, model), fmu3(fmu_path, model)):
        runs.append(
            simulate_fmu(
                str(path),
                stop_time=stop,
                output_interval=h,
                start_values=start,
                input=inp,
                output=outputs,
                fmi_type="CoSimulation",
            )
        )
    r2, r3 = runs
    assert len(r2) == len(r3) > stop / h / 2
    for name in ["time", *outputs]:
        assert np.array_equal(r2[name], r3[name]), f"{name} differs between FMI 2.0 and 3.0"
    # Not a trivial run: the first output moves.
    assert np.ptp(r3[outputs[0]]) > 0 or np.ptp(r3[outputs[1]]) > 0


def _slave3(path, tmp_path, name="x"):
    from fmpy import extract, read_model_description
    from fmpy.fmi3 import FMU3Slave

    md = read_model_description(str(path))
    d = extract(str(path), unzipdir=str(tmp_path / name))
    s = FMU3Slave(
        guid=md.guid,
        unzipDirectory=d,
        modelIdentifier=md.coSimulation.modelIdentifier,
        instanceName=name,
    )
    return md, s


def test_fmu_state_get_set_serialize_repeat_a_run(fmu_path, tmp_path):
    """kvo630 (elastic rod: states, integrator memory): save at t = 10 ms, run 10 ms more, restore
    the state (directly and through its serialized bytes) and run again: bit-identical."""
    md, s = _slave3(fmu3(fmu_path, "ReciprocatingDrive"), tmp_path)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    outs = [v.valueReference for v in md.modelVariables if v.causality == "output"]
    params = {k: v for k, v in preset_values("kvo630").items() if k != "crank.angle"}
    h = 2e-4
    s.instantiate()
    s.enterInitializationMode()
    for k, v in params.items():
        var = next(x for x in md.modelVariables if x.name == k)
        if var.type == "Float64":
            s.setFloat64([vr[k]], [float(v)])
        elif var.type == "Int32":
            s.setInt32([vr[k]], [int(v)])
        else:
            s.setBoolean([vr[k]], [bool(v)])
    s.exitInitializationMode()
    omega = s.getFloat64([vr["crank.speed"]])[0]

    def run(t0, n):
        rows = []
        for k in range(n):
            t = t0 + k * h
            s.setFloat64([vr["crank.angle"], vr["crank.speed"]], [omega * t, omega])
            s.doStep(t, h)
            rows.append(s.getFloat64(outs))
        return np.array(rows)

    run(0.0, 50)
    t1 = 50 * h
    state = s.getFMUState()
    blob = s.serializeFMUState(state)
    first = run(t1, 50)
    s.setFMUState(state)
    again = run(t1, 50)
    s.freeFMUState(state)
    restored = s.deserializeFMUState(blob)
    s.setFMUState(restored)
    third = run(t1, 50)
    s.freeFMUState(restored)
    # The independent variable reads the FMU's time.
    assert s.getFloat64([vr["time"]])[0] == t1 + 49 * h + h
    s.terminate()
    s.freeInstance()
    assert np.ptp(first[:, 0]) > 0
    assert np.array_equal(first, again)
    assert np.array_equal(first, third)


def test_state_serialized_by_fmi2_continues_in_fmi3(fmu_path, tmp_path):
    """One instance core, one state format: the DriveTrain's state after 0.5 s of run-up,
    serialized through FMI 2.0, continues through FMI 3.0 exactly as in FMI 2.0."""
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    p2 = fmu2(fmu_path, "DriveTrain")
    md2 = read_model_description(str(p2))
    vr = {v.name: v.valueReference for v in md2.modelVariables}
    d2 = extract(str(p2), unzipdir=str(tmp_path / "two"))
    s2 = FMU2Slave(guid=md2.guid, unzipDirectory=d2, modelIdentifier="DriveTrain", instanceName="a")
    s2.instantiate()
    s2.setupExperiment(startTime=0.0)
    s2.enterInitializationMode()
    s2.setReal([vr["crank.speed_start"], vr["load.torque"]], [0.0, 600.0])
    s2.exitInitializationMode()
    h = 1e-3
    for k in range(500):
        s2.doStep(k * h, h)
    blob = s2.serializeFMUstate(s2.getFMUstate())
    ref = []
    for k in range(500, 600):
        s2.doStep(k * h, h)
        ref.append(s2.getReal([vr["crank.speed"], vr["motor.torque"]]))
    s2.terminate()
    s2.freeInstance()

    md3, s3 = _slave3(fmu3(fmu_path, "DriveTrain"), tmp_path, "three")
    s3.instantiate()
    s3.setFMUState(s3.deserializeFMUState(blob))
    got = []
    for k in range(500, 600):
        s3.doStep(k * h, h)
        got.append(s3.getFloat64([vr["crank.speed"], vr["motor.torque"]]))
    s3.terminate()
    s3.freeInstance()
    assert np.array_equal(np.array(ref), np.array(got))


def test_errors_name_the_fmi3_function(fmu_path, tmp_path):
    md, s = _slave3(fmu3(fmu_path, "DriveTrain"), tmp_path)
    messages = []

    def log(env, status, category, message):
        messages.append((status, message.decode()))

    s.instantiate(logMessage=log)
    # fmpy raises on an error status; call the C functions directly to see status and message.
    flags = [ctypes.c_bool() for _ in range(3)]
    last = ctypes.c_double()
    status = s.dll.fmi3DoStep(
        s.component,
        ctypes.c_double(0.0),
        ctypes.c_double(1e-3),
        ctypes.c_bool(True),
        *[ctypes.byref(f) for f in flags],
        ctypes.byref(last),
    )
    assert status == 3  # fmi3Error
    status = s.dll.fmi3EnterInitializationMode(
        s.component,
        ctypes.c_bool(True),
        ctypes.c_double(2.0),
        ctypes.c_double(0.0),
        ctypes.c_bool(False),
        ctypes.c_double(0.0),
    )
    assert status == 3
    s.freeInstance()
    text = "\n".join(m for _, m in messages)
    assert "fmi3DoStep: illegal call sequence" in text, text
    assert "fmi3EnterInitializationMode: tolerance = 2" in text, text
    assert "fmi2" not in text, text


def test_wrong_token_is_refused_with_a_message(fmu_path, tmp_path):
    from fmpy import extract
    from fmpy.fmi3 import FMU3Slave

    p = fmu3(fmu_path, "DriveTrain")
    d = extract(str(p), unzipdir=str(tmp_path / "t"))
    messages = []
    s = FMU3Slave(
        guid="{not-the-token}", unzipDirectory=d, modelIdentifier="DriveTrain", instanceName="x"
    )
    with pytest.raises(Exception, match="Failed to instantiate"):
        s.instantiate(logMessage=lambda env, st, cat, msg: messages.append(msg.decode()))
    assert any("instantiationToken" in m and "{not-the-token}" in m for m in messages), messages


# ------------------------------------------------------------------------------ hosts and wine

win64 = pytest.mark.skipif(os.environ.get("RD_WIN64") == "0", reason="RD_WIN64=0: no win64 build")


@pytest.fixture(scope="module")
def hosts(tmp_path_factory):
    d = tmp_path_factory.mktemp("hosts3")
    for src, exe in (("host.c", "host"), ("host3.c", "host3")):
        subprocess.run(["gcc", "-O2", "-o", d / exe, ROOT / "tests" / "win64" / src, "-ldl"])
    if os.environ.get("RD_WIN64") != "0":
        subprocess.run(
            ["x86_64-w64-mingw32-gcc", "-O2", "-o", d / "host3.exe", ROOT / "tests/win64/host3.c"],
            check=True,
        )
    return d


def run_host(cmd, **env):
    p = subprocess.run(
        cmd,
        capture_output=True,
        text=True,
        timeout=600,
        env={**os.environ, "WINEDEBUG": "-all", **env},
    )
    assert p.returncode == 0, p.stderr[-2000:]
    return np.array([[float(x) for x in line.split(",")] for line in p.stdout.split()])


def host_args(md, steps, h, params):
    vr = {v.name: v for v in md.modelVariables}
    outs = [v for v in md.modelVariables if v.causality == "output"]
    args = [
        md.guid,
        str(steps),
        repr(h),
        f"{vr['crank.angle'].valueReference},{vr['crank.speed'].valueReference}",
        ",".join(str(v.valueReference) for v in outs),
    ]
    for name, value in params.items():
        v = vr[name]
        kind = {"Integer": ":i", "Int32": ":i", "Boolean": ":b"}.get(v.type, "")
        args.append(f"{v.valueReference}{kind}={int(value) if kind else float(value)!r}")
    return args, [v.name for v in outs]


@pytest.mark.parametrize(
    "machine,steps,h,tol", [("default", 2000, 1e-3, 1e-13), ("kvo630", 1000, 2e-4, 1e-9)]
)
def test_hosts_fmi3_linux_equals_fmi2_and_win64_under_wine(
    fmu_path, hosts, tmp_path, machine, steps, h, tol
):
    from fmpy import read_model_description

    params = {k: v for k, v in preset_values(machine).items() if k != "crank.angle"}
    d2, d3 = tmp_path / "two", tmp_path / "three"
    zipfile.ZipFile(fmu2(fmu_path, "ReciprocatingDrive")).extractall(d2)
    zipfile.ZipFile(fmu3(fmu_path, "ReciprocatingDrive")).extractall(d3)
    md2 = read_model_description(str(d2 / "modelDescription.xml"))
    md3 = read_model_description(str(d3 / "modelDescription.xml"))
    a2, names = host_args(md2, steps, h, params)
    a3, _ = host_args(md3, steps, h, params)
    lin2 = run_host(
        [
            str(hosts / "host"),
            str(d2 / "binaries/linux64/ReciprocatingDrive.so"),
            "ReciprocatingDrive",
            *a2,
        ]
    )
    lin3 = run_host(
        [
            str(hosts / "host3"),
            str(d3 / "binaries/x86_64-linux/ReciprocatingDrive.so"),
            "ReciprocatingDrive",
            *a3,
        ]
    )
    assert lin2.shape == lin3.shape == (steps + 1, len(names))
    assert np.array_equal(lin2, lin3), "FMI 3.0 and FMI 2.0 give different numbers on Linux"
    if os.environ.get("RD_WIN64") == "0":
        return
    dll = d3 / "binaries" / "x86_64-windows" / "ReciprocatingDrive.dll"
    assert dll.is_file(), "the FMI 3.0 FMU has binaries/x86_64-windows/ReciprocatingDrive.dll"
    shutil.copy(hosts / "host3.exe", d3 / "host3.exe")
    win3 = run_host(
        [
            "wine",
            str(d3 / "host3.exe"),
            "Z:" + str(dll).replace("/", "\\"),
            "ReciprocatingDrive",
            *a3,
        ]
    )
    scale = np.maximum(np.max(np.abs(lin3), axis=0), 1e-300)
    rel = np.max(np.abs(win3 - lin3), axis=0) / scale
    worst = int(np.argmax(rel))
    print(f"{machine}: worst {names[worst]} {rel[worst]:.3g} of its scale")
    assert rel[worst] <= tol, f"{names[worst]} differs by {rel[worst]:.3g} of its scale"


@win64
@pytest.mark.parametrize("model", MODELS)
def test_win64_dll_exports_every_fmi3_function(fmu_path, tmp_path, model):
    with zipfile.ZipFile(fmu3(fmu_path, model)) as z:
        z.extractall(tmp_path)
    dll = tmp_path / "binaries" / "x86_64-windows" / f"{model}.dll"
    dump = subprocess.run(
        ["x86_64-w64-mingw32-objdump", "-p", dll], capture_output=True, text=True, check=True
    ).stdout
    header = pathlib.Path(os.environ.get("CARGO_HOME", pathlib.Path.home() / ".cargo")).glob(
        "registry/src/*/fmi-sys-0.6.0/fmi-standard3/headers/fmi3FunctionTypes.h"
    )
    header = next(header, None)
    if header is None:
        pytest.skip("fmi-sys sources (the FMI 3.0 headers) not in the cargo registry")
    import re

    names = set(re.findall(r"typedef\s+\w+\s+(fmi3\w+)TYPE\s*\(", header.read_text()))
    assert len(names) > 70
    missing = sorted(n for n in names if f" {n}\n" not in dump and not dump.count(n))
    assert not missing, f"{model}.dll does not export {missing}"


def test_resource_path_is_the_native_folder(fmu_path, tmp_path):
    """FMI 3.0 passes resources/ as a native path (FMI 2.0: a file URI); the instance finds it."""
    md, s = _slave3(fmu3(fmu_path, "ReciprocatingDrive"), tmp_path)
    messages = []
    s.instantiate(loggingOn=True, logMessage=lambda e, st, c, m: messages.append(m.decode()))
    s.freeInstance()
    expected = str(tmp_path / "x" / "resources")
    assert any(f'resources: Some("{expected}")' in m for m in messages), messages


# ------------------------------------------------------------------------------ aarch64-linux

aarch64 = pytest.mark.skipif(
    os.environ.get("RD_AARCH64") == "0", reason="RD_AARCH64=0: no aarch64 build"
)


def qemu_aarch64():
    """qemu-user (scripts/lib/aarch64.sh installs it; scripts/test.sh calls it)."""
    q = shutil.which("qemu-aarch64") or shutil.which("qemu-aarch64-static")
    if q is None or not shutil.which("aarch64-linux-gnu-gcc"):
        msg = "qemu-aarch64 or aarch64-linux-gnu-gcc missing: source scripts/lib/aarch64.sh"
        if os.environ.get("CI") or os.environ.get("RD_REQUIRE_FMU"):
            pytest.fail(msg)
        pytest.skip(msg)
    return q


@aarch64
@pytest.mark.parametrize("model", MODELS)
def test_every_fmi3_fmu_has_an_aarch64_linux_binary(fmu_path, tmp_path, model):
    with zipfile.ZipFile(fmu3(fmu_path, model)) as z:
        z.extractall(tmp_path)
    so = tmp_path / "binaries" / "aarch64-linux" / f"{model}.so"
    assert so.is_file(), f"{model}-fmi3.fmu has no binaries/aarch64-linux/{model}.so"
    head = so.read_bytes()[:20]
    # ELF, 64-bit, little-endian, e_machine = EM_AARCH64 (183).
    assert head[:4] == b"\x7fELF" and head[4] == 2 and head[5] == 1
    assert int.from_bytes(head[18:20], "little") == 183


@aarch64
@pytest.mark.parametrize(
    "machine,steps,h,tol", [("default", 2000, 1e-3, 1e-13), ("kvo630", 1000, 2e-4, 1e-9)]
)
def test_aarch64_under_qemu_matches_x86_64(fmu_path, hosts, tmp_path, machine, steps, h, tol):
    """The aarch64 binary run by host3.c built for aarch64 under qemu-user against the x86_64
    binary run by host3.c: the same tolerances as win64 (another libm, and GCC may fuse a
    multiply-add on aarch64 where x86_64 rounds twice)."""
    from fmpy import read_model_description

    q = qemu_aarch64()
    params = {k: v for k, v in preset_values(machine).items() if k != "crank.angle"}
    d = tmp_path / "three"
    zipfile.ZipFile(fmu3(fmu_path, "ReciprocatingDrive")).extractall(d)
    md = read_model_description(str(d / "modelDescription.xml"))
    args, names = host_args(md, steps, h, params)
    arm_host = tmp_path / "host3-aarch64"
    subprocess.run(
        ["aarch64-linux-gnu-gcc", "-O2", "-o", arm_host, ROOT / "tests/win64/host3.c", "-ldl"],
        check=True,
    )
    lib = "binaries/{}/ReciprocatingDrive.so"
    x86 = run_host(
        [str(hosts / "host3"), str(d / lib.format("x86_64-linux")), "ReciprocatingDrive", *args]
    )
    # qemu-user finds the arm64 C library (libc6-arm64-cross) under this prefix.
    arm = run_host(
        [q, str(arm_host), str(d / lib.format("aarch64-linux")), "ReciprocatingDrive", *args],
        QEMU_LD_PREFIX=os.environ.get("QEMU_LD_PREFIX", "/usr/aarch64-linux-gnu"),
    )
    assert arm.shape == x86.shape == (steps + 1, len(names))
    scale = np.maximum(np.max(np.abs(x86), axis=0), 1e-300)
    rel = np.max(np.abs(arm - x86), axis=0) / scale
    worst = int(np.argmax(rel))
    print(
        f"{machine}: aarch64 bit-identical {bool(np.array_equal(arm, x86))}; "
        f"worst {names[worst]} {rel[worst]:.3g} of its scale"
    )
    assert rel[worst] <= tol, f"{names[worst]} differs by {rel[worst]:.3g} of its scale"


# ------------------------------------------------------------------------------ Model Exchange

J = 50.0 + 23.0**2 * 0.5  # J_c + i²·J_m of the default drive train [kg·m²]


def kloss_acceleration(w, load):
    """(i·T_m(ω) − T_L)/J with Kloss's curve and the default parameters (docs/closed-loop.md),
    written here from the formulas, not from the FMU."""
    i, ws, tb, sb = 23.0, 2 * np.pi * 1500 / 60, 200.0, 0.15
    s = 1 - i * w / ws
    return (i * 2 * tb * s * sb / (s * s + sb * sb) - load) / J


def test_drive_train_model_exchange_cvode_matches_co_simulation(fmu_path):
    """The DriveTrain as Model Exchange (its θ and ω are the continuous states) integrated by
    fmpy's CVODE at rtol 1e-10 against the co-simulation FMU (its own integrator at 1e-8) and
    against scipy's solution of J·ω̇ = i·T_m(ω) − T_L written here: run-up under 600 N·m over 3 s.
    The bound is the co-simulation's: 1e-6 of the synchronous crank speed (test_drive_train.py)."""
    from fmpy import simulate_fmu
    from scipy.integrate import solve_ivp

    start = {"crank.speed_start": 0.0, "load.torque": 600.0}
    stop, h = 3.0, 1e-3
    me = simulate_fmu(
        str(fmu3(fmu_path, "DriveTrain")),
        fmi_type="ModelExchange",
        solver="CVode",
        relative_tolerance=1e-10,
        stop_time=stop,
        output_interval=h,
        start_values=start,
        output=["crank.angle", "crank.speed", "crank.acceleration", "motor.torque"],
    )
    cs = simulate_fmu(
        str(fmu2(fmu_path, "DriveTrain")),
        stop_time=stop,
        output_interval=h,
        start_values=start,
        output=["crank.angle", "crank.speed", "crank.acceleration", "motor.torque"],
    )
    t = me["time"]
    assert np.allclose(t, cs["time"][: len(t)]) and len(t) == len(cs["time"])
    w0 = 2 * np.pi * 1500 / 60 / 23.0
    dw = np.max(np.abs(me["crank.speed"] - cs["crank.speed"]))
    assert dw <= 1e-6 * w0, f"crank speed: ME - CS = {dw:.3g} rad/s"
    da = np.max(np.abs(me["crank.angle"] - cs["crank.angle"]))
    assert da <= 1e-6, f"crank angle: ME - CS = {da:.3g} rad"
    ref = solve_ivp(
        lambda _, y: [y[1], kloss_acceleration(y[1], 600.0)],
        (0, stop),
        [0.0, 0.0],
        method="DOP853",
        rtol=1e-12,
        atol=1e-12,
        t_eval=t,
    ).y
    assert np.max(np.abs(me["crank.speed"] - ref[1])) <= 1e-7 * w0
    # The acceleration output is the state derivative at the recorded state.
    assert np.allclose(
        me["crank.acceleration"],
        kloss_acceleration(me["crank.speed"], 600.0),
        rtol=1e-12,
        atol=1e-12,
    )
    # Not a trivial run: the motor runs up to near its synchronous speed.
    assert 0.8 * w0 < me["crank.speed"][-1] < w0


def test_model_exchange_calls_and_refusals(fmu_path, tmp_path):
    """The Model Exchange calls directly: states in and out, derivatives from the formulas, the
    derivative variables readable, no event indicators; fmi3DoStep refused on an ME instance with a
    message; the pump's elastic rod accepted with its two cage states."""
    from fmpy import extract, read_model_description
    from fmpy.fmi3 import FMU3Model

    p = fmu3(fmu_path, "DriveTrain")
    md = read_model_description(str(p))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    d = extract(str(p), unzipdir=str(tmp_path / "me"))
    m = FMU3Model(guid=md.guid, unzipDirectory=d, modelIdentifier="DriveTrain", instanceName="m")
    messages = []
    m.instantiate(logMessage=lambda e, st, c, msg: messages.append(msg.decode()))
    m.enterInitializationMode()
    m.setFloat64([vr["load.torque"]], [300.0])
    m.exitInitializationMode()
    m.updateDiscreteStates()
    m.enterContinuousTimeMode()
    assert m.getNumberOfContinuousStates() == 2 and m.getNumberOfEventIndicators() == 0
    x = (ctypes.c_double * 2)()
    m.getContinuousStates(x, 2)
    assert list(x) == [
        0.0,
        float(
            md.modelVariables[[v.name for v in md.modelVariables].index("crank.speed_start")].start
        ),
    ]
    m.setTime(0.25)
    m.setContinuousStates((ctypes.c_double * 2)(1.5, 5.0), 2)
    m.getContinuousStates(x, 2)
    assert list(x) == [1.5, 5.0]
    dx = (ctypes.c_double * 2)()
    m.getContinuousStateDerivatives(dx, 2)
    assert dx[0] == 5.0
    assert abs(dx[1] - kloss_acceleration(5.0, 300.0)) <= 1e-13 * abs(dx[1])
    got = m.getFloat64(
        [vr["der(crank.angle)"], vr["der(crank.speed)"], vr["crank.speed"], vr["time"]]
    )
    assert got == [dx[0], dx[1], 5.0, 0.25]
    flags = [ctypes.c_bool() for _ in range(3)]
    last = ctypes.c_double()
    st = m.dll.fmi3DoStep(
        m.component, ctypes.c_double(0.25), ctypes.c_double(1e-3), ctypes.c_bool(True),
        *[ctypes.byref(f) for f in flags], ctypes.byref(last),
    )  # fmt: skip
    assert st == 3
    assert any("fmi3DoStep: an instance for Model Exchange" in msg for msg in messages), messages
    m.terminate()
    m.freeInstance()

    # The pump offers Model Exchange for every machine, an elastic rod (kvo630) with its two cage
    # states (test_model_exchange.py integrates them).
    p = fmu3(fmu_path, "ReciprocatingDrive")
    d = extract(str(p), unzipdir=str(tmp_path / "pump"))
    mdp = read_model_description(str(p))
    vrp = {v.name: v for v in mdp.modelVariables}
    pm = FMU3Model(
        guid=mdp.guid, unzipDirectory=d, modelIdentifier="ReciprocatingDrive", instanceName="p"
    )
    pm.instantiate()
    pm.enterInitializationMode()
    for k, v in preset_values("kvo630").items():
        var = vrp[k]
        if var.type == "Float64":
            pm.setFloat64([var.valueReference], [float(v)])
        elif var.type == "Int32":
            pm.setInt32([var.valueReference], [int(v)])
        else:
            pm.setBoolean([var.valueReference], [bool(v)])
    pm.exitInitializationMode()
    assert pm.getNumberOfContinuousStates() == 2
    pm.terminate()
    pm.freeInstance()


@pytest.mark.parametrize("machine", ["default", "sk8-3.5-4000"])
def test_rigid_pump_model_exchange_matches_co_simulation(fmu_path, machine):
    """A rigid mechanism as Model Exchange (no continuous state: every output a function of the
    crank inputs, evaluated when read) in fmpy, with crank.angle = ω·t fed as a continuous input,
    against the co-simulation FMU fed the same values at its communication points: the outputs
    at the recorded points agree to rounding (1e-9 of each output's scale)."""
    from fmpy import read_model_description, simulate_fmu

    md = read_model_description(str(fmu2(fmu_path, "ReciprocatingDrive")))
    outputs = [v.name for v in md.modelVariables if v.causality == "output"]
    start = {k: v for k, v in preset_values(machine).items() if k != "crank.angle"}
    omega = float(
        start.pop(
            "crank.speed", next(v.start for v in md.modelVariables if v.name == "crank.speed")
        )
    )
    stop, h = 1.0, 1e-3
    inp = crank_input(stop, h, omega)
    kw = dict(stop_time=stop, output_interval=h, start_values=start, input=inp, output=outputs)
    me = simulate_fmu(str(fmu3(fmu_path, "ReciprocatingDrive")), fmi_type="ModelExchange", **kw)
    cs = simulate_fmu(str(fmu2(fmu_path, "ReciprocatingDrive")), **kw)
    assert len(me) == len(cs) > stop / h / 2
    assert np.allclose(me["time"], cs["time"], rtol=0, atol=1e-12)
    for name in outputs:
        scale = max(np.max(np.abs(cs[name])), 1e-300)
        d = np.max(np.abs(me[name] - cs[name])) / scale
        assert d <= 1e-9, f"{name}: Model Exchange and co-simulation differ by {d:.3g} of its scale"
    assert np.ptp(me["suspension.position"]) > 0


def test_hostile_calls_are_refused_with_one_line_naming_the_function(fmu_path, tmp_path):
    """Bad arguments through the FMI 3.0 ABI (C calls, no fmpy wrapper): each returns fmi3Error
    and logs one line that names the function and what is wrong; the instance stays usable."""
    C = ctypes
    md, s = _slave3(fmu3(fmu_path, "DriveTrain"), tmp_path)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    messages = []
    s.instantiate(logMessage=lambda e, st, c, m: messages.append(m.decode()))
    s.enterInitializationMode()
    s.exitInitializationMode()
    dll, c = s.dll, s.component
    u32 = C.c_uint32 * 1
    d1 = C.c_double * 1

    def refused(status, *needles):
        assert status == 3, (status, messages[-1:])
        last = messages[-1]
        assert "\n" not in last and all(n in last for n in needles), last

    one = u32(vr["crank.speed"])
    refused(
        dll.fmi3GetFloat64(c, one, C.c_size_t(1), d1(), C.c_size_t(2)),
        "fmi3GetFloat64",
        "nValues = 2",
    )
    refused(
        dll.fmi3GetFloat64(c, one, C.c_size_t(1), None, C.c_size_t(1)), "fmi3GetFloat64", "NULL"
    )
    refused(
        dll.fmi3GetFloat64(c, u32(999), C.c_size_t(1), d1(), C.c_size_t(1)), "fmi3GetFloat64", "999"
    )
    refused(
        dll.fmi3SetFloat64(
            c, u32(vr["load.torque"]), C.c_size_t(1), d1(float("nan")), C.c_size_t(1)
        ),
        "fmi3SetFloat64",
        "load.torque",
    )
    refused(
        dll.fmi3GetInt8(c, one, C.c_size_t(1), (C.c_int8 * 1)(), C.c_size_t(1)),
        "fmi3GetInt8",
        "not a Int8 variable",
    )
    refused(
        dll.fmi3GetString(c, one, C.c_size_t(1), (C.c_char_p * 1)(), C.c_size_t(1)), "fmi3GetString"
    )
    refused(
        dll.fmi3DeserializeFMUState(
            c, (C.c_uint8 * 8)(*b"garbage!"), C.c_size_t(8), C.byref(C.c_void_p())
        ),
        "fmi3DeserializeFMUState",
    )
    refused(dll.fmi3SetFMUState(c, C.c_void_p(0)), "fmi3SetFMUState", "NULL")
    refused(
        dll.fmi3SetTime(c, C.c_double(1.0)), "fmi3SetTime", "not an instance for Model Exchange"
    )
    refused(
        dll.fmi3GetVariableDependencies(
            c, C.c_uint32(vr["motor.inertia"]), None, None, None, None, C.c_size_t(0)
        ),
        "fmi3GetVariableDependencies",
        "not an output",
    )
    refused(dll.fmi3EnterConfigurationMode(c), "fmi3EnterConfigurationMode", "structural")
    # Still usable: a step, and the dependencies of an output from the table.
    s.doStep(0.0, 1e-3)
    n = C.c_size_t()
    assert (
        dll.fmi3GetNumberOfVariableDependencies(c, C.c_uint32(vr["crank.acceleration"]), C.byref(n))
        == 0
    )
    assert n.value == 2  # load.torque and the state crank.speed
    s.terminate()
    s.freeInstance()
    # fmpy's error messages never carry FMI 2.0 names.
    assert not any("fmi2" in m for m in messages), messages


# A freed instance, driven in a child process: on a binary that reads the freed instance the child
# dies (SIGSEGV) or returns what the freed memory happens to hold, and the test fails either way.
_FREED_CHILD = r"""
import ctypes as C, json, re, sys

so, header, token, kind = sys.argv[1:5]
lib = C.CDLL(so)
# Every function of the standard's header (fmpy ships the official fmi3Functions.h).
names = re.findall(r"FMI3_Export\s+fmi3\w+TYPE\s+(fmi3\w+)\s*;", open(header).read())
LOG = C.CFUNCTYPE(None, C.c_void_p, C.c_int, C.c_char_p, C.c_char_p)
messages = []
logger = LOG(lambda env, status, category, message: messages.append(message.decode()))
V = C.c_void_p


def instantiate(name):
    if kind == "me":
        f = lib.fmi3InstantiateModelExchange
        f.restype = V
        return f(name, token.encode(), None, False, True, None, logger)
    f = lib.fmi3InstantiateCoSimulation
    f.restype = V
    return f(name, token.encode(), None, False, True, False, False, None, C.c_size_t(0), None,
             logger, None)


inst = instantiate(b"freed")
assert inst, messages
lib.fmi3FreeInstance.restype = None
lib.fmi3FreeInstance(V(inst))
logged = len(messages)
status = {}
for n in names:
    if n == "fmi3GetVersion" or n.startswith("fmi3Instantiate"):
        continue  # no instance argument
    f = getattr(lib, n)
    if n == "fmi3FreeInstance":
        f(V(inst))  # a second free: void, it must simply return
        status[n] = None
        continue
    f.restype = C.c_int
    # The instance, then NULL for every other argument: a freed instance is refused first.
    status[n] = f(V(inst), *[V(None)] * 9)
# The freed instance's logger is not called any more (the importer may have released it).
after = messages[logged:]
# Another instance is unharmed by all this.
live = instantiate(b"live")
lib.fmi3EnterInitializationMode.restype = C.c_int
lib.fmi3ExitInitializationMode.restype = C.c_int
ok = [lib.fmi3EnterInitializationMode(V(live), False, C.c_double(0.0), C.c_double(0.0), False,
                                      C.c_double(0.0)),
      lib.fmi3ExitInitializationMode(V(live))]
lib.fmi3FreeInstance(V(live))
print(json.dumps({"names": names, "status": status, "after": after, "ok": ok}))
"""


@pytest.mark.parametrize("kind", ["cs", "me"])
@pytest.mark.parametrize("model", MODELS)
def test_a_freed_instance_is_refused_by_every_function(fmu_path, tmp_path, model, kind):
    """After fmi3FreeInstance, a second fmi3FreeInstance and every other function of the standard's
    fmi3Functions.h that takes an instance return (fmi3Error, 3) without touching freed memory:
    the process lives on, another instance still works, the freed instance's logger is not
    called again, and one line on standard error names the first function called on it."""
    r, stderr = run_freed_child(
        fmu3(fmu_path, model),
        "x86_64-linux",
        model,
        "fmi3Functions.h",
        _FREED_CHILD,
        kind,
        tmp_path,
    )
    assert len(r["names"]) == 75, len(r["names"])  # FMI 3.0: 75 functions
    refused = {n: s for n, s in r["status"].items() if s is not None}
    assert len(refused) == 70 and all(s == 3 for s in refused.values()), {
        n: s for n, s in refused.items() if s != 3
    }
    assert r["after"] == [] and r["ok"] == [0, 0], r
    lines = stderr.strip().splitlines()
    first = next(n for n in r["status"])
    assert len(lines) == 1, lines
    assert (
        lines[0].startswith(f"{model}: {first}: instance ")
        and "was freed by fmi3FreeInstance" in lines[0]
    ), lines
