#!/usr/bin/env python3
"""A simulated pump PLC (docs/plant.md): an OPC UA server on 127.0.0.1 playing a crank data file
(data/twin/pump_encoder.csv by default) in real time or faster, with scalar and block nodes and
history, optionally secured.

    rdrive plc-sim                       # real time, no security
    rdrive plc-sim --port 4840 --speed 4 --security SignAndEncrypt \\
        --cert-dir /tmp/plc --user operator --password-env PLC_PASSWORD

Prints "plc_sim: listening on opc.tcp://..." when ready. With --cert-dir the server's certificate
is written there (plc-sim.der), for the twin's trust list.
"""

# Layer: commands (docs/architecture.md); a comment, as --help prints the docstring.

from __future__ import annotations

import argparse
import asyncio
import math
import os
import pathlib
import sys

from .. import artifacts
from ..cli_errors import ArgumentParser, UserError, run_cli
from . import prefix

FAULTS = ("bad_status", "nan", "wrong_type", "double2", "block2d", "no_stamp")
#: Seconds the server stays up after "finished playing" unless --linger says otherwise: enough
#: for a subscriber's last notification (Pump.Finished among them), then it exits.
LINGER = 2.0


def fault(text: str):
    try:
        i, kind = text.split(":")
        if kind not in FAULTS:
            raise ValueError
        return int(i), kind
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"--fault {text!r}: give SAMPLE:KIND, KIND one of {', '.join(FAULTS)}"
        ) from None


def outage(text: str):
    try:
        t, s = (float(x) for x in text.split(":"))
        if not (math.isfinite(t) and math.isfinite(s) and t >= 0 and s > 0):
            raise ValueError
        return t, s
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"--outage {text!r}: give T:SECONDS (data time t >= 0, seconds > 0)"
        ) from None


