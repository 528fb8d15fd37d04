"""The digital twin (docs/twin.md) through its command line, against a truth independent of its
code: the crank motion of python/reciprocating_drive/twin/sample.py in closed form and the
crank-slider's acceleration a = TF·ε + TF′·ω² in closed form (docs/model.md §3.1).

* exact, noise-free wrapped angles at 1 kHz, no speed channel: the suspension acceleration within
  1e-4 of its peak;
* the shipped encoder data (4096 counts/rev, jitter, a gap): within 1 % of its peak away from the
  gap (and the smoothing window around it);
* every bad-data case stops with its message and line number;
* an FMU that fails in the middle of a chunk: the samples before the failing one are written,
  equal to a run where nothing fails, and the message names the failing line;
* live mode (standard input, each line flushed) and replay give identical files;
* a run stopped with a checkpoint and resumed gives files identical to an uninterrupted run.
"""

from __future__ import annotations

import csv
import math
import subprocess
import sys

import numpy as np
import pytest
from conftest import ROOT
from reciprocating_drive.twin.sample import crank_slider_acceleration, truth

TWIN = [sys.executable, str(ROOT / "scripts" / "twin.py")]
SAMPLE = ROOT / "data" / "twin" / "pump_encoder.csv"
ENCODER = ["--angle-unit", "counts", "--counts-per-rev", "4096"]


def run(args, fmu_path, stdin=None, check=True):
    p = subprocess.run(
        TWIN + list(map(str, args)) + ["--fmu", fmu_path],
        input=stdin,
        capture_output=True,
        text=True,
        timeout=300,
    )
    if check:
        assert p.returncode == 0, p.stderr
    return p


def read(path):
    """name -> column of a CSV the twin wrote (headers `name [unit]`: the unit is dropped; an
    empty cell is NaN)."""
    with open(path) as f:
        rows = list(csv.reader(f))
    head = [h.rpartition(" [")[0] or h for h in rows[0]]
    return {
        h: np.array([float(r[i]) if r[i] else math.nan for r in rows[1:]])
        for i, h in enumerate(head)
    }


def test_exact_angles_give_the_exact_acceleration(fmu_path, tmp_path):
    t = np.arange(3001) / 1000.0
    theta, _, _ = truth(t)
    src = tmp_path / "exact.csv"
    src.write_text(
        "time,crank_angle\n"
        + "".join(f"{float(a)!r},{float(b)!r}\n" for a, b in zip(t, np.mod(theta, 2 * math.pi)))
    )
    # Noise-free data wants a short window (docs/twin.md: the cubic's bias grows with the window
    # squared; 6 ms gives 3.5e-5 of the peak here, the default 0.1 s, made for encoders, 8e-3).
    run([src, "--out", tmp_path / "o.csv", "--window", "0.006"], fmu_path)
    o = read(tmp_path / "o.csv")
    th, w, e = truth(o["time"])
    exact = crank_slider_acceleration(th, w, e)
    err = np.max(np.abs(o["suspension.acceleration"] - exact)) / np.max(np.abs(exact))
    assert err <= 1e-4, err


def test_encoder_data_within_one_percent_away_from_the_gap(fmu_path, tmp_path):
    p = run(
        [SAMPLE, *ENCODER, "--out", tmp_path / "o.csv", "--plots", tmp_path / "plots"], fmu_path
    )
    assert "gap of 0.201" in p.stderr and "re-initialized" in p.stderr
    o = read(tmp_path / "o.csv")
    th, w, e = truth(o["time"])
    exact = crank_slider_acceleration(th, w, e)
    away = (
        (np.abs(o["time"] - 6.1) > 0.1 + 0.1)
        & (o["time"] > 0.1)
        & (o["time"] < o["time"][-1] - 0.1)
    )
    err = np.max(np.abs(o["suspension.acceleration"][away] - exact[away])) / np.max(np.abs(exact))
    assert err <= 0.01, err
    # Per-revolution summary: mean speed of the truth (ω0 on average) and its fluctuation (±3 %).
    s = read(tmp_path / "o-revolutions.csv")
    assert len(s["revolution"]) >= 9
    assert np.allclose(s["mean_speed"], 2 * math.pi * 65 / 60, rtol=2e-3)
    assert np.allclose(s["speed_fluctuation"], 0.06, rtol=0.05)
    for name in ("timeseries.png", "card.png", "revolutions.png"):
        assert (tmp_path / "plots" / name).read_bytes()[:4] == b"\x89PNG"


