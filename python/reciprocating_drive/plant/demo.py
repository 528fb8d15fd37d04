"""The one-command demo (docs/plant.md, "Demo"): the simulated pump PLC plays the shipped sample
in real time, the twin subscribes to it over OPC UA, results go to SQLite.

    .venv/bin/python scripts/twin_plant.py --demo [--seconds S] [--db results/twin/demo.sqlite]
"""

from __future__ import annotations

import os
import pathlib
import subprocess
import sys
import tempfile
import time

from .. import artifacts
from .pipeline import run_config
from .plc_sim import free_port


def demo(db: str, seconds: float | None = None, page_port: int = 8050) -> int:
    port = free_port()
    endpoint = f"opc.tcp://127.0.0.1:{port}/plc"
    pathlib.Path(db).parent.mkdir(parents=True, exist_ok=True)
    # The simulated PLC in a process of its own, from this very package (checkout or wheel).
    env = {**os.environ, "PYTHONPATH": str(artifacts.PACKAGE.parent)}
    plc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "reciprocating_drive.commands.plc_sim",
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
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline:
            line = plc.stdout.readline()
            if not line:
                print("demo: the simulated PLC did not start", file=sys.stderr)
                return 1
            if "listening on" in line:
                break
        run = time.strftime("demo-%Y%m%dT%H%M%S")
        with tempfile.TemporaryDirectory() as d:
            cfg = pathlib.Path(d) / "demo.toml"
            cfg.write_text(
                f'[run]\nid = "{run}"\nmachine_id = "demo-pump"\n\n'
                f'[source]\ntype = "opcua"\nendpoint = "{endpoint}"\nmode = "scalar"\n'
                'angle_node = "ns=2;s=Pump.CrankAngle"\nend_node = "ns=2;s=Pump.Finished"\n'
                'angle_unit = "counts"\ncounts_per_rev = 4096\n\n'
                f'[[sink]]\ntype = "sqlite"\npath = "{pathlib.Path(db).resolve()}"\n\n'
                # The live page with the example alarm limits (docs/page.md), on 127.0.0.1.
                f'[page]\nport = {page_port}\nlimits = "{artifacts.examples_dir() / "limits.toml"}"\n'
                'title = "Demo pump (simulated PLC)"\n'
            )
            print(
                f"demo: PLC at {endpoint} playing data/twin/pump_encoder.csv in real time (12 s); "
                f"twin run {run!r} -> {db}",
                file=sys.stderr,
            )
            # --seconds: the pipeline stops itself (and commits) after that long, which is
            # the demo asked for, complete: exit 0 (docs/install.md "Exit codes").
            status = run_config(str(cfg), stop_after=seconds)
        print(
            f'demo: query it with: sqlite3 {db} "SELECT revolution, start_time, mean_speed, '
            f"rod_force_max FROM revolutions JOIN runs USING (run) WHERE name = '{run}'\"",
            file=sys.stderr,
        )
        return status
    finally:
        plc.terminate()
        try:
            plc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            plc.kill()
            plc.wait(timeout=10)
