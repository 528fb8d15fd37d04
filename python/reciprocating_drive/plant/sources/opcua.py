"""OPC UA as a source (docs/plant.md, "OPC UA source"), with asyncua.

The client runs on its own thread and event loop and hands chunks of samples to the pipeline
through a queue, so a slow database never stalls the subscription (the queue buffers).

* **scalar** mode: the angle node (and speed, force) through a subscription; each value's
  SourceTimestamp is its sample time, and values of the nodes with the same timestamp form one
  sample. **block** mode: arrays of timestamps (DateTime[]) and values that the PLC rewrites every
  N ms, each array of a block with the same SourceTimestamp.
* Times: seconds from `time_origin`, the whole Unix second of the first sample (kept in the
  checkpoint), so a resumed run continues the same time axis.
* A value whose status is not Good, of a type that is not a number, or not finite is not fed to
  the twin: the sample is dropped, counted, and reported as a data-health event ("dropped").
* A lost connection is retried with a doubling delay (up to `reconnect_max` s, for at most
  `reconnect_for` s in all). If the server keeps history, the samples since the last one received
  are read back (HistoryRead) before the subscription's own; without, the interval is a gap, which
  the twin reports like a gap in a file.
* Security: Basic256Sha256 (Sign or SignAndEncrypt) with the client's certificate and key; the
  server's certificate must be one of the `trust` files (DER or PEM); user name and password. A
  refusal stops the run with one line; a password is never part of a message.

Layer: workflows, the plant (docs/architecture.md).
"""

from __future__ import annotations

import asyncio
import bisect
import collections
import datetime as dt
import heapq
import logging
import math
import queue
import sys
import threading
import time

from ...twin.samples import Samples
from ..samples import Chunk, Event

EPOCH = dt.datetime(1970, 1, 1, tzinfo=dt.UTC)
_NUMERIC = None  # the numeric VariantTypes (set on first use: asyncua imported lazily)


class _Fatal(Exception):
    pass


class _BadNode(_Fatal):
    """A configured node the server does not have as the role needs it (a configuration error)."""


#: Node classes and data types for the start-up check (OPC UA Part 3 and Part 6: the standard
#: DataType node ids of namespace 0). Numbers: Boolean excluded; the abstract Number, Integer,
#: UInteger and BaseDataType are accepted (the value's own type is checked on every sample).
_NUMBER_TYPES = {2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 26, 27, 28, 24}
_TIME_TYPES = {13, 294, 24}  # DateTime, UtcTime, BaseDataType
_BOOLEAN_TYPES = {1, 24}


def _numeric_types():
    global _NUMERIC
    if _NUMERIC is None:
        from asyncua import ua

        V = ua.VariantType
        _NUMERIC = {
            V.Double,
            V.Float,
            V.SByte,
            V.Byte,
            V.Int16,
            V.UInt16,
            V.Int32,
            V.UInt32,
            V.Int64,
            V.UInt64,
        }
    return _NUMERIC


def _der(path: str) -> bytes:
    from cryptography import x509
    from cryptography.hazmat.primitives.serialization import Encoding

    data = open(path, "rb").read()
    if b"-----BEGIN" in data:
        return x509.load_pem_x509_certificate(data).public_bytes(Encoding.DER)
    return x509.load_der_x509_certificate(data).public_bytes(Encoding.DER)


def _cert_uri(cert) -> str | None:
    """The application URI in a certificate's subject alternative names (None if absent)."""
    from cryptography import x509

    try:
        san = cert.extensions.get_extension_for_class(x509.SubjectAlternativeName).value
    except x509.ExtensionNotFound:
        return None
    uris = san.get_values_for_type(x509.UniformResourceIdentifier)
    return uris[0] if uris else None


def _application_uri(path: str) -> str | None:
    """The application URI in a certificate's subject alternative names (None if absent)."""
    from cryptography import x509

    try:
        data = open(path, "rb").read()
        cert = (
            x509.load_pem_x509_certificate(data)
            if b"-----BEGIN" in data
            else x509.load_der_x509_certificate(data)
        )
        san = cert.extensions.get_extension_for_class(x509.SubjectAlternativeName).value
        uris = san.get_values_for_type(x509.UniformResourceIdentifier)
        return uris[0] if uris else None
    except (OSError, ValueError, x509.ExtensionNotFound):
        return None


