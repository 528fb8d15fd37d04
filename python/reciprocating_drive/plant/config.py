"""The twin's configuration file (docs/plant.md, "Configuration"): TOML, read with the standard
library's tomllib, checked key by key. Every mistake is one line naming the file, the key, the
value and what is allowed (`ConfigError`).

Layer: workflows, the plant (docs/architecture.md).
"""

from __future__ import annotations

import math
import os
import pathlib
import re
from dataclasses import dataclass, field

from .. import artifacts
from ..cli_errors import read_toml
from ..presets import available_presets


class ConfigError(ValueError):
    pass


_MISSING = object()
MIN_PACE, MAX_PACE = 1e-3, 1e6  # source.pace: multiples of real time (docs/plant.md "Sources")


class _Table:
    """One table of the file, with the keys read from it tracked (unknown keys are errors)."""

    def __init__(self, path: str, name: str, data):
        self.path, self.name = path, name
        if not isinstance(data, dict):
            raise ConfigError(f"{path}: [{name}] must be a table (found {data!r})")
        self.data, self.used = data, set()

    def err(self, key, value, allowed) -> ConfigError:
        return ConfigError(f"{self.path}: {self.name}.{key} = {value!r}: {allowed}")

    def get(self, key, kind, default=_MISSING, allowed: str | None = None, check=None):
        self.used.add(key)
        if key not in self.data:
            if default is _MISSING:
                raise ConfigError(f"{self.path}: {self.name}.{key} is missing ({allowed})")
            return default
        v = self.data[key]
        if kind is float and isinstance(v, int) and not isinstance(v, bool):
            v = float(v)
        if not isinstance(v, kind) or (kind is int and isinstance(v, bool)):
            raise self.err(key, v, allowed or f"must be a {getattr(kind, '__name__', kind)}")
        if isinstance(v, float) and not math.isfinite(v):
            raise self.err(key, v, allowed or "must be a finite number")
        if isinstance(v, str) and "\0" in v:
            # The operating system takes no path or name with a NUL in it.
            raise self.err(key, v, "a NUL character is not allowed")
        if check is not None and not check(v):
            raise self.err(key, v, allowed)
        return v

    def choice(self, key, options, default=_MISSING):
        return self.get(key, str, default, "allowed: " + ", ".join(options), lambda v: v in options)

    def positive(self, key, default=_MISSING, zero=False):
        return self.get(
            key,
            float,
            default,
            "must be a number >= 0" if zero else "must be a number > 0",
            (lambda v: v >= 0) if zero else (lambda v: v > 0),
        )

    def done(self) -> None:
        extra = sorted(set(self.data) - self.used)
        if "password" in extra:
            raise ConfigError(
                f"{self.path}: {self.name}.password: a password is never written in the "
                "configuration; use password_file or password_env"
            )
        if extra:
            raise ConfigError(
                f"{self.path}: {self.name}.{extra[0]} is not a known key "
                f"(known: {', '.join(sorted(self.used))})"
            )


@dataclass
class SourceConfig:
    type: str
    settings: dict  # the checked keys, secrets excluded
    password: str | None = field(default=None, repr=False)

    def public(self) -> dict:
        return {"type": self.type, **self.settings}


@dataclass
class SinkConfig:
    type: str
    settings: dict
    password: str | None = field(default=None, repr=False)


@dataclass
class Config:
    path: str
    run_id: str
    machine_id: str
    machine: str
    fmu: str
    options: dict  # reciprocating_drive.twin.Options fields
    source: SourceConfig
    sinks: list[SinkConfig]
    commit_interval: float = 0.1
    commit_samples: int = 20000
    checkpoint_interval: float = 2.0
    page: dict | None = None  # the [page] table (docs/page.md), checked when the page is made
    snapshot_interval: float = 300.0  # s of input between stored snapshots (docs/plant.md)


