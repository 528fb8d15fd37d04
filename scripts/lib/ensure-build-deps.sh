# Sourced by the scripts: installs what the Rust build needs on a fresh machine.
#
# bindgen (used by fmi-sys for the FMI 2.0 header types) loads libclang through clang-sys, which
# accepts only the C API library: libclang.so, libclang-N.so, libclang.so.N or libclang-N.so.N.
# libclang-cpp.so.N (the C++ library some Debian packages pull in) is NOT usable, so a plain
# `libclang*` glob is wrong: it finds libclang-cpp on a machine where bindgen then fails with
# "Unable to find libclang".
#
#   find_libclang      prints the path of a usable libclang, or nothing (exit 1)
#   ensure_libclang    finds one or installs libclang-dev, then exports LIBCLANG_PATH (its folder)
#   ensure_build_deps  everything the Rust build needs (today: libclang)
#
# For tests the search can be pointed at fake trees:
#   RD_LIBCLANG_DIRS      colon-separated list of directory globs searched (instead of the
#                         system's: llvm-config --libdir, /usr/lib/llvm-*/lib, /usr/lib*, ...)
#   RD_LIBCLANG_NO_LDCONFIG=1   do not ask `ldconfig -p`
#   RD_LIBCLANG_INSTALL   the command that installs libclang (default: apt-get install libclang-dev)

# The directories clang-sys searches on Linux when LIBCLANG_PATH is unset (clang-sys
# build/common.rs: llvm-config's libdir, then these globs), most specific first.
_libclang_default_dirs() {
    if command -v llvm-config >/dev/null 2>&1; then
        llvm-config --libdir 2>/dev/null
    fi
    local g
    for g in /usr/lib/llvm-*/lib /usr/local/llvm*/lib* /usr/local/lib* /usr/lib* /usr/lib*/*; do
        echo "$g"
    done
}

# A file name clang-sys can load (version suffixes only; never libclang-cpp).
_libclang_usable_name() {
    [[ "$1" =~ ^libclang(-[0-9]+(\.[0-9]+)*)?\.so(\.[0-9]+)*$ ]]
}

find_libclang() {
    local dirs=() d f
    if [ -n "${LIBCLANG_PATH:-}" ]; then
        dirs+=("$LIBCLANG_PATH")
    fi
    if [ -n "${RD_LIBCLANG_DIRS:-}" ]; then
        local IFS=:
        # shellcheck disable=SC2206  # globs are meant to expand here
        dirs+=($RD_LIBCLANG_DIRS)
        unset IFS
    else
        while IFS= read -r d; do dirs+=($d); done < <(_libclang_default_dirs)
    fi
    for d in "${dirs[@]}"; do
        [ -d "$d" ] || continue
        for f in "$d"/libclang*.so*; do
            [ -e "$f" ] || continue
            if _libclang_usable_name "$(basename "$f")"; then
                echo "$f"
                return 0
            fi
        done
    done
    if [ -z "${RD_LIBCLANG_NO_LDCONFIG:-}" ] && [ -z "${RD_LIBCLANG_DIRS:-}" ]; then
        # The dynamic loader's cache: "libclang-14.so.1 (libc6,x86-64) => /usr/lib/.../libclang-14.so.1"
        while read -r name _ _ path; do
            if _libclang_usable_name "$name" && [ -e "$path" ]; then
                echo "$path"
                return 0
            fi
        done < <(ldconfig -p 2>/dev/null | awk '/libclang/ {print $1, $2, $3, $NF}')
    fi
    return 1
}

_install_libclang() {
    if [ -n "${RD_LIBCLANG_INSTALL:-}" ]; then
        eval "$RD_LIBCLANG_INSTALL"
        return
    fi
    source "$(dirname "${BASH_SOURCE[0]}")/apt.sh"
    apt_install libclang-dev
}

ensure_libclang() {
    local lib
    if ! lib="$(find_libclang)"; then
        echo "ensure-build-deps: no usable libclang (libclang.so, libclang-N.so, libclang.so.N);" \
            "installing libclang-dev (needed by bindgen)" >&2
        _install_libclang
        if ! lib="$(find_libclang)"; then
            echo "ensure-build-deps: libclang is still missing after installing libclang-dev;" \
                "install it by hand and set LIBCLANG_PATH to its folder" >&2
            return 1
        fi
    fi
    # Point bindgen at exactly the library found, so a libclang-cpp or a broken copy elsewhere on
    # the default search path can never be picked instead.
    LIBCLANG_PATH="$(dirname "$lib")"
    export LIBCLANG_PATH
}

ensure_build_deps() {
    ensure_libclang
}
