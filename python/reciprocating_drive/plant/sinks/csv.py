"""The CSV sink (docs/plant.md "CSV sink"): the files `rdrive twin` writes, exactly once.

Per-sample rows (`time` and every output, headers `name [unit]`) and one row per revolution, the
same bytes as `rdrive twin` writes them. Exactly once against a kill (docs/plant.md "Exactly
once"): at every checkpoint the data files are flushed and fsync'ed, then a sidecar file records
their sizes with the twin's checkpoint, written atomically (a temporary file, fsync, rename, fsync
of the folder). Opened again, the files are cut to the sizes the sidecar records (what follows was
written after the checkpoint and is computed again); a file shorter than recorded was changed
since and is refused (it is never padded). The sidecar is written before any data, so a file
without one is not this sink's and is never overwritten.

Layer: workflows, the plant (docs/architecture.md).
"""

from __future__ import annotations

import json
import os
import pathlib

import numpy as np

from ...fmu.batch import format_csv
from ...twin.core import SUMMARY_FIELDS, summary_header
from .base import RunInfo, Sink, SinkError, parse_state

FORMAT = "rdrive-plant-csv-sink"
VERSION = 1


def _fmt(v) -> str:
    # As `rdrive twin` writes a summary field (repr reads back exactly; None is empty).
    return "" if v is None else repr(v)