def _secret(t: _Table, what: str) -> str | None:
    """A password from `password_file` or `password_env`, never from the file itself."""
    if "password" in t.data:
        raise ConfigError(
            f"{t.path}: {t.name}.password: a password is never written in the configuration; "
            "use password_file or password_env"
        )
    pf = t.get("password_file", str, None)
    pe = t.get("password_env", str, None)
    if pf and pe:
        raise ConfigError(f"{t.path}: {t.name}: give password_file or password_env, not both")
    if pf:
        p = _path(t.path, pf)
        try:
            return pathlib.Path(p).read_text().strip("\r\n")
        except OSError as e:
            raise ConfigError(f"{t.path}: {t.name}.password_file = {pf!r}: {e.strerror}") from None
    if pe:
        if pe not in os.environ:
            raise ConfigError(
                f"{t.path}: {t.name}.password_env = {pe!r}: the environment has no such variable"
            )
        return os.environ[pe]
    return None


def _path(config_path: str, p: str) -> str:
    """A path of the file, relative to the configuration file's folder."""
    q = pathlib.Path(p)
    return str(q if q.is_absolute() else (pathlib.Path(config_path).resolve().parent / q).resolve())


def load(path: str) -> Config:
    data = read_toml(path, ConfigError, "the configuration file")
    return parse(data, str(path))