class OpcUaSource:
    rewindable = False

    def __init__(self, settings: dict, password: str | None = None, config_path: str = "<config>"):
        # asyncua logs warnings and tracebacks of its own; the twin reports in one line instead.
        logging.getLogger("asyncua").setLevel(logging.CRITICAL)
        self.s = settings
        self._password = password
        self.config_path = config_path
        self.ended = False
        self.time_origin = None
        self.q: queue.Queue = queue.Queue()
        self.thread = None
        self.loop = None
        self._stop = threading.Event()
        self.roles = {"angle": settings["angle_node"]}
        if settings.get("speed_node"):
            self.roles["speed"] = settings["speed_node"]
        if settings.get("force_node"):
            self.roles["force"] = settings["force_node"]
        for role in PRESSURE_ROLES:
            if settings.get(f"{role}_node"):
                self.roles[role] = settings[f"{role}_node"]
        # With a pressure node a sample's process value (the force's place in the clock's tuples)
        # is the tuple (force, discharge, suction), None for a node not configured.
        self.packed = any(r in self.roles for r in PRESSURE_ROLES)
        if settings["mode"] == "block":
            self.roles["time"] = settings["time_node"]
            if settings.get("seq_node"):
                self.roles["seq"] = settings["seq_node"]
        self.block = settings["mode"] == "block"
        self.join = None
        # One line for the operator (set by the pipeline; standard error by default).
        self.log = lambda m: print(m, file=sys.stderr, flush=True)
        self._recent: dict = {}  # SourceTimestamp -> values of samples handed out (bounded)
        self._gone: dict = {}  # the same for samples dropped by the clock's rules
        self._recent_order: collections.deque = collections.deque()
        self.gap_limit = 0.05  # conditioning.gap_limit (set by the pipeline)

    # ---- the pipeline's side --------------------------------------------------------------------
    def start(self, lines_read: int = 0, last_t=None, time_origin=None) -> None:
        self.last_t = last_t  # the last sample handed out (twin time)
        self.time_origin = time_origin
        if last_t is not None and time_origin is not None:
            # Resumed: the samples after the checkpoint's last one are read back from the
            # server's history at the first connection, as after a lost connection.
            self._origin_dt = EPOCH + dt.timedelta(seconds=time_origin)
            self.last_dt = self._origin_dt + dt.timedelta(microseconds=round(last_t * 1e6))
            self._resumed = True
        elif time_origin is not None:
            # Killed before its first checkpoint: the run's first sample is at or after its
            # time origin (a whole second), and the history is read from there.
            self._origin_dt = EPOCH + dt.timedelta(seconds=time_origin)
            self.last_dt = self._origin_dt - dt.timedelta(microseconds=1)
            self._resumed = True
        self.connected = threading.Event()
        self.thread = threading.Thread(target=self._thread, name="opcua-source", daemon=True)
        self.thread.start()
        # The first connection's outcome: a refusal is an error of the start.
        deadline = time.monotonic() + self.s["reconnect_for"] + self.s["timeout"] + 5
        while not self.connected.wait(0.05):
            if not self.thread.is_alive() or time.monotonic() > deadline:
                break
            try:
                item = self.q.queue[0] if self.q.queue else None
            except IndexError:
                item = None
            if isinstance(item, Exception):
                break
        if not self.q.empty() and isinstance(self.q.queue[0], Exception):
            self._raise(self.q.get())

    def _raise(self, e):
        from ..config import ConfigError
        from .base import SourceError

        if isinstance(e, ConfigError):  # a configured node the server does not have: exit 2
            raise ConfigError(str(e)) from None
        raise SourceError(str(e)) from None

    def get(self, timeout: float) -> Chunk | None:
        try:
            item = self.q.get(timeout=timeout)
        except queue.Empty:
            return None
        if isinstance(item, Exception):
            self._raise(item)
        if item is None:
            self.ended = True
            return None
        # Take whatever else is there too: one chunk per call.
        while not self.q.empty():
            more = self.q.queue[0]
            if not isinstance(more, Chunk):
                break
            more = self.q.get()
            item.lines += more.lines
            if more.samples is not None:
                item.samples = more.samples if item.samples is None else item.samples + more.samples
            item.events += more.events
        return item

    def close(self) -> None:
        self._stop.set()
        if self.thread is not None:
            self.thread.join(timeout=self.s["timeout"] + 5)

    # ---- the client's thread --------------------------------------------------------------------
    def _thread(self) -> None:
        from ..config import ConfigError

        try:
            asyncio.run(self._main())
        except _BadNode as e:
            self.q.put(ConfigError(str(e)))
        except _Fatal as e:
            self.q.put(RuntimeError(str(e)))
        except Exception as e:  # noqa: BLE001 - reported by the pipeline as one line
            self.q.put(RuntimeError(f"OPC UA source {self.s['endpoint']}: {type(e).__name__}: {e}"))

    def _emit(self, samples: Samples | list, events: list) -> None:
        # The numbers as received (`[]` with events only): the twin numbers them as the lines of
        # the input's CSV form (its header is line 1 of a new run), so messages name the same lines.
        if len(samples) or events:
            self.q.put(Chunk(events=list(events), samples=samples if len(samples) else None))

    async def _main(self) -> None:
        s = self.s
        delay, lost_at, reason, first = 0.2, None, None, True
        while not self._stop.is_set():
            try:
                client = await self._connect()
            except _Fatal:
                raise
            except (TimeoutError, OSError, ConnectionError) as e:
                reason = reason or (str(e).splitlines()[0] if str(e) else type(e).__name__)
                lost_at = lost_at or time.monotonic()
                self._notice(lost_at, e)
                if time.monotonic() - lost_at > s["reconnect_for"]:
                    raise _Fatal(
                        f"OPC UA source {s['endpoint']}: unreachable for {s['reconnect_for']:g} s "
                        f"(reconnect_for): {reason}"
                    ) from None
                await asyncio.sleep(delay)
                delay = min(delay * 2, s["reconnect_max"])
                continue
            if first:
                try:
                    await self._check_nodes(client)
                except _BadNode:
                    try:
                        await asyncio.wait_for(client.disconnect(), 2.0)
                    except Exception:  # noqa: BLE001 - refused anyway
                        pass
                    raise
                except (TimeoutError, OSError, ConnectionError):
                    continue  # the connection went: retried as any lost connection
            self.connected.set()
            if self._noticed is not None:
                self.log(
                    f"OPC UA source {s['endpoint']}: answering again after "
                    f"{time.monotonic() - lost_at:.3g} s"
                )
                self._noticed = None
            delay = 0.2
            try:
                ended = await self._session(client, None if first else (lost_at, reason))
            except (TimeoutError, OSError, ConnectionError, _Lost) as e:
                reason = str(e).splitlines()[0] if str(e) else type(e).__name__
                lost_at = time.monotonic()
                first = False
                try:
                    await asyncio.wait_for(client.disconnect(), 1.0)
                except Exception:  # noqa: BLE001 - the connection is gone anyway
                    pass
                continue
            try:
                await asyncio.wait_for(client.disconnect(), 2.0)
            except Exception:  # noqa: BLE001
                pass
            if ended:
                self.q.put(None)
                return
            return  # stopped by the pipeline

    _noticed = None  # monotonic time of the last "not answering" line

    def _notice(self, since: float, e) -> None:
        """A line when the server first stops answering (or cannot be reached), then one every
        notice_interval s while it stays so (docs/plant.md "Unresponsive server or database")."""
        now = time.monotonic()
        every = self.s.get("notice_interval", 30.0)
        if self._noticed is not None and now - self._noticed < every:
            return
        why = str(e).splitlines()[0] if str(e) else type(e).__name__
        if isinstance(e, TimeoutError):
            why = f"no answer within timeout = {self.s['timeout']:g} s"
        first = self._noticed is None
        self._noticed = now
        self.log(
            f"OPC UA source {self.s['endpoint']}: "
            + ("not answering" if first else f"still not answering after {now - since:.0f} s")
            + f" ({why}); retrying for up to reconnect_for = {self.s['reconnect_for']:g} s"
        )

    async def _check_nodes(self, client) -> None:
        """Every configured node read once before subscribing (docs/plant.md "Start-up
        checks"): it exists, is a Variable, and its DataType and ValueRank fit its role (a number,
        DateTime[] for block times, Boolean for the end node; scalar in scalar mode, an array in
        block mode). Otherwise one line, and the run stops with exit status 2: a subscription to
        a node that never notifies would wait for ever."""
        from asyncua import ua
        from asyncua.ua.object_ids import ObjectIdNames

        s = self.s
        block = self.block
        keys = {"angle": "angle_node", "speed": "speed_node", "force": "force_node"}
        keys.update({r: f"{r}_node" for r in PRESSURE_ROLES})
        keys["time"] = "time_node"
        keys["seq"] = "seq_node"
        checks = [(keys[role], nid, role) for role, nid in self.roles.items()]
        if s.get("end_node"):
            checks.append(("end_node", s["end_node"], "end"))
        for key, nid, role in checks:
            where = f"{self.config_path}: source.{key} = {nid!r}"
            node = client.get_node(nid)
            try:
                cls = await asyncio.wait_for(node.read_node_class(), s["timeout"])
            except ua.UaStatusCodeError as e:
                raise _BadNode(
                    f"{where}: no such node on {s['endpoint']} ({type(e).__name__}); check the "
                    "namespace index and the name"
                ) from None
            if cls != ua.NodeClass.Variable:
                raise _BadNode(f"{where}: a node of class {cls.name}, not a Variable")
            try:
                dtype = await asyncio.wait_for(node.read_data_type(), s["timeout"])
                rank = await asyncio.wait_for(node.read_value_rank(), s["timeout"])
            except ua.UaStatusCodeError as e:
                raise _BadNode(
                    f"{where}: its data type cannot be read ({type(e).__name__})"
                ) from None
            tid = dtype.Identifier if dtype.NamespaceIndex == 0 else None
            tname = ObjectIdNames.get(tid, dtype.to_string())
            array = rank >= 0  # -1 scalar, -2 any, -3 scalar or 1-D; 0 one or more dimensions
            if role == "end":
                want, ok = "a Boolean", tid in _BOOLEAN_TYPES and not array
            elif role == "time":
                want, ok = "an array of DateTime", tid in _TIME_TYPES and rank in (1, 0, -2, -3)
            elif role == "seq":
                want, ok = "a number (the block counter)", tid in _NUMBER_TYPES and not array
            elif block:
                want = "an array of numbers (block mode)"
                ok = tid in _NUMBER_TYPES and rank in (1, 0, -2, -3)
            else:
                want, ok = "a number (scalar mode)", tid in _NUMBER_TYPES and not array
            if not ok:
                shape = {-1: "scalar", -2: "any shape", -3: "scalar or 1-D", 0: "array"}.get(
                    rank, f"{rank}-D array"
                )
                raise _BadNode(f"{where}: of type {tname}, {shape}; allowed: {want}")

    async def _connect(self):
        from asyncua import Client, ua
        from asyncua.crypto.security_policies import SecurityPolicyBasic256Sha256

        s = self.s
        client = Client(s["endpoint"], timeout=s["timeout"])
        client.session_timeout = 30000
        if s["username"]:
            client.set_user(s["username"])
            client.set_password(self._password or "")
        where = f"OPC UA source {s['endpoint']}"
        if s["security_policy"] == "Basic256Sha256":
            trusted = {}
            for p in s["trust"]:
                try:
                    trusted[_der(p)] = p
                except (OSError, ValueError) as e:
                    raise _Fatal(f"{where}: trust file {p}: not a certificate ({e})") from None

            async def check(cert, _app):
                from cryptography.hazmat.primitives import hashes
                from cryptography.hazmat.primitives.serialization import Encoding

                if cert.public_bytes(Encoding.DER) not in trusted:
                    fp = cert.fingerprint(hashes.SHA256()).hex(":")
                    raise _Fatal(
                        f"{where}: the server's certificate ({cert.subject.rfc4514_string()}, "
                        f"SHA-256 {fp}) is not in the trust list (source.trust); refused"
                    )
                want = s.get("server_uri")
                if want and _cert_uri(cert) != want:
                    raise _Fatal(
                        f"{where}: the server's certificate names the application URI "
                        f"{_cert_uri(cert)!r}, not {want!r} (source.server_uri); refused"
                    )

            client.certificate_validator = check
            uri = _application_uri(s["certificate"])
            if uri:
                client.application_uri = uri  # as the client certificate says
            mode = getattr(ua.MessageSecurityMode, s["security_mode"])
            try:
                await client.set_security(
                    SecurityPolicyBasic256Sha256, s["certificate"], s["private_key"], mode=mode
                )
            except (TimeoutError, OSError, ConnectionError):
                raise
            except ua.UaError as e:
                raise _Fatal(
                    f"{where}: no {s['security_policy']} {s['security_mode']} endpoint ({e})"
                ) from None
            except Exception as e:  # noqa: BLE001 - a bad certificate or key file
                raise _Fatal(
                    f"{where}: the client certificate or key: {type(e).__name__}: {e}"
                ) from None
        try:
            await client.connect()
        except _Fatal:
            raise
        except (TimeoutError, OSError, ConnectionError):
            raise
        except ua.UaStatusCodeError as e:
            raise _Fatal(self._refusal(e)) from None
        except ua.UaError as e:
            raise _Fatal(f"{where}: refused: {str(e).splitlines()[0]}") from None
        return client

    def _refusal(self, e) -> str:
        s, where = self.s, f"OPC UA source {self.s['endpoint']}"
        name = type(e).__name__
        login = "set source.username and password_file or password_env"
        if "UserAccessDenied" in name or "IdentityTokenRejected" in name:
            if not s["username"]:
                return f"{where}: the server refuses anonymous connections ({name}); {login}"
            return (
                f"{where}: the server refused user {s['username']!r} ({name}): "
                "wrong user name or password"
            )
        if "IdentityTokenInvalid" in name:
            return f"{where}: the server refuses this kind of login ({name}); {login}"
        if "Security" in name or "Certificate" in name:
            return (
                f"{where}: the secure channel was refused ({name}); check security_policy, "
                "security_mode and the certificates"
            )
        return f"{where}: refused ({name})"

    async def _session(self, client, lost) -> bool:
        """Subscribes, reads back what was missed, then hands out samples until the connection is
        lost (raises) or the PLC says it has finished (returns True) or the pipeline stops."""
        from asyncua import ua

        notes: list = []  # (role, DataValue) in arrival order, from the subscription's handler
        nodes = {role: client.get_node(nid) for role, nid in self.roles.items()}
        by_node = {n.nodeid: role for role, n in nodes.items()}
        end_node = client.get_node(self.s["end_node"]) if self.s.get("end_node") else None
        finished = []  # the SourceTimestamp of the PLC's "finished"

        class Handler:
            def datachange_notification(self, node, val, data):
                if end_node is not None and node.nodeid == end_node.nodeid:
                    if val is True:
                        finished.append(data.monitored_item.Value.SourceTimestamp)
                    return
                notes.append((by_node[node.nodeid], data.monitored_item.Value))

        sub = await client.create_subscription(self.s["publishing_interval"] * 1000, Handler())
        # Notifications when the SourceTimestamp changes too, not only the value: a PLC that
        # writes the same speed or force every cycle then notifies every sample (OPC UA Part 4,
        # DataChangeTrigger StatusValueTimestamp). asyncua's public subscribe_data_change takes
        # no filter; its _subscribe does. A node that refuses the filter is subscribed without.
        trigger = ua.DataChangeFilter(Trigger=ua.DataChangeTrigger.StatusValueTimestamp)
        handles = await sub._subscribe(list(nodes.values()), mfilter=trigger, queuesize=10000)
        refused = [
            n for n, h in zip(nodes.values(), handles, strict=True) if isinstance(h, ua.StatusCode)
        ]
        if refused:
            await sub.subscribe_data_change(refused, queuesize=10000)
        if end_node is not None:
            await sub.subscribe_data_change(end_node)
        if "seq" in self.roles:
            # Kept across reconnections: the counter value last taken is where history starts.
            self.join = self.join or _SeqJoiner(self)
        else:
            self.join = _Joiner(self) if self.block else _ScalarJoiner(self)
        events = []
        if lost is None and getattr(self, "_resumed", False):
            lost = (None, "the twin was restarted")
            self._resumed = False
        if lost is not None:
            lost_at, reason = lost
            if lost_at is None:
                msg = f"resumed on {self.s['endpoint']} after the last checkpoint"
            else:
                down = time.monotonic() - lost_at
                msg = f"connection to {self.s['endpoint']} lost ({reason}), back after {down:.3g} s"
            if self.s["history"] and self.last_dt is not None:
                got = 0
                since = getattr(self.join, "taken_dt", None) or self.last_dt
                if lost_at is not None and not self.block:
                    # Scalar mode, from clock_tolerance before the last sample handed out: a
                    # clock step back during the outage (samples stamped before it) is then in
                    # the history as it would have come live, and none of the samples after
                    # the step is left out. What was handed out or dropped before comes again
                    # and is counted as a duplicate with the same values (docs/plant.md
                    # "History"). Not in block mode: a bad block's samples share one stamp and
                    # cannot be told from the same block again.
                    since -= dt.timedelta(seconds=self.s.get("clock_tolerance", 1.0))
                try:
                    hist = await self._history(nodes, since + dt.timedelta(microseconds=1))
                    for role, dvs in hist.items():
                        hist[role] = _written_order(dvs)
                    # Interleave the roles by timestamp, as the subscription would have, but
                    # keep each node's values in the order the server gives them (the order
                    # they were written): sorting them by time would interleave the samples
                    # before a clock step back with those after it, and hide the step from
                    # the clock's rules (docs/plant.md "Timestamps").
                    merged = heapq.merge(
                        *(
                            [(dv.SourceTimestamp, k, i, role, dv) for i, dv in enumerate(dvs)]
                            for k, (role, dvs) in enumerate(hist.items())
                        ),
                        key=lambda x: (x[0], x[1]),
                    )
                    before = self.samples_out
                    self._process([(role, dv) for _ts, _k, _i, role, dv in merged], events)
                    got = self.samples_out - before
                    msg += f"; {got} missed samples read back from the server's history"
                except _NoHistory as e:
                    msg += f"; history not available ({e}): the interval is a gap"
            else:
                msg += "; no history: the interval is a gap"
            events.insert(
                0, Event("reconnect", msg, t=self._t(self.last_dt) if self.last_dt else None)
            )
        last_probe = quiet = time.monotonic()
        while not self._stop.is_set():
            await asyncio.sleep(self.s["publishing_interval"] / 2)
            if notes:
                quiet = time.monotonic()
                batch = notes[:]
                del notes[: len(batch)]
                self._process(batch, events)
            else:
                # Nothing new: what waits for the rest of its group still times out (bounded).
                self._process([], events)
                if events:
                    self._emit([], events)
            events = []
            if finished and (
                (self.newest_dt is not None and self.newest_dt >= finished[0])
                or time.monotonic() - quiet > 2.0
            ):
                # Every sample up to the PLC's end is out (or nothing came for 2 s after it).
                self._process([], events, flush=True)
                self._emit([], events)
                return True
            if time.monotonic() - last_probe > 0.5:
                last_probe = time.monotonic()
                try:
                    await asyncio.wait_for(
                        client.nodes.server_state.read_value(), self.s["timeout"]
                    )
                except (TimeoutError, OSError, ConnectionError, ua.UaError) as e:
                    raise _Lost(str(e).splitlines()[0] if str(e) else type(e).__name__) from None
        return False

    async def _history(self, nodes, start) -> dict:
        """Every node's history from `start` (asyncua follows the server's continuation points
        when it caps a response). A failing HistoryRead (BadInternalError, BadTimeout, ...) is
        retried with the reconnection's doubling delay for up to history_retry_for s before the
        interval becomes a gap (docs/plant.md "History")."""
        from asyncua import ua

        s = self.s
        t0, delay, tries = time.monotonic(), 0.2, 0
        while True:
            tries += 1
            try:
                hist = {}
                # The block counter first: the PLC goes on writing while the nodes are read one
                # after another, and every array of a counter value read is written before it,
                # so it is in the arrays' reads that follow (not so the other way round).
                order = sorted(nodes.items(), key=lambda x: x[0] != "seq")
                for role, node in order:
                    hist[role] = await asyncio.wait_for(
                        node.read_raw_history(start, None), s["timeout"] * 4
                    )
                if tries > 1:
                    self.log(
                        f"OPC UA source {s['endpoint']}: history read on attempt {tries}, "
                        f"after {time.monotonic() - t0:.3g} s"
                    )
                return hist
            except ua.UaStatusCodeError as e:
                name = type(e).__name__
                if name in ("BadHistoryOperationUnsupported", "BadHistoryOperationInvalid"):
                    raise _NoHistory(name) from None  # not kept at all: retrying cannot help
                spent = time.monotonic() - t0
                if spent + delay > s["history_retry_for"]:
                    self.log(
                        f"OPC UA source {s['endpoint']}: HistoryRead failed {tries} times over "
                        f"{spent:.3g} s ({name}); the interval is a gap"
                    )
                    raise _NoHistory(
                        f"{name}, {tries} attempts over {spent:.3g} s (history_retry_for)"
                    ) from None
                if tries == 1:
                    self.log(
                        f"OPC UA source {s['endpoint']}: HistoryRead failed ({name}); retrying "
                        f"for up to history_retry_for = {s['history_retry_for']:g} s"
                    )
                await asyncio.sleep(delay)
                delay = min(delay * 2, s["reconnect_max"])

    # ---- samples --------------------------------------------------------------------------------
    last_dt = None  # SourceTimestamp of the last sample handed out
    samples_out = 0

    def _t(self, ts: dt.datetime) -> float:
        """Twin time of a timestamp: exact for whole microseconds (timedelta arithmetic)."""
        return (ts - self._origin_dt).total_seconds()

    def _process(self, batch, events, flush=False) -> None:
        """Joined samples through the clock's rules (docs/plant.md "Timestamps"): every sample is
        handed out or dropped with its reason, counted in a `dropped` event."""
        out = ([], [], [], [])
        dropped: dict = {}

        def drop(why, ts):
            dropped.setdefault(why, []).append(ts)

        for ts, _t_dt, a, w, f, bad in self.join.feed(batch, flush):
            self.received += 1
            gone = self._gone.get(ts) if ts is not None else None
            if gone is not None and _dup((a, w, f, bad), gone) == _SAME:
                # A sample dropped before, delivered again (the history after a reconnection).
                drop(_SAME, ts)
                continue
            if bad:
                drop(bad, ts)
                if ts is not None and not self.block:
                    # Scalar mode: one sample a stamp. (A bad block gives each of its samples
                    # the block's stamp: they are not the same sample again.)
                    self._remember(self._gone, ts, (a, w, f, bad))
                continue
            self._admit(ts, (a, w, f), out, drop, events)
        if flush and self._held is not None:
            hts, hvals, _ = self._held
            self._held = None
            if self.last_dt is None or hts > self.last_dt:
                self._hand(hts, hvals, out)
            else:
                drop(_BACK, hts)
        for why, stamps in dropped.items():
            self.dropped += len(stamps)
            first = next((x for x in stamps if x is not None), None)
            at = self._t(first) if first is not None and hasattr(self, "_origin_dt") else None
            when = f" (first at {first.isoformat()})" if first is not None else ""
            events.append(
                Event(
                    "dropped",
                    f"{len(stamps)} sample(s) dropped: {why}{when}",
                    t=at,
                    count=len(stamps),
                    reason=why,
                )
            )
        out_t, out_a, out_w, out_f = out
        self.samples_out += len(out_t)
        if self.packed:
            out_f, *pressures = (list(c) for c in zip(*out_f)) if out_f else ([], [], [])
        else:
            pressures = [None, None]
        samples = Samples.of(
            time=out_t,
            crank_angle=out_a,
            crank_speed=out_w if "speed" in self.roles else None,
            process_force=out_f if "force" in self.roles else None,
            discharge_pressure=pressures[0] if "discharge" in self.roles else None,
            suction_pressure=pressures[1] if "suction" in self.roles else None,
        )
        self._emit(samples, events)
        events.clear()

    # The clock's state: a sample held for one more (the first, or one after a forward jump
    # beyond clock_tolerance), samples handed out recently (duplicates), samples before the last.
    _held = None
    _back_streak = 0
    _resync = None
    received = dropped = 0

    def _admit(self, ts, vals, out, drop_, events) -> None:
        tol = dt.timedelta(seconds=self.s.get("clock_tolerance", 1.0))

        def drop(why, when, v=vals):
            # Remembered (bounded, with the samples handed out): the same sample delivered again
            # (subscription and history) is then counted as such, not twice under its reason.
            drop_(why, when)
            if why != _SAME:
                self._remember(self._gone, when, (*v, None))

        if self._held is not None:
            hts, hvals, _kind = self._held
            if ts > hts:
                self._held = None
                self._hand(hts, hvals, out)
            elif ts == hts:
                drop(_dup(vals, hvals), ts)
                return
            elif self.last_dt is None or ts > self.last_dt:
                # Ahead of the samples before and after it: the PLC clock glitched for it.
                self._held = None
                ahead = (hts - ts).total_seconds()
                drop(_GLITCH, hts, hvals)
                events.append(
                    Event(
                        "clock_jump",
                        f"a sample stamped {hts.isoformat()}, {ahead:.6g} s ahead of the next "
                        "one, dropped as a glitch of the PLC clock; the samples after it go on",
                        t=self._t(ts) if hasattr(self, "_origin_dt") else None,
                    )
                )
            else:
                drop(_BACK, ts)
                return
        last = self.last_dt
        if last is None:
            self._held = (ts, vals, "first")
            return
        if ts <= last:
            prev = self._recent.get(ts)
            if prev is not None:
                why = _dup(vals, prev)
                drop(why, ts)
                if why == _SAME:
                    return  # the same sample delivered again: nothing about the clock
            else:
                drop(_BACK, ts)
            # A stamp at or before the last one (a time reused with other values counts too).
            self._back_streak += 1
            if self._back_streak == 2:
                # Two in a row before the last sample: the PLC clock stepped back. The samples
                # stamped before the last one are dropped, and after it until the clock has passed
                # it by more than gap_limit, so that the core sees a gap and restarts after it.
                gap = self.gap_limit
                self._resync = last + dt.timedelta(seconds=gap)
                events.append(
                    Event(
                        "clock_jump",
                        f"the PLC clock stepped back {(last - ts).total_seconds():.6g} s (a sample "
                        f"stamped {ts.isoformat()} after {last.isoformat()}): samples are dropped "
                        f"until the clock passes {self._resync.isoformat()} (gap_limit {gap:g} s "
                        "beyond the last sample), then the run goes on after a gap",
                        t=self._t(last),
                    )
                )
            return
        self._back_streak = 0
        if self._resync is not None and ts <= self._resync:
            drop(_BACK, ts)
            return
        if ts - last > tol:
            self._held = (ts, vals, "jump")
            return
        self._hand(ts, vals, out)

    def _hand(self, ts, vals, out) -> None:
        if self.time_origin is None:
            self.time_origin = float(math.floor((ts - EPOCH).total_seconds()))
        if not hasattr(self, "_origin_dt"):
            self._origin_dt = EPOCH + dt.timedelta(seconds=self.time_origin)
        t = self._t(ts)
        self.last_t, self.last_dt = t, ts
        if self._resync is not None and ts > self._resync:
            self._resync = None  # past a step back: only a sample handed out ends the wait
        self._remember(self._recent, ts, vals)
        for col, v in zip(out, (t, *vals), strict=True):
            col.append(v)

    def accounting(self) -> tuple[int, int, int]:
        """(samples received, handed to the twin, dropped and counted) in this process."""
        held = int(self._held is not None)
        return self.received, self.samples_out + held, self.dropped

    def _remember(self, table: dict, ts, vals) -> None:
        table[ts] = vals
        self._recent_order.append((table, ts))
        if len(self._recent_order) > 40000:  # bounded: a sample comes again within seconds
            t, k = self._recent_order.popleft()
            t.pop(k, None)

    @property
    def newest_dt(self):
        """The newest sample time handed out or held (the end node's test)."""
        if self._held is not None and (self.last_dt is None or self._held[0] > self.last_dt):
            return self._held[0]
        return self.last_dt


