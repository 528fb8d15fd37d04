"""Sweeps on a cluster that shares no disk with the client (docs/sweeps.md, "On a cluster").

A real Dask scheduler on 127.0.0.1 and real workers started as another user (rdworker), from
another directory, in a venv where only the wheel is installed, with the repository made unreadable
to them: whatever they compute, they cannot have taken from the checkout. The reference for the
numbers is the client's own FMU run in this process."""

from __future__ import annotations

import contextlib
import os
import pathlib
import pwd
import shutil
import socket
import subprocess
import sys
import tempfile
import time

import cloudpickle
import pytest
from wheel_env import ROOT, clean_env

USER = "rdworker"

# The helpers below run on the workers, which cannot import this test file: send them by value.
cloudpickle.register_pickle_by_value(sys.modules[__name__])


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="module")
def worker_user():
    if os.geteuid() != 0:
        pytest.skip("starting workers as another user needs root (CI runs as root)")
    try:
        pwd.getpwnam(USER)
    except KeyError:
        subprocess.run(
            ["useradd", "--system", "--no-create-home", "--shell", "/usr/sbin/nologin", USER],
            check=True,
            timeout=60,
        )
    return USER


@contextlib.contextmanager
def repository_hidden():
    """The checkout unreadable to other users for the duration (root's processes are unaffected)."""
    mode = ROOT.stat().st_mode & 0o7777
    os.chmod(ROOT, 0o700)
    try:
        yield
    finally:
        os.chmod(ROOT, mode)


@contextlib.contextmanager
def package_of_another_version(where: pathlib.Path, version: str = "0.0.1"):
    """A copy of the wheel's installed package whose distribution says `version`, in a folder to
    put ahead of the venv's site-packages (PYTHONPATH): a worker that really imports other code.
    Yields the folder; removes it afterwards."""
    from reciprocating_drive._version import __version__

    site = next((where / "venv" / "lib").glob("python3*/site-packages"))
    other = pathlib.Path(tempfile.mkdtemp(prefix="rdrive-other-"))
    os.chmod(other, 0o755)
    try:
        shutil.copytree(site / "reciprocating_drive", other / "reciprocating_drive")
        info = next(site.glob("reciprocating_drive-*.dist-info"))
        dest = other / f"reciprocating_drive-{version}.dist-info"
        shutil.copytree(info, dest)
        meta = (dest / "METADATA").read_text()
        (dest / "METADATA").write_text(
            meta.replace(f"Version: {__version__}", f"Version: {version}")
        )
        subprocess.run(["chmod", "-R", "a+rX", str(other)], check=True, timeout=30)
        yield other
    finally:
        shutil.rmtree(other, ignore_errors=True)


def _stop(procs):
    for p in procs:
        if p.poll() is None:
            p.terminate()
    for p in procs:
        try:
            p.wait(timeout=20)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait(timeout=10)


@contextlib.contextmanager
def cluster(worker_bin: pathlib.Path, user: str, n_workers: int = 2, extra_env=None):
    """A scheduler (the client's venv) and `n_workers` workers as `user` from `worker_bin`'s venv,
    in a private working folder; yields the scheduler's address; stops everything."""
    from dask.distributed import Client

    work = pathlib.Path(tempfile.mkdtemp(prefix="rdrive-worker-"))
    os.chmod(work, 0o777)
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    dask_cli = pathlib.Path(sys.executable).parent / "dask"
    procs = [
        subprocess.Popen(
            [str(dask_cli), "scheduler", "--host", "127.0.0.1", "--port", str(port),
             "--dashboard-address", ":0", "--no-show"],
            cwd=work, env=clean_env(), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
        )
    ]  # fmt: skip
    try:
        env = clean_env(HOME=str(work), **(extra_env or {}))
        for _ in range(n_workers):
            procs.append(
                subprocess.Popen(
                    ["runuser", "-u", user, "--", str(worker_bin / "dask"), "worker", address,
                     "--nthreads", "1", "--nworkers", "1", "--no-nanny",
                     "--local-directory", str(work), "--dashboard-address", ":0"],
                    cwd=work, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                )
            )  # fmt: skip
        with Client(address, timeout=30) as client:
            client.wait_for_workers(n_workers, timeout=90)
        yield address
    finally:
        _stop(procs)
        shutil.rmtree(work, ignore_errors=True)


def _worker_view():
    """Runs on a worker: who it is, and whether it can see the checkout."""
    import os
    import pwd

    import reciprocating_drive

    try:
        os.listdir(ROOT_ON_CLIENT)
        sees = True
    except OSError:
        sees = False
    return {
        "user": pwd.getpwuid(os.geteuid()).pw_name,
        "package": reciprocating_drive.__file__,
        "sees_repository": sees,
    }


ROOT_ON_CLIENT = str(ROOT)


def _one_step(fmu):
    fmu.start({"crank.angle": 0.7, "crank.speed": 6.8})
    fmu.step(1e-3)
    return fmu.get(["suspension.position", "suspension.acceleration", "crank.torque"])