def parse(data: dict, path: str = "<config>") -> Config:
    top = _Table(path, "(top)", data)
    for key in data:
        if key not in ("run", "source", "conditioning", "sink", "page"):
            raise ConfigError(
                f"{path}: [{key}] is not a known table "
                "(known: run, source, conditioning, sink, page)"
            )
    if "page" in data and not isinstance(data["page"], dict):
        raise ConfigError(f"{path}: page = {data['page']!r}: must be a table [page]")
    run = _Table(path, "run", data.get("run", _MISSING) if "run" in data else {})
    if "run" not in data:
        raise ConfigError(f"{path}: [run] is missing (it names the run and the machine)")
    ident = r"letters, digits and . _ - only, 1-64 characters"

    def is_ident(v):
        return 0 < len(v) <= 64 and all(c.isalnum() or c in "._-" for c in v)

    run_id = run.get("id", str, allowed=ident, check=is_ident)
    machine_id = run.get("machine_id", str, allowed=ident, check=is_ident)
    machine = run.get("machine", str, "default")
    presets = available_presets()
    if machine not in presets and not machine.endswith(".ssv"):
        raise run.err("machine", machine, "allowed: " + ", ".join(presets) + ", or an .ssv file")
    if machine.endswith(".ssv"):
        machine = _path(path, machine)
    fmu = run.get("fmu", str, str(artifacts.fmu()))
    fmu = _path(path, fmu)
    commit_interval = run.positive("commit_interval", 0.1)
    checkpoint_interval = run.positive("checkpoint_interval", 2.0)
    commit_samples = run.get(
        "commit_samples", int, 20000, "must be an integer >= 1", lambda v: v >= 1
    )
    snapshot_interval = run.positive("snapshot_interval", 300.0)
    run.done()

    src = _Table(path, "source", data.get("source", {}))
    if "source" not in data:
        raise ConfigError(f'{path}: [source] is missing (type = "csv", "stdin" or "opcua")')
    stype = src.choice("type", ("csv", "opcua", "stdin"))
    opts = {
        "angle_unit": src.choice("angle_unit", ("rad", "deg", "counts"), "rad"),
        "counts_per_rev": src.get(
            "counts_per_rev", float, None, "must be a number > 0", lambda v: v > 0
        ),
        "wrapped": src.get("wrapped", bool, True),
        "speed_unit": src.choice("speed_unit", ("rad/s", "rpm"), "rad/s"),
    }
    if opts["angle_unit"] == "counts" and opts["counts_per_rev"] is None:
        raise ConfigError(
            f'{path}: source.counts_per_rev is missing (angle_unit = "counts" needs it)'
        )
    if stype in ("csv", "stdin"):
        # The zone of ISO 8601 timestamps without an offset (docs/twin.md "Timestamps").
        opts["timezone"] = src.get(
            "timezone",
            str,
            None,
            "an IANA time zone, e.g. Europe/Berlin",
            _is_zone,
        )
    password = None
    if stype == "csv":
        settings = _csv_source_settings(src, path)
    elif stype == "stdin":
        settings = {"path": "-", "pace": 0.0, "follow": False}
    else:
        settings = _opcua_settings(src, path)
        password = _secret(src, "source")
    src.done()

    cond = _Table(path, "conditioning", data.get("conditioning", {}))
    opts.update(
        duplicates=cond.choice("duplicates", ("drop", "error"), "drop"),
        window=cond.positive("window", 0.1),
        gap_limit=cond.positive("gap_limit", 0.05),
        max_speed=cond.positive("max_speed", 100.0),
        use_measured_speed=cond.get("use_measured_speed", bool, True),
        # Machine states (docs/twin.md "Machine states"): rpm and seconds.
        stop_speed=cond.positive("stop_speed", 1.0),
        stop_duration=cond.positive("stop_duration", 0.5),
    )
    cond.done()

    sinks_data = data.get("sink", [])
    if not isinstance(sinks_data, list) or not sinks_data:
        raise ConfigError(
            f'{path}: no [[sink]] (at least one: type = "sqlite", "postgres" or "csv")'
        )
    sinks = []
    for i, sd in enumerate(sinks_data):
        s = _Table(path, f"sink[{i}]", sd)
        stype_ = s.choice("type", ("sqlite", "postgres", "csv"))
        samples = s.get(
            "samples",
            (str, int),
            "all",
            'allowed: "all", "none", or N >= 1 (every N-th sample)',
            lambda v: v in ("all", "none") or (isinstance(v, int) and v >= 1),
        )
        common = {
            "samples": samples,
            "retry_for": s.positive("retry_for", 300.0),
            "retry_max": s.positive("retry_max", 5.0),
            "notice_interval": s.positive("notice_interval", 30.0),
        }
        if stype_ != "csv":
            # Retention (docs/plant.md "Retention"): seconds, or "all" (kept for ever).
            for key, default in (("keep_samples", 3600.0), ("keep_input", "all")):
                v = s.get(
                    key,
                    (str, int, float),
                    default,
                    'allowed: "all" or a number of seconds > 0',
                    lambda v: (
                        v == "all"
                        or (not isinstance(v, (str, bool)) and math.isfinite(v) and v > 0)
                    ),
                )
                common[key] = None if v == "all" else float(v)
        pw = None
        if stype_ == "sqlite":
            settings_ = {"path": _path(path, s.get("path", str, allowed="the database file"))}
        elif stype_ == "csv":
            settings_ = _csv_sink_settings(s, path)
        else:
            dsn = s.get(
                "dsn",
                str,
                allowed="a libpq connection string without password, e.g. "
                '"host=127.0.0.1 port=5432 dbname=twin user=twin"',
            )
            _dsn_without_password(path, f"sink[{i}]", dsn)
            settings_ = {"dsn": dsn}
            pw = _secret(s, f"sink[{i}]")
        s.done()
        sinks.append(SinkConfig(stype_, {**settings_, **common}, pw))
    _distinct_files(path, settings if stype != "opcua" else {}, sinks)
    top.used.update(data)
    return Config(
        path,
        run_id,
        machine_id,
        machine,
        fmu,
        opts,
        SourceConfig(stype, settings, password),
        sinks,
        commit_interval,
        commit_samples,
        checkpoint_interval,
        data.get("page"),
        snapshot_interval,
    )


