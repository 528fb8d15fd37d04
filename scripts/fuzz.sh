#!/usr/bin/env bash
# A long fuzzing campaign of the C ABI (tests/fuzz_abi.rs, docs/hardening.md): by default
# 1 000 000 random call sequences from seed 1; CI runs 20 000 with scripts/test.sh.
#
#   scripts/fuzz.sh [SEQUENCES] [SEED]
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/lib/ensure-build-deps.sh
ensure_build_deps
RD_FUZZ_SEQUENCES="${1:-1000000}" RD_FUZZ_SEED="${2:-1}" \
    cargo test --release --test fuzz_abi -- --nocapture --test-threads=1
