"""The twin's live page (docs/page.md): a Tornado web server on its own thread, fed like a sink.

    page = PageServer(host="127.0.0.1", port=8050, database="twin.sqlite", limits=limits)
    page.start()                                   # PageError (one line) for a port in use, ...
    page.open(outputs=twin.outputs, time_origin=t0)
    page.add(rows, first_seq, summaries, first_rev, events)   # as the plant sinks get them
    page.health(connected=True)
    page.close()

Tornado: an asynchronous web server that is already among the project's dependencies (Dask's
distributed runs on it), well kept, with server-sent events through a plain streaming response.
The browser side is three static files and uPlot (MIT, vendored from the npm registry with its
licence in static/): every asset comes from the twin itself, nothing from the internet.

The twin's thread only appends to a queue under a lock (`add`); the server's thread takes it every
`FLUSH` seconds, keeps the state the page shows and pushes what is new to the open pages as
server-sent events. So the twin never waits for a browser, and a completed revolution is on the
page within FLUSH plus the network's delay.

Access (docs/page.md, "Access"): bound to 127.0.0.1 by default. Bound to any other address, and
127.0.0.2 counts as another address, the server refuses to start without an access token, and then
every request must carry it: an `Authorization: Bearer` header, or the HttpOnly cookie of a session
opened by the login form (the token is posted once, never put in a URL). Without it: 401 and a
login form, no data. The page is read-only: no request changes the twin.

Layer: workflows, the page (docs/architecture.md).
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import errno
import hmac
import json
import logging
import math
import secrets
import sqlite3
import threading
import time
from collections import OrderedDict, deque
from pathlib import Path

import numpy as np
import tornado.escape
import tornado.httpserver
import tornado.ioloop
import tornado.iostream
import tornado.netutil
import tornado.web

from ..alarms import UNITS, AlarmEngine, Limits, derived_values
from .history import TREND_SQL, History, HistoryError

STATIC = Path(__file__).parent / "static"
FLUSH = 0.1  # s between two pushes to the pages (bounds both the latency and the server's work)
LOOPBACK = "127.0.0.1"
COOKIE = "rd_page_session"
SESSION_LIFE = 86400.0  # s: a login lasts a day (sessions live in memory: a restart ends them)
#: Wrong logins: at most LOGIN_TRIES per client address in LOGIN_WINDOW seconds; beyond, 429 with
#: Retry-After, the token not even compared (docs/page.md "Access").
LOGIN_TRIES, LOGIN_WINDOW = 5, 60.0
#: Refused requests logged: at most LOG_LINES in LOG_WINDOW seconds, then one line with how many
#: were left out. A line names the status, method, path (never the query string) and client.
LOG_LINES, LOG_WINDOW = 10, 60.0
#: The page's own logger, not tornado's "tornado.access": Dask (imported by the sweeps and the
#: distributed replay in the same process) configures "tornado" at CRITICAL, which would silence it.
ACCESS_LOG = logging.getLogger("reciprocating_drive.page.access")
#: The values of the last revolution the page shows, in its order (units: alarms.UNITS).
SHOWN = tuple(TREND_SQL)
LABELS = {
    "strokes_per_minute": "strokes per minute",
    "speed_fluctuation": "speed fluctuation",
    "crank_torque_peak": "peak crank torque",
    "rod_force_largest": "largest rod force",
    "friction_work": "friction work",
    "rod_angle_amplitude": "rod angle amplitude ϑ (elastic rod)",
    "stress_max": "largest rod stress",
    "flow_mean": "mean flow (pump)",
    "flow_pulsation": "flow pulsation (pump)",
    "hydraulic_power_mean": "mean hydraulic power (pump)",
    "mechanical_power_mean": "mean mechanical power",
}
#: The plant's machine-state events (docs/plant.md "Machine states") and the state each enters.
MACHINE_EVENTS = {
    "machine_stopped": "stopped",
    "machine_started": "running",
    "machine_reversed": "reversing",
}

#: A rigid rod (rod.kind 0) has no stress of its own and no cage angle: its ϑ is the crank-slider's
#: swing of the rod, named as such, and the stress (0) is not shown (docs/page.md, "What the page
#: shows").
RIGID_LABELS = {**LABELS, "rod_angle_amplitude": "rod swing amplitude (rigid rod)"}
RIGID_HIDDEN = ("stress_max",)
#: A pump's values (docs/page.md): shown only for a machine known to be a pump (its process force
#: from the pressures, load.profile 3, or more than one cylinder): every machine computes a
#: flow, which means nothing without one.
PUMP_VALUES = ("flow_mean", "flow_pulsation", "hydraulic_power_mean", "mechanical_power_mean")
#: Units as an operator reads them: the speed fluctuation, a ratio, in percent (the page scales
#: it; `data-value` and the trend data stay the summary's SI number).
SHOWN_UNITS = {**UNITS, "speed_fluctuation": "%"}
CARDS = 6  # revolutions kept for the card: the last over the previous ones
CARD_POINTS = 720  # points of one card at most (decimated)
MEMORY = 200_000  # revolutions kept for the trends when there is no database
ALARMS = 500  # alarm list entries kept (the database keeps them all)


class PageError(RuntimeError):
    """The page cannot start (one line: the address, the port, what to do)."""


def _clean(v):
    """JSON has no NaN or infinity: a missing or non-finite value is null."""
    if v is None:
        return None
    v = float(v)
    return v if math.isfinite(v) else None


class _State:
    """What the page shows; touched only on the server's thread."""

    def __init__(self, limits: Limits | None):
        self.limits = limits
        self.last: dict | None = None
        self.cards: deque = deque(maxlen=CARDS)
        self.trend: deque = deque(maxlen=MEMORY)
        self.alarms: OrderedDict = OrderedDict()  # key -> entry (newest last)
        self.health = {
            "connected": None,
            "lag": None,
            "gaps": 0,
            "dropped": 0,
            "fmu_errors": 0,
            "last_sample_time": None,
            "last_event": None,
            "run_status": None,
            "run_message": None,
            "ended": False,
            # The machine's state from its events (docs/twin.md "Machine states"): None before
            # the first, else {"state": running|stopped|reversing, "since": twin time [s]}.
            "machine": None,
        }
        self.time_origin = None
        self.revolutions = 0
        self.elastic = None  # None: the rod is not known (a followed database), both are shown
        self.pump = None  # True: a pump, whose values are shown

    def shown(self) -> tuple:
        return tuple(
            k
            for k in SHOWN
            if not (self.elastic is False and k in RIGID_HIDDEN)
            and (self.pump is True or k not in PUMP_VALUES)
        )

    def snapshot(self) -> dict:
        lim = {
            k: (self.limits.for_value(k) if self.limits else {"high": None, "low": None})
            for k in SHOWN
        }
        labels = RIGID_LABELS if self.elastic is False else LABELS
        return {
            "values": [
                {"key": k, "label": labels[k], "unit": SHOWN_UNITS[k]} for k in self.shown()
            ],
            "elastic": self.elastic,
            "limits": lim,
            "last": self.last,
            "cards": list(self.cards),
            "alarms": list(self.alarms.values()),
            "health": self.health,
            "time_origin": self.time_origin,
            "revolutions": self.revolutions,
        }