def mask_dsn(dsn: str) -> str:
    """A connection string as a message may show it: any password replaced by ***, in a URI's
    user-info (postgresql://user:***@host/db), as a key (password=***) or a URI parameter."""
    dsn = re.sub(r"(://[^/@:?#]*:)[^@/?#]*@", r"\1***@", dsn)
    dsn = re.sub(r"(?i)(password\s*=\s*)('(?:[^'\\]|\\.)*'|[^\s&]*)", r"\1***", dsn)
    return dsn


def _service_files() -> list[pathlib.Path]:
    """The connection service files libpq reads (PGSERVICEFILE or ~/.pg_service.conf, then
    PGSYSCONFDIR/pg_service.conf): the PostgreSQL manual, "The Connection Service File"."""
    out = [pathlib.Path(os.environ.get("PGSERVICEFILE", "~/.pg_service.conf")).expanduser()]
    if os.environ.get("PGSYSCONFDIR"):
        out.append(pathlib.Path(os.environ["PGSYSCONFDIR"]) / "pg_service.conf")
    return out


def _dsn_without_password(path: str, name: str, dsn: str) -> None:
    """Refuses a connection string that carries a password in any form libpq reads: the key
    `password`, a URI's user-info (user:PW@) or parameter (?password=), or the connection service
    it names (service=NAME) in a service file. libpq's own parser (psycopg.conninfo) reads the
    string, so every form it accepts is seen."""
    how = (
        f"a password is never written in the configuration; remove it and give it with "
        f"{name}.password_file or {name}.password_env"
    )
    from psycopg import ProgrammingError
    from psycopg.conninfo import conninfo_to_dict

    try:
        parts = conninfo_to_dict(dsn)
    except ProgrammingError as e:
        raise ConfigError(
            f"{path}: {name}.dsn = {mask_dsn(dsn)!r}: not a libpq connection string "
            f"({str(e).splitlines()[0] if str(e) else 'unreadable'})"
        ) from None
    if "password" in parts:
        where = "in the URI's user-info" if re.search(r"://[^/@]*:[^@/]*@", dsn) else "as a key"
        raise ConfigError(
            f"{path}: {name}.dsn = {mask_dsn(dsn)!r}: holds a password ({where}); {how}"
        )
    service = parts.get("service")
    if service:
        import configparser

        for f in _service_files():
            cp = configparser.ConfigParser(interpolation=None)
            try:
                cp.read(f, encoding="utf-8")
            except (configparser.Error, UnicodeDecodeError, OSError):
                continue  # libpq reports an unreadable service file when it connects
            if cp.has_section(service) and cp.has_option(service, "password"):
                raise ConfigError(
                    f"{path}: {name}.dsn = {mask_dsn(dsn)!r}: its service {service!r} in {f} holds "
                    f"a password; {how} (and remove it from the service file)"
                )


def _certificate_in_date(path: str, cert_file: str) -> None:
    """A server certificate of source.trust that has expired or is not valid yet is refused
    here, at the configuration check (a certificate that cannot be read is reported when the
    source connects). The dates are the certificate's own (X.509 notBefore / notAfter)."""
    import datetime as dt

    from cryptography import x509

    try:
        data = pathlib.Path(cert_file).read_bytes()
        cert = (
            x509.load_pem_x509_certificate(data)
            if b"-----BEGIN" in data
            else x509.load_der_x509_certificate(data)
        )
    except (OSError, ValueError):
        return
    now = dt.datetime.now(dt.UTC)
    start, end = cert.not_valid_before_utc, cert.not_valid_after_utc
    span = f"valid from {start:%Y-%m-%d %H:%M} to {end:%Y-%m-%d %H:%M} UTC"
    if now > end:
        raise ConfigError(
            f"{path}: source.trust: {cert_file}: the certificate expired ({span}); refused: "
            "trust the server's current certificate"
        )
    if now < start:
        raise ConfigError(
            f"{path}: source.trust: {cert_file}: the certificate is not valid yet ({span}); "
            "refused: check the server's and this machine's clocks"
        )


