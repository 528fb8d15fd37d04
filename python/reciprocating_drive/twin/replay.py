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
   sequential run. Rows and summaries are formatted on the worker. A LocalCluster's workers
   write each piece's rows at their place in the work folder's rows file (`run_claimed`); a
   cluster that shares no disk sends them back as bytes, which the client places
   (`Assembler`). The rows file becomes the output at the end.

Layer: workflows, the twin (docs/architecture.md).
"""

from __future__ import annotations

import contextlib
import errno
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

from ..fmu.batch import format_csv
from ..fmu.instance import Fmu, FmuError
from ..revolution import TWO_PI
from .conditioning import SPARSE_REACH, complete, window_counts
from .core import SUMMARY_FIELDS, DataError, Options, Twin, _Segment
from .line_input import chunks_of

#: 3: the smoothing window is a time (pieces of a version 2 work folder were planned and computed
#: with a window of samples; they are not reused).
MANIFEST_VERSION = 3

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
        self.seg_part = 0

    def _drain(self, final: bool, rows: list) -> None:
        b = self.buf
        if len(b.t):
            if self.seg_n == 0:
                self.seg_line = int(b.line[0])
                self.seg_part = len(self.parts)
            self.parts.append((b.line, b.t, b.theta, b.speed, b.force))
            self.seg_n += len(b.t)
            self.buf = _Segment()
        if final:
            if 0 < self.seg_n < 4:
                raise DataError(
                    f"line {self.seg_line}: a segment of {self.seg_n} sample(s) between gaps is "
                    "too short (at least 4 are needed)"
                )
            if self.seg_n:
                # The sparse windows of the segment, reported as the sequential twin does.
                seg = self.parts[self.seg_part :]
                t = np.concatenate([p[1] for p in seg])
                line = np.concatenate([p[0] for p in seg])
                self._note_sparse(window_counts(t, 0.5 * self.o.window), line, t)
                self._close_sparse()
            self.seg_n = 0

    def arrays(self) -> dict:
        cols = list(zip(*self.parts)) if self.parts else [[np.empty(0)]] * 5
        names = ("line", "t", "theta", "speed", "force")
        return {n: np.concatenate(c) for n, c in zip(names, cols)}


@dataclass
class Scanned:
    data: dict  # line, t, theta, speed, force of every accepted sample
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
COLUMNS = (
    "time",
    "crank_angle",
    "crank_speed",
    "process_force",
    "discharge_pressure",
    "suction_pressure",
)


def is_sqlite(path) -> bool:
    """An SQLite database file (its 16-byte header)."""
    try:
        with open(path, "rb") as f:
            return f.read(16) == b"SQLite format 3\x00"
    except OSError:
        return False


def _csv_lines(rows) -> list[str]:
    """A database's rows as the lines of a CSV file: a REAL as repr writes it (the same double
    back), NULL as an empty field (refused by the twin like an empty CSV field)."""
    return [
        ",".join("" if v is None else repr(v) if isinstance(v, float) else str(v) for v in r)
        for r in rows
    ]


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
            yield _csv_lines(got)
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
                yield _csv_lines(got)
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


def exact_tail(t: np.ndarray, half: float, gap_limit: float, m: int, a: int, b: int) -> int:
    """The end f (<= b, the end of the segment a..b) of a piece whose rows up to sample m must be
    exact: the window of m (conditioning.window: a window after the segment's start where it is
    shifted inward there, or half a window after m and at most the gap limit further where a
    dropout left that side short, with a sample beyond) ends before the piece's last sample,
    which then shifts none of them, and SPARSE_REACH samples follow m (a sparse window)."""
    end = t[a] + 2.0 * half if t[m] - half < t[a] else t[m] + half + gap_limit
    j = int(np.searchsorted(t, end, side="left"))
    return min(b, max(j + 2, m + SPARSE_REACH + 1))


def exact_rows(t: np.ndarray, half: float, seg_end: bool) -> int:
    """How many leading rows of a piece computed from the samples at times t are exact: all of
    them if its last sample ends the segment; else those whose window no later sample changes
    (conditioning.complete, Twin._ready's rule; the piece's twin starts its segment at t[0])."""
    if seg_end:
        return len(t)
    return complete(t, half, float(t[0]))


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
    half, gap = 0.5 * sc.options.window, sc.options.gap_limit
    pieces = []
    extra = sorted(int(c) for c in cuts)
    for a, b in zip(bounds[:-1], bounds[1:]):
        cuts_at = [a]
        if revolutions_per_piece:
            # At the model angle's revolution boundaries (crank angle + crank.angle_offset,
            # docs/fmi-interface.md): the last revolution of a piece then ends at its cut, and
            # the tail is only the smoothing window's half-width.
            # The running maximum: revolutions are bounded by the first sample reaching 2πk
            # whichever way the crank turned before (docs/twin.md "Machine states").
            ma = np.maximum.accumulate(th[a:b] + sc.offset)
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
            # Warm-up (docs/twin.md "Conditioning"): the rows from a few samples before s are
            # exact (a revolution starting at s needs the row before it): their windows reach
            # back half a window, and at most the gap limit and a sample further where a
            # dropout left that side short, a whole window before the segment's end (shifted
            # inward there), and SPARSE_REACH samples (a sparse window). The piece starts a
            # sample before the last one at or before that, so its own start shifts none of
            # them. Then the cage's.
            x = max(a, s - SPARSE_REACH)
            reach = min(t[x] - half - gap, t[b - 1] - 2.0 * half)
            w = int(np.searchsorted(t, reach, side="right")) - 2
            w = max(a, min(w, x - SPARSE_REACH))
            if warm_s > 0 and s > a:
                w = min(w, max(a, int(np.searchsorted(t, t[s] - warm_s, side="right")) - 1))
            # Tail: the rows to sample m must be exact, and the revolution in progress at e
            # completes within 2π of the angle reached at e-1 (model angle = crank angle + a
            # constant; the running maximum, as the crank may stand or turn back).
            if e < b and e in aligned:
                # A boundary found from the crank angle may be a sample off the FMU's own.
                m = e + 2
            elif e < b:
                reached = np.maximum.accumulate(th[a:b])
                m = int(np.searchsorted(reached, reached[e - 1 - a] + TWO_PI, side="right")) + a + 2
                m = max(e, m)
            f = b if e >= b else exact_tail(t, half, gap, min(m, b - 1), a, b)
            # The angle reached before the piece: a revolution first reached there belongs to
            # an earlier piece even if the crank, having turned back, reaches it again here.
            prior = float(np.max(th[a:s]) + sc.offset) if s > a else None
            pieces.append([s, e, w, f, f == b, prior])
    return pieces


#: FMUs loaded in this (worker) process, by path.
_LOADED: dict = {}


def load_fmu(fmu_key_or_path) -> Fmu:
    """On a worker: the FMU (shipped by the client, or a path), loaded once per process."""
    from ..cluster import _RECEIVED, local_fmu

    path = local_fmu(fmu_key_or_path) if fmu_key_or_path in _RECEIVED else fmu_key_or_path
    fmu = _LOADED.get(path)
    if fmu is None:
        fmu = _LOADED[path] = Fmu(path)
    return fmu


def warm_worker(fmu_key_or_path) -> None:
    """Run on every worker before the pieces: imports and the FMU's loading happen once, not
    in the first piece (client.run)."""
    load_fmu(fmu_key_or_path)


def piece_text(fmu_key_or_path, values, options: dict, cols: dict, offset: float,
               piece, arrays, buffer: bytearray | None = None):  # fmt: skip
    """On a worker: one piece's rows and summaries as CSV text: (rows, summaries, number of rows).
    The rows are bytes, or with `buffer` a memoryview into it (formatted in place: a piece's
    ~2.5 MB of text neither allocated afresh nor copied); release it before the buffer is used
    again."""
    # One loaded FMU per worker process, re-initialized at each piece's first sample as the
    # sequential twin re-initializes it after a gap (fmi2Reset, then initialization).
    fmu = load_fmu(fmu_key_or_path)
    s, e, w, f = piece[:4]
    line, t, theta, speed, force = arrays
    o = Options(**options)
    tw = Twin(fmu, "default", o, values)
    tw.cols = cols
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
    exact_end = exact_rows(t, 0.5 * o.window, seg_end)
    # A revolution belongs to the piece where the crank angle + offset first reaches its start:
    # the rule the planner cuts by (the same doubles), so each is written exactly once.
    model = theta + offset
    prior = piece[5] if len(piece) > 5 else None
    keep = []
    for sm in sums + sums2:
        r = sm["revolution"]
        if prior is not None and prior >= TWO_PI * r:
            continue  # first reached before this piece (the crank turned back since)
        j = int(np.argmax(model >= TWO_PI * r))
        if s <= w + j < e:
            done = int(np.argmax(ang >= TWO_PI * (r + 1)))
            if done + 1 >= exact_end and not seg_end:
                raise RuntimeError(f"piece {piece}: revolution {r} ends past the exact tail")
            keep.append(sm)
    summ = "".join(
        ",".join("" if sm[k] is None else repr(sm[k]) for k in SUMMARY_FIELDS) + "\n" for sm in keep
    ).encode()
    out = format_csv(allrows[s - w : e - w], buffer)
    return (bytes(out) if buffer is None else out), summ, e - s


def run_piece(fmu_key_or_path, values, options: dict, cols: dict, offset: float,
              piece, arrays):  # fmt: skip
    """On a worker: the formatted rows and summaries of one piece (bytes, bytes, rows, CPU
    seconds of this thread)."""
    cpu = time.thread_time()
    out, summ, n = piece_text(fmu_key_or_path, values, options, cols, offset, piece, arrays)
    return out, summ, n, time.thread_time() - cpu


def run_group(fmu_key_or_path, values, options, cols, offset, items):
    """On a worker of a cluster that shares no disk: consecutive pieces, one Dask task
    (docs/twin.md "Distributed replay", Speed: the scheduler's cost is per task, not per
    sample). `items` holds (index, piece, arrays) in order; the result is the list of each
    piece's (bytes, bytes, rows, CPU seconds)."""
    return [
        run_piece(fmu_key_or_path, values, options, cols, offset, piece, arrays)
        for _, piece, arrays in items
    ]


