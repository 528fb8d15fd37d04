"""Design sweeps on Dask's distributed scheduler (docs/sweeps.md).

The cases of a study (python/reciprocating_drive/sweeps/study.py) are cut into small batches; each batch is
one Dask task that runs its cases one after the other on the FMU its worker process has loaded once
(`_worker_fmu`). Batches are sized to about a second of work and only a few per worker are in flight,
planned lazily as results come back: a study of any size costs the same memory before its first case,
and a kill loses about a second of each worker's work. Results are appended to `<out>/<study>.csv` as
each batch finishes, each row with the study's fingerprint (`fingerprint`: the study's content and
the FMU's GUID and version); started again, the sweep computes only the missing cases, and refuses a
result file of another study or FMU (`fresh=True` starts afresh). At the end the rows are sorted by
case and written as Parquet and CSV.

A case the FMU rejects (a linkage that cannot assemble, a self-locking guide, a buckled rod) is a
row with status "error" and the FMU's message; it never ends the sweep.

By default the sweep starts a `dask.distributed.LocalCluster` with one single-threaded worker
process per core; `scheduler="tcp://host:port"` attaches to an existing cluster instead (workers
started with `dask worker`, dask-jobqueue, dask-kubernetes, ...), after checking within
`connect_timeout` that a Dask scheduler answers there. Such workers share no disk with the client:
they need the package (the wheel) installed, at the client's version, and receive the FMU from the
client (cluster.py).

Layer: workflows, the sweeps (docs/architecture.md).
"""

from __future__ import annotations

import contextlib
import csv
import hashlib
import io
import itertools
import logging
import math
import os
import pathlib
import signal
import socket
import sys
import time
from dataclasses import asdict, dataclass, field

import numpy as np

from ..cli_errors import RunFailed, UserError, show
from .cases import outputs_of, run_case, run_cases
from .study import Study, check_fmu

_FMUS: dict = {}

#: The most cases in one Dask task (batches are sized to `batch_seconds` of work).
_MAX_BATCH = 20_000


def _worker_fmu(path: str):
    """The FMU of this worker process, loaded once and reused by every case (fmi2Reset between)."""
    from ..fmu.instance import Fmu

    f = _FMUS.get(path)
    if f is None:
        f = _FMUS[path] = Fmu(path)
    return f


@dataclass
class Row:
    case: int
    status: str
    message: str
    seconds_fmu: float
    seconds_case: float
    worker: str


def _worker_name() -> str:
    """The Dask worker's address (which machine computed a row), or the process id outside one."""
    try:
        from distributed import get_worker

        return get_worker().address
    except (ImportError, ValueError):
        return f"pid {os.getpid()}"


def run_batch(
    fmu_path: str, study: Study, cases: list[int], shipped: bool = False, reference: bool = False
) -> list[dict]:
    """One Dask task: the cases `cases` of `study`, each a result row (never raises for a case).
    `shipped`: `fmu_path` is the SHA-256 of the FMU the client shipped to a cluster that shares no
    disk with it (cluster.py), otherwise a path on this machine. The cases run through the native
    batch driver with the metrics computed for the whole batch at once (sweep_cases.py);
    `reference=True` runs the reference path instead, one FMU call per step from Python
    (`run_case`), whose rows are the same bit for bit (but for the timings)."""
    from ..fmu.instance import FmuError

    if shipped:
        from ..cluster import local_fmu

        fmu_path = local_fmu(fmu_path)
    fmu = _worker_fmu(fmu_path)
    worker = _worker_name()
    if not reference:
        res = run_cases(fmu, study, list(cases), outputs_of(study))
        return [
            {"case": i, **res.params_of(c), **dict(zip(study.metrics, res.metrics[c].tolist())),
             "status": res.status[c], "message": res.message[c],
             "seconds_fmu": float(res.seconds_fmu[c]), "seconds_case": float(res.seconds_case[c]),
             "worker": worker}
            for c, i in enumerate(res.cases)
        ]  # fmt: skip
    out = []
    for i in cases:
        params = study.case(i)
        t0 = time.perf_counter()
        metrics, inside, status, message = {}, 0.0, "ok", ""
        try:
            metrics, inside = run_case(fmu, study, params)
        except (FmuError, ValueError, RuntimeError) as e:
            status, message = "error", str(e)
            metrics = {m: math.nan for m in study.metrics}
        row = asdict(Row(i, status, message, inside, time.perf_counter() - t0, worker))
        out.append({**{"case": i}, **params, **metrics, **row})
    return out