class PageServer:
    def __init__(
        self,
        host: str = LOOPBACK,
        port: int = 8050,
        token: str | None = None,
        database: str | None = None,
        run: str | None = None,
        limits: Limits | None = None,
        title: str = "ReciprocatingDrive twin",
        on_alarm=None,
    ):
        """`token`: required when `host` is not 127.0.0.1 (read it from a file or an environment
        variable, never from a command line). `database`: the twin's SQLite file, for the
        trends. `limits`: the alarms to evaluate on each revolution; `on_alarm(change)` is called
        on the twin's thread for each alarm raised or cleared (to log it and write it to the
        database)."""
        if host != LOOPBACK and not token:
            raise PageError(
                f"page: bound to {host}, which is not {LOOPBACK}: an access token is required "
                "(page.token_file, or the environment variable RD_PAGE_TOKEN)"
            )
        if token is not None and (len(token) < 16 or token.strip() != token):
            raise PageError(
                "page: the access token must have at least 16 characters and no surrounding blanks"
            )
        self.host, self.port, self.token = host, port, token
        self.database, self.run = database, run
        #: Writes the outputs of a time range, recomputed, to a CSV file: `recompute(t0, t1, path)`,
        #: raising RangeUnavailable (one line) when it cannot; set by whoever knows the run's
        #: stored input (the plant, docs/plant.md "Recomputing a range"). None: no range form.
        self.recompute = None
        self.limits = limits
        self.engine = AlarmEngine(limits) if limits is not None else None
        self.on_alarm = on_alarm
        self.title = title
        self._lock = threading.Lock()
        self._pending: list = []
        self._outputs: list | None = None
        self._cols = None
        self._card: list = []  # pieces of the revolution in progress: (angle, position, force)
        self._card_index = None
        self._thread = None
        self._loop = None
        self.state = _State(limits)
        self._clients: set = set()
        self.sessions: OrderedDict = OrderedDict()
        self._wrong_logins: OrderedDict = OrderedDict()  # client address -> deque of times
        self._log_start, self._log_lines, self._log_left_out = -math.inf, 0, 0
        self.native_thread_id = None
        # Database reads on a thread of their own (SQLite connections stay on the thread that
        # made them), so a long window's query never holds up the pushes to the pages.
        self._reader = concurrent.futures.ThreadPoolExecutor(1, thread_name_prefix="twin-page-db")
        self._history = None
        #: True for the page that follows a database written by another process (page/follow.py):
        #: a database it cannot read is then an error, not a run that has not started yet.
        self.follows = False

    # ---- life -----------------------------------------------------------------------------------
    def start(self) -> PageServer:
        try:
            # Bound here, on the caller's thread, so that a port in use is an error of start().
            sockets = tornado.netutil.bind_sockets(self.port, address=self.host, reuse_port=False)
        except OSError as e:
            if e.errno == errno.EADDRINUSE:
                raise PageError(
                    f"page: port {self.port} on {self.host} is in use (another page or program); "
                    "choose another port (page.port)"
                ) from None
            raise PageError(
                f"page: cannot listen on {self.host}:{self.port}: {e.strerror}"
            ) from None
        self.port = sockets[0].getsockname()[1]
        ready = threading.Event()

        def serve():
            asyncio.set_event_loop(asyncio.new_event_loop())
            self._loop = tornado.ioloop.IOLoop.current()
            self.native_thread_id = threading.get_native_id()
            server = tornado.httpserver.HTTPServer(self._app(), xheaders=False)
            server.add_sockets(sockets)
            tornado.ioloop.PeriodicCallback(self._flush, FLUSH * 1000).start()
            self._server = server
            ready.set()
            self._loop.start()
            server.stop()
            self._loop.close(all_fds=True)

        self._thread = threading.Thread(target=serve, name="twin-page", daemon=True)
        self._thread.start()
        if not ready.wait(10):
            raise PageError("page: the server thread did not start within 10 s")
        return self

    @property
    def url(self) -> str:
        return f"http://{self.host}:{self.port}/"

    def close(self, timeout: float = 5.0) -> None:
        if self._loop is None:
            return

        def stop():
            # What is still queued (the run's end, its last revolutions) reaches the pages
            # before they are told that the server stops: they then stop listening instead of
            # trying to reconnect.
            self._flush()
            bye = json.dumps({"closed": True})
            for q in list(self._clients):
                q.put_nowait(bye)
                q.put_nowait(None)
            self._loop.call_later(0.05, self._loop.stop)

        self._loop.add_callback(stop)
        self._thread.join(timeout)
        self._loop = None
        # The trends' read-only connection is closed on the thread that made it: an open reader
        # would keep the twin's database from being checkpointed when its sink closes.
        if self._history is not None:
            try:
                self._reader.submit(self._history.close).result(timeout)
            except Exception:  # noqa: BLE001 - a database already gone: nothing left to close
                pass
            self._history = None
        self._reader.shutdown(wait=False, cancel_futures=True)

    # ---- the sink side (any thread) -------------------------------------------------------------
    def open(
        self,
        outputs,
        time_origin: float | None = None,
        elastic: bool | None = None,
        pump: bool | None = None,
    ) -> None:
        """The FMU's outputs (the columns after time of the rows handed to `add`), the Unix
        time of the twin's time 0 (None when the source has no clock: file replay; a live source
        whose clock is known only from its first sample hands it later to `clock`), and whether
        the rod is elastic (rod.kind != 0; False hides what a rigid rod does not have, None: not
        known), and whether it is a pump (True shows its flow and powers)."""
        self._outputs = list(outputs)
        self._cols = tuple(
            1 + self._outputs.index(n)
            for n in ("crank.model_angle", "suspension.position", "rod.force")
        )
        with self._lock:
            self._pending.append(("origin", time_origin))
            self._pending.append(("elastic", elastic))
            self._pending.append(("pump", pump))
            self._pending.append(("health", {"run_status": "running"}))

    def clock(self, time_origin: float | None) -> None:
        """The Unix time of the twin's time 0, once the source knows it (an OPC UA source: from
        its first sample's timestamp): the page switches to clock times."""
        with self._lock:
            self._pending.append(("origin", time_origin))

    def end(self, status: str, message: str | None = None) -> None:
        """The run is over (`status`: finished, failed, stopped): the page says so, with the
        failure's message, and the source is no longer watched."""
        end = {"run_status": status, "run_message": message, "connected": None, "ended": True}
        with self._lock:
            self._pending.append(("health", end))

    def add(self, rows, first_seq=0, summaries=(), first_rev=0, events=()) -> None:
        """What the twin produced: rows (time, outputs), revolution summaries and data-health
        events (`(seq, wall_time, Event)` or Event). The alarms are evaluated here, on the
        caller's thread, so `on_alarm` sees them in the order of the revolutions."""
        items = []
        if rows is not None and len(rows) and self._cols is not None:
            items += self._cards(np.asarray(rows))
            items.append(("sample_time", float(rows[-1, 0]), time.time()))
        elif summaries:
            # No rows (a page following a database without per-sample rows): the last
            # revolution's end, start + 2π/mean speed (revolution.py: mean_speed = 2π/duration).
            s = summaries[-1]
            end = _clean(s.get("start_time"))
            w = _clean(s.get("mean_speed"))
            if end is not None and w:
                items.append(("sample_time", end + 2 * math.pi / w, time.time()))
        for s in summaries:
            items.append(("rev", dict(s)))
            if self.engine is not None:
                for ch in self.engine.update(s):
                    items.append(("alarm", ch.to_dict(), time.time()))
                    if self.on_alarm is not None:
                        self.on_alarm(ch)
        for ev in events:
            ev = ev[2] if isinstance(ev, tuple) else ev
            items.append(("event", ev.kind, ev.count, ev.message, time.time()))
            if ev.kind in MACHINE_EVENTS:
                items.append(("machine", MACHINE_EVENTS[ev.kind], getattr(ev, "t", None)))
        if items:
            with self._lock:
                self._pending += items

    def health(self, **kw) -> None:
        """Source state: connected (bool), lag (s) and any other of the health fields."""
        with self._lock:
            self._pending.append(("health", kw))

    def commit(self, *_args, **_kw) -> None:
        """A sink's commit: the page keeps nothing durable."""

    def _cards(self, rows: np.ndarray) -> list:
        """Splits the rows into revolutions of the model angle (the card of each one completed)."""
        ia, ix, iy = self._cols
        k = np.floor(rows[:, ia] / (2 * np.pi))
        out = []
        cuts = np.flatnonzero(np.diff(k)) + 1
        for piece in np.split(np.arange(len(rows)), cuts):
            if not len(piece):
                continue
            idx = int(k[piece[0]])
            if self._card_index is not None and idx != self._card_index and self._card:
                out.append(("card", self._card_index, self._finish_card()))
            self._card_index = idx
            self._card.append(rows[piece][:, (ix, iy)])
        return out

    def _finish_card(self) -> dict:
        xy = np.concatenate(self._card)
        self._card = []
        step = max(1, math.ceil(len(xy) / CARD_POINTS))
        xy = xy[::step]
        return {"x": xy[:, 0].tolist(), "y": xy[:, 1].tolist()}

    # ---- the server's thread --------------------------------------------------------------------
    def _flush(self) -> None:
        with self._lock:
            items, self._pending = self._pending, []
        if not items:
            return
        st = self.state
        push: dict = {"revs": [], "alarms": []}
        for it in items:
            kind = it[0]
            if kind == "rev":
                s = it[1]
                v = derived_values(s)
                entry = {
                    "revolution": s.get("revolution"),
                    "t": _clean(s.get("start_time")),
                    **{k: _clean(v.get(k)) for k in st.shown()},
                }
                st.last = entry
                st.trend.append(entry)
                st.revolutions += 1
                push["revs"].append(entry)
            elif kind == "card":
                card = {"index": it[1], **it[2]}
                st.cards.append(card)
                push["card"] = card
            elif kind == "alarm":
                ch, wall = it[1], it[2]
                key = ch["name"]
                if ch["state"] == "raised":
                    st.alarms[f"{key}@{ch['revolution']}"] = {
                        "name": key,
                        "severity": ch["severity"],
                        "message": ch["message"],
                        "raised": _clean(ch["t"]),
                        "raised_wall": wall,
                        "cleared": None,
                        "cleared_wall": None,
                    }
                else:
                    for e in reversed(st.alarms.values()):
                        if e["name"] == key and e["cleared"] is None:
                            e["cleared"], e["cleared_wall"] = _clean(ch["t"]), wall
                            e["clear_message"] = ch["message"]
                            break
                while len(st.alarms) > ALARMS:
                    st.alarms.popitem(last=False)
                push["alarms"] = list(st.alarms.values())
            elif kind == "event":
                _, ek, count, msg, wall = it
                h = st.health
                if ek == "gap":
                    h["gaps"] += count
                elif ek in ("dropped", "bad_sample"):
                    h["dropped"] += count
                elif ek == "fmu_error":
                    h["fmu_errors"] += count
                elif ek in ("disconnected", "connection_lost"):
                    h["connected"] = False
                elif ek in ("connected", "reconnected", "reconnect"):
                    h["connected"] = True
                h["last_event"] = {"kind": ek, "message": msg, "wall": wall}
                push["health"] = h
            elif kind == "machine":
                st.health["machine"] = {"state": it[1], "since": it[2]}
                push["health"] = st.health
            elif kind == "sample_time":
                t, wall = it[1], it[2]
                st.health["last_sample_time"] = t
                if st.time_origin is not None:
                    st.health["lag"] = wall - (st.time_origin + t)
                push["health"] = st.health
            elif kind == "health":
                st.health.update({k: v for k, v in it[1].items() if k in st.health})
                push["health"] = st.health
            elif kind == "origin":
                if it[1] != st.time_origin:
                    st.time_origin = it[1]
                    if st.health["last_sample_time"] is not None and it[1] is not None:
                        st.health["lag"] = time.time() - (it[1] + st.health["last_sample_time"])
                    push["origin"] = it[1]
                    push["health"] = st.health
            elif kind == "pump":
                if it[1] != st.pump:
                    st.pump = it[1]
                    push["values"] = st.snapshot()["values"]
            elif kind == "elastic":
                if it[1] != st.elastic:
                    # The rod known (the twin made): the values it has, under their names.
                    st.elastic = it[1]
                    push["values"] = st.snapshot()["values"]
        if not push["alarms"]:
            del push["alarms"]
        msg = json.dumps(push, allow_nan=False)
        for q in list(self._clients):
            if q.qsize() > 100:  # a page that stopped reading: drop it, it reloads its state
                q.put_nowait(None)
                self._clients.discard(q)
            else:
                q.put_nowait(msg)

    # ---- access ---------------------------------------------------------------------------------
    def authorized(self, handler: tornado.web.RequestHandler) -> bool:
        if self.token is None:
            return True
        auth = handler.request.headers.get("Authorization", "")
        if auth.startswith("Bearer ") and hmac.compare_digest(
            auth[7:].encode(), self.token.encode()
        ):
            return True
        sid = handler.get_cookie(COOKIE)
        opened = self.sessions.get(sid) if sid is not None else None
        return opened is not None and time.time() - opened < SESSION_LIFE

    def trend_from_database(self, window: float) -> dict:
        """On the reader thread."""
        if self._history is None:
            self._history = History(self.database, self.run)
        return self._history.trend(window)

    def new_session(self) -> str:
        sid = secrets.token_urlsafe(32)
        self.sessions[sid] = time.time()
        while len(self.sessions) > 1000:
            self.sessions.popitem(last=False)
        return sid

    def login_wait(self, client: str) -> float:
        """Seconds until `client` may try to log in again (0: now)."""
        tries = self._wrong_logins.get(client)
        now = time.monotonic()
        while tries and now - tries[0] >= LOGIN_WINDOW:
            tries.popleft()
        if not tries or len(tries) < LOGIN_TRIES:
            return 0.0
        return LOGIN_WINDOW - (now - tries[0])

    def wrong_login(self, client: str) -> None:
        self._wrong_logins.setdefault(client, deque()).append(time.monotonic())
        self._wrong_logins.move_to_end(client)
        while len(self._wrong_logins) > 10000:  # bounded memory whatever the clients
            self._wrong_logins.popitem(last=False)

    def log_request(self, handler: tornado.web.RequestHandler) -> None:
        """Tornado's access log, replaced: only refused or failed requests (status >= 400), by
        path without the query string (a token put in a URL is never written), at most LOG_LINES
        per LOG_WINDOW seconds (a flood of wrong requests cannot fill the log)."""
        status = handler.get_status()
        if status < 400:
            return
        now = time.monotonic()
        if now - self._log_start >= LOG_WINDOW:
            if self._log_left_out:
                ACCESS_LOG.warning(
                    "page: %d more refused requests in %g s not logged",
                    self._log_left_out,
                    LOG_WINDOW,
                )
            self._log_start, self._log_lines, self._log_left_out = now, 0, 0
        if self._log_lines >= LOG_LINES:
            self._log_left_out += 1
            return
        self._log_lines += 1
        r = handler.request
        ACCESS_LOG.warning("page: %d %s %s (%s)", status, r.method, r.path, r.remote_ip)

    def _app(self) -> tornado.web.Application:
        args = {"page": self}
        return tornado.web.Application(
            [
                (r"/", _Index, args),
                (r"/login", _Login, args),
                (r"/api/state", _StateApi, args),
                (r"/api/trend", _TrendApi, args),
                (r"/api/range", _RangeApi, args),
                (r"/stream", _Stream, args),
                (r"/favicon.ico", _NoIcon, args),
                (r"/static/(.*)", _Static, {"path": str(STATIC), "page": self}),
            ],
            compress_response=True,
            log_function=self.log_request,
        )