#: The file by which a stopped client tells its LocalCluster's workers to start no more pieces.
STOP = "stop"

#: The output's rows as they are assembled, in the work folder (renamed to --out at the end).
ROWS = "rows.csv"

#: The scanned arrays in a work folder that the workers share (`save_inputs`), by name.
INPUT_NAMES = ("line", "t", "theta", "speed", "force")


def save_inputs(work: pathlib.Path, data: dict) -> None:
    """The scanned samples, one .npy file per array, for the workers of a LocalCluster (which
    share the client's disk): each worker maps them (`run_claimed`) instead of receiving its
    pieces' samples through the scheduler, which would cost the client, which hosts that
    scheduler, CPU on the cores the workers need (docs/twin.md "Distributed replay", Speed)."""
    for name in INPUT_NAMES:
        tmp = work / f"input-{name}.tmp.npy"
        np.save(tmp, np.ascontiguousarray(data[name]))
        os.replace(tmp, work / f"input-{name}.npy")


def _claim(work: pathlib.Path, i: int) -> bool:
    """Piece i taken by this worker for this run: the first to create its claim file (O_EXCL,
    atomic on a local file system) computes it; the client removes stale claims first."""
    try:
        os.close(os.open(work / f"claim-{i:06d}", os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644))
        return True
    except FileExistsError:
        return False