def _atomic_write(path: pathlib.Path, text: str) -> None:
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "w") as f:
        f.write(text)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)
    # The rename itself is durable only once the folder is.
    fd = os.open(path.parent, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


class CsvSink(Sink):
    def __init__(self, path: str, summary: str | None = None, checkpoint: str | None = None, **kw):
        super().__init__(**kw)
        self.path = pathlib.Path(path)
        self.summary = (
            pathlib.Path(summary)
            if summary
            else self.path.with_name(self.path.stem + "-revolutions.csv")
        )
        self.sidecar = (
            pathlib.Path(checkpoint)
            if checkpoint
            else self.path.with_name(self.path.name + ".checkpoint.json")
        )
        self.name = f"csv {self.path}"
        self.files: dict = {}  # path -> open binary file
        self.meta: dict = {}
        self.text = bytearray()  # format_csv's buffer, reused

    def _connect(self) -> None:
        for p in (self.path, self.summary, self.sidecar):
            try:
                p.parent.mkdir(parents=True, exist_ok=True)
            except OSError as e:
                raise SinkError(
                    f"{self.name}: cannot make the folder {p.parent}: {e.strerror}"
                ) from None

    def _read_sidecar(self, run: RunInfo) -> dict | None:
        if not self.sidecar.exists():
            return None
        try:
            meta = json.loads(self.sidecar.read_text())
            ok = isinstance(meta, dict) and meta.get("format") == FORMAT
            sizes = meta.get("sizes") if ok else None
            ok = (
                ok and isinstance(sizes, dict) and isinstance(meta.get("state"), (dict, type(None)))
            )
            ok = ok and all(
                type(sizes.get(k)) is int and sizes[k] >= 0 for k in ("samples", "summary")
            )
            ok = ok and (meta["state"] is None or isinstance(meta["state"].get("counters"), dict))
        except (OSError, ValueError) as e:
            raise SinkError(f"{self.sidecar}: not a CSV sink checkpoint ({e})") from None
        if not ok:
            raise SinkError(
                f"{self.sidecar}: not a CSV sink checkpoint (format {FORMAT} with the files' sizes "
                "and the twin's state expected)"
            )
        if meta.get("version") != VERSION:
            raise SinkError(
                f"{self.sidecar}: checkpoint version {meta.get('version')!r}; this twin reads "
                f"version {VERSION} (start afresh with new files)"
            )
        got = (meta.get("run"), meta.get("machine_id"), meta.get("machine"))
        if got != (run.name, run.machine_id, run.machine):
            raise SinkError(
                f"{self.sidecar}: the files belong to run {got[0]!r} of machine {got[1]!r} "
                f"({got[2]}), not run {run.name!r} of {run.machine_id!r} ({run.machine}); "
                "name other files"
            )
        if meta.get("header") != run.header:
            raise SinkError(f"{self.path}: its columns are those of another FMU; name other files")
        return meta

    def _open_run(self, run: RunInfo):
        meta = self._read_sidecar(run)
        paths = {"samples": self.path, "summary": self.summary}
        if meta is None:
            for p in paths.values():
                if p.exists() and p.stat().st_size > 0:
                    raise SinkError(
                        f"{p}: exists and has no checkpoint {self.sidecar}: it is not this run's "
                        "output; remove it or name another file"
                    )
            # The sidecar first: from now on the files are this sink's (docs/plant.md).
            meta = {
                "format": FORMAT,
                "version": VERSION,
                "run": run.name,
                "machine_id": run.machine_id,
                "machine": run.machine,
                "header": run.header,
                "sizes": {"samples": 0, "summary": 0},
                "status": None,
                "state": None,
            }
            try:
                _atomic_write(self.sidecar, json.dumps(meta))
            except OSError as e:
                raise SinkError(self._cannot(self.sidecar, e)) from None
        for key, p in paths.items():
            size = int(meta["sizes"][key])
            have = p.stat().st_size if p.is_file() else None
            if have is None and size > 0:
                raise SinkError(
                    f"{p}: missing; the checkpoint {self.sidecar} covers {size} bytes of it"
                )
            if have is not None and have < size:
                raise SinkError(
                    f"{p}: {have} bytes, shorter than the {size} the checkpoint {self.sidecar} "
                    "covers: it was changed since; start afresh with new files"
                )
            try:
                f = open(p, "r+b" if have is not None else "w+b")
                self.files[key] = f
                # What follows the checkpoint's size was written after it: computed again.
                if have is not None and have != size:
                    f.truncate(size)
                f.seek(size)
                if size == 0:
                    head = run.header if key == "samples" else summary_header()
                    f.write((",".join(head) + "\n").encode())
                    f.flush()  # the headers are out before the first sample, as rdrive twin's
            except OSError as e:
                raise SinkError(self._cannot(p, e)) from None
        self.meta = meta
        state = meta["state"]
        if state is not None:
            state = parse_state(json.dumps(state), str(self.sidecar), run.name)
            state["status"] = meta.get("status")
        return str(self.path), state

    def _cannot(self, p, e: OSError) -> str:
        """A file that cannot be written (a full disk, no permission): one line naming it."""
        return f"{self.name}: cannot write {p}: {e.strerror or e}"

    def _write(self, batch, state: str | None, c, status) -> None:
        try:
            self._write_files(batch, state, status)
        except OSError as e:
            p = e.filename or (self.sidecar if state is not None else self.path)
            raise SinkError(self._cannot(p, e)) from None

    def _write_files(self, batch, state: str | None, status) -> None:
        out, summ = self.files["samples"], self.files["summary"]
        for _first, rows in batch.rows:
            out.write(format_csv(np.asarray(rows), self.text))
        if batch.summaries:
            summ.write(
                "".join(
                    ",".join(_fmt(s[k]) for k in SUMMARY_FIELDS) + "\n" for s in batch.summaries
                ).encode()
            )
        out.flush()
        summ.flush()
        if state is None:
            return  # rows only: visible to readers, covered by no checkpoint yet
        for f in (out, summ):
            os.fsync(f.fileno())
        self.meta.update(
            sizes={"samples": out.tell(), "summary": summ.tell()},
            state=json.loads(state),
            status=status or self.meta.get("status"),
        )
        _atomic_write(self.sidecar, json.dumps(self.meta))

    def rewind(self, state: dict) -> None:
        """Nothing to go back to: the files hold no events, and rows are skipped as held."""

    def _committed(self) -> int:
        return self.commits

    def close(self) -> None:
        failed = None
        for f in self.files.values():
            try:
                f.close()  # every row was flushed at its commit; a failure here is the disk's
            except OSError as e:
                failed = failed or SinkError(self._cannot(f.name, e))
        self.files = {}
        if failed is not None:
            raise failed
