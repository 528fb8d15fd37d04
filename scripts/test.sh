#!/usr/bin/env bash
# Runs every test of the project: the Rust unit and integration tests (release), then builds the
# FMU and runs the Python tests (fmpy, libcosim) against target/fmu/ReciprocatingDrive.fmu.
# Exits non-zero on any failure. Used by .ci/run.
set -euo pipefail
cd "$(dirname "$0")/.."

source scripts/lib/ensure-build-deps.sh
ensure_build_deps
source scripts/lib/venv.sh

echo "== cargo test --release"
cargo test --release
# The native batch driver of the digital twin is a workspace member outside default-members.
cargo test --release -p fmi2-batch

echo "== scripts/valgrind.sh (C-ABI tests under memcheck)"
bash scripts/valgrind.sh

echo "== scripts/build-fmu.sh"
bash scripts/build-fmu.sh

echo "== Python environment (.venv)"
ensure_venv
source scripts/lib/win64.sh
if win64_enabled; then
    ensure_wine  # tests/python/test_win64.py runs the win64 DLL under wine
fi
source scripts/lib/aarch64.sh
if aarch64_enabled; then
    ensure_qemu_aarch64  # tests/python/test_fmi3.py runs the aarch64-linux binary under qemu-user
fi

source scripts/lib/fmi_sim.sh
if fmi_sim_enabled; then
    ensure_fmi_sim  # tests/python/test_fmi_sim.py runs rust-fmi's fmi-sim (a second FMI 3.0 importer)
fi

echo "== scripts/build-wheel.sh (the installable package, tests/python/test_wheel.py)"
bash scripts/build-wheel.sh --no-build
# The wheel's tests install it into a venv of Debian's python3, which another user can run.
if ! /usr/bin/python3 -c 'import ensurepip, venv' 2>/dev/null; then
    source scripts/lib/apt.sh
    apt_install python3 python3-venv
fi

echo "== scripts/lint.sh (rustfmt, clippy -D warnings, ruff, lint-imports)"
bash scripts/lint.sh

# The twin's PostgreSQL sink is tested against a real temporary server (tests/python/pg_server.py).
source scripts/lib/postgres.sh
ensure_postgres

echo "== pytest tests/python"
# RD_REQUIRE_FMU: a missing FMU fails the run instead of skipping the tests.
# (pytest's summary stays the last line of the run.)
RD_REQUIRE_FMU=1 "$VENV_PYTHON" -m pytest tests/python -q -p no:cacheprovider