def clear_claims(work: pathlib.Path, indices) -> None:
    """Before a round: the claims and lengths of an earlier round or run (a piece claimed by a
    worker that died is claimed afresh)."""
    for i in indices:
        (work / f"claim-{i:06d}").unlink(missing_ok=True)
        _len_path(work, i).unlink(missing_ok=True)


def _len_path(work: pathlib.Path, i: int) -> pathlib.Path:
    return work / f"len-{i:06d}"


def _piece_len(work: pathlib.Path, i: int) -> int | None:
    """The length of piece i's rows text, once a worker has computed it (its length file) or
    written it (its record); None before."""
    try:
        return int(_len_path(work, i).read_bytes())
    except (OSError, ValueError):
        pass
    try:
        return int(json.loads(_names(work, i)[2].read_text())["out"][0])
    except (OSError, ValueError, KeyError, TypeError, IndexError):
        return None


class _Offsets:
    """Where each piece's rows start in the work folder's rows file: after the header and every
    earlier piece's rows, known as soon as every earlier piece is computed (their lengths)."""

    def __init__(self, work: pathlib.Path, first: int):
        self.work = work
        self.starts = [first]  # starts[k] of pieces 0..len-1

    def of(self, i: int) -> int | None:
        while len(self.starts) <= i:
            n = _piece_len(self.work, len(self.starts) - 1)
            if n is None:
                return None
            self.starts.append(self.starts[-1] + n)
        return self.starts[i]


