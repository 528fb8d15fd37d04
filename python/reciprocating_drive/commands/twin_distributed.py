"""`rdrive twin --distributed`: a recorded file replayed in pieces on Dask (docs/twin.md
"Distributed replay"). The output files are those of the sequential replay: identical byte for
byte for a rigid rod, within 1e-8 rad of rod.angle for an elastic rod.

Layer: commands (docs/architecture.md).
"""

from __future__ import annotations

import gc
import os
import pathlib
import shutil
import sys
import time

from ..fmu.instance import FmuError
from ..twin.core import CheckpointError, DataError, Options, summary_header
from ..twin.line_input import InputChanged
from ..twin.replay import (
    INPUT_NAMES,
    STOP,
    Assembler,
    PieceFailed,
    Progress,
    ReplayError,
    _names,
    clear_claims,
    header_bytes,
    is_postgres,
    is_sqlite,
    manifest_of,
    open_work,
    piece_cpu,
    plan,
    run_claimed,
    run_group,
    save_inputs,
    scan,
    warm_up_time,
    warm_worker,
    write_piece,
)
from . import prefix

#: At most this many pieces in one Dask task (`_compute`).
_GROUP_MAX = 32

#: Options of the sequential twin that a distributed replay does not take (it reads a whole
#: recorded file; its work folder is its checkpoint).
_NOT_WITH = (
    ("live", "--live"),
    ("follow", "--follow"),
    ("checkpoint", "--checkpoint"),
    ("resume", "--resume"),
    ("stop_after", "--stop-after"),
    ("idle_limit", "--idle-limit"),
)


def worker_options(o: Options) -> dict:
    """The options of a piece's twin: the angle arrives unwrapped in rad and the speed in rad/s
    (the scan converted them), duplicates are already dropped; the rest as resolved."""
    d = o.to_dict()
    d.update(angle_unit="rad", counts_per_rev=None, wrapped=False, speed_unit="rad/s")
    return d


