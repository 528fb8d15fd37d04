#!/usr/bin/env python3
"""The FMU's cost against an FMU that computes nothing (docs/performance.md), measured side by side
in one run by a native C host (benches/c/host_loop.c) that loads both shared objects with dlopen:

* the baseline, benches/c/feedthrough.c, an FMI 2.0 co-simulation FMU equivalent in the work of
  each call to the Modelica Reference FMUs' Feedthrough, built here with gcc -O3;
* target/release/libReciprocatingDrive.so (built here with cargo build --release).

Per step: fmi2SetReal of the 3 crank inputs, fmi2DoStep (h = 1 ms), fmi2GetReal of 8 outputs;
and fmi2DoStep alone. Runs of both FMUs alternate; each figure is the median of ROUNDS runs.
Ratios hold across machines; absolute times do not (the machines are noisy). With --instructions
the same loop runs under valgrind's callgrind, which counts the instructions each FMU's functions
execute per step: repeatable to the instruction, whatever else the machine is doing.

With --step H the communication step is H seconds instead of 1 ms; with --instances N the host
steps N instances of each FMU in turn at every communication point (STEPS/N steps each, at least
10), and the figures are per instance and step.

    python3 scripts/bench_ratio.py [--steps 200000] [--rounds 9] [--instructions] [--fmu LIB]
                                   [--step H] [--instances N] [filter]
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import re
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET

ROOT = pathlib.Path(__file__).resolve().parents[1]
OUT = ROOT / "target" / "bench-c"

# The outputs the loop reads (the same as benches/host_loop.rs), and the kinematics only.
EIGHT = [
    "suspension.position",
    "suspension.velocity",
    "suspension.acceleration",
    "kinematics.torque_factor",
    "inertia.force",
    "rod.force",
    "crank.torque",
    "rod.angle",
]
KINEMATICS = [
    "suspension.position",
    "suspension.velocity",
    "suspension.acceleration",
    "kinematics.torque_factor",
    "rod.angle",
    "rod.angular_velocity",
    "crank.model_angle",
    "crank.model_speed",
]
NO_SUPPORTS = {"support_A.kind": 0, "support_B.kind": 0, "support_C.kind": 0}
# The pump's loop (docs/model.md §4.1): the eight, of which crank.torque sums every cylinder, and
# the pump's flow and hydraulic power.
PUMP = EIGHT + ["fluid_end.flow", "fluid_end.hydraulic_power"]

# (name, preset or None, overrides, outputs read, target: the FMU's instructions per loop step,
# or None; docs/performance.md "Current figures")
SCENARIOS = [
    ("crank-slider, friction off", None, NO_SUPPORTS, EIGHT, None),
    ("beam unit sk8-3.5-4000 (a single clamp: no friction)", "sk8-3.5-4000", {}, EIGHT, None),
    ("default machine, friction on, friction outputs read", None, {}, EIGHT, 1500),
    ("default machine, friction on, kinematics read", None, {}, KINEMATICS, None),
    ("kvo630, elastic rod, tolerance 1e-8", "kvo630", {}, EIGHT, 7500),
    # One cylinder, two and three, each with its guide friction, loaded by the pressures: the cost
    # of a cylinder and of the pressure mapping (docs/performance.md "The pump").
    (
        "pump, pressures, friction on: one cylinder of unb600a",
        "unb600a",
        {"fluid_end.cylinders": 1},
        PUMP,
        None,
    ),
    ("pump, pressures, friction on: unb600a (duplex double-acting)", "unb600a", {}, PUMP, None),
    (
        "pump, pressures, friction on: triplex-1600 (triplex single-acting)",
        "triplex-1600",
        {},
        PUMP,
        None,
    ),
]


def fmi_headers() -> pathlib.Path:
    """The FMI 2.0 headers shipped in the fmi-sys crate the FMU is built with."""
    meta = json.loads(
        subprocess.run(
            ["cargo", "metadata", "--format-version", "1"],
            cwd=ROOT,
            check=True,
            capture_output=True,
            text=True,
        ).stdout
    )
    pkg = next(p for p in meta["packages"] if p["name"] == "fmi-sys")
    return pathlib.Path(pkg["manifest_path"]).parent / "fmi-standard2" / "headers"


def build() -> tuple[pathlib.Path, pathlib.Path, pathlib.Path]:
    subprocess.run(
        ["cargo", "build", "--release", "-q", "-p", "fmu-reciprocating-drive"], cwd=ROOT, check=True
    )
    OUT.mkdir(parents=True, exist_ok=True)
    inc = fmi_headers()
    base = OUT / "libFeedthrough.so"
    host = OUT / "host_loop"
    cc = ["gcc", "-O3", "-std=c11", "-D_GNU_SOURCE", f"-I{inc}"]
    subprocess.run(
        cc + ["-shared", "-fPIC", "-o", base, ROOT / "benches/c/feedthrough.c"], check=True
    )
    subprocess.run(cc + ["-o", host, ROOT / "benches/c/host_loop.c", "-ldl"], check=True)
    return host, base, ROOT / "target" / "release" / "libReciprocatingDrive.so"


def model_description():
    root = ET.parse(ROOT / "modelDescription" / "modelDescription.xml").getroot()
    kinds = {}
    for v in root.iter("ScalarVariable"):
        t = next(iter(v))
        kinds[v.get("name")] = (int(v.get("valueReference")), t.tag)
    return root.get("guid"), kinds


def preset(name: str) -> dict:
    ns = {"ssv": "http://ssp-standard.org/SSP1/SystemStructureParameterValues"}
    root = ET.parse(ROOT / "resources" / "presets" / f"{name}.ssv").getroot()
    out = {}
    for p in root.iter(f"{{{ns['ssv']}}}Parameter"):
        v = next(iter(p))
        tag = v.tag.split("}")[1]
        raw = v.get("value")
        out[p.get("name")] = (
            (raw == "true") if tag == "Boolean" else int(raw) if tag == "Integer" else float(raw)
        )
    return out


def callgrind_inclusive(cmd: list[str], functions, env: dict | None = None) -> dict:
    """Inclusive instructions of each of `functions` in one callgrind run of `cmd`
    (callgrind_annotate adds up same-named functions of all the libraries loaded); the driver
    of every instruction benchmark here (bench_me.py, bench_directional.py)."""
    with tempfile.TemporaryDirectory() as d:
        out = pathlib.Path(d) / "callgrind.out"
        subprocess.run(
            ["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}", *cmd],
            check=True,
            capture_output=True,
            env=env,
        )
        text = subprocess.run(
            ["callgrind_annotate", "--inclusive=yes", "--threshold=100", str(out)],
            check=True,
            capture_output=True,
            text=True,
        ).stdout
    count = {}
    for f in functions:
        pat = re.compile(r"^\s*([\d,]+)\s.*:" + f + r"( \[|$)", re.M)
        count[f] = sum(int(m.group(1).replace(",", "")) for m in pat.finditer(text))
    return count


def _fmi_instructions(cmd: list[str], env: dict) -> dict:
    """Inclusive instructions of fmi2SetReal, fmi2DoStep and fmi2GetReal in one callgrind run of
    the host."""
    return callgrind_inclusive(cmd, ("fmi2SetReal", "fmi2DoStep", "fmi2GetReal"), env)


def instructions(
    base_cmd: list[str], cmd: list[str], steps: int, env: dict, instances: int
) -> tuple:
    """Instructions per step of the loop (fmi2SetReal + fmi2DoStep + fmi2GetReal) and of
    fmi2DoStep alone, for the baseline and the FMU. The host makes steps/10 warm-up steps and one
    round of `steps` in each mode (loop, then fmi2DoStep alone) on each of its two libraries;
    `base_cmd` runs the baseline twice, `cmd` the baseline and the FMU, and the FMU's counts are
    the difference."""
    both_base, mixed = _fmi_instructions(base_cmd, env), _fmi_instructions(cmd, env)
    calls = (steps + steps // 10) * instances

    def per_step(c):
        dostep = c["fmi2DoStep"] / (2 * calls)
        return (c["fmi2SetReal"] + c["fmi2GetReal"]) / calls + dostep, dostep

    base = {f: v / 2 for f, v in both_base.items()}
    fmu = {f: mixed[f] - base[f] for f in mixed}
    return per_step(base), per_step(fmu)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("filter", nargs="?", default="")
    ap.add_argument("--steps", type=int, default=200_000)
    ap.add_argument("--rounds", type=int, default=9)
    ap.add_argument(
        "--instructions", action="store_true", help="count instructions under callgrind instead"
    )
    ap.add_argument(
        "--fmu",
        type=pathlib.Path,
        default=None,
        help="another build of libReciprocatingDrive.so to measure (e.g. of an earlier commit)",
    )
    ap.add_argument("--step", type=float, default=1e-3, help="communication step [s]")
    ap.add_argument("--instances", type=int, default=1, help="instances stepped in turn")
    a = ap.parse_args(argv)
    if not a.step > 0 or a.instances < 1:
        ap.error(f"--step must be > 0 and --instances >= 1 (got {a.step}, {a.instances})")
    env = dict(os.environ, HOST_H=repr(a.step), HOST_INSTANCES=str(a.instances))
    steps = max(a.steps // a.instances, 10)
    host, base, lib = build()
    lib = a.fmu.resolve() if a.fmu else lib
    guid, kinds = model_description()
    vr = {n: k[0] for n, k in kinds.items()}
    inputs = ",".join(str(vr[n]) for n in ("crank.angle", "crank.speed", "crank.acceleration"))
    if a.instructions:
        a.rounds = 1
        print(
            f"baseline: {base.relative_to(ROOT)} (gcc -O3); FMU: {lib}; instructions per step (callgrind), "
            f"{steps} steps of {a.step:g} s, {a.instances} instance(s)"
        )
        print(
            "| scenario | loop instructions/step (Feedthrough / FMU) | loop ratio | target (FMU) "
            "| fmi2DoStep (Feedthrough / FMU) | fmi2DoStep ratio |"
        )
    else:
        print(
            f"baseline: {base.relative_to(ROOT)} (gcc -O3); FMU: {lib}; "
            f"{a.rounds} alternating runs of {steps} steps of {a.step:g} s, {a.instances} instance(s), "
            "medians"
        )
        print(
            "| scenario | loop ns/step (Feedthrough / FMU) | loop ratio | target (instructions) "
            "| fmi2DoStep ns (Feedthrough / FMU) | fmi2DoStep ratio |"
        )
    print("|---|---|---|---|---|---|")
    for name, pre, overrides, outputs, target in SCENARIOS:
        if a.filter not in name:
            continue
        values = {k: v for k, v in (preset(pre) if pre else {}).items()}
        speed = values.pop("crank.speed", 2 * 3.141592653589793 * 65 / 60)
        values.update(overrides)
        sets = []
        for n, v in values.items():
            tag = kinds[n][1]
            sets.append(
                f"r:{vr[n]}={v!r}"
                if tag == "Real"
                else f"i:{vr[n]}={int(v)}"
                if tag == "Integer"
                else f"b:{vr[n]}={int(bool(v))}"
            )
        cmd = [
            str(host),
            str(base),
            "base",
            "0,1,2",
            "3,4,5,6,7,8,9,10",
            str(lib),
            guid,
            inputs,
            ",".join(str(vr[n]) for n in outputs),
            repr(speed),
            str(steps),
            str(a.rounds),
            *sets,
        ]
        if a.instructions:
            base_cmd = cmd[:5] + cmd[1:5] + cmd[9:12]
            (lb, db), (lf, df) = instructions(base_cmd, cmd, steps, env, a.instances)
            lr, dr = lf / lb, df / db
        else:
            res = {}
            for line in subprocess.run(
                cmd, check=True, capture_output=True, text=True, env=env
            ).stdout.splitlines():
                mode, _, b, _, f, _, r = line.split()
                res[mode] = (float(b), float(f), float(r))
            lb, lf, lr = res["loop"]
            db, df, dr = res["dostep"]
        # The targets are instruction counts: a wall time says nothing of them (--instructions).
        goal = "" if target is None else f"≤ {target}"
        if target is not None and a.instructions:
            goal += " (met)" if lf <= target else " (NOT met)"
        print(
            f"| {name} | {lb:.1f} / {lf:.1f} | **{lr:.2f}** | {goal} | {db:.1f} / {df:.1f} | {dr:.2f} |",
            flush=True,
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