def run_batch_csv(
    fmu_path: str, study: Study, cases: list[int], shipped: bool, cols: list, fp: str
) -> tuple[str, int, float, float]:
    """One Dask task of `run_sweep`: the rows of `run_batch` as the lines of the result file
    (columns `cols`, which are `columns(study)`; fingerprint `fp`), formatted on the worker: the
    client only appends them, so it takes no share of the cores from the workers. Returns (text,
    rows, Σ seconds in FMU calls, seconds of the whole task but loading the FMU)."""
    if cols != columns(study):
        raise ValueError("run_batch_csv: the columns are not the study's")
    if shipped:
        from ..cluster import local_fmu

        fmu_path = local_fmu(fmu_path)
    fmu = _worker_fmu(fmu_path)
    t0 = time.perf_counter()
    worker = _worker_name()
    res = run_cases(fmu, study, list(cases), outputs_of(study))
    text = _csv_lines(res, worker, fp)
    return text, len(res.cases), float(res.seconds_fmu.sum()), time.perf_counter() - t0


def _csv_row(fields: list) -> str:
    """One line of csv.writer (the result file's dialect), without its line end."""
    buf = io.StringIO()
    csv.writer(buf).writerow(fields)
    return buf.getvalue()[:-2]


def _csv_lines(res, worker: str, fp: str) -> str:
    """The lines csv.writer writes for the rows of `res` (run_cases) with `worker` and the
    fingerprint `fp`, byte for byte: the numbers formatted natively as repr writes them
    (batch.format_csv: csv.writer writes a float as its repr), the text cells as csv.writer
    quotes them, once per distinct value."""
    from ..fmu import batch

    study = res.study
    if not res.cases:
        return ""
    if not study.floats_only:  # integer or boolean values: csv.writer, as they are
        lines = [
            [i, *[int(v) if isinstance(v, bool) else v for v in res.params_of(c).values()],
             *res.metrics[c].tolist(), res.status[c], res.message[c],
             float(res.seconds_fmu[c]), float(res.seconds_case[c]), worker, fp]
            for c, i in enumerate(res.cases)
        ]  # fmt: skip
        buf = io.StringIO()
        csv.writer(buf).writerows(lines)
        return buf.getvalue()
    numbers = batch.format_csv(np.hstack([res.params, res.metrics])).decode().split("\n")
    seconds = batch.format_csv(np.column_stack([res.seconds_fmu, res.seconds_case]))
    seconds = seconds.decode().split("\n")
    tail = _csv_row([worker, fp])
    middle: dict = {}
    for sm in zip(res.status, res.message):
        if sm not in middle:
            middle[sm] = _csv_row(list(sm))
    return "".join(
        f"{i},{a},{middle[sm]},{s},{tail}\r\n"
        for i, a, sm, s in zip(res.cases, numbers, zip(res.status, res.message), seconds)
    )


def columns(study: Study) -> list[str]:
    return [
        "case",
        *study.varied,
        *study.metrics,
        "status",
        "message",
        "seconds_fmu",
        "seconds_case",
        "worker",
        "fingerprint",
    ]


class SweepError(UserError):
    """A sweep that must not start (a result file of another study, a scheduler that does not
    answer): one line saying what and what to do."""


class ClusterStartError(SweepError):
    """The local Dask cluster could not start: its worker processes died while starting (killed
    by the system, out of memory). Not an input error: exit code 1 (docs/install.md)."""

    exit_code = RunFailed.exit_code


#: Attempts to start a LocalCluster whose workers die while starting (a worker killed once by the
#: system should not end a sweep; one that dies every time is reported).
CLUSTER_ATTEMPTS = 2


