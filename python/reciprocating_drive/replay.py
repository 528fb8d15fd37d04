"""Distributed replay of a recorded history on Dask (docs/twin.md "Distributed replay").

The sequential twin carries state from sample to sample: the unwrapped angle (a running sum of
the angle's steps), the smoothing window's neighbours, the FMU's state, the revolution in
progress. The distributed replay makes every cut exact as follows.

1. **Scan** (the client, sequential, no FMU): the twin's own reader, checks, unwrapping and gap
   rule (`Twin._accept`, with the conditioning and FMU stage replaced by a collector) turn the
   whole input into arrays of accepted samples: line, time, unwrapped angle, speed, force. The
   unwrapped angle is the sequential running sum itself, so no piece has to rebuild its offset
   2πk. A bad line stops the replay here, before anything runs.
2. **Pieces**: every gap is a cut (the FMU is re-initialized there in the sequential run too); with
   `revolutions_per_piece` N a segment is also cut every N revolutions of the angle. A piece
   [s, e) is computed by a fresh `Twin` fed the samples [w, f): a warm-up from w (at least
   the smoothing window's half-width before s, more for an elastic rod, see `warm_up_time`) and a
   tail to f (the window after e-1, and until the revolution in progress at e completes). The
   angle arrives unwrapped (continuous), so the piece's twin reproduces the sequential one's
   inputs bit for bit.
3. **Result**: the rows of [s, e), and the summaries of the revolutions whose first sample (the
   first with model angle >= 2πk) lies in [s, e). A revolution's numbers depend only on its own
   samples and their neighbours (revolution.revolution_table), so they are those of the
   sequential run. Rows and summaries come back formatted (bytes); each piece is written
   atomically to the work folder, and the output files are assembled in order at the end.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import math
import os
import pathlib
import shutil
import threading
import time
import zlib
from dataclasses import dataclass

import numpy as np

from .batch import format_csv
from .fmu import Fmu, FmuError
from .line_input import chunks_of
from .revolution import TWO_PI
from .twin import SUMMARY_FIELDS, DataError, Options, Twin, _Segment

MANIFEST_VERSION = 1

#: Error in rad the elastic rod's cage angle may keep from its quasi-static start at the end of
#: a piece's warm-up (docs/twin.md "Distributed replay"), and the bound on the start's error.
CAGE_TOLERANCE = 1e-8
CAGE_START_ERROR = 1.0


class ReplayError(ValueError):
    """A replay that cannot start or continue (one line for the user)."""


class PieceFailed(RuntimeError):
    """Bad data or an FMU error in a piece (the message names the line); a plain exception,
    so that it travels from a worker to the client."""


def cage_decay_rate(values: dict, fmu_starts: dict) -> float | None:
    """σ = B_d/(2·J_m) [1/s], the rate at which the elastic rod's cage oscillation decays
    (docs/model.md §6: J_m·ϑ̈ + B_d·ϑ̇ + K_ϑ·ϑ = ...), or None for a rigid rod (rod.kind 0).
    B_d = rod.damping when positive, else 2ζ·√(K_ϑ(0)·J_m) with K_ϑ(0) = A2·W/W* at P = 0, where
    the fundamental functions are polynomials (§6: x = 0, s_N = 1, V3 = z²/2, V4 = z³/6)."""

    def v(name):
        return float(values.get(name, fmu_starts.get(name)))

    if int(v("rod.kind")) == 0:
        return None
    jm = v("rod.cage_inertia")
    if v("rod.damping") > 0:
        return v("rod.damping") / (2.0 * jm)
    e, nu, d = v("rod.E"), v("rod.poisson"), v("rod.wire_diameter")
    g = e / (2.0 * (1.0 + nu))
    if int(v("rod.kind")) == 1:
        a2 = e * math.pi * d**4 / 64.0
        a1 = 0.9 * g * math.pi * d**2 / 4.0
    else:
        dc, coils, lf = v("rod.coil_diameter"), v("rod.coils"), v("rod.flex_length")
        h = lf / coils
        bt, bb = g * math.pi * d**4 / 32.0, e * math.pi * d**4 / 64.0
        a1 = 8.0 * h * bb / (math.pi * dc**3)
        a2 = (2.0 * h / (math.pi * dc)) * bt * bb / (bt + bb)
    z, f = v("rod.flex_length"), v("rod.rigid_length")
    eta = a2 / a1
    v3, v4, v3p, v4p, v3pp, v4pp, v4ppp = z * z / 2, z**3 / 6, z, z * z / 2, 1.0, z, 1.0
    e_bar = v3 + f * v3p
    d_bar = v4 + f * v4p - eta * z
    l3, l4 = v3pp, v4pp + f * v4ppp
    w_star = v3 * v4p - v3p * v4 + eta * z * v3p
    k0 = a2 * (e_bar * l4 - d_bar * l3) / w_star
    return v("rod.damping_ratio") * math.sqrt(k0 / jm)


def warm_up_time(sigma: float | None) -> float:
    """The elastic rod's warm-up [s]: the cage starts quasi-statically with an error below
    CAGE_START_ERROR rad, which decays as e^(−σt); after ln(CAGE_START_ERROR/CAGE_TOLERANCE)/σ
    it is below CAGE_TOLERANCE. 0 for a rigid rod (no state carries over)."""
    if sigma is None:
        return 0.0
    return math.log(CAGE_START_ERROR / CAGE_TOLERANCE) / sigma


class _Scan(Twin):
    """The twin's reader, checks, unwrapping and gap rule, without conditioning and FMU: the
    samples the sequential twin would send on, collected as arrays."""

    def __init__(self, *args, **kw):
        super().__init__(*args, **kw)
        self.parts: list = []
        self.seg_n = 0
        self.seg_line = None

    def _drain(self, final: bool, rows: list) -> None:
        b = self.buf
        if len(b.t):
            if self.seg_n == 0:
                self.seg_line = int(b.line[0])
            self.parts.append((b.line, b.t, b.theta, b.speed, b.force))
            self.seg_n += len(b.t)
            self.buf = _Segment()
        if final:
            if 0 < self.seg_n < 4:
                raise DataError(
                    f"line {self.seg_line}: a segment of {self.seg_n} sample(s) between gaps is "
                    "too short (at least 4 are needed)"
                )
            self.seg_n = 0

    def arrays(self) -> dict:
        cols = list(zip(*self.parts)) if self.parts else [[np.empty(0)]] * 5
        names = ("line", "t", "theta", "speed", "force")
        return {n: np.concatenate(c) for n, c in zip(names, cols)}


@dataclass
class Scanned:
    data: dict  # line, t, theta, speed, force of every accepted sample
    half: int
    cols: dict
    gaps: list
    duplicates: int
    messages: list
    sha256: str
    size: int
    header: list
    guid: str
    options: Options  # resolved
    values: dict
    sigma: float | None
    offset: float  # crank.angle_offset [rad]


#: The columns the twin reads (docs/twin.md "Input"), the names of a table's columns too.
COLUMNS = ("time", "crank_angle", "crank_speed", "process_force")


def is_sqlite(path) -> bool:
    """An SQLite database file (its 16-byte header)."""
    try:
        with open(path, "rb") as f:
            return f.read(16) == b"SQLite format 3\x00"
    except OSError:
        return False


def sqlite_lines(path, table: str, stop=None, rows: int = 1 << 15):
    """The table's samples as the lines of a CSV file: a header naming its columns among
    COLUMNS, then one line per row in rowid order, each REAL written as repr writes it (the
    same double back), NULL as an empty field (refused by the twin like an empty CSV field).
    Row k is line k + 1 in messages. ReplayError for a database or table that cannot be read."""
    import sqlite3

    try:
        con = sqlite3.connect(f"file:{pathlib.Path(path).resolve()}?mode=ro", uri=True)
    except sqlite3.Error as e:
        raise ReplayError(f"{path}: cannot be opened as an SQLite database ({e})") from None
    try:
        tables = [r[0] for r in con.execute("SELECT name FROM sqlite_master WHERE type='table'")]
        if table not in tables:
            raise ReplayError(
                f"--table {table!r}: no such table in {path}; it has: {', '.join(tables) or 'none'}"
            )
        names = [r[1] for r in con.execute(f'PRAGMA table_info("{table}")')]
        cols = [c for c in COLUMNS if c in names]
        yield [",".join(cols or names[:1])]
        if not cols:
            return
        quoted = ", ".join(f'"{c}"' for c in cols)
        cur = con.execute(f'SELECT {quoted} FROM "{table}" ORDER BY rowid')
        while not (stop and stop()):
            got = cur.fetchmany(rows)
            if not got:
                break
            yield [
                ",".join(
                    "" if v is None else repr(v) if isinstance(v, float) else str(v) for v in r
                )
                for r in got
            ]
    except sqlite3.Error as e:
        raise ReplayError(f"{path}: table {table!r} cannot be read ({e})") from None
    finally:
        con.close()


def is_postgres(name: str) -> bool:
    """A PostgreSQL connection URI (postgresql://USER@HOST:PORT/DATABASE)."""
    return name.startswith(("postgresql://", "postgres://"))


def postgres_lines(uri: str, table: str, stop=None, rows: int = 1 << 15):
    """A PostgreSQL table's samples as the lines of a CSV file, as `sqlite_lines` makes them, in
    time order (ties in the order the table stores them). A password in the URI is refused: it
    would show in the process list and in messages (PGPASSWORD or ~/.pgpass hold it)."""
    import psycopg
    from psycopg.conninfo import conninfo_to_dict

    try:
        info = conninfo_to_dict(uri)
    except psycopg.Error as e:
        raise ReplayError(f"the input's PostgreSQL URI cannot be read ({e})") from None
    where = f"postgresql://{info.get('host', '')}:{info.get('port', '')}/{info.get('dbname', '')}"
    if info.get("password"):
        raise ReplayError(
            f"{where}: a password in the URI would show in the process list; give it in "
            "PGPASSWORD or ~/.pgpass"
        )
    try:
        con = psycopg.connect(uri, connect_timeout=10)
    except psycopg.Error as e:
        first = " ".join(str(e).split())[:200]
        raise ReplayError(f"{where}: cannot connect within 10 s ({first})") from None
    try:
        tables = [
            r[0]
            for r in con.execute(
                "SELECT table_name FROM information_schema.tables "
                "WHERE table_schema = current_schema() ORDER BY table_name"
            )
        ]
        if table not in tables:
            raise ReplayError(
                f"--table {table!r}: no such table in {where}; it has: {', '.join(tables) or 'none'}"
            )
        names = [
            r[0]
            for r in con.execute(
                "SELECT column_name FROM information_schema.columns WHERE table_schema = "
                "current_schema() AND table_name = %s ORDER BY ordinal_position",
                (table,),
            )
        ]
        cols = [c for c in COLUMNS if c in names]
        yield [",".join(cols or names[:1])]
        if not cols or "time" not in cols:
            return
        quoted = ", ".join(f'"{c}"' for c in cols)
        with con.cursor(name="rdrive_replay") as cur:  # server side: the table is streamed
            cur.execute(f'SELECT {quoted} FROM "{table}" ORDER BY "time", ctid')
            while not (stop and stop()):
                got = cur.fetchmany(rows)
                if not got:
                    break
                yield [
                    ",".join(
                        "" if v is None else repr(v) if isinstance(v, float) else str(v) for v in r
                    )
                    for r in got
                ]
    except psycopg.Error as e:
        first = " ".join(str(e).split())[:200]
        raise ReplayError(f"{where}: table {table!r} cannot be read ({first})") from None
    finally:
        con.close()


def scan(
    path: str, fmu: str, machine: str, options: Options, stop=None, table: str | None = None
) -> Scanned:
    """Reads and checks the whole input, a CSV file or the table `table` of an SQLite database
    or of a PostgreSQL one (`path` a postgresql:// URI) (DataError naming the line on bad
    data)."""
    tw = _Scan(fmu, machine, options)
    digest = hashlib.sha256()
    size = 0
    lineno = 0
    with contextlib.ExitStack() as stack:
        if is_postgres(path):
            chunks = postgres_lines(path, table or "samples", stop)
        elif table is not None:
            chunks = sqlite_lines(path, table, stop)
        else:
            src = stack.enter_context(open(path, "rb", buffering=0))
            chunks = chunks_of(src, False, 1 << 20, path=path, stop=stop)
        for lines in chunks:
            text = ("\n".join(lines) + "\n").encode()
            digest.update(text)
            size += len(text)
            tw.feed(lines, lineno + 1)
            lineno += len(lines)
    tw.finish()
    starts = {n: v.start for n, v in tw.fmu.variables.items()}
    return Scanned(
        data=tw.arrays(),
        half=int(tw.half),
        cols=tw.cols,
        gaps=list(tw.gaps),
        duplicates=tw.duplicates,
        messages=list(tw.messages),
        sha256=digest.hexdigest(),
        size=size,
        header=tw.header_with_units(),
        guid=tw.fmu.model_description.guid,
        options=tw.o,
        values=dict(tw.values),
        sigma=cage_decay_rate(tw.values, starts),
        offset=float(tw.values.get("crank.angle_offset", starts.get("crank.angle_offset", 0.0))),
    )


def plan(sc: Scanned, revolutions_per_piece: int | None, overlap: float | None, cuts=()) -> list:
    """Pieces [s, e, w, f, f ends its segment] in sample indices: rows s..e-1 computed from
    samples w..f-1. Cuts at every gap, every `revolutions_per_piece` revolutions of a segment,
    and at the sample indices `cuts` (tests place cuts next to a gap and at the ends)."""
    t, th = sc.data["t"], sc.data["theta"]
    n = len(t)
    if n == 0:
        return []
    # The twin's gap rule (twin.Twin._accept): an interval longer than gap_limit.
    gap_at = (np.flatnonzero((t[1:] - t[:-1]) > sc.options.gap_limit) + 1).tolist()
    bounds = [0, *gap_at, n]
    warm_s = warm_up_time(sc.sigma) if overlap is None else overlap
    half = sc.half
    pieces = []
    extra = sorted(int(c) for c in cuts)
    for a, b in zip(bounds[:-1], bounds[1:]):
        cuts_at = [a]
        if revolutions_per_piece:
            # At the model angle's revolution boundaries (crank angle + crank.angle_offset,
            # docs/fmi-interface.md): the last revolution of a piece then ends at its cut, and
            # the tail is only the smoothing window's half-width.
            ma = th[a:b] + sc.offset
            r = math.ceil(ma[0] / TWO_PI) + revolutions_per_piece
            while True:
                c = int(np.searchsorted(ma, TWO_PI * r, side="left")) + a
                if c >= b:
                    break
                if c > cuts_at[-1]:
                    cuts_at.append(c)
                r += revolutions_per_piece
        aligned = set(cuts_at)
        cuts_here = sorted({*cuts_at, *(c for c in extra if a < c < b), b})
        for s, e in zip(cuts_here[:-1], cuts_here[1:]):
            # Warm-up: the window's half-width and the sample before, and the cage's time. Near
            # the segment's end the window shifts inward (docs/twin.md "Conditioning"): the
            # last sample's window starts 2·half samples before the end.
            w = max(a, min(s - half - 4, b - 2 * half - 3))
            if warm_s > 0 and s > a:
                w = min(w, max(a, int(np.searchsorted(t, t[s] - warm_s, side="right")) - 1))
            # Tail: the revolution in progress at e completes within 2π of angle after e-1
            # (model angle = crank angle + a constant; the angle only grows within a segment),
            # then the window's half-width.
            if e < b and e in aligned:
                # A boundary found from the crank angle may be a sample off the FMU's own.
                f = min(b, max(e + half + 5, a + 2 * half + 3))
            elif e < b:
                x = int(np.searchsorted(th[a:b], th[e - 1] + TWO_PI, side="right")) + a + 1
                f = min(b, max(max(e, x) + half + 2, a + 2 * half + 3))
            else:
                f = b
            pieces.append([s, e, w, f, f == b])
    return pieces


#: FMUs loaded in this (worker) process, by path.
_LOADED: dict = {}


def load_fmu(fmu_key_or_path) -> Fmu:
    """On a worker: the FMU (shipped by the client, or a path), loaded once per process."""
    from .cluster import _RECEIVED, local_fmu

    path = local_fmu(fmu_key_or_path) if fmu_key_or_path in _RECEIVED else fmu_key_or_path
    fmu = _LOADED.get(path)
    if fmu is None:
        fmu = _LOADED[path] = Fmu(path)
    return fmu


def warm_worker(fmu_key_or_path) -> None:
    """Run on every worker before the pieces: imports and the FMU's loading happen once, not
    in the first piece (client.run)."""
    load_fmu(fmu_key_or_path)


def run_piece(
    fmu_key_or_path,
    values,
    options: dict,
    half: int,
    cols: dict,
    offset: float,
    piece,
    arrays,
    work: str | None = None,
    index: int = 0,
):
    """On a worker: the formatted rows and summaries of one piece (bytes, bytes, rows, CPU
    seconds of this thread). With `work` (a worker on the client's disk: a LocalCluster) the
    worker writes the piece there itself (`write_piece`) and returns None for the bytes: the
    client then handles none."""
    # One loaded FMU per worker process, re-initialized at each piece's first sample as the
    # sequential twin re-initializes it after a gap (fmi2Reset, then initialization).
    fmu = load_fmu(fmu_key_or_path)
    s, e, w, f = piece[:4]
    cpu = time.thread_time()
    line, t, theta, speed, force = arrays
    o = Options(**options)
    tw = Twin(fmu, "default", o, values)
    tw.half, tw.cols = half, cols
    rows = [tw._empty()]
    try:
        err = tw._accept(line, t, theta, speed, force, rows)
        if err is not None:
            raise err
        got, sums = tw._hand_out(rows, None)
        tail, sums2 = tw.finish()
    except (DataError, FmuError) as e:
        raise PieceFailed(" ".join(str(e).split())) from None
    allrows = np.concatenate([got, tail]) if len(tail) else got
    if len(allrows) != f - w:
        raise RuntimeError(f"piece {piece}: {len(allrows)} rows for {f - w} samples")
    ang = allrows[:, tw.i_angle]
    # Rows are exact up to half a window before f, unless f ends the segment (docs/twin.md).
    seg_end = bool(piece[4]) if len(piece) > 4 else False
    exact_end = f - w if seg_end else f - w - half - 1
    # A revolution belongs to the piece where the crank angle + offset first reaches its start:
    # the rule the planner cuts by (the same doubles), so each is written exactly once.
    model = theta + offset
    keep = []
    for sm in sums + sums2:
        r = sm["revolution"]
        j = int(np.argmax(model >= TWO_PI * r))
        if s <= w + j < e:
            done = int(np.argmax(ang >= TWO_PI * (r + 1)))
            if done + 1 >= exact_end and not seg_end:
                raise RuntimeError(f"piece {piece}: revolution {r} ends past the exact tail")
            keep.append(sm)
    summ = "".join(
        ",".join("" if sm[k] is None else repr(sm[k]) for k in SUMMARY_FIELDS) + "\n" for sm in keep
    ).encode()
    if work is not None:
        # Formatted into this process's buffer and written from it: a piece's ~5 MB of text
        # is neither allocated afresh nor copied (as the sequential twin's writer does).
        text = _TEXT.__dict__.setdefault("buffer", bytearray())
        out = format_csv(allrows[s - w : e - w], text)
        try:
            write_piece(pathlib.Path(work), index, out, summ, cpu)
        finally:
            if isinstance(out, memoryview):  # b"" for a piece without rows
                out.release()  # the buffer can grow again for the next piece
        return None, None, e - s, time.thread_time() - cpu
    return bytes(format_csv(allrows[s - w : e - w])), summ, e - s, time.thread_time() - cpu


#: The file by which a stopped client tells its LocalCluster's workers to start no more pieces.
STOP = "stop"


def run_group(fmu_key_or_path, values, options, half, cols, offset, items, work=None):
    """On a worker: consecutive pieces, one Dask task (docs/twin.md "Distributed replay",
    Speed: the scheduler's cost is per task, not per sample). `items` holds (index, piece,
    arrays) in order. With `work` each piece is written there as it ends (the client counts
    and assembles it from its record) and the result is None; without, the list of each
    piece's (bytes, bytes, rows, CPU seconds). A stopped client's STOP file in `work` ends
    the group before its next piece: a running task cannot be cancelled, and a group is long."""
    got = []
    for i, piece, arrays in items:
        if work is not None and (pathlib.Path(work) / STOP).exists():
            return None  # the client stopped: it counts none of these (resume computes them)
        r = run_piece(fmu_key_or_path, values, options, half, cols, offset, piece, arrays, work, i)
        if work is None:
            got.append(r)
    return None if work is not None else got


#: format_csv's buffer of each thread of this (worker) process, reused by every piece.
_TEXT = threading.local()


# ---- the work folder ---------------------------------------------------------------------------


def _atomic_write(path: pathlib.Path, data: bytes, sync: bool = True) -> None:
    """Written beside and renamed over: a kill leaves the old file or the new one. Without
    `sync` a power loss may leave a damaged file, which is fine where a checksum finds it."""
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "wb") as fh:
        fh.write(data)
        if sync:
            fh.flush()
            os.fsync(fh.fileno())
    os.replace(tmp, path)


