"""The twin in a plant (docs/plant.md): source -> the twin's core -> database sinks.

    from reciprocating_drive.plant.pipeline import run_config
    sys.exit(run_config("examples/twin/replay-sqlite.toml"))

A source hands out chunks of input lines and data-health events; `Twin.feed` turns them into
per-sample rows and revolution summaries; every sink gets them all and commits them, every
`commit_interval` seconds or `commit_samples` input lines, in ONE transaction with the checkpoint
that covers them (the twin's state: FMU state, input position, conditioning buffers, and the
counts of rows, summaries and events handed out). Restarted with the same configuration, the
pipeline resumes from the last committed checkpoint (docs/plant.md "Exactly once").

Layer: workflows, the plant (docs/architecture.md).
"""

from __future__ import annotations

import os
import pathlib
import signal
import sys
import tempfile
import time
import traceback

from ..cli_errors import one_line
from ..fmu.instance import FmuError
from ..mission import is_pump
from ..twin.core import DataError, Options, Twin
from .config import Config, ConfigError, load
from .samples import Event, input_lines
from .sinks.base import Counters, RunInfo, SinkError
from .sources.base import SourceError


def make_source(cfg: Config):
    s = cfg.source
    if s.type == "stdin" or (
        s.type == "csv" and (s.settings["follow"] or s.settings["path"] == "-")
    ):
        from .sources.stream import StreamSource

        return StreamSource(s.settings["path"], follow=s.settings["follow"], run_id=cfg.run_id)
    if s.type == "csv":
        from .sources.csv import CsvSource

        return CsvSource(s.settings["path"], pace=s.settings["pace"])
    from .sources.opcua import OpcUaSource

    src = OpcUaSource(s.settings, password=s.password, config_path=cfg.path)
    src.gap_limit = cfg.options["gap_limit"]  # a clock step back ends in a gap (docs/plant.md)
    return src


def make_sinks(cfg: Config) -> list:
    out = []
    for s in cfg.sinks:
        common = {
            k: s.settings[k] for k in ("samples", "retry_for", "retry_max", "notice_interval")
        }
        if s.type != "csv":
            common.update(
                keep_samples=s.settings["keep_samples"], keep_input=s.settings["keep_input"]
            )
        if s.type == "sqlite":
            from .sinks.sqlite import SqliteSink

            out.append(SqliteSink(s.settings["path"], **common))
        elif s.type == "csv":
            from .sinks.csv import CsvSink

            out.append(
                CsvSink(
                    s.settings["path"],
                    summary=s.settings["summary"],
                    checkpoint=s.settings["checkpoint"],
                    **common,
                )
            )
        else:
            from .sinks.postgres import PostgresSink

            out.append(PostgresSink(s.settings["dsn"], password=s.password, **common))
    return out


def make_page(cfg: Config, on_alarm):
    """The live page of the [page] table (docs/page.md), or None. Its trends read the first SQLite
    sink. The page is handed what the sinks get but is not one of them: it keeps nothing durable
    (its alarms' state goes into the twin's checkpoint instead)."""
    if cfg.page is None:
        return None
    from ..page import PageError
    from ..page.config import page_from_table

    sqlite = next((s for s in cfg.sinks if s.type == "sqlite"), None)
    try:
        page = page_from_table(
            cfg.page,
            cfg.path,
            base=pathlib.Path(cfg.path).resolve().parent,
            database=sqlite.settings["path"] if sqlite else None,
            run=cfg.run_id,
            on_alarm=on_alarm,
        )
    except PageError as e:  # a bad [page] table or limits file: a configuration error (exit 2)
        raise ConfigError(str(e)) from None
    if sqlite:
        from .query import page_recompute

        page.recompute = page_recompute(sqlite.settings["path"], cfg.run_id)
    return page


def _make_twin(cfg: Config, opts: dict) -> Twin:
    """The twin of the configuration. The twin names what it refuses as its command's options
    (--machine, --fmu); here they are the keys run.machine and run.fmu of the file (exit 2)."""
    try:
        return Twin(cfg.fmu, cfg.machine, Options(**opts))
    except ValueError as e:
        text = str(e)
        for option, key in (("--machine ", "run.machine = "), ("--fmu ", "run.fmu = ")):
            if text.startswith(option):
                text = key + text[len(option) :]
        raise ConfigError(f"{cfg.path}: {text}") from None