def _distinct_nodes(path: str, s: dict, allowed: str) -> None:
    """Each node id is one (asyncua's parser, the OPC UA string form), and no node is named for
    two roles (the same node as angle and speed, the time array again as the angle)."""
    from asyncua import ua

    seen: dict = {}
    for key in (
        "angle_node",
        "speed_node",
        "force_node",
        "discharge_node",
        "suction_node",
        "time_node",
        "seq_node",
        "end_node",
    ):
        v = s.get(key)
        if v is None:
            continue
        try:
            nid = ua.NodeId.from_string(v)
        except Exception:  # noqa: BLE001 - asyncua raises several kinds for a bad string
            raise ConfigError(f"{path}: source.{key} = {v!r}: not a node id; {allowed}") from None
        if nid in seen:
            raise ConfigError(
                f"{path}: source.{key} = {v!r}: the same node as source.{seen[nid]}; "
                "each role needs its own node"
            )
        seen[nid] = key


def _opcua_settings(src: _Table, path: str) -> dict:
    mode = src.choice("mode", ("scalar", "block"), "scalar")
    node = 'an OPC UA node id, e.g. "ns=2;s=Pump.CrankAngle"'
    s = {
        "endpoint": src.get(
            "endpoint", str, allowed="an opc.tcp:// URL", check=lambda v: v.startswith("opc.tcp://")
        ),
        "mode": mode,
        "angle_node": src.get("angle_node", str, allowed=node),
        "speed_node": src.get("speed_node", str, None),
        "force_node": src.get("force_node", str, None),
        # A pump's pressures [Pa] (docs/plant.md "OPC UA source"): the twin's discharge_pressure
        # and suction_pressure columns.
        "discharge_node": src.get("discharge_node", str, None),
        "suction_node": src.get("suction_node", str, None),
        "time_node": src.get("time_node", str, None),  # block mode: the timestamps' array
        # block mode: the PLC's block counter, written after the arrays ("Sample assembly")
        "seq_node": src.get("seq_node", str, None),
        "history": src.get("history", bool, True),
        "security_policy": src.choice("security_policy", ("None", "Basic256Sha256"), "None"),
        "security_mode": src.choice("security_mode", ("Sign", "SignAndEncrypt"), "SignAndEncrypt"),
        "certificate": src.get("certificate", str, None),
        "private_key": src.get("private_key", str, None),
        "trust": src.get(
            "trust",
            list,
            [],
            "must be a list of certificate files (strings)",
            lambda v: all(isinstance(x, str) and x and "\0" not in x for x in v),
        ),
        "username": src.get("username", str, None),
        "timeout": src.positive("timeout", 5.0),
        "reconnect_max": src.positive("reconnect_max", 5.0),
        "reconnect_for": src.positive("reconnect_for", 300.0),
        "publishing_interval": src.positive("publishing_interval", 0.05),
        # docs/plant.md "History" and "Unresponsive server or database"
        "history_retry_for": src.positive("history_retry_for", 30.0, zero=True),
        "notice_interval": src.positive("notice_interval", 30.0),
        "end_node": src.get("end_node", str, None),
        # docs/plant.md "Timestamps" and "Sample assembly"
        "clock_tolerance": src.positive("clock_tolerance", 1.0),
        "join_tolerance": src.positive("join_tolerance", 0.0005, zero=True),
        "hold_limit": src.positive("hold_limit", 10.0),
        # The server's application URI: its certificate must name it (checked at connection).
        "server_uri": src.get("server_uri", str, None),
    }
    _distinct_nodes(path, s, node)
    if s["seq_node"] and mode != "block":
        raise ConfigError(
            f'{path}: source.seq_node = {s["seq_node"]!r}: only with mode = "block" (the block '
            "counter written after the arrays)"
        )
    if mode == "block" and not s["time_node"]:
        raise ConfigError(
            f'{path}: source.time_node is missing (mode = "block" needs the timestamps\' array)'
        )
    for k in ("certificate", "private_key"):
        if s[k]:
            s[k] = _path(path, s[k])
    s["trust"] = [_path(path, p) for p in s["trust"]]
    for p in s["trust"]:
        _certificate_in_date(path, p)
    if s["security_policy"] != "None":
        for k in ("certificate", "private_key"):
            if not s[k]:
                raise ConfigError(
                    f'{path}: source.{k} is missing (security_policy = "{s["security_policy"]}" needs it)'
                )
        if not s["trust"]:
            raise ConfigError(
                f"{path}: source.trust is missing (the server certificates to trust, a list of files)"
            )
    return s


