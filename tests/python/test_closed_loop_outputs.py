"""What `rdrive closed-loop` writes (docs/closed-loop.md "Outputs"): closed_loop.csv with the same
columns for every importer, closed_loop.json with the mean crank speed over the last whole
revolutions, both SSPs in --out-dir (never into the FMUs' folder), and for the Model Exchange run
the names of what really ran (ClosedLoopME.ssp, a variable step).

Independent references: the mean speed is recomputed here from the CSV's speed column (the
trapezoidal integral of ω between the sample times nearest the revolution crossings, divided by
their distance) where the command uses the angle column (2π·k over the crossing times); the
importers are compared with each other; docs/closed-loop.md's "runs at N strokes/min" is read
from the page and compared with a 10 s run of the shipped system.
"""

from __future__ import annotations

import csv
import json
import math
import pathlib
import re
import subprocess
import sys

import numpy as np
import pytest
from conftest import ROOT

SCRIPT = ROOT / "scripts" / "closed_loop.py"
IMPORTERS = ("libcosim", "fmpy", "model-exchange")


def run(out: pathlib.Path, fmu_dir, *args, timeout=300) -> subprocess.CompletedProcess:
    p = subprocess.run(
        [sys.executable, str(SCRIPT), "--out-dir", str(out), *map(str, args)]
        + ([] if fmu_dir is None else ["--fmu-dir", str(fmu_dir)]),
        capture_output=True,
        text=True,
        timeout=timeout,
    )
    assert p.returncode == 0, p.stderr
    return p


def read_csv(path: pathlib.Path) -> tuple[list[str], np.ndarray]:
    with open(path) as f:
        rows = list(csv.reader(f))
    return rows[0], np.array(rows[1:], dtype=float)


def mean_speed_from_omega(t, theta, omega, k) -> float:
    """The time average of ω over the last k whole revolutions, from the ω column."""
    rev = np.floor(theta / (2 * math.pi))
    starts = np.flatnonzero(np.diff(rev) > 0) + 1  # first sample of each new revolution
    a, b = starts[-1 - k], starts[-1]
    return float(np.trapezoid(omega[a : b + 1], t[a : b + 1]) / (t[b] - t[a]))


@pytest.fixture(scope="module")
def runs(fmu_path, tmp_path_factory):
    fmu_dir = pathlib.Path(fmu_path).parent
    out = {}
    for imp in IMPORTERS:
        d = tmp_path_factory.mktemp(imp)
        p = run(d, fmu_dir, "--importer", imp, "--time", 4)
        out[imp] = (d, p.stdout)
    return out


def test_every_importer_writes_the_same_columns(runs):
    heads = {}
    for imp, (d, _) in runs.items():
        head, data = read_csv(d / "closed_loop.csv")
        heads[imp] = head
        assert head[0] == "time [s]" and "drivetrain.crank.speed [rad/s]" in head
        assert "pump.crank.torque [N.m]" in head
        # One row per communication point t_k = k·h, h = 1 ms, k = 1 .. 4000.
        assert data.shape == (4000, len(head))
        assert np.allclose(data[:, 0], np.arange(1, 4001) * 1e-3, rtol=0, atol=1e-12)
        assert np.isfinite(data).all()
    assert heads["libcosim"] == heads["fmpy"] == heads["model-exchange"]
    # The importers agree: fmpy and libcosim but for the first step (docs/closed-loop.md),
    # Model Exchange within the co-simulation's one-step delay.
    w = {imp: read_csv(d / "closed_loop.csv")[1][:, 1] for imp, (d, _) in runs.items()}
    scale = w["libcosim"].mean()
    assert np.abs(w["fmpy"][10:] - w["libcosim"][10:]).max() < 1e-4 * scale
    assert np.abs(w["model-exchange"] - w["libcosim"]).max() < 1e-3 * scale


@pytest.mark.parametrize("imp", IMPORTERS)
def test_summary_holds_the_mean_speed_over_the_last_revolutions(runs, imp):
    d, stdout = runs[imp]
    s = json.loads((d / "closed_loop.json").read_text())
    head, data = read_csv(d / "closed_loop.csv")
    t, w, theta = data[:, 0], data[:, 1], data[:, 2]
    k = s["mean_over_revolutions"]
    assert k == 3 and s["revolutions"] >= 3
    ref = mean_speed_from_omega(t, theta, w, k)
    # Sample-bounded interval vs the crossings: ω swings by δ ≈ 3 %, over 1 ms of 2.8 s.
    assert abs(s["mean_speed"] - ref) < 2e-5 * ref, (s["mean_speed"], ref)
    assert s["strokes_per_minute"] == pytest.approx(s["mean_speed"] * 60 / (2 * math.pi))
    # The instantaneous speed at the end is not the mean (that was the old printed figure).
    assert s["speed_at_end"] == w[-1]
    line = f"mean crank speed over the last 3 revolution(s): {s['mean_speed']:.5g} rad/s"
    assert line in stdout


def test_the_model_exchange_run_names_what_ran(runs):
    d, stdout = runs["model-exchange"]
    s = json.loads((d / "closed_loop.json").read_text())
    assert s["system"] == "ClosedLoopME.ssp" and s["variable_step"] is True
    first = stdout.split("\n")[0]
    assert first.startswith("model-exchange: ClosedLoopME.ssp, 4 s (one ODE, DOP853 with variable")
    assert "h = " not in stdout
    d, stdout = runs["libcosim"]
    assert stdout.startswith("libcosim: ClosedLoop.ssp, 4 s (h = 0.001 s)")


def test_out_dir_holds_the_ssps_and_the_fmu_folder_is_untouched(fmu_path, tmp_path):
    fmu_dir = pathlib.Path(fmu_path).parent
    before = {p.name: p.stat().st_mtime_ns for p in fmu_dir.iterdir()}
    # The default --fmu-dir (the checkout's target/fmu), as a user runs it.
    run(tmp_path / "o", None, "--importer", "fmpy", "--time", 1)
    for name in ("ClosedLoop.ssp", "ClosedLoopME.ssp", "closed_loop.csv", "closed_loop.json"):
        assert (tmp_path / "o" / name).is_file(), name
    default_dir = ROOT / "target" / "fmu"
    if default_dir.resolve() == fmu_dir.resolve():
        after = {p.name: p.stat().st_mtime_ns for p in fmu_dir.iterdir()}
        assert after == before


def test_the_docs_speed_is_the_mean_of_a_run(fmu_path, tmp_path):
    """docs/closed-loop.md states the shipped system's speed: the mean over the last three
    revolutions of the command's default run (10 s, libcosim), to its printed digits."""
    text = (ROOT / "docs" / "closed-loop.md").read_text()
    m = re.search(r"runs at\s+([\d.]+)\s+strokes/min \(the mean", text)
    assert m, "docs/closed-loop.md states the shipped system's speed"
    run(tmp_path, pathlib.Path(fmu_path).parent)
    s = json.loads((tmp_path / "closed_loop.json").read_text())
    digits = len(m.group(1).split(".")[1])
    assert f"{s['strokes_per_minute']:.{digits}f}" == m.group(1)
