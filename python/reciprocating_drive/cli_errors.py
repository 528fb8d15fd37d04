"""How the command-line tools end (docs/sweeps.md "Errors and exit codes"): a user error is ONE line
on stderr naming the file, key or option, the value and what is allowed; Ctrl-C is one line saying
how to resume; a bug is one line saying where its details were written. No traceback reaches a user.

    def main(argv=None) -> int: ...
    if __name__ == "__main__":
        sys.exit(run_cli("sweep.py", main))

Exit codes: 0 done, 1 the run finished but its result is not usable (every case rejected, a loop
that diverged), 2 a user error, 70 an internal error, 130 stopped by Ctrl-C or SIGTERM.

Layer: shared, below the FMU access (docs/architecture.md).
"""

from __future__ import annotations

import argparse
import datetime
import os
import pathlib
import signal
import sys
import tempfile
import tomllib
import traceback
from collections.abc import Callable

EXIT_OK = 0
EXIT_FAILED = 1
EXIT_USAGE = 2
EXIT_INTERNAL = 70
EXIT_INTERRUPTED = 130


class UserError(Exception):
    """An error in what the user gave (a file, a key, an option): its text is the whole message,
    one line naming what is wrong, the value and what is allowed."""

    exit_code = EXIT_USAGE


class RunFailed(Exception):
    """The run finished but its result must not be taken for a good one (exit code 1)."""

    exit_code = EXIT_FAILED


class Interrupted(Exception):
    """Ctrl-C or SIGTERM, with what to do next ("resume with ...")."""

    exit_code = EXIT_INTERRUPTED


def one_line(text: object, limit: int = 4000) -> str:
    """`text` on a single line (newlines folded), cut to `limit` characters."""
    s = " ".join(str(text).split())
    return s if len(s) <= limit else s[: limit - 1] + "…"


def show(value: object, limit: int = 60) -> str:
    """A value as it appears in a message: repr on one line, cut when long."""
    return one_line(repr(value), limit)


class ArgumentParser(argparse.ArgumentParser):
    """argparse with a one-line error (argparse's own prints the usage first)."""

    def parse_args(self, args=None, namespace=None):
        ns = super().parse_args(args, namespace)
        # argparse takes "--opt=--" for an empty list of values: the option has no value.
        for action in self._actions:
            if not action.option_strings or action.nargs is not None:
                continue
            v = getattr(ns, action.dest, None)
            items = (v or []) if isinstance(action, argparse._AppendAction) else [v]
            if any(isinstance(x, list) for x in items):
                self.error(f"argument {'/'.join(action.option_strings)}: expected one argument")
        return ns

    def error(self, message: str):  # noqa: D401 - argparse's interface
        print(one_line(f"{self.prog}: {message} (see {self.prog} --help)"), file=sys.stderr)
        raise SystemExit(EXIT_USAGE)


def positive_float(name: str, value: str, *, allow_zero: bool = False) -> float:
    """Parses an option's value as a finite number > 0 (>= 0 with allow_zero)."""
    if not isinstance(value, str):  # argparse gives a list for "--opt=--"
        raise UserError(f"{name}: a value is needed; allowed: a finite number")
    try:
        x = float(value)
    except ValueError:
        raise UserError(f"{name} {show(value)}: not a number; allowed: a finite number") from None
    ok = x >= 0 if allow_zero else x > 0
    if not (ok and x == x and abs(x) != float("inf")):
        allowed = ">= 0" if allow_zero else "> 0"
        raise UserError(f"{name} {value}: allowed: a finite number {allowed}")
    return x


def read_toml(path, error: type[Exception] = UserError, what: str = "a TOML file") -> dict:
    """A TOML file parsed, or `error` with one line naming the file: unreadable, a path with a
    NUL character, bytes that are not UTF-8, not TOML, or nested deeper than the parser goes
    (tomllib recurses once per level: 100 000 nested arrays exhaust Python's stack)."""
    p = str(path)
    try:
        data = pathlib.Path(p).read_bytes()
    except ValueError:  # "embedded null byte": the operating system takes no such path
        raise error(f"{show(p)}: a path with a NUL character; allowed: {what}") from None
    except IsADirectoryError:
        raise error(f"{p}: is a folder; allowed: {what}") from None
    except OSError as e:
        raise error(f"{p}: cannot read {what}: {e.strerror or e}") from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as e:
        raise error(f"{p}: byte {e.start} is not UTF-8; allowed: {what} in UTF-8") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise error(f"{p}: not valid TOML: {one_line(e, 200)}") from None
    except RecursionError:
        raise error(
            f"{p}: tables or arrays nested too deep to read; allowed: {what} of a few levels"
        ) from None


def _raise_interrupt(signum, _frame):
    raise KeyboardInterrupt


def _write_details(prog: str) -> pathlib.Path:
    stamp = datetime.datetime.now().strftime("%Y%m%d-%H%M%S")
    fd, name = tempfile.mkstemp(prefix=f"{prog.removesuffix('.py')}-{stamp}-", suffix=".txt")
    with os.fdopen(fd, "w") as f:
        f.write(f"{prog} {' '.join(sys.argv[1:])}\n\n")
        traceback.print_exc(file=f)
    return pathlib.Path(name)


def run_cli(
    prog: str, main: Callable[[], int], on_interrupt: Callable[[], str] | None = None
) -> int:
    """Runs `main` and turns every way it can end into an exit code and at most one line on
    stderr. SIGTERM is handled like Ctrl-C. `on_interrupt` returns the line printed after Ctrl-C
    (default "stopped")."""
    signal.signal(signal.SIGTERM, _raise_interrupt)
    try:
        return main()
    except (UserError, RunFailed, Interrupted) as e:
        print(one_line(f"{prog}: {e}"), file=sys.stderr)
        return e.exit_code
    except KeyboardInterrupt:
        # A second Ctrl-C while the message is printed must not bring the traceback back.
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        text = on_interrupt() if on_interrupt is not None else "stopped"
        print(one_line(f"{prog}: {text}"), file=sys.stderr)
        return EXIT_INTERRUPTED
    except SystemExit:
        raise
    except BaseException as e:
        try:
            where = f"details written to {_write_details(prog)}"
        except OSError:
            where = "no details written"
        print(
            one_line(
                f"{prog}: internal error ({type(e).__name__}: {one_line(e, 160)}); please report it "
                f"with the command line; {where}"
            ),
            file=sys.stderr,
        )
        return EXIT_INTERNAL