def test_workers_without_the_repository_compute_with_the_shipped_fmu(
    wheel_venv, worker_user, fmu_path
):
    from dask.distributed import Client
    from reciprocating_drive.cluster import prepare_workers
    from reciprocating_drive.fmu import Fmu

    bin_dir, _, _ = wheel_venv
    with repository_hidden(), cluster(bin_dir, worker_user) as address:
        with Client(address, timeout=30) as client:
            views = client.run(_worker_view)
            assert len(views) == 2
            for v in views.values():
                assert v["user"] == worker_user
                assert not v["sees_repository"]
                assert str(ROOT) not in v["package"]  # the wheel's copy, not the checkout's
            key = prepare_workers(client, fmu_path)

            # Defined here, not at module level, so that Dask sends it by value (the workers cannot
            # import this test file); it loads the shipped FMU and steps it once.
            def _guid_and_row(key):
                from reciprocating_drive.cluster import local_fmu
                from reciprocating_drive.fmu import Fmu

                fmu = Fmu(local_fmu(key))
                fmu.start({"crank.angle": 0.7, "crank.speed": 6.8})
                fmu.step(1e-3)
                names = ["suspension.position", "suspension.acceleration", "crank.torque"]
                return fmu.model_description.guid, fmu.get(names)

            results = client.gather(
                [client.submit(_guid_and_row, key, pure=False, workers=[w]) for w in views]
            )
    ref = Fmu(fmu_path)
    expected = (ref.model_description.guid, _one_step(ref))
    for guid, row in results:
        assert guid == expected[0]
        assert row == expected[1]  # same binary, same inputs: bit for bit


def test_a_worker_with_another_version_is_named_before_anything_runs(wheel_venv, worker_user):
    from dask.distributed import Client
    from reciprocating_drive._version import __version__
    from reciprocating_drive.cluster import WorkerMismatch, prepare_workers

    bin_dir, _, where = wheel_venv
    with (
        package_of_another_version(where) as other,
        repository_hidden(),
        cluster(bin_dir, worker_user, n_workers=1, extra_env={"PYTHONPATH": str(other)}) as address,
        Client(address, timeout=30) as client,
    ):
        t0 = time.monotonic()
        with pytest.raises(WorkerMismatch) as e:
            prepare_workers(client, ROOT / "target" / "fmu" / "ReciprocatingDrive.fmu")
        assert time.monotonic() - t0 < 30
    msg = str(e.value)
    assert "0.0.1" in msg and __version__ in msg and "tcp://127.0.0.1:" in msg


@pytest.mark.parametrize("study", sorted(p.name for p in (ROOT / "studies").glob("*.toml")))
def test_every_example_study_runs_on_the_cluster_that_shares_nothing(
    wheel_venv, worker_user, fmu_path, study, tmp_path
):
    """The sweep command of the checkout as the client; the workers as above. Reference: the same
    cases run in this process through run_case on the client's FMU, with no Dask at all."""
    import pyarrow.parquet as pq
    from reciprocating_drive.fmu import Fmu
    from reciprocating_drive.sweeps.study import load_study
    from reciprocating_drive.sweeps.sweep import run_case

    bin_dir, _, _ = wheel_venv
    out = tmp_path / "out"
    with repository_hidden(), cluster(bin_dir, worker_user) as address:
        r = subprocess.run(
            [sys.executable, str(ROOT / "scripts" / "sweep.py"), str(ROOT / "studies" / study),
             "--scheduler", address, "--out-dir", str(out), "--fmu", fmu_path, "--no-progress"],
            capture_output=True, text=True, timeout=900,
        )  # fmt: skip
    assert r.returncode == 0, r.stderr
    st = load_study(ROOT / "studies" / study, fmu=fmu_path)
    table = pq.read_table(out / f"{st.name}.parquet").to_pylist()
    assert [row["case"] for row in table] == list(range(st.n_cases))
    workers = {row["worker"] for row in table}
    assert all(w.startswith("tcp://127.0.0.1:") for w in workers)
    ref = Fmu(fmu_path)
    for i in sorted({0, st.n_cases // 2, st.n_cases - 1}):
        row = table[i]
        metrics, _ = run_case(ref, st, st.case(i))
        assert row["status"] == "ok", row
        for k, v in metrics.items():
            assert row[k] == v, (study, i, k, row[k], v)  # the same FMU binary: bit for bit


def test_the_sweep_names_a_worker_of_another_version_and_runs_nothing(
    wheel_venv, worker_user, fmu_path, tmp_path
):
    from reciprocating_drive._version import __version__

    bin_dir, _, where = wheel_venv
    with (
        package_of_another_version(where) as other,
        cluster(bin_dir, worker_user, n_workers=1, extra_env={"PYTHONPATH": str(other)}) as address,
    ):
        r = subprocess.run(
            [sys.executable, str(ROOT / "scripts" / "sweep.py"),
             str(ROOT / "studies" / "default_balancer.toml"), "--scheduler", address,
             "--out-dir", str(tmp_path), "--fmu", fmu_path, "--no-progress"],
            capture_output=True, text=True, timeout=300,
        )  # fmt: skip
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    line = r.stderr.strip()
    assert (
        "\n" not in line and "0.0.1" in line and __version__ in line and "tcp://127.0.0.1:" in line
    )
    assert not list(tmp_path.glob("*.csv"))  # no case ran
