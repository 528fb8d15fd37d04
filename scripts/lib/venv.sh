# Sourced by the scripts: creates or refreshes the project-local Python environment .venv from
# requirements.txt (fmpy, libcosimpy, pytest, matplotlib, numpy, scipy, mpmath, dask.distributed,
# pyarrow, tqdm, ruff, import-linter, hypothesis, asyncua, psycopg, playwright).
#
#   source scripts/lib/venv.sh; ensure_venv      # then use "$VENV_PYTHON"
#
# Idempotent and quick: a stamp file in .venv holds a hash of requirements.txt and of the
# interpreter; when it matches and the venv's python runs, nothing is done. Works on a fresh
# Debian machine as root (installs python3-venv and the C++ runtime libcosimpy's binary needs when
# they are missing), and as a user with sudo. Two scripts calling it at once for the same
# checkout take turns (a lock per .venv, scripts/lib/lock.sh): the second finds the venv ready.

_venv_root() { (cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd); }

source "$(dirname "${BASH_SOURCE[0]}")/apt.sh"

_venv_apt_install() {
    apt_install "$@"
}

# libcosimpy ships libcosimc.so (libcosim, the FMI Library, boost, statically linked) that needs
# only the C/C++ runtime: libstdc++6, libgcc-s1 and libatomic1. The last is not on a minimal
# Debian.
_venv_system_libs() {
    local missing=()
    for lib in libatomic.so.1 libstdc++.so.6 libgcc_s.so.1; do
        ldconfig -p 2>/dev/null | grep -q "$lib" || missing+=("$lib")
    done
    [ ${#missing[@]} -eq 0 ] && return 0
    local pkgs=()
    for lib in "${missing[@]}"; do
        case "$lib" in
            libatomic.so.1) pkgs+=(libatomic1) ;;
            libstdc++.so.6) pkgs+=(libstdc++6) ;;
            libgcc_s.so.1) pkgs+=(libgcc-s1) ;;
        esac
    done
    _venv_apt_install "${pkgs[@]}"
}

ensure_venv() {
    local root
    root="$(_venv_root)"
    # One lock per venv folder (its path's hash names it), so other checkouts are not held up.
    rd_with_lock "venv-$(echo "$root/.venv" | sha256sum | cut -c1-16)" _ensure_venv_unlocked "$root"
}

_ensure_venv_unlocked() {
    local root="$1" venv req py
    venv="$root/.venv"
    req="$root/requirements.txt"
    py="${PYTHON:-python3}"
    if ! command -v "$py" >/dev/null 2>&1; then
        _venv_apt_install python3 python3-venv
    fi
    local pyver
    pyver="$("$py" -c 'import sys; print(sys.version_info[:2] >= (3, 11), sys.version)')"
    case "$pyver" in
        True*) ;;
        *) echo "venv.sh: $py is too old (need Python >= 3.11): $pyver" >&2; return 1 ;;
    esac
    local want
    want="$( { cat "$req"; echo "$pyver"; "$py" -c 'import sys; print(sys.executable)'; } | sha256sum | cut -d' ' -f1)"
    VENV_PYTHON="$venv/bin/python"
    export VENV_PYTHON
    if [ -f "$venv/.requirements.sha256" ] && [ "$(cat "$venv/.requirements.sha256")" = "$want" ] \
        && "$VENV_PYTHON" -c 'import fmpy, libcosimpy, pytest, matplotlib, numpy, scipy, mpmath, dask.distributed, pyarrow, tqdm, hypothesis, asyncua, psycopg, playwright, importlinter' 2>/dev/null; then
        _venv_link_package "$root"
        return 0
    fi
    _venv_system_libs
    echo "venv.sh: creating $venv from requirements.txt" >&2
    rm -rf "$venv"
    if ! "$py" -m venv "$venv" 2>/dev/null; then
        # Debian's python3 needs python3-venv (ensurepip) to create a venv.
        rm -rf "$venv"
        _venv_apt_install python3-venv
        "$py" -m venv "$venv"
    fi
    "$VENV_PYTHON" -m pip install --quiet --disable-pip-version-check --no-input -r "$req"
    "$VENV_PYTHON" -c 'import fmpy, libcosimpy, pytest, matplotlib, numpy, scipy, mpmath, dask.distributed, pyarrow, tqdm, hypothesis, asyncua, psycopg, playwright, importlinter'
    echo "$want" > "$venv/.requirements.sha256"
    _venv_link_package "$root"
}

# Makes the project's Python package (python/reciprocating_drive) importable in the venv, as an
# editable install would: a .pth file naming this checkout's python/ folder, and the package's
# command .venv/bin/rdrive (the launcher pip writes for a console script).
_venv_link_package() {
    local root="$1" site launcher
    site="$("$VENV_PYTHON" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')"
    [ "$(cat "$site/reciprocating_drive.pth" 2>/dev/null)" = "$root/python" ] \
        || echo "$root/python" > "$site/reciprocating_drive.pth"
    launcher="$(dirname "$VENV_PYTHON")/rdrive"
    # The __main__ guard matters: Dask's LocalCluster starts its workers by re-running __main__.
    if ! grep -q "__main__" "$launcher" 2>/dev/null; then
        cat > "$launcher" <<EOF
#!$VENV_PYTHON
import sys
from reciprocating_drive.cli import main
if __name__ == "__main__":
    sys.exit(main())
EOF
        chmod +x "$launcher"
    fi
}