def run_claimed(fmu_key_or_path, values, options, cols, offset, items, work: str,
                first: int) -> int:  # fmt: skip
    """On a worker of a LocalCluster: takes the pieces `items` ((index, piece) in order) that no
    other worker has claimed, one at a time in order, computes each from the mapped input
    (`save_inputs`) and writes its rows straight into the rows file of the work folder at their
    place (`first` is the header's length). Every worker runs one such task over the same
    list, so the pieces are dealt out as the workers free up and end nearly in order; Dask sees
    one task per worker, and the client copies almost no text (docs/twin.md "Distributed
    replay", Speed). A piece whose place is not known yet (an earlier one still computing on another
    worker) waits in memory and is placed after this worker's next piece; at the end of the
    list one still waiting is written to its own file, which the client places. Returns the
    number of pieces this task computed. A piece claimed by a worker that died is computed in
    the client's next round (`clear_claims`)."""
    folder = pathlib.Path(work)
    arrays = [np.load(folder / f"input-{n}.npy", mmap_mode="r") for n in INPUT_NAMES]
    offsets = _Offsets(folder, first)
    buffer = _TEXT.__dict__.setdefault("buffer", bytearray())
    waiting: list = []  # (index, rows bytes, summaries, CPU seconds)
    fd = os.open(folder / ROWS, os.O_WRONLY)
    done = 0
    try:
        for i, piece in items:
            if (folder / STOP).exists():
                break  # the client stopped: the pieces not written are computed by a resumed run
            if not _claim(folder, i):
                continue
            cpu = time.thread_time()
            w, f = piece[2], piece[3]
            mine = tuple(np.array(x[w:f]) for x in arrays)  # writable copies, as Dask's would be
            out, summ, _ = piece_text(
                fmu_key_or_path, values, options, cols, offset, piece, mine, buffer
            )
            try:
                _atomic_write(_len_path(folder, i), str(len(out)).encode(), sync=False)
                at = offsets.of(i)
                if at is not None:
                    _place(fd, folder, i, out, summ, at, cpu)
                else:
                    waiting.append((i, bytes(out), summ, time.thread_time() - cpu))
            finally:
                if isinstance(out, memoryview):  # b"" for a piece without rows
                    out.release()  # the buffer can grow again for the next piece
            done += 1
            waiting = [x for x in waiting if not _place_waiting(fd, folder, offsets, x)]
        for i, out, summ, cpu in waiting:
            if not _place_waiting(fd, folder, offsets, (i, out, summ, cpu)):
                write_piece(folder, i, out, summ, cpu=cpu)
    finally:
        os.close(fd)
    return done


def _place_waiting(fd, folder, offsets, item) -> bool:
    i, out, summ, cpu = item
    at = offsets.of(i)
    if at is None:
        return False
    _place(fd, folder, i, out, summ, at, None, cpu)
    return True


def _place(fd, folder, i, out, summ, at, cpu0, cpu=None) -> None:
    """Piece i's rows written into the rows file at `at`, its summaries to their file, then its
    record (last: a piece without a valid record is computed again)."""
    view = memoryview(out)
    done = 0
    while done < len(view):
        done += os.pwrite(fd, view[done:], at + done)
    view.release()
    p_out, p_rev, p_rec = _names(folder, i)
    _atomic_write(p_rev, summ, sync=False)
    p_out.unlink(missing_ok=True)
    rec = {
        "out": [len(out), zlib.crc32(out)],
        "rev": [len(summ), zlib.crc32(summ)],
        "at": at,
        "cpu": (time.thread_time() - cpu0) if cpu is None else cpu,
    }
    _atomic_write(p_rec, json.dumps(rec).encode(), sync=False)


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


def open_work(work: pathlib.Path, manifest: dict, header: bytes) -> set:
    """Creates the work folder with its manifest and its rows file (`header` first), or checks
    an existing one against `manifest` (ReplayError naming what differs). Returns the indices of
    the pieces already written."""
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
        _rows_file(work, header)
        return {i for i in range(len(manifest["pieces"])) if _piece_ok(work, i)}
    work.mkdir(parents=True, exist_ok=True)
    _rows_file(work, header)
    _atomic_write(mpath, json.dumps({**manifest, "sha256": _digest(manifest)}).encode())
    return set()


