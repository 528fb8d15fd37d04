# Sourced by the set-up scripts and the browser tests' runner: makes sure Debian's chromium is
# installed (the twin page's tests drive it headless, docs/page.md "Tests").
#
#   source scripts/lib/chromium.sh; ensure_chromium    # prints the browser's path
#
# An existing install is used as it is: RD_CHROMIUM (a path) first, then chromium or
# chromium-browser on PATH. Otherwise Debian's package is installed through scripts/lib/apt.sh.
# Never a browser build downloaded by a test tool (no `playwright install`).

_rd_chromium_dir="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"

find_chromium() {
    if [ -n "${RD_CHROMIUM:-}" ] && [ -x "$RD_CHROMIUM" ]; then
        echo "$RD_CHROMIUM"
        return 0
    fi
    local name
    for name in chromium chromium-browser; do
        if command -v "$name" >/dev/null 2>&1; then
            command -v "$name"
            return 0
        fi
    done
    return 1
}

ensure_chromium() {
    if find_chromium; then
        return 0
    fi
    # shellcheck source=apt.sh
    source "$_rd_chromium_dir/apt.sh"
    apt_install chromium || {
        echo "chromium.sh: could not install Debian's chromium" >&2
        return 1
    }
    find_chromium
}