def fingerprint(study: Study, fmu_path: str | pathlib.Path) -> str:
    """What produced a result row: 12 hex digits of the study's content (study.content_hash), a
    dash, 8 of the FMU's GUID and version. Two parts, so a mismatch can say which changed."""
    _, guid, version = check_fmu(fmu_path)
    fmu = hashlib.sha256(f"{guid}\n{version}".encode()).hexdigest()
    return f"{study.content_hash[:12]}-{fmu[:8]}"


def read_done(csv_path: pathlib.Path, fp: str | None = None, cols: list | None = None) -> set[int]:
    """The cases already in a result file (a resumed sweep does not compute them again). With
    `fp`, every row must carry that fingerprint and the header must be `cols`: a result file of
    another study or FMU is refused (SweepError), never mixed with new rows."""
    if not csv_path.is_file():
        return set()
    done = set()
    fresh = "run again with --fresh to discard it (or choose another --out-dir)"
    with open(csv_path, newline="", encoding="utf-8", errors="replace") as f:
        reader = csv.DictReader(f)
        header = reader.fieldnames or []
        if fp is not None and header and "fingerprint" not in header:
            raise SweepError(
                f"{csv_path}: a result file without a fingerprint (written by an older version): "
                f"its study and FMU are unknown; {fresh}"
            )
        if fp is not None and cols is not None and header and header != cols:
            raise SweepError(
                f"{csv_path}: its columns ({', '.join(header[1:-6])}) are not this study's "
                f"({', '.join(cols[1:-6])}): it holds another study's results; {fresh}"
            )
        rows = iter(reader)
        line = 1
        while True:
            try:
                r = next(rows)
            except StopIteration:
                break
            except csv.Error as e:
                raise SweepError(
                    f"{csv_path} line {reader.line_num}: not a CSV row ({e}); the file is damaged: "
                    f"{fresh}"
                ) from None
            line = reader.line_num
            if fp is not None and (None in r or None in r.values()):
                # Only the last line can be cut by a kill, and that one is dropped before.
                n = sum(v is not None for k, v in r.items() if k is not None)
                n += len(r.get(None) or [])
                raise SweepError(
                    f"{csv_path} line {line}: {n} fields, the header has {len(header)}; the file "
                    f"is damaged: {fresh}"
                )
            if r.get("status") not in ("ok", "error") or not r.get("fingerprint"):
                if fp is not None:
                    raise SweepError(
                        f"{csv_path} line {line}: status = {show(r.get('status'))}; allowed: ok, "
                        f"error; the file is damaged: {fresh}"
                    )
                continue
            if fp is not None and r["fingerprint"] != fp:
                theirs, ours = r["fingerprint"], fp
                what = (
                    "the study's content (machine, fixed values, parameters, design, revolutions, "
                    "steps or metrics)"
                    if theirs.split("-")[0] != ours.split("-")[0]
                    else "the FMU (its GUID or version)"
                )
                raise SweepError(
                    f"{csv_path} line {line}: computed with fingerprint {theirs}, this run is {ours}: "
                    f"{what} changed since; {fresh}"
                )
            try:
                case = int(r["case"])
            except (KeyError, ValueError):
                if fp is not None:
                    raise SweepError(
                        f"{csv_path} line {line}: case = {show(r.get('case'))}; allowed: an "
                        f"integer; the file is damaged: {fresh}"
                    ) from None
                continue
            done.add(case)
    return done


def _drop_cut_line(csv_path: pathlib.Path) -> None:
    """A sweep killed while writing leaves a last line without its newline: remove it, so that
    the rows appended on resume start on a line of their own (that case is computed again)."""
    if not csv_path.is_file():
        return
    size = csv_path.stat().st_size
    if size == 0:
        return
    with open(csv_path, "rb+") as f:
        f.seek(size - 1)
        if f.read(1) == b"\n":
            return
        # Look back for the last newline without reading the whole file.
        pos = size
        while pos > 0:
            start = max(0, pos - 65536)
            f.seek(start)
            chunk = f.read(pos - start)
            k = chunk.rfind(b"\n")
            if k >= 0:
                f.truncate(start + k + 1)
                return
            pos = start
        f.truncate(0)


