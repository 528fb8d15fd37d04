#!/usr/bin/env python3
"""Model Exchange evaluation against the co-simulation loop (docs/performance.md "Model
Exchange"), measured side by side in one run by a native C host (benches/c/me_eval.c) that loads
target/release/libReciprocatingDrive.so with dlopen (one binary, both interfaces):

* cs:  per time point fmi2SetReal of the 3 crank inputs, fmi2DoStep (h = 1 ms), fmi2GetReal of
       8 outputs (the loop of scripts/bench_ratio.py);
* me:  fmi2SetTime, fmi2SetReal of the 3 crank inputs, fmi2GetReal of the same 8 outputs (a
       solver's evaluation of a rigid mechanism: the outputs it asks for);
* rhs: as me, plus fmi2SetContinuousStates and fmi2GetDerivatives of the two cage states (a
       solver that integrates the states the FMU declares).

Runs of the three alternate; each figure is the median of ROUNDS runs. With --instructions each
mode runs alone under valgrind's callgrind, which counts the instructions the FMU's functions
execute per time point: repeatable to the instruction, whatever else the machine is doing. The
target: me ≤ cs and rhs ≤ cs, rigid and elastic.

    python3 scripts/bench_me.py [--steps 200000] [--rounds 9] [--instructions] [filter]
"""

from __future__ import annotations

import argparse
import os
import pathlib
import subprocess
import sys

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from bench_ratio import (  # noqa: E402
    EIGHT,
    NO_SUPPORTS,
    OUT,
    ROOT,
    callgrind_inclusive,
    fmi_headers,
    model_description,
    preset,
)

# (name, preset or None, overrides); the scenarios of scripts/bench_ratio.py: three rigid
# mechanisms, and an elastic rod (its co-simulation step integrates the cage, about 15 right-hand
# sides per step; Model Exchange's rhs is one of them).
SCENARIOS = [
    ("crank-slider, friction off", None, NO_SUPPORTS),
    ("beam unit sk8-3.5-4000", "sk8-3.5-4000", {}),
    ("default machine, friction on", None, {}),
    ("kvo630, elastic rod, tolerance 1e-8", "kvo630", {}),
]


def build() -> tuple[pathlib.Path, pathlib.Path]:
    subprocess.run(
        ["cargo", "build", "--release", "-q", "-p", "fmu-reciprocating-drive"], cwd=ROOT, check=True
    )
    OUT.mkdir(parents=True, exist_ok=True)
    host = OUT / "me_eval"
    subprocess.run(
        ["gcc", "-O3", "-std=c11", "-D_GNU_SOURCE", f"-I{fmi_headers()}", "-o", host]
        + [ROOT / "benches/c/me_eval.c", "-ldl"],
        check=True,
    )
    return host, ROOT / "target" / "release" / "libReciprocatingDrive.so"


FUNCTIONS = (
    "fmi2SetReal",
    "fmi2DoStep",
    "fmi2GetReal",
    "fmi2SetTime",
    "fmi2SetContinuousStates",
    "fmi2GetDerivatives",
)


def instructions(cmd: list[str], mode: str, steps: int) -> float:
    """Instructions per time point of the FMU's functions in one callgrind run of `mode` alone
    (steps/10 warm-up time points and one round of `steps`)."""
    count = callgrind_inclusive(cmd, FUNCTIONS, dict(os.environ, ME_EVAL_ONLY=mode))
    return sum(count.values()) / (steps + steps // 10)


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
    a = ap.parse_args(argv)
    if a.steps < 10 or not 1 <= a.rounds <= 99:
        ap.error(f"--steps must be >= 10 and --rounds 1..99 (got {a.steps}, {a.rounds})")
    host, lib = build()
    guid, kinds = model_description()
    vr = {n: k[0] for n, k in kinds.items()}
    inputs = ",".join(str(vr[n]) for n in ("crank.angle", "crank.speed", "crank.acceleration"))
    outputs = ",".join(str(vr[n]) for n in EIGHT)
    unit = "instructions" if a.instructions else "ns"
    if a.instructions:
        a.rounds = 1
        print(f"FMU: {lib.relative_to(ROOT)}; instructions per time point (callgrind), {a.steps}")
    else:
        print(f"FMU: {lib.relative_to(ROOT)}; {a.rounds} alternating runs of {a.steps} time points")
    print(
        f"| scenario | cs {unit} (set 3, step, get 8) | me {unit} (time, set 3, get 8) | me / cs "
        f"| rhs {unit} (+ states, derivatives) | rhs / cs | target (both) |"
    )
    print("|---|---|---|---|---|---|---|")
    for name, pre, overrides in SCENARIOS:
        if a.filter not in name:
            continue
        values = dict(preset(pre)) if pre else {}
        speed = values.pop("crank.speed", 2 * 3.141592653589793 * 65 / 60)
        values.update(overrides)
        sets = []
        for n, v in values.items():
            tag = kinds[n][1]
            kind = "r" if tag == "Real" else "i" if tag == "Integer" else "b"
            sets.append(f"{kind}:{vr[n]}={v!r}" if kind == "r" else f"{kind}:{vr[n]}={int(v)}")
        cmd = [str(host), str(lib), guid, inputs, outputs, "2", repr(speed), "1e-3"]
        cmd += [str(a.steps), str(a.rounds), *sets]
        res = {}
        if a.instructions:
            res = {m: instructions(cmd, m, a.steps) for m in ("cs", "me", "rhs")}
        else:
            run = subprocess.run(cmd, check=True, capture_output=True, text=True)
            for line in run.stdout.splitlines():
                mode, ns = line.split()
                res[mode] = float(ns)
        cs, me, rhs = res["cs"], res["me"], res["rhs"]
        mark = "met" if max(me, rhs) <= cs else "NOT met"
        print(
            f"| {name} | {cs:.1f} | {me:.1f} | **{me / cs:.2f}** | {rhs:.1f} | **{rhs / cs:.2f}** "
            f"| ≤ 1 ({mark}) |",
            flush=True,
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
