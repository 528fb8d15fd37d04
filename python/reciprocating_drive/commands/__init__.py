"""The workflows' command-line entry points, each `main(argv=None, prog=None) -> exit code`:
`rdrive <command>` (cli.py) and the checkout's `scripts/<command>.py` run the same function.

| module | rdrive | scripts/ |
|---|---|---|
| simulate | run | simulate.py (scripts/run.sh) |
| twin | twin | twin.py |
| twin_plant | plant | twin_plant.py |
| plc_sim | plc-sim | plc_sim.py |
| sweep | sweep | sweep.py |
| closed_loop | closed-loop | closed_loop.py |

Layer: commands (docs/architecture.md).
"""

from __future__ import annotations

import signal
import sys

#: What a command's messages start with: `rdrive <command>` when run through rdrive (cli.py sets
#: it), else the checkout script's file name (`twin.py`).
RUNNING: str | None = None


def prefix(script: str) -> str:
    """The name a command's messages start with (RUNNING, or `script` in a checkout)."""
    return RUNNING or script


def load(module: str):
    """Imports a command's module. Ctrl-C while the modules load (numpy, fmpy, dask take a while)
    is a quiet stop with exit code 130, not a traceback; then Python's own handler is put back,
    under which Ctrl-C raises KeyboardInterrupt in the command, which handles it itself
    (cli_errors.run_cli: "stopped; resume with ...")."""
    import importlib

    signal.signal(signal.SIGINT, lambda signum, frame: sys.exit(130))
    mod = importlib.import_module(f"reciprocating_drive.commands.{module}")
    signal.signal(signal.SIGINT, signal.default_int_handler)
    return mod


def run_script(module: str) -> None:
    """The body of a checkout's scripts/<name>.py: the command's main, its exit code the
    process's."""
    sys.exit(load(module).main())
