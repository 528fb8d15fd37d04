"""Lines of a CSV input as they arrive: a file, a pipe (standard input) or a growing file
(docs/twin.md "Input" and "Live mode"), and the CSV reader that makes samples of them
(`parse_header`, `parse_lines`: numbers for the twin's core, `samples.Samples`). Shared by
`rdrive twin` and the plant pipeline's CSV and stream sources (docs/plant.md "Sources").

Layer: workflows, the twin (docs/architecture.md).
"""

from __future__ import annotations

import math
import os
import re
import select
import stat
import time

import numpy as np

from ..fmu.batch import parse_csv
from ..timestamps import LOOKS_ISO
from .samples import OPTIONAL, REQUIRED, DataError, Samples


class InputChanged(Exception):
    """The followed input was truncated or replaced (docs/twin.md "Live mode")."""


class Idle(Exception):
    """No new input for --idle-limit seconds."""


def chunks_of(raw, follow: bool, size: int, poll: float = 0.05, path=None, idle=None, stop=None):
    """Lists of consecutive lines of a binary stream, each list as soon as it is available: one
    read blocks until there is at least one complete line, and takes whatever else has arrived
    (a pipe or a growing file gives what is there now; a file gives blocks of `size` bytes). A
    line 'EOF' ends the input in every mode (docs/twin.md "Input"); in a file, a line after it
    that is not blank is an error. With `follow`, waits for more at the end of the file `path`:
    a line still being written waits for its end; the file shrinking or being replaced (another
    inode at `path`) raises InputChanged. A wait longer than `idle` seconds raises Idle; `stop()`
    true ends the input where it is. Bytes that are not UTF-8 become U+FFFD (and are reported as
    not a number)."""
    tail = b""
    pos = 0  # bytes read
    lineno = 0  # complete lines yielded
    waited = 0.0
    fd = raw.fileno() if hasattr(raw, "fileno") else None
    pipe = fd is not None and not follow and not stat.S_ISREG(os.fstat(fd).st_mode)
    while True:
        if stop is not None and stop():
            return
        if pipe:
            # A bounded wait, so that Ctrl-C and --idle-limit are seen while no data comes.
            ready, _, _ = select.select([fd], [], [], poll * 4)
            if not ready:
                waited += poll * 4
                if idle is not None and waited >= idle:
                    raise Idle(f"no new input for {idle:g} s (--idle-limit)")
                continue
        data = raw.read(size)
        if data is None:  # a non-blocking source with nothing now
            data = b""
        if not data:
            if follow:
                try:
                    st = os.stat(path)
                except FileNotFoundError:
                    raise InputChanged(
                        f"{path} was removed after line {lineno}: following it ends here"
                    ) from None
                here = os.fstat(fd)
                if (st.st_ino, st.st_dev) != (here.st_ino, here.st_dev):
                    raise InputChanged(
                        f"{path} was replaced (another file now has its name) after line "
                        f"{lineno}: the new file is not read; restart the twin on it"
                    )
                if here.st_size < pos:
                    raise InputChanged(
                        f"{path} was truncated from {pos} to {here.st_size} bytes after line "
                        f"{lineno}: what was rewritten is not read; restart the twin on it"
                    )
                time.sleep(poll)
                waited += poll
                if idle is not None and waited >= idle:
                    raise Idle(f"no new data in {path} for {idle:g} s (--idle-limit)")
                continue
            if tail:
                line = tail.decode("utf-8", "replace")
                if line.strip() != "EOF":
                    yield [line]
            return
        waited = 0.0
        pos += len(data)
        data = tail + data
        cut = data.rfind(b"\n")
        if cut < 0:
            tail = data
            continue
        lines, tail = data[:cut].decode("utf-8", "replace").split("\n"), data[cut + 1 :]
        ends = [i for i, line in enumerate(lines) if line.strip() == "EOF"]
        if ends:
            if ends[0]:
                yield lines[: ends[0]]
            at = lineno + ends[0] + 1
            if not follow and not pipe:
                rest = lines[ends[0] + 1 :] + [tail.decode("utf-8", "replace")]
                rest += raw.read().decode("utf-8", "replace").split("\n")
                k = next((i for i, line in enumerate(rest) if line.strip()), None)
                if k is not None:
                    raise DataError(
                        f"line {at + 1 + k}: data after the line 'EOF' (line {at}), "
                        "which ends the input"
                    )
            return
        lineno += len(lines)
        yield lines


_NUMBER = re.compile(  # ASCII: \d would match any script's digits
    r"[+-]?(?:\d+\.?\d*(?:[eE][+-]?\d+)?|\.\d+(?:[eE][+-]?\d+)?|inf|infinity|nan)", re.I | re.ASCII
)