@dataclass
class SweepResult:
    csv: pathlib.Path
    parquet: pathlib.Path
    computed: int  # cases computed by this call
    skipped: int  # cases found in the result file
    wall: float  # seconds of this call, from the first submission to the last result
    seconds_fmu: float  # sum over the computed cases of the time inside FMU calls
    workers: int
    total: int = 0  # rows in the result file at the end
    rejected: int = 0  # of them with status "error"
    seconds_cases: float = 0.0  # sum over the batches of their time on the workers
    batches: int = 0  # Dask tasks


@dataclass
class Progress:
    """What a running sweep has done so far (read by the Ctrl-C message)."""

    computed: int = 0
    found: int = 0
    csv: pathlib.Path | None = None
    started: bool = False
    extra: dict = field(default_factory=dict)


def scheduler_address(addr: str) -> tuple[str, str, int]:
    """Checks the form of a scheduler address: (scheme, host, port), or a one-line UserError."""
    from distributed.comm.addressing import parse_address, parse_host_port

    allowed = "allowed: tcp://HOST:PORT (or tls://HOST:PORT), e.g. tcp://10.0.0.5:8786"
    try:
        scheme, loc = parse_address(addr)
        host, port = parse_host_port(loc)
    except (ValueError, TypeError) as e:
        raise SweepError(f"--scheduler {show(addr)}: {e}; {allowed}") from None
    if scheme not in ("tcp", "tls"):
        raise SweepError(f"--scheduler {show(addr)}: scheme {scheme!r}; {allowed}")
    if not host or not isinstance(port, int) or not 1 <= port <= 65535:
        raise SweepError(f"--scheduler {show(addr)}: host {host!r}, port {port!r}; {allowed}")
    return scheme, host, port


def probe_scheduler(addr: str, timeout: float) -> None:
    """Connects to a tcp:// scheduler address and waits at most `timeout` seconds for the Dask
    handshake, which a Dask server sends first (distributed.comm.core: the server writes its
    handshake on accept). distributed's own connect waits for that handshake without a bound, so
    an address where something else listens (an HTTP server) would hang the sweep forever."""
    scheme, host, port = scheduler_address(addr)
    if scheme != "tcp":
        return
    where = f"--scheduler {addr}"
    try:
        s = socket.create_connection((host, port), timeout=timeout)
    except socket.gaierror as e:
        raise SweepError(f"{where}: host {host!r} cannot be resolved ({e.strerror})") from None
    except ConnectionRefusedError:
        raise SweepError(
            f"{where}: connection refused: no Dask scheduler listens on {host}:{port}"
        ) from None
    except TimeoutError:
        raise SweepError(f"{where}: no answer within {timeout:g} s (--connect-timeout)") from None
    except OSError as e:
        raise SweepError(f"{where}: cannot connect ({e.strerror or e})") from None
    data = b""
    try:
        s.settimeout(timeout)
        deadline = time.monotonic() + timeout
        while len(data) < 16 and time.monotonic() < deadline:
            chunk = s.recv(16 - len(data))
            if not chunk:
                break
            data += chunk
    except TimeoutError:
        pass
    except OSError as e:
        raise SweepError(f"{where}: the connection failed ({e.strerror or e})") from None
    finally:
        s.close()
    if not data:
        raise SweepError(
            f"{where}: something listens there but sent no Dask handshake within {timeout:g} s: "
            "not a Dask scheduler (an HTTP server?)"
        )
    total, nframes = int.from_bytes(data[:8], "little"), int.from_bytes(data[8:16], "little")
    if len(data) < 16 or not (1 <= nframes <= 1000 and 16 <= total < 1 << 30):
        raise SweepError(f"{where}: answered {show(data, 40)}: not a Dask scheduler")


