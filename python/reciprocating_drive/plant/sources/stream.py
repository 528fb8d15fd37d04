"""Standard input and a growing file as sources (docs/plant.md "Sources").

The lines come from `line_input.chunks_of`, the reader of `rdrive twin`, on a thread of their own,
so that the pipeline commits by time while no data comes and sees a stop signal at once. A line
`EOF` ends the input. A followed file that is truncated, replaced or removed ends the run with
one line saying so (what was computed before is committed).

Resuming: a followed file is read again from its start and the lines the checkpoint consumed are
skipped, as for a CSV file. Standard input cannot be rewound, and nothing says which of its lines
the checkpoint covers: a run of standard input that has a checkpoint is refused (name a new run,
or give the data as a file).

Layer: workflows, the plant (docs/architecture.md).
"""

from __future__ import annotations

import queue
import sys
import threading

from ...twin.core import DataError
from ...twin.line_input import InputChanged, chunks_of
from ..samples import Chunk


class StreamSource:
    live = True  # commits by time: the rows' latency

    def __init__(self, path: str, follow: bool = False, run_id: str = "", block: int = 1 << 16):
        self.path, self.follow, self.run_id, self.block = str(path), follow, run_id, block
        self.stdin = self.path == "-"
        self.rewindable = not self.stdin
        if self.stdin:
            self.resume_hint = (
                "Standard input cannot be rewound: the run cannot be resumed from it; name a new "
                "run.id, or resume from the same data as a file (source.path)."
            )
        self.name = "standard input" if self.stdin else self.path
        self.ended = False
        self.q: queue.Queue = queue.Queue(maxsize=64)  # bounded: a fast producer waits
        self._stop = threading.Event()
        self.thread = None
        self.raw = None

    def start(self, lines_read: int = 0, last_t=None, time_origin=None) -> None:
        from .base import SourceError

        if self.stdin and lines_read > 0:
            raise SourceError(
                f"standard input: run {self.run_id!r} has a checkpoint at input line "
                f"{lines_read}, and standard input cannot be rewound to it; name a new run.id, "
                "or resume from the same data as a file (source.path)"
            )
        try:
            self.raw = sys.stdin.buffer.raw if self.stdin else open(self.path, "rb", buffering=0)
        except OSError as e:
            raise SourceError(f"source {self.path}: {e.strerror}") from None
        self.thread = threading.Thread(
            target=self._read, args=(lines_read,), name="stream-source", daemon=True
        )
        self.thread.start()

    def _put(self, item) -> bool:
        while not self._stop.is_set():
            try:
                self.q.put(item, timeout=0.1)
                return True
            except queue.Full:
                pass
        return False

    def _read(self, skip: int) -> None:
        lineno = 0
        try:
            chunks = chunks_of(
                self.raw, self.follow, self.block, path=self.path, stop=self._stop.is_set
            )
            for lines in chunks:
                if lineno == 0 and lines:
                    # A spreadsheet's UTF-8 byte-order mark (docs/twin.md "Input").
                    lines[0] = lines[0].removeprefix("\ufeff")
                first, lineno = lineno, lineno + len(lines)
                if lineno <= skip:
                    continue
                if not self._put(Chunk(lines=lines[max(0, skip - first) :])):
                    return
            self._put(None)
        except InputChanged as e:
            # The message starts with the path, which the pipeline's line names already.
            self._put(DataError(str(e).removeprefix(self.path + " ")))
        except DataError as e:
            self._put(DataError(str(e)))
        except OSError as e:
            self._put(DataError(f"cannot read: {e.strerror or e}"))

    def get(self, timeout: float) -> Chunk | None:
        try:
            item = self.q.get(timeout=timeout)
        except queue.Empty:
            return None
        if isinstance(item, Exception):
            self.ended = True
            raise item
        if item is None:
            self.ended = True
            return None
        # Take whatever else is there too: one chunk per call.
        while not self.q.empty():
            more = self.q.queue[0]
            if not isinstance(more, Chunk):
                break
            item.lines += self.q.get().lines
        return item

    def close(self) -> None:
        self._stop.set()
        if self.thread is not None:
            # The reader sees the stop within its poll (0.2 s on a pipe, 0.05 s on a file).
            self.thread.join(timeout=5)
        if self.raw is not None and not self.stdin:
            self.raw.close()
