"""Alarms written back to OPC UA nodes (page/alarm_nodes.py, docs/page.md "Alarms to OPC UA"),
against a real asyncua server on 127.0.0.1 whose node values the test reads itself."""

from __future__ import annotations

import socket
import time

import pytest
from asyncua import ua
from asyncua.sync import Server
from reciprocating_drive.alarms import AlarmChange
from reciprocating_drive.page.alarm_nodes import AlarmNodes


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture
def plc():
    port = free_port()
    srv = Server()
    srv.set_endpoint(f"opc.tcp://127.0.0.1:{port}/")
    idx = srv.register_namespace("urn:test:twin-alarms")
    obj = srv.nodes.objects.add_object(idx, "Twin")
    torque = obj.add_variable(ua.NodeId("Twin.TorqueHigh", idx), "TorqueHigh", False)
    torque.set_writable()
    fixed = obj.add_variable(ua.NodeId("Twin.ReadOnly", idx), "ReadOnly", False)
    srv.start()
    try:
        yield srv, port, idx, torque, fixed
    finally:
        srv.stop()


def change(state, name="crank torque high"):
    return AlarmChange(state, name, "crank_torque_peak", "critical", 1, 1.0, 9e3, 8e3, "m")


def wait_for(cond, timeout=10.0):
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        if cond():
            return True
        time.sleep(0.05)
    return False


def test_raised_and_cleared_alarms_set_and_reset_their_node(plc):
    srv, port, idx, torque, fixed = plc
    torque.write_value(True)  # a stale state from before: the writer starts from "all clear"
    logs = []
    nodes = AlarmNodes(
        f"opc.tcp://127.0.0.1:{port}/",
        {"crank torque high": f"ns={idx};s=Twin.TorqueHigh"},
        log=logs.append,
    ).start()
    try:
        assert wait_for(lambda: torque.read_value() is False)
        nodes(change("raised"))
        assert wait_for(lambda: torque.read_value() is True)
        nodes(change("raised", name="no node for this one"))  # ignored
        nodes(change("cleared"))
        assert wait_for(lambda: torque.read_value() is False)
        assert wait_for(lambda: nodes.pending() == {})
    finally:
        nodes.close()
    assert logs == []


def test_refused_node_is_reported_once_and_others_still_written(plc):
    srv, port, idx, torque, fixed = plc
    logs = []
    nodes = AlarmNodes(
        f"opc.tcp://127.0.0.1:{port}/",
        {"a": f"ns={idx};s=Twin.ReadOnly", "b": f"ns={idx};s=Twin.TorqueHigh"},
        log=logs.append,
        retry_max=0.5,
    ).start()
    try:
        nodes(change("raised", "a"))
        nodes(change("raised", "b"))
        assert wait_for(lambda: torque.read_value() is True)
        assert wait_for(lambda: len(logs) == 1)
        assert "Twin.ReadOnly (alarm 'a'): write refused: " in logs[0], logs
        assert fixed.read_value() is False
    finally:
        nodes.close()


def test_unreachable_server_is_one_line_retried_until_it_is_there():
    logs = []
    port = free_port()  # nothing listens there yet
    nodes = AlarmNodes(
        f"opc.tcp://127.0.0.1:{port}/",
        {"a": "ns=2;s=Twin.TorqueHigh"},
        log=logs.append,
        timeout=1.0,
        retry_max=0.5,
    ).start()
    srv = None
    try:
        nodes(change("raised", "a"))
        assert wait_for(lambda: len(logs) >= 1)
        srv = Server()
        srv.set_endpoint(f"opc.tcp://127.0.0.1:{port}/")
        idx = srv.register_namespace("urn:test:twin-alarms")
        assert idx == 2
        node = srv.nodes.objects.add_variable(ua.NodeId("Twin.TorqueHigh", idx), "T", False)
        node.set_writable()
        srv.start()
        assert wait_for(lambda: node.read_value() is True, timeout=20)
    finally:
        t0 = time.monotonic()
        nodes.close(timeout=10)
        assert time.monotonic() - t0 < 10
        if srv is not None:
            srv.stop()
    # One line for the whole series of failed attempts, naming the endpoint; no traceback.
    assert len(logs) == 1 and logs[0].startswith(f"alarm nodes: opc.tcp://127.0.0.1:{port}/:")
    assert "\n" not in logs[0]
