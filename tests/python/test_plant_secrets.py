"""Secrets of the plant (docs/plant.md "Configuration", docs/page.md "Access"): a password in any
form of a PostgreSQL connection string is refused at the configuration check and never printed;
the page logs no query string or token, logs refused requests at a bounded rate and limits wrong
logins; a server certificate out of its validity dates is refused."""

from __future__ import annotations

import copy
import datetime as dt
import logging
import urllib.error
import urllib.parse
import urllib.request

import plant_util as pu
import pytest
from reciprocating_drive.plant.config import ConfigError, parse

PW = "Pw-7f3a9c"
BASE = {
    "run": {"id": "r1", "machine_id": "pump-1"},
    "source": {"type": "csv", "path": "x.csv"},
    "sink": [{"type": "postgres", "dsn": "host=127.0.0.1 dbname=twin user=twin"}],
}


def _with_dsn(dsn):
    d = copy.deepcopy(BASE)
    d["sink"][0]["dsn"] = dsn
    return d


@pytest.mark.parametrize(
    "dsn, where",
    [
        (f"postgresql://twin:{PW}@127.0.0.1/twin", "in the URI's user-info"),
        (f"postgres://twin:{PW}@127.0.0.1:5432/twin?sslmode=disable", "in the URI's user-info"),
        (f"host=127.0.0.1 dbname=twin user=twin password={PW}", "as a key"),
        (f"host=127.0.0.1 dbname=twin user=twin password = '{PW}'", "as a key"),
        (f"postgresql://twin@127.0.0.1/twin?password={PW}", "as a key"),
    ],
    ids=["uri user-info", "uri user-info with port", "key", "key quoted", "uri parameter"],
)
def test_password_in_any_form_of_dsn_is_refused_and_not_printed(dsn, where):
    with pytest.raises(ConfigError) as e:
        parse(_with_dsn(dsn), "t.toml")
    msg = str(e.value)
    assert PW not in msg, msg
    assert "sink[0].dsn" in msg and where in msg and "sink[0].password_file" in msg, msg


def test_password_in_the_named_service_file_is_refused(tmp_path, monkeypatch):
    svc = tmp_path / "pg_service.conf"
    svc.write_text(f"[pump]\nhost=127.0.0.1\ndbname=twin\nuser=twin\npassword={PW}\n")
    monkeypatch.setenv("PGSERVICEFILE", str(svc))
    with pytest.raises(ConfigError) as e:
        parse(_with_dsn("service=pump"), "t.toml")
    msg = str(e.value)
    assert PW not in msg and "service 'pump'" in msg and str(svc) in msg, msg
    # A service without a password is accepted (the password then comes from password_file).
    svc.write_text("[pump]\nhost=127.0.0.1\ndbname=twin\nuser=twin\n")
    assert parse(_with_dsn("service=pump"), "t.toml").sinks[0].settings["dsn"] == "service=pump"


def test_the_command_refuses_a_uri_password_in_one_line_without_printing_it(tmp_path):
    cfg = pu.write_config(
        tmp_path / "pw.toml",
        source=pu.csv_source(),
        sinks=pu.pg_sink(f"postgresql://twin:{PW}@127.0.0.1:1/twin"),
    )
    p = pu.run(cfg)
    assert p.returncode == 2, p.stderr
    assert PW not in p.stdout + p.stderr
    assert len(p.stderr.strip().splitlines()) == 1 and "password_env" in p.stderr


def test_messages_show_a_dsn_with_its_password_masked():
    from reciprocating_drive.plant.config import mask_dsn
    from reciprocating_drive.plant.sinks.postgres import PostgresSink

    for dsn in (
        f"postgresql://twin:{PW}@127.0.0.1:1/twin",
        f"host=127.0.0.1 port=1 password={PW} user=twin",
        f"postgresql://twin@127.0.0.1:1/twin?password={PW}&sslmode=disable",
    ):
        assert PW not in mask_dsn(dsn) and "***" in mask_dsn(dsn)
        assert PW not in PostgresSink(dsn).name
    assert mask_dsn("postgresql://twin@127.0.0.1:5432/twin") == (
        "postgresql://twin@127.0.0.1:5432/twin"
    )


# ---- the page --------------------------------------------------------------------------------

