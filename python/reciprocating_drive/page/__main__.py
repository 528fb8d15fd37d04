"""The twin's page beside a running twin (docs/page.md, "Beside a twin"):

    python -m reciprocating_drive.page --database twin.sqlite [--run NAME] [--limits FILE]
        [--host 127.0.0.1] [--port 8050] [--token-file FILE] [--poll 0.25]

Serves the page of the run the database holds (the most recent one unless --run names it) and
follows what the twin commits. Bound to any address but 127.0.0.1 it needs an access token, read
from --token-file or the environment variable RD_PAGE_TOKEN (never from the command line, where
`ps` would show it). Errors are one line and a non-zero exit; stopped by SIGINT or SIGTERM.
"""

# Layer: workflows, the page (docs/architecture.md); a comment, as --help prints the docstring.

from __future__ import annotations

import argparse
import os
import signal
import sys
import tempfile
import threading
import traceback

from ..alarms import LimitsError, load_limits
from .follow import Follower
from .history import HistoryError
from .server import PageError, PageServer


class _Args(argparse.ArgumentParser):
    def error(self, message):
        print(f"page: {message} (see --help)", file=sys.stderr)
        sys.exit(2)


def read_token(path: str | None) -> str | None:
    if path:
        try:
            with open(path, encoding="utf-8") as f:
                tok = f.read().strip()
        except OSError as e:
            raise PageError(f"page: --token-file {path}: cannot read it: {e.strerror}") from None
        if not tok:
            raise PageError(f"page: --token-file {path}: the file is empty")
        return tok
    return os.environ.get("RD_PAGE_TOKEN") or None


def main(argv=None) -> int:
    ap = _Args(prog="python -m reciprocating_drive.page", description=__doc__.split("\n\n")[0])
    ap.add_argument("--database", required=True, help="the twin's SQLite database")
    ap.add_argument("--run", help="the run's name (default: the most recent run)")
    ap.add_argument("--limits", help="alarm limits file (TOML, docs/page.md)")
    ap.add_argument("--host", default="127.0.0.1", help="address to bind (default 127.0.0.1)")
    ap.add_argument("--port", type=int, default=8050, help="port (default 8050; 0: any free)")
    ap.add_argument("--token-file", help="file holding the access token (else RD_PAGE_TOKEN)")
    ap.add_argument("--poll", type=float, default=0.25, help="seconds between database polls")
    ap.add_argument("--title", default="ReciprocatingDrive twin")
    a = ap.parse_args(argv)
    if not (0 <= a.port <= 65535):
        return _fail(f"page: --port {a.port}: must be 0 to 65535", 2)
    if not (0.01 <= a.poll <= 60):
        return _fail(f"page: --poll {a.poll:g}: must be 0.01 to 60 seconds", 2)
    if not os.path.isfile(a.database):
        return _fail(f"page: --database {a.database}: no such file", 2)
    try:
        limits = load_limits(a.limits) if a.limits else None
        token = read_token(a.token_file)

        def log_alarm(ch):
            print(f"page: {ch.message}", file=sys.stderr, flush=True)

        page = PageServer(
            a.host, a.port, token, a.database, a.run, limits, a.title, on_alarm=log_alarm
        )
        page.follows = True
        if a.run:
            # The range form recomputes from the run's stored input (docs/plant.md "Recomputing a
            # range"); this command is the one place of the page that knows the plant's storage.
            from ..plant.query import page_recompute

            page.recompute = page_recompute(a.database, a.run)
        warmup = max((t.recent + t.reference for t in limits.trends), default=0.0) if limits else 0
        follower = Follower(a.database, page, a.run, warmup)
        page.start()
    except (PageError, LimitsError, HistoryError) as e:
        return _fail(str(e), 2)
    stop = threading.Event()

    def on_signal(_sig, _frame):
        stop.set()

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    print(f"page: serving {a.database} on {page.url}", file=sys.stderr, flush=True)
    try:
        follower.run_forever(a.poll, stop, log=lambda m: print(m, file=sys.stderr, flush=True))
    except HistoryError as e:
        return _fail(str(e), 1)
    except Exception:  # noqa: BLE001 - a bug: one line for the user, the details in a file
        fd, where = tempfile.mkstemp(prefix="twin-page-", suffix=".txt")
        with os.fdopen(fd, "w") as f:
            traceback.print_exc(file=f)
        return _fail(f"page: internal error; please report it with the details in {where}", 3)
    finally:
        page.close()
        follower.close()
    return 0


def _fail(msg: str, code: int) -> int:
    print(msg, file=sys.stderr, flush=True)
    return code


if __name__ == "__main__":
    sys.exit(main())