@contextlib.contextmanager
def _quiet_distributed():
    """distributed logs to stderr; while a cluster is started and closed (also after Ctrl-C) its
    routine warnings would bury the tool's own one-line messages. Its table of version differences
    between client and workers too: what must agree (this package, dask, distributed) is checked
    by cluster.prepare_workers, which names the worker in one line."""
    import warnings

    from distributed.versions import VersionMismatchWarning

    # tornado.application by name: distributed's logging configuration gives it a level of its
    # own (error), so it does not follow "tornado"; a callback failing inside distributed while
    # the cluster closes after Ctrl-C would print its traceback there.
    names = ("distributed", "tornado", "tornado.application", "asyncio")
    levels = [logging.getLogger(n).level for n in names]
    for n in names:
        logging.getLogger(n).setLevel(logging.CRITICAL)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", VersionMismatchWarning)
            yield
    finally:
        for n, lv in zip(names, levels):
            logging.getLogger(n).setLevel(lv)


def _client(scheduler: str | None, workers: int | None, connect_timeout: float):
    from dask.distributed import Client, LocalCluster

    if scheduler:
        probe_scheduler(scheduler, connect_timeout)
        try:
            client = Client(scheduler, timeout=connect_timeout)
        except (OSError, TimeoutError) as e:
            raise SweepError(f"--scheduler {scheduler}: cannot connect ({e})") from None
        try:
            client.wait_for_workers(1, timeout=max(connect_timeout, 30.0))
        except TimeoutError:
            client.close()
            raise SweepError(
                f"--scheduler {scheduler}: no worker joined within {max(connect_timeout, 30):g} s; "
                "start workers with: dask worker " + scheduler
            ) from None
        return client, None
    n = workers or os.cpu_count() or 1
    # The workers' logging goes to the same terminal: errors only (a batch cancelled after Ctrl-C
    # is not one). Config reaches the spawned workers through the environment.
    # Their statistical profiler feeds the dashboard, which a sweep does not show: without it a
    # worker spends some percent less CPU per case (scripts/bench_sweep.py, docs/sweeps.md "Speed").
    env = {
        "DASK_LOGGING__DISTRIBUTED": "error",
        "DASK_DISTRIBUTED__WORKER__PROFILE__ENABLED": "False",
    }
    old_env = {k: os.environ.get(k) for k in env}
    os.environ.update(env)
    try:
        for attempt in range(1, CLUSTER_ATTEMPTS + 1):
            try:
                cluster = LocalCluster(
                    n_workers=n,
                    threads_per_worker=1,
                    processes=True,
                    dashboard_address=":0",
                    host="127.0.0.1",
                    preload=[__name__],  # dask_setup below: the workers ignore Ctrl-C
                )
                break
            except RuntimeError as e:
                # distributed says "Nanny failed to start." when a worker process dies (is
                # killed) before it has started; it cleans up what it had started itself.
                if "failed to start" not in str(e) or attempt == CLUSTER_ATTEMPTS:
                    if "failed to start" not in str(e):
                        raise
                    raise ClusterStartError(
                        f"the local Dask cluster ({n} worker processes) could not start: a worker "
                        f"process died while starting ({e}), {CLUSTER_ATTEMPTS} times; check the "
                        "memory free and the system log (a process killed), or use fewer "
                        "--workers"
                    ) from None
    finally:
        for k, v in old_env.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v
    return Client(cluster), cluster


def dask_setup(worker) -> None:
    """Preload of the LocalCluster's workers: Ctrl-C in the terminal reaches the whole process
    group; the sweep itself saves what is done and stops the workers (cluster.close), so a worker
    must not die of it with a KeyboardInterrupt traceback of its own."""
    import threading

    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)


def _close(client, cluster) -> None:
    with contextlib.suppress(Exception):
        client.close(timeout=10)
    if cluster is not None:
        with contextlib.suppress(Exception):
            cluster.close(timeout=10)


