"""python/reciprocating_drive/fmu/instance.py: FMU errors carry the FMU's message, a restart gives the same
run, serialized states continue bit for bit, and the fast channel equals the by-name path."""

from __future__ import annotations

import math

import numpy as np
import pytest
from reciprocating_drive import Fmu, FmuError

W = 2 * math.pi * 65 / 60
INS = ["crank.angle", "crank.speed", "crank.acceleration"]
OUTS = ["suspension.position", "suspension.acceleration", "guide.friction", "crank.torque"]


def run(fmu, n, h=1e-3):
    ch = fmu.channel(INS, OUTS)
    rows = np.empty((n, len(OUTS)))
    for k in range(n):
        ch.step(fmu.time + h, [W * fmu.time, W, 0.0], rows[k])
    return rows


def test_error_names_variable_value_and_range(fmu_path):
    with Fmu(fmu_path) as f:
        with pytest.raises(FmuError) as e:
            f.start({"geometry.crank_radius": -0.2})
        assert e.value.function == "fmi2ExitInitializationMode"
        assert "geometry.crank_radius" in str(e.value) and "-0.2" in str(e.value)


def test_restart_and_serialized_state_continue_bit_for_bit(fmu_path):
    with Fmu(fmu_path) as f:
        f.start({"crank.speed": W})
        first = run(f, 50)
        data, t_saved = f.serialize(), f.time
        tail = run(f, 50)
        f.start({"crank.speed": W})  # fmi2Reset and a second initialization
        assert np.array_equal(run(f, 50), first)
        f.restore(data, t_saved)
        assert np.array_equal(run(f, 50), tail)


def test_channel_equals_get_by_name(fmu_path):
    with Fmu(fmu_path) as f:
        f.start({"crank.speed": W})
        rows = run(f, 7)
        assert list(rows[-1]) == f.get(OUTS)


def test_the_extracted_fmu_is_removed_without_close(fmu_path, tmp_path):
    """An Fmu kept for a process's life (a Dask worker's, a command's) is never closed: its
    extracted copy in the temporary folder goes when the process exits normally, and one that is
    closed or collected goes at once."""
    import os
    import subprocess
    import sys

    script = (
        "import gc, os, sys\n"
        "from reciprocating_drive import Fmu\n"
        "kept = Fmu(sys.argv[1]); kept.start({})\n"
        "Fmu(sys.argv[1]).close()\n"
        "Fmu(sys.argv[1]); gc.collect()\n"
        "print(len(os.listdir(os.environ['TMPDIR'])))\n"
    )
    env = dict(os.environ, TMPDIR=str(tmp_path))
    p = subprocess.run(
        [sys.executable, "-c", script, fmu_path],
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert p.returncode == 0, p.stderr
    assert p.stdout.split() == ["1"]  # only the kept instance's copy while the process runs
    assert os.listdir(tmp_path) == []  # and none once it has exited