def positive(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        v = math.nan
    if not (math.isfinite(v) and v > 0):
        raise argparse.ArgumentTypeError(f"{text!r} is not a number > 0")
    return v


def at_sample(option: str, kinds=None):
    """SAMPLE:SECONDS (a finite number) or, with `kinds`, SAMPLE:KIND."""

    def parse(text: str):
        try:
            i, v = text.split(":")
            i = int(i)
            if i < 0:
                raise ValueError
            if kinds is None:
                v = float(v)
                if not math.isfinite(v):
                    raise ValueError
            elif v not in kinds:
                raise ValueError
            return i, v
        except ValueError:
            what = "SECONDS (a finite number)" if kinds is None else "|".join(kinds)
            raise argparse.ArgumentTypeError(
                f"{option} {text!r}: give SAMPLE:{what}, SAMPLE a whole number >= 0"
            ) from None

    return parse


def history_fail(text: str) -> int:
    if text == "always":
        return -1
    try:
        v = int(text)
    except ValueError:
        v = -1
    if v < 0:
        raise argparse.ArgumentTypeError(
            f"--history-fail {text!r}: give N (a whole number >= 0) or always"
        )
    return v


def count(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        v = 0
    if v < 1:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number >= 1")
    return v


def port(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        v = -1
    if not 0 <= v <= 65535:
        raise argparse.ArgumentTypeError(f"{text!r} is not a port 0 to 65535 (0: a free one)")
    return v


def main(argv=None, prog: str | None = None) -> int:
    """The command: its exit code, with every error as one line (cli_errors.run_cli)."""
    prog = prog or "plc_sim.py"
    return run_cli(prog, lambda: _main(argv, prog))


def _main(argv, prog: str) -> int:
    ap = ArgumentParser(
        prog=prog, description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--data", default=str(artifacts.twin_sample()))
    ap.add_argument("--port", type=port, default=0, help="default: a free port")
    ap.add_argument("--speed", type=positive, default=1.0, help="multiple of real time")
    ap.add_argument("--block-ms", type=positive, default=50.0)
    ap.add_argument("--no-history", action="store_true")
    ap.add_argument(
        "--nodes", choices=("scalar", "block", "both"), default="both", help="which nodes to write"
    )
    ap.add_argument("--security", choices=("Sign", "SignAndEncrypt"), default=None)
    ap.add_argument("--cert-dir", default=None)
    ap.add_argument("--user", default=None)
    ap.add_argument("--password-file", default=None)
    ap.add_argument("--password-env", default=None)
    ap.add_argument("--fault", type=fault, action="append", default=[])
    ap.add_argument("--outage", type=outage, default=None)
    ap.add_argument("--origin", type=float, default=None, help="Unix seconds of t = 0")
    ap.add_argument(
        "--start-delay", type=float, default=0.0, help="seconds from listening to the first sample"
    )
    ap.add_argument(
        "--linger",
        type=float,
        nargs="?",
        const=math.inf,
        default=LINGER,
        help=f"seconds to stay up after the end (default {LINGER:g}: subscribers get the last "
        "values, then it exits); --linger alone: until stopped",
    )
    ap.add_argument(
        "--clock-glitch",
        type=at_sample("--clock-glitch"),
        default=None,
        help="SAMPLE:SECONDS: that one sample stamped SECONDS ahead (a PLC clock glitch)",
    )
    ap.add_argument(
        "--clock-step",
        type=at_sample("--clock-step"),
        default=None,
        help="SAMPLE:SECONDS: from that sample on, every stamp SECONDS earlier (a step back)",
    )
    ap.add_argument(
        "--duplicate",
        type=at_sample("--duplicate", ("same", "other")),
        default=None,
        help="SAMPLE:same|other: that sample's angle written again after the next sample, with "
        "its timestamp and the same or another value",
    )
    ap.add_argument(
        "--stamp-apart",
        type=int,
        default=0,
        help="µs between the angle's stamp and the speed's and force's of the same sample",
    )
    ap.add_argument(
        "--block-writes",
        choices=("together", "sequential"),
        default="together",
        help="block arrays stamped alike (together), or written one after another, each stamped "
        "by the server at its write, then the counter Pump.Block.Seq (sequential)",
    )
    ap.add_argument(
        "--history-fail",
        type=history_fail,
        default=0,
        metavar="N|always",
        help="the first N HistoryRead requests (or all) answered BadInternalError",
    )
    ap.add_argument(
        "--history-cap",
        type=count,
        default=0,
        metavar="M",
        help="at most M values per HistoryRead response (the rest through continuation points)",
    )
    ap.add_argument(
        "--history-order",
        choices=("written", "time"),
        default="written",
        help="HistoryRead values in the order written (written), or sorted by SourceTimestamp "
        "(time), as some servers answer",
    )
    ap.add_argument(
        "--silent",
        action="store_true",
        help="accept connections and never answer (a hung server); plays nothing",
    )
    ap.add_argument(
        "--stop-cycle",
        type=int,
        default=None,
        metavar="N",
        help="play N stop/start cycles (ramp down, rollback, dither, standstill, ramp up; "
        "4096-count encoder, 22 s each) instead of --data",
    )
    a = ap.parse_args(argv)
    if a.stop_cycle is not None:
        if a.stop_cycle < 1:
            print(
                f"{prefix('plc_sim.py')}: --stop-cycle {a.stop_cycle}: must be a whole number >= 1",
                file=sys.stderr,
            )
            return 2
        import tempfile

        from ..plant import stop_cycle

        cycles_dir = tempfile.TemporaryDirectory(prefix="plc-sim-")
        a.data = str(stop_cycle.write(pathlib.Path(cycles_dir.name) / "cycles.csv", a.stop_cycle))
    password = None
    if a.user:
        if a.password_file:
            try:
                password = pathlib.Path(a.password_file).read_text().strip("\r\n")
            except OSError as e:
                print(
                    f"{prefix('plc_sim.py')}: --password-file {a.password_file}: {e.strerror}",
                    file=sys.stderr,
                )
                return 2
        elif a.password_env and a.password_env in os.environ:
            password = os.environ[a.password_env]
        else:
            print(
                f"{prefix('plc_sim.py')}: --user needs --password-file or --password-env (set)",
                file=sys.stderr,
            )
            return 2
    if a.cert_dir:
        pathlib.Path(a.cert_dir).mkdir(parents=True, exist_ok=True)
    if a.port:
        # A port taken is one line here (asyncua would log its traceback when it fails to bind).
        import socket

        with socket.socket() as probe:
            try:
                probe.bind(("127.0.0.1", a.port))
            except OSError as e:
                raise UserError(
                    f"--port {a.port}: cannot listen on 127.0.0.1 ({e.strerror or e}); "
                    "choose another port, or 0 for a free one"
                ) from None
    from ..plant.plc_sim import PlcSim, serve

    try:
        sim = PlcSim(
            data=a.data,
            port=a.port,
            speed=a.speed,
            block_ms=a.block_ms,
            history=not a.no_history,
            security=a.security,
            user=a.user,
            password=password,
            cert_dir=a.cert_dir,
            faults=dict(a.fault),
            outage=a.outage,
            origin=a.origin,
            start_delay=a.start_delay,
            written=a.nodes,
            clock_glitch=a.clock_glitch,
            clock_step=a.clock_step,
            duplicate=a.duplicate,
            stamp_apart_us=a.stamp_apart,
            block_writes=a.block_writes,
            history_fail=a.history_fail,
            history_cap=a.history_cap,
            history_order=a.history_order,
            silent=a.silent,
        )
    except (OSError, ValueError) as e:
        print(f"{prefix('plc_sim.py')}: --data {a.data}: {e}", file=sys.stderr)
        return 2
    try:
        asyncio.run(serve(sim, a.linger))
    except KeyboardInterrupt:
        pass
    except OSError as e:  # the port taken by another program, or not ours to bind
        raise UserError(
            f"--port {sim.port}: cannot listen on 127.0.0.1 ({e.strerror or e})"
        ) from None
    return 0


if __name__ == "__main__":
    sys.exit(main())
