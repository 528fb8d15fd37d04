"""Runs a freed-instance probe (a ctypes script) in a child process against one binary of an FMU,
for the freed-instance tests of both standards (test_lowlevel.py for FMI 2.0, test_fmi3.py for
FMI 3.0; docs/fmi-interface.md "A freed instance"). A child, because the failure this guards
against is the process dying."""

from __future__ import annotations

import json
import pathlib
import subprocess
import sys
import zipfile

import fmpy


def run_freed_child(fmu, platform, model, header, child, kind, tmp_path):
    """The child's JSON report and its standard error: `child` is run with the binary
    binaries/<platform>/<model>.so of `fmu`, the path of fmpy's copy of the standard's `header`
    (fmi2Functions.h or fmi3Functions.h), the FMU's GUID and `kind` ("cs" or "me")."""
    md = fmpy.read_model_description(str(fmu))
    so = tmp_path / f"{model}.so"
    with zipfile.ZipFile(fmu) as z:
        so.write_bytes(z.read(f"binaries/{platform}/{model}.so"))
    header = pathlib.Path(fmpy.__file__).parent / "c-code" / header
    p = subprocess.run(
        [sys.executable, "-c", child, str(so), str(header), md.guid, kind],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert p.returncode == 0, f"exit {p.returncode}: {p.stderr[-2000:]}"
    return json.loads(p.stdout), p.stderr