def manifest_of(sc: Scanned, machine: str, pieces: list, extra: dict) -> dict:
    return {
        "version": MANIFEST_VERSION,
        "input_sha256": sc.sha256,
        "input_bytes": sc.size,
        "fmu_guid": sc.guid,
        "machine": machine,
        "options": sc.options.to_dict(),
        **extra,
        "pieces": pieces,
    }


def open_work(work: pathlib.Path, manifest: dict) -> set:
    """Creates the work folder with its manifest, or checks an existing one against `manifest`
    (ReplayError naming what differs). Returns the indices of the pieces already written."""
    mpath = work / "manifest.json"
    if work.exists() and not work.is_dir():
        raise ReplayError(f"--work-dir {work}: not a folder")
    if mpath.exists():
        try:
            old = json.loads(mpath.read_text())
            if not isinstance(old, dict) or old.get("sha256") != _digest(old):
                raise ValueError("checksum")
        except (ValueError, UnicodeDecodeError):
            raise ReplayError(
                f"{mpath}: damaged (not the manifest this replay wrote); remove {work} to start "
                "afresh"
            ) from None
        mine, theirs = manifest["options"], old.get("options")
        if isinstance(theirs, dict):
            for k in mine:
                if theirs.get(k) != mine[k]:
                    flag = "--" + k.replace("_", "-")
                    raise ReplayError(
                        f"{mpath}: its option {flag} {theirs.get(k)!r} differs from this run's "
                        f"{mine[k]!r}: the pieces there belong to another replay; remove {work} "
                        "or give another --work-dir"
                    )
        for key in ("version", "input_sha256", "input_bytes", "fmu_guid", "machine", "options"):
            if old.get(key) != manifest[key]:
                raise ReplayError(
                    f"{mpath}: its {key} {_show(old.get(key))} differs from this run's "
                    f"{_show(manifest[key])}: the pieces there belong to another replay; remove "
                    f"{work} or give another --work-dir"
                )
        for key in manifest:
            if old.get(key) != manifest[key]:
                raise ReplayError(
                    f"{mpath}: its {key} differs from this run's (other piece options); remove "
                    f"{work} or give another --work-dir"
                )
        return {i for i in range(len(manifest["pieces"])) if _piece_ok(work, i)}
    work.mkdir(parents=True, exist_ok=True)
    _atomic_write(mpath, json.dumps({**manifest, "sha256": _digest(manifest)}).encode())
    return set()


