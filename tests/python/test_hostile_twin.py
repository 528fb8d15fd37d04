"""The digital twin's command line (scripts/twin.py) under hostile input: malformed CSV, damaged
checkpoints, illegal options, files that change while followed, Ctrl-C (docs/twin.md).

The rules every case checks (`refused`, `accepted`): a user error exits non-zero with ONE line
naming the line, option or file and the value, and no traceback; a run that exits 0 wrote files
identical byte for byte to the clean run of the same data (an independent run of the clean CSV,
not of the code under test's own idea of clean); a refused run left any earlier output as a prefix
of the clean run's (nothing invented). Every process is bounded in time.

The first part are the findings of issue 23 (and the CSV of issue 25, the newcomer findings of
issue 24 about options) as named tests; the second part generates cases with Hypothesis.
"""

from __future__ import annotations

import base64
import json
import math
import os
import re
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from conftest import ROOT
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

TWIN = [sys.executable, str(ROOT / "scripts" / "twin.py")]
TIMEOUT = 120
#: The default machine at its design speed, 65 strokes/min: exact wrapped angles, 1 kHz.
OMEGA = 2 * math.pi * 65 / 60
N = 400


def clean_rows(n=N, speed=False, force=False):
    rows = []
    for k in range(n):
        t = k / 1000.0
        r = [repr(t), repr(math.fmod(OMEGA * t, 2 * math.pi))]
        if speed:
            r.append(repr(OMEGA))
        if force:
            r.append(repr(100.0 * math.sin(t)))
        rows.append(r)
    return rows


def csv_text(rows, header=("time", "crank_angle")):
    return ",".join(header) + "\n" + "".join(",".join(r) + "\n" for r in rows)


CLEAN = csv_text(clean_rows())


def twin(args, fmu_path, stdin=None, timeout=TIMEOUT):
    return subprocess.run(
        TWIN + [str(a) for a in args] + ["--fmu", fmu_path],
        input=stdin,
        capture_output=True,
        timeout=timeout,
    )


def refused(p, *needles, code=None):
    """Non-zero exit, one line on stderr holding every needle, no traceback."""
    err = p.stderr.decode("utf-8", "replace")
    assert p.returncode != 0, (p.returncode, err)
    if code is not None:
        assert p.returncode == code, (p.returncode, err)
    assert "Traceback" not in err and "internal error" not in err, err
    lines = [x for x in err.splitlines() if x.strip()]
    assert len(lines) == 1, err
    for n in needles:
        assert n in lines[0], (n, lines[0])
    return lines[0]


def accepted(p, out, clean_out):
    """Exit 0, no traceback, and the outputs identical to the clean run's."""
    err = p.stderr.decode("utf-8", "replace")
    assert p.returncode == 0, err
    assert "Traceback" not in err
    assert out.read_bytes() == clean_out.read_bytes()
    assert summary_of(out).read_bytes() == summary_of(clean_out).read_bytes()


def summary_of(out):
    return out.with_name(out.stem + "-revolutions.csv")


def prefix_of_clean(out, clean_out):
    """A refused run's outputs hold nothing the clean run does not (whole lines, in order)."""
    if out.exists():
        got, ref = out.read_bytes(), clean_out.read_bytes()
        assert ref.startswith(got) and (not got or got.endswith(b"\n"))


@pytest.fixture(scope="module")
def clean(fmu_path, tmp_path_factory):
    """The clean CSV and its run's outputs."""
    d = tmp_path_factory.mktemp("clean")
    src = d / "clean.csv"
    src.write_text(CLEAN)
    out = d / "clean-out.csv"
    p = twin([src, "--out", out], fmu_path)
    assert p.returncode == 0, p.stderr
    return src, out


# ---- issue 23 item 4 and issue 25 (the CSV): bad data is never used silently -----------------


@pytest.mark.parametrize(
    "line,needles",
    [
        ("0.001,", ["line 3: crank_angle is empty"]),
        ("0.001,1_0", ["line 3: crank_angle = '1_0' is not a number"]),
        ("0.001,0.0068,7", ["line 3: 3 fields, the header names 2"]),
        ("0.001", ["line 3: 1 fields, the header names 2"]),
        ("0.001,\u0661", ["line 3: crank_angle = '\u0661' is not a number"]),
        ("0x1,0.0068", ["line 3: time = '0x1' is not a number"]),
        ("0.001,nan", ["line 3: crank_angle = 'nan' is not a finite number"]),
    ],
)
def test_a_bad_field_or_row_is_refused_with_its_line(fmu_path, tmp_path, line, needles):
    src = tmp_path / "bad.csv"
    src.write_text(f"time,crank_angle\n0,0\n{line}\n0.002,0.0136\n")
    refused(twin([src, "--out", tmp_path / "o.csv"], fmu_path), "bad.csv", *needles)


def test_an_empty_process_force_is_refused(fmu_path, tmp_path):
    rows = clean_rows(force=True)
    rows[200][2] = ""
    src = tmp_path / "f.csv"
    src.write_text(csv_text(rows, ("time", "crank_angle", "process_force")))
    refused(twin([src, "--out", tmp_path / "o.csv"], fmu_path), "line 202: process_force is empty")


