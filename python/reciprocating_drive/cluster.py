"""Dask workers that share no disk with the client (docs/sweeps.md, "On a cluster").

A worker needs the `reciprocating_drive` package (the functions it runs are pickled by reference),
so it runs in an environment where the wheel is installed (scripts/build-wheel.sh). Nothing else is
shared: the client ships the FMU's bytes in a worker plugin, and each worker process keeps them in
a private temporary folder, keyed by their SHA-256, so a case never names a path of the client's
machine.

Before any case runs, `prepare_workers` checks that every worker runs the client's package version
and names each worker that does not, with both versions: a worker with other code would compute
other numbers.

Layer: shared, below the FMU access (docs/architecture.md).
"""

from __future__ import annotations

import hashlib
import os
import pathlib
import tempfile

from distributed.diagnostics.plugin import WorkerPlugin

from ._version import __version__


class WorkerMismatch(RuntimeError):
    """Workers whose package differs from the client's (the message names each)."""


#: FMUs received by this worker process: SHA-256 -> local path.
_RECEIVED: dict[str, str] = {}


def fmu_key(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def _identity() -> dict:
    """What must agree between the client and a worker: this package's version, and dask's and
    distributed's (the task protocol). Runs on a worker, and on the client for the reference."""
    import dask
    import distributed

    return {
        "reciprocating_drive": __version__,
        "dask": dask.__version__,
        "distributed": distributed.__version__,
    }


def _receive_fmu(data: bytes, key: str) -> str:
    """Runs on a worker: stores the FMU sent by the client once per worker process."""
    path = _RECEIVED.get(key)
    if path is None or not os.path.isfile(path):
        if fmu_key(data) != key:
            raise ValueError("the FMU arrived damaged (SHA-256 mismatch)")
        folder = tempfile.mkdtemp(prefix="rdrive-fmu-")
        path = os.path.join(folder, f"{key[:16]}.fmu")
        with open(path, "wb") as f:
            f.write(data)
        _RECEIVED[key] = path
    return path


def local_fmu(key: str) -> str:
    """On a worker: the local path of the FMU the client shipped (`prepare_workers`)."""
    path = _RECEIVED.get(key)
    if path is None or not os.path.isfile(path):
        raise RuntimeError(f"this worker has not received the FMU {key[:16]} from the client")
    return path


class ShipFmu(WorkerPlugin):
    """A Dask worker plugin that stores the client's FMU on every worker, those of the cluster
    now and those that join later (its `setup` runs on each). Cases then carry only the FMU's
    SHA-256, so the scheduler spreads them over the workers as it would any task without data."""

    name = "reciprocating-drive-fmu"

    def __init__(self, data: bytes, key: str):
        self.data, self.key = data, key

    def setup(self, worker=None) -> None:
        _receive_fmu(self.data, self.key)


def prepare_workers(client, fmu_path: str | os.PathLike) -> str:
    """Checks every worker's versions against the client's, then ships the FMU to every worker
    (ShipFmu). Returns the FMU's SHA-256, which the cases pass to `local_fmu`. Raises
    WorkerMismatch naming each worker whose versions differ, before anything runs."""
    ids = client.run(_identity)
    mine = _identity()
    wrong = {
        w: ", ".join(f"{k} {v}" for k, v in i.items() if v != mine[k])
        for w, i in ids.items()
        if i != mine
    }
    if wrong:
        names = "; ".join(f"{w} has {v}" for w, v in sorted(wrong.items()))
        ours = ", ".join(f"{k} {v}" for k, v in mine.items())
        raise WorkerMismatch(
            f"{len(wrong)} of {len(ids)} workers run other versions than the client's ({ours}): "
            f"{names}; install the same wheel and dask on every worker"
        )
    data = pathlib.Path(fmu_path).read_bytes()
    key = fmu_key(data)
    client.register_plugin(ShipFmu(data, key), name=ShipFmu.name)
    return key
