"""ISO 8601 timestamps in the twin's CSV input (docs/twin.md "Timestamps").

The truth is written here without the code under test: the shipped encoder sample's times (seconds)
are turned into timestamps by datetime arithmetic on a chosen start, and for local times in
Europe/Berlin by the zone's rule written out by hand (UTC+2 until 2026-10-25 01:00 UTC, UTC+1
after it; UTC+1 until 2026-03-29 01:00 UTC, then UTC+2), not by zoneinfo. A run on the
timestamps must give, bit for bit, the rows of a run on the same instants written as seconds from
the whole UTC second of the first one.
"""

from __future__ import annotations

import datetime as dt
import sqlite3
import subprocess
import sys

import numpy as np
import plant_util as pu
import pytest
from conftest import ROOT
from reciprocating_drive.twin import DataError, Options, Twin

SAMPLE = ROOT / "data" / "twin" / "pump_encoder.csv"
ENCODER = dict(angle_unit="counts", counts_per_rev=4096)
UTC = dt.UTC
N = 2500  # samples of the sample file used (2.5 s, two revolutions and more)


def sample() -> tuple[list[int], list[str]]:
    """The sample's times in whole microseconds and its angle fields."""
    lines = SAMPLE.read_text().split("\n")[1 : N + 1]
    us = [round(float(line.split(",")[0]) * 1e6) for line in lines]
    return us, [line.split(",")[1] for line in lines]


def run_twin(fmu_path, text: str, **opts) -> tuple[np.ndarray, Twin]:
    tw = Twin(fmu_path, "default", Options(**ENCODER, **opts))
    lines = text.rstrip("\n").split("\n")
    rows, _ = tw.feed(lines, 1)
    tail, _ = tw.finish()
    return np.concatenate([rows, tail]), tw


def seconds_file(us: list[int], angles: list[str], origin_us: int) -> str:
    return "time,crank_angle\n" + "".join(
        f"{(u - origin_us) / 1e6!r},{a}\n" for u, a in zip(us, angles, strict=True)
    )


def iso_file(stamps: list[str], angles: list[str]) -> str:
    return "time,crank_angle\n" + "".join(f"{s},{a}\n" for s, a in zip(stamps, angles, strict=True))


def stamp(d: dt.datetime, suffix: str) -> str:
    return d.strftime("%Y-%m-%dT%H:%M:%S.%f") + suffix


@pytest.fixture(scope="module")
def utc_case(fmu_path):
    """Timestamps from 2026-11-28T08:00:00.123Z on, and the reference run in seconds."""
    us, angles = sample()
    start = dt.datetime(2026, 11, 28, 8, 0, 0, 123000, tzinfo=UTC)
    instants = [start + dt.timedelta(microseconds=u) for u in us]
    origin = dt.datetime(2026, 11, 28, 8, 0, 0, tzinfo=UTC)
    origin_us = round(origin.timestamp()) * 10**6
    abs_us = [origin_us + 123000 + u for u in us]
    ref, _ = run_twin(fmu_path, seconds_file(abs_us, angles, origin_us))
    return instants, angles, ref, origin.timestamp()


def test_utc_timestamps_give_the_rows_of_seconds_from_the_origin(fmu_path, utc_case):
    instants, angles, ref, origin = utc_case
    rows, tw = run_twin(fmu_path, iso_file([stamp(d, "Z") for d in instants], angles))
    assert rows.shape == ref.shape and len(rows) > 2000
    assert np.array_equal(rows, ref)  # bit for bit, the time column included
    assert rows[0, 0] == 0.123
    assert tw.time_origin == origin
    assert any("ISO 8601 timestamps" in m and "2026-11-28T08:00:00Z" in m for m in tw.messages)


def test_an_offset_gives_the_same_instants(fmu_path, utc_case):
    instants, angles, ref, origin = utc_case
    plus1 = dt.timedelta(hours=1)
    local = [stamp((d + plus1).replace(tzinfo=None), "+01:00") for d in instants]
    rows, tw = run_twin(fmu_path, iso_file(local, angles))
    assert np.array_equal(rows, ref)
    assert tw.time_origin == origin
    # A decimal comma in the seconds, with the ';' separator, reads the same.
    text = iso_file(local, angles).replace(",", ";").replace(".", ",")
    rows2, _ = run_twin(fmu_path, text)
    assert np.array_equal(rows2, ref)


def berlin_by_hand(d: dt.datetime) -> dt.datetime:
    """Europe/Berlin's local time of a UTC instant in 2026, from the EU rule (last Sundays of
    March and October at 01:00 UTC), without zoneinfo."""
    summer = dt.datetime(2026, 3, 29, 1, tzinfo=UTC) <= d < dt.datetime(2026, 10, 25, 1, tzinfo=UTC)
    return (d + dt.timedelta(hours=2 if summer else 1)).replace(tzinfo=None)