@pytest.mark.parametrize(
    "text,needle",
    [
        ("", "the input is empty"),
        ("time,crank_angle\n", "the input has no sample"),
        ("time,crank_angle\n\n\n", "the input has no sample"),
    ],
)
def test_an_input_without_samples_is_an_error(fmu_path, tmp_path, text, needle):
    src = tmp_path / "empty.csv"
    src.write_text(text)
    refused(twin([src, "--out", tmp_path / "o.csv"], fmu_path), "empty.csv", needle)


@pytest.mark.parametrize(
    "transform",
    [
        pytest.param(lambda s: "\ufeff" + s, id="utf8-bom"),
        pytest.param(lambda s: s.replace(",", ";").replace(".", ","), id="semicolon-decimal-comma"),
        pytest.param(
            lambda s: s.replace("time,crank_angle", '"time","crank_angle"', 1), id="quoted"
        ),
        pytest.param(lambda s: s.replace("\n", "\r\n"), id="crlf"),
        pytest.param(lambda s: s + "EOF\n\n", id="eof-line"),
    ],
)
def test_csv_as_plants_export_it_gives_the_clean_result(fmu_path, clean, tmp_path, transform):
    src = tmp_path / "variant.csv"
    src.write_bytes(transform(CLEAN).encode("utf-8"))
    out = tmp_path / "o.csv"
    p = twin([src, "--out", out], fmu_path)
    accepted(p, out, clean[1])


def test_the_decimal_comma_is_reported(fmu_path, tmp_path):
    src = tmp_path / "eu.csv"
    src.write_text(CLEAN.replace(",", ";").replace(".", ","))
    p = twin([src, "--out", tmp_path / "o.csv"], fmu_path)
    assert p.returncode == 0 and b"';'-separated: a decimal comma" in p.stderr


def test_data_after_an_eof_line_is_refused(fmu_path, tmp_path):
    src = tmp_path / "e.csv"
    src.write_text(CLEAN + "EOF\n1,2\n")
    refused(twin([src, "--out", tmp_path / "o.csv"], fmu_path), f"line {N + 3}: data after")


def test_an_eof_line_ends_standard_input(fmu_path, clean, tmp_path):
    """Item 11: 'EOF' on standard input ends the input, like in --follow; the producer keeping
    its end of the pipe open does not hold the twin."""
    out = tmp_path / "o.csv"
    p = subprocess.Popen(
        TWIN + ["-", "--out", str(out), "--fmu", fmu_path],
        stdin=subprocess.PIPE,
        stderr=subprocess.PIPE,
        stdout=subprocess.PIPE,
    )
    try:
        p.stdin.write((CLEAN + "EOF\n").encode())
        p.stdin.flush()
        assert p.wait(timeout=TIMEOUT) == 0, p.stderr.read()
    finally:
        p.kill()
        p.stdin.close()
        p.wait(timeout=10)
    assert out.read_bytes() == clean[1].read_bytes()


@pytest.mark.parametrize(
    "header,needle",
    [
        ("time,time,crank_angle", "line 1: the header names 'time' twice"),
        ("time,angle", "line 1: the header must name 'crank_angle'"),
    ],
)
def test_bad_headers(fmu_path, tmp_path, header, needle):
    src = tmp_path / "h.csv"
    src.write_text(header + "\n0,0,0\n")
    refused(twin([src, "--out", tmp_path / "o.csv"], fmu_path), needle)


# ---- item 3: the measured speed against the angle ----------------------------------------------


def test_a_speed_in_rpm_read_as_rad_per_s_is_refused(fmu_path, tmp_path):
    rows = clean_rows(speed=True)
    for r in rows:
        r[2] = repr(OMEGA * 60 / (2 * math.pi))
    src = tmp_path / "rpm.csv"
    src.write_text(csv_text(rows, ("time", "crank_angle", "crank_speed")))
    refused(
        twin([src, "--out", tmp_path / "o.csv"], fmu_path),
        "line 2: crank_speed = 65 rad/s contradicts the crank angle",
        "--speed-unit",
    )
    # Read with its unit it agrees with the angle and runs.
    p = twin([src, "--out", tmp_path / "o.csv", "--speed-unit", "rpm"], fmu_path)
    assert p.returncode == 0, p.stderr


def test_a_negative_speed_with_a_forward_angle_is_refused(fmu_path, tmp_path):
    rows = clean_rows(speed=True)
    for r in rows[100:]:
        r[2] = repr(-OMEGA)
    src = tmp_path / "neg.csv"
    src.write_text(csv_text(rows, ("time", "crank_angle", "crank_speed")))
    out = tmp_path / "o.csv"
    line = refused(twin([src, "--out", out], fmu_path), "line 102: crank_speed = -6.80678")
    assert "contradicts" in line


