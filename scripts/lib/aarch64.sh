# Sourced by scripts/build-fmu.sh: what the aarch64-linux binaries of the FMI 3.0 FMUs need
# (docs/fmi-interface.md "FMI 3.0"). Installs, when missing: rustup's aarch64-unknown-linux-gnu
# standard library, Debian's aarch64 C toolchain (the linker, and the C headers bindgen reads for
# the FMI types), and qemu-user with the arm64 C library (the tests run an aarch64 host under it).
# RD_AARCH64=0 skips the aarch64 build entirely.

AARCH64_TARGET=aarch64-unknown-linux-gnu

aarch64_enabled() {
    [ "${RD_AARCH64:-1}" != 0 ]
}

source "$(dirname "${BASH_SOURCE[0]}")/apt.sh"
source "$(dirname "${BASH_SOURCE[0]}")/lock.sh"

ensure_aarch64_build() {
    rd_rustup_target_add "$AARCH64_TARGET"
    if ! command -v aarch64-linux-gnu-gcc >/dev/null 2>&1; then
        apt_install gcc-aarch64-linux-gnu libc6-dev-arm64-cross
    fi
    export CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_LINKER=aarch64-linux-gnu-gcc
    # bindgen parses the FMI headers for the aarch64 target with the cross toolchain's headers.
    export BINDGEN_EXTRA_CLANG_ARGS_aarch64_unknown_linux_gnu="--target=aarch64-linux-gnu -I/usr/aarch64-linux-gnu/include"
}

# The aarch64 host of the tests runs under qemu-user with the arm64 C library as its sysroot
# (QEMU_LD_PREFIX=/usr/aarch64-linux-gnu).
ensure_qemu_aarch64() {
    if ! command -v qemu-aarch64 >/dev/null 2>&1 && ! command -v qemu-aarch64-static >/dev/null 2>&1; then
        apt_install qemu-user
    fi
    if [ ! -e /usr/aarch64-linux-gnu/lib/ld-linux-aarch64.so.1 ]; then
        apt_install libc6-arm64-cross
    fi
}
