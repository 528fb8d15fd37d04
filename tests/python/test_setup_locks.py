"""The set-up scripts on a fresh machine: the main job (scripts/run.sh) builds for this machine only,
and two set-ups started at once take turns at what they share (scripts/lib/lock.sh).

The programs the scripts would call (cargo, rustup, apt-get, python) are replaced by small
recording stand-ins on PATH, so nothing is installed or built; what is checked is which commands the
scripts ask for, and, for the concurrent runs, that the time intervals the stand-ins were busy in
never overlap (the independent observation of "serialised").
"""

from __future__ import annotations

import os
import pathlib
import shutil
import stat
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
LIB = ROOT / "scripts" / "lib"

pytestmark = pytest.mark.skipif(shutil.which("flock") is None, reason="flock(1) is not installed")


def stub(bindir: pathlib.Path, name: str, body: str) -> None:
    p = bindir / name
    p.write_text("#!/usr/bin/env bash\n" + body)
    p.chmod(p.stat().st_mode | stat.S_IXUSR)


def env_with(bindir: pathlib.Path, tmp: pathlib.Path, **extra: str) -> dict[str, str]:
    env = dict(os.environ)
    env["PATH"] = f"{bindir}:{env['PATH']}"
    env["RD_LOCK_DIR"] = str(tmp)
    env.update(extra)
    return env


def intervals(log: pathlib.Path) -> list[tuple[float, float]]:
    """Pairs of (start, end) from lines "start T" / "end T" written by one busy stand-in per run."""
    starts: dict[str, float] = {}
    out = []
    for line in log.read_text().split("\n"):
        if not line:
            continue
        what, pid, t = line.split()
        if what == "start":
            starts[pid] = float(t)
        else:
            out.append((starts.pop(pid), float(t)))
    return sorted(out)


def assert_serialised(spans: list[tuple[float, float]], n: int) -> None:
    assert len(spans) == n, spans
    for (_, end), (start, _) in zip(spans, spans[1:], strict=False):
        assert start >= end, f"the two runs overlapped: {spans}"