LOGIN = """<!doctype html><html lang="en"><head><meta charset="utf-8"><title>Log in</title>
<link rel="stylesheet" href="/static/login.css"></head><body><form method="post" action="/login">
<h1>Twin page</h1><p>{note}</p><label>Access token <input type="password" name="token"
autocomplete="current-password" autofocus></label> <button type="submit">Log in</button></form>
</body></html>"""


class _Base(tornado.web.RequestHandler):
    def initialize(self, page: PageServer, **_kw):
        self.page = page

    def set_default_headers(self):
        # Everything from this server only (no inline script), not framed, nothing cached.
        self.set_header(
            "Content-Security-Policy",
            "default-src 'self'; style-src 'self' 'unsafe-inline'; img-src 'self' data:; "
            "frame-ancestors 'none'; form-action 'self'",
        )
        self.set_header("X-Frame-Options", "DENY")
        self.set_header("X-Content-Type-Options", "nosniff")
        self.set_header("Referrer-Policy", "no-referrer")
        self.set_header("Cache-Control", "no-store")

    def prepare(self):
        if not self.page.authorized(self):
            self.set_status(401)
            self.set_header("WWW-Authenticate", 'Bearer realm="twin page"')
            if self.request.path == "/":
                self.finish(LOGIN.format(note="An access token is required."))
            else:
                self.finish("401: an access token is required\n")

    def check_xsrf_cookie(self):
        """The only POST is the login; its cookie is SameSite=Strict, and nothing changes state."""

    def write_error(self, status_code, **kw):
        self.finish(f"{status_code}: {self._reason}\n")


