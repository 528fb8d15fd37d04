"""Standard input and a growing file as sources of the plant pipeline (docs/plant.md "Sources").
The reference is `rdrive twin` on the whole file (test_plant_csv_sink.rdrive_twin); a CSV sink's
files are compared with it byte for byte. The producers are real: a pipe into the process, and a
thread appending to a file while the twin follows it."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time

import plant_util as pu
import pytest
from test_plant_csv_sink import csv_sink, rdrive_twin

LINES = pu.SAMPLE.read_text().splitlines()


@pytest.fixture(scope="module")
def reference(fmu_path, tmp_path_factory):
    return rdrive_twin(tmp_path_factory.mktemp("ref"), fmu_path)


def _files(out):
    return out.read_bytes(), out.with_name(out.stem + "-revolutions.csv").read_bytes()


def _covered(out) -> int:
    try:
        m = json.loads(out.with_name(out.name + ".checkpoint.json").read_text())
    except (OSError, ValueError):
        return 0
    return m["state"]["counters"]["samples"] if m["state"] else 0


def _rows(out) -> int:
    return max(0, len(out.read_bytes().splitlines()) - 1) if out.exists() else 0


def stdin_source(kind="stdin"):
    units = 'angle_unit = "counts"\ncounts_per_rev = 4096\n'
    return ('type = "stdin"\n' if kind == "stdin" else 'type = "csv"\npath = "-"\n') + units


def follow_source(path):
    return f'type = "csv"\npath = "{path}"\nfollow = true\nangle_unit = "counts"\ncounts_per_rev = 4096\n'


class Appender(threading.Thread):
    """Appends `lines` to `path` in blocks of `block` lines every `pause` s, then 'EOF'."""

    def __init__(self, path, lines, block=500, pause=0.02, eof=True):
        super().__init__(daemon=True)
        self.path, self.lines, self.block, self.pause, self.eof = path, lines, block, pause, eof
        self.stop = threading.Event()

    def run(self):
        with open(self.path, "a") as f:
            for i in range(0, len(self.lines), self.block):
                if self.stop.is_set():
                    return
                f.write("\n".join(self.lines[i : i + self.block]) + "\n")
                f.flush()
                time.sleep(self.pause)
            if self.eof:
                f.write("EOF\n")


def _start(cfg, stdin=None):
    return subprocess.Popen(
        [sys.executable, str(pu.SCRIPT), "--config", str(cfg)],
        env=pu.env(), stdin=stdin, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip


@pytest.mark.parametrize("kind", ["stdin", "dash"])
def test_standard_input_equals_rdrive_twin(kind, fmu_path, tmp_path, reference):
    out = tmp_path / "out.csv"
    cfg = pu.write_config(tmp_path / "t.toml", source=stdin_source(kind), sinks=csv_sink(out),
                          fmu=fmu_path)  # fmt: skip
    with open(pu.SAMPLE, "rb") as f:
        p = subprocess.run([sys.executable, str(pu.SCRIPT), "--config", str(cfg)], stdin=f,
                           env=pu.env(), capture_output=True, text=True, timeout=120)  # fmt: skip
    assert p.returncode == 0, p.stderr
    assert _files(out) == reference


def test_standard_input_empty_is_an_error(fmu_path, tmp_path):
    cfg = pu.write_config(tmp_path / "t.toml", source=stdin_source(), sinks=csv_sink(tmp_path / "o.csv"),
                          fmu=fmu_path)  # fmt: skip
    p = subprocess.run([sys.executable, str(pu.SCRIPT), "--config", str(cfg)], input="",
                       env=pu.env(), capture_output=True, text=True, timeout=60)  # fmt: skip
    assert p.returncode == 1 and p.stderr.count("\n") == 1, p.stderr
    assert p.stderr.startswith("standard input: the input is empty"), p.stderr


def test_standard_input_with_a_checkpoint_is_refused(fmu_path, tmp_path):
    """Standard input cannot be rewound: after a kill, the same run on standard input is refused
    with one line; nothing in the sink's files changes."""
    out = tmp_path / "out.csv"
    cfg = pu.write_config(tmp_path / "t.toml", source=stdin_source(), sinks=csv_sink(out),
                          fmu=fmu_path, run_extra="commit_samples = 1000\n")  # fmt: skip
    p = _start(cfg, stdin=subprocess.PIPE)
    try:
        p.stdin.write("\n".join(LINES[:3000]) + "\n")
        p.stdin.flush()
        deadline = time.monotonic() + 30
        while _covered(out) == 0:
            assert time.monotonic() < deadline and p.poll() is None, "no checkpoint"
            time.sleep(0.01)
        p.send_signal(signal.SIGKILL)
        p.wait(timeout=10)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait(timeout=10)
    p.stdin.close()
    covered = _covered(out)
    size = out.stat().st_size
    with open(pu.SAMPLE, "rb") as f:
        again = subprocess.run([sys.executable, str(pu.SCRIPT), "--config", str(cfg)], stdin=f,
                               env=pu.env(), capture_output=True, text=True, timeout=60)  # fmt: skip
    assert again.returncode == 1 and again.stderr.count("\n") == 1, again.stderr
    assert "standard input: run 'r1' has a checkpoint at input line" in again.stderr
    assert "cannot be rewound" in again.stderr
    assert _covered(out) == covered and out.stat().st_size <= size


