"""The win64 binaries in the FMUs (docs/win64.md): each FMU carries binaries/win64/<id>.dll that
imports only system DLLs of Windows 10 and later, and the DLL run under wine by a small C host
(tests/win64/host.c, built with mingw) gives the same outputs as the linux64 binary run by the
same host built for Linux, over a run of the default machine and of kvo630.

Not bit for bit in general: the DLL uses the Windows C runtime's libm (msvcrt), whose sin, cos,
exp and sqrt may differ from glibc's in the last bit. The tolerance is therefore relative to each
output's scale: 1e-13 for the rigid machine (exact kinematics and a direct solve amplify a last-bit
difference by at most ~1e3) and 1e-9 for kvo630 (an integrator with error control at 1e-8 may
place its internal steps differently; 1e-9 is a tenth of its tolerance).
"""

from __future__ import annotations

import os
import pathlib
import shutil
import subprocess
import zipfile

import numpy as np
import pytest
from conftest import ROOT
from reciprocating_drive import preset_values

SYSTEM_DLLS = {
    "kernel32.dll",
    "ntdll.dll",
    "msvcrt.dll",
    "bcryptprimitives.dll",
    "advapi32.dll",
    "ws2_32.dll",
    "userenv.dll",
    "bcrypt.dll",
    "user32.dll",
    "shell32.dll",
    "ole32.dll",
}

pytestmark = pytest.mark.skipif(
    os.environ.get("RD_WIN64") == "0", reason="RD_WIN64=0: no win64 build"
)


@pytest.fixture(scope="module")
def hosts(tmp_path_factory):
    d = tmp_path_factory.mktemp("hosts")
    src = ROOT / "tests" / "win64" / "host.c"
    subprocess.run(["gcc", "-O2", "-o", d / "host", src, "-ldl"], check=True)
    subprocess.run(["x86_64-w64-mingw32-gcc", "-O2", "-o", d / "host.exe", src], check=True)
    return d


def unpack(fmu: pathlib.Path, dest: pathlib.Path) -> pathlib.Path:
    with zipfile.ZipFile(fmu) as z:
        z.extractall(dest)
    return dest


@pytest.mark.parametrize("model", ["ReciprocatingDrive", "DriveTrain"])
def test_every_fmu_has_a_win64_dll_with_system_imports_only(fmu_path, tmp_path, model):
    fmu = pathlib.Path(fmu_path).parent / f"{model}.fmu"
    d = unpack(fmu, tmp_path)
    dll = d / "binaries" / "win64" / f"{model}.dll"
    assert dll.is_file(), f"{fmu} has no binaries/win64/{model}.dll"
    dump = subprocess.run(
        ["x86_64-w64-mingw32-objdump", "-p", dll], capture_output=True, text=True, check=True
    ).stdout
    imports = {
        line.split(":", 1)[1].strip().lower() for line in dump.splitlines() if "DLL Name:" in line
    }
    foreign = {x for x in imports if x not in SYSTEM_DLLS and not x.startswith("api-ms-win-")}
    assert not foreign, f"{model}.dll imports non-system DLLs: {foreign}"
    exports = dump.count("fmi2")
    assert exports >= 34, "the 34 FMI functions are exported"


def run_host(hosts, d, model_description, steps, h, params, wine):
    from fmpy import read_model_description

    md = read_model_description(str(model_description))
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
        kind = {"Integer": ":i", "Boolean": ":b"}.get(v.type, "")
        args.append(f"{v.valueReference}{kind}={int(value) if kind else float(value)!r}")
    if wine:
        dll = d / "binaries" / "win64" / "ReciprocatingDrive.dll"
        shutil.copy(hosts / "host.exe", d / "host.exe")
        cmd = [
            "wine",
            str(d / "host.exe"),
            "Z:" + str(dll).replace("/", "\\"),
            "ReciprocatingDrive",
            *args,
        ]
    else:
        cmd = [
            str(hosts / "host"),
            str(d / "binaries" / "linux64" / "ReciprocatingDrive.so"),
            "ReciprocatingDrive",
            *args,
        ]
    p = subprocess.run(
        cmd, capture_output=True, text=True, timeout=600, env={**os.environ, "WINEDEBUG": "-all"}
    )
    assert p.returncode == 0, p.stderr[-2000:]
    return np.array([[float(x) for x in line.split(",")] for line in p.stdout.split()]), [
        v.name for v in outs
    ]


@pytest.mark.parametrize(
    "machine,steps,h,tol", [("default", 2000, 1e-3, 1e-13), ("kvo630", 1000, 2e-4, 1e-9)]
)
def test_win64_under_wine_matches_linux64(fmu_path, hosts, tmp_path, machine, steps, h, tol):
    d = unpack(pathlib.Path(fmu_path), tmp_path)
    params = (
        {k: v for k, v in preset_values(machine).items() if k != "crank.angle"}
        if machine != "default"
        else {}
    )
    lin, names = run_host(hosts, d, d / "modelDescription.xml", steps, h, params, wine=False)
    win, _ = run_host(hosts, d, d / "modelDescription.xml", steps, h, params, wine=True)
    assert lin.shape == win.shape == (steps + 1, len(names))
    scale = np.maximum(np.max(np.abs(lin), axis=0), 1e-300)
    rel = np.max(np.abs(win - lin), axis=0) / scale
    worst = int(np.argmax(rel))
    identical = bool(np.array_equal(lin, win))
    print(
        f"{machine}: bit-identical {identical}; worst {names[worst]} {rel[worst]:.3g} of its scale"
    )
    assert rel[worst] <= tol, f"{names[worst]} differs by {rel[worst]:.3g} of its scale"