class Pipeline:
    def __init__(self, cfg: Config, log=None, stop_after: float | None = None):
        self.cfg = cfg
        self.log = log or (lambda m: print(m, file=sys.stderr, flush=True))
        self.stop_signal = None
        # `rdrive plant --demo --seconds S`: the run stops after S seconds as asked (exit 0).
        self.stop_after = stop_after
        self.timed_out = False
        self.commits = 0
        self.page = None
        self.page_origin = None

    def _on_alarm(self, change) -> None:
        """An alarm raised or cleared (alarms.py): the log, and an event every sink stores."""
        self.log(change.message)
        self._event(Event("alarm", change.message, t=change.t))

    # ---- events and hand-over -------------------------------------------------------------------
    def _event(self, ev: Event) -> None:
        self.events.append((self.c.events, time.time(), ev))
        self.c.events += 1
        if ev.kind == "dropped":
            why = ev.reason or "other"
            self.drops[why] = self.drops.get(why, 0) + ev.count

    def _hand(self, rows, summaries) -> None:
        first = self.twin.rows_out - len(rows)
        self._twin_events()
        events, self.events = self.events, []
        for s in self.sinks:
            s.add(rows, first, summaries, self.c.revolutions, events)
        if self.page is not None:
            origin = self.source_origin()
            if origin != self.page_origin:  # a live source's clock, known from its first sample
                self.page_origin = origin
                self.page.clock(origin)
            self.page.add(rows, first, summaries, self.c.revolutions, events)
        if len(rows):
            self.last_row_t = float(rows[-1, 0])
            if self.block_t0 is None:  # the run's first block: from its first sample's time
                self.block_t0 = float(rows[0, 0])
        self.c.samples = self.twin.rows_out
        self.c.revolutions += len(summaries)
        if summaries:
            self.c.rev_upto = int(summaries[-1]["revolution"])
        self.dirty = True

    def _twin_events(self) -> None:
        tw = self.twin
        for gap in tw.gaps[self.gaps_seen :]:
            # One event per gap, its text made from the gap itself (the twin's other messages,
            # such as the separator it detected, are not gaps).
            if tuple(gap) != self.last_gap:
                t0, t1 = gap
                msg = tw.gap_notes.get(
                    (t0, t1),
                    f"gap of {t1 - t0:.6g} s from t = {t0!r} s to {t1!r} s: the FMU is "
                    "re-initialized after it",
                )
                self._event(Event("gap", msg, t=t0))
                self.gap_count += 1
            self.last_gap = tuple(gap)
        self.gaps_seen = len(tw.gaps)
        # The machine's state changes (docs/twin.md "Machine states"), as machine_stopped,
        # machine_started, machine_reversed (`started` is the run's own start).
        new = tw.motion_count - self.motion_seen
        for ev in tw.motion_events[len(tw.motion_events) - min(new, len(tw.motion_events)) :]:
            self._event(Event(f"machine_{ev[0]}", tw.motion_message(ev), t=ev[1]))
        self.motion_seen = tw.motion_count
        for line, n in tw.short_dropped[self.short_seen :]:
            self._event(
                Event(
                    "dropped",
                    f"{n} sample(s) from input line {line} dropped: a segment between gaps too "
                    "short for the local cubic (at least 4 samples)",
                    count=n,
                )
            )
        self.short_seen = len(tw.short_dropped)
        # A sparse stretch once it has ended (the twin extends the last one while it goes on).
        closed = len(tw.sparse) - tw.sparse_open
        for sp in tw.sparse[self.sparse_seen : closed]:
            self._event(Event("sparse", tw.sparse_message(sp), t=sp[1], count=sp[3]))
        self.sparse_seen = max(self.sparse_seen, closed)
        if tw.duplicates > self.dups_seen:
            n = tw.duplicates - self.dups_seen
            self._event(Event("duplicates", f"{n} duplicate timestamp(s) dropped", count=n))
            self.dups_seen = tw.duplicates

    def _commit(self, status: str | None = None, checkpoint: bool = True) -> None:
        for s in self.sinks:
            if s.retries:
                self._event(
                    Event("sink_retry", f"{s.notes[0]} ({s.retries} retries)", count=s.retries)
                )
                s.retries, s.notes = 0, []
        self._hand(self.twin._empty(), [])
        state = None
        if checkpoint or status is not None:
            state = {
                "twin": self.twin.checkpoint(),
                "time_origin": self.source_origin(),
                "duplicates_reported": self.dups_seen,
                "gaps_reported": self.gap_count,
            }
            if self.page is not None and self.page.engine is not None:
                state["alarms"] = self.page.engine.checkpoint()
            state["last_row_t"] = self.last_row_t
            self.last_checkpoint = time.monotonic()
            self.lines_since_checkpoint = 0
            self._store_input(state["twin"])
        origin = self.source_origin()
        for s in self.sinks:
            s.batch.origin = origin  # stored at once: a restart reads the history from it
            s.commit(state, self.c, status)
        if status is not None:
            for s in self.sinks:
                s.flush()
        self.commits += 1
        self.dirty = False
        self.last_commit = time.monotonic()
        self.lines_since = 0

    def _store_input(self, twin_state: dict) -> None:
        """The input lines consumed since the last checkpoint, as a block that commits with it,
        and a snapshot of the twin every `snapshot_interval` s of input time (docs/plant.md
        "Storage"): what a recomputation of any range starts from."""
        tw = self.twin
        t_in = tw.last_t
        if self.last_snap_t is None:
            self.last_snap_t = t_in
        elif t_in is not None and t_in - self.last_snap_t >= self.cfg.snapshot_interval:
            self.snaps.append((tw.lines_read, tw.rows_out, self.last_row_t, t_in, twin_state))
            self.last_snap_t = t_in
        self.c.lines = tw.lines_read
        for s in self.sinks:
            s.add_input(self.block_first, self.block_lines, self.block_t0, t_in, self.snaps)
        self.block_first, self.block_lines = tw.lines_read + 1, []
        self.block_t0, self.snaps = t_in, []

    def _check_input(self) -> list[str]:
        """The stored input's blocks checked at resume (docs/plant.md "Storage"): a damaged one
        is named with its lines and times; the run goes on (only that range cannot be
        recomputed)."""
        from .query import Database, QueryError, check_blocks

        out = []
        for sc in self.cfg.sinks:
            if sc.type == "csv":
                continue
            try:
                db = Database(sc.settings.get("path") or sc.settings["dsn"], sc.password)
                out += check_blocks(db, self.cfg.run_id)
                db.conn.close()
            except QueryError as e:
                out.append(str(e))
        return out

    def source_origin(self):
        """Unix seconds of the twin's time 0: the source's clock (OPC UA), or the input's ISO 8601
        timestamps (docs/twin.md "Timestamps"); None for times in seconds."""
        origin = getattr(self.source, "time_origin", None)
        if origin is None and getattr(self, "twin", None) is not None:
            origin = self.twin.time_origin
        return origin

    # ---- the run --------------------------------------------------------------------------------
    def run(self) -> int:
        cfg = self.cfg
        self.source = make_source(cfg)
        if hasattr(self.source, "log"):
            self.source.log = self.log  # the source's own lines (an unresponsive server)
        self.sinks = make_sinks(cfg)
        for s in self.sinks:
            s.log = self.log  # a database that stops answering (sinks/base.py)
        try:
            self.page = make_page(cfg, self._on_alarm)
            if self.page is not None:
                from ..page import PageError

                try:
                    self.page.start()
                except PageError as e:  # a port in use: one line, as for any option (exit 2)
                    self.page = None
                    raise ConfigError(str(e)) from None
                self.log(f"page: http://{self.page.host}:{self.page.port}/")
            try:
                return self._run()
            except Exception as e:  # a source or sink that failed: the page says so too
                self._page_end("failed", str(e) or type(e).__name__)
                raise
        finally:
            if self.page is not None:
                self.page.close()
            self.source.close()
            for s in self.sinks:
                try:
                    s.flush()
                finally:
                    s.shutdown()

    def _run(self) -> int:
        cfg = self.cfg
        opts = dict(cfg.options)
        if getattr(self.source, "live", True):
            # A live source's reconnect can leave a sample or two between two gaps: dropped and
            # reported (an event), not a reason to stop a twin that runs for months.
            opts.setdefault("short_segments", "drop")
        twin = _make_twin(cfg, opts)
        info = RunInfo(
            cfg.run_id,
            cfg.machine_id,
            cfg.machine,
            twin.outputs,
            cfg.options,
            cfg.source.public(),
            header=twin.header_with_units(),
            fmu_guid=twin.fmu.model_description.guid,
        )
        states = [s.open(info) for s in self.sinks]
        have = [st for st in states if st is not None]
        state = None
        if have and (len(have) == len(states) or not self.source.rewindable):
            state = min(have, key=lambda st: st["counters"]["samples"])
        if (
            state is not None
            and state.get("status") == "finished"
            and all(st is not None and st.get("status") == "finished" for st in states)
        ):
            self.log(f"run {cfg.run_id!r} is already finished in every sink; nothing to do")
            return 0
        self.c = Counters()
        self.events: list = []
        self.drops: dict = {}  # reason -> samples dropped (this process's share of the run)
        self.dups_seen = 0
        if state is not None:
            try:
                twin = Twin.from_checkpoint(cfg.fmu, state["twin"])
            except (KeyError, TypeError, ValueError, IndexError) as e:
                # The counters were checked (sinks/base.py parse_state); the twin's part too.
                raise SinkError(
                    f"{', '.join(s.name for s in self.sinks)}: the checkpoint of run "
                    f"{cfg.run_id!r} is damaged: the twin's state is not readable "
                    f"({type(e).__name__}: {one_line(e, 80)}); restore the database from a copy, "
                    "or name a new run"
                ) from None
            c = state["counters"]
            self.c = Counters(
                c["samples"], c["revolutions"], c["events"], 0, c.get("rev_upto"), twin.lines_read
            )
            self.dups_seen = state.get("duplicates_reported", 0)
            # Several sinks: those ahead go back to the checkpoint that covers least, so that
            # all hold the same events, numbered alike (docs/plant.md "Exactly once").
            key = ("samples", "revolutions", "events")
            for s, st in zip(self.sinks, states):
                if st is not None and any(st["counters"][k] != c[k] for k in key):
                    s.rewind(state)
        self.twin = twin
        self.last_row_t = state.get("last_row_t") if state else None
        # The stored input (docs/plant.md "Storage"): a fresh run's first snapshot is the twin
        # before any line, so that every range can be recomputed.
        self.snaps = [] if state else [(0, 0, None, None, twin.checkpoint())]
        self.last_snap_t = twin.last_t
        self.block_first, self.block_lines, self.block_t0 = twin.lines_read + 1, [], twin.last_t
        # A run without a checkpoint whose time origin is stored (killed before its first
        # checkpoint): an OPC UA source reads the server's history from the run's first sample.
        origin = state.get("time_origin") if state else None
        if state is None:
            origin = next(
                (s.stored_origin for s in self.sinks if s.stored_origin is not None), None
            )
        self.gaps_seen, self.short_seen = len(twin.gaps), len(twin.short_dropped)
        self.motion_seen = twin.motion_count
        self.sparse_seen = len(twin.sparse) - twin.sparse_open
        self.last_gap = tuple(twin.gaps[-1]) if twin.gaps else None
        self.gap_count = state.get("gaps_reported", 0) if state else 0
        resumed = state is not None
        self.source.start(lines_read=twin.lines_read, last_t=twin.last_t, time_origin=origin)
        if self.page is not None:
            if state is not None and "alarms" in state and self.page.engine is not None:
                self.page.engine.restore(state["alarms"])
            self.page_origin = self.source_origin()
            kind = twin.values.get("rod.kind", twin.fmu.variables["rod.kind"].start)
            self.page.open(
                twin.outputs,
                self.page_origin,
                elastic=int(float(kind)) != 0,
                pump=is_pump(twin.values),
            )
        damaged = self._check_input() if resumed else []
        self._event(
            Event(
                "resumed" if resumed else "started",
                f"{'resumed' if resumed else 'started'} run {cfg.run_id!r} of machine "
                f"{cfg.machine_id!r} at input line {twin.lines_read}",
            )
        )
        for msg in damaged:
            self.log(msg)
            self._event(Event("damaged_input", msg))
        self.dirty = True
        self.last_commit = self.last_checkpoint = time.monotonic()
        self.lines_since = self.lines_since_checkpoint = 0
        lineno = twin.lines_read
        live = getattr(self.source, "live", True)

        def on_signal(signum, _frame):
            self.stop_signal = signal.Signals(signum).name

        old = {sig: signal.signal(sig, on_signal) for sig in (signal.SIGTERM, signal.SIGINT)}
        deadline = None if self.stop_after is None else time.monotonic() + self.stop_after
        try:
            while self.stop_signal is None:
                if deadline is not None and time.monotonic() >= deadline:
                    self.timed_out = True
                    break
                wait = max(0.0, cfg.commit_interval - (time.monotonic() - self.last_commit))
                if deadline is not None:
                    wait = min(wait, max(0.0, deadline - time.monotonic()))
                try:
                    chunk = self.source.get(wait)
                except DataError as e:  # a followed file truncated, replaced or removed
                    return self._failed(e)
                if self.page is not None:
                    connected = getattr(self.source, "connected", None)
                    self.page.health(connected=connected.is_set() if connected else True)
                if chunk is None and self.source.ended:
                    break
                if chunk is not None:
                    for ev in chunk.events:
                        self._event(ev)
                    if chunk.events:
                        self.dirty = True
                    if chunk.lines or chunk.samples is not None:
                        # Consumed: the stored input (docs/plant.md "Storage"). A source of
                        # numbers is stored as the CSV form it stands for (repr reads back to the
                        # same double), its header first when these are the run's first samples.
                        self.block_lines.extend(
                            chunk.lines
                            if chunk.samples is None
                            else input_lines(chunk.samples, header=twin.cols is None)
                        )
                        had_origin = twin.time_origin is not None
                        try:
                            if chunk.samples is None:
                                rows, sums = twin.feed(chunk.lines, lineno + 1)
                            else:
                                rows, sums = twin.feed_samples(chunk.samples, lineno + 1)
                        except (DataError, FmuError) as e:
                            return self._failed(e)
                        if self.page is not None and not had_origin and twin.time_origin:
                            # Timestamps in the input: the page's clock starts at their origin.
                            self.page.open(twin.outputs, self.source_origin())
                        # Input lines consumed (a source of numbers: its samples' lines).
                        n = twin.lines_read - lineno
                        lineno += n
                        self.lines_since += n
                        self.lines_since_checkpoint += n
                        self._hand(rows, sums)
                # A live source commits every commit_interval (the rows' latency); a replay
                # as fast as possible every commit_samples lines (fewer, larger transactions).
                # Rows of a live source go out every commit_interval, with a checkpoint every
                # checkpoint_interval; a replay commits rows and checkpoint together.
                now = time.monotonic()
                if self.dirty and (
                    self.lines_since >= cfg.commit_samples
                    or (live and now - self.last_commit >= cfg.commit_interval)
                ):
                    self._commit(
                        checkpoint=not live
                        or self.lines_since_checkpoint >= cfg.commit_samples
                        or now - self.last_checkpoint >= cfg.checkpoint_interval
                    )
            if self.timed_out:
                # Stopped after the time asked for: complete as asked, and resumable.
                self._commit()
                self.log(
                    f"stopped after {self.stop_after:g} s as asked (--seconds), after input line "
                    f"{lineno}: {twin.rows_out} samples, {self.c.revolutions} revolutions "
                    f"committed to {', '.join(s.name for s in self.sinks)}"
                )
                return 0
            if self.stop_signal is not None:
                self._commit()
                hint = getattr(
                    self.source,
                    "resume_hint",
                    "Run again with the same configuration to resume.",
                )
                self.log(
                    f"stopped by {self.stop_signal} after input line {lineno}; committed. {hint}"
                )
                self._page_end("stopped", f"by {self.stop_signal}")
                # Not 0: the run did not reach the end of its input (128 + the signal, as a shell).
                return 128 + int(signal.Signals[self.stop_signal])
            try:
                rows, sums = twin.finish()
            except (DataError, FmuError) as e:
                return self._failed(e)
            self._hand(rows, sums)
            if twin.rows_out == 0:
                self._event(Event("data_error", "the input holds no sample"))
                self._commit("failed")
                self.log(f"{self._source_name()}: the input holds no sample")
                self._page_end("failed", "the input holds no sample")
                return 1
            acct = getattr(self.source, "accounting", None)
            if acct is not None:
                received, out, dropped = acct()
                if received != out + dropped:
                    # Never "finished" with a sample neither stored nor counted (docs/plant.md
                    # "Final status").
                    msg = (
                        f"{received} samples received, {out} handed to the twin and {dropped} "
                        f"dropped: {received - out - dropped} unaccounted for"
                    )
                    self._event(Event("data_error", msg))
                    self._commit("failed")
                    self.log(f"{self._source_name()}: {msg}")
                    return 1
            self._event(Event("finished", f"finished: {twin.rows_out} samples"))
            self._commit("finished")
            self._page_end("finished", f"{twin.rows_out} samples, {self.c.revolutions} revolutions")
        finally:
            for sig, h in old.items():
                signal.signal(sig, h)
        for m in dict.fromkeys(twin.messages):
            self.log(f"twin: {m}")
        n_drop = sum(self.drops.values())
        why = "; ".join(f"{k}: {v}" for k, v in sorted(self.drops.items()))
        lost = sum(t1 - t0 for t0, t1 in twin.gaps)
        self.log(
            f"run {cfg.run_id!r}: {twin.rows_out} samples stored, {n_drop} dropped"
            f"{f' ({why})' if why else ''}, {twin.duplicates} duplicate timestamps dropped, "
            f"{self.gap_count} gap(s) ({lost:.6g} s lost); {self.c.revolutions} revolutions; "
            f"{self.commits} commits to {', '.join(s.name for s in self.sinks)}"
        )
        return 0

    def _failed(self, e) -> int:
        """Bad data or an FMU failure: the rows before it are committed, then the run stops."""
        if getattr(e, "rows", None) is not None:
            self._hand(e.rows, e.summaries or [])
        kind = "fmu_error" if isinstance(e, FmuError) else "data_error"
        self._event(Event(kind, str(e)))
        self._commit("failed")
        self.log(f"{self._source_name()}: {e}")
        self._page_end("failed", str(e))
        return 1

    def _page_end(self, status: str, message: str) -> None:
        if self.page is not None:
            self.page.end(status, message)

    def _source_name(self) -> str:
        src = self.cfg.source.public()
        if src.get("path") == "-":
            return "standard input"
        return src.get("path") or src.get("endpoint") or "twin"