def test_growing_file_is_followed_until_eof(fmu_path, tmp_path, reference):
    src, out = tmp_path / "growing.csv", tmp_path / "out.csv"
    src.write_text("")
    cfg = pu.write_config(tmp_path / "t.toml", source=follow_source(src), sinks=csv_sink(out),
                          fmu=fmu_path, run_extra="commit_interval = 0.05\n")  # fmt: skip
    p = _start(cfg)
    writer = Appender(src, LINES[:6000], eof=False)
    try:
        writer.start()
        writer.join(timeout=30)
        # All of it written, no 'EOF' yet: the twin waits, and the rows so far are out.
        deadline = time.monotonic() + 30
        while _rows(out) < 5800:
            assert time.monotonic() < deadline
            time.sleep(0.02)
        time.sleep(0.5)
        assert p.poll() is None, p.stderr.read()
        rest = Appender(src, LINES[6000:])
        rest.start()
        rest.join(timeout=30)
        _, err = p.communicate(timeout=60)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait(timeout=10)
    assert p.returncode == 0, err
    assert _files(out) == reference


def test_growing_file_killed_and_resumed(fmu_path, tmp_path, reference):
    src, out = tmp_path / "growing.csv", tmp_path / "out.csv"
    src.write_text("")
    cfg = pu.write_config(tmp_path / "t.toml", source=follow_source(src), sinks=csv_sink(out),
                          fmu=fmu_path, run_extra="commit_interval = 0.05\ncheckpoint_interval = 0.2\n")  # fmt: skip
    writer = Appender(src, LINES, block=200, pause=0.03)
    writer.start()
    p = _start(cfg)
    try:
        deadline = time.monotonic() + 30
        while _covered(out) < 2000:
            assert time.monotonic() < deadline and p.poll() is None, "no checkpoint"
            time.sleep(0.01)
        p.send_signal(signal.SIGKILL)
        p.wait(timeout=10)
        assert writer.is_alive(), "the file was complete before the kill"
        p = _start(cfg)
        writer.join(timeout=60)
        _, err = p.communicate(timeout=60)
    finally:
        writer.stop.set()
        if p.poll() is None:
            p.kill()
            p.wait(timeout=10)
    assert p.returncode == 0, err
    assert _files(out) == reference