TOKEN = "page-token-0123456789abcdef"


@pytest.fixture
def page():
    from reciprocating_drive.page.server import PageServer

    s = PageServer(port=0, token=TOKEN).start()
    yield s
    s.close()


def _request(url, data=None):
    req = urllib.request.Request(url, data=data)
    try:
        with urllib.request.urlopen(req, timeout=5) as r:
            return r.status, dict(r.headers)
    except urllib.error.HTTPError as e:
        return e.code, dict(e.headers)


class _Lines(logging.Handler):
    def __init__(self):
        super().__init__()
        self.lines = []

    def emit(self, record):
        self.lines.append(record.getMessage())


@pytest.fixture
def access_log():
    h = _Lines()
    log = logging.getLogger("reciprocating_drive.page.access")
    log.addHandler(h)
    yield h.lines
    log.removeHandler(h)


def test_page_never_logs_query_strings_or_tokens(page, access_log):
    status, _ = _request(page.url + f"?token={TOKEN}")
    assert status == 401
    status, _ = _request(page.url + "api/state?x=" + urllib.parse.quote("secret stuff"))
    assert status == 401
    import time

    time.sleep(0.2)
    assert access_log, "refused requests are logged"
    text = "\n".join(access_log)
    assert TOKEN not in text and "?" not in text and "secret" not in text, text
    assert "401 GET / (127.0.0.1)" in text, text


def test_page_logs_refused_requests_at_a_bounded_rate(page, access_log):
    from reciprocating_drive.page.server import LOG_LINES

    for _ in range(300):
        _request(page.url + "api/state")
    assert len(access_log) == LOG_LINES, len(access_log)


def test_page_limits_wrong_logins_per_client(page, access_log):
    from reciprocating_drive.page.server import LOGIN_TRIES, LOGIN_WINDOW

    codes = []
    for i in range(300):
        codes.append(_request(page.url + "login", data=f"token=wrong-{i}".encode())[0])
    assert codes[:LOGIN_TRIES] == [401] * LOGIN_TRIES
    assert set(codes[LOGIN_TRIES:]) == {429}, codes
    # Even the right token waits its turn: no guess is checked while the client is held back.
    status, headers = _request(page.url + "login", data=f"token={TOKEN}".encode())
    assert status == 429 and 0 < int(headers["Retry-After"]) <= LOGIN_WINDOW
    assert len(access_log) <= 10


# ---- server certificates ---------------------------------------------------------------------


def _certificate(path, start: dt.datetime, end: dt.datetime):
    from cryptography import x509
    from cryptography.hazmat.primitives import hashes
    from cryptography.hazmat.primitives.asymmetric import rsa
    from cryptography.hazmat.primitives.serialization import Encoding
    from cryptography.x509.oid import NameOID

    key = rsa.generate_private_key(public_exponent=65537, key_size=2048)
    name = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, "old-plc")])
    cert = (
        x509.CertificateBuilder()
        .subject_name(name)
        .issuer_name(name)
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(start)
        .not_valid_after(end)
        .sign(key, hashes.SHA256())
    )
    path.write_bytes(cert.public_bytes(Encoding.DER))
    return path


@pytest.mark.parametrize(
    "start, end, words",
    [
        (dt.datetime(2019, 1, 1), dt.datetime(2020, 1, 1), "the certificate expired"),
        (dt.datetime(2090, 1, 1), dt.datetime(2091, 1, 1), "not valid yet"),
    ],
    ids=["expired 2020", "from 2090"],
)
def test_server_certificate_out_of_its_dates_is_refused(tmp_path, start, end, words):
    cert = _certificate(tmp_path / "plc.der", start, end)
    src = {
        "type": "opcua",
        "endpoint": "opc.tcp://127.0.0.1:1/plc",
        "angle_node": "ns=2;s=Pump.CrankAngle",
        "security_policy": "Basic256Sha256",
        "certificate": "c.der",
        "private_key": "c.pem",
        "trust": [str(cert)],
    }
    with pytest.raises(ConfigError) as e:
        parse({**BASE, "source": src, "sink": [{"type": "sqlite", "path": "x.db"}]}, "t.toml")
    msg = str(e.value)
    assert "source.trust" in msg and str(cert) in msg and words in msg, msg