class _Index(_Base):
    def get(self):
        html = (STATIC / "index.html").read_text(encoding="utf-8")
        self.set_header("Content-Type", "text/html; charset=utf-8")
        self.finish(html.replace("{{title}}", tornado.escape.xhtml_escape(self.page.title)))


class _Login(_Base):
    def prepare(self):
        """The login form itself needs no session."""

    def get(self):
        self.redirect("/")

    def post(self):
        client = self.request.remote_ip or "?"
        wait = self.page.login_wait(client)
        if wait > 0:
            self.set_status(429)
            self.set_header("Retry-After", str(math.ceil(wait)))
            self.finish(LOGIN.format(note=f"Too many wrong tokens: try again in {wait:.0f} s."))
            return
        given = self.get_body_argument("token", "")
        tok = self.page.token
        if tok is None or not hmac.compare_digest(given.encode(), tok.encode()):
            self.page.wrong_login(client)
            self.set_status(401)
            self.finish(LOGIN.format(note="Wrong access token."))
            return
        self.set_cookie(COOKIE, self.page.new_session(), httponly=True, samesite="Strict")
        self.redirect("/", status=303)


class _StateApi(_Base):
    def get(self):
        self.set_header("Content-Type", "application/json")
        self.finish(json.dumps(self.page.state.snapshot(), allow_nan=False))


