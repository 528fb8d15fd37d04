"""The database schema of the twin's sinks (docs/plant.md, "Schema"), for SQLite and PostgreSQL.

Version 3 (version 2 had no input blocks, snapshots, `runs.fmu_guid`, the checkpoint's checksum
and first rows, and no pump columns `flow_mean`, `flow_pulsation`, `hydraulic_power_mean`,
`mechanical_power_mean` in `revolutions`; version 1 no `interrupted` column in `revolutions`). A
version 2 database is migrated when a twin opens it (`migrate`: columns and tables added, nothing
removed). Every table is keyed by the run (an integer, `runs.run`); a run has a name (the
configuration's `run.id`, unique) and a machine identifier. Per-sample and per-revolution rows
have primary keys (run, seq) and (run, revolution), so a row can never be stored twice: a bug that
tried would fail its transaction instead of duplicating data. The time index (run, t) serves the
queries plants make ("this machine, this hour"). Times `t` are seconds from the run's
`time_origin` (Unix seconds), the twin's own time; wall-clock times are Unix seconds.

Layer: workflows, the plant (docs/architecture.md).
"""

from __future__ import annotations

from ..revolution import PUMP_COLUMNS
from ..twin.core import SUMMARY_FIELDS

SCHEMA_VERSION = 3


def column(output: str) -> str:
    """The column of an FMU output: `support_A.reaction` -> `support_a_reaction` (lower case:
    PostgreSQL folds unquoted names)."""
    return output.replace(".", "_").lower()


def ddl(dialect: str, outputs: list[str]) -> list[str]:
    """The statements creating the schema (idempotent: IF NOT EXISTS)."""
    real = "DOUBLE PRECISION" if dialect == "postgres" else "REAL"
    big = "BIGINT" if dialect == "postgres" else "INTEGER"
    runkey = (
        "BIGINT GENERATED ALWAYS AS IDENTITY PRIMARY KEY"
        if dialect == "postgres"
        else "INTEGER PRIMARY KEY AUTOINCREMENT"
    )
    # SQLite: the rows stored in the primary key's order (one B-tree fewer per row inserted).
    clustered = " WITHOUT ROWID" if dialect == "sqlite" else ""
    outs = ",\n  ".join(f"{column(o)} {real} NOT NULL" for o in outputs)
    revs = ",\n  ".join(f"{f} {real}" for f in SUMMARY_FIELDS[1:])
    return [
        "CREATE TABLE IF NOT EXISTS schema_info (version INTEGER NOT NULL)",
        f"""CREATE TABLE IF NOT EXISTS runs (
  run {runkey},
  name TEXT NOT NULL UNIQUE,
  machine_id TEXT NOT NULL,
  machine TEXT NOT NULL,
  outputs TEXT NOT NULL,
  options TEXT NOT NULL,
  source TEXT NOT NULL,
  time_origin {real},
  started_at {real} NOT NULL,
  finished_at {real},
  status TEXT NOT NULL,
  fmu_guid TEXT
)""",
        f"""CREATE TABLE IF NOT EXISTS samples (
  run {big} NOT NULL REFERENCES runs(run),
  seq {big} NOT NULL,
  t {real} NOT NULL,
  {outs},
  PRIMARY KEY (run, seq)
){clustered}""",
        "CREATE INDEX IF NOT EXISTS samples_time ON samples (run, t)",
        f"""CREATE TABLE IF NOT EXISTS revolutions (
  run {big} NOT NULL REFERENCES runs(run),
  revolution {big} NOT NULL,
  {revs},
  PRIMARY KEY (run, revolution)
)""",
        "CREATE INDEX IF NOT EXISTS revolutions_time ON revolutions (run, start_time)",
        f"""CREATE TABLE IF NOT EXISTS events (
  run {big} NOT NULL REFERENCES runs(run),
  seq {big} NOT NULL,
  t {real},
  wall_time {real} NOT NULL,
  kind TEXT NOT NULL,
  count {big} NOT NULL,
  message TEXT NOT NULL,
  PRIMARY KEY (run, seq)
)""",
        "CREATE INDEX IF NOT EXISTS events_time ON events (run, t)",
        f"""CREATE TABLE IF NOT EXISTS checkpoints (
  run {big} PRIMARY KEY REFERENCES runs(run),
  commits {big} NOT NULL,
  samples {big} NOT NULL,
  revolutions {big} NOT NULL,
  events {big} NOT NULL,
  wall_time {real} NOT NULL,
  state TEXT NOT NULL,
  checksum TEXT,
  samples_from {big},
  revolutions_from {big},
  events_from {big}
)""",
        *storage_ddl(dialect),
    ]