_GLITCH = "a glitch of the PLC clock (one sample stamped ahead)"
_BACK = "stamped before the last sample handed out (out of order, or a clock step back)"


#: A pump's pressure roles (source.discharge_node, source.suction_node; docs/plant.md).
PRESSURE_ROLES = ("discharge", "suction")


def _process_value(src, values: dict):
    """A sample's process value from its roles' values: the force alone, or with a pressure node
    configured the tuple (force, discharge, suction) (None for a role not configured)."""
    if not src.packed:
        return values.get("force")
    return tuple(values.get(r) for r in ("force", *PRESSURE_ROLES))


def _dup(vals, prev) -> str:
    """The reason of a sample whose timestamp was handed out already."""
    if prev is None or all(
        (a == b) or (a != a and b != b) for a, b in zip(vals, prev, strict=True)
    ):
        return _SAME
    return "duplicate timestamp with other values (the first kept)"


_SAME = "duplicate timestamp, same values"


_WAITING = 0x80320000  # BadWaitingForInitialData


class _Lost(Exception):
    pass


class _NoHistory(Exception):
    pass


def _stamp(item):
    return item[0]


def _written_order(dvs: list) -> list:
    """A node's history values in the order they were written (docs/plant.md "History"): by
    ServerTimestamp, the server's own clock when it received each value, when every value has
    one; otherwise as the server gives them. A server that sorts raw history by SourceTimestamp
    (OPC UA Part 11) would otherwise interleave the samples stamped before a step back of the
    PLC clock with those after it and hide the step from the clock's rules. The sort is stable:
    values the server stamped alike keep the server's order."""
    if dvs and all(dv.ServerTimestamp is not None for dv in dvs):
        return sorted(dvs, key=lambda dv: dv.ServerTimestamp)
    return list(dvs)