def test_local_times_across_the_end_of_summer_time(fmu_path):
    """2026-10-25: at 03:00 CEST the clocks go back to 02:00 CET; the samples span the change, so
    local times repeat (02:59:59 then 02:00:00) while the instants go on evenly."""
    us, angles = sample()
    start = dt.datetime(2026, 10, 25, 0, 59, 58, 500000, tzinfo=UTC)
    instants = [start + dt.timedelta(microseconds=u) for u in us]
    local = [stamp(berlin_by_hand(d), "") for d in instants]
    assert local[0].startswith("2026-10-25T02:59:58") and "2026-10-25T02:00:00" in local[-1][:19]
    origin_us = round(dt.datetime(2026, 10, 25, 0, 59, 58, tzinfo=UTC).timestamp()) * 10**6
    ref, _ = run_twin(
        fmu_path,
        seconds_file([origin_us + 500000 + u for u in us], angles, origin_us),
    )
    rows, tw = run_twin(fmu_path, iso_file(local, angles), timezone="Europe/Berlin")
    assert np.array_equal(rows, ref)
    assert any("repeats" in m for m in tw.messages)
    # Without the zone: refused at the first sample, naming the option.
    with pytest.raises(DataError, match=r"^line 2: time = .* no UTC offset.*--timezone"):
        run_twin(fmu_path, iso_file(local, angles))


def test_a_skipped_local_time_is_refused(fmu_path):
    """2026-03-29: the clocks go from 02:00 CET to 03:00 CEST; 02:30 does not exist in Berlin."""
    text = iso_file(
        ["2026-03-29T01:59:59.998", "2026-03-29T01:59:59.999", "2026-03-29T02:30:00.000"],
        ["0", "1", "2"],
    )
    with pytest.raises(DataError) as e:
        run_twin(fmu_path, text, timezone="Europe/Berlin")
    assert str(e.value) == (
        "line 4: time = '2026-03-29T02:30:00.000' does not exist in Europe/Berlin (the clocks "
        "skip it when daylight-saving time begins)"
    )


@pytest.mark.parametrize(
    "fields, message",
    [
        (
            ["2026-11-28T08:00:00.000Z", "2026-11-28T08:00:00.001Z", "0.002"],
            "line 4: time = '0.002' is a number, but the input's times are ISO 8601 timestamps "
            "(from line 2): one format per input",
        ),
        (
            ["0.000", "0.001", "2026-11-28T08:00:00.002Z"],
            "line 4: time = '2026-11-28T08:00:00.002Z' is an ISO 8601 timestamp, but the first "
            "sample's time is a number (seconds): one format per input",
        ),
        (
            ["2026-11-28T08:00:00.000Z", "2026-13-28T08:00:00.001Z"],
            "line 3: time = '2026-13-28T08:00:00.001Z' is not a valid timestamp (month must be "
            "in 1..12)",
        ),
        (
            ["2026-11-28T08:00:00.000Z", "2026-11-28 8:00:00Z"],
            "line 3: time = '2026-11-28 8:00:00Z' is not an ISO 8601 timestamp",
        ),
    ],
)
def test_mixed_and_invalid_timestamps_name_their_line(fmu_path, tmp_path, fields, message):
    text = iso_file(fields, [str(i) for i in range(len(fields))])
    with pytest.raises(DataError) as e:
        run_twin(fmu_path, text)
    assert str(e.value) == message
    # The command: exit 1, that one line (after the rows before it are written).
    src = tmp_path / "in.csv"
    src.write_text(text)
    p = subprocess.run(
        [sys.executable, "-m", "reciprocating_drive.cli", "twin", str(src), "--fmu", fmu_path]
        + ["--angle-unit", "counts", "--counts-per-rev", "4096", "--out", str(tmp_path / "o.csv")],
        capture_output=True,
        text=True,
        timeout=120,
        env=pu.env(),
    )
    assert p.returncode == 1, p.stderr
    assert message in p.stderr and len(p.stderr.strip().split("\n")) == 1, p.stderr


def test_an_unknown_zone_is_a_bad_option(fmu_path, tmp_path):
    src = tmp_path / "in.csv"
    src.write_text("time,crank_angle\n2026-11-28T08:00:00,0\n")
    p = subprocess.run(
        [sys.executable, "-m", "reciprocating_drive.cli", "twin", str(src), "--fmu", fmu_path]
        + ["--timezone", "Europe/Berln", "--out", str(tmp_path / "o.csv")],
        capture_output=True,
        text=True,
        timeout=120,
        env=pu.env(),
    )
    assert p.returncode == 2, p.stderr
    assert "--timezone 'Europe/Berln': not a time zone" in p.stderr
    assert len(p.stderr.strip().split("\n")) == 1, p.stderr


