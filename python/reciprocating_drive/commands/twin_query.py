#!/usr/bin/env python3
"""A range of a plant run's per-sample outputs, recomputed from its stored input (docs/plant.md
"Recomputing a range"), bit for bit what the live run computed, as CSV or Parquet.

    rdrive twin-query --db results/twin/sample-replay.sqlite --run sample-replay \\
        --from 2 --to 4 --out range.csv
    rdrive twin-query --config examples/twin/replay-postgres.toml --from 3600 --to 7200 \\
        --out hour.parquet

Times are seconds of the run's own time (the samples table's `t`). The FMU is the run's (its
GUID is stored); another is refused unless --other-fmu.
"""

from __future__ import annotations

import argparse
import os
import sys

from .. import artifacts
from ..cli_errors import ArgumentParser, RunFailed, UserError, run_cli


def main(argv=None, prog: str | None = None) -> int:
    prog = prog or "twin_query.py"
    return run_cli(prog, lambda: _main(argv, prog))


def _number(name: str, v: str) -> float:
    import math

    try:
        x = float(v)
    except (TypeError, ValueError):
        x = math.nan
    if not math.isfinite(x):
        raise UserError(f"{name} {v!r}: allowed: a finite number of seconds of the run's time")
    return x


def _main(argv, prog: str) -> int:
    ap = ArgumentParser(
        prog=prog, description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    g = ap.add_mutually_exclusive_group(required=True)
    g.add_argument("--db", help="an SQLite database of `rdrive plant`")
    g.add_argument(
        "--config", help="a plant configuration: its first database sink, run.id and run.fmu"
    )
    ap.add_argument("--run", help="the run's name (run.id; default: the configuration's)")
    ap.add_argument("--from", dest="t_from", required=True, help="s of the run's time")
    ap.add_argument("--to", dest="t_to", required=True, help="s of the run's time")
    ap.add_argument("--out", required=True, help="a .csv or .parquet file, or - (CSV on stdout)")
    ap.add_argument(
        "--fmu", default=None, help="the FMU (default: the configuration's, or the package's)"
    )
    ap.add_argument(
        "--other-fmu",
        action="store_true",
        help="recompute with --fmu even though it is not the FMU the run used (its own results)",
    )
    ap.add_argument(
        "--workers",
        type=int,
        default=None,
        help="processes recomputing the stretches between snapshots at once (default: the "
        "machine's cores, at most 2)",
    )
    a = ap.parse_args(argv)
    workers = a.workers if a.workers is not None else min(2, os.cpu_count() or 1)
    if workers < 1:
        raise UserError(f"--workers {a.workers}: allowed: a whole number >= 1")
    t0, t1 = _number("--from", a.t_from), _number("--to", a.t_to)
    if t1 < t0:
        raise UserError(f"--to {a.t_to}: before --from {a.t_from}")
    if not (a.out == "-" or a.out.endswith((".csv", ".parquet"))):
        raise UserError(f"--out {a.out!r}: allowed: a file ending .csv or .parquet, or -")
    target, password, run, fmu = a.db, None, a.run, a.fmu
    if a.config:
        from ..plant.config import ConfigError, load

        try:
            cfg = load(a.config)
        except ConfigError as e:
            raise UserError(str(e)) from None
        db = next((s for s in cfg.sinks if s.type in ("sqlite", "postgres")), None)
        if db is None:
            raise UserError(f"--config {a.config}: no sqlite or postgres [[sink]]")
        target = db.settings.get("path") or db.settings["dsn"]
        password, run, fmu = db.password, run or cfg.run_id, fmu or cfg.fmu
    if run is None:
        raise UserError("--run: the run's name is needed with --db")
    from ..plant.query import QueryError, write_range

    try:
        n = write_range(
            target,
            run,
            t0,
            t1,
            a.out,
            fmu=fmu or str(artifacts.fmu()),
            other_fmu=a.other_fmu,
            password=password,
            workers=workers,
        )
    except QueryError as e:
        raise RunFailed(str(e)) from None
    if a.out != "-":
        print(f"{n} samples of run {run!r} from t = {t0:g} s to {t1:g} s written to {a.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
