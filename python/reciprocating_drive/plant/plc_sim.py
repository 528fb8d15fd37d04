"""A simulated pump PLC (docs/plant.md, "Simulated PLC"): an asyncua OPC UA server that plays a
crank data file (the shipped sample by default) in real time or faster.

Nodes (namespace "urn:reciprocating-drive:plc-sim", string ids):

* scalar: `Pump.CrankAngle`, and `Pump.CrankSpeed` / `Pump.ProcessForce` when the file has them,
  one value per sample with the sample's time as its SourceTimestamp;
* block: `Pump.Block.Time` (DateTime[]), `Pump.Block.CrankAngle` (and speed, force),
  rewritten every `block_ms` of data time with the samples since the last block; all arrays of a
  block carry the same SourceTimestamp, or (`block_writes="sequential"`) each array is stamped by
  the server's clock when it is written, one after another; `Pump.Block.Seq` (UInt32) counts the
  blocks and is written after a block's arrays;
* `Pump.Finished` (Boolean): true once the last sample is out.

Every value written is kept in the server's history (OPC UA HistoryRead), unless history is off.
Sample i carries the timestamp origin + t_i, origin a whole Unix second: a twin that subtracts the
origin sees the file's own times. Security (optional): Basic256Sha256 Sign or SignAndEncrypt only,
with a certificate made at run time, and user name + password. Faults for the tests: a sample's
angle with a bad status, NaN, a value of the wrong type, two numbers on the scalar node, a 2-D
block array, no SourceTimestamp; a history that fails, caps its responses or answers sorted by
SourceTimestamp; an outage (the endpoint closed for some
seconds while the PLC goes on recording into its history).

Layer: workflows, the plant (docs/architecture.md).
"""

from __future__ import annotations

import asyncio
import datetime as dt
import logging
import math
import pathlib
import socket
import tempfile
import time
from dataclasses import dataclass, field

import numpy as np
from asyncua import Server, ua
from asyncua.crypto.permission_rules import User, UserRole
from asyncua.server.binary_server_asyncio import BinaryServer

from .. import artifacts

NAMESPACE = "urn:reciprocating-drive:plc-sim"
SAMPLE = artifacts.twin_sample()
EPOCH = dt.datetime(1970, 1, 1, tzinfo=dt.UTC)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def make_certificate(directory, name: str, server: bool) -> tuple[pathlib.Path, pathlib.Path]:
    """A self-signed application certificate (DER) and its key (PEM) for 127.0.0.1, made now."""
    import ipaddress

    from asyncua.crypto.cert_gen import (
        dump_private_key_as_pem,
        generate_private_key,
        generate_self_signed_app_certificate,
    )
    from cryptography import x509
    from cryptography.hazmat.primitives.serialization import Encoding
    from cryptography.x509.oid import ExtendedKeyUsageOID

    d = pathlib.Path(directory)
    key = generate_private_key()
    uri = f"urn:reciprocating-drive:{name}"
    cert = generate_self_signed_app_certificate(
        key,
        name,
        {"organizationName": "ReciprocatingDrive"},
        [
            x509.UniformResourceIdentifier(uri),
            x509.DNSName("localhost"),
            x509.IPAddress(ipaddress.ip_address("127.0.0.1")),
        ],
        [ExtendedKeyUsageOID.SERVER_AUTH if server else ExtendedKeyUsageOID.CLIENT_AUTH],
    )
    cp, kp = d / f"{name}.der", d / f"{name}.pem"
    cp.write_bytes(cert.public_bytes(Encoding.DER))
    kp.write_bytes(dump_private_key_as_pem(key))
    kp.chmod(0o600)
    return cp, kp


class _Users:
    """One user name and password; anything else is refused."""

    def __init__(self, name: str, password: str):
        self.name, self.password = name, password

    def get_user(self, iserver, username=None, password=None, certificate=None):
        if username == self.name and password == self.password:
            return User(role=UserRole.User, name=username)
        return None


