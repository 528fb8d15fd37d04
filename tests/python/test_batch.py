"""The native batch driver (tools/fmi2-batch, python/reciprocating_drive/fmu/batch.py) against an
independent path through the same FMU: fmpy's ctypes functions called once per sample
(`Channel.advance`, `set_inputs`, `read`, `step`). Results must be identical bit for bit, a failing
call in the middle of a batch must stop it at the right sample with the FMU's own message, and the
CSV formatter must write every number exactly as Python's repr does.
"""

from __future__ import annotations

import ctypes
import math

import numpy as np
import pytest
from reciprocating_drive.fmu import Fmu, FmuError, batch
from reciprocating_drive.presets import preset_values

INPUTS = ["crank.angle", "crank.speed", "crank.acceleration", "link.external_force"]


def crank_motion(n, w0, force=100.0, seed=0):
    """Variable communication steps (jittered 1 ms) and a crank whose speed fluctuates."""
    rng = np.random.default_rng(seed)
    t = np.cumsum(1e-3 + rng.uniform(-2e-4, 2e-4, n))
    w = w0 * (1 + 0.03 * np.sin(2 * w0 * t))
    th = w0 * t - 0.03 / 2 * (np.cos(2 * w0 * t) - 1)
    e = 0.03 * w0 * 2 * w0 * np.cos(2 * w0 * t)
    return t, np.column_stack([th, w, e, rng.normal(0, force, n)])


def started(fmu_path, machine):
    f = Fmu(fmu_path)
    values = {k: v for k, v in preset_values(machine).items() if k not in INPUTS}
    f.start(values)
    return f, f.channel(INPUTS, f.outputs)


def per_sample(ch, t, x, set_first=False):
    """The reference: three fmpy calls per sample."""
    out = np.full((len(t), len(ch.outputs)), np.nan)
    for k in range(len(t)):
        if set_first:
            ch.step(float(t[k]), x[k].tolist(), out[k])
        else:
            ch.advance(float(t[k]))
            ch.set_inputs(x[k].tolist())
            ch.read(out[k])
    return out


@pytest.mark.parametrize("machine,w0,force", [("default", 6.8, 100.0), ("kvo630", 157.0, 1.0)])
@pytest.mark.parametrize("set_first", [False, True])
def test_batch_is_bit_identical_to_per_sample_calls(fmu_path, machine, w0, force, set_first):
    t, x = crank_motion(1500, w0, force)
    f1, ch1 = started(fmu_path, machine)
    ref = per_sample(ch1, t, x, set_first)
    f2, ch2 = started(fmu_path, machine)
    # Uneven batches, outputs into columns 1: of a wider table (strided rows).
    table = np.full((len(t), 1 + len(ch2.outputs)), np.nan)
    for a, b in ((0, 1), (1, 2), (2, 700), (700, 1500)):
        ch2.run(t[a:b], x[a:b], table[a:b, 1:], set_first=set_first)
        assert f2.time == t[b - 1]
    assert np.isnan(table[:, 0]).all()
    got = table[:, 1:]
    assert np.isfinite(ref).all()
    assert np.array_equal(got.view(np.uint64), ref.view(np.uint64))
    f1.close()
    f2.close()


@pytest.mark.parametrize("bad,function", [("time", "fmi2DoStep"), ("speed", "fmi2SetReal")])
def test_a_failing_call_stops_the_batch_with_the_fmus_message(fmu_path, bad, function):
    t, x = crank_motion(100, 6.8)
    k = 60
    if bad == "time":
        t[k] = t[k - 1] - 5e-4  # a step backwards: the FMU refuses it
    else:
        x[k, 1] = math.nan  # crank.speed = NaN: the FMU refuses it
    # The reference message: the same calls one by one through fmpy.
    f1, ch1 = started(fmu_path, "default")
    ref = per_sample(ch1, t[:k], x[:k])
    with pytest.raises(FmuError) as want:
        per_sample(ch1, t[k : k + 1], x[k : k + 1])
    f2, ch2 = started(fmu_path, "default")
    out = np.full((len(t), len(ch2.outputs)), np.nan)
    with pytest.raises(FmuError) as got:
        ch2.run(t, x, out)
    e = got.value
    assert e.index == k and e.function == function and e.status == 3
    assert e.messages == want.value.messages and str(e) == str(want.value)
    assert ("communicationStepSize" if bad == "time" else "crank.speed = NaN") in str(e)
    assert np.array_equal(out[:k], ref) and np.isnan(out[k:]).all()
    # The FMU's time is the last communication point it reached.
    assert f2.time == (t[k - 1] if bad == "time" else t[k])
    f1.close()
    f2.close()