def _show(v) -> str:
    text = repr(v)
    return text if len(text) <= 80 else text[:77] + "..."


def _digest(d: dict) -> str:
    body = {k: v for k, v in d.items() if k != "sha256"}
    return hashlib.sha256(json.dumps(body, sort_keys=True).encode()).hexdigest()


def _names(work: pathlib.Path, i: int):
    return (
        work / f"piece-{i:06d}.csv",
        work / f"piece-{i:06d}-rev.csv",
        work / f"piece-{i:06d}.json",
    )


def piece_cpu(work: pathlib.Path, i: int) -> float:
    """The CPU seconds a worker wrote in piece i's record (0 where it holds none)."""
    try:
        return float(json.loads(_names(work, i)[2].read_text()).get("cpu", 0.0))
    except (OSError, ValueError, TypeError, AttributeError):
        return 0.0


def _piece_ok(work: pathlib.Path, i: int) -> bool:
    """A piece written completely: its record's sizes and CRC-32 match its two files (a check
    against damage, which a crash or a cut can do; the manifest holds the input's SHA-256)."""
    out, rev, rec = _names(work, i)
    try:
        r = json.loads(rec.read_text())
        for p, key in ((out, "out"), (rev, "rev")):
            data = p.read_bytes()
            if len(data) != r[key][0] or zlib.crc32(data) != r[key][1]:
                return False
        return True
    except (OSError, ValueError, KeyError, TypeError, IndexError):
        return False