def _csv_sink_settings(s: _Table, path: str) -> dict:
    """The files of a CSV sink (docs/plant.md "CSV sink"), beside `path` by default."""
    out = _path(path, s.get("path", str, allowed="the per-sample CSV file to write"))
    stem = pathlib.Path(out)
    return {
        "path": out,
        "summary": _path(
            path, s.get("summary", str, str(stem.with_name(stem.stem + "-revolutions.csv")))
        ),
        "checkpoint": _path(
            path, s.get("checkpoint", str, str(stem.with_name(stem.name + ".checkpoint.json")))
        ),
    }


def _distinct_files(path: str, source: dict, sinks: list) -> None:
    """No file is written twice or over the input (it would be destroyed)."""
    seen = {}
    if source.get("path") and source["path"] != "-":
        seen[str(pathlib.Path(source["path"]).resolve())] = "source.path"
    for i, sk in enumerate(sinks):
        keys = ("path", "summary", "checkpoint") if sk.type == "csv" else ("path",)
        for k in keys:
            if k not in sk.settings:
                continue
            f = str(pathlib.Path(sk.settings[k]).resolve())
            if artifacts.installed() and pathlib.Path(f).is_relative_to(artifacts.PACKAGE):
                # The shipped configurations write ../../results/ beside themselves: run from
                # the installation they would write into it (docs/install.md "Examples").
                raise ConfigError(
                    f"{path}: sink[{i}].{k} = {sk.settings[k]!r} is inside the installed package "
                    f"({artifacts.PACKAGE}); copy the examples into a folder of your own with "
                    "`rdrive examples DIR` and use the configuration there"
                )
            if f in seen:
                raise ConfigError(
                    f"{path}: sink[{i}].{k} = {sk.settings[k]!r}: the same file as {seen[f]}; "
                    "each file is read or written by one part only"
                )
            seen[f] = f"sink[{i}].{k}"


def _is_zone(name: str) -> bool:
    from ..timestamps import zone

    try:
        zone(name)
    except ValueError:
        return False
    return True


def _csv_source_settings(src: _Table, path: str) -> dict:
    """A CSV file replayed, a growing file followed, or standard input (`path = "-"`)
    (docs/plant.md "Sources")."""
    p = src.get("path", str, allowed='the CSV file to replay, or "-" for standard input')
    follow = src.get("follow", bool, False)
    # A pace below MIN_PACE would wait longer than any plant runs between two samples (and
    # 1e-300 overflows the sleep): 0 (as fast as possible) or MIN_PACE to MAX_PACE.
    pace = src.get(
        "pace",
        float,
        0.0,
        f"must be a number >= 0: 0 (as fast as possible) or {MIN_PACE:g} to {MAX_PACE:g}",
        lambda v: v == 0 or MIN_PACE <= v <= MAX_PACE,
    )
    if p == "-" and follow:
        raise src.err("follow", True, 'follows a file, not standard input (path = "-")')
    if pace > 0 and (follow or p == "-"):
        raise src.err("pace", pace, "a followed file or standard input comes at its own pace; 0")
    return {"path": p if p == "-" else _path(path, p), "pace": pace, "follow": follow}
