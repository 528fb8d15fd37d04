"""A real, temporary PostgreSQL server for the tests (docs/plant.md): Debian's `postgresql`
binaries, initdb and pg_ctl in a temporary directory, listening on 127.0.0.1 on a free port, run
as an unprivileged user (the server refuses root). Every wait is bounded; `stop()` always ends it.

    with PgServer() as pg:
        dsn = pg.dsn   # "host=127.0.0.1 port=... dbname=twin user=twin"
"""

from __future__ import annotations

import glob
import os
import pwd
import shutil
import socket
import subprocess
import tempfile
import time


def pg_bindir() -> str | None:
    """The newest installed server's bin directory, or None."""
    found = sorted(
        glob.glob("/usr/lib/postgresql/*/bin/pg_ctl"), key=lambda p: int(p.split("/")[4])
    )
    return os.path.dirname(found[-1]) if found else None


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class PgServer:
    def __init__(self, user: str = "postgres"):
        self.bindir = pg_bindir()
        if self.bindir is None:
            raise RuntimeError("PostgreSQL is not installed (scripts/lib/postgres.sh installs it)")
        self.user = user
        self.port = _free_port()
        self.dir = tempfile.mkdtemp(prefix="rd-pg-")
        self.data = os.path.join(self.dir, "data")
        self.dsn = f"host=127.0.0.1 port={self.port} dbname=twin user=twin connect_timeout=3"

    def _as_user(self, args, timeout=60.0):
        cmd = [os.path.join(self.bindir, args[0]), *args[1:]]
        if os.geteuid() == 0:
            cmd = ["runuser", "-u", self.user, "--", *cmd]
        return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, check=True)

    def init(self) -> PgServer:
        if os.geteuid() == 0:
            try:
                pw = pwd.getpwnam(self.user)
            except KeyError:
                # The server refuses root: an unprivileged system user to run it.
                subprocess.run(
                    [
                        "useradd",
                        "--system",
                        "--no-create-home",
                        "--shell",
                        "/usr/sbin/nologin",
                        self.user,
                    ],
                    check=True,
                    capture_output=True,
                    timeout=30,
                )
                pw = pwd.getpwnam(self.user)
            os.chown(self.dir, pw.pw_uid, pw.pw_gid)
        self._as_user(["initdb", "-D", self.data, "-U", "twin", "--auth=trust", "-E", "UTF8"])
        with open(os.path.join(self.data, "postgresql.conf"), "a") as f:
            f.write(
                f"listen_addresses = '127.0.0.1'\nport = {self.port}\n"
                f"unix_socket_directories = '{self.dir}'\nfsync = on\n"
            )
        self.start()
        self._as_user(["createdb", "-h", "127.0.0.1", "-p", str(self.port), "-U", "twin", "twin"])
        return self

    def add_password_user(self, name: str, password: str) -> str:
        """A login role that must give its password (scram-sha-256); its connection string,
        without the password."""
        import psycopg
        from psycopg import sql

        with psycopg.connect(self.dsn, autocommit=True) as c:
            # DDL takes no parameters: the password as a quoted literal.
            c.execute(
                sql.SQL("CREATE ROLE {} LOGIN PASSWORD {}").format(
                    sql.Identifier(name), sql.Literal(password)
                )
            )
            # The rights of the tables' owner (the schema may exist already).
            c.execute(sql.SQL("GRANT twin TO {}").format(sql.Identifier(name)))
        hba = os.path.join(self.data, "pg_hba.conf")
        with open(hba) as f:
            rules = f.read()
        with open(hba, "w") as f:
            f.write(f"host all {name} 127.0.0.1/32 scram-sha-256\n" + rules)
        self._as_user(["pg_ctl", "-D", self.data, "reload"], timeout=30)
        return self.dsn.replace("user=twin", f"user={name}")

    def start(self) -> None:
        self._as_user(
            [
                "pg_ctl",
                "-D",
                self.data,
                "-l",
                os.path.join(self.dir, "log"),
                "-w",
                "-t",
                "30",
                "start",
            ],
            timeout=45,
        )

    def stop(self, mode: str = "fast") -> None:
        try:
            self._as_user(
                ["pg_ctl", "-D", self.data, "-m", mode, "-w", "-t", "30", "stop"], timeout=45
            )
        except subprocess.CalledProcessError:
            pass  # not running

    def restart_after(self, seconds: float) -> None:
        self.stop("immediate")
        time.sleep(seconds)
        self.start()

    def destroy(self) -> None:
        self.stop("immediate")
        shutil.rmtree(self.dir, ignore_errors=True)

    def __enter__(self) -> PgServer:
        try:
            return self.init()
        except BaseException:
            self.destroy()
            raise

    def __exit__(self, *exc) -> None:
        self.destroy()