@pytest.mark.parametrize("change", ["truncated", "replaced", "removed"])
def test_growing_file_changed_ends_with_one_line(change, fmu_path, tmp_path):
    src, out = tmp_path / "growing.csv", tmp_path / "out.csv"
    src.write_text("\n".join(LINES[:3001]) + "\n")
    cfg = pu.write_config(tmp_path / "t.toml", source=follow_source(src), sinks=csv_sink(out),
                          fmu=fmu_path, run_extra="commit_interval = 0.05\n")  # fmt: skip
    p = _start(cfg)
    try:
        deadline = time.monotonic() + 30
        # Rows go out every commit_interval (a checkpoint waits for more data or the end).
        while _rows(out) < 2900:
            assert time.monotonic() < deadline and p.poll() is None, "not read"
            time.sleep(0.01)
        if change == "truncated":
            os.truncate(src, 100)
        elif change == "replaced":
            other = tmp_path / "other.csv"
            other.write_text("\n".join(LINES[:10]) + "\n")
            os.replace(other, src)
        else:
            src.unlink()
        _, err = p.communicate(timeout=30)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait(timeout=10)
    assert p.returncode == 1 and err.count("\n") == 1, err
    assert err.startswith(f"{src}: was {change}") and "after line 3001" in err, err
    # What was computed before is committed, with a checkpoint that covers it.
    assert _covered(out) == _rows(out) >= 2900


@pytest.mark.parametrize(
    "source, message",
    [
        ('type = "csv"\npath = "-"\nfollow = true\n', "source.follow = True: follows a file"),
        ('type = "csv"\npath = "a.csv"\nfollow = true\npace = 2\n', "source.pace = 2.0:"),
        ('type = "csv"\npath = "a.csv"\nfollow = "yes"\n', "source.follow = 'yes': must be a bool"),
        ('type = "pipe"\n', "source.type = 'pipe': allowed: csv, opcua, stdin"),
    ],
)
def test_stream_source_configuration_errors(tmp_path, fmu_path, source, message):
    cfg = pu.write_config(tmp_path / "t.toml", source=source, sinks=csv_sink("o.csv"), fmu=fmu_path)
    p = pu.run(cfg)
    assert p.returncode == 2 and p.stderr.count("\n") == 1, p.stderr
    assert message in p.stderr and str(cfg) in p.stderr


def test_standard_input_stopped_by_sigterm_commits_and_says_it_cannot_resume(fmu_path, tmp_path):
    """SIGTERM while standard input is open and silent: the twin stops at once (bounded), commits
    what it computed (the checkpoint covers every row in the file) and says how to go on."""
    out = tmp_path / "out.csv"
    cfg = pu.write_config(tmp_path / "t.toml", source=stdin_source(), sinks=csv_sink(out),
                          fmu=fmu_path)  # fmt: skip
    p = _start(cfg, stdin=subprocess.PIPE)
    try:
        p.stdin.write("\n".join(LINES[:3001]) + "\n")
        p.stdin.flush()
        deadline = time.monotonic() + 30
        while _rows(out) < 2900:
            assert time.monotonic() < deadline and p.poll() is None, "not read"
            time.sleep(0.01)
        p.send_signal(signal.SIGTERM)
        _, err = p.communicate(timeout=10)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait(timeout=10)
    assert p.returncode == 128 + signal.SIGTERM, err
    assert "stopped by SIGTERM after input line 3001; committed" in err
    assert "Standard input cannot be rewound" in err and err.count("\n") == 1, err
    assert _covered(out) == _rows(out) >= 2900


@pytest.mark.parametrize("sep", [",", ";"])
def test_paced_replay_keeps_the_pace_of_a_semicolon_file(sep, tmp_path):
    """A CSV file replayed at pace 4: 1 s of data takes at least 0.2 s (0.25 s less the first
    block), whether its fields are separated by ',' or, as a European export writes it, by ';'
    with decimal commas."""
    from reciprocating_drive.plant.sources.csv import CsvSource

    src = tmp_path / "in.csv"
    lines = LINES[:1002]  # 1 kHz: 1 s of data after the header
    if sep == ";":
        lines = [line.replace(",", ";").replace(".", ",") for line in lines]
    src.write_text("\n".join(lines) + "\n")
    s = CsvSource(str(src), pace=4.0, block=1 << 10)
    s.start()
    start, got = time.monotonic(), []
    while not s.ended:
        c = s.get(0.1)
        if c is not None:
            got += c.lines
    took = time.monotonic() - start
    s.close()
    assert got == lines
    assert took >= 0.2, took  # the first block (about 60 lines) sets the origin
