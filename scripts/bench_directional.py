#!/usr/bin/env python3
"""The cost of one exact directional derivative of one output against reading that output
(docs/performance.md "Directional derivatives"), counted by callgrind: a native host
(benches/c/directional.c) loads target/release/libReciprocatingDrive.so with dlopen, sets the three
crank inputs at every iteration (the angle advancing, so nothing is cached), and then either reads
the output with fmi2GetReal or asks fmi2GetDirectionalDerivative for its derivative with respect
to one input (seed 1). The figures are the inclusive instructions per call of fmi2GetReal and of
fmi2GetDirectionalDerivative, from two callgrind runs of the same loop; the ratio is the issue's
"a directional derivative of one output costs at most 3x the output itself".

    python3 scripts/bench_directional.py [--steps 20000] [--fmu LIB]
"""

from __future__ import annotations

import argparse
import pathlib
import subprocess
import sys

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from bench_ratio import (  # noqa: E402
    NO_SUPPORTS,
    ROOT,
    callgrind_inclusive,
    fmi_headers,
    model_description,
    preset,
)

OUT = ROOT / "target" / "bench-c"

# (name, preset or None, overrides, output, known)
CASES = [
    ("default machine (friction on)", None, {}, "crank.torque", "crank.acceleration"),
    ("default machine (friction on)", None, {}, "crank.torque", "crank.angle"),
    ("default machine (friction on)", None, {}, "guide.friction", "crank.angle"),
    ("crank-slider, friction off", None, NO_SUPPORTS, "crank.torque", "crank.acceleration"),
    ("crank-slider, friction off", None, NO_SUPPORTS, "crank.torque", "crank.angle"),
    ("unb600a (gland)", "unb600a-simplex", {}, "crank.torque", "crank.angle"),
    ("beam unit sk8-3.5-4000", "sk8-3.5-4000", {}, "crank.torque", "crank.angle"),
    ("kvo630 (elastic rod, clamp friction)", "kvo630", {}, "crank.torque", "crank.acceleration"),
    ("kvo630 (elastic rod, clamp friction)", "kvo630", {}, "crank.torque", "crank.angle"),
]


def build() -> pathlib.Path:
    subprocess.run(
        ["cargo", "build", "--release", "-q", "-p", "fmu-reciprocating-drive"], cwd=ROOT, check=True
    )
    OUT.mkdir(parents=True, exist_ok=True)
    host = OUT / "directional"
    cmd = ["gcc", "-O3", "-std=c11", "-D_GNU_SOURCE", f"-I{fmi_headers()}", "-o", str(host)]
    subprocess.run(cmd + [str(ROOT / "benches/c/directional.c"), "-ldl"], check=True)
    return host


def per_call(cmd: list[str], function: str, calls: int) -> float:
    """Inclusive instructions of `function` per call in one callgrind run of `cmd`."""
    return callgrind_inclusive(cmd, (function,))[function] / calls


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--steps", type=int, default=20_000)
    ap.add_argument("--fmu", type=pathlib.Path, help="the shared object (default: built here)")
    a = ap.parse_args(argv)
    host = build()
    lib = a.fmu.resolve() if a.fmu else ROOT / "target" / "release" / "libReciprocatingDrive.so"
    guid, kinds = model_description()
    ins = ",".join(str(kinds[n][0]) for n in ["crank.angle", "crank.speed", "crank.acceleration"])
    print(f"{'machine':32} {'output':14} {'wrt':19} {'GetReal':>8} {'GetDD':>8} {'ratio':>6}")
    worst = 0.0
    for name, pre, over, output, known in CASES:
        values = {**(preset(pre) if pre else {}), **over}
        speed = float(values.get("crank.speed", 6.0))
        sets = []
        for k, v in values.items():
            vr, tag = kinds[k]
            code = {"Real": "r", "Integer": "i", "Boolean": "b"}[tag]
            sets.append(f"{code}:{vr}={float(v)}")
        base = [str(host), str(lib), guid, ins, str(kinds[output][0]), str(kinds[known][0])]
        tail = [str(speed), str(a.steps), *sets]
        value = per_call(base + ["value"] + tail, "fmi2GetReal", a.steps)
        deriv = per_call(base + ["derivative"] + tail, "fmi2GetDirectionalDerivative", a.steps)
        worst = max(worst, deriv / value)
        print(f"{name:32} {output:14} {known:19} {value:8.0f} {deriv:8.0f} {deriv / value:6.2f}")
    print(f"largest ratio {worst:.2f} (target <= 3)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
