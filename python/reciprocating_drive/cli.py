"""`rdrive`: the one command of the package; its subcommands are the workflows.

    rdrive run [PRESET]          the main job: simulate a machine over whole revolutions
    rdrive twin ...              the digital twin (measured crank data in, loads out)
    rdrive plant --config F      the twin in a plant (OPC UA, SQLite/PostgreSQL, live page)
    rdrive twin-query ...        a range of a plant run's outputs, recomputed from its input
    rdrive plc-sim ...           a simulated pump PLC (OPC UA server) for demos and tests
    rdrive sweep STUDY ...       a design sweep on Dask
    rdrive closed-loop ...       the pump and its drive train in one system
    rdrive examples DIR          copy the examples (data, configurations, studies) into DIR
    rdrive fmu-path [MODEL]      the path of an FMU, for other importers

`rdrive --version`, and `--help` on each. Exit codes (docs/install.md): 0 success, 1 a run that
failed (the FMU refused, every case was rejected, the data stopped the run), 2 a usage or input
error (a bad option, file or value: one line saying which), 70 an internal error (one line saying
where its details were written), 128 + N stopped by signal N (130 Ctrl-C, 143 SIGTERM; a resumable
run says how to resume).

Layer: commands (docs/architecture.md).
"""

from __future__ import annotations

import argparse
import sys

from . import __version__, artifacts

#: subcommand -> (module under reciprocating_drive.commands, one-line help)
COMMANDS = {
    "run": ("simulate", "the main job: simulate a machine over whole crank revolutions"),
    "twin": ("twin", "the digital twin: measured crank data in, the FMU's loads out"),
    "plant": ("twin_plant", "the twin in a plant: a configuration file (OPC UA, databases, page)"),
    "twin-query": (
        "twin_query",
        "a range of a plant run's outputs, recomputed bit for bit from its stored input",
    ),
    "plc-sim": ("plc_sim", "a simulated pump PLC: an OPC UA server playing crank data"),
    "sweep": ("sweep", "a design sweep on Dask (a local cluster, or --scheduler)"),
    "closed-loop": ("closed_loop", "the pump and its drive train in one SSP system"),
    "examples": ("examples", "copy the example data, configurations and studies into a folder"),
}


def _fmu_path(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(
        prog="rdrive fmu-path",
        description="Print the path of an FMU shipped with this package, for other importers "
        "(fmpy, libcosim, OMSimulator, a system simulator).",
    )
    ap.add_argument("model", nargs="?", default="ReciprocatingDrive", choices=artifacts.MODELS)
    a = ap.parse_args(argv)
    path = artifacts.fmu(a.model)
    if not path.is_file():
        print(
            f"rdrive fmu-path: {path} not found: build it with scripts/build-fmu.sh (in a "
            "checkout; an installed package carries it)",
            file=sys.stderr,
        )
        return 1
    print(path)
    return 0


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    ap = argparse.ArgumentParser(
        prog="rdrive",
        description="ReciprocatingDrive: FMUs of crank-driven reciprocating mechanisms and their "
        "workflows. `rdrive COMMAND --help` describes each command.",
    )
    ap.add_argument("--version", action="version", version=f"rdrive {__version__}")
    sub = ap.add_subparsers(dest="command", metavar="COMMAND")
    for name, (_, text) in COMMANDS.items():
        sub.add_parser(name, help=text, add_help=False)
    sub.add_parser("fmu-path", help="print the path of an FMU, for other importers", add_help=False)
    if not argv or argv[0] in ("-h", "--help", "--version"):
        ap.parse_args(argv or ["--help"])
        return 0
    command, rest = argv[0], argv[1:]
    if command == "fmu-path":
        return _fmu_path(rest)
    if command not in COMMANDS:
        ap.print_usage(sys.stderr)
        print(
            f"rdrive: unknown command {command!r}; one of: {', '.join([*COMMANDS, 'fmu-path'])}",
            file=sys.stderr,
        )
        return 2
    from . import commands
    from .commands import load

    commands.RUNNING = f"rdrive {command}"
    module = load(COMMANDS[command][0])
    return int(module.main(rest, prog=f"rdrive {command}") or 0)


if __name__ == "__main__":
    sys.exit(main())