@pytest.mark.parametrize(
    "text,args,message",
    [
        ("time,crank_angle\n0,0\n0.001,abc\n", [], "line 3: crank_angle = 'abc' is not a number"),
        (
            "time,crank_angle\n0,0\n0.002,0.01\n0.001,0.02\n",
            [],
            "line 4: time 0.001 s goes backwards",
        ),
        (
            "time,crank_angle\n0,0\n0.001,0.01\n0.001,0.01\n",
            ["--duplicates", "error"],
            "line 4: duplicate timestamp",
        ),
        ("time,crank_angle\n0,0\n0.001,0.01\n0.002,1.5\n", [], "line 4: the crank angle moves"),
        ("t,angle\n0,0\n", [], "line 1: the header must name 'time'"),
        (
            "time,crank_angle,crank_speed\n0,0,1\n0.001,0.01,inf\n",
            [],
            "line 3: crank_speed = 'inf' is not a finite number",
        ),
    ],
)
def test_bad_data_is_refused_with_its_line(fmu_path, tmp_path, text, args, message):
    src = tmp_path / "bad.csv"
    src.write_text(text)
    p = run([src, "--out", tmp_path / "o.csv", *args], fmu_path, check=False)
    assert p.returncode != 0 and message in p.stderr, p.stderr


def test_fmu_failure_keeps_the_samples_before_it(fmu_path, tmp_path):
    """kvo630 whose process force jumps to 1e5 N at sample 2000 (line 2002): the elastic rod
    buckles there. All 2000 samples before it are in one input block with it; their rows and the
    summaries of the revolutions they complete must equal those of the same data without the
    jump, and the message must name the line."""
    w = 2 * math.pi * 1500 / 60
    t = np.arange(3001) / 1000.0
    angle = np.mod(w * t, 2 * math.pi)
    common = ["--machine", "kvo630", "--window", "0.006", "--max-speed", "400"]
    outs = {}
    for name, jump in (("calm", 0.0), ("buckled", 1e5)):
        src = tmp_path / f"{name}.csv"
        src.write_text(
            "time,crank_angle,process_force\n"
            + "".join(
                f"{float(a)!r},{float(b)!r},{(jump if k >= 2000 else 0.0)!r}\n"
                for k, (a, b) in enumerate(zip(t, angle))
            )
        )
        outs[name] = run(
            [src, *common, "--out", tmp_path / f"{name}-out.csv"], fmu_path, check=jump == 0.0
        )
    p = outs["buckled"]
    assert p.returncode == 1 and "line 2002 (t = 2.0 s)" in p.stderr and "buckled" in p.stderr, (
        p.stderr
    )
    calm = (tmp_path / "calm-out.csv").read_text().splitlines()
    buckled = (tmp_path / "buckled-out.csv").read_text().splitlines()
    assert len(buckled) == 1 + 2000 and buckled == calm[: len(buckled)]
    calm_s = (tmp_path / "calm-out-revolutions.csv").read_text().splitlines()
    buckled_s = (tmp_path / "buckled-out-revolutions.csv").read_text().splitlines()
    assert len(buckled_s) > 40 and buckled_s == calm_s[: len(buckled_s)]


def test_duplicates_are_dropped_and_counted(fmu_path, tmp_path):
    t = np.arange(200) / 1000.0
    theta, _, _ = truth(t)
    lines = [f"{float(a)!r},{float(b)!r}\n" for a, b in zip(t, theta)]
    lines.insert(50, lines[49])
    src = tmp_path / "dup.csv"
    src.write_text("time,crank_angle\n" + "".join(lines))
    p = run([src, "--out", tmp_path / "o.csv"], fmu_path)
    assert "1 duplicate timestamps dropped" in p.stdout
    assert len(read(tmp_path / "o.csv")["time"]) == 200


