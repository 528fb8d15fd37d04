"""Lines of a CSV input as they arrive: a file, a pipe (standard input) or a growing file
(docs/twin.md "Input" and "Live mode"). Shared by `rdrive twin` and the plant pipeline's stream
source (docs/plant.md "Sources").

Layer: workflows, the twin (docs/architecture.md).
"""

from __future__ import annotations

import os
import select
import stat
import time

from .core import DataError


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