def run(a, opts: Options, stopping: list) -> int:
    """Exit codes as the twin's: 0 done, 1 bad data or an FMU error, 2 a bad option, input,
    scheduler or work folder, 128 + signal when stopped (the pieces written are kept)."""
    err = sys.stderr
    if a.input == "-":
        print(f"{prefix('twin.py')}: --distributed replays a file, not standard input", file=err)
        return 2
    for attr, flag in _NOT_WITH:
        if getattr(a, attr, None):
            print(f"{prefix('twin.py')}: {flag} cannot be combined with --distributed", file=err)
            return 2
    if a.speed_check == "warn":
        print(
            f"{prefix('twin.py')}: --speed-check warn cannot be combined with --distributed (the count of "
            "ignored speeds is per sample); use refuse or --ignore-speed",
            file=err,
        )
        return 2
    summary = a.summary or a.out.with_name(a.out.stem + "-revolutions.csv")
    work = a.work_dir or a.out.with_name(a.out.name + ".parts")
    remote = is_postgres(a.input)
    try:
        if remote:
            pass  # a table of a PostgreSQL database: checked when it is read
        elif not os.path.exists(a.input):
            raise ReplayError(f"{a.input}: no such file")
        if os.path.isdir(a.input):
            raise ReplayError(f"{a.input}: a folder, not a CSV file")
        named = [("--out", a.out), ("--summary", summary), ("--work-dir", work)]
        seen = {} if remote else {str(pathlib.Path(a.input).resolve()): "input"}
        for flag, p in named:
            key = str(pathlib.Path(p).resolve())
            if key in seen:
                raise ReplayError(f"{flag} {p}: the same file as {seen[key]}")
            seen[key] = flag
    except ReplayError as e:
        print(f"{prefix('twin.py')}: {e}", file=err)
        return 2

    if a.scheduler:
        # Before reading the input: a scheduler that is not there is said at once, bounded.
        from ..sweeps.sweep import SweepError, probe_scheduler

        try:
            probe_scheduler(a.scheduler, a.connect_timeout)
        except SweepError as e:
            print(f"{prefix('twin.py')}: {e}", file=err)
            return 2
    t0 = time.monotonic()
    machine = a.machine or "default"
    try:
        table = a.table
        if table is None and (remote or is_sqlite(a.input)):
            table = "samples"
        sc = scan(a.input, a.fmu, machine, opts, stop=lambda: bool(stopping), table=table)
    except (DataError, InputChanged) as e:
        where = "the table" if remote else a.input
        print(f"{prefix('twin.py')}: {where}: {' '.join(str(e).split())}", file=err)
        return 1
    except ReplayError as e:
        print(f"{prefix('twin.py')}: {e}", file=err)
        return 2
    except (FmuError, ValueError, OSError) as e:
        print(f"{prefix('twin.py')}: {' '.join(str(e).split())}", file=err)
        return 2
    if stopping:
        print(
            f"{prefix('twin.py')}: stopped while reading the input; nothing was written", file=err
        )
        return 128 + stopping[0]
    pieces = plan(sc, a.revolutions_per_piece, a.overlap)
    n_samples = len(sc.data["t"])
    extra = {"revolutions_per_piece": a.revolutions_per_piece, "overlap": a.overlap}
    manifest = manifest_of(sc, machine, pieces, extra)
    try:
        written = open_work(work, manifest, header_bytes(sc.header))
        if a.scheduler is None and len(written) < len(pieces):
            # A local cluster's workers map the scanned samples from the work folder: written
            # now, part of the scan, while nothing waits for it.
            save_inputs(work, sc.data)
    except (ReplayError, OSError) as e:
        print(f"{prefix('twin.py')}: {e}", file=err)
        return 2
    if not a.quiet:
        warm = warm_up_time(sc.sigma) if a.overlap is None else a.overlap
        print(
            f"replay: {n_samples} samples in {len(pieces)} pieces (scan {time.monotonic() - t0:.1f}"
            f" s); warm-up {warm:.3g} s and half the smoothing window, "
            f"{0.5 * sc.options.window:.3g} s, before each cut",
            file=err,
            flush=True,
        )
    todo = [i for i in range(len(pieces)) if i not in written]
    if written and not a.quiet:
        print(
            f"replay: resuming: {len(written)} of {len(pieces)} pieces already in {work}",
            file=err,
            flush=True,
        )
    progress = Progress(len(pieces), n_samples, a.quiet, err)
    progress.done = len(written)
    progress.done_samples = sum(pieces[i][1] - pieces[i][0] for i in written)
    a.out.parent.mkdir(parents=True, exist_ok=True)
    summary.parent.mkdir(parents=True, exist_ok=True)
    asm = Assembler(work, len(pieces), a.out, summary, summary_header())
    try:
        for i in sorted(written):
            asm.add(i)
        if todo:
            code = _compute(a, sc, pieces, todo, work, progress, stopping, asm)
            if code is not None:
                asm.abort()
                return code
        t_assemble = time.monotonic()
        asm.finish()
    except BaseException:
        asm.abort()
        raise
    if todo and not a.quiet:
        # From the workers being ready to the result files written, less the cluster's shut-down
        # (scripts/bench_replay.py).
        took = progress.t_end - progress.t0 + time.monotonic() - t_assemble
        done = progress.done_samples - progress.base
        busy = progress.machine_busy()
        cores = "" if busy is None else f"; the machine's {os.cpu_count()} cores {busy:.0%} busy"
        print(
            f"replay: {done} samples computed in {took:.3f} s on {progress.workers} worker(s) "
            f"({done / max(took, 1e-9):.0f} samples/s, result files written; the workers' CPU "
            f"in the pieces {progress.cpu:.3f} s, the client's {progress.client_cpu:.3f} s"
            f"{cores})",
            file=err,
        )
    shutil.rmtree(work, ignore_errors=True)
    for m in sc.messages:
        print(f"{prefix('twin.py')}: {m}", file=err)
    print(
        f"{n_samples} samples, {sc.duplicates} duplicate timestamps dropped, "
        f"{len(sc.gaps)} gap(s); {len(pieces)} pieces; wrote {a.out} and {summary}"
    )
    if a.plots:
        from ..twin.plots import plot_twin

        plot_twin(
            a.out, summary, a.plots, machine=machine, source=a.input, gap_limit=sc.options.gap_limit
        )
        print(f"wrote plots to {a.plots}")
    return 0


def _compute(a, sc, pieces, todo, work, progress, stopping, asm) -> int | None:
    """Runs the pieces `todo` on Dask and writes each to the work folder as it arrives. None when
    all are written, else the exit code."""
    from ..sweeps.sweep import _quiet_distributed

    # distributed's own log lines stay out of the replay's messages for the whole run, not only
    # while the cluster starts and stops: a worker lost with a result it held makes the client
    # log that it reschedules it, and asyncio a task's traceback ("exception was never
    # retrieved") for the fetch given up; the replay says what matters in its own line.
    with _quiet_distributed():
        try:
            return _compute_quietly(a, sc, pieces, todo, work, progress, stopping, asm)
        finally:
            # The closed client's abandoned tasks go now, while their log lines are muted,
            # rather than whenever the collector would have found them.
            gc.collect()