#: Decimal comma to point and ';' to ',' (a ';'-separated file with decimal commas, docs/twin.md).
_EUROPEAN = str.maketrans({",": ".", ";": ","})


def detect_separator(line: str) -> str:
    """',' or ';': the separator of a header line (';' when it has a ';' and no ',')."""
    return ";" if ";" in line and "," not in line else ","


def parse_header(line: str, separator: str = ",") -> dict:
    """Column name -> field index of the header line. A UTF-8 byte-order mark and quotes around
    a name are removed; a name given twice, or no `time` or `crank_angle`, is an error."""
    line = line.lstrip("\ufeff")
    names = [c.strip().strip('"').strip() for c in line.strip().split(separator)]
    cols: dict = {}
    for i, n in enumerate(names):
        if n in cols and n:
            raise DataError(
                f"line 1: the header names {n!r} twice (columns {cols[n] + 1} and {i + 1})"
            )
        cols.setdefault(n, i)
    for need in ("time", "crank_angle"):
        if need not in cols:
            shown = ", ".join(repr(n) for n in names)
            raise DataError(f"line 1: the header must name '{need}' (found: {shown})")
    cols["\0fields"] = len(names)
    return cols


def n_fields(cols: dict) -> int:
    """The number of fields of a data line (the header's)."""
    return cols.get("\0fields", len(cols))


def columns_of(cols: dict) -> list[str]:
    """The input columns a header names, in the order of `samples.Samples.names`."""
    return [c for c in (*REQUIRED, *OPTIONAL) if c in cols]


def parse_line(line: str, lineno: int, cols: dict) -> list[float]:
    """The numbers of one data line, in the order of `columns_of(cols)`."""
    parts = line.strip().split(",")
    if len(parts) != n_fields(cols):
        raise DataError(f"line {lineno}: {len(parts)} fields, the header names {n_fields(cols)}")

    def num(name):
        raw = parts[cols[name]].strip()
        if raw == "":
            raise DataError(f"line {lineno}: {name} is empty (a number is needed)")
        if not _NUMBER.fullmatch(raw):
            if name == "time" and LOOKS_ISO.match(raw):
                raise DataError(
                    f"line {lineno}: time = {raw!r} is an ISO 8601 timestamp, but the first "
                    "sample's time is a number (seconds): one format per input"
                )
            raise DataError(f"line {lineno}: {name} = {raw!r} is not a number")
        v = float(raw)
        if not math.isfinite(v):
            raise DataError(f"line {lineno}: {name} = {raw!r} is not a finite number")
        return v

    return [num(c) for c in columns_of(cols)]


def parse_lines(
    lines: list[str], first_lineno: int, cols: dict
) -> tuple[Samples, DataError | None]:
    """Consecutive data lines (the first is line `first_lineno`) as `Samples` (each with its line
    number; a column the header does not name takes its default), blank lines skipped. Returns
    the samples of the lines before the first bad one and its DataError (or None). The clean lines
    are parsed natively (`batch.parse_csv`), from the first other one on in Python."""
    names = columns_of(cols)
    # Every field is required: an empty field is an error (docs/twin.md "Input").
    defaults = [None] * len(names)
    n, pos, parts = len(lines), 0, []
    while pos < n:
        got = parse_csv(
            "\n".join(lines[pos:]).encode(),
            n_fields(cols),
            [cols[c] for c in names],
            defaults,
            n - pos,
        )
        k = len(got[0])
        parts.append(
            Samples(dict(zip(names, got)), np.arange(first_lineno + pos, first_lineno + pos + k))
        )
        pos += k
        if pos < n:
            # One line for Python: blank, bad (the message), or a number only Python reads.
            part, err = _parse_slowly(lines[pos : pos + 1], first_lineno + pos, cols)
            parts.append(part)
            pos += 1
            if err is not None:
                return Samples.concat(parts), err
    if not parts:
        return _parse_slowly([], first_lineno, cols)
    return Samples.concat(parts), None


def _parse_slowly(lines, first_lineno, cols):
    """parse_lines line by line: finds the first bad line and its message."""
    names = columns_of(cols)
    out, err = [], None
    for i, line in enumerate(lines):
        if not line.strip():
            continue
        try:
            out.append((first_lineno + i, *parse_line(line, first_lineno + i, cols)))
        except DataError as e:
            err = e
            break
    cols_ = list(zip(*out)) if out else [()] * (1 + len(names))
    columns = {c: np.array(v, dtype=float) for c, v in zip(names, cols_[1:])}
    return Samples(columns, np.array(cols_[0], dtype=np.int64)), err