def test_the_plant_csv_source_keeps_the_origin(fmu_path, tmp_path, utc_case):
    """rdrive plant with a CSV source of timestamps: the database's samples are those of the
    seconds run, and the run's time origin is the first timestamp's whole second (the page's
    clock, docs/page.md, starts from it)."""
    instants, angles, ref, origin = utc_case
    src = tmp_path / "historian.csv"
    src.write_text(iso_file([stamp(d, "Z") for d in instants], angles))
    db = tmp_path / "t.sqlite"
    cfg = pu.write_config(
        tmp_path / "plant.toml",
        source=pu.csv_source(src),
        sinks=pu.sqlite_sink(db),
        fmu=fmu_path,
    )
    p = pu.run(cfg)
    assert p.returncode == 0, p.stderr
    got = pu.samples(db)
    assert np.array_equal(got[:, 1], ref[:, 0])  # (seq, t, ...)
    with sqlite3.connect(db) as c:
        (o,) = c.execute("SELECT time_origin FROM runs").fetchone()
    assert o == origin


def test_the_page_clock_starts_at_the_origin(fmu_path, tmp_path, utc_case):
    """The live page of a paced replay of timestamps gets the origin (its clock axis,
    docs/page.md), read from its state API while the run goes on."""
    import json
    import time
    import urllib.request

    from reciprocating_drive.plant.plc_sim import free_port

    instants, angles, _, origin = utc_case
    src = tmp_path / "historian.csv"
    src.write_text(iso_file([stamp(d, "Z") for d in instants], angles))
    port = free_port()
    cfg = pu.write_config(
        tmp_path / "plant.toml",
        source=pu.csv_source(src, pace=1.0),
        sinks=pu.sqlite_sink(tmp_path / "t.sqlite") + f"\n[page]\nport = {port}\n",
        fmu=fmu_path,
    )
    proc = pu.start(cfg)
    try:
        seen = None
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and proc.poll() is None:
            try:
                with urllib.request.urlopen(f"http://127.0.0.1:{port}/api/state", timeout=2) as r:
                    seen = json.load(r).get("time_origin")
            except OSError:
                pass
            if seen is not None:
                break
            time.sleep(0.1)
        assert seen == origin
    finally:
        proc.terminate()
        proc.wait(timeout=30)


def rdrive_twin(fmu_path, *args) -> subprocess.CompletedProcess:
    p = subprocess.run(
        [sys.executable, "-m", "reciprocating_drive.cli", "twin", *map(str, args)]
        + ["--fmu", fmu_path, "--angle-unit", "counts", "--counts-per-rev", "4096"],
        capture_output=True,
        text=True,
        timeout=600,
        env=pu.env(),
    )
    assert p.returncode == 0, p.stderr
    return p


@pytest.fixture(scope="module")
def berlin_file(tmp_path_factory):
    """The whole sample as Berlin local times across the 2026-10-25 change (its gap included)."""
    lines = SAMPLE.read_text().split("\n")[1:]
    lines = [line for line in lines if line.strip()]
    start = dt.datetime(2026, 10, 25, 0, 59, 55, tzinfo=UTC)
    out = ["time,crank_angle"]
    for line in lines:
        t, a = line.split(",")
        d = start + dt.timedelta(microseconds=round(float(t) * 1e6))
        out.append(f"{stamp(berlin_by_hand(d), '')},{a}")
    p = tmp_path_factory.mktemp("berlin") / "berlin.csv"
    p.write_text("\n".join(out) + "\n")
    return p


def test_checkpoint_and_resume_keep_the_clock(fmu_path, tmp_path, berlin_file):
    """Stopped and resumed twice (once inside the repeated hour): the files of an uninterrupted
    run, byte for byte (the origin and the last instant are in the checkpoint)."""
    zone = ["--timezone", "Europe/Berlin"]
    full = tmp_path / "full.csv"
    rdrive_twin(fmu_path, berlin_file, "--out", full, *zone)
    part, cp = tmp_path / "part.csv", tmp_path / "twin.checkpoint"
    rdrive_twin(
        fmu_path, berlin_file, "--out", part, "--checkpoint", cp, "--stop-after", 3333, *zone
    )
    rdrive_twin(
        fmu_path, berlin_file, "--out", part, "--checkpoint", cp, "--resume", cp,
        "--stop-after", 7777, *zone,
    )  # fmt: skip
    rdrive_twin(fmu_path, berlin_file, "--out", part, "--resume", cp, *zone)
    assert part.read_bytes() == full.read_bytes()


def test_the_distributed_replay_reads_timestamps(fmu_path, tmp_path, berlin_file):
    """--distributed on timestamps: the sequential replay's files, byte for byte."""
    zone = ["--timezone", "Europe/Berlin"]
    seq = tmp_path / "seq.csv"
    rdrive_twin(fmu_path, berlin_file, "--out", seq, *zone)
    dist = tmp_path / "dist.csv"
    rdrive_twin(
        fmu_path, berlin_file, "--out", dist, "--distributed", "--workers", 1,
        "--revolutions-per-piece", 3, "--quiet", *zone,
    )  # fmt: skip
    assert dist.read_bytes() == seq.read_bytes()
    assert (tmp_path / "dist-revolutions.csv").read_bytes() == (
        tmp_path / "seq-revolutions.csv"
    ).read_bytes()