def run_sweep(
    study: Study,
    fmu_path: str,
    out_dir: str | pathlib.Path,
    scheduler: str | None = None,
    workers: int | None = None,
    batch_size: int | None = None,
    progress: bool = True,
    stop_after: int | None = None,
    fresh: bool = False,
    connect_timeout: float = 10.0,
    batch_seconds: float = 1.0,
    state: Progress | None = None,
) -> SweepResult:
    """Runs every case of `study` not yet in `<out_dir>/<name>.csv`. `stop_after` stops after that
    many new cases (to split a sweep, and in the tests). `fresh` discards the results of an
    earlier run first. `batch_size` fixes the cases per Dask task; by default batches are sized
    to `batch_seconds` of work from the cases' measured time."""
    from dask.distributed import as_completed

    state = state if state is not None else Progress()
    out = pathlib.Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise SweepError(f"--out-dir {out}: cannot be created ({e.strerror})") from None
    csv_path, pq_path = out / f"{study.name}.csv", out / f"{study.name}.parquet"
    fmu_path = str(pathlib.Path(fmu_path).resolve())
    fp = fingerprint(study, fmu_path)
    cols = columns(study)
    if fresh:
        for p in (csv_path, pq_path):
            p.unlink(missing_ok=True)
    try:  # writable, before a cluster starts (and no empty file left behind)
        existed = csv_path.exists()
        with open(csv_path, "a", encoding="utf-8"):
            pass
        if not existed:
            csv_path.unlink()
    except OSError as e:
        raise SweepError(
            f"--out-dir {out}: {csv_path.name} cannot be written ({e.strerror})"
        ) from None
    _drop_cut_line(csv_path)
    done = read_done(csv_path, fp, cols)
    state.found, state.csv = len(done), csv_path
    todo = (i for i in range(study.n_cases) if i not in done)
    left = study.n_cases - len(done)  # cases not submitted yet
    if stop_after is not None:
        todo = itertools.islice(todo, stop_after)
        left = min(left, stop_after)
    with _quiet_distributed():
        client, cluster = _client(scheduler, workers, connect_timeout)
    n_workers = len(client.scheduler_info()["workers"]) or 1
    # A cluster of other machines shares no disk with the client: every worker's package version is
    # checked before anything runs, and the FMU travels as bytes (cluster.py). A LocalCluster's
    # workers run here and open the FMU's path.
    fmu_ref, shipped = fmu_path, False
    if scheduler:
        from ..cluster import WorkerMismatch, prepare_workers

        try:
            fmu_ref, shipped = prepare_workers(client, fmu_path), True
        except WorkerMismatch as e:
            client.close()
            raise SweepError(f"--scheduler {scheduler}: {e}") from None
    bar = None
    computed, fmu_seconds, wall, case_seconds, batches = 0, 0.0, 0.0, 0.0, 0
    try:
        study_f = client.scatter(study, broadcast=True)
        new_file = not csv_path.is_file() or csv_path.stat().st_size == 0
        if progress:
            from tqdm import tqdm

            bar = tqdm(
                total=study.n_cases,
                initial=len(done),
                unit="case",
                desc=study.name,
                file=sys.stderr,
            )
        # Batch size: fixed, or adapted to about batch_seconds of work (one case at first, to
        # measure). With two batches per worker in flight, a kill loses ~2·batch_seconds per worker.
        size, per_case = batch_size or 1, None
        in_flight = 2 * n_workers

        def submit():
            nonlocal left
            n = size
            if batch_size is None and per_case is not None:
                # The last batches shrink (to no less than a twentieth of batch_seconds), so that
                # the workers finish together instead of one waiting for another's last batch.
                n = min(n, max(int(0.05 * batch_seconds / per_case), -(-left // in_flight), 1))
            b = list(itertools.islice(todo, n))
            left -= len(b)
            if not b:
                return None
            return client.submit(run_batch_csv, fmu_ref, study_f, b, shipped, cols, fp, pure=False)

        t0 = time.perf_counter()
        state.started = True
        with open(csv_path, "a", newline="", encoding="utf-8") as f:
            w = csv.DictWriter(f, fieldnames=cols)
            if new_file:
                w.writeheader()
                f.flush()
            first = [x for x in (submit() for _ in range(in_flight)) if x is not None]
            ac = as_completed(first)
            for fut in ac:
                text, n_rows, inside, seconds = fut.result()
                f.write(text)
                f.flush()
                fmu_seconds += inside
                case_seconds += seconds
                batches += 1
                computed += n_rows
                state.computed = computed
                if bar is not None:
                    bar.update(n_rows)
                if batch_size is None and n_rows:
                    t = seconds / n_rows
                    per_case = t if per_case is None else 0.5 * (per_case + t)
                    size = int(min(_MAX_BATCH, max(1, batch_seconds / max(per_case, 1e-6))))
                nxt = submit()
                if nxt is not None:
                    ac.add(nxt)
        wall = time.perf_counter() - t0
    finally:
        if bar is not None:
            bar.close()
        with _quiet_distributed():
            _close(client, cluster)
    total, rejected = write_tables(csv_path, pq_path, study)
    return SweepResult(
        csv_path, pq_path, computed, len(done), wall, fmu_seconds, n_workers, total, rejected,
        case_seconds, batches,
    )  # fmt: skip


def warnings(study: Study) -> list[str]:
    """One line per varied parameter that cannot act in any case of the study."""
    return [
        f'{k} cannot act in this study: {why} (docs/sweeps.md "Parameters that cannot act")'
        for k, why in study.inert.items()
    ]


def _arrow_table(csv_path: pathlib.Path, study: Study):
    """The result file as an Arrow table: complete rows only, one per case, sorted by case;
    parameters, metrics and timings as float64 (NaN for a rejected case's metrics)."""
    import pyarrow as pa
    import pyarrow.compute as pc
    import pyarrow.csv as pcsv

    cols = columns(study)
    floats = [*study.varied, *study.metrics, "seconds_fmu", "seconds_case"]
    types = {c: pa.float64() for c in floats}
    types.update(
        case=pa.int64(),
        status=pa.string(),
        message=pa.string(),
        worker=pa.string(),
        fingerprint=pa.string(),
    )
    if not csv_path.is_file() or csv_path.stat().st_size == 0:
        return pa.table({c: pa.array([], type=types[c]) for c in cols})
    t = pcsv.read_csv(
        csv_path,
        read_options=pcsv.ReadOptions(block_size=1 << 24),
        parse_options=pcsv.ParseOptions(newlines_in_values=True),
        convert_options=pcsv.ConvertOptions(
            column_types=types,
            strings_can_be_null=False,
            true_values=["True", "true"],
            false_values=["False", "false"],
            null_values=[""],
        ),
    )
    t = t.filter(pc.is_in(t["status"], pa.array(["ok", "error"])))
    t = t.sort_by([("case", "ascending")])
    case = t["case"].to_numpy()
    if len(case) > 1:
        keep = np.concatenate([[True], case[1:] != case[:-1]])
        t = t.filter(pa.array(keep))
    return t.select(cols)


def load_rows(csv_path: pathlib.Path, study: Study) -> list[dict]:
    """The result rows sorted by case, numbers as floats (NaN for a rejected case's metrics)."""
    rows = _arrow_table(csv_path, study).to_pylist()
    for r in rows:
        for k in (*study.varied, *study.metrics, "seconds_fmu", "seconds_case"):
            if r[k] is None:
                r[k] = math.nan
    return rows


def write_tables(csv_path: pathlib.Path, pq_path: pathlib.Path, study: Study) -> tuple[int, int]:
    """Rewrites the CSV sorted by case (through a temporary file, replaced at once) and writes the
    same table as Parquet with the fingerprint in its metadata. Returns (rows, rejected rows)."""
    import pyarrow.parquet as pq

    t = _arrow_table(csv_path, study)
    cols = columns(study)
    tmp = csv_path.with_suffix(".csv.tmp")
    with open(tmp, "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(cols)
        for batch in t.to_batches(max_chunksize=65536):
            for r in zip(*(batch.column(c).to_pylist() for c in cols)):
                w.writerow([repr(v) if isinstance(v, float) else v for v in r])
    tmp.replace(csv_path)
    fps = sorted(set(t["fingerprint"].to_pylist())) if t.num_rows else []
    meta = {
        b"fingerprint": ",".join(fps).encode(),
        b"study": study.name.encode(),
        # Varied parameters that cannot act (docs/sweeps.md "Parameters that cannot act").
        b"warnings": "\n".join(warnings(study)).encode(),
    }
    pq.write_table(t.replace_schema_metadata(meta), pq_path)
    n_err = int(np.sum(np.asarray(t["status"].to_pylist(), dtype=object) == "error"))
    return t.num_rows, n_err