def test_speed_check_warn_ignores_the_contradicting_speed(fmu_path, clean, tmp_path):
    """--speed-check warn: every contradicting speed is ignored, so a file whose every speed is
    wrong gives the run without a speed channel, byte for byte."""
    rows = clean_rows(speed=True)
    for r in rows:
        r[2] = "65.0"
    src = tmp_path / "rpm.csv"
    src.write_text(csv_text(rows, ("time", "crank_angle", "crank_speed")))
    out = tmp_path / "o.csv"
    p = twin([src, "--out", out, "--speed-check", "warn"], fmu_path)
    accepted(p, out, clean[1])
    assert b"400 measured speeds ignored" in p.stdout and b"contradicts" in p.stderr


# ---- item 11: options, machines, FMUs ---------------------------------------------------------


@pytest.mark.parametrize(
    "args,needles",
    [
        (["--machine", "nosuch"], ["--machine 'nosuch'", "allowed: default, kvo630"]),
        (["--window", "nan"], ["--window", "'nan'", "finite number > 0"]),
        (["--window", "-1"], ["--window", "'-1'"]),
        (["--gap-limit", "0"], ["--gap-limit", "'0'"]),
        (["--max-speed", "nan"], ["--max-speed", "'nan'"]),
        (["--stop-after", "0"], ["--stop-after", "'0'", "at least 1"]),
        (["--checkpoint-every", "0"], ["--checkpoint-every", "'0'"]),
        (["--checkpoint-every", "-1"], ["--checkpoint-every", "'-1'"]),
        (["--angle-unit", "counts"], ["--counts-per-rev must be given"]),
        (["--angle-unit", "grad"], ["--angle-unit", "'grad'"]),
    ],
)
def test_illegal_options_are_refused(fmu_path, clean, tmp_path, args, needles):
    p = twin([clean[0], "--out", tmp_path / "o.csv", *args], fmu_path, timeout=60)
    refused(p, *needles, code=2)


def test_a_wrong_fmu_is_refused(fmu_path, clean, tmp_path):
    drive_train = os.path.join(os.path.dirname(fmu_path), "DriveTrain.fmu")
    if not os.path.isfile(drive_train):
        pytest.skip(f"{drive_train} not built")
    p = subprocess.run(
        TWIN + [str(clean[0]), "--out", str(tmp_path / "o.csv"), "--fmu", drive_train],
        capture_output=True,
        timeout=60,
    )
    refused(p, "--fmu", "DriveTrain.fmu", "not the ReciprocatingDrive FMU")
    p = subprocess.run(
        TWIN + [str(clean[0]), "--out", str(tmp_path / "o.csv"), "--fmu", str(clean[0])],
        capture_output=True,
        timeout=60,
    )
    refused(p, "--fmu", "clean.csv", "not a usable FMU")


def test_a_gap_on_a_chunk_boundary_is_reported_once(fmu_path, tmp_path):
    """The chunks cut at the checkpoints: with --checkpoint-every 200 the gap's first sample
    (line 202) starts a chunk."""
    rows = clean_rows()
    for r in rows[200:]:
        t = float(r[0]) + 0.2
        r[0], r[1] = repr(t), repr(math.fmod(OMEGA * t, 2 * math.pi))
    src = tmp_path / "gap.csv"
    src.write_text(csv_text(rows))
    base = [src, "--out", tmp_path / "a.csv"]
    p = twin(base + ["--checkpoint", tmp_path / "cp", "--checkpoint-every", "200"], fmu_path)
    assert p.returncode == 0, p.stderr
    assert p.stderr.count(b"gap of") == 1 and b"1 gap(s)" in p.stdout, p.stderr


# ---- item 2: a resume checks what it resumes --------------------------------------------------


@pytest.fixture()
def stopped(fmu_path, clean, tmp_path):
    """A run of the clean input stopped at line 150 with a checkpoint."""
    out, cp = tmp_path / "p.csv", tmp_path / "cp.json"
    p = twin([clean[0], "--out", out, "--checkpoint", cp, "--stop-after", 150], fmu_path)
    assert p.returncode == 0, p.stderr
    return out, cp


def test_resume_continues_exactly(fmu_path, clean, stopped):
    out, cp = stopped
    p = twin([clean[0], "--out", out, "--resume", cp], fmu_path)
    accepted(p, out, clean[1])


def test_resume_refuses_an_output_cut_shorter_and_never_pads_it(fmu_path, clean, stopped):
    out, cp = stopped
    os.truncate(out, 500)
    p = twin([clean[0], "--out", out, "--resume", cp], fmu_path)
    refused(p, "p.csv", "500 bytes, shorter than")
    assert out.stat().st_size == 500 and b"\0" not in out.read_bytes()
    assert out.stat().st_blocks * 512 < 64 * 1024  # no sparse giant


def test_resume_refuses_an_edited_checkpoint(fmu_path, clean, stopped):
    """A recorded size of 1e12 (the finding: a 1 TB sparse file): the checkpoint's checksum."""
    out, cp = stopped
    d = json.loads(cp.read_text())
    d["out_bytes"] = 10**12
    cp.write_text(json.dumps(d))
    before = out.read_bytes()
    refused(twin([clean[0], "--out", out, "--resume", cp], fmu_path), "cp.json", "checksum")
    assert out.read_bytes() == before


