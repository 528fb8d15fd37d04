# Sourced by scripts/test.sh: makes sure a PostgreSQL server is installed for the tests of the
# twin's PostgreSQL sink (tests/python/pg_server.py starts a temporary one as an unprivileged
# user on 127.0.0.1; nothing is configured system-wide and no service is started).
#
#   source scripts/lib/postgres.sh; ensure_postgres
#
# Idempotent: an installed server (any /usr/lib/postgresql/*/bin/pg_ctl, Debian's layout) is
# detected and nothing is done; otherwise Debian's `postgresql` package is installed.

source "$(dirname "${BASH_SOURCE[0]}")/apt.sh"

ensure_postgres() {
    if compgen -G "/usr/lib/postgresql/*/bin/pg_ctl" >/dev/null; then
        return 0
    fi
    apt_install postgresql
    # The Debian package creates and starts a cluster of its own; the tests do not use it.
    compgen -G "/usr/lib/postgresql/*/bin/pg_ctl" >/dev/null || {
        echo "postgres.sh: postgresql installed but no pg_ctl under /usr/lib/postgresql" >&2
        return 1
    }
}