class _ScalarJoiner:
    """Scalar mode (docs/plant.md "Sample assembly"): the angle node is the clock. Each angle
    value is a sample; speed and force take the value of their node stamped at most
    `join_tolerance` after the angle's stamp, or the latest before it (sample and hold), if it
    is at most `hold_limit` s older than the angle. An angle waits until every other node has a
    value stamped after it (+ join_tolerance), or until an angle stamped JOIN_WAIT s later has
    come (a node whose value does not change may not notify), so nothing waits for ever; what
    waits is bounded (MAX_PENDING angles, then the oldest goes out with the values held)."""

    JOIN_WAIT = 0.2  # s of PLC time
    MAX_PENDING = 20000

    def __init__(self, src: OpcUaSource):
        self.src = src
        self.others = [r for r in ("speed", "force", *PRESSURE_ROLES) if r in src.roles]
        self.values: dict = {r: [] for r in self.others}  # (ts, value, bad) in time order
        self.angles: collections.deque = collections.deque()
        self.tol = dt.timedelta(seconds=src.s.get("join_tolerance", 0.0005))
        self.hold = dt.timedelta(seconds=src.s.get("hold_limit", 10.0))
        self.wait = dt.timedelta(seconds=self.JOIN_WAIT)
        self.clock = dt.timedelta(seconds=src.s.get("clock_tolerance", 1.0))
        self.check = _Joiner(src)._check

    def feed(self, batch, flush=False):
        out = []
        for role, dv in batch:
            if dv.StatusCode.value == _WAITING:
                continue  # the PLC has measured nothing yet: no sample
            ts = dv.SourceTimestamp
            value, bad = self.check(role, dv, False)
            if role == "angle":
                if ts is None:
                    out.append((None, None, None, None, None, "no SourceTimestamp on angle"))
                else:
                    self.angles.append((ts, value, bad))
            elif ts is not None:
                q = self.values[role]
                if q and ts < q[-1][0]:  # late: kept in time order
                    bisect.insort_right(q, (ts, value, bad), key=_stamp)
                else:
                    q.append((ts, value, bad))
        while self.angles:
            ts, a, bad = self.angles[0]
            last = self.angles[-1][0]
            ready = (
                flush
                or len(self.angles) > self.MAX_PENDING
                or all(
                    self.values[r] and self.values[r][-1][0] > ts + self.tol for r in self.others
                )
                or ts + self.wait <= last <= ts + self.clock
                # An angle came stamped before this one: this one is ahead of the clock (the
                # clock's rules decide); waiting for values after it would hold up the rest.
                or last < ts
            )
            if not ready:
                break
            self.angles.popleft()
            if bad:
                out.append((ts, ts, None, None, None, bad))
                continue
            got, why = {}, None
            for r in self.others:
                got[r], w = self._at(r, ts)
                why = why or w
            out.append((ts, ts, a, got.get("speed"), _process_value(self.src, got), why))
        # Bounded memory: of the values before the oldest angle still to come, only the latest
        # is needed (it is the one held); at most MAX_PENDING are kept whatever the server sends.
        upto = min(x[0] for x in self.angles) if self.angles else None
        for q in self.values.values():
            k = bisect.bisect_right(q, upto, key=_stamp) - 1 if upto is not None else 0
            k = max(k, len(q) - self.MAX_PENDING)
            if k > 0:
                del q[:k]
        return out

    def _at(self, role, ts):
        """The value of `role` for an angle stamped `ts`, or (None, why)."""
        q = self.values[role]
        k = bisect.bisect_right(q, ts + self.tol, key=_stamp)
        best = q[k - 1] if k > 0 else None
        if best is None:
            return None, f"no value of {role} at or before the angle's time"
        if best[2]:
            return None, best[2]
        if ts - best[0] > self.hold:
            age = (ts - best[0]).total_seconds()
            return None, f"{role} stale: its last value is {age:.3g} s old (hold_limit)"
        return best[1], None