def test_live_equals_replay(fmu_path, tmp_path):
    run([SAMPLE, *ENCODER, "--out", tmp_path / "replay.csv"], fmu_path)
    run(
        ["-", *ENCODER, "--live", "--out", tmp_path / "live.csv"],
        fmu_path,
        stdin=SAMPLE.read_text(),
    )
    assert (tmp_path / "replay.csv").read_bytes() == (tmp_path / "live.csv").read_bytes()
    assert (tmp_path / "replay-revolutions.csv").read_bytes() == (
        tmp_path / "live-revolutions.csv"
    ).read_bytes()


def test_live_in_small_pieces_equals_replay(fmu_path, tmp_path):
    """Live input arriving in pieces of random size (partial lines, single samples, bursts) gives
    the replay's files byte for byte."""
    import random
    import time

    text = "".join(SAMPLE.read_text().splitlines(keepends=True)[:1501]).encode()
    src = tmp_path / "part.csv"
    src.write_bytes(text)
    run([src, *ENCODER, "--out", tmp_path / "replay.csv"], fmu_path)
    p = subprocess.Popen(
        TWIN + ["-", *ENCODER, "--live", "--out", str(tmp_path / "live.csv"), "--fmu", fmu_path],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    rng = random.Random(5)
    pos = 0
    while pos < len(text):
        n = rng.choice([1, 7, 30, 41, 200, 3000])
        p.stdin.write(text[pos : pos + n])
        p.stdin.flush()
        pos += n
        time.sleep(rng.choice([0, 0, 0.0005, 0.002]))
    p.stdin.close()
    err = p.stderr.read().decode()
    assert p.wait(timeout=300) == 0, err
    assert (tmp_path / "replay.csv").read_bytes() == (tmp_path / "live.csv").read_bytes()
    assert (tmp_path / "replay-revolutions.csv").read_bytes() == (
        tmp_path / "live-revolutions.csv"
    ).read_bytes()


def test_checkpoint_and_resume_are_bit_identical(fmu_path, tmp_path):
    full = tmp_path / "full.csv"
    run([SAMPLE, *ENCODER, "--out", full], fmu_path)
    part = tmp_path / "part.csv"
    cp = tmp_path / "twin.checkpoint"
    # Stop in the middle of a revolution, well before the gap; then after the gap.
    run([SAMPLE, *ENCODER, "--out", part, "--checkpoint", cp, "--stop-after", 3333], fmu_path)
    run(
        [SAMPLE, *ENCODER, "--out", part, "--checkpoint", cp, "--resume", cp, "--stop-after", 7777],
        fmu_path,
    )
    run([SAMPLE, *ENCODER, "--out", part, "--resume", cp], fmu_path)
    assert part.read_bytes() == full.read_bytes()
    assert (tmp_path / "part-revolutions.csv").read_bytes() == (
        tmp_path / "full-revolutions.csv"
    ).read_bytes()


def test_summary_stroke_and_units(fmu_path, tmp_path):
    """The per-revolution stroke of the default machine (central crank-slider, r = 0.2 m) is the
    closed form 2r; every CSV header is `name [unit]` with the FMU's declared unit (read here by
    fmpy from the model description, not by the twin)."""
    from fmpy import read_model_description

    t = np.arange(3001) / 1000.0
    theta, _, _ = truth(t)
    src = tmp_path / "exact.csv"
    src.write_text(
        "time,crank_angle\n"
        + "".join(f"{float(a)!r},{float(b)!r}\n" for a, b in zip(t, np.mod(theta, 2 * math.pi)))
    )
    run([src, "--out", tmp_path / "o.csv", "--window", "0.006"], fmu_path)
    s = read(tmp_path / "o-revolutions.csv")
    assert len(s["stroke"]) >= 2
    # The peaks are refined by a parabola through 3 samples 6.8 mrad apart: error ~(Δθ)^3.
    assert np.allclose(s["stroke"], 2 * 0.2, rtol=1e-9, atol=0)
    units = {v.name: v.unit or "-" for v in read_model_description(fmu_path).modelVariables}
    head = (tmp_path / "o.csv").read_text().splitlines()[0].split(",")
    assert head[0] == "time [s]"
    assert head[1:] == [
        f"{n.rpartition(' [')[0]} [{units[n.rpartition(' [')[0]]}]" for n in head[1:]
    ]
    shead = (tmp_path / "o-revolutions.csv").read_text().splitlines()[0].split(",")
    assert "stroke [m]" in shead and "mean_speed [rad/s]" in shead and "revolution [-]" in shead


def test_plots_show_constants_as_constants_and_break_at_gaps(tmp_path):
    """No offset notation on a constant (the finding: '1e-5+3.203'); NaN breaks in the drawn
    line at a gap and at a missing revolution."""
    import matplotlib.pyplot as plt
    from reciprocating_drive.twin.plots import broken, steady_axis

    fig, ax = plt.subplots()
    y = np.full(50, 3.2037) + np.arange(50) * 1e-16
    ax.plot(y)
    steady_axis(ax, y)
    fig.canvas.draw()
    assert ax.yaxis.get_offset_text().get_text() == ""
    lo, hi = ax.get_ylim()
    assert lo < 3.2037 < hi and hi - lo >= 0.02 * 3.2037  # the y-range rule: plots.y_range
    plt.close(fig)
    x = np.array([0.0, 1.0, 2.0, 10.0, 11.0])
    bx, by = broken(x, x * 2, np.flatnonzero(np.diff(x) > 5))
    assert np.isnan(bx[3]) and np.isnan(by[3]) and len(bx) == 6


def test_plot_titles_name_the_machine_and_the_input(fmu_path, tmp_path):
    from reciprocating_drive.twin.plots import plot_twin

    run([SAMPLE, *ENCODER, "--out", tmp_path / "o.csv"], fmu_path)
    titles = plot_twin(
        tmp_path / "o.csv",
        tmp_path / "o-revolutions.csv",
        tmp_path / "plots",
        machine="default",
        source=str(SAMPLE),
    )
    assert set(titles) == {"timeseries.png", "card.png", "revolutions.png"}
    for name, title in titles.items():
        assert "default" in title and "pump_encoder.csv" in title, title
        assert (tmp_path / "plots" / name).read_bytes()[:4] == b"\x89PNG"


def test_the_public_api_resumes_exactly(fmu_path):
    """The API other sources and sinks drive (`Twin`, `feed`, `finish`, `checkpoint`,
    `from_checkpoint` through JSON): fed in chunks of odd sizes and resumed in the middle of a
    revolution, it gives the rows and summaries of one pass, bit for bit."""
    import json

    from reciprocating_drive.twin import Options, Twin

    lines = SAMPLE.read_text().splitlines()[:4001]
    opts = Options(angle_unit="counts", counts_per_rev=4096.0)

    one = Twin(fmu_path, "default", opts)
    r1, s1 = one.feed(lines, 1)
    r2, s2 = one.finish()
    ref_rows, ref_sums = np.concatenate([r1, r2]), s1 + s2

    tw = Twin(fmu_path, "default", opts)
    rows, sums, pos = [], [], 0
    for size in (1, 7, 500, 1234):
        r, s = tw.feed(lines[pos : pos + size], pos + 1)
        rows.append(r)
        sums += s
        pos += size
    cp = json.loads(json.dumps(tw.checkpoint()))
    tw = Twin.from_checkpoint(fmu_path, cp)
    r, s = tw.feed(lines[pos:], pos + 1)
    rows.append(r)
    sums += s
    r, s = tw.finish()
    rows.append(r)
    sums += s
    got = np.concatenate(rows)
    assert got.shape == ref_rows.shape and np.array_equal(got, ref_rows)
    assert sums == ref_sums and len(sums) >= 4
