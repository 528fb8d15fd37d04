# Sourced by the set-up scripts: makes the steps that change something shared safe when two
# scripts run at once (two main jobs started together on a fresh machine: rustup refuses a second
# `rustup target add` of the same target with "detected conflict", and two `python -m venv` into
# one .venv delete each other's files).
#
#   source scripts/lib/lock.sh
#   rd_with_lock NAME CMD [ARG...]     runs CMD (a command or a shell function, in this shell, so
#                                      its exports stay) while holding the lock NAME
#   rd_rustup_target_add TARGET        adds a rustup target unless installed, under the lock "rustup"
#
# The lock is flock(1) on ${RD_LOCK_DIR:-${TMPDIR:-/tmp}}/reciprocating-drive-NAME.lock: the kernel
# releases it when the holder exits, also when it is killed, so a crashed run never leaves a stale
# lock. A waiter gives up after RD_LOCK_TIMEOUT seconds (default 1800) with one line.

rd_lock_file() {
    echo "${RD_LOCK_DIR:-${TMPDIR:-/tmp}}/reciprocating-drive-$1.lock"
}

rd_with_lock() {
    local name="$1" file fd rc
    shift
    file="$(rd_lock_file "$name")"
    exec {fd}>>"$file" || {
        echo "lock.sh: cannot open the lock file $file" >&2
        return 1
    }
    if ! flock -w "${RD_LOCK_TIMEOUT:-1800}" "$fd"; then
        exec {fd}>&-
        echo "lock.sh: waited ${RD_LOCK_TIMEOUT:-1800} s for the lock $file (another set-up still running?)" >&2
        return 1
    fi
    # No `|| rc=$?` here: that would switch off a caller's `set -e` inside CMD.
    "$@"
    rc=$?
    exec {fd}>&-
    return $rc
}

_rd_rustup_target_add_unlocked() {
    # Checked again under the lock: the other run may have added it while this one waited.
    if ! rustup target list --installed 2>/dev/null | grep -qx "$1"; then
        echo "lock.sh: adding the rustup target $1" >&2
        rustup target add "$1" >&2
    fi
}

rd_rustup_target_add() {
    if rustup target list --installed 2>/dev/null | grep -qx "$1"; then
        return 0
    fi
    rd_with_lock rustup _rd_rustup_target_add_unlocked "$1"
}
