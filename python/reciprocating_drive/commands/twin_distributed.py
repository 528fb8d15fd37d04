"""`rdrive twin --distributed`: a recorded file replayed in pieces on Dask (docs/twin.md
"Distributed replay"). The output files are those of the sequential replay: identical byte for
byte for a rigid rod, within 1e-8 rad of rod.angle for an elastic rod."""

from __future__ import annotations

import os
import pathlib
import shutil
import sys
import time

from ..fmu import FmuError
from ..line_input import InputChanged
from ..replay import (
    STOP,
    Assembler,
    PieceFailed,
    Progress,
    ReplayError,
    _names,
    is_postgres,
    is_sqlite,
    manifest_of,
    open_work,
    piece_cpu,
    plan,
    run_group,
    scan,
    warm_up_time,
    warm_worker,
    write_piece,
)
from ..twin import CheckpointError, DataError, Options, summary_header

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
        print("twin.py: --distributed replays a file, not standard input", file=err)
        return 2
    for attr, flag in _NOT_WITH:
        if getattr(a, attr, None):
            print(f"twin.py: {flag} cannot be combined with --distributed", file=err)
            return 2
    if a.speed_check == "warn":
        print(
            "twin.py: --speed-check warn cannot be combined with --distributed (the count of "
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
        print(f"twin.py: {e}", file=err)
        return 2

    if a.scheduler:
        # Before reading the input: a scheduler that is not there is said at once, bounded.
        from ..sweep import SweepError, probe_scheduler

        try:
            probe_scheduler(a.scheduler, a.connect_timeout)
        except SweepError as e:
            print(f"twin.py: {e}", file=err)
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
        print(f"twin.py: {where}: {' '.join(str(e).split())}", file=err)
        return 1
    except ReplayError as e:
        print(f"twin.py: {e}", file=err)
        return 2
    except (FmuError, ValueError, OSError) as e:
        print(f"twin.py: {' '.join(str(e).split())}", file=err)
        return 2
    if stopping:
        print("twin.py: stopped while reading the input; nothing was written", file=err)
        return 128 + stopping[0]
    pieces = plan(sc, a.revolutions_per_piece, a.overlap)
    n_samples = len(sc.data["t"])
    extra = {"revolutions_per_piece": a.revolutions_per_piece, "overlap": a.overlap}
    manifest = manifest_of(sc, machine, pieces, extra)
    try:
        written = open_work(work, manifest)
    except (ReplayError, OSError) as e:
        print(f"twin.py: {e}", file=err)
        return 2
    if not a.quiet:
        warm = warm_up_time(sc.sigma) if a.overlap is None else a.overlap
        print(
            f"replay: {n_samples} samples in {len(pieces)} pieces (scan {time.monotonic() - t0:.1f}"
            f" s); warm-up {warm:.3g} s and {sc.half + 2} samples before each cut",
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
    asm = Assembler(work, len(pieces), [(a.out, sc.header), (summary, summary_header())])
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
        print(
            f"replay: {done} samples computed in {took:.3f} s on {progress.workers} worker(s) "
            f"({done / max(took, 1e-9):.0f} samples/s, result files written; the workers' CPU "
            f"in the pieces {progress.cpu:.3f} s, the client's {progress.client_cpu:.3f} s)",
            file=err,
        )
    shutil.rmtree(work, ignore_errors=True)
    for m in sc.messages:
        print(f"twin.py: {m}", file=err)
    print(
        f"{n_samples} samples, {sc.duplicates} duplicate timestamps dropped, "
        f"{len(sc.gaps)} gap(s); {len(pieces)} pieces; wrote {a.out} and {summary}"
    )
    if a.plots:
        from ..twin_plots import plot_twin

        plot_twin(
            a.out, summary, a.plots, machine=machine, source=a.input, gap_limit=sc.options.gap_limit
        )
        print(f"wrote plots to {a.plots}")
    return 0


def _compute(a, sc, pieces, todo, work, progress, stopping, asm) -> int | None:
    """Runs the pieces `todo` on Dask and writes each to the work folder as it arrives. None when
    all are written, else the exit code."""
    from distributed import wait

    from ..cluster import WorkerMismatch, prepare_workers
    from ..sweep import SweepError, _client, _close, _quiet_distributed

    err = sys.stderr
    try:
        with _quiet_distributed():
            client, cluster = _client(a.scheduler, a.workers, a.connect_timeout)
    except SweepError as e:
        print(f"twin.py: {e}", file=err)
        return 2
    try:
        try:
            key = prepare_workers(client, a.fmu)
        except WorkerMismatch as e:
            print(f"twin.py: {e}", file=err)
            return 2
        client.run(warm_worker, key)
        n_workers = max(1, len(client.scheduler_info()["workers"]))
        progress.start()
        cpu0 = time.process_time()
        progress.workers = n_workers
        wopts = worker_options(sc.options)
        names = ("line", "t", "theta", "speed", "force")
        lonely = None  # since when the cluster has had no worker
        # A local cluster's workers write their pieces to the work folder themselves; those of
        # a cluster that shares no disk send them back as bytes.
        shared = str(work.resolve()) if a.scheduler is None else None
        if shared:
            # A record in the work folder then says a worker wrote that piece in this run: a
            # stale one (a damaged piece of an earlier run, which resume computes again) goes.
            for i in todo:
                _names(work, i)[2].unlink(missing_ok=True)
            (work / STOP).unlink(missing_ok=True)  # that of a stopped run: this one resumes
        # Consecutive pieces in groups, one task each: Dask's scheduler (in this process for a
        # LocalCluster) costs about the same CPU per task whatever its size, which 2 cores cannot
        # hide (docs/twin.md "Distributed replay", Speed). Two groups per worker keep the
        # workers evenly busy to the end; a group stays small enough that the arrays sent ahead
        # stay bounded and a worker killed loses little.
        size = max(1, min(_GROUP_MAX, -(-len(todo) // (2 * n_workers))))
        queue = [todo[k : k + size] for k in range(0, len(todo), size)]
        running: dict = {}  # future -> the group's pieces not yet counted
        limit = 2 * n_workers
        # The records of a shared disk are looked at often, so that the (sequential) assembly
        # follows the pieces as they end rather than their groups.
        poll = 0.05 if shared else 0.5

        def count(i):
            asm.add(i)
            progress.cpu += piece_cpu(work, i)
            progress.step(pieces[i][1] - pieces[i][0])

        while queue or running:
            while queue and len(running) < limit:
                group = queue.pop(0)
                items = [
                    (i, pieces[i], tuple(sc.data[n][pieces[i][2] : pieces[i][3]] for n in names))
                    for i in group
                ]
                fut = client.submit(
                    run_group,
                    key,
                    sc.values,
                    wopts,
                    sc.half,
                    sc.cols,
                    sc.offset,
                    items,
                    shared,
                    pure=False,
                    key=f"replay-group-{group[0]}-{os.getpid()}",
                )
                running[fut] = list(group)
            if stopping:
                break
            try:
                done, _ = wait(list(running), timeout=poll, return_when="FIRST_COMPLETED")
            except TimeoutError:  # none ended meanwhile: look at the records and the signals
                done = ()
            fetched = 0
            if shared:
                # A group's pieces are written in order: each one whose record is there is
                # counted and assembled now, not when its whole group ends (progress, resume).
                for left in running.values():
                    while left and _names(work, left[0])[2].exists():
                        count(left.pop(0))
                        fetched += 1
            for fut in done:
                if shared and fut.status == "finished":
                    # The worker wrote its pieces and their records to the work folder: its
                    # result (None) is not fetched, which saves the client (and the scheduler
                    # it hosts) a round trip to the worker (docs/twin.md, Speed).
                    for i in running.pop(fut):
                        count(i)
                        fetched += 1
                    continue
                try:
                    got = fut.result(timeout=1.0)
                except TimeoutError:
                    continue  # its result went with its worker: Dask computes it again
                except PieceFailed as e:
                    print(f"twin.py: {a.input}: {e}", file=err)
                    return 1
                for i, (out, rev, n, cpu) in zip(running.pop(fut), got):
                    write_piece(work, i, out, rev)
                    asm.add(i)
                    progress.cpu += cpu
                    progress.step(n)
                    fetched += 1
            # A cluster whose workers are all gone would wait for ever: bounded.
            if fetched or client.scheduler_info().get("workers"):
                lonely = None
            elif lonely is None:
                lonely = time.monotonic()
            elif time.monotonic() - lonely > max(a.connect_timeout, 30.0):
                print(
                    f"twin.py: no worker on the cluster for {max(a.connect_timeout, 30.0):g} s; "
                    f"{progress.done} of {progress.total} pieces are in {work}: run the same "
                    "command again to resume",
                    file=err,
                )
                return 1
            if stopping:
                break
        progress.t_end = time.monotonic()
        progress.client_cpu = time.process_time() - cpu0
        if stopping:
            if shared:
                (work / STOP).touch()  # the groups running end at their next piece
            for fut in running:
                fut.cancel()
            print(
                f"twin.py: stopped with {progress.done} of {progress.total} pieces written to "
                f"{work}; run the same command again to resume",
                file=err,
            )
            return 128 + stopping[0]
        return None
    except (ReplayError, CheckpointError) as e:
        print(f"twin.py: {e}", file=err)
        return 2
    finally:
        with _quiet_distributed():
            _close(client, cluster)