def test_resume_refuses_another_input(fmu_path, clean, stopped, tmp_path):
    out, cp = stopped
    other = tmp_path / "other.csv"
    other.write_text(CLEAN.replace("0.01", "0.02", 1))
    refused(twin([other, "--out", out, "--resume", cp], fmu_path), "other.csv", "not the input of")
    short = tmp_path / "short.csv"
    short.write_text("".join(CLEAN.splitlines(keepends=True)[:100]))
    refused(
        twin([short, "--out", out, "--resume", cp], fmu_path), "short.csv", "fewer than the 150"
    )


@pytest.mark.parametrize(
    "args,needle",
    [
        (["--machine", "kvo630"], "--machine 'kvo630' differs from the checkpoint's 'default'"),
        (["--angle-unit", "deg"], "--angle-unit 'deg' differs from the checkpoint's 'rad'"),
        (["--window", "0.05"], "--window 0.05 differs from the checkpoint's 0.1"),
    ],
)
def test_resume_refuses_changed_options(fmu_path, clean, stopped, args, needle):
    out, cp = stopped
    refused(twin([clean[0], "--out", out, "--resume", cp, *args], fmu_path), needle)


def test_resume_refuses_a_stop_before_the_checkpoint(fmu_path, clean, stopped):
    out, cp = stopped
    before = out.read_bytes()
    p = twin([clean[0], "--out", out, "--resume", cp, "--stop-after", "100"], fmu_path)
    refused(p, "--stop-after 100", "at line 150 already", code=2)
    assert out.read_bytes() == before