def _compute_quietly(a, sc, pieces, todo, work, progress, stopping, asm) -> int | None:
    from ..cluster import WorkerMismatch, prepare_workers
    from ..sweeps.sweep import SweepError, _client, _close

    err = sys.stderr
    try:
        client, cluster = _client(a.scheduler, a.workers, a.connect_timeout)
    except SweepError as e:
        print(f"{prefix('twin.py')}: {e}", file=err)
        return e.exit_code  # 2, or 1 for a local cluster whose workers die while starting
    try:
        try:
            key = prepare_workers(client, a.fmu)
        except WorkerMismatch as e:
            print(f"{prefix('twin.py')}: {e}", file=err)
            return 2
        client.run(warm_worker, key)
        n_workers = max(1, len(client.scheduler_info()["workers"]))
        progress.start()
        cpu0 = time.process_time()
        progress.workers = n_workers
        job = _Job(a, sc, pieces, work, progress, stopping, asm, client, key, n_workers)
        # A local cluster's workers share this disk: they map the input and write their pieces
        # to the work folder themselves. Those of a cluster that shares no disk receive their
        # pieces' samples with the task and send the pieces back as bytes.
        code = job.shared(todo) if a.scheduler is None else job.remote(todo)
        progress.stop(time.process_time() - cpu0)
        if code is None and stopping:
            print(
                f"{prefix('twin.py')}: stopped with {progress.done} of {progress.total} pieces written to "
                f"{work}; run the same command again to resume",
                file=err,
            )
            return 128 + stopping[0]
        return code
    except (ReplayError, CheckpointError) as e:
        print(f"{prefix('twin.py')}: {e}", file=err)
        return 2
    finally:
        _close(client, cluster)


