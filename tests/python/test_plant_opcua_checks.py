"""Start-up checks of the OPC UA source (docs/plant.md "Start-up checks"): every configured node is
read once before the twin subscribes; a node that does not exist, is not a Variable, has the wrong
type or shape for its role, or is named twice is one line with exit status 2, within seconds
(before, the twin subscribed and waited for ever). Against the simulated PLC as a real process."""

from __future__ import annotations

import time

import plant_util as pu
import pytest


@pytest.fixture(scope="module")
def plc():
    with pu.PlcProcess("--speed", "1", "--start-delay", "0", "--linger", "120") as p:
        yield p


def _source(endpoint, mode="scalar", **nodes) -> str:
    text = f'type = "opcua"\nendpoint = "{endpoint}"\nmode = "{mode}"\nreconnect_for = 20\n'
    for k, v in nodes.items():
        text += f'{k} = "{v}"\n'
    return text


CASES = {
    "typo": ({"angle_node": "ns=2;s=Pump.CrankAngel"}, "no such node"),
    "other namespace": ({"angle_node": "ns=3;s=Pump.CrankAngle"}, "no such node"),
    "object node": ({"angle_node": "ns=2;s=Pump"}, "a node of class Object, not a Variable"),
    "time node as angle": (
        {"angle_node": "ns=2;s=Pump.Block.Time"},
        "of type DateTime, array; allowed: a number (scalar mode)",
    ),
    "array on a scalar role": (
        {"angle_node": "ns=2;s=Pump.CrankAngle", "force_node": "ns=2;s=Pump.Block.CrankAngle"},
        "source.force_node = 'ns=2;s=Pump.Block.CrankAngle': of type Double, array",
    ),
    "end node not Boolean": (
        {"angle_node": "ns=2;s=Pump.CrankAngle", "end_node": "ns=2;s=Pump.CrankAngle0"},
        "no such node",
    ),
}


@pytest.mark.parametrize("name", list(CASES))
def test_a_bad_node_is_one_line_exit_2_within_seconds(plc, tmp_path, name):
    nodes, words = CASES[name]
    cfg = pu.write_config(
        tmp_path / "n.toml",
        source=_source(plc.endpoint, **nodes),
        sinks=pu.sqlite_sink(tmp_path / "n.sqlite"),
    )
    t0 = time.monotonic()
    p = pu.run(cfg, timeout=60)
    assert "Traceback" not in p.stderr, p.stderr
    lines = [x for x in p.stderr.splitlines() if x.strip()]
    assert p.returncode == 2, p.stderr
    assert len(lines) == 1 and words in lines[0] and str(cfg) in lines[0], p.stderr
    assert time.monotonic() - t0 < 30


@pytest.mark.parametrize(
    "nodes, words",
    [
        (
            {"angle_node": "ns=2;s=Pump.CrankAngle", "time_node": "ns=2;s=Pump.Block.Time"},
            "source.angle_node = 'ns=2;s=Pump.CrankAngle': of type Double, scalar; allowed: an "
            "array of numbers (block mode)",
        ),
        (
            {
                "angle_node": "ns=2;s=Pump.Block.CrankAngle",
                "time_node": "ns=2;s=Pump.Block.Time",
                "end_node": "ns=2;s=Pump.Block.CrankAngle0",
            },
            "no such node",
        ),
        (
            {
                "angle_node": "ns=2;s=Pump.Block.CrankAngle",
                "time_node": "ns=2;s=Pump.Block.Time",
                "end_node": "ns=2;s=Pump.CrankAngle",
            },
            "source.end_node = 'ns=2;s=Pump.CrankAngle': of type Double, scalar; allowed: a Boolean",
        ),
        (
            {"angle_node": "ns=2;s=Pump.Block.CrankAngle", "time_node": "ns=2;s=Pump.CrankAngle"},
            "source.time_node = 'ns=2;s=Pump.CrankAngle': of type Double, scalar; allowed: an "
            "array of DateTime",
        ),
    ],
    ids=[
        "scalar angle in block mode",
        "missing end node",
        "end node a number",
        "time not DateTime",
    ],
)
def test_block_mode_nodes_are_checked(plc, tmp_path, nodes, words):
    cfg = pu.write_config(
        tmp_path / "b.toml",
        source=_source(plc.endpoint, mode="block", **nodes),
        sinks=pu.sqlite_sink(tmp_path / "b.sqlite"),
    )
    p = pu.run(cfg, timeout=60)
    lines = [x for x in p.stderr.splitlines() if x.strip()]
    assert p.returncode == 2 and len(lines) == 1 and words in lines[0], p.stderr


@pytest.mark.parametrize(
    "nodes, words",
    [
        (
            {"angle_node": "ns=2;s=Pump.CrankAngle", "speed_node": "ns=2;s=Pump.CrankAngle"},
            "source.speed_node = 'ns=2;s=Pump.CrankAngle': the same node as source.angle_node",
        ),
        (
            {"angle_node": "ns=2;s=Pump.CrankAngle", "end_node": "ns=2;s=Pump.CrankAngle"},
            "source.end_node = 'ns=2;s=Pump.CrankAngle': the same node as source.angle_node",
        ),
        ({"angle_node": "Pump.CrankAngle"}, "source.angle_node = 'Pump.CrankAngle': not a node id"),
    ],
    ids=["speed is the angle", "end is the angle", "not a node id"],
)
def test_a_node_named_twice_or_malformed_is_a_configuration_error(tmp_path, nodes, words):
    cfg = pu.write_config(
        tmp_path / "t.toml",
        source=_source("opc.tcp://127.0.0.1:1/plc", **nodes),
        sinks=pu.sqlite_sink(tmp_path / "t.sqlite"),
    )
    p = pu.run(cfg, timeout=60)
    lines = [x for x in p.stderr.splitlines() if x.strip()]
    assert p.returncode == 2 and len(lines) == 1 and words in lines[0], p.stderr