def test_run_sh_asks_for_no_cross_target(tmp_path):
    """scripts/run.sh up to its FMU build: cargo is asked for this machine's libraries only, and
    rustup / apt-get are never asked for the aarch64 or Windows targets or toolchains."""
    bindir = tmp_path / "bin"
    bindir.mkdir()
    calls = tmp_path / "calls.log"
    # rustup knows no installed target, so a script that wanted one would add it.
    stub(bindir, "rustup", f'echo "rustup $*" >> "{calls}"\n')
    stub(bindir, "apt-get", f'echo "apt-get $*" >> "{calls}"\n')
    stub(bindir, "sudo", f'echo "sudo $*" >> "{calls}"\n')
    # cargo records and succeeds, but stops the job at the model-description generator (the
    # cross builds, if any, come before it); exit 3 is what run.sh then exits with.
    stub(
        bindir,
        "cargo",
        f'echo "cargo $*" >> "{calls}"\ncase "$*" in *gen-model-description*) exit 3;; esac\n',
    )
    env = env_with(bindir, tmp_path)
    env.pop("RD_AARCH64", None)
    env.pop("RD_WIN64", None)
    p = subprocess.run(
        ["bash", str(ROOT / "scripts" / "run.sh")],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    log = calls.read_text() if calls.exists() else ""
    assert p.returncode == 3, (p.returncode, p.stderr, log)
    assert "cargo build --release --workspace --lib" in log
    for word in ("aarch64", "windows", "mingw", "--target", "rustup target add"):
        assert word not in log, f"run.sh asked for {word!r}:\n{log}"


def test_the_lock_serialises_two_processes(tmp_path):
    log = tmp_path / "busy.log"
    script = (
        f'source "{LIB}/lock.sh"; '
        f'busy() {{ echo "start $$ $(date +%s.%N)" >> "{log}"; sleep 1; '
        f'echo "end $$ $(date +%s.%N)" >> "{log}"; }}; rd_with_lock test busy'
    )
    env = env_with(tmp_path, tmp_path)
    procs = [subprocess.Popen(["bash", "-c", script], env=env) for _ in range(2)]
    assert [p.wait(timeout=30) for p in procs] == [0, 0]
    assert_serialised(intervals(log), 2)


def test_the_lock_keeps_the_exit_status_and_errexit(tmp_path):
    env = env_with(tmp_path, tmp_path)
    lock = f'source "{LIB}/lock.sh"; '
    p = subprocess.run(["bash", "-c", lock + "rd_with_lock t bash -c 'exit 7'"], env=env)
    assert p.returncode == 7
    # Under set -e a failing step inside the locked function stops the script there.
    p = subprocess.run(
        ["bash", "-c", "set -e; " + lock + "f() { false; echo NOT-STOPPED; }; rd_with_lock t f"],
        env=env,
        capture_output=True,
        text=True,
    )
    assert p.returncode != 0 and "NOT-STOPPED" not in p.stdout


def test_two_rustup_target_adds_take_turns(tmp_path):
    """Two ensure_aarch64_build at once: rustup's `target add` never runs twice at the same time
    (rustup itself fails with "detected conflict" then), and the second finds the target added."""
    bindir = tmp_path / "bin"
    bindir.mkdir()
    log = tmp_path / "busy.log"
    added = tmp_path / "added"
    stub(
        bindir,
        "rustup",
        f"""case "$*" in
  "target list --installed") [ -e "{added}" ] && echo aarch64-unknown-linux-gnu; exit 0;;
  "target add"*) echo "start $$ $(date +%s.%N)" >> "{log}"; sleep 1; touch "{added}"
                 echo "end $$ $(date +%s.%N)" >> "{log}";;
esac
""",
    )
    stub(bindir, "aarch64-linux-gnu-gcc", "exit 0\n")
    env = env_with(bindir, tmp_path)
    script = f'set -e; source "{LIB}/aarch64.sh"; ensure_aarch64_build'
    procs = [subprocess.Popen(["bash", "-c", script], env=env) for _ in range(2)]
    assert [p.wait(timeout=30) for p in procs] == [0, 0]
    # Serialised, and the second run, re-checking under the lock, did not add it again.
    assert_serialised(intervals(log), 1)


def test_two_ensure_venv_take_turns(tmp_path):
    """Two ensure_venv for one checkout at once: the venv is created once, never twice at the same
    time. A copy of scripts/lib in a scratch checkout, with a stand-in python that records when it
    creates a venv (one second long) and accepts the rest."""
    checkout = tmp_path / "checkout"
    shutil.copytree(LIB, checkout / "scripts" / "lib")
    (checkout / "requirements.txt").write_text("nothing==1\n")
    log = tmp_path / "busy.log"
    fake = tmp_path / "fakepython"
    fake.write_text(
        f"""#!/usr/bin/env bash
case "$1 $2" in
  "-m venv") echo "start $$ $(date +%s.%N)" >> "{log}"; mkdir -p "$3/bin" "$3/lib"; sleep 1
             cp "{fake}" "$3/bin/python"; echo "end $$ $(date +%s.%N)" >> "{log}";;
  "-m pip") ;;
  -c*) case "$2" in
         *version_info*) echo "True 3.99 fake";;
         *executable*) echo "$0";;
         *purelib*) echo "$(dirname "$(dirname "$0")")/lib";;
       esac;;
esac
"""
    )
    fake.chmod(0o755)
    env = env_with(tmp_path, tmp_path, PYTHON=str(fake))
    script = f'set -e; source "{checkout}/scripts/lib/venv.sh"; ensure_venv'
    procs = [subprocess.Popen(["bash", "-c", script], env=env) for _ in range(2)]
    assert [p.wait(timeout=30) for p in procs] == [0, 0]
    assert_serialised(intervals(log), 1)
    assert (checkout / ".venv" / ".requirements.sha256").exists()
    assert (checkout / ".venv" / "bin" / "rdrive").exists()


if __name__ == "__main__":
    sys.exit(pytest.main([__file__, "-q"]))
