"""Design sweeps on Dask's distributed scheduler (docs/sweeps.md).

The cases of a study (python/reciprocating_drive/study.py) are cut into batches; each batch is one
Dask task that runs its cases one after the other on the FMU its worker process has loaded once
(`_worker_fmu`). Results arrive as tasks finish and are appended to `<out>/<study>.csv` at once, so
a sweep that is killed keeps every finished case; started again, it reads that file and computes
only the missing cases. At the end the rows are sorted by case and written as Parquet and CSV.

A case the FMU rejects (a linkage that cannot assemble, a self-locking guide, a buckled rod) is a
row with status "error" and the FMU's message; it never ends the sweep.

By default the sweep starts a `dask.distributed.LocalCluster` with one single-threaded worker
process per core; `scheduler="tcp://host:port"` attaches to an existing cluster instead (workers
started with `dask worker`, dask-jobqueue, dask-kubernetes, ...). Workers need the FMU at the same
path, or a shared file system.
"""

from __future__ import annotations

import csv
import math
import os
import pathlib
import sys
import time
from dataclasses import asdict, dataclass

import numpy as np

from .revolution import TWO_PI, summarize_revolutions
from .study import SPEED_PARAMETERS, Study

#: Outputs read at every step of a case.
OUTPUTS = (
    "crank.model_angle",
    "suspension.position",
    "suspension.acceleration",
    "inertia.force",
    "guide.friction",
    "link.friction_total",
    "rod.force",
    "crank.torque",
    "rod.angle",
    "rod.stress_max",
)

_FMUS: dict = {}


def _worker_fmu(path: str):
    """The FMU of this worker process, loaded once and reused by every case (fmi2Reset between)."""
    from .fmu import Fmu

    f = _FMUS.get(path)
    if f is None:
        f = _FMUS[path] = Fmu(path)
    return f


def _speed(study: Study, params: dict) -> float:
    if "strokes_per_minute" in params:
        return float(params["strokes_per_minute"]) * TWO_PI / 60.0
    if "crank.speed" in params:
        return float(params["crank.speed"])
    return study.crank_speed


def run_case(fmu, study: Study, params: dict) -> tuple[dict, float]:
    """Runs one case on a loaded Fmu; returns (metrics, seconds spent in FMU calls). Raises the
    FMU's error (FmuError) for a rejected case."""
    omega = _speed(study, params)
    if not (omega > 0 and math.isfinite(omega)):
        raise ValueError(f"crank speed = {omega} rad/s; allowed: > 0")
    values = {
        k: v
        for k, v in study.base_values.items()
        if k not in ("crank.angle", "crank.speed", "crank.acceleration")
    }
    values.update({k: v for k, v in params.items() if k not in SPEED_PARAMETERS})
    values["crank.speed"] = omega
    n_rev = study.skip_revolutions + study.revolutions
    n = n_rev * study.steps_per_revolution + 2
    h = TWO_PI / omega / study.steps_per_revolution
    rows = np.empty((n + 1, len(OUTPUTS)))
    t0 = time.perf_counter()
    fmu.start(values)
    ch = fmu.channel(["crank.angle", "crank.speed"], list(OUTPUTS))
    ch.set_inputs([0.0, omega])
    ch.read(rows[0])
    for k in range(1, n + 1):
        t = k * h
        ch.step(
            t, [omega * (t - h), omega], rows[k]
        )  # inputs at the step's start (docs/model.md §2)
    inside = time.perf_counter() - t0
    time_ = np.arange(n + 1) * h
    data = {name: rows[:, i] for i, name in enumerate(OUTPUTS)}
    revs = [
        r
        for r in summarize_revolutions(time_, data["crank.model_angle"], data)
        if r.index >= study.skip_revolutions
    ][: study.revolutions]
    return metrics_of(revs, study.metrics), inside


def metrics_of(revs, wanted) -> dict:
    if not revs:
        raise RuntimeError("no complete evaluated revolution")

    def ext(q, key):
        vals = [getattr(r.extremes[q], key) for r in revs]
        return max(vals) if key == "max" else min(vals)

    last = revs[-1]
    all_metrics = {
        "friction_work": lambda: float(np.mean([r.friction_work for r in revs])),
        "torque_peak": lambda: max(
            abs(ext("crank.torque", "max")), abs(ext("crank.torque", "min"))
        ),
        "torque_max": lambda: ext("crank.torque", "max"),
        "torque_min": lambda: ext("crank.torque", "min"),
        "acceleration_max": lambda: ext("suspension.acceleration", "max"),
        "acceleration_max_angle": lambda: last.extremes["suspension.acceleration"].max_angle_deg,
        "acceleration_min": lambda: ext("suspension.acceleration", "min"),
        "inertia_force_max": lambda: ext("inertia.force", "max"),
        "inertia_force_min": lambda: ext("inertia.force", "min"),
        "guide_friction_max": lambda: ext("guide.friction", "max"),
        "guide_friction_min": lambda: ext("guide.friction", "min"),
        "rod_force_max": lambda: ext("rod.force", "max"),
        "rod_force_max_angle": lambda: last.extremes["rod.force"].max_angle_deg,
        "rod_force_min": lambda: ext("rod.force", "min"),
        "rod_angle_amplitude": lambda: max(r.rod_angle_amplitude for r in revs),
        "stress_max": lambda: max(r.stress_max for r in revs),
    }
    return {m: float(all_metrics[m]()) for m in wanted}


@dataclass
class Row:
    case: int
    status: str
    message: str
    seconds_fmu: float
    seconds_case: float
    worker: str


