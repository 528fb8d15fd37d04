"""Alarms written back to OPC UA nodes that the PLC or SCADA reads (docs/page.md, "Alarms to
OPC UA"): one Boolean node per alarm, True while it is active.

    nodes = AlarmNodes("opc.tcp://plc:4840", {"crank torque high": "ns=2;s=Twin.TorqueHigh"})
    nodes.start()
    page = PageServer(..., on_alarm=lambda ch: (log(ch), nodes(ch)))
    ...
    nodes.close()

With asyncua (the OPC UA library the twin's source uses), on a thread of its own: the twin's
thread only records the state wanted (`__call__`), never waits for the network. The writer
connects, writes every node whose wanted state it has not written yet, and on a lost connection
retries with a doubling back-off (up to `retry_max` s); the first failure of a series is reported
once through `log` (one line, without the password). A node whose write is refused (wrong id, not
writable, wrong type) is reported once and not tried again.

Layer: workflows, the page (docs/architecture.md).
"""

from __future__ import annotations

import asyncio
import threading

from asyncua import Client, ua


class AlarmNodes:
    def __init__(
        self,
        endpoint: str,
        nodes: dict,
        username: str | None = None,
        password: str | None = None,
        log=None,
        timeout: float = 5.0,
        retry_max: float = 10.0,
    ):
        self.endpoint, self.nodes = endpoint, dict(nodes)
        self.username, self.password = username, password
        self.log = log or (lambda m: None)
        self.timeout, self.retry_max = timeout, retry_max
        self._wanted: dict = {name: False for name in self.nodes}  # all clear at the start
        self._written: dict = {}
        self._refused: set = set()
        self._lock = threading.Lock()
        self._wake = threading.Event()
        self._stop = threading.Event()
        self._thread = None
        self.writes = 0  # node writes done (for the tests and the health page)

    def __call__(self, change) -> None:
        """An `alarms.AlarmChange`; alarms without a node are ignored."""
        if change.name in self.nodes:
            with self._lock:
                self._wanted[change.name] = change.state == "raised"
            self._wake.set()

    def start(self) -> AlarmNodes:
        self._thread = threading.Thread(target=self._run, name="alarm-nodes", daemon=True)
        self._thread.start()
        return self

    def close(self, timeout: float = 10.0) -> None:
        """Stops after writing what is wanted (bounded by `timeout`)."""
        self._stop.set()
        self._wake.set()
        if self._thread is not None:
            self._thread.join(timeout)

    def pending(self) -> dict:
        with self._lock:
            return {
                k: v
                for k, v in self._wanted.items()
                if self._written.get(k) != v and k not in self._refused
            }

    def _run(self) -> None:
        asyncio.run(self._main())

    async def _main(self) -> None:
        delay, failing = 0.2, False
        while True:
            todo = self.pending()
            if not todo and self._stop.is_set():
                return
            if todo:
                try:
                    await self._write(todo)
                    delay, failing = 0.2, False
                except (TimeoutError, OSError, ua.UaError) as e:
                    if not failing:
                        self.log(
                            f"alarm nodes: {self.endpoint}: cannot write ({type(e).__name__}: "
                            f"{str(e).splitlines()[0] if str(e) else ''}); retrying"
                        )
                    failing = True
                    if self._stop.is_set():
                        return  # closing: what could not be written is reported above
                    await asyncio.sleep(delay)
                    delay = min(2 * delay, self.retry_max)
                    continue
            await asyncio.get_running_loop().run_in_executor(None, self._wake.wait, 1.0)
            self._wake.clear()

    async def _write(self, todo: dict) -> None:
        client = Client(self.endpoint, timeout=self.timeout)
        if self.username:
            client.set_user(self.username)
            client.set_password(self.password or "")
        async with asyncio.timeout(self.timeout * 2):
            await client.connect()
        try:
            # Alarms are rare: one connection per batch of changes, closed after it.
            while todo:
                for name, active in todo.items():
                    node = client.get_node(self.nodes[name])
                    value = ua.DataValue(ua.Variant(active, ua.VariantType.Boolean))
                    try:
                        await node.write_value(value)
                    except ua.UaStatusCodeError as e:
                        self._refused.add(name)
                        self.log(
                            f"alarm nodes: {self.nodes[name]} (alarm {name!r}): write refused: "
                            f"{type(e).__name__}; not tried again"
                        )
                        continue
                    with self._lock:
                        self._written[name] = active
                    self.writes += 1
                todo = self.pending()
        finally:
            try:
                async with asyncio.timeout(self.timeout):
                    await client.disconnect()
            except Exception:  # noqa: BLE001 - the connection may be gone already
                pass
