# Sourced by scripts/build-fmu.sh and scripts/test.sh: what the win64 binaries of the FMUs need
# (docs/win64.md). Installs, when missing: rustup's x86_64-pc-windows-gnu standard library,
# Debian's mingw-w64 C toolchain (the linker, and the C headers bindgen reads for the FMI types),
# and wine (the tests run the DLLs under it). RD_WIN64=0 skips the Windows build entirely.

WIN64_TARGET=x86_64-pc-windows-gnu

win64_enabled() {
    [ "${RD_WIN64:-1}" != 0 ]
}

source "$(dirname "${BASH_SOURCE[0]}")/apt.sh"
source "$(dirname "${BASH_SOURCE[0]}")/lock.sh"

_win64_apt() {
    apt_install "$@"
}

ensure_win64_build() {
    rd_rustup_target_add "$WIN64_TARGET"
    if ! command -v x86_64-w64-mingw32-gcc >/dev/null 2>&1; then
        _win64_apt gcc-mingw-w64-x86-64
    fi
    local gcc_inc
    gcc_inc="$(dirname "$(x86_64-w64-mingw32-gcc -print-file-name=include/stddef.h)")"
    export CARGO_TARGET_X86_64_PC_WINDOWS_GNU_LINKER=x86_64-w64-mingw32-gcc
    # bindgen parses the FMI headers for the Windows target with mingw's headers (and gcc's own,
    # for mm_malloc.h and stddef.h).
    export BINDGEN_EXTRA_CLANG_ARGS_x86_64_pc_windows_gnu="--target=$WIN64_TARGET -I/usr/x86_64-w64-mingw32/include -I$gcc_inc"
}

ensure_wine() {
    if ! command -v wine >/dev/null 2>&1; then
        _win64_apt wine64 wine
    fi
    export WINEDEBUG=-all
}
