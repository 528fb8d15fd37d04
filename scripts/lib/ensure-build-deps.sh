# Sourced by the scripts: installs what the Rust build needs on a fresh machine.
# bindgen (used by fmi-sys for the FMI 2.0 header types) needs libclang.
ensure_build_deps() {
    if ! ls /usr/lib/llvm-*/lib/libclang*.so* >/dev/null 2>&1 && ! ldconfig -p 2>/dev/null | grep -q libclang; then
        echo "installing libclang-dev (needed by bindgen)" >&2
        local sudo=""
        [ "$(id -u)" -ne 0 ] && sudo="sudo"
        $sudo apt-get update -qq
        DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq libclang-dev >/dev/null
    fi
}
