"""The SQLite sink (docs/plant.md): the standard library's sqlite3, write-ahead log.

WAL with synchronous=NORMAL: a transaction is atomic and survives the process being killed
(SIGKILL) at any moment; after a power cut the last transactions may be lost, but always together
with their checkpoint, so the twin resumes from the last one that the file holds.

Layer: workflows, the plant (docs/architecture.md).
"""

from __future__ import annotations

import json
import pathlib
import sqlite3
import time

import numpy as np

from ...twin.core import SUMMARY_FIELDS
from ..schema import SCHEMA_VERSION, column, ddl, insert_events, migrate, upsert_checkpoint
from ..storage import checksum
from .base import RunInfo, Sink, SinkError, parse_state, uncovered, verify, write_storage


class SqliteSink(Sink):
    transient = (sqlite3.OperationalError,)  # "database is locked" beyond the busy timeout

    def __init__(self, path: str, **kw):
        super().__init__(**kw)
        self.path = str(path)
        self.name = f"sqlite {self.path}"
        self.db = None
        self.outputs: list[str] = []

    def _connect(self) -> None:
        if self.db is not None:
            return
        try:
            # The database's folder is made as an output folder is (results/twin/ of a fresh clone).
            pathlib.Path(self.path).parent.mkdir(parents=True, exist_ok=True)
            # One thread at a time uses it: the pipeline's to open, then the writer's.
            db = sqlite3.connect(
                self.path, isolation_level=None, timeout=30.0, check_same_thread=False
            )
            db.execute("PRAGMA journal_mode=WAL")
            db.execute("PRAGMA synchronous=NORMAL")
        except OSError as e:
            raise SinkError(f"{self.name}: cannot make its folder: {e.strerror}") from None
        except sqlite3.DatabaseError as e:
            raise SinkError(f"{self.name}: cannot open the database: {e}") from None
        self.db = db

    def _open_run(self, run: RunInfo):
        db = self.db
        self.outputs = list(run.outputs)
        try:
            db.execute("BEGIN IMMEDIATE")
            old = (
                db.execute("SELECT name FROM sqlite_master WHERE name = 'schema_info'").fetchone()
                and db.execute("SELECT version FROM schema_info").fetchall()
            )
            if old and old[0][0] != SCHEMA_VERSION and migrate("sqlite", old[0][0]):
                # An older schema that can be migrated is, in this transaction (schema.py).
                for stmt in migrate("sqlite", old[0][0]):
                    db.execute(stmt)
            for stmt in ddl("sqlite", run.outputs):
                db.execute(stmt)
            got = db.execute("SELECT version FROM schema_info").fetchall()
            if not got:
                db.execute("INSERT INTO schema_info VALUES (?)", (SCHEMA_VERSION,))
            elif got[0][0] != SCHEMA_VERSION:
                db.execute("ROLLBACK")
                raise SinkError(
                    f"{self.name}: schema version {got[0][0]}; this twin writes version "
                    f"{SCHEMA_VERSION} (use a new database file)"
                )
            cols = [r[1] for r in db.execute("PRAGMA table_info(samples)")]
            missing = [column(o) for o in run.outputs if column(o) not in cols]
            if missing:
                db.execute("ROLLBACK")
                raise SinkError(
                    f"{self.name}: table samples has no column {missing[0]} (the database was "
                    "made for another FMU; use a new database file)"
                )
            row = db.execute(
                "SELECT run, machine_id, machine, status, time_origin FROM runs WHERE name = ?",
                (run.name,),
            ).fetchone()
            state = None
            if row is None:
                cur = db.execute(
                    "INSERT INTO runs (name, machine_id, machine, outputs, options, source, "
                    "time_origin, started_at, status, fmu_guid) "
                    "VALUES (?, ?, ?, ?, ?, ?, ?, ?, 'running', ?)",
                    (
                        run.name,
                        run.machine_id,
                        run.machine,
                        json.dumps(run.outputs),
                        json.dumps(run.options),
                        json.dumps(run.source),
                        run.time_origin,
                        time.time(),
                        run.fmu_guid,
                    ),
                )
                key = cur.lastrowid
            else:
                key, machine_id, machine, status, self.stored_origin = row
                self.run_status = status
                if (machine_id, machine) != (run.machine_id, run.machine):
                    db.execute("ROLLBACK")
                    raise SinkError(
                        f"{self.name}: run {run.name!r} belongs to machine {machine_id!r} "
                        f"({machine}), not {run.machine_id!r} ({run.machine}); name a new run"
                    )
                cp = db.execute("SELECT state FROM checkpoints WHERE run = ?", (key,)).fetchone()
                if cp is not None and cp[0]:
                    try:
                        state = parse_state(cp[0], self.name, run.name)
                    except SinkError:
                        db.execute("ROLLBACK")
                        raise
                    state["status"] = status
                # What the last checkpoint does not cover is computed again (base.py).
                for stmt, args in uncovered(state, key):
                    db.execute(stmt, args)
                if state is not None:
                    try:
                        verify(db.execute, self, key, run.name, state, status)
                    except SinkError:
                        db.execute("ROLLBACK")
                        raise
            db.execute("COMMIT")
        except sqlite3.DatabaseError as e:
            if db.in_transaction:
                db.execute("ROLLBACK")
            if isinstance(e, sqlite3.OperationalError) and "locked" in str(e):
                raise
            raise SinkError(f"{self.name}: {e}") from None
        return key, state

    def _write(self, batch, state: str, c, status) -> None:
        db, run = self.db, self.run_key
        cols = ", ".join(["run", "seq", "t", *map(column, self.outputs)])
        marks = ", ".join("?" * (3 + len(self.outputs)))
        try:
            db.execute("BEGIN IMMEDIATE")
            if batch.rewind is not None:
                for stmt, args in uncovered(batch.rewind, run):
                    db.execute(stmt, args)
            for first, rows in batch.rows:
                seq = (
                    first if isinstance(first, np.ndarray) else np.arange(first, first + len(rows))
                )
                db.executemany(
                    f"INSERT INTO samples ({cols}) VALUES ({marks})",
                    ((run, s, *r) for s, r in zip(seq.tolist(), rows.tolist())),
                )
            if batch.summaries:
                names = ", ".join(SUMMARY_FIELDS)
                db.executemany(
                    f"INSERT INTO revolutions (run, {names}) VALUES (?{', ?' * len(SUMMARY_FIELDS)})",
                    ((run, *(s[k] for k in SUMMARY_FIELDS)) for s in batch.summaries),
                )
            if batch.events:
                db.executemany(
                    insert_events("?"),
                    ((run, s, e.t, w, e.kind, e.count, e.message) for s, w, e in batch.events),
                )
            if state is None:
                # Rows only: the commit number moves (to settle a COMMIT of unknown outcome).
                db.execute(
                    upsert_checkpoint("?", rows_only=True),
                    (run, c.commits, time.time()),
                )
            else:
                db.execute(
                    upsert_checkpoint("?", rows_only=False),
                    (
                        run,
                        c.commits,
                        c.samples,
                        c.revolutions,
                        c.events,
                        time.time(),
                        state,
                        checksum(state.encode()),
                    ),
                )
            write_storage(db.execute, self, run, batch, state, c)
            origin = batch.origin
            if origin is None and state:
                origin = json.loads(state).get("time_origin")
            db.execute(
                "UPDATE runs SET time_origin = COALESCE(time_origin, ?), status = COALESCE(?, status), "
                "finished_at = CASE WHEN ? = 'finished' THEN ? ELSE finished_at END WHERE run = ?",
                (origin, status, status, time.time(), run),
            )
            db.execute("COMMIT")
        except sqlite3.IntegrityError as e:
            db.execute("ROLLBACK")
            raise SinkError(
                f"{self.name}: internal error, a row would be stored twice: {e}"
            ) from None
        except sqlite3.OperationalError:
            if db.in_transaction:
                db.execute("ROLLBACK")
            raise

    def _committed(self) -> int:
        row = self.db.execute(
            "SELECT commits FROM checkpoints WHERE run = ?", (self.run_key,)
        ).fetchone()
        return row[0] if row else 0

    def close(self) -> None:
        if self.db is not None:
            # Everything into the database file itself, the WAL file emptied: SQLite does so on
            # closing only when no other connection is open (a page reading the trends may be),
            # so the .sqlite alone then holds every committed row.
            try:
                self.db.execute("PRAGMA wal_checkpoint(TRUNCATE)")
            except sqlite3.Error:
                pass  # busy or gone: the WAL stays, as valid, and the next opening replays it
            self.db.close()
            self.db = None
