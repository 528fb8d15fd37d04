"""The `[page]` table of a twin configuration file (docs/page.md, "Configuration"):

    [page]
    host = "127.0.0.1"           # default; any other address needs a token
    port = 8050
    token_file = "page.token"    # or token_env = "RD_PAGE_TOKEN" (never the token itself)
    limits = "limits.toml"       # alarms (optional)

`page_from_table(table, where, base)` checks it (one-line errors naming the file and key) and
returns an unstarted `PageServer`; relative paths are taken from `base`, the configuration file's
folder.

Layer: workflows, the page (docs/architecture.md).
"""

from __future__ import annotations

import os
from pathlib import Path

from ..alarms import LimitsError, load_limits
from .server import LOOPBACK, PageError, PageServer

KEYS = {"host", "port", "token_file", "token_env", "limits", "title"}


def page_from_table(
    table: dict,
    where: str,
    base: str | os.PathLike = ".",
    database: str | None = None,
    run: str | None = None,
    on_alarm=None,
) -> PageServer:
    """`where`: the configuration file's name, for the messages; `database`/`run`: the twin's
    SQLite file and run name, for the trends."""
    if "token" in table:
        # A token written in the configuration would be copied, logged and committed with it.
        raise PageError(
            f"{where}: page.token: not allowed; put the token in a file (page.token_file) or an "
            "environment variable (page.token_env)"
        )
    bad = sorted(set(table) - KEYS)
    if bad:
        raise PageError(f"{where}: page.{bad[0]}: unknown key (allowed: {', '.join(sorted(KEYS))})")
    host = table.get("host", LOOPBACK)
    if not isinstance(host, str) or not host:
        raise PageError(f"{where}: page.host = {host!r}: must be an address such as 127.0.0.1")
    port = table.get("port", 8050)
    if not isinstance(port, int) or isinstance(port, bool) or not 0 <= port <= 65535:
        raise PageError(f"{where}: page.port = {port!r}: must be a whole number 0 to 65535")
    base = Path(base)
    token = None
    if "token_file" in table and "token_env" in table:
        raise PageError(f"{where}: page.token_file and page.token_env: give one of them")
    if "token_file" in table:
        path = base / str(table["token_file"])
        try:
            token = path.read_text(encoding="utf-8").strip()
        except OSError as e:
            raise PageError(
                f"{where}: page.token_file = {str(table['token_file'])!r}: cannot read it: "
                f"{e.strerror}"
            ) from None
        except ValueError:  # a NUL in the path, or bytes that are not UTF-8
            raise PageError(
                f"{where}: page.token_file = {str(table['token_file'])!r}: not a readable UTF-8 "
                "file name and text"
            ) from None
        if not token:
            raise PageError(f"{where}: page.token_file = {str(table['token_file'])!r}: empty")
    elif "token_env" in table:
        name = str(table["token_env"])
        token = os.environ.get(name) or None
        if token is None:
            raise PageError(f"{where}: page.token_env = {name!r}: the variable is not set")
    limits = None
    if "limits" in table:
        try:
            limits = load_limits(base / str(table["limits"]))
        except LimitsError as e:
            raise PageError(str(e)) from None
    title = table.get("title", "ReciprocatingDrive twin")
    if not isinstance(title, str):
        raise PageError(f"{where}: page.title = {title!r}: must be a string")
    try:
        return PageServer(host, port, token, database, run, limits, title, on_alarm)
    except PageError as e:
        raise PageError(f"{where}: {e}") from None