class _TrendApi(_Base):
    async def get(self):
        try:
            window = float(self.get_query_argument("window", "3600"))
            if not (math.isfinite(window) and 0 < window <= 366 * 86400):
                raise ValueError
        except ValueError:
            self.set_status(400)
            self.finish("400: window must be a number of seconds in (0, 31622400]\n")
            return
        page = self.page
        source = "memory"
        data = None
        if page.database:
            try:
                data = await asyncio.wrap_future(
                    page._reader.submit(page.trend_from_database, window)
                )
                source = "database"
            except (HistoryError, sqlite3.Error) as e:
                if not page.follows:
                    # The twin serves its page before its sink has made the database or the
                    # run (a fresh run): what the page got so far, from memory.
                    source = "memory (no run in the database yet)"
                else:
                    why = str(e) if isinstance(e, HistoryError) else f"{page.database}: {e}"
                    self.set_status(503)
                    self.finish(f"503: {why}\n")
                    return
        if data is None:
            rev = list(page.state.trend)
            if rev:
                t0 = rev[-1]["t"] - window
                rev = [r for r in rev if r["t"] is not None and r["t"] >= t0]
            data = {"t": [r["t"] for r in rev], **{k: [r.get(k) for r in rev] for k in SHOWN}}
        data = {k: [_clean(v) for v in vals] for k, vals in data.items()}
        self.set_header("Content-Type", "application/json")
        self.finish(json.dumps({"source": source, "window": window, **data}, allow_nan=False))


