"""Alarms from a limits file (python/reciprocating_drive/alarms.py, docs/page.md "Alarms").

The expected raise and clear revolutions are worked out by hand from the scenario (the step's
time, the windows' contents), not by running the engine's own logic a second way."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from reciprocating_drive.alarms import (
    AlarmEngine,
    LimitsError,
    derived_values,
    load_limits,
    parse_limits,
)

ROOT = Path(__file__).resolve().parents[2]


def run(engine, values, key="crank_torque_max", dt=1.0):
    out = []
    for i, v in enumerate(values):
        for ch in engine.update({"revolution": i, "start_time": i * dt, key: v, "mean_speed": 6.8}):
            out.append((ch.state, i))
    return out


def test_example_limits_file_loads():
    lim = load_limits(ROOT / "examples" / "twin" / "limits.toml")
    assert [x.name for x in lim.limits][0] == "crank torque high"
    assert lim.trends[0].recent == 3600.0 and lim.trends[0].rise == 0.15
    assert lim.for_value("strokes_per_minute") == {"high": 70.0, "low": 60.0}


def test_high_limit_with_hysteresis_and_delay_raises_and_clears_once():
    eng = AlarmEngine(
        parse_limits(
            {"limit": [{"name": "T", "value": "crank_torque_peak", "high": 100.0,
                        "hysteresis": 10.0, "delay": 2}]}
        )
    )  # fmt: skip
    # rev:   0   1    2    3    4    5   6   7   8   9   10  11  12
    vals = [50, 101, 50, 101, 102, 103, 95, 92, 89, 95, 89, 88, 200]
    # 1 alone (delay 2) raises nothing; 3,4 beyond -> raised at 4; 5 still beyond: nothing new;
    # 6,7 inside the limit but not below 90 (hysteresis): stays; 8 below 90, 9 not: counter reset;
    # 10, 11 below 90 -> cleared at 11; 12 beyond once: nothing (delay 2).
    assert run(eng, vals) == [("raised", 4), ("cleared", 11)]
    assert eng.active == {}


def test_low_and_high_limits_on_one_value_are_two_alarms():
    eng = AlarmEngine(
        parse_limits(
            {"limit": [{"name": "spm", "value": "strokes_per_minute", "low": 55.0, "high": 75.0,
                        "hysteresis": 1.0, "delay": 1}]}
        )
    )  # fmt: skip
    got = []
    for i, spm in enumerate([65, 54, 55.5, 56.5, 76, 74.5, 73.9]):
        s = {"revolution": i, "start_time": float(i), "mean_speed": spm * 2 * math.pi / 60}
        got += [(c.name, c.state, i) for c in eng.update(s)]
    assert got == [
        ("spm.low", "raised", 1),
        ("spm.low", "cleared", 3),
        ("spm.high", "raised", 4),
        ("spm.high", "cleared", 6),
    ]


def test_missing_or_nan_values_change_nothing():
    eng = AlarmEngine(
        parse_limits({"limit": [{"value": "stress_max", "high": 1.0, "delay": 2}]})
    )  # fmt: skip
    got = []
    for i, v in enumerate([2.0, math.nan, None, 2.0, 0.5]):
        got += [(c.state, i) for c in eng.update({"revolution": i, "stress_max": v})]
    # NaN and missing neither count nor reset: revolutions 0 and 3 are the two in a row.
    assert got == [("raised", 3)]


def test_trend_alarm_raised_when_recent_mean_exceeds_reference_by_rise():
    eng = AlarmEngine(
        parse_limits(
            {"trend": [{"name": "fw", "value": "friction_work", "recent": 10, "reference": "10 s",
                        "rise": 0.15, "clear": 0.05, "min_revolutions": 5}]}
        )
    )  # fmt: skip
    # One revolution a second: -100 J up to t = 49, -120 J from t = 50 (a ratio above 1 = more
    # work lost). At t = 50 + k (k < 10) the recent window (t-10, t] holds k+1 values of -120 and
    # 9-k of -100, the reference window only -100: ratio (102 + 2k)/100 > 1.15 first at k = 7.
    vals = [-100.0] * 50 + [-120.0] * 40 + [-100.0] * 40
    got = run(eng, vals, key="friction_work")
    # The reference window then fills with -120 too: at t = 60 + k the recent window is all
    # -120 and the reference holds k+1 values of -120 and 9-k of -100: ratio 120/(102 + 2k) - 1
    # below clear = 0.05 first at k = 7. Back to -100 from t = 90 is a fall, which is not watched.
    assert got == [("raised", 57), ("cleared", 67)]


def test_trend_waits_for_min_revolutions_in_both_windows():
    eng = AlarmEngine(
        parse_limits(
            {"trend": [{"value": "friction_work", "recent": 60, "reference": 100, "rise": 0.1,
                        "min_revolutions": 50}]}
        )
    )  # fmt: skip
    # -200 J from t = 100. At t = 100 + k the recent window (t-60, t] holds k+1 values of -200
    # among 60: ratio 1 + (k+1)/60 above 1.1 from k = 6 (t = 106). But the reference window
    # (t-160, t-60] holds only t-59 values: 50 first at t = 109, so the alarm waits for it.
    vals = [-100.0] * 100 + [-200.0] * 20
    got = run(eng, vals, key="friction_work")
    assert got == [("raised", 109)]


BAD = [
    ({"limit": [{"value": "torque", "high": 1}]}, "limit[0].value = 'torque': must be one of"),
    ({"limit": [{"value": "friction_work"}]}, "limit[0]: needs 'high' or 'low'"),
    (
        {"limit": [{"value": "friction_work", "high": 1, "hysteresis": -1}]},
        "limit[0].hysteresis = -1: must be a finite number >= 0",
    ),
    (
        {"limit": [{"value": "friction_work", "high": float("nan")}]},
        "limit[0].high = nan: must be a finite number",
    ),
    (
        {"limit": [{"value": "friction_work", "high": 1, "delay": 0}]},
        "limit[0].delay = 0: must be a whole number >= 1",
    ),
    (
        {"limit": [{"value": "friction_work", "high": 1, "severity": "loud"}]},
        "limit[0].severity = 'loud': must be one of info, warning, critical",
    ),
    (
        {"limit": [{"value": "friction_work", "high": 1, "colour": 1}]},
        "limit[0]: unknown key 'colour'",
    ),
    ({"limit": [{"value": "friction_work", "high": 1, "low": 2}]}, "limit[0].low = 2: must be"),
    (
        {"trend": [{"value": "friction_work", "recent": "1 week", "reference": 1, "rise": 1}]},
        "trend[0].recent = '1 week': must be a duration",
    ),
    (
        {
            "trend": [
                {"value": "friction_work", "recent": 1, "reference": 1, "rise": 0.1, "clear": 0.2}
            ]
        },
        "trend[0].clear = 0.2: must be below rise = 0.1",
    ),  # fmt: skip
    ({"alarm": []}, "unknown key 'alarm'"),
    (
        {
            "limit": [
                {"name": "a", "value": "friction_work", "high": 1},
                {"name": "a", "value": "friction_work", "low": 0},
            ]
        },
        "limit[1].name = 'a': used twice",
    ),  # fmt: skip
]


@pytest.mark.parametrize("doc,msg", BAD)
def test_bad_limits_give_one_line_naming_file_key_and_value(doc, msg):
    with pytest.raises(LimitsError) as e:
        parse_limits(doc, "lim.toml")
    text = str(e.value)
    assert text.startswith("lim.toml: ") and msg in text and "\n" not in text, text


def test_unreadable_and_malformed_files(tmp_path):
    with pytest.raises(LimitsError, match=r"nope\.toml: cannot read the limits file"):
        load_limits(tmp_path / "nope.toml")
    p = tmp_path / "bad.toml"
    p.write_text("[[limit]\nvalue = 1\n")
    with pytest.raises(LimitsError, match=r"bad\.toml: not valid TOML"):
        load_limits(p)


def test_derived_values_against_hand_computation():
    d = derived_values(
        {"mean_speed": 2 * math.pi, "crank_torque_max": 5.0, "crank_torque_min": -7.0,
         "rod_force_max": 3.0, "rod_force_min": -1.0, "friction_work": -2.0}
    )  # fmt: skip
    assert math.isclose(d["strokes_per_minute"], 60.0, rel_tol=1e-15)  # 2π·60/(2π), rounded
    assert d["crank_torque_peak"] == 7.0 and d["rod_force_largest"] == 3.0
    assert d["friction_work"] == -2.0


# ---- with the FMU: the twin's own revolution summaries -------------------------------------------


def sample_lines(t0, t1, force, rate=1000.0):
    """Sample data of the default machine at 65 strokes/min (twin_sample.truth) with a constant
    process force [N]."""
    from reciprocating_drive.twin.sample import truth

    t = np.arange(round(t0 * rate), round(t1 * rate)) / rate
    theta, _, _ = truth(t)
    return [
        f"{float(a)!r},{float(b)!r},{float(force)!r}" for a, b in zip(t, np.mod(theta, 2 * math.pi))
    ]


def test_process_force_step_raises_high_torque_and_stepping_back_clears_it(fmu_path):
    from reciprocating_drive.twin import Twin

    tw = Twin(fmu_path)
    eng = AlarmEngine(
        parse_limits(
            {"limit": [{"name": "T", "value": "crank_torque_peak", "high": 8000.0,
                        "hysteresis": 500.0, "delay": 2}]}
        )
    )  # fmt: skip
    up, down = 4.0, 9.0  # s: 50 kN process force between them (peak torque ~10 kN·m, else ~0.4)
    lines = ["time,crank_angle,process_force"]
    lines += sample_lines(0, up, 0.0) + sample_lines(up, down, 50e3) + sample_lines(down, 15, 0.0)
    _, sums = tw.feed(lines, 1)
    _, rest = tw.finish()
    sums += rest
    changes = [(c.state, c.revolution) for s in sums for c in eng.update(s)]
    starts = [s["start_time"] for s in sums]
    # A revolution holding a sample after the step: the first one ends after `up`; delay 2 -> the
    # next one raises. Cleared: the first revolution starting after `down` is the first whose
    # peak is low again; delay 2 -> the one after it clears.
    first_loaded = next(i for i in range(len(starts) - 1) if starts[i + 1] > up)
    first_unloaded = next(i for i, t in enumerate(starts) if t >= down)
    assert changes == [("raised", first_loaded + 1), ("cleared", first_unloaded + 1)]


def test_friction_ramp_raises_the_trend_alarm(fmu_path):
    """A guide wearing: the friction coefficient of the guide (support B) ramped up from run to
    run (it is fixed within one FMU instance, so each step is a new twin over the same crank
    data); the trend alarm on friction work is raised once the recent mean exceeds the reference
    mean by 15 %, and not before."""
    from reciprocating_drive.twin import Twin

    eng = AlarmEngine(
        parse_limits(
            {"trend": [{"name": "fw", "value": "friction_work", "recent": 20, "reference": 20,
                        "rise": 0.15, "min_revolutions": 10}]}
        )
    )  # fmt: skip
    lines = ["time,crank_angle,process_force", *sample_lines(0, 2.9, 0.0)]
    period = 60 / 65
    mus, works, raised = [], [], []
    rev = 0
    for step in range(40):
        mu = 0.1 if step < 20 else 0.1 * (1 + 0.04 * (step - 19))  # +4 % a step after 20
        tw = Twin(fmu_path, extra_values={"guide.friction_coefficient": mu})
        _, sums = tw.feed(lines, 1)
        s = dict(sums[1])  # a whole revolution of this run, placed at our own time axis
        s["revolution"], s["start_time"] = rev, rev * period
        works.append(s["friction_work"])
        mus.append(mu)
        raised += [c.revolution for c in eng.update(s) if c.state == "raised"]
        rev += 1
    # The independent check: the window means of the FMU's friction work themselves.
    w = np.array(works)
    t = np.arange(len(w)) * period
    first = None
    for k in range(len(w)):
        rec = w[(t > t[k] - 20) & (t <= t[k])]
        ref = w[(t > t[k] - 40) & (t <= t[k] - 20)]
        if len(rec) >= 10 and len(ref) >= 10 and rec.mean() / ref.mean() - 1 > 0.15:
            first = k
            break
    assert first is not None and first > 20, (first, works)
    assert raised == [first]


def test_checkpoint_and_restore_continue_exactly_like_an_uninterrupted_run():
    """Stopped and restored (through JSON, as a checkpoint in a database would be) at every
    revolution of a run with limit and trend alarms, the engine gives the changes of the run
    that was never stopped, and an alarm active at the stop is not raised again."""
    import json
    import random

    doc = {
        "limit": [
            {"name": "T", "value": "crank_torque_peak", "high": 100.0, "hysteresis": 10.0,
             "delay": 2},
        ],
        "trend": [
            {"name": "fw", "value": "friction_work", "recent": 10, "reference": 10, "rise": 0.15,
             "clear": 0.05, "min_revolutions": 5, "delay": 2},
        ],
    }  # fmt: skip
    rng = random.Random(3)
    sums = []
    for i in range(160):
        fw = -100.0 - (25.0 if 60 <= i < 100 else 0.0) + rng.uniform(-1, 1)
        torque = 150.0 if 30 <= i < 50 or 120 <= i < 125 else 50.0 + rng.uniform(0, 5)
        sums.append(
            {"revolution": i, "start_time": 0.9 * i, "crank_torque_max": torque,
             "friction_work": fw, "mean_speed": 6.8}
        )  # fmt: skip

    def changes(engine, part):
        return [(c.name, c.state, c.revolution, c.value) for s in part for c in engine.update(s)]

    clean = changes(AlarmEngine(parse_limits(doc)), sums)
    assert [(n, st) for n, st, _, _ in clean] == [
        ("T", "raised"), ("T", "cleared"), ("fw", "raised"), ("fw", "cleared"),
        ("T", "raised"), ("T", "cleared"),
    ]  # fmt: skip
    for k in range(1, len(sums)):
        first = AlarmEngine(parse_limits(doc))
        got = changes(first, sums[:k])
        cp = json.loads(json.dumps(first.checkpoint()))
        second = AlarmEngine(parse_limits(doc)).restore(cp)
        got += changes(second, sums[k:])
        assert got == clean, k