def run_config(path: str, log=None, stop_after: float | None = None) -> int:
    """The whole pipeline of a configuration file; returns the exit status (messages are one line
    each on standard error; an unexpected failure writes its traceback to a file and says where)."""
    log = log or (lambda m: print(m, file=sys.stderr, flush=True))
    try:
        cfg = load(path)
    except ConfigError as e:
        log(str(e))
        return 2
    try:
        return Pipeline(cfg, log, stop_after).run()
    except ConfigError as e:  # the [page] table, its limits file, its port
        log(str(e))
        return 2
    except (SinkError, SourceError) as e:
        log(str(e))
        return 1
    except FmuError as e:
        log(f"FMU {cfg.fmu}: {e}")
        return 1
    except (OSError, ValueError, KeyError) as e:
        log(f"{type(e).__name__}: {e}" if not isinstance(e, OSError) else str(e))
        return 1
    except Exception:  # noqa: BLE001 - a bug: one line for the user, the details in a file
        fd, where = tempfile.mkstemp(prefix="twin-plant-", suffix=".txt")
        with os.fdopen(fd, "w") as f:
            traceback.print_exc(file=f)
        log(f"internal error of the twin; please report it with the details in {where}")
        return 70  # EX_SOFTWARE, as every command of the package (cli_errors.py)
