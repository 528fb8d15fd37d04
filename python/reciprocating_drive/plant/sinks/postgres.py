"""The PostgreSQL sink (docs/plant.md): psycopg 3, per-sample rows by COPY in binary format.

The rows of a chunk are one numpy array; its binary COPY image (big-endian fields with their
lengths, PostgreSQL's "binary copy format") is built by numpy in one pass, so the doubles go to
the server bit for bit and no Python object is made per value.

Layer: workflows, the plant (docs/architecture.md).
"""

from __future__ import annotations

import json
import time

import numpy as np
import psycopg

from ...twin.core import SUMMARY_FIELDS
from ..config import mask_dsn
from ..schema import SCHEMA_VERSION, column, ddl, insert_events, migrate, upsert_checkpoint
from ..storage import checksum
from .base import RunInfo, Sink, SinkError, parse_state, uncovered, verify, write_storage


def _ex(conn):
    """`ex(sql, args)` with ? marks (base.py's shared statements) on a psycopg connection."""
    return lambda sql, args=(): conn.execute(sql.replace("?", "%s"), args)


_COPY_HEADER = b"PGCOPY\n\xff\r\n\x00" + (0).to_bytes(4, "big") + (0).to_bytes(4, "big")
_COPY_TRAILER = (-1).to_bytes(2, "big", signed=True)


def copy_image(run: int, seq: np.ndarray, rows: np.ndarray) -> bytes:
    """Binary COPY tuples (run bigint, seq bigint, then float8 columns) of these rows."""
    n, m = rows.shape
    fields = [("n", ">i2"), ("l_run", ">i4"), ("run", ">i8"), ("l_seq", ">i4"), ("seq", ">i8")]
    fields += [x for j in range(m) for x in ((f"l{j}", ">i4"), (f"v{j}", ">f8"))]
    a = np.empty(n, dtype=np.dtype(fields))
    a["n"] = 2 + m
    a["l_run"], a["run"], a["l_seq"], a["seq"] = 8, run, 8, seq
    for j in range(m):
        a[f"l{j}"] = 8
        a[f"v{j}"] = rows[:, j]
    return a.tobytes()