def _rows_file(work: pathlib.Path, header: bytes) -> None:
    """The rows file, begun with the header (made afresh if it does not begin with it: the
    pieces placed in it then fail their check and are computed again)."""
    path = work / ROWS
    try:
        with open(path, "rb") as fh:
            if fh.read(len(header)) == header:
                return
    except FileNotFoundError:
        pass
    with open(path, "wb") as fh:
        fh.write(header)


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
    """A piece written completely: its record's sizes and CRC-32 match its summaries' file and
    its rows, in their own file or at their place in the rows file (a check against damage,
    which a crash or a cut can do; the manifest holds the input's SHA-256)."""
    out, rev, rec = _names(work, i)
    try:
        r = json.loads(rec.read_text())
        if r.get("at") is None:
            data = out.read_bytes()
        else:
            with open(work / ROWS, "rb") as fh:
                fh.seek(int(r["at"]))
                data = fh.read(int(r["out"][0]))
        if len(data) != r["out"][0] or zlib.crc32(data) != r["out"][1]:
            return False
        data = rev.read_bytes()
        return len(data) == r["rev"][0] and zlib.crc32(data) == r["rev"][1]
    except (OSError, ValueError, KeyError, TypeError, IndexError):
        return False


def write_piece(
    work: pathlib.Path, i: int, out: bytes, rev: bytes, cpu: float | None = None
) -> None:
    """The piece's rows and summaries in files of their own, then its record (last: a piece
    without a valid record is computed again); the client places the rows (`Assembler`). Not
    synced: a piece whose files do not match its record's CRC-32 after a crash is computed
    again, so the sync buys nothing. `cpu`: the CPU seconds of the piece on its worker."""
    p_out, p_rev, p_rec = _names(work, i)
    _atomic_write(p_out, out, sync=False)
    _atomic_write(p_rev, rev, sync=False)
    rec = {
        # CRC-32, not SHA-256: a third of the time on the worker, and damage is what it finds.
        "out": [len(out), zlib.crc32(out)],
        "rev": [len(rev), zlib.crc32(rev)],
    }
    if cpu is not None:
        rec["cpu"] = cpu
    _atomic_write(p_rec, json.dumps(rec).encode(), sync=False)


def header_bytes(header: list) -> bytes:
    return (",".join(header) + "\n").encode()


class Assembler:
    """The output files, made from the pieces in order while later pieces still run. The rows
    grow in the work folder's rows file, where the workers of a LocalCluster write their
    pieces' rows at their place themselves (`run_claimed`); a piece that arrives in a file of
    its own (from a cluster that shares no disk, or one whose worker did not know its place) is
    copied to its place here, in the kernel, as soon as every piece before it is written. The
    summaries (small) are appended to `<summary>.tmp`. `finish` syncs both and renames them
    over the outputs; `abort` removes the summaries' file (the pieces and the rows file stay in
    the work folder for a resumed run)."""

    def __init__(self, work: pathlib.Path, n: int, out: pathlib.Path, summary, header: list):
        self.work, self.n, self.out, self.summary = work, n, out, summary
        self.rows = open(work / ROWS, "r+b")
        self.summ = open(summary.with_name(summary.name + ".tmp"), "wb")
        self.summ.write(header_bytes(header))
        self.ready: set = set()
        self.next = 0
        self.at = len(self.rows.readline())  # where the next piece's rows start: after the header
        # The rows reach the disk while the pieces run (a thread's fdatasync every 50 ms), so that
        # the sync at the end, in the replay's sequential part, has only the last ones left.
        self._stop_sync = threading.Event()
        self._sync = threading.Thread(target=self._sync_rows, name="rows-sync", daemon=True)
        self._sync.start()

    def _sync_rows(self) -> None:
        while not self._stop_sync.wait(0.05):
            try:
                os.fdatasync(self.rows.fileno())
            except (OSError, ValueError):  # closed meanwhile (abort), or a file system without
                return

    def add(self, i: int) -> None:
        self.ready.add(i)
        while self.next in self.ready:
            k = self.next
            p_out, p_rev, p_rec = _names(self.work, k)
            rec = json.loads(p_rec.read_text())
            n = int(rec["out"][0])
            if rec.get("at") is None:
                with open(p_out, "rb") as src:
                    _copy_to(src, self.rows, n, self.at)
                # The record says where the rows are now (a resumed run checks them there); the
                # piece's own file goes after it.
                _atomic_write(p_rec, json.dumps({**rec, "at": self.at}).encode(), sync=False)
                p_out.unlink(missing_ok=True)
            elif int(rec["at"]) != self.at:
                raise RuntimeError(f"piece {k}: its rows are at {rec['at']}, not at {self.at}")
            with open(p_rev, "rb") as src:
                shutil.copyfileobj(src, self.summ)
            self.at += n
            self.ready.discard(k)
            self.next += 1

    def finish(self) -> None:
        if self.next != self.n:
            raise RuntimeError(f"{self.n - self.next} pieces not assembled")
        self._end_sync()
        if os.fstat(self.rows.fileno()).st_size != self.at:
            self.rows.truncate(self.at)
        for fh in (self.rows, self.summ):
            fh.flush()
            os.fsync(fh.fileno())
            fh.close()
        # An earlier output at --out keeps a second name in the work folder, which is removed
        # after the result is in place: freeing its blocks (tens of MB: milliseconds, with the
        # disk's discard) is not on the way to the result.
        with contextlib.suppress(OSError):
            os.link(self.out, self.work / "superseded.csv")
        _move(self.work / ROWS, self.out)
        os.replace(self.summ.name, self.summary)

    def _end_sync(self) -> None:
        self._stop_sync.set()
        if self._sync.is_alive():
            self._sync.join()

    def abort(self) -> None:
        self._end_sync()
        self.rows.close()
        self.summ.close()
        pathlib.Path(self.summ.name).unlink(missing_ok=True)