def run_batch(fmu_path: str, study: Study, cases: list[int]) -> list[dict]:
    """One Dask task: the cases `cases` of `study`, each a result row (never raises for a case)."""
    from .fmu import FmuError

    fmu = _worker_fmu(fmu_path)
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
        row = asdict(
            Row(i, status, message, inside, time.perf_counter() - t0, f"pid {os.getpid()}")
        )
        out.append({**{"case": i}, **params, **metrics, **row})
    return out


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
    ]


def read_done(csv_path: pathlib.Path) -> dict[int, dict]:
    """Rows already in a result file (a resumed sweep does not recompute them)."""
    if not csv_path.is_file():
        return {}
    done = {}
    with open(csv_path, newline="") as f:
        for r in csv.DictReader(f):
            # A line cut short when the sweep was killed lacks its last fields: not done.
            if r.get("status") not in ("ok", "error") or not r.get("worker"):
                continue
            try:
                done[int(r["case"])] = r
            except (KeyError, ValueError):
                continue
    return done


def _drop_cut_line(csv_path: pathlib.Path) -> None:
    """A sweep killed while writing leaves a last line without its newline: remove it, so that
    the rows appended on resume start on a line of their own (that case is computed again)."""
    if not csv_path.is_file():
        return
    data = csv_path.read_bytes()
    if data and not data.endswith(b"\n"):
        csv_path.write_bytes(data[: data.rfind(b"\n") + 1])


@dataclass
class SweepResult:
    csv: pathlib.Path
    parquet: pathlib.Path
    computed: int  # cases computed by this call
    skipped: int  # cases found in the result file
    wall: float  # seconds of this call, from the first submission to the last result
    seconds_fmu: float  # sum over the computed cases of the time inside FMU calls
    workers: int


def _client(scheduler: str | None, workers: int | None):
    from dask.distributed import Client, LocalCluster

    if scheduler:
        return Client(scheduler), None
    n = workers or os.cpu_count() or 1
    cluster = LocalCluster(
        n_workers=n, threads_per_worker=1, processes=True, dashboard_address=":0", host="127.0.0.1"
    )
    return Client(cluster), cluster


def run_sweep(
    study: Study,
    fmu_path: str,
    out_dir: str | pathlib.Path,
    scheduler: str | None = None,
    workers: int | None = None,
    batch_size: int | None = None,
    progress: bool = True,
    max_cases: int | None = None,
) -> SweepResult:
    """Runs every case of `study` not yet in `<out_dir>/<name>.csv`. `max_cases` stops after that
    many new cases (to split a sweep, and in the tests)."""
    from dask.distributed import as_completed

    out = pathlib.Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    csv_path, pq_path = out / f"{study.name}.csv", out / f"{study.name}.parquet"
    cols = columns(study)
    _drop_cut_line(csv_path)
    done = read_done(csv_path)
    todo = [i for i in range(len(study.case_values)) if i not in done]
    if max_cases is not None:
        todo = todo[:max_cases]
    fmu_path = str(pathlib.Path(fmu_path).resolve())
    client, cluster = _client(scheduler, workers)
    n_workers = len(client.scheduler_info()["workers"]) or 1
    try:
        if batch_size is None:
            # A few batches per worker: balanced load, little scheduling overhead per case.
            batch_size = max(1, math.ceil(len(todo) / (4 * n_workers)))
        batches = [todo[k : k + batch_size] for k in range(0, len(todo), batch_size)]
        study_f = client.scatter(study, broadcast=True) if batches else None
        new_file = not csv_path.is_file() or csv_path.stat().st_size == 0
        bar = None
        if progress:
            from tqdm import tqdm

            bar = tqdm(
                total=len(study.case_values),
                initial=len(done),
                unit="case",
                desc=study.name,
                file=sys.stderr,
            )
        computed, fmu_seconds = 0, 0.0
        t0 = time.perf_counter()
        with open(csv_path, "a", newline="") as f:
            w = csv.DictWriter(f, fieldnames=cols)
            if new_file:
                w.writeheader()
            futures = [client.submit(run_batch, fmu_path, study_f, b, pure=False) for b in batches]
            for fut in as_completed(futures):
                rows = fut.result()
                for r in rows:
                    w.writerow({k: r.get(k, "") for k in cols})
                    fmu_seconds += r["seconds_fmu"]
                f.flush()
                computed += len(rows)
                if bar is not None:
                    bar.update(len(rows))
        wall = time.perf_counter() - t0
        if bar is not None:
            bar.close()
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    write_tables(csv_path, pq_path, study)
    return SweepResult(csv_path, pq_path, computed, len(done), wall, fmu_seconds, n_workers)


def load_rows(csv_path: pathlib.Path, study: Study) -> list[dict]:
    """The result rows sorted by case, numbers as floats (NaN for a rejected case's metrics)."""
    rows = []
    for r in read_done(csv_path).values():
        row = {"case": int(r["case"])}
        for k in (*study.varied, *study.metrics, "seconds_fmu", "seconds_case"):
            v = r.get(k, "")
            row[k] = math.nan if v == "" else float({"True": 1.0, "False": 0.0}.get(v, v))
        row.update(status=r["status"], message=r["message"], worker=r["worker"])
        rows.append(row)
    return sorted(rows, key=lambda r: r["case"])


def write_tables(csv_path: pathlib.Path, pq_path: pathlib.Path, study: Study) -> None:
    """Rewrites the CSV sorted by case and writes the same table as Parquet."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    rows = load_rows(csv_path, study)
    cols = columns(study)
    tmp = csv_path.with_suffix(".csv.tmp")
    with open(tmp, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=cols)
        w.writeheader()
        for r in rows:
            w.writerow({k: (repr(v) if isinstance(v, float) else v) for k, v in r.items()})
    tmp.replace(csv_path)
    pq.write_table(pa.Table.from_pylist(rows), pq_path)
