"""A CSV file as a source (docs/twin.md "Input"): its own lines go to the twin, so messages name
the file's line numbers. `pace` replays at that multiple of real time (0: as fast as possible).
A UTF-8 byte-order mark (spreadsheets write one) is skipped.

Layer: workflows, the plant (docs/architecture.md).
"""

from __future__ import annotations

import time

from ... import timestamps
from ...twin.core import detect_separator
from ..samples import Chunk


def _pace_seconds(field: str) -> float:
    """A time field as seconds for pacing: a number, or an ISO 8601 timestamp (docs/twin.md
    "Timestamps"; one without an offset is taken as UTC here: pacing needs only differences, and
    the twin itself reads it in its zone)."""
    try:
        return float(field)
    except ValueError:
        d = timestamps.parse(field)
        return (d if d.tzinfo else d.replace(tzinfo=timestamps.dt.UTC)).timestamp()


class CsvSource:
    rewindable = True

    def __init__(self, path: str, pace: float = 0.0, block: int | None = None):
        # Paced: blocks of about 250 lines, so the pace holds within a fraction of a second.
        self.path, self.pace = str(path), pace
        self.block = block or (1 << 12 if pace > 0 else 1 << 16)
        self.ended = False
        self.live = pace > 0  # paced: commits by time, as a live source
        self._it = None

    def start(self, lines_read: int = 0, last_t=None, time_origin=None) -> None:
        self._it = self._chunks(lines_read)

    def _chunks(self, skip: int):
        try:
            f = open(self.path, "rb")
        except OSError as e:
            raise OSError(f"source {self.path}: {e.strerror}") from None
        with f:
            tail, lineno, time_col, t0, wall0 = b"", 0, None, None, time.monotonic()
            while True:
                data = f.read(self.block)
                if not data:
                    lines = [tail.decode("utf-8", "replace")] if tail.strip() else []
                else:
                    data = tail + data
                    cut = data.rfind(b"\n")
                    if cut < 0:
                        tail = data
                        continue
                    lines = data[:cut].decode("utf-8", "replace").split("\n")
                    tail = data[cut + 1 :]
                if lineno == 0 and lines:
                    lines[0] = lines[0].removeprefix("\ufeff")
                    # The twin detects the separator from the header (docs/twin.md "Input"):
                    # pacing reads the times the same way.
                    sep = detect_separator(lines[0])
                    names = [c.strip().strip('"').strip() for c in lines[0].split(sep)]
                    time_col = names.index("time") if "time" in names else None
                first = lineno
                lineno += len(lines)
                if lineno > skip:
                    lines = lines[max(0, skip - first) :]
                    if self.pace > 0 and time_col is not None:
                        t0, wall0 = self._wait(lines, time_col, t0, wall0, sep)
                    yield Chunk(lines=lines)
                if not data:
                    return

    def _wait(self, lines, col, t0, wall0, sep=","):
        """Sleeps until the last sample of these lines is due (pace times real time)."""
        for line in reversed(lines):
            try:
                field = line.split(sep)[col]
                t = _pace_seconds(field.replace(",", ".") if sep == ";" else field)
            except (ValueError, IndexError):
                continue
            if t0 is None:
                return t, time.monotonic()
            due = wall0 + (t - t0) / self.pace
            time.sleep(max(0.0, due - time.monotonic()))
            break
        return t0, wall0

    def get(self, timeout: float) -> Chunk | None:
        try:
            return next(self._it)
        except StopIteration:
            self.ended = True
            return None

    def close(self) -> None:
        if self._it is not None:
            self._it.close()
