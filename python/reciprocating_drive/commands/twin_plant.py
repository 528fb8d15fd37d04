#!/usr/bin/env python3
"""The twin in a plant (docs/plant.md): a configuration file names the machine, the source (a CSV
file or an OPC UA server), the sinks (SQLite, PostgreSQL) and the conditioning.

    rdrive plant --config examples/twin/replay-sqlite.toml
    rdrive plant --demo        # simulated PLC + OPC UA + SQLite

The paths above are those of a checkout, or of a folder made by `rdrive examples DIR` (the sample
data, configurations and studies of an installed package).

Run again with the same configuration after a crash or a stop: it resumes from the last
checkpoint committed in the database, and nothing is lost or stored twice.
"""

# Layer: commands (docs/architecture.md); a comment, as --help prints the docstring.

from __future__ import annotations

import argparse
import sys

from .. import artifacts
from ..cli_errors import ArgumentParser, UserError, positive_float, run_cli


def main(argv=None, prog: str | None = None) -> int:
    """The command: its exit code, with every error as one line (cli_errors.run_cli)."""
    prog = prog or "twin_plant.py"
    return run_cli(prog, lambda: _main(argv, prog))


def _main(argv, prog: str) -> int:
    ap = ArgumentParser(
        prog=prog, description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    g = ap.add_mutually_exclusive_group(required=True)
    g.add_argument("--config", help="the twin's configuration file (TOML)")
    g.add_argument(
        "--demo",
        action="store_true",
        help="start the simulated pump PLC, subscribe the twin to it over OPC UA, write SQLite",
    )
    ap.add_argument(
        "--seconds",
        default=None,
        help="with --demo: stop after this long (a finite number > 0; exit 0, the run resumable)",
    )
    ap.add_argument(
        "--page-port",
        type=int,
        default=8050,
        help="with --demo: the live page's port on 127.0.0.1 (0: any free port)",
    )
    ap.add_argument(
        "--db",
        default=str(artifacts.results_dir() / "twin" / "demo.sqlite"),
        help="with --demo: the database",
    )
    ap.add_argument(
        "--force-step",
        type=float,
        default=None,
        help="with --demo: the process force [N] the PLC adds from 3 s to 8 s of the sample, "
        "which raises and clears the example's torque and rod force alarms (default 2000; 0: "
        "the sample as shipped)",
    )
    ap.add_argument(
        "--stop-cycle",
        type=int,
        default=None,
        metavar="N",
        help="with --demo: the PLC plays N stop/start cycles (ramp down, rollback, dither, "
        "standstill, ramp up; 22 s each) instead of the sample",
    )
    ap.add_argument(
        "--status",
        action="store_true",
        help="with --config: each database's size, bytes per sample, and days until its disk is "
        'full at the current rate (docs/plant.md "Retention")',
    )
    a = ap.parse_args(argv)
    if a.status:
        if not a.config:
            raise UserError("--status: only with --config (the databases it names)")
        return _status(a.config)
    if a.stop_cycle is not None and (a.stop_cycle < 1 or not a.demo):
        raise UserError(f"--stop-cycle {a.stop_cycle}: a whole number >= 1, with --demo")
    if a.seconds is not None:
        if not a.demo:
            raise UserError("--seconds: only with --demo (a configured run ends with its input)")
        a.seconds = positive_float("--seconds", a.seconds)
    if a.demo:
        from ..plant.demo import FORCE_STEP, demo

        step = FORCE_STEP if a.force_step is None else a.force_step
        return demo(a.db, a.seconds, a.page_port, force_step=step, stop_cycles=a.stop_cycle)
    from ..plant.pipeline import run_config

    return run_config(a.config)


def _status(path: str) -> int:
    from ..plant.config import ConfigError, load
    from ..plant.query import QueryError, status

    try:
        cfg = load(path)
    except ConfigError as e:
        raise UserError(str(e)) from None
    for s in cfg.sinks:
        if s.type == "csv":
            continue
        try:
            for line in status(s.settings.get("path") or s.settings["dsn"], s.password):
                print(line)
        except QueryError as e:
            print(e)
    return 0


if __name__ == "__main__":
    sys.exit(main())
