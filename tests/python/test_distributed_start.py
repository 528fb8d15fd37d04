"""`rdrive twin --distributed` when the local Dask cluster's worker processes are killed while it
starts (docs/twin.md "Distributed replay", docs/install.md "Exit codes"): a real LocalCluster
whose spawned worker processes SIGKILL themselves as they start (a `sitecustomize` module on the
workers' path; the client is not touched). Killed once, the cluster is started again and the
replay is the sequential run's files byte for byte; killed every time, one line and exit 1,
never "internal error (Nanny failed to start)"."""

from __future__ import annotations

import os
import subprocess
import sys

from conftest import ROOT

SAMPLE = ROOT / "data" / "twin" / "pump_encoder.csv"
COUNTS = ["--angle-unit", "counts", "--counts-per-rev", "4096"]
TWIN = [sys.executable, "-m", "reciprocating_drive.cli", "twin"]

#: Runs at the start of every Python process on the path; kills a multiprocessing child (a Dask
#: worker process spawned by the nanny) at once: always, or only the first (a marker file).
KILLER = """import os, signal, sys
if "--multiprocessing-fork" in sys.argv:
    once = os.environ.get("RD_KILL_ONCE")
    if not once:
        os.kill(os.getpid(), signal.SIGKILL)
    try:
        os.close(os.open(once, os.O_CREAT | os.O_EXCL))
        os.kill(os.getpid(), signal.SIGKILL)
    except FileExistsError:
        pass
"""


def _twin(tmp_path, fmu_path, out, extra_env=None, distributed=True):
    killer = tmp_path / "killer"
    killer.mkdir(exist_ok=True)
    (killer / "sitecustomize.py").write_text(KILLER)
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(
        [str(killer), str(ROOT / "python"), env.get("PYTHONPATH", "")]
    )
    env.update(extra_env or {})
    args = [str(SAMPLE), *COUNTS, "--out", str(out), "--fmu", fmu_path]
    if distributed:
        args += ["--distributed", "--workers", "2"]
    else:
        env.pop("PYTHONPATH")
    return subprocess.run(
        [*TWIN, *args], capture_output=True, text=True, timeout=300, env=env, cwd=tmp_path
    )


def test_workers_killed_every_time_the_cluster_starts_is_one_line_exit_1(fmu_path, tmp_path):
    p = _twin(tmp_path, fmu_path, tmp_path / "d.csv")
    err = p.stderr.strip().splitlines()
    assert p.returncode == 1, p.stderr
    assert "internal error" not in p.stderr and "Traceback" not in p.stderr, p.stderr
    assert err[-1].startswith("rdrive twin: the local Dask cluster (2 worker processes) could not")
    assert "a worker process died while starting" in err[-1] and "2 times" in err[-1], err
    assert not (tmp_path / "d.csv").exists()


def test_a_worker_killed_once_while_the_cluster_starts_is_started_again(fmu_path, tmp_path):
    seq = tmp_path / "seq.csv"
    q = _twin(tmp_path, fmu_path, seq, distributed=False)
    assert q.returncode == 0, q.stderr
    marker = tmp_path / "killed-once"
    p = _twin(tmp_path, fmu_path, tmp_path / "d.csv", {"RD_KILL_ONCE": str(marker)})
    assert p.returncode == 0, p.stderr
    assert marker.exists()  # a worker was killed
    assert (tmp_path / "d.csv").read_bytes() == seq.read_bytes()
    assert (tmp_path / "d-revolutions.csv").read_bytes() == (
        tmp_path / "seq-revolutions.csv"
    ).read_bytes()
