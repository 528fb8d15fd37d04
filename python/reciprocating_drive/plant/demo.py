"""The one-command demo (docs/plant.md, "Demo"): the simulated pump PLC plays the shipped sample
in real time, with a process-force step, the twin subscribes to it over OPC UA, results go to
SQLite, and the live page shows the alarms the step raises and clears.

    rdrive plant --demo [--seconds S] [--db results/twin/demo.sqlite] [--force-step N]

Layer: workflows, the plant (docs/architecture.md).
"""

from __future__ import annotations

import os
import pathlib
import subprocess
import sys
import tempfile
import time

import numpy as np

from .. import artifacts
from .pipeline import run_config
from .plc_sim import free_port

#: The demo's process force [N], added from STEP_FROM to STEP_TO seconds of the sample: with the
#: example limits (examples/twin/limits.toml) it raises the crank torque alarm (374 -> 624 N·m,
#: limit 500) and the rod force alarm (3.48 -> 4.62 kN, limit 4 kN) two revolutions after 3 s, and
#: both clear two revolutions after 8 s, before the 12 s of the sample are over.
FORCE_STEP = 2000.0
STEP_FROM, STEP_TO = 3.0, 8.0


#: The force's ripple [N] and its frequency [Hz]: a measured force is never constant, and the
#: demo shows what a measured one looks like (docs/plant.md, "Demo").
RIPPLE, RIPPLE_HZ = 10.0, 7.0


def demo_data(path, force_step: float = FORCE_STEP) -> pathlib.Path:
    """The shipped sample with a `process_force` column: `force_step` from STEP_FROM to STEP_TO
    seconds, 0 elsewhere (the sample's own load is the machine's), plus a ripple of ±RIPPLE N.
    Returns `path`."""
    src = artifacts.twin_sample()
    with open(src, encoding="utf-8") as f:
        head = f.readline().strip()
        rows = [line.strip() for line in f if line.strip()]
    t = np.array([float(r.split(",", 1)[0]) for r in rows])
    force = np.where((t >= STEP_FROM) & (t < STEP_TO), float(force_step), 0.0)
    force += RIPPLE * np.sin(2 * np.pi * RIPPLE_HZ * t)
    path = pathlib.Path(path)
    with open(path, "w", encoding="utf-8") as f:
        f.write(f"{head},process_force\n")
        for r, x in zip(rows, force.tolist()):
            f.write(f"{r},{x!r}\n")
    return path


def demo(
    db: str,
    seconds: float | None = None,
    page_port: int = 8050,
    force_step: float = FORCE_STEP,
    stop_cycles: int | None = None,
) -> int:
    port = free_port()
    endpoint = f"opc.tcp://127.0.0.1:{port}/plc"
    pathlib.Path(db).parent.mkdir(parents=True, exist_ok=True)
    # The simulated PLC in a process of its own, from this very package (checkout or wheel).
    env = {**os.environ, "PYTHONPATH": str(artifacts.PACKAGE.parent)}
    with tempfile.TemporaryDirectory() as d:
        if stop_cycles:
            # Stops and starts instead of the sample (docs/plant.md "Machine states").
            from . import stop_cycle

            data = stop_cycle.write(pathlib.Path(d) / "cycles.csv", stop_cycles, force=True)
            force_step = 0.0
        else:
            data = demo_data(pathlib.Path(d) / "demo_data.csv", force_step)
        plc = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "reciprocating_drive.commands.plc_sim",
                "--data",
                str(data),
                "--port",
                str(port),
                "--start-delay",
                "2",
                "--linger",
                "30",
            ],
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
        )
        try:
            return _run(plc, d, endpoint, db, seconds, page_port, force_step, stop_cycles)
        finally:
            plc.terminate()
            try:
                plc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                plc.kill()
                plc.wait(timeout=10)


def _run(plc, d, endpoint, db, seconds, page_port, force_step, stop_cycles=None) -> int:
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline:
        line = plc.stdout.readline()
        if not line:
            print("demo: the simulated PLC did not start", file=sys.stderr)
            return 1
        if "listening on" in line:
            break
    run = time.strftime("demo-%Y%m%dT%H%M%S")
    cfg = pathlib.Path(d) / "demo.toml"
    cfg.write_text(
        f'[run]\nid = "{run}"\nmachine_id = "demo-pump"\n\n'
        f'[source]\ntype = "opcua"\nendpoint = "{endpoint}"\nmode = "scalar"\n'
        'angle_node = "ns=2;s=Pump.CrankAngle"\nforce_node = "ns=2;s=Pump.ProcessForce"\n'
        'end_node = "ns=2;s=Pump.Finished"\n'
        'angle_unit = "counts"\ncounts_per_rev = 4096\n\n'
        f'[[sink]]\ntype = "sqlite"\npath = "{pathlib.Path(db).resolve()}"\n\n'
        # The live page with the example alarm limits (docs/page.md), on 127.0.0.1.
        f'[page]\nport = {page_port}\nlimits = "{artifacts.examples_dir() / "limits.toml"}"\n'
        'title = "Demo pump (simulated PLC)"\n'
    )
    step = (
        f", process force {force_step:g} N from {STEP_FROM:g} s to {STEP_TO:g} s"
        if force_step
        else ""
    )
    played = (
        f"{stop_cycles} stop/start cycle(s) ({22 * stop_cycles} s of data"
        if stop_cycles
        else f"data/twin/pump_encoder.csv{step} (12 s of data"
    )
    about = (
        f"demo: PLC at {endpoint} playing {played} in real time after a 2 s start); "
        f"twin run {run!r} -> {db}"
    )
    pending = [about]

    def log(m):
        # The page's address first (docs/plant.md, "Demo"), then what the demo plays.
        print(m, file=sys.stderr, flush=True)
        if pending and m.startswith("page: "):
            print(pending.pop(), file=sys.stderr, flush=True)

    # --seconds: the pipeline stops itself (and commits) after that long, which is the demo
    # asked for, complete: exit 0 (docs/install.md "Exit codes").
    status = run_config(str(cfg), log=log, stop_after=seconds)
    print(
        f'demo: query it with: sqlite3 {db} "SELECT revolution, start_time, mean_speed, '
        f"rod_force_max FROM revolutions JOIN runs USING (run) WHERE name = '{run}'\"",
        file=sys.stderr,
    )
    return status