class RangeUnavailable(RuntimeError):
    """A range the page's `recompute` cannot give (one line: the run, the range, why)."""


class _RangeApi(_Base):
    """Every output of a time range at full resolution, recomputed from the run's stored input
    (docs/plant.md "Recomputing a range"), as CSV: `?from=T0&to=T1` in s of the run's time, at
    most RANGE_MAX s (a response of tens of MB)."""

    RANGE_MAX = 60.0

    async def get(self):
        try:
            t0 = float(self.get_query_argument("from"))
            t1 = float(self.get_query_argument("to"))
            if not (math.isfinite(t0) and math.isfinite(t1) and 0 <= t1 - t0 <= self.RANGE_MAX):
                raise ValueError
        except (ValueError, tornado.web.MissingArgumentError):
            self.set_status(400)
            self.finish(
                f"400: from and to must be seconds of the run, to - from in [0, {self.RANGE_MAX:g}]\n"
            )
            return
        if self.page.recompute is None:
            self.set_status(404)
            self.finish("404: this page has no database to recompute from\n")
            return

        def make():
            import tempfile

            with tempfile.NamedTemporaryFile(suffix=".csv") as f:
                self.page.recompute(t0, t1, f.name)
                return open(f.name, "rb").read()

        try:
            body = await asyncio.wrap_future(self.page._reader.submit(make))
        except RangeUnavailable as e:
            self.set_status(404)
            self.finish(f"404: {e}\n")
            return
        self.set_header("Content-Type", "text/csv; charset=utf-8")
        self.set_header(
            "Content-Disposition", f'attachment; filename="{self.page.run}-{t0:g}-{t1:g}.csv"'
        )
        self.finish(body)