def test_bad_arguments_are_refused_without_a_crash(fmu_path):
    f, ch = started(fmu_path, "default")
    t, x = crank_motion(10, 6.8)
    with pytest.raises(ValueError):
        ch.run(t, x[:, :3], np.empty((10, len(ch.outputs))))
    with pytest.raises(ValueError):
        ch.run(t, x, np.empty((9, len(ch.outputs))))
    lib = batch.library()
    fail = batch.Failure()
    # Null function pointers, component or failure record: BAD_ARGUMENTS (-1), nothing called.
    assert (
        lib.fmi2_batch_run(
            None,
            None,
            None,
            None,
            None,
            0,
            None,
            0,
            0.0,
            0,
            None,
            None,
            0,
            None,
            0,
            0,
            1,
            ctypes.byref(fail),
        )
        == -1
    )
    assert (
        lib.fmi2_batch_run(
            *ch._addresses,
            f._component,
            None,
            4,
            None,
            1,
            0.0,
            1,
            None,
            None,
            4,
            None,
            1,
            0,
            1,
            None,
        )
        == -1
    )
    assert lib.fmi2_batch_format_csv(None, 1, 1, 1, None, 100) == -1
    f.close()


def test_csv_numbers_are_pythons_repr():
    rng = np.random.default_rng(7)
    bits = rng.integers(0, 2**64, size=100_000, dtype=np.uint64).view(np.float64)
    values = np.concatenate(
        [
            bits[np.isfinite(bits)],
            rng.normal(size=50_000) * 10.0 ** rng.integers(-30, 30, 50_000),
            np.round(rng.normal(size=5_000), 3),
            10.0 ** np.arange(-320, 309),
            -(10.0 ** np.arange(-20, 20)),
            [
                0.0,
                -0.0,
                5e-324,
                1.7976931348623157e308,
                1e16,
                1e-5,
                1e-4,
                9999999999999998.0,
                math.inf,
                -math.inf,
                math.nan,
            ],
        ]
    )
    table = np.resize(values, (len(values) // 7, 7))
    text = batch.format_csv(table).decode()
    want = "".join(",".join(map(repr, row)) + "\n" for row in table.tolist())
    assert text == want
    back = np.array([[float(v) for v in line.split(",")] for line in text.splitlines()])
    assert np.array_equal(back.view(np.uint64), table.view(np.uint64))
    # Into a reused buffer (the twin's writer): the same text, whatever the buffer held before.
    buffer = bytearray(b"x" * 10)
    for rows in (table[:5], table[:1000], table[3:2000:3]):
        view = batch.format_csv(rows, buffer)
        assert bytes(view) == "".join(",".join(map(repr, r)) + "\n" for r in rows.tolist()).encode()
        view.release()


@pytest.mark.parametrize("half", [0.0021, 0.003, 0.05])
def test_local_cubic_agrees_with_the_numpy_fit(half):
    """The native estimate of ω and ε against conditioning.derivatives (numpy's batched LAPACK
    solver), windows of ±half seconds, on jittered timestamps of an encoder-like angle with
    dropouts (sparse windows for the short ones), edges of the segment included."""
    from reciprocating_drive.twin import conditioning as cond

    rng = np.random.default_rng(int(half * 1e4))
    n = 600
    t = np.sort(np.arange(n) * 1e-3 + rng.uniform(-3e-4, 3e-4, n))
    t = t[(t < 0.2) | (t > 0.207)]
    n = len(t)
    theta = (
        6.8 * t + 0.1 * np.sin(13.6 * t) + np.floor(rng.uniform(0, 1, n) * 4) * (2 * math.pi / 4096)
    )
    w_ref, e_ref, in_ref = cond.derivatives(t, theta, half)
    w, e, inside = batch.local_cubic(t, theta, half, 0, n, t[0], t[-1])
    assert np.array_equal(inside, in_ref)
    assert np.array_equal(cond.window_counts(t, half), inside)  # the vectorised count
    if half < 0.003:
        assert np.any(inside < cond.MIN_SAMPLES)  # the dropout makes sparse windows
    assert np.allclose(w, w_ref, rtol=0, atol=1e-9 * np.abs(w_ref).max())
    assert np.allclose(e, e_ref, rtol=0, atol=1e-9 * np.abs(e_ref).max())
    # A sub-range gives the same numbers bit for bit (each centre on its own), and so does the
    # segment's beginning, before its end is known, for the samples whose window it holds.
    w2, e2, _ = batch.local_cubic(t, theta, half, 123, 200, t[0], t[-1])
    assert np.array_equal(w2, w[123:323]) and np.array_equal(e2, e[123:323])
    m = 400
    k = int(np.searchsorted(t[:m] + half, t[m - 1], side="right"))
    w3, e3, _ = batch.local_cubic(t[:m], theta[:m], half, 0, k - 2, t[0], math.inf)
    assert np.array_equal(w3, w[: k - 2]) and np.array_equal(e3, e[: k - 2])
    with pytest.raises(ValueError, match="singular"):
        batch.local_cubic(np.zeros(10), np.arange(10.0), 2.0, 0, 10, 0.0, 0.0)