def _move(src: pathlib.Path, dst: pathlib.Path) -> None:
    """Renamed; across file systems (a --work-dir elsewhere) copied beside `dst`, synced and
    renamed over it."""
    try:
        os.replace(src, dst)
    except OSError as e:
        if e.errno != errno.EXDEV:
            raise
        tmp = dst.with_name(dst.name + ".tmp")
        with open(src, "rb") as a, open(tmp, "wb") as b:
            _copy_to(a, b, os.fstat(a.fileno()).st_size, 0)
            b.flush()
            os.fsync(b.fileno())
        os.replace(tmp, dst)
        src.unlink()


def _copy_to(src, dst, size: int, at: int) -> None:
    """`size` bytes of the file `src` written into `dst` at `at`, in the kernel
    (os.copy_file_range) where it can (the copy is in the replay's sequential part)."""
    done = 0
    try:
        while done < size:
            k = os.copy_file_range(src.fileno(), dst.fileno(), size - done, done, at + done)
            if k == 0:
                break
            done += k
    except OSError:
        pass
    while done < size:
        chunk = os.pread(src.fileno(), min(size - done, 1 << 20), done)
        if not chunk:
            raise RuntimeError(f"{src.name}: {size - done} bytes short")
        done += os.pwrite(dst.fileno(), chunk, at + done)


def machine_cpu() -> tuple[int, int] | None:
    """(busy, total) clock ticks of all the machine's cores since boot (Linux's /proc/stat:
    busy is everything but idle and waiting for I/O), or None elsewhere."""
    try:
        with open("/proc/stat") as f:
            ticks = [int(x) for x in f.readline().split()[1:]]
    except (OSError, ValueError):
        return None
    total = sum(ticks[:8])  # user nice system idle iowait irq softirq steal (guest is in user)
    return total - ticks[3] - ticks[4], total


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
        self.machine0 = machine_cpu()

    def stop(self, client_cpu: float) -> None:
        """The pieces are all written (or the run stopped): the clock and the CPU counts."""
        self.t_end = time.monotonic()
        self.client_cpu = client_cpu
        self.machine1 = machine_cpu()

    def machine_busy(self) -> float | None:
        """The share of the machine's cores that was busy while the pieces ran (every process,
        the kernel's too), or None where the kernel does not say (no /proc/stat)."""
        a, b = getattr(self, "machine0", None), getattr(self, "machine1", None)
        if a is None or b is None or b[1] <= a[1]:
            return None
        return (b[0] - a[0]) / (b[1] - a[1])

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