def storage_ddl(dialect: str) -> list[str]:
    """The tables of the stored input (docs/plant.md "Storage"): blocks of input lines (lines
    first_line..last_line, input times t_first..t_last) and snapshots of the twin (at input line
    `lines`, `samples` rows handed out, the last of them at time `t`)."""
    real = "DOUBLE PRECISION" if dialect == "postgres" else "REAL"
    big = "BIGINT" if dialect == "postgres" else "INTEGER"
    blob = "BYTEA" if dialect == "postgres" else "BLOB"
    return [
        f"""CREATE TABLE IF NOT EXISTS input_blocks (
  run {big} NOT NULL REFERENCES runs(run),
  first_line {big} NOT NULL,
  last_line {big} NOT NULL,
  t_first {real},
  t_last {real},
  codec TEXT NOT NULL,
  checksum TEXT NOT NULL,
  data {blob} NOT NULL,
  PRIMARY KEY (run, first_line)
)""",
        f"""CREATE TABLE IF NOT EXISTS snapshots (
  run {big} NOT NULL REFERENCES runs(run),
  lines {big} NOT NULL,
  samples {big} NOT NULL,
  t {real},
  t_input {real},
  checksum TEXT NOT NULL,
  state {blob} NOT NULL,
  PRIMARY KEY (run, lines)
)""",
    ]


def migrate(dialect: str, version: int) -> list[str] | None:
    """The statements that bring a database of schema `version` to SCHEMA_VERSION, or None if
    it cannot be migrated. 2 -> 3 adds columns and tables: the runs of version 2 keep their rows;
    their input was not kept, so their ranges cannot be recomputed."""
    if version != 2:
        return None
    big = "BIGINT" if dialect == "postgres" else "INTEGER"
    real = "DOUBLE PRECISION" if dialect == "postgres" else "REAL"
    return [
        "ALTER TABLE runs ADD COLUMN fmu_guid TEXT",
        "ALTER TABLE checkpoints ADD COLUMN checksum TEXT",
        f"ALTER TABLE checkpoints ADD COLUMN samples_from {big}",
        f"ALTER TABLE checkpoints ADD COLUMN revolutions_from {big}",
        f"ALTER TABLE checkpoints ADD COLUMN events_from {big}",
        *storage_ddl(dialect),
        # A pump's revolution summary (docs/twin.md "Output"): empty in version 2's rows.
        *(f"ALTER TABLE revolutions ADD COLUMN {c} {real}" for c in PUMP_COLUMNS),
        f"UPDATE schema_info SET version = {SCHEMA_VERSION}",
    ]


SAMPLE_COLUMNS = ("run", "seq", "t")
REVOLUTION_COLUMNS = ("run", *SUMMARY_FIELDS)
EVENT_COLUMNS = ("run", "seq", "t", "wall_time", "kind", "count", "message")


def insert_events(ph: str) -> str:
    """The INSERT of data-health events, with the driver's placeholder `ph` (? or %s)."""
    return f"INSERT INTO events ({', '.join(EVENT_COLUMNS)}) VALUES ({', '.join([ph] * 7)})"


def upsert_checkpoint(ph: str, rows_only: bool) -> str:
    """The checkpoint's row of a run, in the same transaction as the rows it covers (docs/plant.md
    "Exactly once"). `rows_only`: a commit without a new checkpoint moves only the commit number
    (to settle a COMMIT of unknown outcome); parameters (run, commits, wall_time). Otherwise
    (run, commits, samples, revolutions, events, wall_time, state, checksum)."""
    cols = "run, commits, samples, revolutions, events, wall_time, state, checksum"
    if rows_only:
        return (
            f"INSERT INTO checkpoints ({cols}) VALUES ({ph}, {ph}, 0, 0, 0, {ph}, '', NULL) "
            "ON CONFLICT (run) DO UPDATE SET commits = excluded.commits"
        )
    update = ", ".join(f"{c} = excluded.{c}" for c in cols.split(", ")[1:])
    return (
        f"INSERT INTO checkpoints ({cols}) VALUES ({', '.join([ph] * 8)}) "
        f"ON CONFLICT (run) DO UPDATE SET {update}"
    )