@dataclass
class PlcSim:
    data: str = str(SAMPLE)
    port: int = 0
    speed: float = 1.0  # multiple of real time
    block_ms: float = 50.0
    history: bool = True
    security: str | None = None  # None, "Sign" or "SignAndEncrypt"
    user: str | None = None
    password: str | None = field(default=None, repr=False)
    cert_dir: str | None = None
    faults: dict = field(
        default_factory=dict
    )  # sample index -> "bad_status" | "nan" | "wrong_type"
    outage: tuple | None = None  # (data time t [s], seconds closed)
    origin: float | None = None  # Unix seconds of t = 0 (default: the next whole second)
    start_delay: float = 0.0  # seconds between listening and the first sample
    written: str = "both"  # which nodes are written: "scalar", "block" or "both"
    log: object = print
    # Behaviours of other PLCs, for the tests (docs/plant.md "Simulated PLC"):
    clock_glitch: tuple | None = None  # (sample, seconds): that one sample stamped ahead
    clock_step: tuple | None = None  # (sample, seconds): from that sample on, stamped earlier
    duplicate: tuple | None = None  # (sample, "same" | "other"): its angle written again later
    stamp_apart_us: int = 0  # speed and force stamped this many µs after the angle
    block_writes: str = "together"  # "sequential": each array stamped by the server at its write
    history_fail: int = 0  # HistoryRead requests answered BadInternalError first (-1: all)
    history_cap: int = 0  # values per HistoryRead response at most (0: asyncua's 10 000)
    history_order: str = "written"  # "time": HistoryRead values sorted by SourceTimestamp
    silent: bool = False  # accept connections and never answer (no OPC UA at all)

    def __post_init__(self):
        self.port = self.port or free_port()
        self.endpoint = f"opc.tcp://127.0.0.1:{self.port}/plc"
        self.server = None
        self.certificate = None
        cols, rows = self._read(self.data)
        self.t = rows[:, cols["time"]]
        self.angle = rows[:, cols["crank_angle"]]
        self.speed_col = rows[:, cols["crank_speed"]] if "crank_speed" in cols else None
        self.force_col = rows[:, cols["process_force"]] if "process_force" in cols else None
        # A pump's pressures (docs/plant.md "Simulated PLC"): node -> column, when the data has it.
        self.pressure_cols = {
            node: rows[:, cols[c]]
            for node, c in (
                ("DischargePressure", "discharge_pressure"),
                ("SuctionPressure", "suction_pressure"),
            )
            if c in cols
        }

    @staticmethod
    def _read(path):
        with open(path) as f:
            names = [c.strip() for c in f.readline().removeprefix("\ufeff").strip().split(",")]
        rows = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
        return {n: i for i, n in enumerate(names)}, rows

    # ---- set-up ---------------------------------------------------------------------------------
    async def start(self) -> None:
        if self.silent:
            await self._start_silent()
            return
        # asyncua's own warnings (self-signed certificate, no encryption) are expected here.
        logging.getLogger("asyncua").setLevel(logging.ERROR)
        users = _Users(self.user, self.password) if self.user else None
        srv = Server(user_manager=users)
        await srv.init()
        srv.set_endpoint(self.endpoint)
        srv.set_server_name("ReciprocatingDrive simulated pump PLC")
        if self.security:
            d = pathlib.Path(self.cert_dir or tempfile.mkdtemp(prefix="plc-sim-"))
            cert, key = make_certificate(d, "plc-sim", server=True)
            await srv.load_certificate(str(cert))
            await srv.load_private_key(str(key))
            self.certificate = cert
            policy = {
                "Sign": ua.SecurityPolicyType.Basic256Sha256_Sign,
                "SignAndEncrypt": ua.SecurityPolicyType.Basic256Sha256_SignAndEncrypt,
            }[self.security]
            srv.set_security_policy([policy])
        else:
            srv.set_security_policy([ua.SecurityPolicyType.NoSecurity])
        if users:
            srv.set_identity_tokens([ua.UserNameIdentityToken])
        ns = await srv.register_namespace(NAMESPACE)
        pump = await srv.nodes.objects.add_object(ua.NodeId("Pump", ns), "Pump")
        self.nodes = {}

        async def var(name, value, vtype):
            node = await pump.add_variable(ua.NodeId(name, ns), name.split(".")[-1], value, vtype)
            self.nodes[name] = node
            # Nothing measured yet: the standard status for it, which the twin skips.
            await srv.write_attribute_value(
                node.nodeid,
                ua.DataValue(
                    ua.Variant(value, vtype),
                    StatusCode=ua.StatusCode(ua.StatusCodes.BadWaitingForInitialData),
                ),
            )
            return node

        d, da = ua.VariantType.Double, ua.VariantType.Double
        await var("Pump.CrankAngle", 0.0, d)
        if self.speed_col is not None:
            await var("Pump.CrankSpeed", 0.0, d)
        if self.force_col is not None:
            await var("Pump.ProcessForce", 0.0, d)
        for name in self.pressure_cols:
            await var(f"Pump.{name}", 0.0, d)
        for name in ("Time", "CrankAngle", "CrankSpeed", "ProcessForce", *self.pressure_cols):
            col = {
                "CrankSpeed": self.speed_col,
                "ProcessForce": self.force_col,
                **self.pressure_cols,
            }.get(name, 0)
            if col is not None:
                await var(
                    f"Pump.Block.{name}", [], ua.VariantType.DateTime if name == "Time" else da
                )
        await var("Pump.Block.Seq", 0, ua.VariantType.UInt32)
        self.seq = 0
        self._last_stamp = None
        await var("Pump.Finished", False, ua.VariantType.Boolean)
        self.storage = srv.iserver.history_manager.storage
        if self.history_cap:
            # A server that caps a HistoryRead response: the rest through continuation points.
            self.storage.max_history_data_response_size = self.history_cap
        if self.history_fail:
            self._failing_history(srv.iserver.history_manager)
        if self.history_order == "time":
            self._time_ordered_history()
        if self.history:
            for node in self.nodes.values():
                # The PLC records every value it writes (not a sampled subscription).
                await self.storage.new_historized_node(node.nodeid, None, 0)
                await node.write_attribute(
                    ua.AttributeIds.AccessLevel,
                    ua.DataValue(
                        ua.Variant(
                            ua.AccessLevel.CurrentRead.mask | ua.AccessLevel.HistoryRead.mask,
                            ua.VariantType.Byte,
                        )
                    ),
                )
                await node.write_attribute(
                    ua.AttributeIds.Historizing,
                    ua.DataValue(ua.Variant(True, ua.VariantType.Boolean)),
                )
        await srv.start()
        self.server = srv
        self.log(f"plc_sim: listening on {self.endpoint}", flush=True)

    def _failing_history(self, manager) -> None:
        """HistoryRead answered BadInternalError (each node of the request) for the first
        `history_fail` requests, or for all (-1): a server whose history store is failing."""
        read = manager.read_history
        self.history_failed = 0

        async def failing(params):
            if self.history_fail < 0 or self.history_failed < self.history_fail:
                self.history_failed += 1
                self.log(f"plc_sim: HistoryRead failed on purpose ({self.history_failed})")
                return [
                    ua.HistoryReadResult(StatusCode=ua.StatusCode(ua.StatusCodes.BadInternalError))
                    for _ in params.NodesToRead
                ]
            return await read(params)

        manager.read_history = failing

    def _time_ordered_history(self) -> None:
        """HistoryRead values sorted by SourceTimestamp (stable), as OPC UA Part 11 describes raw
        history and as many servers answer: a step back of the PLC clock is then not visible in
        the order, only in the ServerTimestamps (the server's own clock at each write)."""
        storage = self.storage
        read = storage.read_node_history

        async def sorted_read(node_id, start, end, nb_values):
            kept = storage._datachanges.get(node_id)
            if kept is None:
                return await read(node_id, start, end, nb_values)
            # asyncua's memory storage filters its list in write order; sorted for this one
            # request (the read does not yield to the event loop, so no write comes between).
            storage._datachanges[node_id] = sorted(kept, key=lambda dv: dv.SourceTimestamp)
            try:
                return await read(node_id, start, end, nb_values)
            finally:
                storage._datachanges[node_id] = kept

        storage.read_node_history = sorted_read

    async def _start_silent(self) -> None:
        """A server that accepts TCP connections and never answers (a hung PLC runtime)."""
        self.conns = []

        async def swallow(reader, writer):
            self.conns.append(writer)
            while await reader.read(65536):
                pass

        self.server = await asyncio.start_server(swallow, "127.0.0.1", self.port)
        self.log(f"plc_sim: listening on {self.endpoint} (silent: never answers)", flush=True)

    def _clear(self, name) -> None:
        att = self.server.iserver.aspace._nodes[self.nodes[name].nodeid].attributes
        att[ua.AttributeIds.Value].value = None

    async def _write(self, name, value, vtype, ts, status=ua.StatusCodes.Good, dims=None) -> None:
        node = self.nodes[name]
        dv = ua.DataValue(
            ua.Variant(value, vtype, Dimensions=dims),
            StatusCode=ua.StatusCode(status),
            SourceTimestamp=ts,
            # The server's own clock at the write (monotonic: a step of the PLC's clock, which
            # stamps the SourceTimestamp, does not move it), as a server stamps a value received.
            ServerTimestamp=self._now(),
        )
        await self.server.write_attribute_value(node.nodeid, dv)
        if self.history and ts is not None:  # a value without a timestamp has no place in it
            await self.storage.save_node_value(node.nodeid, dv)

    def _now(self) -> dt.datetime:
        """The server's clock at a write, strictly after the previous stamp it gave."""
        now = dt.datetime.now(dt.UTC)
        if self._last_stamp is not None and now <= self._last_stamp:
            now = self._last_stamp + dt.timedelta(microseconds=1)
        self._last_stamp = now
        return now

    # ---- playing --------------------------------------------------------------------------------
    async def play(self) -> None:
        if self.silent:
            return
        await asyncio.sleep(self.start_delay)
        origin = float(math.floor(self.origin if self.origin is not None else time.time() + 1.0))
        self.origin = origin
        wall0 = (
            time.monotonic() + max(0.0, origin - time.time())
            if self.speed == 1.0
            else time.monotonic()
        )
        n, i, block_start = len(self.t), 0, 0
        next_block = self.block_ms / 1000.0
        outage_done = self.outage is None
        D = ua.VariantType.Double
        while i < n:
            now = (time.monotonic() - wall0) * self.speed
            if not outage_done and now >= self.outage[0]:
                outage_done = True
                asyncio.get_running_loop().create_task(self._outage(self.outage[1]))
            scalar = self.written in ("scalar", "both")
            while i < n and self.t[i] <= now:
                ts = self._stamp_of(origin, i)
                if not scalar:
                    i += 1
                    if self.t[i - 1] >= next_block or i == n:
                        await self._block(block_start, i, origin, ts)
                        block_start = i
                        next_block = self.t[i - 1] + self.block_ms / 1000.0
                    continue
                other_ts = ts + dt.timedelta(microseconds=self.stamp_apart_us)
                if self.speed_col is not None:
                    await self._write("Pump.CrankSpeed", float(self.speed_col[i]), D, other_ts)
                if self.force_col is not None:
                    await self._write("Pump.ProcessForce", float(self.force_col[i]), D, other_ts)
                for name, col in self.pressure_cols.items():
                    await self._write(f"Pump.{name}", float(col[i]), D, other_ts)
                fault = self.faults.get(i)
                if fault == "bad_status":
                    await self._write(
                        "Pump.CrankAngle",
                        float(self.angle[i]),
                        D,
                        ts,
                        ua.StatusCodes.BadSensorFailure,
                    )
                elif fault == "nan":
                    await self._write("Pump.CrankAngle", math.nan, D, ts)
                elif fault == "double2":
                    # Two numbers on the scalar angle node (a PLC writing an array into it).
                    self._clear("Pump.CrankAngle")
                    a = float(self.angle[i])
                    await self._write("Pump.CrankAngle", [a, a], D, ts)
                    self._clear("Pump.CrankAngle")
                elif fault == "no_stamp":
                    # The angle without a SourceTimestamp (a server that leaves it out).
                    await self._write("Pump.CrankAngle", float(self.angle[i]), D, None)
                elif fault == "wrong_type":
                    # A PLC program writing text into the angle's tag: the server's type check
                    # is sidestepped (the stored value cleared first) so that the text goes out.
                    self._clear("Pump.CrankAngle")
                    await self._write("Pump.CrankAngle", "12.5", ua.VariantType.String, ts)
                    self._clear("Pump.CrankAngle")
                else:
                    await self._write("Pump.CrankAngle", float(self.angle[i]), D, ts)
                if self.duplicate is not None and i == self.duplicate[0] + 1:
                    # The previous sample's angle again, with its timestamp: a late duplicate.
                    k = self.duplicate[0]
                    extra = 0.0 if self.duplicate[1] == "same" else 1.0
                    await self._write(
                        "Pump.CrankAngle",
                        float(self.angle[k]) + extra,
                        D,
                        self._stamp_of(origin, k),
                    )
                i += 1
                if self.written == "both" and (self.t[i - 1] >= next_block or i == n):
                    await self._block(block_start, i, origin, ts)
                    block_start = i
                    next_block = self.t[i - 1] + self.block_ms / 1000.0
            await asyncio.sleep(0.002)
        ts = self._stamp(origin, self.t[-1])
        await self._write("Pump.Finished", True, ua.VariantType.Boolean, ts)
        self.log("plc_sim: finished playing", flush=True)

    def _stamp_of(self, origin: float, i: int) -> dt.datetime:
        """Sample i's timestamp, with the clock's glitch or step when one is asked for."""
        ts = self._stamp(origin, self.t[i])
        if self.clock_step is not None and i >= self.clock_step[0]:
            ts -= dt.timedelta(seconds=self.clock_step[1])
        if self.clock_glitch is not None and i == self.clock_glitch[0]:
            ts += dt.timedelta(seconds=self.clock_glitch[1])
        return ts

    @staticmethod
    def _stamp(origin: float, t: float) -> dt.datetime:
        """The timestamp of data time t: whole microseconds, added as integers (exact)."""
        return EPOCH + dt.timedelta(microseconds=round(origin * 1e6) + round(float(t) * 1e6))

    async def _block(self, lo, hi, origin, ts) -> None:
        D = ua.VariantType.Double
        ang = [float(v) for v in self.angle[lo:hi]]
        dims = None
        for k in range(lo, hi):
            if self.faults.get(k) == "nan":
                ang[k - lo] = math.nan
            if self.faults.get(k) == "block2d":
                # The block's angle as a 2-D array (n x 1): a PLC writing a matrix.
                dims = [len(ang), 1]
        seq = self.block_writes == "sequential"

        def stamp():
            return self._now() if seq else ts

        # Sequential: time, angle, speed, force, then the counter, one write after another, each
        # stamped by the server when it is written (as most servers do).
        # The samples' times as the PLC's clock stamps them (a step back shifts them too).
        times = [self._stamp(origin, v) for v in self.t[lo:hi]]
        if self.clock_step is not None:
            k0, back = self.clock_step
            times = [
                x - dt.timedelta(seconds=back) if lo + j >= k0 else x for j, x in enumerate(times)
            ]
        await self._write("Pump.Block.Time", times, ua.VariantType.DateTime, stamp())
        if dims is not None:
            self._clear("Pump.Block.CrankAngle")
        await self._write("Pump.Block.CrankAngle", ang, D, stamp(), dims=dims)
        if dims is not None:
            self._clear("Pump.Block.CrankAngle")
        if self.speed_col is not None:
            await self._write(
                "Pump.Block.CrankSpeed", [float(v) for v in self.speed_col[lo:hi]], D, stamp()
            )
        if self.force_col is not None:
            await self._write(
                "Pump.Block.ProcessForce", [float(v) for v in self.force_col[lo:hi]], D, stamp()
            )
        for name, col in self.pressure_cols.items():
            await self._write(f"Pump.Block.{name}", [float(v) for v in col[lo:hi]], D, stamp())
        self.seq = (self.seq + 1) % 2**32
        await self._write("Pump.Block.Seq", self.seq, ua.VariantType.UInt32, stamp())

    async def _outage(self, seconds: float) -> None:
        """Closes the endpoint (every connection drops, new ones are refused) for `seconds`."""
        srv = self.server
        await srv.bserver.stop()
        self.log(f"plc_sim: endpoint closed for {seconds:g} s", flush=True)
        await asyncio.sleep(seconds)
        host, port = srv._get_bind_socket_info()
        srv.bserver = BinaryServer(srv.iserver, host, port, srv.limits)
        srv.bserver.set_policies(srv._policies)
        await srv.bserver.start()
        self.log("plc_sim: endpoint open again", flush=True)

    async def stop(self) -> None:
        if self.server is not None:
            if self.silent:
                self.server.close()
                for w in self.conns:
                    w.close()
            else:
                await self.server.stop()
            self.server = None


async def serve(sim: PlcSim, linger: float = 0.0) -> None:
    """Starts, plays the file, stays up `linger` seconds (inf: until cancelled), stops."""
    await sim.start()
    try:
        await sim.play()
        await asyncio.sleep(linger if math.isfinite(linger) else 1e9)
    finally:
        await sim.stop()