def write_piece(
    work: pathlib.Path, i: int, out: bytes, rev: bytes, cpu0: float | None = None
) -> None:
    """The piece's files, then its record (last: a piece without a valid record is computed
    again). Not synced: a piece whose files do not match its record's CRC-32 after a crash is
    computed again, so the sync (the slowest part of a piece on the client) buys nothing.
    With `cpu0` (this thread's CPU clock when the piece started, on a worker) the record holds
    the piece's CPU seconds, which the client reads instead of fetching the task's result."""
    p_out, p_rev, p_rec = _names(work, i)
    _atomic_write(p_out, out, sync=False)
    _atomic_write(p_rev, rev, sync=False)
    rec = {
        # CRC-32, not SHA-256: a third of the time on the worker, and damage is what it finds.
        "out": [len(out), zlib.crc32(out)],
        "rev": [len(rev), zlib.crc32(rev)],
    }
    if cpu0 is not None:
        rec["cpu"] = time.thread_time() - cpu0
    _atomic_write(p_rec, json.dumps(rec).encode(), sync=False)


class Assembler:
    """The output files, made from the pieces in order while later pieces still run: each piece
    is appended as soon as every piece before it is written, so that at the end only the last
    ones remain to copy (the assembly is the replay's sequential part). The files grow beside
    the outputs (`<out>.tmp`) and are renamed over them by `finish`; `abort` removes them (the
    pieces stay in the work folder, and a resumed run assembles afresh)."""

    def __init__(self, work: pathlib.Path, n: int, targets: list):
        self.work, self.n = work, n
        self.targets = targets  # (path, header line) of the rows and of the summaries
        self.files = []
        for target, header in targets:
            fh = open(target.with_name(target.name + ".tmp"), "wb")
            fh.write((",".join(header) + "\n").encode())
            fh.flush()
            self.files.append(fh)
        self.ready: set = set()
        self.next = 0

    def add(self, i: int) -> None:
        self.ready.add(i)
        while self.next in self.ready:
            for idx, fh in enumerate(self.files):
                with open(_names(self.work, self.next)[idx], "rb") as src:
                    _copy(src, fh)
            self.ready.discard(self.next)
            self.next += 1

    def finish(self) -> None:
        if self.next != self.n:
            raise RuntimeError(f"{self.n - self.next} pieces not assembled")
        for (target, _), fh in zip(self.targets, self.files):
            fh.flush()
            os.fsync(fh.fileno())
            fh.close()
            os.replace(fh.name, target)

    def abort(self) -> None:
        for fh in self.files:
            fh.close()
            pathlib.Path(fh.name).unlink(missing_ok=True)


