# Sourced by the set-up scripts: the one way they install Debian packages.
#
#   source scripts/lib/apt.sh; apt_install PKG...
#
# Waits for the package manager's lock (another apt or an unattended upgrade holding it) for up to
# RD_APT_LOCK_TIMEOUT seconds (default 600) instead of failing at once, runs `apt-get update` once
# per shell, and uses sudo when not root. Two set-up scripts of this project run their apt-get
# calls one after the other (the lock "apt", scripts/lib/lock.sh): the dpkg lock timeout covers
# install, and the lock also covers `apt-get update`'s list lock.

source "$(dirname "${BASH_SOURCE[0]}")/lock.sh"

apt_install() {
    rd_with_lock apt _apt_install_unlocked "$@"
}

_apt_install_unlocked() {
    local sudo="" wait="${RD_APT_LOCK_TIMEOUT:-600}"
    [ "$(id -u)" -ne 0 ] && sudo="sudo"
    echo "apt.sh: installing Debian packages: $*" >&2
    if [ -z "${_RD_APT_UPDATED:-}" ]; then
        $sudo apt-get -o DPkg::Lock::Timeout="$wait" update -qq
        _RD_APT_UPDATED=1
    fi
    DEBIAN_FRONTEND=noninteractive $sudo apt-get -o DPkg::Lock::Timeout="$wait" install -y -qq "$@" >/dev/null
}