class _Joiner:
    """Values of the nodes with the same SourceTimestamp make one sample (scalar mode) or one
    block (block mode). A group is complete when every node has given its value; groups left
    incomplete behind a complete one are dropped (a value never came). A group still incomplete
    when a value stamped GROUP_WAIT s later has come, or after GROUP_WAIT s of waiting, is dropped
    and reported while the run goes on; at most MAX_GROUPS wait (docs/plant.md "Sample
    assembly")."""

    GROUP_WAIT = 1.0
    MAX_GROUPS = 2000

    def __init__(self, src: OpcUaSource):
        self.src = src
        self.roles = set(src.roles)
        self.groups: dict = {}
        self.arrived: dict = {}  # group -> monotonic time of its first value
        self.newest = None

    def _check(self, role, dv, block):
        from asyncua import ua

        if not dv.StatusCode.is_good():
            return None, f"status {ua.StatusCode(dv.StatusCode.value).name} on {role}"
        var = dv.Value
        if var is None:
            return None, f"no value on {role}"
        if role == "time":
            if (
                not block
                or not isinstance(var.Value, list)
                or not all(isinstance(x, dt.datetime) for x in var.Value)
            ):
                return None, "the time array is not DateTime[]"
            return var.Value, None
        if var.VariantType not in _numeric_types():
            return None, f"{role} of type {var.VariantType.name}, not a number"
        if block:
            if not isinstance(var.Value, list):
                return None, f"{role} is not an array"
            if any(isinstance(x, list) for x in var.Value):
                return None, f"{role} is an array of more than one dimension"
            return [float(x) for x in var.Value], None
        if isinstance(var.Value, list):
            return None, f"{role} is an array ({len(var.Value)} values), not a number"
        v = float(var.Value)
        if not math.isfinite(v):
            return None, f"{role} not finite ({v})"
        return v, None

    def feed(self, batch, flush=False):
        """(ts, sample time, angle, speed, force, why dropped or None) of completed samples."""
        block = self.src.block
        done = []
        out_now: list = []
        for role, dv in batch:
            if dv.StatusCode.value == _WAITING:
                continue  # the PLC has measured nothing yet: no sample
            ts = dv.SourceTimestamp
            if ts is None:
                # Without a SourceTimestamp a value has no sample time: dropped and counted.
                out_now.append((None, None, None, None, None, f"no SourceTimestamp on {role}"))
                continue
            if ts not in self.groups:
                self.arrived[ts] = time.monotonic()
                self.newest = ts if self.newest is None else max(self.newest, ts)
            g = self.groups.setdefault(ts, {})
            value, bad = self._check(role, dv, block)
            g[role] = value
            if bad:
                g.setdefault("_bad", bad)
            if self.roles <= set(g):
                done.append(ts)
        out = out_now
        if done:
            newest = max(done)
            # Complete groups in the order they completed (the order written), not sorted by
            # stamp: after a step back of the PLC clock, its blocks would otherwise go before
            # the ones written earlier, and the clock's rules would drop those instead
            # (docs/plant.md "Timestamps").
            for ts in done:
                g = self.groups.pop(ts, None)
                if g is not None:
                    out += self._samples(ts, g, g.get("_bad"), block)
            for ts in sorted(t for t in self.groups if t <= newest or flush):
                g = self.groups.pop(ts)
                bad = g.get("_bad")
                if not self.roles <= set(g):
                    bad = bad or "a value never came for " + ", ".join(sorted(self.roles - set(g)))
                out += self._samples(ts, g, bad, block)
        elif flush:
            for ts in sorted(self.groups):
                g = self.groups.pop(ts)
                out += self._samples(ts, g, g.get("_bad") or "incomplete at the end", block)
        # What waits too long is reported now, not at the end (bounded in time and memory).
        now, wait = time.monotonic(), dt.timedelta(seconds=self.GROUP_WAIT)
        for ts in sorted(self.groups):
            if not (
                len(self.groups) > self.MAX_GROUPS
                or ts + wait <= self.newest
                or now - self.arrived[ts] >= self.GROUP_WAIT
            ):
                break
            g = self.groups.pop(ts)
            missing = ", ".join(sorted(self.roles - set(g)))
            hint = " (block arrays stamped at their writes? see source.seq_node)" if block else ""
            out += self._samples(
                ts, g, g.get("_bad") or f"incomplete: no value of {missing} came{hint}", block
            )
        for ts in [t for t in self.arrived if t not in self.groups]:
            del self.arrived[ts]
        return out

    def _samples(self, ts, g, bad, block):
        return _block_samples(self.src, ts, g, bad, block)