def _copy(src, dst) -> None:
    """Appends the file `src` to `dst` in the kernel (os.copy_file_range) where it can: the
    result's assembly is sequential, so it is kept to the disk's speed."""
    size = os.fstat(src.fileno()).st_size
    try:
        done = 0
        while done < size:
            k = os.copy_file_range(src.fileno(), dst.fileno(), size - done)
            if k == 0:
                break
            done += k
        if done == size:
            return
        src.seek(done)
    except (AttributeError, OSError):
        src.seek(0)
        dst.seek(0, os.SEEK_END)
    shutil.copyfileobj(src, dst, 1 << 20)


class Progress:
    """Pieces done/total and samples/s on stderr, at most once a second (and at the end)."""

    def __init__(self, total: int, samples: int, quiet: bool, stream):
        self.total, self.samples, self.quiet, self.stream = total, samples, quiet, stream
        self.t0 = time.monotonic()
        self.last = 0.0
        self.done = 0
        self.done_samples = 0
        self.base = 0  # samples done before the clock started (resumed pieces)
        self.workers = 0
        self.t_end = self.t0
        self.cpu = 0.0  # the workers' CPU seconds in the pieces
        self.client_cpu = 0.0  # this process's CPU seconds while the pieces ran

    def start(self) -> None:
        """The clock starts when the workers are ready (the cluster's start-up is not a rate)."""
        self.t0 = time.monotonic()
        self.base = self.done_samples

    def step(self, samples: int, final: bool = False) -> None:
        self.done += 1
        self.done_samples += samples
        now = time.monotonic()
        if self.quiet or (now - self.last < 1.0 and self.done < self.total):
            return
        self.last = now
        rate = (self.done_samples - self.base) / max(now - self.t0, 1e-9)
        print(
            f"replay: {self.done}/{self.total} pieces, {self.done_samples}/{self.samples} "
            f"samples, {rate:.0f} samples/s",
            file=self.stream,
            flush=True,
        )