@pytest.mark.parametrize(
    "damage,needle",
    [
        (lambda b: b[: len(b) // 2], "not JSON"),
        (lambda b: b"{}", "no checksum"),
        (lambda b: b"[1, 2]", "no checksum"),
        (lambda b: b"\xff\xfe", "not JSON"),
        (lambda b: b[:40] + bytes([b[40] ^ 0x04]) + b[41:], "cp.json"),
    ],
)
def test_corrupt_checkpoints_are_refused(fmu_path, clean, stopped, damage, needle):
    out, cp = stopped
    cp.write_bytes(damage(cp.read_bytes()))
    before = out.read_bytes()
    refused(twin([clean[0], "--out", out, "--resume", cp], fmu_path), "cp.json", needle)
    assert out.read_bytes() == before


def test_a_damaged_fmu_state_with_a_valid_checksum_is_refused(fmu_path, clean, stopped):
    """A checkpoint written by a twin whose FMU state is garbage (not an edit: the checksum is
    made again): the FMU's refusal is a one-line message."""
    from reciprocating_drive.twin import save_checkpoint

    out, cp = stopped
    d = json.loads(cp.read_text())
    del d["sha256"]
    d["fmu_state"] = base64.b64encode(b"garbage" * 10).decode()
    save_checkpoint(cp, d)
    refused(twin([clean[0], "--out", out, "--resume", cp], fmu_path), "checkpoint")


def test_a_checkpoint_of_another_fmu_build_is_refused(fmu_path, clean, stopped):
    from reciprocating_drive.twin import save_checkpoint

    out, cp = stopped
    d = json.loads(cp.read_text())
    del d["sha256"]
    d["fmu_guid"] = "{00000000-0000-0000-0000-000000000000}"
    save_checkpoint(cp, d)
    refused(twin([clean[0], "--out", out, "--resume", cp], fmu_path), "another build")


def test_an_output_over_the_input_is_refused(fmu_path, tmp_path):
    src = tmp_path / "data.csv"
    src.write_text(CLEAN)
    refused(twin([src, "--out", src], fmu_path), "the same file as --out", code=2)
    assert src.read_text() == CLEAN
    refused(
        twin([src, "--out", tmp_path / "o.csv", "--checkpoint", tmp_path / "o.csv"], fmu_path),
        "must name different files",
        code=2,
    )


# ---- items 5, 7, 13: --follow, Ctrl-C ---------------------------------------------------------


def _follow(fmu_path, src, out, change):
    p = subprocess.Popen(
        TWIN + [str(src), "--follow", "--out", str(out), "--fmu", fmu_path],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    try:
        deadline = time.monotonic() + 60
        while not out.exists() or out.stat().st_size < 1000:  # the first rows are out
            assert time.monotonic() < deadline and p.poll() is None, p.stderr.read()
            time.sleep(0.05)
        change()
        p.wait(timeout=60)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait(timeout=10)
    return subprocess.CompletedProcess(p.args, p.returncode, p.stdout.read(), p.stderr.read())


def test_follow_detects_truncation(fmu_path, tmp_path):
    src, out = tmp_path / "g.csv", tmp_path / "o.csv"
    src.write_text(CLEAN)

    def rewrite():
        with open(src, "r+") as f:
            f.truncate(0)
            f.write("".join(CLEAN.splitlines(keepends=True)[:100]))

    p = _follow(fmu_path, src, out, rewrite)
    refused(p, "g.csv was truncated", f"after line {N + 1}")


def test_follow_detects_a_replaced_file_and_does_not_hang(fmu_path, tmp_path):
    src, out = tmp_path / "g.csv", tmp_path / "o.csv"
    src.write_text(CLEAN)

    def replace():
        new = tmp_path / "new.csv"
        new.write_text(CLEAN + "EOF\n")
        os.replace(new, src)

    p = _follow(fmu_path, src, out, replace)
    refused(p, "g.csv was replaced")


def test_follow_detects_a_removed_file(fmu_path, tmp_path):
    src, out = tmp_path / "g.csv", tmp_path / "o.csv"
    src.write_text(CLEAN)
    p = _follow(fmu_path, src, out, src.unlink)
    refused(p, "g.csv was removed", f"after line {N + 1}")


def test_ctrl_c_stops_with_a_resume_hint_and_the_resume_is_exact(fmu_path, clean, tmp_path):
    src, out, cp = tmp_path / "g.csv", tmp_path / "o.csv", tmp_path / "cp.json"
    src.write_text("".join(CLEAN.splitlines(keepends=True)[:201]))
    p = subprocess.Popen(
        TWIN
        + [str(src), "--follow", "--out", str(out), "--checkpoint", str(cp)]
        + ["--fmu", fmu_path],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    try:
        deadline = time.monotonic() + 60
        while not out.exists() or out.stat().st_size < 1000:
            assert time.monotonic() < deadline and p.poll() is None, p.stderr.read()
            time.sleep(0.05)
        time.sleep(0.3)
        p.send_signal(signal.SIGINT)
        assert p.wait(timeout=60) == 130
    finally:
        if p.poll() is None:
            p.kill()
            p.wait(timeout=10)
    line = refused(subprocess.CompletedProcess(p.args, 130, b"", p.stderr.read()), "resume with")
    assert "stopped after line 201" in line and f"--resume {cp}" in line
    src.write_text(CLEAN)  # the rest arrives; the run goes on from the checkpoint
    p = twin([src, "--out", out, "--resume", cp], fmu_path)
    accepted(p, out, clean[1])


def test_idle_limit_bounds_the_wait_on_standard_input(fmu_path, tmp_path):
    """A producer that sends a few lines and then nothing, keeping the pipe open."""
    p = subprocess.Popen(
        TWIN + ["-", "--out", str(tmp_path / "o.csv"), "--idle-limit", "1", "--fmu", fmu_path],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    try:
        p.stdin.write("".join(CLEAN.splitlines(keepends=True)[:50]).encode())
        p.stdin.flush()
        t0 = time.monotonic()
        assert p.wait(timeout=60) == 1
        assert time.monotonic() - t0 < 30
    finally:
        if p.poll() is None:
            p.kill()
            p.wait(timeout=10)
        p.stdin.close()
    refused(subprocess.CompletedProcess(p.args, 1, b"", p.stderr.read()), "no new input for 1 s")


@pytest.mark.parametrize(
    "rows,needle",
    [
        ("0,1e300\n0.001,1e300\n0.002,1e300\n", "line 2: crank_angle = 1e+300 rad is beyond"),
        ("1e300,0\n2e300,0\n", "line 2: time = 1e+300 s is beyond"),
        ("0,0\n1e-300,0\n2e-300,0\n3e-300,0\n", "line 2: the speed and acceleration at t = 0.0 s"),
    ],
)
def test_numbers_a_double_cannot_resolve_are_refused_without_a_hang(
    fmu_path, tmp_path, rows, needle
):
    src = tmp_path / "x.csv"
    src.write_text("time,crank_angle\n" + rows)
    refused(twin([src, "--out", tmp_path / "o.csv"], fmu_path, timeout=60), needle)


def test_unix_timestamps_give_the_clean_result_shifted(fmu_path, tmp_path):
    """Time as a plant logs it (seconds since 1970) is within the limits."""
    rows = clean_rows(100)
    for r in rows:
        r[0] = repr(1.764e9 + float(r[0]))
    src = tmp_path / "epoch.csv"
    src.write_text(csv_text(rows))
    p = twin([src, "--out", tmp_path / "o.csv"], fmu_path)
    assert p.returncode == 0, p.stderr


# ---- issue 24 item 4: the options follow the machine ------------------------------------------


def test_kvo630_runs_at_its_design_speed_with_default_options(fmu_path, tmp_path):
    w = 2 * math.pi * 1500 / 60
    t = np.arange(1001) / 1000.0
    src = tmp_path / "kvo.csv"
    src.write_text(
        "time,crank_angle\n"
        + "".join(f"{a!r},{math.fmod(w * a, 2 * math.pi)!r}\n" for a in t.tolist())
    )
    out = tmp_path / "o.csv"
    p = twin([src, "--machine", "kvo630", "--out", out], fmu_path)
    assert p.returncode == 0, p.stderr
    head = summary_of(out).read_text().splitlines()
    assert len(head) > 20
    speeds = [float(x.split(",")[2]) for x in head[1:]]
    assert np.allclose(speeds, w, rtol=1e-9)


# ---- the generated cases ----------------------------------------------------------------------

#: Independent of the twin's reader: what a CSV number is (docs/twin.md "Input").
NUMBER = r"\s*[-+]?([0-9]+\.?[0-9]*|\.[0-9]+)([eE][-+]?[0-9]+)?\s*"

GENERATED = settings(
    # RD_HOSTILE_EXAMPLES=50 for a deeper search than the test suite's.
    max_examples=int(os.environ.get("RD_HOSTILE_EXAMPLES", "8")),
    deadline=None,
    derandomize=True,
    database=None,  # derandomized: nothing to replay, nothing to write in the checkout
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)
#: Cases per generated example, run as concurrent processes (most of a run is start-up).
BATCH = 3


def twin_all(arg_lists, fmu_path):
    """Runs scripts/twin.py once per argument list, concurrently; each bounded by TIMEOUT."""
    procs = [
        subprocess.Popen(
            TWIN + [str(a) for a in args] + ["--fmu", fmu_path],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
        )
        for args in arg_lists
    ]
    done = []
    try:
        for p in procs:
            out, err = p.communicate(timeout=TIMEOUT)
            done.append(subprocess.CompletedProcess(p.args, p.returncode, out, err))
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
                p.wait(timeout=10)
    return done


def numberlike(s: str) -> bool:
    return re.fullmatch(NUMBER, s) is not None


#: Fields that are not numbers: the findings' and what a spreadsheet or a PLC writes, and any
#: text at all (without a line break, which would change the line numbers).
NOT_NUMBERS = st.one_of(
    st.sampled_from(
        [
            "",
            " ",
            "1_0",
            "0x10",
            "1e",
            "--1",
            "1..2",
            "١٢",
            "１",
            "nan",
            "-inf",
            "Infinity",
            "1e400",
            "NULL",
            "#N/A",
            "1 2",
            "1,5",
            '"1"',
            "\x00",
            "\ufffd",
        ]
    ),
    st.text(
        alphabet=st.characters(blacklist_categories=("Cs",), blacklist_characters="\n\r"),
        max_size=6,
    ),
).filter(lambda s: not numberlike(s) or not math.isfinite(float(s)))


def _fresh(tmp_path_factory, name="case"):
    return tmp_path_factory.mktemp(name)


@GENERATED
@given(
    st.lists(
        st.tuples(st.integers(0, N - 1), st.integers(0, 1), NOT_NUMBERS),
        min_size=BATCH,
        max_size=BATCH,
    )
)
def test_generated_bad_fields(fmu_path, clean, tmp_path_factory, cases):
    d = _fresh(tmp_path_factory)
    args = []
    for j, (row, col, value) in enumerate(cases):
        rows = clean_rows()
        rows[row][col] = value
        src = d / f"bad{j}.csv"
        src.write_bytes(csv_text(rows).encode("utf-8", "surrogatepass"))
        args.append([src, "--out", d / f"o{j}.csv"])
    for j, (p, (row, _, _)) in enumerate(zip(twin_all(args, fmu_path), cases)):
        refused(p, f"bad{j}.csv: line {row + 2}:")
        prefix_of_clean(d / f"o{j}.csv", clean[1])


LINE_DAMAGE = st.sampled_from(["drop-field", "extra-field", "text", "bad-utf8", "nul", "both"])


@GENERATED
@given(
    st.lists(
        st.tuples(st.integers(0, N - 1), LINE_DAMAGE, st.text(max_size=5)),
        min_size=BATCH,
        max_size=BATCH,
    )
)
def test_generated_bad_lines(fmu_path, clean, tmp_path_factory, cases):
    d = _fresh(tmp_path_factory)
    args = []
    for j, (row, kind, text) in enumerate(cases):
        lines = CLEAN.encode().split(b"\n")
        line = lines[row + 1]
        if kind == "drop-field":
            line = line.split(b",")[0]
        elif kind == "extra-field":
            line = line + b"," + (text.replace("\n", "").replace("\r", "") or "0").encode()
        elif kind == "text":
            line = b"x" + text.replace("\n", "").replace("\r", "").encode("utf-8", "replace")
        elif kind == "bad-utf8":
            line = line[:3] + b"\xff\xc3(" + line[3:]
        elif kind == "nul":
            line = line[:2] + b"\x00" + line[2:]
        else:
            line = line + b"," + line
        lines[row + 1] = line
        src = d / f"bad{j}.csv"
        src.write_bytes(b"\n".join(lines))
        args.append([src, "--out", d / f"o{j}.csv"])
    for j, (p, (row, _, _)) in enumerate(zip(twin_all(args, fmu_path), cases)):
        refused(p, f"bad{j}.csv: line {row + 2}:")
        prefix_of_clean(d / f"o{j}.csv", clean[1])


def _variant(rows, header, options: set, rng_text: str) -> bytes:
    """The clean data written another way a plant might (every form accepted, same numbers)."""
    header, rows = list(header), [list(r) for r in rows]
    if "extra-column" in options:
        header.insert(1, "note")
        for r in rows:
            r.insert(1, rng_text.replace(",", " ").replace(";", " "))
    if "spaces" in options:
        rows = [[f" {v}  " for v in r] for r in rows]
    if "quoted" in options:
        header = [f'"{h}"' for h in header]
    sep = ";" if "semicolon" in options else ","
    if sep == ";":
        rows = [[v.replace(".", ",") for v in r] for r in rows]
    text = sep.join(header) + "\n" + "".join(sep.join(r) + "\n" for r in rows)
    if "blank-lines" in options:
        text = text.replace("\n", "\n\n", 7)
    if "eof" in options:
        text += "EOF\n"
    if "crlf" in options:
        text = text.replace("\n", "\r\n")
    data = text.encode("latin-1" if "latin-1" in options else "utf-8", "replace")
    if "bom" in options:
        data = b"\xef\xbb\xbf" + data
    return data


VARIANTS = st.sets(
    st.sampled_from(
        [
            "extra-column",
            "spaces",
            "quoted",
            "semicolon",
            "blank-lines",
            "eof",
            "crlf",
            "latin-1",
            "bom",
        ]
    ),
    min_size=1,
)


@GENERATED
@given(
    st.lists(
        st.tuples(VARIANTS, st.text(alphabet="abcé ü€\t", max_size=6)),
        min_size=BATCH,
        max_size=BATCH,
    )
)
def test_generated_accepted_forms_give_the_clean_result(fmu_path, clean, tmp_path_factory, cases):
    d = _fresh(tmp_path_factory)
    args = []
    for j, (options, text) in enumerate(cases):
        src = d / f"v{j}.csv"
        src.write_bytes(_variant(clean_rows(), ("time", "crank_angle"), options, text))
        args.append([src, "--out", d / f"o{j}.csv"])
    for j, p in enumerate(twin_all(args, fmu_path)):
        accepted(p, d / f"o{j}.csv", clean[1])


HEADER_DAMAGE = st.sampled_from(
    ["drop-time", "drop-angle", "duplicate", "rename", "utf-16", "utf-32", "empty-name-twice"]
)


@GENERATED
@given(
    st.lists(
        st.tuples(HEADER_DAMAGE, st.sampled_from(["time", "crank_angle"])),
        min_size=BATCH,
        max_size=BATCH,
    )
)
def test_generated_bad_headers(fmu_path, tmp_path_factory, cases):
    d = _fresh(tmp_path_factory)
    args = []
    for j, (kind, name) in enumerate(cases):
        header, encoding = ["time", "crank_angle"], "utf-8"
        rows = clean_rows(50)
        if kind == "drop-time":
            header[0] = "tim"
        elif kind == "drop-angle":
            header[1] = "crank angle"
        elif kind == "duplicate":
            header.append(name)
            rows = [r + ["0"] for r in rows]
        elif kind == "rename":
            header[header.index(name)] = name.upper()
        elif kind == "empty-name-twice":
            header = [header[0], "", "", header[1]]
            rows = [[r[0], "", "", r[1]] for r in rows]
        else:
            encoding = kind
        src = d / f"h{j}.csv"
        src.write_bytes(csv_text(rows, header).encode(encoding))
        args.append([src, "--out", d / f"o{j}.csv"])
    for j, (p, (kind, _)) in enumerate(zip(twin_all(args, fmu_path), cases)):
        if kind == "empty-name-twice":  # unnamed columns are ignored like any extra column
            assert p.returncode == 0, p.stderr
        else:
            refused(p, f"h{j}.csv: line 1: the header")


@pytest.fixture(scope="module")
def checkpointed(fmu_path, clean, tmp_path_factory):
    """A run of the clean input stopped at line 150: its outputs and checkpoint."""
    d = tmp_path_factory.mktemp("checkpointed")
    out, cp = d / "p.csv", d / "cp.json"
    p = twin([clean[0], "--out", out, "--checkpoint", cp, "--stop-after", 150], fmu_path)
    assert p.returncode == 0, p.stderr
    return out.read_bytes(), summary_of(out).read_bytes(), cp.read_bytes()


def _nested(values):
    return st.one_of(
        st.lists(values, max_size=3), st.dictionaries(st.text(max_size=3), values, max_size=3)
    )


JSON_VALUES = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=5),
    _nested,
    max_leaves=5,
)


def _same_json(a: bytes, b: bytes) -> bool:
    try:
        return json.loads(a) == json.loads(b)
    except (ValueError, UnicodeDecodeError):
        return False


@GENERATED
@given(
    st.lists(
        st.one_of(
            st.tuples(st.just("truncate"), st.floats(0, 1, exclude_max=True), st.just(0)),
            st.tuples(st.just("flip"), st.floats(0, 1, exclude_max=True), st.integers(0, 7)),
            st.tuples(st.just("edit"), st.integers(0, 40), JSON_VALUES),
            st.tuples(st.just("drop"), st.integers(0, 40), st.just(0)),
        ),
        min_size=BATCH,
        max_size=BATCH,
    )
)
def test_generated_damaged_checkpoints(fmu_path, clean, checkpointed, tmp_path_factory, cases):
    d = _fresh(tmp_path_factory)
    out_bytes, summary_bytes, cp_bytes = checkpointed
    args, changed = [], []
    for j, (kind, where, what) in enumerate(cases):
        cp = d / f"cp{j}.json"
        data = cp_bytes
        if kind == "truncate":
            data = data[: int(where * len(data))]
        elif kind == "flip":
            k = int(where * len(data))
            data = data[:k] + bytes([data[k] ^ (1 << what)]) + data[k + 1 :]
        else:
            doc = json.loads(data)
            key = sorted(doc)[where % len(doc)]
            if kind == "edit":
                doc[key] = what
            else:
                del doc[key]
            data = json.dumps(doc).encode()
        cp.write_bytes(data)
        # A flipped last digit of a float can name the same double ("...436" and "...437"):
        # the checkpoint's content, and its checksum, are then unchanged, and it is used.
        changed.append(not _same_json(data, cp_bytes))
        out = d / f"p{j}.csv"
        out.write_bytes(out_bytes)
        summary_of(out).write_bytes(summary_bytes)
        args.append([clean[0], "--out", out, "--resume", cp])
    for j, (p, was_changed) in enumerate(zip(twin_all(args, fmu_path), changed)):
        out = d / f"p{j}.csv"
        if was_changed:
            refused(p, f"cp{j}.json")
            assert out.read_bytes() == out_bytes
            assert summary_of(out).read_bytes() == summary_bytes
        else:
            accepted(p, out, clean[1])


EXTREME = st.one_of(
    st.floats(allow_nan=False, allow_infinity=False),
    st.sampled_from([0.0, -0.0, 1e-300, 5e-324, 1e300, -1e300, 1e10, 1.764e9, 2**53, 1e-9]),
)


@GENERATED
@given(
    st.lists(
        st.tuples(st.integers(0, 3), st.integers(0, 3), EXTREME),
        min_size=BATCH,
        max_size=BATCH,
    )
)
def test_generated_extreme_numbers(fmu_path, tmp_path_factory, cases):
    """Numbers that are numbers but not sane (1e300 s, 5e-324 rad, a force of -1e300 N) in a
    sample of the first rows of a speed and force file: exit 0, or one line naming the line;
    never a traceback or a hang (the finding: 1e300 rad looped in the revolution count)."""
    d = _fresh(tmp_path_factory)
    args = []
    for j, (row, col, value) in enumerate(cases):
        rows = clean_rows(60, speed=True, force=True)
        rows[row][col] = repr(value)
        src = d / f"x{j}.csv"
        src.write_text(csv_text(rows, ("time", "crank_angle", "crank_speed", "process_force")))
        args.append([src, "--out", d / f"o{j}.csv"])
    for j, p in enumerate(twin_all(args, fmu_path)):
        if p.returncode != 0:
            refused(p, f"x{j}.csv")
        else:
            assert b"Traceback" not in p.stderr


NUMERIC = [
    "--window",
    "--gap-limit",
    "--max-speed",
    "--counts-per-rev",
    "--speed-tolerance",
    "--idle-limit",
]
COUNTS = ["--stop-after", "--checkpoint-every"]
CHOICES = {
    "--angle-unit": ("rad", "deg", "counts"),
    "--speed-unit": ("rad/s", "rpm"),
    "--duplicates": ("drop", "error"),
    "--separator": ("auto", ",", ";"),
    "--speed-check": ("refuse", "warn"),
}
OPTION_TEXT = st.one_of(
    st.floats().map(repr),
    st.integers(-(10**20), 10**20).map(str),
    st.sampled_from(["nan", "inf", "-0", "0", "1e-320", "1_0", "", " 1", "0x5", "rpm", "rad"]),
    st.text(
        alphabet=st.characters(blacklist_categories=("Cs",), blacklist_characters="\x00"),
        max_size=5,
    ),
)


def _option_valid(flag: str, value: str) -> bool:
    """The oracle, from docs/twin.md's option table, not from the code under test."""
    if flag in CHOICES:
        return value in CHOICES[flag]
    if flag in COUNTS:
        return re.fullmatch(r"\s*[+-]?[0-9]+\s*", value) is not None and int(value) >= 1
    try:
        v = float(value)
    except ValueError:
        return False
    return math.isfinite(v) and v > 0


@GENERATED
@given(
    st.lists(
        st.tuples(st.sampled_from(NUMERIC + COUNTS + sorted(CHOICES)), OPTION_TEXT),
        min_size=BATCH,
        max_size=BATCH,
    )
)
def test_generated_options(fmu_path, clean, tmp_path_factory, cases):
    d = _fresh(tmp_path_factory)
    args = [
        [clean[0], "--out", d / f"o{j}.csv", f"{flag}={value}"]
        for j, (flag, value) in enumerate(cases)
    ]
    for j, (p, (flag, value)) in enumerate(zip(twin_all(args, fmu_path), cases)):
        err = p.stderr.decode("utf-8", "replace")
        assert "Traceback" not in err and "internal error" not in err, err
        if not _option_valid(flag, value):
            refused(p, flag, code=2)
        elif flag in (
            "--checkpoint-every",
            "--idle-limit",
            "--speed-tolerance",
            "--duplicates",
            "--separator",
            "--speed-check",
        ) and not (flag == "--separator" and value == ";"):
            # Options that do not change the numbers of this input.
            accepted(p, d / f"o{j}.csv", clean[1])
        elif p.returncode != 0:
            refused(p)