class _Stream(_Base):
    """Server-sent events: one JSON message per flush with something new."""

    async def get(self):
        self.set_header("Content-Type", "text/event-stream")
        q: asyncio.Queue = asyncio.Queue()
        self.page._clients.add(q)
        try:
            self.write("retry: 1000\n\n")
            await self.flush()
            while True:
                try:
                    msg = await asyncio.wait_for(q.get(), 15.0)
                except TimeoutError:
                    msg = ""  # a comment line keeps proxies from closing an idle stream
                if msg is None:
                    break
                self.write(f"data: {msg}\n\n" if msg else ": keep-alive\n\n")
                await self.flush()
        except tornado.iostream.StreamClosedError:
            pass
        finally:
            self.page._clients.discard(q)


class _NoIcon(_Base):
    def get(self):
        self.set_status(204)
        self.finish()


class _Static(tornado.web.StaticFileHandler):
    def initialize(self, path, page):
        super().initialize(path)
        self.page = page

    def set_extra_headers(self, path):
        self.set_header("X-Content-Type-Options", "nosniff")

    def prepare(self):
        # The login form's stylesheet is the one asset served without a session.
        if self.request.path != "/static/login.css" and not self.page.authorized(self):
            self.set_status(401)
            self.finish("401: an access token is required\n")