class PostgresSink(Sink):
    transient = (psycopg.OperationalError, psycopg.InterfaceError)

    def __init__(self, dsn: str, password: str | None = None, connect_timeout: float = 5.0, **kw):
        super().__init__(**kw)
        self.dsn, self.password, self.connect_timeout = dsn, password, connect_timeout
        # The name shown in messages: the connection string without any password in it.
        self.name = f"postgres {mask_dsn(dsn)}"
        self.conn = None
        self.outputs: list[str] = []

    def _connect(self) -> None:
        if self.conn is not None and not self.conn.closed and not self.conn.broken:
            return
        self.close()
        kw = {"password": self.password} if self.password is not None else {}
        try:
            self.conn = psycopg.connect(
                self.dsn, connect_timeout=max(1, int(self.connect_timeout)), autocommit=True, **kw
            )
        except psycopg.OperationalError as e:
            text = str(e).strip().splitlines()[-1] if str(e).strip() else type(e).__name__
            # A refusal is not an outage: retrying cannot help.
            if any(k in text for k in ("authentication failed", "does not exist", "no password")):
                raise SinkError(f"{self.name}: refused: {text}") from None
            if "does not support SSL" in text:
                raise SinkError(
                    f"{self.name}: refused: the server does not support SSL, and the connection "
                    "string asks for it (sslmode); turn SSL on in the server, or change sslmode "
                    "in dsn"
                ) from None
            raise

    def _open_run(self, run: RunInfo):
        c = self.conn
        self.outputs = list(run.outputs)
        try:
            with c.transaction():
                # One twin at a time creates the schema.
                c.execute("SELECT pg_advisory_xact_lock(7452031)")
                # Made once (a role that only writes rows need not own the tables).
                if c.execute("SELECT to_regclass('schema_info')").fetchone()[0] is None:
                    for stmt in ddl("postgres", run.outputs):
                        c.execute(stmt)
                got = c.execute("SELECT version FROM schema_info").fetchall()
                if got and got[0][0] != SCHEMA_VERSION and migrate("postgres", got[0][0]):
                    # An older schema that can be migrated is, in this transaction (schema.py).
                    for stmt in migrate("postgres", got[0][0]):
                        c.execute(stmt)
                    got = [(SCHEMA_VERSION,)]
                if not got:
                    c.execute("INSERT INTO schema_info VALUES (%s)", (SCHEMA_VERSION,))
                elif got[0][0] != SCHEMA_VERSION:
                    raise SinkError(
                        f"{self.name}: schema version {got[0][0]}; this twin writes version "
                        f"{SCHEMA_VERSION} (use a new database)"
                    )
                cols = [
                    r[0]
                    for r in c.execute(
                        "SELECT column_name FROM information_schema.columns "
                        "WHERE table_name = 'samples' AND table_schema = current_schema()"
                    )
                ]
                missing = [column(o) for o in run.outputs if column(o) not in cols]
                if missing:
                    raise SinkError(
                        f"{self.name}: table samples has no column {missing[0]} (the database "
                        "was made for another FMU; use a new database)"
                    )
                row = c.execute(
                    "SELECT run, machine_id, machine, status, time_origin FROM runs "
                    "WHERE name = %s",
                    (run.name,),
                ).fetchone()
                state = None
                if row is None:
                    key = c.execute(
                        "INSERT INTO runs (name, machine_id, machine, outputs, options, source, "
                        "time_origin, started_at, status, fmu_guid) VALUES (%s, %s, %s, %s, %s, "
                        "%s, %s, %s, 'running', %s) RETURNING run",
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
                    ).fetchone()[0]
                else:
                    key, machine_id, machine, status, self.stored_origin = row
                    self.run_status = status
                    if (machine_id, machine) != (run.machine_id, run.machine):
                        raise SinkError(
                            f"{self.name}: run {run.name!r} belongs to machine {machine_id!r} "
                            f"({machine}), not {run.machine_id!r} ({run.machine}); name a new run"
                        )
                    cp = c.execute(
                        "SELECT state FROM checkpoints WHERE run = %s", (key,)
                    ).fetchone()
                    if cp is not None and cp[0]:
                        state = parse_state(cp[0], self.name, run.name)
                        state["status"] = status
                    # What the last checkpoint does not cover is computed again (base.py).
                    for stmt, args in uncovered(state, key):
                        c.execute(stmt.replace("?", "%s"), args)
                    if state is not None:
                        verify(_ex(c), self, key, run.name, state, status)
        except psycopg.errors.UniqueViolation:
            # Another twin created the same run at the same moment.
            raise SinkError(
                f"{self.name}: run {run.name!r} is being created by another twin"
            ) from None
        except psycopg.DatabaseError as e:
            if isinstance(e, self.transient):
                raise
            raise SinkError(f"{self.name}: {str(e).splitlines()[0]}") from None
        return key, state

    def _write(self, batch, state: str, c, status) -> None:
        conn, run = self.conn, self.run_key
        try:
            with conn.transaction():
                with conn.cursor() as cur:
                    if batch.rewind is not None:
                        for stmt, args in uncovered(batch.rewind, run):
                            cur.execute(stmt.replace("?", "%s"), args)
                    if batch.rows:
                        cols = ", ".join(["run", "seq", "t", *map(column, self.outputs)])
                        with cur.copy(f"COPY samples ({cols}) FROM STDIN (FORMAT BINARY)") as cp:
                            cp.write(_COPY_HEADER)
                            for first, rows in batch.rows:
                                seq = (
                                    first
                                    if isinstance(first, np.ndarray)
                                    else np.arange(first, first + len(rows))
                                )
                                cp.write(copy_image(run, seq, rows))
                            cp.write(_COPY_TRAILER)
                    if batch.summaries:
                        names = ", ".join(SUMMARY_FIELDS)
                        cur.executemany(
                            f"INSERT INTO revolutions (run, {names}) "
                            f"VALUES (%s{', %s' * len(SUMMARY_FIELDS)})",
                            [(run, *(s[k] for k in SUMMARY_FIELDS)) for s in batch.summaries],
                        )
                    if batch.events:
                        cur.executemany(
                            insert_events("%s"),
                            [
                                (run, s, e.t, w, e.kind, e.count, e.message)
                                for s, w, e in batch.events
                            ],
                        )
                    if state is None:
                        # Rows only: the commit number moves (to settle an unknown outcome).
                        cur.execute(
                            upsert_checkpoint("%s", rows_only=True),
                            (run, c.commits, time.time()),
                        )
                    else:
                        cur.execute(
                            upsert_checkpoint("%s", rows_only=False),
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
                    write_storage(_ex(conn), self, run, batch, state, c)
                    origin = batch.origin
                    if origin is None and state:
                        origin = json.loads(state).get("time_origin")
                    cur.execute(
                        "UPDATE runs SET time_origin = COALESCE(time_origin, %s), "
                        "status = COALESCE(%s, status), finished_at = CASE WHEN %s = 'finished' "
                        "THEN %s ELSE finished_at END WHERE run = %s",
                        (origin, status, status, time.time(), run),
                    )
        except psycopg.errors.UniqueViolation as e:
            raise SinkError(
                f"{self.name}: internal error, a row would be stored twice: {str(e).splitlines()[0]}"
            ) from None
        except self.transient:
            raise
        except psycopg.DatabaseError as e:
            if conn.broken:
                raise psycopg.OperationalError(str(e)) from None
            raise SinkError(f"{self.name}: {str(e).splitlines()[0]}") from None

    def _committed(self) -> int:
        row = self.conn.execute(
            "SELECT commits FROM checkpoints WHERE run = %s", (self.run_key,)
        ).fetchone()
        return row[0] if row else 0

    def close(self) -> None:
        if self.conn is not None:
            try:
                self.conn.close()
            except Exception:  # noqa: BLE001 - a broken connection closes anyway
                pass
            self.conn = None