class _Job:
    """The client's side of one distributed replay on a started cluster: submits the pieces,
    counts and assembles them as they are written, and watches for a cluster left without
    workers. `shared` and `remote` return None when every piece is written or the run was
    stopped (`stopping`), else the exit code."""

    def __init__(self, a, sc, pieces, work, progress, stopping, asm, client, key, n_workers):
        self.a, self.sc, self.pieces, self.work = a, sc, pieces, work
        self.progress, self.stopping, self.asm = progress, stopping, asm
        self.client, self.key, self.n_workers = client, key, n_workers
        self.wopts = worker_options(sc.options)
        self.lonely = None  # since when the cluster has had no worker

    def count(self, i: int, cpu: float | None = None, n: int | None = None) -> None:
        self.asm.add(i)
        self.progress.cpu += piece_cpu(self.work, i) if cpu is None else cpu
        p = self.pieces[i]
        self.progress.step(p[1] - p[0] if n is None else n)

    def _common(self) -> tuple:
        sc = self.sc
        return (self.key, sc.values, self.wopts, sc.cols, sc.offset)

    def abandoned(self, fetched: int) -> int | None:
        """1 (with its message) when the cluster has had no worker for the connect timeout
        (30 s at least) and nothing arrived meanwhile: a wait for ever, bounded."""
        a = self.a
        if fetched or self.client.scheduler_info().get("workers"):
            self.lonely = None
        elif self.lonely is None:
            self.lonely = time.monotonic()
        elif time.monotonic() - self.lonely > max(a.connect_timeout, 30.0):
            print(
                f"{prefix('twin.py')}: no worker on the cluster for {max(a.connect_timeout, 30.0):g} s; "
                f"{self.progress.done} of {self.progress.total} pieces are in {self.work}: run "
                "the same command again to resume",
                file=sys.stderr,
            )
            return 1
        return None

    def failed(self, fut) -> int | None:
        """The exit code of a task that ended in error: 1 for bad data or an FMU error in a
        piece (its message names the line); other errors (a worker lost too often) go up."""
        try:
            fut.result(timeout=1.0)
        except TimeoutError:
            return None  # its result went with its worker: Dask computes it again
        except PieceFailed as e:
            print(f"{prefix('twin.py')}: {self.a.input}: {e}", file=sys.stderr)
            return 1
        return None

    def shared(self, todo: list) -> int | None:
        """A LocalCluster: the input mapped from the work folder, one task per worker over the
        whole list, each claiming the next piece no worker has taken (replay.run_claimed), the
        pieces counted and assembled from their records as they appear. Pieces a lost worker
        had claimed are computed in another round."""
        work, client = self.work, self.client
        # A record in the work folder says a worker wrote that piece in this run: a stale one
        # (a damaged piece of an earlier run, which resume computes again) goes, and so do the
        # claims and the stop file of an earlier run.
        for i in todo:
            _names(work, i)[2].unlink(missing_ok=True)
        (work / STOP).unlink(missing_ok=True)
        folder = str(work.resolve())
        first = len(header_bytes(self.sc.header))  # the rows file's header
        left = list(todo)  # not yet counted, in order
        rounds = 0
        while left:
            if rounds and not self.a.quiet:
                print(
                    f"replay: {len(left)} piece(s) claimed by a worker that was lost are computed "
                    "again",
                    file=sys.stderr,
                    flush=True,
                )
            clear_claims(work, left)
            items = [(i, self.pieces[i]) for i in left]
            futs = [
                client.submit(
                    run_claimed, *self._common(), items, folder, first, pure=False,
                    key=f"replay-claims-{rounds}-{k}-{os.getpid()}",
                )
                for k in range(self.n_workers)
            ]  # fmt: skip
            rounds += 1
            before = len(left)
            # The records say when the pieces are written: the client looks for them (a stat or
            # a few each time) every 20 ms, every 3 ms once the last pieces run, and goes on to
            # the assembly's end as soon as the last one is there, without the round trip of the
            # tasks' end through the scheduler (docs/twin.md "Distributed replay", Speed).
            t_workers = time.monotonic()
            while left and not all(f.done() for f in futs):
                if self.stopping:
                    (work / STOP).touch()  # the tasks end at their next piece
                    for fut in futs:
                        fut.cancel()
                    return None
                time.sleep(0.003 if len(left) <= 2 * self.n_workers else 0.02)
                fetched = self._collect(left)
                for fut in futs:
                    if fut.status == "error":
                        code = self.failed(fut)
                        if code is not None:
                            return code
                if fetched or time.monotonic() - t_workers > 0.5:
                    t_workers = time.monotonic()
                    code = self.abandoned(fetched)
                    if code is not None:
                        return code
            self._collect(left, everything=True)
            if len(left) == before:
                raise ReplayError(
                    f"{len(left)} pieces were claimed but not written by the workers; run the "
                    "same command again to resume"
                )
        return None

    def _collect(self, left: list, everything: bool = False) -> int:
        """Counts the pieces of `left` whose record is written (removing them from it): the
        first few only while the tasks run (pieces end nearly in order; each look is a stat),
        all of them at the end of a round. Returns how many were counted."""
        work, got, missing = self.work, [], 0
        for i in left:
            if _names(work, i)[2].exists():
                got.append(i)
            else:
                missing += 1
                if not everything and missing > 2 * self.n_workers:
                    break
        for i in got:
            left.remove(i)
            self.count(i)
        return len(got)

    def remote(self, todo: list) -> int | None:
        """A cluster that shares no disk: consecutive pieces in groups, one task each, their
        samples sent with the task and the pieces sent back as bytes. Dask's scheduler costs
        about the same CPU per task whatever its size (docs/twin.md "Distributed replay",
        Speed); two groups per worker keep the workers evenly busy to the end, and a group stays
        small enough that the arrays sent ahead stay bounded and a worker killed loses little."""
        from distributed import wait

        work, client, sc = self.work, self.client, self.sc
        n_workers = self.n_workers
        size = max(1, min(_GROUP_MAX, -(-len(todo) // (2 * n_workers))))
        queue = [todo[k : k + size] for k in range(0, len(todo), size)]
        running: dict = {}  # future -> the group's pieces
        limit = 2 * n_workers
        while queue or running:
            while queue and len(running) < limit:
                group = queue.pop(0)
                items = [
                    (i, self.pieces[i], tuple(sc.data[n][self.pieces[i][2] : self.pieces[i][3]]
                                              for n in INPUT_NAMES))
                    for i in group
                ]  # fmt: skip
                fut = client.submit(
                    run_group, *self._common(), items, pure=False,
                    key=f"replay-group-{group[0]}-{os.getpid()}",
                )  # fmt: skip
                running[fut] = list(group)
            if self.stopping:
                for fut in running:
                    fut.cancel()
                return None
            try:
                done, _ = wait(list(running), timeout=0.5, return_when="FIRST_COMPLETED")
            except TimeoutError:  # none ended meanwhile: look at the signals and the workers
                done = ()
            fetched = 0
            for fut in done:
                try:
                    got = fut.result(timeout=1.0)
                except TimeoutError:
                    continue  # its result went with its worker: Dask computes it again
                except PieceFailed as e:
                    print(f"{prefix('twin.py')}: {self.a.input}: {e}", file=sys.stderr)
                    return 1
                for i, (out, rev, n, cpu) in zip(running.pop(fut), got):
                    write_piece(work, i, out, rev)
                    self.count(i, cpu, n)
                    fetched += 1
            code = self.abandoned(fetched)
            if code is not None:
                return code
        return None
