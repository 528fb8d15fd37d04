#!/usr/bin/env python3
"""Runs a design study (a TOML study file, docs/sweeps.md) on Dask and writes
<out>/<study>.parquet, <out>/<study>.csv and <out>/<study>.png.

    rdrive sweep studies/kvo630_resonance.toml
    rdrive sweep STUDY --workers 2               # LocalCluster with 2 workers
    rdrive sweep STUDY --scheduler tcp://host:8786  # an existing cluster

The paths above are those of a checkout, or of a folder made by `rdrive examples DIR` (the sample
data, configurations and studies of an installed package).

A killed or stopped sweep resumes: run the same command again and only the missing cases are
computed. A result file of another study or FMU is refused; --fresh discards it and starts afresh.
Exit codes: 0 done, 1 every case rejected, 2 a user error, 70 an internal error, 130 stopped.
"""

# Layer: commands (docs/architecture.md); a comment, as --help prints the docstring.

from __future__ import annotations

import argparse
import pathlib
import shlex
import sys

from .. import artifacts
from ..cli_errors import (
    ArgumentParser,
    RunFailed,
    UserError,
    positive_float,
    run_cli,
)
from ..sweeps.study import DEFAULT_MAX_CASES, check_fmu, load_study
from . import prefix

PROG = "sweep.py"
STATE: dict = {}


def _count(name: str, minimum: int):
    def parse(text: str) -> int:
        try:
            n = int(text)
        except (ValueError, TypeError):  # TypeError: argparse gives a list for "--opt=--"
            raise UserError(f"{name} {text!r}: not an integer; allowed: >= {minimum}") from None
        if n < minimum:
            raise UserError(f"{name} {n}; allowed: an integer >= {minimum}")
        return n

    return parse


def parser(prog: str = PROG) -> ArgumentParser:
    ap = ArgumentParser(
        prog=prog,
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    ap.add_argument("study", type=pathlib.Path)
    ap.add_argument("--fmu", default=str(artifacts.fmu()))
    ap.add_argument("--out-dir", type=pathlib.Path, default=artifacts.results_dir() / "sweeps")
    ap.add_argument(
        "--scheduler",
        default=None,
        help="address of a running Dask scheduler (default: a LocalCluster)",
    )
    ap.add_argument(
        "--connect-timeout",
        default="10",
        help="seconds to wait for the scheduler's answer (default 10)",
    )
    ap.add_argument("--workers", default=None, help="LocalCluster workers (default: one per core)")
    ap.add_argument(
        "--batch-size",
        default=None,
        help="cases per Dask task (default: about a second of work each)",
    )
    ap.add_argument(
        "--max-cases",
        default=None,
        help=f"refuse a study of more cases than this (default {DEFAULT_MAX_CASES:,})",
    )
    ap.add_argument(
        "--stop-after", default=None, help="compute at most this many new cases, then stop"
    )
    ap.add_argument(
        "--fresh",
        "--restart",
        action="store_true",
        help="discard the results of an earlier run of this study in --out-dir and start afresh",
    )
    ap.add_argument("--no-progress", action="store_true")
    return ap


def resume_hint() -> str:
    argv = [a for a in sys.argv[1:] if a not in ("--fresh", "--restart")]
    p = STATE.get("progress")
    done = ""
    if p is not None and p.csv is not None:
        done = f" ({p.found + p.computed} cases in {p.csv})"
    # Through rdrive its launcher is the command; a checkout's script runs with the interpreter.
    run = [sys.argv[0]] if prefix("") else [sys.executable, sys.argv[0]]
    return f"stopped{done}; resume with: {shlex.join([*run, *argv])}"


def main(argv=None, prog: str = PROG) -> int:
    """The command: its exit code, with every error as one line (cli_errors.run_cli)."""
    return run_cli(prog, lambda: _main(argv, prog), on_interrupt=resume_hint)


def _main(argv, prog: str) -> int:
    a = parser(prog).parse_args(argv)
    workers = None if a.workers is None else _count("--workers", 1)(a.workers)
    batch = None if a.batch_size is None else _count("--batch-size", 1)(a.batch_size)
    max_cases = None if a.max_cases is None else _count("--max-cases", 1)(a.max_cases)
    stop_after = None if a.stop_after is None else _count("--stop-after", 1)(a.stop_after)
    timeout = positive_float("--connect-timeout", a.connect_timeout)
    if timeout > 3600:
        raise UserError(f"--connect-timeout {a.connect_timeout}; allowed: > 0 and <= 3600 s")
    if a.scheduler is not None and workers is not None:
        raise UserError("--workers: applies to the LocalCluster only; not with --scheduler")
    check_fmu(a.fmu)
    # Everything is validated before a cluster starts (docs/sweeps.md "Errors and exit codes").
    study = load_study(a.study, fmu=a.fmu, max_cases=max_cases)
    if a.scheduler is not None:
        from ..sweeps.sweep import scheduler_address

        scheduler_address(a.scheduler)

    from ..sweeps.plots import plot_sweep
    from ..sweeps.sweep import Progress, load_rows, run_sweep, warnings

    for w in warnings(study):
        print(f"warning: {w}", flush=True)

    STATE["progress"] = Progress()
    r = run_sweep(
        study,
        a.fmu,
        a.out_dir,
        scheduler=a.scheduler,
        workers=workers,
        batch_size=batch,
        progress=not a.no_progress,
        stop_after=stop_after,
        fresh=a.fresh,
        connect_timeout=timeout,
        state=STATE["progress"],
    )
    rows = load_rows(r.csv, study)
    png = a.out_dir / f"{study.name}.png"
    plot_sweep(study, rows, png)
    rate = r.computed / r.wall if r.wall > 0 and r.computed else 0
    print(
        f"{study.name}: {r.computed} cases computed, {r.skipped} found in {r.csv}, "
        f"{r.rejected} rejected; {rate:.1f} cases/s on {r.workers} worker(s)"
    )
    print(f"wrote {r.parquet}, {r.csv} and {png}")
    if r.total and r.rejected == r.total:
        first = next(x["message"] for x in rows if x["status"] != "ok")
        raise RunFailed(f"every case ({r.total}) was rejected by the FMU; the first: {first}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
