"""A property-based suite (Hypothesis, as for the command-line tools): `rdrive plant` against the
simulated PLC playing generated behaviours of other PLCs (a clock glitch, a clock step back, a late
duplicate, speed and force stamped apart from the angle, and pairs of them). The invariant of
docs/plant.md "Final status": the run ends `finished` with exit 0, and every sample the PLC wrote
is stored or counted in a `dropped` event; the summary line gives the same counts. Bounded in time:
4 s of data (a crank at constant speed, speed and force nodes that stay constant for seconds)
played 4x, RD_HOSTILE_EXAMPLES examples (default 6), about 10 s each."""

from __future__ import annotations

import os

import plant_util as pu
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

SAMPLES = 4000
SAME = "duplicate timestamp, same values"
HYPOTHESIS = settings(
    max_examples=int(os.environ.get("RD_HOSTILE_EXAMPLES", "6")),
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
    derandomize=True,
)

sample = st.integers(1, SAMPLES - 10)
behaviour = st.one_of(
    st.tuples(st.just("--clock-glitch"), sample, st.sampled_from([2.0, 60.0, 86400.0])),
    st.tuples(st.just("--clock-step"), sample, st.floats(0.01, 1.5).map(lambda x: round(x, 3))),
    st.tuples(st.just("--duplicate"), sample, st.sampled_from(["same", "other"])),
    st.tuples(st.just("--stamp-apart"), st.integers(0, 400), st.none()),
)
behaviours = st.lists(behaviour, min_size=1, max_size=2, unique_by=lambda b: b[0])


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    """4 s at 1 kHz of a crank at a constant 6.8 rad/s: the speed node constant, the process force
    0, 20 kN from 1.5 s to 3 s, then 0 (constant nodes that a PLC writes every cycle)."""
    import math

    w = 6.8
    lines = ["time,crank_angle,crank_speed,process_force"]
    for i in range(SAMPLES):
        t = i / 1000
        f = 20000.0 if 1.5 <= t < 3 else 0.0
        lines.append(f"{t!r},{math.fmod(w * t, 2 * math.pi)!r},{w!r},{f!r}")
    path = tmp_path_factory.mktemp("plc") / "constant.csv"
    path.write_text("\n".join(lines) + "\n")
    return path


def _args(bs) -> list[str]:
    out = []
    for opt, a, b in bs:
        out += [opt, str(a) if b is None else f"{a}:{b}"]
    return out


@HYPOTHESIS
@given(bs=behaviours)
def test_generated_plc_behaviours_lose_nothing_silently(fmu_path, tmp_path, data, bs):
    name = f"h{abs(hash(tuple(bs))) % 10**8}"
    plc = pu.PlcProcess(
        "--speed", "4", "--start-delay", "1.5", "--linger", "30", *_args(bs), data=data
    )
    cfg = pu.write_config(
        tmp_path / f"{name}.toml",
        run=name,
        source=(
            f'type = "opcua"\nendpoint = "{plc.endpoint}"\n'
            'angle_node = "ns=2;s=Pump.CrankAngle"\nend_node = "ns=2;s=Pump.Finished"\n'
            'speed_node = "ns=2;s=Pump.CrankSpeed"\nforce_node = "ns=2;s=Pump.ProcessForce"\n'
            "reconnect_max = 0.5\n"
        ),
        sinks=pu.sqlite_sink(tmp_path / f"{name}.sqlite"),
        fmu=fmu_path,
    )
    p = pu.start(cfg)
    try:
        with plc:
            out, err = p.communicate(timeout=60)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait(timeout=10)
    db = tmp_path / f"{name}.sqlite"
    assert "Traceback" not in err and p.returncode == 0, (bs, err)
    assert pu.query(db, "SELECT status FROM runs")[0][0] == "finished"
    stored = len(pu.samples(db, name))
    drops: dict = {}
    for _seq, kind, count, msg in pu.events(db, name):
        if kind == "dropped":
            why = msg.split("dropped: ", 1)[1].split(" (first at")[0]
            drops[why] = drops.get(why, 0) + count
    # Every value of the angle the PLC wrote (a --duplicate writes one more) is stored or counted;
    # a sample delivered twice with the same values (by the subscription and the history) is
    # counted on top as a same-values duplicate, so: nothing lost, nothing invented.
    written = SAMPLES + sum(o == "--duplicate" for o, _a, _b in bs)
    assert stored + sum(drops.values()) >= written, (bs, stored, drops)
    assert stored + sum(v for k, v in drops.items() if k != SAME) <= written, (bs, stored, drops)
    assert stored + sum(v for k, v in drops.items() if k != SAME) >= SAMPLES, (bs, stored, drops)
    assert f"{stored} samples stored, {sum(drops.values())} dropped" in err, (bs, err)