def _block_samples(src, ts, g, bad, block):
    """The samples of a group: one (scalar mode), or one per element of the block's arrays."""
    if not block:
        return [(ts, ts, g.get("angle"), g.get("speed"), _process_value(src, g), bad)]
    times = g.get("time") or []
    if bad:
        return [(ts, ts, None, None, None, bad)] * max(1, len(times))
    n = len(times)
    arrays = {r: g[r] for r in ("angle", "speed", "force", *PRESSURE_ROLES) if r in g}
    if any(len(a) != n for a in arrays.values()):
        return [(ts, ts, None, None, None, "arrays of a block differ in length")] * max(1, n)
    out = []
    for i in range(n):
        a = arrays["angle"][i]
        w = arrays["speed"][i] if "speed" in arrays else None
        f = _process_value(src, {r: v[i] for r, v in arrays.items()})
        values = (a, w, *(f if isinstance(f, tuple) else (f,)))
        why = None
        if not all(math.isfinite(x) for x in values if x is not None):
            why = "a value of a block not finite"
        out.append((times[i], times[i], a, w, f, why))
    return out


class _SeqJoiner:
    """Block mode with a counter (source.seq_node; docs/plant.md "Sample assembly"): the PLC
    writes its arrays one after another, each stamped by the server at its write, then the
    counter. A block is the latest value of each array stamped after the previous counter value
    and at or before this one; their SourceTimestamps need not be equal. An array missing from a
    block makes it incomplete (dropped and reported at once); arrays waiting for a counter that
    does not come within GROUP_WAIT s are dropped too; at most MAX_PENDING wait per node."""

    GROUP_WAIT = 1.0
    MAX_PENDING = 1000

    def __init__(self, src: OpcUaSource):
        self.src = src
        self.arrays = [r for r in src.roles if r != "seq"]
        self.pending: dict = {r: [] for r in self.arrays}  # (ts, value, bad, arrived)
        self.counters: collections.deque = collections.deque()  # (ts, value, arrived)
        self.taken_dt = None  # the stamp of the last counter value taken
        self.taken_value = None
        # The writes taken, (role, stamp), bounded: the same write given again by a new
        # subscription or the history is left out, and a write stamped before the last counter
        # (a step back of the PLC clock) is not (docs/plant.md "Timestamps").
        self.taken: set = set()
        self.taken_order: collections.deque = collections.deque()
        self.check = _Joiner(src)._check

    def feed(self, batch, flush=False):
        out = []
        now = time.monotonic()
        for role, dv in batch:
            if dv.StatusCode.value == _WAITING:
                continue
            ts = dv.SourceTimestamp
            if ts is None:
                out.append((None, None, None, None, None, f"no SourceTimestamp on {role}"))
                continue
            if (role, ts) in self.taken:
                continue  # taken already (given again by a new subscription or the history)
            if role == "seq":
                v = dv.Value.Value if dv.Value is not None else None
                if not dv.StatusCode.is_good() or not isinstance(v, int) or isinstance(v, bool):
                    out.append(
                        (
                            ts,
                            ts,
                            None,
                            None,
                            None,
                            f"the block counter is not a whole number ({v!r})",
                        )
                    )
                    continue
                if all(c[0] != ts for c in self.counters):
                    # In the order written, each write once: after a step back of the PLC clock
                    # a counter value is stamped before the previous one.
                    self.counters.append((ts, v, now))
                continue
            value, bad = self.check(role, dv, True)
            q = self.pending[role]
            k = bisect.bisect_left(q, ts, key=_stamp)
            if k < len(q) and q[k][0] == ts:
                continue  # the same write again (the history, then the subscription)
            q.insert(k, (ts, value, bad, now))
        while self.counters:
            cts, cv, arrived = self.counters[0]
            # The block's arrays: stamped after the previous counter value taken and at or
            # before this one; after a step back (this one stamped before the previous), at or
            # before this one.
            prev_dt = self.taken_dt
            group, extra, window = {}, [], {}
            for r in self.arrays:
                q = self.pending[r]
                k = bisect.bisect_right(q, cts, key=_stamp)
                lo = bisect.bisect_right(q, prev_dt, key=_stamp) if prev_dt and prev_dt < cts else 0
                window[r] = (lo, k)
                if k > lo:
                    group[r] = q[k - 1]
                    extra += [(r, x) for x in q[lo : k - 1]]
            complete = len(group) == len(self.arrays)
            if not (
                complete or flush or len(self.counters) > 1 or now - arrived >= self.GROUP_WAIT
            ):
                break  # the arrays written before this counter value may still be on their way
            self.counters.popleft()
            for r in self.arrays:
                lo, k = window[r]
                del self.pending[r][lo:k]
            for key in [("seq", cts), *((r, x[0]) for r, x in group.items())]:
                self.taken.add(key)
                self.taken_order.append(key)
            while len(self.taken_order) > 50000:
                self.taken.discard(self.taken_order.popleft())
            for r, x in extra:
                # An array written twice before the counter moved: the earlier value is lost.
                n = len(x[1]) if r == "time" and isinstance(x[1], list) else 1
                why = f"block overwritten before the counter moved ({r} written twice)"
                out += [(x[0], x[0], None, None, None, why)] * n
            prev, self.taken_value, self.taken_dt = self.taken_value, cv, cts
            g = {r: x[1] for r, x in group.items()}
            bad = next((x[2] for x in group.values() if x[2]), None)
            if not complete:
                missing = ", ".join(r for r in self.arrays if r not in group)
                bad = bad or (
                    f"incomplete block: no {missing} array written before counter value {cv}"
                )
            if prev is not None and cv != (prev + 1) % 2**32 and cv != prev + 1:
                self.src.log(
                    f"OPC UA source {self.src.s['endpoint']}: block counter went from {prev} to "
                    f"{cv}: the blocks between were not received"
                )
            out += _block_samples(self.src, cts, g, bad, True)
        # Arrays that no counter value claims within GROUP_WAIT s: dropped and reported now.
        for r in self.arrays:
            q = self.pending[r]
            while q and (
                flush
                or len(q) > self.MAX_PENDING
                or (now - q[0][3] >= self.GROUP_WAIT and not self.counters)
            ):
                ts, v, _bad, _a = q.pop(0)
                n = len(v) if r == "time" and isinstance(v, list) else 1
                why = f"block {r} array with no counter change (seq_node) within {self.GROUP_WAIT:g} s"
                out += [(ts, ts, None, None, None, why)] * n
        return out
